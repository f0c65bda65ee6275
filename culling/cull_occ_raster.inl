/*
 * cull_occ_raster.inl — software occlusion, the drawing, compiled twice:
 * cull_occ_raster.c for any x86-64 (and the public entry points), and
 * cull_occ_raster_avx2.c with AVX2, the same code in VEX form plus a few
 * paths of its own under __AVX2__ (CULL_OCC_RASTER_ISA) that give the same
 * bits (test_occ_avx2_build_same_bits). The occluders of one view rendered into the occlusion buffer in bands on the pool's
 * threads (cull_occ.c owns the buffer, the depth convention, the
 * hierarchy and the tests that read it; cull_occ_tiles.inl the tile
 * state kept during the render; cull_occ_kern.inl the per-ISA span
 * loops).
 *
 * Rasterisation is homogeneous (Olano & Greer 1997): a polygon's edges are
 * the planes through the eye and each pair of clip-space vertices,
 * n_k = v_k x v_(k+1) over (x, y, w), and a pixel centre s = (X, Y, 1) is
 * inside when every n_k.s > 0. Vertices behind the eye need no special
 * case; the near plane becomes one more linear function of s on the
 * polygon's plane, and so does the nearness (sum_i d_i E_i(s) / det with
 * E_i the adjugate rows). All set-up is in double; per row, each
 * constraint gives a bound on x, so a row is one span; the span is filled
 * by a vectorisable loop in float. Every constraint is shrunk by 2^-24 of
 * its range over the screen, so the covered set is a subset of what an
 * exact rasteriser covers: conservative in coverage and in depth.
 *
 * Order and threads. Occluders are split into clusters of <= 64 faces
 * (cull_occluder.c). Per view: clusters outside the frustum are dropped,
 * the rest sorted near to far by their nearest point; horizontal bands of
 * whole 8-row tiles are rendered in parallel, each band walking the whole
 * sorted list, skipping clusters whose rectangle misses the band or is
 * already hidden in it (front-to-back pays here: most of a city is behind
 * its first street). Bands need no merging and no locks; a cluster that
 * spans two bands has its vertices transformed twice (cheap next to the
 * pixels). Per-occluder buffers merged afterwards were the alternative:
 * the merge alone costs a pass over every buffer, and it loses the hidden-
 * occluder skip.
 */
#include "cull_internal.h"
#include "cull_occ.h"
#include "cull_occ_num.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#ifdef __SSE2__
#include <emmintrin.h>
#endif
#ifdef __AVX2__
#include <immintrin.h>
#endif

#define MAX_BANDS CULL_OCC_MAX_BANDS

#include "cull_occ_tiles.inl"

static uint64_t now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000000ull + (uint64_t)ts.tv_nsec;
}

/* ---- rasterisation -------------------------------------------------------------- */

/* One vertex in clip space, plus what the polygon set-up needs. */
typedef struct cvert {
    double x, y, w;   /* homogeneous screen coordinates */
    double n;         /* near-plane function: >= 0 in front */
    double d;         /* nearness numerator */
} cvert;

typedef struct lin3 {
    double a, b, c;   /* a * i + b * j + c over pixel indices */
} lin3;

static inline void cross_xyw(double o[3], const cvert *p, const cvert *q)
{
    o[0] = p->y * q->w - p->w * q->y;
    o[1] = p->w * q->x - p->x * q->w;
    o[2] = p->x * q->y - p->y * q->x;
}

/* A linear function of s = (X, Y, 1) in NDC -> over pixel indices. */
static inline lin3 to_pixels(const cull_occ_buffer *b, const double f[3])
{
    double ax = f[0] / b->sx, ay = f[1] / b->sy;
    return (lin3){ax, ay, f[2] + f[0] * (0.5 / b->sx - 1.0) + f[1] * (0.5 / b->sy - 1.0)};
}

/* A thread's share of the buffer: the tile rows ty with ty % nb == k
 * (interleaved, so the near, busy rows of a street view are shared out
 * evenly), within pixel rows [y0, y1). */
typedef struct band {
    cull_occ_buffer *b;
    int y0, y1;
    int k, nb;
    uint32_t faces, clusters;
    uint32_t next;          /* the band's next pixel slot (occ_tile_take) */
} __attribute__((aligned(64))) band; /* one cache line per band: no false sharing */

/* Set-up of one half (a triangle) of a face: the adjugate rows scaled by
 * 1/det give the nearness, and the near function where asked (near not
 * NULL), as planes. */
static bool half_planes(const cull_occ_buffer *b, const cvert *v0, const cvert *v1, const cvert *v2, lin3 *near,
                        lin3 *nearness, double *det_out)
{
    double e0[3], e1[3], e2[3];
    cross_xyw(e0, v1, v2);
    cross_xyw(e1, v2, v0);
    cross_xyw(e2, v0, v1);
    double det = e0[0] * v0->x + e0[1] * v0->y + e0[2] * v0->w;
    double s0 = fabs(v0->x) + fabs(v0->y) + fabs(v0->w), s1 = fabs(v1->x) + fabs(v1->y) + fabs(v1->w),
           s2 = fabs(v2->x) + fabs(v2->y) + fabs(v2->w);
    *det_out = det;
    /* back-facing, or edge-on: its plane is ill-conditioned and it covers
       (next to) nothing */
    if (!(det > 1e-9 * s0 * s1 * s2)) return false;
    double inv = 1.0 / det, fn[3], fd[3];
    for (int k = 0; k < 3; k++) fd[k] = (v0->d * e0[k] + v1->d * e1[k] + v2->d * e2[k]) * inv;
    *nearness = to_pixels(b, fd);
    if (near) { /* NULL: not wanted (a polygon wholly in front) */
        for (int k = 0; k < 3; k++) fn[k] = (v0->n * e0[k] + v1->n * e1[k] + v2->n * e2[k]) * inv;
        *near = to_pixels(b, fn);
    }
    return true;
}

