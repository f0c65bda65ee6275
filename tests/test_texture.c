/*
 * test_texture.c — textures in the scene (daemon/texture.c through
 * edit.c, render/vt_texture.c), in-process:
 *   - decoded pixels against the source: PNG (lossless: exact), JPEG
 *     (against libjpeg's own decode of the same stream, and near the
 *     source), EXR (float: exact);
 *   - every mip level against a slow reference: the area integral of the
 *     level above over the pixel's footprint, in double (sRGB decoded
 *     with pow, non-separable), at odd and even sizes, sRGB and linear;
 *   - every bad input as a named row, each leaving the scene unchanged;
 *   - TEXTURE_REMOVE: unknown, twice, in use (the sky), and the memory
 *     given back; replacing an id keeps its users.
 */
#include "test_util.h"

#include "edit.h"
#include "vt_exr.h"
#include "vt_image.h"
#include "vt_texture.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const scene_limits LIMITS = {.max_entities = 1024, .max_lights = 16, .max_occluders = 16,
                                    .max_occluder_tris = 16, .max_mesh_verts = 16, .max_materials = 16,
                                    .max_texture_size = 4096, .max_texture_mem = 64u << 20};

static scene *scene_new(const scene_limits *lim)
{
    scene *s = calloc(1, sizeof *s);
    assert_non_null(s);
    assert_int_equal(scene_init(s, 64, lim ? lim : &LIMITS), 0);
    return s;
}

static void scene_gone(scene *s)
{
    scene_free(s);
    free(s);
}

/* Random RGBA pixels, or a smooth ramp (JPEG likes those). */
static uint8_t *pixels(uint32_t w, uint32_t h, uint64_t seed, bool smooth)
{
    uint8_t *p = malloc((size_t)w * h * 4);
    assert_non_null(p);
    for (uint32_t y = 0; y < h; y++)
        for (uint32_t x = 0; x < w; x++)
            for (int c = 0; c < 4; c++) {
                uint8_t *q = p + ((size_t)y * w + x) * 4 + c;
                *q = smooth ? (uint8_t)(20 + x * 150 / (w > 1 ? w - 1 : 1) + y * 60 / (h > 1 ? h - 1 : 1) + 8 * c)
                            : (uint8_t)(splitmix64(&seed) >> 56);
            }
    return p;
}

/* The bytes a file writer makes (through a file in a fresh folder). */
typedef int (*write_fn)(const char *path, const void *px, uint32_t w, uint32_t h, char *err, size_t errlen);

static uint8_t *bytes_of(write_fn write, const void *px, uint32_t w, uint32_t h, size_t *len)
{
    tdir t;
    char err[256];
    tdir_make(&t, "tex");
    const char *path = tdir_file(&t, "a.img");
    assert_int_equal(write(path, px, w, h, err, sizeof err), 0);
    uint8_t *b = test_slurp(path, len);
    tdir_remove(&t);
    return b;
}

static int write_png(const char *path, const void *px, uint32_t w, uint32_t h, char *err, size_t errlen)
{
    return vt_png_write(path, w, h, px, (size_t)w * 4, true, 1, err, errlen);
}

static int write_exr(const char *path, const void *px, uint32_t w, uint32_t h, char *err, size_t errlen)
{
    static const char *const names[4] = {"R", "G", "B", "A"};
    const float *f = px;
    vt_exr_channel ch[4];
    for (int c = 0; c < 4; c++) ch[c] = (vt_exr_channel){names[c], VT_EXR_FLOAT, f + c, 4, 4 * (ptrdiff_t)w};
    return vt_exr_write(path, w, h, ch, 4, VT_EXR_ZIP, err, errlen);
}

static uint8_t *png_of(const uint8_t *px, uint32_t w, uint32_t h, size_t *len)
{
    return bytes_of(write_png, px, w, h, len);
}

static uint8_t *exr_of(const float *rgba, uint32_t w, uint32_t h, size_t *len)
{
    return bytes_of(write_exr, rgba, w, h, len);
}

static float *hdr_pixels(uint32_t w, uint32_t h)
{
    float *p = malloc((size_t)w * h * 16);
    assert_non_null(p);
    for (size_t i = 0; i < (size_t)w * h * 4; i++) p[i] = (float)(i % 7) * 0.75f + (float)(i % 3) * 100.0f;
    return p;
}

/* TEXTURE_PUT of a whole image through edit_decode / edit_apply (what the
 * daemon and the journal's replay run). */
