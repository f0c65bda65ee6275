/*
 * vt_shadow.c — the sun's cascaded shadow maps (see vt_shadow.h for the
 * rules): the cascade fitting both renderers use (and the daemon's caster
 * view), the lookup (per pixel here; over a span, 4 or 8 lanes at once,
 * in vt_shadow.inl, which the shading kernel calls), and the software
 * path's depth-only rasterizer:
 *
 *   1. set-up (threads over contiguous shares of the casters): an
 *      instance's world box in light coordinates says which cascades it
 *      can reach: those whose sphere it touches and whose outline (the
 *      slice of the view the cascade's lookups come from, seen from the
 *      sun: vt_shadow_fit's hull) it meets, as u and v are what a
 *      shadow keeps along the sun's rays; a caster across an outline,
 *      its triangles' boxes each (a caster outside darkens nothing the
 *      view shows: a quarter to a half of the city's triangles); its
 *      vertices go to (u.p, v.p, s.p) once, its faces
 *      turned away from the sun (all faces of a double-sided material)
 *      to each of those cascades' lists in map coordinates;
 *   2. raster (threads over interleaved 32-row bands of every cascade,
 *      each thread clears its bands and walks every list once): per row
 *      the covered run solved from the three edge functions (double), the
 *      depth plane clamped to the triangle's depth range (no spikes from
 *      a face seen edge-on), max into the band. No depth clipping: a
 *      face farther from the sun than a receiver never darkens it, and
 *      an orthographic projection needs no division; then each band's
 *      parts of the footprint tiles (per 2 x 2 tile, the depth range of
 *      its rows over 5 columns);
 *   3. the footprint tiles (vt_shadow_tiles.c: 5 x 5 texels each, three
 *      parts joined) the span lookup decides most pixels by without its
 *      16 taps.
 * Cost: one pass over the caster vertices, a few compares per triangle
 * and cascade; the maps (4 x 1024^2 floats at 720p, 16 MB) are cleared by
 * the raster threads as they draw, only where the last frames drew. */
#include "vt_shadow.h"
#include "vt_shadow_tiles.h"

#include "vt_mask.h"
#include "vt_picture.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#ifdef __SSE2__
#include <emmintrin.h>
#endif

#define BAND VT_SHADOW_BAND
#define MAX_THREADS 32u
#define NC VT_SHADOW_CASCADES

/* ---- the fit ---------------------------------------------------------------------- */

bool vt_shadow_sun_dir(const vt_env *env, uint32_t fx_off, float s[3])
{
    if (!env || (fx_off & VT_FX_SHADOWS)) return false;
    double n2 = 0;
    for (int k = 0; k < 3; k++) n2 += (double)env->sun_dir[k] * env->sun_dir[k];
    if (!(n2 > 0) || !(env->sun[0] > 0 || env->sun[1] > 0 || env->sun[2] > 0)) return false;
    for (int k = 0; k < 3; k++) s[k] = (float)(env->sun_dir[k] / sqrt(n2));
    return s[1] >= VT_SHADOW_MIN_SUN;
}

/* Solves a p = b (3x3, rows); false when singular or not finite. */
static bool solve3(const double a[3][3], const double b[3], double p[3])
{
    double c0 = a[1][1] * a[2][2] - a[1][2] * a[2][1];
    double c1 = a[1][2] * a[2][0] - a[1][0] * a[2][2];
    double c2 = a[1][0] * a[2][1] - a[1][1] * a[2][0];
    double det = a[0][0] * c0 + a[0][1] * c1 + a[0][2] * c2;
    if (!(fabs(det) > 1e-300) || !isfinite(det)) return false;
    double id = 1 / det;
    /* Cramer: p_k = det(a with column k = b) / det */
    for (int k = 0; k < 3; k++) {
        double m[3][3];
        memcpy(m, a, sizeof m);
        for (int r = 0; r < 3; r++) m[r][k] = b[r];
        p[k] = (m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) + m[0][1] * (m[1][2] * m[2][0] - m[1][0] * m[2][2]) +
                m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])) *
               id;
    }
    return isfinite(p[0]) && isfinite(p[1]) && isfinite(p[2]);
}

/* The point where clip x = X (times d, perspective), clip y = Y (likewise)
 * and depth row = d. */
static bool corner(const cull_view_rows *vr, const double dr[4], double X, double Y, double d, double p[3])
{
    double k = vr->ortho ? 1 : d;
    double a[3][3] = {{vr->x[0], vr->x[1], vr->x[2]}, {vr->y[0], vr->y[1], vr->y[2]}, {dr[0], dr[1], dr[2]}};
    double b[3] = {X * k - vr->x[3], Y * k - vr->y[3], d - dr[3]};
    return solve3(a, b, p);
}

/* The view depth where plane row f (a clip-space function, >= 0 inside)
 * crosses the view's axis. */
static bool axis_depth(const cull_view_rows *vr, const double dr[4], const double f[4], double *d)
{
    double a[3][3] = {{vr->x[0], vr->x[1], vr->x[2]}, {vr->y[0], vr->y[1], vr->y[2]}, {f[0], f[1], f[2]}};
    double b[3] = {-vr->x[3], -vr->y[3], -f[3]}, p[3];
    if (!solve3(a, b, p)) return false;
    *d = dr[0] * p[0] + dr[1] * p[1] + dr[2] * p[2] + dr[3];
    return isfinite(*d);
}

/* The farthest view depth of instance in's box and, with a ground, of its
 * shadow on it; -inf when it cannot be placed. */
static double inst_reach(const vt_instance *in, const float b[6], const double origin[3], const double dr[4],
                         const float s[3], bool ground, double gy)
{
    vt_place pl;
    vt_instance_place(in, b, origin, &pl);
    double c[3], h[3], bc[3], bh[3];
    for (int a = 0; a < 3; a++) {
        bc[a] = 0.5 * ((double)b[a] + b[3 + a]);
        bh[a] = 0.5 * ((double)b[3 + a] - b[a]);
    }
    double top = 0;
    for (int a = 0; a < 3; a++) {
        c[a] = pl.t[a] + pl.m[a][0] * bc[0] + pl.m[a][1] * bc[1] + pl.m[a][2] * bc[2];
        h[a] = fabs(pl.m[a][0]) * bh[0] + fabs(pl.m[a][1]) * bh[1] + fabs(pl.m[a][2]) * bh[2];
    }
    double far = dr[0] * c[0] + dr[1] * c[1] + dr[2] * c[2] + dr[3];
    far += fabs(dr[0]) * h[0] + fabs(dr[1]) * h[1] + fabs(dr[2]) * h[2];
    if (ground && (top = c[1] + h[1] - gy) > 0) {
        /* the shadow of its top reaches top / s_y along -s (the sun's
           height clamped at 0.2: at most 5 heights long) */
        double k = top / (s[1] > 0.2f ? s[1] : 0.2f);
        double step = -(dr[0] * s[0] + dr[1] * s[1] + dr[2] * s[2]) * k;
        if (step > 0) far += step;
    }
    return isfinite(far) ? far : -INFINITY;
}

/* The convex outline of points p (counter-clockwise: Andrew's monotone
 * chain), widened by m, as edges (a, b, h): a x + b y <= h inside, (a, b)
 * a unit normal. *n 0: the points are (nearly) on a line, or not finite. */
