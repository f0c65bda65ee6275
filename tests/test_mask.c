/*
 * test_mask.c — the destruction mask as the renderers draw it (vt_mask.h)
 * against an independent model: a ray per pixel centre (tests/occ_ref.c)
 * hits a damaged slab's front face in double; there the mask is computed
 * again in double (the field's trilinear value plus the detail noise,
 * written out here from its definition: the same lattice hash, nothing of
 * vt_mask.h's float code). Where that mask is clearly positive the pixel
 * must show the face, charred by exactly the rim factor; where it is
 * clearly negative it must not. Then a box with a hole: its inside shows
 * through, turned over and darkened, in both renderers.
 */
#include "test_util.h"

#include "occ_ref.h"
#include "vt_gldraw.h"
#include "vt_mask.h"
#include "vt_shade.h"
#include "vt_soft.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ---- the mask in double, from its definition ---- */

static double ref_lattice(int64_t i, int64_t j, int64_t k)
{
    uint32_t h = (uint32_t)i * 0x8da6b343u ^ (uint32_t)j * 0xd8163841u ^ (uint32_t)k * 0xcb1ab31fu;
    h ^= h >> 16;
    h *= 0x7feb352du;
    h ^= h >> 15;
    h *= 0x846ca68bu;
    h ^= h >> 16;
    return (double)(h >> 8) / 8388607.5 - 1.0;
}

static double ref_fade(double t)
{
    return t * t * (3 - 2 * t);
}

static double ref_vnoise(const double p[3])
{
    int64_t c[3];
    double t[3];
    for (int a = 0; a < 3; a++) {
        double f = floor(p[a]);
        c[a] = (int64_t)f;
        t[a] = ref_fade(p[a] - f);
    }
    double sum = 0;
    for (int corner = 0; corner < 8; corner++) {
        double wgt = 1;
        for (int a = 0; a < 3; a++) wgt *= corner >> a & 1 ? t[a] : 1 - t[a];
        sum += wgt * ref_lattice(c[0] + (corner & 1), c[1] + (corner >> 1 & 1), c[2] + (corner >> 2 & 1));
    }
    return sum;
}

typedef struct ref_mask {
    double amp, band, cell;
} ref_mask;

static ref_mask ref_scales(const cull_dvol *v)
{
    double s = fmax(v->step[0], fmax(v->step[1], v->step[2]));
    return (ref_mask){.amp = s / 4, .band = s / 4, .cell = s / 2};
}

/* The mask at world point p. */
static double ref_mask_at(const cull_dvol *v, const double p[3])
{
    ref_mask m = ref_scales(v);
    double q[3], q2[3];
    for (int a = 0; a < 3; a++) {
        double u = (p[a] - v->origin[a]) / v->step[a];
        u = fmin(fmax(u, 0), v->n[a] - 1.0);
        q[a] = u * v->step[a] / m.cell;
        q2[a] = 2 * q[a] + 17;
    }
    return cull_dvol_sample(v, p) + m.amp * (0.6 * ref_vnoise(q) + 0.4 * ref_vnoise(q2));
}

static double ref_rim(const cull_dvol *v, double e)
{
    double k = e / ref_scales(v).band;
    if (k >= 1) return 1;
    if (k <= 0) return VT_MASK_CHAR;
    return VT_MASK_CHAR + (1 - VT_MASK_CHAR) * ref_fade(k);
}

/* ---- renderers ---- */

typedef struct rend {
    const char *name;
    vt_soft *soft;
    vt_gl *g;
    vt_gldraw *gl;
} rend;

static int rend_draw(const rend *r, const cull_view *v, uint32_t w, uint32_t h, const vt_mesh *m,
                     const vt_instance *in, uint32_t n, float *rgba, float *depth)
{
    char err[256];
    int rc = r->soft ? vt_soft_render(r->soft, v, w, h, m, 1, in, n, NULL, 0, rgba, depth, w, NULL, err, sizeof err)
                     : vt_gldraw_render(r->gl, v, w, h, m, 1, in, n, NULL, 0, rgba, depth, w, NULL, err, sizeof err);
    if (rc) fprintf(stderr, "%s: %s\n", r->name, err);
    return rc;
}

