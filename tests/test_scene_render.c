/*
 * test_scene_render.c — both renderers on the scene model (issue 19)
 * against independent models:
 *   - a textured quad placed by a transform, each pixel against the
 *     texture evaluated directly at the UV of the pixel centre's ray hit
 *     (double; nearest and bilinear with wrap modes and sRGB, a mip level
 *     from the UV's finite differences; the holes of an alpha mask; a
 *     back face drawn double-sided and culled one-sided);
 *   - rotated, scaled and mirrored open meshes against the ray caster of
 *     tests/occ_ref.c on the triangles transformed here (quaternion
 *     rotation written out, a mirrored triangle's winding turned);
 *   - the sky, the ground and fog at chosen pixels against their closed
 *     forms; the default environment's exposure;
 *   - the software and GL renderers on the same textured, transformed
 *     scenes with sky, ground and fog (llvmpipe here), with the tolerances
 *     of test_soft_and_gl_agree;
 *   - bad transforms, materials, textures and environments: refused by
 *     both with VT_ERR_INVALID.
 * VANTAGE_SCENE_PNG=DIR writes the rendered pictures there as PNG.
 */
#include "test_util.h"

#include "frame_scene.h"
#include "occ_ref.h"
#include "test_daemon.h"
#include "vantage.h"
#include "vt_gldraw.h"
#include "vt_image.h"
#include "vt_shade.h"
#include "vt_soft.h"

#include <stdio.h>
#include <string.h>

/* A perspective view from eye towards at, w x h, vertical fov (rad). */
static void look(cull_view *v, const double eye[3], const double at[3], uint32_t w, uint32_t h, double fov, int mode)
{
    cull_view_desc d = {.depth_mode = (uint32_t)mode, .viewport_w = w, .viewport_h = h};
    memcpy(d.origin, eye, sizeof d.origin);
    double proj[16], view[16], dir[3] = {at[0] - eye[0], at[1] - eye[1], at[2] - eye[2]}, up[3] = {0, 1, 0};
    cull_mat_perspective(proj, fov, (double)w / h, 0.1, 5000, (uint32_t)mode);
    cull_mat_look_dir(view, dir, up);
    cull_mat_mul(d.view_proj, proj, view);
    assert_int_equal(cull_view_init(v, &d), CULL_OK);
}

/* q v q* for a unit quaternion (x, y, z, w), in double. */
static void qrot(const double q[4], const double v[3], double o[3])
{
    double w = q[3], x = q[0], y = q[1], z = q[2];
    /* p = q (0, v) */
    double pw = -x * v[0] - y * v[1] - z * v[2];
    double px = w * v[0] + y * v[2] - z * v[1];
    double py = w * v[1] + z * v[0] - x * v[2];
    double pz = w * v[2] + x * v[1] - y * v[0];
    /* o = p q* */
    o[0] = -pw * x + px * w - py * z + pz * y;
    o[1] = -pw * y + py * w - pz * x + px * z;
    o[2] = -pw * z + pz * w - px * y + py * x;
}

static void axis_angle(double ax, double ay, double az, double ang, float q[4])
{
    double l = sqrt(ax * ax + ay * ay + az * az), s = sin(ang / 2) / l;
    q[0] = (float)(ax * s);
    q[1] = (float)(ay * s);
    q[2] = (float)(az * s);
    q[3] = (float)cos(ang / 2);
}

static double srgb_dec(uint8_t c)
{
    double x = c / 255.0;
    return x <= 0.04045 ? x / 12.92 : pow((x + 0.055) / 1.055, 2.4);
}

static int32_t wrap_ref(int64_t i, int32_t n, int mode)
{
    if (mode == VT_WRAP_CLAMP) return (int32_t)(i < 0 ? 0 : i >= n ? n - 1 : i);
    int64_t m = mode == VT_WRAP_MIRROR ? 2 * (int64_t)n : n, p = ((i % m) + m) % m;
    return (int32_t)(p < n ? p : 2 * n - 1 - p);
}

/* A texture of random RGBA8 texels with a box-filtered mip chain. */
typedef struct tex_own {
    vt_texview t;
    uint8_t *lv[16];
} tex_own;

static void tex_make(tex_own *o, rng *r, uint32_t w, uint32_t h, uint32_t levels, uint32_t id)
{
    memset(o, 0, sizeof *o);
    o->t = (vt_texview){.w = w, .h = h, .levels = levels, .mip = (const uint8_t *const *)o->lv, .id = id, .gen = 1};
    for (uint32_t k = 0; k < levels; k++) {
        uint32_t lw = w >> k ? w >> k : 1, lh = h >> k ? h >> k : 1;
        o->lv[k] = malloc((size_t)lw * lh * 4);
        assert_non_null(o->lv[k]);
        for (size_t i = 0; i < (size_t)lw * lh * 4; i++) o->lv[k][i] = (uint8_t)rng_below(r, 256);
    }
}

static void tex_free(tex_own *o)
{
    for (int k = 0; k < 16; k++) free(o->lv[k]);
}

/* Texel (x, y) of level lv, decoded. */
static void texel_ref(const tex_own *o, uint32_t lv, int32_t x, int32_t y, bool srgb, double c[4])
{
    uint32_t w = o->t.w >> lv ? o->t.w >> lv : 1;
    const uint8_t *p = o->lv[lv] + 4 * ((size_t)y * w + (size_t)x);
    for (int k = 0; k < 3; k++) c[k] = srgb ? srgb_dec(p[k]) : p[k] / 255.0;
    c[3] = p[3] / 255.0;
}

/* The quad [-1, 1]^2 at z = 0 facing +z, UVs 0..3 across, 0..2 up. */
static const float quad_pos[12] = {-1, -1, 0, 1, -1, 0, 1, 1, 0, -1, 1, 0};
static const float quad_nrm[12] = {0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1};
static const float quad_uv[8] = {0, 2, 3, 2, 3, 0, 0, 0};
static const uint32_t quad_idx[6] = {0, 1, 2, 0, 2, 3};

static void maybe_png(const char *name, uint32_t w, uint32_t h, const float *rgba)
{
    const char *dir = getenv("VANTAGE_SCENE_PNG");
    if (!dir || !*dir) return;
    uint8_t *px = malloc((size_t)w * h * 4);
    assert_non_null(px);
    vt_image_src src = {.r = {rgba + (size_t)(h - 1) * w * 4, 4, -(ptrdiff_t)w * 4},
                        .g = {rgba + (size_t)(h - 1) * w * 4 + 1, 4, -(ptrdiff_t)w * 4},
                        .b = {rgba + (size_t)(h - 1) * w * 4 + 2, 4, -(ptrdiff_t)w * 4}};
    vt_tonemap_desc td = {.op = VT_TONEMAP_ACES};
    assert_int_equal(vt_image_tonemap(w, h, &src, &td, px, 4 * (size_t)w), 0);
    char path[512], err[256];
    snprintf(path, sizeof path, "%s/%s.png", dir, name);
    if (vt_png_write(path, w, h, px, 4 * (size_t)w, false, 6, err, sizeof err)) fprintf(stderr, "png: %s\n", err);
    free(px);
}

/* ---- a textured quad against the texture at each pixel's UV ---------------------- */

/* Where the ray of pixel px hits the placed quad: its local (x, y), and
 * the UV there. false: no hit inside (with a margin). */
static bool quad_hit(const occ_ref *ref, size_t px, const double pos[3], const double q[4], const double s[3],
                     const double origin[3], double uv[2])
{
    const double *ray = ref->ray + 6 * px;
    double n[3], zn[3] = {0, 0, 1}, c[3];
    qrot(q, zn, n);
    for (int a = 0; a < 3; a++) c[a] = pos[a] - origin[a];
    double den = n[0] * ray[3] + n[1] * ray[4] + n[2] * ray[5];
    if (fabs(den) < 1e-12) return false;
    double t = (n[0] * (c[0] - ray[0]) + n[1] * (c[1] - ray[1]) + n[2] * (c[2] - ray[2])) / den;
    if (!(t > 0)) return false;
    double hit[3], d[3], l[3], qi[4] = {-q[0], -q[1], -q[2], q[3]};
    for (int a = 0; a < 3; a++) d[a] = ray[a] + t * ray[3 + a] - c[a];
    qrot(qi, d, hit);
    for (int a = 0; a < 2; a++) l[a] = hit[a] / s[a];
    if (fabs(l[0]) > 0.98 || fabs(l[1]) > 0.98) return false;
    uv[0] = (l[0] + 1) * 1.5;
    uv[1] = (1 - l[1]); /* v 2 at the bottom edge, 0 at the top */
    return true;
}

typedef struct quad_case {
    const char *name;
    uint8_t wrap_s, wrap_t, min_f, mag_f;
    uint32_t tw, th, levels;
    double dist;            /* camera distance */
    uint8_t flags;          /* QUAD_* */
} quad_case;
#define QUAD_MASK 1u        /* alpha MASK, cutoff 0.5: texels below it are holes */
#define QUAD_BACK 2u        /* turned by pi about its y: seen from behind */
#define QUAD_TWO 4u         /* a double-sided material */

