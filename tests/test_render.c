/*
 * test_render.c — the software renderer against the ray caster of
 * tests/occ_ref.c: the same triangles (instances of a unit box stretched
 * onto random boxes, front faces only), random cameras. Per pixel centre:
 * covered in both or in neither, and where both cover it, the same depth to
 * 1e-5 relative. Snapping vertices to 1/256 pixel may flip a centre that
 * lies within that of an edge (coverage, or which of two faces meeting at
 * a crease wins): allowed on at most 0.1 % of the pixels.
 */
#include "test_util.h"

#include "occ_ref.h"
#include "vt_gldraw.h"
#include "vt_soft.h"
#include "vt_picture.h"
#include "vt_raster.h"
#include "vt_shade.h"
#include <errno.h>
#include <stdio.h>
#include <string.h>

/* A random perspective view of w x h pixels from within +-60 m towards a
 * point within +-10 m of the origin: any depth mode, a vertical field of
 * view of 0.5..fov_max rad, the near plane log-uniform in near_min..1 m. */
static void random_view(rng *r, cull_view *v, uint32_t w, uint32_t h, double fov_max, double near_min, double far)
{
    cull_view_desc d = {.depth_mode = rng_below(r, 3), .viewport_w = w, .viewport_h = h};
    for (int a = 0; a < 3; a++) d.origin[a] = rng_range(r, -60, 60);
    double proj[16], view[16], dir[3], up[3] = {0, 1, 0};
    for (int a = 0; a < 3; a++) dir[a] = rng_range(r, -10, 10) - d.origin[a];
    if (fabs(dir[0]) + fabs(dir[2]) < 1e-2) dir[0] = 1;
    cull_mat_perspective(proj, rng_range(r, 0.5, fov_max), (double)w / h, rng_log(r, near_min, 1), far, d.depth_mode);
    cull_mat_look_dir(view, dir, up);
    cull_mat_mul(d.view_proj, proj, view);
    assert_int_equal(cull_view_init(v, &d), CULL_OK);
}

/* The unit cube [-1, 1]^3: 8 vertices, 12 counter-clockwise triangles. */
static const float cube_pos[24] = {-1, -1, -1, 1, -1, -1, -1, 1, -1, 1, 1, -1,
                                   -1, -1, 1,  1, -1, 1,  -1, 1, 1,  1, 1, 1};
static const uint32_t cube_idx[36] = {0, 4, 6, 0, 6, 2, 1, 3, 7, 1, 7, 5, 0, 1, 5, 0, 5, 4,
                                      2, 6, 7, 2, 7, 3, 0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6};

static void test_soft_matches_ray_caster(void **state)
{
    (void)state;
    rng r = {test_seed() ^ 0x5EF7u};
    vt_soft *sr;
    cull_pool *pool;
    assert_int_equal(cull_pool_create(2, &pool), CULL_OK);
    assert_int_equal(vt_soft_create(pool, 0, &sr), 0);
    vt_mesh cube = {.pos = cube_pos, .idx = cube_idx, .nv = 8, .ni = 36};
    char err[256];
    assert_int_equal(vt_mesh_check(&cube, err, sizeof err), 0);
    uint64_t pixels = 0, both = 0, mismatch = 0, depth_bad = 0;
    uint32_t frames = (uint32_t)(24 * test_scale());
    for (uint32_t f = 0; f < frames; f++) {
        uint32_t w = 32 + rng_below(&r, 160), h = 24 + rng_below(&r, 120);
        uint32_t n = 1 + rng_below(&r, 40);
        vt_instance *in = calloc(n, sizeof *in);
        double *tri = malloc((size_t)n * 12 * 9 * sizeof *tri);
        assert_non_null(in);
        assert_non_null(tri);
        for (uint32_t i = 0; i < n; i++) {
            for (int a = 0; a < 3; a++) {
                double c = rng_range(&r, -20, 20), e = rng_log(&r, 0.3, 8);
                in[i].bmin[a] = c - e;
                in[i].bmax[a] = c + e;
                in[i].albedo[a] = 0.5f;
            }
            for (int t = 0; t < 12; t++)
                for (int k = 0; k < 3; k++)
                    for (int a = 0; a < 3; a++) {
                        float u = cube_pos[3 * cube_idx[3 * t + k] + a];
                        tri[(size_t)(i * 12 + t) * 9 + 3 * k + a] =
                            in[i].bmin[a] + (u + 1) * 0.5 * (in[i].bmax[a] - in[i].bmin[a]);
                    }
        }
        cull_view v;
        random_view(&r, &v, w, h, 1.6, 0.05, 1e5);
        float *rgba = malloc((size_t)w * h * 4 * sizeof *rgba), *depth = malloc((size_t)w * h * sizeof *depth);
        assert_non_null(rgba);
        assert_non_null(depth);
        vt_soft_stats st;
        assert_int_equal(vt_soft_render(sr, &v, w, h, &cube, 1, in, n, NULL, 0, rgba, depth, w, &st, err, sizeof err), 0);
        occ_ref ref;
        assert_int_equal(occ_ref_init(&ref, &v, w, h), 0);
        occ_ref_add_triangles(&ref, tri, (size_t)n * 12);
        for (uint32_t j = 0; j < h; j++)
            for (uint32_t i = 0; i < w; i++) {
                size_t px = (size_t)j * w + i;
                bool ours = depth[px] != INFINITY, theirs = ref.t[px] != INFINITY;
                pixels++;
                if (ours != theirs) {
                    mismatch++;
                    continue;
                }
                if (!ours) continue;
                both++;
                assert_true(rgba[4 * px + 3] == 1.0f);
                const double *ray = ref.ray + 6 * px, *m = v.clip;
                double p[3];
                for (int a = 0; a < 3; a++) p[a] = ray[a] + ref.t[px] * ray[3 + a];
                double wref = m[3] * p[0] + m[7] * p[1] + m[11] * p[2] + m[15];
                if (!(fabs(depth[px] - wref) <= 1e-5 * wref)) {
                    depth_bad++;
                    if (depth_bad < 3) fprintf(stderr, "depth %u,%u: %g vs %g (an edge)\n", i, j, depth[px], wref);
                }
            }
        occ_ref_free(&ref);
        free(rgba);
        free(depth);
        free(in);
        free(tri);
    }
    fprintf(stderr, "soft renderer vs ray caster: %llu pixels, %llu covered by both, %llu differ in coverage, %llu in "
                    "depth\n",
            (unsigned long long)pixels, (unsigned long long)both, (unsigned long long)mismatch,
            (unsigned long long)depth_bad);
    assert_true(both * 12 > pixels); /* not vacuous */
    assert_true((mismatch + depth_bad) * 1000 <= pixels);
    vt_soft_destroy(sr);
    cull_pool_destroy(pool);
}

