/*
 * test_shadow.c — the sun's cascaded shadow maps (render/vt_shadow.c)
 * against independent models:
 *   - a box on the ground under a known sun, 1280x720, software path: the
 *     analytic shadow (the convex hull of the box's corners projected
 *     along the sun onto the ground, in double here) projected to the
 *     screen; every ground pixel more than 2 px from its edge is shadowed
 *     iff inside, the levels measured from pixels well inside and outside;
 *   - stabilization: the camera moved by fractions of a texel and turned
 *     a little: each cascade's size is unchanged and its texel grid stays
 *     on the same world lattice; the visibility of fixed ground points is
 *     the same from every camera;
 *   - adversarial inputs (the sun at the horizon, huge and degenerate
 *     instances): no crash, nothing non-finite in the picture.
 */
#include "test_daemon.h"
#include "test_util.h"

#include "vantage.h"

#include "vt_gl.h"
#include "vt_gldraw.h"
#include "vt_image.h"
#include "vt_shadow.h"
#include "vt_soft.h"

#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* A perspective view (GL depth, 1 rad vertical, near 0.1, far 1000) from
 * eye towards at: test_util's. */
static void look(cull_view *v, const double eye[3], const double at[3], uint32_t w, uint32_t h)
{
    test_view_look(v, eye, (const double[3]){at[0] - eye[0], at[1] - eye[1], at[2] - eye[2]}, w, h);
}

/* The scene: a sun from (0.5, 0.7, 0.35) (normalised), a grey ground at
 * y 0, a constant sky (the ambient that shadowed ground keeps), fixed
 * exposure, every other effect off. */
static vt_env scene_env(const double sun[3])
{
    double l = sqrt(sun[0] * sun[0] + sun[1] * sun[1] + sun[2] * sun[2]);
    return (vt_env){.sun_dir = {(float)(sun[0] / l), (float)(sun[1] / l), (float)(sun[2] / l)},
                    .sun = {20000, 20000, 20000}, .sky_mode = VT_SKY_COLOR, .sky = {1000, 1000, 1000},
                    .ground = true, .ground_height = 0, .ground_albedo = {0.5f, 0.5f, 0.5f},
                    .exposure_mode = VT_EXPOSURE_FIXED, .exposure_ev = 12};
}
#define FX_ONLY_SHADOWS (VT_FX_SSAO | VT_FX_IBL | VT_FX_FXAA | VT_FX_MSAA)

/* 2D convex hull (monotone chain) of n points (x, z), counter-clockwise
 * seen from above (+y). Returns the count. */
static int hull(double (*p)[2], int n, double (*out)[2])
{
    for (int i = 1; i < n; i++) /* insertion sort by x, then z */
        for (int j = i; j > 0 && (p[j][0] < p[j - 1][0] || (p[j][0] == p[j - 1][0] && p[j][1] < p[j - 1][1])); j--) {
            double t0 = p[j][0], t1 = p[j][1];
            p[j][0] = p[j - 1][0], p[j][1] = p[j - 1][1];
            p[j - 1][0] = t0, p[j - 1][1] = t1;
        }
    int k = 0;
    for (int pass = 0; pass < 2; pass++) {
        int start = k;
        for (int ii = 0; ii < n; ii++) {
            int i = pass ? n - 1 - ii : ii;
            while (k >= start + 2) {
                double *a = out[k - 2], *b = out[k - 1];
                double cr = (b[0] - a[0]) * (p[i][1] - a[1]) - (b[1] - a[1]) * (p[i][0] - a[0]);
                if (cr > 0) break; /* keep turns one way (either orientation works below) */
                k--;
            }
            out[k][0] = p[i][0], out[k][1] = p[i][1], k++;
        }
        k--;
    }
    return k;
}

static bool in_convex(double (*h)[2], int n, double x, double z)
{
    int pos = 0, neg = 0;
    for (int i = 0; i < n; i++) {
        const double *a = h[i], *b = h[(i + 1) % n];
        double cr = (b[0] - a[0]) * (z - a[1]) - (b[1] - a[1]) * (x - a[0]);
        pos += cr > 0, neg += cr < 0;
    }
    return !pos || !neg;
}

/* Screen position (pixels, y up as the buffers) of world point p. */
static void to_screen(const cull_view *v, const double p[3], double s[2])
{
    double q[4] = {p[0] - v->origin[0], p[1] - v->origin[1], p[2] - v->origin[2], 1}, c[4] = {0};
    for (int r = 0; r < 4; r++)
        for (int k = 0; k < 4; k++) c[r] += v->clip[k * 4 + r] * q[k];
    s[0] = (c[0] / c[3] + 1) * 0.5 * v->viewport_w;
    s[1] = (c[1] / c[3] + 1) * 0.5 * v->viewport_h;
}

static double seg_dist(const double a[2], const double b[2], double x, double y)
{
    double dx = b[0] - a[0], dy = b[1] - a[1], l2 = dx * dx + dy * dy;
    double t = l2 > 0 ? ((x - a[0]) * dx + (y - a[1]) * dy) / l2 : 0;
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    double ex = a[0] + t * dx - x, ey = a[1] + t * dy - y;
    return sqrt(ex * ex + ey * ey);
}

/* VANTAGE_SHADOW_PNG=DIR: the picture as DIR/name.png (clamped, rows
 * flipped to top-down), to look at. */
static void dump_png(const char *name, const float *rgba, uint32_t W, uint32_t H)
{
    const char *dir = getenv("VANTAGE_SHADOW_PNG");
    if (!dir) return;
    uint8_t *px = malloc((size_t)W * H * 4);
    assert_non_null(px);
    for (uint32_t y = 0; y < H; y++)
        for (uint32_t x = 0; x < W * 4; x++) {
            float c = rgba[(size_t)(H - 1 - y) * W * 4 + x];
            c = x % 4 == 3 ? 1 : c;
            px[(size_t)y * W * 4 + x] = (uint8_t)(c <= 0 ? 0 : c >= 1 ? 255 : sqrtf(c) * 255 + 0.5f);
        }
    char path[512], err[128];
    snprintf(path, sizeof path, "%s/%s.png", dir, name);
    vt_png_write(path, W, H, px, (size_t)W * 4, true, 1, err, sizeof err);
    free(px);
}

