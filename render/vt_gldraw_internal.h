/*
 * vt_gldraw_internal.h — what the OpenGL renderer's files share (internal
 * to render/): its shader sources (vt_gldraw_glsl.c) and its texture
 * cache (vt_gltex.c).
 */
#ifndef VANTAGE_VT_GLDRAW_INTERNAL_H
#define VANTAGE_VT_GLDRAW_INTERNAL_H

#include "vt_mask.h"
#include "vt_shade.h"
#include "vt_scene.h"

#include <stdbool.h>
#include <stdint.h>

#define VT_EMPTY_GLSL -3.402823466e38 /* VT_EMPTY, as a GLSL literal */

extern const char *const vt_gldraw_vs, *const vt_gldraw_fs;
extern const char *const vt_gldraw_bg_vs, *const vt_gldraw_bg_fs;

/* GL texture objects for vt_textures, kept by (id, gen, sRGB) from frame
 * to frame (id 0: uploaded for this frame only), each with its whole mip
 * chain. A texture unused for VT_GLTEX_KEEP frames is deleted. */
#define VT_GLTEX_KEEP 120u
typedef struct vt_gltex_entry {
    uint32_t id, gen;
    bool srgb;
    unsigned name;
    uint64_t used;          /* the frame it was last used in */
} vt_gltex_entry;
typedef struct vt_gltex {
    vt_gltex_entry *e;
    size_t n, cap;
    uint64_t frame;
    uint32_t uploads;       /* this frame's uploads (stats, tests) */
} vt_gltex;

/* The texture object for t (bound to GL_TEXTURE_2D on the active unit as a
 * side effect), or 0 when it cannot be made (out of memory, a GL error). */
unsigned vt_gltex_get(vt_gltex *c, const vt_texview *t, bool srgb);
/* Ends a frame: deletes this frame's temporary textures and those unused
 * for VT_GLTEX_KEEP frames. */
void vt_gltex_end_frame(vt_gltex *c);
void vt_gltex_free(vt_gltex *c);
/* A sampler object set as the slot says (wrap, filters). */
void vt_gltex_sampler(unsigned sampler, const vt_texref *r);

#endif
