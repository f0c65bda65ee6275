/*
 * cull_kernel.inl — the block kernel, written once. Included by
 * cull_kernels_{scalar,sse41,avx2}.c after cull_simd.h with CULL_KERNEL_NAME
 * set; each instance is compiled with its own ISA flags.
 *
 * Pass 1, per view the cell stage kept (view outer, W-lane groups inner):
 *   sphere: s_i = n_i.c + d_i over the view's active planes (0..6, the
 *           loop fully unrolled per count); culled if min s < -r; fully
 *           inside if min s >= r, and then the AABB cannot cull it;
 *   AABB:   p-vertex distance over the same planes, only for groups with
 *           a lane that straddles a plane.
 * Pass 2, per group: the screen-area stage for lanes still visible (only
 *   when asked: the exact rectangle with CULL_Q_WANT_AREA, else a cheap
 *   upper bound), then one result per lane with a non-zero view mask.
 * Cost per 8 lanes and view with 6 active planes: 18 FMA + 6 min for the
 * sphere, the same again for the AABB where it runs; ~70 flops and 8
 * divisions per view for the area.
 */

#define CULL_KV_MAX_GROUPS (CULL_BLOCK_CAP / W)

static const float cull_lane_index[8] __attribute__((aligned(32))) = {0, 1, 2, 3, 4, 5, 6, 7};

#include "cull_occ_test.inl"

/* One view's sphere (and AABB) pass over the block, NP planes. Inlined
 * with a constant NP so the plane loops unroll. */
static inline __attribute__((always_inline)) void
sphere_pass(const cull_block *restrict b, uint32_t ng, const cull_kview *restrict k, const uint32_t NP,
            bool aabb, vu *restrict mask, vu *restrict msph)
{
    vf px[6], py[6], pz[6], pd[6];
    const float *bxp[6], *byp[6], *bzp[6];
#pragma GCC unroll 6
    for (uint32_t i = 0; i < NP; i++) {
        px[i] = vf_set(k->px[i]);
        py[i] = vf_set(k->py[i]);
        pz[i] = vf_set(k->pz[i]);
        pd[i] = vf_set(k->pd[i]);
        /* p-vertex: the box corner furthest along the normal */
        bxp[i] = k->px[i] >= 0.0f ? b->maxx : b->minx;
        byp[i] = k->py[i] >= 0.0f ? b->maxy : b->miny;
        bzp[i] = k->pz[i] >= 0.0f ? b->maxz : b->minz;
    }
    const uint32_t bit = k->bit;
    const vf zero = vf_set(0.0f);
    for (uint32_t g = 0; g < ng; g++) {
        const uint32_t o = g * W;
        vf x = vf_load(b->x + o), y = vf_load(b->y + o), z = vf_load(b->z + o), r = vf_load(b->r + o);
        vf smin = vf_fma(px[0], x, vf_fma(py[0], y, vf_fma(pz[0], z, pd[0])));
#pragma GCC unroll 6
        for (uint32_t i = 1; i < NP; i++)
            smin = vf_min(smin, vf_fma(px[i], x, vf_fma(py[i], y, vf_fma(pz[i], z, pd[i]))));
        vm vis = vf_ge(vf_add(smin, r), zero);
        msph[g] = vu_or_bit(msph[g], vis, bit);
        if (aabb) {
            vm straddle = vm_andnot(vis, vf_ge(smin, r));
            if (vm_bits(straddle)) {
                vf amin = vf_fma(px[0], vf_load(bxp[0] + o),
                                 vf_fma(py[0], vf_load(byp[0] + o), vf_fma(pz[0], vf_load(bzp[0] + o), pd[0])));
#pragma GCC unroll 6
                for (uint32_t i = 1; i < NP; i++)
                    amin = vf_min(amin, vf_fma(px[i], vf_load(bxp[i] + o),
                                               vf_fma(py[i], vf_load(byp[i] + o),
                                                      vf_fma(pz[i], vf_load(bzp[i] + o), pd[i]))));
                vis = vm_andnot(vis, vm_and(straddle, vf_lt(amin, zero)));
            }
        }
        mask[g] = vu_or_bit(mask[g], vis, bit);
    }
}

/* Area of the viewport-clipped bounding rectangle of the projected box, for
 * view k; behind is set for lanes with a corner at or behind the eye. */