static int cmp_float(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

/* The box of the analytic test and its sun. */
static const double BOX_MIN[3] = {-1, 0, -1.5}, BOX_MAX[3] = {1, 2.5, 0.5};
static const double SUN[3] = {0.5, 0.7, 0.35};

/* The analytic test on a picture drawn by `draw` (rgba, depth of view v).
 * Returns the number of pixels checked. */
static size_t check_analytic(const cull_view *v, const float *rgba, const float *depth, const char *who)
{
    const uint32_t W = v->viewport_w, H = v->viewport_h;
    double sl = sqrt(SUN[0] * SUN[0] + SUN[1] * SUN[1] + SUN[2] * SUN[2]), s[3] = {SUN[0] / sl, SUN[1] / sl, SUN[2] / sl};
    /* the shadow on the ground: the hull of the corners moved along -s to y 0 */
    double pts[8][2], hl[16][2];
    for (int k = 0; k < 8; k++) {
        double c[3] = {k & 1 ? BOX_MAX[0] : BOX_MIN[0], k & 2 ? BOX_MAX[1] : BOX_MIN[1], k & 4 ? BOX_MAX[2] : BOX_MIN[2]};
        double t = c[1] / s[1];
        pts[k][0] = c[0] - s[0] * t;
        pts[k][1] = c[2] - s[2] * t;
    }
    int nh = hull(pts, 8, hl);
    assert_true(nh >= 4);
    double sc[16][2];
    for (int i = 0; i < nh; i++) to_screen(v, (double[3]){hl[i][0], 0, hl[i][1]}, sc[i]);
    /* the ground's hit per pixel, in double: the ray through the pixel
       centre from the inverse of the view's rows */
    cull_view_rows vr;
    cull_view_rows_get(v, &vr);
    float *lit = malloc(sizeof(float) * W * H), *dark = malloc(sizeof(float) * W * H);
    uint8_t *cls = calloc((size_t)W * H, 1); /* 0: not checked, 1 in, 2 out */
    assert_true(lit && dark && cls);
    size_t nl = 0, nd = 0;
    for (uint32_t y = 0; y < H; y++)
        for (uint32_t x = 0; x < W; x++) {
            double X = (x + 0.5) * 2.0 / W - 1, Y = (y + 0.5) * 2.0 / H - 1;
            /* ray: the points with clip x = X w, clip y = Y w, a line; two
               of its points at w 1 and w 2 */
            double P[2][3];
            for (int k = 0; k < 2; k++) {
                double w = k + 1.0;
                double a[3][3] = {{vr.x[0], vr.x[1], vr.x[2]}, {vr.y[0], vr.y[1], vr.y[2]}, {vr.w[0], vr.w[1], vr.w[2]}};
                double b[3] = {X * w - vr.x[3], Y * w - vr.y[3], w - vr.w[3]};
                /* Cramer */
                double det = a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) -
                             a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0]) +
                             a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
                for (int c = 0; c < 3; c++) {
                    double m[3][3];
                    memcpy(m, a, sizeof m);
                    for (int r = 0; r < 3; r++) m[r][c] = b[r];
                    P[k][c] = (m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) -
                               m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
                               m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])) /
                              det;
                }
            }
            double gy = -v->origin[1], dy = P[1][1] - P[0][1];
            if (!(dy < 0)) continue;
            double t = (gy - P[0][1]) / dy, wg = 1 + t; /* view depth w of the ground hit */
            if (!(wg > 0.1)) continue;
            float d = depth[(size_t)y * W + x];
            /* the pixel shows the ground where its depth is the hit's
               (relative 1e-3: float depth; a box face in front is nearer
               by far more) */
            if (!(fabs(d - wg) <= 1e-3 * wg)) continue;
            double gx = v->origin[0] + P[0][0] + t * (P[1][0] - P[0][0]);
            double gz = v->origin[2] + P[0][2] + t * (P[1][2] - P[0][2]);
            double dist = 1e9;
            for (int i = 0; i < nh; i++) {
                double e = seg_dist(sc[i], sc[(i + 1) % nh], x + 0.5, y + 0.5);
                dist = e < dist ? e : dist;
            }
            if (dist <= 2) continue;
            bool in = in_convex(hl, nh, gx, gz);
            cls[(size_t)y * W + x] = in ? 1 : 2;
            float g = rgba[((size_t)y * W + x) * 4 + 1];
            if (dist > 4 + 6.0 * W / 1280) { /* well inside / outside: the levels */
                if (in) dark[nd++] = g;
                else lit[nl++] = g;
            }
        }
    assert_true(nl > 100 && nd > 100);
    qsort(lit, nl, sizeof *lit, cmp_float);
    qsort(dark, nd, sizeof *dark, cmp_float);
    float Ll = lit[nl / 2], Ld = dark[nd / 2], mid = 0.5f * (Ll + Ld);
    /* the sun is 20000 lux against a 1000 nit sky: lit ground is several
       times the shadowed */
    if (!(Ll > 2 * Ld)) fail_msg("%s: lit %g shadowed %g", who, (double)Ll, (double)Ld);
    size_t checked = 0, bad = 0;
    for (uint32_t y = 0; y < H; y++)
        for (uint32_t x = 0; x < W; x++) {
            uint8_t c = cls[(size_t)y * W + x];
            if (!c) continue;
            checked++;
            float g = rgba[((size_t)y * W + x) * 4 + 1];
            if ((c == 1) != (g < mid)) {
                if (bad < 5)
                    print_message("%s: pixel %u,%u %s the shadow: %g (lit %g, shadowed %g)\n", who, x, y,
                                  c == 1 ? "inside" : "outside", (double)g, (double)Ll, (double)Ld);
                bad++;
            }
        }
    if (bad) fail_msg("%s: %zu of %zu ground pixels on the wrong side of the shadow", who, bad, checked);
    free(lit);
    free(dark);
    free(cls);
    return checked;
}

static void analytic_view(cull_view *v, uint32_t w, uint32_t h)
{
    look(v, (double[3]){3, 9, 11}, (double[3]){-1.5, 0, -2.5}, w, h);
}

static void test_shadow_analytic_box_soft(void **state)
{
    (void)state;
    cull_view v;
    analytic_view(&v, 1280, 720);
    vt_env env = scene_env(SUN);
    vt_instance in = {.mesh = 0, .bmin = {BOX_MIN[0], BOX_MIN[1], BOX_MIN[2]},
                      .bmax = {BOX_MAX[0], BOX_MAX[1], BOX_MAX[2]}, .albedo = {0.6f, 0.6f, 0.6f}};
    const uint32_t W = 1280, H = 720;
    float *rgba = malloc(sizeof(float) * 4 * W * H), *depth = malloc(sizeof(float) * W * H);
    assert_true(rgba && depth);
    cull_pool *pool;
    assert_int_equal(cull_pool_create(2, &pool), CULL_OK);
    vt_soft *r;
    assert_int_equal(vt_soft_create(pool, 0, &r), 0);
    vt_frame f = {.view = &v, .width = W, .height = H, .meshes = &vt_mesh_box, .nmesh = 1, .inst = &in, .ninst = 1,
                  .env = &env, .rgba = rgba, .depth = depth, .stride = W, .fx_off = FX_ONLY_SHADOWS};
    vt_soft_stats st;
    char err[256];
    assert_int_equal(vt_soft_draw(r, &f, &st, err, sizeof err), 0);
    assert_true(st.shadow_triangles > 0);
    dump_png("shadow_box_soft", rgba, W, H);
    size_t n = check_analytic(&v, rgba, depth, "soft");
    assert_true(n > 100000);
    /* VT_FX_SHADOWS off: no pass at all */
    f.fx_off |= VT_FX_SHADOWS;
    assert_int_equal(vt_soft_draw(r, &f, &st, err, sizeof err), 0);
    assert_int_equal(st.shadow_triangles, 0);
    assert_int_equal((int)st.shadow_ns, 0);
    vt_soft_destroy(r);
    cull_pool_destroy(pool);
    free(rgba);
    free(depth);
}

/* The same scene through the GL renderer (llvmpipe here), at 640x360
 * (the 2 px margin is the same; the cost is llvmpipe's). Skipped without
 * OpenGL, as tests/test_gl.c does. */
