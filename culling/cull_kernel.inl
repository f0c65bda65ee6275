/*
 * cull_kernel.inl — the block kernel, written once. Included by
 * cull_kernels_{scalar,sse41,avx2}.c after cull_simd.h with CULL_KERNEL_NAME
 * set; each instance is compiled with its own ISA flags.
 *
 * Per group of W lanes, for each view that the cell stage kept:
 *   sphere:  s_i = n_i.c + d_i over the view's active planes; culled if
 *            min s < -r; fully inside if min s >= r (then the AABB cannot
 *            cull it and its test is skipped);
 *   AABB:    p-vertex distance over the same planes, only for lanes that
 *            straddle a plane;
 *   area:    the projected AABB's viewport-clipped bounding rectangle, only
 *            for lanes still visible in that view, and only when asked.
 * Cost per lane and view with 6 active planes: ~20 flops for the sphere,
 * +18 for the AABB where it runs, ~70 and one division for the area.
 */

uint32_t CULL_KERNEL_NAME(const cull_block *b, uint32_t n, const cull_kview *kv,
                          uint32_t nv, const cull_kparams *p, cull_result *out,
                          cull_kcount *cnt)
{
    uint32_t written = 0;
    const vf zero = vf_set(0.0f);
    const vf inf = vf_set(INFINITY);
    for (uint32_t g = 0; g < n; g += W) {
        uint32_t left = n - g;
        uint32_t valid = (1u << (left >= W ? W : left)) - 1u;
        vf x = vf_load(b->x + g), y = vf_load(b->y + g), z = vf_load(b->z + g);
        vf r = vf_load(b->r + g);
        vf nr = vf_sub(zero, r);
        vu msph = vu_zero(), mask = vu_zero();
        for (uint32_t v = 0; v < nv; v++) {
            const cull_kview *k = &kv[v];
            vm vis = vm_ones();
            if (k->nplanes) {
                vf smin = inf;
                for (uint32_t i = 0; i < k->nplanes; i++) {
                    vf s = vf_fma(vf_set(k->px[i]), x,
                                  vf_fma(vf_set(k->py[i]), y,
                                         vf_fma(vf_set(k->pz[i]), z, vf_set(k->pd[i]))));
                    smin = vf_min(smin, s);
                }
                vis = vf_ge(smin, nr);
                msph = vu_or_bit(msph, vis, k->bit);
                if (p->aabb) {
                    vm straddle = vm_andnot(vis, vf_ge(smin, r));
                    if (vm_bits(straddle) & valid) {
                        vf bx[2] = {vf_load(b->minx + g), vf_load(b->maxx + g)};
                        vf by[2] = {vf_load(b->miny + g), vf_load(b->maxy + g)};
                        vf bz[2] = {vf_load(b->minz + g), vf_load(b->maxz + g)};
                        vf amin = inf;
                        for (uint32_t i = 0; i < k->nplanes; i++) {
                            vf a = vf_fma(vf_set(k->px[i]), bx[k->px[i] >= 0.0f],
                                          vf_fma(vf_set(k->py[i]), by[k->py[i] >= 0.0f],
                                                 vf_fma(vf_set(k->pz[i]), bz[k->pz[i] >= 0.0f],
                                                        vf_set(k->pd[i]))));
                            amin = vf_min(amin, a);
                        }
                        vis = vm_andnot(vis, vm_and(straddle, vf_lt(amin, zero)));
                    }
                }
            } else {
                msph = vu_or_bit(msph, vis, k->bit);
            }
            mask = vu_or_bit(mask, vis, k->bit);
        }
        uint32_t live = vu_nonzero_bits(mask) & valid;
        cnt->tested += (uint32_t)__builtin_popcount(valid);
        cnt->after_spheres += (uint32_t)__builtin_popcount(vu_nonzero_bits(msph) & valid);
        cnt->after_aabb += (uint32_t)__builtin_popcount(live);
        vf area = vf_set(-1.0f);
        if (p->area && live) {
            vf bx[2] = {vf_load(b->minx + g), vf_load(b->maxx + g)};
            vf by[2] = {vf_load(b->miny + g), vf_load(b->maxy + g)};
            vf bz[2] = {vf_load(b->minz + g), vf_load(b->maxz + g)};
            vf ax = vf_max(vf_abs(bx[0]), vf_abs(bx[1]));
            vf ay = vf_max(vf_abs(by[0]), vf_abs(by[1]));
            vf az = vf_max(vf_abs(bz[0]), vf_abs(bz[1]));
            area = zero;
            for (uint32_t v = 0; v < nv; v++) {
                const cull_kview *k = &kv[v];
                vm in = vu_has_bit(mask, k->bit);
                if (!(vm_bits(in) & valid)) continue;
                /* clip x, y, w of the 8 corners from per-axis products */
                vf px[2][3], py[2][3], pw[2][3];
                for (int s = 0; s < 2; s++) {
                    px[s][0] = vf_mul(vf_set(k->cx[0]), bx[s]);
                    px[s][1] = vf_mul(vf_set(k->cx[1]), by[s]);
                    px[s][2] = vf_mul(vf_set(k->cx[2]), bz[s]);
                    py[s][0] = vf_mul(vf_set(k->cy[0]), bx[s]);
                    py[s][1] = vf_mul(vf_set(k->cy[1]), by[s]);
                    py[s][2] = vf_mul(vf_set(k->cy[2]), bz[s]);
                    pw[s][0] = vf_mul(vf_set(k->cw[0]), bx[s]);
                    pw[s][1] = vf_mul(vf_set(k->cw[1]), by[s]);
                    pw[s][2] = vf_mul(vf_set(k->cw[2]), bz[s]);
                }
                /* w below its rounding error counts as behind the eye */
                vf wtol = vf_mul(vf_set(0x1p-20f),
                                 vf_fma(vf_set(fabsf(k->cw[0])), ax,
                                        vf_fma(vf_set(fabsf(k->cw[1])), ay,
                                               vf_fma(vf_set(fabsf(k->cw[2])), az,
                                                      vf_set(fabsf(k->cw[3]))))));
                vf xmin = inf, ymin = inf, xmax = vf_sub(zero, inf), ymax = xmax;
                vm behind = vf_lt(zero, zero);
                for (int c = 0; c < 8; c++) {
                    int i = c & 1, j = (c >> 1) & 1, l = c >> 2;
                    vf X = vf_add(vf_add(px[i][0], px[j][1]), vf_add(px[l][2], vf_set(k->cx[3])));
                    vf Y = vf_add(vf_add(py[i][0], py[j][1]), vf_add(py[l][2], vf_set(k->cy[3])));
                    vf Wc = vf_add(vf_add(pw[i][0], pw[j][1]), vf_add(pw[l][2], vf_set(k->cw[3])));
                    behind = vm_or(behind, vf_lt(Wc, wtol));
                    vf rw = vf_div(vf_set(1.0f), Wc);
                    vf nx = vf_mul(X, rw), ny = vf_mul(Y, rw);
                    xmin = vf_min(xmin, nx);
                    xmax = vf_max(xmax, nx);
                    ymin = vf_min(ymin, ny);
                    ymax = vf_max(ymax, ny);
                }
                /* NDC -> pixels, grown by 2^-16 of the viewport (above the
                   float error of the projection) and clipped to it */
                vf hw = vf_set(k->half_w), hh = vf_set(k->half_h);
                vf vw = vf_set(k->vp_w), vh = vf_set(k->vp_h), one = vf_set(1.0f);
                vf gx = vf_set(k->half_w * 0x1p-16f), gy = vf_set(k->half_h * 0x1p-16f);
                vf x0 = vf_min(vf_max(vf_sub(vf_mul(vf_add(xmin, one), hw), gx), zero), vw);
                vf x1 = vf_min(vf_max(vf_add(vf_mul(vf_add(xmax, one), hw), gx), zero), vw);
                vf y0 = vf_min(vf_max(vf_sub(vf_mul(vf_add(ymin, one), hh), gy), zero), vh);
                vf y1 = vf_min(vf_max(vf_add(vf_mul(vf_add(ymax, one), hh), gy), zero), vh);
                vf a = vf_mul(vf_sub(x1, x0), vf_sub(y1, y0));
                a = vf_select(behind, vf_mul(vw, vh), a);
                if (p->min_area > 0) {
                    vm small = vm_and(in, vf_lt(a, vf_set(p->min_area)));
                    mask = vu_clear_bit(mask, small, k->bit);
                    in = vm_andnot(in, small);
                }
                area = vf_select(in, vf_max(area, a), area);
            }
            live = vu_nonzero_bits(mask) & valid;
        }
        cnt->after_area += (uint32_t)__builtin_popcount(live);
        if (!live) continue;
        uint32_t mk[W];
        float ar[W];
        vu_store(mk, mask);
        vf_store(ar, area);
        while (live) {
            uint32_t l = (uint32_t)__builtin_ctz(live);
            live &= live - 1;
            uint32_t e = g + l;
            out[written++] = (cull_result){
                .handle = b->handle[e],
                .view_mask = mk[l],
                .class_id = b->class_id[e],
                .sublevel = b->sublevel[e],
                .screen_area = ar[l],
            };
        }
    }
    return written;
}
