/*
 * vt_ssao.inl — the SSAO pass' two lane kernels (vt_ssao.h has the rules,
 * vt_ssao_kern.h the instances): GTAO over a half-resolution row and the
 * depth-aware upsample of a full row, W texels a step. Included after
 * cull_simd.h with VT_SSAO_GTAO_NAME and VT_SSAO_UP_NAME defined.
 *
 * Every lane does the one-lane instance's float operations in its order
 * (plain multiplies and adds, true divisions and square roots, no FMA;
 * the one estimate, ss_rsqrt's, is the same instruction in every
 * instance), so the instances agree bit for bit and the GLSL's mirror of
 * the rules stays the reference. A sample is its texel's nearness fetched
 * by index (AVX2: a gather; SSE4.1: four loads; one lane: the load),
 * lanes off the image or on the sky masked to texel 0, its point made
 * only where the tangent-plane test (ss_tan) leaves it a candidate.
 */
#include <float.h>
#include <math.h>
#include <stdint.h>
#if CULL_SIMD_ISA == 1 && defined(__SSE__)
#include <xmmintrin.h>
#endif

#ifndef VT_SSAO_INL_ONCE
#define VT_SSAO_INL_ONCE
#define SS_PI 3.14159265f
#endif

/* floor(a) for 0 <= a < 2^31, integral floats (the samples' rounding). */
static inline vf ss_floor(vf a)
{
#if CULL_SIMD_ISA == 3
    return _mm256_floor_ps(a);
#elif CULL_SIMD_ISA == 2
    return _mm_floor_ps(a);
#else
    return (float)(int32_t)a;
#endif
}

/* The greatest lane of a (no NaN lanes). */
static inline float ss_hmax(vf a)
{
#if CULL_SIMD_ISA == 3
    __m128 m = _mm_max_ps(_mm256_castps256_ps128(a), _mm256_extractf128_ps(a, 1));
#elif CULL_SIMD_ISA == 2
    __m128 m = a;
#endif
#if CULL_SIMD_ISA >= 2
    m = _mm_max_ps(m, _mm_movehl_ps(m, m));
    m = _mm_max_ss(m, _mm_shuffle_ps(m, m, 1));
    return _mm_cvtss_f32(m);
#else
    return a;
#endif
}

/* The half texels' nearness at q (exact integral floats, >= 0). */
static inline vf ss_fetchn(const vt_ssao_kjob *k, vf q)
{
#if CULL_SIMD_ISA == 3
    return _mm256_i32gather_ps(k->pn, _mm256_cvttps_epi32(q), 4);
#elif CULL_SIMD_ISA == 2
    __m128i i = _mm_cvttps_epi32(q);
    return _mm_setr_ps(k->pn[(uint32_t)_mm_cvtsi128_si32(i)], k->pn[(uint32_t)_mm_extract_epi32(i, 1)],
                       k->pn[(uint32_t)_mm_extract_epi32(i, 2)], k->pn[(uint32_t)_mm_extract_epi32(i, 3)]);
#else
    return k->pn[(uint32_t)q];
#endif
}

/* base[idx[k]] for the W lanes' indices at idx. */
static inline vf ss_gather(const float *base, const int32_t *idx)
{
#if CULL_SIMD_ISA == 3
    return _mm256_i32gather_ps(base, _mm256_loadu_si256((const __m256i *)idx), 4);
#elif CULL_SIMD_ISA == 2
    return _mm_setr_ps(base[idx[0]], base[idx[1]], base[idx[2]], base[idx[3]]);
#else
    return base[idx[0]];
#endif
}

#if CULL_SIMD_ISA >= 2
/* The upsample's tap c of a whole step at an even full column x, from the
 * half row's texels p = x / 2 - 1 ..: lane l (column x + l) reads the
 * texel vt_ssao.c's taps() gives it (even l: l / 2 + c; odd: (l + 1) / 2,
 * (l + 3) / 2, and (l + 1) / 2 again at weight 0): a load and a permute,
 * not a gather. */
static inline vf ss_tap(const float *p, int c)
{
#if CULL_SIMD_ISA == 3
    const __m256i perm = c == 0   ? _mm256_setr_epi32(0, 1, 1, 2, 2, 3, 3, 4)
                         : c == 1 ? _mm256_setr_epi32(1, 2, 2, 3, 3, 4, 4, 5)
                                  : _mm256_setr_epi32(2, 1, 3, 2, 4, 3, 5, 4);
    return _mm256_permutevar8x32_ps(_mm256_loadu_ps(p), perm);
#else
    const __m128 v = _mm_loadu_ps(p);
    return c == 0 ? _mm_shuffle_ps(v, v, _MM_SHUFFLE(2, 1, 1, 0))
           : c == 1 ? _mm_shuffle_ps(v, v, _MM_SHUFFLE(3, 2, 2, 1))
                    : _mm_shuffle_ps(v, v, _MM_SHUFFLE(2, 3, 1, 2));
#endif
}
#endif

/* The point of half texel (X, Y) at nearness N (vt_ssao.h: B / N or
 * B + N bn, B = b0 + X bi + Y bj): garbage where N is not a drawn
 * texel's (the callers' masks). */
static inline void ss_point(const vt_ssao_view *sv, vf X, vf Y, vf N, vf p[3])
{
    const vf r = sv->ortho ? N : vf_div(vf_set(1), N);
    for (int c = 0; c < 3; c++) {
        vf B = vf_add(vf_add(vf_set(sv->b0[c]), vf_mul(X, vf_set(sv->bi[c]))), vf_mul(Y, vf_set(sv->bj[c])));
        p[c] = sv->ortho ? vf_add(B, vf_mul(r, vf_set(sv->bn[c]))) : vf_mul(B, r);
    }
}

/* The half texels (X, Y) (integral floats) that are the consecutive
 * texels q .. q + W - 1 (a step's own row, or one a fixed step away):
 * their nearness (a load: the pads keep it in the buffer); *ok: the
 * lanes of m on the image (bounds: else known to be) and drawn. */