static void test_shadow_analytic_box_gl(void **state)
{
    (void)state;
    vt_gl *g = NULL;
    char err[1024];
    int rc = vt_gl_open(&g, NULL, err, sizeof err);
    if (rc == VT_ERR_NO_DISPLAY || rc == VT_ERR_NO_CONTEXT) {
        const char *req = getenv("VANTAGE_GL_REQUIRED");
        if (req && req[0] && strcmp(req, "0") != 0) fail_msg("VANTAGE_GL_REQUIRED is set but: %s", err);
        print_message("no OpenGL 3.3 core here, GL test skipped: %s\n", err);
        skip();
    }
    assert_int_equal(rc, 0);
    vt_gldraw *gr;
    assert_int_equal(vt_gldraw_create(g, &gr, err, sizeof err), 0);
    const uint32_t W = 640, H = 360;
    cull_view v;
    analytic_view(&v, W, H);
    vt_env env = scene_env(SUN);
    vt_instance in = {.mesh = 0, .bmin = {BOX_MIN[0], BOX_MIN[1], BOX_MIN[2]},
                      .bmax = {BOX_MAX[0], BOX_MAX[1], BOX_MAX[2]}, .albedo = {0.6f, 0.6f, 0.6f}};
    float *rgba = malloc(sizeof(float) * 4 * W * H), *depth = malloc(sizeof(float) * W * H);
    assert_true(rgba && depth);
    vt_frame f = {.view = &v, .width = W, .height = H, .meshes = &vt_mesh_box, .nmesh = 1, .inst = &in, .ninst = 1,
                  .env = &env, .rgba = rgba, .depth = depth, .stride = W, .fx_off = FX_ONLY_SHADOWS};
    vt_soft_stats st;
    rc = vt_gldraw_draw(gr, &f, &st, err, sizeof err);
    if (rc) fail_msg("%s", err);
    assert_true(st.shadow_triangles > 0);
    dump_png("shadow_box_gl", rgba, W, H);
    assert_true(check_analytic(&v, rgba, depth, "gl") > 20000);
    vt_gldraw_destroy(gr);
    vt_gl_close(g);
    free(rgba);
    free(depth);
}

/* ---- stabilization ------------------------------------------------------------------- */

static void fit_for(const cull_view *v, const vt_env *env, const vt_instance *in, vt_shadow_fit *fit)
{
    float s[3], mb[1][6];
    assert_true(vt_shadow_sun_dir(env, 0, s));
    for (int a = 0; a < 3; a++) mb[0][a] = -1, mb[0][3 + a] = 1;
    assert_true(vt_shadow_fit_make(v, v->viewport_w, v->viewport_h, env, s, (const float(*)[6])mb, in, 1, fit));
}

static void test_shadow_stable(void **state)
{
    (void)state;
    vt_env env = scene_env(SUN);
    vt_instance in = {.mesh = 0, .bmin = {-1, 0, -1.5}, .bmax = {1, 6, 0.5}};
    float mb[1][6] = {{-1, -1, -1, 1, 1, 1}};
    vt_shadow *sh;
    assert_int_equal(vt_shadow_create(&sh), 0);
    /* fixed ground points around the box, in world space */
    enum { NP = 2000 };
    double gp[NP][3];
    uint64_t seed = 7;
    for (int i = 0; i < NP; i++) {
        gp[i][0] = -8 + 16 * ((double)(splitmix64(&seed) >> 11) * 0x1p-53);
        gp[i][1] = 0;
        gp[i][2] = -12 + 16 * ((double)(splitmix64(&seed) >> 11) * 0x1p-53);
    }
    float vis0[NP];
    vt_shadow_fit f0 = {0};
    double g0[VT_SHADOW_CASCADES][2];
    for (int step = 0; step < 6; step++) {
        /* moves of 0.13 m .. (a fraction of the far cascades' texels,
           several of the near ones'), and a turn of the camera */
        double eye[3] = {3 + 0.013 * step, 5 + 0.007 * step, 9 - 0.011 * step};
        double at[3] = {-1 + 0.013 * step + (step == 5 ? 0.3 : 0), 0, -3 - 0.011 * step};
        cull_view v;
        look(&v, eye, at, 320, 180);
        vt_shadow_fit fit;
        fit_for(&v, &env, &in, &fit);
        uint32_t tris;
        char err[128];
        assert_int_equal(vt_shadow_draw(sh, NULL, 1, &fit, v.origin, &vt_mesh_box, (const float(*)[6])mb, &in, 1,
                                        &tris, err, sizeof err),
                         0);
        assert_true(tris > 0);
        for (uint32_t c = 0; c < fit.n; c++) {
            /* the world u, v of the map's texel corner 0 */
            double g[2];
            const float *ax[2] = {fit.u, fit.v};
            for (int a = 0; a < 2; a++)
                g[a] = -(double)fit.off[c][a] / fit.scale[c] +
                       (ax[a][0] * v.origin[0] + ax[a][1] * v.origin[1] + ax[a][2] * v.origin[2]);
            if (step == 0) {
                g0[c][0] = g[0], g0[c][1] = g[1];
                continue;
            }
            /* the same texel size (the sphere does not change with a move
               or a turn), the grid moved by whole texels (to 1e-3 of a
               texel: float offsets) */
            assert_true(fit.texel[c] == f0.texel[c]);
            for (int a = 0; a < 2; a++) {
                double k = (g[a] - g0[c][a]) / fit.texel[c];
                if (!(fabs(k - round(k)) < 2e-3))
                    fail_msg("step %d cascade %u axis %d: the grid moved %g texels", step, c, a, k);
            }
        }
        /* the visibility of the fixed ground points */
        size_t same = 0, n = 0;
        for (int i = 0; i < NP; i++) {
            float p[3] = {(float)(gp[i][0] - v.origin[0]), (float)(gp[i][1] - v.origin[1]),
                          (float)(gp[i][2] - v.origin[2])};
            float vis = vt_shadow_sun(sh, p, (const float[3]){0, 1, 0});
            assert_true(vis >= 0 && vis <= 1);
            if (step == 0) {
                vis0[i] = vis;
                continue;
            }
            /* the points in the same cascade before and after (a cascade's
               texels differ from the next one's) */
            float d0 = f0.drow[0] * (float)(gp[i][0] - 3) + f0.drow[1] * (float)(gp[i][1] - 5) +
                       f0.drow[2] * (float)(gp[i][2] - 9) + f0.drow[3];
            float d1 = fit.drow[0] * p[0] + fit.drow[1] * p[1] + fit.drow[2] * p[2] + fit.drow[3];
            int c0 = 0, c1 = 0;
            while (c0 + 1 < (int)f0.n && d0 >= f0.split[c0 + 1] * (1 - VT_SHADOW_BLEND)) c0++;
            while (c1 + 1 < (int)fit.n && d1 >= fit.split[c1 + 1] * (1 - VT_SHADOW_BLEND)) c1++;
            if (step == 5 || c0 != c1 || d0 > f0.split[c0 + 1] * (1 - VT_SHADOW_BLEND) ||
                d1 > fit.split[c1 + 1] * (1 - VT_SHADOW_BLEND))
                continue;
            n++;
            /* 1e-3: the taps' bilinear fractions differ by float rounding
               of camera-relative coordinates */
            same += fabsf(vis - vis0[i]) < 1e-3f;
        }
        if (step == 0) f0 = fit;
        else if (step < 5 && !(n > NP / 4 && same >= n - n / 200))
            fail_msg("step %d: %zu of %zu fixed ground points kept their shadow", step, same, n);
    }
    vt_shadow_destroy(sh);
}

