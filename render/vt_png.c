/*
 * vt_png.c — PNG files for vt_image.h through libpng 1.6: the writer (RGB
 * or RGBA, through the shared sink into a temporary file renamed into
 * place, vt_sink.h) and the reader to RGBA8 (for the tests and tools).
 *
 * libpng and libjpeg report fatal errors by longjmp. The rule here: the
 * function that calls setjmp does nothing else (png_guarded, jpg_guarded:
 * no locals change after setjmp, so none is left indeterminate and none
 * needs volatile), and every resource the longjmp could strand lives in a
 * job struct owned by the caller, which frees it on either path. Bodies
 * store each allocation in the job before the next library call.
 *
 * Measured on the development machine (one core of a 2-core AMD EPYC VM,
 * gcc 12 -O2, medians of 15), a 1280x720 frame of an HDR ramp with a
 * bright spot, smooth / with 8% grain, tone mapped: RGB level 1 37 / 56 ms
 * (424 / 892 KB), level 6 136 / 294 ms (276 / 754 KB), RGBA level 1 45 /
 * 70 ms; PNG read 8 / 14 ms. 16384x16384: level 1 9.5 s. libpng's
 * adaptive filter choice costs about a third of the level-1 time; a fixed
 * SUB filter was faster and no larger on these images, but that depends
 * on content, so the default stays.
 */
#ifndef _GNU_SOURCE
#define _GNU_SOURCE
#endif
#include "vt_image.h"
#include "vt_sink.h"

#include <errno.h>
#include <fcntl.h>
#include <setjmp.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <png.h>

/* ---- PNG ------------------------------------------------------------------- */

typedef struct png_job {
    vt_call     *c;
    png_structp   png;
    png_infop     info;
    bool          nomem;   /* an allocation failed: the likely cause */
    bool          too_big; /* reading: larger than VT_IMAGE_MAX_DIM */
    /* writing */
    vt_sink         *out;
    const uint8_t *px;
    size_t        stride;
    bool          alpha;
    int           level;
    /* reading: from fd, or from mem[0..mem_len) when mem is set */
    int           fd;
    int           io_err;  /* errno of a failed read */
    const uint8_t *mem;
    size_t        mem_len, mem_pos;
    bool          header_only; /* the size only: no pixel is allocated */
    uint8_t      *pix;     /* the decoded image, malloc'ed */
    png_bytep    *rows;    /* row pointers into pix, malloc'ed */
    bool          has_alpha;
    uint32_t      w, h;
} png_job;

static void png_on_error(png_structp png, png_const_charp msg)
{
    png_job *j = png_get_error_ptr(png);
    vt_call_msg(j->c, "%s", msg ? msg : "libpng error");
    png_longjmp(png, 1);
}

/* Warnings (ancillary chunks dropped, CRCs of unknown chunks) change no
 * pixel; they are not printed either. */
static void png_on_warning(png_structp png, png_const_charp msg)
{
    (void)png;
    (void)msg;
}

static png_voidp png_on_malloc(png_structp png, png_alloc_size_t n)
{
    void *p = malloc(n);
    png_job *j = png_get_mem_ptr(png);
    if (!p && j) j->nomem = true;
    return p;
}

static void png_on_free(png_structp png, png_voidp p)
{
    (void)png;
    free(p);
}

static void png_on_write(png_structp png, png_bytep data, size_t n)
{
    png_job *j = png_get_io_ptr(png);
    if (!vt_sink_put(j->out, data, n)) png_error(png, "write failed");
}

static void png_on_flush(png_structp png)
{
    (void)png; /* the vt_sink is flushed once, at the end */
}

static void png_on_read(png_structp png, png_bytep data, size_t n)
{
    png_job *j = png_get_io_ptr(png);
    char buf[128];
    if (j->mem) {
        if (n > j->mem_len - j->mem_pos) png_error(png, "unexpected end of the stream");
        memcpy(data, j->mem + j->mem_pos, n);
        j->mem_pos += n;
        return;
    }
    while (n > 0) {
        ssize_t got = read(j->fd, data, n);
        if (got < 0 && errno == EINTR) continue;
        if (got < 0) {
            j->io_err = errno;
            vt_call_msg(j->c, "read: %s", vt_errno_text(errno, buf, sizeof buf));
            png_error(png, "read failed");
        }
        if (got == 0) png_error(png, "unexpected end of file");
        data += got;
        n -= (size_t)got;
    }
}

/* The only function that calls setjmp for libpng (see the top). */
static int png_guarded(png_job *j, void (*body)(png_job *))
{
    if (setjmp(png_jmpbuf(j->png))) return -1;
    body(j);
    return 0;
}

