/*
 * protocol.c — see protocol.h and PROTOCOL.md: errors and type names,
 * framing (on vp_bytes.h's writer and reader), and the session messages.
 * The other messages are one file per family (vp_entities.c, vp_query.c,
 * vp_assets.c, vp_sublevel.c, vp_events.c). Byte-level reads and
 * writes are vp_bytes.h's explicit little-endian shifts, so the code is
 * right on any host.
 * Decoders check sizes from the counts before touching records and never
 * allocate; a payload is either accepted whole or rejected with a code.
 */
#include "vp_internal.h"
#include "vp_layout.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

VP_ERR_DEFINE_STRERROR(vp_strerror, VP_ERRORS)

static const struct { uint16_t type; const char *name; } type_names[] = {
    {VP_HELLO, "hello"},
    {VP_HELLO_OK, "hello_ok"},
    {VP_ERROR, "error"},
    {VP_PING, "ping"},
    {VP_PONG, "pong"},
    {VP_STATS, "stats"},
    {VP_STATS_REPLY, "stats_reply"},
    {VP_SUBSCRIBE, "subscribe"},
    {VP_EVENT, "event"},
    {VP_ACK, "ack"},
    {VP_ENTITY_ADD, "entity_add"},
    {VP_ENTITY_ADD_REPLY, "entity_add_reply"},
    {VP_ENTITY_UPDATE, "entity_update"},
    {VP_ENTITY_REMOVE, "entity_remove"},
    {VP_ENTITY_LIST, "entity_list"},
    {VP_ENTITY_LIST_REPLY, "entity_list_reply"},
    {VP_ENTITY_GET, "entity_get"},
    {VP_MESH_PUT, "mesh_put"},
    {VP_MESH_GET, "mesh_get"},
    {VP_MESH_REPLY, "mesh_reply"},
    {VP_OCCLUDER_PUT, "occluder_put"},
    {VP_OCCLUDER_REMOVE, "occluder_remove"},
    {VP_LIGHT_PUT, "light_put"},
    {VP_LIGHT_REMOVE, "light_remove"},
    {VP_LIGHT_LIST, "light_list"},
    {VP_LIGHT_LIST_REPLY, "light_list_reply"},
    {VP_TRANSFORM_SET, "transform_set"},
    {VP_MATERIAL_PUT, "material_put"},
    {VP_MATERIAL_REMOVE, "material_remove"},
    {VP_MATERIAL_LIST, "material_list"},
    {VP_MATERIAL_LIST_REPLY, "material_list_reply"},
    {VP_TEXTURE_PUT, "texture_put"},
    {VP_TEXTURE_REMOVE, "texture_remove"},
    {VP_TEXTURE_GET, "texture_get"},
    {VP_TEXTURE_REPLY, "texture_reply"},
    {VP_ENV_SET, "env_set"},
    {VP_ENV_GET, "env_get"},
    {VP_ENV_REPLY, "env_reply"},
    {VP_SUBLEVEL_NAMES, "sublevel_names"},
    {VP_SUBLEVEL_IDS, "sublevel_ids"},
    {VP_SUBLEVEL_LIST, "sublevel_list"},
    {VP_SUBLEVEL_LIST_REPLY, "sublevel_list_reply"},
    {VP_SUBLEVEL_BEGIN, "sublevel_begin"},
    {VP_SUBLEVEL_BEGUN, "sublevel_begun"},
    {VP_SUBLEVEL_COMMIT, "sublevel_commit"},
    {VP_SUBLEVEL_ABORT, "sublevel_abort"},
    {VP_SUBLEVEL_UNLOAD, "sublevel_unload"},
    {VP_SUBLEVEL_INFO, "sublevel_info"},
    {VP_SUBLEVEL_INFO_REPLY, "sublevel_info_reply"},
    {VP_DESTROY, "destroy"},
    {VP_DESTROYED, "destroyed"},
    {VP_MARK, "mark"},
    {VP_MARKED, "marked"},
    {VP_SELECT, "select"},
    {VP_SELECTED, "selected"},
    {VP_VIS_QUERY, "vis_query"},
    {VP_VIS_RESULT, "vis_result"},
    {VP_RENDER, "render"},
    {VP_FRAME, "frame"},
    {VP_FRAME_SUBSCRIBE, "frame_subscribe"},
    {VP_LIGHT_QUERY, "light_query"},
    {VP_LIGHT_TILES, "light_tiles"},
    {VP_FRAME_UNSUBSCRIBE, "frame_unsubscribe"},
    {VP_METRICS, "metrics"},
    {VP_METRICS_REPLY, "metrics_reply"},
};

