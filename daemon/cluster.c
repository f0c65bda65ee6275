/*
 * cluster.c — the scene shared through NATS JetStream (cluster.h).
 *
 * Names, for scene NAME: the stream VANTAGE_NAME (subject
 * vantage.NAME.journal, file storage), the KV bucket vantage-lease-NAME
 * (key "writer", value "ENDPOINT\nNODE", TTL the lease).
 *
 * A stream message is one record in the journal's format (journal.h), or,
 * when a record is larger than the servers' max_payload allows, one part
 * of it. Headers: Vantage-Lease (the writer's lease revision),
 * Vantage-Part "i/n" (parts only), and Nats-Msg-Id "LEASE-SEQ" for the
 * stream's de-duplication. The record header's sequence number counts
 * records; the stream's sequence counts messages.
 */
#include "cluster_internal.h"
#include "journal.h"
#include "log.h"

#include <nats/nats.h>

#include <errno.h>
#include <inttypes.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/eventfd.h>
#include <time.h>
#include <unistd.h>


int64_t cl_mono_ms(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (int64_t)t.tv_sec * 1000 + t.tv_nsec / 1000000;
}

uint64_t cl_mono_ns(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (uint64_t)t.tv_sec * 1000000000ull + (uint64_t)t.tv_nsec;
}

void cl_wake(cluster *cl)
{
    uint64_t one = 1;
    ssize_t ignored = write(cl->efd, &one, sizeof one);
    (void)ignored;
}

/* Whether the writer's lease may have expired: its last renewal that
 * succeeded was sent more than 80 % of the TTL ago (the key's message was
 * stored after it was sent, and expires a TTL after it was stored: no one
 * else can hold the lease before then; the rest is margin for the clocks'
 * rates). Even past it no record of ours can follow another writer's (the
 * expected last sequence): the lease decides who writes, not what the
 * stream holds. */
bool cl_lease_doubtful(cluster *cl)
{
    return cl_mono_ms() - atomic_load(&cl->renewed) > (int64_t)cl->cfg.lease_ms * 4 / 5;
}

const char *cluster_role_name(int role)
{
    return role == CLUSTER_WRITER ? "writer" : role == CLUSTER_PROMOTING ? "promoting" : "replica";
}

const char *cl_nats_why(natsStatus s)
{
    const char *t = nats_GetLastError(NULL);
    return t && *t ? t : natsStatus_GetText(s);
}

/* A fault that leaves the scene in doubt: at start it is returned, later
 * the process ends (the scene must not be served or written past it). */
bool cl_fatal(cluster *cl, const char *fmt, ...)
{
    char msg[400];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    if (cl->startup) {
        if (!cl->startup_err[0]) snprintf(cl->startup_err, sizeof cl->startup_err, "%s", msg);
        return false;
    }
    LOGE("cluster %s: %s: exiting (a restart joins the cluster again from the stream)", cl->name, msg);
    _exit(3);
}

/* ---- the stream's messages (libnats's thread -> the loop) -------------------------------- */

static void on_msg(natsConnection *nc, natsSubscription *sub, natsMsg *m, void *closure)
{
    (void)nc;
    (void)sub;
    cluster *cl = closure;
    pthread_mutex_lock(&cl->mu);
    while (!cl->draining && !cl->stop && cl->qbytes > QUEUE_BYTES) pthread_cond_wait(&cl->cv, &cl->mu);
    if (cl->draining || cl->stop) {
        pthread_mutex_unlock(&cl->mu);
        natsMsg_Destroy(m);
        return;
    }
    if (cl->qn == cl->qcap) {
        size_t cap = cl->qcap ? cl->qcap * 2 : 1024;
        natsMsg **q = malloc(cap * sizeof *q);
        if (!q) {
            pthread_mutex_unlock(&cl->mu);
            natsMsg_Destroy(m); /* the gap it leaves stops the replica, with its sequence */
            return;
        }
        for (size_t i = 0; i < cl->qn; i++) q[i] = cl->q[(cl->qhead + i) % cl->qcap];
        free(cl->q);
        cl->q = q;
        cl->qhead = 0;
        cl->qcap = cap;
    }
    cl->q[(cl->qhead + cl->qn++) % cl->qcap] = m;
    cl->qbytes += (size_t)natsMsg_GetDataLength(m) + 128;
    pthread_cond_broadcast(&cl->cv); /* cluster_open's catching up waits on it */
    pthread_mutex_unlock(&cl->mu);
    cl_wake(cl);
}

