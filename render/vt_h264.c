/*
 * vt_h264.c — the H.264 encoder of vt_h264.h over libx264, and the RGB8 ->
 * I420 conversion that feeds it (BT.709, limited range, chroma sited as
 * H.264 assumes by default).
 *
 * The conversion, two rows at a time: each row is copied into a padded
 * RGBA row with its edge pixel repeated on either side (the chroma
 * filter's border and the odd sizes' padding in one place, RGB and RGBA
 * alike), then luma and chroma are fixed-point sums over the two rows
 * (vt_h264_kern.h): the AVX2 lanes (vt_h264_avx2.c) 16 columns a step
 * where the CPU has them, the scalar rows for the rest and everywhere
 * else, the same sums bit for bit. Coefficients are 2^-16 fractions, each
 * within 2^-17 of the exact value, so a result is at most 1.5 * 255 /
 * 65536 = 0.006 codes from the exact one before rounding: it rounds the
 * other way only within 0.006 of a half, never by more than 1 code
 * (test_h264_convert checks every sample against a double reference).
 *
 * Measured (the development machine, 2 cores shared with two other
 * builds, load 4.5; medians of 41 runs of random 1280x720 RGBA): the
 * conversion 0.68 ms with the lanes, 1.83 ms scalar (1920x1080: 1.74
 * against 5.77 ms). x264's encode of a demo-city frame is 5-20 ms on the
 * same machine (BENCHMARKS.md, bench_h264), so the lanes save 5-20 %.
 */
#include "vt_h264.h"
#include "vt_h264_kern.h"
#include "culling.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <x264.h>

/* ---- RGB8 -> I420 -------------------------------------------------------- */

static const int32_t CY_R = VT_H264_CY_R, CY_G = VT_H264_CY_G, CY_B = VT_H264_CY_B;
static const int32_t CU_R = VT_H264_CU_R, CU_G = VT_H264_CU_G, CU_B = VT_H264_CU_B;
static const int32_t CV_R = VT_H264_CV_R, CV_G = VT_H264_CV_G, CV_B = VT_H264_CV_B;

/* Bytes of one padded row: columns -1 .. cw (cw + 2 pixels), 4 bytes each. */
static size_t pad_bytes(uint32_t cw)
{
    return 4 * ((size_t)cw + 2);
}

/* Row p (w pixels of pb bytes) into the padded RGBA row t: column i at
 * t + 4 (i + 1) for -1 <= i <= cw, the edges repeated (column -1 is
 * column 0, columns w.. are column w - 1). The fourth byte is junk. */
static void pad_row(const uint8_t *p, uint32_t w, uint32_t cw, uint32_t pb, uint8_t *t)
{
    if (pb == 4) {
        memcpy(t + 4, p, 4 * (size_t)w);
    } else {
        for (uint32_t x = 0; x < w; x++) memcpy(t + 4 * ((size_t)x + 1), p + 3 * (size_t)x, 3);
    }
    for (uint32_t x = w; x <= cw; x++) memcpy(t + 4 * ((size_t)x + 1), t + 4 * (size_t)w, 4);
    memcpy(t, t + 4, 4);
}

/* The rows of vt_h264_kern.h's contract, columns [x0, cw) (x0 even), one
 * pixel at a time: the reference the lanes match and the tail they leave. */
