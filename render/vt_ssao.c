/*
 * vt_ssao.c — the software renderer's ambient occlusion (see vt_ssao.h):
 * four passes over bands of rows, each thread taking the next band as it
 * finishes one (as vt_soft's shading takes tile rows):
 *   1. the half texels' nearness (every other pixel of every other
 *      row; VT_EMPTY where the point is not finite);
 *   2. the crease texels (vt_ssao.inl's crease kernel), counted into an
 *      integral image over blocks of 8 texels along the rows;
 *   3. GTAO per half texel (2 slices x 2 sides x 4 steps), each point
 *      made from its nearness where it is used (vt_ssao.h: a load, 9
 *      multiply-adds and a divide; the 4 planes of points this replaced
 *      cost 4 gathers a sample and 4 times the memory);
 *   4. the depth-aware tent upsample to every full pixel.
 * The skip: nearness is affine in the texels over a plane, so where no
 * crease texel (a second difference above crease_tol, or drawn next to
 * nothing) is within a step's reach (its samples and the normal's
 * neighbours), all it samples is one plane, none is above P's tangent
 * plane by the bias (a nearness that bends by less than crease_tol a
 * texel stays within a quarter of that margin over 128 texels), and its
 * AO is 1 without a sample: 4 reads of the integral image. A street
 * view's open ground and walls (about 44 % of its steps) end there.
 * Each pass' rows run in the lane kernels of vt_ssao.inl (1, 4 or 8
 * lanes, the same bits: vt_ssao_kern.h); this file owns the view, the
 * buffers, the bands and the per-frame tables.
 * Memory: 4 + 4 bytes a half texel, 4 a pixel (about 5.5 MB at
 * 1280x720), kept from frame to frame.
 */
#include "vt_picture.h"
#include "vt_ssao_kern.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* rows a band, each pass' (the threads take the next band as they
   finish one: a frame's sky rows cost nothing, its ground near the eye
   the most, and a thread the shared machine holds back leaves its bands
   to the others; 4 half rows of GTAO are about 90 bands a frame) */
#define BAND_POS 16u        /* half rows */
#define BAND_GTAO 4u        /* half rows */
#define BAND_UP 4u          /* pairs of full rows */
#define PI_F 3.14159265f

struct vt_ssao {
    float *pos;             /* half texels' nearness, padded (vt_ssao_kjob's pn) */
    size_t pos_cap;
    float *hao;             /* half texels' AO */
    size_t hao_cap;
    int32_t *cs;            /* the crease texels' counts (vt_ssao_kjob) */
    size_t cs_cap;
    int32_t *cx;            /* 3 planes of w + 8 (padded with 0): each full column's taps' half columns, weights */
    float *cw;
    size_t cx_cap, cw_cap;
    float *ao;              /* full pixels' AO */
    size_t ao_cap;
    uint32_t isa;           /* vt_ssao_set_isa's + 1; 0: the default */
    bool no_skip;           /* vt_ssao_no_skip */
};

typedef struct job {
    uint32_t nt;
    vt_ssao_kjob k;
    vt_ssao_kern kern;
} job;

/* (p, 1) ~ inv (X, Y, N, 1); false where it is not a finite point (the
 * view's set-up). */
static bool unproject(const vt_ssao_view *sv, float X, float Y, float N, float p[3])
{
    float q[4];
    for (int r = 0; r < 4; r++) q[r] = sv->inv[r][0] * X + sv->inv[r][1] * Y + sv->inv[r][2] * N + sv->inv[r][3];
    float iw = 1 / q[3];
    for (int k = 0; k < 3; k++) p[k] = q[k] * iw;
    return isfinite(p[0]) && isfinite(p[1]) && isfinite(p[2]);
}