static inline vf box_area(const cull_kview *restrict k, const vf bx[2], const vf by[2], const vf bz[2])
{
    vf ax = vf_max(vf_abs(bx[0]), vf_abs(bx[1]));
    vf ay = vf_max(vf_abs(by[0]), vf_abs(by[1]));
    vf az = vf_max(vf_abs(bz[0]), vf_abs(bz[1]));
    const vf zero = vf_set(0.0f), inf = vf_set(INFINITY);
    /* clip x, y, w of the 8 corners from per-axis products */
    vf px[2][3], py[2][3], pw[2][3];
#pragma GCC unroll 2
    for (int s = 0; s < 2; s++) {
        px[s][0] = vf_mul(vf_set(k->cx[0]), bx[s]);
        px[s][1] = vf_mul(vf_set(k->cx[1]), by[s]);
        px[s][2] = vf_fma(vf_set(k->cx[2]), bz[s], vf_set(k->cx[3]));
        py[s][0] = vf_mul(vf_set(k->cy[0]), bx[s]);
        py[s][1] = vf_mul(vf_set(k->cy[1]), by[s]);
        py[s][2] = vf_fma(vf_set(k->cy[2]), bz[s], vf_set(k->cy[3]));
        pw[s][0] = vf_mul(vf_set(k->cw[0]), bx[s]);
        pw[s][1] = vf_mul(vf_set(k->cw[1]), by[s]);
        pw[s][2] = vf_fma(vf_set(k->cw[2]), bz[s], vf_set(k->cw[3]));
    }
    /* w below its rounding error counts as behind the eye */
    vf wtol = vf_max(vf_set(1e-30f),
                     vf_mul(vf_set(0x1p-20f),
                            vf_fma(vf_set(fabsf(k->cw[0])), ax,
                                   vf_fma(vf_set(fabsf(k->cw[1])), ay,
                                          vf_fma(vf_set(fabsf(k->cw[2])), az, vf_set(fabsf(k->cw[3])))))));
    vf xmin = inf, ymin = inf, xmax = vf_sub(zero, inf), ymax = xmax;
    /* the nearest corner's w, from the per-axis minima */
    vf wmin = vf_add(vf_add(vf_min(pw[0][0], pw[1][0]), vf_min(pw[0][1], pw[1][1])),
                     vf_min(pw[0][2], pw[1][2]));
    vm behind = vf_lt(wmin, wtol);
#pragma GCC unroll 8
    for (int c = 0; c < 8; c++) {
        int i = c & 1, j = (c >> 1) & 1, l = c >> 2;
        vf X = vf_add(vf_add(px[i][0], px[j][1]), px[l][2]);
        vf Y = vf_add(vf_add(py[i][0], py[j][1]), py[l][2]);
        vf Wc = vf_add(vf_add(pw[i][0], pw[j][1]), pw[l][2]);
        vf rw = vf_rcp(Wc);
        vf nx = vf_mul(X, rw), ny = vf_mul(Y, rw);
        xmin = vf_min(xmin, nx);
        xmax = vf_max(xmax, nx);
        ymin = vf_min(ymin, ny);
        ymax = vf_max(ymax, ny);
    }
    /* NDC -> pixels, grown by 2^-16 of the viewport (above the float error
       of the projection) and clipped to it */
    vf hw = vf_set(k->half_w), hh = vf_set(k->half_h);
    vf vw = vf_set(k->vp_w), vh = vf_set(k->vp_h), one = vf_set(1.0f);
    vf gx = vf_set(k->half_w * 0x1p-16f), gy = vf_set(k->half_h * 0x1p-16f);
    vf x0 = vf_min(vf_max(vf_sub(vf_mul(vf_add(xmin, one), hw), gx), zero), vw);
    vf x1 = vf_min(vf_max(vf_add(vf_mul(vf_add(xmax, one), hw), gx), zero), vw);
    vf y0 = vf_min(vf_max(vf_sub(vf_mul(vf_add(ymin, one), hh), gy), zero), vh);
    vf y1 = vf_min(vf_max(vf_add(vf_mul(vf_add(ymax, one), hh), gy), zero), vh);
    vf a = vf_mul(vf_sub(x1, x0), vf_sub(y1, y0));
    return vf_select(behind, vf_mul(vw, vh), a);
}


/* A cheap upper bound on box_area, for a threshold without exact areas:
 * over the box, clip x and w lie in the centre/extent intervals Xc +- Ex and
 * Wc +- Ew, so x = X/w lies between the four quotients of their ends (two
 * reciprocals instead of eight). Never below the exact rectangle, so a
 * threshold on it never culls what the exact test keeps; it keeps a few
 * more (BENCHMARKS.md gives how many). Padded as the exact path. */
static inline vf area_upper(const cull_kview *restrict k, const vf bx[2], const vf by[2], const vf bz[2])
{
    const vf zero = vf_set(0.0f);
    /* s = min + max = 2 centre, d = max - min = 2 extent; rows are halved */
    vf sx = vf_add(bx[0], bx[1]), dx = vf_sub(bx[1], bx[0]);
    vf sy = vf_add(by[0], by[1]), dy = vf_sub(by[1], by[0]);
    vf sz = vf_add(bz[0], bz[1]), dz = vf_sub(bz[1], bz[0]);
    vf X = vf_fma(vf_set(k->hx[0]), sx, vf_fma(vf_set(k->hx[1]), sy, vf_fma(vf_set(k->hx[2]), sz, vf_set(k->cx[3]))));
    vf Y = vf_fma(vf_set(k->hy[0]), sx, vf_fma(vf_set(k->hy[1]), sy, vf_fma(vf_set(k->hy[2]), sz, vf_set(k->cy[3]))));
    vf Wc = vf_fma(vf_set(k->hw[0]), sx, vf_fma(vf_set(k->hw[1]), sy, vf_fma(vf_set(k->hw[2]), sz, vf_set(k->cw[3]))));
    vf Ex = vf_fma(vf_set(k->ax[0]), dx, vf_fma(vf_set(k->ax[1]), dy, vf_mul(vf_set(k->ax[2]), dz)));
    vf Ey = vf_fma(vf_set(k->ay[0]), dx, vf_fma(vf_set(k->ay[1]), dy, vf_mul(vf_set(k->ay[2]), dz)));
    vf Ew = vf_fma(vf_set(k->aw[0]), dx, vf_fma(vf_set(k->aw[1]), dy, vf_mul(vf_set(k->aw[2]), dz)));
    /* w within its rounding error of 0: no bound (the eye may be inside);
       the margin also covers the rounding of Ex, Ey and the quotients */
    vf wlo = vf_sub(Wc, Ew), whi = vf_add(Wc, Ew);
    vf wtol = vf_max(vf_set(1e-30f), vf_mul(vf_set(0x1p-20f), vf_add(vf_abs(Wc), Ew)));
    vm front = vf_ge(wlo, wtol);
    vf rlo = vf_rcp(wlo), rhi = vf_rcp(whi);
    vf xa = vf_sub(X, Ex), xb = vf_add(X, Ex), ya = vf_sub(Y, Ey), yb = vf_add(Y, Ey);
    vf x0 = vf_min(vf_mul(xa, rlo), vf_mul(xa, rhi)), x1 = vf_max(vf_mul(xb, rlo), vf_mul(xb, rhi));
    vf y0 = vf_min(vf_mul(ya, rlo), vf_mul(ya, rhi)), y1 = vf_max(vf_mul(yb, rlo), vf_mul(yb, rhi));
    /* pixels: (ndc + 1) * half, grown by 2^-16 half, clipped to the viewport */
    vf hw = vf_set(k->half_w), hh = vf_set(k->half_h), vw = vf_set(k->vp_w), vh = vf_set(k->vp_h);
    vf gw = vf_set(k->half_w * 0x1p-16f), gh = vf_set(k->half_h * 0x1p-16f);
    vf px0 = vf_min(vf_max(vf_fma(x0, hw, vf_set(k->off_w)), zero), vw);
    vf px1 = vf_min(vf_max(vf_fma(x1, hw, vf_add(hw, gw)), zero), vw);
    vf py0 = vf_min(vf_max(vf_fma(y0, hh, vf_set(k->off_h)), zero), vh);
    vf py1 = vf_min(vf_max(vf_fma(y1, hh, vf_add(hh, gh)), zero), vh);
    return vf_select(front, vf_mul(vf_sub(px1, px0), vf_sub(py1, py0)), vf_mul(vw, vh));
}


