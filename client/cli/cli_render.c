/*
 * cli_render.c — pictures from the daemon. `vantage render` asks for one
 * frame and writes it as OpenEXR (half RGBA + float Z, from the raw frame),
 * PNG (tone mapped here from the raw frame) or JPEG (encoded by the
 * daemon), chosen by the output file's extension. `vantage watch --frames
 * DIR` subscribes to a stream and writes each frame pushed into DIR,
 * optionally orbiting the camera (the view re-aimed in place). `vantage
 * lights` shows a view's Forward+ tile light lists as a heat map (or JSON).
 */
#include "cli.h"
#include "vt_exr.h"
#include "vt_image.h"

#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <signal.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <time.h>

typedef enum { OUT_EXR, OUT_PNG, OUT_JPG } out_kind;

static bool ends_with(const char *s, const char *suffix)
{
    size_t n = strlen(s), m = strlen(suffix);
    return n >= m && !strcasecmp(s + n - m, suffix);
}

/* The format a file name's extension names. */
static bool kind_of(const char *name, out_kind *k)
{
    if (ends_with(name, ".exr")) *k = OUT_EXR;
    else if (ends_with(name, ".png")) *k = OUT_PNG;
    else if (ends_with(name, ".jpg") || ends_with(name, ".jpeg")) *k = OUT_JPG;
    else return false;
    return true;
}

/* The format --format names: exr, png, jpg or jpeg. */
static bool kind_named(const char *name, out_kind *k)
{
    char dotted[8];
    return strlen(name) <= 4 && strchr(name, '.') == NULL && snprintf(dotted, sizeof dotted, ".%s", name) > 0 &&
           kind_of(dotted, k);
}

/* What `render` and `watch --frames` share: the camera and the frame. */
typedef struct frame_opts {
    double eye[3], at[3], up[3], fov, znear, zfar, ev;
    bool have_eye, have_at;
    unsigned w, h, quality;
    uint8_t flags, renderer;
    uint8_t nhl;            /* --highlight: entities outlined in the frame */
    uint64_t hl[VP_RENDER_MAX_HIGHLIGHT];
} frame_opts;

#define FRAME_LONGOPTS                                                                                              \
    {"eye", 1, 0, 'e'}, {"at", 1, 0, 'a'}, {"up", 1, 0, 'u'}, {"fov", 1, 0, 'f'}, {"near", 1, 0, 'n'},          \
        {"far", 1, 0, 'F'}, {"size", 1, 0, 's'}, {"exposure", 1, 0, 'x'}, {"quality", 1, 0, 'q'},               \
        {"no-occlusion", 0, 0, 'N'}, {"renderer", 1, 0, 'R'}, {"highlight", 1, 0, 'H'}, {"fx-off", 1, 0, 'X'}
#define FRAME_USAGE                                                                                                 \
    "--eye X,Y,Z --at X,Y,Z [--up X,Y,Z] [--fov DEG] [--near N] [--far F] [--size WxH] [--exposure EV] "          \
    "[--quality Q] [--no-occlusion] [--renderer soft|gl] [--highlight ID[,ID..]] [--fx-off LIST]"

/* What each camera/frame option accepts, for the refusal of a bad value
 * (the bounds frame_opt checks). */
static const cli_opt_doc frame_docs[] = {
    {'e', "--eye", "X,Y,Z (three finite numbers)"}, {'a', "--at", "X,Y,Z (three finite numbers)"},
    {'u', "--up", "X,Y,Z (three finite numbers)"},  {'f', "--fov", "degrees, more than 0 and less than 180"},
    {'n', "--near", "a finite number"},             {'F', "--far", "a finite number"},
    {'s', "--size", "WxH, each 1..4096"},           {'x', "--exposure", "EV, -64..64"},
    {'q', "--quality", "1..100"},                   {'R', "--renderer", "soft or gl"},
    {'H', "--highlight", "1..8 entity ids, comma-separated (decimal or 0x hex)"},
    {'X', "--fx-off", "effects, comma-separated: shadows, ssao, ibl, fxaa"},
    /* watch --frames */
    {'r', "--fps", "frames a second, 1..240"},      {'c', "--count", "a count of frames"},
    {'O', "--orbit", "degrees a second (a finite number)"}, {'S', "--seconds", "seconds, >= 0"},
};
#define FRAME_DOCS frame_docs, sizeof frame_docs / sizeof frame_docs[0]

