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
#include "vp_grow.h" /* vp_grow32: every growing array here (header-only) */
#include <stdatomic.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#define CULL_BLOCK_CAP 64u /* lanes per block: 8 AVX2 groups */
#define CULL_GEN_BITS (32u - CULL_HANDLE_SLOT_BITS)
#define CULL_SLOT_MASK (CULL_MAX_ENTITIES - 1u)

/* One block: 64 entities, SoA, 64-byte aligned, 3 KiB. What the
 * sphere stage and the result writer read (sphere, handle, class,
 * sub-level) comes first and is contiguous (1.5 KiB), so a one-view query
 * streams that prefix and never touches the AABBs unless it needs them. */
typedef struct cull_block {
    float x[CULL_BLOCK_CAP], y[CULL_BLOCK_CAP], z[CULL_BLOCK_CAP], r[CULL_BLOCK_CAP];
    uint32_t handle[CULL_BLOCK_CAP];
    uint32_t class_sub[CULL_BLOCK_CAP]; /* class_id | sublevel << 16: the
                                            result's layout, one load */
    float minx[CULL_BLOCK_CAP], miny[CULL_BLOCK_CAP], minz[CULL_BLOCK_CAP];
    float maxx[CULL_BLOCK_CAP], maxy[CULL_BLOCK_CAP], maxz[CULL_BLOCK_CAP];
} cull_block;
#define CULL_BLOCK_HOT_BYTES offsetof(cull_block, minx)

typedef struct cull_region cull_region;

typedef struct cull_cell {
    int32_t  key[3];        /* first: the hash maps read it there */
    uint32_t grid;          /* 0 static, 1 dynamic */
    cull_region *region;
    uint32_t index;         /* position in region->cells */
    double   origin[3];     /* key * cell_size, metres */
    float    bmin[3], bmax[3]; /* local bounds of every sphere and AABB; may
                                  be loose after removals until commit */
    uint32_t count;         /* entities */
    uint32_t nblocks, cap_blocks;
    cull_block **blocks;
    uint32_t dirty_pos;     /* index in the world's dirty list + 1; 0 = clean */
    uint64_t subs;          /* bit s % 64 for every sub-level s it holds (may
                               keep bits of removed entities until commit) */
    uint64_t stamp;         /* w->stamp when its entities or bounds last
                               changed: a kept occlusion buffer's verdicts
                               for its blocks stand while it is the same */
} cull_cell;
_Static_assert(sizeof(cull_cell) <= 128, "a cell is two cache lines (cull_query.c prefetches them)");

/* Cell bounds for the SIMD cell stage: six arrays of cap doubles (world
 * centre x y z, half extent x y z), cap a multiple of 4 above the count so
 * kernels read whole vectors. */
typedef struct cull_bounds_soa {
    double  *v;
    uint32_t cap;
} cull_bounds_soa;
#define CULL_SOA(s, k) ((s)->v + (size_t)(k) * (s)->cap)
/* Room for need boxes (count are kept); false on allocation failure. */
bool cull_soa_reserve(cull_bounds_soa *s, uint32_t count, uint32_t need);
void cull_soa_set(cull_bounds_soa *s, uint32_t i, const double lo[3], const double hi[3]);
void cull_soa_copy(cull_bounds_soa *s, uint32_t dst, uint32_t src);

/* A region: CULL_REGION_CELLS^3 cells, tested as one box first, so a query
 * touches only the cells of regions its views can see (a 16 km world of 64 m
 * cells has 65k cells but ~250 regions). */
#define CULL_REGION_SHIFT 3
#define CULL_REGION_CELLS (1 << CULL_REGION_SHIFT)
struct cull_region {
    int32_t  key[3];        /* first: the hash maps read it there */
    uint32_t grid;
    uint32_t index;         /* position in grid->regions */
    cull_cell **cells;      /* dense, iteration order = query order */
    uint32_t ncells, cap_cells;
    cull_bounds_soa soa;    /* bounds of cells[] */
    double   bmin[3], bmax[3]; /* world bounds of its cells; loose until commit */
    bool     dirty;
};