/* The occlusion stage for the live lanes of one group: each box's pixel
 * rectangle in the view's occlusion buffer (every pixel its projection
 * touches) and its nearest nearness, then the buffer's hierarchy
 * (cull_occ.c). The rectangle is grown and the nearness raised by bounds
 * on their float error (2^-20 of the magnitudes that were summed, over
 * the nearest w); a box reaching w <= 0 within that error is kept. A box
 * whose rectangle misses the buffer entirely is not on screen: culled.
 * Returns the lanes still visible. */
/* The lanes of `lanes` whose NDC rectangle (grown by e) has a pixel of the
 * occlusion buffer not nearer than z. A rectangle that misses the buffer
 * is off screen: not visible. */
static inline uint32_t occ_rect_lanes(const cull_kview *restrict k, vf xmin, vf xmax, vf ymin, vf ymax, vf e, vf z,
                                      uint32_t lanes, vf rect[4], uint32_t seen)
{
    vf one = vf_set(1.0f), hw = vf_set(k->occ_sx), hh = vf_set(k->occ_sy);
    vf lo = vf_set(-1.0f), hix = vf_set(k->occ_w + 1.0f), hiy = vf_set(k->occ_h + 1.0f);
    float fz[W];
    vf_store(fz, z);
    return occ_rect_group(k->occ, vf_min(vf_max(vf_mul(vf_sub(vf_add(xmin, one), e), hw), lo), hix),
                          vf_min(vf_max(vf_mul(vf_add(vf_add(xmax, one), e), hw), lo), hix),
                          vf_min(vf_max(vf_mul(vf_sub(vf_add(ymin, one), e), hh), lo), hiy),
                          vf_min(vf_max(vf_mul(vf_add(vf_add(ymax, one), e), hh), lo), hiy), fz, lanes, rect, seen);
}

