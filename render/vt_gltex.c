/*
 * vt_gltex.c — the OpenGL renderer's textures (see vt_gldraw_internal.h):
 * each vt_texview uploaded once with its mip chain (RGBA8, sRGB for the
 * colour slots; float RGBA for an environment map) and kept by (id,
 * generation) while frames use it; the sampler states of a material slot.
 * Cost: one upload per new texture (a 2k RGBA8 chain is 22 MB of copies
 * on llvmpipe), a linear search per lookup (a scene has tens to hundreds
 * of textures).
 */
#include "vt_gldraw_internal.h"
#include "vp_grow.h"

#include <epoxy/gl.h>
#include <stdlib.h>

static unsigned upload(const vt_texview *t, bool srgb)
{
    GLuint name = 0;
    glGenTextures(1, &name);
    if (!name) return 0;
    glBindTexture(GL_TEXTURE_2D, name);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    glPixelStorei(GL_UNPACK_ROW_LENGTH, 0);
    if (t->hdr) {
        glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA32F, (GLsizei)t->w, (GLsizei)t->h, 0, GL_RGBA, GL_FLOAT, t->hdr);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAX_LEVEL, 0);
    } else {
        for (uint32_t k = 0; k < t->levels; k++) {
            GLsizei w = (GLsizei)(t->w >> k ? t->w >> k : 1), h = (GLsizei)(t->h >> k ? t->h >> k : 1);
            glTexImage2D(GL_TEXTURE_2D, (GLint)k, srgb ? GL_SRGB8_ALPHA8 : GL_RGBA8, w, h, 0, GL_RGBA,
                         GL_UNSIGNED_BYTE, t->mip[k]);
        }
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAX_LEVEL, (GLint)t->levels - 1);
    }
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    if (glGetError() != GL_NO_ERROR) {
        glDeleteTextures(1, &name);
        return 0;
    }
    return name;
}

unsigned vt_gltex_get(vt_gltex *c, const vt_texview *t, bool srgb)
{
    if (t->id)
        for (size_t i = 0; i < c->n; i++) {
            vt_gltex_entry *e = &c->e[i];
            if (e->id == t->id && e->gen == t->gen && e->srgb == srgb) {
                e->used = c->frame;
                glBindTexture(GL_TEXTURE_2D, e->name);
                return e->name;
            }
        }
    if (!vp_grow((void **)&c->e, &c->cap, c->n + 1, sizeof *c->e)) return 0;
    unsigned name = upload(t, srgb);
    if (!name) return 0;
    c->uploads++;
    c->e[c->n++] = (vt_gltex_entry){.id = t->id, .gen = t->gen, .srgb = srgb, .name = name, .used = c->frame};
    return name;
}

void vt_gltex_end_frame(vt_gltex *c)
{
    size_t k = 0;
    for (size_t i = 0; i < c->n; i++) {
        vt_gltex_entry *e = &c->e[i];
        if (!e->id || c->frame - e->used >= VT_GLTEX_KEEP) {
            glDeleteTextures(1, &e->name);
            continue;
        }
        c->e[k++] = *e;
    }
    c->n = k;
    c->frame++;
    c->uploads = 0;
}

void vt_gltex_free(vt_gltex *c)
{
    for (size_t i = 0; i < c->n; i++) glDeleteTextures(1, &c->e[i].name);
    free(c->e);
    *c = (vt_gltex){0};
}

static GLint wrap_gl(uint8_t w)
{
    return w == VT_WRAP_CLAMP ? GL_CLAMP_TO_EDGE : w == VT_WRAP_MIRROR ? GL_MIRRORED_REPEAT : GL_REPEAT;
}

void vt_gltex_sampler(unsigned s, const vt_texref *r)
{
    static const GLint minf[6] = {GL_NEAREST, GL_LINEAR, GL_NEAREST_MIPMAP_NEAREST, GL_LINEAR_MIPMAP_NEAREST,
                                  GL_NEAREST_MIPMAP_LINEAR, GL_LINEAR_MIPMAP_LINEAR};
    glSamplerParameteri(s, GL_TEXTURE_WRAP_S, wrap_gl(r->wrap_s));
    glSamplerParameteri(s, GL_TEXTURE_WRAP_T, wrap_gl(r->wrap_t));
    glSamplerParameteri(s, GL_TEXTURE_MIN_FILTER, minf[r->min_filter <= 5 ? r->min_filter : 0]);
    glSamplerParameteri(s, GL_TEXTURE_MAG_FILTER, r->mag_filter == VT_FILTER_LINEAR ? GL_LINEAR : GL_NEAREST);
}
