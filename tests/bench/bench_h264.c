/*
 * bench_h264.c — H.264 (render/vt_h264.h) against JPEG for the browser
 * frames of issue 21: bytes a frame and quality on the demo city, and the
 * encoder's time a frame (a benchmark: it fails on nothing but errors).
 *
 *   bench_h264 [--size WxH] [--frames N] [--orbit DEG] [--crf A,B,..] [--quality A,B,..]
 *              [--big WxH] [--big-frames N] [--speed 0|1|2] [--threads N] [--json] [--smoke]
 *   bench_h264 --motion [--size WxH] [--frames N] [--orbit DEG] [--json] [--smoke]
 *
 * The frames: the demo city as bench_render draws it (bench_city.c: the
 * daemon's scene and software renderer, 2 threads) from a street camera
 * orbiting its target, 60 frames of 0.5 degrees (15 degrees a second at
 * 30 frames/s: a viewer dragging the view; the eye 300 m out, 20 m up, so
 * near buildings move tens of pixels a frame), 1280x720, each tone mapped
 * as the daemon does (ACES, exposure 0, to RGBA8). Each frame then goes
 * to every encoder: JPEG at each quality (vt_jpeg_encode, one band; the
 * clients' default is 80, bench_render's 85) and one H.264 stream per CRF
 * (vt_h264, the first frame the IDR, the rest P-frames). Every output is
 * decoded (libjpeg; libavcodec with h264_ref.c's exact BT.709 inverse)
 * and compared with the tone-mapped RGB8 the encoders were given: PSNR
 * over R, G and B. Reported per encoder: the first (key) frame's bytes, the
 * median and mean bytes a frame, mean and worst PSNR, median ms a frame
 * (H.264: conversion + x264; the conversion alone is a line of its own).
 * Then, for each JPEG quality, the H.264 bytes at JPEG's mean PSNR
 * (log-bytes interpolated between the two CRFs around it) and the ratio.
 * Last the encoder's time alone at --size and at --big (1920x1080),
 * --big-frames frames of the same orbit each, CRF 23, no decoding.
 *
 * --motion: the daemon's dynamic resolution instead (a moving stream's
 * frame drawn at a fraction of each side, tone mapped, scaled up by
 * vt_image_resize_rgba8): for each scale, the median time to draw the
 * frame (bench_city_draw: cull and render on 2 threads) and to scale it
 * up, and the PSNR of the scaled-up picture against the full-size one
 * (both tone mapped, before any encoder), over the orbit's frames.
 *
 * --threads: vt_h264_cfg.threads (x264's sliced threads; 1, the default,
 * is what the daemon gives a stream among several). --speed: vt_h264_cfg.speed (0 ultrafast, the default; 1 superfast; 2
 * veryfast). --json: one object a line ({codec, ...}); --smoke: 320x180,
 * 4 frames, 2 big frames at 640x360.
 */
#include "bench_city.h"
#include "bench_util.h"
#include "culling.h"
#include "h264_ref.h"
#include "vt_h264.h"
#include "vt_image.h"
#include "vt_soft.h"

#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define MAX_CODECS 16

/* One encoder's results over the run. */
typedef struct codec {
    char name[32];
    int jpeg_q;         /* > 0: JPEG at this quality */
    int crf_x10;        /* else H.264 at this CRF */
    vt_h264 *enc;
    h264_dec dec;
    double *bytes, *psnr, *ms;
} codec;

static int parse_list(const char *s, int *v, int cap, double scale)
{
    int n = 0;
    while (*s && n < cap) {
        char *end;
        double x = strtod(s, &end);
        if (end == s) return -1;
        v[n++] = (int)lround(x * scale);
        s = *end == ',' ? end + 1 : end;
        if (*end && *end != ',') return -1;
    }
    return n;
}

static double mean_of(const double *v, int n)
{
    double s = 0;
    for (int i = 0; i < n; i++) s += v[i];
    return s / n;
}

