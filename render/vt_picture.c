/*
 * vt_picture.c — see vt_picture.h.
 */
#include "vt_picture.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* The unit box, for instances of classes without a mesh of their own. */
static const float box_pos[24] = {-1, -1, -1, 1, -1, -1, -1, 1, -1, 1, 1, -1, -1, -1, 1, 1, -1, 1, -1, 1, 1, 1, 1, 1};
static const uint32_t box_idx[36] = {0, 4, 6, 0, 6, 2, 1, 3, 7, 1, 7, 5, 0, 1, 5, 0, 5, 4,
                                     2, 6, 7, 2, 7, 3, 0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6};
const vt_mesh vt_mesh_box = {.pos = box_pos, .idx = box_idx, .nv = 8, .ni = 36};

int vt_mesh_check(const vt_mesh *m, char *err, size_t errlen)
{
    if (!m || !m->pos || !m->idx || !m->nv || !m->ni || m->ni % 3)
        return vp_errf(err, errlen, VT_ERR_INVALID, "mesh: needs vertices and a multiple of 3 indices");
    for (uint32_t i = 0; i < m->ni; i++)
        if (m->idx[i] >= m->nv)
            return vp_errf(err, errlen, VT_ERR_INVALID, "mesh: index %u is %u, past %u vertices", i, m->idx[i], m->nv);
    for (uint32_t i = 0; i < 3 * m->nv; i++)
        if (!isfinite(m->pos[i]) || (m->nrm && !isfinite(m->nrm[i])))
            return vp_errf(err, errlen, VT_ERR_INVALID, "mesh: vertex %u is not finite", i / 3);
    return 0;
}

/* A destruction volume as the renderers read it: fields and spheres
 * there, 2..CULL_DVOL_MAX_RES samples an axis, finite steps and corner. */
static bool dvol_ok(const cull_dvol *dv)
{
    if (!dv->d || !dv->sph) return false;
    for (int a = 0; a < 3; a++)
        if (dv->n[a] < 2 || dv->n[a] > CULL_DVOL_MAX_RES || !(dv->step[a] > 0) || !isfinite(dv->step[a]) ||
            !isfinite(dv->origin[a]))
            return false;
    return true;
}

/* An instance's placement: finite bounds in order, or a transform as the
 * protocol's vp_trs_check accepts it (the daemon renormalised it). */
static int place_check(const vt_instance *in, uint32_t i, char *err, size_t errlen)
{
    if (in->place == VT_PLACE_BOUNDS) {
        for (int a = 0; a < 3; a++)
            if (!isfinite(in->bmin[a]) || !isfinite(in->bmax[a]) || in->bmin[a] > in->bmax[a])
                return vp_errf(err, errlen, VT_ERR_INVALID, "instance %u: bad bounds", i);
        return 0;
    }
    if (in->place != VT_PLACE_TRS) return vp_errf(err, errlen, VT_ERR_INVALID, "instance %u: placement %u", i, in->place);
    double q2 = 0;
    int zeros = 0;
    for (int a = 0; a < 3; a++) {
        if (!(fabs(in->pos[a]) <= 1e15))
            return vp_errf(err, errlen, VT_ERR_INVALID, "instance %u: position %d not finite or beyond 1e15", i, a);
        if (!(fabsf(in->scale[a]) <= 1e6f))
            return vp_errf(err, errlen, VT_ERR_INVALID, "instance %u: scale %d not finite or beyond 1e6", i, a);
        zeros += in->scale[a] == 0;
    }
    for (int a = 0; a < 4; a++) {
        if (!isfinite(in->rot[a])) return vp_errf(err, errlen, VT_ERR_INVALID, "instance %u: rotation not finite", i);
        q2 += (double)in->rot[a] * in->rot[a];
    }
    if (!(fabs(sqrt(q2) - 1) <= 1e-3))
        return vp_errf(err, errlen, VT_ERR_INVALID, "instance %u: rotation of length %g, not a unit quaternion", i,
                       sqrt(q2));
    if (zeros > 1) return vp_errf(err, errlen, VT_ERR_INVALID, "instance %u: scale 0 on %d axes", i, zeros);
    return 0;
}

