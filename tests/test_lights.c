/*
 * test_lights.c — Forward+ tile lists against a brute-force per-pixel
 * light test. Random views (perspective in every depth mode, finite and
 * infinite far, orthographic), random viewports, random point and spot
 * lights, and a random "depth pre-pass": each pixel shows a surface point
 * at a random distance along its ray (the ray from tests/occ_ref.c), or
 * nothing. The property: every light that reaches a pixel's surface point
 * (within its radius, and inside its cone for a spot) is in that pixel's
 * tile list. Plus: lists are ascending, tiles that show nothing have none,
 * and the lists without depth ranges contain the lists with them.
 */
#include "test_util.h"

#include "occ_ref.h"
#include <float.h>
#include <stdbool.h>
#include <stdio.h>
#include <string.h>

static bool in_list(const cull_light_tiles *t, uint32_t tile, uint32_t light)
{
    for (uint32_t k = t->offset[tile]; k < t->offset[tile + 1]; k++)
        if (t->index[k] == light) return true;
    return false;
}

static void random_lights(rng *r, const double eye[3], cull_light *l, uint32_t n)
{
    for (uint32_t i = 0; i < n; i++) {
        memset(&l[i], 0, sizeof l[i]);
        for (int a = 0; a < 3; a++) l[i].pos[a] = eye[a] + rng_range(r, -80, 80);
        l[i].radius = rng_log(r, 0.2, 60);
        if (rng_below(r, 3) == 0) {
            l[i].type = CULL_LIGHT_SPOT;
            double d[3], len = 0;
            for (int a = 0; a < 3; a++) {
                d[a] = rng_range(r, -1, 1);
                len += d[a] * d[a];
            }
            len = sqrt(len);
            if (len < 1e-3) {
                d[0] = 1;
                len = 1;
            }
            for (int a = 0; a < 3; a++) l[i].dir[a] = (float)(d[a] / len);
            l[i].cos_outer = (float)cos(rng_range(r, 0.05, 1.5));
        }
    }
}

static bool reaches(const cull_light *l, const double origin[3], const double p[3])
{
    double d[3], dd = 0;
    for (int a = 0; a < 3; a++) {
        d[a] = p[a] + origin[a] - l->pos[a];
        dd += d[a] * d[a];
    }
    if (dd > l->radius * l->radius) return false;
    if (l->type == CULL_LIGHT_POINT) return true;
    double len = sqrt(dd);
    if (len == 0) return true;
    return (d[0] * l->dir[0] + d[1] * l->dir[1] + d[2] * l->dir[2]) / len >= l->cos_outer;
}

