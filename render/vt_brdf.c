/*
 * vt_brdf.c — glTF 2.0's metallic-roughness BRDF in scalar form, the
 * split-sum DFG table and the image-based ambient (see vt_brdf.h).
 * Costs: the DFG table 32 x 32 x 2 x 1024 samples once per process (6
 * ms; 24 before the half vectors were made once a row and the cosine
 * estimator once a column, the same table bit for bit); vt_ibl_update,
 * per sky change, 64 x 32 x 16 + 4096 environment lookups and 1024 x
 * 2048 + 3 x 1024 x 512 lobe weights (4.1 ms on one thread of this
 * machine, 2.2 on two with vt_ibl_update_pool: the lobes four cells a
 * step, the rows shared by the threads; 8.2 before); per pixel the
 * kernels then pay one SH polynomial, one DFG lookup and two bilinear
 * octahedral lookups.
 */
#include "vt_brdf.h"

#include "vt_soft.h"

#include <math.h>
#include <pthread.h>
#include <string.h>
#ifdef __SSE2__
#include <emmintrin.h>
#endif

#define PI_F 3.14159265358979f

float vt_brdf_rough(float r)
{
    return r >= VT_MIN_ROUGHNESS ? (r <= 1 ? r : 1) : r < VT_MIN_ROUGHNESS ? VT_MIN_ROUGHNESS : 1;
}

float vt_brdf_d(float ndh, float a2)
{
    if (!(ndh > 0)) return 0;
    /* 1 - n.h^2 (1 - a2) as (1 - n.h)(1 + n.h) + n.h^2 a2: no cancellation
       near the peak, where t ~ a2 >= 4e-6 (1 - n.h is exact there) */
    float t = (1 - ndh) * (1 + ndh) + ndh * ndh * a2;
    return a2 / (PI_F * t * t);
}

float vt_brdf_v(float ndl, float ndv, float a2)
{
    ndl = fabsf(ndl), ndv = fabsf(ndv);
    float gl = ndl + sqrtf(a2 + (1 - a2) * ndl * ndl), gv = ndv + sqrtf(a2 + (1 - a2) * ndv * ndv);
    return 1 / (gl * gv);
}

float vt_brdf_f(float f0, float vdh)
{
    float k = 1 - fabsf(vdh), k2 = k * k;
    return f0 + (1 - f0) * k2 * k2 * k;
}

