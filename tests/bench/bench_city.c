/*
 * bench_city.c — issue 20's frame budget: the demo city as the daemon
 * draws it, for bench_render (bench_city.h).
 *
 * The scene is the daemon's own: scene_init with vantaged's defaults, then
 * the EDIT_CITY edit (daemon/city.c: 3000 cars, the "day" environment),
 * through the daemon's scene objects linked in (as the tests link them).
 * A frame is what daemon/frames.c's render_frame does for a JPEG RENDER:
 * the culling query with occlusion over the visible sub-levels, the
 * visible entities turned into instances of their class meshes with their
 * materials and transforms (frame_scene.c), all the scene's lights, the
 * software renderer on 2 threads, then the ACES tone map and the JPEG at
 * quality 85 in 4 bands on the 2 threads (vt_jpeg_encode_frame, as
 * frames.c's jpeg_frame). Timed apart: the gather (cull + instances),
 * each pass of vt_soft_draw (its stats), and the tone map + JPEG
 * ("encode"); the frame is their sum. The GL path (llvmpipe) draws the
 * same vt_frame in the same run.
 *
 * Two cameras (60 degrees, 0.1..10000 m, as `vantage render`): down a
 * street (test_e2e's stream camera) and the aerial view of `make run`'s
 * hint (BENCHMARKS.md, issue 19's 127-144 ms).
 */
#include "bench_city.h"
#include "bench_util.h"
#include "edit.h"
#include "frame_scene.h"
#include "scene.h"
#include "vt_gldraw.h"
#include "vt_image.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* What one frame draws (daemon/frames.c's frame_in). */
typedef struct city_frame {
    vt_instance *inst;
    vt_mesh *meshes;
    uint32_t ninst, nmesh;
    vt_light *lights;
    uint32_t nl;
    frame_scene fs;
} city_frame;

typedef struct city_run {
    scene *sc;
    cull_pool *pool;
    cull_ctx *ctx;
    cull_result *res;
    size_t cap;
    uint32_t *mesh_of;      /* class -> mesh index + 1, zero between frames */
    uint64_t vis[CULL_SUBLEVEL_WORDS];
    uint32_t max_lights;    /* bench_city_opts' */
} city_run;

static void city_frame_free(city_frame *cf)
{
    free(cf->inst);
    free(cf->meshes);
    free(cf->lights);
    frame_scene_free(&cf->fs);
    memset(cf, 0, sizeof *cf);
}

/* The daemon's gather (frames.c) for a scene whose entities all have a
 * material and none is damaged: the class albedo a material-less entity
 * would take is not needed, nor the destruction volumes. */
