/*
 * vt_h264.c — the H.264 encoder of vt_h264.h over libx264, and the RGB8 ->
 * I420 conversion that feeds it (BT.709, limited range, chroma sited as
 * H.264 assumes by default).
 *
 * The conversion, two rows at a time: each row's pixels are copied into
 * planar R, G, B byte rows with one repeated pixel on either side (the
 * filter's edge and the odd sizes' padding in one place, and RGB or RGBA
 * alike), then luma and chroma are fixed-point sums over those planes:
 * loops without branches or strides, which gcc -O3 vectorises with the
 * baseline SSE2. Coefficients are 16-bit fractions (2^-16; chroma 2^-19,
 * the filter's weights summing to 8), each within 2^-17 of the exact
 * value, so a result is at most 1.5 * 255 / 65536 = 0.006 codes from the
 * exact one before rounding: it rounds the other way only within 0.006 of
 * a half, never by more than 1 code (test_h264_convert checks every code
 * against a double-precision reference).
 *
 * Measured (the development machine, 2 cores shared with two other
 * builds, load ~2; medians of 60 frames, gcc 12 -O3; tests/bench/bench_h264.c):
 * the conversion of 1280x720 RGBA about 1 ms (see the report for the
 * AVX2 question), the x264 encode of a demo-city frame 4-8 ms.
 */
#include "vt_h264.h"

#include <limits.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <x264.h>

/* ---- RGB8 -> I420 -------------------------------------------------------- */

/* BT.709: Kr 0.2126, Kb 0.0722. Limited range: luma 219 codes over 255,
 * chroma 224 over the span of B - Y (2 (1 - Kb)) and R - Y (2 (1 - Kr)). */
#define KR 0.2126
#define KB 0.0722
#define KG (1.0 - KR - KB)
#define YS (219.0 / 255.0)
#define US (224.0 / 255.0 / (2.0 * (1.0 - KB)))
#define VS (224.0 / 255.0 / (2.0 * (1.0 - KR)))
#define FIX(x) ((int32_t)((x) * 65536.0 + ((x) < 0 ? -0.5 : 0.5)))
static const int32_t CY_R = FIX(YS * KR), CY_G = FIX(YS * KG), CY_B = FIX(YS * KB);
static const int32_t CU_R = FIX(-US * KR), CU_G = FIX(-US * KG), CU_B = FIX(US * (1.0 - KB));
static const int32_t CV_R = FIX(VS * (1.0 - KR)), CV_G = FIX(-VS * KG), CV_B = FIX(-VS * KB);
/* 16 (128) and the rounding half, at the sums' scale */
#define Y_ADD ((16 << 16) + (1 << 15))
#define C_ADD ((128 << 19) + (1 << 18))

/* Row `p` (w pixels of pb bytes) into planar rows r/g/b of cw + 2 bytes:
 * index i + 1 holds pixel min(i, w - 1), index 0 pixel 0 (the chroma
 * filter's left neighbour of column 0). */
static void planar_row(const uint8_t *p, uint32_t w, uint32_t cw, uint32_t pb, uint8_t *r, uint8_t *g, uint8_t *b)
{
    if (pb == 4) {
        for (uint32_t x = 0; x < w; x++) r[x + 1] = p[4 * x], g[x + 1] = p[4 * x + 1], b[x + 1] = p[4 * x + 2];
    } else {
        for (uint32_t x = 0; x < w; x++) r[x + 1] = p[3 * x], g[x + 1] = p[3 * x + 1], b[x + 1] = p[3 * x + 2];
    }
    for (uint32_t x = w; x <= cw; x++) r[x + 1] = r[w], g[x + 1] = g[w], b[x + 1] = b[w];
    r[0] = r[1], g[0] = g[1], b[0] = b[1];
}

static void luma_row(const uint8_t *r, const uint8_t *g, const uint8_t *b, uint32_t cw, uint8_t *y)
{
    for (uint32_t x = 0; x < cw; x++)
        y[x] = (uint8_t)((CY_R * r[x + 1] + CY_G * g[x + 1] + CY_B * b[x + 1] + Y_ADD) >> 16);
}

/* The chroma of a row pair: at column 2x, [1 2 1] over columns 2x-1..2x+1
 * of both rows (weights summing to 8, hence 2^-19). */