/* Open addressing, linear probing, power-of-two capacity; entries are
 * pointers to structs whose first member is int32_t key[3]. */
typedef struct cull_map {
    void   **slot;
    uint32_t cap, used;
} cull_map;

typedef struct cull_grid {
    cull_region **regions;  /* dense, iteration order = query order */
    uint32_t    nregions, cap_regions;
    cull_bounds_soa soa;    /* bounds of regions[] */
    cull_map    region_map, cell_map;
    uint32_t    ncells, entities;
} cull_grid;

/* Exact (double) bounds kept per slot so get() returns what was given. */
typedef struct cull_slot {
    uint32_t  gen;          /* 1..2^10-1; generation of the live or next handle */
    uint32_t  next_free;    /* free list link when cell == NULL */
    cull_cell *cell;        /* NULL when free */
    uint32_t  lane;         /* index within the cell: block = lane / 64 */
    cull_entity_desc desc;  /* normalised */
} cull_slot;

/* ---- occluders (cull_occluder.c) ------------------------------------------ */
/* A drawn polygon: a triangle, or two coplanar triangles sharing an edge
 * merged into a convex quad (v[0..3] counter-clockwise; the halves are
 * (0,1,2) and (2,3,0)). Indices are local to the cluster. */
typedef struct cull_occ_face {
    uint16_t v[4];
    uint32_t n;        /* 3 or 4 */
} cull_occ_face;

/* Up to CULL_OCC_CLUSTER_FACES faces of one occluder, near each other:
 * the unit of frustum culling, front-to-back sorting and the hidden-
 * occluder test. Vertices in world metres (double: a camera-relative
 * transform per frame keeps 1e6 m exact). */
#define CULL_OCC_CLUSTER_FACES 64u
typedef struct cull_occ_cluster {
    double   bmin[3], bmax[3];
    const double *v;   /* 3 * nv */
    const cull_occ_face *f;
    uint32_t nv, nf;
    uint32_t widx;     /* position in the world's cluster arrays */
    uint16_t sublevel; /* its occluder's */
    uint32_t convex;   /* closed (every edge shared by two faces, opposite
                          ways) and convex: drawn as one silhouette */
    uint32_t two_sided; /* CULL_OCC_TWO_SIDED: back faces are drawn too */
} cull_occ_cluster;

typedef struct cull_occ_mesh {
    cull_occ_cluster *cl;   /* one allocation: clusters, vertices, faces */
    uint32_t ncl;
    uint32_t triangles, dropped, faces;
    uint64_t build_steps;   /* work the build did (cull_occluder_info) */
    double   bmin[3], bmax[3];
    uint16_t sublevel;
    uint32_t slot, dense;
} cull_occ_mesh;

typedef struct cull_occ_slot {
    uint32_t gen, next_free;
    cull_occ_mesh *m;       /* NULL when free */
} cull_occ_slot;

struct cull_world {
    double     cell_size, inv_cell_size;
    uint32_t   max_entities;
    cull_grid  grid[2];
    cull_slot *slots;
    uint32_t   nslots, cap_slots, free_head, live;
    cull_cell **dirty;      /* cells whose bounds may be loose */
    uint32_t   ndirty, cap_dirty;
    cull_block **block_pool; /* freed blocks for reuse */
    uint32_t   npool, cap_pool;
    /* blocks are carved from slabs (64 blocks, doubling to ~2 MiB, the big
       ones on transparent huge pages): neighbours in memory and few TLB
       misses when a query streams 10^6 entities; freed with the world */
    void     **slabs;
    uint32_t   nslabs, cap_slabs;
    char      *slab_next;     /* next block to carve from slabs[nslabs-1] */
    uint32_t   slab_left;     /* blocks left there */
    size_t     slab_bytes;
    uint32_t   nblocks_total;
    /* occluders: slots for handles, a dense list for rendering */
    cull_occ_slot *oslots;
    uint32_t   noslots, cap_oslots, ofree_head;
    cull_occ_mesh **occ;
    uint32_t   nocc, cap_occ;
    /* every occluder's clusters, with their bounds in SoA for the SIMD box
       test (the same kernel as the cell stage) */
    cull_occ_cluster **ocl;
    uint32_t   nclusters, cap_ocl;
    cull_bounds_soa ocl_soa;
    /* one more with every occluder added, replaced or removed; starts at
       a value no other world of the process starts at, so (world,
       version) names what cull_occ_render draws (a query context's reuse
       of a view's occlusion buffer, cull_query.c) */
    uint64_t   occ_version;
    /* one more with every change to a cell (cull_cell.stamp) */
    uint64_t   stamp;
};

