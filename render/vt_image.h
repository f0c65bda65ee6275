/*
 * vt_image.h — 8-bit image output for the renderer: tone mapping of linear
 * HDR float RGBA (any layout: planar, interleaved, bottom-up) to 8-bit
 * sRGB, PNG files, and JPEG files or in-memory JPEG streams. Small
 * readers (PNG to RGBA8, JPEG to RGB8) serve the tests and tools.
 *
 * Built on libpng 1.6 (Debian: libpng-dev, pkg-config libpng) and the
 * libjpeg API of libjpeg-turbo 2.1 (Debian: libjpeg62-turbo-dev,
 * pkg-config libjpeg).
 *
 * Load it expects: a frame at a time, 1x1 to 16384x16384 pixels. Costs on
 * one core for 1280x720 (details in vt_tonemap.c, vt_png.c, vt_jpeg.c):
 * tone mapping 15 ms; PNG level 1 40-60 ms, level 6 130-300 ms (zlib
 * dominates); JPEG quality 85 2-3 ms (SIMD libjpeg-turbo). Memory: the PNG and JPEG writers hold a
 * 64 KiB output buffer plus the libraries' row buffers (a few rows: up to
 * about 1 MiB at 16384 wide), never a copy of the image; the in-memory
 * JPEG grows its result by doubling. Readers allocate the decoded image.
 *
 * Pixels in 8-bit buffers are R, G, B[, A] bytes in that order, top row
 * first, rows row_stride_bytes apart (>= width x bytes per pixel; the
 * padding is never read or written). 8-bit colour is sRGB-encoded; alpha
 * is linear and straight (not premultiplied), as PNG defines it.
 *
 * Files: like vt_exr_write. The image goes to a new temporary file beside
 * `path` ("path.XXXXXXXXXXXXXXXX.tmp", created with O_EXCL, mode 0666 less
 * the umask) which is renamed over `path` once complete, so a reader never
 * sees a torn file and on any failure `path` is untouched (an old file of
 * that name survives) and the temporary is removed. Not fsync'ed. A
 * symlink at `path` is replaced, not written through.
 *
 * Threading: no shared mutable state but the ACES tone-mapping tables,
 * built once on first use (pthread_once) and read-only after; no
 * thread-locals (both libraries hand each call's own state to their error
 * callbacks). Any number of calls may run at once on different paths.
 *
 * Errors: 0 or a negative code from render/'s table (vt_err.h), never an
 * errno — VT_ERR_INVALID bad arguments (including a size outside
 * 1..VT_IMAGE_MAX_DIM), VT_ERR_NOMEM, VT_ERR_NOT_FOUND a missing file,
 * VT_ERR_FILE any other file-system failure (EACCES, ENOSPC, EFBIG, ...:
 * strerror's text is in the message), VT_ERR_CORRUPT a file or stream that
 * is not a valid PNG / JPEG or is corrupt (for JPEG this includes data
 * libjpeg would only warn about, e.g. a truncated stream),
 * VT_ERR_UNSUPPORTED a valid image these readers do not handle (CMYK JPEG),
 * VT_ERR_TOO_LARGE an image larger than VT_IMAGE_MAX_DIM (or a JPEG file
 * over 1 GiB), VT_ERR_CODEC anything else a library reports. `err` (may be NULL, any errlen) receives a
 * NUL-terminated message, the library's own where it gave one, prefixed
 * with the path ("<memory>" for streams); it is set to "" on success.
 */
#ifndef VANTAGE_VT_IMAGE_H
#define VANTAGE_VT_IMAGE_H

#include "vt_err.h"

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Largest width and height accepted by every function here. */
#define VT_IMAGE_MAX_DIM 16384u

/* ---- tone mapping -------------------------------------------------------- */

/* One float channel of the source, laid out as vt_exr_channel's data and
 * strides (vt_exr.h): sample (x, y) at data[x * x_stride + y * y_stride],
 * data the top-left pixel, strides in floats of any sign (1 planar, 4
 * interleaved RGBA, 0 repeats; a negative y_stride for bottom-up rows). */
typedef struct vt_image_channel {
    const float *data;
    ptrdiff_t    x_stride, y_stride;
} vt_image_channel;

/* Source of vt_image_tonemap: linear scene-referred RGB (Rec.709 / sRGB
 * primaries) and optional alpha. r.data is required. g.data and b.data
 * both NULL make a grey image from r (a depth or mask channel); one of
 * them alone is an error. a.data NULL is opaque. */