bool vp_type_known(uint16_t type)
{
    for (size_t i = 0; i < sizeof type_names / sizeof type_names[0]; i++)
        if (type_names[i].type == type) return true;
    return false;
}

const char *vp_type_name(uint16_t type)
{
    for (size_t i = 0; i < sizeof type_names / sizeof type_names[0]; i++)
        if (type_names[i].type == type) return type_names[i].name;
    return "unknown";
}

/* ---- framing ---------------------------------------------------------------------- */

int vp_frame_check(const uint8_t *buf, size_t n, uint32_t max_payload, vp_header *h, size_t *frame_size)
{
    if (n < VP_HEADER_SIZE) return VP_NEED_MORE;
    h->len = rd32(buf);
    h->type = rd16(buf + 4);
    h->flags = rd16(buf + 6);
    h->req = rd32(buf + 8);
    if (h->len > max_payload) return VP_ERR_TOO_LARGE;
    if (h->flags) return VP_ERR_INVALID;
    *frame_size = VP_HEADER_SIZE + (size_t)h->len;
    return n >= *frame_size ? VP_OK : VP_NEED_MORE;
}

/* The writer and the reader are vp_bytes.h's; a frame is written on the
 * writer and a payload finished on the reader here. */
void vp_frame_begin(vp_writer *w, uint16_t type, uint32_t req)
{
    w->frame_start = w->len;
    /* one reservation for the header, not four: every reply starts here */
    uint8_t *p = vp_reserve(w, VP_HEADER_SIZE);
    if (!p) return;
    vp_st_u32(p, 0); /* the length, patched by vp_frame_end */
    vp_st_u16(p + 4, type);
    vp_st_u16(p + 6, 0); /* flags */
    vp_st_u32(p + 8, req);
}

bool vp_frame_end(vp_writer *w)
{
    if (w->overflow) return false;
    size_t payload = w->len - w->frame_start - VP_HEADER_SIZE;
    if (payload > UINT32_MAX) {
        w->overflow = true;
        return false;
    }
    wr32(w->p + w->frame_start, (uint32_t)payload);
    return true;
}

int vp_reader_finish(const vp_reader *r)
{
    if (r->short_read) return VP_ERR_TRUNCATED;
    return r->pos == r->len ? VP_OK : VP_ERR_TRAILING;
}

int vp_take_array(vp_reader *r, uint32_t n, size_t rec, uint32_t max, const uint8_t **out)
{
    if (max && n > max) return VP_ERR_COUNT;
    size_t left = vp_remaining(r);
    if (r->short_read) return VP_ERR_TRUNCATED;
    if ((uint64_t)n * rec > left) return VP_ERR_COUNT;
    *out = vp_get_bytes(r, (size_t)n * rec);
    return VP_OK;
}

int vp_take_rest(vp_reader *r, uint32_t n, size_t rec, uint32_t max, const uint8_t **out)
{
    if (r->short_read) return VP_ERR_TRUNCATED;
    int rc = vp_take_array(r, n, rec, max, out);
    if (rc) return rc;
    rc = vp_reader_finish(r);
    return rc == VP_ERR_TRAILING ? VP_ERR_COUNT : rc;
}

void vp_enc_batch(vp_writer *w, uint16_t type, uint32_t req, const void *recs, size_t stride, uint32_t n,
                  void (*put)(vp_writer *w, const void *rec))
{
    vp_frame_begin(w, type, req);
    vp_put_u32(w, n);
    for (uint32_t i = 0; i < n; i++) put(w, (const uint8_t *)recs + i * stride);
    vp_frame_end(w);
}