static inline float dot3(const float a[3], const float b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

void vt_brdf_eval(const float n[3], const float v[3], const float l[3], const float base[3], float metallic,
                  float roughness, float out[3])
{
    float r = vt_brdf_rough(roughness), a = r * r, a2 = a * a;
    float ndl = dot3(n, l), ndv = dot3(n, v), h[3] = {l[0] + v[0], l[1] + v[1], l[2] + v[2]};
    float hl = sqrtf(dot3(h, h));
    if (!(ndl > 0) || !(hl > 0)) {
        out[0] = out[1] = out[2] = 0;
        return;
    }
    for (int k = 0; k < 3; k++) h[k] /= hl;
    float dv = vt_brdf_d(dot3(n, h), a2) * vt_brdf_v(ndl, ndv, a2), vh = dot3(v, h);
    for (int c = 0; c < 3; c++) {
        /* lerp(0.04, base, metallic) as a sum of two positive terms: 0.04 +
           (base - 0.04) m cancels for a metal of a small base */
        float f0 = VT_F0_DIELECTRIC * (1 - metallic) + base[c] * metallic;
        float F = vt_brdf_f(f0, vh), cd = base[c] * (1 - metallic);
        out[c] = (1 - F) * cd / PI_F + F * dv;
    }
}

/* ---- the DFG table ------------------------------------------------------------------ */

static float dfg[VT_DFG_N * VT_DFG_N * 4];
static pthread_once_t dfg_once = PTHREAD_ONCE_INIT;

static float radical_inverse(uint32_t b)
{
    b = (b << 16) | (b >> 16);
    b = ((b & 0x55555555u) << 1) | ((b & 0xAAAAAAAAu) >> 1);
    b = ((b & 0x33333333u) << 2) | ((b & 0xCCCCCCCCu) >> 2);
    b = ((b & 0x0F0F0F0Fu) << 4) | ((b & 0xF0F0F0F0u) >> 4);
    b = ((b & 0x00FF00FFu) << 8) | ((b & 0xFF00FF00u) >> 8);
    return (float)b * 2.3283064365386963e-10f;
}

/* The sample points, the same for every entry: Hammersley's (i + 0.5) / N
   and the radical inverse of i as the azimuth. */
enum { DFG_SAMPLES = 1024 };
static double dfg_x1[DFG_SAMPLES], dfg_cos[DFG_SAMPLES], dfg_sin[DFG_SAMPLES];

static inline double pow5(double x)
{
    double x2 = x * x;
    return x2 * x2 * x;
}

/* The cosine-distributed estimator (l: pdf n.l / pi) of column ndv: it
 * does not depend on the roughness, so once a column. n = z, v in the xz
 * plane; the sum in double. */
static double dfg_c(float ndv)
{
    double nv = ndv > 1e-4f ? ndv : 1e-4, v[3] = {sqrt(1 - nv * nv), 0, nv};
    double C = 0;
    for (uint32_t i = 0; i < DFG_SAMPLES; i++) {
        double x1 = dfg_x1[i], cp = dfg_cos[i], sp = dfg_sin[i];
        double sr = sqrt(x1), l[3] = {sr * cp, sr * sp, sqrt(1 - x1)};
        double hh[3] = {l[0] + v[0], l[1] + v[1], l[2] + v[2]};
        double hn = sqrt(hh[0] * hh[0] + hh[1] * hh[1] + hh[2] * hh[2]);
        double vh2 = hn > 0 ? (v[0] * hh[0] + v[2] * hh[2]) / hn : 1;
        C += 1 - pow5(1 - vh2);
    }
    return C;
}

/* One entry's GGX-distributed estimators (the half vector: pdf D n.h /
 * (4 v.h)) at column ndv of the row whose alpha^2 is a2 and whose half
 * vectors' cosines ct and sines st the row made. */
static void dfg_ab(float ndv, float a2, const double *ct, const double *st, double *A_, double *B_)
{
    double nv = ndv > 1e-4f ? ndv : 1e-4, v[3] = {sqrt(1 - nv * nv), 0, nv};
    double A = 0, B = 0;
    /* vt_brdf_v's view half, once an entry (its float operations) */
    const float fv = fabsf((float)nv), gv = fv + sqrtf(a2 + (1 - a2) * fv * fv);
    for (uint32_t i = 0; i < DFG_SAMPLES; i++) {
        double h[3] = {st[i] * dfg_cos[i], st[i] * dfg_sin[i], ct[i]};
        double vh = v[0] * h[0] + v[2] * h[2], lz = 2 * vh * h[2] - v[2];
        if (lz > 0 && vh > 0) {
            const float fl = fabsf((float)lz), gl = fl + sqrtf(a2 + (1 - a2) * fl * fl);
            double g = (1 / (gl * gv)) * lz * 4 * vh / ct[i], fc = pow5(1 - vh);
            A += (1 - fc) * g;
            B += fc * g;
        }
    }
    *A_ = A, *B_ = B;
}

/* The table: per roughness row its half vectors once, per n.v column the
 * cosine estimator once (the same sums as one entry at a time: ~4x
 * fewer square roots and divisions). */
static void dfg_make(void)
{
    for (uint32_t i = 0; i < DFG_SAMPLES; i++) {
        double ph = 2 * M_PI * radical_inverse(i);
        dfg_x1[i] = (i + 0.5) / DFG_SAMPLES;
        dfg_cos[i] = cos(ph);
        dfg_sin[i] = sin(ph);
    }
    double C[VT_DFG_N];
    for (uint32_t i = 0; i < VT_DFG_N; i++) C[i] = dfg_c((float)i / (VT_DFG_N - 1));
    static double ct[DFG_SAMPLES], st[DFG_SAMPLES];
    for (uint32_t j = 0; j < VT_DFG_N; j++) {
        float r = vt_brdf_rough((float)j / (VT_DFG_N - 1)), a = r * r, a2 = a * a;
        for (uint32_t k = 0; k < DFG_SAMPLES; k++) {
            double x1 = dfg_x1[k];
            ct[k] = sqrt((1 - x1) / (1 + (a2 - 1) * x1)), st[k] = sqrt(1 - ct[k] * ct[k]);
        }
        for (uint32_t i = 0; i < VT_DFG_N; i++) {
            double A, B;
            dfg_ab((float)i / (VT_DFG_N - 1), a2, ct, st, &A, &B);
            float *out = dfg + 4 * (j * VT_DFG_N + i);
            out[0] = (float)(A / DFG_SAMPLES);
            out[1] = (float)(B / DFG_SAMPLES);
            out[2] = (float)(C[i] / DFG_SAMPLES);
            out[3] = 0;
        }
    }
}

const float *vt_dfg_table(void)
{
    pthread_once(&dfg_once, dfg_make);
    return dfg;
}

static uint32_t dfg10[VT_DFG_N * VT_DFG_N];
static pthread_once_t dfg10_once = PTHREAD_ONCE_INIT;

static uint32_t unorm10(float v)
{
    return (uint32_t)(v > 0 ? (v < 1 ? v * 1023 + 0.5f : 1023) : 0);
}

static void dfg10_make(void)
{
    const float *t = vt_dfg_table();
    for (uint32_t i = 0; i < VT_DFG_N * VT_DFG_N; i++)
        dfg10[i] = unorm10(t[4 * i]) | unorm10(t[4 * i + 1]) << 10 | unorm10(t[4 * i + 2]) << 20;
}

const uint32_t *vt_dfg_table10(void)
{
    pthread_once(&dfg10_once, dfg10_make);
    return dfg10;
}

uint32_t vt_rgb_e5(const float c[3])
{
    const float top = 511.0f / 512 * (float)(1u << (31 - VT_E5_BIAS)); /* the largest value */
    float v[3];
    for (int k = 0; k < 3; k++) v[k] = c[k] > 0 ? (c[k] < top ? c[k] : top) : 0; /* NaN: 0 */
    float mx = v[0] > v[1] ? v[0] : v[1];
    mx = mx > v[2] ? mx : v[2];
    /* the exponent: 2^(e - bias - 9) a mantissa step, the largest channel's mantissa <= 511 */
    int e = mx > 0 ? ilogbf(mx) + 1 + VT_E5_BIAS : 0;
    e = e < 0 ? 0 : e;
    float step = ldexpf(1, e - VT_E5_BIAS - 9);
    if (floorf(mx / step + 0.5f) > 511) e++, step *= 2;
    if (e > 31) e = 31;
    uint32_t m[3];
    for (int k = 0; k < 3; k++) {
        float q = floorf(v[k] / step + 0.5f);
        m[k] = (uint32_t)(q < 511 ? q : 511);
    }
    return m[0] | m[1] << 9 | m[2] << 18 | (uint32_t)e << 27;
}

void vt_rgb_e5_decode(uint32_t t, float c[3])
{
    float step = ldexpf(1, (int)(t >> 27) - VT_E5_BIAS - 9);
    for (int k = 0; k < 3; k++) c[k] = (float)(t >> (9 * k) & 511) * step;
}

void vt_dfg(float ndv, float roughness, float out[3])
{
    /* grid points at 0 .. N - 1: texel units are value x (N - 1) */
    const float m = (float)(VT_DFG_N - 1);
    out[0] = out[1] = out[2] = 0;
    vt_bilerp_add(vt_dfg_table(), VT_DFG_N, (ndv > 0 ? (ndv < 1 ? ndv : 1) : 0) * m, vt_brdf_rough(roughness) * m, 1, out);
}

/* ---- the image-based ambient -------------------------------------------------------- */

void vt_oct_uv(const float d[3], float uv[2])
{
    float s = fabsf(d[0]) + fabsf(d[1]) + fabsf(d[2]);
    float px = s > 0 ? d[0] / s : 0, pz = s > 0 ? d[2] / s : 0;
    if (d[1] < 0) {
        float qx = (1 - fabsf(pz)) * (px < 0 ? -1 : 1), qz = (1 - fabsf(px)) * (pz < 0 ? -1 : 1);
        px = qx, pz = qz;
    }
    uv[0] = 0.5f * px + 0.5f;
    uv[1] = 0.5f * pz + 0.5f;
}

void vt_oct_dir(const float uv[2], float d[3])
{
    float px = 2 * uv[0] - 1, pz = 2 * uv[1] - 1, y = 1 - fabsf(px) - fabsf(pz);
    if (y < 0) {
        float qx = (1 - fabsf(pz)) * (px < 0 ? -1 : 1), qz = (1 - fabsf(px)) * (pz < 0 ? -1 : 1);
        px = qx, pz = qz;
    }
    float l = sqrtf(px * px + y * y + pz * pz);
    d[0] = px / l, d[1] = y / l, d[2] = pz / l;
}

void vt_ibl_env(const vt_penv *pe, const float d[3], float out[3])
{
    if (d[1] < 0 && pe->ground) {
        memcpy(out, pe->amb_down, 3 * sizeof *out);
        return;
    }
    vt_sky_radiance(pe, d, out);
    for (int c = 0; c < 3; c++) out[c] = isfinite(out[c]) && out[c] > 0 ? out[c] : 0;
}

/* Rows j0..j1 - 1 of the environment on a w x h equirectangular grid,
   each cell the mean of ss x ss directions: direction, radiance, exact
   solid angle, as 7 planes of w h floats at g (x, y, z, r, g, b, w). */
static void grid_rows(const vt_penv *pe, uint32_t w, uint32_t h, uint32_t ss, float *g, uint32_t j0, uint32_t j1)
{
    const size_t pl = (size_t)w * h;
    for (uint32_t j = j0; j < j1; j++) {
        double t0 = M_PI * j / h, t1 = M_PI * (j + 1) / h;
        float dw = (float)(2 * M_PI / w * (cos(t0) - cos(t1)));
        for (uint32_t i = 0; i < w; i++) {
            float L[3] = {0, 0, 0};
            for (uint32_t b = 0; b < ss; b++)
                for (uint32_t a = 0; a < ss; a++) {
                    float th = (float)M_PI * (j + (b + 0.5f) / ss) / h, ph = 2 * (float)M_PI * (i + (a + 0.5f) / ss) / w;
                    float d[3] = {sinf(th) * cosf(ph), cosf(th), sinf(th) * sinf(ph)}, e[3];
                    vt_ibl_env(pe, d, e);
                    for (int c = 0; c < 3; c++) L[c] += e[c] / (float)(ss * ss);
                }
            float th = (float)M_PI * (j + 0.5f) / h, ph = 2 * (float)M_PI * (i + 0.5f) / w;
            const size_t q = (size_t)j * w + i;
            g[q] = sinf(th) * cosf(ph), g[pl + q] = cosf(th), g[2 * pl + q] = sinf(th) * sinf(ph);
            g[3 * pl + q] = L[0], g[4 * pl + q] = L[1], g[5 * pl + q] = L[2], g[6 * pl + q] = dw;
        }
    }
}

/* The basis: {1, y, z, x, xy, yz, 3z^2 - 1, xz, x^2 - y^2} times these are
   the real spherical harmonics of bands 0..2. */
static const float sh_c[9] = {0.282095f, 0.488603f, 0.488603f, 0.488603f, 1.092548f,
                              1.092548f, 0.315392f, 1.092548f, 0.546274f};

static inline void sh_poly(const float n[3], float p[9])
{
    float x = n[0], y = n[1], z = n[2];
    p[0] = 1, p[1] = y, p[2] = z, p[3] = x;
    p[4] = x * y, p[5] = y * z, p[6] = 3 * z * z - 1, p[7] = x * z, p[8] = x * x - y * y;
}

/* Level 0's texel row j: the environment itself, 2 x 2 directions a texel. */
static void level0_row(vt_ibl *ibl, const vt_penv *pe, uint32_t j)
{
    for (uint32_t i = 0; i < VT_IBL_RES; i++) {
        float *o = ibl->spec[0] + 4 * (j * VT_IBL_RES + i);
        o[0] = o[1] = o[2] = 0, o[3] = 1;
        for (uint32_t b = 0; b < 2; b++)
            for (uint32_t a = 0; a < 2; a++) {
                float uv[2] = {(i + 0.25f + 0.5f * a) / VT_IBL_RES, (j + 0.25f + 0.5f * b) / VT_IBL_RES}, d[3], e[3];
                vt_oct_dir(uv, d);
                vt_ibl_env(pe, d, e);
                for (int c = 0; c < 3; c++) o[c] += 0.25f * e[c];
            }
        ibl->spec_e5[0][j * VT_IBL_RES + i] = vt_rgb_e5(o);
    }
}

/* Level lv >= 1's texel row j: the GGX lobe about r (n = v = r, so n.h^2
   = (1 + r.l) / 2 and the l-space density is D / 4), weighted by r.l;
   the narrowest (roughness 0.25: a lobe about 7 degrees wide) from the
   fine grid (5.6 degree cells), the others from the coarse one (11
   degrees; 0.5's lobe is 28). SSE2: four partial sums a texel, cells
   facing away weighing 0 (every t >= a2 > 0). */
static void lobe_row(vt_ibl *ibl, uint32_t lv, uint32_t j)
{
    const float r = vt_brdf_rough((float)lv / (VT_IBL_LEVELS - 1)), am = r * r * r * r - 1;
    const float *g = lv <= 1 ? &ibl->src_hi[0][0] : &ibl->src_lo[0][0];
    const uint32_t ng = lv <= 1 ? 64 * 32 : 32 * 16;
    const float *gx = g, *gy = g + ng, *gz = g + 2 * (size_t)ng, *gr = g + 3 * (size_t)ng, *gg = g + 4 * (size_t)ng,
                *gb = g + 5 * (size_t)ng, *gw = g + 6 * (size_t)ng;
    for (uint32_t i = 0; i < VT_IBL_RES; i++) {
        float uv[2] = {(i + 0.5f) / VT_IBL_RES, (j + 0.5f) / VT_IBL_RES}, R[3];
        vt_oct_dir(uv, R);
        float L[3] = {0, 0, 0}, Ws = 0;
#ifdef __SSE2__
        const __m128 rx = _mm_set1_ps(R[0]), ry = _mm_set1_ps(R[1]), rz = _mm_set1_ps(R[2]), va = _mm_set1_ps(am),
                     half = _mm_set1_ps(0.5f), one = _mm_set1_ps(1), zero = _mm_setzero_ps();
        __m128 s0 = zero, s1 = zero, s2 = zero, sw = zero;
        for (uint32_t k = 0; k < ng; k += 4) {
            /* maxps(c, 0): 0 for a NaN too */
            __m128 c = _mm_add_ps(_mm_add_ps(_mm_mul_ps(rx, _mm_loadu_ps(gx + k)), _mm_mul_ps(ry, _mm_loadu_ps(gy + k))),
                                  _mm_mul_ps(rz, _mm_loadu_ps(gz + k)));
            c = _mm_max_ps(c, zero);
            __m128 t = _mm_add_ps(_mm_mul_ps(_mm_mul_ps(half, _mm_add_ps(one, c)), va), one);
            __m128 w = _mm_div_ps(_mm_mul_ps(c, _mm_loadu_ps(gw + k)), _mm_mul_ps(t, t));
            s0 = _mm_add_ps(s0, _mm_mul_ps(w, _mm_loadu_ps(gr + k)));
            s1 = _mm_add_ps(s1, _mm_mul_ps(w, _mm_loadu_ps(gg + k)));
            s2 = _mm_add_ps(s2, _mm_mul_ps(w, _mm_loadu_ps(gb + k)));
            sw = _mm_add_ps(sw, w);
        }
        float f[4][4];
        _mm_storeu_ps(f[0], s0), _mm_storeu_ps(f[1], s1), _mm_storeu_ps(f[2], s2), _mm_storeu_ps(f[3], sw);
        for (int l = 0; l < 4; l++) L[0] += f[0][l], L[1] += f[1][l], L[2] += f[2][l], Ws += f[3][l];
#else
        for (uint32_t k = 0; k < ng; k++) {
            float c = R[0] * gx[k] + R[1] * gy[k] + R[2] * gz[k];
            if (!(c > 0)) continue;
            float t = 0.5f * (1 + c) * am + 1, w = c * gw[k] / (t * t);
            L[0] += w * gr[k], L[1] += w * gg[k], L[2] += w * gb[k], Ws += w;
        }
#endif
        float *o = ibl->spec[lv] + 4 * (j * VT_IBL_RES + i);
        for (int c = 0; c < 3; c++) o[c] = Ws > 0 ? L[c] / Ws : 0;
        o[3] = 1;
        ibl->spec_e5[lv][j * VT_IBL_RES + i] = vt_rgb_e5(o);
    }
}

/* A remake's parallel steps, taken by the pool's threads as they finish
   one (cull_pool_each): the fine grid's rows and level 0's, then the
   lobe levels' rows. */
typedef struct ibl_job {
    vt_ibl *ibl;
    const vt_penv *pe;
} ibl_job;

static void ibl_grid_step(void *arg, uint32_t k)
{
    ibl_job *j = arg;
    if (k < 32) grid_rows(j->pe, 64, 32, 4, &j->ibl->src_hi[0][0], k, k + 1);
    else level0_row(j->ibl, j->pe, k - 32);
}

static void ibl_lobe_step(void *arg, uint32_t k)
{
    ibl_job *j = arg;
    lobe_row(j->ibl, 1 + k / VT_IBL_RES, k % VT_IBL_RES);
}

bool vt_ibl_update(vt_ibl *ibl, const vt_penv *pe)
{
    return vt_ibl_update_pool(ibl, pe, NULL, 1);
}

bool vt_ibl_update_pool(vt_ibl *ibl, const vt_penv *pe, cull_pool *pool, uint32_t threads)
{
    float key[VT_IBL_KEY] = {pe->sky_mode, pe->sky[0], pe->sky[1], pe->sky[2], pe->sky_mul[0], pe->sky_mul[1],
                             pe->sky_mul[2], pe->sky_rot, pe->sun_dir[0], pe->sun_dir[1], pe->sun_dir[2],
                             pe->zenith[0], pe->zenith[1], pe->zenith[2], pe->perez[0][0], pe->perez[1][0],
                             pe->ground, pe->amb_down[0], pe->amb_down[1], pe->amb_down[2]};
    const void *img = pe->sky_img == &pe->sky_tab ? NULL : pe->sky_img; /* the table: its key is above */
    if (img) {
        memcpy(&key[20], &pe->sky_img->id, sizeof(float));
        memcpy(&key[21], &pe->sky_img->gen, sizeof(float));
    }
    ibl->dfg = vt_dfg_table();
    ibl->dfg10 = vt_dfg_table10();
    if (ibl->ok && ibl->key_img == img && !memcmp(key, ibl->key, sizeof key)) return false;
    memcpy(ibl->key, key, sizeof key);
    ibl->key_img = img;
    ibl->ok = true;
    ibl->gen++;
    ibl_job jb = {.ibl = ibl, .pe = pe};
    cull_pool_each(pool, threads, 32 + VT_IBL_RES, ibl_grid_step, &jb); /* the fine grid, level 0 */
    /* the low grid: 2 x 2 cells of the high one */
    const size_t ph = 64 * 32, pq = 32 * 16;
    const float *hi = &ibl->src_hi[0][0];
    float *lo = &ibl->src_lo[0][0];
    for (uint32_t j = 0; j < 16; j++)
        for (uint32_t i = 0; i < 32; i++) {
            float L[3] = {0, 0, 0}, w = 0;
            for (uint32_t b = 0; b < 2; b++)
                for (uint32_t a = 0; a < 2; a++) {
                    const size_t q = (size_t)(2 * j + b) * 64 + 2 * i + a;
                    for (int c = 0; c < 3; c++) L[c] += hi[(3 + c) * ph + q] * hi[6 * ph + q];
                    w += hi[6 * ph + q];
                }
            float th = (float)M_PI * (j + 0.5f) / 16, phi = 2 * (float)M_PI * (i + 0.5f) / 32;
            const size_t q = (size_t)j * 32 + i;
            lo[q] = sinf(th) * cosf(phi), lo[pq + q] = cosf(th), lo[2 * pq + q] = sinf(th) * sinf(phi);
            for (int c = 0; c < 3; c++) lo[(3 + c) * pq + q] = L[c] / w;
            lo[6 * pq + q] = w;
        }
    /* irradiance: the projection, times Ramamoorthi and Hanrahan's band
       factors pi, 2 pi / 3, pi / 4, over pi */
    static const float band[9] = {1, 2.0f / 3, 2.0f / 3, 2.0f / 3, 0.25f, 0.25f, 0.25f, 0.25f, 0.25f};
    double acc[9][3] = {{0}};
    for (uint32_t k = 0; k < 64 * 32; k++) {
        const float n[3] = {hi[k], hi[ph + k], hi[2 * ph + k]};
        float p[9];
        sh_poly(n, p);
        for (int i = 0; i < 9; i++)
            for (int c = 0; c < 3; c++) acc[i][c] += (double)hi[(3 + c) * ph + k] * hi[6 * ph + k] * sh_c[i] * p[i];
    }
    for (int i = 0; i < 9; i++)
        for (int c = 0; c < 3; c++) ibl->sh[i][c] = (float)acc[i][c] * sh_c[i] * band[i];
    cull_pool_each(pool, threads, (VT_IBL_LEVELS - 1) * VT_IBL_RES, ibl_lobe_step, &jb); /* the rougher levels */
    return true;
}

/* ibl's entry of roughness r (vt_brdf_rough's) asked for by this frame:
 * found, or made in a free slot or one no frame asked for since. */
static void rough_entry(vt_ibl *ibl, float r)
{
    int k = vt_ibl_rough_find(ibl, r);
    if (k < 0) {
        for (uint32_t q = 0; q < ibl->nr && k < 0; q++)
            if (ibl->rused[q] != ibl->rframe) k = (int)q;
        if (k < 0 && ibl->nr == VT_IBL_NR) return; /* all taken this frame: the levels */
        if (k < 0) k = (int)ibl->nr++;
        /* the levels' blend as vt_ibl_specular takes it */
        float f = r * (VT_IBL_LEVELS - 1);
        uint32_t lv = (uint32_t)f < VT_IBL_LEVELS - 2 ? (uint32_t)f : VT_IBL_LEVELS - 2;
        float t = f - (float)lv;
        for (uint32_t i = 0; i < VT_IBL_RES * VT_IBL_RES; i++) {
            const float *a = ibl->spec[lv] + 4 * i, *b = ibl->spec[lv + 1] + 4 * i;
            float c[3] = {a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]), a[2] + t * (b[2] - a[2])};
            ibl->rspec[k][i] = vt_rgb_e5(c);
        }
        /* the DFG table's row at r, as vt_dfg reads it */
        const float *dt = vt_dfg_table(), m = (float)(VT_DFG_N - 1), y = (r < 1 ? r : 1) * m;
        uint32_t j = (uint32_t)y < VT_DFG_N - 2 ? (uint32_t)y : VT_DFG_N - 2;
        float ay = y - (float)j;
        for (uint32_t i = 0; i < VT_DFG_N; i++) {
            const float *a = dt + 4 * (j * VT_DFG_N + i), *b = a + 4 * VT_DFG_N;
            uint32_t v = 0;
            for (int c = 0; c < 3; c++) v |= unorm10(a[c] + ay * (b[c] - a[c])) << 10 * c;
            ibl->rdfg[k][i] = v;
        }
        ibl->rough[k] = r;
    }
    ibl->rused[k] = ibl->rframe;
}

