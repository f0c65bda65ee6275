/*
 * vt_gather.inl — the shading kernel's gather in lanes (included by
 * vt_shade.inl after its lane helpers, once per instruction set): what
 * surface each pixel of a span shows, its material evaluated, W pixels
 * at a time; and the sky where nothing is drawn. vt_span_surface and
 * vt_span_sky (vt_span.c) are the scalar reference and the path for what
 * the lanes do not cover (a damaged instance's rim, a normal map, a
 * mirrored or non-power-of-two texture, a filter other than GL's
 * trilinear default); tests/test_scene_render.c's test_scene_gather_lanes
 * compares the two on every instruction set.
 *
 * Why: the scalar gather was ~750 M instructions of a 1280x720 city
 * frame's ~1.75 G (BENCHMARKS.md, issue 20's frame): a call per pixel
 * through vt_surface_params and two trilinear samples through
 * vt_tex_sample, each with its own transform, LOD (libm's log2f) and 8
 * texels decoded one by one. Here the pixels of a group showing the same
 * triangle (most of a group: the city's triangles cover tens to hundreds
 * of pixels) share its coefficients as broadcast constants, the pixels
 * of one material sample its textures together, every slot's transform
 * and level sizes are resolved once a call, and the 8 texels of a
 * trilinear sample are fetched for W pixels at once (AVX2 gathers; sRGB
 * slots from vt_texlin's half-float copies where there is one, else
 * decoded by the scalar sampler's table).
 *
 * Numbers: the same sampling rules as vt_tex_sample (GL's: the scale
 * factor from the longer derivative in texels, the level's texel centres,
 * wraps after flooring, sRGB decoded per texel before filtering), with the
 * LOD's log2 by a polynomial (|error| < 2e-7 in the level), the texture
 * coordinates in float (the scalar sampler scales them in double: the same
 * texels and weights to ~1e-6 of a texel), fused multiply-adds with AVX2
 * and the half-float copies (2^-11 relative a texel): a pixel's radiance
 * agrees with the reference's to ~2e-4.
 */

/* ---- integer lanes -------------------------------------------------------------- */
#if CULL_SIMD_ISA == 3
static inline vix vi_set(int32_t a) { return _mm256_set1_epi32(a); }
static inline vix vi_add(vix a, vix b) { return _mm256_add_epi32(a, b); }
static inline vix vi_and(vix a, vix b) { return _mm256_and_si256(a, b); }
static inline vix vi_or(vix a, vix b) { return _mm256_or_si256(a, b); }
static inline vix vi_sll(vix a, int n) { return _mm256_sll_epi32(a, _mm_cvtsi32_si128(n)); }
static inline vix vi_srl(vix a, int n) { return _mm256_srl_epi32(a, _mm_cvtsi32_si128(n)); }
static inline vix vi_clamp(vix a, int32_t hi)
{
    return _mm256_min_epi32(_mm256_max_epi32(a, _mm256_setzero_si256()), _mm256_set1_epi32(hi));
}
static inline vix vi_gather(const uint32_t *b, vix i) { return _mm256_i32gather_epi32((const int *)b, i, 4); }
static inline vf vi_tof(vix a) { return _mm256_cvtepi32_ps(a); }
static inline vm vi_eq(vix a, vix b) { return _mm256_castsi256_ps(_mm256_cmpeq_epi32(a, b)); }
static inline vix vf_bits(vf a) { return _mm256_castps_si256(a); }
static inline vf vi_asf(vix a) { return _mm256_castsi256_ps(a); }
static inline void vi_store(int32_t *p, vix a) { _mm256_storeu_si256((__m256i *)p, a); }
static inline vix vi_loadu(const uint32_t *p) { return _mm256_loadu_si256((const __m256i *)(const void *)p); }
#elif CULL_SIMD_ISA == 2
static inline vix vi_set(int32_t a) { return _mm_set1_epi32(a); }
static inline vix vi_add(vix a, vix b) { return _mm_add_epi32(a, b); }
static inline vix vi_and(vix a, vix b) { return _mm_and_si128(a, b); }
static inline vix vi_or(vix a, vix b) { return _mm_or_si128(a, b); }
static inline vix vi_sll(vix a, int n) { return _mm_sll_epi32(a, _mm_cvtsi32_si128(n)); }
static inline vix vi_srl(vix a, int n) { return _mm_srl_epi32(a, _mm_cvtsi32_si128(n)); }
static inline vix vi_clamp(vix a, int32_t hi) { return _mm_min_epi32(_mm_max_epi32(a, _mm_setzero_si128()), _mm_set1_epi32(hi)); }
static inline vix vi_gather(const uint32_t *b, vix i)
{
    return _mm_setr_epi32((int)b[_mm_extract_epi32(i, 0)], (int)b[_mm_extract_epi32(i, 1)], (int)b[_mm_extract_epi32(i, 2)],
                          (int)b[_mm_extract_epi32(i, 3)]);
}
static inline vf vi_tof(vix a) { return _mm_cvtepi32_ps(a); }
static inline vm vi_eq(vix a, vix b) { return _mm_castsi128_ps(_mm_cmpeq_epi32(a, b)); }
static inline vix vf_bits(vf a) { return _mm_castps_si128(a); }
static inline vf vi_asf(vix a) { return _mm_castsi128_ps(a); }
static inline void vi_store(int32_t *p, vix a) { _mm_storeu_si128((__m128i *)p, a); }
static inline vix vi_loadu(const uint32_t *p) { return _mm_loadu_si128((const __m128i *)(const void *)p); }
#else
static inline vix vi_set(int32_t a) { return a; }
static inline vix vi_add(vix a, vix b) { return (int32_t)((uint32_t)a + (uint32_t)b); }
static inline vix vi_and(vix a, vix b) { return a & b; }
static inline vix vi_or(vix a, vix b) { return a | b; }
static inline vix vi_sll(vix a, int n) { return (int32_t)((uint32_t)a << n); }
static inline vix vi_srl(vix a, int n) { return (int32_t)((uint32_t)a >> n); }
static inline vix vi_clamp(vix a, int32_t hi) { return a < 0 ? 0 : a > hi ? hi : a; }
static inline vix vi_gather(const uint32_t *b, vix i) { return (int32_t)b[i]; }
static inline vf vi_tof(vix a) { return (float)a; }
static inline vm vi_eq(vix a, vix b) { return a == b ? ~0u : 0u; }
static inline vix vf_bits(vf a)
{
    int32_t i;
    memcpy(&i, &a, sizeof i);
    return i;
}
static inline vf vi_asf(vix a)
{
    float f;
    memcpy(&f, &a, sizeof f);
    return f;
}
static inline void vi_store(int32_t *p, vix a) { *p = a; }
static inline vix vi_loadu(const uint32_t *p) { return (int32_t)*p; }
#endif

