/*
 * bench_occlusion.c — software occlusion on the shared city scene: run time
 * against error (a benchmark: nothing here fails on time).
 *
 *   bench_occlusion [--scene F] [--walk W[,W...]] [--frames N] [--reps N]
 *                   [--size WxH] [--json] [--quick] [--smoke] [--exr DIR] [--cold]
 *
 * The walks (--walk; default all of them, --loop: street), 16 frames each:
 *   street   the city scene's 15,000 object AABBs as entities, its 1,000
 *            boxes as 1,000 occluders; the scene's street-level camera
 *            walks 0.5 m per frame toward the target (a frozen camera lets
 *            branch predictors learn the scene)
 *   raised   the city from above the street camera: 30 -> 60 m up, looking
 *            along +z and down 30 -> 45 degrees, 2 m per frame
 *   topdown  the city straight down from 250 m over its centre (a
 *            commander's view), 5 m per frame
 *   orbit    the city's centre circled once at 100 m radius, 50 m up,
 *            looking at the centre on the ground
 *   town, dense, sparse   seeded random towns (bench_town_make, as
 *            report_cull's; 15,000 objects, 700 / 2,000 / 150 boxes), the
 *            town's street-level camera walking 0.5 m per frame
 *   ("town" selects the three towns, "all" every walk.)
 * --size WxH: that buffer size only. --smoke: 2 frames, 3 reps, 256x114,
 * every walk, the false/hidden-visible reference at 960x540 (make test). The exit status is 3 if any walk has a false
 * occluded object (times never fail).
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
 *   kept_query_ns  the same query again, a second time: the context keeps
 *              the buffer it drew and the verdicts its first re-query
 *              recorded (what a still camera pays a frame; issue 24's
 *              target: <= 1.3 x frustum)
 *   kept_first_ns  (JSON) that first re-query, which records the verdicts
 *   frustum_ns the query without occlusion
 *   cold_query_ns  (--cold) the whole query (FRESH) right after 64 MiB of
 *              other memory traffic: caches hold none of the scene, the
 *              buffer or the context (issue 24: "first call after other
 *              work"); -1 without --cold
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
 * (--walk W: that walk's frames instead of the street's)
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

/* ---- the walks ------------------------------------------------------------------------------- */
enum { W_STREET, W_RAISED, W_TOPDOWN, W_ORBIT, W_TOWN, W_DENSE, W_SPARSE, NWALKS };
static const char *const walk_name[NWALKS] = {"street", "raised", "topdown", "orbit", "town", "dense", "sparse"};
#define TOWN_SEED 0x70F7u

/* The city scene's boxes span x -794..794, z 6..994, roofs up to 199 m;
 * its camera stands at (1, 1.7, 220) looking along +z. */
static const double city_centre[3] = {0, 0, 500};

/* frames views of walk k on sf (the city scene for street .. orbit, the
 * town for the others): 0, or the cull_view_init error. */
static int make_walk(int k, const scene_file *sf, int frames, cull_view *out)
{
    if (k == W_STREET || k >= W_TOWN) return bench_walk(sf, NULL, frames, out);
    double up[3] = {0, 1, 0};
    for (int f = 0; f < frames; f++) {
        double t = frames > 1 ? (double)f / (frames - 1) : 0, eye[3], dir[3];
        if (k == W_RAISED) {
            /* above the street camera, 30 -> 60 m up, looking along +z and down 30 -> 45
               degrees, moving 2 m a frame */
            double pitch = (30 + 15 * t) * M_PI / 180;
            eye[0] = sf->eye[0], eye[1] = 30 + 30 * t, eye[2] = sf->eye[2] + 2.0 * f;
            dir[0] = 0, dir[1] = -sin(pitch), dir[2] = cos(pitch);
        } else if (k == W_TOPDOWN) {
            /* a commander's view: straight down from 250 m, over the centre, 5 m a frame */
            eye[0] = city_centre[0], eye[1] = 250, eye[2] = city_centre[2] - 40 + 5.0 * f;
            dir[0] = 0, dir[1] = -1, dir[2] = 0;
            up[0] = 0, up[1] = 0, up[2] = 1;
        } else {
            /* orbiting the centre at 100 m radius, 50 m up, looking at the centre on the ground */
            double a = 2 * M_PI * f / frames;
            eye[0] = city_centre[0] + 100 * sin(a), eye[1] = 50, eye[2] = city_centre[2] - 100 * cos(a);
            for (int i = 0; i < 3; i++) dir[i] = city_centre[i] - eye[i];
        }
        int rc = bench_view_look(sf, NULL, eye, dir, up, &out[f]);
        if (rc) return rc;
    }
    return 0;
}

