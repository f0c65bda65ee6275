/*
 * vt_gl_target.c — vt_gl.h's offscreen targets (a framebuffer object with
 * a float colour texture and a 32-bit float depth texture, listed on their
 * context so vt_gl_close frees them) and their readback (direct, or
 * through a pixel pack buffer the target owns). Every call needs the
 * context current (vt_gl_need_current) and restores the bindings it
 * changes.
 */
#include "vt_gl_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static const char *fbo_status_name(GLenum s)
{
    switch (s) {
    case GL_FRAMEBUFFER_COMPLETE:                      return "complete";
    case GL_FRAMEBUFFER_UNDEFINED:                     return "GL_FRAMEBUFFER_UNDEFINED";
    case GL_FRAMEBUFFER_INCOMPLETE_ATTACHMENT:         return "GL_FRAMEBUFFER_INCOMPLETE_ATTACHMENT";
    case GL_FRAMEBUFFER_INCOMPLETE_MISSING_ATTACHMENT: return "GL_FRAMEBUFFER_INCOMPLETE_MISSING_ATTACHMENT";
    case GL_FRAMEBUFFER_INCOMPLETE_DRAW_BUFFER:        return "GL_FRAMEBUFFER_INCOMPLETE_DRAW_BUFFER";
    case GL_FRAMEBUFFER_INCOMPLETE_READ_BUFFER:        return "GL_FRAMEBUFFER_INCOMPLETE_READ_BUFFER";
    case GL_FRAMEBUFFER_UNSUPPORTED:                   return "GL_FRAMEBUFFER_UNSUPPORTED";
    case GL_FRAMEBUFFER_INCOMPLETE_MULTISAMPLE:        return "GL_FRAMEBUFFER_INCOMPLETE_MULTISAMPLE";
    }
    return "unknown framebuffer status";
}

/* ---- targets ----------------------------------------------------------------- */

/* (Re)specifies both textures at w x h and checks the framebuffer. The
 * caller has checked the size. Restores the bindings it changes. */
static int target_alloc(vt_gl_target *t, uint32_t w, uint32_t h, char *err, size_t errlen)
{
    GLint old_tex = 0, old_draw = 0, old_read = 0;
    glGetIntegerv(GL_TEXTURE_BINDING_2D, &old_tex);
    glGetIntegerv(GL_DRAW_FRAMEBUFFER_BINDING, &old_draw);
    glGetIntegerv(GL_READ_FRAMEBUFFER_BINDING, &old_read);
    vt_gl_drain();

    GLenum cfmt = t->format == VT_GL_RGBA32F ? GL_RGBA32F : GL_RGBA16F;
    const GLuint tex[2] = {t->color, t->depth};
    for (int i = 0; i < 2; i++) {
        glBindTexture(GL_TEXTURE_2D, tex[i]);
        if (i == 0)
            glTexImage2D(GL_TEXTURE_2D, 0, (GLint)cfmt, (GLsizei)w, (GLsizei)h, 0, GL_RGBA, GL_FLOAT,
                         NULL);
        else
            glTexImage2D(GL_TEXTURE_2D, 0, GL_DEPTH_COMPONENT32F, (GLsizei)w, (GLsizei)h, 0,
                         GL_DEPTH_COMPONENT, GL_FLOAT, NULL);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_BASE_LEVEL, 0);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAX_LEVEL, 0);
    }
    glBindFramebuffer(GL_FRAMEBUFFER, t->fbo);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, t->color, 0);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_TEXTURE_2D, t->depth, 0);
    const GLenum buf = GL_COLOR_ATTACHMENT0;
    glDrawBuffers(1, &buf);
    glReadBuffer(GL_COLOR_ATTACHMENT0);
    GLenum st = glCheckFramebufferStatus(GL_FRAMEBUFFER);
    GLenum ge = glGetError();

    glBindTexture(GL_TEXTURE_2D, (GLuint)old_tex);
    glBindFramebuffer(GL_DRAW_FRAMEBUFFER, (GLuint)old_draw);
    glBindFramebuffer(GL_READ_FRAMEBUFFER, (GLuint)old_read);
    const char *fname = t->format == VT_GL_RGBA32F ? "RGBA32F" : "RGBA16F";
    if (ge != GL_NO_ERROR)
        return vp_errf(err, errlen, VT_ERR_GL, "target %ux%u %s: %s", w, h, fname,
                    vt_gl_error_name(ge));
    if (st != GL_FRAMEBUFFER_COMPLETE)
        return vp_errf(err, errlen, VT_ERR_FRAMEBUFFER, "target %ux%u %s: %s", w, h, fname,
                    fbo_status_name(st));
    t->w = w;
    t->h = h;
    return VT_OK;
}

