/*
 * bench_destruct.c — destruction distance volumes: an 8^3 field over a
 * 20 x 12 x 20 m box rebuilt from 64 spheres, and one sphere folded in,
 * medians of many runs (this machine: see BENCHMARKS.md).
 *
 *   bench_destruct [--reps N] [--res R] [--spheres S] [--port P]
 *
 * With --port, against a running vantaged with the demo city: for each of
 * the first 100 buildings, a destruction sphere on its -z face, then a
 * query of a view looking at it: the time from sending DESTROY to the
 * query's reply (the hole in the next query), and the server's own time.
 */
#include "bench_util.h"
#include "culling.h"
#include "vantage.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int main(int argc, char **argv)
{
    int reps = 2001, port = 0;
    uint32_t res = 8, ns = 64;
    for (int i = 1; i + 1 < argc; i += 2) {
        if (!strcmp(argv[i], "--port")) port = atoi(argv[i + 1]);
        else if (!strcmp(argv[i], "--reps")) reps = atoi(argv[i + 1]);
        else if (!strcmp(argv[i], "--res")) res = (uint32_t)atoi(argv[i + 1]);
        else if (!strcmp(argv[i], "--spheres")) ns = (uint32_t)atoi(argv[i + 1]);
    }
    if (reps < 1 || res < 2 || !ns) {
        fprintf(stderr, "usage: bench_destruct [--reps N] [--res R] [--spheres S]\n");
        return 2;
    }
    double lo[3] = {100, 0, -40}, hi[3] = {120, 12, -20};
    cull_dvol v;
    if (cull_dvol_init(&v, lo, hi, res)) return 1;
    for (uint32_t k = 0; k < ns; k++) {
        double c[3] = {lo[0] + 20 * bench_frand(), 12 * bench_frand(), lo[2] + 20 * bench_frand()};
        if (cull_dvol_add_sphere(&v, c, 0.5 + 3 * bench_frand())) return 1;
    }
    double *t = malloc((size_t)reps * sizeof *t), *u = malloc((size_t)reps * sizeof *u);
    volatile float sink = 0;
    for (int r = 0; r < reps; r++) {
        double t0 = bench_now_ns();
        cull_dvol_rebuild(&v);
        double t1 = bench_now_ns();
        sink += v.d[r % (res * res * res)];
        t[r] = (t1 - t0) / 1e3;
    }
    cull_dvol w;
    cull_dvol_init(&w, lo, hi, res);
    for (int r = 0; r < reps; r++) {
        double c[3] = {110, 6, -30};
        if (w.nsph == CULL_DVOL_MAX_SPHERES) {
            cull_dvol_free(&w);
            cull_dvol_init(&w, lo, hi, res);
        }
        double t0 = bench_now_ns();
        cull_dvol_add_sphere(&w, c, 2);
        u[r] = (bench_now_ns() - t0) / 1e3;
    }
    qsort(t, (size_t)reps, sizeof *t, bench_cmp_d);
    qsort(u, (size_t)reps, sizeof *u, bench_cmp_d);
    printf("distance volume %u^3 from %u spheres: rebuild median %.2f us (p90 %.2f), one sphere folded in %.3f us; "
           "%d reps\n",
           res, ns, t[reps / 2], t[(size_t)(0.9 * reps)], u[reps / 2], reps);
    (void)sink;
    if (port) {
        vtc_client *c;
        char err[256];
        if (vtc_connect(&(vtc_connect_opts){.port = port, .role = VP_ROLE_EDITOR, .name = "bench_destruct"}, &c, err,
                        sizeof err)) {
            fprintf(stderr, "bench_destruct: %s\n", err);
            return 3;
        }
        double lat[100], srv[100];
        int n = 0;
        for (uint64_t id = 1; id <= 100; id++) {
            vp_list_reply lr;
            vp_entity e;
            if (vtc_get(c, &id, 1, &lr) || vp_entity_get(&lr.batch, 0, &e) || e.class_id != 1) continue;
            double face[3] = {0.5 * (e.aabb[0] + e.aabb[3]), 0.5 * (e.aabb[1] + e.aabb[4]), e.aabb[2]};
            double eye[3] = {face[0], face[1], face[2] - 40}, up[3] = {0, 1, 0};
            vp_view view;
            vtc_view_perspective(&view, eye, face, up, 60, 1280, 720, 0.5, 2000);
            vp_destroy m = {.id = id, .center = {face[0], face[1], face[2]}, .radius = 3};
            vp_destroyed out;
            vp_vis_result r;
            double t0 = bench_now_ns();
            if (vtc_send_destruction(c, &m, &out) || vtc_query(c, &view, 1, 0, 0, &r)) {
                fprintf(stderr, "bench_destruct: %s\n", vtc_last_error(c)->msg);
                return 1;
            }
            lat[n] = (bench_now_ns() - t0) / 1e3;
            srv[n++] = out.cut_us;
        }
        qsort(lat, (size_t)n, sizeof *lat, bench_cmp_d);
        qsort(srv, (size_t)n, sizeof *srv, bench_cmp_d);
        if (n)
            printf("destruction to the next query (%d buildings): median %.0f us, max %.0f us; the server's cut "
                   "median %.0f us, max %.0f us\n",
                   n, lat[n / 2], lat[n - 1], srv[n / 2], srv[n - 1]);
        vtc_close(c);
    }
    cull_dvol_free(&v);
    cull_dvol_free(&w);
    free(t);
    free(u);
    return 0;
}