static void check_quad(const quad_case *qc, vt_gldraw *gr)
{
    rng r = {test_seed() ^ 0x7E57u};
    tex_own to;
    tex_make(&to, &r, qc->tw, qc->th, qc->levels, 0);
    /* mip test: each level one colour, so the level is read off the pixel */
    for (uint32_t k = 1; k < qc->levels; k++) {
        uint32_t lw = qc->tw >> k ? qc->tw >> k : 1, lh = qc->th >> k ? qc->th >> k : 1;
        for (size_t i = 0; i < (size_t)lw * lh; i++) memcpy(to.lv[k] + 4 * i, (uint8_t[4]){(uint8_t)(30 * k), 200, (uint8_t)(255 - 30 * k), 255}, 4);
    }
    if (qc->levels > 1)
        for (size_t i = 0; i < (size_t)qc->tw * qc->th; i++) memcpy(to.lv[0] + 4 * i, (uint8_t[4]){0, 200, 255, 255}, 4);
    vt_material mat = {.base = {1, 1, 1, 1}, .roughness = 1, .normal_scale = 1,
                       .alpha_mode = qc->flags & QUAD_MASK ? VT_ALPHA_MASK : VT_ALPHA_OPAQUE, .alpha_cutoff = 0.5f,
                       .double_sided = (qc->flags & QUAD_TWO) != 0};
    mat.tex[VT_SLOT_BASE] = (vt_texref){.tex = &to.t, .wrap_s = qc->wrap_s, .wrap_t = qc->wrap_t,
                                        .min_filter = qc->min_f, .mag_filter = qc->mag_f, .scale = {1, 1}};
    vt_mesh quad = {.pos = quad_pos, .nrm = quad_nrm, .uv = quad_uv, .idx = quad_idx, .nv = 4, .ni = 6};
    const uint32_t W = 160, H = 120;
    double eye[3] = {0.2, 0.1, 0}, at[3] = {0, 0, -qc->dist};
    double pos[3] = {0.1, -0.15, -qc->dist}, s[3] = {qc->dist * 0.7, qc->dist * 0.45, 1};
    float qf[4];
    axis_angle(0.3, 1, 0.2, qc->levels > 1 ? 1.1 : 0.45, qf);
    if (qc->flags & QUAD_BACK) { /* q (x) (0, 1, 0, 0): a half turn about the quad's own y */
        float a[4] = {qf[0], qf[1], qf[2], qf[3]};
        qf[0] = -a[2], qf[1] = a[3], qf[2] = a[0], qf[3] = -a[1];
    }
    double q[4] = {qf[0], qf[1], qf[2], qf[3]}, ql = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    for (int a = 0; a < 4; a++) q[a] /= ql;
    vt_instance in = {.place = VT_PLACE_TRS, .pos = {pos[0], pos[1], pos[2]}, .rot = {qf[0], qf[1], qf[2], qf[3]},
                      .scale = {(float)s[0], (float)s[1], 1}, .mat = &mat};
    cull_view v;
    look(&v, eye, at, W, H, 1.0, CULL_DEPTH_ZERO_ONE);
    float *rgba = malloc((size_t)W * H * 16), *depth = malloc((size_t)W * H * 4);
    assert_true(rgba && depth);
    occ_ref ref;
    assert_int_equal(occ_ref_init(&ref, &v, W, H), 0);
    for (int which = 0; which < (gr ? 2 : 1); which++) {
        vt_frame f = {.view = &v, .width = W, .height = H, .meshes = &quad, .nmesh = 1, .inst = &in, .ninst = 1,
                      .rgba = rgba, .depth = depth, .stride = W};
        char err[256];
        vt_soft *sr;
        assert_int_equal(vt_soft_create(NULL, 0, &sr), 0);
        int rc = which ? vt_gldraw_draw(gr, &f, NULL, err, sizeof err) : vt_soft_draw(sr, &f, NULL, err, sizeof err);
        vt_soft_destroy(sr);
        if (rc) fprintf(stderr, "%s: %s\n", qc->name, err);
        assert_int_equal(rc, 0);
        uint64_t judged = 0, bad = 0;
        double worst = 0;
        for (uint32_t y = 0; y < H; y++)
            for (uint32_t x = 0; x < W; x++) {
                size_t px = (size_t)y * W + x;
                double uv[2], ux[2], uy[2];
                if (!quad_hit(&ref, px, pos, q, s, v.origin, uv)) continue;
                double want[4] = {0, 0, 0, 0};
                if (qc->levels > 1) {
                    /* the level from the UV's differences one pixel over */
                    if (x + 1 >= W || y + 1 >= H || !quad_hit(&ref, px + 1, pos, q, s, v.origin, ux) ||
                        !quad_hit(&ref, px + W, pos, q, s, v.origin, uy))
                        continue;
                    double lx = hypot((ux[0] - uv[0]) * qc->tw, (ux[1] - uv[1]) * qc->th);
                    double ly = hypot((uy[0] - uv[0]) * qc->tw, (uy[1] - uv[1]) * qc->th);
                    double lod = log2(lx > ly ? lx : ly);
                    /* near a switch of level: not judged */
                    if (fabs(lod - 0.5 - floor(lod - 0.5) - 0.5) > 0.4) continue;
                    int lv = lod <= 0.5 ? 0 : (int)ceil(lod + 0.5) - 1;
                    if (lv > (int)qc->levels - 1) lv = (int)qc->levels - 1;
                    texel_ref(&to, (uint32_t)lv, 0, 0, true, want);
                } else if (qc->mag_f == VT_FILTER_NEAREST) {
                    double fx = uv[0] * qc->tw, fy = uv[1] * qc->th;
                    if (fabs(fx - floor(fx + 0.5)) < 0.02 || fabs(fy - floor(fy + 0.5)) < 0.02) continue;
                    texel_ref(&to, 0, wrap_ref((int64_t)floor(fx), (int32_t)qc->tw, qc->wrap_s),
                              wrap_ref((int64_t)floor(fy), (int32_t)qc->th, qc->wrap_t), true, want);
                } else {
                    double fx = uv[0] * qc->tw - 0.5, fy = uv[1] * qc->th - 0.5, x0 = floor(fx), y0 = floor(fy);
                    double ax = fx - x0, ay = fy - y0, c[4][4];
                    for (int k = 0; k < 4; k++)
                        texel_ref(&to, 0, wrap_ref((int64_t)x0 + (k & 1), (int32_t)qc->tw, qc->wrap_s),
                                  wrap_ref((int64_t)y0 + (k >> 1), (int32_t)qc->th, qc->wrap_t), true, c[k]);
                    for (int k = 0; k < 4; k++)
                        want[k] = (1 - ay) * ((1 - ax) * c[0][k] + ax * c[1][k]) + ay * ((1 - ax) * c[2][k] + ax * c[3][k]);
                }
                judged++;
                /* seen from behind and one-sided, or a hole of the mask: nothing */
                bool hole = ((qc->flags & QUAD_BACK) && !(qc->flags & QUAD_TWO)) ||
                            ((qc->flags & QUAD_MASK) && want[3] < 0.5);
                if (hole || depth[px] == INFINITY) {
                    if (hole != (depth[px] == INFINITY)) {
                        if (bad < 3)
                            fprintf(stderr, "%s (%s) %u,%u: %s, want %s\n", qc->name, which ? "gl" : "soft", x, y,
                                    depth[px] == INFINITY ? "nothing" : "drawn", hole ? "nothing" : "drawn");
                        bad++;
                    }
                    continue;
                }
                /* no environment, no lights: the constant ambient of the base colour */
                for (int k = 0; k < 3; k++) {
                    double got = rgba[4 * px + k], e = fabs(got - 0.03 * want[k]);
                    double tol = qc->mag_f == VT_FILTER_LINEAR && qc->levels == 1 ? 0.03 * 0.01 : 0.03 * 2e-3;
                    if (e > worst) worst = e;
                    if (e > tol) {
                        if (bad < 3)
                            fprintf(stderr, "%s (%s) %u,%u: channel %d %g, want %g (uv %g %g)\n", qc->name,
                                    which ? "gl" : "soft", x, y, k, got, 0.03 * want[k], uv[0], uv[1]);
                        bad++;
                        break;
                    }
                }
            }
        fprintf(stderr, "textured quad, %s (%s): %llu pixels judged, %llu off, worst %.3g (of 0.03)\n", qc->name,
                which ? "gl" : "soft", (unsigned long long)judged, (unsigned long long)bad, worst);
        assert_true(judged > 500);
        /* the soft renderer exactly (UVs to float rounding); llvmpipe's
           own filtering and LOD rounding: a few pixels */
        assert_true(which ? bad * 100 <= judged : bad * 1000 <= judged);
        if (!which) maybe_png(qc->name, W, H, rgba);
    }
    occ_ref_free(&ref);
    free(rgba);
    free(depth);
    tex_free(&to);
}

/* Both renderers (GL where a context can be made). */
typedef struct rpair {
    vt_gl *g;
    vt_gldraw *gr;
    vt_soft *sr;
} rpair;

static void rpair_open(rpair *p)
{
    p->gr = test_gldraw_or_null(&p->g);
    assert_int_equal(vt_soft_create(NULL, 0, &p->sr), 0);
}

static void rpair_close(rpair *p)
{
    vt_soft_destroy(p->sr);
    vt_gldraw_destroy(p->gr);
    vt_gl_close(p->g);
}

static void test_scene_textured_quad(void **state)
{
    (void)state;
    static const quad_case cases[] = {
        {"nearest, repeat x mirror", VT_WRAP_REPEAT, VT_WRAP_MIRROR, VT_FILTER_NEAREST, VT_FILTER_NEAREST, 8, 8, 1, 4, 0},
        {"bilinear, mirror x clamp", VT_WRAP_MIRROR, VT_WRAP_CLAMP, VT_FILTER_LINEAR, VT_FILTER_LINEAR, 5, 4, 1, 4, 0},
        {"mip levels (nearest-mip-nearest)", VT_WRAP_REPEAT, VT_WRAP_REPEAT, VT_FILTER_NEAREST_MIP_NEAREST,
         VT_FILTER_NEAREST, 256, 256, 9, 40, 0},
        {"alpha mask at 0.5", VT_WRAP_REPEAT, VT_WRAP_REPEAT, VT_FILTER_NEAREST, VT_FILTER_NEAREST, 8, 8, 1, 4, QUAD_MASK},
        {"back face, double-sided", VT_WRAP_REPEAT, VT_WRAP_MIRROR, VT_FILTER_NEAREST, VT_FILTER_NEAREST, 8, 8, 1, 4,
         QUAD_BACK | QUAD_TWO},
        {"back face, one-sided", VT_WRAP_REPEAT, VT_WRAP_MIRROR, VT_FILTER_NEAREST, VT_FILTER_NEAREST, 8, 8, 1, 4,
         QUAD_BACK},
    };
    vt_gl *g;
    vt_gldraw *gr = test_gldraw_or_null(&g);
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) check_quad(&cases[i], gr);
    vt_gldraw_destroy(gr);
    vt_gl_close(g);
}

