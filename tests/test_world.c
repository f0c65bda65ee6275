/*
 * test_world.c — scene storage: handles, add/update/remove against a plain
 * array model, bad input rejected with nothing changed, capacity, far cells.
 */
#include "test_util.h"

#include "culling.h"
#include <string.h>

static cull_world *mk_world(double cell, uint32_t max)
{
    cull_world *w = NULL;
    assert_int_equal(cull_world_create(&(cull_world_desc){.cell_size = cell, .max_entities = max}, &w),
                     CULL_OK);
    return w;
}

static size_t query_all(cull_world *w, cull_result **res)
{
    return test_query_everything(w, NULL, res);
}

static void test_create_destroy(void **state)
{
    (void)state;
    cull_world *w = NULL;
    assert_int_equal(cull_world_create(NULL, &w), CULL_OK);
    cull_world_info info;
    cull_world_info_get(w, &info);
    assert_int_equal(info.entities, 0);
    assert_int_equal(info.cells, 0);
    cull_world_destroy(w);
    cull_world_destroy(NULL);
    assert_int_equal(cull_world_create(&(cull_world_desc){.cell_size = -1}, &w), CULL_ERR_RANGE);
    assert_null(w);
    assert_int_equal(cull_world_create(&(cull_world_desc){.cell_size = NAN}, &w), CULL_ERR_RANGE);
    assert_int_equal(cull_world_create(&(cull_world_desc){.max_entities = CULL_MAX_ENTITIES + 1}, &w),
                     CULL_ERR_RANGE);
    assert_int_equal(cull_world_create(NULL, NULL), CULL_ERR_INVALID);
    assert_string_equal(cull_strerror(CULL_ERR_HANDLE), "stale or never-issued entity handle");
    assert_string_equal(cull_strerror(12345), "unknown error");
}

static void test_add_get_derive(void **state)
{
    (void)state;
    cull_world *w = mk_world(0, 0);
    cull_handle h1, h2, h3;
    /* sphere only: AABB derived */
    assert_int_equal(cull_entity_add(w, &(cull_entity_desc){.center = {1, 2, 3}, .radius = 2, .class_id = 7,
                                                              .sublevel = 9},
                                     &h1),
                     CULL_OK);
    /* AABB only: sphere derived */
    assert_int_equal(cull_entity_add(w, &(cull_entity_desc){.aabb_min = {0, 0, 0}, .aabb_max = {2, 4, 4},
                                                              .flags = CULL_ENTITY_DYNAMIC},
                                     &h2),
                     CULL_OK);
    /* point */
    assert_int_equal(cull_entity_add(w, &(cull_entity_desc){.center = {-5, 0, 0}}, &h3), CULL_OK);
    assert_int_not_equal(h1, 0);
    assert_int_not_equal(h1, h2);
    cull_entity_desc d;
    assert_int_equal(cull_entity_get(w, h1, &d), CULL_OK);
    assert_true(d.aabb_min[0] == -1 && d.aabb_max[2] == 5 && d.class_id == 7 && d.sublevel == 9);
    assert_int_equal(cull_entity_get(w, h2, &d), CULL_OK);
    assert_true(d.center[0] == 1 && d.center[1] == 2 && d.center[2] == 2 && d.radius == 3);
    assert_int_equal(cull_entity_get(w, h3, &d), CULL_OK);
    assert_true(d.radius == 0 && d.aabb_min[0] == -5 && d.aabb_max[0] == -5);
    cull_world_info info;
    cull_world_info_get(w, &info);
    assert_int_equal(info.entities, 3);
    assert_int_equal(info.static_entities, 2);
    assert_int_equal(info.dynamic_entities, 1);
    cull_world_destroy(w);
}

/* An entity the world refuses, added and as an update of one it holds:
 * the code, no handle written, nothing changed. */
typedef struct bad_entity {
    const char *name;
    cull_entity_desc d;
    int code;
} bad_entity;

