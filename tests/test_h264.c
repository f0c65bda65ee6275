/*
 * test_h264.c — the H.264 encoder for browser frames (render/vt_h264.h)
 * against an independent decoder, Debian's libavcodec (FFmpeg 5.1's h264
 * decoder, linked into the tests only), and the RGB -> I420 conversion
 * against a slow double-precision reference.
 *
 * Decoded pictures go back to RGB with h264_ref.c's inverse (double,
 * BT.709 limited range, chroma interpolated from where H.264 sites it), so
 * a PSNR here measures the whole path: conversion, x264, decoder, inverse.
 * Sizes are small (the whole file runs in about a second in the release
 * build); one 4096x4096 frame of flat colour checks the largest size.
 */
#include "test_util.h"
#include "vt_h264.h"

#include <stdio.h>
#include <string.h>

#include "h264_ref.h"

/* ---- the decoder (h264_ref.h), asserted --------------------------------- */

typedef h264_dec dec;

static void dec_open(dec *d)
{
    assert_int_equal(h264_dec_open(d), 0);
}

static void dec_close(dec *d)
{
    h264_dec_close(d);
}

/* Decodes one access unit; the picture it gives is d->f (one picture per
 * access unit, nothing held back). */
static void dec_au(dec *d, const uint8_t *au, size_t len)
{
    assert_int_equal(h264_dec_au(d, au, len), 0);
}

#define frame_to_rgb h264_ref_frame_rgb
#define i420_px h264_ref_px
#define i420_to_rgb h264_ref_to_rgb
#define psnr h264_ref_psnr
#define nal_types h264_ref_nal_types

static bool has_type(const int *t, int n, int type)
{
    for (int i = 0; i < n; i++)
        if (t[i] == type) return true;
    return false;
}

/* ---- pictures --------------------------------------------------------- */

/* A smooth picture (gradients and slow waves, what a rendered sky, ground
 * and large surfaces look like) with a soft disc moving with t. */
static void smooth_pic(uint8_t *p, uint32_t w, uint32_t h, size_t stride, uint32_t pb, int t)
{
    for (uint32_t y = 0; y < h; y++)
        for (uint32_t x = 0; x < w; x++) {
            double dx = x - (w * 0.3 + 2.0 * t), dy = y - h * 0.5, disc = exp(-(dx * dx + dy * dy) / (0.02 * w * w));
            double r = 60 + 120 * (double)x / w + 60 * disc;
            double g = 40 + 150 * (double)y / h + 30 * sin((x + 3.0 * t) * 0.05);
            double b = 128 + 90 * sin(x * 0.021 + y * 0.017 + t * 0.1) - 80 * disc;
            uint8_t *o = p + y * stride + x * pb;
            double c[3] = {r, g, b};
            for (int k = 0; k < 3; k++) o[k] = (uint8_t)lround(c[k] < 0 ? 0 : c[k] > 255 ? 255 : c[k]);
            if (pb == 4) o[3] = 0x5a; /* alpha: ignored */
        }
}

static uint8_t *alloc_pic(uint32_t h, size_t stride)
{
    uint8_t *p = malloc(stride * h);
    assert_non_null(p);
    memset(p, 0xee, stride * h); /* the row padding: never read */
    return p;
}

static vt_h264 *open_enc(const vt_h264_cfg *c)
{
    vt_h264 *e = NULL;
    char err[256];
    int rc = vt_h264_open(&e, c, err, sizeof err);
    if (rc) fail_msg("vt_h264_open: %s", err);
    assert_string_equal(err, "");
    return e;
}

typedef struct au_out {
    const uint8_t *p;
    size_t len;
    bool key;
} au_out;

static au_out enc(vt_h264 *e, const uint8_t *pix, size_t stride, uint32_t pb, bool idr)
{
    au_out a;
    char err[256];
    int rc = vt_h264_encode(e, pix, stride, pb, idr, &a.p, &a.len, &a.key, err, sizeof err);
    if (rc) fail_msg("vt_h264_encode: %s", err);
    assert_true(a.p && a.len > 0);
    return a;
}

/* ---- the tests ---------------------------------------------------------- */

/* The first picture: an IDR with SPS and PPS, decoding alone to w x h
 * with the BT.709 limited-range description. The bound: the conversion
 * and inverse alone give 52.7 dB on this picture (8-bit planes, 4:2:0 of
 * smooth colour), CRF 23 brings it to 45.3 (measured: CRF 10 50.1, 20
 * 46.5, 25 44.4, 30 41.2). 40 dB is an RMS error of 2.5 codes, which a
 * wrong matrix (BT.601 coded, 709 decoded: 32.0 dB here) or a picture
 * shifted by a pixel would fall below. */
