/*
 * vt_picture.h — what the two renderers (vt_soft.c, vt_gldraw.c) share,
 * so they draw the same picture from the same rules: the checks of a
 * picture's inputs (vt_picture_check; a wire frame is protocol/'s), a
 * mesh's bounds stretched onto an instance's box, the per-tile nearness
 * ranges that feed the light binning, the depth the outputs carry, and a
 * spot light's inner cone. Internal to render/.
 */
#ifndef VANTAGE_VT_PICTURE_H
#define VANTAGE_VT_PICTURE_H

#include "vt_mask.h"
#include "vt_overlay.h"
#include "vt_shade.h"
#include "vt_soft.h"
#include "vp_grow.h"

#include <float.h>
#include <stdbool.h>
#include <stddef.h>

#define VT_TILE CULL_LIGHT_TILE

/* vt_frame_check, then fills *vr for the view. 0, or VT_ERR_INVALID with
 * err filled. */
int vt_picture_check(const vt_frame *f, cull_view_rows *vr, char *err, size_t errlen);

/* A mesh's bounds: lo[0..2], hi[3..5]. */
void vt_mesh_bounds(const vt_mesh *m, float b[6]);

/* The mesh with bounds b stretched onto the instance's box, camera-relative
 * (origin subtracted), in double: p' = p * scale + shift. A flat axis of
 * the mesh maps to the box's centre. */
void vt_instance_xform(const vt_instance *in, const float b[6], const double origin[3], double scale[3],
                       double shift[3]);

/* An instance's placement, camera-relative, in double: p' = m p + t,
 * normals by n (then normalised); mirror: the determinant is negative
 * (the winding turns over). Bounds instances have q = identity. */
typedef struct vt_place {
    double m[3][3], n[3][3], t[3];
    double q[4], s[3];      /* the rotation (unit) and scale m is made of */
    bool mirror;
} vt_place;
void vt_instance_place(const vt_instance *in, const float b[6], const double origin[3], vt_place *pl);

/* The destruction masks of in[0..n)'s damaged instances for a view at
 * origin (vt_mask_make), into *mk (grown; *mk_cap entries), and per
 * instance its mask + 1 (0: intact) into *mk_of (grown, *of_cap): the
 * software renderer's and the shadow cascades' one table. *count: the
 * masks made (0: nothing written, most frames). false: out of memory. */
bool vt_masks_make(const vt_instance *in, uint32_t n, const double origin[3], struct vt_mask **mk, size_t *mk_cap,
                   uint32_t **mk_of, size_t *of_cap, uint32_t *count);

/* Per 16x16 tile {nearest, farthest} nearness of what the tile shows, from
 * a width x height nearness image (pixel (x, y) at near[y * ys + x * xs],
 * VT_EMPTY where nothing is): the depth_range of cull_lights_bin. */
void vt_tile_ranges(const float *near, size_t xs, size_t ys, uint32_t width, uint32_t height, float (*range)[2]);

/* The output depth rule of view v (vt_depth_apply). */
static inline vt_depth_rule vt_depth_rule_of(const cull_view *v, const cull_view_rows *vr)
{
    return (vt_depth_rule){.ortho = vr->ortho, .k = v->depth_mode == CULL_DEPTH_GL ? 0.5f : 1.0f};
}

/* A light as both renderers shade it (camera-relative, the spot's inner
 * cosine kept above the outer one so the smoothstep between them never
 * divides by zero) and as the binning takes it. Checked beforehand by
 * vt_picture_check. */
void vt_light_prepare(const vt_light *L, const double origin[3], vt_slight *q, cull_light *cl);

#endif
