/*
 * cluster_bench — edit throughput and replica lag of a Vantage cluster
 * (BENCHMARKS.md, "Scale-out"; driven by tests/cluster/bench.py).
 *
 *   cluster_bench --writer EP [--replica EP] [--rate N] [--seconds S] [--batch B] [--window W]
 *                 [--base ID] [--max MESSAGES]
 *
 * One editor connection to the writer sends ENTITY_ADD messages (B new
 * entities each) pipelined, at N messages a second (0: as fast as W in
 * flight allow); a second thread reads the answers. With --replica, a
 * viewer subscribed to the replica's scene EVENTs records when each epoch
 * became visible there. Prints one JSON line: messages acknowledged, the
 * rate reached, the answer latency (send to ACK), the replica lag (the
 * writer's ACK of an edit to the first EVENT on the replica whose epoch
 * includes it; 0 when the replica had it first) and the time from sending
 * an edit to seeing it on the replica, p50/p99 in ms. BUSY answers (the
 * writer's stream is behind) are counted apart.
 */
#include "vantage.h"

#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>
#include <getopt.h>

static double now_ms(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec * 1e3 + t.tv_nsec / 1e6;
}

#define MAXMSG 4000000u

typedef struct bench {
    vtc_client *w, *r;
    double rate, seconds;
    uint32_t batch, window;
    uint64_t base;
    double *sent_at;          /* by req (1..) */
    double *ack_at;           /* by req */
    uint64_t *ack_epoch;      /* by req */
    atomic_uint inflight;
    atomic_uint sent, acked, busy; /* acked counts the BUSY answers too */
    atomic_bool done, failed;
    /* the replica's EVENTs: (epoch, time) in order */
    uint64_t *ev_epoch;
    double *ev_at;
    size_t nev, cap_ev;
} bench;

static void *reader(void *arg)
{
    bench *b = arg;
    for (;;) {
        if (atomic_load(&b->done) && atomic_load(&b->acked) == atomic_load(&b->sent)) break;
        vp_header h;
        const uint8_t *p;
        int rc = vtc_recv(b->w, &h, &p, 200);
        if (rc == VTC_ERR_IO && vtc_last_error(b->w)->timed_out) continue;
        if (rc) {
            fprintf(stderr, "cluster_bench: writer: %s\n", vtc_last_error(b->w)->msg);
            atomic_store(&b->failed, true);
            break;
        }
        if (h.type == VP_ERROR) {
            vp_error e;
            vp_dec_error(p, h.len, &e);
            if (e.code == VP_ERR_BUSY) { /* the stream is behind: back-pressure, counted */
                atomic_fetch_add(&b->busy, 1);
                atomic_fetch_sub(&b->inflight, 1);
                atomic_fetch_add(&b->acked, 1);
                continue;
            }
            fprintf(stderr, "cluster_bench: writer refused: %.*s\n", (int)e.msg_len, (const char *)e.msg);
            atomic_store(&b->failed, true);
            break;
        }
        if (h.type != VP_ENTITY_ADD_REPLY || !h.req || h.req >= MAXMSG) continue;
        vp_add_reply ar;
        if (vp_dec_add_reply(p, h.len, &ar)) continue;
        b->ack_at[h.req] = now_ms();
        b->ack_epoch[h.req] = ar.epoch;
        atomic_fetch_sub(&b->inflight, 1);
        atomic_fetch_add(&b->acked, 1);
    }
    return NULL;
}

static void *watcher(void *arg)
{
    bench *b = arg;
    while (!atomic_load(&b->failed)) {
        vp_event ev;
        int rc = vtc_wait_event(b->r, &ev, 200);
        if (rc == VTC_ERR_IO && vtc_last_error(b->r)->timed_out) {
            if (atomic_load(&b->done) && atomic_load(&b->acked) == atomic_load(&b->sent) && b->nev &&
                b->ev_epoch[b->nev - 1] >= b->ack_epoch[atomic_load(&b->sent)])
                break;
            continue;
        }
        if (rc) break;
        if (b->nev == b->cap_ev) {
            b->cap_ev = b->cap_ev ? b->cap_ev * 2 : 4096;
            b->ev_epoch = realloc(b->ev_epoch, b->cap_ev * sizeof *b->ev_epoch);
            b->ev_at = realloc(b->ev_at, b->cap_ev * sizeof *b->ev_at);
        }
        b->ev_epoch[b->nev] = ev.epoch;
        b->ev_at[b->nev++] = now_ms();
    }
    return NULL;
}

