/*
 * test_occlusion.c — software occlusion against an independent model: the
 * double-precision ray caster of tests/occ_ref.c.
 *
 * The property: the occlusion stage never culls an entity the exact caster
 * sees. With the default coverage (pixels covered whole) that must hold
 * for a caster of any resolution (checked at 3x the buffer's size in each
 * direction, nine samples per buffer pixel); with centre coverage, for a
 * caster of the buffer's own size. Random scenes: boxes (axis-aligned and
 * rotated), triangle soups with slivers and degenerate triangles, height
 * fields, walls through the near plane; random cameras, some inside
 * boxes, some 1e5 m from the origin, perspective (finite and infinite far,
 * every depth mode) and orthographic; every ISA; 1 and 2 threads. And the
 * stage must be worth having: over the run it culls most of what the
 * caster hides.
 */
#include "test_util.h"

#include "cull_ref.h"
#include "cull_occ.h" /* the buffer's layout and per-ISA tests: test_occ_wide_matches_scalar */
#include "occ_ref.h"
#include <float.h>
#include <stdbool.h>
#include <stdio.h>
#include <string.h>

/* ---- scenes ---------------------------------------------------------------------- */

typedef struct oscene {
    cull_world *w;
    double *tri;           /* every occluder triangle, world space, for the caster */
    size_t ntri, cap;
    cull_entity_desc *e;
    cull_handle *h;
    uint32_t n;
    double base[3];        /* where the scene is, far from the origin or not */
    double boxes[64][6];   /* occluder boxes' world AABBs (cameras go inside some) */
    uint32_t nboxes;
} oscene;

static void push_tri(oscene *s, const double *p)
{
    if (s->ntri == s->cap) {
        s->cap = s->cap ? 2 * s->cap : 256;
        s->tri = realloc(s->tri, s->cap * 9 * sizeof *s->tri);
        assert_non_null(s->tri);
    }
    memcpy(s->tri + 9 * s->ntri++, p, 9 * sizeof *p);
}

/* The 12 triangles of the unit cube [-1,1]^3, counter-clockwise seen from
 * outside, as 36 vertices. */
static void unit_cube(float v[108])
{
    static const int face[6][4] = {
        {0, 4, 6, 2}, /* -x */ {1, 3, 7, 5}, /* +x */ {0, 1, 5, 4}, /* -y */
        {2, 6, 7, 3}, /* +y */ {0, 2, 3, 1}, /* -z */ {4, 5, 7, 6}, /* +z */
    };
    int k = 0;
    for (int f = 0; f < 6; f++) {
        const int tri[2][3] = {{face[f][0], face[f][1], face[f][2]}, {face[f][0], face[f][2], face[f][3]}};
        for (int t = 0; t < 2; t++)
            for (int i = 0; i < 3; i++) {
                int c = tri[t][i];
                v[k++] = (c & 1) ? 1.0f : -1.0f;
                v[k++] = (c & 2) ? 1.0f : -1.0f;
                v[k++] = (c & 4) ? 1.0f : -1.0f;
            }
    }
}

/* Applies the occluder transform the way the core documents it. */
static void xform(const double m[16], const float *p, double *o)
{
    for (int a = 0; a < 3; a++) o[a] = m[a] * p[0] + m[4 + a] * p[1] + m[8 + a] * p[2] + m[12 + a];
}

static void random_rotation(rng *r, double m[16], const double scale[3], const double at[3])
{
    /* a random unit quaternion */
    double q[4], l = 0;
    for (int i = 0; i < 4; i++) {
        q[i] = rng_range(r, -1, 1);
        l += q[i] * q[i];
    }
    l = sqrt(l);
    for (int i = 0; i < 4; i++) q[i] /= l;
    double x = q[0], y = q[1], z = q[2], w = q[3];
    double R[3][3] = {{1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)},
                      {2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)},
                      {2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)}};
    memset(m, 0, 16 * sizeof *m);
    for (int c = 0; c < 3; c++)
        for (int rr = 0; rr < 3; rr++) m[c * 4 + rr] = R[rr][c] * scale[c];
    for (int a = 0; a < 3; a++) m[12 + a] = at[a];
    m[15] = 1;
}

static void add_box(rng *r, oscene *s, bool rotated)
{
    float v[108];
    unit_cube(v);
    double half[3], at[3], m[16] = {0};
    for (int a = 0; a < 3; a++) {
        half[a] = rng_log(r, 0.3, 25);
        at[a] = s->base[a] + rng_range(r, -60, 60);
    }
    if (rotated) {
        random_rotation(r, m, half, at);
    } else {
        for (int a = 0; a < 3; a++) {
            m[a * 5] = half[a];
            m[12 + a] = at[a];
        }
        m[15] = 1;
    }
    cull_occluder_desc d = {.vertices = v, .vertex_count = 36};
    memcpy(d.transform, m, sizeof m);
    cull_occluder h;
    assert_int_equal(cull_occluder_add(s->w, &d, &h), CULL_OK);
    cull_occluder_info info;
    assert_int_equal(cull_occluder_get_info(s->w, h, &info), CULL_OK);
    assert_int_equal(info.triangles, 12);
    assert_int_equal(info.dropped, 0);
    assert_int_equal(info.faces, 6); /* each side one quad, rotated or not */
    assert_int_equal(info.convex_clusters, 1); /* drawn as one silhouette */
    for (int t = 0; t < 12; t++) {
        double p[9];
        for (int i = 0; i < 3; i++) xform(m, v + 9 * t + 3 * i, p + 3 * i);
        push_tri(s, p);
    }
    if (s->nboxes < 64) {
        double *b = s->boxes[s->nboxes++];
        memcpy(b, info.aabb_min, 3 * sizeof *b);
        memcpy(b + 3, info.aabb_max, 3 * sizeof *b);
    }
}

/* Random triangles, some slivers, some collapsed to a segment or a point. */
static void add_soup(rng *r, oscene *s)
{
    uint32_t n = 1 + rng_below(r, 6);
    float v[6 * 9];
    double c[3];
    for (int a = 0; a < 3; a++) c[a] = rng_range(r, -60, 60);
    uint32_t degenerate = 0;
    for (uint32_t t = 0; t < n; t++) {
        for (int i = 0; i < 9; i++) v[9 * t + i] = (float)(c[i % 3] + rng_range(r, -15, 15));
        uint32_t kind = rng_below(r, 8);
        if (kind == 0) { /* collapse to a point */
            for (int i = 3; i < 9; i++) v[9 * t + i] = v[9 * t + i % 3];
            degenerate++;
        } else if (kind == 1) { /* exact copy of one edge: a segment */
            for (int i = 0; i < 3; i++) v[9 * t + 6 + i] = v[9 * t + i];
            degenerate++;
        }
    }
    double m[16] = {0};
    m[0] = m[5] = m[10] = m[15] = 1;
    for (int a = 0; a < 3; a++) m[12 + a] = s->base[a];
    cull_occluder_desc d = {.vertices = v, .vertex_count = 3 * n};
    memcpy(d.transform, m, sizeof m);
    cull_occluder h;
    assert_int_equal(cull_occluder_add(s->w, &d, &h), CULL_OK);
    cull_occluder_info info;
    assert_int_equal(cull_occluder_get_info(s->w, h, &info), CULL_OK);
    assert_true(info.dropped >= degenerate);
    assert_int_equal(info.triangles + info.dropped, n);
    for (uint32_t t = 0; t < n; t++) {
        double p[9];
        for (int i = 0; i < 3; i++) xform(m, v + 9 * t + 3 * i, p + 3 * i);
        push_tri(s, p);
    }
}

static void add_terrain(rng *r, oscene *s)
{
    uint32_t nx = 2 + rng_below(r, 12), nz = 2 + rng_below(r, 12);
    float *h = malloc((size_t)nx * nz * sizeof *h);
    assert_non_null(h);
    for (uint32_t i = 0; i < nx * nz; i++) h[i] = (float)rng_range(r, -3, 8);
    cull_terrain_desc d = {.heights = h, .nx = nx, .nz = nz, .spacing = rng_log(r, 1, 12)};
    for (int a = 0; a < 3; a++) d.origin[a] = s->base[a] + rng_range(r, -80, 20);
    cull_occluder oh;
    assert_int_equal(cull_terrain_add(s->w, &d, &oh), CULL_OK);
    for (uint32_t z = 0; z + 1 < nz; z++)
        for (uint32_t x = 0; x + 1 < nx; x++) {
            double q[4][3];
            for (int k = 0; k < 4; k++) {
                uint32_t xi = x + (k & 1), zi = z + (k >> 1);
                q[k][0] = d.origin[0] + xi * d.spacing;
                q[k][1] = d.origin[1] + h[zi * nx + xi];
                q[k][2] = d.origin[2] + zi * d.spacing;
            }
            /* (x,z) (x,z+1) (x+1,z) and (x+1,z) (x,z+1) (x+1,z+1): up-facing */
            double t0[9], t1[9];
            memcpy(t0, q[0], 24);
            memcpy(t0 + 3, q[2], 24);
            memcpy(t0 + 6, q[1], 24);
            memcpy(t1, q[1], 24);
            memcpy(t1 + 3, q[2], 24);
            memcpy(t1 + 6, q[3], 24);
            push_tri(s, t0);
            push_tri(s, t1);
        }
    free(h);
}

static void add_entities(rng *r, oscene *s, uint32_t n)
{
    s->n = n;
    s->e = calloc(n, sizeof *s->e);
    s->h = calloc(n, sizeof *s->h);
    assert_non_null(s->e);
    assert_non_null(s->h);
    for (uint32_t i = 0; i < n; i++) {
        cull_entity_desc *e = &s->e[i];
        for (int a = 0; a < 3; a++) {
            double c = s->base[a] + rng_range(r, -90, 90), hs = rng_log(r, 0.02, 6);
            e->aabb_min[a] = c - hs;
            e->aabb_max[a] = c + hs;
        }
        e->flags = rng_below(r, 4) == 0 ? CULL_ENTITY_DYNAMIC : 0;
        assert_int_equal(cull_entity_add(s->w, e, &s->h[i]), CULL_OK);
        assert_int_equal(cull_entity_get(s->w, s->h[i], e), CULL_OK);
    }
}

static void build_scene(rng *r, oscene *s)
{
    memset(s, 0, sizeof *s);
    if (rng_below(r, 3) == 0)
        for (int a = 0; a < 3; a++) s->base[a] = rng_range(r, -2e5, 2e5);
    assert_int_equal(cull_world_create(NULL, &s->w), CULL_OK);
    uint32_t nb = 6 + rng_below(r, 30);
    for (uint32_t i = 0; i < nb; i++) add_box(r, s, rng_below(r, 3) == 0);
    for (uint32_t i = rng_below(r, 3); i > 0; i--) add_soup(r, s);
    if (rng_below(r, 2)) add_terrain(r, s);
    add_entities(r, s, 300 + rng_below(r, 500));
}

static void free_scene(oscene *s)
{
    cull_world_destroy(s->w);
    free(s->tri);
    free(s->e);
    free(s->h);
}

static void random_view(rng *r, const oscene *s, cull_view *v, uint32_t bw, uint32_t bh)
{
    for (;;) {
        cull_view_desc d = {.depth_mode = rng_below(r, 3), .viewport_w = bw, .viewport_h = bh};
        if (s->nboxes && rng_below(r, 6) == 0) {
            /* inside an occluder box */
            const double *b = s->boxes[rng_below(r, s->nboxes)];
            for (int a = 0; a < 3; a++) d.origin[a] = 0.5 * (b[a] + b[a + 3]);
        } else {
            for (int a = 0; a < 3; a++) d.origin[a] = s->base[a] + rng_range(r, -100, 100);
        }
        double dir[3], up[3] = {0, 1, 0}, proj[16], view[16];
        /* mostly toward the middle of the scene, where the occluders are */
        bool aim = rng_below(r, 4) != 0;
        for (int a = 0; a < 3; a++)
            dir[a] = aim ? s->base[a] + rng_range(r, -30, 30) - d.origin[a] : rng_range(r, -1, 1);
        if (fabs(dir[0]) + fabs(dir[2]) < 1e-3) continue;
        double aspect = (double)bw / bh;
        if (rng_below(r, 5) == 0) {
            double hw = rng_log(r, 5, 200);
            cull_mat_ortho(proj, -hw, hw, -hw / aspect, hw / aspect, rng_range(r, -50, 1), rng_range(r, 60, 400),
                           d.depth_mode);
        } else {
            double n = rng_log(r, 1e-3, 2);
            double f = rng_below(r, 3) == 0 ? INFINITY : rng_log(r, 50, 1e4);
            cull_mat_perspective(proj, rng_range(r, 0.3, 1.9), aspect, n, f, d.depth_mode);
        }
        cull_mat_look_dir(view, dir, up);
        cull_mat_mul(d.view_proj, proj, view);
        if (cull_view_init(v, &d) == CULL_OK) return;
    }
}

