/*
 * server_internal.h — what server.c (sockets, connections, the loop) and
 * handlers.c (messages, queries on the workers) share.
 */
#ifndef VANTAGE_SERVER_INTERNAL_H
#define VANTAGE_SERVER_INTERNAL_H

#include "ae.h"
#include "log.h"
#include "server.h"

#include <pthread.h>
#include <stdbool.h>
#include <stdint.h>
#include <time.h>

typedef struct conn {
    int fd;
    uint32_t id;
    int role;
    bool hello, closing, subscribed;
    bool busy;          /* a query is with a worker: later frames wait */
    uint32_t live_pos;  /* index in server.live */
    uint8_t *in;
    size_t in_len, in_cap;
    uint8_t *out;
    size_t out_len, out_pos, out_cap;
    uint32_t ev_added, ev_updated, ev_removed; /* coalesced, not yet sent */
    char name[64];
} conn;

struct server {
    server_config cfg;
    ae_loop *loop;
    int tcp_fd, unix_fd, sig_fd;
    conn **conns;           /* by fd */
    int conns_cap;
    conn **live;            /* dense: the connections, for the tick's sweep */
    uint32_t nconns, next_id;
    scene *sc;
    uint64_t start_ms, queries, bytes_in, bytes_out, errors;
    /* query workers: they read the scene under scene_lock (shared); the
       loop thread takes it exclusively to apply edits */
    pthread_rwlock_t scene_lock;
    pthread_mutex_t mu;
    pthread_cond_t cv;
    struct job *jobs_head, *jobs_tail;      /* to the workers */
    struct job *done_head, *done_tail;      /* back to the loop */
    int done_fd;                            /* eventfd: results are waiting */
    pthread_t *workers;
    uint32_t nworkers;
    bool stopping;
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
} job;

static inline uint64_t now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000000ull + (uint64_t)ts.tv_nsec;
}

/* ---- server.c: output to a connection ---- */
/* A writer over c's output buffer with room for need bytes (false: out of memory). */
bool out_reserve(conn *c, size_t need, vp_writer *w);
void out_commit(conn *c, const vp_writer *w);
void send_error(server *s, conn *c, uint32_t req, int code, uint32_t index, const char *msg);

/* ---- handlers.c ---- */
/* Handles one complete frame from c (may set c->closing or c->busy). */
void dispatch(server *s, conn *c, const vp_header *h, const uint8_t *p);
/* A query worker thread: jobs in, replies out through s->done_fd. */
void *worker_main(void *arg);

#endif
