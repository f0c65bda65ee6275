/*
 * vt_shade.inl — the shading kernel (see vt_shade.h), included once per
 * instruction set after cull_simd.h (W lanes) with VT_SHADE_NAME defined.
 * glTF 2.0's metallic-roughness BRDF (vt_brdf.h: GGX D, height-
 * correlated Smith V, Schlick F, diffuse x (1 - F)) for the sun and the
 * point and spot lights, inverse-square falloff windowed to zero at the
 * light's range, smoothstep spot cones; the ambient image-based (SH
 * irradiance, prefiltered sky x the DFG table) or the two-colour
 * hemisphere, or without an environment a small constant.
 */
#include "vt_brdf.h"
#include "vt_mask.h"
#include "vt_texlin.h"

#include <float.h>
#include <math.h>
#include <string.h>

#define S VT_SPAN
#define A _Alignas(32)

/* The surface the span's pixels show (structure of arrays). */
typedef struct surf {
    A float px[S]; A float py[S]; A float pz[S];   /* camera-relative position */
    A float nx[S]; A float ny[S]; A float nz[S];   /* unit normal */
    A float vx[S]; A float vy[S]; A float vz[S];   /* unit direction to the eye */
    A float ar[S]; A float ag[S]; A float ab[S];   /* albedo / pi */
    A float cr[S]; A float cg[S]; A float cb[S];   /* radiance so far */
    /* with an environment: the material's specular and emission */
    A float fr[S]; A float fg[S]; A float fb[S];   /* F0 */
    A float er[S]; A float eg[S]; A float eb[S];   /* emitted */
    A float a2[S]; A float ro[S];                  /* GGX alpha^2, perceptual roughness (clamped) */
    A float vv[S];                                 /* 1 / (|n.v| + sqrt(a2 + (1 - a2) n.v^2)): V's view half */
    A float sv[S]; A float ao[S];                  /* the sun's visibility (shadows), ambient occlusion */
} surf;

static inline vf dot3(vf ax, vf ay, vf az, vf bx, vf by, vf bz)
{
    return vf_fma(ax, bx, vf_fma(ay, by, vf_mul(az, bz)));
}

/* Table lookups in lanes: floor, float to index, and a gather of one
 * float per lane at base + index (AVX2's gather; one load a lane below). */
#if CULL_SIMD_ISA == 3
typedef __m256i vix;
static inline vf vf_floor(vf a) { return _mm256_floor_ps(a); }
static inline vix vx_of(vf a) { return _mm256_cvttps_epi32(a); }
static inline vf vf_gather(const float *b, vix i) { return _mm256_i32gather_ps(b, i, 4); }
#elif CULL_SIMD_ISA == 2
typedef __m128i vix;
static inline vf vf_floor(vf a) { return _mm_floor_ps(a); }
static inline vix vx_of(vf a) { return _mm_cvttps_epi32(a); }
static inline vf vf_gather(const float *b, vix i)
{
    return _mm_setr_ps(b[_mm_extract_epi32(i, 0)], b[_mm_extract_epi32(i, 1)], b[_mm_extract_epi32(i, 2)],
                       b[_mm_extract_epi32(i, 3)]);
}
#else
typedef int32_t vix;
static inline vf vf_floor(vf a) { return floorf(a); }
static inline vix vx_of(vf a) { return (int32_t)a; }
static inline vf vf_gather(const float *b, vix i) { return b[i]; }
#endif

/* 2^n for integral n in -126..127 (the exponent field set directly). */
#if CULL_SIMD_ISA == 3
static inline vf vf_pow2i(vix n) { return _mm256_castsi256_ps(_mm256_slli_epi32(_mm256_add_epi32(n, _mm256_set1_epi32(127)), 23)); }
#elif CULL_SIMD_ISA == 2
static inline vf vf_pow2i(vix n) { return _mm_castsi128_ps(_mm_slli_epi32(_mm_add_epi32(n, _mm_set1_epi32(127)), 23)); }
#else
static inline vf vf_pow2i(vix n)
{
    uint32_t b = (uint32_t)(n + 127) << 23;
    float f;
    memcpy(&f, &b, sizeof f);
    return f;
}
#endif

/* 1 / sqrt(a) for 1e-30 < a < FLT_MAX (rsqrt's 12 bits and one Newton
 * step: ~2^-22 relative), else 0 (0, tiny, infinite or NaN: what the
 * kernel's normalisations treat as degenerate). A division and a square
 * root were ~15 cycles a vector; this is four multiplies. */
#if CULL_SIMD_ISA == 3
static inline vf vf_rsqrt0(vf a)
{
    __m256 r = _mm256_rsqrt_ps(a);
    r = _mm256_mul_ps(_mm256_mul_ps(_mm256_set1_ps(0.5f), r),
                      _mm256_fnmadd_ps(_mm256_mul_ps(a, r), r, _mm256_set1_ps(3.0f)));
    return vf_select(vm_and(vf_lt(vf_set(1e-30f), a), vf_lt(a, vf_set(FLT_MAX))), r, vf_set(0));
}
#elif CULL_SIMD_ISA == 2
static inline vf vf_rsqrt0(vf a)
{
    __m128 r = _mm_rsqrt_ps(a);
    r = _mm_mul_ps(_mm_mul_ps(_mm_set1_ps(0.5f), r), _mm_sub_ps(_mm_set1_ps(3.0f), _mm_mul_ps(_mm_mul_ps(a, r), r)));
    return vf_select(vm_and(vf_lt(vf_set(1e-30f), a), vf_lt(a, vf_set(FLT_MAX))), r, vf_set(0));
}
#else
static inline vf vf_rsqrt0(vf a)
{
    return a > 1e-30f && a < FLT_MAX ? 1 / sqrtf(a) : 0;
}
#endif

