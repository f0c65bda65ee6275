/*
 * vt_jpeg.c — JPEG for vt_image.h through the libjpeg API of libjpeg-turbo
 * 2.1: the writer to a file (through the shared sink into a temporary file
 * renamed into place, vt_sink.h) or to a memory stream, and the decoder to
 * RGB8 from memory or a file. Any libjpeg warning is an error.
 *
 * libpng and libjpeg report fatal errors by longjmp. The rule here: the
 * function that calls setjmp does nothing else (png_guarded, jpg_guarded:
 * no locals change after setjmp, so none is left indeterminate and none
 * needs volatile), and every resource the longjmp could strand lives in a
 * job struct owned by the caller, which frees it on either path. Bodies
 * store each allocation in the job before the next library call.
 *
 * Measured on the development machine (one core of a 2-core AMD EPYC VM,
 * gcc 12 -O2, medians of 15), a 1280x720 tone-mapped frame: q85 2-3 ms,
 * smooth or with 8% grain (31 / 39 KB), memory or file; decode 2 ms.
 * 16384x16384 q85: 0.6 s.
 *
 * vt_jpeg_encode_par encodes bands of MCU rows on several threads and
 * splices their scans with RSTn markers (vt_image.h); vt_jpeg_encode_frame
 * is the daemon's JPEG frame on it, each band tone-mapping its own rows.
 * The city frames' tone map + JPEG, as the thread CPU of the longest of 2
 * threads (a loaded 2-core Xeon): street 5.4 -> 3.5 ms, aerial 5.9 -> 3.1
 * (4 bands; libjpeg-turbo alone: 3.45 -> 1.63, 4.10 -> 1.81).
 */
#ifndef _GNU_SOURCE
#define _GNU_SOURCE
#endif
#include "vt_image.h"
#include "vt_sink.h"

#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stdatomic.h>
#include <stdio.h> /* before jpeglib.h, which uses FILE */
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include <jerror.h>
#include <jpeglib.h>

/* ---- JPEG ------------------------------------------------------------------ */

typedef struct jpg_err {
    struct jpeg_error_mgr pub; /* first: libjpeg's cinfo->err points here */
    jmp_buf    jump;
    vt_call  *c;
    int        code; /* a negative errno chosen here before jumping, or 0 */
} jpg_err;

static void jpg_on_error(j_common_ptr ci)
{
    jpg_err *e = (jpg_err *)ci->err;
    char msg[JMSG_LENGTH_MAX];
    (*ci->err->format_message)(ci, msg);
    vt_call_msg(e->c, "%s", msg);
    longjmp(e->jump, 1);
}

/* Warnings (msg_level < 0) mean corrupt or truncated data, which libjpeg
 * would paper over with grey: an error here. Trace messages are dropped. */
static void jpg_on_message(j_common_ptr ci, int msg_level)
{
    if (msg_level >= 0) return;
    ci->err->num_warnings++;
    jpg_on_error(ci);
}

static void jpg_on_output(j_common_ptr ci)
{
    (void)ci; /* never print to stderr */
}

/* Fails the running body with a code of our choosing. */
#if defined(__GNUC__)
__attribute__((noreturn, format(printf, 3, 4)))
#endif
static void jpg_abort(j_common_ptr ci, int code, const char *fmt, ...)
{
    jpg_err *e = (jpg_err *)ci->err;
    char msg[256];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    vt_call_msg(e->c, "%s", msg);
    e->code = code;
    longjmp(e->jump, 1);
}

static void jpg_err_init(jpg_err *e, vt_call *c)
{
    jpeg_std_error(&e->pub);
    e->pub.error_exit = jpg_on_error;
    e->pub.emit_message = jpg_on_message;
    e->pub.output_message = jpg_on_output;
    e->c = c;
    e->code = 0;
}

/* The errno for a failed body. */
static int jpg_code(const jpg_err *e, const vt_sink *s, int otherwise)
{
    if (e->code) return e->code;
    if (s && s->err) return vt_err_from_errno(s->err);
    if (e->pub.msg_code == JERR_OUT_OF_MEMORY) return VT_ERR_NOMEM;
    return otherwise;
}

typedef struct jpg_dest {
    struct jpeg_destination_mgr pub; /* first: cinfo->dest points here */
    vt_sink *s;
} jpg_dest;