static inline uint32_t occ_lanes(const cull_kview *restrict k, const vf bx[2], const vf by[2], const vf bz[2],
                                 uint32_t live)
{
    vf ax = vf_max(vf_abs(bx[0]), vf_abs(bx[1]));
    vf ay = vf_max(vf_abs(by[0]), vf_abs(by[1]));
    vf az = vf_max(vf_abs(bz[0]), vf_abs(bz[1]));
    vf px[2][3], py[2][3], pw[2][3];
    vf dmax = vf_set(k->cd[3]), wmin = vf_set(0.0f), wmax = vf_set(0.0f);
#pragma GCC unroll 2
    for (int s = 0; s < 2; s++) {
        px[s][0] = vf_mul(vf_set(k->cx[0]), bx[s]);
        px[s][1] = vf_mul(vf_set(k->cx[1]), by[s]);
        px[s][2] = vf_fma(vf_set(k->cx[2]), bz[s], vf_set(k->cx[3]));
        py[s][0] = vf_mul(vf_set(k->cy[0]), bx[s]);
        py[s][1] = vf_mul(vf_set(k->cy[1]), by[s]);
        py[s][2] = vf_fma(vf_set(k->cy[2]), bz[s], vf_set(k->cy[3]));
        pw[s][0] = vf_mul(vf_set(k->cw[0]), bx[s]);
        pw[s][1] = vf_mul(vf_set(k->cw[1]), by[s]);
        pw[s][2] = vf_fma(vf_set(k->cw[2]), bz[s], vf_set(k->cw[3]));
    }
    /* nearest nearness: max over corners of d / w, with d and w sums of
       per-axis terms (one of them constant: 1/w in perspective, w = 1 in
       orthographic views) */
    const vf *bs[3] = {bx, by, bz};
#pragma GCC unroll 3
    for (int a = 0; a < 3; a++) {
        vf d0 = vf_mul(vf_set(k->cd[a]), bs[a][0]), d1 = vf_mul(vf_set(k->cd[a]), bs[a][1]);
        dmax = vf_add(dmax, vf_max(d0, d1));
        wmin = vf_add(wmin, vf_min(pw[0][a], pw[1][a]));
        wmax = vf_add(wmax, vf_max(pw[0][a], pw[1][a]));
    }
    vf sw = vf_fma(vf_set(fabsf(k->cw[0])), ax, vf_fma(vf_set(fabsf(k->cw[1])), ay,
                   vf_fma(vf_set(fabsf(k->cw[2])), az, vf_set(fabsf(k->cw[3])))));
    vf sx = vf_fma(vf_set(fabsf(k->cx[0])), ax, vf_fma(vf_set(fabsf(k->cx[1])), ay,
                   vf_fma(vf_set(fabsf(k->cx[2])), az, vf_set(fabsf(k->cx[3])))));
    vf sy = vf_fma(vf_set(fabsf(k->cy[0])), ax, vf_fma(vf_set(fabsf(k->cy[1])), ay,
                   vf_fma(vf_set(fabsf(k->cy[2])), az, vf_set(fabsf(k->cy[3])))));
    vf sd = vf_fma(vf_set(fabsf(k->cd[0])), ax, vf_fma(vf_set(fabsf(k->cd[1])), ay,
                   vf_fma(vf_set(fabsf(k->cd[2])), az, vf_set(fabsf(k->cd[3])))));
    const vf eps = vf_set(0x1p-20f), zero = vf_set(0.0f);
    vf ew = vf_mul(eps, sw);
    vf wlo = vf_sub(wmin, ew);
    uint32_t front = vm_bits(vf_ge(wlo, vf_set(1e-30f))) & live;
    if (!front) return live;
    vf num = vf_fma(eps, sd, dmax);
    vf den = vf_select(vf_ge(num, zero), wlo, vf_add(wmax, ew));
    vf z = vf_div(num, den);
    z = vf_fma(vf_abs(z), eps, z);
    /* NDC error: (err X + |ndc| err W) / w, bounded generously */
    vf e = vf_fma(vf_mul(vf_set(0x1p-18f), vf_add(vf_add(sx, sy), sw)), vf_rcp(wlo), eps);
    /* first a cheap rectangle: over the box, clip x lies in [Xlo, Xhi] and
       w in [wlo, whi], so x / w lies between the quotients of their ends
       (2 reciprocals); what it hides is hidden */
    vf rlo = vf_rcp(wlo), rhi = vf_rcp(vf_add(wmax, ew));
    vf xlo = vf_add(vf_add(vf_min(px[0][0], px[1][0]), vf_min(px[0][1], px[1][1])), vf_min(px[0][2], px[1][2]));
    vf xhi = vf_add(vf_add(vf_max(px[0][0], px[1][0]), vf_max(px[0][1], px[1][1])), vf_max(px[0][2], px[1][2]));
    vf ylo = vf_add(vf_add(vf_min(py[0][0], py[1][0]), vf_min(py[0][1], py[1][1])), vf_min(py[0][2], py[1][2]));
    vf yhi = vf_add(vf_add(vf_max(py[0][0], py[1][0]), vf_max(py[0][1], py[1][1])), vf_max(py[0][2], py[1][2]));
    vf rect[4];
    uint32_t vis = occ_rect_lanes(k, vf_min(vf_mul(xlo, rlo), vf_mul(xlo, rhi)), vf_max(vf_mul(xhi, rlo), vf_mul(xhi, rhi)),
                                  vf_min(vf_mul(ylo, rlo), vf_mul(ylo, rhi)), vf_max(vf_mul(yhi, rlo), vf_mul(yhi, rhi)),
                                  e, z, front, rect, 0);
    if (vis) {
        /* then, for what may be visible, the exact rectangle of the 8
           projected corners (inside the cheap one) */
        vf xmin = vf_set(INFINITY), ymin = xmin, xmax = vf_set(-INFINITY), ymax = xmax;
#pragma GCC unroll 8
        for (int c = 0; c < 8; c++) {
            int i = c & 1, j = (c >> 1) & 1, l = c >> 2;
            vf X = vf_add(vf_add(px[i][0], px[j][1]), px[l][2]);
            vf Y = vf_add(vf_add(py[i][0], py[j][1]), py[l][2]);
            vf Wc = vf_add(vf_add(pw[i][0], pw[j][1]), pw[l][2]);
            vf rw = vf_rcp(Wc);
            xmin = vf_min(xmin, vf_mul(X, rw));
            xmax = vf_max(xmax, vf_mul(X, rw));
            ymin = vf_min(ymin, vf_mul(Y, rw));
            ymax = vf_max(ymax, vf_mul(Y, rw));
        }
        /* (a lane whose pixel rectangle is the cheap one's is visible:
           the same test) */
        vis = occ_rect_lanes(k, xmin, xmax, ymin, ymax, e, z, vis, rect, vis);
    }
    return (live & ~front) | vis;
}

/* A block's record against a kept buffer (cull_occ_memo) stands for view
 * k, or starts again. */
static void occ_memo_start(cull_occ_memo *restrict memo, const cull_kview *restrict k)
{
    float kc[20];
    __builtin_memcpy(kc, k->cx, 12 * sizeof(float));
    __builtin_memcpy(kc + 12, k->cd, 4 * sizeof(float));
    kc[16] = k->occ_sx, kc[17] = k->occ_sy, kc[18] = k->occ_w, kc[19] = k->occ_h;
    if (memo->valid && memo->occ == k->occ && !__builtin_memcmp(memo->kv, kc, sizeof kc)) return;
    __builtin_memcpy(memo->kv, kc, sizeof kc);
    memo->occ = k->occ;
    memo->in = 0;
    memo->valid = true;
}

/* occ_lanes through the block's record: the group at lane o with the
 * same live lanes and, bit for bit, the same boxes as recorded takes the
 * recorded verdicts; else it is tested and recorded. */
static uint32_t occ_lanes_kept(const cull_kview *restrict k, const vf bx[2], const vf by[2], const vf bz[2],
                               uint32_t live, cull_occ_memo *restrict memo, uint32_t o)
{
    const uint64_t gm = (uint64_t)((1u << W) - 1u) << o;
    if ((memo->in & gm) == (uint64_t)live << o) {
        vm same = vm_and(vm_and(vf_same(bx[0], vf_loadu(memo->box[0] + o)), vf_same(bx[1], vf_loadu(memo->box[1] + o))),
                         vm_and(vf_same(by[0], vf_loadu(memo->box[2] + o)), vf_same(by[1], vf_loadu(memo->box[3] + o))));
        same = vm_and(same, vm_and(vf_same(bz[0], vf_loadu(memo->box[4] + o)), vf_same(bz[1], vf_loadu(memo->box[5] + o))));
        if ((vm_bits(same) & live) == live) return (uint32_t)(memo->vis >> o) & live;
    }
    uint32_t vis = occ_lanes(k, bx, by, bz, live);
    vf_store(memo->box[0] + o, bx[0]);
    vf_store(memo->box[1] + o, bx[1]);
    vf_store(memo->box[2] + o, by[0]);
    vf_store(memo->box[3] + o, by[1]);
    vf_store(memo->box[4] + o, bz[0]);
    vf_store(memo->box[5] + o, bz[1]);
    memo->in = (memo->in & ~gm) | (uint64_t)live << o;
    memo->vis = (memo->vis & ~gm) | (uint64_t)vis << o;
    return vis;
}