static void outline(double p[8][2], double m, float e[8][3], uint32_t *n)
{
    *n = 0;
    for (int i = 1; i < 8; i++) /* sorted by x, then y (insertion: 8 points) */
        for (int j = i; j > 0 && (p[j][0] < p[j - 1][0] || (p[j][0] == p[j - 1][0] && p[j][1] < p[j - 1][1])); j--) {
            double t0 = p[j][0], t1 = p[j][1];
            p[j][0] = p[j - 1][0], p[j][1] = p[j - 1][1], p[j - 1][0] = t0, p[j - 1][1] = t1;
        }
    int h[17], k = 0;
    for (int pass = 0; pass < 2; pass++) { /* the lower chain, then the upper */
        const int k0 = k;
        for (int t = 0; t < 8; t++) {
            const int i = pass ? 7 - t : t;
            while (k >= k0 + 2) {
                const double *a = p[h[k - 2]], *b = p[h[k - 1]];
                if ((b[0] - a[0]) * (p[i][1] - a[1]) - (b[1] - a[1]) * (p[i][0] - a[0]) > 0) break;
                k--;
            }
            h[k++] = i;
        }
        k--; /* the chain's last point starts the other one */
    }
    if (k < 3) return;
    for (int j = 0; j < k; j++) {
        const double *a = p[h[j]], *b = p[h[(j + 1) % k]];
        double nx = b[1] - a[1], ny = a[0] - b[0], l = sqrt(nx * nx + ny * ny);
        if (!(l > 0) || !isfinite(l)) return (void)(*n = 0);
        nx /= l, ny /= l;
        e[*n][0] = (float)nx, e[*n][1] = (float)ny, e[*n][2] = (float)(nx * a[0] + ny * a[1] + m);
        (*n)++;
    }
}

bool vt_shadow_fit_make(const cull_view *v, uint32_t width, uint32_t height, const vt_env *env, const float s[3],
                        const float (*mb)[6], const vt_instance *inst, uint32_t ninst, vt_shadow_fit *fit)
{
    memset(fit, 0, sizeof *fit);
    cull_view_rows vr;
    cull_view_rows_get(v, &vr);
    if (!vr.usable) return false;
    /* a point's view depth: w (perspective), metres from the near plane
       (orthographic) */
    double dr[4], nearv = 0, farv = INFINITY, farfn[4];
    if (!vr.ortho) {
        memcpy(dr, vr.w, sizeof dr);
        if (!axis_depth(&vr, dr, vr.nearfn, &nearv)) return false;
    } else {
        double g = sqrt(vr.nearfn[0] * vr.nearfn[0] + vr.nearfn[1] * vr.nearfn[1] + vr.nearfn[2] * vr.nearfn[2]);
        if (!(g > 0) || !isfinite(g)) return false;
        for (int k = 0; k < 4; k++) dr[k] = vr.nearfn[k] / g;
    }
    for (int k = 0; k < 4; k++) farfn[k] = v->depth_mode == CULL_DEPTH_REVERSED ? vr.z[k] : vr.w[k] - vr.z[k];
    double fd;
    if (axis_depth(&vr, dr, farfn, &fd) && fd > nearv) farv = fd;
    /* the shadow distance: what the frame shows and its shadows on the
       ground, within the far plane and VT_SHADOW_MAX_DIST */
    double reach = ninst ? -INFINITY : VT_SHADOW_MAX_DIST;
    const bool ground = env && env->ground;
    const double gy = ground ? env->ground_height - v->origin[1] : 0;
    for (uint32_t i = 0; i < ninst; i++) {
        double r = inst_reach(&inst[i], mb[inst[i].mesh], v->origin, dr, s, ground, gy);
        if (r > reach) reach = r;
    }
    /* rounded up to 1/8 of its power of two: the cascades keep their
       size (and their texel grid) while the camera moves, until the
       distance crosses a step */
    double D = reach, dq = exp2(floor(log2(D)) - 3);
    if (isfinite(dq) && dq > 0) D = ceil(D / dq) * dq;
    D = D < farv ? D : farv;
    if (D > VT_SHADOW_MAX_DIST) D = VT_SHADOW_MAX_DIST;
    /* the split's near end at least 1 m (and 1/500 of the distance): a
       0.1 m near plane would spend the first cascade on the first metre */
    double n0 = nearv > 1.0 ? nearv : 1.0;
    n0 = n0 > D * 2e-3 ? n0 : D * 2e-3;
    if (!(D > n0) || !isfinite(D)) return false;
    /* an orthographic view has no perspective aliasing to split against:
       one cascade over its whole depth (4 would each cover the whole
       picture's width, every caster drawn 4 times) */
    const int N = vr.ortho ? 1 : NC;
    fit->n = (uint32_t)N;
    /* the map: about 0.8 of the picture's larger side, in 64s (1024 at
       1280x720), 64..2048 */
    uint32_t big = width > height ? width : height, sz = (uint32_t)(big * 0.8 + 63) / 64 * 64;
    fit->size = sz < 64 ? 64 : sz > 2048 ? 2048 : sz;
    /* the light basis: s, and u, v perpendicular (from the sun alone, so
       the grid does not turn with the camera) */
    double sd[3] = {s[0], s[1], s[2]}, ref[3] = {0, 0, 1}, u[3], w[3];
    if (fabs(sd[2]) > 0.9) ref[0] = 1, ref[2] = 0;
    u[0] = ref[1] * sd[2] - ref[2] * sd[1];
    u[1] = ref[2] * sd[0] - ref[0] * sd[2];
    u[2] = ref[0] * sd[1] - ref[1] * sd[0];
    double ul = sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
    for (int k = 0; k < 3; k++) u[k] /= ul;
    w[0] = sd[1] * u[2] - sd[2] * u[1]; /* v = s x u: (u, v, s) right-handed */
    w[1] = sd[2] * u[0] - sd[0] * u[2];
    w[2] = sd[0] * u[1] - sd[1] * u[0];
    for (int k = 0; k < 3; k++) {
        fit->s[k] = s[k];
        fit->u[k] = (float)u[k];
        fit->v[k] = (float)w[k];
    }
    for (int k = 0; k < 4; k++) fit->drow[k] = (float)dr[k];
    /* the practical split: lambda x logarithmic + (1 - lambda) x uniform
       (orthographic views: uniform, depth is not perspective there) */
    double lambda = vr.ortho ? 0 : VT_SHADOW_LAMBDA;
    for (int i = 0; i <= N; i++) {
        double t = (double)i / N;
        double lg = vr.ortho ? 0 : n0 * pow(D / n0, t), un = n0 + (D - n0) * t;
        fit->split[i] = (float)(lambda * lg + (1 - lambda) * un);
    }
    fit->split[0] = (float)nearv;
    fit->split[N] = (float)D;
    double uo = u[0] * v->origin[0] + u[1] * v->origin[1] + u[2] * v->origin[2];
    double vo = w[0] * v->origin[0] + w[1] * v->origin[1] + w[2] * v->origin[2];
    for (int i = 0; i < N; i++) {
        double a = i ? fit->split[i] : vr.ortho ? nearv : n0, b = fit->split[i + 1], pc[8][3], c[3] = {0, 0, 0}, r2 = 0;
        for (int k = 0; k < 8; k++) {
            if (!corner(&vr, dr, k & 1 ? 1 : -1, k & 2 ? 1 : -1, k & 4 ? b : a, pc[k])) return false;
            for (int q = 0; q < 3; q++) c[q] += pc[k][q] / 8;
        }
        for (int k = 0; k < 8; k++) {
            double d2 = 0;
            for (int q = 0; q < 3; q++) d2 += (pc[k][q] - c[q]) * (pc[k][q] - c[q]);
            r2 = d2 > r2 ? d2 : r2;
        }
        /* the radius rounded up to 1/64 of its power of two: the same
           sphere whatever the camera's rotation (the corners' rounding
           differs in the last bits) */
        double r = sqrt(r2), q = exp2(floor(log2(r)) - 6);
        r = ceil(r / q) * q;
        if (!(r > 0) || !isfinite(r)) return false;
        double tx = 2 * r / fit->size;
        /* the centre in world-space light coordinates, moved to whole
           texels: the grid is k texel along u and v, wherever the camera */
        double cu = uo + u[0] * c[0] + u[1] * c[1] + u[2] * c[2];
        double cv = vo + w[0] * c[0] + w[1] * c[1] + w[2] * c[2];
        double su = floor(cu / tx) * tx, sv = floor(cv / tx) * tx;
        fit->texel[i] = (float)tx;
        fit->scale[i] = (float)(1 / tx);
        fit->off[i][0] = (float)((uo - su) / tx + fit->size / 2);
        fit->off[i][1] = (float)((vo - sv) / tx + fit->size / 2);
        for (int q2 = 0; q2 < 3; q2++) fit->cen[i][q2] = (float)c[q2];
        fit->rad[i] = (float)r;
        /* what its lookups read: the slice from the previous cascade's
           blend band on, seen from the sun */
        double a2 = i ? fit->split[i] - VT_SHADOW_BLEND * (fit->split[i] - fit->split[i - 1]) : nearv, hp[8][2];
        bool ok = true;
        for (int k = 0; k < 8 && ok; k++) {
            double pk[3];
            ok = corner(&vr, dr, k & 1 ? 1 : -1, k & 2 ? 1 : -1, k & 4 ? b : a2, pk);
            hp[k][0] = u[0] * pk[0] + u[1] * pk[1] + u[2] * pk[2];
            hp[k][1] = w[0] * pk[0] + w[1] * pk[1] + w[2] * pk[2];
        }
        if (ok) outline(hp, VT_SHADOW_REACH * tx + 1e-4 * r, fit->hull[i], &fit->nhull[i]);
    }
    return true;
}

