/*
 * bench_render.c — frames per second of the render path (a benchmark: it
 * fails on nothing).
 *
 *   bench_render [--json] [--quick] [--smoke] [--no-gl] [--size WxH] [--reps N] [--city-only]
 *                [--no-city] [--png DIR] [--view street|aerial] [--lights N]
 *
 * First issue 20's budget, the demo city (bench_city.c): the daemon's
 * city and day environment, a street and an aerial view at 1280x720 on 2
 * threads, each pass of the software frame timed (setup, raster, bin,
 * shade, and shadow / ssao / post when they run), the tone map and the
 * JPEG apart, the GL path on the same frames. --city-only stops there;
 * --no-city skips it; --png DIR writes the last city frames there;
 * --view: that city view only.
 *
 * The scene: N boxes (1k, 15k, 100k) of 0.5..4 m scattered over a 200 x
 * 380 m field in front of the camera, 0, 16 or 256 point lights of 30 m
 * range among them, a camera 60 degrees wide at 1280x720. The software
 * path runs the whole frame: the culling query (frustum; no occluders here,
 * so no occlusion stage) picks the visible boxes, then vt_soft renders
 * them; 1 and 2 threads. The GL path (vt_gldraw through headless EGL:
 * llvmpipe here, LP_NUM_THREADS=2 unless set) draws the same visible set
 * in the same run: the culling query, then two passes (nearness, then
 * shading with the CPU-binned tile lists) and the readback of colour and
 * depth. --no-gl skips it. Then the encoders on the last frame: EXR (half
 * RGBA + float Z; ZIP and none), PNG (levels 1 and 6), JPEG (q 85), each
 * after tone mapping where the format is 8-bit. For 1k and 15k boxes, the
 * cost of destruction masks: the same frame (16 lights, 2 threads) with no
 * box, every tenth box and every box damaged (an 8^3 volume, 3 holes on
 * its surface: drawn masked and two-sided).
 *
 * --json: one object per line, {path, renderer, width, height, boxes,
 * lights, threads, damaged, median_ms, ...}, and {encode, width, height, median_ms,
 * bytes} for the encoders.
 */
#include "culling.h"
#include "bench_city.h"
#include "bench_util.h"
#include "vt_exr.h"
#include "vt_gldraw.h"
#include "vt_image.h"
#include "vt_soft.h"

#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>




typedef struct scene {
    cull_world *w;
    vt_instance *all;       /* by entity slot */
    cull_dvol *dv;          /* by entity slot: a damaged box's volume (built on first use) */
    uint32_t n;
} scene;

static int make_scene(scene *s, uint32_t n)
{
    memset(s, 0, sizeof *s);
    if (cull_world_create(NULL, &s->w)) return -1;
    s->all = calloc(n, sizeof *s->all);
    if (!s->all) return -1;
    s->n = n;
    for (uint32_t i = 0; i < n; i++) {
        vt_instance *in = &s->all[i];
        double c[3] = {bench_frand() * 200 - 100, 0, 20 + bench_frand() * 380}, e[3];
        for (int a = 0; a < 3; a++) e[a] = 0.25 + bench_frand() * 1.75;
        c[1] = e[1] + bench_frand() * 6;
        cull_entity_desc d = {0};
        for (int a = 0; a < 3; a++) {
            in->bmin[a] = d.aabb_min[a] = c[a] - e[a];
            in->bmax[a] = d.aabb_max[a] = c[a] + e[a];
            in->albedo[a] = (float)(0.3 + 0.5 * bench_frand());
        }
        cull_handle h;
        if (cull_entity_add(s->w, &d, &h) || (h & (CULL_MAX_ENTITIES - 1)) != i) return -1;
    }
    return 0;
}

/* Damages every k-th box (k 0: none): an 8^3 volume with 3 holes on its
 * surface, each 0.3..0.6 of its largest half-extent. */
static int damage(scene *s, uint32_t k)
{
    if (!s->dv) {
        if (!(s->dv = calloc(s->n, sizeof *s->dv))) return -1;
        for (uint32_t i = 0; i < s->n; i++) {
            vt_instance *in = &s->all[i];
            if (cull_dvol_init(&s->dv[i], in->bmin, in->bmax, 8)) return -1;
            double emax = 0;
            for (int a = 0; a < 3; a++) emax = fmax(emax, 0.5 * (in->bmax[a] - in->bmin[a]));
            for (int h = 0; h < 3; h++) {
                double c[3];
                int face = (int)(bench_frand() * 6) % 6;
                for (int a = 0; a < 3; a++)
                    c[a] = a == face / 2 ? (face % 2 ? in->bmax[a] : in->bmin[a])
                                         : in->bmin[a] + bench_frand() * (in->bmax[a] - in->bmin[a]);
                if (cull_dvol_add_sphere(&s->dv[i], c, emax * (0.3 + 0.3 * bench_frand()))) return -1;
            }
        }
    }
    for (uint32_t i = 0; i < s->n; i++) s->all[i].dvol = k && i % k == 0 ? &s->dv[i] : NULL;
    return 0;
}

