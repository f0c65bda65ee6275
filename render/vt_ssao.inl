/*
 * vt_ssao.inl — the SSAO pass' two lane kernels (vt_ssao.h has the rules,
 * vt_ssao_kern.h the instances): GTAO over a half-resolution row and the
 * depth-aware upsample of a full row, W texels a step. Included after
 * cull_simd.h with VT_SSAO_GTAO_NAME and VT_SSAO_UP_NAME defined.
 *
 * Every lane does the one-lane instance's float operations in its order
 * (plain multiplies and adds, true divisions and square roots: no rcp,
 * no FMA), so the instances agree bit for bit and the GLSL's mirror of
 * the rules stays the reference. A texel's samples are fetched by index
 * (AVX2: gathers; SSE4.1: four 16-byte loads turned over; one lane: the
 * load), lanes off the image or on the sky masked to texel 0.
 */
#include <float.h>
#include <stdint.h>

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

/* The planes' texels q (exact integral floats, >= 0). */
static inline void ss_fetch4(const vt_ssao_kjob *k, vf q, vf *x, vf *y, vf *z, vf *n)
{
#if CULL_SIMD_ISA == 3
    __m256i i = _mm256_cvttps_epi32(q);
    *x = _mm256_i32gather_ps(k->px, i, 4);
    *y = _mm256_i32gather_ps(k->py, i, 4);
    *z = _mm256_i32gather_ps(k->pz, i, 4);
    *n = _mm256_i32gather_ps(k->pn, i, 4);
#elif CULL_SIMD_ISA == 2
    __m128i i = _mm_cvttps_epi32(q);
    const size_t a = (uint32_t)_mm_cvtsi128_si32(i), b = (uint32_t)_mm_extract_epi32(i, 1),
                 c = (uint32_t)_mm_extract_epi32(i, 2), d = (uint32_t)_mm_extract_epi32(i, 3);
    *x = _mm_setr_ps(k->px[a], k->px[b], k->px[c], k->px[d]);
    *y = _mm_setr_ps(k->py[a], k->py[b], k->py[c], k->py[d]);
    *z = _mm_setr_ps(k->pz[a], k->pz[b], k->pz[c], k->pz[d]);
    *n = _mm_setr_ps(k->pn[a], k->pn[b], k->pn[c], k->pn[d]);
#else
    const size_t i = (uint32_t)q;
    *x = k->px[i], *y = k->py[i], *z = k->pz[i], *n = k->pn[i];
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

/* A texel of the half image at (X, Y) (integral floats) where mask m:
 * its point and nearness; *ok narrowed to the lanes on the image and not
 * on the sky. */
static inline void ss_texel(const vt_ssao_kjob *k, vf X, vf Y, vm m, vf *x, vf *y, vf *z, vf *n, vm *ok)
{
    const vt_ssao_view *sv = k->sv;
    m = vm_and(m, vm_and(vm_and(vf_ge(X, vf_set(0)), vf_lt(X, vf_set((float)sv->hw))),
                         vm_and(vf_ge(Y, vf_set(0)), vf_lt(Y, vf_set((float)sv->hh)))));
    vf q = vf_select(m, vf_add(vf_mul(Y, vf_set((float)sv->hw)), X), vf_set(0));
    ss_fetch4(k, q, x, y, z, n);
    *ok = vm_and(m, vf_lt(vf_set(VT_EMPTY), *n)); /* not the sky (nearness is never NaN) */
}

/* ss_texel for (X, Y) known to be on the image where m (a step whose
 * samples all stay inside): no bounds. (The planes' nearness is never
 * NaN: the sky is VT_EMPTY, the least float, so one compare tells it.) */
static inline void ss_texel_in(const vt_ssao_kjob *k, vf X, vf Y, vm m, vf *x, vf *y, vf *z, vf *n, vm *ok)
{
    vf q = vf_select(m, vf_add(vf_mul(Y, vf_set((float)k->sv->hw)), X), vf_set(0));
    ss_fetch4(k, q, x, y, z, n);
    *ok = vm_and(m, vf_lt(vf_set(VT_EMPTY), *n));
}

/* ss_texel for texels (X, Y) that are the planes' consecutive texels
 * q .. q + W - 1 (a step's own row, or one a fixed step away): loads, not
 * gathers (the pads keep them in the buffer; the lanes off the image are
 * masked as ss_texel's). */
static inline void ss_texel_at(const vt_ssao_kjob *k, vf X, vf Y, vm m, ptrdiff_t q, vf *x, vf *y, vf *z, vf *n,
                               vm *ok)
{
    const vt_ssao_view *sv = k->sv;
    m = vm_and(m, vm_and(vm_and(vf_ge(X, vf_set(0)), vf_lt(X, vf_set((float)sv->hw))),
                         vm_and(vf_ge(Y, vf_set(0)), vf_lt(Y, vf_set((float)sv->hh)))));
    *x = vf_loadu(k->px + q), *y = vf_loadu(k->py + q), *z = vf_loadu(k->pz + q), *n = vf_loadu(k->pn + q);
    *ok = vm_and(m, vf_lt(vf_set(VT_EMPTY), *n)); /* not the sky (nearness is never NaN) */
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
static inline void ss_side(const vt_ssao_kjob *k, vf X, vf Y, vf ux, vf uy, ptrdiff_t q, ptrdiff_t du, vm m,
                           const vf P[4], vf d[3], vm *ok)
{
    vf lo[4], lo2[4], hi[4], hi2[4];
    vm mlo, mlo2, mhi, mhi2;
    /* texel q is (X, Y); one step along the axis is du texels */
    ss_texel_at(k, vf_sub(X, ux), vf_sub(Y, uy), m, q - du, &lo[0], &lo[1], &lo[2], &lo[3], &mlo);
    ss_texel_at(k, vf_sub(X, vf_add(ux, ux)), vf_sub(Y, vf_add(uy, uy)), m, q - 2 * du, &lo2[0], &lo2[1], &lo2[2],
                &lo2[3], &mlo2);
    ss_texel_at(k, vf_add(X, ux), vf_add(Y, uy), m, q + du, &hi[0], &hi[1], &hi[2], &hi[3], &mhi);
    ss_texel_at(k, vf_add(X, vf_add(ux, ux)), vf_add(Y, vf_add(uy, uy)), m, q + 2 * du, &hi2[0], &hi2[1], &hi2[2],
                &hi2[3], &mhi2);
    const vf two = vf_set(2);
    vf el = vf_select(mlo, vf_select(mlo2, vf_abs(vf_sub(vf_sub(vf_mul(two, lo[3]), lo2[3]), P[3])), vf_set(FLT_MAX)),
                      vf_set(INFINITY));
    vf eh = vf_select(mhi, vf_select(mhi2, vf_abs(vf_sub(vf_sub(vf_mul(two, hi[3]), hi2[3]), P[3])), vf_set(FLT_MAX)),
                      vf_set(INFINITY));
    vm usehi = vm_or(vf_lt(eh, el), vm_and(vm_and(vf_le(eh, el), vf_le(el, eh)), mhi));
    for (int c = 0; c < 3; c++) d[c] = vf_select(usehi, vf_sub(hi[c], P[c]), vf_sub(P[c], lo[c]));
    *ok = vm_or(mlo, mhi);
}

void VT_SSAO_GTAO_NAME(const vt_ssao_kjob *k, uint32_t j)
{
    const vt_ssao_view *sv = k->sv;
    const float R = VT_SSAO_RADIUS, inv_fade = 1 / (VT_SSAO_FADE * VT_SSAO_RADIUS);
    /* the 2x2 pattern's turns: lane l of a step starting at column i0 has
       column parity (i0 + l) & 1 (W > 1: i0 is even) */
    float dc[2][VT_SSAO_SLICES][W], ds[2][VT_SSAO_SLICES][W], lane[W];
    for (int ph = 0; ph < 2; ph++)
        for (int l = 0; l < W; l++) {
            const float(*dir)[2] = k->dir + (((ph + l) & 1) + 2 * (j & 1)) * VT_SSAO_SLICES;
            for (int sl = 0; sl < VT_SSAO_SLICES; sl++) dc[ph][sl][l] = dir[sl][0], ds[ph][sl][l] = dir[sl][1];
            lane[l] = (float)l;
        }
    const vf Y = vf_set((float)j), zero = vf_set(0), one = vf_set(1);
    for (uint32_t i0 = 0; i0 < sv->hw; i0 += W) {
        vf X = vf_add(vf_set((float)i0), vf_loadu(lane));
        vf P[4];
        vm ok;
        const ptrdiff_t qc = (ptrdiff_t)j * sv->hw + i0;
        ss_texel_at(k, X, Y, vm_ones(), qc, &P[0], &P[1], &P[2], &P[3], &ok);
        float res[W];
        if (!vm_bits(ok)) {
            vf_store(res, one);
            goto out;
        }
        {
            vf rpx = vf_div(vf_mul(vf_set(R), sv->ortho ? one : P[3]), vf_set(sv->texel1));
            ok = vm_and(ok, vf_ge(rpx, one));
            rpx = vf_select(vf_lt(rpx, vf_set(VT_SSAO_MAX_PX)), rpx, vf_set(VT_SSAO_MAX_PX));
            vf nst = vf_select(vf_lt(rpx, vf_set((float)VT_SSAO_STEPS)), ss_floor(vf_select(ok, rpx, one)),
                               vf_set((float)VT_SSAO_STEPS));
            vf inv_nst = vf_div(one, nst);
            vf dx[3], dy[3], n[3], V[3];
            vm okx, oky;
            ss_side(k, X, Y, one, zero, qc, 1, ok, P, dx, &okx);
            ss_side(k, X, Y, zero, one, qc, (ptrdiff_t)sv->hw, ok, P, dy, &oky);
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
            for (int c = 0; c < 3; c++) {
                n[c] = vf_mul(n[c], ns);
                V[c] = vf_div(V[c], vl);
            }
            vf num = zero, den = zero;
            /* the steps' distances, the same for every slice and side */
            vf tts[VT_SSAO_STEPS];
            for (int st = 0; st < VT_SSAO_STEPS; st++) tts[st] = vf_mul(vf_mul(rpx, vf_set((float)st + 0.5f)), inv_nst);
            /* a sample is at most rpx (< B) texels away on either axis
               (|cos|, |sin| <= 1, the steps' distances below rpx): a step
               at least B from every side needs no bounds on its samples */
            bool inner;
            {
                float rr[W], rmax = 0;
                vf_store(rr, vf_select(ok, rpx, zero));
                for (int l = 0; l < W; l++) rmax = rr[l] > rmax ? rr[l] : rmax;
                const uint32_t B = (uint32_t)rmax + 2;
                inner = i0 >= B && i0 + W - 1 + B < sv->hw && j >= B && j + B < sv->hh;
            }
            for (int sl = 0; sl < VT_SSAO_SLICES; sl++) {
                const vf c = vf_loadu(dc[i0 & 1][sl]), s = vf_loadu(ds[i0 & 1][sl]);
                vf T[3];
                for (int q = 0; q < 3; q++) T[q] = vf_add(vf_mul(c, vf_set(sv->ex[q])), vf_mul(s, vf_set(sv->ey[q])));
                vf tv = ss_dot(T[0], T[1], T[2], V[0], V[1], V[2]);
                for (int q = 0; q < 3; q++) T[q] = vf_sub(T[q], vf_mul(tv, V[q]));
                vf tl = vf_sqrt(ss_dot(T[0], T[1], T[2], T[0], T[1], T[2]));
                vf a = ss_dot(n[0], n[1], n[2], V[0], V[1], V[2]);
                vf b = vf_div(ss_dot(n[0], n[1], n[2], T[0], T[1], T[2]), tl);
                vf pl = vf_sqrt(vf_add(vf_mul(a, a), vf_mul(b, b)));
                vm sok = vm_and(ok, vm_and(vf_lt(zero, tl), vf_lt(zero, pl)));
                if (!vm_bits(sok)) continue;
                vf cn = vf_div(a, pl), sn = vf_div(b, pl), na = ss_acos(cn);
                na = vf_select(vf_lt(sn, zero), vf_sub(zero, na), na);
                vf hc[2] = {sn, vf_sub(zero, sn)};
                vm up[2] = {vm_andnot(sok, sok), vm_andnot(sok, sok)};
                for (int side = 0; side < 2; side++) {
                    const vf sgc = vf_mul(vf_set(side ? 1.0f : -1.0f), c), sgs = vf_mul(vf_set(side ? 1.0f : -1.0f), s);
                    const vf lo = hc[side];
                    for (int st = 0; st < VT_SSAO_STEPS; st++) {
                        vm m = vm_and(sok, vf_lt(vf_set((float)st), nst));
                        if (!vm_bits(m)) break;
                        const vf tt = tts[st];
                        const vf h = vf_set(1024.5f), kk = vf_set(1024);
                        vf SX = vf_add(X, vf_sub(ss_floor(vf_select(m, vf_add(vf_mul(sgc, tt), h), h)), kk));
                        vf SY = vf_add(Y, vf_sub(ss_floor(vf_select(m, vf_add(vf_mul(sgs, tt), h), h)), kk));
                        vf S[4];
                        if (inner) ss_texel_in(k, SX, SY, m, &S[0], &S[1], &S[2], &S[3], &m);
                        else ss_texel(k, SX, SY, m, &S[0], &S[1], &S[2], &S[3], &m);
                        if (!vm_bits(m)) continue;
                        vf d[3] = {vf_sub(S[0], P[0]), vf_sub(S[1], P[1]), vf_sub(S[2], P[2])};
                        vf l2 = ss_dot(d[0], d[1], d[2], d[0], d[1], d[2]), hn = ss_dot(d[0], d[1], d[2], n[0], n[1], n[2]);
                        m = vm_and(m, vm_and(vm_and(vf_lt(zero, l2), vf_lt(l2, vf_set(R * R))), vf_lt(zero, hn)));
                        m = vm_and(m, vf_ge(vf_mul(hn, hn), vf_mul(vf_set(VT_SSAO_BIAS * VT_SSAO_BIAS), l2)));
                        if (!vm_bits(m)) continue;
                        vf il = vf_div(one, vf_sqrt(l2)), dist = vf_mul(l2, il);
                        vf wf = vf_mul(vf_sub(vf_set(R), dist), vf_set(inv_fade));
                        vf cv = vf_mul(ss_dot(d[0], d[1], d[2], V[0], V[1], V[2]), il);
                        cv = vf_add(lo, vf_mul(vf_sub(cv, lo), vf_select(vf_lt(wf, one), wf, one)));
                        vm raise = vm_and(m, vf_lt(hc[side], cv));
                        hc[side] = vf_select(raise, cv, hc[side]);
                        up[side] = vm_or(up[side], raise);
                    }
                }
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
    const size_t q0 = (size_t)j * sv->hw;
    float *const o[4] = {k->px + q0, k->py + q0, k->pz + q0, k->pn + q0};
    const vf Y = vf_set((float)((2.0 * (2 * j) + 1) / sv->h - 1)), inf = vf_set(INFINITY);
    vf a[4][4];
    for (int r = 0; r < 4; r++)
        for (int c = 0; c < 4; c++) a[r][c] = vf_set(sv->inv[r][c]);
    for (uint32_t i0 = 0; i0 < sv->hw; i0 += W) {
        uint32_t nw = sv->hw - i0 < (uint32_t)W ? sv->hw - i0 : (uint32_t)W;
        /* a whole step's 2 W full columns are in the row (w >= 2 hw - 1) */
        const bool whole = nw == (uint32_t)W && 2 * (i0 + W) <= sv->w;
        float nb[W], t[4][W];
        vf N;
        if (whole) {
            N = ss_even(nrow + 2 * (size_t)i0);
        } else {
            for (uint32_t l = 0; l < (uint32_t)W; l++) nb[l] = l < nw ? nrow[2 * (i0 + l)] : VT_EMPTY;
            N = vf_loadu(nb);
        }
        vf X = vf_loadu(k->colx + i0), q[4];
        /* (p, 1) ~ inv (X, Y, N, 1) (vt_ssao.c's unproject) */
        for (int r = 0; r < 4; r++) q[r] = vf_add(vf_add(vf_add(vf_mul(a[r][0], X), vf_mul(a[r][1], Y)), vf_mul(a[r][2], N)), a[r][3]);
        vf iw = vf_div(vf_set(1), q[3]), p[3];
        vm ok = vm_and(vf_lt(vf_set(VT_EMPTY), N), vf_lt(N, inf));
        for (int c = 0; c < 3; c++) {
            p[c] = vf_mul(q[c], iw);
            ok = vm_and(ok, vf_lt(vf_abs(p[c]), inf));
        }
        const vf nn = vf_select(ok, N, vf_set(VT_EMPTY));
        if (nw == (uint32_t)W) { /* the row's own texels: no other thread's */
            for (int c = 0; c < 3; c++) vf_store(o[c] + i0, p[c]);
            vf_store(o[3] + i0, nn);
            continue;
        }
        for (int c = 0; c < 3; c++) vf_store(t[c], p[c]);
        vf_store(t[3], nn);
        for (uint32_t l = 0; l < nw; l++)
            for (int c = 0; c < 4; c++) o[c][i0 + l] = t[c][l];
    }
}

void VT_SSAO_UP_NAME(const vt_ssao_kjob *k, uint32_t y)
{
    const vt_ssao_view *sv = k->sv;
    /* the rows' taps (vt_ssao.c's taps(), rows) */
    uint32_t jy[3];
    float wy[3];
    if (y & 1) {
        jy[0] = (y - 1) / 2, wy[0] = 0.5f;
        jy[1] = (y + 1) / 2 < sv->hh ? (y + 1) / 2 : jy[0], wy[1] = (y + 1) / 2 < sv->hh ? 0.5f : 0;
        jy[2] = jy[0], wy[2] = 0;
    } else {
        jy[0] = y >= 2 ? y / 2 - 1 : y / 2, wy[0] = y >= 2 ? 0.25f : 0;
        jy[1] = y / 2, wy[1] = 0.5f;
        jy[2] = y / 2 + 1 < sv->hh ? y / 2 + 1 : y / 2, wy[2] = y / 2 + 1 < sv->hh ? 0.25f : 0;
    }
    const float *nrow = k->near + (size_t)y * sv->w;
    float *o = k->ao + (size_t)y * sv->w;
    const float *hn[3], *ha[3];
    for (int a = 0; a < 3; a++) {
        hn[a] = k->pn + (size_t)jy[a] * sv->hw;
        ha[a] = k->hao + (size_t)jy[a] * sv->hw;
    }
    const size_t pl = (size_t)sv->w + 8;
    const vf zero = vf_set(0), one = vf_set(1);
    for (uint32_t x = 0; x < sv->w; x += W) {
        float nb[W], res[W];
        uint32_t nw = sv->w - x < (uint32_t)W ? sv->w - x : (uint32_t)W;
#if W > 1
        bool cont = false; /* a whole step whose taps ss_tap reads */
        /* most of a frame is unoccluded: where the three half rows are 1
           over the step's taps (half columns x/2 - 1 .. x/2 + W/2 within
           the W at x/2 - 1), every lane's mean is 1 (the general path's
           answer too), without the gathers */
        if (x >= 2 && nw == (uint32_t)W && x / 2 - 1 + W <= sv->hw) {
            cont = true;
            vm all1 = vm_and(vm_and(vf_le(one, vf_loadu(ha[0] + x / 2 - 1)), vf_le(one, vf_loadu(ha[1] + x / 2 - 1))),
                             vf_le(one, vf_loadu(ha[2] + x / 2 - 1)));
            if (vm_bits(all1) == (1u << W) - 1) {
                vf_store(o + x, one);
                continue;
            }
        }
#endif
        vf N;
        if (nw == (uint32_t)W) {
            N = vf_loadu(nrow + x);
        } else {
            for (uint32_t l = 0; l < (uint32_t)W; l++) nb[l] = l < nw ? nrow[x + l] : VT_EMPTY;
            N = vf_loadu(nb);
        }
        vf tol = sv->ortho ? vf_set(sv->ntol) : vf_mul(vf_set(VT_SSAO_DEPTH_TOL), N);
        vm ok = vm_and(vm_and(vf_lt(vf_set(VT_EMPTY), N), vf_lt(zero, tol)), vf_lt(tol, vf_set(FLT_MAX)));
        vf av[3][3];
        vf lo = one;
        for (int a = 0; a < 3; a++)
            for (int c = 0; c < 3; c++) {
#if W > 1
                av[a][c] = cont ? ss_tap(ha[a] + x / 2 - 1, c) : ss_gather(ha[a], k->cx + c * pl + x);
#else
                av[a][c] = ss_gather(ha[a], k->cx + c * pl + x);
#endif
                lo = vf_select(vf_lt(av[a][c], lo), av[a][c], lo);
            }
        /* most of a frame is unoccluded: the mean of ones is 1 */
        ok = vm_and(ok, vf_lt(lo, one));
        if (!vm_bits(ok)) {
            vf_store(res, one);
        } else {
            vf kk = vf_div(one, tol), sum = zero, acc = zero;
            for (int a = 0; a < 3; a++)
                for (int c = 0; c < 3; c++) {
#if W > 1
                    vf hv = cont ? ss_tap(hn[a] + x / 2 - 1, c) : ss_gather(hn[a], k->cx + c * pl + x);
#else
                    vf hv = ss_gather(hn[a], k->cx + c * pl + x);
#endif
                    vf wd = vf_sub(one, vf_mul(vf_abs(vf_sub(hv, N)), kk));
                    vf wt = vf_mul(vf_mul(vf_set(wy[a]), vf_loadu(k->cw + c * pl + x)), wd);
                    wt = vf_select(vf_lt(zero, wd), wt, zero);
                    sum = vf_add(sum, wt);
                    acc = vf_add(acc, vf_mul(wt, av[a][c]));
                }
            vm sp = vf_lt(zero, sum);
            vf ao = vf_div(acc, vf_select(sp, sum, one));
            ao = vf_select(vf_ge(ao, zero), vf_select(vf_le(ao, one), ao, one), vf_select(vf_lt(ao, zero), zero, one));
            vf_store(res, vf_select(vm_and(ok, sp), ao, one));
        }
        if (nw == (uint32_t)W) vf_store(o + x, vf_loadu(res));
        else
            for (uint32_t l = 0; l < nw; l++) o[x + l] = res[l];
    }
}