/* The soft renderer, and the GL one where there is GL (n: how many). */
static uint32_t rends_open(rend rs[2])
{
    memset(rs, 0, 2 * sizeof *rs);
    rs[0].name = "soft";
    assert_int_equal(vt_soft_create(NULL, 0, &rs[0].soft), 0);
    char err[256];
    if (vt_gl_open(&rs[1].g, NULL, err, sizeof err)) {
        fprintf(stderr, "no GL here, the GL renderer's masks are not checked: %s\n", err);
        return 1;
    }
    assert_int_equal(vt_gldraw_create(rs[1].g, &rs[1].gl, err, sizeof err), 0);
    rs[1].name = "gl";
    return 2;
}

static void rends_close(rend rs[2], uint32_t n)
{
    vt_soft_destroy(rs[0].soft);
    if (n > 1) {
        vt_gldraw_destroy(rs[1].gl);
        vt_gl_close(rs[1].g);
    }
}

static void look_at(cull_view *v, const double eye[3], const double at[3], double fov, uint32_t w, uint32_t h,
                    uint32_t depth_mode)
{
    cull_view_desc d = {.depth_mode = depth_mode, .viewport_w = w, .viewport_h = h};
    memcpy(d.origin, eye, sizeof d.origin);
    double proj[16], view[16], dir[3], up[3] = {0, 1, 0};
    for (int a = 0; a < 3; a++) dir[a] = at[a] - eye[a];
    cull_mat_perspective(proj, fov, (double)w / h, 0.1, 1e4, depth_mode);
    cull_mat_look_dir(view, dir, up);
    cull_mat_mul(d.view_proj, proj, view);
    assert_int_equal(cull_view_init(v, &d), CULL_OK);
}

/* A slab 10 x 10 x 0.4 m (anywhere up to 1e4 m out) with 1..6 holes on its
 * front face (+z), random volume resolutions, cameras in front of it in
 * every depth mode; each renderer, damaged and intact. */
