/*
 * vt_resize.c — bilinear resampling of an RGBA8 picture (vt_image.h:
 * vt_image_resize_rgba8): a stream frame drawn at a lower resolution while
 * its camera moves (the daemon's dynamic resolution) brought back to the
 * stream's size before it is encoded.
 *
 * Pixel centres are aligned (output pixel x samples the input at
 * (x + 0.5) * sw / dw - 0.5, clamped to the edge pixels), so the picture
 * neither shifts nor loses its border. Separable, in 8-bit fixed point:
 * each input row a band needs is resampled across once into a 16-bit row
 * (2 of them live: a band walks its output rows downwards, and each pair
 * of input rows serves about dh / sh output rows), then each output row
 * is the two rows' blend, a loop the compiler vectorises. Weights are
 * 0..256 (the position's fraction rounded to 1/256); the result is within
 * 1.5 of the exact bilinear value (test_image.c holds it to a double-precision
 * reference).
 */
#include "vt_err.h"
#include "vt_image.h"

#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#define RS_MAX_BANDS 16u

typedef struct rs_job {
    uint32_t sw, sh, dw, dh;
    const uint8_t *src;
    size_t sstride, dstride;
    uint8_t *dst;
    const uint32_t *x0; /* per output column: the left input pixel's byte offset */
    const uint16_t *fx; /* its right neighbour's weight, 0..256 */
    uint32_t nbands;
    atomic_uint next;
    int rc[RS_MAX_BANDS];
} rs_job;

/* Where output coordinate i (of n) samples an input of m pixels: the first
 * pixel and the second's weight (0..256), clamped to the edges. */
static void rs_pos(uint32_t i, uint32_t n, uint32_t m, uint32_t *p0, uint16_t *w)
{
    /* (i + 0.5) * m / n - 0.5 in 1/256ths, exactly: (512 i m + 256 m - 256 n) / 2n */
    int64_t num = (int64_t)512 * i * m + 256 * (int64_t)m - 256 * (int64_t)n;
    int64_t q = num <= 0 ? 0 : (num + n) / (2 * (int64_t)n); /* rounded; left of pixel 0's centre: pixel 0 */
    int64_t last = 256 * ((int64_t)m - 1);
    if (q >= last) q = last; /* right of the last centre: the last pixel */
    *p0 = (uint32_t)(q >> 8);
    *w = (uint16_t)(q & 255);
    if (*p0 + 1 >= m) *w = 0; /* (only q == last gets here; its weight is 0 already) */
}

/* Input row y resampled across into out (dw x 4, in 1/256ths) */
static void rs_row(const rs_job *j, uint32_t y, uint16_t *out)
{
    const uint8_t *s = j->src + (size_t)y * j->sstride;
    for (uint32_t x = 0; x < j->dw; x++) {
        const uint8_t *a = s + j->x0[x];
        const uint32_t w1 = j->fx[x], w0 = 256 - w1;
        const uint8_t *b = w1 ? a + 4 : a; /* the last column has no right neighbour */
        for (int c = 0; c < 4; c++) out[4 * x + c] = (uint16_t)(a[c] * w0 + b[c] * w1);
    }
}

static void rs_band(void *arg, uint32_t t)
{
    (void)t;
    rs_job *j = arg;
    const size_t n = (size_t)j->dw * 4;
    uint16_t *buf = malloc(2 * n * sizeof *buf);
    for (uint32_t b; (b = atomic_fetch_add(&j->next, 1)) < j->nbands;) {
        if (!buf) {
            j->rc[b] = VT_ERR_NOMEM;
            continue;
        }
        uint32_t y0 = (uint32_t)((uint64_t)j->dh * b / j->nbands), y1 = (uint32_t)((uint64_t)j->dh * (b + 1) / j->nbands);
        uint16_t *row[2] = {buf, buf + n};
        uint32_t have[2] = {UINT32_MAX, UINT32_MAX}; /* the input row each holds */
        for (uint32_t y = y0; y < y1; y++) {
            uint32_t s0;
            uint16_t wy;
            rs_pos(y, j->dh, j->sh, &s0, &wy);
            const uint32_t s1 = wy ? s0 + 1 : s0;
            /* the rows needed, reusing what the last output row made (a
               weight of 0: the one row, blended with itself) */
            for (int k = 0; k < (wy ? 2 : 1); k++) {
                const uint32_t want = k ? s1 : s0;
                if (have[k] == want) continue;
                if (have[!k] == want) { /* the other slot has it: swap */
                    uint16_t *r = row[k];
                    row[k] = row[!k], row[!k] = r;
                    uint32_t h = have[k];
                    have[k] = have[!k], have[!k] = h;
                    continue;
                }
                rs_row(j, want, row[k]);
                have[k] = want;
            }
            const uint16_t *r0 = row[0], *r1 = wy ? row[1] : row[0];
            const uint32_t w1 = wy, w0 = 256 - wy;
            uint8_t *d = j->dst + (size_t)y * j->dstride;
            for (size_t i = 0; i < n; i++) d[i] = (uint8_t)((r0[i] * w0 + r1[i] * w1 + 32768u) >> 16);
        }
    }
    free(buf);
}

int vt_image_resize_rgba8(uint32_t sw, uint32_t sh, const uint8_t *src, size_t sstride, uint32_t dw, uint32_t dh,
                          uint8_t *dst, size_t dstride, uint32_t bands,
                          void (*run)(void *run_ctx, vt_jpeg_job_fn job, void *arg, uint32_t n), void *run_ctx)
{
    if (!src || !dst || !sw || !sh || !dw || !dh || sw > VT_IMAGE_MAX_DIM || sh > VT_IMAGE_MAX_DIM ||
        dw > VT_IMAGE_MAX_DIM || dh > VT_IMAGE_MAX_DIM || sstride < 4 * (size_t)sw || dstride < 4 * (size_t)dw)
        return VT_ERR_INVALID;
    uint32_t *x0 = malloc(dw * sizeof *x0);
    uint16_t *fx = malloc(dw * sizeof *fx);
    if (!x0 || !fx) {
        free(x0), free(fx);
        return VT_ERR_NOMEM;
    }
    for (uint32_t x = 0; x < dw; x++) {
        uint32_t p;
        rs_pos(x, dw, sw, &p, &fx[x]);
        x0[x] = 4 * p;
    }
    rs_job j = {.sw = sw, .sh = sh, .dw = dw, .dh = dh, .src = src, .sstride = sstride, .dstride = dstride, .dst = dst,
                .x0 = x0, .fx = fx, .nbands = bands < 1 ? 1 : bands > RS_MAX_BANDS ? RS_MAX_BANDS : bands};
    if (j.nbands > dh) j.nbands = dh;
    atomic_init(&j.next, 0);
    if (run && j.nbands > 1) run(run_ctx, rs_band, &j, j.nbands);
    rs_band(&j, 0); /* whatever bands the runner left (none, when it ran them all) */
    free(x0), free(fx);
    for (uint32_t b = 0; b < j.nbands; b++)
        if (j.rc[b]) return j.rc[b];
    return 0;
}
