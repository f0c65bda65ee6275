/*
 * vt_shade_avx2_evex.c — the 8-lane shading kernel (vt_shade.inl) built
 * again with AVX-512 VL/DQ/BW allowed at 256 bits: the same intrinsics,
 * so the same operations and the same bits as vt_shade_avx2.c, but the
 * compiler has 32 vector registers (the kernel's working set spilled to
 * the stack with 16) and mask registers for its selects. Used by
 * vt_kern_pick only where cull_isa_evex() says the CPU and OS have it;
 * a build without the flags (the fuzzers') leaves it out.
 */
#include "vt_shade.h"

#if defined(__AVX2__) && defined(__FMA__) && defined(__AVX512VL__) && defined(__AVX512BW__) && defined(__AVX512DQ__)
#define CULL_SIMD_ISA 3
#include "cull_simd.h"
#define VT_SHADE_NAME vt_shade_avx2_evex
#define VT_RANGES_NAME vt_ranges_avx2_evex
#include "vt_shade.inl"

vt_kern vt_kern_evex(void)
{
    return (vt_kern){vt_shade_avx2_evex, vt_ranges_avx2_evex};
}
#else
vt_kern vt_kern_evex(void)
{
    return (vt_kern){NULL, NULL};
}
#endif
