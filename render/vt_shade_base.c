/*
 * vt_shade_base.c — the shading kernel one lane at a time (any CPU, and
 * the CONFIG=scalar build), and the choice of instance.
 */
#include "vt_shade.h"
#include "culling.h"

#define CULL_SIMD_ISA 1
#include "cull_simd.h"
#define VT_SHADE_NAME vt_shade_scalar
#define VT_RANGES_NAME vt_ranges_scalar
#include "vt_shade.inl"

vt_kern vt_kern_pick(void)
{
    switch (cull_isa_default()) {
#ifndef CULL_SCALAR_ONLY
    case CULL_ISA_AVX2: {
        const vt_kern e = vt_kern_evex(); /* the same kernel's EVEX build, where it runs */
        if (e.shade && cull_isa_evex()) return e;
        return (vt_kern){vt_shade_avx2, vt_ranges_avx2};
    }
    case CULL_ISA_SSE41: return (vt_kern){vt_shade_sse41, vt_ranges_sse41};
#endif
    default: return (vt_kern){vt_shade_scalar, vt_ranges_scalar};
    }
}