/* The camera's required options, named when missing. */
static int frame_missing(const char *cmd, const frame_opts *f)
{
    if (!f->have_eye) return die_missing(cmd, "--eye X,Y,Z", "where the camera is");
    return die_missing(cmd, "--at X,Y,Z", "the point the camera looks at");
}

static void frame_opts_init(frame_opts *f)
{
    *f = (frame_opts){.up = {0, 1, 0}, .fov = 60, .znear = 0.1, .zfar = 10000, .w = 1280, .h = 720, .quality = 85};
}

/* --highlight's ids: 1..VP_RENDER_MAX_HIGHLIGHT comma-separated u64s. */
static bool parse_highlight(const char *arg, frame_opts *f)
{
    char buf[512];
    if (snprintf(buf, sizeof buf, "%s", arg) >= (int)sizeof buf) return false;
    f->nhl = 0;
    for (char *save = NULL, *t = strtok_r(buf, ",", &save); t; t = strtok_r(NULL, ",", &save)) {
        if (f->nhl == VP_RENDER_MAX_HIGHLIGHT || !parse_u64(t, &f->hl[f->nhl])) return false;
        f->nhl++;
    }
    return f->nhl > 0;
}

/* One camera/frame option: 1 taken, 0 not one of ours, -1 a bad value. */
static int frame_opt(frame_opts *f, int o, const char *arg)
{
    double q;
    bool ok = true;
    switch (o) {
    case 'e': ok = f->have_eye = parse_vec(arg, f->eye, 3); break;
    case 'a': ok = f->have_at = parse_vec(arg, f->at, 3); break;
    case 'u': ok = parse_vec(arg, f->up, 3); break;
    case 'f': ok = parse_vec(arg, &f->fov, 1) && f->fov > 0 && f->fov < 180; break;
    case 'n': ok = parse_vec(arg, &f->znear, 1); break;
    case 'F': ok = parse_vec(arg, &f->zfar, 1); break;
    case 's': ok = parse_size(arg, 4096, &f->w, &f->h); break;
    case 'x': ok = parse_vec(arg, &f->ev, 1) && f->ev >= -64 && f->ev <= 64; break;
    case 'q': ok = parse_vec(arg, &q, 1) && q >= 1 && q <= 100 && (f->quality = (unsigned)q); break;
    case 'N': f->flags |= VP_RENDER_NO_OCCLUSION; break;
    case 'R': ok = parse_renderer(arg, &f->renderer); break;
    case 'H': ok = parse_highlight(arg, f); break;
    case 'X': {
        uint8_t bits;
        ok = vp_render_fx_parse(arg, &bits, NULL, 0) == 0;
        f->flags = (uint8_t)((f->flags & VP_RENDER_NO_OCCLUSION) | bits);
        break;
    }
    default: return 0;
    }
    return ok ? 1 : -1;
}

/* The RENDER fields for the options, the camera at eye. */
static bool frame_request(const frame_opts *f, const double eye[3], out_kind k, vp_render *m)
{
    *m = (vp_render){.format = k == OUT_JPG ? VP_FRAME_JPEG : VP_FRAME_RAW,
                     .quality = k == OUT_JPG ? (uint8_t)f->quality : 0, .flags = f->flags, .renderer = f->renderer,
                     .exposure_ev = (float)f->ev, .nhighlight = f->nhl};
    memcpy(m->highlight, f->hl, sizeof m->highlight);
    return vtc_view_perspective(&m->view, eye, f->at, f->up, f->fov, (uint16_t)f->w, (uint16_t)f->h, f->znear,
                                f->zfar);
}