static int check_size(const vt_gl *g, uint32_t w, uint32_t h, char *err, size_t errlen)
{
    uint32_t m = (uint32_t)g->info.max_target_size;
    if (w < 1 || h < 1 || w > m || h > m)
        return vp_errf(err, errlen, VT_ERR_RANGE, "target %ux%u: each side must be 1..%u", w, h, m);
    return VT_OK;
}

static void target_delete_gl(vt_gl_target *t)
{
    glDeleteFramebuffers(1, &t->fbo);
    glDeleteTextures(1, &t->color);
    glDeleteTextures(1, &t->depth);
    if (t->pbo) glDeleteBuffers(1, &t->pbo);
}

int vt_gl_target_create(vt_gl *g, uint32_t w, uint32_t h, const vt_gl_target_desc *desc,
                        vt_gl_target **out, char *err, size_t errlen)
{
    vt_gl_target_desc d = desc ? *desc : (vt_gl_target_desc){0};
    if (!out) return vp_errf(err, errlen, VT_ERR_INVALID, "vt_gl_target_create: out is NULL");
    *out = NULL;
    int rc = vt_gl_need_current(g, "vt_gl_target_create", err, errlen);
    if (rc) return rc;
    if (d.color != VT_GL_RGBA16F && d.color != VT_GL_RGBA32F)
        return vp_errf(err, errlen, VT_ERR_INVALID, "vt_gl_target_create: bad colour format");
    if ((rc = check_size(g, w, h, err, errlen))) return rc;
    vt_gl_target *t = calloc(1, sizeof *t);
    if (!t) return vp_errf(err, errlen, VT_ERR_NOMEM, "vt_gl_target_create: out of memory");
    t->g = g;
    t->format = d.color;
    glGenFramebuffers(1, &t->fbo);
    glGenTextures(1, &t->color);
    glGenTextures(1, &t->depth);
    if ((rc = target_alloc(t, w, h, err, errlen))) {
        target_delete_gl(t);
        free(t);
        return rc;
    }
    t->next = g->targets;
    if (g->targets) g->targets->prev = t;
    g->targets = t;
    *out = t;
    return vt_gl_ok(err, errlen);
}

int vt_gl_target_resize(vt_gl_target *t, uint32_t w, uint32_t h, char *err, size_t errlen)
{
    if (!t) return vp_errf(err, errlen, VT_ERR_INVALID, "vt_gl_target_resize: NULL");
    int rc = vt_gl_need_current(t->g, "vt_gl_target_resize", err, errlen);
    if (rc) return rc;
    if ((rc = check_size(t->g, w, h, err, errlen))) return rc;
    if (w == t->w && h == t->h) return vt_gl_ok(err, errlen);
    if ((rc = target_alloc(t, w, h, err, errlen))) return rc;
    return vt_gl_ok(err, errlen);
}

void vt_gl_target_destroy(vt_gl_target *t)
{
    if (!t) return;
    vt_gl *g = t->g;
    eglBindAPI(EGL_OPENGL_API);
    if (vt_gl_is_current(g)) target_delete_gl(t);
    if (t->prev) t->prev->next = t->next;
    else g->targets = t->next;
    if (t->next) t->next->prev = t->prev;
    free(t);
}

int vt_gl_target_bind(vt_gl_target *t)
{
    if (!t) return VT_ERR_INVALID;
    int rc = vt_gl_need_current(t->g, "vt_gl_target_bind", NULL, 0);
    if (rc) return rc;
    glBindFramebuffer(GL_FRAMEBUFFER, t->fbo);
    glViewport(0, 0, (GLsizei)t->w, (GLsizei)t->h);
    return VT_OK;
}

int vt_gl_target_clear(vt_gl_target *t, const float rgba[4], float depth)
{
    int rc = vt_gl_target_bind(t);
    if (rc) return rc;
    if (rgba) glClearBufferfv(GL_COLOR, 0, rgba);
    if (!isnan(depth)) {
        const GLfloat z = depth < 0 ? 0.0f : depth > 1 ? 1.0f : depth;
        glClearBufferfv(GL_DEPTH, 0, &z);
    }
    return VT_OK;
}

void vt_gl_target_size(const vt_gl_target *t, uint32_t *w, uint32_t *h)
{
    if (w) *w = t ? t->w : 0;
    if (h) *h = t ? t->h : 0;
}

unsigned vt_gl_target_fbo(const vt_gl_target *t) { return t ? t->fbo : 0; }
unsigned vt_gl_target_color_texture(const vt_gl_target *t) { return t ? t->color : 0; }
unsigned vt_gl_target_depth_texture(const vt_gl_target *t) { return t ? t->depth : 0; }

/* ---- readback ------------------------------------------------------------------ */

size_t vt_gl_read_bound(uint32_t w, uint32_t h, bool color)
{
    size_t n = (size_t)w * h;
    if (h && n / h != w) return 0;
    if (color) {
        if (n > SIZE_MAX / 16) return 0; /* 4 floats of 4 bytes must fit too */
        n *= 4;
    }
    return n;
}

