/*
 * vt_exr.c — the EXR writer, reader and size query of vt_exr.h on top of
 * OpenEXRCore (OpenEXR 3.1's C API).
 *
 * What it owns: the file descriptors (the library is given read / write /
 * size callbacks on our own fd instead of a path, so errno reaches the
 * caller's message and the temporary-file-and-rename is ours), the chunk
 * scratch buffer, and the translation of library results and errno into
 * render/'s codes (vt_err.h).
 *
 * Writing, per chunk of 1, 16 or 32 rows (set by the compression): the
 * caller's samples are gathered into a planar float scratch, then an
 * OpenEXRCore encode pipeline converts to half where asked (its own
 * round-to-nearest-even conversion), packs, compresses and writes. The
 * gather is one extra pass over the chunk, small next to compression, and
 * it is what makes negative and huge strides safe: the library takes byte
 * strides as int32 and, in 3.1, multiplies them as uint64.
 *
 * Error messages: OpenEXRCore reports through a callback that receives
 * only the context. exr_get_user_data() cannot be used there: in write
 * mode it takes the context's mutex, which the library already holds when
 * it reports most header errors (a duplicate channel deadlocks). So the
 * running call parks a pointer to its message buffer in a thread-local for
 * its duration; the callback runs on the calling thread.
 */
#ifndef _GNU_SOURCE
#define _GNU_SOURCE /* pread, pwrite, GNU strerror_r */
#endif
#include "vt_exr.h"
#include "vt_file.h"

#include <openexr.h>

#include <errno.h>
#include <fcntl.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* ---- one call's error state ---------------------------------------------- */

/* The running call on this thread (vt_file.h's context), for the library's
 * error callback, which gets no user pointer it could use (see the top). */
static _Thread_local vt_call *tl_call;

static void on_exr_error(exr_const_context_t ctxt, exr_result_t code, const char *msg)
{
    (void)ctxt;
    if (!tl_call) return;
    if (!tl_call->lib_code) tl_call->lib_code = code;
    vt_call_msg(tl_call, "%s", msg ? msg : exr_get_default_error_message(code));
}

/* Starts a call: clears err, installs the thread-local. Pair with call_end. */
static vt_call *call_begin(vt_call *c, const char *path, char *err, size_t errlen, vt_call **saved)
{
    *c = vt_call_begin(path, err, errlen);
    *saved = tl_call;
    tl_call = c;
    return c;
}

static int call_end(vt_call *c, vt_call *saved, int rc)
{
    tl_call = saved;
    return vt_call_end(c, rc);
}

/* ---- file I/O callbacks ---------------------------------------------------- */

typedef struct exr_file {
    int       fd;
    int       err; /* first errno from a failed read/write/close, else 0 */
    vt_call *call;
    const uint8_t *mem; /* reading from memory (vt_exr_decode_rgba): mem[0..mem_len), no fd */
    size_t    mem_len;
} exr_file;

static void file_failed(exr_file *f, int e, const char *what)
{
    char buf[128];
    if (!f->err) f->err = e;
    vt_call_msg(f->call, "%s: %s", what, vt_errno_text(e, buf, sizeof buf));
}

/* Reads into or writes from buf[0..sz) at off, retrying after EINTR; a
 * read stops early at the end of the file (the library decides whether
 * short is bad). The bytes moved, or -1 with the failure recorded. */
static int64_t file_move(exr_file *f, const void *buf, uint64_t sz, uint64_t off, bool write)
{
    uint64_t done = 0;
    if (sz > INT64_MAX || off > INT64_MAX - sz) return -1;
    while (done < sz) {
        char *at = (char *)(uintptr_t)buf + done; /* the reader's buf is not const */
        size_t want = (size_t)(sz - done);
        off_t where = (off_t)(off + done);
        ssize_t n = write ? pwrite(f->fd, at, want, where) : pread(f->fd, at, want, where);
        if (n < 0 && errno == EINTR) continue;
        if (n < 0 || (n == 0 && write)) {
            file_failed(f, n < 0 ? errno : EIO, write ? "write" : "read");
            return -1;
        }
        if (n == 0) break;
        done += (uint64_t)n;
    }
    return (int64_t)done;
}

