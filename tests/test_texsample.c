/*
 * test_texsample.c — the texture sampler (render/vt_texsample.c) against
 * issue 19's sampler, kept here as the slow, obviously GL-shaped reference
 * (a function call per texel, the level's size and GL's wrap rules per
 * texel, libm's floor and hypotf): random textures (power-of-two and not,
 * 1x1 up, partial mip chains), every wrap and filter, slot transforms with
 * and without rotation, UVs near and far from the origin, derivatives
 * from magnification to past the last level, and non-finite inputs.
 *
 * The fast sampler does the same float and double operations in the same
 * order, so the results must be equal bit for bit (tolerance 0): a
 * difference is a change of GL semantics, not rounding.
 */
#include "test_util.h"
#include "vt_surface.h"
#include "vt_texlin.h"

#include <math.h>
#include <string.h>

/* ---- the reference: issue 19's vt_scene.c sampler, verbatim but for names ---- */

static float ref_srgb_table[256];

static void ref_srgb_init(void)
{
    for (int i = 0; i < 256; i++) {
        double c = i / 255.0;
        ref_srgb_table[i] = (float)(c <= 0.04045 ? c / 12.92 : pow((c + 0.055) / 1.055, 2.4));
    }
}

static int32_t ref_wrap_i(int32_t i, int32_t n, int mode)
{
    if (mode == VT_WRAP_CLAMP) return i < 0 ? 0 : i >= n ? n - 1 : i;
    if (mode == VT_WRAP_MIRROR) {
        int32_t p = i % (2 * n);
        if (p < 0) p += 2 * n;
        return p < n ? p : 2 * n - 1 - p;
    }
    int32_t p = i % n;
    return p < 0 ? p + n : p;
}

static void ref_texel(const vt_texview *t, uint32_t lv, int32_t x, int32_t y, bool srgb, float o[4])
{
    uint32_t w = t->w >> lv ? t->w >> lv : 1;
    const uint8_t *px = t->mip[lv] + 4 * ((size_t)y * w + (size_t)x);
    for (int c = 0; c < 3; c++) o[c] = srgb ? ref_srgb_table[px[c]] : px[c] * (1 / 255.0f);
    o[3] = px[3] * (1 / 255.0f);
}

static void ref_sample_level(const vt_texref *r, uint32_t lv, float u, float v, bool linear, bool srgb, float o[4])
{
    const vt_texview *t = r->tex;
    int32_t w = (int32_t)(t->w >> lv ? t->w >> lv : 1), h = (int32_t)(t->h >> lv ? t->h >> lv : 1);
    double fu = fmin(fmax((double)u * w, -1e9), 1e9), fv = fmin(fmax((double)v * h, -1e9), 1e9);
    if (!linear) {
        int32_t x = (int32_t)floor(fu), y = (int32_t)floor(fv);
        ref_texel(t, lv, ref_wrap_i(x, w, r->wrap_s), ref_wrap_i(y, h, r->wrap_t), srgb, o);
        return;
    }
    double x = fu - 0.5, y = fv - 0.5, x0 = floor(x), y0 = floor(y);
    float ax = (float)(x - x0), ay = (float)(y - y0);
    int32_t i0 = ref_wrap_i((int32_t)x0, w, r->wrap_s), i1 = ref_wrap_i((int32_t)x0 + 1, w, r->wrap_s);
    int32_t j0 = ref_wrap_i((int32_t)y0, h, r->wrap_t), j1 = ref_wrap_i((int32_t)y0 + 1, h, r->wrap_t);
    float a[4], b[4], c[4], d[4];
    ref_texel(t, lv, i0, j0, srgb, a);
    ref_texel(t, lv, i1, j0, srgb, b);
    ref_texel(t, lv, i0, j1, srgb, c);
    ref_texel(t, lv, i1, j1, srgb, d);
    for (int k = 0; k < 4; k++) {
        float top = a[k] + ax * (b[k] - a[k]), bot = c[k] + ax * (d[k] - c[k]);
        o[k] = top + ay * (bot - top);
    }
}

static void ref_xform(const vt_texref *r, const float uv[2], bool vec, float out[2])
{
    float su = uv[0] * (r->scale[0] == 0 && r->scale[1] == 0 ? 1 : r->scale[0]);
    float sv = uv[1] * (r->scale[0] == 0 && r->scale[1] == 0 ? 1 : r->scale[1]);
    float c = r->rotation == 0 ? 1.0f : cosf(r->rotation), s = r->rotation == 0 ? 0.0f : sinf(r->rotation);
    out[0] = c * su - s * sv + (vec ? 0 : r->offset[0]);
    out[1] = s * su + c * sv + (vec ? 0 : r->offset[1]);
}

