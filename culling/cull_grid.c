/*
 * cull_grid.c — the storage under a world: per grid a hash map of regions
 * (8x8x8 cells) and one of cells, each region a dense list of cells with
 * their bounds in SoA doubles, each cell a list of 64-entity SoA blocks.
 *
 * Edits are O(1): cull_grid_reserve allocates everything an add needs
 * before anything changes (so a failed add changes nothing); a removal
 * moves the cell's last entity into the hole, frees an emptied block (to a
 * pool), cell and region, and never allocates. Bounds only grow on edits;
 * cull_grid_commit tightens the cells and regions edits left loose.
 */
#include "cull_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>

/* ---- hash map of {int32_t key[3], ...} pointers ------------------------------ */

static uint32_t key_hash(const int32_t k[3])
{
    uint64_t h = (uint64_t)(uint32_t)k[0] * 0x9E3779B97F4A7C15ull;
    h ^= (uint64_t)(uint32_t)k[1] * 0xC2B2AE3D27D4EB4Full;
    h ^= (uint64_t)(uint32_t)k[2] * 0x165667B19E3779F9ull;
    h ^= h >> 29;
    return (uint32_t)(h ^ (h >> 32));
}

static const int32_t *key_of(const void *e)
{
    return (const int32_t *)e;
}

static bool key_eq(const int32_t a[3], const int32_t b[3])
{
    return a[0] == b[0] && a[1] == b[1] && a[2] == b[2];
}

static void *map_find(const cull_map *m, const int32_t k[3])
{
    if (!m->cap) return NULL;
    uint32_t mask = m->cap - 1;
    for (uint32_t i = key_hash(k) & mask;; i = (i + 1) & mask) {
        void *e = m->slot[i];
        if (!e || key_eq(key_of(e), k)) return e;
    }
}

static void map_insert_nogrow(cull_map *m, void *e)
{
    uint32_t mask = m->cap - 1, i = key_hash(key_of(e)) & mask;
    while (m->slot[i]) i = (i + 1) & mask;
    m->slot[i] = e;
    m->used++;
}

/* Room for `need` entries at load <= 1/2. */
static bool map_reserve(cull_map *m, uint32_t need)
{
    if ((uint64_t)need * 2 <= m->cap) return true;
    size_t grown = vp_grow_cap(m->cap, (size_t)need * 2, 64, sizeof(void *), (size_t)1 << 31);
    if (!grown) return false;
    uint32_t cap = (uint32_t)grown;
    void **old = m->slot;
    uint32_t old_cap = m->cap;
    void **n = calloc(cap, sizeof *n);
    if (!n) return false;
    m->slot = n;
    m->cap = cap;
    m->used = 0;
    for (uint32_t i = 0; i < old_cap; i++)
        if (old[i]) map_insert_nogrow(m, old[i]);
    free(old);
    return true;
}

/* Backward-shift deletion keeps probe chains intact without tombstones. */
static void map_erase(cull_map *m, const void *e)
{
    uint32_t mask = m->cap - 1, i = key_hash(key_of(e)) & mask;
    while (m->slot[i] != e) i = (i + 1) & mask;
    m->slot[i] = NULL;
    m->used--;
    for (uint32_t j = (i + 1) & mask; m->slot[j]; j = (j + 1) & mask) {
        uint32_t home = key_hash(key_of(m->slot[j])) & mask;
        /* move j back to i unless its home lies cyclically in (i, j] */
        bool stays = (i <= j) ? (home > i && home <= j) : (home > i || home <= j);
        if (!stays) {
            m->slot[i] = m->slot[j];
            m->slot[j] = NULL;
            i = j;
        }
    }
}

/* ---- bounds arrays --------------------------------------------------------------- */