static int city_gather(city_run *cr, const cull_view *v, city_frame *cf)
{
    const scene *sc = cr->sc;
    memset(cf, 0, sizeof *cf);
    size_t n = 0;
    cull_query_desc q = {.views = v, .view_count = 1, .sublevels = scene_visible(sc, NULL, cr->vis)};
    if (cull_query(sc->world, cr->ctx, &q, cr->res, cr->cap, &n, NULL)) return -1;
    cf->inst = malloc((n + 1) * sizeof *cf->inst);
    cf->meshes = malloc((n + 1) * sizeof *cf->meshes);
    cf->lights = malloc((sc->lights.count + 1) * sizeof *cf->lights);
    if (!cf->inst || !cf->meshes || !cf->lights || !frame_scene_init(&cf->fs, sc)) return -1;
    cf->meshes[cf->nmesh++] = vt_mesh_box;
    for (size_t i = 0; i < n; i++) {
        uint16_t cls = cr->res[i].class_id;
        const scene_mesh *sm = &sc->meshes[cls];
        if (sm->pos && sm->ni && !cr->mesh_of[cls]) {
            cf->meshes[cf->nmesh] = (vt_mesh){.pos = sm->pos, .nrm = sm->nrm, .idx = sm->idx, .nv = sm->nv,
                                              .ni = sm->ni, .uv = sm->uv, .tan = sm->tan};
            cr->mesh_of[cls] = ++cf->nmesh;
        }
        cull_entity_desc e;
        cull_entity_get(sc->world, cr->res[i].handle, &e);
        vt_instance *in = &cf->inst[i];
        *in = (vt_instance){.mesh = cr->mesh_of[cls] ? cr->mesh_of[cls] - 1 : 0, .albedo = {0.5f, 0.5f, 0.5f}};
        memcpy(in->bmin, e.aabb_min, sizeof e.aabb_min);
        memcpy(in->bmax, e.aabb_max, sizeof e.aabb_max);
        uint32_t slot = cr->res[i].handle & (CULL_MAX_ENTITIES - 1);
        const scene_xform *x = sc->xf && slot < sc->id_cap ? &sc->xf[slot] : NULL;
        if (!x) continue;
        in->mat = frame_scene_material(&cf->fs, sc, x->material);
        if (x->flags & VP_ENT_TRANSFORM) {
            in->place = VT_PLACE_TRS;
            memcpy(in->pos, x->pos, sizeof x->pos);
            memcpy(in->rot, x->rot, sizeof x->rot);
            memcpy(in->scale, x->scale, sizeof x->scale);
        }
    }
    for (size_t i = 0; i < n; i++) cr->mesh_of[cr->res[i].class_id] = 0;
    cf->ninst = (uint32_t)n;
    for (size_t i = 0; i < sc->lights.cap; i++) {
        if (!sc->lights.used[i]) continue;
        const vp_light *l = &((const scene_light *)(uintptr_t)sc->lights.vals[i])->l;
        if (!scene_light_drawable(l)) continue;
        vt_light *o = &cf->lights[cf->nl++];
        double rad[3];
        memset(o, 0, sizeof *o);
        scene_light_cull(l, &o->l, rad);
        o->cos_inner = l->inner_cos;
        for (int a = 0; a < 3; a++) o->color[a] = (float)rad[a];
    }
    /* a budget of lights: max_lights of them, every (nl / max)th */
    if (cr->max_lights && cf->nl > cr->max_lights) {
        const uint32_t all = cf->nl, m = cr->max_lights;
        for (uint32_t k = 0; k < m; k++) cf->lights[k] = cf->lights[(uint64_t)k * all / m];
        cf->nl = m;
    }
    return 0;
}

/* The pool as vt_jpeg_encode_frame's runner, as frames.c's. */
static void pool_run(void *pool, vt_jpeg_job_fn fn, void *arg, uint32_t n)
{
    cull_pool_run(pool, fn, arg, n);
}

/* The passes a row reports, in the order of the frame. */
/* "encode": the tone map and the JPEG, in bands fused per thread as the
 * daemon's (vt_jpeg_encode_frame; they were "tonemap" and "jpeg") */
enum { P_GATHER, P_SETUP, P_RASTER, P_BIN, P_SHADE, P_SHADOW, P_SSAO, P_POST, P_ENCODE, P_TOTAL, NP };
static const char *const pass_name[NP] = {"gather", "setup", "raster", "bin",    "shade",
                                          "shadow", "ssao",   "post",   "encode", "total"};

static int cmp_d(const void *a, const void *b)
{
    return bench_cmp_d(a, b);
}

/* The camera of `vantage render`: 60 degrees, 0.1..10000 m, from eye to at. */
static int city_make_view(uint32_t W, uint32_t H, const double eye[3], const double at[3], cull_view *v)
{
    double proj[16], view[16], dir[3] = {at[0] - eye[0], at[1] - eye[1], at[2] - eye[2]}, up[3] = {0, 1, 0};
    cull_mat_perspective(proj, 60 * M_PI / 180, (double)W / H, 0.1, 10000, CULL_DEPTH_GL);
    cull_mat_look_dir(view, dir, up);
    cull_view_desc d = {.viewport_w = W, .viewport_h = H, .depth_mode = CULL_DEPTH_GL};
    memcpy(d.origin, eye, sizeof d.origin);
    cull_mat_mul(d.view_proj, proj, view);
    return cull_view_init(v, &d) ? -1 : 0;
}

/* One software frame of view v: the gather, then vt_soft_draw into
 * rgba / depth (W x H, rows bottom-up); *st its passes, *gather_ms the
 * gather's time, the counts out (each may be NULL but st). */