int cl_subscribe_from(cluster *cl, uint64_t seq, char *err, size_t errlen)
{
    jsSubOptions so;
    jsSubOptions_Init(&so);
    so.Stream = cl->stream;
    so.Ordered = true;
    so.Config.DeliverPolicy = js_DeliverByStartSequence;
    so.Config.OptStartSeq = seq;
    jsErrCode jerr = 0;
    pthread_mutex_lock(&cl->mu);
    cl->draining = false;
    pthread_mutex_unlock(&cl->mu);
    natsStatus s = js_Subscribe(&cl->sub, cl->js, cl->subject, on_msg, cl, NULL, &so, &jerr);
    if (s != NATS_OK) {
        snprintf(err, errlen, "cannot follow the stream %s from %" PRIu64 ": %s (%d)", cl->stream, seq, cl_nats_why(s),
                 (int)jerr);
        return -1;
    }
    natsSubscription_SetPendingLimits(cl->sub, -1, -1); /* our queue bounds it, with back-pressure */
    return 0;
}

static void *unsub_main(void *arg)
{
    natsSubscription *sub = arg;
    natsSubscription_Unsubscribe(sub); /* deletes the consumer: a JetStream request */
    natsSubscription_Destroy(sub);
    return NULL;
}

void cl_unsub_join(cluster *cl)
{
    if (cl->unsub_on) pthread_join(cl->unsub_thr, NULL);
    cl->unsub_on = false;
}

/* Stops following: what still comes is dropped, and the consumer is
 * deleted on a thread of its own (a JetStream request the loop must not
 * wait for while the servers elect a leader). */
void cl_unsubscribe(cluster *cl)
{
    if (!cl->sub) return;
    pthread_mutex_lock(&cl->mu);
    cl->draining = true;
    pthread_cond_broadcast(&cl->cv);
    pthread_mutex_unlock(&cl->mu);
    cl_unsub_join(cl);
    if (pthread_create(&cl->unsub_thr, NULL, unsub_main, cl->sub) == 0) {
        cl->unsub_on = true;
    } else {
        natsSubscription_Unsubscribe(cl->sub);
        natsSubscription_Destroy(cl->sub);
    }
    cl->sub = NULL;
}

uint64_t cl_header_u64(natsMsg *m, const char *key, bool *ok)
{
    const char *v = NULL;
    *ok = natsMsgHeader_Get(m, key, &v) == NATS_OK && v && *v;
    if (!*ok) return 0;
    char *end;
    errno = 0;
    unsigned long long x = strtoull(v, &end, 10);
    *ok = !errno && *end == 0 && v[0] != '-';
    return x;
}

/* One stream message (seq) applied to sc: a record, or a part of one.
 * false with the reason logged (cl_fatal) when it is not ours to apply. */
static bool apply_msg(cluster *cl, scene *sc, natsMsg *m, uint64_t seq)
{
    const char *lease = NULL, *part = NULL;
    natsMsgHeader_Get(m, "Vantage-Lease", &lease);
    if (natsMsgHeader_Get(m, "Vantage-Part", &part) != NATS_OK) part = NULL;
    const uint8_t *rec;
    size_t rlen;
    char why[300];
    int k = cl_asm_take(&cl->as, seq, lease, part, (const uint8_t *)natsMsg_GetData(m),
                        (size_t)natsMsg_GetDataLength(m), &rec, &rlen, why, sizeof why);
    if (k == CL_ASM_GAP && !cl->startup) {
        /* trimmed past this replica while it was behind: the loop starts
           it again from the newest snapshot (rebuild) */
        LOGW("cluster %s: stream message %" PRIu64 " came after %" PRIu64 ": the stream was trimmed past this "
             "replica", cl->name, seq, cl->as.applied);
        atomic_store(&cl->rebuild, true);
        return false;
    }
    if (k == CL_ASM_GAP)
        return cl_fatal(cl, "stream message %" PRIu64 " came after %" PRIu64 ": the stream has a gap (trimmed or "
                        "purged past this daemon)", seq, cl->as.applied);
    if (k == CL_ASM_BAD) return cl_fatal(cl, "%s", why);
    if (k == CL_ASM_PART) return true;
    scene_err se = {0};
    bool was = sc->replaying;
    sc->replaying = true; /* the writer took it: applied as it was */
    int rc = journal_rec_apply(sc, rec, 2, &se);
    sc->replaying = was;
    if (rc)
        return cl_fatal(cl, "stream message %" PRIu64 " (record %" PRIu64 ") cannot be applied: %s", seq, cl->as.recs,
                        se.msg);
    return true;
}

