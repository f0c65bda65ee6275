/*
 * test_validate.c — one validation of lights, occluders and views, shared
 * by the daemon's edit path and the renderers, and what the daemon answers
 * for each bad input (issue 18 items 5 and 8), over a real socket:
 * - a bad LIGHT_PUT record is refused with its index and a message naming
 *   the field, changes nothing, and RENDER / LIGHT_QUERY / frame streams
 *   keep working for everyone; every light at a boundary that is accepted
 *   renders;
 * - NaN or undefined flags in record i of an ENTITY batch name record i;
 * - sub-level names are strict UTF-8 (the validator checked against a
 *   table and against glibc's iconv), and no ERROR carries raw
 *   client bytes;
 * - FRAME_SUBSCRIBE refuses a view RENDER refuses, before any ACK;
 * - DESTROY's messages name the real cause.
 */
#include "test_util.h"
#include "test_daemon.h"
#include "vantage.h"
#include "vt_soft.h"

#include <dirent.h>
#include <float.h>
#include <iconv.h>
#include <stdbool.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

/* The whole ERROR message is valid UTF-8 without control bytes. */
static void assert_clean_msg(const char *msg)
{
    size_t n = strlen(msg);
    assert_int_equal(vp_utf8_check((const uint8_t *)msg, n, NULL), n);
    for (size_t i = 0; i < n; i++) assert_true((uint8_t)msg[i] >= 32 && (uint8_t)msg[i] != 127);
}

static void assert_error(vtc_client *c, int rc, int code, uint32_t index, const char *want)
{
    const vtc_error *e = vtc_last_error(c);
    if (rc != code || e->index != index || !strstr(e->msg, want))
        print_message("got %d index %u \"%s\"; want %d index %u \"%s\"\n", rc, e->index, e->msg, code, index, want);
    assert_int_equal(rc, code);
    assert_int_equal(e->index, index);
    assert_non_null(strstr(e->msg, want));
    assert_clean_msg(e->msg);
}

/* ---- lights ---------------------------------------------------------------------- */

static vp_light good_light(uint64_t id)
{
    return (vp_light){.id = id, .kind = VP_LIGHT_POINT, .pos = {0, 2, -20}, .color = {1, 1, 1}, .intensity = 50,
                      .range = 30};
}

static vp_light spot_light(uint64_t id)
{
    vp_light l = good_light(id);
    l.kind = VP_LIGHT_SPOT;
    l.dir[2] = -1;
    l.inner_cos = 0.9f;
    l.outer_cos = 0.8f;
    return l;
}

static const double kMaxCoord = 1e12;

/* The LIGHT_PUT rows: name, the light it starts from (good_light or
 * spot_light, id 77), what changes, the code (0: accepted) and what the
 * message says. An X-macro, so that one list gives both the named rows
 * and the change each makes (the changes are statements). */
#define LIGHT_CASES(ROW, SPOT)                                                                                    \
    /* the issue's inputs */                                                                                    \
    ROW("position beyond 1e12", l.pos[0] = 2e12, VP_ERR_INVALID, "position x is 2e+12 m, beyond")               \
    ROW("range 3e38", l.range = 3e38f, VP_ERR_INVALID, "range is 3e+38 m, outside")                            \
    ROW("colour 3e38", l.color[1] = 3e38f, VP_ERR_INVALID, "colour g x intensity")                             \
    ROW("colour 3e38 x intensity 50 (float overflow)", (l.color[2] = 3e38f, l.intensity = 50), VP_ERR_INVALID, \
        "colour b x intensity is 1.5e+40")                                                                      \
    SPOT("spot direction zero", (l.dir[0] = l.dir[1] = l.dir[2] = 0), VP_ERR_INVALID, "spot direction is (0, 0, 0)") \
    /* the record's own checks */                                                                               \
    ROW("position NaN", l.pos[1] = NAN, VP_ERR_NONFINITE, "position y is nan")                                 \
    ROW("range infinite", l.range = INFINITY, VP_ERR_NONFINITE, "range is inf")                                \
    ROW("range zero", l.range = 0, VP_ERR_INVALID, "range 0 is not > 0")                                        \
    ROW("negative intensity", l.intensity = -1, VP_ERR_INVALID, "intensity -1 is negative")                    \
    ROW("negative colour", l.color[0] = -0.5f, VP_ERR_INVALID, "colour r -0.5 is negative")                    \
    ROW("kind 7", l.kind = 7, VP_ERR_INVALID, "kind 7 is neither")                                              \
    SPOT("cone outer > inner", l.outer_cos = 0.95f, VP_ERR_INVALID, "spot cone")                                \
    SPOT("inner cosine NaN", l.inner_cos = NAN, VP_ERR_NONFINITE, "inner cosine is nan")                       \
    /* boundaries: the limit itself accepted, the next value refused */                                         \
    ROW("position at +1e12", l.pos[2] = kMaxCoord, 0, "")                                                       \
    ROW("position just past -1e12", l.pos[2] = -nextafter(kMaxCoord, INFINITY), VP_ERR_INVALID, "position z")  \
    ROW("range at 1e9", l.range = 1e9f, 0, "")                                                                  \
    ROW("range just past 1e9", l.range = nextafterf(1e9f, INFINITY), VP_ERR_INVALID, "range")                  \
    ROW("range at 1e-3", l.range = 1e-3f, 0, "")                                                                \
    ROW("range just under 1e-3", l.range = nextafterf(1e-3f, 0), VP_ERR_INVALID, "range")                      \
    ROW("range 1e-30", l.range = 1e-30f, VP_ERR_INVALID, "range is 1e-30 m, outside 0.001..1e+09 m")           \
    ROW("colour x intensity at 1e12", (l.color[0] = 1e6f, l.intensity = 1e6f), 0, "")                          \
    ROW("colour x intensity past 1e12", (l.color[0] = 1e6f, l.intensity = 1000001.0f), VP_ERR_INVALID,         \
        "colour r x intensity is 1e+12, outside 0..1e+12")                                                      \
    /* spot axes of any finite non-zero length are normalised in double */                                      \
    SPOT("spot direction 1e-30", (l.dir[0] = 1e-30f, l.dir[2] = -1e-30f), 0, "")                                \
    SPOT("spot direction 3e38", (l.dir[1] = 3e38f, l.dir[2] = -3e38f), 0, "")                                   \
    SPOT("spot direction denormal", (l.dir[2] = -1e-45f), 0, "")                                               \
    SPOT("spot cone of a denormal width", (l.inner_cos = 0.8f, l.outer_cos = nextafterf(0.8f, 0)), 0, "")      \
    SPOT("outer cosine -1", (l.outer_cos = -1, l.inner_cos = 0), 0, "")                                         \
    SPOT("outer cosine just under -1", (l.outer_cos = nextafterf(-1, -2), l.inner_cos = 0), VP_ERR_INVALID,    \
         "spot cone")                                                                                           \
    SPOT("inner cosine 1", l.inner_cos = 1, 0, "")                                                              \
    SPOT("inner cosine just over 1", l.inner_cos = nextafterf(1, 2), VP_ERR_INVALID, "spot cone")              \
    ROW("point light with no direction", (l.dir[0] = l.dir[1] = l.dir[2] = 0), 0, "")                          \
    ROW("intensity 0", l.intensity = 0, 0, "")