static void png_write_body(png_job *j)
{
    png_structp png = j->png;
    png_infop info = j->info;
    png_uint_32 w = j->w, h = j->h;
    png_set_write_fn(png, j, png_on_write, png_on_flush);
    if (j->level >= 0) png_set_compression_level(png, j->level);
    png_set_IHDR(png, info, w, h, 8, j->alpha ? PNG_COLOR_TYPE_RGB_ALPHA : PNG_COLOR_TYPE_RGB,
                 PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    png_set_sRGB(png, info, PNG_sRGB_INTENT_PERCEPTUAL);
    png_write_info(png, info);
    if (!j->alpha) png_set_filler(png, 0, PNG_FILLER_AFTER); /* rows stay RGBA: skip A */
    for (png_uint_32 y = 0; y < h; y++) png_write_row(png, j->px + (size_t)y * j->stride);
    png_write_end(png, NULL);
}

static int png_encode(void *job, vt_sink *s)
{
    png_job *j = job;
    j->out = s;
    j->png = png_create_write_struct_2(PNG_LIBPNG_VER_STRING, j, png_on_error, png_on_warning, j,
                                       png_on_malloc, png_on_free);
    if (j->png) j->info = png_create_info_struct(j->png);
    int rc = j->info ? png_guarded(j, png_write_body) : -1;
    if (rc != 0) {
        rc = s->err ? vt_err_from_errno(s->err) : j->nomem || !j->info ? VT_ERR_NOMEM : VT_ERR_CODEC;
        vt_call_msg(j->c, "libpng failed");
    }
    png_destroy_write_struct(&j->png, &j->info);
    return rc;
}

int vt_png_write(const char *path, uint32_t width, uint32_t height, const uint8_t *rgba8,
                 size_t row_stride_bytes, bool alpha, int compression_level, char *err,
                 size_t errlen)
{
    vt_call c = vt_call_begin(path, err, errlen);
    int rc = vt_image_check_path(&c, path);
    if (rc == 0) rc = vt_image_check_pixels(&c, width, height, rgba8, row_stride_bytes, 4);
    if (rc == 0 && (compression_level < -1 || compression_level > 9)) {
        vt_call_msg(&c, "compression level %d outside -1..9", compression_level);
        rc = VT_ERR_INVALID;
    }
    if (rc != 0) return vt_call_end(&c, rc);
    png_job j = {.c = &c, .px = rgba8, .stride = row_stride_bytes, .alpha = alpha,
                 .level = compression_level, .w = width, .h = height, .fd = -1};
    return vt_call_end(&c, vt_sink_write_file(&c, path, png_encode, &j));
}

int vt_png_encode(uint32_t width, uint32_t height, const uint8_t *rgba8, size_t row_stride_bytes, bool alpha,
                  int compression_level, uint8_t **out, size_t *out_len, char *err, size_t errlen)
{
    vt_call c = vt_call_begin("<memory>", err, errlen);
    if (out) *out = NULL;
    if (out_len) *out_len = 0;
    int rc = vt_image_check_pixels(&c, width, height, rgba8, row_stride_bytes, 4);
    if (rc == 0 && (compression_level < -1 || compression_level > 9)) {
        vt_call_msg(&c, "compression level %d outside -1..9", compression_level);
        rc = VT_ERR_INVALID;
    }
    if (rc == 0 && (!out || !out_len)) {
        vt_call_msg(&c, "no output for the stream");
        rc = VT_ERR_INVALID;
    }
    if (rc != 0) return vt_call_end(&c, rc);
    png_job j = {.c = &c, .px = rgba8, .stride = row_stride_bytes, .alpha = alpha,
                 .level = compression_level, .w = width, .h = height, .fd = -1};
    return vt_call_end(&c, vt_sink_encode_mem(&c, (size_t)width * height, png_encode, &j, out, out_len));
}

static void png_read_body(png_job *j)
{
    png_structp png = j->png;
    png_infop info = j->info;
    png_uint_32 w = 0, h = 0;
    int depth = 0, ctype = 0;
    png_set_read_fn(png, j, png_on_read);
    png_read_info(png, info);
    png_get_IHDR(png, info, &w, &h, &depth, &ctype, NULL, NULL, NULL);
    if (w > VT_IMAGE_MAX_DIM || h > VT_IMAGE_MAX_DIM) {
        j->too_big = true;
        vt_call_msg(j->c, "image %ux%u larger than %ux%u", (unsigned)w, (unsigned)h, VT_IMAGE_MAX_DIM,
                 VT_IMAGE_MAX_DIM);
        png_error(png, "image too large");
    }
    if (j->header_only) {
        j->w = w;
        j->h = h;
        return;
    }
    bool trns = png_get_valid(png, info, PNG_INFO_tRNS) != 0;
    j->has_alpha = (ctype & PNG_COLOR_MASK_ALPHA) || trns;
    if (ctype == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(png);
    if (ctype == PNG_COLOR_TYPE_GRAY && depth < 8) png_set_expand_gray_1_2_4_to_8(png);
    if (trns) png_set_tRNS_to_alpha(png);
    if (depth == 16) png_set_scale_16(png);
    if (!(ctype & PNG_COLOR_MASK_COLOR)) png_set_gray_to_rgb(png);
    if (!j->has_alpha) png_set_filler(png, 0xff, PNG_FILLER_AFTER);
    png_set_interlace_handling(png);
    png_read_update_info(png, info);
    if (png_get_rowbytes(png, info) != (size_t)w * 4 || png_get_bit_depth(png, info) != 8)
        png_error(png, "unexpected row layout after conversion to RGBA8");
    j->pix = malloc((size_t)w * h * 4);
    j->rows = malloc((size_t)h * sizeof *j->rows);
    if (!j->pix || !j->rows) {
        j->nomem = true;
        png_error(png, "out of memory for the image");
    }
    for (png_uint_32 y = 0; y < h; y++) j->rows[y] = j->pix + (size_t)y * w * 4;
    png_read_image(png, j->rows);
    png_read_end(png, NULL); /* the rest of the file: CRCs, IEND */
    j->w = w;
    j->h = h;
}

/* Runs a read job (its source set): the image (or, header_only, its size)
 * into j, or a code with nothing left allocated. */
static int png_decode_job(vt_call *c, png_job *j)
{
    int rc;
    j->png = png_create_read_struct_2(PNG_LIBPNG_VER_STRING, j, png_on_error, png_on_warning, j,
                                      png_on_malloc, png_on_free);
    if (j->png) j->info = png_create_info_struct(j->png);
    rc = j->info ? png_guarded(j, png_read_body) : -1;
    if (rc != 0) {
        rc = j->io_err ? vt_err_from_errno(j->io_err)
             : j->nomem || !j->info ? VT_ERR_NOMEM
             : j->too_big ? VT_ERR_TOO_LARGE
             : VT_ERR_CORRUPT;
        vt_call_msg(c, "libpng failed");
    }
    png_destroy_read_struct(&j->png, &j->info, NULL);
    free(j->rows);
    j->rows = NULL;
    if (rc != 0) {
        free(j->pix);
        j->pix = NULL;
    }
    return rc;
}

int vt_png_read(const char *path, uint8_t **rgba8, uint32_t *width, uint32_t *height,
                bool *has_alpha, char *err, size_t errlen)
{
    vt_call c = vt_call_begin(path, err, errlen);
    char buf[128];
    if (rgba8) *rgba8 = NULL;
    if (width) *width = 0;
    if (height) *height = 0;
    if (has_alpha) *has_alpha = false;
    int rc = vt_image_check_path(&c, path);
    if (rc == 0 && (!rgba8 || !width || !height)) {
        vt_call_msg(&c, "no output for the image or its size");
        rc = VT_ERR_INVALID;
    }
    if (rc != 0) return vt_call_end(&c, rc);
    png_job j = {.c = &c, .fd = open(path, O_RDONLY | O_CLOEXEC)};
    if (j.fd < 0) {
        int e = errno;
        rc = vt_err_from_errno(e);
        vt_call_msg(&c, "open: %s", vt_errno_text(e, buf, sizeof buf));
        return vt_call_end(&c, rc);
    }
    rc = png_decode_job(&c, &j);
    close(j.fd);
    if (rc != 0) return vt_call_end(&c, rc);
    *rgba8 = j.pix;
    *width = j.w;
    *height = j.h;
    if (has_alpha) *has_alpha = j.has_alpha;
    return vt_call_end(&c, 0);
}

int vt_png_decode(const uint8_t *data, size_t len, uint8_t **rgba8, uint32_t *width, uint32_t *height,
                  bool *has_alpha, char *err, size_t errlen)
{
    vt_call c = vt_call_begin("<memory>", err, errlen);
    if (rgba8) *rgba8 = NULL;
    if (width) *width = 0;
    if (height) *height = 0;
    if (has_alpha) *has_alpha = false;
    if (!data || !len || !width || !height) {
        vt_call_msg(&c, "no stream, or no output for its size");
        return vt_call_end(&c, data && !len ? VT_ERR_CORRUPT : VT_ERR_INVALID);
    }
    png_job j = {.c = &c, .fd = -1, .mem = data, .mem_len = len, .header_only = !rgba8};
    int rc = png_decode_job(&c, &j);
    if (rc != 0) return vt_call_end(&c, rc);
    if (rgba8) *rgba8 = j.pix;
    *width = j.w;
    *height = j.h;
    if (has_alpha) *has_alpha = j.has_alpha;
    return vt_call_end(&c, 0);
}
