/*
 * vt_ssao_base.c — the SSAO kernels one lane at a time (any CPU, the
 * CONFIG=scalar build, the tests' reference), and the choice of instance.
 */
#include "vt_ssao_kern.h"
#include "culling.h"

#define CULL_SIMD_ISA 1
#include "cull_simd.h"
#define VT_SSAO_GTAO_NAME vt_ssao_gtao_scalar
#define VT_SSAO_POS_NAME vt_ssao_pos_scalar
#define VT_SSAO_CREASE_NAME vt_ssao_crease_scalar
#define VT_SSAO_UP_NAME vt_ssao_up_scalar
#include "vt_ssao.inl"

vt_ssao_kern vt_ssao_kern_pick(uint32_t isa)
{
    switch (isa < CULL_ISA_COUNT && cull_isa_supported(isa) ? isa : cull_isa_default()) {
#ifndef CULL_SCALAR_ONLY
    case CULL_ISA_AVX2: {
        const vt_ssao_kern e = vt_ssao_kern_evex(); /* the same kernels' EVEX build, where it runs */
        if (e.gtao && cull_isa_evex()) return e;
        return (vt_ssao_kern){vt_ssao_pos_avx2, vt_ssao_crease_avx2, vt_ssao_gtao_avx2, vt_ssao_up_avx2};
    }
    case CULL_ISA_SSE41: return (vt_ssao_kern){vt_ssao_pos_sse41, vt_ssao_crease_sse41, vt_ssao_gtao_sse41, vt_ssao_up_sse41};
#endif
    default: return (vt_ssao_kern){vt_ssao_pos_scalar, vt_ssao_crease_scalar, vt_ssao_gtao_scalar, vt_ssao_up_scalar};
    }
}
