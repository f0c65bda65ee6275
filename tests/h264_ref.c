/*
 * h264_ref.c — libavcodec as the independent H.264 decoder, and the
 * double-precision inverse of vt_h264's conversion (h264_ref.h).
 */
#include "h264_ref.h"

#include <math.h>
#include <string.h>

#include <libavutil/pixfmt.h>

int h264_dec_open(h264_dec *d)
{
    memset(d, 0, sizeof *d);
    const AVCodec *codec = avcodec_find_decoder(AV_CODEC_ID_H264);
    if (!codec || !(d->c = avcodec_alloc_context3(codec))) return -1;
    d->c->thread_count = 1;
    d->c->flags |= AV_CODEC_FLAG_LOW_DELAY;
    d->pkt = av_packet_alloc();
    d->f = av_frame_alloc();
    if (!d->pkt || !d->f || avcodec_open2(d->c, codec, NULL) < 0) {
        h264_dec_close(d);
        return -1;
    }
    return 0;
}

void h264_dec_close(h264_dec *d)
{
    av_frame_free(&d->f);
    av_packet_free(&d->pkt);
    avcodec_free_context(&d->c);
}

int h264_dec_au(h264_dec *d, const uint8_t *au, size_t len)
{
    /* a packet of its own: the decoder reads up to AV_INPUT_BUFFER_PADDING_SIZE past the end */
    if (len > INT32_MAX - AV_INPUT_BUFFER_PADDING_SIZE || av_new_packet(d->pkt, (int)len) < 0) return -1;
    memcpy(d->pkt->data, au, len);
    int rc = avcodec_send_packet(d->c, d->pkt);
    av_packet_unref(d->pkt);
    if (rc < 0 || avcodec_receive_frame(d->c, d->f) < 0) return -1;
    return d->f->format == AV_PIX_FMT_YUV420P ? 0 : -1;
}

/* The exact inverse of one sample triple, unrounded, 0..255 scale. */
static void ycc_to_rgb(double y, double cb, double cr, double rgb[3])
{
    const double kr = 0.2126, kb = 0.0722, kg = 1 - kr - kb;
    double yy = (y - 16) / 219, pb = (cb - 128) / 224, pr = (cr - 128) / 224;
    double r = yy + 2 * (1 - kr) * pr, b = yy + 2 * (1 - kb) * pb;
    double g = (yy - kr * r - kb * b) / kg;
    rgb[0] = 255 * r, rgb[1] = 255 * g, rgb[2] = 255 * b;
}

/* Chroma of plane p (cw2 x ch2, stride s) at luma (x, y): sample (i, j)
 * sits at luma (2i, 2j + 0.5), bilinear between the nearest four, edges held. */
static double chroma_at(const uint8_t *p, int s, int cw2, int ch2, int x, int y)
{
    double fx = x / 2.0, fy = (y - 0.5) / 2.0;
    if (fy < 0) fy = 0;
    int i0 = (int)fx, j0 = (int)fy;
    int i1 = i0 + 1 < cw2 ? i0 + 1 : cw2 - 1, j1 = j0 + 1 < ch2 ? j0 + 1 : ch2 - 1;
    if (i0 >= cw2) i0 = i1 = cw2 - 1;
    if (j0 >= ch2) j0 = j1 = ch2 - 1;
    double ax = fx - (int)fx, ay = fy - (int)fy;
    double top = p[j0 * s + i0] * (1 - ax) + p[j0 * s + i1] * ax;
    double bot = p[j1 * s + i0] * (1 - ax) + p[j1 * s + i1] * ax;
    return top * (1 - ay) + bot * ay;
}

void h264_ref_px(const uint8_t *const pl[3], const int st[3], int cw, int ch, int x, int y, uint8_t o[3])
{
    double c[3];
    ycc_to_rgb(pl[0][y * st[0] + x], chroma_at(pl[1], st[1], cw / 2, ch / 2, x, y),
               chroma_at(pl[2], st[2], cw / 2, ch / 2, x, y), c);
    for (int k = 0; k < 3; k++) o[k] = (uint8_t)(c[k] < 0 ? 0 : c[k] > 255 ? 255 : lround(c[k]));
}

void h264_ref_to_rgb(const uint8_t *const pl[3], const int st[3], int cw, int ch, int w, int h, uint8_t *rgb)
{
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) h264_ref_px(pl, st, cw, ch, x, y, rgb + 3 * ((size_t)y * w + x));
}

void h264_ref_frame_rgb(const AVFrame *f, int w, int h, uint8_t *rgb)
{
    const uint8_t *pl[3] = {f->data[0], f->data[1], f->data[2]};
    const int st[3] = {f->linesize[0], f->linesize[1], f->linesize[2]};
    h264_ref_to_rgb(pl, st, f->width, f->height, w, h, rgb);
}

double h264_ref_psnr(const uint8_t *a, const uint8_t *b, size_t stride, uint32_t pb, uint32_t w, uint32_t h)
{
    double se = 0;
    for (uint32_t y = 0; y < h; y++)
        for (uint32_t x = 0; x < w; x++)
            for (uint32_t k = 0; k < 3; k++) {
                double d = (double)a[3 * ((size_t)y * w + x) + k] - b[y * stride + x * pb + k];
                se += d * d;
            }
    double mse = se / (3.0 * w * h);
    return mse > 0 ? 10 * log10(255.0 * 255.0 / mse) : 99;
}

int h264_ref_nal_types(const uint8_t *au, size_t len, int *types, int cap)
{
    int n = 0;
    for (size_t i = 0; i + 3 < len; i++)
        if (au[i] == 0 && au[i + 1] == 0 && au[i + 2] == 1) {
            if (n < cap) types[n] = au[i + 3] & 31;
            n++;
            i += 3;
        }
    return n;
}