static int city_draw(city_run *cr, vt_soft *sr, const cull_view *v, uint32_t W, uint32_t H, float *rgba,
                     float *depth, vt_soft_stats *st, double *gather_ms, uint32_t *ninst, uint32_t *nl)
{
    city_frame cf;
    char err[512];
    double t0 = bench_now_ns();
    int grc = city_gather(cr, v, &cf);
    if (gather_ms) *gather_ms = (bench_now_ns() - t0) / 1e6;
    if (grc) {
        city_frame_free(&cf);
        fprintf(stderr, "bench_render: city: gather failed (out of memory)\n");
        return -1;
    }
    vt_frame f = {.view = v, .width = W, .height = H, .meshes = cf.meshes, .nmesh = cf.nmesh, .inst = cf.inst,
                  .ninst = cf.ninst, .lights = cf.lights, .nl = cf.nl, .env = cf.fs.env_ok ? &cf.fs.env : NULL,
                  .rgba = rgba, .depth = depth, .stride = W};
    int rc = vt_soft_draw(sr, &f, st, err, sizeof err);
    if (rc) fprintf(stderr, "bench_render: city: %s\n", err);
    if (ninst) *ninst = cf.ninst;
    if (nl) *nl = cf.nl;
    city_frame_free(&cf);
    return rc ? -1 : 0;
}

/* One camera: the software frame reps times (median per pass), then the
 * GL path's draw of the same frames. */
