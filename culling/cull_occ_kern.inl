/*
 * cull_occ_kern.inl — the occlusion rasteriser's inner loops, written once
 * over cull_simd.h and compiled per ISA (cull_kernels_<isa>.c).
 * CULL_OCC_SUFFIX names the instance.
 */
#define CULL_OCC_CAT2(a, b) a##b
#define CULL_OCC_CAT(a, b) CULL_OCC_CAT2(a, b)

/* lane k holds k: cull_lane_index, from cull_kernel.inl (included first) */

/* row[x] = max(row[x], max(min(a0 + da x, b0 + db x, c0 + dc x), lo)), x in [x0, x1].
 * The last partial vector is masked (z = -FLT_MAX leaves a pixel as it
 * is) instead of finished one lane at a time; it may read and rewrite,
 * unchanged, pixels past x1 but never past `room` (the row's length in
 * memory), so no other row is touched. */
static inline __attribute__((always_inline)) void occ_span_row(float *restrict row, int x0, int x1, int room, vf va,
                                                               vf vb, vf vc, vf vda, vf vdb, vf vdc, vf vlo)
{
    const vf step = vf_set((float)W), iota = vf_load(cull_lane_index);
    int x = x0;
    vf fx = vf_add(vf_set((float)x0), iota);
    for (; x + W - 1 <= x1; x += W) {
        vf z = vf_max(vf_min(vf_min(vf_fma(vda, fx, va), vf_fma(vdb, fx, vb)), vf_fma(vdc, fx, vc)), vlo);
        vf_store(row + x, vf_max(vf_loadu(row + x), z));
        fx = vf_add(fx, step);
    }
    if (x > x1) return;
    if (x + W > room) { /* stay in the row: lanes before x0 are masked too */
        x = room - W;
        fx = vf_add(vf_set((float)x), iota);
    } /* (else fx is x's already: the steps add whole numbers exactly) */
    vm in = vm_and(vf_ge(fx, vf_set((float)x0)), vf_le(fx, vf_set((float)x1)));
    vf z = vf_max(vf_min(vf_min(vf_fma(vda, fx, va), vf_fma(vdb, fx, vb)), vf_fma(vdc, fx, vc)), vlo);
    z = vf_select(in, z, vf_set(-FLT_MAX));
    vf_store(row + x, vf_max(vf_loadu(row + x), z));
}

void CULL_OCC_CAT(cull_occ_span_, CULL_OCC_SUFFIX)(float *restrict row, int x0, int x1, int room, float a0,
                                                    float da, float b0, float db, float c0, float dc, float lo)
{
    occ_span_row(row, x0, x1, room, vf_set(a0), vf_set(b0), vf_set(c0), vf_set(da), vf_set(db), vf_set(dc),
                 vf_set(lo));
}

/* Row r of the tile row whose tile tx's pixels are at pool + 64 slot[tx]
 * over [x0, x1]: the same pixels as span over the row, a vector of one
 * tile at a time (W divides 8), its lanes outside [x0, x1] masked (z =
 * -FLT_MAX leaves a pixel as it is). fx is the pixel's index exactly. */
static inline __attribute__((always_inline)) void occ_span_tiles(float *restrict pool, const uint32_t *restrict slot,
                                                                 int r, int x0, int x1, vf va, vf vb, vf vc, vf vda,
                                                                 vf vdb, vf vdc, vf vlo)
{
    const vf iota = vf_load(cull_lane_index), step = vf_set((float)W);
    float *const row = pool + 8 * r;
    int x = x0 & ~(W - 1);
    vf fx = vf_add(vf_set((float)x), iota); /* (the steps add whole numbers exactly) */
    if (x < x0) {
        float *p = row + ((size_t)slot[x >> 3] << 6) + (W < 8 ? (x & 7) : 0);
        vm in = vm_and(vf_ge(fx, vf_set((float)x0)), vf_le(fx, vf_set((float)x1)));
        vf z = vf_max(vf_min(vf_min(vf_fma(vda, fx, va), vf_fma(vdb, fx, vb)), vf_fma(vdc, fx, vc)), vlo);
        vf_store(p, vf_max(vf_load(p), vf_select(in, z, vf_set(-FLT_MAX))));
        x += W;
        fx = vf_add(fx, step);
    }
    for (; x + W - 1 <= x1; x += W) {
        float *p = row + ((size_t)slot[x >> 3] << 6) + (W < 8 ? (x & 7) : 0);
        vf z = vf_max(vf_min(vf_min(vf_fma(vda, fx, va), vf_fma(vdb, fx, vb)), vf_fma(vdc, fx, vc)), vlo);
        vf_store(p, vf_max(vf_load(p), z));
        fx = vf_add(fx, step);
    }
    if (x > x1) return;
    float *p = row + ((size_t)slot[x >> 3] << 6) + (W < 8 ? (x & 7) : 0);
    vm in = vf_le(fx, vf_set((float)x1));
    vf z = vf_max(vf_min(vf_min(vf_fma(vda, fx, va), vf_fma(vdb, fx, vb)), vf_fma(vdc, fx, vc)), vlo);
    vf_store(p, vf_max(vf_load(p), vf_select(in, z, vf_set(-FLT_MAX))));
}

