/*
 * vt_post_avx2.c — the post passes' rows 8 pixels a step (vt_post_kern.h):
 * the exposure histogram, FXAA's exposure + luma pass and its early exit.
 * Compiled with -mavx2 -mfma (no FMA used: the scalar rows' operations in
 * their order, so the same bits); called only after CPUID says AVX2 is
 * there (vt_post.c). Loads are contiguous: 8 RGBA pixels are 4 registers,
 * the luminance's sums come from horizontal adds (a histogram does not
 * care which lane a pixel lands in), the luma's from an 8x4 transpose.
 */
#include "vt_post_kern.h"

#if defined(__AVX2__)
#include <immintrin.h>
#include <pthread.h>
#include <string.h>

/* 0.2126 R + 0.7152 G + 0.0722 B of 8 pixels (a..d: 2 each), summed as
 * the scalar lum does: (r' + g') + (b' + 0), alpha's product forced to 0
 * (its value, NaN or inf, never counts). Lanes in pixel order 0 2 1 3 4 6
 * 5 7 (hadd's), which binning ignores. */
static inline __m256 lum8(__m256 a, __m256 b, __m256 c, __m256 d)
{
    const __m256 wt = _mm256_setr_ps(0.2126f, 0.7152f, 0.0722f, 0, 0.2126f, 0.7152f, 0.0722f, 0);
    a = _mm256_mul_ps(_mm256_blend_ps(a, _mm256_setzero_ps(), 0x88), wt);
    b = _mm256_mul_ps(_mm256_blend_ps(b, _mm256_setzero_ps(), 0x88), wt);
    c = _mm256_mul_ps(_mm256_blend_ps(c, _mm256_setzero_ps(), 0x88), wt);
    d = _mm256_mul_ps(_mm256_blend_ps(d, _mm256_setzero_ps(), 0x88), wt);
    return _mm256_hadd_ps(_mm256_hadd_ps(a, b), _mm256_hadd_ps(c, d));
}

static uint32_t hist_row(const float *p, uint32_t n, const uint32_t q[3], uint32_t (*hb)[VT_HIST_BINS], uint32_t wgt)
{
    const __m256i top = _mm256_set1_epi32(VT_HIST_BINS - 1), mant = _mm256_set1_epi32(0x7fffff);
    const __m256i q0 = _mm256_set1_epi32((int)q[0] - 1), q1 = _mm256_set1_epi32((int)q[1] - 1);
    const __m256i q2 = _mm256_set1_epi32((int)q[2] - 1), bias = _mm256_set1_epi32(127 + VT_HIST_LO);
    uint32_t x = 0;
    for (; x + 8 <= n; x += 8, p += 32) {
        __m256 L = lum8(_mm256_loadu_ps(p), _mm256_loadu_ps(p + 8), _mm256_loadu_ps(p + 16), _mm256_loadu_ps(p + 24));
        __m256i bits = _mm256_castps_si256(L), m = _mm256_and_si256(bits, mant);
        __m256i e4 = _mm256_slli_epi32(_mm256_sub_epi32(_mm256_srli_epi32(bits, 23), bias), 2);
        /* m >= q: m > q - 1, -1 a lane, subtracted (bin_of's comparisons) */
        e4 = _mm256_sub_epi32(e4, _mm256_cmpgt_epi32(m, q0));
        e4 = _mm256_sub_epi32(e4, _mm256_cmpgt_epi32(m, q1));
        e4 = _mm256_sub_epi32(e4, _mm256_cmpgt_epi32(m, q2));
        e4 = _mm256_min_epi32(e4, top); /* in range here: e4 >= 0 where L > 2^-16 */
        __m256i hi = _mm256_castps_si256(_mm256_cmp_ps(L, _mm256_set1_ps(0x1p16f), _CMP_LT_OQ)); /* NaN, inf: no */
        __m256i lo = _mm256_castps_si256(_mm256_cmp_ps(L, _mm256_set1_ps(0x1p-16f), _CMP_GT_OQ));
        e4 = _mm256_blendv_epi8(top, e4, hi);
        e4 = _mm256_and_si256(lo, e4); /* not above 2^-16 (NaN too): 0 */
        uint32_t o[8];
        _mm256_storeu_si256((__m256i *)o, e4);
        hb[0][o[0]] += wgt, hb[1][o[1]] += wgt, hb[2][o[2]] += wgt, hb[3][o[3]] += wgt;
        hb[0][o[4]] += wgt, hb[1][o[5]] += wgt, hb[2][o[6]] += wgt, hb[3][o[7]] += wgt;
    }
    return x;
}