static void test_h264_first_frame(void **state)
{
    (void)state;
    const uint32_t w = 320, h = 240;
    uint8_t *p = alloc_pic(h, 3 * w);
    smooth_pic(p, w, h, 3 * w, 3, 0);
    vt_h264 *e = open_enc(&(vt_h264_cfg){.width = w, .height = h});
    au_out a = enc(e, p, 3 * w, 3, false);
    assert_true(a.key);
    int t[16], n = nal_types(a.p, a.len, t, 16);
    assert_true(n >= 3 && n <= 16);
    assert_int_equal(t[0], 7); /* SPS, PPS, then the IDR slice (an SEI may sit between) */
    assert_int_equal(t[1], 8);
    assert_true(has_type(t, n, 5) && !has_type(t, n, 1));
    /* constrained baseline: profile_idc 66, constraint_set0 and set1 (the SPS's first bytes) */
    const uint8_t *sps = memchr(a.p + 2, 0x67, 8);
    assert_non_null(sps);
    assert_int_equal(sps[1], 66);
    assert_int_equal(sps[2] & 0xc0, 0xc0);
    dec d;
    dec_open(&d);
    dec_au(&d, a.p, a.len);
    assert_int_equal(d.f->width, w);
    assert_int_equal(d.f->height, h);
    assert_true(d.f->key_frame);
    assert_int_equal(d.f->color_primaries, AVCOL_PRI_BT709);
    assert_int_equal(d.f->color_trc, AVCOL_TRC_BT709);
    assert_int_equal(d.f->colorspace, AVCOL_SPC_BT709);
    assert_int_equal(d.f->color_range, AVCOL_RANGE_MPEG);
    uint8_t *rgb = malloc(3 * (size_t)w * h);
    assert_non_null(rgb);
    frame_to_rgb(d.f, w, h, rgb);
    double q = psnr(rgb, p, 3 * w, 3, w, h);
    if (q < 40) fail_msg("first frame: PSNR %.2f dB < 40", q);
    free(rgb);
    dec_close(&d);
    vt_h264_close(e);
    free(p);
}

/* 30 moving frames (RGBA rows with padding, as the daemon's buffer could
 * be) decode frame for frame, at each speed (x264 preset): one IDR, then P-frames well under its size
 * (the disc and the wave move 2-3 pixels a frame over a still gradient:
 * x264 predicts most of it; measured 10-20 % of the IDR, bound 50 %),
 * each decoded picture within 40 dB of its own source (the first
 * frame's bound) and closer to it than to the source before (it follows
 * the motion rather than repeating a picture). */
static void sequence_at(vt_h264_speed speed)
{
    const uint32_t w = 256, h = 144, pb = 4;
    const size_t stride = 4 * w + 12;
    uint8_t *p = alloc_pic(h, stride), *prev = alloc_pic(h, stride), *rgb = malloc(3 * (size_t)w * h);
    assert_non_null(rgb);
    vt_h264 *e = open_enc(&(vt_h264_cfg){.width = w, .height = h, .fps = 60, .speed = speed});
    dec d;
    dec_open(&d);
    size_t key_len = 0;
    double worst = 99;
    for (int t = 0; t < 30; t++) {
        smooth_pic(p, w, h, stride, pb, t);
        au_out a = enc(e, p, stride, pb, false);
        int ty[16], n = nal_types(a.p, a.len, ty, 16);
        if (t == 0) {
            assert_true(a.key);
            key_len = a.len;
        } else {
            assert_false(a.key);
            assert_int_equal(n, 1);
            assert_int_equal(ty[0], 1);
            if (a.len > key_len / 2) fail_msg("frame %d: %zu bytes, the IDR %zu", t, a.len, key_len);
        }
        dec_au(&d, a.p, a.len);
        assert_int_equal(d.f->width, w);
        assert_int_equal(d.f->height, h);
        frame_to_rgb(d.f, w, h, rgb);
        double q = psnr(rgb, p, stride, pb, w, h);
        if (q < 40) fail_msg("frame %d: PSNR %.2f dB < 40", t, q);
        if (t > 0 && psnr(rgb, prev, stride, pb, w, h) >= q) fail_msg("frame %d: nearer the previous source", t);
        worst = q < worst ? q : worst;
        memcpy(prev, p, stride * h);
    }
    print_message("h264 sequence, speed %d: worst PSNR %.2f dB, IDR %zu bytes\n", speed, worst, key_len);
    dec_close(&d);
    vt_h264_close(e);
    free(p);
    free(prev);
    free(rgb);
}

static void test_h264_sequence(void **state)
{
    (void)state;
    for (int speed = VT_H264_ULTRAFAST; speed <= VT_H264_VERYFAST; speed++) sequence_at((vt_h264_speed)speed);
}

