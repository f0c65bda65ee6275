/*
 * vt_mask.h — the destruction mask both renderers draw ("Destruction
 * Masking in Frostbite 2", SIGGRAPH 2010): an instance with a destruction
 * volume (cull_dvol: the signed distance to its sphere set on a small grid
 * over its box) is drawn where
 *
 *     mask(p) = trilinear field(p) + amp * detail(p)  >=  0
 *
 * and discarded where it is negative: a hole. detail is a procedural value
 * noise in -1..1 (two octaves, smoothstep-filtered lattice of hashed
 * values) fixed to the volume, so the rim of a hole is ragged, not a
 * sphere, and moves with the entity. Near the rim (0 <= mask < band) the
 * albedo is blended towards char. A damaged instance is drawn two-sided:
 * through the hole one sees its inside (its back faces, normals turned
 * inwards, albedo darkened), not through the whole object.
 *
 * Scales, from the volume's largest step s: amp = s / 4, the detail's
 * lattice cell s / 2, band = s / 4. The drawn hole is inside
 * { exact distance to the sphere set < vt_mask_margin(v) }: the field is
 * within cull_dvol_bound of the exact distance and the detail moves it by
 * at most amp; the occluder cut (daemon/destruct.c) widens by that margin
 * so the occluder's hole always contains the drawn one.
 *
 * The float code here is what vt_soft runs per pixel; vt_gldraw's fragment
 * shader is the same formula in GLSL (same hash, same order of
 * operations), so the two agree but for pixels on the rim itself.
 */
#ifndef VANTAGE_VT_MASK_H
#define VANTAGE_VT_MASK_H

#include "culling.h"

#include <math.h>
#include <stdbool.h>
#include <stdint.h>

#define VT_MASK_INTERIOR 0.35f  /* albedo factor of a damaged instance's inside without an
                                   environment; with one (issue 20) the inside is the same
                                   surface lit as geometry: its normals turned inwards, the
                                   sky's ambient occluded by the cavity (SSAO), the sun's
                                   cascades */
#define VT_MASK_CHAR 0.08f      /* albedo factor right at a hole's rim */

/* A volume as the renderers sample it, camera-relative. */
typedef struct vt_mask {
    float o[3];             /* sample (0, 0, 0) */
    float is[3];            /* 1 / step: samples per metre */
    float hi[3];            /* n - 1: the last sample's coordinate */
    float cs[3];            /* detail cells per sample step */
    float amp, ib;          /* detail amplitude (metres), 1 / band */
    float reach;            /* amp + band: past it the detail cannot matter */
    uint32_t n0, n01;       /* samples per row, per slice */
    const float *d;         /* the field, x fastest */
    /* for vt_mask_clear: the spheres (world), the camera, the distance
       from every sphere past which nothing is masked */
    const double (*sph)[4];
    uint32_t nsph;
    double cam[3], clear;
} vt_mask;

/* Past this many spheres vt_mask_clear does not try (every pixel of a
 * damaged instance tests the mask). */
#define VT_MASK_CLEAR_MAX 64u

/* Whether v damages its instance (a volume with at least one sphere):
 * the one test of whether an instance is drawn masked. */
static inline bool vt_dvol_live(const cull_dvol *v)
{
    return v && v->nsph;
}

/* m for v seen from a camera at origin. v must have spheres. */
void vt_mask_make(const cull_dvol *v, const double origin[3], vt_mask *m);

/* How far from its sphere set a hole drawn for v can reach: the field's
 * bound plus the detail amplitude. */
double vt_mask_margin(const cull_dvol *v);

/* The detail amplitude of v (metres). */
double vt_mask_amp(const cull_dvol *v);

/* Whether the triangle p[0..2] (camera-relative) is clear of every hole:
 * its bounding box is farther than r + clear from every sphere, so the
 * exact distance there is, the field is within the bound of it, and the
 * mask is >= band all over it: nothing to discard, no rim. The talk's
 * split of a mesh into masked and unmasked parts; conservative (a clear
 * triangle may be called masked, never the reverse), O(spheres). */
bool vt_mask_clear(const vt_mask *m, const float (*p)[3]);

/* A lattice point's value in -1..1 (an integer hash: exact in GLSL too). */
static inline float vt_mask_lattice(int32_t i, int32_t j, int32_t k)
{
    uint32_t h = (uint32_t)i * 0x8da6b343u ^ (uint32_t)j * 0xd8163841u ^ (uint32_t)k * 0xcb1ab31fu;
    h ^= h >> 16;
    h *= 0x7feb352du;
    h ^= h >> 15;
    h *= 0x846ca68bu;
    h ^= h >> 16;
    return (float)(h >> 8) * (1.0f / 8388607.5f) - 1.0f;
}

