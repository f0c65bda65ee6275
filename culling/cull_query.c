/*
 * cull_query.c — the query pipeline driver.
 *
 *   1. box stage (SIMD, double; cull_cells.inl): each region's bounds (8^3
 *      cells) against each view's planes, then the cells of the regions a
 *      view may see, against only the planes the region straddles.
 *      A cell outside a view drops that view; a plane the cell is entirely
 *      inside is dropped; a cell with no views left is skipped whole. What
 *      survives is re-based to the cell origin and rounded to float
 *      (cull_kview), so the kernels work on small, exact-enough numbers.
 *   2. block stage (SIMD kernel): spheres -> AABB -> screen area -> results.
 *      One thread: straight into the caller's buffer. Several: blocks are
 *      handed out in chunks by an atomic counter; each thread writes to its
 *      own scratch, then the chunks are copied to the caller's buffer in
 *      chunk order, in parallel, so the order never depends on threads.
 *
 * Costs: stage 1 is ~60 flops per cell and view; stage 2 is in
 * cull_kernel.inl. The context allocates only when the world has grown.
 */
#include "cull_internal.h"
#include "cull_occ.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define CHUNK_BLOCKS 8u          /* 512 entities per chunk */
#define PARALLEL_MIN_WORK 32768u /* entity x view tests below which one thread wins */
#define MAX_THREADS 64u

typedef struct cull_item {
    const cull_block *block;
    uint32_t n;       /* entities in the block */
    uint32_t kv_off;  /* first cull_kview of its cell */
    uint32_t nv;      /* views the cell kept */
    cull_occ_memo *rec; /* its record against a kept buffer, or NULL */
} cull_item;

typedef struct cull_chunk {
    uint32_t thread, off, count, dst;
} cull_chunk;

/* A cell's verdict against a kept buffer: whether its bounds (origin,
 * bmin, bmax) were hidden. cell_occluded is a function of those and of
 * the buffer alone, so while the buffer is kept the verdict stands for
 * any cell with the same bounds. */
typedef struct occ_cell_memo {
    double origin[3];
    float  bmin[3], bmax[3];
    bool   occluded;
    const cull_cell *cell;  /* the cell and its stamp last seen with these */
    uint64_t stamp;         /* bounds: the same again, no compare */
} occ_cell_memo;

/* What a context's occlusion buffer for one view index was rendered
 * from: when a query asks for the same again, the buffer is kept (a still
 * camera of a stream or a commander re-queries many times a second). */
typedef struct occ_key {
    bool valid;
    const cull_world *w;
    uint64_t version;           /* w->occ_version */
    cull_view view;             /* compared field by field (it has padding) */
    uint32_t inner, isa;
    uint32_t nsub;              /* UINT32_MAX: every sub-level; else the set's words to its last non-zero one */
    uint64_t *sub;
    uint32_t sub_cap;
    /* the cell stage's verdicts against this buffer, in the order the
       cells were tested since it was drawn (the order a still world
       repeats): a cell's projection and walk (~500 instructions) become a
       48-byte compare. Emptied whenever the buffer is drawn. */
    occ_cell_memo *memo;
    uint32_t memo_n, memo_cap;
    /* the kernel's verdicts against this buffer, per block in query order
       (single-view cells only; at most OCC_BLOCK_MEMO_MAX blocks, 1.6 KB
       each): invalidated whenever the buffer is drawn */
    cull_occ_memo *bmemo;
    uint32_t bmemo_cap;
    uint64_t bgen;              /* records of another generation are not
                                   valid: emptying them is bgen++ */
    /* the kernel parameters the records were made with (a record that
       stands says which lanes reach the occlusion stage: the same only
       for the same stages) */
    float kp_min_area;
    uint32_t kp_flags;
} occ_key;

#define OCC_BLOCK_MEMO_MAX 2048u
/* block records for the first views of a query only: at most 4 x 3.3 MB per
   context (a worker's), not 32 x (a stream or a commander queries one or
   two views; a 32-view query's later views are tested, not recorded) */
#define OCC_BLOCK_MEMO_VIEWS 4u

struct cull_ctx {
    cull_pool *pool;
    uint32_t isa;
    cull_block_fn kernel;
    cull_cells_fn cells;
    uint8_t *codes;         /* cell stage output: [view][cell] */
    uint32_t codes_cap;
    cull_kview *kv;
    uint32_t kv_cap;
    cull_item *items;
    uint32_t items_cap;
    cull_chunk *chunks;
    uint32_t chunks_cap;
    cull_result *tres[MAX_THREADS];
    uint32_t tres_cap[MAX_THREADS];
    cull_occ_buffer *occ[CULL_MAX_VIEWS]; /* per view index, made on demand */
    occ_key occ_key[CULL_MAX_VIEWS];      /* what each was rendered from */
};

int cull_ctx_create(cull_pool *pool, cull_ctx **out)
{
    if (!out) return CULL_ERR_INVALID;
    cull_ctx *c = calloc(1, sizeof *c);
    if (!c) return CULL_ERR_NOMEM;
    c->pool = pool;
    c->isa = cull_isa_default();
    c->kernel = cull_isa_kernel(c->isa);
    c->cells = cull_isa_cells(c->isa);
    *out = c;
    return CULL_OK;
}