typedef struct vt_image_src {
    vt_image_channel r, g, b, a;
} vt_image_src;

/* The curve from scene-linear (after exposure) to display-linear [0, 1],
 * applied to R, G and B independently. */
typedef enum vt_tonemap_op {
    VT_TONEMAP_CLAMP = 0, /* min(max(x, 0), 1): LDR content, masks, tests */
    VT_TONEMAP_ACES  = 1, /* Narkowicz's fit of the ACES RRT+ODT filmic curve:
                             x(2.51x+0.03) / (x(2.43x+0.59)+0.14), clamped;
                             1.0 maps to 0.80, white from x = 7.24. For the
                             original ACES exposure use exposure_ev
                             log2(0.6) = -0.737 */
} vt_tonemap_op;

struct vt_lut3d;

/* Zero is the default: exposure 0 EV, CLAMP, straight alpha, no LUT. */
typedef struct vt_tonemap_desc {
    float         exposure_ev;   /* colour times 2^exposure_ev before the
                                    curve; finite, -64..64 */
    vt_tonemap_op op;
    bool          premultiplied; /* the source colour is premultiplied by
                                    alpha (the EXR convention): divided out
                                    first, colour 0 where alpha <= 0; the
                                    output is straight, as PNG wants */
    const struct vt_lut3d *lut;  /* colour grading (vt_lut.h), NULL: none.
                                    Applied after the curve to the display
                                    value sRGB-encoded (0..1), its output
                                    clamped and rounded to 8 bits */
} vt_tonemap_desc;

/* Bytes of an RGBA8 buffer of width x height packed rows (4 * width * height),
 * 0 if the size is outside 1..VT_IMAGE_MAX_DIM. */
size_t vt_image_rgba8_size(uint32_t width, uint32_t height);

/* Tone maps src into out: per pixel, colour c -> sRGB8(curve(c * 2^ev))
 * and alpha a -> round(255 * clamp(a, 0, 1)). NaN becomes 0, +inf 1
 * (255), -inf 0, in colour and alpha. `desc` may be NULL (defaults). out
 * holds height rows of width RGBA pixels, out_stride_bytes >= 4 * width
 * apart (the caller's buffer; size it with vt_image_rgba8_size for packed
 * rows). Reads sample (x, y) of each given channel for 0 <= x < width,
 * 0 <= y < height, nothing else. No allocation.
 * Returns 0 or VT_ERR_INVALID (size, NULL pointers, stride, op, exposure,
 * a LUT without a table). */
int vt_image_tonemap(uint32_t width, uint32_t height, const vt_image_src *src,
                     const vt_tonemap_desc *desc, uint8_t *out, size_t out_stride_bytes);

/* The curve alone, for tests and plots: display-linear [0, 1] for
 * scene-linear x (NaN -> 0, +inf -> 1). Evaluated in double. */
float vt_tonemap_curve(vt_tonemap_op op, float x);

/* The exact sRGB OETF (IEC 61966-2-1: 12.92 v for v <= 0.0031308, else
 * 1.055 v^(1/2.4) - 0.055) scaled to 0..255 and rounded to nearest (half
 * up), for every float: the result is what the real-valued formula gives,
 * not an approximation of it. v <= 0 and NaN give 0, v >= 1 gives 255.
 * A table lookup and one comparison. */
uint8_t vt_srgb8_from_linear(float v);

/* ---- PNG ------------------------------------------------------------------- */

/* Writes `path` as an 8-bit non-interlaced PNG with an sRGB chunk: RGBA
 * (colour type 6) if `alpha`, else RGB (colour type 2, the A bytes are
 * skipped). rgba8 holds height rows of width RGBA pixels (4 bytes each,
 * also when !alpha), row_stride_bytes >= 4 * width apart.
 * compression_level: zlib's 0 (stored) .. 9, or -1 for zlib's default (6).
 * Levels 1-2 are for frames (fast), 6 for files that are kept. Rows are
 * filtered with libpng's adaptive choice (all five filters). Returns 0 or
 * a negative errno value (see the top of this file). */
int vt_png_write(const char *path, uint32_t width, uint32_t height, const uint8_t *rgba8,
                 size_t row_stride_bytes, bool alpha, int compression_level, char *err,
                 size_t errlen);

/* The same PNG in memory: *out (malloc'ed; free()) and *out_len. */
int vt_png_encode(uint32_t width, uint32_t height, const uint8_t *rgba8, size_t row_stride_bytes, bool alpha,
                  int compression_level, uint8_t **out, size_t *out_len, char *err, size_t errlen);

