/*
 * bench_sublevel.c — sub-level loads against a running vantaged: how long a
 * load and an unload take, what queries on the other sub-levels feel while
 * one runs, and what the daemon's memory does.
 *
 *   bench_sublevel --port P --pid PID --level FILE [--reps N] [--json]
 *
 * A querier thread sends VIS_QUERY (the demo city's street view, seeing
 * only sub-level 0) back to back the whole time and stamps each; each rep
 * runs `vantage sublevel load` (this directory's CLI) on FILE, then unloads
 * it and waits until it is freed. Queries that overlap the daemon's part
 * of a load (the last load_ms of the CLI's run: the import before it is the
 * client's) or an unload are compared with the rest. RSS from /proc/PID.
 */
#include "bench_util.h"
#include "vantage.h"

#include <libgen.h>
#include <pthread.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

typedef struct sample {
    uint64_t t0, t1;
} sample;

typedef struct querier {
    int port;
    volatile int stop;
    sample *s;
    size_t n, cap;
    int failed;
} querier;

static void *query_loop(void *p)
{
    querier *q = p;
    vtc_client *c;
    char err[256];
    if (vtc_connect(&(vtc_connect_opts){.port = q->port, .name = "bench_sublevel"}, &c, err, sizeof err)) {
        fprintf(stderr, "bench_sublevel: %s\n", err);
        q->failed = 1;
        return NULL;
    }
    vp_view v;
    double eye[3] = {0, 2, -300}, at[3] = {0, 2, 0}, up[3] = {0, 1, 0};
    vtc_view_perspective(&v, eye, at, up, 60, 1920, 1080, 0.5, 2000);
    uint16_t only = 0;
    while (!q->stop && q->n < q->cap) {
        vp_vis_result r;
        uint64_t t0 = (uint64_t)bench_now_ns();
        if (vtc_query_sub(c, &v, 1, 0, 0, &only, 1, &r)) {
            q->failed = 1;
            break;
        }
        q->s[q->n++] = (sample){t0, (uint64_t)bench_now_ns()};
    }
    vtc_close(c);
    return NULL;
}

static long rss_kib(int pid)
{
    char path[64], line[256];
    snprintf(path, sizeof path, "/proc/%d/status", pid);
    FILE *f = fopen(path, "r");
    long kb = -1;
    while (f && fgets(line, sizeof line, f))
        if (!strncmp(line, "VmRSS:", 6)) kb = atol(line + 6);
    if (f) fclose(f);
    return kb;
}

typedef struct window {
    uint64_t a, b;
} window;

/* Latency percentiles (ms) of the samples inside (in = true) or outside
 * every window. */
static void stats(const querier *q, const window *w, int nw, bool in, double out[4], size_t *count)
{
    double *lat = malloc((q->n + 1) * sizeof *lat);
    size_t k = 0;
    for (size_t i = 0; i < q->n; i++) {
        bool overlaps = false;
        for (int j = 0; j < nw && !overlaps; j++) overlaps = q->s[i].t1 >= w[j].a && q->s[i].t0 <= w[j].b;
        if (overlaps == in) lat[k++] = (q->s[i].t1 - q->s[i].t0) / 1e6;
    }
    qsort(lat, k, sizeof *lat, bench_cmp_d);
    *count = k;
    out[0] = k ? lat[k / 2] : 0;
    out[1] = k ? lat[(size_t)(0.99 * (k - 1))] : 0;
    out[2] = k ? lat[(size_t)(0.999 * (k - 1))] : 0;
    out[3] = k ? lat[k - 1] : 0;
    free(lat);
}

