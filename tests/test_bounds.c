/*
 * test_bounds.c — cull_bounds_from_trs against an independent long-double
 * model: the quaternion normalised and turned into a matrix in long double,
 * the 8 corners of the local box scaled, rotated and translated in long
 * double. The property: the derived AABB and sphere contain every corner,
 * and the AABB is at most 2^-43 (|pos| + A) per face larger than the exact
 * one (A = sum_j |scale_j| max|local_j|, culling.h "Derived bounds"), so it
 * is not trivially huge. Random transforms include adversarial ones:
 * positions up to 1e9 m, scales 1e-6..1e6 of either sign or 0 on one axis,
 * quaternions off unit by up to 1e-3, axis-aligned rotations (faces meet
 * corners exactly), degenerate boxes. Bad fields are refused, one row each.
 */
#include "test_util.h"

#include <stdio.h>
#include <string.h>

/* The model: world corners of the box, their AABB, and A. */
typedef struct ref_box {
    long double corner[8][3];
    long double lo[3], hi[3];
    long double mag; /* A */
} ref_box;

static void reference(const double lmin[3], const double lmax[3], const cull_trs *t, ref_box *b)
{
    long double q[4], n = 0;
    for (int k = 0; k < 4; k++) n += (long double)t->rot[k] * t->rot[k];
    n = sqrtl(n);
    for (int k = 0; k < 4; k++) q[k] = t->rot[k] / n;
    long double x = q[0], y = q[1], z = q[2], w = q[3];
    long double r[3][3] = {
        {1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)},
        {2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)},
        {2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)},
    };
    b->mag = 0;
    for (int j = 0; j < 3; j++)
        b->mag += fabsl((long double)t->scale[j]) * fmaxl(fabsl(lmin[j]), fabsl(lmax[j]));
    for (int i = 0; i < 3; i++) {
        b->lo[i] = INFINITY;
        b->hi[i] = -INFINITY;
    }
    for (int k = 0; k < 8; k++) {
        long double p[3];
        for (int j = 0; j < 3; j++) p[j] = (long double)((k >> j & 1) ? lmax[j] : lmin[j]) * t->scale[j];
        for (int i = 0; i < 3; i++) {
            long double v = t->pos[i] + (r[i][0] * p[0] + r[i][1] * p[1] + r[i][2] * p[2]);
            b->corner[k][i] = v;
            b->lo[i] = fminl(b->lo[i], v);
            b->hi[i] = fmaxl(b->hi[i], v);
        }
    }
}

static double signed_log(rng *r, double a, double b) { return (rng_below(r, 2) ? -1 : 1) * rng_log(r, a, b); }

/* One adversarial transform and box; the quaternion's length is within
 * 0.999e-3 of 1. */
static void random_case(rng *r, double lmin[3], double lmax[3], cull_trs *t)
{
    uint32_t kind = rng_below(r, 4);
    for (int a = 0; a < 3; a++) {
        t->pos[a] = kind == 0 ? 0 : kind == 1 ? rng_range(r, -10, 10) : signed_log(r, 1e-3, 1e9);
        double c = rng_below(r, 4) == 0 ? 0 : signed_log(r, 1e-6, 1e6);
        double e = rng_below(r, 6) == 0 ? 0 : rng_log(r, 1e-6, 1e3); /* zero extent: a flat or point box */
        lmin[a] = c - e;
        lmax[a] = c + e;
        t->scale[a] = (float)signed_log(r, 1e-6, 1e6);
    }
    if (rng_below(r, 8) == 0) t->scale[rng_below(r, 3)] = 0;
    double q[4], n = 0;
    if (rng_below(r, 4) == 0) { /* axis-aligned: 0 or +-1 or +-1/sqrt2 pairs */
        memset(q, 0, sizeof q);
        q[rng_below(r, 4)] = 1;
        if (rng_below(r, 2)) q[rng_below(r, 4)] += rng_below(r, 2) ? 1 : -1;
    } else {
        for (int k = 0; k < 4; k++) q[k] = rng_range(r, -1, 1);
    }
    for (int k = 0; k < 4; k++) n += q[k] * q[k];
    if (n < 1e-6) q[3] = n = 1;
    double len = rng_below(r, 2) ? 1 : 1 + rng_range(r, -0.999e-3, 0.999e-3);
    for (int k = 0; k < 4; k++) t->rot[k] = q[k] / sqrt(n) * len;
}

