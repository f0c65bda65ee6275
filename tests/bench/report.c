/*
 * report.c — `make report`: run time against error for the culling
 * configurations, and a numerical stress table (issue 9). A benchmark and
 * an accuracy check: times never fail; a false invisible (an entity culled
 * that the reference sees, other than by a screen-area threshold) makes the
 * exit status 3, after everything is written.
 *
 *   report_cull [--scene F] [--out DIR] [--reps N] [--rounds N] [--frames N]
 *               [--seeds N] [--truth WxH] [--smoke]
 *
 * Writes DIR/report.md (tables, definitions, machine, command),
 * DIR/time_vs_error.csv and DIR/stress.csv (raw figures), and
 * DIR/time_vs_error.gp, a gnuplot script with the data inline that draws
 * time_vs_error.svg and .png next to itself (make report runs it).
 *
 * Configurations (query flags of culling.h), each at 1 and 2 threads:
 *   spheres only; spheres + AABB; + screen area >= 1, 2, 4 px (the default
 *   centre/extent bound); spheres + AABB + occlusion at 128x64, 256x114,
 *   512x256, 1280x720 (whole-pixel coverage, the default; drawn every
 *   query), and at 256x114 and 1280x720 through the kept buffer (a still
 *   camera: each frame asked three times, the first drawing, the second
 *   recording, the third timed; its verdicts must be the fresh buffer's).
 * Scenes: the shared city scene's walk (16 frames, 0.5 m apart) and three
 * seeded random towns (8 frames each), every entity an AABB, every
 * occluder a box. References, per frame and entity:
 *   exact frustum   tests/cull_ref.c (long double): sphere and AABB planes
 *   truly visible   in the exact frustum and seen at some pixel centre of
 *                   a 1920x1080 image by the ray caster tests/occ_ref.c
 *                   (double) before any occluder triangle
 * Timing as bench_cull: the camera moves every call (the walk's frames in
 * turn), caches warm (an untimed call first), the median over every timed
 * call; every scene and point take turns in rounds so that the machine's
 * noise falls on all of them alike.
 *
 * Stress: (1) probe entities around 8 cameras, half within a hair of a
 * frustum plane, against cull_ref, per case (far from the origin, tiny and
 * huge radii, near 1e-3 / far 1e7, reversed-Z, infinite far); (2) the city
 * with its occluders moved far from the origin and seen through extreme
 * projections, against cull_ref and the ray caster.
 */
#include "bench_scene.h"
#include "bench_util.h"
#include "cull_ref.h"
#include "culling.h"
#include "occ_ref.h"
#include "scene_file.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#define MAX_FRAMES 64
#define NTHR 2 /* thread counts 1..NTHR */

/* ---- configurations ---------------------------------------------------------- */
typedef struct config {
    const char *name;      /* the tables */
    const char *label;     /* the plot */
    uint32_t    flags;     /* CULL_Q_* */
    float       area;      /* screen-area threshold, pixels; 0 = none */
    uint32_t    occ_w, occ_h; /* occlusion buffer; 0 = no occlusion */
    bool        still;     /* a still camera: each frame's query asked again
                              through the buffer the context kept from the
                              first (timed: the third, after the second
                              recorded the blocks' verdicts) */
} config;

static const config g_cfg[] = {
    {"spheres only", "spheres", CULL_Q_NO_AABB | CULL_Q_NO_OCCLUSION, 0, 0, 0, false},
    {"spheres + AABB", "+AABB", CULL_Q_NO_OCCLUSION, 0, 0, 0, false},
    {"+ area >= 1 px", ">=1px", CULL_Q_NO_OCCLUSION, 1, 0, 0, false},
    {"+ area >= 2 px", ">=2px", CULL_Q_NO_OCCLUSION, 2, 0, 0, false},
    {"+ area >= 4 px", ">=4px", CULL_Q_NO_OCCLUSION, 4, 0, 0, false},
    {"+ occlusion 128x64", "occ 128x64", CULL_Q_OCC_FRESH, 0, 128, 64, false},
    {"+ occlusion 256x114", "occ 256x114", CULL_Q_OCC_FRESH, 0, 256, 114, false},
    {"+ occlusion 512x256", "occ 512x256", CULL_Q_OCC_FRESH, 0, 512, 256, false},
    {"+ occlusion 1280x720", "occ 1280x720", CULL_Q_OCC_FRESH, 0, 1280, 720, false},
    {"+ occlusion 256x114, kept buffer", "occ 256x114 kept", 0, 0, 256, 114, true},
    {"+ occlusion 1280x720, kept buffer", "occ 1280x720 kept", 0, 0, 1280, 720, true},
};
#define NCFG ((int)(sizeof g_cfg / sizeof g_cfg[0]))
#define NPT (NCFG * NTHR)
#define NFRUSTUM 5 /* the first five: no occlusion */

static cull_query_desc qdesc(const config *c, const cull_view *v, uint32_t threads, bool no_occ)
{
    cull_query_desc q = {.views = v, .view_count = 1, .flags = c->flags, .min_screen_area = c->area,
                         .threads = threads, .occ_w = c->occ_w, .occ_h = c->occ_h};
    if (no_occ) q.flags |= CULL_Q_NO_OCCLUSION;
    return q;
}

/* ---- options ------------------------------------------------------------------ */
typedef struct opts {
    const char *scene, *out;
    int         city_frames, rand_frames, seeds, reps, rounds;
    uint32_t    truth_w, truth_h;
    int         probe_n, probe_views, stress_frames;
    bool        smoke;
} opts;

/* ---- a scene under test: world, walk, references ----------------------------- */
typedef struct evscene {
    const scene_file *sf;
    double            offset[3];
    cull_world       *w;
    cull_handle      *h;
    int               frames;
    cull_view         walk[MAX_FRAMES];
    size_t            n;        /* objects */
    uint8_t          *keep_sph; /* frames x n: cull_ref sphere margin >= 0 */
    uint8_t          *keep_box; /* frames x n: and AABB margin >= 0 (exact frustum) */
    uint8_t          *truth;    /* frames x n: exact frustum and seen by the caster */
    double           *area;     /* frames x n: cull_ref projected AABB area, pixels */
} evscene;

static void ev_free(evscene *e)
{
    cull_world_destroy(e->w);
    free(e->h);
    free(e->keep_sph);
    free(e->keep_box);
    free(e->truth);
    free(e->area);
    memset(e, 0, sizeof *e);
}

static void view_desc_of(const cull_view *v, cull_view_desc *d)
{
    memset(d, 0, sizeof *d);
    memcpy(d->view_proj, v->clip, sizeof d->view_proj);
    memcpy(d->origin, v->origin, sizeof d->origin);
    d->depth_mode = v->depth_mode;
    d->viewport_w = v->viewport_w;
    d->viewport_h = v->viewport_h;
}

/* Builds the world (objects and occluder boxes, translated by cam->offset),
 * the walk and every frame's references. */
static int ev_build(evscene *e, const scene_file *sf, const bench_cam *cam, int frames, uint32_t tw, uint32_t th)
{
    memset(e, 0, sizeof *e);
    e->sf = sf;
    e->n = sf->nobjects;
    e->frames = frames;
    memcpy(e->offset, cam->offset, sizeof e->offset);
    size_t fn = (size_t)frames * e->n;
    e->h = malloc(e->n * sizeof *e->h);
    e->keep_sph = calloc(fn, 1);
    e->keep_box = calloc(fn, 1);
    e->truth = calloc(fn, 1);
    e->area = calloc(fn, sizeof *e->area);
    /* no offset: exactly what bench_occlusion builds */
    const double *off = e->offset[0] || e->offset[1] || e->offset[2] ? e->offset : NULL;
    double *tri = bench_tris_world(sf, off);
    int rc = -1;
    if (!e->h || !e->keep_sph || !e->keep_box || !e->truth || !e->area || !tri) goto out;
    if (cull_world_create(NULL, &e->w) || bench_add_objects(e->w, sf, off, e->h) || bench_add_boxes(e->w, sf, off) ||
        bench_walk(sf, cam, frames, e->walk))
        goto out;
    for (int f = 0; f < frames; f++) {
        cull_view_desc d;
        view_desc_of(&e->walk[f], &d);
        ref_view rv;
        ref_view_make(&rv, &d);
        size_t base = (size_t)f * e->n;
        for (size_t i = 0; i < e->n; i++) {
            cull_entity_desc ed;
            ref_verdict vd;
            if (cull_entity_get(e->w, e->h[i], &ed)) goto out;
            ref_test(&rv, &ed, &vd);
            e->keep_sph[base + i] = vd.sphere_margin >= 0;
            e->keep_box[base + i] = vd.sphere_margin >= 0 && vd.aabb_margin >= 0;
            e->area[base + i] = (double)vd.area;
        }
        if (bench_caster(&e->walk[f], tw, th, tri, sf->ntris, sf, off, e->keep_box + base, e->truth + base))
            goto out;
    }
    rc = 0;
out:
    free(tri);
    if (rc) ev_free(e);
    return rc;
}

