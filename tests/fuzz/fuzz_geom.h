/*
 * fuzz_geom.h — the byte decoder fuzz_query.c and fuzz_render.c share:
 * numbers, views and lights from the fuzzer's bytes, made so that most
 * inputs are *valid* (finite, counts in range: what the decoders and
 * validators let through) but adversarial: small integers (an eye exactly
 * on an occluder's plane, level with its base), tiny and huge terms
 * (1e-300 .. 1e30), raw doubles (NaN and infinities too, rarely), zero.
 * Reading past the end gives zeros, so every input decodes to something.
 */
#ifndef VANTAGE_FUZZ_GEOM_H
#define VANTAGE_FUZZ_GEOM_H

#include "culling.h"

#include <math.h>
#include <stdint.h>
#include <string.h>

typedef struct fz {
    const uint8_t *p;
    size_t n;
} fz;

static inline uint8_t fz_u8(fz *f)
{
    if (!f->n) return 0;
    f->n--;
    return *f->p++;
}

static inline uint32_t fz_u16(fz *f)
{
    uint32_t a = fz_u8(f);
    return a | (uint32_t)fz_u8(f) << 8;
}

/* One number: a kind byte, then what that kind reads. `scale` is the
 * size of an ordinary value (metres of a scene, 1 for a matrix term). */
static inline double fz_num(fz *f, double scale)
{
    uint8_t k = fz_u8(f);
    switch (k & 7) {
    case 0: /* a small integer: exact coordinates, planes through the eye */
        return (double)((int)(k >> 3) - 16);
    case 1: /* an ordinary value */
    case 2:
        return scale * ((double)fz_u16(f) / 32768.0 - 1.0);
    case 3: { /* tiny or huge, either sign: 10^-300 .. 10^30 */
        double e = -300.0 + 330.0 * (double)fz_u8(f) / 255.0;
        double v = pow(10.0, e) * (1.0 + (double)(k >> 3) / 32.0);
        return (k & 8) ? -v : v;
    }
    case 4: /* an ordinary value plus a tiny or huge cross term */
        return scale * ((double)fz_u16(f) / 32768.0 - 1.0) + ((k & 8) ? 1 : -1) * pow(10.0, (double)fz_u8(f) - 300.0);
    case 5:
        return 0;
    case 6: { /* a float's bits (what the wire carries for vertices) */
        uint32_t u = fz_u16(f) | fz_u16(f) << 16;
        float x;
        memcpy(&x, &u, sizeof x);
        return x;
    }
    default: { /* a raw double: anything, NaN and infinities included */
        uint64_t u = 0;
        for (int i = 0; i < 8; i++) u |= (uint64_t)fz_u8(f) << (8 * i);
        double x;
        memcpy(&x, &u, sizeof x);
        return x;
    }
    }
}

/* A view desc: a look-at (eye, target, up: any of them on integers, or with
 * cross terms) times a perspective or orthographic projection with near
 * and far from the bytes (1e-6 .. 1e30, infinite), or 16 raw terms; then
 * a few terms overwritten or perturbed, or one row made nearly a multiple
 * of another. viewport_w/h as given. */
static inline void fz_view_desc(fz *f, cull_view_desc *d, uint32_t vw, uint32_t vh)
{
    memset(d, 0, sizeof *d);
    uint8_t k = fz_u8(f);
    d->depth_mode = k % 3;
    d->viewport_w = vw;
    d->viewport_h = vh;
    for (int a = 0; a < 3; a++) d->origin[a] = fz_num(f, 100);
    if ((k >> 2) % 8 == 0) { /* 16 raw terms */
        for (int i = 0; i < 16; i++) d->view_proj[i] = fz_num(f, 2);
        return;
    }
    double dir[3], up[3], proj[16], view[16];
    for (int a = 0; a < 3; a++) dir[a] = fz_num(f, 100);
    for (int a = 0; a < 3; a++) up[a] = (k & 32) ? fz_num(f, 1) : a == 1;
    double n = fz_num(f, 1), fa = fz_num(f, 1000);
    if (k & 64) {
        double hw = fz_num(f, 100), hh = fz_num(f, 100);
        cull_mat_ortho(proj, -hw, hw, -hh, hh, n, fa, d->depth_mode);
    } else {
        double fov = 0.1 + 3.0 * (double)fz_u8(f) / 255.0, aspect = (double)vw / (double)(vh ? vh : 1);
        uint8_t m = fz_u8(f);
        if (m & 1) n = 1e-6;
        if (m & 2) fa = (m & 4) ? INFINITY : 1e30;
        cull_mat_perspective(proj, fov, aspect, n, fa, d->depth_mode);
    }
    cull_mat_look_dir(view, dir, up);
    cull_mat_mul(d->view_proj, proj, view);
    for (uint32_t c = fz_u8(f) % 4; c > 0; c--) {
        uint8_t i = fz_u8(f);
        double t = fz_num(f, 1);
        if (i & 16) d->view_proj[i & 15] += t;
        else d->view_proj[i & 15] = t;
    }
    if (k & 128) { /* nearly singular: row i almost a multiple of row j */
        uint8_t ij = fz_u8(f);
        int i = ij & 3, j = (i + 1 + (ij >> 2) % 3) % 4;
        double s = fz_num(f, 2), e = pow(10.0, -(double)(ij >> 4));
        for (int c = 0; c < 4; c++) d->view_proj[c * 4 + i] = s * d->view_proj[c * 4 + j] + e * d->view_proj[c * 4 + i];
    }
}

/* A light: position, range (tiny to huge; positive unless a bit says
 * otherwise), point or spot with an axis (unit unless a bit says
 * otherwise: zero and denormal axes then) and a cone from the bytes. */
static inline void fz_light(fz *f, cull_light *l)
{
    memset(l, 0, sizeof *l);
    uint8_t k = fz_u8(f);
    for (int a = 0; a < 3; a++) l->pos[a] = fz_num(f, 100);
    double r = fz_num(f, 50);
    l->radius = (k & 4) ? r : fabs(r);
    if (k & 1) {
        l->type = CULL_LIGHT_SPOT;
        for (int a = 0; a < 3; a++) l->dir[a] = (float)fz_num(f, 1);
        if (!(k & 2)) { /* a unit axis, as the validators want */
            double n = sqrt((double)l->dir[0] * l->dir[0] + (double)l->dir[1] * l->dir[1] + (double)l->dir[2] * l->dir[2]);
            if (n > 0 && n < INFINITY)
                for (int a = 0; a < 3; a++) l->dir[a] = (float)(l->dir[a] / n);
        }
        l->cos_outer = (float)((double)fz_u8(f) / 127.5 - 1.0);
    }
}

#endif