static void test_mask_matches_reference(void **state)
{
    (void)state;
    rng r = {test_seed() ^ 0x3A5Cu};
    rend rs[2];
    uint32_t nr = rends_open(rs);
    const vt_mesh cube = vt_mesh_box; /* the unit cube, flat normals */
    const uint32_t W = 160, H = 120;
    float *cd = malloc(W * H * 16), *dd = malloc(W * H * 4), *ci = malloc(W * H * 16), *di = malloc(W * H * 4);
    assert_true(cd && dd && ci && di);
    for (uint32_t ri = 0; ri < nr; ri++) {
        uint64_t face = 0, open = 0, band = 0, bad_cov = 0, bad_rim = 0;
        double worst_rim = 0;
        for (int f = 0; f < 24; f++) {
            double off[3];
            for (int a = 0; a < 3; a++) off[a] = rng_below(&r, 3) ? rng_range(&r, -50, 50) : rng_range(&r, -1e4, 1e4);
            vt_instance in = {.mesh = 0, .albedo = {0.6f, 0.5f, 0.4f}};
            for (int a = 0; a < 3; a++) {
                double e = a == 2 ? 0.2 : 5;
                in.bmin[a] = off[a] - e;
                in.bmax[a] = off[a] + e;
            }
            cull_dvol dv;
            assert_int_equal(cull_dvol_init(&dv, in.bmin, in.bmax, 4 + rng_below(&r, 9)), CULL_OK);
            uint32_t ns = 1 + rng_below(&r, 6);
            for (uint32_t k = 0; k < ns; k++) {
                double c[3] = {off[0] + rng_range(&r, -4, 4), off[1] + rng_range(&r, -4, 4), off[2] + 0.2};
                assert_int_equal(cull_dvol_add_sphere(&dv, c, rng_range(&r, 0.4, 2.5)), CULL_OK);
            }
            double eye[3] = {off[0] + rng_range(&r, -3, 3), off[1] + rng_range(&r, -3, 3), off[2] + rng_range(&r, 6, 18)};
            double at[3] = {off[0] + rng_range(&r, -2, 2), off[1] + rng_range(&r, -2, 2), off[2]};
            cull_view v;
            look_at(&v, eye, at, rng_range(&r, 0.6, 1.2), W, H, rng_below(&r, 3));
            assert_int_equal(rend_draw(&rs[ri], &v, W, H, &cube, &in, 1, ci, di), 0);
            in.dvol = &dv;
            assert_int_equal(rend_draw(&rs[ri], &v, W, H, &cube, &in, 1, cd, dd), 0);
            occ_ref ref;
            assert_int_equal(occ_ref_init(&ref, &v, W, H), 0);
            double zc = off[2] + 0.2 - eye[2]; /* the front face, camera-relative */
            for (uint32_t j = 0; j < H; j++)
                for (uint32_t i = 0; i < W; i++) {
                    size_t px = (size_t)j * W + i;
                    if (di[px] == INFINITY) continue; /* the ray misses the slab */
                    const double *ray = ref.ray + 6 * px;
                    double t = (zc - ray[2]) / ray[5], p[3];
                    for (int a = 0; a < 3; a++) p[a] = eye[a] + ray[a] + t * ray[3 + a];
                    if (fabs(p[0] - off[0]) > 4.98 || fabs(p[1] - off[1]) > 4.98) continue; /* near the outline */
                    double m = ref_mask_at(&dv, p);
                    if (fabs(m) <= 1e-3) {
                        band++;
                        continue;
                    }
                    if (m > 0) {
                        face++;
                        if (dd[px] != di[px]) {
                            if (bad_cov++ < 3)
                                fprintf(stderr, "%s: (%u,%u) mask %g: face not drawn (depth %g, intact %g)\n",
                                        rs[ri].name, i, j, m, dd[px], di[px]);
                            continue;
                        }
                        for (int a = 0; a < 3; a++) {
                            double e = fabs(cd[4 * px + a] / ci[4 * px + a] - ref_rim(&dv, m));
                            worst_rim = fmax(worst_rim, e);
                            if (e > 2e-3 && bad_rim++ < 3)
                                fprintf(stderr, "%s: (%u,%u) mask %g: rim %g, expected %g\n", rs[ri].name, i, j, m,
                                        cd[4 * px + a] / ci[4 * px + a], ref_rim(&dv, m));
                        }
                    } else {
                        open++;
                        /* destroyed: nothing there, or something behind the face */
                        if (!(dd[px] == INFINITY || dd[px] > di[px] * (1 + 1e-6))) {
                            if (bad_cov++ < 3) fprintf(stderr, "%s: (%u,%u) mask %g: face drawn\n", rs[ri].name, i, j, m);
                        }
                    }
                }
            occ_ref_free(&ref);
            cull_dvol_free(&dv);
        }
        fprintf(stderr,
                "mask (%s) vs double reference: %llu face pixels, %llu open, %llu within 1 mm of the rim (not "
                "judged); %llu wrong coverage, %llu wrong rim shade (worst %.2g)\n",
                rs[ri].name, (unsigned long long)face, (unsigned long long)open, (unsigned long long)band,
                (unsigned long long)bad_cov, (unsigned long long)bad_rim, worst_rim);
        assert_true(open > 1000 && face > 10000); /* not vacuous */
        assert_true(band * 200 < face + open);
        assert_int_equal(bad_cov, 0);
        assert_int_equal(bad_rim, 0);
    }
    free(cd);
    free(dd);
    free(ci);
    free(di);
    rends_close(rs, nr);
}

/* A 4 m box (the unit cube stretched) with a 1.2 m hole in its front
 * face (z = 2), seen head-on from z = 10 (reversed-Z) at 101 x 101, with
 * the renderers and the pictures' buffers. */
enum { HW = 101, HH = 101 };
typedef struct holed {
    rend rs[2];
    uint32_t nr;
    vt_mesh cube;           /* the unit cube, flat normals */
    float *c, *d;           /* colour and depth, HW x HH */
    vt_instance in;
    cull_dvol dv;
    cull_view v;
} holed;

static void holed_open(holed *h)
{
    h->nr = rends_open(h->rs);
    h->cube = vt_mesh_box;
    h->c = malloc(HW * HH * 16), h->d = malloc(HW * HH * 4);
    assert_true(h->c && h->d);
    h->in = (vt_instance){.mesh = 0, .bmin = {-2, -2, -2}, .bmax = {2, 2, 2}, .albedo = {0.8f, 0.6f, 0.4f}};
    assert_int_equal(cull_dvol_init(&h->dv, h->in.bmin, h->in.bmax, 8), CULL_OK);
    assert_int_equal(cull_dvol_add_sphere(&h->dv, (double[3]){0, 0, 2}, 1.2), CULL_OK);
    h->in.dvol = &h->dv;
    look_at(&h->v, (double[3]){0, 0, 10}, (double[3]){0, 0, 0}, 0.8, HW, HH, CULL_DEPTH_REVERSED);
}

static void holed_close(holed *h)
{
    cull_dvol_free(&h->dv);
    free(h->c);
    free(h->d);
    rends_close(h->rs, h->nr);
}

