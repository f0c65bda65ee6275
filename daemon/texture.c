/*
 * texture.c — the scene's textures: uploaded images (PNG, JPEG, OpenEXR),
 * decoded once (render/vt_texture.c), kept with their mip chain and their
 * encoded bytes (snapshots and export hand those back as uploaded).
 *
 * A TEXTURE_PUT reaches here whole (the connection assembled its chunks,
 * handlers.c / upload.c; the journal keeps it whole). Its limits are
 * checked from the image's header before a pixel is allocated: each side
 * <= lim.max_texture_size, and the textures' memory (encoded bytes +
 * decoded levels, scene_texture.mem) <= lim.max_texture_mem. Cost: the
 * decode and the mip chain, on the loop thread under the scene lock
 * (a 2048x2048 PNG: tens of ms; queries wait that long).
 */
#include "scene.h"
#include "vt_texture.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

_Static_assert(VP_TEX_PNG == VT_TEXTURE_PNG && VP_TEX_JPEG == VT_TEXTURE_JPEG && VP_TEX_EXR == VT_TEXTURE_EXR,
               "texture formats: the protocol's and render/'s values agree");

/* scene_texture.flags bit held only inside scene_textures_remove (marks a
 * texture named earlier in the batch); never on the wire (VP_TEX_* is 0x1). */
#define TEX_MARK 0x80u

scene_texture *scene_texture_find(const scene *s, uint32_t id)
{
    uint64_t v;
    if (!id || !idmap_get(&s->textures, id, &v)) return NULL;
    return (scene_texture *)(uintptr_t)v;
}

static void texture_free(scene_texture *t)
{
    if (!t) return;
    vt_texture vt = {.w = t->w, .h = t->h, .levels = t->levels, .mip = t->mip, .hdr = t->hdr};
    vt_texture_free(&vt);
    free(t->bytes);
    free(t);
}

void scene_textures_free(scene *s)
{
    for (size_t i = 0; i < s->textures.cap; i++)
        if (s->textures.used[i]) texture_free((scene_texture *)(uintptr_t)s->textures.vals[i]);
    idmap_free(&s->textures);
    s->texture_mem = 0;
}

/* The first NaN or infinity of an HDR image, as an error. */
static int check_finite(const scene_texture *t, scene_err *err)
{
    static const char ch[4] = {'R', 'G', 'B', 'A'};
    size_t n = (size_t)t->w * t->h * 4;
    for (size_t i = 0; i < n; i++)
        if (!isfinite(t->hdr[i]))
            return scene_fail(err, VP_ERR_NONFINITE, UINT32_MAX, "texture %u: pixel (%zu, %zu) channel %c is %g",
                              t->id, i / 4 % t->w, i / 4 / t->w, ch[i % 4], (double)t->hdr[i]);
    return VP_OK;
}

