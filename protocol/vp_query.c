/*
 * vp_query.c — the query and picture messages of the protocol (see
 * protocol.h and PROTOCOL.md): the view record, VIS_QUERY / VIS_RESULT,
 * RENDER / FRAME / FRAME_SUBSCRIBE and LIGHT_QUERY / LIGHT_TILES.
 */
#include "vp_internal.h"
#include "vp_layout.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

/* ---- views ---------------------------------------------------------------------- */

#define VIEW_FIELDS(X)                                                                                      \
    X(f64a, origin) X(f64a, view_proj) X(u8, depth_mode) X(pad8, pad1) X(u16, viewport_w) X(u16, viewport_h) \
    X(pad16, pad2)
VP_LAYOUT(view, vp_view, VIEW_FIELDS)

static int view_check(const vp_view *v)
{
    if (!vp_finite_n(v->origin, 3) || !vp_finite_n(v->view_proj, 16)) return VP_ERR_NONFINITE;
    if (v->depth_mode > 2) return VP_ERR_INVALID;
    if ((v->viewport_w == 0) != (v->viewport_h == 0)) return VP_ERR_INVALID;
    return VP_OK;
}

/* A view from the wire (VP_VIEW_SIZE bytes at p, length already checked):
 * read, pads zero, fields checked. */
static int view_take(const uint8_t *p, vp_view *v)
{
    vp_reader r;
    vp_reader_init(&r, p, VP_VIEW_SIZE);
    if (view_get(&r, v)) return VP_ERR_INVALID;
    return view_check(v);
}

/* A picture's view (RENDER, LIGHT_QUERY): 0 x 0 is 1920 x 1080, and at most
 * VP_FRAME_MAX_PIXELS. */
static int picture_view_take(const uint8_t *p, vp_view *v)
{
    int rc = view_take(p, v);
    if (rc) return rc;
    uint32_t w = v->viewport_w ? v->viewport_w : 1920, h = v->viewport_h ? v->viewport_h : 1080;
    return (uint64_t)w * h > VP_FRAME_MAX_PIXELS ? VP_ERR_LIMIT : VP_OK;
}

/* ---- VIS_QUERY / VIS_RESULT ----------------------------------------------------- */

#define VIS_QUERY_FIELDS(X) X(u8, view_count) X(u8, flags) X(pad16, pad1) X(f32, min_area)
VP_LAYOUT(vis_query, vp_vis_query, VIS_QUERY_FIELDS)

size_t vp_size_vis_query(uint32_t n)
{
    return VP_HEADER_SIZE + vis_query_size() + (size_t)n * VP_VIEW_SIZE;
}

size_t vp_size_vis_query_sub(uint8_t flags, uint32_t n, const uint16_t *subs, uint32_t nsub)
{
    bool listed = subs || (flags & VP_Q_SUBLEVELS);
    return vp_size_vis_query(n) + (listed ? 2 + 2 * (size_t)nsub : 0);
}

void vp_enc_vis_query_sub(vp_writer *w, uint32_t req, uint8_t flags, float min_area, const vp_view *v, uint32_t n,
                          const uint16_t *subs, uint32_t nsub)
{
    if (subs) flags |= VP_Q_SUBLEVELS;
    vp_frame_begin(w, VP_VIS_QUERY, req);
    vis_query_put(w, &(vp_vis_query){.view_count = (uint8_t)n, .flags = flags, .min_area = min_area});
    for (uint32_t i = 0; i < n; i++) view_put(w, &v[i]);
    if (flags & VP_Q_SUBLEVELS) {
        vp_put_u16(w, (uint16_t)nsub);
        for (uint32_t i = 0; i < nsub; i++) vp_put_u16(w, subs[i]);
    }
    vp_frame_end(w);
}

