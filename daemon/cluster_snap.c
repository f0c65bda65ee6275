/*
 * cluster_snap.c — the scene's snapshots on JetStream, and the stream
 * trimmed behind them (cluster.h).
 *
 * The writer, once it has published --compact-mb of records since its last
 * snapshot, forks a child that writes the scene (snapshot.h, the same
 * format as --data-dir's) into a memfd; a thread then publishes it in parts
 * on the stream VANTAGE_NAME_SNAP (subject vantage.NAME.snap), and, once
 * the journal stream has stored every record the snapshot covers, one
 * index message (subject vantage.NAME.snapidx): the stream sequence S and
 * record count it is as of, the lease it was written under, where its
 * parts begin, how many, its size and SHA-256. A snapshot without its index
 * does not exist for a reader.
 *
 * Then the journal stream is trimmed below the previous snapshot (a replica
 * up to a whole snapshot interval behind still catches up from the stream)
 * and the snapshot stream below the previous snapshot's parts (two are
 * kept).
 *
 * A daemon starting reads the newest index, fetches and checks the parts,
 * loads the snapshot and follows the journal stream from S + 1. Where the
 * journal stream still holds message S, its message id must be the
 * snapshot's lease and S: a snapshot of a history the stream does not hold
 * is refused.
 */
#include "cluster_internal.h"
#include "log.h"
#include "snapshot.h"

#include <openssl/evp.h>

#include <errno.h>
#include <inttypes.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/prctl.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

typedef struct snap_index {
    uint64_t seq, records, lease, first, parts, bytes;
    char sha[65];
} snap_index;

static void sha256_hex(const uint8_t *p, size_t n, char out[65])
{
    unsigned char d[32];
    unsigned int dl = 0;
    EVP_Digest(p, n, d, &dl, EVP_sha256(), NULL);
    for (unsigned i = 0; i < 32; i++) snprintf(out + 2 * i, 3, "%02x", d[i]);
}

static bool index_parse(const char *t, int n, snap_index *x)
{
    char buf[400];
    if (n <= 0 || n >= (int)sizeof buf) return false;
    memcpy(buf, t, (size_t)n);
    buf[n] = 0;
    int end = 0;
    return sscanf(buf,
                  "seq %" SCNu64 " records %" SCNu64 " lease %" SCNu64 " first %" SCNu64 " parts %" SCNu64
                  " bytes %" SCNu64 " sha256 %64[0-9a-f]%n",
                  &x->seq, &x->records, &x->lease, &x->first, &x->parts, &x->bytes, x->sha, &end) == 7 &&
           strlen(x->sha) == 64 && x->parts && x->parts < (1u << 24);
}

/* The newest complete snapshot's index: 1 found, 0 none, -1 error. */
static int index_latest(cluster *cl, snap_index *x, char *err, size_t errlen)
{
    natsMsg *m = NULL;
    jsErrCode jerr = 0;
    natsStatus s = js_GetLastMsg(&m, cl->js, cl->snap_stream, cl->snap_index, &cl->quick, &jerr);
    if (s == NATS_NOT_FOUND || jerr == JSNoMessageFoundErr) return 0;
    if (s != NATS_OK) {
        snprintf(err, errlen, "the snapshot index: %s (%d)", cl_nats_why(s), (int)jerr);
        return -1;
    }
    bool ok = index_parse(natsMsg_GetData(m), natsMsg_GetDataLength(m), x);
    natsMsg_Destroy(m);
    if (!ok) {
        snprintf(err, errlen, "the snapshot index on %s is not one of ours", cl->snap_stream);
        return -1;
    }
    return 1;
}

int cl_snap_probe(cluster *cl, char *err, size_t errlen)
{
    snap_index x;
    return index_latest(cl, &x, err, errlen) < 0 ? -1 : 0;
}

int cl_snap_ensure(cluster *cl, char *err, size_t errlen)
{
    jsStreamInfo *si = NULL;
    const char *subj[2] = {cl->snap_subject, cl->snap_index};
    if (cl_stream_ensure(cl, cl->snap_stream, subj, 2, 0, &si, err, errlen)) return -1;
    jsStreamInfo_Destroy(si);
    return 0;
}