typedef struct light_case {
    const char *name;
    bool spot;
    int code;          /* 0: accepted */
    const char *want;  /* in the message */
} light_case;

#define LIGHT_ROW(nm, expr, code_, want_) {nm, false, code_, want_},
#define LIGHT_SPOT(nm, expr, code_, want_) {nm, true, code_, want_},
static const light_case light_cases[] = {LIGHT_CASES(LIGHT_ROW, LIGHT_SPOT)};
#undef LIGHT_ROW
#undef LIGHT_SPOT

/* The light of row t: its start, with the row's change made. */
static vp_light light_of(const light_case *t)
{
    size_t row = (size_t)(t - light_cases), k = 0;
    vp_light l = t->spot ? spot_light(77) : good_light(77);
#define LIGHT_EDIT(nm, expr, code_, want_) \
    if (row == k++) expr;
    LIGHT_CASES(LIGHT_EDIT, LIGHT_EDIT)
#undef LIGHT_EDIT
    return l;
}

/* What the viewer sees keeps working: RENDER, LIGHT_QUERY and a frame. */
static void viewer_still_served(vtc_client *v, const vp_render *m, uint32_t want_lights)
{
    vp_frame f;
    assert_int_equal(vtc_render(v, m, &f), VP_OK);
    vp_light_tiles t;
    assert_int_equal(vtc_light_query(v, &(vp_light_query){.view = m->view}, &t), VP_OK);
    assert_true(t.in_view <= want_lights);
    vp_stats_reply st;
    assert_int_equal(vtc_stats(v, &st), VP_OK);
    assert_int_equal(st.lights, want_lights);
}

/* One LIGHT_PUT row: a good light and the row's in one batch. A refused
 * batch names record 1 and leaves nothing (all or nothing); every client
 * keeps being served, and an accepted light renders. */
static void test_bad_lights_refused(void **state)
{
    const light_case *t = *state;
    daemon_proc d;
    vtc_client *ed = daemon_open(&d, VP_ROLE_EDITOR);
    vtc_client *viewer = connect_role(&d, VP_ROLE_VIEWER, false);
    vtc_client *stream = connect_role(&d, VP_ROLE_VIEWER, false);
    vp_entity e[4];
    for (int i = 0; i < 4; i++)
        e[i] = (vp_entity){.id = (uint64_t)i + 1, .aabb = {-8.0 + 4 * i, -1, -25, -6.0 + 4 * i, 1, -23}};
    assert_int_equal(vtc_add(ed, e, 4, NULL, NULL), VP_OK);
    vp_light base[2] = {good_light(1), spot_light(2)};
    assert_int_equal(vtc_put_lights(ed, base, 2), VP_OK);
    uint32_t nlights = 2;
    vp_render m = {.format = VP_FRAME_RAW, .renderer = VP_RENDERER_SOFT};
    const double eye[3] = {0, 2, 0}, at[3] = {0, 0, -30}, up[3] = {0, 1, 0};
    assert_true(vtc_view_perspective(&m.view, eye, at, up, 70, 96, 64, 0.1, 300));
    vp_frame f;
    assert_int_equal(vtc_frame_subscribe(stream, &(vp_frame_sub){.r = m, .max_fps = 60}), VP_OK);
    assert_int_equal(vtc_wait_frame(stream, &f, 10000), VP_OK);

    vp_light batch[2] = {good_light(1000), light_of(t)};
    batch[1].id = 2000;
    int rc = vtc_put_lights(ed, batch, 2);
    if (t->code) {
        assert_error(ed, rc, t->code, 1, t->want);
        assert_non_null(strstr(vtc_last_error(ed)->msg, "record 1: "));
    } else {
        assert_int_equal(rc, VP_OK);
        nlights += 2;
    }
    viewer_still_served(viewer, &m, nlights);
    m.view.origin[0] += 1e-3; /* a new aim: the stream must draw again */
    assert_int_equal(vtc_frame_subscribe(stream, &(vp_frame_sub){.r = m, .max_fps = 60}), VP_OK);
    assert_int_equal(vtc_wait_frame(stream, &f, 10000), VP_OK);
    vtc_close(stream);
    vtc_close(viewer);
    daemon_close(&d, ed);
}

