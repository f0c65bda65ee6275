/*
 * server_internal.h — what server.c (sockets, connections, the loop) and
 * handlers.c (messages, queries on the workers) share.
 */
#ifndef VANTAGE_SERVER_INTERNAL_H
#define VANTAGE_SERVER_INTERNAL_H

#include "ae.h"
#include "edit.h"
#include "frame_marks.h"
#include "journal.h"
#include "log.h"
#include "metrics.h"
#include "server.h"

#include <pthread.h>
#include <stdbool.h>
#include <stdint.h>
#include <time.h>

/* A connection's frame stream (FRAME_SUBSCRIBE); see frames.c. */
typedef struct frame_sub {
    bool active;
    bool inflight;          /* a frame is with a worker */
    bool dirty;             /* the view changed: draw even at the same epoch */
    uint32_t req;           /* the subscription's req: every FRAME carries it */
    uint32_t gen;           /* bumped when re-aimed or ended: stale frames drop */
    vp_frame_sub m;
    uint64_t shown_epoch;   /* the scene epoch of the last frame sent */
    uint64_t shown_marks;   /* the marks' gen when the last frame was started */
    uint64_t next_ns;       /* the rate cap: no frame starts before (now_ns) */
    uint64_t frames;
    uint32_t last_bytes;    /* the size of the last frame sent */
    uint64_t drain_wait_ns, drain_next_ns; /* the last frame still in the kernel: when to look again */
    uint32_t aims;          /* re-aims (FRAME_SUBSCRIBE on an open stream), ever */
    /* a due frame held back because the viewer has not taken the last one
       (metrics: frames dropped): since when, and what it would show */
    uint64_t held_ns, held_epoch;
    uint32_t held_aims;
    /* eye adaptation (vt_adapt): the EV100 of the last frame sent, and
       when that frame started (now_ns); reset when the stream ends */
    float adapt_ev;
    bool adapt_valid;
    uint64_t adapt_ns;
    /* H.264 (video.h): the stream's encoder between frames (NULL while a
       worker has it, or before the first), and whether the next frame
       must be a key frame (a new viewer or chain, a frame not sent) */
    struct video_enc *venc;
    bool vkey;
    /* dynamic resolution (VP_RENDER_MOTION, frames.c): when the view was
       last re-aimed; whether the next frame follows a move (a re-aim
       of the view); the scale of each
       side a moving frame is drawn at, kept to the render budget; the
       last frame sent was drawn smaller, so a full-size one is due once
       the view rests */
    uint64_t aim_ns;
    bool moving;
    bool refine;
    float mscale;
    struct job *job;        /* the frame with a worker (while inflight): a full-size one the
                               view moved away from is stopped through its cancel */
} frame_sub;

/* One block of a connection's reply queue (server.c). Small replies are
 * encoded straight into the tail block (OUT_BLOCK bytes, or one reply's
 * size when larger); a worker's reply (a RAW frame is W x H x 20 bytes) is
 * linked in as a block of its own by pointer, never copied. */
typedef struct out_block {
    struct out_block *next;
    uint8_t *p;       /* the bytes, p[0..len): data[] here, or a worker's reply (linked) */
    size_t len, cap;  /* bytes queued in it; room (a linked reply: cap = len, nothing is appended) */
    size_t mem;       /* memory it holds, this header included: its share of server.out_held */
    uint8_t data[];   /* a tail block's bytes; none for a linked reply */
} out_block;

/* A texture being uploaded in chunks on a connection (upload.c): the
 * whole TEXTURE_PUT payload it will become, header (offset 0) and bytes. */
typedef struct tex_upload {
    uint32_t id, total, got; /* got: bytes received, the next chunk's offset */
    uint8_t format, flags;
    uint8_t *payload;        /* VP_TEXTURE_PUT_HEADER + total bytes */
} tex_upload;

