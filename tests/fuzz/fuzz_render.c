/*
 * fuzz_render.c — libFuzzer target for the software renderer
 * (render/vt_soft.c, through vt_soft_render as the daemon's RENDER and
 * frame streams call it), and, built as fuzz_render_gl.c, for the GL path
 * (render/vt_gldraw.c on vt_egl.c and vt_gl_*.c) where an EGL context can be made; without one
 * every input returns at once (a note on stderr, once).
 *
 * The input (fuzz_geom.h decodes numbers, views and lights): a header byte,
 * the frame size (1..64 a side, so one execution is fast), one view
 * (cull_view_init must accept it, as the daemon's would), up to 4 instances
 * of the unit box or of a mesh from the bytes (up to 12 vertices, 8
 * triangles, degenerate ones and normals of any length included; checked
 * with vt_mesh_check as the daemon does before it keeps a mesh), stretched
 * onto boxes from the bytes, and up to 4 lights with colours and cones.
 * Then the scene model (issue 19), from the bytes after those: an
 * environment (sun, sky mode, ground, fog, exposure: any values, the
 * out-of-range ones included), a material with a 4x4 base texture (its
 * sampler, KHR transform, alpha mode, double-sided), UVs and tangents for
 * the mesh, and per instance a transform (position, quaternion of any
 * length, scales of any sign, zeros) and the material or none.
 * Checked:
 *   1. vt_*_render returns 0, or VT_ERR_INVALID with a message and the caller's
 *      buffers untouched (the daemon answers INVALID with it);
 *   2. drawn frames have alpha 0 or 1 (0..1 under an overlay's outline),
 *      colours that are not NaN, and a depth per pixel that is INFINITY
 *      (nothing) or not NaN.
 * With header bit 5, an overlay from the bytes (vt_overlay.h: both
 * outlines, with instance indices past the frame's and boxes of any
 * bounds, icons anywhere, colours of any sign). The software build also,
 * as the daemon's dynamic resolution does: with bit 6, the drawn frame in
 * bytes, scaled to a size from the bytes (1..96 a side, up or down;
 * vt_image_resize_rgba8), every channel of the result within the
 * picture's range of that channel (a bilinear blend cannot leave it); with
 * bit 7, the frame's cancel word set: VT_ERR_CANCELLED, or VT_ERR_INVALID
 * for a frame refused before any pass.
 * ASan and UBSan catch the rest (issue 18: a 1e30 term in the view
 * overflowed an int32 at the vertex snap). A broken property calls abort().
 */
#include "culling.h"
#include "fuzz_geom.h"
#include "vt_image.h"
#include "vt_overlay.h"
#include "vt_soft.h"
#ifdef FUZZ_RENDER_GL
#include "vt_gl.h"
#include "vt_gldraw.h"
#endif

#define FUZZ_NAME "fuzz_render"
#include "fuzz_check.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { MAX_W = 64, MAX_INST = 4, MAX_LIGHTS = 4, MAX_MV = 12, MAX_MT = 8 };

