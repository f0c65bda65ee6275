/*
 * vt_shadow_tiles.h — the shadow maps' footprint tiles (internal to
 * vt_shadow*.c; the rule in vt_shadow.h at vt_shadow_tiles): per cascade
 * of a map of sz texels, (sz / VT_SHADOW_TILE)^2 packed depth ranges
 * over 5 x 5 texels each, joined from two parts per tile made per
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

/* Band k's parts of map m (size sz; texels outside columns x0..x1 are
 * -FLT_MAX) into P (each tile's two rows) and O (its second row), over
 * the 5 columns TS s - 1 .. TS s + 3, packed by qlo, qinv (vt_shadow.h,
 * vt_shadow_tiles). */
void vt_shadow_tiles_band(uint32_t *P, uint32_t *O, const float *m, uint32_t sz, uint32_t k, uint32_t x0, uint32_t x1,
                          float qlo, float qinv);

/* Tile row ty of cascade c from the parts P and O of every cascade into
 * the packed tiles: O of the row above, P of the row and of the row
 * below; lo..hi: the texel columns the raster wrote in the rows the row
 * sees (lo > hi: none). */
void vt_shadow_tiles_row(const uint32_t *P, const uint32_t *O, uint32_t *tiles, uint32_t sz, uint32_t c, uint32_t ty,
                         uint32_t lo, uint32_t hi);

#endif