/* The occlusion stage of the group at lane o, through the block's record
 * when there is one. Not inlined: the loops that call it keep their
 * registers for the frustum stages (inlined, the record's code cost the
 * frustum-only query ~2 % more instructions; as a call, ~0.1 %). */
static __attribute__((noinline)) uint32_t occ_group(const cull_kview *restrict k, const cull_block *restrict b,
                                                    uint32_t o, uint32_t live, cull_occ_memo *restrict memo)
{
    vf bx[2] = {vf_load(b->minx + o), vf_load(b->maxx + o)};
    vf by[2] = {vf_load(b->miny + o), vf_load(b->maxy + o)};
    vf bz[2] = {vf_load(b->minz + o), vf_load(b->maxz + o)};
    return memo ? occ_lanes_kept(k, bx, by, bz, live, memo, o) : occ_lanes(k, bx, by, bz, live);
}

/* ---- writing results ------------------------------------------------------ */
#if W == 8
/* Left-pack for AVX2 (no compress instruction): byte k of entry m is the
 * lane of the k-th set bit of m. */
static const uint64_t cull_pack_lut[256] = {
    0x0000000000000000ull, 0x0000000000000000ull, 0x0000000000000001ull, 0x0000000000000100ull,
    0x0000000000000002ull, 0x0000000000000200ull, 0x0000000000000201ull, 0x0000000000020100ull,
    0x0000000000000003ull, 0x0000000000000300ull, 0x0000000000000301ull, 0x0000000000030100ull,
    0x0000000000000302ull, 0x0000000000030200ull, 0x0000000000030201ull, 0x0000000003020100ull,
    0x0000000000000004ull, 0x0000000000000400ull, 0x0000000000000401ull, 0x0000000000040100ull,
    0x0000000000000402ull, 0x0000000000040200ull, 0x0000000000040201ull, 0x0000000004020100ull,
    0x0000000000000403ull, 0x0000000000040300ull, 0x0000000000040301ull, 0x0000000004030100ull,
    0x0000000000040302ull, 0x0000000004030200ull, 0x0000000004030201ull, 0x0000000403020100ull,
    0x0000000000000005ull, 0x0000000000000500ull, 0x0000000000000501ull, 0x0000000000050100ull,
    0x0000000000000502ull, 0x0000000000050200ull, 0x0000000000050201ull, 0x0000000005020100ull,
    0x0000000000000503ull, 0x0000000000050300ull, 0x0000000000050301ull, 0x0000000005030100ull,
    0x0000000000050302ull, 0x0000000005030200ull, 0x0000000005030201ull, 0x0000000503020100ull,
    0x0000000000000504ull, 0x0000000000050400ull, 0x0000000000050401ull, 0x0000000005040100ull,
    0x0000000000050402ull, 0x0000000005040200ull, 0x0000000005040201ull, 0x0000000504020100ull,
    0x0000000000050403ull, 0x0000000005040300ull, 0x0000000005040301ull, 0x0000000504030100ull,
    0x0000000005040302ull, 0x0000000504030200ull, 0x0000000504030201ull, 0x0000050403020100ull,
    0x0000000000000006ull, 0x0000000000000600ull, 0x0000000000000601ull, 0x0000000000060100ull,
    0x0000000000000602ull, 0x0000000000060200ull, 0x0000000000060201ull, 0x0000000006020100ull,
    0x0000000000000603ull, 0x0000000000060300ull, 0x0000000000060301ull, 0x0000000006030100ull,
    0x0000000000060302ull, 0x0000000006030200ull, 0x0000000006030201ull, 0x0000000603020100ull,
    0x0000000000000604ull, 0x0000000000060400ull, 0x0000000000060401ull, 0x0000000006040100ull,
    0x0000000000060402ull, 0x0000000006040200ull, 0x0000000006040201ull, 0x0000000604020100ull,
    0x0000000000060403ull, 0x0000000006040300ull, 0x0000000006040301ull, 0x0000000604030100ull,
    0x0000000006040302ull, 0x0000000604030200ull, 0x0000000604030201ull, 0x0000060403020100ull,
    0x0000000000000605ull, 0x0000000000060500ull, 0x0000000000060501ull, 0x0000000006050100ull,
    0x0000000000060502ull, 0x0000000006050200ull, 0x0000000006050201ull, 0x0000000605020100ull,
    0x0000000000060503ull, 0x0000000006050300ull, 0x0000000006050301ull, 0x0000000605030100ull,
    0x0000000006050302ull, 0x0000000605030200ull, 0x0000000605030201ull, 0x0000060503020100ull,
    0x0000000000060504ull, 0x0000000006050400ull, 0x0000000006050401ull, 0x0000000605040100ull,
    0x0000000006050402ull, 0x0000000605040200ull, 0x0000000605040201ull, 0x0000060504020100ull,
    0x0000000006050403ull, 0x0000000605040300ull, 0x0000000605040301ull, 0x0000060504030100ull,
    0x0000000605040302ull, 0x0000060504030200ull, 0x0000060504030201ull, 0x0006050403020100ull,
    0x0000000000000007ull, 0x0000000000000700ull, 0x0000000000000701ull, 0x0000000000070100ull,
    0x0000000000000702ull, 0x0000000000070200ull, 0x0000000000070201ull, 0x0000000007020100ull,
    0x0000000000000703ull, 0x0000000000070300ull, 0x0000000000070301ull, 0x0000000007030100ull,
    0x0000000000070302ull, 0x0000000007030200ull, 0x0000000007030201ull, 0x0000000703020100ull,
    0x0000000000000704ull, 0x0000000000070400ull, 0x0000000000070401ull, 0x0000000007040100ull,
    0x0000000000070402ull, 0x0000000007040200ull, 0x0000000007040201ull, 0x0000000704020100ull,
    0x0000000000070403ull, 0x0000000007040300ull, 0x0000000007040301ull, 0x0000000704030100ull,
    0x0000000007040302ull, 0x0000000704030200ull, 0x0000000704030201ull, 0x0000070403020100ull,
    0x0000000000000705ull, 0x0000000000070500ull, 0x0000000000070501ull, 0x0000000007050100ull,
    0x0000000000070502ull, 0x0000000007050200ull, 0x0000000007050201ull, 0x0000000705020100ull,
    0x0000000000070503ull, 0x0000000007050300ull, 0x0000000007050301ull, 0x0000000705030100ull,
    0x0000000007050302ull, 0x0000000705030200ull, 0x0000000705030201ull, 0x0000070503020100ull,
    0x0000000000070504ull, 0x0000000007050400ull, 0x0000000007050401ull, 0x0000000705040100ull,
    0x0000000007050402ull, 0x0000000705040200ull, 0x0000000705040201ull, 0x0000070504020100ull,
    0x0000000007050403ull, 0x0000000705040300ull, 0x0000000705040301ull, 0x0000070504030100ull,
    0x0000000705040302ull, 0x0000070504030200ull, 0x0000070504030201ull, 0x0007050403020100ull,
    0x0000000000000706ull, 0x0000000000070600ull, 0x0000000000070601ull, 0x0000000007060100ull,
    0x0000000000070602ull, 0x0000000007060200ull, 0x0000000007060201ull, 0x0000000706020100ull,
    0x0000000000070603ull, 0x0000000007060300ull, 0x0000000007060301ull, 0x0000000706030100ull,
    0x0000000007060302ull, 0x0000000706030200ull, 0x0000000706030201ull, 0x0000070603020100ull,
    0x0000000000070604ull, 0x0000000007060400ull, 0x0000000007060401ull, 0x0000000706040100ull,
    0x0000000007060402ull, 0x0000000706040200ull, 0x0000000706040201ull, 0x0000070604020100ull,
    0x0000000007060403ull, 0x0000000706040300ull, 0x0000000706040301ull, 0x0000070604030100ull,
    0x0000000706040302ull, 0x0000070604030200ull, 0x0000070604030201ull, 0x0007060403020100ull,
    0x0000000000070605ull, 0x0000000007060500ull, 0x0000000007060501ull, 0x0000000706050100ull,
    0x0000000007060502ull, 0x0000000706050200ull, 0x0000000706050201ull, 0x0000070605020100ull,
    0x0000000007060503ull, 0x0000000706050300ull, 0x0000000706050301ull, 0x0000070605030100ull,
    0x0000000706050302ull, 0x0000070605030200ull, 0x0000070605030201ull, 0x0007060503020100ull,
    0x0000000007060504ull, 0x0000000706050400ull, 0x0000000706050401ull, 0x0000070605040100ull,
    0x0000000706050402ull, 0x0000070605040200ull, 0x0000070605040201ull, 0x0007060504020100ull,
    0x0000000706050403ull, 0x0000070605040300ull, 0x0000070605040301ull, 0x0007060504030100ull,
    0x0000070605040302ull, 0x0007060504030200ull, 0x0007060504030201ull, 0x0706050403020100ull,
};

