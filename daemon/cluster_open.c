/*
 * cluster_open.c — joining a cluster (cluster.h): the NATS connection, the
 * scene's streams and lease bucket made when missing, the scene caught up
 * from the stream, the lease taken when free; and leaving it.
 */
#include "cluster_internal.h"
#include "log.h"

#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/eventfd.h>
#include <time.h>
#include <unistd.h>

/* ---- open / close ---------------------------------------------------------------------------- */

static bool name_ok(const char *n)
{
    size_t k = 0;
    for (; n[k]; k++)
        if (!((n[k] >= 'a' && n[k] <= 'z') || (n[k] >= 'A' && n[k] <= 'Z') || (n[k] >= '0' && n[k] <= '9') ||
              n[k] == '_' || n[k] == '-'))
            return false;
    return k >= 1 && k <= 48;
}

/* The URLs as logs may show them: a password ("nats://USER:PASSWORD@")
 * replaced by "***". */
static const char *redacted(const char *urls, char *out, size_t outlen)
{
    size_t o = 0;
    for (const char *p = urls; *p && o + 4 < outlen;) {
        const char *end = strchr(p, ','), *at = NULL, *colon = NULL, *scheme = strstr(p, "://");
        if (!end) end = p + strlen(p);
        const char *host = scheme && scheme < end ? scheme + 3 : p;
        for (const char *q = host; q < end; q++) {
            if (*q == '@') at = q;
            if (*q == ':' && !at && !colon) colon = q;
        }
        for (const char *q = p; q < end && o + 4 < outlen; q++) {
            if (at && colon && colon < at && q > colon && q < at) {
                if (q == colon + 1) o += (size_t)snprintf(out + o, outlen - o, "***");
                continue;
            }
            out[o++] = *q;
        }
        if (*end == ',' && o + 4 < outlen) out[o++] = ',';
        p = *end ? end + 1 : end;
    }
    out[o] = 0;
    return out;
}

static int connect_nats(cluster *cl, char *err, size_t errlen)
{
    char *urls = strdup(cl->cfg.urls);
    const char *list[32];
    int n = 0;
    for (char *sv, *t = urls ? strtok_r(urls, ",", &sv) : NULL; t && n < 32; t = strtok_r(NULL, ",", &sv))
        list[n++] = t;
    natsStatus s = n ? natsOptions_Create(&cl->opts) : NATS_INVALID_ARG;
    if (s == NATS_OK) s = natsOptions_SetServers(cl->opts, list, n);
    if (s == NATS_OK) s = natsOptions_SetName(cl->opts, cl->node);
    if (s == NATS_OK) s = natsOptions_SetMaxReconnect(cl->opts, -1);
    if (s == NATS_OK) s = natsOptions_SetReconnectWait(cl->opts, 100);
    if (s == NATS_OK) s = natsOptions_SetTimeout(cl->opts, 2000);
    if (s == NATS_OK) s = natsOptions_SetReconnectBufSize(cl->opts, 64 << 20);
    /* TLS: the servers verified against these CAs (a tls:// URL, or a
       server that requires TLS, uses them) */
    if (s == NATS_OK && cl->cfg.ca_file) {
        s = natsOptions_LoadCATrustedCertificates(cl->opts, cl->cfg.ca_file);
        if (s == NATS_OK) s = natsOptions_SetSecure(cl->opts, true);
        if (s != NATS_OK) {
            snprintf(err, errlen, "--cluster-ca %s: %s", cl->cfg.ca_file, cl_nats_why(s));
            free(urls);
            return -1;
        }
    }
    if (s == NATS_OK) s = natsConnection_Connect(&cl->nc, cl->opts);
    free(urls);
    if (s != NATS_OK) {
        char shown[512];
        snprintf(err, errlen, "cannot reach NATS at %s: %s", redacted(cl->cfg.urls, shown, sizeof shown),
                 cl_nats_why(s));
        return -1;
    }
    jsOptions_Init(&cl->quick);
    cl->quick.Wait = 1000;
    jsOptions jo;
    jsOptions_Init(&jo);
    jo.Wait = 5000;
    jo.PublishAsync.AckHandler = cl_on_ack;
    jo.PublishAsync.AckHandlerClosure = cl;
    jo.PublishAsync.MaxPending = UNSTORED_MSGS * 2;
    s = natsConnection_JetStream(&cl->js, cl->nc, &jo);
    if (s != NATS_OK) {
        snprintf(err, errlen, "JetStream: %s", cl_nats_why(s));
        return -1;
    }
    jsOptions_Init(&jo);
    jo.Wait = cl->cfg.lease_ms / 4;
    if ((s = natsConnection_JetStream(&cl->jskv, cl->nc, &jo)) != NATS_OK) {
        snprintf(err, errlen, "JetStream: %s", cl_nats_why(s));
        return -1;
    }
    int64_t mp = natsConnection_GetMaxPayload(cl->nc);
    cl->max_part = mp > 4096 ? mp - 1024 : 4096; /* the headers ride in the same payload */
    return 0;
}

