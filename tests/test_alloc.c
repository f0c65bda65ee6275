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

const struct CMUnitTest alloc_tests[] = {
    cmocka_unit_test(test_edits_under_failing_allocations),
};
const size_t alloc_tests_count = sizeof alloc_tests / sizeof alloc_tests[0];
