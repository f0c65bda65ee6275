/*
 * test_alloc.c — allocation failure: every add and update is retried with
 * its 1st, 2nd, ... allocation failing until it succeeds; each failure must
 * return CULL_ERR_NOMEM and leave the world exactly as it was (counts,
 * every entity's desc, the set an everything-view query returns). Queries
 * and contexts under failing allocations return an error or a right answer.
 *
 * The test binary is linked with -Wl,--wrap for malloc, calloc, realloc
 * and aligned_alloc (see the Makefile); the wrappers fail one chosen call
 * while armed and otherwise pass through.
 */
#include "test_util.h"

#include "culling.h"
#include "protocol.h"
#include "scene.h"
#include "test_util.h"
#include "vt_h264.h"
#include "vt_image.h"

#include <limits.h>
#include <stdlib.h>
#include <stdbool.h>
#include <stdio.h>
#include <string.h>

void *__real_malloc(size_t n);
void *__real_calloc(size_t n, size_t m);
void *__real_realloc(void *p, size_t n);
void *__real_aligned_alloc(size_t a, size_t n);
void *__wrap_malloc(size_t n);
void *__wrap_calloc(size_t n, size_t m);
void *__wrap_realloc(void *p, size_t n);
void *__wrap_aligned_alloc(size_t a, size_t n);

static long g_fail_at = -1; /* index of the call to fail while armed */
static long g_calls;

static bool fail_now(void)
{
    return g_fail_at >= 0 && g_calls++ == g_fail_at;
}

void *__wrap_malloc(size_t n) { return fail_now() ? NULL : __real_malloc(n); }
void *__wrap_calloc(size_t n, size_t m) { return fail_now() ? NULL : __real_calloc(n, m); }
void *__wrap_realloc(void *p, size_t n) { return fail_now() ? NULL : __real_realloc(p, n); }
void *__wrap_aligned_alloc(size_t a, size_t n) { return fail_now() ? NULL : __real_aligned_alloc(a, n); }

static void arm(long k)
{
    g_calls = 0;
    g_fail_at = k;
}

static void disarm(void)
{
    g_fail_at = -1;
}

typedef struct ment {
    cull_handle h;
    cull_entity_desc d;
} ment;

/* The world holds exactly the model's entities. */
static void check_world(cull_world *w, cull_ctx *c, const ment *m, size_t n)
{
    cull_world_info info;
    cull_world_info_get(w, &info);
    assert_int_equal(info.entities, n);
    for (size_t i = 0; i < n; i++) {
        cull_entity_desc d;
        assert_int_equal(cull_entity_get(w, m[i].h, &d), CULL_OK);
        assert_memory_equal(&d, &m[i].d, sizeof d);
    }
    cull_result *res;
    size_t got = test_query_everything(w, c, &res);
    cull_handle *want = malloc((n + 1) * sizeof *want);
    for (size_t i = 0; i < n; i++) want[i] = m[i].h;
    test_assert_same_handles(want, n, res, got);
    free(want);
    free(res);
}

static void rand_desc(rng *r, cull_entity_desc *d)
{
    memset(d, 0, sizeof *d);
    /* wide spread: new cells and new regions are common */
    for (int a = 0; a < 3; a++) d->center[a] = rng_range(r, -3000, 3000);
    d->radius = rng_log(r, 0.01, 20);
    d->class_id = (uint16_t)rng_below(r, 100);
    d->flags = rng_below(r, 2) ? CULL_ENTITY_DYNAMIC : 0;
}

