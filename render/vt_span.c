/*
 * vt_span.c — the per-pixel half of the software renderer's shading (see
 * vt_shade.h), one copy for every instruction set: which surface a pixel
 * shows (a triangle's shading record, perspective-correct, or the ground
 * plane), its UVs with their derivatives one pixel over and one up (the
 * mip level), its material (vt_surface_params), and after the lights,
 * the sky where nothing is drawn (the kernel fogs the rest in lanes).
 * Scalar: texture fetches and the sky are per pixel anyway.
 */
#include "vt_mask.h"
#include "vt_shade.h"

#include <math.h>
#include <string.h>

int vt_gather_scalar;

/* Interpolated UVs of t at barycentrics b. */
static inline void tri_uv_b(const vt_stri *t, const float b[3], float uv[2])
{
    uv[0] = b[0] * t->uv[0][0] + b[1] * t->uv[1][0] + b[2] * t->uv[2][0];
    uv[1] = b[0] * t->uv[0][1] + b[1] * t->uv[1][1] + b[2] * t->uv[2][1];
}

/* Interpolated UVs of t at NDC (X, Y). */
static inline void tri_uv(const vt_stri *t, float X, float Y, float uv[2])
{
    float b[3];
    vt_stri_bary(t, X, Y, b);
    tri_uv_b(t, b, uv);
}

/* The UVs at (X, Y), whose barycentrics are b, and their differences one
 * pixel right and one up. */
static void tri_uv_d(const vt_stri *t, const float b[3], float X, float Y, float dX, float dY, float uv[2], float dx[2],
                     float dy[2])
{
    float ux[2], uy[2];
    tri_uv_b(t, b, uv);
    tri_uv(t, X + dX, Y, ux);
    tri_uv(t, X, Y + dY, uy);
    for (int k = 0; k < 2; k++) {
        dx[k] = ux[k] - uv[k];
        dy[k] = uy[k] - uv[k];
    }
}

bool vt_stri_alpha_pass(const vt_stri *t, float X, float Y, float dX, float dY)
{
    float b[3], uv[2], dx[2], dy[2];
    vt_stri_bary(t, X, Y, b);
    tri_uv_d(t, b, X, Y, dX, dY, uv, dx, dy);
    return vt_surface_alpha(t->mat, uv, dx, dy) >= t->mat->alpha_cutoff;
}

/* The ground's UVs: world x and z (modulo 4096 m at the view's origin). */
static bool ground_uv(const vt_span *sp, double X, double Y, float uv[2])
{
    double q[3], nz;
    if (!vt_ground_at(sp->gr, X, Y, &nz)) return false;
    vt_ground_point(sp->gr, X, Y, nz, q);
    uv[0] = (float)(sp->pe->ground_uv0[0] + q[0]);
    uv[1] = (float)(sp->pe->ground_uv0[1] + q[2]);
    return true;
}

/* vt_surface_params of the default material (no texture, no map). */
static inline void default_params(const float n[3], const float albedo[3], vt_surfout *o)
{
    float l = sqrtf(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]), il = l > 0 ? 1 / l : 0;
    const float a = VT_DEFAULT_ROUGHNESS * VT_DEFAULT_ROUGHNESS;
    for (int c = 0; c < 3; c++) {
        o->n[c] = n[c] * il;
        o->diffuse[c] = albedo[c];
        o->f0[c] = 0.04f;
        o->em[c] = 0;
    }
    o->a2 = a * a;
    o->rough = VT_DEFAULT_ROUGHNESS;
    o->alpha = 1;
}

