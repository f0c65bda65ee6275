/*
 * vt_ssao.c — the software renderer's ambient occlusion (see vt_ssao.h):
 * three passes over bands of 8 half-resolution rows (16 full rows: one
 * light-tile row), interleaved over the threads as vt_soft's raster and
 * shading split tile rows:
 *   1. positions: each half texel's camera-relative point from its
 *      nearness (16 multiply-adds and a divide);
 *   2. GTAO per half texel (2 slices x 2 sides x 4 steps);
 *   3. the depth-aware tent upsample to every full pixel.
 * Memory: 16 + 4 bytes a half texel, 4 a pixel (about 5.5 MB at
 * 1280x720), kept from frame to frame.
 */
#include "vt_picture.h"
#include "vt_ssao.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define BAND 8u             /* half rows a band */
#define PI_F 3.14159265f

struct vt_ssao {
    float *pos;             /* half texels: x, y, z camera-relative, nearness (VT_EMPTY: sky) */
    size_t pos_cap;
    float *hao;             /* half texels' AO */
    size_t hao_cap;
    float *hnear;           /* half texels' nearness (a copy, packed for the upsample) */
    size_t hnear_cap;
    uint32_t *cx;           /* per full column: its 3 taps' half columns, weights */
    float *cw;
    size_t cx_cap, cw_cap;
    float *ao;              /* full pixels' AO */
    size_t ao_cap;
};

typedef struct job {
    const vt_ssao_view *sv;
    const float *near;
    vt_ssao *s;
    uint32_t nt;
    float dir[4 * VT_SSAO_SLICES][2]; /* vt_ssao_dirs */
} job;

/* (p, 1) ~ inv (X, Y, N, 1); false where it is not a finite point. */
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
    if (!w || !h || !vt_inv4(R, Ri)) return;
    sv->w = w, sv->h = h, sv->hw = (w + 1) / 2, sv->hh = (h + 1) / 2;
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

/* Pass 1: the half texels' points of band rows. */
static void job_pos(void *arg, uint32_t t)
{
    job *jb = arg;
    const vt_ssao_view *sv = jb->sv;
    const uint32_t bands = (sv->hh + BAND - 1) / BAND;
    for (uint32_t b = t; b < bands; b += jb->nt)
        for (uint32_t j = b * BAND; j < sv->hh && j < (b + 1) * BAND; j++) {
            const float *nrow = jb->near + (size_t)(2 * j) * sv->w;
            float *o = jb->s->pos + (size_t)4 * j * sv->hw;
            float Y = (float)((2.0 * (2 * j) + 1) / sv->h - 1);
            for (uint32_t i = 0; i < sv->hw; i++, o += 4) {
                float N = nrow[2 * i], X = (float)((2.0 * (2 * i) + 1) / sv->w - 1);
                o[3] = VT_EMPTY;
                if (!(N > VT_EMPTY) || !isfinite(N) || !unproject(sv, X, Y, N, o)) continue;
                o[3] = N;
            }
        }
}

/* Texel (i, j)'s point, or NULL off the image or on the sky. */
static inline const float *texel(const job *jb, int64_t i, int64_t j)
{
    const vt_ssao_view *sv = jb->sv;
    if (i < 0 || j < 0 || i >= sv->hw || j >= sv->hh) return NULL;
    const float *q = jb->s->pos + 4 * ((size_t)j * sv->hw + (size_t)i);
    return q[3] == VT_EMPTY ? NULL : q;
}

