/*
 * bench_cull.c — the culling benchmark (a benchmark, not a test: nothing
 * here fails on time).
 *
 *   bench_cull                 full matrix: 15k and 1M entities x 1/4/16/32
 *                              views x 1/2 threads x every ISA x stages,
 *                              plus the talk's naive early-out intersect()
 *   bench_cull --quick         the 15k cases only
 *   bench_cull --smoke         a few iterations of a few cases (make test)
 *   bench_cull --demo --scene F  the shared city scene through the pipeline
 *   --json                     one JSON object per line instead of a table
 *   --filter S                 only cases whose name contains S
 *
 * The camera moves every call (a path of 64 poses, 0.5 m and 0.7 degrees
 * apart): a frozen camera lets the branch predictor learn 15k outcomes.
 * "cold" cases stream 256 MiB through the caches before every call.
 * Times are per query: median and minimum over the iterations.
 */
#include "culling.h"
#include "bench_util.h"
#include "bench_scene.h"
#include "scene_file.h"

#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define PATH_LEN 64
/* the flat world is the same scene moved by this much in x and z, so that
   with 16 km cells it is one cell: every entity tested every query */
#define FLAT_SHIFT 8192.0

static bool g_json, g_smoke;
static const char *g_filter;




/* ---- the scene: N entities in a slab, cameras on a path ------------------ */
typedef struct bscene {
    uint32_t n;
    double half;                  /* slab is [-half, half] x [0, 60] x [-half, half] */
    float *aos;                   /* x y z r per entity, world, for the baseline */
    cull_world *grid, *flat;      /* 64 m cells / everything in one cell */
    cull_view path[PATH_LEN][CULL_MAX_VIEWS];
    cull_view path_flat[PATH_LEN][CULL_MAX_VIEWS]; /* the same, shifted by FLAT_SHIFT */
    float planes[PATH_LEN][6][4]; /* view 0's planes, world, for the baseline */
} bscene;

static void make_camera(cull_view *v, double x, double z, double yaw, uint32_t vw, uint32_t vh)
{
    cull_view_desc d = {.viewport_w = vw, .viewport_h = vh, .depth_mode = CULL_DEPTH_REVERSED};
    d.origin[0] = x;
    d.origin[1] = 2.0;
    d.origin[2] = z;
    double proj[16], view[16];
    cull_mat_perspective(proj, 60 * M_PI / 180, (double)vw / vh, 0.1, 1000, d.depth_mode);
    cull_mat_look_dir(view, (double[]){sin(yaw), -0.05, -cos(yaw)}, (double[]){0, 1, 0});
    cull_mat_mul(d.view_proj, proj, view);
    if (cull_view_init(v, &d) != CULL_OK) abort();
}

static void scene_build(bscene *s, uint32_t n)
{
    memset(s, 0, sizeof *s);
    s->n = n;
    /* ~15k entities per km^2, as the talk's level */
    s->half = 500.0 * sqrt(n / 15000.0);
    s->aos = malloc((size_t)n * 4 * sizeof *s->aos);
    if (cull_world_create(&(cull_world_desc){.cell_size = 64}, &s->grid) ||
        cull_world_create(&(cull_world_desc){.cell_size = 16384}, &s->flat))
        abort();
    for (uint32_t i = 0; i < n; i++) {
        cull_entity_desc e = {0};
        e.center[0] = (bench_frand() * 2 - 1) * s->half;
        e.center[1] = bench_frand() * 60;
        e.center[2] = (bench_frand() * 2 - 1) * s->half;
        e.radius = 0.25 + 4 * bench_frand() * bench_frand();
        e.class_id = (uint16_t)(i % 64);
        cull_handle h;
        if (cull_entity_add(s->grid, &e, &h)) abort();
        e.center[0] += FLAT_SHIFT;
        e.center[2] += FLAT_SHIFT;
        if (cull_entity_add(s->flat, &e, &h)) abort();
        e.center[0] -= FLAT_SHIFT;
        e.center[2] -= FLAT_SHIFT;
        for (int a = 0; a < 3; a++) s->aos[i * 4 + a] = (float)e.center[a];
        s->aos[i * 4 + 3] = (float)e.radius;
    }
    for (int p = 0; p < PATH_LEN; p++) {
        double x = -16 + 0.5 * p, z = 10 - 0.3 * p, yaw = p * 0.0122;
        for (uint32_t v = 0; v < CULL_MAX_VIEWS; v++) {
            make_camera(&s->path[p][v], x + 3.0 * v, z, yaw + v * (2 * M_PI / CULL_MAX_VIEWS), 1280, 720);
            s->path_flat[p][v] = s->path[p][v];
            s->path_flat[p][v].origin[0] += FLAT_SHIFT;
            s->path_flat[p][v].origin[2] += FLAT_SHIFT;
        }
        const cull_view *v0 = &s->path[p][0];
        for (uint32_t i = 0; i < 6; i++) {
            const double *pl = v0->plane[i < v0->plane_count ? i : 0];
            /* world-space plane: d - n.origin */
            for (int a = 0; a < 3; a++) s->planes[p][i][a] = (float)pl[a];
            s->planes[p][i][3] = (float)(pl[3] - pl[0] * v0->origin[0] - pl[1] * v0->origin[1] -
                                         pl[2] * v0->origin[2]);
        }
    }
}

