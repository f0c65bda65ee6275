/*
 * cluster_internal.h — what cluster.c (the stream, the lease, the loop's
 * side), cluster_open.c (connecting, the streams, the start) and
 * cluster_snap.c (snapshots on JetStream) share: the cluster's state.
 */
#ifndef VANTAGE_CLUSTER_INTERNAL_H
#define VANTAGE_CLUSTER_INTERNAL_H

#include "cluster.h"
#include "cluster_rec.h"

#include <nats/nats.h>

#include <stdatomic.h>
#include <sys/types.h>

#define QUEUE_BYTES (64u << 20)     /* records from the stream the loop has not applied yet */
#define UNSTORED_BYTES (64u << 20)  /* the writer's records not yet stored: past it edits wait (BUSY) */
#define UNSTORED_MSGS 16384u
#define TURN_NS 20000000ull         /* a turn applies records for at most this long */

typedef struct pend_msg {           /* a published message not yet stored (writer) */
    uint64_t seq;
    uint64_t lease;                 /* the lease revision it was published under (its id: LEASE-SEQ) */
    uint8_t *data;
    uint32_t len;
    char part[24];
} pend_msg;

struct cluster {
    cluster_config cfg;
    char name[64], stream[80], subject[96], bucket[80], node[96], value[320];
    natsOptions *opts;
    natsConnection *nc;
    jsCtx *js;
    jsOptions quick;                /* JetStream requests the loop waits for: a short timeout */
    jsCtx *jskv;                    /* the lease's: requests time out well inside the TTL */
    kvStore *kv;
    natsSubscription *sub;
    int efd;
    int64_t max_part;               /* bytes of a record per message */
    /* shared with libnats's threads and the lease thread, under mu */
    pthread_mutex_t mu;
    pthread_cond_t cv;
    natsMsg **q;                    /* the stream's messages for the loop, a ring */
    size_t qhead, qn, qcap, qbytes;
    bool draining;                  /* the subscription is being closed: drop what comes */
    uint64_t acked;                 /* the highest stream sequence stored (writer) */
    uint64_t fail_seq;              /* the first publish that failed (0: none) */
    char fail[240];
    int news_won, news_lost;        /* the lease thread's news */
    uint64_t lease_rev;
    char writer[200];               /* the lease holder's endpoint, as it advertises */
    bool stop;
    pthread_t lease_thr;
    bool lease_on;
    atomic_bool fenced;             /* the writer may not publish (its lease is in doubt) */
    atomic_llong renewed;           /* when the last renewal that succeeded was sent (mono ms) */
    pthread_t unsub_thr;            /* a closed subscription's consumer being deleted */
    bool unsub_on;
    atomic_int role;
    /* the loop's own */
    uint64_t last_seen;
    cl_asm as;                      /* messages made records, and where the scene stands: as.applied the
                                       stream sequence applied (replica) or published (writer), as.recs
                                       the last record's number, as.max_lease the highest lease seen */
    pend_msg *pend;                 /* published, not yet stored, oldest first (a ring) */
    size_t phead, pn, pcap, pbytes;
    uint64_t promotions, started_ms;
    /* snapshots (cluster_snap.c) */
    char snap_stream[96], snap_subject[112], snap_index[112];
    uint64_t snap_limit;            /* record bytes published between snapshots */
    uint64_t since_snap;            /* record bytes published since the last one began */
    pid_t snap_child;               /* writing one into snap_fd (a memfd) */
    int snap_fd;
    uint64_t snap_seq, snap_recs, snap_lease; /* what it is as of (snap_lease: the last record's lease) */
    uint64_t last_lease;            /* the lease revision the last published message carries */
    pthread_t snap_thr;             /* publishing it */
    bool snap_thr_on;
    atomic_bool snap_busy;
    uint64_t snap_prev_seq, snap_prev_first; /* the newest published: as of, and its first part */
    atomic_ullong snapshots;        /* published by this daemon */
    bool startup;                   /* cluster_open is catching up: failures return, not exit */
    atomic_bool rebuild;            /* this replica's scene must be made anew from a snapshot and the stream
                                       (trimmed past it, or a writer stepping down); the lease thread wakes
                                       the loop to try again while the stream cannot be read */
    bool rebuild_said;
    bool step_down;                 /* a writer with messages in doubt: a replica again, its scene rebuilt */
    uint64_t dropped_above;         /* answers waiting for a stream sequence above it are never sent
                                       (UINT64_MAX: none; cluster_take_dropped) */
    char startup_err[400];
};

int64_t cl_mono_ms(void);
uint64_t cl_mono_ns(void);
void cl_wake(cluster *cl);
bool cl_lease_doubtful(cluster *cl);
const char *cl_nats_why(natsStatus s);
/* A fault that leaves the scene in doubt: at start it is kept for
 * cluster_open to return, later the process ends. Returns false. */
bool cl_fatal(cluster *cl, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
uint64_t cl_header_u64(natsMsg *m, const char *key, bool *ok);
int cl_subscribe_from(cluster *cl, uint64_t seq, char *err, size_t errlen);
void cl_unsub_join(cluster *cl);
void cl_unsubscribe(cluster *cl);
bool cl_apply_queue(cluster *cl, scene *sc, pthread_rwlock_t *lock, bool *more);
bool cl_promote(cluster *cl, scene *sc, pthread_rwlock_t *lock);
void cl_lease_writer_seen(cluster *cl, kvEntry *e);
void *cl_lease_main(void *arg);
void cl_on_ack(jsCtx *js, natsMsg *m, jsPubAck *pa, jsPubAckErr *pae, void *closure);
int cl_stream_ensure(cluster *cl, const char *name, const char **subjects, int nsubjects, int64_t dup_ns,
                     jsStreamInfo **out, char *err, size_t errlen);
/* cluster_snap.c: the snapshot stream made when missing; the newest
 * snapshot loaded into sc (1; 0: none and the stream begins at 1; -1 with
 * err); the writer's turn (a snapshot started, or its child done); stopped
 * at close; the newest snapshot's position read again (a new writer). */
int cl_snap_ensure(cluster *cl, char *err, size_t errlen);
/* Whether the snapshot index answers (0; -1 and err, "the snapshot
 * index: ..." while its servers do not): a rebuild asks before it lets
 * the scene go. */
int cl_snap_probe(cluster *cl, char *err, size_t errlen);
int cl_snap_load(cluster *cl, scene *sc, uint64_t first, char *err, size_t errlen);
void cl_snap_poll(cluster *cl, const scene *sc);
void cl_snap_stop(cluster *cl);
void cl_snap_refresh(cluster *cl);

#endif