/* ---- the property ----------------------------------------------------------------- */

typedef struct otally {
    uint64_t queries, survivors, occ_culled, hidden_exact, hidden_culled, false_occluded;
} otally;

static uint32_t slot_of(cull_handle h)
{
    return h & (CULL_MAX_ENTITIES - 1);
}

/* One view: the frustum survivors, the query with occlusion, and the
 * caster's verdict on every entity occlusion removed. */
static void check_view(const oscene *s, cull_ctx *c, const cull_view *v, uint32_t bw, uint32_t bh, uint32_t cover,
                       uint32_t threads, otally *t)
{
    size_t cap = cull_query_bound(s->w), n0, n1;
    cull_result *r0 = malloc(cap * sizeof *r0), *r1 = malloc(cap * sizeof *r1);
    assert_non_null(r0);
    assert_non_null(r1);
    cull_query_desc q = {.views = v, .view_count = 1, .threads = threads, .flags = CULL_Q_NO_OCCLUSION};
    assert_int_equal(cull_query(s->w, c, &q, r0, cap, &n0, NULL), CULL_OK);
    q.flags = cover == CULL_OCC_COVER_CENTRE ? CULL_Q_OCC_CENTRE : 0;
    q.occ_w = bw;
    q.occ_h = bh;
    cull_query_stats st;
    assert_int_equal(cull_query(s->w, c, &q, r1, cap, &n1, &st), CULL_OK);
    assert_true(n1 <= n0);
    assert_int_equal(st.visible, n1);

    uint8_t *kept = calloc(s->n, 1);
    assert_non_null(kept);
    for (size_t i = 0; i < n1; i++) {
        assert_true(slot_of(r1[i].handle) < s->n);
        kept[slot_of(r1[i].handle)] = 1;
    }
    /* the caster: at the buffer's size for centre coverage, at 3x for
       whole-pixel coverage (nine samples per buffer pixel) */
    uint32_t k = cover == CULL_OCC_COVER_CENTRE ? 1 : 3;
    occ_ref ref;
    assert_int_equal(occ_ref_init(&ref, v, bw * k, bh * k), 0);
    occ_ref_add_triangles(&ref, s->tri, s->ntri);
    occ_ref exact;
    bool have_exact = false;
    for (size_t i = 0; i < n0; i++) {
        uint32_t e = slot_of(r0[i].handle);
        t->survivors++;
        if (kept[e]) continue;
        t->occ_culled++;
        const cull_entity_desc *d = &s->e[e];
        if (occ_ref_box_visible(&ref, d->aabb_min, d->aabb_max)) {
            t->false_occluded++;
            if (t->false_occluded < 6)
                fprintf(stderr, "false occluded: entity %u box %g %g %g / %g %g %g cover %u buffer %ux%u mode %u\n",
                        e, d->aabb_min[0], d->aabb_min[1], d->aabb_min[2], d->aabb_max[0], d->aabb_max[1],
                        d->aabb_max[2], cover, bw, bh, v->depth_mode);
        }
    }
    /* how much of what the occluders hide from a caster of the buffer's
       size was culled (entities no pixel centre sees at all do not count) */
    occ_ref bare;
    assert_int_equal(occ_ref_init(&bare, v, bw, bh), 0);
    if (k != 1) {
        assert_int_equal(occ_ref_init(&exact, v, bw, bh), 0);
        occ_ref_add_triangles(&exact, s->tri, s->ntri);
        have_exact = true;
    }
    for (size_t i = 0; i < n0; i++) {
        uint32_t e = slot_of(r0[i].handle);
        const cull_entity_desc *d = &s->e[e];
        if (occ_ref_box_visible(&bare, d->aabb_min, d->aabb_max) &&
            !occ_ref_box_visible(have_exact ? &exact : &ref, d->aabb_min, d->aabb_max)) {
            t->hidden_exact++;
            if (!kept[e]) t->hidden_culled++;
        }
    }
    occ_ref_free(&bare);
    if (have_exact) occ_ref_free(&exact);
    occ_ref_free(&ref);
    t->queries++;
    free(kept);
    free(r0);
    free(r1);
}

/* Random scenes, each under every supported ISA with its own context,
 * each with `views` buffer sizes (16..95 x 8..63): while
 * (scene_walk_next(&w)) runs its body once per view, with w.s, w.c, w.bw
 * and w.bh. The random numbers are drawn in that order, the scene first. */
typedef struct scene_walk {
    rng *r;
    cull_pool *pool;
    uint32_t scenes, views;
    uint32_t sc, isa, k; /* where it is */
    bool in_scene;
    oscene s;
    cull_ctx *c;
    uint32_t bw, bh;
} scene_walk;

static bool scene_walk_next(scene_walk *w)
{
    while (!w->c || w->k == w->views) {
        if (w->c) {
            cull_ctx_destroy(w->c);
            w->c = NULL;
            w->isa++;
        }
        while (w->in_scene && w->isa < CULL_ISA_COUNT && !cull_isa_supported(w->isa)) w->isa++;
        if (!w->in_scene || w->isa == CULL_ISA_COUNT) {
            if (w->in_scene) free_scene(&w->s), w->sc++;
            w->in_scene = false;
            if (w->sc == w->scenes) return false;
            build_scene(w->r, &w->s);
            w->in_scene = true;
            w->isa = 0;
            continue;
        }
        assert_int_equal(cull_ctx_create(w->pool, &w->c), CULL_OK);
        assert_int_equal(cull_ctx_set_isa(w->c, w->isa), CULL_OK);
        w->k = 0;
    }
    w->k++;
    w->bw = 16 + rng_below(w->r, 80);
    w->bh = 8 + rng_below(w->r, 56);
    return true;
}

static void test_random_scenes_never_false_occluded(void **state)
{
    (void)state;
    rng r = {test_seed() ^ 0x0CC1u};
    cull_pool *pool;
    assert_int_equal(cull_pool_create(2, &pool), CULL_OK);
    uint32_t scenes = (uint32_t)(60 * test_scale());
    otally t[2] = {{0}};
    scene_walk it = {.r = &r, .pool = pool, .scenes = scenes, .views = 3};
    while (scene_walk_next(&it)) {
        cull_view v;
        random_view(&r, &it.s, &v, it.bw, it.bh);
        uint32_t cover = rng_below(&r, 2);
        check_view(&it.s, it.c, &v, it.bw, it.bh, cover, 1 + rng_below(&r, 2), &t[cover]);
    }
    for (int cover = 0; cover < 2; cover++)
        fprintf(stderr, "occlusion (%s): %llu views, %llu frustum survivors, %llu culled by occlusion; of %llu "
                        "the occluders hide from an exact caster of the buffer's size, %llu culled; %llu false "
                        "occluded\n",
                cover ? "centre" : "inner", (unsigned long long)t[cover].queries,
                (unsigned long long)t[cover].survivors, (unsigned long long)t[cover].occ_culled,
                (unsigned long long)t[cover].hidden_exact, (unsigned long long)t[cover].hidden_culled,
                (unsigned long long)t[cover].false_occluded);
    for (int cover = 0; cover < 2; cover++) {
        assert_int_equal(t[cover].false_occluded, 0);
        /* not vacuous: much of what is hidden gets culled (whole-pixel
           coverage loses the edge pixels of each polygon, a lot in these
           16..96-pixel buffers) */
        assert_true(t[cover].hidden_culled * (cover ? 2 : 3) > t[cover].hidden_exact);
    }
    cull_pool_destroy(pool);
}

/* ---- adversarial views (issue 18) ---------------------------------------------- */

/* A term of either sign from 1e-300 to 1e30, log-uniform: the cross terms
 * a hand-made or hostile view-projection may carry. */
static double adv_term(rng *r)
{
    double t = pow(10, rng_range(r, -300, 30));
    return rng_below(r, 2) ? t : -t;
}

/* A view a decoder accepts (cull_view_init says OK) but that is built to
 * break the rasteriser's arithmetic: the eye on the plane of an occluder
 * box's face (level with its base, as a street-level camera is), tiny and
 * huge cross terms in the up vector and in the matrix, near 1e-6, far 1e30
 * or infinite, rows nearly dependent. false if the view was refused. */
static bool adversarial_view(rng *r, const oscene *s, cull_view *v, cull_view_desc *out, uint32_t bw, uint32_t bh)
{
    cull_view_desc d = {.depth_mode = rng_below(r, 3), .viewport_w = bw, .viewport_h = bh};
    const double *box = s->nboxes ? s->boxes[rng_below(r, s->nboxes)] : NULL;
    if (box && rng_below(r, 5) != 0) {
        for (int a = 0; a < 3; a++) d.origin[a] = box[a] + rng_range(r, -2, 3) * (box[a + 3] - box[a]);
        int a = rng_below(r, 4) ? 1 : (int)rng_below(r, 3); /* mostly level with the base or top */
        d.origin[a] = box[a + 3 * rng_below(r, 2)];
    } else {
        for (int a = 0; a < 3; a++) d.origin[a] = s->base[a] + rng_range(r, -100, 100);
    }
    double dir[3], up[3] = {0, 1, 0}, proj[16], view[16];
    for (int a = 0; a < 3; a++)
        dir[a] = (box ? 0.5 * (box[a] + box[a + 3]) : s->base[a]) + rng_range(r, -3, 3) - d.origin[a];
    if (rng_below(r, 3)) dir[1] = rng_below(r, 2) ? 0 : dir[1] * 1e-12; /* horizontal: along the planes */
    if (rng_below(r, 4)) up[rng_below(r, 3)] += adv_term(r);
    if (fabs(dir[0]) + fabs(dir[1]) + fabs(dir[2]) < 1e-9) return false;
    double aspect = (double)bw / bh;
    if (rng_below(r, 6) == 0) {
        double hw = rng_log(r, 1e-3, 1e6);
        cull_mat_ortho(proj, -hw, hw, -hw / aspect, hw / aspect, -rng_log(r, 1e-6, 1e3), rng_log(r, 1, 1e30),
                       d.depth_mode);
    } else {
        double n = rng_below(r, 2) ? 1e-6 : rng_log(r, 1e-6, 2);
        uint32_t fk = rng_below(r, 3);
        double f = fk == 0 ? INFINITY : fk == 1 ? 1e30 : rng_log(r, 10, 1e30);
        cull_mat_perspective(proj, rng_range(r, 0.05, 3.0), aspect, n, f, d.depth_mode);
    }
    cull_mat_look_dir(view, dir, up);
    cull_mat_mul(d.view_proj, proj, view);
    /* cross terms straight into the matrix */
    for (uint32_t k = rng_below(r, 4); k > 0; k--) {
        uint32_t i = rng_below(r, 16);
        if (rng_below(r, 2)) d.view_proj[i] += adv_term(r);
        else d.view_proj[i] = adv_term(r);
    }
    /* nearly singular: one row almost a multiple of another */
    if (rng_below(r, 6) == 0) {
        uint32_t i = rng_below(r, 4), j = (i + 1 + rng_below(r, 3)) % 4;
        double f = rng_range(r, -2, 2), e = pow(10, -rng_range(r, 6, 14));
        for (int c = 0; c < 4; c++) d.view_proj[c * 4 + i] = f * d.view_proj[c * 4 + j] + e * d.view_proj[c * 4 + i];
    }
    *out = d;
    return cull_view_init(v, &d) == CULL_OK;
}

/* Adversarial views: the frustum stage against the long-double model
 * (tests/cull_ref.c: nothing it keeps is culled), occlusion against the
 * ray caster (check_view: nothing it sees is culled), and a directly
 * rendered buffer keeps its padding columns and holds no NaN (with ASan,
 * any write outside the buffer is caught too). Before the fix, the eye on
 * an occluder's base with a tiny cross term crashed write_span (issue 18). */
