/*
 * vp_messages.c — the scene and query messages of the protocol (see
 * protocol.h and PROTOCOL.md): entity batches, lists, visibility queries
 * and results, meshes, occluders, lights and sub-level names.
 */
#include "vp_internal.h"

#include <math.h>

/* ---- entities ------------------------------------------------------------------ */

size_t vp_size_entities(uint32_t n)
{
    return VP_HEADER_SIZE + 4 + (size_t)n * VP_ENTITY_REC_SIZE;
}

size_t vp_size_ids(uint32_t n)
{
    return VP_HEADER_SIZE + 4 + (size_t)n * 8;
}

static void put_entities(vp_writer *w, const vp_entity *e, uint32_t n)
{
    vp_put_u32(w, n);
    for (uint32_t i = 0; i < n; i++) {
        vp_put_u64(w, e[i].id);
        vp_put_u32(w, e[i].handle);
        vp_put_u16(w, e[i].class_id);
        vp_put_u16(w, e[i].sublevel);
        vp_put_u32(w, e[i].flags);
        vp_put_u32(w, 0);
        for (int k = 0; k < 4; k++) vp_put_f64(w, e[i].sphere[k]);
        for (int k = 0; k < 6; k++) vp_put_f64(w, e[i].aabb[k]);
    }
}

void vp_enc_entities(vp_writer *w, uint16_t type, uint32_t req, const vp_entity *e, uint32_t n)
{
    vp_frame_begin(w, type, req);
    put_entities(w, e, n);
    vp_frame_end(w);
}

static void entity_read(const uint8_t *p, vp_entity *e)
{
    e->id = rd64(p);
    e->handle = rd32(p + 8);
    e->class_id = rd16(p + 12);
    e->sublevel = rd16(p + 14);
    e->flags = rd32(p + 16);
    for (int k = 0; k < 4; k++) e->sphere[k] = rdf64(p + 24 + 8 * k);
    for (int k = 0; k < 6; k++) e->aabb[k] = rdf64(p + 56 + 8 * k);
}

/* A record's own checks (what no scene state decides), with the field and
 * the cause in why (may be NULL). The range checks are the scene's. */
static int entity_check(const vp_entity *e, char *why, size_t whylen)
{
    static const char *const sname[4] = {"sphere x", "sphere y", "sphere z", "sphere radius"};
    static const char *const bname[6] = {"aabb min x", "aabb min y", "aabb min z",
                                         "aabb max x", "aabb max y", "aabb max z"};
    for (int k = 0; k < 4; k++)
        if (!isfinite(e->sphere[k]))
            return vp_errf(why, whylen, VP_ERR_NONFINITE, "%s is %g: NaN or infinite", sname[k], e->sphere[k]);
    for (int k = 0; k < 6; k++)
        if (!isfinite(e->aabb[k]))
            return vp_errf(why, whylen, VP_ERR_NONFINITE, "%s is %g: NaN or infinite", bname[k], e->aabb[k]);
    if (e->flags & ~VP_ENT_DYNAMIC)
        return vp_errf(why, whylen, VP_ERR_INVALID,
                       "flags 0x%08x has undefined bits 0x%08x (only 0x1, dynamic, is defined)", e->flags,
                       e->flags & ~VP_ENT_DYNAMIC);
    return VP_OK;
}

int vp_entity_rec_check(const vp_entity_batch *b, uint32_t i, char *why, size_t whylen)
{
    if (i >= b->count) return VP_ERR_COUNT;
    vp_entity e;
    entity_read(b->recs + (size_t)i * VP_ENTITY_REC_SIZE, &e);
    return entity_check(&e, why, whylen);
}

/* count + records to the end of the payload */
static int get_entities(vp_reader *rd, uint32_t max_batch, vp_entity_batch *m)
{
    vp_reader r = *rd;
    m->count = vp_get_u32(&r);
    if (r.short_read) return VP_ERR_TRUNCATED;
    int rc = vp_take_array(&r, m->count, VP_ENTITY_REC_SIZE, max_batch, &m->recs);
    if (rc) return rc;
    if ((rc = vp_reader_finish(&r))) return rc == VP_ERR_TRAILING ? VP_ERR_COUNT : rc;
    for (uint32_t i = 0; i < m->count; i++) {
        vp_entity e;
        entity_read(m->recs + (size_t)i * VP_ENTITY_REC_SIZE, &e);
        if ((rc = entity_check(&e, NULL, 0))) return rc;
    }
    *rd = r;
    return VP_OK;
}

int vp_dec_entities(const uint8_t *p, size_t len, uint32_t max_batch, vp_entity_batch *m)
{
    vp_reader r;
    vp_reader_init(&r, p, len);
    return get_entities(&r, max_batch, m);
}

void vp_enc_list(vp_writer *w, uint32_t req, const vp_list *m)
{
    vp_frame_begin(w, VP_ENTITY_LIST, req);
    vp_put_u64(w, m->cursor);
    vp_put_u32(w, m->max);
    vp_frame_end(w);
}

int vp_dec_list(const uint8_t *p, size_t len, uint32_t max_batch, vp_list *m)
{
    vp_reader r;
    vp_reader_init(&r, p, len);
    m->cursor = vp_get_u64(&r);
    m->max = vp_get_u32(&r);
    int rc = vp_reader_finish(&r);
    if (rc) return rc;
    return (m->max == 0 || (max_batch && m->max > max_batch)) ? VP_ERR_COUNT : VP_OK;
}