int cl_snap_load(cluster *cl, scene *sc, uint64_t first, char *err, size_t errlen)
{
    snap_index x;
    int found = index_latest(cl, &x, err, errlen);
    if (found < 0) return -1;
    if (!found) {
        if (first > 1) {
            snprintf(err, errlen, "stream %s begins at message %" PRIu64 " and there is no snapshot before it",
                     cl->stream, first);
            return -1;
        }
        return 0;
    }
    if (x.seq + 1 < first) {
        snprintf(err, errlen, "the newest snapshot is as of stream message %" PRIu64 " but the stream begins at %"
                 PRIu64 ": the records between are gone", x.seq, first);
        return -1;
    }
    uint64_t t0 = (uint64_t)cl_mono_ms();
    /* the stream's own record S, while it has it, must be the one the
       snapshot's writer published */
    if (x.seq >= first && x.seq) {
        natsMsg *m = NULL;
        jsErrCode jerr = 0;
        if (js_GetMsg(&m, cl->js, cl->stream, x.seq, &cl->quick, &jerr) == NATS_OK) {
            const char *id = NULL;
            char want[48];
            snprintf(want, sizeof want, "%" PRIu64 "-%" PRIu64, x.lease, x.seq);
            bool same = natsMsgHeader_Get(m, "Nats-Msg-Id", &id) == NATS_OK && id && !strcmp(id, want);
            natsMsg_Destroy(m);
            if (!same) {
                snprintf(err, errlen, "the snapshot as of stream message %" PRIu64 " was written under lease %" PRIu64
                         ", and the stream's message %" PRIu64 " is another writer's", x.seq, x.lease, x.seq);
                return -1;
            }
        }
    }
    uint8_t *buf = malloc(x.bytes ? x.bytes : 1);
    if (!buf) {
        snprintf(err, errlen, "out of memory for a snapshot of %" PRIu64 " bytes", x.bytes);
        return -1;
    }
    size_t got = 0;
    for (uint64_t i = 0; i < x.parts; i++) {
        natsMsg *m = NULL;
        jsErrCode jerr = 0;
        natsStatus s = js_GetMsg(&m, cl->js, cl->snap_stream, x.first + i, NULL, &jerr);
        if (s != NATS_OK) {
            snprintf(err, errlen, "snapshot part %" PRIu64 " (message %" PRIu64 " of %s): %s", i + 1, x.first + i,
                     cl->snap_stream, cl_nats_why(s));
            free(buf);
            return -1;
        }
        bool ok;
        uint64_t of = cl_header_u64(m, "Vantage-Snap", &ok);
        size_t n = (size_t)natsMsg_GetDataLength(m);
        if (!ok || of != x.seq || got + n > x.bytes) {
            natsMsg_Destroy(m);
            snprintf(err, errlen, "snapshot part %" PRIu64 " (message %" PRIu64 " of %s) belongs to no snapshot as of %"
                     PRIu64, i + 1, x.first + i, cl->snap_stream, x.seq);
            free(buf);
            return -1;
        }
        memcpy(buf + got, natsMsg_GetData(m), n);
        got += n;
        natsMsg_Destroy(m);
    }
    char sha[65];
    sha256_hex(buf, got, sha);
    uint64_t next = 0;
    char why[300];
    if (got != x.bytes || strcmp(sha, x.sha)) {
        snprintf(err, errlen, "the snapshot as of stream message %" PRIu64 " is damaged (%zu of %" PRIu64
                 " bytes, SHA-256 %.16s.. where its index says %.16s..)", x.seq, got, x.bytes, sha, x.sha);
        free(buf);
        return -1;
    }
    if (snapshot_load(buf, got, sc, x.seq, &next, why, sizeof why) || next != x.records + 1) {
        snprintf(err, errlen, "the snapshot as of stream message %" PRIu64 ": %s", x.seq,
                 next != x.records + 1 ? "its record count disagrees with its index" : why);
        free(buf);
        return -1;
    }
    free(buf);
    cl_asm_reset(&cl->as, x.seq, x.records, x.lease);
    cl->snap_prev_seq = x.seq;
    cl->snap_prev_first = x.first;
    LOGI("cluster %s: snapshot as of stream message %" PRIu64 " (%" PRIu64 " records, %.1f MB) loaded in %" PRIu64
         " ms: epoch %" PRIu64, cl->name, x.seq, x.records, x.bytes / 1e6, (uint64_t)cl_mono_ms() - t0, sc->epoch);
    return 1;
}

