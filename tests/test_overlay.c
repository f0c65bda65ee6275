/*
 * test_overlay.c — the commander's overlay (issue 20 item 8): the
 * outline of highlighted instances checked against the box's analytic
 * silhouette in both renderers, icons at their projected positions (and
 * none behind the camera), RENDER's highlight list on the wire, and the
 * daemon's marks drawn into RAW frames while they live.
 */
#include "test_util.h"
#include "test_daemon.h"
#include "vantage.h"
#include "vt_gldraw.h"
#include "vt_overlay.h"
#include "vt_soft.h"

#include <stdio.h>
#include <string.h>
#include <unistd.h>

/* ---- the outline, against the analytic silhouette ---------------------------------- */

/* A top-down orthographic view of the box -16..16 (x) by -12..12 (z) from
 * y = 50, 4 px a metre: screen x is world x, screen up is world -z. */
#define OW 128u
#define OH 96u
#define PPM 4.0
static const double box_lo[3] = {-3.3, 0, -2.1}, box_hi[3] = {4.2, 5, 3.7};
/* a plate above the box's right part, hiding it from the camera */
static const double plate_lo[3] = {1, 8, -4}, plate_hi[3] = {8, 9, 6};

static void ortho_view(cull_view *v)
{
    cull_view_desc d = {.origin = {0, 50, 0}, .depth_mode = CULL_DEPTH_GL, .viewport_w = OW, .viewport_h = OH};
    double p[16], l[16];
    cull_mat_ortho(p, -16, 16, -12, 12, 1, 100, CULL_DEPTH_GL);
    cull_mat_look_dir(l, (const double[3]){0, -1, 0}, (const double[3]){0, 0, -1});
    cull_mat_mul(d.view_proj, p, l);
    assert_int_equal(cull_view_init(v, &d), CULL_OK);
}

/* pixel x of world x, pixel row of world z */
static double px_of_x(double x) { return (x + 16) * PPM; }
static double py_of_z(double z) { return (-z + 12) * PPM; }

/* The distance of pixel (x, y)'s centre from the box's projected
 * rectangle's boundary (inside or out). */
static double rect_dist(uint32_t x, uint32_t y)
{
    double X0 = px_of_x(box_lo[0]), X1 = px_of_x(box_hi[0]), Y0 = py_of_z(box_hi[2]), Y1 = py_of_z(box_lo[2]);
    double cx = x + 0.5, cy = y + 0.5;
    if (cx >= X0 && cx <= X1 && cy >= Y0 && cy <= Y1) return fmin(fmin(cx - X0, X1 - cx), fmin(cy - Y0, Y1 - cy));
    return hypot(fmax(fmax(X0 - cx, 0), cx - X1), fmax(fmax(Y0 - cy, 0), cy - Y1));
}

typedef struct drawer {
    vt_soft *soft;
    vt_gldraw *gl;
} drawer;

/* Draws the box (instance 0) and the plate (1) over a sunlit ground,
 * with overlay ov (NULL: none), into rgba (OW x OH). */
static void draw_scene(const drawer *dr, const vt_overlay *ov, const vt_icon *icons, uint32_t nicons, float *rgba)
{
    static float depth[OW * OH];
    cull_view v;
    ortho_view(&v);
    vt_instance in[2] = {{.albedo = {0.6f, 0.2f, 0.2f}}, {.albedo = {0.2f, 0.5f, 0.2f}}};
    memcpy(in[0].bmin, box_lo, sizeof box_lo);
    memcpy(in[0].bmax, box_hi, sizeof box_hi);
    memcpy(in[1].bmin, plate_lo, sizeof plate_lo);
    memcpy(in[1].bmax, plate_hi, sizeof plate_hi);
    float s = 1 / sqrtf(0.3f * 0.3f + 0.9f * 0.9f + 0.3f * 0.3f);
    vt_env env = {.sun_dir = {0.3f * s, 0.9f * s, 0.3f * s}, .sun = {2, 2, 2}, .sky_mode = VT_SKY_COLOR,
                  .sky = {0.3f, 0.4f, 0.6f}, .ground = true, .ground_albedo = {0.3f, 0.3f, 0.3f}};
    vt_overlay o = ov ? *ov : (vt_overlay){0};
    o.icons = icons;
    o.nicons = nicons;
    vt_frame f = {.view = &v, .width = OW, .height = OH, .meshes = &vt_mesh_box, .nmesh = 1, .inst = in, .ninst = 2,
                  .env = &env, .rgba = rgba, .depth = depth, .stride = OW,
                  .overlay = ov || nicons ? &o : NULL};
    char err[256];
    int rc = dr->gl ? vt_gldraw_draw(dr->gl, &f, NULL, err, sizeof err) : vt_soft_draw(dr->soft, &f, NULL, err, sizeof err);
    if (rc) fail_msg("draw: %s", err);
}

