/*
 * fuzz_protocol.c — libFuzzer target for the wire-protocol decoders.
 *
 * The input is a byte stream as a server or client would read it:
 *   1. vp_frame_check on the raw input under a few payload limits, with the
 *      framing properties checked (sizes, need-more vs. error, limits);
 *   2. the input is cut into frames; each complete frame's payload goes to
 *      the decoder for its header type (an unknown type picks a decoder from
 *      the type bits, so every decoder sees every shape of payload);
 *      batch decoders run with no limit and with the request id as the limit;
 *   3. every record of an accepted batch is read with its getter, and the
 *      getters must accept what the decoder accepted;
 *   4. accepted messages with a plain encoder are re-encoded and must decode
 *      to the same values with a payload of the same length (round trip).
 * A broken property calls abort(), so both the fuzzer and the replay driver
 * (replay_main.c) report it like a sanitizer crash.
 */
#include "protocol.h"

#define FUZZ_NAME "fuzz_protocol"
#include "fuzz_check.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Frames per input; keeps a pathological stream of empty frames bounded. */
#define MAX_FRAMES 4096u

/* ---- small helpers -------------------------------------------------------------- */

static bool same_f64(double a, double b) { return memcmp(&a, &b, sizeof a) == 0; }
static bool same_f32(float a, float b) { return memcmp(&a, &b, sizeof a) == 0; }

/* Every code a decoder returns is one of the table's. */
static void check_code(int rc)
{
    CHECK(rc <= VP_OK && rc >= VP_ERR_INTERNAL);
    CHECK(strcmp(vp_strerror(rc), "unknown error") != 0);
}

/* Frames the encoded bytes and returns the payload; its type and length must
 * match what was decoded. */
static const uint8_t *enc_payload(fuzz_wbuf *b, uint16_t type, size_t want_len)
{
    size_t len;
    const uint8_t *p = fuzz_wframe(b, type, &len);
    CHECK(len == want_len);
    return p;
}

static bool same_entity(const vp_entity *a, const vp_entity *b) { return fuzz_same_entity(a, b, same_f64); }

static bool same_view(const vp_view *a, const vp_view *b)
{
    for (int k = 0; k < 3; k++)
        if (!same_f64(a->origin[k], b->origin[k])) return false;
    for (int k = 0; k < 16; k++)
        if (!same_f64(a->view_proj[k], b->view_proj[k])) return false;
    return a->depth_mode == b->depth_mode && a->viewport_w == b->viewport_w && a->viewport_h == b->viewport_h;
}

static bool same_light(const vp_light *a, const vp_light *b)
{
    if (a->id != b->id || a->kind != b->kind) return false;
    for (int k = 0; k < 3; k++)
        if (!same_f64(a->pos[k], b->pos[k]) || !same_f32(a->dir[k], b->dir[k]) ||
            !same_f32(a->color[k], b->color[k]))
            return false;
    return same_f32(a->intensity, b->intensity) && same_f32(a->range, b->range) &&
           same_f32(a->inner_cos, b->inner_cos) && same_f32(a->outer_cos, b->outer_cos);
}

/* Reads every record of an accepted entity batch; returns them (caller frees). */
static vp_entity *read_entities(const vp_entity_batch *b)
{
    vp_entity *e = malloc(((size_t)b->count ? b->count : 1) * sizeof *e);
    CHECK(e != NULL);
    for (uint32_t i = 0; i < b->count; i++) CHECK(vp_entity_get(b, i, &e[i]) == VP_OK);
    vp_entity past;
    CHECK(vp_entity_get(b, b->count, &past) == VP_ERR_COUNT);
    return e;
}

#include "fuzz_scene.h"

/* ---- one decoder per message kind --------------------------------------------------- */

static void fuzz_hello(const uint8_t *p, size_t len)
{
    vp_hello m;
    int rc = vp_dec_hello(p, len, &m);
    check_code(rc);
    if (rc) return;
    CHECK(len == 9u + m.token_len + m.name_len);
    fuzz_wbuf b;
    fuzz_wopen(&b, VP_HEADER_SIZE + len);
    vp_enc_hello(&b.w, 1, &m);
    const uint8_t *q = enc_payload(&b, VP_HELLO, len);
    vp_hello r;
    CHECK(vp_dec_hello(q, len, &r) == VP_OK);
    CHECK(r.magic == m.magic && r.version == m.version && r.role == m.role);
    CHECK(r.token_len == m.token_len && r.name_len == m.name_len);
    CHECK(memcmp(r.token, m.token, m.token_len) == 0 && memcmp(r.name, m.name, m.name_len) == 0);
    fuzz_wclose(&b);
}

static void fuzz_hello_ok(const uint8_t *p, size_t len)
{
    vp_hello_ok m;
    int rc = vp_dec_hello_ok(p, len, &m);
    check_code(rc);
    if (rc) return;
    fuzz_wbuf b;
    fuzz_wopen(&b, VP_HEADER_SIZE + len);
    vp_enc_hello_ok(&b.w, 2, &m);
    const uint8_t *q = enc_payload(&b, VP_HELLO_OK, len);
    vp_hello_ok r;
    CHECK(vp_dec_hello_ok(q, len, &r) == VP_OK);
    CHECK(r.version == m.version && r.role == m.role && r.max_payload == m.max_payload &&
          r.max_batch == m.max_batch && r.max_views == m.max_views && r.epoch == m.epoch &&
          r.client_id == m.client_id);
    fuzz_wclose(&b);
}

static void fuzz_error(const uint8_t *p, size_t len)
{
    vp_error m;
    int rc = vp_dec_error(p, len, &m);
    check_code(rc);
    if (rc) return;
    CHECK(m.msg_len <= VP_MAX_ERROR_MSG && len == 10u + m.msg_len);
    volatile uint8_t sink = 0;
    for (uint16_t i = 0; i < m.msg_len; i++) sink ^= m.msg[i];
    (void)sink;
    (void)vp_strerror(m.code);
}

static void fuzz_ping(const uint8_t *p, size_t len)
{
    const uint8_t *d = NULL;
    uint32_t n = 0;
    int rc = vp_dec_ping(p, len, &d, &n);
    check_code(rc);
    if (rc) return;
    CHECK(n == len && n <= VP_MAX_PING);
    if (n) CHECK(d == p);
}

static void fuzz_empty(const uint8_t *p, size_t len)
{
    int rc = vp_dec_empty(p, len);
    check_code(rc);
    CHECK((rc == VP_OK) == (len == 0));
}