/* e^x in lanes (Cephes' expf: x = n ln 2 + r, |r| <= ln 2 / 2, ln 2 in
 * two parts, a degree-7 polynomial for e^r): relative error 8.3e-8
 * (about 1 ulp; measured against double exp every 0.0007 with fused
 * multiply-adds, the SSE4.1 instance's unfused ones add an ulp) over the
 * clamp -87.3..88.3, where libm's expf is within 1 ulp; beyond it the
 * ends' values (about 1e-38 and 2e38, never 0 or inf).
 * A NaN stays NaN. About 20 operations against libm's call per lane. */
static inline vf vf_exp(vf x)
{
    x = vf_min(vf_max(x, vf_set(-87.3f)), vf_set(88.3f));
    vf fx = vf_floor(vf_fma(x, vf_set(1.44269504088896341f), vf_set(0.5f)));
    vf r = vf_sub(vf_sub(x, vf_mul(fx, vf_set(0.693359375f))), vf_mul(fx, vf_set(-2.12194440e-4f)));
    vf y = vf_set(1.9875691500e-4f);
    y = vf_fma(y, r, vf_set(1.3981999507e-3f));
    y = vf_fma(y, r, vf_set(8.3334519073e-3f));
    y = vf_fma(y, r, vf_set(4.1665795894e-2f));
    y = vf_fma(y, r, vf_set(1.6666665459e-1f));
    y = vf_fma(y, r, vf_set(5.0000001201e-1f));
    y = vf_add(vf_fma(vf_mul(y, r), r, r), vf_set(1));
    return vf_mul(y, vf_pow2i(vx_of(fx)));
}

/* All W lanes' bits. */
static inline uint32_t lanes_all(void)
{
    return (1u << W) - 1;
}

#include "vt_gather.inl"

/* vt_fog_apply (vt_scene.c, the reference; the GLSL mirrors it) on W
 * pixels at i, for those cov says are drawn: the height fog's optical
 * depth from the eye to p, the radiance towards the fog's by e^-depth.
 * e0: e^min(k y0, 80), the span's constant. The same formula; the
 * exponentials are vf_exp's (1-2 ulps) and the height term's quotient near
 * 0 its series, so the optical depth is within ~3e-6 of the exact one
 * (the reference's own rounding is of that order), the pixel's radiance
 * within that of the fog's contrast. ~100 instructions a pixel before
 * (two libm expf), ~60 for 8 lanes now. */
static inline void fog_lanes(surf *restrict s, const vt_penv *pe, float e0, const float *cov, unsigned i)
{
    const vf zero = vf_set(0), one = vf_set(1);
    vf px = vf_load(s->px + i), py = vf_load(s->py + i), pz = vf_load(s->pz + i);
    vf L = vf_sqrt(dot3(px, py, pz, px, py, pz)), od;
    const float k = pe->fog_falloff;
    if (k > 0) {
        vf kd = vf_mul(vf_set(k), py);
        /* (1 - e^-kd) / kd; near 0 its Taylor series to kd^4 (error
           < kd^5 / 720 < 1.3e-9 below 1/16), where the quotient would
           lose digits: the reference switches at 1e-4, where its
           1 - 0.5 kd is as close */
        vf g = vf_div(vf_sub(one, vf_exp(vf_sub(zero, kd))), kd);
        vf t = vf_fma(kd, vf_set(1.0f / 120), vf_set(-1.0f / 24));
        t = vf_fma(vf_fma(vf_fma(t, kd, vf_set(1.0f / 6)), kd, vf_set(-0.5f)), kd, one);
        g = vf_select(vf_lt(vf_set(0.0625f), vf_abs(kd)), g, t);
        od = vf_mul(vf_mul(vf_set(pe->fog_density * e0), L), g);
    } else {
        od = vf_mul(vf_set(pe->fog_density), L);
    }
    vf T = vf_exp(vf_sub(zero, vf_max(od, zero))), T1 = vf_sub(one, T); /* a NaN depth: 0, as the reference */
    vm drawn = vf_lt(zero, vf_load(cov + i));
    float *const c[3] = {s->cr, s->cg, s->cb};
    for (int k3 = 0; k3 < 3; k3++) {
        vf v = vf_load(c[k3] + i);
        vf_store(c[k3] + i, vf_select(drawn, vf_add(vf_mul(v, T), vf_mul(vf_set(pe->fog[k3]), T1)), v));
    }
}

/* vt_bilerp_add in lanes over a table packed to 32 bits a texel
 * (vt_brdf.h: e5 the shared-exponent radiance, else 10-bit unorms): a
 * res x res table at t, plus off texels per lane (the level), at texel
 * units (x, y) clamped to the edge texels (a NaN: 0), w x the RGB added
 * to o. One gather a corner (three with floats). */
static inline __attribute__((always_inline)) void bilerp_lanes(const uint32_t *t, int res, vix off, vf x, vf y, vf w, vf o[3], bool e5)
{
    const vf zero = vf_set(0), m = vf_set((float)(res - 1)), m2 = vf_set((float)(res - 2));
    x = vf_min(vf_max(x, zero), m);
    y = vf_min(vf_max(y, zero), m);
    vf fi = vf_min(vf_floor(x), m2), fj = vf_min(vf_floor(y), m2);
    vf ax = vf_sub(x, fi), ay = vf_sub(y, fj);
    vix i00 = vi_add(vx_of(vf_fma(fj, vf_set((float)res), fi)), off);
    vix c[4] = {vi_gather(t, i00), vi_gather(t, vi_add(i00, vi_set(1))), vi_gather(t, vi_add(i00, vi_set(res))),
                vi_gather(t, vi_add(i00, vi_set(res + 1)))};
    vf v[4][3];
    for (int q = 0; q < 4; q++) {
        if (e5) {
            /* 2^(e - bias - 9) by the exponent field */
            vf step = vi_asf(vi_sll(vi_add(vi_srl(c[q], 27), vi_set(127 - VT_E5_BIAS - 9)), 23));
            for (int k = 0; k < 3; k++) v[q][k] = vf_mul(vi_tof(vi_and(vi_srl(c[q], 9 * k), vi_set(511))), step);
        } else {
            for (int k = 0; k < 3; k++)
                v[q][k] = vf_mul(vi_tof(vi_and(vi_srl(c[q], 10 * k), vi_set(1023))), vf_set(1 / 1023.0f));
        }
    }
    for (int k = 0; k < 3; k++) {
        vf top = vf_fma(ax, vf_sub(v[1][k], v[0][k]), v[0][k]), bot = vf_fma(ax, vf_sub(v[3][k], v[2][k]), v[2][k]);
        o[k] = vf_fma(w, vf_fma(ay, vf_sub(bot, top), top), o[k]);
    }
}