static uint32_t prep_row(float *p, uint32_t n, float s, float *l)
{
    const __m256 sc = _mm256_setr_ps(s, s, s, 1, s, s, s, 1), zero = _mm256_setzero_ps(), big = _mm256_set1_ps(1e6f);
    const __m256i order = _mm256_setr_epi32(0, 4, 1, 5, 2, 6, 3, 7);
    uint32_t x = 0;
    for (; x + 8 <= n; x += 8, p += 32, l += 8) {
        /* 1 KiB ahead (past the row's end: harmless, the next row is
           next in memory): the hardware's stream prefetch stops at each
           4 KiB page */
        _mm_prefetch((const char *)(p + 256), _MM_HINT_T0);
        _mm_prefetch((const char *)(p + 272), _MM_HINT_T0);
        __m256 a = _mm256_mul_ps(_mm256_loadu_ps(p), sc), b = _mm256_mul_ps(_mm256_loadu_ps(p + 8), sc);
        __m256 c = _mm256_mul_ps(_mm256_loadu_ps(p + 16), sc), d = _mm256_mul_ps(_mm256_loadu_ps(p + 24), sc);
        _mm256_storeu_ps(p, a);
        _mm256_storeu_ps(p + 8, b);
        _mm256_storeu_ps(p + 16, c);
        _mm256_storeu_ps(p + 24, d);
        /* to planes, pixels 0 2 4 6 1 3 5 7 (unpack and shuffle stay in halves) */
        __m256 t0 = _mm256_unpacklo_ps(a, b), t1 = _mm256_unpackhi_ps(a, b);
        __m256 t2 = _mm256_unpacklo_ps(c, d), t3 = _mm256_unpackhi_ps(c, d);
        __m256 r = _mm256_shuffle_ps(t0, t2, 0x44), g = _mm256_shuffle_ps(t0, t2, 0xee);
        __m256 bl = _mm256_shuffle_ps(t1, t3, 0x44);
        /* max(x, 0) gives 0 for NaN (the second operand), as p > 0 ? .. : 0 */
        r = _mm256_min_ps(_mm256_max_ps(r, zero), big);
        g = _mm256_min_ps(_mm256_max_ps(g, zero), big);
        bl = _mm256_min_ps(_mm256_max_ps(bl, zero), big);
        __m256 k = _mm256_div_ps(_mm256_set1_ps(1), _mm256_add_ps(_mm256_set1_ps(1), _mm256_max_ps(_mm256_max_ps(r, g), bl)));
        __m256 y = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(_mm256_set1_ps(0.2126f), _mm256_mul_ps(r, k)),
                                               _mm256_mul_ps(_mm256_set1_ps(0.7152f), _mm256_mul_ps(g, k))),
                                 _mm256_mul_ps(_mm256_set1_ps(0.0722f), _mm256_mul_ps(bl, k)));
        _mm256_storeu_ps(l, _mm256_permutevar8x32_ps(_mm256_sqrt_ps(y), order));
    }
    return x;
}

static inline uint32_t edge8(const float *L, size_t m, size_t w)
{
    __m256 M = _mm256_loadu_ps(L + m), N = _mm256_loadu_ps(L + m - w), S = _mm256_loadu_ps(L + m + w);
    __m256 E = _mm256_loadu_ps(L + m + 1), Wl = _mm256_loadu_ps(L + m - 1);
    __m256 hi = _mm256_max_ps(_mm256_max_ps(_mm256_max_ps(M, N), _mm256_max_ps(S, E)), Wl);
    __m256 lo = _mm256_min_ps(_mm256_min_ps(_mm256_min_ps(M, N), _mm256_min_ps(S, E)), Wl);
    __m256 th = _mm256_max_ps(_mm256_set1_ps(VT_FX_EDGE_MIN), _mm256_mul_ps(hi, _mm256_set1_ps(VT_FX_EDGE)));
    return (uint32_t)_mm256_movemask_ps(_mm256_cmp_ps(_mm256_sub_ps(hi, lo), th, _CMP_GE_OQ));
}


