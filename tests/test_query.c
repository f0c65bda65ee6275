/*
 * test_query.c — the query pipeline against the long double model
 * (cull_ref.c): >= 10^6 random entity x view cases per ISA and thread count,
 * coordinates to ±1e6 m, radii 1e-4..1e4, near planes to 1e-4, far planes to
 * 1e7 and infinity, GL / [0,1] / reversed-Z, perspective and orthographic,
 * entities placed on purpose within a hair of a plane.
 *
 * False culls, strictly: an entity culled from a view while the model keeps
 * it (frustum margin >= 0 and, with a threshold, area >= threshold); there
 * must be none. The other way, the core may keep what the model culls, by
 * the outward rounding of stored bounds: eps = 2^-20 * (4 * cell + r +
 * reach), reach being the AABB's largest distance from the cell origin
 * (the storage slack is 2 eps). Such cases within 8 eps are counted and
 * reported; beyond 8 eps they fail.
 */
#include "test_util.h"

#include "cull_ref.h"
#include "culling.h"
#include "scene_file.h"
#include <stdatomic.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

typedef struct tally {
    uint64_t cases, false_culls, kept_within_eps, kept_beyond_eps, area_false_culls,
        area_kept_within, area_low, results;
} tally;

static tally g_tally;

typedef struct scene {
    double cell;
    uint32_t n, nv;
    cull_entity_desc *e;     /* normalised */
    cull_handle *h;
    cull_view_desc vd[CULL_MAX_VIEWS];
    cull_view v[CULL_MAX_VIEWS];
    ref_view rv[CULL_MAX_VIEWS];
    float min_area;
    uint32_t flags;
    ref_verdict *model;      /* n * nv */
} scene;

static void random_view(rng *r, cull_view_desc *d, double span)
{
    memset(d, 0, sizeof *d);
    d->depth_mode = rng_below(r, 3);
    d->viewport_w = 16 + rng_below(r, 3000);
    d->viewport_h = 16 + rng_below(r, 2000);
    double eye[3];
    for (int a = 0; a < 3; a++) eye[a] = rng_range(r, -span, span);
    double proj[16], view[16];
    if (rng_below(r, 4)) {
        double n = rng_log(r, 1e-4, 10);
        double f = rng_below(r, 5) ? rng_log(r, n * 10, 1e7) : INFINITY;
        if (isinf(f) && d->depth_mode == CULL_DEPTH_ZERO_ONE) d->depth_mode = CULL_DEPTH_REVERSED;
        cull_mat_perspective(proj, rng_range(r, 0.05, 2.6), rng_range(r, 0.3, 3.5), n, f, d->depth_mode);
    } else {
        double hw = rng_log(r, 0.5, 1e4), hh = rng_log(r, 0.5, 1e4);
        double n = rng_range(r, -1000, 10);
        cull_mat_ortho(proj, -hw, hw, -hh, hh, n, n + rng_log(r, 1, 1e6), d->depth_mode);
    }
    double dir[3], up[3] = {0, 1, 0};
    do {
        for (int a = 0; a < 3; a++) dir[a] = rng_range(r, -1, 1);
    } while (fabs(dir[0]) + fabs(dir[2]) < 1e-3);
    cull_mat_look_dir(view, dir, up);
    cull_mat_mul(d->view_proj, proj, view);
    if (rng_below(r, 3)) {
        memcpy(d->origin, eye, sizeof eye); /* camera-relative */
    } else {
        /* world matrix: VP * translate(-eye), origin 0 */
        double t[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, -eye[0], -eye[1], -eye[2], 1};
        cull_mat_mul(d->view_proj, d->view_proj, t);
    }
}

