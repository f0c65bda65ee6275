/*
 * vt_soft.c — the software renderer (see vt_soft.h). A visibility buffer:
 *
 *   1. set-up (one thread): each instance's vertices to clip space (double,
 *      camera-relative), back faces culled (a damaged instance's kept,
 *      turned over, after its front faces; its triangles clear of every
 *      hole marked plain: vt_mask_clear), triangles clipped in clip space
 *      against the near and far planes and a guard band (x, y within 4 w),
 *      projected and snapped to 1/256 pixel; one raster record per clipped
 *      triangle, one shading record per source triangle;
 *   2. raster (threads over interleaved 16-row tile rows): integer edge
 *      functions with the top-left rule at pixel centres, nearness (1/w
 *      perspective, 1 - z_ndc orthographic: affine in screen space) as the
 *      depth test, the winning shading record per pixel (a masked
 *      triangle's pixel only where the destruction mask is >= 0);
 *   3. light tiles: per 16x16 tile the nearness range of what it shows,
 *      then cull_lights_bin;
 *   4. shading (threads over tile rows): per pixel, perspective-correct
 *      barycentrics from the homogeneous edge functions of the source
 *      triangle give the surface point and normal (and a masked one's
 *      rim char); glTF's metallic-roughness BRDF (vt_brdf.h) over the
 *      tile's lights and the sun, plus the ambient (image-based, vt_brdf.h).
 *
 * Shading once per pixel, whatever the overdraw, is the point of the
 * visibility buffer.
 */
#include "vt_brdf.h"
#include "vt_picture.h"
#include "vt_post.h"
#include "vt_raster.h"
#include "vt_shade.h"
#include "vt_ssao.h"
#include "vt_texlin.h"

#include <float.h>
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define SUB 256.0          /* sub-pixel steps */
#define GUARD 4.0          /* guard band: |x|, |y| <= GUARD w */
#define TILE VT_TILE
#define EMPTY VT_EMPTY
_Static_assert(VT_SPAN == TILE, "a shading span is one light tile's row");
#define MAX_THREADS 32u
#define ID_BITS VT_ID_BITS

/* A clipped, projected triangle for the rasteriser. */
typedef struct rtri {
    int32_t x[3], y[3];     /* fixed point, 1/256 pixel, y up */
    double  na, nb, nc;     /* nearness = na px + nb py + nc over pixel coordinates */
    float   zmax;           /* no pixel it covers gets a nearness above this (+inf: unknown) */
    int32_t bx0, by0, bx1, by1; /* pixel bounds */
    uint32_t shade;         /* shading record */
    uint32_t masked;        /* its instance is damaged: each pixel tests the mask */
} rtri;

typedef vt_stri stri;

typedef struct cv {
    double c[4];            /* clip x, y, z, w */
    double d;               /* nearness numerator */
} cv;

typedef struct xv {
    double p[3];            /* camera-relative */
    cv v;
    unsigned out;           /* bit p: outside clip plane p */
    float n[3];             /* its normal under the instance's scale (unit) */
    bool has_n;             /* false: no normal, or it collapsed: the face's */
    bool attr;              /* p, n, has_n and tg are made (only for the vertices
                               of triangles that get a shading record) */
    float tg[4];            /* its tangent under the placement (unit), handedness */
} xv;

/* What one set-up thread produces, for its range of instances, in order. */
typedef struct tbuf {
    rtri *rt;
    size_t nrt, rt_cap;
    stri *st;
    size_t nst, st_cap;
    xv *vx;                 /* one instance's transformed vertices */
    size_t vx_cap;
    int rc;
    char err[128];
} tbuf;

typedef vt_slight slight;

struct vt_soft {
    cull_pool *pool;
    uint32_t threads;
    float *near;            /* nearness per pixel */
    size_t near_cap;
    uint32_t *id;           /* shading record + 1 per pixel, 0 = nothing */
    size_t id_cap;
    float (*mb)[6];         /* each mesh's bounds, this frame */
    size_t mb_cap;
    struct tbuf *tb;        /* per set-up thread: its triangles */
    float (*range)[2];
    size_t range_cap;
    cull_light_tiles tiles;
    cull_light *cl;
    size_t cl_cap;
    slight *sl;             /* the lights as shading reads them */
    size_t sl_cap;
    vt_mask *mk;            /* this frame's damaged instances' masks */
    size_t mk_cap;
    uint32_t *mk_of;        /* per instance: mask + 1 */
    size_t mk_of_cap;
    vt_kern k;              /* the kernels for this CPU */
    vt_rkern rk;            /* the raster's row kernels for this CPU */
    double *xtab;           /* each column's NDC x (vt_ndc_row) */
    size_t xtab_cap;
    float *hz;              /* per 16 x 16 tile: <= its pixels' least nearness (the coarse depth) */
    size_t hz_cap;
    uint8_t *hz_old;        /* per tile: drawn into since hz was last made */
    size_t hz_old_cap;
    bool coarse;            /* the coarse depth test is on (vt_soft_coarse_depth) */
    vt_skytab sky;          /* the analytic sky's table */
    vt_texcache tc;         /* decoded copies of the sRGB textures (vt_texlin.h) */
    vt_post post;           /* exposure and FXAA's scratch (vt_post.h) */
    vt_shadow *shadow;      /* the sun's cascades (made at the first frame with shadows) */
    vt_ibl ibl;             /* the image-based ambient, kept while the sky is the same */
    vt_ssao *ssao;          /* the ambient occlusion's buffers (vt_ssao.h) */
    vt_hist *hist;          /* per shading thread: the exposure's histogram of what it shaded */
    size_t hist_cap;
};

static uint64_t now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000000ull + (uint64_t)ts.tv_nsec;
}


int vt_soft_create(cull_pool *pool, uint32_t threads, vt_soft **out)
{
    if (!out) return VT_ERR_INVALID;
    vt_soft *r = calloc(1, sizeof *r);
    if (!r) return VT_ERR_NOMEM;
    r->pool = pool;
    r->k = vt_kern_pick();
    r->rk = vt_rkern_pick();
    r->coarse = true;
    uint32_t pt = cull_pool_threads(pool);
    r->threads = threads && threads < pt ? threads : pt;
    if (r->threads > MAX_THREADS) r->threads = MAX_THREADS;
    *out = r;
    return 0;
}

void vt_soft_coarse_depth(vt_soft *r, bool on)
{
    if (r) r->coarse = on;
}

void vt_soft_destroy(vt_soft *r)
{
    if (!r) return;
    vt_post_free(&r->post);
    vt_texcache_free(&r->tc);
    free(r->near);
    free(r->id);
    free(r->xtab);
    free(r->hz);
    free(r->hz_old);
    free(r->mb);
    for (uint32_t t = 0; r->tb && t < MAX_THREADS; t++) {
        free(r->tb[t].rt);
        free(r->tb[t].st);
        free(r->tb[t].vx);
    }
    free(r->tb);
    free(r->range);
    free(r->cl);
    free(r->sl);
    free(r->mk);
    free(r->mk_of);
    vt_shadow_destroy(r->shadow);
    cull_light_tiles_free(&r->tiles);
    vt_ssao_destroy(r->ssao);
    free(r->hist);
    free(r);
}