static const bad_entity bad_entities[] = {
    {"centre x NaN", {.center = {NAN, 0, 0}, .radius = 1}, CULL_ERR_NONFINITE},
    {"centre y inf", {.center = {0, INFINITY, 0}, .radius = 1}, CULL_ERR_NONFINITE},
    {"aabb min z -inf", {.aabb_min = {0, 0, -INFINITY}, .aabb_max = {1, 1, 1}}, CULL_ERR_NONFINITE},
    {"radius -1", {.center = {0, 0, 0}, .radius = -1}, CULL_ERR_RADIUS},
    {"radius NaN", {.center = {0, 0, 0}, .radius = NAN}, CULL_ERR_RADIUS},
    {"radius inf", {.center = {0, 0, 0}, .radius = INFINITY}, CULL_ERR_RADIUS},
    {"aabb min x > max x", {.aabb_min = {1, 0, 0}, .aabb_max = {0, 1, 1}}, CULL_ERR_AABB},
    {"aabb min z > max z, with a radius", {.aabb_min = {0, 0, 2}, .aabb_max = {1, 1, 1}, .radius = 3}, CULL_ERR_AABB},
    {"centre 2e12", {.center = {2e12, 0, 0}, .radius = 1}, CULL_ERR_RANGE},
    {"radius 2e9", {.center = {0, 0, 0}, .radius = 2e9}, CULL_ERR_RANGE},
    /* 1e12 m is a valid coordinate, but not with 64 m cells (int32 keys) */
    {"centre z 1e12 with 64 m cells", {.center = {0, 0, 1e12}, .radius = 1}, CULL_ERR_RANGE},
};

static void test_bad_input_changes_nothing(void **state)
{
    const bad_entity *t = *state;
    cull_world *w = mk_world(0, 0);
    cull_handle h = 0xDEAD, keep;
    assert_int_equal(cull_entity_add(w, &(cull_entity_desc){.center = {1, 1, 1}, .radius = 1}, &keep),
                     CULL_OK);
    cull_world_info before, after;
    cull_world_info_get(w, &before);
    assert_int_equal(cull_entity_add(w, &t->d, &h), t->code);
    assert_int_equal(h, 0xDEAD);
    assert_int_equal(cull_entity_update(w, keep, &t->d), t->code);
    cull_world_info_get(w, &after);
    assert_memory_equal(&before, &after, sizeof before);
    cull_entity_desc d;
    assert_int_equal(cull_entity_get(w, keep, &d), CULL_OK);
    assert_true(d.center[0] == 1 && d.radius == 1);
    cull_world_destroy(w);
}

/* NULL arguments are refused. */
static void test_null_entity_refused(void **state)
{
    (void)state;
    cull_world *w = mk_world(0, 0);
    cull_handle h;
    cull_entity_desc d = {.center = {1, 1, 1}, .radius = 1};
    assert_int_equal(cull_entity_add(w, NULL, &h), CULL_ERR_INVALID);
    assert_int_equal(cull_entity_add(NULL, &d, &h), CULL_ERR_INVALID);
    cull_world_destroy(w);
}

static void test_stale_handles(void **state)
{
    (void)state;
    cull_world *w = mk_world(0, 0);
    cull_handle h, h2;
    cull_entity_desc d = {.center = {3, 3, 3}, .radius = 1};
    assert_int_equal(cull_entity_remove(w, 0), CULL_ERR_HANDLE);
    assert_int_equal(cull_entity_remove(w, 12345), CULL_ERR_HANDLE);
    assert_int_equal(cull_entity_add(w, &d, &h), CULL_OK);
    assert_int_equal(cull_entity_remove(w, h), CULL_OK);
    assert_int_equal(cull_entity_remove(w, h), CULL_ERR_HANDLE);
    assert_int_equal(cull_entity_update(w, h, &d), CULL_ERR_HANDLE);
    assert_int_equal(cull_entity_get(w, h, &d), CULL_ERR_HANDLE);
    /* the slot is reused with a new generation: the old handle stays stale */
    assert_int_equal(cull_entity_add(w, &d, &h2), CULL_OK);
    assert_int_not_equal(h, h2);
    assert_int_equal(h & (CULL_MAX_ENTITIES - 1), h2 & (CULL_MAX_ENTITIES - 1));
    assert_int_equal(cull_entity_get(w, h, &d), CULL_ERR_HANDLE);
    assert_int_equal(cull_entity_get(w, h2, &d), CULL_OK);
    /* a forged generation on a live slot */
    assert_int_equal(cull_entity_get(w, h2 ^ (1u << 30), &d), CULL_ERR_HANDLE);
    cull_world_destroy(w);
}

static void test_capacity(void **state)
{
    (void)state;
    cull_world *w = mk_world(0, 10);
    cull_handle h[11];
    for (int i = 0; i < 10; i++)
        assert_int_equal(cull_entity_add(w, &(cull_entity_desc){.center = {i * 100.0, 0, 0}, .radius = 1}, &h[i]),
                         CULL_OK);
    assert_int_equal(cull_entity_add(w, &(cull_entity_desc){.radius = 1}, &h[10]), CULL_ERR_CAPACITY);
    cull_result *res;
    size_t n = query_all(w, &res);
    assert_int_equal(n, 10);
    free(res);
    assert_int_equal(cull_entity_remove(w, h[4]), CULL_OK);
    assert_int_equal(cull_entity_add(w, &(cull_entity_desc){.radius = 1}, &h[10]), CULL_OK);
    cull_world_destroy(w);
}