void cull_ctx_destroy(cull_ctx *c)
{
    if (!c) return;
    free(c->kv);
    free(c->codes);
    free(c->items);
    free(c->chunks);
    for (uint32_t i = 0; i < MAX_THREADS; i++) free(c->tres[i]);
    for (uint32_t i = 0; i < CULL_MAX_VIEWS; i++) {
        cull_occ_buffer_destroy(c->occ[i]);
        free(c->occ_key[i].sub);
        free(c->occ_key[i].memo);
        free(c->occ_key[i].bmemo);
    }
    free(c);
}

int cull_ctx_set_isa(cull_ctx *c, uint32_t isa)
{
    if (!c || isa >= CULL_ISA_COUNT || !cull_isa_supported(isa)) return CULL_ERR_INVALID;
    c->isa = isa;
    c->kernel = cull_isa_kernel(isa);
    c->cells = cull_isa_cells(isa);
    return CULL_OK;
}

uint32_t cull_ctx_isa(const cull_ctx *c)
{
    return c ? c->isa : CULL_ISA_SCALAR;
}

/* The words of a sub-level set up to its last non-zero one (UINT32_MAX:
 * no set, every sub-level). */
static uint32_t sub_words(const uint64_t *subs)
{
    if (!subs) return UINT32_MAX;
    uint32_t n = CULL_SUBLEVEL_WORDS;
    while (n && !subs[n - 1]) n--;
    return n;
}

static bool view_same(const cull_view *a, const cull_view *b)
{
    return a->plane_count == b->plane_count && a->depth_mode == b->depth_mode && a->viewport_w == b->viewport_w &&
           a->viewport_h == b->viewport_h && !memcmp(a->plane, b->plane, sizeof a->plane) &&
           !memcmp(a->clip, b->clip, sizeof a->clip) && !memcmp(a->origin, b->origin, sizeof a->origin);
}

/* Whether k says buffer b holds what rendering v of w now would give. */
static bool occ_key_same(const occ_key *k, const cull_world *w, const cull_view *v, uint32_t inner, uint32_t isa,
                         const uint64_t *subs, uint32_t nsub)
{
    return k->valid && k->w == w && k->version == w->occ_version && k->inner == inner && k->isa == isa &&
           k->nsub == nsub && view_same(&k->view, v) &&
           (nsub == UINT32_MAX || !memcmp(k->sub, subs, (size_t)nsub * sizeof *subs));
}

/* Records what the buffer was just rendered from; false (the key left
 * invalid: the next query renders again) without memory for the set. */
static bool occ_key_set(occ_key *k, const cull_world *w, const cull_view *v, uint32_t inner, uint32_t isa,
                        const uint64_t *subs, uint32_t nsub)
{
    k->valid = false;
    if (nsub != UINT32_MAX && nsub > k->sub_cap) {
        uint64_t *p = realloc(k->sub, (size_t)nsub * sizeof *p);
        if (!p) return false;
        k->sub = p;
        k->sub_cap = nsub;
    }
    if (nsub != UINT32_MAX && nsub) memcpy(k->sub, subs, (size_t)nsub * sizeof *subs);
    k->w = w;
    k->version = w->occ_version;
    k->view = *v;
    k->inner = inner;
    k->isa = isa;
    k->nsub = nsub;
    k->valid = true;
    return true;
}

/* What the region stage leaves for one view: the planes the region
 * straddles, compacted for the cell kernel, and where they came from. */
typedef struct region_view {
    uint32_t view;
    uint32_t np;
    cull_cplane pl[6];
    uint8_t from[6];  /* pl[k] is the view's plane from[k] */
} region_view;

/* Whether a cell's bounds are entirely behind view v's occluders. */
static bool cell_occluded(const cull_cell *cell, const cull_occ_buffer *ob)
{
    double mn[3], mx[3];
    for (int a = 0; a < 3; a++) {
        mn[a] = cell->origin[a] + cell->bmin[a];
        mx[a] = cell->origin[a] + cell->bmax[a];
    }
    cull_occ_rect r;
    switch (cull_occ_project_bound(ob, mn, mx, &r)) {
    case OCC_BOX_OFF: return true;
    case OCC_BOX_NEAR: return false;
    default: return !ob->fns.rect_visible(ob, r.x0, r.y0, r.x1, r.y1, r.z);
    }
}

/* cell_occluded through the memo of a kept buffer (NULL: none, a caller's
 * buffer); *pos counts the view's cell tests in this query. A verdict is
 * reused only for the same bounds at the same position; the rest are
 * tested and recorded while the memo stays contiguous (a failed growth
 * records nothing: the verdicts are the same, only not kept). */