static void jpg_dest_init(j_compress_ptr ci)
{
    jpg_dest *d = (jpg_dest *)ci->dest;
    d->pub.next_output_byte = d->s->buf + d->s->len;
    d->pub.free_in_buffer = d->s->cap - d->s->len;
}

/* Called with the buffer full, whatever the pointers say (libjpeg.txt). */
static boolean jpg_dest_empty(j_compress_ptr ci)
{
    jpg_dest *d = (jpg_dest *)ci->dest;
    d->s->len = d->s->cap;
    if (!vt_sink_room(d->s)) {
        if (d->s->err == ENOMEM) ERREXIT1(ci, JERR_OUT_OF_MEMORY, 0);
        ERREXIT(ci, JERR_FILE_WRITE);
    }
    jpg_dest_init(ci);
    return TRUE;
}

static void jpg_dest_term(j_compress_ptr ci)
{
    jpg_dest *d = (jpg_dest *)ci->dest;
    d->s->len = d->s->cap - d->pub.free_in_buffer;
}

typedef struct jpg_job {
    jpg_err        err;
    /* compressing */
    struct jpeg_compress_struct   ci;
    jpg_dest       dest;
    const uint8_t *px;
    size_t         stride;
    uint32_t       pixel_bytes;
    int            quality;
    unsigned       restart;     /* restart interval in MCUs (vt_jpeg_encode_par's bands), 0: none */
    /* decompressing */
    struct jpeg_decompress_struct di;
    const uint8_t *data;
    size_t         len;
    uint8_t       *pix; /* the decoded image, malloc'ed */
    uint32_t       w, h;
    bool           header_only; /* the size only (vt_jpeg_info) */
} jpg_job;

/* The only function that calls setjmp for libjpeg (see the top). */
static int jpg_guarded(jpg_job *j, void (*body)(jpg_job *))
{
    if (setjmp(j->err.jump)) return -1;
    body(j);
    return 0;
}

/* Rows handed to libjpeg per call: fewer calls, and a multiple of the 16
 * rows of a 4:2:0 MCU row. */
#define JPG_ROWS 16

static void jpg_compress_body(jpg_job *j)
{
    struct jpeg_compress_struct *ci = &j->ci;
    jpeg_create_compress(ci); /* keeps ->err, zeroes the rest */
    ci->dest = &j->dest.pub;
    ci->image_width = j->w;
    ci->image_height = j->h;
    ci->input_components = (int)j->pixel_bytes;
    ci->in_color_space = j->pixel_bytes == 4 ? JCS_EXT_RGBX : JCS_RGB;
    jpeg_set_defaults(ci); /* YCbCr 4:2:0, JFIF, ISLOW, standard Huffman tables */
    jpeg_set_quality(ci, j->quality, TRUE);
    ci->restart_interval = j->restart;
    jpeg_start_compress(ci, TRUE);
    JSAMPROW rows[JPG_ROWS];
    while (ci->next_scanline < ci->image_height) {
        JDIMENSION n = ci->image_height - ci->next_scanline;
        if (n > JPG_ROWS) n = JPG_ROWS;
        for (JDIMENSION i = 0; i < n; i++) /* libjpeg only reads the rows */
            rows[i] = (JSAMPROW)(uintptr_t)(j->px + (size_t)(ci->next_scanline + i) * j->stride);
        jpeg_write_scanlines(ci, rows, n);
    }
    jpeg_finish_compress(ci);
}

/* Compresses into s (file or memory). */
static int jpg_encode_to(void *job, vt_sink *s)
{
    jpg_job *j = job;
    j->dest = (jpg_dest){.pub = {.init_destination = jpg_dest_init,
                                 .empty_output_buffer = jpg_dest_empty,
                                 .term_destination = jpg_dest_term},
                         .s = s};
    memset(&j->ci, 0, sizeof j->ci); /* ->mem NULL: destroy is safe if create fails */
    j->ci.err = &j->err.pub;
    int rc = jpg_guarded(j, jpg_compress_body);
    if (rc != 0) rc = jpg_code(&j->err, s, VT_ERR_CODEC);
    jpeg_destroy_compress(&j->ci);
    return rc;
}

static int jpg_check(vt_call *c, uint32_t width, uint32_t height, const uint8_t *pix,
                     size_t stride, uint32_t pixel_bytes, int quality)
{
    if (pixel_bytes != 3 && pixel_bytes != 4) {
        vt_call_msg(c, "pixel_bytes %u: must be 3 (RGB) or 4 (RGBA)", pixel_bytes);
        return VT_ERR_INVALID;
    }
    int rc = vt_image_check_pixels(c, width, height, pix, stride, pixel_bytes);
    if (rc == 0 && (quality < 1 || quality > 100)) {
        vt_call_msg(c, "quality %d outside 1..100", quality);
        rc = VT_ERR_INVALID;
    }
    return rc;
}

