/*
 * vt_raster.c — the visibility buffer's row kernels (see vt_raster.h):
 * one pixel at a time (any CPU, the reference), and 8 at a time with AVX2.
 *
 * Why 8 lanes of doubles: a pixel's nearness is a plane evaluated in
 * double and rounded once to float (set-up's planes are solved in double;
 * a float plane would move the depth test's ties). Two 4-double vectors
 * per 8 pixels cost a multiply, an add and a conversion each, against the
 * ~7 instructions a pixel of the scalar loop; the compare and the two
 * stores are one of each for 8 pixels (a run shorter than a vector, or
 * its tail, takes a vector ending at its last pixel, lanes outside the
 * run masked: the row's other pixels are rewritten unchanged, and the
 * caller owns the whole row).
 */
#include "vt_raster.h"
#include "culling.h"
#include "vt_shade.h"

#include <math.h>
#include <string.h>

#if !defined(CULL_SCALAR_ONLY) && (defined(__x86_64__) || defined(__i386__))
#define VT_RASTER_AVX2 1
#include <immintrin.h>
#endif

/* ---- one pixel at a time --------------------------------------------------------- */

static void span_scalar(float *nrow, uint32_t *irow, int32_t i0, int32_t i1, uint32_t w, double na, double nz,
                        uint32_t id)
{
    (void)w;
    for (int32_t i = i0; i <= i1; i++) {
        float z = (float)(na * (i + 0.5) + nz);
        if (z > nrow[i]) {
            nrow[i] = z;
            irow[i] = id;
        }
    }
}

static void ground_scalar(float *nrow, uint32_t *irow, int32_t i0, int32_t i1, const double *X, const vt_ground *g,
                          double Y, bool sure)
{
    (void)sure; /* the full test gives the same answer there */
    for (int32_t x = i0; x <= i1; x++) {
        double nz;
        if (!vt_ground_at(g, X[x], Y, &nz)) continue;
        float z = (float)nz;
        if (z > nrow[x]) {
            nrow[x] = z;
            irow[x] = VT_ID_GROUND;
        }
    }
}

static void clear_scalar(float *near, uint32_t *id, size_t n)
{
    for (size_t i = 0; i < n; i++) near[i] = VT_EMPTY;
    memset(id, 0, n * sizeof *id);
}

static float tmin_scalar(const float *near, size_t ys, uint32_t cols, uint32_t rows)
{
    float m = INFINITY;
    for (uint32_t y = 0; y < rows; y++)
        for (uint32_t x = 0; x < cols; x++) m = near[y * ys + x] < m ? near[y * ys + x] : m;
    return m;
}

vt_rkern vt_rkern_scalar(void)
{
    return (vt_rkern){span_scalar, ground_scalar, clear_scalar, tmin_scalar};
}

/* ---- AVX2: 8 pixels a step ---------------------------------------------------------- */

#ifdef VT_RASTER_AVX2
/* AVX2 without FMA: no multiply-add may fuse (the bits must be the
   scalar reference's) */
#define AVX2_FN __attribute__((target("avx2")))

/* Lanes k of the 8 pixels from column s with i0 <= s + k <= i1. */
AVX2_FN static inline __m256 lanes_in(int32_t s, int32_t i0, int32_t i1)
{
    __m256i k = _mm256_add_epi32(_mm256_set1_epi32(s), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7));
    __m256i lo = _mm256_cmpgt_epi32(_mm256_set1_epi32(i0), k), hi = _mm256_cmpgt_epi32(k, _mm256_set1_epi32(i1));
    return _mm256_castsi256_ps(_mm256_andnot_si256(_mm256_or_si256(lo, hi), _mm256_set1_epi32(-1)));
}

/* The 8 pixels from column s: z where it is nearer and the lane is in m. */
AVX2_FN static inline void keep8(float *nrow, uint32_t *irow, int32_t s, __m256 z, __m256 m, __m256 id)
{
    __m256 old = _mm256_loadu_ps(nrow + s);
    m = _mm256_and_ps(m, _mm256_cmp_ps(z, old, _CMP_GT_OQ));
    _mm256_storeu_ps(nrow + s, _mm256_blendv_ps(old, z, m));
    __m256 oid = _mm256_loadu_ps((const float *)(irow + s));
    _mm256_storeu_ps((float *)(irow + s), _mm256_blendv_ps(oid, id, m));
}

/* The nearness of the 8 pixels from column s: na (i + 0.5) + nz per lane,
 * in double (i + 0.5 is exact), rounded to float. */
AVX2_FN static inline __m256 plane8(int32_t s, __m256d na, __m256d nz)
{
    __m256d x0 = _mm256_add_pd(_mm256_set1_pd((double)s), _mm256_setr_pd(0.5, 1.5, 2.5, 3.5));
    __m256d x1 = _mm256_add_pd(x0, _mm256_set1_pd(4.0));
    __m128 a = _mm256_cvtpd_ps(_mm256_add_pd(_mm256_mul_pd(na, x0), nz));
    __m128 b = _mm256_cvtpd_ps(_mm256_add_pd(_mm256_mul_pd(na, x1), nz));
    return _mm256_set_m128(b, a);
}