static inline vf ss_near_at(const vt_ssao_kjob *k, vf X, vf Y, vm m, ptrdiff_t q, bool bounds, vm *ok)
{
    const vt_ssao_view *sv = k->sv;
    if (bounds)
        m = vm_and(m, vm_and(vm_and(vf_ge(X, vf_set(0)), vf_lt(X, vf_set((float)sv->hw))),
                             vm_and(vf_ge(Y, vf_set(0)), vf_lt(Y, vf_set((float)sv->hh)))));
    vf N = vf_loadu(k->pn + q);
    *ok = vm_and(m, vf_lt(vf_set(VT_EMPTY), N)); /* not the sky (nearness is never NaN) */
    return N;
}

static inline vf ss_dot(vf ax, vf ay, vf az, vf bx, vf by, vf bz)
{
    return vf_add(vf_add(vf_mul(ax, bx), vf_mul(ay, by)), vf_mul(az, bz));
}

/* vt_ssao_acos, lane-wise. */
static inline vf ss_acos(vf x)
{
    vf a = vf_min(vf_abs(x), vf_set(1));
    vf r = vf_add(vf_mul(vf_sub(vf_mul(vf_add(vf_mul(vf_set(-0.0187293f), a), vf_set(0.0742610f)), a),
                                vf_set(0.2121144f)),
                         a),
                  vf_set(1.5707288f));
    vf b = vf_sub(vf_set(1), a);
    r = vf_mul(r, vf_select(vf_lt(vf_set(0), b), vf_sqrt(vf_max(b, vf_set(0))), vf_set(0)));
    return vf_select(vf_lt(x, vf_set(0)), vf_sub(vf_set(SS_PI), r), r);
}

/* vt_ssao_arc, lane-wise. */
static inline vf ss_arc(vf h, vf ch, vf sh, vf cn, vf sn)
{
    vf c2h = vf_sub(vf_mul(vf_mul(vf_set(2), ch), ch), vf_set(1)), s2h = vf_mul(vf_mul(vf_set(2), sh), ch);
    vf t = vf_sub(vf_set(0), vf_add(vf_mul(c2h, cn), vf_mul(s2h, sn)));
    return vf_mul(vf_set(0.25f), vf_add(vf_add(t, cn), vf_mul(vf_mul(vf_set(2), h), sn)));
}

/* The step along one screen axis (vt_ssao.c's side_step): the side whose
 * two texels extrapolate to P's nearness best; *ok false where neither
 * neighbour exists. */
static inline __attribute__((always_inline)) void ss_side(const vt_ssao_kjob *k, vf X, vf Y, vf ux, vf uy, ptrdiff_t q, ptrdiff_t du, vm m, bool bounds,
                           const vf P[4], vf d[3], vm *ok)
{
    vm mlo, mlo2, mhi, mhi2;
    /* texel q is (X, Y); one step along the axis is du texels */
    const vf lo = ss_near_at(k, vf_sub(X, ux), vf_sub(Y, uy), m, q - du, bounds, &mlo);
    const vf lo2 = ss_near_at(k, vf_sub(X, vf_add(ux, ux)), vf_sub(Y, vf_add(uy, uy)), m, q - 2 * du, bounds, &mlo2);
    const vf hi = ss_near_at(k, vf_add(X, ux), vf_add(Y, uy), m, q + du, bounds, &mhi);
    const vf hi2 = ss_near_at(k, vf_add(X, vf_add(ux, ux)), vf_add(Y, vf_add(uy, uy)), m, q + 2 * du, bounds, &mhi2);
    const vf two = vf_set(2);
    vf el = vf_select(mlo, vf_select(mlo2, vf_abs(vf_sub(vf_sub(vf_mul(two, lo), lo2), P[3])), vf_set(FLT_MAX)),
                      vf_set(INFINITY));
    vf eh = vf_select(mhi, vf_select(mhi2, vf_abs(vf_sub(vf_sub(vf_mul(two, hi), hi2), P[3])), vf_set(FLT_MAX)),
                      vf_set(INFINITY));
    vm usehi = vm_or(vf_lt(eh, el), vm_and(vm_and(vf_le(eh, el), vf_le(el, eh)), mhi));
    /* the chosen neighbour's point only */
    vf Q[3];
    ss_point(k->sv, vf_select(usehi, vf_add(X, ux), vf_sub(X, ux)), vf_select(usehi, vf_add(Y, uy), vf_sub(Y, uy)),
             vf_select(usehi, hi, lo), Q);
    for (int c = 0; c < 3; c++) d[c] = vf_select(usehi, vf_sub(Q[c], P[c]), vf_sub(P[c], Q[c]));
    *ok = vm_or(mlo, mhi);
}

/* One side's horizon in a slice: the highest faded cosine so far (from
 * lo, the tangent plane's), and the lanes where a sample raised it. */
typedef struct ss_hor {
    vf h, lo;
    vm up;
} ss_hor;

/* 1 / sqrt(a) for a > 0: the estimate and one Newton step (about 2e-7
 * relative: the horizon cosines' float noise). Every instance uses the
 * same estimate instruction (rsqrtps / rsqrtss give the same bits on one
 * CPU), so the instances agree bit for bit; without SSE, the division. */
static inline vf ss_rsqrt(vf a)
{
#if CULL_SIMD_ISA == 3
    vf y = _mm256_rsqrt_ps(a);
#elif CULL_SIMD_ISA == 2
    vf y = _mm_rsqrt_ps(a);
#elif defined(__SSE__)
    vf y = _mm_cvtss_f32(_mm_rsqrt_ss(_mm_set_ss(a)));
#else
    vf y = 1 / sqrtf(a);
#endif
    return vf_mul(y, vf_sub(vf_set(1.5f), vf_mul(vf_mul(vf_set(0.5f), a), vf_mul(y, y))));
}

