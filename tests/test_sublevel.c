/*
 * test_sublevel.c — level import and sub-level loads.
 *
 * Import: the glTF and OBJ levels of tests/data (authored by
 * make_levels.py, where the expected numbers come from) give the expected
 * entities, classes, bounds, occluders and lights; bad files fail naming
 * the node. Loads, end to end against the real daemon: a query running
 * all through a load and an unload sees all of the sub-level or none of it
 * (and which, by the epoch it reports); a load whose connection dies is
 * never seen and is freed; the rules (one load per connection, no writes
 * into someone else's load, unload of what is loaded) hold; queries can
 * name their sub-levels; the CLI loads, lists and unloads a glTF level.
 */
#include "test_util.h"

#include "import.h"
#include "test_daemon.h"
#include "vantage.h"

#include <assimp/version.h>

#include <fcntl.h>
#include <sys/stat.h>
#include <pthread.h>
#include <sys/wait.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

static const char *data_file(const char *name)
{
    static char path[512];
    const char *d = getenv("VANTAGE_DATA_DIR");
    snprintf(path, sizeof path, "%s/%s", d ? d : "tests/data", name);
    return path;
}

static const lvl_entity *entity_named(const imp_level *lv, const char *name)
{
    for (uint32_t i = 0; i < lv->nent; i++)
        if (!strcmp(lv->ent[i].name, name)) return &lv->ent[i];
    fail_msg("no entity %s", name);
    return NULL;
}

static void assert_box(const lvl_entity *e, double x0, double y0, double z0, double x1, double y1, double z1)
{
    const double want[6] = {x0, y0, z0, x1, y1, z1}, got[6] = {e->lo[0], e->lo[1], e->lo[2], e->hi[0], e->hi[1], e->hi[2]};
    for (int a = 0; a < 6; a++)
        if (!(fabs(got[a] - want[a]) <= 1e-5 * (1 + fabs(want[a]))))
            fail_msg("%s: bound %d is %.9g, want %.9g", e->name, a, got[a], want[a]);
}

/* An entity's transform against the file's (q and -q are one rotation). */
static void assert_trs(const lvl_entity *e, const double pos[3], const double rot[4], const double scale[3])
{
    double dot = 0;
    for (int a = 0; a < 4; a++) dot += rot[a] * e->rot[a];
    for (int a = 0; a < 3; a++)
        if (!(fabs(e->pos[a] - pos[a]) <= 1e-6 * (1 + fabs(pos[a])) && fabs(e->scale[a] - scale[a]) <= 1e-6))
            fail_msg("%s: position or scale axis %d is %.9g / %.9g, want %.9g / %.9g", e->name, a, e->pos[a],
                     (double)e->scale[a], pos[a], scale[a]);
    if (!(fabs(fabs(dot) - 1) <= 1e-6))
        fail_msg("%s: rotation (%g %g %g %g), want (%g %g %g %g)", e->name, (double)e->rot[0], (double)e->rot[1],
                 (double)e->rot[2], (double)e->rot[3], rot[0], rot[1], rot[2], rot[3]);
}

/* Imports tests/data/name into lv; fails the test with the importer's message. */
static void import_ok(const char *name, imp_level *lv)
{
    char err[512];
    if (imp_level_import(data_file(name), lv, err, sizeof err)) fail_msg("%s: %s", name, err);
}