void vp_enc_list_reply(vp_writer *w, uint32_t req, uint64_t next_cursor, uint64_t epoch, const vp_entity *e,
                       uint32_t n)
{
    vp_frame_begin(w, VP_ENTITY_LIST_REPLY, req);
    vp_put_u64(w, next_cursor);
    vp_put_u64(w, epoch);
    put_entities(w, e, n);
    vp_frame_end(w);
}

int vp_dec_list_reply(const uint8_t *p, size_t len, vp_list_reply *m)
{
    vp_reader r;
    vp_reader_init(&r, p, len);
    m->next_cursor = vp_get_u64(&r);
    m->epoch = vp_get_u64(&r);
    if (r.short_read) return VP_ERR_TRUNCATED;
    return get_entities(&r, 0, &m->batch);
}

int vp_entity_get(const vp_entity_batch *b, uint32_t i, vp_entity *out)
{
    if (i >= b->count) return VP_ERR_COUNT;
    entity_read(b->recs + (size_t)i * VP_ENTITY_REC_SIZE, out);
    return entity_check(out, NULL, 0);
}

void vp_enc_ids(vp_writer *w, uint16_t type, uint32_t req, const uint64_t *ids, uint32_t n)
{
    vp_frame_begin(w, type, req);
    vp_put_u32(w, n);
    for (uint32_t i = 0; i < n; i++) vp_put_u64(w, ids[i]);
    vp_frame_end(w);
}

int vp_dec_ids(const uint8_t *p, size_t len, uint32_t max_batch, vp_id_batch *m)
{
    vp_reader r;
    vp_reader_init(&r, p, len);
    m->count = vp_get_u32(&r);
    if (r.short_read) return VP_ERR_TRUNCATED;
    int rc = vp_take_array(&r, m->count, 8, max_batch, &m->ids);
    if (rc) return rc;
    rc = vp_reader_finish(&r);
    return rc == VP_ERR_TRAILING ? VP_ERR_COUNT : rc;
}

uint64_t vp_id_get(const vp_id_batch *b, uint32_t i)
{
    return i < b->count ? rd64(b->ids + (size_t)i * 8) : 0;
}

void vp_enc_add_reply(vp_writer *w, uint32_t req, uint64_t epoch, const uint32_t *handles, uint32_t n)
{
    vp_frame_begin(w, VP_ENTITY_ADD_REPLY, req);
    vp_put_u64(w, epoch);
    vp_put_u32(w, n);
    for (uint32_t i = 0; i < n; i++) vp_put_u32(w, handles[i]);
    vp_frame_end(w);
}

int vp_dec_add_reply(const uint8_t *p, size_t len, vp_add_reply *m)
{
    vp_reader r;
    vp_reader_init(&r, p, len);
    m->epoch = vp_get_u64(&r);
    m->count = vp_get_u32(&r);
    if (r.short_read) return VP_ERR_TRUNCATED;
    int rc = vp_take_array(&r, m->count, 4, 0, &m->handles);
    if (rc) return rc;
    rc = vp_reader_finish(&r);
    return rc == VP_ERR_TRAILING ? VP_ERR_COUNT : rc;
}

uint32_t vp_handle_get(const vp_add_reply *b, uint32_t i)
{
    return i < b->count ? rd32(b->handles + (size_t)i * 4) : 0;
}

/* ---- visibility ---------------------------------------------------------------- */

static void view_write(vp_writer *w, const vp_view *v)
{
    for (int k = 0; k < 3; k++) vp_put_f64(w, v->origin[k]);
    for (int k = 0; k < 16; k++) vp_put_f64(w, v->view_proj[k]);
    vp_put_u8(w, v->depth_mode);
    vp_put_u8(w, 0);
    vp_put_u16(w, v->viewport_w);
    vp_put_u16(w, v->viewport_h);
    vp_put_u16(w, 0);
}

