/*
 * test_env.c — the environment (daemon/env.c) and texture uploads through
 * the real daemon (daemon/upload.c):
 *   - ENV_SET's scene checks as named rows (missing sky texture, a PNG or
 *     a square EXR for the sky, a missing ground material, a field out of
 *     range), each leaving the environment as it was;
 *   - ENV_SET / ENV_GET round trip through vantaged, roles;
 *   - a texture uploaded in several chunks (max_payload 1024), stored and
 *     replayed from the journal after a restart, the environment too;
 *   - chunks out of order or disagreeing: refused, the upload dropped;
 *   - an upload abandoned half-way: its bytes given back when the
 *     connection closes (and no leak: the asan daemon exits clean);
 *   - uploads under way count against --max-texture-mem;
 *   - the CLI: texture put / rm, env with its options.
 */
#include "test_daemon.h"
#include "test_util.h"

#include "edit.h"
#include "vt_exr.h"
#include "vt_image.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static const scene_limits LIMITS = {.max_entities = 1024, .max_lights = 16, .max_occluders = 16,
                                    .max_occluder_tris = 16, .max_mesh_verts = 16, .max_materials = 16,
                                    .max_texture_size = 4096, .max_texture_mem = 64u << 20};

/* An EXR of w x h (finite values) in t's folder as name: its path. */
static const char *write_exr(tdir *t, const char *name, uint32_t w, uint32_t h)
{
    float *px = malloc((size_t)w * h * 16);
    assert_non_null(px);
    for (size_t i = 0; i < (size_t)w * h * 4; i++) px[i] = 0.25f * (float)(i % 9);
    vt_exr_channel ch[3] = {{"R", VT_EXR_HALF, px, 4, 4 * (ptrdiff_t)w},
                            {"G", VT_EXR_HALF, px + 1, 4, 4 * (ptrdiff_t)w},
                            {"B", VT_EXR_HALF, px + 2, 4, 4 * (ptrdiff_t)w}};
    char err[256];
    const char *path = tdir_file(t, name);
    assert_int_equal(vt_exr_write(path, w, h, ch, 3, VT_EXR_ZIP, err, sizeof err), 0);
    free(px);
    return path;
}

/* A PNG of random pixels (incompressible: its size is about 4 w h). */
static const char *write_png(tdir *t, const char *name, uint32_t w, uint32_t h, uint64_t seed)
{
    uint8_t *px = malloc((size_t)w * h * 4);
    assert_non_null(px);
    for (size_t i = 0; i < (size_t)w * h * 4; i++) px[i] = (uint8_t)(splitmix64(&seed) >> 56);
    char err[256];
    const char *path = tdir_file(t, name);
    assert_int_equal(vt_png_write(path, w, h, px, (size_t)w * 4, true, 1, err, sizeof err), 0);
    free(px);
    return path;
}

/* ---- ENV_SET's scene checks ------------------------------------------------------------ */

typedef struct env_row {
    const char *name;
    void (*change)(vp_env *e);
    int want;
    const char *says;
} env_row;

static void sky_missing(vp_env *e) { e->sky_mode = VP_SKY_TEXTURE, e->sky_texture = 99; }
static void sky_png(vp_env *e) { e->sky_mode = VP_SKY_TEXTURE, e->sky_texture = 1; }
static void sky_square(vp_env *e) { e->sky_mode = VP_SKY_TEXTURE, e->sky_texture = 2; }
static void sky_no_id(vp_env *e) { e->sky_mode = VP_SKY_TEXTURE, e->sky_texture = 0; }
static void ground_missing(vp_env *e) { e->ground_material = 12; }
static void turbidity(vp_env *e) { e->turbidity = 20; }
static void fog_nan(vp_env *e) { e->fog_density = NAN; }
static void sun_short(vp_env *e) { e->sun_dir[0] = 0.5f, e->sun_dir[1] = 0, e->sun_dir[2] = 0; }

static const env_row env_rows[] = {
    {"sky_texture_missing", sky_missing, VP_ERR_UNKNOWN_ID, "sky texture 99: no such texture"},
    {"sky_texture_not_exr", sky_png, VP_ERR_INVALID, "sky texture 1 is a PNG image"},
    {"sky_exr_not_lat_long", sky_square, VP_ERR_INVALID, "sky texture 2 is 16x16: a lat-long"},
    {"sky_texture_id_0", sky_no_id, VP_ERR_INVALID, "needs a sky texture id"},
    {"ground_material_missing", ground_missing, VP_ERR_UNKNOWN_ID, "ground material 12: no such material"},
    {"turbidity_out_of_range", turbidity, VP_ERR_INVALID, "turbidity"},
    {"fog_nan", fog_nan, VP_ERR_NONFINITE, "fog density"},
    {"sun_not_unit", sun_short, VP_ERR_INVALID, "not a unit vector"},
};