/* Writes frame fr to path as kind k. 0, or 1 with a message printed. */
static int write_frame(const char *path, out_kind k, const vp_frame *fr, double ev)
{
    char err[256];
    int wrc = 0;
    if (k == OUT_JPG) {
        if (fr->format != VP_FRAME_JPEG) {
            fprintf(stderr, "%s: %s: the daemon sent a raw frame for a JPEG\n", g_prog, path);
            return 1;
        }
        FILE *fp = fopen(path, "wb");
        bool ok = fp && fwrite(fr->data, 1, fr->data_len, fp) == fr->data_len;
        if (fp && fclose(fp)) ok = false;
        if (!ok) {
            fprintf(stderr, "%s: %s: %s\n", g_prog, path, strerror(errno));
            return 1;
        }
        return 0;
    }
    /* the raw frame: RGBA floats then depth, rows bottom-up; copied out of
       the reply (the wire is little-endian, and so is this host) */
    size_t np = (size_t)fr->width * fr->height;
    if (fr->format != VP_FRAME_RAW || fr->data_len != np * 20) {
        fprintf(stderr, "%s: %s: the daemon's frame is not %ux%u raw pixels\n", g_prog, path, fr->width, fr->height);
        return 1;
    }
    float *px = malloc(np * 20);
    if (!px) {
        fprintf(stderr, "%s: out of memory\n", g_prog);
        return 1;
    }
    memcpy(px, fr->data, np * 20);
    const float *top = px + (np - fr->width) * 4, *ztop = px + np * 4 + (np - fr->width);
    ptrdiff_t ys = -(ptrdiff_t)fr->width * 4;
    if (k == OUT_EXR) {
        vt_exr_channel ch[5] = {{"R", VT_EXR_HALF, top, 4, ys},     {"G", VT_EXR_HALF, top + 1, 4, ys},
                                {"B", VT_EXR_HALF, top + 2, 4, ys}, {"A", VT_EXR_HALF, top + 3, 4, ys},
                                {"Z", VT_EXR_FLOAT, ztop, 1, -(ptrdiff_t)fr->width}};
        wrc = vt_exr_write(path, fr->width, fr->height, ch, 5, VT_EXR_ZIP, err, sizeof err);
    } else {
        uint8_t *rgb8 = malloc(vt_image_rgba8_size(fr->width, fr->height));
        vt_image_src src = {.r = {top, 4, ys}, .g = {top + 1, 4, ys}, .b = {top + 2, 4, ys}};
        vt_tonemap_desc td = {.exposure_ev = (float)ev, .op = VT_TONEMAP_ACES};
        wrc = !rgb8 ? VT_ERR_NOMEM : vt_image_tonemap(fr->width, fr->height, &src, &td, rgb8, 4 * (size_t)fr->width);
        if (!wrc) wrc = vt_png_write(path, fr->width, fr->height, rgb8, 4 * (size_t)fr->width, false, 6, err, sizeof err);
        else snprintf(err, sizeof err, "tone mapping failed");
        free(rgb8);
    }
    free(px);
    if (wrc) {
        fprintf(stderr, "%s: %s\n", g_prog, err);
        return 1;
    }
    return 0;
}