#define MAX_CONS CULL_OCC_MAX_CONS

/* What the row and tile loops rasterise: a convex region given by linear
 * constraints over pixel indices (edges, the near plane), up to three
 * nearness planes whose minimum is the surface, and the nearness range and
 * NDC bounds of the region's vertices. */
typedef struct rpoly {
    lin3 con[MAX_CONS];
    uint32_t nc;
    lin3 z[3];
    uint32_t nz;
    double nmin, nmax;
    double xmin, xmax, ymin, ymax;
} rpoly;

#ifndef CULL_OCC_RASTER_ISA
/* The rows of a tile row (cull_occ_fns.rows), the reference: every
 * constraint, the slow ones included, in double; row r's span is the
 * pixels every bound admits, within [i0, i1] (floor / ceil clamped as
 * dfloor / dceil do, so every int is defined). */
cull_occ_rowsum cull_occ_rows_scalar(const cull_occ_rowset *rs, int jb, int a, int b, int *lo, int *hi, float *z0)
{
    cull_occ_rowsum o = {INT32_MIN, INT32_MAX, INT32_MAX, INT32_MIN, a == 0 && b == 7};
    for (int r = 0; r < 8; r++) {
        int j = jb + r;
        for (int k = 0; k < 3; k++) z0[8 * k + r] = (float)(rs->zb[k] * j + rs->zc[k] - rs->corner[k] - rs->m[k]);
        if (r < a || r > b) {
            lo[r] = 1;
            hi[r] = 0;
            continue;
        }
        double tl = -0x1p40, th = 0x1p40;
        for (uint32_t k = 0; k < rs->nl; k++) tl = dmax(tl, rs->lal[k] + rs->lbe[k] * j);
        for (uint32_t k = 0; k < rs->nr; k++) th = dmin(th, rs->ral[k] + rs->rbe[k] * j);
        for (uint32_t k = 0; k < rs->ns; k++) {
            double q = (rs->st[k] - rs->sb[k] * j) / rs->sa[k]; /* +-inf at worst */
            if (rs->sa[k] > 0) tl = dmax(tl, q);
            else th = dmin(th, q);
        }
        int x0 = (int)dmax(rs->i0, dfloor(tl) + 1), x1 = (int)dmin(rs->i1, dceil(th) - 1);
        lo[r] = x0;
        hi[r] = x1;
        if (x0 > x1) o.whole = 0;
        else o.U0 = x0 < o.U0 ? x0 : o.U0, o.U1 = x1 > o.U1 ? x1 : o.U1;
        o.L = x0 > o.L ? x0 : o.L;
        o.H = x1 < o.H ? x1 : o.H;
    }
    return o;
}
#endif

/* Nearness planes are evaluated in float over the buffer: beyond this
 * magnitude (at any pixel) a plane, or the polygon's nearness range, is
 * not drawn with (a view that gives 2^100 has overflowed somewhere). */
#define Z_LIM 0x1p100

