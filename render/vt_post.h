/*
 * vt_post.h — the post passes both renderers run on their HDR picture
 * (issue 20): exposure (fixed, or automatic from the frame's luminance
 * histogram, with eye adaptation for a stream) and then FXAA on the
 * exposed picture. One C implementation for both renderers: the GL path
 * runs it on its readback, so the two share one set of rules exactly.
 *
 * The buffer is the renderers' output (vt_soft.h): rgba, 4 floats per
 * pixel, linear HDR, rows bottom-up, `stride` pixels apart. The passes run
 * in place, over bands of rows on a cull_pool (NULL: one thread); FXAA
 * needs a luma plane and room for its results, the scratch of a vt_post
 * (owned by the renderer, grown as needed, 20 bytes per pixel).
 */
#ifndef VANTAGE_VT_POST_H
#define VANTAGE_VT_POST_H

#include "culling.h"

#include "vt_scene.h"
#include "vt_soft.h"

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* The histogram: 4 bins per EV of log2 luminance (cd/m^2) over
 * [VT_HIST_LO, VT_HIST_LO + 32) EV, 2^-16 .. 2^16 nits: a moonlit street
 * (~1e-3) to a sunlit white wall (~1e4); darker pixels count in the first
 * bin, brighter (the sun's disc) in the last. Bins of 1/4 EV are found
 * exactly from the float's exponent and three mantissa comparisons. */
#define VT_HIST_BINS 128
#define VT_HIST_LO (-16)
/* The part of the histogram the exposure averages: from the darkest 50 %
 * to the brightest 5 %, both left out, as engines do (a dark half of
 * shadows and the sun's disc do not set the exposure). */
#define VT_HIST_PLO 0.50
#define VT_HIST_PHI 0.95
/* The automatic exposure's range, EV100: the FIXED mode's low end (-10, a
 * starless night) to 20 (above a sunlit snow field, ~16). */
#define VT_EV_MIN (-10.0f)
#define VT_EV_MAX 20.0f
/* Eye adaptation: time constants in seconds. Towards a brighter scene
 * (the EV rises) the eye adapts fast, towards a darker one slowly, as
 * light and dark adaptation do (and as engines default: UE's speed up 3,
 * down 1 EV/s). */
#define VT_ADAPT_TAU_UP 0.5f
#define VT_ADAPT_TAU_DOWN 1.5f

typedef struct vt_post {
    float *scratch; /* FXAA's luma plane (a float a pixel), then its results (4 a pixel at most) */
    size_t cap;     /* in floats */
    uint32_t isa;   /* vt_post_set_isa's + 1; 0 (zero-initialised): the default */
    uint32_t *cost; /* the last FXAA's edge pixels a row (its bands' split for the next) */
    uint32_t cost_w, cost_h, cost_cap; /* the picture they were counted on; rows allocated */
} vt_post;

void vt_post_free(vt_post *p);
/* Later passes of p (and vt_post_apply's histogram) use the lane kernels
 * of isa (enum cull_isa: scalar and SSE4.1 take the one-lane rows,
 * AVX2 its own) where the CPU has them, else the default
 * (cull_isa_default); CULL_ISA_COUNT: the default. For tests comparing
 * instances; every instance gives the same bits. */
void vt_post_set_isa(vt_post *p, uint32_t isa);

/* The post passes of a frame with an environment env (NULL: nothing,
 * returns 0 and *ev 0): exposure (env's mode; AUTO: the histogram EV,
 * moved by adapt when adapt is non-NULL, see vt_adapt), then FXAA unless
 * fx_off has VT_FX_FXAA. pool NULL or threads <= 1: one thread. *ev: the
 * EV100 used. 0, or VT_ERR_NOMEM (the scratch; the picture is exposed but
 * not anti-aliased). */
int vt_post_apply(vt_post *p, cull_pool *pool, uint32_t threads, const vt_frame *f, float *ev);

/* Pictures of at least this many pixels meter a quarter of them (tiles
 * of 4 rows by 64 pixels, a run of 16 from each row, vt_post.c's
 * job_hist): within a few hundredths of an EV of every pixel's histogram
 * on the demo city and on adversarial pictures (tests/test_post.c). */
#define VT_HIST_SAMPLE_MIN (1u << 15)

/* The exposure's histogram made by a renderer as it writes the picture
 * (vt_soft: each thread over the spans it shades), so the post passes do
 * not read the finished picture again for it: the same pixels, the same
 * weights and the same bins as vt_exposure_auto's own pass, so the same
 * EV bit for bit (tests/test_post.c). Spans are runs of pixels of one row
 * that start at a multiple of VT_HIST_RUN and are at most that long. */
#define VT_HIST_RUN 16u
typedef struct vt_hist {
    uint32_t q[3]; /* vt_post.c's bin thresholds */
    uint32_t (*lanes)(const float *p, uint32_t n, const uint32_t q[3], uint32_t (*hb)[VT_HIST_BINS], uint32_t wgt);
    uint32_t b[4][VT_HIST_BINS]; /* 4 sub-histograms, summed at the end */
} vt_hist;
/* h emptied, with p's lane kernel (vt_post_set_isa). */
void vt_hist_begin(const vt_post *p, vt_hist *h);
/* How the exposure's metering weighs the pixels of row y of a width x
 * height picture in the 4 runs of VT_HIST_RUN from x0 (x0 % (4
 * VT_HIST_RUN) == 0): -1, every pixel counts once (the margins past the
 * subsample's whole tiles, small pictures); else the one run k (0..3,
 * pixels x0 + k VT_HIST_RUN ..) whose pixels count 4 times, the other
 * three not at all (VT_HIST_SAMPLE_MIN). */
int vt_hist_quarter(uint32_t width, uint32_t height, uint32_t x0, uint32_t y);
/* The span's n pixels (RGBA floats) into h, each counting wgt. */
void vt_hist_add(vt_hist *h, const float *rgba, uint32_t n, uint32_t wgt);
/* vt_post_apply with the histogram already made (the sum of parts[0 ..
 * nparts), every pixel of f's picture added once with the weight
 * vt_hist_quarter gives it): an AUTO exposure takes it instead of
 * metering the picture. parts NULL: vt_post_apply. */
int vt_post_apply_hist(vt_post *p, cull_pool *pool, uint32_t threads, const vt_frame *f, const vt_hist *parts,
                       uint32_t nparts, float *ev);

/* The histogram exposure's EV100 of a picture (before exposure):
 * comp is subtracted (env's exposure_comp: brighter), the result clamped
 * to VT_EV_MIN..VT_EV_MAX. Pictures of VT_HIST_SAMPLE_MIN pixels or more
 * are metered on the subsample, smaller ones on every pixel; pool as
 * vt_post_apply. */
float vt_exposure_auto(const float *rgba, uint32_t width, uint32_t height, size_t stride, float comp,
                       cull_pool *pool, uint32_t threads);
/* The same with every pixel counted whatever the size (the subsample's
 * reference in the tests). */
float vt_exposure_auto_all(const float *rgba, uint32_t width, uint32_t height, size_t stride, float comp,
                           cull_pool *pool, uint32_t threads);
/* The EV100 whose exposure maps luminance L (cd/m^2, > 0) to mid grey:
 * log2(L x 100 / 12.5), as a reflected-light meter's calibration K = 12.5. */
double vt_ev_of_luminance(double L);
/* One step of eye adaptation: ev moved towards target over dt seconds
 * (tau VT_ADAPT_TAU_UP when the target is higher, else TAU_DOWN):
 * target + (ev - target) exp(-dt / tau). Never past target. dt NaN or
 * negative: 0. */
float vt_adapt_step(float ev, float target, float dt);

/* FXAA (Lottes' FXAA 3.11, quality preset 12) over the picture in place. */
int vt_fxaa(vt_post *p, cull_pool *pool, uint32_t threads, float *rgba, uint32_t width, uint32_t height,
            size_t stride);

#ifdef __cplusplus
}
#endif
#endif