static void test_soft_bad_input(void **state)
{
    (void)state;
    vt_soft *sr;
    assert_int_equal(vt_soft_create(NULL, 0, &sr), 0);
    char err[256];
    uint32_t bad_idx[3] = {0, 1, 9};
    vt_mesh m = {.pos = cube_pos, .idx = bad_idx, .nv = 8, .ni = 3};
    assert_int_equal(vt_mesh_check(&m, err, sizeof err), VT_ERR_INVALID);
    assert_non_null(strstr(err, "index"));
    float nanpos[9] = {0, 0, 0, 1, 0, 0, 0, NAN, 0};
    uint32_t idx3[3] = {0, 1, 2};
    vt_mesh m2 = {.pos = nanpos, .idx = idx3, .nv = 3, .ni = 3};
    assert_int_equal(vt_mesh_check(&m2, err, sizeof err), VT_ERR_INVALID);
    cull_view v;
    test_view_look_range(&v, (double[3]){0, 0, 0}, (double[3]){0, 0, -1}, 8, 8, 0.1, 100);
    float rgba[8 * 8 * 4], depth[64];
    vt_mesh cube = {.pos = cube_pos, .idx = cube_idx, .nv = 8, .ni = 36};
    vt_instance in = {.mesh = 3};
    assert_int_equal(vt_soft_render(sr, &v, 8, 8, &cube, 1, &in, 1, NULL, 0, rgba, depth, 8, NULL, err, sizeof err),
                     VT_ERR_INVALID);
    in.mesh = 0;
    assert_int_equal(vt_soft_render(sr, &v, 0, 8, &cube, 1, &in, 1, NULL, 0, rgba, depth, 8, NULL, err, sizeof err),
                     VT_ERR_INVALID);
    in.bmin[0] = NAN;
    assert_int_equal(vt_soft_render(sr, &v, 8, 8, &cube, 1, &in, 1, NULL, 0, rgba, depth, 8, NULL, err, sizeof err),
                     VT_ERR_INVALID);
    /* both renderers refuse every bad input the same way, with a reason,
       and leave the caller's buffers as they were */
    vt_gl *g = NULL;
    vt_gldraw *gr = NULL;
    char gerr[512];
    if (vt_gl_open(&g, NULL, gerr, sizeof gerr) == 0) assert_int_equal(vt_gldraw_create(g, &gr, gerr, sizeof gerr), 0);
    vt_instance good = {.mesh = 0, .bmin = {-1, -1, -5}, .bmax = {1, 1, -3}}, bad_bounds = good;
    bad_bounds.bmin[2] = -2; /* min above max */
    vt_light nan_light = {.l = {.pos = {0, 0, NAN}, .radius = 5}};
    vt_light hot_light = {.l = {.pos = {0, 0, -4}, .radius = 5}, .color = {INFINITY, 1, 1}};
    const struct {
        const vt_mesh *m;
        const vt_instance *in;
        const vt_light *l;
        uint32_t nl;
        const char *why;
    } cases[] = {
        {&m, &good, NULL, 0, "index"},          /* a mesh index past its vertices */
        {&m2, &good, NULL, 0, "not finite"},    /* a NaN vertex */
        {&cube, &bad_bounds, NULL, 0, "bounds"},
        {&cube, &good, &nan_light, 1, "light"},
        {&cube, &good, &hot_light, 1, "light 0: colour"}, /* an infinite colour: NaN pixels once shaded */
    };
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        for (int path = 0; path < (gr ? 2 : 1); path++) {
            for (size_t i = 0; i < 64; i++) rgba[4 * i] = rgba[4 * i + 1] = rgba[4 * i + 2] = rgba[4 * i + 3] = depth[i] = 7;
            err[0] = 0;
            int rc = path ? vt_gldraw_render(gr, &v, 8, 8, cases[c].m, 1, cases[c].in, 1, cases[c].l, cases[c].nl, rgba,
                                             depth, 8, NULL, err, sizeof err)
                          : vt_soft_render(sr, &v, 8, 8, cases[c].m, 1, cases[c].in, 1, cases[c].l, cases[c].nl, rgba,
                                           depth, 8, NULL, err, sizeof err);
            assert_int_equal(rc, VT_ERR_INVALID);
            if (!strstr(err, cases[c].why)) fail_msg("case %zu, %s: \"%s\"", c, path ? "gl" : "soft", err);
            for (size_t i = 0; i < 64; i++) assert_true(rgba[4 * i] == 7 && depth[i] == 7);
        }
    }
    vt_gldraw_destroy(gr);
    vt_gl_close(g);
    vt_soft_destroy(sr);
}

/* A term of either sign from 1e-300 to 1e30, log-uniform. */
static double adv_term(rng *r)
{
    double t = pow(10, rng_range(r, -300, 30));
    return rng_below(r, 2) ? t : -t;
}

/* Views every check accepts (cull_view_init, vt_picture_check) but built to
 * break the renderers' arithmetic: the 1e30 in element 5 (the
 * clip y scale), tiny and huge cross terms elsewhere, near 1e-6 and far
 * 1e30, the eye on a box's face plane; lights with tiny and huge ranges.
 * Each frame renders (or is refused with a reason); under UBSan (the asan
 * build) a signed overflow or an out-of-range conversion aborts: before
 * the fix, vt_soft.c snapped a vertex the clipper rounded to ~1e15 pixels
 * into int32 and overflowed the edge set-up (issue 18, item 6). A drawn
 * frame has no NaN depth and alpha 0 or 1. Where a GL context can be made
 * the GL path gets the same frames. */