/* The shared validation against the renderer, directly: for random and
 * adversarial lights, cull_light_validate accepting one means the
 * software renderer draws it (and bins it) without an error and without a
 * non-finite pixel. */
static void test_accepted_lights_render(void **state)
{
    (void)state;
    rng r = {test_seed() ^ 0x5107};
    vt_soft *sr;
    assert_int_equal(vt_soft_create(NULL, 1, &sr), 0);
    const uint32_t W = 48, H = 32;
    float *rgba = malloc((size_t)W * H * 4 * sizeof *rgba), *depth = malloc((size_t)W * H * sizeof *depth);
    assert_true(rgba && depth);
    cull_view v;
    cull_view_desc vd = {.viewport_w = W, .viewport_h = H};
    double proj[16], look[16];
    cull_mat_perspective(proj, 1.2, (double)W / H, 0.1, 1000, CULL_DEPTH_GL);
    cull_mat_look_dir(look, (double[3]){0, 0, -1}, (double[3]){0, 1, 0});
    cull_mat_mul(vd.view_proj, proj, look);
    assert_int_equal(cull_view_init(&v, &vd), CULL_OK);
    vt_instance in = {.mesh = 0, .bmin = {-5, -5, -30}, .bmax = {5, 5, -20}, .albedo = {1, 1, 1}};
    const double mags[] = {0, 1e-45, 1e-30, 1e-6, 1e-3, 1, 30, 1e6, 1e9, 1e12, 1e13, 3e38};
    uint32_t accepted = 0, refused = 0;
    for (int it = 0; it < 400; it++) {
        vt_light L = {.l = {.type = rng_below(&r, 2)}};
        for (int a = 0; a < 3; a++) {
            L.l.pos[a] = (rng_below(&r, 2) ? 1 : -1) * mags[rng_below(&r, 12)] * rng_range(&r, 0.5, 1.0);
            L.l.dir[a] = (float)((rng_below(&r, 2) ? 1 : -1) * mags[rng_below(&r, 12)]);
            L.color[a] = (float)(mags[rng_below(&r, 12)] * mags[rng_below(&r, 8)]);
        }
        if (rng_below(&r, 2)) L.l.pos[2] = -25, L.l.pos[0] = L.l.pos[1] = 0; /* in view */
        L.l.radius = mags[rng_below(&r, 12)] * rng_range(&r, 0.5, 2);
        L.l.cos_outer = (float)rng_range(&r, -1, 1);
        L.cos_inner = (float)fmin(1.0, L.l.cos_outer + mags[rng_below(&r, 6)]);
        /* the daemon normalises a spot axis in double before it checks */
        double n = 0;
        for (int a = 0; a < 3; a++) n += (double)L.l.dir[a] * L.l.dir[a];
        if (n > 0)
            for (int a = 0; a < 3; a++) L.l.dir[a] = (float)(L.l.dir[a] / sqrt(n));
        const double rad[3] = {L.color[0], L.color[1], L.color[2]};
        if (cull_light_validate(&L.l, rad, NULL, 0) != CULL_OK) {
            refused++;
            continue;
        }
        accepted++;
        char err[256] = "";
        int rc = vt_soft_render(sr, &v, W, H, &vt_mesh_box, 1, &in, 1, &L, 1, rgba, depth, W, NULL, err, sizeof err);
        if (rc) print_message("accepted light refused by the renderer: %s\n", err);
        assert_int_equal(rc, 0);
        for (size_t k = 0; k < (size_t)W * H * 4; k++) assert_true(isfinite(rgba[k]));
    }
    print_message("%u lights accepted and rendered, %u refused\n", accepted, refused);
    assert_true(accepted > 50 && refused > 50);
    free(rgba);
    free(depth);
    vt_soft_destroy(sr);
}

/* ---- batches name the record --------------------------------------------------- */

/* One bad record in an ENTITY batch of 3 (ADD or UPDATE): the ERROR
 * names that record and nothing changes. */
typedef struct bad_record {
    const char *name;
    int type; /* 0 add, 1 update */
    uint32_t bad;
    int field; /* 0..3 sphere, 4..9 aabb, 10 flags */
    double val;
    uint32_t flags;
    int code;
    const char *want;
} bad_record;

static const bad_record bad_records[] = {
    {"NaN sphere radius in record 2 of an ADD", 0, 2, 3, NAN, 0, VP_ERR_NONFINITE, "record 2: sphere radius is nan"},
    {"inf aabb max y in record 0 of an ADD", 0, 0, 8, INFINITY, 0, VP_ERR_NONFINITE, "record 0: aabb max y is inf"},
    {"undefined flags in record 1 of an ADD", 0, 1, 10, 0, 0x4, VP_ERR_INVALID,
     "record 1: flags 0x00000004 has undefined bits 0x00000004"},
    {"NaN centre x in record 1 of an UPDATE", 1, 1, 0, NAN, 0, VP_ERR_NONFINITE, "record 1: sphere x is nan"},
    {"undefined flags in record 2 of an UPDATE", 1, 2, 10, 0, 0x80000001u, VP_ERR_INVALID,
     "record 2: flags 0x80000001 has undefined bits 0x80000000"},
};