static int put(scene *s, uint32_t id, uint8_t format, uint8_t flags, const uint8_t *b, size_t n, scene_err *err)
{
    size_t cap = vp_size_texture_put((uint32_t)n);
    uint8_t *buf = malloc(cap);
    assert_non_null(buf);
    vp_writer w;
    vp_writer_init(&w, buf, cap);
    vp_enc_texture_put(&w, 1, &(vp_texture_put){.id = id, .format = format, .flags = flags, .total = (uint32_t)n,
                                                 .len = (uint32_t)n, .data = b});
    edit e;
    edit_result r;
    int rc = edit_decode(VP_TEXTURE_PUT, buf + VP_HEADER_SIZE, (uint32_t)(w.len - VP_HEADER_SIZE), 0, EDIT_LAYOUT,
                         &e);
    if (rc) edit_explain(&e, rc, err);
    else if (!(rc = edit_apply(s, &e, &r, err))) edit_result_free(&r);
    free(buf);
    return rc;
}

static int remove_tex(scene *s, const uint64_t *ids, uint32_t n, scene_err *err)
{
    uint8_t buf[256];
    vp_writer w;
    vp_writer_init(&w, buf, sizeof buf);
    vp_enc_ids(&w, VP_TEXTURE_REMOVE, 1, ids, n);
    edit e;
    edit_result r;
    int rc = edit_decode(VP_TEXTURE_REMOVE, buf + VP_HEADER_SIZE, (uint32_t)(w.len - VP_HEADER_SIZE), 0, EDIT_LAYOUT,
                         &e);
    if (!rc && !(rc = edit_apply(s, &e, &r, err))) edit_result_free(&r);
    return rc;
}

static int env_set(scene *s, const vp_env *env, scene_err *err)
{
    return edit_apply(s, &(edit){.type = VP_ENV_SET, .u.env = *env}, &(edit_result){0}, err);
}

/* ---- the slow reference box filter ------------------------------------------------------- */

static double srgb_dec(uint8_t v)
{
    double c = v / 255.0;
    return c <= 0.04045 ? c / 12.92 : pow((c + 0.055) / 1.055, 2.4);
}

static double srgb_enc255(double l)
{
    if (l <= 0) return 0;
    if (l >= 1) return 255;
    return 255 * (l <= 0.0031308 ? 12.92 * l : 1.055 * pow(l, 1 / 2.4) - 0.055);
}

/* Pixel (x, y) channel c of the level below src (sw x sh), 0..255 before
 * rounding: the mean of src over the pixel's footprint, by area. */
static double ref_down(const uint8_t *src, uint32_t sw, uint32_t sh, uint32_t x, uint32_t y, int c, bool srgb)
{
    uint32_t dw = sw / 2 ? sw / 2 : 1, dh = sh / 2 ? sh / 2 : 1;
    double x0 = (double)x * sw / dw, x1 = (double)(x + 1) * sw / dw;
    double y0 = (double)y * sh / dh, y1 = (double)(y + 1) * sh / dh;
    double sum = 0, area = 0;
    for (uint32_t sy = 0; sy < sh; sy++)
        for (uint32_t sx = 0; sx < sw; sx++) {
            double ox = fmin(sx + 1.0, x1) - fmax((double)sx, x0), oy = fmin(sy + 1.0, y1) - fmax((double)sy, y0);
            if (ox <= 0 || oy <= 0) continue;
            uint8_t v = src[((size_t)sy * sw + sx) * 4 + c];
            sum += ox * oy * (srgb && c < 3 ? srgb_dec(v) : v);
            area += ox * oy;
        }
    double m = sum / area;
    return srgb && c < 3 ? srgb_enc255(m) : m;
}

/* Every level of t against ref_down of the level above (its own: each
 * level is made from the one before, rounded), within 1/255. */
static void check_mips(const scene_texture *t, const uint8_t *src, bool srgb)
{
    assert_int_equal(t->levels, vt_texture_levels(t->w, t->h));
    assert_memory_equal(t->mip[0], src, (size_t)t->w * t->h * 4);
    uint32_t sw = t->w, sh = t->h;
    for (uint32_t i = 1; i < t->levels; i++) {
        uint32_t dw = sw / 2 ? sw / 2 : 1, dh = sh / 2 ? sh / 2 : 1;
        for (uint32_t y = 0; y < dh; y++)
            for (uint32_t x = 0; x < dw; x++)
                for (int c = 0; c < 4; c++) {
                    double want = ref_down(t->mip[i - 1], sw, sh, x, y, c, srgb);
                    int got = t->mip[i][((size_t)y * dw + x) * 4 + c];
                    if (fabs(got - want) > 1.0)
                        fail_msg("level %u (%ux%u) pixel (%u, %u) channel %d: %d, the reference %.3f", i, dw, dh, x,
                                 y, c, got, want);
                }
        sw = dw;
        sh = dh;
    }
    assert_int_equal(sw, 1);
    assert_int_equal(sh, 1);
}

