/*
 * vp_bytes.h — the one little-endian byte writer and reader: the wire
 * protocol's frames, the journal's headers and records, the snapshot's
 * body and the importer's pipe are all written and read with it.
 * Header-only (static inline, libc only; C and C++, as protocol.h), so
 * any folder uses it without linking the protocol library; the protocol's
 * framing (vp_frame_begin / vp_frame_end) and its error codes
 * (vp_reader_finish) stay in protocol.c.
 *
 * Bytes are explicit little-endian shifts, right on any host. Three layers:
 *  - vp_ld_* / vp_st_*: a value at a pointer, for fields at fixed offsets
 *    (a journal record header checked in place, a length patched later);
 *  - vp_writer: a cursor over a buffer, fixed (vp_writer_init: a write
 *    that does not fit sets `overflow`, writes nothing, and every later
 *    write is refused: one check at the end covers them all) or growing
 *    (vp_writer_init_grow: the buffer is the writer's own and grows by
 *    vp_grow.h's rule; overflow then means out of memory or past SIZE_MAX);
 *  - vp_reader: a cursor over bytes that may be hostile. A read past the
 *    end sets `short_read`, returns zeros (NULL for bytes) and every later
 *    read fails too (sticky), so a decoder reads its fields and checks
 *    once. Counts are checked against what is left by division, never by a
 *    product that could wrap (vp_get_array).
 * Cost: a put or get is a bounds check and a few shifts, inlined.
 */
#ifndef VANTAGE_VP_BYTES_H
#define VANTAGE_VP_BYTES_H

#include "vp_grow.h"

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

/* ---- a value at a pointer ------------------------------------------------------------ */

static inline uint8_t vp_ld_u8(const uint8_t *p) { return p[0]; }
static inline uint16_t vp_ld_u16(const uint8_t *p) { return (uint16_t)(p[0] | p[1] << 8); }
static inline uint32_t vp_ld_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}
static inline uint64_t vp_ld_u64(const uint8_t *p) { return (uint64_t)vp_ld_u32(p) | (uint64_t)vp_ld_u32(p + 4) << 32; }
static inline int32_t vp_ld_i32(const uint8_t *p) { return (int32_t)vp_ld_u32(p); }
static inline float vp_ld_f32(const uint8_t *p)
{
    uint32_t u = vp_ld_u32(p);
    float f;
    memcpy(&f, &u, sizeof f);
    return f;
}
static inline double vp_ld_f64(const uint8_t *p)
{
    uint64_t u = vp_ld_u64(p);
    double d;
    memcpy(&d, &u, sizeof d);
    return d;
}
static inline void vp_st_u8(uint8_t *p, uint8_t v) { p[0] = v; }
static inline void vp_st_u16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
}
static inline void vp_st_u32(uint8_t *p, uint32_t v)
{
    for (int i = 0; i < 4; i++) p[i] = (uint8_t)(v >> (8 * i));
}
static inline void vp_st_u64(uint8_t *p, uint64_t v)
{
    for (int i = 0; i < 8; i++) p[i] = (uint8_t)(v >> (8 * i));
}
static inline void vp_st_i32(uint8_t *p, int32_t v) { vp_st_u32(p, (uint32_t)v); }
static inline void vp_st_f32(uint8_t *p, float v)
{
    uint32_t u;
    memcpy(&u, &v, sizeof u);
    vp_st_u32(p, u);
}
static inline void vp_st_f64(uint8_t *p, double v)
{
    uint64_t u;
    memcpy(&u, &v, sizeof u);
    vp_st_u64(p, u);
}

/* The scalars a writer puts and a reader gets: suffix, C type, bytes. */
#define VP_SCALARS(X)                                                                                                \
    X(u8, uint8_t, 1) X(u16, uint16_t, 2) X(u32, uint32_t, 4) X(u64, uint64_t, 8) X(i32, int32_t, 4)                  \
    X(f32, float, 4) X(f64, double, 8)

/* ---- writer ----------------------------------------------------------------------------- */

typedef struct vp_writer {
    uint8_t *p;
    size_t   cap, len;      /* bytes: room and written */
    size_t   frame_start;   /* where the open frame began (vp_frame_begin) */
    bool     overflow;      /* sticky: a write did not fit; nothing after it was written */
    bool     grows;         /* p is the writer's own (vp_writer_init_grow; vp_writer_free) */
} vp_writer;

