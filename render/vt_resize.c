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
 * is the two rows' blend. Weights are 0..256 (the position's fraction
 * rounded to 1/256). Across: a * w0 + b * w1, exact in 16 bits (at most
 * 255 * 256). Down: ((h0 * w0) >> 8) + ((h1 * w1) >> 8), rounded >> 8: a
 * product's high half as SSE2's pmulhuw gives it (w << 8 fits 16 bits
 * for a weight under 256; a weight of 256 is the row itself), so the SSE2
 * loops and the plain C ones (other machines, the rows' ends) give the
 * same bytes. Each channel is within 1.5 of the exact bilinear value
 * (test_image.c holds it to a double-precision reference) and within the
 * input's range of that channel (fuzz_render checks it).
 */
#include "vt_err.h"
#include "vt_image.h"

#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#if defined(__SSE2__) && !defined(CULL_SCALAR_ONLY)
#include <emmintrin.h>
#endif

#define RS_MAX_BANDS 16u

typedef struct rs_job {
    uint32_t sw, sh, dw, dh;
    const uint8_t *src;
    size_t sstride, dstride;
    uint8_t *dst;
    const uint32_t *x0; /* per output column: the left input pixel's byte offset */
    const uint16_t *wt; /* per output column: the left pixel's weight w0 four times, then its right
                           neighbour's w1 = 256 - w0 four times (the SSE2 loop loads them as they are) */
    uint32_t wide;      /* columns [0, wide) may read 8 bytes at x0 (both pixels inside the row) */
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
    uint32_t x = 0;
#if defined(__SSE2__) && !defined(CULL_SCALAR_ONLY)
    const __m128i zero = _mm_setzero_si128();
    for (; x + 2 <= j->wide; x += 2) { /* two output pixels: a0 b0 | a1 b1, weighted, the halves summed */
        __m128i p = _mm_unpacklo_epi64(_mm_loadl_epi64((const __m128i *)(const void *)(s + j->x0[x])),
                                       _mm_loadl_epi64((const __m128i *)(const void *)(s + j->x0[x + 1])));
        __m128i m0 = _mm_mullo_epi16(_mm_unpacklo_epi8(p, zero), _mm_loadu_si128((const __m128i *)(const void *)(j->wt + 8 * x))),
                m1 = _mm_mullo_epi16(_mm_unpackhi_epi8(p, zero), _mm_loadu_si128((const __m128i *)(const void *)(j->wt + 8 * x + 8)));
        _mm_storeu_si128((__m128i *)(void *)(out + 4 * x),
                         _mm_add_epi16(_mm_unpacklo_epi64(m0, m1), _mm_unpackhi_epi64(m0, m1)));
    }
#endif
    for (; x < j->dw; x++) {
        const uint8_t *a = s + j->x0[x];
        const uint32_t w0 = j->wt[8 * x], w1 = j->wt[8 * x + 4];
        const uint8_t *b = w1 ? a + 4 : a; /* the last column has no right neighbour */
        for (int c = 0; c < 4; c++) out[4 * x + c] = (uint16_t)(a[c] * w0 + b[c] * w1);
    }
}

/* An output row from the two resampled rows r0 and r1 (r1's weight w1,
 * 1..255; r1 NULL: r0 alone) into n bytes of d */
static void rs_blend(const uint16_t *r0, const uint16_t *r1, uint32_t w1, uint8_t *d, size_t n)
{
    size_t i = 0;
    if (!r1) {
#if defined(__SSE2__) && !defined(CULL_SCALAR_ONLY)
        const __m128i half = _mm_set1_epi16(128);
        for (; i + 16 <= n; i += 16) {
            __m128i a = _mm_srli_epi16(_mm_adds_epu16(_mm_loadu_si128((const __m128i *)(const void *)(r0 + i)), half), 8),
                    b = _mm_srli_epi16(_mm_adds_epu16(_mm_loadu_si128((const __m128i *)(const void *)(r0 + i + 8)), half), 8);
            _mm_storeu_si128((__m128i *)(void *)(d + i), _mm_packus_epi16(a, b));
        }
#endif
        for (; i < n; i++) d[i] = (uint8_t)((r0[i] + 128u) >> 8);
        return;
    }
    const uint32_t w0 = 256 - w1;
#if defined(__SSE2__) && !defined(CULL_SCALAR_ONLY)
    const __m128i k0 = _mm_set1_epi16((short)(w0 << 8)), k1 = _mm_set1_epi16((short)(w1 << 8)),
                  half = _mm_set1_epi16(128);
    for (; i + 16 <= n; i += 16) {
        __m128i v[2];
        for (int h = 0; h < 2; h++) {
            __m128i a = _mm_loadu_si128((const __m128i *)(const void *)(r0 + i + 8 * h)),
                    b = _mm_loadu_si128((const __m128i *)(const void *)(r1 + i + 8 * h));
            /* (a w0) >> 8 + (b w1) >> 8 <= 65280: no carry out of 16 bits; + 128 saturates nowhere */
            __m128i s = _mm_add_epi16(_mm_mulhi_epu16(a, k0), _mm_mulhi_epu16(b, k1));
            v[h] = _mm_srli_epi16(_mm_adds_epu16(s, half), 8);
        }
        _mm_storeu_si128((__m128i *)(void *)(d + i), _mm_packus_epi16(v[0], v[1]));
    }
#endif
    for (; i < n; i++) d[i] = (uint8_t)((((r0[i] * w0) >> 8) + ((r1[i] * w1) >> 8) + 128u) >> 8);
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
            uint8_t *d = j->dst + (size_t)y * j->dstride;
            rs_blend(row[0], wy ? row[1] : NULL, wy, d, n);
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
    uint16_t *wt = malloc(8 * (size_t)dw * sizeof *wt);
    if (!x0 || !wt) {
        free(x0), free(wt);
        return VT_ERR_NOMEM;
    }
    uint32_t wide = 0;
    for (uint32_t x = 0; x < dw; x++) {
        uint32_t p;
        uint16_t w1;
        rs_pos(x, dw, sw, &p, &w1);
        x0[x] = 4 * p;
        for (int c = 0; c < 4; c++) wt[8 * x + c] = (uint16_t)(256 - w1), wt[8 * x + 4 + c] = w1;
        if (p + 1 < sw) wide = x + 1; /* x0 rises with x: the columns before it read inside the row too */
    }
    rs_job j = {.sw = sw, .sh = sh, .dw = dw, .dh = dh, .src = src, .sstride = sstride, .dstride = dstride, .dst = dst,
                .x0 = x0, .wt = wt, .wide = wide,
                .nbands = bands < 1 ? 1 : bands > RS_MAX_BANDS ? RS_MAX_BANDS : bands};
    if (j.nbands > dh) j.nbands = dh;
    atomic_init(&j.next, 0);
    if (run && j.nbands > 1) run(run_ctx, rs_band, &j, j.nbands);
    rs_band(&j, 0); /* whatever bands the runner left (none, when it ran them all) */
    free(x0), free(wt);
    for (uint32_t b = 0; b < j.nbands; b++)
        if (j.rc[b]) return j.rc[b];
    return 0;
}