typedef struct conn {
    struct server *srv; /* the server it belongs to (output accounting) */
    int fd;
    uint32_t id;
    int role;
    bool hello, closing; /* closing: ends once its output has left (or cannot) */
    uint8_t dead;       /* MD_*: ended (conn_kill); freed at the loop's safe point, 0: live */
    uint32_t sub_kinds; /* SUBSCRIBE: VP_EVENT_* pushed to it */
    bool busy;          /* a query is with a worker: later frames wait */
    uint32_t live_pos;  /* index in server.live */
    uint8_t *in;
    size_t in_len, in_cap;
    uint64_t since_ms;  /* when the partial frame in `in` began (0: none) */
    uint64_t born_ms;   /* accepted at */
    out_block *out_head, *out_tail; /* the reply queue, oldest first */
    size_t out_pos;     /* bytes of out_head already written */
    size_t out_bytes;   /* bytes queued and not yet written: what --out-limit bounds */
    size_t out_mem;     /* memory the blocks hold (their mem summed) */
    uint32_t pend_pos;  /* index in server.pend; UINT32_MAX: not there */
    size_t in_peak;     /* most input bytes held since the last sweep (conn_trim) */
    uint16_t sublevel;  /* the sub-level this connection is loading (its open load), 0 = none */
    bool held;          /* an edit's answer waits for the journal's sync (always) */
    uint64_t held_seq;  /* --cluster, replicated: answers wait until the stream stores this (0: none) */
    bool ev_pending;    /* the scene changed since the last EVENT sent */
    uint32_t ev_added, ev_updated, ev_removed; /* coalesced, not yet sent */
    frame_sub fsub;
    tex_upload *upload; /* a chunked TEXTURE_PUT under way, or NULL (one per connection) */
    struct wsio *ws;    /* a WebSocket's framing (web.c), NULL: the socket carries the protocol as it is */
    char name[64];
} conn;

struct server {
    server_config cfg;
    ae_loop *loop;
    int tcp_fd, unix_fd, sig_fd;
    int unix_lock_fd;       /* --unix PATH.lock, flock'ed while the daemon serves PATH */
    conn **conns;           /* by fd */
    int conns_cap;
    conn **live;            /* dense: the connections, for the tick's sweep */
    uint32_t nconns, next_id;
    conn **pend;            /* dense: the connections with output to write, a coalesced event to
                               send or an answer held for the journal: the only ones a turn visits */
    uint32_t npend;
    uint32_t nev_subs;      /* connections subscribed to scene events (VP_EVENT_SCENE) */
    conn **dead;            /* ended this turn (conn_kill), freed at the end of before_sleep */
    uint32_t ndead;
    bool clocks;            /* some client is on a HELLO or frame clock, or holds a big input
                               buffer: the sweep is due (exact after each sweep, set on news) */
    size_t out_held;        /* the connections' output blocks together (sum of out_mem),
                               held under cfg.out_limit_total */
    scene *sc;
    struct cluster *cluster;  /* --cluster: the stream, the lease, the role (cluster.h) */
    uint64_t start_ms, queries, bytes_in, bytes_out, errors;
    uint64_t sweep_ms;      /* when the slow-client sweep is next due */
    /* query workers: they read the scene under scene_lock (shared); the
       loop thread takes it exclusively to apply edits */
    pthread_rwlock_t scene_lock;
    pthread_mutex_t mu;
    pthread_cond_t cv;
    struct job *jobs_head, *jobs_tail;      /* to the workers: frames */
    struct job *fast_head, *fast_tail;      /* to the workers first: queries and light lists */
    struct job *done_head, *done_tail;      /* back to the loop */
    int done_fd;                            /* eventfd: results are waiting */
    pthread_t *workers;
    uint32_t nworkers;
    bool stopping;
    /* pictures (frames.c): the shared OpenGL renderer, taken in turn */
    pthread_mutex_t gl_mu;
    struct vt_gl *gl;
    struct vt_gldraw *gldraw;
    bool gl_failed;
    char gl_err[400];
    uint32_t nsubs;         /* connections with a frame stream */
    uint32_t nvideo;        /* of them, H.264 streams (--max-video) */
    mark_store marks;       /* the recent MARKs, drawn into frames (frame_marks.h) */
    uint64_t ev_epoch;      /* the epoch the last tick's events reported */
    uint64_t upload_bytes;  /* the connections' unfinished texture uploads (total sizes): held
                               under lim.max_texture_mem with the textures */
    journal *journal;       /* --data-dir: the edit journal; NULL = none */
    /* metrics (metrics.h): written on the loop thread only */
    metrics m;
    mbuf mtext;             /* the exposition, rebuilt at each scrape */
    uint64_t start_unix_ns; /* CLOCK_REALTIME when it started serving */
    struct httpd *http;     /* --metrics: the HTTP endpoint; NULL = none */
    struct httpd *web;      /* --web: the browser viewer's endpoint (web.c); NULL = none */
    int web_root_fd;        /* --web-root, opened; -1 = none */
    struct ssl_ctx_st *web_tls; /* --web-cert/--web-key: TLS for --web; NULL = plain HTTP */
};