/* vt_ibl_lookup in lanes: the prefiltered sky towards r = 2 (n.v) n - v
 * at the pixels' roughness (two levels), and the DFG table at |n.v|. */
static inline void ibl_lanes(const vt_ibl *ibl, vf nx, vf ny, vf nz, vf vx_, vf vy, vf vz, vf nv, vf ro, vf sp[3],
                             vf g[3])
{
    const vf zero = vf_set(0), one = vf_set(1), half = vf_set(0.5f), none = vf_set(-1);
    vf two_d = vf_add(nv, nv);
    vf rx = vf_fma(two_d, nx, vf_sub(zero, vx_)), ry = vf_fma(two_d, ny, vf_sub(zero, vy)), rz = vf_fma(two_d, nz, vf_sub(zero, vz));
    vf s = vf_add(vf_add(vf_abs(rx), vf_abs(ry)), vf_abs(rz));
    vf is = vf_select(vf_lt(zero, s), vf_div(one, s), zero);
    vf px = vf_mul(rx, is), pz = vf_mul(rz, is);
    vf qx = vf_mul(vf_sub(one, vf_abs(pz)), vf_select(vf_lt(px, zero), none, one));
    vf qz = vf_mul(vf_sub(one, vf_abs(px)), vf_select(vf_lt(pz, zero), none, one));
    vm below = vf_lt(ry, zero);
    px = vf_select(below, qx, px);
    pz = vf_select(below, qz, pz);
    const vf res = vf_set((float)VT_IBL_RES), centre = vf_set(0.5f * VT_IBL_RES - 0.5f);
    vf x = vf_sub(vf_mul(vf_fma(half, px, half), res), half), y = vf_sub(vf_mul(vf_fma(half, pz, half), res), half);
    vm ok = vm_and(vf_ge(x, x), vf_ge(y, y)); /* a NaN direction: the centre */
    x = vf_select(ok, x, centre);
    y = vf_select(ok, y, centre);
    for (int k = 0; k < 3; k++) sp[k] = g[k] = zero;
    const vf dm = vf_set((float)(VT_DFG_N - 1)), dx = vf_mul(vf_min(vf_abs(nv), one), dm);
    /* one roughness over the group (one material's pixels) with an entry
       for it (vt_brdf.h): its blend of the levels, its row of the DFG
       table (a lane's cell of the row: the lanes' x clamped as
       bilerp_lanes clamps) */
    const float r0 = vf_hmin(ro);
    const int e = vm_bits(vf_le(ro, vf_set(r0))) == lanes_all() ? vt_ibl_rough_find(ibl, r0) : -1;
    if (e >= 0) {
        bilerp_lanes(ibl->rspec[e], VT_IBL_RES, vi_set(0), x, y, one, sp, true);
        vf cx = vf_min(vf_max(dx, zero), dm), fi = vf_min(vf_floor(cx), vf_set((float)(VT_DFG_N - 2))), ax = vf_sub(cx, fi);
        vix i0 = vx_of(fi);
        vix c0 = vi_gather(ibl->rdfg[e], i0), c1 = vi_gather(ibl->rdfg[e], vi_add(i0, vi_set(1)));
        for (int k = 0; k < 3; k++) {
            vf a = vf_mul(vi_tof(vi_and(vi_srl(c0, 10 * k), vi_set(1023))), vf_set(1 / 1023.0f));
            vf b = vf_mul(vi_tof(vi_and(vi_srl(c1, 10 * k), vi_set(1023))), vf_set(1 / 1023.0f));
            g[k] = vf_fma(ax, vf_sub(b, a), a);
        }
        return;
    }
    vf f = vf_mul(ro, vf_set((float)(VT_IBL_LEVELS - 1)));
    vf lv = vf_min(vf_floor(f), vf_set((float)(VT_IBL_LEVELS - 2))), t = vf_sub(f, lv);
    vix off = vx_of(vf_mul(lv, vf_set((float)(VT_IBL_RES * VT_IBL_RES))));
    bilerp_lanes(ibl->spec_e5[0], VT_IBL_RES, off, x, y, vf_sub(one, t), sp, true);
    bilerp_lanes(ibl->spec_e5[1], VT_IBL_RES, off, x, y, t, sp, true);
    bilerp_lanes(ibl->dfg10, VT_DFG_N, vi_set(0), dx, vf_mul(vf_min(ro, one), dm), one, g, false);
}

/* glTF's D V for one light (Appendix B): n.h, n.l >= 0, alpha^2, and
 * the pixel's view half of V (vv). One square root, one division. */
static inline vf ggx_dv(vf ndh, vf ndl, vf a2, vf vv)
{
    const vf one = vf_set(1);
    /* (1 - n.h)(1 + n.h) + n.h^2 a2: vt_brdf_d's well-conditioned form */
    vf t = vf_fma(vf_mul(ndh, ndh), a2, vf_mul(vf_sub(one, ndh), vf_add(one, ndh)));
    vf gl = vf_add(ndl, vf_sqrt(vf_fma(vf_sub(one, a2), vf_mul(ndl, ndl), a2)));
    return vf_div(vf_mul(vf_mul(a2, vf_set(1.0f / 3.14159265f)), vv), vf_mul(vf_mul(t, t), gl));
}

/* (1 - v.h)^5 of Schlick's Fresnel, for unit v, l (h = (l + v) / |l + v|),
 * and n.h >= 0. */
