/*
 * vt_overlay.c — the frame's overlay: the highlighted instances' outline
 * and the icons (vt_overlay.h). Runs once per frame on the caller's
 * thread, after the renderer's last pass; without an overlay it costs one
 * branch.
 */
#include "vt_overlay.h"

#include "vt_picture.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* after exposure, before the tone map: ACES at exposure_ev 0 maps 4.0 to
   0.97, 0.6 to 0.67 and 0.15 to 0.22 (sRGB 0.99, 0.84, 0.5): a golden
   outline, an orange ping, a cyan select, a white unit, each saturated
   (the curve is steep: 2.0 would already read as 0.92, nearly white) */
static const float icon_default[3][3] = {{4.0f, 0.15f, 0.0f}, {0.0f, 0.6f, 4.0f}, {3.0f, 3.0f, 3.0f}};
static const float outline_default[VT_OUTLINES][3] = {{4.0f, 0.6f, 0.0f}, {0.0f, 0.6f, 4.0f}};
#define HIDDEN_WEIGHT 0.45f /* an edge behind something: blended this much */
#define HALO_WEIGHT 0.8f    /* an icon's halo darkens what is under it this much */

uint32_t vt_overlay_half_width(uint32_t height)
{
    uint32_t h = (height + 180) / 720;
    return h ? h : 1;
}

static bool color_ok(const float c[3])
{
    for (int a = 0; a < 3; a++)
        if (!(c[a] >= 0 && c[a] <= 1e6f)) return false;
    return true;
}

static int outline_check(const vt_frame *f, const vt_outline *o, int g, char *err, size_t errlen)
{
    if ((o->nhl && !o->hl) || (o->nextra && !o->extra))
        return vp_errf(err, errlen, VT_ERR_INVALID, "overlay: outline %d: missing argument", g);
    if (o->nhl > VT_OVERLAY_MAX_HL || o->nextra > VT_OVERLAY_MAX_HL)
        return vp_errf(err, errlen, VT_ERR_INVALID, "overlay: outline %d: %u highlights, %u extra instances (at most %u)",
                       g, o->nhl, o->nextra, VT_OVERLAY_MAX_HL);
    for (uint32_t i = 0; i < o->nextra; i++) {
        const vt_instance *in = &o->extra[i];
        bool ok = in->place == VT_PLACE_BOUNDS && in->mesh < f->nmesh;
        for (int a = 0; a < 3; a++)
            ok = ok && fabs(in->bmin[a]) <= 1e15 && fabs(in->bmax[a]) <= 1e15 && in->bmin[a] <= in->bmax[a];
        if (!ok)
            return vp_errf(err, errlen, VT_ERR_INVALID, "overlay: outline %d: extra instance %u: bad mesh or bounds",
                           g, i);
    }
    for (uint32_t i = 0; i < o->nhl; i++)
        if (o->hl[i] >= f->ninst)
            return vp_errf(err, errlen, VT_ERR_INVALID, "overlay: outline %d: highlight %u is instance %u, past %u", g,
                           i, o->hl[i], f->ninst);
    if (!color_ok(o->color))
        return vp_errf(err, errlen, VT_ERR_INVALID, "overlay: outline %d: colour outside 0..1e6", g);
    return 0;
}

int vt_overlay_check(const vt_frame *f, char *err, size_t errlen)
{
    const vt_overlay *o = f->overlay;
    if (!o) return 0;
    if (o->nicons && !o->icons) return vp_errf(err, errlen, VT_ERR_INVALID, "overlay: missing argument");
    if (o->nicons > VT_OVERLAY_MAX_ICONS)
        return vp_errf(err, errlen, VT_ERR_INVALID, "overlay: %u icons (at most %u)", o->nicons, VT_OVERLAY_MAX_ICONS);
    for (int g = 0; g < VT_OUTLINES; g++) {
        int rc = outline_check(f, &o->outline[g], g, err, errlen);
        if (rc) return rc;
    }
    for (uint32_t i = 0; i < o->nicons; i++) {
        const vt_icon *ic = &o->icons[i];
        for (int a = 0; a < 3; a++)
            if (!(fabs(ic->pos[a]) <= 1e15))
                return vp_errf(err, errlen, VT_ERR_INVALID, "overlay: icon %u position not finite or past 1e15", i);
        if (!color_ok(ic->color))
            return vp_errf(err, errlen, VT_ERR_INVALID, "overlay: icon %u colour outside 0..1e6", i);
    }
    return 0;
}

