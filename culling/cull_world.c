/*
 * cull_world.c — the world's public face: handles (slots with generations),
 * validation of entity descs, add / update / remove in O(1) on top of the
 * grids in cull_grid.c.
 *
 * Every edit validates first and allocates before it changes anything, so a
 * failed call leaves the world exactly as it was. Removal swaps the cell's
 * last entity into the hole and fixes that entity's slot (its handle is
 * unchanged).
 */
#include "cull_internal.h"

#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

VP_ERR_DEFINE_STRERROR(cull_strerror, CULL_ERRORS)

int cull_world_create(const cull_world_desc *desc, cull_world **out)
{
    cull_world_desc d = desc ? *desc : (cull_world_desc){0};
    if (!out) return CULL_ERR_INVALID;
    *out = NULL;
    if (d.cell_size == 0) d.cell_size = 64.0;
    if (d.max_entities == 0) d.max_entities = CULL_MAX_ENTITIES;
    if (!(d.cell_size >= 1e-3 && d.cell_size <= 1e6)) return CULL_ERR_RANGE;
    if (d.max_entities > CULL_MAX_ENTITIES) return CULL_ERR_RANGE;
    cull_world *w = calloc(1, sizeof *w);
    if (!w) return CULL_ERR_NOMEM;
    w->cell_size = d.cell_size;
    w->inv_cell_size = 1.0 / d.cell_size;
    w->max_entities = d.max_entities;
    w->free_head = UINT32_MAX;
    w->ofree_head = UINT32_MAX;
    static _Atomic uint64_t worlds;
    w->occ_version = (atomic_fetch_add(&worlds, 1) + 1) << 40; /* 2^40 edits a world before two could meet */
    w->stamp = w->occ_version;
    *out = w;
    return CULL_OK;
}

void cull_world_destroy(cull_world *w)
{
    if (!w) return;
    for (int g = 0; g < 2; g++) cull_grid_free(&w->grid[g]);
    cull_occluders_free(w);
    for (uint32_t i = 0; i < w->nslabs; i++) free(w->slabs[i]);
    free(w->slabs);
    free(w->block_pool);
    free(w->slots);
    free(w->dirty);
    free(w);
}

/* ---- validation and normalisation ---------------------------------------- */

static bool finite3(const double v[3])
{
    return isfinite(v[0]) && isfinite(v[1]) && isfinite(v[2]);
}

static bool in_range3(const double v[3])
{
    return fabs(v[0]) <= CULL_MAX_COORD && fabs(v[1]) <= CULL_MAX_COORD &&
           fabs(v[2]) <= CULL_MAX_COORD;
}

/* Validates d and fills in the derived sphere or AABB. */
static int normalise(const cull_entity_desc *in, cull_entity_desc *o)
{
    if (!in) return CULL_ERR_INVALID;
    *o = *in;
    if (!finite3(o->center) || !finite3(o->aabb_min) || !finite3(o->aabb_max))
        return CULL_ERR_NONFINITE;
    if (!(o->radius >= 0) || !isfinite(o->radius)) return CULL_ERR_RADIUS;
    if (o->radius > CULL_MAX_RADIUS) return CULL_ERR_RANGE;
    for (int k = 0; k < 3; k++)
        if (o->aabb_min[k] > o->aabb_max[k]) return CULL_ERR_AABB;
    if (!in_range3(o->center) || !in_range3(o->aabb_min) || !in_range3(o->aabb_max))
        return CULL_ERR_RANGE;
    bool box_zero = o->aabb_min[0] == 0 && o->aabb_min[1] == 0 && o->aabb_min[2] == 0 &&
                    o->aabb_max[0] == 0 && o->aabb_max[1] == 0 && o->aabb_max[2] == 0;
    if (o->radius == 0 && !box_zero) {
        double e2 = 0;
        for (int k = 0; k < 3; k++) {
            o->center[k] = 0.5 * (o->aabb_min[k] + o->aabb_max[k]);
            double e = 0.5 * (o->aabb_max[k] - o->aabb_min[k]);
            e2 += e * e;
        }
        o->radius = sqrt(e2);
        if (o->radius > CULL_MAX_RADIUS) return CULL_ERR_RANGE;
    } else if (box_zero) {
        for (int k = 0; k < 3; k++) {
            o->aabb_min[k] = o->center[k] - o->radius;
            o->aabb_max[k] = o->center[k] + o->radius;
        }
    }
    return CULL_OK;
}

/* CULL_ERR_RANGE when a key would not fit in int32. */
static int cell_key(const cull_world *w, const double p[3], int32_t k[3])
{
    for (int a = 0; a < 3; a++) {
        double f = floor(p[a] * w->inv_cell_size);
        if (!(fabs(f) < 2147483000.0)) return CULL_ERR_RANGE;
        k[a] = (int32_t)f;
    }
    return CULL_OK;
}

