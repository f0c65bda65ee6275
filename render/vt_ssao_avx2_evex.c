/*
 * vt_ssao_avx2_evex.c — the 8-lane SSAO kernels (vt_ssao.inl) built again
 * with AVX-512 VL/DQ/BW allowed at 256 bits: the same intrinsics, the same
 * bits as vt_ssao_avx2.c, with 32 vector registers (GTAO's working set
 * spilled to the stack with 16) and mask registers. Taken only where
 * cull_isa_evex() says the CPU and OS have it (vt_ssao_kern_pick); a build
 * without the flags leaves it out.
 */
#include "vt_ssao_kern.h"

#if defined(__AVX2__) && defined(__FMA__) && defined(__AVX512VL__) && defined(__AVX512BW__) && defined(__AVX512DQ__)
#define CULL_SIMD_ISA 3
#include "cull_simd.h"
#define VT_SSAO_GTAO_NAME vt_ssao_gtao_avx2_evex
#define VT_SSAO_POS_NAME vt_ssao_pos_avx2_evex
#define VT_SSAO_CREASE_NAME vt_ssao_crease_avx2_evex
#define VT_SSAO_UP_NAME vt_ssao_up_avx2_evex
#include "vt_ssao.inl"

vt_ssao_kern vt_ssao_kern_evex(void)
{
    return (vt_ssao_kern){vt_ssao_pos_avx2_evex, vt_ssao_crease_avx2_evex, vt_ssao_gtao_avx2_evex, vt_ssao_up_avx2_evex};
}
#else
vt_ssao_kern vt_ssao_kern_evex(void)
{
    return (vt_ssao_kern){NULL, NULL, NULL, NULL};
}
#endif