/* ---- transformed silhouettes against the ray caster --------------------------------- */

/* An open box: the unit cube without its +x and +y faces (8 triangles),
 * so a wrongly culled or wrongly wound face shows. */
static const float obox_pos[24] = {-1, -1, -1, 1, -1, -1, -1, 1, -1, 1, 1, -1, -1, -1, 1, 1, -1, 1, -1, 1, 1, 1, 1, 1};
static const uint32_t obox_idx[24] = {0, 4, 6, 0, 6, 2, 0, 1, 5, 0, 5, 4, 0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6};

static void test_scene_transformed_silhouettes(void **state)
{
    (void)state;
    rng r = {test_seed() ^ 0x511u};
    vt_mesh m = {.pos = obox_pos, .idx = obox_idx, .nv = 8, .ni = 24};
    rpair rp;
    rpair_open(&rp);
    vt_gldraw *gr = rp.gr;
    vt_soft *sr = rp.sr;
    uint64_t pixels = 0, both = 0, mismatch = 0, depth_bad = 0, gl_mismatch = 0, mirrored = 0;
    for (int fno = 0; fno < 12; fno++) {
        const uint32_t W = 96 + rng_below(&r, 64), H = 64 + rng_below(&r, 64), n = 1 + rng_below(&r, 6);
        vt_instance in[8];
        double tri[8 * 8 * 9];
        memset(in, 0, sizeof in);
        for (uint32_t i = 0; i < n; i++) {
            in[i].place = VT_PLACE_TRS;
            in[i].albedo[0] = in[i].albedo[1] = in[i].albedo[2] = 0.5f;
            for (int a = 0; a < 3; a++) {
                in[i].pos[a] = rng_range(&r, -6, 6) + (a == 2 ? -25 : 0) + 1e6; /* far from the origin */
                float sc = (float)rng_range(&r, 0.5, 3);
                in[i].scale[a] = rng_below(&r, 3) == 0 ? -sc : sc;
            }
            axis_angle(rng_range(&r, -1, 1), rng_range(&r, -1, 1), rng_range(&r, -1, 1) + 0.01, rng_range(&r, -3, 3),
                       in[i].rot);
            double q[4] = {in[i].rot[0], in[i].rot[1], in[i].rot[2], in[i].rot[3]};
            double ql = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
            for (int a = 0; a < 4; a++) q[a] /= ql;
            bool mir = (in[i].scale[0] < 0) ^ (in[i].scale[1] < 0) ^ (in[i].scale[2] < 0);
            mirrored += mir;
            for (int t = 0; t < 8; t++)
                for (int k = 0; k < 3; k++) {
                    /* a mirrored triangle is wound the other way round */
                    int kk = mir && k ? 3 - k : k;
                    const float *p = obox_pos + 3 * obox_idx[3 * t + kk];
                    double sp[3] = {p[0] * in[i].scale[0], p[1] * in[i].scale[1], p[2] * in[i].scale[2]}, o[3];
                    qrot(q, sp, o);
                    for (int a = 0; a < 3; a++) tri[(i * 8 + (uint32_t)t) * 9 + 3 * (uint32_t)k + (uint32_t)a] = o[a] + in[i].pos[a];
                }
        }
        double eye[3] = {rng_range(&r, -4, 4) + 1e6, rng_range(&r, -4, 4) + 1e6, -12 + 1e6}, at[3] = {1e6, 1e6, -25 + 1e6};
        cull_view v;
        look(&v, eye, at, W, H, 1.2, (int)rng_below(&r, 3));
        size_t np = (size_t)W * H;
        float *c1 = malloc(np * 16), *d1 = malloc(np * 4), *c2 = malloc(np * 16), *d2 = malloc(np * 4);
        assert_true(c1 && d1 && c2 && d2);
        char err[256];
        vt_frame f = {.view = &v, .width = W, .height = H, .meshes = &m, .nmesh = 1, .inst = in, .ninst = n,
                      .rgba = c1, .depth = d1, .stride = W};
        assert_int_equal(vt_soft_draw(sr, &f, NULL, err, sizeof err), 0);
        occ_ref ref;
        assert_int_equal(occ_ref_init(&ref, &v, W, H), 0);
        occ_ref_add_triangles(&ref, tri, (size_t)n * 8);
        if (gr) {
            f.rgba = c2;
            f.depth = d2;
            assert_int_equal(vt_gldraw_draw(gr, &f, NULL, err, sizeof err), 0);
        }
        for (size_t px = 0; px < np; px++) {
            bool ours = d1[px] != INFINITY, theirs = ref.t[px] != INFINITY;
            pixels++;
            if (gr && (d2[px] != INFINITY) != ours) gl_mismatch++;
            if (ours != theirs) {
                mismatch++;
                continue;
            }
            if (!ours) continue;
            both++;
            const double *ray = ref.ray + 6 * px, *mm = v.clip;
            double p[3];
            for (int a = 0; a < 3; a++) p[a] = ray[a] + ref.t[px] * ray[3 + a];
            double wref = mm[3] * p[0] + mm[7] * p[1] + mm[11] * p[2] + mm[15];
            if (v.depth_mode == CULL_DEPTH_GL || 1) {
                /* the depth output is w for perspective views */
                if (!(fabs(d1[px] - wref) <= 1e-4 * wref)) depth_bad++;
            }
        }
        occ_ref_free(&ref);
        free(c1);
        free(d1);
        free(c2);
        free(d2);
    }
    fprintf(stderr, "transformed open boxes (%llu mirrored) vs ray caster: %llu pixels, %llu covered by both, %llu differ "
                    "in coverage, %llu in depth; GL differs from soft in coverage on %llu\n",
            (unsigned long long)mirrored, (unsigned long long)pixels, (unsigned long long)both,
            (unsigned long long)mismatch, (unsigned long long)depth_bad, (unsigned long long)gl_mismatch);
    assert_true(mirrored > 3);
    assert_true(both * 20 > pixels);
    assert_true((mismatch + depth_bad) * 1000 <= pixels);
    assert_true(gl_mismatch * 1000 <= pixels);
    rpair_close(&rp);
}

/* ---- sky, ground, fog in closed form -------------------------------------------------- */

static void test_scene_sky_ground_fog(void **state)
{
    (void)state;
    rpair rp;
    rpair_open(&rp);
    vt_gldraw *gr = rp.gr;
    vt_soft *sr = rp.sr;
    const uint32_t W = 64, H = 48;
    const double eye[3] = {3, 2.5, 7}, at[3] = {3, 1.5, -3};
    const float L[3] = {500, 800, 1200}, rho[3] = {0.3f, 0.2f, 0.1f};
    for (int fog = 0; fog < 2; fog++)
        for (int which = 0; which < (gr ? 2 : 1); which++) {
            vt_env env = {.sky_mode = VT_SKY_COLOR, .sky = {L[0], L[1], L[2]}, .ground = true, .ground_height = 0.5,
                          .ground_albedo = {rho[0], rho[1], rho[2]}, .exposure_mode = VT_EXPOSURE_FIXED,
                          .exposure_ev = 3, .fog_density = fog ? 0.05f : 0, .fog_color = {0.5f, 0.5f, 0.5f}};
            cull_view v;
            look(&v, eye, at, W, H, 1.0, CULL_DEPTH_REVERSED);
            float *c = malloc((size_t)W * H * 16), *d = malloc((size_t)W * H * 4);
            assert_true(c && d);
            /* per-pixel closed forms: no FXAA (it blends the horizon), the
               two-colour hemisphere ambient, whose closed form is below (the
               image-based one: test_brdf's white furnace) */
            vt_frame f = {.view = &v, .width = W, .height = H, .env = &env, .rgba = c, .depth = d, .stride = W,
                          .fx_off = VT_FX_FXAA | VT_FX_IBL};
            char err[256];
            int rc = which ? vt_gldraw_draw(gr, &f, NULL, err, sizeof err) : vt_soft_draw(sr, &f, NULL, err, sizeof err);
            if (rc) fprintf(stderr, "%s\n", err);
            assert_int_equal(rc, 0);
            occ_ref ref;
            assert_int_equal(occ_ref_init(&ref, &v, W, H), 0);
            const double k = 1 / (1.2 * 8.0); /* EV100 3 */
            double worst = 0;
            uint32_t sky = 0, ground = 0;
            for (uint32_t y = 0; y < H; y++)
                for (uint32_t x = 0; x < W; x++) {
                    size_t px = (size_t)y * W + x;
                    const double *ray = ref.ray + 6 * px;
                    double dl = sqrt(ray[3] * ray[3] + ray[4] * ray[4] + ray[5] * ray[5]);
                    double dy = ray[4] / dl, t = (0.5 - eye[1] - ray[1]) / ray[4];
                    double want[3];
                    assert_true(c[4 * px + 3] == 1.0f); /* opaque with an environment */
                    if (fabs(dy) < 0.02) continue; /* at the horizon: not judged */
                    if (dy > 0) {
                        /* the sky: L, unfogged */
                        for (int q = 0; q < 3; q++) want[q] = L[q] * k;
                        assert_true(d[px] == INFINITY);
                        sky++;
                    } else {
                        double p[3];
                        for (int a = 0; a < 3; a++) p[a] = ray[a] + t * ray[3 + a];
                        double dist = sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
                        /* a Lambert ground under a uniform sky L: the
                           ambient from above is L (the sky's cosine-
                           weighted mean), from below rho L (its bounce);
                           diffuse rho L; the specular share F of the
                           ambient towards the reflected direction (height
                           n.v: rho L + (0.5 + 0.5 n.v)(1 - rho) L), F =
                           0.04 + 0.96 (1 - n.v)^5 (1 - roughness 0.6)^2 */
                        double nv = -dy, F = 0.04 + 0.96 * pow(1 - nv, 5) * 0.16;
                        double T = exp(-0.05 * dist * fog);
                        for (int q = 0; q < 3; q++) {
                            double lr = rho[q] * L[q] + (0.5 + 0.5 * nv) * (1 - rho[q]) * L[q];
                            want[q] = ((rho[q] * L[q] + F * lr) * T + 0.5 * L[q] * (1 - T)) * k;
                        }
                        /* depth: w of the hit */
                        const double *m = v.clip;
                        double w = m[3] * p[0] + m[7] * p[1] + m[11] * p[2] + m[15];
                        assert_true(fabs(d[px] - w) <= 1e-3 * w);
                        ground++;
                    }
                    for (int q = 0; q < 3; q++) {
                        double e = fabs(c[4 * px + q] - want[q]) / want[q];
                        if (e > worst) worst = e;
                    }
                }
            fprintf(stderr, "sky and ground%s (%s): %u sky and %u ground pixels judged, worst relative error %.3g\n",
                    fog ? " with fog" : "", which ? "gl" : "soft", sky, ground, worst);
            assert_true(sky > 100 && ground > 100);
            assert_true(worst < (which ? 2e-3 : 1e-4));
            occ_ref_free(&ref);
            free(c);
            free(d);
        }
    rpair_close(&rp);
}


