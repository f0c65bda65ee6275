/*
 * test_destruct.c — destruction distance volumes against brute force: the
 * exact signed distance to the sphere set (cull_dvol_exact, a plain loop
 * in double). At the samples the field holds that distance to float
 * rounding; between them, trilinear filtering stays within the stated
 * bound (the voxel diagonal) of it; a field built sphere by sphere equals
 * one rebuilt from the set, bit for bit. Boxes near and 1e5 m from the
 * origin, flat boxes, 1..64 spheres, resolutions 2..16.
 */
#include "test_util.h"

#include <stdio.h>
#include <string.h>

static void random_box(rng *r, double lo[3], double hi[3])
{
    double base = rng_below(r, 3) == 0 ? rng_range(r, -1e5, 1e5) : 0;
    for (int a = 0; a < 3; a++) {
        double c = base + rng_range(r, -50, 50), e = rng_below(r, 10) == 0 ? 0 : rng_log(r, 0.5, 40);
        lo[a] = c - e;
        hi[a] = c + e;
    }
}

static void test_dvol_matches_brute_force(void **state)
{
    (void)state;
    rng r = {test_seed() ^ 0xD1u};
    double worst_grid = 0, worst_ratio = 0;
    uint64_t points = 0;
    for (int f = 0; f < 200; f++) {
        double lo[3], hi[3];
        random_box(&r, lo, hi);
        uint32_t res = 2 + rng_below(&r, 15);
        cull_dvol v, w;
        assert_int_equal(cull_dvol_init(&v, lo, hi, res), CULL_OK);
        assert_int_equal(cull_dvol_init(&w, lo, hi, res), CULL_OK);
        uint32_t ns = 1 + rng_below(&r, 64);
        for (uint32_t k = 0; k < ns; k++) {
            double c[3];
            for (int a = 0; a < 3; a++) c[a] = rng_range(&r, lo[a] - 5, hi[a] + 5);
            double rad = rng_log(&r, 0.1, 12);
            assert_int_equal(cull_dvol_add_sphere(&v, c, rad), CULL_OK);
            assert_int_equal(cull_dvol_add_sphere(&w, c, rad), CULL_OK);
        }
        /* sphere by sphere == rebuilt from the set */
        cull_dvol_rebuild(&w);
        size_t n = (size_t)v.n[0] * v.n[1] * v.n[2];
        assert_memory_equal(v.d, w.d, n * sizeof *v.d);
        /* the samples: the exact distance, to float rounding of the box-relative coordinates */
        double diag = sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                           (hi[2] - lo[2]) * (hi[2] - lo[2]));
        size_t i = 0;
        for (uint32_t z = 0; z < v.n[2]; z++)
            for (uint32_t y = 0; y < v.n[1]; y++)
                for (uint32_t x = 0; x < v.n[0]; x++, i++) {
                    double p[3] = {v.origin[0] + x * v.step[0], v.origin[1] + y * v.step[1], v.origin[2] + z * v.step[2]};
                    double e = cull_dvol_exact(&v, p), err = fabs(v.d[i] - e);
                    double tol = 4e-7 * (diag + 60 + fabs(e)) + 1e-6;
                    if (!(err <= tol)) fail_msg("sample %zu: %.9g vs exact %.9g (tolerance %.3g)", i, v.d[i], e, tol);
                    worst_grid = fmax(worst_grid, err / tol);
                }
        /* between the samples: within the voxel diagonal */
        double bound = cull_dvol_bound(&v);
        for (int k = 0; k < 200; k++) {
            double p[3];
            for (int a = 0; a < 3; a++) p[a] = rng_range(&r, lo[a], hi[a]);
            double e = cull_dvol_exact(&v, p), s = cull_dvol_sample(&v, p);
            double err = fabs(s - e), tol = bound + 4e-7 * (diag + 60 + fabs(e)) + 1e-6;
            if (!(err <= tol)) fail_msg("point: %.9g vs exact %.9g, bound %.9g", s, e, bound);
            worst_ratio = fmax(worst_ratio, err / bound);
            points++;
        }
        cull_dvol_free(&v);
        cull_dvol_free(&w);
    }
    fprintf(stderr, "distance volumes: samples within %.2f of their tolerance; %llu points between samples, worst "
                    "error %.2f of the bound (the voxel diagonal)\n",
            worst_grid, (unsigned long long)points, worst_ratio);
}

static void test_dvol_bad_input(void **state)
{
    (void)state;
    cull_dvol v;
    double lo[3] = {0, 0, 0}, hi[3] = {4, 4, 4}, nan3[3] = {NAN, 0, 0}, c[3] = {1, 1, 1};
    assert_int_equal(cull_dvol_init(&v, lo, hi, 1), CULL_ERR_INVALID);
    assert_int_equal(cull_dvol_init(&v, lo, hi, CULL_DVOL_MAX_RES + 1), CULL_ERR_INVALID);
    assert_int_equal(cull_dvol_init(&v, nan3, hi, 8), CULL_ERR_NONFINITE);
    assert_int_equal(cull_dvol_init(&v, hi, lo, 8), CULL_ERR_AABB);
    assert_int_equal(cull_dvol_init(&v, lo, hi, 8), CULL_OK);
    assert_true(isinf(cull_dvol_sample(&v, c)) && cull_dvol_sample(&v, c) > 0); /* no spheres: nothing destroyed */
    assert_int_equal(cull_dvol_add_sphere(&v, nan3, 1), CULL_ERR_NONFINITE);
    assert_int_equal(cull_dvol_add_sphere(&v, c, 0), CULL_ERR_RADIUS);
    assert_int_equal(cull_dvol_add_sphere(&v, c, -1), CULL_ERR_RADIUS);
    assert_int_equal(cull_dvol_add_sphere(&v, c, NAN), CULL_ERR_RADIUS);
    assert_int_equal(v.nsph, 0);
    assert_int_equal(v.version, 0);
    for (uint32_t k = 0; k < CULL_DVOL_MAX_SPHERES; k++) assert_int_equal(cull_dvol_add_sphere(&v, c, 0.5), CULL_OK);
    assert_int_equal(cull_dvol_add_sphere(&v, c, 0.5), CULL_ERR_CAPACITY);
    assert_true(cull_dvol_sample(&v, c) < 0); /* inside the spheres (filtered: not -0.5 between samples) */
    cull_dvol_free(&v);
}

const struct CMUnitTest destruct_tests[] = {
    cmocka_unit_test(test_dvol_matches_brute_force),
    cmocka_unit_test(test_dvol_bad_input),
};
const size_t destruct_tests_count = sizeof destruct_tests / sizeof destruct_tests[0];
