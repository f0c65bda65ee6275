/*
 * vt_texsample.c — texture sampling as OpenGL samples (vt_surface.h:
 * vt_tex_sample, vt_tex_xform): KHR_texture_transform, the mip level from
 * the UV derivatives (GL's scale factor: the longer derivative vector in
 * texels), nearest or bilinear per level, trilinear between levels, sRGB
 * decoded per texel before filtering, GL's wrap rules after flooring.
 * vt_gldraw's GL sampler does the same on the GL path.
 *
 * Cost: the hot loop of a textured frame (a trilinear sample is 8 texels;
 * a facade pixel of the demo city takes two, base colour and emissive).
 * Issue 19's version went through a call per texel with the level's size
 * and the wrap recomputed per texel, libm's floor and hypotf, and the slot
 * transform called 3 times: 35-45 % of a city frame. This one computes the
 * same numbers (bit for bit: the same operations in the same order on the
 * same types; tests/test_texsample.c holds issue 19's code as the
 * reference and compares) with a level's size and base pointer resolved
 * once, the power-of-two REPEAT wraps as masks, the floors as integer
 * conversions (the coordinates are clamped to +-1e9 first, so they fit),
 * hypotf's length compared squared, and a texel's 4 channels decoded and
 * filtered together in SSE2 lanes: half the instructions of the old one
 * on the demo city (BENCHMARKS.md, issue 20's frame).
 */
#include "vt_surface.h"

#include <math.h>
#include <string.h>

/* RGBA in 4 lanes: SSE2 on x86-64 (every such CPU; the lanes' adds and
 * multiplies are the scalar ones, so the numbers are the same), 4 floats
 * elsewhere. */
#if defined(__SSE2__) && !defined(VT_NO_SSE2) /* VT_NO_SSE2: the portable lanes on x86 too (a check) */
#include <emmintrin.h>
typedef __m128 v4;
static inline v4 v4_set(float a, float b, float c, float d) { return _mm_setr_ps(a, b, c, d); }
static inline v4 v4_set1(float a) { return _mm_set1_ps(a); }
static inline v4 v4_add(v4 a, v4 b) { return _mm_add_ps(a, b); }
static inline v4 v4_sub(v4 a, v4 b) { return _mm_sub_ps(a, b); }
static inline v4 v4_mul(v4 a, v4 b) { return _mm_mul_ps(a, b); }
static inline void v4_store(float *o, v4 a) { _mm_storeu_ps(o, a); }
/* 4 bytes to 4 floats, each times 1/255 */
static inline v4 v4_unorm8(const uint8_t *p)
{
    int32_t v;
    memcpy(&v, p, 4);
    __m128i z = _mm_setzero_si128(), b = _mm_cvtsi32_si128(v);
    return _mm_mul_ps(_mm_cvtepi32_ps(_mm_unpacklo_epi16(_mm_unpacklo_epi8(b, z), z)), _mm_set1_ps(1 / 255.0f));
}
#else
typedef struct v4 { float l[4]; } v4;
static inline v4 v4_set(float a, float b, float c, float d) { return (v4){{a, b, c, d}}; }
static inline v4 v4_set1(float a) { return (v4){{a, a, a, a}}; }
static inline v4 v4_add(v4 a, v4 b) { return (v4){{a.l[0] + b.l[0], a.l[1] + b.l[1], a.l[2] + b.l[2], a.l[3] + b.l[3]}}; }
static inline v4 v4_sub(v4 a, v4 b) { return (v4){{a.l[0] - b.l[0], a.l[1] - b.l[1], a.l[2] - b.l[2], a.l[3] - b.l[3]}}; }
static inline v4 v4_mul(v4 a, v4 b) { return (v4){{a.l[0] * b.l[0], a.l[1] * b.l[1], a.l[2] * b.l[2], a.l[3] * b.l[3]}}; }
static inline void v4_store(float *o, v4 a) { memcpy(o, a.l, sizeof a.l); }
static inline v4 v4_unorm8(const uint8_t *p)
{
    return v4_set(p[0] * (1 / 255.0f), p[1] * (1 / 255.0f), p[2] * (1 / 255.0f), p[3] * (1 / 255.0f));
}
#endif