/* Preetham, Shirley and Smits (1999) in double, from the paper's tables:
 * the clear sky's radiance (cd/m2, linear sRGB) towards unit d for a sun
 * towards unit s and turbidity T. */
static void preetham_ref(const double d[3], const double s[3], double T, double out[3])
{
    static const double k[3][5][2] = {
        {{0.1787, -1.4630}, {-0.3554, 0.4275}, {-0.0227, 5.3251}, {0.1206, -2.5771}, {-0.0670, 0.3703}},
        {{-0.0193, -0.2592}, {-0.0665, 0.0008}, {-0.0004, 0.2125}, {-0.0641, -0.8989}, {-0.0033, 0.0452}},
        {{-0.0167, -0.2608}, {-0.0950, 0.0092}, {-0.0079, 0.2102}, {-0.0441, -1.6537}, {-0.0109, 0.0529}}};
    double ts = acos(s[1]), t2 = ts * ts, t3 = t2 * ts, chi = (4.0 / 9 - T / 120) * (M_PI - 2 * ts);
    double z[3] = {((4.0453 * T - 4.9710) * tan(chi) - 0.2155 * T + 2.4192) * 1000,
                   T * T * (0.00166 * t3 - 0.00375 * t2 + 0.00209 * ts) +
                       T * (-0.02903 * t3 + 0.06377 * t2 - 0.03202 * ts + 0.00394) +
                       (0.11693 * t3 - 0.21196 * t2 + 0.06052 * ts + 0.25886),
                   T * T * (0.00275 * t3 - 0.00610 * t2 + 0.00317 * ts) +
                       T * (-0.04214 * t3 + 0.08970 * t2 - 0.04153 * ts + 0.00516) +
                       (0.15346 * t3 - 0.26756 * t2 + 0.06670 * ts + 0.26688)};
    double g = acos(d[0] * s[0] + d[1] * s[1] + d[2] * s[2]), Yxy[3];
    for (int c = 0; c < 3; c++) {
        double A = k[c][0][0] * T + k[c][0][1], B = k[c][1][0] * T + k[c][1][1], C = k[c][2][0] * T + k[c][2][1];
        double D = k[c][3][0] * T + k[c][3][1], E = k[c][4][0] * T + k[c][4][1];
        double F = (1 + A * exp(B / d[1])) * (1 + C * exp(D * g) + E * cos(g) * cos(g));
        double F0 = (1 + A * exp(B)) * (1 + C * exp(D * ts) + E * cos(ts) * cos(ts));
        Yxy[c] = z[c] * F / F0;
    }
    double Y = Yxy[0], X = Yxy[1] / Yxy[2] * Y, Z = (1 - Yxy[1] - Yxy[2]) / Yxy[2] * Y;
    out[0] = 3.2406 * X - 1.5372 * Y - 0.4986 * Z;
    out[1] = -0.9689 * X + 1.8758 * Y + 0.0415 * Z;
    out[2] = 0.0557 * X - 0.2040 * Y + 1.0570 * Z;
}

/* The analytic sky (tabulated, interpolated across the screen) against
 * the paper's formulas at every sky pixel above 5 degrees: within 2 %
 * (the table's bilinear error near the sun). */
static void test_scene_analytic_sky(void **state)
{
    (void)state;
    rpair rp;
    rpair_open(&rp);
    const uint32_t W = 120, H = 90;
    const double sun[3] = {-0.4545, 0.7660, -0.4545}, sl = sqrt(0.4545 * 0.4545 * 2 + 0.766 * 0.766);
    vt_env env = {.sun_dir = {(float)(sun[0] / sl), (float)(sun[1] / sl), (float)(sun[2] / sl)},
                  .sky_mode = VT_SKY_ANALYTIC, .sky = {1, 1, 1}, .turbidity = 3,
                  .exposure_mode = VT_EXPOSURE_FIXED, .exposure_ev = 0};
    const double s[3] = {env.sun_dir[0], env.sun_dir[1], env.sun_dir[2]};
    float *c = malloc((size_t)W * H * 16), *dz = malloc((size_t)W * H * 4);
    assert_true(c && dz);
    for (int look_i = 0; look_i < 3; look_i++) {
        const double eye[3] = {0, 1, 0}, at[3][3] = {{-3, 3, -3}, {5, 2, 1}, {0, 8, -1}};
        cull_view v;
        look(&v, eye, at[look_i], W, H, 1.3, CULL_DEPTH_ZERO_ONE);
        occ_ref ref;
        assert_int_equal(occ_ref_init(&ref, &v, W, H), 0);
        for (int which = 0; which < (rp.gr ? 2 : 1); which++) {
            vt_frame f = {.view = &v, .width = W, .height = H, .env = &env, .rgba = c, .depth = dz, .stride = W};
            char err[256];
            assert_int_equal(which ? vt_gldraw_draw(rp.gr, &f, NULL, err, sizeof err)
                                   : vt_soft_draw(rp.sr, &f, NULL, err, sizeof err),
                             0);
            double worst = 0;
            uint32_t judged = 0;
            for (size_t px = 0; px < (size_t)W * H; px++) {
                const double *ray = ref.ray + 6 * px;
                double l = sqrt(ray[3] * ray[3] + ray[4] * ray[4] + ray[5] * ray[5]), d[3] = {ray[3] / l, ray[4] / l, ray[5] / l};
                if (d[1] < 0.09) continue;
                double want[3];
                preetham_ref(d, s, 3, want);
                for (int k = 0; k < 3; k++) {
                    double e = fabs(c[4 * px + k] * 1.2 - want[k]) / want[k]; /* EV100 0: x 1 / 1.2 */
                    worst = e > worst ? e : worst;
                }
                judged++;
            }
            fprintf(stderr, "analytic sky, view %d (%s): %u pixels against Preetham in double, worst relative %.3g\n",
                    look_i, which ? "gl" : "soft", judged, worst);
            assert_true(judged > 1000);
            assert_true(worst < 0.02);
        }
        occ_ref_free(&ref);
    }
    free(c);
    free(dz);
    rpair_close(&rp);
}

/* ---- a small textured scene: the default environment, soft vs GL ---------------------- */

/* The protocol's default environment (vp_env_default) as the daemon
 * hands it to the renderers. */
static void env_default(vt_env *e)
{
    double el = 50 * M_PI / 180, az = 225 * M_PI / 180;
    *e = (vt_env){.sun_dir = {(float)(cos(el) * sin(az)), (float)sin(el), (float)(cos(el) * cos(az))},
                  .sun = {100000.0f, 96000.0f, 90000.0f}, .sky_mode = VT_SKY_ANALYTIC, .sky = {1, 1, 1},
                  .turbidity = 2.5f, .ground = true, .ground_albedo = {0.25f, 0.25f, 0.25f}, .fog_density = 0.0005f,
                  .fog_color = {0.6f, 0.7f, 0.8f}, .exposure_mode = VT_EXPOSURE_AUTO, .exposure_ev = 14};
}

/* A checker of two colours, 8x8 texels of 8x8 cells, with its mip chain. */
static void checker(tex_own *o, uint32_t id)
{
    rng r = {1};
    tex_make(o, &r, 64, 64, 7, id);
    for (uint32_t k = 0; k < 7; k++) {
        uint32_t n = 64 >> k, cell = 8 >> k ? 8 >> k : 1;
        for (uint32_t y = 0; y < n; y++)
            for (uint32_t x = 0; x < n; x++) {
                bool a = ((x / cell) + (y / cell)) % 2 == 0;
                uint8_t *p = o->lv[k] + 4 * (y * n + x);
                if (k >= 3) memcpy(p, (uint8_t[4]){170, 90, 60, 255}, 4); /* the average, roughly */
                else memcpy(p, a ? (uint8_t[4]){230, 200, 60, 255} : (uint8_t[4]){90, 30, 40, 255}, 4);
            }
    }
}

/* A 64 x 64 emissive map like the city's window lights: black but for
 * a window lit in one 8 x 8 cell in four, its mips box-filtered (the
 * coarse levels' black where a footprint holds no window). */
