/*
 * h264_ref.h — the independent side of the H.264 checks (test_h264.c,
 * bench_h264.c): Debian's libavcodec decoder (FFmpeg 5.1's h264, linked
 * into the tests and the bench only, never the daemon), the exact BT.709
 * limited-range inverse in double with chroma interpolated from where
 * H.264 sites it (co-sited with the even column, between the two rows),
 * PSNR, and an Annex B NAL lister. Slow and plain on purpose: about 40 ns
 * a pixel.
 */
#ifndef VANTAGE_H264_REF_H
#define VANTAGE_H264_REF_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include <libavcodec/avcodec.h>
#include <libavutil/frame.h>

/* One decoder: single-threaded, low delay (a picture out per access unit,
 * as WebCodecs' optimizeForLatency). f is the last picture decoded. */
typedef struct h264_dec {
    AVCodecContext *c;
    AVPacket       *pkt;
    AVFrame        *f;
} h264_dec;

/* 0, or -1 (no h264 decoder, out of memory). */
int h264_dec_open(h264_dec *d);
/* Frees what open made; a zeroed or closed decoder is fine. */
void h264_dec_close(h264_dec *d);
/* Decodes one access unit into d->f; 0, or -1 when the decoder refused it
 * or gave no YUV420P picture for it (nothing held back is allowed). */
int h264_dec_au(h264_dec *d, const uint8_t *au, size_t len);

/* Pixel (x, y) of I420 planes pl (strides st; cw x ch luma) as RGB8: the
 * exact BT.709 limited-range inverse of bilinear chroma, rounded, clamped. */
void h264_ref_px(const uint8_t *const pl[3], const int st[3], int cw, int ch, int x, int y, uint8_t o[3]);
/* The top-left w x h of planes pl as packed RGB8 (3 w bytes a row). */
void h264_ref_to_rgb(const uint8_t *const pl[3], const int st[3], int cw, int ch, int w, int h, uint8_t *rgb);
/* The same of a decoded picture. */
void h264_ref_frame_rgb(const AVFrame *f, int w, int h, uint8_t *rgb);

/* PSNR in dB of packed RGB8 a against pixels b (pb bytes each, R G B
 * first, stride bytes a row) over w x h x 3; 99 for equal pictures. */
double h264_ref_psnr(const uint8_t *a, const uint8_t *b, size_t stride, uint32_t pb, uint32_t w, uint32_t h);

/* The NAL unit types of an Annex B stream in order, at most cap of them
 * stored; returns how many there are. */
int h264_ref_nal_types(const uint8_t *au, size_t len, int *types, int cap);

#endif
