/*
 * vt_texlin.c — decoded half-float copies of the frame's sRGB textures
 * for the software sampler (see vt_texlin.h).
 */
#include "vt_texlin.h"

#include "vt_surface.h"

#include <stdlib.h>
#include <string.h>

#define TEXLIN_BUDGET ((size_t)96 << 20) /* bytes of copies kept at most */
#define TEXLIN_KEEP 8                    /* frames a copy outlives its last use */

uint16_t vt_half_of(float v)
{
    if (!(v > 0)) return 0; /* 0, negative, NaN */
    if (v >= 65504.0f) return 0x7BFF;
    uint32_t b;
    memcpy(&b, &v, sizeof b);
    int e = (int)(b >> 23) - 127;
    if (e < -14) { /* a subnormal half: a multiple of 2^-24 */
        float m = v * 16777216.0f;
        uint32_t q = (uint32_t)m;
        float r = m - (float)q;
        if (r > 0.5f || (r == 0.5f && (q & 1))) q++;
        return (uint16_t)q; /* 1024: the least normal, as it should */
    }
    uint32_t mant = b & 0x7FFFFF, h = (uint32_t)(e + 15) << 10 | mant >> 13, rest = mant & 0x1FFF;
    if (rest > 0x1000 || (rest == 0x1000 && (h & 1))) h++; /* a carry steps the exponent: still right */
    return (uint16_t)h;
}

float vt_half_to_float(uint16_t h)
{
    uint32_t b = (uint32_t)(h & 0x7FFF) << 13;
    float f;
    memcpy(&f, &b, sizeof f);
    return f * 0x1p112f;
}

/* The copy of view t (its pixels named by id and generation), or NULL. */
static vt_texlin *entry_of(const vt_texcache *c, const vt_texview *t)
{
    if (!c || !t || !t->id) return NULL; /* id 0: pixels of this frame only (vt_scene.h) */
    for (uint32_t i = 0; i < c->n; i++) {
        vt_texlin *e = &c->e[i];
        if (e->id == t->id && e->gen == t->gen && e->w == t->w && e->h == t->h && e->levels == t->levels) return e;
    }
    return NULL;
}

const vt_texlin *vt_texcache_search(const vt_texcache *c, const vt_texview *t)
{
    return entry_of(c, t);
}

static void entry_free(vt_texcache *c, uint32_t i)
{
    vt_texlin *e = &c->e[i];
    for (int k = 0; k < 16; k++) free(e->lv[k]), free(e->zb[k]);
    c->bytes -= e->bytes;
    c->e[i] = c->e[--c->n];
}

/* The black footprints of a w x h level (vt_texlin.h's zb) into z
 * (zeroed, (w h + 31) / 32 words); returns how many. */
static size_t black_mask(const uint64_t *lv, size_t w, size_t h, uint32_t *z)
{
    const uint64_t rgb = 0xFFFFFFFFFFFFull;
    size_t n = 0;
    for (size_t y = 0; y < h; y++) {
        const uint64_t *r0 = lv + y * w, *r1 = lv + (y + 1 == h ? 0 : y + 1) * w;
        for (size_t x = 0; x < w; x++) {
            size_t x1 = x + 1 == w ? 0 : x + 1;
            if ((r0[x] | r0[x1] | r1[x] | r1[x1]) & rgb) continue;
            size_t i = y * w + x;
            z[i / 32] |= 1u << (i % 32);
            n++;
        }
    }
    return n;
}

/* e's black-footprint masks where level 0 has at least 1 in 8 black
 * (else none: vt_texlin.h); false: no memory. */
static bool masks_make(vt_texlin *e)
{
    for (uint32_t k = 0; k < e->levels; k++) {
        size_t w = e->w >> k ? e->w >> k : 1, h = e->h >> k ? e->h >> k : 1, words = (w * h + 31) / 32;
        if (!(e->zb[k] = calloc(words, 4))) return false;
        size_t n = black_mask(e->lv[k], w, h, e->zb[k]);
        e->bytes += words * 4;
        if (k == 0 && n * 8 < w * h) {
            free(e->zb[0]);
            e->zb[0] = NULL;
            e->bytes -= words * 4;
            return true;
        }
    }
    return true;
}

