/*
 * vt_post.c — the post passes of both renderers (vt_post.h): exposure from
 * a luminance histogram with eye adaptation, then FXAA 3.11. Runs once per
 * frame on the whole picture, in bands of rows on the renderer's pool.
 * The rows that touch every pixel (histogram, exposure + luma, FXAA's
 * early exit) run 8 pixels a step where the CPU has AVX2
 * (vt_post_avx2.c, the same bits as the rows here); on the 1280x720 demo
 * city they are ~15 M instructions a frame, the edge pixels' FXAA (about
 * a fifth of the pixels there: texture detail passes the threshold) the
 * rest.
 *
 * FXAA works in a perceptual space, as it was designed to: Lottes' shader
 * expects gamma-space luma and blends display values. Blending the HDR
 * values themselves would let a sky of 10 next to a roof of 0.1 blend to 5,
 * white after the tone map: no anti-aliasing where it shows most. So each
 * colour is blended compressed, c / (1 + max(c)) (invertible, Karis'
 * weighting for HDR resolves), and its luma is sqrt(Y(compressed)) (a
 * Reinhard-compressed luminance, square root for ~gamma 2); the blend is
 * expanded back, c' / (1 - max(c')). The scratch holds the luma plane
 * (the early exit and the edge search read only it, a quarter of the
 * picture's bytes) and each band's results: the few texels a blend reads
 * are compressed where read, and the results go into the picture only
 * after every band has read it (FXAA reads neighbours it also writes; a
 * compressed copy of the whole picture was 14 MB written a frame).
 * Pixels FXAA leaves alone are not written: they keep their exact values.
 */
#include "vt_post.h"

#include "vt_err.h"
#include "vt_post_kern.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define MAX_BANDS 64

static uint32_t bands_of(cull_pool *pool, uint32_t threads, uint32_t height)
{
    uint32_t n = pool ? cull_pool_threads(pool) : 1;
    if (threads && threads < n) n = threads;
    if (n > MAX_BANDS) n = MAX_BANDS;
    if (n > height) n = height;
    return n ? n : 1;
}

static void run(cull_pool *pool, cull_job_fn fn, void *arg, uint32_t n)
{
    if (n > 1) cull_pool_run(pool, fn, arg, n);
    else fn(arg, 0);
}

/* The lane kernels of isa (vt_post_set_isa's + 1; 0: cull_isa_default):
 * the AVX2 rows where picked and present, else none (the one-lane
 * rows below). */
static vt_post_kern post_kern(uint32_t isa)
{
    uint32_t i = isa && isa - 1 < CULL_ISA_COUNT && cull_isa_supported(isa - 1) ? isa - 1 : cull_isa_default();
    vt_post_kern k = {0};
    if (i == CULL_ISA_AVX2) k = vt_post_kern_avx2();
    return k;
}

void vt_post_set_isa(vt_post *p, uint32_t isa)
{
    p->isa = isa < CULL_ISA_COUNT ? isa + 1 : 0;
}

void vt_post_free(vt_post *p)
{
    if (!p) return;
    free(p->scratch);
    free(p->cost);
    p->scratch = NULL;
    p->cost = NULL;
    p->cap = 0;
    p->cost_w = p->cost_h = p->cost_cap = 0;
}

/* ---- exposure ------------------------------------------------------------------ */

typedef struct hist_job {
    const float *rgba;
    uint32_t w, h, nb;
    size_t stride;
    uint32_t q[3];      /* mantissa bits of the smallest floats >= 2^0.25, 2^0.5, 2^0.75 */
    vt_post_hist_fn lanes; /* the AVX2 row, or NULL */
    bool sample;        /* count the tiles' subsample (job_hist) */
    uint32_t hist[][4][VT_HIST_BINS]; /* nb bands of 4 (vt_post_kern.h), 2 KiB each */
} hist_job;

static inline float lum(const float *p)
{
    return 0.2126f * p[0] + 0.7152f * p[1] + 0.0722f * p[2];
}

/* The bin of luminance L: floor(4 (log2 L - VT_HIST_LO)), clamped; NaN and
 * L <= 2^-16: 0. Exact: 4 log2 L = 4 e + 4 log2 m, the quarter found by
 * comparing the mantissa with 2^(k/4). */
static inline uint32_t bin_of(const uint32_t q[3], float L)
{
    if (!(L > 0x1p-16f)) return 0;
    if (!(L < 0x1p16f)) return VT_HIST_BINS - 1;
    uint32_t bits;
    memcpy(&bits, &L, sizeof bits);
    int e = (int)(bits >> 23) - 127; /* L is normal here */
    uint32_t m = bits & 0x7fffffu;
    uint32_t b = (uint32_t)(4 * (e - VT_HIST_LO)) + (m >= q[0]) + (m >= q[1]) + (m >= q[2]);
    return b < VT_HIST_BINS ? b : VT_HIST_BINS - 1;
}