static int put_file(scene *s, uint32_t id, uint8_t format, const char *path)
{
    size_t n;
    uint8_t *b = test_slurp(path, &n);
    scene_err err;
    int rc = scene_texture_put(s, &(vp_texture_put){.id = id, .format = format, .total = (uint32_t)n,
                                                    .len = (uint32_t)n, .data = b},
                               &err);
    free(b);
    return rc;
}

static void test_env_bad(void **state)
{
    const env_row *row = *state;
    scene *s = calloc(1, sizeof *s);
    assert_non_null(s);
    assert_int_equal(scene_init(s, 64, &LIMITS), 0);
    tdir t;
    tdir_make(&t, "env");
    assert_int_equal(put_file(s, 1, VP_TEX_PNG, write_png(&t, "a.png", 8, 4, 1)), VP_OK);
    assert_int_equal(put_file(s, 2, VP_TEX_EXR, write_exr(&t, "b.exr", 16, 16)), VP_OK);
    vp_env e, before = s->env;
    vp_env_default(&e);
    row->change(&e);
    uint64_t epoch = s->epoch;
    scene_err err = {0};
    edit_result r;
    int rc = edit_apply(s, &(edit){.type = VP_ENV_SET, .u.env = e}, &r, &err);
    assert_int_equal(rc, row->want);
    if (!strstr(err.msg, row->says)) fail_msg("message \"%s\" does not say \"%s\"", err.msg, row->says);
    assert_memory_equal(&s->env, &before, sizeof before);
    assert_int_equal(s->epoch, epoch);
    assert_int_equal(scene_texture_find(s, 1)->users + scene_texture_find(s, 2)->users, 0);
    tdir_remove(&t);
    scene_free(s);
    free(s);
}

/* ---- through the daemon ----------------------------------------------------------------- */

static bool env_equal(const vp_env *a, const vp_env *b)
{
    uint8_t x[VP_HEADER_SIZE + VP_ENV_SIZE], y[VP_HEADER_SIZE + VP_ENV_SIZE];
    vp_writer w;
    vp_writer_init(&w, x, sizeof x);
    vp_enc_env(&w, VP_ENV_REPLY, 1, a);
    vp_writer_init(&w, y, sizeof y);
    vp_enc_env(&w, VP_ENV_REPLY, 1, b);
    return !memcmp(x, y, sizeof x);
}

/* A metric's value from the exposition (the first sample of the name). */
static uint64_t metric(vtc_client *c, const char *name)
{
    const char *text;
    size_t len;
    assert_int_equal(vtc_metrics(c, &text, &len), VP_OK);
    char key[128];
    snprintf(key, sizeof key, "\n%s ", name);
    char *copy = strndup(text, len);
    const char *at = strstr(copy, key);
    if (!at) fail_msg("no metric %s", name);
    uint64_t v = strtoull(at + strlen(key), NULL, 10);
    free(copy);
    return v;
}

static vp_env test_env(void)
{
    vp_env e;
    vp_env_default(&e);
    e.sun_dir[0] = 0, e.sun_dir[1] = 0.6f, e.sun_dir[2] = 0.8f;
    e.sun_lux = 54321;
    e.sky_mode = VP_SKY_COLOR;
    e.sky_color[2] = 0.75f;
    e.sky_intensity = 3;
    e.flags = 0;
    e.ground_height = -12.5;
    e.fog_density = 0.01f;
    e.fog_height_falloff = 0.2f;
    e.exposure_mode = VP_EXPOSURE_FIXED;
    e.exposure_ev = 11;
    return e;
}

