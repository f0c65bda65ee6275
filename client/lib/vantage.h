/*
 * vantage.h — libvantage, the C client of vantaged: connect and hand-
 * shake over TCP or a Unix socket, then blocking calls for every request
 * in protocol/PROTOCOL.md, or vt_send / vt_recv for pipelined batches.
 *
 * A vt_client is not thread-safe: one per thread. Replies point into the
 * client's receive buffer and stay valid until the next call on it.
 *
 * Contracts, for every function below unless its comment says otherwise:
 *   - c is a client from vt_connect, never NULL;
 *   - other pointers must be non-NULL; an input array of n elements
 *     (e, ids, l, views, names) may be NULL when n is 0;
 *   - out parameters hold the reply only when the call returns VP_OK (on
 *     an error they may hold part of one); views in them (data, recs,
 *     text) point into the receive buffer, valid until the next call;
 *   - returns VP_OK; a negative VP_ERR_* the server answered with (ERROR;
 *     vt_last_error has its message and failing record index); a negative
 *     VP_ERR_* of the protocol decoder for a reply that did not decode
 *     (message "malformed <reply> from the server: <why>", index
 *     UINT32_MAX; the connection stays usable); VP_ERR_LIMIT for a request
 *     too large for the send buffer, VP_ERR_TOO_LARGE for one past the
 *     server's max_payload (nothing sent); or VT_ERR_IO (connection lost,
 *     timeout, out of memory; vt_last_error says which, timed_out is set
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

#define VT_ERR_IO (-100)
#define VT_DEFAULT_PORT VP_DEFAULT_PORT
#define VT_MAX_REPLY (1u << 30) /* largest reply frame accepted */

typedef struct vt_client vt_client;

typedef struct vt_connect_opts {
    const char *host;      /* NULL = 127.0.0.1 (ignored with unix_path) */
    int port;              /* 0 = VT_DEFAULT_PORT */
    const char *unix_path; /* Unix socket instead of TCP */
    int role;              /* enum vp_role; 0 = viewer */
    const char *token;     /* NULL = none */
    const char *name;      /* for the server's logs; NULL = "libvantage" */
    int timeout_ms;        /* per call; 0 = 10000, < 0 = none */
} vt_connect_opts;

typedef struct vt_error {
    int code;
    uint32_t index;        /* failing record of a batch, or UINT32_MAX */
    bool timed_out;        /* VT_ERR_IO because the call's timeout passed */
    char msg[1100];
} vt_error;

/* Connects and says hello. o may be NULL (every default); err may be
 * NULL (errlen unused), else it gets a message of at most errlen - 1
 * bytes. VP_OK with *out set; on failure *out is NULL and the return is
 * VT_ERR_IO (no connection, out of memory) or the server's or decoder's
 * code for the handshake (VP_ERR_AUTH: role or token refused). */
int  vt_connect(const vt_connect_opts *o, vt_client **out, char *err, size_t errlen);
/* Closes and frees; c may be NULL. */
void vt_close(vt_client *c);
/* The server's HELLO_OK and the last call's error: valid until vt_close. */
const vp_hello_ok *vt_server(const vt_client *c);
const vt_error *vt_last_error(const vt_client *c);

/* Pipelining: encode frames with the protocol encoders into a buffer, send
 * it, then read the replies in order. vt_next_req hands out request ids. */
uint32_t vt_next_req(vt_client *c); /* never 0 */
/* Sends data[0..len) whole: VP_OK or VT_ERR_IO. */
int vt_send(vt_client *c, const uint8_t *data, size_t len);
/* Reads the next frame (a reply or a pushed EVENT). *payload is valid
 * until the next call. timeout_ms < 0 = the client's default; 0 = only
 * what has arrived: VP_NEED_MORE if no whole frame is there yet. */
int vt_recv(vt_client *c, vp_header *h, const uint8_t **payload, int timeout_ms);
/* The fd, for poll() in an event loop of the caller's. */
int vt_fd(const vt_client *c);