static void free_scene(scene *s)
{
    for (uint32_t i = 0; s->dv && i < s->n; i++) cull_dvol_free(&s->dv[i]);
    free(s->dv);
    free(s->all);
    cull_world_destroy(s->w);
}

/* What every measurement shares. */
typedef struct run {
    cull_pool *pool;
    cull_ctx *ctx;
    cull_view v;
    uint32_t W, H;
    int reps;
    bool json;
    float *rgba, *depth;
    cull_result *res;
    vt_instance *vis;
    size_t cap;
    vt_gl *g;
    vt_gldraw *gr;
    const char *gl_name;
    unsigned lp_threads;
} run;

/* The visible boxes of s (the culling query), as instances. */
static int visible(run *rn, const scene *s, uint32_t threads, size_t *n)
{
    cull_query_desc q = {.views = &rn->v, .view_count = 1, .threads = threads};
    if (cull_query(s->w, rn->ctx, &q, rn->res, rn->cap, n, NULL)) return -1;
    for (size_t k = 0; k < *n; k++) rn->vis[k] = s->all[rn->res[k].handle & (CULL_MAX_ENTITIES - 1)];
    return 0;
}

/* " damaged N %" for the table (damaged < 0: nothing). Not reentrant. */
static const char *damage_label(double damaged)
{
    static char b[32];
    if (damaged < 0) return "";
    snprintf(b, sizeof b, " damaged %.0f %%", 100 * damaged);
    return b;
}

/* The software path: median frame time (query + render), one line out.
 * damaged: the share of boxes damaged, for the label (-1: no label). */
static int time_soft_env(run *rn, const scene *s, const vt_light *L, uint32_t nl, uint32_t threads, double damaged,
                         const vt_env *env);
static int time_soft(run *rn, const scene *s, const vt_light *L, uint32_t nl, uint32_t threads, double damaged)
{
    return time_soft_env(rn, s, L, nl, threads, damaged, NULL);
}

/* The scene model's default environment (the protocol's vp_env_default):
 * sun, analytic sky, ground, light fog, auto exposure. */
static const vt_env *default_env(void)
{
    static vt_env e;
    double el = 50 * M_PI / 180, az = 225 * M_PI / 180;
    e = (vt_env){.sun_dir = {(float)(cos(el) * sin(az)), (float)sin(el), (float)(cos(el) * cos(az))},
                 .sun = {100000.0f, 96000.0f, 90000.0f}, .sky_mode = VT_SKY_ANALYTIC, .sky = {1, 1, 1},
                 .turbidity = 2.5f, .ground = true, .ground_albedo = {0.25f, 0.25f, 0.25f}, .fog_density = 0.0005f,
                 .fog_color = {0.6f, 0.7f, 0.8f}, .exposure_mode = VT_EXPOSURE_AUTO, .exposure_ev = 14};
    return &e;
}

