/*
 * vt_shadow_gl.h — the sun's shadow cascades in the GL renderer (internal
 * to render/): the maps drawn by vt_shadow.c's rasterizer from the same
 * fit (so both renderers compare against the same depths), uploaded as an
 * R32F texture array on unit VT_SHADOW_GL_UNIT, and the GLSL fragment
 * object defining `float sun_visibility(vec3 p, vec3 n)` (the lookup of
 * vt_shadow.c, operation for operation) linked into vt_gldraw's programs.
 */
#ifndef VANTAGE_VT_SHADOW_GL_H
#define VANTAGE_VT_SHADOW_GL_H

#include "vt_gl.h"
#include "vt_soft.h"

#define VT_SHADOW_GL_UNIT 10

typedef struct vt_shadow_gl vt_shadow_gl;

/* The shadow lookup's fragment-shader object (sun_visibility), linked
 * into each shading program; vt_shadow_gl_program_init binds a linked
 * program's map sampler to VT_SHADOW_GL_UNIT (leaves it in use). */
extern const char *const vt_shadow_gl_fs;
void vt_shadow_gl_program_init(unsigned prog);
int vt_shadow_gl_create(vt_shadow_gl **out);
/* Deletes its texture (g's context current). NULL: nothing. */
void vt_shadow_gl_destroy(vt_shadow_gl *s);
/* The frame's cascades (none: the shaders get u_sh_on 0): fitted, drawn,
 * uploaded; *tris the triangles drawn, *ns the time it took (0: none).
 * 0, or VT_ERR_NOMEM / VT_ERR_GL with err. */
int vt_shadow_gl_frame(vt_shadow_gl *s, const vt_frame *f, uint32_t *tris, uint64_t *ns, char *err, size_t errlen);
/* Sets program prog's (in use) shadow uniforms for the last frame. */
void vt_shadow_gl_uniforms(const vt_shadow_gl *s, unsigned prog);

#endif