bool vt_shadow_fit_frame(const vt_frame *f, vt_shadow_fit *fit)
{
    float sd[3];
    if (!vt_shadow_sun_dir(f->env, f->fx_off, sd)) return false;
    float(*mb)[6] = malloc(((size_t)f->nmesh + 1) * sizeof *mb);
    if (!mb) return false;
    for (uint32_t i = 0; i < f->nmesh; i++) vt_mesh_bounds(&f->meshes[i], mb[i]);
    bool ok = vt_shadow_fit_make(f->view, f->width, f->height, f->env, sd, (const float(*)[6])mb, f->inst, f->ninst, fit);
    free(mb);
    return ok;
}

bool vt_shadow_caster_view(const vt_shadow_fit *fit, const double origin[3], double reach, cull_view *out)
{
    if (!fit || !fit->n || !out) return false;
    double lo[3] = {DBL_MAX, DBL_MAX, DBL_MAX}, hi[3] = {-DBL_MAX, -DBL_MAX, -DBL_MAX};
    const float *ax[3] = {fit->u, fit->v, fit->s};
    for (uint32_t i = 0; i < fit->n; i++)
        for (int a = 0; a < 3; a++) {
            double c = (double)ax[a][0] * fit->cen[i][0] + (double)ax[a][1] * fit->cen[i][1] +
                       (double)ax[a][2] * fit->cen[i][2];
            double r = fit->rad[i] + 2.0 * fit->texel[i];
            lo[a] = c - r < lo[a] ? c - r : lo[a];
            hi[a] = c + r > hi[a] ? c + r : hi[a];
        }
    hi[2] += reach > 0 ? reach : 0;
    /* x = (u.p - cu) / hu, y likewise, z (GL) -1 at the sun's side, w 1 */
    double m[16] = {0};
    for (int a = 0; a < 2; a++) {
        double c = 0.5 * (lo[a] + hi[a]), h = 0.5 * (hi[a] - lo[a]);
        for (int k = 0; k < 3; k++) m[k * 4 + a] = ax[a][k] / h;
        m[12 + a] = -c / h;
    }
    double dz = hi[2] - lo[2];
    for (int k = 0; k < 3; k++) m[k * 4 + 2] = -2 * fit->s[k] / dz;
    m[14] = 2 * hi[2] / dz - 1;
    m[15] = 1;
    cull_view_desc d = {.origin = {origin[0], origin[1], origin[2]}, .depth_mode = CULL_DEPTH_GL,
                        .viewport_w = 64, .viewport_h = 64};
    memcpy(d.view_proj, m, sizeof m);
    return cull_view_init(out, &d) == CULL_OK;
}

/* ---- the lookup -------------------------------------------------------------------- */

/* Cascade i's PCF at camera-relative p (normal n, n.s = ndl > 0). */
static float cascade_vis(const vt_shadow_fit *f, const float *maps, int i, const float p[3], const float n[3],
                         float ndl)
{
    const float tx = f->texel[i];
    float sn = sqrtf(fmaxf(1.0f - ndl * ndl, 0.0f)), tn = fminf(sn / ndl, 8.0f);
    float o = VT_SHADOW_NOFS * tx * sn;
    float q[3] = {p[0] + n[0] * o, p[1] + n[1] * o, p[2] + n[2] * o};
    float dref = f->s[0] * q[0] + f->s[1] * q[1] + f->s[2] * q[2] + tx * (VT_SHADOW_BIAS_C + VT_SHADOW_BIAS_S * tn);
    float mx = (f->u[0] * q[0] + f->u[1] * q[1] + f->u[2] * q[2]) * f->scale[i] + f->off[i][0];
    float my = (f->v[0] * q[0] + f->v[1] * q[1] + f->v[2] * q[2]) * f->scale[i] + f->off[i][1];
    const float sz = (float)f->size;
    if (!(mx > -2.0f && mx < sz + 2.0f && my > -2.0f && my < sz + 2.0f)) return 1.0f;
    float X = mx - 0.5f, Y = my - 0.5f, fx0 = floorf(X), fy0 = floorf(Y), fx = X - fx0, fy = Y - fy0;
    int x0 = (int)fx0 - 1, y0 = (int)fy0 - 1, S = (int)f->size;
    const float wx[4] = {1.0f - fx, 1.0f, 1.0f, fx}, wy[4] = {1.0f - fy, 1.0f, 1.0f, fy};
    const float *m = maps + (size_t)i * f->size * f->size;
    float lit = 0;
    for (int b = 0; b < 4; b++) {
        int y = y0 + b;
        if (y < 0 || y >= S) {
            lit += wy[b] * 3.0f;
            continue;
        }
        const float *row = m + (size_t)y * f->size;
        float r = 0;
        for (int a = 0; a < 4; a++) {
            int x = x0 + a;
            r += (x < 0 || x >= S || row[x] <= dref) ? wx[a] : 0.0f;
        }
        lit += wy[b] * r;
    }
    return lit * (1.0f / 9.0f);
}