static int mesh_attr_check(const vt_mesh *m, char *err, size_t errlen)
{
    for (uint32_t k = 0; m->uv && k < 2 * m->nv; k++)
        if (!(fabsf(m->uv[k]) <= 1e6f))
            return vp_errf(err, errlen, VT_ERR_INVALID, "mesh: UV of vertex %u not finite or beyond 1e6", k / 2);
    for (uint32_t k = 0; m->tan && k < 4 * m->nv; k++)
        if (!isfinite(m->tan[k]))
            return vp_errf(err, errlen, VT_ERR_INVALID, "mesh: tangent of vertex %u not finite", k / 4);
    return 0;
}

/* Instances (the frame's, or its shadow casters: what names them in a
 * message). */
static int insts_check(const vt_instance *inst, uint32_t n, uint32_t nmesh, const char *what, char *err,
                       size_t errlen)
{
    const vt_material *last = NULL; /* instances share few materials: each checked once in a run */
    for (uint32_t i = 0; i < n; i++) {
        const vt_instance *in = &inst[i];
        if (in->mesh >= nmesh) return vp_errf(err, errlen, VT_ERR_INVALID, "%sinstance %u: no mesh %u", what, i, in->mesh);
        char why[160];
        int rc = place_check(in, i, why, sizeof why);
        if (rc) return vp_errf(err, errlen, rc, "%s%s", what, why);
        if (vt_dvol_live(in->dvol) && !dvol_ok(in->dvol))
            return vp_errf(err, errlen, VT_ERR_INVALID, "%sinstance %u: bad destruction volume", what, i);
        for (int a = 0; a < 3; a++)
            if (!(fabsf(in->albedo[a]) <= 1e6f))
                return vp_errf(err, errlen, VT_ERR_INVALID, "%sinstance %u: albedo not finite", what, i);
        if (in->mat && in->mat != last) {
            if (vt_material_check(in->mat, why, sizeof why))
                return vp_errf(err, errlen, VT_ERR_INVALID, "%sinstance %u: material: %s", what, i, why);
            last = in->mat;
        }
    }
    return 0;
}

int vt_frame_check(const vt_frame *f, char *err, size_t errlen)
{
    if (!f || !f->view || !f->rgba || !f->depth || (f->ninst && (!f->inst || !f->meshes)) || (f->nl && !f->lights) ||
        (f->ncasters && f->casters && !f->meshes) ||
        (f->nmesh && !f->meshes))
        return vp_errf(err, errlen, VT_ERR_INVALID, "missing argument");
    if (f->width < 1 || f->height < 1 || f->width > 16384 || f->height > 16384 || f->stride < f->width)
        return vp_errf(err, errlen, VT_ERR_INVALID, "size %ux%u (stride %zu) outside 1..16384", f->width, f->height,
                       f->stride);
    for (uint32_t i = 0; i < f->nmesh; i++) {
        char why[160];
        if (vt_mesh_check(&f->meshes[i], why, sizeof why) || mesh_attr_check(&f->meshes[i], why, sizeof why))
            return vp_errf(err, errlen, VT_ERR_INVALID, "%u: %s", i, why);
    }
    int rc = insts_check(f->inst, f->ninst, f->nmesh, "", err, errlen);
    if (!rc && f->casters && f->ncasters) rc = insts_check(f->casters, f->ncasters, f->nmesh, "caster: ", err, errlen);
    if (rc) return rc;
    for (uint32_t i = 0; i < f->nl; i++) {
        /* the daemon's LIGHT_PUT runs the same validation: a light it
           acknowledged is never refused here */
        const vt_light *L = &f->lights[i];
        const double rad[3] = {L->color[0], L->color[1], L->color[2]};
        char why[120];
        if (cull_light_validate(&L->l, rad, why, sizeof why) != CULL_OK)
            return vp_errf(err, errlen, VT_ERR_INVALID, "light %u: %s", i, why);
        if (!isfinite(L->cos_inner))
            return vp_errf(err, errlen, VT_ERR_INVALID, "light %u: inner cosine not finite", i);
    }
    rc = vt_overlay_check(f, err, errlen);
    return rc ? rc : vt_env_check(f->env, err, errlen);
}

int vt_picture_check(const vt_frame *f, cull_view_rows *vr, char *err, size_t errlen)
{
    int rc = vt_frame_check(f, err, errlen);
    if (rc) return rc;
    cull_view_rows_get(f->view, vr);
    if (!vr->usable) return vp_errf(err, errlen, VT_ERR_INVALID, "orthographic view with w <= 0");
    return 0;
}

