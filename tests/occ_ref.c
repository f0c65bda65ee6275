/*
 * occ_ref.c — see occ_ref.h. Slow on purpose: per pixel, per primitive.
 * A primitive's pixel range comes from projecting its corners after
 * clipping its edges to the near plane, grown by two pixels, so the range
 * can only be too generous.
 */
#include "occ_ref.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static bool invert4(const double m[16], double inv[16])
{
    /* Gauss-Jordan with partial pivoting on a column-major matrix */
    double a[4][8];
    for (int r = 0; r < 4; r++)
        for (int c = 0; c < 4; c++) {
            a[r][c] = m[c * 4 + r];
            a[r][c + 4] = r == c;
        }
    for (int c = 0; c < 4; c++) {
        int p = c;
        for (int r = c + 1; r < 4; r++)
            if (fabs(a[r][c]) > fabs(a[p][c])) p = r;
        if (a[p][c] == 0) return false;
        for (int k = 0; k < 8; k++) {
            double t = a[c][k];
            a[c][k] = a[p][k];
            a[p][k] = t;
        }
        double d = a[c][c];
        for (int k = 0; k < 8; k++) a[c][k] /= d;
        for (int r = 0; r < 4; r++) {
            if (r == c) continue;
            double f = a[r][c];
            for (int k = 0; k < 8; k++) a[r][k] -= f * a[c][k];
        }
    }
    for (int r = 0; r < 4; r++)
        for (int c = 0; c < 4; c++) inv[c * 4 + r] = a[r][c + 4];
    return true;
}

static void unproject(const double inv[16], double x, double y, double z, double out[3])
{
    double p[4];
    for (int r = 0; r < 4; r++) p[r] = inv[r] * x + inv[4 + r] * y + inv[8 + r] * z + inv[12 + r];
    for (int a = 0; a < 3; a++) out[a] = p[a] / p[3];
}

int occ_ref_init(occ_ref *r, const cull_view *v, uint32_t w, uint32_t h)
{
    memset(r, 0, sizeof *r);
    r->w = w;
    r->h = h;
    memcpy(r->origin, v->origin, sizeof r->origin);
    memcpy(r->m, v->clip, sizeof r->m);
    double inv[16];
    if (!invert4(v->clip, inv)) return -1;
    /* depth of the near plane and of a plane between near and far, NDC */
    double zn, zm;
    switch (v->depth_mode) {
    case CULL_DEPTH_GL: zn = -1; zm = 0; break;
    case CULL_DEPTH_ZERO_ONE: zn = 0; zm = 0.5; break;
    default: zn = 1; zm = 0.5; break;
    }
    for (int c = 0; c < 4; c++) {
        double r2 = v->clip[c * 4 + 2], r3 = v->clip[c * 4 + 3];
        r->nearfn[c] = v->depth_mode == CULL_DEPTH_GL ? r3 + r2 : v->depth_mode == CULL_DEPTH_ZERO_ONE ? r2 : r3 - r2;
    }
    r->ray = malloc((size_t)w * h * 6 * sizeof *r->ray);
    r->t = malloc((size_t)w * h * sizeof *r->t);
    if (!r->ray || !r->t) {
        occ_ref_free(r);
        return -1;
    }
    for (uint32_t j = 0; j < h; j++)
        for (uint32_t i = 0; i < w; i++) {
            double x = (2.0 * i + 1) / w - 1, y = (2.0 * j + 1) / h - 1;
            double *ray = r->ray + 6 * ((size_t)j * w + i);
            double b[3];
            unproject(inv, x, y, zn, ray);
            unproject(inv, x, y, zm, b);
            for (int a = 0; a < 3; a++) ray[3 + a] = b[a] - ray[a];
            r->t[(size_t)j * w + i] = INFINITY;
        }
    return 0;
}

void occ_ref_free(occ_ref *r)
{
    free(r->ray);
    free(r->t);
    r->ray = r->t = NULL;
}

static double nearf(const occ_ref *r, const double q[3])
{
    return r->nearfn[0] * q[0] + r->nearfn[1] * q[1] + r->nearfn[2] * q[2] + r->nearfn[3];
}

/* Pixel range of a convex polygon or a box's corners (camera-relative),
 * clipped to the near plane first; false if nothing is in front or on
 * screen. box: p holds 8 corners, clipped as the box's 12 edges. */