static int64_t file_read(exr_const_context_t ctxt, void *ud, void *buf, uint64_t sz, uint64_t off,
                         exr_stream_error_func_ptr_t error_cb)
{
    (void)ctxt;
    (void)error_cb;
    const exr_file *f = ud;
    if (f->mem) { /* short at the end, as a file read is */
        if (off >= f->mem_len) return 0;
        size_t n = sz < f->mem_len - off ? (size_t)sz : (size_t)(f->mem_len - off);
        memcpy(buf, f->mem + off, n);
        return (int64_t)n;
    }
    return file_move(ud, buf, sz, off, false);
}

static int64_t file_write(exr_const_context_t ctxt, void *ud, const void *buf, uint64_t sz,
                          uint64_t off, exr_stream_error_func_ptr_t error_cb)
{
    (void)ctxt;
    (void)error_cb;
    return file_move(ud, buf, sz, off, true);
}

static int64_t file_size(exr_const_context_t ctxt, void *ud)
{
    (void)ctxt;
    struct stat st;
    const exr_file *f = ud;
    if (f->mem) return (int64_t)f->mem_len;
    return fstat(f->fd, &st) == 0 ? (int64_t)st.st_size : -1;
}

/* An OpenEXRCore result as a VT_ERRORS code; an errno from our own I/O
 * wins, being the cause. */
static int exr_code(exr_result_t rv, const exr_file *f)
{
    if (rv == EXR_ERR_SUCCESS) return 0;
    if (f && f->err) return vt_err_from_errno(f->err);
    switch (rv) {
    case EXR_ERR_OUT_OF_MEMORY: return VT_ERR_NOMEM;
    case EXR_ERR_MISSING_CONTEXT_ARG:
    case EXR_ERR_INVALID_ARGUMENT:
    case EXR_ERR_ARGUMENT_OUT_OF_RANGE:
    case EXR_ERR_NAME_TOO_LONG: return VT_ERR_INVALID;
    case EXR_ERR_FILE_BAD_HEADER:
    case EXR_ERR_READ_IO: /* no errno: a short read, the file is truncated */
    case EXR_ERR_MISSING_REQ_ATTR:
    case EXR_ERR_INVALID_ATTR:
    case EXR_ERR_ATTR_TYPE_MISMATCH:
    case EXR_ERR_ATTR_SIZE_MISMATCH:
    case EXR_ERR_BAD_CHUNK_LEADER:
    case EXR_ERR_CORRUPT_CHUNK:
    case EXR_ERR_INVALID_SAMPLE_DATA: return VT_ERR_CORRUPT;
    case EXR_ERR_SCAN_TILE_MIXEDAPI:
    case EXR_ERR_TILE_SCAN_MIXEDAPI:
    case EXR_ERR_FEATURE_NOT_IMPLEMENTED: return VT_ERR_UNSUPPORTED;
    default: return VT_ERR_CODEC;
    }
}

/* Fails the call with an OpenEXRCore result, making sure err says something.
 * The first code the library reported is the cause and wins over rv: 3.1
 * returns e.g. "bad header" for a header it could not allocate. */
static int exr_fail(vt_call *c, exr_result_t rv, const exr_file *f, const char *what)
{
    vt_call_msg(c, "%s: %s", what, exr_get_default_error_message(rv));
    return exr_code(c->lib_code ? c->lib_code : rv, f);
}

/* ---- writing ------------------------------------------------------------- */

static int cmp_channel_name(const void *a, const void *b)
{
    const vt_exr_channel *x = *(const vt_exr_channel *const *)a;
    const vt_exr_channel *y = *(const vt_exr_channel *const *)b;
    return strcmp(x->name, y->name);
}

static exr_compression_t exr_compression(vt_exr_compression c)
{
    switch (c) {
    case VT_EXR_ZIP: return EXR_COMPRESSION_ZIP;
    case VT_EXR_ZIPS: return EXR_COMPRESSION_ZIPS;
    case VT_EXR_PIZ: return EXR_COMPRESSION_PIZ;
    case VT_EXR_RLE: return EXR_COMPRESSION_RLE;
    default: return EXR_COMPRESSION_NONE;
    }
}