/* ---- accuracy --------------------------------------------------------------------- */
/* One (configuration, thread count) over one scene. Counts are sums over
 * frames; times in ns. */
typedef struct point {
    double   t_med, t_min, t_q1, t_q3;
    uint64_t frames, queries;
    uint64_t kept;           /* reported visible */
    uint64_t truth;          /* truly visible */
    uint64_t fv;             /* kept, not truly visible */
    uint64_t fv_frustum;     /* kept, outside the exact frustum */
    uint64_t fi_frustum;     /* culled before occlusion though the stage's exact test keeps it
                                (and, with a threshold, its exact area is >= the threshold) */
    uint64_t fi_occ;         /* culled by occlusion though the caster sees it */
    uint64_t thr_culled;     /* culled by the threshold: exact test keeps, exact area below */
    uint64_t thr_culled_vis; /* of those, truly visible */
    uint64_t kept_diff;      /* still configurations: verdicts through the kept buffer that differ
                                from the freshly drawn buffer's (must be 0) */
    uint64_t kept_reused;    /* still configurations: frames whose second query kept the buffer */
    bool     pareto;
} point;

/* Runs q and marks mark[slot] = 1 for every result (mark zeroed first). */
static int run_mark(const cull_world *w, cull_ctx *ctx, const cull_query_desc *q, cull_result *out, size_t cap,
                    uint8_t *mark, size_t n)
{
    size_t cnt;
    if (cull_query(w, ctx, q, out, cap, &cnt, NULL)) return -1;
    memset(mark, 0, n);
    for (size_t k = 0; k < cnt; k++) {
        uint32_t slot = out[k].handle & (CULL_MAX_ENTITIES - 1);
        if (slot >= n) return -1;
        mark[slot] = 1;
    }
    return 0;
}

/* Frame f of e through configuration c: kept[] (and keptn[], the same
 * query without occlusion) filled, *p's counts added. */
static int accuracy(const evscene *e, cull_ctx *ctx, const config *c, uint32_t threads, int f, cull_result *out,
                    size_t cap, uint8_t *kept, uint8_t *keptn, point *p)
{
    cull_query_desc q = qdesc(c, &e->walk[f], threads, false);
    if (c->still) {
        /* drawn afresh into keptn, then asked again through the kept buffer into kept: the same verdicts */
        cull_query_desc qf = q;
        qf.flags |= CULL_Q_OCC_FRESH;
        if (run_mark(e->w, ctx, &qf, out, cap, keptn, e->n)) return -1;
        size_t cnt;
        cull_query_stats st;
        if (cull_query(e->w, ctx, &q, out, cap, &cnt, &st)) return -1;
        memset(kept, 0, e->n);
        for (size_t k = 0; k < cnt; k++) {
            uint32_t slot = out[k].handle & (CULL_MAX_ENTITIES - 1);
            if (slot >= e->n) return -1;
            kept[slot] = 1;
        }
        p->kept_reused += st.occ_reused > 0;
        for (size_t i = 0; i < e->n; i++) p->kept_diff += kept[i] != keptn[i];
    } else if (run_mark(e->w, ctx, &q, out, cap, kept, e->n)) {
        return -1;
    }
    if (c->occ_w) {
        q = qdesc(c, &e->walk[f], threads, true);
        if (run_mark(e->w, ctx, &q, out, cap, keptn, e->n)) return -1;
    } else {
        memcpy(keptn, kept, e->n);
    }
    size_t base = (size_t)f * e->n;
    const uint8_t *stage = (c->flags & CULL_Q_NO_AABB) ? e->keep_sph + base : e->keep_box + base;
    for (size_t i = 0; i < e->n; i++) {
        bool truth = e->truth[base + i], box = e->keep_box[base + i];
        bool below = c->area > 0 && !(e->area[base + i] >= c->area);
        p->kept += kept[i];
        p->truth += truth;
        p->fv += kept[i] && !truth;
        p->fv_frustum += kept[i] && !box;
        if (!keptn[i] && stage[i]) {
            if (below) {
                p->thr_culled++;
                p->thr_culled_vis += truth;
            } else {
                p->fi_frustum++;
            }
        }
        p->fi_occ += keptn[i] && !kept[i] && truth;
    }
    p->frames++;
    return 0;
}

/* ---- timing -------------------------------------------------------------------------- */
/* Every (scene, point)'s time per query over the scene's walk, all of them
 * interleaved so that a burst of load on the shared machine falls on every
 * scene and point alike: `rounds` rounds; in each, every scene, and in it
 * every point in turn (rotated every round): one untimed call, then
 * reps/rounds passes over the walk, each call timed. One context per
 * configuration serves every scene (its occlusion buffer keeps its size). */
static int time_all(evscene *const *sc, int nsc, cull_ctx *const *ctx, int reps, int rounds, point (*pts)[NPT])
{
    int passes = (reps + rounds - 1) / rounds, maxf = 0;
    size_t cap = 0;
    for (int k = 0; k < nsc; k++) {
        maxf = sc[k]->frames > maxf ? sc[k]->frames : maxf;
        size_t c = cull_query_bound(sc[k]->w);
        cap = c > cap ? c : cap;
    }
    size_t per = (size_t)rounds * passes * maxf;
    double *t = malloc(sizeof *t * per * NPT * (size_t)nsc);
    cull_result *out = malloc(cap * sizeof *out);
    int rc = -1;
    if (!t || !out) goto out;
    size_t cnt;
    /* warm up: clocks, page faults of the contexts' scratch and buffers */
    double t_end = bench_now_ns() + 3e8;
    for (int k = 0; bench_now_ns() < t_end || k < NPT * nsc; k++) {
        const evscene *e = sc[(k / NPT) % nsc];
        int p = k % NPT;
        cull_query_desc q = qdesc(&g_cfg[p / NTHR], &e->walk[k % e->frames], (uint32_t)(p % NTHR + 1), false);
        if (cull_query(e->w, ctx[p / NTHR], &q, out, cap, &cnt, NULL)) goto out;
    }
    for (int r = 0; r < rounds; r++)
        for (int si = 0; si < nsc; si++) {
            const evscene *e = sc[si];
            for (int k = 0; k < NPT; k++) {
                int p = (k + r) % NPT;
                double *tp = t + ((size_t)si * NPT + p) * per + (size_t)r * passes * e->frames;
                cull_query_desc q = qdesc(&g_cfg[p / NTHR], &e->walk[0], (uint32_t)(p % NTHR + 1), false);
                if (cull_query(e->w, ctx[p / NTHR], &q, out, cap, &cnt, NULL)) goto out;
                bool still = g_cfg[p / NTHR].still;
                for (int pass = 0; pass < passes; pass++)
                    for (int f = 0; f < e->frames; f++) {
                        q.views = &e->walk[f];
                        /* a still camera: the frame's first query draws and its second
                           records the blocks' verdicts (untimed); the timed one, what every
                           later frame of a still view pays, reads them */
                        if (still && (cull_query(e->w, ctx[p / NTHR], &q, out, cap, &cnt, NULL) ||
                                      cull_query(e->w, ctx[p / NTHR], &q, out, cap, &cnt, NULL)))
                            goto out;
                        double t0 = bench_now_ns();
                        if (cull_query(e->w, ctx[p / NTHR], &q, out, cap, &cnt, NULL)) goto out;
                        *tp++ = bench_now_ns() - t0;
                    }
            }
        }
    for (int si = 0; si < nsc; si++)
        for (int p = 0; p < NPT; p++) {
            int n = rounds * passes * sc[si]->frames;
            double *v = t + ((size_t)si * NPT + p) * per;
            point *q = &pts[si][p];
            q->t_med = bench_median(v, n); /* sorts v */
            q->t_min = v[0];
            q->t_q1 = v[n / 4];
            q->t_q3 = v[(3 * n) / 4];
            q->queries = (uint64_t)n;
        }
    rc = 0;
out:
    free(t);
    free(out);
    return rc;
}

/* Accuracy of every point over every frame of e. */
static int eval_accuracy(const evscene *e, cull_ctx *const *ctx, point *pts)
{
    size_t cap = cull_query_bound(e->w);
    cull_result *out = malloc(cap * sizeof *out);
    uint8_t *kept = malloc(e->n), *keptn = malloc(e->n);
    int rc = -1;
    if (!out || !kept || !keptn) goto out;
    memset(pts, 0, sizeof *pts * NPT);
    for (int p = 0; p < NPT; p++)
        for (int f = 0; f < e->frames; f++)
            if (accuracy(e, ctx[p / NTHR], &g_cfg[p / NTHR], (uint32_t)(p % NTHR + 1), f, out, cap, kept, keptn,
                         &pts[p]))
                goto out;
    rc = 0;
out:
    free(out);
    free(kept);
    free(keptn);
    return rc;
}