static void test_renderers_adversarial_views(void **state)
{
    (void)state;
    rng r = {test_seed() ^ 0xAD7E4u};
    vt_soft *sr;
    assert_int_equal(vt_soft_create(NULL, 0, &sr), 0);
    vt_gl *g = NULL;
    vt_gldraw *gr = NULL;
    char gerr[512];
    if (vt_gl_open(&g, NULL, gerr, sizeof gerr) == 0) assert_int_equal(vt_gldraw_create(g, &gr, gerr, sizeof gerr), 0);
    vt_mesh cube = {.pos = cube_pos, .idx = cube_idx, .nv = 8, .ni = 36};
    /* first the view itself, over many boxes: the eye at y = 0,
       looking along +z, 1e30 in element 5, 48 boxes straddling y = 0.
       Their side faces cross clip y from -1e31 to +1e31; about 5 % of those
       edges come out of the bottom guard plane's clip at y ~ -2^50 (t's
       rounding times 1e31), and a polygon with two such vertices gave the
       old snap two wild int32s whose difference overflows */
    for (uint32_t f = 0; f < (uint32_t)(60 * test_scale()); f++) {
        enum { NB = 48, W = 64, H = 48 };
        vt_instance in[NB];
        memset(in, 0, sizeof in);
        for (uint32_t i = 0; i < NB; i++) {
            double c[3] = {rng_range(&r, -30, 30), 0, rng_range(&r, 8, 80)};
            for (int a = 0; a < 3; a++) {
                in[i].bmin[a] = a == 1 ? -rng_range(&r, 0.1, 20) : c[a] - rng_range(&r, 0.3, 4);
                in[i].bmax[a] = a == 1 ? rng_range(&r, 0.1, 20) : c[a] + rng_range(&r, 0.3, 4);
                in[i].albedo[a] = 0.5f;
            }
        }
        cull_view_desc d = {.depth_mode = rng_below(&r, 3), .viewport_w = W, .viewport_h = H};
        double proj[16], view[16], dir[3] = {0, 0, 1}, up[3] = {0, 1, 0};
        cull_mat_perspective(proj, 1.2, (double)W / H, 0.1, 1e4, d.depth_mode);
        cull_mat_look_dir(view, dir, up);
        cull_mat_mul(d.view_proj, proj, view);
        d.view_proj[5] = 1e30;
        cull_view v;
        assert_int_equal(cull_view_init(&v, &d), CULL_OK);
        static float rgba[W * H * 4], depth[W * H];
        char err[256];
        assert_int_equal(vt_soft_render(sr, &v, W, H, &cube, 1, in, NB, NULL, 0, rgba, depth, W, NULL, err, sizeof err), 0);
        for (size_t i = 0; i < (size_t)W * H; i++) assert_false(isnan(depth[i]));
    }
    uint32_t frames = (uint32_t)(300 * test_scale()), rendered = 0, refused = 0, tried = 0;
    for (uint32_t f = 0; f < frames; f++) {
        uint32_t w = 4 + rng_below(&r, 60), h = 4 + rng_below(&r, 60), n = 1 + rng_below(&r, 6);
        /* the case, a third of the time: boxes on integer
           coordinates standing on y = 0, the eye at y = 0 or within a box's
           height, looking horizontally, 1e30 in element 5: clip y is 0 or
           +-1e30, and an edge from below to above is clipped at y ~ 0 by
           cancelling terms of 1e30 (its rounding, ~1e14, lands the vertex
           far outside the guard band) */
        bool exact = rng_below(&r, 3) == 0;
        vt_instance in[6];
        memset(in, 0, sizeof in);
        for (uint32_t i = 0; i < n; i++)
            for (int a = 0; a < 3; a++) {
                double c = rng_range(&r, -20, 20), e = rng_log(&r, 0.3, 8);
                if (exact) c = floor(c), e = a == 1 ? c : ceil(e), c = a == 1 ? fabs(c) + 1 : c;
                in[i].bmin[a] = exact && a == 1 ? 0 : c - e;
                in[i].bmax[a] = exact && a == 1 ? c : c + e;
                in[i].albedo[a] = 0.5f;
            }
        cull_view_desc d = {.depth_mode = rng_below(&r, 3), .viewport_w = w, .viewport_h = h};
        for (int a = 0; a < 3; a++) d.origin[a] = exact ? floor(rng_range(&r, -40, 40)) : rng_range(&r, -40, 40);
        if (exact) d.origin[1] = rng_below(&r, 2) ? 0 : rng_range(&r, 0.1, 0.9) * in[0].bmax[1]; /* on the base, or
                                                                   within the box's height */
        else if (rng_below(&r, 2)) d.origin[1] = in[0].bmin[1]; /* level with a box's base */
        double proj[16], view[16], dir[3], up[3] = {0, 1, 0};
        for (int a = 0; a < 3; a++) dir[a] = 0.5 * (in[0].bmin[a] + in[0].bmax[a]) - d.origin[a];
        if (exact || rng_below(&r, 2)) dir[1] = 0;
        if (fabs(dir[0]) + fabs(dir[2]) < 1e-2) dir[0] = 1;
        if (!exact && rng_below(&r, 3)) up[rng_below(&r, 3)] += adv_term(&r);
        cull_mat_perspective(proj, rng_range(&r, 0.1, 2.5), (double)w / h, rng_below(&r, 2) ? 1e-6 : rng_log(&r, 1e-6, 1),
                             rng_below(&r, 2) ? 1e30 : INFINITY, d.depth_mode);
        cull_mat_look_dir(view, dir, up);
        cull_mat_mul(d.view_proj, proj, view);
        if (exact || rng_below(&r, 2)) d.view_proj[5] = rng_below(&r, 2) ? 1e30 : -1e30;
        else if (rng_below(&r, 2)) d.view_proj[rng_below(&r, 16)] = (rng_below(&r, 2) ? 1 : -1) * pow(10, rng_range(&r, 12, 30));
        for (uint32_t k = exact ? 0 : rng_below(&r, 3); k > 0; k--) {
            uint32_t i = rng_below(&r, 16);
            if (rng_below(&r, 2)) d.view_proj[i] += adv_term(&r);
            else d.view_proj[i] = adv_term(&r);
        }
        tried++;
        cull_view v;
        if (cull_view_init(&v, &d) != CULL_OK) continue;
        vt_light L[3];
        uint32_t nl = rng_below(&r, 4);
        memset(L, 0, sizeof L);
        for (uint32_t i = 0; i < nl; i++) {
            for (int a = 0; a < 3; a++) L[i].l.pos[a] = rng_range(&r, -30, 30);
            L[i].l.radius = rng_below(&r, 2) ? rng_log(&r, 1e-6, 1e6) : pow(10, rng_range(&r, -30, 12));
            L[i].color[0] = L[i].color[1] = L[i].color[2] = 1;
            if (rng_below(&r, 2)) {
                L[i].l.type = CULL_LIGHT_SPOT;
                L[i].l.dir[1] = -1;
                L[i].l.cos_outer = 0.5f;
                L[i].cos_inner = 0.7f;
            }
        }
        float *rgba = malloc((size_t)w * h * 4 * sizeof *rgba), *depth = malloc((size_t)w * h * sizeof *depth);
        assert_non_null(rgba);
        assert_non_null(depth);
        for (int path = 0; path < (gr ? 2 : 1); path++) {
            char err[256] = "";
            int rc = path ? vt_gldraw_render(gr, &v, w, h, &cube, 1, in, n, L, nl, rgba, depth, w, NULL, err,
                                             sizeof err)
                          : vt_soft_render(sr, &v, w, h, &cube, 1, in, n, L, nl, rgba, depth, w, NULL, err, sizeof err);
            if (rc == 0) {
                rendered++;
                for (size_t i = 0; i < (size_t)w * h; i++) {
                    assert_false(isnan(depth[i]));
                    assert_true(rgba[4 * i + 3] == 0 || rgba[4 * i + 3] == 1);
                }
                continue;
            }
            /* a refusal names its reason */
            refused++;
            assert_int_equal(rc, VT_ERR_INVALID);
            assert_true(err[0] != 0);
        }
        free(rgba);
        free(depth);
    }
    fprintf(stderr, "adversarial frames: %u views tried, %u renders, %u refused (%s)\n", tried, rendered, refused,
            gr ? "soft and gl" : "soft; no GL context");
    assert_true(rendered * 2 > tried); /* most of them were drawn */
    vt_gldraw_destroy(gr);
    vt_gl_close(g);
    vt_soft_destroy(sr);
}

/* The software and GL paths on the same scenes (llvmpipe here): coverage
 * the same on >= 99.9 % of pixels, depth within 1e-4 relative, colour
 * within 1 % + 1e-3 where both cover a pixel away from an edge. Skipped
 * where no GL context can be made. */
/* Each instance of the per-tile-row range kernel against vt_tile_ranges
 * (the plain loop the GL path uses): random nearness with empty pixels,
 * widths and heights not multiples of 16. */
static void test_tile_ranges_kernels(void **state)
{
    (void)state;
    rng r = {test_seed() ^ 0x7A9u};
    vt_ranges_fn fns[3] = {vt_ranges_scalar,
#ifndef CULL_SCALAR_ONLY
                           vt_ranges_sse41, vt_ranges_avx2
#else
                           NULL, NULL
#endif
    };
    for (int f = 0; f < 40; f++) {
        uint32_t w = 1 + rng_below(&r, 100), h = 1 + rng_below(&r, 40), tx = (w + 15) / 16, ty = (h + 15) / 16;
        float *near = malloc((size_t)w * h * sizeof *near);
        float(*want)[2] = malloc((size_t)tx * ty * sizeof *want), (*got)[2] = malloc((size_t)tx * ty * sizeof *got);
        assert_true(near && want && got);
        uint32_t empty_pct = rng_below(&r, 101);
        for (size_t p = 0; p < (size_t)w * h; p++)
            near[p] = rng_below(&r, 100) < empty_pct ? VT_EMPTY : (float)rng_log(&r, 1e-4, 10);
        vt_tile_ranges(near, 1, w, w, h, want);
        for (int k = 0; k < 3; k++) {
            if (!fns[k] || !cull_isa_supported((uint32_t)k)) continue;
            memset(got, 0x55, (size_t)tx * ty * sizeof *got);
            for (uint32_t t = 0; t < ty; t++) {
                uint32_t rows = h - 16 * t < 16 ? h - 16 * t : 16;
                fns[k](near + (size_t)16 * t * w, w, w, rows, got + (size_t)t * tx);
            }
            assert_memory_equal(got, want, (size_t)tx * ty * sizeof *got);
        }
        free(near);
        free(want);
        free(got);
    }
}

/* A random frame of lit boxes: sizes, boxes, point and spot lights (none
 * in a quarter of the frames), a perspective camera in any depth mode; in
 * half the frames a third of the boxes damaged (1..4 holes on their
 * surface: drawn masked and two-sided). */
typedef struct lit_frame {
    uint32_t w, h, n, nl;
    vt_instance *in;
    vt_light *L;
    cull_dvol *dv;          /* one per instance, used where in[i].dvol is set */
    cull_view v;
} lit_frame;