bool cull_soa_reserve(cull_bounds_soa *s, uint32_t count, uint32_t need)
{
    need = (need + 4u) & ~3u; /* whole vectors past the last entry */
    if (need <= s->cap) return true;
    uint32_t cap = (uint32_t)vp_grow_cap(s->cap, need, 8, 6 * sizeof(double), (size_t)1 << 31);
    double *n = cap ? calloc((size_t)cap * 6, sizeof *n) : NULL;
    if (!n) return false;
    for (int k = 0; k < 6 && s->v; k++)
        memcpy(n + (size_t)k * cap, s->v + (size_t)k * s->cap, count * sizeof *n);
    free(s->v);
    s->v = n;
    s->cap = cap;
    return true;
}

void cull_soa_set(cull_bounds_soa *s, uint32_t i, const double lo[3], const double hi[3])
{
    for (int a = 0; a < 3; a++) {
        bool empty = !(lo[a] <= hi[a]); /* never queried: empty boxes are freed */
        CULL_SOA(s, a)[i] = empty ? 0 : 0.5 * (lo[a] + hi[a]);
        CULL_SOA(s, 3 + a)[i] = empty ? 0 : 0.5 * (hi[a] - lo[a]);
    }
}

void cull_soa_copy(cull_bounds_soa *s, uint32_t dst, uint32_t src)
{
    for (int k = 0; k < 6; k++) CULL_SOA(s, k)[dst] = CULL_SOA(s, k)[src];
}

static void cell_world_bounds(const cull_cell *c, double lo[3], double hi[3])
{
    for (int a = 0; a < 3; a++) {
        lo[a] = c->origin[a] + (double)c->bmin[a];
        hi[a] = c->origin[a] + (double)c->bmax[a];
    }
}

/* Writes cell c's bounds into its region's arrays and grows the region's
 * bounds to hold them. */
static void cell_publish(cull_world *w, const cull_cell *c)
{
    cull_region *r = c->region;
    double lo[3], hi[3];
    cell_world_bounds(c, lo, hi);
    cull_soa_set(&r->soa, c->index, lo, hi);
    bool grew = false;
    for (int a = 0; a < 3; a++) {
        if (lo[a] < r->bmin[a]) r->bmin[a] = lo[a], grew = true;
        if (hi[a] > r->bmax[a]) r->bmax[a] = hi[a], grew = true;
    }
    if (grew) cull_soa_set(&w->grid[r->grid].soa, r->index, r->bmin, r->bmax);
}

static void empty_bounds_f(float lo[3], float hi[3])
{
    for (int a = 0; a < 3; a++) lo[a] = INFINITY, hi[a] = -INFINITY;
}

static void empty_bounds_d(double lo[3], double hi[3])
{
    for (int a = 0; a < 3; a++) lo[a] = INFINITY, hi[a] = -INFINITY;
}

/* ---- regions and cells -------------------------------------------------------- */

static int32_t floor_shift(int32_t k)
{
    return k >= 0 ? k >> CULL_REGION_SHIFT : -((-(k + 1) >> CULL_REGION_SHIFT) + 1);
}

static void region_free(cull_region *r)
{
    if (!r) return;
    free(r->cells);
    free(r->soa.v);
    free(r);
}

/* Blocks belong to the world's slabs; a cell only holds pointers. */
static void cell_free(cull_cell *c)
{
    if (!c) return;
    free(c->blocks);
    free(c);
}

#define SLAB_MIN_BLOCKS 64u
#define SLAB_MAX_BYTES (2u << 20)

static cull_block *block_carve(cull_world *w)
{
    if (w->npool) return w->block_pool[--w->npool];
    if (!w->slab_left) {
        if (!vp_grow32((void **)&w->slabs, &w->cap_slabs, w->nslabs + 1, sizeof *w->slabs)) return NULL;
        size_t blocks = (size_t)SLAB_MIN_BLOCKS << (w->nslabs < 6 ? w->nslabs : 6);
        if (blocks * sizeof(cull_block) > SLAB_MAX_BYTES) blocks = SLAB_MAX_BYTES / sizeof(cull_block);
        bool huge = blocks * sizeof(cull_block) * 2 > SLAB_MAX_BYTES;
        size_t align = huge ? SLAB_MAX_BYTES : 64;
        size_t bytes = (blocks * sizeof(cull_block) + align - 1) / align * align;
        char *slab = aligned_alloc(align, bytes);
        if (!slab) return NULL;
#ifdef MADV_HUGEPAGE
        if (huge) (void)madvise(slab, bytes, MADV_HUGEPAGE);
#endif
        w->slabs[w->nslabs++] = slab;
        w->slab_next = slab;
        w->slab_left = (uint32_t)blocks;
        w->slab_bytes += bytes;
    }
    cull_block *b = (cull_block *)w->slab_next;
    w->slab_next += sizeof(cull_block);
    w->slab_left--;
    return b;
}