/* Blocking calls. */
/* PING with 7 bytes; VT_ERR_IO if the PONG does not echo them. */
int vt_ping(vt_client *c);
int vt_stats(vt_client *c, vp_stats_reply *out);
/* The daemon's metrics (METRICS): *text (text_len bytes, not terminated,
 * no NUL inside) is the Prometheus text exposition format 0.0.4, what
 * `vantaged --metrics` serves; valid until the next call. A daemon older
 * than the message answers VP_ERR_TYPE. */
int vt_metrics(vt_client *c, const char **text, size_t *text_len);
/* Adds e[0..n) (all or nothing). handles may be NULL, else it has room
 * for n (the handles in record order); epoch may be NULL (the scene epoch
 * after the edit). A reply with another count than n is VP_ERR_COUNT. */
int vt_add(vt_client *c, const vp_entity *e, uint32_t n, uint32_t *handles, uint64_t *epoch);
/* Updates and removals: epoch may be NULL. */
int vt_update(vt_client *c, const vp_entity *e, uint32_t n, uint64_t *epoch);
int vt_remove(vt_client *c, const uint64_t *ids, uint32_t n, uint64_t *epoch);
/* Records of the given ids, in order (out->batch views the reply). */
int vt_get(vt_client *c, const uint64_t *ids, uint32_t n, vp_list_reply *out);
/* One page of the scene's entities; pass out->next_cursor back until 0. */
int vt_list(vt_client *c, uint64_t cursor, uint32_t max, vp_list_reply *out);
/* VIS_QUERY of views[0..nviews) (1..VP_MAX_VIEWS), flags VP_Q_* (its
 * VP_Q_SUBLEVELS is ignored), min_area >= 0 pixels; out views the reply
 * (vp_vis_rec_get), valid until the next call. */
int vt_query(vt_client *c, const vp_view *views, uint32_t nviews, uint8_t flags, float min_area,
             vp_vis_result *out);
/* The same, seeing only the sub-levels subs[0..nsub) (1..4096 ids); subs
 * NULL is vt_query (VP_Q_SUBLEVELS is set exactly when subs is given). */
int vt_query_sub(vt_client *c, const vp_view *views, uint32_t nviews, uint8_t flags, float min_area,
                 const uint16_t *subs, uint32_t nsub, vp_vis_result *out);
/* One frame (RENDER -> FRAME); out->data is valid until the next call. */
int vt_render(vt_client *c, const vp_render *m, vp_frame *out);
int vt_subscribe(vt_client *c, uint32_t kinds);
/* The Forward+ tile light lists of a view (LIGHT_QUERY); out views the
 * reply (vp_light_tiles_offset / _id), valid until the next call. */
int vt_light_query(vt_client *c, const vp_light_query *m, vp_light_tiles *out);
/* A frame stream (FRAME_SUBSCRIBE): frames come as the scene or the view
 * changes, latest-frame-wins, at most m->max_fps a second. Called again it
 * re-aims the stream in place. Frames that arrive during other calls are
 * dropped (the next is newer); an error that ends the stream is returned
 * by the next vt_wait_frame. */
int vt_frame_subscribe(vt_client *c, const vp_frame_sub *m);
int vt_frame_unsubscribe(vt_client *c);
/* The next frame of the stream; out->data is valid until the next call.
 * VT_ERR_IO with vt_last_error()->timed_out on timeout (timeout_ms < 0:
 * the client's timeout). */
int vt_wait_frame(vt_client *c, vp_frame *out, int timeout_ms);
/* Ids of names[0..n) (NUL-terminated, 1..255 bytes each; longer ones are
 * cut to 255), defining new ones; ids has room for n. A reply with another
 * count is VP_ERR_COUNT. */