static void lit_frame_make(rng *rp, lit_frame *lf)
{
    rng r = *rp;
    uint32_t w = 64 + rng_below(&r, 200), h = 48 + rng_below(&r, 120), n = 5 + rng_below(&r, 40);
    uint32_t nl = rng_below(&r, 4) ? 4 + rng_below(&r, 60) : 0;
    vt_instance *in = calloc(n, sizeof *in);
    vt_light *L = calloc(nl + 1, sizeof *L);
    cull_dvol *dv = calloc(n, sizeof *dv);
    assert_non_null(in);
    assert_non_null(L);
    assert_non_null(dv);
    bool damage = rng_below(&r, 2);
    for (uint32_t i = 0; i < n; i++) {
        double emax = 0;
        for (int a = 0; a < 3; a++) {
            double c = rng_range(&r, -20, 20), e = rng_log(&r, 0.3, 8);
            in[i].bmin[a] = c - e;
            in[i].bmax[a] = c + e;
            in[i].albedo[a] = (float)rng_range(&r, 0.2, 0.9);
            emax = e > emax ? e : emax;
        }
        if (!damage || rng_below(&r, 3)) continue;
        assert_int_equal(cull_dvol_init(&dv[i], in[i].bmin, in[i].bmax, 3 + rng_below(&r, 10)), CULL_OK);
        for (uint32_t k = 1 + rng_below(&r, 4); k--;) {
            /* a point on the box's surface */
            double c[3];
            int face = (int)rng_below(&r, 6);
            for (int a = 0; a < 3; a++)
                c[a] = a == face / 2 ? (face % 2 ? in[i].bmax[a] : in[i].bmin[a]) : rng_range(&r, in[i].bmin[a], in[i].bmax[a]);
            assert_int_equal(cull_dvol_add_sphere(&dv[i], c, emax * rng_range(&r, 0.2, 0.8)), CULL_OK);
        }
        in[i].dvol = &dv[i];
    }
    for (uint32_t i = 0; i < nl; i++) {
        for (int a = 0; a < 3; a++) L[i].l.pos[a] = rng_range(&r, -25, 25);
        L[i].l.radius = rng_range(&r, 5, 30);
        for (int a = 0; a < 3; a++) L[i].color[a] = (float)rng_range(&r, 10, 200);
        if (rng_below(&r, 3) == 0) {
            L[i].l.type = CULL_LIGHT_SPOT;
            L[i].l.dir[1] = -1;
            L[i].l.cos_outer = 0.5f;
            L[i].cos_inner = 0.8f;
        }
    }
    random_view(&r, &lf->v, w, h, 1.4, 0.1, 1e4);
    *rp = r;
    lf->w = w;
    lf->h = h;
    lf->n = n;
    lf->nl = nl;
    lf->in = in;
    lf->L = L;
    lf->dv = dv;
}

static void lit_frame_free(lit_frame *lf)
{
    for (uint32_t i = 0; i < lf->n; i++) cull_dvol_free(&lf->dv[i]);
    free(lf->dv);
    free(lf->in);
    free(lf->L);
}

/* The shading kernel's instances (scalar, SSE4.1, AVX2: VANTAGE_ISA at
 * creation) draw the same frame: the same coverage and depth bit for bit
 * (the raster is shared), colours within a few ulps (only fused
 * multiply-adds round differently). */
static void test_soft_isas_agree(void **state)
{
    (void)state;
    rng r = {test_seed() ^ 0x15Au};
    const char *isas[] = {"scalar", "sse41", "avx2"};
    char *saved = test_env_keep("VANTAGE_ISA");
    vt_mesh cube = {.pos = cube_pos, .idx = cube_idx, .nv = 8, .ni = 36};
    char err[256];
    uint32_t tried = 0;
    double worst = 0;
    for (int f = 0; f < 6; f++) {
        lit_frame lf;
        lit_frame_make(&r, &lf);
        size_t np = (size_t)lf.w * lf.h;
        float *c0 = malloc(np * 16), *d0 = malloc(np * 4), *c1 = malloc(np * 16), *d1 = malloc(np * 4);
        assert_true(c0 && d0 && c1 && d1);
        for (int k = 0; k < 3; k++) {
            if (!cull_isa_supported((uint32_t)k)) continue;
            setenv("VANTAGE_ISA", isas[k], 1);
            vt_soft *sr;
            assert_int_equal(vt_soft_create(NULL, 0, &sr), 0);
            assert_int_equal(vt_soft_render(sr, &lf.v, lf.w, lf.h, &cube, 1, lf.in, lf.n, lf.L, lf.nl, k ? c1 : c0,
                                            k ? d1 : d0, lf.w, NULL, err, sizeof err),
                             0);
            vt_soft_destroy(sr);
            tried++;
            if (!k) continue;
            for (size_t p = 0; p < np; p++) {
                assert_memory_equal(&d0[p], &d1[p], sizeof d0[p]);
                assert_true(c0[4 * p + 3] == c1[4 * p + 3]);
                for (int a = 0; a < 3; a++) {
                    double e = fabs(c0[4 * p + a] - c1[4 * p + a]) / (1e-6 + fabs(c0[4 * p + a]));
                    if (e > worst) worst = e;
                    assert_true(e <= 1e-4);
                }
            }
        }
        free(c0);
        free(d0);
        free(c1);
        free(d1);
        lit_frame_free(&lf);
    }
    test_env_restore("VANTAGE_ISA", saved);
    fprintf(stderr, "shading kernels: %u renders, worst relative colour difference to scalar %.2g\n", tried, worst);
}

/* The AVX2 kernel's EVEX build (vt_shade_avx2_evex.c, taken where the CPU
 * has AVX-512 VL/DQ/BW) draws the same frames as the plain AVX2 build bit
 * for bit: the same intrinsics, only more registers. Skipped where the
 * CPU lacks it (VANTAGE_EVEX=0 picks the plain build). */
static void test_soft_evex_same_bits(void **state)
{
    (void)state;
    if (!cull_isa_supported(CULL_ISA_AVX2) || !vt_kern_evex().shade || !cull_isa_evex()) {
        fprintf(stderr, "no EVEX build or no AVX-512 VL/DQ/BW here: skipped\n");
        return;
    }
    rng r = {test_seed() ^ 0xE7Eu};
    char *saved_isa = test_env_keep("VANTAGE_ISA"), *saved_evex = test_env_keep("VANTAGE_EVEX");
    setenv("VANTAGE_ISA", "avx2", 1);
    vt_mesh cube = {.pos = cube_pos, .idx = cube_idx, .nv = 8, .ni = 36};
    char err[256];
    for (int f = 0; f < 6; f++) {
        lit_frame lf;
        lit_frame_make(&r, &lf);
        size_t np = (size_t)lf.w * lf.h;
        float *c[2], *d[2];
        for (int k = 0; k < 2; k++) {
            c[k] = malloc(np * 16), d[k] = malloc(np * 4);
            assert_true(c[k] && d[k]);
            setenv("VANTAGE_EVEX", k ? "1" : "0", 1);
            assert_true(cull_isa_evex() == k);
            vt_soft *sr;
            assert_int_equal(vt_soft_create(NULL, 0, &sr), 0);
            assert_int_equal(vt_soft_render(sr, &lf.v, lf.w, lf.h, &cube, 1, lf.in, lf.n, lf.L, lf.nl, c[k], d[k], lf.w,
                                            NULL, err, sizeof err),
                             0);
            vt_soft_destroy(sr);
        }
        assert_memory_equal(c[0], c[1], np * 16);
        assert_memory_equal(d[0], d[1], np * 4);
        for (int k = 0; k < 2; k++) free(c[k]), free(d[k]);
        lit_frame_free(&lf);
    }
    test_env_restore("VANTAGE_ISA", saved_isa);
    test_env_restore("VANTAGE_EVEX", saved_evex);
}