int vt_gl_readback(vt_gl_target *t, float *rgba, float *depth, const vt_gl_read_desc *desc,
                   char *err, size_t errlen)
{
    vt_gl_read_desc d = desc ? *desc : (vt_gl_read_desc){0};
    if (!t) return vp_errf(err, errlen, VT_ERR_INVALID, "vt_gl_readback: NULL target");
    if (!rgba && !depth)
        return vp_errf(err, errlen, VT_ERR_INVALID, "vt_gl_readback: no colour or depth buffer");
    if ((unsigned)d.path > VT_GL_READ_PBO)
        return vp_errf(err, errlen, VT_ERR_INVALID, "vt_gl_readback: bad path");
    int rc = vt_gl_need_current(t->g, "vt_gl_readback", err, errlen);
    if (rc) return rc;
    if (d.w == 0 && d.h == 0) {
        d.x = d.y = 0;
        d.w = t->w;
        d.h = t->h;
    }
    if (d.w == 0 || d.h == 0 || d.x > t->w || d.w > t->w - d.x || d.y > t->h ||
        d.h > t->h - d.y)
        return vp_errf(err, errlen, VT_ERR_RANGE,
                    "vt_gl_readback: region %ux%u at (%u,%u) outside the %ux%u target", d.w, d.h,
                    d.x, d.y, t->w, t->h);
    const size_t npx = (size_t)d.w * d.h; /* sides below 2^31 each: no overflow */
    const size_t cbytes = rgba ? npx * 16 : 0, zbytes = depth ? npx * 4 : 0;
    bool pbo = d.path == VT_GL_READ_PBO;

    GLint old_read = 0, old_pack = 0;
    glGetIntegerv(GL_READ_FRAMEBUFFER_BINDING, &old_read);
    glGetIntegerv(GL_PIXEL_PACK_BUFFER_BINDING, &old_pack);
    vt_gl_drain();
    glBindFramebuffer(GL_READ_FRAMEBUFFER, t->fbo);
    glPixelStorei(GL_PACK_ALIGNMENT, 4);
    glPixelStorei(GL_PACK_ROW_LENGTH, 0);
    glPixelStorei(GL_PACK_SKIP_ROWS, 0);
    glPixelStorei(GL_PACK_SKIP_PIXELS, 0);
    const GLint x = (GLint)d.x, y = (GLint)d.y;
    const GLsizei w = (GLsizei)d.w, h = (GLsizei)d.h;
    GLenum ge = GL_NO_ERROR;
    if (!pbo) {
        glBindBuffer(GL_PIXEL_PACK_BUFFER, 0);
        if (rgba) glReadPixels(x, y, w, h, GL_RGBA, GL_FLOAT, rgba);
        if (depth) glReadPixels(x, y, w, h, GL_DEPTH_COMPONENT, GL_FLOAT, depth);
        ge = glGetError();
    } else {
        size_t need = cbytes + zbytes;
        if (!t->pbo) glGenBuffers(1, &t->pbo);
        glBindBuffer(GL_PIXEL_PACK_BUFFER, t->pbo);
        if (t->pbo_bytes < need) {
            glBufferData(GL_PIXEL_PACK_BUFFER, (GLsizeiptr)need, NULL, GL_STREAM_READ);
            t->pbo_bytes = (ge = glGetError()) == GL_NO_ERROR ? need : 0;
        }
        if (ge == GL_NO_ERROR) {
            /* both reads queued before the one wait in the map */
            if (rgba) glReadPixels(x, y, w, h, GL_RGBA, GL_FLOAT, (void *)0);
            if (depth)
                glReadPixels(x, y, w, h, GL_DEPTH_COMPONENT, GL_FLOAT, (void *)(uintptr_t)cbytes);
            const unsigned char *p =
                glMapBufferRange(GL_PIXEL_PACK_BUFFER, 0, (GLsizeiptr)need, GL_MAP_READ_BIT);
            if (p) {
                if (rgba) memcpy(rgba, p, cbytes);
                if (depth) memcpy(depth, p + cbytes, zbytes);
                glUnmapBuffer(GL_PIXEL_PACK_BUFFER);
            }
            ge = glGetError();
            if (!p && ge == GL_NO_ERROR) ge = GL_OUT_OF_MEMORY;
        }
    }
    glBindBuffer(GL_PIXEL_PACK_BUFFER, (GLuint)old_pack);
    glBindFramebuffer(GL_READ_FRAMEBUFFER, (GLuint)old_read);
    if (ge != GL_NO_ERROR)
        return vp_errf(err, errlen, VT_ERR_GL, "vt_gl_readback%s: %s", pbo ? " (PBO)" : "",
                    vt_gl_error_name(ge));
    return vt_gl_ok(err, errlen);
}
