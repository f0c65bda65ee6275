/*
 * cull_occ.c — software occlusion, the buffer and what reads it: the
 * occlusion buffers (create, cover mode, the depth read-back), the view
 * set-up, the projection of boxes to pixel rectangles, and the rectangle
 * test the query's last stage runs ("Culling the Battlefield", DICE 2011,
 * slides 41-52). Drawing the occluders into it: cull_occ_raster.inl.
 *
 * Depth. Each pixel stores a "nearness" that is affine in screen space:
 * 1/w for perspective views, 1 - z_ndc (z_ndc with reversed-Z) for
 * orthographic ones; larger is nearer, -FLT_MAX is "no occluder". A pixel's
 * value is never nearer than the occluder anywhere over the pixel: the
 * plane's value at the pixel's farthest corner, but not below the polygon's
 * farthest vertex, minus the float rounding of the evaluation.
 *
 * Hierarchy: min over 8x8 tiles and over 64x64 tiles. A rectangle test
 * walks the big tiles, then the small ones, and reads pixels only where a
 * tile is not entirely nearer than the box: a hidden box costs a few loads.
 */
#include "cull_internal.h"
#include "cull_occ.h"
#include "cull_occ_num.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

_Static_assert((int)TILE_INVALID == (int)OCC_TILE_INVALID, "cull_occ_test.inl reads tstate");

/* ---- buffers ------------------------------------------------------------------ */

int cull_occ_buffer_create(uint32_t width, uint32_t height, cull_occ_buffer **out)
{
    if (!out) return CULL_ERR_INVALID;
    *out = NULL;
    if (width < 8 || height < 8 || width > 8192 || height > 8192) return CULL_ERR_BUFFER;
    cull_occ_buffer *b = calloc(1, sizeof *b);
    if (!b) return CULL_ERR_NOMEM;
    b->w = width;
    b->h = height;
    b->stride = (width + 127) & ~127u; /* tile rows of floats: whole cache lines */
    b->hp = (height + 63) & ~63u;
    b->tw = b->stride / 8;
    b->th = b->hp / 8;
    b->t2w = b->stride / 64;
    b->t2h = b->hp / 64;
    /* a slot for every tile of the real tile rows (those above, all
       padding, are never drawn or read), and OCC_SLOT_AHEAD more that only
       prefetches reach */
    const uint32_t rows = (b->h + 7) / 8;
    b->pool = aligned_alloc(64, ((size_t)rows * b->tw + OCC_SLOT_AHEAD) * 64 * sizeof(float));
    b->tslot = calloc((size_t)b->tw * b->th, sizeof *b->tslot);
    b->tile = aligned_alloc(64, (size_t)b->tw * b->th * sizeof(float)); /* tw * 4 bytes = 64 k */
    b->tile2 = malloc((size_t)b->t2w * b->t2h * sizeof(float));
    b->tile_full = aligned_alloc(64, (size_t)b->tw * b->th * sizeof(float));
    b->teff = aligned_alloc(64, (size_t)b->tw * b->th * sizeof(float));
    b->tmax = aligned_alloc(64, (size_t)b->tw * b->th * sizeof(float));
    b->vkey = aligned_alloc(64, (size_t)b->tw * b->th * sizeof(float));
    /* strips: 8 tiles of one tile row (64 x 8 pixels); rows padded to 64
       bytes like the tile states */
    b->spitch = (b->t2w + 15) & ~15u;
    b->sdpitch = (b->t2w + 63) & ~63u;
    b->strip = aligned_alloc(64, (size_t)b->spitch * b->th * sizeof(float));
    b->sdirty = aligned_alloc(64, (size_t)b->sdpitch * b->th);
    /* a tile row of states per 64 bytes: bands never share a cache line */
    b->tpitch = (b->tw + 63) & ~63u;
    b->tstate = aligned_alloc(64, (size_t)b->tpitch * b->th);
    if (!b->pool || !b->tslot || !b->tile || !b->tile2 || !b->tile_full || !b->teff || !b->tmax || !b->vkey || !b->tstate ||
        !b->strip || !b->sdirty) {
        cull_occ_buffer_destroy(b);
        return CULL_ERR_NOMEM;
    }
    /* every tile clean and EMPTY (padding PAD: it never lowers a tile's
       minimum), as band 0 of a one-band render would leave it */
    b->threads_used = 1;
    for (uint32_t ty = 0; ty < rows; ty++)
        for (uint32_t tx = 0; tx < b->tw; tx++) (void)occ_tile_take(b, &b->slot_next[0], (int)tx, (int)ty);
    for (size_t i = 0; i < (size_t)b->tw * b->th; i++) b->tile[i] = b->tile_full[i] = b->teff[i] = EMPTY;
    memset(b->tstate, TILE_CLEAN, (size_t)b->tpitch * b->th);
    for (size_t i = 0; i < (size_t)b->tw * b->th; i++) b->tmax[i] = EMPTY; /* the pixels; vkey below */
    /* strips of padding tile rows (above the buffer) are never drawn or
       cleared: padding, so the big tiles' minima see only real rows */
    for (size_t i = 0; i < (size_t)b->spitch * b->th; i++)
        b->strip[i] = i / b->spitch < (b->h + 7) / 8 ? EMPTY : PAD;
    memset(b->sdirty, 0, (size_t)b->sdpitch * b->th);
    for (size_t i = 0; i < (size_t)b->t2w * b->t2h; i++) b->tile2[i] = EMPTY;
    b->inner = true;
    b->isa = cull_isa_default();
    b->fns = cull_occ_fns_for(b->isa);
    for (uint32_t ty = 0; ty < b->th; ty++) cull_occ_vkey_row(b, ty);
    *out = b;
    return CULL_OK;
}