/* The tangent plane's nearness at the texel ox, oy from P: c0 + ox ax +
 * oy ay (nearness is affine in the texels over a plane: perspective
 * 1 / w, orthographic depth). A sample the full test takes is above the
 * plane by the bias, at least BIAS |d| along n, which is a nearness
 * above the plane's by more than VT_SSAO_BIAS / 4 of the least angle
 * between two texels' rays (vt_ssao_view's kappa) times the texels
 * between them (at least tt - 0.71 for a step tt texels out: the angle,
 * or the distance, grows with it): so a sample whose nearness N has
 * N al - be <= the plane's (al = 1 - k, be = 0; orthographic al = 1,
 * be = k; k = kappa max(1, tt - 0.71)) is not one, and costs a load and
 * 6 operations instead of its point. Lanes whose plane is seen nearly
 * edge on (n.V < 0.05: the prediction's rounding grows as 1 / n.V) have
 * NaN coefficients: nothing is rejected there. */
typedef struct ss_tan {
    vf c0, ax, ay, al[VT_SSAO_STEPS], be[VT_SSAO_STEPS];
} ss_tan;

/* The sample ox, oy texels from the step's texels (X, Y) (qcf: its index)
 * in lanes m: raises hs where it is an occluder (vt_ssao.h: within the
 * radius, above the tangent plane by the bias, faded over the radius'
 * last quarter). inner: every sample is on the image. */
static inline __attribute__((always_inline)) void ss_sample(const vt_ssao_kjob *k, vf X, vf Y, vf qcf, vf ox, vf oy, vm m,
                                                            bool inner, const ss_tan *tp, int st, const vf P[4], const vf n[3],
                                                            const vf V[3], ss_hor *hs)
{
    const vt_ssao_view *sv = k->sv;
    const vf zero = vf_set(0), one = vf_set(1), R = vf_set(VT_SSAO_RADIUS);
    vf q = vf_add(qcf, vf_add(vf_mul(oy, vf_set((float)sv->hw)), ox));
    if (!inner) {
        /* the lanes whose sample is off the image read texel 0 */
        const vf SX = vf_add(X, ox), SY = vf_add(Y, oy);
        m = vm_and(m, vm_and(vm_and(vf_ge(SX, zero), vf_lt(SX, vf_set((float)sv->hw))),
                             vm_and(vf_ge(SY, zero), vf_lt(SY, vf_set((float)sv->hh)))));
        q = vf_select(m, q, zero);
    }
    /* not surely below the tangent plane (ss_tan): most samples, a
       plane's, end here (so does the sky's nearness, the least float,
       but where the plane's is NaN) */
    vf S[3], N = ss_fetchn(k, q);
    m = vm_andnot(m, vf_le(vf_sub(vf_mul(N, tp->al[st]), tp->be[st]),
                           vf_add(vf_add(tp->c0, vf_mul(ox, tp->ax)), vf_mul(oy, tp->ay))));
    if (!vm_bits(m)) return;
    m = vm_and(m, vf_lt(vf_set(VT_EMPTY), N)); /* not the sky (nearness is never NaN) */
    ss_point(sv, vf_add(X, ox), vf_add(Y, oy), N, S);
    vf d[3] = {vf_sub(S[0], P[0]), vf_sub(S[1], P[1]), vf_sub(S[2], P[2])};
    vf l2 = ss_dot(d[0], d[1], d[2], d[0], d[1], d[2]), hn = ss_dot(d[0], d[1], d[2], n[0], n[1], n[2]);
    m = vm_and(m, vm_and(vm_and(vf_lt(zero, l2), vf_lt(l2, vf_mul(R, R))), vf_lt(zero, hn)));
    m = vm_and(m, vf_ge(vf_mul(hn, hn), vf_mul(vf_set(VT_SSAO_BIAS * VT_SSAO_BIAS), l2)));
    if (!vm_bits(m)) return;
    vf il = ss_rsqrt(vf_select(m, l2, one)), dist = vf_mul(l2, il);
    vf wf = vf_mul(vf_sub(R, dist), vf_set(1 / (VT_SSAO_FADE * VT_SSAO_RADIUS)));
    vf cv = vf_mul(ss_dot(d[0], d[1], d[2], V[0], V[1], V[2]), il);
    cv = vf_add(hs->lo, vf_mul(vf_sub(cv, hs->lo), vf_select(vf_lt(wf, one), wf, one)));
    vm raise = vm_and(m, vf_lt(hs->h, cv));
    hs->h = vf_select(raise, cv, hs->h);
    hs->up = vm_or(hs->up, raise);
}