/* ---- the writer's snapshots ------------------------------------------------------------------ */

/* The snapshot's thread: waits for the child (so an idle loop need not
 * poll it), publishes what it wrote, trims. */
static void *publisher(void *arg)
{
    cluster *cl = arg;
    struct stat st;
    uint8_t *p = NULL;
    const char *fail = NULL;
    char why[300] = "";
    int status = 0;
    pid_t r;
    while ((r = waitpid(cl->snap_child, &status, 0)) < 0 && errno == EINTR) {}
    cl->snap_child = 0; /* reaped: its pid may be another process's from now */
    if (r < 0 || !WIFEXITED(status) || WEXITSTATUS(status)) fail = "the child that writes it failed";
    else if (fstat(cl->snap_fd, &st) || !st.st_size ||
        (p = mmap(NULL, (size_t)st.st_size, PROT_READ, MAP_SHARED, cl->snap_fd, 0)) == MAP_FAILED) {
        p = NULL;
        fail = "cannot read what the child wrote";
    }
    if (p == MAP_FAILED) p = NULL;
    size_t n = p ? (size_t)st.st_size : 0;
    snap_index x = {.seq = cl->snap_seq, .records = cl->snap_recs, .lease = cl->snap_lease, .bytes = n};
    if (p) sha256_hex(p, n, x.sha);
    /* the parts */
    size_t part = (size_t)cl->max_part;
    x.parts = (n + part - 1) / part;
    for (uint64_t i = 0; !fail && i < x.parts; i++) {
        if (atomic_load(&cl->role) != CLUSTER_WRITER) {
            fail = "this daemon is no longer the writer";
            break;
        }
        natsMsg *m = NULL;
        size_t off = (size_t)i * part, len = n - off < part ? n - off : part;
        char v[32];
        snprintf(v, sizeof v, "%" PRIu64, x.seq);
        jsPubAck *pa = NULL;
        jsErrCode jerr = 0;
        natsStatus s = natsMsg_Create(&m, cl->snap_subject, NULL, (const char *)p + off, (int)len);
        if (s == NATS_OK) s = natsMsgHeader_Set(m, "Vantage-Snap", v);
        if (s == NATS_OK) s = js_PublishMsg(&pa, cl->js, m, NULL, &jerr);
        if (s == NATS_OK && !i) x.first = pa->Sequence;
        if (pa) jsPubAck_Destroy(pa);
        natsMsg_Destroy(m);
        if (s != NATS_OK) {
            snprintf(why, sizeof why, "part %" PRIu64 ": %s", i + 1, cl_nats_why(s));
            fail = why;
        }
    }
    /* the index, once the journal stream holds what the snapshot covers */
    for (int64_t until = cl_mono_ms() + 30000; !fail;) {
        pthread_mutex_lock(&cl->mu);
        bool stored = cl->acked >= x.seq, stop = cl->stop || atomic_load(&cl->role) != CLUSTER_WRITER;
        pthread_mutex_unlock(&cl->mu);
        if (stored) break;
        if (stop || cl_mono_ms() > until) fail = "the records it covers were not stored";
        else usleep(10000);
    }
    if (!fail && (atomic_load(&cl->role) != CLUSTER_WRITER || atomic_load(&cl->fenced)))
        fail = "this daemon is no longer the writer";
    if (!fail) {
        char body[400];
        int bl = snprintf(body, sizeof body,
                          "seq %" PRIu64 " records %" PRIu64 " lease %" PRIu64 " first %" PRIu64 " parts %" PRIu64
                          " bytes %" PRIu64 " sha256 %s",
                          x.seq, x.records, x.lease, x.first, x.parts, x.bytes, x.sha);
        jsPubAck *pa = NULL;
        jsErrCode jerr = 0;
        natsStatus s = js_Publish(&pa, cl->js, cl->snap_index, body, bl, NULL, &jerr);
        if (pa) jsPubAck_Destroy(pa);
        if (s != NATS_OK) {
            snprintf(why, sizeof why, "its index: %s", cl_nats_why(s));
            fail = why;
        }
    }
    if (p) munmap(p, n);
    if (fail) {
        LOGW("cluster %s: the snapshot as of stream message %" PRIu64 " was not published: %s", cl->name, x.seq,
             fail);
    } else {
        /* trimmed behind the previous snapshot: replicas up to a snapshot
           interval behind still catch up from the stream */
        jsOptions po;
        jsOptions_Init(&po);
        uint64_t trim = cl->snap_prev_seq, trim_snap = cl->snap_prev_first;
        if (trim) {
            po.Stream.Purge.Sequence = trim + 1;
            (void)js_PurgeStream(cl->js, cl->stream, &po, NULL);
        }
        if (trim_snap > 1) { /* (a purge "below 1" empties a stream: libnats 3.4 sends no sequence) */
            jsOptions_Init(&po);
            po.Stream.Purge.Sequence = trim_snap;
            (void)js_PurgeStream(cl->js, cl->snap_stream, &po, NULL);
        }
        cl->snap_prev_seq = x.seq;
        cl->snap_prev_first = x.first;
        atomic_fetch_add(&cl->snapshots, 1);
        if (trim)
            LOGI("cluster %s: snapshot as of stream message %" PRIu64 " published (%.1f MB in %" PRIu64
                 " parts); the stream trimmed below message %" PRIu64 " (the previous snapshot's)",
                 cl->name, x.seq, n / 1e6, x.parts, trim + 1);
        else
            LOGI("cluster %s: snapshot as of stream message %" PRIu64 " published (%.1f MB in %" PRIu64 " parts)",
                 cl->name, x.seq, n / 1e6, x.parts);
    }
    close(cl->snap_fd);
    cl->snap_fd = -1;
    atomic_store(&cl->snap_busy, false);
    return NULL;
}