/* Applies what the queue holds, for at most a turn's time (all at start). */
bool cl_apply_queue(cluster *cl, scene *sc, pthread_rwlock_t *lock, bool *more)
{
    uint64_t t0 = cl_mono_ns();
    bool changed = false;
    *more = false;
    if (lock) pthread_rwlock_wrlock(lock);
    for (;;) {
        pthread_mutex_lock(&cl->mu);
        natsMsg *m = NULL;
        if (cl->qn) {
            m = cl->q[cl->qhead];
            cl->qhead = (cl->qhead + 1) % cl->qcap;
            cl->qn--;
            cl->qbytes -= (size_t)natsMsg_GetDataLength(m) + 128;
            pthread_cond_broadcast(&cl->cv);
        }
        pthread_mutex_unlock(&cl->mu);
        if (!m) break;
        jsMsgMetaData *meta = NULL;
        natsStatus s = natsMsg_GetMetaData(&meta, m);
        bool ok = s == NATS_OK;
        if (!ok) cl_fatal(cl, "a stream message after %" PRIu64 " without JetStream metadata: %s", cl->as.applied,
                       natsStatus_GetText(s));
        else ok = apply_msg(cl, sc, m, meta->Sequence.Stream);
        if (meta) {
            if (meta->NumPending + meta->Sequence.Stream > cl->last_seen)
                cl->last_seen = meta->NumPending + meta->Sequence.Stream;
            jsMsgMetaData_Destroy(meta);
        }
        natsMsg_Destroy(m);
        if (!ok) break;
        changed = true;
        if (lock && cl_mono_ns() - t0 > TURN_NS) {
            *more = true;
            break;
        }
    }
    if (changed && !sc->unloading) cull_world_commit(sc->world);
    if (lock) pthread_rwlock_unlock(lock);
    return changed;
}

/* ---- the writer's publishing ------------------------------------------------------------ */

void cl_on_ack(jsCtx *js, natsMsg *m, jsPubAck *pa, jsPubAckErr *pae, void *closure)
{
    (void)js;
    cluster *cl = closure;
    bool ok;
    uint64_t seq = cl_header_u64(m, "Vantage-Seq", &ok);
    pthread_mutex_lock(&cl->mu);
    if (pa && !pae) {
        if (pa->Sequence > cl->acked) cl->acked = pa->Sequence;
    } else if (pae && ok && (!cl->fail_seq || seq < cl->fail_seq)) {
        cl->fail_seq = seq;
        snprintf(cl->fail, sizeof cl->fail, "%s (JetStream error %d)",
                 pae->ErrText && *pae->ErrText ? pae->ErrText : natsStatus_GetText(pae->Err), (int)pae->ErrCode);
    }
    pthread_mutex_unlock(&cl->mu);
    natsMsg_Destroy(m);
    cl_wake(cl);
}

static natsMsg *make_msg(cluster *cl, const pend_msg *p, uint64_t lease)
{
    natsMsg *m = NULL;
    if (natsMsg_Create(&m, cl->subject, NULL, (const char *)p->data, (int)p->len) != NATS_OK) return NULL;
    char v[32];
    snprintf(v, sizeof v, "%" PRIu64, lease);
    natsMsgHeader_Set(m, "Vantage-Lease", v);
    snprintf(v, sizeof v, "%" PRIu64, p->seq);
    natsMsgHeader_Set(m, "Vantage-Seq", v);
    if (p->part[0]) natsMsgHeader_Set(m, "Vantage-Part", p->part);
    return m;
}

static void pub_opts(cluster *cl, const pend_msg *p, uint64_t lease, jsPubOptions *po, char *id, size_t idlen)
{
    jsPubOptions_Init(po);
    snprintf(id, idlen, "%" PRIu64 "-%" PRIu64, lease, p->seq);
    po->MsgId = id;
    po->ExpectStream = cl->stream;
    if (p->seq > 1) po->ExpectLastSeq = p->seq - 1;
    else po->ExpectNoMessage = true;
}

static void pend_pop_stored(cluster *cl, uint64_t acked)
{
    while (cl->pn && cl->pend[cl->phead].seq <= acked) {
        pend_msg *p = &cl->pend[cl->phead];
        cl->pbytes -= p->len;
        free(p->data);
        cl->phead = (cl->phead + 1) % cl->pcap;
        cl->pn--;
    }
}