static double median_of(const double *v, int n)
{
    double *c = malloc((size_t)n * sizeof *c);
    if (!c) return NAN;
    memcpy(c, v, (size_t)n * sizeof *c);
    double m = bench_median(c, n);
    free(c);
    return m;
}

static double min_of(const double *v, int n)
{
    double m = v[0];
    for (int i = 1; i < n; i++) m = v[i] < m ? v[i] : m;
    return m;
}

/* The orbit's eye at frame k: around the target, deg degrees a frame. */
static void orbit_eye(int k, double deg, double eye[3])
{
    double a = k * deg * M_PI / 180;
    eye[0] = -300 * sin(a), eye[1] = 20, eye[2] = -300 * cos(a);
}

/* The daemon's tone map of a rendered frame (rows bottom-up) to RGBA8, top row first. */
static int tonemap(uint32_t W, uint32_t H, const float *rgba, uint8_t *rgba8)
{
    const float *top = rgba + (size_t)(H - 1) * W * 4;
    ptrdiff_t ys = -(ptrdiff_t)W * 4;
    vt_image_src src = {.r = {top, 4, ys}, .g = {top + 1, 4, ys}, .b = {top + 2, 4, ys}};
    vt_tonemap_desc td = {.op = VT_TONEMAP_ACES};
    return vt_image_tonemap(W, H, &src, &td, rgba8, 4 * (size_t)W);
}

/* One frame through codec c: encode, decode, PSNR against rgba8. */
static int run_codec(codec *c, int k, uint32_t W, uint32_t H, const uint8_t *rgba8, uint8_t *rgb)
{
    char err[512];
    double t0 = bench_now_ns();
    if (c->jpeg_q) {
        uint8_t *jpg = NULL, *dec = NULL;
        size_t len = 0;
        uint32_t dw, dh;
        if (vt_jpeg_encode(W, H, rgba8, 4 * (size_t)W, 4, c->jpeg_q, &jpg, &len, err, sizeof err)) goto fail;
        c->ms[k] = (bench_now_ns() - t0) / 1e6;
        c->bytes[k] = (double)len;
        int rc = vt_jpeg_decode(jpg, len, &dec, &dw, &dh, err, sizeof err);
        free(jpg);
        if (rc) goto fail;
        c->psnr[k] = h264_ref_psnr(dec, rgba8, 4 * (size_t)W, 4, W, H);
        free(dec);
        return 0;
    }
    const uint8_t *au;
    size_t len;
    bool key;
    if (vt_h264_encode(c->enc, rgba8, 4 * (size_t)W, 4, false, &au, &len, &key, err, sizeof err)) goto fail;
    c->ms[k] = (bench_now_ns() - t0) / 1e6;
    c->bytes[k] = (double)len;
    if (key != (k == 0)) {
        snprintf(err, sizeof err, "frame %d: key %d", k, key);
        goto fail;
    }
    if (h264_dec_au(&c->dec, au, len)) {
        snprintf(err, sizeof err, "libavcodec refused frame %d", k);
        goto fail;
    }
    h264_ref_frame_rgb(c->dec.f, (int)W, (int)H, rgb);
    c->psnr[k] = h264_ref_psnr(rgb, rgba8, 4 * (size_t)W, 4, W, H);
    return 0;
fail:
    fprintf(stderr, "bench_h264: %s: %s\n", c->name, err);
    return -1;
}

static void report_codec(const codec *c, int n, uint32_t W, uint32_t H, bool json)
{
    double key = c->bytes[0], med = median_of(c->bytes + (c->jpeg_q ? 0 : 1), c->jpeg_q ? n : n - 1);
    double mean = mean_of(c->bytes, n), q = mean_of(c->psnr, n), qmin = min_of(c->psnr, n), ms = median_of(c->ms, n);
    if (json)
        printf("{\"codec\":\"%s\",\"width\":%u,\"height\":%u,\"frames\":%d,\"first_bytes\":%.0f,"
               "\"median_bytes\":%.0f,\"mean_bytes\":%.0f,\"mean_psnr_db\":%.3f,\"min_psnr_db\":%.3f,"
               "\"median_ms\":%.3f}\n",
               c->name, W, H, n, key, med, mean, q, qmin, ms);
    else
        printf("%-10s first %8.0f  median %8.0f  mean %8.0f bytes   PSNR mean %6.2f  worst %6.2f dB   %6.2f ms\n",
               c->name, key, med, mean, q, qmin, ms);
}