/* Stream name with these subjects, made (file storage, the cluster's
 * replication; dup_ns: the de-duplication window, 0 = JetStream's) when
 * missing, by this daemon or another one first. Its info in *out, or -1. */
int cl_stream_ensure(cluster *cl, const char *name, const char **subjects, int nsubjects, int64_t dup_ns,
                     jsStreamInfo **out, char *err, size_t errlen)
{
    jsStreamInfo *si = NULL;
    jsErrCode jerr = 0;
    natsStatus s = js_GetStreamInfo(&si, cl->js, name, NULL, &jerr);
    if (s == NATS_NOT_FOUND || jerr == JSStreamNotFoundErr) {
        jsStreamConfig sc;
        jsStreamConfig_Init(&sc);
        sc.Name = name;
        sc.Subjects = subjects;
        sc.SubjectsLen = nsubjects;
        sc.Storage = js_FileStorage;
        sc.Replicas = cl->cfg.replicas;
        sc.Duplicates = dup_ns;
        sc.AllowDirect = true;
        jerr = 0;
        s = js_AddStream(&si, cl->js, &sc, NULL, &jerr);
        if (s == NATS_OK) LOGI("cluster %s: stream %s made, replicated %d ways", cl->name, name, cl->cfg.replicas);
        else {
            /* another daemon made it first, or it cannot be made (say,
               more replicas than servers): then that is the reason */
            char why[300];
            snprintf(why, sizeof why, "%s (%d)", cl_nats_why(s), (int)jerr);
            jerr = 0;
            s = js_GetStreamInfo(&si, cl->js, name, NULL, &jerr);
            if (s != NATS_OK) {
                snprintf(err, errlen, "stream %s (replicated %d ways) cannot be made: %s", name, cl->cfg.replicas, why);
                return -1;
            }
        }
    }
    if (s != NATS_OK) {
        snprintf(err, errlen, "stream %s: %s (%d)", name, cl_nats_why(s), (int)jerr);
        return -1;
    }
    *out = si;
    return 0;
}

static int ensure_stream(cluster *cl, uint64_t *first, uint64_t *last, char *err, size_t errlen)
{
    jsStreamInfo *si = NULL;
    const char *subj[1] = {cl->subject};
    /* a retried publish within 2 minutes is stored once */
    if (cl_stream_ensure(cl, cl->stream, subj, 1, (int64_t)120 * 1000000000, &si, err, errlen)) return -1;
    *first = si->State.FirstSeq;
    *last = si->State.LastSeq;
    jsStreamInfo_Destroy(si);
    if (cl_snap_ensure(cl, err, errlen)) return -1;
    natsStatus s = cl->kv ? NATS_OK : js_KeyValue(&cl->kv, cl->jskv, cl->bucket);
    if (s != NATS_OK) {
        kvConfig kc;
        kvConfig_Init(&kc);
        kc.Bucket = cl->bucket;
        kc.History = 1;
        kc.TTL = (int64_t)cl->cfg.lease_ms * 1000000; /* nanoseconds (libnats 3.4) */
        kc.StorageType = js_FileStorage;
        kc.Replicas = cl->cfg.replicas;
        s = js_CreateKeyValue(&cl->kv, cl->jskv, &kc);
        if (s != NATS_OK) {
            char why[200];
            snprintf(why, sizeof why, "%s", cl_nats_why(s));
            s = js_KeyValue(&cl->kv, cl->jskv, cl->bucket); /* another daemon made it first? */
            if (s != NATS_OK) {
                snprintf(err, errlen, "lease bucket %s cannot be made: %s", cl->bucket, why);
                return -1;
            }
        }
    }
    if (s != NATS_OK) {
        snprintf(err, errlen, "lease bucket %s: %s", cl->bucket, cl_nats_why(s));
        return -1;
    }
    return 0;
}