AVX2_FN static void span_avx2(float *nrow, uint32_t *irow, int32_t i0, int32_t i1, uint32_t w, double na, double nz,
                              uint32_t id)
{
    if (w < 8) {
        span_scalar(nrow, irow, i0, i1, w, na, nz, id);
        return;
    }
    const __m256d vna = _mm256_set1_pd(na), vnz = _mm256_set1_pd(nz);
    const __m256 vid = _mm256_castsi256_ps(_mm256_set1_epi32((int)id)), all = _mm256_castsi256_ps(_mm256_set1_epi32(-1));
    int32_t i = i0;
    for (; i + 7 <= i1; i += 8) keep8(nrow, irow, i, plane8(i, vna, vnz), all, vid);
    if (i > i1) return;
    /* the rest (1..7 pixels): the vector ending at i1, or the row's first */
    int32_t s = i1 - 7 < 0 ? 0 : i1 - 7;
    keep8(nrow, irow, s, plane8(s, vna, vnz), lanes_in(s, i, i1), vid);
}

/* vt_ground_at over columns [i0, i1], 8 at a time: the same operations in
 * the same order (n1 Y and l1 Y are the same products for the whole row).
 * sure: every column hits (vt_ground_row's inner run): only the nearness. */
AVX2_FN static void ground_avx2(float *nrow, uint32_t *irow, int32_t i0, int32_t i1, const double *X, const vt_ground *g,
                                double Y, bool sure)
{
    if (i1 - i0 < 7 || !g->on) { /* the scalar loop needs no vector of 8 inside the row */
        ground_scalar(nrow, irow, i0, i1, X, g, Y, sure);
        return;
    }
    const __m256 vid = _mm256_castsi256_ps(_mm256_set1_epi32((int)VT_ID_GROUND));
    const __m256d n0 = _mm256_set1_pd(g->n[0]), n1y = _mm256_set1_pd(g->n[1] * Y), n2 = _mm256_set1_pd(g->n[2]);
    const __m256d zero = _mm256_setzero_pd();
    const __m256d pm = g->persp ? zero : _mm256_castsi256_pd(_mm256_set1_epi64x(-1));
    __m256d l0[2], l1y[2], l2[2], l3[2];
    for (int k = 0; k < 2; k++) {
        l0[k] = _mm256_set1_pd(g->lim[k][0]);
        l1y[k] = _mm256_set1_pd(g->lim[k][1] * Y);
        l2[k] = _mm256_set1_pd(g->lim[k][2]);
        l3[k] = _mm256_set1_pd(g->lim[k][3]);
    }
    for (int32_t i = i0;; i += 8) {
        /* the last step: the 8 columns ending at i1, those before i masked */
        int32_t s = i + 7 <= i1 ? i : i1 - 7;
        __m256d N[2], ok[2];
        for (int h = 0; h < 2; h++) {
            __m256d x = _mm256_loadu_pd(X + s + 4 * h);
            __m256d n = _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(n0, x), n1y), n2);
            N[h] = n;
            if (sure) continue;
            __m256d m = _mm256_or_pd(pm, _mm256_cmp_pd(n, zero, _CMP_GT_OQ));
            for (int k = 0; k < 2; k++) {
                __m256d f = _mm256_add_pd(_mm256_mul_pd(l0[k], x), l1y[k]);
                f = _mm256_add_pd(_mm256_add_pd(f, _mm256_mul_pd(l2[k], n)), l3[k]);
                m = _mm256_and_pd(m, _mm256_cmp_pd(f, zero, _CMP_GE_OQ));
            }
            ok[h] = m;
        }
        __m256 z = _mm256_set_m128(_mm256_cvtpd_ps(N[1]), _mm256_cvtpd_ps(N[0]));
        __m256 m = s == i ? _mm256_castsi256_ps(_mm256_set1_epi32(-1)) : lanes_in(s, i, i1);
        if (!sure) {
            /* the two 4-lane double masks as one 8-lane float mask: an
               all-ones double is a NaN, and converts to a NaN float */
            __m256 mm = _mm256_set_m128(_mm256_cvtpd_ps(ok[1]), _mm256_cvtpd_ps(ok[0]));
            m = _mm256_and_ps(m, _mm256_cmp_ps(mm, mm, _CMP_UNORD_Q));
        }
        keep8(nrow, irow, s, z, m, vid);
        if (s + 7 >= i1) return;
    }
}