static void test_tile_lists_cover_brute_force(void **state)
{
    (void)state;
    rng r = {test_seed() ^ 0x11647u};
    cull_light_tiles with = {0}, without = {0};
    uint64_t pairs = 0, listed = 0, listed_without = 0, views = 0, lit_pixels = 0;
    uint32_t nviews = (uint32_t)(40 * test_scale());
    for (uint32_t it = 0; it < nviews; it++) {
        uint32_t w = 16 + rng_below(&r, 300), h = 16 + rng_below(&r, 200);
        cull_view_desc d = {.depth_mode = rng_below(&r, 3), .viewport_w = w, .viewport_h = h};
        for (int a = 0; a < 3; a++) d.origin[a] = rng_below(&r, 4) == 0 ? rng_range(&r, -1e5, 1e5) : 0;
        double proj[16], view[16], dir[3], up[3] = {0, 1, 0};
        for (int a = 0; a < 3; a++) dir[a] = rng_range(&r, -1, 1);
        if (fabs(dir[0]) + fabs(dir[2]) < 1e-2) dir[0] = 1;
        bool ortho = rng_below(&r, 5) == 0;
        if (ortho) {
            double hw = rng_log(&r, 5, 100);
            cull_mat_ortho(proj, -hw, hw, -hw * h / w, hw * h / w, rng_range(&r, -20, 1), rng_range(&r, 50, 300),
                           d.depth_mode);
        } else {
            cull_mat_perspective(proj, rng_range(&r, 0.3, 1.8), (double)w / h, rng_log(&r, 1e-2, 1),
                                 rng_below(&r, 3) == 0 ? INFINITY : rng_log(&r, 100, 1e4), d.depth_mode);
        }
        cull_mat_look_dir(view, dir, up);
        cull_mat_mul(d.view_proj, proj, view);
        cull_view v;
        if (cull_view_init(&v, &d) != CULL_OK) continue;
        occ_ref rays;
        assert_int_equal(occ_ref_init(&rays, &v, w, h), 0);

        /* the depth pre-pass: per pixel a surface point along its ray (a
           parameter t >= 0 from the near plane; nearness from the view's
           rows), or nothing; per tile the nearness range */
        uint32_t tx = (w + 15) / 16, ty = (h + 15) / 16;
        float (*range)[2] = malloc((size_t)tx * ty * sizeof *range);
        double *pt = malloc((size_t)w * h * 3 * sizeof *pt);
        bool *has = malloc((size_t)w * h * sizeof *has);
        assert_non_null(range);
        assert_non_null(pt);
        assert_non_null(has);
        for (uint32_t t = 0; t < tx * ty; t++) {
            range[t][0] = -FLT_MAX;
            range[t][1] = FLT_MAX;
        }
        const double *m = v.clip;
        /* surfaces within a tile mostly lie together (a wall, the ground);
           one tile in five spans everything */
        double *base = malloc((size_t)tx * ty * sizeof *base);
        assert_non_null(base);
        for (uint32_t t = 0; t < tx * ty; t++) base[t] = rng_below(&r, 5) ? rng_log(&r, 1e-2, 150) : -1;
        for (uint32_t j = 0; j < h; j++)
            for (uint32_t i = 0; i < w; i++) {
                size_t px = (size_t)j * w + i;
                has[px] = rng_below(&r, 6) != 0;
                if (!has[px]) continue;
                const double *ray = rays.ray + 6 * px;
                double len = sqrt(ray[3] * ray[3] + ray[4] * ray[4] + ray[5] * ray[5]);
                double b0 = base[(j / 16) * tx + i / 16];
                double t = (b0 < 0 ? rng_log(&r, 1e-3, 150) : b0 * rng_range(&r, 0.97, 1.03)) / len;
                double *p = pt + 3 * px;
                for (int a = 0; a < 3; a++) p[a] = ray[a] + t * ray[3 + a];
                double cw = m[3] * p[0] + m[7] * p[1] + m[11] * p[2] + m[15];
                double cz = m[2] * p[0] + m[6] * p[1] + m[10] * p[2] + m[14];
                double nearness = !ortho ? 1 / cw : d.depth_mode == CULL_DEPTH_REVERSED ? cz / cw : 1 - cz / cw;
                uint32_t tile = (j / 16) * tx + i / 16;
                float lo = (float)nearness, hi = (float)nearness;
                if ((double)lo > nearness) lo = nextafterf(lo, -INFINITY);
                if ((double)hi < nearness) hi = nextafterf(hi, INFINITY);
                if (hi > range[tile][0]) range[tile][0] = hi;
                if (lo < range[tile][1]) range[tile][1] = lo;
            }
        uint32_t nl = rng_below(&r, 4) == 0 ? 0 : 1 + rng_below(&r, 120);
        cull_light *l = calloc(nl + 1, sizeof *l);
        assert_non_null(l);
        random_lights(&r, d.origin, l, nl);
        assert_int_equal(cull_lights_bin(&v, w, h, l, nl, (const float(*)[2])range, &with), CULL_OK);
        assert_int_equal(cull_lights_bin(&v, w, h, l, nl, NULL, &without), CULL_OK);
        assert_int_equal(with.tiles_x, tx);
        assert_int_equal(with.tiles_y, ty);
        if (!nl) {
            assert_int_equal(with.offset[tx * ty], 0);
            assert_int_equal(with.in_view, 0);
        }
        for (uint32_t t = 0; t < tx * ty; t++) {
            if (!(range[t][0] >= range[t][1])) assert_int_equal(with.offset[t + 1] - with.offset[t], 0);
            for (uint32_t k = with.offset[t]; k + 1 < with.offset[t + 1]; k++)
                assert_true(with.index[k] < with.index[k + 1]);
            for (uint32_t k = with.offset[t]; k < with.offset[t + 1]; k++)
                assert_true(in_list(&without, t, with.index[k]));
        }
        listed += with.offset[tx * ty];
        listed_without += without.offset[tx * ty];
        for (uint32_t j = 0; j < h; j++)
            for (uint32_t i = 0; i < w; i++) {
                size_t px = (size_t)j * w + i;
                if (!has[px]) continue;
                uint32_t tile = (j / 16) * tx + i / 16;
                bool lit = false;
                for (uint32_t k = 0; k < nl; k++) {
                    if (!reaches(&l[k], d.origin, pt + 3 * px)) continue;
                    lit = true;
                    pairs++;
                    if (!in_list(&with, tile, k))
                        fail_msg("light %u reaches pixel %u,%u (tile %u) but is not listed; view %u", k, i, j,
                                 tile, it);
                }
                lit_pixels += lit;
            }
        views++;
        free(l);
        free(range);
        free(base);
        free(pt);
        free(has);
        occ_ref_free(&rays);
    }
    fprintf(stderr,
            "light tiles: %llu views, %llu lit pixels, %llu (pixel, light) pairs all listed; %llu tile entries "
            "with depth ranges, %llu without\n",
            (unsigned long long)views, (unsigned long long)lit_pixels, (unsigned long long)pairs,
            (unsigned long long)listed, (unsigned long long)listed_without);
    assert_true(pairs > 1000); /* not vacuous */
    assert_true(listed * 5 < listed_without * 4); /* the depth ranges cull a good share */
    cull_light_tiles_free(&with);
    cull_light_tiles_free(&without);
}