static void test_adversarial_views_never_false_culled(void **state)
{
    (void)state;
    rng r = {test_seed() ^ 0xAD5E4u};
    cull_pool *pool;
    assert_int_equal(cull_pool_create(2, &pool), CULL_OK);
    uint32_t scenes = (uint32_t)(12 * test_scale());
    otally t[2] = {{0}};
    uint64_t tried = 0, accepted = 0, frustum_checked = 0, frustum_false = 0;
    scene_walk it = {.r = &r, .pool = pool, .scenes = scenes, .views = 12};
    while (scene_walk_next(&it)) {
        cull_view v;
        cull_view_desc d;
        tried++;
        if (!adversarial_view(&r, &it.s, &v, &d, it.bw, it.bh)) continue;
        accepted++;
        /* the frustum stage: every entity the model keeps is kept */
        size_t cap = cull_query_bound(it.s.w), n0;
        cull_result *res = malloc(cap * sizeof *res);
        uint8_t *kept = calloc(it.s.n, 1);
        assert_non_null(res);
        assert_non_null(kept);
        cull_query_desc q = {.views = &v, .view_count = 1, .flags = CULL_Q_NO_OCCLUSION};
        assert_int_equal(cull_query(it.s.w, it.c, &q, res, cap, &n0, NULL), CULL_OK);
        for (size_t i = 0; i < n0; i++) kept[slot_of(res[i].handle)] = 1;
        ref_view rv;
        ref_view_make(&rv, &d);
        for (uint32_t e = 0; e < it.s.n; e++) {
            ref_verdict rr;
            ref_test(&rv, &it.s.e[e], &rr);
            frustum_checked++;
            if (rr.visible && !kept[e] && ++frustum_false < 6)
                fprintf(stderr, "frustum false cull: entity %u view %g %g %g ... origin %g %g %g\n", e,
                        d.view_proj[0], d.view_proj[1], d.view_proj[2], d.origin[0], d.origin[1],
                        d.origin[2]);
        }
        free(kept);
        free(res);
        uint32_t cover = rng_below(&r, 2);
        check_view(&it.s, it.c, &v, it.bw, it.bh, cover, 1 + rng_below(&r, 2), &t[cover]);
        /* a buffer rendered directly: padding intact, no NaN */
        cull_occ_buffer *b;
        assert_int_equal(cull_occ_buffer_create(it.bw, it.bh, &b), CULL_OK);
        assert_int_equal(cull_occ_buffer_set_cover(b, cover), CULL_OK);
        assert_int_equal(cull_occ_render(it.s.w, &v, b, pool, 2, NULL), CULL_OK);
        uint32_t ww, hh;
        size_t stride;
        const float *z = cull_occ_depth(b, &ww, &hh, &stride);
        assert_non_null(z);
        for (uint32_t y = 0; y < hh; y++)
            for (size_t x = 0; x < stride; x++) {
                float f = z[y * stride + x];
                if (x >= ww) assert_true(f == FLT_MAX);
                else assert_false(isnan(f));
            }
        cull_occ_buffer_destroy(b);
    }
    fprintf(stderr, "adversarial views: %llu tried, %llu accepted; frustum: %llu entity tests, %llu false culls; "
                    "occlusion: %llu + %llu views, %llu + %llu culled, %llu + %llu false occluded\n",
            (unsigned long long)tried, (unsigned long long)accepted, (unsigned long long)frustum_checked,
            (unsigned long long)frustum_false, (unsigned long long)t[0].queries, (unsigned long long)t[1].queries,
            (unsigned long long)t[0].occ_culled, (unsigned long long)t[1].occ_culled,
            (unsigned long long)t[0].false_occluded, (unsigned long long)t[1].false_occluded);
    assert_true(accepted * 2 > tried); /* most views are decoded-valid */
    assert_int_equal(frustum_false, 0);
    assert_int_equal(t[0].false_occluded, 0);
    assert_int_equal(t[1].false_occluded, 0);
    cull_pool_destroy(pool);
}

/* A camera inside a closed box sees only back faces: nothing is drawn,
 * nothing is culled, even entities behind the box's far wall. */
static void test_camera_inside_occluder(void **state)
{
    (void)state;
    cull_world *w;
    assert_int_equal(cull_world_create(NULL, &w), CULL_OK);
    float v[108];
    unit_cube(v);
    double m[16] = {10, 0, 0, 0, 0, 10, 0, 0, 0, 0, 10, 0, 0, 0, 0, 1};
    cull_occluder_desc d = {.vertices = v, .vertex_count = 36};
    memcpy(d.transform, m, sizeof m);
    cull_occluder oh;
    assert_int_equal(cull_occluder_add(w, &d, &oh), CULL_OK);
    cull_handle eh[3];
    const double z[3] = {-5, -30, -100};
    for (int i = 0; i < 3; i++) {
        cull_entity_desc e = {.center = {0, 0, z[i]}, .radius = 1};
        assert_int_equal(cull_entity_add(w, &e, &eh[i]), CULL_OK);
    }
    cull_view_desc vd = {.viewport_w = 256, .viewport_h = 114};
    double proj[16], view[16], dir[3] = {0, 0, -1}, up[3] = {0, 1, 0};
    cull_mat_perspective(proj, 1.0, 256.0 / 114, 0.1, 1000, CULL_DEPTH_GL);
    cull_mat_look_dir(view, dir, up);
    cull_mat_mul(vd.view_proj, proj, view);
    cull_view cv;
    assert_int_equal(cull_view_init(&cv, &vd), CULL_OK);
    cull_occ_buffer *b;
    assert_int_equal(cull_occ_buffer_create(256, 114, &b), CULL_OK);
    cull_occ_stats st;
    assert_int_equal(cull_occ_render(w, &cv, b, NULL, 1, &st), CULL_OK);
    assert_true(cull_occ_buffer_empty(b));
    assert_int_equal(st.faces_drawn, 0);
    cull_ctx *c;
    assert_int_equal(cull_ctx_create(NULL, &c), CULL_OK);
    cull_result res[16];
    size_t n;
    assert_int_equal(cull_query(w, c, &(cull_query_desc){.views = &cv, .view_count = 1}, res, 16, &n, NULL),
                     CULL_OK);
    assert_int_equal(n, 3);
    /* from outside, in front of the box, the far entities are hidden */
    vd.origin[2] = 20;
    assert_int_equal(cull_view_init(&cv, &vd), CULL_OK);
    assert_int_equal(cull_query(w, c, &(cull_query_desc){.views = &cv, .view_count = 1}, res, 16, &n, NULL),
                     CULL_OK);
    assert_int_equal(n, 0);
    assert_int_equal(cull_occ_render(w, &cv, b, NULL, 1, &st), CULL_OK);
    assert_false(cull_occ_buffer_empty(b));
    for (int i = 0; i < 3; i++) {
        cull_entity_desc e;
        assert_int_equal(cull_entity_get(w, eh[i], &e), CULL_OK);
        assert_int_equal(cull_occ_test_aabb(b, e.aabb_min, e.aabb_max), 0);
    }
    cull_occ_buffer_destroy(b);
    cull_ctx_destroy(c);
    cull_world_destroy(w);
}

/* A wall that passes through the near plane and behind the eye: the part
 * in front is drawn, clipped exactly; what it hides is culled, nothing
 * the caster sees is. */
static void test_wall_through_near_plane(void **state)
{
    (void)state;
    rng r = {test_seed() ^ 0xFA11u};
    for (int rep = 0; rep < 20; rep++) {
        oscene s;
        memset(&s, 0, sizeof s);
        assert_int_equal(cull_world_create(NULL, &s.w), CULL_OK);
        /* a slanted quad from behind the eye (z = +5) to z = -20 */
        double zb = rng_range(&r, 0.5, 8), zf = rng_range(&r, -40, -5), x = rng_range(&r, 5, 40);
        float q[18] = {(float)-x, -20, (float)zb, (float)x, -20, (float)zf, (float)x, 20, (float)zf,
                       (float)-x, -20, (float)zb, (float)x, 20, (float)zf, (float)-x, 20, (float)zb};
        cull_occluder_desc d = {.vertices = q, .vertex_count = 6};
        cull_occluder oh;
        assert_int_equal(cull_occluder_add(s.w, &d, &oh), CULL_OK);
        cull_occluder_info info;
        assert_int_equal(cull_occluder_get_info(s.w, oh, &info), CULL_OK);
        assert_int_equal(info.faces, 1);
        assert_int_equal(info.convex_clusters, 0); /* not closed */
        for (int t = 0; t < 2; t++) {
            double p[9];
            for (int i = 0; i < 9; i++) p[i] = q[9 * t + i];
            push_tri(&s, p);
        }
        add_entities(&r, &s, 400);
        for (int k = 0; k < 4; k++) {
            cull_view_desc vd = {.viewport_w = 64, .viewport_h = 40, .depth_mode = rng_below(&r, 3)};
            double proj[16], view[16], dir[3] = {rng_range(&r, -0.3, 0.3), rng_range(&r, -0.3, 0.3), -1},
                                      up[3] = {0, 1, 0};
            cull_mat_perspective(proj, 1.2, 1.6, rng_log(&r, 0.01, 1), 500, vd.depth_mode);
            cull_mat_look_dir(view, dir, up);
            cull_mat_mul(vd.view_proj, proj, view);
            cull_view v;
            assert_int_equal(cull_view_init(&v, &vd), CULL_OK);
            cull_ctx *c;
            assert_int_equal(cull_ctx_create(NULL, &c), CULL_OK);
            otally t = {0};
            check_view(&s, c, &v, 64, 40, CULL_OCC_COVER_INNER, 1, &t);
            check_view(&s, c, &v, 64, 40, CULL_OCC_COVER_CENTRE, 1, &t);
            assert_int_equal(t.false_occluded, 0);
            cull_ctx_destroy(c);
        }
        free_scene(&s);
    }
}

/* Several views in one query give each view the answer it gets alone. */
static void test_multi_view_matches_single(void **state)
{
    (void)state;
    rng r = {test_seed() ^ 0x3u};
    oscene s;
    build_scene(&r, &s);
    cull_ctx *c;
    assert_int_equal(cull_ctx_create(NULL, &c), CULL_OK);
    cull_view v[5];
    for (int i = 0; i < 5; i++) random_view(&r, &s, &v[i], 200, 100);
    size_t cap = cull_query_bound(s.w), n;
    cull_result *all = malloc(cap * sizeof *all), *one = malloc(cap * sizeof *one);
    assert_non_null(all);
    assert_non_null(one);
    cull_query_desc q = {.views = v, .view_count = 5, .occ_w = 200, .occ_h = 100};
    cull_query_stats st;
    assert_int_equal(cull_query(s.w, c, &q, all, cap, &n, &st), CULL_OK);
    uint32_t *mask = calloc(s.n, sizeof *mask);
    for (size_t i = 0; i < n; i++) mask[slot_of(all[i].handle)] = all[i].view_mask;
    for (int i = 0; i < 5; i++) {
        size_t m;
        cull_query_desc q1 = {.views = &v[i], .view_count = 1, .occ_w = 200, .occ_h = 100};
        assert_int_equal(cull_query(s.w, c, &q1, one, cap, &m, NULL), CULL_OK);
        size_t in_all = 0;
        for (uint32_t e = 0; e < s.n; e++) in_all += (mask[e] >> i) & 1;
        assert_int_equal(in_all, m);
        for (size_t k = 0; k < m; k++) assert_true((mask[slot_of(one[k].handle)] >> i) & 1);
    }
    free(mask);
    free(all);
    free(one);
    cull_ctx_destroy(c);
    free_scene(&s);
}

