/*
 * cull_occ_raster_avx2.c — the occlusion render (cull_occ_raster.inl)
 * compiled with AVX2: the same operations (no contraction under -std=c11),
 * so the same buffers; called by cull_occ_render_isa for the AVX2 kernels,
 * which only run where CPUID says AVX2 and FMA are there.
 */
#if defined(__AVX2__) && defined(__FMA__)
#define CULL_OCC_RASTER_ISA avx2
#include "cull_occ_rows.h"
#include "cull_occ_raster.inl"

int cull_occ_render_avx2(const cull_world *w, const cull_view *v, cull_occ_buffer *b, cull_pool *pool,
                         uint32_t threads, uint32_t isa, const uint64_t *sublevels, cull_occ_stats *st)
{
    return render_impl(w, v, b, pool, threads, isa, sublevels, st);
}
#endif
