/*
 * idmap.h — open-addressing hash map from a 64-bit id to a 64-bit value
 * (the daemon maps editor ids to handles, occluders and lights). Linear
 * probing, backward-shift deletion, load <= 1/2. Id 0 is allowed: a
 * separate "used" bitmap marks slots.
 */
#ifndef VANTAGE_IDMAP_H
#define VANTAGE_IDMAP_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

typedef struct idmap {
    uint64_t *keys, *vals;
    uint8_t  *used;
    size_t    cap, count;
} idmap;

void idmap_free(idmap *m);
/* Room for `need` entries without rehashing; false on allocation failure
 * (the map is unchanged). */
bool idmap_reserve(idmap *m, size_t need);
bool idmap_get(const idmap *m, uint64_t key, uint64_t *val);
/* Inserts or replaces; the caller reserved room. */
void idmap_put(idmap *m, uint64_t key, uint64_t val);
bool idmap_del(idmap *m, uint64_t key);
/* Iteration: slots 0..cap-1 where used[i]. */

#endif
