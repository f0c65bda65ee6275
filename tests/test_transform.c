/*
 * test_transform.c — entities placed by a transform (VP_ENT_TRANSFORM),
 * through a real daemon: the bounds it derives hold the exact image of the
 * class mesh's local box (a long-double model of its 8 corners under the
 * TRS) and are tight to it; no query culls a point of the transformed mesh;
 * TRANSFORM_SET shows in the very next query; every batch is all or
 * nothing; each bad input gets its code, record and field; a new mesh
 * re-derives its class (or is refused); attached occluders and
 * destruction follow the entity.
 */
#include "test_util.h"

#include "test_daemon.h"
#include "vantage.h"

#include <math.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#define CLS 7

/* A mesh of nv random points in [lo, hi] with lo and hi among them (its
 * local box is exactly [lo, hi]); triangles over consecutive points. */
static const double MLO[3] = {-2, -1, -3}, MHI[3] = {4, 5, 1};
static void put_mesh(vtc_client *c, uint16_t cls, const double lo[3], const double hi[3], rng *r)
{
    enum { NV = 30 };
    float pos[3 * NV];
    uint32_t idx[3 * (NV - 2)];
    for (int v = 0; v < NV; v++)
        for (int a = 0; a < 3; a++)
            pos[3 * v + a] = (float)(v == 0 ? lo[a] : v == 1 ? hi[a] : rng_range(r, lo[a], hi[a]));
    for (int t = 0; t < NV - 2; t++) idx[3 * t] = (uint32_t)t, idx[3 * t + 1] = (uint32_t)t + 1, idx[3 * t + 2] = (uint32_t)t + 2;
    assert_int_equal(vtc_put_mesh(c, cls, pos, NULL, NV, idx, 3 * (NV - 2)), VP_OK);
}

/* A random unit quaternion (as floats, normalised in double). */
static void rand_quat(rng *r, float q[4])
{
    double v[4], n = 0;
    do {
        n = 0;
        for (int a = 0; a < 4; a++) {
            v[a] = rng_range(r, -1, 1);
            n += v[a] * v[a];
        }
    } while (n < 1e-3 || n > 1);
    for (int a = 0; a < 4; a++) q[a] = (float)(v[a] / sqrt(n));
}

static void rand_trs(rng *r, vp_entity *e, uint64_t id)
{
    double pos[3];
    float q[4], s[3];
    int kind = (int)rng_below(r, 3);
    for (int a = 0; a < 3; a++) {
        pos[a] = kind == 0 ? rng_range(r, -100, 100) : kind == 1 ? rng_range(r, -1e4, 1e4) : rng_log(r, 1e6, 1e9);
        if (kind == 2 && rng_below(r, 2)) pos[a] = -pos[a];
        s[a] = (float)rng_log(r, 0.01, 100) * (rng_below(r, 3) == 0 ? -1.0f : 1.0f); /* negative: mirrored */
    }
    if (rng_below(r, 6) == 0) s[rng_below(r, 3)] = 0; /* flat on one axis */
    rand_quat(r, q);
    vtc_entity_trs(e, id, CLS, pos, q, s);
}

/* Model: corner k of [lo, hi] under e's TRS, in long double, with the
 * rotation the daemon stored (its floats; R(q/|q|)). */
static void model_corner(const vp_entity *e, const double lo[3], const double hi[3], int k, long double out[3])
{
    long double x = e->rot[0], y = e->rot[1], z = e->rot[2], w = e->rot[3];
    long double s = 2.0L / (x * x + y * y + z * z + w * w);
    long double R[3][3] = {{1 - s * (y * y + z * z), s * (x * y - z * w), s * (x * z + y * w)},
                           {s * (x * y + z * w), 1 - s * (x * x + z * z), s * (y * z - x * w)},
                           {s * (x * z - y * w), s * (y * z + x * w), 1 - s * (x * x + y * y)}};
    long double p[3];
    for (int a = 0; a < 3; a++) p[a] = (long double)((k >> a) & 1 ? hi[a] : lo[a]) * e->scale[a];
    for (int a = 0; a < 3; a++) out[a] = e->pos[a] + R[a][0] * p[0] + R[a][1] * p[1] + R[a][2] * p[2];
}

/* Whether a query with one view sees entity id. */
static bool view_sees(vtc_client *c, const double eye[3], const double at[3], double znear, double zfar, uint64_t id)
{
    vp_view v;
    double up[3] = {0, 1, 0};
    if (fabs(eye[0] - at[0]) < 1e-9 * fabs(eye[0]) + 1e-12 && fabs(eye[2] - at[2]) < 1e-9 * fabs(eye[2]) + 1e-12)
        up[0] = 1, up[1] = 0; /* looking straight down or up */
    assert_true(vtc_view_perspective(&v, eye, at, up, 40, 320, 240, znear, zfar));
    vp_vis_result res;
    assert_int_equal(vtc_query(c, &v, 1, 0, 0, &res), VP_OK);
    for (uint32_t i = 0; i < res.count; i++) {
        vp_vis_rec rec;
        vp_vis_rec_get(&res, i, &rec);
        if (rec.id == id) return true;
    }
    return false;
}

