/*
 * cull_lights.c — Forward+ light binning ("DirectX 11 Rendering in
 * Battlefield 3", GDC 2011; the same binning Frostbite did on the CPU for
 * mobile): per view, lights outside the frustum are dropped; each of the
 * rest is tested against the 16x16-pixel tiles its bounding sphere's
 * projection covers, each tile being a small frustum: four side planes
 * through the eye and the tile's edges, and two depth planes from the
 * nearest and farthest surface the tile shows. A light goes into a tile's
 * list if its sphere is not entirely outside any of those six planes.
 *
 * Everything is in double, camera-relative; the side planes are shared by
 * a tile column (row), the depth planes are made per tile. A spot light is
 * tested by its bounding sphere (conservative: a cone inside the sphere
 * never reaches a tile the sphere misses).
 *
 * Output is CSR (offsets, then indices): the pairs (tile, light) are
 * collected light by light, then counted and placed by tile, so each tile's
 * list comes out in ascending light order.
 */
#include "cull_internal.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct plane {
    double n[3], d; /* inside: n.p + d >= 0 over camera-relative p; |n| = 1, or n = 0 */
} plane;

/* A plane from a linear function of (p, 1), normalised; a function with no
 * direction becomes a constant (always or never satisfied). */
static plane mk_plane(const double f[4])
{
    double l = sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
    if (!(l > 1e-300)) return (plane){{0, 0, 0}, f[3] >= 0 ? 1.0 : -1.0};
    return (plane){{f[0] / l, f[1] / l, f[2] / l}, f[3] / l};
}

/* a * f + b * g, the linear function */
static void lin(double out[4], double a, const double f[4], double b, const double g[4])
{
    for (int c = 0; c < 4; c++) out[c] = a * f[c] + b * g[c];
}

/* The sphere (camera-relative centre c, radius r) is not entirely outside. */
static inline bool touches(const plane *p, const double c[3], double r)
{
    return p->n[0] * c[0] + p->n[1] * c[1] + p->n[2] * c[2] + p->d >= -r;
}

/* The one definition of a light a renderer can draw. The bounds keep
 * every derived value finite in float: |pos| <= 1e12 (the world's
 * coordinates); range in [1e-3, 1e9] m, so range^2 (1e18) and 1/range^2
 * (1e6) are normal floats; each channel of colour x intensity <= 1e12, so
 * even 65,536 lights summed at full strength (6.6e16) stay far below
 * FLT_MAX (3.4e38) and squares of a channel (1e24) do too; a spot axis of
 * unit length within 1e-3 (the daemon normalises a client's axis in double
 * first) and a cone cosine in [-1, 1]. */
int cull_light_validate(const cull_light *l, const double radiance[3], char *why, size_t whylen)
{
    static const char axis[3] = {'x', 'y', 'z'}, chan[3] = {'r', 'g', 'b'};
    if (!l) return vp_errf(why, whylen, CULL_ERR_INVALID, "no light");
    for (int a = 0; a < 3; a++) {
        if (!isfinite(l->pos[a]))
            return vp_errf(why, whylen, CULL_ERR_NONFINITE, "position %c is %g: NaN or infinite", axis[a], l->pos[a]);
        if (fabs(l->pos[a]) > CULL_MAX_COORD)
            return vp_errf(why, whylen, CULL_ERR_RANGE, "position %c is %g m, beyond the world's +-%g m",
                           axis[a], l->pos[a], CULL_MAX_COORD);
    }
    if (!isfinite(l->radius))
        return vp_errf(why, whylen, CULL_ERR_NONFINITE, "range is %g: NaN or infinite", l->radius);
    if (!(l->radius >= CULL_LIGHT_MIN_RANGE) || !(l->radius <= CULL_LIGHT_MAX_RANGE))
        return vp_errf(why, whylen, CULL_ERR_RADIUS, "range is %g m, outside %g..%g m",
                       l->radius, CULL_LIGHT_MIN_RANGE, CULL_LIGHT_MAX_RANGE);
    for (int k = 0; radiance && k < 3; k++) {
        if (!isfinite(radiance[k]))
            return vp_errf(why, whylen, CULL_ERR_NONFINITE, "colour %c x intensity is %g: NaN or infinite",
                           chan[k], radiance[k]);
        if (!(radiance[k] >= 0) || radiance[k] > CULL_LIGHT_MAX_RADIANCE)
            return vp_errf(why, whylen, CULL_ERR_RANGE, "colour %c x intensity is %g, outside 0..%g",
                           chan[k], radiance[k], CULL_LIGHT_MAX_RADIANCE);
    }
    if (l->type == CULL_LIGHT_POINT) return CULL_OK;
    if (l->type != CULL_LIGHT_SPOT)
        return vp_errf(why, whylen, CULL_ERR_INVALID, "type %u is neither point (0) nor spot (1)", l->type);
    double n = (double)l->dir[0] * l->dir[0] + (double)l->dir[1] * l->dir[1] + (double)l->dir[2] * l->dir[2];
    if (!isfinite(n) || !(fabs(n - 1) < 1e-3))
        return vp_errf(why, whylen, CULL_ERR_INVALID, "spot direction (%g, %g, %g) is not of unit length",
                       (double)l->dir[0], (double)l->dir[1], (double)l->dir[2]);
    if (!(l->cos_outer >= -1 && l->cos_outer <= 1))
        return vp_errf(why, whylen, CULL_ERR_INVALID, "spot outer cosine %g is outside -1..1", (double)l->cos_outer);
    return CULL_OK;
}

