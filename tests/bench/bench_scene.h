/*
 * bench_scene.h — what the benchmarks on the shared scene files share
 * (bench_cull --demo, bench_occlusion, report_cull): a scene's objects and
 * occluder boxes loaded into a world, the camera walk, and the exact
 * occlusion reference (tests/occ_ref.c) per object.
 *
 * Header-only (static inline), as bench_util.h, so that each benchmark's
 * link line stays as it is; a program that never calls bench_caster does
 * not need occ_ref.o.
 *
 * The walk: the scene's camera (its fovy, aspect, near and far), 1920 x
 * 1080, stepping `step` metres per frame toward the target. An offset
 * translates the whole scene (objects, occluders, cameras) in double: the
 * same geometry far from the origin.
 */
#ifndef VANTAGE_BENCH_SCENE_H
#define VANTAGE_BENCH_SCENE_H

#include "culling.h"
#include "occ_ref.h"
#include "scene_file.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

/* The scene's object AABBs as entities (radius 0: the sphere is the box's
 * circumsphere), translated by offset (NULL: none); their handles into
 * handles[0..nobjects) unless NULL. On a fresh world slot i is object i,
 * which the benchmarks rely on to map results back (handle &
 * (CULL_MAX_ENTITIES - 1)); returns -1 if that does not hold or an add
 * fails. */
static inline int bench_add_objects(cull_world *w, const scene_file *sf, const double offset[3],
                                    cull_handle *handles)
{
    for (size_t i = 0; i < sf->nobjects; i++) {
        cull_entity_desc e = {0};
        for (int a = 0; a < 3; a++) {
            double o = offset ? offset[a] : 0;
            e.aabb_min[a] = sf->objects[i * 6 + a] + o;
            e.aabb_max[a] = sf->objects[i * 6 + 3 + a] + o;
        }
        cull_handle h;
        if (cull_entity_add(w, &e, &h) || (h & (CULL_MAX_ENTITIES - 1)) != i) return -1;
        if (handles) handles[i] = h;
    }
    return 0;
}

/* Loads the scene file at path (its error printed after who: on failure)
 * and makes a world (desc may be NULL) holding its objects, as
 * bench_add_objects does; 0 or -1. */
static inline int bench_load_world(const char *who, const char *path, scene_file *sf, const cull_world_desc *desc,
                                   cull_world **w)
{
    char err[256];
    if (scene_file_load(path, sf, err, sizeof err)) {
        fprintf(stderr, "%s: %s\n", who, err);
        return -1;
    }
    if (cull_world_create(desc, w)) return -1;
    return bench_add_objects(*w, sf, NULL, NULL);
}

/* The scene's occluder triangles as one occluder per box (12 triangles, 36
 * vertices each), translated by offset through the occluder's transform, so
 * the vertices stay the file's floats. */
static inline int bench_add_boxes(cull_world *w, const scene_file *sf, const double offset[3])
{
    size_t nboxes = sf->ntris / 12;
    for (size_t k = 0; k < nboxes; k++) {
        cull_occluder_desc d = {.vertices = sf->tris + k * 108, .vertex_count = 36};
        if (offset) {
            d.transform[0] = d.transform[5] = d.transform[10] = d.transform[15] = 1;
            for (int a = 0; a < 3; a++) d.transform[12 + a] = offset[a];
        }
        cull_occluder h;
        if (cull_occluder_add(w, &d, &h)) return -1;
    }
    return 0;
}

/* The occluder triangles in double, world space, translated by offset
 * (NULL: none): what occ_ref casts against. malloc'ed; NULL when out of
 * memory. */
static inline double *bench_tris_world(const scene_file *sf, const double offset[3])
{
    double *t = malloc((sf->ntris ? sf->ntris : 1) * 9 * sizeof *t);
    if (!t) return NULL;
    for (size_t i = 0; i < sf->ntris * 9; i++) t[i] = (double)sf->tris[i] + (offset ? offset[i % 3] : 0);
    return t;
}

/* How the walk's camera differs from the scene's. Zero = the scene's. */
typedef struct bench_cam {
    double   offset[3];     /* added to the eye: the scene translated along */
    double   znear, zfar;   /* 0 = the scene's; zfar may be INFINITY */
    uint32_t depth_mode;    /* enum cull_depth_mode */
    double   step;          /* metres per frame toward the target; 0 = 0.5 */
} bench_cam;

/* frames views of the walk into out. cam NULL: the scene's camera, GL
 * depth, 0.5 m per frame. Returns 0, or the cull_view_init error. */
static inline int bench_walk(const scene_file *sf, const bench_cam *cam, int frames, cull_view *out)
{
    static const bench_cam plain;
    if (!cam) cam = &plain;
    double dir[3];
    for (int a = 0; a < 3; a++) dir[a] = sf->target[a] - sf->eye[a];
    double len = sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
    double step = cam->step > 0 ? cam->step : 0.5;
    double zn = cam->znear > 0 ? cam->znear : sf->znear, zf = cam->zfar > 0 ? cam->zfar : sf->zfar;
    for (int f = 0; f < frames; f++) {
        cull_view_desc d = {.viewport_w = 1920, .viewport_h = 1080, .depth_mode = cam->depth_mode};
        double proj[16], view[16];
        for (int a = 0; a < 3; a++) d.origin[a] = sf->eye[a] + dir[a] / len * step * f + cam->offset[a];
        cull_mat_perspective(proj, sf->fovy_deg * M_PI / 180, sf->aspect, zn, zf, cam->depth_mode);
        cull_mat_look_dir(view, dir, sf->up);
        cull_mat_mul(d.view_proj, proj, view);
        int rc = cull_view_init(&out[f], &d);
        if (rc) return rc;
    }
    return 0;
}

/* The exact occlusion reference: vis[i] = 1 if object i (translated by
 * offset, NULL: none) is seen by a pixel-centre ray of a w x h image of v
 * before any occluder triangle (tri: ntri world triangles in double, from
 * bench_tris_world), else 0. Only objects with cand[i] set are cast (the
 * rest get 0); cand NULL: every object. About 0.4 s per 1920 x 1080 view
 * of the city here. Returns 0, or -1 (out of memory, singular view). */
static inline int bench_caster(const cull_view *v, uint32_t w, uint32_t h, const double *tri, size_t ntri,
                               const scene_file *sf, const double offset[3], const uint8_t *cand, uint8_t *vis)
{
    occ_ref r;
    if (occ_ref_init(&r, v, w, h)) return -1;
    occ_ref_add_triangles(&r, tri, ntri);
    for (size_t i = 0; i < sf->nobjects; i++) {
        vis[i] = 0;
        if (cand && !cand[i]) continue;
        double mn[3], mx[3];
        for (int a = 0; a < 3; a++) {
            double o = offset ? offset[a] : 0;
            mn[a] = sf->objects[6 * i + a] + o;
            mx[a] = sf->objects[6 * i + 3 + a] + o;
        }
        vis[i] = occ_ref_box_visible(&r, mn, mx);
    }
    occ_ref_free(&r);
    return 0;
}

#endif