/* One walk's world: the scene's objects as entities and its boxes as occluders. */
typedef struct walk_scene {
    scene_file sf;
    cull_world *w;
    double *tri;
} walk_scene;

static int walk_scene_make(int k, const char *scene, walk_scene *ws)
{
    memset(ws, 0, sizeof *ws);
    if (k < W_TOWN) {
        if (bench_load_world("bench_occlusion", scene, &ws->sf, NULL, &ws->w)) return 1;
    } else {
        if (bench_town_make(k - W_TOWN, TOWN_SEED + (uint64_t)(k - W_TOWN) * 0x9E37, 15000, &ws->sf)) return 1;
        if (cull_world_create(NULL, &ws->w) || bench_add_objects(ws->w, &ws->sf, NULL, NULL)) return 1;
    }
    if (bench_add_boxes(ws->w, &ws->sf, NULL)) return 1;
    ws->tri = bench_tris_world(&ws->sf, NULL);
    return ws->tri ? 0 : 1;
}

static void walk_scene_free(walk_scene *ws)
{
    free(ws->tri);
    if (ws->w) cull_world_destroy(ws->w);
    scene_file_free(&ws->sf);
}

typedef struct run_opts {
    int frames, reps;
    bool json, smoke, cold;
    const char *exr_dir;
    uint32_t only_w, only_h; /* one buffer size; 0 = all */
} run_opts;

/* Evicts the caches: 64 MiB written and read back (twice this VM's L3). */
static void flush_caches(void)
{
    static unsigned char *junk;
    enum { JUNK = 64u << 20 };
    if (!junk && !(junk = malloc(JUNK))) return;
    static unsigned char v;
    memset(junk, ++v, JUNK);
    volatile unsigned sum = 0;
    for (size_t i = 0; i < JUNK; i += 64) sum += junk[i];
    (void)sum;
}

/* The table for one walk; *false_occ gets the false-occluded objects
 * summed over its frames and modes. 0, or 1 on failure. */
