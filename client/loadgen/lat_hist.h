/*
 * lat_hist.h — a latency histogram with log buckets in the manner of Gil Tene's
 * HdrHistogram: every octave of values is cut into SCN_HIST_SUB linear buckets,
 * so a recorded value is known to within half a bucket, 1/(2 SCN_HIST_SUB) of
 * itself (0.39 %), from 1 ns to 2^40 ns (18 minutes) in 35 KiB, with O(1)
 * recording and no allocation after init. Values are nanoseconds (any
 * unsigned unit works). Not thread-safe: one per thread, merged after.
 */
#ifndef VANTAGE_LAT_HIST_H
#define VANTAGE_LAT_HIST_H

#include <stdbool.h>
#include <stdint.h>

#define SCN_HIST_SUB_BITS 7u
#define SCN_HIST_SUB (1u << SCN_HIST_SUB_BITS) /* buckets per octave */
#define SCN_HIST_MAX_BITS 40u /* values >= 2^40 are clamped (counted in .clamped) */
#define SCN_HIST_BUCKETS ((SCN_HIST_MAX_BITS - SCN_HIST_SUB_BITS + 1u) * SCN_HIST_SUB)

typedef struct scn_hist {
    uint64_t count, clamped; /* values recorded; of them, above the range */
    uint64_t min, max;       /* exact, as recorded (max clamped too) */
    double   sum;            /* for the mean */
    uint32_t counts[SCN_HIST_BUCKETS];
} scn_hist;

void scn_hist_init(scn_hist *h);
void scn_hist_record(scn_hist *h, uint64_t v);
/* Records v as if it were n values (n >= 1). */
void scn_hist_record_n(scn_hist *h, uint64_t v, uint32_t n);
/* into += from. */
void scn_hist_merge(scn_hist *into, const scn_hist *from);
/* The value at percentile q (0..100): the smallest recorded-bucket value
 * v such that at least q % of the values are <= v, reported as the middle
 * of its bucket (exact below SCN_HIST_SUB), kept inside [min, max]. 0 when
 * empty. q = 100 is max, q = 0 is min. */
uint64_t scn_hist_percentile(const scn_hist *h, double q);
double scn_hist_mean(const scn_hist *h);

/* Bucket arithmetic, exposed for the tests: the index of v, and the
 * lowest value and the width of bucket i. */
uint32_t scn_hist_index(uint64_t v);
uint64_t scn_hist_bucket_low(uint32_t i);
uint64_t scn_hist_bucket_width(uint32_t i);

#endif
