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
 * tiles (vt_shadow.c, tiles_make): a lane whose 4x4 footprint lies in the
 * map and whose tile's depth range is wholly at or below its reference
 * passes every tap, wholly above it fails every one; when every lane of
 * a step is so decided, its value is the PCF's for that case computed
 * with the same operations (all pass: the weights' sums in the taps'
 * order; all fail: 0), so the answer is the same bit for bit, for two
 * gathers instead of sixteen.
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

/* cascade_vis (vt_shadow.c) for each lane's cascade ci, lanes m. */
static inline vf sh_vis(const vt_shadow_fit *f, const sh_cons *kc, const float *maps, vf ci, vm m, const vf p[3],
                        const vf n[3], vf ndl)
{
    const vf zero = vf_set(0), one = vf_set(1);
    const float *offx = kc->offx, *offy = kc->offy, *base = kc->base;
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
    const vf sz = vf_set(szf), lo = vf_set(-2.0f), hi = vf_set(szf + 2.0f);
    m = vm_and(m, vm_and(vm_and(vf_lt(lo, mx), vf_lt(mx, hi)), vm_and(vf_lt(lo, my), vf_lt(my, hi))));
    if (!vm_bits(m)) return one;
    vf X = vf_sub(mx, vf_set(0.5f)), Y = vf_sub(my, vf_set(0.5f));
    X = vf_select(m, X, zero), Y = vf_select(m, Y, zero);
    vf fx0 = sh_floor(X), fy0 = sh_floor(Y), fx = vf_sub(X, fx0), fy = vf_sub(Y, fy0);
    vf x0 = vf_sub(fx0, one), y0 = vf_sub(fy0, one);
    const vf wx[4] = {vf_sub(one, fx), one, one, fx}, wy[4] = {vf_sub(one, fy), one, one, fy};
    if (kc->tmin) {
        /* the footprint x0..x0 + 3 lies in tile floor((x0 + 2) / 4)'s
           range (texels 4t - 4 .. 4t + 7): tiles_make's rule */
        const vf lim = vf_set(szf - 4.0f), two = vf_set(2.0f), qu = vf_set(0.25f);
        vm fin = vm_and(vm_and(vf_le(zero, x0), vf_le(x0, lim)), vm_and(vf_le(zero, y0), vf_le(y0, lim)));
        const uint32_t mbits = vm_bits(m);
        if ((vm_bits(vm_and(m, fin)) & mbits) == mbits) {
            vf tix = sh_floor(vf_mul(vf_add(x0, two), qu)), tiy = sh_floor(vf_mul(vf_add(y0, two), qu));
            vf ti = vf_select(m, vf_add(sh_pick(kc->tbase, f->n, ci), vf_add(vf_mul(tiy, vf_set(kc->g)), tix)), zero);
            vm all = vf_le(sh_gather(kc->tmax, ti), dref), none = vf_lt(dref, sh_gather(kc->tmin, ti));
            if ((vm_bits(vm_or(all, none)) & mbits) == mbits) {
                /* the taps' sums when every tap passes, in their order */
                vf r = vf_add(vf_add(vf_add(vf_add(zero, wx[0]), wx[1]), wx[2]), wx[3]), lit = zero;
                for (int b = 0; b < 4; b++) lit = vf_add(lit, vf_mul(wy[b], r));
                return vf_select(m, vf_select(all, vf_mul(lit, vf_set(1.0f / 9.0f)), zero), one);
            }
        }
    }
    const vf mb = sh_pick(base, f->n, ci);
    vf lit = zero, xs[4];
    vm xin[4];
    for (int a = 0; a < 4; a++) { /* the columns, the same for every row */
        xs[a] = vf_add(x0, vf_set((float)a));
        xin[a] = vm_and(vf_le(zero, xs[a]), vf_lt(xs[a], sz));
    }
    for (int b = 0; b < 4; b++) {
        vf y = vf_add(y0, vf_set((float)b));
        vm yin = vm_and(vf_le(zero, y), vf_lt(y, sz)), mrow = vm_and(m, yin);
        vf rowq = vf_add(mb, vf_mul(y, sz));
        vf r = zero;
        for (int a = 0; a < 4; a++) {
            vf t = sh_gather(maps, vf_select(vm_and(mrow, xin[a]), vf_add(rowq, xs[a]), zero));
            vm pass = vm_or(vm_andnot(vm_ones(), xin[a]), vf_le(t, dref));
            r = vf_add(r, vf_select(pass, wx[a], zero));
        }
        lit = vf_add(lit, vf_mul(wy[b], vf_select(yin, r, vf_set(3.0f))));
    }
    return vf_select(m, vf_mul(lit, vf_set(1.0f / 9.0f)), one);
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
    for (unsigned i = 0; i < n; i += W) {
        float tp[6][W], res[W];
        unsigned nw = n - i < (unsigned)W ? n - i : (unsigned)W;
        const float *src[6] = {px, py, pz, nx, ny, nz};
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
        if (!vm_bits(m)) continue; /* lit: out unchanged (times 1) */
        vf ci = zero;
        for (uint32_t c = 1; c < N; c++) ci = vf_add(ci, vf_select(vf_ge(d, vf_set(f->split[c])), one, zero));
        vf vis = sh_vis(f, &k, maps, ci, m, p, nn, ndl);
        vf fr = sh_pick(far, N, ci), band = sh_pick(bandv, N, ci);
        vf t = vf_div(vf_sub(d, vf_sub(fr, band)), band);
        vm bl = vm_and(m, vf_lt(zero, t));
        if (vm_bits(bl)) {
            vf cn = vf_add(ci, one);
            vm nx2 = vf_lt(cn, vf_set((float)N));
            vf v2 = sh_vis(f, &k, maps, vf_select(nx2, cn, ci), vm_and(bl, nx2), p, nn, ndl);
            v2 = vf_select(nx2, v2, one);
            vis = vf_select(bl, vf_add(vis, vf_mul(vf_sub(v2, vis), vf_min(t, one))), vis);
        }
        if (nw == (unsigned)W) {
            vf_store(out + i, vf_mul(vf_loadu(out + i), vf_select(m, vis, one)));
            continue;
        }
        vf_store(res, vf_select(m, vis, one));
        for (unsigned l = 0; l < nw; l++) out[i + l] *= res[l];
    }
}