static void test_batch_errors_name_the_record(void **state)
{
    const bad_record *t = *state;
    daemon_proc d;
    vtc_client *c = daemon_open(&d, VP_ROLE_EDITOR);
    vp_entity base[3];
    for (int i = 0; i < 3; i++) base[i] = (vp_entity){.id = 10 + (uint64_t)i, .sphere = {i * 3.0, 0, 0, 1}};
    uint32_t h[3];
    assert_int_equal(vtc_add(c, base, 3, h, NULL), VP_OK);
    vp_entity b[3];
    for (int i = 0; i < 3; i++) {
        b[i] = base[i];
        if (t->type == 0) b[i].id += 100;
        else b[i].handle = h[i];
    }
    vp_entity *x = &b[t->bad];
    if (t->field < 4) x->sphere[t->field] = t->val;
    else if (t->field < 10) x->aabb[t->field - 4] = t->val;
    else x->flags = t->flags;
    vp_stats_reply before, after;
    assert_int_equal(vtc_stats(c, &before), VP_OK);
    int rc = t->type == 0 ? vtc_add(c, b, 3, NULL, NULL) : vtc_update(c, b, 3, NULL);
    assert_error(c, rc, t->code, t->bad, t->want);
    assert_int_equal(vtc_stats(c, &after), VP_OK);
    assert_int_equal(after.epoch, before.epoch); /* nothing changed */
    assert_int_equal(after.entities, before.entities);
    daemon_close(&d, c);
}

/* A bad LIGHT_PUT record by the decoder's own check names it too. */
static void test_light_record_named(void **state)
{
    daemon_proc *d = *state;
    vtc_client *c = connect_role(d, VP_ROLE_EDITOR, false);
    vp_light L[3] = {good_light(1), good_light(2), good_light(3)};
    L[2].pos[1] = NAN;
    assert_error(c, vtc_put_lights(c, L, 3), VP_ERR_NONFINITE, 2, "record 2: position y is nan");
    vtc_close(c);
}

/* ---- UTF-8 ------------------------------------------------------------------------ */

typedef struct utf8_case {
    const char *name;
    const char *s;
    size_t len;
    size_t bad; /* SIZE_MAX: valid */
    const char *why;
} utf8_case;

static const utf8_case utf8_cases[] = {
    {"ascii", "plain", 5, SIZE_MAX, ""},
    {"2-byte e-acute", "caf\xC3\xA9", 5, SIZE_MAX, ""},
    {"3-byte euro", "\xE2\x82\xAC", 3, SIZE_MAX, ""},
    {"4-byte U+10FFFF", "\xF4\x8F\xBF\xBF", 4, SIZE_MAX, ""},
    {"U+D7FF before the surrogates", "\xED\x9F\xBF", 3, SIZE_MAX, ""},
    {"U+E000 after them", "\xEE\x80\x80", 3, SIZE_MAX, ""},
    {"U+0080 smallest 2-byte", "\xC2\x80", 2, SIZE_MAX, ""},
    {"U+0800 smallest 3-byte", "\xE0\xA0\x80", 3, SIZE_MAX, ""},
    {"U+10000 smallest 4-byte", "\xF0\x90\x80\x80", 4, SIZE_MAX, ""},
    {"lone continuation", "a\x80", 2, 1, "continuation"},
    {"overlong slash C0 AF", "\xC0\xAF", 2, 0, "overlong"},
    {"overlong C1 BF", "\xC1\xBF", 2, 0, "overlong"},
    {"overlong 3-byte E0 80 AF", "x\xE0\x80\xAF", 4, 1, "overlong"},
    {"overlong 4-byte F0 8F BF BF", "\xF0\x8F\xBF\xBF", 4, 0, "overlong"},
    {"surrogate D800", "\xED\xA0\x80", 3, 0, "surrogate"},
    {"surrogate DFFF", "ab\xED\xBF\xBF", 5, 2, "surrogate"},
    {"U+110000", "\xF4\x90\x80\x80", 4, 0, "beyond U+10FFFF"},
    {"F5 lead", "\xF5\x80\x80\x80", 4, 0, "beyond U+10FFFF"},
    {"F8 byte", "\xF8\x88\x80\x80\x80", 5, 0, "never occurs"},
    {"FF byte", "\xFF", 1, 0, "never occurs"},
    {"cut short at the end", "ok\xE2\x82", 4, 2, "cut short"},
    {"cut short by ascii", "\xE2" "a\xAC", 3, 0, "cut short"},
};

static void test_utf8_validator(void **state)
{
    const utf8_case *t = *state;
    const char *why = "";
    size_t at = vp_utf8_check((const uint8_t *)t->s, t->len, &why);
    size_t want = t->bad == SIZE_MAX ? t->len : t->bad;
    if (at != want || (t->bad != SIZE_MAX && !strstr(why, t->why)))
        print_message("at %zu (%s), want %zu (%s)\n", at, why, want, t->why);
    assert_int_equal(at, want);
    if (t->bad != SIZE_MAX) assert_non_null(strstr(why, t->why));
}