/* (mark_tiles is inlined here: its flag loops stay loops, as in mark_tiles) */
__attribute__((optimize("no-tree-loop-distribute-patterns"))) static void raster_poly(band *bd, rpoly *p)
{
    cull_occ_buffer *b = bd->b;
    /* Robust to any input (defence in depth: a view the decoder accepts can
       still overflow double in the set-up, 1e30 terms times 1e12 metres):
       a polygon whose bounds, nearness range or constraints are not finite
       is not drawn. Drawing less only culls less; a NaN bound taken as
       "no bound" would draw where the occluder is not (a wrong cull). */
    if (!(isfin(p->nmin) && isfin(p->nmax) && fabs(p->nmin) <= Z_LIM && fabs(p->nmax) <= Z_LIM)) return;
    if (p->xmin != p->xmin || p->xmax != p->xmax || p->ymin != p->ymin || p->ymax != p->ymax) return;
    /* the pixels that may be marked: centres inside (centre coverage), or
       squares inside (whole-pixel coverage), of the projected bounds;
       dceil/dfloor clamp to +-2^30, so every int below is in range */
    double in0 = b->inner ? 0.0 : 0.5, in1 = b->inner ? 1.0 : 0.5;
    double fi0 = dmax(dceil((p->xmin + 1) * b->sx - in0), 0), fi1 = dmin(dfloor((p->xmax + 1) * b->sx - in1), b->w - 1.0);
    double fj0 = dmax(dceil((p->ymin + 1) * b->sy - in0), bd->y0);
    double fj1 = dmin(dfloor((p->ymax + 1) * b->sy - in1), bd->y1 - 1.0);
    if (!(fi0 <= fi1 && fj0 <= fj1)) return;
    int i0 = (int)fi0, i1 = (int)fi1;
    bd->faces++;

    /* per constraint, the row's bound on x is linear in j: x > al + be j
       (a > 0: a left edge) or x < al + be j (a < 0: a right edge); with
       a == 0 it bounds the rows instead. Each constraint is shrunk by 2^-24
       of its range over the buffer, and for whole-pixel coverage by half
       its gradient (the pixel's worst corner).
       al + be j must not be NaN at any row (inf - inf from an edge with a
       tiny a: al and be both overflow): where |al| or |be| > 2^900 (an
       edge within 2^-900 of horizontal, or a tiny a from a hostile view),
       the constraint goes to the slow list, whose bound is (t - b j) / a
       per row: a division, but never NaN (t, b finite, a != 0). Real
       views never take it. */
    cull_occ_rowset rs;
    uint32_t nl = 0, nr = 0, ns = 0;
    for (uint32_t k = 0; k < p->nc; k++) {
        const lin3 *c = &p->con[k];
        double marg = 0x1p-24 * (fabs(c->a) * b->w + fabs(c->b) * b->h + fabs(c->c));
        if (b->inner) marg += 0.5 * (fabs(c->a) + fabs(c->b));
        double a = c->a, bb = c->b, t = marg - c->c;
        /* one test for the three: a NaN or infinite term makes the sum
           NaN or infinite (a sum of finite terms that overflows is
           refused too: drawing less is safe) */
        if (!isfin(a + bb + t)) return; /* overflowed (or NaN): drawn nowhere */
        if (a != 0) {
            double al = t / a, be = -bb / a;
            if (!(fabs(al) <= 0x1p900 && fabs(be) <= 0x1p900)) {
                rs.sa[ns] = a;
                rs.sb[ns] = bb;
                rs.st[ns++] = t;
            } else if (a > 0) {
                rs.lal[nl] = al;
                rs.lbe[nl++] = be;
            } else {
                rs.ral[nr] = al;
                rs.rbe[nr++] = be;
            }
        } else if (bb > 0) {
            fj0 = dmax(fj0, dfloor(t / bb) + 1); /* j > t / b */
        } else if (bb < 0) {
            fj1 = dmin(fj1, dceil(t / bb) - 1);
        } else if (!(0 > t)) {
            return; /* 0 > marg - c fails everywhere */
        }
    }
    if (fj0 > fj1) return;
    int j0 = (int)fj0, j1 = (int)fj1;

    /* nearness at the pixel's farthest corner (per plane: half its
       gradients off), never below the farthest vertex; one margin per plane
       for every row, 2^-20 of the largest magnitude the span loop sees */
    double nlo = p->nmin - 0x1p-20 * fabs(p->nmin);
    /* a plane that is not finite, or reaches Z_LIM over the buffer (float
       would overflow, and inf - inf is NaN), is replaced by the constant
       nlo: below the polygon's nearness everywhere, so still conservative */
    for (uint32_t k = 0; k < p->nz; k++) {
        const lin3 *z = &p->z[k];
        if (!(fabs(z->a) * b->w + fabs(z->b) * b->h + fabs(z->c) <= Z_LIM)) p->z[k] = (lin3){0, 0, nlo};
    }
    while (p->nz < 3) p->z[p->nz++] = p->z[0];
    double *corner = rs.corner;
    for (int k = 0; k < 3; k++) {
        const lin3 *z = &p->z[k];
        corner[k] = 0.5 * (fabs(z->a) + fabs(z->b));
        rs.m[k] = 0x1p-20 * (fabs(z->b) * (j1 + 1) + fabs(z->c) + corner[k] + fabs(z->a) * (i1 + 1));
        rs.zb[k] = z->b;
        rs.zc[k] = z->c;
    }
    rs.nl = nl;
    rs.nr = nr;
    rs.ns = ns;
    rs.i0 = i0;
    rs.i1 = i1;
    /* the rows' spans and start nearness (the reference takes the slow
       constraints; the ISA's own rows do not) */
#ifdef CULL_OCC_RASTER_ISA
    /* the AVX2 build: the AVX2 rows inlined, the reference for slow
       constraints */
#define ROWS(...) (ns ? cull_occ_rows_scalar(__VA_ARGS__) : cull_occ_rows8(__VA_ARGS__))
#else
    cull_occ_rowsum (*rows)(const cull_occ_rowset *, int, int, int, int *, int *, float *) =
        ns ? cull_occ_rows_scalar : b->fns.rows;
#define ROWS rows
#endif
    float zlo = cull_round_down(nlo);
    float da[3] = {(float)p->z[0].a, (float)p->z[1].a, (float)p->z[2].a};
    /* where the buffer is already nearer than the region's nearest point over
       a whole tile row of its bounds, the tile row is skipped: front-to-
       back order pays again, inside a cluster and for the part of a face
       that a nearer one hides */
    float zhi = cull_round_up(p->nmax + 0x1p-20 * fabs(p->nmax));
    /* the coarse values' steps, and (the AVX2 build) their starts' terms
       that do not change from tile row to tile row: each plane at the
       tile's farthest pixel corner, a * ia + b * ja + c - corner */
    float dt[3];
    for (int k = 0; k < 3; k++) dt[k] = (float)(8 * p->z[k].a);
#ifdef __AVX2__
    __m256d caia, cb, cc, cco, cjs, cad;
    {
        double aia[4] = {0}, bb[4] = {0}, c[4] = {0}, co[4] = {0}, js[4] = {0}, ad[4] = {0};
        for (int k = 0; k < 3; k++) {
            const lin3 *z = &p->z[k];
            aia[k] = z->a * (z->a >= 0 ? 0 : 7);
            bb[k] = z->b;
            c[k] = z->c;
            co[k] = corner[k];
            js[k] = z->b >= 0 ? 0 : 7;
            ad[k] = fabs(8 * z->a);
        }
        caia = _mm256_loadu_pd(aia);
        cb = _mm256_loadu_pd(bb);
        cc = _mm256_loadu_pd(c);
        cco = _mm256_loadu_pd(co);
        cjs = _mm256_loadu_pd(js);
        cad = _mm256_loadu_pd(ad);
    }
#endif
    /* a tile row (8 pixel rows) at a time: tiles that every row's span
       covers whole get one coarse value (tile_full); only the rest of
       each span is written pixel by pixel */
    for (int ty = j0 >> 3; ty <= j1 >> 3; ty++) {
        if (ty % bd->nb != bd->k) continue;
        if (tile_row_hidden(b, ty, i0 >> 3, i1 >> 3, zhi)) continue;
        int r0 = j0 > ty * 8 ? j0 : ty * 8, r1 = j1 < ty * 8 + 7 ? j1 : ty * 8 + 7;
        int lo[8], hi[8];
        float z0[3 * 8];
        const cull_occ_rowsum rsum = ROWS(&rs, ty * 8, r0 - ty * 8, r1 - ty * 8, lo, hi, z0);
        const int L = rsum.L, H = rsum.H, U0 = rsum.U0, U1 = rsum.U1;
        const bool whole = rsum.whole;
        int ft0 = 1, ft1 = 0;
        if (whole && L <= H) {
            ft0 = (L + 7) >> 3;
            ft1 = ((H + 1) >> 3) - 1;
        }
        if (ft0 <= ft1) {
            /* the minimum over a tile's pixels of what they would store is
               each plane at the tile's farthest pixel corner: linear in tx,
               so the coarse values are one more span, over tile_full */
            float t0[4];
#ifdef __AVX2__
            /* the three planes a vector: the same operations per lane */
            __m256d ja = _mm256_add_pd(_mm256_set1_pd((double)(ty * 8)), cjs);
            __m256d t = _mm256_sub_pd(_mm256_add_pd(_mm256_add_pd(caia, _mm256_mul_pd(cb, ja)), cc), cco);
            __m256d mg = _mm256_add_pd(_mm256_andnot_pd(_mm256_set1_pd(-0.0), t),
                                       _mm256_mul_pd(cad, _mm256_set1_pd((double)(ft1 + 1))));
            _mm_storeu_ps(t0, _mm256_cvtpd_ps(_mm256_sub_pd(t, _mm256_mul_pd(_mm256_set1_pd(0x1p-20), mg))));
#else
            for (int k = 0; k < 3; k++) {
                const lin3 *z = &p->z[k];
                double ia = z->a >= 0 ? 0 : 7, ja = z->b >= 0 ? ty * 8 : ty * 8 + 7;
                double t = z->a * ia + z->b * ja + z->c - corner[k], d = 8 * z->a;
                t0[k] = (float)(t - 0x1p-20 * (fabs(t) + fabs(d) * (ft1 + 1)));
            }
#endif
            b->fns.span(b->tile_full + (size_t)ty * b->tw, ft0, ft1, (int)b->tw, t0[0], dt[0], t0[1], dt[1], t0[2],
                        dt[2], zlo);
            b->fns.span(b->teff + (size_t)ty * b->tw, ft0, ft1, (int)b->tw, t0[0], dt[0], t0[1], dt[1], t0[2], dt[2],
                        zlo);
            memset(b->sdirty + (size_t)ty * b->sdpitch + (ft0 >> 3), 1, (size_t)((ft1 >> 3) - (ft0 >> 3) + 1));
        }
        if (ft0 <= ft1) {
            mark_tiles(b, &bd->next, ty, U0, ft0 * 8 - 1);
            mark_tiles(b, &bd->next, ty, ft1 * 8 + 8, U1);
        } else {
            mark_tiles(b, &bd->next, ty, U0, U1);
        }
        /* the rows' spans, left of the coarse tiles and right of them (or
           whole), one kernel call */
        b->fns.spans(b->pool, b->tslot + (size_t)ty * b->tw, lo, hi, ft0 <= ft1 ? ft0 * 8 : 1,
                     ft0 <= ft1 ? ft1 * 8 + 7 : 0, z0, da[0], da[1], da[2], zlo);
    }
}