static bool px_differs(const float *a, const float *b)
{
    for (int k = 0; k < 3; k++)
        if (fabsf(a[k] - b[k]) > 1e-6f) return true;
    return false;
}

/* vt_overlay.c's default outline colours: a viewer's highlight, the
   shared selection */
static const float outline_col[VT_OUTLINES][3] = {{4.0f, 0.6f, 0.0f}, {0.0f, 0.6f, 4.0f}};

/* The outline pixels (those the highlight changed) lie within 1 px of the
 * box's projected silhouette, and every pixel whose centre is within
 * 0.5 px of it is one (a 2 px band: 1 px each side, vt_overlay.h). Where
 * the box is seen they are amber; under the plate, 45 % amber over the
 * picture (the hidden weight). */
static void check_outline(const drawer *dr, const char *name, bool as_extra, int group)
{
    const float *amber = outline_col[group];
    static float base[OW * OH * 4], hl[OW * OH * 4];
    draw_scene(dr, NULL, NULL, 0, base);
    uint32_t idx = 0;
    /* the box as an outlined instance not drawn (the daemon's culled
       highlight): the same geometry, the same band */
    vt_instance box = {.place = VT_PLACE_BOUNDS};
    memcpy(box.bmin, box_lo, sizeof box_lo);
    memcpy(box.bmax, box_hi, sizeof box_hi);
    vt_overlay ov = {0};
    ov.outline[group] = as_extra ? (vt_outline){.extra = &box, .nextra = 1} : (vt_outline){.hl = &idx, .nhl = 1};
    draw_scene(dr, &ov, NULL, 0, hl);
    uint32_t band = 0, bright = 0, dim = 0;
    /* the plate's left edge x = 1 on screen; 2 px either side of it a
       band pixel may see either side of the plate's edge */
    double plate_x = px_of_x(plate_lo[0]);
    for (uint32_t y = 0; y < OH; y++)
        for (uint32_t x = 0; x < OW; x++) {
            size_t i = ((size_t)y * OW + x) * 4;
            bool out = px_differs(&base[i], &hl[i]);
            double d = rect_dist(x, y);
            if (out && d > 1.0 + 1e-9) fail_msg("%s: outline pixel (%u, %u) is %.3f px from the silhouette", name, x, y, d);
            if (!out && d <= 0.5) fail_msg("%s: pixel (%u, %u), %.3f px from the silhouette, not outlined", name, x, y, d);
            if (!out) continue;
            band++;
            double cx = x + 0.5;
            /* the outline is written after exposure: its values exactly
               (up to float blending: 1e-5 relative) */
            for (int k = 0; k < 3; k++) {
                float want = cx < plate_x - 2 ? amber[k] : cx > plate_x + 2 ? 0.55f * base[i + k] + 0.45f * amber[k] : NAN;
                if (isnan(want)) continue;
                if (fabsf(hl[i + k] - want) > 1e-5f * (1 + want))
                    fail_msg("%s: (%u, %u) channel %d is %g, expected %g", name, x, y, k, hl[i + k], want);
            }
            bright += cx < plate_x - 2;
            dim += cx > plate_x + 2;
        }
    /* the rectangle is 30 x 23.2 px: its ring 2 px wide is about 2 x 106 px */
    assert_true(band > 190 && band < 240);
    assert_true(bright > 50 && dim > 50);
    fprintf(stderr, "%s outline: %u px (%u seen, %u hidden), all within 1 px of the silhouette\n", name, band, bright,
            dim);
}