/* The lanes' indices 0 .. W - 1, as floats. */
static inline vf lane_index(void)
{
    static const A float k[8] = {0, 1, 2, 3, 4, 5, 6, 7};
    return vf_load(k);
}

/* The NDC x of the span's columns i .. i + W - 1. */
static inline vf lanes_ndc_x(const vt_span *sp, unsigned i)
{
    return vf_fma(lane_index(), vf_set((float)sp->inv_w), vf_set(vt_ndc_x(sp->x0 + i, sp->inv_w)));
}

/* log2 of x > 0 finite (normal or not: subnormals read as their exponent
 * field's 2^-126 band, a level far below 0 either way): the exponent plus
 * log2 of the mantissa m in [sqrt(1/2), sqrt(2)) by Cephes' logf
 * polynomial (relative error ~1e-7). Only the mip level is made from it. */
static inline vf vf_log2(vf x)
{
    const vf one = vf_set(1);
    vix b = vf_bits(x);
    vix e = vi_add(vi_srl(b, 23), vi_set(-127));
    vf m = vi_asf(vi_or(vi_and(b, vi_set(0x007FFFFF)), vi_set(0x3F800000))); /* [1, 2) */
    vm big = vf_lt(vf_set(1.41421356f), m);
    m = vf_select(big, vf_mul(m, vf_set(0.5f)), m);
    vf ef = vf_add(vi_tof(e), vf_select(big, one, vf_set(0)));
    vf t = vf_sub(m, one), z = vf_mul(t, t);
    vf y = vf_set(7.0376836292e-2f);
    y = vf_fma(y, t, vf_set(-1.1514610310e-1f));
    y = vf_fma(y, t, vf_set(1.1676998740e-1f));
    y = vf_fma(y, t, vf_set(-1.2420140846e-1f));
    y = vf_fma(y, t, vf_set(1.4249322787e-1f));
    y = vf_fma(y, t, vf_set(-1.6668057665e-1f));
    y = vf_fma(y, t, vf_set(2.0000714765e-1f));
    y = vf_fma(y, t, vf_set(-2.4999993993e-1f));
    y = vf_fma(y, t, vf_set(3.3333331174e-1f));
    y = vf_mul(vf_mul(y, t), z);
    y = vf_fma(z, vf_set(-0.5f), y);
    vf ln = vf_add(t, y); /* ln(m) */
    return vf_fma(ln, vf_set(1.44269504088896341f), ef);
}

/* ---- textures -------------------------------------------------------------------- */

/* Whether slot r's sampling has a lane path: a power-of-two texture
 * (every level then is one), REPEAT or CLAMP wraps, linear magnification,
 * trilinear minification (glTF's usual sampler and the city's) or linear
 * without mips. Anything else goes through vt_tex_sample per pixel. */
static inline bool tex_lanes_ok(const vt_texref *r)
{
    const vt_texview *t = r->tex;
    if (!t) return true;
    if ((t->w & (t->w - 1)) || (t->h & (t->h - 1)) || !t->mip || t->levels < 1 || t->levels > 16) return false;
    if (r->wrap_s == VT_WRAP_MIRROR || r->wrap_t == VT_WRAP_MIRROR || r->mag_filter != VT_FILTER_LINEAR) return false;
    return r->min_filter == VT_FILTER_LINEAR_MIP_LINEAR || r->min_filter == VT_FILTER_LINEAR;
}

/* log2 of a power of two v >= 1 */
static inline int ilog2u(uint32_t v)
{
    return __builtin_ctz(v);
}

/* The texel coordinate along one axis of a level of size 1 << ls: (x,
 * the lower texel's index wrapped, the upper's, and the weight of the
 * upper). u is finite (the caller clamped it). */
static inline void axis(vf u, int ls, uint8_t wrap, vix *i0, vix *i1, vf *a)
{
    const vf half = vf_set(0.5f), n = vf_set((float)(1u << ls));
    /* REPEAT: the fraction first (u - floor u is exact), so a large u
       keeps its position inside the texture; CLAMP: past [-1, 2] every
       texel index clamps the same */
    vf x = wrap == VT_WRAP_REPEAT ? vf_sub(u, vf_floor(u)) : vf_min(vf_max(u, vf_set(-1)), vf_set(2));
    x = vf_sub(vf_mul(x, n), half);
    vf xf = vf_floor(x);
    *a = vf_sub(x, xf);
    vix xi = vx_of(xf);
    vix x1 = vi_add(xi, vi_set(1));
    if (wrap == VT_WRAP_REPEAT) {
        vix m = vi_set((int32_t)(1u << ls) - 1);
        *i0 = vi_and(xi, m), *i1 = vi_and(x1, m);
    } else {
        *i0 = vi_clamp(xi, (int32_t)(1u << ls) - 1), *i1 = vi_clamp(x1, (int32_t)(1u << ls) - 1);
    }
}

/* Channel k (0..2) of W texels, decoded: sRGB by the table, else / 255. */
static inline vf chan(vix t, int k, const float *tab)
{
    vix c = vi_and(vi_srl(t, 8 * k), vi_set(255));
    if (tab) return vf_gather(tab, c);
    return vf_mul(vi_tof(c), vf_set(1 / 255.0f));
}

/* Level lv of slot r, bilinear at (u, v), RGB into o (ch: the channels
 * wanted, bits 0..2). */
static inline __attribute__((always_inline)) void bilinear(const vt_texref *r, uint32_t lv, vf u, vf v, const float *tab, unsigned ch, vf o[3])
{
    const vt_texview *t = r->tex;
    int ws = ilog2u(t->w), hs = ilog2u(t->h);
    ws = ws > (int)lv ? ws - (int)lv : 0;
    hs = hs > (int)lv ? hs - (int)lv : 0;
    const uint32_t *px = (const uint32_t *)(const void *)t->mip[lv];
    vix i0, i1, j0, j1;
    vf ax, ay;
    axis(u, ws, r->wrap_s, &i0, &i1, &ax);
    axis(v, hs, r->wrap_t, &j0, &j1, &ay);
    j0 = vi_sll(j0, ws), j1 = vi_sll(j1, ws);
    vix t00 = vi_gather(px, vi_add(j0, i0)), t10 = vi_gather(px, vi_add(j0, i1));
    vix t01 = vi_gather(px, vi_add(j1, i0)), t11 = vi_gather(px, vi_add(j1, i1));
    for (int k = 0; k < 3; k++) {
        if (!(ch >> k & 1)) continue;
        vf a = chan(t00, k, tab), b = chan(t10, k, tab), c = chan(t01, k, tab), d = chan(t11, k, tab);
        vf top = vf_fma(ax, vf_sub(b, a), a), bot = vf_fma(ax, vf_sub(d, c), c);
        o[k] = vf_fma(ay, vf_sub(bot, top), top);
    }
}