void cull_occluders_free(cull_world *w);

/* ---- storage internals (cull_grid.c) ---------------------------------------- */
/* Finds or makes cell key k of grid gi with room for one more entity.
 * Allocates everything the edit needs up front; on error nothing changed. */
int  cull_grid_reserve(cull_world *w, uint32_t gi, const int32_t k[3], cull_cell **out);
/* Writes entity d into lane i of c (floats relative to the cell origin,
 * rounded outward) and grows the cell's and region's bounds. */
void cull_grid_store(cull_world *w, cull_cell *c, uint32_t i, const cull_entity_desc *d, cull_handle h);
/* Removes lane i of c (swap with the cell's last); frees an emptied block,
 * cell and region. Never fails, never allocates (see cull_grid_reserve_removal). */
void cull_grid_take_out(cull_world *w, cull_cell *c, uint32_t i);
void cull_grid_reserve_removal(cull_world *w);
void cull_grid_mark_dirty(cull_world *w, cull_cell *c);
void cull_grid_commit(cull_world *w);
void cull_grid_free(cull_grid *g);

/* A view plane for the box stage: world-space offset d = d - n.origin
 * (double keeps 1e6 m exact to ~1e-10 m), |n| for the extent term. */
typedef struct cull_cplane {
    double n[3], an[3], d;
} cull_cplane;

/* Box stage (regions, then cells): code[i] for each of the n boxes in s
   (see cull_cells.inl). code has room for n rounded up to 4. */
typedef void (*cull_cells_fn)(const cull_bounds_soa *s, uint32_t n, const cull_cplane *pl, uint32_t np,
                              uint8_t *code);
void cull_cells_scalar(const cull_bounds_soa *, uint32_t, const cull_cplane *, uint32_t, uint8_t *);
void cull_cells_sse41(const cull_bounds_soa *, uint32_t, const cull_cplane *, uint32_t, uint8_t *);
void cull_cells_avx2(const cull_bounds_soa *, uint32_t, const cull_cplane *, uint32_t, uint8_t *);
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
    /* the area bound works on min+max and max-min: rows x, y, w halved,
       their absolute values, and pixel offsets half - 2^-16 half */
    float    hx[3], hy[3], hw[3], ax[3], ay[3], aw[3];
    float    off_w, off_h;
    /* occlusion (NULL: none for this view): the buffer, the nearness
       numerator row (re-based like cx), the buffer's half size */
    const struct cull_occ_buffer *occ;
    float    cd[4];
    float    occ_sx, occ_sy, occ_w, occ_h;
    /* 1: every block of the cell has a standing record (cull_occ_memo.blk):
       the occlusion stage reads the records, and cd / occ_* (and the clip
       rows unless the area stage runs) are not filled */
    uint32_t hot;
    uint32_t pmask;         /* bit i: the view's plane i is among px..pd */
} cull_kview;

/* One block's occlusion verdicts against a buffer the query context keeps
 * (cull_query.c): the view's constants the kernel tested with, and per
 * lane the box it tested and whether it was visible. occ_lanes is a
 * function of those and of the buffer alone, so while the buffer is kept
 * a group whose live lanes and boxes are bit for bit the recorded ones
 * takes the recorded verdicts instead of projecting and walking again. */
