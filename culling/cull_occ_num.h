/*
 * cull_occ_num.h — what cull_occ.c (buffers, projection, rectangle tests)
 * and cull_occ_raster.inl (rasterisation) share inside the occlusion
 * buffer: the pixel values that mean "no occluder" and "padding", the
 * tiles' states, a tile's taking of its pixels' slot in the pool, and the
 * inlined double helpers whose NaN and overflow rules the conservative
 * bounds rely on. Private to those two files
 * (cull_occ.h is the layout the query and the ISA loops see; these names
 * are too short to share with them).
 */
#ifndef VANTAGE_CULL_OCC_NUM_H
#define VANTAGE_CULL_OCC_NUM_H

#include <float.h>
#include <stdbool.h>
#include <stdint.h>
#ifdef __SSE2__
#include <immintrin.h>
#endif

#include "cull_occ.h"

#define EMPTY (-FLT_MAX)
enum { TILE_INVALID = 0, TILE_CLEAN = 1, TILE_DIRTY = 2 }; /* pixels stale / minimum current / written since */
#define PAD FLT_MAX

/* libm's fmin, fmax, floor and ceil are calls on baseline x86-64 (NaN
 * and errno rules); these are inlined. They do not order NaN (dmin(x, NaN)
 * is NaN, dmin(NaN, x) is x): every caller keeps NaN out first (the
 * isfin() checks below), because a NaN bound dropped silently would mark
 * pixels the occluder does not cover, a wrong cull. */
static inline double dmin(double a, double b) { return a < b ? a : b; }
static inline double dmax(double a, double b) { return a > b ? a : b; }
static inline float fmin_(float a, float b) { return a < b ? a : b; }
/* neither infinite nor NaN (no libm call, no errno) */
static inline bool isfin(double x) { return x - x == 0; }
/* floor and ceil of pixel indices: x is clamped to +-2^30 first, so the
 * result and the result +- 1 fit an int (buffers are <= 8192 pixels) and
 * every (int) cast of them is defined; NaN (never passed) gives -2^30,
 * not undefined behaviour */
#define PIX_LIM 0x1p30
static inline double clamp_pix(double x)
{
    return x >= -PIX_LIM ? (x <= PIX_LIM ? x : PIX_LIM) : -PIX_LIM;
}
static inline double dfloor(double x)
{
    x = clamp_pix(x);
    double i = (double)(int64_t)x;
    return i > x ? i - 1 : i;
}
static inline double dceil(double x)
{
    x = clamp_pix(x);
    double i = (double)(int64_t)x;
    return i < x ? i + 1 : i;
}
/* r . (p, 1): one row of the view-projection (cull_occ_setup_view) at a
 * camera-relative point */
static inline double lin4(const double r[4], const double p[3])
{
    return r[0] * p[0] + r[1] * p[1] + r[2] * p[2] + r[3];
}

#define OCC_SLOT_AHEAD 4u

/* Gives tile (tx, ty) of b the slot *next (then one more) and sets its
 * pixels: EMPTY, and PAD where they are past the buffer's right or top
 * edge (padding never lowers a minimum). Returns them. Only for a tile
 * that has no slot in this render (TILE_INVALID): a band's range holds
 * each of its tiles once. */
static inline float *occ_tile_take(cull_occ_buffer *b, uint32_t *next, int tx, int ty)
{
    uint32_t s = (*next)++;
    b->tslot[(size_t)ty * b->tw + (size_t)tx] = s;
    float *p = b->pool + ((size_t)s << 6);
    /* the slot OCC_SLOT_AHEAD on, for writing (the pool has that many
       spare at its end): after other work the slots arrive before spans
       reach them (raised walk, 1280x720, cold: median 259 -> 251 us over
       6 alternations) */
    const char *q = (const char *)(p + ((size_t)OCC_SLOT_AHEAD << 6));
    __builtin_prefetch(q, 1, 3);
    __builtin_prefetch(q + 64, 1, 3);
    __builtin_prefetch(q + 128, 1, 3);
    __builtin_prefetch(q + 192, 1, 3);
    int nx = (int)b->w - tx * 8, ny = (int)b->h - ty * 8;
    if (nx >= 8 && ny >= 8) {
        /* a whole tile (64-byte aligned: the pool is, a slot is 256 bytes) */
#ifdef __AVX2__
        const __m256 e = _mm256_set1_ps(EMPTY);
        for (int k = 0; k < 64; k += 8) _mm256_store_ps(p + k, e);
#elif defined(__SSE2__)
        const __m128 e = _mm_set1_ps(EMPTY);
        for (int k = 0; k < 64; k += 4) _mm_store_ps(p + k, e);
#else
        for (int k = 0; k < 64; k++) p[k] = EMPTY;
#endif
        return p;
    }
    for (int y = 0; y < 8; y++)
        for (int x = 0; x < 8; x++) p[8 * y + x] = x < nx && y < ny ? EMPTY : PAD;
    return p;
}

#endif