static void test_outline_soft(void **state)
{
    (void)state;
    drawer dr = {0};
    assert_int_equal(vt_soft_create(NULL, 1, &dr.soft), 0);
    check_outline(&dr, "soft", false, VT_OUTLINE_HIGHLIGHT);
    check_outline(&dr, "soft (extra)", true, VT_OUTLINE_HIGHLIGHT);
    check_outline(&dr, "soft (shared selection)", false, VT_OUTLINE_SELECTION);
    vt_soft_destroy(dr.soft);
}

static void test_outline_gl(void **state)
{
    (void)state;
    char err[512];
    vt_gl *g;
    if (vt_gl_open(&g, NULL, err, sizeof err) != 0) {
        fprintf(stderr, "no GL here, outline skipped: %s\n", err);
        skip();
    }
    drawer dr = {0};
    assert_int_equal(vt_gldraw_create(g, &dr.gl, err, sizeof err), 0);
    check_outline(&dr, "gl", false, VT_OUTLINE_HIGHLIGHT);
    check_outline(&dr, "gl (shared selection, extra)", true, VT_OUTLINE_SELECTION);
    vt_gldraw_destroy(dr.gl);
    vt_gl_close(g);
}

/* Icons: the kind's colour at the projected centre, a dark halo around
 * it, nothing past it, and nothing for a position behind the camera
 * (above y = 50 here) even where its mirrored projection would land. */
static void test_icons_soft(void **state)
{
    (void)state;
    drawer dr = {0};
    assert_int_equal(vt_soft_create(NULL, 1, &dr.soft), 0);
    static float base[OW * OH * 4], ic[OW * OH * 4];
    draw_scene(&dr, NULL, NULL, 0, base);
    vt_icon icons[2] = {{.pos = {-10, 0, 8}, .kind = VT_ICON_PING}, {.pos = {10, 60, -8}, .kind = VT_ICON_PING}};
    draw_scene(&dr, NULL, icons, 2, ic);
    const float ping[3] = {4.0f, 0.15f, 0.0f}; /* vt_overlay.c's default ping colour */
    /* the centre: (-10, 8) -> pixel (24, 16) exactly; the pixel whose
       corner is there is 0.7 px from it, inside the 4 px diamond */
    double cx = px_of_x(-10), cy = py_of_z(8);
    size_t c = ((size_t)(cy - 0.5) * OW + (size_t)(cx - 0.5)) * 4;
    for (int k = 0; k < 3; k++) assert_float_equal(ic[c + k], ping[k], 1e-5);
    /* radius max(4, 7 * 96 / 720) = 4 px, halo 1.5 px: at 4.5 px along an
       axis (just past the diamond) the halo darkens; at 8 px nothing */
    size_t h = ((size_t)(cy - 0.5) * OW + (size_t)(cx + 4.5 - 0.5)) * 4;
    for (int k = 0; k < 3; k++) assert_true(ic[h + k] < base[h + k] * 0.6f);
    size_t far = ((size_t)(cy - 0.5) * OW + (size_t)(cx + 8 - 0.5)) * 4;
    assert_false(px_differs(&ic[far], &base[far]));
    /* behind the camera: (10, -8) projects to pixel (104, 80); nothing */
    uint32_t changed = 0;
    for (uint32_t y = 60; y < OH; y++)
        for (uint32_t x = 84; x < OW; x++) changed += px_differs(&ic[((size_t)y * OW + x) * 4], &base[((size_t)y * OW + x) * 4]);
    assert_int_equal(changed, 0);
    /* bad overlays are refused before drawing */
    cull_view v;
    ortho_view(&v);
    float rgba[4], depth[1];
    uint32_t past = 1;
    vt_icon nan_icon = {.pos = {NAN, 0, 0}};
    vt_overlay bad[4] = {{.outline[0] = {.hl = &past, .nhl = 1}},
                         {.icons = &nan_icon, .nicons = 1},
                         {.outline[0] = {.color = {-1, 0, 0}}},
                         {.outline[1] = {.hl = &past, .nhl = 1}}};
    for (int i = 0; i < 4; i++) {
        vt_frame f = {.view = &v, .width = 1, .height = 1, .meshes = &vt_mesh_box, .nmesh = 1,
                      .inst = &(vt_instance){.bmax = {1, 1, 1}}, .ninst = 1, .rgba = rgba, .depth = depth,
                      .stride = 1, .overlay = &bad[i]};
        char err[200];
        assert_int_equal(vt_soft_draw(dr.soft, &f, NULL, err, sizeof err), VT_ERR_INVALID);
        assert_non_null(strstr(err, "overlay"));
    }
    vt_soft_destroy(dr.soft);
}

