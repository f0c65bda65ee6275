/*
 * bench_occlusion.c — software occlusion on the shared city scene: run time
 * against error (a benchmark: nothing here fails on time).
 *
 *   bench_occlusion [--scene F] [--frames N] [--reps N] [--json] [--quick]
 *                   [--smoke] [--exr DIR]
 *
 * The world: the scene's 15,000 object AABBs as entities, its 1,000 boxes
 * as 1,000 occluders. The camera walks 0.5 m per frame toward the target
 * (16 frames): a frozen camera lets branch predictors learn the scene.
 *
 * Per buffer size (256x114, 512x256, 1280x720, 1920x1080), coverage rule
 * (inner: pixels covered whole; centre: pixels whose centre is covered) and
 * thread count (1, 2), per frame:
 *   raster_ns  cull_occ_render: clear, cluster selection, sort, raster,
 *              hierarchy (median over reps)
 *   test_ns    query with that buffer minus the same query without
 *              occlusion: the occlusion stage's share of the pipeline
 *   query_ns   the whole query, rendering included (what a caller pays for a
 *              moving camera: CULL_Q_OCC_FRESH)
 *   kept_query_ns  the same query again: the context keeps the buffer it drew
 *              (a still camera's re-query; issue 24's target: <= 1.3 x frustum)
 *   frustum_ns the query without occlusion
 *   tested     frustum survivors; visible: kept after occlusion
 *   false_visible   kept, but the exact 1920x1080 ray caster sees nothing
 *   hidden_visible  culled, but the exact 1920x1080 caster sees it
 *   false_occluded  culled, but an exact caster of the buffer's size sees it
 * The reference is tests/occ_ref.c (double precision, per pixel centre).
 * --exr DIR writes frame 0's buffers as one-channel EXRs (Z = the stored
 * nearness, 0 where no occluder) for an EXR viewer.
 *
 * --loop N [--size WxH] [--centre]: no references and no table; per frame,
 * one drawing query, then N kept queries (kept_loop) and N frustum-only
 * queries (frust_loop), one thread, for an instruction count:
 *   valgrind --tool=callgrind --collect-atstart=no --toggle-collect=kept_loop
 *            --toggle-collect=frust_loop build/release/bench_occlusion --loop 20
 * (callgrind_annotate --inclusive=yes gives each loop's share; fresh_loop:
 * the same number of drawing queries, CULL_Q_OCC_FRESH). It prints
 * the per-query stats of the kept query and the two loops' medians.
 */
#include "culling.h"
#include "bench_util.h"
#include "bench_scene.h"
#include "occ_ref.h"
#include "scene_file.h"
#include "vt_exr.h"

#include <float.h>
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define MAX_FRAMES 64

/* The loops --loop counts: noipa (not inlined, not folded into one), so callgrind can name them. */
__attribute__((noipa)) static int kept_loop(cull_world *w, cull_ctx *ctx, const cull_query_desc *q,
                                               cull_result *out, size_t cap, int n, size_t *count)
{
    for (int i = 0; i < n; i++)
        if (cull_query(w, ctx, q, out, cap, count, NULL)) return 1;
    return 0;
}

__attribute__((noipa)) static int frust_loop(cull_world *w, cull_ctx *ctx, const cull_query_desc *q,
                                                cull_result *out, size_t cap, int n, size_t *count)
{
    for (int i = 0; i < n; i++)
        if (cull_query(w, ctx, q, out, cap, count, NULL)) return 1;
    return 0;
}

__attribute__((noipa)) static int fresh_loop(cull_world *w, cull_ctx *ctx, const cull_query_desc *q,
                                                cull_result *out, size_t cap, int n, size_t *count)
{
    for (int i = 0; i < n; i++)
        if (cull_query(w, ctx, q, out, cap, count, NULL)) return 1;
    return 0;
}

/* --loop: per frame, a drawing query, then n kept, n frustum-only and n
 * drawing (CULL_Q_OCC_FRESH) queries; prints the kept query's stats and
 * the medians per query. */