void vp_enc_vis_query(vp_writer *w, uint32_t req, uint8_t flags, float min_area, const vp_view *v, uint32_t n)
{
    vp_enc_vis_query_sub(w, req, flags & (uint8_t)~VP_Q_SUBLEVELS, min_area, v, n, NULL, 0);
}

int vp_dec_vis_query(const uint8_t *p, size_t len, vp_vis_query *m)
{
    vp_reader r;
    int rc = vis_query_head(&r, p, len, m);
    if (rc) return rc;
    if (m->view_count == 0 || m->view_count > VP_MAX_VIEWS) return VP_ERR_COUNT;
    if (!isfinite(m->min_area)) return VP_ERR_NONFINITE;
    if (m->min_area < 0) return VP_ERR_INVALID;
    if ((m->flags & VP_Q_STATIC_ONLY) && (m->flags & VP_Q_DYNAMIC_ONLY)) return VP_ERR_INVALID;
    if ((rc = vp_take_array(&r, m->view_count, VP_VIEW_SIZE, 0, &m->views))) return rc;
    m->nsub = 0;
    m->subs = NULL;
    if (m->flags & VP_Q_SUBLEVELS) {
        m->nsub = vp_get_u16(&r);
        if (r.short_read) return VP_ERR_TRUNCATED;
        if (m->nsub == 0) return VP_ERR_COUNT;
        if ((rc = vp_take_array(&r, m->nsub, 2, VP_MAX_QUERY_SUBLEVELS, &m->subs))) return rc;
    }
    if ((rc = vp_reader_finish(&r))) return rc == VP_ERR_TRAILING ? VP_ERR_COUNT : rc;
    for (uint32_t i = 0; i < m->view_count; i++) {
        vp_view v;
        if ((rc = view_take(m->views + (size_t)i * VP_VIEW_SIZE, &v))) return rc;
    }
    return VP_OK;
}

uint16_t vp_query_sublevel_get(const vp_vis_query *q, uint32_t i)
{
    return i < q->nsub ? rd16(q->subs + 2 * (size_t)i) : 0;
}

int vp_view_get(const vp_vis_query *q, uint32_t i, vp_view *out)
{
    if (i >= q->view_count) return VP_ERR_COUNT;
    return view_take(q->views + (size_t)i * VP_VIEW_SIZE, out);
}

#define VIS_RESULT_FIELDS(X) X(u64, epoch) X(u32, tested) X(u32, visible) X(u32a, stage_ns) X(u32, count)
VP_LAYOUT(vis_result, vp_vis_result, VIS_RESULT_FIELDS)

#define VIS_REC_FIELDS(X) \
    X(u64, id) X(u32, handle) X(u32, view_mask) X(u16, class_id) X(u16, sublevel) X(f32, area)
VP_LAYOUT(vis_rec, vp_vis_rec, VIS_REC_FIELDS)

size_t vp_size_vis_result(uint32_t n)
{
    return VP_HEADER_SIZE + vis_result_size() + (size_t)n * VP_VIS_REC_SIZE;
}

void vp_enc_vis_result_begin(vp_writer *w, uint32_t req, const vp_vis_result *m)
{
    vp_frame_begin(w, VP_VIS_RESULT, req);
    vis_result_put(w, m);
}

/* The daemon writes every visible entity through here: one reservation
 * and direct stores (vis_rec_put would check the room six times). */
void vp_put_vis_rec(vp_writer *w, const vp_vis_rec *r)
{
    uint8_t *p = vp_reserve(w, VP_VIS_REC_SIZE);
    if (!p) return;
    wr64(p, r->id);
    wr32(p + 8, r->handle);
    wr32(p + 12, r->view_mask);
    wr16(p + 16, r->class_id);
    wr16(p + 18, r->sublevel);
    uint32_t a;
    memcpy(&a, &r->area, sizeof a);
    wr32(p + 20, a);
}