#if CULL_SIMD_ISA == 3
/* Channels 0..2 of 8 texels of a half-float copy (vt_texlin.h) at
 * texel index i: two 64-bit gathers (texels 0-3, 4-7), each 128-bit half
 * of them byte-shuffled to R R G G B B A A (two texels), the R and G
 * words and the B words put in lane order by one vpermd each, widened
 * by F16C (exact). */
static inline void texels_h(const uint64_t *px, vix i, vf c[3])
{
    const long long *p = (const long long *)(const void *)px;
    __m256i lo = _mm256_i32gather_epi64(p, _mm256_castsi256_si128(i), 8);
    __m256i hi = _mm256_i32gather_epi64(p, _mm256_extracti128_si256(i, 1), 8);
    const __m256i by = _mm256_setr_epi8(0, 1, 8, 9, 2, 3, 10, 11, 4, 5, 12, 13, 6, 7, 14, 15,
                                        0, 1, 8, 9, 2, 3, 10, 11, 4, 5, 12, 13, 6, 7, 14, 15);
    lo = _mm256_shuffle_epi8(lo, by); /* R01 G01 B01 A01 | R23 G23 B23 A23 (32-bit words) */
    hi = _mm256_shuffle_epi8(hi, by); /* R45 G45 B45 A45 | R67 G67 B67 A67 */
    __m256i rg = _mm256_unpacklo_epi64(lo, hi); /* R01 G01 R45 G45 | R23 G23 R67 G67 */
    __m256i ba = _mm256_unpackhi_epi64(lo, hi); /* B01 A01 B45 A45 | B23 A23 B67 A67 */
    const __m256i q = _mm256_setr_epi32(0, 4, 2, 6, 1, 5, 3, 7);
    rg = _mm256_permutevar8x32_epi32(rg, q); /* R01 R23 R45 R67 | G01 G23 G45 G67 */
    ba = _mm256_permutevar8x32_epi32(ba, q);
    c[0] = _mm256_cvtph_ps(_mm256_castsi256_si128(rg));
    c[1] = _mm256_cvtph_ps(_mm256_extracti128_si256(rg, 1));
    c[2] = _mm256_cvtph_ps(_mm256_castsi256_si128(ba));
}

/* A level's texel coordinates for W lanes, as bilinear() makes them: the
 * two columns, the two rows (times the row length) and the weights. */
typedef struct taxes {
    vix i0, i1, j0, j1;
    vf ax, ay;
} taxes;

static inline __attribute__((always_inline)) void tex_axes(const vt_texref *r, const vt_texlin *tl, uint32_t lv, vf u,
                                                           vf v, taxes *a)
{
    int ws = ilog2u(tl->w), hs = ilog2u(tl->h);
    ws = ws > (int)lv ? ws - (int)lv : 0;
    hs = hs > (int)lv ? hs - (int)lv : 0;
    axis(u, ws, r->wrap_s, &a->i0, &a->i1, &a->ax);
    axis(v, hs, r->wrap_t, &a->j0, &a->j1, &a->ay);
    a->j0 = vi_sll(a->j0, ws), a->j1 = vi_sll(a->j1, ws);
}

/* bilinear() on the half-float copy of the slot's texture at level lv's
 * coordinates a: the two texel rows blended along x as they come (fewer
 * live registers). */
static inline __attribute__((always_inline)) void bilinear_h(const vt_texlin *tl, uint32_t lv, const taxes *x, vf o[3])
{
    vf a[3], b[3], top[3];
    texels_h(tl->lv[lv], vi_add(x->j0, x->i0), a);
    texels_h(tl->lv[lv], vi_add(x->j0, x->i1), b);
    for (int k = 0; k < 3; k++) top[k] = vf_fma(x->ax, vf_sub(b[k], a[k]), a[k]);
    texels_h(tl->lv[lv], vi_add(x->j1, x->i0), a);
    texels_h(tl->lv[lv], vi_add(x->j1, x->i1), b);
    for (int k = 0; k < 3; k++) {
        vf bot = vf_fma(x->ax, vf_sub(b[k], a[k]), a[k]);
        o[k] = vf_fma(x->ay, vf_sub(bot, top[k]), top[k]);
    }
}
/* The lanes whose bilinear sample of the copy's level lv at coordinates
 * a is black by its masks (vt_texlin.h's zb; there are some): one gather
 * of mask words at the lower texel. */
static inline vm black_lanes(const vt_texlin *tl, uint32_t lv, const taxes *a)
{
    vix i = vi_add(a->j0, a->i0);
    vix w = vi_gather(tl->zb[lv], vi_srl(i, 5));
    vix b = _mm256_srlv_epi32(w, vi_and(i, vi_set(31)));
    return vi_eq(vi_and(b, vi_set(1)), vi_set(1));
}
#endif

/* vt_tex_sample in lanes for a lane-able slot (tex_lanes_ok): uv and its
 * per-pixel differences (before the slot's transform), the lanes in act
 * (the others get some finite value); RGB channels ch into o. */