static int check_write_args(vt_call *c, uint32_t width, uint32_t height, const vt_exr_channel *ch,
                            uint32_t nch, vt_exr_compression comp)
{
    if (width < 1 || width > VT_EXR_MAX_WIDTH || height < 1 || height > VT_EXR_MAX_HEIGHT) {
        vt_call_msg(c, "image size %ux%u outside 1x1..%dx%d", width, height, VT_EXR_MAX_WIDTH,
                 VT_EXR_MAX_HEIGHT);
        return VT_ERR_INVALID;
    }
    if (!ch || nch < 1 || nch > VT_EXR_MAX_CHANNELS) {
        vt_call_msg(c, "need 1..%u channels, got %u", VT_EXR_MAX_CHANNELS, ch ? nch : 0);
        return VT_ERR_INVALID;
    }
    if ((unsigned)comp > VT_EXR_RLE) {
        vt_call_msg(c, "unknown compression %d", (int)comp);
        return VT_ERR_INVALID;
    }
    for (uint32_t i = 0; i < nch; i++) {
        size_t len = ch[i].name ? strlen(ch[i].name) : 0;
        if (len < 1 || len > 31) {
            vt_call_msg(c, "channel %u: name must be 1..31 bytes", i);
            return VT_ERR_INVALID;
        }
        if (!ch[i].data || (ch[i].type != VT_EXR_HALF && ch[i].type != VT_EXR_FLOAT)) {
            vt_call_msg(c, "channel '%s': no data or unknown type", ch[i].name);
            return VT_ERR_INVALID;
        }
    }
    return 0;
}

/* Declares the part: windows, compression, channels in name order. */
static int define_part(vt_call *c, exr_context_t ctx, const exr_file *f, uint32_t width,
                       uint32_t height, const vt_exr_channel *const *sorted, uint32_t nch,
                       vt_exr_compression comp)
{
    int part = 0;
    exr_result_t rv = exr_add_part(ctx, NULL, EXR_STORAGE_SCANLINE, &part);
    if (rv == EXR_ERR_SUCCESS)
        rv = exr_initialize_required_attr_simple(ctx, part, (int32_t)width, (int32_t)height,
                                                 exr_compression(comp));
    for (uint32_t i = 0; i < nch && rv == EXR_ERR_SUCCESS; i++)
        rv = exr_add_channel(ctx, part, sorted[i]->name,
                             sorted[i]->type == VT_EXR_HALF ? EXR_PIXEL_HALF : EXR_PIXEL_FLOAT,
                             EXR_PERCEPTUALLY_LOGARITHMIC, 1, 1);
    if (rv == EXR_ERR_SUCCESS) rv = exr_write_header(ctx);
    return rv == EXR_ERR_SUCCESS ? 0 : exr_fail(c, rv, f, "header");
}

/* Copies rows [y0, y0 + rows) of one channel into dst, planar. */
static void gather(float *dst, const vt_exr_channel *ch, uint32_t width, int32_t y0, int32_t rows)
{
    for (int32_t r = 0; r < rows; r++) {
        const float *src = ch->data + (ptrdiff_t)(y0 + r) * ch->y_stride;
        float *d = dst + (size_t)r * width;
        if (ch->x_stride == 1) {
            memcpy(d, src, (size_t)width * sizeof *d);
        } else {
            for (uint32_t x = 0; x < width; x++) d[x] = src[(ptrdiff_t)x * ch->x_stride];
        }
    }
}

/* The pipeline's channels come in the file's (sorted) order; src[i] is the
 * caller's channel for pipeline channel i. */
static int match_channels(vt_call *c, const exr_encode_pipeline_t *enc,
                          const vt_exr_channel *const *sorted, uint32_t nch,
                          const vt_exr_channel **src)
{
    if (enc->channel_count < 0 || (uint32_t)enc->channel_count != nch) {
        vt_call_msg(c, "library reports %d channels, expected %u", enc->channel_count, nch);
        return VT_ERR_CODEC;
    }
    for (uint32_t i = 0; i < nch; i++) {
        src[i] = NULL;
        for (uint32_t j = 0; j < nch && !src[i]; j++)
            if (strcmp(enc->channels[i].channel_name, sorted[j]->name) == 0) src[i] = sorted[j];
        if (!src[i]) {
            vt_call_msg(c, "library reports unknown channel '%s'", enc->channels[i].channel_name);
            return VT_ERR_CODEC;
        }
    }
    return 0;
}

