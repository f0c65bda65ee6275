/*
 * cull_view.c — views: frustum planes from a view-projection matrix
 * (Gribb & Hartmann), for perspective and orthographic cameras, OpenGL
 * [-1,1] and [0,1] depth and reversed-Z, infinite far planes included; and
 * the matrix helpers a client needs to build such a view camera-relative.
 *
 * All in double. A view is prepared once per query (a few hundred flops).
 */
#include "cull_internal.h"

#include <math.h>
#include <string.h>

static double det4(const double m[16])
{
    /* Laplace expansion over 2x2 minors (column-major, rows/cols alike) */
    double s0 = m[0] * m[5] - m[4] * m[1], s1 = m[0] * m[9] - m[8] * m[1];
    double s2 = m[0] * m[13] - m[12] * m[1], s3 = m[4] * m[9] - m[8] * m[5];
    double s4 = m[4] * m[13] - m[12] * m[5], s5 = m[8] * m[13] - m[12] * m[9];
    double c5 = m[10] * m[15] - m[14] * m[11], c4 = m[6] * m[15] - m[14] * m[7];
    double c3 = m[6] * m[11] - m[10] * m[7], c2 = m[2] * m[15] - m[14] * m[3];
    double c1 = m[2] * m[11] - m[10] * m[3], c0 = m[2] * m[7] - m[6] * m[3];
    return s0 * c5 - s1 * c4 + s2 * c3 + s3 * c2 - s4 * c1 + s5 * c0;
}

/* The one validation of a view: the daemon runs it on every request that
 * carries one (VIS_QUERY, RENDER, LIGHT_QUERY, FRAME_SUBSCRIBE, before any
 * ACK), and the renderers and light binning take only views it made. */
int cull_view_init(cull_view *v, const cull_view_desc *d)
{
    if (!v || !d) return CULL_ERR_INVALID;
    double scale = 0;
    for (int i = 0; i < 16; i++) {
        if (!isfinite(d->view_proj[i])) return CULL_ERR_MATRIX;
        scale = fmax(scale, fabs(d->view_proj[i]));
    }
    for (int a = 0; a < 3; a++)
        if (!isfinite(d->origin[a])) return CULL_ERR_NONFINITE;
    if (d->depth_mode > CULL_DEPTH_REVERSED) return CULL_ERR_INVALID;
    uint32_t vw = d->viewport_w, vh = d->viewport_h;
    if (vw == 0 && vh == 0) {
        vw = 1920;
        vh = 1080;
    }
    if (vw == 0 || vh == 0 || vw > 65535 || vh > 65535) return CULL_ERR_VIEWPORT;
    if (scale == 0) return CULL_ERR_MATRIX;
    /* singularity test invariant to per-row scale (an orthographic camera
       1e13 m wide has rows of 1e-13 and 1): det with each row normalised */
    double ms[16];
    for (int r = 0; r < 4; r++) {
        double rs = 0;
        for (int c = 0; c < 4; c++) rs = fmax(rs, fabs(d->view_proj[c * 4 + r]));
        if (rs == 0) return CULL_ERR_MATRIX;
        for (int c = 0; c < 4; c++) ms[c * 4 + r] = d->view_proj[c * 4 + r] / rs;
    }
    if (!(fabs(det4(ms)) > 1e-12)) return CULL_ERR_MATRIX;

    const double *m = d->view_proj;
    double row[4][4];
    for (int r = 0; r < 4; r++)
        for (int c = 0; c < 4; c++) row[r][c] = m[c * 4 + r];
    double p[6][4];
    double ps[6]; /* size of the normals that were added: cancellation test */
    const int other[6] = {0, 0, 1, 1, 2, 2};
    for (int c = 0; c < 4; c++) {
        p[0][c] = row[3][c] + row[0][c]; /* left   */
        p[1][c] = row[3][c] - row[0][c]; /* right  */
        p[2][c] = row[3][c] + row[1][c]; /* bottom */
        p[3][c] = row[3][c] - row[1][c]; /* top    */
        p[4][c] = d->depth_mode == CULL_DEPTH_GL ? row[3][c] + row[2][c] : row[2][c];
        p[5][c] = row[3][c] - row[2][c];
    }
    for (int i = 0; i < 6; i++) {
        const double *a = row[3], *b = row[other[i]];
        ps[i] = sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]) +
                sqrt(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]);
    }
    memset(v, 0, sizeof *v);
    uint32_t n = 0;
    for (int i = 0; i < 6; i++) {
        double len = sqrt(p[i][0] * p[i][0] + p[i][1] * p[i][1] + p[i][2] * p[i][2]);
        if (len <= 1e-12 * ps[i]) {
            /* a plane at infinity (infinite far, reversed-Z): always
               satisfied if d > 0, an empty frustum otherwise */
            if (p[i][3] > 0) continue;
            return CULL_ERR_MATRIX;
        }
        for (int c = 0; c < 4; c++) v->plane[n][c] = p[i][c] / len;
        n++;
    }
    if (n < 5) return CULL_ERR_MATRIX;
    v->plane_count = n;
    memcpy(v->clip, m, sizeof v->clip);
    memcpy(v->origin, d->origin, sizeof v->origin);
    v->depth_mode = d->depth_mode;
    v->viewport_w = vw;
    v->viewport_h = vh;
    /* an orthographic view with w <= 0 everywhere shows nothing and no
       renderer or light binning can use it: refused here, where every
       request's view is checked, not later by a renderer */
    cull_view_rows r;
    cull_view_rows_get(v, &r);
    if (!r.usable) return CULL_ERR_MATRIX;
    return CULL_OK;
}

void cull_view_rows_get(const cull_view *v, cull_view_rows *r)
{
    double *rows[4] = {r->x, r->y, r->z, r->w};
    for (int i = 0; i < 4; i++)
        for (int c = 0; c < 4; c++) rows[i][c] = v->clip[c * 4 + i];
    double wl = fabs(r->w[0]) + fabs(r->w[1]) + fabs(r->w[2]);
    r->ortho = !(wl > 1e-12 * fabs(r->w[3]));
    for (int c = 0; c < 4; c++) {
        switch (v->depth_mode) {
        case CULL_DEPTH_GL: r->nearfn[c] = r->w[c] + r->z[c]; break;
        case CULL_DEPTH_ZERO_ONE: r->nearfn[c] = r->z[c]; break;
        default: r->nearfn[c] = r->w[c] - r->z[c]; break;
        }
        if (!r->ortho) r->d[c] = c == 3 ? 1.0 : 0.0;
        else r->d[c] = v->depth_mode == CULL_DEPTH_REVERSED ? r->z[c] : r->w[c] - r->z[c];
    }
    r->usable = !r->ortho || r->w[3] > 0;
}