static void fuzz_stats_reply(const uint8_t *p, size_t len)
{
    vp_stats_reply m;
    int rc = vp_dec_stats_reply(p, len, &m);
    check_code(rc);
    if (rc) return;
    fuzz_wbuf b;
    fuzz_wopen(&b, VP_HEADER_SIZE + len);
    vp_enc_stats_reply(&b.w, 3, &m);
    const uint8_t *q = enc_payload(&b, VP_STATS_REPLY, len);
    vp_stats_reply r;
    CHECK(vp_dec_stats_reply(q, len, &r) == VP_OK);
    CHECK(r.epoch == m.epoch && r.uptime_ms == m.uptime_ms && r.entities == m.entities &&
          r.static_entities == m.static_entities && r.dynamic_entities == m.dynamic_entities &&
          r.regions == m.regions && r.cells == m.cells && r.connections == m.connections &&
          r.meshes == m.meshes && r.occluders == m.occluders && r.lights == m.lights &&
          r.queries == m.queries && r.edits == m.edits && r.bytes_in == m.bytes_in &&
          r.bytes_out == m.bytes_out && r.errors == m.errors);
    CHECK(memcmp(q, p, len) == 0); /* no pad bytes: the bytes themselves round-trip */
    fuzz_wclose(&b);
}

static void fuzz_subscribe(const uint8_t *p, size_t len)
{
    uint32_t kinds;
    int rc = vp_dec_subscribe(p, len, &kinds);
    check_code(rc);
    if (rc) return;
    CHECK((kinds & ~VP_EVENT_ALL) == 0); /* MARKS since MARK/MARKED, SELECTION since SELECT */
    fuzz_wbuf b;
    fuzz_wopen(&b, VP_HEADER_SIZE + len);
    vp_enc_subscribe(&b.w, 4, kinds);
    const uint8_t *q = enc_payload(&b, VP_SUBSCRIBE, len);
    uint32_t r;
    CHECK(vp_dec_subscribe(q, len, &r) == VP_OK && r == kinds);
    fuzz_wclose(&b);
}

static void fuzz_event(const uint8_t *p, size_t len)
{
    vp_event m;
    int rc = vp_dec_event(p, len, &m);
    check_code(rc);
    if (rc) return;
    fuzz_wbuf b;
    fuzz_wopen(&b, VP_HEADER_SIZE + len);
    vp_enc_event(&b.w, &m);
    const uint8_t *q = enc_payload(&b, VP_EVENT, len);
    vp_event r;
    CHECK(vp_dec_event(q, len, &r) == VP_OK);
    CHECK(r.kind == m.kind && r.epoch == m.epoch && r.added == m.added && r.updated == m.updated &&
          r.removed == m.removed);
    fuzz_wclose(&b);
}

static void fuzz_ack(const uint8_t *p, size_t len)
{
    vp_ack m;
    int rc = vp_dec_ack(p, len, &m);
    check_code(rc);
    if (rc) return;
    fuzz_wbuf b;
    fuzz_wopen(&b, VP_HEADER_SIZE + len);
    vp_enc_ack(&b.w, 5, &m);
    const uint8_t *q = enc_payload(&b, VP_ACK, len);
    vp_ack r;
    CHECK(vp_dec_ack(q, len, &r) == VP_OK && r.epoch == m.epoch && r.count == m.count);
    CHECK(memcmp(q, p, len) == 0);
    fuzz_wclose(&b);
}

static int ent_check(const uint8_t *recs, uint32_t n, uint32_t i, char *why, size_t whylen)
{
    vp_entity_batch b = {.count = n, .recs = recs, .version = 2};
    return vp_entity_rec_check(&b, i, why, whylen);
}

static void fuzz_entities(const uint8_t *p, size_t len, uint16_t type, uint32_t limit)
{
    vp_entity_batch m;
    int rc = vp_dec_entities(p, len, 0, &m);
    check_code(rc);
    vp_entity_batch lim;
    int rcl = vp_dec_entities(p, len, limit, &lim);
    check_code(rcl);
    /* a limit can only turn an accept into COUNT, never the other way */
    if (rcl == VP_OK) CHECK(rc == VP_OK && (limit == 0 || lim.count <= limit));
    if (rc == VP_OK && rcl != VP_OK) CHECK(rcl == VP_ERR_COUNT && limit && m.count > limit);
    check_refusal(rc, p, len, VP_ENTITY_REC_SIZE, ent_check);
    if (rc) return;
    CHECK(len == 4 + (size_t)m.count * VP_ENTITY_REC_SIZE);
    vp_entity *e = read_entities(&m);
    fuzz_wbuf b;
    fuzz_wopen(&b, vp_size_entities(m.count));
    vp_enc_entities(&b.w, type, 6, e, m.count);
    const uint8_t *q = enc_payload(&b, type, len);
    vp_entity_batch r;
    CHECK(vp_dec_entities(q, len, 0, &r) == VP_OK && r.count == m.count);
    for (uint32_t i = 0; i < r.count; i++) {
        vp_entity x;
        CHECK(vp_entity_get(&r, i, &x) == VP_OK);
        CHECK(same_entity(&x, &e[i]));
    }
    fuzz_wclose(&b);
    free(e);
}

static void fuzz_ids(const uint8_t *p, size_t len, uint16_t type, uint32_t limit)
{
    vp_id_batch m;
    int rc = vp_dec_ids(p, len, 0, &m);
    check_code(rc);
    vp_id_batch lim;
    int rcl = vp_dec_ids(p, len, limit, &lim);
    check_code(rcl);
    if (rcl == VP_OK) CHECK(rc == VP_OK && (limit == 0 || lim.count <= limit));
    if (rc == VP_OK && rcl != VP_OK) CHECK(rcl == VP_ERR_COUNT && limit && m.count > limit);
    if (rc) return;
    CHECK(len == 4 + (size_t)m.count * 8);
    uint64_t *ids = malloc(((size_t)m.count ? m.count : 1) * sizeof *ids);
    CHECK(ids != NULL);
    for (uint32_t i = 0; i < m.count; i++) ids[i] = vp_id_get(&m, i);
    CHECK(vp_id_get(&m, m.count) == 0);
    fuzz_wbuf b;
    fuzz_wopen(&b, vp_size_ids(m.count));
    vp_enc_ids(&b.w, type, 7, ids, m.count);
    const uint8_t *q = enc_payload(&b, type, len);
    CHECK(memcmp(q, p, len) == 0);
    vp_id_batch r;
    CHECK(vp_dec_ids(q, len, 0, &r) == VP_OK && r.count == m.count);
    for (uint32_t i = 0; i < r.count; i++) CHECK(vp_id_get(&r, i) == ids[i]);
    fuzz_wclose(&b);
    free(ids);
}

static void fuzz_add_reply(const uint8_t *p, size_t len)
{
    vp_add_reply m;
    int rc = vp_dec_add_reply(p, len, &m);
    check_code(rc);
    if (rc) return;
    CHECK(len == 12 + (size_t)m.count * 4);
    uint32_t *h = malloc(((size_t)m.count ? m.count : 1) * sizeof *h);
    CHECK(h != NULL);
    for (uint32_t i = 0; i < m.count; i++) h[i] = vp_handle_get(&m, i);
    CHECK(vp_handle_get(&m, m.count) == 0);
    fuzz_wbuf b;
    fuzz_wopen(&b, VP_HEADER_SIZE + len);
    vp_enc_add_reply(&b.w, 8, m.epoch, h, m.count);
    const uint8_t *q = enc_payload(&b, VP_ENTITY_ADD_REPLY, len);
    CHECK(memcmp(q, p, len) == 0);
    fuzz_wclose(&b);
    free(h);
}