/* ---- the highlighted instances' coverage --------------------------------------------- */

/* A vertex in clip space with the view's near function and nearness
 * numerator: all linear in the camera-relative position, so clipping
 * interpolates them exactly. */
typedef struct cvert {
    double x, y, w, nf, d;
} cvert;

static double row(const double r[4], const double p[3])
{
    return r[0] * p[0] + r[1] * p[1] + r[2] * p[2] + r[3];
}

static cvert cvert_of(const cull_view_rows *vr, const double p[3])
{
    return (cvert){row(vr->x, p), row(vr->y, p), row(vr->w, p), row(vr->nearfn, p), row(vr->d, p)};
}

static cvert cvert_lerp(const cvert *a, const cvert *b, double t)
{
    return (cvert){a->x + (b->x - a->x) * t, a->y + (b->y - a->y) * t, a->w + (b->w - a->w) * t,
                   a->nf + (b->nf - a->nf) * t, a->d + (b->d - a->d) * t};
}

/* The pixels whose centres a screen triangle (pixels, nearness per
 * vertex, affine on screen) covers, either winding, edges included:
 * each keeps the largest nearness met (the nearest surface). Two passes
 * over the triangles: the first (measure) only finds the box they cover
 * on screen, so the buffers are the box's, not the picture's. */
typedef struct cover {
    bool measure;
    uint32_t w, h;          /* the picture */
    int x0, y0, x1, y1;     /* measure: the covered box, inclusive (x0 > x1: empty) */
    int ox, oy, bw, bh;     /* the buffers' box: origin and size */
    float *near;            /* bw x bh, -INFINITY: not covered */
} cover;

static void cover_tri(cover *c, const double sx[3], const double sy[3], const double nz[3])
{
    double area = (sx[1] - sx[0]) * (sy[2] - sy[0]) - (sx[2] - sx[0]) * (sy[1] - sy[0]);
    if (!(fabs(area) > 1e-12)) return; /* degenerate (or NaN): covers no centre */
    double lo_x = fmin(sx[0], fmin(sx[1], sx[2])), hi_x = fmax(sx[0], fmax(sx[1], sx[2]));
    double lo_y = fmin(sy[0], fmin(sy[1], sy[2])), hi_y = fmax(sy[0], fmax(sy[1], sy[2]));
    /* centres x + 0.5 in lo..hi, within the picture */
    int x0 = (int)fmax(0, ceil(lo_x - 0.5)), x1 = (int)fmin((double)c->w - 1, floor(hi_x - 0.5));
    int y0 = (int)fmax(0, ceil(lo_y - 0.5)), y1 = (int)fmin((double)c->h - 1, floor(hi_y - 0.5));
    if (x0 > x1 || y0 > y1) return;
    if (c->measure) {
        if (x0 < c->x0) c->x0 = x0;
        if (x1 > c->x1) c->x1 = x1;
        if (y0 < c->y0) c->y0 = y0;
        if (y1 > c->y1) c->y1 = y1;
        return;
    }
    /* barycentric k = ea[k] x + eb[k] y + ec[k] at a centre (x, y) */
    double ea[3], eb[3], ec[3];
    for (int k = 0; k < 3; k++) {
        int i = (k + 1) % 3, j = (k + 2) % 3;
        ea[k] = -(sy[j] - sy[i]) / area;
        eb[k] = (sx[j] - sx[i]) / area;
        ec[k] = -(ea[k] * sx[i] + eb[k] * sy[i]);
    }
    for (int y = y0; y <= y1; y++) {
        double py = y + 0.5;
        float *row = c->near + (size_t)(y - c->oy) * (size_t)c->bw - c->ox;
        for (int x = x0; x <= x1; x++) {
            double px = x + 0.5, b0 = ea[0] * px + eb[0] * py + ec[0], b1 = ea[1] * px + eb[1] * py + ec[1],
                   b2 = ea[2] * px + eb[2] * py + ec[2];
            if (b0 < 0 || b1 < 0 || b2 < 0) continue;
            float n = (float)(b0 * nz[0] + b1 * nz[1] + b2 * nz[2]);
            if (n > row[x]) row[x] = n;
        }
    }
}