/* The subsample of a large picture's histogram: in each tile of 4 rows
 * by 64 pixels, one run of 16 pixels from each row, the 4 runs at the 4
 * column quarters in an order drawn per tile (one of the 24): every row
 * and every column of a tile is a quarter sampled, so a pattern of rows
 * alone (stripes, a horizon) or of columns alone is counted exactly, and
 * a diagonal one without bias; each sampled pixel counts 4 times. The
 * right and bottom margins past whole tiles count every pixel once. A
 * quarter of the pixels and of the cache lines (the runs are whole
 * lines): 14 MB read -> 4 on a 1280x720 frame. */
static const uint8_t tile_order[24][4] = {
    {0, 1, 2, 3}, {0, 1, 3, 2}, {0, 2, 1, 3}, {0, 2, 3, 1}, {0, 3, 1, 2}, {0, 3, 2, 1},
    {1, 0, 2, 3}, {1, 0, 3, 2}, {1, 2, 0, 3}, {1, 2, 3, 0}, {1, 3, 0, 2}, {1, 3, 2, 0},
    {2, 0, 1, 3}, {2, 0, 3, 1}, {2, 1, 0, 3}, {2, 1, 3, 0}, {2, 3, 0, 1}, {2, 3, 1, 0},
    {3, 0, 1, 2}, {3, 0, 2, 1}, {3, 1, 0, 2}, {3, 1, 2, 0}, {3, 2, 0, 1}, {3, 2, 1, 0},
};

/* tile (g, b)'s order: a fixed hash (the same picture, the same EV) */
static inline const uint8_t *tile_of(uint32_t g, uint32_t b)
{
    uint32_t x = g * 0x9E3779B1u ^ (b + 0x7F4A7C15u) * 0x85EBCA77u;
    x ^= x >> 15;
    x *= 0x2C1B3C6Du;
    x ^= x >> 12;
    return tile_order[x % 24];
}

/* n pixels from p into band t's histogram, each counting wgt */
static void hist_run(hist_job *j, uint32_t t, const float *p, uint32_t n, uint32_t wgt)
{
    uint32_t x = j->lanes ? j->lanes(p, n, j->q, j->hist[t], wgt) : 0;
    for (p += 4 * (size_t)x; x < n; x++, p += 4) j->hist[t][0][bin_of(j->q, lum(p))] += wgt;
}

/* tiles ahead that job_hist prefetches: a tile's run (16 pixels, ~30
 * instructions) is far shorter than a miss to memory */
#define HIST_AHEAD 4

static void job_hist(void *arg, uint32_t t)
{
    hist_job *j = arg;
    uint32_t y0 = (uint32_t)((uint64_t)j->h * t / j->nb), y1 = (uint32_t)((uint64_t)j->h * (t + 1) / j->nb);
    memset(j->hist[t], 0, sizeof j->hist[t]);
    const uint32_t tiles_w = j->sample ? j->w / 64 : 0, tiles_h = j->sample ? j->h / 4 : 0;
    for (uint32_t y = y0; y < y1; y++) {
        const float *p = j->rgba + 4 * (size_t)y * j->stride;
        uint32_t x = 0;
        if (y / 4 < tiles_h) {
            for (uint32_t g = 0; g < tiles_w; g++) {
                /* the run HIST_AHEAD tiles on asked for now: the runs
                   skip 3 lines in 4, which the hardware's stream
                   prefetch does not follow (the run's first load took
                   over half of the pass' time, a miss to DRAM) */
                if (g + HIST_AHEAD < tiles_w) {
                    const char *n =
                        (const char *)(p + 4 * ((size_t)(g + HIST_AHEAD) * 64 + 16 * tile_of(g + HIST_AHEAD, y / 4)[y % 4]));
                    for (int k = 0; k < 4; k++) __builtin_prefetch(n + 64 * k);
                }
                hist_run(j, t, p + 4 * ((size_t)g * 64 + 16 * tile_of(g, y / 4)[y % 4]), 16, 4);
            }
            x = tiles_w * 64;
        }
        hist_run(j, t, p + 4 * (size_t)x, j->w - x, 1);
    }
}

typedef struct scale_job {
    float *rgba;
    uint32_t w, h, nb;
    size_t stride;
    float scale;
} scale_job;

static void job_scale(void *arg, uint32_t t)
{
    scale_job *j = arg;
    uint32_t y0 = (uint32_t)((uint64_t)j->h * t / j->nb), y1 = (uint32_t)((uint64_t)j->h * (t + 1) / j->nb);
    for (uint32_t y = y0; y < y1; y++) {
        float *p = j->rgba + 4 * (size_t)y * j->stride;
        for (uint32_t x = 0; x < j->w; x++, p += 4) {
            p[0] *= j->scale;
            p[1] *= j->scale;
            p[2] *= j->scale;
        }
    }
}

double vt_ev_of_luminance(double L)
{
    return log2(L * 100.0 / 12.5);
}