static void test_texture_png_mips(void **state)
{
    (void)state;
    static const uint32_t sizes[][2] = {{1, 1}, {2, 2}, {3, 1}, {5, 3}, {7, 1}, {1, 9}, {37, 23}, {64, 64}, {33, 65}};
    for (size_t k = 0; k < sizeof sizes / sizeof sizes[0]; k++)
        for (int srgb = 0; srgb < 2; srgb++) {
            uint32_t w = sizes[k][0], h = sizes[k][1];
            scene *s = scene_new(NULL);
            uint8_t *px = pixels(w, h, 1000 + k, false);
            size_t n;
            uint8_t *b = png_of(px, w, h, &n);
            scene_err err;
            assert_int_equal(put(s, 5, VP_TEX_PNG, srgb ? VP_TEX_SRGB : 0, b, n, &err), VP_OK);
            scene_texture *t = scene_texture_find(s, 5);
            assert_non_null(t);
            assert_int_equal(t->w, w);
            assert_int_equal(t->h, h);
            assert_int_equal(t->nbytes, n);
            assert_memory_equal(t->bytes, b, n); /* the upload kept as sent */
            assert_null(t->hdr);
            check_mips(t, px, srgb);
            /* the memory it is charged: upload + levels (+ bookkeeping) */
            assert_true(t->mem >= n + vt_texture_pixel_bytes(VT_TEXTURE_PNG, w, h));
            assert_int_equal(s->texture_mem, t->mem);
            free(px);
            free(b);
            scene_gone(s);
        }
}

/* A grey of 128 everywhere but one white pixel: linear averaging gives a
 * darker sRGB grey than sRGB averaging would; both match the reference. */
static void test_texture_srgb_linear_light(void **state)
{
    (void)state;
    uint8_t px[2 * 2 * 4] = {0, 0, 0, 255, 255, 255, 255, 255, 0, 0, 0, 255, 255, 255, 255, 255};
    size_t n;
    uint8_t *b = png_of(px, 2, 2, &n);
    scene *s = scene_new(NULL);
    scene_err err;
    assert_int_equal(put(s, 1, VP_TEX_PNG, VP_TEX_SRGB, b, n, &err), VP_OK);
    assert_int_equal(put(s, 2, VP_TEX_PNG, 0, b, n, &err), VP_OK);
    /* half black, half white: linear 0.5 is sRGB 188; the plain mean is 128 */
    assert_int_equal(scene_texture_find(s, 1)->mip[1][0], 188);
    assert_int_equal(scene_texture_find(s, 2)->mip[1][0], 128);
    assert_int_equal(scene_texture_find(s, 1)->mip[1][3], 255);
    free(b);
    scene_gone(s);
}

static void test_texture_jpeg(void **state)
{
    (void)state;
    uint32_t w = 45, h = 31;
    uint8_t *px = pixels(w, h, 7, true);
    uint8_t *jpg, *rgb;
    size_t n;
    uint32_t jw, jh;
    char err[256];
    assert_int_equal(vt_jpeg_encode(w, h, px, (size_t)w * 4, 4, 95, &jpg, &n, err, sizeof err), 0);
    assert_int_equal(vt_jpeg_decode(jpg, n, &rgb, &jw, &jh, err, sizeof err), 0);
    scene *s = scene_new(NULL);
    scene_err se;
    assert_int_equal(put(s, 9, VP_TEX_JPEG, VP_TEX_SRGB, jpg, n, &se), VP_OK);
    const scene_texture *t = scene_texture_find(s, 9);
    assert_int_equal(t->w, w);
    assert_int_equal(t->h, h);
    double err_sum = 0;
    for (size_t i = 0; i < (size_t)w * h; i++) {
        for (int c = 0; c < 3; c++) {
            assert_int_equal(t->mip[0][4 * i + c], rgb[3 * i + c]); /* libjpeg's decode, exactly */
            err_sum += fabs((double)t->mip[0][4 * i + c] - px[4 * i + c]);
        }
        assert_int_equal(t->mip[0][4 * i + 3], 255);
    }
    assert_true(err_sum / (w * h * 3.0) < 4); /* and near the source (q95) */
    uint8_t *l0 = malloc((size_t)w * h * 4);
    memcpy(l0, t->mip[0], (size_t)w * h * 4);
    check_mips(t, l0, true);
    free(l0);
    free(rgb);
    free(jpg);
    free(px);
    scene_gone(s);
}

