/*
 * cluster.h — many daemons, one live scene, through NATS JetStream
 * (libnats): `vantaged --cluster URLS --scene-name NAME` (or --follow NAME).
 *
 * One daemon of a scene is its writer: it holds the lease, a key in a
 * JetStream KV bucket with a TTL, renewed well inside it and taken with
 * compare-and-set on the key's revision (no consensus of our own: the KV's
 * stream is Raft-replicated by NATS). Every edit the writer applies is
 * published, as the journal's record format (journal.h), to the scene's
 * stream, in order: each publish expects the stream's last sequence to be
 * the one before it (a writer that lost the race, or its lease, cannot add
 * a record after someone else's) and carries a message id for the
 * stream's de-duplication (a retried publish is stored once) and the
 * lease's revision.
 *
 * The others are replicas: an ordered consumer of the stream feeds the
 * loop, which applies each record with journal_rec_apply, the code crash
 * recovery replays the journal with. A record that fails its checks (CRC,
 * sequence, lease order, the scene refusing it) stops the replica with the
 * stream sequence in the log: it never serves a diverged scene. When the
 * lease expires a replica takes it, applies the stream to its end, and
 * writes from there: the record numbers and the scene epoch go on.
 *
 * A writer that loses its lease, or finds another writer's message where
 * its own should be, with messages not known to be stored, steps down: a
 * replica again, its scene rebuilt from the newest snapshot and the stream
 * (the edits in doubt are dropped with their answers, which never left).
 *
 * Durability `replicated` (the default with --cluster) holds an edit's
 * answer until the stream has stored its record (on a stream replicated R
 * ways, a quorum of the NATS servers); `off` answers at once.
 *
 * Threads: libnats's own deliver the stream's messages and the publish
 * acknowledgements; a lease thread renews or watches the key. They hand
 * their news to the loop through a queue and an eventfd (cluster_fd); the
 * scene is only ever changed on the loop thread.
 */
#ifndef VANTAGE_CLUSTER_H
#define VANTAGE_CLUSTER_H

#include "edit.h"
#include "scene.h"

#include <pthread.h>
#include <stdbool.h>
#include <stdint.h>

typedef struct cluster_config {
    const char *urls;       /* nats://HOST:PORT[,nats://...] */
    const char *name;       /* the scene's name: [A-Za-z0-9_-], 1..48 */
    bool follow;            /* --follow: a replica at start (else a writer candidate) */
    bool wait_stored;       /* durability replicated: answers wait for the stream */
    const char *advertise;  /* the endpoint clients are redirected to when this daemon writes */
    int replicas;           /* the stream's and the lease bucket's replication (1..5) */
    uint32_t lease_ms;      /* the lease's TTL */
    uint64_t snapshot_bytes; /* the writer publishes a snapshot after this many bytes of records */
    double cell_size;       /* the scene's (a replica rebuilt from a snapshot makes its scene anew) */
    const char *ca_file;    /* --cluster-ca: PEM certificates NATS servers are verified against (TLS) */
} cluster_config;

enum { CLUSTER_REPLICA, CLUSTER_PROMOTING, CLUSTER_WRITER };

typedef struct cluster cluster;

typedef struct cluster_stats {
    int role;
    uint64_t applied;       /* stream sequence applied (replica) or published (writer) */
    uint64_t stored;        /* writer: stored by the stream (acknowledged) */
    uint64_t last;          /* the stream's last sequence as last seen */
    uint64_t records;       /* records applied or published since start */
    uint64_t lease_rev;     /* this daemon's lease revision (0: none) */
    uint64_t promotions;
    uint64_t snapshots;     /* published by this daemon */
    char writer[200];       /* the writer's endpoint ("-": none known) */
} cluster_stats;

/* Connects, makes the scene's stream and lease bucket if they are
 * missing, applies the stream to its end into sc (empty on entry), and
 * takes the lease when it is free (a writer candidate). 0, or -1 with err
 * saying why. *fresh: the stream held no record (the writer builds the
 * starting scene). */
int cluster_open(const cluster_config *cfg, scene *sc, cluster **out, bool *fresh, char *err, size_t errlen);
void cluster_close(cluster *cl);
/* The eventfd the loop watches: news from the stream or the lease. */
int cluster_fd(const cluster *cl);
/* The loop's turn: applies the records that came (under lock, taken
 * exclusively; NULL at start), counts stored acknowledgements, promotes
 * or steps down. Returns true when the scene changed. A record that
 * cannot be applied, or a writer that cannot tell what the stream holds,
 * ends the process (logged). */
bool cluster_poll(cluster *cl, scene *sc, pthread_rwlock_t *lock);
int cluster_role(const cluster *cl);
/* Whether edits are taken now; if not, err holds the NOT_WRITER message
 * (the writer's endpoint first) or a BUSY reason, and *code the error. */
bool cluster_writable(cluster *cl, int *code, char *err, size_t errlen);
/* Publishes an applied edit's record (the writer, after edit_apply).
 * Returns the stream sequence the answer waits for, or 0 when it failed
 * (the caller ends the process: the scene holds what the stream may not). */
uint64_t cluster_publish(cluster *cl, const edit *e, const uint8_t *p, uint32_t len);
/* Whether the stream has stored everything up to seq (answers wait). */
bool cluster_stored(cluster *cl, uint64_t seq);
bool cluster_waits(const cluster *cl);
/* After a writer stepped down with messages in doubt: the last stream
 * sequence known stored; answers waiting for a later one must never leave
 * (their connections are ended). UINT64_MAX: nothing to drop. */
uint64_t cluster_take_dropped(cluster *cl);
void cluster_stats_get(cluster *cl, cluster_stats *out);
const char *cluster_role_name(int role);

#endif