int main(int argc, char **argv)
{
    int port = 0, pid = 0, reps = 3;
    const char *level = NULL;
    bool json = false;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--port") && i + 1 < argc) port = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--pid") && i + 1 < argc) pid = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--level") && i + 1 < argc) level = argv[++i];
        else if (!strcmp(argv[i], "--reps") && i + 1 < argc) reps = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--json")) json = true;
        else {
            fprintf(stderr, "usage: bench_sublevel --port P --pid PID --level FILE [--reps N] [--json]\n");
            return 2;
        }
    }
    if (reps > 32) reps = 32; /* the per-rep arrays below */
    if (!port || !level || reps < 1) {
        fprintf(stderr, "usage: bench_sublevel --port P --pid PID --level FILE [--reps N] [--json]\n");
        return 2;
    }
    char self[4096], cli[4200];
    snprintf(self, sizeof self, "%s", argv[0]);
    snprintf(cli, sizeof cli, "%s/vantage", dirname(self));
    vtc_client *ed;
    char err[256];
    if (vtc_connect(&(vtc_connect_opts){.port = port, .role = VP_ROLE_EDITOR, .name = "bench_sublevel",
                                      .timeout_ms = 60000},
                   &ed, err, sizeof err)) {
        fprintf(stderr, "bench_sublevel: %s\n", err);
        return 3;
    }
    querier q = {.port = port, .cap = 1u << 22};
    q.s = malloc(q.cap * sizeof *q.s);
    pthread_t th;
    pthread_create(&th, NULL, query_loop, &q);
    usleep(300000);
    window w[64];
    int nw = 0;
    long rss0 = pid ? rss_kib(pid) : -1, rss_loaded = -1, rss_after = -1;
    double load_ms[64], import_ms[64], unload_ms[64], free_ms[64];
    for (int r = 0; r < reps; r++) {
        char cmd[8400], out[1024];
        snprintf(cmd, sizeof cmd, "%s -p %d sublevel load bench %s --json", cli, port, level);
        FILE *p = popen(cmd, "r");
        size_t n = p ? fread(out, 1, sizeof out - 1, p) : 0;
        uint64_t end = (uint64_t)bench_now_ns();
        out[n] = 0;
        if (!p || pclose(p) != 0) {
            fprintf(stderr, "bench_sublevel: %s failed: %s\n", cmd, out);
            return 1;
        }
        const char *lm = strstr(out, "\"load_ms\": "), *im = strstr(out, "\"import_ms\": ");
        load_ms[r] = lm ? atof(lm + 11) : 0;
        import_ms[r] = im ? atof(im + 13) : 0;
        w[nw++] = (window){end - (uint64_t)(load_ms[r] * 1e6), end};
        usleep(200000);
        if (pid) rss_loaded = rss_kib(pid);
        /* unload: hidden at the ack, freed a slice a loop turn after it */
        uint64_t u0 = (uint64_t)bench_now_ns();
        vp_ack a;
        if (vtc_sublevel_unload(ed, "bench", &a)) {
            fprintf(stderr, "bench_sublevel: unload: %s\n", vtc_last_error(ed)->msg);
            return 1;
        }
        uint64_t u1 = (uint64_t)bench_now_ns();
        for (;;) {
            vp_sublevel_infos in;
            vp_sublevel_info si = {0};
            bool found = false;
            if (vtc_sublevel_info(ed, &in)) {
                fprintf(stderr, "bench_sublevel: sublevel info: %s\n", vtc_last_error(ed)->msg);
                return 1;
            }
            size_t pos = 0;
            while (!found && vp_sublevel_info_next(&in, &pos, &si)) found = si.name_len == 5 && !memcmp(si.name, "bench", 5);
            if (!found) {
                fprintf(stderr, "bench_sublevel: the sub-level \"bench\" is gone from the list\n");
                return 1;
            }
            if (si.state == VP_SL_EMPTY) break;
            usleep(1000);
        }
        uint64_t u2 = (uint64_t)bench_now_ns();
        unload_ms[r] = (u1 - u0) / 1e6;
        free_ms[r] = (u2 - u0) / 1e6;
        w[nw++] = (window){u0, u2};
        usleep(200000);
        if (pid) rss_after = rss_kib(pid);
    }
    q.stop = 1;
    pthread_join(th, NULL);
    if (q.failed) fprintf(stderr, "bench_sublevel: a query failed\n");
    double in[4], outside[4];
    size_t nin, nout;
    stats(&q, w, nw, true, in, &nin);
    stats(&q, w, nw, false, outside, &nout);
    qsort(load_ms, (size_t)reps, sizeof *load_ms, bench_cmp_d);
    qsort(import_ms, (size_t)reps, sizeof *import_ms, bench_cmp_d);
    qsort(unload_ms, (size_t)reps, sizeof *unload_ms, bench_cmp_d);
    qsort(free_ms, (size_t)reps, sizeof *free_ms, bench_cmp_d);
    if (json) {
        printf("{\"level\": \"%s\", \"reps\": %d, \"import_ms\": %.1f, \"load_ms\": %.1f, \"unload_ack_ms\": %.2f, "
               "\"unload_freed_ms\": %.1f, \"queries_during\": %zu, \"during_p50_ms\": %.3f, \"during_p99_ms\": %.3f, "
               "\"during_max_ms\": %.3f, \"queries_outside\": %zu, \"outside_p50_ms\": %.3f, \"outside_p99_ms\": %.3f, "
               "\"outside_max_ms\": %.3f, \"rss_kib\": [%ld, %ld, %ld]}\n",
               level, reps, import_ms[reps / 2], load_ms[reps / 2], unload_ms[reps / 2], free_ms[reps / 2], nin, in[0],
               in[1], in[3], nout, outside[0], outside[1], outside[3], rss0, rss_loaded, rss_after);
    } else {
        printf("%s, %d reps (medians): import %.0f ms (client), load %.1f ms, unload ack %.2f ms, freed after %.1f ms\n",
               level, reps, import_ms[reps / 2], load_ms[reps / 2], unload_ms[reps / 2], free_ms[reps / 2]);
        printf("queries on sub-level 0 during loads/unloads: %zu, p50 %.3f p99 %.3f p99.9 %.3f max %.3f ms\n", nin,
               in[0], in[1], in[2], in[3]);
        printf("queries at other times:                      %zu, p50 %.3f p99 %.3f p99.9 %.3f max %.3f ms\n", nout,
               outside[0], outside[1], outside[2], outside[3]);
        if (pid)
            printf("daemon RSS: %ld KiB before, %ld loaded, %ld after the last unload\n", rss0, rss_loaded, rss_after);
    }
    vtc_close(ed);
    free(q.s);
    return q.failed;
}