int cmd_render(cli *k, int argc, char **argv)
{
    frame_opts f;
    frame_opts_init(&f);
    const char *out = NULL;
    static const struct option opts[] = {FRAME_LONGOPTS, {"output", 1, 0, 'o'}, {0, 0, 0, 0}};
    const char *use = "render " FRAME_USAGE " -o FILE.exr|png|jpg";
    optind = 1;
    int o;
    while ((o = getopt_long(argc, argv, "o:", opts, NULL)) != -1) {
        int r = frame_opt(&f, o, optarg);
        if (r < 0) return die_bad_opt("render", FRAME_DOCS, o, optarg);
        if (r) continue;
        if (o == 'o') out = optarg;
        else return die_usage("%s", use);
    }
    if (optind != argc) return die_usage("render: unexpected argument %s", argv[optind]);
    if (!f.have_eye || !f.have_at) return frame_missing("render", &f);
    if (!out) return die_missing("render", "-o FILE.exr|png|jpg", "the file to write the frame to");
    out_kind kind;
    if (!kind_of(out, &kind))
        return die_bad_value("render", "-o", out, "a file name ending in .exr, .png, .jpg or .jpeg");
    vp_render m;
    if (!frame_request(&f, f.eye, kind, &m))
        return die_usage("render: degenerate camera (eye == at, up parallel to the view, or near/far)");
    int rc = connect_cli(k, VP_ROLE_VIEWER);
    if (rc) return rc;
    vp_frame fr;
    if ((rc = vtc_render(k->c, &m, &fr))) return server_fail(k, "render", rc);
    if (write_frame(out, kind, &fr, f.ev)) return 1;
    printf("%s: %ux%u, %u entities drawn at epoch %llu; render %.2f ms, encode %.2f ms (server)\n", out, fr.width,
           fr.height, fr.visible, (unsigned long long)fr.epoch, fr.render_ns / 1e6, fr.encode_ns / 1e6);
    return 0;
}

/* eye turned by angle (radians) about the vertical through at */
static void orbit(const frame_opts *f, double angle, double eye[3])
{
    double dx = f->eye[0] - f->at[0], dz = f->eye[2] - f->at[2], c = cos(angle), s = sin(angle);
    eye[0] = f->at[0] + c * dx - s * dz;
    eye[1] = f->eye[1];
    eye[2] = f->at[2] + s * dx + c * dz;
}