#undef ROWS

/* One face: its edges (and the near plane where it crosses it), its
 * halves' nearness planes, the bounds of its part in front of the near
 * plane. Back faces and edge-on faces are skipped. */
static void raster_face(band *bd, const cvert *cv, const cull_occ_face *f, bool two_sided)
{
    cull_occ_buffer *b = bd->b;
    const cvert *v[4];
    for (uint32_t k = 0; k < f->n; k++) v[k] = &cv[f->v[k]];
    uint32_t n = f->n;

    bool all_front = true, any_front = false;
    for (uint32_t k = 0; k < n; k++) {
        if (v[k]->n > 0) any_front = true;
        else all_front = false;
    }
    if (!any_front) return;

    /* back faces first: they are half of what arrives, and cheap to spot.
       An open occluder's back face is drawn as a front face, its corners
       taken the other way round (edge-on and NaN faces never are) */
    {
        double e[3];
        cross_xyw(e, v[1], v[2]);
        double side = e[0] * v[0]->x + e[1] * v[0]->y + e[2] * v[0]->w;
        if (!(side > 0)) {
            if (!(side < 0) || !two_sided) return;
            const cvert *t = v[1];
            v[1] = v[n - 1];
            v[n - 1] = t;
        }
    }

    /* the part in front of the near plane: its projection bounds the rows,
       its vertices bound the nearness */
    rpoly p = {.xmin = INFINITY, .xmax = -INFINITY, .ymin = INFINITY, .ymax = -INFINITY, .nmin = INFINITY,
               .nmax = -INFINITY};
    for (uint32_t k = 0; k < n; k++) {
        const cvert *a = v[k], *q = v[(k + 1) % n];
        cvert o[2];
        uint32_t no = 0;
        if (a->n > 0) o[no++] = *a;
        if ((a->n > 0) != (q->n > 0)) {
            double t = a->n / (a->n - q->n);
            o[no++] = (cvert){a->x + t * (q->x - a->x), a->y + t * (q->y - a->y), a->w + t * (q->w - a->w), 0,
                              a->d + t * (q->d - a->d)};
        }
        for (uint32_t i = 0; i < no; i++) {
            if (!(o[i].w > 0)) return; /* a projection whose near plane is not in front of the eye */
            double iw = 1.0 / o[i].w, x = o[i].x * iw, y = o[i].y * iw;
            if (x != x || y != y || o[i].d * iw != o[i].d * iw) return; /* overflowed: drawn nowhere */
            p.xmin = dmin(p.xmin, x);
            p.xmax = dmax(p.xmax, x);
            p.ymin = dmin(p.ymin, y);
            p.ymax = dmax(p.ymax, y);
            p.nmin = dmin(p.nmin, o[i].d * iw);
            p.nmax = dmax(p.nmax, o[i].d * iw);
        }
    }

    /* halves (0,1,2) and, for a quad, (2,3,0): both must face the eye */
    lin3 nearA, nearB;
    double det;
    if (!half_planes(b, v[0], v[1], v[2], all_front ? NULL : &nearA, &p.z[0], &det)) return;
    p.nz = 1;
    if (n == 4 && !half_planes(b, v[2], v[3], v[0], all_front ? NULL : &nearB, &p.z[p.nz++], &det)) return;

    /* constraints: the edges, then the near plane if the face crosses it */
    for (uint32_t k = 0; k < n; k++) {
        double e[3];
        cross_xyw(e, v[k], v[(k + 1) % n]);
        p.con[p.nc++] = to_pixels(b, e);
    }
    if (!all_front) {
        p.con[p.nc++] = nearA;
        if (n == 4) p.con[p.nc++] = nearB;
    }
    raster_poly(bd, &p);
}