/* ---- the span lookup and the partial clear ---------------------------------------------- */

/* vt_shadow_sun_n's lane instances against vt_shadow_sun, pixel by pixel,
 * bit for bit (they do its float operations in its order: no tolerance),
 * on points around a box's shadow (penumbrae, every cascade, past the
 * last, normals away from the sun, zero and non-finite ones) in spans of
 * odd lengths; and the maps of a second draw into the same vt_shadow (the
 * raster clears only the bands drawn into before) equal to a fresh one's. */
static void test_shadow_lookup_lanes(void **state)
{
    (void)state;
    vt_env env = scene_env(SUN);
    vt_instance in[2] = {{.mesh = 0, .bmin = {-1, 0, -1.5}, .bmax = {1, 6, 0.5}},
                         {.mesh = 0, .bmin = {30, 0, -80}, .bmax = {40, 20, -60}}};
    float mb[1][6] = {{-1, -1, -1, 1, 1, 1}};
    vt_shadow *sh, *fresh;
    assert_int_equal(vt_shadow_create(&sh), 0);
    assert_int_equal(vt_shadow_create(&fresh), 0);
    cull_view v;
    look(&v, (const double[3]){3, 5, 9}, (const double[3]){-1, 0, -3}, 320, 180);
    vt_shadow_fit fit;
    float s[3];
    assert_true(vt_shadow_sun_dir(&env, 0, s));
    assert_true(vt_shadow_fit_make(&v, 320, 180, &env, s, (const float(*)[6])mb, in, 2, &fit));
    uint32_t tris;
    char err[128];
    /* the far box first, then the near one alone: its bands must be clean */
    assert_int_equal(vt_shadow_draw(sh, NULL, 1, &fit, v.origin, &vt_mesh_box, (const float(*)[6])mb, &in[1], 1, &tris,
                                    err, sizeof err),
                     0);
    assert_int_equal(vt_shadow_draw(sh, NULL, 1, &fit, v.origin, &vt_mesh_box, (const float(*)[6])mb, in, 1, &tris,
                                    err, sizeof err),
                     0);
    assert_int_equal(vt_shadow_draw(fresh, NULL, 1, &fit, v.origin, &vt_mesh_box, (const float(*)[6])mb, in, 1, &tris,
                                    err, sizeof err),
                     0);
    assert_memory_equal(vt_shadow_maps(sh), vt_shadow_maps(fresh), (size_t)fit.n * fit.size * fit.size * sizeof(float));
    enum { NP = 4000 };
    static float px[NP], py[NP], pz[NP], nx[NP], ny[NP], nz[NP], ref[NP], got[NP];
    uint64_t seed = 11;
    size_t part = 0, dark = 0;
    for (int i = 0; i < NP; i++) {
        double r[6];
        for (int k = 0; k < 6; k++) r[k] = (double)(splitmix64(&seed) >> 11) * 0x1p-53;
        /* ground and box faces near the box; every 10th far away */
        double sc = i % 10 ? 8 : 400;
        px[i] = (float)(-3 + sc * (r[0] - 0.5) - v.origin[0]);
        py[i] = (float)((i % 3 ? 0 : 6 * r[1]) - v.origin[1]);
        pz[i] = (float)(-3 + sc * (r[2] - 0.5) - v.origin[2]);
        float n3[3] = {(float)(r[3] - 0.5), 1, (float)(r[5] - 0.5)};
        if (i % 7 == 0) n3[1] = -0.5f;            /* turned from the sun */
        if (i % 11 == 0) n3[0] = n3[1] = n3[2] = 0; /* degenerate */
        if (i % 13 == 0) px[i] = NAN;
        float l = sqrtf(n3[0] * n3[0] + n3[1] * n3[1] + n3[2] * n3[2]);
        nx[i] = l > 0 ? n3[0] / l : 0, ny[i] = l > 0 ? n3[1] / l : 0, nz[i] = l > 0 ? n3[2] / l : 0;
        ref[i] = vt_shadow_sun(sh, (const float[3]){px[i], py[i], pz[i]}, (const float[3]){nx[i], ny[i], nz[i]});
        part += ref[i] > 0 && ref[i] < 1;
        dark += ref[i] == 0;
    }
    assert_true(part > 20 && dark > 100); /* penumbrae and umbrae to compare */
    for (uint32_t isa = 0; isa < CULL_ISA_COUNT; isa++) {
        if (!cull_isa_supported(isa)) continue;
        vt_shadow_set_isa(sh, isa);
        size_t bad = 0;
        for (int i0 = 0, n = 1; i0 < NP; i0 += n, n = n % 37 + 5) {
            int m = i0 + n <= NP ? n : NP - i0;
            for (int i = i0; i < i0 + m; i++) got[i] = 1;
            vt_shadow_sun_n(sh, (unsigned)m, px + i0, py + i0, pz + i0, nx + i0, ny + i0, nz + i0, got + i0);
        }
        for (int i = 0; i < NP; i++) bad += memcmp(&got[i], &ref[i], sizeof got[i]) != 0;
        fprintf(stderr, "%s: %zu of %d lookups differ from vt_shadow_sun (%zu in penumbrae, %zu dark)\n",
                cull_isa_name(isa), bad, NP, part, dark);
        assert_int_equal(bad, 0);
    }
    vt_shadow_destroy(sh);
    vt_shadow_destroy(fresh);
}

/* n boxes on the ground (mesh 0), corners x at r[0] + r[1] u, z at r[2] +
 * r[3] u, heights r[4] + r[5] u (u uniform in 0..1 from *seed), w x d
 * metres. */
static void box_field(vt_instance *in, int n, uint64_t *seed, const float r[6], float w, float d)
{
    for (int i = 0; i < n; i++) {
        double u[3];
        for (int k = 0; k < 3; k++) u[k] = (double)(splitmix64(seed) >> 11) * 0x1p-53;
        float x = (float)(r[0] + r[1] * u[0]), z = (float)(r[2] + r[3] * u[1]), hgt = (float)(r[4] + r[5] * u[2]);
        in[i] = (vt_instance){.mesh = 0, .bmin = {x, 0, z}, .bmax = {x + w, hgt, z + d}};
    }
}

/* The footprint tiles the span lookup decides most pixels by, against
 * the maps themselves: every tile's packed bounds against the least and greatest depth over its
 * texels (vt_shadow.h's rule, by brute force here), on a field of boxes
 * of random heights drawn twice into the same vt_shadow (the tiles of
 * the cleared bands too); then lookups at random points over the field,
 * where most footprints are decided by a tile, equal to vt_shadow_sun
 * (the 16 taps) bit for bit in every instance. */