static void ref_tex_sample(const vt_texref *r, const float uv0[2], const float dx0[2], const float dy0[2], bool srgb,
                           float out[4])
{
    const vt_texview *t = r->tex;
    float uv[2], dx[2], dy[2];
    ref_xform(r, uv0, false, uv);
    ref_xform(r, dx0, true, dx);
    ref_xform(r, dy0, true, dy);
    float lx = hypotf(dx[0] * (float)t->w, dx[1] * (float)t->h), ly = hypotf(dy[0] * (float)t->w, dy[1] * (float)t->h);
    float rho = lx > ly ? lx : ly;
    float lod = rho > 0 && isfinite(rho) ? log2f(rho) : rho > 0 ? 64.0f : -64.0f;
    uint8_t mf = r->min_filter;
    if (lod <= 0 || mf <= VT_FILTER_LINEAR) {
        bool lin = lod <= 0 ? r->mag_filter == VT_FILTER_LINEAR : mf == VT_FILTER_LINEAR;
        ref_sample_level(r, 0, uv[0], uv[1], lin, srgb, out);
        return;
    }
    bool lin = mf == VT_FILTER_LINEAR_MIP_NEAREST || mf == VT_FILTER_LINEAR_MIP_LINEAR;
    float top = (float)(t->levels - 1);
    if (mf <= VT_FILTER_LINEAR_MIP_NEAREST) {
        float lv = lod <= 0.5f ? 0 : ceilf(lod + 0.5f) - 1;
        ref_sample_level(r, (uint32_t)(lv < top ? lv : top), uv[0], uv[1], lin, srgb, out);
        return;
    }
    if (lod >= top) {
        ref_sample_level(r, (uint32_t)top, uv[0], uv[1], lin, srgb, out);
        return;
    }
    float l0 = floorf(lod), f = lod - l0;
    float a[4], b[4];
    ref_sample_level(r, (uint32_t)l0, uv[0], uv[1], lin, srgb, a);
    ref_sample_level(r, (uint32_t)l0 + 1, uv[0], uv[1], lin, srgb, b);
    for (int k = 0; k < 4; k++) out[k] = a[k] + f * (b[k] - a[k]);
}

/* ---- the comparison ---- */

/* A UV coordinate: mostly near the texture, some far, a few not finite. */
static float some_uv(rng *r)
{
    uint32_t k = rng_below(r, 40);
    if (k == 0) return NAN;
    if (k == 1) return rng_below(r, 2) ? INFINITY : -INFINITY;
    if (k < 5) return (float)rng_range(r, -3e7, 3e7);
    if (k < 8) return (float)rng_below(r, 64) / 16.0f; /* on texel edges and centres */
    return (float)rng_range(r, -4, 4);
}

/* A derivative: magnification to far past the last level, signed, some 0,
 * a few not finite. */
static float some_d(rng *r)
{
    uint32_t k = rng_below(r, 60);
    if (k == 0) return NAN;
    if (k == 1) return INFINITY;
    if (k < 6) return 0;
    if (k < 9) return exp2f((float)(int)rng_below(r, 12) - 8); /* levels exactly: the boundaries */
    return (float)((rng_below(r, 2) ? 1 : -1) * rng_log(r, 1e-5, 1e3));
}

