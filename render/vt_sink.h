/*
 * vt_sink.h — what the PNG and JPEG files (vt_png.c, vt_jpeg.c) share: the
 * output sink both encoders write through (a file descriptor behind a
 * 64 KiB staging buffer, or a growing memory buffer), the
 * temporary-file-and-rename around an encoder, and the argument checks of
 * an 8-bit image. Internal to render/; errors are render/'s codes
 * (vt_err.h) with the message in the call's context (vt_file.h).
 */
#ifndef VANTAGE_VT_SINK_H
#define VANTAGE_VT_SINK_H

#include "vt_file.h"

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

/* Staging buffer for files and the first allocation for memory streams. */
#define VT_SINK_CHUNK ((size_t)64 << 10)

typedef struct vt_sink {
    int       fd;   /* >= 0: a file, buf stages writes; < 0: memory, buf is
                       the stream so far */
    uint8_t  *buf;  /* malloc'ed */
    size_t    len;  /* bytes in buf */
    size_t    cap;  /* bytes allocated */
    int       err;  /* first failure: a write's errno, or ENOMEM */
    vt_call *call;
} vt_sink;

/* Records the first failure (errno e; ENOMEM for memory) with "what:
 * strerror" in the call's message; false. */
bool vt_sink_fail(vt_sink *s, int e, const char *what);

/* File: writes buf[0..len) out. false on failure (s->err set). */
bool vt_sink_flush(vt_sink *s);

/* Makes cap - len > 0: a file is flushed, memory doubles. */
bool vt_sink_room(vt_sink *s);

/* Appends p[0..n). */
bool vt_sink_put(vt_sink *s, const void *p, size_t n);

/* Runs enc(job, sink) into a temporary file beside path and renames it
 * into place; on failure the temporary is removed and path untouched. */
int vt_sink_write_file(vt_call *c, const char *path, int (*enc)(void *job, vt_sink *s), void *job);

/* Runs enc(job, sink) into a growing memory buffer (first guess bytes,
 * doubling); on success *out (malloc'ed, the slack given back) and
 * *out_len; on failure nothing is kept. */
int vt_sink_encode_mem(vt_call *c, size_t guess, int (*enc)(void *job, vt_sink *s), void *job, uint8_t **out,
                       size_t *out_len);

/* Checks an 8-bit image argument set: size within 1..VT_IMAGE_MAX_DIM,
 * pixels, a row stride of at least width * pixel_bytes. VT_ERR_INVALID. */
int vt_image_check_pixels(vt_call *c, uint32_t width, uint32_t height, const uint8_t *pix, size_t stride,
                          uint32_t pixel_bytes);

/* A non-empty path, else VT_ERR_INVALID. */
int vt_image_check_path(vt_call *c, const char *path);

#endif
