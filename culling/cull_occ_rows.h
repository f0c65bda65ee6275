/*
 * cull_occ_rows.h — the occlusion render's rows set-up in AVX2 and the
 * clamped floor / ceil it and the AVX2 rectangles share
 * (cull_occ_fns.rows), inlined by the render's AVX2 build
 * (cull_occ_raster_avx2.c) and exported by the AVX2 kernels
 * (cull_occ_rows_avx2, cull_occ_kern.inl). Include only where __AVX2__.
 */
#ifndef VANTAGE_CULL_OCC_ROWS_H
#define VANTAGE_CULL_OCC_ROWS_H

#include "cull_occ.h"
#include <immintrin.h>

/* The 8 lanes' largest / smallest. */
static inline int occ_hmax_epi32(__m256i v)
{
    __m128i m = _mm_max_epi32(_mm256_castsi256_si128(v), _mm256_extracti128_si256(v, 1));
    m = _mm_max_epi32(m, _mm_shuffle_epi32(m, _MM_SHUFFLE(1, 0, 3, 2)));
    return _mm_cvtsi128_si32(_mm_max_epi32(m, _mm_shuffle_epi32(m, _MM_SHUFFLE(2, 3, 0, 1))));
}

static inline int occ_hmin_epi32(__m256i v)
{
    __m128i m = _mm_min_epi32(_mm256_castsi256_si128(v), _mm256_extracti128_si256(v, 1));
    m = _mm_min_epi32(m, _mm_shuffle_epi32(m, _MM_SHUFFLE(1, 0, 3, 2)));
    return _mm_cvtsi128_si32(_mm_min_epi32(m, _mm_shuffle_epi32(m, _MM_SHUFFLE(2, 3, 0, 1))));
}

/* dfloor / dceil of cull_occ_num.h four a vector: the clamp to +-2^30,
 * then roundpd (the same integers for every value that is not NaN; no
 * caller passes NaN) */
static inline __m256d occ_dfloor4(__m256d v)
{
    v = _mm256_max_pd(_mm256_min_pd(v, _mm256_set1_pd(0x1p30)), _mm256_set1_pd(-0x1p30));
    return _mm256_round_pd(v, _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC);
}

static inline __m256d occ_dceil4(__m256d v)
{
    v = _mm256_max_pd(_mm256_min_pd(v, _mm256_set1_pd(0x1p30)), _mm256_set1_pd(-0x1p30));
    return _mm256_round_pd(v, _MM_FROUND_TO_POS_INF | _MM_FROUND_NO_EXC);
}

/* cull_occ_rows_scalar's rows, four a vector, with the same operations in
 * the same order (so the same bits): maxpd / minpd pick as dmax / dmin do
 * (a > b ? a : b), dfloor / dceil as occ_dfloor4 / occ_dceil4 (the
 * bounds are never NaN) */
static inline __attribute__((always_inline)) cull_occ_rowsum cull_occ_rows8(const cull_occ_rowset *rs, int jb, int a,
                                                                           int b, int *lo, int *hi, float *z0)
{
    const __m256d j[2] = {_mm256_add_pd(_mm256_set1_pd((double)jb), _mm256_set_pd(3, 2, 1, 0)),
                          _mm256_add_pd(_mm256_set1_pd((double)jb), _mm256_set_pd(7, 6, 5, 4))};
    for (int k = 0; k < 3; k++) {
        const __m256d zb = _mm256_set1_pd(rs->zb[k]), zc = _mm256_set1_pd(rs->zc[k]),
                      co = _mm256_set1_pd(rs->corner[k]), m = _mm256_set1_pd(rs->m[k]);
        for (int h = 0; h < 2; h++) {
            __m256d v = _mm256_sub_pd(_mm256_sub_pd(_mm256_add_pd(_mm256_mul_pd(zb, j[h]), zc), co), m);
            _mm_storeu_ps(z0 + 8 * k + 4 * h, _mm256_cvtpd_ps(v));
        }
    }
    const __m256d one = _mm256_set1_pd(1.0);
    __m128i x0[2], x1[2];
    for (int h = 0; h < 2; h++) {
        __m256d l = _mm256_set1_pd(-0x1p40), r = _mm256_set1_pd(0x1p40);
        for (uint32_t k = 0; k < rs->nl; k++)
            l = _mm256_max_pd(l, _mm256_add_pd(_mm256_set1_pd(rs->lal[k]), _mm256_mul_pd(_mm256_set1_pd(rs->lbe[k]), j[h])));
        for (uint32_t k = 0; k < rs->nr; k++)
            r = _mm256_min_pd(r, _mm256_add_pd(_mm256_set1_pd(rs->ral[k]), _mm256_mul_pd(_mm256_set1_pd(rs->rbe[k]), j[h])));
        l = _mm256_add_pd(occ_dfloor4(l), one);
        r = _mm256_sub_pd(occ_dceil4(r), one);
        x0[h] = _mm256_cvttpd_epi32(_mm256_max_pd(_mm256_set1_pd(rs->i0), l));
        x1[h] = _mm256_cvttpd_epi32(_mm256_min_pd(_mm256_set1_pd(rs->i1), r));
    }
    __m256i vlo = _mm256_set_m128i(x0[1], x0[0]), vhi = _mm256_set_m128i(x1[1], x1[0]);
    const __m256i rid = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    const __m256i in = _mm256_and_si256(_mm256_cmpgt_epi32(rid, _mm256_set1_epi32(a - 1)),
                                        _mm256_cmpgt_epi32(_mm256_set1_epi32(b + 1), rid));
    const __m256i ne = _mm256_andnot_si256(_mm256_cmpgt_epi32(vlo, vhi), in);
    const __m256i imin = _mm256_set1_epi32(INT32_MIN), imax = _mm256_set1_epi32(INT32_MAX);
    cull_occ_rowsum o = {.L = occ_hmax_epi32(_mm256_blendv_epi8(imin, vlo, in)),
                         .H = occ_hmin_epi32(_mm256_blendv_epi8(imax, vhi, in)),
                         .U0 = occ_hmin_epi32(_mm256_blendv_epi8(imax, vlo, ne)),
                         .U1 = occ_hmax_epi32(_mm256_blendv_epi8(imin, vhi, ne)),
                         .whole = a == 0 && b == 7 && _mm256_movemask_ps(_mm256_castsi256_ps(ne)) == 0xff};
    _mm256_storeu_si256((__m256i *)lo, _mm256_blendv_epi8(_mm256_set1_epi32(1), vlo, in));
    _mm256_storeu_si256((__m256i *)hi, _mm256_blendv_epi8(_mm256_setzero_si256(), vhi, in));
    return o;
}

#endif
