/*
 * vt_shadow.inl — the sun's shadow lookup (vt_shadow_lookup, vt_shadow.c)
 * over a span, W pixels a step: included by vt_shadow_{sse41,avx2}.c
 * after cull_simd.h with VT_SHADOW_N_NAME defined (one lane is
 * vt_shadow_lookup itself, in vt_shadow.c).
 *
 * Each lane does vt_shadow_lookup's float operations in its order (plain
 * multiplies and adds, true divisions and square roots, no FMA: the build
 * is ISO C, -ffp-contract=off), so the span gives the per-pixel lookup's
 * value bit for bit (test_shadow_lookup_lanes). A lane's cascade is picked
 * by selects over the (at most 4) cascades; its 16 PCF taps: where every
 * lane's 4x4 footprint is in the map (most), a row of 4 texels a lane by
 * one contiguous load, transposed into columns; else fetched by index
 * (AVX2: gathers; SSE4.1: four loads), off-map taps masked to 0.
 *
 * Most lookups are decided before the taps by the cascade's footprint
 * tiles (vt_shadow.c, the footprint tiles): a lane whose 4x4 footprint
 * lies in the map and whose tile's depth range is wholly at or below its
 * reference passes every tap, wholly above it fails every one; its value
 * is the PCF's for that case computed with the same operations (all
 * pass: the weights' sums in the taps' order; all fail: 0), so the answer
 * is the same bit for bit, for one gather of the packed tiles (a
 * quantised range in 32 bits, conservative by more than a step: a range
 * it calls decided is) instead of the taps. The lanes
 * left undecided (penumbrae, and footprints whose tile straddles a
 * depth) are packed, from up to CH pixels, into whole steps of taps.
 */
#include <math.h>

static inline vf sh_floor(vf a)
{
#if CULL_SIMD_ISA == 3
    return _mm256_floor_ps(a);
#else
    return _mm_floor_ps(a);
#endif
}

/* base[q] for exact integral float indices q (masked lanes: 0). */
static inline vf sh_gather(const float *base, vf q)
{
#if CULL_SIMD_ISA == 3
    return _mm256_i32gather_ps(base, _mm256_cvttps_epi32(q), 4);
#else
    __m128i i = _mm_cvttps_epi32(q);
    return _mm_setr_ps(base[_mm_cvtsi128_si32(i)], base[_mm_extract_epi32(i, 1)], base[_mm_extract_epi32(i, 2)],
                       base[_mm_extract_epi32(i, 3)]);
#endif
}

/* The packed tiles base[q] for exact integral float indices q (masked
 * lanes: 0) as their bounds' steps: *a the lower, *b the upper. */
static inline void sh_gather_q(const uint32_t *base, vf q, vf *a, vf *b)
{
#if CULL_SIMD_ISA == 3
    const __m256i t = _mm256_i32gather_epi32((const int *)base, _mm256_cvttps_epi32(q), 4);
    *a = _mm256_cvtepi32_ps(_mm256_and_si256(t, _mm256_set1_epi32(0xffff)));
    *b = _mm256_cvtepi32_ps(_mm256_srli_epi32(t, 16));
#else
    __m128i i = _mm_cvttps_epi32(q);
    const __m128i t = _mm_setr_epi32((int)base[_mm_cvtsi128_si32(i)], (int)base[_mm_extract_epi32(i, 1)],
                                     (int)base[_mm_extract_epi32(i, 2)], (int)base[_mm_extract_epi32(i, 3)]);
    *a = _mm_cvtepi32_ps(_mm_and_si128(t, _mm_set1_epi32(0xffff)));
    *b = _mm_cvtepi32_ps(_mm_srli_epi32(t, 16));
#endif
}

/* Each lane's cascade (0..n-1), as sh_pick reads it: AVX2 a variable
 * permute of the (at most 4) cascades' constants; else selects over
 * "ci >= c" masks made once. */