/* ---- RENDER's highlight list on the wire -------------------------------------------- */

static void test_render_highlight_wire(void **state)
{
    (void)state;
    static uint8_t buf[1024];
    vp_render m = {.format = VP_FRAME_JPEG, .quality = 80, .nhighlight = 3, .highlight = {7, 0x123456789abcdefull, 9}};
    double eye[3] = {0, 10, 0}, at[3] = {0, 0, 0}, up[3] = {0, 0, -1};
    assert_true(vtc_view_perspective(&m.view, eye, at, up, 60, 64, 48, 0.5, 100));
    vp_writer w;
    vp_writer_init(&w, buf, sizeof buf);
    vp_enc_render(&w, 5, &m);
    assert_int_equal(w.len, VP_HEADER_SIZE + VP_RENDER_SIZE);
    uint8_t *p = buf + VP_HEADER_SIZE;
    vp_render r;
    assert_int_equal(vp_dec_render(p, VP_RENDER_SIZE, &r), VP_OK);
    assert_int_equal(r.nhighlight, 3);
    assert_true(r.highlight[1] == 0x123456789abcdefull && r.highlight[2] == 9 && r.highlight[3] == 0);
    /* the count at 168, the ids from 176 (PROTOCOL.md) */
    assert_int_equal(p[168], 3);
    assert_int_equal(p[176], 7);
    /* nine ids: COUNT; an id past the count: INVALID; a pad byte: INVALID */
    p[168] = 9;
    assert_int_equal(vp_dec_render(p, VP_RENDER_SIZE, &r), VP_ERR_COUNT);
    p[168] = 2;
    assert_int_equal(vp_dec_render(p, VP_RENDER_SIZE, &r), VP_ERR_INVALID);
    p[168] = 3;
    p[170] = 1;
    assert_int_equal(vp_dec_render(p, VP_RENDER_SIZE, &r), VP_ERR_INVALID);
    p[170] = 0;
    assert_int_equal(vp_dec_render(p, VP_RENDER_SIZE, &r), VP_OK);
    /* FRAME_SUBSCRIBE carries the same, max_fps and view_seq after it */
    vp_frame_sub fs = {.r = m, .max_fps = 30, .view_seq = 4}, gs;
    vp_writer_init(&w, buf, sizeof buf);
    vp_enc_frame_sub(&w, 6, &fs);
    assert_int_equal(w.len, VP_HEADER_SIZE + VP_FRAME_SUB_SIZE);
    assert_int_equal(vp_dec_frame_sub(buf + VP_HEADER_SIZE, VP_FRAME_SUB_SIZE, &gs), VP_OK);
    assert_true(gs.r.nhighlight == 3 && gs.r.highlight[1] == 0x123456789abcdefull && gs.max_fps == 30 &&
                gs.view_seq == 4);
}

/* ---- the daemon: marks drawn into frames ----------------------------------------------- */

#define DW 96u
#define DH 72u

/* The pixel (x right, row up) vp_view v puts world point p at, in
 * double from the view's matrix; false behind the eye. */
static bool project(const vp_view *v, const double p[3], double *x, double *y)
{
    double q[4] = {p[0] - v->origin[0], p[1] - v->origin[1], p[2] - v->origin[2], 1}, c[4] = {0};
    for (int r = 0; r < 4; r++)
        for (int k = 0; k < 4; k++) c[r] += v->view_proj[k * 4 + r] * q[k];
    if (c[3] <= 0) return false;
    *x = (c[0] / c[3] + 1) * 0.5 * v->viewport_w;
    *y = (c[1] / c[3] + 1) * 0.5 * v->viewport_h;
    return true;
}