/* Encodes and writes every chunk. scratch holds lines x width floats per
 * channel. */
static int write_chunks(vt_call *c, exr_context_t ctx, const exr_file *f, uint32_t width,
                        uint32_t height, const vt_exr_channel *const *sorted, uint32_t nch,
                        int32_t lines, float *scratch, const vt_exr_channel **src)
{
    exr_encode_pipeline_t enc = EXR_ENCODE_PIPELINE_INITIALIZER;
    exr_result_t rv = EXR_ERR_SUCCESS;
    const char *what = "chunk";
    int rc = 0;
    bool started = false;
    size_t plane = (size_t)lines * width;
    for (int64_t y = 0; y < (int64_t)height && rv == EXR_ERR_SUCCESS && rc == 0; y += lines) {
        exr_chunk_info_t ci;
        what = "chunk";
        rv = exr_write_scanline_chunk_info(ctx, 0, (int)y, &ci);
        if (rv != EXR_ERR_SUCCESS) break;
        rv = started ? exr_encoding_update(ctx, 0, &ci, &enc) : exr_encoding_initialize(ctx, 0, &ci, &enc);
        if (rv != EXR_ERR_SUCCESS) break;
        if (!started && (rc = match_channels(c, &enc, sorted, nch, src)) != 0) break;
        if (ci.height < 1 || ci.height > lines || ci.start_y != y || ci.width != (int32_t)width) {
            vt_call_msg(c, "library chunk at row %lld is %dx%d at %d", (long long)y, ci.width, ci.height,
                     ci.start_y);
            rc = VT_ERR_CODEC;
            break;
        }
        for (uint32_t i = 0; i < nch; i++) {
            exr_coding_channel_info_t *cc = &enc.channels[i];
            gather(scratch + i * plane, src[i], width, ci.start_y, ci.height);
            cc->encode_from_ptr = (const uint8_t *)(scratch + i * plane);
            cc->user_pixel_stride = (int32_t)sizeof(float);
            cc->user_line_stride = (int32_t)(width * sizeof(float));
            cc->user_data_type = EXR_PIXEL_FLOAT;
            cc->user_bytes_per_element = (int16_t)sizeof(float);
        }
        if (!started) {
            started = true;
            rv = exr_encoding_choose_default_routines(ctx, 0, &enc);
            if (rv != EXR_ERR_SUCCESS) break;
        }
        what = "encoding";
        rv = exr_encoding_run(ctx, 0, &enc);
    }
    exr_encoding_destroy(ctx, &enc);
    if (rc == 0 && rv != EXR_ERR_SUCCESS) rc = exr_fail(c, rv, f, what);
    return rc;
}

/* Writes the whole image through fd; the context is finished either way. */
static int write_exr(vt_call *c, const char *path, exr_file *f, uint32_t width, uint32_t height,
                     const vt_exr_channel *const *sorted, uint32_t nch, vt_exr_compression comp)
{
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.error_handler_fn = on_exr_error;
    init.user_data = f;
    init.write_fn = file_write;
    exr_context_t ctx = NULL;
    float *scratch = NULL;
    const vt_exr_channel **src = NULL;
    exr_result_t rv = exr_start_write(&ctx, path, EXR_WRITE_FILE_DIRECTLY, &init);
    if (rv != EXR_ERR_SUCCESS) return exr_fail(c, rv, f, "start");
    int rc = define_part(c, ctx, f, width, height, sorted, nch, comp);
    int32_t lines = 0;
    if (rc == 0 && (rv = exr_get_scanlines_per_chunk(ctx, 0, &lines)) != EXR_ERR_SUCCESS)
        rc = exr_fail(c, rv, f, "chunk rows");
    if (rc == 0 && (lines < 1 || lines > 256)) {
        vt_call_msg(c, "library reports %d rows per chunk", lines);
        rc = VT_ERR_CODEC;
    }
    if (rc == 0) {
        if (width > SIZE_MAX / sizeof(float) / (size_t)lines / nch) rc = VT_ERR_NOMEM;
        if (rc == 0) scratch = malloc((size_t)lines * width * nch * sizeof(float));
        if (rc == 0) src = malloc(nch * sizeof *src);
        if (!scratch || !src) rc = VT_ERR_NOMEM;
        if (rc) vt_call_msg(c, "out of memory for %d rows x %u x %u channels", lines, width, nch);
    }
    if (rc == 0) rc = write_chunks(c, ctx, f, width, height, sorted, nch, lines, scratch, src);
    /* finishing a complete write emits what is still buffered; a failed
     * one just frees (our fd and temp file are ours to clean up) */
    rv = exr_finish(&ctx);
    if (rc == 0 && rv != EXR_ERR_SUCCESS) rc = exr_fail(c, rv, f, "finish");
    if (rc == 0 && f->err) rc = vt_err_from_errno(f->err);
    /* nothing the library complained about is kept, even if it carried on */
    if (rc == 0 && c->lib_code) rc = exr_fail(c, c->lib_code, f, "write");
    free(src);
    free(scratch);
    return rc;
}

