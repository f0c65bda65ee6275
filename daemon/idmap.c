/*
 * idmap.c — see idmap.h.
 */
#include "idmap.h"
#include "vp_grow.h"

#include <stdlib.h>

static size_t hash64(uint64_t k, size_t mask)
{
    k ^= k >> 33;
    k *= 0xff51afd7ed558ccdull;
    k ^= k >> 33;
    k *= 0xc4ceb9fe1a85ec53ull;
    k ^= k >> 33;
    return (size_t)k & mask;
}

void idmap_free(idmap *m)
{
    free(m->keys);
    free(m->vals);
    free(m->used);
    *m = (idmap){0};
}

static void put_nogrow(idmap *m, uint64_t key, uint64_t val)
{
    size_t mask = m->cap - 1, i = hash64(key, mask);
    while (m->used[i] && m->keys[i] != key) i = (i + 1) & mask;
    if (!m->used[i]) m->count++;
    m->used[i] = 1;
    m->keys[i] = key;
    m->vals[i] = val;
}

bool idmap_reserve(idmap *m, size_t need)
{
    if (need <= m->cap / 2) return true;
    /* at most half full; a power of two (the probe masks with cap - 1) */
    size_t cap = vp_grow_cap(m->cap, need <= SIZE_MAX / 2 ? need * 2 : SIZE_MAX, 64,
                             sizeof *m->keys + sizeof *m->vals + 1, SIZE_MAX);
    if (!cap) return false;
    idmap n = {.cap = cap};
    n.keys = malloc(cap * sizeof *n.keys);
    n.vals = malloc(cap * sizeof *n.vals);
    n.used = calloc(cap, 1);
    if (!n.keys || !n.vals || !n.used) {
        idmap_free(&n);
        return false;
    }
    for (size_t i = 0; i < m->cap; i++)
        if (m->used[i]) put_nogrow(&n, m->keys[i], m->vals[i]);
    idmap_free(m);
    *m = n;
    return true;
}

bool idmap_get(const idmap *m, uint64_t key, uint64_t *val)
{
    if (!m->cap) return false;
    size_t mask = m->cap - 1;
    for (size_t i = hash64(key, mask); m->used[i]; i = (i + 1) & mask) {
        if (m->keys[i] == key) {
            if (val) *val = m->vals[i];
            return true;
        }
    }
    return false;
}

void idmap_put(idmap *m, uint64_t key, uint64_t val)
{
    put_nogrow(m, key, val);
}

bool idmap_del(idmap *m, uint64_t key)
{
    if (!m->cap) return false;
    size_t mask = m->cap - 1, i = hash64(key, mask);
    while (m->used[i] && m->keys[i] != key) i = (i + 1) & mask;
    if (!m->used[i]) return false;
    m->used[i] = 0;
    m->count--;
    for (size_t j = (i + 1) & mask; m->used[j]; j = (j + 1) & mask) {
        size_t home = hash64(m->keys[j], mask);
        bool stays = (i <= j) ? (home > i && home <= j) : (home > i || home <= j);
        if (!stays) {
            m->used[i] = 1;
            m->keys[i] = m->keys[j];
            m->vals[i] = m->vals[j];
            m->used[j] = 0;
            i = j;
        }
    }
    return true;
}