static void rows_scalar(const uint8_t *t0, const uint8_t *t1, uint32_t x0, uint32_t cw, uint8_t *y0, uint8_t *y1,
                        uint8_t *u, uint8_t *v)
{
    for (uint32_t x = x0; x < cw; x++) {
        const uint8_t *a = t0 + 4 * (size_t)x, *b = t1 + 4 * (size_t)x;
        y0[x] = (uint8_t)((CY_R * a[0] + CY_G * a[1] + CY_B * a[2] + VT_H264_Y_ADD) >> 16);
        y1[x] = (uint8_t)((CY_R * b[0] + CY_G * b[1] + CY_B * b[2] + VT_H264_Y_ADD) >> 16);
    }
    for (uint32_t i = x0 / 2; i < cw / 2; i++) {
        const uint8_t *a = t0 + 8 * (size_t)i, *b = t1 + 8 * (size_t)i; /* column 2i */
        int32_t s[3];
        for (int k = 0; k < 3; k++) s[k] = a[k - 4] + 2 * a[k] + a[k + 4] + b[k - 4] + 2 * b[k] + b[k + 4];
        u[i] = (uint8_t)((CU_R * s[0] + CU_G * s[1] + CU_B * s[2] + VT_H264_C_ADD) >> 19);
        v[i] = (uint8_t)((CV_R * s[0] + CV_G * s[1] + CV_B * s[2] + VT_H264_C_ADD) >> 19);
    }
}

/* The lanes where the culling core's pick is AVX2 (CPUID, VANTAGE_ISA), as
 * vt_raster.c's; the scalar rows otherwise. */
static vt_i420_rows_fn rows_pick(void)
{
    return cull_isa_default() == CULL_ISA_AVX2 ? vt_i420_rows_avx2() : NULL;
}

/* The conversion into planes already checked; t: 2 pad_bytes(cw) of
 * scratch; lanes: rows_pick's. */
static void to_i420(uint32_t w, uint32_t h, const uint8_t *pix, size_t stride, uint32_t pb, uint8_t *t,
                    vt_i420_rows_fn lanes, uint8_t *y, size_t ys, uint8_t *u, size_t us, uint8_t *v, size_t vs)
{
    uint32_t cw = (w + 1) & ~1u, ch = (h + 1) & ~1u, n = lanes ? cw & ~15u : 0;
    uint8_t *t0 = t, *t1 = t + pad_bytes(cw);
    for (uint32_t j = 0; j < ch / 2; j++) {
        uint32_t r0 = 2 * j, r1 = 2 * j + 1 < h ? 2 * j + 1 : h - 1;
        uint8_t *yr0 = y + r0 * ys, *yr1 = yr0 + ys, *ur = u + j * us, *vr = v + j * vs;
        pad_row(pix + r0 * stride, w, cw, pb, t0);
        pad_row(pix + r1 * stride, w, cw, pb, t1);
        if (n) lanes(t0 + 4, t1 + 4, n, yr0, yr1, ur, vr);
        rows_scalar(t0 + 4, t1 + 4, n, cw, yr0, yr1, ur, vr);
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
    uint8_t *t = malloc(2 * pad_bytes(cw));
    if (!t) return VT_ERR_NOMEM;
    to_i420(w, h, pix, stride, pixel_bytes, t, rows_pick(), y, ys, u, us, v, vs);
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
    uint8_t       *rows;     /* conversion scratch, 2 pad_bytes(cw) */
    vt_i420_rows_fn lanes;   /* the conversion's AVX2 rows, or NULL */
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

/* cfg -> x264's parameters: 0, or VT_ERR_INVALID / VT_ERR_TOO_LARGE / VT_ERR_CODEC
 * with the reason in err. */
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
    static const char *const presets[] = {"ultrafast", "superfast", "veryfast"};
    if ((unsigned)c->speed >= sizeof presets / sizeof presets[0])
        return vp_errf(err, errlen, VT_ERR_INVALID, "h264: speed %d outside 0..2 (ultrafast, superfast, veryfast)",
                       (int)c->speed);
    if (x264_param_default_preset(p, presets[c->speed], "zerolatency"))
        return vp_errf(err, errlen, VT_ERR_CODEC, "h264: x264 has no %s/zerolatency preset", presets[c->speed]);
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
    e->lanes = rows_pick();
    if (!(e->rows = malloc(2 * pad_bytes((uint32_t)p.i_width)))) {
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
    to_i420(e->w, e->h, pix, stride, pixel_bytes, e->rows, e->lanes, im->plane[0], (size_t)im->i_stride[0],
            im->plane[1], (size_t)im->i_stride[1], im->plane[2], (size_t)im->i_stride[2]);
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