int cull_entity_check(const cull_world *w, const cull_entity_desc *desc, cull_entity_desc *out)
{
    if (!w) return CULL_ERR_INVALID;
    cull_entity_desc d;
    int rc = normalise(desc, &d);
    if (rc) return rc;
    int32_t k[3];
    if ((rc = cell_key(w, d.center, k))) return rc;
    if (out) *out = d;
    return CULL_OK;
}

static cull_slot *slot_of(const cull_world *w, cull_handle h)
{
    uint32_t s = h & CULL_SLOT_MASK, gen = h >> CULL_HANDLE_SLOT_BITS;
    if (h == 0 || s >= w->nslots) return NULL;
    cull_slot *sl = &w->slots[s];
    if (!sl->cell || sl->gen != gen) return NULL;
    return sl;
}

/* ---- public edits ------------------------------------------------------------ */

/* A slot on no free list, kept for cull_entity_add_at (restored worlds). */
#define SLOT_RESERVED (UINT32_MAX - 1)

/* Puts normalised d into slot s (taken off the free list or reserved by the
 * caller once this succeeds: *take says to do it). */
static int place(cull_world *w, const cull_entity_desc *d, uint32_t s, cull_handle *out)
{
    uint32_t gi = (d->flags & CULL_ENTITY_DYNAMIC) ? 1 : 0;
    int32_t k[3];
    int rc = cell_key(w, d->center, k);
    if (rc) return rc;
    cull_cell *c;
    if ((rc = cull_grid_reserve(w, gi, k, &c))) return rc;
    cull_slot *sl = &w->slots[s];
    cull_handle h = (sl->gen << CULL_HANDLE_SLOT_BITS) | s;
    sl->cell = c;
    sl->lane = c->count++;
    sl->desc = *d;
    w->grid[gi].entities++;
    w->live++;
    cull_grid_store(w, c, sl->lane, d, h);
    *out = h;
    return CULL_OK;
}

int cull_entity_add(cull_world *w, const cull_entity_desc *desc, cull_handle *out)
{
    if (!w || !out) return CULL_ERR_INVALID;
    cull_entity_desc d;
    int rc = normalise(desc, &d);
    if (rc) return rc;
    if (w->live >= w->max_entities) return CULL_ERR_CAPACITY;
    uint32_t s = w->free_head;
    bool fresh = s == UINT32_MAX;
    if (fresh) {
        if (w->nslots >= w->max_entities) return CULL_ERR_CAPACITY;
        if (!vp_grow32((void **)&w->slots, &w->cap_slots, w->nslots + 1, sizeof *w->slots))
            return CULL_ERR_NOMEM;
        s = w->nslots;
        w->slots[s] = (cull_slot){.gen = 1};
    }
    uint32_t next = w->slots[s].next_free;
    if ((rc = place(w, &d, s, out))) return rc;
    if (fresh) w->nslots++;
    else w->free_head = next;
    return CULL_OK;
}

int cull_entity_add_at(cull_world *w, const cull_entity_desc *desc, cull_handle h)
{
    if (!w) return CULL_ERR_INVALID;
    uint32_t s = h & CULL_SLOT_MASK;
    if (s >= w->nslots || w->slots[s].cell || w->slots[s].next_free != SLOT_RESERVED ||
        w->slots[s].gen != h >> CULL_HANDLE_SLOT_BITS)
        return CULL_ERR_HANDLE;
    cull_entity_desc d;
    int rc = normalise(desc, &d);
    if (rc) return rc;
    if (w->live >= w->max_entities) return CULL_ERR_CAPACITY;
    cull_handle got;
    if ((rc = place(w, &d, s, &got))) return rc;
    w->slots[s].next_free = UINT32_MAX;
    return CULL_OK;
}

uint32_t cull_world_slots(const cull_world *w)
{
    return w->nslots;
}

uint32_t cull_world_slot_gen(const cull_world *w, uint32_t s, bool *live)
{
    if (s >= w->nslots) {
        *live = false;
        return 0;
    }
    *live = w->slots[s].cell != NULL;
    return w->slots[s].gen;
}

uint32_t cull_world_free_list(const cull_world *w, uint32_t *out, uint32_t max)
{
    uint32_t n = 0;
    for (uint32_t s = w->free_head; s < w->nslots && n < max; s = w->slots[s].next_free) out[n++] = s;
    return n;
}