/* ---- FXAA for 8 pixels of a row --------------------------------------------------- */

typedef __m256 vf;
typedef __m256i vi;
#define S1(v) _mm256_set1_ps(v)
#define ADD _mm256_add_ps
#define SUB _mm256_sub_ps
#define MUL _mm256_mul_ps
#define SEL(m, a, b) _mm256_blendv_ps((b), (a), (m)) /* m ? a : b */

static inline vf vabs(vf a) { return _mm256_andnot_ps(S1(-0.0f), a); }
/* mx / mn of vt_post.c: a > b ? a : b is maxps' rule, a < b ? a : b minps' */
static inline vf vmx(vf a, vf b) { return _mm256_max_ps(a, b); }
static inline vf vmn(vf a, vf b) { return _mm256_min_ps(a, b); }

static inline vi clampi(vi v, vi hi) { return _mm256_min_epi32(_mm256_max_epi32(v, _mm256_setzero_si256()), hi); }

/* luma_at: bilinear at pixel coordinates, clamped to the picture (inside
 * the clamps change nothing: the scalar path's two branches agree) */
static inline vf luma8(const vt_post_fx *fx, vf px, vf py, int clamp)
{
    vf fx0 = _mm256_floor_ps(px), fy0 = _mm256_floor_ps(py);
    vf fxr = SUB(px, fx0), fyr = SUB(py, fy0);
    vi x0 = _mm256_cvttps_epi32(fx0), y0 = _mm256_cvttps_epi32(fy0), w = _mm256_set1_epi32((int)fx->w);
    vf a, b, c, d;
    if (clamp) {
        vi one = _mm256_set1_epi32(1), wm = _mm256_set1_epi32((int)fx->w - 1), hm = _mm256_set1_epi32((int)fx->h - 1);
        vi xa = clampi(x0, wm), xb = clampi(_mm256_add_epi32(x0, one), wm);
        vi ya = _mm256_mullo_epi32(clampi(y0, hm), w), yb = _mm256_mullo_epi32(clampi(_mm256_add_epi32(y0, one), hm), w);
        a = _mm256_i32gather_ps(fx->luma, _mm256_add_epi32(ya, xa), 4);
        b = _mm256_i32gather_ps(fx->luma, _mm256_add_epi32(ya, xb), 4);
        c = _mm256_i32gather_ps(fx->luma, _mm256_add_epi32(yb, xa), 4);
        d = _mm256_i32gather_ps(fx->luma, _mm256_add_epi32(yb, xb), 4);
    } else {
        /* every tap inside: the 2 x 2 texels at one index, the base
           pointer moved for the other three */
        vi i = _mm256_add_epi32(_mm256_mullo_epi32(y0, w), x0);
        a = _mm256_i32gather_ps(fx->luma, i, 4);
        b = _mm256_i32gather_ps(fx->luma + 1, i, 4);
        c = _mm256_i32gather_ps(fx->luma + fx->w, i, 4);
        d = _mm256_i32gather_ps(fx->luma + fx->w + 1, i, 4);
    }
    vf top = ADD(a, MUL(SUB(b, a), fxr)), bot = ADD(c, MUL(SUB(d, c), fxr));
    return ADD(top, MUL(SUB(bot, top), fyr));
}

/* the texels at float offsets idx (4 (y stride + x)) compressed: clamped
 * to 0..1e6 (NaN 0), times 1 / (1 + max) */
static inline void texel8(const float *rgba, vi idx, vf q[3])
{
    vf r = _mm256_i32gather_ps(rgba, idx, 4), g = _mm256_i32gather_ps(rgba + 1, idx, 4);
    vf b = _mm256_i32gather_ps(rgba + 2, idx, 4);
    r = vmn(_mm256_max_ps(r, _mm256_setzero_ps()), S1(1e6f));
    g = vmn(_mm256_max_ps(g, _mm256_setzero_ps()), S1(1e6f));
    b = vmn(_mm256_max_ps(b, _mm256_setzero_ps()), S1(1e6f));
    vf k = _mm256_div_ps(S1(1), ADD(S1(1), vmx(vmx(r, g), b)));
    q[0] = MUL(r, k), q[1] = MUL(g, k), q[2] = MUL(b, k);
}

