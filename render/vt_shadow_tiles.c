/*
 * vt_shadow_tiles.c — the shadow maps' footprint tiles (vt_shadow_tiles.h),
 * made by vt_shadow.c's raster threads after they draw.
 *
 * The span lookup (vt_shadow.inl) decides a pixel without its 16 taps
 * where its footprint's depth range is wholly below or above its
 * reference: each cascade's (size / TS)^2 tiles t hold the least and the
 * greatest depth of the map over texels TS t - 1 .. TS t + 3 (both axes;
 * a 4 x 4 footprint starting at x0 lies in tile floor((x0 + 1) / 2)'s:
 * x0 is 2t - 1 or 2t, so 5 x 5 texels are the two footprints' union.
 * The 6 x 6 of 3 x 3 whole 2 x 2 tiles left twice as many lookups to
 * their taps on the city: a sloped surface's depth moves over the sixth
 * texel). Made in two steps:
 *   1. each raster thread, for its bands' rows, per tile the range over
 *      the 5 columns TS s - 1 .. TS s + 3 of its two rows (P) and of its
 *      second row alone (O), packed as the tiles are (the dirty columns
 *      read, the rest empty);
 *   2. per tile row, O of the row above, P of the row and of the row
 *      below: the 5 rows TS t - 1 .. TS t + 3.
 * The parts are packed with pack1's margins, and their union's bounds
 * are the least and the greatest of theirs: as tight as packing the
 * union (the part that holds the union's least depth gives the same
 * lower bound). Cost: one more read of the drawn texels (about 1
 * instruction a texel) and about 4 a tile; 8 MB at 720p (16 with the
 * parts).
 */

#include "vt_shadow_tiles.h"
#include "vt_shadow.h"

#include <float.h>
#include <stddef.h>
#ifdef __SSE2__
#include <emmintrin.h>
#endif

#define TS ((uint32_t)VT_SHADOW_TILE)
#define BAND VT_SHADOW_BAND

/* n floats at r to -FLT_MAX (the clear: GCC -O2 leaves the plain loop
 * one store a texel, 16 M instructions a city frame). */
void vt_shadow_fill_lowest(float *r, uint32_t n)
{
    uint32_t i = 0;
#ifdef __SSE2__
    const __m128 v = _mm_set1_ps(-FLT_MAX);
    for (; i + 16 <= n; i += 16) {
        _mm_storeu_ps(r + i, v);
        _mm_storeu_ps(r + i + 4, v);
        _mm_storeu_ps(r + i + 8, v);
        _mm_storeu_ps(r + i + 12, v);
    }
    for (; i + 4 <= n; i += 4) _mm_storeu_ps(r + i, v);
#endif
    for (; i < n; i++) r[i] = -FLT_MAX;
}

/* n packed tiles at o to v (SSE2: four stores a step, as vt_shadow_fill_lowest). */
static void fill_u32(uint32_t *o, uint32_t n, uint32_t v)
{
    uint32_t i = 0;
#ifdef __SSE2__
    const __m128i q = _mm_set1_epi32((int)v);
    for (; i + 16 <= n; i += 16) {
        _mm_storeu_si128((__m128i *)(o + i), q);
        _mm_storeu_si128((__m128i *)(o + i + 4), q);
        _mm_storeu_si128((__m128i *)(o + i + 8), q);
        _mm_storeu_si128((__m128i *)(o + i + 12), q);
    }
    for (; i + 4 <= n; i += 4) _mm_storeu_si128((__m128i *)(o + i), q);
#endif
    for (; i < n; i++) o[i] = v;
}

/* The packed tile of depth range lo..hi (vt_shadow_tiles.h): the range
 * widened to whole steps and one more each side, so that the float
 * rounding of this and of the lookup's (dref - qlo) qinv (each well
 * under 0.1 of a step at 65536) never narrows it; a NaN gives the
 * unknown range (0, 65535). */
static inline uint32_t pack1(float lo, float hi, float qlo, float qinv)
{
    float a = (lo - qlo) * qinv, b = (hi - qlo) * qinv;
    a = a > 1.0f ? a : 1.0f, a = a < 65535.0f ? a : 65535.0f;   /* NaN: 1 */
    b = b < 65533.0f ? b : 65533.0f, b = b > -1.0f ? b : -1.0f; /* NaN: 65533 */
    return (uint32_t)((int32_t)a - 1) | (uint32_t)((int32_t)b + 2) << 16;
}

#ifdef __SSE2__
/* pack1 of four ranges (the same float operations; min and max order
   their operands so a NaN takes pack1's way) */