static void test_env_roundtrip(void **state)
{
    daemon_proc *d = *state;
    vtc_client *ed = connect_role(d, VP_ROLE_EDITOR, false), *viewer = connect_role(d, VP_ROLE_VIEWER, true);
    vp_env got, def, e = test_env();
    vp_env_default(&def);
    assert_int_equal(vtc_env_get(viewer, &got), VP_OK);
    assert_true(env_equal(&got, &def));
    assert_int_equal(vtc_env_set(viewer, &e, NULL), VP_ERR_AUTH); /* editing needs the editor role */
    uint64_t epoch = 0;
    assert_int_equal(vtc_env_set(ed, &e, &epoch), VP_OK);
    assert_true(epoch > 0);
    assert_int_equal(vtc_env_get(viewer, &got), VP_OK);
    assert_true(env_equal(&got, &e));
    assert_int_equal(metric(viewer, "vantage_env_sun_lux"), 54321);
    assert_int_equal(metric(viewer, "vantage_env_ground"), 0);
    /* a refused one names its field and changes nothing */
    vp_env bad = e;
    bad.exposure_ev = 99;
    assert_int_equal(vtc_env_set(ed, &bad, NULL), VP_ERR_INVALID);
    assert_non_null(strstr(vtc_last_error(ed)->msg, "exposure EV"));
    assert_int_equal(vtc_env_get(viewer, &got), VP_OK);
    assert_true(env_equal(&got, &e));
    vtc_close(ed);
    vtc_close(viewer);
}

/* One raw TEXTURE_PUT chunk; the reply's type (ACK or ERROR), its ACK
 * count or ERROR code and message. */
static uint16_t chunk(vtc_client *c, uint32_t id, uint32_t total, uint32_t off, const uint8_t *data, uint32_t len,
                      int *code, char *msg, size_t msglen)
{
    size_t cap = vp_size_texture_put(len);
    uint8_t *buf = malloc(cap);
    assert_non_null(buf);
    vp_writer w;
    vp_writer_init(&w, buf, cap);
    uint32_t req = vtc_next_req(c);
    vp_enc_texture_put(&w, req, &(vp_texture_put){.id = id, .format = VP_TEX_PNG, .total = total, .offset = off,
                                                   .len = len, .data = data});
    assert_int_equal(vtc_send(c, buf, w.len), VP_OK);
    free(buf);
    vp_header h;
    const uint8_t *p;
    assert_int_equal(vtc_recv(c, &h, &p, -1), VP_OK);
    assert_int_equal(h.req, req);
    *code = 0;
    msg[0] = 0;
    if (h.type == VP_ACK) {
        vp_ack a;
        assert_int_equal(vp_dec_ack(p, h.len, &a), VP_OK);
        *code = (int)a.count;
    } else if (h.type == VP_ERROR) {
        vp_error e;
        assert_int_equal(vp_dec_error(p, h.len, &e), VP_OK);
        *code = e.code;
        snprintf(msg, msglen, "%.*s", (int)e.msg_len, (const char *)e.msg);
    }
    return h.type;
}

