/*
 * vt_post_avx2.c — the post passes' rows 8 pixels a step (vt_post_kern.h):
 * the exposure histogram, FXAA's exposure + luma pass and its early exit.
 * Compiled with -mavx2 -mfma (no FMA used: the scalar rows' operations in
 * their order, so the same bits); called only after CPUID says AVX2 is
 * there (vt_post.c). Loads are contiguous: 8 RGBA pixels are 4 registers,
 * the luminance's sums come from horizontal adds (a histogram does not
 * care which lane a pixel lands in), the luma's from an 8x4 transpose.
 */
#include "vt_post_kern.h"

#if defined(__AVX2__)
#include <immintrin.h>

/* 0.2126 R + 0.7152 G + 0.0722 B of 8 pixels (a..d: 2 each), summed as
 * the scalar lum does: (r' + g') + (b' + 0), alpha's product forced to 0
 * (its value, NaN or inf, never counts). Lanes in pixel order 0 2 1 3 4 6
 * 5 7 (hadd's), which binning ignores. */
static inline __m256 lum8(__m256 a, __m256 b, __m256 c, __m256 d)
{
    const __m256 wt = _mm256_setr_ps(0.2126f, 0.7152f, 0.0722f, 0, 0.2126f, 0.7152f, 0.0722f, 0);
    a = _mm256_mul_ps(_mm256_blend_ps(a, _mm256_setzero_ps(), 0x88), wt);
    b = _mm256_mul_ps(_mm256_blend_ps(b, _mm256_setzero_ps(), 0x88), wt);
    c = _mm256_mul_ps(_mm256_blend_ps(c, _mm256_setzero_ps(), 0x88), wt);
    d = _mm256_mul_ps(_mm256_blend_ps(d, _mm256_setzero_ps(), 0x88), wt);
    return _mm256_hadd_ps(_mm256_hadd_ps(a, b), _mm256_hadd_ps(c, d));
}

static uint32_t hist_row(const float *p, uint32_t n, const uint32_t q[3], uint32_t (*hb)[VT_HIST_BINS])
{
    const __m256i top = _mm256_set1_epi32(VT_HIST_BINS - 1), mant = _mm256_set1_epi32(0x7fffff);
    const __m256i q0 = _mm256_set1_epi32((int)q[0] - 1), q1 = _mm256_set1_epi32((int)q[1] - 1);
    const __m256i q2 = _mm256_set1_epi32((int)q[2] - 1), bias = _mm256_set1_epi32(127 + VT_HIST_LO);
    uint32_t x = 0;
    for (; x + 8 <= n; x += 8, p += 32) {
        __m256 L = lum8(_mm256_loadu_ps(p), _mm256_loadu_ps(p + 8), _mm256_loadu_ps(p + 16), _mm256_loadu_ps(p + 24));
        __m256i bits = _mm256_castps_si256(L), m = _mm256_and_si256(bits, mant);
        __m256i e4 = _mm256_slli_epi32(_mm256_sub_epi32(_mm256_srli_epi32(bits, 23), bias), 2);
        /* m >= q: m > q - 1, -1 a lane, subtracted (vt_post.c's bin4) */
        e4 = _mm256_sub_epi32(e4, _mm256_cmpgt_epi32(m, q0));
        e4 = _mm256_sub_epi32(e4, _mm256_cmpgt_epi32(m, q1));
        e4 = _mm256_sub_epi32(e4, _mm256_cmpgt_epi32(m, q2));
        e4 = _mm256_min_epi32(e4, top); /* in range here: e4 >= 0 where L > 2^-16 */
        __m256i hi = _mm256_castps_si256(_mm256_cmp_ps(L, _mm256_set1_ps(0x1p16f), _CMP_LT_OQ)); /* NaN, inf: no */
        __m256i lo = _mm256_castps_si256(_mm256_cmp_ps(L, _mm256_set1_ps(0x1p-16f), _CMP_GT_OQ));
        e4 = _mm256_blendv_epi8(top, e4, hi);
        e4 = _mm256_and_si256(lo, e4); /* not above 2^-16 (NaN too): 0 */
        uint32_t o[8];
        _mm256_storeu_si256((__m256i *)o, e4);
        hb[0][o[0]]++, hb[1][o[1]]++, hb[2][o[2]]++, hb[3][o[3]]++;
        hb[0][o[4]]++, hb[1][o[5]]++, hb[2][o[6]]++, hb[3][o[7]]++;
    }
    return x;
}