static void windows(tex_own *o, uint32_t id)
{
    rng r = {2};
    tex_make(o, &r, 64, 64, 7, id);
    for (uint32_t y = 0; y < 64; y++)
        for (uint32_t x = 0; x < 64; x++) {
            bool lit = ((x / 8) * 3 + (y / 8) * 5) % 4 == 0 && x % 8 >= 2 && x % 8 < 6 && y % 8 >= 1 && y % 8 < 7;
            memcpy(o->lv[0] + 4 * (y * 64 + x), lit ? (uint8_t[4]){250, 200, 120, 255} : (uint8_t[4]){0, 0, 0, 255}, 4);
        }
    for (uint32_t k = 1; k < 7; k++) {
        uint32_t n = 64 >> k;
        for (uint32_t y = 0; y < n; y++)
            for (uint32_t x = 0; x < n; x++)
                for (int c = 0; c < 4; c++) {
                    const uint8_t *a = o->lv[k - 1] + 4 * (2 * y * 2 * n + 2 * x) + c;
                    o->lv[k][4 * (y * n + x) + c] = (uint8_t)((a[0] + a[4] + a[8 * n] + a[8 * n + 4] + 2) / 4);
                }
    }
}

/* Boxes with normals per face (24 vertices) and UVs 0..1 on each face. */
static float cube24_pos[72], cube24_nrm[72], cube24_uv[48];
static uint32_t cube24_idx[36];
static vt_mesh cube24(void)
{
    static const int axis[6][3] = {{0, 1, 2}, {0, 1, 2}, {1, 2, 0}, {1, 2, 0}, {2, 0, 1}, {2, 0, 1}};
    for (int f = 0; f < 6; f++) {
        float sgn = f % 2 ? -1.0f : 1.0f;
        int n = axis[f][2], u = axis[f][0], w = axis[f][1];
        for (int k = 0; k < 4; k++) {
            float cu = (k == 1 || k == 2) ? 1.0f : -1.0f, cw = k >= 2 ? 1.0f : -1.0f;
            float *p = cube24_pos + 3 * (4 * f + k), *nn = cube24_nrm + 3 * (4 * f + k);
            p[n] = sgn;
            p[u] = cu * sgn; /* mirrored on the negative faces: counter-clockwise from outside */
            p[w] = cw;
            nn[0] = nn[1] = nn[2] = 0;
            nn[n] = sgn;
            cube24_uv[2 * (4 * f + k)] = (cu + 1) / 2;
            cube24_uv[2 * (4 * f + k) + 1] = (1 - cw) / 2;
        }
        uint32_t b = 4 * (uint32_t)f, q[6] = {b, b + 1, b + 2, b, b + 2, b + 3};
        memcpy(cube24_idx + 6 * f, q, sizeof q);
    }
    return (vt_mesh){.pos = cube24_pos, .nrm = cube24_nrm, .uv = cube24_uv, .idx = cube24_idx, .nv = 24, .ni = 36};
}

typedef struct small_scene {
    vt_mesh mesh;
    tex_own tex;
    vt_material mat[3];
    vt_instance in[6];
    vt_env env;
    cull_view v;
} small_scene;

static void small_scene_make(small_scene *sc, uint32_t W, uint32_t H)
{
    sc->mesh = cube24();
    checker(&sc->tex, 7);
    env_default(&sc->env);
    vt_texref tr = {.tex = &sc->tex.t, .min_filter = VT_FILTER_LINEAR_MIP_LINEAR, .mag_filter = VT_FILTER_LINEAR,
                    .scale = {2, 2}};
    sc->mat[0] = (vt_material){.base = {1, 1, 1, 1}, .roughness = 0.7f, .normal_scale = 1};
    sc->mat[0].tex[VT_SLOT_BASE] = tr;
    sc->mat[1] = (vt_material){.base = {0.9f, 0.9f, 0.95f, 1}, .metallic = 1, .roughness = 0.3f, .normal_scale = 1};
    sc->mat[2] = (vt_material){.base = {0.2f, 0.5f, 0.2f, 1}, .roughness = 0.5f, .emissive = {1, 0.5f, 0.1f},
                               .emissive_strength = 20000, .normal_scale = 1};
    sc->mat[2].tex[VT_SLOT_EMISSIVE] = tr;
    memset(sc->in, 0, sizeof sc->in);
    const double P[6][3] = {{0, 1, 0}, {3.5, 1.5, -2}, {-3.5, 0.75, -1}, {1, 0.5, 3}, {-1.5, 2.5, -5}, {5, 3, -8}};
    const float S[6][3] = {{1, 1, 1}, {1, 1.5f, 1}, {0.75f, 0.75f, -0.75f}, {2, 0.5f, 0.5f}, {1, 1, 1}, {-1, 3, 1}};
    for (int i = 0; i < 6; i++) {
        sc->in[i].place = VT_PLACE_TRS;
        memcpy(sc->in[i].pos, P[i], sizeof P[i]);
        memcpy(sc->in[i].scale, S[i], sizeof S[i]);
        axis_angle(0.2, 1, 0.1 * i, 0.4 * i, sc->in[i].rot);
        sc->in[i].mat = i == 4 ? NULL : &sc->mat[i % 3];
        sc->in[i].albedo[0] = 0.6f, sc->in[i].albedo[1] = 0.3f, sc->in[i].albedo[2] = 0.3f;
    }
    double eye[3] = {6, 4, 10}, at[3] = {0, 1, -1};
    look(&sc->v, eye, at, W, H, 0.9, CULL_DEPTH_REVERSED);
}

/* The shading kernels' gather in lanes (render/vt_gather.inl) against
 * its scalar reference (vt_span_surface, vt_tex_sample) on every
 * instruction set: the small scene with more texture slots than it
 * draws by default (metallic-roughness, a mostly black emission, a clamped and a
 * rotated, offset, scaled transform, UVs far from the origin) and a
 * textured ground, fixed exposure, the passes with discrete decisions
 * (shadow compares, FXAA) off; then a narrow view of sky and ground (the
 * sky interpolated across columns in lanes, per 4 in the reference). The two evaluate the same formulas in a
 * different order (fused multiply-adds, the LOD's log2 by a polynomial,
 * texel coordinates in float): a pixel's radiance agrees to ~1e-5
 * relative; 1e-3 says the same texels, weights and material. Where a
 * triangle is seen nearly edge-on its edge functions cancel and any two
 * roundings of the barycentrics differ more (AVX2's fused multiply-adds
 * against the reference's separate ones: one pixel of this scene at
 * 5e-3): at most 1 channel in 1000 may be over 1e-3, none over 2e-2. */
static void test_scene_gather_lanes(void **state)
{
    (void)state;
    const uint32_t W = 192, H = 120;
    small_scene sc;
    small_scene_make(&sc, W, H);
    rng r = {7};
    tex_own mr;
    tex_make(&mr, &r, 32, 16, 6, 8);
    sc.mat[0].tex[VT_SLOT_MR] = (vt_texref){.tex = &mr.t, .wrap_s = VT_WRAP_CLAMP, .min_filter = VT_FILTER_LINEAR_MIP_LINEAR,
                                            .mag_filter = VT_FILTER_LINEAR, .scale = {1.5f, 0.75f}, .offset = {-0.2f, 0.3f}};
    sc.mat[1].tex[VT_SLOT_BASE] = (vt_texref){.tex = &sc.tex.t, .wrap_t = VT_WRAP_CLAMP, .min_filter = VT_FILTER_LINEAR,
                                              .mag_filter = VT_FILTER_LINEAR, .scale = {3, 3}, .rotation = 0.7f,
                                              .offset = {1000.25f, -500.5f}};
    sc.mat[2].tex[VT_SLOT_MR] = sc.mat[0].tex[VT_SLOT_MR];
    /* mostly black emission (the sampler skips black footprints,
       vt_texlin.h), clamped down its t axis */
    tex_own win;
    windows(&win, 9);
    sc.mat[2].tex[VT_SLOT_EMISSIVE] = (vt_texref){.tex = &win.t, .wrap_t = VT_WRAP_CLAMP,
                                                  .min_filter = VT_FILTER_LINEAR_MIP_LINEAR,
                                                  .mag_filter = VT_FILTER_LINEAR, .scale = {1.5f, 1.5f}};
    sc.env.ground_mat = &sc.mat[0];
    sc.env.exposure_mode = VT_EXPOSURE_FIXED;
    sc.env.exposure_ev = 13;
    char *keep = test_env_keep("VANTAGE_ISA");
    size_t np = (size_t)W * H;
    float *c[2] = {malloc(np * 16), malloc(np * 16)}, *d = malloc(np * 4);
    assert_true(c[0] && c[1] && d);
    static const char *const isas[] = {"scalar", "sse41", "avx2"};
    for (int k = 0; k < 6; k++) {
        if (k == 3) {
            /* a narrow view along the horizon: the sky's 16-column spans
               then see less than a texel of its table (interpolated) */
            const double eye[3] = {6, 4, 10}, at[3] = {106, 6, -90};
            look(&sc.v, eye, at, W, H, 0.1, CULL_DEPTH_REVERSED);
        }
        setenv("VANTAGE_ISA", isas[k % 3], 1);
        vt_soft *sr;
        assert_int_equal(vt_soft_create(NULL, 0, &sr), 0);
        for (int scalar = 0; scalar < 2; scalar++) {
            vt_gather_scalar = scalar;
            vt_frame f = {.view = &sc.v, .width = W, .height = H, .meshes = &sc.mesh, .nmesh = 1, .inst = sc.in,
                          .ninst = 6, .env = &sc.env, .rgba = c[scalar], .depth = d, .stride = W,
                          .fx_off = VT_FX_SHADOWS | VT_FX_SSAO | VT_FX_FXAA};
            char err[256];
            int rc = vt_soft_draw(sr, &f, NULL, err, sizeof err);
            if (rc) fprintf(stderr, "%s\n", err);
            assert_int_equal(rc, 0);
        }
        vt_gather_scalar = 0;
        vt_soft_destroy(sr);
        double worst = 0;
        size_t drawn = 0, off = 0;
        for (size_t p = 0; p < np; p++) {
            drawn += d[p] != INFINITY;
            for (int q = 0; q < 3; q++) {
                double a = c[0][4 * p + q], b = c[1][4 * p + q];
                assert_true(isfinite(a));
                double e = fabs(a - b) / (fabs(b) + 1e-4);
                worst = e > worst ? e : worst;
                off += e > 1e-3;
            }
        }
        fprintf(stderr,
                "gather in lanes (%s) against the scalar reference: %zu pixels drawn, worst relative %.3g, %zu channels "
                "over 1e-3\n",
                isas[k % 3], drawn, worst, off);
        assert_true(k >= 3 ? drawn * 5 > np && drawn * 5 < 4 * np : drawn * 3 > np);
        assert_true(off * 1000 <= drawn && worst < 0.02);
    }
    test_env_restore("VANTAGE_ISA", keep);
    free(c[0]);
    free(c[1]);
    free(d);
    tex_free(&mr);
    tex_free(&win);
    tex_free(&sc.tex);
}