int cmd_watch_frames(cli *k, int argc, char **argv)
{
    frame_opts f;
    frame_opts_init(&f);
    const char *dir = NULL, *format = "jpg";
    uint64_t count = 0, fps = 30;
    double orbit_dps = 0, seconds = 0;
    static const struct option opts[] = {FRAME_LONGOPTS,       {"frames", 1, 0, 'D'}, {"format", 1, 0, 'T'},
                                         {"fps", 1, 0, 'r'},   {"count", 1, 0, 'c'},  {"orbit", 1, 0, 'O'},
                                         {"seconds", 1, 0, 'S'}, {0, 0, 0, 0}};
    const char *use = "watch --frames DIR " FRAME_USAGE
                      " [--format jpg|png|exr] [--fps N] [--count N] [--seconds S] [--orbit DEG_PER_S]";
    optind = 1;
    int o;
    while ((o = getopt_long(argc, argv, "", opts, NULL)) != -1) {
        int r = frame_opt(&f, o, optarg);
        if (r < 0) return die_bad_opt("watch", FRAME_DOCS, o, optarg);
        if (r) continue;
        bool ok = true;
        switch (o) {
        case 'D': dir = optarg; break;
        case 'T': format = optarg; break;
        case 'r': ok = parse_u64(optarg, &fps) && fps >= 1 && fps <= VP_FRAME_SUB_MAX_FPS; break;
        case 'c': ok = parse_u64(optarg, &count); break;
        case 'O': ok = parse_vec(optarg, &orbit_dps, 1); break;
        case 'S': ok = parse_vec(optarg, &seconds, 1) && seconds >= 0; break;
        default: return die_usage("%s", use);
        }
        if (!ok) return die_bad_opt("watch", FRAME_DOCS, o, optarg);
    }
    out_kind kind;
    if (optind != argc) return die_usage("watch: unexpected argument %s", argv[optind]);
    if (!dir) return die_missing("watch", "--frames DIR", "the folder to write the frames to");
    if (!f.have_eye || !f.have_at) return frame_missing("watch", &f);
    if (!kind_named(format, &kind)) return die_bad_value("watch", "--format", format, "jpg, png or exr");
    vp_frame_sub sub = {.max_fps = (uint16_t)fps};
    if (!frame_request(&f, f.eye, kind, &sub.r))
        return die_usage("watch: degenerate camera (eye == at, up parallel to the view, or near/far)");
    if (mkdir(dir, 0777) && errno != EEXIST) {
        fprintf(stderr, "%s: %s: %s\n", g_prog, dir, strerror(errno));
        return 1;
    }
    int rc = connect_cli(k, VP_ROLE_VIEWER);
    if (rc) return rc;
    if ((rc = vtc_frame_subscribe(k->c, &sub))) return server_fail(k, "watch", rc);
    catch_sigint();
    fprintf(stderr, "writing frames to %s/ (Ctrl-C to stop)\n", dir);
    const char *ext = kind == OUT_EXR ? "exr" : kind == OUT_PNG ? "png" : "jpg";
    double t0 = now_s(), period = 1.0 / (double)fps, next_aim = t0 + period;
    uint64_t n = 0;
    while (!g_stop && (!count || n < count) && (seconds <= 0 || now_s() - t0 < seconds)) {
        vp_frame fr;
        rc = vtc_wait_frame(k->c, &fr, 250);
        if (rc == VTC_ERR_IO && vtc_last_error(k->c)->timed_out) continue;
        if (rc) return server_fail(k, "watch", rc);
        char path[4096];
        snprintf(path, sizeof path, "%s/frame-%06llu.%s", dir, (unsigned long long)n, ext);
        if (write_frame(path, kind, &fr, f.ev)) return 1;
        n++;
        double t = now_s() - t0;
        printf("{\"frame\": %llu, \"file\": \"%s\", \"epoch\": %llu, \"t\": %.4f, \"fps\": %.2f, \"visible\": %u, "
               "\"render_ms\": %.3f, \"encode_ms\": %.3f, \"bytes\": %u}\n",
               (unsigned long long)n - 1, path, (unsigned long long)fr.epoch, t, t > 0 ? n / t : 0.0, fr.visible,
               fr.render_ns / 1e6, fr.encode_ns / 1e6, fr.data_len);
        fflush(stdout);
        if (orbit_dps != 0) {
            /* the view re-aimed in place after each frame: same stream, the
               camera turned to where it is now. The daemon draws a re-aimed
               view at once (a moving camera must not wait for its cap), so
               --fps is kept here: one re-aim a period, as the daemon paces
               frame starts (a late one does not bank time for a burst). */
            for (double now = now_s(); !g_stop && now < next_aim; now = now_s()) {
                if (seconds > 0 && now - t0 >= seconds) break;
                double sl = fmin(next_aim - now, 0.05);
                nanosleep(&(struct timespec){0, (long)(sl * 1e9)}, NULL);
            }
            if (g_stop || (seconds > 0 && now_s() - t0 >= seconds)) break;
            double now = now_s();
            next_aim = (now - next_aim < period ? next_aim : now) + period;
            double eye[3];
            orbit(&f, (now_s() - t0) * orbit_dps * M_PI / 180, eye);
            if (!frame_request(&f, eye, kind, &sub.r)) return die_usage("watch: degenerate orbit camera");
            if ((rc = vtc_frame_subscribe(k->c, &sub))) return server_fail(k, "watch", rc);
        }
    }
    vtc_frame_unsubscribe(k->c);
    return 0;
}

/* A tile's light count as one character: ' ' none, 1-9, a-z for 10-35,
 * A-Z for 36-61, '#' beyond. */
static char count_char(uint32_t n)
{
    if (!n) return '.';
    if (n < 10) return (char)('0' + n);
    if (n < 36) return (char)('a' + n - 10);
    if (n < 62) return (char)('A' + n - 36);
    return '#';
}