static inline vf half_terms(vf nx, vf ny, vf nz, vf vx, vf vy, vf vz, vf lx, vf ly, vf lz, vf *ndh)
{
    const vf zero = vf_set(0), one = vf_set(1);
    vf hx = vf_add(lx, vx), hy = vf_add(ly, vy), hz = vf_add(lz, vz);
    vf hl2 = dot3(hx, hy, hz, hx, hy, hz);
    vf ih = vf_rsqrt0(hl2);
    *ndh = vf_max(vf_mul(dot3(nx, ny, nz, hx, hy, hz), ih), zero);
    vf vh = vf_min(vf_max(vf_mul(dot3(vx, vy, vz, hx, hy, hz), ih), zero), one);
    vf f1 = vf_sub(one, vh), f2 = vf_mul(f1, f1);
    return vf_mul(vf_mul(f2, f2), f1);
}

/* The sky's ambient and the sun on W pixels at i (vt_surface.h's model).
 * Image-based (pe->ibl): diffuse x (1 - f0) C x the SH irradiance / pi,
 * plus the prefiltered sky towards the reflected direction x (f0 A + B)
 * (A, B, C: vt_dfg at |n.v|, roughness), both x the occlusion; else the
 * hemisphere of before: diffuse x the ambient by the normal's height,
 * Fresnel (Schlick, weighted by (1 - roughness)^2) x the ambient by the
 * reflected direction's. Emission. The sun: glTF's BRDF x n.l x its
 * visibility. vt_gldraw's GLSL (vt_brdf_glsl.c): the same. */
static inline void env_light(surf *restrict s, const vt_penv *pe, unsigned i)
{
    const vf zero = vf_set(0), one = vf_set(1), half = vf_set(0.5f), two = vf_set(2);
    vf nx = vf_load(s->nx + i), ny = vf_load(s->ny + i), nz = vf_load(s->nz + i);
    vf vx = vf_load(s->vx + i), vy = vf_load(s->vy + i), vz = vf_load(s->vz + i);
    vf nv = dot3(nx, ny, nz, vx, vy, vz);
    vf ao = vf_load(s->ao + i);
    float *const dif[3] = {s->ar, s->ag, s->ab}, *const f0[3] = {s->fr, s->fg, s->fb}, *const em[3] = {s->er, s->eg, s->eb};
    float *const out[3] = {s->cr, s->cg, s->cb};
    vf c[3];
    if (pe->ibl) {
        /* the lookups (prefiltered sky, DFG) in lanes */
        vf sp[3], dfg[3];
        ibl_lanes(pe->ibl, nx, ny, nz, vx, vy, vz, nv, vf_load(s->ro + i), sp, dfg);
        const float(*sh)[3] = pe->ibl->sh;
        vf xy = vf_mul(nx, ny), yz = vf_mul(ny, nz), xz = vf_mul(nx, nz);
        vf z3 = vf_fma(vf_set(3), vf_mul(nz, nz), vf_set(-1)), x2y2 = vf_sub(vf_mul(nx, nx), vf_mul(ny, ny));
        vf dA = dfg[0], dB = dfg[1], dC = dfg[2];
        for (int k = 0; k < 3; k++) {
            vf e = vf_fma(vf_set(sh[1][k]), ny, vf_fma(vf_set(sh[2][k]), nz, vf_fma(vf_set(sh[3][k]), nx, vf_set(sh[0][k]))));
            e = vf_fma(vf_set(sh[4][k]), xy, vf_fma(vf_set(sh[5][k]), yz, vf_fma(vf_set(sh[6][k]), z3, e)));
            e = vf_max(vf_fma(vf_set(sh[7][k]), xz, vf_fma(vf_set(sh[8][k]), x2y2, e)), zero);
            vf F0 = vf_load(f0[k] + i);
            vf d = vf_mul(vf_mul(vf_load(dif[k] + i), vf_mul(vf_sub(one, F0), dC)), e);
            vf sr = vf_mul(sp[k], vf_fma(F0, dA, dB));
            c[k] = vf_fma(vf_add(d, sr), ao, vf_load(em[k] + i));
        }
    } else {
        vf ry = vf_sub(vf_mul(vf_mul(two, nv), ny), vy);
        vf ka = vf_fma(half, ny, half), kr = vf_fma(half, vf_min(vf_max(ry, vf_set(-1)), one), half);
        vf fv = vf_sub(one, vf_max(nv, zero)), fv2 = vf_mul(fv, fv), fv5 = vf_mul(vf_mul(fv2, fv2), fv);
        vf g = vf_sub(one, vf_load(s->ro + i));
        vf wf = vf_mul(fv5, vf_mul(g, g));
        for (int k = 0; k < 3; k++) {
            vf up = vf_set(pe->amb_up[k]), dn = vf_set(pe->amb_down[k]), d = vf_sub(up, dn);
            vf la = vf_fma(ka, d, dn), lr = vf_fma(kr, d, dn), F0 = vf_load(f0[k] + i);
            vf fr = vf_fma(vf_sub(one, F0), wf, F0);
            /* the ambient, occluded */
            c[k] = vf_fma(vf_mul(vf_load(dif[k] + i), la), ao, vf_fma(vf_mul(fr, lr), ao, vf_load(em[k] + i)));
        }
    }
    const vf lx = vf_set(pe->sun_dir[0]), ly = vf_set(pe->sun_dir[1]), lz = vf_set(pe->sun_dir[2]);
    vf ndl = zero, kl = zero;
    if (pe->sun_on) {
        ndl = vf_max(dot3(nx, ny, nz, lx, ly, lz), zero);
        kl = vf_mul(ndl, vf_load(s->sv + i)); /* n.l, times the sun's visibility (the shadow cascades) */
    }
    /* the sun's BRDF only where some lane sees it (a group in shadow or
       facing away, or no sun, adds nothing: 0 x a finite BRDF) */
    if (vm_bits(vf_lt(zero, kl))) {
        vf ndh, f5 = half_terms(nx, ny, nz, vx, vy, vz, lx, ly, lz, &ndh);
        vf dv = ggx_dv(ndh, ndl, vf_load(s->a2 + i), vf_load(s->vv + i));
        for (int k = 0; k < 3; k++) {
            vf F0 = vf_load(f0[k] + i), F = vf_fma(vf_sub(one, F0), f5, F0);
            vf cd = vf_mul(vf_load(dif[k] + i), vf_set(1.0f / 3.14159265f));
            vf b = vf_fma(F, vf_sub(dv, cd), cd); /* (1 - F) c_diff / pi + F D V */
            c[k] = vf_fma(vf_mul(vf_set(pe->sun[k]), kl), b, c[k]);
        }
    }
    for (int k = 0; k < 3; k++) vf_store(out[k] + i, c[k]);
}

