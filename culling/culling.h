/*
 * culling.h — Vantage's culling core: scene storage for culling and the
 * multi-view visibility query ("Culling the Battlefield", DICE, GDC 2011).
 *
 * What it owns: a world of entities (bounding sphere + AABB + class, sub-level
 * and flags) kept in two uniform grids (static and dynamic) of cells, the
 * cells grouped in regions of 8x8x8; each cell is a list of fixed-capacity
 * SoA blocks. A query tests up to 32 views at once, skips whole regions and
 * cells, and returns one {handle, view mask, class, sub-level, screen area}
 * per entity visible in at least one view.
 *
 * Load it expects: 10^3..10^7 entities, queries of 1..32 views at 10^2..10^4
 * per second, edits in batches between queries. A query on 15k entities and
 * one view costs a few microseconds on one AVX2 core (BENCHMARKS.md).
 *
 * Threading: a world is not internally locked. Edits and queries must not
 * overlap; any number of queries may run at once on one world, each with its
 * own cull_ctx. A cull_pool may be shared by contexts only if their queries
 * do not overlap in time (the pool runs one job at a time).
 *
 * Precision: positions are given in double and stored as floats relative to
 * their cell's origin; every plane is re-based per cell in double. A camera
 * 10^6 m from the origin is as exact as one at the origin. Stored bounds are
 * rounded outward by (4*cell_size + r + reach) * 2^-19, reach being the
 * AABB's largest distance from its cell's origin, so float evaluation never
 * culls a bound the exact (double) test keeps.
 *
 * Derived bounds (cull_bounds_from_trs): a mesh's local box [lo, hi] under
 * position t, quaternion q = (x,y,z,w) and scale S gives an AABB and a
 * sphere that contain the exact image of the box. Exactly, with
 * M = R(q/|q|) S, c = (lo+hi)/2, h = (hi-lo)/2, the image's AABB is
 * t + Mc -+ |M|h (Arvo). R is formed with s = 2/|q|^2 where the unit
 * formula has 2 (R_00 = 1 - s(y^2+z^2), R_01 = s(xy-zw), ...), which is
 * R(q/|q|) exactly: renormalising q is implied (|q| is only checked to be
 * within 1e-3 of 1). Let u = 2^-53 and A = sum_j |S_j| max(|lo_j|, |hi_j|):
 *  - |q|^2 carries 4u, s 5u. An off-diagonal s(xy-zw) is off by at most
 *    2u s(|xy|+|zw|) + 6u |s(xy-zw)| <= 8u, since s(|xy|+|zw|) <= 1 (AM-GM);
 *    a diagonal's s(y^2+z^2) <= 2 carries 8u (16u absolute), 1 - it one u
 *    more: 17u. Times S_j, rounded: |M~ - M|_ij <= 18u |S_j| (used as 20u);
 *  - c~ and h~ are off by u max(|lo_j|, |hi_j|) each;
 *  - the dots M~c~ and |M~|h~ add gamma_3 = 3u of A; so mc~ and mh~ are
 *    each within (20u + u + 3u) A = 24u A of Mc and |M|h;
 *  - mh~ + W, then mc~ -+ that: 3u A more (|mc~|, mh~ <= A (1 + 2^-40)).
 * Sum: 51u A < 2^-47.3 A to first order; the second-order terms are below
 * 2^-90 A. W = 2^-46 A = 128u A (a 2.5x margin; its own rounding is 5u of
 * W) plus 2^-900 m for underflow (a subnormal sum or difference is exact;
 * a product or halving loses at most 2^-1075, at most 2^7 of them, scaled
 * by at most |S| max|lo, hi| < 2^128 2^40). Nothing overflows: inputs are
 * within 1e12 m and float scales, so every term is below 1e52. So
 * mc~ - (mh~ + W) <= Mc - |M|h exactly (>= for the max face); the last
 * step, t + that, rounds to nearest, within half an ulp, and one ulp down
 * (up for the max face) makes it <= (>=) the exact face. A contracted FMA
 * only removes roundings, so the bound holds with or without one.
 * The sphere: its centre is any double (the AABB's midpoint); each axis'
 * reach e_i to the farther AABB face is rounded up one ulp; the radius is
 * sqrt(sum e_i^2) (1 + 2^-48) rounded up one ulp (the squares, sum and
 * root lose < 4u; 2^-48 is 16u), or 2 max e_i when max e_i < 2^-500
 * (squares would underflow; 2 > sqrt 3). It holds the AABB's corners,
 * hence the image. Cost: each face moves out by at most
 * 2^-45 A + 2 ulp(|t| + A) + 2^-899 m beyond the exact one; tests/
 * test_bounds.c holds it to 2^-43 (|t_i| + A) + 2^-898 m against a
 * long-double model (seen: 1.5e-14 (|t_i| + A) = 2^-45.9). A position
 * 1e9 m from the origin adds only its own two ulps, 2.4e-7 m.
 *
 * No I/O, no sockets, no files. Errors are negative codes from CULL_ERRORS.
 */
#ifndef VANTAGE_CULLING_H
#define VANTAGE_CULLING_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include "cull_mat.h"

#include "vp_err.h" /* the X-macro plumbing of CULL_ERRORS, vp_errf */