int vp_dec_vis_result(const uint8_t *p, size_t len, vp_vis_result *m)
{
    vp_reader r;
    vp_reader_init(&r, p, len);
    (void)vis_result_get(&r, m);
    return vp_take_rest(&r, m->count, VP_VIS_REC_SIZE, 0, &m->recs);
}

void vp_vis_rec_get(const vp_vis_result *r, uint32_t i, vp_vis_rec *out)
{
    if (i >= r->count) {
        memset(out, 0, sizeof *out);
        return;
    }
    vp_reader rd;
    vp_reader_init(&rd, r->recs + (size_t)i * VP_VIS_REC_SIZE, VP_VIS_REC_SIZE);
    (void)vis_rec_get(&rd, out);
}

/* ---- RENDER / FRAME_SUBSCRIBE / FRAME --------------------------------------------- */

/* RENDER's fields after its view */
#define RENDER_FIELDS(X)                                                                                    \
    X(u8, format) X(u8, quality) X(u8, flags) X(u8, renderer) X(f32, exposure_ev) X(u8, nhighlight)        \
    X(pad8, pad1) X(pad16, pad2) X(u32, max_kbps) X(u64a, highlight)
#define RENDER_CHECKS(X)                                                                                    \
    X(count, nhighlight, "highlights", "", 0, VP_RENDER_MAX_HIGHLIGHT)                                     \
    X(max, renderer, "renderer", "0 default, 1 software, 2 OpenGL are defined", 0, VP_RENDERER_GL)         \
    X(max, format, "format", "0 raw, 1 JPEG, 2 H.264 are defined", 0, VP_FRAME_H264)                      \
    X(mask, flags, "flags",                                                                                \
      "0x1 no occlusion, 0x2 no shadows, 0x4 no ambient occlusion, 0x8 no image-based ambient, 0x10 no FXAA, " \
      "0x20 no shared selection, 0x40 dynamic resolution while the view moves are defined",                \
      0, VP_RENDER_FLAGS)                                                                                  \
    X(range, exposure_ev, "exposure", "", -64, 64)
VP_LAYOUT_CHECKED(render_tail, vp_render, RENDER_FIELDS, RENDER_CHECKS)

static void render_put(vp_writer *w, const vp_render *m)
{
    view_put(w, &m->view);
    render_tail_put(w, m);
}

/* The RENDER fields at p (VP_RENDER_SIZE bytes, already length-checked). */
static int render_read(const uint8_t *p, vp_render *m)
{
    vp_reader r;
    vp_reader_init(&r, p + VP_VIEW_SIZE, VP_RENDER_SIZE - VP_VIEW_SIZE);
    int rc = render_tail_check_fields(m, render_tail_get(&r, m), "", NULL, 0);
    if (rc) return rc;
    if (m->format == VP_FRAME_JPEG && (m->quality < 1 || m->quality > 100)) return VP_ERR_INVALID;
    if (m->format == VP_FRAME_RAW && m->quality) return VP_ERR_INVALID;
    if (m->format == VP_FRAME_H264 && m->quality > 51) return VP_ERR_INVALID; /* x264's CRF scale */
    if (m->format != VP_FRAME_H264 && m->max_kbps) return VP_ERR_INVALID;
    for (uint32_t i = m->nhighlight; i < VP_RENDER_MAX_HIGHLIGHT; i++)
        if (m->highlight[i]) return VP_ERR_INVALID; /* past the count: 0, so a list has one reading */
    return picture_view_take(p, &m->view);
}

/* A payload of exactly size bytes, or the code that says how it is not. */
static int exact(size_t len, size_t size)
{
    return len < size ? VP_ERR_TRUNCATED : len > size ? VP_ERR_TRAILING : VP_OK;
}

size_t vp_size_render(void)
{
    return VP_HEADER_SIZE + VP_RENDER_SIZE;
}

void vp_enc_render(vp_writer *w, uint32_t req, const vp_render *m)
{
    vp_frame_begin(w, VP_RENDER, req);
    render_put(w, m);
    vp_frame_end(w);
}