typedef struct sh_ci {
#if CULL_SIMD_ISA == 3
    __m256i idx;
#else
    vm ge[VT_SHADOW_CASCADES];
#endif
} sh_ci;

_Static_assert(VT_SHADOW_CASCADES == 4, "sh_pick reads 4 constants a cascade");

static inline sh_ci sh_ci_make(vf ci, uint32_t n)
{
    sh_ci c;
#if CULL_SIMD_ISA == 3
    (void)n;
    c.idx = _mm256_cvttps_epi32(ci);
#else
    for (uint32_t k = 0; k < VT_SHADOW_CASCADES; k++) c.ge[k] = vf_le(vf_set((float)k), ci);
    (void)n;
#endif
    return c;
}

/* A per-cascade constant (v: VT_SHADOW_CASCADES floats) for each lane's cascade. */
static inline vf sh_pick(const float *v, uint32_t n, const sh_ci *c)
{
#if CULL_SIMD_ISA == 3
    (void)n;
    const __m128 t = _mm_loadu_ps(v);
    return _mm256_permutevar_ps(_mm256_set_m128(t, t), c->idx);
#else
    vf r = vf_set(v[0]);
    for (uint32_t k = 1; k < n; k++) r = vf_select(c->ge[k], vf_set(v[k]), r);
    return r;
#endif
}

/* Per-cascade constants as sh_pick reads them (vt_shadow.h). */
typedef vt_shadow_cons sh_cons;

/* What one lookup of one cascade needs for its taps (a lane of a step). */
typedef struct sh_tap {
    vf x0, y0, fx, fy, dref, mb;
} sh_tap;

/* The first half of cascade_vis (vt_shadow.c) for each lane's cascade ci,
 * lanes m: the value where the tiles decide it (or the point is off the
 * map: 1), *und the lanes that need their taps (whose inputs *t gets). */