/* 2D convex hull (Andrew's monotone chain) of points (x, y), counter-
 * clockwise, collinear points dropped; writes indices, returns how many. */
static uint32_t hull2(const double (*pt)[2], uint32_t n, uint32_t *idx, uint32_t *out)
{
    /* insertion sort by x, then y: n <= 4 * 64 and usually 8 */
    for (uint32_t i = 0; i < n; i++) idx[i] = i;
    for (uint32_t i = 1; i < n; i++) {
        uint32_t t = idx[i], j = i;
        while (j > 0 && (pt[idx[j - 1]][0] > pt[t][0] || (pt[idx[j - 1]][0] == pt[t][0] && pt[idx[j - 1]][1] > pt[t][1]))) {
            idx[j] = idx[j - 1];
            j--;
        }
        idx[j] = t;
    }
    uint32_t k = 0;
    for (int pass = 0; pass < 2; pass++) {
        uint32_t start = k;
        for (uint32_t ii = 0; ii < n; ii++) {
            uint32_t i = pass ? idx[n - 1 - ii] : idx[ii];
            while (k >= start + 2) {
                const double *a = pt[out[k - 2]], *c = pt[out[k - 1]], *d = pt[i];
                double cr = (c[0] - a[0]) * (d[1] - a[1]) - (c[1] - a[1]) * (d[0] - a[0]);
                if (cr > 0) break;
                k--;
            }
            out[k++] = i;
        }
        k--; /* the last point of each chain starts the other */
    }
    return k < 3 ? 0 : k;
}

/* A closed convex cluster entirely in front of the near plane, drawn as
 * one polygon: its silhouette (the hull of its projected vertices), at the
 * minimum of its front faces' planes (a ray enters a convex solid through
 * the front face whose plane it crosses last). One polygon instead of two
 * or three faces: no seam along the crease between them, and fewer rows.
 * false if the cluster does not qualify (the caller draws its faces). */
static bool same_plane(const lin3 *p, const lin3 *q)
{
    double tol = 0x1p-40 * (fabs(p->a) + fabs(p->b) + fabs(p->c) + fabs(q->a) + fabs(q->b) + fabs(q->c));
    return fabs(p->a - q->a) * 8192 <= tol && fabs(p->b - q->b) * 8192 <= tol && fabs(p->c - q->c) <= tol;
}

/* The silhouette of a closed convex cluster as the loop of its front
 * faces' edges that no other front face shares (a closed cluster's faces
 * meet edge to edge, opposite ways), in the faces' own order: the same
 * outline as the hull of its projected vertices, found without sorting
 * them. Writes the loop's vertices; 0 where the edges do not make one
 * loop of at most MAX_CONS (the caller takes the hull then). */
static uint32_t front_loop(const cull_occ_cluster *cl, const uint32_t *front, uint32_t nfront, uint32_t *out)
{
    uint16_t ea[12], eb[12]; /* at most 3 front faces (the caller's limit) of 4 edges */
    uint32_t ne = 0;
    for (uint32_t k = 0; k < nfront; k++) {
        const cull_occ_face *f = &cl->f[front[k]];
        for (uint32_t i = 0; i < f->n; i++) {
            uint16_t a = f->v[i], c = f->v[(i + 1) % f->n];
            /* an edge another front face has the other way is inside */
            uint32_t j = 0;
            while (j < ne && !(ea[j] == c && eb[j] == a)) j++;
            if (j < ne) {
                ea[j] = ea[--ne];
                eb[j] = eb[ne];
            } else {
                ea[ne] = a;
                eb[ne++] = c;
            }
        }
    }
    if (ne < 3 || ne > MAX_CONS) return 0;
    uint32_t n = 0, at = 0;
    do {
        out[n++] = ea[at];
        uint32_t j = 0;
        while (j < ne && ea[j] != eb[at]) j++;
        if (j == ne) return 0;
        at = j;
    } while (at != 0 && n < ne);
    return at == 0 && n == ne ? n : 0;
}

