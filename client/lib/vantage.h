/*
 * vantage.h — libvantage, the C client of vantaged: connect and hand-
 * shake over TCP or a Unix socket, then blocking calls for every request
 * in protocol/PROTOCOL.md, or vtc_send / vtc_recv for pipelined batches.
 *
 * A vtc_client is not thread-safe: one per thread. Replies point into the
 * client's receive buffer and stay valid until the next call on it.
 *
 * Contracts, for every function below unless its comment says otherwise:
 *   - c is a client from vtc_connect, never NULL;
 *   - other pointers must be non-NULL; an input array of n elements
 *     (e, ids, l, views, names) may be NULL when n is 0;
 *   - out parameters hold the reply only when the call returns VP_OK (on
 *     an error they may hold part of one); views in them (data, recs,
 *     text) point into the receive buffer, valid until the next call;
 *   - returns VP_OK; a negative VP_ERR_* the server answered with (ERROR;
 *     vtc_last_error has its message and failing record index); a negative
 *     VP_ERR_* of the protocol decoder for a reply that did not decode
 *     (message "malformed <reply> from the server: <why>", index
 *     UINT32_MAX; the connection stays usable); VP_ERR_LIMIT for a request
 *     too large for the send buffer, VP_ERR_TOO_LARGE for one past the
 *     server's max_payload (nothing sent); or VTC_ERR_IO (connection lost,
 *     timeout, out of memory; vtc_last_error says which, timed_out is set
 *     on a timeout).
 */
#ifndef VANTAGE_CLIENT_H
#define VANTAGE_CLIENT_H

#include "protocol.h"

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* The library's own codes, a space beside the protocol's VP_ERRORS (no
 * value shared): the calls return a VP code or one of these. */
#define VTC_ERRORS(X) X(VTC_ERR_IO, -100, "connection lost, timed out or out of memory")
VP_ERR_ENUM(VTC_ERRORS);
#define VTC_DEFAULT_PORT VP_DEFAULT_PORT

/* The message for any code a call returns: VTC_ERRORS' rows, else
 * vp_strerror's ("unknown error" for a value in neither). Never NULL;
 * static storage. */
const char *vtc_strerror(int code);
#define VTC_MAX_REPLY (1u << 30) /* largest reply frame accepted */

typedef struct vtc_client vtc_client;

typedef struct vtc_connect_opts {
    const char *host;      /* NULL = 127.0.0.1 (ignored with unix_path) */
    int port;              /* 0 = VTC_DEFAULT_PORT */
    const char *unix_path; /* Unix socket instead of TCP */
    int role;              /* enum vp_role; 0 = viewer */
    const char *token;     /* NULL = none */
    const char *name;      /* for the server's logs; NULL = "libvantage" */
    int timeout_ms;        /* per call; 0 = 10000, < 0 = none */
    /* Several daemons (a cluster, vantaged --cluster): comma-separated
     * endpoints, each HOST:PORT, [IPv6]:PORT or a Unix socket path (it has a
     * '/'), tried in turn until one answers HELLO. A viewer or commander
     * starts at a random one (spreading viewers across replicas), an editor
     * at the first. NULL: host, port and unix_path above. */
    const char *endpoints;
    /* An edit answered NOT_WRITER (sent to a replica) is sent again to the
     * writer the answer names, on a new connection that replaces this one
     * (at most 3 hops), unless no_follow; while no writer is known, or the
     * one named cannot be reached (a failover), it is asked again every
     * 100 ms for up to the call's timeout (10 s at most). */
    bool no_follow;
} vtc_connect_opts;

typedef struct vtc_error {
    int code;
    uint32_t index;        /* failing record of a batch, or UINT32_MAX */
    bool timed_out;        /* VTC_ERR_IO because the call's timeout passed */
    char msg[1100];
} vtc_error;

/* Connects and says hello. o may be NULL (every default); err may be
 * NULL (errlen unused), else it gets a message of at most errlen - 1
 * bytes. VP_OK with *out set; on failure *out is NULL and the return is
 * VTC_ERR_IO (no connection, out of memory) or the server's or decoder's
 * code for the handshake (VP_ERR_AUTH: role or token refused). */
int  vtc_connect(const vtc_connect_opts *o, vtc_client **out, char *err, size_t errlen);
/* Closes and frees; c may be NULL. */
void vtc_close(vtc_client *c);
/* The server's HELLO_OK and the last call's error: valid until vtc_close. */
const vp_hello_ok *vtc_server(const vtc_client *c);
const vtc_error *vtc_last_error(const vtc_client *c);

/* Pipelining: encode frames with the protocol encoders into a buffer, send
 * it, then read the replies in order. vtc_next_req hands out request ids. */