void vt_ssao_view_make(const cull_view_rows *vr, uint32_t w, uint32_t h, vt_ssao_view *sv)
{
    memset(sv, 0, sizeof *sv);
    double R[4][4], Ri[4][4];
    memcpy(R[0], vr->x, sizeof R[0]);
    memcpy(R[1], vr->y, sizeof R[1]);
    memcpy(R[2], vr->d, sizeof R[2]);
    memcpy(R[3], vr->w, sizeof R[3]);
    /* the size first: a view it cannot unproject (ok false) still gets
       an ambient occlusion of 1 for every pixel the shading reads */
    sv->w = w, sv->h = h, sv->hw = (w + 1) / 2, sv->hh = (h + 1) / 2;
    if (!w || !h || !vt_inv4(R, Ri)) return;
    sv->ortho = vr->ortho != 0;
    for (int r = 0; r < 4; r++)
        for (int c = 0; c < 4; c++) sv->inv[r][c] = (float)Ri[r][c];
    /* a half texel is 4 / w of NDC across, 4 / h up; perspective: at
       nearness 1 (w = 1), where its size scales as 1 / N */
    float p0[3], px[3], py[3], pn[3];
    if (!unproject(sv, 0, 0, sv->ortho ? 0.5f : 1.0f, p0) || !unproject(sv, 4.0f / w, 0, sv->ortho ? 0.5f : 1.0f, px) ||
        !unproject(sv, 0, 4.0f / h, sv->ortho ? 0.5f : 1.0f, py) || !unproject(sv, 0, 0, 0.75f, pn))
        return;
    float l2 = 0, n2 = 0;
    for (int k = 0; k < 3; k++) {
        sv->ex[k] = px[k] - p0[k];
        sv->ey[k] = py[k] - p0[k];
        sv->vdir[k] = pn[k] - p0[k]; /* orthographic: nearness grows towards the eye */
        l2 += sv->ex[k] * sv->ex[k];
        n2 += sv->vdir[k] * sv->vdir[k];
    }
    /* the rows' (X, Y, N, 1) is the clip vector over w, and perspective
       nearness is 1 / w (cull_view_rows' d): (p, 1) = Ri (X, Y, N, 1) / N,
       p = Ri (X, Y, 0, 1) / N plus the eye Ri's column 2; orthographic, w
       is the constant w[3]: p = w[3] Ri (X, Y, N, 1). Half texel i is at
       X = (4 i + 1) / w - 1. */
    const double ws = sv->ortho ? vr->w[3] : 1, X0 = 1.0 / w - 1, Y0 = 1.0 / h - 1;
    for (int k = 0; k < 3; k++) {
        double b0 = ws * (Ri[k][0] * X0 + Ri[k][1] * Y0 + Ri[k][3]), bi = ws * Ri[k][0] * 4 / w,
               bj = ws * Ri[k][1] * 4 / h, bn = sv->ortho ? ws * Ri[k][2] : 0;
        sv->b0[k] = (float)b0, sv->bi[k] = (float)bi, sv->bj[k] = (float)bj, sv->bn[k] = (float)bn;
        if (!isfinite(sv->b0[k]) || !isfinite(sv->bi[k]) || !isfinite(sv->bj[k]) || !isfinite(sv->bn[k])) return;
    }
    /* kappa (vt_ssao.inl's ss_tan): the least over the image's corners
       and the steps to a neighbour of the sine between the two texels'
       rays (perspective: along b0 + i bi + j bj) or of their distance
       (orthographic: the rays along bn), over 8 (the quarter, and half for
       a step of more than one texel that is not the sum of these) */
    {
        double lo = INFINITY, bn[3], bl = 0;
        for (int k = 0; k < 3; k++) bn[k] = sv->bn[k], bl += bn[k] * bn[k];
        bl = sqrt(bl);
        static const int off[4][2] = {{1, 0}, {0, 1}, {1, 1}, {1, -1}};
        for (int c = 0; c < 4; c++)
            for (int o = 0; o < 4; o++) {
                double i = c & 1 ? sv->hw - 1.0 : 0, jj = c & 2 ? sv->hh - 1.0 : 0, a[3], b[3], x[3];
                double di = c & 1 ? -off[o][0] : off[o][0], dj = c & 2 ? -off[o][1] : off[o][1];
                for (int k = 0; k < 3; k++) {
                    a[k] = sv->ortho ? 0 : (double)sv->b0[k] + i * sv->bi[k] + jj * sv->bj[k];
                    b[k] = a[k] + di * sv->bi[k] + dj * sv->bj[k];
                }
                const double *u = sv->ortho ? bn : a;
                x[0] = u[1] * b[2] - u[2] * b[1], x[1] = u[2] * b[0] - u[0] * b[2], x[2] = u[0] * b[1] - u[1] * b[0];
                double ul = sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]), vl = sqrt(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]);
                double q = sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]) / (sv->ortho ? ul * ul : ul * vl);
                lo = q < lo ? q : lo;
            }
        sv->kappa = (float)(VT_SSAO_BIAS * lo / 8);
        if (!(sv->kappa >= 0) || !isfinite(sv->kappa)) sv->kappa = 0;
    }
    sv->texel1 = sqrtf(l2);
    if (!(sv->texel1 > 0) || !isfinite(sv->texel1)) return;
    if (sv->ortho) {
        /* nearness is affine in depth: 0.25 nearness units are |vdir| metres */
        float nl = sqrtf(n2);
        if (!(nl > 0) || !isfinite(nl)) return;
        for (int k = 0; k < 3; k++) sv->vdir[k] /= nl;
        sv->ntol = VT_SSAO_DEPTH_TOL_M * 0.25f / nl;
        if (!(sv->ntol > 0) || !isfinite(sv->ntol)) return;
    }
    sv->ok = true;
}

