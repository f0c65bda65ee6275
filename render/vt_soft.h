/*
 * vt_soft.h — the software renderer: what the culling core says is visible,
 * rasterised with a top-left fill rule into an HDR colour buffer and a depth
 * buffer, and shaded (glTF's metallic-roughness BRDF, point and spot lights) with
 * the Forward+ tile light lists of culling/ (cull_lights_bin).
 *
 * Meshes are per class: positions, optional normals, counter-clockwise
 * triangles. An instance stretches its mesh's bounding box onto a world
 * AABB (entities carry bounds, not transforms), so a unit box or sphere
 * fills the entity's box. Back faces are culled, except on damaged
 * instances (vt_instance.dvol, vt_mask.h): those are drawn where their
 * destruction mask is >= 0, two-sided, their inside darkened.
 *
 * Buffers are the caller's: rgba (4 floats per pixel, linear HDR, alpha 1
 * where something was drawn, 0 elsewhere) and depth (1 float per pixel:
 * the view-space depth w for perspective views, 0..1 from near to far for
 * orthographic ones; +inf where nothing was drawn), rows bottom-up (row 0
 * is the bottom of the view, as OpenGL reads back), `stride` pixels apart.
 */
#ifndef VANTAGE_VT_SOFT_H
#define VANTAGE_VT_SOFT_H

#include "culling.h"

#include "vt_err.h"
#include "vt_scene.h"

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct vt_mesh {
    const float    *pos;    /* 3 per vertex */
    const float    *nrm;    /* 3 per vertex, unit; NULL: flat (face) normals */
    const uint32_t *idx;    /* 3 per triangle */
    uint32_t        nv, ni;
    const float    *uv;     /* 2 per vertex, or NULL (no textures drawn on it) */
    const float    *tan;    /* 4 per vertex (xyz unit, w +-1 handedness), or NULL */
} vt_mesh;

/* How an instance places its mesh. */
enum {
    VT_PLACE_BOUNDS,        /* the mesh's bounding box stretched onto bmin..bmax */
    VT_PLACE_TRS            /* p' = pos + rot (scale * p): negative scale mirrors */
};

typedef struct vt_instance {
    uint32_t mesh;          /* index into the mesh array */
    double   bmin[3], bmax[3]; /* BOUNDS: world AABB the mesh's bounds are stretched onto */
    float    albedo[3];     /* linear; the material's base colour when mat is NULL */
    uint8_t  place;         /* VT_PLACE_* (zero: BOUNDS) */
    double   pos[3];        /* TRS: world position, |x| <= 1e15 */
    float    rot[4];        /* TRS: unit quaternion x, y, z, w (within 1e-3) */
    float    scale[3];      /* TRS: |x| <= 1e6, at most one axis 0 */
    const vt_material *mat; /* NULL: the default material of albedo */
    const cull_dvol *dvol;  /* its destruction (NULL, or no spheres: intact);
                               drawn masked and two-sided (vt_mask.h). Read
                               during the call only. */
} vt_instance;

typedef struct vt_light {
    cull_light l;           /* position, range, spot cone (outer) */
    float      color[3];    /* linear RGB times intensity */
    float      cos_inner;   /* spot: full intensity inside this cosine */
} vt_light;

typedef struct vt_soft_stats {
    uint32_t triangles;     /* sent to the rasteriser, after back faces and clipping */
    uint32_t lights_in_view;
    uint32_t max_lights_per_tile;
    uint32_t threads;
    uint64_t setup_ns, raster_ns, bin_ns, shade_ns; /* bin: the light tiles and the frame's other
                               tables, run beside the occlusion's GTAO pass when it runs (so
                               inside ssao_ns's time, not after it) */
    /* issue 20's passes (0 when off): the sun's shadow cascades (caster
       set-up and depth raster), the ambient occlusion from the nearness
       buffer, the post passes (FXAA, exposure) */
    uint64_t shadow_ns, ssao_ns, post_ns;
    uint32_t shadow_triangles; /* drawn into the cascades, all together */
    uint64_t overlay_ns;    /* the overlay (vt_overlay.h: outline, icons); 0 without one */
    float exposure_ev;      /* the EV100 the frame was exposed with (0 without an environment) */
    uint32_t coarse_skips;  /* a triangle's part in one 16-row tile row, skipped by the
                               coarse depth test (nothing of it could show) */
} vt_soft_stats;

/* The effects of a frame with an environment (issue 20), as bits of
 * vt_frame.fx_off: each is on unless its bit is set. Without an
 * environment none of them runs (the look before the scene model). */
