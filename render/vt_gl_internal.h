/*
 * vt_gl_internal.h — what the three files of the GL context module share
 * (vt_egl.c: bring-up and current-ness; vt_gl_target.c: offscreen targets
 * and readback; vt_gl_shader.c: shaders): the two structs behind vt_gl.h's
 * handles and the small helpers every GL-calling function uses. Internal
 * to render/; the public contract is vt_gl.h.
 */
#ifndef VANTAGE_VT_GL_INTERNAL_H
#define VANTAGE_VT_GL_INTERNAL_H

#include "vt_gl.h"

#include <epoxy/gl.h>
#include <EGL/egl.h>

_Static_assert(sizeof(GLuint) == sizeof(unsigned), "GL names are passed as unsigned");

struct vt_gl_target {
    vt_gl              *g;
    vt_gl_target       *prev, *next; /* g's live targets */
    uint32_t            w, h;
    vt_gl_color_format  format;
    GLuint              fbo, color, depth;
    GLuint              pbo;         /* 0 until a PBO readback */
    size_t              pbo_bytes;   /* its size */
};

struct vt_gl {
    EGLDisplay    dpy;
    EGLContext    ctx;
    vt_gl_info    info;
    vt_gl_target *targets;
};

/* Clears err (when there is one) and returns VT_OK: a call's success. */
int vt_gl_ok(char *err, size_t errlen);

/* g's context is current on the calling thread. */
bool vt_gl_is_current(const vt_gl *g);

/* VT_OK, or VT_ERR_INVALID (g NULL) / VT_ERR_CURRENT with a message naming
 * `what`; binds EGL_OPENGL_API on the calling thread. */
int vt_gl_need_current(const vt_gl *g, const char *what, char *err, size_t errlen);

/* Clears GL's error flags so the next check sees only our calls. */
void vt_gl_drain(void);

/* "GL_INVALID_ENUM", ...: glGetError's value by name. Static. */
const char *vt_gl_error_name(GLenum e);

#endif