uint64_t cluster_publish(cluster *cl, const edit *e, const uint8_t *p, uint32_t len)
{
    if (atomic_load(&cl->role) != CLUSTER_WRITER) return 0;
    size_t rlen = JOURNAL_REC_HDR + (size_t)len;
    uint8_t *rec = malloc(rlen);
    if (!rec) return 0;
    journal_rec_header(rec, cl->as.recs + 1, e->type, e->sublevel, e->aux, p, len);
    if (len) memcpy(rec + JOURNAL_REC_HDR, p, len);
    uint32_t parts = (uint32_t)((rlen + (size_t)cl->max_part - 1) / (size_t)cl->max_part);
    pthread_mutex_lock(&cl->mu);
    uint64_t lease = cl->lease_rev;
    pthread_mutex_unlock(&cl->mu);
    for (uint32_t i = 0; i < parts; i++) {
        if (cl->pn == cl->pcap) {
            size_t cap = cl->pcap ? cl->pcap * 2 : 256;
            pend_msg *q = malloc(cap * sizeof *q);
            if (!q) {
                free(rec);
                return 0;
            }
            for (size_t k = 0; k < cl->pn; k++) q[k] = cl->pend[(cl->phead + k) % cl->pcap];
            free(cl->pend);
            cl->pend = q;
            cl->phead = 0;
            cl->pcap = cap;
        }
        size_t off = (size_t)i * (size_t)cl->max_part, n = rlen - off < (size_t)cl->max_part ? rlen - off : (size_t)cl->max_part;
        pend_msg pm = {.seq = cl->as.applied + 1, .lease = lease, .len = (uint32_t)n};
        if (parts > 1) snprintf(pm.part, sizeof pm.part, "%u/%u", i + 1, parts);
        pm.data = malloc(n ? n : 1);
        if (!pm.data) {
            free(rec);
            return 0;
        }
        memcpy(pm.data, rec + off, n);
        natsMsg *m = make_msg(cl, &pm, lease);
        jsPubOptions po;
        char id[48];
        pub_opts(cl, &pm, lease, &po, id, sizeof id);
        natsStatus s = m ? js_PublishMsgAsync(cl->js, &m, &po) : NATS_NO_MEMORY;
        if (m) natsMsg_Destroy(m);
        if (s != NATS_OK) {
            LOGE("cluster %s: record %" PRIu64 " could not be published: %s", cl->name, cl->as.recs + 1, cl_nats_why(s));
            free(pm.data);
            free(rec);
            return 0;
        }
        cl->pend[(cl->phead + cl->pn++) % cl->pcap] = pm;
        cl->pbytes += n;
        cl->as.applied++;
    }
    free(rec);
    cl->as.recs++;
    cl->since_snap += rlen;
    cl->last_lease = lease;
    return cl->as.applied;
}

/* A publish failed, or its answer was lost: finds out what the stream
 * holds of the unstored messages (the ones it has are ours: their message
 * ids say so) and publishes the rest again, in order. Blocks the loop
 * (the writer takes no edit meanwhile); gives up, stepping down
 * (cl->step_down), when the lease is in doubt or another writer's record is
 * in the way. */
static void recover(cluster *cl, const char *what)
{
    LOGW("cluster %s: %s: checking what the stream holds", cl->name, what);
    jsPubOptions wait;
    jsPubOptions_Init(&wait);
    wait.MaxWait = cl->cfg.lease_ms;
    (void)js_PublishAsyncComplete(cl->js, &wait);
    for (;;) {
        if (atomic_load(&cl->fenced) || cl_lease_doubtful(cl)) {
            LOGW("cluster %s: the lease was lost with %zu messages not known to be stored", cl->name, cl->pn);
            cl->step_down = true;
            return;
        }
        pthread_mutex_lock(&cl->mu);
        uint64_t acked = cl->acked;
        cl->fail_seq = 0;
        pthread_mutex_unlock(&cl->mu);
        pend_pop_stored(cl, acked);
        if (!cl->pn) break;
        jsStreamInfo *si = NULL;
        jsErrCode jerr = 0;
        natsStatus s = js_GetStreamInfo(&si, cl->js, cl->stream, &cl->quick, &jerr);
        if (s != NATS_OK) {
            LOGW("cluster %s: stream info: %s; trying again", cl->name, cl_nats_why(s));
            usleep(100000);
            continue;
        }
        uint64_t last = si->State.LastSeq;
        jsStreamInfo_Destroy(si);
        bool retry = false;
        while (cl->pn && !retry) {
            pend_msg *p = &cl->pend[cl->phead];
            char id[48];
            jsPubOptions po;
            pub_opts(cl, p, p->lease, &po, id, sizeof id); /* the same id: stored once */
            if (p->seq <= last) {
                natsMsg *got = NULL;
                s = js_GetMsg(&got, cl->js, cl->stream, p->seq, &cl->quick, &jerr);
                if (s != NATS_OK) {
                    retry = true;
                    break;
                }
                const char *gid = NULL;
                bool ours = natsMsgHeader_Get(got, "Nats-Msg-Id", &gid) == NATS_OK && gid && !strcmp(gid, id);
                natsMsg_Destroy(got);
                if (!ours) {
                    LOGW("cluster %s: stream message %" PRIu64 " is another writer's (ours would be %s)", cl->name,
                         p->seq, id);
                    cl->step_down = true;
                    return;
                }
            } else {
                natsMsg *m = make_msg(cl, p, p->lease);
                jsPubAck *pa = NULL;
                s = m ? js_PublishMsg(&pa, cl->js, m, &po, &jerr) : NATS_NO_MEMORY;
                if (m) natsMsg_Destroy(m);
                if (pa) jsPubAck_Destroy(pa);
                if (s != NATS_OK) {
                    if (jerr == JSStreamWrongLastSequenceErr) {
                        retry = true; /* stored after all, or someone else's: the next round reads it back */
                        last = p->seq - 1;
                    } else {
                        LOGW("cluster %s: stream message %" PRIu64 " again: %s (%d)", cl->name, p->seq, cl_nats_why(s),
                             (int)jerr);
                        usleep(100000);
                        retry = true;
                    }
                    break;
                }
            }
            pthread_mutex_lock(&cl->mu);
            if (p->seq > cl->acked) cl->acked = p->seq;
            pthread_mutex_unlock(&cl->mu);
            pend_pop_stored(cl, p->seq);
        }
    }
    LOGI("cluster %s: the stream holds every record up to %" PRIu64, cl->name, cl->as.applied);
}

