/*
 * gen_corpus.c — writes the seed corpus for fuzz_protocol with the
 * protocol's own encoders: one valid frame per message type, a few
 * multi-frame streams, and a few deliberately broken inputs (each breaks one
 * rule, so the fuzzer starts next to every rejection path).
 *
 *   fuzz_gen_corpus DIR      (make fuzz-corpus: DIR = tests/fuzz/corpus/protocol)
 *
 * Output is deterministic; file names are seed-*.bin so they never collide
 * with the hash-named files libFuzzer merges in.
 */
#include "protocol.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static uint8_t g_buf[1 << 16];
static vp_writer g_w;
static const char *g_dir;
static unsigned g_files;

static void reset(void) { vp_writer_init(&g_w, g_buf, sizeof g_buf); }

static void save_bytes(const char *name, const uint8_t *p, size_t n)
{
    char path[4096];
    snprintf(path, sizeof path, "%s/seed-%s.bin", g_dir, name);
    FILE *f = fopen(path, "wb");
    if (!f || (n && fwrite(p, 1, n, f) != n) || fclose(f) != 0) {
        fprintf(stderr, "gen_corpus: cannot write %s\n", path);
        exit(1);
    }
    g_files++;
}

/* Writes everything encoded since reset() and resets. */
static void save(const char *name)
{
    if (g_w.overflow) {
        fprintf(stderr, "gen_corpus: %s overflowed\n", name);
        exit(1);
    }
    save_bytes(name, g_buf, g_w.len);
    reset();
}

/* Payload byte off of the frame that starts at frame_start. */
static uint8_t *payload_at(size_t frame_start, size_t off) { return g_buf + frame_start + VP_HEADER_SIZE + off; }

static void patch32(uint8_t *p, uint32_t v)
{
    for (int i = 0; i < 4; i++) p[i] = (uint8_t)(v >> (8 * i));
}

/* ---- sample messages --------------------------------------------------------------- */

static vp_entity entity(uint32_t i)
{
    vp_entity e;
    memset(&e, 0, sizeof e);
    e.id = 1000 + i;
    e.handle = i ? (i << 22) | i : 0;
    e.class_id = (uint16_t)(i % 4);
    e.sublevel = (uint16_t)(i / 2);
    e.flags = i & VP_ENT_DYNAMIC;
    e.sphere[0] = 10.0 * i;
    e.sphere[1] = -5.0;
    e.sphere[2] = 2.5 * i;
    e.sphere[3] = i % 2 ? 0.0 : 1.5; /* r = 0: derive from the AABB */
    if (i % 3 != 1)
        for (int k = 0; k < 3; k++) {
            e.aabb[k] = e.sphere[k] - 1.0;
            e.aabb[3 + k] = e.sphere[k] + 1.0;
        }
    return e;
}

static vp_view view(uint32_t i)
{
    vp_view v;
    memset(&v, 0, sizeof v);
    v.origin[0] = 100.0 * i;
    v.origin[1] = 1.8;
    v.origin[2] = -50.0;
    /* a plain perspective matrix (column-major) */
    double f = 1.0 / tan(0.5 * 1.0471975511965976), aspect = 16.0 / 9.0, n = 0.1, fa = 1000.0;
    v.view_proj[0] = f / aspect;
    v.view_proj[5] = f;
    v.view_proj[10] = (fa + n) / (n - fa);
    v.view_proj[11] = -1.0;
    v.view_proj[14] = 2.0 * fa * n / (n - fa);
    v.depth_mode = (uint8_t)(i % 3);
    v.viewport_w = i % 2 ? 0 : 1920;
    v.viewport_h = i % 2 ? 0 : 1080;
    return v;
}

static vp_light light(uint32_t i)
{
    vp_light l;
    memset(&l, 0, sizeof l);
    l.id = 500 + i;
    l.kind = (uint8_t)(i % 2 ? VP_LIGHT_SPOT : VP_LIGHT_POINT);
    l.pos[0] = 3.0 * i;
    l.pos[1] = 4.0;
    l.pos[2] = -1.0;
    l.dir[1] = -1.0f;
    l.color[0] = 1.0f;
    l.color[1] = 0.9f;
    l.color[2] = 0.8f;
    l.intensity = 800.0f;
    l.range = 25.0f;
    l.inner_cos = 0.95f;
    l.outer_cos = 0.8f;
    return l;
}

static const vp_hello hello_msg = {.magic = VP_MAGIC, .version = VP_VERSION, .role = VP_ROLE_EDITOR,
                                   .token_len = 6, .token = (const uint8_t *)"tok3n!", .name_len = 7,
                                   .name = (const uint8_t *)"fuzzcli"};