void vt_light_prepare(const vt_light *L, const double origin[3], vt_slight *q, cull_light *cl)
{
    *cl = L->l;
    for (int a = 0; a < 3; a++) {
        q->p[a] = (float)(L->l.pos[a] - origin[a]);
        q->color[a] = L->color[a];
        q->dir[a] = L->l.dir[a];
    }
    q->range2 = (float)(L->l.radius * L->l.radius);
    q->inv_range2 = 1.0f / q->range2;
    q->spot = L->l.type == CULL_LIGHT_SPOT;
    q->cos_outer = L->l.cos_outer;
    /* a cone edge under 1e-4 wide is a hard edge: 1 / (inner - outer) of
       a denormal difference would be infinite, and 0 x inf NaN */
    q->cos_inner = L->cos_inner > L->l.cos_outer + 1e-4f ? L->cos_inner : L->l.cos_outer + 1e-4f;
    q->inv_cone = 1.0f / (q->cos_inner - q->cos_outer);
}

void vt_mesh_bounds(const vt_mesh *m, float b[6])
{
    for (int a = 0; a < 3; a++) b[a] = FLT_MAX, b[3 + a] = -FLT_MAX;
    for (uint32_t k = 0; k < m->nv; k++)
        for (int a = 0; a < 3; a++) {
            b[a] = fminf(b[a], m->pos[3 * k + a]);
            b[3 + a] = fmaxf(b[3 + a], m->pos[3 * k + a]);
        }
}

void vt_instance_xform(const vt_instance *in, const float b[6], const double origin[3], double scale[3],
                       double shift[3])
{
    for (int a = 0; a < 3; a++) {
        double ext = (double)b[3 + a] - b[a];
        scale[a] = ext > 0 ? (in->bmax[a] - in->bmin[a]) / ext : 0;
        shift[a] = ext > 0 ? in->bmin[a] - origin[a] - b[a] * scale[a] : 0.5 * (in->bmin[a] + in->bmax[a]) - origin[a];
    }
}

void vt_instance_place(const vt_instance *in, const float b[6], const double origin[3], vt_place *pl)
{
    double s[3];
    if (in->place != VT_PLACE_TRS) {
        vt_instance_xform(in, b, origin, s, pl->t);
        for (int a = 0; a < 3; a++) pl->q[a] = 0;
        pl->q[3] = 1;
    } else {
        for (int a = 0; a < 3; a++) {
            s[a] = in->scale[a];
            pl->t[a] = in->pos[a] - origin[a];
        }
        double q2 = 0;
        for (int a = 0; a < 4; a++) q2 += (double)in->rot[a] * in->rot[a];
        double iq = 1 / sqrt(q2); /* checked: within 1e-3 of 1 */
        for (int a = 0; a < 4; a++) pl->q[a] = in->rot[a] * iq;
    }
    /* R from the unit quaternion (x, y, z, w) */
    double x = pl->q[0], y = pl->q[1], z = pl->q[2], w = pl->q[3];
    double R[3][3] = {{1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)},
                      {2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)},
                      {2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)}};
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++) {
            pl->m[r][c] = R[r][c] * s[c];
            /* normals: the inverse transpose, R diag(1 / s); a flat axis
               (scale 0) keeps its normal component */
            pl->n[r][c] = R[r][c] * (s[c] != 0 ? 1 / s[c] : 1);
        }
    for (int a = 0; a < 3; a++) pl->s[a] = s[a];
    pl->mirror = (s[0] < 0) ^ (s[1] < 0) ^ (s[2] < 0);
}

void vt_tile_ranges(const float *near, size_t xs, size_t ys, uint32_t width, uint32_t height, float (*range)[2])
{
    uint32_t tx = (width + VT_TILE - 1) / VT_TILE, ty = (height + VT_TILE - 1) / VT_TILE;
    for (size_t t = 0; t < (size_t)tx * ty; t++) {
        range[t][0] = -FLT_MAX;
        range[t][1] = FLT_MAX;
    }
    for (uint32_t y = 0; y < height; y++) {
        const float *row = near + (size_t)y * ys;
        float(*rr)[2] = range + (size_t)(y / VT_TILE) * tx;
        for (uint32_t x = 0; x < width; x++) {
            float z = row[(size_t)x * xs];
            if (z == VT_EMPTY) continue;
            float(*q)[2] = &rr[x / VT_TILE];
            if (z > (*q)[0]) (*q)[0] = z;
            if (z < (*q)[1]) (*q)[1] = z;
        }
    }
}

