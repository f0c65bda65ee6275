/*
 * vt_h264.h — H.264 for browser frames (issue 21, the FRAME format
 * VP_FRAME_H264): one encoder per stream over Debian's libx264 (build 164,
 * pkg-config x264; GPL-2+), a picture of 8-bit sRGB-encoded RGB(A) in, one
 * Annex B access unit out, and the RGB8 -> I420 conversion it feeds x264
 * with. vt_h264.c.
 *
 * The stream: Constrained Baseline (WebCodecs' `avc1.42E0xx`; the level is
 * x264's pick from the size, 3.1 at 1280x720), x264's ultrafast preset
 * (or superfast, veryfast: vt_h264_cfg.speed) tuned zerolatency (no
 * B-frames, no lookahead: one picture in, its access unit out at once),
 * CAVLC, Annex B start codes,
 * SPS and PPS before every IDR, so any key frame decodes alone (a browser
 * joining late, a decoder reset after a dropped frame). The first IDR also
 * carries x264's version SEI (about 600 bytes, once per encoder). VUI:
 * BT.709 primaries, transfer and matrix, limited range (16..235 / 16..240),
 * chroma location unspecified (0, the H.264 default: chroma co-sited with
 * the left luma column, centred between the two rows), which is how
 * vt_h264_rgb_to_i420 converts; a decoder that honours the VUI converts
 * back with the same matrix.
 *
 * Sizes: 2..4096 by 2..4096 pixels. 4:2:0 H.264 crops in units of 2 luma
 * samples (the spec's CropUnitX/Y), so no stream can say "333 wide": an
 * odd width or height is coded one pixel larger, the picture's last column
 * (row) repeated, and the decoded picture is (w + 1) & ~1 by (h + 1) & ~1
 * (vt_h264_coded_size). The receiver, who knows w x h from the FRAME
 * header, shows its top-left w x h (in the page: drawImage with a source
 * rectangle, or VideoFrame's visibleRect).
 *
 * Load it expects: one encoder per viewer stream, a frame at a time, 1
 * thread each. Costs on one core of the loaded development machine
 * (BENCHMARKS.md, bench_h264), a demo-city frame under motion, ultrafast:
 * 5.9 ms at 1280x720 (the conversion 0.8 of it), 13.7 ms at 1920x1080.
 * Memory: about 15 MB resident a 1280x720 encoder once it has encoded (29 MB
 * at 1920x1080, 4.3 MB at 640x360): x264's frame pool (the picture, its
 * reference and reconstruction with 32-pixel borders, and the half-size
 * copies its CRF rate control measures), so a daemon caps its H.264
 * streams, not only their bytes. The encode call does not allocate
 * beyond what x264 does inside.
 *
 * The conversion's AVX2 rows are picked as the renderer's kernels are, by
 * culling/'s cull_isa_default (CPUID; VANTAGE_ISA=scalar forces the
 * scalar rows), so a binary linking vt_h264 links libvculling too.
 *
 * Threading: an encoder is used by one thread at a time; different
 * encoders are independent (x264 keeps no global mutable state after its
 * first open).
 *
 * Errors: 0 or a negative code from vt_err.h: VT_ERR_INVALID bad
 * arguments or configuration (a size of 0 or 1, a CRF, fps, thread count
 * or speed out of range, a NULL pointer, a stride too small), VT_ERR_TOO_LARGE a
 * width or height over VT_H264_MAX_DIM, VT_ERR_NOMEM, VT_ERR_CODEC x264
 * refused or failed (its own message in err). `err` (may be NULL, any
 * errlen) receives a NUL-terminated message; "" on success.
 */
#ifndef VANTAGE_VT_H264_H
#define VANTAGE_VT_H264_H

