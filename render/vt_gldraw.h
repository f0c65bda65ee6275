/*
 * vt_gldraw.h — the OpenGL renderer: the same inputs and outputs as the
 * software renderer (vt_soft.h), drawn through a vt_gl context (headless
 * EGL; llvmpipe where there is no GPU). Instanced draws per mesh; a first
 * pass writes each pixel's nearness, from which the Forward+ tile lists are
 * built on the CPU (cull_lights_bin, the same lists as the software path);
 * the second pass shades with them (buffer textures) and the same BRDF.
 *
 * The context must be current on the calling thread (vt_gl_make_current).
 */
#ifndef VANTAGE_VT_GLDRAW_H
#define VANTAGE_VT_GLDRAW_H

#include "vt_gl.h"
#include "vt_soft.h"

typedef struct vt_gldraw vt_gldraw;

int  vt_gldraw_create(vt_gl *g, vt_gldraw **out, char *err, size_t errlen);
void vt_gldraw_destroy(vt_gldraw *r);

/* As vt_soft_draw (same frame, same conventions). */
int vt_gldraw_draw(vt_gldraw *r, const vt_frame *f, vt_soft_stats *st, char *err, size_t errlen);

/* As vt_soft_render (same buffers, same conventions). 0 or a VT_ERRORS
 * code (vt_err.h) with err filled. */
int vt_gldraw_render(vt_gldraw *r, const cull_view *v, uint32_t width, uint32_t height, const vt_mesh *meshes,
                     uint32_t nmesh, const vt_instance *inst, uint32_t ninst, const vt_light *lights, uint32_t nl,
                     float *rgba, float *depth, size_t stride, vt_soft_stats *st, char *err, size_t errlen);

#endif