static void fuzz_list(const uint8_t *p, size_t len, uint32_t limit)
{
    vp_list m;
    int rc = vp_dec_list(p, len, 0, &m);
    check_code(rc);
    vp_list lim;
    int rcl = vp_dec_list(p, len, limit, &lim);
    check_code(rcl);
    if (rcl == VP_OK) CHECK(rc == VP_OK && lim.max >= 1 && (limit == 0 || lim.max <= limit));
    if (rc == VP_OK && rcl != VP_OK) CHECK(rcl == VP_ERR_COUNT && limit && m.max > limit);
    if (rc) return;
    CHECK(m.max >= 1);
    fuzz_wbuf b;
    fuzz_wopen(&b, VP_HEADER_SIZE + len);
    vp_enc_list(&b.w, 9, &m);
    const uint8_t *q = enc_payload(&b, VP_ENTITY_LIST, len);
    CHECK(memcmp(q, p, len) == 0);
    fuzz_wclose(&b);
}

static void fuzz_list_reply(const uint8_t *p, size_t len)
{
    vp_list_reply m;
    int rc = vp_dec_list_reply(p, len, &m);
    check_code(rc);
    if (rc) return;
    CHECK(len == 20 + (size_t)m.batch.count * VP_ENTITY_REC_SIZE);
    vp_entity *e = read_entities(&m.batch);
    fuzz_wbuf b;
    fuzz_wopen(&b, VP_HEADER_SIZE + len);
    vp_enc_list_reply(&b.w, 10, m.next_cursor, m.epoch, e, m.batch.count);
    const uint8_t *q = enc_payload(&b, VP_ENTITY_LIST_REPLY, len);
    vp_list_reply r;
    CHECK(vp_dec_list_reply(q, len, &r) == VP_OK);
    CHECK(r.next_cursor == m.next_cursor && r.epoch == m.epoch && r.batch.count == m.batch.count);
    for (uint32_t i = 0; i < r.batch.count; i++) {
        vp_entity x;
        CHECK(vp_entity_get(&r.batch, i, &x) == VP_OK && same_entity(&x, &e[i]));
    }
    fuzz_wclose(&b);
    free(e);
}

/* n floats of a decoded array (NULL: none), copied out */
static float *floats_of(const uint8_t *p, size_t n)
{
    if (!p) return NULL;
    float *f = malloc(n * sizeof *f + 1);
    CHECK(f != NULL);
    for (size_t k = 0; k < n; k++) f[k] = vp_ld_f32(p + 4 * k);
    return f;
}

static void fuzz_mesh(const uint8_t *p, size_t len, uint32_t limit)
{
    vp_mesh m;
    int rc = vp_dec_mesh(p, len, 0, &m);
    check_code(rc);
    vp_mesh lim;
    int rcl = vp_dec_mesh(p, len, limit, &lim);
    check_code(rcl);
    if (rcl == VP_OK)
        CHECK(rc == VP_OK && (limit == 0 || (lim.vertex_count <= limit && lim.index_count / 3 <= limit)));
    /* within the limit (vertices <= max_batch, triangles <= max_batch) the
     * limit must not matter */
    if (rc == VP_OK && (limit == 0 || (m.vertex_count <= limit && m.index_count / 3 <= limit)))
        CHECK(rcl == VP_OK);
    if (rc) return;
    CHECK(m.index_count % 3 == 0 && !(m.flags & ~VP_MESH_FLAGS));
    bool normals = !(m.flags & VP_MESH_NO_NORMALS), uvs = m.flags & VP_MESH_UVS, tan = m.flags & VP_MESH_TANGENTS;
    CHECK(normals == (m.normals != NULL) && uvs == (m.uvs != NULL) && tan == (m.tangents != NULL) && (uvs || !tan));
    size_t nv = m.vertex_count;
    CHECK(len == 12 + nv * (12 + (normals ? 12 : 0) + (uvs ? 8 : 0) + (tan ? 16 : 0)) + (size_t)m.index_count * 4);
    CHECK(vp_size_mesh_uv(m.vertex_count, m.index_count, normals, uvs, tan) == VP_HEADER_SIZE + len);
    vp_reader r;
    vp_reader_init(&r, m.indices, (size_t)m.index_count * 4);
    uint32_t *idx = malloc((size_t)m.index_count * 4 + 1);
    CHECK(idx != NULL);
    for (uint32_t i = 0; i < m.index_count; i++) CHECK((idx[i] = vp_get_u32(&r)) < m.vertex_count);
    CHECK(vp_reader_finish(&r) == VP_OK);
    /* decode -> encode: the same bytes (the arrays are taken as sent) */
    float *pos = floats_of(m.positions, 3 * nv), *nrm = floats_of(m.normals, 3 * nv), *uv = floats_of(m.uvs, 2 * nv),
          *tg = floats_of(m.tangents, 4 * nv);
    fuzz_wbuf b;
    fuzz_wopen(&b, VP_HEADER_SIZE + len);
    vp_enc_mesh_uv(&b.w, 3, m.class_id, pos ? pos : (float[1]){0}, nrm, uv, tg, m.vertex_count, idx, m.index_count);
    const uint8_t *q = enc_payload(&b, VP_MESH_PUT, len);
    CHECK(memcmp(q, p, len) == 0);
    vp_mesh x;
    CHECK(vp_dec_mesh(q, len, 0, &x) == VP_OK && x.flags == m.flags && x.vertex_count == m.vertex_count);
    fuzz_wclose(&b);
    free(pos), free(nrm), free(uv), free(tg), free(idx);
}

static void fuzz_occluder(const uint8_t *p, size_t len, uint32_t limit)
{
    vp_occluder m;
    int rc = vp_dec_occluder(p, len, 0, &m);
    check_code(rc);
    vp_occluder lim;
    int rcl = vp_dec_occluder(p, len, limit, &lim);
    check_code(rcl);
    if (rcl == VP_OK) CHECK(rc == VP_OK && (limit == 0 || lim.tri_count <= limit));
    if (rc == VP_OK && rcl != VP_OK) CHECK(rcl == VP_ERR_COUNT && limit && m.tri_count > limit);
    if (rc) return;
    CHECK(len == 40 + (size_t)m.tri_count * 36 && !(m.flags & ~VP_OCC_ATTACHED));
    /* decode -> encode: the same bytes */
    float *v = floats_of(m.verts, 9 * (size_t)m.tri_count);
    fuzz_wbuf b;
    fuzz_wopen(&b, vp_size_occluder(m.tri_count));
    vp_enc_occluder_flags(&b.w, 4, m.id, m.flags, m.origin, v ? v : (float[1]){0}, m.tri_count);
    CHECK(memcmp(enc_payload(&b, VP_OCCLUDER_PUT, len), p, len) == 0);
    fuzz_wclose(&b);
    free(v);
}