int vt_exr_write(const char *path, uint32_t width, uint32_t height, const vt_exr_channel *ch,
                 uint32_t nch, vt_exr_compression comp, char *err, size_t errlen)
{
    vt_call call, *saved;
    vt_call *c = call_begin(&call, path, err, errlen, &saved);
    exr_file f = {.fd = -1, .call = c};
    const vt_exr_channel **sorted = NULL;
    char *tmp = NULL;
    int rc = 0;
    if (!path || !path[0]) {
        vt_call_msg(c, "no path");
        return call_end(c, saved, VT_ERR_INVALID);
    }
    if ((rc = check_write_args(c, width, height, ch, nch, comp)) != 0) return call_end(c, saved, rc);
    sorted = malloc(nch * sizeof *sorted);
    if (!sorted) {
        vt_call_msg(c, "out of memory");
        return call_end(c, saved, VT_ERR_NOMEM);
    }
    for (uint32_t i = 0; i < nch; i++) sorted[i] = &ch[i];
    qsort(sorted, nch, sizeof *sorted, cmp_channel_name);
    for (uint32_t i = 1; i < nch && rc == 0; i++) {
        if (strcmp(sorted[i - 1]->name, sorted[i]->name) == 0) {
            vt_call_msg(c, "channel '%s' given twice", sorted[i]->name);
            rc = VT_ERR_INVALID;
        }
    }
    if (rc == 0) rc = vt_temp_open(c, path, &tmp, &f.fd);
    if (rc == 0) rc = write_exr(c, path, &f, width, height, sorted, nch, comp);
    rc = vt_temp_finish(c, path, tmp, f.fd, rc);
    free(sorted);
    return call_end(c, saved, rc);
}

/* ---- reading ------------------------------------------------------------- */

/* Finishes the context (if any) and closes the file. */
static void read_close(exr_file *f, exr_context_t *ctx)
{
    if (*ctx) exr_finish(ctx);
    if (f->fd >= 0) close(f->fd);
    f->fd = -1;
}

/* Opens path and parses its header. On success *ctx must be finished and
 * f->fd closed (read_close). */
static int read_open(vt_call *c, const char *path, exr_file *f, exr_context_t *ctx)
{
    char buf[128];
    *ctx = NULL;
    if (!f->mem && (!path || !path[0])) {
        vt_call_msg(c, "no path");
        return VT_ERR_INVALID;
    }
    if (!f->mem) f->fd = open(path, O_RDONLY | O_CLOEXEC);
    if (!f->mem && f->fd < 0) {
        int e = errno;
        vt_call_msg(c, "open: %s", vt_errno_text(e, buf, sizeof buf));
        return vt_err_from_errno(e);
    }
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.error_handler_fn = on_exr_error;
    init.user_data = f;
    init.read_fn = file_read;
    init.size_fn = file_size;
    exr_result_t rv = exr_start_read(ctx, path, &init);
    if (rv != EXR_ERR_SUCCESS) *ctx = NULL; /* the library finished it */
    /* 3.1 reports an allocation failure while parsing an attribute, then
     * carries on without the attribute and returns success */
    if (rv == EXR_ERR_SUCCESS && c->lib_code == EXR_ERR_OUT_OF_MEMORY) rv = EXR_ERR_OUT_OF_MEMORY;
    if (rv != EXR_ERR_SUCCESS) {
        read_close(f, ctx);
        return exr_fail(c, rv, f, "header");
    }
    return 0;
}