/* colour_at: the compressed colours bilinear, clamped to the picture */
static inline void colour8(const vt_post_fx *fx, vf px, vf py, float out[3][8])
{
    vf fx0 = _mm256_floor_ps(px), fy0 = _mm256_floor_ps(py);
    vf fxr = SUB(px, fx0), fyr = SUB(py, fy0);
    vi x0 = _mm256_cvttps_epi32(fx0), y0 = _mm256_cvttps_epi32(fy0), one = _mm256_set1_epi32(1);
    vi wm = _mm256_set1_epi32((int)fx->w - 1), hm = _mm256_set1_epi32((int)fx->h - 1);
    vi st = _mm256_set1_epi32((int)fx->stride);
    vi xa = clampi(x0, wm), xb = clampi(_mm256_add_epi32(x0, one), wm);
    vi ya = _mm256_mullo_epi32(clampi(y0, hm), st), yb = _mm256_mullo_epi32(clampi(_mm256_add_epi32(y0, one), hm), st);
    vf a[3], b[3], c[3], d[3];
    texel8(fx->rgba, _mm256_slli_epi32(_mm256_add_epi32(ya, xa), 2), a);
    texel8(fx->rgba, _mm256_slli_epi32(_mm256_add_epi32(ya, xb), 2), b);
    texel8(fx->rgba, _mm256_slli_epi32(_mm256_add_epi32(yb, xa), 2), c);
    texel8(fx->rgba, _mm256_slli_epi32(_mm256_add_epi32(yb, xb), 2), d);
    vf o[3];
    for (int k = 0; k < 3; k++) {
        vf top = ADD(a[k], MUL(SUB(b[k], a[k]), fxr)), bot = ADD(c[k], MUL(SUB(d[k], c[k]), fxr));
        o[k] = ADD(top, MUL(SUB(bot, top), fyr));
    }
    /* expanded back: c / (1 - max c) (vt_post.c's expand) */
    vf e = _mm256_div_ps(S1(1), SUB(S1(1), vmx(vmx(o[0], o[1]), o[2])));
    for (int k = 0; k < 3; k++) _mm256_storeu_ps(out[k], MUL(o[k], e));
}

/* FXAA of 8 edge pixels of row y at columns xi (lanes not in live: a
 * copy of a live lane's column, results dropped). clamp 0: every tap of
 * the search is inside the picture (fxaa_row checks the margin), the
 * clamps are skipped (they would change nothing). The 3 x 3 neighbours
 * are gathered at one index (the base pointer moved): the pixels are
 * the row's edge pixels packed, not 8 neighbours. */