void vt_ibl_rough_frame(vt_ibl *ibl, const vt_instance *inst, uint32_t ninst, const vt_material *ground)
{
    if (ibl->rgen != ibl->gen) ibl->nr = 0, ibl->rgen = ibl->gen; /* a new sky: new blends */
    ibl->rframe++;
    const vt_material *last = NULL;
    bool dflt = false;
    for (uint32_t i = 0; i <= ninst; i++) {
        const vt_material *m = i < ninst ? inst[i].mat : ground;
        if (m && (m == last || m->tex[VT_SLOT_MR].tex)) continue; /* instances of one material come in runs */
        if (!m && dflt) continue;
        last = m;
        dflt |= !m;
        rough_entry(ibl, vt_brdf_rough(m ? m->roughness : VT_DEFAULT_ROUGHNESS));
    }
}

void vt_ibl_irradiance(const vt_ibl *ibl, const float n[3], float out[3])
{
    float p[9];
    sh_poly(n, p);
    for (int c = 0; c < 3; c++) {
        float e = 0;
        for (int i = 0; i < 9; i++) e += ibl->sh[i][c] * p[i];
        out[c] = e > 0 ? e : 0;
    }
}

void vt_ibl_specular(const vt_ibl *ibl, const float r[3], float roughness, float out[3])
{
    float uv[2], f = vt_brdf_rough(roughness) * (VT_IBL_LEVELS - 1);
    uint32_t k = (uint32_t)f < VT_IBL_LEVELS - 2 ? (uint32_t)f : VT_IBL_LEVELS - 2;
    float t = f - (float)k;
    vt_oct_uv(r, uv);
    if (!(uv[0] >= 0 && uv[0] <= 1 && uv[1] >= 0 && uv[1] <= 1)) uv[0] = uv[1] = 0.5f; /* NaN: straight up */
    out[0] = out[1] = out[2] = 0;
    float x = uv[0] * VT_IBL_RES - 0.5f, y = uv[1] * VT_IBL_RES - 0.5f;
    vt_bilerp_add(ibl->spec[k], VT_IBL_RES, x, y, 1 - t, out);
    vt_bilerp_add(ibl->spec[k + 1], VT_IBL_RES, x, y, t, out);
}