/* A query handed to a worker, and its reply coming back. */
typedef struct job {
    struct job *next;
    int fd;
    uint32_t conn_id;
    vp_header h;
    uint8_t *payload;   /* a copy of the request's payload */
    uint8_t *reply;     /* the encoded reply frame (VIS_RESULT or ERROR) */
    size_t reply_len;
    bool ok;
    /* a frame of a stream (no payload; the request is stream_req) */
    bool stream;
    uint32_t gen;
    uint16_t view_seq;      /* the subscription's, when the frame was started */
    vp_render stream_req;
    uint64_t start_ns;      /* a stream's frame: when it was started (now_ns) */
    float adapt_ev, adapt_dt; /* its eye adaptation in (and out: the EV used) */
    struct video_enc *venc; /* H.264: the stream's encoder, with the job until it is back */
    bool vkey;              /* H.264: this frame is a key frame */
    uint16_t fps;           /* a stream's max_fps (H.264's rate control) */
    bool adapt_valid;
    float scale;            /* a moving stream's frame: each side drawn at this (dynamic resolution); 0: not moving */
    bool scaled;            /* the worker drew it smaller than its size */
    bool refine;            /* the full-size frame of a view that stopped moving: stopped when it moves again */
    int cancel;             /* set (atomically) by the loop: the worker stops drawing and sends nothing */
    bool cancelled;         /* the worker stopped it */
    uint32_t video_threads; /* H.264: x264's threads if its encoder is opened now */
    uint64_t epoch;     /* the scene epoch it was drawn from */
    /* metrics: when the request was taken (loop clock, ns), the error code
       of a failed job, what the worker measured */
    uint64_t t0;
    int code;
    bool has_query;
    metrics_query mq;
    bool has_frame;
    uint32_t render_ns, encode_ns;
} job;

/* A worker's own scratch, kept between jobs. */
typedef struct worker {
    cull_ctx *ctx;
    cull_result *res;
    size_t res_cap;
    struct vt_soft *soft;
    cull_pool *pool;        /* the software renderer's threads (all cores) */
    uint32_t *mesh_of;      /* class -> frame mesh + 1, all 0 between frames */
    uint64_t vis[CULL_SUBLEVEL_WORDS]; /* the sub-levels a query sees */
    uint64_t only[CULL_SUBLEVEL_WORDS]; /* a query's own sub-level list */
    bool scene_released;    /* the job let go of scene_lock early (a frame, before its encode) */
    uint32_t fast_run;      /* queries taken in a row while frames waited */
} worker;

static inline uint64_t now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000000ull + (uint64_t)ts.tv_nsec;
}

/* ---- server.c: output to a connection ---- */
/* A TCP listener on an IPv4 address (logged on failure: -1). */
int listen_tcp(const char *addr, int port);
/* The Unix socket at path, under its lock file PATH.lock (*lock_fd, held
 * for the daemon's life): -1 (logged) when it cannot be had (listen.c). */
int listen_unix(const char *path, int *lock_fd);
/* Whether a connection more may be taken now (--max-clients). */
bool server_has_room(const server *s);
/* Takes the upgraded WebSocket fd as a protocol connection (web.c's w
 * becomes its framing). fd and w are its from the call on: 0, or -1 when
 * it could not (both given back). */