/* span over the 8 rows of a tile row held tile by tile (cull_occ_fns.spans):
 * row r over [x0[r], x1[r]] (none where x0[r] > x1[r]) less the columns
 * [g0, g1] (a tile row's coarse tiles; none where g0 > g1), from a0, b0,
 * c0 = z0[r], z0[8 + r], z0[16 + r]: the same pixels as span over each
 * part (one call and one set of broadcasts a tile row) */
void CULL_OCC_CAT(cull_occ_spans_, CULL_OCC_SUFFIX)(float *restrict pool, const uint32_t *restrict slot,
                                                     const int *x0, const int *x1, int g0, int g1, const float *z0,
                                                     float da, float db, float dc, float lo)
{
    const vf vda = vf_set(da), vdb = vf_set(db), vdc = vf_set(dc), vlo = vf_set(lo);
    for (int r = 0; r < 8; r++) {
        int s = x0[r], e = x1[r];
        if (s > e) continue;
        const vf va = vf_set(z0[r]), vb = vf_set(z0[8 + r]), vc = vf_set(z0[16 + r]);
        if (g0 > g1) {
            occ_span_tiles(pool, slot, r, s, e, va, vb, vc, vda, vdb, vdc, vlo);
            continue;
        }
        if (s < g0) occ_span_tiles(pool, slot, r, s, e < g0 - 1 ? e : g0 - 1, va, vb, vc, vda, vdb, vdc, vlo);
        if (e > g1) occ_span_tiles(pool, slot, r, s > g1 + 1 ? s : g1 + 1, e, va, vb, vc, vda, vdb, vdc, vlo);
    }
}

#if CULL_SIMD_ISA == 3
cull_occ_rowsum cull_occ_rows_avx2(const cull_occ_rowset *rs, int jb, int a, int b, int *lo, int *hi, float *z0)
{
    return cull_occ_rows8(rs, jb, a, b, lo, hi, z0);
}

/* cull_occ_project_scalar's projections, four boxes a vector (gathered
 * from the SoA by index), the same operations in the same order: minpd /
 * maxpd pick as dmin / dmax do, and the far nearness's choice is a blend
 * on the same compare. Lanes past n repeat box idx[0] and are stored in
 * the pitch's padding. */