/* Writes the live lanes of group o as results; stores all 8 slots (callers
 * leave CULL_RESULT_PAD spare entries), returns how many are valid. */
static inline uint32_t emit_group(cull_result *restrict out, const cull_block *restrict b, uint32_t o,
                                  uint32_t live, vu mask, vf area)
{
    __m256i idx = _mm256_cvtepu8_epi32(_mm_loadl_epi64((const __m128i *)&cull_pack_lut[live]));
    __m256i h = _mm256_load_si256((const __m256i *)(b->handle + o));
    __m256i cs = _mm256_load_si256((const __m256i *)(b->class_sub + o));
    h = _mm256_permutevar8x32_epi32(h, idx);
    __m256i m = _mm256_permutevar8x32_epi32(mask, idx);
    cs = _mm256_permutevar8x32_epi32(cs, idx);
    __m256i a = _mm256_permutevar8x32_epi32(_mm256_castps_si256(area), idx);
    /* 4 x 8 transpose into eight {handle, mask, class|sublevel, area} */
    __m256i t0 = _mm256_unpacklo_epi32(h, m), t1 = _mm256_unpackhi_epi32(h, m);
    __m256i t2 = _mm256_unpacklo_epi32(cs, a), t3 = _mm256_unpackhi_epi32(cs, a);
    __m256i r0 = _mm256_unpacklo_epi64(t0, t2), r1 = _mm256_unpackhi_epi64(t0, t2);
    __m256i r2 = _mm256_unpacklo_epi64(t1, t3), r3 = _mm256_unpackhi_epi64(t1, t3);
    __m256i *d = (__m256i *)out;
    _mm256_storeu_si256(d + 0, _mm256_permute2x128_si256(r0, r1, 0x20));
    _mm256_storeu_si256(d + 1, _mm256_permute2x128_si256(r2, r3, 0x20));
    _mm256_storeu_si256(d + 2, _mm256_permute2x128_si256(r0, r1, 0x31));
    _mm256_storeu_si256(d + 3, _mm256_permute2x128_si256(r2, r3, 0x31));
    return (uint32_t)__builtin_popcount(live);
}
#else
static inline uint32_t emit_group(cull_result *restrict out, const cull_block *restrict b, uint32_t o,
                                  uint32_t live, vu mask, vf area)
{
    uint32_t mk[W], k = 0;
    float ar[W];
    vu_store(mk, mask);
    vf_store(ar, area);
    do {
        uint32_t l = (uint32_t)__builtin_ctz(live);
        live &= live - 1;
        cull_result *res = &out[k++];
        res->handle = b->handle[o + l];
        res->view_mask = mk[l];
        res->class_id = (uint16_t)b->class_sub[o + l];
        res->sublevel = (uint16_t)(b->class_sub[o + l] >> 16);
        res->screen_area = ar[l];
    } while (live);
    return k;
}
#endif