/* bin_of's thresholds: the mantissa bits of the smallest floats >= 2^0.25, 2^0.5, 2^0.75 */
static void hist_q(uint32_t q[3])
{
    for (int k = 0; k < 3; k++) {
        double r = exp2((k + 1) / 4.0);
        float f = (float)r;
        if ((double)f < r) f = nextafterf(f, 2.0f);
        uint32_t bits;
        memcpy(&bits, &f, sizeof bits);
        q[k] = bits & 0x7fffffu;
    }
}

static float ev_of_hist(const uint64_t hist[VT_HIST_BINS], float comp);

/* A part's 4 sub-histograms added to the sum. */
static void bins_add(uint64_t hist[VT_HIST_BINS], const uint32_t (*b)[VT_HIST_BINS])
{
    for (int k = 0; k < 4; k++)
        for (int i = 0; i < VT_HIST_BINS; i++) hist[i] += b[k][i];
}

static float exposure_auto(const float *rgba, uint32_t width, uint32_t height, size_t stride, float comp,
                           cull_pool *pool, uint32_t threads, uint32_t isa, bool sample)
{
    /* the bins of the bands used (not on a worker's stack; a few KiB,
       not MAX_BANDS' 128 KiB, which malloc would map and unmap a frame) */
    uint32_t nb = bands_of(pool, threads, height);
    hist_job *j = calloc(1, sizeof *j + nb * sizeof j->hist[0]);
    if (!j) return 0;
    j->rgba = rgba;
    j->w = width;
    j->h = height;
    j->stride = stride;
    j->nb = nb;
    hist_q(j->q);
    j->lanes = post_kern(isa).hist;
    j->sample = sample && (uint64_t)width * height >= VT_HIST_SAMPLE_MIN;
    run(pool, job_hist, j, j->nb);
    uint64_t hist[VT_HIST_BINS] = {0};
    for (uint32_t t = 0; t < j->nb; t++) bins_add(hist, j->hist[t]);
    free(j);
    return ev_of_hist(hist, comp);
}

/* The EV100 of the summed histogram: the mean log2 luminance of the
 * metered part, less comp, clamped. */
static float ev_of_hist(const uint64_t hist[VT_HIST_BINS], float comp)
{
    uint64_t n = 0;
    for (int b = 0; b < VT_HIST_BINS; b++) n += hist[b];
    /* the mean log2 luminance of the pixels ranked [PLO n, PHI n) (bin
       centres; a bin straddling a bound counts in part) */
    double lo = VT_HIST_PLO * (double)n, hi = VT_HIST_PHI * (double)n, acc = 0, sum = 0, wsum = 0;
    for (int b = 0; b < VT_HIST_BINS; b++) {
        double a = acc, c = acc + (double)hist[b];
        acc = c;
        double in = fmin(c, hi) - fmax(a, lo);
        if (in <= 0) continue;
        sum += in * (VT_HIST_LO + (b + 0.5) / 4.0);
        wsum += in;
    }
    double l2 = wsum > 0 ? sum / wsum : VT_HIST_LO;
    double ev = l2 + log2(100.0 / 12.5) - comp;
    return (float)(ev < VT_EV_MIN ? VT_EV_MIN : ev > VT_EV_MAX ? VT_EV_MAX : ev);
}

float vt_exposure_auto(const float *rgba, uint32_t width, uint32_t height, size_t stride, float comp,
                       cull_pool *pool, uint32_t threads)
{
    return exposure_auto(rgba, width, height, stride, comp, pool, threads, 0, true);
}

float vt_exposure_auto_all(const float *rgba, uint32_t width, uint32_t height, size_t stride, float comp,
                           cull_pool *pool, uint32_t threads)
{
    return exposure_auto(rgba, width, height, stride, comp, pool, threads, 0, false);
}

void vt_hist_begin(const vt_post *p, vt_hist *h)
{
    memset(h->b, 0, sizeof h->b);
    hist_q(h->q);
    h->lanes = post_kern(p ? p->isa : 0).hist;
}

int vt_hist_quarter(uint32_t width, uint32_t height, uint32_t x0, uint32_t y)
{
    /* job_hist's rule: with the subsample, row y of a whole band of
       tiles meters one run of 16 in each tile of 64 (x 4), and every
       pixel right of the last whole tile and below the last whole band
       once */
    _Static_assert(VT_HIST_RUN == 16, "the subsample's runs are 16 pixels");
    if ((uint64_t)width * height < VT_HIST_SAMPLE_MIN || y / 4 >= height / 4 || x0 / 64 >= width / 64) return -1;
    return tile_of(x0 / 64, y / 4)[y % 4];
}

void vt_hist_add(vt_hist *h, const float *rgba, uint32_t n, uint32_t wgt)
{
    uint32_t x = h->lanes ? h->lanes(rgba, n, h->q, h->b, wgt) : 0;
    for (rgba += 4 * (size_t)x; x < n; x++, rgba += 4) h->b[0][bin_of(h->q, lum(rgba))] += wgt;
}