static void test_import_gltf(void **state)
{
    (void)state;
    imp_level lv;
    import_ok("level_small.gltf", &lv);
    /* crate_a..d, cart, tower, wall, lamp_post; OCC_* are not entities */
    assert_int_equal(lv.nent, 8);
    /* the scene model: one class per mesh the file has, however placed:
       the box (crates, cart, tower, lamp post) and the wall */
    assert_int_equal(lv.nmesh, 2);
    assert_int_equal(entity_named(&lv, "crate_a")->cls, entity_named(&lv, "crate_b")->cls);
    assert_int_equal(entity_named(&lv, "crate_a")->cls, entity_named(&lv, "crate_c")->cls);
    assert_int_equal(entity_named(&lv, "crate_a")->cls, entity_named(&lv, "lamp_post")->cls);
    assert_int_not_equal(entity_named(&lv, "crate_a")->cls, entity_named(&lv, "wall")->cls);
    /* transforms as the file gives them (make_levels.py), the lamp post's
       composed with its group's (a quarter turn about y, moved to 20,0,20) */
    const double s45 = sin(M_PI / 8), c45 = cos(M_PI / 8), s90 = sin(M_PI / 4);
    assert_trs(entity_named(&lv, "crate_c"), (double[3]){0, 1, 10}, (double[4]){0, s45, 0, c45},
               (double[3]){2, 1, 1});
    assert_trs(entity_named(&lv, "crate_a"), (double[3]){0, 1, 0}, (double[4]){0, 0, 0, 1}, (double[3]){1, 1, 1});
    assert_trs(entity_named(&lv, "lamp_post"), (double[3]){20, 2, 20}, (double[4]){0, s90, 0, s90},
               (double[3]){0.2, 2, 0.2});
    /* the box class in its own space, -1..1 */
    const lvl_mesh *bm = &lv.mesh[entity_named(&lv, "crate_a")->cls];
    for (uint32_t v = 0; v < 3 * bm->nv; v++) assert_true(fabsf(fabsf(bm->pos[v]) - 1) < 1e-6f);
    assert_box(entity_named(&lv, "crate_a"), -1, 0, -1, 1, 2, 1);
    assert_box(entity_named(&lv, "crate_b"), 9, 0, -1, 11, 2, 1);
    double r = 3 / sqrt(2.0); /* half extents (2, 1) turned 45 degrees */
    assert_box(entity_named(&lv, "crate_c"), -r, 0, 10 - r, r, 2, 10 + r);
    assert_box(entity_named(&lv, "cart"), -11, 0, -2, -9, 1, 2);
    /* a child of a group turned 90 degrees: transforms compose */
    assert_box(entity_named(&lv, "lamp_post"), 19.8, 0, 19.8, 20.2, 4, 20.2);
    assert_true(entity_named(&lv, "cart")->dynamic);
    assert_false(entity_named(&lv, "crate_a")->dynamic);
    /* occluders: the tower's own, OCC_wall on the wall, OCC_hill on nothing */
    assert_int_equal(lv.nocc, 3);
    const lvl_entity *tower = entity_named(&lv, "tower"), *wall = entity_named(&lv, "wall");
    assert_true(tower->occluder >= 0 && wall->occluder >= 0);
    assert_int_equal(lv.occ[tower->occluder].ntri, 12);
    assert_int_equal(lv.occ[wall->occluder].ntri, 2);
    assert_string_equal(lv.occ[wall->occluder].name, "OCC_wall");
    uint32_t free_occ = 0;
    for (uint32_t i = 0; i < lv.nocc; i++) free_occ += lv.occ[i].entity < 0;
    assert_int_equal(free_occ, 1);
    /* the wall occluder in world space: x within +-9.5, at z = 20 */
    const lvl_occluder *wo = &lv.occ[wall->occluder];
    for (uint32_t v = 0; v < 3 * wo->ntri; v++) {
        double x = wo->tri[3 * v] + wo->origin[0], z = wo->tri[3 * v + 2] + wo->origin[2];
        assert_true(fabs(fabs(x) - 9.5) < 1e-5);
        assert_true(fabs(z - 20) < 1e-5);
    }
    /* lights: bulb (point, range 25) and spot (down); the sun (3 lux, a
       node turned 30 degrees about y: it shines along (-1/2, 0, -sqrt 3/2),
       so the sun is towards (1/2, 0, sqrt 3/2)) */
    assert_int_equal(lv.nlight, 2);
    assert_int_equal(lv.skipped_lights, 0);
    assert_true(lv.has_sun);
    assert_true(fabs(lv.sun_lux - 3) < 1e-6);
    assert_true(fabs(lv.sun_dir[0] - 0.5) < 1e-6 && fabs(lv.sun_dir[1]) < 1e-6 &&
                fabs(lv.sun_dir[2] - sqrt(3) / 2) < 1e-6);
    for (uint32_t i = 0; i < lv.nlight; i++) {
        const vp_light *l = &lv.light[i];
        if (l->kind == VP_LIGHT_POINT) {
            assert_true(fabs(l->pos[0] - 5) < 1e-6 && fabs(l->pos[1] - 4) < 1e-6 && fabs(l->pos[2] - 5) < 1e-6);
            assert_true(fabs(l->range - 25) < 1e-4);
            assert_true(fabs(l->intensity - 200) < 1e-3);
            assert_true(fabs(l->color[1] - 0.8f) < 1e-5);
        } else {
            assert_int_equal(l->kind, VP_LIGHT_SPOT);
            assert_true(fabs(l->pos[1] - 12) < 1e-6);
            assert_true(fabs(l->dir[1] + 1) < 1e-6);
            assert_true(fabs(l->outer_cos - cos(0.6)) < 1e-6 && fabs(l->inner_cos - cos(0.3)) < 1e-6);
            assert_true(fabs(l->range - 40) < 1e-4);
        }
    }
    /* every class mesh: indices in range, unit normals */
    for (uint32_t m = 0; m < lv.nmesh; m++) {
        const lvl_mesh *me = &lv.mesh[m];
        assert_true(me->ni > 0 && me->ni % 3 == 0);
        for (uint32_t i = 0; i < me->ni; i++) assert_true(me->idx[i] < me->nv);
        for (uint32_t v = 0; v < me->nv; v++) {
            const float *n = me->nrm + 3 * v;
            assert_true(fabs(n[0] * n[0] + n[1] * n[1] + n[2] * n[2] - 1) < 1e-4);
        }
    }
    imp_level_free(&lv);
}