/* The common shape, one view, fused: test, screen area, then write the
 * group's survivors at once (no mask arrays, no second pass). area: 0 none,
 * 1 threshold on the upper bound, 2 exact. */
static inline __attribute__((always_inline)) uint32_t
single_view(const cull_block *restrict b, uint32_t n, const cull_kview *restrict k, const uint32_t NP, bool aabb,
            int area, float min_area, bool count_only, cull_result *restrict out, uint32_t *c_sph,
            uint32_t *c_aabb, uint32_t *c_area, uint32_t *c_occ, cull_occ_memo *restrict memo)
{
    vf px[6], py[6], pz[6], pd[6];
    const float *bxp[6], *byp[6], *bzp[6];
#pragma GCC unroll 6
    for (uint32_t i = 0; i < NP; i++) {
        px[i] = vf_set(k->px[i]);
        py[i] = vf_set(k->py[i]);
        pz[i] = vf_set(k->pz[i]);
        pd[i] = vf_set(k->pd[i]);
        bxp[i] = k->px[i] >= 0.0f ? b->maxx : b->minx;
        byp[i] = k->py[i] >= 0.0f ? b->maxy : b->miny;
        bzp[i] = k->pz[i] >= 0.0f ? b->maxz : b->minz;
    }
    const vf zero = vf_set(0.0f), none = vf_set(-1.0f), thr = vf_set(min_area);
    const vu bit = vu_or_bit(vu_zero(), vm_ones(), k->bit);
    uint32_t written = 0, ns = 0, na = 0, nr = 0, no = 0;
    for (uint32_t o = 0; o < n; o += W) {
        const uint32_t valid = n - o >= W ? (1u << W) - 1u : (1u << (n - o)) - 1u;
        uint32_t live = valid;
        if (NP) {
            vf x = vf_load(b->x + o), y = vf_load(b->y + o), z = vf_load(b->z + o), r = vf_load(b->r + o);
            vf smin = vf_fma(px[0], x, vf_fma(py[0], y, vf_fma(pz[0], z, pd[0])));
#pragma GCC unroll 6
            for (uint32_t i = 1; i < NP; i++)
                smin = vf_min(smin, vf_fma(px[i], x, vf_fma(py[i], y, vf_fma(pz[i], z, pd[i]))));
            vm vis = vf_ge(vf_add(smin, r), zero);
            live &= vm_bits(vis);
            ns += (uint32_t)__builtin_popcount(live);
            if (aabb) {
                vm straddle = vm_andnot(vis, vf_ge(smin, r));
                if (vm_bits(straddle) & live) {
                    vf amin = vf_fma(px[0], vf_load(bxp[0] + o),
                                     vf_fma(py[0], vf_load(byp[0] + o), vf_fma(pz[0], vf_load(bzp[0] + o), pd[0])));
#pragma GCC unroll 6
                    for (uint32_t i = 1; i < NP; i++)
                        amin = vf_min(amin, vf_fma(px[i], vf_load(bxp[i] + o),
                                                   vf_fma(py[i], vf_load(byp[i] + o),
                                                          vf_fma(pz[i], vf_load(bzp[i] + o), pd[i]))));
                    live &= ~vm_bits(vm_and(straddle, vf_lt(amin, zero)));
                }
            }
        } else {
            ns += (uint32_t)__builtin_popcount(live);
        }
        if (!live) continue;
        na += (uint32_t)__builtin_popcount(live);
        vf a = none;
        if (area) {
            vf bx[2] = {vf_load(b->minx + o), vf_load(b->maxx + o)};
            vf by[2] = {vf_load(b->miny + o), vf_load(b->maxy + o)};
            vf bz[2] = {vf_load(b->minz + o), vf_load(b->maxz + o)};
            a = area == 2 ? box_area(k, bx, by, bz) : area_upper(k, bx, by, bz);
            if (min_area > 0) live &= ~vm_bits(vf_lt(a, thr));
            if (area == 1) a = none;
            if (!live) continue;
        }
        nr += (uint32_t)__builtin_popcount(live);
        if (k->occ) {
            if (k->hot) {
                /* the record stands: its verdicts for the lanes it tested
                   (the same lanes, by the record's terms; one it did not
                   would stay visible, never be hidden) */
                const uint32_t in = (uint32_t)(memo->in >> o), vis = (uint32_t)(memo->vis >> o);
                live &= vis | ~in;
            } else {
                live = occ_group(k, b, o, live, memo);
            }
            if (!live) continue;
        }
        no += (uint32_t)__builtin_popcount(live);
        written += count_only ? (uint32_t)__builtin_popcount(live) : emit_group(out + written, b, o, live, bit, a);
    }
    *c_sph += ns;
    *c_aabb += na;
    *c_area += nr;
    *c_occ += no;
    return written;
}

