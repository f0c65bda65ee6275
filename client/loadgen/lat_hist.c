/*
 * lat_hist.c — the log-bucket latency histogram (lat_hist.h).
 *
 * Index of v: below 2^(S+1) the value itself (buckets of width 1); above,
 * with m the top bit of v, the top S+1 bits t = v >> (m - S) in
 * [2^S, 2^(S+1)) and index (m - S) 2^S + t, so each octave [2^m, 2^(m+1))
 * gets 2^S buckets of width 2^(m-S) and the indices run on without gaps.
 */
#include "lat_hist.h"

#include <string.h>

void scn_hist_init(scn_hist *h)
{
    memset(h, 0, sizeof *h);
    h->min = UINT64_MAX;
}

uint32_t scn_hist_index(uint64_t v)
{
    if (v < (2ull << SCN_HIST_SUB_BITS)) return (uint32_t)v;
    unsigned m = 63u - (unsigned)__builtin_clzll(v);
    unsigned shift = m - SCN_HIST_SUB_BITS;
    return (uint32_t)((uint64_t)shift * SCN_HIST_SUB + (v >> shift));
}

uint64_t scn_hist_bucket_low(uint32_t i)
{
    if (i < (2u << SCN_HIST_SUB_BITS)) return i;
    unsigned shift = (i >> SCN_HIST_SUB_BITS) - 1u;
    return (uint64_t)(i - shift * SCN_HIST_SUB) << shift;
}

uint64_t scn_hist_bucket_width(uint32_t i)
{
    if (i < (2u << SCN_HIST_SUB_BITS)) return 1;
    return 1ull << ((i >> SCN_HIST_SUB_BITS) - 1u);
}

void scn_hist_record_n(scn_hist *h, uint64_t v, uint32_t n)
{
    if (n == 0) return;
    const uint64_t top = (1ull << SCN_HIST_MAX_BITS) - 1;
    if (v > top) {
        v = top;
        h->clamped += n;
    }
    h->counts[scn_hist_index(v)] += n;
    h->count += n;
    h->sum += (double)v * n;
    if (v < h->min) h->min = v;
    if (v > h->max) h->max = v;
}

void scn_hist_record(scn_hist *h, uint64_t v)
{
    scn_hist_record_n(h, v, 1);
}

void scn_hist_merge(scn_hist *into, const scn_hist *from)
{
    if (!from->count) return;
    for (uint32_t i = 0; i < SCN_HIST_BUCKETS; i++) into->counts[i] += from->counts[i];
    into->count += from->count;
    into->clamped += from->clamped;
    into->sum += from->sum;
    if (from->min < into->min) into->min = from->min;
    if (from->max > into->max) into->max = from->max;
}

uint64_t scn_hist_percentile(const scn_hist *h, double q)
{
    if (!h->count) return 0;
    if (!(q > 0)) return h->min;
    if (q >= 100) return h->max;
    /* the rank of the value asked for, 1-based: ceil(q/100 n), at least 1 */
    double r = q / 100.0 * (double)h->count;
    uint64_t rank = (uint64_t)r;
    if ((double)rank < r) rank++;
    if (rank < 1) rank = 1;
    uint64_t seen = 0;
    for (uint32_t i = 0; i < SCN_HIST_BUCKETS; i++) {
        seen += h->counts[i];
        if (seen >= rank) {
            uint64_t v = scn_hist_bucket_low(i) + scn_hist_bucket_width(i) / 2;
            if (v < h->min) v = h->min;
            if (v > h->max) v = h->max;
            return v;
        }
    }
    return h->max;
}

double scn_hist_mean(const scn_hist *h)
{
    return h->count ? h->sum / (double)h->count : 0.0;
}