int cull_world_slots_restore(cull_world *w, uint32_t n, const uint16_t *gens, const uint32_t *free_list,
                             uint32_t nfree)
{
    if (!w || w->nslots || n > w->max_entities || nfree > n) return CULL_ERR_INVALID;
    for (uint32_t s = 0; s < n; s++)
        if (gens[s] == 0 || gens[s] >= (1u << CULL_GEN_BITS)) return CULL_ERR_INVALID;
    if (n && !vp_grow32((void **)&w->slots, &w->cap_slots, n, sizeof *w->slots)) return CULL_ERR_NOMEM;
    for (uint32_t s = 0; s < n; s++) w->slots[s] = (cull_slot){.gen = gens[s], .next_free = SLOT_RESERVED};
    /* the free list, in the order it hands slots out; a slot twice or out
       of range is a bad image */
    uint32_t head = UINT32_MAX;
    for (uint32_t i = nfree; i-- > 0;) {
        uint32_t s = free_list[i];
        if (s >= n || w->slots[s].next_free != SLOT_RESERVED) {
            memset(w->slots, 0, (size_t)n * sizeof *w->slots);
            return CULL_ERR_INVALID;
        }
        w->slots[s].next_free = head;
        head = s;
    }
    w->nslots = n;
    w->free_head = head;
    return CULL_OK;
}

int cull_entity_update(cull_world *w, cull_handle h, const cull_entity_desc *desc)
{
    if (!w) return CULL_ERR_INVALID;
    cull_slot *sl = slot_of(w, h);
    if (!sl) return CULL_ERR_HANDLE;
    cull_entity_desc d;
    int rc = normalise(desc, &d);
    if (rc) return rc;
    uint32_t gi = (d.flags & CULL_ENTITY_DYNAMIC) ? 1 : 0;
    int32_t k[3];
    if ((rc = cell_key(w, d.center, k))) return rc;
    cull_cell *old = sl->cell;
    cull_grid_reserve_removal(w);
    if (old->grid == gi && old->key[0] == k[0] && old->key[1] == k[1] && old->key[2] == k[2]) {
        /* same cell: overwrite in place; the old bounds may now be loose */
        cull_grid_mark_dirty(w, old);
        cull_grid_store(w, old, sl->lane, &d, h);
        sl->desc = d;
        return CULL_OK;
    }
    cull_cell *c;
    rc = cull_grid_reserve(w, gi, k, &c);
    if (rc) return rc;
    uint32_t lane = c->count++;
    w->grid[gi].entities++;
    cull_grid_store(w, c, lane, &d, h);
    cull_grid_take_out(w, old, sl->lane);
    sl->cell = c;
    sl->lane = lane;
    sl->desc = d;
    return CULL_OK;
}

int cull_entity_remove(cull_world *w, cull_handle h)
{
    if (!w) return CULL_ERR_INVALID;
    cull_slot *sl = slot_of(w, h);
    if (!sl) return CULL_ERR_HANDLE;
    cull_grid_reserve_removal(w);
    cull_grid_take_out(w, sl->cell, sl->lane);
    uint32_t s = h & CULL_SLOT_MASK;
    sl->cell = NULL;
    sl->gen = (sl->gen + 1) & ((1u << CULL_GEN_BITS) - 1);
    if (sl->gen == 0) sl->gen = 1;
    sl->next_free = w->free_head;
    w->free_head = s;
    w->live--;
    return CULL_OK;
}

int cull_entity_get(const cull_world *w, cull_handle h, cull_entity_desc *out)
{
    if (!w || !out) return CULL_ERR_INVALID;
    const cull_slot *sl = slot_of(w, h);
    if (!sl) return CULL_ERR_HANDLE;
    *out = sl->desc;
    return CULL_OK;
}

void cull_world_commit(cull_world *w)
{
    if (w) cull_grid_commit(w);
}

void cull_world_info_get(const cull_world *w, cull_world_info *o)
{
    memset(o, 0, sizeof *o);
    if (!w) return;
    o->entities = w->live;
    o->static_entities = w->grid[0].entities;
    o->dynamic_entities = w->grid[1].entities;
    o->cells = w->grid[0].ncells + w->grid[1].ncells;
    o->regions = w->grid[0].nregions + w->grid[1].nregions;
    o->blocks = w->nblocks_total;
    o->bytes = sizeof *w + (size_t)w->cap_slots * sizeof(cull_slot) +
               w->slab_bytes +
               (size_t)o->cells * (sizeof(cull_cell) + 6 * sizeof(double) + 2 * sizeof(void *)) +
               (size_t)o->regions * (sizeof(cull_region) + 6 * sizeof(double) + 2 * sizeof(void *)) +
               (size_t)w->cap_dirty * sizeof(void *);
}

size_t cull_query_bound(const cull_world *w)
{
    return (w ? w->live : 0) + CULL_RESULT_PAD;
}
