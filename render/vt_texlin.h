/*
 * vt_texlin.h — the software renderer's decoded copies of its sRGB
 * textures (internal to render/): each level as linear-light RGBA in
 * IEEE half floats, 64 bits a texel, so the shading kernel's sampler
 * (vt_gather.inl, AVX2) fetches a texel's decoded colour with two 64-bit
 * gathers a corner for 8 pixels instead of its bytes and three sRGB
 * table gathers. A half keeps 11 significant bits: a decoded value
 * within 2^-11 relative of the table's (tests/test_scene_render.c's
 * gather test holds the sampler to 1e-3).
 *
 * The cache is keyed by texture id and generation (a replaced texture
 * has a new generation; id 0, pixels named for one frame only, is never
 * kept), made at the start of a frame for the sRGB slots
 * the frame's materials sample, and forgets what a frame no longer uses
 * after a few frames; textures above a size budget are left to the table
 * path.
 */
#ifndef VANTAGE_VT_TEXLIN_H
#define VANTAGE_VT_TEXLIN_H

#include "vt_soft.h"

#include <stddef.h>
#include <stdint.h>

typedef struct vt_texlin {
    uint32_t id, gen, w, h, levels;
    uint64_t *lv[16];       /* level k: (w >> k) x (h >> k) texels, R G B A halves from bit 0 */
    /* level k's black footprints, a bit a texel (bit i % 32 of word i /
       32, i = y w + x): set where texels (x, y), (x + 1, y), (x, y + 1),
       (x + 1, y + 1), wrapped, all have R = G = B = 0, so a bilinear
       sample whose lower texel is (x, y) is black without fetching it
       (with CLAMP's edges too: their footprints are subsets of these).
       NULL (every level) for a texture with few black footprints: the
       test would cost the sampler more than it skips. Made for the
       city's window lights (black but for a window in one bay in
       three), where whole groups of 8 pixels skip their samples. */
    uint32_t *zb[16];
    uint64_t used;          /* the frame that last used it */
    size_t bytes;
} vt_texlin;

typedef struct vt_texcache {
    vt_texlin *e;
    uint32_t n, cap;
    uint64_t frame;
    size_t bytes;
    /* the frame's sRGB slots' views and their copies (NULL: none), at a
       hash of the view's address (vt_texcache_find's probe; a view whose
       slot another took is searched for) */
    const vt_texview *mv[16];
    const vt_texlin *ml[16];
} vt_texcache;

/* The frame's sRGB texture slots (instances' materials and the ground's)
 * made ready where memory and the budget allow (the rest is sampled by
 * table). */
void vt_texcache_prepare(vt_texcache *c, const vt_instance *inst, uint32_t ninst, const vt_material *ground);
/* The decoded copy of view t, or NULL: the prepared views by one probe
 * (the sampler asks for one 2-3 times a group of 8 pixels: the search
 * over the entries was ~2 % of the shading's instructions), others by
 * vt_texcache_search. */
const vt_texlin *vt_texcache_search(const vt_texcache *c, const vt_texview *t);
static inline unsigned vt_texcache_slot(const vt_texview *t)
{
    uintptr_t a = (uintptr_t)t;
    return (unsigned)((a >> 4 ^ a >> 8) & 15);
}
static inline const vt_texlin *vt_texcache_find(const vt_texcache *c, const vt_texview *t)
{
    if (c && t && c->mv[vt_texcache_slot(t)] == t) return c->ml[vt_texcache_slot(t)];
    return vt_texcache_search(c, t);
}
void vt_texcache_free(vt_texcache *c);

/* A float in [0, 1] as an IEEE half (round to nearest even; below the
 * smallest normal half, 2^-14, a subnormal), and back. */
uint16_t vt_half_of(float v);
float vt_half_to_float(uint16_t h);

#endif
