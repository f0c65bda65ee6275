/*
 * vt_shadow.h — the sun's cascaded shadow maps (issue 20), drawn by the
 * project's own rasterizer in the software path (and by GL in the GL
 * path, with the same cascade fitting): what the shading kernels ask per
 * pixel is the sun's visibility at a camera-relative point.
 *
 * The rules both renderers follow (vt_shadow.c; vt_shadow_glsl.c mirrors
 * the lookup):
 *  * cascades: VT_SHADOW_CASCADES slices of the view's depth range, split
 *    by the practical scheme (lambda VT_SHADOW_LAMBDA between the
 *    logarithmic and the uniform split) up to the shadow distance: the
 *    farthest view depth of what the frame shows (its instances, and the
 *    ground their shadows fall on), at most VT_SHADOW_MAX_DIST and the far
 *    plane. Each is an orthographic map along the sun fitted to its
 *    slice's bounding sphere (whose size does not change as the camera
 *    turns) and moved in whole texels in world-space light coordinates,
 *    so the texel grid stays put on the ground as the camera moves;
 *  * the maps hold, per texel, the largest s.p (s: towards the sun) of the
 *    casters' faces turned away from the sun (back faces: the lit front
 *    faces of closed meshes then never compare against themselves, so
 *    there is no acne on them; double-sided materials cast both faces),
 *    of the casters whose shadow can reach what the view shows in that
 *    cascade (vt_shadow_fit's hull; elsewhere a map may miss casters);
 *  * lookup: the cascade by the point's view depth, a band over the last
 *    VT_SHADOW_BLEND of each cascade blended into the next (the last one
 *    fades to lit), the point moved along its normal by
 *    VT_SHADOW_NOFS texels (normal offset) and compared with a depth bias
 *    of (VT_SHADOW_BIAS_C + VT_SHADOW_BIAS_S tan theta) texels (slope
 *    scaled), PCF: a 3-texel box filter in bilinear steps (4x4 texels,
 *    weights (1 - f, 1, 1, f) / 3 per axis): edges soft over 3 texels;
 *    faces turned away from the sun (n.s <= 0) get 1 (the sun term is 0
 *    there anyway); beyond the last cascade: lit.
 * Alpha-MASK materials cast as opaque (a MASK material whose constant
 * alpha is under its cutoff casts nothing); damaged instances cast as
 * intact (their holes do not let the sun through).
 */
#ifndef VANTAGE_VT_SHADOW_H
#define VANTAGE_VT_SHADOW_H

#include "culling.h"
#include "vt_scene.h"

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#define VT_SHADOW_CASCADES 4
#define VT_SHADOW_LAMBDA 0.8
#define VT_SHADOW_MAX_DIST 2000.0 /* metres */
#define VT_SHADOW_BLEND 0.1f      /* of a cascade's depth range */
#define VT_SHADOW_NOFS 1.0f       /* texels */
#define VT_SHADOW_BIAS_C 0.5f     /* texels */
#define VT_SHADOW_BIAS_S 1.0f     /* texels per unit tan theta, tan clamped to 8 */
#define VT_SHADOW_MIN_SUN 0.02f   /* sun's y: lower is "at the horizon", no shadows */
#define VT_SHADOW_REACH 4.0f      /* texels: how far from a receiver its lookup reads (1 normal offset + 2.5 taps, rounded up) */

typedef struct vt_shadow vt_shadow;
struct vt_mesh;
struct vt_instance;
struct vt_frame;

/* The cascades of one frame, as both renderers draw and read them.
 * Camera-relative, float where the lookup reads it. */