float vt_shadow_lookup(const vt_shadow_fit *f, const float *maps, const float p[3], const float n[3])
{
    float ndl = f->s[0] * n[0] + f->s[1] * n[1] + f->s[2] * n[2];
    if (!(ndl > 0)) return 1.0f;
    float d = f->drow[0] * p[0] + f->drow[1] * p[1] + f->drow[2] * p[2] + f->drow[3];
    int N = (int)f->n;
    if (!(d < f->split[N])) return 1.0f;
    int i = 0;
    while (i + 1 < N && d >= f->split[i + 1]) i++;
    float vis = cascade_vis(f, maps, i, p, n, ndl);
    /* the band at the cascade's far end blends into the next one (the
       last one fades to lit) */
    float band = VT_SHADOW_BLEND * (f->split[i + 1] - f->split[i]);
    float t = (d - (f->split[i + 1] - band)) / band;
    if (t > 0) {
        float v2 = i + 1 < N ? cascade_vis(f, maps, i + 1, p, n, ndl) : 1.0f;
        vis += (v2 - vis) * fminf(t, 1.0f);
    }
    return vis;
}

/* ---- the maps ------------------------------------------------------------------------ */

/* A triangle in one cascade's map coordinates (texels, y along v) and
 * its depth s.p at the corners. */
typedef struct ltri {
    float x[3], y[3], z[3];
    const vt_mask *mk;      /* a damaged caster's destruction mask (its holes let the sun through), or NULL */
} ltri;

typedef struct sbuf {
    ltri *t[NC];
    size_t n[NC], cap[NC];
    float *vx;              /* one instance's vertices: u.p, v.p, s.p */
    size_t vx_cap;
    int rc;
} sbuf;

/* Bands a map may hold (2048 / BAND). */
#define MAX_BANDS (2048u / BAND)

struct vt_shadow {
    vt_shadow_fit fit;
    float *maps;
    size_t maps_cap;
    /* per cascade and band: the columns dlo..dhi may have been written
       since its last clear (dlo > dhi: none; the rest still holds
       -FLT_MAX): the raster clears only those, not the whole 16 MB a
       frame; the maps' size and count they were kept for (a new layout:
       all dirty) */
    uint16_t dlo[NC][MAX_BANDS], dhi[NC][MAX_BANDS];
    uint32_t dirty_size, dirty_n;
    /* the footprint tiles the span lookup decides most pixels by
       (vt_shadow_tiles.h): per cascade (size / VT_SHADOW_TILE)^2 packed
       ranges; raw: their parts, P (a tile's two rows) then O (its
       second row), packed alike */
    uint32_t *tiles;
    uint32_t *raw;
    size_t tiles_cap, raw_cap;
    vt_shadow_cons cons;    /* the span lookup's constants of the last draw */
    vt_shadow_n_fn lookup_n; /* the span lookup's instance; NULL: one lane */
    sbuf tb[MAX_THREADS];
    vt_mask *mk;            /* this frame's damaged casters' masks */
    size_t mk_cap;
    uint32_t *mk_of;        /* per caster: its mask + 1, 0 intact */
    size_t mk_of_cap;
};

/* The span lookup one pixel at a time (any CPU; the lane instances' reference). */
static void lookup_n_scalar(const vt_shadow_fit *f, const float *maps, const vt_shadow_cons *k, unsigned n,
                            const float *px, const float *py, const float *pz, const float *nx, const float *ny,
                            const float *nz, float *out)
{
    (void)k;
    for (unsigned i = 0; i < n; i++) {
        const float p[3] = {px[i], py[i], pz[i]}, nn[3] = {nx[i], ny[i], nz[i]};
        out[i] *= vt_shadow_lookup(f, maps, p, nn);
    }
}

void vt_shadow_set_isa(vt_shadow *sh, uint32_t isa)
{
    switch (isa < CULL_ISA_COUNT && cull_isa_supported(isa) ? isa : cull_isa_default()) {
#ifndef CULL_SCALAR_ONLY
    case CULL_ISA_AVX2: sh->lookup_n = vt_shadow_lookup_n_avx2; break;
    case CULL_ISA_SSE41: sh->lookup_n = vt_shadow_lookup_n_sse41; break;
#endif
    default: sh->lookup_n = lookup_n_scalar; break;
    }
}

void vt_shadow_sun_n(const vt_shadow *sh, unsigned n, const float *px, const float *py, const float *pz,
                     const float *nx, const float *ny, const float *nz, float *out)
{
    if (sh && sh->fit.n) sh->lookup_n(&sh->fit, sh->maps, &sh->cons, n, px, py, pz, nx, ny, nz, out);
}

int vt_shadow_create(vt_shadow **out)
{
    if (!out) return VT_ERR_INVALID;
    *out = calloc(1, sizeof **out);
    if (!*out) return VT_ERR_NOMEM;
    vt_shadow_set_isa(*out, CULL_ISA_COUNT);
    return 0;
}

void vt_shadow_destroy(vt_shadow *sh)
{
    if (!sh) return;
    for (uint32_t t = 0; t < MAX_THREADS; t++) {
        for (int c = 0; c < NC; c++) free(sh->tb[t].t[c]);
        free(sh->tb[t].vx);
    }
    free(sh->maps);
    free(sh->tiles);
    free(sh->raw);
    free(sh->mk);
    free(sh->mk_of);
    free(sh);
}

const vt_shadow_fit *vt_shadow_fit_of(const vt_shadow *sh)
{
    return &sh->fit;
}

const float *vt_shadow_maps(const vt_shadow *sh)
{
    return sh->maps;
}

const uint32_t *vt_shadow_tiles(const vt_shadow *sh, float qlo[VT_SHADOW_CASCADES], float qinv[VT_SHADOW_CASCADES])
{
    memcpy(qlo, sh->cons.qlo, sizeof sh->cons.qlo);
    memcpy(qinv, sh->cons.qinv, sizeof sh->cons.qinv);
    return sh->tiles;
}

float vt_shadow_sun(const vt_shadow *sh, const float p[3], const float n[3])
{
    return sh ? vt_shadow_lookup(&sh->fit, sh->maps, p, n) : 1.0f;
}

typedef struct sjob {
    vt_shadow *sh;
    const double *origin;
    const vt_mesh *meshes;
    const float (*mb)[6];
    const vt_instance *in;
    uint32_t nin, nt;
    bool masked;            /* some casters are damaged (sh->mk_of holds them) */
} sjob;

/* Whether [a, b] (within the map's -1 .. size + 1 after clamping) holds
 * no texel centre j + 0.5: ceil(a - 0.5) > floor(b - 0.5), by truncation
 * of the clamped values (SSE2 has no rounding instruction). */