static int run_walk(int k, const walk_scene *ws, const cull_view *walk, cull_pool *pool, cull_ctx *ctx,
                    const run_opts *o, uint64_t *false_occ)
{
    const scene_file *psf = &ws->sf;
    cull_world *w = ws->w;
    const double *tri = ws->tri;
    int frames = o->frames, reps = o->reps;
    const char *wname = walk_name[k];
    size_t cap = cull_query_bound(w);
    cull_result *out = malloc(cap * sizeof *out);
    uint8_t *kept = malloc(psf->nobjects), *surv = malloc(psf->nobjects);
    if (!out || !kept || !surv) return 1;
    size_t nboxes = psf->ntris / 12;

    /* frustum survivors and the reference (1920x1080; --smoke: 960x540), per frame */
    uint32_t tw = o->smoke ? 960 : 1920, th = o->smoke ? 540 : 1080;
    frame_ref ref[MAX_FRAMES];
    double t0 = bench_now_ns();
    for (int f = 0; f < frames; f++) {
        size_t n;
        cull_query_desc q = {.views = &walk[f], .view_count = 1, .flags = CULL_Q_NO_OCCLUSION};
        if (cull_query(w, ctx, &q, out, cap, &n, NULL)) return 1;
        ref[f].r1080 = calloc(psf->nobjects, 1);
        if (!ref[f].r1080) return 1;
        memset(surv, 0, psf->nobjects);
        for (size_t i = 0; i < n; i++) surv[out[i].handle & (CULL_MAX_ENTITIES - 1)] = 1;
        if (bench_caster(&walk[f], tw, th, tri, psf->ntris, psf, NULL, surv, ref[f].r1080)) return 1;
    }
    if (!o->json)
        printf("\nwalk %s: %zu objects, %zu occluder boxes; %d frames; exact %ux%u references in %.1f s; kernels %s\n",
               wname, psf->nobjects, nboxes, frames, tw, th, (bench_now_ns() - t0) / 1e9,
               cull_isa_name(cull_ctx_isa(ctx)));

    /* warm up: caches, page faults of the contexts' buffers, clocks */
    {
        double t_end = bench_now_ns() + (o->smoke ? 2e7 : 3e8);
        size_t n;
        for (int f = 0; bench_now_ns() < t_end; f = (f + 1) % frames) {
            cull_query_desc q = {.views = &walk[f], .view_count = 1};
            if (cull_query(w, ctx, &q, out, cap, &n, NULL)) return 1;
        }
    }
    if (!o->json) {
        printf("%-8s %-10s %-6s %3s %10s %9s %10s %9s %8s %8s %8s | %7s %8s %8s %8s %9s\n", "walk", "buffer", "cover",
               "thr", "raster_us", "test_us", "rast+test", "query_us", "kept_us", "frust_us", "cold_us", "tested", "visible",
               "false_vis", "hidden_vis", "false_occ");
    }
    size_t nsizes = o->smoke ? 1 : NSIZES;
    for (size_t s = 0; s < nsizes; s++) {
        uint32_t bw = sizes[s].w, bh = sizes[s].h;
        if (o->only_w && (bw != o->only_w || bh != o->only_h)) continue;
        /* the exact caster at this size, per frame (for false_occluded) */
        uint8_t *rsame[MAX_FRAMES];
        for (int f = 0; f < frames; f++) {
            rsame[f] = calloc(psf->nobjects, 1);
            if (!rsame[f]) return 1;
            if (bw == tw && bh == th) {
                memcpy(rsame[f], ref[f].r1080, psf->nobjects);
                continue;
            }
            if (bench_caster(&walk[f], bw, bh, tri, psf->ntris, psf, NULL, NULL, rsame[f])) return 1;
        }
        cull_occ_buffer *buf;
        if (cull_occ_buffer_create(bw, bh, &buf)) return 1;
        for (uint32_t cover = 0; cover < 2; cover++) {
            cull_occ_buffer_set_cover(buf, cover);
            for (uint32_t threads = 1; threads <= 2; threads++) {
                double tr[MAX_FRAMES], tt[MAX_FRAMES], tq[MAX_FRAMES], tsum[MAX_FRAMES], tk[MAX_FRAMES],
                    tn[MAX_FRAMES], tc[MAX_FRAMES], tk1[MAX_FRAMES];
                uint64_t s_tested = 0, s_vis = 0, s_fv = 0, s_hv = 0, s_fo = 0;
                for (int f = 0; f < frames; f++) {
                    double *a = malloc(sizeof(double) * 7 * (size_t)reps), *b = a + reps, *c = b + reps,
                           *d = c + reps, *e = d + reps, *g = e + reps, *h = g + reps;
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
                        h[r] = bench_now_ns() - x;
                        x = bench_now_ns();
                        if (cull_query(w, ctx, &qk, out, cap, &n, NULL)) return 1;
                        e[r] = bench_now_ns() - x;
                    }
                    tr[f] = bench_median(a, reps);
                    tt[f] = bench_median(b, reps) - bench_median(c, reps);
                    tq[f] = bench_median(d, reps);
                    tk[f] = bench_median(e, reps);
                    tk1[f] = bench_median(h, reps);
                    tn[f] = bench_median(c, reps);
                    tsum[f] = tr[f] + tt[f];
                    tc[f] = -1;
                    if (o->cold) {
                        for (int r = 0; r < reps; r++) {
                            flush_caches();
                            double x = bench_now_ns();
                            if (cull_query(w, ctx, &qw, out, cap, &n, NULL)) return 1;
                            g[r] = bench_now_ns() - x;
                        }
                        tc[f] = bench_median(g, reps);
                    }
                    free(a);
                    /* accuracy, from the query on the rendered buffer */
                    if (cull_occ_render(w, &walk[f], buf, pool, threads, NULL)) return 1;
                    if (cull_query(w, ctx, &qo, out, cap, &n, NULL)) return 1;
                    memset(kept, 0, psf->nobjects);
                    for (size_t i = 0; i < n; i++) kept[out[i].handle & (CULL_MAX_ENTITIES - 1)] = 1;
                    size_t ns;
                    if (cull_query(w, ctx, &qn, out, cap, &ns, NULL)) return 1;
                    memset(surv, 0, psf->nobjects);
                    for (size_t i = 0; i < ns; i++) surv[out[i].handle & (CULL_MAX_ENTITIES - 1)] = 1;
                    uint32_t fv = 0, hv = 0, fo = 0;
                    for (size_t i = 0; i < psf->nobjects; i++) {
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
                    *false_occ += fo;
                    if (o->json)
                        printf("{\"walk\":\"%s\",\"frame\":%d,\"buffer\":\"%ux%u\",\"cover\":\"%s\",\"threads\":%u,"
                               "\"raster_ns\":%.0f,\"test_ns\":%.0f,\"query_ns\":%.0f,\"kept_query_ns\":%.0f,\"kept_first_ns\":%.0f,"
                               "\"frustum_ns\":%.0f,\"cold_query_ns\":%.0f,\"tested\":%zu,\"visible\":%zu,"
                               "\"false_visible\":%u,\"hidden_visible_1080\":%u,\"false_occluded\":%u}\n",
                               wname, f, bw, bh, cover ? "centre" : "inner", threads, tr[f], tt[f], tq[f], tk[f], tk1[f], tn[f], tc[f], ns,
                               n, fv, hv, fo);
                    if (o->exr_dir && f == 0 && threads == 1) {
                        uint32_t W, H;
                        size_t stride;
                        cull_occ_render(w, &walk[f], buf, pool, 1, NULL);
                        const float *dep = cull_occ_depth(buf, &W, &H, &stride);
                        if (!dep) {
                            fprintf(stderr, "bench_occlusion: --exr: no memory for the buffer's copy\n");
                            return 1;
                        }
                        float *img = malloc(sizeof(float) * W * H);
                        if (!img) return 1;
                        for (uint32_t y = 0; y < H; y++)
                            for (uint32_t x = 0; x < W; x++) {
                                float z = dep[(size_t)(H - 1 - y) * stride + x];
                                img[(size_t)y * W + x] = z == -FLT_MAX ? 0.0f : z;
                            }
                        char path[512];
                        snprintf(path, sizeof path, "%s/occlusion_%s_%ux%u_%s.exr", o->exr_dir, wname, W, H,
                                 cover ? "centre" : "inner");
                        vt_exr_channel ch = {"Z", VT_EXR_FLOAT, img, 1, (ptrdiff_t)W};
                        char err[256];
                        if (vt_exr_write(path, W, H, &ch, 1, VT_EXR_ZIP, err, sizeof err))
                            fprintf(stderr, "bench_occlusion: %s: %s\n", path, err);
                        else if (!o->json)
                            printf("wrote %s\n", path);
                        free(img);
                    }
                }
                if (!o->json)
                    printf("%-8s %4ux%-5u %-6s %3u %10.1f %9.1f %10.1f %9.1f %8.1f %8.1f %8.1f | %7.0f %8.1f %8.1f %8.2f "
                           "%9.2f\n",
                           wname, bw, bh, cover ? "centre" : "inner", threads, bench_median(tr, frames) / 1e3,
                           bench_median(tt, frames) / 1e3, bench_median(tsum, frames) / 1e3, bench_median(tq, frames) / 1e3,
                           bench_median(tk, frames) / 1e3, bench_median(tn, frames) / 1e3,
                           o->cold ? bench_median(tc, frames) / 1e3 : -1.0,
                           (double)s_tested / frames, (double)s_vis / frames, (double)s_fv / frames,
                           (double)s_hv / frames, (double)s_fo / frames);
                fflush(stdout);
            }
        }
        cull_occ_buffer_destroy(buf);
        for (int f = 0; f < frames; f++) free(rsame[f]);
    }
    for (int f = 0; f < frames; f++) free(ref[f].r1080);
    free(out);
    free(kept);
    free(surv);
    return 0;
}