static bool cell_occluded_kept(const cull_cell *cell, const cull_occ_buffer *ob, occ_key *k, uint32_t *pos)
{
    if (!k) return cell_occluded(cell, ob);
    uint32_t i = (*pos)++;
    if (i < k->memo_n) {
        occ_cell_memo *m = &k->memo[i];
        if (m->cell == cell && m->stamp == cell->stamp) return m->occluded;
        if (!memcmp(m->origin, cell->origin, sizeof m->origin) && !memcmp(m->bmin, cell->bmin, sizeof m->bmin) &&
            !memcmp(m->bmax, cell->bmax, sizeof m->bmax)) {
            m->cell = cell;
            m->stamp = cell->stamp;
            return m->occluded;
        }
    }
    bool hidden = cell_occluded(cell, ob);
    if (i <= k->memo_n && vp_grow32((void **)&k->memo, &k->memo_cap, (size_t)i + 1, sizeof *k->memo)) {
        occ_cell_memo *m = &k->memo[i];
        memcpy(m->origin, cell->origin, sizeof m->origin);
        memcpy(m->bmin, cell->bmin, sizeof m->bmin);
        memcpy(m->bmax, cell->bmax, sizeof m->bmax);
        m->occluded = hidden;
        m->cell = cell;
        m->stamp = cell->stamp;
        if (i == k->memo_n) k->memo_n++;
    }
    return hidden;
}

/* The clip rows of view v re-based by t (the cell origin minus the view
 * origin): what the screen-area stage and the occlusion projection read. */
static inline __attribute__((always_inline)) void kview_clip(cull_kview *k, const cull_view *view, const double t[3])
{
    const double *m = view->clip;
    static const int rows[3] = {0, 1, 3};
    float *dst[3] = {k->cx, k->cy, k->cw};
    for (int r = 0; r < 3; r++) {
        int row = rows[r];
        for (int c = 0; c < 3; c++) dst[r][c] = (float)m[c * 4 + row];
        dst[r][3] = (float)(m[row] * t[0] + m[4 + row] * t[1] + m[8 + row] * t[2] + m[12 + row]);
    }
    k->vp_w = (float)view->viewport_w;
    k->vp_h = (float)view->viewport_h;
    k->half_w = 0.5f * k->vp_w;
    k->half_h = 0.5f * k->vp_h;
    for (int c = 0; c < 3; c++) {
        k->hx[c] = 0.5f * k->cx[c];
        k->hy[c] = 0.5f * k->cy[c];
        k->hw[c] = 0.5f * k->cw[c];
        k->ax[c] = fabsf(k->hx[c]);
        k->ay[c] = fabsf(k->hy[c]);
        k->aw[c] = fabsf(k->hw[c]);
    }
    k->off_w = k->half_w - k->half_w * 0x1p-16f;
    k->off_h = k->half_h - k->half_h * 0x1p-16f;
}

/* The occlusion constants of buffer occ re-based by t. */
static inline __attribute__((always_inline)) void kview_occ(cull_kview *k, const cull_occ_buffer *occ, const double t[3])
{
    for (int c = 0; c < 3; c++) k->cd[c] = (float)occ->rd[c];
    k->cd[3] = (float)(occ->rd[0] * t[0] + occ->rd[1] * t[1] + occ->rd[2] * t[2] + occ->rd[3]);
    k->occ_sx = (float)occ->sx;
    k->occ_sy = (float)occ->sy;
    k->occ_w = (float)occ->w;
    k->occ_h = (float)occ->h;
}

/* Whether every block of cell, queried from position pos on, has a record
 * in key k that stands (cull_occ_memo.blk): written by a kernel run over
 * the same block of the same cell contents (stamp) against the same
 * planes, with this buffer. Only records that exist now count (the
 * array grows after the cell stage). */
static bool records_stand(const occ_key *k, const cull_cell *cell, uint32_t pos, const cull_occ_buffer *occ,
                          uint32_t pmask, uint32_t lim)
{
    if (pos >= lim || cell->nblocks > lim - pos) return false;
    for (uint32_t b = 0; b < cell->nblocks; b++) {
        const cull_occ_memo *r = &k->bmemo[pos + b];
        if (r->gen != k->bgen || !r->valid || r->occ != occ || r->blk != cell->blocks[b] || r->stamp != cell->stamp ||
            r->pmask != pmask)
            return false;
    }
    return true;
}

/* The kviews of one cell: every view whose cell code says it may see the
 * cell and whose occluders do not hide it whole, with the planes the cell
 * straddles re-based to the cell origin (double, then float). pos: the
 * query position of the cell's first block. Returns how many; *occluded
 * counts the views dropped by occlusion. */