static void test_soft_and_gl_agree(void **state)
{
    (void)state;
    char err[512];
    vt_gl *g;
    if (vt_gl_open(&g, NULL, err, sizeof err) != 0) {
        fprintf(stderr, "no GL here, cross-check skipped: %s\n", err);
        skip();
    }
    vt_gldraw *gr;
    assert_int_equal(vt_gldraw_create(g, &gr, err, sizeof err), 0);
    vt_soft *sr;
    assert_int_equal(vt_soft_create(NULL, 0, &sr), 0);
    rng r = {test_seed() ^ 0x61u};
    vt_mesh cube = {.pos = cube_pos, .idx = cube_idx, .nv = 8, .ni = 36};
    float corner_nrm[24];
    for (int i = 0; i < 24; i++) corner_nrm[i] = cube_pos[i] / sqrtf(3.0f);
    vt_mesh smooth = cube;
    smooth.nrm = corner_nrm;
    uint64_t pixels = 0, cov_diff = 0, both = 0, depth_bad = 0, color_bad = 0, compared = 0, damaged = 0;
    double worst = 0;
    for (int f = 0; f < 8; f++) {
        lit_frame lf;
        lit_frame_make(&r, &lf);
        for (uint32_t i = 0; i < lf.n; i++) damaged += lf.in[i].dvol != NULL;
        uint32_t w = lf.w, h = lf.h, n = lf.n, nl = lf.nl;
        vt_instance *in = lf.in;
        vt_light *L = lf.L;
        cull_view v = lf.v;
        size_t np = (size_t)w * h;
        float *c1 = malloc(np * 16), *d1 = malloc(np * 4), *c2 = malloc(np * 16), *d2 = malloc(np * 4);
        /* odd frames: the cube with smooth corner normals (GL draws it indexed) */
        const vt_mesh *mesh = f % 2 ? &smooth : &cube;
        assert_int_equal(vt_soft_render(sr, &v, w, h, mesh, 1, in, n, L, nl, c1, d1, w, NULL, err, sizeof err), 0);
        int grc = vt_gldraw_render(gr, &v, w, h, mesh, 1, in, n, L, nl, c2, d2, w, NULL, err, sizeof err);
        if (grc) fprintf(stderr, "gl render: %s\n", err);
        assert_int_equal(grc, 0);
        for (uint32_t y = 0; y < h; y++)
            for (uint32_t x = 0; x < w; x++) {
                size_t p = (size_t)y * w + x;
                pixels++;
                bool a = c1[4 * p + 3] > 0, b = c2[4 * p + 3] > 0;
                if (a != b) {
                    cov_diff++;
                    continue;
                }
                if (!a) continue;
                both++;
                if (!(fabsf(d1[p] - d2[p]) <= 1e-4f * d1[p])) depth_bad++;
                /* colour only away from edges (the neighbours show the same
                   surface in both) */
                bool interior = x > 0 && y > 0 && x + 1 < w && y + 1 < h;
                for (int dy = -1; dy <= 1 && interior; dy++)
                    for (int dx = -1; dx <= 1 && interior; dx++) {
                        size_t q = p + (size_t)((ptrdiff_t)dy * w + dx);
                        interior = c1[4 * q + 3] > 0 && c2[4 * q + 3] > 0 && fabsf(d1[q] - d2[q]) <= 1e-4f * d1[q];
                    }
                if (!interior) continue;
                compared++;
                for (int k = 0; k < 3; k++) {
                    double e = fabs(c1[4 * p + k] - c2[4 * p + k]) / (1e-3 + fabs(c1[4 * p + k]));
                    if (e > worst) worst = e;
                    if (fabsf(c1[4 * p + k] - c2[4 * p + k]) > 0.01f * fabsf(c1[4 * p + k]) + 1e-3f) {
                        color_bad++;
                        break;
                    }
                }
            }
        free(c1);
        free(d1);
        free(c2);
        free(d2);
        lit_frame_free(&lf);
    }
    fprintf(stderr, "soft vs GL (%s): %llu damaged boxes, %llu pixels, %llu differ in coverage, %llu covered by both "
                    "(%llu off in depth), %llu compared in colour, %llu off (worst relative %.2g)\n",
            vt_gl_get_info(g)->renderer, (unsigned long long)damaged, (unsigned long long)pixels, (unsigned long long)cov_diff,
            (unsigned long long)both, (unsigned long long)depth_bad, (unsigned long long)compared,
            (unsigned long long)color_bad, worst);
    assert_true(both > 1000);
    assert_true(damaged > 5);
    assert_true(cov_diff * 1000 <= pixels);
    assert_true(depth_bad * 1000 <= both);
    assert_true(color_bad * 1000 <= compared);
    vt_gldraw_destroy(gr);
    vt_soft_destroy(sr);
    vt_gl_close(g);
}

/* A row's nearness or record as the depth test leaves them, one pixel at
 * a time, written out here (the rule the row kernels must follow): the
 * plane in double, rounded once to float, kept where strictly nearer. */
static void span_ref(float *nrow, uint32_t *irow, int32_t i0, int32_t i1, double na, double nz, uint32_t id)
{
    for (int32_t i = i0; i <= i1; i++) {
        double x = (double)i + 0.5, zd = na * x;
        zd += nz;
        float z = (float)zd;
        if (z > nrow[i]) {
            nrow[i] = z;
            irow[i] = id;
        }
    }
}

/* An adversarial double: NaN, infinities, huge, tiny, or ordinary. */
static double odd_double(rng *r)
{
    switch (rng_below(r, 8)) {
    case 0: return NAN;
    case 1: return rng_below(r, 2) ? INFINITY : -INFINITY;
    case 2: return rng_range(r, -1, 1) * 1e300;
    case 3: return rng_range(r, -1, 1) * 1e-300;
    default: return rng_range(r, -1, 1) * rng_log(r, 1e-6, 10);
    }
}

/* The raster's row kernels (vt_raster.h; scalar and AVX2 where the CPU
 * has it) against the one-pixel rule: runs of every length at every
 * offset of rows of 1..100 pixels (shorter than a vector too), rows
 * holding empty pixels, NaN, and values equal to the plane's (ties keep
 * what is there), planes with NaN, infinite and huge coefficients; bit for
 * bit, and nothing outside the run touched. The ground's row: random views
 * (perspective and orthographic, every depth mode, looking up, down and
 * level) and ground heights: the kernel over vt_ground_row's columns
 * equals vt_ground_at over the whole row, pixel by pixel. */
