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
#include "splitmix.h"

typedef struct scene_mesh {
    uint32_t nv, ni;
    float *pos, *nrm;
    float *uv;              /* 2 per vertex, or NULL */
    float *tan;             /* 4 per vertex (xyz, w handedness), or NULL */
    uint32_t *idx;
    double lo[3], hi[3];    /* local bounds of the positions */
} scene_mesh;

/* An entity's placement (entities with VP_ENT_TRANSFORM), by handle slot. */
typedef struct scene_xform {
    double pos[3];
    float rot[4];           /* unit (renormalised on the way in) */
    float scale[3];
    uint32_t material;      /* every entity's material, transform or not */
    uint32_t flags;         /* the entity's VP_ENT_* (VP_ENT_TRANSFORM: pos/rot/scale hold) */
} scene_xform;

/* A material as stored (the materials map's values point to these). */
typedef struct scene_material {
    vp_material m;
    uint32_t users;         /* entities using it (it cannot be removed while > 0) */
} scene_material;

/* A texture as stored (the textures map's values point to these): the
 * encoded bytes as uploaded (snapshots, export) and the decoded image
 * with its mip chain. */
typedef struct scene_texture {
    uint32_t id;
    uint8_t format, flags;  /* VP_TEX_* */
    uint8_t *bytes;         /* the upload, encoded */
    uint32_t nbytes;
    uint32_t w, h;          /* level 0 */
    uint32_t levels;
    float *hdr;             /* EXR: RGBA float, level 0 only */
    uint8_t **mip;          /* PNG / JPEG: RGBA8 per level, levels of them */
    size_t mem;             /* bytes held, for the texture memory limit */
    uint32_t users;         /* materials (and the environment) using it */
    uint32_t gen;           /* new with every upload (scene.texture_gens): with the id, the
                               key of a renderer's cache (the GL textures) */
} scene_texture;

typedef struct scene_occluder {
    uint64_t id;
    double origin[3];       /* VP_OCC_ATTACHED: in the entity's local space */
    uint32_t ntris;
    float *verts;           /* 9 per triangle, relative to origin (as sent) */
    uint32_t flags;         /* VP_OCC_*: ATTACHED follows entity id's transform */
    cull_occluder h;        /* in the culling world, which draws it */
    uint16_t sublevel;
} scene_occluder;

/* An entity's destruction: its distance volume (the sphere set in it). */
typedef struct scene_destruct {
    cull_dvol v;
    /* destroyed while the entity had a transform: the spheres in its local
       space (centre xyz, radius divided by the smallest non-zero |scale|),
       v.nsph of them, from which v is rebuilt when it moves; else NULL */
    double (*local)[4];
} scene_destruct;

/* A light as stored (the lights map's values point to these). */
typedef struct scene_light {
    vp_light l;
    uint16_t sublevel;
} scene_light;

#define SCENE_MAX_SUBLEVELS 4096u

/* A named sub-level. Its state on the wire (VP_SL_*) is LOADING or
 * UNLOADING while one of those runs, else LOADED or EMPTY by its content. */
typedef struct scene_sublevel {
    char *name;             /* NULL: not named */
    uint8_t state;          /* VP_SL_LOADING, VP_SL_UNLOADING, or 0 */
    uint32_t owner;         /* LOADING: the loading connection's id */
    uint16_t class_base, classes; /* mesh classes reserved for it */
    uint64_t *doomed;       /* UNLOADING: ids of the entities left to free */
    uint32_t ndoomed, doomed_pos;
    uint64_t *members;      /* ids of the entities put into it (some may have
                               left since: checked when used) */
    uint32_t nmembers, members_cap;
    uint32_t occluders, lights; /* it holds */
} scene_sublevel;