static int city_view(city_run *cr, const bench_city_opts *o, const char *name, const double eye[3],
                     const double at[3])
{
    uint32_t W = o->width, H = o->height;
    cull_view v;
    if (city_make_view(W, H, eye, at, &v)) return -1;
    int reps = o->reps;
    float *rgba = malloc((size_t)W * H * 4 * sizeof *rgba), *depth = malloc((size_t)W * H * sizeof *depth);
    uint8_t *rgb8 = malloc(vt_image_rgba8_size(W, H));
    double *t = calloc((size_t)NP * (size_t)(reps + 1), sizeof *t);
    vt_soft *sr = NULL;
    char err[512];
    int rc = -1;
    if (!rgba || !depth || !rgb8 || !t || vt_soft_create(cr->pool, 2, &sr)) goto out;
    uint32_t ninst = 0, nl = 0, tris = 0, shadow_tris = 0;
    size_t jbytes = 0;
    /* one warm-up frame (the sky's table, the renderer's buffers), not counted */
    for (int r = -1; r < reps; r++) {
        double *row = t + (size_t)NP * (size_t)(r + 1);
        double t0 = bench_now_ns();
        vt_soft_stats st = {0};
        double gather_ms;
        if (city_draw(cr, sr, &v, W, H, rgba, depth, &st, &gather_ms, &ninst, &nl)) goto out;
        tris = st.triangles, shadow_tris = st.shadow_triangles;
        double t2 = bench_now_ns();
        vt_tonemap_desc td = {.op = VT_TONEMAP_ACES};
        uint8_t *jpeg = NULL;
        if (vt_jpeg_encode_frame(W, H, rgba, W, &td, rgb8, 85, 4, pool_run, cr->pool, &jpeg, &jbytes, err,
                                 sizeof err)) {
            fprintf(stderr, "bench_render: city: jpeg: %s\n", err);
            goto out;
        }
        if (r == reps - 1 && o->png_dir) {
            /* the stream as the daemon sends it (spliced bands) */
            char path[512];
            snprintf(path, sizeof path, "%s/city-%s.jpg", o->png_dir, name);
            FILE *jf = fopen(path, "wb");
            if (!jf || fwrite(jpeg, 1, jbytes, jf) != jbytes) fprintf(stderr, "bench_render: %s: write failed\n", path);
            if (jf) fclose(jf);
        }
        free(jpeg);
        double t4 = bench_now_ns();
        row[P_GATHER] = gather_ms;
        row[P_SETUP] = st.setup_ns / 1e6;
        row[P_RASTER] = st.raster_ns / 1e6;
        row[P_BIN] = st.bin_ns / 1e6;
        row[P_SHADE] = st.shade_ns / 1e6;
        row[P_SHADOW] = st.shadow_ns / 1e6;
        row[P_SSAO] = st.ssao_ns / 1e6;
        row[P_POST] = st.post_ns / 1e6;
        row[P_ENCODE] = (t4 - t2) / 1e6;
        row[P_TOTAL] = (t4 - t0) / 1e6;
        if (r == reps - 1 && o->png_dir) {
            char path[512];
            snprintf(path, sizeof path, "%s/city-%s.png", o->png_dir, name);
            if (vt_png_write(path, W, H, rgb8, 4 * (size_t)W, false, 1, err, sizeof err))
                fprintf(stderr, "bench_render: %s\n", err);
        }
    }
    /* medians per pass (the frame's median is its own, not the sum of the passes') */
    double med[NP], *col = malloc((size_t)reps * sizeof *col);
    if (!col) goto out;
    for (int p = 0; p < NP; p++) {
        for (int r = 0; r < reps; r++) col[r] = t[(size_t)NP * (size_t)(r + 1) + (size_t)p];
        qsort(col, (size_t)reps, sizeof *col, cmp_d);
        med[p] = reps % 2 ? col[reps / 2] : 0.5 * (col[reps / 2 - 1] + col[reps / 2]);
    }
    free(col);
    if (o->json) {
        printf("{\"path\":\"soft\",\"renderer\":\"vantage soft\",\"scene\":\"city\",\"view\":\"%s\",\"width\":%u,"
               "\"height\":%u,\"threads\":2,\"instances\":%u,\"lights\":%u,\"triangles\":%u,\"shadow_triangles\":%u,"
               "\"jpeg_bytes\":%zu,\"reps\":%d",
               name, W, H, ninst, nl, tris, shadow_tris, jbytes, reps);
        for (int p = 0; p < NP; p++) printf(",\"%s_ms\":%.3f", pass_name[p], med[p]);
        printf(",\"median_ms\":%.3f}\n", med[P_TOTAL]);
    } else {
        printf("city %-7s soft 2 threads %ux%u: %u instances, %u lights, %u triangles: %.2f ms a frame (%.1f fps), "
               "median of %d\n  ",
               name, W, H, ninst, nl, tris, med[P_TOTAL], 1000 / med[P_TOTAL], reps);
        for (int p = 0; p < P_TOTAL; p++)
            if (med[p] > 0 || p <= P_SHADE || p >= P_ENCODE) printf("%s %.2f  ", pass_name[p], med[p]);
        printf("(ms; jpeg %zu bytes)\n", jbytes);
    }
    fflush(stdout);
    /* the GL path: the same frame (gather, draw, readback; no encode) */
    if (o->gl) {
        /* per rep: the whole, the gather, the shadow cascades, the CPU post passes */
        double *g = malloc(4 * (size_t)(reps + 1) * sizeof *g);
        if (!g) goto out;
        double *gg = g + (reps + 1), *gs = gg + (reps + 1), *gp = gs + (reps + 1);
        for (int r = 0; r <= reps; r++) {
            double t0 = bench_now_ns();
            city_frame cf;
            if (city_gather(cr, &v, &cf)) {
                city_frame_free(&cf);
                free(g);
                goto out;
            }
            vt_frame f = {.view = &v, .width = W, .height = H, .meshes = cf.meshes, .nmesh = cf.nmesh,
                          .inst = cf.inst, .ninst = cf.ninst, .lights = cf.lights, .nl = cf.nl,
                          .env = cf.fs.env_ok ? &cf.fs.env : NULL, .rgba = rgba, .depth = depth, .stride = W};
            double tg = bench_now_ns();
            vt_soft_stats gst = {0};
            int grc = vt_gldraw_draw(o->gl, &f, &gst, err, sizeof err);
            city_frame_free(&cf);
            gg[r] = (tg - t0) / 1e6, gs[r] = gst.shadow_ns / 1e6, gp[r] = gst.post_ns / 1e6;
            if (grc) {
                fprintf(stderr, "bench_render: city: gl: %s\n", err);
                free(g);
                goto out;
            }
            g[r] = (bench_now_ns() - t0) / 1e6;
        }
        double gm = bench_median(g + 1, reps); /* the first: shader compiles, texture uploads */
        double ggm = bench_median(gg + 1, reps), gsm = bench_median(gs + 1, reps), gpm = bench_median(gp + 1, reps);
        free(g);
        if (o->json)
            printf("{\"path\":\"gl\",\"renderer\":\"%s\",\"scene\":\"city\",\"view\":\"%s\",\"width\":%u,"
                   "\"height\":%u,\"threads\":%u,\"median_ms\":%.3f,\"soft_render_ms\":%.3f}\n",
                   o->gl_name, name, W, H, o->lp_threads, gm, med[P_TOTAL] - med[P_ENCODE]);
        else
            printf("city %-7s gl (%s, %u threads): %.2f ms (gather + draw + readback); soft's same part %.2f ms: "
                   "gl / soft %.2f\n  gather %.2f  shadow %.2f  post (CPU, one thread) %.2f  the rest (draws, "
                   "readbacks, conversions) %.2f\n",
                   name, o->gl_name, o->lp_threads, gm, med[P_TOTAL] - med[P_ENCODE],
                   gm / (med[P_TOTAL] - med[P_ENCODE]), ggm, gsm, gpm, gm - ggm - gsm - gpm);
        fflush(stdout);
    }
    rc = 0;
out:
    vt_soft_destroy(sr);
    free(t);
    free(rgb8);
    free(rgba);
    free(depth);
    return rc;
}

