/*
 * vt_shadow.h — the sun's cascaded shadow maps (issue 20), drawn by the
 * project's own rasterizer in the software path (and by GL in the GL
 * path, with the same cascade fitting): what the shading kernels ask per
 * pixel is the sun's visibility at a camera-relative point.
 */
#ifndef VANTAGE_VT_SHADOW_H
#define VANTAGE_VT_SHADOW_H

#include <stdint.h>

typedef struct vt_shadow vt_shadow;

/* The fraction of the sun that reaches camera-relative point p with unit
 * geometric normal n, 0 (in shadow) .. 1 (lit), PCF-filtered. sh NULL: 1. */
float vt_shadow_sun(const vt_shadow *sh, const float p[3], const float n[3]);

#endif