static void chroma_row(const uint8_t *t, uint32_t cw, uint8_t *u, uint8_t *v)
{
    const size_t n = (size_t)cw + 2;
    const uint8_t *r0 = t, *g0 = t + n, *b0 = t + 2 * n, *r1 = t + 3 * n, *g1 = t + 4 * n, *b1 = t + 5 * n;
    for (uint32_t x = 0; x < cw / 2; x++) {
        uint32_t c = 2 * x + 1; /* column 2x's index */
        int32_t sr = r0[c - 1] + 2 * r0[c] + r0[c + 1] + r1[c - 1] + 2 * r1[c] + r1[c + 1];
        int32_t sg = g0[c - 1] + 2 * g0[c] + g0[c + 1] + g1[c - 1] + 2 * g1[c] + g1[c + 1];
        int32_t sb = b0[c - 1] + 2 * b0[c] + b0[c + 1] + b1[c - 1] + 2 * b1[c] + b1[c + 1];
        u[x] = (uint8_t)((CU_R * sr + CU_G * sg + CU_B * sb + C_ADD) >> 19);
        v[x] = (uint8_t)((CV_R * sr + CV_G * sg + CV_B * sb + C_ADD) >> 19);
    }
}

/* The conversion into planes already checked; t: 6 (cw + 2) bytes. */
static void to_i420(uint32_t w, uint32_t h, const uint8_t *pix, size_t stride, uint32_t pb, uint8_t *t, uint8_t *y,
                    size_t ys, uint8_t *u, size_t us, uint8_t *v, size_t vs)
{
    uint32_t cw = (w + 1) & ~1u, ch = (h + 1) & ~1u;
    const size_t n = (size_t)cw + 2;
    for (uint32_t j = 0; j < ch / 2; j++) {
        uint32_t y0 = 2 * j, y1 = 2 * j + 1 < h ? 2 * j + 1 : h - 1;
        planar_row(pix + y0 * stride, w, cw, pb, t, t + n, t + 2 * n);
        planar_row(pix + y1 * stride, w, cw, pb, t + 3 * n, t + 4 * n, t + 5 * n);
        luma_row(t, t + n, t + 2 * n, cw, y + y0 * ys);
        luma_row(t + 3 * n, t + 4 * n, t + 5 * n, cw, y + (y0 + 1) * ys);
        chroma_row(t, cw, u + j * us, v + j * vs);
    }
}

/* The checks vt_h264_encode and vt_h264_rgb_to_i420 share. */
static int check_pix(uint32_t w, const uint8_t *pix, size_t stride, uint32_t pb, char *err,
                     size_t errlen)
{
    if (!pix) return vp_errf(err, errlen, VT_ERR_INVALID, "h264: no picture");
    if (pb != 3 && pb != 4)
        return vp_errf(err, errlen, VT_ERR_INVALID, "h264: %u bytes a pixel (3 RGB or 4 RGBA)", pb);
    if (stride < (size_t)w * pb)
        return vp_errf(err, errlen, VT_ERR_INVALID, "h264: row stride %zu bytes under the row's %zu", stride,
                       (size_t)w * pb);
    return 0;
}

static int check_size(uint32_t w, uint32_t h, uint32_t min, char *err, size_t errlen)
{
    if (w > VT_H264_MAX_DIM || h > VT_H264_MAX_DIM)
        return vp_errf(err, errlen, VT_ERR_TOO_LARGE, "h264: %ux%u is over %ux%u", w, h, VT_H264_MAX_DIM,
                       VT_H264_MAX_DIM);
    if (w < min || h < min)
        return vp_errf(err, errlen, VT_ERR_INVALID, "h264: %ux%u is under %ux%u", w, h, min, min);
    return 0;
}

void vt_h264_coded_size(uint32_t w, uint32_t h, uint32_t *coded_w, uint32_t *coded_h)
{
    if (coded_w) *coded_w = (w + 1) & ~1u;
    if (coded_h) *coded_h = (h + 1) & ~1u;
}