static void test_import_obj(void **state)
{
    (void)state;
    imp_level lv;
    import_ok("level_small.obj", &lv);
    assert_int_equal(lv.nent, 2);
    assert_int_equal(lv.nocc, 1);
    assert_int_equal(lv.occ[0].entity >= 0, 1);
    assert_string_equal(lv.ent[lv.occ[0].entity].name, "shed");
    assert_box(entity_named(&lv, "shed"), -1, 0, -1, 1, 2, 1);
    imp_level_free(&lv);
    /* names are matched whole, however long: the occluder goes to the one
       entity whose name is its name after OCC_ (not to the near namesake) */
    import_ok("level_names.gltf", &lv);
    assert_int_equal(lv.nent, 2);
    assert_int_equal(lv.nocc, 1);
    assert_true(lv.occ[0].entity >= 0);
    assert_true(lv.ent[lv.occ[0].entity].lo[0] < 0); /* the first, at x = 0, not the one at x = 20 */
    imp_level_free(&lv);
}

/* A bad level file: an error that names the node (or the file's
 * trouble), and nothing half-read handed back. */
typedef struct bad_level {
    const char *name; /* the file in tests/data */
    const char *says;
} bad_level;

static const bad_level bad_levels[] = {
    {"bad_huge.gltf", "node 'vast': bounds beyond"},
    {"bad_zero.gltf", "node 'flat': its transform has zero scale"},
    {"bad_points.gltf", "node 'dots': its meshes have no triangles"},
    {"bad_nan.obj", "node 'broken': mesh 'broken' has a non-finite vertex"},
    {"bad_occ_far.gltf", "bounds beyond +-1e12 m"},
    {"make_levels.py", "unsupported format"},
    {"missing.glb", "No such file or directory"},
};

static void test_import_bad_file(void **state)
{
    const bad_level *t = *state;
    imp_level lv;
    char err[512] = "";
    assert_int_equal(imp_level_import(data_file(t->name), &lv, err, sizeof err), -1);
    if (!strstr(err, t->says)) fail_msg("%s: \"%s\" does not say \"%s\"", t->name, err, t->says);
    assert_int_equal(lv.nent, 0); /* nothing half-read is handed back */
}

/* A corrupt glTF: valid JSON cut short. */
static void test_import_cut_gltf(void **state)
{
    (void)state;
    imp_level lv;
    char err[512];
    tdir td;
    tdir_make(&td, "vantage_import");
    const char *cut = tdir_file(&td, "cut.gltf");
    FILE *in = fopen(data_file("level_small.gltf"), "rb"), *out = fopen(cut, "wb");
    char buf[2000];
    size_t n = fread(buf, 1, sizeof buf, in);
    fwrite(buf, 1, n, out);
    fclose(in);
    fclose(out);
    assert_int_equal(imp_level_import(cut, &lv, err, sizeof err), -1);
    assert_non_null(strstr(err, "cannot import"));
    tdir_remove(&td);
}