/* For each JPEG: the H.264 mean bytes at its mean PSNR, log-interpolated
 * between the CRFs on either side (none when no two bracket it). */
static void equal_quality(const codec *cs, int nc, int n, bool json)
{
    for (int j = 0; j < nc; j++) {
        if (!cs[j].jpeg_q) continue;
        double qj = mean_of(cs[j].psnr, n), bj = mean_of(cs[j].bytes, n);
        const codec *lo = NULL, *hi = NULL; /* the H.264 runs just under and just over qj */
        for (int i = 0; i < nc; i++) {
            if (cs[i].jpeg_q) continue;
            double qi = mean_of(cs[i].psnr, n);
            if (qi <= qj && (!lo || qi > mean_of(lo->psnr, n))) lo = &cs[i];
            if (qi >= qj && (!hi || qi < mean_of(hi->psnr, n))) hi = &cs[i];
        }
        if (!lo || !hi) {
            printf("%s: mean PSNR %.2f dB outside the CRFs' range; add CRFs (--crf)\n", cs[j].name, qj);
            continue;
        }
        double ql = mean_of(lo->psnr, n), qh = mean_of(hi->psnr, n);
        double bl = log(mean_of(lo->bytes, n)), bh = log(mean_of(hi->bytes, n));
        double t = qh > ql ? (qj - ql) / (qh - ql) : 0, b = exp(bl + t * (bh - bl));
        double crf = (lo->crf_x10 + t * (hi->crf_x10 - lo->crf_x10)) / 10;
        if (json)
            printf("{\"equal_quality\":\"%s\",\"psnr_db\":%.3f,\"jpeg_mean_bytes\":%.0f,\"h264_crf\":%.2f,"
                   "\"h264_mean_bytes\":%.0f,\"ratio\":%.3f}\n",
                   cs[j].name, qj, bj, crf, b, bj / b);
        else
            printf("equal quality: %s (%.2f dB, %.0f bytes a frame) = H.264 at CRF %.1f, %.0f bytes: %.2fx smaller\n",
                   cs[j].name, qj, bj, crf, b, bj / b);
    }
}

static int g_threads = 1; /* --threads */

/* --motion: the scales of each side the daemon may draw a moving frame at */
static const double motion_scales[] = {0.25, 1.0 / 3, 0.4, 0.5, 0.6, 0.75, 1.0};
#define NSCALES (sizeof motion_scales / sizeof motion_scales[0])