static uint32_t prep_row(float *p, uint32_t n, float s, float *l)
{
    const __m256 sc = _mm256_setr_ps(s, s, s, 1, s, s, s, 1), zero = _mm256_setzero_ps(), big = _mm256_set1_ps(1e6f);
    const __m256i order = _mm256_setr_epi32(0, 4, 1, 5, 2, 6, 3, 7);
    uint32_t x = 0;
    for (; x + 8 <= n; x += 8, p += 32, l += 8) {
        __m256 a = _mm256_mul_ps(_mm256_loadu_ps(p), sc), b = _mm256_mul_ps(_mm256_loadu_ps(p + 8), sc);
        __m256 c = _mm256_mul_ps(_mm256_loadu_ps(p + 16), sc), d = _mm256_mul_ps(_mm256_loadu_ps(p + 24), sc);
        _mm256_storeu_ps(p, a);
        _mm256_storeu_ps(p + 8, b);
        _mm256_storeu_ps(p + 16, c);
        _mm256_storeu_ps(p + 24, d);
        /* to planes, pixels 0 2 4 6 1 3 5 7 (unpack and shuffle stay in halves) */
        __m256 t0 = _mm256_unpacklo_ps(a, b), t1 = _mm256_unpackhi_ps(a, b);
        __m256 t2 = _mm256_unpacklo_ps(c, d), t3 = _mm256_unpackhi_ps(c, d);
        __m256 r = _mm256_shuffle_ps(t0, t2, 0x44), g = _mm256_shuffle_ps(t0, t2, 0xee);
        __m256 bl = _mm256_shuffle_ps(t1, t3, 0x44);
        /* max(x, 0) gives 0 for NaN (the second operand), as p > 0 ? .. : 0 */
        r = _mm256_min_ps(_mm256_max_ps(r, zero), big);
        g = _mm256_min_ps(_mm256_max_ps(g, zero), big);
        bl = _mm256_min_ps(_mm256_max_ps(bl, zero), big);
        __m256 k = _mm256_div_ps(_mm256_set1_ps(1), _mm256_add_ps(_mm256_set1_ps(1), _mm256_max_ps(_mm256_max_ps(r, g), bl)));
        __m256 y = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(_mm256_set1_ps(0.2126f), _mm256_mul_ps(r, k)),
                                               _mm256_mul_ps(_mm256_set1_ps(0.7152f), _mm256_mul_ps(g, k))),
                                 _mm256_mul_ps(_mm256_set1_ps(0.0722f), _mm256_mul_ps(bl, k)));
        _mm256_storeu_ps(l, _mm256_permutevar8x32_ps(_mm256_sqrt_ps(y), order));
    }
    return x;
}

static uint32_t edge8(const float *L, size_t m, size_t w)
{
    __m256 M = _mm256_loadu_ps(L + m), N = _mm256_loadu_ps(L + m - w), S = _mm256_loadu_ps(L + m + w);
    __m256 E = _mm256_loadu_ps(L + m + 1), Wl = _mm256_loadu_ps(L + m - 1);
    __m256 hi = _mm256_max_ps(_mm256_max_ps(_mm256_max_ps(M, N), _mm256_max_ps(S, E)), Wl);
    __m256 lo = _mm256_min_ps(_mm256_min_ps(_mm256_min_ps(M, N), _mm256_min_ps(S, E)), Wl);
    __m256 th = _mm256_max_ps(_mm256_set1_ps(VT_FX_EDGE_MIN), _mm256_mul_ps(hi, _mm256_set1_ps(VT_FX_EDGE)));
    return (uint32_t)_mm256_movemask_ps(_mm256_cmp_ps(_mm256_sub_ps(hi, lo), th, _CMP_GE_OQ));
}

vt_post_kern vt_post_kern_avx2(void)
{
    return (vt_post_kern){hist_row, prep_row, edge8};
}
#else
vt_post_kern vt_post_kern_avx2(void)
{
    return (vt_post_kern){0};
}
#endif