void VT_SSAO_GTAO_NAME(const vt_ssao_kjob *k, uint32_t j)
{
    const vt_ssao_view *sv = k->sv;
    const float R = VT_SSAO_RADIUS;
    /* the 2x2 pattern's turns: lane l of a step starting at column i0 has
       column parity (i0 + l) & 1 (W > 1: i0 is even) */
    float dc[2][VT_SSAO_SLICES][W], ds[2][VT_SSAO_SLICES][W], dt2[2][VT_SSAO_SLICES][W], lane[W];
    /* |c ex + s ey|^2 of each direction (the slice's screen direction in the world) */
    const float exx = sv->ex[0] * sv->ex[0] + sv->ex[1] * sv->ex[1] + sv->ex[2] * sv->ex[2];
    const float exy = sv->ex[0] * sv->ey[0] + sv->ex[1] * sv->ey[1] + sv->ex[2] * sv->ey[2];
    const float eyy = sv->ey[0] * sv->ey[0] + sv->ey[1] * sv->ey[1] + sv->ey[2] * sv->ey[2];
    for (int ph = 0; ph < 2; ph++)
        for (int l = 0; l < W; l++) {
            const float(*dir)[2] = k->dir + (((ph + l) & 1) + 2 * (j & 1)) * VT_SSAO_SLICES;
            for (int sl = 0; sl < VT_SSAO_SLICES; sl++) {
                const float c = dir[sl][0], s = dir[sl][1];
                dc[ph][sl][l] = c, ds[ph][sl][l] = s;
                dt2[ph][sl][l] = c * c * exx + 2 * c * s * exy + s * s * eyy;
            }
            lane[l] = (float)l;
        }
    const vf Y = vf_set((float)j), zero = vf_set(0), one = vf_set(1);
    for (uint32_t i0 = 0; i0 < sv->hw; i0 += W) {
        vf X = vf_add(vf_set((float)i0), vf_loadu(lane));
        vf P[4];
        vm ok;
        const ptrdiff_t qc = (ptrdiff_t)j * sv->hw + i0;
        P[3] = ss_near_at(k, X, Y, vm_ones(), qc, true, &ok);
        float res[W];
        if (!vm_bits(ok)) {
            vf_store(res, one);
            goto out;
        }
        {
            vf rpx = vf_div(vf_mul(vf_set(R), sv->ortho ? one : P[3]), vf_set(sv->texel1));
            ok = vm_and(ok, vf_ge(rpx, one));
            if (!vm_bits(ok)) { /* all beyond the distance where the radius is a texel */
                vf_store(res, one);
                goto out;
            }
            /* a sample is at most rpx (< B - 1) texels away on either axis
               (|cos|, |sin| <= 1, the steps' distances below rpx), the
               normal's neighbours 2: no crease texel in the box B around
               the step's texels (cs: 4 reads) means one plane there, no
               sample above it by the bias (vt_ssao.c): AO 1 */
            const uint32_t B = (uint32_t)ss_hmax(vf_select(ok, vf_min(rpx, vf_set(VT_SSAO_MAX_PX)), zero)) + 2;
            {
                /* the box [a0, a1) x [b0, b1) widened to whole blocks */
                const size_t cw = VT_SSAO_CBLKS(sv->hw);
                const uint32_t a0 = (i0 >= B ? i0 - B : 0) / VT_SSAO_CBLK;
                const uint32_t a1 = ((i0 + W + B < sv->hw ? i0 + W + B : sv->hw) + VT_SSAO_CBLK - 1) / VT_SSAO_CBLK;
                const uint32_t b0 = j >= B ? j - B : 0, b1 = j + 1 + B < sv->hh ? j + 1 + B : sv->hh;
                const int32_t *c0 = k->cs + b0 * cw, *c1 = k->cs + b1 * cw;
                if (c1[a1] - c1[a0] - c0[a1] + c0[a0] == 0 && !k->no_skip) {
                    vf_store(res, one);
                    goto out;
                }
            }
            rpx = vf_select(vf_lt(rpx, vf_set(VT_SSAO_MAX_PX)), rpx, vf_set(VT_SSAO_MAX_PX));
            vf nst = vf_select(vf_lt(rpx, vf_set((float)VT_SSAO_STEPS)), ss_floor(vf_select(ok, rpx, one)),
                               vf_set((float)VT_SSAO_STEPS));
            vf inv_nst = vf_div(one, nst);
            ss_point(sv, X, Y, P[3], P);
            vf dx[3], dy[3], n[3], V[3];
            vm okx, oky;
            /* the neighbours two texels out are on the image */
            const bool bounds = !(i0 >= 2 && i0 + W + 2 <= sv->hw && j >= 2 && j + 2 < sv->hh);
            ss_side(k, X, Y, one, zero, qc, 1, ok, bounds, P, dx, &okx);
            ss_side(k, X, Y, zero, one, qc, (ptrdiff_t)sv->hw, ok, bounds, P, dy, &oky);
            ok = vm_and(ok, vm_and(okx, oky));
            n[0] = vf_sub(vf_mul(dx[1], dy[2]), vf_mul(dx[2], dy[1]));
            n[1] = vf_sub(vf_mul(dx[2], dy[0]), vf_mul(dx[0], dy[2]));
            n[2] = vf_sub(vf_mul(dx[0], dy[1]), vf_mul(dx[1], dy[0]));
            for (int c = 0; c < 3; c++) V[c] = sv->ortho ? vf_set(sv->vdir[c]) : vf_sub(zero, P[c]);
            vf nl = vf_sqrt(ss_dot(n[0], n[1], n[2], n[0], n[1], n[2]));
            vf vl = vf_sqrt(ss_dot(V[0], V[1], V[2], V[0], V[1], V[2]));
            const vf inf = vf_set(INFINITY);
            ok = vm_and(ok, vm_and(vm_and(vf_lt(zero, nl), vf_lt(nl, inf)), vm_and(vf_lt(zero, vl), vf_lt(vl, inf))));
            if (!vm_bits(ok)) {
                vf_store(res, one);
                goto out;
            }
            vf inl = vf_div(one, nl);
            vf ns = vf_select(vf_lt(ss_dot(n[0], n[1], n[2], V[0], V[1], V[2]), zero), vf_sub(zero, inl), inl);
            const vf ivl = vf_div(one, vl);
            for (int c = 0; c < 3; c++) {
                n[c] = vf_mul(n[c], ns);
                V[c] = vf_mul(V[c], ivl);
            }
            /* the slices' terms: T = c ex + s ey less its part along V, the
               normal's angle in the slice from a = n.V and b = n.T / |T|
               (n.T = c n.ex + s n.ey - (T.V) a, |T|^2 = dt2 - (T.V)^2) */
            const vf a = ss_dot(n[0], n[1], n[2], V[0], V[1], V[2]);
            const vf exV = ss_dot(vf_set(sv->ex[0]), vf_set(sv->ex[1]), vf_set(sv->ex[2]), V[0], V[1], V[2]);
            const vf eyV = ss_dot(vf_set(sv->ey[0]), vf_set(sv->ey[1]), vf_set(sv->ey[2]), V[0], V[1], V[2]);
            const vf nex = ss_dot(vf_set(sv->ex[0]), vf_set(sv->ex[1]), vf_set(sv->ex[2]), n[0], n[1], n[2]);
            const vf ney = ss_dot(vf_set(sv->ey[0]), vf_set(sv->ey[1]), vf_set(sv->ey[2]), n[0], n[1], n[2]);
            vf num = zero, den = zero;
            /* the steps' distances and lanes, the same for every slice and
               side; the steps past every lane's count are not looked at */
            vf tts[VT_SSAO_STEPS];
            vm mst[VT_SSAO_STEPS];
            int nmax = 0;
            for (int st = 0; st < VT_SSAO_STEPS; st++) {
                mst[st] = vm_and(ok, vf_lt(vf_set((float)st), nst));
                /* 0 in the lanes that take no sample at this step: their
                   index is their own texel (ss_sample reads it unmasked
                   inside the image) */
                tts[st] = vf_select(mst[st], vf_mul(vf_mul(rpx, vf_set((float)st + 0.5f)), inv_nst), zero);
                nmax = vm_bits(mst[st]) ? st + 1 : nmax;
            }
            /* a sample is at most rpx (< B) texels away on either axis
               (|cos|, |sin| <= 1, the steps' distances below rpx): a step
               at least B from every side needs no bounds on its samples */
            const bool inner = i0 >= B && i0 + W - 1 + B < sv->hw && j >= B && j + B < sv->hh;
            const vf qcf = vf_add(vf_mul(Y, vf_set((float)sv->hw)), X);
            ss_tan tp;
            {
                /* perspective: the plane's nearness at texel s is n.B(s) / n.(B / N)
                   (P = B / N); orthographic: N + (n.(B(s) - B)) / -n.bn */
                vf nbi = ss_dot(n[0], n[1], n[2], vf_set(sv->bi[0]), vf_set(sv->bi[1]), vf_set(sv->bi[2]));
                vf nbj = ss_dot(n[0], n[1], n[2], vf_set(sv->bj[0]), vf_set(sv->bj[1]), vf_set(sv->bj[2]));
                vf tden;
                if (sv->ortho) {
                    tden = vf_sub(zero, ss_dot(n[0], n[1], n[2], vf_set(sv->bn[0]), vf_set(sv->bn[1]), vf_set(sv->bn[2])));
                } else {
                    vf Bp[3];
                    for (int c = 0; c < 3; c++)
                        Bp[c] = vf_add(vf_add(vf_set(sv->b0[c]), vf_mul(X, vf_set(sv->bi[c]))), vf_mul(Y, vf_set(sv->bj[c])));
                    tden = vf_div(ss_dot(n[0], n[1], n[2], Bp[0], Bp[1], Bp[2]), P[3]);
                }
                vm edge = vf_lt(ss_dot(n[0], n[1], n[2], V[0], V[1], V[2]), vf_set(0.05f));
                tp.c0 = vf_select(edge, vf_set(NAN), P[3]);
                tp.ax = vf_div(nbi, tden), tp.ay = vf_div(nbj, tden);
                for (int st = 0; st < VT_SSAO_STEPS; st++) {
                    vf kt = vf_mul(vf_set(sv->kappa), vf_max(vf_sub(tts[st], vf_set(0.71f)), one));
                    tp.al[st] = sv->ortho ? one : vf_sub(one, kt);
                    tp.be[st] = sv->ortho ? kt : zero;
                }
            }
            for (int sl = 0; sl < VT_SSAO_SLICES; sl++) {
                const vf c = vf_loadu(dc[i0 & 1][sl]), s = vf_loadu(ds[i0 & 1][sl]);
                const vf tv = vf_add(vf_mul(c, exV), vf_mul(s, eyV));
                vf tl = vf_sqrt(vf_max(vf_sub(vf_loadu(dt2[i0 & 1][sl]), vf_mul(tv, tv)), zero));
                vf b = vf_div(vf_sub(vf_add(vf_mul(c, nex), vf_mul(s, ney)), vf_mul(tv, a)), tl);
                vf pl = vf_sqrt(vf_add(vf_mul(a, a), vf_mul(b, b)));
                vm sok = vm_and(ok, vm_and(vf_lt(zero, tl), vf_lt(zero, pl)));
                if (!vm_bits(sok)) continue;
                vf cn = vf_div(a, pl), sn = vf_div(b, pl), na = ss_acos(cn);
                na = vf_select(vf_lt(sn, zero), vf_sub(zero, na), na);
                ss_hor hs[2] = {{sn, sn, vm_andnot(sok, sok)}, {vf_sub(zero, sn), vf_sub(zero, sn), vm_andnot(sok, sok)}};
                for (int st = 0; st < nmax; st++) {
                    const vm m = vm_and(sok, mst[st]);
                    const vf ct = vf_mul(c, tts[st]), stt = vf_mul(s, tts[st]);
                    /* the two sides' texels: floor(+-(c, s) tt + 0.5), the
                       1024 keeping the one-lane floor (a truncation) on
                       positive values */
                    const vf h = vf_set(1024.5f), kk = vf_set(1024);
                    ss_sample(k, X, Y, qcf, vf_sub(ss_floor(vf_sub(h, ct)), kk), vf_sub(ss_floor(vf_sub(h, stt)), kk), m,
                              inner, &tp, st, P, n, V, &hs[0]);
                    ss_sample(k, X, Y, qcf, vf_sub(ss_floor(vf_add(ct, h)), kk), vf_sub(ss_floor(vf_add(stt, h)), kk), m,
                              inner, &tp, st, P, n, V, &hs[1]);
                }
                vf hc[2] = {hs[0].h, hs[1].h};
                vm up[2] = {hs[0].up, hs[1].up};
                const vf hp = vf_set(SS_PI / 2);
                vf e0 = ss_arc(vf_sub(na, hp), sn, vf_sub(zero, cn), cn, sn);
                vf e1 = ss_arc(vf_add(na, hp), vf_sub(zero, sn), cn, cn, sn);
                vf de = vf_mul(pl, vf_add(e0, e1)), nu = de;
                /* a side whose horizon was not raised has the same arc as
                   the open hemisphere's (the same arguments): with no lane
                   raised, num adds exactly den's term (most of a city) */
                if (vm_bits(vm_or(up[0], up[1]))) {
                    vf h0 = vf_select(up[0], vf_sub(zero, ss_acos(hc[0])), vf_sub(na, hp));
                    vf s0 = vf_select(up[0], vf_sub(zero, vf_sqrt(vf_max(vf_sub(one, vf_mul(hc[0], hc[0])), zero))),
                                      vf_sub(zero, cn));
                    vf h1 = vf_select(up[1], ss_acos(hc[1]), vf_add(na, hp));
                    vf s1 = vf_select(up[1], vf_sqrt(vf_max(vf_sub(one, vf_mul(hc[1], hc[1])), zero)), cn);
                    nu = vf_mul(pl, vf_add(ss_arc(h0, hc[0], s0, cn, sn), ss_arc(h1, hc[1], s1, cn, sn)));
                }
                num = vf_select(sok, vf_add(num, nu), num);
                den = vf_select(sok, vf_add(den, de), den);
            }
            vm dp = vf_lt(zero, den);
            vf ao = vf_div(num, vf_select(dp, den, one));
            /* clamped to 0..1, NaN to 1 */
            ao = vf_select(vf_ge(ao, zero), vf_select(vf_le(ao, one), ao, one), vf_select(vf_lt(ao, zero), zero, one));
            vf_store(res, vf_select(vm_and(ok, dp), ao, one));
        }
    out:;
        uint32_t nw = sv->hw - i0 < (uint32_t)W ? sv->hw - i0 : (uint32_t)W;
        size_t q0 = (size_t)j * sv->hw + i0;
        if (nw == (uint32_t)W) vf_store(k->hao + q0, vf_loadu(res)); /* the row's own texels */
        else
            for (uint32_t l = 0; l < nw; l++) k->hao[q0 + l] = res[l];
    }
}