static void enc_hello(uint32_t req) { vp_enc_hello(&g_w, req, &hello_msg); }

static void enc_hello_ok(uint32_t req)
{
    vp_hello_ok m = {.version = VP_VERSION, .role = VP_ROLE_EDITOR, .max_payload = 1u << 24, .max_batch = 4096,
                     .max_views = VP_MAX_VIEWS, .epoch = 7, .client_id = 3};
    vp_enc_hello_ok(&g_w, req, &m);
}

static void enc_entities(uint16_t type, uint32_t req, uint32_t n)
{
    vp_entity e[8];
    for (uint32_t i = 0; i < n; i++) e[i] = entity(i);
    vp_enc_entities(&g_w, type, req, e, n);
}

static void enc_ids(uint16_t type, uint32_t req, uint32_t n)
{
    uint64_t ids[8];
    for (uint32_t i = 0; i < n; i++) ids[i] = 1000 + 2 * i;
    vp_enc_ids(&g_w, type, req, ids, n);
}

static void enc_vis_query(uint32_t req, uint8_t flags, uint32_t n)
{
    vp_view v[VP_MAX_VIEWS];
    for (uint32_t i = 0; i < n; i++) v[i] = view(i);
    vp_enc_vis_query(&g_w, req, flags, 0.5f, v, n);
}

static void enc_vis_result(uint32_t req, uint32_t n)
{
    vp_vis_result m;
    memset(&m, 0, sizeof m);
    m.epoch = 9;
    m.tested = 40;
    m.visible = n;
    for (uint32_t i = 0; i < VP_STAGES; i++) m.stage_ns[i] = 1000 * (i + 1);
    m.count = n;
    vp_enc_vis_result_begin(&g_w, req, &m);
    for (uint32_t i = 0; i < n; i++) {
        vp_vis_rec r = {.id = 1000 + i, .handle = (1u << 22) | i, .view_mask = 1u | (i << 1),
                        .class_id = (uint16_t)i, .sublevel = 0, .area = i ? 12.5f * (float)i : -1.0f};
        vp_put_vis_rec(&g_w, &r);
    }
    vp_frame_end(&g_w);
}