static int time_soft_env(run *rn, const scene *s, const vt_light *L, uint32_t nl, uint32_t threads, double damaged,
                         const vt_env *env)
{
    vt_soft *sr;
    if (vt_soft_create(rn->pool, threads, &sr)) return -1;
    double *t = malloc((size_t)rn->reps * sizeof *t);
    if (!t) return -1;
    vt_soft_stats st = {0};
    char err[512];
    for (int r = 0; r < rn->reps; r++) {
        double t0 = (bench_now_ns() / 1e6);
        size_t n;
        if (visible(rn, s, threads, &n)) return -1;
        vt_frame f = {.view = &rn->v, .width = rn->W, .height = rn->H, .meshes = &vt_mesh_box, .nmesh = 1,
                      .inst = rn->vis, .ninst = (uint32_t)n, .lights = L, .nl = nl, .env = env, .rgba = rn->rgba,
                      .depth = rn->depth, .stride = rn->W};
        if (vt_soft_draw(sr, &f, &st, err, sizeof err)) {
            fprintf(stderr, "bench_render: %s\n", err);
            return -1;
        }
        t[r] = (bench_now_ns() / 1e6) - t0;
    }
    qsort(t, (size_t)rn->reps, sizeof *t, bench_cmp_d);
    double med = t[rn->reps / 2];
    if (rn->json)
        printf("{\"path\":\"soft\",\"renderer\":\"vantage soft\",\"width\":%u,\"height\":%u,\"boxes\":%u,"
               "\"lights\":%u,\"threads\":%u,\"damaged\":%.3f,\"env\":%s,\"median_ms\":%.3f,\"triangles\":%u,"
               "\"setup_ms\":%.3f,\"raster_ms\":%.3f,\"bin_ms\":%.3f,\"shade_ms\":%.3f}\n",
               rn->W, rn->H, s->n, nl, threads, damaged < 0 ? 0 : damaged, env ? "true" : "false", med, st.triangles,
               st.setup_ns / 1e6, st.raster_ns / 1e6, st.bin_ns / 1e6, st.shade_ns / 1e6);
    else
        printf("%-6s %8u %7u %7u %10.2f %8.1f %9u  (setup %.2f raster %.2f bin %.2f shade %.2f ms)%s\n", "soft",
               s->n, nl, threads, med, 1000 / med, st.triangles, st.setup_ns / 1e6, st.raster_ns / 1e6,
               st.bin_ns / 1e6, st.shade_ns / 1e6, env ? " sun, sky, ground, fog, auto exposure" : damage_label(damaged));
    fflush(stdout);
    free(t);
    vt_soft_destroy(sr);
    return 0;
}

/* The GL path, the same way (one warm-up frame first: shader compiles,
 * buffers grow). */
static int time_gl(run *rn, const scene *s, const vt_light *L, uint32_t nl, double damaged)
{
    double *t = malloc((size_t)(rn->reps + 1) * sizeof *t);
    if (!t) return -1;
    uint32_t drawn = 0;
    char err[512];
    for (int r = 0; r <= rn->reps; r++) {
        double t0 = (bench_now_ns() / 1e6);
        size_t n;
        if (visible(rn, s, 2, &n)) return -1;
        if (vt_gldraw_render(rn->gr, &rn->v, rn->W, rn->H, &vt_mesh_box, 1, rn->vis, (uint32_t)n, L, nl, rn->rgba,
                             rn->depth, rn->W, NULL, err, sizeof err)) {
            fprintf(stderr, "bench_render: gl: %s\n", err);
            return -1;
        }
        t[r] = (bench_now_ns() / 1e6) - t0;
        drawn = (uint32_t)n;
    }
    qsort(t + 1, (size_t)rn->reps, sizeof *t, bench_cmp_d);
    double med = t[1 + rn->reps / 2];
    if (rn->json)
        printf("{\"path\":\"gl\",\"renderer\":\"%s\",\"width\":%u,\"height\":%u,\"boxes\":%u,"
               "\"lights\":%u,\"threads\":%u,\"damaged\":%.3f,\"median_ms\":%.3f,\"triangles_submitted\":%u}\n",
               rn->gl_name, rn->W, rn->H, s->n, nl, rn->lp_threads, damaged < 0 ? 0 : damaged, med, drawn * 12);
    else
        printf("%-6s %8u %7u %7u %10.2f %8.1f %9u  (submitted; %s)%s\n", "gl", s->n, nl, rn->lp_threads, med,
               1000 / med, drawn * 12, rn->gl_name, damage_label(damaged));
    fflush(stdout);
    free(t);
    return 0;
}

static vt_light *make_lights(uint32_t nl)
{
    vt_light *L = calloc(nl + 1, sizeof *L);
    for (uint32_t k = 0; L && k < nl; k++) {
        L[k].l.pos[0] = bench_frand() * 200 - 100;
        L[k].l.pos[1] = 1 + bench_frand() * 8;
        L[k].l.pos[2] = 20 + bench_frand() * 380;
        L[k].l.radius = 30;
        L[k].color[0] = 400;
        L[k].color[1] = (float)(300 + 100 * bench_frand());
        L[k].color[2] = (float)(200 + 200 * bench_frand());
    }
    return L;
}

/* The encoders on the frame in rgba and depth: tone map, EXR (ZIP and
 * none), PNG (levels 1 and 6), JPEG 85; a line each. */