/* Asserts containment and tightness; returns the largest face overshoot
 * over (|pos_i| + A). */
static double check_case(const double lmin[3], const double lmax[3], const cull_trs *t)
{
    cull_entity_desc d;
    memset(&d, 0, sizeof d);
    char err[160] = "";
    int rc = cull_bounds_from_trs(lmin, lmax, t, &d, err, sizeof err);
    if (rc != CULL_OK) fail_msg("refused: %s", err);
    ref_box b;
    reference(lmin, lmax, t, &b);
    double worst = 0;
    long double slack_abs = 0x1p-898L, /* W's underflow floor 2^-900, then an ulp */ half_diag2 = 0;
    for (int i = 0; i < 3; i++) {
        for (int k = 0; k < 8; k++)
            if (!(d.aabb_min[i] <= b.corner[k][i] && b.corner[k][i] <= d.aabb_max[i]))
                fail_msg("corner %d axis %d at %.21Lg outside %.17g..%.17g", k, i, b.corner[k][i], d.aabb_min[i],
                         d.aabb_max[i]);
        long double scale = fabsl((long double)t->pos[i]) + b.mag;
        long double over = fmaxl(b.lo[i] - d.aabb_min[i], d.aabb_max[i] - b.hi[i]);
        if (!(over <= 0x1p-43L * scale + slack_abs))
            fail_msg("axis %d: AABB %.17g..%.17g exceeds the exact %.21Lg..%.21Lg by %Lg, over 2^-43 x %Lg", i,
                     d.aabb_min[i], d.aabb_max[i], b.lo[i], b.hi[i], over, scale);
        if (scale > 0) worst = fmax(worst, (double)(over / scale));
        long double hd = (b.hi[i] - b.lo[i]) / 2;
        half_diag2 += hd * hd;
    }
    long double r2 = (long double)d.radius * d.radius;
    for (int k = 0; k < 8; k++) {
        long double dd = 0;
        for (int i = 0; i < 3; i++) {
            long double v = b.corner[k][i] - d.center[i];
            dd += v * v;
        }
        if (!(dd <= r2)) fail_msg("corner %d at distance %.21Lg outside radius %.17g", k, sqrtl(dd), d.radius);
    }
    /* the proof's sharper claim: the sphere holds the derived AABB's corners */
    for (int k = 0; k < 8; k++) {
        long double dd = 0;
        for (int i = 0; i < 3; i++) {
            long double v = (long double)((k >> i & 1) ? d.aabb_max[i] : d.aabb_min[i]) - d.center[i];
            dd += v * v;
        }
        if (!(dd <= r2)) fail_msg("AABB corner %d at distance %.21Lg outside radius %.17g", k, sqrtl(dd), d.radius);
    }
    /* the sphere is the derived AABB's: at most its slack wider than the
     * exact AABB's half-diagonal */
    long double tmax = fmaxl(fabsl((long double)t->pos[0]), fmaxl(fabsl((long double)t->pos[1]), fabsl((long double)t->pos[2])));
    long double rmax = sqrtl(half_diag2) * (1 + 0x1p-45L) + 2 * 0x1p-43L * (tmax + b.mag) + 0x1p-440L;
    if (!(d.radius <= rmax)) fail_msg("radius %.17g over the bound %.21Lg", d.radius, rmax);
    return worst;
}

static void test_bounds_contain_reference(void **state)
{
    (void)state;
    rng r = {test_seed() ^ 0xB0D5};
    uint32_t n = (uint32_t)(200000 * test_scale());
    double worst = 0;
    for (uint32_t i = 0; i < n; i++) {
        double lmin[3], lmax[3];
        cull_trs t;
        random_case(&r, lmin, lmax, &t);
        worst = fmax(worst, check_case(lmin, lmax, &t));
    }
    print_message("%u random transforms: every corner inside; largest face overshoot %.3g x (|pos| + A), "
                  "allowed %.3g\n", n, worst, 0x1p-43);
}