/* A pass over rows [0, rows) in bands of band rows, the threads taking
 * the next band as they finish one (cull_pool_each): the lane kernel fn
 * (vt_ssao.inl) one row at a time. */
typedef struct pass_job {
    const vt_ssao_kjob *k;
    vt_ssao_row_fn fn;
    uint32_t rows, band;
} pass_job;

static void pass_band(void *arg, uint32_t b)
{
    const pass_job *q = arg;
    for (uint32_t j = b * q->band; j < q->rows && j < (b + 1) * q->band; j++) q->fn(q->k, j);
}

/* The tent taps along one axis for full coordinate x: the half texels
 * (sample points 2i) within two pixels, weighted so each of the 2x2
 * pattern's turns weighs the same; a tap off the image has weight 0
 * (index clamped). */
static void taps(uint32_t x, uint32_t hn, uint32_t idx[3], float wt[3])
{
    if (x & 1) {
        idx[0] = (x - 1) / 2, wt[0] = 0.5f;
        idx[1] = (x + 1) / 2 < hn ? (x + 1) / 2 : idx[0], wt[1] = (x + 1) / 2 < hn ? 0.5f : 0;
        idx[2] = idx[0], wt[2] = 0;
        return;
    }
    idx[0] = x >= 2 ? x / 2 - 1 : x / 2, wt[0] = x >= 2 ? 0.25f : 0;
    idx[1] = x / 2, wt[1] = 0.5f;
    idx[2] = x / 2 + 1 < hn ? x / 2 + 1 : x / 2, wt[2] = x / 2 + 1 < hn ? 0.25f : 0;
}

void vt_ssao_dirs(float dir[4 * VT_SSAO_SLICES][2])
{
    for (int t = 0; t < 4; t++)
        for (int k = 0; k < VT_SSAO_SLICES; k++) {
            float phi = ((float)k + (float)t * 0.25f) * (PI_F / VT_SSAO_SLICES);
            dir[t * VT_SSAO_SLICES + k][0] = cosf(phi);
            dir[t * VT_SSAO_SLICES + k][1] = sinf(phi);
        }
}

int vt_ssao_run(vt_ssao **sp, cull_pool *pool, uint32_t nt, const vt_ssao_view *sv, const float *near,
                const float **ao)
{
    return vt_ssao_run_side(sp, pool, nt, sv, near, ao, NULL, NULL);
}