static inline __attribute__((always_inline)) vf sh_prep(const vt_shadow_fit *f, const sh_cons *kc, const sh_ci *ci, vm m, const vf p[3], const vf n[3],
                         vf ndl, sh_tap *t, vm *und)
{
    const vf zero = vf_set(0), one = vf_set(1);
    const float *offx = kc->offx, *offy = kc->offy;
    const vf tx = sh_pick(f->texel, f->n, ci), scale = sh_pick(f->scale, f->n, ci);
    vf sn = vf_sqrt(vf_max(vf_sub(one, vf_mul(ndl, ndl)), zero)), tn = vf_min(vf_div(sn, ndl), vf_set(8.0f));
    vf o = vf_mul(vf_mul(vf_set(VT_SHADOW_NOFS), tx), sn);
    vf q[3];
    for (int k = 0; k < 3; k++) q[k] = vf_add(p[k], vf_mul(n[k], o));
    vf dref = vf_add(vf_add(vf_add(vf_mul(vf_set(f->s[0]), q[0]), vf_mul(vf_set(f->s[1]), q[1])), vf_mul(vf_set(f->s[2]), q[2])),
                     vf_mul(tx, vf_add(vf_set(VT_SHADOW_BIAS_C), vf_mul(vf_set(VT_SHADOW_BIAS_S), tn))));
    vf mx = vf_add(vf_mul(vf_add(vf_add(vf_mul(vf_set(f->u[0]), q[0]), vf_mul(vf_set(f->u[1]), q[1])),
                                 vf_mul(vf_set(f->u[2]), q[2])),
                          scale),
                   sh_pick(offx, f->n, ci));
    vf my = vf_add(vf_mul(vf_add(vf_add(vf_mul(vf_set(f->v[0]), q[0]), vf_mul(vf_set(f->v[1]), q[1])),
                                 vf_mul(vf_set(f->v[2]), q[2])),
                          scale),
                   sh_pick(offy, f->n, ci));
    const float szf = (float)f->size;
    const vf lo = vf_set(-2.0f), hi = vf_set(szf + 2.0f);
    m = vm_and(m, vm_and(vm_and(vf_lt(lo, mx), vf_lt(mx, hi)), vm_and(vf_lt(lo, my), vf_lt(my, hi))));
    *und = m;
    if (!vm_bits(m)) return one;
    vf X = vf_sub(mx, vf_set(0.5f)), Y = vf_sub(my, vf_set(0.5f));
    X = vf_select(m, X, zero), Y = vf_select(m, Y, zero);
    vf fx0 = sh_floor(X), fy0 = sh_floor(Y);
    t->fx = vf_sub(X, fx0), t->fy = vf_sub(Y, fy0);
    t->x0 = vf_sub(fx0, one), t->y0 = vf_sub(fy0, one);
    t->dref = dref;
    t->mb = sh_pick(kc->base, f->n, ci);
    if (!kc->tq) return one;
    /* the footprint x0..x0 + 3 lies in tile floor((x0 + 1) / 2)'s range
       (texels 2t - 1 .. 2t + 3): the tiles' rule */
    const vf lim = vf_set(szf - 4.0f), half = vf_set(0.5f);
    vm fin = vm_and(m, vm_and(vm_and(vf_le(zero, t->x0), vf_le(t->x0, lim)), vm_and(vf_le(zero, t->y0), vf_le(t->y0, lim))));
    if (!vm_bits(fin)) return one;
    vf tix = sh_floor(vf_mul(vf_add(t->x0, one), half)), tiy = sh_floor(vf_mul(vf_add(t->y0, one), half));
    vf ti = vf_select(fin, vf_add(sh_pick(kc->tbase, f->n, ci), vf_add(vf_mul(tiy, vf_set(kc->g)), tix)), zero);
    /* the reference in the tiles' steps; decided only within 0 .. 65535
       (the bounds 0 and 65535 stand for "unbounded") */
    vf qa, qb, dq = vf_mul(vf_sub(dref, sh_pick(kc->qlo, f->n, ci)), sh_pick(kc->qinv, f->n, ci));
    sh_gather_q(kc->tq, ti, &qa, &qb);
    fin = vm_and(fin, vm_and(vf_le(zero, dq), vf_lt(dq, vf_set(65535.0f))));
    vm all = vm_and(fin, vf_le(qb, dq)), none = vm_and(fin, vf_lt(dq, qa));
    *und = vm_andnot(m, vm_or(all, none));
    /* the taps' sums when every tap passes, in their order */
    vf wx0 = vf_sub(one, t->fx), wy0 = vf_sub(one, t->fy);
    vf r = vf_add(vf_add(vf_add(vf_add(zero, wx0), one), one), t->fx);
    vf lit = vf_add(vf_add(vf_add(vf_add(zero, vf_mul(wy0, r)), vf_mul(one, r)), vf_mul(one, r)), vf_mul(t->fy, r));
    return vf_select(all, vf_mul(lit, vf_set(1.0f / 9.0f)), vf_select(none, zero, one));
}

/* The 4 texels base[id[l]] .. base[id[l] + 3] of each lane l as 4 columns
 * (c[a]: texel a of every lane): a contiguous load a lane and a
 * transpose, cheaper than 4 gathers (8 loads each on Zen 3). */