uint32_t vtc_next_req(vtc_client *c); /* never 0 */
/* Sends data[0..len) whole: VP_OK or VTC_ERR_IO. */
int vtc_send(vtc_client *c, const uint8_t *data, size_t len);
/* Reads the next frame (a reply or a pushed EVENT). *payload is valid
 * until the next call. timeout_ms < 0 = the client's default; 0 = only
 * what has arrived: VP_NEED_MORE if no whole frame is there yet. */
int vtc_recv(vtc_client *c, vp_header *h, const uint8_t **payload, int timeout_ms);
/* The fd, for poll() in an event loop of the caller's. */
int vtc_fd(const vtc_client *c);

/* Blocking calls. */
/* PING with 7 bytes; VTC_ERR_IO if the PONG does not echo them. */
int vtc_ping(vtc_client *c);
int vtc_stats(vtc_client *c, vp_stats_reply *out);
/* The daemon's metrics (METRICS): *text (text_len bytes, not terminated,
 * no NUL inside) is the Prometheus text exposition format 0.0.4, what
 * `vantaged --metrics` serves; valid until the next call. A daemon older
 * than the message answers VP_ERR_TYPE. */
int vtc_metrics(vtc_client *c, const char **text, size_t *text_len);
/* Adds e[0..n) (all or nothing). handles may be NULL, else it has room
 * for n (the handles in record order); epoch may be NULL (the scene epoch
 * after the edit). A reply with another count than n is VP_ERR_COUNT. */
int vtc_add(vtc_client *c, const vp_entity *e, uint32_t n, uint32_t *handles, uint64_t *epoch);
/* Updates and removals: epoch may be NULL. */
int vtc_update(vtc_client *c, const vp_entity *e, uint32_t n, uint64_t *epoch);
int vtc_remove(vtc_client *c, const uint64_t *ids, uint32_t n, uint64_t *epoch);
/* Records of the given ids, in order (out->batch views the reply). */
int vtc_get(vtc_client *c, const uint64_t *ids, uint32_t n, vp_list_reply *out);
/* One page of the scene's entities; pass out->next_cursor back until 0. */
int vtc_list(vtc_client *c, uint64_t cursor, uint32_t max, vp_list_reply *out);
/* VIS_QUERY of views[0..nviews) (1..VP_MAX_VIEWS), flags VP_Q_* (its
 * VP_Q_SUBLEVELS is ignored), min_area >= 0 pixels; out views the reply
 * (vp_vis_rec_get), valid until the next call. */
int vtc_query(vtc_client *c, const vp_view *views, uint32_t nviews, uint8_t flags, float min_area,
              vp_vis_result *out);
/* The same, seeing only the sub-levels subs[0..nsub) (1..4096 ids); subs
 * NULL is vtc_query (VP_Q_SUBLEVELS is set exactly when subs is given). */
int vtc_query_sub(vtc_client *c, const vp_view *views, uint32_t nviews, uint8_t flags, float min_area,
                  const uint16_t *subs, uint32_t nsub, vp_vis_result *out);
/* One frame (RENDER -> FRAME); out->data is valid until the next call. */
int vtc_render(vtc_client *c, const vp_render *m, vp_frame *out);
int vtc_subscribe(vtc_client *c, uint32_t kinds);
/* The Forward+ tile light lists of a view (LIGHT_QUERY); out views the
 * reply (vp_light_tiles_offset / _id), valid until the next call. */
int vtc_light_query(vtc_client *c, const vp_light_query *m, vp_light_tiles *out);
/* A frame stream (FRAME_SUBSCRIBE): frames come as the scene or the view
 * changes, latest-frame-wins, at most m->max_fps a second. Called again it
 * re-aims the stream in place. Frames that arrive during other calls are
 * dropped (the next is newer); an error that ends the stream is returned
 * by the next vtc_wait_frame. */
int vtc_frame_subscribe(vtc_client *c, const vp_frame_sub *m);
int vtc_frame_unsubscribe(vtc_client *c);
/* The next frame of the stream; out->data is valid until the next call.
 * VTC_ERR_IO with vtc_last_error()->timed_out on timeout (timeout_ms < 0:
 * the client's timeout). */
int vtc_wait_frame(vtc_client *c, vp_frame *out, int timeout_ms);
/* Ids of names[0..n) (NUL-terminated, 1..255 bytes each; longer ones are
 * cut to 255), defining new ones; ids has room for n. A reply with another
 * count is VP_ERR_COUNT. */