typedef struct vt_shadow_fit {
    uint32_t n;              /* cascades */
    uint32_t size;           /* texels a side of each map */
    float s[3], u[3], v[3];  /* light basis: towards the sun, map x, map y (u x v = s) */
    float drow[4];           /* a point's view depth: drow . (p, 1) */
    float split[VT_SHADOW_CASCADES + 1]; /* view depths: cascade i covers split[i]..split[i+1] */
    float scale[VT_SHADOW_CASCADES];     /* 1 / texel size */
    float off[VT_SHADOW_CASCADES][2];    /* map x = u.p scale + off[0], y likewise (texels) */
    float texel[VT_SHADOW_CASCADES];     /* metres a texel */
    float cen[VT_SHADOW_CASCADES][3];    /* the slice's bounding sphere */
    float rad[VT_SHADOW_CASCADES];
    /* what cascade i's lookups can read: the outline, seen from the sun,
       of the view's slice its lookups come from (split[i] less the
       previous cascade's blend band .. split[i + 1]), as nhull[i] edges
       (a, b, h): u.p a + v.p b <= h inside, widened by VT_SHADOW_REACH
       texels (the normal offset and the PCF's footprint). A caster
       wholly outside darkens none of them: vt_shadow_draw leaves it out
       of that map. nhull[i] 0: no outline (every caster of the sphere) */
    float hull[VT_SHADOW_CASCADES][8][3];
    uint32_t nhull[VT_SHADOW_CASCADES];
} vt_shadow_fit;

/* The unit direction towards env's sun, normalised as vt_penv_make does;
 * false (no shadow pass): no environment, no sun, the sun at or below
 * the horizon (y < VT_SHADOW_MIN_SUN), or VT_FX_SHADOWS in fx_off. */
bool vt_shadow_sun_dir(const vt_env *env, uint32_t fx_off, float s[3]);

/* Fits the cascades for view v (width x height pixels: the map size is
 * scaled from it) and sun s, the shadow distance bounded by the view depth
 * of the instances inst (what the frame shows; their world boxes from
 * their meshes' bounds mb) and their shadows on env's ground. false: no
 * usable cascade (the view's depth range is empty or not finite). */
bool vt_shadow_fit_make(const cull_view *v, uint32_t width, uint32_t height, const vt_env *env, const float s[3],
                        const float (*mb)[6], const struct vt_instance *inst, uint32_t ninst, vt_shadow_fit *fit);

/* The cascades of frame f (its environment and fx_off, view, size,
 * instances; the meshes' bounds computed here): vt_shadow_sun_dir, then
 * vt_shadow_fit_make. false: no shadow pass (or out of memory for the
 * bounds, a frame without shadows). What the GL path and the daemon's
 * caster query use. */
bool vt_shadow_fit_frame(const struct vt_frame *f, vt_shadow_fit *fit);

/* An orthographic view along the sun covering every cascade's sphere,
 * extended `reach` metres towards the sun: what may cast into the
 * cascades (the daemon's caster query, frustum only). false: no view. */
bool vt_shadow_caster_view(const vt_shadow_fit *fit, const double origin[3], double reach, cull_view *out);

int vt_shadow_create(vt_shadow **out);
void vt_shadow_destroy(vt_shadow *sh);

/* Draws the cascades of fit from the casters (camera-relative to origin;
 * mb: each mesh's bounds) with pool's threads (NULL: one). Returns 0 or
 * VT_ERR_NOMEM (err filled); *tris: the triangles drawn, all cascades. */
int vt_shadow_draw(vt_shadow *sh, cull_pool *pool, uint32_t threads, const vt_shadow_fit *fit,
                   const double origin[3], const struct vt_mesh *meshes, const float (*mb)[6],
                   const struct vt_instance *casters, uint32_t ncasters, uint32_t *tris, char *err, size_t errlen);

/* The fit of the last draw, and its maps: n maps of size x size floats,
 * rows by v (what the tests inspect). */