#ifdef __cplusplus
extern "C" {
#endif

/* ---- error codes: one table, tests assert on the code ------------------- */
#define CULL_ERRORS(X)                                                          \
    X(CULL_OK,                0, "ok")                                          \
    X(CULL_ERR_INVALID,      -1, "invalid argument")                            \
    X(CULL_ERR_NONFINITE,    -2, "coordinate is NaN or infinite")               \
    X(CULL_ERR_RADIUS,       -3, "radius is negative, NaN or infinite")         \
    X(CULL_ERR_AABB,         -4, "AABB has min > max on some axis")             \
    X(CULL_ERR_RANGE,        -5, "coordinate or size beyond the world's range") \
    X(CULL_ERR_MATRIX,       -6, "degenerate or non-finite view-projection")    \
    X(CULL_ERR_VIEWPORT,     -7, "viewport must be 1..65535 pixels per side")   \
    X(CULL_ERR_VIEWS,        -8, "a query takes 1..32 views")                   \
    X(CULL_ERR_HANDLE,       -9, "stale or never-issued entity handle")         \
    X(CULL_ERR_CAPACITY,    -10, "entity capacity exhausted")                   \
    X(CULL_ERR_NOMEM,       -11, "out of memory")                               \
    X(CULL_ERR_OUTPUT,      -12, "output buffer smaller than cull_query_bound") \
    X(CULL_ERR_THREADS,     -13, "cannot start worker threads")             \
    X(CULL_ERR_MESH,        -14, "occluder mesh: bad counts or index out of range") \
    X(CULL_ERR_BUFFER,      -15, "occlusion buffer must be 8..8192 x 8..8192 pixels")

VP_ERR_ENUM(CULL_ERRORS);

/* Message for a code from CULL_ERRORS; "unknown error" otherwise. Static. */
const char *cull_strerror(int code);

/* ---- handles ------------------------------------------------------------ */
/* 32 bits: low CULL_HANDLE_SLOT_BITS the slot, high bits a generation that is
 * never 0, so 0 is never a valid handle. A removed entity's handle is stale
 * forever after (until the 10-bit generation wraps for that slot: 1023
 * reuses). Moving or removing other entities never changes a live handle. */
typedef uint32_t cull_handle;
#define CULL_HANDLE_SLOT_BITS 22u
#define CULL_MAX_ENTITIES (1u << CULL_HANDLE_SLOT_BITS) /* 4,194,304 */

/* ---- world -------------------------------------------------------------- */
typedef struct cull_world cull_world;

typedef struct cull_world_desc {
    double   cell_size;    /* metres, edge of a grid cell; 0 = 64 */
    uint32_t max_entities; /* 0 = CULL_MAX_ENTITIES; at most that */
} cull_world_desc;

/* Creates an empty world. Returns CULL_OK and *out, or a negative code.
 * Destroy with cull_world_destroy (accepts NULL). */
int  cull_world_create(const cull_world_desc *desc, cull_world **out);
void cull_world_destroy(cull_world *w);

/* Entity flags. */
#define CULL_ENTITY_DYNAMIC 0x1u /* lives in the dynamic grid */

/* An entity's bounds, in world metres (double). Zero means default:
 * - radius == 0 and an AABB not all zero: the sphere is the AABB's
 *   circumsphere (center is then ignored);
 * - AABB all zero: the AABB is the sphere's bounding box.
 * Coordinates must be finite and within ±1e12 m; radius within 0..1e9 m. */
#define CULL_MAX_COORD 1e12  /* metres: every position in the world */
#define CULL_MAX_RADIUS 1e9  /* metres: bounding and destruction spheres */
typedef struct cull_entity_desc {
    double   center[3];
    double   radius;
    double   aabb_min[3];
    double   aabb_max[3];
    uint16_t class_id;
    uint16_t sublevel;
    uint32_t flags;     /* CULL_ENTITY_* */
} cull_entity_desc;

/* Checks a desc as add/update would (values, ranges, this world's cell
 * keys) without storing anything; fills *out with the normalised desc if
 * out is not NULL. Lets a caller validate a whole batch before applying. */
int cull_entity_check(const cull_world *w, const cull_entity_desc *d, cull_entity_desc *out);
/* Adds an entity. O(1) amortised. On error nothing is stored. */
int cull_entity_add(cull_world *w, const cull_entity_desc *d, cull_handle *out);
/* Replaces an entity's bounds, class, sub-level and flags (moving it across
 * cells or grids as needed). O(1). On error the entity is unchanged. */
int cull_entity_update(cull_world *w, cull_handle h, const cull_entity_desc *d);
/* Removes an entity (swap with the last of its cell). O(1). */
int cull_entity_remove(cull_world *w, cull_handle h);
/* Reads back an entity's stored bounds (the desc as normalised at add/update:
 * derived sphere or AABB filled in). */
int cull_entity_get(const cull_world *w, cull_handle h, cull_entity_desc *out);

/* An entity's transform: local box -> world, in the order scale, rotate,
 * translate. */
#define CULL_QUAT_TOLERANCE 1e-3 /* |rot| may be 1 +- this; it is renormalised */
typedef struct cull_trs {
    double pos[3];   /* metres, within +-CULL_MAX_COORD */
    double rot[4];   /* unit quaternion x, y, z, w */
    float  scale[3]; /* per local axis; negative mirrors; 0 on at most one axis */
} cull_trs;
/* Derives an entity's bounds from a mesh's local box [local_min, local_max]
 * (metres, within +-CULL_MAX_COORD, min <= max; a zero extent is fine) and
 * t: fills d's center, radius, aabb_min and aabb_max, rounded outward (the
 * proof is under "Derived bounds" above) and leaves its class, sub-level and
 * flags as they are, so d goes to cull_entity_add/update as is (which check
 * the derived bounds' ranges). Refuses NaN or Inf in any field
 * (CULL_ERR_NONFINITE), a quaternion whose length is not within
 * CULL_QUAT_TOLERANCE of 1 or a scale 0 on two or three axes
 * (CULL_ERR_INVALID), min > max (CULL_ERR_AABB), a position or local bound
 * beyond +-CULL_MAX_COORD (CULL_ERR_RANGE); err (may be NULL) names the
 * field. On error d is unchanged. Stores nothing; about 730 instructions
 * (callgrind), 70..130 ns on a loaded 2-core box (tests/test_bounds.c). */
int cull_bounds_from_trs(const double local_min[3], const double local_max[3], const cull_trs *t,
                         cull_entity_desc *d, char *err, size_t errlen);

/* ---- persistence: the handle allocator saved and restored exactly ------ */
/* Slots ever used (live or free); slot s's generation (of its live handle,
 * or of the next one it hands out) and whether it is live; the free list
 * in the order it will be reused (up to max; returns how many). */
uint32_t cull_world_slots(const cull_world *w);
uint32_t cull_world_slot_gen(const cull_world *w, uint32_t s, bool *live);
uint32_t cull_world_free_list(const cull_world *w, uint32_t *out, uint32_t max);
/* On a world that never held an entity: n slots with generations gens[],
 * free_list[0..nfree) its free list in that order; every other slot is
 * reserved for cull_entity_add_at. CULL_ERR_INVALID for a bad image. */
int cull_world_slots_restore(cull_world *w, uint32_t n, const uint16_t *gens, const uint32_t *free_list,
                             uint32_t nfree);
/* Adds an entity as handle h, whose slot is reserved with h's generation
 * (else CULL_ERR_HANDLE). */
int cull_entity_add_at(cull_world *w, const cull_entity_desc *d, cull_handle h);

/* Tightens the cell and region bounds that removals and moves left loose.
 * O(entities in touched cells + regions). Queries are correct without it,
 * only slower; call it after a batch of edits. */
void cull_world_commit(cull_world *w);

typedef struct cull_world_info {
    uint32_t entities, static_entities, dynamic_entities;
    uint32_t regions, cells, blocks;
    size_t   bytes; /* heap held by storage */
} cull_world_info;
void cull_world_info_get(const cull_world *w, cull_world_info *out);


/* ---- occluders ------------------------------------------------------------ */
/* Occluders are a separate set from the entities: closed low-poly meshes
 * (artist-made, or a terrain height field) that hide entities behind them.
 * They are rendered, conservatively, into a small depth buffer per view
 * (cull_occ_*), and the query's last stage drops entities whose screen
 * rectangle lies entirely behind it. Nothing is baked: add, update and
 * remove at any time (destruction replaces an occluder's triangles). */
typedef uint32_t cull_occluder; /* same handle scheme as entities; 0 = none */
#define CULL_MAX_OCCLUDERS (1u << 20)
#define CULL_OCC_MAX_VERTICES (1u << 20) /* per occluder */
#define CULL_OCC_MAX_TRIANGLES (1u << 20) /* per occluder */

/* A triangle list with a model-to-world transform. Front faces are
 * counter-clockwise seen from outside; back faces are never drawn, so a
 * camera inside a closed occluder sees through it (it hides nothing).
 * Degenerate triangles (zero area, or NaN-free but collinear) and repeated
 * ones (the same corners in the same order, after merging equal
 * positions) are dropped and counted; a non-finite vertex or transform
 * rejects the whole desc. Building costs O(n log n) in the triangles,
 * whatever they are (cull_occluder.c). */
typedef struct cull_occluder_desc {
    const float    *vertices;     /* xyz, 3 * vertex_count, model space */
    uint32_t        vertex_count;
    const uint32_t *indices;      /* 3 per triangle; NULL: vertices are a
                                     triangle list (vertex_count % 3 == 0) */
    uint32_t        index_count;
    double          transform[16]; /* column-major affine model -> world;
                                      all zero = identity */
    uint16_t        sublevel;
    uint32_t        flags;        /* CULL_OCC_* */
} cull_occluder_desc;

/* cull_occluder_desc.flags. By default an occluder hides from the side its
 * counter-clockwise faces look to (the solid is behind them; a closed
 * mesh's front faces cover all of it). TWO_SIDED: its faces hide from both
 * sides: a shell that destruction cut open, whose far walls, seen through
 * the hole from inside, still hide what stands behind them (as the
 * renderers draw the inside). Costs the back faces' set-up. */
#define CULL_OCC_TWO_SIDED 1u

/* A height field: heights[z * nx + x] at world (origin.x + x * spacing,
 * origin.y + h, origin.z + z * spacing), nx, nz >= 2. Triangulated and
 * split into chunks; the solid is below the surface (seen from below it
 * hides nothing). */
typedef struct cull_terrain_desc {
    const float *heights;
    uint32_t     nx, nz;
    double       origin[3];
    double       spacing;      /* metres between samples, > 0 */
    uint16_t     sublevel;
} cull_terrain_desc;

typedef struct cull_occluder_info {
    uint32_t triangles;        /* kept (after dropping degenerates) */
    uint32_t dropped;          /* degenerate or repeated triangles dropped */
    uint32_t faces;            /* drawn polygons (coplanar pairs merged) */
    uint32_t clusters;         /* culled as units */
    uint32_t convex_clusters;  /* closed and convex: drawn as one silhouette */
    uint64_t build_steps;      /* work the last add/update did: hash probes,
                                  edge candidates examined, sort compares
                                  (n log2 n per split), plus one per input
                                  vertex and triangle. Tests assert the
                                  build's cost bound on it */
    double   aabb_min[3], aabb_max[3];
    uint16_t sublevel;
} cull_occluder_info;

/* Adds an occluder (O(triangles)). On error nothing is stored. */
int cull_occluder_add(cull_world *w, const cull_occluder_desc *d, cull_occluder *out);
int cull_terrain_add(cull_world *w, const cull_terrain_desc *d, cull_occluder *out);
/* Replaces an occluder's geometry (mesh or terrain, either kind); the
 * handle stays. On error the occluder is unchanged. */
int cull_occluder_update(cull_world *w, cull_occluder h, const cull_occluder_desc *d);
int cull_terrain_update(cull_world *w, cull_occluder h, const cull_terrain_desc *d);
int cull_occluder_remove(cull_world *w, cull_occluder h);
int cull_occluder_get_info(const cull_world *w, cull_occluder h, cull_occluder_info *out);
uint32_t cull_occluder_count(const cull_world *w);

/* ---- views -------------------------------------------------------------- */
/* enum cull_depth_mode: cull_mat.h */

typedef struct cull_view_desc {
    /* Column-major 4x4 (m[col*4 + row]), mapping (p - origin, 1) to clip
     * space. Give origin = the camera position and a camera-relative
     * view-projection for large worlds; origin 0 and a world matrix works too. */
    double   view_proj[16];
    double   origin[3];
    uint32_t depth_mode;          /* enum cull_depth_mode */
    uint32_t viewport_w, viewport_h; /* pixels; 0 = 1920 x 1080 */
} cull_view_desc;

/* A prepared view: normalised planes (an infinite far plane is dropped). */
typedef struct cull_view {
    double   plane[6][4];   /* n.x n.y n.z d, |n| = 1, inside: n.(p-origin)+d >= 0 */
    uint32_t plane_count;   /* 5 or 6 */
    double   clip[16];      /* the view-projection, as given */
    double   origin[3];
    uint32_t depth_mode;
    uint32_t viewport_w, viewport_h;
} cull_view;

/* Prepares a view. CULL_ERR_MATRIX for non-finite, singular or empty
 * frustums (an orthographic view with w <= 0 included), CULL_ERR_VIEWPORT
 * for a bad viewport. The one validation of a view: what it accepts, light
 * binning and both renderers draw. */
int cull_view_init(cull_view *v, const cull_view_desc *d);

/* A view's clip rows as linear functions of (p - origin, 1), for code that
 * rasterises for it (occlusion, light tiles, renderers): the clip rows x, y,
 * z, w; the near plane (>= 0 in front); and the nearness numerator d, with
 * nearness = d / w: 1/w for perspective views, 1 - z_ndc (z_ndc with
 * reversed-Z) for orthographic ones, so larger is nearer and it is affine
 * in screen space. */
typedef struct cull_view_rows {
    double x[4], y[4], z[4], w[4];
    double nearfn[4];
    double d[4];
    int    ortho;
    int    usable;          /* 0: an orthographic view with w <= 0 */
} cull_view_rows;
void cull_view_rows_get(const cull_view *v, cull_view_rows *r);

/* Matrix helpers (cull_mat_perspective, _ortho, _look_dir, _mul): cull_mat.h,
 * header-only, included above. */

/* ---- query -------------------------------------------------------------- */
#define CULL_MAX_VIEWS 32u

/* Query flags. Zero = spheres, then AABBs, then the screen-area threshold if
 * min_screen_area > 0, both grids. */
#define CULL_Q_NO_AABB      0x1u /* stop after the sphere test */
#define CULL_Q_WANT_AREA    0x2u /* report exact screen areas and test the
                                    threshold on them (8 projections per entity
                                    and view); without it the threshold is tested
                                    on a cheap upper bound (2 projections): it
                                    never culls more, it may keep a little more */
#define CULL_Q_STATIC_ONLY  0x4u /* only the static grid */
#define CULL_Q_DYNAMIC_ONLY 0x8u /* only the dynamic grid */
#define CULL_Q_COUNT_ONLY   0x10u /* *count = the visible entities; out is not
                                     written (may be NULL with cap 0) */
#define CULL_Q_NO_OCCLUSION 0x20u /* skip the occlusion stage (it runs by
                                     default for every view that has an
                                     occluder in its frustum) */
