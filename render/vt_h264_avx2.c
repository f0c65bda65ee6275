/*
 * vt_h264_avx2.c — the RGB -> I420 conversion (vt_h264_kern.h) 16 pixels
 * of a row pair a step. Compiled with -mavx2; called only after CPUID says
 * AVX2 is there (vt_h264.c). The scalar rows' integer sums exactly: a
 * pixel is a 32-bit lane, R and B in its two 16-bit halves after a mask,
 * G (and the ignored A) after a 16-bit shift, so pmaddwd multiplies and
 * adds two channels at once into the scalar path's 32-bit sums (luma's G
 * coefficient, over 2^15, as (G << 15) + G (CY_G - 2^15)). Chroma is
 * computed at every column and the even ones kept: simpler than
 * deinterleaving, and the loads are from cache.
 */
#include "vt_h264_kern.h"

#include <stddef.h>

#if defined(__AVX2__)
#include <immintrin.h>

#define PAIR(lo, hi) ((int)(((uint32_t)(uint16_t)(int16_t)(hi) << 16) | (uint16_t)(int16_t)(lo)))

/* 8 pixels -> their 8 luma values in 32-bit lanes */
static inline __m256i luma8(__m256i px)
{
    const __m256i m = _mm256_set1_epi32(0x00ff00ff), k_rb = _mm256_set1_epi32(PAIR(VT_H264_CY_R, VT_H264_CY_B));
    const __m256i k_g = _mm256_set1_epi32(PAIR(VT_H264_CY_G - 32768, 0));
    __m256i rb = _mm256_and_si256(px, m), ga = _mm256_srli_epi16(px, 8);
    __m256i g15 = _mm256_slli_epi32(_mm256_and_si256(ga, _mm256_set1_epi32(0xffff)), 15);
    __m256i s = _mm256_add_epi32(_mm256_add_epi32(_mm256_madd_epi16(rb, k_rb), _mm256_madd_epi16(ga, k_g)), g15);
    return _mm256_srli_epi32(_mm256_add_epi32(s, _mm256_set1_epi32(VT_H264_Y_ADD)), 16);
}

/* 16 luma values (two vectors of 8 in 32-bit lanes) to 16 bytes */
static inline __m128i bytes16(__m256i a, __m256i b)
{
    __m256i w = _mm256_permute4x64_epi64(_mm256_packus_epi32(a, b), 0xd8); /* a0..7 b0..7 as u16 */
    return _mm_packus_epi16(_mm256_castsi256_si128(w), _mm256_extracti128_si256(w, 1));
}

/* The [1 2 1] sums of 8 columns of one row at p (pixel -1 and 8 readable),
 * R + B (16-bit halves) and G + A, added into *rb and *ga */
static inline void sums8(const uint8_t *p, __m256i *rb, __m256i *ga)
{
    const __m256i m = _mm256_set1_epi32(0x00ff00ff);
    __m256i l = _mm256_loadu_si256((const __m256i *)(p - 4)), c = _mm256_loadu_si256((const __m256i *)p);
    __m256i r = _mm256_loadu_si256((const __m256i *)(p + 4));
    __m256i c_rb = _mm256_and_si256(c, m), c_ga = _mm256_srli_epi16(c, 8);
    *rb = _mm256_add_epi16(*rb, _mm256_add_epi16(_mm256_add_epi16(_mm256_and_si256(l, m), _mm256_and_si256(r, m)),
                                                 _mm256_add_epi16(c_rb, c_rb)));
    *ga = _mm256_add_epi16(*ga, _mm256_add_epi16(_mm256_add_epi16(_mm256_srli_epi16(l, 8), _mm256_srli_epi16(r, 8)),
                                                 _mm256_add_epi16(c_ga, c_ga)));
}

/* U and V of 8 columns (every one; the caller keeps the even) in 32-bit lanes */
static inline void chroma8(const uint8_t *r0, const uint8_t *r1, __m256i *u, __m256i *v)
{
    __m256i rb = _mm256_setzero_si256(), ga = _mm256_setzero_si256();
    sums8(r0, &rb, &ga);
    sums8(r1, &rb, &ga);
    const __m256i add = _mm256_set1_epi32(VT_H264_C_ADD);
    const __m256i ku_rb = _mm256_set1_epi32(PAIR(VT_H264_CU_R, VT_H264_CU_B));
    const __m256i kv_rb = _mm256_set1_epi32(PAIR(VT_H264_CV_R, VT_H264_CV_B));
    const __m256i ku_g = _mm256_set1_epi32(PAIR(VT_H264_CU_G, 0)), kv_g = _mm256_set1_epi32(PAIR(VT_H264_CV_G, 0));
    __m256i su = _mm256_add_epi32(_mm256_madd_epi16(rb, ku_rb), _mm256_madd_epi16(ga, ku_g));
    __m256i sv = _mm256_add_epi32(_mm256_madd_epi16(rb, kv_rb), _mm256_madd_epi16(ga, kv_g));
    *u = _mm256_srai_epi32(_mm256_add_epi32(su, add), 19);
    *v = _mm256_srai_epi32(_mm256_add_epi32(sv, add), 19);
}

static void rows(const uint8_t *r0, const uint8_t *r1, uint32_t n, uint8_t *y0, uint8_t *y1, uint8_t *u, uint8_t *v)
{
    /* the even columns of two vectors a (columns 0..7) and b (8..15):
       blend gives a0 b0 a2 b2 | a4 b4 a6 b6, the permutation puts them in order */
    const __m256i order = _mm256_setr_epi32(0, 2, 4, 6, 1, 3, 5, 7);
    for (uint32_t x = 0; x < n; x += 16) {
        const uint8_t *p0 = r0 + 4 * (size_t)x, *p1 = r1 + 4 * (size_t)x;
        _mm_storeu_si128((__m128i *)(y0 + x), bytes16(luma8(_mm256_loadu_si256((const __m256i *)p0)),
                                                      luma8(_mm256_loadu_si256((const __m256i *)(p0 + 32)))));
        _mm_storeu_si128((__m128i *)(y1 + x), bytes16(luma8(_mm256_loadu_si256((const __m256i *)p1)),
                                                      luma8(_mm256_loadu_si256((const __m256i *)(p1 + 32)))));
        __m256i ua, va, ub, vb;
        chroma8(p0, p1, &ua, &va);
        chroma8(p0 + 32, p1 + 32, &ub, &vb);
        __m256i uu = _mm256_permutevar8x32_epi32(_mm256_blend_epi32(ua, _mm256_slli_si256(ub, 4), 0xaa), order);
        __m256i vv = _mm256_permutevar8x32_epi32(_mm256_blend_epi32(va, _mm256_slli_si256(vb, 4), 0xaa), order);
        __m128i uv = bytes16(uu, vv); /* u0..7 v0..7 */
        _mm_storel_epi64((__m128i *)(u + x / 2), uv);
        _mm_storel_epi64((__m128i *)(v + x / 2), _mm_srli_si128(uv, 8));
    }
}

vt_i420_rows_fn vt_i420_rows_avx2(void)
{
    return rows;
}
#else
vt_i420_rows_fn vt_i420_rows_avx2(void)
{
    return NULL;
}
#endif
