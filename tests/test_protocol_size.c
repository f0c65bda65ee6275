/*
 * test_protocol_size.c — every encoder's size function against the bytes
 * the encoder really writes. One test per message, each over several
 * inputs (empty, typical, maximal, and past a limit the encoder cuts to):
 * the size equals the frame's length; a buffer of exactly that size takes
 * the frame byte for byte and one byte less overflows; the header's length
 * is the size less the header. Fixed layouts are also held to the sizes
 * PROTOCOL.md states (the VP_*_SIZE constants), an independent model.
 */
#include "test_util.h"

#include "protocol.h"

#include <stdlib.h>
#include <string.h>

static uint8_t g_big[1 << 22], g_exact[1 << 22];

/* Encodes variant v of a message into w and returns its size function's
 * answer for the same input; SIZE_MAX past the last variant. */
typedef size_t (*size_case)(vp_writer *w, int v);

static void check_case(size_case c)
{
    for (int v = 0;; v++) {
        vp_writer w;
        vp_writer_init(&w, g_big, sizeof g_big);
        size_t size = c(&w, v);
        if (size == SIZE_MAX) {
            assert_true(v >= 2); /* every message is tried on several inputs */
            return;
        }
        assert_false(w.overflow);
        assert_int_equal(w.len, size);
        vp_header h;
        size_t fs;
        assert_int_equal(vp_frame_check(g_big, w.len, UINT32_MAX, &h, &fs), VP_OK);
        assert_int_equal(fs, size);
        assert_int_equal(h.len, size - VP_HEADER_SIZE);
        /* exactly that much room: the same bytes, no overflow */
        vp_writer x;
        vp_writer_init(&x, g_exact, size);
        assert_int_equal(c(&x, v), size);
        assert_false(x.overflow);
        assert_int_equal(x.len, size);
        assert_memory_equal(g_exact, g_big, size);
        /* one byte less: the writer says so */
        vp_writer_init(&x, g_exact, size - 1);
        (void)c(&x, v);
        assert_true(x.overflow);
    }
}

static vp_entity ent(uint32_t i)
{
    return (vp_entity){.id = 100 + i, .handle = i, .class_id = (uint16_t)i, .sublevel = 1, .flags = i & 1,
                       .sphere = {1, 2, 3, 4}, .aabb = {-1, -1, -1, 1, 1, 1}};
}

static vp_view view(uint32_t i)
{
    vp_view v = {.origin = {i, 2, 3}, .depth_mode = 1, .viewport_w = 64, .viewport_h = 32};
    for (int k = 0; k < 16; k++) v.view_proj[k] = k % 5 == 0;
    return v;
}

/* a name of n bytes ('a'..), in a static buffer per slot */
static const char *name_of(int slot, size_t n)
{
    static char names[4][400];
    memset(names[slot], 'a' + slot, n);
    names[slot][n] = 0;
    return names[slot];
}

static size_t case_hello(vp_writer *w, int v)
{
    static const uint8_t tok[VP_MAX_TOKEN] = {1};
    uint8_t l[] = {0, 5, 255};
    if (v >= 3) return SIZE_MAX;
    vp_hello m = {.magic = VP_MAGIC, .version = VP_VERSION, .token_len = l[v], .token = tok, .name_len = l[2 - v],
                  .name = tok};
    vp_enc_hello(w, 1, &m);
    return vp_size_hello(&m);
}

static size_t case_hello_ok(vp_writer *w, int v)
{
    if (v >= 2) return SIZE_MAX;
    vp_enc_hello_ok(w, 1, &(vp_hello_ok){.version = 1, .epoch = v ? UINT64_MAX : 0});
    assert_int_equal(vp_size_hello_ok(), VP_HEADER_SIZE + 28);
    return vp_size_hello_ok();
}

