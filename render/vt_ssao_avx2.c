/*
 * vt_ssao_avx2.c — the SSAO kernels, 8 lanes. Compiled with -mavx2 -mfma; called only after CPUID says both are there (vt_ssao_kern_pick).
 */
#include "vt_ssao_kern.h"

#if defined(__AVX2__) && defined(__FMA__)
#define CULL_SIMD_ISA 3
#include "cull_simd.h"
#define VT_SSAO_GTAO_NAME vt_ssao_gtao_avx2
#define VT_SSAO_POS_NAME vt_ssao_pos_avx2
#define VT_SSAO_CREASE_NAME vt_ssao_crease_avx2
#define VT_SSAO_UP_NAME vt_ssao_up_avx2
#include "vt_ssao.inl"
#endif