/* Bad occluders: clear errors, and nothing changes. */
static void test_bad_occluders(void **state)
{
    (void)state;
    cull_world *w;
    assert_int_equal(cull_world_create(NULL, &w), CULL_OK);
    float v[108];
    unit_cube(v);
    cull_occluder good;
    assert_int_equal(cull_occluder_add(w, &(cull_occluder_desc){.vertices = v, .vertex_count = 36}, &good), CULL_OK);
    cull_occluder_info before, after;
    assert_int_equal(cull_occluder_get_info(w, good, &before), CULL_OK);

    cull_occluder h = 123;
    float bad[9] = {0, 0, 0, 1, 0, 0, 0, NAN, 0};
    assert_int_equal(cull_occluder_add(w, &(cull_occluder_desc){.vertices = bad, .vertex_count = 3}, &h),
                     CULL_ERR_NONFINITE);
    assert_int_equal(h, 0);
    bad[7] = INFINITY;
    assert_int_equal(cull_occluder_add(w, &(cull_occluder_desc){.vertices = bad, .vertex_count = 3}, &h),
                     CULL_ERR_NONFINITE);
    bad[7] = 1;
    assert_int_equal(cull_occluder_add(w, &(cull_occluder_desc){.vertices = bad, .vertex_count = 2}, &h),
                     CULL_ERR_MESH);
    assert_int_equal(cull_occluder_add(w, &(cull_occluder_desc){.vertices = NULL, .vertex_count = 3}, &h),
                     CULL_ERR_MESH);
    uint32_t idx[3] = {0, 1, 3};
    assert_int_equal(cull_occluder_add(w, &(cull_occluder_desc){.vertices = bad, .vertex_count = 3, .indices = idx,
                                                                .index_count = 3},
                                       &h),
                     CULL_ERR_MESH);
    idx[2] = 2;
    assert_int_equal(cull_occluder_add(w, &(cull_occluder_desc){.vertices = bad, .vertex_count = 3, .indices = idx,
                                                                .index_count = 2},
                                       &h),
                     CULL_ERR_MESH);
    cull_occluder_desc d = {.vertices = bad, .vertex_count = 3};
    d.transform[3] = 1; /* projective: not an affine transform */
    assert_int_equal(cull_occluder_add(w, &d, &h), CULL_ERR_MATRIX);
    d.transform[3] = NAN;
    assert_int_equal(cull_occluder_add(w, &d, &h), CULL_ERR_NONFINITE);
    memset(d.transform, 0, sizeof d.transform);
    d.transform[0] = d.transform[5] = d.transform[10] = d.transform[15] = 1;
    d.transform[12] = 2e12;
    assert_int_equal(cull_occluder_add(w, &d, &h), CULL_ERR_RANGE);
    /* all degenerate: accepted, every triangle dropped and counted, draws nothing */
    float line[9] = {0, 0, 0, 1, 1, 1, 2, 2, 2};
    assert_int_equal(cull_occluder_add(w, &(cull_occluder_desc){.vertices = line, .vertex_count = 3}, &h), CULL_OK);
    cull_occluder_info li;
    assert_int_equal(cull_occluder_get_info(w, h, &li), CULL_OK);
    assert_int_equal(li.triangles, 0);
    assert_int_equal(li.dropped, 1);
    assert_int_equal(li.clusters, 0);
    assert_int_equal(cull_occluder_remove(w, h), CULL_OK);
    assert_int_equal(cull_occluder_remove(w, h), CULL_ERR_HANDLE);
    assert_int_equal(cull_occluder_get_info(w, h, &li), CULL_ERR_HANDLE);
    assert_int_equal(cull_occluder_remove(w, 0), CULL_ERR_HANDLE);
    /* a failed update leaves the occluder as it was */
    assert_int_equal(cull_occluder_update(w, good, &(cull_occluder_desc){.vertices = bad, .vertex_count = 2}),
                     CULL_ERR_MESH);
    assert_int_equal(cull_occluder_get_info(w, good, &after), CULL_OK);
    assert_memory_equal(&before, &after, sizeof before);
    /* terrains */
    float hts[4] = {0, 1, 2, NAN};
    cull_terrain_desc td = {.heights = hts, .nx = 2, .nz = 2, .spacing = 1};
    assert_int_equal(cull_terrain_add(w, &td, &h), CULL_ERR_NONFINITE);
    hts[3] = 3;
    td.nx = 1;
    assert_int_equal(cull_terrain_add(w, &td, &h), CULL_ERR_MESH);
    td.nx = 2;
    td.spacing = 0;
    assert_int_equal(cull_terrain_add(w, &td, &h), CULL_ERR_INVALID);
    td.spacing = 2;
    assert_int_equal(cull_terrain_add(w, &td, &h), CULL_OK);
    assert_int_equal(cull_occluder_count(w), 2);
    assert_int_equal(cull_terrain_update(w, good, &td), CULL_OK); /* a mesh becomes a terrain */
    assert_int_equal(cull_occluder_get_info(w, good, &after), CULL_OK);
    assert_int_equal(after.triangles, 2);
    /* buffers */
    cull_occ_buffer *b = (cull_occ_buffer *)1;
    assert_int_equal(cull_occ_buffer_create(7, 100, &b), CULL_ERR_BUFFER);
    assert_null(b);
    assert_int_equal(cull_occ_buffer_create(100, 8193, &b), CULL_ERR_BUFFER);
    assert_int_equal(cull_occ_buffer_create(8, 8, &b), CULL_OK);
    assert_int_equal(cull_occ_buffer_set_cover(b, 7), CULL_ERR_INVALID);
    cull_occ_buffer_destroy(b);
    cull_world_destroy(w);
}

/* Edits show in the next query: remove the wall and the hidden come back;
 * replace it (destruction) by one with a hole and what is behind the hole
 * comes back too. */
static void test_edits_change_occlusion(void **state)
{
    (void)state;
    cull_world *w;
    assert_int_equal(cull_world_create(NULL, &w), CULL_OK);
    /* a wall at z = -10 facing +z, 40 x 40 m */
    float wall[18] = {-20, -20, -10, 20, -20, -10, 20, 20, -10, -20, -20, -10, 20, 20, -10, -20, 20, -10};
    cull_occluder oh;
    assert_int_equal(cull_occluder_add(w, &(cull_occluder_desc){.vertices = wall, .vertex_count = 6}, &oh), CULL_OK);
    cull_handle left, right;
    assert_int_equal(cull_entity_add(w, &(cull_entity_desc){.center = {-8, 0, -30}, .radius = 1}, &left), CULL_OK);
    assert_int_equal(cull_entity_add(w, &(cull_entity_desc){.center = {8, 0, -30}, .radius = 1}, &right), CULL_OK);
    cull_view_desc vd = {.viewport_w = 256, .viewport_h = 114};
    double proj[16], view[16], dir[3] = {0, 0, -1}, up[3] = {0, 1, 0};
    cull_mat_perspective(proj, 1.0, 256.0 / 114, 0.1, 1000, CULL_DEPTH_REVERSED);
    vd.depth_mode = CULL_DEPTH_REVERSED;
    cull_mat_look_dir(view, dir, up);
    cull_mat_mul(vd.view_proj, proj, view);
    cull_view v;
    assert_int_equal(cull_view_init(&v, &vd), CULL_OK);
    cull_ctx *c;
    assert_int_equal(cull_ctx_create(NULL, &c), CULL_OK);
    cull_result res[16];
    size_t n;
    cull_query_desc q = {.views = &v, .view_count = 1};
    assert_int_equal(cull_query(w, c, &q, res, 16, &n, NULL), CULL_OK);
    assert_int_equal(n, 0);
    /* the wall with a slot: quads left of x = 1.5 and right of x = 4.5 (the
       right entity, seen from the eye, crosses z = -10 at x = 2.3 .. 3.1) */
    float holed[36] = {-20,  -20, -10, 1.5f, -20, -10, 1.5f, 20, -10, -20,  -20, -10, 1.5f, 20, -10, -20,  20, -10,
                       4.5f, -20, -10, 20,   -20, -10, 20,   20, -10, 4.5f, -20, -10, 20,   20, -10, 4.5f, 20, -10};
    assert_int_equal(cull_occluder_update(w, oh, &(cull_occluder_desc){.vertices = holed, .vertex_count = 12}),
                     CULL_OK);
    assert_int_equal(cull_query(w, c, &q, res, 16, &n, NULL), CULL_OK);
    assert_int_equal(n, 1);
    assert_int_equal(res[0].handle, right);
    assert_int_equal(cull_occluder_remove(w, oh), CULL_OK);
    assert_int_equal(cull_query(w, c, &q, res, 16, &n, NULL), CULL_OK);
    assert_int_equal(n, 2);
    q.flags = CULL_Q_NO_OCCLUSION;
    assert_int_equal(cull_query(w, c, &q, res, 16, &n, NULL), CULL_OK);
    assert_int_equal(n, 2);
    (void)left;
    cull_ctx_destroy(c);
    cull_world_destroy(w);
}

/* Sub-levels: a query that sees only the set S of sub-levels equals a
 * query of a world holding only S's occluders (and every entity), its
 * results then kept to S by hand. Sub-level ids past 63 alias the cells'
 * 64-bit summaries on purpose. Counting, 1 and 2 threads, every ISA. */
static void test_sublevel_filter(void **state)
{
    (void)state;
    rng r = {test_seed() ^ 0x5B1u};
    static const uint16_t subs[] = {0, 1, 2, 65, 130, 4000};
    const uint32_t nsubs = sizeof subs / sizeof subs[0];
    cull_pool *pool;
    assert_int_equal(cull_pool_create(2, &pool), CULL_OK);
    cull_ctx *c;
    assert_int_equal(cull_ctx_create(pool, &c), CULL_OK);
    uint64_t filtered_total = 0, kept_total = 0;
    for (int round = 0; round < 12; round++) {
        uint64_t set[CULL_SUBLEVEL_WORDS] = {0};
        bool in[6];
        for (uint32_t k = 0; k < nsubs; k++) {
            in[k] = rng_below(&r, 2);
            if (in[k]) set[subs[k] / 64] |= 1ull << (subs[k] % 64);
        }
        cull_world *all, *only;
        assert_int_equal(cull_world_create(NULL, &all), CULL_OK);
        assert_int_equal(cull_world_create(NULL, &only), CULL_OK);
        float v[108];
        unit_cube(v);
        for (int b = 0; b < 30; b++) {
            uint32_t k = rng_below(&r, nsubs);
            cull_occluder_desc d = {.vertices = v, .vertex_count = 36, .sublevel = subs[k]};
            for (int a = 0; a < 3; a++) {
                d.transform[a * 5] = rng_log(&r, 0.5, 20);
                d.transform[12 + a] = rng_range(&r, -60, 60);
            }
            d.transform[15] = 1;
            cull_occluder h;
            assert_int_equal(cull_occluder_add(all, &d, &h), CULL_OK);
            if (in[k]) assert_int_equal(cull_occluder_add(only, &d, &h), CULL_OK);
        }
        uint32_t n = 500 + rng_below(&r, 1500);
        cull_handle *hl = malloc(n * sizeof *hl);
        assert_non_null(hl);
        for (uint32_t i = 0; i < n; i++) {
            cull_entity_desc e = {.sublevel = subs[rng_below(&r, nsubs)]};
            for (int a = 0; a < 3; a++) {
                double m = rng_range(&r, -90, 90), hs = rng_log(&r, 0.05, 5);
                e.aabb_min[a] = m - hs;
                e.aabb_max[a] = m + hs;
            }
            e.flags = rng_below(&r, 4) == 0 ? CULL_ENTITY_DYNAMIC : 0;
            cull_handle h1, h2;
            assert_int_equal(cull_entity_add(all, &e, &h1), CULL_OK);
            assert_int_equal(cull_entity_add(only, &e, &h2), CULL_OK);
            assert_int_equal(h1, h2);
            hl[i] = h1;
        }
        /* removals leave the cells' summaries loose until commit */
        for (uint32_t i = 0; i < n; i += 1 + rng_below(&r, 8)) {
            assert_int_equal(cull_entity_remove(all, hl[i]), CULL_OK);
            assert_int_equal(cull_entity_remove(only, hl[i]), CULL_OK);
        }
        free(hl);
        if (round % 2) cull_world_commit(all);
        size_t cap = cull_query_bound(all), na, nb, nc;
        cull_result *ra = malloc(cap * sizeof *ra), *rb = malloc(cap * sizeof *rb);
        assert_true(ra && rb);
        for (int vi = 0; vi < 4; vi++) {
            oscene tmp = {.w = all};
            cull_view view;
            random_view(&r, &tmp, &view, 256, 114);
            uint32_t isa = rng_below(&r, CULL_ISA_COUNT);
            if (!cull_isa_supported(isa)) isa = CULL_ISA_SCALAR;
            assert_int_equal(cull_ctx_set_isa(c, isa), CULL_OK);
            uint32_t threads = 1 + rng_below(&r, 2);
            cull_query_desc q = {.views = &view, .view_count = 1, .threads = threads, .sublevels = set};
            cull_query_stats st;
            assert_int_equal(cull_query(all, c, &q, ra, cap, &na, &st), CULL_OK);
            cull_query_desc qb = {.views = &view, .view_count = 1, .threads = threads};
            assert_int_equal(cull_query(only, c, &qb, rb, cap, &nb, NULL), CULL_OK);
            size_t k = 0;
            for (size_t i = 0; i < nb; i++)
                if (cull_sublevel_in(set, rb[i].sublevel)) rb[k++] = rb[i];
            assert_int_equal(na, k);
            for (size_t i = 0; i < na; i++) {
                assert_int_equal(ra[i].handle, rb[i].handle);
                assert_int_equal(ra[i].view_mask, rb[i].view_mask);
            }
            q.flags = CULL_Q_COUNT_ONLY;
            assert_int_equal(cull_query(all, c, &q, NULL, 0, &nc, NULL), CULL_OK);
            assert_int_equal(nc, na);
            filtered_total += st.filtered;
            kept_total += na;
        }
        free(ra);
        free(rb);
        cull_world_destroy(all);
        cull_world_destroy(only);
    }
    fprintf(stderr, "sub-level filter: %llu kept, %llu filtered out\n", (unsigned long long)kept_total,
            (unsigned long long)filtered_total);
    assert_true(kept_total > 0 && filtered_total > 0);
    cull_ctx_destroy(c);
    cull_pool_destroy(pool);
}

/* ---- the cost of building an occluder (issue 18 item 4) -------------------- */

/* The adversarial meshes: n triangles each, as a triangle list. */
enum { BUILD_SAME, BUILD_BOTH_WINDINGS, BUILD_BOOK, BUILD_NEEDLES, BUILD_FAN, BUILD_TINY_GRID, BUILD_KINDS };
static const char *const build_kind_name[BUILD_KINDS] = {"identical", "coincident both windings", "book on one edge",
                                                          "needles", "fan on one vertex", "tiny grid"};