/* ---- set-up --------------------------------------------------------------------- */


typedef struct frame {
    const cull_view *v;
    cull_view_rows vr;
    uint32_t w, h;
    vt_penv pe;             /* the environment, prepared */
    vt_ground gr;           /* its ground plane in screen space */
    const vt_mask *mk;      /* the damaged instances' masks */
    const uint32_t *mk_of;  /* per instance: its mask + 1, 0 intact; NULL: none damaged */
} frame;

static double dot4(const double f[4], const double c[4])
{
    return f[0] * c[0] + f[1] * c[1] + f[2] * c[2] + f[3] * c[3];
}

/* lrint (nearest, ties to even) for |v| < 2^31, without the call: adding
 * and taking away 1.5 2^52 leaves v rounded to an integer in the
 * default rounding mode. */
static inline int32_t round_even(double v)
{
    const double big = 0x1.8p52; /* IEEE arithmetic: not folded away (no -ffast-math) */
    return (int32_t)((v + big) - big);
}

/* floor(v / SUB) for v within the guard band's fixed point (integer). */
static inline int32_t floor_sub(int32_t v)
{
    return (v >= 0 ? v : v - ((int32_t)SUB - 1)) / (int32_t)SUB;
}

/* The clip planes a vertex is outside of, as bits (clip_planes' order):
 * their functions without their zero terms. */
static unsigned outcode(const cv *v, uint32_t depth_mode)
{
    const double x = v->c[0], y = v->c[1], z = v->c[2], w = v->c[3], g = GUARD * w;
    double nf, ff; /* near, far */
    switch (depth_mode) {
    case CULL_DEPTH_GL: nf = z + w, ff = -z + w; break;
    case CULL_DEPTH_ZERO_ONE: nf = z, ff = -z + w; break;
    default: nf = -z + w, ff = z; break;
    }
    return (unsigned)(nf < 0) | (unsigned)(ff < 0) << 1 | (unsigned)(x + g < 0) << 2 | (unsigned)(-x + g < 0) << 3 |
           (unsigned)(y + g < 0) << 4 | (unsigned)(-y + g < 0) << 5;
}

/* The clip planes a triangle is cut by, as functions of clip (x, y, z, w). */
static void clip_planes(const frame *fr, double pl[6][4])
{
    /* near and far in clip space: the culling core's depth conventions */
    switch (fr->v->depth_mode) {
    case CULL_DEPTH_GL:
        memcpy(pl[0], (double[4]){0, 0, 1, 1}, sizeof pl[0]);
        memcpy(pl[1], (double[4]){0, 0, -1, 1}, sizeof pl[1]);
        break;
    case CULL_DEPTH_ZERO_ONE:
        memcpy(pl[0], (double[4]){0, 0, 1, 0}, sizeof pl[0]);
        memcpy(pl[1], (double[4]){0, 0, -1, 1}, sizeof pl[1]);
        break;
    default: /* reversed: near at z = w, far at z = 0 */
        memcpy(pl[0], (double[4]){0, 0, -1, 1}, sizeof pl[0]);
        memcpy(pl[1], (double[4]){0, 0, 1, 0}, sizeof pl[1]);
        break;
    }
    memcpy(pl[2], (double[4]){1, 0, 0, GUARD}, sizeof pl[2]);
    memcpy(pl[3], (double[4]){-1, 0, 0, GUARD}, sizeof pl[3]);
    memcpy(pl[4], (double[4]){0, 1, 0, GUARD}, sizeof pl[4]);
    memcpy(pl[5], (double[4]){0, -1, 0, GUARD}, sizeof pl[5]);
}

/* Sutherland-Hodgman against the six planes; returns the vertex count. */
static int clip_poly(cv *in, int n, double pl[6][4])
{
    cv tmp[12];
    cv *src = in, *dst = tmp;
    for (int p = 0; p < 6 && n; p++) {
        int m = 0;
        for (int i = 0; i < n; i++) {
            const cv *a = &src[i], *b = &src[(i + 1) % n];
            double fa = dot4(pl[p], a->c), fb = dot4(pl[p], b->c);
            if (fa >= 0) dst[m++] = *a;
            if ((fa >= 0) != (fb >= 0)) {
                double t = fa / (fa - fb);
                cv *o = &dst[m++];
                for (int k = 0; k < 4; k++) o->c[k] = a->c[k] + t * (b->c[k] - a->c[k]);
                o->d = a->d + t * (b->d - a->d);
            }
        }
        n = m;
        cv *x = src;
        src = dst;
        dst = x;
    }
    if (src != in) memcpy(in, src, (size_t)n * sizeof *in);
    return n;
}

/* The first adjugate row of the clip-space vertices (a, b): the barycentric
 * of the third vertex, up to the determinant. */
static void adj_row(const cv *a, const cv *b, double r[3])
{
    r[0] = a->c[1] * b->c[3] - a->c[3] * b->c[1];
    r[1] = a->c[3] * b->c[0] - a->c[0] * b->c[3];
    r[2] = a->c[0] * b->c[1] - a->c[1] * b->c[0];
}

/* m v, normalised into o (0 when it collapses); false if it did. */
static bool xform_unit(const double m[3][3], const float *v, float o[3])
{
    double t[3], l = 0;
    for (int a = 0; a < 3; a++) {
        t[a] = m[a][0] * v[0] + m[a][1] * v[1] + m[a][2] * v[2];
        l += t[a] * t[a];
    }
    l = sqrt(l);
    for (int a = 0; a < 3; a++) o[a] = l > 0 ? (float)(t[a] / l) : 0;
    return l > 0;
}

/* An upper bound of the nearness the raster computes at any pixel centre
 * a triangle of a w x h view covers (for the coarse depth test): its
 * plane (as computed: affine) is highest at a vertex (x, y: unsnapped), a
 * covered centre lies within the snapped triangle (vertices moved by <=
 * 1/512 pixel on each axis: the plane by <= (|na| + |nb|) / 512 more),
 * and the raster's evaluation of the plane at a pixel rounds by far less
 * than 1e-9 of its terms' magnitude; rounded up to a float. +inf where
 * anything is not finite: such a triangle is never rejected. */
static float near_bound(const rtri *rt, const double x[3], const double y[3], uint32_t w, uint32_t h)
{
    double zm = -INFINITY;
    for (int k = 0; k < 3; k++) {
        double z = rt->na * x[k] + rt->nb * y[k] + rt->nc;
        zm = z > zm ? z : zm;
    }
    double an = fabs(rt->na), bn = fabs(rt->nb);
    double mag = an * (w + 1.0) + bn * (h + 1.0) + fabs(rt->nc) + fabs(zm);
    double b = zm + (an + bn) / (SUB / 2) + 1e-9 * mag;
    if (!(b < FLT_MAX)) return INFINITY; /* NaN too */
    float f = (float)b;
    if (!((double)f < b)) return f;
    /* the next float up (f is finite: b < FLT_MAX): one step of its bits
       away from zero when positive, towards zero when negative */
    if (f == 0) return FLT_MIN; /* a bound: above the smallest subnormal, fine */
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    u = f > 0 ? u + 1 : u - 1;
    memcpy(&f, &u, sizeof f);
    return f;
}