static void fuzz_lights(const uint8_t *p, size_t len, uint32_t limit)
{
    const uint8_t *recs = NULL;
    uint32_t n = 0;
    int rc = vp_dec_lights(p, len, 0, &recs, &n);
    check_code(rc);
    const uint8_t *lrecs = NULL;
    uint32_t ln = 0;
    int rcl = vp_dec_lights(p, len, limit, &lrecs, &ln);
    check_code(rcl);
    if (rcl == VP_OK) CHECK(rc == VP_OK && (limit == 0 || ln <= limit));
    if (rc == VP_OK && rcl != VP_OK) CHECK(rcl == VP_ERR_COUNT && limit && n > limit);
    if (rc) return;
    CHECK(len == 4 + (size_t)n * VP_LIGHT_SIZE);
    vp_light *l = malloc(((size_t)n ? n : 1) * sizeof *l);
    CHECK(l != NULL);
    for (uint32_t i = 0; i < n; i++) CHECK(vp_light_get(recs, n, i, &l[i]) == VP_OK);
    fuzz_wbuf b;
    fuzz_wopen(&b, VP_HEADER_SIZE + len);
    vp_enc_lights(&b.w, 11, l, n);
    const uint8_t *q = enc_payload(&b, VP_LIGHT_PUT, len);
    const uint8_t *rrecs = NULL;
    uint32_t rn = 0;
    CHECK(vp_dec_lights(q, len, 0, &rrecs, &rn) == VP_OK && rn == n);
    for (uint32_t i = 0; i < rn; i++) {
        vp_light x;
        CHECK(vp_light_get(rrecs, n, i, &x) == VP_OK && same_light(&x, &l[i]));
    }
    fuzz_wclose(&b);
    free(l);
}

static void fuzz_vis_query(const uint8_t *p, size_t len)
{
    vp_vis_query m;
    int rc = vp_dec_vis_query(p, len, &m);
    check_code(rc);
    if (rc) return;
    CHECK(m.view_count >= 1 && m.view_count <= VP_MAX_VIEWS);
    CHECK(((m.flags & VP_Q_SUBLEVELS) != 0) == (m.nsub != 0));
    CHECK(m.nsub <= VP_MAX_QUERY_SUBLEVELS);
    CHECK(len == 8 + (size_t)m.view_count * VP_VIEW_SIZE + (m.nsub ? 2 + 2 * (size_t)m.nsub : 0));
    vp_view v[VP_MAX_VIEWS];
    for (uint32_t i = 0; i < m.view_count; i++) CHECK(vp_view_get(&m, i, &v[i]) == VP_OK);
    vp_view past;
    CHECK(vp_view_get(&m, m.view_count, &past) == VP_ERR_COUNT);
    static uint16_t subs[VP_MAX_QUERY_SUBLEVELS];
    for (uint32_t i = 0; i < m.nsub; i++) subs[i] = vp_query_sublevel_get(&m, i);
    CHECK(vp_query_sublevel_get(&m, m.nsub) == 0);
    fuzz_wbuf b;
    fuzz_wopen(&b, VP_HEADER_SIZE + len);
    vp_enc_vis_query_sub(&b.w, 12, m.flags, m.min_area, v, m.view_count, m.nsub ? subs : NULL, m.nsub);
    const uint8_t *q = enc_payload(&b, VP_VIS_QUERY, len);
    vp_vis_query r;
    CHECK(vp_dec_vis_query(q, len, &r) == VP_OK);
    CHECK(r.nsub == m.nsub && (!m.nsub || !memcmp(r.subs, m.subs, 2 * (size_t)m.nsub)));
    CHECK(r.view_count == m.view_count && r.flags == m.flags && same_f32(r.min_area, m.min_area));
    for (uint32_t i = 0; i < r.view_count; i++) {
        vp_view x;
        CHECK(vp_view_get(&r, i, &x) == VP_OK && same_view(&x, &v[i]));
    }
    fuzz_wclose(&b);
}

static void fuzz_render(const uint8_t *p, size_t len)
{
    vp_render m;
    int rc = vp_dec_render(p, len, &m);
    check_code(rc);
    if (rc) return;
    CHECK(len == VP_RENDER_SIZE && m.format <= VP_FRAME_JPEG);
    fuzz_wbuf b;
    fuzz_wopen(&b, VP_HEADER_SIZE + len);
    vp_enc_render(&b.w, 14, &m);
    const uint8_t *q = enc_payload(&b, VP_RENDER, len);
    vp_render r;
    CHECK(vp_dec_render(q, len, &r) == VP_OK);
    CHECK(same_view(&r.view, &m.view) && r.format == m.format && r.quality == m.quality && r.flags == m.flags &&
          r.renderer == m.renderer && same_f32(r.exposure_ev, m.exposure_ev));
    fuzz_wclose(&b);
}

static void fuzz_light_query(const uint8_t *p, size_t len)
{
    vp_light_query m;
    int rc = vp_dec_light_query(p, len, &m);
    check_code(rc);
    if (rc) return;
    CHECK(len == VP_LIGHT_QUERY_SIZE && !(m.flags & ~VP_LQ_NO_DEPTH));
    fuzz_wbuf b;
    fuzz_wopen(&b, VP_HEADER_SIZE + len);
    vp_enc_light_query(&b.w, 17, &m);
    const uint8_t *q = enc_payload(&b, VP_LIGHT_QUERY, len);
    CHECK(memcmp(q, p, len) == 0); /* the encoding is canonical */
    fuzz_wclose(&b);
}

static void fuzz_light_tiles(const uint8_t *p, size_t len)
{
    vp_light_tiles m;
    int rc = vp_dec_light_tiles(p, len, &m);
    check_code(rc);
    if (rc) return;
    uint32_t tiles = (uint32_t)m.tiles_x * m.tiles_y;
    CHECK(vp_size_light_tiles(tiles, m.count) == VP_HEADER_SIZE + len);
    /* the lists are well formed: walking them stays inside the ids */
    uint32_t prev = 0;
    for (uint32_t t = 0; t <= tiles; t++) {
        uint32_t o = vp_light_tiles_offset(&m, t);
        CHECK(o >= prev && o <= m.count);
        prev = o;
    }
    CHECK(prev == m.count);
    fuzz_wbuf b;
    fuzz_wopen(&b, VP_HEADER_SIZE + len);
    vp_enc_light_tiles_begin(&b.w, 18, &m);
    for (uint32_t t = 0; t <= tiles; t++) vp_put_u32(&b.w, vp_light_tiles_offset(&m, t));
    for (uint32_t k = 0; k < m.count; k++) vp_put_u64(&b.w, vp_light_tiles_id(&m, k));
    vp_frame_end(&b.w);
    const uint8_t *q = enc_payload(&b, VP_LIGHT_TILES, len);
    CHECK(memcmp(q, p, len) == 0);
    fuzz_wclose(&b);
}