void vp_enc_vis_query_sub(vp_writer *w, uint32_t req, uint8_t flags, float min_area, const vp_view *v, uint32_t n,
                          const uint16_t *subs, uint32_t nsub)
{
    if (subs) flags |= VP_Q_SUBLEVELS;
    vp_frame_begin(w, VP_VIS_QUERY, req);
    vp_put_u8(w, (uint8_t)n);
    vp_put_u8(w, flags);
    vp_put_u16(w, 0);
    vp_put_f32(w, min_area);
    for (uint32_t i = 0; i < n; i++) view_write(w, &v[i]);
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

static void view_read(const uint8_t *p, vp_view *v)
{
    for (int k = 0; k < 3; k++) v->origin[k] = rdf64(p + 8 * k);
    for (int k = 0; k < 16; k++) v->view_proj[k] = rdf64(p + 24 + 8 * k);
    v->depth_mode = p[152];
    v->viewport_w = rd16(p + 154);
    v->viewport_h = rd16(p + 156);
}

static int view_check(const vp_view *v);

/* A view from the wire: read, pads zero, fields checked. */
static int view_take(const uint8_t *p, vp_view *v)
{
    view_read(p, v);
    if (p[153] || rd16(p + 158)) return VP_ERR_INVALID;
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

static int view_check(const vp_view *v)
{
    if (!vp_finite_n(v->origin, 3) || !vp_finite_n(v->view_proj, 16)) return VP_ERR_NONFINITE;
    if (v->depth_mode > 2) return VP_ERR_INVALID;
    if ((v->viewport_w == 0) != (v->viewport_h == 0)) return VP_ERR_INVALID;
    return VP_OK;
}

int vp_dec_vis_query(const uint8_t *p, size_t len, vp_vis_query *m)
{
    vp_reader r;
    vp_reader_init(&r, p, len);
    m->view_count = vp_get_u8(&r);
    m->flags = vp_get_u8(&r);
    uint16_t pad = vp_get_u16(&r);
    m->min_area = vp_get_f32(&r);
    if (r.short_read) return VP_ERR_TRUNCATED;
    if (pad) return VP_ERR_INVALID;
    if (m->view_count == 0 || m->view_count > VP_MAX_VIEWS) return VP_ERR_COUNT;
    if (!isfinite(m->min_area)) return VP_ERR_NONFINITE;
    if (m->min_area < 0) return VP_ERR_INVALID;
    if ((m->flags & VP_Q_STATIC_ONLY) && (m->flags & VP_Q_DYNAMIC_ONLY)) return VP_ERR_INVALID;
    int rc = vp_take_array(&r, m->view_count, VP_VIEW_SIZE, 0, &m->views);
    if (rc) return rc;
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

size_t vp_size_vis_result(uint32_t n)
{
    return VP_HEADER_SIZE + 20 + 4 * VP_STAGES + (size_t)n * VP_VIS_REC_SIZE;
}

void vp_enc_vis_result_begin(vp_writer *w, uint32_t req, const vp_vis_result *m)
{
    vp_frame_begin(w, VP_VIS_RESULT, req);
    vp_put_u64(w, m->epoch);
    vp_put_u32(w, m->tested);
    vp_put_u32(w, m->visible);
    for (uint32_t i = 0; i < VP_STAGES; i++) vp_put_u32(w, m->stage_ns[i]);
    vp_put_u32(w, m->count);
}

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
    m->epoch = vp_get_u64(&r);
    m->tested = vp_get_u32(&r);
    m->visible = vp_get_u32(&r);
    for (uint32_t i = 0; i < VP_STAGES; i++) m->stage_ns[i] = vp_get_u32(&r);
    m->count = vp_get_u32(&r);
    if (r.short_read) return VP_ERR_TRUNCATED;
    int rc = vp_take_array(&r, m->count, VP_VIS_REC_SIZE, 0, &m->recs);
    if (rc) return rc;
    rc = vp_reader_finish(&r);
    return rc == VP_ERR_TRAILING ? VP_ERR_COUNT : rc;
}

void vp_vis_rec_get(const vp_vis_result *r, uint32_t i, vp_vis_rec *out)
{
    if (i >= r->count) {
        memset(out, 0, sizeof *out);
        return;
    }
    const uint8_t *p = r->recs + (size_t)i * VP_VIS_REC_SIZE;
    out->id = rd64(p);
    out->handle = rd32(p + 8);
    out->view_mask = rd32(p + 12);
    out->class_id = rd16(p + 16);
    out->sublevel = rd16(p + 18);
    out->area = rdf32(p + 20);
}

/* ---- meshes, occluders, lights ---------------------------------------------------- */

void vp_enc_mesh(vp_writer *w, uint32_t req, uint16_t class_id, const float *pos, const float *nrm, uint32_t nv,
                 const uint32_t *idx, uint32_t ni)
{
    vp_frame_begin(w, VP_MESH_PUT, req);
    vp_put_u16(w, class_id);
    vp_put_u16(w, 0);
    vp_put_u32(w, nv);
    vp_put_u32(w, ni);
    for (uint32_t i = 0; i < 3 * nv; i++) vp_put_f32(w, pos[i]);
    for (uint32_t i = 0; i < 3 * nv; i++) vp_put_f32(w, nrm[i]);
    for (uint32_t i = 0; i < ni; i++) vp_put_u32(w, idx[i]);
    vp_frame_end(w);
}

int vp_dec_mesh(const uint8_t *p, size_t len, uint32_t max_batch, vp_mesh *m)
{
    vp_reader r;
    vp_reader_init(&r, p, len);
    m->class_id = vp_get_u16(&r);
    uint16_t pad = vp_get_u16(&r);
    m->vertex_count = vp_get_u32(&r);
    m->index_count = vp_get_u32(&r);
    if (r.short_read) return VP_ERR_TRUNCATED;
    if (pad) return VP_ERR_INVALID;
    if (m->index_count % 3) return VP_ERR_COUNT;
    int rc;
    if ((rc = vp_take_array(&r, m->vertex_count, 12, max_batch, &m->positions)) ||
        (rc = vp_take_array(&r, m->vertex_count, 12, max_batch, &m->normals)) ||
        (rc = vp_take_array(&r, m->index_count, 4,
                         max_batch ? (uint32_t)(max_batch > UINT32_MAX / 3 ? UINT32_MAX : 3 * max_batch) : 0,
                         &m->indices)))
        return rc;
    if ((rc = vp_reader_finish(&r))) return rc == VP_ERR_TRAILING ? VP_ERR_COUNT : rc;
    for (uint32_t i = 0; i < 3 * m->vertex_count; i++) {
        float f[2] = {rdf32(m->positions + 4 * (size_t)i), rdf32(m->normals + 4 * (size_t)i)};
        if (!vp_finite_nf(f, 2)) return VP_ERR_NONFINITE;
    }
    for (uint32_t i = 0; i < m->index_count; i++)
        if (rd32(m->indices + 4 * (size_t)i) >= m->vertex_count) return VP_ERR_INVALID;
    return VP_OK;
}

void vp_enc_occluder(vp_writer *w, uint32_t req, uint64_t id, const double origin[3], const float *verts,
                     uint32_t ntris)
{
    vp_frame_begin(w, VP_OCCLUDER_PUT, req);
    vp_put_u64(w, id);
    for (int k = 0; k < 3; k++) vp_put_f64(w, origin[k]);
    vp_put_u32(w, ntris);
    for (uint32_t i = 0; i < 9 * ntris; i++) vp_put_f32(w, verts[i]);
    vp_frame_end(w);
}

int vp_dec_occluder(const uint8_t *p, size_t len, uint32_t max_batch, vp_occluder *m)
{
    vp_reader r;
    vp_reader_init(&r, p, len);
    m->id = vp_get_u64(&r);
    for (int k = 0; k < 3; k++) m->origin[k] = vp_get_f64(&r);
    m->tri_count = vp_get_u32(&r);
    if (r.short_read) return VP_ERR_TRUNCATED;
    if (!vp_finite_n(m->origin, 3)) return VP_ERR_NONFINITE;
    int rc = vp_take_array(&r, m->tri_count, 36, max_batch, &m->verts);
    if (rc) return rc;
    if ((rc = vp_reader_finish(&r))) return rc == VP_ERR_TRAILING ? VP_ERR_COUNT : rc;
    for (uint32_t i = 0; i < 9 * m->tri_count; i++) {
        float f = rdf32(m->verts + 4 * (size_t)i);
        if (!isfinite(f)) return VP_ERR_NONFINITE;
    }
    return VP_OK;
}

void vp_enc_lights(vp_writer *w, uint32_t req, const vp_light *l, uint32_t n)
{
    vp_frame_begin(w, VP_LIGHT_PUT, req);
    vp_put_u32(w, n);
    for (uint32_t i = 0; i < n; i++) {
        vp_put_u64(w, l[i].id);
        vp_put_u8(w, l[i].kind);
        vp_put_u8(w, 0);
        vp_put_u16(w, 0);
        vp_put_f32(w, l[i].intensity);
        for (int k = 0; k < 3; k++) vp_put_f64(w, l[i].pos[k]);
        for (int k = 0; k < 3; k++) vp_put_f32(w, l[i].dir[k]);
        for (int k = 0; k < 3; k++) vp_put_f32(w, l[i].color[k]);
        vp_put_f32(w, l[i].range);
        vp_put_f32(w, l[i].inner_cos);
        vp_put_f32(w, l[i].outer_cos);
        vp_put_u32(w, 0);
    }
    vp_frame_end(w);
}

static void light_read(const uint8_t *p, vp_light *l)
{
    l->id = rd64(p);
    l->kind = p[8];
    l->intensity = rdf32(p + 12);
    for (int k = 0; k < 3; k++) l->pos[k] = rdf64(p + 16 + 8 * k);
    for (int k = 0; k < 3; k++) l->dir[k] = rdf32(p + 40 + 4 * k);
    for (int k = 0; k < 3; k++) l->color[k] = rdf32(p + 52 + 4 * k);
    l->range = rdf32(p + 64);
    l->inner_cos = rdf32(p + 68);
    l->outer_cos = rdf32(p + 72);
}

/* A light record's own checks, the field and cause in why (may be NULL).
 * What a renderer can draw (position, range, colour and direction bounds)
 * is the culling module's cull_light_validate, which the daemon runs too. */
static int light_check(const vp_light *l, char *why, size_t whylen)
{
    static const char *const pname[3] = {"position x", "position y", "position z"};
    const struct { const char *name; float v; } f[] = {
        {"intensity", l->intensity}, {"direction x", l->dir[0]}, {"direction y", l->dir[1]},
        {"direction z", l->dir[2]},  {"colour r", l->color[0]},  {"colour g", l->color[1]},
        {"colour b", l->color[2]},   {"range", l->range},        {"inner cosine", l->inner_cos},
        {"outer cosine", l->outer_cos}};
    for (int k = 0; k < 3; k++)
        if (!isfinite(l->pos[k]))
            return vp_errf(why, whylen, VP_ERR_NONFINITE, "%s is %g: NaN or infinite", pname[k], l->pos[k]);
    for (size_t k = 0; k < sizeof f / sizeof f[0]; k++)
        if (!isfinite(f[k].v))
            return vp_errf(why, whylen, VP_ERR_NONFINITE, "%s is %g: NaN or infinite", f[k].name, (double)f[k].v);
    if (l->kind > VP_LIGHT_SPOT)
        return vp_errf(why, whylen, VP_ERR_INVALID, "kind %u is neither 0 (point) nor 1 (spot)", l->kind);
    if (!(l->range > 0)) return vp_errf(why, whylen, VP_ERR_INVALID, "range %g is not > 0", (double)l->range);
    if (l->intensity < 0)
        return vp_errf(why, whylen, VP_ERR_INVALID, "intensity %g is negative", (double)l->intensity);
    for (int k = 0; k < 3; k++)
        if (l->color[k] < 0)
            return vp_errf(why, whylen, VP_ERR_INVALID, "%s %g is negative", f[4 + k].name, (double)l->color[k]);
    if (l->kind == VP_LIGHT_SPOT && !(l->outer_cos <= l->inner_cos && l->outer_cos >= -1 && l->inner_cos <= 1))
        return vp_errf(why, whylen, VP_ERR_INVALID, "spot cone: need -1 <= outer cosine (%g) <= inner cosine (%g) <= 1",
                       (double)l->outer_cos, (double)l->inner_cos);
    return VP_OK;
}

int vp_light_rec_check(const uint8_t *recs, uint32_t n, uint32_t i, char *why, size_t whylen)
{
    if (i >= n) return VP_ERR_COUNT;
    vp_light l;
    light_read(recs + (size_t)i * VP_LIGHT_SIZE, &l);
    return light_check(&l, why, whylen);
}

int vp_dec_lights(const uint8_t *p, size_t len, uint32_t max_batch, const uint8_t **recs, uint32_t *n)
{
    vp_reader r;
    vp_reader_init(&r, p, len);
    *n = vp_get_u32(&r);
    if (r.short_read) return VP_ERR_TRUNCATED;
    int rc = vp_take_array(&r, *n, VP_LIGHT_SIZE, max_batch, recs);
    if (rc) return rc;
    if ((rc = vp_reader_finish(&r))) return rc == VP_ERR_TRAILING ? VP_ERR_COUNT : rc;
    for (uint32_t i = 0; i < *n; i++) {
        vp_light l;
        light_read(*recs + (size_t)i * VP_LIGHT_SIZE, &l);
        if ((rc = light_check(&l, NULL, 0))) return rc;
    }
    return VP_OK;
}

int vp_light_get(const uint8_t *recs, uint32_t n, uint32_t i, vp_light *out)
{
    if (i >= n) return VP_ERR_COUNT;
    light_read(recs + (size_t)i * VP_LIGHT_SIZE, out);
    return light_check(out, NULL, 0);
}

/* ---- sub-level names ------------------------------------------------------------ */

/* A name on the wire: 1..255 bytes, no control bytes. */
static int name_take(vp_reader *r, uint8_t *len, const uint8_t **name)
{
    *len = vp_get_u8(r);
    *name = vp_get_bytes(r, *len);
    if (r->short_read) return VP_ERR_TRUNCATED;
    if (*len == 0) return VP_ERR_INVALID;
    for (uint8_t k = 0; k < *len; k++)
        if ((*name)[k] < 32 || (*name)[k] == 127) return VP_ERR_INVALID;
    return VP_OK;
}

static void name_put(vp_writer *w, const uint8_t *name, size_t l)
{
    if (l > VP_MAX_NAME) l = VP_MAX_NAME;
    vp_put_u8(w, (uint8_t)l);
    vp_put_bytes(w, name, l);
}


void vp_enc_names(vp_writer *w, uint16_t type, uint32_t req, const char *const *names, const uint16_t *ids,
                  uint32_t n)
{
    vp_frame_begin(w, type, req);
    vp_put_u32(w, n);
    for (uint32_t i = 0; i < n; i++) {
        if (ids) vp_put_u16(w, ids[i]);
        name_put(w, (const uint8_t *)names[i], strlen(names[i]));
    }
    vp_frame_end(w);
}

int vp_dec_names(const uint8_t *p, size_t len, bool with_ids, vp_name_list *m)
{
    vp_reader r;
    vp_reader_init(&r, p, len);
    m->count = vp_get_u32(&r);
    m->with_ids = with_ids;
    if (r.short_read) return VP_ERR_TRUNCATED;
    if (m->count > VP_MAX_SUBLEVELS) return VP_ERR_COUNT;
    m->p = p + r.pos;
    m->len = len - r.pos;
    for (uint32_t i = 0; i < m->count; i++) {
        if (with_ids) (void)vp_get_u16(&r);
        uint8_t l;
        const uint8_t *name;
        int rc = name_take(&r, &l, &name);
        if (rc) return rc == VP_ERR_TRUNCATED ? VP_ERR_COUNT : rc;
    }
    int rc = vp_reader_finish(&r);
    return rc == VP_ERR_TRAILING ? VP_ERR_COUNT : rc;
}

bool vp_name_next(const vp_name_list *l, size_t *pos, vp_name *out)
{
    if (*pos >= l->len) return false;
    const uint8_t *p = l->p + *pos;
    out->id = 0;
    if (l->with_ids) {
        out->id = rd16(p);
        p += 2;
    }
    out->len = p[0];
    out->name = p + 1;
    *pos += (l->with_ids ? 2u : 0u) + 1u + out->len;
    return true;
}

void vp_enc_sublevel_ids(vp_writer *w, uint32_t req, const uint16_t *ids, uint32_t n)
{
    vp_frame_begin(w, VP_SUBLEVEL_IDS, req);
    vp_put_u32(w, n);
    for (uint32_t i = 0; i < n; i++) vp_put_u16(w, ids[i]);
    vp_frame_end(w);
}

int vp_dec_sublevel_ids(const uint8_t *p, size_t len, uint32_t *n, const uint8_t **ids)
{
    vp_reader r;
    vp_reader_init(&r, p, len);
    *n = vp_get_u32(&r);
    if (r.short_read) return VP_ERR_TRUNCATED;
    int rc = vp_take_array(&r, *n, 2, VP_MAX_SUBLEVELS, ids);
    if (rc) return rc;
    rc = vp_reader_finish(&r);
    return rc == VP_ERR_TRAILING ? VP_ERR_COUNT : rc;
}

uint16_t vp_sublevel_id_get(const uint8_t *ids, uint32_t n, uint32_t i)
{
    return i < n ? rd16(ids + 2 * (size_t)i) : 0;
}

/* ---- sub-level loads ----------------------------------------------------------- */

void vp_enc_sublevel_begin(vp_writer *w, uint32_t req, const vp_sublevel_begin *m)
{
    vp_frame_begin(w, VP_SUBLEVEL_BEGIN, req);
    vp_put_u16(w, m->classes);
    name_put(w, m->name, m->name_len);
    vp_frame_end(w);
}

int vp_dec_sublevel_begin(const uint8_t *p, size_t len, vp_sublevel_begin *m)
{
    vp_reader r;
    vp_reader_init(&r, p, len);
    m->classes = vp_get_u16(&r);
    int rc = name_take(&r, &m->name_len, &m->name);
    if (rc) return rc;
    if (m->classes > 4096) return VP_ERR_LIMIT;
    return vp_reader_finish(&r);
}

void vp_enc_sublevel_begun(vp_writer *w, uint32_t req, const vp_sublevel_begun *m)
{
    vp_frame_begin(w, VP_SUBLEVEL_BEGUN, req);
    vp_put_u16(w, m->id);
    vp_put_u16(w, m->class_base);
    vp_put_u32(w, 0);
    vp_put_u64(w, m->epoch);
    vp_frame_end(w);
}

int vp_dec_sublevel_begun(const uint8_t *p, size_t len, vp_sublevel_begun *m)
{
    vp_reader r;
    vp_reader_init(&r, p, len);
    m->id = vp_get_u16(&r);
    m->class_base = vp_get_u16(&r);
    uint32_t pad = vp_get_u32(&r);
    m->epoch = vp_get_u64(&r);
    int rc = vp_reader_finish(&r);
    if (rc) return rc;
    return pad ? VP_ERR_INVALID : VP_OK;
}

void vp_enc_sublevel_name(vp_writer *w, uint16_t type, uint32_t req, const char *name)
{
    vp_frame_begin(w, type, req);
    name_put(w, (const uint8_t *)name, strlen(name));
    vp_frame_end(w);
}

int vp_dec_sublevel_name(const uint8_t *p, size_t len, vp_name *m)
{
    vp_reader r;
    vp_reader_init(&r, p, len);
    m->id = 0;
    int rc = name_take(&r, &m->len, &m->name);
    return rc ? rc : vp_reader_finish(&r);
}

void vp_enc_sublevel_infos_begin(vp_writer *w, uint32_t req, uint64_t epoch, uint32_t n)
{
    vp_frame_begin(w, VP_SUBLEVEL_INFO_REPLY, req);
    vp_put_u64(w, epoch);
    vp_put_u32(w, n);
}

void vp_put_sublevel_info(vp_writer *w, const vp_sublevel_info *m)
{
    vp_put_u16(w, m->id);
    vp_put_u8(w, m->state);
    vp_put_u32(w, m->entities);
    vp_put_u32(w, m->occluders);
    vp_put_u32(w, m->lights);
    vp_put_u16(w, m->class_base);
    vp_put_u16(w, m->classes);
    name_put(w, m->name, m->name_len);
}

int vp_dec_sublevel_infos(const uint8_t *p, size_t len, vp_sublevel_infos *m)
{
    vp_reader r;
    vp_reader_init(&r, p, len);
    m->epoch = vp_get_u64(&r);
    m->count = vp_get_u32(&r);
    if (r.short_read) return VP_ERR_TRUNCATED;
    if (m->count > VP_MAX_SUBLEVELS) return VP_ERR_COUNT;
    m->p = p + r.pos;
    m->len = len - r.pos;
    for (uint32_t i = 0; i < m->count; i++) {
        const uint8_t *e = vp_get_bytes(&r, VP_SUBLEVEL_INFO_SIZE - 1); /* all but the name */
        uint8_t l;
        const uint8_t *name;
        if (r.short_read) return VP_ERR_COUNT;
        if (e[2] > VP_SL_UNLOADING) return VP_ERR_INVALID;
        int rc = name_take(&r, &l, &name);
        if (rc) return rc == VP_ERR_TRUNCATED ? VP_ERR_COUNT : rc;
    }
    int rc = vp_reader_finish(&r);
    return rc == VP_ERR_TRAILING ? VP_ERR_COUNT : rc;
}

bool vp_sublevel_info_next(const vp_sublevel_infos *l, size_t *pos, vp_sublevel_info *out)
{
    if (*pos >= l->len) return false;
    const uint8_t *p = l->p + *pos;
    out->id = rd16(p);
    out->state = p[2];
    out->entities = rd32(p + 3);
    out->occluders = rd32(p + 7);
    out->lights = rd32(p + 11);
    out->class_base = rd16(p + 15);
    out->classes = rd16(p + 17);
    out->name_len = p[19];
    out->name = p + 20;
    *pos += VP_SUBLEVEL_INFO_SIZE + out->name_len;
    return true;
}

/* ---- RENDER / FRAME ------------------------------------------------------------- */

static void render_write(vp_writer *w, const vp_render *m)
{
    view_write(w, &m->view);
    vp_put_u8(w, m->format);
    vp_put_u8(w, m->quality);
    vp_put_u8(w, m->flags);
    vp_put_u8(w, m->renderer);
    vp_put_f32(w, m->exposure_ev);
}

void vp_enc_render(vp_writer *w, uint32_t req, const vp_render *m)
{
    vp_frame_begin(w, VP_RENDER, req);
    render_write(w, m);
    vp_frame_end(w);
}

/* The RENDER fields at p (VP_RENDER_SIZE bytes, already length-checked). */
static int render_read(const uint8_t *p, vp_render *m)
{
    const uint8_t *q = p + VP_VIEW_SIZE;
    m->format = q[0];
    m->quality = q[1];
    m->flags = q[2];
    m->renderer = q[3];
    m->exposure_ev = rdf32(q + 4);
    if (m->renderer > VP_RENDERER_GL) return VP_ERR_INVALID;
    if (m->format > VP_FRAME_JPEG || (m->flags & ~VP_RENDER_NO_OCCLUSION)) return VP_ERR_INVALID;
    if (m->format == VP_FRAME_JPEG && (m->quality < 1 || m->quality > 100)) return VP_ERR_INVALID;
    if (m->format == VP_FRAME_RAW && m->quality) return VP_ERR_INVALID;
    if (!isfinite(m->exposure_ev)) return VP_ERR_NONFINITE;
    if (fabsf(m->exposure_ev) > 64) return VP_ERR_INVALID;
    return picture_view_take(p, &m->view);
}

int vp_dec_render(const uint8_t *p, size_t len, vp_render *m)
{
    if (len < VP_RENDER_SIZE) return VP_ERR_TRUNCATED;
    if (len > VP_RENDER_SIZE) return VP_ERR_TRAILING;
    return render_read(p, m);
}

void vp_enc_light_query(vp_writer *w, uint32_t req, const vp_light_query *m)
{
    vp_frame_begin(w, VP_LIGHT_QUERY, req);
    view_write(w, &m->view);
    vp_put_u8(w, m->flags);
    vp_put_u8(w, 0);
    vp_put_u16(w, 0);
    vp_frame_end(w);
}

int vp_dec_light_query(const uint8_t *p, size_t len, vp_light_query *m)
{
    if (len < VP_LIGHT_QUERY_SIZE) return VP_ERR_TRUNCATED;
    if (len > VP_LIGHT_QUERY_SIZE) return VP_ERR_TRAILING;
    const uint8_t *q = p + VP_VIEW_SIZE;
    m->flags = q[0];
    if ((m->flags & ~VP_LQ_NO_DEPTH) || q[1] || rd16(q + 2)) return VP_ERR_INVALID;
    return picture_view_take(p, &m->view);
}

size_t vp_size_light_tiles(uint32_t tiles, uint32_t count)
{
    return VP_HEADER_SIZE + VP_LIGHT_TILES_HEADER + 4 * ((size_t)tiles + 1) + 8 * (size_t)count;
}

void vp_enc_light_tiles_begin(vp_writer *w, uint32_t req, const vp_light_tiles *m)
{
    vp_frame_begin(w, VP_LIGHT_TILES, req);
    vp_put_u64(w, m->epoch);
    vp_put_u16(w, m->tiles_x);
    vp_put_u16(w, m->tiles_y);
    vp_put_u16(w, m->tile);
    vp_put_u8(w, m->flags);
    vp_put_u8(w, 0);
    vp_put_u32(w, m->in_view);
    vp_put_u32(w, m->max_per_tile);
    vp_put_u32(w, m->count);
    vp_put_u32(w, m->ns);
}

int vp_dec_light_tiles(const uint8_t *p, size_t len, vp_light_tiles *m)
{
    if (len < VP_LIGHT_TILES_HEADER) return VP_ERR_TRUNCATED;
    m->epoch = rd64(p);
    m->tiles_x = rd16(p + 8);
    m->tiles_y = rd16(p + 10);
    m->tile = rd16(p + 12);
    m->flags = p[14];
    m->in_view = rd32(p + 16);
    m->max_per_tile = rd32(p + 20);
    m->count = rd32(p + 24);
    m->ns = rd32(p + 28);
    if (p[15]) return VP_ERR_INVALID;
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

void vp_enc_frame_sub(vp_writer *w, uint32_t req, const vp_frame_sub *m)
{
    vp_frame_begin(w, VP_FRAME_SUBSCRIBE, req);
    render_write(w, &m->r);
    vp_put_u16(w, m->max_fps);
    vp_put_u16(w, m->view_seq);
    vp_frame_end(w);
}

int vp_dec_frame_sub(const uint8_t *p, size_t len, vp_frame_sub *m)
{
    if (len < VP_FRAME_SUB_SIZE) return VP_ERR_TRUNCATED;
    if (len > VP_FRAME_SUB_SIZE) return VP_ERR_TRAILING;
    int rc = render_read(p, &m->r);
    if (rc) return rc;
    m->max_fps = rd16(p + VP_RENDER_SIZE);
    m->view_seq = rd16(p + VP_RENDER_SIZE + 2);
    if (m->max_fps < 1 || m->max_fps > VP_FRAME_SUB_MAX_FPS) return VP_ERR_INVALID;
    return VP_OK;
}

size_t vp_size_frame(uint32_t data_len)
{
    return VP_HEADER_SIZE + VP_FRAME_HEADER + (size_t)data_len;
}

void vp_enc_frame(vp_writer *w, uint32_t req, const vp_frame *m)
{
    vp_frame_begin(w, VP_FRAME, req);
    vp_put_u64(w, m->epoch);
    vp_put_u16(w, m->width);
    vp_put_u16(w, m->height);
    vp_put_u8(w, m->format);
    vp_put_u8(w, 0);
    vp_put_u16(w, m->view_seq);
    vp_put_u32(w, m->visible);
    vp_put_u32(w, m->render_ns);
    vp_put_u32(w, m->encode_ns);
    vp_put_u32(w, m->data_len);
    if (m->data) vp_put_bytes(w, m->data, m->data_len);
    else if (w->cap - w->len >= m->data_len) w->len += m->data_len; /* written in place */
    else w->overflow = true;
    vp_frame_end(w);
}

int vp_dec_frame(const uint8_t *p, size_t len, vp_frame *m)
{
    if (len < VP_FRAME_HEADER) return VP_ERR_TRUNCATED;
    m->epoch = rd64(p);
    m->width = rd16(p + 8);
    m->height = rd16(p + 10);
    m->format = p[12];
    m->view_seq = rd16(p + 14);
    m->visible = rd32(p + 16);
    m->render_ns = rd32(p + 20);
    m->encode_ns = rd32(p + 24);
    m->data_len = rd32(p + 28);
    m->data = p + VP_FRAME_HEADER;
    if (p[13] || m->format > VP_FRAME_JPEG || !m->width || !m->height) return VP_ERR_INVALID;
    if (len - VP_FRAME_HEADER < m->data_len) return VP_ERR_TRUNCATED;
    if (len - VP_FRAME_HEADER > m->data_len) return VP_ERR_TRAILING;
    if (m->format == VP_FRAME_RAW && (uint64_t)m->data_len != (uint64_t)m->width * m->height * 20) return VP_ERR_COUNT;
    return VP_OK;
}

/* ---- marks -------------------------------------------------------------------------- */

static void mark_write(vp_writer *w, const vp_mark *m)
{
    for (int k = 0; k < 3; k++) vp_put_f64(w, m->pos[k]);
    vp_put_u64(w, m->entity);
    vp_put_u8(w, m->kind);
    vp_put_u8(w, 0);
    vp_put_u16(w, 0);
    vp_put_u32(w, m->ttl_ms);
}

static int mark_read(vp_reader *r, vp_mark *m)
{
    for (int k = 0; k < 3; k++) m->pos[k] = vp_get_f64(r);
    m->entity = vp_get_u64(r);
    m->kind = vp_get_u8(r);
    uint8_t pad8 = vp_get_u8(r);
    uint16_t pad16 = vp_get_u16(r);
    m->ttl_ms = vp_get_u32(r);
    int rc = vp_reader_finish(r);
    if (rc) return rc;
    if (pad8 || pad16) return VP_ERR_INVALID;
    if (!vp_finite_n(m->pos, 3)) return VP_ERR_NONFINITE;
    for (int k = 0; k < 3; k++)
        if (fabs(m->pos[k]) > 1e12) return VP_ERR_INVALID;
    if (m->ttl_ms < 1 || m->ttl_ms > 600000) return VP_ERR_INVALID;
    return VP_OK;
}

void vp_enc_mark(vp_writer *w, uint32_t req, const vp_mark *m)
{
    vp_frame_begin(w, VP_MARK, req);
    mark_write(w, m);
    vp_frame_end(w);
}

int vp_dec_mark(const uint8_t *p, size_t len, vp_mark *m)
{
    vp_reader r;
    vp_reader_init(&r, p, len);
    return mark_read(&r, m);
}

void vp_enc_marked(vp_writer *w, const vp_marked *m)
{
    vp_frame_begin(w, VP_MARKED, 0);
    vp_put_u32(w, m->client_id);
    vp_put_u32(w, 0);
    mark_write(w, &m->m);
    vp_frame_end(w);
}

int vp_dec_marked(const uint8_t *p, size_t len, vp_marked *m)
{
    vp_reader r;
    vp_reader_init(&r, p, len);
    m->client_id = vp_get_u32(&r);
    uint32_t pad = vp_get_u32(&r);
    int rc = mark_read(&r, &m->m);
    if (rc) return rc;
    return pad ? VP_ERR_INVALID : VP_OK;
}

/* ---- destruction --------------------------------------------------------------- */

void vp_enc_destroy(vp_writer *w, uint32_t req, const vp_destroy *m)
{
    vp_frame_begin(w, VP_DESTROY, req);
    vp_put_u64(w, m->id);
    vp_put_u32(w, m->handle);
    vp_put_u8(w, m->debris);
    vp_put_u8(w, 0);
    vp_put_u16(w, 0);
    for (int k = 0; k < 3; k++) vp_put_f64(w, m->center[k]);
    vp_put_f64(w, m->radius);
    vp_frame_end(w);
}

int vp_dec_destroy(const uint8_t *p, size_t len, vp_destroy *m)
{
    vp_reader r;
    vp_reader_init(&r, p, len);
    m->id = vp_get_u64(&r);
    m->handle = vp_get_u32(&r);
    m->debris = vp_get_u8(&r);
    uint8_t pad8 = vp_get_u8(&r);
    uint16_t pad16 = vp_get_u16(&r);
    for (int k = 0; k < 3; k++) m->center[k] = vp_get_f64(&r);
    m->radius = vp_get_f64(&r);
    int rc = vp_reader_finish(&r);
    if (rc) return rc;
    if (pad8 || pad16) return VP_ERR_INVALID;
    if (!vp_finite_n(m->center, 3) || !isfinite(m->radius)) return VP_ERR_NONFINITE;
    if (!(m->radius > 0) || m->debris > VP_MAX_DEBRIS) return VP_ERR_INVALID;
    return VP_OK;
}

void vp_enc_destroyed(vp_writer *w, uint32_t req, const vp_destroyed *m)
{
    vp_frame_begin(w, VP_DESTROYED, req);
    vp_put_u64(w, m->epoch);
    vp_put_u32(w, m->spheres);
    vp_put_u32(w, m->occluder_tris);
    vp_put_u32(w, m->debris);
    vp_put_u32(w, m->cut_us);
    vp_frame_end(w);
}

int vp_dec_destroyed(const uint8_t *p, size_t len, vp_destroyed *m)
{
    vp_reader r;
    vp_reader_init(&r, p, len);
    m->epoch = vp_get_u64(&r);
    m->spheres = vp_get_u32(&r);
    m->occluder_tris = vp_get_u32(&r);
    m->debris = vp_get_u32(&r);
    m->cut_us = vp_get_u32(&r);
    return vp_reader_finish(&r);
}