static void test_utf8_validator_vs_iconv(void **state)
{
    (void)state;
    /* against the C library's decoder (glibc's iconv from UTF-8 is strict:
       no overlongs, surrogates or code points past U+10FFFF; its mbrtowc
       is not, it takes up to 0x7FFFFFFF), over random strings biased
       towards bytes that start and continue sequences */
    iconv_t cd = iconv_open("UTF-32LE", "UTF-8");
    assert_true(cd != (iconv_t)-1);
    rng r = {test_seed() ^ 0x0718};
    static const uint8_t pick[] = {0x00, 0x41, 0x7F, 0x80, 0x8F, 0x90, 0x9F, 0xA0, 0xBF, 0xC0, 0xC1, 0xC2,
                                   0xDF, 0xE0, 0xE1, 0xEC, 0xED, 0xEE, 0xEF, 0xF0, 0xF1, 0xF3, 0xF4, 0xF5, 0xFF};
    uint32_t valid = 0, runs = (uint32_t)(200000 * test_scale());
    for (uint32_t it = 0; it < runs; it++) {
        uint8_t s[16];
        size_t n = 0;
        if (rng_below(&r, 2)) {
            /* code points near every boundary, encoded the plain way
               (surrogates and past U+10FFFF included), then maybe one
               byte changed */
            static const uint32_t cps[] = {0x0,    0x41,   0x7F,   0x80,    0x7FF,    0x800,   0xD7FF,
                                           0xD800, 0xDFFF, 0xE000, 0xFFFD,  0xFFFF,   0x10000, 0x10FFFF,
                                           0x110000, 0x1FFFFF};
            for (uint32_t m = 1 + rng_below(&r, 3); m-- > 0;) {
                uint32_t cp = rng_below(&r, 4) ? cps[rng_below(&r, 16)] : rng_below(&r, 0x110000);
                if (cp < 0x80) s[n++] = (uint8_t)cp;
                else if (cp < 0x800) s[n++] = (uint8_t)(0xC0 | cp >> 6), s[n++] = (uint8_t)(0x80 | (cp & 63));
                else if (cp < 0x10000)
                    s[n++] = (uint8_t)(0xE0 | cp >> 12), s[n++] = (uint8_t)(0x80 | (cp >> 6 & 63)),
                    s[n++] = (uint8_t)(0x80 | (cp & 63));
                else
                    s[n++] = (uint8_t)(0xF0 | cp >> 18), s[n++] = (uint8_t)(0x80 | (cp >> 12 & 63)),
                    s[n++] = (uint8_t)(0x80 | (cp >> 6 & 63)), s[n++] = (uint8_t)(0x80 | (cp & 63));
            }
            if (!rng_below(&r, 4)) s[rng_below(&r, (uint32_t)n)] = pick[rng_below(&r, sizeof pick)];
        } else {
            n = 1 + rng_below(&r, 8);
            for (size_t k = 0; k < n; k++)
                s[k] = rng_below(&r, 3) ? pick[rng_below(&r, sizeof pick)] : (uint8_t)rng_below(&r, 256);
        }
        /* the reference: where iconv stops (EILSEQ, or EINVAL for a
           sequence cut short by the end) */
        char out[64], *in = (char *)s, *o = out;
        size_t il = n, ol = sizeof out;
        iconv(cd, NULL, NULL, NULL, NULL);
        size_t ref = iconv(cd, &in, &il, &o, &ol) == (size_t)-1 ? (size_t)(in - (char *)s) : n;
        size_t got = vp_utf8_check(s, n, NULL);
        if (got != ref) {
            print_message("bytes:");
            for (size_t k = 0; k < n; k++) print_message(" %02x", s[k]);
            print_message(": ours %zu, iconv %zu\n", got, ref);
        }
        assert_int_equal(got, ref);
        valid += got == n;
    }
    iconv_close(cd);
    print_message("%u random strings, %u valid: vp_utf8_check agrees with iconv on all\n", runs, valid);
    assert_true(valid > runs / 5 && valid < runs - runs / 5);
}

/* A sub-level name that is not UTF-8: SUBLEVEL_NAMES names record 2 and
 * why, SUBLEVEL_BEGIN and SUBLEVEL_UNLOAD quote it escaped; nothing is
 * defined, and a valid UTF-8 name still is. */
typedef struct bad_name {
    const char *name, *bad, *want_why, *want_esc;
} bad_name;

static const bad_name bad_names[] = {
    {"overlong slash", "x\xC0\xAFy", "overlong encoding at byte 1", "x\\xc0\\xafy"},
    {"surrogate", "\xED\xA0\x80", "surrogate", "\\xed\\xa0\\x80"},
    {"past U+10FFFF", "a\xF4\x90\x80\x80", "beyond U+10FFFF", "a\\xf4\\x90\\x80\\x80"},
    {"cut short", "ab\xE2\x82", "cut short", "ab\\xe2\\x82"},
    {"latin-1 e-acute", "caf\xE9", "cut short", "caf\\xe9"},
    {"lone continuation", "\x80", "continuation", "\\x80"},
};