static inline void sh_row4(const float *base, const int32_t *id, vf c[4])
{
#if CULL_SIMD_ISA == 3
    __m256 a0 = _mm256_insertf128_ps(_mm256_castps128_ps256(_mm_loadu_ps(base + id[0])), _mm_loadu_ps(base + id[4]), 1);
    __m256 a1 = _mm256_insertf128_ps(_mm256_castps128_ps256(_mm_loadu_ps(base + id[1])), _mm_loadu_ps(base + id[5]), 1);
    __m256 a2 = _mm256_insertf128_ps(_mm256_castps128_ps256(_mm_loadu_ps(base + id[2])), _mm_loadu_ps(base + id[6]), 1);
    __m256 a3 = _mm256_insertf128_ps(_mm256_castps128_ps256(_mm_loadu_ps(base + id[3])), _mm_loadu_ps(base + id[7]), 1);
    __m256 t0 = _mm256_unpacklo_ps(a0, a1), t1 = _mm256_unpackhi_ps(a0, a1);
    __m256 t2 = _mm256_unpacklo_ps(a2, a3), t3 = _mm256_unpackhi_ps(a2, a3);
    c[0] = _mm256_shuffle_ps(t0, t2, 0x44), c[1] = _mm256_shuffle_ps(t0, t2, 0xee);
    c[2] = _mm256_shuffle_ps(t1, t3, 0x44), c[3] = _mm256_shuffle_ps(t1, t3, 0xee);
#else
    __m128 a0 = _mm_loadu_ps(base + id[0]), a1 = _mm_loadu_ps(base + id[1]), a2 = _mm_loadu_ps(base + id[2]),
           a3 = _mm_loadu_ps(base + id[3]);
    _MM_TRANSPOSE4_PS(a0, a1, a2, a3);
    c[0] = a0, c[1] = a1, c[2] = a2, c[3] = a3;
#endif
}

/* The second half of cascade_vis: the 16 taps of lanes m. */
static inline vf sh_taps(const vt_shadow_fit *f, const float *maps, const sh_tap *t, vm m)
{
    const vf zero = vf_set(0), one = vf_set(1);
    const float szf = (float)f->size;
    const vf sz = vf_set(szf);
    const vf wx[4] = {vf_sub(one, t->fx), one, one, t->fx}, wy[4] = {vf_sub(one, t->fy), one, one, t->fy};
    vf lit = zero, xs[4];
    /* every lane's footprint in the map (most): one index, the 16 taps at
       constant offsets from it (no per-tap index or bounds), the sums in
       the same order */
    const vf lim = vf_set(szf - 4.0f);
    vm fin = vm_and(vm_and(vf_le(zero, t->x0), vf_le(t->x0, lim)), vm_and(vf_le(zero, t->y0), vf_le(t->y0, lim)));
    if (vm_bits(vm_andnot(m, fin)) == 0) {
        const vf q = vf_select(m, vf_add(t->mb, vf_add(vf_mul(t->y0, sz), t->x0)), zero);
        int32_t id[W];
#if CULL_SIMD_ISA == 3
        _mm256_storeu_si256((__m256i *)id, _mm256_cvttps_epi32(q));
#else
        _mm_storeu_si128((__m128i *)id, _mm_cvttps_epi32(q));
#endif
        for (int b = 0; b < 4; b++) {
            vf c[4], r = zero;
            sh_row4(maps + (size_t)b * f->size, id, c);
            for (int a = 0; a < 4; a++) r = vf_add(r, vm_and(vf_le(c[a], t->dref), wx[a]));
            lit = vf_add(lit, vf_mul(wy[b], r));
        }
        return vf_mul(lit, vf_set(1.0f / 9.0f));
    }
    vm xin[4];
    for (int a = 0; a < 4; a++) { /* the columns, the same for every row */
        xs[a] = vf_add(t->x0, vf_set((float)a));
        xin[a] = vm_and(vf_le(zero, xs[a]), vf_lt(xs[a], sz));
    }
    for (int b = 0; b < 4; b++) {
        vf y = vf_add(t->y0, vf_set((float)b));
        vm yin = vm_and(vf_le(zero, y), vf_lt(y, sz)), mrow = vm_and(m, yin);
        vf rowq = vf_add(t->mb, vf_mul(y, sz));
        vf r = zero;
        for (int a = 0; a < 4; a++) {
            vf v = sh_gather(maps, vf_select(vm_and(mrow, xin[a]), vf_add(rowq, xs[a]), zero));
            vm pass = vm_or(vm_andnot(vm_ones(), xin[a]), vf_le(v, t->dref));
            r = vf_add(r, vf_select(pass, wx[a], zero));
        }
        lit = vf_add(lit, vf_mul(wy[b], vf_select(yin, r, vf_set(3.0f))));
    }
    return vf_mul(lit, vf_set(1.0f / 9.0f));
}