/* ---- Pareto front over (time, false-visible rate) ------------------------------------ */
static double fv_rate(const point *p)
{
    return p->kept ? (double)p->fv / (double)p->kept : 0;
}

static void mark_pareto(point *pts, int n)
{
    for (int i = 0; i < n; i++) {
        double ti = pts[i].t_med, ei = fv_rate(&pts[i]);
        pts[i].pareto = true;
        for (int j = 0; j < n && pts[i].pareto; j++) {
            double tj = pts[j].t_med, ej = fv_rate(&pts[j]);
            if (j != i && tj <= ti && ej <= ei && (tj < ti || ej < ei)) pts[i].pareto = false;
        }
    }
}

/* ---- random towns: bench_town_make (bench_scene.h) ---------------------------------------- */
#define NTOWNS BENCH_NTOWNS

static double rnd(uint64_t *s, double lo, double hi)
{
    return lo + (hi - lo) * bench_rand01(s);
}

static double rnd_log(uint64_t *s, double lo, double hi)
{
    return lo * pow(hi / lo, bench_rand01(s));
}

/* ---- stress 1: probe entities against cull_ref ------------------------------------------- */
typedef struct probe_case {
    const char *name;
    double      offset;     /* scene and cameras translated by (d, d, d) */
    double      rmin, rmax; /* radii, log-uniform */
    double      znear, zfar;
    uint32_t    depth_mode;
} probe_case;

static const probe_case g_probe[] = {
    {"origin (baseline): radii 0.01..100 m, near 0.1, far 2000, GL", 0, 1e-2, 1e2, 0.1, 2000, CULL_DEPTH_GL},
    {"1e4 m from the origin", 1e4, 1e-2, 1e2, 0.1, 2000, CULL_DEPTH_GL},
    {"1e5 m from the origin", 1e5, 1e-2, 1e2, 0.1, 2000, CULL_DEPTH_GL},
    {"1e6 m from the origin", 1e6, 1e-2, 1e2, 0.1, 2000, CULL_DEPTH_GL},
    {"1e7 m from the origin", 1e7, 1e-2, 1e2, 0.1, 2000, CULL_DEPTH_GL},
    {"tiny radii: 1e-4 m", 0, 1e-4, 1e-4, 0.1, 2000, CULL_DEPTH_GL},
    {"huge radii: 1e5 m", 0, 1e5, 1e5, 0.1, 2000, CULL_DEPTH_GL},
    {"near 1e-3, far 1e7, GL", 0, 1e-2, 1e2, 1e-3, 1e7, CULL_DEPTH_GL},
    {"near 1e-3, far 1e7, [0,1] depth", 0, 1e-2, 1e2, 1e-3, 1e7, CULL_DEPTH_ZERO_ONE},
    {"reversed-Z, near 0.1, far 2000", 0, 1e-2, 1e2, 0.1, 2000, CULL_DEPTH_REVERSED},
    {"reversed-Z, near 1e-3, far 1e7", 0, 1e-2, 1e2, 1e-3, 1e7, CULL_DEPTH_REVERSED},
    {"reversed-Z, near 1e-3, infinite far", 0, 1e-2, 1e2, 1e-3, INFINITY, CULL_DEPTH_REVERSED},
    {"all at once: 1e7 m, radii 1e-4..1e5, reversed-Z, near 1e-3, infinite far", 1e7, 1e-4, 1e5, 1e-3, INFINITY,
     CULL_DEPTH_REVERSED},
};
#define NPROBE ((int)(sizeof g_probe / sizeof g_probe[0]))
#define PROBE_CELL 64.0

typedef struct ptally {
    uint64_t cases;        /* entity x view */
    uint64_t wrong;        /* culled while the model keeps it (margin >= 0, area >= threshold) */
    uint64_t cons_eps;     /* kept while the model culls, within 8 eps of the planes */
    uint64_t cons_beyond;  /* kept while the model culls, beyond 8 eps */
    uint64_t cons_area;    /* kept below the threshold by the bound (the model's area is below) */
    uint64_t thread_diff;  /* entities whose verdict differs between 1 and 2 threads */
} ptally;

static double reach_of(const cull_entity_desc *e)
{
    double m = 0;
    for (int a = 0; a < 3; a++) {
        double o = floor(e->center[a] / PROBE_CELL) * PROBE_CELL;
        m = fmax(m, fmax(fabs(e->aabb_min[a] - o), fabs(e->aabb_max[a] - o)));
    }
    return m;
}

/* One case: views views, n probe entities; tallies per frustum config (1 thread; 2 threads compared). */
static int probe_run(const probe_case *pc, int nviews, int n, cull_pool *pool, ptally t[NFRUSTUM])
{
    uint64_t s = 0x57E55u; /* the same set in every case (translated, or with other radii) */
    double off[3] = {pc->offset, pc->offset, pc->offset};
    cull_view_desc vd[16];
    cull_view v[16];
    ref_view rv;
    if (nviews > 16) nviews = 16;
    for (int k = 0; k < nviews; k++) {
        memset(&vd[k], 0, sizeof vd[k]);
        vd[k].depth_mode = pc->depth_mode;
        vd[k].viewport_w = 1920;
        vd[k].viewport_h = 1080;
        double eye[3] = {rnd(&s, -500, 500), rnd(&s, 1, 50), rnd(&s, -500, 500)};
        double yaw = rnd(&s, 0, 2 * M_PI), pitch = rnd(&s, -0.3, 0.3);
        double dir[3] = {sin(yaw) * cos(pitch), sin(pitch), -cos(yaw) * cos(pitch)}, up[3] = {0, 1, 0};
        double proj[16], view[16];
        cull_mat_perspective(proj, 60 * M_PI / 180, 16.0 / 9.0, pc->znear, pc->zfar, pc->depth_mode);
        cull_mat_look_dir(view, dir, up);
        cull_mat_mul(vd[k].view_proj, proj, view);
        for (int a = 0; a < 3; a++) vd[k].origin[a] = eye[a] + off[a];
        if (cull_view_init(&v[k], &vd[k])) return -1;
    }
    cull_world *w;
    if (cull_world_create(&(cull_world_desc){.cell_size = PROBE_CELL}, &w)) return -1;
    cull_handle *h = malloc((size_t)n * sizeof *h);
    cull_entity_desc *ed = malloc((size_t)n * sizeof *ed);
    ref_verdict *m = malloc((size_t)n * sizeof *m);
    size_t cap = (size_t)n + CULL_RESULT_PAD;
    cull_result *out = malloc(cap * sizeof *out);
    uint8_t *mark[NFRUSTUM][NTHR];
    for (int c = 0; c < NFRUSTUM; c++)
        for (int th = 0; th < NTHR; th++) mark[c][th] = malloc((size_t)n);
    cull_ctx *ctx = NULL;
    int rc = -1;
    if (!h || !ed || !m || !out || cull_ctx_create(pool, &ctx)) goto out;
    for (int c = 0; c < NFRUSTUM; c++)
        for (int th = 0; th < NTHR; th++)
            if (!mark[c][th]) goto out;
    double dmax = fmin(isinf(pc->zfar) ? 1e7 : pc->zfar, 1e7) * 1.5, dmin = pc->znear * 0.5;
    for (int i = 0; i < n; i++) {
        /* relative to a view's eye, then translated: the same set in every far case */
        const cull_view *vv = &v[(int)(bench_rand01(&s) * nviews)];
        double rad = pc->rmin == pc->rmax ? pc->rmin : rnd_log(&s, pc->rmin, pc->rmax);
        double dist = rnd_log(&s, dmin, dmax), c[3];
        for (int a = 0; a < 3; a++) c[a] = rnd(&s, -1, 1) * dist;
        if (bench_rand01(&s) < 0.5) {
            /* onto a plane, then a hair in or out of touching it */
            const double *pl = vv->plane[(int)(bench_rand01(&s) * vv->plane_count)];
            double sd = pl[0] * c[0] + pl[1] * c[1] + pl[2] * c[2] + pl[3];
            double hair = (bench_rand01(&s) < 0.5 ? 1 : -1) * fmax(rad, 1) * pow(10, -rnd(&s, 0, 9));
            for (int a = 0; a < 3; a++) c[a] -= (sd + rad - hair) * pl[a];
        }
        cull_entity_desc e = {0};
        double kind = bench_rand01(&s);
        for (int a = 0; a < 3; a++) c[a] += vv->origin[a];
        if (kind < 1.0 / 3) { /* a sphere; AABB derived */
            memcpy(e.center, c, sizeof c);
            e.radius = rad;
        } else if (kind < 2.0 / 3) { /* an AABB; sphere derived */
            for (int a = 0; a < 3; a++) {
                double hx = rad * rnd(&s, 0.05, 1);
                e.aabb_min[a] = c[a] - hx;
                e.aabb_max[a] = c[a] + hx;
            }
        } else { /* both: a box inside the sphere's bounding box */
            memcpy(e.center, c, sizeof c);
            e.radius = rad;
            for (int a = 0; a < 3; a++) {
                e.aabb_min[a] = c[a] - rad * bench_rand01(&s);
                e.aabb_max[a] = c[a] + rad * bench_rand01(&s);
            }
        }
        if (cull_entity_add(w, &e, &h[i]) || cull_entity_get(w, h[i], &ed[i])) goto out;
        if ((h[i] & (CULL_MAX_ENTITIES - 1)) != (uint32_t)i) goto out;
    }
    for (int k = 0; k < nviews; k++) {
        ref_view_make(&rv, &vd[k]);
        for (int i = 0; i < n; i++) ref_test(&rv, &ed[i], &m[i]);
        for (int c = 0; c < NFRUSTUM; c++) {
            const config *cf = &g_cfg[c];
            bool aabb = !(cf->flags & CULL_Q_NO_AABB);
            for (int th = 0; th < NTHR; th++) {
                cull_query_desc q = qdesc(cf, &v[k], (uint32_t)(th + 1), true);
                if (run_mark(w, ctx, &q, out, cap, mark[c][th], (size_t)n)) goto out;
            }
            for (int i = 0; i < n; i++) {
                const ref_verdict *r = &m[i];
                long double margin = aabb ? fminl(r->sphere_margin, r->aabb_margin) : r->sphere_margin;
                bool fk = margin >= 0, ak = cf->area <= 0 || r->area >= cf->area;
                double eps = 0x1p-20 * (4 * PROBE_CELL + ed[i].radius + reach_of(&ed[i]));
                t[c].cases++;
                for (int th = 1; th < NTHR; th++) t[c].thread_diff += mark[c][th][i] != mark[c][0][i];
                if (!mark[c][0][i]) {
                    t[c].wrong += fk && ak;
                } else if (!fk) {
                    if (margin >= -8 * eps) t[c].cons_eps++;
                    else t[c].cons_beyond++;
                } else if (!ak) {
                    t[c].cons_area++;
                }
            }
        }
    }
    rc = 0;
out:
    cull_ctx_destroy(ctx);
    cull_world_destroy(w);
    for (int c = 0; c < NFRUSTUM; c++)
        for (int th = 0; th < NTHR; th++) free(mark[c][th]);
    free(h);
    free(ed);
    free(m);
    free(out);
    return rc;
}