static int data_window(vt_call *c, exr_context_t ctx, const exr_file *f, exr_attr_box2i_t *dw,
                       uint32_t *w, uint32_t *h)
{
    exr_result_t rv = exr_get_data_window(ctx, 0, dw);
    if (rv != EXR_ERR_SUCCESS) return exr_fail(c, rv, f, "data window");
    int64_t ww = (int64_t)dw->max.x - dw->min.x + 1, hh = (int64_t)dw->max.y - dw->min.y + 1;
    if (ww < 1 || hh < 1 || ww > UINT32_MAX || hh > UINT32_MAX) {
        vt_call_msg(c, "bad data window (%d %d) - (%d %d)", dw->min.x, dw->min.y, dw->max.x, dw->max.y);
        return VT_ERR_CORRUPT;
    }
    *w = (uint32_t)ww;
    *h = (uint32_t)hh;
    return 0;
}

/* Checks the part and finds channel `name` in it. */
static int find_channel(vt_call *c, exr_context_t ctx, const exr_file *f, const char *name)
{
    exr_storage_t st;
    const exr_attr_chlist_t *cl = NULL;
    exr_result_t rv = exr_get_storage(ctx, 0, &st);
    if (rv == EXR_ERR_SUCCESS && st != EXR_STORAGE_SCANLINE) {
        vt_call_msg(c, "only flat scanline images can be read (storage %d)", (int)st);
        return VT_ERR_UNSUPPORTED;
    }
    if (rv == EXR_ERR_SUCCESS) rv = exr_get_channels(ctx, 0, &cl);
    if (rv != EXR_ERR_SUCCESS) return exr_fail(c, rv, f, "channels");
    for (int i = 0; i < cl->num_channels; i++) {
        const exr_attr_chlist_entry_t *e = &cl->entries[i];
        if (strcmp(e->name.str, name) != 0) continue;
        if (e->x_sampling != 1 || e->y_sampling != 1) {
            vt_call_msg(c, "channel '%s' is subsampled", name);
            return VT_ERR_UNSUPPORTED;
        }
        return 0;
    }
    vt_call_msg(c, "no channel '%s'", name);
    return VT_ERR_NOT_FOUND;
}

/* Where decoded channels go: channel names[k] to out + k, pixels `stride`
 * floats apart (1: one planar channel; 4: interleaved RGBA). */
typedef struct exr_aim {
    const char *const *names;
    int n;
    uint32_t stride;
} exr_aim;

/* Points the decoder at out for the aimed channels and at junk for the
 * others. OpenEXRCore documents a NULL destination as "skip this channel",
 * but 3.1's generic unpacker (used whenever it converts half to float)
 * writes through it anyway; so every channel gets a destination, the
 * unwanted ones sharing one chunk of junk rows. */
static void aim_decoder(exr_decode_pipeline_t *dec, const exr_aim *a, float *out, float *junk, uint32_t width)
{
    for (int i = 0; i < dec->channel_count; i++) {
        exr_coding_channel_info_t *cc = &dec->channels[i];
        float *to = junk;
        int32_t stride = 1;
        for (int k = 0; k < a->n; k++)
            if (strcmp(cc->channel_name, a->names[k]) == 0) {
                to = out + k;
                stride = (int32_t)a->stride;
            }
        cc->decode_to_ptr = (uint8_t *)to;
        cc->user_pixel_stride = stride * (int32_t)sizeof(float);
        cc->user_line_stride = (int32_t)(width * (uint32_t)stride * sizeof(float));
        cc->user_data_type = EXR_PIXEL_FLOAT;
        cc->user_bytes_per_element = (int16_t)sizeof(float);
    }
}