/* The default environment on a small textured scene: a picture that is
 * neither dark nor blown out (ACES after the auto exposure), sky, ground
 * and objects all there; soft and GL agree. */
static void test_scene_default_env(void **state)
{
    (void)state;
    const uint32_t W = 320, H = 200;
    small_scene sc;
    small_scene_make(&sc, W, H);
    rpair rp;
    rpair_open(&rp);
    vt_gldraw *gr = rp.gr;
    vt_soft *sr = rp.sr;
    size_t np = (size_t)W * H;
    float *c[2] = {malloc(np * 16), malloc(np * 16)}, *d[2] = {malloc(np * 4), malloc(np * 4)};
    assert_true(c[0] && c[1] && d[0] && d[1]);
    for (int fog = 0; fog < 2; fog++) {
        sc.env.fog_density = fog ? 0.03f : 0.0005f;
        sc.env.fog_falloff = fog ? 0.2f : 0;
        for (int which = 0; which < (gr ? 2 : 1); which++) {
            vt_frame f = {.view = &sc.v, .width = W, .height = H, .meshes = &sc.mesh, .nmesh = 1, .inst = sc.in,
                          .ninst = 6, .env = &sc.env, .rgba = c[which], .depth = d[which], .stride = W};
            char err[256];
            vt_soft_stats st;
            int rc = which ? vt_gldraw_draw(gr, &f, &st, err, sizeof err) : vt_soft_draw(sr, &f, &st, err, sizeof err);
            if (rc) fprintf(stderr, "%s\n", err);
            assert_int_equal(rc, 0);
            /* brightness after the tone map, as the daemon's JPEG has it */
            double mean = 0;
            uint32_t black = 0, white = 0, sky = 0, ground = 0;
            for (size_t p = 0; p < np; p++) {
                double Y = 0;
                for (int k = 0; k < 3; k++) {
                    double x = c[which][4 * p + k];
                    double t = x * (2.51 * x + 0.03) / (x * (2.43 * x + 0.59) + 0.14);
                    Y += (k == 1 ? 0.7152 : k ? 0.0722 : 0.2126) * (t < 0 ? 0 : t > 1 ? 1 : t);
                }
                double s8 = Y <= 0.0031308 ? 12.92 * Y : 1.055 * pow(Y, 1 / 2.4) - 0.055;
                mean += s8;
                black += s8 < 0.05;
                white += s8 > 0.98;
                sky += d[which][p] == INFINITY;
                ground += d[which][p] != INFINITY && c[which][4 * p + 3] == 1;
            }
            mean /= (double)np;
            fprintf(stderr, "default environment%s (%s): EV100 %.2f, mean sRGB %.3f, %.1f %% black, %.1f %% white, "
                            "%.0f %% sky\n",
                    fog ? ", thick height fog" : "", which ? "gl" : "soft", st.exposure_ev, mean,
                    100.0 * black / (double)np, 100.0 * white / (double)np, 100.0 * sky / (double)np);
            assert_true(mean > 0.25 && mean < 0.8);
            assert_true(black * 50 < np && white * 20 < np);
            assert_true(sky * 10 > np && sky * 10 < 9 * np);
            assert_true(st.exposure_ev > 10 && st.exposure_ev < 17);
        }
        if (!fog) maybe_png("default_env_soft", W, H, c[0]);
        if (!fog && gr) maybe_png("default_env_gl", W, H, c[1]);
        if (fog) maybe_png("height_fog_soft", W, H, c[0]);
        if (!gr) continue;
        /* soft vs GL: the tolerances of test_soft_and_gl_agree */
        uint64_t cov_diff = 0, both = 0, depth_bad = 0, compared = 0, color_bad = 0;
        double worst = 0;
        for (uint32_t y = 1; y + 1 < H; y++)
            for (uint32_t x = 1; x + 1 < W; x++) {
                size_t p = (size_t)y * W + x;
                bool a = d[0][p] != INFINITY, b = d[1][p] != INFINITY;
                if (a != b) {
                    cov_diff++;
                    continue;
                }
                bool interior = true;
                for (int dy = -1; dy <= 1 && interior; dy++)
                    for (int dx = -1; dx <= 1 && interior; dx++) {
                        size_t q = p + (size_t)((ptrdiff_t)dy * W + dx);
                        interior = (d[0][q] == INFINITY) == (d[1][q] == INFINITY) &&
                                   (d[0][q] == INFINITY || fabsf(d[0][q] - d[1][q]) <= 1e-4f * d[0][q]);
                    }
                if (a) {
                    both++;
                    if (!(fabsf(d[0][p] - d[1][p]) <= 1e-4f * d[0][p])) depth_bad++;
                }
                if (!interior) continue;
                compared++;
                for (int k = 0; k < 3; k++) {
                    double e = fabs(c[0][4 * p + k] - c[1][4 * p + k]) / (1e-3 + fabs(c[0][4 * p + k]));
                    if (e > worst) worst = e;
                    if (fabsf(c[0][4 * p + k] - c[1][4 * p + k]) > 0.01f * fabsf(c[0][4 * p + k]) + 1e-3f) {
                        color_bad++;
                        break;
                    }
                }
            }
        fprintf(stderr, "soft vs GL, textured transformed scene%s: %llu differ in coverage, %llu covered by both (%llu off "
                        "in depth), %llu compared in colour, %llu off (worst relative %.3g)\n",
                fog ? " in fog" : "", (unsigned long long)cov_diff, (unsigned long long)both,
                (unsigned long long)depth_bad, (unsigned long long)compared, (unsigned long long)color_bad, worst);
        assert_true(cov_diff * 500 <= np);
        assert_true(depth_bad * 500 <= both);
        assert_true(color_bad * 50 <= compared);
    }
    free(c[0]);
    free(c[1]);
    free(d[0]);
    free(d[1]);
    tex_free(&sc.tex);
    rpair_close(&rp);
}

/* ---- bad input ---------------------------------------------------------------------- */

typedef struct bad_row {
    const char *name;
    void (*spoil)(small_scene *sc);
} bad_row;

static void sp_pos_nan(small_scene *sc) { sc->in[1].pos[0] = NAN; }
static void sp_pos_huge(small_scene *sc) { sc->in[1].pos[2] = 1e16; }
static void sp_quat(small_scene *sc) { sc->in[1].rot[3] += 0.1f; }
static void sp_quat_inf(small_scene *sc) { sc->in[1].rot[0] = INFINITY; }
static void sp_scale2(small_scene *sc) { sc->in[1].scale[0] = sc->in[1].scale[2] = 0; }
static void sp_scale_nan(small_scene *sc) { sc->in[1].scale[1] = NAN; }
static void sp_place(small_scene *sc) { sc->in[1].place = 7; }
static void sp_rough(small_scene *sc) { sc->mat[1].roughness = NAN; }
static void sp_base(small_scene *sc) { sc->mat[1].base[3] = 2; }
static void sp_emis(small_scene *sc) { sc->mat[2].emissive_strength = INFINITY; }
static void sp_alpha(small_scene *sc) { sc->mat[0].alpha_mode = 5; }
static void sp_wrap(small_scene *sc) { sc->mat[0].tex[0].wrap_s = 3; }
static void sp_filter(small_scene *sc) { sc->mat[0].tex[0].mag_filter = VT_FILTER_LINEAR_MIP_LINEAR; }
static void sp_xform(small_scene *sc) { sc->mat[0].tex[0].rotation = NAN; }
static void sp_levels(small_scene *sc) { sc->tex.t.levels = 9; }
static void sp_level_null(small_scene *sc) { free(sc->tex.lv[2]), sc->tex.lv[2] = NULL; }
static void sp_tex_size(small_scene *sc) { sc->tex.t.w = 0; }
static void sp_tex_hdr(small_scene *sc) { sc->tex.t.hdr = (const float *)sc->tex.lv[0]; }
static void sp_sun(small_scene *sc) { sc->env.sun_dir[0] = 0.5f; }
static void sp_sun_nan(small_scene *sc) { sc->env.sun[1] = NAN; }
static void sp_sky_mode(small_scene *sc) { sc->env.sky_mode = 3; }
static void sp_sky_tex(small_scene *sc) { sc->env.sky_mode = VT_SKY_TEXTURE; }
static void sp_turb(small_scene *sc) { sc->env.turbidity = 0; }
static void sp_ground(small_scene *sc) { sc->env.ground_height = INFINITY; }
static void sp_fog(small_scene *sc) { sc->env.fog_density = NAN; }
static void sp_falloff(small_scene *sc) { sc->env.fog_falloff = -1; }
static void sp_ev(small_scene *sc) { sc->env.exposure_ev = 99; }
static void sp_expmode(small_scene *sc) { sc->env.exposure_mode = 2; }
static void sp_uv(small_scene *sc) { cube24_uv[5] = NAN; (void)sc; }