/* ---- stress 2: the city, far away and through extreme projections ----------------------- */
typedef struct city_case {
    const char *name;
    double      offset; /* (d, d, d) */
    double      znear, zfar; /* 0 = the scene's */
    uint32_t    depth_mode;
} city_case;

static const city_case g_city_stress[] = {
    {"origin, GL, near 0.1, far 2000 (the scene's)", 0, 0, 0, CULL_DEPTH_GL},
    {"1e4 m from the origin", 1e4, 0, 0, CULL_DEPTH_GL},
    {"1e5 m from the origin", 1e5, 0, 0, CULL_DEPTH_GL},
    {"1e6 m from the origin", 1e6, 0, 0, CULL_DEPTH_GL},
    {"1e7 m from the origin", 1e7, 0, 0, CULL_DEPTH_GL},
    {"reversed-Z, near 0.1, far 2000", 0, 0, 0, CULL_DEPTH_REVERSED},
    {"near 1e-3, far 1e7, GL", 0, 1e-3, 1e7, CULL_DEPTH_GL},
    {"reversed-Z, near 1e-3, infinite far", 0, 1e-3, INFINITY, CULL_DEPTH_REVERSED},
    {"1e7 m, reversed-Z, near 1e-3, infinite far", 1e7, 1e-3, INFINITY, CULL_DEPTH_REVERSED},
};
#define NCITY ((int)(sizeof g_city_stress / sizeof g_city_stress[0]))

typedef struct ctally {
    point    p[NCFG];       /* 1 thread */
    uint64_t thread_diff;   /* entity verdicts that differ at 2 threads, all configs */
    int64_t  origin_diff;   /* entity verdicts that differ from the origin case, all configs; -1: n/a */
    double   truth;         /* truly visible per frame */
} ctally;

static int city_stress(const scene_file *sf, const opts *o, cull_pool *pool, ctally *ct)
{
    int frames = o->stress_frames;
    size_t n = sf->nobjects;
    uint8_t *origin_kept = malloc((size_t)NCFG * frames * n);
    uint8_t *k1 = malloc(n), *k2 = malloc(n), *kn = malloc(n);
    if (!origin_kept || !k1 || !k2 || !kn) return -1;
    int rc = -1;
    for (int cs = 0; cs < NCITY; cs++) {
        const city_case *cc = &g_city_stress[cs];
        bench_cam cam = {.offset = {cc->offset, cc->offset, cc->offset}, .znear = cc->znear, .zfar = cc->zfar,
                         .depth_mode = cc->depth_mode, .step = 4};
        evscene e;
        double t0 = bench_now_ns();
        if (ev_build(&e, sf, &cam, frames, o->truth_w, o->truth_h)) goto out;
        size_t cap = cull_query_bound(e.w);
        cull_result *res = malloc(cap * sizeof *res);
        cull_ctx *ctx = NULL;
        memset(&ct[cs], 0, sizeof ct[cs]);
        /* the same frustum as the first row: translations, and reversed-Z with the same near and far */
        bool comparable = cc->znear == 0 && cc->zfar == 0;
        ct[cs].origin_diff = cs > 0 && comparable ? 0 : -1;
        int bad = !res || cull_ctx_create(pool, &ctx);
        for (int c = 0; c < NCFG && !bad; c++)
            for (int f = 0; f < frames && !bad; f++) {
                point p2 = {0};
                bad = accuracy(&e, ctx, &g_cfg[c], 1, f, res, cap, k1, kn, &ct[cs].p[c]) ||
                      accuracy(&e, ctx, &g_cfg[c], 2, f, res, cap, k2, kn, &p2);
                for (size_t i = 0; i < n && !bad; i++) ct[cs].thread_diff += k1[i] != k2[i];
                uint8_t *ok = origin_kept + ((size_t)c * frames + f) * n;
                if (cs == 0) memcpy(ok, k1, n);
                else if (ct[cs].origin_diff >= 0)
                    for (size_t i = 0; i < n; i++) ct[cs].origin_diff += ok[i] != k1[i];
            }
        ct[cs].truth = (double)ct[cs].p[0].truth / frames;
        cull_ctx_destroy(ctx);
        free(res);
        ev_free(&e);
        if (bad) goto out;
        fprintf(stderr, "report_cull: stress, city %s: %.1f s\n", cc->name, (bench_now_ns() - t0) / 1e9);
    }
    rc = 0;
out:
    free(origin_kept);
    free(k1);
    free(k2);
    free(kn);
    return rc;
}

/* ---- output ------------------------------------------------------------------------------ */
static FILE *open_out(const char *dir, const char *name)
{
    char path[4096];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    FILE *f = fopen(path, "w");
    if (!f) fprintf(stderr, "report_cull: %s: %s\n", path, strerror(errno));
    return f;
}

static void machine_line(char *buf, size_t n)
{
    char model[256] = "unknown cpu", line[512];
    FILE *f = fopen("/proc/cpuinfo", "r");
    while (f && fgets(line, sizeof line, f)) {
        if (strncmp(line, "model name", 10)) continue;
        char *p = strchr(line, ':');
        if (!p) break;
        p++;
        while (*p == ' ' || *p == '\t') p++;
        p[strcspn(p, "\n")] = 0;
        snprintf(model, sizeof model, "%s", p);
        break;
    }
    if (f) fclose(f);
    char date[32];
    time_t now = time(NULL);
    strftime(date, sizeof date, "%Y-%m-%d", gmtime(&now));
    snprintf(buf, n, "machine: %ld cpus, %s; %s", sysconf(_SC_NPROCESSORS_ONLN), model, date);
}

/* The 1-minute load average (-1 if unknown): how busy the shared machine was. */
static double load_avg(void)
{
    double l = -1;
    FILE *f = fopen("/proc/loadavg", "r");
    if (f) {
        if (fscanf(f, "%lf", &l) != 1) l = -1;
        fclose(f);
    }
    return l;
}

static double per_frame(uint64_t v, const point *p)
{
    return p->frames ? (double)v / (double)p->frames : 0;
}