/* imp_level_import runs assimp in a child and takes the level back over a
 * pipe: the level is the one the same bytes give in this process, record
 * for record; files that crash Debian 12's assimp 5.2 (tests/fuzz/known)
 * are errors naming the file, and this process goes on. */
static void test_import_isolated(void **state)
{
    (void)state;
    const char *path = data_file("level_small.gltf");
    FILE *f = fopen(path, "rb");
    assert_non_null(f);
    static char bytes[1 << 20];
    size_t n = fread(bytes, 1, sizeof bytes, f);
    fclose(f);
    assert_true(n > 0 && n < sizeof bytes);
    imp_level a, b;
    char err[512];
    if (imp_level_import(path, &a, err, sizeof err)) fail_msg("%s", err);
    if (imp_level_import_mem(bytes, n, "gltf", &b, err, sizeof err)) fail_msg("%s", err);
    test_level_equal(&a, &b);
    imp_level_free(&a);
    imp_level_free(&b);

    static const char *const known[] = {"tests/fuzz/known/gltf/segv-sparse-no-values.gltf",
                                        "tests/fuzz/known/gltf/segv-line-loop-bad-index.glb",
                                        "tests/fuzz/known/gltf/overread-opengex-fallback.gltf"};
    /* what these do to assimp depends on memory they read past their end:
       under ASan the OpenGEX over-read was seen to spin in the child for
       the whole default timeout (300 s). A bound of 10 s per file makes
       that an error like the others, whatever the memory held (each takes
       well under a second when it crashes) */
    setenv("VANTAGE_IMPORT_TIMEOUT", "10", 1);
    for (size_t i = 0; i < sizeof known / sizeof known[0]; i++) {
        err[0] = 0;
        /* the child's last words (a sanitizer's report under ASan) to /dev/null */
        fflush(stderr);
        int saved = dup(2), null = open("/dev/null", O_WRONLY);
        assert_true(saved >= 0 && null >= 0);
        dup2(null, 2);
        int rc = imp_level_import(known[i], &a, err, sizeof err);
        dup2(saved, 2);
        close(saved);
        close(null);
        assert_int_equal(rc, -1);
        if (strncmp(err, known[i], strlen(known[i]))) fail_msg("\"%s\" does not name the file", err);
        if (i < 2 && aiGetVersionMajor() == 5 && aiGetVersionMinor() == 2 && !strstr(err, "assimp crashed"))
            fail_msg("%s: \"%s\"", known[i], err);
        assert_int_equal(a.nent, 0);
    }
    /* the bound itself: a file assimp never finishes reading (a FIFO no
       one writes) is stopped after it, with an error naming the file */
    tdir td;
    tdir_make(&td, "vantage_import_timeout");
    char fifo[400];
    snprintf(fifo, sizeof fifo, "%s", tdir_file(&td, "never.gltf"));
    assert_int_equal(mkfifo(fifo, 0600), 0);
    setenv("VANTAGE_IMPORT_TIMEOUT", "0.5", 1);
    assert_int_equal(imp_level_import(fifo, &a, err, sizeof err), -1);
    if (!strstr(err, fifo) || !strstr(err, "did not finish reading the file in 0.5 s")) fail_msg("%s", err);
    tdir_remove(&td);
    unsetenv("VANTAGE_IMPORT_TIMEOUT");
    /* and the next import is whole */
    if (imp_level_import(path, &a, err, sizeof err)) fail_msg("%s", err);
    assert_int_equal(a.nent, 8);
    imp_level_free(&a);
}

/* ---- loads, end to end ----------------------------------------------------------------- */

static vp_view everything(void)
{
    vp_view v;
    double eye[3] = {0, 1e5, 0}, at[3] = {0, 0, 0}, up[3] = {0, 0, 1};
    assert_true(vtc_view_ortho(&v, eye, at, up, 1e6, 1e6, 256, 256, 1, 1e6));
    return v;
}