static inline __m128i pack4(__m128 lo, __m128 hi, __m128 vlo, __m128 vinv)
{
    const __m128 amax = _mm_set1_ps(65535.0f), one = _mm_set1_ps(1.0f), bmin = _mm_set1_ps(-1.0f),
                 bmax = _mm_set1_ps(65533.0f);
    __m128 a = _mm_mul_ps(_mm_sub_ps(lo, vlo), vinv), b = _mm_mul_ps(_mm_sub_ps(hi, vlo), vinv);
    a = _mm_max_ps(_mm_min_ps(amax, a), one);  /* minps(amax, NaN): NaN; maxps(NaN, one): 1 */
    b = _mm_min_ps(_mm_max_ps(bmin, b), bmax); /* maxps(bmin, NaN): NaN; minps(NaN, bmax): 65533 */
    __m128i qa = _mm_sub_epi32(_mm_cvttps_epi32(a), _mm_set1_epi32(1));
    __m128i qb = _mm_add_epi32(_mm_cvttps_epi32(b), _mm_set1_epi32(2));
    return _mm_or_si128(qa, _mm_slli_epi32(qb, 16));
}
#endif

/* The empty tile: pack1 of -FLT_MAX (no caster: every tap passes). */
#define EMPTY ((uint32_t)1 << 16)

/* x's bounds and y's together: the least lower bound, the greatest upper. */
static inline uint32_t join(uint32_t x, uint32_t y)
{
    uint32_t a = x & 0xffffu, b = y & 0xffffu, c = x >> 16, d = y >> 16;
    return (a < b ? a : b) | (c > d ? c : d) << 16;
}

/* Band k's parts of map m (size sz; texels outside columns x0..x1 are
 * -FLT_MAX), quantised by qlo, qinv: P over each tile's two rows, O over
 * its second row, both over the 5 columns 2s - 1 .. 2s + 3 (clipped to
 * the map); tiles that see no column of x0..x1 empty. */
void vt_shadow_tiles_band(uint32_t *P, uint32_t *O, const float *m, uint32_t sz, uint32_t k, uint32_t x0, uint32_t x1,
                          float qlo, float qinv)
{
    const uint32_t g = sz / TS;
    /* tiles s0..s1 see a written column: 2s + 3 >= x0 and 2s - 1 <= x1 */
    uint32_t s0 = g, s1 = 0;
    if (x0 <= x1) s0 = x0 >= 3 ? (x0 - 2) / 2 : 0, s1 = (x1 + 1) / 2 < g ? (x1 + 1) / 2 : g - 1;
    /* per block s (at index s + 1): its 2 x 2 texels' bounds (bl, bh),
       its second column's (cl, ch), its second row's (rl, rh) and its
       second row's second texel (ql, qh) */
    enum { N = 2048 / TS + 2 };
    float bl[N], bh[N], cl[N], ch[N], rl[N], rh[N], ql[N], qh[N];
    for (uint32_t ty = k * (BAND / TS); ty < (k + 1) * (BAND / TS) && ty < g; ty++) {
        uint32_t *p = P + (size_t)ty * g, *o = O + (size_t)ty * g;
        if (s0 > s1) {
            fill_u32(p, g, EMPTY), fill_u32(o, g, EMPTY);
            continue;
        }
        fill_u32(p, s0, EMPTY), fill_u32(o, s0, EMPTY);
        fill_u32(p + s1 + 1, g - 1 - s1, EMPTY), fill_u32(o + s1 + 1, g - 1 - s1, EMPTY);
        const float *r0 = m + (size_t)TS * ty * sz, *r1 = r0 + sz;
        /* the blocks s0 - 1 .. s1 + 1 (clipped to the map) */
        const uint32_t a0 = s0 ? s0 - 1 : 0, a1 = s1 + 1 < g ? s1 + 1 : s1;
        uint32_t s = a0;
#ifdef __SSE2__
        /* four blocks a step: the rows' even and odd texels apart */
        for (; s + 4 <= a1 + 1; s += 4) {
            const __m128 a = _mm_loadu_ps(r0 + TS * s), c = _mm_loadu_ps(r0 + TS * s + 4), b = _mm_loadu_ps(r1 + TS * s),
                         d = _mm_loadu_ps(r1 + TS * s + 4);
            const __m128 e0 = _mm_shuffle_ps(a, c, _MM_SHUFFLE(2, 0, 2, 0)), o0 = _mm_shuffle_ps(a, c, _MM_SHUFFLE(3, 1, 3, 1));
            const __m128 e1 = _mm_shuffle_ps(b, d, _MM_SHUFFLE(2, 0, 2, 0)), o1 = _mm_shuffle_ps(b, d, _MM_SHUFFLE(3, 1, 3, 1));
            const __m128 l1 = _mm_min_ps(e1, o1), h1 = _mm_max_ps(e1, o1);
            _mm_storeu_ps(rl + s + 1, l1), _mm_storeu_ps(rh + s + 1, h1);
            _mm_storeu_ps(bl + s + 1, _mm_min_ps(_mm_min_ps(e0, o0), l1));
            _mm_storeu_ps(bh + s + 1, _mm_max_ps(_mm_max_ps(e0, o0), h1));
            _mm_storeu_ps(cl + s + 1, _mm_min_ps(o0, o1)), _mm_storeu_ps(ch + s + 1, _mm_max_ps(o0, o1));
            _mm_storeu_ps(ql + s + 1, o1), _mm_storeu_ps(qh + s + 1, o1);
        }
#endif
        for (; s <= a1; s++) {
            const float e0 = r0[TS * s], e1 = r0[TS * s + 1], f0 = r1[TS * s], f1 = r1[TS * s + 1];
            rl[s + 1] = min2(f0, f1), rh[s + 1] = max2(f0, f1);
            bl[s + 1] = min2(min2(e0, e1), rl[s + 1]), bh[s + 1] = max2(max2(e0, e1), rh[s + 1]);
            cl[s + 1] = min2(e1, f1), ch[s + 1] = max2(e1, f1);
            ql[s + 1] = qh[s + 1] = f1;
        }
        /* past the map's sides: nothing (each bound's neutral value) */
        if (!s0) cl[0] = ql[0] = FLT_MAX, ch[0] = qh[0] = -FLT_MAX;
        if (s1 + 1 >= g) bl[g + 1] = rl[g + 1] = FLT_MAX, bh[g + 1] = rh[g + 1] = -FLT_MAX;
        /* tile s: columns 2s - 1 (block s - 1's second), 2s .. 2s + 1
           (block s), 2s + 2 .. 2s + 3 (block s + 1) */
        s = s0;
#ifdef __SSE2__
        const __m128 vlo = _mm_set1_ps(qlo), vinv = _mm_set1_ps(qinv);
#define MN3(x, y) _mm_min_ps(_mm_min_ps(_mm_loadu_ps(x + s), _mm_loadu_ps(y + s + 1)), _mm_loadu_ps(y + s + 2))
#define MX3(x, y) _mm_max_ps(_mm_max_ps(_mm_loadu_ps(x + s), _mm_loadu_ps(y + s + 1)), _mm_loadu_ps(y + s + 2))
        for (; s + 4 <= s1 + 1; s += 4) {
            _mm_storeu_si128((__m128i *)(p + s), pack4(MN3(cl, bl), MX3(ch, bh), vlo, vinv));
            _mm_storeu_si128((__m128i *)(o + s), pack4(MN3(ql, rl), MX3(qh, rh), vlo, vinv));
        }
#undef MN3
#undef MX3
#endif
        for (; s <= s1; s++) {
            p[s] = pack1(min2(min2(cl[s], bl[s + 1]), bl[s + 2]), max2(max2(ch[s], bh[s + 1]), bh[s + 2]), qlo, qinv);
            o[s] = pack1(min2(min2(ql[s], rl[s + 1]), rl[s + 2]), max2(max2(qh[s], rh[s + 1]), rh[s + 2]), qlo, qinv);
        }
    }
}