void vt_span_surface(const vt_span *sp, uint32_t i, float p[3], vt_surfout *o, float *cov)
{
    uint32_t id = i < sp->n ? sp->id[i] : 0;
    if (!id) {
        memset(o, 0, sizeof *o);
        p[0] = p[1] = p[2] = 0;
        *cov = 0;
        return;
    }
    *cov = 1;
    const float X = vt_ndc_x(sp->x0 + i, sp->inv_w), dX = (float)sp->inv_w, dY = (float)sp->inv_h;
    vt_surfin in = {0};
    if (id == VT_ID_GROUND) {
        double q[3], nz;
        const vt_penv *pe = sp->pe;
        if (vt_ground_at(sp->gr, X, sp->Y, &nz)) vt_ground_point(sp->gr, X, sp->Y, nz, q);
        else q[0] = q[1] = q[2] = 0; /* the raster found it there */
        for (int k = 0; k < 3; k++) p[k] = in.p[k] = (float)q[k];
        in.n[1] = 1;
        if (!pe->ground_mat) {
            default_params(in.n, pe->ground_albedo, o);
            return;
        }
        in.albedo = pe->ground_albedo;
        in.mat = pe->ground_mat;
        if (in.mat && ground_uv(sp, X, sp->Y, in.uv)) {
            float ux[2], uy[2];
            in.has_uv = true;
            bool hx = ground_uv(sp, X + dX, sp->Y, ux), hy = ground_uv(sp, X, sp->Y + dY, uy);
            for (int k = 0; k < 2; k++) {
                in.dx[k] = hx ? ux[k] - in.uv[k] : 0;
                in.dy[k] = hy ? uy[k] - in.uv[k] : 0;
            }
        }
        vt_surface_params(&in, o);
        return;
    }
    id--;
    const vt_stri *t = &sp->st[id >> VT_ID_BITS][id & VT_ID_MASK];
    float b[3];
    vt_stri_bary(t, X, sp->Y, b);
    for (int k = 0; k < 3; k++) {
        p[k] = in.p[k] = b[0] * t->p[0][k] + b[1] * t->p[1][k] + b[2] * t->p[2][k];
        in.n[k] = b[0] * t->n[0][k] + b[1] * t->n[1][k] + b[2] * t->n[2][k];
    }
    /* a damaged instance: charred towards a hole's rim (the raster kept
       only pixels whose mask is >= 0) */
    float k = t->mask ? vt_mask_rim(t->mask, vt_mask_eval(t->mask, p[0], p[1], p[2])) : 1.0f;
    float alb[3] = {t->albedo[0] * k, t->albedo[1] * k, t->albedo[2] * k};
    if (!t->mat) { /* the default material: vt_surface_params' fast path, inline */
        default_params(in.n, alb, o);
        return;
    }
    in.albedo = alb;
    in.mat = t->mat;
    const vt_texref *tx = t->mat->tex; /* UVs only for a material with a texture (they read nothing else) */
    if (t->has_uv && (tx[VT_SLOT_BASE].tex || tx[VT_SLOT_MR].tex || tx[VT_SLOT_NORMAL].tex || tx[VT_SLOT_EMISSIVE].tex)) {
        in.has_uv = true;
        /* the UVs at the pixel and their differences one right and one up */
        tri_uv_d(t, b, X, sp->Y, dX, dY, in.uv, in.dx, in.dy);
        if (t->has_tg && t->mat->tex[VT_SLOT_NORMAL].tex) { /* only a normal map reads the tangent */
            in.has_t = true;
            for (int c = 0; c < 4; c++) in.t[c] = b[0] * t->tg[0][c] + b[1] * t->tg[1][c] + b[2] * t->tg[2][c];
        }
    }
    vt_surface_params(&in, o);
    if (t->mat && k != 1.0f)
        for (int c = 0; c < 3; c++) {
            o->diffuse[c] *= k;
            o->f0[c] *= k;
            o->em[c] *= k;
        }
}

/* The sky image's coordinates of column i's ray (row coefficients c0, c1). */
static void sky_uv_at(const vt_span *sp, uint32_t i, const float c0[3], const float c1[3], float uv[2])
{
    float X = vt_ndc_x(sp->x0 + i, sp->inv_w), d[3];
    for (int k = 0; k < 3; k++) d[k] = c0[k] + X * c1[k];
    float l = sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]), il = l > 0 ? 1 / l : 0;
    for (int k = 0; k < 3; k++) d[k] *= il;
    vt_sky_uv(sp->pe, d, uv);
}

void vt_span_sky(const vt_span *sp, float *cr, float *cg, float *cb, const float *cov)
{
    float c0[3] = {0, 0, 0}, c1[3] = {0, 0, 0}, ua[2] = {0, 0}, ub[2] = {0, 0};
    bool row = false;
    uint32_t ia = UINT32_MAX, ib = 0;
    for (uint32_t i = 0; i < sp->n; i++) {
        float c[3];
        if (cov[i] > 0) {
            continue; /* drawn: its fog is the kernel's (in lanes) */
        } else {
            if (!row) vt_view_dir_row(sp->vr, sp->Y, c0, c1);
            row = true;
            if (!sp->pe->sky_img) {
                float X = vt_ndc_x(sp->x0 + i, sp->inv_w), d[3];
                for (int k = 0; k < 3; k++) d[k] = c0[k] + X * c1[k];
                float l = sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]), il = l > 0 ? 1 / l : 0;
                for (int k = 0; k < 3; k++) d[k] *= il;
                vt_sky_radiance(sp->pe, d, c);
            } else {
                /* the image's coordinates are smooth across the screen:
                   exact every 4th column, linear between, exact where the
                   azimuth wraps or near the poles (two inverse
                   trigonometric calls saved on 3 pixels of 4) */
                uint32_t a = i & ~3u, b = a + 4 < sp->n ? a + 4 : sp->n - 1;
                if (a != ia) {
                    sky_uv_at(sp, a, c0, c1, ua);
                    if (b != a) sky_uv_at(sp, b, c0, c1, ub);
                    ia = a, ib = b;
                }
                float uv[2];
                if (i == ia) {
                    memcpy(uv, ua, sizeof uv);
                } else if (fabsf(ua[0] - ub[0]) < 0.25f && ua[1] > 0.05f && ua[1] < 0.95f && ub[1] > 0.05f &&
                           ub[1] < 0.95f) {
                    float f = (float)(i - ia) / (float)(ib - ia);
                    uv[0] = ua[0] + f * (ub[0] - ua[0]);
                    uv[1] = ua[1] + f * (ub[1] - ua[1]);
                } else {
                    sky_uv_at(sp, i, c0, c1, uv);
                }
                vt_sky_sample(sp->pe, uv, c);
            }
        }
        cr[i] = c[0], cg[i] = c[1], cb[i] = c[2];
    }
}