/* One triangle clipped to the near plane (nf >= 0), then covered as a fan. */
static void cover_clip(cover *c, const cvert v[3])
{
    cvert poly[4];
    int n = 0;
    for (int k = 0; k < 3; k++) {
        const cvert *a = &v[k], *b = &v[(k + 1) % 3];
        if (a->nf >= 0) poly[n++] = *a;
        if ((a->nf >= 0) != (b->nf >= 0)) poly[n++] = cvert_lerp(a, b, a->nf / (a->nf - b->nf));
    }
    if (n < 3) return;
    double sx[4], sy[4], nz[4];
    for (int k = 0; k < n; k++) {
        if (!(poly[k].w > 1e-30)) return; /* on the eye plane: nothing to project */
        sx[k] = (poly[k].x / poly[k].w + 1) * 0.5 * c->w;
        sy[k] = (poly[k].y / poly[k].w + 1) * 0.5 * c->h;
        nz[k] = poly[k].d / poly[k].w;
        /* far off screen: the box clamp keeps the loops short, but keep
           the arithmetic finite */
        if (!(fabs(sx[k]) < 1e9 && fabs(sy[k]) < 1e9 && isfinite(nz[k]))) return;
    }
    for (int k = 1; k + 1 < n; k++) {
        double tx[3] = {sx[0], sx[k], sx[k + 1]}, ty[3] = {sy[0], sy[k], sy[k + 1]}, tz[3] = {nz[0], nz[k], nz[k + 1]};
        cover_tri(c, tx, ty, tz);
    }
}

static void cover_instance(cover *c, const vt_frame *f, const cull_view_rows *vr, const vt_instance *in)
{
    const vt_mesh *m = &f->meshes[in->mesh];
    float b[6];
    vt_mesh_bounds(m, b);
    vt_place pl;
    vt_instance_place(in, b, f->view->origin, &pl);
    for (uint32_t t = 0; t + 2 < m->ni; t += 3) {
        cvert v[3];
        for (int k = 0; k < 3; k++) {
            const float *q = &m->pos[3 * (size_t)m->idx[t + (uint32_t)k]];
            double p[3];
            for (int a = 0; a < 3; a++)
                p[a] = pl.m[a][0] * q[0] + pl.m[a][1] * q[1] + pl.m[a][2] * q[2] + pl.t[a];
            v[k] = cvert_of(vr, p);
        }
        cover_clip(c, v);
    }
}

/* The frame's nearness at an output depth (vt_depth_apply inverted);
   nothing drawn (+inf) is -inf: anything is in front of it. */
static float near_of_depth(vt_depth_rule rule, float dz)
{
    if (!(dz < INFINITY)) return -INFINITY;
    return !rule.ortho ? 1.0f / dz : (1.0f - dz) / rule.k;
}

/* ---- the outline ----------------------------------------------------------------------- */

/* c over px with weight a (0..1). Full weight is c itself: the picture
 * may hold an infinity (a sky texel near FLT_MAX times the sky's
 * multiplier), and inf * 0 would leave a NaN there (fuzz_render found it) */
static void blend(float *px, const float c[3], float a)
{
    for (int k = 0; k < 3; k++) px[k] = a >= 1 ? c[k] : px[k] * (1 - a) + c[k] * a;
    if (a > px[3]) px[3] = a > 1 ? 1 : a;
}

/* Sums over a sliding window of 2 hw + 1 (clipped to 0..n): out[i] = the
   sum of in[i - hw .. i + hw], each n values stride apart. */
static void window_sum(const uint16_t *in, uint16_t *out, int n, size_t stride, int hw)
{
    uint32_t s = 0;
    for (int i = 0; i < hw && i < n; i++) s += in[(size_t)i * stride];
    for (int i = 0; i < n; i++) {
        if (i + hw < n) s += in[(size_t)(i + hw) * stride];
        if (i - hw - 1 >= 0) s -= in[(size_t)(i - hw - 1) * stride];
        out[(size_t)i * stride] = (uint16_t)s;
    }
}

