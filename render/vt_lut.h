/*
 * vt_lut.h — colour grading by a 3D lookup table (issue 20), read from the
 * .cube format of Adobe and Resolve, applied by the tone map
 * (vt_tonemap_desc.lut, vt_image.h) after ACES to the display values
 * (sRGB-encoded, 0..1: the space grading tools export .cube LUTs for).
 *
 * The format (Adobe's "Cube LUT Specification" 1.0): text lines; `#`
 * starts a comment line; keywords first: TITLE "text", LUT_3D_SIZE N,
 * DOMAIN_MIN r g b, DOMAIN_MAX r g b (default 0 0 0 and 1 1 1), and
 * Resolve's LUT_3D_INPUT_RANGE lo hi; then N^3 rows of three numbers,
 * red changing fastest. 1D LUTs are refused (VT_ERR_UNSUPPORTED). Every
 * bad input is VT_ERR_CORRUPT with a message naming the line.
 */
#ifndef VANTAGE_VT_LUT_H
#define VANTAGE_VT_LUT_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Limits: LUT_3D_SIZE 2..128 (the tools export 17, 33, 65; 128^3 rows are
 * 25 MB of floats), a file of at most 64 MiB, a line of at most 1023
 * bytes. */
#define VT_LUT_MAX_SIZE 128u
#define VT_LUT_MAX_FILE (64u << 20)
#define VT_LUT_MAX_LINE 1023u

typedef struct vt_lut3d {
    uint32_t n;          /* LUT_3D_SIZE */
    float dmin[3], dmax[3]; /* the input domain, dmin < dmax per channel */
    float *rgb;          /* n^3 rows of r, g, b; red fastest (malloc'ed) */
    char title[128];     /* TITLE, cut to fit; "" without one */
} vt_lut3d;

/* Parses len bytes of .cube text into *out (its rgb malloc'ed; free with
 * vt_lut_free). 0, or VT_ERR_CORRUPT / VT_ERR_UNSUPPORTED / VT_ERR_TOO_LARGE
 * with "line N: what" in err, or VT_ERR_NOMEM. *out is zeroed on error. */
int vt_lut_parse(const char *text, size_t len, vt_lut3d *out, char *err, size_t errlen);

/* Reads and parses the file at path: as vt_lut_parse, plus VT_ERR_FILE /
 * VT_ERR_NOT_FOUND for the file system; err starts with the path. */
int vt_lut_load(const char *path, vt_lut3d *out, char *err, size_t errlen);

/* Frees out->rgb and zeroes *l. l may be NULL. */
void vt_lut_free(vt_lut3d *l);

/* The LUT at in (clamped to the domain) by trilinear interpolation of the
 * 8 surrounding rows. in and out may alias. */
void vt_lut_apply(const vt_lut3d *l, const float in[3], float out[3]);

/* vt_lut_apply inline, for loops over pixels: k[c] = (n - 1) /
 * (dmax[c] - dmin[c]), computed once by the caller (vt_lut_scale). */
static inline void vt_lut_scale(const vt_lut3d *l, float k[3])
{
    for (int c = 0; c < 3; c++) k[c] = (float)(l->n - 1) / (l->dmax[c] - l->dmin[c]);
}

static inline void vt_lut_sample(const vt_lut3d *l, const float k[3], const float in[3], float out[3])
{
    const uint32_t n = l->n;
    uint32_t i[3];
    float f[3];
    for (int c = 0; c < 3; c++) {
        float x = (in[c] - l->dmin[c]) * k[c];
        float top = (float)(n - 1);
        x = x > 0 ? (x < top ? x : top) : 0.0f; /* NaN: 0 */
        uint32_t q = (uint32_t)x;
        if (q > n - 2) q = n - 2;
        i[c] = q;
        f[c] = x - (float)q;
    }
    const size_t sr = 3, sg = 3 * (size_t)n, sb = 3 * (size_t)n * n;
    const float *p = l->rgb + i[0] * sr + i[1] * sg + i[2] * sb;
    for (int c = 0; c < 3; c++) {
        float c00 = p[c] + (p[sr + c] - p[c]) * f[0];
        float c10 = p[sg + c] + (p[sg + sr + c] - p[sg + c]) * f[0];
        float c01 = p[sb + c] + (p[sb + sr + c] - p[sb + c]) * f[0];
        float c11 = p[sb + sg + c] + (p[sb + sg + sr + c] - p[sb + sg + c]) * f[0];
        float c0 = c00 + (c10 - c00) * f[1], c1 = c01 + (c11 - c01) * f[1];
        out[c] = c0 + (c1 - c0) * f[2];
    }
}

#ifdef __cplusplus
}
#endif
#endif