static int setup(tbuf *r, uint32_t tid, const frame *fr, const vt_mesh *meshes, const float (*mb)[6],
                 const vt_instance *inst, uint32_t i0, uint32_t i1, char *err, size_t errlen)
{
    r->nrt = r->nst = 0;
    double cpl[6][4];
    clip_planes(fr, cpl);
    const cull_view_rows *vr = &fr->vr;
    const double *o = fr->v->origin;
    for (uint32_t ii = i0; ii < i1; ii++) {
        const vt_instance *in = &inst[ii];
        const vt_mesh *m = &meshes[in->mesh];
        const vt_mask *mk = fr->mk_of && fr->mk_of[ii] ? &fr->mk[fr->mk_of[ii] - 1] : NULL;
        /* the placement: the mesh's bounds onto the instance's box, or
           its transform; camera-relative, in double */
        vt_place pl;
        vt_instance_place(in, mb[in->mesh], o, &pl);
        const vt_material *mat = in->mat;
        const bool two_sided = mat && mat->double_sided;
        const bool alpha_test = mat && mat->alpha_mode == VT_ALPHA_MASK && mat->tex[VT_SLOT_BASE].tex && m->uv;
        /* a MASK material whose alpha is a constant below its cutoff:
           nothing of it is drawn */
        if (mat && mat->alpha_mode == VT_ALPHA_MASK && !alpha_test && mat->base[3] < mat->alpha_cutoff) continue;
        /* every vertex once: its clip coordinates, by the view's rows and
           the placement composed once an instance (the camera-relative
           position only for the vertices of drawn triangles, below) */
        if (!vp_grow((void **)&r->vx, &r->vx_cap, m->nv, sizeof *r->vx))
            return vp_errf(err, errlen, VT_ERR_NOMEM, "out of memory for %u vertices", m->nv);
        double cm[5][4];
        const double *vrow[5] = {vr->x, vr->y, vr->z, vr->w, vr->d};
        for (int q = 0; q < 5; q++) {
            const double *f = vrow[q];
            for (int c = 0; c < 3; c++) cm[q][c] = f[0] * pl.m[0][c] + f[1] * pl.m[1][c] + f[2] * pl.m[2][c];
            cm[q][3] = f[0] * pl.t[0] + f[1] * pl.t[1] + f[2] * pl.t[2] + f[3];
        }
        for (uint32_t k = 0; k < m->nv; k++) {
            xv *x = &r->vx[k];
            const double p0 = m->pos[3 * k], p1 = m->pos[3 * k + 1], p2 = m->pos[3 * k + 2];
            for (int q = 0; q < 4; q++) x->v.c[q] = cm[q][0] * p0 + cm[q][1] * p1 + cm[q][2] * p2 + cm[q][3];
            x->v.d = cm[4][0] * p0 + cm[4][1] * p1 + cm[4][2] * p2 + cm[4][3];
            x->out = outcode(&x->v, fr->v->depth_mode);
            x->attr = false;
        }
        /* a damaged instance: its front faces first, then its back faces,
           so most of the inside fails the depth test before any mask is
           evaluated (pass 1 takes only back faces) */
        const uint32_t ntri = m->ni / 3;
        for (uint32_t step = 0; step < (mk ? 2 * ntri : ntri); step++) {
            const uint32_t pass = step >= ntri, t = pass ? step - ntri : step;
            const xv *xs[3];
            unsigned out_and = ~0u, out_or = 0;
            for (int k = 0; k < 3; k++) {
                /* a mirrored placement turns the winding over: read the
                   triangle backwards so its front stays its front */
                const xv *x = xs[k] = &r->vx[m->idx[3 * t + (pl.mirror && k ? 3 - k : k)]];
                out_and &= x->out;
                out_or |= x->out;
            }
            /* all outside one clip plane: nothing to draw */
            if (out_and) continue;
            /* back faces: the sign of the homogeneous determinant (its first
               adjugate row is the shading record's too) */
            double rows[3][3];
            adj_row(&xs[1]->v, &xs[2]->v, rows[0]);
            double det = rows[0][0] * xs[0]->v.c[0] + rows[0][1] * xs[0]->v.c[1] + rows[0][2] * xs[0]->v.c[3];
            bool back = false;
            if (!(det > 0)) {
                /* a damaged instance is two-sided: its inside shows
                   through its holes, drawn as the face turned over */
                if (!(det < 0) || (!mk && !two_sided) || (mk && pass == 0)) continue;
                const xv *tx = xs[1];
                xs[1] = xs[2];
                xs[2] = tx;
                adj_row(&xs[1]->v, &xs[2]->v, rows[0]);
                det = -det;
                back = true;
            } else if (pass == 1) {
                continue;
            }
            /* all inside every plane: nothing to clip */
            cv v[12]; /* not initialised: clip_poly writes what it reads */
            v[0] = xs[0]->v, v[1] = xs[1]->v, v[2] = xs[2]->v;
            const double *p[3] = {xs[0]->p, xs[1]->p, xs[2]->p};
            const cv *src = v;
            cv srcc[3];
            if (out_or) { /* clipping rewrites v: the source triangle kept apart */
                memcpy(srcc, v, sizeof srcc);
                src = srcc;
            }
            int n = out_or ? clip_poly(v, 3, cpl) : 3;
            if (n < 3) continue;
            if (r->nst + 2 >= (1u << ID_BITS)) /* record + 1 stays below VT_ID_GROUND */
                return vp_errf(err, errlen, VT_ERR_RANGE, "more than 2^27 triangles a thread");
            if (!vp_grow((void **)&r->st, &r->st_cap, r->nst + 1, sizeof *r->st) ||
                !vp_grow((void **)&r->rt, &r->rt_cap, r->nrt + (size_t)n - 2, sizeof *r->rt))
                return vp_errf(err, errlen, VT_ERR_NOMEM, "out of memory for %zu triangles", r->nrt);
            /* the shading record: adjugate rows of the source triangle,
               scaled by 1/det (homogeneous barycentrics: the kernel divides
               by their sum) */
            stri *s = &r->st[r->nst];
            /* the corners' normals under a scale (by the inverse scale) and
               tangents with the placement, once a vertex (most vertices of
               a mesh belong to faces culled above) */
            for (int k = 0; k < 3; k++) {
                xv *x = &r->vx[xs[k] - r->vx];
                if (x->attr) continue;
                uint32_t vi = (uint32_t)(xs[k] - r->vx);
                const float *mp = m->pos + 3 * (size_t)vi;
                for (int a = 0; a < 3; a++)
                    x->p[a] = pl.m[a][0] * mp[0] + pl.m[a][1] * mp[1] + pl.m[a][2] * mp[2] + pl.t[a];
                x->has_n = m->nrm && xform_unit(pl.n, m->nrm + 3 * (size_t)vi, x->n);
                if (m->tan && mat) {
                    xform_unit(pl.m, m->tan + 4 * (size_t)vi, x->tg);
                    x->tg[3] = (m->tan[4 * (size_t)vi + 3] < 0) != pl.mirror ? -1.0f : 1.0f;
                }
                x->attr = true;
            }
            adj_row(&src[2], &src[0], rows[1]);
            adj_row(&src[0], &src[1], rows[2]);
            const double idet = 1 / det;
            for (int i = 0; i < 3; i++)
                for (int k = 0; k < 3; k++) s->e[i][k] = (float)(rows[i][k] * idet);
            /* the face normal, only where a corner has none of its own
               (turned over with the face: inwards for a back face) */
            float fn[3] = {0, 0, 0};
            if (!xs[0]->has_n || !xs[1]->has_n || !xs[2]->has_n) {
                double u[3], w2[3];
                for (int k = 0; k < 3; k++) {
                    u[k] = p[1][k] - p[0][k];
                    w2[k] = p[2][k] - p[0][k];
                }
                double nn[3] = {u[1] * w2[2] - u[2] * w2[1], u[2] * w2[0] - u[0] * w2[2], u[0] * w2[1] - u[1] * w2[0]};
                double l = sqrt(nn[0] * nn[0] + nn[1] * nn[1] + nn[2] * nn[2]);
                for (int k = 0; k < 3; k++) fn[k] = l > 0 ? (float)(nn[k] / l) : 0;
            }
            for (int k = 0; k < 3; k++) {
                for (int q = 0; q < 3; q++) {
                    s->p[k][q] = (float)p[k][q];
                    s->n[k][q] = !xs[k]->has_n ? fn[q] : back ? -xs[k]->n[q] : xs[k]->n[q];
                }
            }
            for (int q = 0; q < 3; q++) s->albedo[q] = back && mk && !fr->pe.on ? in->albedo[q] * VT_MASK_INTERIOR : in->albedo[q];
            s->mat = mat;
            s->has_uv = m->uv != NULL;
            s->has_tg = m->tan != NULL && mat;
            s->alpha_test = alpha_test;
            for (int k = 0; k < 3; k++) {
                uint32_t vi = (uint32_t)(xs[k] - r->vx);
                if (m->uv) memcpy(s->uv[k], m->uv + 2 * (size_t)vi, sizeof s->uv[k]);
                if (s->has_tg) memcpy(s->tg[k], xs[k]->tg, sizeof s->tg[k]);
            }
            /* a triangle the holes do not come near is drawn plain (the
               mask is >= its band all over it: nothing discarded, no rim) */
            s->mask = mk && !vt_mask_clear(mk, (const float(*)[3])s->p) ? mk : NULL;
            /* the clipped polygon, projected and snapped, as a fan */
            /* In exact arithmetic a clipped vertex lies in the guard band,
               so |px|, |py| <= (GUARD + 1) / 2 * 16384 pixels and the fixed
               point below (and the edge functions' products) fit their
               integers. Clipping a huge coordinate (a 1e30 term in the
               view) cancels catastrophically, and the rounding can put the
               vertex anywhere, as far as overflowing int32 (undefined
               behaviour): the vertex is clamped back to the band (where
               it belongs, to within that rounding), and a NaN or infinite
               one (w rounded to 0) drops the polygon. Two compares per
               coordinate. */
            double px[12], py[12], pn[12];
            int32_t ix[12], iy[12];
            const double gx0 = (1 - GUARD) * 0.5 * fr->w, gx1 = (1 + GUARD) * 0.5 * fr->w;
            const double gy0 = (1 - GUARD) * 0.5 * fr->h, gy1 = (1 + GUARD) * 0.5 * fr->h;
            bool bad = false;
            for (int k = 0; k < n; k++) {
                double iw = 1.0 / v[k].c[3];
                px[k] = (v[k].c[0] * iw + 1) * 0.5 * fr->w;
                py[k] = (v[k].c[1] * iw + 1) * 0.5 * fr->h;
                pn[k] = v[k].d * iw;
                if (px[k] != px[k] || py[k] != py[k] || pn[k] - pn[k] != 0) bad = true;
                px[k] = px[k] < gx0 ? gx0 : px[k] > gx1 ? gx1 : px[k];
                py[k] = py[k] < gy0 ? gy0 : py[k] > gy1 ? gy1 : py[k];
                ix[k] = bad ? 0 : round_even(px[k] * SUB);
                iy[k] = bad ? 0 : round_even(py[k] * SUB);
            }
            if (bad) continue; /* its shading record is not kept either */
            for (int k = 1; k + 1 < n; k++) {
                rtri *rt = &r->rt[r->nrt];
                int id[3] = {0, k, k + 1};
                for (int q = 0; q < 3; q++) {
                    rt->x[q] = ix[id[q]];
                    rt->y[q] = iy[id[q]];
                }
                int64_t area = (int64_t)(rt->x[1] - rt->x[0]) * (rt->y[2] - rt->y[0]) -
                       (int64_t)(rt->y[1] - rt->y[0]) * (rt->x[2] - rt->x[0]);
                if (area <= 0) continue; /* snapped to nothing, or turned over */
                /* nearness plane through the three projected vertices */
                double ux = px[id[1]] - px[id[0]], uy = py[id[1]] - py[id[0]], un = pn[id[1]] - pn[id[0]];
                double vx = px[id[2]] - px[id[0]], vy = py[id[2]] - py[id[0]], vn = pn[id[2]] - pn[id[0]];
                double den = ux * vy - uy * vx;
                if (den == 0) continue;
                rt->na = (un * vy - uy * vn) / den;
                rt->nb = (ux * vn - un * vx) / den;
                rt->nc = pn[id[0]] - rt->na * px[id[0]] - rt->nb * py[id[0]];
                rt->zmax = near_bound(rt, (double[3]){px[id[0]], px[id[1]], px[id[2]]},
                                      (double[3]){py[id[0]], py[id[1]], py[id[2]]}, fr->w, fr->h);
                int32_t xmin = rt->x[0], xmax = rt->x[0], ymin = rt->y[0], ymax = rt->y[0];
                for (int q = 1; q < 3; q++) {
                    xmin = rt->x[q] < xmin ? rt->x[q] : xmin;
                    xmax = rt->x[q] > xmax ? rt->x[q] : xmax;
                    ymin = rt->y[q] < ymin ? rt->y[q] : ymin;
                    ymax = rt->y[q] > ymax ? rt->y[q] : ymax;
                }
                /* pixels whose centre (i + 0.5) can be inside */
                const int32_t half = (int32_t)SUB / 2;
                rt->bx0 = floor_sub(xmin - half);
                rt->bx1 = -floor_sub(half - xmax);
                rt->by0 = floor_sub(ymin - half);
                rt->by1 = -floor_sub(half - ymax);
                if (rt->bx0 < 0) rt->bx0 = 0;
                if (rt->by0 < 0) rt->by0 = 0;
                if (rt->bx1 > (int32_t)fr->w - 1) rt->bx1 = (int32_t)fr->w - 1;
                if (rt->by1 > (int32_t)fr->h - 1) rt->by1 = (int32_t)fr->h - 1;
                if (rt->bx0 > rt->bx1 || rt->by0 > rt->by1) continue;
                rt->shade = tid << ID_BITS | (uint32_t)r->nst;
                rt->masked = s->mask != NULL || s->alpha_test;
                r->nrt++;
            }
            r->nst++;
        }
    }
    return 0;
}

