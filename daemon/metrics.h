/*
 * metrics.h — vantaged's metrics: counters and latency histograms per
 * request type, the query pipeline's stage times and entity counts, frame
 * streams (sent, dropped, discarded), clients by role, connections and
 * their ends, bytes; shown in the Prometheus text exposition format 0.0.4
 * by `vantaged --metrics [ADDR:]PORT` (a small HTTP/1.x responder on the
 * daemon's own loop, metrics_http.c) and by the METRICS message.
 *
 * Cost and threads: everything here is written on the loop thread only.
 * A request costs two clock reads, a counter and one histogram sample (a
 * linear scan of at most 22 bounds); a query's stage times are measured on
 * its worker (as before, for VIS_RESULT's stage_ns) and travel back in its
 * job, so they are recorded on the loop when the reply is queued. No
 * atomics, no locks, and a scrape (also on the loop) reads one consistent
 * state. Gauges (clients by role, the scene's counts) are computed at
 * scrape time, costing nothing in between.
 */
#ifndef VANTAGE_METRICS_H
#define VANTAGE_METRICS_H

#include "httpd.h"
#include "protocol.h"

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

/* The requests counted by type: every client -> server message. */
#define METRICS_REQUEST_TYPES(X)                                                                    \
    X(VP_HELLO) X(VP_PING) X(VP_STATS) X(VP_SUBSCRIBE) X(VP_METRICS) X(VP_ENTITY_ADD)               \
    X(VP_ENTITY_UPDATE) X(VP_ENTITY_REMOVE) X(VP_ENTITY_LIST) X(VP_ENTITY_GET) X(VP_MESH_PUT)       \
    X(VP_OCCLUDER_PUT) X(VP_OCCLUDER_REMOVE) X(VP_LIGHT_PUT) X(VP_LIGHT_REMOVE) X(VP_VIS_QUERY)     \
    X(VP_LIGHT_QUERY) X(VP_RENDER) X(VP_FRAME_SUBSCRIBE) X(VP_FRAME_UNSUBSCRIBE)                   \
    X(VP_SUBLEVEL_NAMES) X(VP_SUBLEVEL_LIST) X(VP_SUBLEVEL_BEGIN) X(VP_SUBLEVEL_COMMIT)             \
    X(VP_SUBLEVEL_ABORT) X(VP_SUBLEVEL_UNLOAD) X(VP_SUBLEVEL_INFO) X(VP_DESTROY) X(VP_MARK)

enum metrics_type {
#define METRICS_X_ENUM(t) MT_##t,
    METRICS_REQUEST_TYPES(METRICS_X_ENUM)
#undef METRICS_X_ENUM
    MT_OTHER,   /* a frame of a type that is no request (unknown, or a reply's) */
    MT_NONE,    /* errors that answer no request: a frame over the limit or with flags, a timeout */
    MT_COUNT
};

/* Latency histograms: fixed buckets, 1-2-5 from 1 us to 10 s, with an
 * upper bound inclusive (Prometheus `le`); n[MH_BOUNDS] counts the rest. */
#define MH_BOUNDS 22u
extern const uint64_t mh_bound_ns[MH_BOUNDS];
typedef struct mhist {
    uint64_t n[MH_BOUNDS + 1]; /* observations per bucket, not cumulative */
    uint64_t sum_ns;
} mhist;

static inline void mhist_add(mhist *h, uint64_t ns)
{
    unsigned i = 0;
    while (i < MH_BOUNDS && ns > mh_bound_ns[i]) i++;
    h->n[i]++;
    h->sum_ns += ns;
}

/* The query stages the daemon measures (VIS_RESULT's stage_ns): the
 * culling core runs cells, spheres, AABBs, screen area and the occlusion
 * test as one fused pass and times only the occlusion raster apart. */