/* A sphere and AABB that bound the same object (they share its centre). */
static void random_bounds(rng *r, cull_entity_desc *e, const double c[3], double rad)
{
    memset(e, 0, sizeof *e);
    uint32_t kind = rng_below(r, 3);
    if (kind == 0) { /* sphere; AABB derived */
        memcpy(e->center, c, 3 * sizeof *c);
        e->radius = rad;
    } else if (kind == 1) { /* AABB; sphere derived */
        for (int a = 0; a < 3; a++) {
            double h = rad * rng_range(r, 0.05, 1);
            e->aabb_min[a] = c[a] - h;
            e->aabb_max[a] = c[a] + h;
        }
    } else { /* both: a box inside the sphere's bounding box */
        memcpy(e->center, c, 3 * sizeof *c);
        e->radius = rad;
        for (int a = 0; a < 3; a++) {
            e->aabb_min[a] = c[a] - rad * rng_f(r);
            e->aabb_max[a] = c[a] + rad * rng_f(r);
        }
    }
    e->class_id = (uint16_t)rng_below(r, 65536);
    e->sublevel = (uint16_t)rng_below(r, 65536);
    e->flags = rng_below(r, 2) ? CULL_ENTITY_DYNAMIC : 0;
}

/* An entity near one of the scene's views: at a random distance, or on
 * purpose within a hair of touching one of its planes. */
static void random_entity(rng *r, const scene *s, cull_entity_desc *e)
{
    const cull_view *v = &s->v[rng_below(r, s->nv)];
    double rad = rng_below(r, 10) == 0 ? 0 : rng_log(r, 1e-4, 1e4);
    double c[3];
    double dist = rng_log(r, 1e-3, 3e5);
    for (int a = 0; a < 3; a++) c[a] = v->origin[a] + rng_range(r, -1, 1) * dist;
    if (rng_below(r, 2)) {
        /* onto a plane, then a hair in or out of touching it */
        const double *pl = v->plane[rng_below(r, v->plane_count)];
        double sd = pl[0] * (c[0] - v->origin[0]) + pl[1] * (c[1] - v->origin[1]) +
                    pl[2] * (c[2] - v->origin[2]) + pl[3];
        double off = -rad + (rng_below(r, 2) ? 1 : -1) * fmax(rad, 1) * pow(10, -rng_range(r, 0, 9));
        for (int a = 0; a < 3; a++) c[a] -= (sd - off) * pl[a];
    }
    for (int a = 0; a < 3; a++) c[a] = fmax(-1e6, fmin(1e6, c[a]));
    random_bounds(r, e, c, rad);
}

static void scene_make(rng *r, scene *s, uint32_t n, uint32_t nv)
{
    static const double cells[] = {1, 8, 64, 512};
    memset(s, 0, sizeof *s);
    s->cell = cells[rng_below(r, 4)];
    s->n = n;
    s->nv = nv;
    double span = rng_below(r, 2) ? 1e6 : 1e3;
    for (uint32_t v = 0; v < nv; v++) {
        do random_view(r, &s->vd[v], span);
        while (cull_view_init(&s->v[v], &s->vd[v]) != CULL_OK);
        ref_view_make(&s->rv[v], &s->vd[v]);
    }
    s->e = calloc(n, sizeof *s->e);
    s->h = calloc(n, sizeof *s->h);
    for (uint32_t i = 0; i < n; i++) random_entity(r, s, &s->e[i]);
    s->min_area = rng_below(r, 2) ? 0 : (float)rng_log(r, 0.01, 1e4);
    s->flags = rng_below(r, 5) == 0 ? CULL_Q_NO_AABB : CULL_Q_WANT_AREA * rng_below(r, 2);
}

static void scene_free(scene *s)
{
    free(s->e);
    free(s->h);
    free(s->model);
}

/* Builds the world, then (in most scenes) edits it: a third of the
 * entities move somewhere else, a tenth are removed and added again, and
 * the bounds are tightened half of the time, so queries run on storage that
 * edits have shuffled. Then the model's verdicts. */