/* ---- destruction masks (vt_mask.h) ---- */

/* The volume's largest step: the scale of its detail. */
static double mask_scale(const cull_dvol *v)
{
    double s = v->step[0];
    s = v->step[1] > s ? v->step[1] : s;
    return v->step[2] > s ? v->step[2] : s;
}

double vt_mask_amp(const cull_dvol *v)
{
    return 0.25 * mask_scale(v);
}

double vt_mask_margin(const cull_dvol *v)
{
    return cull_dvol_bound(v) + vt_mask_amp(v);
}

void vt_mask_make(const cull_dvol *v, const double origin[3], vt_mask *m)
{
    double s = mask_scale(v), cell = 0.5 * s, band = 0.25 * s;
    for (int a = 0; a < 3; a++) {
        m->o[a] = (float)(v->origin[a] - origin[a]);
        m->is[a] = (float)(1.0 / v->step[a]);
        m->hi[a] = (float)(v->n[a] - 1);
        m->cs[a] = (float)(v->step[a] / cell);
    }
    m->amp = (float)vt_mask_amp(v);
    m->ib = (float)(1.0 / band);
    m->reach = (float)(vt_mask_amp(v) + band);
    m->n0 = v->n[0];
    m->n01 = v->n[0] * v->n[1];
    m->d = v->d;
    m->sph = (const double(*)[4])v->sph;
    m->nsph = v->nsph;
    memcpy(m->cam, origin, sizeof m->cam);
    /* the field is within the bound of the exact distance: a point this
       much farther than every sphere has mask >= band (a millimetre and a
       hundredth of a step of slack; vt_mask_clear adds the rounding of
       positions far from the camera) */
    m->clear = cull_dvol_bound(v) + vt_mask_amp(v) + band + 0.01 * s + 1e-3;
}

bool vt_mask_clear(const vt_mask *m, const float (*p)[3])
{
    if (m->nsph > VT_MASK_CLEAR_MAX) return false; /* not worth it: every pixel tests */
    float lo[3], hi[3];
    for (int a = 0; a < 3; a++) {
        lo[a] = hi[a] = p[0][a];
        for (int k = 1; k < 3; k++) {
            lo[a] = p[k][a] < lo[a] ? p[k][a] : lo[a];
            hi[a] = p[k][a] > hi[a] ? p[k][a] : hi[a];
        }
    }
    for (uint32_t k = 0; k < m->nsph; k++) {
        /* the sphere's centre (camera-relative) to the triangle's box */
        double d2 = 0, c2 = 0;
        for (int a = 0; a < 3; a++) {
            double c = m->sph[k][a] - m->cam[a], e = c < lo[a] ? lo[a] - c : c > hi[a] ? c - hi[a] : 0;
            d2 += e * e;
            c2 += c * c;
        }
        /* plus the float rounding of positions that far from the camera */
        double need = m->sph[k][3] + m->clear + 1e-6 * (sqrt(c2) + m->sph[k][3]);
        if (!(d2 >= need * need)) return false;
    }
    return true;
}

bool vt_masks_make(const vt_instance *in, uint32_t n, const double origin[3], vt_mask **mk, size_t *mk_cap,
                   uint32_t **mk_of, size_t *of_cap, uint32_t *count)
{
    uint32_t nmk = 0;
    *count = 0;
    for (uint32_t i = 0; i < n; i++) nmk += vt_dvol_live(in[i].dvol);
    if (!nmk) return true;
    if (!vp_grow((void **)mk, mk_cap, nmk, sizeof **mk) || !vp_grow((void **)mk_of, of_cap, n, sizeof **mk_of))
        return false;
    nmk = 0;
    for (uint32_t i = 0; i < n; i++) {
        (*mk_of)[i] = 0;
        if (!vt_dvol_live(in[i].dvol)) continue;
        vt_mask_make(in[i].dvol, origin, &(*mk)[nmk]);
        (*mk_of)[i] = ++nmk;
    }
    *count = nmk;
    return true;
}