static void scene_free(bscene *s)
{
    free(s->aos);
    cull_world_destroy(s->grid);
    cull_world_destroy(s->flat);
}

/* ---- the talk's baseline: AoS spheres, early-out per plane --------------- */
typedef struct sphere { float x, y, z, r; } sphere;
typedef struct plane { float nx, ny, nz, d; } plane;

static __attribute__((noinline)) bool intersect(const plane *frustum, sphere s)
{
    for (int i = 0; i < 6; i++) {
        const plane *p = &frustum[i];
        if (p->nx * s.x + p->ny * s.y + p->nz * s.z + p->d < -s.r) return false;
    }
    return true;
}

static __attribute__((noinline)) size_t naive_cull(const float *aos, uint32_t n, const plane *fr,
                                                   uint32_t *out)
{
    size_t k = 0;
    for (uint32_t i = 0; i < n; i++) {
        sphere s = {aos[i * 4], aos[i * 4 + 1], aos[i * 4 + 2], aos[i * 4 + 3]};
        if (intersect(fr, s)) out[k++] = i;
    }
    return k;
}

/* ---- measurement ---------------------------------------------------------- */
static char *g_flush;
#define FLUSH_BYTES (256u << 20)

static void flush_caches(void)
{
    if (!g_flush) g_flush = malloc(FLUSH_BYTES);
    for (size_t i = 0; i < FLUSH_BYTES; i += 64) g_flush[i]++;
}

typedef struct result {
    double median, min, visible;
    int iters;
    uint32_t tested; /* entities that reached the block stage, last call */
} result;

static int iters_for(uint32_t n, uint32_t views)
{
    if (g_smoke) return 3;
    double work = (double)n * views;
    int it = (int)(4e8 / (work + 1e5));
    return it < 15 ? 15 : it > 2001 ? 2001 : it;
}

static void report(const char *bench, const char *scene, uint32_t n, uint32_t views, uint32_t threads,
                   const char *isa, const char *stage, const char *cache, const result *r)
{
    if (g_json) {
        printf("{\"bench\":\"%s\",\"scene\":\"%s\",\"entities\":%u,\"views\":%u,\"threads\":%u,"
               "\"isa\":\"%s\",\"stage\":\"%s\",\"cache\":\"%s\",\"median_ns\":%.0f,\"min_ns\":%.0f,"
               "\"visible\":%.0f,\"tested\":%u,\"iterations\":%d}\n",
               bench, scene, n, views, threads, isa, stage, cache, r->median, r->min, r->visible, r->tested,
               r->iters);
    } else {
        printf("%-6s %-5s %8u %5u %7u %-7s %-7s %-5s %12.2f %12.2f %9.0f\n", bench, scene, n, views, threads,
               isa, stage, cache, r->median / 1e3, r->min / 1e3, r->visible);
    }
    fflush(stdout);
}

static bool wanted(const char *name)
{
    return !g_filter || strstr(name, g_filter);
}

static void run_naive(bscene *s, bool cold)
{
    char name[128];
    snprintf(name, sizeof name, "naive %u %s", s->n, cold ? "cold" : "warm");
    if (!wanted(name)) return;
    uint32_t *out = malloc((size_t)s->n * sizeof *out);
    int it = iters_for(s->n, 1);
    if (cold && !g_smoke && it > 30) it = 30;
    double *t = malloc(it * sizeof *t), vis = 0;
    for (int i = 0; i < it; i++) {
        if (cold) flush_caches();
        const plane *fr = (const plane *)s->planes[i % PATH_LEN];
        double t0 = bench_now_ns();
        size_t k = naive_cull(s->aos, s->n, fr, out);
        t[i] = bench_now_ns() - t0;
        vis += k;
    }
    qsort(t, it, sizeof *t, bench_cmp_d);
    result r = {t[it / 2], t[0], vis / it, it, s->n};
    report("naive", "aos", s->n, 1, 1, "scalar", "sphere", cold ? "cold" : "warm", &r);
    free(t);
    free(out);
}