void cull_occ_buffer_destroy(cull_occ_buffer *b)
{
    if (!b) return;
    free(b->pool);
    free(b->tslot);
    free(b->plane);
    free(b->tile);
    free(b->tile2);
    free(b->tile_full);
    free(b->teff);
    free(b->tmax);
    free(b->vkey);
    free(b->tstate);
    free(b->strip);
    free(b->sdirty);
    free(b->items);
    free(b->items2);
    free(b->sortbuf);
    free(b->codes);
    free(b->pidx);
    free(b->proj);
    free(b->pcode);
    free(b->rects);
    free(b);
}

int cull_occ_buffer_set_cover(cull_occ_buffer *b, uint32_t cover)
{
    if (!b || cover > CULL_OCC_COVER_CENTRE) return CULL_ERR_INVALID;
    b->inner = cover == CULL_OCC_COVER_INNER;
    return CULL_OK;
}

int cull_occ_buffer_empty(const cull_occ_buffer *b)
{
    return !b || !b->drawn;
}

const float *cull_occ_depth(cull_occ_buffer *b, uint32_t *width, uint32_t *height, size_t *stride)
{
    if (!b) return NULL;
    if (!b->plane && !(b->plane = aligned_alloc(64, (size_t)b->stride * b->hp * sizeof(float)))) return NULL;
    /* fold the coarse per-tile values into the pixels (tests read either
       way; the pixels alone are what a viewer shows), then copy the tiles
       out row by row (PAD above the real tile rows) */
    const uint32_t rows = (b->h + 7) / 8, nb = b->threads_used;
    for (uint32_t ty = 0; ty < b->th; ty++)
        for (uint32_t tx = 0; tx < b->tw; tx++) {
            float *out = b->plane + (size_t)ty * 8 * b->stride + (size_t)tx * 8;
            if (ty >= rows) {
                for (uint32_t y = 0; y < 8; y++)
                    for (uint32_t x = 0; x < 8; x++) out[y * b->stride + x] = PAD;
                continue;
            }
            size_t i = (size_t)ty * b->tw + tx;
            uint8_t *st = &b->tstate[(size_t)ty * b->tpitch + tx];
            float full = b->tile_full[i];
            if (*st == TILE_INVALID || full != EMPTY) {
                float *px = *st == TILE_INVALID ? occ_tile_take(b, &b->slot_next[ty % nb], (int)tx, (int)ty)
                                                : cull_occ_tile_px(b, i);
                uint32_t ny = ty * 8 + 8 < b->h ? 8 : b->h - ty * 8, nx = tx * 8 + 8 < b->w ? 8 : b->w > tx * 8 ? b->w - tx * 8 : 0;
                for (uint32_t y = 0; y < ny; y++)
                    for (uint32_t x = 0; x < nx; x++) {
                        float *p = &px[8 * y + x];
                        *p = *st == TILE_INVALID || full > *p ? full : *p;
                    }
                b->fns.tiles(b->pool, b->tslot + i, 1, b->tile + i, b->tmax + i);
                *st = TILE_CLEAN;
                b->teff[i] = b->tile[i];
            }
            const float *px = cull_occ_tile_px(b, i);
            for (uint32_t y = 0; y < 8; y++) memcpy(out + y * b->stride, px + 8 * y, 8 * sizeof *px);
        }
    for (uint32_t ty = 0; ty < b->th; ty++) cull_occ_vkey_row(b, ty);
    if (width) *width = b->w;
    if (height) *height = b->h;
    if (stride) *stride = b->stride;
    return b->plane;
}