static void test_texture_sample_matches_reference(void **state)
{
    (void)state;
    ref_srgb_init();
    rng r = {test_seed() ^ 0x7E5A3B1Eu};
    static const uint32_t sizes[] = {1, 2, 3, 4, 5, 8, 12, 16, 33, 64, 100, 128};
    uint8_t *levels[VT_TEX_MAX_LEVELS];
    const uint8_t *clevels[VT_TEX_MAX_LEVELS];
    uint32_t cases = 0;
    for (int tex = 0; tex < 60; tex++) {
        vt_texview t = {.w = sizes[rng_below(&r, 12)], .h = sizes[rng_below(&r, 12)]};
        uint32_t full = 1;
        while (((t.w > t.h ? t.w : t.h) >> full) > 0) full++;
        t.levels = 1 + rng_below(&r, full); /* partial chains too */
        for (uint32_t k = 0; k < t.levels; k++) {
            size_t n = 4 * (size_t)(t.w >> k ? t.w >> k : 1) * (t.h >> k ? t.h >> k : 1);
            levels[k] = malloc(n);
            assert_non_null(levels[k]);
            for (size_t i = 0; i < n; i++) levels[k][i] = (uint8_t)rng_u64(&r);
            clevels[k] = levels[k];
        }
        t.mip = clevels;
        char why[160];
        assert_int_equal(vt_texview_check(&t, why, sizeof why), 0);
        for (int slot = 0; slot < 60; slot++) {
            vt_texref ref = {.tex = &t, .wrap_s = (uint8_t)rng_below(&r, 3), .wrap_t = (uint8_t)rng_below(&r, 3),
                             .min_filter = (uint8_t)rng_below(&r, 6), .mag_filter = (uint8_t)rng_below(&r, 2)};
            if (rng_below(&r, 4)) {
                ref.scale[0] = (float)rng_range(&r, -8, 8);
                ref.scale[1] = (float)rng_range(&r, -8, 8);
                ref.offset[0] = (float)rng_range(&r, -2, 2);
                ref.offset[1] = (float)rng_range(&r, -2, 2);
            }
            if (!rng_below(&r, 3)) ref.rotation = (float)rng_range(&r, -7, 7);
            for (int px = 0; px < 40; px++, cases++) {
                float uv[2] = {some_uv(&r), some_uv(&r)}, dx[2] = {some_d(&r), some_d(&r)};
                float dy[2] = {some_d(&r), some_d(&r)}, want[4], got[4];
                bool srgb = rng_below(&r, 2);
                ref_tex_sample(&ref, uv, dx, dy, srgb, want);
                vt_tex_sample(&ref, uv, dx, dy, srgb, got);
                if (memcmp(want, got, sizeof want))
                    fail_msg("%ux%u, %u levels, wrap %u/%u, filter %u/%u, scale %g %g rot %g, uv (%g, %g) dx (%g, %g) "
                             "dy (%g, %g) srgb %d: want (%.9g %.9g %.9g %.9g), got (%.9g %.9g %.9g %.9g)",
                             t.w, t.h, t.levels, ref.wrap_s, ref.wrap_t, ref.min_filter, ref.mag_filter,
                             ref.scale[0], ref.scale[1], ref.rotation, uv[0], uv[1], dx[0], dx[1], dy[0], dy[1],
                             srgb, want[0], want[1], want[2], want[3], got[0], got[1], got[2], got[3]);
            }
        }
        for (uint32_t k = 0; k < t.levels; k++) free(levels[k]);
    }
    printf("texture sampler: %u samples equal to the reference\n", cases);
}

/* Half floats for the sampler's decoded copies (vt_texlin.h) against a
 * reference made from the definition: every one of the 31,744 finite
 * non-negative halves decoded by ldexp (exact in double), and the
 * encoder's choice for the 256 sRGB decodes and 200,000 random values of
 * 0..1 checked to be a nearest half (ties to the even one). */
static void test_texture_half_floats(void **state)
{
    (void)state;
    static double val[0x7C00];
    for (uint32_t h = 0; h < 0x7C00; h++) {
        uint32_t e = h >> 10, m = h & 1023;
        val[h] = e ? ldexp(1024 + m, (int)e - 25) : ldexp(m, -24);
        assert_true((double)vt_half_to_float((uint16_t)h) == val[h]);
    }
    rng r = {test_seed() ^ 0x4A1Fu};
    const float *tab = vt_srgb_table();
    for (int i = 0; i < 200256; i++) {
        float v = i < 256 ? tab[i] : i % 3 ? (float)rng_f(&r) : (float)rng_log(&r, 1e-9, 1);
        uint16_t h = vt_half_of(v);
        assert_true(h < 0x7C00);
        double d = fabs(val[h] - v), lo = h ? fabs(val[h - 1] - v) : INFINITY, hi = fabs(val[h + 1] - v);
        assert_true(d <= lo && d <= hi);
        if (d == lo || d == hi) assert_true((h & 1) == 0); /* a tie goes to the even half */
    }
    assert_int_equal(vt_half_of(0), 0);
    assert_int_equal(vt_half_of(-1), 0);
    assert_int_equal(vt_half_of(NAN), 0);
    assert_int_equal(vt_half_of(1), 0x3C00);
}

const struct CMUnitTest texsample_tests[] = {
    cmocka_unit_test(test_texture_sample_matches_reference),
    cmocka_unit_test(test_texture_half_floats),
};
const size_t texsample_tests_count = sizeof texsample_tests / sizeof texsample_tests[0];