int cluster_open(const cluster_config *cfg, scene *sc, cluster **out, bool *fresh, char *err, size_t errlen)
{
    *out = NULL;
    *fresh = false;
    if (!name_ok(cfg->name)) {
        snprintf(err, errlen, "scene name \"%.60s\": use 1 to 48 letters, digits, '_' or '-'", cfg->name);
        return -1;
    }
    cluster *cl = calloc(1, sizeof *cl);
    if (!cl) {
        snprintf(err, errlen, "out of memory");
        return -1;
    }
    cl->cfg = *cfg;
    cl->efd = eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
    pthread_mutex_init(&cl->mu, NULL);
    pthread_cond_init(&cl->cv, NULL);
    snprintf(cl->name, sizeof cl->name, "%s", cfg->name);
    snprintf(cl->stream, sizeof cl->stream, "VANTAGE_%s", cfg->name);
    snprintf(cl->subject, sizeof cl->subject, "vantage.%s.journal", cfg->name);
    snprintf(cl->bucket, sizeof cl->bucket, "vantage-lease-%s", cfg->name);
    snprintf(cl->snap_stream, sizeof cl->snap_stream, "VANTAGE_%s_SNAP", cfg->name);
    snprintf(cl->snap_subject, sizeof cl->snap_subject, "vantage.%s.snap", cfg->name);
    snprintf(cl->snap_index, sizeof cl->snap_index, "vantage.%s.snapidx", cfg->name);
    cl->snap_limit = cfg->snapshot_bytes ? cfg->snapshot_bytes : 64ull << 20;
    cl->snap_fd = -1;
    cl->dropped_above = UINT64_MAX;
    char host[64] = "?";
    gethostname(host, sizeof host - 1);
    struct timespec t;
    clock_gettime(CLOCK_REALTIME, &t);
    snprintf(cl->node, sizeof cl->node, "vantaged %s:%d:%lx", host, (int)getpid(), (unsigned long)t.tv_nsec);
    snprintf(cl->value, sizeof cl->value, "%s\n%s", cfg->advertise, cl->node);
    snprintf(cl->writer, sizeof cl->writer, "-");
    cl->started_ms = (uint64_t)cl_mono_ms();
    cl->startup = true;
    atomic_store(&cl->role, CLUSTER_REPLICA);
    uint64_t first = 0, last = 0;
    if (cl->efd < 0 || connect_nats(cl, err, errlen)) {
        cluster_close(cl);
        return -1;
    }
    /* JetStream answers "timeout" or "no responders" for a while after a
       server (re)starts, until its cluster has a leader: waited out */
    int64_t patience = cl_mono_ms() + 30000;
    while (ensure_stream(cl, &first, &last, err, errlen)) {
        if (cl_mono_ms() > patience) {
            cluster_close(cl);
            return -1;
        }
        LOGW("cluster %s: %s: trying again", cl->name, err);
        usleep(500000);
    }
    /* the newest snapshot, then the stream after it */
    while (cl_snap_load(cl, sc, first, err, errlen) < 0) {
        if (cl_mono_ms() > patience || !strstr(err, "snapshot index:")) {
            cluster_close(cl);
            return -1;
        }
        LOGW("cluster %s: %s: trying again", cl->name, err);
        usleep(500000);
    }
    /* the stream from its start, applied to its end as it was at open */
    uint64_t t0 = (uint64_t)cl_mono_ms(), told = t0;
    while (cl_subscribe_from(cl, cl->as.applied + 1, err, errlen)) {
        if (cl_mono_ms() > patience) {
            cluster_close(cl);
            return -1;
        }
        LOGW("cluster %s: %s: trying again", cl->name, err);
        usleep(500000);
    }
    while (cl->as.applied < last && !cl->startup_err[0]) {
        pthread_mutex_lock(&cl->mu);
        if (!cl->qn) {
            struct timespec until;
            clock_gettime(CLOCK_REALTIME, &until);
            until.tv_sec += 1;
            pthread_cond_timedwait(&cl->cv, &cl->mu, &until);
        }
        pthread_mutex_unlock(&cl->mu);
        bool more;
        cl_apply_queue(cl, sc, NULL, &more);
        uint64_t now = (uint64_t)cl_mono_ms();
        if (now - told > 2000) {
            told = now;
            LOGI("cluster %s: catching up, stream message %" PRIu64 " of %" PRIu64, cl->name, cl->as.applied, last);
        }
    }
    if (cl->startup_err[0]) {
        snprintf(err, errlen, "%s", cl->startup_err);
        cluster_close(cl);
        return -1;
    }
    cull_world_commit(sc->world);
    LOGI("cluster %s: %" PRIu64 " stream messages (%" PRIu64 " records) applied in %" PRIu64 " ms: epoch %" PRIu64,
         cl->name, cl->as.applied, cl->as.recs, (uint64_t)cl_mono_ms() - t0, sc->epoch);
    /* a writer candidate takes a free lease now; a replica learns whom
       to send edits to (before its first client asks) */
    uint64_t rev = 0;
    int64_t sent = cl_mono_ms();
    natsStatus s = cfg->follow ? NATS_ERR : kvStore_Create(&rev, cl->kv, "writer", cl->value, (int)strlen(cl->value));
    if (s == NATS_OK) {
        atomic_store(&cl->renewed, sent);
        cl->lease_rev = rev;
        atomic_store(&cl->role, CLUSTER_PROMOTING);
        if (!cl_promote(cl, sc, NULL) || cl->startup_err[0]) {
            snprintf(err, errlen, "%s", cl->startup_err);
            cluster_close(cl);
            return -1;
        }
        cl->promotions = 0;
        *fresh = cl->as.applied == 0;
    } else {
        kvEntry *e = NULL;
        if (kvStore_Get(&e, cl->kv, "writer") == NATS_OK) {
            cl_lease_writer_seen(cl, e);
            kvEntry_Destroy(e);
        }
        LOGI("cluster %s: %s holds the lease: this daemon is a replica", cl->name,
             strcmp(cl->writer, "-") ? cl->writer : "no daemon");
    }
    cl->startup = false;
    if (pthread_create(&cl->lease_thr, NULL, cl_lease_main, cl)) {
        snprintf(err, errlen, "cannot start the lease thread");
        cluster_close(cl);
        return -1;
    }
    cl->lease_on = true;
    *out = cl;
    return 0;
}