typedef struct model_ent {
    cull_handle h;
    cull_entity_desc d;
} model_ent;

static void random_desc(rng *r, cull_entity_desc *d, double span)
{
    memset(d, 0, sizeof *d);
    for (int a = 0; a < 3; a++) d->center[a] = rng_range(r, -span, span);
    d->radius = rng_log(r, 1e-3, 50);
    d->class_id = (uint16_t)rng_below(r, 65536);
    d->sublevel = (uint16_t)rng_below(r, 65536);
    d->flags = rng_below(r, 2) ? CULL_ENTITY_DYNAMIC : 0;
}

/* Random add / move (in cell, across cells, across grids) / remove against
 * an array model; after every step batch: counts, get(), stale handles and
 * an everything-view query must agree with the model. */
static void test_ops_vs_model(void **state)
{
    (void)state;
    rng r = {test_seed() ^ 0x1111};
    cull_world *w = mk_world(16, 0);
    size_t cap = 6000, n = 0, nstale = 0;
    model_ent *m = calloc(cap, sizeof *m);
    cull_handle *stale = calloc(200000, sizeof *stale);
    int rounds = (int)(60 * test_scale()) + 1;
    for (int round = 0; round < rounds; round++) {
        for (int step = 0; step < 300; step++) {
            uint32_t op = rng_below(&r, 10);
            double span = rng_below(&r, 4) == 0 ? 1e6 : 200;
            if (op < 4 || n == 0) {
                if (n == cap) continue;
                random_desc(&r, &m[n].d, span);
                assert_int_equal(cull_entity_add(w, &m[n].d, &m[n].h), CULL_OK);
                cull_entity_get(w, m[n].h, &m[n].d); /* the normalised form */
                n++;
            } else if (op < 8) {
                size_t i = rng_below(&r, (uint32_t)n);
                cull_entity_desc d = m[i].d;
                if (op == 7) {
                    random_desc(&r, &d, span);
                } else { /* small move: usually stays in its cell */
                    for (int a = 0; a < 3; a++) d.center[a] += rng_range(&r, -0.5, 0.5);
                    memset(d.aabb_min, 0, sizeof d.aabb_min);
                    memset(d.aabb_max, 0, sizeof d.aabb_max);
                }
                assert_int_equal(cull_entity_update(w, m[i].h, &d), CULL_OK);
                cull_entity_get(w, m[i].h, &m[i].d);
                assert_true(m[i].d.center[0] == d.center[0] && m[i].d.flags == d.flags);
            } else {
                size_t i = rng_below(&r, (uint32_t)n);
                assert_int_equal(cull_entity_remove(w, m[i].h), CULL_OK);
                if (nstale < 200000) stale[nstale++] = m[i].h;
                m[i] = m[--n];
            }
        }
        if (round % 3 == 0) cull_world_commit(w);
        cull_world_info info;
        cull_world_info_get(w, &info);
        assert_int_equal(info.entities, n);
        uint32_t dyn = 0;
        for (size_t i = 0; i < n; i++) {
            cull_entity_desc d;
            assert_int_equal(cull_entity_get(w, m[i].h, &d), CULL_OK);
            assert_memory_equal(&d, &m[i].d, sizeof d);
            dyn += (m[i].d.flags & CULL_ENTITY_DYNAMIC) != 0;
        }
        assert_int_equal(info.dynamic_entities, dyn);
        for (size_t i = 0; i < nstale; i++) {
            cull_entity_desc d;
            /* a stale handle may only be valid again if its slot's 10-bit
               generation wrapped, which needs >1000 reuses: not here */
            assert_int_equal(cull_entity_get(w, stale[i], &d), CULL_ERR_HANDLE);
        }
        cull_result *res;
        size_t got = query_all(w, &res);
        cull_handle *want = malloc((n + 1) * sizeof *want);
        for (size_t i = 0; i < n; i++) want[i] = m[i].h;
        test_assert_same_handles(want, n, res, got);
        free(want);
        for (size_t i = 0; i < n; i++) {
            cull_entity_desc d;
            assert_int_equal(cull_entity_get(w, res[i].handle, &d), CULL_OK);
            assert_int_equal(res[i].class_id, d.class_id);
            assert_int_equal(res[i].sublevel, d.sublevel);
            assert_int_equal(res[i].view_mask, 1);
        }
        free(res);
    }
    /* remove everything: every cell and block is given back */
    while (n) assert_int_equal(cull_entity_remove(w, m[--n].h), CULL_OK);
    cull_world_info info;
    cull_world_info_get(w, &info);
    assert_int_equal(info.entities, 0);
    assert_int_equal(info.cells, 0);
    assert_int_equal(info.blocks, 0);
    free(m);
    free(stale);
    cull_world_destroy(w);
}