/* Tile row ty of cascade c: O of the row above, P of the row and of the
 * row below (clipped at the map's sides) joined, over the tiles that see
 * the columns the rows' bands wrote (lo..hi; lo > hi: none). */
void vt_shadow_tiles_row(const uint32_t *P, const uint32_t *O, uint32_t *tiles, uint32_t sz, uint32_t c, uint32_t ty,
                         uint32_t lo, uint32_t hi)
{
    const uint32_t g = sz / TS;
    const size_t base = (size_t)c * g * g;
    uint32_t *o = tiles + base + (size_t)ty * g;
    if (lo > hi) {
        fill_u32(o, g, EMPTY);
        return;
    }
    const uint32_t s0 = lo >= 3 ? (lo - 2) / 2 : 0, s1 = (hi + 1) / 2 < g ? (hi + 1) / 2 : g - 1;
    fill_u32(o, s0, EMPTY);
    fill_u32(o + s1 + 1, g - 1 - s1, EMPTY);
    const uint32_t *a = ty ? O + base + (size_t)(ty - 1) * g : NULL, *b = P + base + (size_t)ty * g,
                   *d = ty + 1 < g ? P + base + (size_t)(ty + 1) * g : NULL;
    uint32_t s = s0;
#ifdef __SSE2__
    /* four tiles a step: the lower bounds' least and the upper's
       greatest as 16-bit lanes (SSE2's are signed: biased by 0x8000) */
    const __m128i bias = _mm_set1_epi16((short)0x8000), lows = _mm_set1_epi32(0xffff);
    for (; s + 4 <= s1 + 1; s += 4) {
        __m128i t = _mm_xor_si128(_mm_loadu_si128((const __m128i *)(b + s)), bias), mn = t, mx = t;
        if (a) {
            __m128i u = _mm_xor_si128(_mm_loadu_si128((const __m128i *)(a + s)), bias);
            mn = _mm_min_epi16(mn, u), mx = _mm_max_epi16(mx, u);
        }
        if (d) {
            __m128i u = _mm_xor_si128(_mm_loadu_si128((const __m128i *)(d + s)), bias);
            mn = _mm_min_epi16(mn, u), mx = _mm_max_epi16(mx, u);
        }
        t = _mm_or_si128(_mm_and_si128(mn, lows), _mm_andnot_si128(lows, mx));
        _mm_storeu_si128((__m128i *)(o + s), _mm_xor_si128(t, bias));
    }
#endif
    for (; s <= s1; s++) {
        uint32_t t = b[s];
        if (a) t = join(t, a[s]);
        if (d) t = join(t, d[s]);
        o[s] = t;
    }
}