static inline void tex_lanes(const vt_texref *r, vf u0, vf v0, vf dxu0, vf dxv0, vf dyu0, vf dyv0, vm act, bool srgb_on,
                             unsigned ch, const vt_texcache *tc, vf o[3])
{
#if CULL_SIMD_ISA == 3
    /* an sRGB slot with a decoded copy: halves, no table (nor its call) */
    const vt_texlin *tl = srgb_on ? vt_texcache_find(tc, r->tex) : NULL;
    const float *tab = srgb_on && !tl ? vt_srgb_table() : NULL;
#else
    (void)tc;
    const float *tab = srgb_on ? vt_srgb_table() : NULL;
#endif
    const vt_texview *t = r->tex;
    const float c = r->rotation == 0 ? 1.0f : cosf(r->rotation), s = r->rotation == 0 ? 0.0f : sinf(r->rotation);
    const bool unit = r->scale[0] == 0 && r->scale[1] == 0;
    const vf sx = vf_set(unit ? 1 : r->scale[0]), sy = vf_set(unit ? 1 : r->scale[1]);
    const vf vc = vf_set(c), vs = vf_set(s), big = vf_set(1e9f), nbig = vf_set(-1e9f);
#define XF(a, b, off0, off1, ou, ov)                                                                                   \
    do {                                                                                                               \
        vf su_ = vf_mul(a, sx), sv_ = vf_mul(b, sy);                                                                   \
        ou = vf_add(vf_sub(vf_mul(vc, su_), vf_mul(vs, sv_)), vf_set(off0));                                           \
        ov = vf_add(vf_add(vf_mul(vs, su_), vf_mul(vc, sv_)), vf_set(off1));                                           \
    } while (0)
    vf u, v, dxu, dxv, dyu, dyv;
    XF(u0, v0, r->offset[0], r->offset[1], u, v);
    XF(dxu0, dxv0, 0.0f, 0.0f, dxu, dxv);
    XF(dyu0, dyv0, 0.0f, 0.0f, dyu, dyv);
#undef XF
    /* the coordinates kept finite (NaN: -1e9, as the scalar sampler) */
    u = vf_min(vf_max(u, nbig), big);
    v = vf_min(vf_max(v, nbig), big);
    /* GL's scale factor: the longer derivative in texels, squared */
    const vf fw = vf_set((float)t->w), fh = vf_set((float)t->h);
    vf ax = vf_mul(dxu, fw), ay = vf_mul(dxv, fh), bx = vf_mul(dyu, fw), by = vf_mul(dyv, fh);
    vf r2 = vf_max(vf_fma(ax, ax, vf_mul(ay, ay)), vf_fma(bx, bx, vf_mul(by, by)));
    const float top = (float)(t->levels - 1);
    const bool mips = r->min_filter == VT_FILTER_LINEAR_MIP_LINEAR && t->levels > 1;
    vf lod;
    if (mips) {
        /* 0.5 log2(rho^2); rho 0 or NaN: magnified; infinite: the last level */
        vm fin = vm_and(vf_lt(vf_set(0), r2), vf_lt(r2, vf_set(INFINITY)));
        vf safe = vf_select(fin, r2, vf_set(1));
        lod = vf_select(fin, vf_mul(vf_log2(safe), vf_set(0.5f)), vf_select(vf_lt(vf_set(0), r2), vf_set(top), vf_set(0)));
        lod = vf_min(vf_max(lod, vf_set(0)), vf_set(top));
    } else {
        lod = vf_set(0);
    }
    /* levels l0 and l0 + 1 blended by f (f 0 at level 0 when magnified,
       1 at the last level: the last level's value) */
    vf fl = vf_min(vf_floor(lod), vf_set(top > 0 ? top - 1 : 0));
    vf f = mips ? vf_sub(lod, fl) : vf_set(0);
    A int32_t lvl[W];
    vi_store(lvl, vx_of(fl));
    uint32_t todo = vm_bits(act);
    const vf zero = vf_set(0);
    for (int k = 0; k < 3; k++) o[k] = zero;
    while (todo) {
        uint32_t L = (uint32_t)lvl[__builtin_ctz(todo)];
        vm mk = vm_and(act, vi_eq(vx_of(fl), vi_set((int32_t)L)));
        vf a[3] = {zero, zero, zero}, b[3] = {zero, zero, zero};
        vf fk = vf_select(mk, f, zero);
        const bool two = mips && vm_bits(vf_lt(zero, fk));
#if CULL_SIMD_ISA == 3
        if (tl) {
            /* each level's coordinates once, for the black test and the
               sample */
            taxes x0, x1;
            tex_axes(r, tl, L, u, v, &x0);
            x1 = x0; /* read only when two */
            if (two) tex_axes(r, tl, L + 1, u, v, &x1);
            /* a black footprint at both levels: black (o is 0 there)
               without the texels; a test of ~10 instructions against
               two bilinear samples' ~200. The second level is tested
               only where the first is black in every lane */
            if (tl->zb[0] && !vm_bits(vm_andnot(mk, black_lanes(tl, L, &x0))) &&
                (!two || !vm_bits(vm_andnot(mk, black_lanes(tl, L + 1, &x1))))) {
                todo &= ~vm_bits(mk);
                continue;
            }
            bilinear_h(tl, L, &x0, a);
            if (two) {
                bilinear_h(tl, L + 1, &x1, b);
                for (int k = 0; k < 3; k++) a[k] = vf_fma(fk, vf_sub(b[k], a[k]), a[k]);
            }
            for (int k = 0; k < 3; k++) o[k] = vf_select(mk, a[k], o[k]);
            todo &= ~vm_bits(mk);
            continue;
        }
#endif
        bilinear(r, L, u, v, tab, ch, a);
        if (two) {
            bilinear(r, L + 1, u, v, tab, ch, b);
            for (int k = 0; k < 3; k++) a[k] = vf_fma(fk, vf_sub(b[k], a[k]), a[k]);
        }
        for (int k = 0; k < 3; k++) o[k] = vf_select(mk, a[k], o[k]);
        todo &= ~vm_bits(mk);
    }
}

/* ---- the material ---------------------------------------------------------------- */

/* A point's interpolated inputs for W pixels: position, normal (any
 * length), the default material's colour, UV and its differences one
 * pixel right and one up. */
typedef struct gin {
    vf px, py, pz, nx, ny, nz, al[3];
    vf u, v, dxu, dxv, dyu, dyv;
} gin;

/* The material's outputs for W pixels (vt_surfout in lanes). */
typedef struct gout {
    vf dr, dg, db, fr, fg, fb, er, eg, eb, a2, ro;
} gout;

/* Whether material m (NULL: the default) has a lane path. */
static inline bool mat_lanes_ok(const vt_material *m)
{
    if (!m) return true;
    if (m->tex[VT_SLOT_NORMAL].tex) return false;
    return tex_lanes_ok(&m->tex[VT_SLOT_BASE]) && tex_lanes_ok(&m->tex[VT_SLOT_MR]) &&
           tex_lanes_ok(&m->tex[VT_SLOT_EMISSIVE]);
}

/* Whether m's textures are read (it has one) on a surface with UVs. */
static inline bool mat_reads_uv(const vt_material *m)
{
    return m && (m->tex[VT_SLOT_BASE].tex || m->tex[VT_SLOT_MR].tex || m->tex[VT_SLOT_EMISSIVE].tex);
}

/* vt_surface_params in lanes (no normal map: mat_lanes_ok) for the lanes
 * in act: uv says the lanes' UVs are read. The normal stays as
 * interpolated (the kernel normalises it). */