static void test_far_cells(void **state)
{
    (void)state;
    cull_world *w = mk_world(1000, 0);
    const double far[][3] = {{1e12, -1e12, 5e11}, {-9.99e11, 0, 0}, {0, 0, 0}, {123456789.123, 7, -987654321.5}};
    cull_handle h[4];
    for (int i = 0; i < 4; i++) {
        cull_entity_desc d = {.radius = 0.25};
        memcpy(d.center, far[i], sizeof d.center);
        assert_int_equal(cull_entity_add(w, &d, &h[i]), CULL_OK);
    }
    /* a tight view around each far entity sees it, and only it */
    cull_ctx *c;
    assert_int_equal(cull_ctx_create(NULL, &c), CULL_OK);
    for (int i = 0; i < 4; i++) {
        cull_view_desc vd = {.viewport_w = 64, .viewport_h = 64};
        memcpy(vd.origin, far[i], sizeof vd.origin);
        vd.origin[2] += 10; /* eye 10 m behind, looking down -z */
        double proj[16], view[16];
        cull_mat_perspective(proj, 0.1, 1, 0.5, 100, CULL_DEPTH_ZERO_ONE);
        cull_mat_look_dir(view, (double[]){0, 0, -1}, (double[]){0, 1, 0});
        cull_mat_mul(vd.view_proj, proj, view);
        cull_view v;
        assert_int_equal(cull_view_init(&v, &vd), CULL_OK);
        cull_result res[4 + CULL_RESULT_PAD];
        size_t n;
        assert_int_equal(cull_query(w, c, &(cull_query_desc){.views = &v, .view_count = 1}, res, 12, &n, NULL),
                         CULL_OK);
        assert_int_equal(n, 1);
        assert_int_equal(res[0].handle, h[i]);
        /* a 0.8 m sideways shift of the camera loses it (frustum is
           ~0.1 rad * 10 m = 1 m wide; entity radius 0.25) */
        vd.origin[0] += 0.8;
        assert_int_equal(cull_view_init(&v, &vd), CULL_OK);
        assert_int_equal(cull_query(w, c, &(cull_query_desc){.views = &v, .view_count = 1}, res, 12, &n, NULL),
                         CULL_OK);
        assert_int_equal(n, 0);
    }
    cull_ctx_destroy(c);
    cull_world_destroy(w);
}

static void test_many_in_one_cell(void **state)
{
    (void)state;
    /* several blocks in one cell; removal from the middle keeps handles */
    cull_world *w = mk_world(1000, 0);
    enum { N = 300 };
    cull_handle h[N];
    for (int i = 0; i < N; i++)
        assert_int_equal(cull_entity_add(w, &(cull_entity_desc){.center = {i, 1, 1}, .radius = 0.5,
                                                                  .class_id = (uint16_t)i},
                                         &h[i]),
                         CULL_OK);
    cull_world_info info;
    cull_world_info_get(w, &info);
    assert_int_equal(info.cells, 1);
    assert_int_equal(info.blocks, 5);
    for (int i = 0; i < N; i += 2) assert_int_equal(cull_entity_remove(w, h[i]), CULL_OK);
    cull_world_info_get(w, &info);
    assert_int_equal(info.blocks, 3);
    for (int i = 1; i < N; i += 2) {
        cull_entity_desc d;
        assert_int_equal(cull_entity_get(w, h[i], &d), CULL_OK);
        assert_int_equal(d.class_id, i);
    }
    cull_result *res;
    size_t n = query_all(w, &res);
    assert_int_equal(n, N / 2);
    for (size_t i = 0; i < n; i++) assert_int_equal(res[i].class_id % 2, 1);
    free(res);
    cull_world_destroy(w);
}

const struct CMUnitTest world_tests[] = {
    cmocka_unit_test(test_create_destroy),
    cmocka_unit_test(test_add_get_derive),
    TEST_ROWS(test_bad_input_changes_nothing, bad_entities),
    cmocka_unit_test(test_null_entity_refused),
    cmocka_unit_test(test_stale_handles),
    cmocka_unit_test(test_capacity),
    cmocka_unit_test(test_ops_vs_model),
    cmocka_unit_test(test_far_cells),
    cmocka_unit_test(test_many_in_one_cell),
};
const size_t world_tests_count = sizeof world_tests / sizeof world_tests[0];