static void test_texture_chunks(void **state)
{
    (void)state;
    tdir t;
    tdir_make(&t, "texd");
    daemon_proc d;
    char dir[300];
    snprintf(dir, sizeof dir, "%s", tdir_file(&t, "data"));
    const char *extra[] = {"--max-payload", "1024", "--data-dir", dir, "--max-texture-mem", "200000", NULL};
    daemon_start_args(&d, extra);
    vtc_client *c = connect_role(&d, VP_ROLE_EDITOR, false);
    /* 40x30 random RGBA: about 4.8 KB, five chunks of at most 1008 bytes */
    size_t n;
    uint8_t *png = test_slurp(write_png(&t, "a.png", 40, 30, 9), &n);
    assert_true(n > 4 * 1008);
    uint64_t epoch = 0;
    assert_int_equal(vtc_texture_put(c, 5, VP_TEX_PNG, VP_TEX_SRGB, png, n, &epoch), VP_OK);
    assert_int_equal(metric(c, "vantage_scene_textures"), 1);
    uint64_t bytes = metric(c, "vantage_scene_texture_bytes");
    assert_true(bytes >= n + 40 * 30 * 4);
    assert_int_equal(metric(c, "vantage_texture_upload_bytes"), 0);

    /* out of order: refused, and the upload is gone (its next chunk too) */
    int code;
    char msg[600];
    assert_int_equal(chunk(c, 6, (uint32_t)n, 0, png, 1000, &code, msg, sizeof msg), VP_ACK);
    assert_int_equal(code, 0); /* an intermediate chunk: ACK count 0 */
    assert_int_equal(metric(c, "vantage_texture_upload_bytes"), n);
    assert_int_equal(chunk(c, 6, (uint32_t)n, 2000, png + 2000, 1000, &code, msg, sizeof msg), VP_ERROR);
    assert_int_equal(code, VP_ERR_STATE);
    assert_non_null(strstr(msg, "does not continue the upload of texture 6"));
    assert_int_equal(metric(c, "vantage_texture_upload_bytes"), 0);
    assert_int_equal(chunk(c, 6, (uint32_t)n, 1000, png + 1000, 1000, &code, msg, sizeof msg), VP_ERROR);
    assert_int_equal(code, VP_ERR_STATE);
    assert_non_null(strstr(msg, "no upload is open"));
    /* another id (or total) mid-upload: refused, dropped */
    assert_int_equal(chunk(c, 6, (uint32_t)n, 0, png, 1000, &code, msg, sizeof msg), VP_ACK);
    assert_int_equal(chunk(c, 7, (uint32_t)n, 1000, png + 1000, 1000, &code, msg, sizeof msg), VP_ERROR);
    assert_int_equal(code, VP_ERR_STATE);
    assert_int_equal(chunk(c, 6, (uint32_t)n + 1, 0, png, 1000, &code, msg, sizeof msg), VP_ACK);
    assert_int_equal(chunk(c, 6, (uint32_t)n, 1000, png + 1000, 1000, &code, msg, sizeof msg), VP_ERROR);
    assert_int_equal(metric(c, "vantage_texture_upload_bytes"), 0);
    assert_int_equal(metric(c, "vantage_scene_textures"), 1);

    /* assembled but not an image: the last chunk gets the decoder's refusal, nothing stays */
    uint8_t *junk = malloc(n);
    memcpy(junk, png, n);
    memset(junk + 100, 0x5a, n - 200); /* the header intact, the pixels garbage */
    uint32_t off = 0;
    for (; off + 1000 < n; off += 1000)
        assert_int_equal(chunk(c, 11, (uint32_t)n, off, junk + off, 1000, &code, msg, sizeof msg), VP_ACK);
    assert_int_equal(chunk(c, 11, (uint32_t)n, off, junk + off, (uint32_t)n - off, &code, msg, sizeof msg), VP_ERROR);
    assert_int_equal(code, VP_ERR_INVALID);
    assert_non_null(strstr(msg, "texture 11: the PNG image does not decode"));
    free(junk);
    assert_int_equal(metric(c, "vantage_texture_upload_bytes"), 0);
    assert_int_equal(metric(c, "vantage_scene_textures"), 1);
    /* a viewer cannot start one */
    vtc_client *v = connect_role(&d, VP_ROLE_VIEWER, false);
    assert_int_equal(chunk(v, 12, (uint32_t)n, 0, png, 1000, &code, msg, sizeof msg), VP_ERROR);
    assert_int_equal(code, VP_ERR_AUTH);
    vtc_close(v);

    /* uploads under way count against --max-texture-mem: one of 195000
       bytes does not fit beside the texture held */
    static uint8_t big[1000];
    assert_int_equal(chunk(c, 8, 195000, 0, big, 1000, &code, msg, sizeof msg), VP_ERROR);
    assert_int_equal(code, VP_ERR_LIMIT);
    assert_non_null(strstr(msg, "--max-texture-mem"));

    /* abandoned half-way: the connection closes, its bytes come back */
    vtc_client *quitter = connect_role(&d, VP_ROLE_EDITOR, true);
    assert_int_equal(chunk(quitter, 9, (uint32_t)n, 0, png, 1000, &code, msg, sizeof msg), VP_ACK);
    assert_int_equal(metric(c, "vantage_texture_upload_bytes"), n);
    vtc_close(quitter);
    uint64_t left = 1;
    for (int i = 0; i < 200 && left; i++) { /* the close is seen at the daemon's next turn */
        left = metric(c, "vantage_texture_upload_bytes");
        if (left) usleep(10000);
    }
    assert_int_equal(left, 0);

    /* an EXR for the sky, which then holds on to it */
    size_t en;
    uint8_t *exr = test_slurp(write_exr(&t, "sky.exr", 32, 16), &en);
    assert_int_equal(vtc_texture_put(c, 10, VP_TEX_EXR, 0, exr, en, NULL), VP_OK);
    vp_env e = test_env();
    e.sky_mode = VP_SKY_TEXTURE;
    e.sky_texture = 10;
    assert_int_equal(vtc_env_set(c, &e, NULL), VP_OK);
    uint64_t rm[1] = {10};
    assert_int_equal(vtc_texture_remove(c, rm, 1, NULL), VP_ERR_STATE);
    bytes = metric(c, "vantage_scene_texture_bytes");
    /* one left half-way when the daemon stops: freed with its connection
       (the asan daemon's leak check fails daemon_stop's clean exit if not) */
    assert_int_equal(chunk(c, 13, (uint32_t)n, 0, png, 1000, &code, msg, sizeof msg), VP_ACK);
    daemon_stop(&d);
    vtc_close(c);

    /* restarted on the same data: the journal gives back both textures
       (decoded again) and the environment */
    daemon_start_args(&d, extra);
    c = connect_role(&d, VP_ROLE_VIEWER, false);
    assert_int_equal(metric(c, "vantage_scene_textures"), 2);
    assert_int_equal(metric(c, "vantage_scene_texture_bytes"), bytes);
    vp_env got;
    assert_int_equal(vtc_env_get(c, &got), VP_OK);
    assert_true(env_equal(&got, &e));
    vtc_close(c);
    c = connect_role(&d, VP_ROLE_EDITOR, false);
    assert_int_equal(vtc_texture_remove(c, rm, 1, NULL), VP_ERR_STATE); /* the sky's users came back too */
    vtc_close(c);
    daemon_stop(&d);
    free(png);
    free(exr);
    dir_unlink_files(dir);
    rmdir(dir);
    tdir_remove(&t);
}

