/*
 * vt_surface.h — the scene model's shading as both renderers compute it
 * (internal to render/; the code is vt_scene.c, vt_gldraw.c's shader
 * mirrors it): the environment prepared once a frame (vt_penv), texture
 * sampling, a surface point's material evaluated (the kernels light it:
 * vt_shade.inl), the ground plane, the sky, fog (exposure: vt_post.h).
 * Positions are camera-relative (the view's origin subtracted), in float
 * for shading, in double where they are solved for.
 */
#ifndef VANTAGE_VT_SURFACE_H
#define VANTAGE_VT_SURFACE_H

#include "culling.h"
#include "vt_scene.h"

#include <stdbool.h>
#include <stdint.h>

#define VT_DEFAULT_ROUGHNESS 0.6f
/* The analytic sky is tabulated once a frame (equirectangular, as an
 * environment map is laid out) and read bilinearly by both renderers: a
 * sky pixel then costs one lookup, not three Perez evaluations. */
#define VT_SKY_TAB_W 256u
#define VT_SKY_TAB_H 128u
#define VT_SKY_TAB_FLOATS (4u * VT_SKY_TAB_W * VT_SKY_TAB_H)
/* The table, kept from frame to frame while the sky's inputs (sun
 * direction, turbidity, multipliers) stay the same: 32768 Perez
 * evaluations (a few ms) only when the sky changes. */
typedef struct vt_skytab {
    float t[VT_SKY_TAB_FLOATS];
    float key[7];
    bool ok;
} vt_skytab;

/* The environment as the shading reads it (vt_penv_make). */
typedef struct vt_penv {
    bool on;                     /* an environment was given (else: the look before issue 19) */
    bool sun_on;
    float sun_dir[3], sun[3];    /* unit towards the sun; irradiance, lux */
    uint8_t sky_mode;
    float sky[3];
    const vt_texview *sky_img;   /* TEXTURE: the environment map; ANALYTIC: the table */
    vt_texview sky_tab;          /* ANALYTIC: the table as a float texture */
    float sky_mul[3];            /* times what sky_img gives */
    float sky_rot;
    /* ANALYTIC: Perez coefficients (Y, x, y) x (A..E), zenith values,
       1 / F(0, theta_s) per channel, the sun's zenith angle */
    float perez[3][5], zenith[3], inv_f0[3], theta_s;
    float amb_up[3], amb_down[3]; /* ambient radiance from above and below */
    bool ground;
    float ground_y;              /* camera-relative */
    float ground_albedo[3];
    const vt_material *ground_mat;
    float ground_uv0[2];         /* the view origin's x, z, modulo 4096 m */
    float fog_density, fog_falloff, fog_y0; /* fog_y0: the fog's reference height, camera-relative */
    float fog_e0;                /* e^min(falloff y0, 80): the height fog's factor at the eye */
    float fog[3];                /* fog radiance: fog_color x the sky's mean */
    const struct vt_ibl *ibl;    /* image-based ambient (vt_brdf.h), or NULL: the two-colour
                                    hemisphere of amb_up, amb_down (VT_FX_IBL off); the
                                    renderer sets it after vt_penv_make */
} vt_penv;

/* Prepares env (NULL: off) for a view at origin; tab (the caller's, kept
 * while pe is used) holds the analytic sky's table, made again only when
 * the sky changed. */
void vt_penv_make(const vt_env *env, const double origin[3], vt_skytab *tab, vt_penv *pe);

/* The sky's radiance towards unit direction d (camera-independent). */
void vt_sky_radiance(const vt_penv *pe, const float d[3], float out[3]);
/* With an image (pe->sky_img): direction d's coordinates in it, and the
 * image (bilinear, times sky_mul) at them. */
void vt_sky_uv(const vt_penv *pe, const float d[3], float uv[2]);
void vt_sky_sample(const vt_penv *pe, const float uv[2], float out[3]);

/* An integer texel coordinate wrapped into 0..n-1 (GL's rules, mode a
 * VT_WRAP_*). */
static inline int32_t vt_wrap_i(int32_t i, int32_t n, int mode)
{
    if (mode == VT_WRAP_CLAMP) return i < 0 ? 0 : i >= n ? n - 1 : i;
    if (mode == VT_WRAP_MIRROR) {
        int32_t p = i % (2 * n);
        if (p < 0) p += 2 * n;
        return p < n ? p : 2 * n - 1 - p;
    }
    if (!(n & (n - 1))) return i & (n - 1); /* a power of two (most textures): the same, without a division */
    int32_t p = i % n;
    return p < 0 ? p + n : p;
}

