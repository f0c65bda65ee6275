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
 * by selects over the (at most 4) cascades, its 16 PCF taps fetched by
 * index (AVX2: gathers; SSE4.1: four loads), off-map taps masked to 0.
 *
 * Most lookups are decided before the taps by the cascade's footprint
 * tiles (vt_shadow.c, the footprint tiles): a lane whose 4x4 footprint
 * lies in the map and whose tile's depth range is wholly at or below its
 * reference passes every tap, wholly above it fails every one; its value
 * is the PCF's for that case computed with the same operations (all
 * pass: the weights' sums in the taps' order; all fail: 0), so the answer
 * is the same bit for bit, for two gathers instead of sixteen. The lanes
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

/* A per-cascade constant for each lane's cascade ci (0..n-1 as floats). */
static inline vf sh_pick(const float *v, uint32_t n, vf ci)
{
    vf r = vf_set(v[0]);
    for (uint32_t c = 1; c < n; c++) r = vf_select(vf_le(vf_set((float)c), ci), vf_set(v[c]), r);
    return r;
}

/* Per-cascade constants as sh_pick reads them, once a span. */
typedef struct sh_cons {
    float offx[VT_SHADOW_CASCADES], offy[VT_SHADOW_CASCADES], base[VT_SHADOW_CASCADES];
    float far[VT_SHADOW_CASCADES], band[VT_SHADOW_CASCADES];
    float tbase[VT_SHADOW_CASCADES]; /* each cascade's first tile */
    const float *tmin, *tmax;        /* the footprint tiles (NULL: none) */
    float g;                         /* tiles a side */
} sh_cons;

/* What one lookup of one cascade needs for its taps (a lane of a step). */
typedef struct sh_tap {
    vf x0, y0, fx, fy, dref, mb;
} sh_tap;

/* The first half of cascade_vis (vt_shadow.c) for each lane's cascade ci,
 * lanes m: the value where the tiles decide it (or the point is off the
 * map: 1), *und the lanes that need their taps (whose inputs *t gets). */
static inline vf sh_prep(const vt_shadow_fit *f, const sh_cons *kc, vf ci, vm m, const vf p[3], const vf n[3],
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
    if (!kc->tmin) return one;
    /* the footprint x0..x0 + 3 lies in tile floor((x0 + 2) / 4)'s range
       (texels 4t - 4 .. 4t + 7): the tiles' rule */
    const vf lim = vf_set(szf - 4.0f), two = vf_set(2.0f), qu = vf_set(0.25f);
    vm fin = vm_and(m, vm_and(vm_and(vf_le(zero, t->x0), vf_le(t->x0, lim)), vm_and(vf_le(zero, t->y0), vf_le(t->y0, lim))));
    if (!vm_bits(fin)) return one;
    vf tix = sh_floor(vf_mul(vf_add(t->x0, two), qu)), tiy = sh_floor(vf_mul(vf_add(t->y0, two), qu));
    vf ti = vf_select(fin, vf_add(sh_pick(kc->tbase, f->n, ci), vf_add(vf_mul(tiy, vf_set(kc->g)), tix)), zero);
    vm all = vm_and(fin, vf_le(sh_gather(kc->tmax, ti), dref)), none = vm_and(fin, vf_lt(dref, sh_gather(kc->tmin, ti)));
    *und = vm_andnot(m, vm_or(all, none));
    /* the taps' sums when every tap passes, in their order */
    vf wx0 = vf_sub(one, t->fx), wy0 = vf_sub(one, t->fy);
    vf r = vf_add(vf_add(vf_add(vf_add(zero, wx0), one), one), t->fx);
    vf lit = vf_add(vf_add(vf_add(vf_add(zero, vf_mul(wy0, r)), vf_mul(one, r)), vf_mul(one, r)), vf_mul(t->fy, r));
    return vf_select(all, vf_mul(lit, vf_set(1.0f / 9.0f)), vf_select(none, zero, one));
}