/* Pixels a pass: the undecided lookups of this many are packed into
 * whole steps (two per pixel at most: a blend band's second cascade). */
#define CH 32

/* One lookup's taps waiting in the pack: its inputs, and where its value
 * goes (an index into the pass' values: v1, then v2). */
typedef struct sh_pack {
    float x0[2 * CH + W], y0[2 * CH + W], fx[2 * CH + W], fy[2 * CH + W], dref[2 * CH + W], mb[2 * CH + W];
    int32_t dst[2 * CH + W];
    unsigned n;
} sh_pack;

#if CULL_SIMD_ISA == 3
/* Left-packing permutations: for 8 lane bits, the set lanes' numbers in
 * order, 4 bits each (the pack's stores: a permute, not a loop). */
static const uint32_t sh_lp[256] = {
    0x00000000u, 0x00000000u, 0x00000001u, 0x00000010u, 0x00000002u, 0x00000020u, 0x00000021u, 0x00000210u,
    0x00000003u, 0x00000030u, 0x00000031u, 0x00000310u, 0x00000032u, 0x00000320u, 0x00000321u, 0x00003210u,
    0x00000004u, 0x00000040u, 0x00000041u, 0x00000410u, 0x00000042u, 0x00000420u, 0x00000421u, 0x00004210u,
    0x00000043u, 0x00000430u, 0x00000431u, 0x00004310u, 0x00000432u, 0x00004320u, 0x00004321u, 0x00043210u,
    0x00000005u, 0x00000050u, 0x00000051u, 0x00000510u, 0x00000052u, 0x00000520u, 0x00000521u, 0x00005210u,
    0x00000053u, 0x00000530u, 0x00000531u, 0x00005310u, 0x00000532u, 0x00005320u, 0x00005321u, 0x00053210u,
    0x00000054u, 0x00000540u, 0x00000541u, 0x00005410u, 0x00000542u, 0x00005420u, 0x00005421u, 0x00054210u,
    0x00000543u, 0x00005430u, 0x00005431u, 0x00054310u, 0x00005432u, 0x00054320u, 0x00054321u, 0x00543210u,
    0x00000006u, 0x00000060u, 0x00000061u, 0x00000610u, 0x00000062u, 0x00000620u, 0x00000621u, 0x00006210u,
    0x00000063u, 0x00000630u, 0x00000631u, 0x00006310u, 0x00000632u, 0x00006320u, 0x00006321u, 0x00063210u,
    0x00000064u, 0x00000640u, 0x00000641u, 0x00006410u, 0x00000642u, 0x00006420u, 0x00006421u, 0x00064210u,
    0x00000643u, 0x00006430u, 0x00006431u, 0x00064310u, 0x00006432u, 0x00064320u, 0x00064321u, 0x00643210u,
    0x00000065u, 0x00000650u, 0x00000651u, 0x00006510u, 0x00000652u, 0x00006520u, 0x00006521u, 0x00065210u,
    0x00000653u, 0x00006530u, 0x00006531u, 0x00065310u, 0x00006532u, 0x00065320u, 0x00065321u, 0x00653210u,
    0x00000654u, 0x00006540u, 0x00006541u, 0x00065410u, 0x00006542u, 0x00065420u, 0x00065421u, 0x00654210u,
    0x00006543u, 0x00065430u, 0x00065431u, 0x00654310u, 0x00065432u, 0x00654320u, 0x00654321u, 0x06543210u,
    0x00000007u, 0x00000070u, 0x00000071u, 0x00000710u, 0x00000072u, 0x00000720u, 0x00000721u, 0x00007210u,
    0x00000073u, 0x00000730u, 0x00000731u, 0x00007310u, 0x00000732u, 0x00007320u, 0x00007321u, 0x00073210u,
    0x00000074u, 0x00000740u, 0x00000741u, 0x00007410u, 0x00000742u, 0x00007420u, 0x00007421u, 0x00074210u,
    0x00000743u, 0x00007430u, 0x00007431u, 0x00074310u, 0x00007432u, 0x00074320u, 0x00074321u, 0x00743210u,
    0x00000075u, 0x00000750u, 0x00000751u, 0x00007510u, 0x00000752u, 0x00007520u, 0x00007521u, 0x00075210u,
    0x00000753u, 0x00007530u, 0x00007531u, 0x00075310u, 0x00007532u, 0x00075320u, 0x00075321u, 0x00753210u,
    0x00000754u, 0x00007540u, 0x00007541u, 0x00075410u, 0x00007542u, 0x00075420u, 0x00075421u, 0x00754210u,
    0x00007543u, 0x00075430u, 0x00075431u, 0x00754310u, 0x00075432u, 0x00754320u, 0x00754321u, 0x07543210u,
    0x00000076u, 0x00000760u, 0x00000761u, 0x00007610u, 0x00000762u, 0x00007620u, 0x00007621u, 0x00076210u,
    0x00000763u, 0x00007630u, 0x00007631u, 0x00076310u, 0x00007632u, 0x00076320u, 0x00076321u, 0x00763210u,
    0x00000764u, 0x00007640u, 0x00007641u, 0x00076410u, 0x00007642u, 0x00076420u, 0x00076421u, 0x00764210u,
    0x00007643u, 0x00076430u, 0x00076431u, 0x00764310u, 0x00076432u, 0x00764320u, 0x00764321u, 0x07643210u,
    0x00000765u, 0x00007650u, 0x00007651u, 0x00076510u, 0x00007652u, 0x00076520u, 0x00076521u, 0x00765210u,
    0x00007653u, 0x00076530u, 0x00076531u, 0x00765310u, 0x00076532u, 0x00765320u, 0x00765321u, 0x07653210u,
    0x00007654u, 0x00076540u, 0x00076541u, 0x00765410u, 0x00076542u, 0x00765420u, 0x00765421u, 0x07654210u,
    0x00076543u, 0x00765430u, 0x00765431u, 0x07654310u, 0x00765432u, 0x07654320u, 0x07654321u, 0x76543210u,
};
#endif

