/*
 * test_gl.c — the headless OpenGL path (render/vt_gl.h: vt_egl.c,
 * vt_gl_target.c, vt_gl_shader.c) against reference models: a clear reads
 * back bit for bit (RGBA16F and RGBA32F, direct and PBO, whole target and
 * sub-regions); a triangle with vertices on the 1/16-pixel grid covers
 * exactly the pixel centres an edge-function test in double says it covers (pixels within 0.01 px of an edge are not
 * judged), and its depth at those centres is the analytic screen-space
 * interpolation within 1e-6, under GL's default depth convention and
 * under glClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE); random floats go
 * through a texture and a shader into the target and come back exact
 * (RGBA32F) or as one of the two neighbouring halves (RGBA16F); two
 * contexts render at once on two threads, one closing while the other
 * goes on (the shared display must survive); a context moves between
 * threads; open / close cycles (leak-checked under ASan); bad arguments,
 * shader compile and link errors with the driver's log.
 *
 * Machines without OpenGL: every test that needs a context SKIPS, saying
 * why (vt_gl_open's message names each EGL platform and what it said).
 * VANTAGE_GL_REQUIRED=1 turns that skip into a failure, for machines that
 * are known to have Mesa (llvmpipe) or a GPU.
 *
 * Compiles to nothing until the build puts render/ on the include path;
 * once test_main.c lists gl_tests, a missing include path is a link error,
 * not a silent skip.
 */
#include "test_util.h"

#if defined(__has_include)
#if __has_include("vt_gl.h") && __has_include(<epoxy/gl.h>)
#define VT_TEST_GL 1
#endif
#endif

#ifdef VT_TEST_GL
#include "vt_gl.h"

#include <epoxy/gl.h>

#include <pthread.h>
#include <stdbool.h>
#include <stdio.h>
#include <string.h>

TEST_GROUP(gl_tests)

/* ---- opening, or skipping ------------------------------------------------ */

static bool gl_required(void)
{
    const char *s = getenv("VANTAGE_GL_REQUIRED");
    return s && s[0] && strcmp(s, "0") != 0;
}


/* Opens with opts (NULL: auto) or skips the test when this machine has no
 * usable OpenGL at all. */
static vt_gl *open_or_skip(const vt_gl_opts *o)
{
    vt_gl *g = NULL;
    char err[1024];
    int rc = vt_gl_open(&g, o, err, sizeof err);
    if (rc == VT_ERR_NO_DISPLAY || rc == VT_ERR_NO_CONTEXT) {
        if (gl_required()) fail_msg("VANTAGE_GL_REQUIRED is set but: %s", err);
        print_message("no OpenGL 3.3 core here, GL test skipped: %s\n", err);
        skip();
    }
    if (rc) print_message("vt_gl_open: %d %s\n", rc, err);
    assert_int_equal(rc, 0);
    assert_string_equal(err, "");
    assert_non_null(g);
    return g;
}

static vt_gl_target *make_target(vt_gl *g, uint32_t w, uint32_t h, vt_gl_color_format f)
{
    vt_gl_target *t = NULL;
    char err[512];
    int rc = vt_gl_target_create(g, w, h, &(vt_gl_target_desc){.color = f}, &t, err, sizeof err);
    if (rc) print_message("vt_gl_target_create %ux%u: %d %s\n", w, h, rc, err);
    assert_int_equal(rc, 0);
    assert_non_null(t);
    return t;
}

static void read_ok(vt_gl_target *t, float *rgba, float *depth, const vt_gl_read_desc *d)
{
    char err[512];
    int rc = vt_gl_readback(t, rgba, depth, d, err, sizeof err);
    if (rc) print_message("vt_gl_readback: %d %s\n", rc, err);
    assert_int_equal(rc, 0);
    assert_string_equal(err, "");
}

static bool same_float(float a, float b)
{
    return memcmp(&a, &b, sizeof a) == 0;
}

/* ---- a triangle drawer: one program, one VAO, one VBO -------------------- */

/* The vertex layout: clip coordinates, attribute 0, tightly packed. */
typedef struct vtx {
    float x, y, z, w;
} vtx;

static const char *const TRI_VS =
    "#version 330 core\n"
    "layout(location = 0) in vec4 clip;\n"
    "void main() { gl_Position = clip; }\n";

static const char *const TRI_FS =
    "#version 330 core\n"
    "uniform vec4 color;\n"
    "out vec4 o;\n"
    "void main() { o = color; }\n";

typedef struct drawer {
    GLuint prog, vao, vbo;
    GLint  color_loc;
} drawer;

/* Returns 0 or the vt_gl error (threads count failures instead of asserting). */
static int drawer_init(vt_gl *g, drawer *d, char *err, size_t errlen)
{
    memset(d, 0, sizeof *d);
    int rc = vt_gl_program_build(g, TRI_VS, TRI_FS, &d->prog, err, errlen);
    if (rc) return rc;
    d->color_loc = glGetUniformLocation(d->prog, "color");
    glGenVertexArrays(1, &d->vao);
    glGenBuffers(1, &d->vbo);
    glBindVertexArray(d->vao);
    glBindBuffer(GL_ARRAY_BUFFER, d->vbo);
    glVertexAttribPointer(0, 4, GL_FLOAT, GL_FALSE, sizeof(vtx), (void *)0);
    glEnableVertexAttribArray(0);
    glBindVertexArray(0);
    return glGetError() == GL_NO_ERROR ? 0 : VT_ERR_GL;
}