int vp_dec_render(const uint8_t *p, size_t len, vp_render *m)
{
    int rc = exact(len, VP_RENDER_SIZE);
    return rc ? rc : render_read(p, m);
}

size_t vp_size_frame_sub(void)
{
    return VP_HEADER_SIZE + VP_FRAME_SUB_SIZE;
}

void vp_enc_frame_sub(vp_writer *w, uint32_t req, const vp_frame_sub *m)
{
    vp_frame_begin(w, VP_FRAME_SUBSCRIBE, req);
    render_put(w, &m->r);
    vp_put_u16(w, m->max_fps);
    vp_put_u16(w, m->view_seq);
    vp_frame_end(w);
}

int vp_dec_frame_sub(const uint8_t *p, size_t len, vp_frame_sub *m)
{
    int rc = exact(len, VP_FRAME_SUB_SIZE);
    if (rc || (rc = render_read(p, &m->r))) return rc;
    m->max_fps = rd16(p + VP_RENDER_SIZE);
    m->view_seq = rd16(p + VP_RENDER_SIZE + 2);
    if (m->max_fps < 1 || m->max_fps > VP_FRAME_SUB_MAX_FPS) return VP_ERR_INVALID;
    return VP_OK;
}

#define FRAME_FIELDS(X)                                                                                     \
    X(u64, epoch) X(u16, width) X(u16, height) X(u8, format) X(u8, key) X(u16, view_seq) X(u32, visible)     \
    X(u32, render_ns) X(u32, encode_ns) X(u32, data_len)
VP_LAYOUT(frame, vp_frame, FRAME_FIELDS)

size_t vp_size_frame(uint32_t data_len)
{
    return VP_HEADER_SIZE + VP_FRAME_HEADER + (size_t)data_len;
}

void vp_enc_frame(vp_writer *w, uint32_t req, const vp_frame *m)
{
    vp_frame_begin(w, VP_FRAME, req);
    frame_put(w, m);
    if (m->data) vp_put_bytes(w, m->data, m->data_len);
    else if (w->cap - w->len >= m->data_len) w->len += m->data_len; /* written in place */
    else w->overflow = true;
    vp_frame_end(w);
}

int vp_dec_frame(const uint8_t *p, size_t len, vp_frame *m)
{
    vp_reader r;
    int rc = frame_head(&r, p, len, m);
    if (rc) return rc;
    m->data = p + VP_FRAME_HEADER;
    if (m->format > VP_FRAME_H264 || !m->width || !m->height || m->key > 1 || (m->key && m->format != VP_FRAME_H264))
        return VP_ERR_INVALID;
    if (len - VP_FRAME_HEADER < m->data_len) return VP_ERR_TRUNCATED;
    if (len - VP_FRAME_HEADER > m->data_len) return VP_ERR_TRAILING;
    if (m->format == VP_FRAME_RAW && (uint64_t)m->data_len != (uint64_t)m->width * m->height * 20) return VP_ERR_COUNT;
    return VP_OK;
}

/* ---- LIGHT_QUERY / LIGHT_TILES ------------------------------------------------------ */

#define LIGHT_QUERY_FIELDS(X) X(u8, flags) X(pad8, pad1) X(pad16, pad2)
VP_LAYOUT(light_query_tail, vp_light_query, LIGHT_QUERY_FIELDS)

size_t vp_size_light_query(void)
{
    return VP_HEADER_SIZE + VP_LIGHT_QUERY_SIZE;
}

void vp_enc_light_query(vp_writer *w, uint32_t req, const vp_light_query *m)
{
    vp_frame_begin(w, VP_LIGHT_QUERY, req);
    view_put(w, &m->view);
    light_query_tail_put(w, m);
    vp_frame_end(w);
}