static void test_sublevel_names_utf8(void **state)
{
    const bad_name *t = *state;
    daemon_proc d;
    vtc_client *c = daemon_open(&d, VP_ROLE_EDITOR);
    const char *names[3] = {"fine", "ch\xC3\xA2teau", t->bad};
    uint16_t ids[3];
    vp_stats_reply before, after;
    assert_int_equal(vtc_stats(c, &before), VP_OK);
    assert_error(c, vtc_sublevel_ids(c, names, 3, ids), VP_ERR_INVALID, 2, t->want_why);
    assert_non_null(strstr(vtc_last_error(c)->msg, t->want_esc));
    assert_int_equal(vtc_stats(c, &after), VP_OK);
    assert_int_equal(after.epoch, before.epoch);
    vp_sublevel_begun b;
    assert_error(c, vtc_sublevel_begin(c, t->bad, 0, &b), VP_ERR_INVALID, UINT32_MAX, t->want_esc);
    /* an unknown name is quoted escaped too */
    vp_ack a;
    assert_error(c, vtc_sublevel_unload(c, t->bad, &a), VP_ERR_NOT_FOUND, UINT32_MAX, t->want_esc);
    /* nothing was defined; a valid UTF-8 name still is */
    vp_name_list l;
    assert_int_equal(vtc_sublevel_list(c, &l), VP_OK);
    assert_int_equal(l.count, 0);
    const char *ok[2] = {"ch\xC3\xA2teau", "\xF0\x9F\x8F\xB0"};
    assert_int_equal(vtc_sublevel_ids(c, ok, 2, ids), VP_OK);
    assert_int_equal(ids[0], 1);
    assert_int_equal(ids[1], 2);
    daemon_close(&d, c);
}

/* ---- views up front ---------------------------------------------------------------- */

/* A view RENDER refuses: RENDER, FRAME_SUBSCRIBE and LIGHT_QUERY answer
 * the same, before any frame. */
typedef struct bad_view {
    const char *name;
    int kind; /* 0 singular, 1 orthographic with w <= 0, 2 all zero */
    int code;
    const char *want;
} bad_view;

static const bad_view bad_views[] = {
    {"singular", 0, VP_ERR_MATRIX, "view: degenerate"},
    {"orthographic, w <= 0", 1, VP_ERR_MATRIX, "view: degenerate"},
    {"all zero", 2, VP_ERR_MATRIX, "view: degenerate"},
};

static vp_render good_render(void)
{
    vp_render good = {.format = VP_FRAME_RAW, .renderer = VP_RENDERER_SOFT};
    const double eye[3] = {0, 2, 0}, at[3] = {0, 0, -30}, up[3] = {0, 1, 0};
    assert_true(vtc_view_perspective(&good.view, eye, at, up, 70, 64, 48, 0.1, 300));
    return good;
}

static void test_frame_subscribe_checks_view(void **state)
{
    const bad_view *t = *state;
    daemon_proc d;
    vtc_client *c = daemon_open(&d, VP_ROLE_VIEWER);
    vp_render m = good_render();
    double *vp = m.view.view_proj;
    if (t->kind == 0) vp[0] = vp[4] = vp[8] = vp[12] = 0;
    if (t->kind == 1) {
        memset(vp, 0, sizeof m.view.view_proj);
        vp[0] = vp[5] = vp[10] = 0.01;
        vp[15] = -1;
    }
    if (t->kind == 2) memset(vp, 0, sizeof m.view.view_proj);
    vp_frame f;
    assert_error(c, vtc_render(c, &m, &f), t->code, UINT32_MAX, t->want);
    assert_error(c, vtc_frame_subscribe(c, &(vp_frame_sub){.r = m, .max_fps = 30}), t->code, UINT32_MAX, t->want);
    assert_error(c, vtc_light_query(c, &(vp_light_query){.view = m.view}, &(vp_light_tiles){0}), t->code, UINT32_MAX,
                 t->want);
    daemon_close(&d, c);
}

/* A running stream re-aimed at a bad view is refused and keeps going. */
static void test_stream_keeps_a_good_view(void **state)
{
    daemon_proc *d = *state;
    vtc_client *c = connect_role(d, VP_ROLE_VIEWER, false);
    vp_render good = good_render();
    vp_frame f;
    assert_int_equal(vtc_frame_subscribe(c, &(vp_frame_sub){.r = good, .max_fps = 30}), VP_OK);
    assert_int_equal(vtc_wait_frame(c, &f, 10000), VP_OK);
    vp_render bad = good;
    memset(bad.view.view_proj, 0, sizeof bad.view.view_proj);
    assert_error(c, vtc_frame_subscribe(c, &(vp_frame_sub){.r = bad, .max_fps = 30}), VP_ERR_MATRIX, UINT32_MAX,
                 "view");
    vtc_client *ed = connect_role(d, VP_ROLE_EDITOR, false);
    assert_int_equal(vtc_add(ed, &(vp_entity){.id = 1, .sphere = {0, 0, -10, 1}}, 1, NULL, NULL), VP_OK);
    assert_int_equal(vtc_wait_frame(c, &f, 10000), VP_OK); /* the new scene, drawn */
    vtc_close(ed);
    vtc_close(c);
}

/* ---- DESTROY names the real cause ------------------------------------------------- */

/* A DESTROY of entity 5 (a 2 m cube at the origin) with one bad field. */
typedef struct bad_destroy {
    const char *name;
    double centre0, radius;
    int code;
    const char *want;
} bad_destroy;