static int run_loops(cull_world *w, cull_ctx *ctx, const cull_view *walk, int frames, int n, uint32_t bw,
                     uint32_t bh, bool centre, cull_result *out, size_t cap)
{
    double tk[MAX_FRAMES], tn[MAX_FRAMES];
    uint64_t vis = 0, tested = 0, cells_occ = 0, reused = 0, occ_in = 0;
    for (int f = 0; f < frames; f++) {
        cull_query_desc qk = {.views = &walk[f], .view_count = 1, .threads = 1, .occ_w = bw, .occ_h = bh,
                              .flags = centre ? CULL_Q_OCC_CENTRE : 0};
        cull_query_desc qn = {.views = &walk[f], .view_count = 1, .threads = 1, .flags = CULL_Q_NO_OCCLUSION};
        size_t c;
        cull_query_stats st;
        if (cull_query(w, ctx, &qk, out, cap, &c, NULL)) return 1; /* draws */
        if (cull_query(w, ctx, &qk, out, cap, &c, &st)) return 1;
        vis += st.visible;
        tested += st.entities_tested;
        occ_in += st.after_area;
        cells_occ += st.cells_occluded;
        reused += st.occ_reused;
        double x = bench_now_ns();
        if (kept_loop(w, ctx, &qk, out, cap, n, &c)) return 1;
        tk[f] = (bench_now_ns() - x) / n;
        x = bench_now_ns();
        if (frust_loop(w, ctx, &qn, out, cap, n, &c)) return 1;
        tn[f] = (bench_now_ns() - x) / n;
        cull_query_desc qf = qk;
        qf.flags |= CULL_Q_OCC_FRESH;
        if (fresh_loop(w, ctx, &qf, out, cap, n, &c)) return 1;
    }
    printf("loop %ux%u %s: %d frames x %d queries; kept query: %.1f entities tested, %.1f to the occlusion test, %.1f visible, %.1f cells "
           "occluded, %.0f/%d kept; median kept %.1f us, frustum %.1f us\n",
           bw, bh, centre ? "centre" : "inner", frames, n, (double)tested / frames, (double)occ_in / frames, (double)vis / frames,
           (double)cells_occ / frames, (double)reused, frames, bench_median(tk, frames) / 1e3,
           bench_median(tn, frames) / 1e3);
    return 0;
}



typedef struct frame_ref {
    uint8_t *r1080;   /* per object: visible to the exact 1920x1080 caster */
} frame_ref;

static const struct { uint32_t w, h; } sizes[] = {{256, 114}, {512, 256}, {1280, 720}, {1920, 1080}};
#define NSIZES (sizeof sizes / sizeof sizes[0])

