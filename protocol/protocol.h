/*
 * protocol.h — Vantage's wire format: framing, message layouts, limits and
 * error codes, with encode/decode as pure functions over byte buffers.
 * No I/O, no allocation: decoders validate a complete payload and hand back
 * views into it; encoders write into caller buffers sized by *_size().
 * protocol/PROTOCOL.md is the specification a third party writes a client
 * from; this header follows it byte for byte.
 *
 * Everything is little-endian. A frame is a 12-byte header (payload length,
 * type, flags, request id) followed by the payload. vp_frame_check() looks
 * at any prefix of a stream and says "need more", "frame of N bytes" or why
 * the stream can no longer be trusted, before anything is allocated.
 */
#ifndef VANTAGE_PROTOCOL_H
#define VANTAGE_PROTOCOL_H

#include "vp_bytes.h"

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "vp_err.h"

#ifdef __cplusplus
extern "C" {
#endif

#define VP_MAGIC 0x47544E56u /* "VNTG" as little-endian bytes */
#define VP_VERSION 2u       /* 2: the scene model (transforms, materials, textures, environment) */
#define VP_VERSION_MIN 2u   /* the oldest a client may speak (HELLO) */
#define VP_DEFAULT_PORT 7470 /* vantaged's TCP port unless --port, and the client's unless -p */
#define VP_HEADER_SIZE 12u
#define VP_MAX_VIEWS 32u
#define VP_MAX_TOKEN 255u
#define VP_MAX_NAME 255u
#define VP_MAX_PING 1024u
#define VP_MAX_ERROR_MSG 1024u

/* ---- error codes: one table for the wire and the C API ------------------ */
#define VP_ERRORS(X)                                                             \
    X(VP_OK,               0, "ok")                                              \
    X(VP_NEED_MORE,        1, "need more bytes")                                 \
    X(VP_ERR_MAGIC,       -1, "bad magic: not a Vantage client")                 \
    X(VP_ERR_VERSION,     -2, "unsupported protocol version")                    \
    X(VP_ERR_TOO_LARGE,   -3, "frame larger than the negotiated limit")          \
    X(VP_ERR_TRUNCATED,   -4, "payload shorter than its message needs")          \
    X(VP_ERR_TRAILING,    -5, "payload longer than its message")                 \
    X(VP_ERR_TYPE,        -6, "unknown message type")                            \
    X(VP_ERR_COUNT,       -7, "count disagrees with the payload or a limit")     \
    X(VP_ERR_NONFINITE,   -8, "NaN or infinity in a number that must be finite") \
    X(VP_ERR_INVALID,     -9, "invalid field value")                             \
    X(VP_ERR_STATE,      -10, "message not allowed in this state")               \
    X(VP_ERR_AUTH,       -11, "role not allowed or bad token")                   \
    X(VP_ERR_UNKNOWN_ID, -12, "no entity with that id")                          \
    X(VP_ERR_STALE,      -13, "stale or never-issued handle")                    \
    X(VP_ERR_DUPLICATE,  -14, "an entity with that id exists")                   \
    X(VP_ERR_LIMIT,      -15, "server limit reached")                            \
    X(VP_ERR_SCENE,      -16, "the scene rejected the edit")                     \
    X(VP_ERR_MATRIX,     -17, "degenerate view-projection matrix")               \
    X(VP_ERR_BUSY,       -18, "server busy, retry")                              \
    X(VP_ERR_INTERNAL,   -19, "internal server error")                          \
    X(VP_ERR_UNSUPPORTED, -20, "not available on this server")                   \
    X(VP_ERR_TIMEOUT,    -21, "too slow: HELLO or a frame did not arrive in time") \
    X(VP_ERR_IO,         -22, "the server could not make the edit durable")   \
    X(VP_ERR_NOT_FOUND,  -23, "nothing of that name")                            \
    X(VP_ERR_NOT_WRITER, -24, "not the scene's writer: edits go to the writer the message names")

VP_ERR_ENUM(VP_ERRORS);

/* The table's message for code; "unknown error" for a code not in it.
 * Never NULL; static storage. (The modules' message formatter, vp_errf, is
 * in vp_err.h.) */
const char *vp_strerror(int code);
/* Strict UTF-8 (RFC 3629): no overlong forms, no surrogates, nothing past
 * U+10FFFF, no sequence cut short. Returns n if p[0..n) is valid, else the
 * offset of the first bad sequence with the reason in *why (may be NULL). */
size_t vp_utf8_check(const uint8_t *p, size_t n, const char **why);
/* p[0..n) made safe to quote in a message: valid UTF-8 sequences and
 * printable ASCII kept, every other byte (control bytes, 127, '\\', bytes
 * of no valid sequence) written as \\xNN. At most cap - 1 bytes and a NUL;
 * never cuts a sequence or an escape. Returns the length. */
size_t vp_escape(char *out, size_t cap, const uint8_t *p, size_t n);

/* ---- message types: ranges reserved per area ----------------------------- */
enum vp_type {
    /* 0x0001..0x00ff session */
    VP_HELLO = 0x0001,
    VP_HELLO_OK = 0x0002,
    VP_ERROR = 0x0003,
    VP_PING = 0x0004,
    VP_PONG = 0x0005,
    VP_STATS = 0x0006,
    VP_STATS_REPLY = 0x0007,
    VP_SUBSCRIBE = 0x0008,
    VP_EVENT = 0x0009,
    VP_ACK = 0x000a,
    /* 0x0100..0x01ff scene edits */
    VP_ENTITY_ADD = 0x0100,
    VP_ENTITY_ADD_REPLY = 0x0101,
    VP_ENTITY_UPDATE = 0x0102,
    VP_ENTITY_REMOVE = 0x0103,
    VP_ENTITY_LIST = 0x0104,
    VP_ENTITY_LIST_REPLY = 0x0105,
    VP_ENTITY_GET = 0x0106,
    VP_TRANSFORM_SET = 0x0107,
    VP_MESH_PUT = 0x0110,
    VP_MESH_GET = 0x0111,
    VP_MESH_REPLY = 0x0112,
    VP_OCCLUDER_PUT = 0x0120,
    VP_OCCLUDER_REMOVE = 0x0121,
    VP_LIGHT_PUT = 0x0130,
    VP_LIGHT_REMOVE = 0x0131,
    VP_LIGHT_LIST = 0x0132,
    VP_LIGHT_LIST_REPLY = 0x0133,
    VP_MATERIAL_PUT = 0x0140,
    VP_MATERIAL_REMOVE = 0x0141,
    VP_MATERIAL_LIST = 0x0142,
    VP_MATERIAL_LIST_REPLY = 0x0143,
    VP_TEXTURE_PUT = 0x0150,
    VP_TEXTURE_REMOVE = 0x0151,
    VP_TEXTURE_GET = 0x0152,
    VP_TEXTURE_REPLY = 0x0153,
    VP_ENV_SET = 0x0160,
    VP_ENV_GET = 0x0161,
    VP_ENV_REPLY = 0x0162,
    /* 0x0200..0x02ff queries */
    VP_VIS_QUERY = 0x0200,
    VP_VIS_RESULT = 0x0201,
    VP_LIGHT_QUERY = 0x0202,
    VP_LIGHT_TILES = 0x0203,
    VP_RENDER = 0x0500,
    VP_FRAME = 0x0501,
    VP_FRAME_SUBSCRIBE = 0x0502,
    VP_FRAME_UNSUBSCRIBE = 0x0503,
    /* 0x0300..0x03ff sub-levels */
    VP_SUBLEVEL_NAMES = 0x0300,
    VP_SUBLEVEL_IDS = 0x0301,
    VP_SUBLEVEL_LIST = 0x0302,
    VP_SUBLEVEL_LIST_REPLY = 0x0303,
    VP_SUBLEVEL_BEGIN = 0x0304,
    VP_SUBLEVEL_BEGUN = 0x0305,
    VP_SUBLEVEL_COMMIT = 0x0306,
    VP_SUBLEVEL_ABORT = 0x0307,
    VP_SUBLEVEL_UNLOAD = 0x0308,
    VP_SUBLEVEL_INFO = 0x0309,
    VP_SUBLEVEL_INFO_REPLY = 0x030a,
    /* 0x0400..0x04ff destruction */
    VP_DESTROY = 0x0400,
    VP_DESTROYED = 0x0401,

    VP_MARK = 0x0600,
    VP_MARKED = 0x0601,
    VP_SELECT = 0x0602,
    VP_SELECTED = 0x0603,
    /* 0x0700..0x07ff administration (and persistence, later) */
    VP_METRICS = 0x0700,
    VP_METRICS_REPLY = 0x0701,
};

/* Roles, lowest to highest. */
enum vp_role { VP_ROLE_VIEWER = 0, VP_ROLE_COMMANDER = 1, VP_ROLE_EDITOR = 2 };

/* ---- framing ---------------------------------------------------------------- */
typedef struct vp_header {
    uint32_t len;   /* payload bytes after the header */
    uint16_t type;  /* enum vp_type */
    uint16_t flags; /* reserved, 0 */
    uint32_t req;   /* request id, echoed by the reply; 0 for pushed events */
} vp_header;

/* Looks at the first n bytes of a stream. VP_NEED_MORE if the header or the
 * payload is incomplete (*frame_size is set once the header is there),
 * VP_OK with *h and *frame_size (header + payload) when a whole frame is
 * there, VP_ERR_TOO_LARGE when the length exceeds max_payload (decided from
 * the header alone, before any payload is buffered), VP_ERR_INVALID for
 * non-zero flags. buf may be NULL only when n is 0; h and frame_size are
 * non-NULL (*h is filled whenever the header is there). */
int vp_frame_check(const uint8_t *buf, size_t n, uint32_t max_payload, vp_header *h, size_t *frame_size);

/* ---- writer and reader: vp_bytes.h (vp_writer, vp_put_*, vp_reader, vp_get_*) ---- */
/* Starts a frame (header with length patched by vp_frame_end). */
void vp_frame_begin(vp_writer *w, uint16_t type, uint32_t req);
/* Finishes the frame; returns false if the buffer overflowed. */
bool vp_frame_end(vp_writer *w);
/* VP_ERR_TRUNCATED if a read ran short, VP_ERR_TRAILING if bytes are left. */
int      vp_reader_finish(const vp_reader *r);

/* ---- messages ------------------------------------------------------------------ */

typedef struct vp_hello {
    uint32_t magic;
    uint16_t version;
    uint8_t  role;       /* enum vp_role asked for */
    uint8_t  token_len;
    const uint8_t *token;
    uint8_t  name_len;   /* client name, for logs */
    const uint8_t *name;
} vp_hello;

typedef struct vp_hello_ok {
    uint16_t version;
    uint8_t  role;       /* granted */
    uint32_t max_payload;
    uint32_t max_batch;  /* records per edit message */
    uint32_t max_views;
    uint64_t epoch;
    uint32_t client_id;
} vp_hello_ok;

typedef struct vp_error {
    int32_t  code;
    uint32_t index;      /* failing record of a batch, or UINT32_MAX */
    uint16_t msg_len;
    const uint8_t *msg;
} vp_error;

/* One entity record of an add or update batch, VP_ENTITY_REC_SIZE bytes.
 * Two kinds of entity:
 *   - with VP_ENT_TRANSFORM: mesh class_id (which must hold a mesh) placed
 *     by pos / rot / scale; its culling bounds are derived from the mesh's
 *     local bounds and the transform (cull_bounds_from_trs) and sphere /
 *     aabb are ignored on input (0 recommended) and carry the derived
 *     bounds on output (ENTITY_LIST_REPLY);
 *   - without it: bounds as given (sphere, aabb), as in version 1: a
 *     culling-only entity, drawn as its class mesh's bounding box stretched
 *     onto the aabb (the unit box when the class has no mesh). pos / rot /
 *     scale are not read (0 on output).
 * material 0 is the default material (mid grey, rough dielectric). */
#define VP_ENTITY_REC_SIZE 160u
#define VP_ENTITY_REC_SIZE_V1 104u /* version 1's record: no material, no transform (journals, snapshots) */
#define VP_ENT_DYNAMIC 0x1u
#define VP_ENT_TRANSFORM 0x2u
#define VP_ENT_FLAGS (VP_ENT_DYNAMIC | VP_ENT_TRANSFORM)
#define VP_QUAT_TOLERANCE 1e-3 /* |q| may be 1 +- this (renormalised), else INVALID */
typedef struct vp_entity {
    uint64_t id;         /* the editor's own id, unique per scene */
    uint32_t handle;     /* add: ignored; update: 0 or the current handle */
    uint16_t class_id;   /* the mesh class */
    uint16_t sublevel;
    uint32_t flags;      /* VP_ENT_* */
    uint32_t material;   /* a MATERIAL_PUT id, 0 = default */
    double   pos[3];     /* VP_ENT_TRANSFORM: world position (metres) */
    float    rot[4];     /* unit quaternion x y z w */
    float    scale[3];   /* per axis; negative mirrors (winding flipped); at most one axis 0 */
    double   sphere[4];  /* x y z r; r = 0: derived from the AABB */
    double   aabb[6];    /* min xyz, max xyz; all 0: derived from the sphere */
} vp_entity;

/* TRANSFORM_SET: transform-only updates of many entities (entities with
 * VP_ENT_TRANSFORM), answered with ACK. All or nothing, like every batch. */
#define VP_TRANSFORM_REC_SIZE 64u
typedef struct vp_transform {
    uint64_t id;
    uint32_t handle;     /* 0 or the current handle (else STALE) */
    double   pos[3];
    float    rot[4];     /* x y z w */
    float    scale[3];
} vp_transform;
typedef struct vp_transform_batch {
    uint32_t count;
    const uint8_t *recs;
} vp_transform_batch;

/* Batches are views into the payload; read record i with the getters. */
typedef struct vp_entity_batch {
    uint32_t count;
    const uint8_t *recs;
    uint8_t version;     /* record layout: 2 (VP_ENTITY_REC_SIZE), or 1 (a version 1 journal's) */
} vp_entity_batch;

typedef struct vp_id_batch {
    uint32_t count;
    const uint8_t *ids;  /* u64 each */
} vp_id_batch;

/* Reply to an add: the handles given, in record order. */
typedef struct vp_add_reply {
    uint64_t epoch;
    uint32_t count;
    const uint8_t *handles; /* u32 each */
} vp_add_reply;

typedef struct vp_ack {
    uint64_t epoch;      /* scene epoch after the edit was applied */
    uint32_t count;      /* records applied */
} vp_ack;

#define VP_VIEW_SIZE 160u
typedef struct vp_view {
    double   origin[3];
    double   view_proj[16]; /* column-major, maps (p - origin, 1) to clip */
    uint8_t  depth_mode;    /* 0 GL, 1 [0,1], 2 reversed-Z */
    uint16_t viewport_w, viewport_h;
} vp_view;

#define VP_Q_NO_AABB      0x01u
#define VP_Q_WANT_AREA    0x02u
#define VP_Q_NO_OCCLUSION 0x04u
#define VP_Q_STATIC_ONLY  0x08u
#define VP_Q_DYNAMIC_ONLY 0x10u
#define VP_Q_COUNT_ONLY   0x20u /* reply with counts, no records */
#define VP_Q_OCC_CENTRE   0x40u /* occlusion by pixel centres (culls more; exact at 256x114 only) */
#define VP_Q_SUBLEVELS    0x80u /* only the sub-levels listed after the views are seen */
typedef struct vp_vis_query {
    uint8_t  view_count;    /* 1..32 */
    uint8_t  flags;         /* VP_Q_* */
    float    min_area;      /* pixels, >= 0 */
    const uint8_t *views;   /* view_count * VP_VIEW_SIZE */
    uint16_t nsub;          /* VP_Q_SUBLEVELS: 1..VP_MAX_QUERY_SUBLEVELS ids */
    const uint8_t *subs;    /* u16 each */
} vp_vis_query;
#define VP_MAX_QUERY_SUBLEVELS 4096u

#define VP_VIS_REC_SIZE 24u
#define VP_STAGES 6u        /* cells, spheres+AABB+area, write, total, ... */
typedef struct vp_vis_rec {
    uint64_t id;
    uint32_t handle;
    uint32_t view_mask;
    uint16_t class_id;
    uint16_t sublevel;
    float    area;
} vp_vis_rec;

typedef struct vp_vis_result {
    uint64_t epoch;
    uint32_t tested, visible; /* entities that reached the block stage / records */
    uint32_t stage_ns[VP_STAGES];
    uint32_t count;           /* records in this frame (0 with COUNT_ONLY) */
    const uint8_t *recs;
} vp_vis_result;

typedef struct vp_stats_reply {
    uint64_t epoch, uptime_ms;
    uint32_t entities, static_entities, dynamic_entities, regions, cells;
    uint32_t connections, meshes, occluders, lights;
    uint64_t queries, edits, bytes_in, bytes_out, errors;
} vp_stats_reply;

#define VP_EVENT_SCENE 0x1u
#define VP_EVENT_MARKS 0x2u   /* SUBSCRIBE: MARKED pushes */
#define VP_EVENT_SELECTION 0x4u /* SUBSCRIBE: SELECTED pushes */
#define VP_EVENT_ALL (VP_EVENT_SCENE | VP_EVENT_MARKS | VP_EVENT_SELECTION)
typedef struct vp_event {
    uint32_t kind;        /* VP_EVENT_* */
    uint64_t epoch;
    uint32_t added, updated, removed;
} vp_event;

/* MESH_PUT flags: no normals on the wire; the mesh is drawn with flat
 * (face) normals, as the renderers draw a vt_mesh whose nrm is NULL.
 * UVS: a texture coordinate pair per vertex follows the normals;
 * TANGENTS: a tangent (xyz unit, w = +-1 handedness) per vertex follows
 * the UVs (needs UVS). The arrays, in order: positions, normals, uvs,
 * tangents, indices. */
#define VP_MESH_NO_NORMALS 0x1u
#define VP_MESH_UVS 0x2u
#define VP_MESH_TANGENTS 0x4u
#define VP_MESH_FLAGS (VP_MESH_NO_NORMALS | VP_MESH_UVS | VP_MESH_TANGENTS)
typedef struct vp_mesh {
    uint16_t class_id;
    uint16_t flags;           /* VP_MESH_*; other bits INVALID */
    uint32_t vertex_count, index_count;
    const uint8_t *positions; /* f32 x3 per vertex */
    const uint8_t *normals;   /* f32 x3 per vertex; NULL with VP_MESH_NO_NORMALS */
    const uint8_t *uvs;       /* f32 x2 per vertex; NULL without VP_MESH_UVS */
    const uint8_t *tangents;  /* f32 x4 per vertex; NULL without VP_MESH_TANGENTS */
    const uint8_t *indices;   /* u32, triangles */
} vp_mesh;

/* OCCLUDER_PUT flags. ATTACHED: the occluder belongs to the entity with
 * the same id, which must have VP_ENT_TRANSFORM: origin and vertices are
 * in the entity's local space and the occluder follows the entity's
 * transform (no re-upload on a move); it goes when the entity goes. */
#define VP_OCC_ATTACHED 0x1u
typedef struct vp_occluder {
    uint64_t id;
    uint32_t flags;           /* VP_OCC_* (version 1 journals: 0) */
    double   origin[3];       /* vertices are relative to it */
    uint32_t tri_count;
    const uint8_t *verts;     /* f32 x9 per triangle */
} vp_occluder;

#define VP_LIGHT_POINT 0u
#define VP_LIGHT_SPOT 1u
#define VP_LIGHT_SIZE 80u
typedef struct vp_light {
    uint64_t id;
    uint8_t  kind;            /* VP_LIGHT_* */
    double   pos[3];
    float    dir[3];
    float    color[3];        /* linear RGB, multiplied by intensity */
    float    intensity;       /* candela */
    float    range;           /* metres, > 0 */
    float    inner_cos, outer_cos; /* spot cone */
} vp_light;

typedef struct vp_list {
    uint64_t cursor;     /* 0 = from the start */
    uint32_t max;        /* records wanted */
} vp_list;

typedef struct vp_list_reply {
    uint64_t next_cursor; /* 0 = done */
    uint64_t epoch;
    vp_entity_batch batch;
} vp_list_reply;

/* Sub-level names: a list of (id, name). Names are 1..255 bytes of UTF-8;
 * id 0 is the unnamed default sub-level. */
#define VP_MAX_SUBLEVELS 65535u
typedef struct vp_name_list {
    uint32_t count;
    const uint8_t *p;     /* the encoded entries, walked with vp_name_next */
    size_t len;
    bool with_ids;        /* SUBLEVEL_LIST_REPLY entries carry an id */
} vp_name_list;

typedef struct vp_name {
    uint16_t id;          /* 0 in SUBLEVEL_NAMES */
    uint8_t len;
    const uint8_t *name;
} vp_name;

/* Walks a decoded list (l from vp_dec_names, which checked every entry):
 * *pos starts at 0; each true fills *out (name points into the payload,
 * not terminated) and advances *pos; false at the end. */
bool vp_name_next(const vp_name_list *l, size_t *pos, vp_name *out);

/* Sub-level loads. SUBLEVEL_BEGIN opens a load of the named sub-level on
 * this connection (an editor's): what the connection then adds (entities,
 * occluders, lights, meshes of the reserved classes) belongs to the sub-level
 * and stays invisible to every query and frame until SUBLEVEL_COMMIT makes
 * all of it visible at one epoch. SUBLEVEL_ABORT, or the connection closing,
 * throws the load away. SUBLEVEL_UNLOAD hides a loaded sub-level at one
 * epoch and frees it. */
typedef struct vp_sublevel_begin {
    uint16_t classes;       /* mesh classes to reserve for the load (0..4096) */
    uint8_t  name_len;      /* 1..255 */
    const uint8_t *name;
} vp_sublevel_begin;

typedef struct vp_sublevel_begun {
    uint16_t id;            /* the sub-level's id (entities carry it) */
    uint16_t class_base;    /* the reserved classes: class_base .. + classes - 1 */
    uint64_t epoch;
} vp_sublevel_begun;

#define VP_SL_EMPTY 0u      /* named, nothing in it */
#define VP_SL_LOADED 1u     /* visible */
#define VP_SL_LOADING 2u    /* a connection is loading it: invisible */
#define VP_SL_UNLOADING 3u  /* hidden, being freed */
#define VP_SUBLEVEL_INFO_SIZE 20u /* + the name */
typedef struct vp_sublevel_info {
    uint16_t id;
    uint8_t  state;         /* VP_SL_* */
    uint32_t entities, occluders, lights;
    uint16_t class_base, classes;
    uint8_t  name_len;
    const uint8_t *name;
} vp_sublevel_info;

typedef struct vp_sublevel_infos {
    uint64_t epoch;
    uint32_t count;
    const uint8_t *p;       /* the entries, walked with vp_sublevel_info_next */
    size_t len;
} vp_sublevel_infos;

void vp_enc_sublevel_begin(vp_writer *w, uint32_t req, const vp_sublevel_begin *m);
int  vp_dec_sublevel_begin(const uint8_t *p, size_t len, vp_sublevel_begin *m);
void vp_enc_sublevel_begun(vp_writer *w, uint32_t req, const vp_sublevel_begun *m);
int  vp_dec_sublevel_begun(const uint8_t *p, size_t len, vp_sublevel_begun *m);
/* SUBLEVEL_UNLOAD: a name (u8 length, bytes). */
void vp_enc_sublevel_name(vp_writer *w, uint16_t type, uint32_t req, const char *name);
int  vp_dec_sublevel_name(const uint8_t *p, size_t len, vp_name *m);
/* SUBLEVEL_INFO_REPLY: header, then n vp_put_sublevel_info. */
void vp_enc_sublevel_infos_begin(vp_writer *w, uint32_t req, uint64_t epoch, uint32_t n);
void vp_put_sublevel_info(vp_writer *w, const vp_sublevel_info *m);
int  vp_dec_sublevel_infos(const uint8_t *p, size_t len, vp_sublevel_infos *m);
/* As vp_name_next: *pos from 0, *out filled (name into the payload), false
 * at the end. */
bool vp_sublevel_info_next(const vp_sublevel_infos *l, size_t *pos, vp_sublevel_info *out);

/* DESTROY: a sphere of destruction on an entity ("Destruction Masking in
 * Frostbite 2"): added to the entity's sphere set, its distance volume
 * updated, its occluder (the occluder with the entity's id) cut open, so
 * the next query sees through the hole and the next frame shows it.
 * Answered with DESTROYED. */
#define VP_DESTROY_SIZE 48u
#define VP_MAX_DEBRIS 64u
typedef struct vp_destroy {
    uint64_t id;              /* the entity */
    uint32_t handle;          /* 0, or its current handle (else STALE) */
    uint8_t  debris;          /* dynamic debris entities to spawn around the hole, 0..64 */
    double   center[3];       /* world metres */
    double   radius;          /* metres, > 0 */
} vp_destroy;

typedef struct vp_destroyed {
    uint64_t epoch;           /* the scene epoch the destruction is visible at */
    uint32_t spheres;         /* in the entity's set now */
    uint32_t occluder_tris;   /* its occluder's triangles after the cut (0: none left or no occluder) */
    uint32_t debris;          /* debris entities spawned (ids: see PROTOCOL.md) */
    uint32_t cut_us;          /* server time for the event, waiting for the scene lock included */
} vp_destroyed;

void vp_enc_destroy(vp_writer *w, uint32_t req, const vp_destroy *m);
int  vp_dec_destroy(const uint8_t *p, size_t len, vp_destroy *m);
void vp_enc_destroyed(vp_writer *w, uint32_t req, const vp_destroyed *m);
int  vp_dec_destroyed(const uint8_t *p, size_t len, vp_destroyed *m);

/* MARK (commander role): a commander marks a place ("ping a location"),
 * optionally an entity; the daemon pushes it as MARKED to every connection
 * that subscribed to marks, the sender's included, and answers ACK (count
 * = connections it went to). Marks are not scene state: not journaled. */
#define VP_MARK_SIZE 40u
#define VP_MARKED_SIZE 48u
typedef struct vp_mark {
    double   pos[3];          /* world metres, finite, within +-1e12 */
    uint64_t entity;          /* the entity marked, 0 = a place */
    uint8_t  kind;            /* the application's: the commander sends 0 = ping, 1 = select */
    uint32_t ttl_ms;          /* how long viewers show it, 1..600000 */
} vp_mark;

typedef struct vp_marked {
    uint32_t client_id;       /* the sender (HELLO_OK's client_id) */
    vp_mark  m;
} vp_marked;

void vp_enc_mark(vp_writer *w, uint32_t req, const vp_mark *m);
int  vp_dec_mark(const uint8_t *p, size_t len, vp_mark *m);
void vp_enc_marked(vp_writer *w, const vp_marked *m);
int  vp_dec_marked(const uint8_t *p, size_t len, vp_marked *m);

/* SELECT (commander or editor role): replaces the scene's one shared
 * selection (an editor's, a commander's: the last SELECT wins), pushed as
 * SELECTED to every connection subscribed with VP_EVENT_SELECTION, the
 * sender's included, and once at subscription; answered with ACK (count =
 * connections it went to). Not scene state: not journaled, no epoch.
 * Frames outline it (PROTOCOL.md). Ids: u64 each, none 0, none twice;
 * ids not in the scene are kept (they outline nothing). */
#define VP_SELECT_MAX 256u
#define VP_SELECT_HEAD 8u
#define VP_SELECTED_HEAD 16u
typedef struct vp_select {
    uint32_t count;           /* 0..VP_SELECT_MAX; 0 clears */
    uint32_t flags;           /* none defined: 0 */
    const uint8_t *ids;       /* count u64 (vp_id_at) */
} vp_select;

typedef struct vp_selected {
    uint32_t client_id;       /* the sender's (HELLO_OK), 0: none yet */
    uint32_t count;
    uint64_t serial;          /* one more per SELECT since the daemon started */
    const uint8_t *ids;       /* count u64 (vp_id_at) */
} vp_selected;

void vp_enc_select(vp_writer *w, uint32_t req, const uint64_t *ids, uint32_t n);
/* why (may be NULL) names the id at fault: 0, or twice. */
int  vp_dec_select(const uint8_t *p, size_t len, vp_select *m, char *why, size_t whylen);
void vp_enc_selected(vp_writer *w, const vp_selected *m, const uint64_t *ids);
int  vp_dec_selected(const uint8_t *p, size_t len, vp_selected *m);
/* The i-th u64 of an id array on the wire (0 past n). */
uint64_t vp_id_at(const uint8_t *ids, uint32_t n, uint32_t i);

/* ---- materials, textures, environment (version 2) ------------------------- */

/* A texture slot of a material: glTF 2.0's textureInfo with its sampler
 * and KHR_texture_transform. texture 0 = no texture. */
#define VP_WRAP_REPEAT 0u
#define VP_WRAP_CLAMP 1u
#define VP_WRAP_MIRROR 2u
#define VP_FILTER_NEAREST 0u
#define VP_FILTER_LINEAR 1u
#define VP_FILTER_NEAREST_MIP_NEAREST 2u
#define VP_FILTER_LINEAR_MIP_NEAREST 3u
#define VP_FILTER_NEAREST_MIP_LINEAR 4u
#define VP_FILTER_LINEAR_MIP_LINEAR 5u /* trilinear; mag takes NEAREST or LINEAR only */
#define VP_TEXREF_SIZE 32u
typedef struct vp_texref {
    uint32_t texture;         /* a TEXTURE_PUT id; 0 = none */
    uint8_t  wrap_s, wrap_t;  /* VP_WRAP_* */
    uint8_t  min_filter;      /* VP_FILTER_* */
    uint8_t  mag_filter;      /* VP_FILTER_NEAREST or _LINEAR */
    float    offset[2];       /* uv' = offset + R(rotation) * (scale * uv) */
    float    scale[2];
    float    rotation;        /* radians */
    uint8_t  texcoord;        /* 0 (one UV set) */
} vp_texref;

#define VP_ALPHA_OPAQUE 0u
#define VP_ALPHA_MASK 1u
#define VP_MAT_DOUBLE_SIDED 0x1u
#define VP_MATERIAL_SIZE (60u + 4u * VP_TEXREF_SIZE)
enum { VP_TEX_BASE, VP_TEX_MR, VP_TEX_NORMAL, VP_TEX_EMISSIVE, VP_TEX_SLOTS };
/* glTF 2.0 metallic-roughness. Colours linear; textures: base colour and
 * emissive are sRGB, metallic-roughness (G roughness, B metallic) and
 * normal (tangent space) linear. */
typedef struct vp_material {
    uint32_t id;              /* 1..UINT32_MAX (0 is the default material) */
    uint32_t flags;           /* VP_MAT_* */
    uint8_t  alpha_mode;      /* VP_ALPHA_* */
    float    alpha_cutoff;    /* MASK: 0..1 */
    float    base_color[4];   /* 0..1 each, linear RGBA */
    float    metallic, roughness; /* 0..1 */
    float    emissive[3];     /* 0..1 each, linear */
    float    emissive_strength; /* >= 0 (KHR_materials_emissive_strength), <= 1e6 */
    float    normal_scale;    /* finite */
    vp_texref tex[VP_TEX_SLOTS]; /* base colour, metallic-roughness, normal, emissive */
} vp_material;

/* TEXTURE_PUT: an image (PNG or JPEG; OpenEXR for an environment), sent
 * whole or in chunks: each chunk carries the total size and its offset;
 * chunks arrive in order (offset = bytes so far) on one connection. The
 * chunk that completes it makes the daemon decode it (libpng /
 * libjpeg-turbo / OpenEXR), check its limits, build its mip chain, and
 * put it in the scene (journalled whole); earlier chunks are ACKed with
 * count 0 and held by the connection (dropped if it closes first). */
#define VP_TEX_PNG 0u
#define VP_TEX_JPEG 1u
#define VP_TEX_EXR 2u            /* linear RGB(A) half or float: environment maps */
#define VP_TEX_SRGB 0x1u         /* colour data: mips averaged in linear light */
#define VP_TEXTURE_PUT_HEADER 16u
#define VP_MAX_TEXTURE_BYTES (64u << 20) /* encoded, whole */
typedef struct vp_texture_put {
    uint32_t id;              /* 1..UINT32_MAX */
    uint8_t  format;          /* VP_TEX_PNG / JPEG / EXR */
    uint8_t  flags;           /* VP_TEX_* */
    uint32_t total;           /* the whole encoded image, 1..VP_MAX_TEXTURE_BYTES */
    uint32_t offset;          /* of this chunk; offset + len <= total */
    uint32_t len;             /* this chunk: the rest of the payload, >= 1 */
    const uint8_t *data;
} vp_texture_put;

/* ENV_SET (editor), ENV_GET (empty, any role) answered by ENV_REPLY: the
 * environment, one fixed record. Y is up. */
#define VP_SKY_COLOR 0u          /* uniform sky_color x sky_intensity */
#define VP_SKY_ANALYTIC 1u       /* clear sky from the sun's direction and turbidity */
#define VP_SKY_TEXTURE 2u        /* sky_texture: an EXR texture, equirectangular (lat-long) */
#define VP_ENV_GROUND 0x1u       /* an infinite ground plane at ground_height */
#define VP_EXPOSURE_FIXED 0u     /* exposure_ev (EV100) */
#define VP_EXPOSURE_AUTO 1u      /* from the frame's mean luminance, + exposure_comp */
#define VP_ENV_SIZE 120u
typedef struct vp_env {
    float    sun_dir[3];      /* towards the sun; unit within VP_QUAT_TOLERANCE, or 0,0,0 = no sun */
    float    sun_color[3];    /* linear RGB, 0..1 each */
    float    sun_lux;         /* illuminance at normal incidence, 0..200000 */
    uint8_t  sky_mode;        /* VP_SKY_* */
    uint8_t  flags;           /* VP_ENV_* */
    uint8_t  exposure_mode;   /* VP_EXPOSURE_* */
    float    sky_color[3];    /* COLOR: linear RGB, >= 0 */
    float    sky_intensity;   /* multiplier, 0..1e6 (cd/m2 scale of the sky) */
    float    turbidity;       /* ANALYTIC: 1..10 */
    uint32_t sky_texture;     /* TEXTURE: an EXR texture id */
    float    sky_rotation;    /* TEXTURE: radians about +Y */
    double   ground_height;   /* GROUND: metres */
    float    ground_color[3]; /* GROUND: albedo 0..1 */
    uint32_t ground_material; /* GROUND: 0 = ground_color, else a material */
    float    fog_density;     /* per metre, 0 = no fog, <= 1 */
    float    fog_color[3];    /* linear RGB, >= 0 */
    float    fog_height_falloff; /* per metre, >= 0 (0 = uniform) */
    float    exposure_ev;     /* FIXED: EV100, -10..30 */
    float    exposure_comp;   /* AUTO: EV added, -10..10 */
} vp_env;

/* The environment a fresh scene has: a noon-ish sun, the analytic sky,
 * the ground at y = 0, light fog, auto exposure. */
void vp_env_default(vp_env *out);
/* A named environment: "day" (the default's sun and sky over an asphalt
 * ground) or "night" (moonlight, dark sky: lamps and windows carry the
 * frame). VP_OK, or VP_ERR_NOT_FOUND
 * (*out is then the default). */
int vp_env_preset(const char *name, vp_env *out);

size_t vp_size_transforms(uint32_t n);
void   vp_enc_transforms(vp_writer *w, uint32_t req, const vp_transform *t, uint32_t n);
int    vp_dec_transforms(const uint8_t *p, size_t len, uint32_t max_batch, vp_transform_batch *m);
int    vp_transform_get(const vp_transform_batch *b, uint32_t i, vp_transform *out);
int    vp_transform_rec_check(const vp_transform_batch *b, uint32_t i, char *why, size_t whylen);
/* The checks a transform gets wherever it comes from (TRANSFORM_SET, an
 * entity record with VP_ENT_TRANSFORM): finite, |q| within
 * VP_QUAT_TOLERANCE of 1 (rot renormalised in place), at most one scale
 * axis 0, |pos| and |scale| within the culling core's range. VP_OK, or
 * NONFINITE / INVALID with the field named in why (may be NULL). */
int    vp_trs_check(double pos[3], float rot[4], float scale[3], char *why, size_t whylen);

size_t vp_size_materials(uint32_t n);
void   vp_enc_materials(vp_writer *w, uint32_t req, const vp_material *m, uint32_t n);
/* MATERIAL_PUT: u32 count, then records; every record checked. */
int    vp_dec_materials(const uint8_t *p, size_t len, uint32_t max_batch, const uint8_t **recs, uint32_t *n);
int    vp_material_get(const uint8_t *recs, uint32_t n, uint32_t i, vp_material *out);
int    vp_material_rec_check(const uint8_t *recs, uint32_t n, uint32_t i, char *why, size_t whylen);
/* MATERIAL_REMOVE and TEXTURE_REMOVE are id batches (vp_enc_ids). */

size_t vp_size_texture_put(uint32_t len);
void   vp_enc_texture_put(vp_writer *w, uint32_t req, const vp_texture_put *m);
int    vp_dec_texture_put(const uint8_t *p, size_t len, vp_texture_put *m);
/* The same with the field and the cause in why (may be NULL): "total bytes
 * 0 is outside 1..67108864", "chunk at offset 10 of 5 bytes ends past the
 * total, 12 bytes". */
int    vp_dec_texture_put_why(const uint8_t *p, size_t len, vp_texture_put *m, char *why, size_t whylen);
/* A header's checks (id, format, flags, total, the chunk inside it), as
 * the decoder makes them. */
int    vp_texture_put_check(const vp_texture_put *m, char *why, size_t whylen);

size_t vp_size_env(void);
/* ENV_SET or ENV_REPLY (type). */
void   vp_enc_env(vp_writer *w, uint16_t type, uint32_t req, const vp_env *m);
/* Checks every field (finite, ranges, defined modes and flags); the sun
 * direction is normalised in place. why may be NULL. */
int    vp_dec_env(const uint8_t *p, size_t len, vp_env *m);
/* The same with the field and the cause in why (may be NULL). */
int    vp_dec_env_why(const uint8_t *p, size_t len, vp_env *m, char *why, size_t whylen);
int    vp_env_check(vp_env *m, char *why, size_t whylen);

/* ---- read-back (vp_readback.c): what export reads of the live scene ---- */
/* Any role may send these. MESH_GET (u16 class) is answered by MESH_REPLY
 * in MESH_PUT's layout (decode it with vp_dec_mesh), NOT_FOUND when the
 * class has no mesh. MATERIAL_LIST pages through the materials by id:
 * cursor = the id to start after (0 = from the first), max 1..max_batch;
 * MATERIAL_LIST_REPLY has the next cursor (0 = done) and MATERIAL_PUT's
 * records. TEXTURE_GET asks for a texture's stored encoded bytes from
 * offset (< total), at most max_len (1..) and what fits max_payload;
 * TEXTURE_REPLY is a TEXTURE_PUT chunk (decode it with vp_dec_texture_put).
 * LIGHT_LIST pages through the lights (cursor 0 = from the start, as
 * ENTITY_LIST's: opaque, stable while the scene does not change), max
 * 1..max_batch; LIGHT_LIST_REPLY has the next cursor and LIGHT_PUT's
 * records. */
typedef struct vp_mesh_get {
    uint16_t class_id;
} vp_mesh_get;
typedef struct vp_texture_get {
    uint32_t id;
    uint32_t offset;          /* into the encoded bytes */
    uint32_t max_len;         /* >= 1 */
} vp_texture_get;
/* MATERIAL_LIST and LIGHT_LIST: a page of a listing. */
typedef struct vp_page {
    uint64_t cursor;          /* MATERIAL_LIST: the id to start after (u32 on the wire); LIGHT_LIST: 0 = from the start */
    uint32_t max;             /* records wanted, 1..max_batch */
} vp_page;
/* Their replies: the next page's cursor and the records, as the put
 * message has them (read with vp_material_get or vp_light_get). */
typedef struct vp_page_reply {
    uint64_t next_cursor;     /* 0 = done */
    uint32_t count;
    const uint8_t *recs;      /* count records of VP_MATERIAL_SIZE or VP_LIGHT_SIZE */
} vp_page_reply;
/* One record of a put message, as it has them: MATERIAL_PUT's
 * (VP_MATERIAL_SIZE bytes) and LIGHT_PUT's (VP_LIGHT_SIZE bytes). */
void   vp_put_material(vp_writer *w, const vp_material *m);
void   vp_put_light(vp_writer *w, const vp_light *l);
/* MESH_GET; its reply: MESH_PUT's layout under type MESH_REPLY (sized by
 * vp_size_mesh_uv, read with vp_dec_mesh). */
size_t vp_size_mesh_get(void);
void   vp_enc_mesh_get(vp_writer *w, uint32_t req, const vp_mesh_get *m);
int    vp_dec_mesh_get(const uint8_t *p, size_t len, vp_mesh_get *m);
void   vp_enc_mesh_as(vp_writer *w, uint16_t type, uint32_t req, uint16_t class_id, const float *pos, const float *nrm,
                      const float *uv, const float *tan, uint32_t nv, const uint32_t *idx, uint32_t ni);
/* TEXTURE_GET; its reply: TEXTURE_PUT's layout under type TEXTURE_REPLY
 * (sized by vp_size_texture_put, read with vp_dec_texture_put). */
size_t vp_size_texture_get(void);
void   vp_enc_texture_get(vp_writer *w, uint32_t req, const vp_texture_get *m);
int    vp_dec_texture_get(const uint8_t *p, size_t len, vp_texture_get *m);
void   vp_enc_texture_as(vp_writer *w, uint16_t type, uint32_t req, const vp_texture_put *m);
/* MATERIAL_LIST and LIGHT_LIST: max checked against max_batch (0 = none). */
size_t vp_size_material_list(void);
size_t vp_size_light_list(void);
void   vp_enc_material_list(vp_writer *w, uint32_t req, const vp_page *m);
void   vp_enc_light_list(vp_writer *w, uint32_t req, const vp_page *m);
int    vp_dec_material_list(const uint8_t *p, size_t len, uint32_t max_batch, vp_page *m);
int    vp_dec_light_list(const uint8_t *p, size_t len, uint32_t max_batch, vp_page *m);
/* Their replies: n records after the cursor; the decoders check every
 * record as MATERIAL_PUT's and LIGHT_PUT's. */
size_t vp_size_material_list_reply(uint32_t n);
size_t vp_size_light_list_reply(uint32_t n);
void   vp_enc_material_list_reply(vp_writer *w, uint32_t req, uint32_t next_cursor, const vp_material *m, uint32_t n);
void   vp_enc_light_list_reply(vp_writer *w, uint32_t req, uint64_t next_cursor, const vp_light *l, uint32_t n);
int    vp_dec_material_list_reply(const uint8_t *p, size_t len, vp_page_reply *m);
int    vp_dec_light_list_reply(const uint8_t *p, size_t len, vp_page_reply *m);

/* Version 1 layouts, read from journals and snapshots a version 1 daemon
 * wrote (the upgrade on start): ENTITY_ADD / UPDATE batches of 104-byte
 * records (b->version = 1; read with vp_entity_get as bounds entities,
 * material 0) and OCCLUDER_PUT without flags. */
int    vp_dec_entities_v1(const uint8_t *p, size_t len, uint32_t max_batch, vp_entity_batch *m);
int    vp_dec_occluder_v1(const uint8_t *p, size_t len, uint32_t max_batch, vp_occluder *m);

/* METRICS (empty payload, any role) asks for the daemon's metrics;
 * METRICS_REPLY carries them as text in the Prometheus exposition format
 * 0.0.4, the same text `vantaged --metrics` serves over HTTP. The text is
 * UTF-8 without NUL bytes; text points into the payload (no terminator). */
#define VP_METRICS_PROMETHEUS 0u  /* format: Prometheus text 0.0.4 */
#define VP_METRICS_REPLY_HEADER 8u
typedef struct vp_metrics_reply {
    uint8_t  format;          /* VP_METRICS_*; others INVALID */
    uint32_t text_len;
    const uint8_t *text;
} vp_metrics_reply;
size_t vp_size_metrics_reply(uint32_t text_len);
void vp_enc_metrics_reply(vp_writer *w, uint32_t req, const vp_metrics_reply *m);
int  vp_dec_metrics_reply(const uint8_t *p, size_t len, vp_metrics_reply *m);

/* Encoders: append one whole frame to w (header and payload).
 * Contracts for every vp_enc_* and vp_put_* here and above:
 *   - w, and m where there is one, are non-NULL; input arrays hold what
 *     their count says (e: n records, ids: n, v: n views, subs: nsub,
 *     pos/nrm: 3 * nv floats, idx: ni, verts: 9 * ntris, l: n, names: n
 *     NUL-terminated strings, ids of vp_enc_names: n or NULL) and may be
 *     NULL when that count is 0; vp_enc_error's msg may be NULL (empty);
 *     vp_enc_mesh's nrm may be NULL (VP_MESH_NO_NORMALS, no normals sent);
 *     vp_enc_vis_query_sub's subs may be NULL (no sub-level list, unless
 *     flags has VP_Q_SUBLEVELS: then nsub ids are read from subs);
 *   - w needs room for the matching vp_size_* (below); with less,
 *     w->overflow is set and stays set: the frame is incomplete and must
 *     not be sent (vp_frame_end returns false);
 *   - the encoders check nothing: a field out of range is sent as given
 *     and the peer's decoder refuses it; a count wider than its wire field
 *     is cut to it (vis_query's n to u8, nsub to u16); names longer than
 *     VP_MAX_NAME and error messages longer than VP_MAX_ERROR_MSG (after
 *     escaping) are cut;
 *   - *_begin encoders leave the frame open: put the records, then
 *     vp_frame_end(w). */
/* m->token and m->name: token_len and name_len bytes (NULL when 0). */
void vp_enc_hello(vp_writer *w, uint32_t req, const vp_hello *m);
void vp_enc_hello_ok(vp_writer *w, uint32_t req, const vp_hello_ok *m);
/* msg: NUL-terminated or NULL; sent escaped (control bytes and invalid
 * UTF-8 as \\xNN), at most VP_MAX_ERROR_MSG bytes. */
void vp_enc_error(vp_writer *w, uint32_t req, int32_t code, uint32_t index, const char *msg);
/* PING or PONG (type) with data[0..n); a decoder takes at most VP_MAX_PING. */
void vp_enc_ping(vp_writer *w, uint16_t type, uint32_t req, const uint8_t *data, uint32_t n);
/* A frame of any type with an empty payload. */
void vp_enc_empty(vp_writer *w, uint16_t type, uint32_t req);
/* ENTITY_ADD or ENTITY_UPDATE (type): n records. */
void vp_enc_entities(vp_writer *w, uint16_t type, uint32_t req, const vp_entity *e, uint32_t n);
/* An id batch: ENTITY_REMOVE, ENTITY_GET, OCCLUDER_REMOVE or LIGHT_REMOVE. */
void vp_enc_ids(vp_writer *w, uint16_t type, uint32_t req, const uint64_t *ids, uint32_t n);
void vp_enc_add_reply(vp_writer *w, uint32_t req, uint64_t epoch, const uint32_t *handles, uint32_t n);
void vp_enc_ack(vp_writer *w, uint32_t req, const vp_ack *m);
/* n views (1..VP_MAX_VIEWS); VP_Q_SUBLEVELS in flags is cleared. */
void vp_enc_vis_query(vp_writer *w, uint32_t req, uint8_t flags, float min_area, const vp_view *v, uint32_t n);
/* The same seeing only sub-levels subs[0..nsub) (VP_Q_SUBLEVELS is set
 * when subs is given). */
void vp_enc_vis_query_sub(vp_writer *w, uint32_t req, uint8_t flags, float min_area, const vp_view *v, uint32_t n,
                          const uint16_t *subs, uint32_t nsub);

/* RENDER: one frame of one view (its viewport is the frame's size; 0 x 0 =
 * 1920 x 1080), answered with FRAME. Formats: RAW = float32 linear RGBA
 * (alpha = coverage) then float32 depth (view depth w; +inf where nothing),
 * rows bottom-up; JPEG = tone mapped (ACES, exposure_ev), quality 1..100;
 * H264 = tone mapped as JPEG, one H.264 access unit (Annex B, Constrained
 * Baseline) a FRAME, a stream's frames one chain (the first, and the first
 * after any frame not sent, a key frame), quality the CRF (1..51; 0: 23),
 * max_kbps a rate cap (0: none). */
#define VP_FRAME_RAW 0u
#define VP_FRAME_JPEG 1u
#define VP_FRAME_H264 2u
#define VP_RENDER_NO_OCCLUSION 0x01u
/* a frame's effects turned off for this request or stream (on by default;
 * the daemon's --fx-off turns them off for all) */
#define VP_RENDER_NO_SHADOWS 0x02u   /* the sun's shadow cascades */
#define VP_RENDER_NO_SSAO 0x04u      /* ambient occlusion */
#define VP_RENDER_NO_IBL 0x08u       /* image-based ambient (the two-colour sky ambient instead) */
#define VP_RENDER_NO_FXAA 0x10u      /* anti-aliasing */
#define VP_RENDER_FX 0x1Eu           /* the effect bits above */
#define VP_RENDER_NO_SELECTION 0x20u /* the scene's shared selection (SELECT) not outlined */
/* FRAME_SUBSCRIBE: dynamic resolution. The frame of a re-aimed view (the
 * camera moving) may be drawn at a lower resolution, the largest whose
 * render fits the daemon's budget (vantaged --motion-ms), and scaled back
 * up to the stream's size; once the view rests a full-resolution frame
 * follows. RENDER: no effect. */
#define VP_RENDER_MOTION 0x40u
#define VP_RENDER_FLAGS 0x7Fu
/* "shadows,ssao,ibl,fxaa" (any of them, comma-separated; "none": no bit)
 * as VP_RENDER_NO_* bits: 0, or -1 naming the unknown word in bad. */
int vp_render_fx_parse(const char *list, uint8_t *flags, char *bad, size_t badlen);
/* the entities a frame outlines (a commander's selection): at most this many */
#define VP_RENDER_MAX_HIGHLIGHT 8u
#define VP_RENDER_SIZE (VP_VIEW_SIZE + 80u)
#define VP_FRAME_MAX_PIXELS (4096u * 4096u)
/* which renderer draws it: the daemon's default (--render), or one named */
#define VP_RENDERER_DEFAULT 0u
#define VP_RENDERER_SOFT 1u
#define VP_RENDERER_GL 2u
typedef struct vp_render {
    vp_view  view;
    uint8_t  format;        /* VP_FRAME_* */
    uint8_t  quality;       /* JPEG 1..100; RAW 0; H264 the CRF 1..51, 0 = 23 */
    uint8_t  flags;         /* VP_RENDER_* */
    uint8_t  renderer;      /* VP_RENDERER_* */
    float    exposure_ev;   /* JPEG: -64..64 */
    uint8_t  nhighlight;    /* 0..VP_RENDER_MAX_HIGHLIGHT: entities outlined */
    uint32_t max_kbps;      /* H264: the bit rate's cap, kbit/s (0: the CRF alone); others 0 */
    uint64_t highlight[VP_RENDER_MAX_HIGHLIGHT]; /* their ids (0 and unknown ids: nothing drawn);
                               past nhighlight: 0 */
} vp_render;
void vp_enc_render(vp_writer *w, uint32_t req, const vp_render *m);
int  vp_dec_render(const uint8_t *p, size_t len, vp_render *m);

/* LIGHT_QUERY: the Forward+ tile light lists of one view (16 x 16-pixel
 * tiles, rows from the bottom), as the renderers use them: binned against
 * each tile's depth range from a depth pre-pass of what is visible, or
 * with VP_LQ_NO_DEPTH against the whole frustum depth (no rendering).
 * Answered with LIGHT_TILES. */
#define VP_LQ_NO_DEPTH 0x01u
#define VP_LIGHT_QUERY_SIZE (VP_VIEW_SIZE + 4u)
typedef struct vp_light_query {
    vp_view view;
    uint8_t flags;          /* VP_LQ_* */
} vp_light_query;
void vp_enc_light_query(vp_writer *w, uint32_t req, const vp_light_query *m);
int  vp_dec_light_query(const uint8_t *p, size_t len, vp_light_query *m);

/* LIGHT_TILES: CSR lists, tile t = ty * tiles_x + tx has the lights
 * ids[offset[t] .. offset[t + 1]) (scene light ids, ascending by the
 * daemon's light order). */
#define VP_LIGHT_TILES_HEADER 32u
typedef struct vp_light_tiles {
    uint64_t epoch;
    uint16_t tiles_x, tiles_y;
    uint16_t tile;          /* pixels per tile side: 16 */
    uint8_t  flags;         /* as asked */
    uint32_t in_view;       /* lights that survived the frustum */
    uint32_t max_per_tile;
    uint32_t count;         /* ids in all */
    uint32_t ns;            /* time taken */
    const uint8_t *offsets; /* (tiles + 1) u32 */
    const uint8_t *ids;     /* count u64 */
} vp_light_tiles;
size_t vp_size_light_tiles(uint32_t tiles, uint32_t count);
/* Header; then tiles + 1 offsets (vp_put_u32) and count ids (vp_put_u64). */
void vp_enc_light_tiles_begin(vp_writer *w, uint32_t req, const vp_light_tiles *m);
int  vp_dec_light_tiles(const uint8_t *p, size_t len, vp_light_tiles *m);
/* offset[t] for t <= tiles (m->count past it); id k for k < m->count (0
 * past it). m from vp_dec_light_tiles. */
uint32_t vp_light_tiles_offset(const vp_light_tiles *m, uint32_t t);
uint64_t vp_light_tiles_id(const vp_light_tiles *m, uint32_t k);

/* FRAME_SUBSCRIBE: a RENDER that stays. Answered with ACK; then FRAMEs
 * (with this request's req) are pushed whenever the scene or the view has
 * changed, at most max_fps a second, latest-frame-wins: a frame is rendered
 * only once the previous one has left the daemon, from the scene as it is
 * then. Sent again on the same connection it changes the stream in place
 * (view, size, format, rate); FRAME_UNSUBSCRIBE (empty) ends it. */
#define VP_FRAME_SUB_SIZE (VP_RENDER_SIZE + 4u)
#define VP_FRAME_SUB_MAX_FPS 240u
typedef struct vp_frame_sub {
    vp_render r;
    uint16_t  max_fps;      /* 1..VP_FRAME_SUB_MAX_FPS */
    uint16_t  view_seq;     /* the client's number for this view, echoed by the FRAMEs drawn from it */
} vp_frame_sub;
void vp_enc_frame_sub(vp_writer *w, uint32_t req, const vp_frame_sub *m);
int  vp_dec_frame_sub(const uint8_t *p, size_t len, vp_frame_sub *m);

#define VP_FRAME_HEADER 32u
typedef struct vp_frame {
    uint64_t epoch;
    uint16_t width, height;
    uint8_t  format;
    uint8_t  key;           /* H264: 1 a key frame (IDR, SPS and PPS first: decodable alone); others 0 */
    uint16_t view_seq;      /* the subscription's view_seq it was drawn for (RENDER: 0) */
    uint32_t visible;       /* entities drawn */
    uint32_t render_ns, encode_ns;
    uint32_t data_len;
    const uint8_t *data;
} vp_frame;
size_t vp_size_frame(uint32_t data_len);
/* data NULL: the data_len bytes are already in the buffer right after the
 * header (a frame drawn in place); only the header is written. */
void vp_enc_frame(vp_writer *w, uint32_t req, const vp_frame *m);
int  vp_dec_frame(const uint8_t *p, size_t len, vp_frame *m);
/* Result header; records follow with vp_put_vis_rec, count must match. */
void vp_enc_vis_result_begin(vp_writer *w, uint32_t req, const vp_vis_result *m);
void vp_put_vis_rec(vp_writer *w, const vp_vis_rec *r);
void vp_enc_stats_reply(vp_writer *w, uint32_t req, const vp_stats_reply *m);
void vp_enc_subscribe(vp_writer *w, uint32_t req, uint32_t kinds);
void vp_enc_event(vp_writer *w, const vp_event *m);
void vp_enc_mesh(vp_writer *w, uint32_t req, uint16_t class_id, const float *pos, const float *nrm, uint32_t nv,
                 const uint32_t *idx, uint32_t ni);
/* The same with UVs (2 per vertex) and tangents (4 per vertex), each NULL
 * when not sent (tangents need uvs). */
void vp_enc_mesh_uv(vp_writer *w, uint32_t req, uint16_t class_id, const float *pos, const float *nrm,
                    const float *uv, const float *tan, uint32_t nv, const uint32_t *idx, uint32_t ni);
void vp_enc_occluder(vp_writer *w, uint32_t req, uint64_t id, const double origin[3], const float *verts,
                     uint32_t ntris);
/* The same with flags (VP_OCC_*). */
void vp_enc_occluder_flags(vp_writer *w, uint32_t req, uint64_t id, uint32_t flags, const double origin[3],
                           const float *verts, uint32_t ntris);
void vp_enc_lights(vp_writer *w, uint32_t req, const vp_light *l, uint32_t n);
void vp_enc_list(vp_writer *w, uint32_t req, const vp_list *m);
/* SUBLEVEL_NAMES (ids NULL) or SUBLEVEL_LIST_REPLY (ids given). */
void vp_enc_names(vp_writer *w, uint16_t type, uint32_t req, const char *const *names, const uint16_t *ids,
                  uint32_t n);
void vp_enc_sublevel_ids(vp_writer *w, uint32_t req, const uint16_t *ids, uint32_t n);
void vp_enc_list_reply(vp_writer *w, uint32_t req, uint64_t next_cursor, uint64_t epoch, const vp_entity *e,
                       uint32_t n);

/* Size of the frames above, for sizing buffers: the exact bytes the
 * encoder of the same name appends (header included) for the same
 * arguments; a writer with that much room left never overflows. */
size_t vp_size_hello(const vp_hello *m);
size_t vp_size_hello_ok(void);
size_t vp_size_error(const char *msg);
size_t vp_size_ping(uint32_t n);
size_t vp_size_empty(void);
size_t vp_size_entities(uint32_t n);
size_t vp_size_ids(uint32_t n);
size_t vp_size_add_reply(uint32_t n);
size_t vp_size_ack(void);
size_t vp_size_vis_query(uint32_t n);
size_t vp_size_vis_query_sub(uint8_t flags, uint32_t n, const uint16_t *subs, uint32_t nsub);
size_t vp_size_vis_result(uint32_t n);
size_t vp_size_stats_reply(void);
size_t vp_size_subscribe(void);
size_t vp_size_event(void);
size_t vp_size_mesh(uint32_t nv, uint32_t ni, bool normals);
size_t vp_size_mesh_uv(uint32_t nv, uint32_t ni, bool normals, bool uvs, bool tangents);
size_t vp_size_occluder(uint32_t ntris);
size_t vp_size_lights(uint32_t n);
size_t vp_size_list(void);
size_t vp_size_names(const char *const *names, const uint16_t *ids, uint32_t n);
size_t vp_size_sublevel_ids(uint32_t n);
size_t vp_size_list_reply(uint32_t n);
size_t vp_size_sublevel_begin(const vp_sublevel_begin *m);
size_t vp_size_sublevel_begun(void);
size_t vp_size_sublevel_name(const char *name);
size_t vp_size_sublevel_infos(const vp_sublevel_info *infos, uint32_t n);
size_t vp_size_destroy(void);
size_t vp_size_destroyed(void);
size_t vp_size_mark(void);
size_t vp_size_marked(void);
size_t vp_size_select(uint32_t n);
size_t vp_size_selected(uint32_t n);
size_t vp_size_render(void);
size_t vp_size_light_query(void);
size_t vp_size_frame_sub(void);

/* Decoders: payload p of len bytes (the frame minus its header); p may be
 * NULL only when len is 0; m non-NULL. Return VP_OK or a negative code; on
 * error *m is unspecified. Pointers in *m point into p (no copy, no
 * allocation): valid while p is. Batch decoders
 * check count * record size against the payload and against max_batch
 * (0 = no limit) before anything else. Numbers that must be finite are
 * checked (VP_ERR_NONFINITE). */
int vp_dec_hello(const uint8_t *p, size_t len, vp_hello *m);
int vp_dec_hello_ok(const uint8_t *p, size_t len, vp_hello_ok *m);
int vp_dec_error(const uint8_t *p, size_t len, vp_error *m);
int vp_dec_ping(const uint8_t *p, size_t len, const uint8_t **data, uint32_t *n);
int vp_dec_empty(const uint8_t *p, size_t len);
int vp_dec_entities(const uint8_t *p, size_t len, uint32_t max_batch, vp_entity_batch *m);
int vp_dec_ids(const uint8_t *p, size_t len, uint32_t max_batch, vp_id_batch *m);
int vp_dec_add_reply(const uint8_t *p, size_t len, vp_add_reply *m);
int vp_dec_ack(const uint8_t *p, size_t len, vp_ack *m);
int vp_dec_vis_query(const uint8_t *p, size_t len, vp_vis_query *m);
int vp_dec_vis_result(const uint8_t *p, size_t len, vp_vis_result *m);
int vp_dec_stats_reply(const uint8_t *p, size_t len, vp_stats_reply *m);
int vp_dec_subscribe(const uint8_t *p, size_t len, uint32_t *kinds);
int vp_dec_event(const uint8_t *p, size_t len, vp_event *m);
int vp_dec_mesh(const uint8_t *p, size_t len, uint32_t max_batch, vp_mesh *m);
int vp_dec_occluder(const uint8_t *p, size_t len, uint32_t max_batch, vp_occluder *m);
int vp_dec_lights(const uint8_t *p, size_t len, uint32_t max_batch, const uint8_t **recs, uint32_t *n);
int vp_dec_list(const uint8_t *p, size_t len, uint32_t max_batch, vp_list *m);
int vp_dec_names(const uint8_t *p, size_t len, bool with_ids, vp_name_list *m);
int vp_dec_sublevel_ids(const uint8_t *p, size_t len, uint32_t *n, const uint8_t **ids);
/* id i of the n of vp_dec_sublevel_ids; 0 for i >= n. */
uint16_t vp_sublevel_id_get(const uint8_t *ids, uint32_t n, uint32_t i);
int vp_dec_list_reply(const uint8_t *p, size_t len, vp_list_reply *m);

/* Record getters for batches (validated by the decoder that made them).
 * The int getters (entity, view, light) re-check the record they read, so
 * a record is never trusted blind, and return VP_OK or its code; an index
 * past the count is VP_ERR_COUNT (*out untouched). The others return 0
 * (vp_vis_rec_get: a zeroed record) past the count. All non-NULL. */
int  vp_entity_get(const vp_entity_batch *b, uint32_t i, vp_entity *out);
uint64_t vp_id_get(const vp_id_batch *b, uint32_t i);
uint32_t vp_handle_get(const vp_add_reply *b, uint32_t i);
int  vp_view_get(const vp_vis_query *q, uint32_t i, vp_view *out);
uint16_t vp_query_sublevel_get(const vp_vis_query *q, uint32_t i);
void vp_vis_rec_get(const vp_vis_result *r, uint32_t i, vp_vis_rec *out);
int  vp_light_get(const uint8_t *recs, uint32_t n, uint32_t i, vp_light *out);
/* The per-record checks the batch decoders make (finite numbers, defined
 * flags and kinds, cone order), for record i alone: VP_OK, or the code the
 * decoder returned for it with the field and the cause written to why
 * (why may be NULL). A daemon answers a batch the decoder refused with the
 * first record these refuse, so its ERROR names the record. */
int  vp_entity_rec_check(const vp_entity_batch *b, uint32_t i, char *why, size_t whylen);
int  vp_light_rec_check(const uint8_t *recs, uint32_t n, uint32_t i, char *why, size_t whylen);

/* ---- the layouts described: machine-readable (protocol/vp_layout.h) ------- */
/* Every fixed layout (a message, a record, the fixed head of a longer
 * message) is one field list in protocol/vp_*.c, from which its encoder,
 * decoder, size and this description come. tests/test_protocol_doc.c
 * holds PROTOCOL.md's byte tables to it. */
enum vp_kind { VP_KIND_U8, VP_KIND_U16, VP_KIND_U32, VP_KIND_U64, VP_KIND_I32, VP_KIND_F32, VP_KIND_F64,
               VP_KIND_PAD /* written 0, must read 0 */, VP_KIND_RSV /* written 0, not read */ };
enum vp_check_op { VP_CHECK_RANGE, VP_CHECK_MAX, VP_CHECK_MASK, VP_CHECK_NONZERO, VP_CHECK_COUNT, VP_CHECK_IRANGE };
typedef struct vp_field_desc {
    const char *name;    /* the C member ("pos"); pads "pad1", "pad2", ... */
    uint8_t  kind;       /* enum vp_kind of one element */
    uint16_t offset;     /* bytes from the layout's start */
    uint16_t size;       /* bytes, all elements */
    uint16_t count;      /* elements: 1, or the array's length */
} vp_field_desc;
typedef struct vp_check_desc {
    const char *field;   /* the field checked (a vp_field_desc name) */
    const char *label;   /* how messages name it ("base colour") */
    const char *elems;   /* RANGE: element names, comma-separated; others: the defined values, in words */
    uint8_t  op;         /* enum vp_check_op */
    double   lo, hi;     /* RANGE, COUNT, IRANGE: lo..hi; MAX: hi; MASK: hi = the defined bits */
} vp_check_desc;
typedef struct vp_layout_desc {
    const char *name;    /* the layout's name in the sources ("entity", "env") */
    uint32_t size;       /* bytes on the wire */
    uint32_t nfields, nchecks;
    const vp_field_desc *fields; /* in wire order, contiguous */
    const vp_check_desc *checks; /* in the order the decoder runs them */
} vp_layout_desc;
/* The layouts: count, i-th (NULL past the count), by name (NULL if none).
 * All static; never NULL fields. */
size_t vp_layout_count(void);
const vp_layout_desc *vp_layout_at(size_t i);
const vp_layout_desc *vp_layout_find(const char *name);
/* "u8", "u16", "u32", "u64", "i32", "f32", "f64", "pad", "rsv"; "?" else. */
const char *vp_kind_name(unsigned kind);

/* Whether a message type is known to this version, and its name
 * ("entity_add"; "unknown" for another type; never NULL, static). */
bool vp_type_known(uint16_t type);
const char *vp_type_name(uint16_t type);

#ifdef __cplusplus
}
#endif
#endif