static void drawer_free(drawer *d)
{
    glDeleteProgram(d->prog);
    glDeleteVertexArrays(1, &d->vao);
    glDeleteBuffers(1, &d->vbo);
}

/* Draws n/3 triangles into the bound framebuffer, depth test ALWAYS with
 * depth writes on, no culling. */
static void drawer_draw(const drawer *d, const vtx *v, int n, const float color[4])
{
    glUseProgram(d->prog);
    glUniform4fv(d->color_loc, 1, color);
    glBindVertexArray(d->vao);
    glBindBuffer(GL_ARRAY_BUFFER, d->vbo);
    glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)(n * sizeof *v), v, GL_STREAM_DRAW);
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_ALWAYS);
    glDepthMask(GL_TRUE);
    glDisable(GL_CULL_FACE);
    glDrawArrays(GL_TRIANGLES, 0, n);
    glBindVertexArray(0);
}

/* ---- tests ------------------------------------------------------------------ */

static void test_gl_errors_table(void **state)
{
    (void)state;
    assert_string_equal(vt_strerror(VT_OK), "ok");
    assert_string_equal(vt_strerror(VT_ERR_NO_DISPLAY), "no EGL display could be initialised");
    assert_string_equal(vt_strerror(12345), "unknown error");
    assert_string_equal(vt_gl_platform_name(VT_GL_SURFACELESS), "surfaceless");
    assert_string_equal(vt_gl_platform_name((vt_gl_platform)77), "?");
    char err[256] = "x";
    assert_int_equal(vt_gl_open(NULL, NULL, err, sizeof err), VT_ERR_INVALID);
    assert_true(err[0] != 0);
    vt_gl *g = (vt_gl *)&g;
    assert_int_equal(vt_gl_open(&g, &(vt_gl_opts){.platform = (vt_gl_platform)9}, err, sizeof err),
                     VT_ERR_INVALID);
    assert_null(g);
    assert_int_equal(vt_gl_open(&g, &(vt_gl_opts){.device = -2}, NULL, 0), VT_ERR_INVALID);
    /* destroy functions take NULL */
    vt_gl_close(NULL);
    vt_gl_release(NULL);
    vt_gl_target_destroy(NULL);
    assert_null(vt_gl_get_info(NULL));
    assert_int_equal(vt_gl_make_current(NULL, NULL, 0), VT_ERR_INVALID);
    assert_int_equal(vt_gl_read_bound(7, 5, true), 140);
    assert_int_equal(vt_gl_read_bound(7, 5, false), 35);
    if (sizeof(size_t) == 8) assert_int_equal(vt_gl_read_bound(UINT32_MAX, UINT32_MAX, true), 0);
}

static void test_gl_open_info(void **state)
{
    (void)state;
    vt_gl *g = open_or_skip(NULL);
    const vt_gl_info *in = vt_gl_get_info(g);
    print_message("GL: %s | %s | %s | GLSL %s | EGL %d.%d %s, platform %s%s%s, clip control %s\n"
                  "    tried: %s\n",
                  in->vendor, in->renderer, in->version, in->glsl_version, in->egl_major,
                  in->egl_minor, in->egl_vendor, vt_gl_platform_name(in->platform),
                  in->software ? " (software)" : "", in->device_file[0] ? in->device_file : "",
                  in->clip_control ? "yes" : "no", in->tried);
    assert_true(in->gl_major > 3 || (in->gl_major == 3 && in->gl_minor >= 3));
    assert_true(in->platform != VT_GL_AUTO);
    assert_true(in->vendor[0] && in->renderer[0] && in->version[0] && in->tried[0]);
    assert_true(in->max_texture_size >= 1024); /* GL 3.3's minimum */
    assert_true(in->max_target_size >= 1024 && in->max_target_size <= in->max_texture_size);
    assert_true(in->device_index == -1 || in->platform == VT_GL_DEVICE);
    /* the context is current here and really is core 3.3+ */
    GLint mask = 0, major = 0;
    glGetIntegerv(GL_CONTEXT_PROFILE_MASK, &mask);
    glGetIntegerv(GL_MAJOR_VERSION, &major);
    assert_true(mask & GL_CONTEXT_CORE_PROFILE_BIT);
    assert_int_equal(major, in->gl_major);
    assert_int_equal(glGetError(), GL_NO_ERROR);
    assert_int_equal(vt_gl_make_current(g, NULL, 0), 0); /* already current */
    vt_gl_close(g);
}

/* opts.debug asks for a debug context; the driver may refuse (then the
 * open fails like any other), Mesa grants it. */
static void test_gl_debug_context(void **state)
{
    (void)state;
    vt_gl *g = open_or_skip(&(vt_gl_opts){.debug = true});
    GLint flags = 0;
    glGetIntegerv(GL_CONTEXT_FLAGS, &flags);
    print_message("debug context: GL_CONTEXT_FLAGS 0x%x\n", (unsigned)flags);
    assert_true(flags & GL_CONTEXT_FLAG_DEBUG_BIT);
    vt_gl_close(g);
}

/* Each platform alone: it works and says so, or fails with a code and a
 * message that names it. No skip: failing is a valid outcome here. */