/* The RGBA of pixel (x, y) of a RAW frame, rendered now. */
static void raw_frame(vtc_client *c, const vp_render *m, float *rgba)
{
    vp_frame f;
    assert_int_equal(vtc_render(c, m, &f), VP_OK);
    assert_int_equal(f.data_len, DW * DH * 20);
    memcpy(rgba, f.data, (size_t)DW * DH * 16);
}

static void test_marks_in_frames(void **state)
{
    daemon_proc *d = *state;
    vtc_client *cmd = connect_role(d, VP_ROLE_EDITOR, false), *viewer = connect_role(d, VP_ROLE_VIEWER, true);
    /* a block to highlight (and an id that names nothing: ignored) */
    vp_entity e = {.id = 42, .aabb = {-2, 0, -2, 2, 3, 2}};
    uint32_t hnd;
    assert_int_equal(vtc_add(cmd, &e, 1, &hnd, NULL), VP_OK);
    vp_render m = {.format = VP_FRAME_RAW, .renderer = VP_RENDERER_SOFT};
    double eye[3] = {0, 40, 0}, at[3] = {0, 0, 0}, up[3] = {0, 0, -1};
    assert_true(vtc_view_perspective(&m.view, eye, at, up, 60, DW, DH, 1, 200));
    static float base[DW * DH * 4], now[DW * DH * 4];
    raw_frame(viewer, &m, base);
    /* a ping in view, and one behind the eye where the mirrored
       projection of a ground point at (-10, 0, 8) would land */
    const double seen[3] = {10, 0, -8}, mirror[3] = {-10, 0, 8}, behind[3] = {10, 80, -8};
    vp_mark a = {.pos = {seen[0], seen[1], seen[2]}, .kind = 0, .ttl_ms = 2000};
    vp_mark b = {.pos = {behind[0], behind[1], behind[2]}, .kind = 0, .ttl_ms = 2000};
    assert_int_equal(vtc_mark(cmd, &a, NULL), VP_OK);
    assert_int_equal(vtc_mark(cmd, &b, NULL), VP_OK);
    m.nhighlight = 2;
    m.highlight[0] = 999; /* no such entity: nothing, no error */
    m.highlight[1] = 42;
    raw_frame(viewer, &m, now);
    double x, y;
    assert_true(project(&m.view, seen, &x, &y));
    /* the 4 px diamond (radius max(4, 7 * 72 / 720)) in ping orange
       around the projected point: the 2 x 2 pixels about it */
    const float ping[3] = {4.0f, 0.15f, 0.0f}; /* vt_overlay.c's default ping colour */
    for (int dy = -1; dy <= 0; dy++)
        for (int dx = -1; dx <= 0; dx++) {
            size_t i = ((size_t)(floor(y) + dy) * DW + (size_t)(floor(x) + dx)) * 4;
            for (int k = 0; k < 3; k++) assert_float_equal(now[i + k], ping[k], 1e-4);
        }
    /* nothing drawn at the behind-the-eye mark's mirror point */
    assert_true(project(&m.view, mirror, &x, &y));
    for (int dy = -6; dy <= 6; dy++)
        for (int dx = -6; dx <= 6; dx++) {
            size_t i = ((size_t)(floor(y) + dy) * DW + (size_t)(floor(x) + dx)) * 4;
            for (int k = 0; k < 3; k++) assert_float_equal(now[i + k], base[i + k], 1e-6);
        }
    /* the highlighted block's outline: amber pixels, around its top face */
    uint32_t amber_px = 0;
    for (size_t i = 0; i < (size_t)DW * DH; i++) amber_px += fabsf(now[4 * i] - 4.0f) < 1e-4f && fabsf(now[4 * i + 1] - 0.6f) < 1e-4f;
    assert_true(amber_px > 20);
    /* the marks expire with their ttl: gone from a frame after it */
    usleep(2300 * 1000);
    m.nhighlight = 0;
    memset(m.highlight, 0, sizeof m.highlight);
    raw_frame(viewer, &m, now);
    assert_true(project(&m.view, seen, &x, &y));
    size_t i = ((size_t)floor(y) * DW + (size_t)floor(x)) * 4;
    for (int k = 0; k < 3; k++) assert_float_equal(now[i + k], base[i + k], 1e-6);
    vtc_close(cmd);
    vtc_close(viewer);
}