void cull_occ_project_avx2(const cull_occ_buffer *b, const cull_bounds_soa *s, const uint32_t *idx, uint32_t n,
                           double *out, size_t pitch)
{
    const double *rows[5] = {b->rx, b->ry, b->rw, b->rd, b->rn};
    const __m256d sgn = _mm256_set1_pd(-0.0), grow = _mm256_set1_pd(1 + 0x1p-40), one = _mm256_set1_pd(1.0),
                  zero = _mm256_setzero_pd();
    for (uint32_t q = 0; q < n; q += 4) {
        uint32_t ii[4];
        for (uint32_t l = 0; l < 4; l++) ii[l] = idx[q + l < n ? q + l : 0];
        const __m128i vi = _mm_loadu_si128((const __m128i *)ii);
        __m256d c[3], e[3];
        for (int a = 0; a < 3; a++) {
            c[a] = _mm256_sub_pd(_mm256_i32gather_pd(CULL_SOA(s, a), vi, 8), _mm256_set1_pd(b->origin[a]));
            e[a] = _mm256_i32gather_pd(CULL_SOA(s, 3 + a), vi, 8);
        }
        __m256d v[5], ex[5];
        for (int k = 0; k < 5; k++) {
            const double *r = rows[k];
            __m256d t = _mm256_add_pd(_mm256_mul_pd(_mm256_set1_pd(r[0]), c[0]), _mm256_mul_pd(_mm256_set1_pd(r[1]), c[1]));
            t = _mm256_add_pd(t, _mm256_mul_pd(_mm256_set1_pd(r[2]), c[2]));
            v[k] = _mm256_add_pd(t, _mm256_set1_pd(r[3]));
            __m256d u = _mm256_add_pd(_mm256_mul_pd(_mm256_andnot_pd(sgn, _mm256_set1_pd(r[0])), e[0]),
                                      _mm256_mul_pd(_mm256_andnot_pd(sgn, _mm256_set1_pd(r[1])), e[1]));
            u = _mm256_add_pd(u, _mm256_mul_pd(_mm256_andnot_pd(sgn, _mm256_set1_pd(r[2])), e[2]));
            ex[k] = _mm256_mul_pd(u, grow);
        }
        __m256d wlo = _mm256_sub_pd(v[2], ex[2]), whi = _mm256_add_pd(v[2], ex[2]);
        /* !(n - en > 0) || !(wlo > 0) */
        __m256d ok = _mm256_and_pd(_mm256_cmp_pd(_mm256_sub_pd(v[4], ex[4]), zero, _CMP_GT_OQ),
                                   _mm256_cmp_pd(wlo, zero, _CMP_GT_OQ));
        __m256d il = _mm256_div_pd(one, wlo), ih = _mm256_div_pd(one, whi);
        __m256d xa = _mm256_sub_pd(v[0], ex[0]), xb = _mm256_add_pd(v[0], ex[0]);
        __m256d ya = _mm256_sub_pd(v[1], ex[1]), yb = _mm256_add_pd(v[1], ex[1]);
        __m256d d = _mm256_add_pd(v[3], ex[3]);
        double *o = out + q;
        _mm256_storeu_pd(o, _mm256_min_pd(_mm256_mul_pd(xa, il), _mm256_mul_pd(xa, ih)));
        _mm256_storeu_pd(o + pitch, _mm256_max_pd(_mm256_mul_pd(xb, il), _mm256_mul_pd(xb, ih)));
        _mm256_storeu_pd(o + 2 * pitch, _mm256_min_pd(_mm256_mul_pd(ya, il), _mm256_mul_pd(ya, ih)));
        _mm256_storeu_pd(o + 3 * pitch, _mm256_max_pd(_mm256_mul_pd(yb, il), _mm256_mul_pd(yb, ih)));
        _mm256_storeu_pd(o + 4 * pitch, _mm256_blendv_pd(_mm256_mul_pd(d, ih), _mm256_mul_pd(d, il),
                                                         _mm256_cmp_pd(d, zero, _CMP_GE_OQ)));
        _mm256_storeu_pd(o + 5 * pitch, _mm256_andnot_pd(ok, one));
    }
}


/* cull_occ_bound_rect over n projections (cull_occ_fns.project's arrays,
 * pitch apart), four a vector: code[i] its answer (OCC_BOX_*), r[i] the
 * rectangle where OCC_BOX_OK. The same operations as the scalar answer:
 * occ_dfloor4 / occ_dceil4, maxpd / minpd as dmax / dmin, and
 * cull_round_up as a conversion, a compare and one step of the float's
 * bits where the conversion rounded down. */