static cull_world *scene_world(rng *r, scene *s)
{
    cull_world *w;
    assert_int_equal(cull_world_create(&(cull_world_desc){.cell_size = s->cell}, &w), CULL_OK);
    for (uint32_t i = 0; i < s->n; i++) assert_int_equal(cull_entity_add(w, &s->e[i], &s->h[i]), CULL_OK);
    if (rng_below(r, 4)) {
        for (uint32_t i = 0; i < s->n; i++) {
            uint32_t op = rng_below(r, 10);
            if (op < 3) {
                random_entity(r, s, &s->e[i]);
                assert_int_equal(cull_entity_update(w, s->h[i], &s->e[i]), CULL_OK);
            } else if (op == 3) {
                /* the freed slot is reused at once, so slot i stays entity i */
                assert_int_equal(cull_entity_remove(w, s->h[i]), CULL_OK);
                random_entity(r, s, &s->e[i]);
                cull_handle old = s->h[i];
                assert_int_equal(cull_entity_add(w, &s->e[i], &s->h[i]), CULL_OK);
                assert_int_not_equal(old, s->h[i]);
                assert_int_equal(old & (CULL_MAX_ENTITIES - 1), s->h[i] & (CULL_MAX_ENTITIES - 1));
            }
        }
        if (rng_below(r, 2)) cull_world_commit(w);
    }
    for (uint32_t i = 0; i < s->n; i++) assert_int_equal(cull_entity_get(w, s->h[i], &s->e[i]), CULL_OK);
    s->model = calloc((size_t)s->n * s->nv, sizeof *s->model);
    for (uint32_t i = 0; i < s->n; i++)
        for (uint32_t v = 0; v < s->nv; v++) ref_test(&s->rv[v], &s->e[i], &s->model[(size_t)i * s->nv + v]);
    return w;
}

static double reach(const scene *s, const cull_entity_desc *e)
{
    double m = 0;
    for (int a = 0; a < 3; a++) {
        double o = floor(e->center[a] / s->cell) * s->cell;
        m = fmax(m, fmax(fabs(e->aabb_min[a] - o), fabs(e->aabb_max[a] - o)));
    }
    return m;
}