/* ---- raster ------------------------------------------------------------------------ */

typedef struct job {
    vt_soft *r;
    const frame *fr;
    const vt_mesh *meshes;
    const float (*mb)[6];   /* each mesh's bounds */
    const vt_instance *inst;
    uint32_t ninst;
    float *rgba, *depth;
    size_t stride;
    uint32_t nthreads;
    bool ranges;            /* the tile nearness ranges are wanted (there are lights) */
    const vt_shadow *sh;    /* the sun's cascades, or NULL */
    const float *ao;        /* per pixel ambient occlusion (vt_ssao), or NULL: none */
    uint32_t next_row;      /* shading: the next half row of tiles to take (threads take them as
                               they finish: sky rows cost a fraction of a street's) */
    vt_hist *hist;          /* per shading thread (its slot t): the exposure's histogram, or NULL */
    uint32_t skips[MAX_THREADS]; /* per raster thread: the parts the coarse depth test skipped */
    uint32_t split[MAX_THREADS + 1]; /* set-up thread t takes instances [split[t], split[t + 1]) */
    const int *cancel;      /* vt_frame.cancel */
} job;

/* The caller no longer wants the picture (vt_frame.cancel set) */
static inline bool stop_asked(const int *cancel)
{
    return cancel && __atomic_load_n(cancel, __ATOMIC_RELAXED);
}