/* A texture slot sampled at uv (vt_texsample.c) (before its transform) with derivatives
 * duv/dx, duv/dy per pixel: RGBA, sRGB colour decoded when srgb. */
void vt_tex_sample(const vt_texref *r, const float uv[2], const float dx[2], const float dy[2], bool srgb,
                   float out[4]);
/* The sRGB decode of each 8-bit value (256 floats, made once). */
const float *vt_srgb_table(void);
/* The transform of slot r applied to uv (a direction when vec: no offset). */
void vt_tex_xform(const vt_texref *r, const float uv[2], bool vec, float out[2]);

/* A surface point to shade. */
typedef struct vt_surfin {
    const vt_material *mat;      /* NULL: the default material of albedo */
    const float *albedo;         /* 3 */
    float p[3];                  /* camera-relative position */
    float n[3];                  /* interpolated normal (any length) */
    float t[4];                  /* tangent xyz, handedness w; has_t */
    float uv[2], dx[2], dy[2];   /* UV and its per-pixel derivatives; has_uv */
    bool has_uv, has_t;
} vt_surfin;

/* A surface point's material, evaluated (textures sampled, the normal
 * mapped): what the shading kernels light (vt_shade.inl: the sky's
 * ambient, the sun, the point lights; vt_gldraw_glsl.c the same). */
typedef struct vt_surfout {
    float n[3];                  /* unit shading normal */
    float diffuse[3];            /* base x (1 - metallic) */
    float f0[3];                 /* specular colour at normal incidence: 0.04 .. base by metallic */
    float em[3];                 /* emitted radiance */
    float a2;                    /* GGX alpha^2 = roughness^4 (vt_brdf.h) */
    float rough;                 /* perceptual roughness, clamped to VT_MIN_ROUGHNESS..1 */
    float alpha;
} vt_surfout;

/* Evaluates a surface point's material (NULL: the default of albedo). */
void vt_surface_params(const vt_surfin *in, vt_surfout *out);
/* The base colour's alpha at a point (MASK materials test it in raster). */
float vt_surface_alpha(const vt_material *m, const float uv[2], const float dx[2], const float dy[2]);

/* The ground plane's hit for the pixel at NDC (X, Y): the camera-relative
 * point q and its nearness. false: no hit (off, parallel, behind, outside
 * the near and far planes). The slow, direct solve (the reference). */
bool vt_ground_hit(const vt_penv *pe, const cull_view_rows *vr, int depth_mode, double X, double Y, double q[3],
                   double *near);

/* The ground plane in screen space, once a frame: a plane's nearness is
 * affine in (X, Y), and so are the near and far planes' functions over
 * (X, Y, nearness) (the clip rows x, y, d, w are a basis of the affine
 * functions of a point): a pixel's test is three multiply-adds. */
typedef struct vt_ground {
    bool on;
    double n[3];            /* nearness = n0 X + n1 Y + n2 */
    double lim[2][4];       /* a hit is drawn where lim[k] . (X, Y, N, 1) >= 0 for both k */
    bool persp;             /* and, perspective, N > 0 (in front of the eye) */
    double inv[4][4];       /* (q, 1) ~ inv (X, Y, N, 1) */
} vt_ground;
void vt_ground_make(const vt_penv *pe, const cull_view_rows *vr, int depth_mode, vt_ground *g);
static inline bool vt_ground_at(const vt_ground *g, double X, double Y, double *near)
{
    if (!g->on) return false;
    double N = g->n[0] * X + g->n[1] * Y + g->n[2];
    *near = N;
    if (g->persp && !(N > 0)) return false;
    for (int k = 0; k < 2; k++)
        if (!(g->lim[k][0] * X + g->lim[k][1] * Y + g->lim[k][2] * N + g->lim[k][3] >= 0)) return false;
    return true;
}
/* Inverts the 4x4 m (rows) into o; false if singular or not finite.
 * Gauss-Jordan with partial pivoting, in double (the ground's and the
 * ambient occlusion's reconstruction from (X, Y, nearness)). */
bool vt_inv4(const double m[4][4], double o[4][4]);
/* The camera-relative point of the ground at (X, Y) with nearness N. */
void vt_ground_point(const vt_ground *g, double X, double Y, double N, double q[3]);
/* The view ray through NDC (X, Y) away from the eye, unnormalised, as
 * c0 + X c1 (per row Y). */
void vt_view_dir_row(const cull_view_rows *vr, double Y, float c0[3], float c1[3]);
/* Fog over the segment from the eye to camera-relative p: c blended. */
void vt_fog_apply(const vt_penv *pe, const float p[3], float c[3]);

#endif
