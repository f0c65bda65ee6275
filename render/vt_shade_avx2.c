/*
 * vt_shade_avx2.c — the shading kernel, 8 lanes. Compiled with -mavx2
 * -mfma; called only after CPUID says both are there (vt_kern_pick).
 */
#include "vt_shade.h"

#if defined(__AVX2__) && defined(__FMA__)
#define CULL_SIMD_ISA 3
#include "cull_simd.h"
#define VT_SHADE_NAME vt_shade_avx2
#define VT_RANGES_NAME vt_ranges_avx2
#include "vt_shade.inl"
#endif
