/*
 * cull_occ.h — private layout of occlusion buffers, shared by cull_occ.c
 * (buffers, hierarchy, projection, double-precision tests),
 * cull_occ_raster.inl (render), cull_query.c (the query's occlusion stage)
 * and the per-ISA loops (cull_occ_kern.inl).
 */
#ifndef VANTAGE_CULL_OCC_H
#define VANTAGE_CULL_OCC_H

#include "cull_internal.h"
#include <float.h>
#include <stdbool.h>

/* The most bands (threads) a render splits its tile rows into. */
#define CULL_OCC_MAX_BANDS 64u

/* The most constraints (edges, near plane) of a polygon the render draws. */
#define CULL_OCC_MAX_CONS 8

/* One polygon's per-row set-up for the render's tile rows
 * (cull_occ_raster.inl): x > lal + lbe j per left constraint, x < ral +
 * rbe j per right one, x > (st - sb j) / sa or < per "slow" one (|al| or
 * |be| beyond 2^900: sa's sign says which), the columns [i0, i1] the
 * polygon may mark, and per nearness plane k its start at row j,
 * zb j + zc - corner - m, in double and then float. */
typedef struct cull_occ_rowset {
    double lal[CULL_OCC_MAX_CONS], lbe[CULL_OCC_MAX_CONS], ral[CULL_OCC_MAX_CONS], rbe[CULL_OCC_MAX_CONS];
    double sa[CULL_OCC_MAX_CONS], sb[CULL_OCC_MAX_CONS], st[CULL_OCC_MAX_CONS];
    uint32_t nl, nr, ns;
    double i0, i1;
    double zb[3], zc[3], corner[3], m[3];
} cull_occ_rowset;

/* What a tile row's 8 rows sum up to over rows a..b (rows jb + a ..
 * jb + b): L the largest left end, H the smallest right end (empty rows
 * included), U0 / U1 the smallest left and largest right end of the
 * non-empty rows (INT32_MAX / INT32_MIN with none), whole: all 8 rows
 * there and none empty. */
typedef struct cull_occ_rowsum {
    int L, H, U0, U1;
    int whole;
} cull_occ_rowsum;

/* The inner loops, one instance per ISA. */
typedef struct cull_occ_fns {
    /* row[x] = max(row[x], max(min(a0 + da x, b0 + db x, c0 + dc x), lo))
       for x in [x0, x1]; the row has `room` floats (>= 8) */
    void (*span)(float *row, int x0, int x1, int room, float a0, float da, float b0, float db, float c0, float dc,
                 float lo);
    /* span over the 8 rows of a tile row whose tile tx's pixels are at
       pool + 64 slot[tx] (row r at + 8 r), row r over [x0[r], x1[r]]
       (none where x0[r] > x1[r]) less the columns [g0, g1] (none where
       g0 > g1), from a0, b0, c0 = z0[r], z0[8 + r], z0[16 + r] */
    void (*spans)(float *pool, const uint32_t *slot, const int *x0, const int *x1, int g0, int g1, const float *z0,
                  float da, float db, float dc, float lo);
    /* any row[x] <= z for x in [x0, x1]? */
    bool (*any_le)(const float *row, int x0, int x1, int room, float z);
    /* out[t] = min, out_max[t] = max over the 64 pixels at pool + 64 slot[t] */
    void (*tiles)(const float *pool, const uint32_t *slot, uint32_t ntiles, float *out, float *out_max);
    void (*fill)(float *row, uint32_t n, float v);
    /* out[x] = a[x] > b[x] ? a[x] : b[x] for x in [0, n) */
    void (*max2)(float *out, const float *a, const float *b, uint32_t n);
    /* cull_occ_rect_visible's answer, by the walk of cull_occ_test.inl
       (vkey, strips, pixel rows a vector at a time) */
    bool (*rect_visible)(const struct cull_occ_buffer *b, int x0, int y0, int x1, int y1, float z);
    /* lanes (bit k: lane k, k < 8) of the float pixel bounds fx0..fy1
       (the kernel's, in [-1, w + 1] x [-1, h + 1]) visible at nearness
       z: what the kernel's occlusion stage asks per group */
    uint32_t (*lanes)(const struct cull_occ_buffer *b, const float *fx0, const float *fx1, const float *fy0,
                      const float *fy1, const float *z, uint32_t lanes);
    /* rows jb .. jb + 7 of a polygon (rs without slow constraints):
       row r's pixel span [lo[r], hi[r]] (empty outside a..b) and its
       three planes' start nearness z0[r], z0[8 + r], z0[16 + r] (every
       row), and their sums; the same bits in every instance */
    cull_occ_rowsum (*rows)(const cull_occ_rowset *rs, int jb, int a, int b, int *lo, int *hi, float *z0);
    /* boxes idx[0..n) of s projected as cull_occ_project_bound does:
       out[k * pitch + i] for k = 0..5 the NDC x min, x max, y min,
       y max, the far nearness, and 1 where the box reaches the near plane
       (0 otherwise; the rest is then unused); pitch >= n rounded up to 4 */
    void (*project)(const struct cull_occ_buffer *b, const cull_bounds_soa *s, const uint32_t *idx, uint32_t n,
                    double *out, size_t pitch);
} cull_occ_fns;