/* A highlighted entity the occlusion culling hid (a crate behind a wall
 * with an occluder) is outlined all the same, by its box, dim (45 %
 * golden over the wall) and only around where its box projects. */
static void test_highlight_hidden(void **state)
{
    daemon_proc *d = *state;
    vtc_client *ed = connect_role(d, VP_ROLE_EDITOR, false), *viewer = connect_role(d, VP_ROLE_VIEWER, true);
    vp_entity e[2] = {{.id = 10, .aabb = {-10, 0, -0.5, 10, 8, 0.5}}, {.id = 20, .aabb = {-1, 1, 5, 1, 3, 7}}};
    uint32_t hs[2];
    assert_int_equal(vtc_add(ed, e, 2, hs, NULL), VP_OK);
    /* the wall's face towards the camera, both windings */
    const double o[3] = {0, 0, -0.5};
    const float quad[36] = {-10, 0, 0, 10, 0, 0, 10, 8, 0, -10, 0, 0, 10, 8, 0, -10, 8, 0,
                            -10, 0, 0, 10, 8, 0, 10, 0, 0, -10, 0, 0, -10, 8, 0, 10, 8, 0};
    assert_int_equal(vtc_put_occluder(ed, 10, o, quad, 4), VP_OK);
    vp_render m = {.format = VP_FRAME_RAW, .renderer = VP_RENDERER_SOFT};
    double eye[3] = {0, 4, -30}, at[3] = {0, 4, 0}, up[3] = {0, 1, 0};
    assert_true(vtc_view_perspective(&m.view, eye, at, up, 60, DW, DH, 0.5, 200));
    static float base[DW * DH * 4], hl[DW * DH * 4];
    raw_frame(viewer, &m, base);
    m.nhighlight = 1;
    m.highlight[0] = 20;
    vp_frame f;
    assert_int_equal(vtc_render(viewer, &m, &f), VP_OK);
    assert_int_equal(f.visible, 1); /* the wall only: the crate was culled */
    memcpy(hl, f.data, sizeof hl);
    /* the crate's box on screen, from its 8 corners */
    double x0 = 1e9, x1 = -1e9, y0 = 1e9, y1 = -1e9;
    for (int c = 0; c < 8; c++) {
        double p[3] = {e[1].aabb[c & 1 ? 3 : 0], e[1].aabb[c & 2 ? 4 : 1], e[1].aabb[c & 4 ? 5 : 2]}, x, y;
        assert_true(project(&m.view, p, &x, &y));
        x0 = fmin(x0, x), x1 = fmax(x1, x), y0 = fmin(y0, y), y1 = fmax(y1, y);
    }
    uint32_t changed = 0;
    for (uint32_t y = 0; y < DH; y++)
        for (uint32_t x = 0; x < DW; x++) {
            size_t i = ((size_t)y * DW + x) * 4;
            if (!px_differs(&base[i], &hl[i])) continue;
            changed++;
            /* within the band's 1 px of the projected box */
            assert_true(x + 0.5 >= x0 - 1 && x + 0.5 <= x1 + 1 && y + 0.5 >= y0 - 1 && y + 0.5 <= y1 + 1);
            for (int k = 0; k < 3; k++)
                assert_float_equal(hl[i + k], 0.55f * base[i + k] + 0.45f * outline_col[0][k], 1e-4 * (1 + outline_col[0][k]));
        }
    /* the box is about 4.6 x 4.6 px (2 m at 35 m): its band, a ring 2 px wide */
    assert_true(changed >= 12);
    vtc_close(ed);
    vtc_close(viewer);
}