/* The scene model's inputs from the rest of the bytes. */
static void scene_model(fz *f, vt_env *env, bool *env_on, vt_material *mat, vt_texview *tex, uint8_t *texels,
                        const uint8_t **lv, float *uv, float *tan, uint32_t nv, vt_instance *in, uint32_t ni)
{
    uint8_t e = fz_u8(f);
    *env_on = e & 1;
    *env = (vt_env){.sky_mode = (uint8_t)((e >> 1) % 4), .ground = (e & 8) != 0, .exposure_mode = (uint8_t)((e >> 4) % 3)};
    for (int a = 0; a < 3; a++) {
        env->sun_dir[a] = (float)fz_num(f, 1);
        env->sun[a] = (float)fabs(fz_num(f, 1e5));
        env->sky[a] = (float)fabs(fz_num(f, 1e4));
        env->ground_albedo[a] = (float)fabs(fz_num(f, 1));
        env->fog_color[a] = (float)fabs(fz_num(f, 1));
    }
    env->turbidity = (float)fz_num(f, 10);
    env->ground_height = fz_num(f, 30);
    env->fog_density = (float)fz_num(f, 0.1);
    env->fog_falloff = (float)fz_num(f, 1);
    env->exposure_ev = (float)fz_num(f, 20);
    env->exposure_comp = (float)fz_num(f, 5);
    env->sky_rotation = (float)fz_num(f, 3);
    uint8_t m = fz_u8(f);
    *mat = (vt_material){.metallic = (float)fz_num(f, 1), .roughness = (float)fz_num(f, 1),
                         .emissive_strength = (float)fabs(fz_num(f, 10)), .normal_scale = (float)fz_num(f, 2),
                         .alpha_mode = (uint8_t)(m % 3), .alpha_cutoff = (float)fz_num(f, 1),
                         .double_sided = (m & 4) != 0};
    for (int a = 0; a < 4; a++) mat->base[a] = (float)fabs(fz_num(f, 1));
    for (int a = 0; a < 3; a++) mat->emissive[a] = (float)fabs(fz_num(f, 1));
    /* a 4x4 texture with 3 levels (4, 2, 1), or a float one (for the sky) */
    for (int i = 0; i < 4 * (16 + 4 + 1); i++) texels[i] = fz_u8(f);
    lv[0] = texels, lv[1] = texels + 64, lv[2] = texels + 80;
    *tex = (vt_texview){.w = 4, .h = 4, .levels = 1 + fz_u8(f) % 4, .mip = lv, .id = 0};
    vt_texref r = {.tex = (m & 8) ? tex : NULL, .wrap_s = fz_u8(f) % 4, .wrap_t = fz_u8(f) % 4,
                   .min_filter = fz_u8(f) % 7, .mag_filter = fz_u8(f) % 3, .rotation = (float)fz_num(f, 3)};
    for (int a = 0; a < 2; a++) {
        r.offset[a] = (float)fz_num(f, 2);
        r.scale[a] = (float)fz_num(f, 2);
    }
    mat->tex[(m >> 4) % VT_SLOTS] = r;
    for (uint32_t i = 0; i < 2 * nv; i++) uv[i] = (float)fz_num(f, 2);
    for (uint32_t i = 0; i < 4 * nv; i++) tan[i] = (float)fz_num(f, 1);
    for (uint32_t i = 0; i < ni; i++) {
        uint8_t t = fz_u8(f);
        if (t & 1) in[i].mat = mat;
        if (!(t & 2)) continue;
        in[i].place = (t & 4) ? (uint8_t)(t >> 3) : VT_PLACE_TRS;
        for (int a = 0; a < 3; a++) {
            in[i].pos[a] = fz_num(f, 30);
            in[i].scale[a] = (float)fz_num(f, 3);
        }
        for (int a = 0; a < 4; a++) in[i].rot[a] = (float)fz_num(f, 1);
        /* most quaternions from the bytes are not unit: half of them are
           made so, to reach the drawing */
        double q2 = 0;
        for (int a = 0; a < 4; a++) q2 += (double)in[i].rot[a] * in[i].rot[a];
        if ((t & 64) && q2 > 0 && isfinite(q2))
            for (int a = 0; a < 4; a++) in[i].rot[a] = (float)(in[i].rot[a] / sqrt(q2));
    }
}