static size_t case_error(vp_writer *w, int v)
{
    static char big[3000], ctl[600];
    memset(big, 'x', sizeof big - 1);
    memset(ctl, 1, sizeof ctl - 1); /* each byte escaped to 4: cut at the limit */
    const char *msgs[] = {NULL, "", "no such entity", big, ctl, "caf\xc3\xa9 \\ \x7f"};
    if (v >= (int)(sizeof msgs / sizeof msgs[0])) return SIZE_MAX;
    vp_enc_error(w, 1, VP_ERR_INVALID, 3, msgs[v]);
    size_t s = vp_size_error(msgs[v]);
    assert_true(s <= VP_HEADER_SIZE + 10 + VP_MAX_ERROR_MSG);
    return s;
}

static size_t case_ping(vp_writer *w, int v)
{
    static const uint8_t data[VP_MAX_PING];
    uint32_t n[] = {0, 7, VP_MAX_PING};
    if (v >= 3) return SIZE_MAX;
    vp_enc_ping(w, VP_PING, 1, data, n[v]);
    return vp_size_ping(n[v]);
}

static size_t case_empty(vp_writer *w, int v)
{
    uint16_t t[] = {VP_STATS, VP_METRICS, VP_SUBLEVEL_COMMIT};
    if (v >= 3) return SIZE_MAX;
    vp_enc_empty(w, t[v], 1);
    return vp_size_empty();
}

static vp_entity g_ents[2000];

static size_t case_entities(vp_writer *w, int v)
{
    uint32_t n[] = {0, 1, 2000};
    if (v >= 3) return SIZE_MAX;
    for (uint32_t i = 0; i < n[v]; i++) g_ents[i] = ent(i);
    vp_enc_entities(w, VP_ENTITY_ADD, 1, g_ents, n[v]);
    assert_int_equal(vp_size_entities(1) - vp_size_entities(0), VP_ENTITY_REC_SIZE);
    return vp_size_entities(n[v]);
}

static uint64_t g_ids[5000];

static size_t case_ids(vp_writer *w, int v)
{
    uint32_t n[] = {0, 3, 5000};
    if (v >= 3) return SIZE_MAX;
    vp_enc_ids(w, VP_ENTITY_REMOVE, 1, g_ids, n[v]);
    return vp_size_ids(n[v]);
}

static size_t case_add_reply(vp_writer *w, int v)
{
    static uint32_t h[5000];
    uint32_t n[] = {0, 3, 5000};
    if (v >= 3) return SIZE_MAX;
    vp_enc_add_reply(w, 1, 9, h, n[v]);
    return vp_size_add_reply(n[v]);
}

static size_t case_ack(vp_writer *w, int v)
{
    if (v >= 2) return SIZE_MAX;
    vp_enc_ack(w, 1, &(vp_ack){.epoch = (uint64_t)v, .count = (uint32_t)v});
    return vp_size_ack();
}

static vp_view g_views[VP_MAX_VIEWS];

static size_t case_vis_query(vp_writer *w, int v)
{
    uint32_t n[] = {0, 1, VP_MAX_VIEWS};
    if (v >= 3) return SIZE_MAX;
    for (uint32_t i = 0; i < n[v]; i++) g_views[i] = view(i);
    vp_enc_vis_query(w, 1, VP_Q_SUBLEVELS, 0, g_views, n[v]); /* the flag is dropped: no list */
    return vp_size_vis_query(n[v]);
}

static size_t case_vis_query_sub(vp_writer *w, int v)
{
    static uint16_t subs[VP_MAX_QUERY_SUBLEVELS];
    /* flags, views, subs given, count */
    const struct { uint8_t flags; uint32_t n; bool subs; uint32_t nsub; } in[] = {
        {0, 1, false, 0},                 /* no list */
        {0, 1, true, 0},                  /* a list, empty (the decoder refuses it; the size holds) */
        {VP_Q_SUBLEVELS, 2, true, 3},
        {0, VP_MAX_VIEWS, true, VP_MAX_QUERY_SUBLEVELS},
    };
    if (v >= (int)(sizeof in / sizeof in[0])) return SIZE_MAX;
    for (uint32_t i = 0; i < in[v].n; i++) g_views[i] = view(i);
    const uint16_t *s = in[v].subs ? subs : NULL;
    vp_enc_vis_query_sub(w, 1, in[v].flags, 0, g_views, in[v].n, s, in[v].nsub);
    return vp_size_vis_query_sub(in[v].flags, in[v].n, s, in[v].nsub);
}