static bool raster_convex(band *bd, const cvert *cv, const cull_occ_cluster *cl)
{
    cull_occ_buffer *b = bd->b;
    if (!cl->convex) return false;
    /* worth it when two or three faces show; one face is drawn as a face */
    uint32_t front[3], nfront = 0;
    for (uint32_t f = 0; f < cl->nf; f++) {
        const cull_occ_face *fc = &cl->f[f];
        const cvert *v0 = &cv[fc->v[0]], *v1 = &cv[fc->v[1]], *v2 = &cv[fc->v[2]];
        double e[3];
        cross_xyw(e, v1, v2);
        if (!(e[0] * v0->x + e[1] * v0->y + e[2] * v0->w > 0)) continue; /* back or edge-on */
        if (nfront == 3) return false;
        front[nfront++] = f;
    }
    if (nfront < 2) return false;
    rpoly p = {.xmin = INFINITY, .xmax = -INFINITY, .ymin = INFINITY, .ymax = -INFINITY, .nmin = INFINITY,
               .nmax = -INFINITY};
    double pt[4 * CULL_OCC_CLUSTER_FACES][2];
    for (uint32_t i = 0; i < cl->nv; i++) {
        const cvert *v = &cv[i];
        if (!(v->n > 0) || !(v->w > 0)) return false; /* reaches the near plane: faces, clipped */
        double iw = 1.0 / v->w;
        pt[i][0] = v->x * iw;
        pt[i][1] = v->y * iw;
        if (pt[i][0] != pt[i][0] || pt[i][1] != pt[i][1] || v->d * iw != v->d * iw) return true; /* overflowed */
        p.xmin = dmin(p.xmin, pt[i][0]);
        p.xmax = dmax(p.xmax, pt[i][0]);
        p.ymin = dmin(p.ymin, pt[i][1]);
        p.ymax = dmax(p.ymax, pt[i][1]);
        p.nmin = dmin(p.nmin, v->d * iw);
        p.nmax = dmax(p.nmax, v->d * iw);
    }
    for (uint32_t k = 0; k < nfront; k++) {
        const cull_occ_face *fc = &cl->f[front[k]];
        const cvert *v0 = &cv[fc->v[0]], *v2 = &cv[fc->v[2]];
        lin3 za, zb;
        double det;
        if (!half_planes(b, v0, &cv[fc->v[1]], v2, NULL, &za, &det)) return false; /* ill-conditioned */
        if (p.nz == 3) return false; /* more planes than the span loop takes: faces */
        p.z[p.nz++] = za;
        /* a quad's other half: the same plane up to rounding, or one more */
        if (fc->n == 4) {
            if (!half_planes(b, v2, &cv[fc->v[3]], v0, NULL, &zb, &det)) return false;
            if (!same_plane(&za, &zb)) {
                if (p.nz == 3) return false;
                p.z[p.nz++] = zb;
            }
        }
    }
    uint32_t idx[4 * CULL_OCC_CLUSTER_FACES], hull[4 * CULL_OCC_CLUSTER_FACES + 1];
    uint32_t nh = front_loop(cl, front, nfront, hull);
    if (!nh) {
        nh = hull2((const double(*)[2])pt, cl->nv, idx, hull);
        if (!nh) return true; /* degenerate silhouette: covers nothing */
    }
    if (nh > MAX_CONS) return false;
    for (uint32_t k = 0; k < nh; k++) {
        double e[3];
        cross_xyw(e, &cv[hull[k]], &cv[hull[(k + 1) % nh]]);
        p.con[p.nc++] = to_pixels(b, e);
    }
    raster_poly(bd, &p);
    return true;
}

/* The rectangle of a cluster, in this band, already hidden? Strips and
 * tiles are brought up to date on demand, so a hidden cluster costs a few
 * strip reads and a tile is recomputed only when read after a write. */
static bool band_hidden(const band *bd, const cull_occ_rect *r)
{
    cull_occ_buffer *b = bd->b;
    int x0 = r->x0, x1 = r->x1, y0 = r->y0 > bd->y0 ? r->y0 : bd->y0, y1 = r->y1 < bd->y1 - 1 ? r->y1 : bd->y1 - 1;
    float z = r->z;
    for (int ty = y0 >> 3; ty <= y1 >> 3; ty++) {
        if (ty % bd->nb != bd->k) continue;
        const trow tr = trow_of(b, ty);
        for (int tx = first_not_above(&tr, x0 >> 3, x1 >> 3, z); tx <= x1 >> 3;
             tx = first_not_above(&tr, tx + 1, x1 >> 3, z)) {
            /* the tile's minimum is not nearer than z: the pixels decide */
            if (tr.st[tx] == TILE_INVALID) return false;
            int px0 = tx << 3 > x0 ? 0 : x0 & 7, px1 = (tx << 3) + 7 < x1 ? 7 : x1 & 7;
            int py0 = ty << 3 > y0 ? ty << 3 : y0, py1 = (ty << 3) + 7 < y1 ? (ty << 3) + 7 : y1;
            const float *px = cull_occ_tile_px(b, (size_t)ty * b->tw + (size_t)tx);
            for (int py = py0; py <= py1; py++)
                if (b->fns.any_le(px + 8 * (py & 7), px0, px1, 8, z)) return false;
        }
    }
    return true;
}

/* The band's dirty tiles, recomputed at its end. */
static void band_finish_tiles(band *bd)
{
    for (int ty = bd->k; ty < (bd->y1 + 7) >> 3; ty += bd->nb) tile_row_finish(bd->b, ty);
}

static void raster_cluster(band *bd, const cull_occ_cluster *cl)
{
    const cull_occ_buffer *b = bd->b;
    cvert cv[4 * CULL_OCC_CLUSTER_FACES];
    for (uint32_t i = 0; i < cl->nv; i++) {
        double p[3] = {cl->v[3 * i] - b->origin[0], cl->v[3 * i + 1] - b->origin[1], cl->v[3 * i + 2] - b->origin[2]};
        cv[i] = (cvert){lin4(b->rx, p), lin4(b->ry, p), lin4(b->rw, p), lin4(b->rn, p), lin4(b->rd, p)};
    }
    if (raster_convex(bd, cv, cl)) return;
    for (uint32_t f = 0; f < cl->nf; f++) raster_face(bd, cv, &cl->f[f], cl->two_sided);
}

typedef struct render_job {
    cull_occ_buffer *b;
    band bands[MAX_BANDS];
    uint32_t nbands;
} render_job;