static inline float dot3(const float a[3], const float b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* The step along one screen axis, to the neighbour on the side where
 * the surface continues P's plane: nearness is affine in screen space on
 * a plane, so the side whose two texels extrapolate to P's nearness best
 * (a crease's other face, or a silhouette's background, does not); a
 * side with only one texel counts as a perfect fit only when the other
 * side has none. false if neither neighbour exists. */
static bool side_step(const float *p, const float *lo, const float *lo2, const float *hi, const float *hi2, float d[3])
{
    if (!lo && !hi) return false;
    float el = !lo ? INFINITY : lo2 ? fabsf(2 * lo[3] - lo2[3] - p[3]) : FLT_MAX;
    float eh = !hi ? INFINITY : hi2 ? fabsf(2 * hi[3] - hi2[3] - p[3]) : FLT_MAX;
    for (int k = 0; k < 3; k++) d[k] = eh < el || (eh == el && hi) ? hi[k] - p[k] : p[k] - lo[k];
    return true;
}

/* GTAO at half texel (i, j) (vt_ssao.h). */
static float gtao(const job *jb, uint32_t i, uint32_t j)
{
    const vt_ssao_view *sv = jb->sv;
    const float *P = texel(jb, i, j);
    if (!P) return 1;
    const float R = VT_SSAO_RADIUS, inv_fade = 1 / (VT_SSAO_FADE * VT_SSAO_RADIUS);
    float rpx = R * (sv->ortho ? 1 : P[3]) / sv->texel1;
    if (!(rpx >= 1)) return 1; /* the radius is below a texel here: nothing to resolve */
    rpx = rpx < VT_SSAO_MAX_PX ? rpx : VT_SSAO_MAX_PX;
    /* no more steps than texels in the radius (a far surface's steps
       would fetch the same texels again) */
    const int nst = rpx < VT_SSAO_STEPS ? (int)rpx : VT_SSAO_STEPS;
    const float inv_nst = 1.0f / (float)nst;
    float dx[3], dy[3], n[3], V[3];
    const int64_t I = i, J = j;
    if (!side_step(P, texel(jb, I - 1, J), texel(jb, I - 2, J), texel(jb, I + 1, J), texel(jb, I + 2, J), dx) ||
        !side_step(P, texel(jb, I, J - 1), texel(jb, I, J - 2), texel(jb, I, J + 1), texel(jb, I, J + 2), dy))
        return 1;
    n[0] = dx[1] * dy[2] - dx[2] * dy[1];
    n[1] = dx[2] * dy[0] - dx[0] * dy[2];
    n[2] = dx[0] * dy[1] - dx[1] * dy[0];
    if (sv->ortho) {
        memcpy(V, sv->vdir, sizeof V);
    } else {
        for (int k = 0; k < 3; k++) V[k] = -P[k];
    }
    float nl = sqrtf(dot3(n, n)), vl = sqrtf(dot3(V, V));
    if (!(nl > 0) || !(vl > 0) || !isfinite(nl) || !isfinite(vl)) return 1;
    float ns = dot3(n, V) < 0 ? -1 / nl : 1 / nl;
    for (int k = 0; k < 3; k++) {
        n[k] *= ns;
        V[k] /= vl;
    }
    const float(*dir)[2] = jb->dir + ((i & 1) + 2 * (j & 1)) * VT_SSAO_SLICES;
    float num = 0, den = 0;
    for (int sl = 0; sl < VT_SSAO_SLICES; sl++) {
        const float c = dir[sl][0], s = dir[sl][1];
        float T[3];
        for (int k = 0; k < 3; k++) T[k] = c * sv->ex[k] + s * sv->ey[k];
        float tv = dot3(T, V);
        for (int k = 0; k < 3; k++) T[k] -= tv * V[k];
        float tl = sqrtf(dot3(T, T));
        if (!(tl > 0)) continue;
        /* the normal projected into the slice: its length and angle from V */
        float a = dot3(n, V), b = dot3(n, T) / tl, pl = sqrtf(a * a + b * b);
        if (!(pl > 0)) continue;
        float cn = a / pl, sn = b / pl, na = vt_ssao_acos(cn);
        na = sn < 0 ? -na : na;
        /* each side's horizon cosine, from the tangent plane's (the
           hemisphere's edge: cos(n -+ pi/2)) up */
        float hc[2] = {sn, -sn};
        bool up[2] = {false, false};
        for (int side = 0; side < 2; side++) {
            const float sg = side ? 1.0f : -1.0f, lo = hc[side];
            for (int st = 0; st < nst; st++) {
                /* floor(x + 0.5) as the GLSL has it, without a libm
                   call: |x| <= MAX_PX */
                float tt = rpx * ((float)st + 0.5f) * inv_nst;
                const float *S = texel(jb, (int64_t)i + (int32_t)(sg * c * tt + 1024.5f) - 1024,
                                       (int64_t)j + (int32_t)(sg * s * tt + 1024.5f) - 1024);
                if (!S) continue;
                /* out of the radius or not above the tangent plane by
                   the bias: decided on squares (most samples of a city
                   are on their texel's own plane), the root only for
                   occluders */
                float d[3] = {S[0] - P[0], S[1] - P[1], S[2] - P[2]};
                float l2 = dot3(d, d), hn = dot3(d, n);
                if (!(l2 > 0) || !(l2 < R * R) || !(hn > 0) || hn * hn < VT_SSAO_BIAS * VT_SSAO_BIAS * l2) continue;
                float il = 1 / sqrtf(l2), dist = l2 * il;
                float wf = (R - dist) * inv_fade, cv = dot3(d, V) * il;
                cv = lo + (cv - lo) * (wf < 1 ? wf : 1);
                if (cv > hc[side]) {
                    hc[side] = cv;
                    up[side] = true;
                }
            }
        }
        /* the arcs: a raised horizon's angle, else the hemisphere's edge */
        float h0 = up[0] ? -vt_ssao_acos(hc[0]) : na - PI_F / 2, s0 = up[0] ? -sqrtf(fmaxf(1 - hc[0] * hc[0], 0)) : -cn;
        float h1 = up[1] ? vt_ssao_acos(hc[1]) : na + PI_F / 2, s1 = up[1] ? sqrtf(fmaxf(1 - hc[1] * hc[1], 0)) : cn;
        float e0 = vt_ssao_arc(na - PI_F / 2, sn, -cn, cn, sn), e1 = vt_ssao_arc(na + PI_F / 2, -sn, cn, cn, sn);
        num += pl * (vt_ssao_arc(h0, hc[0], s0, cn, sn) + vt_ssao_arc(h1, hc[1], s1, cn, sn));
        den += pl * (e0 + e1);
    }
    float ao = den > 0 ? num / den : 1;
    return ao >= 0 ? (ao <= 1 ? ao : 1) : ao < 0 ? 0 : 1;
}

/* Pass 2: GTAO over band rows. */
static void job_gtao(void *arg, uint32_t t)
{
    job *jb = arg;
    const vt_ssao_view *sv = jb->sv;
    const uint32_t bands = (sv->hh + BAND - 1) / BAND;
    for (uint32_t b = t; b < bands; b += jb->nt)
        for (uint32_t j = b * BAND; j < sv->hh && j < (b + 1) * BAND; j++)
            for (uint32_t i = 0; i < sv->hw; i++) {
                size_t q = (size_t)j * sv->hw + i;
                jb->s->hao[q] = gtao(jb, i, j);
                jb->s->hnear[q] = jb->s->pos[4 * q + 3];
            }
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

/* Pass 3: the upsample of band rows (16 full rows a band); the columns'
 * taps were made once (vt_ssao_run). */
static void job_up(void *arg, uint32_t t)
{
    job *jb = arg;
    const vt_ssao_view *sv = jb->sv;
    const vt_ssao *s = jb->s;
    const uint32_t bands = (sv->h + 2 * BAND - 1) / (2 * BAND);
    for (uint32_t b = t; b < bands; b += jb->nt)
        for (uint32_t y = 2 * BAND * b; y < sv->h && y < 2 * BAND * (b + 1); y++) {
            uint32_t jy[3];
            float wy[3];
            taps(y, sv->hh, jy, wy);
            const float *nrow = jb->near + (size_t)y * sv->w;
            float *o = s->ao + (size_t)y * sv->w;
            const float *hn[3], *ha[3];
            for (int a = 0; a < 3; a++) {
                hn[a] = s->hnear + (size_t)jy[a] * sv->hw;
                ha[a] = s->hao + (size_t)jy[a] * sv->hw;
            }
            for (uint32_t x = 0; x < sv->w; x++) {
                float N = nrow[x];
                o[x] = 1;
                float tol = sv->ortho ? sv->ntol : VT_SSAO_DEPTH_TOL * N;
                if (!(N > VT_EMPTY) || !(tol > 0) || !(tol < FLT_MAX)) continue;
                const uint32_t *ix = s->cx + 3 * (size_t)x;
                const float *wx = s->cw + 3 * (size_t)x;
                /* most of a frame is unoccluded: the mean of ones is 1
                   (exactly: acc and sum add the same terms) */
                float lo = 1;
                for (int a = 0; a < 3; a++)
                    for (int c = 0; c < 3; c++) lo = ha[a][ix[c]] < lo ? ha[a][ix[c]] : lo; /* no libm call */
                if (lo == 1) continue;
                float k = 1 / tol, sum = 0, acc = 0;
                for (int a = 0; a < 3; a++)
                    for (int c = 0; c < 3; c++) {
                        /* a sky texel's nearness is VT_EMPTY: weight 0 */
                        float wd = 1 - fabsf(hn[a][ix[c]] - N) * k;
                        float wt = wd > 0 ? wy[a] * wx[c] * wd : 0;
                        sum += wt;
                        acc += wt * ha[a][ix[c]];
                    }
                if (sum > 0) {
                    float ao = acc / sum;
                    o[x] = ao >= 0 ? (ao <= 1 ? ao : 1) : ao < 0 ? 0 : 1;
                }
            }
        }
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
    if (!*sp && !(*sp = calloc(1, sizeof **sp))) return VT_ERR_NOMEM;
    vt_ssao *s = *sp;
    size_t npx = (size_t)sv->w * sv->h, nh = (size_t)sv->hw * sv->hh;
    if (!vp_grow((void **)&s->ao, &s->ao_cap, npx ? npx : 1, sizeof *s->ao) ||
        !vp_grow((void **)&s->pos, &s->pos_cap, 4 * (nh ? nh : 1), sizeof *s->pos) ||
        !vp_grow((void **)&s->hao, &s->hao_cap, nh ? nh : 1, sizeof *s->hao) ||
        !vp_grow((void **)&s->hnear, &s->hnear_cap, nh ? nh : 1, sizeof *s->hnear) ||
        !vp_grow((void **)&s->cx, &s->cx_cap, 3 * (size_t)sv->w + 3, sizeof *s->cx) ||
        !vp_grow((void **)&s->cw, &s->cw_cap, 3 * (size_t)sv->w + 3, sizeof *s->cw))
        return VT_ERR_NOMEM;
    *ao = s->ao;
    if (!sv->ok) {
        for (size_t i = 0; i < npx; i++) s->ao[i] = 1;
        return 0;
    }
    job jb = {.sv = sv, .near = near, .s = s, .nt = nt && pool ? nt : 1};
    vt_ssao_dirs(jb.dir);
    for (uint32_t x = 0; x < sv->w; x++) taps(x, sv->hw, s->cx + 3 * (size_t)x, s->cw + 3 * (size_t)x);
    void (*const pass[3])(void *, uint32_t) = {job_pos, job_gtao, job_up};
    for (int p = 0; p < 3; p++) {
        if (jb.nt > 1) cull_pool_run(pool, pass[p], &jb, jb.nt);
        else pass[p](&jb, 0);
    }
    return 0;
}

void vt_ssao_destroy(vt_ssao *s)
{
    if (!s) return;
    free(s->pos);
    free(s->hao);
    free(s->hnear);
    free(s->cx);
    free(s->cw);
    free(s->ao);
    free(s);
}