static void test_shadow_tiles(void **state)
{
    (void)state;
    vt_env env = scene_env(SUN);
    enum { NB = 60, NP = 6000 };
    static vt_instance in[NB];
    uint64_t seed = 5;
    box_field(in, NB, &seed, (const float[6]){-60, 120, -120, 110, 2, 30}, 6, 8);
    float mb[1][6] = {{-1, -1, -1, 1, 1, 1}};
    vt_shadow *sh;
    assert_int_equal(vt_shadow_create(&sh), 0);
    cull_view v;
    look(&v, (const double[3]){0, 40, 30}, (const double[3]){0, 0, -50}, 320, 180);
    vt_shadow_fit fit;
    float s[3];
    assert_true(vt_shadow_sun_dir(&env, 0, s));
    assert_true(vt_shadow_fit_make(&v, 320, 180, &env, s, (const float(*)[6])mb, in, NB, &fit));
    uint32_t tris;
    char err[128];
    for (int pass = 0; pass < 2; pass++)
        assert_int_equal(vt_shadow_draw(sh, NULL, 1, &fit, v.origin, &vt_mesh_box, (const float(*)[6])mb, in,
                                        pass ? NB : NB / 2, &tris, err, sizeof err),
                         0);
    float qlo[VT_SHADOW_CASCADES], qinv[VT_SHADOW_CASCADES];
    const float *maps = vt_shadow_maps(sh);
    const uint32_t *tl = vt_shadow_tiles(sh, qlo, qinv);
    const int S = (int)fit.size, T = VT_SHADOW_TILE, g = S / T;
    const size_t plane = (size_t)fit.n * g * g;
    size_t bad = 0, drawn = 0, loose = 0;
    for (uint32_t c = 0; c < fit.n; c++)
        for (int ty = 0; ty < g; ty++)
            for (int tx = 0; tx < g; tx++) {
                float lo = INFINITY, hi = -INFINITY;
                for (int y = T * ty - 1; y <= T * ty + 3; y++)
                    for (int x = T * tx - 1; x <= T * tx + 3; x++) {
                        if (x < 0 || y < 0 || x >= S || y >= S) continue;
                        float d = maps[((size_t)c * S + y) * S + x];
                        lo = d < lo ? d : lo, hi = d > hi ? d : hi;
                    }
                /* the packed bounds hold the range with a step to spare
                   (half of it kept here: float rounding of the
                   quantisation, under 0.1 step at 65536), except where
                   they say "unbounded" (0, 65535); and they are tight:
                   at most 3 steps wider (1 + 1 for the margin, 1 for
                   whole steps) where the range lies within them */
                size_t q = ((size_t)c * g + ty) * g + tx;
                double a = tl[q] & 0xffff, b = tl[q] >> 16;
                double ta = ((double)lo - qlo[c]) * qinv[c], tb = ((double)hi - qlo[c]) * qinv[c];
                bad += (a > 0 && !(ta >= a + 0.5)) || (b < 65535 && !(tb <= b - 0.5));
                loose += (ta >= 2 && ta <= 65533 && ta > a + 3) || (tb >= -1 && tb <= 65531 && tb < b - 3) ||
                         (hi == -FLT_MAX && b > 1);
                drawn += hi > -FLT_MAX;
            }
    fprintf(stderr, "tiles: %zu of %zu do not bound the maps' range, %zu loosely (%zu with a caster)\n", bad, plane,
            loose, drawn);
    assert_int_equal(bad, 0);
    assert_int_equal(loose, 0);
    assert_true(drawn > plane / 50);
    static float px[NP], py[NP], pz[NP], nx[NP], ny[NP], nz[NP], ref[NP], got[NP];
    size_t part = 0, dark = 0;
    for (int i = 0; i < NP; i++) {
        double r[4];
        for (int k = 0; k < 4; k++) r[k] = (double)(splitmix64(&seed) >> 11) * 0x1p-53;
        /* the ground, and every third point on a roof or a box's face */
        const vt_instance *b = &in[i % NB];
        float n3[3] = {0, 1, 0};
        double w[3] = {-70 + 140 * r[0], 0, -130 + 130 * r[1]};
        if (i % 3 == 1) w[0] = b->bmin[0] + 6 * r[2], w[1] = b->bmax[1], w[2] = b->bmin[2] + 8 * r[3];
        if (i % 3 == 2) w[0] = b->bmax[0], w[1] = b->bmax[1] * r[2], w[2] = b->bmin[2] + 8 * r[3], n3[0] = 1, n3[1] = 0;
        px[i] = (float)(w[0] - v.origin[0]), py[i] = (float)(w[1] - v.origin[1]), pz[i] = (float)(w[2] - v.origin[2]);
        nx[i] = n3[0], ny[i] = n3[1], nz[i] = n3[2];
        ref[i] = vt_shadow_sun(sh, (const float[3]){px[i], py[i], pz[i]}, n3);
        part += ref[i] > 0 && ref[i] < 1;
        dark += ref[i] == 0;
    }
    fprintf(stderr, "points: %zu in penumbrae, %zu dark of %d\n", part, dark, NP);
    assert_true(part > 50 && dark > 200); /* umbrae, penumbrae and lit ground to compare */
    for (uint32_t isa = 0; isa < CULL_ISA_COUNT; isa++) {
        if (!cull_isa_supported(isa)) continue;
        vt_shadow_set_isa(sh, isa);
        for (int i = 0; i < NP; i++) got[i] = 1;
        for (int i0 = 0; i0 < NP; i0 += 16)
            vt_shadow_sun_n(sh, 16, px + i0, py + i0, pz + i0, nx + i0, ny + i0, nz + i0, got + i0);
        size_t nb = 0;
        for (int i = 0; i < NP; i++) nb += memcmp(&got[i], &ref[i], sizeof got[i]) != 0;
        fprintf(stderr, "%s: %zu of %d lookups differ (%zu in penumbrae, %zu dark)\n", cull_isa_name(isa), nb, NP, part,
                dark);
        assert_int_equal(nb, 0);
    }
    vt_shadow_destroy(sh);
}

/* The camera-relative point the view shows at clip x = X w, y = Y w and
 * view depth w = d (the 3x3 system of the view's rows, by Cramer). */
static void view_point(const cull_view_rows *vr, double X, double Y, double d, float p[3])
{
    double m[3][3], rhs[3];
    for (int k = 0; k < 3; k++) m[0][k] = vr->x[k] - X * vr->w[k], m[1][k] = vr->y[k] - Y * vr->w[k], m[2][k] = vr->w[k];
    rhs[0] = X * vr->w[3] - vr->x[3], rhs[1] = Y * vr->w[3] - vr->y[3], rhs[2] = d - vr->w[3];
    double det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
                 m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    for (int k = 0; k < 3; k++) {
        double q[3][3];
        memcpy(q, m, sizeof q);
        for (int j = 0; j < 3; j++) q[j][k] = rhs[j];
        p[k] = (float)((q[0][0] * (q[1][1] * q[2][2] - q[1][2] * q[2][1]) - q[0][1] * (q[1][0] * q[2][2] - q[1][2] * q[2][0]) +
                        q[0][2] * (q[1][0] * q[2][1] - q[1][1] * q[2][0])) /
                       det);
    }
}

/* The casters each cascade leaves out (vt_shadow_fit's outlines: those
 * whose box, seen from the sun, misses the slice its lookups come from)
 * against a draw of every caster of the cascades' spheres: fewer
 * triangles, and every lookup at a point the view shows (every cascade,
 * the blend bands, faces turned any way) the same bit for bit. A field
 * of towers around a camera that sees a quarter of it. */
