/*
 * cull_mat.h — the matrix helpers (column-major, double) and the depth
 * modes, header-only: the culling core and every client (libvantage, the
 * tests, the benchmarks) use this one copy without linking the culling
 * library (libvantage.a carried the whole core for these four functions).
 * Pure functions; no state, no allocation.
 */
#ifndef CULL_MAT_H
#define CULL_MAT_H

#include <math.h>
#include <stdbool.h>
#include <stdint.h>
#include <string.h>

enum cull_depth_mode {
    CULL_DEPTH_GL = 0,       /* clip z in [-w, w] (OpenGL) */
    CULL_DEPTH_ZERO_ONE,     /* clip z in [0, w] (D3D, Vulkan, GL clip-control) */
    CULL_DEPTH_REVERSED,     /* clip z in [0, w], near at 1 (reversed-Z) */
};

/* m = a perspective projection (gluPerspective: fovy in radians, aspect =
 * width / height) for depth_mode (enum cull_depth_mode; others are GL).
 * zfar may be INFINITY. m has room for 16. */
static inline void cull_mat_perspective(double m[16], double fovy, double aspect, double n,
                          double f, uint32_t mode)
{
    memset(m, 0, 16 * sizeof *m);
    double t = 1.0 / tan(0.5 * fovy);
    m[0] = t / aspect;
    m[5] = t;
    m[11] = -1;
    bool inf = isinf(f);
    switch (mode) {
    case CULL_DEPTH_ZERO_ONE:
        m[10] = inf ? -1 : f / (n - f);
        m[14] = inf ? -n : f * n / (n - f);
        break;
    case CULL_DEPTH_REVERSED:
        m[10] = inf ? 0 : n / (f - n);
        m[14] = inf ? n : f * n / (f - n);
        break;
    default:
        m[10] = inf ? -1 : (f + n) / (n - f);
        m[14] = inf ? -2 * n : 2 * f * n / (n - f);
        break;
    }
}

/* m = an orthographic projection of the box l..r, b..t, near..far (glOrtho)
 * for depth_mode. m has room for 16. */
static inline void cull_mat_ortho(double m[16], double l, double r, double b, double t,
                    double n, double f, uint32_t mode)
{
    memset(m, 0, 16 * sizeof *m);
    m[0] = 2 / (r - l);
    m[5] = 2 / (t - b);
    m[12] = -(r + l) / (r - l);
    m[13] = -(t + b) / (t - b);
    m[15] = 1;
    switch (mode) {
    case CULL_DEPTH_ZERO_ONE:
        m[10] = -1 / (f - n);
        m[14] = -n / (f - n);
        break;
    case CULL_DEPTH_REVERSED:
        m[10] = 1 / (f - n);
        m[14] = f / (f - n);
        break;
    default:
        m[10] = -2 / (f - n);
        m[14] = -(f + n) / (f - n);
        break;
    }
}

/* v scaled to unit length (a zero vector stays zero) */
static inline void cull_mat_normalize3_(double v[3])
{
    double l = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    if (l > 0) {
        v[0] /= l;
        v[1] /= l;
        v[2] /= l;
    }
}

/* Camera-relative look-at: the eye is at the origin (pass the eye as
 * cull_view_desc.origin). dir = target - eye; up need not be unit. dir
 * parallel to up gives a degenerate (zero-row) matrix: check first. */
static inline void cull_mat_look_dir(double m[16], const double dir[3], const double up[3])
{
    double f[3] = {dir[0], dir[1], dir[2]};
    cull_mat_normalize3_(f);
    double s[3] = {f[1] * up[2] - f[2] * up[1], f[2] * up[0] - f[0] * up[2],
                   f[0] * up[1] - f[1] * up[0]};
    cull_mat_normalize3_(s);
    double u[3] = {s[1] * f[2] - s[2] * f[1], s[2] * f[0] - s[0] * f[2],
                   s[0] * f[1] - s[1] * f[0]};
    memset(m, 0, 16 * sizeof *m);
    for (int i = 0; i < 3; i++) {
        m[i * 4 + 0] = s[i];
        m[i * 4 + 1] = u[i];
        m[i * 4 + 2] = -f[i];
    }
    m[15] = 1;
}

/* out = a * b; out may be a or b. */
static inline void cull_mat_mul(double out[16], const double a[16], const double b[16])
{
    double t[16];
    for (int c = 0; c < 4; c++)
        for (int r = 0; r < 4; r++) {
            double s = 0;
            for (int k = 0; k < 4; k++) s += a[k * 4 + r] * b[c * 4 + k];
            t[c * 4 + r] = s;
        }
    memcpy(out, t, sizeof t);
}

#endif
