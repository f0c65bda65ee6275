/*
 * vt_shadow_avx2.c — the shadow lookup over a span, 8 lanes (vt_shadow.inl).
 * Compiled with -mavx2 -mfma; called only after CPUID says so (vt_shadow_create).
 */
#include "vt_shadow.h"

#if defined(__AVX2__) && defined(__FMA__)
#define CULL_SIMD_ISA 3
#include "cull_simd.h"
#define VT_SHADOW_N_NAME vt_shadow_lookup_n_avx2
#include "vt_shadow.inl"
#endif
