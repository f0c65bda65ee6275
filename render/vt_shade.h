/*
 * vt_shade.h — the software renderer's shading kernel (internal to
 * render/): one span of up to VT_SPAN pixels of one row inside one 16x16
 * light tile, so every pixel of the span loops over the same light list.
 * The per-pixel surface (position, normal, albedo) is gathered from each
 * pixel's shading record, then the lights run outermost and the pixels
 * innermost in lanes of the culling core's vector layer (cull_simd.h): 8
 * with AVX2 + FMA (vt_shade_avx2.c), 4 with SSE4.1 (vt_shade_sse41.c), 1
 * (vt_shade_base.c). One source (vt_shade.inl), one formula; the AVX2
 * instance rounds its fused multiply-adds once, so the instances agree
 * to a few ulps, not bit for bit.
 */
#ifndef VANTAGE_VT_SHADE_H
#define VANTAGE_VT_SHADE_H

#include "vt_shadow.h"
#include "vt_surface.h"

#include <float.h>
#include <stddef.h>
#include <stdint.h>

#define VT_SPAN 16u          /* = VT_TILE: one tile's width */
#define VT_ID_BITS 27u       /* a pixel's record: set-up thread << 27 | its index */
#define VT_ID_MASK ((1u << VT_ID_BITS) - 1)
#define VT_AMBIENT 0.03f
#define VT_EMPTY (-FLT_MAX) /* the nearness of a pixel nothing covers */
#define VT_ID_GROUND 0xFFFFFFFFu /* a pixel's record + 1 where the ground plane shows (set-up
                                    keeps every record + 1 below it) */

/* The output depth of a pixel of nearness z (see vt_soft.h): 1 / z for
 * perspective views, 1 - k z for orthographic ones (k 0.5 with GL depth,
 * else 1). vt_depth_rule_of (vt_picture.h) makes it for a view. */
typedef struct vt_depth_rule {
    int ortho;
    float k;
} vt_depth_rule;

static inline float vt_depth_apply(vt_depth_rule r, float z)
{
    return !r.ortho ? 1.0f / z : 1.0f - r.k * z;
}

/* A source triangle, for shading. */
typedef struct vt_stri {
    float e[3][3];          /* adjugate rows: barycentric i ~ e[i] . (X, Y, 1), NDC */
    float p[3][3];          /* camera-relative positions */
    float n[3][3];          /* unit normals */
    float albedo[3];
    const struct vt_mask *mask; /* its instance's destruction mask, or NULL */
    const vt_material *mat; /* NULL: the default material of albedo */
    float uv[3][2];         /* has_uv */
    float tg[3][4];         /* tangents (xyz, handedness w), has_tg */
    uint8_t has_uv, has_tg;
    uint8_t alpha_test;     /* a MASK material with a base texture: raster tests each pixel */
} vt_stri;

/* Perspective-correct barycentrics of t at NDC (X, Y): what the shading
 * gather and the masked raster both interpolate with. */
static inline void vt_stri_bary(const vt_stri *t, float X, float Y, float b[3])
{
    float b0 = t->e[0][0] * X + t->e[0][1] * Y + t->e[0][2];
    float b1 = t->e[1][0] * X + t->e[1][1] * Y + t->e[1][2];
    float b2 = t->e[2][0] * X + t->e[2][1] * Y + t->e[2][2];
    float sum = b0 + b1 + b2, is = sum != 0 ? 1.0f / sum : 1.0f;
    b[0] = b0 * is;
    b[1] = b1 * is;
    b[2] = b2 * is;
}

/* The NDC x of column x (inv_w = 2 / width). */
static inline float vt_ndc_x(uint32_t x, double inv_w)
{
    return (float)((x + 0.5) * inv_w - 1);
}

/* A light as shading reads it. */
typedef struct vt_slight {
    float p[3];             /* camera-relative */
    float range2, color[3];
    float dir[3], cos_outer, cos_inner;
    uint32_t spot;
    float inv_range2, inv_cone; /* 1 / range2, 1 / (cos_inner - cos_outer): once a frame */
} vt_slight;

