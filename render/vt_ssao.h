/*
 * vt_ssao.h — screen-space ambient occlusion from the nearness buffer the
 * raster leaves (the visibility buffer is the z-prepass: after raster,
 * before shading), for both renderers (internal to render/): vt_ssao.c
 * runs it on the CPU for vt_soft, vt_ssao_gl.c in GLSL for the GL path,
 * with the rules and constants below.
 *
 * The estimator is ground-truth ambient occlusion (GTAO, Jimenez et al.
 * 2016): per pixel, slices through the view vector along screen
 * directions; in each the highest horizon on either side among samples
 * within the world radius, and the cosine-weighted visible arc between
 * the two horizons integrated in closed form against the normal
 * projected into the slice. Divided by the same slices' value with no
 * occluder, so a flat surface is exactly 1 however few slices there are
 * (the raw sum over 2 slices puts a grazing floor at about 0.9).
 *
 * Budget (a few ms at 1280x720 on 2 threads): half resolution (the texel
 * (i, j) is the full-resolution pixel (2i, 2j), its real nearness, no
 * averaging across edges), 2 slices of 4 steps a side, the slices
 * turned by a 2x2 texel pattern (4 turns: 8 directions over a 2x2
 * block), then a depth-aware tent upsample whose taps weigh the four
 * turns equally at every full-resolution pixel.
 *
 * Positions are reconstructed from nearness in float: (p, 1) ~ inv (X,
 * Y, N, 1), inv the inverse of the clip rows x, y, d, w (vt_inv4), which
 * is, the rows being a camera's, p = B (i, j) / N relative to the eye
 * (perspective: N is 1 / w) or p = B (i, j) + N bn (orthographic), B
 * affine in the half texel (i, j): the software pass keeps only the half
 * texels' nearness and a sample costs one load of it; normals from the
 * position differences to the neighbour on the side with the smaller
 * step (a crease or silhouette does not bend them). Sky texels (nothing
 * drawn) have AO 1 and never occlude.
 */
#ifndef VANTAGE_VT_SSAO_H
#define VANTAGE_VT_SSAO_H

#include "culling.h"

#include <math.h>
#include <stdbool.h>
#include <stdint.h>

/* The world radius, metres: a city's contact shadows are at wall bases,
   kerbs, window recesses (0.2 to 0.5 m deep) and the gaps between
   buildings; 1.5 m darkens a storey's bottom metre or so and leaves a
   facade 3 m from another unoccluded. */
#define VT_SSAO_RADIUS 1.5f
/* Occluders fade out over the radius' last quarter (no hard ring, and a
   near object does not darken a far wall behind it: the range check). */
#define VT_SSAO_FADE 0.25f
#define VT_SSAO_SLICES 2
#define VT_SSAO_STEPS 4
/* The screen-space cap, half-resolution texels (128 full pixels): near
   the eye the radius would cover the screen for the same 8 samples. */
#define VT_SSAO_MAX_PX 64.0f
/* Samples less than this sine above the tangent plane do not raise a
   horizon: float noise of a plane's reconstruction stays unoccluded. */
#define VT_SSAO_BIAS 0.03f
/* The upsample: a half-resolution tap weighs 1 - |dN| / (DEPTH_TOL N),
   a relative depth difference (perspective); orthographic views, an
   absolute one of DEPTH_TOL_M metres. */
#define VT_SSAO_DEPTH_TOL 0.05f
#define VT_SSAO_DEPTH_TOL_M 0.5f

/* A view as the pass reads it, once a frame: what both renderers'
 * passes are given. */