static void job_band(void *arg, uint32_t t)
{
    render_job *j = arg;
    for (uint32_t k = t; k < j->nbands; k += j->b->threads_used) {
        band *bd = &j->bands[k];
        cull_occ_buffer *b = bd->b;
        /* no pixel is cleared here: a tile's pixels are cleared when a
           span first writes into it (most tiles are never written, or
           covered whole by a coarse value) */
        for (int ty = bd->k; ty < (bd->y1 + 7) >> 3; ty += bd->nb) {
            b->fns.fill(b->tile_full + (size_t)ty * b->tw, b->tw, EMPTY);
            /* the pixels' minima and the slots too, though only valid tiles'
               are read: written here in one pass, rows in order, their
               lines stream in; written as spans reach tiles, a render after
               other work waited on them a line at a time (raised walk at
               1280x720: cold ~35 us less) */
            b->fns.fill(b->tile + (size_t)ty * b->tw, b->tw, EMPTY);
            memset(b->tslot + (size_t)ty * b->tw, 0, b->tw * sizeof *b->tslot);
            b->fns.fill(b->teff + (size_t)ty * b->tw, b->tw, EMPTY);
            b->fns.fill(b->tmax + (size_t)ty * b->tw, b->tw, EMPTY); /* invalid tiles: see cull_occ_vkey_row */
            /* tiles past the right edge hold padding: they never lower a
               strip's or a big tile's minimum */
            for (uint32_t tx = (b->w + 7) >> 3; tx < b->tw; tx++) b->teff[(size_t)ty * b->tw + tx] = PAD;
            memset(b->tstate + (size_t)ty * b->tpitch, TILE_INVALID, b->tw);
            b->fns.fill(b->strip + (size_t)ty * b->spitch, b->t2w, EMPTY);
            memset(b->sdirty + (size_t)ty * b->sdpitch, 0, b->t2w);
        }
        for (uint32_t i = 0; i < b->nitems; i++) {
            const cull_occ_item *it = &b->items[i];
            if (it->near) {
                raster_cluster(bd, it->cl);
                bd->clusters++;
                continue;
            }
            /* a rectangle within fewer tile rows than bands may miss this one */
            int t0 = it->r.y0 >> 3, first = t0 + ((bd->k - t0 % bd->nb) + bd->nb) % bd->nb;
            if (first > it->r.y1 >> 3) continue;
            if (band_hidden(bd, &it->r)) continue;
            raster_cluster(bd, it->cl);
            bd->clusters++;
        }
        band_finish_tiles(bd);
        b->slot_next[k] = bd->next;
    }
}

/* Nearest first, ties in list order: a stable LSD radix sort on the top 16
 * bits of the keys (sign, exponent, 7 bits of mantissa: nearness to within
 * 1%, plenty for drawing order), turned so that unsigned order is
 * descending float order. Two passes of 8 bits. */
static bool sort_items(cull_occ_buffer *b)
{
    uint32_t n = b->nitems;
    if (!vp_grow32((void **)&b->sortbuf, &b->sortbuf_cap, 2 * (size_t)n, sizeof *b->sortbuf) ||
        !vp_grow32((void **)&b->items2, &b->items2_cap, n, sizeof *b->items2))
        return false;
    uint64_t *a = b->sortbuf, *t = a + n;
    for (uint32_t i = 0; i < n; i++) {
        uint32_t u;
        memcpy(&u, &b->items[i].key, sizeof u);
        u = (u & 0x80000000u) ? ~u : u | 0x80000000u; /* ascending float order */
        a[i] = (uint64_t)~u << 32 | i;                 /* descending */
    }
    for (int pass = 0; pass < 2; pass++) {
        uint32_t shift = 48 + 8 * (uint32_t)pass, count[256] = {0};
        for (uint32_t i = 0; i < n; i++) count[(a[i] >> shift) & 255]++;
        uint32_t sum = 0;
        for (int k = 0; k < 256; k++) {
            uint32_t c = count[k];
            count[k] = sum;
            sum += c;
        }
        for (uint32_t i = 0; i < n; i++) t[count[(a[i] >> shift) & 255]++] = a[i];
        uint64_t *x = a;
        a = t;
        t = x;
    }
    for (uint32_t i = 0; i < n; i++) b->items2[i] = b->items[(uint32_t)a[i]];
    cull_occ_item *x = b->items;
    uint32_t xc = b->items_cap;
    b->items = b->items2;
    b->items_cap = b->items2_cap;
    b->items2 = x;
    b->items2_cap = xc;
    return true;
}