static int read_chunks(vt_call *c, exr_context_t ctx, const exr_file *f, const exr_aim *aim,
                       float *out, uint32_t width, const exr_attr_box2i_t *dw)
{
    exr_decode_pipeline_t dec = EXR_DECODE_PIPELINE_INITIALIZER;
    float *junk = NULL;
    int32_t lines = 0;
    int rc = 0;
    bool started = false;
    exr_result_t rv = exr_get_scanlines_per_chunk(ctx, 0, &lines);
    if (rv == EXR_ERR_SUCCESS && (lines < 1 || lines > 256)) rv = EXR_ERR_FILE_BAD_HEADER;
    if (rv == EXR_ERR_SUCCESS &&
        (width > SIZE_MAX / sizeof *junk / (size_t)lines ||
         !(junk = malloc((size_t)lines * width * sizeof *junk)))) {
        vt_call_msg(c, "out of memory for %d rows x %u", lines, width);
        rc = VT_ERR_NOMEM;
    }
    for (int64_t y = dw->min.y; y <= dw->max.y && rv == EXR_ERR_SUCCESS && rc == 0; y += lines) {
        exr_chunk_info_t ci;
        rv = exr_read_scanline_chunk_info(ctx, 0, (int)y, &ci);
        if (rv != EXR_ERR_SUCCESS) break;
        /* the chunk must lie inside the window: out is exactly its size */
        if (ci.start_y != y || ci.height < 1 || ci.height > lines ||
            (int64_t)ci.start_y + ci.height - 1 > dw->max.y || ci.width != (int32_t)width) {
            vt_call_msg(c, "chunk at row %lld does not fit the data window", (long long)y);
            rc = VT_ERR_CORRUPT;
            break;
        }
        rv = started ? exr_decoding_update(ctx, 0, &ci, &dec) : exr_decoding_initialize(ctx, 0, &ci, &dec);
        if (rv != EXR_ERR_SUCCESS) break;
        aim_decoder(&dec, aim, out + (size_t)(y - dw->min.y) * width * aim->stride, junk, width);
        if (!started) {
            started = true;
            rv = exr_decoding_choose_default_routines(ctx, 0, &dec);
            if (rv != EXR_ERR_SUCCESS) break;
        }
        rv = exr_decoding_run(ctx, 0, &dec);
    }
    exr_decoding_destroy(ctx, &dec);
    free(junk);
    if (rc == 0 && rv != EXR_ERR_SUCCESS) rc = exr_fail(c, rv, f, "decoding");
    return rc;
}

/* One read call's state: its error context, the file, the library's
 * context and the data window once read. */
typedef struct exr_reader {
    vt_call          call, *saved;
    exr_file         f;
    exr_context_t    ctx;
    exr_attr_box2i_t dw;
    uint32_t         w, h;
} exr_reader;

static vt_call *reader_begin(exr_reader *r, const char *path, char *err, size_t errlen)
{
    *r = (exr_reader){.f = {.fd = -1}};
    r->f.call = call_begin(&r->call, path, err, errlen, &r->saved);
    return r->f.call;
}

/* Closes what the call opened and ends it with rc. */
static int reader_end(exr_reader *r, int rc)
{
    read_close(&r->f, &r->ctx);
    return call_end(&r->call, r->saved, rc);
}

int vt_exr_read_channel(const char *path, const char *name, float *out, uint32_t width,
                        uint32_t height, char *err, size_t errlen)
{
    exr_reader r;
    vt_call *c = reader_begin(&r, path, err, errlen);
    if (!name || !out || width < 1 || width > VT_EXR_MAX_WIDTH || height < 1) {
        vt_call_msg(c, "bad arguments (name, out or size %ux%u)", width, height);
        return reader_end(&r, VT_ERR_INVALID);
    }
    int rc = read_open(c, path, &r.f, &r.ctx);
    if (rc == 0) rc = find_channel(c, r.ctx, &r.f, name);
    if (rc == 0) rc = data_window(c, r.ctx, &r.f, &r.dw, &r.w, &r.h);
    if (rc == 0 && (r.w != width || r.h != height)) {
        vt_call_msg(c, "image is %ux%u, buffer %ux%u", r.w, r.h, width, height);
        rc = VT_ERR_INVALID;
    }
    if (rc == 0) rc = read_chunks(c, r.ctx, &r.f, &(exr_aim){.names = &name, .n = 1, .stride = 1}, out, width, &r.dw);
    if (rc == 0 && c->lib_code == EXR_ERR_OUT_OF_MEMORY) rc = exr_fail(c, c->lib_code, &r.f, "decoding");
    return reader_end(&r, rc);
}