static void get_one(vtc_client *c, uint64_t id, vp_entity *out)
{
    vp_list_reply lr;
    assert_int_equal(vtc_get(c, &id, 1, &lr), VP_OK);
    assert_int_equal(lr.batch.count, 1);
    assert_int_equal(vp_entity_get(&lr.batch, 0, out), VP_OK);
}

static void test_transform_bounds_match_model(void **state)
{
    daemon_proc *d = *state;
    vtc_client *c = connect_role(d, VP_ROLE_EDITOR, false);
    rng r = {test_seed() ^ 0x7F5u};
    put_mesh(c, CLS, MLO, MHI, &r);
    enum { N = 240 };
    vp_entity e[N];
    for (int i = 0; i < N; i++) rand_trs(&r, &e[i], 1000 + (uint64_t)i);
    uint32_t hs[N];
    assert_int_equal(vtc_add(c, e, N, hs, NULL), VP_OK);
    double worst = 0;
    int seen = 0;
    for (int i = 0; i < N; i++) {
        vp_entity g, sent = e[i];
        get_one(c, e[i].id, &g);
        /* the model takes the rotation the daemon stored: the one sent,
           renormalised once as the daemon's decoder does (ENTITY_GET's
           record is renormalised again by this client's decoder) */
        assert_int_equal(vp_trs_check(sent.pos, sent.rot, sent.scale, NULL, 0), VP_OK);
        memcpy(g.rot, sent.rot, sizeof g.rot);
        assert_int_equal(g.handle, hs[i]);
        assert_int_equal(g.class_id, CLS);
        assert_int_equal(g.flags, VP_ENT_TRANSFORM);
        assert_memory_equal(g.pos, e[i].pos, sizeof g.pos);
        assert_memory_equal(g.scale, e[i].scale, sizeof g.scale);
        for (int a = 0; a < 4; a++) assert_true(fabsf(g.rot[a] - e[i].rot[a]) <= 1e-6f);
        long double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
        long double A = 0; /* the size the outward rounding scales with */
        for (int a = 0; a < 3; a++) A += fabsl((long double)e[i].scale[a]) * fmax(fabs(MLO[a]), fabs(MHI[a]));
        for (int k = 0; k < 8; k++) {
            long double p[3];
            model_corner(&g, MLO, MHI, k, p);
            long double d2 = 0;
            for (int a = 0; a < 3; a++) {
                lo[a] = fminl(lo[a], p[a]);
                hi[a] = fmaxl(hi[a], p[a]);
                d2 += (p[a] - g.sphere[a]) * (p[a] - g.sphere[a]);
            }
            /* every corner inside the sphere and the box: never a false cull */
            if (!(sqrtl(d2) <= g.sphere[3])) fail_msg("entity %d: corner %d outside the sphere", i, k);
            for (int a = 0; a < 3; a++)
                if (!(p[a] >= g.aabb[a] && p[a] <= g.aabb[3 + a]))
                    fail_msg("entity %d: corner %d axis %d %.17Lg outside [%.17g, %.17g]", i, k, a, p[a], g.aabb[a],
                             g.aabb[3 + a]);
        }
        /* and tight: the box is the exact one rounded outward by a few ulps
           of (|t| + A) plus the culling world's own outward rounding of
           stored bounds ((4 cell + r + reach) 2^-19) */
        for (int a = 0; a < 3; a++) {
            long double tol = 0x1p-40L * (fabsl((long double)e[i].pos[a]) + A) + 1e-12L;
            long double slack = fmaxl(lo[a] - g.aabb[a], g.aabb[3 + a] - hi[a]);
            if (!(slack <= tol)) fail_msg("entity %d axis %d: box %.3Lg m looser than the exact one", i, a, slack);
            worst = fmax(worst, (double)(slack / tol));
        }
        /* a query aimed at a mesh corner from 5 m sees it */
        long double p[3];
        model_corner(&g, MLO, MHI, (int)rng_below(&r, 8), p);
        double at[3] = {(double)p[0], (double)p[1], (double)p[2]};
        double eye[3] = {at[0] + 3, at[1] + 2, at[2] - 3.4};
        if (view_sees(c, eye, at, 0.1, 50, e[i].id)) seen++;
        else fail_msg("entity %d: a view at its corner does not see it", i);
    }
    fprintf(stderr, "transform bounds: %d entities hold their corners; slack at most %.3g of the tolerance; %d "
                    "seen from their corners\n", N, worst, seen);
    vtc_close(c);
}

/* Entity with a transform moved by TRANSFORM_SET: the next query sees it at
 * its new place and not at its old; the record shows the new transform. */