/* A removed block goes to the pool; if the pool could not grow it stays
   unused in its slab until the world is destroyed. */
static void block_release(cull_world *w, cull_block *b)
{
    if (w->npool < w->cap_pool) w->block_pool[w->npool++] = b;
}

void cull_grid_free(cull_grid *g)
{
    for (uint32_t i = 0; i < g->nregions; i++) {
        cull_region *r = g->regions[i];
        for (uint32_t k = 0; k < r->ncells; k++) cell_free(r->cells[k]);
        region_free(r);
    }
    free(g->regions);
    free(g->soa.v);
    free(g->region_map.slot);
    free(g->cell_map.slot);
    memset(g, 0, sizeof *g);
}

/* A region with room for one more cell, made if needed. Nothing is linked
 * into the grid until *fresh is handled by the caller's success path. */
static int region_reserve(cull_grid *g, uint32_t gi, const int32_t ck[3], cull_region **out)
{
    int32_t rk[3] = {floor_shift(ck[0]), floor_shift(ck[1]), floor_shift(ck[2])};
    cull_region *r = map_find(&g->region_map, rk);
    if (!r) {
        if (!map_reserve(&g->region_map, g->region_map.used + 1) ||
            !vp_grow32((void **)&g->regions, &g->cap_regions, g->nregions + 1, sizeof *g->regions) ||
            !cull_soa_reserve(&g->soa, g->nregions, g->nregions + 1))
            return CULL_ERR_NOMEM;
        r = calloc(1, sizeof *r);
        if (!r) return CULL_ERR_NOMEM;
        memcpy(r->key, rk, sizeof r->key);
        r->grid = gi;
        empty_bounds_d(r->bmin, r->bmax);
    }
    if (!vp_grow32((void **)&r->cells, &r->cap_cells, r->ncells + 1, sizeof *r->cells) ||
        !cull_soa_reserve(&r->soa, r->ncells, r->ncells + 1)) {
        if (!r->ncells && !map_find(&g->region_map, rk)) region_free(r);
        return CULL_ERR_NOMEM;
    }
    *out = r;
    return CULL_OK;
}

static void region_link(cull_grid *g, cull_region *r)
{
    if (r->ncells || map_find(&g->region_map, r->key) == r) return;
    r->index = g->nregions;
    g->regions[g->nregions++] = r;
    map_insert_nogrow(&g->region_map, r);
    cull_soa_set(&g->soa, r->index, r->bmin, r->bmax);
}

static bool block_add(cull_world *w, cull_cell *c)
{
    if (!vp_grow32((void **)&c->blocks, &c->cap_blocks, c->nblocks + 1, sizeof *c->blocks)) return false;
    cull_block *b = block_carve(w);
    if (!b) return false;
    memset(b, 0, sizeof *b);
    c->blocks[c->nblocks++] = b;
    w->nblocks_total++;
    return true;
}