typedef struct vt_span {
    const vt_stri *const *st;   /* shading records, per set-up thread */
    const vt_slight *sl;        /* all lights */
    const uint32_t *li;         /* this tile's lights: indices into sl */
    uint32_t nli;
    const uint32_t *id;         /* per pixel: record + 1, 0 = nothing drawn */
    const float *near;          /* per pixel: nearness */
    uint32_t x0, n;             /* first pixel's column, pixels (<= VT_SPAN) */
    double inv_w;               /* 2 / width: NDC x of column x is (x + 0.5) inv_w - 1 */
    float Y;                    /* the row's NDC y */
    vt_depth_rule rule;         /* nearness to output depth */
    float *rgba, *depth;        /* the span's first pixel in the outputs */
    const vt_penv *pe;          /* the environment (pe->on false: none) */
    const cull_view_rows *vr;   /* the view's rows (rays for the sky) */
    const vt_ground *gr;        /* the ground plane */
    double inv_h;               /* 2 / height: one row in NDC */
    const struct vt_shadow *sh; /* the sun's shadow cascades (vt_shadow.h), or NULL: unshadowed */
    const float *ao;            /* per pixel: ambient occlusion 0..1 (the SSAO pass), or NULL: 1 */
    float ray0[3], ray1[3];     /* with an environment: the row's view rays c0 + X c1 (vt_view_dir_row) */
    const struct vt_texcache *tc; /* decoded sRGB textures (vt_texlin.h), or NULL */
} vt_span;

/* The surface a pixel shows (a triangle's record, or the ground plane),
 * its material evaluated: what the kernels gather per pixel before they
 * light it. cov: 0 nothing drawn there, else 1. p: camera-relative
 * position. The scalar reference of the kernels' gather in lanes
 * (vt_gather.inl) and their path for what the lanes do not cover. */
void vt_span_surface(const vt_span *sp, uint32_t i, float p[3], vt_surfout *o, float *cov);
/* Tests: nonzero sends every pixel through vt_span_surface (the
 * reference) instead of the kernels' gather in lanes. */
extern int vt_gather_scalar;
/* Whether a MASK material's triangle keeps the pixel at NDC (X, Y) (the
 * base alpha >= the cutoff; dX, dY one pixel in NDC). */
bool vt_stri_alpha_pass(const vt_stri *t, float X, float Y, float dX, float dY);
/* After the lights and the fog (the kernel's, in lanes: vt_fog_apply's
 * formula), over the span's pixels: the sky's radiance into c* where cov
 * is 0 (drawn pixels are left as they are). */
void vt_span_sky(const vt_span *sp, float *cr, float *cg, float *cb, const float *cov);

typedef void (*vt_shade_fn)(const vt_span *s);
/* vt_tile_ranges for one row of tiles of a packed nearness image. */
typedef void (*vt_ranges_fn)(const float *near, size_t ys, uint32_t width, uint32_t rows, float (*range)[2]);

typedef struct vt_kern {
    vt_shade_fn shade;
    vt_ranges_fn ranges;
} vt_kern;

void vt_shade_scalar(const vt_span *s);
void vt_shade_sse41(const vt_span *s);
void vt_shade_avx2(const vt_span *s);
void vt_ranges_scalar(const float *, size_t, uint32_t, uint32_t, float (*)[2]);
void vt_ranges_sse41(const float *, size_t, uint32_t, uint32_t, float (*)[2]);
void vt_ranges_avx2(const float *, size_t, uint32_t, uint32_t, float (*)[2]);
void vt_shade_avx2_evex(const vt_span *s);
void vt_ranges_avx2_evex(const float *, size_t, uint32_t, uint32_t, float (*)[2]);
/* The AVX2 kernel's EVEX build (vt_shade_avx2_evex.c: the same bits,
 * 32 registers), or NULLs where this build has none. */
vt_kern vt_kern_evex(void);

/* The instances for this CPU and VANTAGE_ISA, as the culling kernels pick
 * theirs (cull_isa_default); for AVX2 its EVEX build where
 * cull_isa_evex() allows it. */
vt_kern vt_kern_pick(void);

#endif