/* force_idr mid-stream: that frame is an IDR carrying SPS and PPS, and it
 * and the frames after it decode in a decoder that never saw the earlier
 * ones (a browser joining late); without keyint or force, no other frame
 * is a key frame. keyint 4: IDRs at 0, 4, 8. */
static void test_h264_force_idr(void **state)
{
    (void)state;
    const uint32_t w = 160, h = 96;
    uint8_t *p = alloc_pic(h, 3 * w), *rgb = malloc(3 * (size_t)w * h);
    assert_non_null(rgb);
    vt_h264 *e = open_enc(&(vt_h264_cfg){.width = w, .height = h});
    dec late = {0};
    for (int t = 0; t < 10; t++) {
        smooth_pic(p, w, h, 3 * w, 3, t);
        au_out a = enc(e, p, 3 * w, 3, t == 6);
        assert_int_equal(a.key, t == 0 || t == 6);
        if (t == 6) {
            int ty[16], n = nal_types(a.p, a.len, ty, 16);
            assert_true(has_type(ty, n, 7) && has_type(ty, n, 8) && has_type(ty, n, 5));
            dec_open(&late);
        }
        if (t >= 6) {
            dec_au(&late, a.p, a.len);
            frame_to_rgb(late.f, w, h, rgb);
            double q = psnr(rgb, p, 3 * w, 3, w, h);
            if (q < 40) fail_msg("late decoder, frame %d: PSNR %.2f dB < 40", t, q);
        }
    }
    dec_close(&late);
    vt_h264_close(e);
    e = open_enc(&(vt_h264_cfg){.width = w, .height = h, .keyint = 4});
    for (int t = 0; t < 10; t++) {
        smooth_pic(p, w, h, 3 * w, 3, t);
        assert_int_equal(enc(e, p, 3 * w, 3, false).key, t % 4 == 0);
    }
    vt_h264_close(e);
    free(p);
    free(rgb);
}

/* Odd sizes: the stream is the size rounded up to even (4:2:0 crops in
 * 2-pixel units, vt_h264.h), the top-left w x h is the picture (40 dB as
 * above), and the padding repeats the last column and row (the strip
 * against the edge it repeats: measured 44-46 dB, the picture's own
 * quality; 36 dB bound, a strip of anything else, black or the next
 * column's mirror, is under 30). */
static void test_h264_odd_sizes(void **state)
{
    (void)state;
    static const uint32_t sz[][2] = {{333, 201}, {201, 333}, {65, 64}, {64, 65}, {3, 3}};
    for (size_t k = 0; k < sizeof sz / sizeof sz[0]; k++) {
        uint32_t w = sz[k][0], h = sz[k][1], cw, ch;
        vt_h264_coded_size(w, h, &cw, &ch);
        assert_true(cw == w + (w & 1) && ch == h + (h & 1));
        uint8_t *p = alloc_pic(h, 3 * w), *rgb = malloc(3 * (size_t)cw * ch);
        assert_non_null(rgb);
        smooth_pic(p, w, h, 3 * w, 3, 0);
        vt_h264 *e = open_enc(&(vt_h264_cfg){.width = w, .height = h});
        au_out a = enc(e, p, 3 * w, 3, false);
        dec d;
        dec_open(&d);
        dec_au(&d, a.p, a.len);
        assert_int_equal(d.f->width, cw);
        assert_int_equal(d.f->height, ch);
        frame_to_rgb(d.f, (int)cw, (int)ch, rgb);
        double q = 99;
        if (w >= 16) {
            /* the picture: rgb has cw columns, so compare row by row */
            uint8_t *crop = malloc(3 * (size_t)w * h);
            assert_non_null(crop);
            for (uint32_t y = 0; y < h; y++) memcpy(crop + 3 * (size_t)y * w, rgb + 3 * (size_t)y * cw, 3 * w);
            q = psnr(crop, p, 3 * w, 3, w, h);
            free(crop);
            if (q < 40) fail_msg("%ux%u: PSNR %.2f dB < 40", w, h, q);
        }
        double se = 0;
        long np = 0;
        for (uint32_t y = 0; y < ch; y++)
            for (uint32_t x = 0; x < cw; x++) {
                if (x < w && y < h) continue;
                const uint8_t *src = p + 3 * ((y < h ? y : h - 1) * (size_t)w + (x < w ? x : w - 1));
                for (int c = 0; c < 3; c++) {
                    double dd = rgb[3 * ((size_t)y * cw + x) + c] - src[c];
                    se += dd * dd, np++;
                }
            }
        double qpad = np ? 10 * log10(65025 / fmax(se / (double)np, 1e-9)) : 99;
        print_message("h264 %ux%u: PSNR %.2f dB, the padding against the edge %.2f dB\n", w, h, q, qpad);
        /* 3x3 is one chroma sample a 2x2 block of a steep picture: its size is what counts */
        if (w >= 16 && qpad < 36) fail_msg("%ux%u: the padding is not the edge repeated: %.2f dB", w, h, qpad);
        dec_close(&d);
        vt_h264_close(e);
        free(p);
        free(rgb);
    }
}