bool vp_finite_n(const double *v, int n)
{
    for (int i = 0; i < n; i++)
        if (!isfinite(v[i])) return false;
    return true;
}

bool vp_finite_nf(const float *v, int n)
{
    for (int i = 0; i < n; i++)
        if (!isfinite(v[i])) return false;
    return true;
}

/* ---- session messages ------------------------------------------------------------ */

size_t vp_size_hello(const vp_hello *m)
{
    return VP_HEADER_SIZE + 9 + (size_t)m->token_len + m->name_len;
}

void vp_enc_hello(vp_writer *w, uint32_t req, const vp_hello *m)
{
    vp_frame_begin(w, VP_HELLO, req);
    vp_put_u32(w, m->magic);
    vp_put_u16(w, m->version);
    vp_put_u8(w, m->role);
    vp_put_u8(w, m->token_len);
    vp_put_bytes(w, m->token, m->token_len);
    vp_put_u8(w, m->name_len);
    vp_put_bytes(w, m->name, m->name_len);
    vp_frame_end(w);
}

int vp_dec_hello(const uint8_t *p, size_t len, vp_hello *m)
{
    vp_reader r;
    vp_reader_init(&r, p, len);
    m->magic = vp_get_u32(&r);
    if (r.short_read) return VP_ERR_TRUNCATED;
    if (m->magic != VP_MAGIC) return VP_ERR_MAGIC;
    m->version = vp_get_u16(&r);
    m->role = vp_get_u8(&r);
    m->token_len = vp_get_u8(&r);
    m->token = vp_get_bytes(&r, m->token_len);
    m->name_len = vp_get_u8(&r);
    m->name = vp_get_bytes(&r, m->name_len);
    int rc = vp_reader_finish(&r);
    if (rc) return rc;
    if (m->version < VP_VERSION_MIN || m->version > VP_VERSION) return VP_ERR_VERSION;
    if (m->role > VP_ROLE_EDITOR) return VP_ERR_INVALID;
    return VP_OK;
}

#define HELLO_OK_FIELDS(X)                                                                                 \
    X(u16, version) X(u8, role) X(rsv8, pad1) X(u32, max_payload) X(u32, max_batch) X(u32, max_views)       \
    X(u64, epoch) X(u32, client_id)
VP_LAYOUT(hello_ok, vp_hello_ok, HELLO_OK_FIELDS)

VP_MESSAGE(hello_ok, vp_hello_ok, VP_HELLO_OK)
VP_MESSAGE_DEC(hello_ok, vp_hello_ok)

/* ---- UTF-8 --------------------------------------------------------------------- */

size_t vp_utf8_check(const uint8_t *p, size_t n, const char **why)
{
    size_t i = 0;
    while (i < n) {
        uint8_t b = p[i];
        if (b < 0x80) {
            i++;
            continue;
        }
        uint32_t len, cp, min;
        if (b < 0xC0) {
            if (why) *why = "a continuation byte without a lead byte";
            return i;
        } else if (b < 0xE0) {
            len = 2, cp = b & 0x1Fu, min = 0x80;
        } else if (b < 0xF0) {
            len = 3, cp = b & 0x0Fu, min = 0x800;
        } else if (b < 0xF8) {
            len = 4, cp = b & 0x07u, min = 0x10000;
        } else {
            if (why) *why = "a byte that never occurs in UTF-8 (0xF8..0xFF)";
            return i;
        }
        for (uint32_t k = 1; k < len; k++) {
            if (i + k >= n || (p[i + k] & 0xC0u) != 0x80) {
                if (why) *why = "a sequence cut short";
                return i;
            }
            cp = cp << 6 | (p[i + k] & 0x3Fu);
        }
        if (cp < min) {
            if (why) *why = "an overlong encoding";
            return i;
        }
        if (cp >= 0xD800 && cp <= 0xDFFF) {
            if (why) *why = "a UTF-16 surrogate (U+D800..U+DFFF)";
            return i;
        }
        if (cp > 0x10FFFF) {
            if (why) *why = "a code point beyond U+10FFFF";
            return i;
        }
        i += len;
    }
    return n;
}

