/*
 * cull_occ_raster.c — the occlusion render's baseline build
 * (cull_occ_raster.inl) and its entry points: cull_occ_render_isa runs the
 * AVX2 build (cull_occ_raster_avx2.c: the same source, VEX-encoded, the
 * same buffers bit for bit) for the AVX2 kernels.
 */
#include "cull_occ_raster.inl"

int cull_occ_render_isa(const cull_world *w, const cull_view *v, cull_occ_buffer *b, cull_pool *pool,
                        uint32_t threads, uint32_t isa, const uint64_t *sublevels, cull_occ_stats *st)
{
#ifndef CULL_SCALAR_ONLY
    if (isa == CULL_ISA_AVX2) return cull_occ_render_avx2(w, v, b, pool, threads, isa, sublevels, st);
#endif
    return render_impl(w, v, b, pool, threads, isa, sublevels, st);
}

int cull_occ_render_generic(const cull_world *w, const cull_view *v, cull_occ_buffer *b, cull_pool *pool,
                            uint32_t threads, uint32_t isa, const uint64_t *sublevels, cull_occ_stats *st)
{
    return render_impl(w, v, b, pool, threads, isa, sublevels, st);
}
