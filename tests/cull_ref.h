/*
 * cull_ref.h — the slow, obviously-correct model the culling core is tested
 * against: long double, world coordinates straight from the entity desc (no
 * cells, no rebasing, no float storage), planes from clip-space planes
 * mapped through the transposed matrix, one entity and one view at a time.
 */
#ifndef VANTAGE_CULL_REF_H
#define VANTAGE_CULL_REF_H

#include "culling.h"
#include <stdbool.h>

typedef struct ref_view {
    long double plane[6][4]; /* unit normal, d; inside >= 0 */
    bool        always[6];   /* plane at infinity: always satisfied */
    long double m[16];
    long double origin[3];
    long double vw, vh;
} ref_view;

typedef struct ref_verdict {
    long double sphere_margin; /* min over planes of (distance + r): >= 0 keeps */
    long double inner_margin;  /* min over planes of (distance - r): >= 0 fully inside */
    long double aabb_margin;   /* min over planes of the p-vertex distance */
    long double area;          /* projected AABB rectangle, pixels, clipped */
    bool        behind;        /* a corner at w <= 0: area = the viewport */
    bool        visible;       /* sphere_margin >= 0 && aabb_margin >= 0 */
} ref_verdict;

void ref_view_make(ref_view *v, const cull_view_desc *d);
/* e must be normalised (as cull_entity_get returns it). */
void ref_test(const ref_view *v, const cull_entity_desc *e, ref_verdict *out);

#endif
