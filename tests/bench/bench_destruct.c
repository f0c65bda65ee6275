/*
 * bench_destruct.c — destruction distance volumes: an 8^3 field over a
 * 20 x 12 x 20 m box rebuilt from 64 spheres, and one sphere folded in,
 * medians of many runs (this machine: see BENCHMARKS.md).
 *
 *   bench_destruct [--reps N] [--res R] [--spheres S]
 */
#include "bench_util.h"
#include "culling.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int main(int argc, char **argv)
{
    int reps = 2001;
    uint32_t res = 8, ns = 64;
    for (int i = 1; i + 1 < argc; i += 2) {
        if (!strcmp(argv[i], "--reps")) reps = atoi(argv[i + 1]);
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
    cull_dvol_free(&v);
    cull_dvol_free(&w);
    free(t);
    free(u);
    return 0;
}