enum { MS_DECODE, MS_CULL, MS_OCC_RASTER, MS_WRITE, MS_COUNT };
/* Entities through a query's stages (cull_query_stats). */
enum { ME_TESTED, ME_SPHERE, ME_AABB, ME_AREA, ME_OCCLUSION, ME_VISIBLE, ME_COUNT };
/* Cells per query (cull_query_stats). */
enum { MC_SEARCHED, MC_FRUSTUM, MC_SUBLEVEL, MC_OCCLUDED, MC_COUNT };
/* Why a connection ended. MD_NONE: it did not. */
enum { MD_NONE, MD_PEER, MD_ERROR, MD_HELLO_TIMEOUT, MD_FRAME_TIMEOUT, MD_OUTPUT_LIMIT, MD_SYNC_FAILED, MD_OUTPUT_TOTAL,
       MD_SHUTDOWN, MD_COUNT };

/* One error code a slot: -1 .. -23 (VP_ERRORS), then the rest. */
#define METRICS_ERR_SLOTS 24u

/* What a query's worker measured, carried back in its job. */
typedef struct metrics_query {
    uint32_t stage_ns[MS_COUNT];
    uint32_t total_ns;        /* on the worker: decode to reply encoded */
    uint32_t entities[ME_COUNT];
    uint32_t cells[MC_COUNT];
    uint32_t occ_kept, occ_rendered; /* views' occlusion buffers kept from the worker's last query / drawn */
} metrics_query;

typedef struct metrics {
    uint64_t requests[MT_COUNT];
    uint64_t errors[MT_COUNT][METRICS_ERR_SLOTS];
    mhist    latency[MT_COUNT];     /* request taken -> reply queued */
    mhist    query;                 /* a query on its worker */
    mhist    stage[MS_COUNT];
    uint64_t entities[ME_COUNT], cells[MC_COUNT];
    uint64_t occ_buffers[2];        /* kept, rendered */
    mhist    frame_render, frame_encode;
    uint64_t frames_sent, frames_dropped, frames_discarded;
    uint64_t frames_scaled; /* drawn smaller while the view moved (VP_RENDER_MOTION), then scaled up */
    uint64_t motion_frames; /* frames of a moving view (VP_RENDER_MOTION), smaller or not */
    double motion_scale_sum; /* their scales of each side (1: full size), summed */
    uint64_t accepted, rejected, auth_failures;
    uint64_t disconnects[MD_COUNT];
    uint64_t jobs_submitted, jobs_done;
    /* workers' reply bytes queued to clients: linked into the reply queue
       by pointer, or copied into its tail block (small ones only) */
    uint64_t out_linked, out_copied;
    uint64_t http[HS_COUNT];     /* --metrics answers by status (httpd.h) */
    uint64_t web_http[HS_COUNT]; /* --web answers by status */
    uint64_t ws_bad;             /* WebSocket text messages refused (the protocol is binary) */
    /* the request being handled (dispatch): whose error send_error counts,
       and when it was taken (a job started now carries it) */
    int      cur;
    uint64_t cur_t0;
} metrics;

/* The metrics_type of a message type. */
int metrics_type(uint16_t type);
/* An error sent: counted under the request being handled (m->cur). */
void metrics_error(metrics *m, int type, int code);
void metrics_query_add(metrics *m, const metrics_query *q);

/* A growing text buffer; oom is sticky. */
typedef struct mbuf {
    char  *p;
    size_t len, cap;
    bool   oom;
} mbuf;
void mbuf_put(mbuf *b, const char *s, size_t n);
void mbuf_free(mbuf *b);

struct server;
/* The exposition of everything (text format 0.0.4) into b, from its start
 * (b->len = 0 first). false: out of memory. */
bool metrics_expose(struct server *s, mbuf *b);

/* ---- metrics_http.c: `vantaged --metrics` -------------------------------------------- */
#define METRICS_HTTP_MAX_CONNS 16u   /* at once; more get 503 */

/* Listens on cfg.metrics_bind:metrics_port and serves GET /metrics from the
 * loop. 0, or -1 (logged). */
int  metrics_http_open(struct server *s);

#endif