static inline void mat_lanes(const vt_material *m, const gin *in, bool uv, vm act, const vt_texcache *tc, gout *g)
{
    const vf zero = vf_set(0), one = vf_set(1);
    if (!m) {
        const float a = VT_DEFAULT_ROUGHNESS * VT_DEFAULT_ROUGHNESS;
        g->dr = in->al[0], g->dg = in->al[1], g->db = in->al[2];
        g->fr = g->fg = g->fb = vf_set(VT_F0_DIELECTRIC);
        g->er = g->eg = g->eb = zero;
        g->a2 = vf_set(a * a), g->ro = vf_set(VT_DEFAULT_ROUGHNESS);
        return;
    }
    vf base[3] = {vf_set(m->base[0]), vf_set(m->base[1]), vf_set(m->base[2])};
    vf metal = vf_set(m->metallic), rough = vf_set(m->roughness);
    vf em[3];
    for (int k = 0; k < 3; k++) em[k] = vf_set(m->emissive[k] * m->emissive_strength);
    if (uv) {
        vf t[3];
        if (m->tex[VT_SLOT_BASE].tex) {
            tex_lanes(&m->tex[VT_SLOT_BASE], in->u, in->v, in->dxu, in->dxv, in->dyu, in->dyv, act, true, 7, tc, t);
            for (int k = 0; k < 3; k++) base[k] = vf_mul(base[k], t[k]);
        }
        if (m->tex[VT_SLOT_MR].tex) {
            tex_lanes(&m->tex[VT_SLOT_MR], in->u, in->v, in->dxu, in->dxv, in->dyu, in->dyv, act, false, 6, tc, t);
            rough = vf_mul(rough, t[1]);
            metal = vf_mul(metal, t[2]);
        }
        /* an emission of 0 stays 0 whatever the texture says: no sample */
        if (m->tex[VT_SLOT_EMISSIVE].tex && (m->emissive[0] != 0 || m->emissive[1] != 0 || m->emissive[2] != 0) &&
            m->emissive_strength != 0) {
            tex_lanes(&m->tex[VT_SLOT_EMISSIVE], in->u, in->v, in->dxu, in->dxv, in->dyu, in->dyv, act, true, 7, tc, t);
            for (int k = 0; k < 3; k++) em[k] = vf_mul(em[k], t[k]);
        }
    }
    vf im = vf_sub(one, metal), f0d = vf_mul(vf_set(0.04f), im);
    g->dr = vf_mul(base[0], im), g->dg = vf_mul(base[1], im), g->db = vf_mul(base[2], im);
    g->fr = vf_fma(base[0], metal, f0d), g->fg = vf_fma(base[1], metal, f0d), g->fb = vf_fma(base[2], metal, f0d);
    g->er = em[0], g->eg = em[1], g->eb = em[2];
    /* vt_brdf_rough: clamped to [VT_MIN_ROUGHNESS, 1], NaN 1 */
    vf rc = vf_select(vf_ge(rough, vf_set(VT_MIN_ROUGHNESS)), vf_min(rough, one),
                      vf_select(vf_lt(rough, vf_set(VT_MIN_ROUGHNESS)), vf_set(VT_MIN_ROUGHNESS), one));
    vf a = vf_mul(rc, rc);
    g->a2 = vf_mul(a, a), g->ro = rc;
}

/* vt_stri_bary in lanes at NDC (X, Y), t's coefficients broadcast. */
static inline void bary_lanes(const vt_stri *t, vf X, vf Y, vf b[3])
{
    for (int k = 0; k < 3; k++) b[k] = vf_fma(vf_set(t->e[k][0]), X, vf_fma(vf_set(t->e[k][1]), Y, vf_set(t->e[k][2])));
    vf sum = vf_add(vf_add(b[0], b[1]), b[2]);
    vm z = vm_and(vf_ge(sum, vf_set(0)), vf_le(sum, vf_set(0)));
    vf is = vf_select(z, vf_set(1), vf_div(vf_set(1), sum));
    for (int k = 0; k < 3; k++) b[k] = vf_mul(b[k], is);
}

/* Triangle t's inputs at W pixels from column x (X: their NDC x); uv:
 * its UVs are read. */
static inline void tri_lanes(const vt_stri *t, const vt_span *sp, vf X, bool uv, gin *g)
{
    vf b[3];
    const vf Y = vf_set(sp->Y);
    bary_lanes(t, X, Y, b);
#define IP(c, arr, k) vf_fma(c[0], vf_set(t->arr[0][k]), vf_fma(c[1], vf_set(t->arr[1][k]), vf_mul(c[2], vf_set(t->arr[2][k]))))
    g->px = IP(b, p, 0), g->py = IP(b, p, 1), g->pz = IP(b, p, 2);
    g->nx = IP(b, n, 0), g->ny = IP(b, n, 1), g->nz = IP(b, n, 2);
    for (int k = 0; k < 3; k++) g->al[k] = vf_set(t->albedo[k]);
    if (uv) {
        vf br[3], bu[3];
        bary_lanes(t, vf_add(X, vf_set((float)sp->inv_w)), Y, br);
        bary_lanes(t, X, vf_set(sp->Y + (float)sp->inv_h), bu);
        g->u = IP(b, uv, 0), g->v = IP(b, uv, 1);
        g->dxu = vf_sub(IP(br, uv, 0), g->u), g->dxv = vf_sub(IP(br, uv, 1), g->v);
        g->dyu = vf_sub(IP(bu, uv, 0), g->u), g->dyv = vf_sub(IP(bu, uv, 1), g->v);
    } else {
        g->u = g->v = g->dxu = g->dxv = g->dyu = g->dyv = vf_set(0);
    }
#undef IP
}

/* Doubles in lanes, for the ground plane's points (far points need the
 * precision): WD lanes a vector. */
#if CULL_SIMD_ISA == 3
typedef __m256d vdd;
#define WD 4
static inline vdd dd_set(double a) { return _mm256_set1_pd(a); }
static inline vdd dd_of(const float *p) { return _mm256_cvtps_pd(_mm_loadu_ps(p)); }
static inline vdd dd_add(vdd a, vdd b) { return _mm256_add_pd(a, b); }
static inline vdd dd_mul(vdd a, vdd b) { return _mm256_mul_pd(a, b); }
static inline uint32_t dd_ge(vdd a, vdd b) { return (uint32_t)_mm256_movemask_pd(_mm256_cmp_pd(a, b, _CMP_GE_OQ)); }
static inline uint32_t dd_gt(vdd a, vdd b) { return (uint32_t)_mm256_movemask_pd(_mm256_cmp_pd(a, b, _CMP_GT_OQ)); }
static inline void dd_store(double *p, vdd a) { _mm256_storeu_pd(p, a); }
/* 1 / a, 0 where a is 0 (NaN stays NaN) */
static inline vdd dd_inv0(vdd a)
{
    return _mm256_and_pd(_mm256_div_pd(_mm256_set1_pd(1), a), _mm256_cmp_pd(a, _mm256_setzero_pd(), _CMP_NEQ_UQ));
}
/* WD floats: a rounded to float (as a C cast), 0 in the lanes not in
 * bits; stored to p */