static void test_texture_exr(void **state)
{
    (void)state;
    uint32_t w = 32, h = 16;
    float *px = hdr_pixels(w, h);
    size_t n;
    uint8_t *b = exr_of(px, w, h, &n);
    scene *s = scene_new(NULL);
    scene_err err;
    assert_int_equal(put(s, 3, VP_TEX_EXR, 0, b, n, &err), VP_OK);
    const scene_texture *t = scene_texture_find(s, 3);
    assert_int_equal(t->levels, 1);
    assert_null(t->mip);
    assert_memory_equal(t->hdr, px, (size_t)w * h * 16);
    free(b);
    free(px);
    scene_gone(s);
}

/* Channels other than RGBA: grey (Y) copied to R, G and B; no A is
 * opaque; half samples (values half holds exactly) come back as stored. */
static void test_texture_exr_channels(void **state)
{
    (void)state;
    enum { W = 6, H = 3 };
    float v[W * H], a[W * H];
    for (int i = 0; i < W * H; i++) /* values halves hold exactly */
        v[i] = 0.25f * (float)i, a[i] = 1.0f / (float)(1 << (i % 4));
    static const struct { const char *names[3]; int n; bool grey, alpha; } cases[] = {
        {{"Y"}, 1, true, false}, {{"Y", "A"}, 2, true, true}, {{"R", "G", "B"}, 3, false, false}};
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        tdir t;
        char err[256];
        tdir_make(&t, "texc");
        vt_exr_channel ch[3];
        for (int c = 0; c < cases[k].n; c++) {
            const char *nm = cases[k].names[c];
            /* R, G, B: the same values scaled 1, 2, 3 */
            static float rgb[3][W * H];
            const float *src = !strcmp(nm, "A") ? a : v;
            if (!cases[k].grey) {
                for (int i = 0; i < W * H; i++) rgb[c][i] = v[i] * (float)(c + 1);
                src = rgb[c];
            }
            ch[c] = (vt_exr_channel){nm, VT_EXR_HALF, src, 1, W};
        }
        const char *path = tdir_file(&t, "c.exr");
        assert_int_equal(vt_exr_write(path, W, H, ch, (uint32_t)cases[k].n, VT_EXR_PIZ, err, sizeof err), 0);
        size_t n;
        uint8_t *b = test_slurp(path, &n);
        scene *s = scene_new(NULL);
        scene_err se;
        assert_int_equal(put(s, 1, VP_TEX_EXR, 0, b, n, &se), VP_OK);
        const float *h = scene_texture_find(s, 1)->hdr;
        for (int i = 0; i < W * H; i++)
            for (int c = 0; c < 4; c++) {
                float want = c == 3 ? (cases[k].alpha ? a[i] : 1.0f) : cases[k].grey ? v[i] : v[i] * (float)(c + 1);
                if (h[4 * i + c] != want)
                    fail_msg("case %zu pixel %d channel %d: %g, want %g", k, i, c, (double)h[4 * i + c], (double)want);
            }
        free(b);
        scene_gone(s);
        tdir_remove(&t);
    }
}

/* ---- bad inputs ----------------------------------------------------------------------- */

typedef enum { IMG_PNG, IMG_PNG_CUT, IMG_GARBAGE, IMG_JPEG_GARBAGE, IMG_EXR, IMG_EXR_NAN, IMG_EXR_INF } img_kind;

typedef struct bad_row {
    const char *name;
    img_kind kind;
    uint8_t format, flags;
    uint32_t w, h;
    uint32_t max_size;  /* 0: LIMITS' */
    uint64_t max_mem;   /* 0: LIMITS' */
    int want;
    const char *says;   /* in the message */
} bad_row;