static size_t escape(char *out, size_t cap, const uint8_t *p, size_t n, bool backslash)
{
    static const char hex[] = "0123456789abcdef";
    size_t o = 0;
    if (!cap) return 0;
    for (size_t i = 0; i < n;) {
        size_t good = p[i] >= 0x80 ? vp_utf8_check(p + i, n - i > 4 ? 4 : n - i, NULL) : 0;
        size_t seq = 1;
        if (p[i] >= 0x80) {
            /* the valid sequence that starts here, if any: its length */
            seq = p[i] < 0xE0 ? 2 : p[i] < 0xF0 ? 3 : 4;
            if (good < seq) seq = 0;
        }
        if (seq && (p[i] >= 0x80 || (p[i] >= 32 && p[i] != 127 && (p[i] != '\\' || !backslash)))) {
            if (o + seq >= cap) break;
            memcpy(out + o, p + i, seq);
            o += seq;
            i += seq;
        } else {
            if (o + 4 >= cap) break;
            out[o++] = '\\';
            out[o++] = 'x';
            out[o++] = hex[p[i] >> 4];
            out[o++] = hex[p[i] & 15];
            i++;
        }
    }
    out[o] = 0;
    return o;
}

size_t vp_escape(char *out, size_t cap, const uint8_t *p, size_t n)
{
    return escape(out, cap, p, n, true);
}

size_t vp_size_error(const char *msg)
{
    char esc[VP_MAX_ERROR_MSG + 1];
    return VP_HEADER_SIZE + 10 + (msg ? escape(esc, sizeof esc, (const uint8_t *)msg, strlen(msg), false) : 0);
}

void vp_enc_error(vp_writer *w, uint32_t req, int32_t code, uint32_t index, const char *msg)
{
    /* escaped: whatever client bytes a message quotes, ERROR carries valid
       UTF-8 without control characters, at most VP_MAX_ERROR_MSG bytes
       (backslashes kept: a message quotes client bytes through vp_escape,
       whose \\xNN must arrive as written) */
    char esc[VP_MAX_ERROR_MSG + 1];
    size_t n = msg ? escape(esc, sizeof esc, (const uint8_t *)msg, strlen(msg), false) : 0;
    vp_frame_begin(w, VP_ERROR, req);
    vp_put_i32(w, code);
    vp_put_u32(w, index);
    vp_put_u16(w, (uint16_t)n);
    vp_put_bytes(w, esc, n);
    vp_frame_end(w);
}

int vp_dec_error(const uint8_t *p, size_t len, vp_error *m)
{
    vp_reader r;
    vp_reader_init(&r, p, len);
    m->code = vp_get_i32(&r);
    m->index = vp_get_u32(&r);
    m->msg_len = vp_get_u16(&r);
    if (m->msg_len > VP_MAX_ERROR_MSG) return VP_ERR_COUNT;
    m->msg = vp_get_bytes(&r, m->msg_len);
    return vp_reader_finish(&r);
}

size_t vp_size_ping(uint32_t n)
{
    return VP_HEADER_SIZE + (size_t)n;
}

void vp_enc_ping(vp_writer *w, uint16_t type, uint32_t req, const uint8_t *data, uint32_t n)
{
    vp_frame_begin(w, type, req);
    vp_put_bytes(w, data, n);
    vp_frame_end(w);
}

int vp_dec_ping(const uint8_t *p, size_t len, const uint8_t **data, uint32_t *n)
{
    if (len > VP_MAX_PING) return VP_ERR_COUNT;
    *data = p;
    *n = (uint32_t)len;
    return VP_OK;
}

size_t vp_size_empty(void)
{
    return VP_HEADER_SIZE;
}

void vp_enc_empty(vp_writer *w, uint16_t type, uint32_t req)
{
    vp_frame_begin(w, type, req);
    vp_frame_end(w);
}

