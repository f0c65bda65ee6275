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
 * same geometry far from the origin. bench_view_look: one view of the
 * scene's camera from any eye, direction and up (the other walks).
 *
 * Random towns (bench_town_make, report_cull's and bench_occlusion's):
 * seeded boxes in scene-file form, three kinds (bench_town_kind).
 */
#ifndef VANTAGE_BENCH_SCENE_H
#define VANTAGE_BENCH_SCENE_H

#include "bench_util.h"
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

/* One view of the scene's camera (fovy, aspect, near and far as cam says;
 * cam NULL: the scene's, GL depth), 1920 x 1080, from eye along dir with
 * up (not parallel to dir). Returns 0, or the cull_view_init error. */
static inline int bench_view_look(const scene_file *sf, const bench_cam *cam, const double eye[3],
                                  const double dir[3], const double up[3], cull_view *out)
{
    static const bench_cam plain;
    if (!cam) cam = &plain;
    double zn = cam->znear > 0 ? cam->znear : sf->znear, zf = cam->zfar > 0 ? cam->zfar : sf->zfar;
    cull_view_desc d = {.viewport_w = 1920, .viewport_h = 1080, .depth_mode = cam->depth_mode};
    double proj[16], view[16];
    for (int a = 0; a < 3; a++) d.origin[a] = eye[a];
    cull_mat_perspective(proj, sf->fovy_deg * M_PI / 180, sf->aspect, zn, zf, cam->depth_mode);
    cull_mat_look_dir(view, dir, up);
    cull_mat_mul(d.view_proj, proj, view);
    return cull_view_init(out, &d);
}

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
    for (int f = 0; f < frames; f++) {
        double eye[3];
        for (int a = 0; a < 3; a++) eye[a] = sf->eye[a] + dir[a] / len * step * f + cam->offset[a];
        int rc = bench_view_look(sf, cam, eye, dir, sf->up, &out[f]);
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

/* ---- random towns ------------------------------------------------------------------------ */
typedef struct bench_town {
    const char *name;
    int         boxes;
    double      half;             /* the town is [-half, half]^2 */
    double      foot_lo, foot_hi; /* box footprint side, metres */
    double      h_lo, h_hi;       /* box height */
    double      eye_hi;           /* eye height 1.7 .. eye_hi */
} bench_town;

#define BENCH_NTOWNS 3

/* Town kind k (0 .. BENCH_NTOWNS-1): town, dense, sparse. */
static inline const bench_town *bench_town_kind(int k)
{
    static const bench_town kinds[BENCH_NTOWNS] = {
        {"town", 700, 600, 8, 35, 5, 60, 6},
        {"dense", 2000, 500, 4, 18, 3, 25, 3},
        {"sparse", 150, 800, 10, 40, 5, 80, 30},
    };
    return &kinds[k];
}

static inline double bench_town_rnd(uint64_t *s, double lo, double hi)
{
    return lo + (hi - lo) * bench_rand01(s);
}

/* The 12 triangles of box [mn, mx] into t (108 floats), counter-clockwise
 * seen from outside. */
static inline void bench_box_tris(float *t, const double mn[3], const double mx[3])
{
    for (int a = 0; a < 3; a++)
        for (int side = 0; side < 2; side++) {
            int b = (a + 1) % 3, c = (a + 2) % 3;
            double q[4][3];
            for (int k = 0; k < 4; k++) {
                q[k][a] = side ? mx[a] : mn[a];
                q[k][b] = (k == 1 || k == 2) ? mx[b] : mn[b];
                q[k][c] = (k >= 2) ? mx[c] : mn[c];
            }
            /* (b, c, a) is a right-handed cycle: this order faces +a; flip for -a */
            if (!side) {
                for (int x = 0; x < 3; x++) {
                    double tmp = q[1][x];
                    q[1][x] = q[3][x];
                    q[3][x] = tmp;
                }
            }
            static const int tri_idx[6] = {0, 1, 2, 0, 2, 3};
            for (int k = 0; k < 6; k++)
                for (int x = 0; x < 3; x++) *t++ = (float)q[tri_idx[k]][x];
        }
}

/* A seeded random town of kind k in scene-file form (scene_file_free
 * frees it): boxes as occluders, nobjects object AABBs (sides 0.2..10 m,
 * log-uniform; 70 % on the ground), a street-level camera outside every
 * box. 0, or -1 when out of memory. */
static inline int bench_town_make(int kind, uint64_t seed, int nobjects, scene_file *sf)
{
    const bench_town *k = bench_town_kind(kind);
    uint64_t s = seed;
    memset(sf, 0, sizeof *sf);
    sf->ntris = (size_t)k->boxes * 12;
    sf->tris = malloc(sf->ntris * 9 * sizeof *sf->tris);
    sf->nobjects = (size_t)nobjects;
    sf->objects = malloc(sf->nobjects * 6 * sizeof *sf->objects);
    double *boxes = malloc((size_t)k->boxes * 6 * sizeof *boxes);
    if (!sf->tris || !sf->objects || !boxes) {
        free(boxes);
        scene_file_free(sf);
        return -1;
    }
    for (int b = 0; b < k->boxes; b++) {
        double *bx = boxes + 6 * b;
        double fx = bench_town_rnd(&s, k->foot_lo, k->foot_hi), fz = bench_town_rnd(&s, k->foot_lo, k->foot_hi);
        double cx = bench_town_rnd(&s, -k->half, k->half), cz = bench_town_rnd(&s, -k->half, k->half);
        bx[0] = cx - fx / 2, bx[1] = 0, bx[2] = cz - fz / 2;
        bx[3] = cx + fx / 2, bx[4] = bench_town_rnd(&s, k->h_lo, k->h_hi), bx[5] = cz + fz / 2;
        bench_box_tris(sf->tris + (size_t)b * 108, bx, bx + 3);
    }
    for (int i = 0; i < nobjects; i++) {
        double *ob = sf->objects + 6 * i;
        double c[3] = {bench_town_rnd(&s, -k->half, k->half), 0, bench_town_rnd(&s, -k->half, k->half)};
        double ext[3];
        for (int a = 0; a < 3; a++) ext[a] = 0.2 * pow(10 / 0.2, bench_rand01(&s));
        c[1] = bench_rand01(&s) < 0.7 ? ext[1] / 2 : bench_town_rnd(&s, 0, 40);
        for (int a = 0; a < 3; a++) {
            ob[a] = c[a] - ext[a] / 2;
            ob[3 + a] = c[a] + ext[a] / 2;
        }
    }
    for (int tries = 0;; tries++) {
        double e[3] = {bench_town_rnd(&s, -k->half / 2, k->half / 2), bench_town_rnd(&s, 1.7, k->eye_hi),
                       bench_town_rnd(&s, -k->half / 2, k->half / 2)};
        int inside = 0;
        for (int b = 0; b < k->boxes && !inside; b++) {
            const double *bx = boxes + 6 * b;
            inside = e[0] > bx[0] - 1 && e[0] < bx[3] + 1 && e[2] > bx[2] - 1 && e[2] < bx[5] + 1 && e[1] < bx[4] + 1;
        }
        if (inside && tries < 10000) continue;
        double yaw = bench_town_rnd(&s, 0, 2 * M_PI), pitch = -bench_town_rnd(&s, 0.02, 0.15);
        memcpy(sf->eye, e, sizeof e);
        sf->target[0] = e[0] + 100 * sin(yaw);
        sf->target[1] = e[1] + 100 * pitch;
        sf->target[2] = e[2] - 100 * cos(yaw);
        break;
    }
    sf->up[1] = 1;
    sf->fovy_deg = 60;
    sf->znear = 0.1;
    sf->zfar = 2000;
    sf->aspect = 16.0 / 9.0;
    free(boxes);
    return 0;
}

#endif