static void run_case(bscene *s, cull_pool *pool, bool flat, uint32_t views, uint32_t threads, uint32_t isa,
                     const char *stage, bool cold)
{
    char name[160];
    snprintf(name, sizeof name, "cull %s %u %u %u %s %s %s", flat ? "flat" : "grid", s->n, views, threads,
             cull_isa_name(isa), stage, cold ? "cold" : "warm");
    if (!wanted(name)) return;
    cull_ctx *ctx;
    if (cull_ctx_create(pool, &ctx) || cull_ctx_set_isa(ctx, isa)) abort();
    cull_world *w = flat ? s->flat : s->grid;
    size_t cap = cull_query_bound(w), n = 0;
    cull_result *out = malloc(cap * sizeof *out);
    cull_query_desc q = {.view_count = views, .threads = threads};
    if (!strcmp(stage, "sphere")) q.flags = CULL_Q_NO_AABB;
    else if (!strcmp(stage, "full")) q.min_screen_area = 4.0f; /* drop what covers < 4 px */
    else if (!strcmp(stage, "area")) q.flags = CULL_Q_WANT_AREA, q.min_screen_area = 4.0f;
    int it = iters_for(s->n, views);
    if (cold && !g_smoke && it > 30) it = 30;
    double *t = malloc(it * sizeof *t), vis = 0;
    cull_query_stats st = {0};
    /* one untimed call grows the context's scratch */
    cull_view (*path)[CULL_MAX_VIEWS] = flat ? s->path_flat : s->path;
    q.views = path[0];
    if (cull_query(w, ctx, &q, out, cap, &n, NULL)) abort();
    for (int i = 0; i < it; i++) {
        if (cold) flush_caches();
        q.views = path[i % PATH_LEN];
        double t0 = bench_now_ns();
        if (cull_query(w, ctx, &q, out, cap, &n, i == it - 1 ? &st : NULL)) abort();
        t[i] = bench_now_ns() - t0;
        vis += n;
    }
    qsort(t, it, sizeof *t, bench_cmp_d);
    result r = {t[it / 2], t[0], vis / it, it, st.entities_tested};
    report("cull", flat ? "flat" : "grid", s->n, views, threads, cull_isa_name(isa), stage,
           cold ? "cold" : "warm", &r);
    free(t);
    free(out);
    cull_ctx_destroy(ctx);
}

static void run_matrix(uint32_t n, cull_pool *pool)
{
    bscene *s = malloc(sizeof *s);
    scene_build(s, n);
    static const uint32_t view_counts[] = {1, 4, 16, 32};
    bool big = n > 100000;
    run_naive(s, false);
    if (big) run_naive(s, true);
    for (uint32_t isa = 0; isa < CULL_ISA_COUNT; isa++) {
        if (!cull_isa_supported(isa)) continue;
        for (int flat = 0; flat < 2; flat++) {
            for (size_t vi = 0; vi < sizeof view_counts / sizeof *view_counts; vi++) {
                uint32_t views = view_counts[vi];
                if (flat && views > 1) continue; /* flat: the talk's brute-force comparison */
                for (uint32_t th = 1; th <= 2; th++) {
                    run_case(s, pool, flat, views, th, isa, "sphere", false);
                    if (!flat) {
                        run_case(s, pool, flat, views, th, isa, "aabb", false);
                        run_case(s, pool, flat, views, th, isa, "full", false);
                        run_case(s, pool, flat, views, th, isa, "area", false);
                    }
                    if (big && views == 1) run_case(s, pool, flat, views, th, isa, "sphere", true);
                }
            }
            if (g_smoke) break;
        }
        if (g_smoke) break;
    }
    scene_free(s);
    free(s);
}