static void test_gl_each_platform(void **state)
{
    (void)state;
    const vt_gl_platform ps[] = {VT_GL_SURFACELESS, VT_GL_DEVICE, VT_GL_DEFAULT_DISPLAY};
    for (size_t i = 0; i < sizeof ps / sizeof ps[0]; i++) {
        vt_gl *g = NULL;
        char err[1024];
        int rc = vt_gl_open(&g, &(vt_gl_opts){.platform = ps[i]}, err, sizeof err);
        if (rc == 0) {
            const vt_gl_info *in = vt_gl_get_info(g);
            print_message("%s: %s (%s)\n", vt_gl_platform_name(ps[i]), in->renderer, in->tried);
            assert_int_equal(in->platform, ps[i]);
            assert_true(ps[i] == VT_GL_DEVICE ? in->device_index >= 0 : in->device_index == -1);
            vt_gl_close(g);
        } else {
            print_message("%s: %d %s\n", vt_gl_platform_name(ps[i]), rc, err);
            assert_true(rc == VT_ERR_NO_DISPLAY || rc == VT_ERR_NO_CONTEXT);
            assert_null(g);
            const char *name = ps[i] == VT_GL_DEVICE ? "device" : vt_gl_platform_name(ps[i]);
            assert_non_null(strstr(err, name));
        }
    }
    /* a device index beyond the list fails, naming the count */
    vt_gl *g = NULL;
    char err[1024];
    int rc = vt_gl_open(&g, &(vt_gl_opts){.platform = VT_GL_DEVICE, .device = VT_GL_DEVICE_INDEX(999)},
                        err, sizeof err);
    assert_true(rc == VT_ERR_NO_DISPLAY || rc == VT_ERR_NO_CONTEXT);
    assert_null(g);
    print_message("device 999: %s\n", err);
}

/* A clear reads back bit for bit: both formats, both paths, the whole
 * target and a sub-region; depth too. */
static void test_gl_clear_exact(void **state)
{
    (void)state;
    vt_gl *g = open_or_skip(NULL);
    enum { W = 37, H = 23 };
    /* each exactly a half, so RGBA16F must return it too */
    const float c[4] = {0.25f, -1.5f, 1000.0f, 0.0009765625f};
    const float z = 0.75f;
    float *rgba = malloc(4 * W * H * sizeof *rgba), *depth = malloc(W * H * sizeof *depth);
    assert_true(rgba && depth);
    for (int f = 0; f < 2; f++) {
        vt_gl_target *t = make_target(g, W, H, f ? VT_GL_RGBA32F : VT_GL_RGBA16F);
        uint32_t tw, th;
        vt_gl_target_size(t, &tw, &th);
        assert_int_equal(tw, W);
        assert_int_equal(th, H);
        assert_true(vt_gl_target_fbo(t) && vt_gl_target_color_texture(t) && vt_gl_target_depth_texture(t));
        assert_int_equal(vt_gl_target_clear(t, c, z), 0);
        for (int path = VT_GL_READ_AUTO; path <= VT_GL_READ_PBO; path++) {
            memset(rgba, 0xff, 4 * W * H * sizeof *rgba);
            memset(depth, 0xff, W * H * sizeof *depth);
            read_ok(t, rgba, depth, &(vt_gl_read_desc){.path = (vt_gl_read_path)path});
            for (int i = 0; i < W * H; i++) {
                for (int k = 0; k < 4; k++) assert_true(same_float(rgba[4 * i + k], c[k]));
                assert_true(same_float(depth[i], z));
            }
            /* a region, colour only, then depth only: nothing beyond it written */
            memset(rgba, 0, 4 * W * H * sizeof *rgba);
            memset(depth, 0, W * H * sizeof *depth);
            vt_gl_read_desc r = {.x = 3, .y = 5, .w = 11, .h = 7, .path = (vt_gl_read_path)path};
            read_ok(t, rgba, NULL, &r);
            read_ok(t, NULL, depth, &r);
            for (int i = 0; i < W * H; i++) {
                bool in = i < 11 * 7;
                for (int k = 0; k < 4; k++) assert_true(same_float(rgba[4 * i + k], in ? c[k] : 0.0f));
                assert_true(same_float(depth[i], in ? z : 0.0f));
            }
        }
        /* depth clamps to [0,1]; NaN leaves depth, NULL leaves colour */
        assert_int_equal(vt_gl_target_clear(t, NULL, 7.0f), 0);
        read_ok(t, rgba, depth, NULL);
        assert_true(same_float(depth[0], 1.0f) && same_float(rgba[2], c[2]));
        const float c2[4] = {1, 2, 3, 4};
        assert_int_equal(vt_gl_target_clear(t, c2, NAN), 0);
        read_ok(t, rgba, depth, NULL);
        assert_true(same_float(depth[W * H - 1], 1.0f) && same_float(rgba[4 * W * H - 1], 4.0f));
        vt_gl_target_destroy(t);
    }
    free(rgba);
    free(depth);
    vt_gl_close(g);
}

/* Rows come back bottom-up: a scissored clear of the lowest rows and
 * leftmost columns shows at the start of each of the first rows. */
