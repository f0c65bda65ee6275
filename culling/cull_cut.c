/*
 * cull_cut.c — destruction cuts holes in occluders (see culling.h,
 * cull_occ_cut): triangles are classified against the destroyed region
 * (the sphere set, each radius widened by a margin) exactly, in double:
 *   - farther than the widened radius from every sphere: kept whole;
 *   - inside one widened sphere (its three corners are; a ball is convex):
 *     dropped;
 *   - otherwise split in four at its edges' midpoints, down to a smallest
 *     edge; a piece still straddling then is dropped.
 * So an occluder only ever loses area (it never hides what the hole shows)
 * and loses at most pieces of the smallest size around each hole's rim.
 */
#include "cull_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define MAX_DEPTH 12

typedef struct cutter {
    const double (*sph)[4];   /* spheres relative to origin, widened radius */
    uint32_t nsph;
    double min_edge2;
    float *out;
    uint32_t n, cap, max_out;
    uint32_t *parent;
    int rc;
    uint64_t work, budget; /* (piece, sphere) tests made / allowed */
} cutter;

static double dot3(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* Squared distance from p to triangle abc (Ericson, "Real-Time Collision
 * Detection" 5.1.5: the closest point by Voronoi regions). */
static double dist2_point_tri(const double p[3], const double a[3], const double b[3], const double c[3])
{
    double ab[3], ac[3], ap[3], q[3];
    for (int k = 0; k < 3; k++) {
        ab[k] = b[k] - a[k];
        ac[k] = c[k] - a[k];
        ap[k] = p[k] - a[k];
    }
    double d1 = dot3(ab, ap), d2 = dot3(ac, ap);
    if (d1 <= 0 && d2 <= 0) return dot3(ap, ap);
    double bp[3], cp[3];
    for (int k = 0; k < 3; k++) {
        bp[k] = p[k] - b[k];
        cp[k] = p[k] - c[k];
    }
    double d3 = dot3(ab, bp), d4 = dot3(ac, bp);
    if (d3 >= 0 && d4 <= d3) return dot3(bp, bp);
    double vc = d1 * d4 - d3 * d2;
    if (vc <= 0 && d1 >= 0 && d3 <= 0) {
        double v = d1 / (d1 - d3);
        for (int k = 0; k < 3; k++) q[k] = a[k] + v * ab[k];
        goto out;
    }
    double d5 = dot3(ab, cp), d6 = dot3(ac, cp);
    if (d6 >= 0 && d5 <= d6) return dot3(cp, cp);
    double vb = d5 * d2 - d1 * d6;
    if (vb <= 0 && d2 >= 0 && d6 <= 0) {
        double w = d2 / (d2 - d6);
        for (int k = 0; k < 3; k++) q[k] = a[k] + w * ac[k];
        goto out;
    }
    double va = d3 * d6 - d5 * d4;
    if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
        double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        for (int k = 0; k < 3; k++) q[k] = b[k] + w * (c[k] - b[k]);
        goto out;
    }
    {
        double den = 1 / (va + vb + vc), v = vb * den, w = vc * den;
        for (int k = 0; k < 3; k++) q[k] = a[k] + ab[k] * v + ac[k] * w;
    }
out:;
    double d[3] = {p[0] - q[0], p[1] - q[1], p[2] - q[2]};
    return dot3(d, d);
}

static void emit(cutter *c, const double t[3][3], uint32_t parent)
{
    if (c->rc) return;
    if (c->n >= c->max_out) {
        c->rc = CULL_ERR_CAPACITY;
        return;
    }
    if (c->n == c->cap) {
        uint32_t cap = (uint32_t)vp_grow_cap(c->cap, (size_t)c->n + 1, 64, 9 * sizeof(float), (size_t)1 << 31);
        float *o = cap ? realloc(c->out, (size_t)cap * 9 * sizeof *o) : NULL;
        uint32_t *p = cap ? realloc(c->parent, (size_t)cap * sizeof *p) : NULL;
        if (o) c->out = o;
        if (p) c->parent = p;
        if (!o || !p) {
            c->rc = CULL_ERR_NOMEM;
            return;
        }
        c->cap = cap;
    }
    for (int v = 0; v < 3; v++)
        for (int k = 0; k < 3; k++) c->out[9 * (size_t)c->n + 3 * v + k] = (float)t[v][k];
    c->parent[c->n++] = parent;
}

static void cut(cutter *c, const double t[3][3], uint32_t parent, int depth)
{
    if (c->rc) return;
    c->work += c->nsph;
    if (c->work > c->budget) { /* the caller's cost bound: give up */
        c->rc = CULL_ERR_CAPACITY;
        return;
    }
    bool straddles = false;
    for (uint32_t k = 0; k < c->nsph; k++) {
        const double *s = c->sph[k];
        double r2 = s[3] * s[3];
        if (dist2_point_tri(s, t[0], t[1], t[2]) > r2) continue; /* clear of this one */
        bool inside = true;
        for (int v = 0; v < 3 && inside; v++) {
            double d[3] = {t[v][0] - s[0], t[v][1] - s[1], t[v][2] - s[2]};
            inside = dot3(d, d) <= r2;
        }
        if (inside) return; /* destroyed */
        straddles = true;
    }
    if (!straddles) {
        emit(c, t, parent);
        return;
    }
    double longest = 0;
    for (int e = 0; e < 3; e++) {
        const double *a = t[e], *b = t[(e + 1) % 3];
        double d[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
        longest = fmax(longest, dot3(d, d));
    }
    if (depth >= MAX_DEPTH || longest <= c->min_edge2) return; /* the rim: dropped */
    double m[3][3];
    for (int e = 0; e < 3; e++)
        for (int k = 0; k < 3; k++) m[e][k] = 0.5 * (t[e][k] + t[(e + 1) % 3][k]);
    const double q[4][3][3] = {{{t[0][0], t[0][1], t[0][2]}, {m[0][0], m[0][1], m[0][2]}, {m[2][0], m[2][1], m[2][2]}},
                               {{m[0][0], m[0][1], m[0][2]}, {t[1][0], t[1][1], t[1][2]}, {m[1][0], m[1][1], m[1][2]}},
                               {{m[2][0], m[2][1], m[2][2]}, {m[1][0], m[1][1], m[1][2]}, {t[2][0], t[2][1], t[2][2]}},
                               {{m[0][0], m[0][1], m[0][2]}, {m[1][0], m[1][1], m[1][2]}, {m[2][0], m[2][1], m[2][2]}}};
    for (int i = 0; i < 4; i++) cut(c, q[i], parent, depth + 1);
}

int cull_occ_cut(const float *tri, uint32_t ntri, const double origin[3], const cull_dvol *v, double margin,
                 double min_edge, uint32_t max_out, float **out, uint32_t **parent, uint32_t *nout)
{
    *out = NULL;
    if (parent) *parent = NULL;
    *nout = 0;
    if ((!tri && ntri) || !v || !(margin >= 0) || !(min_edge > 0) || !isfinite(margin) || !isfinite(min_edge))
        return CULL_ERR_INVALID;
    double(*sph)[4] = malloc(((size_t)v->nsph + 1) * sizeof *sph);
    if (!sph) return CULL_ERR_NOMEM;
    for (uint32_t k = 0; k < v->nsph; k++) {
        for (int a = 0; a < 3; a++) sph[k][a] = v->sph[k][a] - origin[a];
        sph[k][3] = v->sph[k][3] + margin;
    }
    cutter c = {.sph = (const double(*)[4])sph, .nsph = v->nsph, .min_edge2 = min_edge * min_edge,
                .max_out = max_out, .budget = (uint64_t)max_out * CULL_CUT_WORK_PER_PIECE};
    for (uint32_t i = 0; i < ntri && !c.rc; i++) {
        double t[3][3];
        for (int p = 0; p < 3; p++)
            for (int k = 0; k < 3; k++) t[p][k] = tri[9 * (size_t)i + 3 * p + k];
        cut(&c, (const double(*)[3])t, i, 0);
    }
    free(sph);
    if (c.rc) {
        free(c.out);
        free(c.parent);
        return c.rc;
    }
    *out = c.out;
    if (parent) *parent = c.parent;
    else free(c.parent);
    *nout = c.n;
    return CULL_OK;
}
