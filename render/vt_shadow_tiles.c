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
 *      read, the rest empty; four tiles a step from three loads a row);
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

/* Row r's range over tile s's 5 columns 2s - 1 .. 2s + 3 (clipped to
 * the map's sz texels). */
static inline void win5(const float *r, uint32_t sz, uint32_t s, float *lo, float *hi)
{
    const uint32_t a = s ? TS * s - 1 : 0, b = TS * s + 3 < sz ? TS * s + 3 : sz - 1;
    float l = r[a], h = r[a];
    for (uint32_t x = a + 1; x <= b; x++) l = min2(l, r[x]), h = max2(h, r[x]);
    *lo = l, *hi = h;
}

#ifdef __SSE2__
/* win5 of tiles s .. s + 3 (s >= 1, 2s + 9 < sz): columns 2s - 2 .. 2s
 * + 9 in three loads, their even and odd texels apart; tile s + i's
 * window is odd texel i and pairs i + 1, i + 2. */
static inline void win5x4(const float *r, uint32_t s, __m128 *lo, __m128 *hi)
{
    const float *q = r + TS * s - 2;
    const __m128 l0 = _mm_loadu_ps(q), l1 = _mm_loadu_ps(q + 4), l2 = _mm_loadu_ps(q + 8);
    const __m128 e03 = _mm_shuffle_ps(l0, l1, _MM_SHUFFLE(2, 0, 2, 0)), o03 = _mm_shuffle_ps(l0, l1, _MM_SHUFFLE(3, 1, 3, 1));
    const __m128 e25 = _mm_shuffle_ps(l1, l2, _MM_SHUFFLE(2, 0, 2, 0)), o25 = _mm_shuffle_ps(l1, l2, _MM_SHUFFLE(3, 1, 3, 1));
    __m128 m03 = _mm_min_ps(e03, o03), m25 = _mm_min_ps(e25, o25);
    *lo = _mm_min_ps(_mm_min_ps(o03, _mm_shuffle_ps(m03, m25, _MM_SHUFFLE(2, 1, 2, 1))), m25);
    m03 = _mm_max_ps(e03, o03), m25 = _mm_max_ps(e25, o25);
    *hi = _mm_max_ps(_mm_max_ps(o03, _mm_shuffle_ps(m03, m25, _MM_SHUFFLE(2, 1, 2, 1))), m25);
}
#endif

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
#ifdef __SSE2__
    const __m128 vlo = _mm_set1_ps(qlo), vinv = _mm_set1_ps(qinv);
#endif
    for (uint32_t ty = k * (BAND / TS); ty < (k + 1) * (BAND / TS) && ty < g; ty++) {
        uint32_t *p = P + (size_t)ty * g, *o = O + (size_t)ty * g;
        if (s0 > s1) {
            fill_u32(p, g, EMPTY), fill_u32(o, g, EMPTY);
            continue;
        }
        fill_u32(p, s0, EMPTY), fill_u32(o, s0, EMPTY);
        fill_u32(p + s1 + 1, g - 1 - s1, EMPTY), fill_u32(o + s1 + 1, g - 1 - s1, EMPTY);
        const float *r0 = m + (size_t)TS * ty * sz, *r1 = r0 + sz;
        uint32_t s = s0;
        if (!s) { /* tile 0's window stops at the map's side */
            float l0, h0, l1, h1;
            win5(r0, sz, 0, &l0, &h0);
            win5(r1, sz, 0, &l1, &h1);
            p[0] = pack1(min2(l0, l1), max2(h0, h1), qlo, qinv);
            o[0] = pack1(l1, h1, qlo, qinv);
            s = 1;
        }
#ifdef __SSE2__
        /* four tiles a step away from the map's sides; a step past s1
           reads only cleared texels (-FLT_MAX), so the tiles it writes
           there are the empty ones the fill put */
        for (; s <= s1 && s + 5 <= g; s += 4) {
            __m128 l0, h0, l1, h1;
            win5x4(r0, s, &l0, &h0);
            win5x4(r1, s, &l1, &h1);
            _mm_storeu_si128((__m128i *)(p + s), pack4(_mm_min_ps(l0, l1), _mm_max_ps(h0, h1), vlo, vinv));
            _mm_storeu_si128((__m128i *)(o + s), pack4(l1, h1, vlo, vinv));
        }
#endif
        for (; s <= s1; s++) {
            float l0, h0, l1, h1;
            win5(r0, sz, s, &l0, &h0);
            win5(r1, sz, s, &l1, &h1);
            p[s] = pack1(min2(l0, l1), max2(h0, h1), qlo, qinv);
            o[s] = pack1(l1, h1, qlo, qinv);
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