/* The tests' "visible at once" key of each tile of row ty. A rectangle
 * reaching tile t is visible where the exact walk (tiles_visible) would
 * say so at t: teff <= z and (the tile invalid, or a pixel of the part of
 * the rectangle in t <= z). With vkey = teff (invalid) or max(teff, the
 * largest real pixel), vkey <= z implies that for any part of t. Tiles
 * cut by the buffer's right or top edge take the largest of their real
 * pixels only (tmax includes padding, FLT_MAX); tiles past the edge,
 * never tested, get padding. An invalid tile's tmax is EMPTY (filled so
 * when a render makes the row invalid; only tiles() writes it after, for
 * tiles it makes clean), so whole tiles need no state: max(teff, tmax),
 * a vector at a time (a render runs it over every tile). */
void cull_occ_vkey_row(cull_occ_buffer *b, uint32_t ty)
{
    const size_t o = (size_t)ty * b->tw;
    const float *teff = b->teff + o, *tmax = b->tmax + o;
    const uint8_t *st = b->tstate + (size_t)ty * b->tpitch;
    float *vk = b->vkey + o;
    uint32_t real = (b->w + 7) >> 3, whole = ty * 8 + 8 <= b->h ? b->w >> 3 : 0;
    if (ty * 8 >= b->h) real = whole = 0;
    uint32_t tx = 0;
    b->fns.max2(vk, tmax, teff, whole);
    tx = whole;
    for (; tx < real; tx++) {
        float m = teff[tx];
        if (st[tx] != TILE_INVALID) {
            const float *px = cull_occ_tile_px(b, o + tx);
            uint32_t ny = ty * 8 + 8 < b->h ? 8 : b->h - ty * 8, nx = tx * 8 + 8 < b->w ? 8 : b->w - tx * 8;
            for (uint32_t y = 0; y < ny; y++)
                for (uint32_t x = 0; x < nx; x++) {
                    float v = px[8 * y + x];
                    m = v > m ? v : m;
                }
        }
        vk[tx] = m;
    }
    for (; tx < b->tw; tx++) vk[tx] = PAD;
}

/* ---- the view as the rasteriser and the tests see it ------------------------- */

/* Rows of the view-projection (camera-relative), the nearness numerator and
 * the near plane, all as linear functions of (p - origin, 1). */
void cull_occ_setup_view(cull_occ_buffer *b, const cull_view *v)
{
    cull_view_rows r;
    cull_view_rows_get(v, &r);
    memcpy(b->rx, r.x, sizeof b->rx);
    memcpy(b->ry, r.y, sizeof b->ry);
    memcpy(b->rw, r.w, sizeof b->rw);
    memcpy(b->rn, r.nearfn, sizeof b->rn);
    memcpy(b->rd, r.d, sizeof b->rd);
    memcpy(b->origin, v->origin, sizeof b->origin);
    b->usable = r.usable;
    b->sx = 0.5 * b->w;
    b->sy = 0.5 * b->h;
}

/* The one place an NDC extent and a nearness become a pixel rectangle and a
 * float depth; both projections end here. Pixel i spans [i, i + 1) in
 * pixel units, NDC (2i / W - 1 ...): every pixel the projection touches,
 * grown by 2^-20 of the buffer for the rounding of the projection. Not
 * just the pixel centres inside it: an entity smaller than a pixel must
 * still be tested, not dropped. The nearness is grown by 2^-20 of itself
 * and rounded up to a float: the box is never tested as farther than it
 * is. The callers keep NaN out (dmin, dmax and dfloor do not order it). */
static inline int rect_of(const cull_occ_buffer *b, double xmin, double xmax, double ymin, double ymax, double nmax,
                          cull_occ_rect *r)
{
    double i0 = dmax(dfloor((xmin + 1) * b->sx - 0x1p-20 * b->w), 0);
    double i1 = dmin(dceil((xmax + 1) * b->sx + 0x1p-20 * b->w) - 1, b->w - 1.0);
    double j0 = dmax(dfloor((ymin + 1) * b->sy - 0x1p-20 * b->h), 0);
    double j1 = dmin(dceil((ymax + 1) * b->sy + 0x1p-20 * b->h) - 1, b->h - 1.0);
    if (!(i0 <= i1 && j0 <= j1)) return OCC_BOX_OFF;
    r->x0 = (int)i0;
    r->x1 = (int)i1;
    r->y0 = (int)j0;
    r->y1 = (int)j1;
    r->z = cull_round_up(nmax + 0x1p-20 * fabs(nmax));
    return OCC_BOX_OK;
}