/* The second half of cascade_vis: the 16 taps of lanes m. */
static inline vf sh_taps(const vt_shadow_fit *f, const float *maps, const sh_tap *t, vm m)
{
    const vf zero = vf_set(0), one = vf_set(1);
    const float szf = (float)f->size;
    const vf sz = vf_set(szf);
    const vf wx[4] = {vf_sub(one, t->fx), one, one, t->fx}, wy[4] = {vf_sub(one, t->fy), one, one, t->fy};
    vf lit = zero, xs[4];
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

/* One lookup's taps waiting in the pack: its inputs, and where its value goes. */
typedef struct sh_pack {
    float x0[2 * CH + W], y0[2 * CH + W], fx[2 * CH + W], fy[2 * CH + W], dref[2 * CH + W], mb[2 * CH + W];
    float *dst[2 * CH + W];
    unsigned n;
} sh_pack;

/* Lanes und of t to the pack, their values to go to dst[lane]. */
static inline void sh_push(sh_pack *pk, const sh_tap *t, vm und, float *dst)
{
    uint32_t bits = vm_bits(und);
    if (!bits) return;
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
}

void VT_SHADOW_N_NAME(const vt_shadow_fit *f, const float *maps, const float *tiles, unsigned n, const float *px,
                      const float *py, const float *pz, const float *nx, const float *ny, const float *nz, float *out)
{
    const vf zero = vf_set(0), one = vf_set(1);
    const uint32_t N = f->n;
    /* the cascades' map offsets, far ends and blend bands */
    sh_cons k;
    const uint32_t g = f->size / 4;
    k.tmin = tiles, k.tmax = tiles ? tiles + (size_t)N * g * g : NULL, k.g = (float)g;
    for (uint32_t c = 0; c < N; c++) {
        k.tbase[c] = (float)((size_t)c * g * g);
        k.offx[c] = f->off[c][0], k.offy[c] = f->off[c][1], k.base[c] = (float)((size_t)c * f->size * f->size);
        k.far[c] = f->split[c + 1];
        k.band[c] = VT_SHADOW_BLEND * (f->split[c + 1] - f->split[c]);
    }
    const float *far = k.far, *bandv = k.band;
    sh_pack pk;
    /* per pixel of a pass: the first and the second cascade's value, the
       blend's weight (and masks as floats: looked up, blended, the
       second cascade exists) */
    float v1[CH], v2[CH], tb[CH], fm[CH], fbl[CH], fnx[CH];
    for (unsigned c0 = 0; c0 < n; c0 += CH) {
        const unsigned cn = n - c0 < CH ? n - c0 : CH;
        pk.n = 0;
        bool any = false;
        for (unsigned i = 0; i < cn; i += W) {
            float tp[6][W];
            unsigned nw = cn - i < (unsigned)W ? cn - i : (unsigned)W;
            const float *src[6] = {px + c0, py + c0, pz + c0, nx + c0, ny + c0, nz + c0};
            vf p[3], nn[3];
            if (nw == (unsigned)W) { /* a whole step (a span of 16 is two or four) */
                for (int c = 0; c < 3; c++) p[c] = vf_loadu(src[c] + i), nn[c] = vf_loadu(src[3 + c] + i);
            } else {
                for (int c = 0; c < 6; c++)
                    for (unsigned l = 0; l < (unsigned)W; l++) tp[c][l] = l < nw ? src[c][i + l] : 0.0f;
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
            for (uint32_t c = 1; c < N; c++) ci = vf_add(ci, vf_select(vf_ge(d, vf_set(f->split[c])), one, zero));
            sh_tap t;
            vm und;
            vf_store(v1 + i, sh_prep(f, &k, ci, m, p, nn, ndl, &t, &und));
            sh_push(&pk, &t, und, v1 + i);
            vf fr = sh_pick(far, N, ci), band = sh_pick(bandv, N, ci);
            vf tt = vf_div(vf_sub(d, vf_sub(fr, band)), band);
            vm bl = vm_and(m, vf_lt(zero, tt));
            vf_store(tb + i, tt);
            vf_store(fbl + i, vf_select(bl, one, zero));
            if (vm_bits(bl)) {
                vf cn2 = vf_add(ci, one);
                vm nx2 = vf_lt(cn2, vf_set((float)N));
                vf_store(fnx + i, vf_select(nx2, one, zero));
                vf_store(v2 + i, sh_prep(f, &k, vf_select(nx2, cn2, ci), vm_and(bl, nx2), p, nn, ndl, &t, &und));
                sh_push(&pk, &t, und, v2 + i);
            }
        }
        if (!any) continue;
        /* the packed lookups' taps, W at a time (the last step's spare
           lanes repeat its first lookup, stored once) */
        for (unsigned e = 0; e < pk.n; e += W) {
            unsigned ne = pk.n - e < (unsigned)W ? pk.n - e : (unsigned)W;
            for (unsigned l = ne; l < (unsigned)W; l++) {
                pk.x0[e + l] = pk.x0[e], pk.y0[e + l] = pk.y0[e], pk.fx[e + l] = pk.fx[e];
                pk.fy[e + l] = pk.fy[e], pk.dref[e + l] = pk.dref[e], pk.mb[e + l] = pk.mb[e];
            }
            sh_tap t = {vf_loadu(pk.x0 + e), vf_loadu(pk.y0 + e), vf_loadu(pk.fx + e), vf_loadu(pk.fy + e),
                        vf_loadu(pk.dref + e), vf_loadu(pk.mb + e)};
            float r[W];
            vf_store(r, sh_taps(f, maps, &t, vm_ones()));
            for (unsigned l = 0; l < ne; l++) *pk.dst[e + l] = r[l];
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
