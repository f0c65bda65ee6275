/*
 * cull_world.c — scene storage for culling: handles, the two grids, cells
 * and SoA blocks; add, update and remove in O(1).
 *
 * Every edit validates first and allocates before it changes anything, so a
 * failed call leaves the world exactly as it was. Removal swaps the cell's
 * last entity into the hole and fixes that entity's slot (its handle is
 * unchanged). A cell that empties is removed from its grid (swap with the
 * last cell) and freed; its blocks go to a pool for reuse.
 */
#include "cull_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

const char *cull_strerror(int code)
{
    switch (code) {
#define CULL_X_STR(name, value, msg) case value: return msg;
        CULL_ERRORS(CULL_X_STR)
#undef CULL_X_STR
    }
    return "unknown error";
}

float cull_round_down(double v)
{
    float f = (float)v;
    if ((double)f > v) f = nextafterf(f, -INFINITY);
    return f;
}

float cull_round_up(double v)
{
    float f = (float)v;
    if ((double)f < v) f = nextafterf(f, INFINITY);
    return f;
}

static bool grow(void **p, uint32_t *cap, uint32_t need, size_t elem)
{
    if (need <= *cap) return true;
    uint32_t n = *cap ? *cap : 16;
    while (n < need) n *= 2;
    void *q = realloc(*p, (size_t)n * elem);
    if (!q) return false;
    *p = q;
    *cap = n;
    return true;
}

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
    *out = w;
    return CULL_OK;
}

static void cell_free(cull_cell *c)
{
    if (!c) return;
    for (uint32_t i = 0; i < c->nblocks; i++) free(c->blocks[i]);
    free(c->blocks);
    free(c);
}