cull_occ_fns cull_occ_fns_for(uint32_t isa);
void cull_occ_span_scalar(float *, int, int, int, float, float, float, float, float, float, float);
void cull_occ_span_sse41(float *, int, int, int, float, float, float, float, float, float, float);
void cull_occ_span_avx2(float *, int, int, int, float, float, float, float, float, float, float);
void cull_occ_spans_scalar(float *, const uint32_t *, const int *, const int *, int, int, const float *, float,
                           float, float, float);
void cull_occ_spans_sse41(float *, const uint32_t *, const int *, const int *, int, int, const float *, float,
                          float, float, float);
void cull_occ_spans_avx2(float *, const uint32_t *, const int *, const int *, int, int, const float *, float, float,
                         float, float);
/* rows: the reference (any rowset, slow constraints included; every
   ISA without its own), and AVX2's (4 rows a vector) */
cull_occ_rowsum cull_occ_rows_scalar(const cull_occ_rowset *, int, int, int, int *, int *, float *);
cull_occ_rowsum cull_occ_rows_avx2(const cull_occ_rowset *, int, int, int, int *, int *, float *);
void cull_occ_project_scalar(const struct cull_occ_buffer *, const cull_bounds_soa *, const uint32_t *, uint32_t,
                             double *, size_t);
void cull_occ_project_avx2(const struct cull_occ_buffer *, const cull_bounds_soa *, const uint32_t *, uint32_t,
                           double *, size_t);
bool cull_occ_any_le_scalar(const float *, int, int, int, float);
void cull_occ_tiles_scalar(const float *, const uint32_t *, uint32_t, float *, float *);
void cull_occ_fill_scalar(float *, uint32_t, float);
void cull_occ_max2_scalar(float *, const float *, const float *, uint32_t);
bool cull_occ_rect_visible_scalar(const struct cull_occ_buffer *, int, int, int, int, float);
uint32_t cull_occ_lanes_scalar(const struct cull_occ_buffer *, const float *, const float *, const float *,
                              const float *, const float *, uint32_t);
bool cull_occ_any_le_sse41(const float *, int, int, int, float);
void cull_occ_tiles_sse41(const float *, const uint32_t *, uint32_t, float *, float *);
void cull_occ_fill_sse41(float *, uint32_t, float);
void cull_occ_max2_sse41(float *, const float *, const float *, uint32_t);
bool cull_occ_rect_visible_sse41(const struct cull_occ_buffer *, int, int, int, int, float);
uint32_t cull_occ_lanes_sse41(const struct cull_occ_buffer *, const float *, const float *, const float *,
                              const float *, const float *, uint32_t);
bool cull_occ_any_le_avx2(const float *, int, int, int, float);
void cull_occ_tiles_avx2(const float *, const uint32_t *, uint32_t, float *, float *);
void cull_occ_fill_avx2(float *, uint32_t, float);
void cull_occ_max2_avx2(float *, const float *, const float *, uint32_t);
bool cull_occ_rect_visible_avx2(const struct cull_occ_buffer *, int, int, int, int, float);
uint32_t cull_occ_lanes_avx2(const struct cull_occ_buffer *, const float *, const float *, const float *,
                              const float *, const float *, uint32_t);

/* Inclusive pixel rectangle and the nearest nearness of what it bounds. */
typedef struct cull_occ_rect {
    int x0, y0, x1, y1;
    float z;
} cull_occ_rect;

enum { OCC_BOX_OFF = 0, OCC_BOX_OK = 1, OCC_BOX_NEAR = 2 };
/* tstate's "pixels stale" (cull_occ_num.h's TILE_INVALID), for the walk */
enum { OCC_TILE_INVALID = 0 };

/* A cluster in view, for the sorted draw list. */
typedef struct cull_occ_item {
    const cull_occ_cluster *cl;
    cull_occ_rect r;
    float key;          /* nearness of its nearest point; +inf at the near plane */
    bool near;          /* reaches the near plane: drawn in every band */
} cull_occ_item;