static void fuzz_frame_sub(const uint8_t *p, size_t len)
{
    vp_frame_sub m;
    int rc = vp_dec_frame_sub(p, len, &m);
    check_code(rc);
    if (rc) return;
    CHECK(len == VP_FRAME_SUB_SIZE && m.max_fps >= 1 && m.max_fps <= VP_FRAME_SUB_MAX_FPS);
    fuzz_wbuf b;
    fuzz_wopen(&b, VP_HEADER_SIZE + len);
    vp_enc_frame_sub(&b.w, 16, &m);
    const uint8_t *q = enc_payload(&b, VP_FRAME_SUBSCRIBE, len);
    CHECK(memcmp(q, p, len) == 0); /* the encoding is canonical */
    vp_frame_sub r;
    CHECK(vp_dec_frame_sub(q, len, &r) == VP_OK);
    CHECK(same_view(&r.r.view, &m.r.view) && r.r.format == m.r.format && r.r.renderer == m.r.renderer &&
          r.max_fps == m.max_fps);
    fuzz_wclose(&b);
}

static void fuzz_frame(const uint8_t *p, size_t len)
{
    vp_frame m;
    int rc = vp_dec_frame(p, len, &m);
    check_code(rc);
    if (rc) return;
    CHECK(vp_size_frame(m.data_len) == VP_HEADER_SIZE + len);
    fuzz_wbuf b;
    fuzz_wopen(&b, vp_size_frame(m.data_len));
    vp_enc_frame(&b.w, 15, &m);
    const uint8_t *q = enc_payload(&b, VP_FRAME, len);
    CHECK(memcmp(q, p, len) == 0);
    fuzz_wclose(&b);
}

static void fuzz_vis_result(const uint8_t *p, size_t len)
{
    vp_vis_result m;
    int rc = vp_dec_vis_result(p, len, &m);
    check_code(rc);
    if (rc) return;
    CHECK(len == 20 + 4 * VP_STAGES + (size_t)m.count * VP_VIS_REC_SIZE);
    CHECK(vp_size_vis_result(m.count) == VP_HEADER_SIZE + len);
    fuzz_wbuf b;
    fuzz_wopen(&b, vp_size_vis_result(m.count));
    vp_enc_vis_result_begin(&b.w, 13, &m);
    for (uint32_t i = 0; i < m.count; i++) {
        vp_vis_rec rec;
        vp_vis_rec_get(&m, i, &rec);
        vp_put_vis_rec(&b.w, &rec);
    }
    CHECK(vp_frame_end(&b.w));
    const uint8_t *q = enc_payload(&b, VP_VIS_RESULT, len);
    CHECK(memcmp(q, p, len) == 0);
    fuzz_wclose(&b);
}

/* ---- dispatch ------------------------------------------------------------------------ */

typedef void (*plain_fn)(const uint8_t *, size_t);

/* Sub-level names: walk every entry; re-encode and compare. */
static void fuzz_names(const uint8_t *p, size_t len, bool with_ids)
{
    vp_name_list l;
    if (vp_dec_names(p, len, with_ids, &l) != VP_OK) return;
    size_t pos = 0;
    vp_name nm;
    uint32_t n = 0;
    char names[64][256];
    const char *ptrs[64];
    uint16_t ids[64];
    while (vp_name_next(&l, &pos, &nm)) {
        CHECK(nm.len >= 1 && nm.name + nm.len <= p + len);
        if (n < 64) {
            memcpy(names[n], nm.name, nm.len);
            names[n][nm.len] = 0;
            ptrs[n] = names[n];
            ids[n] = nm.id;
        }
        n++;
    }
    CHECK(n == l.count);
    if (n > 64) return;
    uint8_t buf[VP_HEADER_SIZE + 4 + 64 * 258];
    vp_writer w;
    vp_writer_init(&w, buf, sizeof buf);
    vp_enc_names(&w, with_ids ? VP_SUBLEVEL_LIST_REPLY : VP_SUBLEVEL_NAMES, 0, ptrs, with_ids ? ids : NULL, n);
    CHECK(!w.overflow && w.len - VP_HEADER_SIZE == len && !memcmp(buf + VP_HEADER_SIZE, p, len));
}

static void fuzz_sublevel_ids(const uint8_t *p, size_t len)
{
    uint32_t n;
    const uint8_t *ids;
    if (vp_dec_sublevel_ids(p, len, &n, &ids) != VP_OK) return;
    for (uint32_t i = 0; i < n; i++) (void)vp_sublevel_id_get(ids, n, i);
}

/* ---- sub-level loads ---- */

static void fuzz_sublevel_begin(const uint8_t *p, size_t len)
{
    vp_sublevel_begin m;
    int rc = vp_dec_sublevel_begin(p, len, &m);
    check_code(rc);
    if (rc) return;
    CHECK(m.name_len >= 1 && m.classes <= 4096 && len == 3u + m.name_len);
    fuzz_wbuf b;
    fuzz_wopen(&b, VP_HEADER_SIZE + len);
    vp_enc_sublevel_begin(&b.w, 3, &m);
    CHECK(!memcmp(enc_payload(&b, VP_SUBLEVEL_BEGIN, len), p, len));
    fuzz_wclose(&b);
}

static void fuzz_sublevel_begun(const uint8_t *p, size_t len)
{
    vp_sublevel_begun m;
    int rc = vp_dec_sublevel_begun(p, len, &m);
    check_code(rc);
    if (rc) return;
    CHECK(len == 16);
    fuzz_wbuf b;
    fuzz_wopen(&b, VP_HEADER_SIZE + len);
    vp_enc_sublevel_begun(&b.w, 3, &m);
    CHECK(!memcmp(enc_payload(&b, VP_SUBLEVEL_BEGUN, len), p, len));
    fuzz_wclose(&b);
}

static void fuzz_sublevel_name(const uint8_t *p, size_t len)
{
    vp_name m;
    int rc = vp_dec_sublevel_name(p, len, &m);
    check_code(rc);
    if (rc) return;
    CHECK(m.len >= 1 && len == 1u + m.len);
    char name[256];
    memcpy(name, m.name, m.len);
    name[m.len] = 0;
    if (strlen(name) != m.len) return; /* a NUL inside: C strings cannot carry it (the decoder refuses < 32) */
    fuzz_wbuf b;
    fuzz_wopen(&b, VP_HEADER_SIZE + len);
    vp_enc_sublevel_name(&b.w, VP_SUBLEVEL_UNLOAD, 3, name);
    CHECK(!memcmp(enc_payload(&b, VP_SUBLEVEL_UNLOAD, len), p, len));
    fuzz_wclose(&b);
}