/* The city run: vantaged's scene with the city edit, the query's buffers. */
static void city_close(city_run *cr)
{
    if (!cr) return;
    cull_ctx_destroy(cr->ctx);
    free(cr->res);
    free(cr->mesh_of);
    if (cr->sc) scene_free(cr->sc);
    free(cr->sc);
    free(cr);
}

static city_run *city_open(cull_pool *pool, bool quiet)
{
    /* vantaged's defaults (daemon/vantaged.c: cell 64 m, its limits, 3000 props) */
    const scene_limits lim = {.max_entities = CULL_MAX_ENTITIES, .max_lights = 65536, .max_occluders = 1u << 20,
                              .max_occluder_tris = 1u << 20, .max_mesh_verts = 1u << 22, .max_materials = 1u << 20,
                              .max_texture_size = 8192, .max_texture_mem = 1ull << 30};
    city_run *cr = calloc(1, sizeof *cr);
    scene_err serr = {0};
    edit_result er;
    double t0 = bench_now_ns();
    if (!cr) return NULL;
    cr->pool = pool;
    if (!(cr->sc = calloc(1, sizeof *cr->sc)) || scene_init(cr->sc, 64, &lim)) {
        free(cr->sc);
        cr->sc = NULL;
        goto fail;
    }
    if (edit_apply(cr->sc, &(edit){.type = EDIT_CITY, .aux = 3000}, &er, &serr)) {
        fprintf(stderr, "bench_render: city: %s\n", serr.msg);
        goto fail;
    }
    edit_result_free(&er);
    if (!quiet)
        printf("demo city built in %.0f ms (%zu entities, %zu lights)\n", (bench_now_ns() - t0) / 1e6,
               cr->sc->ids.count, cr->sc->lights.count);
    cr->cap = cull_query_bound(cr->sc->world);
    cr->res = malloc(cr->cap * sizeof *cr->res);
    cr->mesh_of = calloc(65536, sizeof *cr->mesh_of);
    if (!cr->res || !cr->mesh_of || cull_ctx_create(pool, &cr->ctx)) goto fail;
    return cr;
fail:
    city_close(cr);
    return NULL;
}

int bench_city_open(cull_pool *pool, bool quiet, bench_city_scene **out)
{
    return (*out = city_open(pool, quiet)) ? 0 : -1;
}

void bench_city_close(bench_city_scene *c)
{
    city_close(c);
}

int bench_city_draw(bench_city_scene *c, struct vt_soft *sr, const double eye[3], const double at[3], uint32_t W,
                    uint32_t H, float *rgba, float *depth)
{
    cull_view v;
    vt_soft_stats st = {0};
    if (city_make_view(W, H, eye, at, &v)) return -1;
    return city_draw(c, sr, &v, W, H, rgba, depth, &st, NULL, NULL, NULL);
}

int bench_city(const bench_city_opts *o)
{
    city_run *cr = city_open(o->pool, o->json);
    if (!cr) return -1;
    cr->max_lights = o->max_lights;
    static const double street_eye[3] = {0, 20, -300}, street_at[3] = {0, 2, 0};
    static const double air_eye[3] = {150, 200, 150}, air_at[3] = {0, 0, 0};
    bool street = !o->view || !strcmp(o->view, "street"), aerial = !o->view || !strcmp(o->view, "aerial");
    int rc = (street && city_view(cr, o, "street", street_eye, street_at)) ||
                     (aerial && city_view(cr, o, "aerial", air_eye, air_at))
                 ? -1
                 : 0;
    city_close(cr);
    return rc;
}