static void csv_point(FILE *f, const char *panel, const char *scene, int pi, const point *p)
{
    const config *c = &g_cfg[pi / NTHR];
    fprintf(f,
            "%s,%s,%s,%s,%d,%g,%u,%u,%llu,%llu,%.3f,%.3f,%.3f,%.3f,%.2f,%.2f,%.2f,%.5f,%.2f,%llu,%llu,%.2f,%.2f,%d\n",
            panel, scene, c->name, c->label, pi % NTHR + 1, (double)c->area, c->occ_w, c->occ_h,
            (unsigned long long)p->frames, (unsigned long long)p->queries, p->t_med / 1e3, p->t_min / 1e3, p->t_q1 / 1e3,
            p->t_q3 / 1e3, per_frame(p->kept, p), per_frame(p->truth, p), per_frame(p->fv, p), fv_rate(p),
            per_frame(p->fv_frustum, p), (unsigned long long)p->fi_frustum, (unsigned long long)p->fi_occ,
            per_frame(p->thr_culled, p), per_frame(p->thr_culled_vis, p), p->pareto);
}

static void md_points(FILE *f, const point *pts)
{
    fprintf(f, "| configuration | threads | µs per query, median [q1-q3] | min µs | visible | truly visible | false "
               "visible | false-visible rate | outside the exact frustum | false invisible | culled by "
               "threshold (truly visible) | Pareto |\n");
    fprintf(f, "|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for (int p = 0; p < NPT; p++) {
        const point *q = &pts[p];
        const config *c = &g_cfg[p / NTHR];
        char thr[64] = "-";
        if (c->area > 0)
            snprintf(thr, sizeof thr, "%.1f (%.1f)", per_frame(q->thr_culled, q), per_frame(q->thr_culled_vis, q));
        fprintf(f, "| %s | %d | %s%.1f%s [%.1f-%.1f] | %.1f | %.1f | %.1f | %.1f | %.1f %% | %.1f | %llu | %s | %s |\n",
                c->name, p % NTHR + 1, q->pareto ? "**" : "", q->t_med / 1e3, q->pareto ? "**" : "", q->t_q1 / 1e3,
                q->t_q3 / 1e3, q->t_min / 1e3, per_frame(q->kept, q), per_frame(q->truth, q), per_frame(q->fv, q), 100 * fv_rate(q),
                per_frame(q->fv_frustum, q), (unsigned long long)(q->fi_frustum + q->fi_occ), thr,
                q->pareto ? "**yes**" : "");
    }
}

/* ---- the plot ------------------------------------------------------------------------ */
/* Geometry of one panel of the figure, for placing labels: the plot area is
 * about 600 x 480 pixels of the 1500 x 650 figure, labels are 10-point text
 * (about 7 x 14 pixels a character). */
#define GP_W_PX 600.0
#define GP_H_PX 480.0
#define GP_YMAX 105.0
#define GP_CHAR_PX 8.0
#define GP_LINE_PX 14.0

typedef struct gp_label {
    double x, y;   /* the point: µs, % */
    double lx, ly; /* the label's left end */
    const char *text;
} gp_label;

/* One label per configuration, at its 1-thread point when the spot is free,
 * else moved up or down to the nearest free spot (and tied to its point by
 * a line): the frustum configurations sit within a few percent of each
 * other and would print on top of one another. */
static void gp_place(const point *pts, double lo, double hi, gp_label *lab)
{
    double dpp = log10(hi / lo) / GP_W_PX, ypp = GP_YMAX / GP_H_PX;
    int order[NCFG];
    for (int c = 0; c < NCFG; c++) {
        const point *p = &pts[c * NTHR];
        lab[c] = (gp_label){p->t_med / 1e3, 100 * fv_rate(p), 0, 0, g_cfg[c].label};
        order[c] = c;
    }
    for (int i = 1; i < NCFG; i++)
        for (int j = i; j > 0 && lab[order[j]].x < lab[order[j - 1]].x; j--) {
            int t = order[j];
            order[j] = order[j - 1];
            order[j - 1] = t;
        }
    /* boxes in (log10 µs, %) of labels placed so far and of every marker */
    double box[NCFG + NPT][4];
    int nb = 0;
    for (int p = 0; p < NPT; p++) {
        double x = log10(pts[p].t_med / 1e3), y = 100 * fv_rate(&pts[p]);
        double b[4] = {x - 6 * dpp, x + 6 * dpp, y - 6 * ypp, y + 6 * ypp};
        memcpy(box[nb++], b, sizeof b);
    }
    static const double tries[] = {0.5, -0.5, 1.5, -1.5, 2.5, -2.5, 3.5, -3.5, 4.5, -4.5, 5.5, -5.5, 6.5, -6.5};
    for (int k = 0; k < NCFG; k++) {
        gp_label *l = &lab[order[k]];
        double x0 = log10(l->x) + 9 * dpp, x1 = x0 + ((double)strlen(l->text) + 1) * GP_CHAR_PX * dpp;
        double h = GP_LINE_PX * ypp;
        double ly = l->y + h; /* fallback */
        for (size_t t = 0; t < sizeof tries / sizeof tries[0]; t++) {
            double y = l->y + tries[t] * 1.1 * h;
            if (y - h / 2 < 1 || y + h / 2 > GP_YMAX - 1) continue;
            bool free_spot = true;
            for (int b = 0; b < nb && free_spot; b++)
                free_spot = x1 < box[b][0] || x0 > box[b][1] || y + h / 2 < box[b][2] || y - h / 2 > box[b][3];
            if (free_spot) {
                ly = y;
                break;
            }
        }
        l->lx = pow(10, x0);
        l->ly = ly;
        double b[4] = {x0, x1, ly - h / 2, ly + h / 2};
        memcpy(box[nb++], b, sizeof b);
    }
}

/* One panel's data: points, labels, the front as a staircase. */
static void gp_block(FILE *f, const char *name, const point *pts, double lo, double hi)
{
    fprintf(f, "$%s << EOD\n# time_us rate_pct threads label\n", name);
    for (int p = 0; p < NPT; p++)
        fprintf(f, "%.3f %.3f %d \"%s\"\n", pts[p].t_med / 1e3, 100 * fv_rate(&pts[p]), p % NTHR + 1,
                g_cfg[p / NTHR].label);
    gp_label lab[NCFG];
    gp_place(pts, lo, hi, lab);
    fprintf(f, "EOD\n$%s_labels << EOD\n# label_x label_y text point_x point_y moved\n", name);
    for (int c = 0; c < NCFG; c++)
        fprintf(f, "%.4f %.3f \"%s\" %.3f %.3f %d\n", lab[c].lx, lab[c].ly, lab[c].text, lab[c].x, lab[c].y,
                fabs(lab[c].ly - lab[c].y) > 0.9 * GP_LINE_PX * GP_YMAX / GP_H_PX);
    fprintf(f, "EOD\n$%s_front << EOD\n", name);
    /* the front by time, then out to the right edge at its last rate */
    int idx[NPT], k = 0;
    for (int p = 0; p < NPT; p++)
        if (pts[p].pareto) idx[k++] = p;
    for (int i = 1; i < k; i++)
        for (int j = i; j > 0 && pts[idx[j]].t_med < pts[idx[j - 1]].t_med; j--) {
            int tmp = idx[j];
            idx[j] = idx[j - 1];
            idx[j - 1] = tmp;
        }
    for (int i = 0; i < k; i++) fprintf(f, "%.3f %.3f\n", pts[idx[i]].t_med / 1e3, 100 * fv_rate(&pts[idx[i]]));
    if (k) fprintf(f, "%g %.3f\n", hi * 10, 100 * fv_rate(&pts[idx[k - 1]]));
    fprintf(f, "EOD\n");
}

/* The Pareto front in one line, by time. */
static void md_front(FILE *f, const point *pts)
{
    bool done[NPT] = {0};
    fprintf(f, "Pareto front, fastest first:");
    for (int n = 0;; n++) {
        int best = -1;
        for (int p = 0; p < NPT; p++)
            if (pts[p].pareto && !done[p] && (best < 0 || pts[p].t_med < pts[best].t_med)) best = p;
        if (best < 0) break;
        done[best] = true;
        fprintf(f, "%s %s, %d thread%s (%.1f µs, %.1f %%)", n ? ";" : "", g_cfg[best / NTHR].name, best % NTHR + 1,
                best % NTHR ? "s" : "", pts[best].t_med / 1e3, 100 * fv_rate(&pts[best]));
    }
    fprintf(f, ".\n\n");
}

/* A table's header: "| case | <second> |", a column per configuration
 * g_cfg[0..ncfg), then `tail` (its own "| ... |" cells, ntail of them),
 * and the rule line under it. */
static void md_cfg_header(FILE *md, const char *second, int ncfg, const char *tail, int ntail)
{
    fprintf(md, "| case | %s |", second);
    for (int c = 0; c < ncfg; c++) fprintf(md, " %s |", g_cfg[c].name);
    fprintf(md, "%s\n|---|---|", tail ? tail : "");
    for (int c = 0; c < ncfg + ntail; c++) fprintf(md, "---|");
    fprintf(md, "\n");
}