static const bad_destroy bad_destroys[] = {
    {"radius 1e300", 0, 1e300, VP_ERR_INVALID, "radius 1e+300 m is larger than the limit 1e+09 m"},
    {"radius just past 1e9", 0, 1000000000.0000001 /* nextafter(1e9, inf) */, VP_ERR_INVALID, "larger than the limit 1e+09 m"},
    {"radius -1", 0, -1, VP_ERR_INVALID, "radius -1 m is not > 0"},
    {"radius 0", 0, 0, VP_ERR_INVALID, "radius 0 m is not > 0"},
    {"radius NaN", 0, NAN, VP_ERR_NONFINITE, "radius is nan"},
    {"radius inf", 0, INFINITY, VP_ERR_NONFINITE, "radius is inf"},
    {"centre NaN", NAN, 1, VP_ERR_NONFINITE, "centre x is nan"},
    {"centre 2e12", 2e12, 1, VP_ERR_INVALID, "centre x is 2e+12 m, beyond the world's +-1e+12 m"},
    /* relative to the entity (a 2 m cube: diagonal 3.4641 m) */
    {"radius past the diagonal", 0, 3.4642, VP_ERR_INVALID, "larger than entity 5's diagonal, 3.4641 m"},
    {"radius 1e9", 0, 1e9, VP_ERR_INVALID, "larger than entity 5's diagonal"},
    {"1 km away", 1000, 5, VP_ERR_INVALID, "does not touch entity 5: its centre is 999 m from"},
    {"just out of reach", 3.5, 2.4999, VP_ERR_INVALID, "does not touch entity 5"},
};

static vtc_client *destroy_target(daemon_proc *d)
{
    vtc_client *c = daemon_open(d, VP_ROLE_EDITOR);
    assert_int_equal(vtc_add(c, &(vp_entity){.id = 5, .aabb = {-1, -1, -1, 1, 1, 1}}, 1, NULL, NULL), VP_OK);
    return c;
}

static void test_destroy_messages(void **state)
{
    const bad_destroy *t = *state;
    daemon_proc d;
    vtc_client *c = destroy_target(&d);
    vp_destroyed out;
    vp_destroy m = {.id = 5, .center = {t->centre0, 0, 0}, .radius = t->radius};
    assert_error(c, vtc_send_destruction(c, &m, &out), t->code, UINT32_MAX, t->want);
    assert_null(strstr(vtc_last_error(c)->msg, "negative, NaN or infinite"));
    daemon_close(&d, c);
}

/* The limits themselves: the diagonal; a sphere that just touches from outside. */
static void test_destroy_limits(void **state)
{
    (void)state;
    daemon_proc d;
    vtc_client *c = destroy_target(&d);
    vp_destroyed out;
    assert_int_equal(vtc_send_destruction(c, &(vp_destroy){.id = 5, .radius = sqrt(12.0)}, &out), VP_OK);
    assert_int_equal(vtc_send_destruction(c, &(vp_destroy){.id = 5, .center = {3.5, 0, 0}, .radius = 2.5}, &out), VP_OK);
    daemon_close(&d, c);
}