float vt_adapt_step(float ev, float target, float dt)
{
    if (!(dt > 0)) return ev;
    float tau = target > ev ? VT_ADAPT_TAU_UP : VT_ADAPT_TAU_DOWN;
    float k = expf(-dt / tau); /* in (0, 1]: never past the target */
    return target + (ev - target) * k;
}

/* ---- FXAA ------------------------------------------------------------------------ */

/* FXAA 3.11's quality settings, preset 12 (its default): the edge search
 * steps in pixels, the thresholds, the sub-pixel amount. */
static const float fx_step[] = VT_FX_STEP_LIST;
#define FX_STEPS VT_FX_STEPS
#define FX_SUBPIX VT_FX_SUBPIX

typedef vt_post_fx_out fx_out;

typedef struct fx_job {
    float *rgba;  /* exposed by job_prep, read by job_fxaa, written by job_apply */
    float *luma;  /* sqrt(Y(c) / (1 + max c)) per pixel, width x height */
    fx_out *out;  /* band t's results from out + its first pixel's index */
    uint32_t n[MAX_BANDS]; /* band t's results */
    uint32_t y[MAX_BANDS + 1]; /* band t's rows: [y[t], y[t + 1]) */
    uint32_t *cost;        /* each row's edge pixels, for the next frame's split (NULL: none) */
    uint32_t w, h, nb;
    size_t stride;
    float scale;  /* the exposure, applied on the way (1: none) */
    vt_post_kern kern;
    vt_post_fx fx; /* the lanes' view of luma and rgba */
} fx_job;

/* NaN-free inputs only (compressed values, luma): plain comparisons, not
 * libm's fmaxf / fminf calls */
static inline float mx(float a, float b) { return a > b ? a : b; }
static inline float mn(float a, float b) { return a < b ? a : b; }

/* A colour as FXAA blends it: clamped to 0..1e6 (NaN 0), then c / (1 + max c). */
static inline void compress(const float *p, float q[3])
{
    float c[3];
    for (int k = 0; k < 3; k++) c[k] = p[k] > 0 ? (p[k] < 1e6f ? p[k] : 1e6f) : 0.0f; /* NaN: 0 */
    float k = 1 / (1 + mx(mx(c[0], c[1]), c[2]));
    q[0] = c[0] * k;
    q[1] = c[1] * k;
    q[2] = c[2] * k;
}

/* The exposure (scale) in place and the luma plane, a row at a time. */

/* Row y: the exposure in place and the luma. */
static void prep_row(const fx_job *j, uint32_t y)
{
    const float s = j->scale;
    float *p = j->rgba + 4 * (size_t)y * j->stride, *l = j->luma + (size_t)y * j->w;
    uint32_t x = j->kern.prep ? j->kern.prep(p, j->w, s, l) : 0;
    for (; x < j->w; x++) {
        float *px = p + 4 * x, q[3];
        px[0] *= s;
        px[1] *= s;
        px[2] *= s;
        compress(px, q);
        l[x] = sqrtf(0.2126f * q[0] + 0.7152f * q[1] + 0.0722f * q[2]);
    }
}

/* floor for the search's positions (|v| < 2^23): libm's floorf is a call
 * on x86-64 before SSE4.1 */
static inline int ifloor(float v)
{
    int i = (int)v;
    return (float)i > v ? i - 1 : i;
}

static inline size_t clamp_at(const fx_job *j, int x, int y)
{
    x = x < 0 ? 0 : x >= (int)j->w ? (int)j->w - 1 : x;
    y = y < 0 ? 0 : y >= (int)j->h ? (int)j->h - 1 : y;
    return (size_t)y * j->w + (size_t)x;
}

/* Bilinear fetch at pixel coordinates (pixel centres on integers), clamped
 * to the edge: the luma, or the compressed colour. */
static inline float luma_at(const fx_job *j, float px, float py)
{
    int x0 = ifloor(px), y0 = ifloor(py);
    float fx = px - (float)x0, fy = py - (float)y0;
    const float *L = j->luma;
    float a, b, c, d;
    if (x0 >= 0 && y0 >= 0 && x0 + 1 < (int)j->w && y0 + 1 < (int)j->h) {
        /* inside (the edge search mostly is): no clamps, the same texels */
        const float *q = L + (size_t)y0 * j->w + (size_t)x0;
        a = q[0], b = q[1], c = q[j->w], d = q[j->w + 1];
    } else {
        a = L[clamp_at(j, x0, y0)], b = L[clamp_at(j, x0 + 1, y0)];
        c = L[clamp_at(j, x0, y0 + 1)], d = L[clamp_at(j, x0 + 1, y0 + 1)];
    }
    float top = a + (b - a) * fx, bot = c + (d - c) * fx;
    return top + (bot - top) * fy;
}

/* The exposed pixel (x, y) clamped to the picture, compressed as FXAA
 * blends it (the same bits the luma was made from). */
