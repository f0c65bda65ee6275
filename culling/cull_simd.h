/*
 * cull_simd.h — the few vector operations the culling kernels use, for one
 * ISA chosen by CULL_SIMD_ISA before inclusion (1 scalar, 2 SSE4.1, 3 AVX2).
 * Included only by cull_kernels_<isa>.c, each compiled with its own flags,
 * so no AVX2 instruction can leak into code that runs before the CPUID check.
 *
 * Types: vf = W floats, vm = W lane masks (all-ones / zero), vu = W uint32
 * view masks.
 */
#ifndef VANTAGE_CULL_SIMD_H
#define VANTAGE_CULL_SIMD_H

#include <stdint.h>

#if CULL_SIMD_ISA == 3
#include <immintrin.h>
#define W 8
typedef __m256 vf;
typedef __m256 vm;
typedef __m256i vu;
static inline vf vf_load(const float *p) { return _mm256_load_ps(p); }
static inline vf vf_loadu(const float *p) { return _mm256_loadu_ps(p); }
static inline float vf_hmin(__m256 a)
{
    __m128 m = _mm_min_ps(_mm256_castps256_ps128(a), _mm256_extractf128_ps(a, 1));
    m = _mm_min_ps(m, _mm_movehl_ps(m, m));
    m = _mm_min_ss(m, _mm_shuffle_ps(m, m, 1));
    return _mm_cvtss_f32(m);
}
static inline float vf_hmax(__m256 a)
{
    __m128 m = _mm_max_ps(_mm256_castps256_ps128(a), _mm256_extractf128_ps(a, 1));
    m = _mm_max_ps(m, _mm_movehl_ps(m, m));
    m = _mm_max_ss(m, _mm_shuffle_ps(m, m, 1));
    return _mm_cvtss_f32(m);
}
static inline void vf_store(float *p, vf a) { _mm256_storeu_ps(p, a); }
static inline vf vf_set(float a) { return _mm256_set1_ps(a); }
static inline vf vf_add(vf a, vf b) { return _mm256_add_ps(a, b); }
static inline vf vf_sub(vf a, vf b) { return _mm256_sub_ps(a, b); }
static inline vf vf_mul(vf a, vf b) { return _mm256_mul_ps(a, b); }
static inline vf vf_div(vf a, vf b) { return _mm256_div_ps(a, b); }
static inline vf vf_sqrt(vf a) { return _mm256_sqrt_ps(a); }
/* 1/a to ~2^-22 relative: rcp (12 bits) and one Newton step */
static inline vf vf_rcp(vf a)
{
    __m256 r = _mm256_rcp_ps(a);
    return _mm256_mul_ps(r, _mm256_fnmadd_ps(a, r, _mm256_set1_ps(2.0f)));
}
static inline vf vf_fma(vf a, vf b, vf c) { return _mm256_fmadd_ps(a, b, c); }
static inline vf vf_trunc(vf a) { return _mm256_round_ps(a, _MM_FROUND_TO_ZERO | _MM_FROUND_NO_EXC); }
/* lanes whose bits are equal */
static inline vm vf_same(vf a, vf b)
{
    return _mm256_castsi256_ps(_mm256_cmpeq_epi32(_mm256_castps_si256(a), _mm256_castps_si256(b)));
}
/* (int)a per lane, a in int range */
static inline void vf_store_i32(int32_t *p, vf a) { _mm256_storeu_si256((__m256i *)p, _mm256_cvttps_epi32(a)); }
/* base[(int)i] per lane, i holding non-negative integers below 2^24 */
static inline vf vf_lookup(const float *base, vf i) { return _mm256_i32gather_ps(base, _mm256_cvttps_epi32(i), 4); }
static inline vf vf_min(vf a, vf b) { return _mm256_min_ps(a, b); }
static inline vf vf_max(vf a, vf b) { return _mm256_max_ps(a, b); }
static inline vf vf_abs(vf a) { return _mm256_andnot_ps(_mm256_set1_ps(-0.0f), a); }
static inline vm vf_ge(vf a, vf b) { return _mm256_cmp_ps(a, b, _CMP_GE_OQ); }
static inline vm vf_lt(vf a, vf b) { return _mm256_cmp_ps(a, b, _CMP_LT_OQ); }
static inline vm vf_le(vf a, vf b) { return _mm256_cmp_ps(a, b, _CMP_LE_OQ); }
static inline vf vf_select(vm m, vf a, vf b) { return _mm256_blendv_ps(b, a, m); }
static inline vm vm_and(vm a, vm b) { return _mm256_and_ps(a, b); }
static inline vm vm_or(vm a, vm b) { return _mm256_or_ps(a, b); }
static inline vm vm_andnot(vm a, vm b) { return _mm256_andnot_ps(b, a); } /* a & ~b */
static inline vm vm_ones(void) { return _mm256_castsi256_ps(_mm256_set1_epi32(-1)); }
static inline uint32_t vm_bits(vm m) { return (uint32_t)_mm256_movemask_ps(m); }
static inline vm vm_from_bits(uint32_t bits)
{
    const __m256i sel = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
    return _mm256_castsi256_ps(_mm256_cmpeq_epi32(_mm256_and_si256(_mm256_set1_epi32((int)bits), sel), sel));
}
static inline vu vu_zero(void) { return _mm256_setzero_si256(); }
static inline vu vu_or_bit(vu acc, vm m, uint32_t bit)
{
    return _mm256_or_si256(acc, _mm256_and_si256(_mm256_castps_si256(m),
                                                 _mm256_set1_epi32((int)bit)));
}
static inline vu vu_clear_bit(vu acc, vm m, uint32_t bit)
{
    return _mm256_andnot_si256(_mm256_and_si256(_mm256_castps_si256(m),
                                                _mm256_set1_epi32((int)bit)), acc);
}
static inline vm vu_has_bit(vu acc, uint32_t bit)
{
    __m256i z = _mm256_cmpeq_epi32(_mm256_and_si256(acc, _mm256_set1_epi32((int)bit)),
                                   _mm256_setzero_si256());
    return _mm256_castsi256_ps(_mm256_xor_si256(z, _mm256_set1_epi32(-1)));
}
static inline uint32_t vu_nonzero_bits(vu a)
{
    __m256i z = _mm256_cmpeq_epi32(a, _mm256_setzero_si256());
    return ~(uint32_t)_mm256_movemask_ps(_mm256_castsi256_ps(z)) & 0xFFu;
}
static inline void vu_store(uint32_t *p, vu a) { _mm256_storeu_si256((__m256i *)p, a); }