static void test_transform_set_visible_next_query(void **state)
{
    daemon_proc *d = *state;
    vtc_client *c = connect_role(d, VP_ROLE_EDITOR, false), *v = connect_role(d, VP_ROLE_VIEWER, true);
    rng r = {test_seed() ^ 0x51u};
    put_mesh(c, CLS, MLO, MHI, &r);
    vp_entity e;
    double p0[3] = {0, 0, 0};
    float q[4] = {0, 0, 0, 1}, s[3] = {1, 1, 1};
    vtc_entity_trs(&e, 5, CLS, p0, q, s);
    uint32_t h;
    assert_int_equal(vtc_add(c, &e, 1, &h, NULL), VP_OK);
    double eye0[3] = {0, 2, -30}, at0[3] = {0, 2, 0}, eye1[3] = {5000, 2, -30}, at1[3] = {5000, 2, 0};
    assert_true(view_sees(v, eye0, at0, 0.5, 100, 5));
    assert_false(view_sees(v, eye1, at1, 0.5, 100, 5));
    for (int k = 1; k <= 20; k++) {
        vp_transform t = {.id = 5, .handle = h, .pos = {k % 2 ? 5000 : 0, 0, 0}, .rot = {0, 0.7071068f, 0, 0.7071068f},
                          .scale = {2, 2, -2}};
        uint64_t ep;
        assert_int_equal(vtc_transform_set(c, &t, 1, &ep), VP_OK);
        assert_true(view_sees(v, k % 2 ? eye1 : eye0, k % 2 ? at1 : at0, 0.5, 100, 5));
        assert_false(view_sees(v, k % 2 ? eye0 : eye1, k % 2 ? at0 : at1, 0.5, 100, 5));
    }
    vp_entity g;
    get_one(c, 5, &g);
    assert_true(g.pos[0] == 0 && g.scale[2] == -2 && fabsf(g.rot[1] - 0.7071068f) < 1e-6f);
    /* the derived box: the mesh rotated 90 degrees about y, scaled 2,2,-2 */
    double want[6] = {-2 * MHI[2], 2 * MLO[1], -2 * MHI[0], -2 * MLO[2], 2 * MHI[1], -2 * MLO[0]};
    for (int a = 0; a < 6; a++) assert_true(fabs(g.aabb[a] - want[a]) < 1e-4);
    vtc_close(v);
    vtc_close(c);
}

/* Every entity in [0, n) of ids, or none, is in the scene. */
static uint32_t listed(vtc_client *c)
{
    uint32_t n = 0;
    uint64_t cur = 0;
    do {
        vp_list_reply lr;
        assert_int_equal(vtc_list(c, cur, 1000, &lr), VP_OK);
        n += lr.batch.count;
        cur = lr.next_cursor;
    } while (cur);
    return n;
}

static void test_transform_batches_all_or_nothing(void **state)
{
    daemon_proc *d = *state;
    vtc_client *c = connect_role(d, VP_ROLE_EDITOR, false);
    rng r = {test_seed() ^ 0xA11u};
    put_mesh(c, CLS, MLO, MHI, &r);
    vp_entity e[9];
    for (int i = 0; i < 9; i++) rand_trs(&r, &e[i], 10 + (uint64_t)i);
    e[4].class_id = CLS + 1; /* no mesh */
    assert_int_equal(vtc_add(c, e, 9, NULL, NULL), VP_ERR_UNKNOWN_ID);
    assert_int_equal(vtc_last_error(c)->index, 4);
    assert_int_equal(listed(c), 0);
    e[4].class_id = CLS;
    uint64_t ep0;
    assert_int_equal(vtc_add(c, e, 9, NULL, &ep0), VP_OK);
    assert_int_equal(listed(c), 9);
    /* TRANSFORM_SET with a bad record in the middle: nothing moves */
    vp_transform t[9];
    for (int i = 0; i < 9; i++)
        t[i] = (vp_transform){.id = e[i].id, .pos = {i * 10.0, 1, 2}, .rot = {0, 0, 0, 1}, .scale = {1, 1, 1}};
    t[6].pos[0] = 2e12; /* beyond the world */
    assert_int_equal(vtc_transform_set(c, t, 9, NULL), VP_ERR_INVALID);
    assert_int_equal(vtc_last_error(c)->index, 6);
    for (int i = 0; i < 9; i++) {
        vp_entity g;
        get_one(c, e[i].id, &g);
        assert_memory_equal(g.pos, e[i].pos, sizeof g.pos);
    }
    vp_stats_reply st;
    assert_int_equal(vtc_stats(c, &st), VP_OK);
    assert_int_equal(st.epoch, ep0);
    t[6].pos[0] = 60;
    assert_int_equal(vtc_transform_set(c, t, 9, NULL), VP_OK);
    for (int i = 0; i < 9; i++) {
        vp_entity g;
        get_one(c, e[i].id, &g);
        assert_true(g.pos[0] == i * 10.0 && g.aabb[0] == g.aabb[0]);
        assert_true(g.aabb[0] <= i * 10.0 + MLO[0] && g.aabb[3] >= i * 10.0 + MHI[0]);
    }
    /* ENTITY_UPDATE with a bad record in the middle: nothing changes */
    vp_entity u[3] = {e[0], e[1], e[2]};
    u[0].pos[0] = 77;
    u[1].material = 99; /* no such material */
    assert_int_equal(vtc_update(c, u, 3, NULL), VP_ERR_UNKNOWN_ID);
    assert_int_equal(vtc_last_error(c)->index, 1);
    vp_entity g;
    get_one(c, e[0].id, &g);
    assert_true(g.pos[0] == 0);
    vtc_close(c);
}