/* Checks one query's results against the model; returns the result count. */
static void check_results(const scene *s, const cull_result *res, size_t n, tally *t)
{
    /* handle -> index: handles here are small slots with generation 1 */
    uint32_t *mask = calloc(s->n, sizeof *mask);
    float *area = calloc(s->n, sizeof *area);
    for (size_t k = 0; k < n; k++) {
        uint32_t slot = res[k].handle & (CULL_MAX_ENTITIES - 1);
        assert_true(slot < s->n);
        assert_int_equal(res[k].handle, s->h[slot]);
        assert_int_equal(mask[slot], 0); /* each entity at most once */
        assert_int_not_equal(res[k].view_mask, 0);
        if (s->nv < 32) assert_int_equal(res[k].view_mask >> s->nv, 0);
        assert_int_equal(res[k].class_id, s->e[slot].class_id);
        assert_int_equal(res[k].sublevel, s->e[slot].sublevel);
        mask[slot] = res[k].view_mask;
        area[slot] = res[k].screen_area;
    }
    bool aabb = !(s->flags & CULL_Q_NO_AABB);
    bool want_area = (s->flags & CULL_Q_WANT_AREA) != 0;
    for (uint32_t i = 0; i < s->n; i++) {
        const cull_entity_desc *e = &s->e[i];
        double eps = 0x1p-20 * (4 * s->cell + e->radius + reach(s, e));
        long double model_max_area = -1;
        for (uint32_t v = 0; v < s->nv; v++) {
            const ref_verdict *m = &s->model[(size_t)i * s->nv + v];
            long double margin = aabb ? fminl(m->sphere_margin, m->aabb_margin) : m->sphere_margin;
            bool fast = (mask[i] >> v) & 1;
            bool frustum_keep = margin >= 0;
            bool area_keep = s->min_area <= 0 || m->area >= s->min_area;
            t->cases++;
            if (!fast) {
                /* strict: whatever the exact test keeps must be kept */
                if (frustum_keep && area_keep) {
                    if (s->min_area > 0) t->area_false_culls++;
                    else t->false_culls++;
                    if (t->false_culls + t->area_false_culls < 5)
                        fprintf(stderr, "false cull: entity %u view %u margin %Lg eps %g area %Lg thr %g\n",
                                i, v, margin, eps, m->area, s->min_area);
                }
            } else {
                if (!frustum_keep) {
                    if (margin >= -4 * 2 * eps) t->kept_within_eps++;
                    else {
                        t->kept_beyond_eps++;
                        if (t->kept_beyond_eps < 5)
                            fprintf(stderr, "kept beyond eps: entity %u view %u margin %Lg (sph %Lg in %Lg box %Lg) eps %g c %g %g %g r %g box %g %g %g / %g %g %g nv %u flags %u planes %u mode %u\n", i, v,
                                    margin, m->sphere_margin, m->inner_margin, m->aabb_margin, eps, e->center[0], e->center[1], e->center[2], e->radius,
                                    e->aabb_min[0], e->aabb_min[1], e->aabb_min[2], e->aabb_max[0], e->aabb_max[1], e->aabb_max[2], s->nv, s->flags, s->v[v].plane_count, s->v[v].depth_mode);
                    }
                } else if (!area_keep) {
                    t->area_kept_within++;
                }
                model_max_area = fmaxl(model_max_area, m->area);
            }
        }
        if (mask[i] && want_area) {
            /* conservative: never smaller than the exact box's area */
            if (!((long double)area[i] >= model_max_area * (1 - 1e-4L) - 1e-3L)) {
                t->area_low++;
                if (t->area_low < 5)
                    fprintf(stderr, "area low: entity %u fast %g model %Lg\n", i, area[i], model_max_area);
            }
        } else if (mask[i]) {
            assert_true(area[i] == -1.0f);
        }
    }
    t->results += n;
    free(mask);
    free(area);
}