static void test_edits_under_failing_allocations(void **state)
{
    (void)state;
    rng r = {test_seed() ^ 0x5555};
    cull_world *w;
    assert_int_equal(cull_world_create(&(cull_world_desc){.cell_size = 16}, &w), CULL_OK);
    cull_ctx *c;
    assert_int_equal(cull_ctx_create(NULL, &c), CULL_OK);
    enum { CAP = 400 };
    ment m[CAP];
    size_t n = 0;
    long failures = 0;
    int ops = (int)(1500 * test_scale());
    for (int op = 0; op < ops; op++) {
        uint32_t kind = n < 50 ? 0 : rng_below(&r, 3);
        if (kind == 0 && n == CAP) kind = 2;
        cull_entity_desc d;
        rand_desc(&r, &d);
        size_t i = n ? rng_below(&r, (uint32_t)n) : 0;
        for (long k = 0;; k++) {
            int rc;
            cull_handle h = 0;
            arm(k);
            if (kind == 0) rc = cull_entity_add(w, &d, &h);
            else if (kind == 1) rc = cull_entity_update(w, m[i].h, &d);
            else rc = cull_entity_remove(w, m[i].h);
            disarm();
            if (rc == CULL_ERR_NOMEM) {
                failures++;
                if (failures % 7 == 0 || n < 60) check_world(w, c, m, n);
                continue;
            }
            assert_int_equal(rc, CULL_OK);
            if (kind == 0) {
                m[n].h = h;
                assert_int_equal(cull_entity_get(w, h, &m[n].d), CULL_OK);
                n++;
            } else if (kind == 1) {
                assert_int_equal(cull_entity_get(w, m[i].h, &m[i].d), CULL_OK);
            } else {
                m[i] = m[--n];
            }
            break;
        }
        if (op % 50 == 0) {
            cull_world_commit(w);
            check_world(w, c, m, n);
        }
    }
    check_world(w, c, m, n);
    printf("allocation failures injected into edits: %ld, each left the world unchanged\n", failures);
    assert_true(failures > 100);

    /* queries: an error or the right answer, never a wrong one */
    cull_view v;
    test_view_everything(&v);
    size_t cap = cull_query_bound(w), want, got;
    cull_result *ref = malloc(cap * sizeof *ref), *res = malloc(cap * sizeof *res);
    cull_pool *pool;
    assert_int_equal(cull_pool_create(2, &pool), CULL_OK);
    cull_ctx *c2;
    assert_int_equal(cull_ctx_create(pool, &c2), CULL_OK);
    cull_query_desc q = {.views = &v, .view_count = 1, .threads = 2};
    assert_int_equal(cull_query(w, c, &q, ref, cap, &want, NULL), CULL_OK);
    for (long k = 0; k < 40; k++) {
        cull_ctx *fresh = NULL;
        arm(k);
        int rc = cull_ctx_create(pool, &fresh);
        if (rc == CULL_OK) rc = cull_query(w, fresh, &q, res, cap, &got, NULL);
        disarm();
        assert_true(rc == CULL_OK || rc == CULL_ERR_NOMEM);
        if (rc == CULL_OK) {
            assert_int_equal(got, want);
            assert_memory_equal(res, ref, got * sizeof *res);
        }
        cull_ctx_destroy(fresh);
    }
    for (long k = 0; k < 8; k++) {
        cull_pool *p2 = NULL;
        arm(k);
        int rc = cull_pool_create(3, &p2);
        disarm();
        assert_true(rc == CULL_OK || rc == CULL_ERR_NOMEM);
        assert_true((rc == CULL_OK) == (p2 != NULL));
        cull_pool_destroy(p2);
    }
    free(ref);
    free(res);
    cull_ctx_destroy(c2);
    cull_pool_destroy(pool);
    cull_ctx_destroy(c);
    cull_world_destroy(w);
}

/* Occluders: every add, update and query with occlusion retried with its
 * k-th allocation failing; a failure is CULL_ERR_NOMEM and changes nothing
 * (occluder count, each occluder's info, what a query culls). */