const vt_shadow_fit *vt_shadow_fit_of(const vt_shadow *sh);
const float *vt_shadow_maps(const vt_shadow *sh);
/* The last draw's footprint tiles, the span lookup's shortcut (vt_shadow.c):
 * per cascade g x g (g = size / VT_SHADOW_TILE); tile (tx, ty) bounds the
 * map's depth over texels VT_SHADOW_TILE t - 1 .. VT_SHADOW_TILE t + 3 on
 * both axes (the union of the 4 x 4 footprints that pick the tile),
 * clipped to the map, packed in 32 bits (half the memory of two floats,
 * one gather): bits 0..15 a and 16..31 b, the
 * depth range within qlo[c] + a / qinv[c] .. qlo[c] + b / qinv[c] of
 * cascade c; a 0 or b 65535: not bounded on that side (beyond the
 * quantised range, or NaN). The bounds are conservative by more than a
 * step (vt_shadow_tiles.c, pack1), so a lookup decided by them is the
 * taps' answer bit for bit. qlo, qinv: filled, VT_SHADOW_CASCADES each. */
#define VT_SHADOW_TILE 2
const uint32_t *vt_shadow_tiles(const vt_shadow *sh, float qlo[VT_SHADOW_CASCADES], float qinv[VT_SHADOW_CASCADES]);

/* The fraction of the sun that reaches camera-relative point p with unit
 * normal n, 0 (in shadow) .. 1 (lit), PCF-filtered. sh NULL: 1. */
float vt_shadow_sun(const vt_shadow *sh, const float p[3], const float n[3]);
/* The same from a fit and its maps (vt_shadow_sun's body). */
float vt_shadow_lookup(const vt_shadow_fit *fit, const float *maps, const float p[3], const float n[3]);

/* vt_shadow_sun over a span: out[i] *= the visibility of point
 * (px, py, pz)[i] with normal (nx, ny, nz)[i], i < n; sh NULL: nothing.
 * The same values as vt_shadow_sun bit for bit, W pixels a step (the
 * instance cull_isa_default picks, or vt_shadow_set_isa's). */
void vt_shadow_sun_n(const vt_shadow *sh, unsigned n, const float *px, const float *py, const float *pz,
                     const float *nx, const float *ny, const float *nz, float *out);
/* Later lookups of sh use isa's instance (enum cull_isa) where this CPU
 * has it, else the default (the tests compare them). */
void vt_shadow_set_isa(vt_shadow *sh, uint32_t isa);

/* The span lookup's instances (vt_shadow.inl); one lane: vt_shadow_lookup. */
/* The span lookup's constants of a draw (vt_shadow.c makes them with its
 * maps): per cascade its map offsets, first texel and first tile, far end
 * and blend band, the tiles' quantisation (vt_shadow_tiles); the packed
 * footprint tiles (tq NULL: every lookup takes its 16 taps) and their
 * count a side. */
typedef struct vt_shadow_cons {
    float offx[VT_SHADOW_CASCADES], offy[VT_SHADOW_CASCADES], base[VT_SHADOW_CASCADES];
    float far[VT_SHADOW_CASCADES], band[VT_SHADOW_CASCADES], tbase[VT_SHADOW_CASCADES];
    float qlo[VT_SHADOW_CASCADES], qinv[VT_SHADOW_CASCADES];
    const uint32_t *tq;
    float g;
} vt_shadow_cons;
typedef void (*vt_shadow_n_fn)(const vt_shadow_fit *f, const float *maps, const vt_shadow_cons *k, unsigned n,
                               const float *px, const float *py, const float *pz, const float *nx, const float *ny,
                               const float *nz, float *out);
void vt_shadow_lookup_n_sse41(const vt_shadow_fit *f, const float *maps, const vt_shadow_cons *k, unsigned n,
                              const float *px, const float *py, const float *pz, const float *nx, const float *ny,
                              const float *nz, float *out);
void vt_shadow_lookup_n_avx2(const vt_shadow_fit *f, const float *maps, const vt_shadow_cons *k, unsigned n,
                             const float *px, const float *py, const float *pz, const float *nx, const float *ny,
                             const float *nz, float *out);

#endif