static bool pixel_range(const occ_ref *r, const double (*p)[3], int n, bool box, int *x0, int *y0, int *x1,
                        int *y1)
{
    static const int box_edges[12][2] = {{0, 1}, {2, 3}, {4, 5}, {6, 7}, {0, 2}, {1, 3},
                                         {4, 6}, {5, 7}, {0, 4}, {1, 5}, {2, 6}, {3, 7}};
    double pts[40][3];
    int np = 0;
    int ne = box ? 12 : n;
    for (int e = 0; e < ne; e++) {
        const double *a = box ? p[box_edges[e][0]] : p[e], *b = box ? p[box_edges[e][1]] : p[(e + 1) % n];
        double fa = nearf(r, a), fb = nearf(r, b);
        if (fa >= 0) memcpy(pts[np++], a, sizeof pts[0]);
        if (box && fb >= 0) memcpy(pts[np++], b, sizeof pts[0]);
        if ((fa >= 0) != (fb >= 0)) {
            double t = fa / (fa - fb);
            for (int k = 0; k < 3; k++) pts[np][k] = a[k] + t * (b[k] - a[k]);
            np++;
        }
    }
    if (!np) return false;
    double xmin = INFINITY, xmax = -INFINITY, ymin = INFINITY, ymax = -INFINITY;
    const double *m = r->m;
    for (int k = 0; k < np; k++) {
        const double *q = pts[k];
        double w = m[3] * q[0] + m[7] * q[1] + m[11] * q[2] + m[15];
        if (!(w > 0)) { /* a projection whose near plane is not in front */
            xmin = ymin = -INFINITY;
            xmax = ymax = INFINITY;
            break;
        }
        double x = (m[0] * q[0] + m[4] * q[1] + m[8] * q[2] + m[12]) / w;
        double y = (m[1] * q[0] + m[5] * q[1] + m[9] * q[2] + m[13]) / w;
        xmin = fmin(xmin, x);
        xmax = fmax(xmax, x);
        ymin = fmin(ymin, y);
        ymax = fmax(ymax, y);
    }
    double a0 = floor((xmin + 1) * 0.5 * r->w) - 2, a1 = ceil((xmax + 1) * 0.5 * r->w) + 2;
    double b0 = floor((ymin + 1) * 0.5 * r->h) - 2, b1 = ceil((ymax + 1) * 0.5 * r->h) + 2;
    a0 = fmax(a0, 0);
    b0 = fmax(b0, 0);
    a1 = fmin(a1, r->w - 1.0);
    b1 = fmin(b1, r->h - 1.0);
    if (!(a0 <= a1 && b0 <= b1)) return false;
    *x0 = (int)a0;
    *x1 = (int)a1;
    *y0 = (int)b0;
    *y1 = (int)b1;
    return true;
}

void occ_ref_add_triangles(occ_ref *r, const double *tri, size_t n)
{
    for (size_t k = 0; k < n; k++) {
        double v[3][3];
        for (int i = 0; i < 3; i++)
            for (int a = 0; a < 3; a++) v[i][a] = tri[9 * k + 3 * i + a] - r->origin[a];
        double e1[3], e2[3], nrm[3];
        for (int a = 0; a < 3; a++) {
            e1[a] = v[1][a] - v[0][a];
            e2[a] = v[2][a] - v[0][a];
        }
        nrm[0] = e1[1] * e2[2] - e1[2] * e2[1];
        nrm[1] = e1[2] * e2[0] - e1[0] * e2[2];
        nrm[2] = e1[0] * e2[1] - e1[1] * e2[0];
        int x0, y0, x1, y1;
        if (!pixel_range(r, (const double(*)[3])v, 3, false, &x0, &y0, &x1, &y1)) continue;
        for (int j = y0; j <= y1; j++)
            for (int i = x0; i <= x1; i++) {
                const double *o = r->ray + 6 * ((size_t)j * r->w + i), *d = o + 3;
                /* front faces only: the ray must run against the normal */
                if (!(nrm[0] * d[0] + nrm[1] * d[1] + nrm[2] * d[2] < 0)) continue;
                double p[3] = {d[1] * e2[2] - d[2] * e2[1], d[2] * e2[0] - d[0] * e2[2],
                               d[0] * e2[1] - d[1] * e2[0]};
                double det = e1[0] * p[0] + e1[1] * p[1] + e1[2] * p[2];
                if (det == 0) continue;
                double s[3] = {o[0] - v[0][0], o[1] - v[0][1], o[2] - v[0][2]};
                double u = (s[0] * p[0] + s[1] * p[1] + s[2] * p[2]) / det;
                if (u < 0 || u > 1) continue;
                double q[3] = {s[1] * e1[2] - s[2] * e1[1], s[2] * e1[0] - s[0] * e1[2],
                               s[0] * e1[1] - s[1] * e1[0]};
                double vv = (d[0] * q[0] + d[1] * q[1] + d[2] * q[2]) / det;
                if (vv < 0 || u + vv > 1) continue;
                double t = (e2[0] * q[0] + e2[1] * q[1] + e2[2] * q[2]) / det;
                if (t < 0) continue; /* before the near plane: clipped */
                double *dst = &r->t[(size_t)j * r->w + i];
                if (t < *dst) *dst = t;
            }
    }
}

bool occ_ref_box_visible(const occ_ref *r, const double mn[3], const double mx[3])
{
    double lo[3], hi[3], c[8][3];
    for (int a = 0; a < 3; a++) {
        lo[a] = mn[a] - r->origin[a];
        hi[a] = mx[a] - r->origin[a];
    }
    for (int k = 0; k < 8; k++)
        for (int a = 0; a < 3; a++) c[k][a] = (k >> a) & 1 ? hi[a] : lo[a];
    int x0, y0, x1, y1;
    if (!pixel_range(r, (const double(*)[3])c, 8, true, &x0, &y0, &x1, &y1)) return false;
    for (int j = y0; j <= y1; j++)
        for (int i = x0; i <= x1; i++) {
            const double *o = r->ray + 6 * ((size_t)j * r->w + i), *d = o + 3;
            double tin = 0, tout = INFINITY; /* t >= 0: at or beyond the near plane */
            bool miss = false;
            for (int a = 0; a < 3 && !miss; a++) {
                if (d[a] == 0) {
                    if (o[a] < lo[a] || o[a] > hi[a]) miss = true;
                    continue;
                }
                double t0 = (lo[a] - o[a]) / d[a], t1 = (hi[a] - o[a]) / d[a];
                if (t0 > t1) {
                    double t = t0;
                    t0 = t1;
                    t1 = t;
                }
                tin = fmax(tin, t0);
                tout = fmin(tout, t1);
                if (tin > tout) miss = true;
            }
            if (!miss && tin < r->t[(size_t)j * r->w + i]) return true;
        }
    return false;
}