int vt_jpeg_write(const char *path, uint32_t width, uint32_t height, const uint8_t *pix,
                  size_t row_stride_bytes, uint32_t pixel_bytes, int quality, char *err,
                  size_t errlen)
{
    vt_call c = vt_call_begin(path, err, errlen);
    int rc = vt_image_check_path(&c, path);
    if (rc == 0) rc = jpg_check(&c, width, height, pix, row_stride_bytes, pixel_bytes, quality);
    if (rc != 0) return vt_call_end(&c, rc);
    jpg_job *j = calloc(1, sizeof *j); /* ~2 KiB of libjpeg structs: not on the stack */
    if (!j) {
        vt_call_msg(&c, "out of memory");
        return vt_call_end(&c, VT_ERR_NOMEM);
    }
    *j = (jpg_job){.px = pix, .stride = row_stride_bytes, .pixel_bytes = pixel_bytes,
                   .quality = quality, .w = width, .h = height};
    jpg_err_init(&j->err, &c);
    rc = vt_sink_write_file(&c, path, jpg_encode_to, j);
    free(j);
    return vt_call_end(&c, rc);
}

/* The in-memory encode of vt_jpeg_encode and of each band of
 * vt_jpeg_encode_par (restart: the interval in MCUs, 0 none); the
 * arguments are checked. */
static int jpg_encode_mem(vt_call *c, uint32_t width, uint32_t height, const uint8_t *pix, size_t stride,
                          uint32_t pixel_bytes, int quality, unsigned restart, uint8_t **out, size_t *out_len)
{
    jpg_job *j = calloc(1, sizeof *j);
    if (!j) {
        vt_call_msg(c, "out of memory");
        return VT_ERR_NOMEM;
    }
    *j = (jpg_job){.px = pix, .stride = stride, .pixel_bytes = pixel_bytes, .quality = quality,
                   .restart = restart, .w = width, .h = height};
    jpg_err_init(&j->err, c);
    /* first guess 1/4 byte per pixel (2 bits: q85 on rendered frames);
     * doubling from there */
    int rc = vt_sink_encode_mem(c, (size_t)width * height / 4, jpg_encode_to, j, out, out_len);
    free(j);
    return rc;
}

static int jpg_check_mem(vt_call *c, uint32_t width, uint32_t height, const uint8_t *pix, size_t stride,
                         uint32_t pixel_bytes, int quality, uint8_t **out, size_t *out_len)
{
    if (out) *out = NULL;
    if (out_len) *out_len = 0;
    int rc = jpg_check(c, width, height, pix, stride, pixel_bytes, quality);
    if (rc == 0 && (!out || !out_len)) {
        vt_call_msg(c, "no output for the stream");
        rc = VT_ERR_INVALID;
    }
    return rc;
}

int vt_jpeg_encode(uint32_t width, uint32_t height, const uint8_t *pix, size_t row_stride_bytes,
                   uint32_t pixel_bytes, int quality, uint8_t **out, size_t *out_len, char *err,
                   size_t errlen)
{
    vt_call c = vt_call_begin("<memory>", err, errlen);
    int rc = jpg_check_mem(&c, width, height, pix, row_stride_bytes, pixel_bytes, quality, out, out_len);
    if (rc == 0) rc = jpg_encode_mem(&c, width, height, pix, row_stride_bytes, pixel_bytes, quality, 0, out, out_len);
    return vt_call_end(&c, rc);
}

/* ---- JPEG in bands (vt_jpeg_encode_par) ------------------------------------- */

/* The MCU of jpeg_set_defaults' YCbCr 4:2:0: 16 x 16 pixels. */
#define JPG_MCU 16

typedef struct jpg_band {
    uint8_t *buf; /* the band's own JPEG stream */
    size_t   len;
    int      rc;
    char     err[256];
} jpg_band;

typedef struct jpg_par_job {
    atomic_uint        next; /* the next band to take */
    const uint8_t     *px;
    size_t             stride;
    uint32_t           pixel_bytes, w, h, rows, n;
    int                quality;
    unsigned           restart;
    const vt_jpeg_par *par;
    jpg_band           band[VT_JPEG_MAX_BANDS];
} jpg_par_job;