static float *build_mesh_of(int kind, uint32_t n)
{
    float *v = malloc((size_t)n * 9 * sizeof *v);
    assert_non_null(v);
    for (uint32_t t = 0; t < n; t++) {
        float *p = v + 9 * (size_t)t;
        float a[3] = {0, 0, 0}, b[3] = {10, 0, 0}, c[3] = {0, 10, 0};
        double ang = 2 * M_PI * t / n;
        switch (kind) {
        case BUILD_SAME: break;
        case BUILD_BOTH_WINDINGS:
            if (t & 1) c[0] = 10, c[1] = 0, b[0] = 0, b[1] = 10; /* a, c, b */
            break;
        case BUILD_BOOK: /* every page on edge a-b, half each way, none coplanar */
            c[0] = 5;
            c[1] = (float)(10 * cos(ang));
            c[2] = (float)(10 * sin(ang));
            if (t & 1) b[0] = 0, a[0] = 10;
            break;
        case BUILD_NEEDLES: /* 1e6:1 slivers along one line, all sharing it */
            c[0] = (float)(10.0 * t / n);
            c[1] = 1e-5f * (float)(1 + t % 7);
            break;
        case BUILD_FAN: /* every triangle has the centre as a corner */
            b[0] = (float)(10 * cos(ang)), b[1] = (float)(10 * sin(ang)), b[2] = 0;
            c[0] = (float)(10 * cos(ang + 2 * M_PI / n)), c[1] = (float)(10 * sin(ang + 2 * M_PI / n)), c[2] = 0;
            break;
        default: { /* a grid of millimetre triangles */
            uint32_t q = t / 2, side = 256;
            float x = 1e-3f * (float)(q % side), y = 1e-3f * (float)(q / side);
            float s = 1e-3f;
            if (t & 1) {
                a[0] = x + s, a[1] = y, b[0] = x + s, b[1] = y + s, c[0] = x, c[1] = y + s;
            } else {
                a[0] = x, a[1] = y, b[0] = x + s, b[1] = y, c[0] = x, c[1] = y + s;
            }
            break;
        }
        }
        memcpy(p, a, sizeof a);
        memcpy(p + 3, b, sizeof b);
        memcpy(p + 6, c, sizeof c);
    }
    return v;
}

static uint64_t build_steps_of(int kind, uint32_t n, cull_occluder_info *info)
{
    cull_world *w;
    assert_int_equal(cull_world_create(&(cull_world_desc){0}, &w), CULL_OK);
    float *v = build_mesh_of(kind, n);
    cull_occluder h;
    assert_int_equal(cull_occluder_add(w, &(cull_occluder_desc){.vertices = v, .vertex_count = 3 * n}, &h), CULL_OK);
    assert_int_equal(cull_occluder_get_info(w, h, info), CULL_OK);
    free(v);
    cull_world_destroy(w);
    return info->build_steps;
}

/* No single OCCLUDER_PUT may hold the daemon: building an occluder of n
 * triangles costs O(n log n) whatever the triangles are. Asserted on the
 * build's own count of its work (hash probes, edge candidates, sort
 * compares), so no timing decides it: at most 40 n log2 n steps at 16k and
 * 64k triangles, and 64k costing at most 6x 16k (n log n gives 4.6x; the
 * quadratic build this replaced did 16x: 0.2 s, 1.3 s, 9.9 s at 16k, 32k,
 * 64k identical triangles). Duplicates (same corners, same winding) are
 * dropped at upload: they draw nothing a first copy does not. */
static void test_occluder_build_bound(void **state)
{
    (void)state;
    for (int kind = 0; kind < BUILD_KINDS; kind++) {
        cull_occluder_info a, b;
        uint32_t n = 16384;
        uint64_t sa = build_steps_of(kind, n, &a), sb = build_steps_of(kind, 4 * n, &b);
        print_message("occluder build, %s: %llu steps at %u triangles, %llu at %u (%u kept, %u faces)\n",
                      build_kind_name[kind], (unsigned long long)sa, n, (unsigned long long)sb, 4 * n, b.triangles,
                      b.faces);
        assert_true(sa <= 40ull * n * 14);
        assert_true(sb <= 40ull * 4 * n * 16);
        assert_true(sb <= 6 * sa);
        assert_int_equal(a.triangles + a.dropped, n);
        assert_int_equal(b.triangles + b.dropped, 4 * n);
        if (kind == BUILD_SAME) assert_int_equal(b.triangles, 1);
        if (kind == BUILD_BOTH_WINDINGS) assert_int_equal(b.triangles, 2);
    }
}

/* Cutting destruction holes into an occluder (every DESTROY, and every
 * OCCLUDER_PUT of a damaged entity's id) tests each piece against each
 * sphere: 4096 spheres on 349,525 triangles took 26 s. The cut gives up
 * (CULL_ERR_CAPACITY: the daemon drops the occluder whole, which only
 * hides less) past max_out * CULL_CUT_WORK_PER_PIECE tests. Here spheres
 * far from every triangle, so nothing is cut and the whole cost is the
 * tests: 20,000 x 4096 is past 65,536 x 512, 2,000 x 4096 is within. */
static void test_occluder_cut_bound(void **state)
{
    (void)state;
    const uint32_t big = 20000, small = 2000, nsph = 4096, max_out = 65536;
    float *tri = malloc((size_t)big * 9 * sizeof *tri);
    assert_non_null(tri);
    for (uint32_t t = 0; t < big; t++) {
        float x = (float)(t % 200), y = (float)(t / 200), *p = tri + 9 * (size_t)t;
        const float v[9] = {x, y, 0, x + 1, y, 0, x, y + 1, 0};
        memcpy(p, v, sizeof v);
    }
    cull_dvol dv;
    const double lo[3] = {0, 0, -1}, hi[3] = {200, 100, 1}, origin[3] = {0, 0, 0};
    assert_int_equal(cull_dvol_init(&dv, lo, hi, 8), CULL_OK);
    for (uint32_t k = 0; k < nsph; k++) {
        const double c[3] = {1000.0 + k % 64, 1000.0 + k / 64, 0};
        assert_int_equal(cull_dvol_add_sphere(&dv, c, 0.5), CULL_OK);
    }
    assert_true((uint64_t)big * nsph > (uint64_t)max_out * CULL_CUT_WORK_PER_PIECE);
    assert_true((uint64_t)small * nsph <= (uint64_t)max_out * CULL_CUT_WORK_PER_PIECE);
    float *out = NULL;
    uint32_t n = 0;
    assert_int_equal(cull_occ_cut(tri, big, origin, &dv, 0.01, 0.25, max_out, &out, NULL, &n), CULL_ERR_CAPACITY);
    assert_null(out);
    assert_int_equal(n, 0);
    assert_int_equal(cull_occ_cut(tri, small, origin, &dv, 0.01, 0.25, max_out, &out, NULL, &n), CULL_OK);
    assert_int_equal(n, small); /* nothing near a sphere: every triangle kept whole */
    assert_memory_equal(out, tri, (size_t)small * 9 * sizeof *tri);
    free(out);
    cull_dvol_free(&dv);
    free(tri);
}

/* ---- a context keeps a view's occlusion buffer (issue 24) ---------------------------------- */

/* The visible set of a query, sorted (handles and view masks). */
static size_t sorted_query(const cull_world *w, cull_ctx *c, const cull_query_desc *q, cull_result *r, size_t cap,
                           cull_query_stats *st)
{
    size_t n;
    assert_int_equal(cull_query(w, c, q, r, cap, &n, st), CULL_OK);
    for (size_t i = 1; i < n; i++) /* insertion sort: a few hundred */
        for (size_t j = i; j > 0 && r[j - 1].handle > r[j].handle; j--) {
            cull_result t = r[j];
            r[j] = r[j - 1];
            r[j - 1] = t;
        }
    return n;
}

/* An axis-aligned box occluder of the unit cube v somewhere in s, in a
 * sub-level 0..2. */
static cull_occluder_desc random_box(rng *r, const oscene *s, const float *v)
{
    cull_occluder_desc d = {.vertices = v, .vertex_count = 36, .sublevel = (uint16_t)rng_below(r, 3)};
    for (int k = 0; k < 3; k++) {
        d.transform[k * 5] = rng_log(r, 0.5, 20);
        d.transform[12 + k] = s->base[k] + rng_range(r, -50, 50);
    }
    d.transform[15] = 1;
    return d;
}

/* A long-lived context answers exactly as a new one (no history at all)
 * through 600 random steps: the same view again, a new view, a view moved
 * by one ulp, occluders added, replaced and removed, sub-level sets and
 * cover modes changed. It keeps the buffer exactly when nothing the
 * render reads changed since its last query of that view, and renders
 * again otherwise (st.occ_reused says which). */
/* One town: a long-lived context against a new one through random
 * views, occluder and entity edits, sub-level sets and cover modes. */
static void buffer_reuse_town(rng *rr, int steps, uint32_t *reused_out, uint32_t *rendered_out)
{
    rng r = *rr;
    oscene s;
    build_scene(&r, &s);
    float v[108];
    unit_cube(v);
    cull_occluder mine[64];
    uint32_t nmine = 0;
    cull_ctx *kept;
    /* the kept context on two threads (its blocks' records written from
       either), the new one on none */
    cull_pool *pool;
    assert_int_equal(cull_pool_create(2, &pool), CULL_OK);
    assert_int_equal(cull_ctx_create(pool, &kept), CULL_OK);
    size_t cap = cull_query_bound(s.w) + 64;
    cull_result *a = malloc(cap * sizeof *a), *b = malloc(cap * sizeof *b);
    assert_non_null(a);
    assert_non_null(b);
    static uint64_t subs[CULL_SUBLEVEL_WORDS];
    bool use_subs = false, changed = true;
    uint32_t flags = 0, kflags = 0, reused = 0, rendered = 0;
    float min_area = 0;
    bool two = false; /* a second view: cells both see take the multi-view kernel */
    cull_view view, view2;
    random_view(&r, &s, &view, 256, 114);
    for (int step = 0; step < steps; step++) {
        uint32_t op = rng_below(&r, 17);
        if (op == 0 || op == 1) {
            random_view(&r, &s, &view, 256, 114);
            changed = true;
        } else if (op == 2) { /* one ulp: a different view, drawn again */
            view.origin[0] = nextafter(view.origin[0], INFINITY);
            changed = true;
        } else if (op == 3 && nmine < 64) {
            cull_occluder_desc d = random_box(&r, &s, v);
            assert_int_equal(cull_occluder_add(s.w, &d, &mine[nmine++]), CULL_OK);
            changed = true;
        } else if (op == 4 && nmine) { /* replaced: another box */
            cull_occluder_desc d = random_box(&r, &s, v);
            assert_int_equal(cull_occluder_update(s.w, mine[rng_below(&r, nmine)], &d), CULL_OK);
            changed = true;
        } else if (op == 5 && nmine) {
            uint32_t k = rng_below(&r, nmine);
            assert_int_equal(cull_occluder_remove(s.w, mine[k]), CULL_OK);
            mine[k] = mine[--nmine];
            changed = true;
        } else if (op == 6) { /* a sub-level set, or every sub-level */
            bool was = use_subs;
            uint64_t w0 = subs[0], w1 = subs[1];
            use_subs = rng_below(&r, 2);
            subs[0] = rng_below(&r, 8);
            subs[1] = rng_below(&r, 2) ? 1 : 0; /* sub-level 64: the set's length changes */
            changed |= use_subs != was || (use_subs && (subs[0] != w0 || subs[1] != w1));
        } else if (op == 7) {
            flags ^= CULL_Q_OCC_CENTRE;
            changed = true;
        } else if (op == 8 || op == 9) { /* an entity moved a little or far: the buffer stays, cells change */
            uint32_t i = rng_below(&r, s.n);
            cull_entity_desc *e = &s.e[i];
            double d = op == 8 ? rng_log(&r, 1e-3, 2) : rng_range(&r, 20, 120);
            bool grow = rng_below(&r, 2); /* or grown in place: its cell's bounds widen, a hidden cell may show */
            for (int ax = 0; ax < 3; ax++) {
                double m = rng_range(&r, -d, d), c = 0.5 * (e->aabb_min[ax] + e->aabb_max[ax]);
                double h = 0.5 * (e->aabb_max[ax] - e->aabb_min[ax]) * rng_range(&r, 1, 8);
                e->aabb_min[ax] = grow ? c - h : e->aabb_min[ax] + m;
                e->aabb_max[ax] = grow ? c + h : e->aabb_max[ax] + m;
            }
            assert_int_equal(cull_entity_update(s.w, s.h[i], e), CULL_OK);
            assert_int_equal(cull_entity_get(s.w, s.h[i], e), CULL_OK);
        } else if (op == 10) { /* removed and added again elsewhere */
            uint32_t i = rng_below(&r, s.n);
            cull_entity_desc *e = &s.e[i];
            assert_int_equal(cull_entity_remove(s.w, s.h[i]), CULL_OK);
            for (int ax = 0; ax < 3; ax++) {
                double c = s.base[ax] + rng_range(&r, -90, 90), hs = rng_log(&r, 0.02, 6);
                e->aabb_min[ax] = c - hs;
                e->aabb_max[ax] = c + hs;
            }
            assert_int_equal(cull_entity_add(s.w, e, &s.h[i]), CULL_OK);
            assert_int_equal(cull_entity_get(s.w, s.h[i], e), CULL_OK);
        } else if (op == 11) {
            cull_world_commit(s.w);
        } else if (op == 12 && rng_below(&r, 3) == 0) {
            /* every entity a whole cell (64 m) along x: the blocks hold the
               same cell-relative boxes in other cells, seen otherwise */
            double d = rng_below(&r, 2) ? 64 : -64;
            for (uint32_t i = 0; i < s.n; i++) {
                s.e[i].aabb_min[0] += d;
                s.e[i].aabb_max[0] += d;
                s.e[i].center[0] += d;
                assert_int_equal(cull_entity_update(s.w, s.h[i], &s.e[i]), CULL_OK);
                assert_int_equal(cull_entity_get(s.w, s.h[i], &s.e[i]), CULL_OK);
            }
            cull_world_commit(s.w);
        } else if (op == 13) {
            /* the kernel's stages: the buffer stays, its blocks' records
               were made with other stages */
            static const float areas[] = {0, 4, 40};
            static const uint32_t kf[] = {0, CULL_Q_WANT_AREA, CULL_Q_NO_AABB, CULL_Q_WANT_AREA | CULL_Q_NO_AABB};
            min_area = areas[rng_below(&r, 3)];
            kflags = kf[rng_below(&r, 4)];
        } else if (op == 14) {
            two = !two;
            if (two) {
                random_view(&r, &s, &view2, 256, 114);
                if (rng_below(&r, 2)) { /* or nearly the first: most cells seen by both */
                    view2 = view;
                    view2.origin[1] += 0.5;
                }
            }
        } /* else: the same query again */
        const cull_view views[2] = {view, view2};
        cull_query_desc q = {.views = views, .view_count = two ? 2 : 1, .flags = flags | kflags,
                             .min_screen_area = min_area, .sublevels = use_subs ? subs : NULL,
                             .threads = rng_below(&r, 3)};
        cull_query_stats st;
        size_t na = sorted_query(s.w, kept, &q, a, cap, &st);
        cull_ctx *fresh;
        assert_int_equal(cull_ctx_create(NULL, &fresh), CULL_OK);
        size_t nb = sorted_query(s.w, fresh, &q, b, cap, NULL);
        cull_ctx_destroy(fresh);
        if (na != nb || memcmp(a, b, na * sizeof *a))
            fail_msg("step %d (op %u): the kept context answered %zu entities, a new one %zu", step, op, na, nb);
        /* (the world always has occluders: the stage runs every time;
           the second view's own reuse is not tracked) */
        if (!two && st.occ_reused != (changed ? 0u : 1u))
            fail_msg("step %d (op %u): reused %u, changed %d, occ_views %u", step, op, st.occ_reused, changed, st.occ_views);
        assert_int_equal(st.occ_reused + st.occ_rendered, two ? 2 : 1);
        reused += st.occ_reused;
        rendered += !st.occ_reused;
        changed = false;
        /* the kept context's buffer, asked to render again, gives the same */
        if (step % 50 == 0) {
            q.flags |= CULL_Q_OCC_FRESH;
            size_t nf = sorted_query(s.w, kept, &q, b, cap, &st);
            assert_int_equal(st.occ_reused, 0);
            assert_true(nf == na && !memcmp(a, b, na * sizeof *a));
        }
    }
    *reused_out += reused;
    *rendered_out += rendered;
    *rr = r;
    free(a);
    free(b);
    cull_ctx_destroy(kept);
    cull_pool_destroy(pool);
    free_scene(&s);
}