int vt_exr_size(const char *path, uint32_t *width, uint32_t *height, char *err, size_t errlen)
{
    exr_reader r;
    vt_call *c = reader_begin(&r, path, err, errlen);
    if (!width || !height) {
        vt_call_msg(c, "no output for the size");
        return reader_end(&r, VT_ERR_INVALID);
    }
    int rc = read_open(c, path, &r.f, &r.ctx);
    if (rc == 0) rc = data_window(c, r.ctx, &r.f, &r.dw, &r.w, &r.h);
    if (rc == 0) {
        *width = r.w;
        *height = r.h;
    }
    return reader_end(&r, rc);
}

int vt_exr_decode_rgba(const uint8_t *data, size_t len, float **rgba, uint32_t *width, uint32_t *height,
                       char *err, size_t errlen)
{
    exr_reader r;
    vt_call *c = reader_begin(&r, "<memory>", err, errlen);
    static const char *const rgba_names[4] = {"R", "G", "B", "A"}, *const grey_names[1] = {"Y"};
    if (rgba) *rgba = NULL;
    if (width) *width = 0;
    if (height) *height = 0;
    if (!data || !len || !width || !height) {
        vt_call_msg(c, "no stream, or no output for its size");
        return reader_end(&r, data && !len ? VT_ERR_CORRUPT : VT_ERR_INVALID);
    }
    r.f.mem = data;
    r.f.mem_len = len;
    int rc = read_open(c, "<memory>", &r.f, &r.ctx);
    if (rc == 0) rc = data_window(c, r.ctx, &r.f, &r.dw, &r.w, &r.h);
    if (rc == 0 && (r.w > VT_EXR_MAX_WIDTH || (uint64_t)r.w * r.h > SIZE_MAX / 16)) {
        vt_call_msg(c, "image %ux%u too large", r.w, r.h);
        rc = VT_ERR_TOO_LARGE;
    }
    /* colour: R, G and B, or Y alone (grey); alpha optional */
    bool grey = false, alpha = false;
    if (rc == 0) {
        char ignored[8];
        vt_call probe = vt_call_begin("", ignored, sizeof ignored); /* find_channel's "no channel" is ours to say */
        for (int k = 0; k < 3 && rc == 0; k++)
            if (find_channel(&probe, r.ctx, &r.f, rgba_names[k])) {
                grey = find_channel(&probe, r.ctx, &r.f, "Y") == 0;
                if (!grey) {
                    rc = find_channel(c, r.ctx, &r.f, rgba_names[k]);
                    if (rc == VT_ERR_NOT_FOUND) {
                        vt_call_msg(c, "no R, G, B (or Y) channels");
                        rc = VT_ERR_CORRUPT;
                    }
                }
                break;
            }
        alpha = find_channel(&probe, r.ctx, &r.f, "A") == 0;
    }
    if (rc != 0 || !rgba) {
        if (rc == 0) {
            *width = r.w;
            *height = r.h;
        }
        return reader_end(&r, rc);
    }
    float *px = malloc((size_t)r.w * r.h * 4 * sizeof *px);
    if (!px) {
        vt_call_msg(c, "out of memory for %ux%u RGBA", r.w, r.h);
        return reader_end(&r, VT_ERR_NOMEM);
    }
    size_t n = (size_t)r.w * r.h;
    for (size_t i = 0; i < n; i++) px[4 * i + 3] = 1.0f; /* no A channel: opaque */
    exr_aim aim = {.names = grey ? grey_names : rgba_names, .n = grey ? 1 : alpha ? 4 : 3, .stride = 4};
    rc = read_chunks(c, r.ctx, &r.f, &aim, px, r.w, &r.dw);
    if (rc == 0 && c->lib_code == EXR_ERR_OUT_OF_MEMORY) rc = exr_fail(c, c->lib_code, &r.f, "decoding");
    if (rc == 0 && grey)
        for (size_t i = 0; i < n; i++) px[4 * i + 1] = px[4 * i + 2] = px[4 * i];
    if (rc == 0 && grey && alpha) { /* Y and A: A in a second pass (rare) */
        static const char *const a_name[1] = {"A"};
        exr_aim aa = {.names = a_name, .n = 1, .stride = 4};
        rc = read_chunks(c, r.ctx, &r.f, &aa, px + 3, r.w, &r.dw);
    }
    if (rc != 0) {
        free(px);
        return reader_end(&r, rc);
    }
    *rgba = px;
    *width = r.w;
    *height = r.h;
    return reader_end(&r, 0);
}