AVX2_FN static float tmin_avx2(const float *near, size_t ys, uint32_t cols, uint32_t rows)
{
    if (cols != 16) return tmin_scalar(near, ys, cols, rows);
    __m256 a = _mm256_set1_ps(INFINITY), b = a;
    for (uint32_t y = 0; y < rows; y++) {
        a = _mm256_min_ps(a, _mm256_loadu_ps(near + y * ys));
        b = _mm256_min_ps(b, _mm256_loadu_ps(near + y * ys + 8));
    }
    a = _mm256_min_ps(a, b);
    __m128 m = _mm_min_ps(_mm256_castps256_ps128(a), _mm256_extractf128_ps(a, 1));
    m = _mm_min_ps(m, _mm_movehl_ps(m, m));
    m = _mm_min_ss(m, _mm_shuffle_ps(m, m, 1));
    return _mm_cvtss_f32(m);
}

AVX2_FN static void clear_avx2(float *near, uint32_t *id, size_t n)
{
    const __m256 e = _mm256_set1_ps(VT_EMPTY);
    const __m256i z = _mm256_setzero_si256();
    size_t i = 0;
    for (; i + 8 <= n; i += 8) {
        _mm256_storeu_ps(near + i, e);
        _mm256_storeu_si256((__m256i *)(id + i), z);
    }
    clear_scalar(near + i, id + i, n - i);
}
#endif

vt_rkern vt_rkern_pick(void)
{
#ifdef VT_RASTER_AVX2
    if (cull_isa_default() == CULL_ISA_AVX2) return (vt_rkern){span_avx2, ground_avx2, clear_avx2, tmin_avx2};
#endif
    return vt_rkern_scalar();
}

/* ---- the ground's row ------------------------------------------------------------- */

/* Narrows [*lo, *hi] (in NDC X) to where f(X) = a X + b >= t can hold
 * (unknown: kept, or emptied when sure). */
static bool narrow(double a, double b, double t, bool sure, double *lo, double *hi)
{
    if (!isfinite(a) || !isfinite(b) || !isfinite(t)) return !sure;
    if (a == 0) return b >= t;
    double x = (t - b) / a;
    if (a > 0) *lo = x > *lo ? x : *lo;
    else *hi = x < *hi ? x : *hi;
    return *lo <= *hi;
}

bool vt_ground_row(const vt_ground *g, double Y, uint32_t w, int32_t c[4])
{
    if (!g->on || !w) return false;
    /* along the row, N = n0 X + k and lim_j = (l0 + l2 n0) X + (l1 Y + l2 k
       + l3): affine in X. A pixel's computed values differ from these by
       a few ulps of the terms' magnitude (|X| <= 1 on the view), far below
       tol, 1e-9 of it; its X, rounded to float, is within 1e-7 of the
       column's, far below the column added on each side. */
    double k = g->n[1] * Y + g->n[2];
    double magN = fabs(g->n[0]) + fabs(g->n[1] * Y) + fabs(g->n[2]);
    double a[3], b[3], tol[3];
    int nf = 0;
    if (g->persp) {
        a[nf] = g->n[0], b[nf] = k, tol[nf++] = 1e-9 * magN;
    }
    for (int j = 0; j < 2; j++) {
        const double *l = g->lim[j];
        a[nf] = l[0] + l[2] * g->n[0], b[nf] = l[1] * Y + l[2] * k + l[3];
        tol[nf++] = 1e-9 * (fabs(l[0]) + fabs(l[1] * Y) + fabs(l[2]) * magN + fabs(l[3]));
    }
    double lo = -1, hi = 1, slo = -1, shi = 1;
    bool in = true;
    for (int f = 0; f < nf; f++) {
        if (!narrow(a[f], b[f], -tol[f], false, &lo, &hi)) return false;
        in = in && narrow(a[f], b[f], tol[f], true, &slo, &shi);
    }
    /* NDC X to columns (X = (i + 0.5) 2 / w - 1) */
    double c0 = floor((lo + 1) * 0.5 * w - 0.5) - 1, c3 = ceil((hi + 1) * 0.5 * w - 0.5) + 1;
    if (!(c0 <= c3) || c3 < 0 || c0 > (double)w - 1) return false;
    c[0] = c0 < 0 ? 0 : (int32_t)c0;
    c[3] = c3 > (double)w - 1 ? (int32_t)w - 1 : (int32_t)c3;
    double c1 = ceil((slo + 1) * 0.5 * w - 0.5) + 1, c2 = floor((shi + 1) * 0.5 * w - 0.5) - 1;
    if (!in || !(c1 <= c2) || c2 < c[0] || c1 > c[3]) { /* no sure run */
        c[1] = c[3] + 1;
        c[2] = c[3];
        return true;
    }
    c[1] = c1 < c[0] ? c[0] : (int32_t)c1;
    c[2] = c2 > c[3] ? c[3] : (int32_t)c2;
    return true;
}

/* The NDC x of each column (vt_ndc_x, as a double). */
void vt_ndc_row(uint32_t w, double *X)
{
    double inv_w = 2.0 / w;
    for (uint32_t x = 0; x < w; x++) X[x] = vt_ndc_x(x, inv_w);
}