typedef struct scene_limits {
    uint32_t max_entities, max_lights, max_occluders, max_occluder_tris, max_mesh_verts;
    uint32_t max_materials;
    uint32_t max_texture_size;   /* pixels on a side */
    uint64_t max_texture_mem;    /* bytes, all textures (mips and uploads) together */
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
    scene_sublevel sl[SCENE_MAX_SUBLEVELS + 1]; /* by id; [0] the unnamed default */
    uint32_t nsublevels;
    uint32_t *sl_entities;  /* entities per sub-level id (65536) */
    uint16_t *class_owner;  /* per class: the sub-level it is reserved for, 0 = none */
    uint32_t *class_entities; /* per class: entities of it */
    uint64_t hidden[CULL_SUBLEVEL_WORDS]; /* sub-levels no query sees (loading, unloading) */
    uint32_t nhidden;
    uint32_t unloading;     /* sub-levels with entities left to free */
    idmap destruct;         /* entity id -> scene_destruct * */
    scene_xform *xf;        /* by handle slot (id_cap of them): transform and material */
    idmap materials;        /* id -> scene_material * */
    idmap textures;         /* id -> scene_texture * */
    uint64_t texture_mem;   /* bytes the textures hold */
    uint32_t texture_gens;  /* textures stored, ever: the next scene_texture.gen */
    vp_env env;
    uint64_t debris_next;   /* debris entities spawned, ever */
    bool replaying;         /* a journal is being replayed: what an older
                               daemon acknowledged before it checked it is
                               kept, not refused: a light (never drawn), a
                               sub-level name that is not UTF-8 */
} scene;

/* Result of a failed edit: code from VP_ERRORS, the failing record, why. */
typedef struct scene_err {
    int code;
    uint32_t index;
    char msg[160];
} scene_err;

int  scene_init(scene *s, double cell_size, const scene_limits *lim);
void scene_free(scene *s);
/* Fills e and returns code (scene.c and sublevel.c). */
int scene_fail(scene_err *e, int code, uint32_t index, const char *fmt, ...) __attribute__((format(printf, 4, 5)));

/* Edits. `loading` is the sub-level the editing connection is loading (0 =
 * none): what it adds goes into that sub-level, invisible until commit.
 * Entity batches (records from the protocol): handles gets one per record;
 * a record with sub-level 0 from a loading connection joins its load. */
int scene_add(scene *s, uint16_t loading, const vp_entity_batch *b, uint32_t *handles, scene_err *err);
/* A snapshot's entities back at their handles (slots the world reserved:
 * cull_world_slots_restore); otherwise as scene_add. */
int scene_add_at(scene *s, const vp_entity_batch *b, const uint32_t *handles, scene_err *err);
int scene_update(scene *s, uint16_t loading, const vp_entity_batch *b, scene_err *err);
int scene_remove(scene *s, uint16_t loading, const vp_id_batch *b, scene_err *err);

int scene_mesh_put(scene *s, uint16_t loading, const vp_mesh *m, scene_err *err);
int scene_occluder_put(scene *s, uint16_t loading, const vp_occluder *o, scene_err *err);
int scene_remove_ids(scene *s, uint16_t loading, idmap *which, const vp_id_batch *b, scene_err *err);
int scene_lights_put(scene *s, uint16_t loading, const uint8_t *recs, uint32_t n, scene_err *err);
/* A light record as the renderers take it: the culling light and colour x
 * intensity per channel (double, so an overflow is seen, not rounded). */
void scene_light_cull(const vp_light *l, cull_light *cl, double radiance[3]);
/* LIGHT_PUT's validation, the one the renderers make: a spot axis
 * normalised in double (in place; zero refused), then cull_light_validate.
 * VP_OK, or VP_ERR_NONFINITE / VP_ERR_INVALID with the field, value and
 * bound in why (may be NULL). */
int scene_light_check(vp_light *l, char *why, size_t whylen);
/* Whether a stored light passes cull_light_validate (one replayed from a
 * journal written before lights were checked may not: it is not drawn). */
bool scene_light_drawable(const vp_light *l);

/* ---- sub-levels (sublevel.c) ---- */
/* Ids of sub-level names, defining the new ones (all or nothing). */
int scene_sublevel_ids(scene *s, const vp_name_list *names, uint16_t *ids, scene_err *err);
/* The id of a named sub-level, 0 if none. */
uint16_t scene_sublevel_find(const scene *s, const uint8_t *name, uint8_t len);
/* Opens a load for connection `owner`: the sub-level (named, defined if
 * new) must be empty and idle; m->classes classes are reserved for it. */
int scene_sublevel_begin(scene *s, const vp_sublevel_begin *m, uint32_t owner, vp_sublevel_begun *out,
                         scene_err *err);
/* Makes a load visible (one epoch); *entities = its entities. */
int scene_sublevel_commit(scene *s, uint16_t id, uint32_t *entities, scene_err *err);
/* Room to record n more members of each named sub-level in subs[0..n)
 * (false: out of memory, nothing changed); then record them. */