int cull_grid_reserve(cull_world *w, uint32_t gi, const int32_t k[3], cull_cell **out)
{
    cull_grid *g = &w->grid[gi];
    cull_cell *c = map_find(&g->cell_map, k);
    if (c) {
        if (c->count == c->nblocks * CULL_BLOCK_CAP && !block_add(w, c)) return CULL_ERR_NOMEM;
        *out = c;
        return CULL_OK;
    }
    /* a new cell: region, maps and the first block, all before linking */
    if (!map_reserve(&g->cell_map, g->cell_map.used + 1)) return CULL_ERR_NOMEM;
    cull_region *r;
    int rc = region_reserve(g, gi, k, &r);
    if (rc) return rc;
    /* two whole cache lines: the query's cell stage prefetches them */
    c = aligned_alloc(64, sizeof *c);
    if (c) memset(c, 0, sizeof *c);
    if (!c || !block_add(w, c)) {
        cell_free(c);
        if (!r->ncells && map_find(&g->region_map, r->key) != r) region_free(r);
        return CULL_ERR_NOMEM;
    }
    memcpy(c->key, k, sizeof c->key);
    c->grid = gi;
    for (int a = 0; a < 3; a++) c->origin[a] = (double)k[a] * w->cell_size;
    empty_bounds_f(c->bmin, c->bmax);
    region_link(g, r);
    c->region = r;
    c->stamp = ++w->stamp;
    c->index = r->ncells;
    r->cells[r->ncells++] = c;
    map_insert_nogrow(&g->cell_map, c);
    g->ncells++;
    *out = c;
    return CULL_OK;
}