/* ---- the lease ----------------------------------------------------------------------------- */

void cl_lease_writer_seen(cluster *cl, kvEntry *e)
{
    const char *v = kvEntry_Value(e);
    int n = kvEntry_ValueLen(e);
    int k = 0;
    while (k < n && v[k] != '\n') k++;
    pthread_mutex_lock(&cl->mu);
    snprintf(cl->writer, sizeof cl->writer, "%.*s", k, v);
    pthread_mutex_unlock(&cl->mu);
}

void *cl_lease_main(void *arg)
{
    cluster *cl = arg;
    for (;;) {
        pthread_mutex_lock(&cl->mu);
        struct timespec until;
        clock_gettime(CLOCK_REALTIME, &until);
        int64_t ns = until.tv_nsec + (int64_t)(cl->cfg.lease_ms / 5) * 1000000;
        until.tv_sec += ns / 1000000000;
        until.tv_nsec = ns % 1000000000;
        if (!cl->stop) pthread_cond_timedwait(&cl->cv, &cl->mu, &until);
        bool stop = cl->stop;
        uint64_t rev = cl->lease_rev;
        pthread_mutex_unlock(&cl->mu);
        if (stop) break;
        int role = atomic_load(&cl->role);
        if (role != CLUSTER_REPLICA && !atomic_load(&cl->fenced)) {
            int64_t sent = cl_mono_ms();
            uint64_t nrev = 0;
            natsStatus s = kvStore_Update(&nrev, cl->kv, "writer", cl->value, (int)strlen(cl->value), rev);
            if (s == NATS_OK) {
                atomic_store(&cl->renewed, sent);
                pthread_mutex_lock(&cl->mu);
                cl->lease_rev = nrev;
                pthread_mutex_unlock(&cl->mu);
                continue;
            }
            /* another revision: someone took it; else in doubt once half the TTL is gone */
            const char *why = cl_nats_why(s);
            bool taken = strstr(why, "wrong last sequence") != NULL;
            if (taken || cl_lease_doubtful(cl)) {
                atomic_store(&cl->fenced, true);
                pthread_mutex_lock(&cl->mu);
                cl->news_lost = 1;
                pthread_mutex_unlock(&cl->mu);
                LOGW("cluster %s: the lease is lost (%s): no more edits here", cl->name,
                     taken ? "another daemon holds it" : why);
                cl_wake(cl);
            }
            continue;
        }
        if (role != CLUSTER_REPLICA) continue;
        if (atomic_load(&cl->rebuild)) { /* the loop tries again; no lease for a scene being rebuilt */
            cl_wake(cl);
            continue;
        }
        kvEntry *e = NULL;
        natsStatus s = kvStore_Get(&e, cl->kv, "writer");
        if (s == NATS_OK) {
            cl_lease_writer_seen(cl, e);
            kvEntry_Destroy(e);
            continue;
        }
        if (s != NATS_NOT_FOUND) continue;
        pthread_mutex_lock(&cl->mu);
        snprintf(cl->writer, sizeof cl->writer, "-");
        pthread_mutex_unlock(&cl->mu);
        /* a follower leaves a starting writer time to take it first */
        if (cl->cfg.follow && cl_mono_ms() - (int64_t)cl->started_ms < 2 * (int64_t)cl->cfg.lease_ms) continue;
        int64_t sent = cl_mono_ms();
        uint64_t nrev = 0;
        if (kvStore_Create(&nrev, cl->kv, "writer", cl->value, (int)strlen(cl->value)) != NATS_OK) continue;
        atomic_store(&cl->renewed, sent);
        atomic_store(&cl->fenced, false);
        pthread_mutex_lock(&cl->mu);
        cl->lease_rev = nrev;
        cl->news_won = 1;
        pthread_mutex_unlock(&cl->mu);
        atomic_store(&cl->role, CLUSTER_PROMOTING);
        LOGI("cluster %s: this daemon took the lease (revision %" PRIu64 ")", cl->name, nrev);
        cl_wake(cl);
    }
    return NULL;
}