/* Lanes und of t to the pack, their values to go to index dst + lane. */
static inline void sh_push(sh_pack *pk, const sh_tap *t, vm und, int32_t dst)
{
    uint32_t bits = vm_bits(und);
    if (!bits) return;
#if CULL_SIMD_ISA == 3
    const __m256i perm = _mm256_and_si256(_mm256_srlv_epi32(_mm256_set1_epi32((int)sh_lp[bits]),
                                                            _mm256_setr_epi32(0, 4, 8, 12, 16, 20, 24, 28)),
                                          _mm256_set1_epi32(15));
    const unsigned e = pk->n;
    _mm256_storeu_ps(pk->x0 + e, _mm256_permutevar8x32_ps(t->x0, perm));
    _mm256_storeu_ps(pk->y0 + e, _mm256_permutevar8x32_ps(t->y0, perm));
    _mm256_storeu_ps(pk->fx + e, _mm256_permutevar8x32_ps(t->fx, perm));
    _mm256_storeu_ps(pk->fy + e, _mm256_permutevar8x32_ps(t->fy, perm));
    _mm256_storeu_ps(pk->dref + e, _mm256_permutevar8x32_ps(t->dref, perm));
    _mm256_storeu_ps(pk->mb + e, _mm256_permutevar8x32_ps(t->mb, perm));
    _mm256_storeu_si256((__m256i *)(pk->dst + e), _mm256_add_epi32(_mm256_set1_epi32(dst), perm));
    pk->n = e + (unsigned)__builtin_popcount(bits);
#else
    float tmp[6][W];
    vf_store(tmp[0], t->x0), vf_store(tmp[1], t->y0), vf_store(tmp[2], t->fx);
    vf_store(tmp[3], t->fy), vf_store(tmp[4], t->dref), vf_store(tmp[5], t->mb);
    for (; bits; bits &= bits - 1) {
        int l = __builtin_ctz(bits);
        unsigned e = pk->n++;
        pk->x0[e] = tmp[0][l], pk->y0[e] = tmp[1][l], pk->fx[e] = tmp[2][l];
        pk->fy[e] = tmp[3][l], pk->dref[e] = tmp[4][l], pk->mb[e] = tmp[5][l];
        pk->dst[e] = dst + l;
    }
#endif
}