/* A 4 m box with a hole in its front face: through it, the back wall's
 * inside (its back face, turned over: depth of the back wall, the albedo
 * times VT_MASK_INTERIOR); beside it, the front face as before. A broken
 * volume is refused with VT_ERR_INVALID before anything is drawn. */
static void test_mask_inside_shows(void **state)
{
    (void)state;
    holed h;
    holed_open(&h);
    for (uint32_t ri = 0; ri < h.nr; ri++) {
        assert_int_equal(rend_draw(&h.rs[ri], &h.v, HW, HH, &h.cube, &h.in, 1, h.c, h.d), 0);
        size_t mid = (size_t)(HH / 2) * HW + HW / 2, side = (size_t)(HH / 2) * HW + HW / 2 + 25;
        fprintf(stderr, "mask (%s): through the hole depth %g (back wall 12), colour %g; beside it depth %g\n",
                h.rs[ri].name, h.d[mid], h.c[4 * mid], h.d[side]);
        assert_true(fabs(h.d[mid] - 12) < 1e-3);
        assert_true(fabs(h.d[side] - 8) < 1e-3);
        for (int a = 0; a < 3; a++) {
            assert_true(fabs(h.c[4 * mid + a] - VT_AMBIENT * h.in.albedo[a] * VT_MASK_INTERIOR) < 1e-6);
            assert_true(fabs(h.c[4 * side + a] - VT_AMBIENT * h.in.albedo[a]) < 1e-6);
        }
    }
    /* a broken volume (one sample on an axis; no field) is refused before
       anything is drawn: the buffers keep what they held */
    cull_dvol bad = h.dv;
    bad.n[0] = 1;
    cull_dvol nofield = h.dv;
    nofield.d = NULL;
    const cull_dvol *broken[2] = {&bad, &nofield};
    for (uint32_t ri = 0; ri < h.nr; ri++)
        for (int k = 0; k < 2; k++) {
            for (size_t q = 0; q < (size_t)HW * HH; q++) h.d[q] = -7.0f;
            h.in.dvol = broken[k];
            char err[256] = "";
            int rc = h.rs[ri].soft ? vt_soft_render(h.rs[ri].soft, &h.v, HW, HH, &h.cube, 1, &h.in, 1, NULL, 0, h.c,
                                                    h.d, HW, NULL, err, sizeof err)
                                   : vt_gldraw_render(h.rs[ri].gl, &h.v, HW, HH, &h.cube, 1, &h.in, 1, NULL, 0, h.c, h.d,
                                                      HW, NULL, err, sizeof err);
            assert_int_equal(rc, VT_ERR_INVALID);
            assert_non_null(strstr(err, "bad destruction volume"));
            for (size_t q = 0; q < (size_t)HW * HH; q++) assert_true(h.d[q] == -7.0f);
        }
    holed_close(&h);
}

/* vt_mask_clear is conservative: wherever it calls a triangle clear, the
 * mask at points all over it (corners, edges, inside) is at least the
 * band (no rim, nothing discarded). Random volumes, spheres and triangles
 * near them; counts how many it calls clear (not vacuous). */