int main(int argc, char **argv)
{
    const char *scene = "tests/data/scenes/city_scene.txt";
    run_opts o = {.frames = 16, .reps = 31};
    bool quick = false, centre = false, sel[NWALKS] = {false}, any = false, size_set = false;
    int loop = 0;
    uint32_t lw = 256, lh = 114;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--scene") && i + 1 < argc) scene = argv[++i];
        else if (!strcmp(argv[i], "--frames") && i + 1 < argc) o.frames = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--reps") && i + 1 < argc) o.reps = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--exr") && i + 1 < argc) o.exr_dir = argv[++i];
        else if (!strcmp(argv[i], "--json")) o.json = true;
        else if (!strcmp(argv[i], "--quick")) quick = true;
        else if (!strcmp(argv[i], "--smoke")) o.smoke = true;
        else if (!strcmp(argv[i], "--cold")) o.cold = true;
        else if (!strcmp(argv[i], "--loop") && i + 1 < argc) loop = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--centre")) centre = true;
        else if (!strcmp(argv[i], "--size") && i + 1 < argc && sscanf(argv[i + 1], "%ux%u", &lw, &lh) == 2) {
            i++;
            size_set = true;
        } else if (!strcmp(argv[i], "--walk") && i + 1 < argc) {
            /* a comma-separated list; "town" is the three towns, "all" every walk */
            char buf[256];
            snprintf(buf, sizeof buf, "%s", argv[++i]);
            for (char *save = NULL, *t = strtok_r(buf, ",", &save); t; t = strtok_r(NULL, ",", &save)) {
                int hit = 0;
                for (int k = 0; k < NWALKS; k++)
                    if (!strcmp(t, "all") || !strcmp(t, walk_name[k]) || (!strcmp(t, "town") && k >= W_TOWN))
                        sel[k] = true, hit = 1;
                if (!hit) {
                    fprintf(stderr, "bench_occlusion: unknown walk %s\n", t);
                    return 2;
                }
                any = true;
            }
        } else {
            fprintf(stderr, "usage: bench_occlusion [--scene F] [--walk street|raised|topdown|orbit|town|dense|sparse"
                            "|all[,...]] [--frames N] [--reps N] [--size WxH] [--json] [--quick] [--smoke] "
                            "[--exr DIR] [--cold] [--loop N [--size WxH] [--centre]]\n");
            return 2;
        }
    }
    if (o.smoke) {
        o.frames = 2;
        o.reps = 3;
    } else if (quick) {
        o.reps = 11;
    }
    if (o.frames < 1 || o.frames > MAX_FRAMES || o.reps < 1 || loop < 0) return 2;
    if (!any) {
        /* every walk; --loop: the street walk */
        for (int k = 0; k < NWALKS; k++) sel[k] = !loop || k == W_STREET;
    }
    if (size_set && !loop) o.only_w = lw, o.only_h = lh;

    cull_pool *pool;
    if (cull_pool_create(2, &pool)) return 1;
    if (!o.json)
        printf("bench_occlusion: scene %s, towns seeded 0x%x; frames of every walk: %d; walks:", scene, TOWN_SEED,
               o.frames);
    for (int k = 0; k < NWALKS && !o.json; k++)
        if (sel[k]) printf(" %s", walk_name[k]);
    if (!o.json) printf("\n");

    uint64_t false_occ[NWALKS] = {0};
    int rc = 0;
    for (int k = 0; k < NWALKS && !rc; k++) {
        if (!sel[k]) continue;
        walk_scene ws;
        cull_view walk[MAX_FRAMES];
        cull_ctx *ctx = NULL; /* one a walk: a context's kept buffers belong to one world */
        if (walk_scene_make(k, scene, &ws) || make_walk(k, &ws.sf, o.frames, walk) || cull_ctx_create(pool, &ctx)) {
            walk_scene_free(&ws);
            rc = 1;
            break;
        }
        if (loop) {
            size_t cap = cull_query_bound(ws.w);
            cull_result *out = malloc(cap * sizeof *out);
            printf("walk %s: ", walk_name[k]);
            rc = !out || run_loops(ws.w, ctx, walk, o.frames, loop, lw, lh, centre, out, cap);
            free(out);
        } else {
            rc = run_walk(k, &ws, walk, pool, ctx, &o, &false_occ[k]);
        }
        cull_ctx_destroy(ctx);
        walk_scene_free(&ws);
    }
    cull_pool_destroy(pool);
    if (rc || loop) return rc;
    uint64_t total = 0;
    for (int k = 0; k < NWALKS; k++) total += false_occ[k];
    if (!o.json) {
        printf("\ncounts are per frame, averaged over the walk; times are medians over frames of the "
               "median over %d repetitions\nfalse occluded, summed over frames and modes:",
               o.reps);
        for (int k = 0; k < NWALKS; k++)
            if (sel[k]) printf(" %s %llu", walk_name[k], (unsigned long long)false_occ[k]);
        printf("\n");
    }
    if (total) {
        fprintf(stderr, "bench_occlusion: FAILED: %llu false occluded (an object culled that an exact caster of the "
                        "buffer's size sees)\n", (unsigned long long)total);
        return 3;
    }
    return 0;
}