#include "vt_err.h"

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Largest width and height (the protocol's frame limit, 4096 x 4096). */
#define VT_H264_MAX_DIM 4096u

typedef struct vt_h264 vt_h264;

/* The encoder's settings; zero is the default for every field but the size.
 *   width, height  2..VT_H264_MAX_DIM pixels (odd sizes: see the top)
 *   crf_x10        quality as x264's CRF times 10, 10..510 (CRF 1.0..51.0;
 *                  lower is better and larger); 0: 230 (CRF 23.0)
 *   max_kbps       0: CRF alone (a scene change may take any size); else a
 *                  VBV cap of max_kbps kbit/s with a buffer of one frame's
 *                  share (max_kbps / fps kbit, at least 1), so a frame
 *                  never takes much more than its share of the link; x264
 *                  raises the quantizer to hold it. 1..1000000
 *   fps            the frame rate VBV assumes, 1..1000; 0: 30
 *   keyint         a key frame (IDR) at least every keyint frames, 1..65535;
 *                  0: only when asked (vt_h264_encode's force_idr) and first
 *   threads        x264 threads (sliced: one slice each, one access unit
 *                  per picture still), 1..16; 0: 1
 *   speed          x264's preset, all tuned zerolatency and held to
 *                  constrained baseline: VT_H264_ULTRAFAST (0, the default),
 *                  VT_H264_SUPERFAST, VT_H264_VERYFAST. On the demo city's
 *                  moving street view at equal PSNR, superfast is about
 *                  25 % smaller than ultrafast for 1.3-1.8x its time, veryfast
 *                  about 33 % smaller for 1.8-2.4x (BENCHMARKS.md, bench_h264) */
typedef enum vt_h264_speed { VT_H264_ULTRAFAST = 0, VT_H264_SUPERFAST = 1, VT_H264_VERYFAST = 2 } vt_h264_speed;
typedef struct vt_h264_cfg {
    uint32_t width, height;
    int      crf_x10;
    uint32_t max_kbps;
    uint32_t fps;
    uint32_t keyint;
    int      threads;
    vt_h264_speed speed;
} vt_h264_cfg;

/* Opens an encoder for cfg in *e (NULL on error). The settings are fixed
 * for its life: a new size, CRF, cap or speed is a new encoder (whose
 * first picture is an IDR). Returns 0, VT_ERR_INVALID, VT_ERR_TOO_LARGE,
 * VT_ERR_NOMEM or VT_ERR_CODEC. */
int vt_h264_open(vt_h264 **e, const vt_h264_cfg *cfg, char *err, size_t errlen);

/* Encodes one picture: height rows of width pixels (the cfg's size), top
 * row first, rows `stride` bytes apart (>= width * pixel_bytes), each pixel
 * pixel_bytes bytes: 3 (R, G, B) or 4 (R, G, B, A: A ignored, so the
 * daemon's tone-mapped RGBA8 goes in as it is). force_idr: this picture is
 * an IDR (with SPS and PPS), so it decodes without any earlier one; the
 * first picture always is.
 * On success *au points at the access unit, *len bytes (all its NAL units,
 * each behind a 00 00 00 01 or 00 00 01 start code), owned by the encoder
 * and valid until the next vt_h264_encode or vt_h264_close; *key says
 * whether it is an IDR. On error *au is NULL, *len 0, and the encoder's
 * reference chain is unchanged unless x264 itself failed (VT_ERR_CODEC:
 * force an IDR next). Returns 0, VT_ERR_INVALID or VT_ERR_CODEC. */
int vt_h264_encode(vt_h264 *e, const uint8_t *pix, size_t stride, uint32_t pixel_bytes, bool force_idr,
                   const uint8_t **au, size_t *len, bool *key, char *err, size_t errlen);

/* Frees the encoder; NULL is fine. */
void vt_h264_close(vt_h264 *e);

/* The size a decoder shows for a w x h stream: w and h rounded up to even. */
void vt_h264_coded_size(uint32_t w, uint32_t h, uint32_t *coded_w, uint32_t *coded_h);

/* The conversion the encoder feeds x264 with, for tests and tools: pix as
 * vt_h264_encode's (w, h 1..VT_H264_MAX_DIM) to I420 of the coded size
 * (vt_h264_coded_size: cw x ch luma, cw/2 x ch/2 each chroma plane), the
 * last column and row repeated into the padding. BT.709 limited range on
 * the sRGB-encoded values as they are (R'G'B', as every video codec):
 * Y = 16 + 219 (0.2126 R + 0.7152 G + 0.0722 B) / 255, Cb and Cr from
 * B - Y and R - Y scaled to +-112 around 128, each rounded to nearest. A
 * chroma sample sits where H.264 puts it by default: on the even column,
 * between the two rows, so it is the [1 2 1] / 4 horizontal filter of the
 * two rows' average (the edge column repeated), not a 2x2 box (which would
 * shift colour half a pixel right). Integer arithmetic, within 1 code of
 * the exact result. Planes at y/u/v with strides ys/us/vs bytes (>= cw,
 * cw/2). Allocates 8 (cw + 2) bytes of scratch. Returns 0, VT_ERR_INVALID,
 * VT_ERR_TOO_LARGE or VT_ERR_NOMEM. */
int vt_h264_rgb_to_i420(uint32_t w, uint32_t h, const uint8_t *pix, size_t stride, uint32_t pixel_bytes,
                        uint8_t *y, size_t ys, uint8_t *u, size_t us, uint8_t *v, size_t vs);

#ifdef __cplusplus
}
#endif

#endif