void VT_SHADOW_N_NAME(const vt_shadow_fit *f, const float *maps, const vt_shadow_cons *kp, unsigned n,
                      const float *px, const float *py, const float *pz, const float *nx, const float *ny,
                      const float *nz, float *out)
{
    const vf zero = vf_set(0), one = vf_set(1);
    const uint32_t N = f->n;
    _Static_assert(VT_SHADOW_TILE == 2, "sh_prep's tile rule is for tiles of 2 texels");
    const sh_cons *const kc = kp;
    const float *far = kc->far, *bandv = kc->band;
    sh_pack pk;
    /* per pixel of a pass: the first and the second cascade's value, the
       blend's weight (and masks as floats: looked up, blended, the
       second cascade exists) */
    float vals[2 * CH], tb[CH], fm[CH], fbl[CH], fnx[CH];
    float *const v1 = vals, *const v2 = vals + CH;
    /* the cascades' starts, those past the last never reached (a loop of
       constant length, unrolled) */
    float splits[VT_SHADOW_CASCADES];
    for (uint32_t c = 0; c < VT_SHADOW_CASCADES; c++) splits[c] = c < N ? f->split[c] : INFINITY;
    for (unsigned c0 = 0; c0 < n; c0 += CH) {
        const unsigned cn = n - c0 < CH ? n - c0 : CH;
        pk.n = 0;
        bool any = false;
        for (unsigned i = 0; i < cn; i += W) {
            unsigned nw = cn - i < (unsigned)W ? cn - i : (unsigned)W;
            const unsigned o = c0 + i;
            vf p[3], nn[3];
            if (nw == (unsigned)W) { /* a whole step (a span of 16 is two or four) */
                p[0] = vf_loadu(px + o), p[1] = vf_loadu(py + o), p[2] = vf_loadu(pz + o);
                nn[0] = vf_loadu(nx + o), nn[1] = vf_loadu(ny + o), nn[2] = vf_loadu(nz + o);
            } else {
                const float *const src[6] = {px + o, py + o, pz + o, nx + o, ny + o, nz + o};
                float tp[6][W];
                for (int c = 0; c < 6; c++)
                    for (unsigned l = 0; l < (unsigned)W; l++) tp[c][l] = l < nw ? src[c][l] : 0.0f;
                for (int c = 0; c < 3; c++) p[c] = vf_loadu(tp[c]), nn[c] = vf_loadu(tp[3 + c]);
            }
            vf ndl = vf_add(vf_add(vf_mul(vf_set(f->s[0]), nn[0]), vf_mul(vf_set(f->s[1]), nn[1])), vf_mul(vf_set(f->s[2]), nn[2]));
            vf d = vf_add(vf_add(vf_add(vf_mul(vf_set(f->drow[0]), p[0]), vf_mul(vf_set(f->drow[1]), p[1])),
                                 vf_mul(vf_set(f->drow[2]), p[2])),
                          vf_set(f->drow[3]));
            vm m = vm_and(vf_lt(zero, ndl), vf_lt(d, vf_set(f->split[N])));
            vf_store(fm + i, vf_select(m, one, zero));
            if (!vm_bits(m)) continue; /* lit: out unchanged (times 1) */
            any = true;
            vf ci = zero;
            for (uint32_t c = 1; c < VT_SHADOW_CASCADES; c++) ci = vf_add(ci, vm_and(vf_ge(d, vf_set(splits[c])), one));
            sh_tap t;
            vm und;
            const sh_ci cs = sh_ci_make(ci, N);
            vf_store(v1 + i, sh_prep(f, kc, &cs, m, p, nn, ndl, &t, &und));
            sh_push(&pk, &t, und, (int32_t)i);
            vf fr = sh_pick(far, N, &cs), band = sh_pick(bandv, N, &cs);
            /* the blend's weight where a lane is in its band (band > 0:
               the sign of the division's; one it rounds to 0 blends by 0) */
            vf tn = vf_sub(d, vf_sub(fr, band));
            vm bl = vm_and(m, vf_lt(zero, tn));
            vf_store(fbl + i, vm_and(bl, one));
            if (vm_bits(bl)) {
                vf_store(tb + i, vf_div(tn, band));
                vf cn2 = vf_add(ci, one);
                vm nx2 = vf_lt(cn2, vf_set((float)N));
                vf_store(fnx + i, vf_select(nx2, one, zero));
                const sh_ci cs2 = sh_ci_make(vf_select(nx2, cn2, ci), N);
                vf_store(v2 + i, sh_prep(f, kc, &cs2, vm_and(bl, nx2), p, nn, ndl, &t, &und));
                sh_push(&pk, &t, und, (int32_t)(CH + i));
            }
        }
        if (!any) continue;
        /* the packed lookups' taps, W at a time (the last step's spare
           lanes masked: zeros, their fetches texel 0, their values unused) */
        for (unsigned e = 0; e < pk.n; e += W) {
            unsigned ne = pk.n - e < (unsigned)W ? pk.n - e : (unsigned)W;
            const vm me = vm_from_bits((1u << ne) - 1);
            sh_tap t = {vf_select(me, vf_loadu(pk.x0 + e), zero), vf_select(me, vf_loadu(pk.y0 + e), zero),
                        vf_select(me, vf_loadu(pk.fx + e), zero), vf_select(me, vf_loadu(pk.fy + e), zero),
                        vf_select(me, vf_loadu(pk.dref + e), zero), vf_select(me, vf_loadu(pk.mb + e), zero)};
            float r[W];
            vf_store(r, sh_taps(f, maps, &t, me));
            for (unsigned l = 0; l < ne; l++) vals[pk.dst[e + l]] = r[l];
        }
        for (unsigned i = 0; i < cn; i += W) {
            unsigned nw = cn - i < (unsigned)W ? cn - i : (unsigned)W;
            vm m = vf_lt(zero, vf_loadu(fm + i));
            if (!vm_bits(m)) continue;
            vf vis = vf_loadu(v1 + i);
            vm bl = vf_lt(zero, vf_loadu(fbl + i));
            if (vm_bits(bl)) {
                vm nx2 = vf_lt(zero, vf_loadu(fnx + i));
                vf w2 = vf_select(nx2, vf_loadu(v2 + i), one);
                vis = vf_select(bl, vf_add(vis, vf_mul(vf_sub(w2, vis), vf_min(vf_loadu(tb + i), one))), vis);
            }
            vf res = vf_select(m, vis, one);
            float *o = out + c0 + i;
            if (nw == (unsigned)W) {
                vf_store(o, vf_mul(vf_loadu(o), res));
                continue;
            }
            float rr[W];
            vf_store(rr, res);
            for (unsigned l = 0; l < nw; l++) o[l] *= rr[l];
        }
    }
}