/* The reference conversion in double of pixel (x, y) of pix (w x h), the
 * coded-size padding by repetition, chroma at (2i, 2j + 0.5): [1 2 1] / 4
 * across, the two rows averaged. */
static uint8_t ref_px(const uint8_t *pix, size_t stride, uint32_t pb, uint32_t w, uint32_t h, int x, int y, int c)
{
    x = x < 0 ? 0 : x >= (int)w ? (int)w - 1 : x;
    y = y >= (int)h ? (int)h - 1 : y;
    return pix[(size_t)y * stride + (size_t)x * pb + (size_t)c];
}

static void ref_i420(const uint8_t *pix, size_t stride, uint32_t pb, uint32_t w, uint32_t h, int x, int y,
                     double *yy, double *cb, double *cr)
{
    const double kr = 0.2126, kb = 0.0722, kg = 1 - kr - kb;
    double rgb[3];
    for (int c = 0; c < 3; c++) rgb[c] = ref_px(pix, stride, pb, w, h, x, y, c) / 255.0;
    *yy = 16 + 219 * (kr * rgb[0] + kg * rgb[1] + kb * rgb[2]);
    if (cb) {
        double a[3] = {0, 0, 0};
        static const double wt[3] = {0.25, 0.5, 0.25};
        for (int dy = 0; dy < 2; dy++)
            for (int dx = -1; dx <= 1; dx++)
                for (int c = 0; c < 3; c++)
                    a[c] += 0.5 * wt[dx + 1] * ref_px(pix, stride, pb, w, h, x + dx, y + dy, c) / 255;
        double ya = kr * a[0] + kg * a[1] + kb * a[2];
        *cb = 128 + 224 * (a[2] - ya) / (2 * (1 - kb));
        *cr = 128 + 224 * (a[0] - ya) / (2 * (1 - kr));
    }
}

/* Every sample of random pictures (noise: every code, every neighbour),
 * primaries and extremes, odd and even sizes, RGB and RGBA with row
 * padding, against the double-precision reference: at most 1 code off
 * (the fixed point's 2^-16 coefficients, vt_h264.c), and nearly all exact. */
static void test_h264_convert(void **state)
{
    (void)state;
    rng r = {test_seed() ^ 0x264};
    static const uint32_t sz[][3] = {{1, 1, 3}, {2, 2, 4}, {5, 3, 3}, {64, 48, 4}, {97, 31, 3}, {255, 17, 4}};
    long exact = 0, total = 0;
    for (size_t k = 0; k < sizeof sz / sizeof sz[0]; k++) {
        uint32_t w = sz[k][0], h = sz[k][1], pb = sz[k][2], cw, ch;
        size_t stride = (size_t)w * pb + 5;
        vt_h264_coded_size(w, h, &cw, &ch);
        uint8_t *p = alloc_pic(h, stride);
        for (uint32_t y = 0; y < h; y++)
            for (uint32_t x = 0; x < w; x++)
                for (uint32_t c = 0; c < pb; c++) {
                    /* corners: black, white and the primaries; else noise */
                    uint32_t m = (x + y) % 8;
                    p[y * stride + x * pb + c] =
                        (uint8_t)(x < 2 && y < 2 ? (m & (1u << c) ? 255 : 0) : rng_below(&r, 256));
                }
        uint8_t *yp = malloc((size_t)cw * ch), *up = malloc((size_t)cw * ch / 4 + 1);
        uint8_t *vp = malloc((size_t)cw * ch / 4 + 1);
        assert_true(yp && up && vp);
        assert_int_equal(vt_h264_rgb_to_i420(w, h, p, stride, pb, yp, cw, up, cw / 2, vp, cw / 2), 0);
        for (uint32_t y = 0; y < ch; y++)
            for (uint32_t x = 0; x < cw; x++) {
                double yy, cb, cr;
                bool c = x % 2 == 0 && y % 2 == 0;
                ref_i420(p, stride, pb, w, h, (int)x, (int)y, &yy, c ? &cb : NULL, c ? &cr : NULL);
                size_t ci = y / 2 * (cw / 2) + x / 2;
                double got[3] = {yp[y * cw + x], c ? up[ci] : 0, c ? vp[ci] : 0};
                double want[3] = {yy, c ? cb : 0, c ? cr : 0};
                for (int s = 0; s < (c ? 3 : 1); s++) {
                    double d = fabs(got[s] - floor(want[s] + 0.5));
                    if (d > 1) fail_msg("%ux%u (%u, %u) plane %d: %g, exact %.4f", w, h, x, y, s, got[s], want[s]);
                    exact += d == 0, total++;
                }
            }
        free(yp), free(up), free(vp), free(p);
    }
    print_message("h264 convert: %ld of %ld samples exact\n", exact, total);
    assert_true(exact >= total - total / 100); /* off by one only within 0.006 of a half */
}