/* The sRGB decode of every 8-bit value, made once (racing threads write
 * the same table). */
static float srgb_table[256];

static const float *srgb(void)
{
    static int once;
    if (!__atomic_load_n(&once, __ATOMIC_ACQUIRE)) {
        for (int i = 0; i < 256; i++) {
            double c = i / 255.0;
            srgb_table[i] = (float)(c <= 0.04045 ? c / 12.92 : pow((c + 0.055) / 1.055, 2.4));
        }
        __atomic_store_n(&once, 1, __ATOMIC_RELEASE);
    }
    return srgb_table;
}

const float *vt_srgb_table(void)
{
    return srgb();
}

/* floor of a double in -1e9 - 1 .. 1e9 (as an integer: no libm call). */
static inline int32_t floor_i(double x)
{
    int32_t i = (int32_t)x;
    return i - (x < (double)i);
}

/* fmin(fmax(x, -1e9), 1e9) without the calls (NaN: -1e9, as fmax gives). */
static inline double clamp9(double x)
{
    return x > 1e9 ? 1e9 : x >= -1e9 ? x : -1e9;
}

/* hypotf(a, b) squared, in double: glibc's hypotf is (float) sqrt of
 * this, and infinite when either is (a NaN beside an infinity too). */
static inline double len2(float a, float b)
{
    if (isinf(a) || isinf(b)) return INFINITY;
    return (double)a * a + (double)b * b;
}

/* ceilf of x in 0.5 .. 64 (lod + 0.5), without the call. */
static inline float ceil_pos(float x)
{
    int32_t i = (int32_t)x;
    return (float)(i + (x > (float)i));
}

/* One mip level, ready to read. */
typedef struct level {
    const uint8_t *px;
    int32_t w, h;
    uint8_t ws, wt;         /* wrap modes */
} level;

static inline level level_of(const vt_texref *r, uint32_t lv)
{
    const vt_texview *t = r->tex;
    return (level){.px = t->mip[lv], .w = (int32_t)(t->w >> lv ? t->w >> lv : 1),
                   .h = (int32_t)(t->h >> lv ? t->h >> lv : 1), .ws = r->wrap_s, .wt = r->wrap_t};
}

/* A wrapped texel coordinate: REPEAT on a power of two (most textures) is
 * a mask, the rest vt_wrap_i. */
static inline int32_t wrap(int32_t i, int32_t n, uint8_t mode)
{
    if (mode == VT_WRAP_REPEAT && !(n & (n - 1))) return i & (n - 1);
    return vt_wrap_i(i, n, mode);
}

/* Texel (x, y) of a level, decoded. */
static inline v4 texel(const level *L, int32_t x, int32_t y, const float *tab)
{
    const uint8_t *p = L->px + 4 * ((size_t)y * (size_t)L->w + (size_t)x);
    if (tab) return v4_set(tab[p[0]], tab[p[1]], tab[p[2]], (float)p[3] * (1 / 255.0f));
    return v4_unorm8(p);
}

/* a + t (b - a), per lane */
static inline v4 lerp(v4 a, v4 b, v4 t)
{
    return v4_add(a, v4_mul(t, v4_sub(b, a)));
}

/* Level L at (u, v), nearest or bilinear; tab: the sRGB table (NULL:
 * linear). Texel coordinates are wrapped after flooring, as GL does; u, v
 * far beyond 2^24 lose their fraction. */
static inline __attribute__((always_inline)) v4 sample_level(const level *L, float u, float v, bool linear, const float *tab)
{
    /* keep the float to int conversions defined far from the origin */
    double fu = clamp9((double)u * L->w), fv = clamp9((double)v * L->h);
    if (!linear) return texel(L, wrap(floor_i(fu), L->w, L->ws), wrap(floor_i(fv), L->h, L->wt), tab);
    double x = fu - 0.5, y = fv - 0.5;
    int32_t xi = floor_i(x), yi = floor_i(y);
    v4 ax = v4_set1((float)(x - xi)), ay = v4_set1((float)(y - yi));
    int32_t i0 = wrap(xi, L->w, L->ws), i1 = wrap(xi + 1, L->w, L->ws);
    int32_t j0 = wrap(yi, L->h, L->wt), j1 = wrap(yi + 1, L->h, L->wt);
    v4 top = lerp(texel(L, i0, j0, tab), texel(L, i1, j0, tab), ax);
    v4 bot = lerp(texel(L, i0, j1, tab), texel(L, i1, j1, tab), ax);
    return lerp(top, bot, ay);
}