void cull_occ_rects_avx2(const cull_occ_buffer *b, const double *proj, size_t pitch, uint32_t n, int32_t *code,
                         cull_occ_rect *r)
{
    const __m256d one = _mm256_set1_pd(1.0),
                  zero = _mm256_setzero_pd(), sx = _mm256_set1_pd(b->sx), sy = _mm256_set1_pd(b->sy),
                  mw = _mm256_set1_pd(0x1p-20 * b->w), mh = _mm256_set1_pd(0x1p-20 * b->h),
                  w1 = _mm256_set1_pd(b->w - 1.0), h1 = _mm256_set1_pd(b->h - 1.0), sgn = _mm256_set1_pd(-0.0);
    for (uint32_t q = 0; q < n; q += 4) {
        const double *o = proj + q;
        __m256d x0 = _mm256_loadu_pd(o), x1 = _mm256_loadu_pd(o + pitch), y0 = _mm256_loadu_pd(o + 2 * pitch),
                y1 = _mm256_loadu_pd(o + 3 * pitch), nm = _mm256_loadu_pd(o + 4 * pitch),
                nearf = _mm256_loadu_pd(o + 5 * pitch);
        /* NEAR: the flag, a NaN bound, a nearness not finite */
        __m256d bad = _mm256_or_pd(_mm256_cmp_pd(nearf, zero, _CMP_NEQ_UQ),
                                   _mm256_or_pd(_mm256_cmp_pd(x0, x1, _CMP_UNORD_Q), _mm256_cmp_pd(y0, y1, _CMP_UNORD_Q)));
        bad = _mm256_or_pd(bad, _mm256_cmp_pd(_mm256_sub_pd(nm, nm), zero, _CMP_NEQ_UQ));
        __m256d i0 = _mm256_max_pd(occ_dfloor4(_mm256_sub_pd(_mm256_mul_pd(_mm256_add_pd(x0, one), sx), mw)), zero);
        __m256d i1 = _mm256_min_pd(_mm256_sub_pd(occ_dceil4(_mm256_add_pd(_mm256_mul_pd(_mm256_add_pd(x1, one), sx), mw)), one), w1);
        __m256d j0 = _mm256_max_pd(occ_dfloor4(_mm256_sub_pd(_mm256_mul_pd(_mm256_add_pd(y0, one), sy), mh)), zero);
        __m256d j1 = _mm256_min_pd(_mm256_sub_pd(occ_dceil4(_mm256_add_pd(_mm256_mul_pd(_mm256_add_pd(y1, one), sy), mh)), one), h1);
        __m256d in = _mm256_and_pd(_mm256_cmp_pd(i0, i1, _CMP_LE_OQ), _mm256_cmp_pd(j0, j1, _CMP_LE_OQ));
        /* the far nearness rounded up to float */
        __m256d v = _mm256_add_pd(nm, _mm256_mul_pd(_mm256_set1_pd(0x1p-20), _mm256_andnot_pd(sgn, nm)));
        __m128 f = _mm256_cvtpd_ps(v);
        __m128 up = _mm256_castps256_ps128(_mm256_permutevar8x32_ps(
            _mm256_castpd_ps(_mm256_cmp_pd(_mm256_cvtps_pd(f), v, _CMP_LT_OQ)), _mm256_setr_epi32(0, 2, 4, 6, 1, 3, 5, 7)));
        __m128i fb = _mm_castps_si128(f);
        /* one step up: +1 on the bits above zero, -1 below, the least
           denormal from zero */
        __m128i step = _mm_or_si128(_mm_srai_epi32(fb, 31), _mm_set1_epi32(1)); /* +1, or -1 with the sign */
        __m128i zf = _mm_castps_si128(_mm_cmpeq_ps(f, _mm_setzero_ps()));
        __m128i nb = _mm_blendv_epi8(_mm_add_epi32(fb, step), _mm_set1_epi32(1), zf);
        __m128 z = _mm_blendv_ps(f, _mm_castsi128_ps(nb), up);
        float zs[4];
        _mm_storeu_ps(zs, z);
        int32_t ii[4][4];
        _mm_storeu_si128((__m128i *)ii[0], _mm256_cvttpd_epi32(_mm256_blendv_pd(zero, i0, in)));
        _mm_storeu_si128((__m128i *)ii[1], _mm256_cvttpd_epi32(_mm256_blendv_pd(zero, i1, in)));
        _mm_storeu_si128((__m128i *)ii[2], _mm256_cvttpd_epi32(_mm256_blendv_pd(zero, j0, in)));
        _mm_storeu_si128((__m128i *)ii[3], _mm256_cvttpd_epi32(_mm256_blendv_pd(zero, j1, in)));
        int mbad = _mm256_movemask_pd(bad), min_ = _mm256_movemask_pd(in);
        for (uint32_t l = 0; l < 4 && q + l < n; l++) {
            code[q + l] = (mbad >> l) & 1 ? OCC_BOX_NEAR : (min_ >> l) & 1 ? OCC_BOX_OK : OCC_BOX_OFF;
            r[q + l] = (cull_occ_rect){ii[0][l], ii[2][l], ii[1][l], ii[3][l], zs[l]};
        }
    }
}
#endif

