/*
 * vt_tonemap_avx2.c — the daemon's tone map (ACES to sRGB8, interleaved
 * RGBX floats) 8 pixels a step. Compiled with -mavx2; called only after
 * CPUID says AVX2 is there (vt_tonemap.c). The scalar path's operations,
 * so its codes exactly: the exposure's product in double, the clamp to
 * [2^-12, 16) (max first: NaN becomes 2^-12, code 0), then one gathered
 * bucket entry and one integer comparison (vt_tonemap_kern.h). About 9
 * instructions a pixel against the SSE2 row's ~60 (the per-channel
 * threshold loop).
 */
#include "vt_tonemap_kern.h"

#include <stddef.h>

#if defined(__AVX2__)
#include <immintrin.h>

/* 8 floats (2 pixels) -> their 8 codes as 32-bit lanes */
static inline __m256i codes8(__m256 v, const uint32_t *tab, __m256d k, int scaled)
{
    if (scaled) {
        __m128 lo = _mm256_castps256_ps128(v), hi = _mm256_extractf128_ps(v, 1);
        __m128 a = _mm256_cvtpd_ps(_mm256_mul_pd(_mm256_cvtps_pd(lo), k));
        __m128 b = _mm256_cvtpd_ps(_mm256_mul_pd(_mm256_cvtps_pd(hi), k));
        v = _mm256_insertf128_ps(_mm256_castps128_ps256(a), b, 1);
    }
    v = _mm256_min_ps(_mm256_max_ps(v, _mm256_set1_ps(0x1p-12f)), _mm256_set1_ps(0x1.fffffep3f));
    __m256i d = _mm256_sub_epi32(_mm256_castps_si256(v), _mm256_set1_epi32((int)VT_ACES_LO_BITS));
    __m256i e = _mm256_i32gather_epi32((const int *)tab, _mm256_srli_epi32(d, 15), 4);
    __m256i off = _mm256_and_si256(d, _mm256_set1_epi32(0x7fff));
    __m256i before = _mm256_cmpgt_epi32(_mm256_and_si256(e, _mm256_set1_epi32(0xffff)), off); /* -1: below */
    return _mm256_add_epi32(_mm256_srli_epi32(e, 16), before); /* the fourth float's: alpha, set after */
}

static void aces_rgbx(const float *p, uint32_t n, double scale, const uint32_t *tab, uint8_t *o)
{
    const __m256d k = _mm256_set1_pd(scale);
    const int scaled = scale != 1.0; /* x * 1.0 in double is x: skipped */
    const __m256i order = _mm256_setr_epi32(0, 4, 1, 5, 2, 6, 3, 7), alpha = _mm256_set1_epi32((int)0xff000000u);
    for (uint32_t x = 0; x < n; x += 8, p += 32, o += 32) {
        /* 1 KiB ahead (a prefetch past the row's end is harmless): the
           hardware's stream prefetch stops at each 4 KiB page */
        _mm_prefetch((const char *)(p + 256), _MM_HINT_T0);
        _mm_prefetch((const char *)(p + 272), _MM_HINT_T0);
        __m256i a = codes8(_mm256_loadu_ps(p), tab, k, scaled), b = codes8(_mm256_loadu_ps(p + 8), tab, k, scaled);
        __m256i c = codes8(_mm256_loadu_ps(p + 16), tab, k, scaled), d = codes8(_mm256_loadu_ps(p + 24), tab, k, scaled);
        /* packs work within 128-bit halves: pixels come out 0 2 4 6 1 3 5 7 */
        __m256i q = _mm256_packus_epi16(_mm256_packus_epi32(a, b), _mm256_packus_epi32(c, d));
        _mm256_storeu_si256((__m256i *)o, _mm256_or_si256(_mm256_permutevar8x32_epi32(q, order), alpha));
    }
}

vt_aces_rgbx_fn vt_aces_rgbx_avx2(void)
{
    return aces_rgbx;
}
#else
vt_aces_rgbx_fn vt_aces_rgbx_avx2(void)
{
    return NULL;
}
#endif