enum {
    VT_FX_SHADOWS = 1u << 0, /* the sun's cascaded shadow maps (vt_shadow.h) */
    VT_FX_SSAO = 1u << 1,    /* screen-space ambient occlusion from the nearness buffer */
    VT_FX_IBL = 1u << 2,     /* image-based ambient (irradiance + prefiltered specular); off: the
                                two-colour hemisphere ambient of issue 19 */
    VT_FX_FXAA = 1u << 3,    /* FXAA over the exposed picture */
    VT_FX_MSAA = 1u << 4     /* the GL path's multisampling (where it is cheap) */
};

/* A stream's eye adaptation (issue 20): the exposure the last frame used,
 * carried by the caller from frame to frame of one viewer's stream. The
 * renderer moves it towards the new frame's histogram exposure at a
 * bounded rate per second of dt; invalid: the first frame, exposed from
 * its own histogram alone. */
typedef struct vt_adapt {
    float ev;               /* EV100 of the last frame */
    bool valid;
} vt_adapt;

/* One picture's inputs and outputs (both renderers take it). Zero fields
 * default: no lights, no environment. */
typedef struct vt_frame {
    const cull_view *view;
    uint32_t width, height;
    const vt_mesh *meshes;
    uint32_t nmesh;
    const vt_instance *inst;
    uint32_t ninst;
    const vt_light *lights;
    uint32_t nl;
    const vt_env *env;      /* NULL: a black background, the small constant
                               ambient, no exposure (the look before the
                               scene model); else sun, sky, ground, fog and
                               exposure, and alpha 1 everywhere */
    float *rgba, *depth;    /* width x height, stride pixels apart */
    size_t stride;
    uint32_t fx_off;        /* VT_FX_* bits turned off; zero: every effect on */
    const vt_instance *casters; /* what may cast the sun's shadows into the view
                               (a superset of inst: casters out of the view
                               frustum included); NULL: inst */
    uint32_t ncasters;
    vt_adapt *adapt;        /* a stream's eye adaptation (in and out); NULL: a
                               single picture */
    float dt;               /* seconds since adapt's frame, >= 0 */
    const struct vt_overlay *overlay; /* outline and icons drawn last (vt_overlay.h); NULL: none */
    const int *cancel;      /* non-zero (read atomically, set by another thread): stop and return
                               VT_ERR_CANCELLED; the software renderer looks between its passes
                               and between rows of the shading. NULL: never */
} vt_frame;

typedef struct vt_soft vt_soft;

/* pool may be NULL (one thread); threads 0 = the pool's. */
int  vt_soft_create(cull_pool *pool, uint32_t threads, vt_soft **out);
/* The Forward+ tile lists the last vt_soft_render shaded with (indices into
 * its light array); valid until the next render or destroy. */
const cull_light_tiles *vt_soft_light_tiles(const vt_soft *r);
void vt_soft_destroy(vt_soft *r);
/* The raster's coarse depth test (per 16 x 16 tile, a bound of the
 * farthest nearness drawn there; a triangle's part wholly behind it is
 * skipped): on by default. It never changes a pixel; off is for the test
 * that checks that, and for measuring what it saves. */
void vt_soft_coarse_depth(vt_soft *r, bool on);

/* Checks a mesh: counts, indices in range, finite positions and normals.
 * 0, or VT_ERR_INVALID with a reason in err. Both renderers check every mesh
 * they are given this way. */
int vt_mesh_check(const vt_mesh *m, char *err, size_t errlen);

/* The unit box (-1..1 on each axis, 12 counter-clockwise triangles, flat
 * normals): what an entity without a mesh of its own is drawn as. */
extern const vt_mesh vt_mesh_box;

/* Renders frame f (see vt_frame). 0, or a VT_ERRORS code with err filled:
 * VT_ERR_INVALID (vt_frame_check's reasons), VT_ERR_NOMEM, VT_ERR_RANGE,
 * VT_ERR_CANCELLED (f->cancel was set: the buffers hold a partial picture). */
int vt_soft_draw(vt_soft *r, const vt_frame *f, vt_soft_stats *st, char *err, size_t errlen);

/* Checks everything a render call is given, as both renderers do before
 * any work: sizes and buffers, meshes, instances (mesh index, bounds or
 * transform), materials and their textures, lights, the environment.
 * 0, or VT_ERR_INVALID with the first bad field named in err. */
int vt_frame_check(const vt_frame *f, char *err, size_t errlen);

/* Renders ninst instances of nmesh meshes lit by nl lights for view v into
 * width x height buffers. 0, or a VT_ERRORS code with err filled: VT_ERR_INVALID
 * (bad size, a bad mesh, a bad mesh index or bounds, a bad light), VT_ERR_NOMEM. */
int vt_soft_render(vt_soft *r, const cull_view *v, uint32_t width, uint32_t height, const vt_mesh *meshes,
                   uint32_t nmesh, const vt_instance *inst, uint32_t ninst, const vt_light *lights, uint32_t nl,
                   float *rgba, float *depth, size_t stride, vt_soft_stats *st, char *err, size_t errlen);

#ifdef __cplusplus
}
#endif
#endif