static inline void texel(const fx_job *j, int x, int y, float q[3])
{
    x = x < 0 ? 0 : x >= (int)j->w ? (int)j->w - 1 : x;
    y = y < 0 ? 0 : y >= (int)j->h ? (int)j->h - 1 : y;
    compress(j->rgba + 4 * ((size_t)y * j->stride + (size_t)x), q);
}

static inline void colour_at(const fx_job *j, float px, float py, float out[3])
{
    int x0 = ifloor(px), y0 = ifloor(py);
    float fx = px - (float)x0, fy = py - (float)y0;
    float a[3], b[3], c[3], d[3];
    texel(j, x0, y0, a);
    texel(j, x0 + 1, y0, b);
    texel(j, x0, y0 + 1, c);
    texel(j, x0 + 1, y0 + 1, d);
    for (int k = 0; k < 3; k++) {
        float top = a[k] + (b[k] - a[k]) * fx, bot = c[k] + (d[k] - c[k]) * fx;
        out[k] = top + (bot - top) * fy;
    }
}

/* FxaaPixelShader (FXAA 3.11, PC quality), written from Lottes' published
 * algorithm: pixel units instead of texture units, "north" is y - 1. 1 and
 * the new colour (compressed) in out, or 0 where it leaves the pixel be. */
static int fxaa_pixel(const fx_job *j, int x, int y, float out[3])
{
    const float *L = j->luma;
    const bool inner = x > 0 && y > 0 && x + 1 < (int)j->w && y + 1 < (int)j->h;
    const size_t w = j->w, m = (size_t)y * w + (size_t)x;
#define LUMA(dx, dy) (inner ? L[m + (size_t)((dy) * (ptrdiff_t)w + (dx))] : L[clamp_at(j, x + (dx), y + (dy))])
    float lumaM = L[m];
    float lumaS = LUMA(0, 1), lumaE = LUMA(1, 0);
    float lumaN = LUMA(0, -1), lumaW = LUMA(-1, 0);
    float maxSM = mx(lumaS, lumaM), minSM = mn(lumaS, lumaM);
    float maxESM = mx(lumaE, maxSM), minESM = mn(lumaE, minSM);
    float maxWN = mx(lumaN, lumaW), minWN = mn(lumaN, lumaW);
    float rangeMax = mx(maxWN, maxESM), rangeMin = mn(minWN, minESM);
    float range = rangeMax - rangeMin;
    if (range < mx(VT_FX_EDGE_MIN, rangeMax * VT_FX_EDGE)) return 0; /* early exit */
    float lumaNW = LUMA(-1, -1), lumaSE = LUMA(1, 1);
    float lumaNE = LUMA(1, -1), lumaSW = LUMA(-1, 1);
#undef LUMA
    float lumaNS = lumaN + lumaS, lumaWE = lumaW + lumaE;
    float subpixRcpRange = 1.0f / range;
    float subpixNSWE = lumaNS + lumaWE;
    float edgeHorz1 = -2.0f * lumaM + lumaNS, edgeVert1 = -2.0f * lumaM + lumaWE;
    float lumaNESE = lumaNE + lumaSE, lumaNWNE = lumaNW + lumaNE;
    float edgeHorz2 = -2.0f * lumaE + lumaNESE, edgeVert2 = -2.0f * lumaN + lumaNWNE;
    float lumaNWSW = lumaNW + lumaSW, lumaSWSE = lumaSW + lumaSE;
    float edgeHorz4 = fabsf(edgeHorz1) * 2.0f + fabsf(edgeHorz2);
    float edgeVert4 = fabsf(edgeVert1) * 2.0f + fabsf(edgeVert2);
    float edgeHorz3 = -2.0f * lumaW + lumaNWSW, edgeVert3 = -2.0f * lumaS + lumaSWSE;
    float edgeHorz = fabsf(edgeHorz3) + edgeHorz4, edgeVert = fabsf(edgeVert3) + edgeVert4;
    float subpixNWSWNESE = lumaNWSW + lumaNESE;
    int horzSpan = edgeHorz >= edgeVert;
    float lengthSign = 1.0f;
    float subpixA = subpixNSWE * 2.0f + subpixNWSWNESE;
    if (!horzSpan) {
        lumaN = lumaW;
        lumaS = lumaE;
    }
    float subpixB = subpixA * (1.0f / 12.0f) - lumaM;
    float gradientN = lumaN - lumaM, gradientS = lumaS - lumaM;
    float lumaNN = lumaN + lumaM, lumaSS = lumaS + lumaM;
    int pairN = fabsf(gradientN) >= fabsf(gradientS);
    float gradient = mx(fabsf(gradientN), fabsf(gradientS));
    if (pairN) lengthSign = -lengthSign;
    float subpixC = mn(mx(fabsf(subpixB) * subpixRcpRange, 0.0f), 1.0f);
    /* posB: half a pixel across the edge, towards the steeper side; the
       search runs along the edge (offNP) both ways from it */
    float bx = (float)x, by = (float)y, ox = horzSpan ? 1.0f : 0.0f, oy = horzSpan ? 0.0f : 1.0f;
    if (!horzSpan) bx += lengthSign * 0.5f;
    else by += lengthSign * 0.5f;
    float nx = bx - ox * fx_step[0], ny = by - oy * fx_step[0];
    float px = bx + ox * fx_step[0], py = by + oy * fx_step[0];
    float subpixD = -2.0f * subpixC + 3.0f;
    float lumaEndN = luma_at(j, nx, ny), lumaEndP = luma_at(j, px, py);
    float subpixE = subpixC * subpixC;
    if (!pairN) lumaNN = lumaSS;
    float gradientScaled = gradient * 0.25f;
    float lumaMM = lumaM - lumaNN * 0.5f;
    float subpixF = subpixD * subpixE;
    int lumaMLTZero = lumaMM < 0.0f;
    lumaEndN -= lumaNN * 0.5f;
    lumaEndP -= lumaNN * 0.5f;
    int doneN = fabsf(lumaEndN) >= gradientScaled, doneP = fabsf(lumaEndP) >= gradientScaled;
    for (int k = 1; k < FX_STEPS; k++) {
        if (!doneN) {
            nx -= ox * fx_step[k];
            ny -= oy * fx_step[k];
        }
        if (!doneP) {
            px += ox * fx_step[k];
            py += oy * fx_step[k];
        }
        if ((doneN && doneP) || k == FX_STEPS - 1) break; /* the last step is a guess, unsampled */
        if (!doneN) lumaEndN = luma_at(j, nx, ny) - lumaNN * 0.5f;
        if (!doneP) lumaEndP = luma_at(j, px, py) - lumaNN * 0.5f;
        doneN = fabsf(lumaEndN) >= gradientScaled;
        doneP = fabsf(lumaEndP) >= gradientScaled;
    }
    float dstN = horzSpan ? (float)x - nx : (float)y - ny;
    float dstP = horzSpan ? px - (float)x : py - (float)y;
    int goodSpanN = (lumaEndN < 0.0f) != lumaMLTZero, goodSpanP = (lumaEndP < 0.0f) != lumaMLTZero;
    float spanLengthRcp = 1.0f / (dstP + dstN);
    int directionN = dstN < dstP;
    float dst = mn(dstN, dstP);
    int goodSpan = directionN ? goodSpanN : goodSpanP;
    float subpixG = subpixF * subpixF;
    float pixelOffset = dst * -spanLengthRcp + 0.5f;
    float subpixH = subpixG * FX_SUBPIX;
    float pixelOffsetGood = goodSpan ? pixelOffset : 0.0f;
    float pixelOffsetSubpix = mx(pixelOffsetGood, subpixH);
    float ux = (float)x, uy = (float)y;
    if (!horzSpan) ux += pixelOffsetSubpix * lengthSign;
    else uy += pixelOffsetSubpix * lengthSign;
    colour_at(j, ux, uy, out);
    return 1;
}