/* vt_soft_draw's answer then: it stops between passes (and the shading
   between rows) */
static int stopped(char *err, size_t errlen)
{
    return vp_errf(err, errlen, VT_ERR_CANCELLED, "the picture was cancelled");
}

/* Splits the instances into nt contiguous shares of about the same work
 * (a mesh's vertices and indices, twice the indices for a damaged one: a
 * city's instances differ by tens of times). */
static void split_setup(job *jb, const frame *fr)
{
    uint64_t total = 0;
    for (uint32_t i = 0; i < jb->ninst; i++) {
        const vt_mesh *m = &jb->meshes[jb->inst[i].mesh];
        total += 16 + m->nv + (uint64_t)m->ni * (fr->mk_of && fr->mk_of[i] ? 2 : 1);
    }
    uint64_t acc = 0;
    uint32_t t = 1;
    jb->split[0] = 0;
    for (uint32_t i = 0; i < jb->ninst && t < jb->nthreads; i++) {
        const vt_mesh *m = &jb->meshes[jb->inst[i].mesh];
        acc += 16 + m->nv + (uint64_t)m->ni * (fr->mk_of && fr->mk_of[i] ? 2 : 1);
        while (t < jb->nthreads && acc * jb->nthreads >= total * t) jb->split[t++] = i + 1;
    }
    while (t <= jb->nthreads) jb->split[t++] = jb->ninst;
}

/* Top-left rule, y up, counter-clockwise: an edge going down (dy < 0) is a
 * left edge, a horizontal one going left (dx < 0) a top edge; a pixel
 * centre exactly on one of those is inside, on any other edge outside. */
static inline int64_t edge_bias(int32_t x0, int32_t y0, int32_t x1, int32_t y1)
{
    int32_t dy = y1 - y0, dx = x1 - x0;
    return (dy < 0 || (dy == 0 && dx < 0)) ? 0 : -1;
}

/* The NDC y of row y (the shading spans' too). */
static inline float ndc_y(const frame *fr, uint32_t y)
{
    return (float)((2.0 * y + 1) / fr->h - 1);
}

/* Columns [i0, i1] of row j of a damaged instance's triangle or of a MASK
 * material's: a pixel nearer than what is there is kept only where the
 * destruction mask is >= 0 at its surface point (interpolated as the
 * shading gather does) and the base alpha reaches the cutoff. */
static void raster_masked(vt_soft *r, const frame *fr, const rtri *rt, int j, int i0, int i1, float *nrow,
                          uint32_t *irow, double nz)
{
    uint32_t id = rt->shade + 1;
    const vt_stri *t = &r->tb[rt->shade >> ID_BITS].st[rt->shade & VT_ID_MASK];
    float Y = ndc_y(fr, (uint32_t)j);
    double inv_w = 2.0 / fr->w;
    for (int i = i0; i <= i1; i++) {
        float z = (float)(rt->na * (i + 0.5) + nz);
        if (!(z > nrow[i])) continue;
        float b[3];
        vt_stri_bary(t, vt_ndc_x((uint32_t)i, inv_w), Y, b);
        if (t->mask) {
            float px = b[0] * t->p[0][0] + b[1] * t->p[1][0] + b[2] * t->p[2][0];
            float py = b[0] * t->p[0][1] + b[1] * t->p[1][1] + b[2] * t->p[2][1];
            float pz = b[0] * t->p[0][2] + b[1] * t->p[1][2] + b[2] * t->p[2][2];
            if (vt_mask_eval(t->mask, px, py, pz) < 0) continue;
        }
        if (t->alpha_test && !vt_stri_alpha_pass(t, vt_ndc_x((uint32_t)i, inv_w), Y, (float)inv_w, (float)(2.0 / fr->h)))
            continue;
        nrow[i] = z;
        irow[i] = id;
    }
}

/* Rows [y0, y1] of one triangle. */
static void raster_tri(vt_soft *r, const frame *fr, const rtri *rt, int y0, int y1)
{
    int by0 = rt->by0 > y0 ? rt->by0 : y0, by1 = rt->by1 < y1 ? rt->by1 : y1;
    if (by0 > by1) return;
    /* The covered run of each row, solved exactly from the three edge
       functions (integer, linear in the column d from bx0 and in the row):
       column bx0 + d is inside iff e_k + d s_k >= 0 for every edge k, s_k
       = 256 A_k: d >= ceil(-e_k / s_k) = -floor(e_k / s_k) for s_k > 0, d
       <= floor(e_k / -s_k) for s_k < 0, e_k >= 0 for s_k = 0. Each
       quotient floor(e_k / |s_k|) is stepped from row to row with its
       remainder (e_k grows by 256 B_k a row): two divisions an edge a
       call instead of one an edge a row. */
    vt_edge E[3];
    const int64_t px = (int64_t)rt->bx0 * 256 + 128, py = (int64_t)by0 * 256 + 128;
    for (int k = 0; k < 3; k++) {
        int a = k, b = k == 2 ? 0 : k + 1;
        /* E(p) = (x_b - x_a)(p_y - y_a) - (y_b - y_a)(p_x - x_a), > 0 inside */
        int64_t A = -(int64_t)(rt->y[b] - rt->y[a]), B = (int64_t)(rt->x[b] - rt->x[a]);
        int64_t e = A * (px - rt->x[a]) + B * (py - rt->y[a]) + edge_bias(rt->x[a], rt->y[a], rt->x[b], rt->y[b]);
        vt_edge *d = &E[k];
        d->sg = A > 0 ? 1 : A < 0 ? -1 : 0;
        if (!d->sg) { /* a horizontal edge: e itself, stepped; no remainder */
            *d = (vt_edge){.f = e, .qs = B * 256, .D = INT64_MAX};
            continue;
        }
        d->D = (A < 0 ? -A : A) * 256;
        d->f = vt_floor_div(e, d->D);
        d->r = e - d->f * d->D;
        d->qs = vt_floor_div(B * 256, d->D);
        d->rs = B * 256 - d->qs * d->D;
    }
    const int64_t nx = rt->bx1 - rt->bx0 + 1;
    for (int j = by0; j <= by1; j++) {
        int64_t lo = 0, hi = nx - 1;
        vt_edge_row(&E[0], &lo, &hi);
        vt_edge_row(&E[1], &lo, &hi);
        vt_edge_row(&E[2], &lo, &hi);
        if (lo > hi) continue;
        float *nrow = r->near + (size_t)j * fr->w;
        uint32_t *irow = r->id + (size_t)j * fr->w;
        double nz = rt->nb * (j + 0.5) + rt->nc;
        if (rt->masked) {
            raster_masked(r, fr, rt, j, rt->bx0 + (int)lo, rt->bx0 + (int)hi, nrow, irow, nz);
            continue;
        }
        r->rk.span(nrow, irow, rt->bx0 + (int32_t)lo, rt->bx0 + (int32_t)hi, fr->w, rt->na, nz, rt->shade + 1);
    }
}

