/*
 * vt_brdf.h — the shading model both renderers share (internal to
 * render/): glTF 2.0's metallic-roughness BRDF (the specification's
 * Appendix B: GGX / Trowbridge-Reitz D with alpha = roughness^2, the
 * height-correlated Smith visibility V, Schlick's Fresnel F, the diffuse
 * weighted by 1 - F) in scalar reference-grade form, and the image-based
 * ambient made from the environment once per sky change: 9 spherical-
 * harmonic irradiance coefficients, the sky prefiltered with the GGX lobe
 * at VT_IBL_LEVELS roughness levels (octahedral maps), and the split-sum
 * DFG table integrated once at start-up.
 * The SIMD kernels (vt_shade.inl) and the GLSL (vt_brdf_glsl.c) compute
 * the same formulas; this file is what they are tested against.
 * Threading: vt_dfg_table is made once (pthread_once) and read-only
 * after; a vt_ibl belongs to one renderer and is updated by the thread
 * that draws, before the shading threads read it.
 */
#ifndef VANTAGE_VT_BRDF_H
#define VANTAGE_VT_BRDF_H

#include "vt_surface.h"

#include <stdbool.h>
#include <stdint.h>

/* Perceptual roughness is clamped to [VT_MIN_ROUGHNESS, 1]: at 0, D is a
 * Dirac (alpha^2 = 0: 0 / 0 at n.h = 1). 0.045 (Filament's bound) gives
 * alpha^2 = 4.1e-6: D's peak 1 / (pi alpha^2) = 7.8e4 and V's 1 / alpha^2
 * = 2.4e5 stay finite in float even times a 1e6 lux sun (2e16), and the
 * highlight of a sun still covers some of a pixel rather than aliasing. */
#define VT_MIN_ROUGHNESS 0.045f
#define VT_F0_DIELECTRIC 0.04f   /* glTF: ior 1.5 */

/* D: GGX normal distribution at n.h with a2 = alpha^2 (1 / sr). */
float vt_brdf_d(float ndh, float a2);
/* V: the height-correlated Smith visibility (G / (4 |n.l| |n.v|)), the
 * spec's V_GGX; n.l, n.v taken in absolute value as the spec writes it. */
float vt_brdf_v(float ndl, float ndv, float a2);
/* Schlick: f0 + (1 - f0)(1 - |v.h|)^5. */
float vt_brdf_f(float f0, float vdh);
/* The whole BRDF f(v, l) (1 / sr, per channel) for unit n, v, l and a
 * material's base colour, metallic and perceptual roughness (clamped as
 * above): (1 - F) c_diff / pi + F D V, c_diff = base (1 - metallic),
 * f0 = 0.04 .. base by metallic; n.v in absolute value as the spec's V
 * takes it; 0 where n.l <= 0 (light from below the surface). */
void vt_brdf_eval(const float n[3], const float v[3], const float l[3], const float base[3], float metallic,
                  float roughness, float out[3]);
/* The roughness a kernel shades with: clamped, NaN -> 1. */
float vt_brdf_rough(float roughness);

/* The split-sum table: per (n.v, roughness) on a VT_DFG_N x VT_DFG_N grid
 * (both 0..1 inclusive, n.v fastest), RGBA: A, B with
 * integral(F D V cos) = f0 A + B, C = integral((1 - (1 - v.h)^5) / pi cos)
 * (the diffuse's share: its 1 - F is (1 - f0)(1 - (1 - v.h)^5)), 0.
 * Integrated by importance sampling (1024 Hammersley points per entry: A,
 * B GGX-distributed half vectors, C cosine-distributed l), once. */
#define VT_DFG_N 32
const float *vt_dfg_table(void);
/* The table at (n.v, roughness), bilinear (clamped to the grid). */
void vt_dfg(float ndv, float roughness, float out[3]);

/* The prefiltered environment: level k is the environment convolved with
 * the GGX lobe of roughness k / (VT_IBL_LEVELS - 1) about the reflected
 * direction (n = v = r, weighted by n.l: the split sum's first half),
 * octahedral VT_IBL_RES^2 texels (y up; no trigonometry per lookup), RGBA
 * (a = 1) as the GL texture takes it. */
#define VT_IBL_LEVELS 5
#define VT_IBL_RES 32
#define VT_IBL_KEY 22
typedef struct vt_ibl {
    float sh[9][3];              /* irradiance / pi as a polynomial in n (vt_ibl_irradiance) */
    float spec[VT_IBL_LEVELS][VT_IBL_RES * VT_IBL_RES * 4];
    float key[VT_IBL_KEY];       /* the environment it was made from */
    const void *key_img;
    bool ok;
    uint32_t gen;                /* counts remakes: the GL copy follows it */
    const float *dfg;            /* vt_dfg_table(), for the kernels */
    /* the same tables packed a texel to 32 bits for the software
       kernels' gathers (one a texel, not three): spec as vt_rgb_e5, the
       DFG table as vt_unorm10 */
    uint32_t spec_e5[VT_IBL_LEVELS][VT_IBL_RES * VT_IBL_RES];
    const uint32_t *dfg10;
    /* per roughness of the frame's materials (vt_ibl_rough_frame;
       VT_IBL_NR at most): the two levels it falls between blended
       (spec_e5's packing) and the DFG table's row at it (dfg10's), so
       the kernels look up a group of one material's pixels with one
       bilinear sample and a linear one (4 + 2 gathers, not 8 + 4, and
       half the decoding: ~100 of ibl_lanes' ~370 instructions a group).
       The same values but for the packing's rounding of the blend
       (spec_e5's 1/512 of the largest channel, dfg10's 1/2046) */
#define VT_IBL_NR 16
    uint32_t nr, rgen, rframe;   /* entries; the gen they are for; the frame */
    float rough[VT_IBL_NR];      /* vt_brdf_rough's value: the key */
    uint32_t rused[VT_IBL_NR];   /* the frame that last asked for it */
    uint32_t rspec[VT_IBL_NR][VT_IBL_RES * VT_IBL_RES];
    uint32_t rdfg[VT_IBL_NR][VT_DFG_N];
    /* scratch of a remake: the environment on 64 x 32 and 32 x 16
       equirectangular grids, as planes: direction x, y, z, radiance r,
       g, b, solid angle */
    float src_hi[7][64 * 32], src_lo[7][32 * 16];
} vt_ibl;