/* Four channels of W pixels, interleaved, to dst (4 W floats). */
static inline void store_rgba(float *dst, vf r, vf g, vf b, vf a)
{
#if CULL_SIMD_ISA == 3
    __m256 rg0 = _mm256_unpacklo_ps(r, g), rg1 = _mm256_unpackhi_ps(r, g); /* r0 g0 r1 g1 | r4 g4 r5 g5 */
    __m256 ba0 = _mm256_unpacklo_ps(b, a), ba1 = _mm256_unpackhi_ps(b, a);
    __m256 p04 = _mm256_shuffle_ps(rg0, ba0, 0x44), p15 = _mm256_shuffle_ps(rg0, ba0, 0xEE);
    __m256 p26 = _mm256_shuffle_ps(rg1, ba1, 0x44), p37 = _mm256_shuffle_ps(rg1, ba1, 0xEE);
    _mm256_storeu_ps(dst, _mm256_permute2f128_ps(p04, p15, 0x20));
    _mm256_storeu_ps(dst + 8, _mm256_permute2f128_ps(p26, p37, 0x20));
    _mm256_storeu_ps(dst + 16, _mm256_permute2f128_ps(p04, p15, 0x31));
    _mm256_storeu_ps(dst + 24, _mm256_permute2f128_ps(p26, p37, 0x31));
#elif CULL_SIMD_ISA == 2
    _MM_TRANSPOSE4_PS(r, g, b, a);
    _mm_storeu_ps(dst, r);
    _mm_storeu_ps(dst + 4, g);
    _mm_storeu_ps(dst + 8, b);
    _mm_storeu_ps(dst + 12, a);
#else
    dst[0] = r;
    dst[1] = g;
    dst[2] = b;
    dst[3] = a;
#endif
}

/* One light over the span; spot is a constant at each call site, so each
 * of the two copies is a straight loop. */
static inline __attribute__((always_inline)) void light(surf *restrict s, const vt_slight *restrict L, int spot)
{
    const vf lpx = vf_set(L->p[0]), lpy = vf_set(L->p[1]), lpz = vf_set(L->p[2]), r2 = vf_set(L->range2);
    const vf ir2 = vf_set(L->inv_range2);
    const vf dx = vf_set(L->dir[0]), dy = vf_set(L->dir[1]), dz = vf_set(L->dir[2]);
    const vf co = vf_set(L->cos_outer), cspan = vf_set(L->inv_cone);
    const vf lr = vf_set(L->color[0]), lg = vf_set(L->color[1]), lb = vf_set(L->color[2]);
    const vf zero = vf_set(0), one = vf_set(1), eps = vf_set(1e-2f), two = vf_set(2), three = vf_set(3);
    for (unsigned i = 0; i < S; i += W) {
        vf nx = vf_load(s->nx + i), ny = vf_load(s->ny + i), nz = vf_load(s->nz + i);
        vf lx = vf_sub(lpx, vf_load(s->px + i)), ly = vf_sub(lpy, vf_load(s->py + i)), lz = vf_sub(lpz, vf_load(s->pz + i));
        vf d2 = dot3(lx, ly, lz, lx, ly, lz);
        vm in = vm_and(vf_lt(d2, r2), vf_lt(zero, d2));
        if (!vm_bits(in)) continue;     /* out of range for all W pixels */
        vf d2s = vf_select(in, d2, one);
        vf il = vf_rsqrt0(d2s);
        lx = vf_mul(lx, il);
        ly = vf_mul(ly, il);
        lz = vf_mul(lz, il);
        vf ndl = dot3(nx, ny, nz, lx, ly, lz);
        vf q = vf_mul(d2s, ir2), win = vf_sub(one, vf_mul(q, q));
        vf att = vf_div(vf_mul(win, win), vf_add(d2s, eps));
        if (spot) {
            vf cd = dot3(lx, ly, lz, dx, dy, dz);      /* -cos to the axis */
            vf t = vf_mul(vf_sub(vf_sub(zero, cd), co), cspan);
            t = vf_min(vf_max(t, zero), one);
            att = vf_mul(att, vf_mul(vf_mul(t, t), vf_sub(three, vf_mul(two, t))));
        }
        vm lit = vm_and(in, vm_and(vf_lt(zero, ndl), vf_lt(zero, att)));
        if (!vm_bits(lit)) continue;
        /* the pixel's material: glTF's BRDF as for the sun (ar.. already
           c_diff / pi here) */
        ndl = vf_max(ndl, zero);
        vf ndh, f5 = half_terms(nx, ny, nz, vf_load(s->vx + i), vf_load(s->vy + i), vf_load(s->vz + i), lx, ly, lz, &ndh);
        vf dv = ggx_dv(ndh, ndl, vf_load(s->a2 + i), vf_load(s->vv + i));
        vf f = vf_mul(att, ndl);
        const vf lc[3] = {lr, lg, lb};
        float *const cd[3] = {s->ar, s->ag, s->ab}, *const f0[3] = {s->fr, s->fg, s->fb}, *const acc[3] = {s->cr, s->cg, s->cb};
        for (int k = 0; k < 3; k++) {
            vf F0 = vf_load(f0[k] + i), F = vf_fma(vf_sub(one, F0), f5, F0), d = vf_load(cd[k] + i);
            vf b = vf_fma(F, vf_sub(dv, d), d);
            vf_store(acc[k] + i, vf_add(vf_load(acc[k] + i), vf_select(lit, vf_mul(vf_mul(lc[k], f), b), zero)));
        }
    }
}

