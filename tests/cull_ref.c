/*
 * cull_ref.c — see cull_ref.h. Deliberately naive: every corner projected,
 * every plane tested, no early outs.
 */
#include "cull_ref.h"

#include <math.h>
#include <string.h>

void ref_view_make(ref_view *v, const cull_view_desc *d)
{
    memset(v, 0, sizeof *v);
    for (int i = 0; i < 16; i++) v->m[i] = d->view_proj[i];
    for (int a = 0; a < 3; a++) v->origin[a] = d->origin[a];
    v->vw = d->viewport_w ? d->viewport_w : 1920;
    v->vh = d->viewport_h ? d->viewport_h : 1080;
    /* clip-space half-spaces c . (x, y, z, w) >= 0 */
    long double zn = d->depth_mode == CULL_DEPTH_GL ? 1 : 0;
    const long double cp[6][4] = {
        {1, 0, 0, 1}, {-1, 0, 0, 1}, {0, 1, 0, 1}, {0, -1, 0, 1}, {0, 0, 1, zn}, {0, 0, -1, 1},
    };
    for (int p = 0; p < 6; p++) {
        long double q[4];
        for (int col = 0; col < 4; col++) { /* (M^T c)[col] = sum_row M[row][col] c[row] */
            q[col] = 0;
            for (int row = 0; row < 4; row++) q[col] += v->m[col * 4 + row] * cp[p][row];
        }
        long double len = sqrtl(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]);
        /* the sum of the |normals| of the clip rows this plane combines */
        long double scale = 0;
        for (int row = 0; row < 4; row++) {
            if (cp[p][row] == 0) continue;
            long double rx = v->m[row], ry = v->m[4 + row], rz = v->m[8 + row];
            scale += sqrtl(rx * rx + ry * ry + rz * rz);
        }
        if (len <= 1e-12L * scale) {
            v->always[p] = true;
            continue;
        }
        for (int k = 0; k < 4; k++) v->plane[p][k] = q[k] / len;
    }
}

void ref_test(const ref_view *v, const cull_entity_desc *e, ref_verdict *o)
{
    long double c[3], lo[3], hi[3];
    for (int a = 0; a < 3; a++) {
        c[a] = (long double)e->center[a] - v->origin[a];
        lo[a] = (long double)e->aabb_min[a] - v->origin[a];
        hi[a] = (long double)e->aabb_max[a] - v->origin[a];
    }
    long double r = e->radius;
    o->sphere_margin = o->inner_margin = o->aabb_margin = INFINITY;
    for (int p = 0; p < 6; p++) {
        if (v->always[p]) continue;
        const long double *pl = v->plane[p];
        long double s = pl[0] * c[0] + pl[1] * c[1] + pl[2] * c[2] + pl[3];
        o->sphere_margin = fminl(o->sphere_margin, s + r);
        o->inner_margin = fminl(o->inner_margin, s - r);
        long double best = -INFINITY;
        for (int k = 0; k < 8; k++) {
            long double x = (k & 1) ? hi[0] : lo[0], y = (k & 2) ? hi[1] : lo[1];
            long double z = (k & 4) ? hi[2] : lo[2];
            best = fmaxl(best, pl[0] * x + pl[1] * y + pl[2] * z + pl[3]);
        }
        o->aabb_margin = fminl(o->aabb_margin, best);
    }
    o->visible = o->sphere_margin >= 0 && o->aabb_margin >= 0;

    long double x0 = INFINITY, x1 = -INFINITY, y0 = INFINITY, y1 = -INFINITY;
    o->behind = false;
    for (int k = 0; k < 8; k++) {
        long double p[3] = {(k & 1) ? hi[0] : lo[0], (k & 2) ? hi[1] : lo[1], (k & 4) ? hi[2] : lo[2]};
        long double cl[4];
        for (int row = 0; row < 4; row++)
            cl[row] = v->m[row] * p[0] + v->m[4 + row] * p[1] + v->m[8 + row] * p[2] + v->m[12 + row];
        if (cl[3] <= 0) {
            o->behind = true;
            continue;
        }
        long double nx = cl[0] / cl[3], ny = cl[1] / cl[3];
        x0 = fminl(x0, nx);
        x1 = fmaxl(x1, nx);
        y0 = fminl(y0, ny);
        y1 = fmaxl(y1, ny);
    }
    if (o->behind) {
        o->area = v->vw * v->vh;
        return;
    }
    long double px0 = fminl(fmaxl((x0 + 1) * 0.5L * v->vw, 0), v->vw);
    long double px1 = fminl(fmaxl((x1 + 1) * 0.5L * v->vw, 0), v->vw);
    long double py0 = fminl(fmaxl((y0 + 1) * 0.5L * v->vh, 0), v->vh);
    long double py1 = fminl(fmaxl((y1 + 1) * 0.5L * v->vh, 0), v->vh);
    o->area = (px1 - px0) * (py1 - py0);
}