static inline __attribute__((always_inline)) uint32_t
cell_kviews(const cull_cell *cell, const cull_query_desc *q, const region_view *rv, uint32_t nrv, const uint8_t *codes,
            size_t stride, bool area, const cull_occ_buffer *const *ob, occ_key *const *memo, uint32_t *memo_pos,
            uint32_t pos, const bool *reused, const uint32_t *mlim, cull_kview *kv, uint32_t *occluded,
            const bool with_occ)
{
    uint32_t nv = 0, nhot = 0;
    for (uint32_t a = 0; a < nrv; a++) {
        uint32_t code = codes[a * stride + cell->index];
        if (code & 0x80u) continue;
        const uint32_t v = rv[a].view;
        const cull_occ_buffer *occ = with_occ ? ob[v] : NULL;
        if (occ && cell_occluded_kept(cell, occ, memo[v], &memo_pos[v])) {
            (*occluded)++;
            continue;
        }
        const cull_view *view = &q->views[v];
        double t[3] = {cell->origin[0] - view->origin[0], cell->origin[1] - view->origin[1],
                       cell->origin[2] - view->origin[2]};
        cull_kview *k = &kv[nv++];
        uint32_t np = 0, pmask = 0;
        for (; code; code &= code - 1) {
            uint32_t from = rv[a].from[__builtin_ctz(code)];
            const double *pl = view->plane[from];
            if (with_occ) pmask |= 1u << from;
            k->px[np] = (float)pl[0];
            k->py[np] = (float)pl[1];
            k->pz[np] = (float)pl[2];
            k->pd[np] = (float)(pl[0] * t[0] + pl[1] * t[1] + pl[2] * t[2] + pl[3]);
            np++;
        }
        k->nplanes = np;
        k->pmask = pmask;
        k->bit = 1u << v;
        k->occ = occ;
        k->hot = occ && reused[v] && v < OCC_BLOCK_MEMO_VIEWS && records_stand(memo[v], cell, pos, occ, pmask, mlim[v]);
        nhot += k->hot;
        if (occ && !k->hot) kview_occ(k, occ, t);
        if (area || (occ && !k->hot)) kview_clip(k, view, t);
    }
    /* records serve single-view cells only: the multi-view kernel tests */
    if (with_occ && nhot && nv > 1)
        for (uint32_t i = 0; i < nv; i++) {
            cull_kview *k = &kv[i];
            if (!k->hot) continue;
            const cull_view *view = &q->views[__builtin_ctz(k->bit)];
            double t[3] = {cell->origin[0] - view->origin[0], cell->origin[1] - view->origin[1],
                           cell->origin[2] - view->origin[2]};
            k->hot = 0;
            kview_occ(k, k->occ, t);
            if (!area) kview_clip(k, view, t);
        }
    return nv;
}

/* Entities in block b of cell (all but the last are full). */
static inline uint32_t block_n(const cull_cell *cell, uint32_t b)
{
    uint32_t n = cell->count - b * CULL_BLOCK_CAP;
    return n > CULL_BLOCK_CAP ? CULL_BLOCK_CAP : n;
}

/* The items of a cell's blocks, from position pos on, when some view
 * keeps records: a single-view cell with a kept buffer gets a record per
 * block below the view's limit; one its kview does not read (not hot) is
 * made to stand by the kernel's run over the whole block. */
static void items_recorded(cull_ctx *c, const cull_cell *cell, uint32_t pos, uint32_t kv_off, uint32_t nv,
                           occ_key *const *memo, const uint32_t *mlim)
{
    const cull_kview *k = &c->kv[kv_off];
    const uint32_t v = (uint32_t)__builtin_ctz(k->bit);
    const bool rec = nv == 1 && k->occ && v < OCC_BLOCK_MEMO_VIEWS && memo[v];
    for (uint32_t b = 0; b < cell->nblocks; b++) {
        uint32_t i = pos + b;
        cull_occ_memo *r = rec && i < mlim[v] ? &memo[v]->bmemo[i] : NULL;
        if (r && !k->hot) {
            if (r->gen != memo[v]->bgen) {
                r->gen = memo[v]->bgen;
                r->valid = false;
            }
            r->blk = cell->blocks[b];
            r->stamp = cell->stamp;
            r->pmask = k->pmask;
        }
        c->items[i] = (cull_item){cell->blocks[b], block_n(cell, b), kv_off, nv, r};
    }
}

/* A query that fails after the cell stage may have named records as
 * standing that no kernel wrote: its kept buffers are dropped (the next
 * query draws again, which empties every record). */
static int records_lost(occ_key *const *memo, uint32_t nviews)
{
    for (uint32_t v = 0; v < nviews; v++)
        if (memo[v]) memo[v]->valid = false;
    return CULL_ERR_NOMEM;
}

/* Blocks of different cells are not neighbours in memory, so the hardware
 * prefetcher cannot see the next one coming: fetch the hot prefix (sphere,
 * handle, class, sub-level: 1.5 KiB) of the block PREFETCH_AHEAD items
 * ahead, and its AABBs too when the query will read them. */
#define PREFETCH_AHEAD 6u
#define PREFETCH_MIN_ITEMS 512u /* ~1.5 MiB of hot block data */
/* A query that draws an occlusion buffer has just pushed its blocks out of
 * L1 and L2 (the render writes ~0.5-1 MiB at 1280x720), and after other
 * work they are in memory: its first PREFETCH_EARLY blocks (~150-300 KiB)
 * are fetched as the cell stage names them, so their loads overlap the
 * cell stage's occlusion tests (street walk, 1280x720, cold: ~11 us less),
 * and the rest PREFETCH_AHEAD items ahead. A query that draws nothing
 * finds a few hundred blocks in L2 from one query to the next, where
 * prefetching only costs instructions (15k entities, frustum only: +7 %):
 * it prefetches only past PREFETCH_MIN_ITEMS. */