typedef __m128 vfd;
static inline vfd dd_f(vdd a, uint32_t bits)
{
    const __m128i sel = _mm_setr_epi32(1, 2, 4, 8);
    __m128 m = _mm_castsi128_ps(_mm_cmpeq_epi32(_mm_and_si128(_mm_set1_epi32((int)bits), sel), sel));
    return _mm_and_ps(_mm256_cvtpd_ps(a), m);
}
static inline vfd fd_sub(vfd a, vfd b) { return _mm_sub_ps(a, b); }
static inline vfd fd_sel(vfd a, uint32_t bits, vfd b) { return _mm_blendv_ps(b, a, dd_f(_mm256_set1_pd(-1), bits)); }
static inline void fd_store(float *p, vfd a) { _mm_storeu_ps(p, a); }
#elif CULL_SIMD_ISA == 2
typedef __m128d vdd;
#define WD 2
static inline vdd dd_set(double a) { return _mm_set1_pd(a); }
static inline vdd dd_of(const float *p) { return _mm_cvtps_pd(_mm_castsi128_ps(_mm_loadl_epi64((const __m128i *)p))); }
static inline vdd dd_add(vdd a, vdd b) { return _mm_add_pd(a, b); }
static inline vdd dd_mul(vdd a, vdd b) { return _mm_mul_pd(a, b); }
static inline uint32_t dd_ge(vdd a, vdd b) { return (uint32_t)_mm_movemask_pd(_mm_cmpge_pd(a, b)); }
static inline uint32_t dd_gt(vdd a, vdd b) { return (uint32_t)_mm_movemask_pd(_mm_cmpgt_pd(a, b)); }
static inline void dd_store(double *p, vdd a) { _mm_storeu_pd(p, a); }
static inline vdd dd_inv0(vdd a) { return _mm_and_pd(_mm_div_pd(_mm_set1_pd(1), a), _mm_cmpneq_pd(a, _mm_setzero_pd())); }
typedef __m128 vfd; /* lanes 0, 1 */
static inline vfd dd_f(vdd a, uint32_t bits)
{
    const __m128i sel = _mm_setr_epi32(1, 2, 4, 8);
    __m128 m = _mm_castsi128_ps(_mm_cmpeq_epi32(_mm_and_si128(_mm_set1_epi32((int)bits), sel), sel));
    return _mm_and_ps(_mm_cvtpd_ps(a), m);
}
static inline vfd fd_sub(vfd a, vfd b) { return _mm_sub_ps(a, b); }
static inline vfd fd_sel(vfd a, uint32_t bits, vfd b) { return _mm_blendv_ps(b, a, dd_f(_mm_set1_pd(-1), bits)); }
static inline void fd_store(float *p, vfd a) { _mm_storel_pi((__m64 *)(void *)p, a); }
#else
typedef double vdd;
#define WD 1
static inline vdd dd_set(double a) { return a; }
static inline vdd dd_of(const float *p) { return *p; }
static inline vdd dd_add(vdd a, vdd b) { return a + b; }
static inline vdd dd_mul(vdd a, vdd b) { return a * b; }
static inline uint32_t dd_ge(vdd a, vdd b) { return a >= b; }
static inline uint32_t dd_gt(vdd a, vdd b) { return a > b; }
static inline void dd_store(double *p, vdd a) { *p = a; }
static inline vdd dd_inv0(vdd a) { return a != 0 ? 1 / a : 0; }
typedef float vfd;
static inline vfd dd_f(vdd a, uint32_t bits) { return bits & 1 ? (float)a : 0.0f; }
static inline vfd fd_sub(vfd a, vfd b) { return a - b; }
static inline vfd fd_sel(vfd a, uint32_t bits, vfd b) { return bits & 1 ? a : b; }
static inline void fd_store(float *p, vfd a) { *p = a; }
#endif

/* vt_ground_at and vt_ground_point at WD points (X, Y as floats, the
 * reference's arguments): q (3 x WD) where hit (bits; elsewhere some
 * value, 0 where none hits). */
static inline uint32_t ground_pts(const vt_ground *g, const float *X, const float *Y, vdd q[3])
{
    vdd x = dd_of(X), y = dd_of(Y);
#define AFF(r, N) dd_add(dd_add(dd_mul(dd_set(r[0]), x), dd_mul(dd_set(r[1]), y)), dd_add(dd_mul(dd_set(r[2]), N), dd_set(r[3])))
    vdd N = dd_add(dd_add(dd_mul(dd_set(g->n[0]), x), dd_mul(dd_set(g->n[1]), y)), dd_set(g->n[2]));
    uint32_t hit = g->persp ? dd_gt(N, dd_set(0)) : (1u << WD) - 1;
    hit &= dd_ge(AFF(g->lim[0], N), dd_set(0)) & dd_ge(AFF(g->lim[1], N), dd_set(0));
    if (!hit) {
        q[0] = q[1] = q[2] = dd_set(0);
        return 0;
    }
    vdd iw = dd_inv0(AFF(g->inv[3], N)); /* 1 / h3, 0 where h3 is 0 (vt_ground_point) */
    for (int k = 0; k < 3; k++) q[k] = dd_mul(AFF(g->inv[k], N), iw);
#undef AFF
    return hit;
}

/* The ground's inputs at W pixels from column offset i (the lanes in
 * bits): its points, and where uv its UVs (world x, z from the view's
 * origin) with their differences one pixel right and one up (0 where
 * that neighbour misses the plane), as vt_span_surface makes them; the
 * points in double, WD lanes at a time. */
static inline void ground_lanes(const vt_span *sp, unsigned i, uint32_t bits, bool uv, gin *g)
{
    const vt_penv *pe = sp->pe;
    A float P[3][W], U[6][W];
    const float dX = (float)sp->inv_w, dY = (float)sp->inv_h;
    for (int k = 0; k < 3; k++) vf_store(P[k], vf_set(0));
    for (int k = 0; k < 6; k++) vf_store(U[k], vf_set(0));
    for (unsigned j0 = 0; j0 < W; j0 += WD) {
        if (!(bits >> j0 & ((1u << WD) - 1))) continue;
        A float X[3][WD], Y[3][WD];
        for (unsigned j = 0; j < WD; j++) {
            X[0][j] = vt_ndc_x(sp->x0 + i + j0 + j, sp->inv_w), Y[0][j] = sp->Y;
            X[1][j] = X[0][j] + dX, Y[1][j] = sp->Y;
            X[2][j] = X[0][j], Y[2][j] = sp->Y + dY;
        }
        vdd q[3][3];
        uint32_t hit = ground_pts(sp->gr, X[0], Y[0], q[0]);
        if (!hit) continue; /* the raster found it there: 0, as vt_span_surface */
        /* in lanes (a lane per point: the same roundings as one by one) */
        for (int k = 0; k < 3; k++) fd_store(P[k] + j0, dd_f(q[0][k], hit));
        if (!uv) continue;
        uint32_t hx = ground_pts(sp->gr, X[1], Y[1], q[1]) & hit, hy = ground_pts(sp->gr, X[2], Y[2], q[2]) & hit;
        const vdd o[2] = {dd_set(pe->ground_uv0[0]), dd_set(pe->ground_uv0[1])};
        const vfd zero = dd_f(dd_set(0), 0);
        for (int a = 0; a < 2; a++) {
            const vfd c = dd_f(dd_add(o[a], q[0][2 * a]), hit); /* x, z */
            fd_store(U[a] + j0, c);
            fd_store(U[2 + a] + j0, fd_sel(fd_sub(dd_f(dd_add(o[a], q[1][2 * a]), hx), c), hx, zero));
            fd_store(U[4 + a] + j0, fd_sel(fd_sub(dd_f(dd_add(o[a], q[2][2 * a]), hy), c), hy, zero));
        }
    }
    g->px = vf_load(P[0]), g->py = vf_load(P[1]), g->pz = vf_load(P[2]);
    g->nx = vf_set(0), g->ny = vf_set(1), g->nz = vf_set(0);
    for (int k = 0; k < 3; k++) g->al[k] = vf_set(pe->ground_albedo[k]);
    g->u = vf_load(U[0]), g->v = vf_load(U[1]), g->dxu = vf_load(U[2]), g->dxv = vf_load(U[3]);
    g->dyu = vf_load(U[4]), g->dyv = vf_load(U[5]);
}

