/*
 * video.h — H.264 frames (VP_FRAME_H264) in the daemon: a stream's encoder
 * (render/vt_h264.h) and the rules of its chain, for frames.c.
 *
 * A stream keeps one encoder between frames; while a frame is drawn it
 * travels with the job to the worker and back (the loop never touches it
 * then, so a connection that ends mid-frame frees it when the job comes
 * back). Its settings (size, CRF, rate cap, frame rate) are fixed for its
 * life: a subscription that changes one gets a new encoder, whose first
 * frame is a key frame. A frame encoded and then not sent (the stream
 * re-aimed to another size, or the frame dropped) leaves a gap in the
 * chain the viewer's decoder cannot bridge: the next frame is a key frame.
 */
#ifndef VANTAGE_VIDEO_H
#define VANTAGE_VIDEO_H

#include "protocol.h"

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

typedef struct video_enc video_enc;

/* Encodes rgba8 (width x height RGBA8, top row first, packed) as the next
 * frame of *ve's chain (a new encoder in *ve when it has none or its
 * settings differ: m's size, quality and max_kbps, and fps), a key frame
 * when key. *au / *len: the access unit, valid until the next call or
 * video_enc_free; *is_key whether it is a key frame. threads: x264's
 * (sliced) threads for an encoder opened by this call (1..16; a chain
 * keeps the count it began with). 0, or a vt_err.h code with err (an x264
 * failure also drops the encoder: the next frame starts a new chain). */
int video_encode(video_enc **ve, uint32_t width, uint32_t height, const vp_render *m, uint32_t fps, bool key,
                 uint32_t threads, const uint8_t *rgba8, const uint8_t **au, size_t *len, bool *is_key, char *err,
                 size_t errlen);
void video_enc_free(video_enc *ve);

#endif