int vtc_sublevel_ids(vtc_client *c, const char *const *names, uint32_t n, uint16_t *ids);
/* Every named sub-level (walk out with vp_name_next; valid until the next call). */
int vtc_sublevel_list(vtc_client *c, vp_name_list *out);
/* Sub-level loads (see PROTOCOL.md): begin, then add entities (sub-level 0
 * or out->id), meshes (classes out->class_base ..), occluders and lights
 * on this connection; commit shows all of it at one epoch (out->epoch,
 * out->count = entities), abort or closing throws it away. Unload hides a
 * loaded sub-level at one epoch and frees it. */
/* name: NUL-terminated, 1..255 bytes, else VP_ERR_INVALID and nothing is
 * sent. classes: mesh classes to reserve, 0..4096. The vp_ack outs of
 * commit, abort and unload may be NULL. */
int vtc_sublevel_begin(vtc_client *c, const char *name, uint16_t classes, vp_sublevel_begun *out);
int vtc_sublevel_commit(vtc_client *c, vp_ack *out);
int vtc_sublevel_abort(vtc_client *c, vp_ack *out);
int vtc_sublevel_unload(vtc_client *c, const char *name, vp_ack *out);
/* Every named sub-level with its state and counts (walk with
 * vp_sublevel_info_next; valid until the next call). */
int vtc_sublevel_info(vtc_client *c, vp_sublevel_infos *out);
/* A destruction event (DESTROY): a sphere on entity m->id; out says the
 * epoch it shows at, the entity's spheres, its occluder's triangles left. */
int vtc_send_destruction(vtc_client *c, const vp_destroy *m, vp_destroyed *out);
/* MARK (commander role): pushed as MARKED to the connections subscribed to
 * VP_EVENT_MARKS; *sent (may be NULL) = how many. */
int vtc_mark(vtc_client *c, const vp_mark *m, uint32_t *sent);
/* SELECT (commander role): replaces the scene's shared selection with
 * ids[0..n) (n <= VP_SELECT_MAX; 0 clears), pushed as SELECTED to the
 * connections subscribed to VP_EVENT_SELECTION and outlined in frames;
 * *sent (may be NULL) = how many it went to. */
int vtc_select(vtc_client *c, const uint64_t *ids, uint32_t n, uint32_t *sent);
/* Waits for a pushed EVENT (other frames are dropped); VTC_ERR_IO with
 * timed_out set on timeout (timeout_ms < 0: the client's timeout). */
int vtc_wait_event(vtc_client *c, vp_event *out, int timeout_ms);
/* The same for a pushed SELECTED (out->ids valid until the next call;
 * vp_id_at reads them). */
int vtc_wait_selected(vtc_client *c, vp_selected *out, int timeout_ms);
/* Adds or replaces the lights l[0..n) (by id); answered with ACK. */
int vtc_put_lights(vtc_client *c, const vp_light *l, uint32_t n);
/* Adds or replaces occluder id: verts holds 9 * ntris floats, ntris
 * counter-clockwise triangles relative to origin (3 doubles). Queries cull
 * what occluders hide (VP_Q_*). */
int vtc_put_occluder(vtc_client *c, uint64_t id, const double origin[3], const float *verts, uint32_t ntris);
int vtc_remove_occluders(vtc_client *c, const uint64_t *ids, uint32_t n, uint64_t *epoch);
/* Scene model (protocol version 2). An entity added with VP_ENT_TRANSFORM
 * in its flags (vtc_add / vtc_update) is placed by pos / rot / scale over
 * its class mesh (which must exist); vtc_entity_trs fills such a record.
 * vtc_transform_set moves many of them (TRANSFORM_SET, all or nothing);
 * vtc_material_put adds or replaces materials (entities using one see the
 * change); vtc_material_remove refuses a material in use (VP_ERR_STATE).
 * Each answered with ACK (epoch in *epoch if not NULL). */
void vtc_entity_trs(vp_entity *e, uint64_t id, uint16_t class_id, const double pos[3], const float rot[4],
                    const float scale[3]);
int vtc_transform_set(vtc_client *c, const vp_transform *t, uint32_t n, uint64_t *epoch);
int vtc_material_put(vtc_client *c, const vp_material *m, uint32_t n, uint64_t *epoch);
int vtc_material_remove(vtc_client *c, const uint64_t *ids, uint32_t n, uint64_t *epoch);
/* The same as vtc_put_occluder with flags (VP_OCC_ATTACHED: verts and
 * origin in the local space of the entity with the same id). */
int vtc_put_occluder_flags(vtc_client *c, uint64_t id, uint32_t flags, const double origin[3], const float *verts,
                           uint32_t ntris);
/* Replaces the mesh of class_id with UVs (2 per vertex) and tangents (4
 * per vertex, need uv), either NULL when not sent. */