/* Hand-picked edges: identity, quarter turns, a point box 1e9 m out, one
 * zero scale axis, |q| just inside the tolerance, and the result straight
 * into cull_entity_add. */
static void test_bounds_edges(void **state)
{
    (void)state;
    const double h = 0.70710678118654752440;
#define QN 0.97467943448089633 /* |(0.3, 0.1, 0.2, 0.9)| */
    const struct { double lmin[3], lmax[3]; cull_trs t; } cases[] = {
        {{-1, -2, -3}, {1, 2, 3}, {.rot = {0, 0, 0, 1}, .scale = {1, 1, 1}}},
        {{-1, -2, -3}, {1, 2, 3}, {.pos = {5, 6, 7}, .rot = {0, 0, h, h}, .scale = {2, 3, 4}}},
        {{0, 0, 0}, {1, 1, 1}, {.pos = {1e9, -1e9, 1e9}, .rot = {h, 0, 0, -h}, .scale = {-1, 1, -1}}},
        {{3, 3, 3}, {3, 3, 3}, {.pos = {1e9, 1e9, -1e9}, .rot = {0.5, 0.5, 0.5, 0.5}, .scale = {1e6f, 1e-6f, 1}}},
        {{-1, -1, -1}, {1, 1, 1}, {.pos = {1, 2, 3}, .rot = {0.3 / QN, 0.1 / QN, 0.2 / QN, 0.9 / QN}, .scale = {1, 0, 2}}},
        {{-1, -1, -1}, {1, 1, 1}, {.rot = {0, 0, 0, 1 + 0.999e-3}, .scale = {1, 1, 1}}},
        {{-1, -1, -1}, {1, 1, 1}, {.rot = {0, 0.9990005 * h, 0, 0.9990005 * h}, .scale = {1, 1, 1}}},
        {{-1e12, -1, -1}, {1e12, 1, 1}, {.pos = {1e12, 0, 0}, .rot = {0, 0, 0, 1}, .scale = {1, 1, 1}}},
    };
#undef QN
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) check_case(cases[i].lmin, cases[i].lmax, &cases[i].t);

    /* identity on a unit box: every face within 2 ulp + W of the box */
    cull_entity_desc d = {.class_id = 7, .sublevel = 3, .flags = CULL_ENTITY_DYNAMIC};
    assert_int_equal(cull_bounds_from_trs(cases[0].lmin, cases[0].lmax, &cases[0].t, &d, NULL, 0), CULL_OK);
    assert_int_equal(d.class_id, 7);
    assert_int_equal(d.sublevel, 3);
    assert_int_equal(d.flags, CULL_ENTITY_DYNAMIC);
    assert_true(d.aabb_min[2] <= -3 && d.aabb_min[2] > -3 - 1e-12);
    assert_true(d.aabb_max[1] >= 2 && d.aabb_max[1] < 2 + 1e-12);
    assert_true(d.radius >= sqrt(14.0) && d.radius < sqrt(14.0) + 1e-12);
    /* a point box still gets a positive radius (0 would mean "derive") */
    assert_int_equal(cull_bounds_from_trs(cases[3].lmin, cases[3].lmax, &cases[3].t, &d, NULL, 0), CULL_OK);
    assert_true(d.radius > 0 && d.radius < 1e-5);
    assert_true(d.aabb_min[0] < d.aabb_max[0]);

    /* the output feeds the world as is and reads back unchanged */
    cull_world *w;
    assert_int_equal(cull_world_create(&(cull_world_desc){0}, &w), CULL_OK);
    assert_int_equal(cull_bounds_from_trs(cases[1].lmin, cases[1].lmax, &cases[1].t, &d, NULL, 0), CULL_OK);
    cull_handle hd;
    assert_int_equal(cull_entity_add(w, &d, &hd), CULL_OK);
    cull_entity_desc back;
    assert_int_equal(cull_entity_get(w, hd, &back), CULL_OK);
    assert_memory_equal(back.center, d.center, sizeof d.center);
    assert_true(back.radius == d.radius);
    assert_memory_equal(back.aabb_min, d.aabb_min, sizeof d.aabb_min);
    assert_memory_equal(back.aabb_max, d.aabb_max, sizeof d.aabb_max);
    cull_world_destroy(w);
}