/* Sub-levels: a query may see only some of them (CULL_SUBLEVEL_WORDS words,
 * bit s % 64 of word s / 64 set = sub-level s is seen). */
#define CULL_SUBLEVELS 65536u
#define CULL_SUBLEVEL_WORDS (CULL_SUBLEVELS / 64u)
static inline int cull_sublevel_in(const uint64_t *set, uint32_t s)
{
    return !set || (int)((set[(s & 0xFFFFu) >> 6] >> (s & 63)) & 1u);
}

#define CULL_Q_OCC_CENTRE   0x40u /* occluders cover the pixels whose centre
                                     they cover, instead of only the pixels
                                     they cover entirely: culls more, exact
                                     only at the buffer's own resolution
                                     (see "occlusion buffers" below) */

#define CULL_Q_OCC_FRESH    0x80u /* render the occluders again even where
                                     the context's buffer for the view is
                                     still right (a bench's "before") */

typedef struct cull_occ_buffer cull_occ_buffer;

typedef struct cull_query_desc {
    const cull_view *views;     /* view_count prepared views */
    uint32_t view_count;        /* 1..32; bit i of a mask = views[i] */
    uint32_t flags;             /* CULL_Q_* */
    float    min_screen_area;   /* pixels; an entity whose projected AABB
                                   rectangle (clipped to the viewport) is
                                   smaller in a view is culled from it; 0 = off */
    uint32_t threads;           /* 0 = automatic: the whole pool when the work
                                   (entities x views after the cell stage) pays
                                   for a dispatch, else the caller alone;
                                   N = up to N of the pool's threads, always */
    uint32_t occ_w, occ_h;      /* occlusion buffer, pixels; 0 = 256 x 114 */
    cull_occ_buffer *const *occ_buffers; /* NULL: the context renders the
                                   occluders for each view, or keeps the
                                   buffer it rendered for view index i last
                                   time when nothing it depends on changed
                                   (the view, buffer size, cover mode,
                                   sub-level set, the world's occluders:
                                   exact, the same bits); else one buffer
                                   per view already rendered for it with
                                   cull_occ_render (NULL entries: no
                                   occlusion for that view) */
    const uint64_t *sublevels;  /* NULL: every sub-level; else the set seen
                                   (CULL_SUBLEVEL_WORDS words): entities of
                                   the others are not reported and their
                                   occluders hide nothing. Cells holding
                                   none of the set are skipped whole */
} cull_query_desc;

/* The talk's EntityRenderCullInfo. 16 bytes. */
typedef struct cull_result {
    cull_handle handle;
    uint32_t    view_mask;   /* bit i: visible in views[i] */
    uint16_t    class_id;
    uint16_t    sublevel;
    float       screen_area; /* pixels, max over the views in view_mask, of
                                the viewport-clipped rectangle of the projected
                                AABB (the full viewport when the box reaches
                                w <= 0); -1 unless CULL_Q_WANT_AREA */
} cull_result;

typedef struct cull_query_stats {
    uint32_t regions, regions_culled; /* regions (8^3 cells) tested / culled whole */
    uint32_t cells, cells_culled;   /* cells in the grids / culled whole (with
                                       their region or alone) */
    uint32_t entities_tested;       /* entities in surviving cells */
    uint32_t after_spheres, after_aabb, after_area; /* entities with any bit */
    uint32_t after_occlusion;       /* entities with any bit after occlusion */
    uint32_t visible;               /* results written */
    uint32_t threads_used;
    uint32_t occ_views;             /* views the occlusion stage ran for */
    uint32_t occ_reused;            /* views whose buffer the context kept from
                                       its last query (the same view, buffer,
                                       cover, sub-levels and occluders) */
    uint32_t occ_rendered;          /* views whose occluders were drawn now */
    uint32_t occ_clusters_drawn;    /* occluder clusters rasterised, all views */
    uint32_t cells_occluded;        /* (cell, view) pairs dropped whole by occlusion */
    uint64_t occ_raster_ns;         /* wall time spent rendering occluders */
    uint32_t cells_filtered;        /* cells skipped: none of the query's sub-levels */
    uint32_t filtered;              /* entities visible but of another sub-level */
} cull_query_stats;

/* Job pool: threads-1 persistent workers plus the caller. threads 0 = the
 * number of online cores. Destroy accepts NULL. */
typedef struct cull_pool cull_pool;
int  cull_pool_create(uint32_t threads, cull_pool **out);
void cull_pool_destroy(cull_pool *p);
uint32_t cull_pool_threads(const cull_pool *p);
/* Runs fn(arg, t) once for each t in 0..n-1 on the pool and waits: the
 * renderers share the culling pool this way. Which thread runs which t is
 * not fixed (the caller runs any slot no worker has taken yet, so a worker
 * the scheduler is late to run delays nothing); the t are run concurrently
 * or one after another, so fn must not wait for another t. n is clamped to
 * the pool's thread count; a NULL pool runs fn(arg, 0). One job at a time
 * per pool. */
typedef void (*cull_job_fn)(void *arg, uint32_t thread);
void cull_pool_run(cull_pool *p, cull_job_fn fn, void *arg, uint32_t n);
/* Runs fn(arg, k) once for each k in 0..n-1 on at most threads of the
 * pool (0: all of them; a NULL pool: the caller alone) and waits: each
 * thread takes the next k as it finishes one, so uneven items balance.
 * The same rules as cull_pool_run. */
typedef void (*cull_each_fn)(void *arg, uint32_t k);
void cull_pool_each(cull_pool *p, uint32_t threads, uint32_t n, cull_each_fn fn, void *arg);
/* cull_pool_each, and side(side_arg) once besides, run by the first
 * thread to start (before it takes items): serial work that does not
 * depend on the items overlaps them on the other threads instead of
 * running before or after the job alone. side NULL: cull_pool_each. */
typedef void (*cull_side_fn)(void *arg);
void cull_pool_each_side(cull_pool *p, uint32_t threads, uint32_t n, cull_each_fn fn, void *arg, cull_side_fn side,
                         void *side_arg);

/* Per-query scratch (grows with the world, then stops allocating). pool may
 * be NULL (single-threaded). One context per concurrent query. */
typedef struct cull_ctx cull_ctx;
int  cull_ctx_create(cull_pool *pool, cull_ctx **out);
void cull_ctx_destroy(cull_ctx *c);

/* Room a query's output needs: the number of entities plus
 * CULL_RESULT_PAD (the SIMD writer stores whole 8-lane groups). */
#define CULL_RESULT_PAD 8u
size_t cull_query_bound(const cull_world *w);

/* Runs a query: *count results in out[0..*count). out has room for cap
 * results, cap >= cull_query_bound(w) (else CULL_ERR_OUTPUT, nothing done).
 * Results come in a deterministic order (grid, region, cell, block, lane)
 * that does not depend on the thread count or ISA. stats may be NULL.
 * Allocates only when the world has outgrown the context's scratch
 * (CULL_ERR_NOMEM then, nothing written). */
int cull_query(const cull_world *w, cull_ctx *c, const cull_query_desc *q,
               cull_result *out, size_t cap, size_t *count,
               cull_query_stats *stats);


/* ---- occlusion buffers ------------------------------------------------------ */
/* A view's occluders rendered into a depth buffer ("Culling the Battlefield"
 * slides 41-52; 256 x 114 by default). Stored per pixel: a nearness value
 * (1/w for perspective views; for orthographic ones 1 - z_ndc, or z_ndc
 * with reversed-Z: larger is nearer), never nearer than the occluder
 * anywhere over the pixel. Coverage, by default: a pixel is marked only if
 * an occluder polygon covers the whole pixel square (shrunk by a rounding
 * margin), so an entity is culled only if it is hidden at every sample
 * position of every resolution. CULL_OCC_COVER_CENTRE marks the pixels
 * whose centre is covered instead (as a GPU z-buffer does): it culls more
 * and is exact for a z-buffer of the buffer's own size, but an entity
 * peeking through a gap narrower than a pixel may be culled. Plus min-
 * tiles of 8x8 and 64x64 pixels, so a rectangle test is near O(1).
 *
 * Entities are tested by every pixel their projected AABB touches and the
 * AABB's nearest point. tests/test_occlusion.c checks both modes against a
 * double-precision ray caster: no entity the caster sees is culled. */
enum cull_occ_cover { CULL_OCC_COVER_INNER = 0, CULL_OCC_COVER_CENTRE = 1 };
#define CULL_OCC_DEFAULT_W 256u
#define CULL_OCC_DEFAULT_H 114u

int  cull_occ_buffer_create(uint32_t width, uint32_t height, cull_occ_buffer **out);
/* enum cull_occ_cover, for the next render (default INNER). */
int  cull_occ_buffer_set_cover(cull_occ_buffer *b, uint32_t cover);
void cull_occ_buffer_destroy(cull_occ_buffer *b);

typedef struct cull_occ_stats {
    uint32_t clusters_in_view;  /* occluder clusters inside the frustum */
    uint32_t clusters_drawn;    /* rasterised: the rest covered no pixel
                                   centre or were hidden by nearer ones */
    uint32_t faces_drawn;       /* front-facing polygons set up */
    uint32_t threads_used;
    uint64_t raster_ns;
} cull_occ_stats;

/* Clears b and renders the world's occluders as seen by v (front to back,
 * in horizontal bands on up to `threads` threads of the pool; 0 = the
 * whole pool). pool may be NULL. */
int cull_occ_render(const cull_world *w, const cull_view *v, cull_occ_buffer *b,
                    cull_pool *pool, uint32_t threads, cull_occ_stats *st);
/* The same with only the occluders of the sub-levels in `sublevels`
 * (CULL_SUBLEVEL_WORDS words; NULL = all). */
int cull_occ_render_sub(const cull_world *w, const cull_view *v, cull_occ_buffer *b, cull_pool *pool,
                        uint32_t threads, const uint64_t *sublevels, cull_occ_stats *st);
/* 1 if an AABB (world metres) may be visible in the view b was rendered
 * for, 0 if it is entirely behind the stored depth (double precision). */
int cull_occ_test_aabb(const cull_occ_buffer *b, const double mn[3], const double mx[3]);
/* Whether the last render drew anything (no occluder: tests always pass). */
int cull_occ_buffer_empty(const cull_occ_buffer *b);
/* The stored nearness per pixel (see above; -FLT_MAX where no occluder
 * covers the pixel), row 0 at the bottom of the view, `stride` floats
 * apart. Folds the buffer's coarse per-tile values into its pixels first
 * and copies them out (the buffer holds its pixels tile by tile) to a
 * plane it keeps (rewritten by the next call; a render leaves it as it
 * was): for inspection and dumps, not per query. NULL if that plane
 * cannot be allocated. */
const float *cull_occ_depth(cull_occ_buffer *b, uint32_t *width, uint32_t *height, size_t *stride);


/* ---- destruction: distance volumes ------------------------------------------ */
/* "Destruction Masking in Frostbite 2" (SIGGRAPH 2010): a destroyed area is
 * a set of spheres placed on an entity; the signed distance to their union,
 * min_i(|p - c_i| - r_i) (negative inside), is sampled on a small grid over
 * the entity's box (typically 8 x 8 x 8) and read back with trilinear
 * filtering. Samples sit on the box's corners and n - 1 steps between, so
 * the grid covers the box exactly.
 *
 * Accuracy: at a sample the stored value is the exact distance computed in
 * floats (a few roundings of the box's size or of r + the centre's
 * distance, whichever is larger). Between samples the trilinear value differs from the exact
 * distance by at most half the voxel diagonal: the distance is
 * 1-Lipschitz, so the error is at most the filter's weighted mean
 * distance to the cell's corners, sum_i w_i |x_i - p|, which is at most
 * sqrt(sum_i w_i |x_i - p|^2) = sqrt(sum_a t_a (1 - t_a) step_a^2) <=
 * |step| / 2. cull_dvol_bound is that plus float rounding. A consumer
 * that must never miss destroyed space (an occluder's hole) widens by
 * it. */
#define CULL_DVOL_MAX_RES 64u
#define CULL_DVOL_MAX_SPHERES 4096u

typedef struct cull_dvol {
    double   origin[3];      /* the box's min corner: sample (0,0,0) */
    double   step[3];        /* metres between samples per axis (> 0) */
    uint32_t n[3];           /* samples per axis, 2..CULL_DVOL_MAX_RES */
    float   *d;              /* n[0] n[1] n[2] distances, x fastest */
    float   *px, *py, *pz;   /* each sample's offset from origin (floats) */
    double  (*sph)[4];       /* the spheres: centre xyz, radius (world) */
    uint32_t nsph, cap;
    uint64_t version;        /* +1 per change of the field */
} cull_dvol;

/* A field over the box [bmin, bmax] with res samples per axis (a flat axis
 * gets 2 samples a millimetre apart), no spheres (every distance +inf).
 * CULL_ERR_AABB / CULL_ERR_NONFINITE / CULL_ERR_INVALID (res) /
 * CULL_ERR_NOMEM. Free with cull_dvol_free. */
int  cull_dvol_init(cull_dvol *v, const double bmin[3], const double bmax[3], uint32_t res);
void cull_dvol_free(cull_dvol *v);
/* Adds a sphere and folds it into the field (one pass over the samples).
 * CULL_ERR_NONFINITE, CULL_ERR_RADIUS (r <= 0), CULL_ERR_CAPACITY. */
int  cull_dvol_add_sphere(cull_dvol *v, const double c[3], double r);
/* Recomputes every sample from the sphere set (what a field built from a
 * saved set does). */
void cull_dvol_rebuild(cull_dvol *v);
/* Trilinear distance at p (world); p outside the box is clamped to it. */
float cull_dvol_sample(const cull_dvol *v, const double p[3]);
/* The largest |trilinear - exact| can be: half the voxel diagonal, plus
 * the samples' float rounding (grows with the spheres' radii). O(spheres). */
double cull_dvol_bound(const cull_dvol *v);
/* The exact signed distance to the sphere set at p (double; +inf with no
 * spheres): the reference the field approximates. */
double cull_dvol_exact(const cull_dvol *v, const double p[3]);

/* The holes destruction cuts in an occluder: of the triangles tri[0..ntri)
 * (9 floats each, relative to origin) the parts farther than r + margin
 * from every sphere of v. A triangle clear of every widened sphere is kept
 * whole, one inside one of them dropped, one straddling a surface split in
 * four down to edges of min_edge metres, the last straddling pieces
 * dropped: an occluder only ever loses area, at most pieces of about
 * min_edge around each hole. margin: cull_dvol_bound(v) plus whatever the
 * renderers add, so the occluder's hole contains the drawn one. *out (and
 * *parent: each piece's source triangle, if parent is not NULL) are
 * malloc'ed; CULL_ERR_CAPACITY past max_out pieces, or past
 * max_out * CULL_CUT_WORK_PER_PIECE (piece, sphere) tests (nothing
 * returned): the cost is at most that many tests, ~20 ns each, whatever
 * the triangles and spheres (4096 spheres on 349,525 triangles took 26 s
 * before the bound). */
#define CULL_CUT_WORK_PER_PIECE 512u
int cull_occ_cut(const float *tri, uint32_t ntri, const double origin[3], const cull_dvol *v, double margin,
                 double min_edge, uint32_t max_out, float **out, uint32_t **parent, uint32_t *nout);

/* ---- lights: Forward+ tile binning ------------------------------------------- */
/* "DirectX 11 Rendering in Battlefield 3" (GDC 2011): lights are culled per
 * screen tile of 16x16 pixels against the tile's frustum, narrowed to the
 * depth range of what the tile shows (from a depth pre-pass), and each tile
 * gets a list of the lights that may touch it. Both renderers shade a pixel
 * with its tile's list only. Conservative: a light that reaches a pixel's
 * surface point is always in that pixel's tile list. */
enum cull_light_type { CULL_LIGHT_POINT = 0, CULL_LIGHT_SPOT = 1 };

typedef struct cull_light {
    double   pos[3];        /* world metres */
    double   radius;        /* range: no effect beyond; > 0 */
    float    dir[3];        /* spot: unit axis */
    float    cos_outer;     /* spot: cosine of the outer half-angle */
    uint32_t type;          /* enum cull_light_type */
} cull_light;

#define CULL_LIGHT_TILE 16u

/* Tile lists, CSR: tile t = ty * tiles_x + tx (ty from the bottom row of the
 * view, like the occlusion buffer) has lights index[offset[t] ..
 * offset[t + 1]), indices into the caller's light array, ascending. The
 * arrays are owned by the struct and grown as needed: zero it first, reuse
 * it, free with cull_light_tiles_free. */
typedef struct cull_light_tiles {
    uint32_t  tiles_x, tiles_y;
    uint32_t *offset;       /* tiles_x * tiles_y + 1 */
    uint32_t *index;
    uint32_t  in_view;      /* lights that survived the view's frustum */
    uint32_t  max_per_tile;
    uint32_t  offset_cap, index_cap;
    uint32_t *scratch;      /* internal */
    uint32_t  scratch_cap;
} cull_light_tiles;

/* Bins n lights into the tiles of a width x height view. depth_range, if
 * not NULL, holds per tile {nearest, farthest} nearness of what the tile
 * shows (the occlusion buffer's convention: 1/w for perspective views,
 * larger is nearer; nearest < farthest marks a tile that shows nothing,
 * which gets no lights); NULL bins against the whole frustum depth.
 * Returns CULL_OK, CULL_ERR_VIEWPORT, CULL_ERR_INVALID (a light with a bad
 * position, radius or axis: nothing binned), CULL_ERR_MATRIX (a view whose
 * rows admit no nearness mapping, e.g. an orthographic one with w <= 0:
 * nothing binned), or CULL_ERR_NOMEM. No lights: every list is empty and
 * nothing is tested. */
int  cull_lights_bin(const cull_view *v, uint32_t width, uint32_t height, const cull_light *lights, uint32_t n,
                     const float (*depth_range)[2], cull_light_tiles *out);
/* What a light may be: the one validation shared by the daemon's edit
 * path (LIGHT_PUT), light binning and both renderers, so nothing is
 * accepted that a renderer later refuses. The bounds keep every derived
 * float finite (cull_lights.c says why each):
 *   pos      finite, |pos[a]| <= CULL_MAX_COORD (1e12 m)
 *   radius   (the range) finite, CULL_LIGHT_MIN_RANGE..CULL_LIGHT_MAX_RANGE
 *   radiance (colour x intensity per channel, if not NULL) finite,
 *            0..CULL_LIGHT_MAX_RADIANCE
 *   spot     dir of unit length within 1e-3, cos_outer in -1..1
 * Returns CULL_OK, or CULL_ERR_NONFINITE / CULL_ERR_RANGE (position,
 * radiance) / CULL_ERR_RADIUS (range) / CULL_ERR_INVALID (type, spot),
 * with the field, its value and the bound written to why (may be NULL). */
#define CULL_LIGHT_MIN_RANGE 1e-3
#define CULL_LIGHT_MAX_RANGE 1e9
#define CULL_LIGHT_MAX_RADIANCE 1e12
int  cull_light_validate(const cull_light *l, const double radiance[3], char *why, size_t whylen);
void cull_light_tiles_free(cull_light_tiles *t);

/* ---- ISA dispatch -------------------------------------------------------- */
enum cull_isa { CULL_ISA_SCALAR = 0, CULL_ISA_SSE41, CULL_ISA_AVX2, CULL_ISA_COUNT };
/* Whether this build and this CPU (CPUID) can run an ISA's kernels. */
int         cull_isa_supported(uint32_t isa);
/* The ISA a new context uses: the best supported, or VANTAGE_ISA=scalar|
 * sse41|avx2 from the environment (an unsupported or unknown name falls back
 * to the best, with a note on stderr). */
uint32_t    cull_isa_default(void);
/* Whether the AVX2 kernels that have an EVEX build (the renderer's
 * shading) take it: the CPU has AVX-512 F, VL, DQ and BW and the OS saves
 * their state, and VANTAGE_EVEX is not "0". The same 256-bit operations
 * with 32 vector registers instead of 16 (fewer spills), the same bits. */
int         cull_isa_evex(void);
const char *cull_isa_name(uint32_t isa);
/* Per-context ISA (tests and benchmarks compare them in one process).
 * CULL_ERR_INVALID if the ISA is not supported here. */
int         cull_ctx_set_isa(cull_ctx *c, uint32_t isa);
uint32_t    cull_ctx_isa(const cull_ctx *c);

#ifdef __cplusplus
}
#endif
#endif /* VANTAGE_CULLING_H */