/* A bad input of the scene model: what is sent, the code, the record and
 * a word of the field the message must name. */
typedef struct bad_row {
    const char *name;
    int what;       /* 0 ENTITY_ADD of rec, 1 TRANSFORM_SET of tr, 2 OCCLUDER_PUT attached to id occ */
    vp_entity rec;
    vp_transform tr;
    uint64_t occ;
    int code;
    uint32_t index;
    const char *field;
} bad_row;

/* an entity record with a transform: class, material, pos, rot, scale */
#define TRS(cls, mat, px, py, pz, rx, ry, rz, rw, sx, sy, sz)                                               \
    {.id = 50, .flags = VP_ENT_TRANSFORM, .class_id = cls, .material = mat, .pos = {px, py, pz},              \
     .rot = {rx, ry, rz, rw}, .scale = {sx, sy, sz}}
#define TR(id_, h, px, rx, ry, rz, rw, sx, sy, sz) \
    {.id = id_, .handle = h, .pos = {px, 0, 0}, .rot = {rx, ry, rz, rw}, .scale = {sx, sy, sz}}
#define T_OK .rot = {0, 0, 0, 1}, .scale = {1, 1, 1}
static const bad_row bad_rows[] = {
    {"quaternion not unit", 0, TRS(CLS, 0, 0, 0, 0, 0, 0, 0, 1.01f, 1, 1, 1), {0}, 0, VP_ERR_INVALID, 1, "rotation"},
    {"quaternion zero", 0, TRS(CLS, 0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1), {0}, 0, VP_ERR_INVALID, 1, "unit quaternion"},
    {"position NaN", 0, TRS(CLS, 0, 0, NAN, 0, 0, 0, 0, 1, 1, 1, 1), {0}, 0, VP_ERR_NONFINITE, 1, "position y"},
    {"position inf", 0, TRS(CLS, 0, INFINITY, 0, 0, 0, 0, 0, 1, 1, 1, 1), {0}, 0, VP_ERR_NONFINITE, 1, "position x"},
    {"rotation NaN", 0, TRS(CLS, 0, 0, 0, 0, 0, 0, NAN, 1, 1, 1, 1), {0}, 0, VP_ERR_NONFINITE, 1, "rotation z"},
    {"scale inf", 0, TRS(CLS, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1, -INFINITY), {0}, 0, VP_ERR_NONFINITE, 1, "scale z"},
    {"scale 0 on two axes", 0, TRS(CLS, 0, 0, 0, 0, 0, 0, 0, 1, 0, 1, 0), {0}, 0, VP_ERR_INVALID, 1, "2 axes"},
    {"scale 0 on three axes", 0, TRS(CLS, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0), {0}, 0, VP_ERR_INVALID, 1, "3 axes"},
    {"position beyond the world", 0, TRS(CLS, 0, 0, 0, 1.5e12, 0, 0, 0, 1, 1, 1, 1), {0}, 0, VP_ERR_INVALID, 1,
     "position"},
    {"class without a mesh", 0, TRS(300, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1, 1), {0}, 0, VP_ERR_UNKNOWN_ID, 1,
     "mesh class 300"},
    {"unknown material", 0, TRS(CLS, 4242, 0, 0, 0, 0, 0, 0, 1, 1, 1, 1), {0}, 0, VP_ERR_UNKNOWN_ID, 1,
     "material 4242"},
    {"unknown material, bounds entity", 0, {.id = 50, .aabb = {0, 0, 0, 1, 1, 1}, .material = 7}, {0}, 0,
     VP_ERR_UNKNOWN_ID, 1, "material 7"},
    {"transform set: quaternion", 1, {0}, TR(1, 0, 0, 0.5f, 0, 0, 0.5f, 1, 1, 1), 0, VP_ERR_INVALID, 1,
     "unit quaternion"},
    {"transform set: NaN scale", 1, {0}, TR(1, 0, 0, 0, 0, 0, 1, 1, NAN, 1), 0, VP_ERR_NONFINITE, 1, "scale y"},
    {"transform set: two zero axes", 1, {0}, TR(1, 0, 0, 0, 0, 0, 1, 1, 0, 0), 0, VP_ERR_INVALID, 1, "2 axes"},
    {"transform set: unknown id", 1, {0}, TR(999, 0, 0, 0, 0, 0, 1, 1, 1, 1), 0, VP_ERR_UNKNOWN_ID, 1, "id 999"},
    {"transform set: stale handle", 1, {0}, TR(1, 77777, 0, 0, 0, 0, 1, 1, 1, 1), 0, VP_ERR_STALE, 1,
     "handle 77777"},
    {"transform set: no transform", 1, {0}, TR(3, 0, 0, 0, 0, 0, 1, 1, 1, 1), 0, VP_ERR_STATE, 1, "no transform"},
    {"transform set: beyond the world", 1, {0}, TR(1, 0, -3e12, 0, 0, 0, 1, 1, 1, 1), 0, VP_ERR_INVALID, 1,
     "position"},
    {"attached occluder: no entity", 2, {0}, {0}, 12345, VP_ERR_UNKNOWN_ID, UINT32_MAX, "no entity"},
    {"attached occluder: bounds entity", 2, {0}, {0}, 3, VP_ERR_STATE, UINT32_MAX, "no transform"},
};