static void test_env_cli(void **state)
{
    daemon_proc *d = *state;
    tdir t;
    tdir_make(&t, "envcli");
    char out[4096];
    const char *png = write_png(&t, "a.png", 8, 8, 3);
    assert_int_equal(vantage_run(d, out, sizeof out, "texture put 7 %s --srgb", png), 0);
    assert_non_null(strstr(out, "texture 7"));
    const char *exr = write_exr(&t, "b.exr", 64, 32);
    assert_int_equal(vantage_run(d, out, sizeof out, "texture put 8 %s", exr), 0);
    assert_int_equal(vantage_run(d, out, sizeof out,
                                 "env --sun 90,30,50000 --sky exr:8 --ground off --fog 0.002,0.1,0.2,0.3 "
                                 "--exposure auto:1.5"),
                     0);
    assert_non_null(strstr(out, "azimuth 90.0, elevation 30.0 degrees, 50000 lux"));
    assert_non_null(strstr(out, "sky:      exr:8"));
    assert_non_null(strstr(out, "ground:   off"));
    assert_non_null(strstr(out, "fog:      density 0.002 per metre, colour 0.1,0.2,0.3"));
    assert_non_null(strstr(out, "exposure: auto, compensation +1.5 EV"));
    /* read back as a viewer would, and through the library */
    assert_int_equal(vantage_run(d, out, sizeof out, "env"), 0);
    assert_non_null(strstr(out, "sky:      exr:8"));
    vtc_client *c = connect_role(d, VP_ROLE_VIEWER, false);
    vp_env e;
    assert_int_equal(vtc_env_get(c, &e), VP_OK);
    assert_true(fabsf(e.sun_dir[0] - 0.8660254f) < 1e-5f && fabsf(e.sun_dir[1] - 0.5f) < 1e-5f);
    assert_int_equal(e.exposure_mode, VP_EXPOSURE_AUTO);
    vtc_close(c);
    /* the sky's texture cannot go; a square EXR cannot be the sky; unknown options say what they want */
    assert_int_equal(vantage_run(d, out, sizeof out, "texture rm 8"), 1);
    assert_non_null(strstr(out, "in use"));
    assert_int_equal(vantage_run(d, out, sizeof out, "env --sky exr:7"), 1);
    assert_non_null(strstr(out, "sky texture 7 is a PNG"));
    assert_int_equal(vantage_run(d, out, sizeof out, "env --exposure bright"), 2);
    assert_non_null(strstr(out, "auto, auto:COMP"));
    assert_int_equal(vantage_run(d, out, sizeof out, "env --night"), 0);
    assert_non_null(strstr(out, "1 lux")); /* the night preset: the full moon as the sun */
    assert_non_null(strstr(out, "sky:      color"));
    assert_int_equal(vantage_run(d, out, sizeof out, "texture rm 7 8"), 0);
    assert_int_equal(vantage_run(d, out, sizeof out, "texture put 9 %s", tdir_file(&t, "missing.png")), 3);
    tdir_remove(&t);
}

const struct CMUnitTest env_tests[] = {
    TEST_ROWS(test_env_bad, env_rows),
    DAEMON_TEST(test_env_roundtrip),
    cmocka_unit_test(test_texture_chunks),
    DAEMON_TEST(test_env_cli),
};
const size_t env_tests_count = sizeof env_tests / sizeof env_tests[0];