int server_adopt_ws(server *s, int fd, struct wsio *w);
/* A writer over c's tail block with room for need bytes (a new block when
 * the tail has less; false: out of memory). out_commit queues what the
 * writer wrote (nothing when it overflowed); nothing else may be queued
 * on c between the two. */
bool out_reserve(conn *c, size_t need, vp_writer *w);
void out_commit(conn *c, const vp_writer *w);
/* Queues a worker's reply j->reply (j->reply_len bytes): linked in by
 * pointer (j->reply becomes NULL: c owns it), or copied into the tail when
 * small. false: out of memory (nothing queued, j keeps its reply). */
bool out_take_reply(conn *c, job *j);
void send_error(server *s, conn *c, uint32_t req, int code, uint32_t index, const char *msg);
/* ACK (handlers.c). */
void reply_ack(conn *c, uint32_t req, uint64_t epoch, uint32_t count);

/* ---- handlers.c ---- */
/* One slice of the unloads' freeing, journaled; true while more is left. */
bool server_unload_slice(server *s, uint32_t budget);
/* A connection that was loading a sub-level is gone: its load is dropped. */
void sublevel_conn_gone(server *s, conn *c);
/* Whether c may edit; if not, it is told (AUTH) and false. */
bool editor(server *s, conn *c, uint32_t req);
/* An edit request (h->len payload bytes at p): decoded, journaled,
 * applied, answered. */
void on_edit(server *s, conn *c, const vp_header *h, const uint8_t *p);
/* Handles one complete frame from c (may set c->closing or c->busy). */
void dispatch(server *s, conn *c, const vp_header *h, const uint8_t *p);
/* readback.c: MESH_GET, MATERIAL_LIST, TEXTURE_GET, LIGHT_LIST answered;
 * false for another type. */
bool readback_dispatch(server *s, conn *c, const vp_header *h, const uint8_t *p);
/* A query worker thread: jobs in, replies out through s->done_fd. */
void *worker_main(void *arg);
/* Queues j for the workers. */
void job_submit(server *s, job *j);
/* Worker side: an ERROR into j->reply; the view from the wire (VP_OK, or
 * an error code with msg naming view `index` unless UINT32_MAX); room for
 * `need` culling results. */
void job_error(job *j, int code, uint32_t index, const char *msg);
int  view_from(const vp_view *pv, uint32_t index, cull_view *v, char *msg, size_t msglen);
bool worker_res_reserve(worker *wk, size_t need);

/* ---- upload.c ---- */
/* TEXTURE_PUT from an editor: a whole image is an edit at once; chunks
 * are assembled on the connection (ACK count 0 each, not journaled) and
 * the one that completes the image becomes the edit. */
void upload_chunk(server *s, conn *c, const vp_header *h, const uint8_t *p);
/* Drops c's unfinished upload (a refused chunk, c gone). */
void upload_drop(server *s, conn *c);
/* ENV_GET: the environment as ENV_REPLY. */
void on_env_get(server *s, conn *c, uint32_t req);

/* ---- frames.c ---- */
int  frames_init(server *s);  /* --render gl: the context now, or fail */
void frames_fini(server *s);
const char *renderer_name(int r);
/* Worker side: RENDER (payload) or a stream's frame, into j->reply. */
void run_render(server *s, worker *wk, job *j);
void run_light_query(server *s, worker *wk, job *j);
void on_frame_subscribe(server *s, conn *c, const vp_header *h, const uint8_t *p);
void on_frame_unsubscribe(server *s, conn *c, const vp_header *h, const uint8_t *p);
/* Loop side: starts the frames that are due; returns in how many ms the
 * next one a rate cap holds back is due (-1: none). */
int frames_schedule(server *s);
void frames_done(server *s, conn *c, job *j);
/* Frees what a job of frames holds besides its reply (an H.264 encoder whose stream is gone). */
void frames_job_free(job *j);
void frames_conn_gone(server *s, conn *c);

#endif