static inline bool no_centre(float a, float b, float sz)
{
    a = a > -1.0f ? (a < sz + 1.0f ? a : sz + 1.0f) : -1.0f;
    b = b > -1.0f ? (b < sz + 1.0f ? b : sz + 1.0f) : -1.0f;
    /* ceil(a - 0.5) = ceil(a + 1.5) - 2, floor likewise: a + 1.5 > 0, where
       truncation is floor */
    float fa = a + 1.5f, fb = b + 1.5f;
    int ca = (int)fa, cb = (int)fb;
    ca += (float)ca < fa;
    return ca > cb;
}

/* Set-up of casters [i0, i1) into b's lists. */
static int setup(sbuf *b, const sjob *jb, uint32_t i0, uint32_t i1)
{
    const vt_shadow_fit *f = &jb->sh->fit;
    for (int c = 0; c < NC; c++) b->n[c] = 0;
    double cu[NC], cv[NC], cs[NC];
    for (int c = 0; c < (int)f->n; c++) {
        cu[c] = (double)f->u[0] * f->cen[c][0] + (double)f->u[1] * f->cen[c][1] + (double)f->u[2] * f->cen[c][2];
        cv[c] = (double)f->v[0] * f->cen[c][0] + (double)f->v[1] * f->cen[c][1] + (double)f->v[2] * f->cen[c][2];
        cs[c] = (double)f->s[0] * f->cen[c][0] + (double)f->s[1] * f->cen[c][1] + (double)f->s[2] * f->cen[c][2];
    }
    /* the outlines in map coordinates (x = u.p scale + off[0], y likewise):
       a x + b y <= h inside, for the triangles of a caster that straddles one */
    float me[NC][8][3];
    for (int c = 0; c < (int)f->n; c++)
        for (uint32_t j = 0; j < f->nhull[c]; j++) {
            const float *e = f->hull[c][j];
            me[c][j][0] = e[0], me[c][j][1] = e[1];
            me[c][j][2] = e[2] * f->scale[c] + e[0] * f->off[c][0] + e[1] * f->off[c][1];
        }
    for (uint32_t ii = i0; ii < i1; ii++) {
        const vt_instance *in = &jb->in[ii];
        const vt_mesh *m = &jb->meshes[in->mesh];
        const vt_material *mat = in->mat;
        if (!m->nv || m->ni < 3) continue;
        if (mat && mat->alpha_mode == VT_ALPHA_MASK && !mat->tex[VT_SLOT_BASE].tex && mat->base[3] < mat->alpha_cutoff)
            continue;
        const float *bb = jb->mb[in->mesh];
        vt_place pl;
        vt_instance_place(in, bb, jb->origin, &pl);
        /* its world box in light coordinates: which cascades it reaches */
        double c[3], h[3], lc[3] = {0, 0, 0}, lh[3] = {0, 0, 0};
        const float *ax[3] = {f->u, f->v, f->s};
        for (int a = 0; a < 3; a++) {
            c[a] = pl.t[a];
            h[a] = 0;
            for (int k = 0; k < 3; k++) {
                double bc = 0.5 * ((double)bb[k] + bb[3 + k]), bh = 0.5 * ((double)bb[3 + k] - bb[k]);
                c[a] += pl.m[a][k] * bc;
                h[a] += fabs(pl.m[a][k]) * bh;
            }
        }
        for (int a = 0; a < 3; a++)
            for (int k = 0; k < 3; k++) {
                lc[a] += ax[a][k] * c[k];
                lh[a] += fabs(ax[a][k]) * h[k];
            }
        unsigned cm = 0, straddle = 0;
        for (int k = 0; k < (int)f->n; k++) {
            double r = f->rad[k] + 2.0 * f->texel[k];
            if (!(fabs(lc[0] - cu[k]) <= lh[0] + r && fabs(lc[1] - cv[k]) <= lh[1] + r && lc[2] + lh[2] >= cs[k] - r))
                continue;
            /* and its box, seen from the sun, meets the outline of what the
               cascade's lookups read (the sun's rays keep u and v) */
            bool meets = true, inside = true;
            for (uint32_t j = 0; j < f->nhull[k] && meets; j++) {
                const float *e = f->hull[k][j];
                double pc = e[0] * lc[0] + e[1] * lc[1], pr = fabs(e[0]) * lh[0] + fabs(e[1]) * lh[1];
                meets = pc - pr <= e[2];
                inside = inside && pc + pr <= e[2];
            }
            cm |= (unsigned)meets << k;
            straddle |= (unsigned)(meets && !inside) << k;
        }
        if (!cm) continue;
        if (!vp_grow((void **)&b->vx, &b->vx_cap, (size_t)m->nv * 3, sizeof *b->vx)) return VT_ERR_NOMEM;
        /* the placement and the light axes in one matrix (light = A mp + a):
           half the operations a vertex of applying them in turn */
        double A[3][3], a0[3];
        for (int a = 0; a < 3; a++) {
            a0[a] = ax[a][0] * pl.t[0] + ax[a][1] * pl.t[1] + ax[a][2] * pl.t[2];
            for (int q = 0; q < 3; q++) A[a][q] = ax[a][0] * pl.m[0][q] + ax[a][1] * pl.m[1][q] + ax[a][2] * pl.m[2][q];
        }
        for (uint32_t k = 0; k < m->nv; k++) {
            const double p[3] = {m->pos[3 * k], m->pos[3 * k + 1], m->pos[3 * k + 2]};
            for (int a = 0; a < 3; a++) b->vx[3 * k + a] = (float)(A[a][0] * p[0] + A[a][1] * p[1] + A[a][2] * p[2] + a0[a]);
        }
        /* a damaged caster casts both faces, each where its mask keeps
           it: through a hole the sun reaches the inside and what is
           behind (the renderers draw it two-sided too) */
        const vt_mask *mk = jb->masked && jb->sh->mk_of[ii] ? &jb->sh->mk[jb->sh->mk_of[ii] - 1] : NULL;
        const bool two = (mat && mat->double_sided) || mk;
        for (uint32_t t = 0; t < m->ni / 3; t++) {
            const float *q0 = b->vx + 3 * m->idx[3 * t], *q1 = b->vx + 3 * m->idx[3 * t + 1],
                        *q2 = b->vx + 3 * m->idx[3 * t + 2];
            /* seen from the sun (u, v right-handed about s): a face
               turned towards it is counter-clockwise (a mirroring
               placement turns that over) */
            float area = (q1[0] - q0[0]) * (q2[1] - q0[1]) - (q1[1] - q0[1]) * (q2[0] - q0[0]);
            if (pl.mirror) area = -area;
            if (!(area < 0) && !(two && area > 0)) continue;
            for (int k = 0; k < (int)f->n; k++) {
                if (!(cm >> k & 1)) continue;
                ltri L;
                L.mk = mk;
                const float *qs[3] = {q0, q1, q2};
                float x0 = FLT_MAX, x1 = -FLT_MAX, y0 = FLT_MAX, y1 = -FLT_MAX;
                for (int e = 0; e < 3; e++) {
                    L.x[e] = qs[e][0] * f->scale[k] + f->off[k][0];
                    L.y[e] = qs[e][1] * f->scale[k] + f->off[k][1];
                    L.z[e] = qs[e][2];
                    x0 = min2(x0, L.x[e]), x1 = max2(x1, L.x[e]);
                    y0 = min2(y0, L.y[e]), y1 = max2(y1, L.y[e]);
                }
                if (!(x1 > 0 && y1 > 0 && x0 < (float)f->size && y0 < (float)f->size)) continue;
                /* no texel centre in its box: it covers none (most of a far
                   cascade's small casters' triangles) */
                if (no_centre(x0, x1, (float)f->size) || no_centre(y0, y1, (float)f->size)) continue;
                /* a caster across the outline: its triangles' boxes against it */
                bool meets = true;
                if (straddle >> k & 1) {
                    const float xc = 0.5f * (x0 + x1), yc = 0.5f * (y0 + y1), hx = 0.5f * (x1 - x0), hy = 0.5f * (y1 - y0);
                    for (uint32_t j = 0; j < f->nhull[k] && meets; j++)
                        meets = me[k][j][0] * xc + me[k][j][1] * yc - (fabsf(me[k][j][0]) * hx + fabsf(me[k][j][1]) * hy) <=
                                me[k][j][2];
                }
                if (!meets) continue;
                if (b->n[k] == b->cap[k] && !vp_grow((void **)&b->t[k], &b->cap[k], b->n[k] + 1, sizeof *b->t[k]))
                    return VT_ERR_NOMEM;
                b->t[k][b->n[k]++] = L;
            }
        }
    }
    return 0;
}

