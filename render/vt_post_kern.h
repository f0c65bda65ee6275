/*
 * vt_post_kern.h — the post passes' lane kernels (internal to
 * vt_post*.c): vt_post.c holds the one-lane rows (the reference),
 * vt_post_avx2.c the same rows 8 pixels a step. Each instance does the
 * same float operations in the same order (no FMA, no reciprocal
 * estimates), so every instance gives the same bins, luma and FXAA
 * output bit for bit (tests/test_post.c compares them).
 */
#ifndef VANTAGE_VT_POST_KERN_H
#define VANTAGE_VT_POST_KERN_H

#include "vt_post.h"

#include <stddef.h>
#include <stdint.h>

/* The histogram bins of a row's n pixels (RGBA floats), each counting
 * wgt, added to hb[k] (4 sub-histograms: consecutive increments of one
 * bin in one array would wait on each other); q: the mantissas of
 * 2^0.25, 2^0.5, 2^0.75 (vt_post.c's bin_of). Returns the pixels done
 * (the rest: the caller). */
typedef uint32_t (*vt_post_hist_fn)(const float *p, uint32_t n, const uint32_t q[3], uint32_t (*hb)[VT_HIST_BINS],
                                    uint32_t wgt);
/* A row of n pixels: colour times scale in place (alpha kept), and each
 * pixel's FXAA luma sqrt(Y(c / (1 + max c))) (c clamped to 0..1e6, NaN 0)
 * into l. Returns the pixels done. */
typedef uint32_t (*vt_post_prep_fn)(float *p, uint32_t n, float scale, float *l);

/* What FXAA reads: the luma plane (w x h packed) and the exposed
 * picture (RGBA floats, rows stride pixels apart). */
typedef struct vt_post_fx {
    const float *luma, *rgba;
    uint32_t w, h;
    size_t stride;
} vt_post_fx;
/* An anti-aliased pixel: its index y * w + x and its new colour (the
 * blend expanded back), kept apart until every band has read the
 * picture. */
typedef struct vt_post_fx_out {
    uint32_t i;
    float c[3];
} vt_post_fx_out;
/* FXAA (vt_post.c's fxaa_pixel, operation for operation) of an inner row
 * y's pixels from x = 1 while x + 9 <= w, 8 at a time: the early exit in
 * lanes, the pixels past it in lanes; their results appended to o.
 * Returns the results written; *x_end: the first pixel not done. */
typedef uint32_t (*vt_post_fxaa_fn)(const vt_post_fx *fx, uint32_t y, vt_post_fx_out *o, uint32_t *x_end);

typedef struct vt_post_kern {
    vt_post_hist_fn hist;
    vt_post_prep_fn prep;
    vt_post_fxaa_fn fxaa_row;
} vt_post_kern;

/* FXAA 3.11's search steps (quality preset 12) and sub-pixel amount */
#define VT_FX_STEPS 5
#define VT_FX_STEP_LIST {1.0f, 1.5f, 2.0f, 4.0f, 12.0f}
#define VT_FX_SUBPIX 0.75f

/* FXAA 3.11's thresholds (quality preset 12), shared by the instances */
#define VT_FX_EDGE 0.166f
#define VT_FX_EDGE_MIN 0.0833f

/* The AVX2 instance's kernels, or all NULL where this build has none. */
vt_post_kern vt_post_kern_avx2(void);

#endif