void cull_light_tiles_free(cull_light_tiles *t)
{
    if (!t) return;
    free(t->offset);
    free(t->index);
    free(t->scratch);
    memset(t, 0, sizeof *t);
}

/* The tile range a sphere's projection may cover: its AABB's corners
 * projected; the whole view when a corner is at or behind the near plane. */
static void tile_range(const cull_view_rows *vr, const double c[3], double r, double sx, double sy, uint32_t tx,
                       uint32_t ty, uint32_t box[4])
{
    double xmin = INFINITY, xmax = -INFINITY, ymin = INFINITY, ymax = -INFINITY;
    for (int k = 0; k < 8; k++) {
        double p[3] = {c[0] + ((k & 1) ? r : -r), c[1] + ((k & 2) ? r : -r), c[2] + ((k & 4) ? r : -r)};
        double w = vr->w[0] * p[0] + vr->w[1] * p[1] + vr->w[2] * p[2] + vr->w[3];
        double nf = vr->nearfn[0] * p[0] + vr->nearfn[1] * p[1] + vr->nearfn[2] * p[2] + vr->nearfn[3];
        if (!(w > 0) || !(nf > 0)) {
            box[0] = box[1] = 0;
            box[2] = tx - 1;
            box[3] = ty - 1;
            return;
        }
        double x = (vr->x[0] * p[0] + vr->x[1] * p[1] + vr->x[2] * p[2] + vr->x[3]) / w;
        double y = (vr->y[0] * p[0] + vr->y[1] * p[1] + vr->y[2] * p[2] + vr->y[3]) / w;
        xmin = fmin(xmin, x);
        xmax = fmax(xmax, x);
        ymin = fmin(ymin, y);
        ymax = fmax(ymax, y);
    }
    /* pixels, then tiles, one tile of slack each way for rounding */
    double t0 = floor((xmin + 1) * sx / CULL_LIGHT_TILE) - 1, t1 = floor((xmax + 1) * sx / CULL_LIGHT_TILE) + 1;
    double u0 = floor((ymin + 1) * sy / CULL_LIGHT_TILE) - 1, u1 = floor((ymax + 1) * sy / CULL_LIGHT_TILE) + 1;
    t0 = fmax(t0, 0);
    u0 = fmax(u0, 0);
    t1 = fmin(t1, tx - 1.0);
    u1 = fmin(u1, ty - 1.0);
    if (t0 > t1 || u0 > u1) { /* off screen: an empty range */
        box[0] = box[1] = 1;
        box[2] = box[3] = 0;
        return;
    }
    box[0] = (uint32_t)t0;
    box[1] = (uint32_t)u0;
    box[2] = (uint32_t)t1;
    box[3] = (uint32_t)u1;
}