static void job_setup(void *arg, uint32_t t)
{
    sjob *jb = arg;
    uint32_t i0 = (uint32_t)((uint64_t)jb->nin * t / jb->nt), i1 = (uint32_t)((uint64_t)jb->nin * (t + 1) / jb->nt);
    jb->sh->tb[t].rc = setup(&jb->sh->tb[t], jb, i0, i1);
}

/* A damaged caster's texels: its mask and the map's light axes (map x
 * = u.p scale + off[0], y likewise; depth s.p; p camera-relative). */
typedef struct rmask {
    const vt_mask *mk;
    const float *u, *v, *s;
    float scale, off[2];
} rmask;

/* Whether the mask keeps the caster's texel centre (cx, cy) at depth zz. */
static bool rmask_keeps(const rmask *r, float cx, float cy, float zz)
{
    float a = (cx - r->off[0]) / r->scale, b = (cy - r->off[1]) / r->scale;
    float p[3];
    for (int k = 0; k < 3; k++) p[k] = a * r->u[k] + b * r->v[k] + zz * r->s[k];
    return vt_mask_eval(r->mk, p[0], p[1], p[2]) >= 0;
}

/* fmin and fmax for finite operands (x86-64's are library calls) */
static inline double dmin(double a, double b)
{
    return a < b ? a : b;
}

static inline double dmax(double a, double b)
{
    return a > b ? a : b;
}

/* Triangle (x, y, z: n corners after clipping, a fan) into map m (size
 * sz), max depth, in the bands of BAND rows starting at rows r0, r0 +
 * step, .. up to row r1 (a thread's: the set-up once for all of them);
 * rm non-NULL: only the texels its mask keeps. */
static void raster_poly(float *m, uint32_t sz, const double *x, const double *y, const double *z, int n, int r0, int r1,
                        int step, const rmask *rm)
{
    for (int f = 1; f + 1 < n; f++) {
        int id[3] = {0, f, f + 1};
        double X[3], Y[3], Z[3];
        for (int k = 0; k < 3; k++) X[k] = x[id[k]], Y[k] = y[id[k]], Z[k] = z[id[k]];
        double area = (X[1] - X[0]) * (Y[2] - Y[0]) - (Y[1] - Y[0]) * (X[2] - X[0]);
        if (!(area != 0) || !isfinite(area)) continue;
        if (area < 0) { /* counter-clockwise, so every edge function is >= 0 inside */
            double t;
            t = X[1], X[1] = X[2], X[2] = t;
            t = Y[1], Y[1] = Y[2], Y[2] = t;
            t = Z[1], Z[1] = Z[2], Z[2] = t;
            area = -area;
        }
        /* rows and columns whose centre (j + 0.5) can be inside: most
           far-cascade triangles cover no texel centre and stop here,
           before the divisions below */
        double ylo = dmin(Y[0], dmin(Y[1], Y[2])), yhi = dmax(Y[0], dmax(Y[1], Y[2]));
        double xlo = dmin(X[0], dmin(X[1], X[2])), xhi = dmax(X[0], dmax(X[1], X[2]));
        double jl = ceil(ylo - 0.5), jh = floor(yhi - 0.5);
        int j0 = jl > r0 ? (int)jl : r0, j1 = jh < r1 ? (int)jh : r1;
        double il = ceil(xlo - 0.5), ih = floor(xhi - 0.5);
        int bx0 = il > 0 ? (int)il : 0, bx1 = ih < sz - 1.0 ? (int)ih : (int)sz - 1;
        if (bx0 > bx1 || j0 > j1) continue;
        /* the depth plane z = za x + zb y + zc, clamped to the corners' range */
        double za = ((Z[1] - Z[0]) * (Y[2] - Y[0]) - (Y[1] - Y[0]) * (Z[2] - Z[0])) / area;
        double zb = ((X[1] - X[0]) * (Z[2] - Z[0]) - (Z[1] - Z[0]) * (X[2] - X[0])) / area;
        double zc = Z[0] - za * X[0] - zb * Y[0];
        float zlo = (float)dmin(Z[0], dmin(Z[1], Z[2])), zhi = (float)dmax(Z[0], dmax(Z[1], Z[2]));
        /* each edge's crossing of a row as x = m yc + c (E(x, yc) >= 0 is
           x >= it where the edge rises to the left, <= where it falls):
           once per triangle, so a row costs three multiply-adds */
        double em[3], ec[3];
        int kind[3];
        for (int k = 0; k < 3; k++) {
            int a = k, b = (k + 1) % 3;
            /* E(x) = (xb - xa)(yc - ya) - (yb - ya)(x - xa) = A x + Bs yc + B0 */
            double A = -(Y[b] - Y[a]), Bs = X[b] - X[a], B0 = -(X[b] - X[a]) * Y[a] + (Y[b] - Y[a]) * X[a];
            kind[k] = A > 0 ? 1 : A < 0 ? -1 : 0;
            em[k] = A != 0 ? -Bs / A : Bs;
            ec[k] = A != 0 ? -B0 / A : B0;
        }
        /* a crossing clamped to the box's columns widened by one: ceil and
           floor by truncation (SSE2 has no rounding instruction; x86-64's
           inline ceil is a dozen instructions); a horizontal edge that
           excludes the row empties it (E = Bs yc + B0 < 0) */
        const double cl = bx0 - 1.0, ch = bx1 + 1.0;
        for (int b0 = r0; b0 <= j1; b0 += step) { /* the bands' rows */
            const int ja = j0 > b0 ? j0 : b0, jb = b0 + (int)BAND - 1 < j1 ? b0 + (int)BAND - 1 : j1;
            for (int j = ja; j <= jb; j++) {
                double yc = j + 0.5;
                int lo = bx0, hi = bx1;
                for (int k = 0; k < 3; k++) {
                    double xm = em[k] * yc + ec[k] - 0.5;
                    if (!kind[k]) {
                        if (xm + 0.5 < 0) hi = -1;
                        continue;
                    }
                    xm = xm > cl ? (xm < ch ? xm : ch) : cl;
                    int ti = (int)xm;
                    if (kind[k] > 0) {
                        int c = ti + ((double)ti < xm);
                        lo = c > lo ? c : lo;
                    } else {
                        int fl = ti - (xm < (double)ti);
                        hi = fl < hi ? fl : hi;
                    }
                }
                if (lo > hi) continue;
                float *row = m + (size_t)j * sz;
                float zr = (float)(zb * yc + zc), fa = (float)za;
                int i = lo, i1 = hi;
                if (rm) {
                    for (; i <= i1; i++) {
                        float zz = fminf(fmaxf(fa * ((float)i + 0.5f) + zr, zlo), zhi);
                        if (zz > row[i] && rmask_keeps(rm, (float)i + 0.5f, (float)yc, zz)) row[i] = zz;
                    }
                    continue;
                }
    #ifdef __SSE2__
                /* four texels a step (x86-64's baseline): the same operations,
                   the centres counted up (exact: halves below 2^23) */
                const __m128 va = _mm_set1_ps(fa), vr = _mm_set1_ps(zr), vlo = _mm_set1_ps(zlo), vhi = _mm_set1_ps(zhi);
                const __m128 four = _mm_set1_ps(4.0f);
                __m128 cx = _mm_add_ps(_mm_set1_ps((float)i + 0.5f), _mm_set_ps(3, 2, 1, 0));
                for (; i + 7 <= i1; i += 8) {
                    __m128 cx2 = _mm_add_ps(cx, four);
                    __m128 z0 = _mm_min_ps(_mm_max_ps(_mm_add_ps(_mm_mul_ps(va, cx), vr), vlo), vhi);
                    __m128 z1 = _mm_min_ps(_mm_max_ps(_mm_add_ps(_mm_mul_ps(va, cx2), vr), vlo), vhi);
                    _mm_storeu_ps(row + i, _mm_max_ps(z0, _mm_loadu_ps(row + i)));
                    _mm_storeu_ps(row + i + 4, _mm_max_ps(z1, _mm_loadu_ps(row + i + 4)));
                    cx = _mm_add_ps(cx2, four);
                }
                for (; i + 3 <= i1; i += 4) {
                    __m128 zz = _mm_min_ps(_mm_max_ps(_mm_add_ps(_mm_mul_ps(va, cx), vr), vlo), vhi);
                    _mm_storeu_ps(row + i, _mm_max_ps(zz, _mm_loadu_ps(row + i)));
                    cx = _mm_add_ps(cx, four);
                }
    #endif
                for (; i <= i1; i++) {
                    float zz = fa * ((float)i + 0.5f) + zr;
                    zz = zz > zlo ? zz : zlo; /* fmaxf, fminf without the calls (NaN: zlo) */
                    zz = zz < zhi ? zz : zhi;
                    row[i] = zz > row[i] ? zz : row[i];
                }
            }
        }
    }
}