static void test_occluders_under_failing_allocations(void **state)
{
    (void)state;
    rng r = {test_seed() ^ 0x0CCu};
    cull_world *w;
    assert_int_equal(cull_world_create(NULL, &w), CULL_OK);
    cull_ctx *c;
    assert_int_equal(cull_ctx_create(NULL, &c), CULL_OK);
    /* entities behind where the walls go */
    for (int i = 0; i < 200; i++) {
        cull_entity_desc d = {.center = {rng_range(&r, -40, 40), rng_range(&r, 0, 20), rng_range(&r, -80, -30)},
                              .radius = rng_range(&r, 0.1, 2)};
        cull_handle h;
        assert_int_equal(cull_entity_add(w, &d, &h), CULL_OK);
    }
    cull_view_desc vd = {.viewport_w = 256, .viewport_h = 114};
    double proj[16], view[16], dir[3] = {0, 0, -1}, up[3] = {0, 1, 0};
    cull_mat_perspective(proj, 1.2, 256.0 / 114, 0.1, 500, CULL_DEPTH_GL);
    cull_mat_look_dir(view, dir, up);
    cull_mat_mul(vd.view_proj, proj, view);
    vd.origin[1] = 5;
    cull_view v;
    assert_int_equal(cull_view_init(&v, &vd), CULL_OK);
    cull_query_desc q = {.views = &v, .view_count = 1};
    enum { N = 12 };
    cull_occluder oh[N];
    cull_occluder_info info[N];
    uint32_t n = 0;
    size_t expect = 0, got;
    long failures = 0;
    for (int op = 0; op < 3 * N; op++) {
        uint32_t kind = n < N && (op % 3 != 2) ? (rng_below(&r, 2) ? 0 : 1) : 2;
        float quad[18];
        float hts[16];
        double x0 = rng_range(&r, -40, 30), y1 = rng_range(&r, 5, 25), z = rng_range(&r, -25, -12);
        const float q6[6][3] = {{(float)x0, 0, (float)z},       {(float)x0 + 12, 0, (float)z},
                                {(float)x0 + 12, (float)y1, (float)z}, {(float)x0, 0, (float)z},
                                {(float)x0 + 12, (float)y1, (float)z}, {(float)x0, (float)y1, (float)z}};
        memcpy(quad, q6, sizeof quad);
        for (int i = 0; i < 16; i++) hts[i] = (float)rng_range(&r, 0, 10);
        cull_terrain_desc td = {.heights = hts, .nx = 4, .nz = 4, .spacing = 5, .origin = {x0, 0, z - 15}};
        uint32_t i = n ? rng_below(&r, n) : 0;
        for (long k = 0;; k++) {
            int rc;
            cull_occluder h = 0;
            arm(k);
            if (kind == 0) rc = cull_occluder_add(w, &(cull_occluder_desc){.vertices = quad, .vertex_count = 6}, &h);
            else if (kind == 1) rc = cull_terrain_add(w, &td, &h);
            else if (n) rc = cull_occluder_update(w, oh[i], &(cull_occluder_desc){.vertices = quad, .vertex_count = 6});
            else rc = CULL_OK;
            disarm();
            if (rc == CULL_ERR_NOMEM) {
                failures++;
                assert_int_equal(h, 0);
                assert_int_equal(cull_occluder_count(w), n);
                for (uint32_t k2 = 0; k2 < n; k2++) {
                    cull_occluder_info now;
                    assert_int_equal(cull_occluder_get_info(w, oh[k2], &now), CULL_OK);
                    assert_memory_equal(&now, &info[k2], sizeof now);
                }
                assert_int_equal(cull_query(w, c, &(cull_query_desc){.views = &v, .view_count = 1,
                                                                     .flags = CULL_Q_COUNT_ONLY},
                                            NULL, 0, &got, NULL),
                                 CULL_OK);
                if (op) assert_int_equal(got, expect);
                continue;
            }
            assert_int_equal(rc, CULL_OK);
            if (kind <= 1) {
                oh[n] = h;
                assert_int_equal(cull_occluder_get_info(w, h, &info[n]), CULL_OK);
                n++;
            } else if (n) {
                assert_int_equal(cull_occluder_get_info(w, oh[i], &info[i]), CULL_OK);
            }
            break;
        }
        q.flags = CULL_Q_COUNT_ONLY;
        assert_int_equal(cull_query(w, c, &q, NULL, 0, &expect, NULL), CULL_OK);
    }
    /* a query whose occlusion buffers cannot be made fails whole */
    cull_ctx *c2;
    assert_int_equal(cull_ctx_create(NULL, &c2), CULL_OK);
    for (long k = 0;; k++) {
        arm(k);
        int rc = cull_query(w, c2, &(cull_query_desc){.views = &v, .view_count = 1, .flags = CULL_Q_COUNT_ONLY},
                            NULL, 0, &got, NULL);
        disarm();
        if (rc == CULL_ERR_NOMEM) {
            failures++;
            continue;
        }
        assert_int_equal(rc, CULL_OK);
        assert_int_equal(got, expect);
        break;
    }
    fprintf(stderr, "allocation failures injected into occluder edits and queries: %ld, none changed anything\n",
            failures);
    assert_true(failures > 20);
    cull_ctx_destroy(c2);
    cull_ctx_destroy(c);
    cull_world_destroy(w);
}

/* The daemon's edits under failing allocations (the scene's own and the
 * culling core's, through daemon/errmap.c): every failure of an ADD is
 * BUSY, "out of memory" in its message, with nothing added; then it
 * succeeds. Out of memory was LIMIT in scene.c and BUSY in frames.c. */