/* ---- the city scene demo --------------------------------------------------- */
static int demo(const char *path, cull_pool *pool)
{
    scene_file sf;
    cull_world *w;
    double cs = getenv("VANTAGE_CELL") ? atof(getenv("VANTAGE_CELL")) : 0;
    if (bench_load_world("bench_cull", path, &sf, &(cull_world_desc){.cell_size = cs}, &w)) return 1;
    cull_world_info info;
    cull_world_info_get(w, &info);
    printf("city scene %s: %zu objects in %u cells, %u blocks, %.1f MiB\n", path, sf.nobjects, info.cells,
           info.blocks, info.bytes / 1048576.0);
    cull_ctx *ctx;
    if (cull_ctx_create(pool, &ctx)) return 1;
    printf("kernels: %s (VANTAGE_ISA=scalar|sse41|avx2 to force)\n", cull_isa_name(cull_ctx_isa(ctx)));
    size_t cap = cull_query_bound(w);
    cull_result *out = malloc(cap * sizeof *out);
    /* the camera walks 0.5 m per frame toward the target, 16 frames */
    cull_view walk[16];
    if (bench_walk(&sf, NULL, 16, walk)) return 1;
    static const struct { const char *name; float area; uint32_t flags; } rows[] = {
        {"spheres only", 0, CULL_Q_NO_AABB},
        {"spheres + AABB", 0, 0},
        {"+ area >= 1 px (bound)", 1, 0},
        {"+ area >= 1 px (exact)", 1, CULL_Q_WANT_AREA},
        {"+ area >= 16 px (bound)", 16, 0},
        {"+ area >= 16 px (exact)", 16, CULL_Q_WANT_AREA},
        {"+ area >= 256 px (bound)", 256, 0},
    };
    printf("  %-26s %8s %10s   (first frame; median over 200 walks of 16 frames)\n", "stages", "visible",
           "median_us");
    for (size_t k = 0; k < sizeof rows / sizeof rows[0]; k++) {
        double t[3200];
        size_t n = 0, first = 0;
        for (int rep = 0; rep < 3200; rep++) {
            cull_query_desc q = {.views = &walk[rep % 16], .view_count = 1, .min_screen_area = rows[k].area,
                                 .flags = rows[k].flags};
            double t0 = bench_now_ns();
            if (cull_query(w, ctx, &q, out, cap, &n, NULL)) return 1;
            t[rep] = bench_now_ns() - t0;
            if (rep == 0) first = n;
        }
        qsort(t, 3200, sizeof *t, bench_cmp_d);
        printf("  %-26s %8zu %10.1f\n", rows[k].name, first, t[1600] / 1e3);
    }
    cull_query_stats st;
    size_t n;
    if (cull_query(w, ctx, &(cull_query_desc){.views = &walk[0], .view_count = 1}, out, cap, &n, &st)) return 1;
    printf("  pipeline on the first frame: %u of %u regions and %u of %u cells culled whole; %u entities "
           "tested, %u pass the spheres, %u the AABBs\n",
           st.regions_culled, st.regions, st.cells_culled, st.cells, st.entities_tested, st.after_spheres,
           st.after_aabb);
    free(out);
    cull_ctx_destroy(ctx);
    cull_world_destroy(w);
    scene_file_free(&sf);
    return 0;
}

int main(int argc, char **argv)
{
    bool quick = false, do_demo = false;
    const char *scene = NULL;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--json")) g_json = true;
        else if (!strcmp(argv[i], "--quick")) quick = true;
        else if (!strcmp(argv[i], "--smoke")) g_smoke = quick = true;
        else if (!strcmp(argv[i], "--demo")) do_demo = true;
        else if (!strcmp(argv[i], "--scene") && i + 1 < argc) scene = argv[++i];
        else if (!strcmp(argv[i], "--filter") && i + 1 < argc) g_filter = argv[++i];
        else {
            fprintf(stderr, "usage: bench_cull [--quick|--smoke] [--json] [--filter S] [--demo --scene FILE]\n");
            return 2;
        }
    }
    cull_pool *pool;
    if (cull_pool_create(2, &pool)) return 1;
    if (do_demo) {
        int rc = demo(scene ? scene : "tests/data/scenes/city_scene.txt", pool);
        cull_pool_destroy(pool);
        return rc;
    }
    if (!g_json) {
        printf("bench_cull: times in microseconds per query (median, min); visible = mean results\n");
        printf("%-6s %-5s %8s %5s %7s %-7s %-7s %-5s %12s %12s %9s\n", "bench", "scene", "entities", "views",
               "threads", "isa", "stage", "cache", "median_us", "min_us", "visible");
    }
    run_matrix(15000, pool);
    if (!quick) run_matrix(1000000, pool);
    cull_pool_destroy(pool);
    free(g_flush);
    return 0;
}