/* 2D Sutherland-Hodgman of a triangle far outside the map against
 * [-1, size + 1]^2 (with depth): the fixed-size coordinates the raster's
 * integer conversions need. Returns the vertex count. */
static int clip_rect(const ltri *t, double sz, double x[9], double y[9], double z[9])
{
    double ax[9], ay[9], az[9];
    int n = 3;
    for (int k = 0; k < 3; k++) x[k] = t->x[k], y[k] = t->y[k], z[k] = t->z[k];
    for (int p = 0; p < 4 && n; p++) {
        int m = 0;
        for (int i = 0; i < n && m < 9; i++) {
            int j = (i + 1) % n;
            double vi = p == 0 ? x[i] + 1 : p == 1 ? sz + 1 - x[i] : p == 2 ? y[i] + 1 : sz + 1 - y[i];
            double vj = p == 0 ? x[j] + 1 : p == 1 ? sz + 1 - x[j] : p == 2 ? y[j] + 1 : sz + 1 - y[j];
            if (vi >= 0) ax[m] = x[i], ay[m] = y[i], az[m] = z[i], m++;
            if ((vi >= 0) != (vj >= 0) && m < 9) {
                double s = vi / (vi - vj);
                ax[m] = x[i] + s * (x[j] - x[i]);
                ay[m] = y[i] + s * (y[j] - y[i]);
                az[m] = z[i] + s * (z[j] - z[i]);
                m++;
            }
        }
        n = m;
        memcpy(x, ax, sizeof ax);
        memcpy(y, ay, sizeof ay);
        memcpy(z, az, sizeof az);
    }
    return n;
}

/* ---- the footprint tiles (vt_shadow_tiles.c) --------------------------------------- */

/* Thread t: tile rows ty % nt == t of every cascade, over the columns the
 * raster wrote in the rows' bands (elsewhere every part is empty, and so
 * the tile). */
static void job_tiles(void *arg, uint32_t t)
{
    sjob *jb = arg;
    vt_shadow *sh = jb->sh;
    const uint32_t sz = sh->fit.size, g = sz / VT_SHADOW_TILE;
    const size_t plane = (size_t)sh->fit.n * g * g;
    for (uint32_t c = 0; c < sh->fit.n; c++)
        for (uint32_t ty = t; ty < g; ty += jb->nt) {
            /* the tile's texel rows, and their bands' written columns */
            const uint32_t y0 = ty ? VT_SHADOW_TILE * ty - 1 : 0,
                           y1 = VT_SHADOW_TILE * ty + 3 < sz ? VT_SHADOW_TILE * ty + 3 : sz - 1;
            uint32_t lo = UINT32_MAX, hi = 0;
            for (uint32_t k = y0 / BAND; k <= y1 / BAND; k++)
                if (sh->dlo[c][k] <= sh->dhi[c][k])
                    lo = sh->dlo[c][k] < lo ? sh->dlo[c][k] : lo, hi = sh->dhi[c][k] > hi ? sh->dhi[c][k] : hi;
            vt_shadow_tiles_row(sh->raw, sh->raw + plane, sh->tiles, sz, c, ty, lo, hi);
        }
}

/* Thread t: bands k of every cascade with k % nt == t, cleared, then
 * every list walked once, then their tiles' parts made. */