static void test_scene_edits_out_of_memory_are_busy(void **state)
{
    (void)state;
    enum { N = 600 };
    static const scene_limits lim = {.max_entities = 1u << 16, .max_lights = 64, .max_occluders = 64,
                                     .max_occluder_tris = 1024, .max_mesh_verts = 1024};
    scene *sc = malloc(sizeof *sc); /* megabytes: not on the stack */
    assert_non_null(sc);
    assert_int_equal(scene_init(sc, 16, &lim), 0);
    vp_entity *ents = calloc(N, sizeof *ents);
    size_t cap = vp_size_entities(N);
    uint8_t *buf = malloc(cap);
    uint32_t *handles = calloc(N, sizeof *handles);
    assert_true(ents && buf && handles);
    for (uint32_t i = 0; i < N; i++) /* spread over many cells: the grid grows */
        ents[i] = (vp_entity){.id = 1000 + i, .sphere = {(double)(i % 40) * 50.0, 0, (double)(i / 40) * 50.0, 1}};
    vp_writer w;
    vp_writer_init(&w, buf, cap);
    vp_enc_entities(&w, VP_ENTITY_ADD, 1, ents, N);
    free(ents);
    assert_false(w.overflow);
    vp_entity_batch b;
    assert_int_equal(vp_dec_entities(buf + VP_HEADER_SIZE, w.len - VP_HEADER_SIZE, 0, &b), VP_OK);
    long failures = 0;
    for (long k = 0;; k++) {
        scene_err e = {0};
        arm(k);
        int rc = scene_add(sc, 0, &b, handles, &e);
        disarm();
        cull_world_info info;
        cull_world_info_get(sc->world, &info);
        if (rc == VP_OK) {
            assert_int_equal(info.entities, N);
            break;
        }
        if (rc != VP_ERR_BUSY || !strstr(e.msg, "out of memory"))
            fail_msg("allocation %ld failing: %d (%s) '%s', want BUSY, out of memory", k, rc, vp_strerror(rc), e.msg);
        assert_int_equal(info.entities, 0);
        failures++;
        assert_true(k < 100000);
    }
    scene_free(sc);
    free(sc);
    free(buf);
    free(handles);
    assert_true(failures > 0);
}

/* TEXTURE_PUT under failing allocations (the decoders', the mip chain's,
 * the store's): every failure is BUSY, nothing stored, nothing charged
 * (and, under ASan, nothing leaked); then it succeeds. PNG and JPEG. */
static void test_textures_under_failing_allocations(void **state)
{
    (void)state;
    static const scene_limits lim = {.max_entities = 64, .max_texture_size = 64, .max_texture_mem = 1u << 20};
    uint8_t px[13 * 7 * 4];
    for (size_t i = 0; i < sizeof px; i++) px[i] = (uint8_t)(i * 29 + 7);
    char err[256];
    tdir t;
    tdir_make(&t, "texalloc");
    const char *path = tdir_file(&t, "a.png");
    assert_int_equal(vt_png_write(path, 13, 7, px, 13 * 4, true, 1, err, sizeof err), 0);
    size_t n[2];
    uint8_t *img[2] = {test_slurp(path, &n[0]), NULL};
    assert_int_equal(vt_jpeg_encode(13, 7, px, 13 * 4, 4, 90, &img[1], &n[1], err, sizeof err), 0);
    for (int f = 0; f < 2; f++) {
        scene *sc = malloc(sizeof *sc);
        assert_non_null(sc);
        assert_int_equal(scene_init(sc, 16, &lim), 0);
        vp_texture_put m = {.id = 3, .format = f ? VP_TEX_JPEG : VP_TEX_PNG, .flags = VP_TEX_SRGB,
                            .total = (uint32_t)n[f], .len = (uint32_t)n[f], .data = img[f]};
        long failures = 0;
        for (long k = 0;; k++) {
            scene_err e = {0};
            arm(k);
            int rc = scene_texture_put(sc, &m, &e);
            disarm();
            if (rc == VP_OK) break;
            if (rc != VP_ERR_BUSY) fail_msg("allocation %ld failing: %d (%s) '%s', want BUSY", k, rc, vp_strerror(rc), e.msg);
            assert_int_equal(sc->textures.count, 0);
            assert_int_equal(sc->texture_mem, 0);
            failures++;
            assert_true(k < 10000);
        }
        assert_non_null(scene_texture_find(sc, 3));
        assert_true(failures > 3);
        scene_free(sc);
        free(sc);
        free(img[f]);
    }
    tdir_remove(&t);
}

/* vt_jpeg_encode_par's runner here: the bands one after another on this
 * thread (the failing allocator counts calls without locks). */
static void serial_run(void *ctx, vt_jpeg_job_fn fn, void *arg, uint32_t n)
{
    (void)ctx;
    for (uint32_t t = 0; t < n; t++) fn(arg, t);
}

