/*
 * cli_bench.c — `vantage bench`: a load generator in the manner of
 * redis-benchmark. Each thread drives its connections from one poll()
 * loop with up to --pipeline requests in flight per connection, and
 * records every request's latency for the percentiles.
 */
#include "cli.h"

#include <math.h>
#include <poll.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ---- bench ------------------------------------------------------------------------ */

typedef struct bench_conn {
    vtc_client *c;
    int idx;            /* client number: ids and camera vary with it */
    long sent, recvd, quota;
    double *sent_at;    /* ring of pipeline send times */
    vp_entity *ents;    /* edit test: the entities this client moves */
    vp_transform *xf;   /* transform test: their transforms */
} bench_conn;

/* One load-generator thread: several connections driven from one poll()
 * loop, like redis-benchmark, so 64 connections do not need 64 threads
 * competing with the daemon for the cores. */
enum bench_test { T_QUERY, T_EDIT, T_PING, T_XFORM };

typedef struct bench_arg {
    cli *k;
    enum bench_test test;
    int first, nconn;
    long per_conn;      /* requests per connection; the first `extra` connections overall send one more */
    int extra;
    int pipeline, views, batch;
    uint8_t qflags;
    double *lat;        /* seconds per request */
    long done;
    int failed;
    char why[300];      /* the first failure */
    bool noconn;        /* it was the connection */
    uint64_t records;
} bench_arg;


static void bench_views(vp_view *v, int n, int idx, long i)
{
    for (int k = 0; k < n; k++) {
        double a = 0.01 * (double)i + k * 0.7 + idx;
        double eye[3] = {cos(a) * 200, 2, sin(a) * 200}, at[3] = {0, 2, 0};
        vtc_view_perspective(&v[k], eye, at, NULL, 60, 1280, 720, 0.1, 2000);
    }
}

/* Encodes and sends request number bc->sent of this connection. */
static int bench_send(bench_arg *a, bench_conn *bc, uint8_t *buf, size_t cap)
{
    vp_writer w;
    vp_writer_init(&w, buf, cap);
    uint32_t req = vtc_next_req(bc->c);
    if (a->test == T_EDIT) {
        for (int e = 0; e < a->batch; e++) bc->ents[e].sphere[1] = (double)(bc->sent % 100) * 0.1;
        vp_enc_entities(&w, VP_ENTITY_UPDATE, req, bc->ents, (uint32_t)a->batch);
    } else if (a->test == T_XFORM) {
        for (int e = 0; e < a->batch; e++) {
            bc->xf[e].pos[1] = (double)(bc->sent % 100) * 0.1;
            bc->xf[e].rot[1] = (float)sin(0.005 * (double)(bc->sent % 100)); /* a turn about y */
            bc->xf[e].rot[3] = (float)cos(0.005 * (double)(bc->sent % 100));
        }
        vp_enc_transforms(&w, req, bc->xf, (uint32_t)a->batch);
    } else if (a->test == T_PING) {
        vp_enc_ping(&w, VP_PING, req, (const uint8_t *)"b", 1);
    } else {
        vp_view views[VP_MAX_VIEWS];
        bench_views(views, a->views, bc->idx, bc->sent);
        vp_enc_vis_query(&w, req, a->qflags, 0, views, (uint32_t)a->views);
    }
    bc->sent_at[bc->sent % a->pipeline] = now_s();
    bc->sent++;
    return vtc_send(bc->c, buf, w.len);
}

/* The transform test's class: a 0.5 m cube, put by each connection (the
 * same mesh each time). */
#define BENCH_XFORM_CLASS 65000u

/* The transform test: bc->ents become transform entities of the bench
 * class, bc->xf their TRANSFORM_SET records. */