int cmd_lights(cli *k, int argc, char **argv)
{
    frame_opts f;
    frame_opts_init(&f);
    bool json = false, no_depth = false;
    /* the camera's options only: nothing here is drawn or encoded */
    static const struct option opts[] = {{"eye", 1, 0, 'e'},  {"at", 1, 0, 'a'},       {"up", 1, 0, 'u'},
                                         {"fov", 1, 0, 'f'},  {"near", 1, 0, 'n'},     {"far", 1, 0, 'F'},
                                         {"size", 1, 0, 's'}, {"json", 0, 0, 'j'},     {"no-depth", 0, 0, 'Z'},
                                         {0, 0, 0, 0}};
    const char *use = "lights --eye X,Y,Z --at X,Y,Z [--up X,Y,Z] [--fov DEG] [--near N] [--far F] [--size WxH] "
                      "[--no-depth] [--json]";
    optind = 1;
    int o;
    while ((o = getopt_long(argc, argv, "", opts, NULL)) != -1) {
        int r = frame_opt(&f, o, optarg);
        if (r < 0) return die_bad_opt("lights", FRAME_DOCS, o, optarg);
        if (r) continue;
        if (o == 'j') json = true;
        else if (o == 'Z') no_depth = true;
        else return die_usage("%s", use);
    }
    if (optind != argc) return die_usage("lights: unexpected argument %s", argv[optind]);
    if (!f.have_eye || !f.have_at) return frame_missing("lights", &f);
    vp_light_query m = {.flags = no_depth ? VP_LQ_NO_DEPTH : 0};
    if (!vtc_view_perspective(&m.view, f.eye, f.at, f.up, f.fov, (uint16_t)f.w, (uint16_t)f.h, f.znear, f.zfar))
        return die_usage("lights: degenerate camera (eye == at, up parallel to the view, or near/far)");
    int rc = connect_cli(k, VP_ROLE_VIEWER);
    if (rc) return rc;
    vp_light_tiles t;
    if ((rc = vtc_light_query(k->c, &m, &t))) return server_fail(k, "lights", rc);
    uint32_t tiles = (uint32_t)t.tiles_x * t.tiles_y, lit = 0;
    for (uint32_t i = 0; i < tiles; i++) lit += vp_light_tiles_offset(&t, i + 1) > vp_light_tiles_offset(&t, i);
    if (json) {
        printf("{\"epoch\": %llu, \"tiles_x\": %u, \"tiles_y\": %u, \"tile\": %u, \"depth\": %s, \"in_view\": %u, "
               "\"max_per_tile\": %u, \"count\": %u, \"ms\": %.3f, \"tiles\": [",
               (unsigned long long)t.epoch, t.tiles_x, t.tiles_y, t.tile, no_depth ? "false" : "true", t.in_view,
               t.max_per_tile, t.count, t.ns / 1e6);
        for (uint32_t i = 0; i < tiles; i++) {
            printf("%s[", i ? ", " : "");
            for (uint32_t q = vp_light_tiles_offset(&t, i); q < vp_light_tiles_offset(&t, i + 1); q++)
                printf("%s%llu", q > vp_light_tiles_offset(&t, i) ? ", " : "",
                       (unsigned long long)vp_light_tiles_id(&t, q));
            printf("]");
        }
        printf("]}\n");
        return 0;
    }
    printf("%u lights in view; %u x %u tiles of %u px, %u lit; at most %u per tile, %.2f per lit tile; %u entries; "
           "%.2f ms (%s)\n",
           t.in_view, t.tiles_x, t.tiles_y, t.tile, lit, t.max_per_tile, lit ? (double)t.count / lit : 0.0, t.count,
           t.ns / 1e6, no_depth ? "frustum depth" : "depth pre-pass");
    /* the heat map, top row first; wide views are sampled to 120 columns */
    uint32_t step = (t.tiles_x + 119) / 120;
    for (uint32_t y = t.tiles_y; y-- > 0;) {
        if (step > 1 && y % step) continue;
        for (uint32_t x = 0; x < t.tiles_x; x += step) {
            uint32_t i = y * t.tiles_x + x;
            putchar(count_char(vp_light_tiles_offset(&t, i + 1) - vp_light_tiles_offset(&t, i)));
        }
        putchar('\n');
    }
    printf("(lights per tile: . none, 1-9, a-z 10-35, A-Z 36-61, # more)\n");
    return 0;
}