static void test_random_vs_model(void **state)
{
    (void)state;
    rng r = {test_seed() ^ 0x3333};
    cull_pool *pool;
    assert_int_equal(cull_pool_create(2, &pool), CULL_OK);
    cull_ctx *ctx;
    assert_int_equal(cull_ctx_create(pool, &ctx), CULL_OK);
    tally t = {0};
    uint64_t target = (uint64_t)(1.05e6 * test_scale());
    uint64_t per_run = 0;
    int scenes = 0;
    while (per_run < target) {
        uint32_t nv = rng_below(&r, 8) == 0 ? 32 : 1 + rng_below(&r, 8);
        scene s;
        scene_make(&r, &s, 1500 + rng_below(&r, 3000), nv);
        cull_world *w = scene_world(&r, &s);
        size_t cap = cull_query_bound(w);
        /* per ISA: threads 1, 2 and automatic */
        cull_result *res[3 * CULL_ISA_COUNT] = {0};
        size_t cnt[3 * CULL_ISA_COUNT] = {0};
        for (uint32_t isa = 0; isa < CULL_ISA_COUNT; isa++) {
            if (!cull_isa_supported(isa)) continue;
            assert_int_equal(cull_ctx_set_isa(ctx, isa), CULL_OK);
            for (uint32_t ti = 0; ti < 3; ti++) {
                uint32_t th = ti == 2 ? 0 : ti + 1;
                size_t k = isa * 3 + ti;
                res[k] = malloc(cap * sizeof *res[k]);
                cull_query_desc q = {.views = s.v, .view_count = nv, .flags = s.flags,
                                     .min_screen_area = s.min_area, .threads = th};
                cull_query_stats st;
                assert_int_equal(cull_query(w, ctx, &q, res[k], cap, &cnt[k], &st), CULL_OK);
                assert_int_equal(st.visible, cnt[k]);
                assert_true(st.after_area <= st.after_aabb && st.after_aabb <= st.after_spheres &&
                            st.after_spheres <= st.entities_tested && st.entities_tested <= s.n);
                check_results(&s, res[k], cnt[k], &t);
                /* counting alone gives the same number and writes nothing */
                size_t counted = 0;
                q.flags |= CULL_Q_COUNT_ONLY;
                assert_int_equal(cull_query(w, ctx, &q, NULL, 0, &counted, NULL), CULL_OK);
                assert_int_equal(counted, cnt[k]);
                if (ti > 0) {
                    /* thread count never changes the answer or its order */
                    assert_int_equal(cnt[k], cnt[isa * 3]);
                    assert_memory_equal(res[k], res[isa * 3], cnt[k] * sizeof(cull_result));
                }
            }
        }
        /* across ISAs: the same order for what both return */
        for (uint32_t isa = 1; isa < CULL_ISA_COUNT; isa++) {
            size_t a = 0, b = isa * 3;
            if (!res[b]) continue;
            uint32_t *pos = calloc(s.n, sizeof *pos);
            for (size_t k = 0; k < cnt[a]; k++) pos[res[a][k].handle & (CULL_MAX_ENTITIES - 1)] = (uint32_t)k + 1;
            uint32_t last = 0;
            for (size_t k = 0; k < cnt[b]; k++) {
                uint32_t p = pos[res[b][k].handle & (CULL_MAX_ENTITIES - 1)];
                if (!p) continue;
                assert_true(p > last);
                last = p;
            }
            free(pos);
        }
        for (size_t k = 0; k < 3 * CULL_ISA_COUNT; k++) free(res[k]);
        per_run += (uint64_t)s.n * nv;
        scenes++;
        cull_world_destroy(w);
        scene_free(&s);
    }
    uint32_t runs = 0;
    for (uint32_t isa = 0; isa < CULL_ISA_COUNT; isa++) runs += cull_isa_supported(isa) ? 3 : 0;
    printf("query vs model: %d scenes, %llu entity x view cases per ISA x threads run, %u runs "
           "(%llu cases): false culls %llu (with an area threshold %llu); kept though the model culls: "
           "%llu within 8 eps, %llu beyond; kept below the area threshold %llu; reported area below "
           "the model's %llu\n",
           scenes, (unsigned long long)per_run, runs, (unsigned long long)t.cases,
           (unsigned long long)t.false_culls, (unsigned long long)t.area_false_culls,
           (unsigned long long)t.kept_within_eps, (unsigned long long)t.kept_beyond_eps,
           (unsigned long long)t.area_kept_within, (unsigned long long)t.area_low);
    g_tally = t;
    assert_int_equal(t.false_culls, 0);
    assert_int_equal(t.area_false_culls, 0);
    assert_int_equal(t.kept_beyond_eps, 0);
    assert_int_equal(t.area_low, 0);
    cull_ctx_destroy(ctx);
    cull_pool_destroy(pool);
}

/* The same scene at the origin and shifted by ~1e6 m (a whole number of
 * 8^3-cell regions, exact in double) gives bit-identical answers. */