static int motion_study(bench_city_scene *city, vt_soft *sr, uint32_t W, uint32_t H, int n, double deg, bool json)
{
    float *rgba = malloc((size_t)W * H * 4 * sizeof *rgba), *depth = malloc((size_t)W * H * sizeof *depth);
    uint8_t *full = malloc(vt_image_rgba8_size(W, H)), *up = malloc(vt_image_rgba8_size(W, H)),
            *small = malloc(vt_image_rgba8_size(W, H));
    double *draw = calloc((size_t)n * NSCALES, sizeof *draw), *scale_ms = calloc((size_t)n * NSCALES, sizeof *draw),
           *psnr = calloc((size_t)n * NSCALES, sizeof *draw);
    int rc = -1;
    if (!rgba || !depth || !full || !up || !small || !draw || !scale_ms || !psnr) goto out;
    if (!json) printf("dynamic resolution: the street orbit at %ux%u, %d frames; each scale drawn, tone mapped, "
                      "scaled up; PSNR against the full-size frame\n", W, H, n);
    for (int k = 0; k < n; k++) {
        double eye[3], at[3] = {0, 2, 0};
        orbit_eye(k, deg, eye);
        if (bench_city_draw(city, sr, eye, at, W, H, rgba, depth) || tonemap(W, H, rgba, full)) goto out;
        for (size_t s = 0; s < NSCALES; s++) {
            uint32_t w = (uint32_t)lrint(W * motion_scales[s]), h = (uint32_t)lrint(H * motion_scales[s]);
            double t0 = bench_now_ns();
            if (bench_city_draw(city, sr, eye, at, w, h, rgba, depth)) goto out;
            double t1 = bench_now_ns();
            if (tonemap(w, h, rgba, small)) goto out;
            double t2 = bench_now_ns();
            if (vt_image_resize_rgba8(w, h, small, 4 * (size_t)w, W, H, up, 4 * (size_t)W, 1, NULL, NULL)) goto out;
            double t3 = bench_now_ns();
            draw[s * n + k] = (t1 - t0) / 1e6;
            scale_ms[s * n + k] = (t3 - t2) / 1e6;
            /* RGB of the scaled-up picture against the full one's RGBA */
            for (size_t i = 0; i < (size_t)W * H; i++) memmove(small + 3 * i, up + 4 * i, 3);
            psnr[s * n + k] = h264_ref_psnr(small, full, 4 * (size_t)W, 4, W, H);
        }
    }
    for (size_t s = 0; s < NSCALES; s++) {
        uint32_t w = (uint32_t)lrint(W * motion_scales[s]), h = (uint32_t)lrint(H * motion_scales[s]);
        double d = median_of(draw + s * n, n), sc = median_of(scale_ms + s * n, n), q = mean_of(psnr + s * n, n),
               qmin = min_of(psnr + s * n, n);
        if (json)
            printf("{\"motion_scale\":%.4f,\"width\":%u,\"height\":%u,\"frames\":%d,\"median_draw_ms\":%.3f,"
                   "\"median_scale_up_ms\":%.3f,\"mean_psnr_db\":%.3f,\"min_psnr_db\":%.3f}\n",
                   motion_scales[s], w, h, n, d, sc, q, qmin);
        else
            printf("scale %.3f (%ux%u): draw %.2f ms, scale up %.2f ms (one thread), PSNR mean %.2f dB, worst %.2f dB\n",
                   motion_scales[s], w, h, d, sc, q, qmin);
    }
    rc = 0;
out:
    free(rgba), free(depth), free(full), free(up), free(small), free(draw), free(scale_ms), free(psnr);
    return rc;
}