static void test_gl_rows_bottom_up(void **state)
{
    (void)state;
    vt_gl *g = open_or_skip(NULL);
    enum { W = 16, H = 12 };
    vt_gl_target *t = make_target(g, W, H, VT_GL_RGBA32F);
    const float zero[4] = {0, 0, 0, 0}, one[4] = {1, 1, 1, 1};
    assert_int_equal(vt_gl_target_clear(t, zero, 1.0f), 0);
    glEnable(GL_SCISSOR_TEST);
    glScissor(0, 0, 5, 3); /* x < 5, y < 3 from the lower left */
    assert_int_equal(vt_gl_target_clear(t, one, 0.0f), 0);
    glDisable(GL_SCISSOR_TEST);
    float rgba[4 * W * H], depth[W * H];
    read_ok(t, rgba, depth, NULL);
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            bool in = x < 5 && y < 3;
            assert_true(same_float(rgba[4 * (y * W + x)], in ? 1.0f : 0.0f));
            assert_true(same_float(depth[y * W + x], in ? 0.0f : 1.0f));
        }
    vt_gl_target_destroy(t);
    vt_gl_close(g);
}

/* Twice the signed area of (a, b, p): > 0 when p is left of a->b. */
static double edge(double ax, double ay, double bx, double by, double px, double py)
{
    return (bx - ax) * (py - ay) - (by - ay) * (px - ax);
}

/* Random triangles in window space, vertices on the 1/16-pixel grid (no
 * snapping moves them: GL guarantees at least 4 subpixel bits), w a power
 * of two so clip = ndc * w is exact; draw each, read back, and judge every
 * pixel centre farther than MARGIN px from all three edge lines.
 *
 * Depth must be within 1e-6 of the exact plane, except on slivers and
 * steep planes. A rasterizer sets the plane up in float (gradients from
 * cross products of the edges, which cancel on a sliver) and evaluates it
 * as z0 + dz/dx x + dz/dy y from the framebuffer's or a tile's origin
 * (terms up to G = |dz/dx| W + |dz/dy| H). A triangle whose height is
 * under 1/20 of its longest edge, or with G > 8, about one in eight here,
 * gets 1e-5. llvmpipe (Mesa 22.3) over 18,000 triangles: 6.4e-7 at worst
 * on the others, 4.9e-6 on these. */
static void check_triangles(vt_gl *g, bool zero_to_one)
{
    enum { W = 80, H = 56 };
    const double MARGIN = 0.01;
    char err[1024];
    drawer d;
    int rc = drawer_init(g, &d, err, sizeof err);
    if (rc) print_message("drawer: %s\n", err);
    assert_int_equal(rc, 0);
    vt_gl_target *t = make_target(g, W, H, VT_GL_RGBA32F);
    float *rgba = malloc(4 * W * H * sizeof *rgba), *depth = malloc(W * H * sizeof *depth);
    assert_true(rgba && depth);
    const float clear[4] = {0, 0, 0, 0}, color[4] = {0.5f, 0.25f, 1.0f, 1.0f};
    rng r = {test_seed() ^ (zero_to_one ? 0x21u : 0x12u)};
    int ntri = (int)(60 * test_scale());
    long judged = 0, covered = 0, total = 0;
    int slivers = 0;
    double worst = 0, worst_sliver = 0;
    for (int n = 0; n < ntri; n++) {
        double X[3], Y[3], Z[3], area2;
        do {
            for (int k = 0; k < 3; k++) {
                X[k] = rng_below(&r, W * 16 + 1) / 16.0;
                Y[k] = rng_below(&r, H * 16 + 1) / 16.0;
                Z[k] = (51 + rng_below(&r, 923)) / 1024.0; /* window depth in (0.05, 0.95) */
            }
            area2 = edge(X[0], Y[0], X[1], Y[1], X[2], Y[2]);
        } while (fabs(area2) < 40); /* 20 px^2 */
        double gx = 0, gy = 0, longest = 0; /* dz/dx, dz/dy, longest edge */
        for (int k = 0; k < 3; k++) {
            int a = (k + 1) % 3, b = (k + 2) % 3;
            gx -= Z[k] * (Y[b] - Y[a]) / area2;
            gy += Z[k] * (X[b] - X[a]) / area2;
            longest = fmax(longest, hypot(X[b] - X[a], Y[b] - Y[a]));
        }
        bool sliver = fabs(area2) / longest < longest / 20 || fabs(gx) * W + fabs(gy) * H > 8;
        const double ztol = sliver ? 1e-5 : 1e-6;
        slivers += sliver;
        vtx v[3];
        for (int k = 0; k < 3; k++) {
            double w = ldexp(1.0, (int)rng_below(&r, 4) - 1); /* 0.5, 1, 2, 4 */
            double zn = zero_to_one ? Z[k] : 2 * Z[k] - 1;
            v[k] = (vtx){(float)((2 * X[k] / W - 1) * w), (float)((2 * Y[k] / H - 1) * w),
                         (float)(zn * w), (float)w};
        }
        assert_int_equal(vt_gl_target_clear(t, clear, 1.0f), 0);
        drawer_draw(&d, v, 3, color);
        assert_int_equal(glGetError(), GL_NO_ERROR);
        read_ok(t, rgba, depth, NULL);
        for (int y = 0; y < H; y++)
            for (int x = 0; x < W; x++) {
                double px = x + 0.5, py = y + 0.5;
                double e[3] = {edge(X[1], Y[1], X[2], Y[2], px, py),  /* opposite vertex 0 */
                               edge(X[2], Y[2], X[0], Y[0], px, py),  /* opposite 1 */
                               edge(X[0], Y[0], X[1], Y[1], px, py)}; /* opposite 2 */
                bool inside = true, near = false;
                for (int k = 0; k < 3; k++) {
                    int a = (k + 1) % 3, b = (k + 2) % 3;
                    double len = hypot(X[b] - X[a], Y[b] - Y[a]);
                    if (fabs(e[k]) < MARGIN * len) near = true;
                    if (e[k] * area2 <= 0) inside = false;
                }
                total++;
                if (near) continue;
                judged++;
                const float *c = &rgba[4 * (y * W + x)];
                float z = depth[y * W + x];
                if (inside) {
                    covered++;
                    double zref = (e[0] * Z[0] + e[1] * Z[1] + e[2] * Z[2]) / area2;
                    double dz = fabs(z - zref);
                    if (sliver) worst_sliver = fmax(worst_sliver, dz);
                    else worst = fmax(worst, dz);
                    if (!same_float(c[0], color[0]) || dz > ztol)
                        fail_msg("triangle %d (%g,%g) (%g,%g) (%g,%g): pixel (%d,%d) inside: "
                                 "colour %g, depth %.9f, want %.9f (tolerance %.3g)",
                                 n, X[0], Y[0], X[1], Y[1], X[2], Y[2], x, y, (double)c[0], (double)z,
                                 zref, ztol);
                } else if (!same_float(c[0], 0.0f) || !same_float(z, 1.0f)) {
                    fail_msg("triangle %d (%g,%g) (%g,%g) (%g,%g): pixel (%d,%d) outside: "
                             "colour %g, depth %g",
                             n, X[0], Y[0], X[1], Y[1], X[2], Y[2], x, y, (double)c[0], (double)z);
                }
            }
    }
    print_message("%s depth: %d triangles, %ld of %ld pixel centres judged, %ld covered; "
                  "worst depth error %.2g (%d slivers or steep: %.2g)\n",
                  zero_to_one ? "[0,1]" : "[-1,1]", ntri, judged, total, covered, worst, slivers,
                  worst_sliver);
    assert_true(covered > ntri * 10);
    assert_true(judged > total * 9 / 10);
    free(rgba);
    free(depth);
    vt_gl_target_destroy(t);
    drawer_free(&d);
}