/* The crease texels of half row j (the skip of vt_ssao.c's header): a
 * drawn texel with a neighbour (4-connected, on the image) that is not,
 * or the reverse, or a drawn one whose second difference along a row or
 * a column, or whose 2x2 cell's mixed one, exceeds crease_tol (times its
 * nearness, perspective) where those texels are drawn. Writes the
 * running count over the row's blocks of 8 texels (VT_SSAO_CBLK, every
 * instance's) into cs's row j + 1 (vt_ssao.c adds the rows up). */
void VT_SSAO_CREASE_NAME(const vt_ssao_kjob *k, uint32_t j)
{
    const vt_ssao_view *sv = k->sv;
    const ptrdiff_t hw = sv->hw;
    const float *p = k->pn + (size_t)j * sv->hw; /* the pads make rows -1 and hh readable */
    const vf E = vf_set(VT_EMPTY), tol = vf_set(k->crease_tol);
    const vm none = vm_andnot(vm_ones(), vm_ones()), hu = j + 1 < sv->hh ? vm_ones() : none,
             hd = j > 0 ? vm_ones() : none;
    float lane[W];
    for (int l = 0; l < W; l++) lane[l] = (float)l;
    int32_t *o = k->cs + (size_t)(j + 1) * VT_SSAO_CBLKS(sv->hw), run = 0;
    o[0] = 0;
    for (uint32_t i0 = 0; i0 < sv->hw; i0 += W) {
        const vf X = vf_add(vf_set((float)i0), vf_loadu(lane));
        const vm hl = vf_ge(X, vf_set(1)), hr = vf_lt(X, vf_set((float)sv->hw - 1));
        const float *q = p + i0;
        const vf t = vf_loadu(q), l = vf_loadu(q - 1), r = vf_loadu(q + 1), u = vf_loadu(q + hw), d = vf_loadu(q - hw),
                 ur = vf_loadu(q + hw + 1);
        const vm mt = vm_and(vf_lt(X, vf_set((float)sv->hw)), vf_lt(E, t)), ml = vm_and(hl, vf_lt(E, l)),
                 mr = vm_and(hr, vf_lt(E, r)), mu = vm_and(hu, vf_lt(E, u)), md = vm_and(hd, vf_lt(E, d)),
                 mur = vm_and(vm_and(hr, hu), vf_lt(E, ur));
        /* drawn next to not drawn (either way; off the image is neither) */
        vm cr = vm_or(vm_or(vm_and(hl, vm_andnot(vm_or(mt, ml), vm_and(mt, ml))),
                            vm_and(hr, vm_andnot(vm_or(mt, mr), vm_and(mt, mr)))),
                      vm_or(vm_and(hu, vm_andnot(vm_or(mt, mu), vm_and(mt, mu))),
                            vm_and(hd, vm_andnot(vm_or(mt, md), vm_and(mt, md)))));
        const vf tt = sv->ortho ? tol : vf_mul(tol, t), t2 = vf_add(t, t);
        cr = vm_or(cr, vm_and(vm_and(mt, vm_and(ml, mr)), vf_lt(tt, vf_abs(vf_add(vf_sub(l, t2), r)))));
        cr = vm_or(cr, vm_and(vm_and(mt, vm_and(md, mu)), vf_lt(tt, vf_abs(vf_add(vf_sub(d, t2), u)))));
        cr = vm_or(cr, vm_and(vm_and(vm_and(mt, mr), vm_and(mu, mur)),
                              vf_lt(tt, vf_abs(vf_add(vf_sub(vf_sub(ur, r), u), t)))));
        cr = vm_and(cr, vf_lt(X, vf_set((float)sv->hw)));
        run += __builtin_popcount(vm_bits(cr));
        /* a block's count once its last lane is in (W divides the block) */
        if ((i0 + W) % VT_SSAO_CBLK == 0 || i0 + W >= sv->hw) o[(i0 + W - 1) / VT_SSAO_CBLK + 1] = run;
    }
}