/* The blend expanded back: c / (1 - max c), in place. */
static inline void expand(float c[3])
{
    float m = mx(mx(c[0], c[1]), c[2]);
    /* m <= 1e6 / (1 + 1e6) < 1: a blend of compressed colours */
    float e = 1 / (1 - m);
    c[0] *= e;
    c[1] *= e;
    c[2] *= e;
}

/* FXAA of row y, its results appended at o; their count. */
static uint32_t fxaa_row_of(const fx_job *j, uint32_t y, fx_out *o)
{
    const bool inner = y > 0 && y + 1 < j->h;
    uint32_t x = 0, no = 0;
    if (inner && j->kern.fxaa_row) {
        /* pixel 0 first (the lanes start at 1), then the lanes */
        if (fxaa_pixel(j, 0, (int)y, o[no].c)) expand(o[no].c), o[no++].i = y * j->w;
        no += j->kern.fxaa_row(&j->fx, y, o + no, &x);
    }
    for (; x < j->w; x++)
        if (fxaa_pixel(j, (int)x, (int)y, o[no].c)) expand(o[no].c), o[no++].i = y * j->w + x;
    return no;
}

/* n results into the picture */
static void put(const fx_job *j, const fx_out *o, uint32_t n)
{
    for (uint32_t k = 0; k < n; k++) {
        uint32_t y = o[k].i / j->w;
        memcpy(j->rgba + 4 * ((size_t)y * j->stride + (o[k].i - y * j->w)), o[k].c, sizeof o[k].c);
    }
}

/* Rows of luma FXAA reads either side of its own: the search's sampled
 * steps reach 8.5 pixels along a vertical edge, its bilinear tap one
 * further. */
#define FX_REACH 10

/* Band t: its rows [y0, y1) and the rows [a, b) among them FXAA runs in
 * the band's own pass, a reach behind the exposure + luma (their luma
 * reach stays in the band: the band's pass needs no other band). The
 * rest, the reach next to a band beside it, waits for every band. */