#define PREFETCH_EARLY 96u

/* Cells are separate allocations too, and a cell's occlusion test is long
 * enough that the out-of-order window never reaches the next cell's loads:
 * a query right after other work waited on each cell in turn (street walk,
 * 1280x720: the cell stage 77-84 us cold against 23 warm). Both lines of
 * the cell CELL_PREFETCH_AHEAD cells ahead are fetched while this one is
 * tested (39-43 us cold). */
#define CELL_PREFETCH_AHEAD 6u
static inline void prefetch_cell(const cull_cell *c)
{
    __builtin_prefetch(c, 0, 3);
    __builtin_prefetch((const char *)c + 64, 0, 3);
}

static inline void prefetch_block(const cull_block *b, bool boxes)
{
    const char *p = (const char *)b;
    size_t end = boxes ? sizeof *b : CULL_BLOCK_HOT_BYTES;
    for (size_t off = 0; off < end; off += 64) __builtin_prefetch(p + off, 0, 3);
}

/* Keeps the results of out[0..n) whose sub-level the query sees, in order;
 * returns how many. */
static uint32_t keep_sublevels(cull_result *out, uint32_t n, const uint64_t *set)
{
    uint32_t k = 0;
    for (uint32_t i = 0; i < n; i++)
        if (cull_sublevel_in(set, out[i].sublevel)) out[k++] = out[i];
    return k;
}

typedef struct job {
    cull_ctx *c;
    const cull_kparams *kp;
    const uint64_t *subs;   /* the query's sub-levels, or NULL */
    const cull_item *items;
    uint32_t nitems, nchunks;
    bool prefetch, boxes;
    uint32_t early;         /* blocks the cell stage prefetched */
    _Atomic uint32_t next;
    cull_result *out;
    cull_kcount cnt[MAX_THREADS];
    uint32_t filtered[MAX_THREADS];
} job;

static void job_cull(void *arg, uint32_t t)
{
    job *j = arg;
    cull_ctx *c = j->c;
    cull_result *dst = c->tres[t];
    uint32_t off = 0;
    cull_kcount cnt = {0};
    for (;;) {
        uint32_t ch = atomic_fetch_add_explicit(&j->next, 1, memory_order_relaxed);
        if (ch >= j->nchunks) break;
        uint32_t start = off;
        uint32_t end = (ch + 1) * CHUNK_BLOCKS;
        if (end > j->nitems) end = j->nitems;
        for (uint32_t i = ch * CHUNK_BLOCKS; i < end; i++) {
            const cull_item *it = &j->items[i];
            if (j->prefetch && i + PREFETCH_AHEAD >= j->early && i + PREFETCH_AHEAD < j->nitems)
                prefetch_block(j->items[i + PREFETCH_AHEAD].block, j->boxes);
            uint32_t k = c->kernel(it->block, it->n, c->kv + it->kv_off, it->nv, j->kp, dst + off, &cnt,
                                  it->rec);
            if (j->subs) {
                uint32_t kept = keep_sublevels(dst + off, k, j->subs);
                j->filtered[t] += k - kept;
                k = kept;
            }
            off += k;
        }
        c->chunks[ch] = (cull_chunk){.thread = t, .off = start, .count = off - start};
    }
    j->cnt[t] = cnt;
}

static void job_copy(void *arg, uint32_t t)
{
    job *j = arg;
    cull_ctx *c = j->c;
    for (uint32_t ch = 0; ch < j->nchunks; ch++) {
        const cull_chunk *k = &c->chunks[ch];
        if (k->thread == t && k->count)
            memcpy(j->out + k->dst, c->tres[t] + k->off, k->count * sizeof *j->out);
    }
}