static bool xform_setup(bench_conn *bc, int batch)
{
    static const float cube[24] = {-0.25f, -0.25f, -0.25f, 0.25f, -0.25f, -0.25f, -0.25f, 0.25f, -0.25f,
                                   0.25f,  0.25f,  -0.25f, -0.25f, -0.25f, 0.25f, 0.25f, -0.25f, 0.25f,
                                   -0.25f, 0.25f,  0.25f,  0.25f,  0.25f,  0.25f};
    static const uint32_t idx[6] = {0, 1, 2, 4, 5, 6};
    if (vtc_put_mesh(bc->c, BENCH_XFORM_CLASS, cube, NULL, 8, idx, 6)) return false;
    if (!(bc->xf = calloc((size_t)batch, sizeof *bc->xf))) return false;
    for (int e = 0; e < batch; e++) {
        double pos[3] = {bc->idx * 10.0, 0, e * 0.5};
        float q[4] = {0, 0, 0, 1}, s[3] = {1, 1, 1};
        vtc_entity_trs(&bc->ents[e], bc->ents[e].id, BENCH_XFORM_CLASS, pos, q, s);
        bc->ents[e].flags |= VP_ENT_DYNAMIC;
        bc->xf[e] = (vp_transform){.id = bc->ents[e].id, .pos = {pos[0], 0, pos[2]}, .rot = {0, 0, 0, 1},
                                   .scale = {1, 1, 1}};
    }
    return true;
}

static void *bench_worker(void *p)
{
    bench_arg *a = p;
    bench_conn *cs = calloc((size_t)a->nconn, sizeof *cs);
    struct pollfd *pf = calloc((size_t)a->nconn, sizeof *pf);
    size_t cap = vp_size_entities((uint32_t)a->batch) + vp_size_transforms((uint32_t)a->batch) + VP_HEADER_SIZE + 8 + (size_t)a->views * VP_VIEW_SIZE;
    uint8_t *buf = malloc(cap);
    bool edit = a->test == T_EDIT || a->test == T_XFORM;
    for (int i = 0; i < a->nconn && !a->failed; i++) {
        bench_conn *bc = &cs[i];
        vtc_connect_opts o = a->k->co;
        o.role = VP_ROLE_EDITOR;
        o.name = "vantage-bench";
        bc->idx = a->first + i;
        bc->quota = a->per_conn + (bc->idx < a->extra); /* N requests exactly, the remainder spread */
        bc->sent_at = calloc((size_t)a->pipeline, sizeof *bc->sent_at);
        char err[256];
        if (vtc_connect(&o, &bc->c, err, sizeof err)) {
            snprintf(a->why, sizeof a->why, "cannot connect: %s", err);
            a->failed = 1;
            a->noconn = true;
            break;
        }
        if (edit) {
            uint64_t base = 0x7B000000000ull + (uint64_t)bc->idx * 100000000ull;
            bc->ents = calloc((size_t)a->batch, sizeof *bc->ents);
            for (int e = 0; e < a->batch; e++)
                bc->ents[e] = (vp_entity){.id = base + (uint64_t)e, .sphere = {bc->idx * 10.0, 0, e * 0.5, 0.25},
                                          .flags = VP_ENT_DYNAMIC};
            if (a->test == T_XFORM && !xform_setup(bc, a->batch)) a->failed = 1;
            if (vtc_add(bc->c, bc->ents, (uint32_t)a->batch, NULL, NULL)) a->failed = 1;
        }
        pf[i] = (struct pollfd){.fd = vtc_fd(bc->c), .events = POLLIN};
    }
    /* fill every connection's pipeline, then one new request per reply */
    for (int i = 0; i < a->nconn && !a->failed; i++)
        while (cs[i].sent < cs[i].quota && cs[i].sent < a->pipeline)
            if (bench_send(a, &cs[i], buf, cap)) a->failed = 1;
    long open = a->failed ? 0 : a->nconn;
    while (open > 0 && !a->failed) {
        int r = poll(pf, (nfds_t)a->nconn, 30000);
        if (r <= 0) {
            a->failed = 1;
            break;
        }
        for (int i = 0; i < a->nconn && !a->failed; i++) {
            if (!pf[i].revents) continue;
            bench_conn *bc = &cs[i];
            for (;;) {
                vp_header h;
                const uint8_t *pl;
                int rc = vtc_recv(bc->c, &h, &pl, 0);
                if (rc == VP_NEED_MORE) break;
                if (rc || h.type == VP_ERROR) {
                    a->failed = 1;
                    break;
                }
                if (h.type == VP_EVENT) continue;
                if (h.type == VP_VIS_RESULT) {
                    vp_vis_result res;
                    if (!vp_dec_vis_result(pl, h.len, &res)) a->records += res.visible;
                }
                a->lat[a->done++] = now_s() - bc->sent_at[bc->recvd % a->pipeline];
                bc->recvd++;
                if (bc->sent < bc->quota && bench_send(a, bc, buf, cap)) a->failed = 1;
                if (bc->recvd == bc->quota) {
                    pf[i].fd = -1; /* done: poll ignores it */
                    open--;
                    break;
                }
            }
        }
    }
    for (int i = 0; i < a->nconn; i++) {
        /* the entities go, so the next run can add them again */
        uint64_t *ids = cs[i].ents && cs[i].c ? malloc((size_t)a->batch * sizeof *ids) : NULL;
        for (int e = 0; ids && e < a->batch; e++) ids[e] = cs[i].ents[e].id;
        if (ids && !a->failed) vtc_remove(cs[i].c, ids, (uint32_t)a->batch, NULL);
        free(ids);
        vtc_close(cs[i].c);
        free(cs[i].sent_at);
        free(cs[i].ents);
        free(cs[i].xf);
    }
    free(cs);
    free(pf);
    free(buf);
    return NULL;
}