/* p[0], p[2], .. p[2 W - 2]: the even full columns of a step. */
static inline vf ss_even(const float *p)
{
#if CULL_SIMD_ISA == 3
    __m256 a = _mm256_loadu_ps(p), b = _mm256_loadu_ps(p + 8);
    __m256 e = _mm256_shuffle_ps(a, b, _MM_SHUFFLE(2, 0, 2, 0)); /* a0 a2 b0 b2 | a4 a6 b4 b6 */
    return _mm256_castpd_ps(_mm256_permute4x64_pd(_mm256_castps_pd(e), _MM_SHUFFLE(3, 1, 2, 0)));
#elif CULL_SIMD_ISA == 2
    return _mm_shuffle_ps(_mm_loadu_ps(p), _mm_loadu_ps(p + 4), _MM_SHUFFLE(2, 0, 2, 0));
#else
    return p[0];
#endif
}

void VT_SSAO_POS_NAME(const vt_ssao_kjob *k, uint32_t j)
{
    const vt_ssao_view *sv = k->sv;
    const float *nrow = k->near + (size_t)(2 * j) * sv->w;
    float *const o = k->pn + (size_t)j * sv->hw;
    const vf Y = vf_set((float)j), inf = vf_set(INFINITY);
    float lane[W];
    for (int l = 0; l < W; l++) lane[l] = (float)l;
    for (uint32_t i0 = 0; i0 < sv->hw; i0 += W) {
        uint32_t nw = sv->hw - i0 < (uint32_t)W ? sv->hw - i0 : (uint32_t)W;
        /* a whole step's 2 W full columns are in the row (w >= 2 hw - 1) */
        const bool whole = nw == (uint32_t)W && 2 * (i0 + W) <= sv->w;
        float nb[W];
        vf N;
        if (whole) {
            N = ss_even(nrow + 2 * (size_t)i0);
        } else {
            for (uint32_t l = 0; l < (uint32_t)W; l++) nb[l] = l < nw ? nrow[2 * (i0 + l)] : VT_EMPTY;
            N = vf_loadu(nb);
        }
        /* a texel is drawn where its point is finite (ss_point) */
        vf p[3];
        ss_point(sv, vf_add(vf_set((float)i0), vf_loadu(lane)), Y, N, p);
        vm ok = vm_and(vf_lt(vf_set(VT_EMPTY), N), vf_lt(N, inf));
        for (int c = 0; c < 3; c++) ok = vm_and(ok, vf_lt(vf_abs(p[c]), inf));
        const vf nn = vf_select(ok, N, vf_set(VT_EMPTY));
        if (nw == (uint32_t)W) { /* the row's own texels: no other thread's */
            vf_store(o + i0, nn);
            continue;
        }
        vf_store(nb, nn);
        for (uint32_t l = 0; l < nw; l++) o[i0 + l] = nb[l];
    }
}