uint32_t CULL_KERNEL_NAME(const cull_block *restrict b, uint32_t n, const cull_kview *restrict kv, uint32_t nv,
                          const cull_kparams *restrict p, cull_result *restrict out, cull_kcount *restrict cnt,
                          cull_occ_memo *restrict memo)
{
    const uint32_t ng = (n + W - 1) / W;
    const bool aabb = p->aabb, want_area = p->area, exact_area = p->exact_area;
    const float min_area = p->min_area;

    if (nv == 1) {
        const int am = !want_area ? 0 : exact_area ? 2 : 1;
        uint32_t cs = 0, ca = 0, cr = 0, co = 0, written;
        if (memo && kv->occ) {
            if (!kv->hot) occ_memo_start(memo, kv);
        } else {
            memo = NULL;
        }
#define CULL_ONE(NP) single_view(b, n, kv, NP, aabb, am, min_area, p->count_only, out, &cs, &ca, &cr, &co, memo)
        switch (kv->nplanes) {
        case 0: written = CULL_ONE(0); break;
        case 1: written = CULL_ONE(1); break;
        case 2: written = CULL_ONE(2); break;
        case 3: written = CULL_ONE(3); break;
        case 4: written = CULL_ONE(4); break;
        case 5: written = CULL_ONE(5); break;
        default: written = CULL_ONE(6); break;
        }
#undef CULL_ONE
        cnt->tested += n;
        cnt->after_spheres += cs;
        cnt->after_aabb += ca;
        cnt->after_area += cr;
        cnt->after_occ += co;
        return written;
    }

    vu mask[CULL_KV_MAX_GROUPS], msph[CULL_KV_MAX_GROUPS];
#pragma GCC unroll 8
    for (uint32_t g = 0; g < CULL_KV_MAX_GROUPS; g++) mask[g] = msph[g] = vu_zero();

    for (uint32_t v = 0; v < nv; v++) {
        const cull_kview *k = &kv[v];
        switch (k->nplanes) {
        case 0:
            for (uint32_t g = 0; g < ng; g++) {
                mask[g] = vu_or_bit(mask[g], vm_ones(), k->bit);
                msph[g] = vu_or_bit(msph[g], vm_ones(), k->bit);
            }
            break;
        case 1: sphere_pass(b, ng, k, 1, aabb, mask, msph); break;
        case 2: sphere_pass(b, ng, k, 2, aabb, mask, msph); break;
        case 3: sphere_pass(b, ng, k, 3, aabb, mask, msph); break;
        case 4: sphere_pass(b, ng, k, 4, aabb, mask, msph); break;
        case 5: sphere_pass(b, ng, k, 5, aabb, mask, msph); break;
        default: sphere_pass(b, ng, k, 6, aabb, mask, msph); break;
        }
    }

    /* lanes past n hold stale data: mask them here, once */
    for (uint32_t g = 0; g < ng; g++) {
        const uint32_t left = n - g * W;
        if (left < W) {
            vm ok = vf_lt(vf_load(cull_lane_index), vf_set((float)left));
            mask[g] = vu_clear_bit(mask[g], vm_andnot(vm_ones(), ok), ~0u);
            msph[g] = vu_clear_bit(msph[g], vm_andnot(vm_ones(), ok), ~0u);
        }
    }
    uint32_t c_sph = 0, c_aabb = 0;
    for (uint32_t g = 0; g < ng; g++) {
        c_sph += (uint32_t)__builtin_popcount(vu_nonzero_bits(msph[g]));
        c_aabb += (uint32_t)__builtin_popcount(vu_nonzero_bits(mask[g]));
    }

    /* screen area, view outer so the view's constants stay in registers */
    vf area[CULL_KV_MAX_GROUPS];
    for (uint32_t g = 0; g < ng; g++) area[g] = vf_set(exact_area ? 0.0f : -1.0f);
    if (want_area && c_aabb) {
        const vf thr = vf_set(min_area);
        for (uint32_t v = 0; v < nv; v++) {
            const cull_kview *k = &kv[v];
            for (uint32_t g = 0; g < ng; g++) {
                vm in = vu_has_bit(mask[g], k->bit);
                if (!vm_bits(in)) continue;
                const uint32_t o = g * W;
                vf bx[2] = {vf_load(b->minx + o), vf_load(b->maxx + o)};
                vf by[2] = {vf_load(b->miny + o), vf_load(b->maxy + o)};
                vf bz[2] = {vf_load(b->minz + o), vf_load(b->maxz + o)};
                if (exact_area) {
                    vf a = box_area(k, bx, by, bz);
                    if (min_area > 0) {
                        vm small = vm_and(in, vf_lt(a, thr));
                        mask[g] = vu_clear_bit(mask[g], small, k->bit);
                        in = vm_andnot(in, small);
                    }
                    area[g] = vf_select(in, vf_max(area[g], a), area[g]);
                } else {
                    /* threshold only: the cheap upper bound decides */
                    vm small = vm_and(in, vf_lt(area_upper(k, bx, by, bz), thr));
                    mask[g] = vu_clear_bit(mask[g], small, k->bit);
                }
            }
        }
    }

    uint32_t c_area = 0;
    for (uint32_t g = 0; g < ng; g++) c_area += (uint32_t)__builtin_popcount(vu_nonzero_bits(mask[g]));

    /* occlusion, per view that has a buffer */
    for (uint32_t v = 0; v < nv; v++) {
        const cull_kview *k = &kv[v];
        if (!k->occ) continue;
        for (uint32_t g = 0; g < ng; g++) {
            uint32_t in = vm_bits(vu_has_bit(mask[g], k->bit));
            if (!in) continue;
            const uint32_t o = g * W;
            vf bx[2] = {vf_load(b->minx + o), vf_load(b->maxx + o)};
            vf by[2] = {vf_load(b->miny + o), vf_load(b->maxy + o)};
            vf bz[2] = {vf_load(b->minz + o), vf_load(b->maxz + o)};
            uint32_t kept = occ_lanes(k, bx, by, bz, in);
            if (kept != in) mask[g] = vu_clear_bit(mask[g], vm_from_bits(in & ~kept), k->bit);
        }
    }

    uint32_t written = 0, c_occ = 0;
    for (uint32_t g = 0; g < ng; g++) {
        uint32_t live = vu_nonzero_bits(mask[g]);
        if (!live) continue;
        c_occ += (uint32_t)__builtin_popcount(live);
        written += p->count_only ? (uint32_t)__builtin_popcount(live)
                                 : emit_group(out + written, b, g * W, live, mask[g], area[g]);
    }
    cnt->tested += n;
    cnt->after_spheres += c_sph;
    cnt->after_aabb += c_aabb;
    cnt->after_area += c_area;
    cnt->after_occ += c_occ;
    return written;
}