/* The AVX2 rows (vt_h264_avx2.c) against the scalar rows (VANTAGE_ISA=
 * scalar), byte for byte: the same integer sums, so the same planes, for
 * widths around the 16-column step (the lanes' blocks, then the scalar
 * tail) and odd sizes, RGB and RGBA. Where the CPU or the build has no
 * AVX2 both runs are scalar and the test says so. */
static void test_h264_convert_isa(void **state)
{
    (void)state;
    rng r = {test_seed() ^ 0x1a};
    static const uint32_t sz[][3] = {{16, 2, 4}, {17, 3, 4}, {31, 4, 3}, {32, 5, 4}, {33, 6, 3}, {48, 7, 4},
                                     {250, 9, 4}, {1280, 4, 4}, {1279, 3, 3}};
    char *saved = test_env_keep("VANTAGE_ISA");
    for (size_t k = 0; k < sizeof sz / sizeof sz[0]; k++) {
        uint32_t w = sz[k][0], h = sz[k][1], pb = sz[k][2], cw, ch;
        size_t stride = (size_t)w * pb + 3;
        vt_h264_coded_size(w, h, &cw, &ch);
        uint8_t *p = alloc_pic(h, stride);
        for (size_t i = 0; i < stride * h; i++) p[i] = (uint8_t)rng_below(&r, 256);
        size_t ny = (size_t)cw * ch, nc = ny / 4;
        uint8_t *a = malloc(ny + 2 * nc), *b = malloc(ny + 2 * nc);
        assert_true(a && b);
        setenv("VANTAGE_ISA", "scalar", 1);
        assert_int_equal(vt_h264_rgb_to_i420(w, h, p, stride, pb, a, cw, a + ny, cw / 2, a + ny + nc, cw / 2), 0);
        unsetenv("VANTAGE_ISA");
        assert_int_equal(vt_h264_rgb_to_i420(w, h, p, stride, pb, b, cw, b + ny, cw / 2, b + ny + nc, cw / 2), 0);
        for (size_t i = 0; i < ny + 2 * nc; i++)
            if (a[i] != b[i])
                fail_msg("%ux%u (%u bytes a pixel): plane byte %zu: scalar %d, lanes %d", w, h, pb, i, a[i], b[i]);
        free(a), free(b), free(p);
    }
    test_env_restore("VANTAGE_ISA", saved);
    if (cull_isa_default() != CULL_ISA_AVX2) print_message("h264 convert isa: no AVX2 rows here, scalar against scalar\n");
}

/* Flat colour patches (a cube of 9^3 colours, edges included) through the
 * conversion and the inverse back to RGB8: quantising Y to 1/219 and
 * Cb/Cr to 1/224 of the range leaves at most 0.5 * 255/219 = 0.58 of a
 * code from Y plus 0.5 * 255/224 * 2 (1 - Kb) = 1.06 from Cb (B; R from
 * Cr: 0.90, G from both: 0.42), so within 1.64 + rounding: 2 codes. */
static void test_h264_roundtrip_flat(void **state)
{
    (void)state;
    const uint32_t w = 6, h = 4; /* odd chroma columns too: the filter sees the patch's own colour at the edge */
    uint8_t p[6 * 4 * 3], yp[6 * 4], up[3 * 2], vp[3 * 2], rgb[6 * 4 * 3];
    int worst = 0;
    for (int ri = 0; ri < 9; ri++)
        for (int gi = 0; gi < 9; gi++)
            for (int bi = 0; bi < 9; bi++) {
                uint8_t c[3] = {(uint8_t)(ri * 255 / 8), (uint8_t)(gi * 255 / 8), (uint8_t)(bi * 255 / 8)};
                for (uint32_t i = 0; i < w * h; i++) memcpy(p + 3 * i, c, 3);
                assert_int_equal(vt_h264_rgb_to_i420(w, h, p, 3 * w, 3, yp, w, up, w / 2, vp, w / 2), 0);
                const uint8_t *pl[3] = {yp, up, vp};
                const int st[3] = {(int)w, (int)w / 2, (int)w / 2};
                i420_to_rgb(pl, st, (int)w, (int)h, (int)w, (int)h, rgb);
                for (uint32_t i = 0; i < 3 * w * h; i++) {
                    int d = abs(rgb[i] - p[i]);
                    worst = d > worst ? d : worst;
                    if (d > 2) fail_msg("colour %d %d %d channel %u: back as %d", c[0], c[1], c[2], i % 3, rgb[i]);
                }
            }
    print_message("h264 flat round trip: worst %d codes\n", worst);
}