typedef struct viewer_arg {
    const char *ep;
    unsigned w, h;
    atomic_bool *stop;
    atomic_ulong *frames;
} viewer_arg;

static void *viewer(void *arg)
{
    viewer_arg *a = arg;
    vtc_client *c;
    char err[600];
    if (vtc_connect(&(vtc_connect_opts){.endpoints = a->ep, .role = VP_ROLE_VIEWER, .name = "cluster_bench"}, &c,
                    err, sizeof err)) {
        fprintf(stderr, "cluster_bench: viewer on %s: %s\n", a->ep, err);
        return NULL;
    }
    vp_frame_sub sub = {.r = {.format = VP_FRAME_JPEG, .quality = 80}, .max_fps = 60};
    vtc_view_perspective(&sub.r.view, (double[]){150, 200, 150}, (double[]){0, 0, 0}, NULL, 60, (uint16_t)a->w,
                         (uint16_t)a->h, 0.1, 10000);
    if (vtc_frame_subscribe(c, &sub)) {
        fprintf(stderr, "cluster_bench: subscribe: %s\n", vtc_last_error(c)->msg);
        vtc_close(c);
        return NULL;
    }
    vp_frame f;
    while (!atomic_load(a->stop))
        if (vtc_wait_frame(c, &f, 200) == VP_OK) atomic_fetch_add(a->frames, 1);
    vtc_close(c);
    return NULL;
}

static int frames_mode(const char *list, const char *wep, int n, unsigned w, unsigned h, double seconds)
{
    char err[600];
    vtc_client *ed;
    if (vtc_connect(&(vtc_connect_opts){.endpoints = wep, .role = VP_ROLE_EDITOR, .name = "cluster_bench"}, &ed, err,
                    sizeof err)) {
        fprintf(stderr, "cluster_bench: %s\n", err);
        return 1;
    }
    vp_entity e = {.id = 90000001, .sphere = {0, 5, 0, 4}};
    uint32_t hd;
    if (vtc_add(ed, &e, 1, &hd, NULL) && vtc_last_error(ed)->code != VP_ERR_DUPLICATE) {
        fprintf(stderr, "cluster_bench: add: %s\n", vtc_last_error(ed)->msg);
        return 1;
    }
    char eps[64][256];
    int k = 0;
    for (const char *p = list; *p && k < 64;) {
        const char *c = strchr(p, ',');
        size_t l = c ? (size_t)(c - p) : strlen(p);
        snprintf(eps[k++], sizeof eps[0], "%.*s", (int)l, p);
        p += l + (c ? 1 : 0);
    }
    atomic_bool stop = false;
    atomic_ulong frames = 0;
    pthread_t *t = calloc((size_t)n, sizeof *t);
    viewer_arg *a = calloc((size_t)n, sizeof *a);
    for (int i = 0; i < n; i++) {
        a[i] = (viewer_arg){.ep = eps[i % k], .w = w, .h = h, .stop = &stop, .frames = &frames};
        pthread_create(&t[i], NULL, viewer, &a[i]);
    }
    usleep(1500000); /* the first frames (the renderers' tables) out of the count */
    unsigned long f0 = atomic_load(&frames);
    double t0 = now_ms();
    for (int i = 0; now_ms() - t0 < seconds * 1000; i++) {
        e.sphere[0] = (i % 200) * 0.5;
        vtc_update(ed, &e, 1, NULL);
        usleep(10000);
    }
    double secs = (now_ms() - t0) / 1e3;
    unsigned long got = atomic_load(&frames) - f0;
    atomic_store(&stop, true);
    for (int i = 0; i < n; i++) pthread_join(t[i], NULL);
    printf("{\"viewers\": %d, \"daemons\": %d, \"size\": \"%ux%u\", \"frames\": %lu, \"seconds\": %.2f, "
           "\"frames_per_s\": %.1f}\n",
           n, k, w, h, got, secs, got / secs);
    free(t);
    free(a);
    vtc_close(ed);
    return 0;
}