/* ---- bad input: one row per field ------------------------------------------ */
enum { F_POS, F_ROT, F_SCALE, F_LMIN, F_LMAX, F_QLEN, F_ZEROS };
typedef struct bad_trs {
    const char *name;
    int field, axis;
    double value;
    int code;
    const char *says; /* the message names the field */
} bad_trs;

static const bad_trs bad_rows[] = {
    {"position x NaN", F_POS, 0, NAN, CULL_ERR_NONFINITE, "position x"},
    {"position y inf", F_POS, 1, INFINITY, CULL_ERR_NONFINITE, "position y"},
    {"position z -inf", F_POS, 2, -INFINITY, CULL_ERR_NONFINITE, "position z"},
    {"position x 2e12", F_POS, 0, 2e12, CULL_ERR_RANGE, "position x"},
    {"rotation x NaN", F_ROT, 0, NAN, CULL_ERR_NONFINITE, "rotation x"},
    {"rotation y inf", F_ROT, 1, INFINITY, CULL_ERR_NONFINITE, "rotation y"},
    {"rotation z -inf", F_ROT, 2, -INFINITY, CULL_ERR_NONFINITE, "rotation z"},
    {"rotation w NaN", F_ROT, 3, NAN, CULL_ERR_NONFINITE, "rotation w"},
    {"scale x NaN", F_SCALE, 0, NAN, CULL_ERR_NONFINITE, "scale x"},
    {"scale y inf", F_SCALE, 1, INFINITY, CULL_ERR_NONFINITE, "scale y"},
    {"scale z -inf", F_SCALE, 2, -INFINITY, CULL_ERR_NONFINITE, "scale z"},
    {"local min x NaN", F_LMIN, 0, NAN, CULL_ERR_NONFINITE, "local min x"},
    {"local min y inf", F_LMIN, 1, INFINITY, CULL_ERR_NONFINITE, "local min y"},
    {"local min z -inf", F_LMIN, 2, -INFINITY, CULL_ERR_NONFINITE, "local min z"},
    {"local max x -inf", F_LMAX, 0, -INFINITY, CULL_ERR_NONFINITE, "local max x"},
    {"local max y inf", F_LMAX, 1, INFINITY, CULL_ERR_NONFINITE, "local max y"},
    {"local max z NaN", F_LMAX, 2, NAN, CULL_ERR_NONFINITE, "local max z"},
    {"local min y > max y", F_LMIN, 1, 5, CULL_ERR_AABB, "local min y"},
    {"local max x 2e12", F_LMAX, 0, 2e12, CULL_ERR_RANGE, "local bounds x"},
    {"rotation length 1.00101", F_QLEN, 0, 1.00101, CULL_ERR_INVALID, "rotation"},
    {"rotation length 0.99899", F_QLEN, 0, 0.99899, CULL_ERR_INVALID, "rotation"},
    {"rotation length 0", F_QLEN, 0, 0, CULL_ERR_INVALID, "rotation"},
    {"rotation length 2", F_QLEN, 0, 2, CULL_ERR_INVALID, "rotation"},
    {"scale 0 on x and z", F_ZEROS, 1, 2, CULL_ERR_INVALID, "scale"},
    {"scale 0 on all axes", F_ZEROS, -1, 3, CULL_ERR_INVALID, "scale"},
};