/* Value noise at (x, y, z) lattice units (|coordinates| well below 2^31). */
static inline float vt_mask_vnoise(float x, float y, float z)
{
    float fx = floorf(x), fy = floorf(y), fz = floorf(z);
    int32_t i = (int32_t)fx, j = (int32_t)fy, k = (int32_t)fz;
    float tx = x - fx, ty = y - fy, tz = z - fz;
    tx = tx * tx * (3.0f - 2.0f * tx);
    ty = ty * ty * (3.0f - 2.0f * ty);
    tz = tz * tz * (3.0f - 2.0f * tz);
    float c00 = vt_mask_lattice(i, j, k) + tx * (vt_mask_lattice(i + 1, j, k) - vt_mask_lattice(i, j, k));
    float c10 = vt_mask_lattice(i, j + 1, k) + tx * (vt_mask_lattice(i + 1, j + 1, k) - vt_mask_lattice(i, j + 1, k));
    float c01 = vt_mask_lattice(i, j, k + 1) + tx * (vt_mask_lattice(i + 1, j, k + 1) - vt_mask_lattice(i, j, k + 1));
    float c11 = vt_mask_lattice(i, j + 1, k + 1) +
                tx * (vt_mask_lattice(i + 1, j + 1, k + 1) - vt_mask_lattice(i, j + 1, k + 1));
    float c0 = c00 + ty * (c10 - c00), c1 = c01 + ty * (c11 - c01);
    return c0 + tz * (c1 - c0);
}

/* The detail at (x, y, z) cells: two octaves, in -1..1. */
static inline float vt_mask_detail(float x, float y, float z)
{
    return 0.6f * vt_mask_vnoise(x, y, z) + 0.4f * vt_mask_vnoise(2.0f * x + 17.0f, 2.0f * y + 17.0f, 2.0f * z + 17.0f);
}

/* The mask at camera-relative p: < 0 destroyed. The detail is only
 * evaluated where it can matter (the field within amp + band of zero);
 * farther out the value returned is the field alone, which is >= band
 * (no rim) or < -amp (destroyed) either way. */
static inline float vt_mask_eval(const vt_mask *m, float px, float py, float pz)
{
    float u[3] = {(px - m->o[0]) * m->is[0], (py - m->o[1]) * m->is[1], (pz - m->o[2]) * m->is[2]};
    float t[3];
    uint32_t base = 0;
    for (int a = 0; a < 3; a++) {
        float c = !(u[a] >= 0.0f) ? 0.0f : u[a] > m->hi[a] ? m->hi[a] : u[a]; /* NaN: 0 */
        u[a] = c;
        float f = floorf(c);
        if (f > m->hi[a] - 1.0f) f = m->hi[a] - 1.0f;
        t[a] = c - f;
        base += (uint32_t)f * (a == 0 ? 1u : a == 1 ? m->n0 : m->n01);
    }
    const float *d = m->d + base;
    uint32_t sy = m->n0, sz = m->n01;
    float c00 = d[0] + t[0] * (d[1] - d[0]), c10 = d[sy] + t[0] * (d[sy + 1] - d[sy]);
    float c01 = d[sz] + t[0] * (d[sz + 1] - d[sz]), c11 = d[sz + sy] + t[0] * (d[sz + sy + 1] - d[sz + sy]);
    float c0 = c00 + t[1] * (c10 - c00), c1 = c01 + t[1] * (c11 - c01);
    float f = c0 + t[2] * (c1 - c0);
    if (f < -m->amp || f >= m->reach) return f;
    return f + m->amp * vt_mask_detail(u[0] * m->cs[0], u[1] * m->cs[1], u[2] * m->cs[2]);
}

/* The albedo factor at mask e >= 0: VT_MASK_CHAR at the rim, rising
 * smoothly to 1 at the band's edge. */
static inline float vt_mask_rim(const vt_mask *m, float e)
{
    float k = e * m->ib;
    if (k >= 1.0f) return 1.0f;
    if (k <= 0.0f) return VT_MASK_CHAR; /* on the rim (rounding may put it a hair inside) */
    k = k * k * (3.0f - 2.0f * k);
    return VT_MASK_CHAR + (1.0f - VT_MASK_CHAR) * k;
}

#endif
