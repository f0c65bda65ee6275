/*
 * vt_texture.h — textures as the daemon keeps them (issue 19): an
 * uploaded image (PNG, JPEG or OpenEXR, whole in memory) decoded once,
 * with its mip chain. The format is told by the uploader (libvantage's
 * vtc_texture_format tells it from the first bytes).
 *
 * PNG and JPEG become RGBA8 (JPEG: A = 255) with a full mip chain down to
 * 1x1, each level from the one above by an exact box filter: a level-n+1
 * pixel is the area-weighted mean of the level-n pixels under its
 * footprint, so odd sizes (a 5-wide level becomes 2 wide, each pixel
 * covering 2.5 source pixels) weigh the shared pixel by the part it
 * covers, and nothing is dropped or shifted. Colour data (srgb) is
 * averaged in linear light (sRGB decoded, averaged, encoded back with
 * vt_srgb8_from_linear's exact rounding), other data and alpha as stored.
 * Colour is not weighted by alpha (glGenerateMipmap's convention).
 *
 * EXR becomes RGBA float, level 0 only (environment maps are sampled by
 * direction; no mip chain is kept for them). Values as stored: the caller
 * checks finiteness (the daemon refuses NaN and infinity).
 *
 * Cost: decoding (libpng ~8 ms, libjpeg ~2 ms per 1280x720, see vt_png.c,
 * vt_jpeg.c) plus the mip chain, one pass over 4/3 of the image with at
 * most 3x3 taps per pixel. Memory: what vt_texture_pixel_bytes says, plus
 * a transient level-0 RGB buffer for JPEG.
 *
 * Errors: render/'s codes (vt_err.h), the decoder's own message in err
 * ("<memory>: ...").
 */
#ifndef VANTAGE_VT_TEXTURE_H
#define VANTAGE_VT_TEXTURE_H

#include "vt_err.h"

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

/* Formats: the protocol's VP_TEX_PNG / JPEG / EXR values. */
enum { VT_TEXTURE_PNG = 0, VT_TEXTURE_JPEG = 1, VT_TEXTURE_EXR = 2 };

/* A decoded texture. LDR: levels RGBA8 buffers in mip[], level i is
 * max(1, w >> i) x max(1, h >> i), packed rows, top row first. EXR: hdr,
 * w x h RGBA float, levels 1, mip NULL. */
typedef struct vt_texture {
    uint32_t w, h, levels;
    uint8_t **mip;
    float *hdr;
} vt_texture;

/* Name of a format ("PNG", "JPEG", "EXR"; "?" otherwise). */
const char *vt_texture_format_name(int format);

/* The size in the image's header, nothing decoded: 0 or a code with err. */
int vt_texture_info(int format, const uint8_t *data, size_t len, uint32_t *w, uint32_t *h, char *err,
                    size_t errlen);
/* Mip levels of a w x h texture: floor(log2(max(w, h))) + 1. */
uint32_t vt_texture_levels(uint32_t w, uint32_t h);
/* Bytes of pixels a decoded w x h texture of the format holds (all LDR
 * levels; EXR level 0 as float RGBA). */
uint64_t vt_texture_pixel_bytes(int format, uint32_t w, uint32_t h);

/* Decodes data[0..len) of the format into *out (zeroed first; free with
 * vt_texture_free) and builds the mip chain (srgb: averaged in linear
 * light). On error nothing is held. */
int vt_texture_decode(int format, bool srgb, const uint8_t *data, size_t len, vt_texture *out, char *err,
                      size_t errlen);
/* Frees what t holds and zeroes it (NULL, or zeroed: nothing). */
void vt_texture_free(vt_texture *t);

/* One mip step: src (sw x sh RGBA8, packed) box-filtered into dst
 * (max(1, sw/2) x max(1, sh/2), packed), as described at the top. */
void vt_texture_mip_down(const uint8_t *src, uint32_t sw, uint32_t sh, uint8_t *dst, bool srgb);

#endif
