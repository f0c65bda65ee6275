/*
 * test_view.c — frustum planes from matrices: every depth convention,
 * perspective and orthographic, infinite far planes, against the long
 * double model and against points placed by hand; bad matrices rejected.
 */
#include "test_util.h"

#include "cull_ref.h"
#include "culling.h"
#include <string.h>

static double plane_dist(const cull_view *v, int i, const double p[3])
{
    return v->plane[i][0] * (p[0] - v->origin[0]) + v->plane[i][1] * (p[1] - v->origin[1]) +
           v->plane[i][2] * (p[2] - v->origin[2]) + v->plane[i][3];
}

static bool inside(const cull_view *v, const double p[3])
{
    for (uint32_t i = 0; i < v->plane_count; i++)
        if (plane_dist(v, (int)i, p) < 0) return false;
    return true;
}

static void persp_view(cull_view *v, uint32_t mode, double n, double f)
{
    cull_view_desc d = {.depth_mode = mode};
    cull_mat_perspective(d.view_proj, 90 * M_PI / 180, 2.0, n, f, mode);
    assert_int_equal(cull_view_init(v, &d), CULL_OK);
}

static void test_perspective_modes(void **state)
{
    (void)state;
    for (uint32_t mode = CULL_DEPTH_GL; mode <= CULL_DEPTH_REVERSED; mode++) {
        cull_view v;
        persp_view(&v, mode, 1, 100);
        assert_int_equal(v.plane_count, 6);
        /* camera looks down -z; half-height = depth, half-width = 2*depth */
        assert_true(inside(&v, (double[]){0, 0, -50}));
        assert_true(inside(&v, (double[]){99, 49, -50}));
        assert_false(inside(&v, (double[]){101, 0, -50}));
        assert_false(inside(&v, (double[]){0, 51, -50}));
        assert_false(inside(&v, (double[]){0, 0, -0.9}));
        assert_true(inside(&v, (double[]){0, 0, -1.1}));
        assert_true(inside(&v, (double[]){0, 0, -99.9}));
        assert_false(inside(&v, (double[]){0, 0, -100.1}));
        assert_false(inside(&v, (double[]){0, 0, 50}));
        for (uint32_t i = 0; i < 6; i++) {
            double l = sqrt(v.plane[i][0] * v.plane[i][0] + v.plane[i][1] * v.plane[i][1] +
                            v.plane[i][2] * v.plane[i][2]);
            assert_true(fabs(l - 1) < 1e-12);
        }
        /* the near plane's distance is metric: 0.4 m beyond it */
        bool found = false;
        for (uint32_t i = 0; i < 6; i++)
            if (fabs(plane_dist(&v, (int)i, (double[]){0, 0, -1.4}) - 0.4) < 1e-9) found = true;
        assert_true(found);
        /* infinite far: 5 planes, and far away is still inside */
        persp_view(&v, mode, 0.01, INFINITY);
        assert_int_equal(v.plane_count, 5);
        assert_true(inside(&v, (double[]){0, 0, -1e15}));
        assert_false(inside(&v, (double[]){0, 0, -0.009}));
    }
}

static void test_ortho_modes(void **state)
{
    (void)state;
    for (uint32_t mode = CULL_DEPTH_GL; mode <= CULL_DEPTH_REVERSED; mode++) {
        cull_view_desc d = {.depth_mode = mode};
        cull_mat_ortho(d.view_proj, -10, 30, -5, 5, 2, 50, mode);
        cull_view v;
        assert_int_equal(cull_view_init(&v, &d), CULL_OK);
        assert_int_equal(v.plane_count, 6);
        assert_true(inside(&v, (double[]){29.9, 4.9, -49.9}));
        assert_true(inside(&v, (double[]){-9.9, -4.9, -2.1}));
        assert_false(inside(&v, (double[]){30.1, 0, -10}));
        assert_false(inside(&v, (double[]){-10.1, 0, -10}));
        assert_false(inside(&v, (double[]){0, 0, -1.9}));
        assert_false(inside(&v, (double[]){0, 0, -50.1}));
        double min = INFINITY;
        for (int i = 0; i < 6; i++) min = fmin(min, plane_dist(&v, i, (double[]){31, 0, -10}));
        assert_true(fabs(min + 1) < 1e-12);
    }
}