static void band_rows(const fx_job *j, uint32_t t, uint32_t *y0, uint32_t *y1, uint32_t *a, uint32_t *b)
{
    *y0 = j->y[t], *y1 = j->y[t + 1];
    uint32_t lo = t == 0 ? *y0 : *y0 + FX_REACH, hi = t + 1 == j->nb ? *y1 : *y1 - FX_REACH;
    if (lo > *y1) lo = *y1;
    if (*y1 < *y0 + FX_REACH && t + 1 < j->nb) hi = lo;
    *a = lo;
    *b = hi > lo ? hi : lo;
}

/* FXAA of band row r in [a, b), in order. A row's colours are read by
 * the blends of its own row and the two beside it: row r - 1 is written
 * as soon as row r is done, unless a row read after the band's pass
 * (outside [a, b)) reads it or it was read before r - 2 was done (a,
 * a + 1); those, and the last, are kept (o[0, *keep)). *no: results. */
static void band_step(const fx_job *j, uint32_t r, uint32_t a, fx_out *o, uint32_t *no, uint32_t *keep)
{
    uint32_t start = *no;
    uint32_t c = fxaa_row_of(j, r, o + start);
    if (j->cost) j->cost[r] = c;
    *no += c;
    if (r == a) return; /* o[*keep, start): row r - 1's */
    if (r >= a + 2) {
        put(j, o + *keep, start - *keep);
        memmove(o + *keep, o + start, (*no - start) * sizeof *o);
        *no = *keep + (*no - start);
    } else {
        *keep = start;
    }
}

/* The band's pass: exposure + luma row by row, FXAA FX_REACH rows behind
 * while the rows it reads are still in cache (luma and colour written a
 * few hundred KiB before). */
static void job_post(void *arg, uint32_t t)
{
    fx_job *j = arg;
    uint32_t y0, y1, a, b;
    band_rows(j, t, &y0, &y1, &a, &b);
    fx_out *o = j->out + (size_t)y0 * j->w;
    uint32_t no = 0, keep = 0, r = a;
    for (uint32_t y = y0; y < y1; y++) {
        prep_row(j, y);
        for (; r < b && r + FX_REACH <= y; r++) band_step(j, r, a, o, &no, &keep);
    }
    for (; r < b; r++) band_step(j, r, a, o, &no, &keep);
    j->n[t] = no; /* all kept: the last row's too */
}

/* FXAA of band t's rows next to the bands beside it, once every band's
 * luma is there; results kept. */
static void band_rest(fx_job *j, uint32_t t)
{
    uint32_t y0, y1, a, b;
    band_rows(j, t, &y0, &y1, &a, &b);
    fx_out *o = j->out + (size_t)y0 * j->w;
    for (uint32_t r = y0; r < y1; r++)
        if (r < a || r >= b) {
            uint32_t c = fxaa_row_of(j, r, o + j->n[t]);
            if (j->cost) j->cost[r] = c;
            j->n[t] += c;
        }
}

static void job_rest(void *arg, uint32_t t)
{
    band_rest(arg, t);
}

/* An edge pixel's FXAA (the search's gathered taps, the blend) against a
 * pixel's exposure, luma and early exit: 10 to 20 to 1 (the street's
 * ~180 k edge pixels take about two thirds of the pass, its 920 k pixels
 * the rest; weights 10 and 20 both left the city's two bands within 10 %
 * of each other in thread CPU, against 4.5 / 6.8 ms split in halves). */
#define FX_EDGE_COST 15

/* The bands' rows: where the last frame of this size (p->cost) puts an
 * equal share of its work in each, else equal heights. A picture's edges
 * are uneven (the street's upper half, buildings and their windows, took
 * 6.2 ms of CPU against the lower's 4.5: one core waited), and a stream's
 * frames follow each other closely; the split changes no pixel (every
 * row's FXAA reads the same inputs whichever band runs it). Bands keep
 * 4 FX_REACH rows at least (a band's own pass FXAAs all but 2 FX_REACH). */
static void band_split(const vt_post *p, fx_job *j)
{
    uint32_t nb = j->nb, h = j->h;
    for (uint32_t t = 0; t <= nb; t++) j->y[t] = (uint32_t)((uint64_t)h * t / nb);
    if (nb < 2 || !p->cost || p->cost_w != j->w || p->cost_h != h || h < nb * 4 * FX_REACH) return;
    uint64_t total = 0;
    for (uint32_t y = 0; y < h; y++) total += j->w + (uint64_t)FX_EDGE_COST * p->cost[y];
    uint64_t acc = 0;
    uint32_t t = 1;
    for (uint32_t y = 0; y < h && t < nb; y++) {
        acc += j->w + (uint64_t)FX_EDGE_COST * p->cost[y];
        if (acc * nb >= total * t) j->y[t++] = y + 1;
    }
    for (; t < nb; t++) j->y[t] = h; /* (never: the last row reaches the total) */
    /* each band 4 FX_REACH rows or more: from the bottom, then the top */
    for (t = 1; t < nb; t++)
        if (j->y[t] < j->y[t - 1] + 4 * FX_REACH) j->y[t] = j->y[t - 1] + 4 * FX_REACH;
    for (t = nb - 1; t >= 1; t--)
        if (j->y[t] > j->y[t + 1] - 4 * FX_REACH) j->y[t] = j->y[t + 1] - 4 * FX_REACH;
}