static size_t case_vis_result(vp_writer *w, int v)
{
    uint32_t n[] = {0, 1, 10000};
    if (v >= 3) return SIZE_MAX;
    vp_enc_vis_result_begin(w, 1, &(vp_vis_result){.count = n[v]});
    for (uint32_t i = 0; i < n[v]; i++) vp_put_vis_rec(w, &(vp_vis_rec){.id = i});
    vp_frame_end(w);
    return vp_size_vis_result(n[v]);
}

static size_t case_stats_reply(vp_writer *w, int v)
{
    if (v >= 2) return SIZE_MAX;
    vp_enc_stats_reply(w, 1, &(vp_stats_reply){.epoch = (uint64_t)v});
    assert_int_equal(vp_size_stats_reply(), VP_HEADER_SIZE + 2 * 8 + 9 * 4 + 5 * 8);
    return vp_size_stats_reply();
}

static size_t case_subscribe(vp_writer *w, int v)
{
    if (v >= 2) return SIZE_MAX;
    vp_enc_subscribe(w, 1, v ? VP_EVENT_SCENE | VP_EVENT_MARKS : 0);
    return vp_size_subscribe();
}

static size_t case_event(vp_writer *w, int v)
{
    if (v >= 2) return SIZE_MAX;
    vp_enc_event(w, &(vp_event){.kind = VP_EVENT_SCENE, .added = (uint32_t)v});
    return vp_size_event();
}

static float g_f[9 * 40000];
static uint32_t g_u[3 * 40000];

static size_t case_mesh(vp_writer *w, int v)
{
    /* v >= 3: the same without normals (VP_MESH_NO_NORMALS) */
    uint32_t nv[] = {0, 3, 40000}, ni[] = {0, 3, 3 * 40000};
    if (v >= 6) return SIZE_MAX;
    bool normals = v < 3;
    vp_enc_mesh(w, 1, 7, g_f, normals ? g_f : NULL, nv[v % 3], g_u, ni[v % 3]);
    return vp_size_mesh(nv[v % 3], ni[v % 3], normals);
}

static size_t case_occluder(vp_writer *w, int v)
{
    uint32_t n[] = {0, 1, 40000};
    double origin[3] = {1, 2, 3};
    if (v >= 3) return SIZE_MAX;
    vp_enc_occluder(w, 1, 5, origin, g_f, n[v]);
    return vp_size_occluder(n[v]);
}

static size_t case_lights(vp_writer *w, int v)
{
    static vp_light l[1000];
    uint32_t n[] = {0, 1, 1000};
    if (v >= 3) return SIZE_MAX;
    vp_enc_lights(w, 1, l, n[v]);
    assert_int_equal(vp_size_lights(1) - vp_size_lights(0), VP_LIGHT_SIZE);
    return vp_size_lights(n[v]);
}

static size_t case_list(vp_writer *w, int v)
{
    if (v >= 2) return SIZE_MAX;
    vp_enc_list(w, 1, &(vp_list){.cursor = (uint64_t)v, .max = 100});
    return vp_size_list();
}

static size_t case_names(vp_writer *w, int v)
{
    /* names of 1, 255 and 300 bytes (cut to 255), with and without ids */
    const char *names[3] = {name_of(0, 1), name_of(1, 255), name_of(2, 300)};
    static const uint16_t ids[3] = {1, 2, 3};
    const struct { uint32_t n; bool ids; } in[] = {{0, false}, {0, true}, {3, false}, {3, true}};
    if (v >= (int)(sizeof in / sizeof in[0])) return SIZE_MAX;
    uint16_t type = in[v].ids ? VP_SUBLEVEL_LIST_REPLY : VP_SUBLEVEL_NAMES;
    vp_enc_names(w, type, 1, names, in[v].ids ? ids : NULL, in[v].n);
    return vp_size_names(names, in[v].ids ? ids : NULL, in[v].n);
}