/* Pictures a codec finds hard or degenerate: noise (every macroblock
 * intra-worst), all black, all white, 2x2, and 4096x4096 (the largest:
 * flat grey with a ramp, cheap to code). Each decodes to its size;
 * the flat ones to within 2 codes of their colour (the round trip above);
 * noise keeps its mean and some of its detail. */
static void test_h264_adversarial(void **state)
{
    (void)state;
    rng r = {test_seed() ^ 0xad};
    static const struct { uint32_t w, h; int kind; } cases[] = {
        {128, 96, 0}, {128, 96, 1}, {128, 96, 2}, {2, 2, 1}, {2, 2, 2}, {2, 2, 0}, {4096, 4096, 3},
    };
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        uint32_t w = cases[k].w, h = cases[k].h;
        int kind = cases[k].kind;
        uint8_t *p = alloc_pic(h, 3 * (size_t)w), *rgb = kind == 0 ? malloc(3 * (size_t)w * h) : NULL;
        assert_true(kind || rgb);
        for (size_t i = 0; i < 3 * (size_t)w * h; i++)
            p[i] = kind == 0 ? (uint8_t)rng_below(&r, 256) : kind == 1 ? 0 : kind == 2 ? 255
                 : (uint8_t)(100 + (i / 3 % w) * 40 / w);
        vt_h264 *e = open_enc(&(vt_h264_cfg){.width = w, .height = h});
        dec d;
        dec_open(&d);
        for (int t = 0; t < 2; t++) { /* an IDR, then a P-frame of the same */
            au_out a = enc(e, p, 3 * (size_t)w, 3, false);
            assert_int_equal(a.key, t == 0);
            dec_au(&d, a.p, a.len);
            assert_int_equal(d.f->width, w);
            assert_int_equal(d.f->height, h);
            if (kind == 0) {
                frame_to_rgb(d.f, (int)w, (int)h, rgb);
                /* noise keeps its mean (CRF's DC), and more than the mean:
                   a flat picture of it would be 10.8 dB (uniform noise's
                   variance 65536 / 12); measured 12.2 */
                double q = psnr(rgb, p, 3 * (size_t)w, 3, w, h), m[2][3] = {{0}};
                for (size_t i = 0; i < 3 * (size_t)w * h; i++) m[0][i % 3] += rgb[i], m[1][i % 3] += p[i];
                for (int c = 0; c < 3 && w > 2; c++) /* 2x2: one chroma sample for 4 random colours */
                    if (fabs(m[0][c] - m[1][c]) > 2.0 * w * h)
                        fail_msg("noise: channel %d mean %.2f, source %.2f", c, m[0][c] / w / h,
                                 m[1][c] / w / h);
                if (w > 2 && q < 11) fail_msg("noise %ux%u: PSNR %.2f dB", w, h, q);
                continue;
            }
            /* flat and the ramp: every pixel of the small ones, a grid of
               rows and columns 61 apart (and the last) of 4096x4096 */
            const uint8_t *pl[3] = {d.f->data[0], d.f->data[1], d.f->data[2]};
            const int st[3] = {d.f->linesize[0], d.f->linesize[1], d.f->linesize[2]};
            uint32_t step = w > 256 ? 61 : 1;
            for (uint32_t y = 0; y < h; y = y + step < h || y == h - 1 ? y + step : h - 1)
                for (uint32_t x = 0; x < w; x = x + step < w || x == w - 1 ? x + step : w - 1) {
                    uint8_t o[3];
                    i420_px(pl, st, (int)w, (int)h, (int)x, (int)y, o);
                    for (int c = 0; c < 3; c++)
                        if (abs(o[c] - p[3 * ((size_t)y * w + x) + (size_t)c]) > 2)
                            fail_msg("kind %d %ux%u (%u, %u): %d for %d", kind, w, h, x, y, o[c],
                                     p[3 * ((size_t)y * w + x) + (size_t)c]);
                }
        }
        dec_close(&d);
        vt_h264_close(e);
        free(p);
        free(rgb);
    }
}

/* Random sizes (2..300 each way), layouts (RGB or RGBA, row padding) and
 * settings (CRF, cap, fps, keyint, threads, speed) across their ranges:
 * every stream opens, its two pictures decode to the coded size, the
 * first is the IDR and the second follows keyint (1: an IDR too). */