static int fxaa_run(vt_post *p, cull_pool *pool, uint32_t threads, float *rgba, uint32_t width, uint32_t height,
                    size_t stride, float scale)
{
    size_t np = (size_t)width * height, need = np * 5;
    if (need > p->cap) {
        float *s = realloc(p->scratch, need * sizeof *s);
        if (!s) return VT_ERR_NOMEM;
        p->scratch = s;
        p->cap = need;
    }
    static fx_job z;
    fx_job *j = malloc(sizeof *j);
    if (!j) return VT_ERR_NOMEM;
    *j = z;
    j->rgba = rgba, j->luma = p->scratch, j->out = (fx_out *)(void *)(p->scratch + np), j->w = width, j->h = height;
    j->stride = stride, j->nb = bands_of(pool, threads, height), j->scale = scale, j->kern = post_kern(p->isa);
    j->fx = (vt_post_fx){.luma = j->luma, .rgba = rgba, .w = width, .h = height, .stride = stride};
    band_split(p, j);
    /* this frame's costs for the next (without memory for them: equal bands) */
    if (j->nb > 1 && height > p->cost_cap) {
        uint32_t *c = realloc(p->cost, height * sizeof *c);
        if (c) p->cost = c, p->cost_cap = height;
    }
    j->cost = j->nb > 1 && height <= p->cost_cap ? p->cost : NULL;
    p->cost_w = j->cost ? width : 0, p->cost_h = j->cost ? height : 0;
    /* the lanes' gathers index floats with 32-bit lanes */
    if ((uint64_t)stride * height * 4 >= (uint64_t)1 << 31) j->kern.fxaa_row = NULL;
    run(pool, job_post, j, j->nb);
    /* the rows beside other bands: 2 FX_REACH a boundary; on the calling
       thread while that is a small part of the picture (2 bands: 20 rows
       of 720, no third hand-over of the pool), else in bands */
    if (j->nb > 1) {
        if ((uint64_t)(j->nb - 1) * 2 * FX_REACH * 16 <= height) {
            for (uint32_t t = 0; t < j->nb; t++) band_rest(j, t);
        } else {
            run(pool, job_rest, j, j->nb);
        }
    }
    for (uint32_t t = 0; t < j->nb; t++) put(j, j->out + (size_t)j->y[t] * width, j->n[t]);
    free(j);
    return 0;
}

int vt_fxaa(vt_post *p, cull_pool *pool, uint32_t threads, float *rgba, uint32_t width, uint32_t height,
            size_t stride)
{
    return fxaa_run(p, pool, threads, rgba, width, height, stride, 1.0f);
}

int vt_post_apply(vt_post *p, cull_pool *pool, uint32_t threads, const vt_frame *f, float *ev)
{
    return vt_post_apply_hist(p, pool, threads, f, NULL, 0, ev);
}

int vt_post_apply_hist(vt_post *p, cull_pool *pool, uint32_t threads, const vt_frame *f, const vt_hist *parts,
                       uint32_t nparts, float *ev)
{
    *ev = 0;
    const vt_env *env = f->env;
    if (!env) return 0;
    double e = env->exposure_ev;
    if (env->exposure_mode == VT_EXPOSURE_AUTO) {
        float target;
        if (parts) {
            uint64_t hist[VT_HIST_BINS] = {0};
            for (uint32_t t = 0; t < nparts; t++) bins_add(hist, parts[t].b);
            target = ev_of_hist(hist, env->exposure_comp);
        } else {
            target = exposure_auto(f->rgba, f->width, f->height, f->stride, env->exposure_comp, pool, threads, p->isa,
                                   true);
        }
        e = target;
        if (f->adapt) {
            /* the caller's state: a bad EV (NaN, out of range) starts over */
            float a = f->adapt->ev;
            if (f->adapt->valid && a >= VT_EV_MIN && a <= VT_EV_MAX) e = vt_adapt_step(a, target, f->dt);
            f->adapt->ev = (float)e;
            f->adapt->valid = true;
        }
    }
    *ev = (float)e;
    float scale = (float)(1.0 / (1.2 * exp2(e)));
    /* FXAA's first pass applies the exposure on its way (one pass over
       the picture fewer); without FXAA, or without memory for it, alone */
    if (!(f->fx_off & VT_FX_FXAA) && !fxaa_run(p, pool, threads, f->rgba, f->width, f->height, f->stride, scale))
        return 0;
    scale_job sj = {.rgba = f->rgba, .w = f->width, .h = f->height, .stride = f->stride,
                    .nb = bands_of(pool, threads, f->height), .scale = scale};
    run(pool, job_scale, &sj, sj.nb);
    return f->fx_off & VT_FX_FXAA ? 0 : VT_ERR_NOMEM;
}