/* Pixel rectangle (every pixel the projection touches) and nearest nearness of
 * a world AABB. Returns OCC_BOX_OFF (no pixel centre), OCC_BOX_NEAR (the box
 * reaches the near plane: treat as visible) or OCC_BOX_OK. */
int cull_occ_project_box(const cull_occ_buffer *b, const double mn[3], const double mx[3], cull_occ_rect *r)
{
    double xmin = INFINITY, xmax = -INFINITY, ymin = INFINITY, ymax = -INFINITY, nmax = -INFINITY;
    for (int c = 0; c < 8; c++) {
        double p[3] = {((c & 1) ? mx[0] : mn[0]) - b->origin[0], ((c & 2) ? mx[1] : mn[1]) - b->origin[1],
                       ((c & 4) ? mx[2] : mn[2]) - b->origin[2]};
        double w = lin4(b->rw, p);
        if (!(lin4(b->rn, p) > 0) || !(w > 0)) return OCC_BOX_NEAR;
        double iw = 1.0 / w, x = lin4(b->rx, p) * iw, y = lin4(b->ry, p) * iw, n = lin4(b->rd, p) * iw;
        /* an overflow (0 * inf, inf - inf) says nothing about where the
           box is or how near: it may be visible */
        if (x != x || y != y || !isfin(n)) return OCC_BOX_NEAR;
        xmin = dmin(xmin, x);
        xmax = dmax(xmax, x);
        ymin = dmin(ymin, y);
        ymax = dmax(ymax, y);
        nmax = dmax(nmax, n);
    }
    return rect_of(b, xmin, xmax, ymin, ymax, nmax, r);
}

/* A cheaper, looser cull_occ_project_box for clusters and cells:
 * over the box, each clip row lies within centre +- extent, so x = X / W
 * lies between the quotients of the interval ends (4 divisions, not 8
 * corners). The rectangle can only be larger and the nearness nearer. */
/* A box (centre c less the origin, half extents e) projected: o[0..3]
 * its NDC x and y range, o[4] its far nearness, o[5] 1 where it reaches
 * the near plane (o[0..4] then unset). */
static inline void bound_ndc(const cull_occ_buffer *b, const double c[3], const double e[3], double o[6])
{
    const double *rows[5] = {b->rx, b->ry, b->rw, b->rd, b->rn};
    double v[5], ex[5];
    for (int k = 0; k < 5; k++) {
        const double *q = rows[k];
        v[k] = q[0] * c[0] + q[1] * c[1] + q[2] * c[2] + q[3];
        ex[k] = (fabs(q[0]) * e[0] + fabs(q[1]) * e[1] + fabs(q[2]) * e[2]) * (1 + 0x1p-40);
    }
    double wlo = v[2] - ex[2], whi = v[2] + ex[2];
    o[5] = !(v[4] - ex[4] > 0) || !(wlo > 0);
    if (o[5]) return;
    double il = 1.0 / wlo, ih = 1.0 / whi;
    double xa = v[0] - ex[0], xb = v[0] + ex[0], ya = v[1] - ex[1], yb = v[1] + ex[1];
    o[0] = dmin(xa * il, xa * ih);
    o[1] = dmax(xb * il, xb * ih);
    o[2] = dmin(ya * il, ya * ih);
    o[3] = dmax(yb * il, yb * ih);
    double d = v[3] + ex[3];
    o[4] = d >= 0 ? d * il : d * ih;
}

int cull_occ_bound_rect(const cull_occ_buffer *b, const double o[6], cull_occ_rect *r)
{
    if (o[5] != 0) return OCC_BOX_NEAR;
    /* NaN from an overflow: nothing known, so drawn in every band (raster
       skips what it cannot set up) and tested as visible */
    if (o[0] != o[0] || o[1] != o[1] || o[2] != o[2] || o[3] != o[3] || !isfin(o[4])) return OCC_BOX_NEAR;
    return rect_of(b, o[0], o[1], o[2], o[3], o[4], r);
}