static void fuzz_sublevel_infos(const uint8_t *p, size_t len)
{
    vp_sublevel_infos m;
    int rc = vp_dec_sublevel_infos(p, len, &m);
    check_code(rc);
    if (rc) return;
    fuzz_wbuf b;
    fuzz_wopen(&b, VP_HEADER_SIZE + len);
    vp_enc_sublevel_infos_begin(&b.w, 3, m.epoch, m.count);
    size_t pos = 0;
    uint32_t n = 0;
    vp_sublevel_info in;
    while (vp_sublevel_info_next(&m, &pos, &in)) {
        CHECK(in.state <= VP_SL_UNLOADING && in.name_len >= 1 && in.name + in.name_len <= p + len);
        vp_put_sublevel_info(&b.w, &in);
        n++;
    }
    CHECK(n == m.count && pos == m.len);
    vp_frame_end(&b.w);
    CHECK(!memcmp(enc_payload(&b, VP_SUBLEVEL_INFO_REPLY, len), p, len));
    fuzz_wclose(&b);
}

static void fuzz_destroy(const uint8_t *p, size_t len)
{
    vp_destroy m;
    int rc = vp_dec_destroy(p, len, &m);
    check_code(rc);
    if (rc) return;
    CHECK(len == VP_DESTROY_SIZE && m.radius > 0 && m.debris <= VP_MAX_DEBRIS);
    fuzz_wbuf b;
    fuzz_wopen(&b, VP_HEADER_SIZE + len);
    vp_enc_destroy(&b.w, 3, &m);
    CHECK(!memcmp(enc_payload(&b, VP_DESTROY, len), p, len));
    fuzz_wclose(&b);
}

static void fuzz_destroyed(const uint8_t *p, size_t len)
{
    vp_destroyed m;
    int rc = vp_dec_destroyed(p, len, &m);
    check_code(rc);
    if (rc) return;
    fuzz_wbuf b;
    fuzz_wopen(&b, VP_HEADER_SIZE + len);
    vp_enc_destroyed(&b.w, 3, &m);
    CHECK(!memcmp(enc_payload(&b, VP_DESTROYED, len), p, len));
    fuzz_wclose(&b);
}

static void fuzz_mark(const uint8_t *p, size_t len)
{
    vp_mark m;
    int rc = vp_dec_mark(p, len, &m);
    check_code(rc);
    if (rc) return;
    CHECK(m.ttl_ms >= 1 && m.ttl_ms <= 600000);
    fuzz_wbuf b;
    fuzz_wopen(&b, VP_HEADER_SIZE + len);
    vp_enc_mark(&b.w, 3, &m);
    CHECK(!memcmp(enc_payload(&b, VP_MARK, len), p, len));
    fuzz_wclose(&b);
}

static void fuzz_marked(const uint8_t *p, size_t len)
{
    vp_marked m;
    int rc = vp_dec_marked(p, len, &m);
    check_code(rc);
    if (rc) return;
    fuzz_wbuf b;
    fuzz_wopen(&b, VP_HEADER_SIZE + len);
    vp_enc_marked(&b.w, &m);
    CHECK(!memcmp(enc_payload(&b, VP_MARKED, len), p, len));
    fuzz_wclose(&b);
}

/* SELECT: what decodes has no 0 and no id twice, and re-encodes to the
 * same bytes; SELECTED the same bytes. */
static void fuzz_select(const uint8_t *p, size_t len)
{
    vp_select m;
    char why[160];
    int rc = vp_dec_select(p, len, &m, why, sizeof why);
    check_code(rc);
    if (rc) return;
    CHECK(m.count <= VP_SELECT_MAX && m.flags == 0 && len == VP_SELECT_HEAD + 8 * (size_t)m.count);
    uint64_t ids[VP_SELECT_MAX];
    for (uint32_t i = 0; i < m.count; i++) {
        ids[i] = vp_id_at(m.ids, m.count, i);
        CHECK(ids[i] != 0);
        for (uint32_t j = 0; j < i; j++) CHECK(ids[j] != ids[i]);
    }
    fuzz_wbuf b;
    fuzz_wopen(&b, VP_HEADER_SIZE + len);
    vp_enc_select(&b.w, 3, ids, m.count);
    CHECK(!memcmp(enc_payload(&b, VP_SELECT, len), p, len));
    fuzz_wclose(&b);
}

static void fuzz_selected(const uint8_t *p, size_t len)
{
    vp_selected m;
    int rc = vp_dec_selected(p, len, &m);
    check_code(rc);
    if (rc) return;
    CHECK(m.count <= VP_SELECT_MAX && len == VP_SELECTED_HEAD + 8 * (size_t)m.count);
    uint64_t ids[VP_SELECT_MAX];
    for (uint32_t i = 0; i < m.count; i++) ids[i] = vp_id_at(m.ids, m.count, i);
    fuzz_wbuf b;
    fuzz_wopen(&b, VP_HEADER_SIZE + len);
    vp_enc_selected(&b.w, &m, ids);
    CHECK(!memcmp(enc_payload(&b, VP_SELECTED, len), p, len));
    fuzz_wclose(&b);
}

/* METRICS_REPLY: the text is the rest of the payload, NUL-free; re-encoded
 * byte for byte. */
static void fuzz_metrics_reply(const uint8_t *p, size_t len)
{
    vp_metrics_reply m;
    int rc = vp_dec_metrics_reply(p, len, &m);
    check_code(rc);
    if (rc) return;
    CHECK(m.format == VP_METRICS_PROMETHEUS && len == VP_METRICS_REPLY_HEADER + (size_t)m.text_len);
    CHECK(vp_size_metrics_reply(m.text_len) == VP_HEADER_SIZE + len);
    CHECK(m.text_len == 0 || (m.text == p + VP_METRICS_REPLY_HEADER && !memchr(m.text, 0, m.text_len)));
    fuzz_wbuf b;
    fuzz_wopen(&b, VP_HEADER_SIZE + len);
    vp_enc_metrics_reply(&b.w, 3, &m);
    CHECK(!memcmp(enc_payload(&b, VP_METRICS_REPLY, len), p, len));
    fuzz_wclose(&b);
}

/* ---- read-back (vp_readback.c) ---- */

static void fuzz_mesh_get(const uint8_t *p, size_t len)
{
    vp_mesh_get m;
    int rc = vp_dec_mesh_get(p, len, &m);
    check_code(rc);
    if (rc) return;
    CHECK(len == 2);
    fuzz_wbuf b;
    fuzz_wopen(&b, vp_size_mesh_get());
    vp_enc_mesh_get(&b.w, 12, &m);
    CHECK(memcmp(enc_payload(&b, VP_MESH_GET, len), p, len) == 0);
    fuzz_wclose(&b);
}

static void fuzz_material_list(const uint8_t *p, size_t len, uint32_t limit)
{
    vp_page m, lim;
    int rc = vp_dec_material_list(p, len, 0, &m), rcl = vp_dec_material_list(p, len, limit, &lim);
    check_code(rc);
    check_code(rcl);
    if (rcl == VP_OK) CHECK(rc == VP_OK && lim.max >= 1 && (limit == 0 || lim.max <= limit));
    if (rc) return;
    fuzz_wbuf b;
    fuzz_wopen(&b, vp_size_material_list());
    vp_enc_material_list(&b.w, 13, &m);
    CHECK(memcmp(enc_payload(&b, VP_MATERIAL_LIST, len), p, len) == 0);
    fuzz_wclose(&b);
}