static size_t case_sublevel_ids(vp_writer *w, int v)
{
    static uint16_t ids[VP_MAX_SUBLEVELS];
    uint32_t n[] = {0, 2, VP_MAX_SUBLEVELS};
    if (v >= 3) return SIZE_MAX;
    vp_enc_sublevel_ids(w, 1, ids, n[v]);
    return vp_size_sublevel_ids(n[v]);
}

static size_t case_list_reply(vp_writer *w, int v)
{
    uint32_t n[] = {0, 1, 2000};
    if (v >= 3) return SIZE_MAX;
    for (uint32_t i = 0; i < n[v]; i++) g_ents[i] = ent(i);
    vp_enc_list_reply(w, 1, 5, 6, g_ents, n[v]);
    return vp_size_list_reply(n[v]);
}

static size_t case_sublevel_begin(vp_writer *w, int v)
{
    uint8_t l[] = {0, 1, 255};
    if (v >= 3) return SIZE_MAX;
    vp_sublevel_begin m = {.classes = 4, .name_len = l[v], .name = (const uint8_t *)name_of(0, 255)};
    vp_enc_sublevel_begin(w, 1, &m);
    return vp_size_sublevel_begin(&m);
}

static size_t case_sublevel_begun(vp_writer *w, int v)
{
    if (v >= 2) return SIZE_MAX;
    vp_enc_sublevel_begun(w, 1, &(vp_sublevel_begun){.id = (uint16_t)v, .epoch = 3});
    return vp_size_sublevel_begun();
}

static size_t case_sublevel_name(vp_writer *w, int v)
{
    size_t l[] = {0, 1, 255, 300};
    if (v >= 4) return SIZE_MAX;
    const char *name = name_of(3, l[v]);
    vp_enc_sublevel_name(w, VP_SUBLEVEL_UNLOAD, 1, name);
    return vp_size_sublevel_name(name);
}

static size_t case_sublevel_infos(vp_writer *w, int v)
{
    static vp_sublevel_info in[300];
    uint32_t n[] = {0, 1, 300};
    if (v >= 3) return SIZE_MAX;
    for (uint32_t i = 0; i < n[v]; i++)
        in[i] = (vp_sublevel_info){.id = (uint16_t)i, .name_len = (uint8_t)(i % 256),
                                   .name = (const uint8_t *)name_of(0, 255)};
    vp_enc_sublevel_infos_begin(w, 1, 5, n[v]);
    for (uint32_t i = 0; i < n[v]; i++) vp_put_sublevel_info(w, &in[i]);
    vp_frame_end(w);
    return vp_size_sublevel_infos(in, n[v]);
}

static size_t case_destroy(vp_writer *w, int v)
{
    if (v >= 2) return SIZE_MAX;
    vp_enc_destroy(w, 1, &(vp_destroy){.id = 1, .debris = v ? VP_MAX_DEBRIS : 0, .radius = 1});
    assert_int_equal(vp_size_destroy(), VP_HEADER_SIZE + VP_DESTROY_SIZE);
    return vp_size_destroy();
}

static size_t case_destroyed(vp_writer *w, int v)
{
    if (v >= 2) return SIZE_MAX;
    vp_enc_destroyed(w, 1, &(vp_destroyed){.epoch = (uint64_t)v});
    assert_int_equal(vp_size_destroyed(), VP_HEADER_SIZE + 24);
    return vp_size_destroyed();
}

static size_t case_mark(vp_writer *w, int v)
{
    if (v >= 2) return SIZE_MAX;
    vp_enc_mark(w, 1, &(vp_mark){.entity = (uint64_t)v, .ttl_ms = 1});
    assert_int_equal(vp_size_mark(), VP_HEADER_SIZE + VP_MARK_SIZE);
    return vp_size_mark();
}

static size_t case_marked(vp_writer *w, int v)
{
    if (v >= 2) return SIZE_MAX;
    vp_enc_marked(w, &(vp_marked){.client_id = (uint32_t)v, .m = {.ttl_ms = 1}});
    assert_int_equal(vp_size_marked(), VP_HEADER_SIZE + VP_MARKED_SIZE);
    return vp_size_marked();
}