/* Becomes the writer: the stream applied to its very end first. */
bool cl_promote(cluster *cl, scene *sc, pthread_rwlock_t *lock)
{
    cl_unsubscribe(cl);
    bool more;
    cl_apply_queue(cl, sc, lock, &more);
    while (cl_apply_queue(cl, sc, lock, &more) || more) {}
    int64_t give_up = cl_mono_ms() + 10000;
    for (;;) {
        jsStreamInfo *si = NULL;
        jsErrCode jerr = 0;
        natsStatus s = js_GetStreamInfo(&si, cl->js, cl->stream, &cl->quick, &jerr);
        if (s != NATS_OK) {
            if (cl_mono_ms() > give_up) return cl_fatal(cl, "cannot read the stream's end to take over: %s", cl_nats_why(s));
            usleep(100000);
            continue;
        }
        uint64_t last = si->State.LastSeq;
        jsStreamInfo_Destroy(si);
        if (lock) pthread_rwlock_wrlock(lock);
        bool ok = true;
        while (ok && cl->as.applied < last) {
            natsMsg *m = NULL;
            s = js_GetMsg(&m, cl->js, cl->stream, cl->as.applied + 1, &cl->quick, &jerr);
            if (s != NATS_OK) {
                ok = false;
                break;
            }
            ok = apply_msg(cl, sc, m, cl->as.applied + 1);
            natsMsg_Destroy(m);
        }
        if (!sc->unloading) cull_world_commit(sc->world);
        if (lock) pthread_rwlock_unlock(lock);
        if (ok) {
            cl->last_seen = last;
            break;
        }
        if (cl_mono_ms() > give_up) return cl_fatal(cl, "cannot read the stream's end to take over");
        usleep(100000);
    }
    if (cl->as.got) return cl_fatal(cl, "the last writer left record %" PRIu64 " in parts", cl->as.recs + 1);
    pthread_mutex_lock(&cl->mu);
    cl->acked = cl->as.applied;
    pthread_mutex_unlock(&cl->mu);
    cl_snap_refresh(cl);
    cl->last_lease = cl->as.max_lease; /* the last message's, until this writer publishes */
    atomic_store(&cl->role, CLUSTER_WRITER);
    cl->promotions++;
    /* loads the last writer's editors left open: their connections are
       gone, so they go as a dropped connection's would (as recovery drops
       them), published like any change */
    if (lock) pthread_rwlock_wrlock(lock);
    for (uint32_t id = 1; id <= sc->nsublevels; id++) {
        if (sc->sl[id].state != VP_SL_LOADING) continue;
        edit e = {.type = VP_SUBLEVEL_ABORT, .sublevel = (uint16_t)id};
        edit_result res;
        scene_err se;
        if (edit_apply(sc, &e, &res, &se)) {
            if (lock) pthread_rwlock_unlock(lock);
            return cl_fatal(cl, "cannot drop sub-level %s, left loading by the last writer: %s", sc->sl[id].name,
                            se.msg);
        }
        edit_result_free(&res);
        if (!cluster_publish(cl, &e, NULL, 0)) {
            if (lock) pthread_rwlock_unlock(lock);
            return cl_fatal(cl, "cannot publish the drop of sub-level %s", sc->sl[id].name);
        }
        LOGI("cluster %s: sub-level %s, left loading by the last writer, dropped", cl->name, sc->sl[id].name);
    }
    if (lock) pthread_rwlock_unlock(lock);
    LOGI("cluster %s: writing from stream message %" PRIu64 " (record %" PRIu64 ", epoch %" PRIu64 ")", cl->name,
         cl->as.applied, cl->as.recs, sc->epoch);
    return true;
}

