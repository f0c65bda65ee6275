/*
 * bench_render.c — frames per second of the render path (a benchmark: it
 * fails on nothing).
 *
 *   bench_render [--json] [--quick] [--smoke] [--no-gl] [--size WxH] [--reps N]
 *
 * The scene: N boxes (1k, 15k, 100k) of 0.5..4 m scattered over a 200 x
 * 380 m field in front of the camera, 0, 16 or 256 point lights of 30 m
 * range among them, a camera 60 degrees wide at 1280x720. The software
 * path runs the whole frame: the culling query (frustum; no occluders here,
 * so no occlusion stage) picks the visible boxes, then vt_soft renders
 * them; 1 and 2 threads. The GL path (vt_glr through headless EGL:
 * llvmpipe here, LP_NUM_THREADS=2 unless set) draws the same visible set
 * in the same run: the culling query, then two passes (nearness, then
 * shading with the CPU-binned tile lists) and the readback of colour and
 * depth. --no-gl skips it. Then the encoders on the last frame: EXR (half
 * RGBA + float Z; ZIP and none), PNG (levels 1 and 6), JPEG (q 85), each
 * after tone mapping where the format is 8-bit.
 *
 * --json: one object per line, {path, renderer, width, height, boxes,
 * lights, threads, median_ms, ...}, and {encode, width, height, median_ms,
 * bytes} for the encoders.
 */
#include "culling.h"
#include "bench_util.h"
#include "vt_exr.h"
#include "vt_glr.h"
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