static int draw_outline(const vt_frame *f, const cull_view_rows *vr, const vt_outline *o, const float dflt[3],
                        char *err, size_t errlen)
{
    const uint32_t W = f->width, H = f->height;
    const int hw = (int)vt_overlay_half_width(H);
    cover c = {.measure = true, .w = W, .h = H, .x0 = (int)W, .y0 = (int)H, .x1 = -1, .y1 = -1};
    for (int pass = 0; pass < 2; pass++) {
        for (uint32_t i = 0; i < o->nhl; i++) cover_instance(&c, f, vr, &f->inst[o->hl[i]]);
        for (uint32_t i = 0; i < o->nextra; i++) cover_instance(&c, f, vr, &o->extra[i]);
        if (pass) break;
        if (c.x0 > c.x1) return 0; /* nothing of them on screen */
        /* the covered box and the band's hw around it, within the picture */
        c.ox = c.x0 - hw > 0 ? c.x0 - hw : 0;
        c.oy = c.y0 - hw > 0 ? c.y0 - hw : 0;
        c.bw = (c.x1 + hw < (int)W - 1 ? c.x1 + hw : (int)W - 1) - c.ox + 1;
        c.bh = (c.y1 + hw < (int)H - 1 ? c.y1 + hw : (int)H - 1) - c.oy + 1;
        size_t n = (size_t)c.bw * (size_t)c.bh;
        if (!(c.near = malloc(n * sizeof *c.near)))
            return vp_errf(err, errlen, VT_ERR_NOMEM, "out of memory for the outline");
        for (size_t i = 0; i < n; i++) c.near[i] = -INFINITY;
        c.measure = false;
    }
    /* per pixel of the box: covered (1 << 0) and seen (1 << 8), as counts
       a window sum adds up; then the sums over the (2 hw + 1)^2 square */
    size_t n = (size_t)c.bw * (size_t)c.bh;
    uint16_t *cov = malloc(n * sizeof *cov), *seen = malloc(n * sizeof *seen), *tmp = malloc(n * sizeof *tmp);
    if (!cov || !seen || !tmp) {
        free(cov), free(seen), free(tmp), free(c.near);
        return vp_errf(err, errlen, VT_ERR_NOMEM, "out of memory for the outline");
    }
    /* each covered pixel seen or hidden by the picture's own depth: the
       same surface differs only by the renderers' float rounding of the
       nearness (a relative 1e-4 covers it; a real occluder in front is
       nearer by far more) */
    vt_depth_rule rule = vt_depth_rule_of(f->view, vr);
    for (int y = 0; y < c.bh; y++)
        for (int x = 0; x < c.bw; x++) {
            size_t i = (size_t)y * (size_t)c.bw + (size_t)x;
            float nz = c.near[i];
            cov[i] = nz != -INFINITY;
            float fz = cov[i] ? near_of_depth(rule, f->depth[(size_t)(y + c.oy) * f->stride + (size_t)(x + c.ox)]) : 0;
            seen[i] = cov[i] && nz >= fz - 1e-4f * fabsf(fz) - 1e-6f;
        }
    /* the band: pixels within hw (square) of a pixel of the other side,
       i.e. whose window holds some covered pixels but not only those */
    uint16_t *cnt[2] = {cov, seen};
    uint8_t *in = malloc(n);
    if (!in) {
        free(cov), free(seen), free(tmp), free(c.near);
        return vp_errf(err, errlen, VT_ERR_NOMEM, "out of memory for the outline");
    }
    for (size_t i = 0; i < n; i++) in[i] = (uint8_t)cov[i];
    for (int k = 0; k < 2; k++) {
        for (int y = 0; y < c.bh; y++) window_sum(cnt[k] + (size_t)y * c.bw, tmp + (size_t)y * c.bw, c.bw, 1, hw);
        for (int x = 0; x < c.bw; x++) window_sum(tmp + x, cnt[k] + x, c.bh, (size_t)c.bw, hw);
    }
    const float *col = o->color[0] + o->color[1] + o->color[2] > 0 ? o->color : dflt;
    for (int y = 0; y < c.bh; y++) {
        int gy = y + c.oy, wy = (gy + hw < (int)H ? gy + hw : (int)H - 1) - (gy - hw > 0 ? gy - hw : 0) + 1;
        for (int x = 0; x < c.bw; x++) {
            size_t i = (size_t)y * (size_t)c.bw + (size_t)x;
            int gx = x + c.ox, wx = (gx + hw < (int)W ? gx + hw : (int)W - 1) - (gx - hw > 0 ? gx - hw : 0) + 1;
            /* the window's pixels in the picture (the box holds every
               covered one, so a window past the box's edge counts right) */
            bool edge = in[i] ? cov[i] < wx * wy : cov[i] > 0;
            if (edge) blend(&f->rgba[((size_t)gy * f->stride + (size_t)gx) * 4], col, seen[i] ? 1.0f : HIDDEN_WEIGHT);
        }
    }
    free(in), free(cov), free(seen), free(tmp), free(c.near);
    return 0;
}

