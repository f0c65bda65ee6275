/*
 * cull_occluder.c — the occluder set: meshes and height fields turned into
 * what the occlusion rasteriser draws (cull_occ_raster.inl).
 *
 * Adding a mesh: transform every vertex to world space (double), weld equal
 * vertices, drop degenerate and repeated triangles (counted), merge pairs of coplanar
 * triangles that share an edge into convex quads (a box face is one quad:
 * half the setup, and no diagonal seam where a pixel centre on the shared
 * edge could fall between both halves), then split the faces into clusters
 * of at most 64 by recursive median cuts of their centroids, each with its
 * own vertex list and AABB. All of it lives in one allocation made before
 * the world changes, so a failed add or update leaves the world as it was.
 *
 * Cost: O(n log n) in the triangles n, whatever they are (the daemon runs
 * it on the event loop, holding the scene): hashes with unique keys and a
 * per-build seed, repeated triangles dropped before pairing, at most
 * OCC_TWIN_TRIES twins tried per edge, median splits. cull_occluder_info's
 * build_steps counts the work; tests/test_occlusion.c bounds it on
 * identical, coincident, book, needle, fan and tiny-grid meshes. Measured
 * (one core of a 2-core VM): 349,525 random triangles 1.1 s, as many
 * identical 0.04 s; the pairing this replaced took 9.9 s for 64k
 * identical triangles (a linear-probing table full of one key).
 */
#include "cull_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define OCC_GEN_MASK ((1u << CULL_GEN_BITS) - 1u)

/* ---- building a mesh -------------------------------------------------------- */

typedef struct build_face {
    uint32_t v[4];
    uint32_t n;
    double   c[3];  /* centroid, for the cluster split */
} build_face;

typedef struct builder {
    double     *v;      /* 3 * nv world positions, welded */
    uint32_t    nv;
    uint32_t   *tri;    /* 3 * ntri after dropping degenerates */
    uint32_t    ntri, dropped;
    build_face *f;
    uint32_t    nf;
    uint64_t    steps;  /* hash probes, edge candidates, sort work: the
                           build's cost, for the bound (see build_mesh) */
    uint64_t    seed;   /* mixed into every hash: positions and index
                           patterns come from clients, and a fixed hash
                           could be fed keys crafted to collide */
} builder;

static void builder_free(builder *b)
{
    free(b->v);
    free(b->tri);
    free(b->f);
}

static uint64_t hash64(uint64_t x)
{
    x ^= x >> 33;
    x *= 0xff51afd7ed558ccdull;
    x ^= x >> 33;
    x *= 0xc4ceb9fe1a85ec53ull;
    x ^= x >> 33;
    return x;
}

/* A fresh seed per build: a counter and the clock, mixed. The output never
 * depends on it (only the order of probes does). */
static uint64_t build_seed(void)
{
    static _Atomic uint64_t counter;
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return hash64(atomic_fetch_add(&counter, 1) * 0x9E3779B97F4A7C15ull ^ (uint64_t)ts.tv_nsec ^
                  (uint64_t)ts.tv_sec << 30);
}

static void cross3(double o[3], const double a[3], const double b[3])
{
    o[0] = a[1] * b[2] - a[2] * b[1];
    o[1] = a[2] * b[0] - a[0] * b[2];
    o[2] = a[0] * b[1] - a[1] * b[0];
}

