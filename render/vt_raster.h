/*
 * vt_raster.h — the software renderer's row kernels for the visibility
 * buffer (internal to render/): a triangle's covered run of one row, the
 * ground plane's row, the clear. vt_soft.c decides what is covered; these
 * write the nearness and the record where the pixel is nearer.
 *
 * Each kernel computes a pixel's nearness with the same double operations
 * in the same order as the one-pixel reference (vt_raster_span_ref, the
 * ground's vt_ground_at), rounded once to float, and keeps it under the
 * same test (strictly nearer; NaN never): the instances agree bit for bit
 * (tests/test_raster.c checks them against the references). The AVX2
 * instance runs 8 pixels a step, 4 doubles per vector, in functions
 * compiled for AVX2 by a target attribute (no file of its own: nothing else
 * here needs the flag), picked at run time as vt_kern_pick picks.
 */
#ifndef VANTAGE_VT_RASTER_H
#define VANTAGE_VT_RASTER_H

#include "vt_surface.h"

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

/* Columns [i0, i1] of a row of width w (0 <= i0 <= i1 < w): where
 * (float)(na (i + 0.5) + nz) > nrow[i], that nearness and id. */
typedef void (*vt_span_fn)(float *nrow, uint32_t *irow, int32_t i0, int32_t i1, uint32_t w, double na, double nz,
                           uint32_t id);
/* Columns [i0, i1] of the row at NDC Y of the ground plane g (X: each
 * column's NDC x, vt_ndc_row): where vt_ground_at hits and (float) of its
 * nearness is nearer, that nearness and VT_ID_GROUND. sure: the ground
 * hits every one of the columns (vt_ground_row's inner run): only the
 * depth test runs. */
typedef void (*vt_gspan_fn)(float *nrow, uint32_t *irow, int32_t i0, int32_t i1, const double *X, const vt_ground *g,
                            double Y, bool sure);
/* n pixels: nearness VT_EMPTY, record 0. */
typedef void (*vt_clear_fn)(float *near, uint32_t *id, size_t n);

/* The least of rows x cols nearness values (rows ys apart). */
typedef float (*vt_tmin_fn)(const float *near, size_t ys, uint32_t cols, uint32_t rows);

typedef struct vt_rkern {
    vt_span_fn span;
    vt_gspan_fn ground;
    vt_clear_fn clear;
    vt_tmin_fn tmin;
} vt_rkern;

/* The instances for this CPU and VANTAGE_ISA (cull_isa_default). */
vt_rkern vt_rkern_pick(void);
/* The one-pixel instances (the reference). */
vt_rkern vt_rkern_scalar(void);

/* The columns of the ground's row at NDC Y of a view w wide that can
 * hit, [c[0], c[3]] (a superset of those vt_ground_at accepts, by a margin
 * far above the rounding of its double evaluation), and within them those
 * that surely hit, [c[1], c[2]] (empty: c[1] > c[2]); false: none can. */
bool vt_ground_row(const vt_ground *g, double Y, uint32_t w, int32_t c[4]);
/* X[x] = vt_ndc_x(x, 2 / w) for the w columns. */
void vt_ndc_row(uint32_t w, double *X);

/* floor(a / b), b > 0. */
static inline int64_t vt_floor_div(int64_t a, int64_t b)
{
    int64_t q = a / b;
    return q - (a % b < 0);
}

/* One edge of a triangle, row by row (vt_soft.c's raster_tri): f =
 * floor(e / D) and its remainder r, stepped by qs and rs a row; a
 * horizontal edge (sg 0) keeps e itself in f (stepped by qs; D never
 * reached). */
typedef struct vt_edge {
    int64_t f, r, qs, rs, D;
    int sg;                 /* the sign of s: 1 bounds the run's start, -1 its end */
} vt_edge;

/* This row's bound of the edge on the run [lo, hi], then the next row. */
static inline void vt_edge_row(vt_edge *d, int64_t *lo, int64_t *hi)
{
    if (d->sg > 0) *lo = -d->f > *lo ? -d->f : *lo;
    else if (d->sg < 0) *hi = d->f < *hi ? d->f : *hi;
    else if (d->f < 0) *hi = -1;
    d->f += d->qs;
    d->r += d->rs;
    int64_t c = d->r >= d->D;
    d->r -= c ? d->D : 0;
    d->f += c;
}

#endif