bool scene_members_reserve(scene *s, const cull_entity_desc *descs, uint32_t n);
void scene_members_add(scene *s, uint16_t sub, uint64_t id);
/* Hides a sub-level (unload, abort, a loading connection gone) and starts
 * freeing it: its occluders, lights and meshes now, its entities in slices
 * by scene_sublevel_work. */
int scene_sublevel_drop(scene *s, uint16_t id, uint32_t *entities, scene_err *err);
/* Frees up to budget entities of unloading sub-levels; true if more is left. */
bool scene_sublevel_work(scene *s, uint32_t budget);
/* What a query sees: every visible sub-level, within `only` if given
 * (CULL_SUBLEVEL_WORDS words). NULL when that is every sub-level; else buf. */
const uint64_t *scene_visible(const scene *s, const uint64_t *only, uint64_t *buf);
/* Whether connection `loading` (its open load; 0 = none) may change what
 * sub-level sub holds (add to it, take from it): not one another connection is
 * loading (STATE), nor one being unloaded (BUSY). VP_OK or an error naming
 * record `index` (UINT32_MAX: none). */
int scene_sublevel_writable(const scene *s, uint16_t loading, uint16_t sub, uint32_t index, scene_err *err);
/* Where an add of connection `loading` puts something of sub-level *sub: a
 * loading connection's sub-level 0 becomes its load and it may add into
 * its load only; others as scene_sublevel_writable. */
int scene_sublevel_target(const scene *s, uint16_t loading, uint16_t *sub, uint32_t index, scene_err *err);
/* Whether no query sees sub-level id now (being loaded or unloaded). */
static inline bool scene_sublevel_hidden(const scene *s, uint16_t id)
{
    return (s->hidden[id >> 6] >> (id & 63)) & 1u;
}
/* VP_SL_*: LOADING or UNLOADING while one runs, else LOADED or EMPTY by
 * what it holds. */
uint8_t scene_sublevel_state(const scene *s, uint16_t id);
/* ---- destruction (destruct.c) ---- */
/* A destruction event: the sphere joins entity m->id's set (its volume made
 * on the first, res^3 over its box), its occluder (same id) is cut open,
 * debris spawned; one epoch. All or nothing. */
int scene_destroy(scene *s, const vp_destroy *m, uint32_t res, vp_destroyed *out, scene_err *err);
/* Where n debris pieces (centres c, half sizes half) thrown by a blast
 * come to rest: each falls straight down onto the ground plane, an
 * entity's box or a piece landed before it (debris.c); c changed in
 * place. VP_OK, or VP_ERR_BUSY (out of memory) with err. */
int scene_debris_settle(const scene *s, uint32_t n, double (*c)[3], const double *half, scene_err *err);
/* The entity's destruction, or NULL. */
const scene_destruct *scene_destruct_of(const scene *s, uint64_t id);
/* An entity's box changed: its destruction follows it. */
void scene_destruct_moved(scene *s, uint64_t id, const cull_entity_desc *from, const cull_entity_desc *to);
/* An entity is gone: so is its destruction. */
void scene_destruct_forget(scene *s, uint64_t id);
void scene_destruct_free_all(scene *s);
/* Draws occluder o in the culling world as it should be: its triangles as
 * sent, with the holes of its entity's destruction (same id) cut in; added,
 * updated in place (o->h) or removed when nothing is left. *kept (if not
 * NULL): the triangles drawn. On error the world's copy is unchanged. */
int scene_occluder_draw(scene *s, scene_occluder *o, uint32_t *kept);
/* Entity id (transform x, bounds now d) was placed anew: its destruction
 * is rebuilt from its local spheres (else follows the box as
 * scene_destruct_moved) and its attached occluder redrawn. */
void scene_destruct_follow(scene *s, uint64_t id, const scene_xform *x, const cull_entity_desc *from,
                           const cull_entity_desc *to);


/* Uniform in [0, 1) from a splitmix64 stream (the demo city, debris). */
static inline double scene_rand(uint64_t *state)
{
    return splitmix_unit(state);
}

/* Takes entity id (handle h, desc d) out of the scene and its counters. */
void scene_entity_gone(scene *s, uint64_t id, cull_handle h, const cull_entity_desc *d);
/* The editor id of a live handle (0 if unknown). */
uint64_t scene_id_of(const scene *s, cull_handle h);
/* An entity as a protocol record. */
void scene_entity_record(const scene *s, cull_handle h, vp_entity *out);

