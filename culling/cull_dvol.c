/*
 * cull_dvol.c — destruction distance volumes (see culling.h).
 *
 * The fold of one sphere into the field is the hot loop: for every sample,
 * d = min(d, |p - c| - r), in floats relative to the box's corner (small
 * numbers wherever the entity is), branch-free over contiguous arrays so
 * the compiler vectorises it (built with -fno-math-errno: sqrtf is one
 * instruction). 8^3 samples x 64 spheres is 32k distances.
 */
#include "cull_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

int cull_dvol_init(cull_dvol *v, const double bmin[3], const double bmax[3], uint32_t res)
{
    memset(v, 0, sizeof *v);
    if (res < 2 || res > CULL_DVOL_MAX_RES) return CULL_ERR_INVALID;
    for (int a = 0; a < 3; a++) {
        if (!isfinite(bmin[a]) || !isfinite(bmax[a])) return CULL_ERR_NONFINITE;
        if (bmin[a] > bmax[a]) return CULL_ERR_AABB;
        if (fabs(bmin[a]) > CULL_MAX_COORD || fabs(bmax[a]) > CULL_MAX_COORD) return CULL_ERR_RANGE;
    }
    size_t total = 1;
    for (int a = 0; a < 3; a++) {
        double ext = bmax[a] - bmin[a];
        v->n[a] = ext > 0 ? res : 2;
        v->origin[a] = bmin[a];
        v->step[a] = ext > 0 ? ext / (res - 1) : 1e-3;
        total *= v->n[a];
    }
    v->d = malloc(total * sizeof *v->d);
    v->px = malloc(total * sizeof *v->px);
    v->py = malloc(total * sizeof *v->py);
    v->pz = malloc(total * sizeof *v->pz);
    if (!v->d || !v->px || !v->py || !v->pz) {
        cull_dvol_free(v);
        return CULL_ERR_NOMEM;
    }
    size_t i = 0;
    for (uint32_t z = 0; z < v->n[2]; z++)
        for (uint32_t y = 0; y < v->n[1]; y++)
            for (uint32_t x = 0; x < v->n[0]; x++, i++) {
                v->px[i] = (float)(x * v->step[0]);
                v->py[i] = (float)(y * v->step[1]);
                v->pz[i] = (float)(z * v->step[2]);
                v->d[i] = INFINITY;
            }
    return CULL_OK;
}

void cull_dvol_free(cull_dvol *v)
{
    free(v->d);
    free(v->px);
    free(v->py);
    free(v->pz);
    free(v->sph);
    memset(v, 0, sizeof *v);
}

static size_t samples(const cull_dvol *v)
{
    return (size_t)v->n[0] * v->n[1] * v->n[2];
}

/* d = min(d, |p - c| - r) over every sample; c relative to the origin. */
static void fold(cull_dvol *v, const double c[3], double r)
{
    const float cx = (float)(c[0] - v->origin[0]), cy = (float)(c[1] - v->origin[1]),
                cz = (float)(c[2] - v->origin[2]), rf = (float)r;
    float *restrict d = v->d;
    const float *restrict px = v->px, *restrict py = v->py, *restrict pz = v->pz;
    size_t n = samples(v);
    for (size_t i = 0; i < n; i++) {
        float dx = px[i] - cx, dy = py[i] - cy, dz = pz[i] - cz;
        float e = sqrtf(dx * dx + dy * dy + dz * dz) - rf;
        d[i] = e < d[i] ? e : d[i];
    }
}

int cull_dvol_add_sphere(cull_dvol *v, const double c[3], double r)
{
    if (!isfinite(c[0]) || !isfinite(c[1]) || !isfinite(c[2])) return CULL_ERR_NONFINITE;
    if (!(r > 0) || !isfinite(r) || r > CULL_MAX_RADIUS) return CULL_ERR_RADIUS;
    for (int a = 0; a < 3; a++)
        if (fabs(c[a]) > CULL_MAX_COORD) return CULL_ERR_RANGE;
    if (v->nsph >= CULL_DVOL_MAX_SPHERES) return CULL_ERR_CAPACITY;
    if (!vp_grow32((void **)&v->sph, &v->cap, (size_t)v->nsph + 1, sizeof *v->sph)) return CULL_ERR_NOMEM;
    double *s = v->sph[v->nsph++];
    memcpy(s, c, 3 * sizeof *c);
    s[3] = r;
    fold(v, c, r);
    v->version++;
    return CULL_OK;
}

void cull_dvol_rebuild(cull_dvol *v)
{
    size_t n = samples(v);
    for (size_t i = 0; i < n; i++) v->d[i] = INFINITY;
    for (uint32_t k = 0; k < v->nsph; k++) fold(v, v->sph[k], v->sph[k][3]);
    v->version++;
}

float cull_dvol_sample(const cull_dvol *v, const double p[3])
{
    if (!v->nsph) return INFINITY; /* nothing destroyed (and inf - inf would be NaN) */
    double t[3];
    uint32_t i0[3];
    for (int a = 0; a < 3; a++) {
        double u = (p[a] - v->origin[a]) / v->step[a], hi = v->n[a] - 1;
        u = u < 0 ? 0 : u > hi ? hi : u;
        uint32_t i = (uint32_t)u;
        if (i >= v->n[a] - 1) i = v->n[a] - 2;
        i0[a] = i;
        t[a] = u - i;
    }
    size_t sx = 1, sy = v->n[0], sz = (size_t)v->n[0] * v->n[1];
    const float *d = v->d + i0[0] * sx + i0[1] * sy + i0[2] * sz;
    double c00 = d[0] + t[0] * (d[sx] - d[0]), c10 = d[sy] + t[0] * (d[sy + sx] - d[sy]);
    double c01 = d[sz] + t[0] * (d[sz + sx] - d[sz]), c11 = d[sz + sy] + t[0] * (d[sz + sy + sx] - d[sz + sy]);
    double c0 = c00 + t[1] * (c10 - c00), c1 = c01 + t[1] * (c11 - c01);
    return (float)(c0 + t[2] * (c1 - c0));
}

double cull_dvol_bound(const cull_dvol *v)
{
    double diag = sqrt(v->step[0] * v->step[0] + v->step[1] * v->step[1] + v->step[2] * v->step[2]);
    /* float samples: |p - c| - r in floats relative to the corner, so a
       few roundings of the largest of the box's size and r + |c - corner|
       (a sphere of 1e4 m whose surface crosses the box rounds to ~1e-3) */
    double big = diag * (v->n[0] + v->n[1] + v->n[2]);
    for (uint32_t k = 0; k < v->nsph; k++) {
        const double *s = v->sph[k];
        double dx = s[0] - v->origin[0], dy = s[1] - v->origin[1], dz = s[2] - v->origin[2];
        double far = s[3] + sqrt(dx * dx + dy * dy + dz * dz);
        big = far > big ? far : big;
    }
    return 0.5 * diag + 0x1p-20 * big;
}

double cull_dvol_exact(const cull_dvol *v, const double p[3])
{
    double best = INFINITY;
    for (uint32_t k = 0; k < v->nsph; k++) {
        const double *s = v->sph[k];
        double dx = p[0] - s[0], dy = p[1] - s[1], dz = p[2] - s[2];
        double e = sqrt(dx * dx + dy * dy + dz * dz) - s[3];
        best = e < best ? e : best;
    }
    return best;
}