int cull_occ_project_bound(const cull_occ_buffer *b, const double mn[3], const double mx[3], cull_occ_rect *r)
{
    double c[3], e[3], o[6];
    for (int a = 0; a < 3; a++) {
        c[a] = 0.5 * (mn[a] + mx[a]) - b->origin[a];
        e[a] = 0.5 * (mx[a] - mn[a]);
    }
    bound_ndc(b, c, e, o);
    return cull_occ_bound_rect(b, o, r);
}

/* cull_occ_fns.project, the reference: the SoA holds the same centres and
 * half extents (cull_soa_set) as cull_occ_project_bound computes */
void cull_occ_project_scalar(const cull_occ_buffer *b, const cull_bounds_soa *s, const uint32_t *idx, uint32_t n,
                             double *out, size_t pitch)
{
    for (uint32_t q = 0; q < n; q++) {
        uint32_t i = idx[q];
        double c[3], e[3], o[6];
        for (int a = 0; a < 3; a++) {
            c[a] = CULL_SOA(s, a)[i] - b->origin[a];
            e[a] = CULL_SOA(s, 3 + a)[i];
        }
        bound_ndc(b, c, e, o);
        for (int k = 0; k < 6; k++) out[(size_t)k * pitch + q] = o[k];
    }
}

/* Some pixel of the rectangle not strictly nearer than z? */
/* The 8x8 tiles over a rectangle, and the pixels of those not entirely
 * nearer than z. Rows of a tile are at most 8 pixels: scanned inline.
 * This is the reference the per-ISA walk (cull_occ_test.inl: the query's
 * kernel and cell stage) must equal, test_occ_wide_matches_scalar: a tile
 * shows the rectangle where teff <= z and (the tile is invalid or one of
 * the rectangle's pixels in it is <= z). */
static bool tiles_visible(const cull_occ_buffer *b, int x0, int y0, int x1, int y1, float z)
{
    for (int ty = y0 >> 3; ty <= y1 >> 3; ty++) {
        for (int tx = x0 >> 3; tx <= x1 >> 3; tx++) {
            if (b->teff[(size_t)ty * b->tw + tx] > z) continue;
            if (b->tstate[(size_t)ty * b->tpitch + tx] == TILE_INVALID) return true; /* pixels all EMPTY */
            int px0 = tx << 3 > x0 ? tx << 3 : x0, px1 = (tx << 3) + 7 < x1 ? (tx << 3) + 7 : x1;
            int py0 = ty << 3 > y0 ? ty << 3 : y0, py1 = (ty << 3) + 7 < y1 ? (ty << 3) + 7 : y1;
            const float *pix = cull_occ_tile_px(b, (size_t)ty * b->tw + tx);
            for (int py = py0; py <= py1; py++) {
                const float *row = pix + 8 * (py & 7) - (tx << 3);
                int hit = 0;
                for (int px = px0; px <= px1; px++) hit |= row[px] <= z;
                if (hit) return true;
            }
        }
    }
    return false;
}

bool cull_occ_rect_visible(const cull_occ_buffer *b, int x0, int y0, int x1, int y1, float z)
{
    /* small rectangles (most entities) go straight to the 8x8 tiles */
    if (x1 - x0 < 32 && y1 - y0 < 32) return tiles_visible(b, x0, y0, x1, y1, z);
    for (int Y = y0 >> 6; Y <= y1 >> 6; Y++)
        for (int X = x0 >> 6; X <= x1 >> 6; X++) {
            if (b->tile2[Y * b->t2w + X] > z) continue;
            int ry0 = Y << 6 > y0 ? Y << 6 : y0, ry1 = (Y << 6) + 63 < y1 ? (Y << 6) + 63 : y1;
            int rx0 = X << 6 > x0 ? X << 6 : x0, rx1 = (X << 6) + 63 < x1 ? (X << 6) + 63 : x1;
            if (tiles_visible(b, rx0, ry0, rx1, ry1, z)) return true;
        }
    return false;
}

int cull_occ_test_aabb(const cull_occ_buffer *b, const double mn[3], const double mx[3])
{
    if (!b || !mn || !mx) return 1;
    if (!b->drawn || !b->usable) return 1;
    cull_occ_rect r;
    switch (cull_occ_project_box(b, mn, mx, &r)) {
    case OCC_BOX_OFF: return 0;
    case OCC_BOX_NEAR: return 1;
    default: return cull_occ_rect_visible(b, r.x0, r.y0, r.x1, r.y1, r.z);
    }
}