/* The first 256 bytes of the shading record of pixel id id (a triangle's) to the cache. */
static inline void prefetch_rec(const vt_span *sp, uint32_t id)
{
    const char *t = (const char *)&sp->st[(id - 1) >> VT_ID_BITS][(id - 1) & VT_ID_MASK];
    __builtin_prefetch(t), __builtin_prefetch(t + 64), __builtin_prefetch(t + 128), __builtin_prefetch(t + 192);
}

/* The records of the span's pixels (at a row's start) and of the next
 * span's to the cache (they are spread over a few MB: one miss after
 * another per group otherwise). */
static inline void prefetch_span(const vt_span *sp)
{
    const uint32_t width = (uint32_t)(2.0 / sp->inv_w + 0.5);
    const unsigned e = sp->x0 + 2 * S <= width ? 2 * S : sp->n;
    unsigned i = sp->x0 ? S : 0;
    /* a record's first pixel in a run (its id not the pixel before's, not
       0 or the ground), W ids a compare: the scalar scan of 16-32 ids was
       7 % of the kernel's instructions. A record seen again after a gap
       is fetched again: a few instructions, the line is in the cache */
    for (; i + W <= e; i += W) {
        A uint32_t lead[W];
        const uint32_t *before = sp->id + i - 1;
        if (!i) {
            lead[0] = 0;
            for (unsigned j = 1; j < W; j++) lead[j] = sp->id[j - 1];
            before = lead;
        }
        const vix a = vi_loadu(sp->id + i);
        const vm same = vm_or(vi_eq(a, vi_loadu(before)), vm_or(vi_eq(a, vi_set(0)), vi_eq(a, vi_set((int32_t)VT_ID_GROUND))));
        for (uint32_t first = lanes_all() & ~vm_bits(same); first; first &= first - 1) {
            prefetch_rec(sp, sp->id[i + (unsigned)__builtin_ctz(first)]);
        }
    }
    for (uint32_t prev = i ? sp->id[i - 1] : 0; i < e; i++) { /* a short span's rest */
        uint32_t id = sp->id[i];
        if (id == prev || id == 0 || id == VT_ID_GROUND) continue;
        prev = id;
        prefetch_rec(sp, id);
    }
}