static void test_h264_random_configs(void **state)
{
    (void)state;
    rng r = {test_seed() ^ 0x7a};
    int n = (int)(24 * test_scale());
    for (int k = 0; k < (n > 4 ? n : 4); k++) {
        uint32_t w = 2 + rng_below(&r, 299), h = 2 + rng_below(&r, 299), pb = 3 + rng_below(&r, 2), cw, ch;
        size_t stride = (size_t)w * pb + rng_below(&r, 9);
        vt_h264_cfg c = {.width = w, .height = h, .crf_x10 = (int)(10 + rng_below(&r, 501)),
                         .max_kbps = rng_below(&r, 2) ? 1 + rng_below(&r, 20000) : 0, .fps = 1 + rng_below(&r, 240),
                         .keyint = rng_below(&r, 3), .threads = 1 + (int)rng_below(&r, 3),
                         .speed = (vt_h264_speed)rng_below(&r, 3)};
        vt_h264_coded_size(w, h, &cw, &ch);
        uint8_t *p = alloc_pic(h, stride);
        smooth_pic(p, w, h, stride, pb, k);
        vt_h264 *e = open_enc(&c);
        dec d;
        dec_open(&d);
        for (int t = 0; t < 2; t++) {
            au_out a = enc(e, p, stride, pb, false);
            if (a.key != (t == 0 || c.keyint == 1))
                fail_msg("%ux%u crf %d keyint %u: frame %d key %d", w, h, c.crf_x10, c.keyint, t, a.key);
            dec_au(&d, a.p, a.len);
            assert_int_equal(d.f->width, cw);
            assert_int_equal(d.f->height, ch);
        }
        dec_close(&d);
        vt_h264_close(e);
        free(p);
    }
}

/* A VBV cap holds noise (the worst case: CRF 23 gives it tens of kB a
 * frame) to about its share: 2000 kbit/s at 30 fps is 8.3 kB a frame.
 * x264 aims the buffer, not each frame, and an IDR at the start may
 * overshoot, so the P-frames' mean must be within 1.5x the share, and
 * far under the uncapped stream's. */
static void test_h264_vbv_cap(void **state)
{
    (void)state;
    rng r = {test_seed() ^ 0xcb};
    const uint32_t w = 192, h = 128, n = 8;
    uint8_t *p = alloc_pic(h, 3 * w);
    double mean[2] = {0, 0};
    for (int capped = 0; capped < 2; capped++) {
        vt_h264 *e = open_enc(&(vt_h264_cfg){.width = w, .height = h, .fps = 30, .max_kbps = capped ? 2000 : 0});
        for (uint32_t t = 0; t < n; t++) {
            for (size_t i = 0; i < 3 * (size_t)w * h; i++) p[i] = (uint8_t)rng_below(&r, 256);
            au_out a = enc(e, p, 3 * w, 3, false);
            if (t) mean[capped] += (double)a.len / (n - 1);
        }
        vt_h264_close(e);
    }
    print_message("h264 vbv: noise P-frames %.0f bytes uncapped, %.0f capped at 8333\n", mean[0], mean[1]);
    assert_true(mean[1] < 1.5 * 2000000 / 8 / 30);
    assert_true(mean[1] < mean[0] / 2);
    free(p);
}

/* ---- bad input -------------------------------------------------------- */

typedef struct bad_cfg_row {
    const char *name;
    vt_h264_cfg cfg;
    int want;
} bad_cfg_row;

static const bad_cfg_row bad_cfgs[] = {
    {"width 0", {.width = 0, .height = 16}, VT_ERR_INVALID},
    {"height 0", {.width = 16, .height = 0}, VT_ERR_INVALID},
    {"width 1", {.width = 1, .height = 16}, VT_ERR_INVALID},
    {"width 4097", {.width = 4097, .height = 16}, VT_ERR_TOO_LARGE},
    {"height 4097", {.width = 16, .height = 4097}, VT_ERR_TOO_LARGE},
    {"width 2^32 - 1", {.width = UINT32_MAX, .height = 16}, VT_ERR_TOO_LARGE},
    {"crf 0.9", {.width = 16, .height = 16, .crf_x10 = 9}, VT_ERR_INVALID},
    {"crf 51.1", {.width = 16, .height = 16, .crf_x10 = 511}, VT_ERR_INVALID},
    {"crf negative", {.width = 16, .height = 16, .crf_x10 = -230}, VT_ERR_INVALID},
    {"crf INT_MIN", {.width = 16, .height = 16, .crf_x10 = INT32_MIN}, VT_ERR_INVALID},
    {"fps 1001", {.width = 16, .height = 16, .fps = 1001}, VT_ERR_INVALID},
    {"max_kbps over 10^6", {.width = 16, .height = 16, .max_kbps = 1000001}, VT_ERR_INVALID},
    {"keyint 65536", {.width = 16, .height = 16, .keyint = 65536}, VT_ERR_INVALID},
    {"threads 17", {.width = 16, .height = 16, .threads = 17}, VT_ERR_INVALID},
    {"threads -1", {.width = 16, .height = 16, .threads = -1}, VT_ERR_INVALID},
    {"speed 3", {.width = 16, .height = 16, .speed = (vt_h264_speed)3}, VT_ERR_INVALID},
    {"speed -1", {.width = 16, .height = 16, .speed = (vt_h264_speed)-1}, VT_ERR_INVALID},
};