static void fuzz_texture_get(const uint8_t *p, size_t len)
{
    vp_texture_get m;
    int rc = vp_dec_texture_get(p, len, &m);
    check_code(rc);
    if (rc) return;
    CHECK(m.id != 0 && m.max_len != 0);
    fuzz_wbuf b;
    fuzz_wopen(&b, vp_size_texture_get());
    vp_enc_texture_get(&b.w, 14, &m);
    CHECK(memcmp(enc_payload(&b, VP_TEXTURE_GET, len), p, len) == 0);
    fuzz_wclose(&b);
}

static void fuzz_light_list(const uint8_t *p, size_t len, uint32_t limit)
{
    vp_page m, lim;
    int rc = vp_dec_light_list(p, len, 0, &m), rcl = vp_dec_light_list(p, len, limit, &lim);
    check_code(rc);
    check_code(rcl);
    if (rcl == VP_OK) CHECK(rc == VP_OK && lim.max >= 1 && (limit == 0 || lim.max <= limit));
    if (rc) return;
    fuzz_wbuf b;
    fuzz_wopen(&b, vp_size_light_list());
    vp_enc_light_list(&b.w, 15, &m);
    CHECK(memcmp(enc_payload(&b, VP_LIGHT_LIST, len), p, len) == 0);
    fuzz_wclose(&b);
}

static void fuzz_material_list_reply(const uint8_t *p, size_t len)
{
    vp_page_reply m;
    int rc = vp_dec_material_list_reply(p, len, &m);
    check_code(rc);
    if (rc) return;
    CHECK(len == 8 + (size_t)m.count * VP_MATERIAL_SIZE);
    vp_material *r = malloc(((size_t)m.count + 1) * sizeof *r);
    CHECK(r != NULL);
    for (uint32_t i = 0; i < m.count; i++) CHECK(vp_material_get(m.recs, m.count, i, &r[i]) == VP_OK);
    fuzz_wbuf b;
    fuzz_wopen(&b, vp_size_material_list_reply(m.count));
    vp_enc_material_list_reply(&b.w, 16, m.next_cursor, r, m.count);
    /* a record's checks renormalise nothing, so the bytes come back */
    CHECK(memcmp(enc_payload(&b, VP_MATERIAL_LIST_REPLY, len), p, len) == 0);
    fuzz_wclose(&b);
    free(r);
}

static void fuzz_light_list_reply(const uint8_t *p, size_t len)
{
    vp_page_reply m;
    int rc = vp_dec_light_list_reply(p, len, &m);
    check_code(rc);
    if (rc) return;
    CHECK(len == 12 + (size_t)m.count * VP_LIGHT_SIZE);
    vp_light *l = malloc(((size_t)m.count + 1) * sizeof *l);
    CHECK(l != NULL);
    for (uint32_t i = 0; i < m.count; i++) CHECK(vp_light_get(m.recs, m.count, i, &l[i]) == VP_OK);
    fuzz_wbuf b;
    fuzz_wopen(&b, vp_size_light_list_reply(m.count));
    vp_enc_light_list_reply(&b.w, 17, m.next_cursor, l, m.count);
    vp_page_reply r;
    CHECK(vp_dec_light_list_reply(enc_payload(&b, VP_LIGHT_LIST_REPLY, len), len, &r) == VP_OK);
    CHECK(r.next_cursor == m.next_cursor && r.count == m.count);
    for (uint32_t i = 0; i < r.count; i++) {
        vp_light x;
        CHECK(vp_light_get(r.recs, r.count, i, &x) == VP_OK && same_light(&x, &l[i]));
    }
    fuzz_wclose(&b);
    free(l);
}

static void fuzz_texture_reply(const uint8_t *p, size_t len)
{
    vp_texture_put m;
    int rc = vp_dec_texture_put(p, len, &m);
    check_code(rc);
    if (rc) return;
    CHECK(m.len >= 1 && m.offset + (uint64_t)m.len <= m.total && len == VP_TEXTURE_PUT_HEADER + (size_t)m.len);
    fuzz_wbuf b;
    fuzz_wopen(&b, vp_size_texture_put(m.len));
    vp_enc_texture_as(&b.w, VP_TEXTURE_REPLY, 18, &m);
    CHECK(memcmp(enc_payload(&b, VP_TEXTURE_REPLY, len), p, len) == 0);
    fuzz_wclose(&b);
}