int vt_h264_rgb_to_i420(uint32_t w, uint32_t h, const uint8_t *pix, size_t stride, uint32_t pixel_bytes,
                        uint8_t *y, size_t ys, uint8_t *u, size_t us, uint8_t *v, size_t vs)
{
    int rc;
    if ((rc = check_size(w, h, 1, NULL, 0)) || (rc = check_pix(w, pix, stride, pixel_bytes, NULL, 0)))
        return rc;
    uint32_t cw = (w + 1) & ~1u;
    if (!y || !u || !v || ys < cw || us < cw / 2 || vs < cw / 2) return VT_ERR_INVALID;
    uint8_t *t = malloc(6 * ((size_t)cw + 2));
    if (!t) return VT_ERR_NOMEM;
    to_i420(w, h, pix, stride, pixel_bytes, t, y, ys, u, us, v, vs);
    free(t);
    return 0;
}

/* ---- the encoder ------------------------------------------------------- */

struct vt_h264 {
    x264_t        *x;
    x264_picture_t pic;      /* the I420 input, coded size (x264_picture_alloc) */
    bool           pic_ok;
    uint32_t       w, h;     /* the picture's size; the coded size is pic's */
    int64_t        pts;      /* frames encoded: x264 wants rising timestamps */
    uint8_t       *rows;     /* conversion scratch, 6 (cw + 2) bytes */
    char           msg[256]; /* x264's last error, from its log callback */
};

/* x264 reports through this (errors only: i_log_level). The last message
 * is kept for the error that follows it. */
static void x264_log(void *priv, int level, const char *fmt, va_list ap)
{
    vt_h264 *e = priv;
    (void)level;
    vsnprintf(e->msg, sizeof e->msg, fmt, ap);
    size_t n = strlen(e->msg);
    while (n && (e->msg[n - 1] == '\n' || e->msg[n - 1] == ' ')) e->msg[--n] = 0;
}

/* cfg -> x264's parameters; 0 or VT_ERR_INVALID with the reason. */
static int make_param(const vt_h264_cfg *c, vt_h264 *e, x264_param_t *p, char *err, size_t errlen)
{
    int rc;
    if ((rc = check_size(c->width, c->height, 2, err, errlen))) return rc;
    int crf = c->crf_x10 ? c->crf_x10 : 230;
    uint32_t fps = c->fps ? c->fps : 30;
    int threads = c->threads ? c->threads : 1;
    if (crf < 10 || crf > 510)
        return vp_errf(err, errlen, VT_ERR_INVALID, "h264: crf_x10 %d outside 10..510 (CRF 1.0..51.0)", c->crf_x10);
    if (fps > 1000) return vp_errf(err, errlen, VT_ERR_INVALID, "h264: fps %u outside 1..1000", fps);
    if (c->max_kbps > 1000000)
        return vp_errf(err, errlen, VT_ERR_INVALID, "h264: max_kbps %u outside 0..1000000", c->max_kbps);
    if (c->keyint > 65535) return vp_errf(err, errlen, VT_ERR_INVALID, "h264: keyint %u outside 0..65535", c->keyint);
    if (threads < 1 || threads > 16)
        return vp_errf(err, errlen, VT_ERR_INVALID, "h264: threads %d outside 1..16", c->threads);
    if (x264_param_default_preset(p, "ultrafast", "zerolatency"))
        return vp_errf(err, errlen, VT_ERR_CODEC, "h264: x264 has no ultrafast/zerolatency preset");
    p->i_csp = X264_CSP_I420;
    p->i_width = (int)((c->width + 1) & ~1u);
    p->i_height = (int)((c->height + 1) & ~1u);
    p->i_threads = threads;
    p->i_fps_num = fps;
    p->i_fps_den = 1;
    p->b_vfr_input = 0; /* rate control by frame count and fps, not timestamps */
    p->i_keyint_max = c->keyint ? (int)c->keyint : X264_KEYINT_MAX_INFINITE;
    p->i_bframe = 0;
    p->b_annexb = 1;
    p->b_repeat_headers = 1;
    p->rc.i_rc_method = X264_RC_CRF;
    p->rc.f_rf_constant = (float)crf / 10;
    if (c->max_kbps) {
        p->rc.i_vbv_max_bitrate = (int)c->max_kbps;
        p->rc.i_vbv_buffer_size = (int)(c->max_kbps / fps ? c->max_kbps / fps : 1);
    }
    p->vui.i_colorprim = 1; /* BT.709 (H.264 table E-3, E-4, E-5) */
    p->vui.i_transfer = 1;
    p->vui.i_colmatrix = 1;
    p->vui.b_fullrange = 0;
    p->i_log_level = X264_LOG_ERROR;
    p->pf_log = x264_log;
    p->p_log_private = e;
    if (x264_param_apply_profile(p, "baseline"))
        return vp_errf(err, errlen, VT_ERR_CODEC, "h264: x264 refused the baseline profile: %s", e->msg);
    return 0;
}