static void test_far_camera_is_exact(void **state)
{
    (void)state;
    rng r = {test_seed() ^ 0x4444};
    const double shift[3] = {1953.0 * 512, -1953.0 * 512, 976.0 * 512};
    cull_ctx *ctx;
    assert_int_equal(cull_ctx_create(NULL, &ctx), CULL_OK);
    int nonempty = 0;
    for (int it = 0; it < 400 && nonempty < 20; it++) {
        cull_world *w[2];
        for (int k = 0; k < 2; k++)
            assert_int_equal(cull_world_create(&(cull_world_desc){.cell_size = 64}, &w[k]), CULL_OK);
        for (int i = 0; i < 3000; i++) {
            cull_entity_desc e = {.radius = ldexp(floor(rng_range(&r, 1, 4096)), -8)};
            for (int a = 0; a < 3; a++) e.center[a] = ldexp(floor(rng_range(&r, -1, 1) * 0x1p28), -20);
            cull_handle h;
            assert_int_equal(cull_entity_add(w[0], &e, &h), CULL_OK);
            for (int a = 0; a < 3; a++) e.center[a] += shift[a];
            assert_int_equal(cull_entity_add(w[1], &e, &h), CULL_OK);
        }
        cull_view_desc d;
        random_view(&r, &d, 0);
        for (int a = 0; a < 3; a++) d.origin[a] = ldexp(floor(rng_range(&r, -1, 1) * 0x1p26), -20);
        cull_view v[2];
        assert_int_equal(cull_view_init(&v[0], &d), CULL_OK);
        for (int a = 0; a < 3; a++) d.origin[a] += shift[a];
        assert_int_equal(cull_view_init(&v[1], &d), CULL_OK);
        cull_result a[3000 + CULL_RESULT_PAD], b[3000 + CULL_RESULT_PAD];
        size_t na, nb;
        cull_query_desc q = {.view_count = 1, .flags = CULL_Q_WANT_AREA};
        q.views = &v[0];
        assert_int_equal(cull_query(w[0], ctx, &q, a, 3000 + CULL_RESULT_PAD, &na, NULL), CULL_OK);
        q.views = &v[1];
        assert_int_equal(cull_query(w[1], ctx, &q, b, 3000 + CULL_RESULT_PAD, &nb, NULL), CULL_OK);
        assert_int_equal(na, nb);
        assert_memory_equal(a, b, na * sizeof *a);
        nonempty += na > 0;
        cull_world_destroy(w[0]);
        cull_world_destroy(w[1]);
    }
    assert_int_equal(nonempty, 20); /* 20 comparisons of non-empty answers */
    cull_ctx_destroy(ctx);
}

static void test_bad_queries(void **state)
{
    (void)state;
    cull_world *w;
    assert_int_equal(cull_world_create(NULL, &w), CULL_OK);
    cull_handle h;
    assert_int_equal(cull_entity_add(w, &(cull_entity_desc){.radius = 1}, &h), CULL_OK);
    cull_ctx *c;
    assert_int_equal(cull_ctx_create(NULL, &c), CULL_OK);
    cull_view v[33];
    cull_view_desc d = {0};
    cull_mat_perspective(d.view_proj, 1, 1, 0.1, 100, CULL_DEPTH_GL);
    d.origin[2] = 10;
    for (int i = 0; i < 33; i++) assert_int_equal(cull_view_init(&v[i], &d), CULL_OK);
    cull_result res[1 + CULL_RESULT_PAD];
    const size_t cap = 1 + CULL_RESULT_PAD;
    assert_int_equal(cull_query_bound(w), cap);
    size_t n = 99;
    assert_int_equal(cull_query(w, c, &(cull_query_desc){.views = v, .view_count = 0}, res, cap, &n, NULL),
                     CULL_ERR_VIEWS);
    assert_int_equal(n, 0);
    assert_int_equal(cull_query(w, c, &(cull_query_desc){.views = v, .view_count = 33}, res, cap, &n, NULL),
                     CULL_ERR_VIEWS);
    assert_int_equal(cull_query(w, c, &(cull_query_desc){.views = NULL, .view_count = 1}, res, cap, &n, NULL),
                     CULL_ERR_VIEWS);
    assert_int_equal(cull_query(w, c, &(cull_query_desc){.views = v, .view_count = 1}, res, cap - 1, &n, NULL),
                     CULL_ERR_OUTPUT);
    assert_int_equal(cull_query(w, c, &(cull_query_desc){.views = v, .view_count = 1, .min_screen_area = NAN},
                                res, cap, &n, NULL),
                     CULL_ERR_INVALID);
    assert_int_equal(cull_query(w, c, &(cull_query_desc){.views = v, .view_count = 1, .min_screen_area = -1},
                                res, cap, &n, NULL),
                     CULL_ERR_INVALID);
    cull_view junk = v[0];
    junk.plane_count = 0;
    assert_int_equal(cull_query(w, c, &(cull_query_desc){.views = &junk, .view_count = 1}, res, cap, &n, NULL),
                     CULL_ERR_MATRIX);
    /* 32 views at once: every bit set */
    assert_int_equal(cull_query(w, c, &(cull_query_desc){.views = v, .view_count = 32}, res, cap, &n, NULL),
                     CULL_OK);
    assert_int_equal(n, 1);
    assert_int_equal(res[0].view_mask, UINT32_MAX);
    assert_int_equal(cull_ctx_set_isa(c, 99), CULL_ERR_INVALID);
    cull_ctx_destroy(c);
    cull_ctx_destroy(NULL);
    cull_world_destroy(w);
}