typedef struct vt_ssao_view {
    bool ok;                /* false: a view the pass cannot reconstruct (no pass: AO 1) */
    bool ortho;
    uint32_t w, h, hw, hh;  /* full and half resolution */
    float inv[4][4];        /* (p, 1) ~ inv (X, Y, N, 1), p camera-relative */
    float ex[3], ey[3];     /* the world step of one half texel right and up at N = 1 (orthographic:
                               any N): the screen's directions in the world */
    float texel1;           /* |ex| (the radius in texels is RADIUS N / texel1; orthographic: / texel1) */
    float vdir[3];          /* orthographic: unit, towards the eye */
    /* half texel (i, j) at nearness N: the point B / N relative to the eye
       (perspective), B + N bn camera-relative (orthographic), B = b0 + i bi
       + j bj (vt_ssao.c's kernels) */
    float b0[3], bi[3], bj[3], bn[3];
    /* perspective: a quarter of VT_SSAO_BIAS times the least sine of the
       angle between two neighbouring half texels' rays; orthographic: of
       BIAS times the least distance between them over |bn| (vt_ssao.inl's
       ss_tan) */
    float kappa;
    float ntol;             /* orthographic: the upsample's tolerance in nearness units */
} vt_ssao_view;

/* The pass' view for vr at w x h; sv->ok false where the rows cannot be
 * inverted or give non-finite steps. */
void vt_ssao_view_make(const cull_view_rows *vr, uint32_t w, uint32_t h, vt_ssao_view *sv);

/* The closed-form GTAO slice value (both renderers: the GLSL has it
 * operation for operation): the cosine-weighted visible part of one
 * side, horizon angle h (cos ch, sin sh), the normal's angle n in the slice (cos cn, sin sn). */
static inline float vt_ssao_arc(float h, float ch, float sh, float cn, float sn)
{
    float c2h = 2 * ch * ch - 1, s2h = 2 * sh * ch;
    return 0.25f * (-(c2h * cn + s2h * sn) + cn + 2 * h * sn);
}

/* acos to about 7e-5 rad (Abramowitz and Stegun 4.4.45), clamped: four
 * multiply-adds and a square root, the same in GLSL. */
static inline float vt_ssao_acos(float x)
{
    float a = x < 0 ? -x : x;
    a = a > 1 ? 1 : a;
    float r = ((-0.0187293f * a + 0.0742610f) * a - 0.2121144f) * a + 1.5707288f;
    float b = 1 - a;
    r *= b > 0 ? sqrtf(b) : 0;
    return x < 0 ? 3.14159265f - r : r;
}


/* The slices' screen directions (cos, sin) of the 2x2 pattern's turn t
 * at dir[t * VT_SSAO_SLICES + slice]: slice k of turn t at (k + t / 4)
 * pi / SLICES. */
void vt_ssao_dirs(float dir[4 * VT_SSAO_SLICES][2]);

typedef struct vt_ssao vt_ssao;

/* Runs the pass over near (w x h floats, rows bottom-up, VT_EMPTY where
 * nothing is drawn) with nt threads of pool (NULL or nt 1: the caller's
 * thread) into an AO image of w x h floats in 0..1 (*ao, owned by *s,
 * valid until the next run or destroy). *s is made on first use. 0, or
 * VT_ERR_NOMEM. A view that is not ok gives all 1. */
int vt_ssao_run(vt_ssao **s, cull_pool *pool, uint32_t nt, const vt_ssao_view *sv, const float *near,
                const float **ao);
/* vt_ssao_run, and side(side_arg) run once besides (side NULL: none):
 * during the GTAO pass, by the first thread to start it
 * (cull_pool_each_side), so the caller's serial work that does not read
 * the AO overlaps the pass. Run whatever the view; not run when the
 * buffers cannot be had (VT_ERR_NOMEM). */
int vt_ssao_run_side(vt_ssao **s, cull_pool *pool, uint32_t nt, const vt_ssao_view *sv, const float *near,
                     const float **ao, cull_side_fn side, void *side_arg);
void vt_ssao_destroy(vt_ssao *s);
/* Later runs of *s use the kernels of isa (enum cull_isa: the one-lane
 * instance is the tests' reference for the 4- and 8-lane ones) where this
 * CPU has it, else the default; *s made if NULL (out of memory: nothing). */
void vt_ssao_set_isa(vt_ssao **s, uint32_t isa);
/* Later runs of *s skip no step (vt_ssao.c's skip off: the tests'
 * reference for it); *s made if NULL (out of memory: nothing). */
void vt_ssao_no_skip(vt_ssao **s);

#endif