static inline void fxaa8(const vt_post_fx *fx, vi xi, uint32_t y, uint32_t live, float out[3][8], int clamp)
{
    static const float step[VT_FX_STEPS] = VT_FX_STEP_LIST;
    const float *L = fx->luma + (size_t)y * fx->w;
    const ptrdiff_t w = (ptrdiff_t)fx->w;
#define TAP(d) _mm256_i32gather_ps(L + (d), xi, 4)
    vf lumaM = TAP(0);
    vf lumaS = TAP(w), lumaE = TAP(1);
    vf lumaN = TAP(-w), lumaW = TAP(-1);
    vf maxSM = vmx(lumaS, lumaM), minSM = vmn(lumaS, lumaM);
    vf maxESM = vmx(lumaE, maxSM), minESM = vmn(lumaE, minSM);
    vf maxWN = vmx(lumaN, lumaW), minWN = vmn(lumaN, lumaW);
    vf rangeMax = vmx(maxWN, maxESM), rangeMin = vmn(minWN, minESM);
    vf range = SUB(rangeMax, rangeMin);
    vf lumaNW = TAP(-w - 1), lumaSE = TAP(w + 1);
    vf lumaNE = TAP(-w + 1), lumaSW = TAP(w - 1);
#undef TAP
    vf lumaNS = ADD(lumaN, lumaS), lumaWE = ADD(lumaW, lumaE);
    vf subpixRcpRange = _mm256_div_ps(S1(1), range);
    vf subpixNSWE = ADD(lumaNS, lumaWE);
    vf edgeHorz1 = ADD(MUL(S1(-2), lumaM), lumaNS), edgeVert1 = ADD(MUL(S1(-2), lumaM), lumaWE);
    vf lumaNESE = ADD(lumaNE, lumaSE), lumaNWNE = ADD(lumaNW, lumaNE);
    vf edgeHorz2 = ADD(MUL(S1(-2), lumaE), lumaNESE), edgeVert2 = ADD(MUL(S1(-2), lumaN), lumaNWNE);
    vf lumaNWSW = ADD(lumaNW, lumaSW), lumaSWSE = ADD(lumaSW, lumaSE);
    vf edgeHorz4 = ADD(MUL(vabs(edgeHorz1), S1(2)), vabs(edgeHorz2));
    vf edgeVert4 = ADD(MUL(vabs(edgeVert1), S1(2)), vabs(edgeVert2));
    vf edgeHorz3 = ADD(MUL(S1(-2), lumaW), lumaNWSW), edgeVert3 = ADD(MUL(S1(-2), lumaS), lumaSWSE);
    vf edgeHorz = ADD(vabs(edgeHorz3), edgeHorz4), edgeVert = ADD(vabs(edgeVert3), edgeVert4);
    vf subpixNWSWNESE = ADD(lumaNWSW, lumaNESE);
    vf horz = _mm256_cmp_ps(edgeHorz, edgeVert, _CMP_GE_OQ);
    vf subpixA = ADD(MUL(subpixNSWE, S1(2)), subpixNWSWNESE);
    const vf lumaN0 = lumaN, lumaS0 = lumaS; /* before the span's choice: first_ends reads them */
    lumaN = SEL(horz, lumaN, lumaW);
    lumaS = SEL(horz, lumaS, lumaE);
    vf subpixB = SUB(MUL(subpixA, S1(1.0f / 12.0f)), lumaM);
    vf gradientN = SUB(lumaN, lumaM), gradientS = SUB(lumaS, lumaM);
    vf lumaNN = ADD(lumaN, lumaM), lumaSS = ADD(lumaS, lumaM);
    vf pairN = _mm256_cmp_ps(vabs(gradientN), vabs(gradientS), _CMP_GE_OQ);
    vf gradient = vmx(vabs(gradientN), vabs(gradientS));
    vf lengthSign = SEL(pairN, S1(-1), S1(1));
    vf subpixC = vmn(vmx(MUL(vabs(subpixB), subpixRcpRange), _mm256_setzero_ps()), S1(1));
    vf xs = _mm256_cvtepi32_ps(xi);
    vf ys = S1((float)y);
    vf ox = SEL(horz, S1(1), S1(0)), oy = SEL(horz, S1(0), S1(1));
    vf half = MUL(lengthSign, S1(0.5f));
    vf bx = SEL(horz, xs, ADD(xs, half)), by = SEL(horz, ADD(ys, half), ys);
    vf nx = SUB(bx, MUL(ox, S1(step[0]))), ny = SUB(by, MUL(oy, S1(step[0])));
    vf px = ADD(bx, MUL(ox, S1(step[0]))), py = ADD(by, MUL(oy, S1(step[0])));
    vf subpixD = ADD(MUL(S1(-2), subpixC), S1(3));
    /* The search's first taps, one pixel along the edge and half a
       pixel across, fall on texel edges inside the 3 x 3 neighbourhood:
       luma8's bilinear there is one texel plus half the difference to
       the next (the other weight is 0, which adds an exact 0), so they
       come from the registers, not 8 gathers (same bits as luma_at):
       horizontal span, N end (x - 1): NW..W or W..SW as the side is N or
       S; P end (x + 1): NE..E or E..SE; vertical span, N end (y - 1):
       NW..N or N..NE; P end (y + 1): SW..S or S..SE. */
    const vf h = S1(0.5f);
    vf hN = SEL(pairN, ADD(lumaNW, MUL(SUB(lumaW, lumaNW), h)), ADD(lumaW, MUL(SUB(lumaSW, lumaW), h)));
    vf hP = SEL(pairN, ADD(lumaNE, MUL(SUB(lumaE, lumaNE), h)), ADD(lumaE, MUL(SUB(lumaSE, lumaE), h)));
    vf vN = SEL(pairN, ADD(lumaNW, MUL(SUB(lumaN0, lumaNW), h)), ADD(lumaN0, MUL(SUB(lumaNE, lumaN0), h)));
    vf vP = SEL(pairN, ADD(lumaSW, MUL(SUB(lumaS0, lumaSW), h)), ADD(lumaS0, MUL(SUB(lumaSE, lumaS0), h)));
    vf lumaEndN = SEL(horz, hN, vN), lumaEndP = SEL(horz, hP, vP);
    vf subpixE = MUL(subpixC, subpixC);
    lumaNN = SEL(pairN, lumaNN, lumaSS);
    vf gradientScaled = MUL(gradient, S1(0.25f));
    vf halfNN = MUL(lumaNN, S1(0.5f));
    vf lumaMM = SUB(lumaM, halfNN);
    vf subpixF = MUL(subpixD, subpixE);
    vf lumaMLTZero = _mm256_cmp_ps(lumaMM, _mm256_setzero_ps(), _CMP_LT_OQ);
    lumaEndN = SUB(lumaEndN, halfNN);
    lumaEndP = SUB(lumaEndP, halfNN);
    /* lanes not live count as done (their results are dropped) */
    vf idle = _mm256_castsi256_ps(_mm256_cmpeq_epi32(
        _mm256_and_si256(_mm256_set1_epi32((int)live), _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128)),
        _mm256_setzero_si256()));
    vf doneN = _mm256_cmp_ps(vabs(lumaEndN), gradientScaled, _CMP_GE_OQ);
    vf doneP = _mm256_cmp_ps(vabs(lumaEndP), gradientScaled, _CMP_GE_OQ);
    for (int k = 1; k < VT_FX_STEPS; k++) {
        nx = SEL(doneN, nx, SUB(nx, MUL(ox, S1(step[k]))));
        ny = SEL(doneN, ny, SUB(ny, MUL(oy, S1(step[k]))));
        px = SEL(doneP, px, ADD(px, MUL(ox, S1(step[k]))));
        py = SEL(doneP, py, ADD(py, MUL(oy, S1(step[k]))));
        /* the last step is a guess, unsampled */
        if (k == VT_FX_STEPS - 1 || _mm256_movemask_ps(_mm256_or_ps(_mm256_and_ps(doneN, doneP), idle)) == 0xff) break;
        lumaEndN = SEL(doneN, lumaEndN, SUB(luma8(fx, nx, ny, clamp), halfNN));
        lumaEndP = SEL(doneP, lumaEndP, SUB(luma8(fx, px, py, clamp), halfNN));
        doneN = _mm256_cmp_ps(vabs(lumaEndN), gradientScaled, _CMP_GE_OQ);
        doneP = _mm256_cmp_ps(vabs(lumaEndP), gradientScaled, _CMP_GE_OQ);
    }
    vf dstN = SEL(horz, SUB(xs, nx), SUB(ys, ny));
    vf dstP = SEL(horz, SUB(px, xs), SUB(py, ys));
    vf goodSpanN = _mm256_xor_ps(_mm256_cmp_ps(lumaEndN, _mm256_setzero_ps(), _CMP_LT_OQ), lumaMLTZero);
    vf goodSpanP = _mm256_xor_ps(_mm256_cmp_ps(lumaEndP, _mm256_setzero_ps(), _CMP_LT_OQ), lumaMLTZero);
    vf spanLengthRcp = _mm256_div_ps(S1(1), ADD(dstP, dstN));
    vf directionN = _mm256_cmp_ps(dstN, dstP, _CMP_LT_OQ);
    vf dst = vmn(dstN, dstP);
    vf goodSpan = SEL(directionN, goodSpanN, goodSpanP);
    vf subpixG = MUL(subpixF, subpixF);
    vf pixelOffset = ADD(MUL(dst, _mm256_xor_ps(spanLengthRcp, S1(-0.0f))), S1(0.5f));
    vf subpixH = MUL(subpixG, S1(VT_FX_SUBPIX));
    vf pixelOffsetGood = _mm256_and_ps(goodSpan, pixelOffset);
    vf pixelOffsetSubpix = vmx(pixelOffsetGood, subpixH);
    vf move = MUL(pixelOffsetSubpix, lengthSign);
    vf ux = SEL(horz, xs, ADD(xs, move)), uy = SEL(horz, ADD(ys, move), ys);
    colour8(fx, ux, uy, out);
}