/* The shared city scene: the frustum stage must agree with the model
 * entity by entity (15,000 objects; the reference says 5,731
 * survive the frustum). */
static void test_city_scene(void **state)
{
    (void)state;
    const char *path = getenv("VANTAGE_SCENE");
    if (!path) path = "tests/data/scenes/city_scene.txt";
    scene_file sf;
    char err[256];
    /* the scene is in the repository: missing is a failure, never a skip */
    if (scene_file_load(path, &sf, err, sizeof err)) fail_msg("city scene: %s", err);
    cull_world *w;
    assert_int_equal(cull_world_create(NULL, &w), CULL_OK);
    for (size_t i = 0; i < sf.nobjects; i++) {
        cull_entity_desc e = {0};
        memcpy(e.aabb_min, sf.objects + i * 6, 3 * sizeof(double));
        memcpy(e.aabb_max, sf.objects + i * 6 + 3, 3 * sizeof(double));
        cull_handle h;
        assert_int_equal(cull_entity_add(w, &e, &h), CULL_OK);
    }
    cull_view_desc d = {.viewport_w = 1920, .viewport_h = 1080};
    double proj[16], view[16], dir[3];
    for (int a = 0; a < 3; a++) dir[a] = sf.target[a] - sf.eye[a];
    cull_mat_perspective(proj, sf.fovy_deg * M_PI / 180, sf.aspect, sf.znear, sf.zfar, CULL_DEPTH_GL);
    cull_mat_look_dir(view, dir, sf.up);
    cull_mat_mul(d.view_proj, proj, view);
    memcpy(d.origin, sf.eye, sizeof d.origin);
    cull_view v;
    assert_int_equal(cull_view_init(&v, &d), CULL_OK);
    ref_view rv;
    ref_view_make(&rv, &d);
    size_t model = 0;
    for (size_t i = 0; i < sf.nobjects; i++) {
        cull_entity_desc e;
        ref_verdict rr;
        assert_int_equal(cull_entity_get(w, (cull_handle)((1u << CULL_HANDLE_SLOT_BITS) | i), &e), CULL_OK);
        ref_test(&rv, &e, &rr);
        model += rr.aabb_margin >= 0;
    }
    cull_ctx *c;
    assert_int_equal(cull_ctx_create(NULL, &c), CULL_OK);
    size_t cap = cull_query_bound(w);
    cull_result *res = malloc(cap * sizeof *res);
    size_t n;
    cull_query_stats st;
    assert_int_equal(cull_query(w, c, &(cull_query_desc){.views = &v, .view_count = 1}, res, cap, &n, &st),
                     CULL_OK);
    printf("city scene: %zu objects, frustum keeps %zu (model %zu, spheres alone %u), %u of %u cells culled\n",
           sf.nobjects, n, model, st.after_spheres, st.cells_culled, st.cells);
    assert_int_equal(n, model);
    assert_int_equal(model, 5731);
    free(res);
    cull_ctx_destroy(c);
    cull_world_destroy(w);
    scene_file_free(&sf);
}