static void test_transform_bad_input(void **state)
{
    const bad_row *row = *state;
    daemon_proc d;
    vtc_client *c = daemon_open(&d, VP_ROLE_EDITOR);
    rng r = {1};
    put_mesh(c, CLS, MLO, MHI, &r);
    /* entities 1, 2 (transforms), 3 (bounds) */
    vp_entity e[3];
    double p[3] = {0, 0, 0};
    float q[4] = {0, 0, 0, 1}, s[3] = {1, 1, 1};
    vtc_entity_trs(&e[0], 1, CLS, p, q, s);
    vtc_entity_trs(&e[1], 2, CLS, p, q, s);
    e[2] = (vp_entity){.id = 3, .aabb = {0, 0, 0, 1, 1, 1}};
    assert_int_equal(vtc_add(c, e, 3, NULL, NULL), VP_OK);
    vp_stats_reply st0, st1;
    assert_int_equal(vtc_stats(c, &st0), VP_OK);
    int rc;
    if (row->what == 0) {
        vp_entity b[3] = {{.id = 40, .aabb = {0, 0, 0, 1, 1, 1}}, row->rec, {.id = 41, .aabb = {0, 0, 0, 1, 1, 1}}};
        rc = vtc_add(c, b, 3, NULL, NULL);
    } else if (row->what == 1) {
        vp_transform b[3] = {{.id = 2, .pos = {9, 9, 9}, T_OK}, row->tr, {.id = 2, .pos = {9, 9, 9}, T_OK}};
        b[2].id = 1 + (row->tr.id == 1); /* never the bad record's id twice */
        rc = vtc_transform_set(c, b, 3, NULL);
    } else {
        float tri[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
        double o[3] = {0, 0, 0};
        rc = vtc_put_occluder_flags(c, row->occ, VP_OCC_ATTACHED, o, tri, 1);
    }
    const vtc_error *er = vtc_last_error(c);
    fprintf(stderr, "%s: %d record %d: %s\n", row->name, rc, (int)er->index, er->msg);
    assert_int_equal(rc, row->code);
    assert_int_equal(er->index, row->index);
    assert_non_null(strstr(er->msg, row->field));
    if (row->index != UINT32_MAX) {
        char rec[32];
        snprintf(rec, sizeof rec, "record %u", row->index);
        assert_non_null(strstr(er->msg, rec));
    }
    /* nothing changed */
    assert_int_equal(vtc_stats(c, &st1), VP_OK);
    assert_int_equal(st1.epoch, st0.epoch);
    assert_int_equal(st1.entities, 3);
    vp_entity g;
    get_one(c, 2, &g);
    assert_true(g.pos[0] == 0);
    daemon_close(&d, c);
}

/* A new mesh for a class: its transform entities take the new bounds; a
 * mesh that would put one beyond the world is refused, nothing changed. */
static void test_transform_mesh_rederives(void **state)
{
    daemon_proc *d = *state;
    vtc_client *c = connect_role(d, VP_ROLE_EDITOR, false);
    rng r = {test_seed() ^ 0x3E5u};
    put_mesh(c, CLS, MLO, MHI, &r);
    vp_entity e[2];
    double p0[3] = {10, 0, 0}, p1[3] = {1.37e11, 0, 0};
    float q[4] = {0, 0, 0, 1}, s[3] = {1, 1, 1};
    vtc_entity_trs(&e[0], 1, CLS, p0, q, s);
    vtc_entity_trs(&e[1], 2, CLS, p1, q, s);
    int arc = vtc_add(c, e, 2, NULL, NULL);
    if (arc) fail_msg("add: %s", vtc_last_error(c)->msg);
    double lo2[3] = {-1, -1, -1}, hi2[3] = {20, 1, 1};
    put_mesh(c, CLS, lo2, hi2, &r);
    vp_entity g;
    get_one(c, 1, &g);
    assert_true(g.aabb[0] <= 9 && g.aabb[0] > 8.99 && g.aabb[3] >= 30 && g.aabb[3] < 30.01);
    /* a mesh 1.8e9 m long: entity 2's centre would be 1.379e11 m out, past
       the range of a world of 64 m cells (2^31 cells, 1.374e11 m) */
    float pos[9] = {0, 0, 0, 1.8e9f, 1, 1, 0, 1, 0};
    uint32_t idx[3] = {0, 1, 2};
    int rc = vtc_put_mesh(c, CLS, pos, NULL, 3, idx, 3);
    fprintf(stderr, "mesh refused: %s\n", vtc_last_error(c)->msg);
    assert_int_equal(rc, VP_ERR_INVALID);
    assert_non_null(strstr(vtc_last_error(c)->msg, "entity 2"));
    get_one(c, 1, &g);
    assert_true(g.aabb[3] >= 30 && g.aabb[3] < 30.01); /* the old mesh stands */
    vtc_close(c);
}

static void box_tris(const double lo[3], const double hi[3], float t[108])
{
    float X = (float)(hi[0] - lo[0]), Y = (float)(hi[1] - lo[1]), Z = (float)(hi[2] - lo[2]);
    const float k[8][3] = {{0, 0, 0}, {X, 0, 0}, {X, Y, 0}, {0, Y, 0}, {0, 0, Z}, {X, 0, Z}, {X, Y, Z}, {0, Y, Z}};
    static const int f[12][3] = {{0, 3, 2}, {0, 2, 1}, {4, 5, 6}, {4, 6, 7}, {0, 1, 5}, {0, 5, 4},
                                 {3, 7, 6}, {3, 6, 2}, {0, 4, 7}, {0, 7, 3}, {1, 2, 6}, {1, 6, 5}};
    for (int i = 0; i < 12; i++)
        for (int v = 0; v < 3; v++)
            for (int a = 0; a < 3; a++) t[i * 9 + v * 3 + a] = k[f[i][v]][a];
}

/* A wall entity (class 9, a box mesh 20 x 8 x 1 centred on x and z) with
 * its attached box occluder, at pos with scale s; crates (bounds entities)
 * to hide. */
static const double WLO[3] = {-10, 0, -0.5}, WHI[3] = {10, 8, 0.5};
static void wall(vtc_client *c, uint64_t id, const double pos[3], const float s[3])
{
    float pos8[24];
    for (int k = 0; k < 8; k++)
        for (int a = 0; a < 3; a++) pos8[3 * k + a] = (float)((k >> a) & 1 ? WHI[a] : WLO[a]);
    uint32_t idx[3] = {0, 1, 2};
    assert_int_equal(vtc_put_mesh(c, 9, pos8, NULL, 8, idx, 3), VP_OK);
    vp_entity e;
    float q[4] = {0, 0, 0, 1};
    vtc_entity_trs(&e, id, 9, pos, q, s);
    assert_int_equal(vtc_add(c, &e, 1, NULL, NULL), VP_OK);
    float tri[108];
    box_tris(WLO, WHI, tri);
    assert_int_equal(vtc_put_occluder_flags(c, id, VP_OCC_ATTACHED, WLO, tri, 12), VP_OK);
}

static void crate(vtc_client *c, uint64_t id, double x, double y, double z)
{
    vp_entity e = {.id = id, .aabb = {x - 0.25, y - 0.25, z - 0.25, x + 0.25, y + 0.25, z + 0.25}};
    assert_int_equal(vtc_add(c, &e, 1, NULL, NULL), VP_OK);
}

static bool street_sees(vtc_client *c, double x, uint64_t id)
{
    double eye[3] = {x, 2, -30}, at[3] = {x, 2, 0};
    return view_sees(c, eye, at, 0.5, 500, id);
}

static void move(vtc_client *c, uint64_t id, double x, double z, const float rot[4], const float s[3])
{
    vp_transform t = {.id = id, .pos = {x, 0, z}};
    memcpy(t.rot, rot, sizeof t.rot);
    memcpy(t.scale, s, sizeof t.scale);
    assert_int_equal(vtc_transform_set(c, &t, 1, NULL), VP_OK);
}

/* The occluder follows its entity's transform with no re-upload, mirrored
 * ones stay conservative, and it goes when the entity goes. */
static void test_attached_occluder_follows(void **state)
{
    daemon_proc *d = *state;
    vtc_client *c = connect_role(d, VP_ROLE_EDITOR, false);
    double p[3] = {0, 0, 0};
    float one[3] = {1, 1, 1}, id4[4] = {0, 0, 0, 1};
    wall(c, 10, p, one);
    crate(c, 20, 0, 2, 10);   /* behind the wall */
    crate(c, 21, 300, 2, 10); /* behind the wall's next place */
    assert_false(street_sees(c, 0, 20));
    assert_true(street_sees(c, 300, 21));
    move(c, 10, 300, 0, id4, one);
    assert_true(street_sees(c, 0, 20));
    assert_false(street_sees(c, 300, 21));
    /* turned 90 degrees about x: lying flat (y within +-0.5 m), it hides
       nothing 2 m up */
    float pitch90[4] = {0.70710678f, 0, 0, 0.70710678f};
    move(c, 10, 300, 0, pitch90, one);
    assert_true(street_sees(c, 300, 21));
    /* mirrored (x and then z): still hides from the street; and a camera
       inside the mirrored wall (scaled 10x in z: 10 m thick) sees the
       crate beyond it, as it would inside an unmirrored one (a closed
       occluder hides nothing from inside). Drawn with the winding as sent,
       the mirrored shell's far side faces the camera and hid the crate. */
    float mx[3] = {-1, 1, 1}, mz[3] = {1, 1, -10};
    move(c, 10, 300, 0, id4, mx);
    assert_false(street_sees(c, 300, 21));
    move(c, 10, 300, 0, id4, mz);
    assert_false(street_sees(c, 300, 21));
    double eye[3] = {300, 4, -3}, at[3] = {300, 2, 10};
    assert_true(view_sees(c, eye, at, 0.1, 100, 21));
    move(c, 10, 300, 0, id4, (float[3]){1, 1, 10});
    assert_true(view_sees(c, eye, at, 0.1, 100, 21));
    /* an ENTITY_UPDATE of the transform moves it too */
    vp_entity u;
    double back[3] = {0, 0, 0};
    vtc_entity_trs(&u, 10, 9, back, id4, one);
    assert_int_equal(vtc_update(c, &u, 1, NULL), VP_OK);
    assert_false(street_sees(c, 0, 20));
    assert_true(street_sees(c, 300, 21));
    /* the entity keeps its transform while the occluder is attached */
    u.flags = 0;
    u.aabb[3] = u.aabb[4] = u.aabb[5] = 1;
    assert_int_equal(vtc_update(c, &u, 1, NULL), VP_ERR_STATE);
    /* the entity goes: so does its occluder */
    vp_stats_reply st;
    assert_int_equal(vtc_stats(c, &st), VP_OK);
    uint64_t gone = 10;
    assert_int_equal(vtc_remove(c, &gone, 1, NULL), VP_OK);
    assert_true(street_sees(c, 0, 20));
    assert_int_equal(vtc_remove_occluders(c, &gone, 1, NULL), VP_ERR_UNKNOWN_ID);
    vtc_close(c);
}

/* Destruction follows the transform: a hole cut in a wall moves with it,
 * so a query through the hole sees behind it at the new place. */
static void test_destruction_follows(void **state)
{
    daemon_proc *d = *state;
    vtc_client *c = connect_role(d, VP_ROLE_EDITOR, false);
    double p[3] = {0, 0, 0};
    float one[3] = {1, 1, 1}, id4[4] = {0, 0, 0, 1};
    wall(c, 10, p, one);
    crate(c, 20, -5, 2, 10); /* behind the hole-to-be */
    crate(c, 21, 5, 2, 10);  /* behind where the hole goes when the wall turns */
    assert_false(street_sees(c, -5, 20));
    vp_destroy m = {.id = 10, .center = {-5, 2, 0}, .radius = 2.5};
    vp_destroyed out;
    assert_int_equal(vtc_send_destruction(c, &m, &out), VP_OK);
    assert_true(out.occluder_tris > 12);
    /* (the hole is cut 2.5 m plus the volume's margin, about 2 m, wide) */
    assert_true(street_sees(c, -5, 20));
    assert_false(street_sees(c, 5, 21));
    /* turned half round about y (its box the same): the hole is at x = +5 */
    float yaw180[4] = {0, 1, 0, 0};
    move(c, 10, 0, 0, yaw180, one);
    assert_true(street_sees(c, 5, 21));
    assert_false(street_sees(c, -5, 20));
    /* slid 10 m along x, unturned: the hole at x = 5 again */
    move(c, 10, 10, 0, id4, one);
    assert_true(street_sees(c, 5, 21));
    /* back where it was destroyed: as before */
    move(c, 10, 0, 0, id4, one);
    assert_true(street_sees(c, -5, 20));
    assert_false(street_sees(c, 5, 21));
    vtc_close(c);
}

/* The CLI: material put / rm, add --mesh with --rotate / --quat /
 * --scale, move of a transform entity, the sphere form kept, bad values
 * refused with exit 2 before anything is sent, the server's refusals
 * with exit 1 and its message. */
static void test_cli_transforms_and_materials(void **state)
{
    daemon_proc *d = *state;
    vtc_client *c = connect_role(d, VP_ROLE_EDITOR, false);
    rng r = {3};
    put_mesh(c, CLS, MLO, MHI, &r);
    char out[4096];
    assert_int_equal(vantage_run(d, out, sizeof out, "material put 3 --base 0.8,0.1,0.1 --roughness 0.4 "
                                                       "--metallic 1 --emissive 1,0.5,0 --emissive-strength 20 "
                                                       "--alpha-mask 0.5 --double-sided"), 0);
    assert_int_equal(vantage_run(d, out, sizeof out, "add 1 --mesh %d --pos 1,2,3 --rotate 90,0,0 --scale 2 "
                                                       "--material 3", CLS), 0);
    vp_entity g;
    get_one(c, 1, &g);
    assert_int_equal(g.flags, VP_ENT_TRANSFORM);
    assert_int_equal(g.material, 3);
    assert_true(g.pos[0] == 1 && g.pos[1] == 2 && g.pos[2] == 3);
    assert_true(g.scale[0] == 2 && g.scale[1] == 2 && g.scale[2] == 2);
    assert_true(fabsf(g.rot[1] - 0.70710678f) < 1e-6f && fabsf(g.rot[3] - 0.70710678f) < 1e-6f);
    /* pitch alone: about +X */
    assert_int_equal(vantage_run(d, out, sizeof out, "add 2 --mesh %d --rotate 0,90,0", CLS), 0);
    get_one(c, 2, &g);
    assert_true(fabsf(g.rot[0] - 0.70710678f) < 1e-6f && fabsf(g.rot[3] - 0.70710678f) < 1e-6f);
    assert_int_equal(vantage_run(d, out, sizeof out, "add 3 --mesh %d --quat 0,0,2,0", CLS), 0);
    get_one(c, 3, &g);
    assert_true(g.rot[2] == 1 && g.rot[3] == 0);
    /* move: what is not given is kept */
    assert_int_equal(vantage_run(d, out, sizeof out, "move 1 --pos 5,6,7 --scale 1,1,-1"), 0);
    get_one(c, 1, &g);
    assert_true(g.pos[0] == 5 && g.scale[2] == -1 && fabsf(g.rot[1] - 0.70710678f) < 1e-6f);
    assert_int_equal(vantage_run(d, out, sizeof out, "move 1 9,9,9"), 0);
    get_one(c, 1, &g);
    assert_true(g.pos[0] == 9 && g.scale[2] == -1);
    /* the sphere form */
    assert_int_equal(vantage_run(d, out, sizeof out, "add 4 1,2,3 0.5 --material 3"), 0);
    get_one(c, 4, &g);
    assert_true(g.flags == 0 && g.material == 3 && g.sphere[3] == 0.5);
    assert_int_equal(vantage_run(d, out, sizeof out, "move 4 2,2,2"), 0);
    /* refusals: the server's (exit 1, its message), and bad values (exit 2) */
    assert_int_equal(vantage_run(d, out, sizeof out, "material rm 3"), 1);
    assert_non_null(strstr(out, "used by 2 entities"));
    assert_int_equal(vantage_run(d, out, sizeof out, "material put 5 --texture base=9"), 1);
    assert_non_null(strstr(out, "base colour texture 9"));
    assert_int_equal(vantage_run(d, out, sizeof out, "material put 5 --roughness 3"), 1);
    assert_non_null(strstr(out, "roughness"));
    assert_int_equal(vantage_run(d, out, sizeof out, "add 9 --mesh %d --scale 0,1,0", CLS), 1);
    assert_non_null(strstr(out, "2 axes"));
    assert_int_equal(vantage_run(d, out, sizeof out, "add 9 --mesh 300"), 1);
    assert_non_null(strstr(out, "mesh class 300 has no mesh"));
    assert_int_equal(vantage_run(d, out, sizeof out, "add 9 --mesh %d --rotate 1,2", CLS), 2);
    assert_int_equal(vantage_run(d, out, sizeof out, "add 9 --mesh %d --quat 0,0,0,0", CLS), 2);
    assert_int_equal(vantage_run(d, out, sizeof out, "material put 5 --texture roof=1"), 2);
    assert_int_equal(vantage_run(d, out, sizeof out, "move 4 --scale 2"), 2);
    assert_int_equal(vantage_run(d, out, sizeof out, "material --help"), 0);
    assert_non_null(strstr(out, "--alpha-mask"));
    /* get and export write the transform and material; import reads them back */
    assert_int_equal(vantage_run(d, out, sizeof out, "get 1"), 0);
    if (!strstr(out, "\"material\": 3, \"pos\": [9, 9, 9], \"rot\": [0, 0.707106769, 0, 0.707106769], "
                     "\"scale\": [1, 1, -1]"))
        fail_msg("get 1: %s", out);
    char path[] = "/tmp/vantage-trs-XXXXXX";
    int fd = mkstemp(path);
    assert_true(fd >= 0);
    close(fd);
    get_one(c, 1, &g);
    vp_entity before = g;
    assert_int_equal(vantage_run(d, out, sizeof out, "export %s", path), 0);
    assert_int_equal(vantage_run(d, out, sizeof out, "remove 1 2 3 4"), 0);
    assert_int_equal(vantage_run(d, out, sizeof out, "import %s", path), 0);
    unlink(path);
    get_one(c, 1, &g);
    assert_true(g.flags == VP_ENT_TRANSFORM && g.material == 3);
    assert_memory_equal(g.pos, before.pos, sizeof g.pos);
    assert_memory_equal(g.rot, before.rot, sizeof g.rot);
    assert_memory_equal(g.scale, before.scale, sizeof g.scale);
    assert_memory_equal(g.aabb, before.aabb, sizeof g.aabb);
    get_one(c, 4, &g);
    assert_true(g.flags == 0 && g.material == 3 && g.sphere[3] == 0.5);
    /* gone: the material can go */
    assert_int_equal(vantage_run(d, out, sizeof out, "remove 1 4"), 0);
    assert_int_equal(vantage_run(d, out, sizeof out, "material rm 3"), 0);
    vtc_close(c);
}

const struct CMUnitTest transform_tests[] = {
    DAEMON_TEST(test_transform_bounds_match_model),
    DAEMON_TEST(test_transform_set_visible_next_query),
    DAEMON_TEST(test_transform_batches_all_or_nothing),
    TEST_ROWS(test_transform_bad_input, bad_rows),
    DAEMON_TEST(test_transform_mesh_rederives),
    DAEMON_TEST(test_attached_occluder_follows),
    DAEMON_TEST(test_destruction_follows),
    DAEMON_TEST(test_cli_transforms_and_materials),
};
const size_t transform_tests_count = sizeof transform_tests / sizeof transform_tests[0];