static void test_raster_row_kernels(void **state)
{
    (void)state;
    rng r = {test_seed() ^ 0x5A57u};
    vt_rkern ks[2] = {vt_rkern_scalar(), vt_rkern_pick()};
    enum { W = 100 };
    float n0[W], n1[W];
    uint32_t i0s[W], i1s[W];
    uint64_t kept = 0, ties = 0;
    for (int it = 0; it < 4000; it++) {
        uint32_t w = 1 + rng_below(&r, W);
        int32_t a = (int32_t)rng_below(&r, w), b = (int32_t)rng_below(&r, w);
        if (a > b) {
            int32_t t = a;
            a = b;
            b = t;
        }
        double na = rng_below(&r, 4) ? rng_range(&r, -1e-2, 1e-2) : odd_double(&r);
        double nz = rng_below(&r, 4) ? rng_range(&r, -0.5, 1.5) : odd_double(&r);
        for (uint32_t i = 0; i < w; i++) {
            uint32_t c = rng_below(&r, 6);
            n0[i] = c == 0 ? VT_EMPTY : c == 1 ? NAN : c == 2 ? (float)(na * (i + 0.5) + nz) /* a tie */
                                                              : (float)rng_range(&r, -0.5, 1.5);
            i0s[i] = (uint32_t)rng_u64(&r);
        }
        for (int k = 0; k < 2; k++) {
            memcpy(n1, n0, sizeof n1);
            memcpy(i1s, i0s, sizeof i1s);
            float nr[W];
            uint32_t ir[W];
            memcpy(nr, n0, sizeof nr);
            memcpy(ir, i0s, sizeof ir);
            span_ref(nr, ir, a, b, na, nz, 77);
            ks[k].span(n1, i1s, a, b, w, na, nz, 77);
            assert_memory_equal(n1, nr, w * sizeof *nr);
            assert_memory_equal(i1s, ir, w * sizeof *ir);
            if (k) continue;
            for (uint32_t i = 0; i < w; i++) {
                kept += ir[i] == 77 && i0s[i] != 77;
                ties += (int32_t)i >= a && (int32_t)i <= b && nr[i] == (float)(na * (i + 0.5) + nz) && ir[i] != 77;
            }
        }
    }
    assert_true(kept > 10000 && ties > 1000); /* not vacuous */
    /* the clear */
    for (int k = 0; k < 2; k++) {
        for (size_t n = 0; n < W; n += 1 + n / 3) {
            for (uint32_t i = 0; i < W; i++) n1[i] = 3, i1s[i] = 5;
            ks[k].clear(n1, i1s, n);
            for (uint32_t i = 0; i < W; i++) {
                assert_true(i < n ? n1[i] == VT_EMPTY && i1s[i] == 0 : n1[i] == 3 && i1s[i] == 5);
            }
        }
    }
    /* the ground */
    uint64_t hits = 0, rows = 0, skipped = 0, sure = 0;
    for (int f = 0; f < 300; f++) {
        uint32_t w = 1 + rng_below(&r, 300), h = 1 + rng_below(&r, 60);
        cull_view_desc d = {.depth_mode = rng_below(&r, 3), .viewport_w = w, .viewport_h = h};
        double proj[16], view[16], dir[3] = {rng_range(&r, -1, 1), rng_range(&r, -1, 1), rng_range(&r, -1, 1)};
        /* rolled in half the views: the horizon and the far plane's edge
           cross the rows */
        double up[3] = {rng_below(&r, 2) ? rng_range(&r, -1, 1) : 0, 1, 0};
        if (rng_below(&r, 4) == 0) dir[1] = 0; /* level: the horizon in view */
        if (fabs(dir[0]) + fabs(dir[2]) < 1e-2) dir[0] = 1;
        cull_view v;
        cull_view_rows vr;
        cull_mat_look_dir(view, dir, up);
        if (rng_below(&r, 4)) {
            cull_mat_perspective(proj, rng_range(&r, 0.3, 2.5), (double)w / h, rng_log(&r, 1e-3, 1), rng_log(&r, 10, 1e6),
                                 d.depth_mode);
        } else {
            double e = rng_log(&r, 1, 1000);
            cull_mat_ortho(proj, -e, e, -e * h / w, e * h / w, rng_range(&r, -100, 0), rng_log(&r, 10, 1e4), d.depth_mode);
        }
        cull_mat_mul(d.view_proj, proj, view);
        if (cull_view_init(&v, &d) != CULL_OK) continue;
        cull_view_rows_get(&v, &vr);
        vt_penv pe;
        memset(&pe, 0, sizeof pe);
        pe.ground = true;
        pe.ground_y = (float)(rng_below(&r, 2) ? -rng_log(&r, 1e-3, 1e3) : rng_range(&r, -2, 2));
        vt_ground g;
        vt_ground_make(&pe, &vr, (int)d.depth_mode, &g);
        if (!g.on) continue;
        double inv_w = 2.0 / w, *X = malloc(w * sizeof *X);
        assert_non_null(X);
        vt_ndc_row(w, X);
        float *gz0 = malloc(w * sizeof *gz0), *gz1 = malloc(w * sizeof *gz1);
        uint32_t *gi0 = malloc(w * sizeof *gi0), *gi1 = malloc(w * sizeof *gi1);
        assert_true(gz0 && gz1 && gi0 && gi1);
        for (uint32_t y = 0; y < h; y++) {
            double Y = (float)((2.0 * y + 1) / h - 1);
            for (uint32_t x = 0; x < w; x++) {
                gz0[x] = rng_below(&r, 3) ? VT_EMPTY : (float)rng_log(&r, 1e-6, 10);
                gi0[x] = 1;
            }
            memcpy(gz1, gz0, w * sizeof *gz0);
            memcpy(gi1, gi0, w * sizeof *gi0);
            for (uint32_t x = 0; x < w; x++) { /* the reference: every pixel */
                double nz;
                if (!vt_ground_at(&g, vt_ndc_x(x, inv_w), Y, &nz) || !((float)nz > gz0[x])) continue;
                gz0[x] = (float)nz;
                gi0[x] = VT_ID_GROUND;
                hits++;
            }
            rows++;
            for (int k = 0; k < 2; k++) {
                float *zk = k ? gz1 : malloc(w * sizeof *zk);
                uint32_t *ik = k ? gi1 : malloc(w * sizeof *ik);
                assert_true(zk && ik);
                if (!k) {
                    memcpy(zk, gz1, w * sizeof *zk);
                    memcpy(ik, gi1, w * sizeof *ik);
                }
                int32_t c[4];
                if (vt_ground_row(&g, Y, w, c)) {
                    /* as vt_soft draws a row: the sure run without the
                       ground's test, the rest with it */
                    assert_true(c[0] >= 0 && c[0] <= c[3] && c[3] < (int32_t)w);
                    assert_true(c[1] > c[2] ? c[1] == c[3] + 1 : c[0] <= c[1] && c[2] <= c[3]);
                    if (c[0] < c[1]) ks[k].ground(zk, ik, c[0], c[1] - 1, X, &g, Y, false);
                    if (c[1] <= c[2]) ks[k].ground(zk, ik, c[1], c[2], X, &g, Y, true);
                    if (c[2] < c[3]) ks[k].ground(zk, ik, c[2] + 1, c[3], X, &g, Y, false);
                    sure += k && c[1] <= c[2] ? (uint64_t)(c[2] - c[1] + 1) : 0;
                    for (int32_t x = c[1]; k && x <= c[2]; x++) {
                        double nz;
                        assert_true(vt_ground_at(&g, X[x], Y, &nz));
                    }
                } else {
                    skipped += k;
                }
                assert_memory_equal(zk, gz0, w * sizeof *zk);
                assert_memory_equal(ik, gi0, w * sizeof *ik);
                if (!k) {
                    free(zk);
                    free(ik);
                }
            }
        }
        free(gz0);
        free(gz1);
        free(gi0);
        free(gi1);
        free(X);
    }
    fprintf(stderr, "raster row kernels: %llu pixels kept, %llu ties held; ground: %llu rows (%llu skipped whole), %llu "
                    "pixels hit (%llu in sure runs)\n",
            (unsigned long long)kept, (unsigned long long)ties, (unsigned long long)rows, (unsigned long long)skipped,
            (unsigned long long)hits, (unsigned long long)sure);
    assert_true(hits > 10000 && skipped > 100 && skipped < rows && sure > hits / 2);
}

static const double *sort_eye;
static int by_distance(const void *a, const void *b)
{
    const vt_instance *p = a, *q = b;
    double dp = 0, dq = 0;
    for (int k = 0; k < 3; k++) {
        double u = (p->bmin[k] + p->bmax[k]) / 2 - sort_eye[k], v = (q->bmin[k] + q->bmax[k]) / 2 - sort_eye[k];
        dp += u * u;
        dq += v * v;
    }
    return dp < dq ? -1 : dp > dq;
}

/* The raster's coarse depth test (vt_soft_coarse_depth) skips only what
 * could not show: random frames of lit boxes (damaged ones among them,
 * drawn masked and two-sided), drawn nearest first so that much is
 * skipped, and the same with a cluster of 300 boxes; the colour and depth
 * with the test on are those with it off, bit for bit. */
