/*
 * vt_scene.h — what the renderers draw besides triangles (issue 19's scene
 * model): textures (views of the daemon's decoded images, never copied),
 * glTF 2.0 metallic-roughness materials with their samplers and
 * KHR_texture_transform, and the environment (sun, sky, ground plane,
 * height fog, exposure). Both renderers take these through vt_frame
 * (vt_soft.h) and check them with the one function vt_frame_check; the
 * shared formulas (texture sampling, the analytic sky, fog, exposure) are
 * in vt_scene.c, and vt_gldraw.c's shader mirrors them operation for
 * operation.
 *
 * Units: the sun's colour is linear RGB times illuminance in lux; the sky
 * and everything the renderers output is radiance in cd/m^2 (nits),
 * multiplied by the exposure (1 / (1.2 x 2^EV100), so mid grey comes out
 * near 0.1 before the tone map). Point and spot lights keep their own
 * units (colour x intensity, inverse square): in daylight exposure they
 * are faint, as real lamps are at noon.
 */
#ifndef VANTAGE_VT_SCENE_H
#define VANTAGE_VT_SCENE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* The sampler states (the protocol's VP_WRAP_* and VP_FILTER_* numbers). */
enum { VT_WRAP_REPEAT, VT_WRAP_CLAMP, VT_WRAP_MIRROR };
enum {
    VT_FILTER_NEAREST, VT_FILTER_LINEAR, VT_FILTER_NEAREST_MIP_NEAREST, VT_FILTER_LINEAR_MIP_NEAREST,
    VT_FILTER_NEAREST_MIP_LINEAR, VT_FILTER_LINEAR_MIP_LINEAR
};
enum { VT_SLOT_BASE, VT_SLOT_MR, VT_SLOT_NORMAL, VT_SLOT_EMISSIVE, VT_SLOTS };
enum { VT_ALPHA_OPAQUE, VT_ALPHA_MASK };
enum { VT_SKY_COLOR, VT_SKY_ANALYTIC, VT_SKY_TEXTURE };
enum { VT_EXPOSURE_FIXED, VT_EXPOSURE_AUTO };

#define VT_TEX_MAX_DIM 16384u
#define VT_TEX_MAX_LEVELS 15u

/* An image: RGBA8 with a mip chain (level k is max(1, w >> k) by
 * max(1, h >> k), rows top-down, tightly packed), or float RGBA level 0
 * (an EXR: hdr set, levels 1). A view: the pixels are the owner's, read
 * during the render call only. (id, gen) name the pixels for a cache (the
 * GL renderer keeps its texture objects by them; id 0: uploaded each
 * frame); a change of pixels under the same id needs a new gen. */
typedef struct vt_texview {
    uint32_t w, h, levels;       /* level 0: 1..VT_TEX_MAX_DIM a side */
    const uint8_t *const *mip;   /* levels RGBA8 images, or NULL */
    const float *hdr;            /* RGBA float, or NULL */
    uint32_t id, gen;
} vt_texview;

/* A material's texture slot: glTF's textureInfo, its sampler and
 * KHR_texture_transform: uv' = offset + Rot(rotation) (scale * uv), with
 * Rot = [cos -sin; sin cos] as the extension's GLSL writes it. */
typedef struct vt_texref {
    const vt_texview *tex;       /* NULL: no texture in this slot */
    uint8_t wrap_s, wrap_t;      /* VT_WRAP_* */
    uint8_t min_filter, mag_filter; /* VT_FILTER_*; mag NEAREST or LINEAR */
    float offset[2], scale[2], rotation;
} vt_texref;

/* glTF 2.0 metallic-roughness: base colour x the sRGB base texture
 * (alpha in .a), metallic x B and roughness x G of the MR texture,
 * emissive x strength x the sRGB emissive texture; the normal texture
 * (tangent space, scaled in xy by normal_scale) only on meshes with
 * tangents. MASK discards below alpha_cutoff; double-sided materials
 * are not back-face culled (a back face is shaded with its normal turned
 * over). */
typedef struct vt_material {
    float base[4];               /* linear, 0..1 */
    float metallic, roughness;   /* 0..1 */
    float emissive[3];           /* linear, 0..1 */
    float emissive_strength;     /* 0..1e6 */
    float normal_scale;          /* finite, |x| <= 1e3 */
    uint8_t alpha_mode;          /* VT_ALPHA_* */
    float alpha_cutoff;          /* 0..1 */
    bool double_sided;
    vt_texref tex[VT_SLOTS];
} vt_material;

/* The environment. Zero is no sun, a black sky, no ground, no fog and a
 * fixed exposure of EV100 0 (scale 1 / 1.2). */
typedef struct vt_env {
    float sun_dir[3];            /* towards the sun, unit (within 1e-3), or 0: no sun */
    float sun[3];                /* linear colour x illuminance, lux, 0..1e6 */
    uint8_t sky_mode;            /* VT_SKY_* */
    float sky[3];                /* COLOR: radiance; ANALYTIC, TEXTURE: a multiplier; >= 0, <= 1e9 */
    float turbidity;             /* ANALYTIC: 1..10 */
    const vt_texview *sky_tex;   /* TEXTURE: equirectangular (u: azimuth, v: 0 at the zenith) */
    float sky_rotation;          /* TEXTURE: radians about +Y, |x| <= 1e3 */
    bool ground;                 /* an infinite plane y = ground_height, facing up */
    double ground_height;        /* |x| <= 1e12 */
    float ground_albedo[3];      /* 0..1: the ground's colour without a material */
    const vt_material *ground_mat; /* NULL: ground_albedo; else this material, its UVs world x, z
                                      in metres (modulo 4096 m at the view's origin) */
    float fog_density;           /* per metre at ground_height (at y = 0 without a ground), 0..1 */
    float fog_falloff;           /* per metre of height, 0..10 (0: uniform) */
    float fog_color[3];          /* times the sky's mean radiance, 0..1e6 */
    uint8_t exposure_mode;       /* VT_EXPOSURE_* */
    float exposure_ev;           /* FIXED: EV100, -10..30 */
    float exposure_comp;         /* AUTO: EV added to the picture's brightness, -10..10 */
} vt_env;

/* Checks a texture, a material, an environment. 0, or VT_ERR_INVALID
 * with the field in err. */
int vt_texview_check(const vt_texview *t, char *err, size_t errlen);
int vt_material_check(const vt_material *m, char *err, size_t errlen);
int vt_env_check(const vt_env *e, char *err, size_t errlen);

/* The material a NULL material pointer draws with, given the instance's
 * albedo: base = albedo, roughness 0.6, nothing else. */
void vt_material_default(const float albedo[3], vt_material *out);

#ifdef __cplusplus
}
#endif
#endif