int vp_dec_empty(const uint8_t *p, size_t len)
{
    (void)p;
    return len ? VP_ERR_TRAILING : VP_OK;
}

#define ACK_FIELDS(X) X(u64, epoch) X(u32, count)
VP_LAYOUT(ack, vp_ack, ACK_FIELDS)

VP_MESSAGE(ack, vp_ack, VP_ACK)
VP_MESSAGE_DEC(ack, vp_ack)

#define STATS_FIELDS(X)                                                                                    \
    X(u64, epoch) X(u64, uptime_ms) X(u32, entities) X(u32, static_entities) X(u32, dynamic_entities)    \
    X(u32, regions) X(u32, cells) X(u32, connections) X(u32, meshes) X(u32, occluders) X(u32, lights)    \
    X(u64, queries) X(u64, edits) X(u64, bytes_in) X(u64, bytes_out) X(u64, errors)
VP_LAYOUT(stats_reply, vp_stats_reply, STATS_FIELDS)
VP_MESSAGE(stats_reply, vp_stats_reply, VP_STATS_REPLY)
VP_MESSAGE_DEC(stats_reply, vp_stats_reply)

size_t vp_size_metrics_reply(uint32_t text_len)
{
    return VP_HEADER_SIZE + VP_METRICS_REPLY_HEADER + (size_t)text_len;
}

#define METRICS_FIELDS(X) X(u8, format) X(pad8, pad1) X(pad16, pad2) X(u32, text_len)
VP_LAYOUT(metrics_head, vp_metrics_reply, METRICS_FIELDS)

void vp_enc_metrics_reply(vp_writer *w, uint32_t req, const vp_metrics_reply *m)
{
    vp_frame_begin(w, VP_METRICS_REPLY, req);
    metrics_head_put(w, m);
    vp_put_bytes(w, m->text, m->text_len);
    vp_frame_end(w);
}

int vp_dec_metrics_reply(const uint8_t *p, size_t len, vp_metrics_reply *m)
{
    vp_reader r;
    vp_reader_init(&r, p, len);
    uint32_t pad = metrics_head_get(&r, m);
    if (r.short_read) return VP_ERR_TRUNCATED;
    if (m->text_len > vp_remaining(&r)) return VP_ERR_TRUNCATED;
    m->text = vp_get_bytes(&r, m->text_len);
    int rc = vp_reader_finish(&r);
    if (rc) return rc;
    if (pad || m->format != VP_METRICS_PROMETHEUS) return VP_ERR_INVALID;
    if (m->text_len && memchr(m->text, 0, m->text_len)) return VP_ERR_INVALID;
    return VP_OK;
}

size_t vp_size_subscribe(void)
{
    return VP_HEADER_SIZE + 4;
}

void vp_enc_subscribe(vp_writer *w, uint32_t req, uint32_t kinds)
{
    vp_frame_begin(w, VP_SUBSCRIBE, req);
    vp_put_u32(w, kinds);
    vp_frame_end(w);
}

int vp_dec_subscribe(const uint8_t *p, size_t len, uint32_t *kinds)
{
    vp_reader r;
    vp_reader_init(&r, p, len);
    *kinds = vp_get_u32(&r);
    int rc = vp_reader_finish(&r);
    if (rc) return rc;
    return (*kinds & ~VP_EVENT_ALL) ? VP_ERR_INVALID : VP_OK;
}

#define EVENT_FIELDS(X) X(u32, kind) X(rsv32, pad1) X(u64, epoch) X(u32, added) X(u32, updated) X(u32, removed)
VP_LAYOUT(event, vp_event, EVENT_FIELDS)

size_t vp_size_event(void)
{
    return VP_HEADER_SIZE + event_size();
}

void vp_enc_event(vp_writer *w, const vp_event *m)
{
    event_enc(w, VP_EVENT, 0, m);
}

int vp_dec_event(const uint8_t *p, size_t len, vp_event *m)
{
    return event_dec(p, len, m);
}