/* Makes ibl from pe (vt_penv_make's; ground and sky) unless it was made
 * from the same environment; a few ms of a renderer's thread when the sky
 * changes. The lower hemisphere is the ground's bounce (pe->amb_down)
 * where there is a ground, else the sky. Returns true when remade. */
bool vt_ibl_update(vt_ibl *ibl, const vt_penv *pe);
/* The same with pool's threads (at most threads; 0: all of them; pool
 * NULL: the caller's alone): the grids' and the levels' rows. */
struct cull_pool;
bool vt_ibl_update_pool(vt_ibl *ibl, const vt_penv *pe, struct cull_pool *pool, uint32_t threads);
/* The entries (above) for the roughness of every material of the
 * frame's instances and of its ground that has no metallic-roughness
 * texture (NULL: the default material), after vt_ibl_update: kept from
 * frame to frame, made when new (~50 us each), those no frame asked for
 * since replaced when VT_IBL_NR are taken; beyond that the kernels take
 * the levels. */
struct vt_instance;
void vt_ibl_rough_frame(vt_ibl *ibl, const struct vt_instance *inst, uint32_t ninst, const vt_material *ground);
/* The entry of roughness r (vt_brdf_rough's), or -1. */
static inline int vt_ibl_rough_find(const vt_ibl *ibl, float r)
{
    for (uint32_t k = 0; k < ibl->nr; k++)
        if (ibl->rough[k] == r) return (int)k;
    return -1;
}
/* The environment's radiance that ibl integrates, towards unit d. */
void vt_ibl_env(const vt_penv *pe, const float d[3], float out[3]);
/* Irradiance / pi at unit normal n (>= 0): a Lambert surface of albedo 1
 * returns this radiance. */
void vt_ibl_irradiance(const vt_ibl *ibl, const float n[3], float out[3]);
/* The prefiltered radiance towards unit r for roughness (linear between
 * the levels, bilinear within one). */
void vt_ibl_specular(const vt_ibl *ibl, const float r[3], float roughness, float out[3]);
/* RGB radiance >= 0 in 32 bits: 9-bit mantissas under a shared 5-bit
 * exponent (EXT_texture_shared_exponent's layout, its bias 10 rather
 * than 15: 2e-6 .. 2e6, above it clamped, NaN 0): each channel within
 * 1/512 of the largest. vt_shade.inl decodes it in lanes. */
uint32_t vt_rgb_e5(const float c[3]);
void vt_rgb_e5_decode(uint32_t t, float c[3]);
#define VT_E5_BIAS 10
/* The DFG table's A, B, C (0..1) as 10-bit unorms (bits 0, 10, 20). */
const uint32_t *vt_dfg_table10(void);

/* Octahedral coordinates (0..1) of unit d, and back. */
void vt_oct_uv(const float d[3], float uv[2]);
void vt_oct_dir(const float uv[2], float d[3]);

/* A RES x RES RGBA table at (x, y) in texel units (texel centres at
 * i + 0.5), bilinear, clamped to the edge texels: w x the RGB added to
 * out: vt_dfg and vt_ibl_specular (vt_shade.inl does the same in lanes). */
static inline void vt_bilerp_add(const float *t, int res, float x, float y, float w, float out[3])
{
    const float m = (float)(res - 1);
    x = x > 0 ? (x < m ? x : m) : 0;
    y = y > 0 ? (y < m ? y : m) : 0;
    int i = (int)x < res - 2 ? (int)x : res - 2, j = (int)y < res - 2 ? (int)y : res - 2;
    float ax = x - (float)i, ay = y - (float)j;
    const float *a = t + 4 * (j * res + i), *c = a + 4 * res;
    for (int k = 0; k < 3; k++) {
        float top = a[k] + ax * (a[4 + k] - a[k]), bot = c[k] + ax * (c[4 + k] - c[k]);
        out[k] += w * (top + ay * (bot - top));
    }
}

/* The GLSL of the above (vt_brdf_glsl.c): one fragment-shader object
 * defining vt_rough, vt_pbr_brdf, vt_pbr_ambient (see there), and what
 * the OpenGL renderer keeps for it: two textures on two units of their
 * own (GL 3.3 guarantees 16 fragment units; vt_gldraw uses 0..9). Call
 * with the renderer's context current. */
extern const char *const vt_brdf_fs;
#define VT_BRDF_UNIT_SPEC 14
#define VT_BRDF_UNIT_DFG 15
typedef struct vt_brdf_gl {
    unsigned tex[2];             /* prefiltered levels, DFG */
    uint32_t gen;                /* the vt_ibl gen uploaded */
} vt_brdf_gl;
void vt_brdf_gl_init(vt_brdf_gl *b);
void vt_brdf_gl_free(vt_brdf_gl *b);
/* Binds the textures (uploading ibl's levels when it was remade; NULL:
 * none this frame). */
void vt_brdf_gl_frame(vt_brdf_gl *b, const vt_ibl *ibl);
/* The uniforms on the program in use: units, u_ibl_on, u_sh. */
void vt_brdf_gl_uniforms(unsigned prog, const vt_penv *pe);

#endif