int vt_sublevel_ids(vt_client *c, const char *const *names, uint32_t n, uint16_t *ids);
/* Every named sub-level (walk out with vp_name_next; valid until the next call). */
int vt_sublevel_list(vt_client *c, vp_name_list *out);
/* Sub-level loads (see PROTOCOL.md): begin, then add entities (sub-level 0
 * or out->id), meshes (classes out->class_base ..), occluders and lights
 * on this connection; commit shows all of it at one epoch (out->epoch,
 * out->count = entities), abort or closing throws it away. Unload hides a
 * loaded sub-level at one epoch and frees it. */
/* name: NUL-terminated, 1..255 bytes, else VP_ERR_INVALID and nothing is
 * sent. classes: mesh classes to reserve, 0..4096. The vp_ack outs of
 * commit, abort and unload may be NULL. */
int vt_sublevel_begin(vt_client *c, const char *name, uint16_t classes, vp_sublevel_begun *out);
int vt_sublevel_commit(vt_client *c, vp_ack *out);
int vt_sublevel_abort(vt_client *c, vp_ack *out);
int vt_sublevel_unload(vt_client *c, const char *name, vp_ack *out);
/* Every named sub-level with its state and counts (walk with
 * vp_sublevel_info_next; valid until the next call). */
int vt_sublevel_info(vt_client *c, vp_sublevel_infos *out);
/* A destruction event (DESTROY): a sphere on entity m->id; out says the
 * epoch it shows at, the entity's spheres, its occluder's triangles left. */
int vt_destroy(vt_client *c, const vp_destroy *m, vp_destroyed *out);
/* MARK (commander role): pushed as MARKED to the connections subscribed to
 * VP_EVENT_MARKS; *sent (may be NULL) = how many. */
int vt_mark(vt_client *c, const vp_mark *m, uint32_t *sent);
/* Waits for a pushed EVENT (other frames are dropped); VT_ERR_IO with
 * timed_out set on timeout (timeout_ms < 0: the client's timeout). */
int vt_wait_event(vt_client *c, vp_event *out, int timeout_ms);
/* Adds or replaces the lights l[0..n) (by id); answered with ACK. */
int vt_put_lights(vt_client *c, const vp_light *l, uint32_t n);
/* Adds or replaces occluder id: verts holds 9 * ntris floats, ntris
 * counter-clockwise triangles relative to origin (3 doubles). Queries cull
 * what occluders hide (VP_Q_*). */
int vt_put_occluder(vt_client *c, uint64_t id, const double origin[3], const float *verts, uint32_t ntris);
int vt_remove_occluders(vt_client *c, const uint64_t *ids, uint32_t n, uint64_t *epoch);
/* Replaces the mesh of class_id: pos holds 3 * nv floats (object space),
 * nrm 3 * nv unit normals or NULL: no normals, drawn flat (MESH_PUT's
 * NO_NORMALS), idx ni indices (a multiple of 3, each < nv, counter-
 * clockwise triangles). */
int vt_put_mesh(vt_client *c, uint16_t class_id, const float *pos, const float *nrm, uint32_t nv,
                const uint32_t *idx, uint32_t ni);

/* Views: gluLookAt + gluPerspective (fovy in degrees, aspect = w/h) or an
 * orthographic box of width x height metres, camera-relative (origin = eye),
 * OpenGL depth. v, eye and at non-NULL; up NULL = +Y. Writes *v and
 * returns true; false (v untouched) for a degenerate camera (eye == at, up
 * parallel to the view), w or h 0, znear <= 0 (perspective), zfar <= znear,
 * fovy outside (0, 180), or width / height <= 0. */
bool vt_view_perspective(vp_view *v, const double eye[3], const double at[3], const double up[3], double fovy_deg,
                         uint16_t w, uint16_t h, double znear, double zfar);
bool vt_view_ortho(vp_view *v, const double eye[3], const double at[3], const double up[3], double width,
                   double height, uint16_t w, uint16_t h, double znear, double zfar);

#ifdef __cplusplus
}
#endif
#endif