static void jpg_band_one(jpg_par_job *p, uint32_t t)
{
    jpg_band *b = &p->band[t];
    uint32_t y0 = t * p->rows, y1 = p->h - y0 > p->rows ? y0 + p->rows : p->h;
    vt_call c = vt_call_begin("band", b->err, sizeof b->err);
    if (p->par->rows_hook && (b->rc = p->par->rows_hook(p->par->hook_ctx, y0, y1))) {
        vt_call_msg(&c, "rows %u..%u: %s", y0, y1, vt_strerror(b->rc));
        return;
    }
    b->rc = jpg_encode_mem(&c, p->w, y1 - y0, p->px + (size_t)y0 * p->stride, p->stride, p->pixel_bytes,
                           p->quality, p->restart, &b->buf, &b->len);
}

/* A runner's job: bands taken in order until none is left, whichever t
 * (more bands than threads balance the load; a runner that runs fewer
 * jobs than asked, as a pool clamps n to its threads, leaves the rest to
 * the caller's own loop). */
static void jpg_band_run(void *arg, uint32_t t)
{
    jpg_par_job *p = arg;
    (void)t;
    for (uint32_t k; (k = atomic_fetch_add(&p->next, 1)) < p->n;) jpg_band_one(p, k);
}

/* Where a libjpeg stream's entropy-coded data begins (past the SOS
 * segment; markers before it are FF xx and a 2-byte length) and, in
 * *sof, the offset of SOF0's height; 0 if the stream is not laid out so,
 * or does not end in EOI right after its scan. */
static size_t jpg_scan_at(const uint8_t *b, size_t n, size_t *sof)
{
    size_t i = 2;
    if (n < 4 || b[0] != 0xFF || b[1] != 0xD8 || b[n - 2] != 0xFF || b[n - 1] != 0xD9) return 0;
    while (i + 4 <= n && b[i] == 0xFF) {
        uint8_t m = b[i + 1];
        size_t len = (size_t)b[i + 2] << 8 | b[i + 3];
        if (m == 0xC0 && len >= 8 && sof) *sof = i + 5;
        i += 2 + len;
        if (m == 0xDA) return i + 2 <= n ? i : 0;
    }
    return 0;
}

/* The bands' streams into one: band 0 to its scan's end, then for each
 * further band RSTn and its scan. */
static int jpg_splice(vt_call *c, jpg_par_job *p, uint8_t **out, size_t *out_len)
{
    size_t at[VT_JPEG_MAX_BANDS], sof = 0, total = 2;
    for (uint32_t t = 0; t < p->n; t++) {
        if (!(at[t] = jpg_scan_at(p->band[t].buf, p->band[t].len, t ? NULL : &sof)) || (t == 0 && !sof)) {
            vt_call_msg(c, "band %u: not a stream of one scan", t);
            return VT_ERR_CODEC;
        }
        total += t ? 2 + p->band[t].len - 2 - at[t] : p->band[t].len - 2;
    }
    uint8_t *o = malloc(total);
    if (!o) {
        vt_call_msg(c, "out of memory");
        return VT_ERR_NOMEM;
    }
    size_t k = p->band[0].len - 2;
    memcpy(o, p->band[0].buf, k);
    o[sof] = (uint8_t)(p->h >> 8), o[sof + 1] = (uint8_t)p->h;
    for (uint32_t t = 1; t < p->n; t++) {
        o[k++] = 0xFF, o[k++] = (uint8_t)(0xD0 + ((t - 1) & 7)); /* RST0, RST1, .. RST7, RST0 */
        size_t m = p->band[t].len - 2 - at[t];
        memcpy(o + k, p->band[t].buf + at[t], m);
        k += m;
    }
    o[k++] = 0xFF, o[k++] = 0xD9;
    *out = o;
    *out_len = k;
    return 0;
}