/* Random matrices: planes agree with the long double model's. */
static void test_planes_vs_model(void **state)
{
    (void)state;
    rng r = {test_seed() ^ 0x2222};
    for (int it = 0; it < 2000; it++) {
        cull_view_desc d = {.depth_mode = rng_below(&r, 3)};
        double proj[16], view[16];
        if (rng_below(&r, 3))
            cull_mat_perspective(proj, rng_range(&r, 0.1, 2.5), rng_range(&r, 0.3, 3), rng_log(&r, 1e-4, 10),
                                 rng_below(&r, 4) ? rng_log(&r, 20, 1e7) : INFINITY, d.depth_mode);
        else
            cull_mat_ortho(proj, -rng_log(&r, 1, 1e4), rng_log(&r, 1, 1e4), -rng_log(&r, 1, 1e4),
                           rng_log(&r, 1, 1e4), rng_range(&r, -100, 10), rng_log(&r, 20, 1e6), d.depth_mode);
        double dir[3] = {rng_range(&r, -1, 1), rng_range(&r, -1, 1), rng_range(&r, -1, 1)};
        cull_mat_look_dir(view, dir, (double[]){0, 1, 0});
        cull_mat_mul(d.view_proj, proj, view);
        for (int a = 0; a < 3; a++) d.origin[a] = rng_range(&r, -1e6, 1e6);
        cull_view v;
        if (cull_view_init(&v, &d) != CULL_OK) continue; /* dir parallel to up */
        ref_view rv;
        ref_view_make(&rv, &d);
        for (int k = 0; k < 20; k++) {
            double p[3];
            for (int a = 0; a < 3; a++) p[a] = d.origin[a] + rng_range(&r, -1e3, 1e3);
            ref_verdict rr;
            cull_entity_desc e = {.center = {p[0], p[1], p[2]}, .aabb_min = {p[0], p[1], p[2]},
                                  .aabb_max = {p[0], p[1], p[2]}};
            ref_test(&rv, &e, &rr);
            double mine = INFINITY;
            for (uint32_t i = 0; i < v.plane_count; i++) mine = fmin(mine, plane_dist(&v, (int)i, p));
            assert_true(fabsl((long double)mine - rr.sphere_margin) <= 1e-9 * (1 + fabs(mine)));
        }
    }
}

static void test_bad_matrices(void **state)
{
    (void)state;
    cull_view v;
    cull_view_desc d = {0};
    assert_int_equal(cull_view_init(&v, &d), CULL_ERR_MATRIX); /* all zero */
    cull_mat_perspective(d.view_proj, 1, 1, 1, 10, CULL_DEPTH_GL);
    assert_int_equal(cull_view_init(&v, &d), CULL_OK);
    cull_view_desc b = d;
    b.view_proj[5] = NAN;
    assert_int_equal(cull_view_init(&v, &b), CULL_ERR_MATRIX);
    b = d;
    b.view_proj[0] = INFINITY;
    assert_int_equal(cull_view_init(&v, &b), CULL_ERR_MATRIX);
    b = d;
    for (int c = 0; c < 4; c++) b.view_proj[c * 4 + 1] = b.view_proj[c * 4 + 0]; /* rank 3 */
    assert_int_equal(cull_view_init(&v, &b), CULL_ERR_MATRIX);
    b = d;
    b.viewport_w = 0;
    b.viewport_h = 5;
    assert_int_equal(cull_view_init(&v, &b), CULL_ERR_VIEWPORT);
    b.viewport_w = 70000;
    assert_int_equal(cull_view_init(&v, &b), CULL_ERR_VIEWPORT);
    b = d;
    b.depth_mode = 7;
    assert_int_equal(cull_view_init(&v, &b), CULL_ERR_INVALID);
    b = d;
    b.origin[1] = NAN;
    assert_int_equal(cull_view_init(&v, &b), CULL_ERR_NONFINITE);
    assert_int_equal(cull_view_init(NULL, &d), CULL_ERR_INVALID);
    /* a frustum that is empty: far plane at infinity facing away */
    b = d;
    memset(b.view_proj, 0, sizeof b.view_proj);
    b.view_proj[0] = b.view_proj[5] = 1;
    b.view_proj[10] = 1;  /* z row (0,0,1,-1) and w row (0,0,1,-1): */
    b.view_proj[14] = -1; /* x-y ok, but w - z = 0 with d 0 */
    b.view_proj[11] = 1;
    b.view_proj[15] = -1;
    assert_int_equal(cull_view_init(&v, &b), CULL_ERR_MATRIX);
}

const struct CMUnitTest view_tests[] = {
    cmocka_unit_test(test_perspective_modes),
    cmocka_unit_test(test_ortho_modes),
    cmocka_unit_test(test_planes_vs_model),
    cmocka_unit_test(test_bad_matrices),
};
const size_t view_tests_count = sizeof view_tests / sizeof view_tests[0];