/* The n (1..8) packed columns q[0..n) of row y through fxaa8, their
 * results appended to o; the count. The margin test is per batch: its
 * columns rise, so the first and the last bound it. */
static uint32_t fxaa_batch(const vt_post_fx *fx, uint32_t y, const uint32_t *q, uint32_t n, vt_post_fx_out *o)
{
    uint32_t xs[8];
    for (uint32_t k = 0; k < 8; k++) xs[k] = q[k < n ? k : n - 1];
    float c[3][8];
    /* the search reaches 8.5 pixels along an edge (its sampled steps), a
       tap 1 further and half a pixel across: a margin of 12 keeps every
       tap inside */
    vi xi = _mm256_loadu_si256((const __m256i *)(const void *)xs);
    uint32_t live = (1u << n) - 1;
    if (xs[0] >= 12 && xs[7] + 12 < fx->w && y >= 12 && y + 12 < fx->h) fxaa8(fx, xi, y, live, c, 0);
    else fxaa8(fx, xi, y, live, c, 1);
    for (uint32_t k = 0; k < n; k++) o[k] = (vt_post_fx_out){.i = y * fx->w + xs[k], .c = {c[0][k], c[1][k], c[2][k]}};
    return n;
}

/* The early exit 8 pixels a step; the pixels past it packed 8 to a
 * batch (a city frame's edge pixels are a fifth of its pixels but come
 * scattered: FXAA on each 8 neighbours with any edge ran its search for
 * all 8 lanes, most of them idle). */