#ifdef FUZZ_RENDER_GL
/* one context for the process (opening one costs tens of ms) */
static vt_gldraw *renderer(void)
{
    static int tried;
    static vt_gl *g;
    static vt_gldraw *r;
    if (!tried) {
        tried = 1;
        char err[512];
        if (vt_gl_open(&g, NULL, err, sizeof err) != 0 || vt_gldraw_create(g, &r, err, sizeof err) != 0) {
            fprintf(stderr, "fuzz_render_gl: no GL context (%s): every input is skipped\n", err);
            r = NULL;
        }
    }
    return r;
}
#else
static vt_soft *renderer(void)
{
    static vt_soft *r;
    if (!r && vt_soft_create(NULL, 1, &r) != 0) abort();
    return r;
}
#endif

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fz f = {data, size};
    if (!renderer()) return 0;
    uint8_t head = fz_u8(&f);
    uint32_t w = 1 + fz_u8(&f) % MAX_W, h = 1 + fz_u8(&f) % MAX_W;
    cull_view_desc d;
    fz_view_desc(&f, &d, w, h);
    cull_view v;
    if (cull_view_init(&v, &d) != CULL_OK) return 0;

    /* meshes: the box, and one from the bytes if it passes the check */
    float pos[3 * MAX_MV], nrm[3 * MAX_MV], uv[2 * MAX_MV], tan[4 * MAX_MV];
    uint32_t idx[3 * MAX_MT];
    vt_mesh meshes[2] = {vt_mesh_box};
    uint32_t nmesh = 1;
    if (head & 1) {
        vt_mesh m = {.pos = pos, .idx = idx, .nv = 3 + fz_u8(&f) % (MAX_MV - 2), .ni = 3 * (1 + fz_u8(&f) % MAX_MT)};
        for (uint32_t i = 0; i < 3 * m.nv; i++) pos[i] = (float)fz_num(&f, 2);
        for (uint32_t i = 0; i < m.ni; i++) idx[i] = fz_u8(&f) % m.nv;
        if (head & 2) {
            for (uint32_t i = 0; i < 3 * m.nv; i++) nrm[i] = (float)fz_num(&f, 1);
            m.nrm = nrm;
        }
        char err[256];
        if (vt_mesh_check(&m, err, sizeof err) == 0) meshes[nmesh++] = m;
    }
    vt_instance in[MAX_INST];
    uint32_t ni = fz_u8(&f) % (MAX_INST + 1);
    memset(in, 0, sizeof in);
    for (uint32_t i = 0; i < ni; i++) {
        in[i].mesh = fz_u8(&f) % nmesh;
        for (int a = 0; a < 3; a++) {
            double c = fz_num(&f, 30), e = fabs(fz_num(&f, 10));
            in[i].bmin[a] = c - e;
            in[i].bmax[a] = c + e;
            in[i].albedo[a] = (float)((double)fz_u8(&f) / 255.0);
        }
    }
    vt_light L[MAX_LIGHTS];
    uint32_t nl = fz_u8(&f) % (MAX_LIGHTS + 1);
    memset(L, 0, sizeof L);
    for (uint32_t i = 0; i < nl; i++) {
        fz_light(&f, &L[i].l);
        for (int a = 0; a < 3; a++) L[i].color[a] = (float)fabs(fz_num(&f, 4));
        L[i].cos_inner = (float)((double)fz_u8(&f) / 127.5 - 1.0);
    }

    vt_env env;
    bool env_on;
    vt_material mat;
    vt_texview tex;
    uint8_t texels[4 * 21];
    const uint8_t *lv[3];
    scene_model(&f, &env, &env_on, &mat, &tex, texels, lv, uv, tan, MAX_MV, in, ni);
    if (nmesh > 1 && (head & 4)) meshes[1].uv = uv;
    if (nmesh > 1 && (head & 8)) meshes[1].tan = tan;
    if (env.sky_mode == VT_SKY_TEXTURE && (head & 16)) {
        static float hdr[4 * 16];
        for (int i = 0; i < 64; i++) hdr[i] = (float)fz_num(&f, 1e3);
        static vt_texview sky;
        sky = (vt_texview){.w = 4, .h = 4, .levels = 1, .hdr = hdr};
        env.sky_tex = &sky;
    }

    /* the overlay (vt_overlay.h): both outlines' instance indices (past
       ninst: refused), boxes of any bounds, icons anywhere, any colour */
    vt_overlay ov = {0};
    uint32_t hl[VT_OUTLINES][2];
    vt_instance extra[VT_OUTLINES][2];
    vt_icon icons[3];
    if (head & 32) {
        for (int g = 0; g < VT_OUTLINES; g++) {
            vt_outline *l = &ov.outline[g];
            l->nhl = fz_u8(&f) % 3;
            l->nextra = fz_u8(&f) % 3;
            for (uint32_t i = 0; i < l->nhl; i++) hl[g][i] = fz_u8(&f) % (ni + 2);
            for (uint32_t i = 0; i < l->nextra; i++) {
                extra[g][i] = (vt_instance){.mesh = fz_u8(&f) % (nmesh + 1), .place = VT_PLACE_BOUNDS};
                for (int a = 0; a < 3; a++) {
                    double c = fz_num(&f, 1e3), e = fz_num(&f, 1e3);
                    extra[g][i].bmin[a] = c - e;
                    extra[g][i].bmax[a] = c + e;
                }
            }
            for (int a = 0; a < 3; a++) l->color[a] = (float)fz_num(&f, 10);
            l->hl = hl[g];
            l->extra = extra[g];
        }
        ov.nicons = fz_u8(&f) % 4;
        for (uint32_t i = 0; i < ov.nicons; i++) {
            icons[i] = (vt_icon){.kind = fz_u8(&f)};
            for (int a = 0; a < 3; a++) icons[i].pos[a] = fz_num(&f, 1e4);
            for (int a = 0; a < 3; a++) icons[i].color[a] = (float)fz_num(&f, 10);
        }
        ov.icons = icons;
    }

    static float rgba[MAX_W * MAX_W * 4], depth[MAX_W * MAX_W];
    for (size_t i = 0; i < (size_t)w * h; i++) rgba[4 * i] = rgba[4 * i + 1] = rgba[4 * i + 2] = rgba[4 * i + 3] = depth[i] = 7;
    char err[256] = "";
    vt_frame fr = {.view = &v, .width = w, .height = h, .meshes = meshes, .nmesh = nmesh, .inst = in, .ninst = ni,
                   .lights = L, .nl = nl, .env = env_on ? &env : NULL, .rgba = rgba, .depth = depth, .stride = w,
                   .overlay = (head & 32) ? &ov : NULL};