/* The gnuplot script: both panels' data inline, run from its own folder. */
static void write_gp(FILE *f, const point *city, const point *rnd_pts, int ntowns, const char *machine)
{
    double lo = 1e30, hi = 0;
    for (int p = 0; p < NPT; p++) {
        lo = fmin(lo, fmin(city[p].t_med, rnd_pts[p].t_med));
        hi = fmax(hi, fmax(city[p].t_med, rnd_pts[p].t_med));
    }
    /* a margin left of the fastest point, room right of the slowest for its label */
    lo = lo / 1e3 * 0.7;
    hi = hi / 1e3 * 3.5;
    fprintf(f, "# time_vs_error.gp — written by report_cull; run from its own folder:\n"
               "#   cd docs/report && gnuplot time_vs_error.gp\n"
               "# draws time_vs_error.svg and time_vs_error.png (the same figure).\n");
    gp_block(f, "city", city, lo, hi);
    gp_block(f, "rnd", rnd_pts, lo, hi);
    fprintf(f,
            "set encoding utf8\n"
            "set logscale x\n"
            "set xrange [%g:%g]\n"
            "set yrange [0:%g]\n"
            "set grid xtics mxtics ytics lc rgb '#dddddd'\n"
            "set xlabel 'time per query, µs (median; log scale)'\n"
            "set ylabel 'false-visible rate, %% of reported entities'\n"
            "set key top right box opaque\n",
            lo, hi, GP_YMAX);
    char title[2][128];
    snprintf(title[0], sizeof title[0], "city scene walk");
    snprintf(title[1], sizeof title[1], "random towns (%d)", ntowns);
    const char *data[2] = {"city", "rnd"};
    fprintf(f, "do for [term = 1:2] {\n"
               "  if (term == 1) { set terminal svg size 1500,650 dynamic font 'DejaVu Sans,12' background "
               "'#ffffff'; set output 'time_vs_error.svg'; psz = 1.0 }\n"
               "  if (term == 2) { set terminal pngcairo size 1500,650 font 'DejaVu Sans,10' background "
               "'#ffffff'; set output 'time_vs_error.png'; psz = 1.3 }\n"
               "  set multiplot layout 1,2 title \"Culling: time per query against false-visible rate "
               "(truth: exact frustum + 1920x1080 ray caster)\\n{/*0.8 %s}\"\n",
            machine);
    for (int k = 0; k < 2; k++) {
        const char *d = data[k];
        fprintf(f,
                "  set title '%s'\n"
                "  plot $%s_front using 1:2 with steps lw 2 lc rgb '#2ca02c' title 'Pareto front', \\\n"
                "       $%s_labels using 1:2:($4 - $1):($6 > 0 ? $5 - $2 : 1/0) with vectors nohead lc rgb '#aaaaaa' "
                "notitle, \\\n"
                "       $%s using 1:($3 == 1 ? $2 : 1/0) with points pt 7 ps psz lc rgb '#1f77b4' title '1 thread', "
                "\\\n"
                "       $%s using 1:($3 == 2 ? $2 : 1/0) with points pt 9 ps psz * 1.15 lc rgb '#d62728' title '2 threads', "
                "\\\n"
                "       $%s_labels using 1:2:3 with labels left font ',10' notitle\n",
                title[k], d, d, d, d, d);
    }
    fprintf(f, "  unset multiplot\n  set output\n}\n");
}