/* The banded JPEG under failing allocations (its job, each band's
 * stream, the splice): every failure is VT_ERR_NOMEM with nothing
 * returned (and, under ASan, nothing leaked), or one the call does
 * without, its stream decoding as one vt_jpeg_encode's. */
static void test_jpeg_bands_under_failing_allocations(void **state)
{
    (void)state;
    enum { W = 40, H = 50 };
    static uint8_t px[W * H * 4];
    for (size_t i = 0; i < sizeof px; i++) px[i] = (uint8_t)(i * 31 + i / 97);
    char err[256];
    uint8_t *one = NULL, *d1 = NULL, *d2 = NULL, *out = NULL;
    size_t n1, n;
    uint32_t w, h;
    assert_int_equal(vt_jpeg_encode(W, H, px, W * 4, 4, 80, &one, &n1, err, sizeof err), 0);
    vt_jpeg_par par = {.bands = 3, .run = serial_run};
    assert_int_equal(vt_jpeg_decode(one, n1, &d1, &w, &h, err, sizeof err), 0);
    /* the allocations of a run (armed past them all), then each failing
       in turn: a failure either fails the call or is one it can do
       without (a stream's slack not given back) */
    arm(LONG_MAX);
    assert_int_equal(vt_jpeg_encode_par(W, H, px, W * 4, 4, 80, &par, &out, &n, err, sizeof err), 0);
    long calls = g_calls;
    disarm();
    free(out);
    long failures = 0;
    for (long k = 0; k < calls; k++) {
        arm(k);
        int rc = vt_jpeg_encode_par(W, H, px, W * 4, 4, 80, &par, &out, &n, err, sizeof err);
        disarm();
        if (rc == 0) {
            assert_int_equal(vt_jpeg_decode(out, n, &d2, &w, &h, err, sizeof err), 0);
            assert_memory_equal(d1, d2, (size_t)W * H * 3);
            free(out), free(d2);
            continue;
        }
        if (rc != VT_ERR_NOMEM) fail_msg("allocation %ld failing: %d '%s', want VT_ERR_NOMEM", k, rc, err);
        assert_null(out);
        assert_int_equal(n, 0);
        failures++;
    }
    /* the job; each of the 2 bands' job and stream; the splice */
    if (failures < 6) fail_msg("%ld of %ld allocations failed the call, want 6 or more", failures, calls);
    free(one), free(d1);
}

/* The H.264 encoder under failing allocations: its own (the encoder, the
 * conversion's rows; x264 allocates through libx264's own malloc, which
 * the wrappers do not reach) each fail vt_h264_open with VT_ERR_NOMEM,
 * nothing returned and, under ASan, nothing leaked; then an encoder opens
 * and encodes. The conversion alone likewise. */
static void test_h264_under_failing_allocations(void **state)
{
    (void)state;
    char err[256];
    vt_h264_cfg cfg = {.width = 34, .height = 18};
    static uint8_t px[34 * 18 * 3], planes[34 * 18 * 2];
    long failures = 0;
    for (long k = 0;; k++) {
        vt_h264 *e = (vt_h264 *)(uintptr_t)1;
        arm(k);
        int rc = vt_h264_open(&e, &cfg, err, sizeof err);
        disarm();
        if (rc == 0) {
            const uint8_t *au;
            size_t len;
            bool key;
            assert_int_equal(vt_h264_encode(e, px, 34 * 3, 3, false, &au, &len, &key, err, sizeof err), 0);
            assert_true(key && len > 0);
            vt_h264_close(e);
            break;
        }
        if (rc != VT_ERR_NOMEM) fail_msg("allocation %ld failing: %d '%s', want VT_ERR_NOMEM", k, rc, err);
        assert_null(e);
        failures++;
    }
    assert_int_equal(failures, 2);
    arm(0);
    int rc = vt_h264_rgb_to_i420(34, 18, px, 34 * 3, 3, planes, 34, planes + 34 * 18, 17, planes + 34 * 18 * 5 / 4, 17);
    disarm();
    assert_int_equal(rc, VT_ERR_NOMEM);
}

const struct CMUnitTest alloc_tests[] = {
    cmocka_unit_test(test_h264_under_failing_allocations),
    cmocka_unit_test(test_textures_under_failing_allocations),
    cmocka_unit_test(test_jpeg_bands_under_failing_allocations),
    cmocka_unit_test(test_occluders_under_failing_allocations),
    cmocka_unit_test(test_edits_under_failing_allocations),
    cmocka_unit_test(test_scene_edits_out_of_memory_are_busy),
};
const size_t alloc_tests_count = sizeof alloc_tests / sizeof alloc_tests[0];