int cmd_bench(cli *k, int argc, char **argv)
{
    for (int i = 1; i + 1 < argc; i++)
        if (!strcmp(argv[i], "--test") && !strcmp(argv[i + 1], "frames")) return bench_frames(k, argc, argv);
    for (int i = 1; i < argc; i++)
        if (!strcmp(argv[i], "--scenario")) return bench_scenario(k, argc, argv);
    const char *use = "bench [--test query|edit|transform|ping|frames] [--clients N] [--threads T] [--requests N] [--pipeline P] "
                      "[--views K] [--batch B] [--count-only] [--no-occlusion] [--json]";
    const char *test = "query";
    uint64_t clients = 64, requests = 100000, pipeline = 1, views = 1, batch = 1000, threads = 2;
    bool json = false;
    uint8_t qflags = 0;
    const struct { const char *name; uint64_t *v; } nums[] = {
        {"--clients", &clients}, {"--requests", &requests}, {"--threads", &threads},
        {"--pipeline", &pipeline}, {"--views", &views}, {"--batch", &batch}};
    for (int i = 1; i < argc; i++) {
        bool ok = false;
        if (!strcmp(argv[i], "--test") && i + 1 < argc) test = argv[++i], ok = true;
        else if (!strcmp(argv[i], "--count-only")) qflags |= VP_Q_COUNT_ONLY, ok = true;
        else if (!strcmp(argv[i], "--no-occlusion")) qflags |= VP_Q_NO_OCCLUSION, ok = true;
        else if (!strcmp(argv[i], "--json")) json = ok = true;
        for (size_t n = 0; !ok && n < sizeof nums / sizeof nums[0]; n++)
            if (!strcmp(argv[i], nums[n].name) && i + 1 < argc) {
                if (!parse_u64(argv[++i], nums[n].v))
                    return die_bad_value("bench", nums[n].name, argv[i], "a count");
                ok = true;
            }
        if (!ok) return die_usage("bench: unexpected %s; %s", argv[i], use);
    }
    enum bench_test kind;
    if (!strcmp(test, "query")) kind = T_QUERY;
    else if (!strcmp(test, "edit")) kind = T_EDIT;
    else if (!strcmp(test, "ping")) kind = T_PING;
    else if (!strcmp(test, "transform")) kind = T_XFORM;
    else return die_bad_value("bench", "--test", test, "query, edit, transform, ping or frames");
    /* each bound named with the option it bounds */
    const struct { const char *name; uint64_t v, lo, hi; } range[] = {
        {"--clients", clients, 1, 1000}, {"--pipeline", pipeline, 1, 1000}, {"--views", views, 1, 32},
        {"--batch", batch, 1, 65536},    {"--threads", threads, 1, 64}};
    for (size_t r = 0; r < sizeof range / sizeof range[0]; r++)
        if (range[r].v < range[r].lo || range[r].v > range[r].hi)
            return die_usage("bench: %s %llu: expected %llu..%llu", range[r].name, (unsigned long long)range[r].v,
                             (unsigned long long)range[r].lo, (unsigned long long)range[r].hi);
    if (requests < clients)
        return die_usage("bench: --requests %llu is fewer than --clients %llu (each client sends at least one)",
                         (unsigned long long)requests, (unsigned long long)clients);
    if (threads > clients) threads = clients;
    pthread_t *th = calloc((size_t)threads, sizeof *th);
    bench_arg *args = calloc((size_t)threads, sizeof *args);
    long per = (long)(requests / clients);
    int extra = (int)(requests % clients);
    double t0 = now_s();
    for (uint64_t i = 0, first = 0; i < threads; i++) {
        int nconn = (int)(clients / threads + (i < clients % threads));
        args[i] = (bench_arg){.k = k, .first = (int)first, .nconn = nconn, .test = kind, .per_conn = per, .extra = extra,
                              .pipeline = (int)pipeline, .views = (int)views, .batch = (int)batch,
                              .qflags = qflags};
        args[i].lat = malloc(sizeof(double) * (size_t)(per + 1) * (size_t)nconn);
        first += nconn;
        pthread_create(&th[i], NULL, bench_worker, &args[i]);
    }
    long done = 0, failed = 0;
    bool noconn = false;
    uint64_t records = 0;
    for (uint64_t i = 0; i < threads; i++) {
        pthread_join(th[i], NULL);
        if (args[i].failed && args[i].why[0] && !failed) fprintf(stderr, "%s: bench: %s\n", g_prog, args[i].why);
        noconn |= args[i].noconn;
        done += args[i].done;
        failed += args[i].failed;
        records += args[i].records;
    }
    double secs = now_s() - t0;
    double *all = malloc(sizeof(double) * (size_t)(done ? done : 1));
    long n = 0;
    for (uint64_t i = 0; i < threads; i++) {
        memcpy(all + n, args[i].lat, sizeof(double) * (size_t)args[i].done);
        n += args[i].done;
        free(args[i].lat);
    }
    qsort(all, (size_t)n, sizeof *all, cmp_dbl);
#define PCT(q) (n ? all[(size_t)((double)(n - 1) * (q))] * 1e3 : 0.0)
    double rate = done / secs;
    if (json) {
        printf("{\"test\": \"%s\", \"clients\": %ld, \"pipeline\": %ld, \"views\": %ld, \"batch\": %ld, "
               "\"requests\": %ld, \"failed_threads\": %ld, \"seconds\": %.3f, \"per_second\": %.0f, "
               "\"records_per_second\": %.0f, \"p50_ms\": %.4f, \"p90_ms\": %.4f, \"p99_ms\": %.4f, "
               "\"p999_ms\": %.4f, \"max_ms\": %.4f}\n",
               test, clients, pipeline, views, batch, done, failed, secs, rate,
               kind == T_EDIT || kind == T_XFORM ? rate * batch : records / secs, PCT(0.5), PCT(0.9), PCT(0.99), PCT(0.999),
               PCT(1.0));
    } else {
        printf("%s: %ld requests, %ld clients, pipeline %ld: %.2f s, %.0f requests/s", test, done, clients,
               pipeline, secs, rate);
        if (kind == T_EDIT) printf(", %.0f entity updates/s", rate * batch);
        if (kind == T_XFORM) printf(", %.0f transforms/s", rate * batch);
        if (!strcmp(test, "query")) printf(", %.0f visible records/s", records / secs);
        printf("\nlatency ms: p50 %.3f  p90 %.3f  p99 %.3f  p99.9 %.3f  max %.3f\n", PCT(0.5), PCT(0.9), PCT(0.99),
               PCT(0.999), PCT(1.0));
        if (failed) printf("%ld load threads failed\n", failed);
    }
#undef PCT
    free(all);
    free(th);
    free(args);
    return noconn ? 3 : failed ? 1 : 0; /* 3: cannot connect, as every command */
}

