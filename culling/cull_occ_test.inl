/*
 * cull_occ_test.inl — the occlusion buffer's rectangle test, written once
 * over cull_simd.h and compiled per ISA (included by cull_kernel.inl; the
 * exported wrappers are in cull_occ_kern.inl). What the query's kernel
 * (8 entities a step with AVX2, 4 with SSE4.1) and its cell stage run.
 *
 * The answer is cull_occ_rect_visible's (cull_occ.c, the scalar
 * reference) bit for bit: the rectangle is visible where some tile t it
 * reaches has teff <= z and (t is invalid, or one of the rectangle's
 * pixels in t is <= z). Only the order of the work differs:
 *   - vkey <= z (cull_occ_vkey_row: every real pixel of t <= z, or t
 *     invalid) answers "visible" at t without reading a pixel;
 *   - the 64x64 tiles' and the strips' (64x8) minima skip tiles whose teff
 *     are all > z: both are minima of teff, never above it;
 *   - a tile's pixels are read a row (8 floats) at a time, and the row
 *     masks of the rectangle's part of the tile or'ed, not one pixel a
 *     step.
 * Cost: a hidden 1-4 tile entity is 1-4 loads and compares; a visible one
 * a vkey load, or a few 8-float rows. test_occ_wide_matches_scalar checks
 * every ISA against the reference on rendered buffers, random rectangles
 * and nearness at and next to the buffer's own values.
 */

/* Tile (tx, ty) shows the rectangle [x0, x1] x [y0, y1] (which reaches it)
 * at nearness z. */
static inline bool occ_tile_shows(const cull_occ_buffer *restrict b, int tx, int ty, int x0, int y0, int x1, int y1,
                                  float z, vf vz)
{
    size_t i = (size_t)ty * b->tw + (size_t)tx;
    if (b->teff[i] > z) return false;
    if (b->vkey[i] <= z || b->tstate[(size_t)ty * b->tpitch + (size_t)tx] == OCC_TILE_INVALID) return true;
    int py0 = ty * 8 > y0 ? ty * 8 : y0, py1 = ty * 8 + 7 < y1 ? ty * 8 + 7 : y1;
    int px0 = tx * 8 > x0 ? 0 : x0 & 7, px1 = tx * 8 + 7 < x1 ? 7 : x1 & 7;
    uint32_t cols = (0xFFu << px0) & (0xFFu >> (7 - px1));
    /* 32-byte aligned: the pool is 64, a tile 256 bytes */
    const float *row = cull_occ_tile_px(b, i) + 8 * (py0 & 7);
    uint32_t hit = 0;
    for (int py = py0; py <= py1; py++, row += 8)
        for (int c = 0; c < 8; c += W) hit |= vm_bits(vf_le(vf_load(row + c), vz)) << c;
    return (hit & cols) != 0;
}

/* cull_occ_rect_visible: a rectangle inside the buffer (x0 <= x1, y0 <= y1). */
static inline bool occ_rect_walk(const cull_occ_buffer *restrict b, int x0, int y0, int x1, int y1, float z)
{
    const vf vz = vf_set(z);
    const int tx0 = x0 >> 3, tx1 = x1 >> 3, ty0 = y0 >> 3, ty1 = y1 >> 3;
    if (tx1 - tx0 < 4 && ty1 - ty0 < 4) {
        /* up to 4 x 4 tiles (most entities): directly */
        for (int ty = ty0; ty <= ty1; ty++)
            for (int tx = tx0; tx <= tx1; tx++)
                if (occ_tile_shows(b, tx, ty, x0, y0, x1, y1, z, vz)) return true;
        return false;
    }
    for (int Y = y0 >> 6; Y <= y1 >> 6; Y++)
        for (int X = x0 >> 6; X <= x1 >> 6; X++) {
            if (b->tile2[(size_t)Y * b->t2w + (size_t)X] > z) continue;
            int a0 = Y * 8 > ty0 ? Y * 8 : ty0, a1 = Y * 8 + 7 < ty1 ? Y * 8 + 7 : ty1;
            int c0 = X * 8 > tx0 ? X * 8 : tx0, c1 = X * 8 + 7 < tx1 ? X * 8 + 7 : tx1;
            for (int ty = a0; ty <= a1; ty++) {
                if (b->strip[(size_t)ty * b->spitch + (size_t)X] > z) continue;
                for (int tx = c0; tx <= c1; tx++)
                    if (occ_tile_shows(b, tx, ty, x0, y0, x1, y1, z, vz)) return true;
            }
        }
    return false;
}

