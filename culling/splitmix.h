/*
 * splitmix.h — Vigna's splitmix64: the one seeded random stream the
 * daemon (demo city, debris), the load generator, the tests and the
 * benchmarks share. Not for anything secret. Header only.
 */
#ifndef VANTAGE_SPLITMIX_H
#define VANTAGE_SPLITMIX_H

#include <stdint.h>

/* The next 64 bits of the stream *state (seed it with any value). */
static inline uint64_t splitmix64(uint64_t *state)
{
    uint64_t z = (*state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

/* Uniform in [0, 1): the top 53 bits. */
static inline double splitmix_unit(uint64_t *state)
{
    return (double)(splitmix64(state) >> 11) * 0x1p-53;
}

#endif
