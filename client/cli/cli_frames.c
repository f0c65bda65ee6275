/*
 * cli_frames.c — `vantage bench --test frames`: the frame stream under
 * load. N viewers subscribe to the same view (each its own connection and
 * thread, counting the frames that reach it), S more subscribe and never
 * read (stalled viewers), and an editor moves an entity of its own at a
 * fixed rate so the scene keeps changing. Reports each viewer's frames per
 * second and the spread of frame intervals: latest-frame-wins means the
 * stalled ones must not lower the others' rate.
 */
#include "cli.h"
#include "vp_grow.h"

#include <inttypes.h>
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

typedef struct viewer {
    pthread_t th;
    vtc_connect_opts co;
    vp_frame_sub sub;
    bool stalled;
    atomic_bool *stop;
    /* results */
    int rc;
    char err[256];
    uint64_t frames, bytes;
    double first, last;     /* arrival times of the first and last frame */
    double *gaps;           /* intervals between frames, ms */
    size_t ngaps, gaps_cap;
    double render_ms, encode_ms; /* sums, as the daemon reports them */
} viewer;

static void *viewer_main(void *p)
{
    viewer *v = p;
    vtc_client *c;
    if ((v->rc = vtc_connect(&v->co, &c, v->err, sizeof v->err))) return NULL;
    if ((v->rc = vtc_frame_subscribe(c, &v->sub))) {
        snprintf(v->err, sizeof v->err, "%.200s", vtc_last_error(c)->msg);
        vtc_close(c);
        return NULL;
    }
    if (v->stalled) {
        /* subscribed, and never reads: the daemon must not queue for it */
        while (!atomic_load(v->stop)) usleep(10000);
        vtc_close(c);
        return NULL;
    }
    double prev = 0;
    while (!atomic_load(v->stop)) {
        vp_frame f;
        int rc = vtc_wait_frame(c, &f, 100);
        if (rc == VTC_ERR_IO && vtc_last_error(c)->timed_out) continue;
        if (rc) {
            v->rc = rc;
            snprintf(v->err, sizeof v->err, "%.200s", vtc_last_error(c)->msg);
            break;
        }
        double t = now_s();
        if (!v->frames) v->first = t;
        else {
            if (!vp_grow((void **)&v->gaps, &v->gaps_cap, v->ngaps + 1, sizeof *v->gaps)) break;
            v->gaps[v->ngaps++] = (t - prev) * 1e3;
        }
        prev = v->last = t;
        v->frames++;
        v->bytes += f.data_len;
        v->render_ms += f.render_ns / 1e6;
        v->encode_ms += f.encode_ns / 1e6;
    }
    vtc_close(c);
    return NULL;
}