static int cmpd(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

static double pct(double *v, size_t n, double q)
{
    if (!n) return -1;
    size_t i = (size_t)(q * (double)(n - 1) + 0.5);
    return v[i];
}

int main(int argc, char **argv)
{
    bench b = {.rate = 1000, .seconds = 5, .batch = 1, .window = 256, .base = 50000000};
    const char *wep = NULL, *rep = NULL, *fr = NULL;
    int nviewers = 4;
    uint32_t max_msgs = MAXMSG - 1; /* --max: stop after this many messages */
    unsigned fw = 640, fh = 360;
    static const struct option opts[] = {{"writer", 1, 0, 'w'}, {"replica", 1, 0, 'r'}, {"rate", 1, 0, 'R'},
                                         {"seconds", 1, 0, 's'}, {"batch", 1, 0, 'b'}, {"window", 1, 0, 'W'},
                                         {"base", 1, 0, 'B'}, {"frames", 1, 0, 'f'}, {"viewers", 1, 0, 'v'},
                                         {"size", 1, 0, 'z'}, {"max", 1, 0, 'm'}, {0, 0, 0, 0}};
    int o;
    while ((o = getopt_long(argc, argv, "", opts, NULL)) != -1) {
        switch (o) {
        case 'w': wep = optarg; break;
        case 'r': rep = optarg; break;
        case 'R': b.rate = atof(optarg); break;
        case 's': b.seconds = atof(optarg); break;
        case 'b': b.batch = (uint32_t)atoi(optarg); break;
        case 'W': b.window = (uint32_t)atoi(optarg); break;
        case 'B': b.base = strtoull(optarg, NULL, 10); break;
        case 'f': fr = optarg; break;
        case 'm': max_msgs = (uint32_t)strtoul(optarg, NULL, 10); break;
        case 'v': nviewers = atoi(optarg); break;
        case 'z': sscanf(optarg, "%ux%u", &fw, &fh); break;
        default: return 2;
        }
    }
    if (!wep || !b.batch || !b.window || b.seconds <= 0) {
        fprintf(stderr, "usage: cluster_bench --writer EP [--replica EP] [--rate N] [--seconds S] [--batch B]\n");
        return 2;
    }
    if (fr) return frames_mode(fr, wep, nviewers, fw, fh, b.seconds);
    char err[600];
    vtc_connect_opts wo = {.endpoints = wep, .role = VP_ROLE_EDITOR, .name = "cluster_bench", .timeout_ms = 10000};
    if (vtc_connect(&wo, &b.w, err, sizeof err)) {
        fprintf(stderr, "cluster_bench: %s\n", err);
        return 1;
    }
    if (rep) {
        vtc_connect_opts ro = {.endpoints = rep, .role = VP_ROLE_VIEWER, .name = "cluster_bench", .timeout_ms = 10000};
        if (vtc_connect(&ro, &b.r, err, sizeof err) || vtc_subscribe(b.r, VP_EVENT_SCENE)) {
            fprintf(stderr, "cluster_bench: replica: %s\n", err);
            return 1;
        }
    }
    b.sent_at = calloc(MAXMSG, sizeof *b.sent_at);
    b.ack_at = calloc(MAXMSG, sizeof *b.ack_at);
    b.ack_epoch = calloc(MAXMSG, sizeof *b.ack_epoch);
    vp_entity *e = calloc(b.batch, sizeof *e);
    size_t cap = vp_size_entities(b.batch);
    uint8_t *buf = malloc(cap);
    if (!b.sent_at || !b.ack_at || !b.ack_epoch || !e || !buf) return 1;
    pthread_t rt, wt;
    pthread_create(&rt, NULL, reader, &b);
    if (rep) pthread_create(&wt, NULL, watcher, &b);
    double t0 = now_ms();
    uint64_t next_id = b.base;
    for (uint32_t k = 1; k <= max_msgs && k < MAXMSG && !atomic_load(&b.failed); k++) {
        double now = now_ms();
        if (now - t0 > b.seconds * 1000) break;
        if (b.rate > 0) {
            double due = t0 + (k - 1) * 1000.0 / b.rate;
            if (due > now) usleep((useconds_t)((due - now) * 1000));
        }
        while (atomic_load(&b.inflight) >= b.window && !atomic_load(&b.failed)) usleep(50);
        for (uint32_t i = 0; i < b.batch; i++) {
            memset(&e[i], 0, sizeof e[i]);
            e[i].id = next_id++;
            e[i].sphere[0] = (double)(e[i].id % 4096) * 2;
            e[i].sphere[2] = (double)(e[i].id / 4096 % 4096) * 2;
            e[i].sphere[3] = 1;
        }
        vp_writer w;
        vp_writer_init(&w, buf, cap);
        vp_enc_entities(&w, VP_ENTITY_ADD, k, e, b.batch);
        b.sent_at[k] = now_ms();
        atomic_fetch_add(&b.inflight, 1);
        if (vtc_send(b.w, w.p, w.len)) {
            fprintf(stderr, "cluster_bench: send: %s\n", vtc_last_error(b.w)->msg);
            atomic_store(&b.failed, true);
            break;
        }
        atomic_store(&b.sent, k);
    }
    atomic_store(&b.done, true);
    pthread_join(rt, NULL);
    double t_all = now_ms() - t0;
    if (rep) pthread_join(wt, NULL);
    uint32_t n = atomic_load(&b.acked);
    double *lat = malloc((n + 1) * sizeof *lat), *lag = malloc((n + 1) * sizeof *lag),
           *vis = malloc((n + 1) * sizeof *vis);
    size_t nl = 0, ng = 0, ev = 0;
    for (uint32_t k = 1; k <= atomic_load(&b.sent); k++) {
        if (!b.ack_at[k]) continue;
        lat[nl++] = b.ack_at[k] - b.sent_at[k];
        if (!rep) continue;
        /* the first EVENT at or past this epoch (acks come in epoch order):
           lag from the writer's answer (negative: the replica had it first,
           counted 0), and from the send */
        while (ev < b.nev && b.ev_epoch[ev] < b.ack_epoch[k]) ev++;
        if (ev < b.nev) {
            lag[ng] = b.ev_at[ev] - b.ack_at[k] > 0 ? b.ev_at[ev] - b.ack_at[k] : 0;
            vis[ng++] = b.ev_at[ev] - b.sent_at[k];
        }
    }
    qsort(lat, nl, sizeof *lat, cmpd);
    qsort(lag, ng, sizeof *lag, cmpd);
    qsort(vis, ng, sizeof *vis, cmpd);
    uint32_t ok = n - atomic_load(&b.busy);
    printf("{\"messages\": %u, \"busy\": %u, \"entities\": %llu, \"seconds\": %.3f, \"msgs_per_s\": %.0f, "
           "\"ack_p50_ms\": %.3f, \"ack_p99_ms\": %.3f, \"lag_n\": %zu, \"lag_p50_ms\": %.3f, \"lag_p99_ms\": %.3f, "
           "\"visible_p50_ms\": %.3f, \"visible_p99_ms\": %.3f, \"failed\": %s}\n",
           ok, atomic_load(&b.busy), (unsigned long long)ok * b.batch, t_all / 1e3, ok / (t_all > 0 ? t_all / 1e3 : 1),
           pct(lat, nl, 0.5), pct(lat, nl, 0.99), ng, pct(lag, ng, 0.5), pct(lag, ng, 0.99), pct(vis, ng, 0.5),
           pct(vis, ng, 0.99), atomic_load(&b.failed) ? "true" : "false");
    vtc_close(b.w);
    vtc_close(b.r);
    free(lat);
    free(lag);
    free(vis);
    free(b.sent_at);
    free(b.ack_at);
    free(b.ack_epoch);
    free(b.ev_epoch);
    free(b.ev_at);
    free(e);
    free(buf);
    return atomic_load(&b.failed) ? 1 : 0;
}