static void test_shadow_outline(void **state)
{
    (void)state;
    vt_env env = scene_env(SUN);
    enum { NB = 3000, NP = 20000 };
    static vt_instance in[NB];
    uint64_t seed = 17;
    box_field(in, NB, &seed, (const float[6]){-150, 300, -150, 300, 1, 20}, 0.4f, 0.4f);
    float mb[1][6] = {{-1, -1, -1, 1, 1, 1}};
    /* views every way round: with the sun across the view (the last two)
       the cascades' slices lie side by side seen from the sun (the strip
       a blend band adds to the next cascade's outline has its own test,
       test_shadow_outline_bands: these posts are too sparse for it) */
    static const double at[][3] = {{-40, 0, -60}, {60, 0, 0},   {-60, 0, 0},  {0, 0, 60},
                                   {0, 0, -60},   {-21, 0, 30}, {21, 0, -30}};
    size_t bad = 0, part = 0, dark = 0, blend = 0;
    for (size_t vi = 0; vi < sizeof at / sizeof at[0]; vi++) {
        cull_view v;
        look(&v, (const double[3]){0, 12, 0}, at[vi], 320, 180);
        vt_shadow_fit fit, all;
        float s[3];
        assert_true(vt_shadow_sun_dir(&env, 0, s));
        assert_true(vt_shadow_fit_make(&v, 320, 180, &env, s, (const float(*)[6])mb, in, NB, &fit));
        all = fit;
        for (uint32_t c = 0; c < fit.n; c++) {
            assert_true(fit.nhull[c] >= 3);
            all.nhull[c] = 0;
        }
        vt_shadow *sh, *ref;
        assert_int_equal(vt_shadow_create(&sh), 0);
        assert_int_equal(vt_shadow_create(&ref), 0);
        uint32_t tris, tris_all;
        char err[128];
        assert_int_equal(vt_shadow_draw(sh, NULL, 1, &fit, v.origin, &vt_mesh_box, (const float(*)[6])mb, in, NB, &tris,
                                        err, sizeof err),
                         0);
        assert_int_equal(vt_shadow_draw(ref, NULL, 1, &all, v.origin, &vt_mesh_box, (const float(*)[6])mb, in, NB,
                                        &tris_all, err, sizeof err),
                         0);
        cull_view_rows vr;
        cull_view_rows_get(&v, &vr);
        size_t bad0 = bad;
        for (int i = 0; i < NP; i++) {
            double r[6];
            for (int k = 0; k < 6; k++) r[k] = (double)(splitmix64(&seed) >> 11) * 0x1p-53;
            /* a point the view shows: clip x = X w, y = Y w at view depth w =
               d (every cascade; half of them at the picture's sides, where
               the outlines are tight) */
            double X = 2 * r[0] - 1, Y = 2 * r[1] - 1, d = fit.split[0] + (fit.split[fit.n] - fit.split[0]) * r[2] * r[2];
            if (i % 2) X = X < 0 ? -1 + 0.01 * r[3] : 1 - 0.01 * r[3];
            if (i % 4 == 1) Y = Y < 0 ? -1 + 0.01 * r[4] : 1 - 0.01 * r[4];
            float p[3];
            view_point(&vr, X, Y, d, p);
            float n3[3] = {(float)(r[3] - 0.5), (float)(r[4] - 0.2), (float)(r[5] - 0.5)};
            float l = sqrtf(n3[0] * n3[0] + n3[1] * n3[1] + n3[2] * n3[2]);
            for (int k = 0; k < 3; k++) n3[k] /= l;
            float a = vt_shadow_sun(sh, p, n3), b = vt_shadow_sun(ref, p, n3);
            for (uint32_t c = 0; c + 1 < fit.n; c++)
                blend += d < fit.split[c + 1] && d > fit.split[c + 1] - VT_SHADOW_BLEND * (fit.split[c + 1] - fit.split[c]);
            bad += memcmp(&a, &b, sizeof a) != 0;
            part += b > 0 && b < 1;
            dark += b == 0;
        }
        fprintf(stderr, "outline, view %zu: %u of %u triangles drawn; %zu of %d lookups in view differ\n", vi, tris,
                tris_all, bad - bad0, NP);
        assert_true(tris < tris_all * 3 / 4); /* the posts behind the camera cast into none */
        vt_shadow_destroy(sh);
        vt_shadow_destroy(ref);
    }
    fprintf(stderr, "outline: %zu lookups differ (%zu in penumbrae, %zu dark, %zu in blend bands)\n", bad, part, dark,
            blend);
    assert_true(part > 2000 && blend > 500); /* thin posts: penumbrae, hardly any umbra */
    assert_int_equal(bad, 0);
}

/* ---- adversarial inputs ---------------------------------------------------------------- */

static void test_shadow_adversarial(void **state)
{
    (void)state;
    const uint32_t W = 64, H = 48;
    float rgba[4 * 64 * 48], depth[64 * 48];
    vt_soft *r;
    assert_int_equal(vt_soft_create(NULL, 0, &r), 0);
    /* a perspective view (GL depth), a reversed-Z one, a top-down
       orthographic one (the commander's) */
    cull_view views[3];
    look(&views[0], (double[3]){0, 3, 10}, (double[3]){0, 0, 0}, W, H);
    {
        double proj[16], view[16], dir[3] = {0, -3, -10}, up[3] = {0, 1, 0};
        cull_view_desc d = {.origin = {0, 3, 10}, .depth_mode = CULL_DEPTH_REVERSED, .viewport_w = W, .viewport_h = H};
        cull_mat_perspective(proj, 1.0, (double)W / H, 0.1, 1000, CULL_DEPTH_REVERSED);
        cull_mat_look_dir(view, dir, up);
        cull_mat_mul(d.view_proj, proj, view);
        assert_int_equal(cull_view_init(&views[1], &d), CULL_OK);
        cull_view_desc o = {.origin = {0, 50, 0}, .depth_mode = CULL_DEPTH_GL, .viewport_w = W, .viewport_h = H};
        double down[3] = {0, -1, 0}, north[3] = {0, 0, -1};
        cull_mat_ortho(proj, -20, 20, -15, 15, 1, 200, CULL_DEPTH_GL);
        cull_mat_look_dir(view, down, north);
        cull_mat_mul(o.view_proj, proj, view);
        assert_int_equal(cull_view_init(&views[2], &o), CULL_OK);
    }
    vt_instance in[4] = {
        {.mesh = 0, .bmin = {-1, 0, -1}, .bmax = {1, 2, 1}, .albedo = {0.5f, 0.5f, 0.5f}},
        {.mesh = 0, .bmin = {-1e12, -1e12, -1e12}, .bmax = {1e12, 1e12, 1e12}, .albedo = {0.5f, 0.5f, 0.5f}},
        {.mesh = 0, .bmin = {2, 0, 2}, .bmax = {2, 0, 2}, .albedo = {0.5f, 0.5f, 0.5f}},
        {.mesh = 0, .place = VT_PLACE_TRS, .pos = {1e9, 0, 0}, .rot = {0, 0, 0, 1}, .scale = {1e6, 1e6, 0}},
    };
    const double suns[][3] = {{1, 0.0201, 0}, {1, 0.02, 0.01}, {0, 1, 0}, {0.3, -0.5, 0}, {0, 1e-7, 1}};
    for (int vi = 0; vi < 3; vi++)
    for (size_t k = 0; k < sizeof suns / sizeof suns[0]; k++)
        for (uint32_t ni = 1; ni <= 4; ni++) {
            vt_env env = scene_env(suns[k]);
            vt_frame f = {.view = &views[vi], .width = W, .height = H, .meshes = &vt_mesh_box, .nmesh = 1, .inst = in,
                          .ninst = ni == 4 ? 1 : ni, .casters = ni == 4 ? in : NULL, .ncasters = ni == 4 ? 4 : 0,
                          .env = &env, .rgba = rgba, .depth = depth, .stride = W, .fx_off = FX_ONLY_SHADOWS};
            vt_soft_stats st;
            char err[256];
            assert_int_equal(vt_soft_draw(r, &f, &st, err, sizeof err), 0);
            for (size_t i = 0; i < 4u * W * H; i++)
                if (!isfinite(rgba[i])) fail_msg("view %d, sun %zu, %u instances: pixel %zu not finite", vi, k, ni, i / 4);
            /* the plain box under a high sun: a pass, and its shadow */
            if (k == 2 && ni == 1) assert_true(st.shadow_triangles > 0);
            /* at or below the horizon: no pass */
            if (suns[k][1] / sqrt(suns[k][0] * suns[k][0] + suns[k][1] * suns[k][1] + suns[k][2] * suns[k][2]) <
                VT_SHADOW_MIN_SUN)
                assert_int_equal(st.shadow_triangles, 0);
        }
    /* a caster with a bad placement is refused like an instance */
    vt_instance bad = {.mesh = 3};
    vt_env env = scene_env(SUN);
    vt_frame f = {.view = &views[0], .width = W, .height = H, .meshes = &vt_mesh_box, .nmesh = 1, .inst = in, .ninst = 1,
                  .casters = &bad, .ncasters = 1, .env = &env, .rgba = rgba, .depth = depth, .stride = W};
    char err[256];
    assert_int_equal(vt_soft_draw(r, &f, NULL, err, sizeof err), VT_ERR_INVALID);
    assert_non_null(strstr(err, "caster"));
    vt_soft_destroy(r);
}