/* Reads a PNG of any colour type, bit depth and interlacing into *rgba8,
 * malloc'ed by this call (caller frees with free()), packed RGBA rows
 * (4 * width bytes each), top row first. Palette and grey are expanded,
 * 16-bit samples are scaled to 8 with rounding, transparency (tRNS)
 * becomes alpha, and images without alpha get A = 255; samples are as
 * stored (no gamma or colour-profile conversion). *has_alpha (may be
 * NULL) says whether the file had alpha or tRNS. On error nothing is
 * allocated and the outputs are 0 / NULL. */
int vt_png_read(const char *path, uint8_t **rgba8, uint32_t *width, uint32_t *height,
                bool *has_alpha, char *err, size_t errlen);

/* vt_png_read of a whole PNG stream in memory, data[0..len) (the daemon's
 * texture uploads). rgba8 NULL reads the header only: *width and *height
 * (checked against VT_IMAGE_MAX_DIM), nothing allocated, so a caller can
 * check its own limits before the pixels are. "<memory>" in messages. */
int vt_png_decode(const uint8_t *data, size_t len, uint8_t **rgba8, uint32_t *width, uint32_t *height,
                  bool *has_alpha, char *err, size_t errlen);

/* ---- JPEG ------------------------------------------------------------------ */

/* Writes `path` as a baseline JFIF JPEG: YCbCr 4:2:0, the IJG tables
 * scaled to `quality` (1..100), standard Huffman tables, libjpeg's
 * accurate integer DCT. pix holds height rows of width pixels of
 * pixel_bytes bytes: 3 (RGB) or 4 (RGBA, the A byte ignored, so tone-
 * mapped RGBA8 goes in as is), rows row_stride_bytes >= width *
 * pixel_bytes apart. The bytes are exactly what vt_jpeg_encode produces
 * for the same arguments. Returns 0 or a negative errno value. */
int vt_jpeg_write(const char *path, uint32_t width, uint32_t height, const uint8_t *pix,
                  size_t row_stride_bytes, uint32_t pixel_bytes, int quality, char *err,
                  size_t errlen);

/* Like vt_jpeg_write, into memory: on success *out is a malloc'ed buffer
 * of *out_len bytes holding the whole JPEG stream (caller frees with
 * free()); on error *out is NULL and *out_len 0. */
int vt_jpeg_encode(uint32_t width, uint32_t height, const uint8_t *pix, size_t row_stride_bytes,
                   uint32_t pixel_bytes, int quality, uint8_t **out, size_t *out_len, char *err,
                   size_t errlen);

/* vt_jpeg_encode in horizontal bands on several threads (libjpeg-turbo
 * encodes on one). Each band of `rows` rows (a multiple of the 16-row
 * MCU; the last band takes the rest) is encoded as a JPEG of its own with
 * a restart interval of one band's MCUs, so the band ends exactly on a
 * restart boundary, and the bands' entropy-coded segments are spliced
 * into one stream behind band 0's headers (its frame height set to the
 * whole), RSTn markers between them. A restart only resets the DC
 * prediction: every DCT coefficient is the one a single encode gives, so
 * the stream decodes to exactly vt_jpeg_encode's pixels (4:2:0's chroma
 * averages pairs of rows inside one MCU, never across two). Costs 2
 * bytes a band and at most a byte of padding.
 *
 * run(run_ctx, job, arg, n) runs job(arg, t) for t in [0, n) and returns
 * when all are done (a cull_pool's cull_pool_run fits; NULL or bands <= 1:
 * one band on the calling thread). Each job takes bands in order until
 * none is left, so bands may be more than the runner's threads (the load
 * balances) and a runner may run fewer jobs than n (a pool clamps n to
 * its threads): the calling thread encodes what is left. rows_hook, when set, is called on the
 * band's own thread before the band is encoded, to fill rows [y0, y1) of
 * pix (a tone map: the band's bytes are then still in that core's cache);
 * a nonzero return fails the call with that code (a vt_err.h code).
 * Falls back to one band when a band's MCUs would not fit the 16-bit
 * restart interval (images over ~4096 wide). Arguments, result and errors
 * as vt_jpeg_encode; the bands' messages come back through err. */