/* MARK: a commander's ping of a place (or an entity), pushed as MARKED to
 * the mark subscribers and drawn as an icon in every frame that shows it
 * while it lives. */
int cmd_mark(cli *k, int argc, char **argv)
{
    const char *use = "mark X,Y,Z [--kind K] [--ttl MS] [--entity ID]";
    vp_mark m = {.ttl_ms = 10000};
    if (argc < 2) return die_usage("%s", use);
    if (!parse_vec(argv[1], m.pos, 3))
        return die_usage("mark: bad position %s: expected X,Y,Z (three finite numbers)", argv[1]);
    for (int i = 2; i < argc; i++) {
        uint64_t v;
        const char *arg = i + 1 < argc ? argv[i + 1] : "(none)";
        if (!strcmp(argv[i], "--kind")) {
            if (!parse_u64(arg, &v) || v > 255) return die_bad_value("mark", "--kind", arg, "0..255 (0 ping, 1 select)");
            m.kind = (uint8_t)v, i++;
        } else if (!strcmp(argv[i], "--ttl")) {
            if (!parse_u64(arg, &v) || v < 1 || v > 600000) return die_bad_value("mark", "--ttl", arg, "1..600000 ms");
            m.ttl_ms = (uint32_t)v, i++;
        } else if (!strcmp(argv[i], "--entity")) {
            if (!parse_u64(arg, &m.entity)) return die_bad_value("mark", "--entity", arg, "an entity id");
            i++;
        } else {
            return die_usage("mark: unexpected %s; %s", argv[i], use);
        }
    }
    int rc = connect_cli(k, VP_ROLE_COMMANDER);
    if (rc) return rc;
    uint32_t sent = 0;
    if ((rc = vtc_mark(k->c, &m, &sent))) return server_fail(k, "mark", rc);
    printf("marked %g,%g,%g (kind %u, %u ms): sent to %u subscriber%s\n", m.pos[0], m.pos[1], m.pos[2], m.kind,
           m.ttl_ms, sent, sent == 1 ? "" : "s");
    return 0;
}

/* SELECT: the scene's shared selection (an editor's, a commander's),
 * pushed as SELECTED to its subscribers and outlined in every frame. */
int cmd_select(cli *k, int argc, char **argv)
{
    const char *use = "select ID[,ID..] [ID...], or select --clear";
    uint64_t ids[VP_SELECT_MAX];
    uint32_t n = 0;
    bool clear = argc == 2 && !strcmp(argv[1], "--clear");
    if (argc < 2) return die_usage("%s", use);
    for (int i = 1; i < argc && !clear; i++)
        for (const char *t = argv[i]; *t;) { /* comma-separated, any length (argv is not ours to cut) */
            size_t len = strcspn(t, ",");
            char one[32];
            if (n == VP_SELECT_MAX) return die_usage("select: more than %u ids", VP_SELECT_MAX);
            snprintf(one, sizeof one, "%.*s", (int)(len < sizeof one ? len : sizeof one - 1), t);
            if (len >= sizeof one || !parse_u64(one, &ids[n]) || !ids[n])
                return die_bad_value("select", "ID", one, "an entity id (decimal or 0x hex), not 0");
            n++;
            t += len + (t[len] == ',');
        }
    int rc = connect_cli(k, VP_ROLE_COMMANDER);
    if (rc) return rc;
    uint32_t sent = 0;
    if ((rc = vtc_select(k->c, ids, n, &sent))) return server_fail(k, "select", rc);
    printf("%s %u entit%s: sent to %u subscriber%s\n", n ? "selected" : "cleared the selection of", n,
           n == 1 ? "y" : "ies", sent, sent == 1 ? "" : "s");
    return 0;
}