void cull_world_destroy(cull_world *w)
{
    if (!w) return;
    for (int g = 0; g < 2; g++) {
        for (uint32_t i = 0; i < w->grid[g].ncells; i++) cell_free(w->grid[g].cells[i]);
        free(w->grid[g].cells);
        free(w->grid[g].map);
        free(w->grid[g].soa);
    }
    for (uint32_t i = 0; i < w->npool; i++) free(w->block_pool[i]);
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

/* ---- grid hash map -------------------------------------------------------- */

static uint32_t key_hash(const int32_t k[3])
{
    uint64_t h = (uint64_t)(uint32_t)k[0] * 0x9E3779B97F4A7C15ull;
    h ^= (uint64_t)(uint32_t)k[1] * 0xC2B2AE3D27D4EB4Full;
    h ^= (uint64_t)(uint32_t)k[2] * 0x165667B19E3779F9ull;
    h ^= h >> 29;
    return (uint32_t)(h ^ (h >> 32));
}

static bool key_eq(const int32_t a[3], const int32_t b[3])
{
    return a[0] == b[0] && a[1] == b[1] && a[2] == b[2];
}

static cull_cell *map_find(const cull_grid *g, const int32_t k[3])
{
    if (!g->map_cap) return NULL;
    uint32_t m = g->map_cap - 1;
    for (uint32_t i = key_hash(k) & m;; i = (i + 1) & m) {
        cull_cell *c = g->map[i];
        if (!c) return NULL;
        if (key_eq(c->key, k)) return c;
    }
}

static void map_insert_nogrow(cull_grid *g, cull_cell *c)
{
    uint32_t m = g->map_cap - 1;
    uint32_t i = key_hash(c->key) & m;
    while (g->map[i]) i = (i + 1) & m;
    g->map[i] = c;
    g->map_used++;
}

static bool map_reserve(cull_grid *g, uint32_t need)
{
    if ((uint64_t)need * 2 <= g->map_cap) return true;
    uint32_t cap = g->map_cap ? g->map_cap : 64;
    while ((uint64_t)need * 2 > cap) cap *= 2;
    cull_cell **old = g->map;
    uint32_t old_cap = g->map_cap;
    g->map = calloc(cap, sizeof *g->map);
    if (!g->map) {
        g->map = old;
        return false;
    }
    g->map_cap = cap;
    g->map_used = 0;
    for (uint32_t i = 0; i < old_cap; i++)
        if (old[i]) map_insert_nogrow(g, old[i]);
    free(old);
    return true;
}

/* Backward-shift deletion keeps probe chains intact without tombstones. */
static void map_erase(cull_grid *g, const cull_cell *c)
{
    uint32_t m = g->map_cap - 1;
    uint32_t i = key_hash(c->key) & m;
    while (g->map[i] != c) i = (i + 1) & m;
    g->map[i] = NULL;
    g->map_used--;
    for (uint32_t j = (i + 1) & m; g->map[j]; j = (j + 1) & m) {
        uint32_t home = key_hash(g->map[j]->key) & m;
        /* move j back to i if its home is not in (i, j] cyclically */
        bool between = (i <= j) ? (home > i && home <= j) : (home > i || home <= j);
        if (!between) {
            g->map[i] = g->map[j];
            g->map[j] = NULL;
            i = j;
        }
    }
}

/* ---- cell bounds arrays ---------------------------------------------------- */

static bool soa_reserve(cull_grid *g, uint32_t need)
{
    need = (need + 3u) & ~3u;
    if (need <= g->soa_cap) return true;
    uint32_t cap = g->soa_cap ? g->soa_cap : 64;
    while (cap < need) cap *= 2;
    double *n = calloc((size_t)cap * 6, sizeof *n);
    if (!n) return false;
    for (int k = 0; k < 6 && g->soa; k++)
        memcpy(n + (size_t)k * cap, g->soa + (size_t)k * g->soa_cap, g->ncells * sizeof *n);
    free(g->soa);
    g->soa = n;
    g->soa_cap = cap;
    return true;
}

void cull_cell_sync(cull_world *w, const cull_cell *c)
{
    cull_grid *g = &w->grid[c->grid];
    for (int a = 0; a < 3; a++) {
        double lo = c->bmin[a], hi = c->bmax[a];
        if (!(lo <= hi)) lo = hi = 0; /* empty: a point at the origin, never
                                          queried (empty cells are freed) */
        CULL_SOA(g, a)[c->index] = c->origin[a] + 0.5 * (lo + hi);
        CULL_SOA(g, 3 + a)[c->index] = 0.5 * (hi - lo);
    }
}

/* ---- cells and blocks -------------------------------------------------------- */

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

static void empty_bounds(cull_cell *c)
{
    for (int a = 0; a < 3; a++) {
        c->bmin[a] = INFINITY;
        c->bmax[a] = -INFINITY;
    }
}

/* Makes sure the grid can take one more cell and the cell one more entity
 * without any allocation failing later in the edit. Returns the existing
 * cell or NULL with *need_cell set. */
static int reserve_slot_in(cull_world *w, uint32_t gi, const int32_t k[3], cull_cell **out)
{
    cull_grid *g = &w->grid[gi];
    cull_cell *c = map_find(g, k);
    if (!c) {
        if (!map_reserve(g, g->map_used + 1)) return CULL_ERR_NOMEM;
        if (!grow((void **)&g->cells, &g->cap_cells, g->ncells + 1, sizeof *g->cells) ||
            !soa_reserve(g, g->ncells + 1))
            return CULL_ERR_NOMEM;
        c = calloc(1, sizeof *c);
        if (!c) return CULL_ERR_NOMEM;
        memcpy(c->key, k, sizeof c->key);
        c->grid = gi;
        for (int a = 0; a < 3; a++) c->origin[a] = (double)k[a] * w->cell_size;
        empty_bounds(c);
        c->index = g->ncells;
        g->cells[g->ncells++] = c;
        map_insert_nogrow(g, c);
    }
    *out = c;
    if (c->count == c->nblocks * CULL_BLOCK_CAP) {
        if (!grow((void **)&c->blocks, &c->cap_blocks, c->nblocks + 1, sizeof *c->blocks))
            goto fail;
        cull_block *b;
        if (w->npool) {
            b = w->block_pool[--w->npool];
        } else {
            b = aligned_alloc(64, sizeof(cull_block));
            if (!b) goto fail;
        }
        memset(b, 0, sizeof *b);
        c->blocks[c->nblocks++] = b;
        w->nblocks_total++;
    }
    return CULL_OK;
fail:
    if (c->count == 0 && c->nblocks == 0) {
        /* a cell we just created: take it out again */
        g->ncells--;
        map_erase(g, c);
        free(c->blocks);
        free(c);
        *out = NULL;
    }
    return CULL_ERR_NOMEM;
}

/* Writes entity d (normalised) into lane i of cell c, as floats relative to
 * the cell origin, rounded outward by the documented slack. */
static void store_lane(cull_world *w, cull_cell *c, uint32_t i,
                       const cull_entity_desc *d, cull_handle h)
{
    cull_block *b = c->blocks[i / CULL_BLOCK_CAP];
    uint32_t l = i % CULL_BLOCK_CAP;
    double lc[3], lmin[3], lmax[3], ext = 0;
    for (int a = 0; a < 3; a++) {
        lc[a] = d->center[a] - c->origin[a];
        ext = fmax(ext, fmax(fabs(d->aabb_min[a] - c->origin[a]),
                             fabs(d->aabb_max[a] - c->origin[a])));
    }
    /* covers float rounding in the kernels' plane evaluation (|terms| are
       bounded by the cell size, the radius and the box's reach) */
    double slack = (4.0 * w->cell_size + d->radius + ext) * 0x1p-19;
    for (int a = 0; a < 3; a++) {
        lmin[a] = d->aabb_min[a] - c->origin[a] - slack;
        lmax[a] = d->aabb_max[a] - c->origin[a] + slack;
    }
    b->x[l] = (float)lc[0];
    b->y[l] = (float)lc[1];
    b->z[l] = (float)lc[2];
    /* the centre moved by rounding at most |(double)f - v| per axis */
    double err = fabs((double)b->x[l] - lc[0]) + fabs((double)b->y[l] - lc[1]) +
                 fabs((double)b->z[l] - lc[2]);
    b->r[l] = cull_round_up(d->radius + err + slack);
    b->minx[l] = cull_round_down(lmin[0]);
    b->miny[l] = cull_round_down(lmin[1]);
    b->minz[l] = cull_round_down(lmin[2]);
    b->maxx[l] = cull_round_up(lmax[0]);
    b->maxy[l] = cull_round_up(lmax[1]);
    b->maxz[l] = cull_round_up(lmax[2]);
    b->handle[l] = h;
    b->class_id[l] = d->class_id;
    b->sublevel[l] = d->sublevel;
    /* grow the cell bounds to hold both the sphere and the AABB */
    float smin[3] = {b->x[l] - b->r[l], b->y[l] - b->r[l], b->z[l] - b->r[l]};
    float smax[3] = {b->x[l] + b->r[l], b->y[l] + b->r[l], b->z[l] + b->r[l]};
    float amin[3] = {b->minx[l], b->miny[l], b->minz[l]};
    float amax[3] = {b->maxx[l], b->maxy[l], b->maxz[l]};
    for (int a = 0; a < 3; a++) {
        /* float sums above may round inward by half an ulp: pad one ulp */
        float lo = nextafterf(fminf(smin[a], amin[a]), -INFINITY);
        float hi = nextafterf(fmaxf(smax[a], amax[a]), INFINITY);
        if (lo < c->bmin[a]) c->bmin[a] = lo;
        if (hi > c->bmax[a]) c->bmax[a] = hi;
    }
    cull_cell_sync(w, c);
}

static void copy_lane(cull_cell *c, uint32_t dst, uint32_t src)
{
    cull_block *bd = c->blocks[dst / CULL_BLOCK_CAP], *bs = c->blocks[src / CULL_BLOCK_CAP];
    uint32_t ld = dst % CULL_BLOCK_CAP, ls = src % CULL_BLOCK_CAP;
    bd->x[ld] = bs->x[ls];
    bd->y[ld] = bs->y[ls];
    bd->z[ld] = bs->z[ls];
    bd->r[ld] = bs->r[ls];
    bd->minx[ld] = bs->minx[ls];
    bd->miny[ld] = bs->miny[ls];
    bd->minz[ld] = bs->minz[ls];
    bd->maxx[ld] = bs->maxx[ls];
    bd->maxy[ld] = bs->maxy[ls];
    bd->maxz[ld] = bs->maxz[ls];
    bd->handle[ld] = bs->handle[ls];
    bd->class_id[ld] = bs->class_id[ls];
    bd->sublevel[ld] = bs->sublevel[ls];
}

static void mark_dirty(cull_world *w, cull_cell *c)
{
    if (c->dirty) return;
    /* the dirty list was reserved by the caller; if that failed the bounds
       just stay loose (still correct) */
    if (w->ndirty < w->cap_dirty) {
        c->dirty = true;
        w->dirty[w->ndirty++] = c;
    }
}

static void dirty_forget(cull_world *w, cull_cell *c)
{
    if (!c->dirty) return;
    for (uint32_t i = 0; i < w->ndirty; i++) {
        if (w->dirty[i] == c) {
            w->dirty[i] = w->dirty[--w->ndirty];
            break;
        }
    }
}

/* Removes lane i from cell c by moving the cell's last entity into it. Frees
 * an emptied trailing block and an emptied cell. Never fails. */
static void cell_take_out(cull_world *w, cull_cell *c, uint32_t i)
{
    uint32_t last = c->count - 1;
    if (i != last) {
        copy_lane(c, i, last);
        uint32_t h = c->blocks[i / CULL_BLOCK_CAP]->handle[i % CULL_BLOCK_CAP];
        w->slots[h & CULL_SLOT_MASK].lane = i;
    }
    c->count--;
    w->grid[c->grid].entities--;
    if (c->count <= (c->nblocks - 1) * CULL_BLOCK_CAP && c->nblocks) {
        cull_block *b = c->blocks[--c->nblocks];
        w->nblocks_total--;
        if (w->npool < w->cap_pool) w->block_pool[w->npool++] = b;
        else free(b);
    }
    if (c->count == 0) {
        cull_grid *g = &w->grid[c->grid];
        dirty_forget(w, c);
        map_erase(g, c);
        cull_cell *moved = g->cells[--g->ncells];
        g->cells[c->index] = moved;
        moved->index = c->index;
        cull_cell_sync(w, moved);
        cell_free(c);
    } else {
        mark_dirty(w, c);
    }
}

/* Reserves the bookkeeping a removal may want (block pool, dirty list) so
 * that cell_take_out never allocates. Failure only costs tightness. */
static void reserve_removal(cull_world *w)
{
    (void)grow((void **)&w->block_pool, &w->cap_pool, w->npool + 1, sizeof *w->block_pool);
    (void)grow((void **)&w->dirty, &w->cap_dirty, w->ndirty + 1, sizeof *w->dirty);
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

int cull_entity_add(cull_world *w, const cull_entity_desc *desc, cull_handle *out)
{
    if (!w || !out) return CULL_ERR_INVALID;
    cull_entity_desc d;
    int rc = normalise(desc, &d);
    if (rc) return rc;
    if (w->live >= w->max_entities) return CULL_ERR_CAPACITY;
    uint32_t s = w->free_head;
    if (s == UINT32_MAX) {
        if (w->nslots >= w->max_entities) return CULL_ERR_CAPACITY;
        if (!grow((void **)&w->slots, &w->cap_slots, w->nslots + 1, sizeof *w->slots))
            return CULL_ERR_NOMEM;
    }
    uint32_t gi = (d.flags & CULL_ENTITY_DYNAMIC) ? 1 : 0;
    int32_t k[3];
    if ((rc = cell_key(w, d.center, k))) return rc;
    cull_cell *c;
    rc = reserve_slot_in(w, gi, k, &c);
    if (rc) return rc;
    if (s == UINT32_MAX) {
        s = w->nslots++;
        w->slots[s] = (cull_slot){.gen = 1};
    } else {
        w->free_head = w->slots[s].next_free;
    }
    cull_slot *sl = &w->slots[s];
    cull_handle h = (sl->gen << CULL_HANDLE_SLOT_BITS) | s;
    sl->cell = c;
    sl->lane = c->count++;
    sl->desc = d;
    w->grid[gi].entities++;
    w->live++;
    store_lane(w, c, sl->lane, &d, h);
    *out = h;
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
    reserve_removal(w);
    if (old->grid == gi && key_eq(old->key, k)) {
        /* same cell: overwrite in place; the old bounds may now be loose */
        mark_dirty(w, old);
        store_lane(w, old, sl->lane, &d, h);
        sl->desc = d;
        return CULL_OK;
    }
    cull_cell *c;
    rc = reserve_slot_in(w, gi, k, &c);
    if (rc) return rc;
    uint32_t lane = c->count++;
    w->grid[gi].entities++;
    store_lane(w, c, lane, &d, h);
    cell_take_out(w, old, sl->lane);
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
    reserve_removal(w);
    cell_take_out(w, sl->cell, sl->lane);
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
    if (!w) return;
    for (uint32_t d = 0; d < w->ndirty; d++) {
        cull_cell *c = w->dirty[d];
        c->dirty = false;
        empty_bounds(c);
        for (uint32_t i = 0; i < c->count; i++) {
            const cull_block *b = c->blocks[i / CULL_BLOCK_CAP];
            uint32_t l = i % CULL_BLOCK_CAP;
            float lo[3] = {fminf(b->x[l] - b->r[l], b->minx[l]), fminf(b->y[l] - b->r[l], b->miny[l]),
                           fminf(b->z[l] - b->r[l], b->minz[l])};
            float hi[3] = {fmaxf(b->x[l] + b->r[l], b->maxx[l]), fmaxf(b->y[l] + b->r[l], b->maxy[l]),
                           fmaxf(b->z[l] + b->r[l], b->maxz[l])};
            for (int a = 0; a < 3; a++) {
                lo[a] = nextafterf(lo[a], -INFINITY);
                hi[a] = nextafterf(hi[a], INFINITY);
                if (lo[a] < c->bmin[a]) c->bmin[a] = lo[a];
                if (hi[a] > c->bmax[a]) c->bmax[a] = hi[a];
            }
        }
        cull_cell_sync(w, c);
    }
    w->ndirty = 0;
}

void cull_world_info_get(const cull_world *w, cull_world_info *o)
{
    memset(o, 0, sizeof *o);
    if (!w) return;
    o->entities = w->live;
    o->static_entities = w->grid[0].entities;
    o->dynamic_entities = w->grid[1].entities;
    o->cells = w->grid[0].ncells + w->grid[1].ncells;
    o->blocks = w->nblocks_total;
    o->bytes = sizeof *w + (size_t)w->cap_slots * sizeof(cull_slot) +
               (size_t)(w->nblocks_total + w->npool) * sizeof(cull_block) +
               (size_t)o->cells * sizeof(cull_cell) + (size_t)w->cap_dirty * sizeof(void *);
    for (int g = 0; g < 2; g++)
        o->bytes += ((size_t)w->grid[g].cap_cells + w->grid[g].map_cap) * sizeof(void *);
}

size_t cull_query_bound(const cull_world *w)
{
    return (w ? w->live : 0) + CULL_RESULT_PAD;
}