struct cull_occ_buffer {
    uint32_t w, h;          /* pixels */
    uint32_t stride, hp;    /* allocated row length (multiple of 128) and rows (of 64) */
    uint32_t tw, th, t2w, t2h; /* 8x8 and 64x64 tiles */
    /* The pixels, 8x8 tile by tile: tile t's 64 (row 0 = bottom, 8 a
       row) are at pool + 64 tslot[t] while t is not TILE_INVALID. A
       render hands out slots as spans first write into tiles, in that
       order, from each band's own range of the pool (a band's tile rows'
       worth: slot_next[k] is band k's next), so the pixels a render
       writes lie together in memory, in the order it wrote them: right
       after other work they stream in, where a whole plane's rows
       (stride floats apart) were fetched a line at a time, 8 lines a
       tile. cull_occ_depth copies them out to plane (stride x hp). */
    float   *pool;
    uint32_t *tslot;        /* per tile */
    uint32_t slot_next[CULL_OCC_MAX_BANDS];
    float   *plane;         /* cull_occ_depth's copy, made on demand */
    float   *tile, *tile2;  /* minima */
    float   *tile_full;     /* per 8x8 tile, a value every pixel's stands at or above */
    float   *teff;          /* per tile, after a render: the larger of tile_full and
                               the pixels' minimum (what the tests read first) */
    float   *tmax;          /* per tile: its pixels' maximum, padding included,
                               taken with the minimum where the tile is not
                               TILE_INVALID; EMPTY where it is */
    float   *vkey;          /* per tile, after a render: a rectangle test with
                               z >= vkey that reaches the tile is visible (a
                               pixel <= z in any part of it): teff for an
                               invalid tile, else the larger of teff and the
                               maximum of its real pixels (cull_occ_vkey_row) */
    uint8_t *tstate;        /* per tile: pixels stale / minimum current / written since */
    uint32_t tpitch;        /* bytes per tile row of tstate */
    float   *strip;         /* per 8 tiles of a tile row: minimum of their effective minima */
    uint8_t *sdirty;        /* strip written since its minimum was taken */
    uint32_t spitch, sdpitch; /* strip row pitches, floats and bytes */
    bool     drawn;         /* the last render set some pixel */
    bool     usable;        /* the view admits the nearness mapping */
    bool     inner;         /* coverage = pixel squares fully inside */
    uint32_t threads_used;
    uint32_t isa;           /* default for cull_occ_render */
    cull_occ_fns fns;
    /* the view: rows x, y, w of the view-projection, the nearness numerator
       and the near plane, over (p - origin, 1) */
    double   origin[3];
    double   rx[4], ry[4], rw[4], rd[4], rn[4];
    double   sx, sy;        /* w / 2, h / 2 */
    cull_occ_item *items, *items2; /* the draw list, and room to sort it */
    uint32_t nitems, items_cap, items2_cap;
    uint64_t *sortbuf;
    uint32_t sortbuf_cap;
    uint8_t *codes;         /* box-stage output over the world's clusters */
    uint32_t codes_cap;
    uint32_t *pidx;         /* the clusters in view, to project */
    double  *proj;          /* their projections, 6 arrays of pcap (cull_occ_fns.project) */
    uint32_t pidx_cap, proj_cap;
    int32_t *pcode;         /* their answers (cull_occ_rects_avx2) */
    cull_occ_rect *rects;   /* and rectangles */
    uint32_t pcode_cap, rects_cap;
};

/* The 64 pixels of tile t (not TILE_INVALID), 8 a row from the bottom. */
static inline float *cull_occ_tile_px(const cull_occ_buffer *b, size_t t)
{
    return b->pool + ((size_t)b->tslot[t] << 6);
}

void cull_occ_setup_view(cull_occ_buffer *b, const cull_view *v);
/* vkey of tile row ty from teff, tmax and tstate (after its tiles are final) */
void cull_occ_vkey_row(cull_occ_buffer *b, uint32_t ty);
int  cull_occ_project_box(const cull_occ_buffer *b, const double mn[3], const double mx[3], cull_occ_rect *r);
/* Looser and cheaper (4 divisions, not 8 corners): for clusters and cells. */
int  cull_occ_project_bound(const cull_occ_buffer *b, const double mn[3], const double mx[3], cull_occ_rect *r);
/* cull_occ_project_bound's answer from a projection (o[0..5] as
   cull_occ_fns.project gives them) */
int  cull_occ_bound_rect(const cull_occ_buffer *b, const double o[6], cull_occ_rect *r);
/* cull_occ_bound_rect over n projections pitch apart, four a vector
   (AVX2): code[i] its answer, r[i] the rectangle where OCC_BOX_OK */
void cull_occ_rects_avx2(const cull_occ_buffer *b, const double *proj, size_t pitch, uint32_t n, int32_t *code,
                         cull_occ_rect *r);
int  cull_occ_render_isa(const cull_world *w, const cull_view *v, cull_occ_buffer *b, cull_pool *pool,
                         uint32_t threads, uint32_t isa, const uint64_t *sublevels, cull_occ_stats *st);
/* the same in the render's baseline build whatever the ISA (its kernels
   still the ISA's): the tests' reference for the AVX2 build */
int  cull_occ_render_generic(const cull_world *w, const cull_view *v, cull_occ_buffer *b, cull_pool *pool,
                             uint32_t threads, uint32_t isa, const uint64_t *sublevels, cull_occ_stats *st);
/* the same, the render's AVX2 build (cull_occ_raster_avx2.c) */
int  cull_occ_render_avx2(const cull_world *w, const cull_view *v, cull_occ_buffer *b, cull_pool *pool,
                          uint32_t threads, uint32_t isa, const uint64_t *sublevels, cull_occ_stats *st);

#endif