void VT_SHADE_NAME(const vt_span *sp)
{
    surf s;
    A float cov[S];
    const bool env = sp->pe && sp->pe->on;
    /* nothing drawn in the whole span (sky, off the geometry): no surface */
    uint32_t any = 0;
    if (sp->n == S) { /* W ids a compare (the loop was ~30 instructions a span) */
        vm none = vm_ones();
        for (unsigned i = 0; i < S; i += W) none = vm_and(none, vi_eq(vi_loadu(sp->id + i), vi_set(0)));
        any = vm_bits(none) != lanes_all();
    } else {
        for (unsigned i = 0; i < sp->n; i++) any |= sp->id[i];
    }
    if (!any) {
        memset(sp->rgba, 0, (size_t)sp->n * 4 * sizeof(float));
        for (unsigned i = 0; i < sp->n; i++) sp->depth[i] = INFINITY;
        if (!env) return;
        A float zero[S] = {0}, r[S], g[S], b[S];
        span_sky(sp, r, g, b, zero);
        if (sp->n == S) {
            for (unsigned i = 0; i < S; i += W)
                store_rgba(sp->rgba + 4 * i, vf_load(r + i), vf_load(g + i), vf_load(b + i), vf_set(1));
            return;
        }
        for (unsigned i = 0; i < sp->n; i++) {
            float *o = sp->rgba + 4 * i;
            o[0] = r[i], o[1] = g[i], o[2] = b[i], o[3] = 1;
        }
        return;
    }
    /* gather, W pixels at a time: per record they show (a triangle or
       the ground) its interpolated inputs in lanes (vt_gather.inl), then
       per material among them the material in lanes: two triangles of
       one mesh side by side sample their textures once. What the lanes
       do not cover goes through vt_span_surface pixel by pixel. */
    prefetch_span(sp);
    const vf zero0 = vf_set(0), one0 = vf_set(1), amb = vf_set(VT_AMBIENT);
    const vt_material *lane_mat = NULL; /* the last material found lane-able (NULL: the default, always) */
    for (unsigned g0 = 0; g0 < S; g0 += W) {
        /* the lanes' records: a vector load from the id buffer (not
           built from scalar stores: that vector reload stalled on store
           forwarding, 7 % of the kernel's time) */
        A uint32_t pad[W];
        const uint32_t *ids = sp->id + g0;
        if (g0 + W > sp->n) {
            for (unsigned j = 0; j < W; j++) pad[j] = g0 + j < sp->n ? sp->id[g0 + j] : 0;
            ids = pad;
        }
        const vix idv = vi_loadu(ids);
        uint32_t pend = lanes_all() & ~vm_bits(vi_eq(idv, vi_set(0))), lanes = 0;
        uintptr_t kl[W]; /* the group's materials (| 1: UVs read) and their lanes */
        uint32_t kb[W];
        unsigned nk = 0;
        /* nothing drawn: zeros (finite V, D in the unlit lanes: a2, ro 1);
           a group drawn all over needs none (every lane is written) */
        const bool full = pend == lanes_all();
        if (!full) {
            /* stores at constant offsets (an array of the pointers was
               built every span, ~50 instructions, used or not) */
#define Z(f) vf_store(s.f + g0, zero0)
            Z(px), Z(py), Z(pz), Z(nx), Z(ny), Z(nz), Z(ar), Z(ag), Z(ab), Z(cr), Z(cg), Z(cb);
            Z(fr), Z(fg), Z(fb), Z(er), Z(eg), Z(eb), Z(sv);
#undef Z
            vf_store(cov + g0, zero0);
            vf_store(s.a2 + g0, one0);
            vf_store(s.ro + g0, one0);
        }
        gin in = {0}; /* every field set by the first lane-able record (zeroed: gcc -O3 cannot tell) */
        while (pend) {
            const uint32_t id = ids[__builtin_ctz(pend)];
            const uint32_t mb = vm_bits(vi_eq(idv, vi_set((int32_t)id)));
            pend &= ~mb;
            const vt_stri *t = id == VT_ID_GROUND ? NULL : &sp->st[(id - 1) >> VT_ID_BITS][(id - 1) & VT_ID_MASK];
            const vt_material *m = t ? t->mat : sp->pe->ground_mat;
            /* the material's check once a span for the material seen last */
            if (!vt_gather_scalar && (t ? !t->mask : true) && (m == lane_mat || (mat_lanes_ok(m) && (lane_mat = m, true)))) {
                const bool uv = mat_reads_uv(m) && (!t || t->has_uv);
                gin g;
                if (t) tri_lanes(t, sp, lanes_ndc_x(sp, g0), uv, &g);
                else ground_lanes(sp, g0, mb, uv, &g);
                const vm act = vm_from_bits(mb);
                if (!lanes) {
                    in = g; /* the first record: every lane may take it */
                } else {
#define SEL(f) in.f = vf_select(act, g.f, in.f)
                    SEL(px), SEL(py), SEL(pz), SEL(nx), SEL(ny), SEL(nz), SEL(al[0]), SEL(al[1]), SEL(al[2]);
                    SEL(u), SEL(v), SEL(dxu), SEL(dxv), SEL(dyu), SEL(dyv);
#undef SEL
                }
                /* the lanes of each material (and whether its UVs are read) */
                const uintptr_t k = (uintptr_t)m | uv;
                unsigned q = 0;
                while (q < nk && kl[q] != k) q++;
                if (q == nk) kl[nk] = k, kb[nk++] = 0;
                kb[q] |= mb;
                lanes |= mb;
                continue;
            }
            for (unsigned j = 0; j < W; j++) {
                if (!(mb >> j & 1)) continue;
                const unsigned i = g0 + j;
                float p[3];
                vt_surfout o;
                vt_span_surface(sp, i, p, &o, &cov[i]);
                s.px[i] = p[0], s.py[i] = p[1], s.pz[i] = p[2];
                s.nx[i] = o.n[0], s.ny[i] = o.n[1], s.nz[i] = o.n[2];
                s.ar[i] = o.diffuse[0], s.ag[i] = o.diffuse[1], s.ab[i] = o.diffuse[2];
                s.fr[i] = o.f0[0], s.fg[i] = o.f0[1], s.fb[i] = o.f0[2];
                s.er[i] = o.em[0], s.eg[i] = o.em[1], s.eb[i] = o.em[2];
                s.a2[i] = o.a2, s.ro[i] = o.rough;
                s.sv[i] = 1.0f; /* times the sun's visibility below */
                s.cr[i] = VT_AMBIENT * o.diffuse[0] + o.em[0];
                s.cg[i] = VT_AMBIENT * o.diffuse[1] + o.em[1];
                s.cb[i] = VT_AMBIENT * o.diffuse[2] + o.em[2];
            }
        }
        if (!lanes) continue;
        /* the materials over the lanes' pixels */
        /* the first material's straight into go (lanes: there is one) */
        gout go;
        mat_lanes((const vt_material *)(kl[0] & ~(uintptr_t)1), &in, kl[0] & 1, vm_from_bits(kb[0]), sp->tc, &go);
        for (unsigned q = 1; q < nk; q++) {
            const uintptr_t k = kl[q];
            const uint32_t mb = kb[q];
            const vm act = vm_from_bits(mb);
            const vt_material *m = (const vt_material *)(k & ~(uintptr_t)1);
            gout g;
            mat_lanes(m, &in, k & 1, act, sp->tc, &g);
#define SEL(f) go.f = vf_select(act, g.f, go.f)
            SEL(dr), SEL(dg), SEL(db), SEL(fr), SEL(fg), SEL(fb), SEL(er), SEL(eg), SEL(eb), SEL(a2), SEL(ro);
#undef SEL
        }
        const vm act = vm_from_bits(lanes);
#define PUT(arr, v) vf_store((arr) + g0, lanes == lanes_all() ? (v) : vf_select(act, (v), vf_load((arr) + g0)))
        PUT(s.px, in.px), PUT(s.py, in.py), PUT(s.pz, in.pz);
        PUT(s.nx, in.nx), PUT(s.ny, in.ny), PUT(s.nz, in.nz);
        PUT(s.ar, go.dr), PUT(s.ag, go.dg), PUT(s.ab, go.db);
        PUT(s.fr, go.fr), PUT(s.fg, go.fg), PUT(s.fb, go.fb);
        PUT(s.er, go.er), PUT(s.eg, go.eg), PUT(s.eb, go.eb);
        PUT(s.a2, go.a2), PUT(s.ro, go.ro);
        PUT(s.sv, one0), PUT(cov, one0);
        /* without an environment: the constant ambient of before */
        PUT(s.cr, vf_fma(amb, go.dr, go.er)), PUT(s.cg, vf_fma(amb, go.dg, go.eg));
        PUT(s.cb, vf_fma(amb, go.db, go.eb));
#undef PUT
    }
    /* the ambient occlusion of what is drawn (sv, ao 0 elsewhere) */
    if (sp->n == S && sp->ao)
        for (unsigned i = 0; i < S; i += W) vf_store(s.ao + i, vf_select(vf_lt(zero0, vf_load(cov + i)), vf_loadu(sp->ao + i), zero0));
    else
        for (unsigned i = 0; i < S; i++) s.ao[i] = i < sp->n && cov[i] > 0 ? (sp->ao ? sp->ao[i] : 1.0f) : 0.0f;
    /* unit normals (interpolated ones are shorter inside a triangle),
       before the shadow lookup: its normal offset and n.l take them so */
    for (unsigned i = 0; i < S; i += W) {
        vf nx = vf_load(s.nx + i), ny = vf_load(s.ny + i), nz = vf_load(s.nz + i);
        vf in = vf_rsqrt0(dot3(nx, ny, nz, nx, ny, nz));
        vf_store(s.nx + i, vf_mul(nx, in));
        vf_store(s.ny + i, vf_mul(ny, in));
        vf_store(s.nz + i, vf_mul(nz, in));
    }
    if (sp->sh) vt_shadow_sun_n(sp->sh, S, s.px, s.py, s.pz, s.nx, s.ny, s.nz, s.sv); /* the span at once */
    const vf zero = vf_set(0), one = vf_set(1), inv_pi = vf_set(1.0f / 3.14159265f);
    for (unsigned i = 0; i < S; i += W) {
        /* towards the eye (the camera-relative origin); for orthographic
           views the same formula is close enough at a distance */
        vf px = vf_load(s.px + i), py = vf_load(s.py + i), pz = vf_load(s.pz + i);
        vf v2 = dot3(px, py, pz, px, py, pz);
        vf iv = vf_sub(zero, vf_rsqrt0(v2));
        vf_store(s.vx + i, vf_mul(px, iv));
        vf_store(s.vy + i, vf_mul(py, iv));
        vf_store(s.vz + i, vf_mul(pz, iv));
        /* V's view half, once a pixel for the sun and every light */
        vf nv = vf_abs(dot3(vf_load(s.nx + i), vf_load(s.ny + i), vf_load(s.nz + i), vf_mul(px, iv), vf_mul(py, iv),
                            vf_mul(pz, iv)));
        vf a2 = vf_load(s.a2 + i);
        vf gv = vf_add(nv, vf_sqrt(vf_fma(vf_sub(one, a2), vf_mul(nv, nv), a2)));
        vf_store(s.vv + i, vf_div(one, vf_max(gv, vf_set(1e-6f))));
        if (env) env_light(&s, sp->pe, i);
        vf_store(s.ar + i, vf_mul(vf_load(s.ar + i), inv_pi));
        vf_store(s.ag + i, vf_mul(vf_load(s.ag + i), inv_pi));
        vf_store(s.ab + i, vf_mul(vf_load(s.ab + i), inv_pi));
    }
    for (uint32_t k = 0; k < sp->nli; k++) {
        const vt_slight *L = &sp->sl[sp->li[k]];
        if (L->spot) light(&s, L, 1);
        else light(&s, L, 0);
    }
    /* fog over what is drawn (in lanes), the sky elsewhere; the picture
       is opaque */
    if (env) {
        const vt_penv *pe = sp->pe;
        if (pe->fog_density > 0) {
            const float e0 = pe->fog_falloff > 0 ? pe->fog_e0 : 1.0f;
            for (unsigned i = 0; i < S; i += W) fog_lanes(&s, pe, e0, cov, i);
        }
        span_sky(sp, s.cr, s.cg, s.cb, cov);
    }
    const vf alpha1 = vf_set(1);
    if (sp->n == S) {
        /* vt_depth_apply, W lanes at a time */
        const vf inf = vf_set(INFINITY), k = vf_set(sp->rule.k);
        for (unsigned i = 0; i < S; i += W) {
            vf c = vf_load(cov + i), z = vf_loadu(sp->near + i);
            vf d = sp->rule.ortho ? vf_sub(one, vf_mul(k, z)) : vf_div(one, z);
            vf_store(sp->depth + i, vf_select(vf_lt(zero, c), d, inf));
            store_rgba(sp->rgba + 4 * i, vf_load(s.cr + i), vf_load(s.cg + i), vf_load(s.cb + i), env ? alpha1 : c);
        }
        return;
    }
    for (unsigned i = 0; i < sp->n; i++) {
        float *o = sp->rgba + 4 * i;
        o[0] = s.cr[i];
        o[1] = s.cg[i];
        o[2] = s.cb[i];
        o[3] = env ? 1.0f : cov[i];
        float z = sp->near[i];
        sp->depth[i] = cov[i] == 0 ? INFINITY : vt_depth_apply(sp->rule, z);
    }
}

