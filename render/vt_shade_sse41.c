/*
 * vt_shade_sse41.c — the shading kernel, 4 lanes. Compiled with -msse4.1;
 * called only after CPUID says it is there (vt_kern_pick).
 */
#include "vt_shade.h"

#if defined(__SSE4_1__)
#define CULL_SIMD_ISA 2
#include "cull_simd.h"
#define VT_SHADE_NAME vt_shade_sse41
#define VT_RANGES_NAME vt_ranges_sse41
#include "vt_shade.inl"
#endif