/* A stream redraws when a mark arrives (the scene's epoch did not move)
 * and again when it expires; each frame shows the marks live then. */
static void test_mark_redraws_stream(void **state)
{
    daemon_proc *d = *state;
    vtc_client *cmd = connect_role(d, VP_ROLE_COMMANDER, false), *viewer = connect_role(d, VP_ROLE_VIEWER, true);
    vp_frame_sub sub = {.r = {.format = VP_FRAME_RAW, .renderer = VP_RENDERER_SOFT}, .max_fps = 60};
    double eye[3] = {0, 40, 0}, at[3] = {0, 0, 0}, up[3] = {0, 0, -1}, spot[3] = {10, 0, -8};
    assert_true(vtc_view_perspective(&sub.r.view, eye, at, up, 60, DW, DH, 1, 200));
    double x, y;
    assert_true(project(&sub.r.view, spot, &x, &y));
    /* the select square's ring: its right side at 0.8 r = 3.2 px from the
       centre, fully covered within 0.5 px of that (r = 4, the ring r/4 but
       at least 1 px thick either side: vt_overlay.c): the pixel whose
       centre is 2.7..3.7 px right of it, in cyan (0, 0.6, 4) */
    size_t i = ((size_t)floor(y) * DW + (size_t)floor(x + 3.2)) * 4;
    assert_int_equal(vtc_frame_subscribe(viewer, &sub), VP_OK);
    static float f0[DW * DH * 4];
    vp_frame f;
    assert_int_equal(vtc_wait_frame(viewer, &f, 10000), VP_OK);
    memcpy(f0, f.data, sizeof f0);
    vp_mark a = {.pos = {spot[0], spot[1], spot[2]}, .kind = 1, .ttl_ms = 1500};
    assert_int_equal(vtc_mark(cmd, &a, NULL), VP_OK);
    assert_int_equal(vtc_wait_frame(viewer, &f, 10000), VP_OK);
    float px[4];
    memcpy(px, f.data + i * 4, sizeof px);
    assert_float_equal(px[2], 4.0f, 1e-4);
    assert_float_equal(px[1], 0.6f, 1e-4);
    /* expired: a next frame comes unasked, without the ring (a stream's
       eye adaptation may move the rest of the picture: only the ring is
       compared) */
    assert_int_equal(vtc_wait_frame(viewer, &f, 10000), VP_OK);
    memcpy(px, f.data + i * 4, sizeof px);
    assert_true(fabsf(px[2] - 4.0f) > 0.1f || fabsf(px[1] - 0.6f) > 0.1f);
    assert_float_equal(px[2], f0[i + 2], 1e-3 + 0.5 * f0[i + 2]);
    vtc_close(cmd);
    vtc_close(viewer);
}

/* The shared selection (SELECT / SELECTED): an editor's selection
 * reaches every selection subscriber (the current one at once on
 * subscribing), a viewer cannot set it, a bad one changes nothing, and
 * frames outline it in cyan (not with VP_RENDER_NO_SELECTION); a stream
 * redraws when it changes. */
static uint32_t cyan_px(const float *rgba)
{
    uint32_t n = 0;
    for (size_t i = 0; i < (size_t)DW * DH; i++)
        n += fabsf(rgba[4 * i + 2] - 4.0f) < 1e-4f && fabsf(rgba[4 * i + 1] - 0.6f) < 1e-4f && rgba[4 * i] < 1e-4f;
    return n;
}

static void expect_selected(vtc_client *c, uint64_t serial, uint32_t client, const uint64_t *ids, uint32_t n)
{
    vp_selected sel;
    assert_int_equal(vtc_wait_selected(c, &sel, 5000), VP_OK);
    assert_int_equal(sel.serial, serial);
    assert_int_equal(sel.client_id, client);
    assert_int_equal(sel.count, n);
    for (uint32_t i = 0; i < n; i++) assert_true(vp_id_at(sel.ids, sel.count, i) == ids[i]);
}

