/*
 * cli_render.c — `vantage render`: one frame from the daemon, written as
 * OpenEXR (half RGBA + float Z, from the raw frame), PNG (tone mapped here
 * from the raw frame) or JPEG (encoded by the daemon), chosen by the output
 * file's extension.
 */
#include "cli.h"
#include "vt_exr.h"
#include "vt_image.h"

#include <errno.h>
#include <getopt.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

static bool ends_with(const char *s, const char *suffix)
{
    size_t n = strlen(s), m = strlen(suffix);
    return n >= m && !strcasecmp(s + n - m, suffix);
}

int cmd_render(cli *k, int argc, char **argv)
{
    double eye[3], at[3], up[3] = {0, 1, 0}, fov = 60, znear = 0.1, zfar = 10000, ev = 0;
    bool have_eye = false, have_at = false;
    unsigned w = 1280, h = 720, quality = 85;
    uint8_t flags = 0;
    const char *out = NULL;
    static const struct option opts[] = {
        {"eye", 1, 0, 'e'}, {"at", 1, 0, 'a'}, {"up", 1, 0, 'u'}, {"fov", 1, 0, 'f'}, {"near", 1, 0, 'n'},
        {"far", 1, 0, 'F'}, {"size", 1, 0, 's'}, {"exposure", 1, 0, 'x'}, {"quality", 1, 0, 'q'},
        {"no-occlusion", 0, 0, 'N'}, {"output", 1, 0, 'o'}, {"help", 0, 0, 'h'}, {0, 0, 0, 0}};
    const char *use = "render --eye X,Y,Z --at X,Y,Z [--up X,Y,Z] [--fov DEG] [--near N] [--far F] [--size WxH] "
                      "[--exposure EV] [--quality Q] [--no-occlusion] -o FILE.exr|png|jpg";
    optind = 1;
    int o;
    while ((o = getopt_long(argc, argv, "o:", opts, NULL)) != -1) {
        bool ok = true;
        double q;
        switch (o) {
        case 'e': ok = have_eye = parse_vec(optarg, eye, 3); break;
        case 'a': ok = have_at = parse_vec(optarg, at, 3); break;
        case 'u': ok = parse_vec(optarg, up, 3); break;
        case 'f': ok = parse_vec(optarg, &fov, 1) && fov > 0 && fov < 180; break;
        case 'n': ok = parse_vec(optarg, &znear, 1); break;
        case 'F': ok = parse_vec(optarg, &zfar, 1); break;
        case 's': ok = sscanf(optarg, "%ux%u", &w, &h) == 2 && w && h && w <= 4096 && h <= 4096; break;
        case 'x': ok = parse_vec(optarg, &ev, 1) && ev >= -64 && ev <= 64; break;
        case 'q': ok = parse_vec(optarg, &q, 1) && q >= 1 && q <= 100 && (quality = (unsigned)q); break;
        case 'N': flags |= VP_RENDER_NO_OCCLUSION; break;
        case 'o': out = optarg; break;
        case 'h': printf("usage: vantage %s\n", use); return 0;
        default: return die_usage("%s", use);
        }
        if (!ok) return die_usage("render: bad value %s", optarg);
    }
    if (!have_eye || !have_at || !out || optind != argc) return die_usage("%s", use);
    bool exr = ends_with(out, ".exr"), png = ends_with(out, ".png");
    bool jpg = ends_with(out, ".jpg") || ends_with(out, ".jpeg");
    if (!exr && !png && !jpg) return die_usage("render: the output must end in .exr, .png or .jpg");
    vp_render m = {.format = jpg ? VP_FRAME_JPEG : VP_FRAME_RAW, .quality = jpg ? (uint8_t)quality : 0,
                   .flags = flags, .exposure_ev = (float)ev};
    if (!vt_view_perspective(&m.view, eye, at, up, fov, (uint16_t)w, (uint16_t)h, znear, zfar))
        return die_usage("render: degenerate camera (eye == at, up parallel to the view, or near/far)");
    int rc = connect_cli(k, VP_ROLE_VIEWER);
    if (rc) return rc;
    vp_frame f;
    if ((rc = vt_render(k->c, &m, &f))) return server_fail(k, "render", rc);
    char err[256];
    int wrc = 0;
    if (jpg) {
        FILE *fp = fopen(out, "wb");
        if (!fp || fwrite(f.data, 1, f.data_len, fp) != f.data_len || fclose(fp)) {
            fprintf(stderr, "vantage: %s: %s\n", out, strerror(errno));
            return 1;
        }
    } else {
        /* the raw frame: RGBA floats then depth, rows bottom-up; copied out
           of the reply (the wire is little-endian, and so is this host) */
        size_t np = (size_t)f.width * f.height;
        float *px = malloc(np * 20);
        if (!px) {
            fprintf(stderr, "vantage: out of memory\n");
            return 1;
        }
        memcpy(px, f.data, np * 20);
        const float *top = px + (np - f.width) * 4, *ztop = px + np * 4 + (np - f.width);
        ptrdiff_t ys = -(ptrdiff_t)f.width * 4;
        if (exr) {
            vt_exr_channel ch[5] = {{"R", VT_EXR_HALF, top, 4, ys},     {"G", VT_EXR_HALF, top + 1, 4, ys},
                                    {"B", VT_EXR_HALF, top + 2, 4, ys}, {"A", VT_EXR_HALF, top + 3, 4, ys},
                                    {"Z", VT_EXR_FLOAT, ztop, 1, -(ptrdiff_t)f.width}};
            wrc = vt_exr_write(out, f.width, f.height, ch, 5, VT_EXR_ZIP, err, sizeof err);
        } else {
            uint8_t *rgb8 = malloc(vt_image_rgba8_size(f.width, f.height));
            vt_image_src src = {.r = {top, 4, ys}, .g = {top + 1, 4, ys}, .b = {top + 2, 4, ys}};
            vt_tonemap_desc td = {.exposure_ev = (float)ev, .op = VT_TONEMAP_ACES};
            wrc = !rgb8 ? -ENOMEM : vt_image_tonemap(f.width, f.height, &src, &td, rgb8, 4 * (size_t)f.width);
            if (!wrc) wrc = vt_png_write(out, f.width, f.height, rgb8, 4 * (size_t)f.width, false, 6, err, sizeof err);
            else snprintf(err, sizeof err, "tone mapping failed");
            free(rgb8);
        }
        free(px);
        if (wrc) {
            fprintf(stderr, "vantage: %s\n", err);
            return 1;
        }
    }
    printf("%s: %ux%u, %u entities drawn at epoch %llu; render %.2f ms, encode %.2f ms (server)\n", out, f.width,
           f.height, f.visible, (unsigned long long)f.epoch, f.render_ns / 1e6, f.encode_ns / 1e6);
    return 0;
}
