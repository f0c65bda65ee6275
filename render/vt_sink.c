/*
 * vt_sink.c — see vt_sink.h: the encoders' output sink, the
 * temporary-file-and-rename around an encoder, the 8-bit image checks.
 */
#include "vt_sink.h"
#include "vt_image.h"
#include "vp_grow.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

bool vt_sink_fail(vt_sink *s, int e, const char *what)
{
    char buf[128];
    if (!s->err) s->err = e;
    vt_call_msg(s->call, "%s: %s", what, vt_errno_text(e, buf, sizeof buf));
    return false;
}

bool vt_sink_flush(vt_sink *s)
{
    size_t done = 0;
    while (done < s->len) {
        ssize_t n = write(s->fd, s->buf + done, s->len - done);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) return vt_sink_fail(s, n < 0 ? errno : EIO, "write");
        done += (size_t)n;
    }
    s->len = 0;
    return true;
}

bool vt_sink_room(vt_sink *s)
{
    if (s->err) return false;
    if (s->fd >= 0) return s->len < s->cap || vt_sink_flush(s);
    if (s->len < s->cap) return true;
    size_t cap = vp_grow_cap(s->cap, s->cap + 1, VT_SINK_CHUNK, 1, SIZE_MAX);
    uint8_t *b = cap ? realloc(s->buf, cap) : NULL;
    if (!b) return vt_sink_fail(s, ENOMEM, "out of memory");
    s->buf = b;
    s->cap = cap;
    return true;
}

bool vt_sink_put(vt_sink *s, const void *p, size_t n)
{
    const uint8_t *q = p;
    while (n > 0) {
        if (!vt_sink_room(s)) return false;
        size_t k = s->cap - s->len < n ? s->cap - s->len : n;
        memcpy(s->buf + s->len, q, k);
        s->len += k;
        q += k;
        n -= k;
    }
    return true;
}

/* ---- files --------------------------------------------------------------- */

int vt_sink_write_file(vt_call *c, const char *path, int (*enc)(void *job, vt_sink *s), void *job)
{
    vt_sink s = {.fd = -1, .call = c};
    char *tmp = NULL;
    int rc = vt_temp_open(c, path, &tmp, &s.fd);
    if (rc == 0 && !(s.buf = malloc(VT_SINK_CHUNK))) {
        vt_call_msg(c, "out of memory");
        rc = VT_ERR_NOMEM;
    }
    s.cap = VT_SINK_CHUNK;
    if (rc == 0) rc = enc(job, &s);
    if (rc == 0 && !vt_sink_flush(&s)) rc = vt_err_from_errno(s.err);
    rc = vt_temp_finish(c, path, tmp, s.fd, rc);
    free(s.buf);
    return rc;
}

int vt_image_check_pixels(vt_call *c, uint32_t width, uint32_t height, const uint8_t *pix,
                        size_t stride, uint32_t pixel_bytes)
{
    if (width < 1 || height < 1 || width > VT_IMAGE_MAX_DIM || height > VT_IMAGE_MAX_DIM) {
        vt_call_msg(c, "image size %ux%u outside 1x1..%ux%u", width, height, VT_IMAGE_MAX_DIM,
                 VT_IMAGE_MAX_DIM);
        return VT_ERR_INVALID;
    }
    if (!pix) {
        vt_call_msg(c, "no pixels");
        return VT_ERR_INVALID;
    }
    if (stride < (size_t)width * pixel_bytes) {
        vt_call_msg(c, "row stride %zu below %u x %u bytes", stride, width, pixel_bytes);
        return VT_ERR_INVALID;
    }
    return 0;
}

int vt_image_check_path(vt_call *c, const char *path)
{
    if (path && path[0]) return 0;
    vt_call_msg(c, "no path");
    return VT_ERR_INVALID;
}

int vt_sink_encode_mem(vt_call *c, size_t guess, int (*enc)(void *job, vt_sink *s), void *job, uint8_t **out,
                       size_t *out_len)
{
    vt_sink s = {.fd = -1, .call = c, .cap = guess < VT_SINK_CHUNK ? VT_SINK_CHUNK : guess};
    if (!(s.buf = malloc(s.cap))) {
        vt_call_msg(c, "out of memory");
        return VT_ERR_NOMEM;
    }
    int rc = enc(job, &s);
    if (rc != 0) {
        free(s.buf);
        return rc;
    }
    uint8_t *fit = s.len < s.cap ? realloc(s.buf, s.len) : NULL; /* give back the slack */
    *out = fit ? fit : s.buf;
    *out_len = s.len;
    return 0;
}