static const bad_row bad_rows[] = {
    {"position NaN", sp_pos_nan}, {"position 1e16", sp_pos_huge}, {"quaternion of length 1.07", sp_quat},
    {"quaternion inf", sp_quat_inf}, {"scale 0 on two axes", sp_scale2}, {"scale NaN", sp_scale_nan},
    {"placement 7", sp_place}, {"roughness NaN", sp_rough}, {"base alpha 2", sp_base},
    {"emissive strength inf", sp_emis}, {"alpha mode 5", sp_alpha}, {"wrap 3", sp_wrap},
    {"mag filter trilinear", sp_filter}, {"texture rotation NaN", sp_xform}, {"9 levels for 64x64", sp_levels},
    {"a level missing", sp_level_null}, {"texture width 0", sp_tex_size}, {"texture both RGBA8 and float", sp_tex_hdr},
    {"sun direction not unit", sp_sun}, {"sun NaN", sp_sun_nan}, {"sky mode 3", sp_sky_mode},
    {"sky texture missing", sp_sky_tex}, {"turbidity 0", sp_turb}, {"ground height inf", sp_ground},
    {"fog NaN", sp_fog}, {"fog falloff -1", sp_falloff}, {"exposure EV 99", sp_ev}, {"exposure mode 2", sp_expmode},
    {"a UV NaN", sp_uv},
};

static void test_scene_bad_input(void **state)
{
    (void)state;
    rpair rp;
    rpair_open(&rp);
    const uint32_t W = 32, H = 24;
    float *c = malloc((size_t)W * H * 16), *d = malloc((size_t)W * H * 4);
    assert_true(c && d);
    for (size_t i = 0; i < sizeof bad_rows / sizeof bad_rows[0]; i++) {
        small_scene sc;
        small_scene_make(&sc, W, H);
        vt_frame f = {.view = &sc.v, .width = W, .height = H, .meshes = &sc.mesh, .nmesh = 1, .inst = sc.in,
                      .ninst = 6, .env = &sc.env, .rgba = c, .depth = d, .stride = W};
        char err[256] = "";
        assert_int_equal(vt_soft_draw(rp.sr, &f, NULL, err, sizeof err), 0); /* the scene is good */
        if (rp.gr) assert_int_equal(vt_gldraw_draw(rp.gr, &f, NULL, err, sizeof err), 0);
        bad_rows[i].spoil(&sc);
        memset(c, 0x5a, (size_t)W * H * 16);
        err[0] = 0;
        assert_int_equal(vt_soft_draw(rp.sr, &f, NULL, err, sizeof err), VT_ERR_INVALID);
        print_message("%s: %s\n", bad_rows[i].name, err);
        assert_true(err[0] != 0);
        assert_true(((uint8_t *)c)[0] == 0x5a); /* nothing drawn */
        if (rp.gr) assert_int_equal(vt_gldraw_draw(rp.gr, &f, NULL, err, sizeof err), VT_ERR_INVALID);
        tex_free(&sc.tex);
        (void)cube24(); /* the shared UVs back */
    }
    free(c);
    free(d);
    rpair_close(&rp);
}


/* ---- the daemon's glue: the scene's model as the renderers take it ------------------- */

/* frame_scene (daemon/frame_scene.c) on a scene with a material, two
 * textures (PNG-like mips, an EXR) and an environment: every field where
 * the renderers read it, the texture views pointing at the scene's own
 * pixels, an EXR refused in a material slot, a missing material the
 * default, and both renderers draw the result. */
static void test_scene_frame_glue(void **state)
{
    (void)state;
    static const scene_limits lim = {.max_entities = 1024, .max_lights = 16, .max_occluders = 16,
                                     .max_occluder_tris = 1024, .max_mesh_verts = 1024, .max_materials = 16,
                                     .max_texture_size = 4096, .max_texture_mem = 1u << 24};
    scene *sc = malloc(sizeof *sc);
    assert_non_null(sc);
    assert_int_equal(scene_init(sc, 64, &lim), 0);
    uint8_t l0[4 * 4 * 4], l1[2 * 2 * 4], l2[4];
    uint8_t *mips[3] = {l0, l1, l2};
    float hdr[8 * 4 * 4];
    for (size_t i = 0; i < sizeof l0; i++) l0[i] = (uint8_t)(i * 7);
    memset(l1, 100, sizeof l1);
    memset(l2, 50, sizeof l2);
    for (size_t i = 0; i < 8 * 4 * 4; i++) hdr[i] = (float)i;
    scene_texture tx = {.id = 5, .format = VP_TEX_PNG, .w = 4, .h = 4, .levels = 3, .mip = mips, .nbytes = 99};
    scene_texture te = {.id = 6, .format = VP_TEX_EXR, .w = 8, .h = 4, .levels = 1, .hdr = hdr, .nbytes = 512};
    scene_material sm = {.m = {.id = 9, .flags = VP_MAT_DOUBLE_SIDED, .alpha_mode = VP_ALPHA_MASK, .alpha_cutoff = 0.25f,
                               .base_color = {0.5f, 0.6f, 0.7f, 1}, .metallic = 0.2f, .roughness = 0.8f,
                               .emissive = {1, 0, 0}, .emissive_strength = 3, .normal_scale = 1}};
    sm.m.tex[VP_TEX_BASE] = (vp_texref){.texture = 5, .wrap_s = VP_WRAP_MIRROR, .wrap_t = VP_WRAP_CLAMP,
                                        .min_filter = VP_FILTER_LINEAR_MIP_LINEAR, .mag_filter = VP_FILTER_LINEAR,
                                        .offset = {0.5f, 0.25f}, .scale = {2, 3}, .rotation = 0.3f};
    sm.m.tex[VP_TEX_EMISSIVE] = (vp_texref){.texture = 6, .scale = {1, 1}}; /* an EXR: not for a material */
    sm.m.tex[VP_TEX_MR] = (vp_texref){.texture = 77, .scale = {1, 1}};     /* missing */
    assert_true(idmap_reserve(&sc->textures, 4) && idmap_reserve(&sc->materials, 4));
    idmap_put(&sc->textures, 5, (uint64_t)(uintptr_t)&tx);
    idmap_put(&sc->textures, 6, (uint64_t)(uintptr_t)&te);
    idmap_put(&sc->materials, 9, (uint64_t)(uintptr_t)&sm);
    sc->env.sky_mode = VP_SKY_COLOR;
    sc->env.sky_color[0] = 0.5f, sc->env.sky_color[1] = 0.25f, sc->env.sky_color[2] = 1;
    sc->env.sky_intensity = 2000;
    sc->env.ground_material = 9;
    frame_scene fs;
    assert_true(frame_scene_init(&fs, sc));
    assert_true(fs.env_ok);
    const vt_env *e = &fs.env;
    for (int k = 0; k < 3; k++) {
        assert_true(e->sun[k] == sc->env.sun_color[k] * sc->env.sun_lux);
        assert_true(e->sun_dir[k] == sc->env.sun_dir[k]);
        assert_true(e->sky[k] == sc->env.sky_color[k] * 2000);
        assert_true(e->ground_albedo[k] == sc->env.ground_color[k]);
    }
    assert_int_equal(e->sky_mode, VT_SKY_COLOR);
    assert_true(e->ground && e->ground_height == sc->env.ground_height);
    assert_true(e->fog_density == sc->env.fog_density && e->exposure_mode == VT_EXPOSURE_AUTO);
    const vt_material *m = e->ground_mat;
    assert_non_null(m);
    assert_true(frame_scene_material(&fs, sc, 9) == m); /* converted once */
    assert_null(frame_scene_material(&fs, sc, 0));
    assert_null(frame_scene_material(&fs, sc, 10));
    assert_true(m->double_sided && m->alpha_mode == VT_ALPHA_MASK && m->alpha_cutoff == 0.25f);
    assert_true(m->base[2] == 0.7f && m->metallic == 0.2f && m->roughness == 0.8f && m->emissive_strength == 3);
    const vt_texref *r = &m->tex[VT_SLOT_BASE];
    assert_non_null(r->tex);
    assert_true(r->tex->mip[0] == l0 && r->tex->mip[2] == l2 && r->tex->levels == 3 && r->tex->id == 5);
    assert_true(r->wrap_s == VT_WRAP_MIRROR && r->wrap_t == VT_WRAP_CLAMP && r->min_filter == VT_FILTER_LINEAR_MIP_LINEAR);
    assert_true(r->offset[0] == 0.5f && r->scale[1] == 3 && r->rotation == 0.3f);
    assert_null(m->tex[VT_SLOT_EMISSIVE].tex);
    assert_null(m->tex[VT_SLOT_MR].tex);
    char err[256];
    assert_int_equal(vt_material_check(m, err, sizeof err), 0);
    frame_scene_free(&fs);
    /* the sky from the EXR: a view of its floats */
    sc->env.sky_mode = VP_SKY_TEXTURE;
    sc->env.sky_texture = 6;
    sc->env.sky_rotation = 1;
    assert_true(frame_scene_init(&fs, sc));
    assert_true(fs.env_ok && fs.env.sky_mode == VT_SKY_TEXTURE && fs.env.sky_tex && fs.env.sky_tex->hdr == hdr);
    /* both renderers draw it: ground with the material's texture, sky */
    rpair rp;
    rpair_open(&rp);
    const uint32_t W = 48, H = 32;
    float *c = malloc((size_t)W * H * 16), *d = malloc((size_t)W * H * 4);
    assert_true(c && d);
    cull_view v;
    look(&v, (const double[3]){0, 3, 0}, (const double[3]){4, 1, -9}, W, H, 1.2, CULL_DEPTH_GL);
    vt_frame f = {.view = &v, .width = W, .height = H, .env = &fs.env, .rgba = c, .depth = d, .stride = W};
    assert_int_equal(vt_soft_draw(rp.sr, &f, NULL, err, sizeof err), 0);
    if (rp.gr) assert_int_equal(vt_gldraw_draw(rp.gr, &f, NULL, err, sizeof err), 0);
    uint32_t ground = 0;
    for (size_t p = 0; p < (size_t)W * H; p++) ground += d[p] != INFINITY;
    assert_true(ground > 100 && ground < W * H - 100);
    /* the sky's texture gone: the analytic sky rather than no picture */
    idmap_del(&sc->textures, 6);
    frame_scene_free(&fs);
    assert_true(frame_scene_init(&fs, sc));
    assert_true(fs.env_ok && fs.env.sky_mode == VT_SKY_ANALYTIC);
    frame_scene_free(&fs);
    rpair_close(&rp);
    free(c);
    free(d);
    /* the maps' values are this test's: emptied before the scene goes */
    idmap_free(&sc->textures);
    idmap_free(&sc->materials);
    memset(&sc->textures, 0, sizeof sc->textures);
    memset(&sc->materials, 0, sizeof sc->materials);
    scene_free(sc);
    free(sc);
}


