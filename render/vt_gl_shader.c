/*
 * vt_gl_shader.c — vt_gl.h's shader helpers: compile one stage, link a
 * program, build one from a vertex and a fragment source, with the info
 * log in the caller's message on failure.
 */
#include "vt_gl_internal.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ---- shaders ------------------------------------------------------------------- */

static const char *stage_name(GLenum s)
{
    switch (s) {
    case GL_VERTEX_SHADER:          return "vertex shader";
    case GL_FRAGMENT_SHADER:        return "fragment shader";
    case GL_GEOMETRY_SHADER:        return "geometry shader";
    case GL_TESS_CONTROL_SHADER:    return "tessellation control shader";
    case GL_TESS_EVALUATION_SHADER: return "tessellation evaluation shader";
    case GL_COMPUTE_SHADER:         return "compute shader";
    }
    return "shader";
}

/* "what: " + the info log of a shader or program, into err. */
static void put_log(char *err, size_t errlen, const char *what, GLuint obj, bool program)
{
    if (!err || !errlen) return;
    int n = snprintf(err, errlen, "%s: ", what);
    if (n < 0 || (size_t)n >= errlen) return;
    GLsizei cap = (GLsizei)(errlen - (size_t)n > 0x7fffffff ? 0x7fffffff : errlen - (size_t)n);
    GLsizei len = 0;
    if (program) glGetProgramInfoLog(obj, cap, &len, err + n);
    else glGetShaderInfoLog(obj, cap, &len, err + n);
    if (len <= 0) snprintf(err + n, errlen - (size_t)n, "(no info log)");
    else /* drop the trailing newline drivers add */
        for (char *e = err + n + len - 1; e >= err + n && (*e == '\n' || *e == ' '); e--) *e = 0;
}

int vt_gl_shader_compile(vt_gl *g, unsigned stage, const char *src, unsigned *out, char *err,
                         size_t errlen)
{
    if (!out || !src) return vp_errf(err, errlen, VT_ERR_INVALID, "vt_gl_shader_compile: NULL");
    *out = 0;
    int rc = vt_gl_need_current(g, "vt_gl_shader_compile", err, errlen);
    if (rc) return rc;
    vt_gl_drain();
    GLuint s = glCreateShader(stage);
    if (!s) {
        GLenum ge = glGetError();
        return vp_errf(err, errlen, ge == GL_INVALID_ENUM ? VT_ERR_INVALID : VT_ERR_GL,
                    "glCreateShader(0x%x): %s", stage, vt_gl_error_name(ge));
    }
    glShaderSource(s, 1, &src, NULL);
    glCompileShader(s);
    GLint okc = GL_FALSE;
    glGetShaderiv(s, GL_COMPILE_STATUS, &okc);
    if (!okc) {
        put_log(err, errlen, stage_name(stage), s, false);
        glDeleteShader(s);
        return VT_ERR_COMPILE;
    }
    *out = s;
    return vt_gl_ok(err, errlen);
}

int vt_gl_program_link(vt_gl *g, const unsigned *shaders, size_t n, unsigned *out, char *err,
                       size_t errlen)
{
    if (!out || (!shaders && n)) return vp_errf(err, errlen, VT_ERR_INVALID, "vt_gl_program_link: NULL");
    *out = 0;
    int rc = vt_gl_need_current(g, "vt_gl_program_link", err, errlen);
    if (rc) return rc;
    vt_gl_drain();
    GLuint p = glCreateProgram();
    if (!p) return vp_errf(err, errlen, VT_ERR_GL, "glCreateProgram: %s", vt_gl_error_name(glGetError()));
    for (size_t i = 0; i < n; i++) glAttachShader(p, shaders[i]);
    GLenum ge = glGetError();
    if (ge != GL_NO_ERROR) {
        glDeleteProgram(p);
        return vp_errf(err, errlen, VT_ERR_INVALID, "glAttachShader: %s (not a shader name?)",
                    vt_gl_error_name(ge));
    }
    glLinkProgram(p);
    GLint okl = GL_FALSE;
    glGetProgramiv(p, GL_LINK_STATUS, &okl);
    for (size_t i = 0; i < n; i++) glDetachShader(p, shaders[i]);
    if (!okl) {
        put_log(err, errlen, "link", p, true);
        glDeleteProgram(p);
        return VT_ERR_LINK;
    }
    *out = p;
    return vt_gl_ok(err, errlen);
}

int vt_gl_program_build(vt_gl *g, const char *vs, const char *fs, unsigned *out, char *err,
                        size_t errlen)
{
    if (!out) return vp_errf(err, errlen, VT_ERR_INVALID, "vt_gl_program_build: NULL");
    *out = 0;
    unsigned sh[2] = {0, 0};
    int rc = vt_gl_shader_compile(g, GL_VERTEX_SHADER, vs, &sh[0], err, errlen);
    if (!rc) rc = vt_gl_shader_compile(g, GL_FRAGMENT_SHADER, fs, &sh[1], err, errlen);
    if (!rc) rc = vt_gl_program_link(g, sh, 2, out, err, errlen);
    if (sh[0]) glDeleteShader(sh[0]);
    if (sh[1]) glDeleteShader(sh[1]);
    return rc;
}