void cull_grid_store(cull_world *w, cull_cell *c, uint32_t i, const cull_entity_desc *d, cull_handle h)
{
    cull_block *b = c->blocks[i / CULL_BLOCK_CAP];
    uint32_t l = i % CULL_BLOCK_CAP;
    double lc[3], lmin[3], lmax[3], ext = 0;
    for (int a = 0; a < 3; a++) {
        lc[a] = d->center[a] - c->origin[a];
        ext = fmax(ext, fmax(fabs(d->aabb_min[a] - c->origin[a]), fabs(d->aabb_max[a] - c->origin[a])));
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
    double err = fabs((double)b->x[l] - lc[0]) + fabs((double)b->y[l] - lc[1]) + fabs((double)b->z[l] - lc[2]);
    b->r[l] = cull_round_up(d->radius + err + slack);
    b->minx[l] = cull_round_down(lmin[0]);
    b->miny[l] = cull_round_down(lmin[1]);
    b->minz[l] = cull_round_down(lmin[2]);
    b->maxx[l] = cull_round_up(lmax[0]);
    b->maxy[l] = cull_round_up(lmax[1]);
    b->maxz[l] = cull_round_up(lmax[2]);
    b->handle[l] = h;
    b->class_sub[l] = (uint32_t)d->class_id | (uint32_t)d->sublevel << 16;
    c->subs |= 1ull << (d->sublevel & 63);
    c->stamp = ++w->stamp;
    /* grow the cell bounds to hold both the sphere and the AABB; float sums
       may round inward by half an ulp, so pad one ulp */
    float lo[3] = {fminf(b->x[l] - b->r[l], b->minx[l]), fminf(b->y[l] - b->r[l], b->miny[l]),
                   fminf(b->z[l] - b->r[l], b->minz[l])};
    float hi[3] = {fmaxf(b->x[l] + b->r[l], b->maxx[l]), fmaxf(b->y[l] + b->r[l], b->maxy[l]),
                   fmaxf(b->z[l] + b->r[l], b->maxz[l])};
    bool grew = false;
    for (int a = 0; a < 3; a++) {
        lo[a] = nextafterf(lo[a], -INFINITY);
        hi[a] = nextafterf(hi[a], INFINITY);
        if (lo[a] < c->bmin[a]) c->bmin[a] = lo[a], grew = true;
        if (hi[a] > c->bmax[a]) c->bmax[a] = hi[a], grew = true;
    }
    if (grew) cell_publish(w, c);
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
    bd->class_sub[ld] = bs->class_sub[ls];
}

void cull_grid_reserve_removal(cull_world *w)
{
    /* failure only costs tightness: a block the pool cannot take stays
       unused in its slab until the world is destroyed, a cell not listed
       dirty keeps loose (still correct) bounds */
    (void)vp_grow32((void **)&w->block_pool, &w->cap_pool, w->npool + 1, sizeof *w->block_pool);
    (void)vp_grow32((void **)&w->dirty, &w->cap_dirty, w->ndirty + 1, sizeof *w->dirty);
}

void cull_grid_mark_dirty(cull_world *w, cull_cell *c)
{
    if (c->dirty_pos || w->ndirty >= w->cap_dirty) return;
    w->dirty[w->ndirty++] = c;
    c->dirty_pos = w->ndirty;
}

static void dirty_forget(cull_world *w, cull_cell *c)
{
    if (!c->dirty_pos) return;
    cull_cell *last = w->dirty[--w->ndirty];
    w->dirty[c->dirty_pos - 1] = last;
    last->dirty_pos = c->dirty_pos;
    c->dirty_pos = 0;
}

static void region_take_out(cull_world *w, cull_region *r, cull_cell *c)
{
    cull_grid *g = &w->grid[r->grid];
    cull_cell *moved = r->cells[--r->ncells];
    r->cells[c->index] = moved;
    cull_soa_copy(&r->soa, c->index, moved->index);
    moved->index = c->index;
    r->dirty = true; /* its bounds may now be loose */
    if (r->ncells) return;
    map_erase(&g->region_map, r);
    cull_region *rm = g->regions[--g->nregions];
    g->regions[r->index] = rm;
    cull_soa_copy(&g->soa, r->index, rm->index);
    rm->index = r->index;
    region_free(r);
}

void cull_grid_take_out(cull_world *w, cull_cell *c, uint32_t i)
{
    uint32_t last = c->count - 1;
    if (i != last) {
        copy_lane(c, i, last);
        uint32_t h = c->blocks[i / CULL_BLOCK_CAP]->handle[i % CULL_BLOCK_CAP];
        w->slots[h & CULL_SLOT_MASK].lane = i;
    }
    c->count--;
    c->stamp = ++w->stamp;
    w->grid[c->grid].entities--;
    if (c->count <= (c->nblocks - 1) * CULL_BLOCK_CAP) {
        cull_block *b = c->blocks[--c->nblocks];
        w->nblocks_total--;
        block_release(w, b);
    }
    if (c->count) {
        cull_grid_mark_dirty(w, c);
        return;
    }
    cull_grid *g = &w->grid[c->grid];
    dirty_forget(w, c);
    map_erase(&g->cell_map, c);
    g->ncells--;
    region_take_out(w, c->region, c);
    cell_free(c);
}

void cull_grid_commit(cull_world *w)
{
    for (uint32_t d = 0; d < w->ndirty; d++) {
        cull_cell *c = w->dirty[d];
        c->dirty_pos = 0;
        c->stamp = ++w->stamp;
        empty_bounds_f(c->bmin, c->bmax);
        c->subs = 0;
        for (uint32_t i = 0; i < c->count; i++) {
            const cull_block *b = c->blocks[i / CULL_BLOCK_CAP];
            uint32_t l = i % CULL_BLOCK_CAP;
            c->subs |= 1ull << ((b->class_sub[l] >> 16) & 63);
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
        double lo[3], hi[3];
        cell_world_bounds(c, lo, hi);
        cull_soa_set(&c->region->soa, c->index, lo, hi);
        c->region->dirty = true;
    }
    w->ndirty = 0;
    /* regions: recompute from their cells where anything changed */
    for (int gi = 0; gi < 2; gi++) {
        cull_grid *g = &w->grid[gi];
        for (uint32_t i = 0; i < g->nregions; i++) {
            cull_region *r = g->regions[i];
            if (!r->dirty) continue;
            r->dirty = false;
            empty_bounds_d(r->bmin, r->bmax);
            for (uint32_t k = 0; k < r->ncells; k++) {
                double lo[3], hi[3];
                cell_world_bounds(r->cells[k], lo, hi);
                for (int a = 0; a < 3; a++) {
                    r->bmin[a] = fmin(r->bmin[a], lo[a]);
                    r->bmax[a] = fmax(r->bmax[a], hi[a]);
                }
            }
            cull_soa_set(&g->soa, r->index, r->bmin, r->bmax);
        }
    }
}