/* The environment end to end: ENV_SET to a running daemon, then RENDER
 * (raw, both renderers): a uniform sky of colour x intensity at a fixed
 * EV100 of 5 comes back at that radiance / (1.2 x 2^5) on every pixel
 * looking up (no depth, opaque); with the ground at y = -2 a view looking
 * down sees it at the ray's distance. */
static void test_scene_env_over_the_wire(void **state)
{
    daemon_proc *d = *state;
    vtc_client *c = connect_role(d, VP_ROLE_EDITOR, false);
    vp_env e;
    vp_env_default(&e);
    e.sky_mode = VP_SKY_COLOR;
    e.sky_color[0] = 0.2f, e.sky_color[1] = 0.4f, e.sky_color[2] = 0.8f;
    e.sky_intensity = 1000;
    e.flags = 0;
    e.fog_density = 0;
    e.exposure_mode = VP_EXPOSURE_FIXED;
    e.exposure_ev = 5;
    assert_int_equal(vtc_env_set(c, &e, NULL), VP_OK);
    for (unsigned renderer = VP_RENDERER_SOFT; renderer <= VP_RENDERER_GL; renderer++) {
        vp_render m = {.format = VP_FRAME_RAW, .renderer = (uint8_t)renderer};
        const double eye[3] = {0, 0, 0}, up_at[3] = {0.1, 10, -1}, down_at[3] = {0, -10, -8};
        assert_true(vtc_view_perspective(&m.view, eye, up_at, NULL, 60, 32, 24, 0.1, 100));
        vp_frame f;
        int rc = vtc_render(c, &m, &f);
        if (rc == VP_ERR_UNSUPPORTED) continue; /* no GL here */
        assert_int_equal(rc, VP_OK);
        const float *px = (const float *)f.data, *z = px + 32 * 24 * 4;
        for (size_t i = 0; i < 32 * 24; i++) {
            assert_true(isinf(z[i]) && px[4 * i + 3] == 1.0f);
            for (int k = 0; k < 3; k++) {
                double want = e.sky_color[k] * 1000.0 / (1.2 * 32);
                assert_true(fabs(px[4 * i + k] - want) <= 1e-5 * want);
            }
        }
        vp_env g = e;
        g.flags = VP_ENV_GROUND;
        g.ground_height = -2;
        assert_int_equal(vtc_env_set(c, &g, NULL), VP_OK);
        assert_true(vtc_view_perspective(&m.view, eye, down_at, NULL, 60, 32, 24, 0.1, 100));
        assert_int_equal(vtc_render(c, &m, &f), VP_OK);
        px = (const float *)f.data, z = px + 32 * 24 * 4;
        /* the centre pixel's ray hits y = -2 at w = |(0, -10, -8)| x 2 / 10 along the axis */
        size_t mid = 12 * 32 + 16;
        double w = sqrt(10.0 * 10 + 8 * 8) * 2 / 10;
        assert_true(fabs(z[mid] - w) <= 0.02 * w); /* the pixel centre is half a pixel off the axis */
        assert_true(px[4 * mid] > 0);
        assert_int_equal(vtc_env_set(c, &e, NULL), VP_OK);
    }
    vtc_close(c);
}

/* A texture replaced under its id shows its new pixels in the next frame
 * from both renderers (the GL renderer keeps textures across frames by id
 * and generation: a replacement must not show the old one). A unit quad
 * filling the view, base colour texture only, lit by the sky colour. */
static void test_scene_texture_replaced(void **state)
{
    daemon_proc *d = *state;
    vtc_client *c = connect_role(d, VP_ROLE_EDITOR, false);
    vp_env e;
    vp_env_default(&e);
    e.sky_mode = VP_SKY_COLOR;
    e.sky_color[0] = e.sky_color[1] = e.sky_color[2] = 1;
    e.sun_dir[0] = e.sun_dir[1] = e.sun_dir[2] = 0;
    e.flags = 0;
    e.fog_density = 0;
    e.exposure_mode = VP_EXPOSURE_FIXED;
    e.exposure_ev = 0;
    assert_int_equal(vtc_env_set(c, &e, NULL), VP_OK);
    static const float pos[12] = {-1, -1, 0, 1, -1, 0, 1, 1, 0, -1, 1, 0}, nrm[12] = {0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1};
    static const float uv[8] = {0, 1, 1, 1, 1, 0, 0, 0};
    static const uint32_t idx[6] = {0, 1, 2, 0, 2, 3};
    assert_int_equal(vtc_put_mesh_uv(c, 5, pos, nrm, uv, NULL, 4, idx, 6), VP_OK);
    uint8_t px[2][4 * 4 * 4];
    for (int k = 0; k < 2; k++)
        for (int i = 0; i < 16; i++)
            px[k][4 * i] = k ? 0 : 255, px[k][4 * i + 1] = k ? 255 : 0, px[k][4 * i + 2] = 0, px[k][4 * i + 3] = 255;
    uint8_t *png[2];
    size_t len[2];
    char why[200];
    for (int k = 0; k < 2; k++) assert_int_equal(vt_png_encode(4, 4, px[k], 16, true, 6, &png[k], &len[k], why, sizeof why), 0);
    assert_int_equal(vtc_texture_put(c, 1, VP_TEX_PNG, VP_TEX_SRGB, png[0], len[0], NULL), VP_OK);
    vp_material m = {.id = 1, .base_color = {1, 1, 1, 1}, .roughness = 1, .emissive_strength = 1, .normal_scale = 1};
    for (int k = 0; k < VP_TEX_SLOTS; k++) m.tex[k] = (vp_texref){.scale = {1, 1}, .mag_filter = VP_FILTER_NEAREST};
    m.tex[VP_TEX_BASE].texture = 1;
    assert_int_equal(vtc_material_put(c, &m, 1, NULL), VP_OK);
    vp_entity ent = {.id = 1, .class_id = 5, .material = 1, .flags = VP_ENT_TRANSFORM, .pos = {0, 0, -2},
                     .rot = {0, 0, 0, 1}, .scale = {4, 4, 1}};
    assert_int_equal(vtc_add(c, &ent, 1, NULL, NULL), VP_OK);
    for (int round = 0; round < 2; round++) {
        if (round) assert_int_equal(vtc_texture_put(c, 1, VP_TEX_PNG, VP_TEX_SRGB, png[1], len[1], NULL), VP_OK);
        for (unsigned renderer = VP_RENDERER_SOFT; renderer <= VP_RENDERER_GL; renderer++) {
            vp_render r = {.format = VP_FRAME_RAW, .renderer = (uint8_t)renderer};
            const double eye[3] = {0, 0, 0}, at[3] = {0, 0, -1};
            assert_true(vtc_view_perspective(&r.view, eye, at, NULL, 40, 16, 16, 0.1, 100));
            vp_frame f;
            int rc = vtc_render(c, &r, &f);
            if (rc == VP_ERR_UNSUPPORTED) continue; /* no GL here */
            assert_int_equal(rc, VP_OK);
            const float *o = (const float *)f.data;
            size_t mid = 8 * 16 + 8;
            /* red, then green: the texture's channel; the other only the dielectric's specular (4 %) */
            float want = o[4 * mid + (round ? 1 : 0)], other = o[4 * mid + (round ? 0 : 1)];
            if (!(want > 0 && other <= 0.1f * want))
                fail_msg("round %d renderer %u: r %g g %g b %g", round, renderer, (double)o[4 * mid],
                         (double)o[4 * mid + 1], (double)o[4 * mid + 2]);
        }
    }
    free(png[0]);
    free(png[1]);
    vtc_close(c);
}

const struct CMUnitTest scene_render_tests[] = {
    cmocka_unit_test(test_scene_textured_quad),
    cmocka_unit_test(test_scene_transformed_silhouettes),
    cmocka_unit_test(test_scene_sky_ground_fog),
    cmocka_unit_test(test_scene_analytic_sky),
    cmocka_unit_test(test_scene_default_env),
    cmocka_unit_test(test_scene_gather_lanes),
    cmocka_unit_test(test_scene_bad_input),
    cmocka_unit_test(test_scene_frame_glue),
    DAEMON_TEST(test_scene_env_over_the_wire),
    DAEMON_TEST(test_scene_texture_replaced),
};
const size_t scene_render_tests_count = sizeof scene_render_tests / sizeof scene_render_tests[0];