/* The coarse depth test: whether nothing of a triangle whose nearness
 * stays <= zmax can show in tiles c0..c1 of tile row tr (every pixel
 * there is at least as near already). A tile's bound hz is remade from
 * its pixels only when it fails and something was drawn into the tile
 * since: a 16 x 16 minimum, far cheaper than the rows it spares. */
/* A raster thread's coarse test: remaking a tile's bound costs about a
 * sixth of the rows a skip spares, so it runs while it pays: credit
 * starts at 64, a remake spends 1, a skip it brings earns 8; out of
 * credit, every 32nd failed test still remakes (to notice when the
 * triangles start coming near to far). */
typedef struct coarse {
    int32_t credit;
    uint32_t probe;
    uint32_t skips;         /* the parts skipped */
} coarse;

static bool hidden(vt_soft *r, const frame *fr, uint32_t tr, uint32_t c0, uint32_t c1, float zmax, coarse *cs)
{
    const uint32_t tx = (fr->w + TILE - 1) / TILE;
    for (uint32_t c = c0; c <= c1; c++) {
        size_t ti = (size_t)tr * tx + c;
        if (zmax < r->hz[ti]) continue;
        if (!r->hz_old[ti] || (cs->credit <= 0 && (++cs->probe & 31))) return false;
        uint32_t x0 = c * TILE, y0 = tr * TILE;
        uint32_t cols = fr->w - x0 < TILE ? fr->w - x0 : TILE, rows = fr->h - y0 < TILE ? fr->h - y0 : TILE;
        r->hz[ti] = r->rk.tmin(r->near + (size_t)y0 * fr->w + x0, fr->w, cols, rows);
        r->hz_old[ti] = 0;
        cs->credit--;
        if (!(zmax < r->hz[ti])) return false;
    }
    cs->credit = cs->credit + 8 < 256 ? cs->credit + 8 : 256;
    cs->skips++;
    return true;
}

/* Set-up, thread t: a contiguous share of the instances (split), so the
 * triangles of threads 0, 1, ... in turn are in instance order. */
static void job_setup(void *arg, uint32_t t)
{
    job *jb = arg;
    tbuf *b = &jb->r->tb[t];
    b->rc = setup(b, t, jb->fr, jb->meshes, jb->mb, jb->inst, jb->split[t], jb->split[t + 1], b->err, sizeof b->err);
}

/* Thread t owns the 16-row tile rows tr with tr % nthreads == t: it clears
 * them, then walks the triangles once, in order (so ties resolve the same
 * way whatever the thread count), drawing the parts in its rows. */
static void job_raster(void *arg, uint32_t t)
{
    job *jb = arg;
    const frame *fr = jb->fr;
    vt_soft *r = jb->r;
    uint32_t trows = (fr->h + TILE - 1) / TILE, nt = jb->nthreads;
    const uint32_t tx = (fr->w + TILE - 1) / TILE;
    for (uint32_t tr = t; tr < trows; tr += nt) {
        uint32_t y1 = (tr + 1) * TILE < fr->h ? (tr + 1) * TILE : fr->h;
        r->rk.clear(r->near + (size_t)tr * TILE * fr->w, r->id + (size_t)tr * TILE * fr->w,
                    (size_t)(y1 - tr * TILE) * fr->w);
        for (uint32_t c = 0; c < tx; c++) r->hz[tr * tx + c] = EMPTY;
        memset(r->hz_old + (size_t)tr * tx, 0, tx);
    }
    coarse cs = {64, 0, 0};
    for (uint32_t b = 0; b < jb->nthreads; b++)
        for (size_t k = 0; k < r->tb[b].nrt; k++) {
            const rtri *rt = &r->tb[b].rt[k];
            uint32_t t0 = (uint32_t)rt->by0 / TILE, t1 = (uint32_t)rt->by1 / TILE;
            uint32_t c0 = (uint32_t)rt->bx0 / TILE, c1 = (uint32_t)rt->bx1 / TILE;
            /* the first tile row of this thread at or after t0 */
            uint32_t tr = t0 + (t + nt - t0 % nt) % nt;
            for (; tr <= t1; tr += nt) {
                if (r->coarse && hidden(r, fr, tr, c0, c1, rt->zmax, &cs)) continue;
                raster_tri(r, fr, rt, (int)(tr * TILE), (int)((tr + 1) * TILE) - 1);
                memset(r->hz_old + (size_t)tr * tx + c0, 1, c1 - c0 + 1);
            }
        }
    jb->skips[t] = cs.skips;
    /* the ground plane, depth-tested against the triangles: its nearness
       plane per pixel (vt_ground_at, double), over the columns of each
       row where it can hit, only the depth test where it surely does */
    if (fr->gr.on)
        for (uint32_t tr = t; tr < trows; tr += nt) {
            uint32_t y1 = (tr + 1) * TILE < fr->h ? (tr + 1) * TILE : fr->h;
            for (uint32_t y = tr * TILE; y < y1; y++) {
                double Y = ndc_y(fr, y);
                int32_t c[4];
                if (!vt_ground_row(&fr->gr, Y, fr->w, c)) continue;
                float *nrow = r->near + (size_t)y * fr->w;
                uint32_t *irow = r->id + (size_t)y * fr->w;
                if (c[0] < c[1]) r->rk.ground(nrow, irow, c[0], c[1] - 1, r->xtab, &fr->gr, Y, false);
                if (c[1] <= c[2]) r->rk.ground(nrow, irow, c[1], c[2], r->xtab, &fr->gr, Y, true);
                if (c[2] < c[3]) r->rk.ground(nrow, irow, c[2] + 1, c[3], r->xtab, &fr->gr, Y, false);
            }
        }
    /* the light tiles' nearness ranges of this thread's rows, while they
       are in its cache */
    if (!jb->ranges) return;
    for (uint32_t tr = t; tr < trows; tr += nt) {
        uint32_t y1 = (tr + 1) * TILE < fr->h ? (tr + 1) * TILE : fr->h;
        r->k.ranges(r->near + (size_t)tr * TILE * fr->w, fr->w, fr->w, y1 - tr * TILE, r->range + (size_t)tr * tx);
    }
}