int main(int argc, char **argv)
{
    bool json = false, quick = false, smoke = false, gl = true;
    uint32_t W = 1280, H = 720;
    int reps = 15;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--json")) json = true;
        else if (!strcmp(argv[i], "--quick")) quick = true;
        else if (!strcmp(argv[i], "--smoke")) smoke = true;
        else if (!strcmp(argv[i], "--no-gl")) gl = false;
        else if (!strcmp(argv[i], "--size") && i + 1 < argc && sscanf(argv[i + 1], "%ux%u", &W, &H) == 2) i++;
        else if (!strcmp(argv[i], "--reps") && i + 1 < argc) reps = atoi(argv[++i]);
        else {
            fprintf(stderr, "usage: bench_render [--json] [--quick] [--smoke] [--no-gl] [--size WxH] [--reps N]\n");
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

    cull_pool *pool;
    if (cull_pool_create(2, &pool)) return 1;
    cull_ctx *ctx;
    if (cull_ctx_create(pool, &ctx)) return 1;
    const vt_mesh cube = vt_mesh_box;
    float *rgba = malloc((size_t)W * H * 4 * sizeof *rgba), *depth = malloc((size_t)W * H * sizeof *depth);
    if (!rgba || !depth) return 1;
    char err[1024];

    /* the GL path, where there is one (a benchmark skips, never fails) */
    vt_gl *g = NULL;
    vt_glr *gr = NULL;
    const char *gl_name = "";
    unsigned lp_threads = 0;
    if (gl) {
        setenv("LP_NUM_THREADS", "2", 0);
        lp_threads = (unsigned)atoi(getenv("LP_NUM_THREADS"));
        if (vt_gl_open(&g, NULL, err, sizeof err) || vt_glr_create(g, &gr, err, sizeof err)) {
            fprintf(stderr, "bench_render: no GL path here (%s)\n", err);
            vt_gl_close(g);
            g = NULL;
        } else {
            gl_name = vt_gl_get_info(g)->renderer;
        }
    }

    cull_view v;
    {
        cull_view_desc d = {.origin = {0, 8, 0}, .viewport_w = W, .viewport_h = H};
        double proj[16], view[16], dir[3] = {0, -0.08, 1}, up[3] = {0, 1, 0};
        cull_mat_perspective(proj, 60 * M_PI / 180, (double)W / H, 0.1, 2000, CULL_DEPTH_GL);
        cull_mat_look_dir(view, dir, up);
        cull_mat_mul(d.view_proj, proj, view);
        if (cull_view_init(&v, &d)) return 1;
    }
    if (!json) printf("%-6s %8s %7s %7s %10s %8s %9s  (median of %d frames)\n", "path", "boxes", "lights", "threads",
                      "median_ms", "fps", "triangles", reps);

    for (size_t ci = 0; ci < ncounts; ci++) {
        scene s;
        if (make_scene(&s, counts[ci])) return 1;
        size_t cap = cull_query_bound(s.w);
        cull_result *res = malloc(cap * sizeof *res);
        vt_instance *vis = malloc(cap * sizeof *vis);
        if (!res || !vis) return 1;
        for (size_t li = 0; li < (smoke ? 2 : 3); li++) {
            uint32_t nl = nlights[li];
            vt_light *L = calloc(nl + 1, sizeof *L);
            if (!L) return 1;
            for (uint32_t k = 0; k < nl; k++) {
                L[k].l.pos[0] = bench_frand() * 200 - 100;
                L[k].l.pos[1] = 1 + bench_frand() * 8;
                L[k].l.pos[2] = 20 + bench_frand() * 380;
                L[k].l.radius = 30;
                L[k].color[0] = 400;
                L[k].color[1] = (float)(300 + 100 * bench_frand());
                L[k].color[2] = (float)(200 + 200 * bench_frand());
            }
            for (uint32_t threads = 1; threads <= 2; threads++) {
                vt_soft *sr;
                if (vt_soft_create(pool, threads, &sr)) return 1;
                double *t = malloc((size_t)reps * sizeof *t);
                vt_soft_stats st = {0};
                for (int r = 0; r < reps; r++) {
                    double t0 = (bench_now_ns() / 1e6);
                    size_t n;
                    cull_query_desc q = {.views = &v, .view_count = 1, .threads = threads};
                    if (cull_query(s.w, ctx, &q, res, cap, &n, NULL)) return 1;
                    for (size_t k = 0; k < n; k++) vis[k] = s.all[res[k].handle & (CULL_MAX_ENTITIES - 1)];
                    if (vt_soft_render(sr, &v, W, H, &cube, 1, vis, (uint32_t)n, L, nl, rgba, depth, W, &st, err,
                                       sizeof err)) {
                        fprintf(stderr, "bench_render: %s\n", err);
                        return 1;
                    }
                    t[r] = (bench_now_ns() / 1e6) - t0;
                }
                qsort(t, (size_t)reps, sizeof *t, bench_cmp_d);
                double med = t[reps / 2];
                if (json)
                    printf("{\"path\":\"soft\",\"renderer\":\"vantage soft\",\"width\":%u,\"height\":%u,\"boxes\":%u,"
                           "\"lights\":%u,\"threads\":%u,\"median_ms\":%.3f,\"triangles\":%u,\"setup_ms\":%.3f,"
                           "\"raster_ms\":%.3f,\"bin_ms\":%.3f,\"shade_ms\":%.3f}\n",
                           W, H, counts[ci], nl, threads, med, st.triangles, st.setup_ns / 1e6, st.raster_ns / 1e6,
                           st.bin_ns / 1e6, st.shade_ns / 1e6);
                else
                    printf("%-6s %8u %7u %7u %10.2f %8.1f %9u  (setup %.2f raster %.2f bin %.2f shade %.2f ms)\n",
                           "soft", counts[ci], nl, threads, med, 1000 / med, st.triangles, st.setup_ns / 1e6,
                           st.raster_ns / 1e6, st.bin_ns / 1e6, st.shade_ns / 1e6);
                fflush(stdout);
                free(t);
                vt_soft_destroy(sr);
            }
            if (g) {
                double *t = malloc((size_t)(reps + 1) * sizeof *t);
                uint32_t drawn = 0;
                for (int r = 0; r <= reps; r++) { /* one warm-up: shader compiles, buffers grow */
                    double t0 = (bench_now_ns() / 1e6);
                    size_t n;
                    cull_query_desc q = {.views = &v, .view_count = 1, .threads = 2};
                    if (cull_query(s.w, ctx, &q, res, cap, &n, NULL)) return 1;
                    for (size_t k = 0; k < n; k++) vis[k] = s.all[res[k].handle & (CULL_MAX_ENTITIES - 1)];
                    if (vt_glr_render(gr, &v, W, H, &cube, 1, vis, (uint32_t)n, L, nl, rgba, depth, W, NULL, err,
                                      sizeof err)) {
                        fprintf(stderr, "bench_render: gl: %s\n", err);
                        return 1;
                    }
                    t[r] = (bench_now_ns() / 1e6) - t0;
                    drawn = (uint32_t)n;
                }
                qsort(t + 1, (size_t)reps, sizeof *t, bench_cmp_d);
                double med = t[1 + reps / 2];
                if (json)
                    printf("{\"path\":\"gl\",\"renderer\":\"%s\",\"width\":%u,\"height\":%u,\"boxes\":%u,"
                           "\"lights\":%u,\"threads\":%u,\"median_ms\":%.3f,\"triangles_submitted\":%u}\n",
                           gl_name, W, H, counts[ci], nl, lp_threads, med, drawn * 12);
                else
                    printf("%-6s %8u %7u %7u %10.2f %8.1f %9u  (submitted; %s)\n", "gl", counts[ci], nl, lp_threads, med,
                           1000 / med, drawn * 12, gl_name);
                fflush(stdout);
                free(t);
            }
            free(L);
        }
        free(res);
        free(vis);
        free(s.all);
        cull_world_destroy(s.w);
    }

    /* the encoders, on the last frame */
    char dir[] = "/tmp/vantage-bench-XXXXXX";
    if (!mkdtemp(dir)) return 1;
    char path[256];
    uint8_t *rgb8 = malloc(vt_image_rgba8_size(W, H));
    if (!rgb8) return 1;
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
                return 1;
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
    free(rgba);
    free(depth);
    vt_glr_destroy(gr);
    vt_gl_close(g);
    cull_ctx_destroy(ctx);
    cull_pool_destroy(pool);
    return 0;
}