/* A copy of t made (false: no memory, or over the budget). */
static bool entry_make(vt_texcache *c, const vt_texview *t)
{
    if (!t->mip || t->levels < 1 || t->levels > 16) return false;
    size_t bytes = 0;
    for (uint32_t k = 0; k < t->levels; k++) {
        size_t w = t->w >> k ? t->w >> k : 1, h = t->h >> k ? t->h >> k : 1;
        bytes += w * h * 8;
    }
    if (bytes > TEXLIN_BUDGET - c->bytes) return false;
    if (c->n == c->cap) {
        uint32_t cap = c->cap ? 2 * c->cap : 8;
        vt_texlin *ne = realloc(c->e, cap * sizeof *ne);
        if (!ne) return false;
        c->e = ne, c->cap = cap;
    }
    vt_texlin e = {.id = t->id, .gen = t->gen, .w = t->w, .h = t->h, .levels = t->levels, .used = c->frame,
                   .bytes = bytes};
    const float *tab = vt_srgb_table();
    uint16_t hs[256], ha[256];
    for (int i = 0; i < 256; i++) hs[i] = vt_half_of(tab[i]), ha[i] = vt_half_of((float)i / 255.0f);
    for (uint32_t k = 0; k < t->levels; k++) {
        size_t w = t->w >> k ? t->w >> k : 1, h = t->h >> k ? t->h >> k : 1, n = w * h;
        if (!(e.lv[k] = malloc(n * 8))) {
            for (uint32_t j = 0; j < k; j++) free(e.lv[j]);
            return false;
        }
        const uint8_t *p = t->mip[k];
        for (size_t i = 0; i < n; i++, p += 4)
            e.lv[k][i] = (uint64_t)hs[p[0]] | (uint64_t)hs[p[1]] << 16 | (uint64_t)hs[p[2]] << 32 | (uint64_t)ha[p[3]] << 48;
    }
    if (!masks_make(&e)) {
        for (uint32_t j = 0; j < t->levels; j++) free(e.lv[j]), free(e.zb[j]);
        return false;
    }
    c->e[c->n++] = e;
    c->bytes += e.bytes; /* the masks too (1/64 of the copy) */
    return true;
}

/* Slot r of a material: an sRGB slot (base colour, emissive) made ready
 * where it can be (else it is sampled by table). */
static void slot_ready(vt_texcache *c, const vt_texref *r)
{
    if (!r->tex || !r->tex->mip || !r->tex->id) return; /* id 0 names no pixels across frames */
    vt_texlin *e = entry_of(c, r->tex);
    if (e) e->used = c->frame;
    else (void)entry_make(c, r->tex);
}

void vt_texcache_prepare(vt_texcache *c, const vt_instance *inst, uint32_t ninst, const vt_material *ground)
{
    c->frame++;
    const vt_material *last = NULL;
    for (uint32_t i = 0; i <= ninst; i++) {
        const vt_material *m = i < ninst ? inst[i].mat : ground;
        if (!m || m == last) continue; /* instances of one material come in runs */
        last = m;
        slot_ready(c, &m->tex[VT_SLOT_BASE]);
        slot_ready(c, &m->tex[VT_SLOT_EMISSIVE]);
    }
    /* what recent frames did not use goes */
    for (uint32_t i = 0; i < c->n;)
        if (c->frame - c->e[i].used > TEXLIN_KEEP) entry_free(c, i);
        else i++;
    /* the probes, once the entries stay where they are */
    memset(c->mv, 0, sizeof c->mv);
    last = NULL;
    for (uint32_t i = 0; i <= ninst; i++) {
        const vt_material *m = i < ninst ? inst[i].mat : ground;
        if (!m || m == last) continue;
        last = m;
        for (int k = 0; k < 2; k++) {
            const vt_texview *t = m->tex[k ? VT_SLOT_EMISSIVE : VT_SLOT_BASE].tex;
            if (!t) continue;
            unsigned h = vt_texcache_slot(t);
            c->mv[h] = t, c->ml[h] = entry_of(c, t);
        }
    }
}

void vt_texcache_free(vt_texcache *c)
{
    while (c->n) entry_free(c, 0);
    free(c->e);
    memset(c, 0, sizeof *c);
}