int vt_ssao_run_side(vt_ssao **sp, cull_pool *pool, uint32_t nt, const vt_ssao_view *sv, const float *near,
                     const float **ao, cull_side_fn side, void *side_arg)
{
    if (!*sp && !(*sp = calloc(1, sizeof **sp))) return VT_ERR_NOMEM;
    vt_ssao *s = *sp;
    size_t npx = (size_t)sv->w * sv->h, nh = (size_t)sv->hw * sv->hh;
    if (!vp_grow((void **)&s->ao, &s->ao_cap, npx ? npx : 1, sizeof *s->ao) ||
        !vp_grow((void **)&s->pos, &s->pos_cap, nh + 2 * VT_SSAO_PAD(sv->hw), sizeof *s->pos) ||
        !vp_grow((void **)&s->hao, &s->hao_cap, nh ? nh : 1, sizeof *s->hao) ||
        !vp_grow((void **)&s->cs, &s->cs_cap, VT_SSAO_CBLKS(sv->hw) * (sv->hh + 1), sizeof *s->cs) ||
        !vp_grow((void **)&s->cx, &s->cx_cap, 3 * ((size_t)sv->w + 8), sizeof *s->cx) ||
        !vp_grow((void **)&s->cw, &s->cw_cap, 3 * ((size_t)sv->w + 8), sizeof *s->cw))
        return VT_ERR_NOMEM;
    *ao = s->ao;
    if (!sv->ok) {
        for (size_t i = 0; i < npx; i++) s->ao[i] = 1;
        if (side) side(side_arg);
        return 0;
    }
    job jb = {.nt = nt && pool ? nt : 1, .kern = vt_ssao_kern_pick(s->isa ? s->isa - 1 : CULL_ISA_COUNT)};
    const size_t pl = (size_t)sv->w + 8;
    jb.k = (vt_ssao_kjob){.sv = sv, .near = near, .hao = s->hao, .cs = s->cs, .cx = s->cx, .cw = s->cw, .ao = s->ao};
    /* the plane's pads (read by the masked lanes of steps at the image's
       sides: set, so no uninitialised memory is read) */
    const size_t pad = VT_SSAO_PAD(sv->hw);
    jb.k.pn = s->pos + pad;
    for (size_t i = 0; i < pad; i++) s->pos[i] = s->pos[pad + nh + i] = VT_EMPTY;
    vt_ssao_dirs(jb.k.dir);
    memset(s->cx, 0, 3 * pl * sizeof *s->cx);
    memset(s->cw, 0, 3 * pl * sizeof *s->cw);
    for (uint32_t x = 0; x < sv->w; x++) {
        uint32_t idx[3];
        float wt[3];
        taps(x, sv->hw, idx, wt);
        for (int c = 0; c < 3; c++) s->cx[c * pl + x] = (int32_t)idx[c], s->cw[c * pl + x] = wt[c];
    }
    /* the crease test's tolerance: a quarter of the least margin by which
       a sample the test takes is above the tangent plane (kappa over 8
       texels out, ss_tan) over the most texels a sample is out (64 sqrt
       2 < 128): nearness that bends less than this between texels stays
       within that margin of the plane over the whole reach (perspective:
       relative to the texel's nearness, which is the larger near the eye) */
    jb.k.crease_tol = sv->kappa / 32;
    jb.k.no_skip = s->no_skip;
    memset(s->cs, 0, VT_SSAO_CBLKS(sv->hw) * sizeof *s->cs);
    /* 1. the half texels' nearness; 2. the crease texels; 3. GTAO (all
       over half rows); 4. the upsample of full rows, two at a time (the
       lane kernel, vt_ssao.inl: the pair's half-row taps read once; the
       columns' taps made above) */
    const pass_job pass[4] = {{&jb.k, jb.kern.pos, sv->hh, BAND_POS},
                              {&jb.k, jb.kern.crease, sv->hh, BAND_POS},
                              {&jb.k, jb.kern.gtao, sv->hh, BAND_GTAO},
                              {&jb.k, jb.kern.up, (sv->h + 1) / 2, BAND_UP}};
    for (int p = 0; p < 4; p++) {
        /* the side job with GTAO, the longest pass (~70 % of the time) */
        cull_pool_each_side(jb.nt > 1 ? pool : NULL, jb.nt, (pass[p].rows + pass[p].band - 1) / pass[p].band,
                            pass_band, (void *)&pass[p], p == 2 ? side : NULL, side_arg);
        if (p == 1) { /* the rows' counts into the integral image (29 k additions) */
            const size_t cw = VT_SSAO_CBLKS(sv->hw);
            for (uint32_t j = 1; j <= sv->hh; j++)
                for (size_t i = 0; i < cw; i++) s->cs[j * cw + i] += s->cs[(j - 1) * cw + i];
        }
    }
    return 0;
}

void vt_ssao_set_isa(vt_ssao **sp, uint32_t isa)
{
    if (!*sp) *sp = calloc(1, sizeof **sp);
    if (*sp) (*sp)->isa = isa < CULL_ISA_COUNT ? isa + 1 : 0;
}

void vt_ssao_no_skip(vt_ssao **sp)
{
    if (!*sp) *sp = calloc(1, sizeof **sp);
    if (*sp) (*sp)->no_skip = true;
}

void vt_ssao_destroy(vt_ssao *s)
{
    if (!s) return;
    free(s->pos);
    free(s->hao);
    free(s->cs);
    free(s->cx);
    free(s->cw);
    free(s->ao);
    free(s);
}
