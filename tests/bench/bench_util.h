/*
 * bench_util.h — what the benchmarks share: a monotonic clock, a qsort
 * comparison and a median, a strict count for options, and seeded
 * splitmix64 streams (the same generator as tests/test_util.h's rng,
 * without cmocka).
 */
#ifndef VANTAGE_BENCH_UTIL_H
#define VANTAGE_BENCH_UTIL_H

#include <stdbool.h>
#include <stdint.h>
#include <stdlib.h>
#include <time.h>
#include "splitmix.h"

/* A command line's count: decimal digits only, 1 .. UINT32_MAX, into *out;
 * false for anything else (the caller prints its usage). */
static inline bool bench_count(const char *s, uint32_t *out)
{
    uint64_t v = 0;
    if (!s || !*s) return false;
    for (; *s; s++) {
        if (*s < '0' || *s > '9' || (v = v * 10 + (uint64_t)(*s - '0')) > UINT32_MAX) return false;
    }
    if (!v) return false;
    *out = (uint32_t)v;
    return true;
}

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