/* The upsample's taps of the step at full column x from three half rows
 * (h: ha's AO or hn's nearness): tap c of row a at t[a][c]. cont: a
 * whole step whose taps ss_tap reads (W > 1), else the columns' tables. */
static inline __attribute__((always_inline)) void ss_up_taps(const vt_ssao_kjob *k, const float *const h[3], uint32_t x,
                                                             bool cont, vf t[3][3])
{
    const size_t pl = (size_t)k->sv->w + 8;
    (void)cont, (void)pl;
    for (int a = 0; a < 3; a++)
        for (int c = 0; c < 3; c++) {
#if W > 1
            t[a][c] = cont ? ss_tap(h[a] + x / 2 - 1, c) : ss_gather(h[a], k->cx + c * pl + x);
#else
            t[a][c] = ss_gather(h[a], k->cx + c * pl + x);
#endif
        }
}

/* The lanes of a full row's step (nearness N) that need the mean: drawn,
 * a usable tolerance (*tol), and some tap below 1 among the half rows
 * a0 .. a0 + na - 1 of av (most of a frame is unoccluded: the mean of
 * ones is 1). */
static inline __attribute__((always_inline)) vm ss_up_need(const vt_ssao_view *sv, vf N, const vf av[3][3], int a0, int na,
                                                           vf *tol)
{
    const vf zero = vf_set(0), one = vf_set(1);
    *tol = sv->ortho ? vf_set(sv->ntol) : vf_mul(vf_set(VT_SSAO_DEPTH_TOL), N);
    vm ok = vm_and(vm_and(vf_lt(vf_set(VT_EMPTY), N), vf_lt(zero, *tol)), vf_lt(*tol, vf_set(FLT_MAX)));
    vf lo = one;
    for (int a = a0; a < a0 + na; a++)
        for (int c = 0; c < 3; c++) lo = vf_select(vf_lt(av[a][c], lo), av[a][c], lo);
    return vm_and(ok, vf_lt(lo, one));
}

/* The tent's depth-weighted mean over the half rows a0 .. a0 + na - 1
 * (weights wy[a]) where ok, 1 elsewhere. */
static inline __attribute__((always_inline)) vf ss_up_mean(const vt_ssao_kjob *k, vf N, vf tol, vm ok, const vf av[3][3],
                                                           const vf hv[3][3], const float wy[3], int a0, int na, uint32_t x)
{
    const size_t pl = (size_t)k->sv->w + 8;
    const vf zero = vf_set(0), one = vf_set(1);
    vf kk = vf_div(one, tol), sum = zero, acc = zero;
    for (int a = a0; a < a0 + na; a++)
        for (int c = 0; c < 3; c++) {
            /* max: a NaN or negative depth weight is 0 */
            vf wd = vf_max(vf_sub(one, vf_mul(vf_abs(vf_sub(hv[a][c], N)), kk)), zero);
            vf wt = vf_mul(vf_mul(vf_set(wy[a]), vf_loadu(k->cw + c * pl + x)), wd);
            sum = vf_add(sum, wt);
            acc = vf_add(acc, vf_mul(wt, av[a][c]));
        }
    vm sp = vf_lt(zero, sum);
    vf ao = vf_div(acc, vf_select(sp, sum, one));
    ao = vf_select(vf_ge(ao, zero), vf_select(vf_le(ao, one), ao, one), vf_select(vf_lt(ao, zero), zero, one));
    return vf_select(vm_and(ok, sp), ao, one);
}