static int time_encoders(uint32_t W, uint32_t H, int reps, bool json, const float *rgba, const float *depth)
{
    char err[1024];
    char dir[] = "/tmp/vantage-bench-XXXXXX";
    if (!mkdtemp(dir)) return -1;
    char path[256];
    uint8_t *rgb8 = malloc(vt_image_rgba8_size(W, H));
    if (!rgb8) return -1;
    const float *top = rgba + (size_t)(H - 1) * W * 4;
    ptrdiff_t ys = -(ptrdiff_t)W * 4;
    vt_image_src src = {.r = {top, 4, ys}, .g = {top + 1, 4, ys}, .b = {top + 2, 4, ys}, .a = {top + 3, 4, ys}};
    vt_tonemap_desc td = {.exposure_ev = -2, .op = VT_TONEMAP_ACES};
    static const char *names[] = {"tonemap", "exr-zip", "exr-none", "png-1", "png-6", "jpeg-85"};
    for (int e = 0; e < 6; e++) {
        double *t = malloc((size_t)reps * sizeof *t);
        long bytes = 0;
        for (int r = 0; r < reps; r++) {
            snprintf(path, sizeof path, "%s/frame", dir);
            double t0 = (bench_now_ns() / 1e6);
            int rc = 0;
            if (e == 0) {
                rc = vt_image_tonemap(W, H, &src, &td, rgb8, 4 * (size_t)W);
            } else if (e <= 2) {
                vt_exr_channel ch[5] = {{"R", VT_EXR_HALF, top, 4, ys},     {"G", VT_EXR_HALF, top + 1, 4, ys},
                                        {"B", VT_EXR_HALF, top + 2, 4, ys}, {"A", VT_EXR_HALF, top + 3, 4, ys},
                                        {"Z", VT_EXR_FLOAT, depth + (size_t)(H - 1) * W, 1, -(ptrdiff_t)W}};
                rc = vt_exr_write(path, W, H, ch, 5, e == 1 ? VT_EXR_ZIP : VT_EXR_NONE, err, sizeof err);
            } else if (e <= 4) {
                rc = vt_png_write(path, W, H, rgb8, 4 * (size_t)W, false, e == 3 ? 1 : 6, err, sizeof err);
            } else {
                rc = vt_jpeg_write(path, W, H, rgb8, 4 * (size_t)W, 4, 85, err, sizeof err);
            }
            t[r] = (bench_now_ns() / 1e6) - t0;
            if (rc) {
                fprintf(stderr, "bench_render: %s: %s\n", names[e], err);
                return -1;
            }
            struct stat sb;
            if (e && stat(path, &sb) == 0) bytes = (long)sb.st_size;
        }
        qsort(t, (size_t)reps, sizeof *t, bench_cmp_d);
        if (json)
            printf("{\"encode\":\"%s\",\"width\":%u,\"height\":%u,\"median_ms\":%.3f,\"bytes\":%ld}\n", names[e], W, H,
                   t[reps / 2], bytes);
        else
            printf("encode %-9s %8.2f ms %9ld bytes\n", names[e], t[reps / 2], bytes);
        free(t);
    }
    unlink(path);
    rmdir(dir);
    free(rgb8);
    return 0;
}