static void test_gl_triangle_coverage_depth(void **state)
{
    (void)state;
    vt_gl *g = open_or_skip(NULL);
    check_triangles(g, false);
    char err[256];
    if (vt_gl_get_info(g)->clip_control) {
        assert_int_equal(vt_gl_clip_control(g, true, err, sizeof err), 0);
        check_triangles(g, true);
        assert_int_equal(vt_gl_clip_control(g, false, err, sizeof err), 0);
        check_triangles(g, false);
    } else {
        print_message("no glClipControl (%s): [0,1] depth not tested\n", vt_gl_get_info(g)->version);
        assert_int_equal(vt_gl_clip_control(g, true, err, sizeof err), VT_ERR_UNSUPPORTED);
    }
    vt_gl_close(g);
}

/* The two halves either side of v (equal when v is a half); |v| < 65504. */
static void half_bracket(double v, double *lo, double *hi)
{
    double a = fabs(v);
    int e = a > 0 ? ilogb(a) : -14;
    if (e < -14) e = -14; /* subnormal halves: spacing 2^-24 */
    double ulp = ldexp(1.0, e - 10);
    double l = floor(a / ulp) * ulp, h = l == a ? l : l + ulp;
    *lo = v < 0 ? -h : l;
    *hi = v < 0 ? -l : h;
}

static const char *const COPY_VS =
    "#version 330 core\n"
    "void main() {\n"
    "    vec2 p = vec2(gl_VertexID == 1 ? 3.0 : -1.0, gl_VertexID == 2 ? 3.0 : -1.0);\n"
    "    gl_Position = vec4(p, 0.0, 1.0);\n"
    "}\n";

static const char *const COPY_FS =
    "#version 330 core\n"
    "uniform sampler2D src;\n"
    "out vec4 o;\n"
    "void main() { o = texelFetch(src, ivec2(gl_FragCoord.xy), 0); }\n";

/* Random floats through an RGBA32F texture and a full-screen triangle
 * into the target: RGBA32F keeps them, RGBA16F rounds each to a
 * neighbouring half (halves themselves come back unchanged). */
