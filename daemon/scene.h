/*
 * scene.h — the daemon's authoritative scene: the culling world plus what
 * the culling core does not keep (the editor's 64-bit ids, class meshes,
 * occluders, lights) and the scene epoch. Edits come in batches from the
 * protocol and are all or nothing: a batch is validated whole, then
 * applied; if applying fails half-way (out of memory) what was applied is
 * rolled back.
 */
#ifndef VANTAGE_SCENE_H
#define VANTAGE_SCENE_H

#include "culling.h"
#include "idmap.h"
#include "protocol.h"

typedef struct scene_mesh {
    uint32_t nv, ni;
    float *pos, *nrm;
    uint32_t *idx;
} scene_mesh;

typedef struct scene_occluder {
    double origin[3];
    uint32_t ntris;
    float *verts;           /* 9 per triangle, relative to origin */
    cull_occluder h;        /* in the culling world, which draws it */
} scene_occluder;

#define SCENE_MAX_SUBLEVELS 4096u

typedef struct scene_limits {
    uint32_t max_entities, max_lights, max_occluders, max_occluder_tris, max_mesh_verts;
} scene_limits;

typedef struct scene {
    cull_world *world;
    idmap ids;              /* editor id -> handle */
    uint64_t *id_of_slot;   /* handle slot -> editor id */
    uint32_t id_cap;
    uint64_t epoch;         /* +1 per applied edit message */
    scene_mesh meshes[65536];
    uint32_t nmeshes;
    idmap occluders;        /* id -> scene_occluder * */
    idmap lights;           /* id -> vp_light * */
    scene_limits lim;
    /* what changed since the last event, for subscribers */
    uint32_t ev_added, ev_updated, ev_removed;
    uint64_t edits;         /* entity records applied, ever */
    char *sublevel_name[SCENE_MAX_SUBLEVELS + 1]; /* by id; [0] unused (default) */
    uint32_t nsublevels;
} scene;

/* Result of a failed edit: code from VP_ERRORS, the failing record, why. */
typedef struct scene_err {
    int code;
    uint32_t index;
    char msg[160];
} scene_err;

int  scene_init(scene *s, double cell_size, const scene_limits *lim);
void scene_free(scene *s);

/* Entity batches (records from the protocol). handles gets one per record. */
int scene_add(scene *s, const vp_entity_batch *b, uint32_t *handles, scene_err *err);
int scene_update(scene *s, const vp_entity_batch *b, scene_err *err);
int scene_remove(scene *s, const vp_id_batch *b, scene_err *err);

int scene_mesh_put(scene *s, const vp_mesh *m, scene_err *err);
int scene_occluder_put(scene *s, const vp_occluder *o, scene_err *err);
int scene_remove_ids(scene *s, idmap *which, const vp_id_batch *b, scene_err *err);
int scene_lights_put(scene *s, const uint8_t *recs, uint32_t n, scene_err *err);

/* Ids of sub-level names, defining the new ones (all or nothing). */
int scene_sublevel_ids(scene *s, const vp_name_list *names, uint16_t *ids, scene_err *err);

/* The editor id of a live handle (0 if unknown). */
uint64_t scene_id_of(const scene *s, cull_handle h);
/* An entity as a protocol record. */
void scene_entity_record(const scene *s, cull_handle h, vp_entity *out);

/* Fills the scene with a procedural city: a street grid of buildings
 * (entities and box occluders), props and lights. Deterministic. */
int scene_build_demo(scene *s, uint32_t props);

#endif