static size_t case_metrics_reply(vp_writer *w, int v)
{
    static uint8_t text[1 << 20];
    uint32_t n[] = {0, 5, sizeof text};
    if (v >= 3) return SIZE_MAX;
    vp_enc_metrics_reply(w, 1, &(vp_metrics_reply){.text_len = n[v], .text = text});
    return vp_size_metrics_reply(n[v]);
}

static size_t case_render(vp_writer *w, int v)
{
    if (v >= 2) return SIZE_MAX;
    vp_render m = {.view = view(0), .format = (uint8_t)v, .quality = v ? 90 : 0, .nhighlight = (uint8_t)(v * 8)};
    for (uint32_t i = 0; i < m.nhighlight; i++) m.highlight[i] = i + 1;
    vp_enc_render(w, 1, &m);
    /* the 8 tail bytes, the count and its pad (8), the 8 ids */
    assert_int_equal(vp_size_render(), VP_HEADER_SIZE + VP_VIEW_SIZE + 8 + 8 + 64);
    return vp_size_render();
}

static size_t case_light_query(vp_writer *w, int v)
{
    if (v >= 2) return SIZE_MAX;
    vp_enc_light_query(w, 1, &(vp_light_query){.view = view(0), .flags = (uint8_t)v});
    assert_int_equal(vp_size_light_query(), VP_HEADER_SIZE + VP_VIEW_SIZE + 4);
    return vp_size_light_query();
}

static size_t case_light_tiles(vp_writer *w, int v)
{
    /* tiles x, y, ids */
    const uint16_t tx[] = {0, 2, 256}, ty[] = {0, 1, 144};
    const uint32_t ids[] = {0, 3, 100000};
    if (v >= 3) return SIZE_MAX;
    uint32_t tiles = (uint32_t)tx[v] * ty[v];
    vp_enc_light_tiles_begin(w, 1, &(vp_light_tiles){.tiles_x = tx[v], .tiles_y = ty[v], .tile = 16, .count = ids[v]});
    for (uint32_t t = 0; t <= tiles; t++) vp_put_u32(w, t == tiles ? ids[v] : 0);
    for (uint32_t k = 0; k < ids[v]; k++) vp_put_u64(w, k);
    vp_frame_end(w);
    return vp_size_light_tiles(tiles, ids[v]);
}

static size_t case_frame_sub(vp_writer *w, int v)
{
    if (v >= 2) return SIZE_MAX;
    vp_enc_frame_sub(w, 1, &(vp_frame_sub){.r = {.view = view(0)}, .max_fps = v ? VP_FRAME_SUB_MAX_FPS : 1});
    assert_int_equal(vp_size_frame_sub(), VP_HEADER_SIZE + VP_VIEW_SIZE + 80 + 4);
    return vp_size_frame_sub();
}

static size_t case_frame(vp_writer *w, int v)
{
    static uint8_t data[64 * 32 * 20];
    /* data given, or drawn in place (NULL: the bytes are already there) */
    const struct { uint32_t len; bool in_place; } in[] = {{0, false}, {3, false}, {sizeof data, false},
                                                           {sizeof data, true}};
    if (v >= (int)(sizeof in / sizeof in[0])) return SIZE_MAX;
    vp_enc_frame(w, 1, &(vp_frame){.width = 64, .height = 32, .data_len = in[v].len,
                                   .data = in[v].in_place ? NULL : data});
    return vp_size_frame(in[v].len);
}

/* mesh with UVs and tangents: normals, uvs, tangents each on or off
 * (tangents only with uvs), over 0, 3 and 40000 vertices */
static size_t case_mesh_uv(vp_writer *w, int v)
{
    uint32_t nv[] = {0, 3, 40000}, ni[] = {0, 3, 3 * 40000};
    if (v >= 3 * 6) return SIZE_MAX;
    int shape = v / 3; /* normals x {none, uvs, uvs + tangents} */
    bool normals = shape % 2, uvs = shape / 2 >= 1, tan = shape / 2 == 2;
    uint32_t n = nv[v % 3];
    vp_enc_mesh_uv(w, 1, 7, g_f, normals ? g_f : NULL, uvs ? g_f : NULL, tan ? g_f : NULL, n, g_u, ni[v % 3]);
    size_t size = vp_size_mesh_uv(n, ni[v % 3], normals, uvs, tan);
    /* PROTOCOL.md: 12 + per vertex 12 (+12 normals, +8 uvs, +16 tangents) + 4 per index */
    size_t per_vertex = 12 + (normals ? 12 : 0) + (uvs ? 8 : 0) + (tan ? 16 : 0);
    assert_int_equal(size, VP_HEADER_SIZE + 12 + (size_t)n * per_vertex + 4 * (size_t)ni[v % 3]);
    return size;
}

