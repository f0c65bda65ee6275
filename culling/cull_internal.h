/*
 * cull_internal.h — private layout of the culling core, shared by the
 * storage (cull_world.c), the query driver (cull_query.c) and the per-ISA
 * kernels (cull_kernels_*.c).
 *
 * Layout: world -> grid[2] (static, dynamic) -> cells (hash map by integer
 * cell key, dense pointer array for iteration) -> blocks of CULL_BLOCK_CAP
 * entities in SoA. Coordinates inside a block are floats relative to the
 * cell origin (key * cell_size), rounded outward.
 */
#ifndef VANTAGE_CULL_INTERNAL_H
#define VANTAGE_CULL_INTERNAL_H

#include "culling.h"
#include <stdatomic.h>
#include <stdbool.h>

#define CULL_BLOCK_CAP 64u /* lanes per block: 8 AVX2 groups */
#define CULL_GEN_BITS (32u - CULL_HANDLE_SLOT_BITS)
#define CULL_SLOT_MASK (CULL_MAX_ENTITIES - 1u)
#define CULL_MAX_COORD 1e12
#define CULL_MAX_RADIUS 1e9

/* One block: 64 entities, SoA, 64-byte aligned. The sphere arrays come
 * first so the sphere stage streams 1 KiB per block and never touches the
 * rest. 3,328 bytes. */
typedef struct cull_block {
    float x[CULL_BLOCK_CAP], y[CULL_BLOCK_CAP], z[CULL_BLOCK_CAP], r[CULL_BLOCK_CAP];
    float minx[CULL_BLOCK_CAP], miny[CULL_BLOCK_CAP], minz[CULL_BLOCK_CAP];
    float maxx[CULL_BLOCK_CAP], maxy[CULL_BLOCK_CAP], maxz[CULL_BLOCK_CAP];
    uint32_t handle[CULL_BLOCK_CAP];
    uint16_t class_id[CULL_BLOCK_CAP];
    uint16_t sublevel[CULL_BLOCK_CAP];
} cull_block;

typedef struct cull_cell {
    int32_t  key[3];
    uint32_t grid;          /* 0 static, 1 dynamic */
    uint32_t index;         /* position in grid->cells */
    double   origin[3];     /* key * cell_size, metres */
    float    bmin[3], bmax[3]; /* local bounds of every sphere and AABB; may
                                  be loose after removals until commit */
    uint32_t count;         /* entities */
    uint32_t nblocks, cap_blocks;
    cull_block **blocks;
    bool     dirty;         /* bounds loose, on the world's dirty list */
} cull_cell;

typedef struct cull_grid {
    cull_cell **cells;      /* dense, iteration order = query order */
    uint32_t    ncells, cap_cells;
    /* cell bounds for the SIMD cell stage, parallel to cells: six arrays of
       soa_cap doubles (world centre x y z, half extent x y z); soa_cap is a
       multiple of 4 above ncells so kernels may read whole vectors */
    double     *soa;
    uint32_t    soa_cap;
    cull_cell **map;        /* open addressing, linear probing, pow2 */
    uint32_t    map_cap, map_used;
    uint32_t    entities;
} cull_grid;

/* Exact (double) bounds kept per slot so get() returns what was given and
 * moves re-derive nothing. */
typedef struct cull_slot {
    uint32_t  gen;          /* 1..2^10-1; generation of the live or next handle */
    uint32_t  next_free;    /* free list link when cell == NULL */
    cull_cell *cell;        /* NULL when free */
    uint32_t  lane;         /* index within the cell: block = lane / 64 */
    cull_entity_desc desc;  /* normalised */
} cull_slot;

struct cull_world {
    double     cell_size, inv_cell_size;
    uint32_t   max_entities;
    cull_grid  grid[2];
    cull_slot *slots;
    uint32_t   nslots, cap_slots, free_head, live;
    cull_cell **dirty;
    uint32_t   ndirty, cap_dirty;
    cull_block **block_pool; /* freed blocks for reuse */
    uint32_t   npool, cap_pool;
    uint32_t   nblocks_total;
};

#define CULL_SOA(g, k) ((g)->soa + (size_t)(k) * (g)->soa_cap)

/* Rewrites cell c's entry in its grid's bounds arrays. */
void cull_cell_sync(cull_world *w, const cull_cell *c);

/* A view plane for the cell stage: world-space offset d = d - n.origin. */
typedef struct cull_cplane {
    double n[3], an[3], d;
} cull_cplane;

/* Cell stage: code[c] for each of g's cells (see cull_cells.inl). code has
   room for ncells rounded up to 4. */
typedef void (*cull_cells_fn)(const cull_grid *g, const cull_cplane *pl, uint32_t np, uint8_t *code);
void cull_cells_scalar(const cull_grid *, const cull_cplane *, uint32_t, uint8_t *);
void cull_cells_sse41(const cull_grid *, const cull_cplane *, uint32_t, uint8_t *);
void cull_cells_avx2(const cull_grid *, const cull_cplane *, uint32_t, uint8_t *);
cull_cells_fn cull_isa_cells(uint32_t isa);

/* ---- what a kernel sees: one (cell, view) pair, prepared in floats ------ */
typedef struct cull_kview {
    float    px[6], py[6], pz[6], pd[6]; /* active planes, d re-based to the cell */
    uint32_t nplanes;       /* 0: cell fully inside, every entity passes */
    uint32_t bit;           /* 1u << view index */
    /* screen area: clip rows x, y, w (3 coefficients + cell translation) */
    float    cx[4], cy[4], cw[4];
    float    half_w, half_h; /* viewport / 2, pixels */
    float    vp_w, vp_h;
} cull_kview;

typedef struct cull_kparams {
    float    min_area;      /* 0 = no threshold */
    bool     aabb;          /* run the AABB stage */
    bool     area;          /* run the screen-area stage */
    bool     exact_area;    /* report exact areas (else bounds may decide) */
} cull_kparams;

typedef struct cull_kcount {
    uint32_t tested, after_spheres, after_aabb, after_area;
} cull_kcount;

/* Tests n (<= 64) entities of block b against nv views, writes one result
 * per entity with a non-zero mask to out, returns how many. */
typedef uint32_t (*cull_block_fn)(const cull_block *b, uint32_t n,
                                  const cull_kview *kv, uint32_t nv,
                                  const cull_kparams *p, cull_result *out,
                                  cull_kcount *cnt);

uint32_t cull_block_scalar(const cull_block *, uint32_t, const cull_kview *,
                           uint32_t, const cull_kparams *, cull_result *, cull_kcount *);
uint32_t cull_block_sse41(const cull_block *, uint32_t, const cull_kview *,
                          uint32_t, const cull_kparams *, cull_result *, cull_kcount *);
uint32_t cull_block_avx2(const cull_block *, uint32_t, const cull_kview *,
                         uint32_t, const cull_kparams *, cull_result *, cull_kcount *);

cull_block_fn cull_isa_kernel(uint32_t isa);

/* ---- job pool ------------------------------------------------------------ */
typedef void (*cull_job_fn)(void *arg, uint32_t thread);
/* Runs fn(arg, t) for t in 0..n-1 (t = 0 on the caller) and waits.
 * n is clamped to the pool's thread count; pool NULL runs fn(arg, 0). */
void cull_pool_run(cull_pool *p, cull_job_fn fn, void *arg, uint32_t n);

/* Outward rounding of a double to float. */
float cull_round_down(double v);
float cull_round_up(double v);

#endif