static void dispatch(const vp_header *h, const uint8_t *p, size_t len)
{
    uint32_t limit = h->req; /* fuzzer-chosen max_batch for the batch decoders */
    switch (h->type) {
    case VP_HELLO: fuzz_hello(p, len); return;
    case VP_HELLO_OK: fuzz_hello_ok(p, len); return;
    case VP_ERROR: fuzz_error(p, len); return;
    case VP_PING:
    case VP_PONG: fuzz_ping(p, len); return;
    case VP_STATS:
    case VP_FRAME_UNSUBSCRIBE: fuzz_empty(p, len); return;
    case VP_STATS_REPLY: fuzz_stats_reply(p, len); return;
    case VP_SUBSCRIBE: fuzz_subscribe(p, len); return;
    case VP_EVENT: fuzz_event(p, len); return;
    case VP_ACK: fuzz_ack(p, len); return;
    case VP_ENTITY_ADD:
    case VP_ENTITY_UPDATE:
        fuzz_entities(p, len, h->type, limit);
        fuzz_entities_v1(p, len, limit); /* a version 1 journal's records */
        return;
    case VP_TRANSFORM_SET: fuzz_transforms(p, len, limit); return;
    case VP_MATERIAL_PUT: fuzz_materials(p, len, limit); return;
    case VP_TEXTURE_PUT: fuzz_texture_put(p, len); return;
    case VP_ENV_SET:
    case VP_ENV_REPLY: fuzz_env(p, len, h->type); return;
    case VP_ENV_GET: fuzz_empty(p, len); return;
    case VP_MATERIAL_REMOVE:
    case VP_TEXTURE_REMOVE: fuzz_ids(p, len, h->type, limit); return;
    case VP_ENTITY_ADD_REPLY: fuzz_add_reply(p, len); return;
    case VP_ENTITY_REMOVE:
    case VP_OCCLUDER_REMOVE:
    case VP_LIGHT_REMOVE: fuzz_ids(p, len, h->type, limit); return;
    case VP_ENTITY_LIST: fuzz_list(p, len, limit); return;
    case VP_ENTITY_LIST_REPLY: fuzz_list_reply(p, len); return;
    case VP_MESH_PUT: fuzz_mesh(p, len, limit); return;
    case VP_OCCLUDER_PUT:
        fuzz_occluder(p, len, limit);
        fuzz_occluder_v1(p, len, limit);
        return;
    case VP_LIGHT_PUT: fuzz_lights(p, len, limit); return;
    case VP_VIS_QUERY: fuzz_vis_query(p, len); return;
    case VP_VIS_RESULT: fuzz_vis_result(p, len); return;
    case VP_RENDER: fuzz_render(p, len); return;
    case VP_FRAME: fuzz_frame(p, len); return;
    case VP_FRAME_SUBSCRIBE: fuzz_frame_sub(p, len); return;
    case VP_LIGHT_QUERY: fuzz_light_query(p, len); return;
    case VP_LIGHT_TILES: fuzz_light_tiles(p, len); return;
    case VP_ENTITY_GET: fuzz_ids(p, len, h->type, limit); return;
    case VP_SUBLEVEL_NAMES:
    case VP_SUBLEVEL_LIST_REPLY: fuzz_names(p, len, h->type == VP_SUBLEVEL_LIST_REPLY); return;
    case VP_SUBLEVEL_IDS: fuzz_sublevel_ids(p, len); return;
    case VP_SUBLEVEL_LIST:
    case VP_SUBLEVEL_COMMIT:
    case VP_SUBLEVEL_ABORT:
    case VP_SUBLEVEL_INFO: fuzz_empty(p, len); return;
    case VP_SUBLEVEL_BEGIN: fuzz_sublevel_begin(p, len); return;
    case VP_SUBLEVEL_BEGUN: fuzz_sublevel_begun(p, len); return;
    case VP_SUBLEVEL_UNLOAD: fuzz_sublevel_name(p, len); return;
    case VP_SUBLEVEL_INFO_REPLY: fuzz_sublevel_infos(p, len); return;
    case VP_DESTROY: fuzz_destroy(p, len); return;
    case VP_DESTROYED: fuzz_destroyed(p, len); return;
    case VP_MARK: fuzz_mark(p, len); return;
    case VP_MARKED: fuzz_marked(p, len); return;
    case VP_SELECT: fuzz_select(p, len); return;
    case VP_SELECTED: fuzz_selected(p, len); return;
    case VP_METRICS: fuzz_empty(p, len); return;
    case VP_METRICS_REPLY: fuzz_metrics_reply(p, len); return;
    case VP_MESH_GET: fuzz_mesh_get(p, len); return;
    case VP_MESH_REPLY: fuzz_mesh(p, len, limit); return;
    case VP_MATERIAL_LIST: fuzz_material_list(p, len, limit); return;
    case VP_MATERIAL_LIST_REPLY: fuzz_material_list_reply(p, len); return;
    case VP_TEXTURE_GET: fuzz_texture_get(p, len); return;
    case VP_TEXTURE_REPLY: fuzz_texture_reply(p, len); return;
    case VP_LIGHT_LIST: fuzz_light_list(p, len, limit); return;
    case VP_LIGHT_LIST_REPLY: fuzz_light_list_reply(p, len); return;
    default: break;
    }
    /* Unknown to this version: a server would answer ERROR TYPE and skip
     * it. Decoders are pure, so feed the payload to one picked by the type
     * bits anyway; every decoder then sees every payload shape. */
    CHECK(!vp_type_known(h->type));
    CHECK(strcmp(vp_type_name(h->type), "unknown") == 0);
    static const plain_fn plain[] = {fuzz_hello,   fuzz_hello_ok,    fuzz_error,     fuzz_ping,
                                     fuzz_empty,   fuzz_stats_reply, fuzz_subscribe, fuzz_event,
                                     fuzz_ack,     fuzz_add_reply,   fuzz_list_reply, fuzz_vis_query,
                                     fuzz_vis_result};
    const size_t np = sizeof plain / sizeof plain[0];
    size_t pick = h->type % (np + 12);
    if (pick < np) {
        plain[pick](p, len);
        return;
    }
    switch (pick - np) {
    case 0: fuzz_entities(p, len, VP_ENTITY_ADD, limit); break;
    case 1: fuzz_ids(p, len, VP_ENTITY_REMOVE, limit); break;
    case 2: fuzz_list(p, len, limit); break;
    case 3: fuzz_mesh(p, len, limit); break;
    case 4: fuzz_occluder(p, len, limit); break;
    case 5: fuzz_lights(p, len, limit); break;
    case 6: fuzz_transforms(p, len, limit); break;
    case 7: fuzz_materials(p, len, limit); break;
    case 8: fuzz_texture_put(p, len); break;
    case 9: fuzz_env(p, len, VP_ENV_SET); break;
    case 10: fuzz_entities_v1(p, len, limit); break;
    default: fuzz_occluder_v1(p, len, limit); break;
    }
}

/* Framing properties of vp_frame_check on a prefix of n bytes. */
static void check_framing(const uint8_t *data, size_t n, uint32_t max_payload)
{
    vp_header h;
    size_t fs = 0;
    int rc = vp_frame_check(data, n, max_payload, &h, &fs);
    check_code(rc == VP_NEED_MORE ? VP_OK : rc);
    if (n < VP_HEADER_SIZE) {
        CHECK(rc == VP_NEED_MORE);
        return;
    }
    switch (rc) {
    case VP_OK:
        CHECK(h.len <= max_payload && h.flags == 0);
        CHECK(fs == VP_HEADER_SIZE + (size_t)h.len && fs <= n);
        break;
    case VP_NEED_MORE:
        CHECK(h.len <= max_payload && h.flags == 0);
        CHECK(fs == VP_HEADER_SIZE + (size_t)h.len && fs > n);
        break;
    case VP_ERR_TOO_LARGE: CHECK(h.len > max_payload); break;
    case VP_ERR_INVALID: CHECK(h.len <= max_payload && h.flags != 0); break;
    default: CHECK(!"unexpected vp_frame_check result");
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    /* 1. framing on the raw input, under a few limits and at a few cuts */
    static const uint32_t limits[] = {0, 64, 65536, UINT32_MAX};
    for (size_t i = 0; i < sizeof limits / sizeof limits[0]; i++) {
        check_framing(data, size, limits[i]);
        check_framing(data, size < VP_HEADER_SIZE ? size : VP_HEADER_SIZE, limits[i]);
        if (size) check_framing(data, size - 1, limits[i]);
    }

    /* 2. the input as a stream of frames; the first byte past the last
     *    whole frame is where a real reader would wait for more */
    size_t off = 0;
    for (unsigned nframes = 0; nframes < MAX_FRAMES && off < size; nframes++) {
        vp_header h;
        size_t fs = 0;
        int rc = vp_frame_check(data + off, size - off, UINT32_MAX, &h, &fs);
        if (rc != VP_OK) break; /* need more, or the stream can't be trusted */
        CHECK(fs >= VP_HEADER_SIZE && fs <= size - off);
        /* copy the payload into its own allocation so ASan catches any
         * decoder read past the payload, not just past the input */
        size_t len = h.len;
        uint8_t *payload = malloc(len ? len : 1);
        CHECK(payload != NULL);
        if (len) memcpy(payload, data + off + VP_HEADER_SIZE, len);
        dispatch(&h, payload, len);
        free(payload);
        off += fs;
    }
    return 0;
}
