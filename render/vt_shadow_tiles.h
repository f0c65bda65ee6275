/*
 * vt_shadow_tiles.h — the shadow maps' footprint tiles (internal to
 * vt_shadow*.c; the rule in vt_shadow.h at vt_shadow_tiles): per cascade
 * of a map of sz texels, (sz / VT_SHADOW_TILE)^2 minima, then (at plane
 * floats on) as many maxima of the map's depth over each tile's 3 x 3
 * raw tiles; the raw tiles (VT_SHADOW_TILE texels square) are made per
 * raster band.
 */
#ifndef VANTAGE_VT_SHADOW_TILES_H
#define VANTAGE_VT_SHADOW_TILES_H

#include <stddef.h>
#include <stdint.h>

#define VT_SHADOW_BAND 32u /* rows a raster band */

/* fminf and fmaxf where no operand is NaN or a NaN may go either way
 * (x86-64's are library calls) */
static inline float min2(float a, float b)
{
    return a < b ? a : b;
}

static inline float max2(float a, float b)
{
    return a > b ? a : b;
}

/* n floats at r to -FLT_MAX (SSE2: four stores a step). */
void vt_shadow_fill_lowest(float *r, uint32_t n);

/* Band k's raw tiles of map m (size sz; texels outside columns x0..x1
 * are -FLT_MAX) into the raw minima lo and maxima hi. */
void vt_shadow_tiles_band(float *lo, float *hi, const float *m, uint32_t sz, uint32_t k, uint32_t x0, uint32_t x1);

/* Tile row ty of cascade c from the raw tiles raw (minima, then maxima
 * plane floats on) into the packed tiles (vt_shadow.h, vt_shadow_tiles:
 * quantised by qlo, qinv); lo..hi: the texel columns the raster wrote in
 * the rows the row sees (lo > hi: none). */
void vt_shadow_tiles_row(const float *raw, uint32_t *tiles, size_t plane, uint32_t sz, uint32_t c, uint32_t ty, uint32_t lo,
                         uint32_t hi, float qlo, float qinv);

#endif