/* A writer over buf[0..cap), which the caller owns. */
static inline void vp_writer_init(vp_writer *w, uint8_t *buf, size_t cap)
{
    memset(w, 0, sizeof *w);
    w->p = buf;
    w->cap = cap;
}

/* A writer over a heap buffer of its own that grows as written; w->p holds
 * w->len bytes until vp_writer_free. */
static inline void vp_writer_init_grow(vp_writer *w)
{
    memset(w, 0, sizeof *w);
    w->grows = true;
}

/* Frees a growing writer's buffer (nothing for a fixed one's) and empties it. */
static inline void vp_writer_free(vp_writer *w)
{
    if (w->grows) free(w->p);
    w->p = NULL;
    w->cap = w->len = 0;
}

/* Room for n more bytes, counted as written: their address, or NULL with
 * w->overflow set (and nothing written) when they do not fit. (NULL too,
 * overflow not set, for n = 0 on a writer with no buffer yet.) */
static inline uint8_t *vp_reserve(vp_writer *w, size_t n)
{
    if (w->overflow) return NULL;
    if (w->cap - w->len < n) {
        void *p = w->p;
        if (!w->grows || n > SIZE_MAX - w->len || !vp_grow(&p, &w->cap, w->len + n, 1)) {
            w->overflow = true;
            return NULL;
        }
        w->p = (uint8_t *)p;
    }
    if (!w->p) return NULL; /* n is 0: no address to give, none needed */
    uint8_t *p = w->p + w->len;
    w->len += n;
    return p;
}

/* vp_put_u8, _u16, _u32, _u64, _i32, _f32, _f64 (VP_SCALARS): the value,
 * little-endian, or nothing and w->overflow. */
#define VP_PUT_SCALAR(t, T, n)                                                                                       \
    static inline void vp_put_##t(vp_writer *w, T v)                                                                 \
    {                                                                                                                \
        uint8_t *p = vp_reserve(w, n);                                                                               \
        if (p) vp_st_##t(p, v);                                                                                      \
    }
VP_SCALARS(VP_PUT_SCALAR)
#undef VP_PUT_SCALAR

/* n bytes as they are (src may be NULL when n is 0). */
static inline void vp_put_bytes(vp_writer *w, const void *src, size_t n)
{
    uint8_t *p = vp_reserve(w, n);
    if (p && n) memcpy(p, src, n);
}

/* ---- reader ---------------------------------------------------------------------------- */

typedef struct vp_reader {
    const uint8_t *p;
    size_t len, pos;        /* bytes: all, and read so far */
    bool   short_read;      /* sticky: a read went past the end */
} vp_reader;

static inline void vp_reader_init(vp_reader *r, const uint8_t *p, size_t len)
{
    memset(r, 0, sizeof *r);
    r->p = p;
    r->len = len;
}

/* The next n bytes, in place, or NULL (and short_read) when fewer are left. */
static inline const uint8_t *vp_get_bytes(vp_reader *r, size_t n)
{
    if (r->short_read || r->len - r->pos < n) {
        r->short_read = true;
        return NULL;
    }
    const uint8_t *p = r->p + r->pos;
    r->pos += n;
    return p;
}

/* Bytes left; 0 once a read ran short. */
static inline size_t vp_remaining(const vp_reader *r) { return r->short_read ? 0 : r->len - r->pos; }

/* n records of size bytes each, in place: NULL (and short_read) when fewer
 * are left. The check divides, so no count can wrap it. size > 0. */
static inline const uint8_t *vp_get_array(vp_reader *r, size_t n, size_t size)
{
    if (n > vp_remaining(r) / size) {
        r->short_read = true;
        return NULL;
    }
    return vp_get_bytes(r, n * size);
}

/* n bytes copied to dst; zeros there when they are not all there. */
static inline void vp_get_copy(vp_reader *r, void *dst, size_t n)
{
    const uint8_t *p = vp_get_bytes(r, n);
    if (p) memcpy(dst, p, n);
    else if (n) memset(dst, 0, n);
}

/* vp_get_u8, _u16, _u32, _u64, _i32, _f32, _f64 (VP_SCALARS): the value,
 * or 0 and short_read. */
#define VP_GET_SCALAR(t, T, n)                                                                                       \
    static inline T vp_get_##t(vp_reader *r)                                                                         \
    {                                                                                                                \
        const uint8_t *p = vp_get_bytes(r, n);                                                                       \
        return p ? vp_ld_##t(p) : (T)0;                                                                              \
    }
VP_SCALARS(VP_GET_SCALAR)
#undef VP_GET_SCALAR

#endif