/* cull_occ_render_isa's work, in this build */
static int render_impl(const cull_world *w, const cull_view *v, cull_occ_buffer *b, cull_pool *pool, uint32_t threads,
                       uint32_t isa, const uint64_t *sublevels, cull_occ_stats *st)
{
    if (st) memset(st, 0, sizeof *st);
    if (!w || !v || !b) return CULL_ERR_INVALID;
    if (v->plane_count < 5 || v->plane_count > 6) return CULL_ERR_MATRIX;
    uint64_t t0 = now_ns();
    b->fns = cull_occ_fns_for(isa);
    cull_occ_setup_view(b, v);
    b->drawn = false;

    /* the clusters in view (the SIMD box kernel of the cell stage over the
       world's cluster bounds), nearest first */
    if (!vp_grow32((void **)&b->items, &b->items_cap, (size_t)w->nclusters + 1, sizeof *b->items) ||
        !vp_grow32((void **)&b->codes, &b->codes_cap, (size_t)w->nclusters + 8, 1) ||
        !vp_grow32((void **)&b->pidx, &b->pidx_cap, (size_t)w->nclusters + 4, sizeof *b->pidx) ||
        !vp_grow32((void **)&b->proj, &b->proj_cap, 6 * ((size_t)w->nclusters + 4), sizeof *b->proj) ||
        !vp_grow32((void **)&b->pcode, &b->pcode_cap, (size_t)w->nclusters + 4, sizeof *b->pcode) ||
        !vp_grow32((void **)&b->rects, &b->rects_cap, (size_t)w->nclusters + 4, sizeof *b->rects))
        return CULL_ERR_NOMEM;
    uint32_t n = 0;
    if (b->usable && w->nclusters) {
        cull_cplane cpl[6];
        for (uint32_t i = 0; i < v->plane_count; i++) {
            const double *pl = v->plane[i];
            for (int a = 0; a < 3; a++) {
                cpl[i].n[a] = pl[a];
                cpl[i].an[a] = fabs(pl[a]);
            }
            cpl[i].d = pl[3] - pl[0] * v->origin[0] - pl[1] * v->origin[1] - pl[2] * v->origin[2];
        }
        cull_isa_cells(isa)(&w->ocl_soa, w->nclusters, cpl, v->plane_count, b->codes);
        /* those in view and in the sub-levels asked, projected together
           (cull_occ_project_bound's bounds, four a vector where the ISA
           has it) */
        uint32_t m = 0;
        /* (a cluster's own memory is read only for a sub-level filter:
           cold, a read per cluster in view cost ~6 us on the street walk) */
        if (!sublevels) {
            for (uint32_t i = 0; i < w->nclusters; i++)
                if (!(b->codes[i] & 0x80u)) b->pidx[m++] = i;
        } else {
            for (uint32_t i = 0; i < w->nclusters; i++)
                if (!(b->codes[i] & 0x80u) && cull_sublevel_in(sublevels, w->ocl[i]->sublevel)) b->pidx[m++] = i;
        }
        size_t pitch = ((size_t)m + 3) & ~(size_t)3;
        b->fns.project(b, &w->ocl_soa, b->pidx, m, b->proj, pitch);
#ifdef CULL_OCC_RASTER_ISA
        /* the AVX2 build: the rectangles four a vector too (into the
           items, then compacted) */
        cull_occ_rects_avx2(b, b->proj, pitch, m, b->pcode, b->rects);
#endif
        for (uint32_t q = 0; q < m; q++) {
            cull_occ_item *it = &b->items[n];
#ifdef CULL_OCC_RASTER_ISA
            int k = b->pcode[q];
            it->r = b->rects[q];
#else
            const double o[6] = {b->proj[q], b->proj[pitch + q], b->proj[2 * pitch + q], b->proj[3 * pitch + q],
                                 b->proj[4 * pitch + q], b->proj[5 * pitch + q]};
            int k = cull_occ_bound_rect(b, o, &it->r);
#endif
            if (k == OCC_BOX_OFF) continue;
            it->cl = w->ocl[b->pidx[q]];
            it->near = k == OCC_BOX_NEAR;
            it->key = it->near ? INFINITY : it->r.z;
            n++;
        }
    }
    b->nitems = n;
    if (st) st->clusters_in_view = n;
    if (!n) {
        if (st) st->raster_ns = now_ns() - t0;
        return CULL_OK;
    }
    if (!sort_items(b)) return CULL_ERR_NOMEM;

    uint32_t nt = cull_pool_threads(pool);
    if (threads && threads < nt) nt = threads;
    uint32_t tile_rows = (b->h + 7) / 8;
    uint32_t nb = nt > tile_rows ? tile_rows : nt;
    if (nb > MAX_BANDS) nb = MAX_BANDS;
    render_job j = {.b = b, .nbands = nb};
    /* band k draws tile rows k, k + nb, ...: its slots are a range of
       that many rows' tiles, after the ranges of bands before it */
    uint32_t base = 0;
    for (uint32_t k = 0; k < nb; k++) {
        j.bands[k] = (band){.b = b, .y0 = 0, .y1 = (int)b->h, .k = (int)k, .nb = (int)nb, .next = base};
        base += (tile_rows - k + nb - 1) / nb * b->tw;
    }
    b->threads_used = nb;
    if (nb > 1) cull_pool_run(pool, job_band, &j, nb);
    else job_band(&j, 0);
    /* the big tiles from the small ones */
    for (uint32_t Y = 0; Y < b->t2h; Y++)
        for (uint32_t X = 0; X < b->t2w; X++) {
            float m = PAD;
            for (uint32_t ty = Y * 8; ty < Y * 8 + 8; ty++) m = fmin_(m, b->strip[(size_t)ty * b->spitch + X]);
            b->tile2[Y * b->t2w + X] = m;
        }
    uint32_t faces = 0, drawn = 0;
    for (uint32_t k = 0; k < nb; k++) {
        faces += j.bands[k].faces;
        drawn += j.bands[k].clusters;
    }
    b->drawn = faces > 0;
    if (st) {
        st->clusters_drawn = drawn;
        st->faces_drawn = faces;
        st->threads_used = nb;
        st->raster_ns = now_ns() - t0;
    }
    return CULL_OK;
}

#ifndef CULL_OCC_RASTER_ISA
int cull_occ_render(const cull_world *w, const cull_view *v, cull_occ_buffer *b, cull_pool *pool,
                    uint32_t threads, cull_occ_stats *st)
{
    if (!b) return CULL_ERR_INVALID;
    return cull_occ_render_isa(w, v, b, pool, threads, b->isa, NULL, st);
}

int cull_occ_render_sub(const cull_world *w, const cull_view *v, cull_occ_buffer *b, cull_pool *pool,
                        uint32_t threads, const uint64_t *sublevels, cull_occ_stats *st)
{
    if (!b) return CULL_ERR_INVALID;
    return cull_occ_render_isa(w, v, b, pool, threads, b->isa, sublevels, st);
}
#endif