static void test_gl_float_roundtrip(void **state)
{
    (void)state;
    vt_gl *g = open_or_skip(NULL);
    enum { W = 64, H = 48, N = 4 * W * H };
    char err[1024];
    unsigned prog;
    int rc = vt_gl_program_build(g, COPY_VS, COPY_FS, &prog, err, sizeof err);
    if (rc) print_message("%s\n", err);
    assert_int_equal(rc, 0);
    float *src = malloc(N * sizeof *src), *out = malloc(N * sizeof *out);
    assert_true(src && out);
    rng r = {test_seed() ^ 0xF10A7};
    for (int f = 0; f < 2; f++) {
        for (int i = 0; i < N; i++) {
            double m = f ? rng_log(&r, 1e-30, 1e30) : rng_log(&r, 1e-7, 6e4);
            if (rng_below(&r, 8) == 0) m = f ? 0 : ldexp(1 + rng_below(&r, 1024), -10 - (int)rng_below(&r, 20));
            src[i] = (float)(rng_below(&r, 2) ? m : -m);
        }
        GLuint tex, vao;
        glGenTextures(1, &tex);
        glBindTexture(GL_TEXTURE_2D, tex);
        glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA32F, W, H, 0, GL_RGBA, GL_FLOAT, src);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
        glGenVertexArrays(1, &vao);
        vt_gl_target *t = make_target(g, W, H, f ? VT_GL_RGBA32F : VT_GL_RGBA16F);
        assert_int_equal(vt_gl_target_bind(t), 0);
        glDisable(GL_DEPTH_TEST);
        glUseProgram(prog);
        glUniform1i(glGetUniformLocation(prog, "src"), 0);
        glBindVertexArray(vao);
        glDrawArrays(GL_TRIANGLES, 0, 3);
        assert_int_equal(glGetError(), GL_NO_ERROR);
        read_ok(t, out, NULL, NULL);
        int nearest = 0, to_zero = 0;
        for (int i = 0; i < N; i++) {
            if (f) {
                if (!same_float(out[i], src[i]))
                    fail_msg("RGBA32F [%d]: %a came back as %a", i, (double)src[i], (double)out[i]);
                continue;
            }
            double lo, hi;
            half_bracket(src[i], &lo, &hi);
            if (out[i] != lo && out[i] != hi)
                fail_msg("RGBA16F [%d]: %a came back as %a, not %a or %a", i, (double)src[i],
                         (double)out[i], lo, hi);
            double dl = fabs(src[i] - lo), dh = fabs(hi - src[i]);
            nearest += (out[i] == lo) ? dl <= dh : dh <= dl;
            to_zero += fabs(out[i]) <= fabs(src[i]);
        }
        if (!f)
            print_message("RGBA16F: of %d floats, %d went to the nearest half, %d toward zero\n", N,
                          nearest, to_zero);
        vt_gl_target_destroy(t);
        glDeleteVertexArrays(1, &vao);
        glDeleteTextures(1, &tex);
    }
    glDeleteProgram(prog);
    free(src);
    free(out);
    vt_gl_close(g);
}

static void test_gl_shader_errors(void **state)
{
    (void)state;
    vt_gl *g = open_or_skip(NULL);
    char err[2048];
    unsigned s = 77, p = 77;
    int rc = vt_gl_shader_compile(g, GL_VERTEX_SHADER, "#version 330 core\nvoid main() { nonsense; }\n",
                                  &s, err, sizeof err);
    print_message("compile: %s\n", err);
    assert_int_equal(rc, VT_ERR_COMPILE);
    assert_int_equal(s, 0);
    assert_int_equal(strncmp(err, "vertex shader: ", 15), 0);
    assert_true(strlen(err) > 20); /* the driver's log follows */
    /* a log longer than the buffer is cut, NUL-terminated */
    char tiny[24];
    rc = vt_gl_shader_compile(g, GL_FRAGMENT_SHADER, "#version 330 core\nvoid main() { x = 1; }\n",
                              &s, tiny, sizeof tiny);
    assert_int_equal(rc, VT_ERR_COMPILE);
    assert_true(strlen(tiny) < sizeof tiny);
    /* one uniform of two types in two stages does not link */
    rc = vt_gl_program_build(g,
                             "#version 330 core\nuniform float u;\nvoid main() { gl_Position = vec4(u); }\n",
                             "#version 330 core\nuniform vec2 u;\nout vec4 o;\nvoid main() { o = u.xyxy; }\n",
                             &p, err, sizeof err);
    print_message("link: %s\n", err);
    assert_int_equal(rc, VT_ERR_LINK);
    assert_int_equal(p, 0);
    assert_int_equal(strncmp(err, "link: ", 6), 0);
    assert_int_equal(vt_gl_shader_compile(g, 0x1234, "", &s, err, sizeof err), VT_ERR_INVALID);
    assert_int_equal(vt_gl_program_build(g, TRI_VS, TRI_FS, &p, err, sizeof err), 0);
    assert_string_equal(err, "");
    assert_true(glIsProgram(p));
    glDeleteProgram(p);
    assert_int_equal(glGetError(), GL_NO_ERROR);
    vt_gl_close(g);
}