/* The encoder alone at W x H: n frames of the orbit at CRF 23. */
static int time_big(bench_city_scene *city, vt_soft *sr, uint32_t W, uint32_t H, int n, double deg, int speed,
                    bool json)
{
    float *rgba = malloc((size_t)W * H * 4 * sizeof *rgba), *depth = malloc((size_t)W * H * sizeof *depth);
    uint8_t *rgba8 = malloc(vt_image_rgba8_size(W, H));
    double *ms = calloc((size_t)n, sizeof *ms), *cv = calloc((size_t)n, sizeof *cv);
    double *bytes = calloc((size_t)n, sizeof *bytes);
    uint32_t cw, ch;
    vt_h264_coded_size(W, H, &cw, &ch);
    uint8_t *planes = malloc((size_t)cw * ch * 3 / 2);
    vt_h264 *e = NULL;
    char err[512];
    int rc = -1;
    if (!rgba || !depth || !rgba8 || !ms || !cv || !bytes || !planes) goto out;
    if (vt_h264_open(&e, &(vt_h264_cfg){.width = W, .height = H, .speed = (vt_h264_speed)speed, .threads = g_threads}, err, sizeof err)) {
        fprintf(stderr, "bench_h264: %s\n", err);
        goto out;
    }
    for (int k = 0; k < n; k++) {
        double eye[3], at[3] = {0, 2, 0};
        orbit_eye(k, deg, eye);
        if (bench_city_draw(city, sr, eye, at, W, H, rgba, depth) || tonemap(W, H, rgba, rgba8)) goto out;
        double t0 = bench_now_ns();
        vt_h264_rgb_to_i420(W, H, rgba8, 4 * (size_t)W, 4, planes, cw, planes + (size_t)cw * ch, cw / 2,
                            planes + (size_t)cw * ch * 5 / 4, cw / 2);
        double t1 = bench_now_ns();
        const uint8_t *au;
        size_t len;
        bool key;
        if (vt_h264_encode(e, rgba8, 4 * (size_t)W, 4, false, &au, &len, &key, err, sizeof err)) {
            fprintf(stderr, "bench_h264: %s\n", err);
            goto out;
        }
        ms[k] = (bench_now_ns() - t1) / 1e6;
        cv[k] = (t1 - t0) / 1e6;
        bytes[k] = (double)len;
    }
    double m = bench_median(ms, n), c = bench_median(cv, n), b = median_of(bytes + (n > 1), n - (n > 1));
    if (json)
        printf("{\"codec\":\"h264-crf23\",\"timing\":true,\"width\":%u,\"height\":%u,\"frames\":%d,"
               "\"median_encode_ms\":%.3f,\"median_convert_ms\":%.3f,\"median_p_bytes\":%.0f}\n",
               W, H, n, m, c, b);
    else
        printf("h264 crf 23 at %ux%u, %d thread(s): encode %.2f ms a frame (conversion + x264; median of %d), the conversion "
               "alone %.2f ms, P-frames %.0f bytes (median)\n",
               W, H, g_threads, m, n, c, b);
    rc = 0;
out:
    vt_h264_close(e);
    free(rgba), free(depth), free(rgba8), free(ms), free(cv), free(bytes), free(planes);
    return rc;
}