int main(int argc, char **argv)
{
    const char *scene = "tests/data/scenes/city_scene.txt", *exr_dir = NULL;
    int frames = 16, reps = 31;
    bool json = false, quick = false, smoke = false, centre = false;
    int loop = 0;
    uint32_t lw = 256, lh = 114;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--scene") && i + 1 < argc) scene = argv[++i];
        else if (!strcmp(argv[i], "--frames") && i + 1 < argc) frames = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--reps") && i + 1 < argc) reps = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--exr") && i + 1 < argc) exr_dir = argv[++i];
        else if (!strcmp(argv[i], "--json")) json = true;
        else if (!strcmp(argv[i], "--quick")) quick = true;
        else if (!strcmp(argv[i], "--smoke")) smoke = true;
        else if (!strcmp(argv[i], "--loop") && i + 1 < argc) loop = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--centre")) centre = true;
        else if (!strcmp(argv[i], "--size") && i + 1 < argc && sscanf(argv[i + 1], "%ux%u", &lw, &lh) == 2) i++;
        else {
            fprintf(stderr, "usage: bench_occlusion [--scene F] [--frames N] [--reps N] [--json] [--quick] "
                            "[--smoke] [--exr DIR] [--loop N [--size WxH] [--centre]]\n");
            return 2;
        }
    }
    if (smoke) {
        frames = 2;
        reps = 3;
    } else if (quick) {
        reps = 11;
    }
    if (frames < 1 || frames > MAX_FRAMES || reps < 1 || loop < 0) return 2;

    scene_file sf;
    cull_world *w;
    /* a fresh world hands out slots 0, 1, 2...: slot = object index */
    if (bench_load_world("bench_occlusion", scene, &sf, NULL, &w) || bench_add_boxes(w, &sf, NULL)) return 1;
    size_t nboxes = sf.ntris / 12;
    double *tri = bench_tris_world(&sf, NULL);
    if (!tri) return 1;

    cull_pool *pool;
    if (cull_pool_create(2, &pool)) return 1;
    cull_ctx *ctx;
    if (cull_ctx_create(pool, &ctx)) return 1;
    size_t cap = cull_query_bound(w);
    cull_result *out = malloc(cap * sizeof *out);
    uint8_t *kept = malloc(sf.nobjects), *surv = malloc(sf.nobjects);
    if (!out || !kept || !surv) return 1;

    /* the walk */
    cull_view walk[MAX_FRAMES];
    if (bench_walk(&sf, NULL, frames, walk)) return 1;

    if (loop) {
        int rc = run_loops(w, ctx, walk, frames, loop, lw, lh, centre, out, cap);
        free(out);
        free(kept);
        free(surv);
        free(tri);
        cull_ctx_destroy(ctx);
        cull_pool_destroy(pool);
        cull_world_destroy(w);
        scene_file_free(&sf);
        return rc;
    }

    /* frustum survivors and the 1080p reference, per frame */
    frame_ref ref[MAX_FRAMES];
    double t0 = bench_now_ns();
    for (int f = 0; f < frames; f++) {
        size_t n;
        cull_query_desc q = {.views = &walk[f], .view_count = 1, .flags = CULL_Q_NO_OCCLUSION};
        if (cull_query(w, ctx, &q, out, cap, &n, NULL)) return 1;
        ref[f].r1080 = calloc(sf.nobjects, 1);
        if (!ref[f].r1080) return 1;
        memset(surv, 0, sf.nobjects);
        for (size_t i = 0; i < n; i++) surv[out[i].handle & (CULL_MAX_ENTITIES - 1)] = 1;
        if (bench_caster(&walk[f], 1920, 1080, tri, sf.ntris, &sf, NULL, surv, ref[f].r1080)) return 1;
    }
    if (!json)
        printf("city scene %s: %zu objects, %zu occluder boxes; %d frames walking 0.5 m; exact 1080p "
               "references in %.1f s; kernels %s\n",
               scene, sf.nobjects, nboxes, frames, (bench_now_ns() - t0) / 1e9, cull_isa_name(cull_ctx_isa(ctx)));

    /* warm up: caches, page faults of the contexts' buffers, clocks */
    {
        double t_end = bench_now_ns() + 3e8;
        size_t n;
        for (int f = 0; bench_now_ns() < t_end; f = (f + 1) % frames) {
            cull_query_desc q = {.views = &walk[f], .view_count = 1};
            if (cull_query(w, ctx, &q, out, cap, &n, NULL)) return 1;
        }
    }
    if (!json) {
        printf("\n%-10s %-6s %3s %10s %9s %10s %9s %8s %8s | %7s %8s %8s %8s %9s\n", "buffer", "cover", "thr",
               "raster_us", "test_us", "rast+test", "query_us", "kept_us", "frust_us", "tested", "visible",
               "false_vis", "hidden_vis", "false_occ");
    }
    size_t nsizes = smoke ? 1 : NSIZES;
    for (size_t s = 0; s < nsizes; s++) {
        uint32_t bw = sizes[s].w, bh = sizes[s].h;
        /* the exact caster at this size, per frame (for false_occluded) */
        uint8_t *rsame[MAX_FRAMES];
        for (int f = 0; f < frames; f++) {
            rsame[f] = calloc(sf.nobjects, 1);
            if (!rsame[f]) return 1;
            if (bw == 1920 && bh == 1080) {
                memcpy(rsame[f], ref[f].r1080, sf.nobjects);
                continue;
            }
            if (bench_caster(&walk[f], bw, bh, tri, sf.ntris, &sf, NULL, NULL, rsame[f])) return 1;
        }
        cull_occ_buffer *buf;
        if (cull_occ_buffer_create(bw, bh, &buf)) return 1;
        for (uint32_t cover = 0; cover < 2; cover++) {
            cull_occ_buffer_set_cover(buf, cover);
            for (uint32_t threads = 1; threads <= 2; threads++) {
                double tr[MAX_FRAMES], tt[MAX_FRAMES], tq[MAX_FRAMES], tsum[MAX_FRAMES], tk[MAX_FRAMES],
                    tn[MAX_FRAMES];
                uint64_t s_tested = 0, s_vis = 0, s_fv = 0, s_hv = 0, s_fo = 0;
                for (int f = 0; f < frames; f++) {
                    double *a = malloc(sizeof(double) * 5 * (size_t)reps), *b = a + reps, *c = b + reps,
                           *d = c + reps, *e = d + reps;
                    if (!a) return 1;
                    cull_occ_buffer *const bufs[1] = {buf};
                    cull_query_desc qo = {.views = &walk[f], .view_count = 1, .threads = threads,
                                          .occ_buffers = bufs};
                    cull_query_desc qn = {.views = &walk[f], .view_count = 1, .threads = threads,
                                          .flags = CULL_Q_NO_OCCLUSION};
                    /* the whole query, its occluders drawn each time (FRESH: a moving camera), and
                       again through the buffer the context kept (a still camera's re-query) */
                    cull_query_desc qw = {.views = &walk[f], .view_count = 1, .threads = threads, .occ_w = bw,
                                          .occ_h = bh, .flags = (cover ? CULL_Q_OCC_CENTRE : 0) | CULL_Q_OCC_FRESH};
                    cull_query_desc qk = qw;
                    qk.flags &= ~CULL_Q_OCC_FRESH;
                    size_t n;
                    for (int r = 0; r < reps; r++) {
                        double x = bench_now_ns();
                        if (cull_occ_render(w, &walk[f], buf, pool, threads, NULL)) return 1;
                        a[r] = bench_now_ns() - x;
                        x = bench_now_ns();
                        if (cull_query(w, ctx, &qo, out, cap, &n, NULL)) return 1;
                        b[r] = bench_now_ns() - x;
                        x = bench_now_ns();
                        if (cull_query(w, ctx, &qn, out, cap, &n, NULL)) return 1;
                        c[r] = bench_now_ns() - x;
                        x = bench_now_ns();
                        if (cull_query(w, ctx, &qw, out, cap, &n, NULL)) return 1;
                        d[r] = bench_now_ns() - x;
                        x = bench_now_ns();
                        if (cull_query(w, ctx, &qk, out, cap, &n, NULL)) return 1;
                        e[r] = bench_now_ns() - x;
                    }
                    tr[f] = bench_median(a, reps);
                    tt[f] = bench_median(b, reps) - bench_median(c, reps);
                    tq[f] = bench_median(d, reps);
                    tk[f] = bench_median(e, reps);
                    tn[f] = bench_median(c, reps);
                    tsum[f] = tr[f] + tt[f];
                    free(a);
                    /* accuracy, from the query on the rendered buffer */
                    if (cull_occ_render(w, &walk[f], buf, pool, threads, NULL)) return 1;
                    if (cull_query(w, ctx, &qo, out, cap, &n, NULL)) return 1;
                    memset(kept, 0, sf.nobjects);
                    for (size_t i = 0; i < n; i++) kept[out[i].handle & (CULL_MAX_ENTITIES - 1)] = 1;
                    size_t ns;
                    if (cull_query(w, ctx, &qn, out, cap, &ns, NULL)) return 1;
                    memset(surv, 0, sf.nobjects);
                    for (size_t i = 0; i < ns; i++) surv[out[i].handle & (CULL_MAX_ENTITIES - 1)] = 1;
                    uint32_t fv = 0, hv = 0, fo = 0;
                    for (size_t i = 0; i < sf.nobjects; i++) {
                        if (!surv[i]) continue;
                        if (kept[i] && !ref[f].r1080[i]) fv++;
                        if (!kept[i] && ref[f].r1080[i]) hv++;
                        if (!kept[i] && rsame[f][i]) fo++;
                    }
                    s_tested += ns;
                    s_vis += n;
                    s_fv += fv;
                    s_hv += hv;
                    s_fo += fo;
                    if (json)
                        printf("{\"scene\":\"city\",\"frame\":%d,\"buffer\":\"%ux%u\",\"cover\":\"%s\",\"threads\":%u,"
                               "\"raster_ns\":%.0f,\"test_ns\":%.0f,\"query_ns\":%.0f,\"kept_query_ns\":%.0f,"
                               "\"frustum_ns\":%.0f,\"tested\":%zu,\"visible\":%zu,"
                               "\"false_visible\":%u,\"hidden_visible_1080\":%u,\"false_occluded\":%u}\n",
                               f, bw, bh, cover ? "centre" : "inner", threads, tr[f], tt[f], tq[f], tk[f], tn[f], ns,
                               n, fv, hv, fo);
                    if (exr_dir && f == 0 && threads == 1) {
                        uint32_t W, H;
                        size_t stride;
                        cull_occ_render(w, &walk[f], buf, pool, 1, NULL);
                        const float *dep = cull_occ_depth(buf, &W, &H, &stride);
                        float *img = malloc(sizeof(float) * W * H);
                        if (!img) return 1;
                        for (uint32_t y = 0; y < H; y++)
                            for (uint32_t x = 0; x < W; x++) {
                                float z = dep[(size_t)(H - 1 - y) * stride + x];
                                img[(size_t)y * W + x] = z == -FLT_MAX ? 0.0f : z;
                            }
                        char path[512];
                        snprintf(path, sizeof path, "%s/occlusion_%ux%u_%s.exr", exr_dir, W, H,
                                 cover ? "centre" : "inner");
                        vt_exr_channel ch = {"Z", VT_EXR_FLOAT, img, 1, (ptrdiff_t)W};
                        char err[256];
                        if (vt_exr_write(path, W, H, &ch, 1, VT_EXR_ZIP, err, sizeof err))
                            fprintf(stderr, "bench_occlusion: %s: %s\n", path, err);
                        else if (!json)
                            printf("wrote %s\n", path);
                        free(img);
                    }
                }
                if (!json)
                    printf("%4ux%-5u %-6s %3u %10.1f %9.1f %10.1f %9.1f %8.1f %8.1f | %7.0f %8.1f %8.1f %8.2f %9.2f\n",
                           bw, bh, cover ? "centre" : "inner", threads, bench_median(tr, frames) / 1e3,
                           bench_median(tt, frames) / 1e3, bench_median(tsum, frames) / 1e3, bench_median(tq, frames) / 1e3,
                           bench_median(tk, frames) / 1e3, bench_median(tn, frames) / 1e3,
                           (double)s_tested / frames, (double)s_vis / frames, (double)s_fv / frames,
                           (double)s_hv / frames, (double)s_fo / frames);
                fflush(stdout);
            }
        }
        cull_occ_buffer_destroy(buf);
        for (int f = 0; f < frames; f++) free(rsame[f]);
    }
    if (!json)
        printf("\ncounts are per frame, averaged over the walk; times are medians over frames of the "
               "median over %d repetitions\n",
               reps);
    for (int f = 0; f < frames; f++) free(ref[f].r1080);
    free(out);
    free(kept);
    free(surv);
    free(tri);
    cull_ctx_destroy(ctx);
    cull_pool_destroy(pool);
    cull_world_destroy(w);
    scene_file_free(&sf);
    return 0;
}