/* doubles, for the cell stage */
#define WD 4
typedef __m256d vd;
static inline vd vd_load(const double *p) { return _mm256_loadu_pd(p); }
static inline vd vd_set(double a) { return _mm256_set1_pd(a); }
static inline vd vd_add(vd a, vd b) { return _mm256_add_pd(a, b); }
static inline vd vd_sub(vd a, vd b) { return _mm256_sub_pd(a, b); }
static inline vd vd_fma(vd a, vd b, vd c) { return _mm256_fmadd_pd(a, b, c); }
static inline vd vd_lt(vd a, vd b) { return _mm256_cmp_pd(a, b, _CMP_LT_OQ); }
static inline vd vd_zero(void) { return _mm256_setzero_pd(); }
/* acc |= (m ? bit : 0), per 64-bit lane */
static inline vd vd_or_bit(vd acc, vd m, uint64_t bit)
{
    return _mm256_or_pd(acc, _mm256_and_pd(m, _mm256_castsi256_pd(_mm256_set1_epi64x((long long)bit))));
}
static inline void vd_store_bits(uint64_t *p, vd a) { _mm256_storeu_pd((double *)p, a); }
#elif CULL_SIMD_ISA == 2
#include <smmintrin.h>
#define W 4
typedef __m128 vf;
typedef __m128 vm;
typedef __m128i vu;
static inline vf vf_load(const float *p) { return _mm_load_ps(p); }
static inline vf vf_loadu(const float *p) { return _mm_loadu_ps(p); }
static inline float vf_hmin(__m128 m)
{
    m = _mm_min_ps(m, _mm_movehl_ps(m, m));
    m = _mm_min_ss(m, _mm_shuffle_ps(m, m, 1));
    return _mm_cvtss_f32(m);
}
static inline float vf_hmax(__m128 m)
{
    m = _mm_max_ps(m, _mm_movehl_ps(m, m));
    m = _mm_max_ss(m, _mm_shuffle_ps(m, m, 1));
    return _mm_cvtss_f32(m);
}
static inline void vf_store(float *p, vf a) { _mm_storeu_ps(p, a); }
static inline vf vf_set(float a) { return _mm_set1_ps(a); }
static inline vf vf_add(vf a, vf b) { return _mm_add_ps(a, b); }
static inline vf vf_sub(vf a, vf b) { return _mm_sub_ps(a, b); }
static inline vf vf_mul(vf a, vf b) { return _mm_mul_ps(a, b); }
static inline vf vf_div(vf a, vf b) { return _mm_div_ps(a, b); }
static inline vf vf_sqrt(vf a) { return _mm_sqrt_ps(a); }
static inline vf vf_rcp(vf a)
{
    __m128 r = _mm_rcp_ps(a);
    return _mm_mul_ps(r, _mm_sub_ps(_mm_set1_ps(2.0f), _mm_mul_ps(a, r)));
}
static inline vf vf_fma(vf a, vf b, vf c) { return _mm_add_ps(_mm_mul_ps(a, b), c); }
static inline vf vf_trunc(vf a) { return _mm_round_ps(a, _MM_FROUND_TO_ZERO | _MM_FROUND_NO_EXC); }
static inline vm vf_same(vf a, vf b) { return _mm_castsi128_ps(_mm_cmpeq_epi32(_mm_castps_si128(a), _mm_castps_si128(b))); }
static inline void vf_store_i32(int32_t *p, vf a) { _mm_storeu_si128((__m128i *)p, _mm_cvttps_epi32(a)); }
static inline vf vf_lookup(const float *base, vf i)
{
    int32_t k[4];
    vf_store_i32(k, i);
    return _mm_setr_ps(base[k[0]], base[k[1]], base[k[2]], base[k[3]]);
}
static inline vf vf_min(vf a, vf b) { return _mm_min_ps(a, b); }
static inline vf vf_max(vf a, vf b) { return _mm_max_ps(a, b); }
static inline vf vf_abs(vf a) { return _mm_andnot_ps(_mm_set1_ps(-0.0f), a); }
static inline vm vf_ge(vf a, vf b) { return _mm_cmpge_ps(a, b); }
static inline vm vf_lt(vf a, vf b) { return _mm_cmplt_ps(a, b); }
static inline vm vf_le(vf a, vf b) { return _mm_cmple_ps(a, b); }
static inline vf vf_select(vm m, vf a, vf b) { return _mm_blendv_ps(b, a, m); }
static inline vm vm_and(vm a, vm b) { return _mm_and_ps(a, b); }
static inline vm vm_or(vm a, vm b) { return _mm_or_ps(a, b); }
static inline vm vm_andnot(vm a, vm b) { return _mm_andnot_ps(b, a); }
static inline vm vm_ones(void) { return _mm_castsi128_ps(_mm_set1_epi32(-1)); }
static inline uint32_t vm_bits(vm m) { return (uint32_t)_mm_movemask_ps(m); }
static inline vm vm_from_bits(uint32_t bits)
{
    const __m128i sel = _mm_setr_epi32(1, 2, 4, 8);
    return _mm_castsi128_ps(_mm_cmpeq_epi32(_mm_and_si128(_mm_set1_epi32((int)bits), sel), sel));
}
static inline vu vu_zero(void) { return _mm_setzero_si128(); }
static inline vu vu_or_bit(vu acc, vm m, uint32_t bit)
{
    return _mm_or_si128(acc, _mm_and_si128(_mm_castps_si128(m), _mm_set1_epi32((int)bit)));
}
static inline vu vu_clear_bit(vu acc, vm m, uint32_t bit)
{
    return _mm_andnot_si128(_mm_and_si128(_mm_castps_si128(m), _mm_set1_epi32((int)bit)), acc);
}
static inline vm vu_has_bit(vu acc, uint32_t bit)
{
    __m128i z = _mm_cmpeq_epi32(_mm_and_si128(acc, _mm_set1_epi32((int)bit)), _mm_setzero_si128());
    return _mm_castsi128_ps(_mm_xor_si128(z, _mm_set1_epi32(-1)));
}
static inline uint32_t vu_nonzero_bits(vu a)
{
    __m128i z = _mm_cmpeq_epi32(a, _mm_setzero_si128());
    return ~(uint32_t)_mm_movemask_ps(_mm_castsi128_ps(z)) & 0xFu;
}
static inline void vu_store(uint32_t *p, vu a) { _mm_storeu_si128((__m128i *)p, a); }