void cluster_close(cluster *cl)
{
    if (!cl) return;
    pthread_mutex_lock(&cl->mu);
    cl->stop = true;
    pthread_cond_broadcast(&cl->cv);
    pthread_mutex_unlock(&cl->mu);
    if (cl->lease_on) pthread_join(cl->lease_thr, NULL);
    cl_snap_stop(cl);
    if (cl->js && atomic_load(&cl->role) == CLUSTER_WRITER) {
        jsPubOptions po;
        jsPubOptions_Init(&po);
        po.MaxWait = 2000;
        (void)js_PublishAsyncComplete(cl->js, &po);
        /* a clean stop hands the lease on at once */
        pthread_mutex_lock(&cl->mu);
        uint64_t rev = cl->lease_rev;
        pthread_mutex_unlock(&cl->mu);
        kvEntry *e = NULL;
        if (cl->kv && kvStore_Get(&e, cl->kv, "writer") == NATS_OK) {
            if (kvEntry_Revision(e) == rev) kvStore_Delete(cl->kv, "writer");
            kvEntry_Destroy(e);
        }
    }
    cl_unsubscribe(cl);
    cl_unsub_join(cl);
    for (size_t i = 0; i < cl->qn; i++) natsMsg_Destroy(cl->q[(cl->qhead + i) % cl->qcap]);
    free(cl->q);
    for (size_t i = 0; i < cl->pn; i++) free(cl->pend[(cl->phead + i) % cl->pcap].data);
    free(cl->pend);
    cl_asm_free(&cl->as);
    if (cl->kv) kvStore_Destroy(cl->kv);
    if (cl->js) jsCtx_Destroy(cl->js);
    if (cl->jskv) jsCtx_Destroy(cl->jskv);
    if (cl->nc) {
        natsConnection_Close(cl->nc);
        natsConnection_Destroy(cl->nc);
    }
    if (cl->opts) natsOptions_Destroy(cl->opts);
    if (cl->efd >= 0) close(cl->efd);
    pthread_cond_destroy(&cl->cv);
    pthread_mutex_destroy(&cl->mu);
    free(cl);
}