int vt_h264_open(vt_h264 **out, const vt_h264_cfg *c, char *err, size_t errlen)
{
    vp_errf(err, errlen, 0, "%s", "");
    if (!out) return vp_errf(err, errlen, VT_ERR_INVALID, "h264: no encoder pointer");
    *out = NULL;
    if (!c) return vp_errf(err, errlen, VT_ERR_INVALID, "h264: no configuration");
    vt_h264 *e = calloc(1, sizeof *e);
    if (!e) return vp_errf(err, errlen, VT_ERR_NOMEM, "h264: out of memory");
    x264_param_t p;
    int rc = make_param(c, e, &p, err, errlen);
    if (rc) goto fail;
    e->w = c->width;
    e->h = c->height;
    if (!(e->rows = malloc(6 * ((size_t)p.i_width + 2)))) {
        rc = vp_errf(err, errlen, VT_ERR_NOMEM, "h264: out of memory");
        goto fail;
    }
    if (x264_picture_alloc(&e->pic, X264_CSP_I420, p.i_width, p.i_height)) {
        rc = vp_errf(err, errlen, VT_ERR_NOMEM, "h264: out of memory (x264 picture %dx%d)", p.i_width, p.i_height);
        goto fail;
    }
    e->pic_ok = true;
    if (!(e->x = x264_encoder_open(&p))) {
        rc = vp_errf(err, errlen, VT_ERR_CODEC, "h264: x264_encoder_open: %s", e->msg[0] ? e->msg : "failed");
        goto fail;
    }
    *out = e;
    return 0;
fail:
    vt_h264_close(e);
    return rc;
}

int vt_h264_encode(vt_h264 *e, const uint8_t *pix, size_t stride, uint32_t pixel_bytes, bool force_idr,
                   const uint8_t **au, size_t *len, bool *key, char *err, size_t errlen)
{
    vp_errf(err, errlen, 0, "%s", "");
    if (au) *au = NULL;
    if (len) *len = 0;
    if (key) *key = false;
    if (!e || !au || !len || !key) return vp_errf(err, errlen, VT_ERR_INVALID, "h264: NULL encoder or output");
    int rc = check_pix(e->w, pix, stride, pixel_bytes, err, errlen);
    if (rc) return rc;
    x264_image_t *im = &e->pic.img;
    to_i420(e->w, e->h, pix, stride, pixel_bytes, e->rows, im->plane[0], (size_t)im->i_stride[0], im->plane[1],
            (size_t)im->i_stride[1], im->plane[2], (size_t)im->i_stride[2]);
    e->pic.i_type = force_idr ? X264_TYPE_IDR : X264_TYPE_AUTO;
    e->pic.i_pts = e->pts;
    x264_nal_t *nal;
    int nnal;
    x264_picture_t pout;
    e->msg[0] = 0;
    int n = x264_encoder_encode(e->x, &nal, &nnal, &e->pic, &pout);
    if (n <= 0 || nnal < 1)
        return vp_errf(err, errlen, VT_ERR_CODEC, "h264: x264_encoder_encode: %s",
                       e->msg[0] ? e->msg : n < 0 ? "failed" : "no access unit out (delayed)");
    e->pts++;
    /* x264 lays the NAL units out back to back from nal[0] (its
       documented contract for one encode call's output) */
    *au = nal[0].p_payload;
    *len = (size_t)n;
    *key = pout.b_keyframe != 0;
    return 0;
}

void vt_h264_close(vt_h264 *e)
{
    if (!e) return;
    if (e->x) x264_encoder_close(e->x);
    if (e->pic_ok) x264_picture_clean(&e->pic);
    free(e->rows);
    free(e);
}