static void add_boxes(vtc_client *c, uint64_t first, uint32_t n, uint16_t sub, uint32_t batch)
{
    vp_entity *e = calloc(batch, sizeof *e);
    assert_non_null(e);
    for (uint32_t i = 0; i < n; i += batch) {
        uint32_t k = n - i < batch ? n - i : batch;
        for (uint32_t j = 0; j < k; j++) {
            uint64_t id = first + i + j;
            e[j] = (vp_entity){.id = id, .sublevel = sub};
            double x = (double)(id % 1000) * 3, z = (double)((id / 1000) % 1000) * 3;
            double b[6] = {x, 0, z, x + 1, 1, z + 1};
            memcpy(e[j].aabb, b, sizeof b);
        }
        int rc = vtc_add(c, e, k, NULL, NULL);
        if (rc) fail_msg("add: %d %s", rc, vtc_last_error(c)->msg);
    }
    free(e);
}

typedef struct watcher {
    const daemon_proc *d;
    volatile int stop;
    uint32_t base, full;      /* the two counts a query may see */
    volatile uint64_t flip;   /* epoch from which `full` is right (0 = unknown yet) */
    volatile uint64_t back;   /* epoch from which `base` is right again */
    uint32_t queries, bad, saw_full, saw_base;
    char why[200];
} watcher;

static void *watch(void *p)
{
    watcher *w = p;
    vtc_client *c = connect_role(w->d, VP_ROLE_VIEWER, true);
    vp_view v = everything();
    while (!w->stop) {
        vp_vis_result r;
        int rc = vtc_query(c, &v, 1, VP_Q_NO_OCCLUSION | VP_Q_COUNT_ONLY, 0, &r);
        if (rc) {
            snprintf(w->why, sizeof w->why, "query failed: %d", rc);
            w->bad++;
            break;
        }
        w->queries++;
        uint64_t flip = w->flip, back = w->back;
        bool ok = r.visible == w->base || r.visible == w->full;
        /* which one, by the epoch the reply reflects */
        if (ok && flip && r.epoch >= flip && (!back || r.epoch < back)) ok = r.visible == w->full;
        if (ok && back && r.epoch >= back) ok = r.visible == w->base;
        if (!ok && !w->bad)
            snprintf(w->why, sizeof w->why, "%u visible at epoch %llu (base %u, full %u, flip %llu, back %llu)",
                     r.visible, (unsigned long long)r.epoch, w->base, w->full, (unsigned long long)flip,
                     (unsigned long long)back);
        w->bad += !ok;
        w->saw_full += r.visible == w->full;
        w->saw_base += r.visible == w->base;
    }
    vtc_close(c);
    return NULL;
}