int bench_frames(cli *k, int argc, char **argv)
{
    const char *use = "bench --test frames [--viewers N] [--stalled S] [--seconds T] [--size WxH] [--fps F] "
                      "[--edits-per-s R] [--quality Q] [--renderer soft|gl] [--eye X,Y,Z] [--at X,Y,Z] [--json]";
    uint64_t viewers = 1, stalled = 0, fps = 240, edit_rate = 100, quality = 80;
    double seconds = 5, eye[3] = {150, 200, 150}, at[3] = {0, 0, 0};
    unsigned w = 1280, h = 720;
    uint8_t renderer = 0;
    bool json = false;
    for (int i = 1; i < argc; i++) {
        bool ok = true;
        const char *a = argv[i], *val = i + 1 < argc ? argv[i + 1] : NULL;
        if (!strcmp(a, "--test")) i++;
        else if (!strcmp(a, "--json")) json = true;
        else if (!val) return die_usage("bench --test frames: unexpected %s (last, with no value); %s", a, use);
        else if (!strcmp(a, "--viewers")) ok = parse_u64(val, &viewers), i++;
        else if (!strcmp(a, "--stalled")) ok = parse_u64(val, &stalled), i++;
        else if (!strcmp(a, "--seconds")) ok = parse_vec(val, &seconds, 1), i++;
        else if (!strcmp(a, "--size")) ok = parse_size(val, 4096, &w, &h), i++;
        else if (!strcmp(a, "--fps")) ok = parse_u64(val, &fps), i++;
        else if (!strcmp(a, "--edits-per-s")) ok = parse_u64(val, &edit_rate), i++;
        else if (!strcmp(a, "--quality")) ok = parse_u64(val, &quality), i++;
        else if (!strcmp(a, "--eye")) ok = parse_vec(val, eye, 3), i++;
        else if (!strcmp(a, "--at")) ok = parse_vec(val, at, 3), i++;
        else if (!strcmp(a, "--renderer")) ok = parse_renderer(val, &renderer), i++;
        else return die_usage("bench --test frames: unexpected %s; %s", a, use);
        if (!ok) return die_usage("bench --test frames: %s %s: not a valid value", a, val);
    }
    if (viewers < 1 || viewers > 256) return die_usage("bench --test frames: --viewers is 1..256");
    if (stalled > 256) return die_usage("bench --test frames: --stalled is 0..256");
    if (seconds <= 0 || seconds > 3600) return die_usage("bench --test frames: --seconds is more than 0, at most 3600");
    if (fps < 1 || fps > VP_FRAME_SUB_MAX_FPS) return die_usage("bench --test frames: --fps is 1..%u", VP_FRAME_SUB_MAX_FPS);
    if (edit_rate > 100000) return die_usage("bench --test frames: --edits-per-s is 0..100000");
    if (quality < 1 || quality > 100) return die_usage("bench --test frames: --quality is 1..100");
    vp_frame_sub sub = {.r = {.format = VP_FRAME_JPEG, .quality = (uint8_t)quality, .renderer = renderer},
                        .max_fps = (uint16_t)fps};
    if (!vtc_view_perspective(&sub.r.view, eye, at, NULL, 60, (uint16_t)w, (uint16_t)h, 0.1, 10000))
        return die_usage("bench: degenerate camera");
    int rc = connect_cli(k, VP_ROLE_EDITOR);
    if (rc) return rc;
    /* the editor's own entity, in front of the camera */
    uint64_t id = 0xBE7C000000000000ull | (uint64_t)getpid();
    double dir[3], len = 0;
    for (int a = 0; a < 3; a++) dir[a] = at[a] - eye[a], len += dir[a] * dir[a];
    len = sqrt(len);
    vp_entity e = {.id = id, .class_id = 7};
    for (int a = 0; a < 3; a++) {
        double c = eye[a] + dir[a] / len * fmin(50, len / 2);
        e.aabb[a] = c - 2, e.aabb[3 + a] = c + 2;
    }
    if ((rc = vtc_add(k->c, &e, 1, NULL, NULL))) return server_fail(k, "bench: add", rc);

    size_t n = (size_t)(viewers + stalled), started = 0;
    viewer *vs = calloc(n, sizeof *vs);
    atomic_bool stop = false;
    int fail = 0;
    if (!vs) {
        fprintf(stderr, "%s: out of memory\n", g_prog);
        fail = 1;
    }
    for (; !fail && started < n; started++) {
        size_t i = started;
        vs[i] = (viewer){.co = k->co, .sub = sub, .stalled = i >= (size_t)viewers, .stop = &stop};
        vs[i].co.role = VP_ROLE_VIEWER;
        vs[i].co.name = "vantage-bench-frames";
        if (pthread_create(&vs[i].th, NULL, viewer_main, &vs[i])) {
            fprintf(stderr, "%s: cannot start a thread\n", g_prog);
            fail = 1;
            break;
        }
    }
    /* the edits: the entity moves back and forth at edit_rate a second */
    double t0 = now_s(), next = t0;
    uint64_t edits = 0;
    while (!fail && now_s() - t0 < seconds) {
        if (edit_rate == 0) {
            usleep(10000);
            continue;
        }
        double dx = 3 * sin(edits * 0.05);
        vp_entity m = e;
        m.aabb[0] += dx, m.aabb[3] += dx;
        if ((rc = vtc_update(k->c, &m, 1, NULL))) {
            fail = server_fail(k, "bench: update", rc);
            break;
        }
        edits++;
        next += 1.0 / edit_rate;
        double sl = next - now_s();
        if (sl > 0) usleep((useconds_t)(sl * 1e6));
    }
    double elapsed = now_s() - t0;
    /* one way out: the viewers stopped and joined, the entity taken away */
    atomic_store(&stop, true);
    for (size_t i = 0; i < started; i++) pthread_join(vs[i].th, NULL);
    vtc_remove(k->c, &id, 1, NULL);
    double *rates = fail ? NULL : calloc((size_t)viewers, sizeof *rates), *gaps = NULL;
    if (!fail && !rates) fail = (fprintf(stderr, "%s: out of memory\n", g_prog), 1);
    if (fail) {
        for (size_t i = 0; vs && i < started; i++) free(vs[i].gaps);
        free(vs);
        return fail;
    }

    /* per viewer: frames/s over the run; pooled intervals */
    size_t ngaps = 0, total_frames = 0;
    double render = 0, encode = 0;
    int failed = 0;
    for (uint64_t i = 0; i < viewers; i++) {
        viewer *v = &vs[i];
        if (v->rc) {
            fprintf(stderr, "%s: viewer %" PRIu64 ": error %d: %s\n", g_prog, i, v->rc, v->err);
            failed++;
        }
        rates[i] = v->frames / elapsed;
        total_frames += v->frames;
        render += v->render_ms;
        encode += v->encode_ms;
        double *g = realloc(gaps, (ngaps + v->ngaps + 1) * sizeof *g);
        if (g) {
            gaps = g;
            memcpy(gaps + ngaps, v->gaps, v->ngaps * sizeof *gaps);
            ngaps += v->ngaps;
        }
    }
    for (size_t i = (size_t)viewers; i < n; i++)
        if (vs[i].rc) fprintf(stderr, "%s: stalled viewer: error %d: %s\n", g_prog, vs[i].rc, vs[i].err), failed++;
    qsort(rates, (size_t)viewers, sizeof *rates, cmp_dbl);
    if (gaps) qsort(gaps, ngaps, sizeof *gaps, cmp_dbl);
#define GAP(q) (ngaps ? gaps[(size_t)((q) * (ngaps - 1))] : 0.0)
    double mean_render = total_frames ? render / total_frames : 0, mean_encode = total_frames ? encode / total_frames : 0;
    if (json)
        printf("{\"test\":\"frames\",\"width\":%u,\"height\":%u,\"viewers\":%" PRIu64 ",\"stalled\":%" PRIu64 ",\"max_fps\":%" PRIu64 ","
               "\"edits_per_s\":%.1f,\"seconds\":%.2f,\"fps_min\":%.2f,\"fps_median\":%.2f,\"fps_max\":%.2f,"
               "\"gap_p50_ms\":%.2f,\"gap_p99_ms\":%.2f,\"gap_max_ms\":%.2f,\"render_ms\":%.2f,\"encode_ms\":%.2f}\n",
               w, h, viewers, stalled, fps, edits / elapsed, elapsed, rates[0], rates[viewers / 2],
               rates[viewers - 1], GAP(0.5), GAP(0.99), GAP(1.0), mean_render, mean_encode);
    else
        printf("frames %ux%u JPEG q%" PRIu64 ": %" PRIu64 " viewers (+%" PRIu64 " stalled), %.0f edits/s for %.1f s: frames/s per viewer "
               "min %.1f, median %.1f, max %.1f; interval p50 %.1f ms, p99 %.1f ms, max %.1f ms; server render %.2f "
               "ms, encode %.2f ms a frame\n",
               w, h, quality, viewers, stalled, edits / elapsed, elapsed, rates[0], rates[viewers / 2],
               rates[viewers - 1], GAP(0.5), GAP(0.99), GAP(1.0), mean_render, mean_encode);
    for (size_t i = 0; i < n; i++) free(vs[i].gaps);
    free(vs);
    free(rates);
    free(gaps);
    return failed ? 1 : 0;
}