/* The pool runs each slot 0..n-1 of a job exactly once, with that job's
 * arg, whoever takes it: 20,000 jobs of 1..5 slots on 4 threads (on this
 * 2-core machine, workers are often not running when a job starts, so the
 * caller takes their slots, and wake to find the next job). */
typedef struct pool_job {
    uint32_t id;
    _Atomic uint32_t ran[8];
    _Atomic uint32_t wrong;
    const uint32_t *cur;
} pool_job;

static void pool_slot(void *arg, uint32_t t)
{
    pool_job *j = arg;
    if (t >= 8 || *j->cur != j->id) atomic_fetch_add(&j->wrong, 1);
    else atomic_fetch_add(&j->ran[t], 1);
}

static void test_pool_runs_each_slot_once(void **state)
{
    (void)state;
    cull_pool *pool;
    assert_int_equal(cull_pool_create(4, &pool), CULL_OK);
    uint32_t cur = 0, bad = 0;
    for (uint32_t i = 0; i < 20000; i++) {
        pool_job j = {.id = i, .cur = &cur};
        cur = i;
        uint32_t n = 1 + i % 5, want = n < 4 ? n : 4;
        cull_pool_run(pool, pool_slot, &j, n);
        cur = UINT32_MAX; /* a slot run after the job returned would see this */
        for (uint32_t t = 0; t < 8; t++) bad += atomic_load(&j.ran[t]) != (t < want);
        bad += atomic_load(&j.wrong);
    }
    cull_pool_destroy(pool);
    assert_int_equal(bad, 0);
}

/* cull_pool_each_side runs every item once and the side job exactly
 * once, before the job returns, for 0..40 items on 1..4 threads (and no
 * pool); cull_pool_each no side job. */
typedef struct each_t {
    _Atomic uint32_t item[41];
    _Atomic uint32_t side;
    const uint32_t *cur;
    uint32_t id;
    _Atomic uint32_t wrong;
} each_t;

static void each_item(void *arg, uint32_t k)
{
    each_t *e = arg;
    if (k >= 41 || *e->cur != e->id) atomic_fetch_add(&e->wrong, 1);
    else atomic_fetch_add(&e->item[k], 1);
}

static void each_side(void *arg)
{
    each_t *e = arg;
    if (*e->cur != e->id) atomic_fetch_add(&e->wrong, 1);
    atomic_fetch_add(&e->side, 1);
}

static void test_pool_each_side(void **state)
{
    (void)state;
    cull_pool *pool;
    assert_int_equal(cull_pool_create(4, &pool), CULL_OK);
    uint32_t cur = 0, bad = 0;
    for (uint32_t i = 0; i < 4000; i++) {
        each_t e = {.cur = &cur, .id = i};
        cur = i;
        const uint32_t n = i % 41, threads = i % 5;
        const bool side = i % 3 != 0;
        cull_pool *p = i % 7 == 0 ? NULL : pool;
        if (side) cull_pool_each_side(p, threads, n, each_item, &e, each_side, &e);
        else cull_pool_each(p, threads, n, each_item, &e);
        cur = UINT32_MAX;
        for (uint32_t k = 0; k < 41; k++) bad += atomic_load(&e.item[k]) != (k < n);
        bad += atomic_load(&e.side) != (side ? 1u : 0u);
        bad += atomic_load(&e.wrong);
    }
    cull_pool_destroy(pool);
    assert_int_equal(bad, 0);
}

const struct CMUnitTest query_tests[] = {
    cmocka_unit_test(test_pool_runs_each_slot_once),
    cmocka_unit_test(test_pool_each_side),
    cmocka_unit_test(test_bad_queries),
    cmocka_unit_test(test_far_camera_is_exact),
    cmocka_unit_test(test_city_scene),
    cmocka_unit_test(test_random_vs_model),
};
const size_t query_tests_count = sizeof query_tests / sizeof query_tests[0];