static size_t case_occluder_flags(vp_writer *w, int v)
{
    uint32_t n[] = {0, 1, 40000};
    double origin[3] = {1, 2, 3};
    if (v >= 3) return SIZE_MAX;
    vp_enc_occluder_flags(w, 1, 5, VP_OCC_ATTACHED, origin, g_f, n[v]);
    assert_int_equal(vp_size_occluder(n[v]), VP_HEADER_SIZE + 40 + 36 * (size_t)n[v]);
    return vp_size_occluder(n[v]);
}

static vp_transform g_xf[3000];

static size_t case_transforms(vp_writer *w, int v)
{
    uint32_t n[] = {0, 1, 3000};
    if (v >= 3) return SIZE_MAX;
    for (uint32_t i = 0; i < n[v]; i++) g_xf[i] = (vp_transform){.id = i, .rot = {0, 0, 0, 1}, .scale = {1, 1, 1}};
    vp_enc_transforms(w, 1, g_xf, n[v]);
    assert_int_equal(vp_size_transforms(n[v]), VP_HEADER_SIZE + 4 + 64 * (size_t)n[v]);
    return vp_size_transforms(n[v]);
}

static vp_material g_mat[2000];

static size_t case_materials(vp_writer *w, int v)
{
    uint32_t n[] = {0, 1, 2000};
    if (v >= 3) return SIZE_MAX;
    for (uint32_t i = 0; i < n[v]; i++) g_mat[i] = (vp_material){.id = i + 1, .roughness = 0.5f};
    vp_enc_materials(w, 1, g_mat, n[v]);
    assert_int_equal(vp_size_materials(n[v]), VP_HEADER_SIZE + 4 + 188 * (size_t)n[v]);
    return vp_size_materials(n[v]);
}

static size_t case_texture_put(vp_writer *w, int v)
{
    static uint8_t data[1 << 20];
    uint32_t len[] = {0, 1, sizeof data};
    if (v >= 3) return SIZE_MAX;
    vp_enc_texture_put(w, 1, &(vp_texture_put){.id = 3, .total = sizeof data, .len = len[v], .data = data});
    assert_int_equal(vp_size_texture_put(len[v]), VP_HEADER_SIZE + 16 + (size_t)len[v]);
    return vp_size_texture_put(len[v]);
}

static size_t case_env(vp_writer *w, int v)
{
    static const uint16_t types[] = {VP_ENV_SET, VP_ENV_REPLY, VP_ENV_SET};
    if (v >= 3) return SIZE_MAX;
    vp_env e;
    vp_env_default(&e);
    if (v == 2) e = (vp_env){0};
    vp_enc_env(w, types[v], 1, &e);
    assert_int_equal(vp_size_env(), VP_HEADER_SIZE + 120);
    return vp_size_env();
}

/* read-back (vp_readback.c) */
static size_t case_mesh_get(vp_writer *w, int v)
{
    if (v >= 2) return SIZE_MAX;
    vp_enc_mesh_get(w, 1, &(vp_mesh_get){.class_id = (uint16_t)(v ? 65535 : 7)});
    assert_int_equal(vp_size_mesh_get(), VP_HEADER_SIZE + 2);
    return vp_size_mesh_get();
}

static size_t case_material_list(vp_writer *w, int v)
{
    if (v >= 2) return SIZE_MAX;
    vp_enc_material_list(w, 1, &(vp_page){.cursor = (uint32_t)v, .max = 100});
    assert_int_equal(vp_size_material_list(), VP_HEADER_SIZE + 8);
    return vp_size_material_list();
}