int vp_dec_light_query(const uint8_t *p, size_t len, vp_light_query *m)
{
    int rc = exact(len, VP_LIGHT_QUERY_SIZE);
    if (rc) return rc;
    vp_reader r;
    vp_reader_init(&r, p + VP_VIEW_SIZE, VP_LIGHT_QUERY_SIZE - VP_VIEW_SIZE);
    if (light_query_tail_get(&r, m) || (m->flags & ~VP_LQ_NO_DEPTH)) return VP_ERR_INVALID;
    return picture_view_take(p, &m->view);
}

#define LIGHT_TILES_FIELDS(X)                                                                              \
    X(u64, epoch) X(u16, tiles_x) X(u16, tiles_y) X(u16, tile) X(u8, flags) X(pad8, pad1) X(u32, in_view)   \
    X(u32, max_per_tile) X(u32, count) X(u32, ns)
VP_LAYOUT(light_tiles, vp_light_tiles, LIGHT_TILES_FIELDS)

size_t vp_size_light_tiles(uint32_t tiles, uint32_t count)
{
    return VP_HEADER_SIZE + VP_LIGHT_TILES_HEADER + 4 * ((size_t)tiles + 1) + 8 * (size_t)count;
}

void vp_enc_light_tiles_begin(vp_writer *w, uint32_t req, const vp_light_tiles *m)
{
    vp_frame_begin(w, VP_LIGHT_TILES, req);
    light_tiles_put(w, m);
}

int vp_dec_light_tiles(const uint8_t *p, size_t len, vp_light_tiles *m)
{
    vp_reader r;
    int rc = light_tiles_head(&r, p, len, m);
    if (rc) return rc;
    uint64_t tiles = (uint64_t)m->tiles_x * m->tiles_y;
    uint64_t need = VP_LIGHT_TILES_HEADER + 4 * (tiles + 1) + 8 * (uint64_t)m->count;
    if (len < need) return VP_ERR_TRUNCATED;
    if (len > need) return VP_ERR_TRAILING;
    m->offsets = p + VP_LIGHT_TILES_HEADER;
    m->ids = m->offsets + 4 * (tiles + 1);
    /* the lists must be well formed: offsets from 0, never falling, to count */
    uint32_t prev = 0;
    for (uint64_t t = 0; t <= tiles; t++) {
        uint32_t o = rd32(m->offsets + 4 * t);
        if ((t == 0 && o != 0) || o < prev || o > m->count) return VP_ERR_INVALID;
        prev = o;
    }
    if (prev != m->count) return VP_ERR_INVALID;
    return VP_OK;
}

uint32_t vp_light_tiles_offset(const vp_light_tiles *m, uint32_t t)
{
    return t <= (uint32_t)m->tiles_x * m->tiles_y ? rd32(m->offsets + 4 * (size_t)t) : m->count;
}

uint64_t vp_light_tiles_id(const vp_light_tiles *m, uint32_t k)
{
    return k < m->count ? rd64(m->ids + 8 * (size_t)k) : 0;
}

int vp_render_fx_parse(const char *list, uint8_t *flags, char *bad, size_t badlen)
{
    static const struct {
        const char *name;
        uint8_t bit;
    } fx[] = {{"shadows", VP_RENDER_NO_SHADOWS}, {"ssao", VP_RENDER_NO_SSAO}, {"ibl", VP_RENDER_NO_IBL},
              {"fxaa", VP_RENDER_NO_FXAA}, {"none", 0}};
    *flags = 0;
    for (const char *p = list; p && *p;) {
        size_t n = strcspn(p, ",");
        size_t k = 0;
        while (k < sizeof fx / sizeof fx[0] && !(strlen(fx[k].name) == n && !strncmp(p, fx[k].name, n))) k++;
        if (k == sizeof fx / sizeof fx[0]) {
            if (bad) snprintf(bad, badlen, "%.*s", (int)(n < 64 ? n : 64), p);
            return -1;
        }
        *flags |= fx[k].bit;
        p += n + (p[n] == ',');
    }
    return 0;
}