static const bad_row bad_rows[] = {
    {"png_not_decodable", IMG_GARBAGE, VP_TEX_PNG, 0, 0, 0, 0, 0, VP_ERR_INVALID, "not a valid PNG image"},
    {"png_truncated", IMG_PNG_CUT, VP_TEX_PNG, 0, 40, 30, 0, 0, VP_ERR_INVALID, "does not decode"},
    {"jpeg_not_decodable", IMG_JPEG_GARBAGE, VP_TEX_JPEG, 0, 0, 0, 0, 0, VP_ERR_INVALID, "not a valid JPEG image"},
    {"png_sent_as_jpeg", IMG_PNG, VP_TEX_JPEG, 0, 8, 8, 0, 0, VP_ERR_INVALID, "not a valid JPEG image"},
    {"png_sent_as_exr", IMG_PNG, VP_TEX_EXR, 0, 8, 8, 0, 0, VP_ERR_INVALID, "not a valid EXR image"},
    {"over_size_wide", IMG_PNG, VP_TEX_PNG, 0, 65, 2, 64, 0, VP_ERR_LIMIT, "65x2 is larger than 64"},
    {"over_size_tall", IMG_PNG, VP_TEX_PNG, 0, 2, 65, 64, 0, VP_ERR_LIMIT, "2x65 is larger than 64"},
    {"over_memory", IMG_PNG, VP_TEX_PNG, 0, 64, 64, 0, 20000, VP_ERR_LIMIT, "the limit is 20000"},
    {"exr_nan", IMG_EXR_NAN, VP_TEX_EXR, 0, 8, 4, 0, 0, VP_ERR_NONFINITE, "pixel (3, 1) channel G is nan"},
    {"exr_inf", IMG_EXR_INF, VP_TEX_EXR, 0, 8, 4, 0, 0, VP_ERR_NONFINITE, "channel B is inf"},
    {"undefined_flags", IMG_PNG, VP_TEX_PNG, 0x2, 8, 8, 0, 0, VP_ERR_INVALID, "flags 0x2"},
    {"undefined_format", IMG_PNG, 3, 0, 8, 8, 0, 0, VP_ERR_INVALID, "format 3"},
};

static void test_texture_bad(void **state)
{
    const bad_row *row = *state;
    scene_limits lim = LIMITS;
    if (row->max_size) lim.max_texture_size = row->max_size;
    if (row->max_mem) lim.max_texture_mem = row->max_mem;
    scene *s = scene_new(&lim);
    uint8_t *b = NULL;
    size_t n = 0;
    if (row->kind == IMG_PNG || row->kind == IMG_PNG_CUT) {
        uint8_t *px = pixels(row->w, row->h, 3, false);
        b = png_of(px, row->w, row->h, &n);
        free(px);
        if (row->kind == IMG_PNG_CUT) n = n * 2 / 3; /* the header whole, the pixels cut */
    } else if (row->kind == IMG_EXR_NAN || row->kind == IMG_EXR_INF) {
        float *px = hdr_pixels(row->w, row->h);
        if (row->kind == IMG_EXR_NAN) px[(1 * row->w + 3) * 4 + 1] = NAN;
        else px[(2 * row->w + 5) * 4 + 2] = INFINITY;
        b = exr_of(px, row->w, row->h, &n);
        free(px);
    } else {
        n = 300;
        b = malloc(n);
        for (size_t i = 0; i < n; i++) b[i] = (uint8_t)(i * 37 + 11);
        if (row->kind == IMG_JPEG_GARBAGE) b[0] = 0xff, b[1] = 0xd8, b[2] = 0xff;
        if (row->kind == IMG_GARBAGE) memcpy(b, "\x89PNG\r\n\x1a\n", 8);
    }
    uint64_t epoch = s->epoch;
    scene_err err = {0};
    int rc = put(s, 4, row->format, row->flags, b, n, &err);
    assert_int_equal(rc, row->want);
    if (!strstr(err.msg, row->says)) fail_msg("message \"%s\" does not say \"%s\"", err.msg, row->says);
    /* nothing changed */
    assert_int_equal(s->textures.count, 0);
    assert_int_equal(s->texture_mem, 0);
    assert_int_equal(s->epoch, epoch);
    free(b);
    scene_gone(s);
}

/* Offsets and lengths that are not a whole image never reach the scene
 * whole: the decoder refuses what disagrees, the scene what is a part. */