/* A kept buffer (and the cell verdicts kept with it) answers as a new
 * context, over random towns, views and edits. */
static void test_occ_buffer_reuse(void **state)
{
    (void)state;
    rng r = {0x0cc5eed};
    int towns = 4, steps = (int)(300 * test_scale());
    uint32_t reused = 0, rendered = 0;
    for (int t = 0; t < towns; t++) buffer_reuse_town(&r, steps, &reused, &rendered);
    assert_true(reused > (uint32_t)(towns * steps) / 10 && rendered > (uint32_t)(towns * steps) / 10);
    fprintf(stderr, "occlusion buffer reuse: %d towns, %d queries, %u kept, %u rendered, all as a new context's\n",
            towns, towns * steps, reused, rendered);
}

/* ---- the per-ISA rectangle test against the scalar one -------------------------- */

/* Pixel (px, py) of b, or its tile's teff where the tile has no pixels
 * (TILE_INVALID: the render has not written it). */
static float pixel_or_teff(const cull_occ_buffer *b, int px, int py)
{
    size_t t = (size_t)(py >> 3) * b->tw + (size_t)(px >> 3);
    if (b->tstate[(size_t)(py >> 3) * b->tpitch + (size_t)(px >> 3)] == OCC_TILE_INVALID) return b->teff[t];
    return cull_occ_tile_px(b, t)[8 * (py & 7) + (px & 7)];
}

/* A nearness to test at: mostly one of the buffer's own values near the
 * rectangle (a pixel, a tile's teff or vkey, a big tile's or a strip's
 * minimum), exactly or one float step either side; else extremes. */
static float pick_z(rng *r, const cull_occ_buffer *b, int x0, int y0, int x1, int y1)
{
    int px = x0 + (int)rng_below(r, (uint32_t)(x1 - x0 + 1)), py = y0 + (int)rng_below(r, (uint32_t)(y1 - y0 + 1));
    size_t t = (size_t)(py >> 3) * b->tw + (size_t)(px >> 3);
    float z;
    switch (rng_below(r, 9)) {
    case 0: z = pixel_or_teff(b, px, py); break;
    case 1: z = b->teff[t]; break;
    case 2: z = b->vkey[t]; break;
    case 3: z = b->tile2[(size_t)(py >> 6) * b->t2w + (size_t)(px >> 6)]; break;
    case 4: z = b->strip[(size_t)(py >> 3) * b->spitch + (size_t)(px >> 6)]; break;
    case 5: z = b->tmax[t]; break;
    case 6: {
        static const float ext[] = {-FLT_MAX, FLT_MAX, -INFINITY, INFINITY, 0.0f, -0.0f, 1e-30f, 1e30f};
        return ext[rng_below(r, 8)];
    }
    case 7: return (float)rng_range(r, -1, 1) * (float)rng_log(r, 1e-6, 1e6);
    default: z = pixel_or_teff(b, px, py); break;
    }
    uint32_t s = rng_below(r, 3);
    return s == 0 ? z : nextafterf(z, s == 1 ? INFINITY : -INFINITY);
}

/* A pixel range [a, b] of n pixels: small, large, whole, at either border. */
static void pick_span(rng *r, uint32_t n, int *a, int *b)
{
    uint32_t len = rng_below(r, 4) == 0 ? 1 + rng_below(r, n) : 1 + rng_below(r, n < 24 ? n : 24);
    uint32_t at = rng_below(r, n - len + 1);
    if (rng_below(r, 6) == 0) at = 0;
    else if (rng_below(r, 5) == 0) at = n - len;
    *a = (int)at;
    *b = (int)(at + len - 1);
}

/* The kernel's float bound to pixel conversion, as it was written per lane
 * before the group conversion: the reference for cull_occ_fns.lanes. */
static bool ref_lane(const cull_occ_buffer *b, float fx0, float fx1, float fy0, float fy1, float z)
{
    int i0 = (int)(fx0 + 1.0f) - 1, j0 = (int)(fy0 + 1.0f) - 1;
    int i1 = (int)fx1, j1 = (int)fy1;
    i1 -= !((float)i1 < fx1);
    j1 -= !((float)j1 < fy1);
    i0 = i0 < 0 ? 0 : i0;
    j0 = j0 < 0 ? 0 : j0;
    i1 = i1 > (int)b->w - 1 ? (int)b->w - 1 : i1;
    j1 = j1 > (int)b->h - 1 ? (int)b->h - 1 : j1;
    return i0 <= i1 && j0 <= j1 && cull_occ_rect_visible(b, i0, j0, i1, j1, z);
}

/* A float bound in [-1, n + 1]: integers, just above or below them, the
 * ends, or anywhere. */
static float pick_bound(rng *r, uint32_t n)
{
    float v = (float)rng_below(r, n + 3) - 1.0f;
    switch (rng_below(r, 5)) {
    case 0: return v;
    case 1: return v > -1.0f ? nextafterf(v, -INFINITY) : v;
    case 2: return v < (float)n + 1.0f ? nextafterf(v, INFINITY) : v;
    case 3: return (float)rng_range(r, -1, n + 1);
    default: return v + (float)rng_f(r) * (v < (float)n ? 1.0f : 0.0f);
    }
}

/* The per-ISA walk (the query's kernel and cell stage) and the kernel's
 * group conversion answer as cull_occ_rect_visible, lane by lane: random
 * scenes and views rendered into buffers of several sizes (tiles cut by
 * the right and top edges), inner and centre cover, some folded by
 * cull_occ_depth; rectangles small, large, whole and at the borders;
 * nearness at the buffer's own values and one float step either side, and
 * extremes (+-FLT_MAX, +-inf, 0). */
/* Every ISA's tile-row span kernel (cull_occ_spans) writes exactly what
 * the same ISA's span does over each part of each row of a row-major
 * model: the tile row's 17 tiles held at random slots of a larger pool
 * (the other slots must stay as they were); random rows (empty, single
 * pixels, whole rows, ends at tile edges and inside tiles), a gap (a tile
 * row's coarse tiles) or none, random planes, floors and prior contents,
 * compared bit for bit. */
static void test_occ_spans_match_span(void **state)
{
    (void)state;
    rng r = {0x5ba45ull};
    enum { NT = 17, ROOM = 8 * NT, STRIDE = 144, NSLOT = 24 };
    float *want = malloc(sizeof(float) * 8 * STRIDE), *init = malloc(sizeof(float) * 8 * STRIDE);
    float *pool = aligned_alloc(64, sizeof(float) * 64 * NSLOT), *pinit = malloc(sizeof(float) * 64 * NSLOT);
    assert_non_null(want);
    assert_non_null(init);
    assert_non_null(pool);
    assert_non_null(pinit);
    int cases = (int)(3000 * test_scale());
    for (int t = 0; t < cases; t++) {
        int x0[8], x1[8];
        float z0[24];
        for (int i = 0; i < 8 * STRIDE; i++) init[i] = rng_below(&r, 4) ? (float)rng_range(&r, -2, 2) : -FLT_MAX;
        /* tile k of the row at slot[k]: a random choice of distinct slots */
        uint32_t slot[NT], perm[NSLOT];
        for (uint32_t i = 0; i < NSLOT; i++) perm[i] = i;
        for (uint32_t i = NSLOT - 1; i > 0; i--) {
            uint32_t j = rng_below(&r, i + 1), x = perm[i];
            perm[i] = perm[j];
            perm[j] = x;
        }
        memcpy(slot, perm, sizeof slot);
        for (int i = 0; i < 64 * NSLOT; i++) pinit[i] = (float)rng_range(&r, -3, 3);
        for (int k = 0; k < NT; k++)
            for (int y = 0; y < 8; y++) memcpy(pinit + 64 * slot[k] + 8 * y, init + y * STRIDE + 8 * k, 8 * sizeof(float));
        for (int k = 0; k < 8; k++) {
            switch (rng_below(&r, 6)) {
            case 0: x0[k] = 5, x1[k] = 4; break; /* empty */
            case 1: x0[k] = x1[k] = (int)rng_below(&r, ROOM); break;
            case 2: x0[k] = 0, x1[k] = ROOM - 1; break;
            case 3: /* tile edges */
                x0[k] = 8 * (int)rng_below(&r, NT);
                x1[k] = x0[k] + 8 * (int)rng_below(&r, (uint32_t)(ROOM - x0[k]) / 8) + 7;
                break;
            default:
                x0[k] = (int)rng_below(&r, ROOM);
                x1[k] = x0[k] + (int)rng_below(&r, (uint32_t)(ROOM - x0[k]));
            }
            for (int c = 0; c < 3; c++) z0[8 * c + k] = (float)rng_range(&r, -1, 1);
        }
        /* the gap: none, or whole tiles somewhere in the row */
        int g0 = 1, g1 = 0;
        if (rng_below(&r, 3)) {
            g0 = 8 * (int)rng_below(&r, ROOM / 8);
            g1 = g0 + 8 * (int)rng_below(&r, (uint32_t)(ROOM - g0) / 8 + 1) - 1;
        }
        float d[3] = {(float)rng_range(&r, -0.01, 0.01), (float)rng_range(&r, -0.01, 0.01),
                      (float)rng_range(&r, -0.01, 0.01)};
        float lo = (float)rng_range(&r, -1.5, 0.5);
        for (uint32_t isa = 0; isa < CULL_ISA_COUNT; isa++) {
            if (!cull_isa_supported(isa)) continue;
            cull_occ_fns fns = cull_occ_fns_for(isa);
            memcpy(pool, pinit, sizeof(float) * 64 * NSLOT);
            memcpy(want, init, sizeof(float) * 8 * STRIDE);
            fns.spans(pool, slot, x0, x1, g0, g1, z0, d[0], d[1], d[2], lo);
            for (int k = 0; k < 8; k++)
                for (int x = x0[k]; x <= x1[k]; x++) {
                    if (x >= g0 && x <= g1) continue;
                    int e = x; /* the run of pixels outside the gap from x */
                    while (e + 1 <= x1[k] && !(e + 1 >= g0 && e + 1 <= g1)) e++;
                    fns.span(want + (size_t)k * STRIDE, x, e, ROOM, z0[k], d[0], z0[8 + k], d[1], z0[16 + k], d[2],
                             lo);
                    x = e;
                }
            for (int k = 0; k < NT; k++)
                for (int y = 0; y < 8; y++)
                    if (memcmp(pool + 64 * slot[k] + 8 * y, want + y * STRIDE + 8 * k, 8 * sizeof(float)))
                        fail_msg("case %d, ISA %u: spans and span differ (tile %d, row %d)", t, isa, k, y);
            for (int k = NT; k < NSLOT; k++)
                if (memcmp(pool + 64 * perm[k], pinit + 64 * perm[k], 64 * sizeof(float)))
                    fail_msg("case %d, ISA %u: spans wrote slot %u, no tile's", t, isa, perm[k]);
        }
    }
    free(pinit);
    free(pool);
    free(init);
    free(want);
}