int main(int argc, char **argv)
{
    opts o = {.scene = "tests/data/scenes/city_scene.txt", .out = "docs/report", .city_frames = 16,
              .rand_frames = 8, .seeds = NTOWNS, .reps = 300, .rounds = 5, .truth_w = 1920, .truth_h = 1080,
              .probe_n = 40000, .probe_views = 8, .stress_frames = 3};
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--scene") && i + 1 < argc) o.scene = argv[++i];
        else if (!strcmp(argv[i], "--out") && i + 1 < argc) o.out = argv[++i];
        else if (!strcmp(argv[i], "--reps") && i + 1 < argc) o.reps = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--frames") && i + 1 < argc) o.city_frames = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--seeds") && i + 1 < argc) o.seeds = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--rounds") && i + 1 < argc) o.rounds = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--truth") && i + 1 < argc) {
            if (sscanf(argv[++i], "%ux%u", &o.truth_w, &o.truth_h) != 2) o.truth_w = 0;
        } else if (!strcmp(argv[i], "--smoke")) {
            o.smoke = true;
            o.city_frames = 2;
            o.rand_frames = 2;
            o.seeds = 1;
            o.reps = 2;
            o.rounds = 1;
            o.truth_w = 960;
            o.truth_h = 540;
            o.probe_n = 2000;
            o.probe_views = 2;
            o.stress_frames = 1;
        } else {
            fprintf(stderr, "usage: report_cull [--scene F] [--out DIR] [--reps N] [--rounds N] [--frames N] "
                            "[--seeds N] [--truth WxH] [--smoke]\n");
            return 2;
        }
    }
    if (o.city_frames < 1 || o.city_frames > MAX_FRAMES || o.reps < 1 || o.rounds < 1 || o.seeds < 0 || o.seeds > NTOWNS ||
        o.truth_w < 8 || o.truth_h < 8)
        return 2;
    if (o.rounds > o.reps) o.rounds = o.reps;
    double t_start = bench_now_ns(), load0 = load_avg();
    if (mkdir(o.out, 0777) && errno != EEXIST) {
        fprintf(stderr, "report_cull: %s: %s\n", o.out, strerror(errno));
        return 1;
    }
    scene_file city;
    char err[256];
    if (scene_file_load(o.scene, &city, err, sizeof err)) {
        fprintf(stderr, "report_cull: %s\n", err);
        return 1;
    }
    cull_pool *pool;
    if (cull_pool_create(NTHR, &pool)) return 1;
    char machine[512];
    machine_line(machine, sizeof machine);
    uint32_t isa = cull_isa_default();

    /* ---- time against error: the city walk and the random towns ---- */
    /* scene 0 the city, 1.. the towns */
    static evscene ev[1 + NTOWNS];
    evscene *evp[1 + NTOWNS];
    static point pts[1 + NTOWNS][NPT];
    point rnd_pts[NPT];
    scene_file towns[NTOWNS];
    int nsc = 1 + o.seeds;
    cull_ctx *ctx[NCFG] = {0};
    for (int c = 0; c < NCFG; c++)
        if (cull_ctx_create(pool, &ctx[c])) return 1;
    for (int k = 0; k < nsc; k++) {
        double t0 = bench_now_ns();
        const scene_file *sf = &city;
        if (k > 0) {
            if (bench_town_make(k - 1, 0x70F7 + (uint64_t)(k - 1) * 0x9E37, 15000, &towns[k - 1])) return 1;
            sf = &towns[k - 1];
        }
        if (ev_build(&ev[k], sf, &(bench_cam){0}, k ? o.rand_frames : o.city_frames, o.truth_w, o.truth_h) ||
            eval_accuracy(&ev[k], ctx, pts[k]))
            return 1;
        evp[k] = &ev[k];
        fprintf(stderr, "report_cull: %s: references and accuracy in %.1f s\n", k ? bench_town_kind(k - 1)->name : "city",
                (bench_now_ns() - t0) / 1e9);
    }
    double t0 = bench_now_ns();
    if (time_all(evp, nsc, ctx, o.reps, o.rounds, pts)) return 1;
    fprintf(stderr, "report_cull: timing, all scenes interleaved: %.1f s\n", (bench_now_ns() - t0) / 1e9);
    for (int c = 0; c < NCFG; c++) cull_ctx_destroy(ctx[c]);
    for (int k = 0; k < nsc; k++) ev_free(&ev[k]);
    point *city_pts = pts[0], (*town_pts)[NPT] = pts + 1;
    mark_pareto(city_pts, NPT);
    memset(rnd_pts, 0, sizeof rnd_pts);
    for (int k = 0; k < o.seeds; k++) mark_pareto(town_pts[k], NPT);
    for (int k = 0; k < o.seeds; k++)
        for (int p = 0; p < NPT; p++) {
            point *a = &rnd_pts[p], *b = &town_pts[k][p];
            /* the time: the mean of the towns' medians (and quartiles, minima) */
            a->t_med += b->t_med / o.seeds;
            a->t_min += b->t_min / o.seeds;
            a->t_q1 += b->t_q1 / o.seeds;
            a->t_q3 += b->t_q3 / o.seeds;
            a->frames += b->frames;
            a->queries += b->queries;
            a->kept += b->kept;
            a->truth += b->truth;
            a->fv += b->fv;
            a->fv_frustum += b->fv_frustum;
            a->fi_frustum += b->fi_frustum;
            a->fi_occ += b->fi_occ;
            a->thr_culled += b->thr_culled;
            a->thr_culled_vis += b->thr_culled_vis;
            a->kept_diff += b->kept_diff;
            a->kept_reused += b->kept_reused;
        }
    mark_pareto(rnd_pts, NPT);

    /* ---- stress ---- */
    ptally probe[NPROBE][NFRUSTUM];
    memset(probe, 0, sizeof probe);
    t0 = bench_now_ns();
    int nprobe = o.smoke ? 3 : NPROBE;
    for (int k = 0; k < nprobe; k++) {
        int kk = o.smoke ? (k == 0 ? 0 : k == 1 ? 4 : NPROBE - 1) : k;
        if (probe_run(&g_probe[kk], o.probe_views, o.probe_n, pool, probe[kk])) {
            fprintf(stderr, "report_cull: stress case %s failed to run\n", g_probe[kk].name);
            return 1;
        }
    }
    fprintf(stderr, "report_cull: stress, probes: %.1f s\n", (bench_now_ns() - t0) / 1e9);
    static ctally cst[NCITY];
    if (city_stress(&city, &o, pool, cst)) return 1;

    /* ---- failures: false invisible anywhere ---- */
    uint64_t fi = 0, wrong = 0, kdiff = 0;
    for (int p = 0; p < NPT; p++) {
        fi += city_pts[p].fi_frustum + city_pts[p].fi_occ + rnd_pts[p].fi_frustum + rnd_pts[p].fi_occ;
        kdiff += city_pts[p].kept_diff + rnd_pts[p].kept_diff;
    }
    for (int k = 0; k < NPROBE; k++)
        for (int c = 0; c < NFRUSTUM; c++) wrong += probe[k][c].wrong + probe[k][c].thread_diff;
    for (int k = 0; k < NCITY; k++) {
        wrong += cst[k].thread_diff;
        for (int c = 0; c < NCFG; c++) {
            fi += cst[k].p[c].fi_frustum + cst[k].p[c].fi_occ;
            kdiff += cst[k].p[c].kept_diff;
        }
    }
    wrong += kdiff;
    double t_total = (bench_now_ns() - t_start) / 1e9;

    /* ---- files ---- */
    char cmd[2048] = "";
    for (int i = 0; i < argc; i++) {
        size_t l = strlen(cmd);
        snprintf(cmd + l, sizeof cmd - l, "%s%s", i ? " " : "", argv[i]);
    }
    FILE *csv = open_out(o.out, "time_vs_error.csv"), *sc = open_out(o.out, "stress.csv"),
         *gp = open_out(o.out, "time_vs_error.gp"), *md = open_out(o.out, "report.md");
    if (!csv || !sc || !gp || !md) return 1;
    fprintf(csv, "panel,scene,config,label,threads,area_px,occ_w,occ_h,frames,queries,time_us_median,time_us_min,time_us_q1,"
                 "time_us_q3,visible_per_frame,true_visible_per_frame,false_visible_per_frame,false_visible_rate,"
                 "outside_exact_frustum_per_frame,false_invisible_frustum,false_invisible_occlusion,"
                 "culled_by_threshold_per_frame,culled_by_threshold_true_visible_per_frame,pareto\n");
    for (int p = 0; p < NPT; p++) csv_point(csv, "city", "city", p, &city_pts[p]);
    for (int p = 0; p < NPT; p++) csv_point(csv, "random", "all", p, &rnd_pts[p]);
    for (int k = 0; k < o.seeds; k++)
        for (int p = 0; p < NPT; p++) csv_point(csv, "random", bench_town_kind(k)->name, p, &town_pts[k][p]);
    fclose(csv);

    fprintf(sc, "table,case,config,cases,false_invisible,conservative_within_8eps,conservative_beyond_8eps,"
                "kept_below_threshold,visible_per_frame,true_visible_per_frame,thread_diff,origin_diff\n");
    for (int k = 0; k < NPROBE; k++)
        for (int c = 0; c < NFRUSTUM && probe[k][0].cases; c++) {
            const ptally *t = &probe[k][c];
            fprintf(sc, "probe,\"%s\",%s,%llu,%llu,%llu,%llu,%llu,,,%llu,\n", g_probe[k].name, g_cfg[c].name,
                    (unsigned long long)t->cases, (unsigned long long)t->wrong, (unsigned long long)t->cons_eps,
                    (unsigned long long)t->cons_beyond, (unsigned long long)t->cons_area,
                    (unsigned long long)t->thread_diff);
        }
    for (int k = 0; k < NCITY; k++)
        for (int c = 0; c < NCFG; c++) {
            const point *q = &cst[k].p[c];
            fprintf(sc, "city,\"%s\",%s,%llu,%llu,,,,%.2f,%.2f,%llu,%lld\n", g_city_stress[k].name, g_cfg[c].name,
                    (unsigned long long)(q->frames * city.nobjects), (unsigned long long)(q->fi_frustum + q->fi_occ),
                    per_frame(q->kept, q), per_frame(q->truth, q), (unsigned long long)cst[k].thread_diff,
                    (long long)cst[k].origin_diff);
        }
    fclose(sc);

    write_gp(gp, city_pts, rnd_pts, o.seeds, machine);
    fclose(gp);

    fprintf(md, "# Culling: run time against error\n\n");
    fprintf(md, "`%s`; kernels %s; %s, `CONFIG=release` (-O2); this run took %.0f s; load average (1 min) "
                "%.2f at its start, %.2f at its end.\n\n",
            machine, cull_isa_name(isa),
#ifdef __VERSION__
            "gcc " __VERSION__,
#else
            "cc",
#endif
            t_total, load0, load_avg());
    fprintf(md, "Made by `make report`, which builds `build/release/report_cull` and runs, from the "
                "repository root:\n\n```sh\n%s\ncd %s && gnuplot time_vs_error.gp\n```\n\n",
            cmd, o.out);
    if (o.smoke) fprintf(md, "**A smoke run** (`--smoke`): few frames and repetitions; the figures mean little.\n\n");
    fprintf(md,
            "## What is measured\n\n"
            "**Configurations** (flags of `cull_query`, `culling/culling.h`), each at 1 and 2 threads of a "
            "2-thread pool (`cull_query_desc.threads`), one view of 1920x1080:\n\n"
            "* *spheres only*: `CULL_Q_NO_AABB`; *spheres + AABB*: the default frustum stages;\n"
            "* *+ area >= 1 / 2 / 4 px*: spheres + AABB + `min_screen_area`, tested on the default "
            "centre/extent upper bound of the projected AABB rectangle;\n"
            "* *+ occlusion WxH*: spheres + AABB + the occlusion stage with the context rendering the "
            "occluders into its own WxH buffer every query (`occ_w`, `occ_h`; whole-pixel coverage, the "
            "default), no area threshold, `CULL_Q_OCC_FRESH`: the occluders drawn every query. Its time "
            "includes the render: what a caller pays for a moving camera;\n"
            "* *+ occlusion WxH, kept buffer*: the same query asked again and again per frame, as a still "
            "camera (a viewer or commander stream re-querying one view) does: the first draws, the second "
            "records the blocks' verdicts, the third (timed) goes through the buffer and the records the "
            "context kept: what every later frame of a still view pays (issue 24). The verdicts through the "
            "kept buffer must equal the freshly drawn buffer's, entity for entity (checked every frame: "
            "`make report` fails otherwise).\n\n"
            "**Scenes.** The shared city scene (`%s`: 15,000 object AABBs as entities, 1,000 boxes as "
            "occluders), its camera walking %d frames 0.5 m apart toward the target, as `bench_cull --demo` "
            "and `bench_occlusion` do; and %d seeded random towns (%d frames each, 0.5 m apart): boxes of "
            "random footprint and height as occluders, 15,000 AABB entities with sides 0.2..10 m "
            "(log-uniform; 70 %% standing on the ground, the rest at 0..40 m), a camera at street level "
            "outside every box (`bench_town_make` in `tests/bench/bench_scene.h`):",
            o.scene, o.city_frames, o.seeds, o.rand_frames);
    for (int k = 0; k < o.seeds; k++)
        fprintf(md, "%s *%s* (%d boxes in %.0f m square, footprints %.0f..%.0f m, heights %.0f..%.0f m)",
                k ? "," : "", bench_town_kind(k)->name, bench_town_kind(k)->boxes, 2 * bench_town_kind(k)->half, bench_town_kind(k)->foot_lo,
                bench_town_kind(k)->foot_hi, bench_town_kind(k)->h_lo, bench_town_kind(k)->h_hi);
    fprintf(md,
            ". Views 60 degrees, near 0.1, far 2000, GL depth.\n\n"
            "**References**, per frame and entity, none sharing code with `culling/`:\n\n"
            "* *exact frustum*: `tests/cull_ref.c` in long double: the bounding sphere and the AABB "
            "(p-vertex) against the six planes, from the entity as stored (`cull_entity_get`);\n"
            "* *truly visible*: in the exact frustum, and seen by the ray caster `tests/occ_ref.c` (double): "
            "some pixel-centre ray of a %ux%u image of the view enters the entity's AABB before it hits any "
            "front-facing occluder triangle: what a %ux%u z-buffer of the occluders would let through, each entity "
            "tested alone (entities hide nothing; an entity that covers no pixel centre counts as not visible).\n\n"
            "**Errors**, counted per frame and entity:\n\n"
            "* *false visible*: reported visible, not truly visible. The **false-visible rate** is false visible "
            "/ reported visible: the share of what a renderer would be handed that it draws for nothing.\n"
            "* *outside the exact frustum*: reported visible although the long double frustum test culls it "
            "(the spheres-only stage's excess, and the outward rounding of stored bounds).\n"
            "* *false invisible*: culled although it should not be: by a frustum stage while the exact test "
            "of that stage keeps it (and, with a threshold, its exact projected area is at least the "
            "threshold), or by occlusion while the ray caster sees it. **Must be 0**; `make report` and "
            "`make report-smoke` fail otherwise.\n"
            "* *culled by threshold*: culled by the area threshold, its exact projected-AABB area "
            "(`cull_ref`) below the threshold: on purpose, not an error; in brackets how many of those the "
            "caster sees.\n\n"
            "**Time** per query: as `bench_cull`, the camera moves every call (the walk's frames in turn), "
            "caches warm; the median over %d passes of the walk per point (and the quartiles and the "
            "minimum). Every scene and point takes turns in %d rounds (a point runs its share of passes in one "
            "go, so its caches stay warm as in `bench_cull`), so that a burst of load on the shared machine "
            "falls on all alike. This machine alternates between a quiet and a busy state in which the same "
            "query takes about 1.6x as long (`bench_cull --demo` shows it too), hence the wide quartiles; the "
            "minimum is the quiet machine. For the random towns: the mean of the towns' medians. 2 threads need "
            "the second vCPU, which other work here often holds: their spread is wide. Counts are means per "
            "frame; for the random towns over all towns' frames.\n\n"
            "**Pareto front**: the points no other point beats on both time and false-visible rate (in bold). "
            "A point on it is the cheapest way to its error level here.\n\n",
            o.truth_w, o.truth_h, o.truth_w, o.truth_h, o.rounds * ((o.reps + o.rounds - 1) / o.rounds), o.rounds);
    fprintf(md, "![time per query against false-visible rate](time_vs_error.svg)\n\n");
    fprintf(md, "## City walk\n\n");
    md_front(md, city_pts);
    md_points(md, city_pts);
    fprintf(md, "\n## Random towns (all %d towns; per town in `time_vs_error.csv`)\n\n", o.seeds);
    md_front(md, rnd_pts);
    md_points(md, rnd_pts);

    fprintf(md,
            "\n## Numerical stress: frustum and area stages against the long double model\n\n"
            "Per case, %d probe entities around %d cameras (60 degrees, 1920x1080, eyes within 500 m, "
            "pitch within 0.3 rad), the same seed in every case: each at a log-uniform distance from a "
            "camera, half of them moved onto one of its planes and then a hair (10^-9..1 m x max(r, 1)) in "
            "or out of touching it; a third spheres, a third AABBs, a third both. Every entity against every "
            "camera (one view per query). \"Far\" cases translate cameras and entities by (d, d, d). Each cell: "
            "**conservative / wrong**: *conservative* = kept although the model culls it (within 8 eps of a "
            "plane, eps = 2^-20 (4 cell + r + reach), the stated rounding; beyond 8 eps in brackets if any; "
            "for area thresholds plus those kept below the threshold by the bound, after the +); *wrong* = "
            "culled although the model keeps it: must be 0. 2 threads gave the same verdicts as 1 in every "
            "case unless a case says otherwise. Occlusion configurations: no occluders here (see the next "
            "table). Reversed-Z: supported by the core (`CULL_DEPTH_REVERSED`, with finite or infinite far "
            "planes), tested here.\n\n",
            o.probe_n, o.probe_views);
    md_cfg_header(md, "cases", NFRUSTUM, NULL, 0);
    for (int k = 0; k < NPROBE; k++) {
        if (!probe[k][0].cases) continue;
        fprintf(md, "| %s | %llu |", g_probe[k].name, (unsigned long long)probe[k][0].cases);
        for (int c = 0; c < NFRUSTUM; c++) {
            const ptally *t = &probe[k][c];
            char beyond[48] = "", area[48] = "", thr[64] = "";
            if (t->cons_beyond) snprintf(beyond, sizeof beyond, " (%llu)", (unsigned long long)t->cons_beyond);
            if (g_cfg[c].area > 0) snprintf(area, sizeof area, "+%llu", (unsigned long long)t->cons_area);
            if (t->thread_diff) snprintf(thr, sizeof thr, " **2 threads differ: %llu**", (unsigned long long)t->thread_diff);
            fprintf(md, " %llu%s%s / %s%llu%s%s |", (unsigned long long)(t->cons_eps + t->cons_beyond), beyond, area,
                    t->wrong ? "**" : "", (unsigned long long)t->wrong, t->wrong ? "**" : "", thr);
        }
        fprintf(md, "\n");
    }
    fprintf(md,
            "\n## Numerical stress: the city with occlusion, far away and through extreme projections\n\n"
            "The city scene (objects, occluder boxes, camera) translated by (d, d, d), or seen through "
            "other projections; %d frame(s) 4 m apart; the truth is the exact frustum and the %ux%u ray caster "
            "at the same place (double, camera-relative). Each cell: **reported visible per frame / false "
            "invisible** (false invisible must be 0). *Differs from origin*: entity verdicts, summed over the "
            "configurations and frames, that differ from the first row's (where the frustum is the same: "
            "translations, and reversed-Z with the same near and far planes; a translation by other than a "
            "multiple of the 64 m cell regroups the entities into other cells, whose float rounding differs). "
            "*2 threads differ*: verdicts that differ between 1 and 2 threads, all configurations.\n\n",
            o.stress_frames, o.truth_w, o.truth_h);
    md_cfg_header(md, "truly visible", NCFG, " differs from origin | 2 threads differ |", 2);
    for (int k = 0; k < NCITY; k++) {
        fprintf(md, "| %s | %.1f |", g_city_stress[k].name, cst[k].truth);
        for (int c = 0; c < NCFG; c++) {
            const point *q = &cst[k].p[c];
            uint64_t f = q->fi_frustum + q->fi_occ;
            fprintf(md, " %.1f / %s%llu%s |", per_frame(q->kept, q), f ? "**" : "", (unsigned long long)f,
                    f ? "**" : "");
        }
        if (cst[k].origin_diff < 0) fprintf(md, " - |");
        else fprintf(md, " %lld |", (long long)cst[k].origin_diff);
        fprintf(md, " %llu |\n", (unsigned long long)cst[k].thread_diff);
    }
    fprintf(md,
            "\n## Files\n\n"
            "* `report.md`: this page; `time_vs_error.csv`: every point (city, random towns together and "
            "each town), its times and counts; `stress.csv`: both stress tables' counts;\n"
            "* `time_vs_error.gp`: the gnuplot script with the plotted data inline; it draws "
            "`time_vs_error.svg` and `time_vs_error.png`.\n");
    {
        uint64_t kr = 0, kf = 0;
        for (int p = 0; p < NPT; p++)
            if (g_cfg[p / NTHR].still) kr += city_pts[p].kept_reused + rnd_pts[p].kept_reused,
                                       kf += city_pts[p].frames + rnd_pts[p].frames;
        fprintf(md, "\n**Kept buffers**: the still-camera configurations kept their buffer on %llu of %llu frames "
                    "(city and towns); %llu verdicts through a kept buffer differed from the fresh buffer's "
                    "(must be 0).\n",
                (unsigned long long)kr, (unsigned long long)kf, (unsigned long long)kdiff);
    }
    if (fi || wrong)
        fprintf(md, "\n**FAILED: %llu false invisible, %llu wrong culls, thread differences in the stress "
                    "tables or kept-buffer verdicts that differ from a fresh buffer's.**\n",
                (unsigned long long)fi, (unsigned long long)wrong);
    fclose(md);

    fprintf(stderr, "report_cull: wrote %s/report.md, time_vs_error.csv, stress.csv, time_vs_error.gp in %.1f s\n",
            o.out, t_total);
    for (int k = 0; k < o.seeds; k++) scene_file_free(&towns[k]);
    scene_file_free(&city);
    cull_pool_destroy(pool);
    if (fi || wrong) {
        fprintf(stderr, "report_cull: FAILED: %llu false invisible, %llu wrong culls, thread differences in the "
                        "stress tables or kept-buffer differences (see report.md)\n",
                (unsigned long long)fi, (unsigned long long)wrong);
        return 3;
    }
    return 0;
}
