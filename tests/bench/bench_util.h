/*
 * bench_util.h — what the benchmarks share: a monotonic clock, a qsort
 * comparison for medians, and a seeded splitmix64 stream (the same
 * generator as tests/test_util.h's rng, without cmocka).
 */
#ifndef VANTAGE_BENCH_UTIL_H
#define VANTAGE_BENCH_UTIL_H

#include <stdint.h>
#include <time.h>

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

/* Uniform in [0, 1), the same sequence every run. */
static inline double bench_frand(void)
{
    static uint64_t state = 0x5EED2011;
    uint64_t z = (state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return (double)((z ^ (z >> 31)) >> 11) * 0x1p-53;
}

#endif