static void test_h264_bad_cfg(void **state)
{
    const bad_cfg_row *row = *state;
    vt_h264 *e = (vt_h264 *)(uintptr_t)1;
    char err[256] = "unchanged";
    assert_int_equal(vt_h264_open(&e, &row->cfg, err, sizeof err), row->want);
    assert_null(e);
    assert_true(strncmp(err, "h264: ", 6) == 0);
    print_message("%s: %s\n", row->name, err);
}

/* NULL arguments and bad pictures: a clear code and message, nothing out,
 * and the encoder goes on (the next good picture is still the first, an
 * IDR; the one after it a P-frame). */
static void test_h264_bad_args(void **state)
{
    (void)state;
    char err[256];
    assert_int_equal(vt_h264_open(NULL, &(vt_h264_cfg){.width = 16, .height = 16}, err, sizeof err), VT_ERR_INVALID);
    vt_h264 *e = NULL;
    assert_int_equal(vt_h264_open(&e, NULL, err, sizeof err), VT_ERR_INVALID);
    assert_null(e);
    vt_h264_close(NULL);
    e = open_enc(&(vt_h264_cfg){.width = 16, .height = 16, .crf_x10 = 510, .max_kbps = 1, .fps = 1000, .threads = 16});
    uint8_t p[16 * 16 * 4] = {0};
    const uint8_t *au = (const uint8_t *)p;
    size_t len = 7;
    bool key = true;
    assert_int_equal(vt_h264_encode(e, NULL, 48, 3, false, &au, &len, &key, err, sizeof err), VT_ERR_INVALID);
    assert_true(au == NULL && len == 0 && !key && strlen(err) > 6);
    assert_int_equal(vt_h264_encode(e, p, 47, 3, false, &au, &len, &key, err, sizeof err), VT_ERR_INVALID);
    assert_non_null(strstr(err, "stride"));
    assert_int_equal(vt_h264_encode(e, p, 63, 4, false, &au, &len, &key, err, sizeof err), VT_ERR_INVALID);
    assert_int_equal(vt_h264_encode(e, p, 64, 2, false, &au, &len, &key, err, sizeof err), VT_ERR_INVALID);
    assert_int_equal(vt_h264_encode(e, p, 64, 4, false, NULL, &len, &key, err, sizeof err), VT_ERR_INVALID);
    assert_int_equal(vt_h264_encode(NULL, p, 64, 4, false, &au, &len, &key, err, sizeof err), VT_ERR_INVALID);
    assert_true(enc(e, p, 64, 4, false).key);
    assert_false(enc(e, p, 64, 4, false).key);
    vt_h264_close(e);
    /* the conversion alone */
    uint8_t y[4], u[1], v[1];
    assert_int_equal(vt_h264_rgb_to_i420(0, 2, p, 6, 3, y, 2, u, 1, v, 1), VT_ERR_INVALID);
    assert_int_equal(vt_h264_rgb_to_i420(4097, 2, p, 6, 3, y, 2, u, 1, v, 1), VT_ERR_TOO_LARGE);
    assert_int_equal(vt_h264_rgb_to_i420(2, 2, p, 5, 3, y, 2, u, 1, v, 1), VT_ERR_INVALID);
    assert_int_equal(vt_h264_rgb_to_i420(2, 2, p, 6, 3, y, 1, u, 1, v, 1), VT_ERR_INVALID);
    assert_int_equal(vt_h264_rgb_to_i420(2, 2, p, 6, 3, NULL, 2, u, 1, v, 1), VT_ERR_INVALID);
    assert_int_equal(vt_h264_rgb_to_i420(2, 2, p, 6, 3, y, 2, u, 1, v, 1), 0);
}

const struct CMUnitTest h264_tests[] = {
    cmocka_unit_test(test_h264_first_frame),
    cmocka_unit_test(test_h264_sequence),
    cmocka_unit_test(test_h264_force_idr),
    cmocka_unit_test(test_h264_odd_sizes),
    cmocka_unit_test(test_h264_convert),
    cmocka_unit_test(test_h264_convert_isa),
    cmocka_unit_test(test_h264_roundtrip_flat),
    cmocka_unit_test(test_h264_adversarial),
    cmocka_unit_test(test_h264_random_configs),
    cmocka_unit_test(test_h264_vbv_cap),
    TEST_ROWS(test_h264_bad_cfg, bad_cfgs),
    cmocka_unit_test(test_h264_bad_args),
};
const size_t h264_tests_count = sizeof h264_tests / sizeof h264_tests[0];