static void job_raster(void *arg, uint32_t t)
{
    sjob *jb = arg;
    vt_shadow *sh = jb->sh;
    const uint32_t sz = sh->fit.size, nb = (sz + BAND - 1) / BAND, nt = jb->nt;
    const uint32_t tracked = sz <= 2048 ? MAX_BANDS : 0; /* bands with a dirty range (the rest: always cleared) */
    for (uint32_t c = 0; c < sh->fit.n; c++) {
        float *m = sh->maps + (size_t)c * sz * sz;
        for (uint32_t k = t; k < nb; k += nt) {
            uint32_t x0 = k < tracked ? sh->dlo[c][k] : 0, x1 = k < tracked ? sh->dhi[c][k] : sz - 1;
            if (x0 > x1) continue;
            uint32_t y1 = (k + 1) * BAND < sz ? (k + 1) * BAND : sz;
            for (uint32_t y = k * BAND; y < y1; y++) vt_shadow_fill_lowest(m + (size_t)y * sz + x0, x1 + 1 - x0);
            if (k < tracked) sh->dlo[c][k] = UINT16_MAX, sh->dhi[c][k] = 0;
        }
        for (uint32_t b = 0; b < nt; b++)
            for (size_t q = 0; q < sh->tb[b].n[c]; q++) {
                const ltri *L = &sh->tb[b].t[c][q];
                float y0 = min2(L->y[0], min2(L->y[1], L->y[2])), y1 = max2(L->y[0], max2(L->y[1], L->y[2]));
                uint32_t k0 = y0 > 0 ? (uint32_t)y0 / BAND : 0, k1 = y1 < (float)sz ? (uint32_t)y1 / BAND : nb - 1;
                uint32_t k = k0 + (t + nt - k0 % nt) % nt;
                if (k > k1) continue;
                double x[9], y[9], z[9];
                int n = 3;
                bool far = false;
                for (int e = 0; e < 3; e++) far |= !(fabsf(L->x[e]) < 4.0f * sz && fabsf(L->y[e]) < 4.0f * sz);
                if (far && (n = clip_rect(L, sz, x, y, z)) < 3) continue;
                if (!far)
                    for (int e = 0; e < 3; e++) x[e] = L->x[e], y[e] = L->y[e], z[e] = L->z[e];
                /* the columns it may write (raster_poly's, widened to whole
                   texels), for the next clear */
                double xl = x[0], xh = x[0];
                for (int e = 1; e < n; e++) xl = x[e] < xl ? x[e] : xl, xh = x[e] > xh ? x[e] : xh;
                xl = floor(xl), xh = ceil(xh);
                uint16_t cl = xl > 0 ? (xl < sz - 1.0 ? (uint16_t)xl : (uint16_t)(sz - 1)) : 0;
                uint16_t ch = xh > 0 ? (xh < sz - 1.0 ? (uint16_t)xh : (uint16_t)(sz - 1)) : 0;
                const uint32_t kf = k;
                for (; k <= k1; k += nt)
                    /* marked whether or not it covers a texel centre: a
                       clear too many costs less than the test */
                    if (k < tracked) {
                        sh->dlo[c][k] = cl < sh->dlo[c][k] ? cl : sh->dlo[c][k];
                        sh->dhi[c][k] = ch > sh->dhi[c][k] ? ch : sh->dhi[c][k];
                    }
                rmask rm = {.mk = L->mk, .u = sh->fit.u, .v = sh->fit.v, .s = sh->fit.s, .scale = sh->fit.scale[c],
                            .off = {sh->fit.off[c][0], sh->fit.off[c][1]}};
                /* set up once, drawn into each of this thread's bands k1..k1 */
                raster_poly(m, sz, x, y, z, n, (int)(kf * BAND), (int)((k1 + 1) * BAND < sz ? (k1 + 1) * BAND : sz) - 1,
                            (int)(nt * BAND), L->mk ? &rm : NULL);
            }
        const size_t g2 = (size_t)(sz / VT_SHADOW_TILE) * (sz / VT_SHADOW_TILE), plane = sh->fit.n * g2;
        for (uint32_t k = t; k < nb; k += nt)
            vt_shadow_tiles_band(sh->raw + c * g2, sh->raw + plane + c * g2, m, sz, k, k < tracked ? sh->dlo[c][k] : 0,
                                 k < tracked ? sh->dhi[c][k] : sz - 1, sh->cons.qlo[c], sh->cons.qinv[c]);
    }
}

int vt_shadow_draw(vt_shadow *sh, cull_pool *pool, uint32_t threads, const vt_shadow_fit *fit,
                   const double origin[3], const vt_mesh *meshes, const float (*mb)[6], const vt_instance *casters,
                   uint32_t ncasters, uint32_t *tris, char *err, size_t errlen)
{
    *tris = 0;
    sh->fit = *fit;
    size_t npx = (size_t)fit->n * fit->size * fit->size;
    if (!vp_grow((void **)&sh->maps, &sh->maps_cap, npx, sizeof *sh->maps) ||
        !vp_grow((void **)&sh->tiles, &sh->tiles_cap, npx / (VT_SHADOW_TILE * VT_SHADOW_TILE), sizeof *sh->tiles) ||
        !vp_grow((void **)&sh->raw, &sh->raw_cap, 2 * npx / (VT_SHADOW_TILE * VT_SHADOW_TILE), sizeof *sh->raw))
        return vp_errf(err, errlen, VT_ERR_NOMEM, "out of memory for the shadow maps");
    if (fit->size != sh->dirty_size || fit->n != sh->dirty_n) {
        for (int c = 0; c < NC; c++)
            for (uint32_t k = 0; k < MAX_BANDS; k++) sh->dlo[c][k] = 0, sh->dhi[c][k] = (uint16_t)(fit->size - 1);
        sh->dirty_size = fit->size, sh->dirty_n = fit->n;
    }
    uint32_t nt = threads ? threads : 1;
    if (nt > MAX_THREADS) nt = MAX_THREADS;
    if (!pool) nt = 1;
    /* the damaged casters' masks, as the renderers make them */
    uint32_t nmk;
    if (!vt_masks_make(casters, ncasters, origin, &sh->mk, &sh->mk_cap, &sh->mk_of, &sh->mk_of_cap, &nmk))
        return vp_errf(err, errlen, VT_ERR_NOMEM, "out of memory for the shadow casters' masks");
    sjob jb = {.sh = sh, .origin = origin, .meshes = meshes, .mb = mb, .in = casters, .nin = ncasters, .nt = nt,
               .masked = nmk > 0};
    if (nt > 1) cull_pool_run(pool, job_setup, &jb, nt);
    else job_setup(&jb, 0);
    for (uint32_t t = 0; t < nt; t++) {
        if (sh->tb[t].rc) return vp_errf(err, errlen, VT_ERR_NOMEM, "out of memory for the shadow casters");
        for (uint32_t c = 0; c < fit->n; c++) *tris += (uint32_t)sh->tb[t].n[c];
    }
    /* the span lookup's constants (vt_shadow.inl), once a draw; the
       tiles' quantisation first (job_tiles packs with it): 65532 steps
       over the sphere's depth +- 3 radii (a step about 1/11 of a
       texel), which holds every receiver's reference with room */
    vt_shadow_cons *k = &sh->cons;
    const uint32_t g = fit->size / VT_SHADOW_TILE;
    memset(k, 0, sizeof *k);
    k->tq = sh->tiles, k->g = (float)g;
    for (uint32_t c = 0; c < fit->n; c++) {
        const double cs = (double)fit->s[0] * fit->cen[c][0] + (double)fit->s[1] * fit->cen[c][1] +
                          (double)fit->s[2] * fit->cen[c][2];
        k->qlo[c] = (float)(cs - 3.0 * fit->rad[c]);
        k->qinv[c] = (float)(65532.0 / (6.0 * fit->rad[c]));
        k->tbase[c] = (float)((size_t)c * g * g);
        k->offx[c] = fit->off[c][0], k->offy[c] = fit->off[c][1], k->base[c] = (float)((size_t)c * fit->size * fit->size);
        k->far[c] = fit->split[c + 1];
        k->band[c] = VT_SHADOW_BLEND * (fit->split[c + 1] - fit->split[c]);
    }
    if (nt > 1) cull_pool_run(pool, job_raster, &jb, nt), cull_pool_run(pool, job_tiles, &jb, nt);
    else job_raster(&jb, 0), job_tiles(&jb, 0);
    return 0;
}