int cull_lights_bin(const cull_view *v, uint32_t width, uint32_t height, const cull_light *lights, uint32_t n,
                    const float (*depth_range)[2], cull_light_tiles *out)
{
    if (!v || !out || (n && !lights)) return CULL_ERR_INVALID;
    if (width == 0 || height == 0 || width > 65535 || height > 65535) return CULL_ERR_VIEWPORT;
    for (uint32_t i = 0; i < n; i++)
        if (cull_light_validate(&lights[i], NULL, NULL, 0) != CULL_OK) return CULL_ERR_INVALID;
    uint32_t tx = (width + CULL_LIGHT_TILE - 1) / CULL_LIGHT_TILE, ty = (height + CULL_LIGHT_TILE - 1) / CULL_LIGHT_TILE;
    size_t ntiles = (size_t)tx * ty;
    if (!vp_grow32((void **)&out->offset, &out->offset_cap, ntiles + 1, sizeof *out->offset)) return CULL_ERR_NOMEM;
    out->tiles_x = tx;
    out->tiles_y = ty;
    out->in_view = 0;
    out->max_per_tile = 0;
    memset(out->offset, 0, (ntiles + 1) * sizeof *out->offset);
    if (!n) return CULL_OK; /* no lights: nothing to test */

    cull_view_rows vr;
    cull_view_rows_get(v, &vr);
    if (!vr.usable) return CULL_ERR_MATRIX;
    double sx = 0.5 * width, sy = 0.5 * height;

    /* side planes: column i spans NDC x in [X_i, X_i+1] (the last tile may
       reach past the viewport: its plane is the viewport's edge) */
    size_t ndepth = depth_range ? 2 * ntiles : 0;
    plane *col = malloc((2 * (size_t)tx + 2 * (size_t)ty + ndepth) * sizeof *col), *row = col + 2 * (size_t)tx;
    plane *dpl = row + 2 * (size_t)ty; /* per tile: far and near depth planes */
    if (!col) return CULL_ERR_NOMEM;
    for (uint32_t i = 0; i < tx; i++) {
        double x0 = -1 + 2.0 * i * CULL_LIGHT_TILE / width, x1 = fmin(1, -1 + 2.0 * (i + 1) * CULL_LIGHT_TILE / width);
        double f[4];
        lin(f, 1, vr.x, -x0, vr.w); /* x >= x0 w */
        col[2 * i] = mk_plane(f);
        lin(f, -1, vr.x, x1, vr.w); /* x <= x1 w */
        col[2 * i + 1] = mk_plane(f);
    }
    for (uint32_t j = 0; j < ty; j++) {
        double y0 = -1 + 2.0 * j * CULL_LIGHT_TILE / height, y1 = fmin(1, -1 + 2.0 * (j + 1) * CULL_LIGHT_TILE / height);
        double f[4];
        lin(f, 1, vr.y, -y0, vr.w);
        row[2 * j] = mk_plane(f);
        lin(f, -1, vr.y, y1, vr.w);
        row[2 * j + 1] = mk_plane(f);
    }

    /* depth planes, once per tile that shows something: nearness in
       [nf, nn], widened by its float rounding: d - nf w >= 0 and
       nn w - d >= 0 */
    for (size_t t = 0; t < ndepth / 2; t++) {
        float nn = depth_range[t][0], nf = depth_range[t][1];
        if (!(nn >= nf)) continue; /* the tile shows nothing: never read */
        double lo = nf - 0x1p-20 * fabs(nf), hi = nn + 0x1p-20 * fabs(nn), f[4];
        lin(f, 1, vr.d, -lo, vr.w);
        dpl[2 * t] = mk_plane(f);
        lin(f, -1, vr.d, hi, vr.w);
        dpl[2 * t + 1] = mk_plane(f);
    }

    /* (tile, light) pairs, light by light */
    size_t npairs = 0;
    int rc = CULL_OK;
    for (uint32_t li = 0; li < n && rc == CULL_OK; li++) {
        const cull_light *l = &lights[li];
        double c[3] = {l->pos[0] - v->origin[0], l->pos[1] - v->origin[1], l->pos[2] - v->origin[2]};
        double r = l->radius * (1 + 0x1p-30) + 1e-9 * (fabs(c[0]) + fabs(c[1]) + fabs(c[2]));
        bool in = true;
        for (uint32_t k = 0; k < v->plane_count && in; k++) {
            const double *pl = v->plane[k];
            in = pl[0] * c[0] + pl[1] * c[1] + pl[2] * c[2] + pl[3] >= -r;
        }
        if (!in) continue;
        out->in_view++;
        uint32_t box[4];
        tile_range(&vr, c, r, sx, sy, tx, ty, box);
        for (uint32_t j = box[1]; j <= box[3] && rc == CULL_OK; j++) {
            if (!touches(&row[2 * j], c, r) || !touches(&row[2 * j + 1], c, r)) continue;
            for (uint32_t i = box[0]; i <= box[2]; i++) {
                if (!touches(&col[2 * i], c, r) || !touches(&col[2 * i + 1], c, r)) continue;
                uint32_t t = j * tx + i;
                if (depth_range) {
                    if (!(depth_range[t][0] >= depth_range[t][1])) continue; /* the tile shows nothing */
                    if (!touches(&dpl[2 * t], c, r) || !touches(&dpl[2 * t + 1], c, r)) continue;
                }
                if (!vp_grow32((void **)&out->scratch, &out->scratch_cap, 2 * (npairs + 1), sizeof *out->scratch)) {
                    rc = CULL_ERR_NOMEM;
                    break;
                }
                out->scratch[2 * npairs] = t;
                out->scratch[2 * npairs + 1] = li;
                npairs++;
            }
        }
    }
    free(col);
    if (rc == CULL_OK && !vp_grow32((void **)&out->index, &out->index_cap, npairs + 1, sizeof *out->index))
        rc = CULL_ERR_NOMEM;
    if (rc != CULL_OK) {
        memset(out->offset, 0, (ntiles + 1) * sizeof *out->offset);
        out->in_view = 0;
        return rc;
    }
    /* counting sort by tile: stable, so each list stays in light order */
    for (size_t k = 0; k < npairs; k++) out->offset[out->scratch[2 * k] + 1]++;
    for (size_t t = 0; t < ntiles; t++) {
        if (out->offset[t + 1] > out->max_per_tile) out->max_per_tile = out->offset[t + 1];
        out->offset[t + 1] += out->offset[t];
    }
    for (size_t k = 0; k < npairs; k++) {
        uint32_t t = out->scratch[2 * k];
        /* offset[t] is used as the fill cursor, then restored */
        out->index[out->offset[t]++] = out->scratch[2 * k + 1];
    }
    for (size_t t = ntiles; t > 0; t--) out->offset[t] = out->offset[t - 1];
    out->offset[0] = 0;
    return CULL_OK;
}