static void test_texture_part_refused(void **state)
{
    (void)state;
    scene *s = scene_new(NULL);
    scene_err err;
    uint8_t part[10] = {0};
    assert_int_equal(scene_texture_put(s, &(vp_texture_put){.id = 1, .total = 20, .offset = 10, .len = 10,
                                                            .data = part},
                                       &err),
                     VP_ERR_INVALID);
    assert_non_null(strstr(err.msg, "not the whole image"));
    assert_int_equal(s->textures.count, 0);
    /* a pad byte set: refused by the decoder, explained as such */
    uint8_t buf[VP_HEADER_SIZE + VP_TEXTURE_PUT_HEADER + 10];
    vp_writer w;
    vp_writer_init(&w, buf, sizeof buf);
    vp_enc_texture_put(&w, 1, &(vp_texture_put){.id = 2, .total = 10, .len = 10, .data = part});
    buf[VP_HEADER_SIZE + 6] = 1;
    edit e;
    int rc = edit_decode(VP_TEXTURE_PUT, buf + VP_HEADER_SIZE, VP_TEXTURE_PUT_HEADER + 10, 0, EDIT_LAYOUT, &e);
    assert_int_equal(rc, VP_ERR_INVALID);
    edit_explain(&e, rc, &err);
    assert_non_null(strstr(err.msg, "texture 2: pad bytes 6..7 must be zero"));
    scene_gone(s);
}

/* ---- remove, replace, users ---------------------------------------------------------- */

static void test_texture_remove(void **state)
{
    (void)state;
    scene *s = scene_new(NULL);
    scene_err err;
    uint8_t *px = pixels(16, 8, 5, false);
    size_t n, en;
    uint8_t *b = png_of(px, 16, 8, &n);
    float *hp = hdr_pixels(16, 8);
    uint8_t *eb = exr_of(hp, 16, 8, &en);
    assert_int_equal(put(s, 1, VP_TEX_PNG, 0, b, n, &err), VP_OK);
    assert_int_equal(put(s, 2, VP_TEX_EXR, 0, eb, en, &err), VP_OK);
    uint64_t mem = s->texture_mem;
    /* unknown, twice, in use: refused whole, naming the record */
    uint64_t unknown[2] = {1, 77};
    assert_int_equal(remove_tex(s, unknown, 2, &err), VP_ERR_UNKNOWN_ID);
    assert_int_equal(err.index, 1);
    uint64_t twice[3] = {1, 2, 1};
    assert_int_equal(remove_tex(s, twice, 3, &err), VP_ERR_DUPLICATE);
    assert_int_equal(err.index, 2);
    assert_int_equal(s->textures.count, 2);
    assert_int_equal(s->texture_mem, mem);
    vp_env env;
    vp_env_default(&env);
    env.sky_mode = VP_SKY_TEXTURE;
    env.sky_texture = 2;
    assert_int_equal(env_set(s, &env, &err), VP_OK);
    assert_int_equal(scene_texture_find(s, 2)->users, 1);
    uint64_t both[2] = {1, 2};
    assert_int_equal(remove_tex(s, both, 2, &err), VP_ERR_STATE);
    assert_int_equal(err.index, 1);
    assert_non_null(strstr(err.msg, "in use"));
    assert_int_equal(s->textures.count, 2);
    /* replaced: the users carry over; the sky's must stay a lat-long EXR */
    assert_int_equal(put(s, 2, VP_TEX_EXR, 0, eb, en, &err), VP_OK);
    assert_int_equal(scene_texture_find(s, 2)->users, 1);
    assert_int_equal(s->texture_mem, mem);
    assert_int_equal(put(s, 2, VP_TEX_PNG, 0, b, n, &err), VP_ERR_INVALID);
    assert_non_null(strstr(err.msg, "sky texture 2 is a PNG"));
    assert_int_equal(scene_texture_find(s, 2)->format, VP_TEX_EXR);
    /* the sky let go: removable, memory back to 0 */
    env.sky_mode = VP_SKY_ANALYTIC;
    assert_int_equal(env_set(s, &env, &err), VP_OK);
    assert_int_equal(scene_texture_find(s, 2)->users, 0);
    assert_int_equal(remove_tex(s, both, 2, &err), VP_OK);
    assert_int_equal(s->textures.count, 0);
    assert_int_equal(s->texture_mem, 0);
    free(b);
    free(eb);
    free(hp);
    free(px);
    scene_gone(s);
}

const struct CMUnitTest texture_tests[] = {
    cmocka_unit_test(test_texture_png_mips),
    cmocka_unit_test(test_texture_srgb_linear_light),
    cmocka_unit_test(test_texture_jpeg),
    cmocka_unit_test(test_texture_exr),
    cmocka_unit_test(test_texture_exr_channels),
    TEST_ROWS(test_texture_bad, bad_rows),
    cmocka_unit_test(test_texture_part_refused),
    cmocka_unit_test(test_texture_remove),
};
const size_t texture_tests_count = sizeof texture_tests / sizeof texture_tests[0];