/* pack[m]: the lanes set in m, in order, a byte each (the rest 0) */
static uint64_t pack[256];

static void pack_init(void)
{
    for (uint32_t m = 0; m < 256; m++) {
        uint64_t v = 0;
        for (uint32_t k = 0, n = 0; k < 8; k++)
            if (m >> k & 1) v |= (uint64_t)k << (8 * n++);
        pack[m] = v;
    }
}

static uint32_t fxaa_row(const vt_post_fx *fx, uint32_t y, vt_post_fx_out *o, uint32_t *x_end)
{
    const size_t w = fx->w;
    uint32_t no = 0, x = 1, q[24], nq = 0;
    for (; x + 9 <= w; x += 8) {
        uint32_t bits = edge8(fx->luma, (size_t)y * w + x, w);
        /* the survivors' columns appended in one store (a loop over the
           bits cost a mispredicted branch a group) */
        __m256i k = _mm256_cvtepu8_epi32(_mm_loadl_epi64((const __m128i *)(const void *)&pack[bits]));
        _mm256_storeu_si256((__m256i *)(void *)(q + nq), _mm256_add_epi32(k, _mm256_set1_epi32((int)x)));
        nq += (uint32_t)__builtin_popcount(bits);
        if (nq >= 8) {
            no += fxaa_batch(fx, y, q, 8, o + no);
            nq -= 8;
            memcpy(q, q + 8, nq * sizeof *q);
        }
    }
    if (nq) no += fxaa_batch(fx, y, q, nq, o + no);
    *x_end = x;
    return no;
}

vt_post_kern vt_post_kern_avx2(void)
{
    static pthread_once_t once = PTHREAD_ONCE_INIT;
    pthread_once(&once, pack_init);
    return (vt_post_kern){hist_row, prep_row, fxaa_row};
}
#else
vt_post_kern vt_post_kern_avx2(void)
{
    return (vt_post_kern){0};
}
#endif