/* ---- icons -------------------------------------------------------------------------------- */

/* The signed distance (pixels, < 0 inside) of a kind's shape of radius r
   at offset (dx, dy) from its centre. */
static double icon_sdf(uint32_t kind, double dx, double dy, double r)
{
    double ax = fabs(dx), ay = fabs(dy);
    if (kind == VT_ICON_PING) return (ax + ay - r) * 0.70710678118654752; /* diamond */
    if (kind == VT_ICON_SELECT) /* a hollow square: a ring r/4 thick */
        return fabs(fmax(ax, ay) - 0.8 * r) - fmax(1.0, 0.22 * r);
    return sqrt(dx * dx + dy * dy) - 0.8 * r; /* disc */
}

static void draw_icon(const vt_frame *f, const cull_view_rows *vr, const vt_icon *ic)
{
    const uint32_t W = f->width, H = f->height;
    double p[3];
    for (int a = 0; a < 3; a++) p[a] = ic->pos[a] - f->view->origin[a];
    cvert v = cvert_of(vr, p);
    if (!(v.nf >= 0) || !(v.w > 1e-30)) return; /* behind the near plane (or NaN) */
    double sx = (v.x / v.w + 1) * 0.5 * W, sy = (v.y / v.w + 1) * 0.5 * H;
    /* constant screen size: 7 px at 720 rows (at least 4), halo 2 px */
    double r = fmax(4.0, 7.0 * H / 720.0), halo = fmax(1.5, 2.0 * H / 720.0), ext = r + halo + 1;
    if (!(sx > -ext && sx < W + ext && sy > -ext && sy < H + ext)) return; /* off screen, or NaN */
    uint32_t kind = ic->kind <= VT_ICON_UNIT ? ic->kind : VT_ICON_UNIT;
    const float *col = ic->color[0] + ic->color[1] + ic->color[2] > 0 ? ic->color : icon_default[kind];
    static const float dark[3] = {0, 0, 0};
    int x0 = (int)fmax(0, floor(sx - ext)), x1 = (int)fmin(W - 1.0, ceil(sx + ext));
    int y0 = (int)fmax(0, floor(sy - ext)), y1 = (int)fmin(H - 1.0, ceil(sy + ext));
    for (int y = y0; y <= y1; y++)
        for (int x = x0; x <= x1; x++) {
            double d = icon_sdf(kind, x + 0.5 - sx, y + 0.5 - sy, r);
            /* coverage of a 1-px box filter across the edge, approximately */
            float cov = (float)fmin(1, fmax(0, 0.5 - d)), hcov = (float)fmin(1, fmax(0, 0.5 - (d - halo)));
            if (hcov <= 0) continue;
            float *px = &f->rgba[((size_t)y * f->stride + (size_t)x) * 4];
            blend(px, dark, HALO_WEIGHT * hcov);
            if (cov > 0) blend(px, col, cov);
            px[3] = 1;
        }
}

int vt_overlay_draw(const vt_frame *f, const cull_view_rows *vr, char *err, size_t errlen)
{
    const vt_overlay *o = f->overlay;
    if (!o) return 0;
    for (int g = 0; g < VT_OUTLINES; g++) {
        const vt_outline *l = &o->outline[g];
        if (!l->nhl && !l->nextra) continue;
        int rc = draw_outline(f, vr, l, outline_default[g], err, errlen);
        if (rc) return rc;
    }
    for (uint32_t i = 0; i < o->nicons; i++) draw_icon(f, vr, &o->icons[i]);
    return 0;
}