int main(int argc, char **argv)
{
    uint32_t W = 1280, H = 720, BW = 1920, BH = 1080;
    int n = 60, big_n = 30, speed = 0, ncrf = 5, nq = 2;
    int crfs[MAX_CODECS] = {180, 200, 230, 260, 280}, qs[MAX_CODECS] = {80, 85};
    double deg = 0.5;
    bool json = false, smoke = false, motion = false;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        bool ok = true;
        if (!strcmp(a, "--json")) json = true;
        else if (!strcmp(a, "--smoke")) smoke = true;
        else if (!strcmp(a, "--motion")) motion = true;
        else if (!v) ok = false;
        else if (!strcmp(a, "--size")) ok = sscanf(v, "%ux%u", &W, &H) == 2, i++;
        else if (!strcmp(a, "--big")) ok = sscanf(v, "%ux%u", &BW, &BH) == 2, i++;
        else if (!strcmp(a, "--frames")) n = atoi(v), i++;
        else if (!strcmp(a, "--big-frames")) big_n = atoi(v), i++;
        else if (!strcmp(a, "--orbit")) deg = atof(v), i++;
        else if (!strcmp(a, "--speed")) speed = atoi(v), i++;
        else if (!strcmp(a, "--threads")) g_threads = atoi(v), i++;
        else if (!strcmp(a, "--crf")) ok = (ncrf = parse_list(v, crfs, MAX_CODECS / 2, 10)) > 0, i++;
        else if (!strcmp(a, "--quality")) ok = (nq = parse_list(v, qs, MAX_CODECS / 2, 1)) > 0, i++;
        else ok = false;
        if (!ok) {
            fprintf(stderr, "usage: bench_h264 [--size WxH] [--frames N] [--orbit DEG] [--crf A,B,..] "
                            "[--quality A,B,..] [--big WxH] [--big-frames N] [--speed 0|1|2] [--threads N] [--json] [--smoke]\n");
            return 2;
        }
    }
    if (smoke) W = 320, H = 180, n = 4, BW = 640, BH = 360, big_n = 2;
    if (W < 16 || H < 16 || W > VT_H264_MAX_DIM || H > VT_H264_MAX_DIM || BW < 16 || BH < 16 ||
        BW > VT_H264_MAX_DIM || BH > VT_H264_MAX_DIM || n < 2 || big_n < 1)
        return 2;
    cull_pool *pool;
    bench_city_scene *city;
    vt_soft *sr;
    if (cull_pool_create(2, &pool) || bench_city_open(pool, json, &city) || vt_soft_create(pool, 2, &sr)) return 1;
    if (motion) {
        int rc = motion_study(city, sr, W, H, n, deg, json);
        vt_soft_destroy(sr);
        bench_city_close(city);
        cull_pool_destroy(pool);
        return rc ? 1 : 0;
    }
    codec cs[MAX_CODECS];
    int nc = 0;
    memset(cs, 0, sizeof cs);
    char err[512];
    for (int i = 0; i < nq; i++, nc++) {
        cs[nc].jpeg_q = qs[i];
        snprintf(cs[nc].name, sizeof cs[nc].name, "jpeg-q%d", qs[i]);
    }
    for (int i = 0; i < ncrf; i++, nc++) {
        cs[nc].crf_x10 = crfs[i];
        snprintf(cs[nc].name, sizeof cs[nc].name, "h264-crf%g", crfs[i] / 10.0);
        vt_h264_cfg cfg = {.width = W, .height = H, .crf_x10 = crfs[i], .speed = (vt_h264_speed)speed,
                           .threads = g_threads};
        if (vt_h264_open(&cs[nc].enc, &cfg, err, sizeof err) || h264_dec_open(&cs[nc].dec)) {
            fprintf(stderr, "bench_h264: %s: %s\n", cs[nc].name, err);
            return 1;
        }
    }
    for (int i = 0; i < nc; i++) {
        cs[i].bytes = calloc((size_t)n, sizeof(double));
        cs[i].psnr = calloc((size_t)n, sizeof(double));
        cs[i].ms = calloc((size_t)n, sizeof(double));
        if (!cs[i].bytes || !cs[i].psnr || !cs[i].ms) return 1;
    }
    float *rgba = malloc((size_t)W * H * 4 * sizeof *rgba), *depth = malloc((size_t)W * H * sizeof *depth);
    uint8_t *rgba8 = malloc(vt_image_rgba8_size(W, H)), *rgb = malloc(3 * (size_t)W * H);
    if (!rgba || !depth || !rgba8 || !rgb) return 1;
    if (!json)
        printf("the demo city's street orbit, %d frames of %.2f degrees at %ux%u, ACES to RGBA8; PSNR against that\n",
               n, deg, W, H);
    for (int k = 0; k < n; k++) {
        double eye[3], at[3] = {0, 2, 0};
        orbit_eye(k, deg, eye);
        if (bench_city_draw(city, sr, eye, at, W, H, rgba, depth) || tonemap(W, H, rgba, rgba8)) return 1;
        for (int i = 0; i < nc; i++)
            if (run_codec(&cs[i], k, W, H, rgba8, rgb)) return 1;
    }
    for (int i = 0; i < nc; i++) report_codec(&cs[i], n, W, H, json);
    equal_quality(cs, nc, n, json);
    fflush(stdout);
    if (time_big(city, sr, W, H, big_n, deg, speed, json) || time_big(city, sr, BW, BH, big_n, deg, speed, json))
        return 1;
    for (int i = 0; i < nc; i++) {
        vt_h264_close(cs[i].enc);
        h264_dec_close(&cs[i].dec);
        free(cs[i].bytes), free(cs[i].psnr), free(cs[i].ms);
    }
    free(rgba), free(depth), free(rgba8), free(rgb);
    vt_soft_destroy(sr);
    bench_city_close(city);
    cull_pool_destroy(pool);
    return 0;
}