static void test_sublevel_load_is_atomic(void **state)
{
    daemon_proc *d = *state;
    vtc_client *ed = connect_role(d, VP_ROLE_EDITOR, false);
    const uint32_t base = 3000, k = (uint32_t)(30000 * test_scale());
    add_boxes(ed, 1, base, 0, 1000);
    watcher w = {.d = d, .base = base, .full = base + k};
    pthread_t th;
    assert_int_equal(pthread_create(&th, NULL, watch, &w), 0);
    usleep(20000);
    vtc_client *ld = connect_role(d, VP_ROLE_EDITOR, false);
    vp_sublevel_begun b;
    assert_int_equal(vtc_sublevel_begin(ld, "alpha", 1, &b), VP_OK);
    assert_true(b.id > 0);
    static const float tri[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    static const uint32_t idx[3] = {0, 1, 2};
    static const float nrm[9] = {0, 0, 1, 0, 0, 1, 0, 0, 1};
    assert_int_equal(vtc_put_mesh(ld, b.class_base, tri, nrm, 3, idx, 3), VP_OK);
    uint32_t q0 = w.queries;
    add_boxes(ld, 1000000, k, 0, 1000); /* sub-level 0 from a loading connection: the load's */
    vp_light l = {.id = 5, .kind = VP_LIGHT_POINT, .pos = {1, 2, 3}, .color = {1, 1, 1}, .intensity = 10, .range = 5};
    assert_int_equal(vtc_put_lights(ld, &l, 1), VP_OK);
    double origin[3] = {0, 0, 0};
    assert_int_equal(vtc_put_occluder(ld, 1000000, origin, tri, 1), VP_OK);
    uint32_t during = w.queries - q0;
    vp_ack a;
    assert_int_equal(vtc_sublevel_commit(ld, &a), VP_OK);
    assert_int_equal(a.count, k);
    w.flip = a.epoch;
    usleep(50000);
    /* listed, with what it holds */
    vp_sublevel_infos in;
    assert_int_equal(vtc_sublevel_info(ed, &in), VP_OK);
    size_t pos = 0;
    vp_sublevel_info si;
    assert_true(vp_sublevel_info_next(&in, &pos, &si));
    assert_int_equal(si.id, b.id);
    assert_int_equal(si.state, VP_SL_LOADED);
    assert_int_equal(si.entities, k);
    assert_int_equal(si.occluders, 1);
    assert_int_equal(si.lights, 1);
    assert_int_equal(si.classes, 1);
    /* unload: gone at one epoch, freed in slices behind it */
    assert_int_equal(vtc_sublevel_unload(ed, "alpha", &a), VP_OK);
    assert_int_equal(a.count, k);
    w.back = a.epoch;
    usleep(50000);
    w.stop = 1;
    pthread_join(th, NULL);
    fprintf(stderr, "load of %u entities: %u queries in all, %u during the load; %u saw it all, %u saw none\n", k,
            w.queries, during, w.saw_full, w.saw_base);
    if (w.bad) fail_msg("%u bad queries: %s", w.bad, w.why);
    assert_true(during > 0 && w.saw_full > 0);
    for (int i = 0; i < 200; i++) {
        assert_int_equal(vtc_sublevel_info(ed, &in), VP_OK);
        pos = 0;
        assert_true(vp_sublevel_info_next(&in, &pos, &si));
        if (si.state == VP_SL_EMPTY) break;
        usleep(10000);
    }
    assert_int_equal(si.state, VP_SL_EMPTY);
    assert_int_equal(si.entities, 0);
    vp_stats_reply st;
    assert_int_equal(vtc_stats(ed, &st), VP_OK);
    assert_int_equal(st.entities, base);
    assert_int_equal(st.occluders, 0);
    assert_int_equal(st.lights, 0);
    assert_int_equal(st.meshes, 0);
    vtc_close(ld);
    vtc_close(ed);
}

static void test_sublevel_rules(void **state)
{
    daemon_proc *d = *state;
    vtc_client *a = connect_role(d, VP_ROLE_EDITOR, false), *b = connect_role(d, VP_ROLE_EDITOR, true);
    vtc_client *viewer = connect_role(d, VP_ROLE_VIEWER, false);
    vtc_client *events = connect_role(d, VP_ROLE_VIEWER, false);
    assert_int_equal(vtc_subscribe(events, VP_EVENT_SCENE), VP_OK);
    vp_entity visible = {.id = 50, .aabb = {20, 0, 0, 21, 1, 1}};
    assert_int_equal(vtc_add(b, &visible, 1, NULL, NULL), VP_OK);
    vp_sublevel_begun ba, bb;
    vp_ack ack;
    /* viewers do not load; commit with nothing open */
    assert_int_equal(vtc_sublevel_begin(viewer, "x", 0, &ba), VP_ERR_AUTH);
    assert_int_equal(vtc_sublevel_commit(a, &ack), VP_ERR_STATE);
    assert_int_equal(vtc_sublevel_begin(a, "north", 2, &ba), VP_OK);
    /* one load a connection; another connection cannot take the same one */
    assert_int_equal(vtc_sublevel_begin(a, "south", 0, &bb), VP_ERR_STATE);
    assert_int_equal(vtc_sublevel_begin(b, "north", 0, &bb), VP_ERR_STATE);
    /* nobody writes into a load but its connection */
    vp_entity e = {.id = 1, .sublevel = ba.id, .aabb = {0, 0, 0, 1, 1, 1}};
    assert_int_equal(vtc_add(b, &e, 1, NULL, NULL), VP_ERR_STATE);
    static const float tri[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0}, nrm[9] = {0, 0, 1, 0, 0, 1, 0, 0, 1};
    static const uint32_t idx[3] = {0, 1, 2};
    assert_int_equal(vtc_put_mesh(b, ba.class_base + 1, tri, nrm, 3, idx, 3), VP_ERR_STATE);
    /* and the loading connection writes only into its load */
    e.sublevel = ba.id + 7;
    assert_int_equal(vtc_add(a, &e, 1, NULL, NULL), VP_ERR_INVALID);
    e.sublevel = ba.id;
    uint64_t ep0, ep1;
    vp_stats_reply st;
    assert_int_equal(vtc_stats(a, &st), VP_OK);
    ep0 = st.epoch;
    assert_int_equal(vtc_add(a, &e, 1, NULL, &ep1), VP_OK);
    assert_int_equal(ep1, ep0); /* nothing anyone sees changed */
    /* nobody moves an entity out of the load, or removes it, but its connection */
    e.sublevel = 0;
    assert_int_equal(vtc_update(b, &e, 1, NULL), VP_ERR_STATE);
    assert_int_equal(vtc_remove(b, &e.id, 1, NULL), VP_ERR_STATE);
    /* nor does the load pull a visible entity in, or push one of its own out */
    visible.sublevel = ba.id;
    assert_int_equal(vtc_update(a, &visible, 1, NULL), VP_ERR_STATE);
    assert_int_equal(vtc_update(a, &e, 1, NULL), VP_ERR_STATE);
    e.sublevel = ba.id;
    /* an empty or repeating light batch is refused */
    vp_light two[2] = {{.id = 3, .kind = VP_LIGHT_POINT, .color = {1, 1, 1}, .intensity = 1, .range = 2},
                       {.id = 3, .kind = VP_LIGHT_POINT, .color = {1, 1, 1}, .intensity = 1, .range = 2}};
    assert_int_equal(vtc_put_lights(b, two, 0), VP_ERR_COUNT);
    assert_int_equal(vtc_put_lights(b, two, 2), VP_ERR_DUPLICATE);
    assert_int_equal(vtc_stats(a, &st), VP_OK);
    assert_int_equal(st.epoch, ep0);
    assert_int_equal(st.lights, 0);
    /* unloading what is being loaded, or what does not exist */
    assert_int_equal(vtc_sublevel_unload(b, "north", &ack), VP_ERR_STATE);
    assert_int_equal(vtc_sublevel_unload(b, "nowhere", &ack), VP_ERR_NOT_FOUND);
    /* an id taken in the load is taken for everyone */
    e.sublevel = 0;
    assert_int_equal(vtc_add(b, &e, 1, NULL, NULL), VP_ERR_DUPLICATE);
    vp_view v = everything();
    vp_vis_result r;
    assert_int_equal(vtc_query(viewer, &v, 1, VP_Q_NO_OCCLUSION, 0, &r), VP_OK);
    assert_int_equal(r.visible, 1); /* entity 50 only */
    assert_int_equal(vtc_sublevel_commit(a, &ack), VP_OK);
    assert_int_equal(ack.count, 1);
    /* the subscriber heard of entity 50 and of the load's one entity, once each */
    uint32_t added = 0;
    for (;;) {
        vp_event ev;
        int erc = vtc_wait_event(events, &ev, 300);
        if (erc) break;
        added += ev.added;
        if (ev.epoch >= ack.epoch) break;
    }
    assert_int_equal(added, 2);
    uint64_t fifty = 50;
    assert_int_equal(vtc_remove(b, &fifty, 1, NULL), VP_OK);
    /* loading a loaded sub-level again: unload first */
    assert_int_equal(vtc_sublevel_begin(b, "north", 0, &bb), VP_ERR_DUPLICATE);
    /* queries may name their sub-levels */
    e = (vp_entity){.id = 2, .aabb = {5, 0, 0, 6, 1, 1}};
    assert_int_equal(vtc_add(b, &e, 1, NULL, NULL), VP_OK);
    uint16_t only = ba.id, none = 999, dflt = 0;
    assert_int_equal(vtc_query_sub(viewer, &v, 1, VP_Q_NO_OCCLUSION, 0, &only, 1, &r), VP_OK);
    assert_int_equal(r.visible, 1);
    vp_vis_rec rec;
    vp_vis_rec_get(&r, 0, &rec);
    assert_int_equal(rec.id, 1);
    assert_int_equal(rec.sublevel, ba.id);
    assert_int_equal(vtc_query_sub(viewer, &v, 1, VP_Q_NO_OCCLUSION, 0, &dflt, 1, &r), VP_OK);
    assert_int_equal(r.visible, 1);
    vp_vis_rec_get(&r, 0, &rec);
    assert_int_equal(rec.id, 2);
    assert_int_equal(vtc_query_sub(viewer, &v, 1, VP_Q_NO_OCCLUSION, 0, &none, 1, &r), VP_OK);
    assert_int_equal(r.visible, 0);
    assert_int_equal(vtc_query(viewer, &v, 1, VP_Q_NO_OCCLUSION, 0, &r), VP_OK);
    assert_int_equal(r.visible, 2);
    /* a load whose connection dies is never seen, and is freed */
    assert_int_equal(vtc_sublevel_begin(b, "east", 0, &bb), VP_OK);
    add_boxes(b, 5000, 2000, 0, 500);
    vtc_close(b);
    b = connect_role(d, VP_ROLE_EDITOR, true);
    vp_sublevel_infos in;
    vp_sublevel_info si = {0};
    for (int i = 0; i < 200; i++) {
        assert_int_equal(vtc_query(viewer, &v, 1, VP_Q_NO_OCCLUSION | VP_Q_COUNT_ONLY, 0, &r), VP_OK);
        assert_int_equal(r.visible, 2);
        assert_int_equal(vtc_sublevel_info(b, &in), VP_OK);
        size_t pos = 0;
        while (vp_sublevel_info_next(&in, &pos, &si) && si.id != bb.id) {}
        if (si.id == bb.id && si.state == VP_SL_EMPTY) break;
        usleep(10000);
    }
    assert_int_equal(si.id, bb.id);
    assert_int_equal(si.state, VP_SL_EMPTY);
    /* and its name can be loaded again */
    assert_int_equal(vtc_sublevel_begin(b, "east", 0, &bb), VP_OK);
    assert_int_equal(vtc_sublevel_abort(b, &ack), VP_OK);
    vtc_close(a);
    vtc_close(b);
    vtc_close(viewer);
    vtc_close(events);
}

static void test_sublevel_cli(void **state)
{
    daemon_proc *d = *state;
    char out[8192];
    assert_int_equal(vantage_run(d, out, sizeof out, "sublevel load town %s --json", data_file("level_small.gltf")), 0);
    assert_non_null(strstr(out, "\"sublevel\": \"town\""));
    assert_non_null(strstr(out, "\"entities\": 8"));
    assert_int_equal(vantage_run(d, out, sizeof out, "sublevel list --json"), 0);
    assert_non_null(strstr(out, "\"name\": \"town\", \"state\": \"loaded\", \"entities\": 8, \"occluders\": 3, "
                                "\"lights\": 2, \"classes\": 2"));
    /* a bad file: an error naming the node, and the scene as it was */
    assert_int_equal(vantage_run(d, out, sizeof out, "sublevel load dunes %s", data_file("bad_zero.gltf")), 1);
    assert_non_null(strstr(out, "node 'flat'"));
    assert_int_equal(vantage_run(d, out, sizeof out, "sublevel load town %s", data_file("level_small.obj")), 1);
    assert_non_null(strstr(out, "unload it first"));
    assert_int_equal(vantage_run(d, out, sizeof out, "stats --json"), 0);
    assert_non_null(strstr(out, "\"entities\": 8"));
    assert_int_equal(vantage_run(d, out, sizeof out, "sublevel unload town"), 0);
    assert_non_null(strstr(out, "sub-level town unloaded"));
    assert_int_equal(vantage_run(d, out, sizeof out, "sublevel load shed %s", data_file("level_small.obj")), 0);
    assert_int_equal(vantage_run(d, out, sizeof out, "sublevel list"), 0);
    assert_non_null(strstr(out, "shed"));
    assert_non_null(strstr(out, "loaded"));
}

const struct CMUnitTest sublevel_tests[] = {
    cmocka_unit_test(test_import_gltf),
    cmocka_unit_test(test_import_obj),
    TEST_ROWS(test_import_bad_file, bad_levels),
    cmocka_unit_test(test_import_cut_gltf),
    cmocka_unit_test(test_import_isolated),
    DAEMON_TEST(test_sublevel_load_is_atomic),
    DAEMON_TEST(test_sublevel_rules),
    DAEMON_TEST(test_sublevel_cli),
};
const size_t sublevel_tests_count = sizeof sublevel_tests / sizeof sublevel_tests[0];
