/*
 * vt_exr.h — OpenEXR output for the renderer: one call writes a
 * single-part scanline EXR from float buffers of any layout (planar,
 * interleaved, bottom-up), storing each channel as half or float under one
 * of the lossless compressions. A small reader (one channel back as float)
 * and a size query serve the tests and tools.
 *
 * Built on OpenEXRCore, the C layer of OpenEXR 3.1 (Debian: libopenexr-dev;
 * link `pkg-config --libs-only-L OpenEXR` -lOpenEXRCore-3_1, nothing from the
 * C++ libraries).
 *
 * Load it expects: a frame or a debug dump at a time, 1x1 to 8192x8192 and
 * beyond, a handful of channels. Cost is one pass over the samples to
 * gather them, the library's conversion to half, and compression (ZIP and
 * PIZ dominate: tens of ms per megapixel and channel on one core). Memory:
 * one chunk of float scratch, at most 32 rows x width x channels x 4 bytes
 * (5 MiB for 8192 wide, 5 channels), plus the library's chunk buffers.
 *
 * Files: the image goes to a new temporary file beside `path`
 * ("path.XXXXXXXXXXXXXXXX.tmp", created with O_EXCL, mode 0666 less the
 * umask) which is renamed over `path` once complete, so a reader never
 * sees a torn file and on any failure `path` is untouched (an old file of
 * that name survives) and the temporary is removed. Not fsync'ed: the
 * rename makes the file appear whole, not durable across a power cut. A
 * symlink at `path` is replaced, not written through.
 *
 * Threading: no shared state. Any number of calls may run at once on
 * different paths (two writes to the same path race, last rename wins).
 * The only static is a thread-local pointer to the running call's error
 * buffer (see vt_exr.c for why OpenEXRCore's error callback needs it).
 *
 * Errors: 0 or a negative code from render/'s table (vt_err.h), never an
 * errno — VT_ERR_INVALID bad arguments, VT_ERR_NOMEM, VT_ERR_NOT_FOUND a
 * missing file (or channel), VT_ERR_FILE any other file-system failure
 * (EACCES, ENOSPC, EFBIG, ...: strerror's text is in the message),
 * VT_ERR_CORRUPT a file that is not a valid EXR or is corrupt,
 * VT_ERR_UNSUPPORTED a valid EXR this reader does not handle (tiled, deep,
 * subsampled), VT_ERR_CODEC anything else the library reports. `err` (may be NULL, any errlen) receives a
 * NUL-terminated message, OpenEXRCore's own where it gave one, prefixed
 * with the path; it is set to "" on success.
 */
#ifndef VANTAGE_VT_EXR_H
#define VANTAGE_VT_EXR_H

#include "vt_err.h"

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* How a channel is stored in the file. Samples in memory are always float. */
typedef enum { VT_EXR_HALF, VT_EXR_FLOAT } vt_exr_type;

/* All lossless. ZIPS: 1 row per chunk; ZIP: 16; PIZ: 32 (wavelet+Huffman,
 * best on noisy images); RLE: 1 row, for flat areas (masks, ids). */
typedef enum { VT_EXR_NONE, VT_EXR_ZIP, VT_EXR_ZIPS, VT_EXR_PIZ, VT_EXR_RLE } vt_exr_compression;

typedef struct vt_exr_channel {
    const char  *name;     /* "R","G","B","A","Z", ...: 1..31 bytes, unique */
    vt_exr_type  type;     /* storage in the file */
    const float *data;     /* sample (x=0, y=0), the top-left pixel */
    ptrdiff_t    x_stride; /* floats between horizontal neighbours: 1 planar,
                              4 interleaved RGBA; any value, 0 repeats */
    ptrdiff_t    y_stride; /* floats from a row to the row below; negative
                              for bottom-up buffers (data = the top row) */
} vt_exr_channel;

/* Largest width and height accepted (the format's int32 window; width also
 * bounded so a row of floats fits the library's int32 byte strides). */
#define VT_EXR_MAX_WIDTH  (INT32_MAX / 4)
#define VT_EXR_MAX_HEIGHT INT32_MAX
/* Most channels in one file. */
#define VT_EXR_MAX_CHANNELS 1024u

/* Writes `path` as a single-part scanline EXR, width x height pixels, data
 * window and display window (0,0)-(width-1,height-1), increasing-Y line
 * order, with the nch channels of ch. Channel order in `ch` does not matter
 * (EXR stores them sorted by name; that is done here). Half conversion is
 * OpenEXRCore's: round to nearest even, overflow to +-inf, denormals kept,
 * NaN stays NaN. Reads sample (x, y) of channel c at
 * ch[c].data[x * x_stride + y * y_stride] for 0 <= x < width, 0 <= y <
 * height, nothing else; the buffers are not modified and may be shared.
 * Returns 0 or a negative errno value (see the top of this file). */
int vt_exr_write(const char *path, uint32_t width, uint32_t height, const vt_exr_channel *ch,
                 uint32_t nch, vt_exr_compression comp, char *err, size_t errlen);

/* Reads channel `name` of the first part of a scanline EXR into out[0 ..
 * width*height), planar, top row first, converting half or uint to float.
 * The file's data window must be exactly width x height (its origin may be
 * anywhere). VT_ERR_NOT_FOUND if there is no such channel, VT_ERR_INVALID if the size
 * differs. On error out may be partly written. */
int vt_exr_read_channel(const char *path, const char *name, float *out, uint32_t width,
                        uint32_t height, char *err, size_t errlen);

/* An EXR stream in memory, data[0..len) (the daemon's texture uploads):
 * the first part, a flat scanline image, as interleaved RGBA float, top
 * row first, into *rgba (malloc'ed by this call, 16 bytes per pixel;
 * caller frees with free()). Colour from channels R, G and B, or Y alone
 * (grey, copied to all three); A if there is one, else 1. Half and uint
 * samples are converted to float; values are as stored (NaN and infinity
 * kept: the caller decides). rgba NULL reads the header only: the size,
 * nothing allocated. On error nothing is allocated. "<memory>" in
 * messages. */
int vt_exr_decode_rgba(const uint8_t *data, size_t len, float **rgba, uint32_t *width, uint32_t *height,
                       char *err, size_t errlen);

/* Width and height of the first part's data window. */
int vt_exr_size(const char *path, uint32_t *width, uint32_t *height, char *err, size_t errlen);

#ifdef __cplusplus
}
#endif

#endif