static void test_soft_coarse_depth_exact(void **state)
{
    (void)state;
    rng r = {test_seed() ^ 0xC0A5u};
    vt_mesh cube = {.pos = cube_pos, .idx = cube_idx, .nv = 8, .ni = 36};
    char err[256];
    vt_soft *sr;
    assert_int_equal(vt_soft_create(NULL, 0, &sr), 0);
    uint64_t skips = 0, parts = 0;
    for (int f = 0; f < 8; f++) {
        lit_frame lf;
        lit_frame_make(&r, &lf);
        uint32_t n0 = lf.n;
        if (f & 1) { /* a dense cluster in front of the camera */
            vt_instance *in = realloc(lf.in, 300 * sizeof *in);
            assert_non_null(in);
            memset(in + lf.n, 0, (300 - lf.n) * sizeof *in);
            double dir[3] = {lf.v.clip[3], lf.v.clip[7], lf.v.clip[11]}; /* the w row: the view direction */
            double l = sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
            for (uint32_t i = lf.n; i < 300; i++) {
                double d = rng_range(&r, 2, 60);
                for (int a = 0; a < 3; a++) {
                    double c = lf.v.origin[a] + dir[a] / l * d + rng_range(&r, -d / 2, d / 2), e = rng_log(&r, 0.2, 3);
                    in[i].bmin[a] = c - e;
                    in[i].bmax[a] = c + e;
                    in[i].albedo[a] = (float)rng_range(&r, 0.2, 0.9);
                }
            }
            lf.in = in;
            lf.n = 300;
        }
        sort_eye = lf.v.origin;
        qsort(lf.in, lf.n, sizeof *lf.in, by_distance);
        size_t np = (size_t)lf.w * lf.h;
        float *c0 = malloc(np * 16), *d0 = malloc(np * 4), *c1 = malloc(np * 16), *d1 = malloc(np * 4);
        assert_true(c0 && d0 && c1 && d1);
        vt_soft_stats st;
        vt_soft_coarse_depth(sr, false);
        assert_int_equal(vt_soft_render(sr, &lf.v, lf.w, lf.h, &cube, 1, lf.in, lf.n, lf.L, lf.nl, c0, d0, lf.w, &st,
                                        err, sizeof err),
                         0);
        assert_int_equal(st.coarse_skips, 0);
        vt_soft_coarse_depth(sr, true);
        assert_int_equal(vt_soft_render(sr, &lf.v, lf.w, lf.h, &cube, 1, lf.in, lf.n, lf.L, lf.nl, c1, d1, lf.w, &st,
                                        err, sizeof err),
                         0);
        assert_memory_equal(d0, d1, np * 4);
        assert_memory_equal(c0, c1, np * 16);
        skips += st.coarse_skips;
        parts += st.triangles;
        free(c0);
        free(d0);
        free(c1);
        free(d1);
        lf.n = n0; /* lit_frame_free frees the first n0's volumes */
        lit_frame_free(&lf);
    }
    /* a wall drawn first, then boxes poking out of it by 1e-2..1e-6 of
       their distance (their fronts just nearer than the wall): a bound
       too low by a fraction of that would drop them */
    uint64_t poke_skips = 0;
    for (int f = 0; f < 6; f++) {
        uint32_t w = 64 + rng_below(&r, 100), h = 48 + rng_below(&r, 80), n = 200;
        cull_view v;
        cull_view_desc d = {.depth_mode = (uint32_t)f % 3, .viewport_w = w, .viewport_h = h};
        double proj[16], view[16], dir[3] = {0, 0, 1}, up[3] = {0, 1, 0}; /* the wall's nearness the same all over */
        cull_mat_perspective(proj, 1.0, (double)w / h, 0.1, 1e4, d.depth_mode);
        cull_mat_look_dir(view, dir, up);
        cull_mat_mul(d.view_proj, proj, view);
        assert_int_equal(cull_view_init(&v, &d), CULL_OK);
        vt_instance *in = calloc(n, sizeof *in);
        assert_non_null(in);
        double D = rng_log(&r, 2, 200);
        for (uint32_t i = 0; i < n; i++) {
            /* nearest first (so the coarse test keeps paying, and stays on) */
            double p = i ? D * 1e-2 * pow(1e-4, (double)i / n) : 0, e = i ? D * rng_log(&r, 0.01, 0.2) : 10 * D;
            double cx = i ? rng_range(&r, -0.6, 0.6) * D : 0, cy = i ? rng_range(&r, -0.4, 0.4) * D : 0;
            in[i].bmin[0] = cx - e, in[i].bmax[0] = cx + e;
            in[i].bmin[1] = cy - e, in[i].bmax[1] = cy + e;
            in[i].bmin[2] = D - p, in[i].bmax[2] = D + 1;
            for (int a = 0; a < 3; a++) in[i].albedo[a] = (float)rng_range(&r, 0.2, 0.9);
        }
        size_t np = (size_t)w * h;
        float *c0 = malloc(np * 16), *d0 = malloc(np * 4), *c1 = malloc(np * 16), *d1 = malloc(np * 4);
        assert_true(c0 && d0 && c1 && d1);
        vt_soft_stats st;
        vt_soft_coarse_depth(sr, false);
        assert_int_equal(vt_soft_render(sr, &v, w, h, &cube, 1, in, n, NULL, 0, c0, d0, w, &st, err, sizeof err), 0);
        vt_soft_coarse_depth(sr, true);
        assert_int_equal(vt_soft_render(sr, &v, w, h, &cube, 1, in, n, NULL, 0, c1, d1, w, &st, err, sizeof err), 0);
        assert_memory_equal(d0, d1, np * 4);
        assert_memory_equal(c0, c1, np * 16);
        poke_skips += st.coarse_skips;
        free(c0);
        free(d0);
        free(c1);
        free(d1);
        free(in);
    }
    fprintf(stderr, "coarse depth test: %llu triangle parts skipped (%llu triangles drawn), %llu behind a wall; pictures "
                    "the same\n",
            (unsigned long long)skips, (unsigned long long)parts, (unsigned long long)poke_skips);
    assert_true(skips > 100 && poke_skips > 100);
    vt_soft_destroy(sr);
}

/* The fill rule, written out: pixel centre (cx, cy) (1/256 pixel, y up)
 * is inside the counter-clockwise triangle (x, y) iff every edge function
 * is > 0 there, or = 0 on a left edge (going down) or a top edge
 * (horizontal, going left). */
static bool fill_rule_inside(const int64_t x[3], const int64_t y[3], int64_t cx, int64_t cy)
{
    for (int k = 0; k < 3; k++) {
        int64_t ax = x[k], ay = y[k], bx = x[(k + 1) % 3], by = y[(k + 1) % 3];
        int64_t e = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax);
        bool top_left = by - ay < 0 || (by == ay && bx - ax < 0);
        if (e < 0 || (e == 0 && !top_left)) return false;
    }
    return true;
}

/* The raster against that rule, pixel for pixel: an orthographic view
 * that maps world x, y to pixels exactly, flat triangles with vertices on
 * the 1/256 pixel grid (so snapping moves nothing): many with edges
 * through pixel centres (x or y = i + 0.5), thin and tiny ones, shared
 * edges between neighbours, several at the same depth (the first drawn
 * keeps a tie), zero-area ones (nothing drawn), and huge ones reaching
 * thousands of pixels past the view (clipped by the guard band: their
 * edges are axis-aligned or at 45 degrees, so the cut points are on the
 * grid too). Which triangle each pixel shows (from its colour) must be
 * the nearest covering one, the first of equals. */