static double dot3(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static void sub3(double o[3], const double a[3], const double b[3])
{
    o[0] = a[0] - b[0];
    o[1] = a[1] - b[1];
    o[2] = a[2] - b[2];
}

static double len3(const double a[3])
{
    return sqrt(dot3(a, a));
}

/* Welds bit-identical world positions: an artist's triangle list repeats
 * each corner; sharing is what lets coplanar pairs be found. */
static int weld(builder *b, const double *pos, uint32_t n, uint32_t *remap)
{
    /* at most half full, a power of two (masked); 2 n in size_t, where it
       cannot wrap */
    uint32_t cap = (uint32_t)vp_grow_cap(0, 2 * (size_t)n, 16, sizeof(uint32_t), (size_t)1 << 31);
    uint32_t *tab = cap ? malloc(cap * sizeof *tab) : NULL;
    b->v = malloc((size_t)n * 3 * sizeof *b->v);
    if (!tab || !b->v) {
        free(tab);
        return CULL_ERR_NOMEM;
    }
    memset(tab, 0xff, cap * sizeof *tab);
    for (uint32_t i = 0; i < n; i++) {
        const double *p = pos + 3 * (size_t)i;
        uint64_t k[3];
        memcpy(k, p, sizeof k);
        uint32_t h = (uint32_t)hash64(k[0] ^ hash64(k[1] ^ hash64(k[2] ^ b->seed))) & (cap - 1);
        for (;;) {
            uint32_t s = tab[h];
            if (s == UINT32_MAX) {
                tab[h] = b->nv;
                memcpy(b->v + 3 * (size_t)b->nv, p, 3 * sizeof *p);
                remap[i] = b->nv++;
                break;
            }
            if (memcmp(b->v + 3 * (size_t)s, p, 3 * sizeof *p) == 0) {
                remap[i] = s;
                break;
            }
            h = (h + 1) & (cap - 1);
            b->steps++;
        }
    }
    free(tab);
    return CULL_OK;
}

static const double *vtx(const builder *b, uint32_t i)
{
    return b->v + 3 * (size_t)i;
}

static bool degenerate(const builder *b, uint32_t i0, uint32_t i1, uint32_t i2)
{
    if (i0 == i1 || i1 == i2 || i0 == i2) return true;
    double e0[3], e1[3], e2[3], n[3];
    sub3(e0, vtx(b, i1), vtx(b, i0));
    sub3(e1, vtx(b, i2), vtx(b, i0));
    sub3(e2, vtx(b, i2), vtx(b, i1));
    cross3(n, e0, e1);
    double l = fmax(dot3(e0, e0), fmax(dot3(e1, e1), dot3(e2, e2)));
    /* area below 1e-12 of the longest edge squared: a sliver that covers
       nothing and whose plane is noise */
    return !(len3(n) > 1e-12 * l);
}

/* Triangle u = (b, a, d) (shares edge b->a with t = (a, b, c)) merges
 * with t into the quad (a, d, b, c) if d lies in t's plane and the quad is
 * strictly convex. */
static bool mergeable(const builder *bl, const uint32_t t[3], uint32_t d)
{
    const double *a = vtx(bl, t[0]), *b = vtx(bl, t[1]), *c = vtx(bl, t[2]), *p = vtx(bl, d);
    double e0[3], e1[3], n[3], ad[3];
    sub3(e0, b, a);
    sub3(e1, c, a);
    cross3(n, e0, e1);
    sub3(ad, p, a);
    double ln = len3(n), scale = fmax(len3(e0), fmax(len3(e1), len3(ad)));
    if (fabs(dot3(n, ad)) > 1e-9 * ln * scale) return false; /* not coplanar */
    const double *q[4] = {a, p, b, c};
    for (int i = 0; i < 4; i++) {
        double u[3], v[3], x[3];
        sub3(u, q[(i + 1) & 3], q[i]);
        sub3(v, q[(i + 2) & 3], q[(i + 1) & 3]);
        cross3(x, u, v);
        if (!(dot3(x, n) > 1e-9 * ln * len3(u) * len3(v))) return false;
    }
    return true;
}

/* Twin candidates a triangle's edge examines for a merge. A manifold mesh
 * has one twin per edge; a non-manifold "book" (many triangles on one edge)
 * could make the pairing quadratic, and merging is only an optimisation:
 * past this many the edge stays unmerged. */
#define OCC_TWIN_TRIES 8u

/* Finds key k in an open-addressing table of unique keys (heads[h] ==
 * UINT32_MAX: empty); returns its slot, the empty slot where it belongs if
 * absent. */
static uint32_t edge_slot(builder *b, const uint64_t *key, const uint32_t *head, uint32_t cap, uint64_t k)
{
    uint32_t h = (uint32_t)hash64(k ^ b->seed) & (cap - 1);
    while (head[h] != UINT32_MAX && key[h] != k) {
        h = (h + 1) & (cap - 1);
        b->steps++;
    }
    return h;
}

/* Pairs triangles across shared edges, greedily. A directed edge is one
 * key in the table (unique keys: probes stay O(1) however often an edge
 * repeats), its occurrences chained in triangle order; a triangle looks
 * at most OCC_TWIN_TRIES unused twins per edge, after dropping the used
 * ones at the chain's head (each dropped once). O(triangles). */
static int make_faces(builder *b)
{
    b->f = malloc((size_t)(b->ntri ? b->ntri : 1) * sizeof *b->f);
    if (!b->f) return CULL_ERR_NOMEM;
    uint32_t cap = (uint32_t)vp_grow_cap(0, 6 * (size_t)b->ntri, 16, sizeof(uint64_t), (size_t)1 << 31);
    uint64_t *key = cap ? malloc(cap * sizeof *key) : NULL;
    uint32_t *head = cap ? malloc(cap * sizeof *head) : NULL;
    uint32_t *next = malloc(((size_t)3 * b->ntri + 1) * sizeof *next);
    uint8_t *used = calloc(b->ntri ? b->ntri : 1, 1);
    if (!key || !head || !next || !used) {
        free(key);
        free(head);
        free(next);
        free(used);
        return CULL_ERR_NOMEM;
    }
    memset(head, 0xff, cap * sizeof *head);
    /* pushed last to first, so each chain runs in triangle order */
    for (uint32_t t = b->ntri; t-- > 0;)
        for (int e = 2; e >= 0; e--) {
            uint64_t k = (uint64_t)b->tri[3 * t + e] << 32 | b->tri[3 * t + (e + 1) % 3];
            uint32_t h = edge_slot(b, key, head, cap, k);
            key[h] = k;
            next[3 * t + (uint32_t)e] = head[h];
            head[h] = 3 * t + (uint32_t)e;
        }
    for (uint32_t t = 0; t < b->ntri; t++) {
        if (used[t]) continue;
        used[t] = 1;
        build_face *f = &b->f[b->nf++];
        const uint32_t *tv = b->tri + 3 * t;
        f->n = 3;
        memcpy(f->v, tv, 3 * sizeof *tv);
        for (int e = 0; e < 3 && f->n == 3; e++) {
            uint32_t a = tv[e], bb = tv[(e + 1) % 3], c = tv[(e + 2) % 3];
            uint32_t h = edge_slot(b, key, head, cap, (uint64_t)bb << 32 | a); /* the twin edge b->a */
            while (head[h] != UINT32_MAX && used[head[h] / 3]) {
                head[h] = next[head[h]];
                b->steps++;
            }
            uint32_t tries = 0;
            for (uint32_t o = head[h]; o != UINT32_MAX && tries < OCC_TWIN_TRIES; o = next[o]) {
                b->steps++;
                uint32_t u = o / 3, ue = o % 3;
                if (used[u]) continue;
                tries++;
                uint32_t d = b->tri[3 * u + (ue + 2) % 3];
                const uint32_t rot[3] = {a, bb, c};
                if (d == c || !mergeable(b, rot, d)) continue;
                used[u] = 1;
                f->v[0] = a;
                f->v[1] = d;
                f->v[2] = bb;
                f->v[3] = c;
                f->n = 4;
                break;
            }
        }
        for (int a = 0; a < 3; a++) {
            double s = 0;
            for (uint32_t i = 0; i < f->n; i++) s += vtx(b, f->v[i])[a];
            f->c[a] = s / f->n;
        }
    }
    free(key);
    free(head);
    free(next);
    free(used);
    return CULL_OK;
}

/* Drops repeated triangles: the same three corners in the same cyclic
 * order draw exactly what the first copy draws. (The opposite winding is
 * another triangle: a two-sided wall keeps both.) Counted as dropped.
 * A hash set of the kept ones, each keyed by its rotation that starts at
 * its smallest index: O(triangles). */
static int drop_duplicates(builder *b)
{
    uint32_t cap = (uint32_t)vp_grow_cap(0, 2 * (size_t)b->ntri, 16, sizeof(uint32_t), (size_t)1 << 31);
    uint32_t *tab = cap ? malloc(cap * sizeof *tab) : NULL;
    if (!tab) return CULL_ERR_NOMEM;
    memset(tab, 0xff, cap * sizeof *tab);
    uint32_t kept = 0;
    for (uint32_t t = 0; t < b->ntri; t++) {
        uint32_t *v = b->tri + 3 * t, r = v[1] < v[0] ? (v[2] < v[1] ? 2 : 1) : (v[2] < v[0] ? 2 : 0);
        uint32_t c[3] = {v[r], v[(r + 1) % 3], v[(r + 2) % 3]};
        uint64_t k = hash64(((uint64_t)c[0] << 32 | c[1]) ^ b->seed) ^ hash64(c[2] ^ (b->seed >> 7));
        uint32_t h = (uint32_t)k & (cap - 1);
        bool dup = false;
        while (tab[h] != UINT32_MAX) {
            const uint32_t *q = b->tri + 3 * tab[h];
            if (q[0] == c[0] && q[1] == c[1] && q[2] == c[2]) {
                dup = true;
                break;
            }
            h = (h + 1) & (cap - 1);
            b->steps++;
        }
        if (dup) {
            b->dropped++;
            continue;
        }
        /* kept triangles are stored rotated: the same corners, the same
           winding */
        memcpy(b->tri + 3 * kept, c, sizeof c);
        tab[h] = kept++;
    }
    b->ntri = kept;
    free(tab);
    return CULL_OK;
}

/* Median split of f[0..n) along the longest axis of the centroids until
 * every cluster has at most CULL_OCC_CLUSTER_FACES faces. */
static int cmp_centroid(const void *x, const void *y, void *axis)
{
    int ax = *(const int *)axis;
    double a = ((const build_face *)x)->c[ax], b = ((const build_face *)y)->c[ax];
    return (a > b) - (a < b);
}

static uint32_t count_clusters(uint32_t n)
{
    if (n <= CULL_OCC_CLUSTER_FACES) return 1;
    return count_clusters(n / 2) + count_clusters(n - n / 2);
}

typedef struct emitter {
    cull_occ_mesh *m;
    double *vout;
    cull_occ_face *fout;
    uint32_t *local;    /* builder vertex -> cluster vertex, UINT32_MAX = none */
    const builder *b;
    uint64_t steps;     /* sorting and convexity work */
} emitter;

static int cmp_u64(const void *x, const void *y)
{
    uint64_t a = *(const uint64_t *)x, b = *(const uint64_t *)y;
    return (a > b) - (a < b);
}

/* Closed: every edge is used twice, once each way. Convex: every vertex on
 * or behind every face's plane. Then the cluster's front faces cover
 * exactly its silhouette, nearest-first by the minimum of their planes. */
static bool closed_convex(const cull_occ_cluster *cl)
{
    if (cl->nf < 4 || cl->nv < 4) return false;
    uint64_t key[4 * CULL_OCC_CLUSTER_FACES];
    uint32_t ne = 0;
    for (uint32_t i = 0; i < cl->nf; i++)
        for (uint32_t k = 0; k < cl->f[i].n; k++) {
            uint32_t a = cl->f[i].v[k], b = cl->f[i].v[(k + 1) % cl->f[i].n];
            /* undirected edge, then its direction in the low bit */
            key[ne++] = (uint64_t)(a < b ? a : b) << 33 | (uint64_t)(a < b ? b : a) << 1 | (a < b);
        }
    qsort(key, ne, sizeof *key, cmp_u64);
    if (ne % 2) return false;
    for (uint32_t i = 0; i < ne; i += 2)
        if ((key[i] >> 1) != (key[i + 1] >> 1) || (key[i] & 1) == (key[i + 1] & 1) ||
            (i + 2 < ne && (key[i + 2] >> 1) == (key[i] >> 1)))
            return false;
    double ext = 0;
    for (int a = 0; a < 3; a++) ext = fmax(ext, cl->bmax[a] - cl->bmin[a]);
    for (uint32_t i = 0; i < cl->nf; i++) {
        const double *p0 = cl->v + 3 * cl->f[i].v[0], *p1 = cl->v + 3 * cl->f[i].v[1], *p2 = cl->v + 3 * cl->f[i].v[2];
        double e0[3], e1[3], n[3];
        sub3(e0, p1, p0);
        sub3(e1, p2, p0);
        cross3(n, e0, e1);
        double tol = 1e-9 * len3(n) * ext;
        for (uint32_t k = 0; k < cl->nv; k++) {
            double d[3];
            sub3(d, cl->v + 3 * k, p0);
            if (dot3(n, d) > tol) return false;
        }
    }
    return true;
}

static void emit_cluster(emitter *e, build_face *f, uint32_t n)
{
    if (n > CULL_OCC_CLUSTER_FACES) {
        double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
        for (uint32_t i = 0; i < n; i++)
            for (int a = 0; a < 3; a++) {
                lo[a] = fmin(lo[a], f[i].c[a]);
                hi[a] = fmax(hi[a], f[i].c[a]);
            }
        int ax = 0;
        for (int a = 1; a < 3; a++)
            if (hi[a] - lo[a] > hi[ax] - lo[ax]) ax = a;
        qsort_r(f, n, sizeof *f, cmp_centroid, &ax);
        for (uint32_t k = n; k > 1; k >>= 1) e->steps += n; /* n log2 n compares */
        emit_cluster(e, f, n / 2);
        emit_cluster(e, f + n / 2, n - n / 2);
        return;
    }
    cull_occ_cluster *cl = &e->m->cl[e->m->ncl++];
    cl->v = e->vout;
    cl->f = e->fout;
    cl->nf = n;
    cl->nv = 0;
    for (int a = 0; a < 3; a++) {
        cl->bmin[a] = INFINITY;
        cl->bmax[a] = -INFINITY;
    }
    for (uint32_t i = 0; i < n; i++) {
        cull_occ_face *o = &e->fout[i];
        o->n = f[i].n;
        for (uint32_t k = 0; k < 4; k++) {
            if (k >= f[i].n) {
                o->v[k] = o->v[k - 1];
                continue;
            }
            uint32_t g = f[i].v[k];
            if (e->local[g] == UINT32_MAX) {
                e->local[g] = cl->nv;
                const double *p = vtx(e->b, g);
                memcpy(e->vout + 3 * (size_t)cl->nv, p, 3 * sizeof *p);
                for (int a = 0; a < 3; a++) {
                    cl->bmin[a] = fmin(cl->bmin[a], p[a]);
                    cl->bmax[a] = fmax(cl->bmax[a], p[a]);
                }
                cl->nv++;
            }
            o->v[k] = (uint16_t)e->local[g];
        }
    }
    /* reset the map for the next cluster */
    for (uint32_t i = 0; i < n; i++)
        for (uint32_t k = 0; k < f[i].n; k++) e->local[f[i].v[k]] = UINT32_MAX;
    e->vout += 3 * (size_t)cl->nv;
    e->fout += n;
    cl->convex = closed_convex(cl);
    e->steps += (uint64_t)cl->nf * (cl->nv + 8);
}

/* The whole pipeline from world-space triangles to a finished mesh. */
static int build_mesh(const double *pos, uint32_t npos, const uint32_t *idx, uint32_t ntri_in, uint16_t sublevel,
                      bool two_sided, cull_occ_mesh **out)
{
    builder b = {.seed = build_seed()};
    uint32_t *remap = malloc((size_t)(npos ? npos : 1) * sizeof *remap);
    b.tri = malloc((size_t)(ntri_in ? ntri_in : 1) * 3 * sizeof *b.tri);
    int rc = CULL_ERR_NOMEM;
    if (!remap || !b.tri) goto done;
    if ((rc = weld(&b, pos, npos, remap)) != CULL_OK) goto done;
    for (uint32_t t = 0; t < ntri_in; t++) {
        uint32_t i0 = remap[idx ? idx[3 * t] : 3 * t], i1 = remap[idx ? idx[3 * t + 1] : 3 * t + 1],
                 i2 = remap[idx ? idx[3 * t + 2] : 3 * t + 2];
        if (degenerate(&b, i0, i1, i2)) {
            b.dropped++;
            continue;
        }
        b.tri[3 * b.ntri] = i0;
        b.tri[3 * b.ntri + 1] = i1;
        b.tri[3 * b.ntri + 2] = i2;
        b.ntri++;
    }
    if ((rc = drop_duplicates(&b)) != CULL_OK) goto done;
    if ((rc = make_faces(&b)) != CULL_OK) goto done;

    /* one block: mesh, clusters, vertices (a vertex may repeat once per
       cluster it appears in: at most 4 per face), faces */
    uint32_t ncl = b.nf ? count_clusters(b.nf) : 0;
    size_t vcap = (size_t)b.nf * 4 < b.nv * (size_t)ncl ? (size_t)b.nf * 4 : (size_t)b.nv * ncl;
    size_t bytes = sizeof(cull_occ_mesh) + ncl * sizeof(cull_occ_cluster) + vcap * 3 * sizeof(double) +
                   (size_t)b.nf * sizeof(cull_occ_face);
    cull_occ_mesh *m = calloc(1, bytes);
    uint32_t *local = malloc((size_t)(b.nv ? b.nv : 1) * sizeof *local);
    if (!m || !local) {
        free(m);
        free(local);
        rc = CULL_ERR_NOMEM;
        goto done;
    }
    memset(local, 0xff, (size_t)(b.nv ? b.nv : 1) * sizeof *local);
    m->cl = (cull_occ_cluster *)(m + 1);
    emitter e = {.m = m, .vout = (double *)(m->cl + ncl), .local = local, .b = &b};
    e.fout = (cull_occ_face *)(e.vout + vcap * 3);
    if (b.nf) emit_cluster(&e, b.f, b.nf);
    free(local);
    m->triangles = b.ntri;
    m->dropped = b.dropped;
    m->faces = b.nf;
    m->build_steps = b.steps + e.steps + ntri_in + npos;
    m->sublevel = sublevel;
    for (uint32_t c = 0; c < m->ncl; c++) {
        m->cl[c].sublevel = sublevel;
        m->cl[c].two_sided = two_sided;
    }
    for (int a = 0; a < 3; a++) {
        m->bmin[a] = INFINITY;
        m->bmax[a] = -INFINITY;
    }
    for (uint32_t c = 0; c < m->ncl; c++)
        for (int a = 0; a < 3; a++) {
            m->bmin[a] = fmin(m->bmin[a], m->cl[c].bmin[a]);
            m->bmax[a] = fmax(m->bmax[a], m->cl[c].bmax[a]);
        }
    if (!m->ncl)
        for (int a = 0; a < 3; a++) m->bmin[a] = m->bmax[a] = 0;
    *out = m;
    rc = CULL_OK;
done:
    free(remap);
    builder_free(&b);
    return rc;
}

/* ---- descs ------------------------------------------------------------------ */

static int mesh_from_desc(const cull_occluder_desc *d, cull_occ_mesh **out)
{
    if (!d || !d->vertices || !d->vertex_count || d->vertex_count > CULL_OCC_MAX_VERTICES) return CULL_ERR_MESH;
    uint32_t ntri;
    if (d->indices) {
        if (!d->index_count || d->index_count % 3 || d->index_count / 3 > CULL_OCC_MAX_TRIANGLES)
            return CULL_ERR_MESH;
        for (uint32_t i = 0; i < d->index_count; i++)
            if (d->indices[i] >= d->vertex_count) return CULL_ERR_MESH;
        ntri = d->index_count / 3;
    } else {
        if (d->vertex_count % 3) return CULL_ERR_MESH;
        ntri = d->vertex_count / 3;
    }
    double m[16];
    bool ident = true;
    for (int i = 0; i < 16; i++) {
        if (!isfinite(d->transform[i])) return CULL_ERR_NONFINITE;
        if (d->transform[i] != 0) ident = false;
    }
    if (ident) {
        memset(m, 0, sizeof m);
        m[0] = m[5] = m[10] = m[15] = 1;
    } else {
        memcpy(m, d->transform, sizeof m);
        if (m[3] != 0 || m[7] != 0 || m[11] != 0 || m[15] != 1) return CULL_ERR_MATRIX; /* affine only */
    }
    double *pos = malloc((size_t)d->vertex_count * 3 * sizeof *pos);
    if (!pos) return CULL_ERR_NOMEM;
    for (uint32_t i = 0; i < d->vertex_count; i++) {
        const float *p = d->vertices + 3 * (size_t)i;
        for (int a = 0; a < 3; a++) {
            double v = m[a] * p[0] + m[4 + a] * p[1] + m[8 + a] * p[2] + m[12 + a];
            if (!isfinite(p[a]) || !isfinite(v)) {
                free(pos);
                return CULL_ERR_NONFINITE;
            }
            if (fabs(v) > CULL_MAX_COORD) {
                free(pos);
                return CULL_ERR_RANGE;
            }
            pos[3 * (size_t)i + a] = v;
        }
    }
    int rc = build_mesh(pos, d->vertex_count, d->indices, ntri, d->sublevel, (d->flags & CULL_OCC_TWO_SIDED) != 0, out);
    free(pos);
    return rc;
}

static int mesh_from_terrain(const cull_terrain_desc *d, cull_occ_mesh **out)
{
    if (!d || !d->heights || d->nx < 2 || d->nz < 2) return CULL_ERR_MESH;
    uint64_t nv = (uint64_t)d->nx * d->nz, ntri = 2ull * (d->nx - 1) * (d->nz - 1);
    if (nv > CULL_OCC_MAX_VERTICES || ntri > CULL_OCC_MAX_TRIANGLES) return CULL_ERR_MESH;
    for (int a = 0; a < 3; a++)
        if (!isfinite(d->origin[a])) return CULL_ERR_NONFINITE;
    if (!(d->spacing > 0) || !isfinite(d->spacing)) return CULL_ERR_INVALID;
    double *pos = malloc(nv * 3 * sizeof *pos);
    uint32_t *idx = malloc(ntri * 3 * sizeof *idx);
    if (!pos || !idx) {
        free(pos);
        free(idx);
        return CULL_ERR_NOMEM;
    }
    int rc = CULL_OK;
    for (uint32_t z = 0; z < d->nz && rc == CULL_OK; z++)
        for (uint32_t x = 0; x < d->nx; x++) {
            float h = d->heights[(size_t)z * d->nx + x];
            double *p = pos + 3 * ((size_t)z * d->nx + x);
            p[0] = d->origin[0] + x * d->spacing;
            p[1] = d->origin[1] + h;
            p[2] = d->origin[2] + z * d->spacing;
            if (!isfinite(h)) rc = CULL_ERR_NONFINITE;
            else if (fabs(p[0]) > CULL_MAX_COORD || fabs(p[1]) > CULL_MAX_COORD || fabs(p[2]) > CULL_MAX_COORD)
                rc = CULL_ERR_RANGE;
        }
    if (rc == CULL_OK) {
        /* counter-clockwise seen from above (+y) */
        uint32_t *t = idx;
        for (uint32_t z = 0; z + 1 < d->nz; z++)
            for (uint32_t x = 0; x + 1 < d->nx; x++) {
                uint32_t i00 = z * d->nx + x, i10 = i00 + 1, i01 = i00 + d->nx, i11 = i01 + 1;
                *t++ = i00; *t++ = i01; *t++ = i10;
                *t++ = i10; *t++ = i01; *t++ = i11;
            }
        rc = build_mesh(pos, (uint32_t)nv, idx, (uint32_t)ntri, d->sublevel, false, out);
    }
    free(pos);
    free(idx);
    return rc;
}

/* ---- the set ------------------------------------------------------------------ */

static cull_occ_mesh *lookup(const cull_world *w, cull_occluder h)
{
    uint32_t slot = h & CULL_SLOT_MASK, gen = h >> CULL_HANDLE_SLOT_BITS;
    if (!w || !h || slot >= w->noslots) return NULL;
    const cull_occ_slot *s = &w->oslots[slot];
    return s->m && s->gen == gen ? s->m : NULL;
}

/* Room in the world's cluster arrays for `more` clusters. */
static int reserve_clusters(cull_world *w, uint32_t more)
{
    size_t need = (size_t)w->nclusters + more;
    if (need > UINT32_MAX / 2) return CULL_ERR_CAPACITY;
    if (!vp_grow32((void **)&w->ocl, &w->cap_ocl, need + 1, sizeof *w->ocl) ||
        !cull_soa_reserve(&w->ocl_soa, w->nclusters, (uint32_t)need + 1))
        return CULL_ERR_NOMEM;
    return CULL_OK;
}

static void link_clusters(cull_world *w, cull_occ_mesh *m)
{
    for (uint32_t c = 0; c < m->ncl; c++) {
        cull_occ_cluster *cl = &m->cl[c];
        cl->widx = w->nclusters++;
        w->ocl[cl->widx] = cl;
        cull_soa_set(&w->ocl_soa, cl->widx, cl->bmin, cl->bmax);
    }
}

/* Swap-removes m's clusters from the world's arrays. */
static void unlink_clusters(cull_world *w, cull_occ_mesh *m)
{
    for (uint32_t c = 0; c < m->ncl; c++) {
        uint32_t i = m->cl[c].widx, last = --w->nclusters;
        if (i != last) {
            w->ocl[i] = w->ocl[last];
            w->ocl[i]->widx = i;
            cull_soa_copy(&w->ocl_soa, i, last);
        }
    }
}

static int insert(cull_world *w, cull_occ_mesh *m, cull_occluder *out)
{
    if (w->nocc >= CULL_MAX_OCCLUDERS) return CULL_ERR_CAPACITY;
    int rc = reserve_clusters(w, m->ncl);
    if (rc != CULL_OK) return rc;
    if (!vp_grow32((void **)&w->occ, &w->cap_occ, (size_t)w->nocc + 1, sizeof *w->occ)) return CULL_ERR_NOMEM;
    uint32_t slot;
    if (w->ofree_head != UINT32_MAX && w->ofree_head < w->noslots) {
        slot = w->ofree_head;
        w->ofree_head = w->oslots[slot].next_free;
    } else {
        if (!vp_grow32((void **)&w->oslots, &w->cap_oslots, (size_t)w->noslots + 1, sizeof *w->oslots))
            return CULL_ERR_NOMEM;
        slot = w->noslots++;
        w->oslots[slot] = (cull_occ_slot){.gen = 1, .next_free = UINT32_MAX};
    }
    cull_occ_slot *s = &w->oslots[slot];
    s->m = m;
    m->slot = slot;
    m->dense = w->nocc;
    w->occ[w->nocc++] = m;
    link_clusters(w, m);
    w->occ_version++;
    *out = slot | s->gen << CULL_HANDLE_SLOT_BITS;
    return CULL_OK;
}

static int add_built(cull_world *w, int rc, cull_occ_mesh *m, cull_occluder *out)
{
    if (rc != CULL_OK) return rc;
    if ((rc = insert(w, m, out)) != CULL_OK) free(m);
    return rc;
}

int cull_occluder_add(cull_world *w, const cull_occluder_desc *d, cull_occluder *out)
{
    if (!w || !out) return CULL_ERR_INVALID;
    *out = 0;
    cull_occ_mesh *m = NULL;
    int rc = mesh_from_desc(d, &m);
    return add_built(w, rc, m, out);
}

int cull_terrain_add(cull_world *w, const cull_terrain_desc *d, cull_occluder *out)
{
    if (!w || !out) return CULL_ERR_INVALID;
    *out = 0;
    cull_occ_mesh *m = NULL;
    int rc = mesh_from_terrain(d, &m);
    return add_built(w, rc, m, out);
}

static int replace(cull_world *w, cull_occ_mesh *old, int rc, cull_occ_mesh *m)
{
    if (rc != CULL_OK) return rc;
    if ((rc = reserve_clusters(w, m->ncl)) != CULL_OK) {
        free(m);
        return rc;
    }
    m->slot = old->slot;
    m->dense = old->dense;
    w->occ[m->dense] = m;
    w->oslots[m->slot].m = m;
    unlink_clusters(w, old);
    link_clusters(w, m);
    free(old);
    w->occ_version++;
    return CULL_OK;
}

int cull_occluder_update(cull_world *w, cull_occluder h, const cull_occluder_desc *d)
{
    cull_occ_mesh *old = lookup(w, h), *m = NULL;
    if (!old) return CULL_ERR_HANDLE;
    int rc = mesh_from_desc(d, &m);
    return replace(w, old, rc, m);
}

int cull_terrain_update(cull_world *w, cull_occluder h, const cull_terrain_desc *d)
{
    cull_occ_mesh *old = lookup(w, h), *m = NULL;
    if (!old) return CULL_ERR_HANDLE;
    int rc = mesh_from_terrain(d, &m);
    return replace(w, old, rc, m);
}

int cull_occluder_remove(cull_world *w, cull_occluder h)
{
    cull_occ_mesh *m = lookup(w, h);
    if (!m) return CULL_ERR_HANDLE;
    cull_occ_slot *s = &w->oslots[m->slot];
    s->m = NULL;
    s->gen = (s->gen + 1) & OCC_GEN_MASK;
    if (!s->gen) s->gen = 1;
    s->next_free = w->ofree_head;
    w->ofree_head = m->slot;
    cull_occ_mesh *last = w->occ[--w->nocc];
    w->occ[m->dense] = last;
    last->dense = m->dense;
    unlink_clusters(w, m);
    free(m);
    w->occ_version++;
    return CULL_OK;
}

int cull_occluder_get_info(const cull_world *w, cull_occluder h, cull_occluder_info *out)
{
    const cull_occ_mesh *m = lookup(w, h);
    if (!m) return CULL_ERR_HANDLE;
    if (!out) return CULL_ERR_INVALID;
    *out = (cull_occluder_info){.triangles = m->triangles, .dropped = m->dropped, .faces = m->faces,
                                .clusters = m->ncl, .sublevel = m->sublevel,
                                .build_steps = m->build_steps};
    for (uint32_t c = 0; c < m->ncl; c++) out->convex_clusters += m->cl[c].convex;
    memcpy(out->aabb_min, m->bmin, sizeof m->bmin);
    memcpy(out->aabb_max, m->bmax, sizeof m->bmax);
    return CULL_OK;
}

uint32_t cull_occluder_count(const cull_world *w)
{
    return w ? w->nocc : 0;
}

void cull_occluders_free(cull_world *w)
{
    for (uint32_t i = 0; i < w->nocc; i++) free(w->occ[i]);
    free(w->occ);
    free(w->oslots);
    free(w->ocl);
    free(w->ocl_soa.v);
}