#ifdef FUZZ_RENDER_GL
    int rc = vt_gldraw_draw(renderer(), &fr, NULL, err, sizeof err);
#else
    int stop = 1;
    if (head & 128) { /* a picture no longer wanted */
        fr.cancel = &stop;
        int src = vt_soft_draw(renderer(), &fr, NULL, err, sizeof err);
        CHECK(src == VT_ERR_CANCELLED || src == VT_ERR_INVALID);
        CHECK(err[0] != 0);
        return 0;
    }
    int rc = vt_soft_draw(renderer(), &fr, NULL, err, sizeof err);
    if (rc == 0 && (head & 64)) { /* dynamic resolution: the picture in bytes, scaled to any size */
        static uint8_t small[MAX_W * MAX_W * 4], big[96 * 96 * 4];
        uint32_t bw = 1 + fz_u8(&f) % 96, bh = 1 + fz_u8(&f) % 96;
        const float gain = (float)fabs(fz_num(&f, 8)); /* (the daemon tone maps; any bytes do here) */
        for (size_t i = 0; i < 4 * (size_t)w * h; i++) {
            float x = rgba[i] * gain;
            small[i] = (uint8_t)(x >= 1 ? 255 : x > 0 ? x * 255 : 0);
        }
        CHECK(vt_image_resize_rgba8(w, h, small, 4 * (size_t)w, bw, bh, big, 4 * (size_t)bw, 1 + fz_u8(&f) % 5, NULL,
                                    NULL) == 0);
        uint8_t lo[4] = {255, 255, 255, 255}, hi[4] = {0, 0, 0, 0};
        for (size_t i = 0; i < (size_t)w * h; i++)
            for (int c = 0; c < 4; c++) {
                if (small[4 * i + c] < lo[c]) lo[c] = small[4 * i + c];
                if (small[4 * i + c] > hi[c]) hi[c] = small[4 * i + c];
            }
        for (size_t i = 0; i < (size_t)bw * bh; i++)
            for (int c = 0; c < 4; c++) CHECK(big[4 * i + c] >= lo[c] && big[4 * i + c] <= hi[c]);
    }
#endif
    if (rc != 0) {
        CHECK(rc == VT_ERR_INVALID && err[0] != 0);
        for (size_t i = 0; i < (size_t)w * h; i++) CHECK(rgba[4 * i] == 7 && depth[i] == 7);
        return 0;
    }
    for (size_t i = 0; i < (size_t)w * h; i++) {
        /* an outline over nothing (no environment) blends its weight into
           alpha (vt_overlay.c): 0..1 there */
        CHECK(rgba[4 * i + 3] == 0 || rgba[4 * i + 3] == 1 || ((head & 32) && rgba[4 * i + 3] > 0 && rgba[4 * i + 3] < 1));
        CHECK(!env_on || rgba[4 * i + 3] == 1); /* opaque with an environment */
        CHECK(depth[i] == depth[i]);
        for (int k = 0; k < 3; k++) CHECK(rgba[4 * i + k] == rgba[4 * i + k]); /* no NaN in the picture */
    }
    return 0;
}