static size_t case_material_list_reply(vp_writer *w, int v)
{
    static const vp_material m[3] = {{.id = 1}, {.id = 2}, {.id = 9}};
    if (v >= 4) return SIZE_MAX;
    vp_enc_material_list_reply(w, 1, (uint32_t)v, m, (uint32_t)v);
    assert_int_equal(vp_size_material_list_reply(1) - vp_size_material_list_reply(0), VP_MATERIAL_SIZE);
    return vp_size_material_list_reply((uint32_t)v);
}

static size_t case_texture_get(vp_writer *w, int v)
{
    if (v >= 2) return SIZE_MAX;
    vp_enc_texture_get(w, 1, &(vp_texture_get){.id = 1, .offset = (uint32_t)v, .max_len = 1000});
    assert_int_equal(vp_size_texture_get(), VP_HEADER_SIZE + 12);
    return vp_size_texture_get();
}

static size_t case_light_list(vp_writer *w, int v)
{
    if (v >= 2) return SIZE_MAX;
    vp_enc_light_list(w, 1, &(vp_page){.cursor = (uint64_t)v, .max = 10});
    assert_int_equal(vp_size_light_list(), VP_HEADER_SIZE + 12);
    return vp_size_light_list();
}

static size_t case_select(vp_writer *w, int v)
{
    static const uint64_t ids[3] = {1, 2, 3};
    if (v >= 4) return SIZE_MAX;
    vp_enc_select(w, 1, ids, (uint32_t)v);
    assert_int_equal(vp_size_select(1) - vp_size_select(0), 8);
    return vp_size_select((uint32_t)v);
}

static size_t case_selected(vp_writer *w, int v)
{
    static const uint64_t ids[3] = {1, 2, 3};
    if (v >= 4) return SIZE_MAX;
    vp_enc_selected(w, &(vp_selected){.client_id = 1, .count = (uint32_t)v, .serial = 2}, ids);
    assert_int_equal(vp_size_selected(0), VP_HEADER_SIZE + VP_SELECTED_HEAD);
    return vp_size_selected((uint32_t)v);
}

static size_t case_light_list_reply(vp_writer *w, int v)
{
    static const vp_light l[2] = {{.id = 1, .range = 1}, {.id = 2, .range = 1}};
    if (v >= 3) return SIZE_MAX;
    vp_enc_light_list_reply(w, 1, (uint64_t)v, l, (uint32_t)v);
    assert_int_equal(vp_size_light_list_reply(1) - vp_size_light_list_reply(0), VP_LIGHT_SIZE);
    return vp_size_light_list_reply((uint32_t)v);
}

#define SIZE_CASES(X)                                                                                      \
    X(hello) X(hello_ok) X(error) X(ping) X(empty) X(entities) X(ids) X(add_reply) X(ack) X(vis_query)     \
    X(vis_query_sub) X(vis_result) X(stats_reply) X(subscribe) X(event) X(mesh) X(occluder) X(lights)      \
    X(list) X(names) X(sublevel_ids) X(list_reply) X(sublevel_begin) X(sublevel_begun) X(sublevel_name)   \
    X(sublevel_infos) X(destroy) X(destroyed) X(mark) X(marked) X(metrics_reply) X(render) X(light_query) \
    X(light_tiles) X(frame_sub) X(frame) X(mesh_uv) X(occluder_flags) X(transforms) X(materials)  \
    X(texture_put) X(env) X(mesh_get) X(material_list) X(material_list_reply) X(texture_get) X(light_list)  \
    X(light_list_reply) X(select) X(selected)

#define SIZE_TEST(name)                                                                                    \
    static void test_size_##name(void **state)                                                             \
    {                                                                                                      \
        (void)state;                                                                                       \
        check_case(case_##name);                                                                           \
    }
SIZE_CASES(SIZE_TEST)

#define SIZE_ROW(name) cmocka_unit_test(test_size_##name),
const struct CMUnitTest protocol_size_tests[] = {SIZE_CASES(SIZE_ROW)};
const size_t protocol_size_tests_count = sizeof protocol_size_tests / sizeof protocol_size_tests[0];