/* ---- shading ------------------------------------------------------------------------ */

/* The threads shade half rows of tiles as they take them (next_row), one
 * span (a row of one tile: one light list) at a time. */
static void job_shade(void *arg, uint32_t t)
{
    job *jb = arg;
    const vt_soft *r = jb->r;
    const frame *fr = jb->fr;
    const cull_light_tiles *lt = &r->tiles;
    const stri *st[MAX_THREADS];
    for (uint32_t b = 0; b < jb->nthreads; b++) st[b] = r->tb[b].st;
    vt_span sp = {.st = st, .sl = r->sl, .inv_w = 2.0 / fr->w, .rule = vt_depth_rule_of(fr->v, &fr->vr),
                  .pe = &fr->pe, .vr = &fr->vr, .gr = &fr->gr, .inv_h = 2.0 / fr->h, .sh = jb->sh, .tc = &r->tc};
    uint32_t trows = (fr->h + TILE - 1) / TILE, tx = (fr->w + TILE - 1) / TILE;
    if (jb->hist) vt_hist_begin(&r->post, &jb->hist[t]);
    /* half a row of tiles at a time (8 pixel rows): the thread that
       finishes first waits half as long for the other's last piece */
    for (uint32_t u; (u = __atomic_fetch_add(&jb->next_row, 1, __ATOMIC_RELAXED)) < 2 * trows;) {
        if (stop_asked(jb->cancel)) break; /* vt_soft_draw says so after the pass */
        const uint32_t tr = u / 2, ya = tr * TILE + (u & 1) * (TILE / 2);
        uint32_t y1 = ya + TILE / 2 < fr->h ? ya + TILE / 2 : fr->h;
        for (uint32_t y = ya; y < y1; y++) {
            sp.Y = ndc_y(fr, y);
            if (fr->pe.on) vt_view_dir_row(&fr->vr, sp.Y, sp.ray0, sp.ray1); /* the sky's, once a row */
            int quarter = -1; /* the exposure's metered run of the 4 spans from c & ~3 */
            _Static_assert(TILE == VT_HIST_RUN, "a span is one of the exposure's metered runs");
            for (uint32_t c = 0; c < tx; c++) {
                uint32_t tile = tr * tx + c;
                sp.li = lt->index ? lt->index + lt->offset[tile] : NULL;
                sp.nli = lt->offset[tile + 1] - lt->offset[tile];
                sp.x0 = c * TILE;
                sp.n = fr->w - sp.x0 < TILE ? fr->w - sp.x0 : TILE;
                sp.id = r->id + (size_t)y * fr->w + sp.x0;
                sp.near = r->near + (size_t)y * fr->w + sp.x0;
                sp.ao = jb->ao ? jb->ao + (size_t)y * fr->w + sp.x0 : NULL;
                sp.rgba = jb->rgba + ((size_t)y * jb->stride + sp.x0) * 4;
                sp.depth = jb->depth + (size_t)y * jb->stride + sp.x0;
                r->k.shade(&sp);
                /* the exposure's metering of the span while it is in
                   the cache (the post passes' own pass would read the
                   picture from memory again) */
                if (jb->hist) {
                    if (c % 4 == 0) quarter = vt_hist_quarter(fr->w, fr->h, sp.x0, y);
                    if (quarter < 0 || (int)(c % 4) == quarter)
                        vt_hist_add(&jb->hist[t], sp.rgba, sp.n, quarter < 0 ? 1 : 4);
                }
            }
        }
    }
}

/* The frame's work between the raster and the shading that does not
 * read the ambient occlusion (vt_soft_draw runs it beside the GTAO pass):
 * the lights as shading reads them and their tiles (from the nearness
 * range of what each tile shows: the ranges came with the raster), the
 * sun's cascades fitted to the view, the sRGB textures' decoded copies
 * and the image-based light's roughness entries. */
typedef struct side_job {
    vt_soft *r;
    const vt_frame *f;
    const frame *fr;
    const float (*mb)[6];
    int lrc;           /* cull_lights_bin's */
    bool shadows;      /* the sun casts: fit is made */
    vt_shadow_fit fit;
    uint64_t ns;       /* its time */
} side_job;

static void frame_side(void *arg)
{
    side_job *j = arg;
    uint64_t t0 = now_ns();
    vt_soft *r = j->r;
    const vt_frame *f = j->f;
    const cull_view *v = f->view;
    for (uint32_t i = 0; i < f->nl; i++) vt_light_prepare(&f->lights[i], v->origin, &r->sl[i], &r->cl[i]);
    j->lrc = cull_lights_bin(v, f->width, f->height, r->cl, f->nl, f->nl ? (const float(*)[2])r->range : NULL,
                             &r->tiles);
    float sdir[3];
    j->shadows = vt_shadow_sun_dir(f->env, f->fx_off, sdir) &&
                 vt_shadow_fit_make(v, f->width, f->height, f->env, sdir, j->mb, f->inst, f->ninst, &j->fit);
    vt_texcache_prepare(&r->tc, f->inst, f->ninst, f->env ? f->env->ground_mat : NULL);
    if (j->fr->pe.ibl) vt_ibl_rough_frame(&r->ibl, f->inst, f->ninst, f->env->ground_mat);
    j->ns = now_ns() - t0;
}

const cull_light_tiles *vt_soft_light_tiles(const vt_soft *r)
{
    return &r->tiles;
}

/* ---- the frame ------------------------------------------------------------------------ */

int vt_soft_render(vt_soft *r, const cull_view *v, uint32_t width, uint32_t height, const vt_mesh *meshes,
                   uint32_t nmesh, const vt_instance *inst, uint32_t ninst, const vt_light *lights, uint32_t nl,
                   float *rgba, float *depth, size_t stride, vt_soft_stats *st, char *err, size_t errlen)
{
    vt_frame f = {.view = v, .width = width, .height = height, .meshes = meshes, .nmesh = nmesh, .inst = inst,
                  .ninst = ninst, .lights = lights, .nl = nl, .rgba = rgba, .depth = depth, .stride = stride};
    return vt_soft_draw(r, &f, st, err, errlen);
}