static void test_gl_target_errors(void **state)
{
    (void)state;
    vt_gl *g = open_or_skip(NULL);
    char err[512];
    vt_gl_target *t = NULL;
    const vt_gl_info *in = vt_gl_get_info(g);
    uint32_t big = (uint32_t)in->max_target_size + 1;
    assert_int_equal(vt_gl_target_create(g, 0, 5, NULL, &t, err, sizeof err), VT_ERR_RANGE);
    assert_int_equal(vt_gl_target_create(g, big, 5, NULL, &t, err, sizeof err), VT_ERR_RANGE);
    assert_int_equal(vt_gl_target_create(g, 5, 5, &(vt_gl_target_desc){.color = 7}, &t, err, sizeof err),
                     VT_ERR_INVALID);
    assert_null(t);
    t = make_target(g, 32, 16, VT_GL_RGBA16F);
    float buf[4 * 50 * 70], zb[50 * 70];
    assert_int_equal(vt_gl_readback(t, NULL, NULL, NULL, err, sizeof err), VT_ERR_INVALID);
    assert_int_equal(vt_gl_readback(t, buf, NULL, &(vt_gl_read_desc){.x = 30, .w = 3, .h = 1}, err, sizeof err),
                     VT_ERR_RANGE);
    assert_int_equal(vt_gl_readback(t, buf, NULL, &(vt_gl_read_desc){.y = UINT32_MAX, .w = 1, .h = 2}, err,
                                    sizeof err),
                     VT_ERR_RANGE);
    assert_int_equal(vt_gl_readback(t, buf, NULL, &(vt_gl_read_desc){.w = 1}, err, sizeof err), VT_ERR_RANGE);
    /* resize: a bad size keeps the old one; a good one takes */
    assert_int_equal(vt_gl_target_resize(t, big, 2, err, sizeof err), VT_ERR_RANGE);
    uint32_t w, h;
    vt_gl_target_size(t, &w, &h);
    assert_true(w == 32 && h == 16);
    assert_int_equal(vt_gl_target_resize(t, 50, 70, err, sizeof err), 0);
    vt_gl_target_size(t, &w, &h);
    assert_true(w == 50 && h == 70);
    const float c[4] = {2, 4, 8, 16};
    assert_int_equal(vt_gl_target_clear(t, c, 0.5f), 0);
    for (int path = VT_GL_READ_DIRECT; path <= VT_GL_READ_PBO; path++) {
        read_ok(t, buf, zb, &(vt_gl_read_desc){.path = (vt_gl_read_path)path});
        assert_true(same_float(buf[4 * 50 * 70 - 1], 16.0f) && same_float(zb[50 * 70 - 1], 0.5f));
    }
    /* not current: every call that needs GL says so */
    vt_gl_release(g);
    assert_int_equal(vt_gl_readback(t, buf, NULL, NULL, err, sizeof err), VT_ERR_CURRENT);
    assert_non_null(strstr(err, "not current"));
    assert_int_equal(vt_gl_target_bind(t), VT_ERR_CURRENT);
    assert_int_equal(vt_gl_target_resize(t, 8, 8, err, sizeof err), VT_ERR_CURRENT);
    unsigned s;
    assert_int_equal(vt_gl_shader_compile(g, GL_VERTEX_SHADER, TRI_VS, &s, err, sizeof err), VT_ERR_CURRENT);
    assert_int_equal(vt_gl_make_current(g, err, sizeof err), 0);
    /* a second target left alive: close frees it */
    make_target(g, 8, 8, VT_GL_RGBA32F);
    vt_gl_target_destroy(t);
    vt_gl_close(g);
}

/* ---- threads ------------------------------------------------------------------ */

typedef struct gl_thread {
    pthread_barrier_t *bar;
    int                id;
    bool               close_early; /* closes while the other still renders */
    int                failures;
    char               msg[512];
} gl_thread;

#if defined(__GNUC__)
__attribute__((format(printf, 2, 3)))
#endif
static void thread_fail(gl_thread *a, const char *fmt, ...)
{
    if (!a->failures++) {
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(a->msg, sizeof a->msg, fmt, ap);
        va_end(ap);
    }
}

/* Clears, draws a triangle over the left half in this thread's colour,
 * reads back and checks a pixel on each side. */
static void thread_round(gl_thread *a, vt_gl_target *t, const drawer *d, int round)
{
    enum { W = 64, H = 64 };
    static const float clear[4] = {0, 0, 0, 0};
    const float col[4] = {(float)a->id + 1, (float)round, 0.5f, 1};
    /* left half: x_ndc in [-1, 0] */
    const vtx v[6] = {{-1, -1, 0, 1}, {0, -1, 0, 1}, {0, 1, 0, 1},
                      {-1, -1, 0, 1}, {0, 1, 0, 1},  {-1, 1, 0, 1}};
    float *rgba = malloc(4 * W * H * sizeof *rgba);
    char err[512];
    if (!rgba) { thread_fail(a, "malloc"); return; }
    if (vt_gl_target_clear(t, clear, 1.0f)) thread_fail(a, "clear");
    drawer_draw(d, v, 6, col);
    if (vt_gl_readback(t, rgba, NULL, NULL, err, sizeof err)) thread_fail(a, "readback: %s", err);
    const float *l = &rgba[4 * (10 * W + 5)], *r = &rgba[4 * (50 * W + 60)];
    if (l[0] != col[0] || l[1] != col[1] || r[0] != 0 || r[3] != 0)
        thread_fail(a, "thread %d round %d: left (%g,%g) right (%g,%g)", a->id, round,
                    (double)l[0], (double)l[1], (double)r[0], (double)r[3]);
    free(rgba);
}

static void *gl_thread_main(void *p)
{
    gl_thread *a = p;
    char err[1024];
    vt_gl *g = NULL;
    vt_gl_target *t = NULL;
    drawer d;
    int rc = vt_gl_open(&g, NULL, err, sizeof err);
    if (rc) thread_fail(a, "open: %s", err);
    else if ((rc = drawer_init(g, &d, err, sizeof err))) thread_fail(a, "drawer: %s", err);
    else if ((rc = vt_gl_target_create(g, 64, 64, &(vt_gl_target_desc){.color = VT_GL_RGBA32F}, &t,
                                       err, sizeof err)))
        thread_fail(a, "target: %s", err);
    pthread_barrier_wait(a->bar); /* both open */
    for (int i = 0; !rc && i < 20; i++) thread_round(a, t, &d, i);
    pthread_barrier_wait(a->bar); /* both have rendered */
    if (a->close_early && g) {
        if (!rc) drawer_free(&d);
        vt_gl_close(g);
        g = NULL;
    }
    pthread_barrier_wait(a->bar); /* the early one has closed */
    if (g) {
        for (int i = 0; !rc && i < 20; i++) thread_round(a, t, &d, 100 + i);
        if (!rc) drawer_free(&d);
        vt_gl_close(g);
    }
    return NULL;
}