/* The light tiles' nearness ranges of one row of tiles (rows <= 16 rows
 * of near, ys apart): per tile {nearest, farthest} of what it shows, as
 * vt_tile_ranges (-FLT_MAX, FLT_MAX where it shows nothing). */
void VT_RANGES_NAME(const float *near, size_t ys, uint32_t width, uint32_t rows, float (*range)[2])
{
    const vf empty = vf_set(VT_EMPTY), huge = vf_set(FLT_MAX), zero = vf_set(0);
    uint32_t x = 0;
    for (; x + S <= width; x += S) {
        vf hi = empty, lo = huge;
        for (uint32_t y = 0; y < rows; y++)
            for (unsigned i = 0; i < S; i += W) {
                vf z = vf_loadu(near + y * ys + x + i);
                hi = vf_max(hi, z);
                lo = vf_min(lo, vf_select(vf_le(z, empty), huge, z));
            }
        range[x / S][0] = -vf_hmin(vf_sub(zero, hi));
        range[x / S][1] = vf_hmin(lo);
    }
    if (x < width) {
        float hi = -FLT_MAX, lo = FLT_MAX;
        for (uint32_t y = 0; y < rows; y++)
            for (uint32_t i = x; i < width; i++) {
                float z = near[y * ys + i];
                if (z == VT_EMPTY) continue;
                hi = z > hi ? z : hi;
                lo = z < lo ? z : lo;
            }
        range[x / S][0] = hi;
        range[x / S][1] = lo;
    }
}

#undef S
#undef A