int scene_texture_put(scene *s, const vp_texture_put *m, scene_err *err)
{
    char why[120];
    uint32_t w = 0, h = 0;
    if (m->offset != 0 || m->len != m->total)
        return scene_fail(err, VP_ERR_INVALID, UINT32_MAX, "texture %u: bytes %u..%u of %u: not the whole image",
                          m->id, m->offset, m->offset + m->len, m->total);
    const char *fmt = vt_texture_format_name(m->format);
    int rc = vt_texture_info(m->format, m->data, m->len, &w, &h, why, sizeof why);
    if (rc)
        return scene_fail(err, rc == VT_ERR_NOMEM ? VP_ERR_BUSY : VP_ERR_INVALID, UINT32_MAX,
                          "texture %u: not a valid %s image: %s", m->id, fmt, why);
    if (w > s->lim.max_texture_size || h > s->lim.max_texture_size)
        return scene_fail(err, VP_ERR_LIMIT, UINT32_MAX,
                          "texture %u: %ux%u is larger than %u pixels a side (--max-texture-size)", m->id, w, h,
                          s->lim.max_texture_size);
    scene_texture *old = scene_texture_find(s, m->id);
    uint64_t mem = sizeof(scene_texture) + (uint64_t)m->len + vt_texture_pixel_bytes(m->format, w, h) +
                   (uint64_t)vt_texture_levels(w, h) * sizeof(uint8_t *);
    uint64_t others = s->texture_mem - (old ? old->mem : 0);
    if (mem > s->lim.max_texture_mem || others > s->lim.max_texture_mem - mem)
        return scene_fail(err, VP_ERR_LIMIT, UINT32_MAX,
                          "texture %u: %ux%u needs %llu bytes, %llu are held, the limit is %llu (--max-texture-mem)",
                          m->id, w, h, (unsigned long long)mem, (unsigned long long)others,
                          (unsigned long long)s->lim.max_texture_mem);
    if (!old && !idmap_reserve(&s->textures, s->textures.count + 1))
        return scene_fail(err, VP_ERR_BUSY, UINT32_MAX, "out of memory");
    vt_texture vt;
    rc = vt_texture_decode(m->format, m->flags & VP_TEX_SRGB, m->data, m->len, &vt, why, sizeof why);
    if (rc)
        return scene_fail(err, rc == VT_ERR_NOMEM ? VP_ERR_BUSY : VP_ERR_INVALID, UINT32_MAX,
                          "texture %u: the %s image does not decode: %s", m->id, fmt, why);
    scene_texture *t = calloc(1, sizeof *t);
    uint8_t *bytes = malloc(m->len);
    if (!t || !bytes || vt.w != w || vt.h != h) {
        if (!t || !bytes) rc = scene_fail(err, VP_ERR_BUSY, UINT32_MAX, "out of memory");
        else rc = scene_fail(err, VP_ERR_INVALID, UINT32_MAX, "texture %u: decoded %ux%u, its header says %ux%u", m->id,
                             vt.w, vt.h, w, h);
        vt_texture_free(&vt);
        free(t);
        free(bytes);
        return rc;
    }
    memcpy(bytes, m->data, m->len);
    *t = (scene_texture){.id = m->id, .format = m->format, .flags = m->flags, .bytes = bytes, .nbytes = m->len,
                         .w = w, .h = h, .levels = vt.levels, .hdr = vt.hdr, .mip = vt.mip, .mem = mem,
                         .users = old ? old->users : 0, .gen = ++s->texture_gens};
    /* an EXR is environment light: NaN or infinity would poison every pixel it lights */
    rc = t->hdr ? check_finite(t, err) : VP_OK;
    /* the sky's texture stays fit to be the sky */
    if (!rc && old && s->env.sky_mode == VP_SKY_TEXTURE && s->env.sky_texture == m->id)
        rc = scene_env_sky_check(s, t, err);
    if (rc) {
        texture_free(t);
        return rc;
    }
    s->texture_mem = others + mem;
    texture_free(old);
    idmap_put(&s->textures, m->id, (uint64_t)(uintptr_t)t);
    s->epoch++;
    return VP_OK;
}

int scene_textures_remove(scene *s, const vp_id_batch *b, scene_err *err)
{
    int rc = VP_OK;
    uint32_t i = 0;
    for (; i < b->count && !rc; i++) {
        uint64_t id = vp_id_get(b, i);
        scene_texture *t = id <= UINT32_MAX ? scene_texture_find(s, (uint32_t)id) : NULL;
        if (!t) rc = scene_fail(err, VP_ERR_UNKNOWN_ID, i, "record %u: no texture %llu", i, (unsigned long long)id);
        else if (t->flags & TEX_MARK)
            rc = scene_fail(err, VP_ERR_DUPLICATE, i, "record %u: texture %llu twice in the batch", i,
                            (unsigned long long)id);
        else if (t->users)
            rc = scene_fail(err, VP_ERR_STATE, i, "record %u: texture %llu is in use (%u materials or the sky)", i,
                            (unsigned long long)id, t->users);
        else t->flags |= TEX_MARK;
    }
    for (uint32_t k = 0; k < i; k++) { /* the marks off again; applied when all passed */
        uint64_t id = vp_id_get(b, k);
        scene_texture *t = id <= UINT32_MAX ? scene_texture_find(s, (uint32_t)id) : NULL;
        if (!t || !(t->flags & TEX_MARK)) continue;
        t->flags &= (uint8_t)~TEX_MARK;
        if (rc) continue;
        s->texture_mem -= t->mem;
        idmap_del(&s->textures, id);
        texture_free(t);
    }
    if (!rc) s->epoch++;
    return rc;
}