static void test_bad_lights(void **state)
{
    (void)state;
    cull_view v;
    test_view_look_range(&v, (double[3]){0, 0, 0}, (double[3]){0, 0, -1}, 64, 64, 0.1, 100);
    cull_light_tiles t = {0};
    cull_light l = {.pos = {0, 0, -5}, .radius = 1};
    assert_int_equal(cull_lights_bin(&v, 64, 64, &l, 1, NULL, &t), CULL_OK);
    assert_int_equal(t.in_view, 1);
    assert_true(t.offset[16] > 0);
    cull_light bad = l;
    bad.radius = 0;
    assert_int_equal(cull_lights_bin(&v, 64, 64, &bad, 1, NULL, &t), CULL_ERR_INVALID);
    bad = l;
    bad.pos[1] = NAN;
    assert_int_equal(cull_lights_bin(&v, 64, 64, &bad, 1, NULL, &t), CULL_ERR_INVALID);
    bad = l;
    bad.type = CULL_LIGHT_SPOT; /* no axis */
    assert_int_equal(cull_lights_bin(&v, 64, 64, &bad, 1, NULL, &t), CULL_ERR_INVALID);
    bad.type = 7;
    assert_int_equal(cull_lights_bin(&v, 64, 64, &bad, 1, NULL, &t), CULL_ERR_INVALID);
    assert_int_equal(cull_lights_bin(&v, 0, 64, &l, 1, NULL, &t), CULL_ERR_VIEWPORT);
    assert_int_equal(cull_lights_bin(&v, 64, 64, NULL, 1, NULL, &t), CULL_ERR_INVALID);
    /* behind the camera: not in view, no lists */
    cull_light behind = {.pos = {0, 0, 10}, .radius = 1};
    assert_int_equal(cull_lights_bin(&v, 64, 64, &behind, 1, NULL, &t), CULL_OK);
    assert_int_equal(t.in_view, 0);
    assert_int_equal(t.offset[16], 0);
    cull_light_tiles_free(&t);
}

const struct CMUnitTest light_tests[] = {
    cmocka_unit_test(test_bad_lights),
    cmocka_unit_test(test_tile_lists_cover_brute_force),
};
const size_t light_tests_count = sizeof light_tests / sizeof light_tests[0];
