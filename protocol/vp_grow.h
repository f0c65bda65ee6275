/*
 * vp_grow.h — the one rule by which an array grows, with its overflow
 * guard. Header-only (static inline, libc only): the culling core, the
 * renderer, the daemon and the client include it without linking the
 * protocol library. It sits in protocol/ beside vp_bytes.h, whose growing
 * writer uses it, because every part's build already has protocol/ on its
 * include path.
 *
 * The rule: the capacity doubles (from `first` when it is 0) until it holds
 * what is needed, so n appends cost O(n) copies in all. The guard: a
 * capacity whose doubling would pass the caller's maximum, or whose size in
 * bytes would pass SIZE_MAX, is refused: the call fails and leaves the
 * array as it was, where an unguarded `while (cap < need) cap *= 2` wraps
 * to 0 and spins, or wraps the byte count and allocates a small block that
 * is then written past its end. Capacities stay powers of two times
 * `first`, so hash tables that mask with cap - 1 may use it too.
 */
#ifndef VANTAGE_VP_GROW_H
#define VANTAGE_VP_GROW_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>

/* The capacity, in elements of elem bytes, that holds need: cap itself when
 * it does, else cap (first when cap is 0, even for need 0: a table's first
 * size) doubled until it holds need. 0 only when refused: the doubling
 * would pass max elements, or the byte size SIZE_MAX. first > 0; elem > 0. */
static inline size_t vp_grow_cap(size_t cap, size_t need, size_t first, size_t elem, size_t max)
{
    if (cap && need <= cap) return cap;
    size_t lim = SIZE_MAX / elem;
    if (max < lim) lim = max;
    if (need > lim) return 0;
    size_t c = cap ? cap : first;
    if (c > lim) return 0; /* a first capacity already past the limit */
    while (c < need) {
        if (c > lim / 2) return 0; /* doubling would pass the limit (or wrap) */
        c *= 2;
    }
    return c;
}

/* Makes the heap array *p (elements of elem bytes, capacity *cap) hold at
 * least need elements, realloc'ing it: true with *p and *cap updated, or
 * false with both as they were (out of memory, or past the guard). */
static inline bool vp_grow(void **p, size_t *cap, size_t need, size_t elem)
{
    size_t c = vp_grow_cap(*cap, need, 8, elem, SIZE_MAX);
    if (!c) return false;
    if (c == *cap) return true;
    void *q = realloc(*p, c * elem);
    if (!q) return false;
    *p = q;
    *cap = c;
    return true;
}

/* vp_grow for a uint32_t capacity (the culling core's and the importer's
 * counts): at most 2^31 elements, so the capacity and every count below
 * it fit. */
static inline bool vp_grow32(void **p, uint32_t *cap, size_t need, size_t elem)
{
    size_t c = vp_grow_cap(*cap, need, 8, elem, (size_t)1 << 31);
    if (!c) return false;
    if (c == *cap) return true;
    void *q = realloc(*p, c * elem);
    if (!q) return false;
    *p = q;
    *cap = (uint32_t)c;
    return true;
}

#endif