static void enc_mesh(uint32_t req)
{
    /* a tetrahedron */
    static const float pos[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
    static const float nrm[] = {-0.577f, -0.577f, -0.577f, 1, 0, 0, 0, 1, 0, 0, 0, 1};
    static const uint32_t idx[] = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
    vp_enc_mesh(&g_w, req, 2, pos, nrm, 4, idx, 12);
}

static void enc_occluder(uint32_t req)
{
    static const double origin[3] = {10, 0, -4};
    static const float verts[] = {0, 0, 0, 4, 0, 0, 4, 3, 0, 0, 0, 0, 4, 3, 0, 0, 3, 0};
    vp_enc_occluder(&g_w, req, 77, origin, verts, 2);
}

static void enc_lights(uint32_t req, uint32_t n)
{
    vp_light l[4];
    for (uint32_t i = 0; i < n; i++) l[i] = light(i);
    vp_enc_lights(&g_w, req, l, n);
}

static void enc_stats_reply(uint32_t req)
{
    vp_stats_reply m = {.epoch = 12, .uptime_ms = 123456, .entities = 40, .static_entities = 30,
                        .dynamic_entities = 10, .regions = 2, .cells = 64, .connections = 1, .meshes = 3,
                        .occluders = 1, .lights = 2, .queries = 99, .edits = 50, .bytes_in = 4096,
                        .bytes_out = 8192, .errors = 1};
    vp_enc_stats_reply(&g_w, req, &m);
}

static void enc_list_reply(uint32_t req, uint32_t n)
{
    vp_entity e[4];
    for (uint32_t i = 0; i < n; i++) e[i] = entity(i + 1);
    vp_enc_list_reply(&g_w, req, n ? 1003 : 0, 8, e, n);
}

/* ---- version 2: the scene model --------------------------------------------------- */

/* A placed mesh (VP_ENT_TRANSFORM): entity(i) with a material and a
 * transform, a quarter turn about +Y, scale 2 x 1 x 0.5. */
static vp_entity placed(uint32_t i)
{
    vp_entity e = entity(i);
    e.flags |= VP_ENT_TRANSFORM;
    e.material = 1 + i % 3;
    e.pos[0] = 12.5 * i;
    e.pos[2] = -4e6; /* far from the origin: f64 positions */
    e.rot[1] = 0.70710678f;
    e.rot[3] = 0.70710678f;
    e.scale[0] = 2;
    e.scale[1] = 1;
    e.scale[2] = i % 2 ? -0.5f : 0.5f; /* mirrored on odd ones */
    memset(e.sphere, 0, sizeof e.sphere);
    memset(e.aabb, 0, sizeof e.aabb);
    return e;
}

static vp_material material(uint32_t i)
{
    vp_material m = {.id = 1 + i, .flags = i % 2 ? VP_MAT_DOUBLE_SIDED : 0, .alpha_mode = (uint8_t)(i % 2),
                     .alpha_cutoff = 0.5f, .base_color = {0.8f, 0.2f, 0.1f, 1}, .metallic = 0.1f * i,
                     .roughness = 0.6f, .emissive = {1, 0.9f, 0.5f}, .emissive_strength = i ? 40.0f : 0,
                     .normal_scale = 1};
    for (int k = 0; k < VP_TEX_SLOTS; k++)
        m.tex[k] = (vp_texref){.texture = i ? (uint32_t)(10 + k) : 0, .wrap_s = (uint8_t)(k % 3),
                               .wrap_t = VP_WRAP_REPEAT, .min_filter = VP_FILTER_LINEAR_MIP_LINEAR,
                               .mag_filter = VP_FILTER_LINEAR, .offset = {0.25f, 0}, .scale = {2, 2},
                               .rotation = 0.5f};
    return m;
}

/* Version 1's 104-byte entity records, written by hand (no encoder
 * writes them any more): what a journal of a version 1 daemon holds. */
static void enc_entities_v1(uint16_t type, uint32_t req, uint32_t n)
{
    vp_frame_begin(&g_w, type, req);
    vp_put_u32(&g_w, n);
    for (uint32_t i = 0; i < n; i++) {
        vp_entity e = entity(i);
        vp_put_u64(&g_w, e.id), vp_put_u32(&g_w, e.handle), vp_put_u16(&g_w, e.class_id);
        vp_put_u16(&g_w, e.sublevel), vp_put_u32(&g_w, e.flags), vp_put_u32(&g_w, 0);
        for (int k = 0; k < 4; k++) vp_put_f64(&g_w, e.sphere[k]);
        for (int k = 0; k < 6; k++) vp_put_f64(&g_w, e.aabb[k]);
    }
    vp_frame_end(&g_w);
}

/* an editor's version 2 session: texture, material, placed entities, moves, environment */
static void seeds_v2_stream(void)
{
    static const uint8_t img[8] = {0xff, 0xd8, 0xff, 0xe0, 0, 0, 0, 0};
    vp_material m = material(1);
    vp_entity e[2] = {placed(0), placed(1)};
    vp_transform t = {.id = e[0].id, .rot = {0, 0, 0, 1}, .scale = {1, 1, 1}};
    vp_env env;
    vp_env_default(&env);
    vp_enc_texture_put(&g_w, 2, &(vp_texture_put){.id = 10, .format = VP_TEX_JPEG, .total = 8, .len = 8, .data = img});
    vp_enc_materials(&g_w, 3, &m, 1);
    vp_enc_entities(&g_w, VP_ENTITY_ADD, 4, e, 2);
    vp_enc_transforms(&g_w, 5, &t, 1);
    vp_enc_env(&g_w, VP_ENV_SET, 6, &env);
    vp_enc_empty(&g_w, VP_ENV_GET, 7);
    save("stream_scene_session");
}

static void seeds_v2(void)
{
    size_t at;
    {
        vp_entity e[3] = {placed(0), placed(1), entity(2)}; /* two placed, one bounds entity */
        vp_enc_entities(&g_w, VP_ENTITY_ADD, 40, e, 3), save("entity_add_placed");
        e[0].rot[3] = 0.7075f; /* off unit by 4e-4: renormalised */
        vp_enc_entities(&g_w, VP_ENTITY_UPDATE, 41, e, 3), save("entity_update_renormalised");
        e[0].rot[3] = 1.01f;
        vp_enc_entities(&g_w, VP_ENTITY_ADD, 42, e, 3), save("bad_entity_quaternion");
        e[0] = placed(0);
        e[1].scale[0] = e[1].scale[1] = 0;
        vp_enc_entities(&g_w, VP_ENTITY_ADD, 42, e, 3), save("bad_entity_scale_zero");
        vp_enc_list_reply(&g_w, 43, 0, 9, e, 1), save("entity_list_reply_placed");
    }
    {
        vp_transform t[3];
        for (uint32_t i = 0; i < 3; i++) {
            vp_entity e = placed(i);
            t[i] = (vp_transform){.id = e.id, .handle = e.handle, .pos = {e.pos[0], 1, e.pos[2]}};
            memcpy(t[i].rot, e.rot, sizeof t[i].rot);
            memcpy(t[i].scale, e.scale, sizeof t[i].scale);
        }
        vp_enc_transforms(&g_w, 44, t, 3), save("transform_set");
        t[2].rot[0] = 0.001f; /* within tolerance */
        vp_enc_transforms(&g_w, 44, t, 3), save("transform_set_renormalised");
        t[1].pos[1] = NAN;
        vp_enc_transforms(&g_w, 45, t, 3), save("bad_transform_nan");
    }
    {
        vp_material m[3] = {material(0), material(1), material(2)};
        vp_enc_materials(&g_w, 46, m, 3), save("material_put");
        m[1].roughness = 2;
        vp_enc_materials(&g_w, 47, m, 3), save("bad_material_roughness");
        m[1] = material(1);
        m[2].tex[VP_TEX_NORMAL].wrap_t = 7;
        vp_enc_materials(&g_w, 47, m, 3), save("bad_material_wrap");
        at = g_w.len, vp_enc_materials(&g_w, 47, m, 1), *payload_at(at, 4 + 60 + 32 + 29) = 1,
            save("bad_material_slot_pad");
        static const uint64_t ids[] = {1, 2};
        vp_enc_ids(&g_w, VP_MATERIAL_REMOVE, 48, ids, 2), save("material_remove");
        vp_enc_ids(&g_w, VP_TEXTURE_REMOVE, 48, ids, 1), save("texture_remove");
    }
    {
        /* a 1 x 1 PNG, whole and in two chunks */
        static const uint8_t png[] = {0x89, 'P',  'N',  'G',  0x0d, 0x0a, 0x1a, 0x0a, 0,    0,    0,    0x0d, 'I',
                                      'H',  'D',  'R',  0,    0,    0,    1,    0,    0,    0,    1,    8,    6,
                                      0,    0,    0,    0x1f, 0x15, 0xc4, 0x89, 0,    0,    0,    0x0d, 'I',  'D',
                                      'A',  'T',  0x78, 0x9c, 0x63, 0xf8, 0xcf, 0xc0, 0xf0, 0x1f, 0,    5,    0,
                                      1,    0xff, 0x56, 0xc7, 0x2f, 0x0d, 0,    0,    0,    0,    'I',  'E',  'N',
                                      'D',  0xae, 0x42, 0x60, 0x82};
        vp_texture_put x = {.id = 10, .format = VP_TEX_PNG, .flags = VP_TEX_SRGB, .total = sizeof png,
                            .len = sizeof png, .data = png};
        vp_enc_texture_put(&g_w, 49, &x), save("texture_put_whole");
        x.len = 20;
        vp_enc_texture_put(&g_w, 50, &x);
        x.offset = 20, x.len = sizeof png - 20, x.data = png + 20;
        vp_enc_texture_put(&g_w, 51, &x), save("texture_put_chunks");
        x.offset = sizeof png - 2, x.len = 5;
        vp_enc_texture_put(&g_w, 52, &x), save("bad_texture_chunk_past_total");
        x = (vp_texture_put){.id = 11, .format = 3, .total = 4, .len = 4, .data = png};
        vp_enc_texture_put(&g_w, 52, &x), save("bad_texture_format");
    }
    {
        vp_env e;
        vp_env_default(&e);
        vp_enc_env(&g_w, VP_ENV_SET, 53, &e), save("env_set");
        vp_enc_empty(&g_w, VP_ENV_GET, 54), save("env_get");
        e.sky_mode = VP_SKY_TEXTURE, e.sky_texture = 12, e.exposure_mode = VP_EXPOSURE_FIXED;
        vp_enc_env(&g_w, VP_ENV_REPLY, 54, &e), save("env_reply_texture_sky");
        e.sky_texture = 0;
        vp_enc_env(&g_w, VP_ENV_SET, 55, &e), save("bad_env_sky_texture_0");
        vp_env_default(&e);
        e.sun_dir[1] *= 1.5f;
        vp_enc_env(&g_w, VP_ENV_SET, 55, &e), save("bad_env_sun_not_unit");
    }
    {
        /* a quad with UVs, and with UVs and tangents */
        static const float pos[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
        static const float nrm[] = {0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1};
        static const float uv[] = {0, 1, 1, 1, 1, 0, 0, 0};
        static const float tan[] = {1, 0, 0, 1, 1, 0, 0, 1, 1, 0, 0, 1, 1, 0, 0, -1};
        static const uint32_t idx[] = {0, 1, 2, 0, 2, 3};
        vp_enc_mesh_uv(&g_w, 56, 5, pos, nrm, uv, NULL, 4, idx, 6), save("mesh_put_uvs");
        vp_enc_mesh_uv(&g_w, 56, 5, pos, nrm, uv, tan, 4, idx, 6), save("mesh_put_uvs_tangents");
        vp_enc_mesh_uv(&g_w, 56, 5, pos, NULL, uv, tan, 4, idx, 6), save("mesh_put_flat_uvs_tangents");
        at = g_w.len, vp_enc_mesh_uv(&g_w, 57, 5, pos, nrm, uv, tan, 4, idx, 6), *payload_at(at, 2) = VP_MESH_TANGENTS,
            save("bad_mesh_tangents_without_uvs");
    }
    {
        static const double origin[3] = {0, 0, 0};
        static const float verts[] = {-1, 0, -1, 1, 0, -1, 1, 2, -1};
        vp_enc_occluder_flags(&g_w, 58, placed(0).id, VP_OCC_ATTACHED, origin, verts, 1), save("occluder_attached");
        vp_enc_occluder_flags(&g_w, 58, 3, 2, origin, verts, 1), save("bad_occluder_flags");
    }
    enc_entities_v1(VP_ENTITY_ADD, 59, 3), save("entity_add_v1");
    at = g_w.len, enc_entities_v1(VP_ENTITY_ADD, 59, 2), *payload_at(at, 4 + 16) = 2, save("bad_entity_v1_flags");
    {
        /* version 1's OCCLUDER_PUT: no flags word */
        vp_frame_begin(&g_w, VP_OCCLUDER_PUT, 60);
        vp_put_u64(&g_w, 77), vp_put_f64(&g_w, 10), vp_put_f64(&g_w, 0), vp_put_f64(&g_w, -4), vp_put_u32(&g_w, 1);
        static const float tri[9] = {0, 0, 0, 4, 0, 0, 4, 3, 0};
        for (int k = 0; k < 9; k++) vp_put_f32(&g_w, tri[k]);
        vp_frame_end(&g_w), save("occluder_put_v1");
    }
    enc_hello(1), seeds_v2_stream();
}


int main(int argc, char **argv)
{
    if (argc != 2) {
        fprintf(stderr, "usage: %s DIR\n", argv[0]);
        return 2;
    }
    g_dir = argv[1];
    reset();
    static const uint8_t ping_data[] = "ping payload \x00\x01\x02\xff";
    const vp_ack ack = {.epoch = 8, .count = 3};
    const vp_event ev = {.kind = VP_EVENT_SCENE, .epoch = 8, .added = 3, .updated = 2, .removed = 1};
    const vp_list list = {.cursor = 0, .max = 100};

    /* ---- one valid frame per message type ---- */
    enc_hello(1), save("hello");
    enc_hello_ok(1), save("hello_ok");
    vp_enc_error(&g_w, 4, VP_ERR_STALE, 2, "entity 2: stale handle"), save("error");
    vp_enc_ping(&g_w, VP_PING, 5, ping_data, sizeof ping_data), save("ping");
    vp_enc_ping(&g_w, VP_PONG, 5, ping_data, sizeof ping_data), save("pong");
    vp_enc_empty(&g_w, VP_STATS, 6), save("stats");
    enc_stats_reply(6), save("stats_reply");
    vp_enc_subscribe(&g_w, 7, VP_EVENT_SCENE), save("subscribe");
    vp_enc_event(&g_w, &ev), save("event");
    vp_enc_ack(&g_w, 8, &ack), save("ack");
    enc_entities(VP_ENTITY_ADD, 10, 3), save("entity_add");
    {
        const uint32_t handles[] = {(1u << 22) | 1, (1u << 22) | 2, (2u << 22) | 3};
        vp_enc_add_reply(&g_w, 10, 8, handles, 3), save("entity_add_reply");
    }
    enc_entities(VP_ENTITY_UPDATE, 11, 2), save("entity_update");
    enc_ids(VP_ENTITY_REMOVE, 12, 2), save("entity_remove");
    vp_enc_list(&g_w, 13, &list), save("entity_list");
    enc_list_reply(13, 2), save("entity_list_reply");
    enc_mesh(14), save("mesh_put");
    enc_occluder(15), save("occluder_put");
    enc_ids(VP_OCCLUDER_REMOVE, 16, 1), save("occluder_remove");
    enc_lights(17, 2), save("light_put");
    enc_ids(VP_LIGHT_REMOVE, 18, 2), save("light_remove");
    enc_vis_query(19, VP_Q_WANT_AREA, 2), save("vis_query");
    enc_vis_result(19, 3), save("vis_result");

    /* a few edge shapes of valid messages */
    enc_vis_query(20, VP_Q_COUNT_ONLY | VP_Q_STATIC_ONLY, VP_MAX_VIEWS), save("vis_query_32_views");
    {
        vp_render rm = {.view = view(0), .format = VP_FRAME_JPEG, .quality = 85, .exposure_ev = -1,
                        .nhighlight = 2, .highlight = {42, 7}}; /* outlined: a selection */
        vp_enc_render(&g_w, 21, &rm), save("render_jpeg");
        rm.format = VP_FRAME_RAW;
        rm.quality = 0;
        rm.flags = VP_RENDER_NO_OCCLUSION;
        vp_enc_render(&g_w, 22, &rm), save("render_raw");
        rm.renderer = VP_RENDERER_GL;
        vp_enc_frame_sub(&g_w, 23, &(vp_frame_sub){.r = rm, .max_fps = 30}), save("frame_subscribe");
        vp_enc_empty(&g_w, VP_FRAME_UNSUBSCRIBE, 24), save("frame_unsubscribe");
        vp_enc_light_query(&g_w, 25, &(vp_light_query){.view = view(0)}), save("light_query");
        vp_enc_light_query(&g_w, 26, &(vp_light_query){.view = view(0), .flags = VP_LQ_NO_DEPTH}),
            save("light_query_no_depth");
        vp_enc_light_tiles_begin(&g_w, 25, &(vp_light_tiles){.epoch = 9, .tiles_x = 2, .tiles_y = 1, .tile = 16,
                                                             .in_view = 2, .max_per_tile = 2, .count = 3});
        vp_put_u32(&g_w, 0), vp_put_u32(&g_w, 2), vp_put_u32(&g_w, 3);
        vp_put_u64(&g_w, 7), vp_put_u64(&g_w, 9), vp_put_u64(&g_w, 9);
        vp_frame_end(&g_w), save("light_tiles");
        static const uint8_t jpeg_bytes[] = {0xff, 0xd8, 0xff, 0xe0, 0, 16, 'J', 'F', 'I', 'F', 0, 1, 1, 0};
        vp_frame fm = {.epoch = 5, .width = 2, .height = 1, .format = VP_FRAME_JPEG, .visible = 3,
                       .render_ns = 1000, .encode_ns = 200, .data_len = sizeof jpeg_bytes, .data = jpeg_bytes};
        vp_enc_frame(&g_w, 21, &fm), save("frame_jpeg");
        float raw[10] = {0.5f, 0.25f, 0.125f, 1, 0, 0, 0, 0, 8.0f, INFINITY};
        fm = (vp_frame){.epoch = 6, .width = 2, .height = 1, .format = VP_FRAME_RAW, .data_len = sizeof raw,
                        .data = (const uint8_t *)raw};
        vp_enc_frame(&g_w, 22, &fm), save("frame_raw");
    }
    vp_enc_empty(&g_w, VP_METRICS, 27), save("metrics");
    {
        static const char text[] = "# HELP vantage_uptime_seconds Time since the daemon started serving.\n"
                                   "# TYPE vantage_uptime_seconds gauge\nvantage_uptime_seconds 1.5\n";
        vp_metrics_reply mr = {.format = VP_METRICS_PROMETHEUS, .text_len = sizeof text - 1,
                               .text = (const uint8_t *)text};
        vp_enc_metrics_reply(&g_w, 27, &mr), save("metrics_reply");
        size_t at = g_w.len;
        at = g_w.len, vp_enc_metrics_reply(&g_w, 28, &mr), *payload_at(at, 0) = 1, save("bad_metrics_reply_format");
        at = g_w.len, vp_enc_metrics_reply(&g_w, 28, &mr), *payload_at(at, 20) = 0, save("bad_metrics_reply_nul");
        at = g_w.len, vp_enc_metrics_reply(&g_w, 28, &mr), patch32(payload_at(at, 4), 200),
            save("bad_metrics_reply_len");
    }
    enc_vis_result(20, 0), save("vis_result_count_only");
    enc_list_reply(21, 0), save("entity_list_reply_last");
    vp_enc_error(&g_w, 0, VP_ERR_TYPE, UINT32_MAX, ""), save("error_empty_msg");
    vp_enc_ping(&g_w, VP_PING, 22, NULL, 0), save("ping_empty");

    /* ---- multi-frame streams ---- */
    enc_hello(1), enc_entities(VP_ENTITY_ADD, 2, 3), enc_entities(VP_ENTITY_UPDATE, 3, 1), enc_mesh(4),
        enc_occluder(5), enc_lights(6, 2), enc_ids(VP_ENTITY_REMOVE, 7, 1), vp_enc_list(&g_w, 8, &list),
        enc_vis_query(9, 0, 1), vp_enc_empty(&g_w, VP_STATS, 10), vp_enc_subscribe(&g_w, 11, VP_EVENT_SCENE),
        vp_enc_ping(&g_w, VP_PING, 12, ping_data, 4), save("stream_editor_session");
    enc_hello_ok(1), vp_enc_add_reply(&g_w, 2, 8, (const uint32_t[]){(1u << 22) | 1}, 1), vp_enc_ack(&g_w, 3, &ack),
        enc_list_reply(8, 1), enc_vis_result(9, 2), enc_stats_reply(10), vp_enc_ack(&g_w, 11, &ack),
        vp_enc_event(&g_w, &ev), vp_enc_error(&g_w, 12, VP_ERR_UNKNOWN_ID, 0, "no entity 1000"),
        vp_enc_ping(&g_w, VP_PONG, 12, ping_data, 4), save("stream_server_replies");
    for (uint32_t i = 0; i < 4; i++) enc_vis_query(100 + i, (uint8_t)(i & 3), 1 + i);
    save("stream_pipelined_queries");
    {
        /* two whole frames, then a third cut short: a reader waits for more */
        enc_hello(1), enc_entities(VP_ENTITY_ADD, 2, 1);
        size_t cut = g_w.len;
        enc_entities(VP_ENTITY_ADD, 3, 2);
        save_bytes("stream_partial_frame", g_buf, cut + VP_HEADER_SIZE + 30);
        reset();
    }
    {
        /* an unknown type in the middle: skipped by its length */
        enc_hello(1);
        vp_frame_begin(&g_w, 0x0300, 2);
        vp_put_u32(&g_w, 0xdeadbeef);
        vp_put_u64(&g_w, 42);
        vp_frame_end(&g_w);
        vp_enc_ping(&g_w, VP_PING, 3, ping_data, 8);
        save("stream_unknown_type");
    }

    /* ---- deliberately broken: each breaks one rule ---- */
    size_t at;
    at = g_w.len, enc_hello(1), patch32(payload_at(at, 0), 0x50545448u), save("bad_hello_magic"); /* "HTTP" */
    at = g_w.len, enc_hello(1), *payload_at(at, 4) = 1, save("bad_hello_version"); /* version 1: refused */
    at = g_w.len, enc_hello(1), *payload_at(at, 6) = 3, save("bad_hello_role");
    at = g_w.len, enc_hello(1), g_buf[at + 6] = 1, save("bad_frame_flags");
    at = g_w.len, vp_enc_empty(&g_w, VP_STATS, 1), patch32(g_buf + at, 0xfffffff0u), save("bad_frame_too_large");
    save_bytes("bad_short_header", (const uint8_t *)"\x1c\x00\x00\x00\x02", 5);
    at = g_w.len, enc_entities(VP_ENTITY_ADD, 1, 3), patch32(payload_at(at, 0), 4), save("bad_entity_count");
    {
        vp_entity e[2] = {entity(0), entity(1)};
        e[1].sphere[2] = NAN;
        vp_enc_entities(&g_w, VP_ENTITY_ADD, 1, e, 2), save("bad_entity_nan");
        e[1] = entity(1);
        e[0].flags = 0x80;
        vp_enc_entities(&g_w, VP_ENTITY_UPDATE, 1, e, 2), save("bad_entity_flags");
    }
    at = g_w.len, enc_ids(VP_ENTITY_REMOVE, 1, 2), patch32(payload_at(at, 0), UINT32_MAX), save("bad_ids_count_huge");
    vp_enc_ack(&g_w, 1, &ack), vp_put_u8(&g_w, 0), vp_frame_end(&g_w), save("bad_ack_trailing");
    {
        vp_view v[2] = {view(0), view(1)};
        static const uint16_t subs[3] = {0, 7, 4095};
        vp_enc_vis_query_sub(&g_w, 30, 0, 0, v, 2, subs, 3), save("vis_query_sublevels");
        vp_enc_vis_query_sub(&g_w, 30, 0, 0, v, 1, subs, 0), save("bad_vis_query_no_sublevels");
        vp_enc_sublevel_begin(&g_w, 31, &(vp_sublevel_begin){.classes = 12, .name_len = 4,
                                                             .name = (const uint8_t *)"town"}),
            save("sublevel_begin");
        vp_enc_sublevel_begin(&g_w, 31, &(vp_sublevel_begin){.classes = 5000, .name_len = 1, .name = (const uint8_t *)"x"}),
            save("bad_sublevel_begin_classes");
        vp_enc_sublevel_begun(&g_w, 31, &(vp_sublevel_begun){.id = 3, .class_base = 100, .epoch = 77}),
            save("sublevel_begun");
        vp_enc_empty(&g_w, VP_SUBLEVEL_COMMIT, 32), save("sublevel_commit");
        vp_enc_empty(&g_w, VP_SUBLEVEL_ABORT, 32), save("sublevel_abort");
        vp_enc_empty(&g_w, VP_SUBLEVEL_INFO, 32), save("sublevel_info");
        vp_enc_sublevel_name(&g_w, VP_SUBLEVEL_UNLOAD, 33, "town"), save("sublevel_unload");
        vp_enc_sublevel_infos_begin(&g_w, 34, 99, 2);
        vp_put_sublevel_info(&g_w, &(vp_sublevel_info){.id = 1, .state = VP_SL_LOADED, .entities = 8, .occluders = 3,
                                                      .lights = 2, .class_base = 3, .classes = 6, .name_len = 4,
                                                      .name = (const uint8_t *)"town"});
        vp_put_sublevel_info(&g_w, &(vp_sublevel_info){.id = 2, .state = VP_SL_LOADING, .name_len = 5,
                                                      .name = (const uint8_t *)"north"});
        vp_frame_end(&g_w), save("sublevel_info_reply");
        vp_enc_destroy(&g_w, 35, &(vp_destroy){.id = 10, .handle = 4194305, .debris = 4, .center = {1, 2, 3}, .radius = 1.5}),
            save("destroy");
        vp_enc_destroy(&g_w, 35, &(vp_destroy){.id = 10, .center = {1, 2, 3}, .radius = -1}), save("bad_destroy_radius");
        vp_enc_destroyed(&g_w, 35, &(vp_destroyed){.epoch = 12, .spheres = 1, .occluder_tris = 40, .debris = 4, .cut_us = 80}),
            save("destroyed");
    }
    at = g_w.len, enc_vis_query(1, 0, 1), *payload_at(at, 2) = 1, save("bad_vis_query_pad");
    at = g_w.len, enc_vis_query(1, 0, 1), *payload_at(at, 0) = 33, save("bad_vis_query_33_views");
    enc_vis_query(1, VP_Q_STATIC_ONLY | VP_Q_DYNAMIC_ONLY, 1), save("bad_vis_query_flags");
    at = g_w.len, enc_vis_query(1, 0, 1), *payload_at(at, 8 + 152) = 3, save("bad_vis_query_depth_mode");
    at = g_w.len, enc_vis_result(1, 2), patch32(payload_at(at, 40), 0x0aaaaaabu), save("bad_vis_result_count");
    at = g_w.len, enc_mesh(1), patch32(payload_at(at, 12 + 2 * 48 + 4), 4), save("bad_mesh_index");
    at = g_w.len, enc_mesh(1), patch32(payload_at(at, 8), 11), save("bad_mesh_index_count");
    {
        vp_light l[2] = {light(0), light(1)};
        l[1].outer_cos = 0.99f; /* outer above inner: empty cone */
        vp_enc_lights(&g_w, 1, l, 2), save("bad_light_cone");
        l[1] = light(1);
        l[0].range = -1.0f;
        vp_enc_lights(&g_w, 1, l, 2), save("bad_light_range");
    }
    at = g_w.len, vp_enc_error(&g_w, 1, VP_ERR_INTERNAL, 0, "x"), payload_at(at, 8)[1] = 0x10, save("bad_error_msg_len");
    vp_enc_subscribe(&g_w, 1, 0x8), save("bad_subscribe_kinds");
    {
        static const uint64_t sel[3] = {7, 0x8000000100000002ull, 42}, zero[2] = {7, 0}, twice[3] = {7, 42, 7};
        vp_enc_select(&g_w, 36, sel, 3), save("select");
        vp_enc_select(&g_w, 36, NULL, 0), save("select_clear");
        vp_enc_select(&g_w, 36, zero, 2), save("bad_select_zero");
        vp_enc_select(&g_w, 36, twice, 3), save("bad_select_twice");
        at = g_w.len, vp_enc_select(&g_w, 36, sel, 3), patch32(payload_at(at, 0), 2), save("bad_select_count");
        at = g_w.len, vp_enc_select(&g_w, 36, sel, 3), patch32(payload_at(at, 4), 1), save("bad_select_flags");
        vp_enc_selected(&g_w, &(vp_selected){.client_id = 3, .count = 3, .serial = 9}, sel), save("selected");
    }
    vp_enc_list(&g_w, 1, &(vp_list){.cursor = 5, .max = 0}), save("bad_list_max_zero");
    at = g_w.len, enc_occluder(1), patch32(payload_at(at, 36), 0x71c71c72u), save("bad_occluder_tri_count");

    seeds_v2();

    printf("gen_corpus: wrote %u files to %s\n", g_files, g_dir);
    return 0;
}