/* ---- the loop's side ------------------------------------------------------------------------ */

/* A replica the stream was trimmed past: its scene made anew from the
 * newest snapshot, under the scene's lock (queries and frames wait), and
 * followed again from there. Texture generations go on from the old
 * scene's, so no renderer cache takes a new texture for an old one (the
 * culling world's occlusion versions are unique per world already). */
static bool rebuild(cluster *cl, scene *sc, pthread_rwlock_t *lock)
{
    cl_unsubscribe(cl);
    pthread_mutex_lock(&cl->mu);
    for (; cl->qn; cl->qn--, cl->qhead = (cl->qhead + 1) % cl->qcap) natsMsg_Destroy(cl->q[cl->qhead]);
    cl->qbytes = 0;
    pthread_cond_broadcast(&cl->cv);
    pthread_mutex_unlock(&cl->mu);
    jsStreamInfo *si = NULL;
    jsErrCode jerr = 0;
    natsStatus s = js_GetStreamInfo(&si, cl->js, cl->stream, &cl->quick, &jerr);
    if (s != NATS_OK) { /* the next turn tries again (the lease thread wakes the loop) */
        if (!cl->rebuild_said)
            LOGW("cluster %s: waiting for the stream to start again from it: %s", cl->name, cl_nats_why(s));
        cl->rebuild_said = true;
        atomic_store(&cl->rebuild, true);
        return false;
    }
    uint64_t first = si->State.FirstSeq;
    jsStreamInfo_Destroy(si);
    /* and the snapshots, before the scene is let go: a daemon whose NATS
       server is coming back waits for them as for the stream (it used to
       exit when the index timed out right after the stream answered) */
    char perr[300];
    if (cl_snap_probe(cl, perr, sizeof perr) < 0 && strstr(perr, "snapshot index:")) {
        if (!cl->rebuild_said) LOGW("cluster %s: waiting for the snapshots to start again from: %s", cl->name, perr);
        cl->rebuild_said = true;
        atomic_store(&cl->rebuild, true);
        return false;
    }
    atomic_store(&cl->rebuild, false);
    cl->rebuild_said = false;
    int64_t t0 = cl_mono_ms();
    if (lock) pthread_rwlock_wrlock(lock);
    uint32_t gens = sc->texture_gens;
    scene_limits lim = sc->lim;
    uint64_t was = sc->epoch;
    scene_free(sc);
    if (scene_init(sc, cl->cfg.cell_size, &lim)) cl_fatal(cl, "out of memory for the scene");
    sc->texture_gens = gens + 1;
    cl_asm_reset(&cl->as, 0, 0, 0);
    char err[500];
    if (cl_snap_load(cl, sc, first, err, sizeof err) < 0) cl_fatal(cl, "starting again from a snapshot: %s", err);
    cull_world_commit(sc->world);
    if (lock) pthread_rwlock_unlock(lock);
    for (int tries = 0; cl_subscribe_from(cl, cl->as.applied + 1, err, sizeof err); tries++) {
        if (tries == 40) cl_fatal(cl, "%s", err);
        usleep(250000);
    }
    LOGW("cluster %s: started again from %s %" PRIu64 " in %" PRIu64 " ms (epoch %" PRIu64 " -> %" PRIu64 ")",
         cl->name, cl->as.applied ? "the snapshot as of stream message" : "the stream's start, message", cl->as.applied + !cl->as.applied,
         (uint64_t)(cl_mono_ms() - t0), was, sc->epoch);
    return true;
}