static void test_mask_clear_is_conservative(void **state)
{
    (void)state;
    rng r = {test_seed() ^ 0xC1EAu};
    uint64_t tris = 0, clear = 0, points = 0;
    for (int f = 0; f < 300; f++) {
        double lo[3], hi[3], cam[3];
        for (int a = 0; a < 3; a++) {
            double c = rng_range(&r, -100, 100), e = rng_log(&r, 0.5, 20);
            lo[a] = c - e;
            hi[a] = c + e;
            cam[a] = c + rng_range(&r, -200, 200);
        }
        cull_dvol dv;
        assert_int_equal(cull_dvol_init(&dv, lo, hi, 3 + rng_below(&r, 14)), CULL_OK);
        for (uint32_t k = 1 + rng_below(&r, 8); k--;) {
            double c[3];
            for (int a = 0; a < 3; a++) c[a] = rng_range(&r, lo[a], hi[a]);
            assert_int_equal(cull_dvol_add_sphere(&dv, c, rng_log(&r, 0.2, 10)), CULL_OK);
        }
        vt_mask m;
        vt_mask_make(&dv, cam, &m);
        double band = 1.0 / m.ib;
        for (int t = 0; t < 50; t++) {
            float p[3][3];
            double c0[3];
            for (int a = 0; a < 3; a++) c0[a] = rng_range(&r, lo[a], hi[a]);
            for (int k = 0; k < 3; k++)
                for (int a = 0; a < 3; a++) {
                    double q = c0[a] + rng_range(&r, -5, 5);
                    q = fmin(fmax(q, lo[a]), hi[a]);
                    p[k][a] = (float)(q - cam[a]);
                }
            tris++;
            if (!vt_mask_clear(&m, (const float(*)[3])p)) continue;
            clear++;
            for (int s = 0; s < 40; s++) {
                double u = rng_f(&r), v = rng_f(&r);
                if (u + v > 1) u = 1 - u, v = 1 - v;
                if (s < 3) u = s == 1, v = s == 2;
                double wp[3];
                for (int a = 0; a < 3; a++)
                    wp[a] = cam[a] + p[0][a] + u * (p[1][a] - p[0][a]) + v * (p[2][a] - p[0][a]);
                double e = ref_mask_at(&dv, wp);
                points++;
                if (!(e >= band)) fail_msg("a clear triangle has mask %g < band %g at a point", e, band);
                float ef = vt_mask_eval(&m, (float)(wp[0] - cam[0]), (float)(wp[1] - cam[1]), (float)(wp[2] - cam[2]));
                assert_true(vt_mask_rim(&m, ef) == 1.0f);
            }
        }
        cull_dvol_free(&dv);
    }
    fprintf(stderr, "mask split: %llu of %llu triangles near holes called clear; %llu points on them checked\n",
            (unsigned long long)clear, (unsigned long long)tris, (unsigned long long)points);
    assert_true(clear * 20 > tris && clear < tris);
}


/* With an environment (issue 20) a hole's inside is lit as geometry, not
 * darkened by a constant: under a uniform white sky (image-based ambient,
 * no sun, no occlusion pass, no FXAA) the back wall's inside seen through
 * the hole (its back face turned over: normal +z, towards the eye) shows
 * what the front face beside the hole (normal +z, the same material)
 * shows, within 2 % (the two pixels' view directions differ by 0.15 rad,
 * the specular's only change). Before, it was VT_MASK_INTERIOR (0.35)
 * times that. */
static void test_mask_inside_lit_with_env(void **state)
{
    (void)state;
    holed h;
    holed_open(&h);
    vt_env env = {.sky_mode = VT_SKY_COLOR, .sky = {1, 1, 1}, .exposure_mode = VT_EXPOSURE_FIXED};
    for (uint32_t ri = 0; ri < h.nr; ri++) {
        vt_frame f = {.view = &h.v, .width = HW, .height = HH, .meshes = &h.cube, .nmesh = 1, .inst = &h.in, .ninst = 1,
                      .env = &env, .rgba = h.c, .depth = h.d, .stride = HW,
                      .fx_off = VT_FX_SSAO | VT_FX_FXAA | VT_FX_SHADOWS};
        char err[256];
        int rc = h.rs[ri].soft ? vt_soft_draw(h.rs[ri].soft, &f, NULL, err, sizeof err)
                             : vt_gldraw_draw(h.rs[ri].gl, &f, NULL, err, sizeof err);
        if (rc) fail_msg("%s: %s", h.rs[ri].name, err);
        size_t mid = (size_t)(HH / 2) * HW + HW / 2, side = (size_t)(HH / 2) * HW + HW / 2 + 25;
        assert_true(fabs(h.d[mid] - 12) < 1e-3 && fabs(h.d[side] - 8) < 1e-3);
        for (int a = 0; a < 3; a++) {
            double ratio = h.c[4 * mid + a] / h.c[4 * side + a];
            fprintf(stderr, "mask inside lit (%s): channel %d inside %g, front face %g, ratio %.4f\n", h.rs[ri].name, a,
                    h.c[4 * mid + a], h.c[4 * side + a], ratio);
            assert_true(h.c[4 * side + a] > 0.05f);
            assert_true(fabs(ratio - 1) < 0.02);
        }
    }
    holed_close(&h);
}

const struct CMUnitTest mask_tests[] = {
    cmocka_unit_test(test_mask_clear_is_conservative),
    cmocka_unit_test(test_mask_inside_shows),
    cmocka_unit_test(test_mask_inside_lit_with_env),
    cmocka_unit_test(test_mask_matches_reference),
};
const size_t mask_tests_count = sizeof mask_tests / sizeof mask_tests[0];