/* any row[x] <= z for x in [x0, x1]? (reads up to `room` as above) */
bool CULL_OCC_CAT(cull_occ_any_le_, CULL_OCC_SUFFIX)(const float *restrict row, int x0, int x1, int room, float z)
{
    int x = x0;
    const vf vz = vf_set(z);
    for (; x + W - 1 <= x1; x += W)
        if (vm_bits(vf_le(vf_loadu(row + x), vz))) return true;
    if (x > x1) return false;
    if (x + W > room) x = room - W;
    vf fx = vf_add(vf_set((float)x), vf_load(cull_lane_index));
    vm in = vm_and(vf_ge(fx, vf_set((float)x0)), vf_le(fx, vf_set((float)x1)));
    return vm_bits(vm_and(in, vf_le(vf_loadu(row + x), vz))) != 0;
}

/* out[t] = min and out_max[t] = max of the 64 pixels at pool + 64 slot[t],
 * t < ntiles (the max comes with the loads the min makes) */
void CULL_OCC_CAT(cull_occ_tiles_, CULL_OCC_SUFFIX)(const float *restrict pool, const uint32_t *restrict slot,
                                                     uint32_t ntiles, float *restrict out, float *restrict out_max)
{
    for (uint32_t t = 0; t < ntiles; t++) {
        const float *p = pool + ((size_t)slot[t] << 6);
        vf m = vf_load(p), M = m;
#pragma GCC unroll 16
        for (uint32_t k = W; k < 64; k += W) {
            vf v = vf_load(p + k);
            m = vf_min(m, v);
            M = vf_max(M, v);
        }
        out[t] = vf_hmin(m);
        out_max[t] = vf_hmax(M);
    }
}

/* row[x] = v for x in [0, n) */
void CULL_OCC_CAT(cull_occ_fill_, CULL_OCC_SUFFIX)(float *restrict row, uint32_t n, float v)
{
    uint32_t x = 0;
    const vf vv = vf_set(v);
    for (; x + W <= n; x += W) vf_store(row + x, vv);
    for (; x < n; x++) row[x] = v;
}

/* out[x] = a[x] > b[x] ? a[x] : b[x], x in [0, n) (maxps keeps b where
 * a is not above it) */
void CULL_OCC_CAT(cull_occ_max2_, CULL_OCC_SUFFIX)(float *restrict out, const float *restrict a,
                                                    const float *restrict b, uint32_t n)
{
    uint32_t x = 0;
    for (; x + W <= n; x += W) vf_store(out + x, vf_max(vf_loadu(a + x), vf_loadu(b + x)));
    for (; x < n; x++) out[x] = a[x] > b[x] ? a[x] : b[x];
}

/* cull_occ_rect_visible by this ISA's walk (cull_occ_test.inl) */
bool CULL_OCC_CAT(cull_occ_rect_visible_, CULL_OCC_SUFFIX)(const cull_occ_buffer *b, int x0, int y0, int x1, int y1,
                                                            float z)
{
    return occ_rect_walk(b, x0, y0, x1, y1, z);
}

/* The kernel's group test over 8 lanes of float bounds, W at a time. */
uint32_t CULL_OCC_CAT(cull_occ_lanes_, CULL_OCC_SUFFIX)(const cull_occ_buffer *b, const float *fx0, const float *fx1,
                                                         const float *fy0, const float *fy1, const float *z,
                                                         uint32_t lanes)
{
    uint32_t vis = 0;
    for (uint32_t o = 0; o < 8; o += W) {
        uint32_t m = (lanes >> o) & ((1u << W) - 1u);
        if (m)
            vis |= occ_rect_group(b, vf_loadu(fx0 + o), vf_loadu(fx1 + o), vf_loadu(fy0 + o), vf_loadu(fy1 + o),
                                  z + o, m, NULL, 0) << o;
    }
    return vis;
}
