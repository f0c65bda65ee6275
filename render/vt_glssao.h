/*
 * vt_glssao.h — the GL path's ambient occlusion (vt_ssao_gl.c; internal
 * to render/): vt_ssao.h's pass in GLSL, after vt_gldraw's nearness pass.
 * All calls need the context current.
 */
#ifndef VANTAGE_VT_GLSSAO_H
#define VANTAGE_VT_GLSSAO_H

#include "vt_gl.h"
#include "vt_ssao.h"

#include <stdbool.h>
#include <stddef.h>

typedef struct vt_glssao vt_glssao;

/* The fragment-shader object every shading program links: it defines
 * `float ambient_occlusion();` (1 until vt_glssao_use turns it on);
 * vt_glssao_program_init sets a linked program's sampler and switch
 * (leaves it in use). */
extern const char *const vt_glssao_fs;
void vt_glssao_program_init(unsigned prog);
/* The pass' two programs; targets come with the first run. */
int vt_glssao_create(vt_gl *g, vt_glssao **out, char *err, size_t errlen);
void vt_glssao_destroy(vt_glssao *s);
/* Runs the pass over near_tex (a w x h texture, alpha nearness, as
 * vt_gldraw's pass 1 leaves it) and binds the AO to the unit the
 * shading programs read. Leaves its own framebuffer and program bound:
 * the caller binds its own again. Depth test and face culling end on.
 * sv not ok: nothing done (then ambient_occlusion must stay off).
 * 0, or VT_ERR_GL / VT_ERR_NOMEM / the target's codes. */
int vt_glssao_run(vt_glssao *s, unsigned near_tex, const vt_ssao_view *sv, char *err, size_t errlen);
/* Turns a shading program's ambient_occlusion() on or off (leaves prog in use). */
void vt_glssao_use(unsigned prog, bool on);

#endif
