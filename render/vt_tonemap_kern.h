/*
 * vt_tonemap_kern.h — the tone map's lane kernels (internal to
 * vt_tonemap*.c): the daemon's layout (interleaved RGB in RGBA floats,
 * ACES, no alpha, no LUT) 8 pixels at a time in AVX2, with the same codes
 * as the scalar aces8 bit for bit (test_image_tonemap_rgbx).
 */
#ifndef VANTAGE_VT_TONEMAP_KERN_H
#define VANTAGE_VT_TONEMAP_KERN_H

#include <stdint.h>

/* The bucket table both paths read: entry i covers the floats whose bits
 * are ACES_LO_BITS + (i << 15) .. + 0x7fff (2^-8 of an octave over
 * [2^-12, 16)); 1 + the code of the bucket's first float in the high
 * 16 bits (the lanes' comparison gives -1 below the threshold), and in
 * the low 16 bits the offset (bits - the bucket's first) of the first
 * float with the next code, 0x8000 if the bucket holds none. Every bucket
 * holds at most one threshold (aces_init checks it): one lookup and one
 * comparison give the exact code. */
#define VT_ACES_LO_BITS 0x39800000u /* 2^-12 */
#define VT_ACES_HI_BITS 0x41800000u /* 16 */
#define VT_ACES_NBUCKETS ((VT_ACES_HI_BITS - VT_ACES_LO_BITS) >> 15)

/* The pixels [0, n) of a row of RGBX floats (x_stride 4) to RGBA8 (alpha
 * 255), colour times scale (in double, as the scalar path) then ACES and
 * sRGB8; n a multiple of 8, and pixel n - 1's fourth float readable. */
typedef void (*vt_aces_rgbx_fn)(const float *p, uint32_t n, double scale, const uint32_t *tab, uint8_t *o);

/* The AVX2 instance, or NULL where this build has none (CONFIG=scalar). */
vt_aces_rgbx_fn vt_aces_rgbx_avx2(void);

#endif