int vtc_put_mesh_uv(vtc_client *c, uint16_t class_id, const float *pos, const float *nrm, const float *uv,
                    const float *tan, uint32_t nv, const uint32_t *idx, uint32_t ni);
/* Replaces the mesh of class_id: pos holds 3 * nv floats (object space),
 * nrm 3 * nv unit normals or NULL: no normals, drawn flat (MESH_PUT's
 * NO_NORMALS), idx ni indices (a multiple of 3, each < nv, counter-
 * clockwise triangles). */
int vtc_put_mesh(vtc_client *c, uint16_t class_id, const float *pos, const float *nrm, uint32_t nv,
                 const uint32_t *idx, uint32_t ni);
/* TEXTURE_PUT (editor): the encoded image data[0..len) (1..
 * VP_MAX_TEXTURE_BYTES; format VP_TEX_PNG / JPEG / EXR, flags VP_TEX_SRGB
 * for colour data) under id (1..UINT32_MAX; an existing one is replaced).
 * Sent in chunks of at most the server's max_payload, each waiting for its
 * ACK; the last is answered once the image is decoded and stored (its
 * errors: INVALID not decodable, LIMIT over --max-texture-size or
 * --max-texture-mem, NONFINITE an EXR with NaN or infinity). epoch may be
 * NULL. A failure part-way leaves nothing on the server (the daemon drops
 * an upload whose chunk it refused). */
int vtc_texture_put(vtc_client *c, uint32_t id, uint8_t format, uint8_t flags, const uint8_t *data, size_t len,
                    uint64_t *epoch);
/* The format an image's first bytes data[0..n) say: VP_TEX_PNG (PNG's
 * 8-byte signature), VP_TEX_JPEG (FF D8 FF), VP_TEX_EXR (76 2F 31 01), or
 * -1. */
int vtc_texture_format(const uint8_t *data, size_t n);
/* The same, from a file read whole; format -1: told by its first bytes
 * (PNG, JPEG, EXR signatures; VP_ERR_INVALID if none). A file that cannot
 * be read: VTC_ERR_IO with the path and why in vtc_last_error. */
int vtc_texture_put_file(vtc_client *c, uint32_t id, int format, uint8_t flags, const char *path, uint64_t *epoch);
/* TEXTURE_REMOVE (editor): ids[0..n), all or nothing; STATE while a
 * material or the sky uses one. */
int vtc_texture_remove(vtc_client *c, const uint64_t *ids, uint32_t n, uint64_t *epoch);
/* ENV_SET (editor): the environment, replaced whole (start from
 * vtc_env_get's or vp_env_default's). ENV_GET (any role): the current one. */
int vtc_env_set(vtc_client *c, const vp_env *env, uint64_t *epoch);
int vtc_env_get(vtc_client *c, vp_env *out);

/* Read-back (any role; what `vantage export` reads). The mesh of a class
 * (NOT_FOUND: none), in MESH_PUT's layout (out's arrays view the reply). */
int vtc_mesh_get(vtc_client *c, uint16_t class_id, vp_mesh *out);
/* A page of materials by id after cursor (0 = from the first), max
 * 1..max_batch; pass out->next_cursor back until 0 (read the records with
 * vp_material_get). */
int vtc_material_list(vtc_client *c, uint32_t cursor, uint32_t max, vp_page_reply *out);
/* Texture id's stored encoded bytes from offset: out->len of them (at most
 * max_len and what fits the server's max_payload), out->total in all. */
int vtc_texture_get(vtc_client *c, uint32_t id, uint32_t offset, uint32_t max_len, vp_texture_put *out);
/* A page of lights (cursor 0 = from the start, then out->next_cursor until
 * 0; read the records with vp_light_get). */
int vtc_light_list(vtc_client *c, uint64_t cursor, uint32_t max, vp_page_reply *out);
/* Views: gluLookAt + gluPerspective (fovy in degrees, aspect = w/h) or an
 * orthographic box of width x height metres, camera-relative (origin = eye),
 * OpenGL depth. v, eye and at non-NULL; up NULL = +Y. Writes *v and
 * returns true; false (v untouched) for a degenerate camera (eye == at, up
 * parallel to the view), w or h 0, znear <= 0 (perspective), zfar <= znear,
 * fovy outside (0, 180), or width / height <= 0. */
bool vtc_view_perspective(vp_view *v, const double eye[3], const double at[3], const double up[3], double fovy_deg,
                          uint16_t w, uint16_t h, double znear, double zfar);
bool vtc_view_ortho(vp_view *v, const double eye[3], const double at[3], const double up[3], double width,
                    double height, uint16_t w, uint16_t h, double znear, double zfar);

#ifdef __cplusplus
}
#endif
#endif