/* The lanes of `lanes` whose pixel bounds (floats in [-1, w + 1] x
 * [-1, h + 1]: every pixel i with fx0 < i + 1 and i < fx1) reach the
 * buffer and are visible at nearness z. The pixel rectangles are taken
 * from the bounds a group at a time, by the same float steps the scalar
 * conversion made ((int)(f + 1) - 1 for the floor of f >= -1, the
 * truncation, less one where it is not below f, for the ceiling less
 * one); then each lane walks.
 * rect (NULL: none) holds the group's pixel rectangles as floats {x0, x1,
 * y0, y1}: with seen 0 they are stored there; with seen set (lanes
 * already found visible at the same z with the rectangles in rect), a lane
 * whose rectangle is the same is visible without a test. */
static inline uint32_t occ_rect_group(const cull_occ_buffer *restrict b, vf fx0, vf fx1, vf fy0, vf fy1,
                                      const float *zl, uint32_t lanes, vf *rect, uint32_t seen)
{
    const vf one = vf_set(1.0f), zero = vf_set(0.0f);
    vf i0 = vf_max(vf_sub(vf_trunc(vf_add(fx0, one)), one), zero);
    vf j0 = vf_max(vf_sub(vf_trunc(vf_add(fy0, one)), one), zero);
    vf i1 = vf_trunc(fx1), j1 = vf_trunc(fy1);
    i1 = vf_min(vf_select(vf_lt(i1, fx1), i1, vf_sub(i1, one)), vf_set((float)b->w - 1.0f));
    j1 = vf_min(vf_select(vf_lt(j1, fy1), j1, vf_sub(j1, one)), vf_set((float)b->h - 1.0f));
    lanes &= vm_bits(vm_and(vf_le(i0, i1), vf_le(j0, j1)));
    if (!lanes) return 0;
    uint32_t vis = 0;
    if (rect && seen) {
        vm same = vm_and(vm_and(vm_and(vf_le(i0, rect[0]), vf_ge(i0, rect[0])), vm_and(vf_le(i1, rect[1]), vf_ge(i1, rect[1]))),
                         vm_and(vm_and(vf_le(j0, rect[2]), vf_ge(j0, rect[2])), vm_and(vf_le(j1, rect[3]), vf_ge(j1, rect[3]))));
        vis = vm_bits(same) & lanes & seen;
        lanes &= ~vis;
        if (!lanes) return vis;
    } else if (rect) {
        rect[0] = i0;
        rect[1] = i1;
        rect[2] = j0;
        rect[3] = j1;
    }
    /* rectangles within 2 x 2 tiles (most entities): their 4 corner
       tiles, gathered, decide the lanes they hide (every teff > z) or
       show (a vkey <= z); only the rest walk */
    const vf eighth = vf_set(0.125f), tw = vf_set((float)b->tw), vz = vf_loadu(zl);
    vf tx0 = vf_trunc(vf_mul(i0, eighth)), tx1 = vf_trunc(vf_mul(i1, eighth));
    vf ty0 = vf_trunc(vf_mul(j0, eighth)), ty1 = vf_trunc(vf_mul(j1, eighth));
    vm small = vm_and(vf_le(vf_sub(tx1, tx0), one), vf_le(vf_sub(ty1, ty0), one));
    uint32_t quick = vm_bits(small) & lanes;
    if (quick) {
        small = vm_from_bits(quick); /* other lanes read tile 0 */
        vf r0 = vf_select(small, vf_mul(ty0, tw), zero), r1 = vf_select(small, vf_mul(ty1, tw), zero);
        tx0 = vf_select(small, tx0, zero);
        tx1 = vf_select(small, tx1, zero);
        vf a = vf_add(r0, tx0), c = vf_add(r0, tx1), d = vf_add(r1, tx0), e = vf_add(r1, tx1);
        vf near = vf_min(vf_min(vf_lookup(b->teff, a), vf_lookup(b->teff, c)),
                         vf_min(vf_lookup(b->teff, d), vf_lookup(b->teff, e)));
        vf key = vf_min(vf_min(vf_lookup(b->vkey, a), vf_lookup(b->vkey, c)),
                        vf_min(vf_lookup(b->vkey, d), vf_lookup(b->vkey, e)));
        uint32_t hid = vm_bits(vf_lt(vz, near)) & quick, shown = vm_bits(vf_le(key, vz)) & quick;
        vis |= shown;
        lanes &= ~(hid | shown);
        if (!lanes) return vis;
    }
    int32_t x0[W], y0[W], x1[W], y1[W];
    vf_store_i32(x0, i0);
    vf_store_i32(y0, j0);
    vf_store_i32(x1, i1);
    vf_store_i32(y1, j1);
    for (uint32_t m = lanes; m; m &= m - 1) {
        uint32_t l = (uint32_t)__builtin_ctz(m);
        if (occ_rect_walk(b, x0[l], y0[l], x1[l], y1[l], zl[l])) vis |= 1u << l;
    }
    return vis;
}