static void test_selection_shared(void **state)
{
    daemon_proc *d = *state;
    vtc_client *ed = connect_role(d, VP_ROLE_EDITOR, false), *viewer = connect_role(d, VP_ROLE_VIEWER, true);
    vp_entity e = {.id = 42, .aabb = {-2, 0, -2, 2, 3, 2}};
    uint32_t hnd;
    assert_int_equal(vtc_add(ed, &e, 1, &hnd, NULL), VP_OK);
    /* subscribing: the selection as it stands (none yet) */
    assert_int_equal(vtc_subscribe(viewer, VP_EVENT_SELECTION), VP_OK);
    expect_selected(viewer, 0, 0, NULL, 0);
    /* a viewer may not set it */
    uint64_t ids[2] = {42, 7777}; /* 7777 names nothing: kept, outlines nothing */
    assert_int_equal(vtc_select(viewer, ids, 2, NULL), VP_ERR_AUTH);
    uint32_t sent = 0;
    assert_int_equal(vtc_select(ed, ids, 2, &sent), VP_OK);
    assert_int_equal(sent, 1);
    expect_selected(viewer, 1, vtc_server(ed)->client_id, ids, 2);
    /* refused ones change nothing: a 0, an id twice */
    uint64_t zero[2] = {42, 0}, twice[3] = {5, 42, 5};
    assert_int_equal(vtc_select(ed, zero, 2, NULL), VP_ERR_INVALID);
    assert_non_null(strstr(vtc_last_error(ed)->msg, "id 1 is 0"));
    assert_int_equal(vtc_select(ed, twice, 3, NULL), VP_ERR_DUPLICATE);
    assert_non_null(strstr(vtc_last_error(ed)->msg, "id 5 is selected twice"));
    vtc_client *late = connect_role(d, VP_ROLE_COMMANDER, true);
    assert_int_equal(vtc_subscribe(late, VP_EVENT_SELECTION), VP_OK);
    expect_selected(late, 1, vtc_server(ed)->client_id, ids, 2);
    /* frames: the block outlined in cyan; not when the request opts out */
    vp_render m = {.format = VP_FRAME_RAW, .renderer = VP_RENDERER_SOFT};
    double eye[3] = {0, 40, 0}, at[3] = {0, 0, 0}, up[3] = {0, 0, -1};
    assert_true(vtc_view_perspective(&m.view, eye, at, up, 60, DW, DH, 1, 200));
    static float now[DW * DH * 4];
    raw_frame(late, &m, now);
    uint32_t outlined = cyan_px(now);
    assert_true(outlined > 20);
    m.flags = VP_RENDER_NO_SELECTION;
    raw_frame(late, &m, now);
    assert_int_equal(cyan_px(now), 0);
    /* a stream redraws when the selection changes (cleared here) */
    vp_frame_sub sub = {.r = m, .max_fps = 60};
    sub.r.flags = 0;
    assert_int_equal(vtc_frame_subscribe(late, &sub), VP_OK);
    vp_frame f;
    assert_int_equal(vtc_wait_frame(late, &f, 10000), VP_OK);
    assert_int_equal(cyan_px((const float *)(const void *)f.data), outlined);
    assert_int_equal(vtc_select(ed, NULL, 0, &sent), VP_OK);
    assert_int_equal(sent, 2);
    assert_int_equal(vtc_wait_frame(late, &f, 10000), VP_OK);
    assert_int_equal(cyan_px((const float *)(const void *)f.data), 0);
    expect_selected(viewer, 2, vtc_server(ed)->client_id, NULL, 0);
    vtc_close(ed);
    vtc_close(viewer);
    vtc_close(late);
}

const struct CMUnitTest overlay_tests[] = {
    cmocka_unit_test(test_outline_soft),
    cmocka_unit_test(test_outline_gl),
    cmocka_unit_test(test_icons_soft),
    cmocka_unit_test(test_render_highlight_wire),
    DAEMON_TEST(test_marks_in_frames),
    DAEMON_TEST(test_mark_redraws_stream),
    DAEMON_TEST(test_highlight_hidden),
    DAEMON_TEST(test_selection_shared),
};
const size_t overlay_tests_count = sizeof overlay_tests / sizeof overlay_tests[0];