/* A tile row's rows set-up (cull_occ_fns.rows): the reference against a
 * pixel-by-pixel model (row r's span is exactly the pixels of [i0, i1]
 * that every bound admits, its sums those of the spans), and every ISA's
 * instance against the reference bit for bit (spans, sums and the planes'
 * start nearness). Random bounds (steep, shallow, flat, far off the
 * buffer, clamped at +-2^30), columns, rows and tile rows; slow bounds
 * for the reference only (the render sends those polygons to it). */
static void test_occ_rows_match_model(void **state)
{
    (void)state;
    rng r = {0x20e5ull};
    int cases = (int)(4000 * test_scale()), nonempty = 0, rows_seen = 0;
    for (int t = 0; t < cases; t++) {
        cull_occ_rowset rs = {0};
        rs.nl = rng_below(&r, 5);
        rs.nr = rng_below(&r, 5);
        bool slow = rng_below(&r, 8) == 0;
        rs.ns = slow ? 1 + rng_below(&r, 2) : 0;
        for (uint32_t k = 0; k < 4; k++) {
            double *al[2] = {&rs.lal[k], &rs.ral[k]}, *be[2] = {&rs.lbe[k], &rs.rbe[k]};
            for (int s = 0; s < 2; s++) {
                switch (rng_below(&r, 8)) {
                case 0: *be[s] = 0; break;
                case 1: *be[s] = rng_range(&r, -1e-9, 1e-9); break;
                case 2: *be[s] = rng_range(&r, -400, 400); break;
                default: *be[s] = rng_range(&r, -3, 3);
                }
                *al[s] = rng_below(&r, 10) ? rng_range(&r, -300, 1600) - *be[s] * rng_range(&r, 0, 800)
                                           : (rng_below(&r, 2) ? 1 : -1) * ldexp(1, 28 + (int)rng_below(&r, 800));
            }
        }
        for (uint32_t k = 0; k < rs.ns; k++) {
            rs.sa[k] = (rng_below(&r, 2) ? 1 : -1) * ldexp(1, -(int)rng_below(&r, 1000));
            rs.sb[k] = rng_range(&r, -1, 1) * ldexp(1, -(int)rng_below(&r, 1000));
            rs.st[k] = rng_range(&r, -1, 1) * ldexp(rs.sa[k] < 0 ? -rs.sa[k] : rs.sa[k], 11);
        }
        int i0 = (int)rng_below(&r, 1300), i1 = i0 + (int)rng_below(&r, 300) - 30;
        rs.i0 = i0;
        rs.i1 = i1;
        for (int k = 0; k < 3; k++) {
            rs.zb[k] = rng_range(&r, -1e-3, 1e-3);
            rs.zc[k] = rng_range(&r, -2, 2);
            rs.corner[k] = rng_range(&r, 0, 1e-3);
            rs.m[k] = rng_range(&r, 0, 1e-6);
        }
        int jb = 8 * (int)rng_below(&r, 100), a = (int)rng_below(&r, 8), b = a + (int)rng_below(&r, (uint32_t)(8 - a));
        int lo[8], hi[8];
        float z0[24];
        cull_occ_rowsum ref = cull_occ_rows_scalar(&rs, jb, a, b, lo, hi, z0);
        /* the model */
        cull_occ_rowsum want = {INT32_MIN, INT32_MAX, INT32_MAX, INT32_MIN, a == 0 && b == 7};
        for (int q = 0; q < 8; q++) {
            int j = jb + q;
            for (int k = 0; k < 3; k++) {
                float zk = (float)(((rs.zb[k] * j + rs.zc[k]) - rs.corner[k]) - rs.m[k]);
                if (memcmp(&zk, &z0[8 * k + q], sizeof zk)) fail_msg("case %d row %d: plane %d's start", t, q, k);
            }
            if (q < a || q > b) {
                if (lo[q] <= hi[q]) fail_msg("case %d: row %d outside %d..%d not empty", t, q, a, b);
                continue;
            }
            int first = INT32_MAX, last = INT32_MIN;
            for (int x = i0; x <= i1; x++) {
                bool in = true;
                for (uint32_t k = 0; k < rs.nl && in; k++) in = x > rs.lal[k] + rs.lbe[k] * j;
                for (uint32_t k = 0; k < rs.nr && in; k++) in = x < rs.ral[k] + rs.rbe[k] * j;
                for (uint32_t k = 0; k < rs.ns && in; k++) {
                    double qb = (rs.st[k] - rs.sb[k] * j) / rs.sa[k];
                    in = rs.sa[k] > 0 ? x > qb : x < qb;
                }
                if (in) {
                    if (first == INT32_MAX) first = x;
                    if (x != last + 1 && last != INT32_MIN) fail_msg("case %d row %d: not one span", t, q);
                    last = x;
                }
            }
            rows_seen++;
            if (first == INT32_MAX) {
                if (lo[q] <= hi[q]) fail_msg("case %d row %d: [%d, %d], the model none", t, q, lo[q], hi[q]);
                want.whole = 0;
            } else {
                nonempty++;
                if (lo[q] != first || hi[q] != last)
                    fail_msg("case %d row %d: [%d, %d], the model [%d, %d]", t, q, lo[q], hi[q], first, last);
                want.U0 = first < want.U0 ? first : want.U0;
                want.U1 = last > want.U1 ? last : want.U1;
            }
            want.L = lo[q] > want.L ? lo[q] : want.L;
            want.H = hi[q] < want.H ? hi[q] : want.H;
        }
        if (memcmp(&want, &ref, sizeof want)) fail_msg("case %d: the reference's sums differ from the spans'", t);
        if (rs.ns) continue;
        for (uint32_t isa = 0; isa < CULL_ISA_COUNT; isa++) {
            if (!cull_isa_supported(isa)) continue;
            int lo2[8], hi2[8];
            float z2[24];
            cull_occ_rowsum got = cull_occ_fns_for(isa).rows(&rs, jb, a, b, lo2, hi2, z2);
            if (memcmp(&got, &ref, sizeof got) || memcmp(lo, lo2, sizeof lo) || memcmp(hi, hi2, sizeof hi) ||
                memcmp(z0, z2, sizeof z0))
                fail_msg("case %d, %s: rows differ from the reference", t, cull_isa_name(isa));
        }
    }
    /* both kinds of row must be common */
    assert_true(nonempty > rows_seen / 10 && nonempty < rows_seen - rows_seen / 10);
}

/* The render's cluster projection (cull_occ_fns.project): every ISA's
 * against the reference bit for bit, and the reference's rectangles
 * against cull_occ_project_bound's box by box, and the AVX2 rectangles
 * (cull_occ_rects_avx2) against those: random scenes' views
 * (perspective and orthographic, inside boxes, far from the origin) over
 * random boxes near and far, thin, huge and straddling the eye; index
 * lists of every length mod 4, repeated and in any order. */
static void test_occ_project_matches_bound(void **state)
{
    (void)state;
    rng r = {0x9e0b0ull};
    int scenes = (int)(12 * test_scale());
    uint64_t boxes = 0, near = 0, drawn = 0;
    for (int sc = 0; sc < scenes; sc++) {
        oscene s;
        build_scene(&r, &s);
        cull_occ_buffer *b;
        assert_int_equal(cull_occ_buffer_create(1280, 720, &b), CULL_OK);
        enum { NB = 203 };
        cull_bounds_soa soa = {0};
        assert_true(cull_soa_reserve(&soa, 0, NB));
        double mn[NB][3], mx[NB][3];
        for (int v = 0; v < 8; v++) {
            cull_view view;
            random_view(&r, &s, &view, 1280, 720);
            cull_occ_setup_view(b, &view);
            if (!b->usable) continue;
            for (int i = 0; i < NB; i++) {
                double ext = rng_below(&r, 8) == 0 ? rng_log(&r, 1e-6, 1e-2) : rng_log(&r, 0.1, 5e3);
                for (int a = 0; a < 3; a++) {
                    double c = s.base[a] + rng_range(&r, -300, 300);
                    double e = rng_below(&r, 3) ? ext : rng_log(&r, 1e-3, 50);
                    mn[i][a] = c - e;
                    mx[i][a] = c + e;
                }
                cull_soa_set(&soa, (uint32_t)i, mn[i], mx[i]);
            }
            uint32_t idx[NB], n = rng_below(&r, NB + 1);
            for (uint32_t q = 0; q < n; q++) idx[q] = rng_below(&r, NB);
            size_t pitch = ((size_t)n + 3) & ~(size_t)3;
            double ref[6 * (NB + 3)], got[6 * (NB + 3)];
            cull_occ_project_scalar(b, &soa, idx, n, ref, pitch);
            for (uint32_t q = 0; q < n; q++) {
                const double o[6] = {ref[q], ref[pitch + q], ref[2 * pitch + q], ref[3 * pitch + q],
                                     ref[4 * pitch + q], ref[5 * pitch + q]};
                cull_occ_rect r1 = {0}, r2 = {0};
                int k1 = cull_occ_bound_rect(b, o, &r1), k2 = cull_occ_project_bound(b, mn[idx[q]], mx[idx[q]], &r2);
                if (k1 != k2 || (k1 == OCC_BOX_OK && memcmp(&r1, &r2, sizeof r1)))
                    fail_msg("scene %d view %d box %u: the projection's answer %d, project_bound's %d", sc, v, idx[q],
                             k1, k2);
                boxes++;
                near += k1 == OCC_BOX_NEAR;
                drawn += k1 == OCC_BOX_OK;
            }
#ifndef CULL_SCALAR_ONLY
            /* the render's AVX2 build's rectangles, four a vector */
            if (cull_isa_supported(CULL_ISA_AVX2)) {
                int32_t code[NB + 3];
                cull_occ_rect rr[NB + 3];
                cull_occ_rects_avx2(b, ref, pitch, n, code, rr);
                for (uint32_t q = 0; q < n; q++) {
                    const double o[6] = {ref[q], ref[pitch + q], ref[2 * pitch + q], ref[3 * pitch + q],
                                         ref[4 * pitch + q], ref[5 * pitch + q]};
                    cull_occ_rect r1 = {0};
                    int k1 = cull_occ_bound_rect(b, o, &r1);
                    if (code[q] != k1 || (k1 == OCC_BOX_OK && memcmp(&r1, &rr[q], sizeof r1)))
                        fail_msg("scene %d view %d box %u: rects_avx2 %d [%d %d %d %d %a], bound_rect %d [%d %d %d %d %a]",
                                 sc, v, idx[q], code[q], rr[q].x0, rr[q].y0, rr[q].x1, rr[q].y1, (double)rr[q].z, k1,
                                 r1.x0, r1.y0, r1.x1, r1.y1, (double)r1.z);
                }
            }
#endif
            for (uint32_t isa = 0; isa < CULL_ISA_COUNT; isa++) {
                if (!cull_isa_supported(isa)) continue;
                memset(got, 0, sizeof got);
                cull_occ_fns_for(isa).project(b, &soa, idx, n, got, pitch);
                for (int k = 0; k < 6; k++)
                    for (uint32_t q = 0; q < n; q++) {
                        /* bounds only where the box does not reach the near plane */
                        if (k < 5 && ref[5 * pitch + q] != 0) continue;
                        if (memcmp(&got[k * pitch + q], &ref[k * pitch + q], sizeof(double)))
                            fail_msg("scene %d view %d, %s: entry %d of box %u: %a, the reference %a", sc, v,
                                     cull_isa_name(isa), k, q, got[k * pitch + q], ref[k * pitch + q]);
                    }
            }
        }
        free(soa.v);
        cull_occ_buffer_destroy(b);
        free_scene(&s);
    }
    /* both kinds common */
    assert_true(near > boxes / 50 && drawn > boxes / 10);
}