static void test_soft_fill_rule_exact(void **state)
{
    (void)state;
    rng r = {test_seed() ^ 0xF111u};
    vt_soft *sr;
    assert_int_equal(vt_soft_create(NULL, 0, &sr), 0);
    char err[256];
    uint64_t pixels = 0, covered = 0, ties = 0;
    for (int f = 0; f < 12; f++) {
        const uint32_t W = 40 + rng_below(&r, 60), H = 24 + rng_below(&r, 50), n = 60;
        cull_view_desc d = {.viewport_w = W, .viewport_h = H, .depth_mode = CULL_DEPTH_GL};
        cull_mat_ortho(d.view_proj, 0, W, 0, H, -10, 10, CULL_DEPTH_GL);
        cull_view v;
        assert_int_equal(cull_view_init(&v, &d), CULL_OK);
        float *pos = malloc((size_t)n * 9 * sizeof *pos);
        uint32_t idx[3] = {0, 1, 2};
        vt_mesh *ms = calloc(n, sizeof *ms);
        vt_instance *in = calloc(n, sizeof *in);
        int64_t(*tx)[3] = malloc(n * sizeof *tx), (*ty)[3] = malloc(n * sizeof *ty);
        int *lvl = malloc(n * sizeof *lvl);
        assert_true(pos && ms && in && tx && ty && lvl);
        for (uint32_t t = 0; t < n; t++) {
            int64_t *x = tx[t], *y = ty[t];
            uint32_t kind = rng_below(&r, 10);
            if (kind < 2) { /* huge: a right triangle, legs on the axes, 45-degree hypotenuse */
                int64_t L = 256 * (int64_t)(2000 + rng_below(&r, 20000));
                int64_t x0 = 256 * (int64_t)rng_below(&r, W) + 128 * rng_below(&r, 2);
                int64_t y0 = 256 * (int64_t)rng_below(&r, H) + 128 * rng_below(&r, 2);
                int64_t sx = rng_below(&r, 2) ? 1 : -1, sy = rng_below(&r, 2) ? 1 : -1;
                x[0] = x0, y[0] = y0, x[1] = x0 + sx * L, y[1] = y0, x[2] = x0, y[2] = y0 + sy * L;
            } else if (kind < 3 && t > 0) { /* sharing an edge with the previous one */
                int64_t *px = tx[t - 1], *py = ty[t - 1];
                x[0] = px[1], y[0] = py[1], x[1] = px[0], y[1] = py[0];
                x[2] = 256 * (int64_t)rng_below(&r, W + 8) - 1024 + rng_below(&r, 256);
                y[2] = 256 * (int64_t)rng_below(&r, H + 8) - 1024 + rng_below(&r, 256);
            } else if (kind < 4) { /* zero area: on one line */
                int64_t x0 = 256 * (int64_t)rng_below(&r, W), y0 = 256 * (int64_t)rng_below(&r, H);
                int64_t dx = (int64_t)rng_below(&r, 2000) - 1000, dy = (int64_t)rng_below(&r, 2000) - 1000;
                x[0] = x0, y[0] = y0, x[1] = x0 + dx, y[1] = y0 + dy, x[2] = x0 + 2 * dx, y[2] = y0 + 2 * dy;
            } else { /* vertices on pixel centres, corners, or anywhere on the grid */
                for (int k = 0; k < 3; k++) {
                    uint32_t snap = rng_below(&r, 3);
                    int64_t sub = snap == 0 ? 128 : snap == 1 ? 0 : (int64_t)rng_below(&r, 256);
                    int64_t span = kind < 6 ? 6 : (int64_t)W + 10; /* small ones near each other */
                    x[k] = 256 * ((int64_t)rng_below(&r, (uint32_t)span) + (kind < 6 ? (int64_t)rng_below(&r, W) : -5)) + sub;
                    sub = snap == 0 ? 128 : snap == 1 ? 0 : (int64_t)rng_below(&r, 256);
                    span = kind < 6 ? 6 : (int64_t)H + 10;
                    y[k] = 256 * ((int64_t)rng_below(&r, (uint32_t)span) + (kind < 6 ? (int64_t)rng_below(&r, H) : -5)) + sub;
                }
            }
            /* counter-clockwise (front facing) */
            int64_t area = (x[1] - x[0]) * (y[2] - y[0]) - (y[1] - y[0]) * (x[2] - x[0]);
            if (area < 0) {
                int64_t a = x[1], b = y[1];
                x[1] = x[2], y[1] = y[2], x[2] = a, y[2] = b;
            }
            lvl[t] = kind < 2 ? 0 : (int)rng_below(&r, 4); /* the huge ones behind (most of the view) */
            for (int k = 0; k < 3; k++) {
                pos[9 * t + 3 * k] = (float)(x[k] / 256.0);
                pos[9 * t + 3 * k + 1] = (float)(y[k] / 256.0);
                pos[9 * t + 3 * k + 2] = (float)lvl[t];
                assert_true(pos[9 * t + 3 * k] * 256.0 == (double)x[k]); /* exact in float */
            }
            ms[t] = (vt_mesh){.pos = pos + 9 * t, .idx = idx, .nv = 3, .ni = 3};
            in[t] = (vt_instance){.mesh = t, .place = VT_PLACE_TRS, .rot = {0, 0, 0, 1}, .scale = {1, 1, 1},
                                  .albedo = {(float)(t + 1) / (n + 1), 0.5f, 0.5f}};
        }
        size_t np = (size_t)W * H;
        float *rgba = malloc(np * 16), *depth = malloc(np * 4);
        assert_true(rgba && depth);
        assert_int_equal(vt_soft_render(sr, &v, W, H, ms, n, in, n, NULL, 0, rgba, depth, W, NULL, err, sizeof err), 0);
        for (uint32_t j = 0; j < H; j++)
            for (uint32_t i = 0; i < W; i++) {
                int want = -1, nties = 0;
                for (uint32_t t = 0; t < n; t++) {
                    int64_t *x = tx[t], *y = ty[t];
                    if ((x[1] - x[0]) * (y[2] - y[0]) - (y[1] - y[0]) * (x[2] - x[0]) == 0) continue;
                    if (!fill_rule_inside(x, y, 256 * (int64_t)i + 128, 256 * (int64_t)j + 128)) continue;
                    if (want >= 0 && lvl[t] == lvl[want]) nties++;
                    if (want < 0 || lvl[t] > lvl[want]) want = (int)t;
                }
                const float *c = rgba + 4 * ((size_t)j * W + i);
                int got = c[3] == 0 ? -1 : (int)lrint(c[0] / c[1] * 0.5 * (n + 1)) - 1;
                if (got != want)
                    fprintf(stderr, "frame %d pixel %u,%u: shows %d, the rule says %d\n", f, i, j, got, want);
                assert_int_equal(got, want);
                pixels++;
                covered += want >= 0;
                ties += nties > 0;
            }
        free(rgba);
        free(depth);
        free(pos);
        free(ms);
        free(in);
        free(tx);
        free(ty);
        free(lvl);
    }
    fprintf(stderr, "fill rule: %llu pixels, %llu covered, %llu with a tie, all as the rule says\n",
            (unsigned long long)pixels, (unsigned long long)covered, (unsigned long long)ties);
    assert_true(covered * 2 > pixels && ties > 100);
    vt_soft_destroy(sr);
}

const struct CMUnitTest render_tests[] = {
    cmocka_unit_test(test_soft_fill_rule_exact),
    cmocka_unit_test(test_soft_coarse_depth_exact),
    cmocka_unit_test(test_raster_row_kernels),
    cmocka_unit_test(test_soft_and_gl_agree),
    cmocka_unit_test(test_soft_bad_input),
    cmocka_unit_test(test_soft_matches_ray_caster),
    cmocka_unit_test(test_soft_isas_agree),
    cmocka_unit_test(test_soft_evex_same_bits),
    cmocka_unit_test(test_tile_ranges_kernels),
    cmocka_unit_test(test_renderers_adversarial_views),
};
const size_t render_tests_count = sizeof render_tests / sizeof render_tests[0];