bool cluster_poll(cluster *cl, scene *sc, pthread_rwlock_t *lock)
{
    uint64_t drained;
    ssize_t r = read(cl->efd, &drained, sizeof drained);
    (void)r;
    pthread_mutex_lock(&cl->mu);
    int won = cl->news_won, lost = cl->news_lost;
    cl->news_won = cl->news_lost = 0;
    uint64_t acked = cl->acked, fail_seq = cl->fail_seq;
    char fail[240];
    snprintf(fail, sizeof fail, "%s", cl->fail);
    pthread_mutex_unlock(&cl->mu);
    bool changed = false, more = false;
    int role = atomic_load(&cl->role);
    if (role != CLUSTER_WRITER) changed = cl_apply_queue(cl, sc, lock, &more);
    if (atomic_load(&cl->rebuild) && rebuild(cl, sc, lock)) {
        changed = true;
        more = true;
    }
    if (won && atomic_load(&cl->role) == CLUSTER_PROMOTING) {
        cl_promote(cl, sc, lock);
        changed = true;
    }
    if (atomic_load(&cl->role) == CLUSTER_WRITER) {
        pend_pop_stored(cl, acked);
        cl_snap_poll(cl, sc);
        if (fail_seq) {
            char what[320];
            snprintf(what, sizeof what, "stream message %" PRIu64 " was not stored: %s", fail_seq, fail);
            recover(cl, what);
        }
        if (lost && cl->pn) {
            LOGW("cluster %s: the lease was lost with %zu messages not yet stored", cl->name, cl->pn);
            cl->step_down = true;
        }
        if (cl->step_down) {
            /* a replica again, rebuilt from what the stream holds: the
               answers still waiting for a message above the last one
               stored never leave (the server ends their connections: their
               edits may or may not be in the stream) */
            cl->step_down = false;
            pthread_mutex_lock(&cl->mu);
            uint64_t stored = cl->acked;
            pthread_mutex_unlock(&cl->mu);
            cl->dropped_above = stored;
            LOGW("cluster %s: stepping down: %zu messages after stream message %" PRIu64 " not known to be stored; "
                 "this daemon's scene is rebuilt from the stream", cl->name, cl->pn, stored);
            atomic_store(&cl->role, CLUSTER_REPLICA); /* first: a snapshot being published stops */
            cl_snap_stop(cl);
            pend_pop_stored(cl, UINT64_MAX);
            atomic_store(&cl->rebuild, true);
            changed = rebuild(cl, sc, lock) || changed;
            lost = false;
        }
        if (lost) {
            atomic_store(&cl->role, CLUSTER_REPLICA);
            char err[300];
            for (int tries = 0; cl_subscribe_from(cl, cl->as.applied + 1, err, sizeof err); tries++) {
                if (tries == 20) cl_fatal(cl, "%s", err);
                usleep(250000);
            }
            LOGW("cluster %s: now a replica, from stream message %" PRIu64, cl->name, cl->as.applied + 1);
        }
    }
    if (more) cl_wake(cl);
    return changed;
}

uint64_t cluster_take_dropped(cluster *cl)
{
    uint64_t d = cl->dropped_above;
    cl->dropped_above = UINT64_MAX;
    return d;
}

bool cluster_writable(cluster *cl, int *code, char *err, size_t errlen)
{
    int role = atomic_load(&cl->role);
    if (role == CLUSTER_WRITER && !atomic_load(&cl->fenced) && !cl_lease_doubtful(cl)) {
        if (cl->pn < UNSTORED_MSGS && cl->pbytes < UNSTORED_BYTES) return true;
        *code = VP_ERR_BUSY;
        snprintf(err, errlen, "the stream has not stored the last %zu edits (%.1f MB): retry", cl->pn,
                 cl->pbytes / 1e6);
        return false;
    }
    *code = VP_ERR_NOT_WRITER;
    pthread_mutex_lock(&cl->mu);
    snprintf(err, errlen, "%s %s", role == CLUSTER_REPLICA && cl->writer[0] ? cl->writer : "-",
             role == CLUSTER_REPLICA ? "is the writer of this scene; this daemon is a replica"
                                     : "this daemon is changing roles: retry");
    pthread_mutex_unlock(&cl->mu);
    return false;
}

bool cluster_stored(cluster *cl, uint64_t seq)
{
    pthread_mutex_lock(&cl->mu);
    bool ok = cl->acked >= seq;
    pthread_mutex_unlock(&cl->mu);
    return ok;
}

bool cluster_waits(const cluster *cl) { return cl->cfg.wait_stored; }
int cluster_role(const cluster *cl) { return atomic_load(&cl->role); }
int cluster_fd(const cluster *cl) { return cl->efd; }

void cluster_stats_get(cluster *cl, cluster_stats *o)
{
    memset(o, 0, sizeof *o);
    o->role = atomic_load(&cl->role);
    o->applied = cl->as.applied;
    o->records = cl->as.recs;
    o->promotions = cl->promotions;
    o->snapshots = atomic_load(&cl->snapshots);
    pthread_mutex_lock(&cl->mu);
    o->stored = cl->acked;
    o->lease_rev = o->role == CLUSTER_REPLICA ? 0 : cl->lease_rev;
    snprintf(o->writer, sizeof o->writer, "%s", o->role == CLUSTER_WRITER ? cl->cfg.advertise : cl->writer);
    pthread_mutex_unlock(&cl->mu);
    o->last = cl->last_seen > cl->as.applied ? cl->last_seen : cl->as.applied;
}