int cull_query(const cull_world *w, cull_ctx *c, const cull_query_desc *q,
               cull_result *out, size_t cap, size_t *count, cull_query_stats *stats)
{
    if (count) *count = 0;
    if (stats) memset(stats, 0, sizeof *stats);
    if (!w || !c || !q || !count || (!out && cap)) return CULL_ERR_INVALID;
    bool count_only = (q->flags & CULL_Q_COUNT_ONLY) != 0;
    /* the sub-level filter reads each result's sub-level: with it, results
       are written even when only counted (to the context's scratch) */
    const uint64_t *subs = q->sublevels;
    uint64_t subs_fold = 0;
    if (subs)
        for (uint32_t i = 0; i < CULL_SUBLEVEL_WORDS; i++) subs_fold |= subs[i];
    if (!q->views || q->view_count == 0 || q->view_count > CULL_MAX_VIEWS) return CULL_ERR_VIEWS;
    if (!(q->min_screen_area >= 0) || q->min_screen_area > 1e12f) return CULL_ERR_INVALID;
    for (uint32_t v = 0; v < q->view_count; v++)
        if (q->views[v].plane_count < 5 || q->views[v].plane_count > 6) return CULL_ERR_MATRIX;
    if (!count_only && cap < cull_query_bound(w)) return CULL_ERR_OUTPUT;

    cull_kparams kp = {
        .min_area = q->min_screen_area,
        .aabb = !(q->flags & CULL_Q_NO_AABB),
        .area = q->min_screen_area > 0 || (q->flags & CULL_Q_WANT_AREA),
        .exact_area = (q->flags & CULL_Q_WANT_AREA) != 0,
        .count_only = count_only && !subs,
    };

    const uint32_t kp_flags = (uint32_t)kp.aabb | (uint32_t)kp.area << 1 | (uint32_t)kp.exact_area << 2;

    /* the occlusion stage: a buffer per view, given or rendered here */
    const cull_occ_buffer *ob[CULL_MAX_VIEWS] = {0};
    occ_key *memo[CULL_MAX_VIEWS] = {0}; /* the context's buffers: their cell verdicts */
    bool reused[CULL_MAX_VIEWS] = {0};   /* ... kept from an earlier query: records may stand */
    uint32_t memo_pos[CULL_MAX_VIEWS] = {0};
    uint32_t occ_views = 0, occ_drawn = 0, occ_reused = 0, occ_rendered = 0;
    uint64_t occ_ns = 0;
    if (!(q->flags & CULL_Q_NO_OCCLUSION) && (q->occ_buffers || w->nocc)) {
        uint32_t ow = q->occ_w ? q->occ_w : CULL_OCC_DEFAULT_W, oh = q->occ_h ? q->occ_h : CULL_OCC_DEFAULT_H;
        uint32_t inner = !(q->flags & CULL_Q_OCC_CENTRE), nsub = q->occ_buffers ? 0 : sub_words(q->sublevels);
        for (uint32_t v = 0; v < q->view_count; v++) {
            cull_occ_buffer *b;
            if (q->occ_buffers) {
                b = q->occ_buffers[v];
                if (!b) continue;
            } else {
                b = c->occ[v];
                occ_key *k = &c->occ_key[v];
                if (!b || b->w != ow || b->h != oh) {
                    cull_occ_buffer *nb;
                    int rc = cull_occ_buffer_create(ow, oh, &nb);
                    if (rc != CULL_OK) return rc;
                    cull_occ_buffer_destroy(c->occ[v]);
                    c->occ[v] = b = nb;
                    k->valid = false;
                }
                if (!(q->flags & CULL_Q_OCC_FRESH) && occ_key_same(k, w, &q->views[v], inner, c->isa, q->sublevels, nsub)) {
                    occ_reused++;
                    reused[v] = true;
                    if (k->kp_flags != kp_flags || k->kp_min_area != kp.min_area) {
                        k->bgen++;
                        k->kp_flags = kp_flags;
                        k->kp_min_area = kp.min_area;
                    }
                } else {
                    k->valid = false; /* a failed render leaves the buffer half drawn */
                    k->memo_n = 0;
                    k->bgen++;
                    k->kp_flags = kp_flags;
                    k->kp_min_area = kp.min_area;
                    b->inner = inner;
                    cull_occ_stats st;
                    int rc = cull_occ_render_isa(w, &q->views[v], b, c->pool, q->threads, c->isa, q->sublevels, &st);
                    if (rc != CULL_OK) return rc;
                    occ_ns += st.raster_ns;
                    occ_drawn += st.clusters_drawn;
                    occ_rendered++;
                    occ_key_set(k, w, &q->views[v], inner, c->isa, q->sublevels, nsub);
                }
                memo[v] = k;
            }
            if (b->drawn && b->usable) {
                ob[v] = b;
                occ_views++;
            }
        }
    }

    /* world-space planes for the box kernel */
    cull_cplane cpl[CULL_MAX_VIEWS][6];
    for (uint32_t v = 0; v < q->view_count; v++) {
        const cull_view *view = &q->views[v];
        for (uint32_t i = 0; i < view->plane_count; i++) {
            const double *pl = view->plane[i];
            for (int a = 0; a < 3; a++) {
                cpl[v][i].n[a] = pl[a];
                cpl[v][i].an[a] = fabs(pl[a]);
            }
            cpl[v][i].d = pl[3] - pl[0] * view->origin[0] - pl[1] * view->origin[1] - pl[2] * view->origin[2];
        }
    }

    /* a single-view cell with a kept buffer: each of its blocks' verdicts
       are recorded and read back, the block's place in the query's order
       naming its record (frustum-only queries, and queries that draw the
       buffer, whose view may well move on, skip this). The records are
       grown first, for as many blocks as the world has (at most
       OCC_BLOCK_MEMO_MAX): pointers into them are taken block by block. A
       view whose records cannot grow keeps the ones it has. */
    bool have_memo = false;
    uint32_t mlim[OCC_BLOCK_MEMO_VIEWS] = {0};
    const uint32_t nmemo = w->nblocks_total < OCC_BLOCK_MEMO_MAX ? w->nblocks_total : OCC_BLOCK_MEMO_MAX;
    for (uint32_t v = 0; v < q->view_count && v < OCC_BLOCK_MEMO_VIEWS; v++) {
        occ_key *k = memo[v];
        if (!k || !ob[v] || !reused[v]) continue; /* a buffer drawn now: its first re-query records */
        uint32_t old = k->bmemo_cap;
        if (nmemo > old && vp_grow32((void **)&k->bmemo, &k->bmemo_cap, nmemo, sizeof *k->bmemo))
            for (uint32_t m = old; m < k->bmemo_cap; m++) k->bmemo[m].gen = 0; /* bgen >= 1 once drawn */
        mlim[v] = k->bmemo_cap < OCC_BLOCK_MEMO_MAX ? k->bmemo_cap : OCC_BLOCK_MEMO_MAX;
        have_memo = true;
    }

    /* stage 1: regions, then the cells of the regions some view may see */
    const bool boxes = kp.area || occ_views; /* stage 2 reads the AABBs too */
    const uint32_t early = occ_rendered ? PREFETCH_EARLY : 0;
    const size_t cstride = CULL_REGION_CELLS * CULL_REGION_CELLS * CULL_REGION_CELLS + 4;
    region_view rv[CULL_MAX_VIEWS];
    uint32_t nkv = 0, nitems = 0, tested = 0;
    uint32_t regions = 0, regions_culled = 0, cells = 0, cells_culled = 0, cells_occluded = 0, cells_filtered = 0;
    for (int g = 0; g < 2; g++) {
        if ((q->flags & CULL_Q_STATIC_ONLY) && g == 1) continue;
        if ((q->flags & CULL_Q_DYNAMIC_ONLY) && g == 0) continue;
        const cull_grid *grid = &w->grid[g];
        if (!grid->nregions) continue;
        regions += grid->nregions;
        cells += grid->ncells;
        size_t rstride = (grid->nregions + 4u) & ~(size_t)3;
        if (!vp_grow32((void **)&c->codes, &c->codes_cap, (rstride + cstride) * q->view_count, 1))
            return records_lost(memo, q->view_count);
        uint8_t *rcodes = c->codes, *ccodes = c->codes + rstride * q->view_count;
        for (uint32_t v = 0; v < q->view_count; v++)
            c->cells(&grid->soa, grid->nregions, cpl[v], q->views[v].plane_count, rcodes + v * rstride);
        for (uint32_t ri = 0; ri < grid->nregions; ri++) {
            const cull_region *region = grid->regions[ri];
            uint32_t nrv = 0;
            for (uint32_t v = 0; v < q->view_count; v++) {
                uint32_t code = rcodes[v * rstride + ri];
                if (code & 0x80u) continue;
                region_view *r = &rv[nrv++];
                r->view = v;
                r->np = 0;
                for (; code; code &= code - 1) {
                    uint32_t i = (uint32_t)__builtin_ctz(code);
                    r->from[r->np] = (uint8_t)i;
                    r->pl[r->np++] = cpl[v][i];
                }
            }
            if (!nrv) {
                regions_culled++;
                cells_culled += region->ncells;
                continue;
            }
            for (uint32_t a = 0; a < nrv; a++) {
                if (rv[a].np) c->cells(&region->soa, region->ncells, rv[a].pl, rv[a].np, ccodes + a * cstride);
                else memset(ccodes + a * cstride, 0, region->ncells); /* region inside every plane */
            }
            /* the cells some view's frustum reaches, found from the codes
               alone: a cell out of every view is not read (with a
               sub-level filter every cell is, to count the ones it drops
               as filtered, as before) */
            uint16_t live[CULL_REGION_CELLS * CULL_REGION_CELLS * CULL_REGION_CELLS];
            uint32_t nlive = 0;
            for (uint32_t ci = 0; ci < region->ncells; ci++) {
                uint32_t in = 0;
                for (uint32_t a = 0; a < nrv; a++) in |= ~ccodes[a * cstride + ci] & 0x80u;
                if (in || subs) live[nlive++] = (uint16_t)ci;
                else cells_culled++;
            }
            for (uint32_t li = 0; li < nlive && li < CELL_PREFETCH_AHEAD; li++) prefetch_cell(region->cells[live[li]]);
            for (uint32_t li = 0; li < nlive; li++) {
                const cull_cell *cell = region->cells[live[li]];
                if (li + CELL_PREFETCH_AHEAD < nlive) prefetch_cell(region->cells[live[li + CELL_PREFETCH_AHEAD]]);
                if (subs && !(cell->subs & subs_fold)) {
                    cells_filtered++;
                    continue;
                }
                if (!vp_grow32((void **)&c->kv, &c->kv_cap, (size_t)nkv + nrv, sizeof *c->kv) ||
                    !vp_grow32((void **)&c->items, &c->items_cap, (size_t)nitems + cell->nblocks, sizeof *c->items))
                    return records_lost(memo, q->view_count);
                uint32_t nv = occ_views ? cell_kviews(cell, q, rv, nrv, ccodes, cstride, kp.area, ob, memo, memo_pos,
                                                      nitems, reused, mlim, c->kv + nkv, &cells_occluded, true)
                                        : cell_kviews(cell, q, rv, nrv, ccodes, cstride, kp.area, ob, memo, memo_pos,
                                                      nitems, reused, mlim, c->kv + nkv, &cells_occluded, false);
                if (!nv) {
                    cells_culled++;
                    continue;
                }
                for (uint32_t b = 0; b < cell->nblocks && nitems + b < early; b++) prefetch_block(cell->blocks[b], boxes);
                if (have_memo) {
                    items_recorded(c, cell, nitems, nkv, nv, memo, mlim);
                    nitems += cell->nblocks;
                    tested += cell->count;
                } else {
                    for (uint32_t b = 0; b < cell->nblocks; b++)
                        c->items[nitems++] = (cull_item){cell->blocks[b], block_n(cell, b), nkv, nv, NULL};
                    tested += cell->count;
                }
                nkv += nv;
            }
        }
    }

    /* stage 2: blocks */
    uint32_t threads = cull_pool_threads(c->pool);
    if (q->threads && q->threads < threads) threads = q->threads;
    if (threads > MAX_THREADS) threads = MAX_THREADS;
    uint64_t work = 0;
    for (uint32_t i = 0; i < nitems; i++) work += (uint64_t)c->items[i].n * c->items[i].nv;
    if (!q->threads && work < PARALLEL_MIN_WORK) threads = 1;

    /* the blocks past the early ones, PREFETCH_AHEAD items ahead */
    bool prefetch = occ_rendered ? nitems > early : nitems > PREFETCH_MIN_ITEMS;
    cull_kcount total = {0};
    size_t written = 0;
    uint32_t filtered = 0;
    if (threads == 1) {
        /* counting through the filter: one block's results at a time */
        if (count_only && subs &&
            !vp_grow32((void **)&c->tres[0], &c->tres_cap[0], CULL_BLOCK_CAP + CULL_RESULT_PAD, sizeof(cull_result)))
            return records_lost(memo, q->view_count);
        for (uint32_t i = 0; i < nitems; i++) {
            const cull_item *it = &c->items[i];
            if (prefetch && i + PREFETCH_AHEAD >= early && i + PREFETCH_AHEAD < nitems)
                prefetch_block(c->items[i + PREFETCH_AHEAD].block, boxes);
            cull_result *dst = !count_only ? out + written : subs ? c->tres[0] : NULL;
            uint32_t k = c->kernel(it->block, it->n, c->kv + it->kv_off, it->nv, &kp, dst, &total, it->rec);
            if (subs) {
                uint32_t kept = keep_sublevels(dst, k, subs);
                filtered += k - kept;
                k = kept;
            }
            written += k;
        }
    } else {
        uint32_t nchunks = (nitems + CHUNK_BLOCKS - 1) / CHUNK_BLOCKS;
        if (!vp_grow32((void **)&c->chunks, &c->chunks_cap, nchunks + 1, sizeof *c->chunks))
            return records_lost(memo, q->view_count);
        for (uint32_t t = 0; t < threads; t++)
            if (!vp_grow32((void **)&c->tres[t], &c->tres_cap[t], (size_t)tested + CULL_RESULT_PAD,
                         sizeof(cull_result)))
                return records_lost(memo, q->view_count);
        job j = {.c = c, .kp = &kp, .subs = subs, .items = c->items, .nitems = nitems, .nchunks = nchunks,
                 .out = out, .prefetch = prefetch, .boxes = boxes, .early = early};
        atomic_init(&j.next, 0);
        cull_pool_run(c->pool, job_cull, &j, threads);
        for (uint32_t ch = 0; ch < nchunks; ch++) {
            c->chunks[ch].dst = (uint32_t)written;
            written += c->chunks[ch].count;
        }
        if (!count_only) cull_pool_run(c->pool, job_copy, &j, threads);
        for (uint32_t t = 0; t < threads; t++) {
            total.tested += j.cnt[t].tested;
            total.after_spheres += j.cnt[t].after_spheres;
            total.after_aabb += j.cnt[t].after_aabb;
            total.after_area += j.cnt[t].after_area;
            total.after_occ += j.cnt[t].after_occ;
            filtered += j.filtered[t];
        }
    }
    *count = written;
    if (stats) {
        stats->regions = regions;
        stats->regions_culled = regions_culled;
        stats->cells = cells;
        stats->cells_culled = cells_culled;
        stats->entities_tested = total.tested;
        stats->after_spheres = total.after_spheres;
        stats->after_aabb = total.after_aabb;
        stats->after_area = total.after_area;
        stats->after_occlusion = total.after_occ;
        stats->occ_views = occ_views;
        stats->occ_reused = occ_reused;
        stats->occ_rendered = occ_rendered;
        stats->occ_clusters_drawn = occ_drawn;
        stats->cells_occluded = cells_occluded;
        stats->occ_raster_ns = occ_ns;
        stats->visible = (uint32_t)written;
        stats->threads_used = threads;
        stats->cells_filtered = cells_filtered;
        stats->filtered = filtered;
    }
    return CULL_OK;
}