/* The slot transform with its cosine and sine given (vt_tex_xform's body). */
static inline void xform(const vt_texref *r, float c, float s, const float uv[2], bool vec, float out[2])
{
    float su = uv[0] * (r->scale[0] == 0 && r->scale[1] == 0 ? 1 : r->scale[0]);
    float sv = uv[1] * (r->scale[0] == 0 && r->scale[1] == 0 ? 1 : r->scale[1]);
    out[0] = c * su - s * sv + (vec ? 0 : r->offset[0]);
    out[1] = s * su + c * sv + (vec ? 0 : r->offset[1]);
}

void vt_tex_xform(const vt_texref *r, const float uv[2], bool vec, float out[2])
{
    /* no rotation (most slots): cos 0 = 1 and sin 0 = 0 exactly, without the calls */
    xform(r, r->rotation == 0 ? 1.0f : cosf(r->rotation), r->rotation == 0 ? 0.0f : sinf(r->rotation), uv, vec, out);
}

void vt_tex_sample(const vt_texref *r, const float uv0[2], const float dx0[2], const float dy0[2], bool srgb_on,
                   float out[4])
{
    const float *tab = srgb_on ? srgb() : NULL;
    const vt_texview *t = r->tex;
    float c = r->rotation == 0 ? 1.0f : cosf(r->rotation), s = r->rotation == 0 ? 0.0f : sinf(r->rotation);
    float uv[2], dx[2], dy[2];
    xform(r, c, s, uv0, false, uv);
    xform(r, c, s, dx0, true, dx);
    xform(r, c, s, dy0, true, dy);
    /* GL's scale factor: the longer of the two derivative vectors, in
       texels: hypotf's length (len2) compared squared, one square root
       (sqrt and the rounding to float keep the order) */
    double lx2 = len2(dx[0] * (float)t->w, dx[1] * (float)t->h), ly2 = len2(dy[0] * (float)t->w, dy[1] * (float)t->h);
    float rho = (float)sqrt(lx2 > ly2 ? lx2 : ly2);
    float lod = rho > 0 && isfinite(rho) ? log2f(rho) : rho > 0 ? 64.0f : -64.0f; /* NaN: -64 */
    /* which levels, how filtered: one level (magnified, no mips, nearest
       mip, past the last) or two blended by f */
    uint8_t mf = r->min_filter;
    uint32_t l0;
    bool lin, two = false;
    float f = 0;
    if (lod <= 0 || mf <= VT_FILTER_LINEAR) {
        lin = lod <= 0 ? r->mag_filter == VT_FILTER_LINEAR : mf == VT_FILTER_LINEAR;
        l0 = 0;
    } else {
        lin = mf == VT_FILTER_LINEAR_MIP_NEAREST || mf == VT_FILTER_LINEAR_MIP_LINEAR;
        float top = (float)(t->levels - 1);
        if (mf <= VT_FILTER_LINEAR_MIP_NEAREST || lod >= top) {
            /* GL: level ceil(lod + 0.5) - 1; past the last level, the last */
            float lv = mf > VT_FILTER_LINEAR_MIP_NEAREST ? top : lod <= 0.5f ? 0 : ceil_pos(lod + 0.5f) - 1;
            l0 = (uint32_t)(lv < top ? lv : top);
        } else {
            float fl = (float)(int32_t)lod; /* floorf: 0 < lod < 15 here */
            l0 = (uint32_t)fl;
            f = lod - fl;
            two = true;
        }
    }
    level L0 = level_of(r, l0);
    v4 a = sample_level(&L0, uv[0], uv[1], lin, tab);
    if (two) {
        level L1 = level_of(r, l0 + 1);
        a = lerp(a, sample_level(&L1, uv[0], uv[1], lin, tab), v4_set1(f));
    }
    v4_store(out, a);
}
