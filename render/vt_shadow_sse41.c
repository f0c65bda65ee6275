/*
 * vt_shadow_sse41.c — the shadow lookup over a span, 4 lanes (vt_shadow.inl).
 * Compiled with -msse4.1; called only after CPUID says so (vt_shadow_create).
 */
#include "vt_shadow.h"

#if defined(__SSE4_1__)
#define CULL_SIMD_ISA 2
#include "cull_simd.h"
#define VT_SHADOW_N_NAME vt_shadow_lookup_n_sse41
#include "vt_shadow.inl"
#endif