static void test_bounds_bad_input(void **state)
{
    const bad_trs *row = *state;
    double lmin[3] = {-1, -1, -1}, lmax[3] = {1, 1, 1};
    const double h = 0.5; /* q = (0.5, 0.5, 0.5, 0.5): unit */
    cull_trs t = {.pos = {1, 2, 3}, .rot = {h, h, h, h}, .scale = {1, 2, 3}};
    switch (row->field) {
    case F_POS: t.pos[row->axis] = row->value; break;
    case F_ROT: t.rot[row->axis] = row->value; break;
    case F_SCALE: t.scale[row->axis] = (float)row->value; break;
    case F_LMIN: lmin[row->axis] = row->value; break;
    case F_LMAX: lmax[row->axis] = row->value; break;
    case F_QLEN:
        for (int k = 0; k < 4; k++) t.rot[k] = h * row->value;
        break;
    case F_ZEROS:
        for (int a = 0; a < 3; a++)
            if (a != row->axis) t.scale[a] = 0;
        break;
    }
    cull_entity_desc d, before;
    memset(&d, 0xA5, sizeof d);
    before = d;
    char err[200] = "";
    assert_int_equal(cull_bounds_from_trs(lmin, lmax, &t, &d, err, sizeof err), row->code);
    assert_memory_equal(&d, &before, sizeof d);
    if (!strstr(err, row->says)) fail_msg("message \"%s\" does not name \"%s\"", err, row->says);
}

/* The neighbours of the tolerance are accepted, and the NULLs refused. */
static void test_bounds_quat_tolerance(void **state)
{
    (void)state;
    const double lmin[3] = {-1, -2, -3}, lmax[3] = {1, 2, 3};
    const double lens[] = {1 - 0.9999e-3, 1 + 0.9999e-3, 1 - 1e-9, 1 + 1e-9};
    for (size_t i = 0; i < sizeof lens / sizeof lens[0]; i++) {
        cull_trs t = {.pos = {4, 5, 6}, .rot = {0.1 * lens[i], 0.7 * lens[i], 0.1 * lens[i], 0.7 * lens[i]},
                      .scale = {1, -1, 2}};
        double n = sqrt(0.01 + 0.49 + 0.01 + 0.49);
        for (int k = 0; k < 4; k++) t.rot[k] /= n;
        check_case(lmin, lmax, &t);
    }
    cull_trs t = {.rot = {0, 0, 0, 1}, .scale = {1, 1, 1}};
    cull_entity_desc d;
    char err[64];
    assert_int_equal(cull_bounds_from_trs(NULL, lmax, &t, &d, err, sizeof err), CULL_ERR_INVALID);
    assert_int_equal(cull_bounds_from_trs(lmin, lmax, NULL, &d, err, sizeof err), CULL_ERR_INVALID);
    assert_int_equal(cull_bounds_from_trs(lmin, lmax, &t, NULL, NULL, 0), CULL_ERR_INVALID);
}

/* ns per call over a ring of random transforms; printed, never asserted. */
static void test_bounds_bench(void **state)
{
    (void)state;
    enum { RING = 1024 };
    static double lmin[RING][3], lmax[RING][3];
    static cull_trs t[RING];
    rng r = {test_seed() ^ 0xBE7C};
    for (int i = 0; i < RING; i++) random_case(&r, lmin[i], lmax[i], &t[i]);
    uint32_t n = (uint32_t)(2000000 * test_scale());
    cull_entity_desc d;
    double sum = 0, t0 = test_now_s();
    for (uint32_t i = 0; i < n; i++) {
        uint32_t k = i & (RING - 1);
        if (cull_bounds_from_trs(lmin[k], lmax[k], &t[k], &d, NULL, 0) == CULL_OK) sum += d.radius;
    }
    double s = test_now_s() - t0;
    assert_true(sum > 0);
    print_message("cull_bounds_from_trs: %.1f ns per call (%u calls, %.3f s)\n", s * 1e9 / n, n, s);
}

const struct CMUnitTest bounds_tests[] = {
    cmocka_unit_test(test_bounds_contain_reference),
    cmocka_unit_test(test_bounds_edges),
    TEST_ROWS(test_bounds_bad_input, bad_rows),
    cmocka_unit_test(test_bounds_quat_tolerance),
    cmocka_unit_test(test_bounds_bench),
};
const size_t bounds_tests_count = sizeof bounds_tests / sizeof bounds_tests[0];
