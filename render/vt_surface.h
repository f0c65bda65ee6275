/*
 * vt_surface.h — the scene model's shading as both renderers compute it
 * (internal to render/; the code is vt_scene.c, vt_gldraw.c's shader
 * mirrors it): the environment prepared once a frame (vt_penv), texture
 * sampling, a surface point's material evaluated and lit by the sun and
 * the sky's ambient, the ground plane's ray hit, the sky, fog, exposure.
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

/* The environment as the shading reads it (vt_penv_make). */
typedef struct vt_penv {
    bool on;                     /* an environment was given (else: the look before issue 19) */
    bool sun_on;
    float sun_dir[3], sun[3];    /* unit towards the sun; irradiance, lux */
    uint8_t sky_mode;
    float sky[3];
    const vt_texture *sky_tex;
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
    float fog[3];                /* fog radiance: fog_color x the sky's mean */
} vt_penv;

/* Prepares env (NULL: off) for a view at origin. */
void vt_penv_make(const vt_env *env, const double origin[3], vt_penv *pe);

/* The sky's radiance towards unit direction d (camera-independent). */
void vt_sky_radiance(const vt_penv *pe, const float d[3], float out[3]);

/* A texture slot sampled at uv (before its transform) with derivatives
 * duv/dx, duv/dy per pixel: RGBA, sRGB colour decoded when srgb. */
void vt_tex_sample(const vt_texref *r, const float uv[2], const float dx[2], const float dy[2], bool srgb,
                   float out[4]);
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

/* What the point lights need of it, and the radiance so far. */
typedef struct vt_surfout {
    float n[3];                  /* unit shading normal */
    float diffuse[3];            /* base x (1 - metallic) */
    float c[3];                  /* ambient + sun + emissive radiance (before fog and exposure) */
    float alpha;
} vt_surfout;

/* Evaluates a surface point: its material, the sky's ambient and the sun
 * (pe off: the ambient of before, VT_AMBIENT x albedo, and no sun). */
void vt_surface_shade(const vt_penv *pe, const vt_surfin *in, vt_surfout *out);
/* The base colour's alpha at a point (MASK materials test it in raster). */
float vt_surface_alpha(const vt_material *m, const float uv[2], const float dx[2], const float dy[2]);

/* The ground plane's hit for the pixel at NDC (X, Y): the camera-relative
 * point q and its nearness. false: no hit (off, parallel, behind, outside
 * the near and far planes). */
bool vt_ground_hit(const vt_penv *pe, const cull_view_rows *vr, int depth_mode, double X, double Y, double q[3],
                   double *near);
/* The unit direction of the view ray through NDC (X, Y), away from the eye. */
void vt_view_dir(const cull_view_rows *vr, double X, double Y, float d[3]);
/* Fog over the segment from the eye to camera-relative p: c blended. */
void vt_fog_apply(const vt_penv *pe, const float p[3], float c[3]);

/* Exposure over a drawn frame (rgb times the scale, alpha and depth kept):
 * FIXED from its EV100, AUTO from the log-average luminance of a grid of
 * pixels. pe off: nothing done. Returns the EV100 used (0 when off). */
float vt_exposure_apply(const vt_env *env, float *rgba, uint32_t width, uint32_t height, size_t stride);

#endif