/* ---- casters outside the view, through the daemon ---------------------------------- */

/* A 40 m tower at x 20..24 (outside a view of the ground about the origin,
 * 64x48 RAW frames) with the sun low from +x: its shadow, a 4 m strip
 * along -x, crosses the view. The frame shows no entity (visible 0) and
 * the strip is dark; with the sun from -x the shadow falls away from the
 * view and nothing on the ground is dark. Both renderers (GL skipped
 * where there is none). */
static void test_shadow_caster_outside_view(void **state)
{
    daemon_proc *d = *state;
    vtc_client *c = connect_role(d, VP_ROLE_EDITOR, false);
    vp_entity e = {.id = 1, .class_id = 0, .aabb = {20, 0, -2, 24, 40, 2}};
    assert_int_equal(vtc_add(c, &e, 1, NULL, NULL), VP_OK);
    /* a white sky of 2000 nits, the ground at y 0, no fog, a fixed exposure */
    vp_env env;
    vp_env_default(&env);
    for (int k = 0; k < 3; k++) env.sky_color[k] = 1;
    env.sky_mode = VP_SKY_COLOR, env.sky_intensity = 2000, env.fog_density = 0, env.ground_height = 0;
    env.exposure_mode = VP_EXPOSURE_FIXED, env.exposure_ev = 13;
    enum { W = 64, H = 48 };
    for (int side = 0; side < 2; side++) {
        float l = sqrtf(0.5f);
        env.sun_dir[0] = side ? -l : l, env.sun_dir[1] = l, env.sun_dir[2] = 0;
        assert_int_equal(vtc_env_set(c, &env, NULL), VP_OK);
        for (unsigned renderer = VP_RENDERER_SOFT; renderer <= VP_RENDERER_GL; renderer++) {
            vp_render m = {.format = VP_FRAME_RAW, .renderer = (uint8_t)renderer};
            const double eye[3] = {0, 15, 4}, at[3] = {0, 0, 0};
            assert_true(vtc_view_perspective(&m.view, eye, at, NULL, 60, W, H, 0.5, 200));
            vp_frame f;
            int rc = vtc_render(c, &m, &f);
            if (rc == VP_ERR_UNSUPPORTED) continue; /* no GL here */
            assert_int_equal(rc, VP_OK);
            assert_int_equal(f.visible, 0);
            /* the centre column, all ground: its darkest pixel against its
               brightest (lit ground is sun + sky, shadowed the sky alone:
               under half) */
            const float *px = (const float *)f.data;
            float lo = INFINITY, hi = 0;
            int dark = 0;
            for (int y = 0; y < H; y++) {
                float g = px[4 * (y * W + W / 2) + 1];
                lo = g < lo ? g : lo;
                hi = g > hi ? g : hi;
            }
            for (int y = 0; y < H; y++) dark += px[4 * (y * W + W / 2) + 1] < 0.5f * hi;
            print_message("sun from %s, renderer %u: ground %g .. %g, %d dark pixels\n", side ? "-x" : "+x", renderer,
                          (double)lo, (double)hi, dark);
            if (!side) assert_true(dark >= 5); /* the 4 m strip: about 10 rows */
            else assert_int_equal(dark, 0);
            if (side) continue;
            /* the request turns the shadows off (VP_RENDER_NO_SHADOWS): the
               strip is lit; a flag past the defined ones is refused */
            m.flags = VP_RENDER_NO_SHADOWS;
            assert_int_equal(vtc_render(c, &m, &f), VP_OK);
            px = (const float *)f.data;
            dark = 0;
            for (int y = 0; y < H; y++) dark += px[4 * (y * W + W / 2) + 1] < 0.5f * hi;
            assert_int_equal(dark, 0);
            m.flags = VP_RENDER_FLAGS + 1;
            assert_int_equal(vtc_render(c, &m, &f), VP_ERR_INVALID);
        }
    }
    vtc_close(c);
}


/* A hole lets the sun through (issue 20 item 7): a 10 x 6 m wall, the
 * sun behind it at 45 degrees, a 1.5 m sphere blown through it at 3 m
 * up. The hole's centre projects along the sun onto the ground at
 * (0, 0, -3): intact, that ground is in the wall's shadow; damaged, the
 * sun reaches it through the hole (the caster's mask in the cascades),
 * in both renderers (GL uses the same maps). The wall's far corner
 * ground, (4, 0, -3), stays shadowed either way. */