/* doubles, for the cell stage */
#define WD 2
typedef __m128d vd;
static inline vd vd_load(const double *p) { return _mm_loadu_pd(p); }
static inline vd vd_set(double a) { return _mm_set1_pd(a); }
static inline vd vd_add(vd a, vd b) { return _mm_add_pd(a, b); }
static inline vd vd_sub(vd a, vd b) { return _mm_sub_pd(a, b); }
static inline vd vd_fma(vd a, vd b, vd c) { return _mm_add_pd(_mm_mul_pd(a, b), c); }
static inline vd vd_lt(vd a, vd b) { return _mm_cmplt_pd(a, b); }
static inline vd vd_zero(void) { return _mm_setzero_pd(); }
static inline vd vd_or_bit(vd acc, vd m, uint64_t bit)
{
    return _mm_or_pd(acc, _mm_and_pd(m, _mm_castsi128_pd(_mm_set1_epi64x((long long)bit))));
}
static inline void vd_store_bits(uint64_t *p, vd a) { _mm_storeu_pd((double *)p, a); }
#else /* scalar: one lane; the compiler is kept from vectorising it */
#define W 1
typedef float vf;
typedef uint32_t vm;
typedef uint32_t vu;
static inline vf vf_load(const float *p) { return *p; }
static inline vf vf_loadu(const float *p) { return *p; }
static inline float vf_hmin(vf a) { return a; }
static inline float vf_hmax(vf a) { return a; }
static inline void vf_store(float *p, vf a) { *p = a; }
static inline vf vf_set(float a) { return a; }
static inline vf vf_add(vf a, vf b) { return a + b; }
static inline vf vf_sub(vf a, vf b) { return a - b; }
static inline vf vf_mul(vf a, vf b) { return a * b; }
static inline vf vf_div(vf a, vf b) { return a / b; }
static inline vf vf_sqrt(vf a) { return __builtin_sqrtf(a); }
static inline vf vf_rcp(vf a) { return 1.0f / a; }
static inline vf vf_fma(vf a, vf b, vf c) { return a * b + c; }
static inline vf vf_trunc(vf a) { return (float)(int32_t)a; } /* a in int range */
static inline vm vf_same(vf a, vf b)
{
    uint32_t x, y;
    __builtin_memcpy(&x, &a, 4);
    __builtin_memcpy(&y, &b, 4);
    return x == y ? ~0u : 0u;
}
static inline void vf_store_i32(int32_t *p, vf a) { *p = (int32_t)a; }
static inline vf vf_lookup(const float *base, vf i) { return base[(int32_t)i]; }
static inline vf vf_min(vf a, vf b) { return a < b ? a : b; }
static inline vf vf_max(vf a, vf b) { return a > b ? a : b; }
static inline vf vf_abs(vf a) { return a < 0 ? -a : a; }
static inline vm vf_ge(vf a, vf b) { return a >= b ? ~0u : 0u; }
static inline vm vf_lt(vf a, vf b) { return a < b ? ~0u : 0u; }
static inline vm vf_le(vf a, vf b) { return a <= b ? ~0u : 0u; }
static inline vf vf_select(vm m, vf a, vf b) { return m ? a : b; }
static inline vm vm_and(vm a, vm b) { return a & b; }
static inline vm vm_or(vm a, vm b) { return a | b; }
static inline vm vm_andnot(vm a, vm b) { return a & ~b; }
static inline vm vm_ones(void) { return ~0u; }
static inline uint32_t vm_bits(vm m) { return m & 1u; }
static inline vm vm_from_bits(uint32_t bits) { return (bits & 1u) ? ~0u : 0u; }
static inline vu vu_zero(void) { return 0; }
static inline vu vu_or_bit(vu acc, vm m, uint32_t bit) { return acc | (m & bit); }
static inline vu vu_clear_bit(vu acc, vm m, uint32_t bit) { return acc & ~(m & bit); }
static inline vm vu_has_bit(vu acc, uint32_t bit) { return (acc & bit) ? ~0u : 0u; }
static inline uint32_t vu_nonzero_bits(vu a) { return a != 0; }
static inline void vu_store(uint32_t *p, vu a) { *p = a; }

/* doubles, for the cell stage; masks are all-ones / zero bit patterns */
#define WD 1
typedef uint64_t vd_mask;
typedef double vd;
static inline vd vd_load(const double *p) { return *p; }
static inline vd vd_set(double a) { return a; }
static inline vd vd_add(vd a, vd b) { return a + b; }
static inline vd vd_sub(vd a, vd b) { return a - b; }
static inline vd vd_fma(vd a, vd b, vd c) { return a * b + c; }
static inline uint64_t vd_lt(vd a, vd b) { return a < b ? ~0ull : 0ull; }
static inline uint64_t vd_zero(void) { return 0; }
static inline uint64_t vd_or_bit(uint64_t acc, uint64_t m, uint64_t bit) { return acc | (m & bit); }
static inline void vd_store_bits(uint64_t *p, uint64_t a) { *p = a; }
#define VD_BITS uint64_t
#endif

#ifndef VD_BITS
#define VD_BITS vd /* a vd holding per-lane bit masks */
#endif

#endif