int vt_soft_draw(vt_soft *r, const vt_frame *f, vt_soft_stats *st, char *err, size_t errlen)
{
    if (st) memset(st, 0, sizeof *st);
    if (!r) return vp_errf(err, errlen, VT_ERR_INVALID, "missing argument");
    frame fr = {.v = f ? f->view : NULL, .w = f ? f->width : 0, .h = f ? f->height : 0};
    int rc = vt_picture_check(f, &fr.vr, err, errlen);
    if (rc) return rc;
    const cull_view *v = f->view;
    const uint32_t width = f->width, height = f->height, nmesh = f->nmesh, ninst = f->ninst, nl = f->nl;
    const vt_mesh *meshes = f->meshes;
    const vt_instance *inst = f->inst;
    vt_penv_make(f->env, v->origin, &r->sky, &fr.pe);
    if (fr.pe.on && !(f->fx_off & VT_FX_IBL)) { /* remade only when the sky changed */
        vt_ibl_update_pool(&r->ibl, &fr.pe, r->pool, r->threads);
        fr.pe.ibl = &r->ibl;
    }
    vt_ground_make(&fr.pe, &fr.vr, (int)v->depth_mode, &fr.gr);
    size_t npx = (size_t)width * height;
    if (!vp_grow((void **)&r->near, &r->near_cap, npx, sizeof *r->near) ||
        !vp_grow((void **)&r->id, &r->id_cap, npx, sizeof *r->id) ||
        !vp_grow((void **)&r->mb, &r->mb_cap, (size_t)nmesh + 1, sizeof *r->mb) ||
        !vp_grow((void **)&r->xtab, &r->xtab_cap, width, sizeof *r->xtab))
        return vp_errf(err, errlen, VT_ERR_NOMEM, "out of memory");
    vt_ndc_row(width, r->xtab);
    for (uint32_t i = 0; i < nmesh; i++) vt_mesh_bounds(&meshes[i], r->mb[i]);
    /* the damaged instances' masks (most frames have none: no table) */
    uint32_t nmk;
    if (!vt_masks_make(inst, ninst, v->origin, &r->mk, &r->mk_cap, &r->mk_of, &r->mk_of_cap, &nmk))
        return vp_errf(err, errlen, VT_ERR_NOMEM, "out of memory");
    if (nmk) {
        fr.mk = r->mk;
        fr.mk_of = r->mk_of;
    }

    if (!r->tb && !(r->tb = calloc(MAX_THREADS, sizeof *r->tb)))
        return vp_errf(err, errlen, VT_ERR_NOMEM, "out of memory");
    uint32_t trows = (height + TILE - 1) / TILE;
    uint32_t nt = r->threads < trows ? r->threads : trows;
    if (!nt) nt = 1;
    uint32_t tx = (width + TILE - 1) / TILE;
    if (!vp_grow((void **)&r->range, &r->range_cap, (size_t)tx * trows, sizeof *r->range) ||
        !vp_grow((void **)&r->cl, &r->cl_cap, (size_t)nl + 1, sizeof *r->cl) ||
        !vp_grow((void **)&r->sl, &r->sl_cap, (size_t)nl + 1, sizeof *r->sl) ||
        !vp_grow((void **)&r->hz, &r->hz_cap, (size_t)tx * trows, sizeof *r->hz) ||
        !vp_grow((void **)&r->hz_old, &r->hz_old_cap, (size_t)tx * trows, sizeof *r->hz_old))
        return vp_errf(err, errlen, VT_ERR_NOMEM, "out of memory");
    /* no lights: no ranges, no binning */
    job jb = {.r = r, .fr = &fr, .meshes = meshes, .mb = (const float(*)[6])r->mb, .inst = inst, .ninst = ninst,
              .rgba = f->rgba, .depth = f->depth, .stride = f->stride, .nthreads = nt, .ranges = nl > 0,
              .cancel = f->cancel};
    uint64_t t0 = now_ns();
    split_setup(&jb, &fr);
    if (nt > 1) cull_pool_run(r->pool, job_setup, &jb, nt);
    else job_setup(&jb, 0);
    size_t ntri = 0;
    for (uint32_t t = 0; t < nt; t++) {
        if (r->tb[t].rc) return vp_errf(err, errlen, r->tb[t].rc, "%s", r->tb[t].err);
        ntri += r->tb[t].nrt;
    }
    uint64_t t1 = now_ns();
    if (nt > 1) cull_pool_run(r->pool, job_raster, &jb, nt);
    else job_raster(&jb, 0);
    uint64_t t2 = now_ns();
    if (stop_asked(f->cancel)) return stopped(err, errlen);
    /* the work between the raster and the shading that does not read the
       ambient occlusion (light tiles, the cascades' fit, the textures'
       and the image-based light's per-frame tables): with the occlusion,
       one thread does it while the other starts GTAO */
    side_job sj = {.r = r, .f = f, .fr = &fr, .mb = jb.mb};
    const bool ssao = f->env && !(f->fx_off & VT_FX_SSAO);
    if (ssao) {
        vt_ssao_view sv;
        vt_ssao_view_make(&fr.vr, width, height, &sv);
        if (vt_ssao_run_side(&r->ssao, r->pool, nt, &sv, r->near, &jb.ao, frame_side, &sj))
            return vp_errf(err, errlen, VT_ERR_NOMEM, "out of memory");
    } else {
        frame_side(&sj);
    }
    uint64_t t2a = now_ns();
    if (sj.lrc != CULL_OK)
        return vp_errf(err, errlen, sj.lrc == CULL_ERR_NOMEM ? VT_ERR_NOMEM : VT_ERR_INVALID, "lights: %s",
                       cull_strerror(sj.lrc));
    if (stop_asked(f->cancel)) return stopped(err, errlen);
    /* the sun's shadow cascades, from the casters (NULL: the instances) */
    uint64_t ts = now_ns();
    uint32_t stris = 0;
    if (sj.shadows) {
        if (!r->shadow && vt_shadow_create(&r->shadow)) return vp_errf(err, errlen, VT_ERR_NOMEM, "out of memory");
        rc = vt_shadow_draw(r->shadow, r->pool, r->threads, &sj.fit, v->origin, meshes, jb.mb,
                            f->casters ? f->casters : inst, f->casters ? f->ncasters : ninst, &stris, err, errlen);
        if (rc) return rc;
        jb.sh = r->shadow;
    }
    uint64_t t3 = now_ns();
    if (stop_asked(f->cancel)) return stopped(err, errlen);

    jb.next_row = 0;
    /* an automatic exposure's histogram made by the shading threads */
    if (f->env && f->env->exposure_mode == VT_EXPOSURE_AUTO &&
        vp_grow((void **)&r->hist, &r->hist_cap, nt, sizeof *r->hist))
        jb.hist = r->hist;
    if (nt > 1) cull_pool_run(r->pool, job_shade, &jb, nt);
    else job_shade(&jb, 0);
    if (stop_asked(f->cancel)) return stopped(err, errlen);
    uint64_t t4 = now_ns();
    float ev;
    if (vt_post_apply_hist(&r->post, r->pool, r->threads, f, jb.hist, jb.hist ? nt : 0, &ev))
        return vp_errf(err, errlen, VT_ERR_NOMEM, "out of memory");
    uint64_t t5 = now_ns();
    /* last: the overlay over the finished picture (after exposure and post) */
    if ((rc = vt_overlay_draw(f, &fr.vr, err, errlen))) return rc;
    if (st) st->overlay_ns = now_ns() - t5;
    if (st) {
        st->triangles = (uint32_t)ntri;
        for (uint32_t t = 0; t < nt; t++) st->coarse_skips += jb.skips[t];
        st->lights_in_view = r->tiles.in_view;
        st->max_lights_per_tile = r->tiles.max_per_tile;
        st->threads = nt;
        st->setup_ns = t1 - t0;
        st->raster_ns = t2 - t1;
        st->ssao_ns = ssao ? t2a - t2 : 0;
        st->bin_ns = sj.ns; /* with the occlusion: beside it, inside ssao_ns */
        st->shadow_ns = jb.sh ? t3 - ts : 0;
        st->shadow_triangles = stris;
        st->shade_ns = t4 - t3;
        st->post_ns = t5 - t4;
        st->exposure_ev = ev;
    }
    return 0;
}
