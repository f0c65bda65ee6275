/*
 * vt_shadow_tiles.c — the shadow maps' footprint tiles (vt_shadow_tiles.h),
 * made by vt_shadow.c's raster threads after they draw.
 *
 * The span lookup (vt_shadow.inl) decides a pixel without its 16 taps
 * where its footprint's depth range is wholly below or above its
 * reference: each cascade's (size / TS)^2 tiles t hold the least and the
 * greatest depth of the map over texels TS (t - 1) .. TS (t + 2) - 1 (both
 * axes; a 4 x 4 footprint starting at x0 lies in tile floor((x0 + 1) / 2)'s:
 * 6 x 6 texels, tight enough for the far cascades' texels of metres,
 * where 12 x 12 left most lookups undecided). Made in two steps: each
 * raster thread its bands' TS x TS tiles (the dirty columns read, the
 * rest -FLT_MAX), then the 3 x 3 dilation. Cost: one more read of the
 * drawn texels (about 1 instruction a texel) and about 3 a tile; 8 MB at
 * 720p (16 with the raw tiles).
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

/* Band k's TS x TS tiles of map m (size sz; texels outside columns
 * x0..x1 are -FLT_MAX) into the raw minima lo and maxima hi. */
void vt_shadow_tiles_band(float *lo, float *hi, const float *m, uint32_t sz, uint32_t k, uint32_t x0, uint32_t x1)
{
    /* whole groups of 4 tiles (g = sz / 2 is a multiple of 32) */
    const uint32_t g = sz / TS, t0 = x0 <= x1 ? x0 / TS / 4 * 4 : g, t1 = x0 <= x1 ? (x1 / TS) | 3u : 0;
    for (uint32_t ty = k * (BAND / TS); ty < (k + 1) * (BAND / TS) && ty < g; ty++) {
        float *l = lo + (size_t)ty * g, *h = hi + (size_t)ty * g;
        const uint32_t e0 = t0 < g ? t0 : g, e1 = t1 + 1 < g ? t1 + 1 : g;
        vt_shadow_fill_lowest(l, e0), vt_shadow_fill_lowest(h, e0);
        if (e1 > e0) vt_shadow_fill_lowest(l + e1, g - e1), vt_shadow_fill_lowest(h + e1, g - e1);
        const float *r0 = m + (size_t)TS * ty * sz, *r1 = r0 + sz;
        for (uint32_t t = t0; t <= t1 && t < g; t += 4) {
#ifdef __SSE2__
            const uint32_t x = TS * t;
            __m128 a = _mm_loadu_ps(r0 + x), b = _mm_loadu_ps(r1 + x), c = _mm_loadu_ps(r0 + x + 4),
                   d = _mm_loadu_ps(r1 + x + 4);
            __m128 l1 = _mm_min_ps(a, b), l2 = _mm_min_ps(c, d), h1 = _mm_max_ps(a, b), h2 = _mm_max_ps(c, d);
            _mm_storeu_ps(l + t, _mm_min_ps(_mm_shuffle_ps(l1, l2, _MM_SHUFFLE(2, 0, 2, 0)),
                                            _mm_shuffle_ps(l1, l2, _MM_SHUFFLE(3, 1, 3, 1))));
            _mm_storeu_ps(h + t, _mm_max_ps(_mm_shuffle_ps(h1, h2, _MM_SHUFFLE(2, 0, 2, 0)),
                                            _mm_shuffle_ps(h1, h2, _MM_SHUFFLE(3, 1, 3, 1))));
#else
            for (uint32_t u = t; u < t + 4; u++) {
                const uint32_t x = TS * u;
                l[u] = min2(min2(r0[x], r0[x + 1]), min2(r1[x], r1[x + 1]));
                h[u] = max2(max2(r0[x], r0[x + 1]), max2(r1[x], r1[x + 1]));
            }
#endif
        }
    }
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

/* Tile row ty of cascade c: the raw tiles' 3 x 3 minima and maxima
 * (clipped at the map's sides) over the columns the rows' bands wrote,
 * packed. */
void vt_shadow_tiles_row(const float *raw_all, uint32_t *tiles, size_t plane, uint32_t sz, uint32_t c, uint32_t ty,
                         uint32_t lo, uint32_t hi, float qlo, float qinv)
{
    const uint32_t g = sz / TS;
    float w[2048 / TS + 2], res[2][2048 / TS];
    uint32_t *o = tiles + (size_t)c * g * g + (size_t)ty * g;
    const uint32_t empty = pack1(-FLT_MAX, -FLT_MAX, qlo, qinv);
    if (lo > hi) {
        fill_u32(o, g, empty);
        return;
    }
    /* tiles x0..x1 (whole 4s) see raw tiles x0 - 1 .. x1 + 1 */
    const uint32_t x0 = lo / TS >= 1 ? (lo / TS - 1) / 4 * 4 : 0,
                   x1 = (hi / TS + 1) / 4 * 4 + 3 < g ? (hi / TS + 1) / 4 * 4 + 3 : g - 1;
    for (int mx = 0; mx < 2; mx++) {
        const float *raw = raw_all + mx * plane + (size_t)c * g * g;
        const float *r0 = raw + (size_t)(ty ? ty - 1 : ty) * g, *r1 = raw + (size_t)ty * g,
                    *r2 = raw + (size_t)(ty + 1 < g ? ty + 1 : ty) * g;
        float *v = w + 1, *oo = res[mx];
        uint32_t x = x0;
#ifdef __SSE2__
        /* x0 and x1 + 1 are multiples of 4 */
        if (mx)
            for (; x + 4 <= x1 + 1; x += 4)
                _mm_storeu_ps(v + x, _mm_max_ps(_mm_max_ps(_mm_loadu_ps(r0 + x), _mm_loadu_ps(r1 + x)),
                                                _mm_loadu_ps(r2 + x)));
        else
            for (; x + 4 <= x1 + 1; x += 4)
                _mm_storeu_ps(v + x, _mm_min_ps(_mm_min_ps(_mm_loadu_ps(r0 + x), _mm_loadu_ps(r1 + x)),
                                                _mm_loadu_ps(r2 + x)));
#endif
        for (; x <= x1; x++) v[x] = mx ? max2(max2(r0[x], r1[x]), r2[x]) : min2(min2(r0[x], r1[x]), r2[x]);
        /* the map's sides clip; inside, what lies beyond x0..x1 is empty */
        v[(int)x0 - 1] = x0 ? -FLT_MAX : v[0];
        v[x1 + 1] = x1 + 1 < g ? -FLT_MAX : v[g - 1];
        x = x0;
#ifdef __SSE2__
        if (mx)
            for (; x + 4 <= x1 + 1; x += 4)
                _mm_storeu_ps(oo + x, _mm_max_ps(_mm_max_ps(_mm_loadu_ps(v + x - 1), _mm_loadu_ps(v + x)),
                                                 _mm_loadu_ps(v + x + 1)));
        else
            for (; x + 4 <= x1 + 1; x += 4)
                _mm_storeu_ps(oo + x, _mm_min_ps(_mm_min_ps(_mm_loadu_ps(v + x - 1), _mm_loadu_ps(v + x)),
                                                 _mm_loadu_ps(v + x + 1)));
#endif
        for (; x <= x1; x++)
            oo[x] = mx ? max2(max2(v[x - 1], v[x]), v[x + 1]) : min2(min2(v[x - 1], v[x]), v[x + 1]);
    }
    fill_u32(o, x0, empty);
    fill_u32(o + x1 + 1, g - 1 - x1, empty);
    uint32_t x = x0;
#ifdef __SSE2__
    /* pack1, four tiles a step (the same float operations; min and max
       order their operands so a NaN takes pack1's way) */
    const __m128 vlo = _mm_set1_ps(qlo), vinv = _mm_set1_ps(qinv), amax = _mm_set1_ps(65535.0f),
                 one = _mm_set1_ps(1.0f), bmin = _mm_set1_ps(-1.0f), bmax = _mm_set1_ps(65533.0f);
    for (; x + 4 <= x1 + 1; x += 4) {
        __m128 a = _mm_mul_ps(_mm_sub_ps(_mm_loadu_ps(res[0] + x), vlo), vinv);
        __m128 b = _mm_mul_ps(_mm_sub_ps(_mm_loadu_ps(res[1] + x), vlo), vinv);
        a = _mm_max_ps(_mm_min_ps(amax, a), one);  /* minps(amax, NaN): NaN; maxps(NaN, one): 1 */
        b = _mm_min_ps(_mm_max_ps(bmin, b), bmax); /* maxps(bmin, NaN): NaN; minps(NaN, bmax): 65533 */
        __m128i qa = _mm_sub_epi32(_mm_cvttps_epi32(a), _mm_set1_epi32(1));
        __m128i qb = _mm_add_epi32(_mm_cvttps_epi32(b), _mm_set1_epi32(2));
        _mm_storeu_si128((__m128i *)(o + x), _mm_or_si128(qa, _mm_slli_epi32(qb, 16)));
    }
#endif
    for (; x <= x1; x++) o[x] = pack1(res[0][x], res[1][x], qlo, qinv);
}
