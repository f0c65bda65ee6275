/*
 * edit.h — one scene edit, as the protocol carries it and as the journal
 * keeps it: decoded from a request's payload, then applied to the scene.
 * The live path (handlers.c) and crash recovery (journal.c replaying its
 * records) go through the same two calls, so a replayed edit does exactly
 * what the acknowledged one did: same entity handles, same sub-level
 * classes, same epoch.
 *
 * An edit depends on the scene and on nothing else except its context,
 * which the journal stores with it: the sub-level the editing connection
 * was loading (`sublevel`) and `aux` (DESTROY: the volume resolution the daemon
 * ran with; SUBLEVEL_BEGIN: the loading connection's id).
 */
#ifndef VANTAGE_EDIT_H
#define VANTAGE_EDIT_H

#include "scene.h"

/* Kinds that are not protocol messages (0xF0xx is never a wire type). */
#define EDIT_DEMO   0xF001u /* aux = props: the procedural demo city */
#define EDIT_WORK   0xF002u /* aux = budget: one slice of the unloads' freeing */
#define EDIT_CITY   0xF003u /* aux = props: the demo city on the scene model (city.c) */

typedef struct edit {
    uint16_t type;   /* a VP_* request type, or EDIT_* */
    uint16_t sublevel; /* the sub-level the editing connection is loading (its open load), 0 = none */
    uint32_t aux;
    uint32_t count;  /* records in it (the ACK's count) */
    union {
        vp_entity_batch ents;
        vp_id_batch ids;
        vp_mesh mesh;
        vp_occluder occ;
        struct { const uint8_t *recs; uint32_t n; } lights;
        vp_name_list names;
        vp_sublevel_begin begin;
        vp_name name;
        vp_destroy destroy;
        vp_transform_batch xf;
        struct { const uint8_t *recs; uint32_t n; } mats;
        vp_texture_put tex;   /* TEXTURE_PUT: the whole image (the connection assembled it) */
        vp_env env;           /* ENV_SET */
    } u;
} edit;

typedef struct edit_result {
    uint32_t *handles;        /* ENTITY_ADD: one per record (malloc'd) */
    uint16_t *ids;            /* SUBLEVEL_NAMES: one per name (malloc'd) */
    vp_sublevel_begun begun;  /* SUBLEVEL_BEGIN */
    vp_destroyed destroyed;   /* DESTROY */
    uint32_t n;               /* ACK count: records, or entities of a sub-level */
} edit_result;

/* Whether type is a request that changes the scene (editor role). */
bool edit_is(uint16_t type);
/* Payload layouts: the protocol version a payload was written in. A
 * request off the socket is EDIT_LAYOUT; a journal says which its records
 * are (journal.c: format 1 files hold version 1's). Version 1 differs in
 * ENTITY_ADD / ENTITY_UPDATE (104-byte records: bounds entities, material
 * 0) and OCCLUDER_PUT (no flags word); every other payload is the same. */
#define EDIT_LAYOUT_V1 1u
#define EDIT_LAYOUT 2u

/* Decodes payload p (len bytes) of request `type`, in `layout` (EDIT_LAYOUT
 * or EDIT_LAYOUT_V1), into e (which points into p); max_batch bounds
 * batches (0 = the protocol's own limit). VP_OK, or a code from the
 * decoders (the message is vp_strerror's). */
int edit_decode(uint16_t type, const uint8_t *p, uint32_t len, uint32_t max_batch, unsigned layout, edit *e);
/* The ERROR for a decode that failed with rc: for a batch whose records
 * the decoder refused (NaN, undefined flags or kinds), the first such
 * record's index and a message naming its field and the cause; else
 * UINT32_MAX and the code's message. e is what edit_decode left. */
void edit_explain(const edit *e, int rc, scene_err *err);
/* Applies e to sc (the caller holds the scene exclusively). VP_OK and *r
 * (free with edit_result_free), or a code with err filled and nothing
 * changed. */
int edit_apply(scene *sc, const edit *e, edit_result *r, scene_err *err);
void edit_result_free(edit_result *r);

/* The demo city on the scene model, built from protocol edits (city.c):
 * deterministic; props cars. VP_OK, or a code with err filled. */
int scene_build_city(scene *s, uint32_t props, scene_err *err);

#endif