/* ---- the sky ------------------------------------------------------------------- */

/* atan(t) for t in [0, 1] (Cephes' atanf: above tan(pi/8), pi/4 + atan((t
 * - 1) / (t + 1)); a degree-9 odd polynomial; ~1e-7 absolute). */
static inline vf atan01(vf t)
{
    const vf one = vf_set(1);
    vm hi = vf_lt(vf_set(0.41421356f), t);
    vf x = vf_select(hi, vf_div(vf_sub(t, one), vf_add(t, one)), t);
    vf z = vf_mul(x, x);
    vf y = vf_fma(vf_set(8.05374449538e-2f), z, vf_set(-1.38776856032e-1f));
    y = vf_fma(y, z, vf_set(1.99777106478e-1f));
    y = vf_fma(y, z, vf_set(-3.33329491539e-1f));
    y = vf_fma(vf_mul(y, z), x, x);
    return vf_add(y, vf_select(hi, vf_set(0.78539816f), vf_set(0)));
}

/* atan2f(y, x) in lanes (~2e-7 absolute; (0, 0): 0). */
static inline vf vf_atan2(vf y, vf x)
{
    const vf zero = vf_set(0);
    vf ax = vf_abs(x), ay = vf_abs(y), mx = vf_max(ax, ay), mn = vf_min(ax, ay);
    vf r = atan01(vf_select(vf_lt(zero, mx), vf_div(mn, mx), zero));
    r = vf_select(vf_lt(ax, ay), vf_sub(vf_set(1.57079633f), r), r);
    r = vf_select(vf_lt(x, zero), vf_sub(vf_set(3.14159265f), r), r);
    return vf_select(vf_lt(y, zero), vf_sub(zero, r), r);
}

/* acosf(x) in lanes for x in [-1, 1] (Cephes' asinf about 0 and about
 * +-1; ~3e-7 absolute). */
static inline vf vf_acos(vf x)
{
    const vf half = vf_set(0.5f), one = vf_set(1);
    vf ax = vf_abs(x);
    vm big = vf_lt(half, ax);
    vf z = vf_select(big, vf_mul(half, vf_sub(one, ax)), vf_mul(x, x));
    vf s = vf_select(big, vf_sqrt(z), ax);
    vf p = vf_fma(vf_set(4.2163199048e-2f), z, vf_set(2.4181311049e-2f));
    p = vf_fma(p, z, vf_set(4.5470025998e-2f));
    p = vf_fma(p, z, vf_set(7.4953002686e-2f));
    p = vf_fma(p, z, vf_set(1.6666752422e-1f));
    vf as = vf_fma(vf_mul(p, z), s, s); /* asin(s) */
    /* |x| <= 1/2: pi/2 - asin(x); x > 1/2: 2 asin(sqrt((1 - x) / 2));
       x < -1/2: pi - that */
    vf small = vf_sub(vf_set(1.57079633f), vf_select(vf_lt(x, vf_set(0)), vf_sub(vf_set(0), as), as));
    vf two = vf_add(as, as);
    vf large = vf_select(vf_lt(x, vf_set(0)), vf_sub(vf_set(3.14159265f), two), two);
    return vf_select(big, large, small);
}

#if CULL_SIMD_ISA == 3
static inline vix vi_mul(vix a, vix b) { return _mm256_mullo_epi32(a, b); }
static inline vm vi_lt(vix a, vix b) { return _mm256_castsi256_ps(_mm256_cmpgt_epi32(b, a)); }
static inline vix vi_select(vm m, vix a, vix b) { return _mm256_castps_si256(vf_select(m, _mm256_castsi256_ps(a), _mm256_castsi256_ps(b))); }
#elif CULL_SIMD_ISA == 2
static inline vix vi_mul(vix a, vix b) { return _mm_mullo_epi32(a, b); }
static inline vm vi_lt(vix a, vix b) { return _mm_castsi128_ps(_mm_cmpgt_epi32(b, a)); }
static inline vix vi_select(vm m, vix a, vix b) { return _mm_castps_si128(vf_select(m, _mm_castsi128_ps(a), _mm_castsi128_ps(b))); }
#else
static inline vix vi_mul(vix a, vix b) { return (int32_t)((uint32_t)a * (uint32_t)b); }
static inline vm vi_lt(vix a, vix b) { return a < b ? ~0u : 0u; }
static inline vix vi_select(vm m, vix a, vix b) { return m ? a : b; }
#endif

/* vt_sky_uv and vt_sky_sample in lanes for a sky image (the analytic
 * sky's table or an environment map) towards the view rays c0 + X c1 of
 * the lanes' NDC x: the radiance into o. */