static uint32_t rd32le(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

/* Bitwise CRC-32 (zlib's polynomial), the journal's record checksum. */
static uint32_t crc32_of(uint32_t c, const uint8_t *p, size_t n)
{
    c = ~c;
    for (size_t i = 0; i < n; i++) {
        c ^= p[i];
        for (int k = 0; k < 8; k++) c = c & 1 ? (c >> 1) ^ 0xEDB88320u : c >> 1;
    }
    return ~c;
}

/* A daemon before these checks acknowledged a light of range 3e38 and a
 * sub-level name that is not UTF-8, and journaled them: such a journal is
 * made here by patching a good one (same lengths, CRCs redone). The daemon
 * must still start from it (replay applies what was acknowledged), keep
 * the light (a later LIGHT_REMOVE may name it) but never draw it, and
 * keep serving frames and light lists. */
static void test_old_journal_replays(void **state)
{
    (void)state;
    tdir td;
    tdir_make(&td, "validate-journal");
    char dir[320];
    snprintf(dir, sizeof dir, "%s", tdir_file(&td, "data"));
    const char *extra[] = {"--data-dir", dir, "--durability", "always", NULL};
    daemon_proc d;
    daemon_start_args(&d, extra);
    vtc_client *c = connect_role(&d, VP_ROLE_EDITOR, false);
    const char *names[1] = {"zz-name"};
    uint16_t ids[1];
    assert_int_equal(vtc_sublevel_ids(c, names, 1, ids), VP_OK);
    assert_int_equal(vtc_add(c, &(vp_entity){.id = 1, .aabb = {-3, -1, -25, 3, 1, -20}}, 1, NULL, NULL), VP_OK);
    vp_light L[2] = {good_light(1), good_light(9)};
    assert_int_equal(vtc_put_lights(c, L, 2), VP_OK);
    vtc_close(c);
    daemon_stop(&d);

    /* patch the journal: light 9's range, the name's first two bytes */
    char path[400];
    snprintf(path, sizeof path, "%s/journal.000001", dir);
    FILE *f = fopen(path, "r+b");
    assert_non_null(f);
    uint8_t buf[1 << 16];
    size_t n = fread(buf, 1, sizeof buf, f);
    assert_true(n > 32 && n < sizeof buf);
    int patched = 0;
    for (size_t off = 32; off + 24 <= n;) {
        uint32_t len = rd32le(buf + off);
        uint16_t type = (uint16_t)(buf[off + 16] | buf[off + 17] << 8);
        uint8_t *pl = buf + off + 24;
        if (type == VP_LIGHT_PUT) {
            uint32_t cnt = rd32le(pl);
            for (uint32_t i = 0; i < cnt; i++) {
                uint8_t *rec = pl + 4 + (size_t)i * VP_LIGHT_SIZE;
                if (rd32le(rec) != 9) continue;
                float big = 3e38f;
                memcpy(rec + 64, &big, 4); /* little-endian host */
                patched++;
            }
        } else if (type == VP_SUBLEVEL_NAMES) {
            assert_int_equal(pl[4], 7);
            pl[5] = 0xC0, pl[6] = 0xAF;
            patched++;
        }
        uint32_t crc = crc32_of(crc32_of(0, buf + off + 8, 16), pl, len);
        for (int k = 0; k < 4; k++) buf[off + 4 + k] = (uint8_t)(crc >> (8 * k));
        off += 24 + len;
    }
    assert_int_equal(patched, 2);
    assert_int_equal(fseek(f, 0, SEEK_SET), 0);
    assert_int_equal(fwrite(buf, 1, n, f), n);
    fclose(f);

    daemon_start_args(&d, extra);
    vtc_client *v = connect_role(&d, VP_ROLE_VIEWER, false);
    vp_stats_reply st;
    assert_int_equal(vtc_stats(v, &st), VP_OK);
    assert_int_equal(st.lights, 2);
    vp_render m = {.format = VP_FRAME_RAW, .renderer = VP_RENDERER_SOFT};
    assert_true(vtc_view_perspective(&m.view, (double[3]){0, 2, 0}, (double[3]){0, 0, -30}, (double[3]){0, 1, 0}, 70,
                                     64, 48, 0.1, 300));
    vp_frame fr;
    assert_int_equal(vtc_render(v, &m, &fr), VP_OK);
    vp_light_tiles t;
    assert_int_equal(vtc_light_query(v, &(vp_light_query){.view = m.view}, &t), VP_OK);
    assert_int_equal(t.in_view, 1);
    for (uint32_t k = 0; k < t.count; k++) assert_int_equal(vp_light_tiles_id(&t, k), 1);
    vtc_close(v);
    /* the light can still be removed by id */
    vtc_client *ed = connect_role(&d, VP_ROLE_EDITOR, false);
    uint8_t msg[64];
    vp_writer w;
    vp_writer_init(&w, msg, sizeof msg);
    vp_enc_ids(&w, VP_LIGHT_REMOVE, vtc_next_req(ed), (const uint64_t[1]){9}, 1);
    assert_int_equal(vtc_send(ed, msg, w.len), VP_OK);
    vp_header h;
    const uint8_t *pl;
    assert_int_equal(vtc_recv(ed, &h, &pl, 10000), VP_OK);
    assert_int_equal(h.type, VP_ACK);
    vtc_close(ed);
    daemon_stop(&d);
    DIR *dd = opendir(dir);
    assert_non_null(dd);
    for (struct dirent *de; (de = readdir(dd));) {
        char p[700];
        snprintf(p, sizeof p, "%s/%s", dir, de->d_name);
        if (de->d_name[0] != '.') unlink(p);
    }
    closedir(dd);
    rmdir(dir);
    tdir_remove(&td);
}

/* ---- OCCLUDER_PUT's bound over the wire ----------------------------------------- */

/* The daemon's triangle limit is the culling core's (349,525: 2^20
 * vertices as a triangle list), refused as LIMIT naming it (it was SCENE,
 * "bad counts"); the worst mesh for the old build (64k identical
 * triangles: 9.9 s to 30 s of a frozen loop) is acknowledged, kept as one
 * triangle, and the daemon keeps answering. */
static void test_occluder_put_bound(void **state)
{
    daemon_proc *d = *state;
    vtc_client *c = connect_role(d, VP_ROLE_EDITOR, false);
    const uint32_t over = 349526, same = 65536;
    float *v = calloc((size_t)over * 9, sizeof *v);
    assert_non_null(v);
    for (uint32_t t = 0; t < over; t++) {
        v[9 * (size_t)t + 3] = 10; /* (0,0,0) (10,0,0) (0,10,0), all alike */
        v[9 * (size_t)t + 7] = 10;
    }
    const double origin[3] = {0, 0, -50};
    assert_error(c, vtc_put_occluder(c, 7, origin, v, over), VP_ERR_LIMIT, UINT32_MAX,
                 "occluder of 349526 triangles, limit 349525");
    assert_int_equal(vtc_put_occluder(c, 7, origin, v, same), VP_OK);
    assert_int_equal(vtc_ping(c), VP_OK);
    vp_stats_reply st;
    assert_int_equal(vtc_stats(c, &st), VP_OK);
    assert_int_equal(st.occluders, 1);
    free(v);
    vtc_close(c);
}

const struct CMUnitTest validate_tests[] = {
    TEST_ROWS(test_utf8_validator, utf8_cases),
    cmocka_unit_test(test_utf8_validator_vs_iconv),
    cmocka_unit_test(test_accepted_lights_render),
    TEST_ROWS(test_bad_lights_refused, light_cases),
    TEST_ROWS(test_batch_errors_name_the_record, bad_records),
    DAEMON_TEST(test_light_record_named),
    TEST_ROWS(test_sublevel_names_utf8, bad_names),
    TEST_ROWS(test_frame_subscribe_checks_view, bad_views),
    DAEMON_TEST(test_stream_keeps_a_good_view),
    TEST_ROWS(test_destroy_messages, bad_destroys),
    cmocka_unit_test(test_destroy_limits),
    cmocka_unit_test(test_old_journal_replays),
    DAEMON_TEST(test_occluder_put_bound),
};
const size_t validate_tests_count = sizeof validate_tests / sizeof validate_tests[0];