int vt_jpeg_encode_par(uint32_t width, uint32_t height, const uint8_t *pix, size_t row_stride_bytes,
                       uint32_t pixel_bytes, int quality, const vt_jpeg_par *par, uint8_t **out, size_t *out_len,
                       char *err, size_t errlen)
{
    vt_call c = vt_call_begin("<memory>", err, errlen);
    int rc = jpg_check_mem(&c, width, height, pix, row_stride_bytes, pixel_bytes, quality, out, out_len);
    if (rc != 0) return vt_call_end(&c, rc);
    /* bands of whole MCU rows, as even as that allows */
    uint32_t n = par && par->run ? par->bands : 1;
    n = n < 1 ? 1 : n > VT_JPEG_MAX_BANDS ? VT_JPEG_MAX_BANDS : n;
    uint32_t rows = ((height + n - 1) / n + JPG_MCU - 1) / JPG_MCU * JPG_MCU;
    n = (height + rows - 1) / rows;
    uint64_t restart = (uint64_t)rows / JPG_MCU * ((width + JPG_MCU - 1) / JPG_MCU);
    if (n < 2 || restart > 65535) {
        /* one band: JPEG's restart interval is 16 bits */
        if (par && par->rows_hook && (rc = par->rows_hook(par->hook_ctx, 0, height)))
            vt_call_msg(&c, "rows 0..%u: %s", height, vt_strerror(rc));
        if (rc == 0)
            rc = jpg_encode_mem(&c, width, height, pix, row_stride_bytes, pixel_bytes, quality, 0, out, out_len);
        return vt_call_end(&c, rc);
    }
    jpg_par_job *p = calloc(1, sizeof *p);
    if (!p) {
        vt_call_msg(&c, "out of memory");
        return vt_call_end(&c, VT_ERR_NOMEM);
    }
    *p = (jpg_par_job){.px = pix, .stride = row_stride_bytes, .pixel_bytes = pixel_bytes, .w = width, .h = height,
                       .rows = rows, .n = n, .quality = quality, .restart = (unsigned)restart, .par = par};
    atomic_init(&p->next, 0);
    par->run(par->run_ctx, jpg_band_run, p, n);
    jpg_band_run(p, 0); /* any band left */
    for (uint32_t t = 0; t < n && rc == 0; t++)
        if ((rc = p->band[t].rc)) vt_call_msg(&c, "%s", p->band[t].err);
    if (rc == 0) rc = jpg_splice(&c, p, out, out_len);
    for (uint32_t t = 0; t < n; t++) free(p->band[t].buf);
    free(p);
    return vt_call_end(&c, rc);
}

typedef struct jpg_frame {
    uint32_t               w;
    const float           *top; /* the frame's top row */
    ptrdiff_t              ys;  /* floats from one row to the one below it */
    const vt_tonemap_desc *td;
    uint8_t               *out;
} jpg_frame;

static int jpg_frame_rows(void *arg, uint32_t y0, uint32_t y1)
{
    const jpg_frame *f = arg;
    const float *row = f->top + (ptrdiff_t)y0 * f->ys;
    vt_image_src src = {.r = {row, 4, f->ys}, .g = {row + 1, 4, f->ys}, .b = {row + 2, 4, f->ys}};
    return vt_image_tonemap(f->w, y1 - y0, &src, f->td, f->out + (size_t)y0 * 4 * f->w, 4 * (size_t)f->w);
}

int vt_jpeg_encode_frame(uint32_t width, uint32_t height, const float *rgba, size_t stride,
                         const vt_tonemap_desc *desc, uint8_t *rgba8, int quality, uint32_t bands,
                         void (*run)(void *run_ctx, vt_jpeg_job_fn job, void *arg, uint32_t n), void *run_ctx,
                         uint8_t **out, size_t *out_len, char *err, size_t errlen)
{
    if (!rgba || !height || stride < width) {
        vt_call c = vt_call_begin("<memory>", err, errlen);
        if (out) *out = NULL;
        if (out_len) *out_len = 0;
        vt_call_msg(&c, "no frame (%ux%u, stride %zu)", width, height, stride);
        return vt_call_end(&c, VT_ERR_INVALID);
    }
    jpg_frame f = {.w = width, .top = rgba + (size_t)(height - 1) * stride * 4, .ys = -(ptrdiff_t)stride * 4,
                   .td = desc, .out = rgba8};
    vt_jpeg_par par = {.bands = bands, .run = run, .run_ctx = run_ctx, .rows_hook = jpg_frame_rows, .hook_ctx = &f};
    return vt_jpeg_encode_par(width, height, rgba8, 4 * (size_t)width, 4, quality, &par, out, out_len, err, errlen);
}

/* vt_tonemap_frame's bands: band t of n tone-maps its share of the rows. */
typedef struct tm_bands {
    jpg_frame f;
    uint32_t height, n;
    atomic_uint next; /* the next band to take: a runner may start fewer jobs than bands */
    int rc[VT_JPEG_MAX_BANDS];
} tm_bands;