typedef struct cull_occ_memo {
    float    box[6][CULL_BLOCK_CAP]; /* minx, maxx, miny, maxy, minz, maxz as tested */
    uint64_t in, vis;       /* lanes tested, lanes found visible */
    const struct cull_occ_buffer *occ;
    float    kv[20];        /* cx, cy, cw, cd, occ_sx, occ_sy, occ_w, occ_h */
    bool     valid;         /* cleared whenever the buffer is drawn */
    /* the block, its cell's stamp and the view's planes the cell straddled
       when the kernel last ran over it whole: while all three are the
       same, the lanes that reach the occlusion stage are the recorded ones
       with the recorded boxes, and a query takes the verdicts without
       comparing boxes (cull_kview.hot) */
    const struct cull_block *blk;
    uint64_t stamp;
    uint32_t pmask;
    uint64_t gen;           /* the record set's generation it belongs to
                               (cull_query.c: an older one is not valid) */
} cull_occ_memo;

typedef struct cull_kparams {
    float    min_area;      /* 0 = no threshold */
    bool     aabb;          /* run the AABB stage */
    bool     area;          /* run the screen-area stage */
    bool     exact_area;    /* report exact areas (else bounds may decide) */
    bool     count_only;    /* count the visible, write no results */
} cull_kparams;

typedef struct cull_kcount {
    uint32_t tested, after_spheres, after_aabb, after_area, after_occ;
} cull_kcount;

/* The occlusion stage's per-entity test (cull_occ.c): some pixel of the
 * rectangle [x0, x1] x [y0, y1] not nearer than z? */
bool cull_occ_rect_visible(const struct cull_occ_buffer *b, int x0, int y0, int x1, int y1, float z);

/* Tests n (<= 64) entities of block b against nv views, writes one result
 * per entity with a non-zero mask to out, returns how many. memo (NULL:
 * none; used when nv is 1 and the view has a buffer) is the block's
 * record against a kept buffer, read and brought up to date. */
typedef uint32_t (*cull_block_fn)(const cull_block *b, uint32_t n,
                                  const cull_kview *kv, uint32_t nv,
                                  const cull_kparams *p, cull_result *out,
                                  cull_kcount *cnt, cull_occ_memo *memo);

uint32_t cull_block_scalar(const cull_block *, uint32_t, const cull_kview *,
                           uint32_t, const cull_kparams *, cull_result *, cull_kcount *, cull_occ_memo *);
uint32_t cull_block_sse41(const cull_block *, uint32_t, const cull_kview *,
                          uint32_t, const cull_kparams *, cull_result *, cull_kcount *, cull_occ_memo *);
uint32_t cull_block_avx2(const cull_block *, uint32_t, const cull_kview *,
                         uint32_t, const cull_kparams *, cull_result *, cull_kcount *, cull_occ_memo *);

cull_block_fn cull_isa_kernel(uint32_t isa);




/* Outward rounding of a double to float (cull_round_up / _down), and
 * f one float step toward +inf (up) or -inf: nextafterf's answer for
 * every f these are called with (finite, or an infinity stepped toward
 * the other), without the libm call: the bits of a float step by one. */
static inline float cull_float_step(float f, bool up)
{
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    if (!(u & 0x7fffffffu)) u = up ? 1u : 0x80000001u; /* +-0: the least denormal that way */
    else if (!(u >> 31) == up) u++;                    /* away from zero */
    else u--;                                          /* toward zero */
    memcpy(&f, &u, sizeof f);
    return f;
}
static inline float cull_round_down(double v)
{
    float f = (float)v;
    return (double)f > v ? cull_float_step(f, false) : f;
}
static inline float cull_round_up(double v)
{
    float f = (float)v;
    return (double)f < v ? cull_float_step(f, true) : f;
}

#endif
