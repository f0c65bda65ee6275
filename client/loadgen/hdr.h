/*
 * hdr.h — a latency histogram with log buckets in the manner of Gil Tene's
 * HdrHistogram: every octave of values is cut into HDR_SUB linear buckets,
 * so a recorded value is known to within half a bucket, 1/(2 HDR_SUB) of
 * itself (0.39 %), from 1 ns to 2^40 ns (18 minutes) in 35 KiB, with O(1)
 * recording and no allocation after init. Values are nanoseconds (any
 * unsigned unit works). Not thread-safe: one per thread, merged after.
 */
#ifndef VANTAGE_HDR_H
#define VANTAGE_HDR_H

#include <stdbool.h>
#include <stdint.h>

#define HDR_SUB_BITS 7u
#define HDR_SUB (1u << HDR_SUB_BITS)      /* buckets per octave */
#define HDR_MAX_BITS 40u                  /* values >= 2^40 are clamped (counted in .clamped) */
#define HDR_BUCKETS ((HDR_MAX_BITS - HDR_SUB_BITS + 1u) * HDR_SUB)

typedef struct hdr {
    uint64_t count, clamped; /* values recorded; of them, above the range */
    uint64_t min, max;       /* exact, as recorded (max clamped too) */
    double   sum;            /* for the mean */
    uint32_t counts[HDR_BUCKETS];
} hdr;

void hdr_init(hdr *h);
void hdr_record(hdr *h, uint64_t v);
/* Records v as if it were n values (n >= 1). */
void hdr_record_n(hdr *h, uint64_t v, uint32_t n);
/* into += from. */
void hdr_merge(hdr *into, const hdr *from);
/* The value at percentile q (0..100): the smallest recorded-bucket value
 * v such that at least q % of the values are <= v, reported as the middle
 * of its bucket (exact below HDR_SUB), kept inside [min, max]. 0 when
 * empty. q = 100 is max, q = 0 is min. */
uint64_t hdr_percentile(const hdr *h, double q);
double hdr_mean(const hdr *h);

/* Bucket arithmetic, exposed for the tests: the index of v, and the
 * lowest value and the width of bucket i. */
uint32_t hdr_index(uint64_t v);
uint64_t hdr_bucket_low(uint32_t i);
uint64_t hdr_bucket_width(uint32_t i);

#endif