static void tm_band(void *arg, uint32_t t)
{
    tm_bands *b = arg;
    (void)t;
    for (uint32_t k; (k = atomic_fetch_add(&b->next, 1)) < b->n;) {
        uint32_t y0 = (uint32_t)((uint64_t)b->height * k / b->n), y1 = (uint32_t)((uint64_t)b->height * (k + 1) / b->n);
        b->rc[k] = y1 > y0 ? jpg_frame_rows(&b->f, y0, y1) : 0;
    }
}

int vt_tonemap_frame(uint32_t width, uint32_t height, const float *rgba, size_t stride, const vt_tonemap_desc *desc,
                     uint8_t *rgba8, uint32_t bands, void (*run)(void *run_ctx, vt_jpeg_job_fn job, void *arg, uint32_t n),
                     void *run_ctx)
{
    if (!rgba || !rgba8 || !width || !height || stride < width) return VT_ERR_INVALID;
    tm_bands b = {.f = {.w = width, .top = rgba + (size_t)(height - 1) * stride * 4, .ys = -(ptrdiff_t)stride * 4,
                        .td = desc, .out = rgba8},
                  .height = height,
                  .n = bands < 1 ? 1 : bands > VT_JPEG_MAX_BANDS ? VT_JPEG_MAX_BANDS : bands};
    if (!run || b.n == 1) return jpg_frame_rows(&b.f, 0, height);
    atomic_init(&b.next, 0);
    run(run_ctx, tm_band, &b, b.n);
    for (uint32_t t = 0; t < b.n; t++)
        if (b.rc[t]) return b.rc[t];
    return 0;
}

static void jpg_decompress_body(jpg_job *j)
{
    struct jpeg_decompress_struct *di = &j->di;
    j_common_ptr cp = (j_common_ptr)di;
    jpeg_create_decompress(di);
    jpeg_mem_src(di, j->data, (unsigned long)j->len); /* no allocation; empty: an error */
    jpeg_read_header(di, TRUE);
    if (di->image_width > VT_IMAGE_MAX_DIM || di->image_height > VT_IMAGE_MAX_DIM)
        jpg_abort(cp, VT_ERR_TOO_LARGE, "image %ux%u larger than %ux%u", di->image_width, di->image_height,
                  VT_IMAGE_MAX_DIM, VT_IMAGE_MAX_DIM);
    if (di->jpeg_color_space != JCS_GRAYSCALE && di->jpeg_color_space != JCS_YCbCr &&
        di->jpeg_color_space != JCS_RGB)
        jpg_abort(cp, VT_ERR_UNSUPPORTED, "colour space %d (CMYK / YCCK?) not supported",
                  (int)di->jpeg_color_space);
    if (j->header_only) {
        j->w = di->image_width;
        j->h = di->image_height;
        return;
    }
    di->out_color_space = JCS_RGB;
    di->dct_method = JDCT_ISLOW;
    jpeg_start_decompress(di);
    if (di->output_components != 3 || di->output_width != di->image_width ||
        di->output_height != di->image_height || di->output_width < 1 || di->output_height < 1)
        jpg_abort(cp, VT_ERR_CODEC, "libjpeg output %ux%ux%d, expected %ux%ux3", di->output_width,
                  di->output_height, di->output_components, di->image_width, di->image_height);
    size_t row = (size_t)di->output_width * 3;
    j->pix = malloc(row * di->output_height);
    if (!j->pix)
        jpg_abort(cp, VT_ERR_NOMEM, "out of memory for %ux%u", di->output_width, di->output_height);
    JSAMPROW rows[JPG_ROWS];
    while (di->output_scanline < di->output_height) {
        JDIMENSION n = di->output_height - di->output_scanline;
        if (n > JPG_ROWS) n = JPG_ROWS;
        for (JDIMENSION i = 0; i < n; i++)
            rows[i] = j->pix + (size_t)(di->output_scanline + i) * row;
        jpeg_read_scanlines(di, rows, n);
    }
    jpeg_finish_decompress(di);
    j->w = di->output_width;
    j->h = di->output_height;
}