/* ---- the scene model (transform.c, material.c, texture.c) ---- */
/* VP_OK when no id appears twice in ids[0..n), else DUPLICATE naming the
 * second appearance's record (BUSY: out of memory). */
int scene_check_unique(const uint64_t *ids, uint32_t n, scene_err *err);
/* Moves entities hs[0..n) from their bounds from[] to to[] (the culling
 * world's update), all or nothing: on failure the ones moved go back. */
int scene_moves_apply(scene *s, uint32_t n, const cull_handle *hs, const cull_entity_desc *from,
                      const cull_entity_desc *to, scene_err *err);
/* Fills m->lo / hi from its positions (0 for an empty mesh). */
void scene_mesh_bounds(scene_mesh *m);
/* Frees a mesh's arrays and zeroes it. */
void scene_mesh_release(scene_mesh *m);
/* Entity record i (e) as a culling desc in *d: a VP_ENT_TRANSFORM record
 * gets bounds derived from its class mesh (which must exist: UNKNOWN_ID)
 * and its TRS; every record's material must be 0 or exist (UNKNOWN_ID);
 * then cull_entity_check. Errors name the record. */
int scene_entity_desc(const scene *s, const vp_entity *e, uint32_t i, cull_entity_desc *d, scene_err *err);
/* Point p of local space under transform x (scale, rotate, translate), in
 * double. */
void scene_xform_apply(const scene_xform *x, const double p[3], double out[3]);
/* The inverse: world point p in x's local space (an axis scaled by 0
 * gives 0). */
void scene_xform_local(const scene_xform *x, const double p[3], double out[3]);
/* TRANSFORM_SET: all or nothing (see protocol.h). */
int scene_transform_set(scene *s, uint16_t loading, const vp_transform_batch *b, scene_err *err);
/* MESH_PUT's new local bounds for class c: every transform entity of the
 * class gets its bounds derived again (all or nothing: refused, nothing
 * changed, if one would leave the world's range). Called before the mesh
 * is stored; VP_OK when the class has no such entity. */
int scene_mesh_rederive(scene *s, uint16_t c, const double lo[3], const double hi[3], scene_err *err);
/* The attached occluder of entity id, or NULL. */
scene_occluder *scene_attached_occluder(const scene *s, uint64_t id);
/* MATERIAL_PUT (records of vp_dec_materials) and MATERIAL_REMOVE: all or
 * nothing; a material in use is not removed (STATE). */
int scene_materials_put(scene *s, const uint8_t *recs, uint32_t n, scene_err *err);
int scene_materials_remove(scene *s, const vp_id_batch *b, scene_err *err);
void scene_materials_free(scene *s);
/* The texture with that id, or NULL. */
scene_texture *scene_texture_find(const scene *s, uint32_t id);
/* The material with that id, or NULL (0 is the default material: NULL). */
scene_material *scene_material_find(const scene *s, uint32_t id);
/* TEXTURE_PUT of a whole image (offset 0, len = total; the connection
 * assembled its chunks): header read, limits checked (LIMIT, with the
 * numbers), decoded (INVALID with the decoder's reason; an EXR with NaN or
 * infinity: NONFINITE), mip chain built, stored under m->id with a copy
 * of the encoded bytes. An existing id is replaced: its users (materials,
 * the sky) carry over and keep pointing at the id; the sky's texture must
 * stay an EXR lat-long. All or nothing. */
int scene_texture_put(scene *s, const vp_texture_put *m, scene_err *err);
/* TEXTURE_REMOVE (ids): each must exist, once, with no users (STATE). */
int scene_textures_remove(scene *s, const vp_id_batch *b, scene_err *err);
/* Frees every texture (scene_free). */
void scene_textures_free(scene *s);
/* ENV_SET (env.c): vp_env_check, then the scene's checks (a TEXTURE sky
 * names an EXR lat-long texture, UNKNOWN_ID if none; the ground material
 * is 0 or exists); s->env replaced, the users of the sky texture and the
 * ground material moved from the old environment to the new. A snapshot's
 * environment is restored through it too (after its textures and
 * materials), so the users counts hold. */
int scene_env_set(scene *s, const vp_env *env, scene_err *err);
/* Whether texture t may be the sky: EXR, width = 2 x height. */
int scene_env_sky_check(const scene *s, const scene_texture *t, scene_err *err);

/* Fills the scene with a procedural city: a street grid of buildings
 * (entities and box occluders), props and lights. Deterministic. */
int scene_build_demo(scene *s, uint32_t props);

#endif
