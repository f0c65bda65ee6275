/*
 * bench_util.h — what the benchmarks share: a monotonic clock, a qsort
 * comparison and a median, and seeded splitmix64 streams (the same
 * generator as tests/test_util.h's rng, without cmocka).
 */
#ifndef VANTAGE_BENCH_UTIL_H
#define VANTAGE_BENCH_UTIL_H

#include <stdint.h>
#include <stdlib.h>
#include <time.h>
#include "splitmix.h"

static inline double bench_now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec * 1e9 + ts.tv_nsec;
}

static inline int bench_cmp_d(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

/* Sorts v[0..n) and returns its median (the mean of the middle two for
 * even n); n >= 1. */
static inline double bench_median(double *v, int n)
{
    qsort(v, (size_t)n, sizeof *v, bench_cmp_d);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/* Uniform in [0, 1) from the stream *state (seed it with any value). */
static inline double bench_rand01(uint64_t *state)
{
    return splitmix_unit(state);
}

/* Uniform in [0, 1), the same sequence every run. */
static inline double bench_frand(void)
{
    static uint64_t state = 0x5EED2011;
    return bench_rand01(&state);
}

#endif