static int jpg_decode(vt_call *c, const uint8_t *data, size_t len, uint8_t **rgb8,
                      uint32_t *width, uint32_t *height)
{
    if (!data || !width || !height) { /* rgb8 NULL: the header only */
        vt_call_msg(c, "no input, or no output for the image's size");
        return VT_ERR_INVALID;
    }
    if (len == 0 || len > ULONG_MAX) {
        vt_call_msg(c, "stream of %zu bytes", len);
        return len ? VT_ERR_TOO_LARGE : VT_ERR_CORRUPT;
    }
    jpg_job *j = calloc(1, sizeof *j);
    if (!j) {
        vt_call_msg(c, "out of memory");
        return VT_ERR_NOMEM;
    }
    j->data = data;
    j->len = len;
    j->header_only = !rgb8;
    jpg_err_init(&j->err, c);
    j->di.err = &j->err.pub;
    int rc = jpg_guarded(j, jpg_decompress_body);
    if (rc != 0) rc = jpg_code(&j->err, NULL, VT_ERR_CORRUPT);
    jpeg_destroy_decompress(&j->di);
    if (rc == 0) {
        if (rgb8) *rgb8 = j->pix;
        *width = j->w;
        *height = j->h;
    } else {
        free(j->pix);
    }
    free(j);
    return rc;
}

int vt_jpeg_decode(const uint8_t *data, size_t len, uint8_t **rgb8, uint32_t *width,
                   uint32_t *height, char *err, size_t errlen)
{
    vt_call c = vt_call_begin("<memory>", err, errlen);
    if (rgb8) *rgb8 = NULL;
    if (width) *width = 0;
    if (height) *height = 0;
    if (!rgb8) { /* NULL is vt_jpeg_info's (the header only), not this call's */
        vt_call_msg(&c, "no output for the image");
        return vt_call_end(&c, VT_ERR_INVALID);
    }
    return vt_call_end(&c, jpg_decode(&c, data, len, rgb8, width, height));
}

int vt_jpeg_info(const uint8_t *data, size_t len, uint32_t *width, uint32_t *height, char *err, size_t errlen)
{
    vt_call c = vt_call_begin("<memory>", err, errlen);
    if (width) *width = 0;
    if (height) *height = 0;
    return vt_call_end(&c, jpg_decode(&c, data, len, NULL, width, height));
}

/* Largest file vt_jpeg_read loads. */
#define JPG_MAX_FILE ((size_t)1 << 30)

int vt_jpeg_read(const char *path, uint8_t **rgb8, uint32_t *width, uint32_t *height, char *err,
                 size_t errlen)
{
    vt_call c = vt_call_begin(path, err, errlen);
    char buf[128];
    if (rgb8) *rgb8 = NULL;
    if (width) *width = 0;
    if (height) *height = 0;
    int rc = vt_image_check_path(&c, path);
    if (rc != 0) return vt_call_end(&c, rc);
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0) {
        int e = errno;
        rc = vt_err_from_errno(e);
        vt_call_msg(&c, "open: %s", vt_errno_text(e, buf, sizeof buf));
        return vt_call_end(&c, rc);
    }
    struct stat st;
    uint8_t *data = NULL;
    size_t len = 0;
    if (fstat(fd, &st) != 0) {
        int e = errno;
        rc = vt_err_from_errno(e);
        vt_call_msg(&c, "stat: %s", vt_errno_text(e, buf, sizeof buf));
    } else if (!S_ISREG(st.st_mode) || st.st_size < 0 || (uint64_t)st.st_size > JPG_MAX_FILE) {
        vt_call_msg(&c, "not a regular file of at most %zu bytes", JPG_MAX_FILE);
        rc = S_ISREG(st.st_mode) ? VT_ERR_TOO_LARGE : VT_ERR_INVALID;
    } else if (!(data = malloc(st.st_size ? (size_t)st.st_size : 1))) {
        vt_call_msg(&c, "out of memory");
        rc = VT_ERR_NOMEM;
    }
    while (rc == 0 && len < (size_t)st.st_size) { /* a file that shrinks meanwhile ends early */
        ssize_t n = read(fd, data + len, (size_t)st.st_size - len);
        if (n < 0 && errno == EINTR) continue;
        if (n < 0) {
            int e = errno;
            rc = vt_err_from_errno(e);
            vt_call_msg(&c, "read: %s", vt_errno_text(e, buf, sizeof buf));
        }
        if (n <= 0) break;
        len += (size_t)n;
    }
    close(fd);
    if (rc == 0) rc = jpg_decode(&c, data, len, rgb8, width, height);
    free(data);
    return vt_call_end(&c, rc);
}
