/*
 * occ_ref.h — the exact occlusion reference: a ray caster in double.
 *
 * For every pixel centre of a W x H image, a ray from the view's near plane
 * (unprojected through the inverse view-projection); the nearest front-
 * facing occluder triangle hit at or beyond the near plane (Moller-Trumbore,
 * inclusive edges); an object AABB is visible if, at some pixel centre, the
 * ray enters it (slab test, clipped to the near plane) strictly before the
 * nearest occluder hit. No rasteriser, no depth buffer format, no shared
 * code with culling/ beyond the matrix helpers: an independent model.
 */
#ifndef VANTAGE_OCC_REF_H
#define VANTAGE_OCC_REF_H

#include "culling.h"
#include <stdbool.h>
#include <stddef.h>

typedef struct occ_ref {
    uint32_t w, h;
    double origin[3];
    double *ray;      /* 6 per pixel: start (camera-relative), direction */
    double *t;        /* nearest occluder hit parameter per pixel, INFINITY = none */
    double m[16];     /* the view-projection (camera-relative) */
    bool   ortho;
    double nearfn[4]; /* near-plane function: >= 0 in front */
} occ_ref;

/* Builds the rays for view v at w x h. Returns 0, or -1 (out of memory or
 * a singular matrix). */
int  occ_ref_init(occ_ref *r, const cull_view *v, uint32_t w, uint32_t h);
void occ_ref_free(occ_ref *r);
/* Casts the rays against n triangles (9 doubles each, world space,
 * counter-clockwise front faces). Accumulates: call once per batch. */
void occ_ref_add_triangles(occ_ref *r, const double *tri, size_t n);
/* 1 if the world AABB is visible at some pixel centre. */
bool occ_ref_box_visible(const occ_ref *r, const double mn[3], const double mx[3]);

#endif
