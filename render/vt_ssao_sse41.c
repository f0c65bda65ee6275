/*
 * vt_ssao_sse41.c — the SSAO kernels, 4 lanes. Compiled with -msse4.1; called only after CPUID says it is there (vt_ssao_kern_pick).
 */
#include "vt_ssao_kern.h"

#if defined(__SSE4_1__)
#define CULL_SIMD_ISA 2
#include "cull_simd.h"
#define VT_SSAO_GTAO_NAME vt_ssao_gtao_sse41
#define VT_SSAO_POS_NAME vt_ssao_pos_sse41
#define VT_SSAO_CREASE_NAME vt_ssao_crease_sse41
#define VT_SSAO_UP_NAME vt_ssao_up_sse41
#include "vt_ssao.inl"
#endif