static inline void sky_lanes(const vt_penv *pe, const float c0[3], const float c1[3], vf X, vf o[3])
{
    const vt_texview *t = pe->sky_img;
    const vf zero = vf_set(0), one = vf_set(1);
    vf dx = vf_fma(X, vf_set(c1[0]), vf_set(c0[0])), dy = vf_fma(X, vf_set(c1[1]), vf_set(c0[1]));
    vf dz = vf_fma(X, vf_set(c1[2]), vf_set(c0[2]));
    vf l2 = vf_fma(dx, dx, vf_fma(dy, dy, vf_mul(dz, dz)));
    vf il = vf_rsqrt0(l2);
    dx = vf_mul(dx, il), dy = vf_mul(dy, il), dz = vf_mul(dz, il);
    /* vt_sky_uv */
    vf u = vf_fma(vf_add(vf_atan2(dx, vf_sub(zero, dz)), vf_set(pe->sky_rot)), vf_set(0.5f / 3.14159265f), vf_set(0.5f));
    u = vf_sub(u, vf_floor(u));
    vf v = vf_mul(vf_acos(vf_min(vf_max(dy, vf_set(-1)), one)), vf_set(1 / 3.14159265f));
    /* vt_sky_sample: bilinear, REPEAT across, CLAMP down; a NaN direction black */
    vm ok = vm_and(vm_and(vf_ge(u, zero), vf_le(u, one)), vm_and(vf_ge(v, zero), vf_le(v, one)));
    u = vf_select(ok, u, zero), v = vf_select(ok, v, zero);
    const int32_t w = (int32_t)t->w, h = (int32_t)t->h;
    vf x = vf_sub(vf_mul(u, vf_set((float)w)), vf_set(0.5f)), y = vf_sub(vf_mul(v, vf_set((float)h)), vf_set(0.5f));
    vf x0 = vf_floor(x), y0 = vf_floor(y), ax = vf_sub(x, x0), ay = vf_sub(y, y0);
    vix xi = vx_of(x0), yi = vx_of(y0), W1 = vi_set(w - 1);
    vix i0 = vi_select(vi_lt(xi, vi_set(0)), W1, vi_select(vi_lt(W1, xi), vi_set(0), xi));
    vix x1 = vi_add(xi, vi_set(1));
    vix i1 = vi_select(vi_lt(W1, x1), vi_set(0), vi_select(vi_lt(x1, vi_set(0)), W1, x1));
    vix j0 = vi_mul(vi_clamp(yi, h - 1), vi_set(w)), j1 = vi_mul(vi_clamp(vi_add(yi, vi_set(1)), h - 1), vi_set(w));
    vix a00 = vi_sll(vi_add(j0, i0), 2), a10 = vi_sll(vi_add(j0, i1), 2);
    vix a01 = vi_sll(vi_add(j1, i0), 2), a11 = vi_sll(vi_add(j1, i1), 2);
    for (int c = 0; c < 3; c++) {
        const float *p = t->hdr + c;
        vf a = vf_gather(p, a00), b = vf_gather(p, a10), e = vf_gather(p, a01), f = vf_gather(p, a11);
        vf top = vf_fma(ax, vf_sub(b, a), a), bot = vf_fma(ax, vf_sub(f, e), e);
        vf sv = vf_fma(ay, vf_sub(bot, top), top);
        sv = vf_select(vf_lt(vf_abs(sv), vf_set(INFINITY)), sv, zero); /* a NaN or infinite texel: 0 */
        o[c] = vf_select(ok, vf_mul(sv, vf_set(pe->sky_mul[c])), zero);
    }
}

/* Whether the view rays at the span's first column and 16 columns on
 * are less than a sky-table texel apart (cos 1.4 degrees = 0.9997). */
static inline bool span_narrow(const vt_span *sp, float X0)
{
    float a[3], b[3], X1 = X0 + (float)S * (float)sp->inv_w;
    for (int k = 0; k < 3; k++) a[k] = sp->ray0[k] + X0 * sp->ray1[k], b[k] = sp->ray0[k] + X1 * sp->ray1[k];
    float ab = a[0] * b[0] + a[1] * b[1] + a[2] * b[2], aa = a[0] * a[0] + a[1] * a[1] + a[2] * a[2];
    float bb = b[0] * b[0] + b[1] * b[1] + b[2] * b[2];
    return ab > 0 && ab * ab > 0.9994f * aa * bb; /* cos^2 */
}

/* The sky where nothing is drawn over the whole span (vt_span_sky's
 * job), in lanes with a sky image, else (a colour, or no image) by it.
 * The analytic sky's table is smooth (a continuous function of the
 * direction, across the azimuth's wrap and the poles too) and magnified
 * (1.4 degrees a texel; a pixel at 1280 across 60 degrees is ~0.05): where
 * the span's 16 columns see less than a texel, its radiance is looked up
 * exactly every 4th column and linearly in between (within a texel's
 * bilinear step); wider spans (small or wide-angle frames) exactly. */
static inline void span_sky(const vt_span *sp, float *cr, float *cg, float *cb, const float *cov)
{
    const vt_penv *pe = sp->pe;
    if (vt_gather_scalar || !pe->sky_img || !pe->sky_img->hdr || sp->n != S) {
        vt_span_sky(sp, cr, cg, cb, cov);
        return;
    }
    const vf zero = vf_set(0), lanes_x = lane_index(), dX = vf_set((float)sp->inv_w);
    uint32_t sky = 0; /* the pixels nothing covers */
    for (unsigned i = 0; i < S; i += W) sky |= vm_bits(vf_le(vf_load(cov + i), zero)) << i;
    if (!sky) return;
    const float X0 = vt_ndc_x(sp->x0, sp->inv_w);
    float *const out[3] = {cr, cg, cb};
    if (pe->sky_img == &pe->sky_tab && W >= 4 && span_narrow(sp, X0)) {
        /* columns 0, 4, .. 16 (the next span's first) */
        A float k[3][S / 4 + 1 + W];
        for (unsigned q = 0; q < S / 4 + 1; q += W) {
            vf o[3];
            sky_lanes(pe, sp->ray0, sp->ray1, vf_fma(vf_mul(vf_add(lanes_x, vf_set((float)q)), vf_set(4)), dX, vf_set(X0)), o);
            for (int c = 0; c < 3; c++) vf_store(k[c] + q, o[c]);
        }
        /* pixel i between k[i / 4] and k[i / 4 + 1] at (i % 4) / 4, in
           lanes (the ends fetched by index from the 5 values) */
        static const A int32_t q_of[16] = {0, 0, 0, 0, 1, 1, 1, 1, 2, 2, 2, 2, 3, 3, 3, 3};
        static const A float f_of[16] = {0, 0.25f, 0.5f, 0.75f, 0, 0.25f, 0.5f, 0.75f,
                                          0, 0.25f, 0.5f, 0.75f, 0, 0.25f, 0.5f, 0.75f};
        for (unsigned i = 0; i < S; i += W) {
            if (!(sky >> i & lanes_all())) continue;
            vix q = vi_loadu((const uint32_t *)(const void *)(q_of + i)), q1 = vi_add(q, vi_set(1));
            vf f = vf_load(f_of + i);
            vm open = vf_le(vf_load(cov + i), zero);
            for (int c = 0; c < 3; c++) {
                vf a = vf_gather(k[c], q), b = vf_gather(k[c], q1);
                vf_store(out[c] + i, vf_select(open, vf_fma(f, vf_sub(b, a), a), vf_load(out[c] + i)));
            }
        }
        return;
    }
    for (unsigned i = 0; i < S; i += W) {
        if (!(sky >> i & lanes_all())) continue;
        vf o[3];
        sky_lanes(pe, sp->ray0, sp->ray1, lanes_ndc_x(sp, i), o);
        vm open = vf_le(vf_load(cov + i), zero);
        for (int c = 0; c < 3; c++) vf_store(out[c] + i, vf_select(open, o[c], vf_load(out[c] + i)));
    }
}
