/*
 * cull_cells.inl — the box stage kernel (regions, then cells), written once
 * (see cull_kernel.inl for how it is instantiated). For one view: n boxes
 * (world centre in double, half extent) against np planes, WD boxes per
 * step in double precision; code[i] gets bit 7 if box i is outside some
 * plane, else bit p for each plane p it straddles (0 = fully inside).
 * ~10 flops per cell and plane; world-space doubles keep 1e6 m exact to
 * ~1e-9 m, far below the storage slack.
 */
void CULL_CELLS_NAME(const cull_bounds_soa *restrict s, uint32_t n, const cull_cplane *restrict pl, uint32_t np,
                     uint8_t *restrict code)
{
    const double *cx = CULL_SOA(s, 0), *cy = CULL_SOA(s, 1), *cz = CULL_SOA(s, 2);
    const double *ex = CULL_SOA(s, 3), *ey = CULL_SOA(s, 4), *ez = CULL_SOA(s, 5);
    const vd zero = vd_set(0.0);
    for (uint32_t c = 0; c < n; c += WD) {
        vd x = vd_load(cx + c), y = vd_load(cy + c), z = vd_load(cz + c);
        vd hx = vd_load(ex + c), hy = vd_load(ey + c), hz = vd_load(ez + c);
        VD_BITS acc = vd_zero();
        for (uint32_t i = 0; i < np; i++) {
            const cull_cplane *p = &pl[i];
            vd mid = vd_fma(vd_set(p->n[0]), x, vd_fma(vd_set(p->n[1]), y, vd_fma(vd_set(p->n[2]), z, vd_set(p->d))));
            vd rad = vd_fma(vd_set(p->an[0]), hx, vd_fma(vd_set(p->an[1]), hy, vd_fma(vd_set(p->an[2]), hz, zero)));
            acc = vd_or_bit(acc, vd_lt(vd_add(mid, rad), zero), 0x80u);
            acc = vd_or_bit(acc, vd_lt(vd_sub(mid, rad), zero), 1u << i);
        }
        uint64_t bits[WD];
        vd_store_bits(bits, acc);
        for (uint32_t l = 0; l < WD; l++) code[c + l] = (uint8_t)bits[l];
    }
}