typedef void (*vt_jpeg_job_fn)(void *arg, uint32_t t);
typedef struct vt_jpeg_par {
    uint32_t bands; /* at most VT_JPEG_MAX_BANDS */
    void (*run)(void *run_ctx, vt_jpeg_job_fn job, void *arg, uint32_t n);
    void *run_ctx;
    int (*rows_hook)(void *hook_ctx, uint32_t y0, uint32_t y1);
    void *hook_ctx;
} vt_jpeg_par;
#define VT_JPEG_MAX_BANDS 16u
int vt_jpeg_encode_par(uint32_t width, uint32_t height, const uint8_t *pix, size_t row_stride_bytes,
                       uint32_t pixel_bytes, int quality, const vt_jpeg_par *par, uint8_t **out, size_t *out_len,
                       char *err, size_t errlen);

/* A renderer's frame as the daemon sends it: rgba (linear floats, 4 a
 * pixel, rows bottom-up, `stride` pixels apart, as vt_soft.h's buffer)
 * tone-mapped by desc into rgba8 (width x 4 bytes a row, top row first,
 * the caller's) and encoded, with vt_jpeg_encode_par's bands: each band
 * tone-maps the rows it then encodes, on its own thread, while they are
 * in that core's cache. The tone map is per pixel, so the bytes are those
 * of one vt_image_tonemap and one vt_jpeg_encode. */
int vt_jpeg_encode_frame(uint32_t width, uint32_t height, const float *rgba, size_t stride,
                         const vt_tonemap_desc *desc, uint8_t *rgba8, int quality, uint32_t bands,
                         void (*run)(void *run_ctx, vt_jpeg_job_fn job, void *arg, uint32_t n), void *run_ctx,
                         uint8_t **out, size_t *out_len, char *err, size_t errlen);

/* The tone map of vt_jpeg_encode_frame alone (a frame another encoder
 * takes: H.264), in bands of rows run by run (NULL or bands 1: here, in
 * one pass). Returns 0 or vt_image_tonemap's error. */
int vt_tonemap_frame(uint32_t width, uint32_t height, const float *rgba, size_t stride, const vt_tonemap_desc *desc,
                     uint8_t *rgba8, uint32_t bands, void (*run)(void *run_ctx, vt_jpeg_job_fn job, void *arg, uint32_t n),
                     void *run_ctx);

/* An RGBA8 picture (sw x sh, rows sstride bytes apart) resampled to
 * dw x dh (rows dstride bytes apart) bilinearly, pixel centres aligned
 * (output x samples input (x + 0.5) sw / dw - 0.5, clamped to the edge
 * pixels): a stream frame drawn smaller while its camera moves, brought
 * back to the stream's size (render/vt_resize.c). Each channel is within
 * 1.5 of the exact bilinear value (weights in 1/256ths). In bands of output rows, as
 * vt_tonemap_frame's (run NULL or bands 1: here). 0, VT_ERR_INVALID (a
 * NULL picture, a size of 0 or over VT_IMAGE_MAX_DIM, a short stride) or
 * VT_ERR_NOMEM. */
int vt_image_resize_rgba8(uint32_t sw, uint32_t sh, const uint8_t *src, size_t sstride, uint32_t dw, uint32_t dh,
                          uint8_t *dst, size_t dstride, uint32_t bands,
                          void (*run)(void *run_ctx, vt_jpeg_job_fn job, void *arg, uint32_t n), void *run_ctx);

/* Decodes a JPEG stream (baseline or progressive, grey, YCbCr or RGB) of
 * len bytes into *rgb8, malloc'ed by this call (caller frees with free()),
 * packed RGB rows (3 * width bytes each), top row first; grey is
 * replicated. libjpeg's accurate integer IDCT and smooth chroma
 * upsampling. Any warning from libjpeg (truncated or corrupt data) is an
 * error, VT_ERR_CORRUPT. On error nothing is allocated and the outputs are
 * 0 / NULL. */
int vt_jpeg_decode(const uint8_t *data, size_t len, uint8_t **rgb8, uint32_t *width,
                   uint32_t *height, char *err, size_t errlen);

/* The size in a JPEG stream's header (frame header parsed, checked against
 * VT_IMAGE_MAX_DIM and the colour spaces vt_jpeg_decode takes); nothing
 * decoded or allocated. */
int vt_jpeg_info(const uint8_t *data, size_t len, uint32_t *width, uint32_t *height, char *err, size_t errlen);

/* vt_jpeg_decode of the contents of `path` (at most 1 GiB, else VT_ERR_TOO_LARGE). */
int vt_jpeg_read(const char *path, uint8_t **rgb8, uint32_t *width, uint32_t *height, char *err,
                 size_t errlen);

#ifdef __cplusplus
}
#endif

#endif