void cl_snap_poll(cluster *cl, const scene *sc)
{
    if (atomic_load(&cl->snap_busy) || cl->since_snap < cl->snap_limit) return;
    if (atomic_load(&cl->role) != CLUSTER_WRITER || cl->as.got) return;
    int fd = memfd_create("vantage-snapshot", MFD_CLOEXEC);
    if (fd < 0) return;
    cl->snap_seq = cl->as.applied;
    cl->snap_recs = cl->as.recs;
    cl->snap_lease = cl->last_lease; /* message S's id is "LEASE-S" with the lease it was published under */
    pid_t parent = getpid();
    pid_t pid = fork();
    if (pid < 0) {
        close(fd);
        return;
    }
    if (pid == 0) {
        /* the child: the scene as of now (copy-on-write), one thread, no
           descriptor but its memfd (journal.c says why) */
        prctl(PR_SET_PDEATHSIG, SIGKILL);
        if (getppid() != parent) _exit(1);
        if (fd > 3) close_range(3, (unsigned)fd - 1, 0);
        close_range((unsigned)fd + 1, ~0u, 0);
        _exit(snapshot_write(fd, sc, cl->snap_seq, cl->snap_recs + 1) ? 1 : 0);
    }
    cl->snap_fd = fd;
    cl->snap_child = pid;
    cl->since_snap = 0;
    atomic_store(&cl->snap_busy, true);
    if (cl->snap_thr_on) pthread_join(cl->snap_thr, NULL); /* the last one's, done (not busy) */
    cl->snap_thr_on = pthread_create(&cl->snap_thr, NULL, publisher, cl) == 0;
    if (!cl->snap_thr_on) { /* no thread: the child is stopped, the snapshot dropped */
        kill(pid, SIGKILL);
        waitpid(pid, NULL, 0);
        close(fd);
        cl->snap_fd = -1;
        atomic_store(&cl->snap_busy, false);
        return;
    }
    LOGI("cluster %s: snapshot as of stream message %" PRIu64 " started (child %d)", cl->name, cl->snap_seq, (int)pid);
}

void cl_snap_stop(cluster *cl)
{
    if (atomic_load(&cl->snap_busy) && cl->snap_child) kill(cl->snap_child, SIGKILL); /* its thread reaps it */
    if (cl->snap_thr_on) pthread_join(cl->snap_thr, NULL);
    cl->snap_thr_on = false;
}

void cl_snap_refresh(cluster *cl)
{
    snap_index x;
    char err[200];
    if (index_latest(cl, &x, err, sizeof err) == 1) {
        cl->snap_prev_seq = x.seq;
        cl->snap_prev_first = x.first;
    }
}