int main(int argc, char **argv)
{
    bool json = false, quick = false, smoke = false, gl = true, city = true, city_only = false;
    const char *png_dir = NULL, *only_view = NULL;
    uint32_t max_lights = 0;
    uint32_t W = 1280, H = 720;
    int reps = 15;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--json")) json = true;
        else if (!strcmp(argv[i], "--quick")) quick = true;
        else if (!strcmp(argv[i], "--smoke")) smoke = true;
        else if (!strcmp(argv[i], "--no-gl")) gl = false;
        else if (!strcmp(argv[i], "--size") && i + 1 < argc && sscanf(argv[i + 1], "%ux%u", &W, &H) == 2) i++;
        else if (!strcmp(argv[i], "--reps") && i + 1 < argc) reps = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--city-only")) city_only = true;
        else if (!strcmp(argv[i], "--no-city")) city = false;
        else if (!strcmp(argv[i], "--png") && i + 1 < argc) png_dir = argv[++i];
        else if (!strcmp(argv[i], "--view") && i + 1 < argc && (!strcmp(argv[i + 1], "street") || !strcmp(argv[i + 1], "aerial")))
            only_view = argv[++i];
        else if (!strcmp(argv[i], "--lights") && i + 1 < argc && bench_count(argv[i + 1], &max_lights)) i++;
        else {
            fprintf(stderr, "usage: bench_render [--json] [--quick] [--smoke] [--no-gl] [--size WxH] [--reps N] "
                            "[--city-only] [--no-city] [--png DIR] [--view street|aerial] [--lights N]\n");
            return 2;
        }
    }
    if (smoke) {
        W = 320;
        H = 180;
        reps = 2;
    } else if (quick) {
        reps = 5;
    }
    if (W < 16 || H < 16 || W > 8192 || H > 8192 || reps < 1) return 2;
    static const uint32_t counts[] = {1000, 15000, 100000};
    static const uint32_t nlights[] = {0, 16, 256};
    size_t ncounts = smoke ? 1 : quick ? 2 : 3;
    run rn = {.W = W, .H = H, .reps = reps, .json = json, .gl_name = ""};
    if (cull_pool_create(2, &rn.pool)) return 1;
    if (cull_ctx_create(rn.pool, &rn.ctx)) return 1;
    float *rgba = rn.rgba = malloc((size_t)W * H * 4 * sizeof *rgba), *depth = rn.depth = malloc((size_t)W * H * sizeof *depth);
    if (!rgba || !depth) return 1;
    char err[1024];
    /* the GL path, where there is one (a benchmark skips, never fails) */
    if (gl) {
        setenv("LP_NUM_THREADS", "2", 0);
        rn.lp_threads = (unsigned)atoi(getenv("LP_NUM_THREADS"));
        if (vt_gl_open(&rn.g, NULL, err, sizeof err) || vt_gldraw_create(rn.g, &rn.gr, err, sizeof err)) {
            fprintf(stderr, "bench_render: no GL path here (%s)\n", err);
            vt_gl_close(rn.g);
            rn.g = NULL;
        } else {
            rn.gl_name = vt_gl_get_info(rn.g)->renderer;
        }
    }
    {
        cull_view_desc d = {.origin = {0, 8, 0}, .viewport_w = W, .viewport_h = H};
        double proj[16], view[16], dir[3] = {0, -0.08, 1}, up[3] = {0, 1, 0};
        cull_mat_perspective(proj, 60 * M_PI / 180, (double)W / H, 0.1, 2000, CULL_DEPTH_GL);
        cull_mat_look_dir(view, dir, up);
        cull_mat_mul(d.view_proj, proj, view);
        if (cull_view_init(&rn.v, &d)) return 1;
    }
    if (city || city_only) {
        bench_city_opts co = {.pool = rn.pool, .width = W, .height = H, .reps = reps, .json = json, .gl = rn.gr,
                              .gl_name = rn.gl_name, .lp_threads = rn.lp_threads, .png_dir = png_dir,
                              .view = only_view, .max_lights = max_lights};
        if (bench_city(&co)) return 1;
    }
    if (city_only) ncounts = 0;
    if (!json && ncounts) printf("%-6s %8s %7s %7s %10s %8s %9s  (median of %d frames)\n", "path", "boxes", "lights", "threads",
                      "median_ms", "fps", "triangles", reps);
    for (size_t ci = 0; ci < ncounts; ci++) {
        scene s;
        if (make_scene(&s, counts[ci])) return 1;
        rn.cap = cull_query_bound(s.w);
        rn.res = malloc(rn.cap * sizeof *rn.res);
        rn.vis = malloc(rn.cap * sizeof *rn.vis);
        if (!rn.res || !rn.vis) return 1;
        for (size_t li = 0; li < (smoke ? 2 : 3); li++) {
            uint32_t nl = nlights[li];
            vt_light *L = make_lights(nl);
            if (!L) return 1;
            for (uint32_t threads = 1; threads <= 2; threads++)
                if (time_soft(&rn, &s, L, nl, threads, -1)) return 1;
            if (rn.g && time_gl(&rn, &s, L, nl, -1)) return 1;
            /* the scene model's default environment (16 lights, 2 threads) */
            if (nl == 16 && time_soft_env(&rn, &s, L, nl, 2, -1, default_env())) return 1;
            free(L);
        }
        /* destruction masks: the same boxes, 16 lights, none / every
           tenth / every box damaged (2 threads) */
        if (ci < 2) {
            vt_light *L = make_lights(16);
            if (!L) return 1;
            if (!json) printf("destruction masks, %u boxes, 16 lights:\n", counts[ci]);
            static const uint32_t every[3] = {0, 10, 1};
            for (int k = 0; k < (smoke ? 2 : 3); k++) {
                if (damage(&s, every[k])) return 1;
                double frac = every[k] ? 1.0 / every[k] : 0;
                if (time_soft(&rn, &s, L, 16, 2, frac)) return 1;
                if (rn.g && time_gl(&rn, &s, L, 16, frac)) return 1;
            }
            free(L);
        }
        free(rn.res);
        free(rn.vis);
        free_scene(&s);
    }

    /* the encoders, on the last frame */
    if (!city_only && time_encoders(W, H, reps, json, rgba, depth)) return 1;
    free(rgba);
    free(depth);
    vt_gldraw_destroy(rn.gr);
    vt_gl_close(rn.g);
    cull_ctx_destroy(rn.ctx);
    cull_pool_destroy(rn.pool);
    return 0;
}