/* cull_round_up / cull_round_down (inlined, a step of the float's bits)
 * against libm's nextafterf: every power-of-two boundary, zeros,
 * denormals, the largest floats and infinities, and random doubles of
 * every magnitude; the result is the nearest float on the right side. */
static void test_round_matches_nextafter(void **state)
{
    (void)state;
    rng r = {0x0a11ull};
    int cases = (int)(200000 * test_scale());
    for (int t = 0; t < cases + 64; t++) {
        double v;
        if (t < 16) {
            static const double special[16] = {0.0, -0.0, 0x1p-149, -0x1p-149, 0x1p-150, -0x1p-150, 0x1p-126,
                                               -0x1p-126, FLT_MAX, -FLT_MAX, 0x1.fffffffp127, -0x1.fffffffp127,
                                               0x1p128, -0x1p128, INFINITY, -INFINITY};
            v = special[t];
        } else {
            v = ldexp(rng_range(&r, 0.5, 1.0), (int)rng_below(&r, 300) - 150) * (rng_below(&r, 2) ? 1 : -1);
            if (rng_below(&r, 4) == 0) v = (double)(float)v; /* exactly a float */
        }
        float up = cull_round_up(v), dn = cull_round_down(v);
        float f = (float)v;
        float wup = (double)f < v ? nextafterf(f, INFINITY) : f, wdn = (double)f > v ? nextafterf(f, -INFINITY) : f;
        if (memcmp(&up, &wup, sizeof up) || memcmp(&dn, &wdn, sizeof dn))
            fail_msg("%a: up %a (nextafterf %a), down %a (%a)", v, (double)up, (double)wup, (double)dn, (double)wdn);
        if (!((double)up >= v) || !((double)dn <= v)) fail_msg("%a: not on its side", v);
    }
}

/* The render's AVX2 build (cull_occ_raster_avx2.c: inlined rows, the
 * rectangles and the coarse values' starts in vectors, tiles compared
 * eight at a time) draws what its baseline build draws with the same
 * kernels, bit for bit: every array the render leaves (pixels, the tiles'
 * minima, maxima, coarse and effective values, keys and states, strips,
 * big tiles), over random scenes, views, sizes, covers and 1-2 threads,
 * each buffer drawn several times over (stale tiles from the frame
 * before). */
static void test_occ_avx2_build_same_bits(void **state)
{
    (void)state;
    if (!cull_isa_supported(CULL_ISA_AVX2)) skip();
    rng r = {0xa7b2ull};
    static const uint32_t sizes[][2] = {{256, 114}, {1280, 720}, {37, 29}, {512, 256}, {8, 8}};
    cull_pool *pool = NULL;
    assert_int_equal(cull_pool_create(2, &pool), CULL_OK);
    int scenes = (int)(16 * test_scale()), compared = 0, drawn = 0;
    for (int sc = 0; sc < scenes; sc++) {
        oscene s;
        build_scene(&r, &s);
        const uint32_t *sz = sizes[rng_below(&r, sizeof sizes / sizeof sizes[0])];
        cull_occ_buffer *a, *g;
        assert_int_equal(cull_occ_buffer_create(sz[0], sz[1], &a), CULL_OK);
        assert_int_equal(cull_occ_buffer_create(sz[0], sz[1], &g), CULL_OK);
        for (int v = 0; v < 6; v++) {
            cull_view view;
            random_view(&r, &s, &view, sz[0], sz[1]);
            int cover = (int)rng_below(&r, 2);
            uint32_t threads = 1 + rng_below(&r, 2);
            assert_int_equal(cull_occ_buffer_set_cover(a, cover), CULL_OK);
            assert_int_equal(cull_occ_buffer_set_cover(g, cover), CULL_OK);
            cull_occ_stats sa, sg;
            assert_int_equal(cull_occ_render_isa(s.w, &view, a, pool, threads, CULL_ISA_AVX2, NULL, &sa), CULL_OK);
            assert_int_equal(cull_occ_render_generic(s.w, &view, g, pool, threads, CULL_ISA_AVX2, NULL, &sg), CULL_OK);
            drawn += sa.faces_drawn > 0;
            assert_int_equal(sa.faces_drawn, sg.faces_drawn);
            assert_int_equal(sa.clusters_drawn, sg.clusters_drawn);
            assert_int_equal(a->drawn, g->drawn);
            size_t rows = (a->h + 7) / 8, nt = rows * a->tw;
            struct { const void *x, *y; size_t n; const char *what; } arr[] = {
                {a->tile, g->tile, nt * sizeof(float), "tile minima"},
                {a->tile_full, g->tile_full, nt * sizeof(float), "coarse values"},
                {a->teff, g->teff, nt * sizeof(float), "effective minima"},
                {a->tmax, g->tmax, nt * sizeof(float), "tile maxima"},
                {a->vkey, g->vkey, nt * sizeof(float), "keys"},
                {a->tstate, g->tstate, rows * a->tpitch, "tile states"},
                {a->strip, g->strip, rows * a->spitch * sizeof(float), "strips"},
                {a->tile2, g->tile2, (size_t)a->t2w * a->t2h * sizeof(float), "big tiles"},
            };
            for (size_t k = 0; k < sizeof arr / sizeof arr[0]; k++)
                if (memcmp(arr[k].x, arr[k].y, arr[k].n))
                    fail_msg("scene %d view %d (%ux%u, cover %d, %u threads): the %s differ", sc, v, sz[0], sz[1],
                             cover, threads, arr[k].what);
            /* the pixels of every tile the renders wrote (the states are
               the same), wherever each put them */
            for (size_t t = 0; t < nt; t++)
                if (a->tstate[t / a->tw * a->tpitch + t % a->tw] != OCC_TILE_INVALID &&
                    memcmp(cull_occ_tile_px(a, t), cull_occ_tile_px(g, t), 64 * sizeof(float)))
                    fail_msg("scene %d view %d (%ux%u, cover %d, %u threads): tile %zu's pixels differ", sc, v,
                             sz[0], sz[1], cover, threads, t);
            compared++;
        }
        cull_occ_buffer_destroy(a);
        cull_occ_buffer_destroy(g);
        free_scene(&s);
    }
    cull_pool_destroy(pool);
    assert_true(drawn > compared / 3);
}

static void test_occ_wide_matches_scalar(void **state)
{
    (void)state;
    rng r = {0x31de5ca1};
    static const uint32_t sizes[][2] = {{256, 114}, {64, 64}, {37, 29}, {512, 256}, {1280, 720}, {8, 8}};
    int scenes = (int)(24 * test_scale());
    uint64_t rects = 0, checked = 0, visible = 0, lanes_checked = 0;
    for (int sc = 0; sc < scenes; sc++) {
        oscene s;
        build_scene(&r, &s);
        const uint32_t *sz = sizes[rng_below(&r, sizeof sizes / sizeof sizes[0])];
        cull_occ_buffer *b;
        assert_int_equal(cull_occ_buffer_create(sz[0], sz[1], &b), CULL_OK);
        for (int v = 0; v < 4; v++) {
            cull_view view;
            random_view(&r, &s, &view, sz[0], sz[1]);
            assert_int_equal(cull_occ_buffer_set_cover(b, rng_below(&r, 2)), CULL_OK);
            assert_int_equal(cull_occ_render(s.w, &view, b, NULL, 1 + rng_below(&r, 2), NULL), CULL_OK);
            if (rng_below(&r, 4) == 0) assert_non_null(cull_occ_depth(b, NULL, NULL, NULL));
            for (int k = 0; k < 400; k++) {
                int x0, x1, y0, y1;
                pick_span(&r, b->w, &x0, &x1);
                pick_span(&r, b->h, &y0, &y1);
                float z = pick_z(&r, b, x0, y0, x1, y1);
                bool want = cull_occ_rect_visible(b, x0, y0, x1, y1, z);
                visible += want;
                rects++;
                for (uint32_t isa = 0; isa < CULL_ISA_COUNT; isa++) {
                    if (!cull_isa_supported(isa)) continue;
                    bool got = cull_occ_fns_for(isa).rect_visible(b, x0, y0, x1, y1, z);
                    if (got != want)
                        fail_msg("%s, %ux%u, [%d, %d] x [%d, %d] at %a: %d, the scalar test %d", cull_isa_name(isa),
                                 b->w, b->h, x0, x1, y0, y1, (double)z, got, want);
                    checked++;
                }
            }
            for (int k = 0; k < 100; k++) {
                float fx0[8], fx1[8], fy0[8], fy1[8], fz[8];
                uint32_t want = 0, lanes = rng_below(&r, 256);
                for (int l = 0; l < 8; l++) {
                    fx0[l] = pick_bound(&r, b->w);
                    fx1[l] = rng_below(&r, 8) ? fx0[l] + (float)rng_f(&r) * (float)rng_log(&r, 0.5, b->w)
                                               : pick_bound(&r, b->w);
                    fx1[l] = fx1[l] > (float)b->w + 1.0f ? (float)b->w + 1.0f : fx1[l];
                    fy0[l] = pick_bound(&r, b->h);
                    fy1[l] = rng_below(&r, 8) ? fy0[l] + (float)rng_f(&r) * (float)rng_log(&r, 0.5, b->h)
                                               : pick_bound(&r, b->h);
                    fy1[l] = fy1[l] > (float)b->h + 1.0f ? (float)b->h + 1.0f : fy1[l];
                    int cx = (int)fx0[l] < 0 ? 0 : (int)fx0[l] >= (int)b->w ? (int)b->w - 1 : (int)fx0[l];
                    int cy = (int)fy0[l] < 0 ? 0 : (int)fy0[l] >= (int)b->h ? (int)b->h - 1 : (int)fy0[l];
                    fz[l] = pick_z(&r, b, cx, cy, cx, cy);
                    if ((lanes >> l & 1) && ref_lane(b, fx0[l], fx1[l], fy0[l], fy1[l], fz[l])) want |= 1u << l;
                }
                for (uint32_t isa = 0; isa < CULL_ISA_COUNT; isa++) {
                    if (!cull_isa_supported(isa)) continue;
                    uint32_t got = cull_occ_fns_for(isa).lanes(b, fx0, fx1, fy0, fy1, fz, lanes);
                    if (got != want) {
                        int l = __builtin_ctz(got ^ want);
                        fail_msg("%s, %ux%u, lanes %02x: %02x, the scalar test %02x; lane %d: x %a..%a, y %a..%a, z %a",
                                 cull_isa_name(isa), b->w, b->h, lanes, got, want, l, (double)fx0[l], (double)fx1[l],
                                 (double)fy0[l], (double)fy1[l], (double)fz[l]);
                    }
                    lanes_checked += (uint32_t)__builtin_popcount(lanes);
                }
            }
        }
        cull_occ_buffer_destroy(b);
        free_scene(&s);
    }
    /* both answers must be common, or the comparison says little */
    assert_true(visible > rects / 20 && visible < rects - rects / 20);
    fprintf(stderr, "occlusion rectangle test: %llu rectangles and %llu lanes, every ISA as the scalar test "
                    "(%llu%% visible)\n", (unsigned long long)checked, (unsigned long long)lanes_checked,
            (unsigned long long)(visible * 100 / (rects ? rects : 1)));
}

const struct CMUnitTest occlusion_tests[] = {
    cmocka_unit_test(test_occ_wide_matches_scalar),
    cmocka_unit_test(test_occ_buffer_reuse),
    cmocka_unit_test(test_occ_spans_match_span),
    cmocka_unit_test(test_occ_rows_match_model),
    cmocka_unit_test(test_occ_project_matches_bound),
    cmocka_unit_test(test_round_matches_nextafter),
    cmocka_unit_test(test_occ_avx2_build_same_bits),
    cmocka_unit_test(test_occluder_cut_bound),
    cmocka_unit_test(test_occluder_build_bound),
    cmocka_unit_test(test_bad_occluders),
    cmocka_unit_test(test_camera_inside_occluder),
    cmocka_unit_test(test_edits_change_occlusion),
    cmocka_unit_test(test_multi_view_matches_single),
    cmocka_unit_test(test_wall_through_near_plane),
    cmocka_unit_test(test_random_scenes_never_false_occluded),
    cmocka_unit_test(test_sublevel_filter),
    cmocka_unit_test(test_adversarial_views_never_false_culled),
};
const size_t occlusion_tests_count = sizeof occlusion_tests / sizeof occlusion_tests[0];