static void test_shadow_through_hole(void **state)
{
    (void)state;
    enum { W = 96, H = 96 };
    float *c = malloc((size_t)W * H * 16), *d = malloc((size_t)W * H * 4);
    assert_true(c && d);
    vt_instance wall = {.mesh = 0, .bmin = {-5, 0, -0.5}, .bmax = {5, 6, 0.5}, .albedo = {0.6f, 0.6f, 0.6f}};
    cull_dvol dv;
    assert_int_equal(cull_dvol_init(&dv, wall.bmin, wall.bmax, 8), CULL_OK);
    assert_int_equal(cull_dvol_add_sphere(&dv, (double[3]){0, 3, 0}, 1.5), CULL_OK);
    vt_env env = scene_env((const double[3]){0, 1, 1});
    cull_view v;
    look(&v, (const double[3]){0, 14, -10}, (const double[3]){0, 0, -3}, W, H);
    vt_soft *soft;
    assert_int_equal(vt_soft_create(NULL, 0, &soft), 0);
    vt_gl *g = NULL;
    vt_gldraw *gr = NULL;
    char err[1024];
    if (!vt_gl_open(&g, NULL, err, sizeof err)) assert_int_equal(vt_gldraw_create(g, &gr, err, sizeof err), 0);
    for (int r = 0; r < (gr ? 2 : 1); r++)
        for (int hole = 0; hole < 2; hole++) {
            wall.dvol = hole ? &dv : NULL;
            vt_frame f = {.view = &v, .width = W, .height = H, .meshes = &vt_mesh_box, .nmesh = 1, .inst = &wall,
                          .ninst = 1, .env = &env, .rgba = c, .depth = d, .stride = W, .fx_off = FX_ONLY_SHADOWS};
            assert_int_equal(r ? vt_gldraw_draw(gr, &f, NULL, err, sizeof err) : vt_soft_draw(soft, &f, NULL, err,
                                                                                               sizeof err),
                             0);
            double sc[2], sk[2];
            to_screen(&v, (const double[3]){0, 0, -3}, sc);
            to_screen(&v, (const double[3]){4, 0, -3}, sk);
            const float *pc = c + 4 * ((size_t)sc[1] * W + (size_t)sc[0]);
            const float *pk = c + 4 * ((size_t)sk[1] * W + (size_t)sk[0]);
            print_message("%s, %s: ground under the hole %g, beside it %g\n", r ? "gl" : "soft",
                          hole ? "a hole" : "intact", (double)pc[1], (double)pk[1]);
            /* lit ground is sun + sky (20000 cos 45 + 1000) x albedo, shadowed
               the sky alone: about 15 x apart */
            if (hole) assert_true(pc[1] > 4 * pk[1]);
            else assert_true(pc[1] < 1.5f * pk[1] && pk[1] < 1.5f * pc[1]);
        }
    if (gr) vt_gldraw_destroy(gr);
    if (g) vt_gl_close(g);
    vt_soft_destroy(soft);
    cull_dvol_free(&dv);
    free(c);
    free(d);
}

/* A cascade's outline starts at the previous cascade's blend band: a
 * lookup there reads both cascades. Posts set just sunward of points in
 * the bands' nearer halves (with the sun across the view, where a band's
 * strip lies beside the next cascade's own slice seen from the sun; at
 * 1280x720, where the maps' texels are small enough for a band to reach
 * past the next cascade's 4-texel margin), lookups at those points: bit
 * for bit the same as with every caster in every cascade, and in shadow
 * (the posts do cast). With the band left out of the outline 3 of the
 * 600 differ. */
static void test_shadow_outline_bands(void **state)
{
    (void)state;
    vt_env env = scene_env(SUN);
    enum { NB = 3000, NP = 600 };
    static vt_instance in[NB + NP];
    static float pts[NP][3];
    float mb[1][6] = {{-1, -1, -1, 1, 1, 1}};
    const double eye[3] = {0, 12, 0};
    cull_view v;
    look(&v, eye, (const double[3]){-21, 0, 30}, 1280, 720);
    float s[3];
    assert_true(vt_shadow_sun_dir(&env, 0, s));
    vt_shadow_fit fit, all;
    /* the outline test's field sets the view's depth range (and so the
       splits; the posts below stay inside it) */
    uint64_t seed = 17;
    box_field(in, NB, &seed, (const float[6]){-150, 300, -150, 300, 1, 20}, 0.4f, 0.4f);
    assert_true(vt_shadow_fit_make(&v, 1280, 720, &env, s, (const float(*)[6])mb, in, NB, &fit));
    assert_true(fit.n >= 2);
    const vt_shadow_fit fit0 = fit;
    cull_view_rows vr;
    cull_view_rows_get(&v, &vr);
    for (int i = 0; i < NP; i++) {
        double r[3];
        for (int k = 0; k < 3; k++) r[k] = (double)(splitmix64(&seed) >> 11) * 0x1p-53;
        uint32_t c = (uint32_t)i % (fit.n - 1); /* the band at the end of cascade c */
        double band = VT_SHADOW_BLEND * (fit.split[c + 1] - fit.split[c]);
        double d = fit.split[c + 1] - band * (0.5 + 0.45 * r[2]); /* its nearer half: past the next one's reach */
        view_point(&vr, 1.8 * r[0] - 0.9, 1.8 * r[1] - 0.9, d, pts[i]);
        /* a post through the point 2 m sunward of it (world space), 4
           texels of the next cascade wide: it covers texel centres there */
        float q[3], h = 2 * fit0.texel[c + 1] > 0.1f ? 2 * fit0.texel[c + 1] : 0.1f;
        for (int k = 0; k < 3; k++) q[k] = (float)(pts[i][k] + eye[k]) + 2 * s[k];
        in[NB + i] = (vt_instance){.mesh = 0, .bmin = {q[0] - h, q[1] - 0.5f, q[2] - h},
                                   .bmax = {q[0] + h, q[1] + 0.5f, q[2] + h}};
    }
    assert_true(vt_shadow_fit_make(&v, 1280, 720, &env, s, (const float(*)[6])mb, in, NB + NP, &fit));
    assert_memory_equal(fit.split, fit0.split, sizeof fit.split);
    all = fit;
    for (uint32_t c = 0; c < fit.n; c++) all.nhull[c] = 0;
    vt_shadow *sh, *ref;
    assert_int_equal(vt_shadow_create(&sh), 0);
    assert_int_equal(vt_shadow_create(&ref), 0);
    uint32_t tris, tris_all;
    char err[128];
    assert_int_equal(vt_shadow_draw(sh, NULL, 1, &fit, v.origin, &vt_mesh_box, (const float(*)[6])mb, in, NB + NP, &tris,
                                    err, sizeof err),
                     0);
    assert_int_equal(vt_shadow_draw(ref, NULL, 1, &all, v.origin, &vt_mesh_box, (const float(*)[6])mb, in, NB + NP,
                                    &tris_all, err, sizeof err),
                     0);
    size_t bad = 0, dark = 0;
    for (int i = 0; i < NP; i++) {
        float a = vt_shadow_sun(sh, pts[i], s), b = vt_shadow_sun(ref, pts[i], s); /* facing the sun */
        bad += memcmp(&a, &b, sizeof a) != 0;
        dark += b < 0.5f;
    }
    fprintf(stderr, "outline bands: %u of %u triangles drawn; %zu of %d lookups differ, %zu in shadow\n", tris,
            tris_all, bad, NP, dark);
    assert_true(dark > NP / 2);
    assert_int_equal(bad, 0);
    vt_shadow_destroy(sh);
    vt_shadow_destroy(ref);
}

const struct CMUnitTest shadow_tests[] = {
    cmocka_unit_test(test_shadow_lookup_lanes),
    cmocka_unit_test(test_shadow_tiles),
    cmocka_unit_test(test_shadow_outline),
    cmocka_unit_test(test_shadow_outline_bands),
    cmocka_unit_test(test_shadow_analytic_box_soft),
    cmocka_unit_test(test_shadow_analytic_box_gl),
    cmocka_unit_test(test_shadow_stable),
    cmocka_unit_test(test_shadow_adversarial),
    cmocka_unit_test(test_shadow_through_hole),
    DAEMON_TEST(test_shadow_caster_outside_view),
};
const size_t shadow_tests_count = sizeof shadow_tests / sizeof shadow_tests[0];