static void test_gl_two_threads(void **state)
{
    (void)state;
    vt_gl_close(open_or_skip(NULL)); /* skip here, not in a thread */
    pthread_barrier_t bar;
    assert_int_equal(pthread_barrier_init(&bar, NULL, 2), 0);
    gl_thread a[2] = {{.bar = &bar, .id = 0, .close_early = true}, {.bar = &bar, .id = 1}};
    pthread_t th[2];
    for (int i = 0; i < 2; i++) assert_int_equal(pthread_create(&th[i], NULL, gl_thread_main, &a[i]), 0);
    for (int i = 0; i < 2; i++) {
        assert_int_equal(pthread_join(th[i], NULL), 0);
        if (a[i].failures) fail_msg("thread %d: %d failures, first: %s", i, a[i].failures, a[i].msg);
    }
    pthread_barrier_destroy(&bar);
}

typedef struct mover {
    vt_gl        *g;
    vt_gl_target *t;
    int           rc_take, rc_clear;
    char          err[512];
} mover;

static void *mover_main(void *p)
{
    mover *m = p;
    m->rc_take = vt_gl_make_current(m->g, m->err, sizeof m->err);
    if (m->rc_take) return NULL;
    const float c[4] = {3, 5, 7, 9};
    m->rc_clear = vt_gl_target_clear(m->t, c, 0.25f);
    vt_gl_release(m->g);
    return NULL;
}

/* The documented handover: release here, take there, release there, take
 * back here; taking a context current elsewhere is VT_ERR_CURRENT. */
static void test_gl_move_between_threads(void **state)
{
    (void)state;
    vt_gl *g = open_or_skip(NULL);
    vt_gl_target *t = make_target(g, 16, 16, VT_GL_RGBA16F);
    mover m = {.g = g, .t = t};
    pthread_t th;
    /* still current here: the other thread is refused */
    assert_int_equal(pthread_create(&th, NULL, mover_main, &m), 0);
    assert_int_equal(pthread_join(th, NULL), 0);
    print_message("while current elsewhere: %s\n", m.err);
    assert_int_equal(m.rc_take, VT_ERR_CURRENT);
    vt_gl_release(g);
    memset(&m, 0, sizeof m);
    m.g = g;
    m.t = t;
    assert_int_equal(pthread_create(&th, NULL, mover_main, &m), 0);
    assert_int_equal(pthread_join(th, NULL), 0);
    assert_int_equal(m.rc_take, 0);
    assert_int_equal(m.rc_clear, 0);
    char err[512];
    assert_int_equal(vt_gl_make_current(g, err, sizeof err), 0);
    float rgba[4 * 16 * 16], depth[16 * 16];
    read_ok(t, rgba, depth, NULL);
    assert_true(same_float(rgba[0], 3.0f) && same_float(rgba[4 * 256 - 1], 9.0f));
    assert_true(same_float(depth[255], 0.25f));
    vt_gl_close(g); /* frees t */
}

/* Open, render, close, again; two open at once on one display, closed in
 * either order. ASan's leak check runs over all of it. */
static void test_gl_reopen(void **state)
{
    (void)state;
    vt_gl_close(open_or_skip(NULL));
    for (int i = 0; i < 4; i++) {
        vt_gl *g = open_or_skip(NULL);
        vt_gl_target *t = make_target(g, 8, 8, VT_GL_RGBA32F);
        const float c[4] = {(float)i, 1, 2, 3};
        assert_int_equal(vt_gl_target_clear(t, c, 0.5f), 0);
        float rgba[4 * 64];
        read_ok(t, rgba, NULL, &(vt_gl_read_desc){.path = VT_GL_READ_PBO});
        assert_true(same_float(rgba[4 * 63], (float)i));
        vt_gl_target_destroy(t);
        vt_gl_close(g);
    }
    for (int order = 0; order < 2; order++) {
        vt_gl *a = open_or_skip(NULL), *b = open_or_skip(NULL); /* b is current */
        char err[256];
        vt_gl *first = order ? b : a, *second = order ? a : b;
        vt_gl_close(first);
        assert_int_equal(vt_gl_make_current(second, err, sizeof err), 0);
        vt_gl_target *t = make_target(second, 4, 4, VT_GL_RGBA16F);
        const float c[4] = {1, 2, 3, 4};
        assert_int_equal(vt_gl_target_clear(t, c, 0.5f), 0);
        float rgba[4 * 16];
        read_ok(t, rgba, NULL, NULL);
        assert_true(same_float(rgba[3], 4.0f));
        vt_gl_close(second);
    }
}

const struct CMUnitTest gl_tests[] = {
    cmocka_unit_test(test_gl_errors_table),
    cmocka_unit_test(test_gl_open_info),
    cmocka_unit_test(test_gl_each_platform),
    cmocka_unit_test(test_gl_debug_context),
    cmocka_unit_test(test_gl_clear_exact),
    cmocka_unit_test(test_gl_rows_bottom_up),
    cmocka_unit_test(test_gl_triangle_coverage_depth),
    cmocka_unit_test(test_gl_float_roundtrip),
    cmocka_unit_test(test_gl_shader_errors),
    cmocka_unit_test(test_gl_target_errors),
    cmocka_unit_test(test_gl_two_threads),
    cmocka_unit_test(test_gl_move_between_threads),
    cmocka_unit_test(test_gl_reopen),
};
const size_t gl_tests_count = sizeof gl_tests / sizeof gl_tests[0];

#else
typedef int vt_test_gl_not_built; /* render/ or libepoxy's headers not on the include path */
#endif