/* The step at full column x of the row pair: row 2m (nearness N0) from
 * the half rows 0, 1, 2 of ha / hn (m - 1, m, m + 1, clamped, weights
 * w0; na0 of them weigh), row 2m + 1 (N1, when two) from rows 1, 2
 * (weights w1; na1). The taps are read once for both rows. */
static inline __attribute__((always_inline)) void ss_up_pair(const vt_ssao_kjob *k, const float *const ha[3],
                                                             const float *const hn[3], const float w0[3], const float w1[3],
                                                             uint32_t x, bool cont, int na0, int na1, bool two, vf N0, vf N1,
                                                             vf r[2])
{
    vf av[3][3], hv[3][3], tol0, tol1 = N1;
    ss_up_taps(k, ha, x, cont, av);
    vm ok0 = ss_up_need(k->sv, N0, av, 0, na0, &tol0), ok1 = two ? ss_up_need(k->sv, N1, av, 1, na1, &tol1) : ok0;
    r[0] = r[1] = vf_set(1);
    if (!vm_bits(vm_or(ok0, ok1))) return;
    ss_up_taps(k, hn, x, cont, hv);
    if (vm_bits(ok0)) r[0] = ss_up_mean(k, N0, tol0, ok0, av, hv, w0, 0, na0, x);
    if (two && vm_bits(ok1)) r[1] = ss_up_mean(k, N1, tol1, ok1, av, hv, w1, 1, na1, x);
}

/* Full rows 2 m and 2 m + 1 (where there is one; vt_ssao.c's taps(),
 * rows: 2 m from the half rows m - 1, m, m + 1 at 1/4, 1/2, 1/4, 2 m + 1
 * from m, m + 1 at 1/2 each, weight 0 off the image). */
void VT_SSAO_UP_NAME(const vt_ssao_kjob *k, uint32_t m)
{
    const vt_ssao_view *sv = k->sv;
    const uint32_t y = 2 * m;
    const bool two = y + 1 < sv->h, below = m + 1 < sv->hh;
    const uint32_t jy[3] = {m >= 1 ? m - 1 : m, m, below ? m + 1 : m};
    const float w0[3] = {m >= 1 ? 0.25f : 0, 0.5f, below ? 0.25f : 0}, w1[3] = {0, 0.5f, below ? 0.5f : 0};
    /* the half rows that weigh: row 2 m's third and row 2 m + 1's second
       (half row m + 1) not below the image */
    const int na = below ? 3 : 2;
    const float *nrow = k->near + (size_t)y * sv->w;
    float *o = k->ao + (size_t)y * sv->w;
    const float *hn[3], *ha[3];
    for (int a = 0; a < 3; a++) {
        hn[a] = k->pn + (size_t)jy[a] * sv->hw;
        ha[a] = k->hao + (size_t)jy[a] * sv->hw;
    }
#if W > 1
    const vf one = vf_set(1);
#endif
    for (uint32_t x = 0; x < sv->w; x += W) {
        float nb[2][W], res[2][W];
        uint32_t nw = sv->w - x < (uint32_t)W ? sv->w - x : (uint32_t)W;
        bool cont = false; /* a whole step whose taps ss_tap reads */
#if W > 1
        /* most of a frame is unoccluded: where the three half rows are 1
           over the step's taps (half columns x/2 - 1 .. x/2 + W/2 within
           the W at x/2 - 1), every lane's mean is 1 in both rows (the
           general path's answer too), without the taps */
        if (x >= 2 && nw == (uint32_t)W && x / 2 - 1 + W <= sv->hw) {
            cont = true;
            vm all1 = vm_and(vm_and(vf_le(one, vf_loadu(ha[0] + x / 2 - 1)), vf_le(one, vf_loadu(ha[1] + x / 2 - 1))),
                             vf_le(one, vf_loadu(ha[2] + x / 2 - 1)));
            if (vm_bits(all1) == (1u << W) - 1) {
                vf_store(o + x, one);
                if (two) vf_store(o + sv->w + x, one);
                continue;
            }
        }
#endif
        vf N[2];
        for (int r = 0; r < 2; r++) {
            const float *row = nrow + (size_t)r * sv->w;
            if (r && !two) N[r] = vf_set(VT_EMPTY);
            else if (nw == (uint32_t)W) N[r] = vf_loadu(row + x);
            else {
                for (uint32_t l = 0; l < (uint32_t)W; l++) nb[r][l] = l < nw ? row[x + l] : VT_EMPTY;
                N[r] = vf_loadu(nb[r]);
            }
        }
        vf rv[2];
        /* (the calls with constant cont and row counts unroll their taps) */
        if (cont) {
            if (na == 3) ss_up_pair(k, ha, hn, w0, w1, x, true, 3, 2, two, N[0], N[1], rv);
            else ss_up_pair(k, ha, hn, w0, w1, x, true, 2, 1, two, N[0], N[1], rv);
        } else {
            if (na == 3) ss_up_pair(k, ha, hn, w0, w1, x, false, 3, 2, two, N[0], N[1], rv);
            else ss_up_pair(k, ha, hn, w0, w1, x, false, 2, 1, two, N[0], N[1], rv);
        }
        for (int r = 0; r < 1 + two; r++) {
            float *orow = o + (size_t)r * sv->w;
            if (nw == (uint32_t)W) vf_store(orow + x, rv[r]);
            else {
                vf_store(res[r], rv[r]);
                for (uint32_t l = 0; l < nw; l++) orow[x + l] = res[r][l];
            }
        }
    }
}
