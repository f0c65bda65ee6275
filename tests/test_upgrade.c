/*
 * test_upgrade.c — a data directory written by protocol version 1's
 * vantaged (tests/data/upgrade_v1: a format 2 snapshot and a format 1
 * journal of version 1's records, made by make_fixture.sh from main at
 * ad84e3d) opened by today's code:
 *   - in process (journal_open on a copy): every entity, mesh, occluder,
 *     light, sub-level and the destruction is what make_fixture.c put in,
 *     checked field by field against this file's own list of it (written
 *     here from the edits, not read back through the code under test);
 *     the directory is upgraded (a format 3 snapshot, a format 2 journal,
 *     the old files gone), and a second open restores the same scene and
 *     upgrades nothing;
 *   - end to end (vantaged --data-dir on a copy): clients see the same
 *     entities and sub-levels, the wall's hole still lets a query see
 *     through it, an edit made after the upgrade survives a restart, and
 *     the restart does not upgrade again.
 */
#include "test_daemon.h"
#include "test_util.h"

#include "edit.h"
#include "journal.h"
#include "log.h"
#include "snapshot.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

static const scene_limits LIMITS = {.max_entities = 1u << 20, .max_lights = 65536, .max_occluders = 1u << 20,
                                    .max_occluder_tris = 1u << 20, .max_mesh_verts = 1u << 20,
                                    .max_materials = 1u << 16, .max_texture_size = 4096,
                                    .max_texture_mem = 1ull << 28};

/* ---- what make_fixture.c put in (after both parts) ------------------------------------------ */

enum { SUB_DEFAULT, SUB_HARBOUR, SUB_PARK, SUB_DOCKS }; /* ids in the order the names were defined */
static const char *const SUB_NAME[4] = {NULL, "harbour", "park", "docks"};
static const uint16_t SUB_CLASSES[4] = {0, 2, 0, 1};
#define IN_SUB 0x8000u /* class: the sub-level's first reserved class + the low bits */

typedef struct want_entity {
    uint64_t id;
    uint16_t cls; /* or IN_SUB | k */
    uint16_t sub;
    uint32_t flags;
    double sphere[4], aabb[6];
} want_entity;

/* sphere and AABB as the daemon keeps them: the one not sent derived
 * (AABB = centre +- r; sphere = the box's centre and half diagonal) */
static const want_entity WANT_ENTITIES[] = {
    {1, 1, SUB_DEFAULT, 0, {0, 1, 0, 1}, {-1, 0, -1, 1, 2, 1}},
    {2, 1, SUB_DEFAULT, VP_ENT_DYNAMIC, {12, 1, 3, 1.5}, {10.5, -0.5, 1.5, 13.5, 2.5, 4.5}}, /* updated */
    {3, 2, SUB_DEFAULT, 0, {0, 2, 21, 3}, {-2, 0, 20, 2, 4, 22}},
    {4, 0, SUB_PARK, 0, {5, 2, -5, 0.5}, {4.5, 1.5, -5.5, 5.5, 2.5, -4.5}},
    {5, 0, SUB_DEFAULT, 0, {0, 2, 30.5, 4.5}, {-4, 0, 30, 4, 4, 31}},
    {7, 1, SUB_DEFAULT, 0, {-10, 1, 5, 2}, {-12, -1, 3, -8, 3, 7}},
    {8, 2, SUB_DEFAULT, 0, {3, 3, 3, 4}, {0, 0, 0, 6, 6, 6}},
    {20, IN_SUB, SUB_HARBOUR, 0, {40, 1, 40, 2}, {38, -1, 38, 42, 3, 42}},
    {21, IN_SUB, SUB_HARBOUR, 0, {44, 1, 40, 2}, {42, -1, 38, 46, 3, 42}},
    {30, IN_SUB, SUB_DOCKS, 0, {-40, 1, -40, 3}, {-43, -2, -43, -37, 4, -37}},
};
#define N_ENTITIES (sizeof WANT_ENTITIES / sizeof WANT_ENTITIES[0])

/* meshes: a tetrahedron of size k with normals, or (k = 0) the triangle
 * of class 2 without normals */
typedef struct want_mesh {
    uint16_t cls; /* or IN_SUB with sub */
    uint16_t sub;
    float k;
} want_mesh;
static const want_mesh WANT_MESHES[] = {
    {1, 0, 1.0f}, {2, 0, 0}, {IN_SUB, SUB_HARBOUR, 2.0f}, {9, 0, 0.5f}, {IN_SUB, SUB_DOCKS, 3.0f},
};
#define N_MESHES (sizeof WANT_MESHES / sizeof WANT_MESHES[0])

/* occluders: a w x h quad in the plane z = 0 from origin */
typedef struct want_occluder {
    uint64_t id;
    double origin[3];
    float w, h;
    uint16_t sub;
} want_occluder;
static const want_occluder WANT_OCCLUDERS[] = {
    {5, {-4, 0, 30.5}, 8, 4, SUB_DEFAULT},  {100, {20, 0, 1}, 5, 2, SUB_DEFAULT}, /* replaced */
    {101, {-20, 0, 0}, 4, 4, SUB_DEFAULT},  {200, {38, 0, 45}, 10, 5, SUB_HARBOUR},
    {300, {-45, 0, -35}, 10, 6, SUB_DOCKS},
};
#define N_OCCLUDERS (sizeof WANT_OCCLUDERS / sizeof WANT_OCCLUDERS[0])

typedef struct want_light {
    uint64_t id;
    uint8_t kind;
    double pos[3];
    float intensity, range;
    uint16_t sub;
} want_light;
static const want_light WANT_LIGHTS[] = { /* 11 was removed */
    {10, VP_LIGHT_POINT, {0, 3, 0}, 100, 15, SUB_DEFAULT},
    {12, VP_LIGHT_POINT, {42, 5, 42}, 300, 25, SUB_HARBOUR},
    {13, VP_LIGHT_SPOT, {-5, 6, -5}, 150, 18, SUB_DEFAULT},
    {14, VP_LIGHT_POINT, {-40, 8, -40}, 400, 30, SUB_DOCKS},
};
#define N_LIGHTS (sizeof WANT_LIGHTS / sizeof WANT_LIGHTS[0])

/* the destruction: one sphere on entity 5 (the wall) */
static const double WANT_HOLE[4] = {0, 2, 30.5, 1.5};

/* ---- files ------------------------------------------------------------------------------------ */

static const char *fixture_dir(char buf[512])
{
    const char *dd = getenv("VANTAGE_DATA_DIR");
    snprintf(buf, 512, "%s/upgrade_v1", dd ? dd : "tests/data");
    return buf;
}

static void copy_file(const char *from, const char *to)
{
    int in = open(from, O_RDONLY), out = open(to, O_WRONLY | O_CREAT | O_TRUNC, 0600);
    if (in < 0 || out < 0) fail_msg("copy %s -> %s: %s", from, to, strerror(errno));
    char buf[65536];
    ssize_t n;
    while ((n = read(in, buf, sizeof buf)) > 0) assert_int_equal(write(out, buf, (size_t)n), n);
    close(in);
    close(out);
}

/* Copies the fixture's snapshot and journal into dir (made); *gen = their
 * generation. */
static void fixture_copy(const char *dir, uint64_t *gen)
{
    char src[512], a[1024], b[1024];
    fixture_dir(src);
    mkdir(dir, 0700);
    DIR *d = opendir(src);
    if (!d) fail_msg("%s: %s (the fixture; run the tests from the repository root)", src, strerror(errno));
    struct dirent *e;
    int n = 0;
    while ((e = readdir(d))) {
        unsigned long long g;
        char kind[16];
        int end = 0;
        if (sscanf(e->d_name, "%15[a-z].%llu%n", kind, &g, &end) != 2 || e->d_name[end]) continue;
        snprintf(a, sizeof a, "%s/%s", src, e->d_name);
        snprintf(b, sizeof b, "%s/%s", dir, e->d_name);
        copy_file(a, b);
        *gen = g;
        n++;
    }
    closedir(d);
    assert_int_equal(n, 2); /* snapshot.<gen> and journal.<gen> */
}

/* The names of dir's snapshot and journal files, sorted, as one string. */
static void dir_files(const char *dir, char *out, size_t cap)
{
    struct dirent **v;
    int n = scandir(dir, &v, NULL, alphasort);
    assert_true(n >= 0);
    size_t k = 0;
    out[0] = 0;
    for (int i = 0; i < n; i++) {
        if (!strncmp(v[i]->d_name, "snapshot", 8) || !strncmp(v[i]->d_name, "journal", 7))
            k += (size_t)snprintf(out + k, cap - k, "%s ", v[i]->d_name);
        free(v[i]);
    }
    free(v);
}

/* The first 8 bytes of dir/<kind>.<gen>, NUL-ended. */
static void magic_of(const char *dir, const char *kind, uint64_t gen, char out[9])
{
    char p[600];
    snprintf(p, sizeof p, "%s/%s.%06llu", dir, kind, (unsigned long long)gen);
    int fd = open(p, O_RDONLY);
    if (fd < 0) fail_msg("%s: %s", p, strerror(errno));
    memset(out, 0, 9);
    assert_int_equal(read(fd, out, 8), 8);
    close(fd);
}

/* dir holds exactly snapshot.<gen> in format 3 and journal.<gen> in
 * format 2 (want: their names, as dir_files lists them). */
static void assert_current_formats(const char *dir, uint64_t gen, char want[512])
{
    char files[512], m[9];
    dir_files(dir, files, sizeof files);
    snprintf(want, 512, "journal.%06llu snapshot.%06llu ", (unsigned long long)gen, (unsigned long long)gen);
    assert_string_equal(files, want);
    magic_of(dir, "snapshot", gen, m);
    assert_string_equal(m, "VNTSNAP3");
    magic_of(dir, "journal", gen, m);
    assert_string_equal(m, "VNTJRNL2");
}

static void rm_dir(const char *dir)
{
    dir_unlink_files(dir);
    rmdir(dir);
}

/* ---- the scene against the list ------------------------------------------------------------- */

static uint16_t want_class(const scene *sc, uint16_t cls, uint16_t sub)
{
    return cls & IN_SUB ? (uint16_t)(sc->sl[sub].class_base + (cls & ~IN_SUB)) : cls;
}

static void check_mesh(const scene *sc, const want_mesh *w)
{
    uint16_t c = want_class(sc, w->cls, w->sub);
    const scene_mesh *m = &sc->meshes[c];
    if (!m->pos) fail_msg("mesh class %u is missing", c);
    float k = w->k;
    if (k == 0) { /* the triangle, no normals */
        const float pos[9] = {0, 0, 0, 2, 0, 0, 0, 2, 0};
        const uint32_t idx[3] = {0, 1, 2};
        assert_int_equal(m->nv, 3);
        assert_int_equal(m->ni, 3);
        assert_memory_equal(m->pos, pos, sizeof pos);
        assert_null(m->nrm);
        assert_memory_equal(m->idx, idx, sizeof idx);
        return;
    }
    const float pos[12] = {0, 0, 0, k, 0, 0, 0, k, 0, 0, 0, k};
    const float nrm[12] = {-0.57735f, -0.57735f, -0.57735f, 1, 0, 0, 0, 1, 0, 0, 0, 1};
    const uint32_t idx[12] = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
    assert_int_equal(m->nv, 4);
    assert_int_equal(m->ni, 12);
    assert_memory_equal(m->pos, pos, sizeof pos);
    assert_non_null(m->nrm);
    assert_memory_equal(m->nrm, nrm, sizeof nrm);
    assert_memory_equal(m->idx, idx, sizeof idx);
    assert_null(m->uv); /* version 1 had none */
}

/* Everything make_fixture.c put in, and nothing else (but `extra`
 * entities the test added in the default sub-level). */
static void check_scene(const scene *sc, uint32_t extra)
{
    /* sub-levels: names in definition order, their reserved classes */
    assert_int_equal(sc->nsublevels, 3);
    for (uint16_t id = 1; id <= 3; id++) {
        const scene_sublevel *l = &sc->sl[id];
        assert_string_equal(l->name, SUB_NAME[id]);
        assert_int_equal(l->state, 0); /* loaded (committed) or never loaded */
        assert_int_equal(l->classes, SUB_CLASSES[id]);
        for (uint32_t k = 0; k < l->classes; k++) assert_int_equal(sc->class_owner[l->class_base + k], id);
        assert_false(scene_sublevel_hidden(sc, id));
    }
    assert_int_equal(sc->nhidden, 0);
    assert_int_equal(sc->unloading, 0);
    /* entities */
    cull_world_info info;
    cull_world_info_get(sc->world, &info);
    assert_int_equal(info.entities, N_ENTITIES + extra);
    uint32_t per_sub[4] = {extra};
    for (size_t i = 0; i < N_ENTITIES; i++) {
        const want_entity *w = &WANT_ENTITIES[i];
        uint64_t h;
        if (!idmap_get(&sc->ids, w->id, &h)) fail_msg("entity %llu is missing", (unsigned long long)w->id);
        vp_entity e;
        scene_entity_record(sc, (cull_handle)h, &e);
        assert_int_equal(e.id, w->id);
        assert_int_equal(e.class_id, want_class(sc, w->cls, w->sub));
        assert_int_equal(e.sublevel, w->sub);
        assert_int_equal(e.flags, w->flags);
        assert_int_equal(e.material, 0);
        for (int k = 0; k < 4; k++)
            if (e.sphere[k] != w->sphere[k])
                fail_msg("entity %llu: sphere[%d] %.17g, want %.17g", (unsigned long long)w->id, k, e.sphere[k],
                         w->sphere[k]);
        for (int k = 0; k < 6; k++)
            if (e.aabb[k] != w->aabb[k])
                fail_msg("entity %llu: aabb[%d] %.17g, want %.17g", (unsigned long long)w->id, k, e.aabb[k],
                         w->aabb[k]);
        per_sub[w->sub]++;
    }
    assert_false(idmap_get(&sc->ids, 6, NULL)); /* removed */
    for (int id = 0; id < 4; id++) assert_int_equal(sc->sl_entities[id], per_sub[id]);
    /* meshes */
    assert_int_equal(sc->nmeshes, N_MESHES);
    for (size_t i = 0; i < N_MESHES; i++) check_mesh(sc, &WANT_MESHES[i]);
    /* occluders: as sent (the world draws the wall's with its hole) */
    assert_int_equal(sc->occluders.count, N_OCCLUDERS);
    uint32_t occ_sub[4] = {0};
    for (size_t i = 0; i < N_OCCLUDERS; i++) {
        const want_occluder *w = &WANT_OCCLUDERS[i];
        uint64_t v;
        if (!idmap_get(&sc->occluders, w->id, &v)) fail_msg("occluder %llu is missing", (unsigned long long)w->id);
        const scene_occluder *o = (const scene_occluder *)(uintptr_t)v;
        const float t[18] = {0, 0, 0, w->w, 0, 0, w->w, w->h, 0, 0, 0, 0, w->w, w->h, 0, 0, w->h, 0};
        assert_memory_equal(o->origin, w->origin, sizeof o->origin);
        assert_int_equal(o->ntris, 2);
        assert_memory_equal(o->verts, t, sizeof t);
        assert_int_equal(o->sublevel, w->sub);
        assert_int_equal(o->flags, 0);
        assert_true(o->h != 0); /* drawn */
        occ_sub[w->sub]++;
    }
    for (int id = 1; id < 4; id++) assert_int_equal(sc->sl[id].occluders, occ_sub[id]);
    /* lights */
    assert_int_equal(sc->lights.count, N_LIGHTS);
    uint32_t light_sub[4] = {0};
    for (size_t i = 0; i < N_LIGHTS; i++) {
        const want_light *w = &WANT_LIGHTS[i];
        uint64_t v;
        if (!idmap_get(&sc->lights, w->id, &v)) fail_msg("light %llu is missing", (unsigned long long)w->id);
        const scene_light *l = (const scene_light *)(uintptr_t)v;
        const float dir[3] = {0, -1, 0}, color[3] = {1, 0.75f, 0.5f};
        assert_int_equal(l->l.kind, w->kind);
        assert_memory_equal(l->l.pos, w->pos, sizeof w->pos);
        assert_memory_equal(l->l.dir, dir, sizeof dir);
        assert_memory_equal(l->l.color, color, sizeof color);
        assert_true(l->l.intensity == w->intensity && l->l.range == w->range);
        assert_true(l->l.inner_cos == 0.9f && l->l.outer_cos == 0.8f);
        assert_int_equal(l->sublevel, w->sub);
        light_sub[w->sub]++;
    }
    for (int id = 1; id < 4; id++) assert_int_equal(sc->sl[id].lights, light_sub[id]);
    /* the destruction: the wall's one hole */
    assert_int_equal(sc->destruct.count, 1);
    const scene_destruct *d = scene_destruct_of(sc, 5);
    assert_non_null(d);
    assert_int_equal(d->v.nsph, 1);
    for (int k = 0; k < 4; k++) assert_true(d->v.sph[0][k] == WANT_HOLE[k]);
    /* the model a version 1 scene had: no materials, textures; the default environment */
    assert_int_equal(sc->materials.count, 0);
    assert_int_equal(sc->textures.count, 0);
    vp_env env;
    vp_env_default(&env);
    assert_memory_equal(&sc->env, &env, sizeof env);
}

/* The scene as bytes: a snapshot body (everything a snapshot keeps). */
static uint8_t *scene_bytes(const scene *sc, size_t *n)
{
    int fd = memfd_create("scene", MFD_CLOEXEC);
    assert_true(fd >= 0);
    assert_int_equal(snapshot_write(fd, sc, 0, 0), 0);
    off_t end = lseek(fd, 0, SEEK_END);
    *n = (size_t)end - 40;
    uint8_t *b = malloc(*n);
    assert_int_equal(pread(fd, b, *n, 40), (ssize_t)*n);
    close(fd);
    return b;
}

static scene *open_dir(const char *dir, journal **j, journal_report *rep)
{
    scene *sc = malloc(sizeof *sc); /* 2.6 MB: not on the stack */
    assert_non_null(sc);
    assert_int_equal(scene_init(sc, 64, &LIMITS), 0);
    char err[800];
    sc->replaying = true; /* as vantaged opens it */
    if (journal_open(dir, JOURNAL_ALWAYS, sc, j, rep, err, sizeof err)) fail_msg("%s: %s", dir, err);
    sc->replaying = false;
    return sc;
}

static void close_dir(scene *sc, journal *j)
{
    assert_int_equal(journal_close(j), 0);
    scene_free(sc);
    free(sc);
}

/* In process: restored exactly as made, upgraded once. */
static void test_upgrade_v1_dir_restores_and_upgrades(void **state)
{
    (void)state;
    int lvl = g_log_level;
    g_log_level = LOG_ERROR;
    tdir td;
    tdir_make(&td, "upgrade");
    char dir[320];
    snprintf(dir, sizeof dir, "%s", tdir_file(&td, "data"));
    uint64_t gen = 0;
    fixture_copy(dir, &gen);
    char m[9];
    magic_of(dir, "snapshot", gen, m);
    assert_string_equal(m, "VNTSNAP2"); /* what version 1 wrote */
    magic_of(dir, "journal", gen, m);
    assert_string_equal(m, "VNTJRNL1");

    journal *j;
    journal_report rep;
    scene *sc = open_dir(dir, &j, &rep);
    assert_int_equal(rep.snapshot_gen, gen);
    assert_true(rep.records >= 15); /* part b: every kind of edit, in version 1's layouts */
    assert_int_equal(rep.cut_bytes, 0);
    assert_int_equal(rep.upgrade_gen, gen + 1);
    check_scene(sc, 0);
    size_t n1;
    uint8_t *b1 = scene_bytes(sc, &n1);
    close_dir(sc, j);

    /* the directory is now the current formats, the old files gone */
    char files[512], want[512];
    assert_current_formats(dir, gen + 1, want);

    /* a second open: the same scene, from the new snapshot, no upgrade */
    sc = open_dir(dir, &j, &rep);
    assert_int_equal(rep.upgrade_gen, 0);
    assert_int_equal(rep.snapshot_gen, gen + 1);
    assert_int_equal(rep.records, 0);
    check_scene(sc, 0);
    size_t n2;
    uint8_t *b2 = scene_bytes(sc, &n2);
    assert_int_equal(n1, n2);
    assert_memory_equal(b1, b2, n1);
    close_dir(sc, j);
    dir_files(dir, files, sizeof files);
    assert_string_equal(files, want);
    free(b1);
    free(b2);
    rm_dir(dir);
    tdir_remove(&td);
    g_log_level = lvl;
}

static size_t file_size(const char *dir, const char *kind, uint64_t gen)
{
    char p[600];
    snprintf(p, sizeof p, "%s/%s.%06llu", dir, kind, (unsigned long long)gen);
    struct stat st;
    if (stat(p, &st)) fail_msg("%s: %s", p, strerror(errno));
    return (size_t)st.st_size;
}

/* An upgrade whose snapshot cannot be written (its temporary file's name
 * taken by a directory): the old files stay as they were, edits go to a
 * new format 2 journal after the format 1 one, and the next start
 * replays across both formats and upgrades then, the edit kept. */
static void test_upgrade_v1_dir_snapshot_fails(void **state)
{
    (void)state;
    int lvl = g_log_level;
    g_log_level = -1;
    tdir td;
    tdir_make(&td, "upgrade-fail");
    char dir[320], block[400];
    snprintf(dir, sizeof dir, "%s", tdir_file(&td, "data"));
    uint64_t gen = 0;
    fixture_copy(dir, &gen);
    size_t v1_size = file_size(dir, "journal", gen);
    snprintf(block, sizeof block, "%s/snapshot.tmp.%06llu", dir, (unsigned long long)gen + 1);
    assert_int_equal(mkdir(block, 0700), 0);
    journal *j;
    journal_report rep;
    scene *sc = open_dir(dir, &j, &rep);
    assert_int_equal(rep.upgrade_gen, 0); /* not done */
    check_scene(sc, 0);
    char files[512], want[512], m[9];
    dir_files(dir, files, sizeof files);
    snprintf(want, sizeof want, "journal.%06llu journal.%06llu snapshot.%06llu snapshot.tmp.%06llu ",
             (unsigned long long)gen, (unsigned long long)gen + 1, (unsigned long long)gen,
             (unsigned long long)gen + 1); /* (the blocker) */
    assert_string_equal(files, want);
    magic_of(dir, "journal", gen + 1, m);
    assert_string_equal(m, "VNTJRNL2");
    /* an edit: into the new journal, not the old one */
    uint8_t buf[VP_HEADER_SIZE + 4 + VP_ENTITY_REC_SIZE];
    vp_writer w;
    vp_writer_init(&w, buf, sizeof buf);
    vp_enc_entities(&w, VP_ENTITY_ADD, 1, &(vp_entity){.id = 77, .sphere = {1, 2, 3, 4}}, 1);
    edit e;
    assert_int_equal(edit_decode(VP_ENTITY_ADD, buf + VP_HEADER_SIZE, (uint32_t)(w.len - VP_HEADER_SIZE), 0,
                                 EDIT_LAYOUT, &e),
                     VP_OK);
    edit_result r;
    scene_err err;
    assert_int_equal(journal_apply(j, sc, &e, buf + VP_HEADER_SIZE, (uint32_t)(w.len - VP_HEADER_SIZE), &r, &err),
                     VP_OK);
    edit_result_free(&r);
    close_dir(sc, j);
    assert_int_equal(file_size(dir, "journal", gen), v1_size);
    assert_int_equal(rmdir(block), 0);
    /* the next start: both journals replayed, upgraded now */
    sc = open_dir(dir, &j, &rep);
    assert_int_equal(rep.upgrade_gen, gen + 2);
    assert_true(idmap_get(&sc->ids, 77, NULL));
    check_scene(sc, 1);
    close_dir(sc, j);
    assert_current_formats(dir, gen + 2, want);
    rm_dir(dir);
    tdir_remove(&td);
    g_log_level = lvl;
}

/* ---- end to end ------------------------------------------------------------------------------ */

static void start_on(daemon_proc *d, const char *dir)
{
    const char *extra[] = {"--data-dir", dir, "--durability", "always", NULL};
    daemon_start_args(d, extra);
}

static int cmp_ent(const void *a, const void *b)
{
    const vp_entity *x = a, *y = b;
    return (x->id > y->id) - (x->id < y->id);
}

/* Every entity a client lists, by id; n of them. */
static vp_entity *list_all(vtc_client *c, uint32_t *n)
{
    vp_entity *e = malloc(64 * sizeof *e);
    *n = 0;
    uint64_t cur = 0;
    do {
        vp_list_reply lr;
        assert_int_equal(vtc_list(c, cur, 16, &lr), VP_OK);
        for (uint32_t i = 0; i < lr.batch.count && *n < 64; i++)
            assert_int_equal(vp_entity_get(&lr.batch, i, &e[(*n)++]), VP_OK);
        cur = lr.next_cursor;
    } while (cur);
    qsort(e, *n, sizeof *e, cmp_ent);
    return e;
}

/* Whether entity id is visible from (0, 2, 60) looking along -z (the
 * wall's triangles face +z: an occluder hides from its front side). */
static bool seen(vtc_client *c, uint64_t id)
{
    vp_view v;
    assert_true(vtc_view_perspective(&v, (double[]){0, 2, 60}, (double[]){0, 2, 0}, NULL, 50, 256, 114, 0.1, 500));
    vp_vis_result res;
    assert_int_equal(vtc_query(c, &v, 1, 0, 0, &res), VP_OK);
    for (uint32_t i = 0; i < res.count; i++) {
        vp_vis_rec x;
        vp_vis_rec_get(&res, i, &x);
        if (x.id == id) return true;
    }
    return false;
}

/* What a client sees of the upgraded scene (probes: the entities the test
 * added behind the wall, if any). */
static void check_client_view(vtc_client *c, bool probes)
{
    uint32_t n;
    vp_entity *e = list_all(c, &n);
    assert_int_equal(n, N_ENTITIES + (probes ? 2 : 0));
    vp_sublevel_infos li;
    assert_int_equal(vtc_sublevel_info(c, &li), VP_OK);
    size_t pos = 0;
    vp_sublevel_info in;
    uint16_t base[4] = {0};
    while (vp_sublevel_info_next(&li, &pos, &in)) {
        assert_true(in.id >= 1 && in.id <= 3);
        assert_int_equal(in.name_len, strlen(SUB_NAME[in.id]));
        assert_memory_equal(in.name, SUB_NAME[in.id], in.name_len);
        assert_int_equal(in.classes, SUB_CLASSES[in.id]);
        base[in.id] = in.class_base;
    }
    uint32_t k = 0;
    for (size_t i = 0; i < N_ENTITIES; i++) {
        const want_entity *w = &WANT_ENTITIES[i];
        while (k < n && e[k].id != w->id) k++;
        if (k == n) fail_msg("entity %llu is not listed", (unsigned long long)w->id);
        uint16_t cls = w->cls & IN_SUB ? (uint16_t)(base[w->sub] + (w->cls & ~IN_SUB)) : w->cls;
        assert_int_equal(e[k].class_id, cls);
        assert_int_equal(e[k].sublevel, w->sub);
        assert_int_equal(e[k].flags, w->flags);
        assert_memory_equal(e[k].sphere, w->sphere, sizeof w->sphere);
        assert_memory_equal(e[k].aabb, w->aabb, sizeof w->aabb);
    }
    free(e);
}

/* vantaged on a copy of the fixture: it upgrades, serves the scene, keeps
 * an edit made after the upgrade across a restart, and the restart does
 * not upgrade again. */
static void test_upgrade_v1_dir_daemon(void **state)
{
    (void)state;
    tdir td;
    tdir_make(&td, "upgrade-e2e");
    char dir[320];
    snprintf(dir, sizeof dir, "%s", tdir_file(&td, "data"));
    uint64_t gen = 0;
    fixture_copy(dir, &gen);
    daemon_proc d;
    start_on(&d, dir);
    vtc_client *c = connect_role(&d, VP_ROLE_EDITOR, false);
    check_client_view(c, false);
    /* the files: the current formats from the start, nothing appended to
       version 1's */
    char files[512], want[512];
    assert_current_formats(dir, gen + 1, want);
    /* the wall's hole (the version 1 journal's destruction) is open: a
       probe behind its centre is seen, one behind a corner of the wall
       (which the hole, cut conservatively large, leaves) is not. Without
       the destruction the wall hides both; through the wall's front (it
       faces +z), from z = 60, points on it at (0, 2) and (3.8, 3.8) put
       at z = 10 (x 50 / 29.5 from the eye) */
    vp_entity probes[2] = {
        {.id = 1000, .sphere = {0, 2, 10, 0.05}},
        {.id = 1001, .sphere = {3.8 * 50 / 29.5, 2 + 1.8 * 50 / 29.5, 10, 0.05}},
    };
    uint32_t hs[2];
    uint64_t epoch;
    assert_int_equal(vtc_add(c, probes, 2, hs, &epoch), VP_OK);
    assert_true(seen(c, 1000));
    assert_false(seen(c, 1001));
    vtc_close(c);
    daemon_stop(&d);

    /* a restart: no upgrade (same files), the edit is there */
    start_on(&d, dir);
    c = connect_role(&d, VP_ROLE_EDITOR, false);
    check_client_view(c, true);
    assert_true(seen(c, 1000));
    assert_false(seen(c, 1001));
    dir_files(dir, files, sizeof files);
    assert_string_equal(files, want);
    vtc_close(c);
    daemon_stop(&d);
    rm_dir(dir);
    tdir_remove(&td);
}

const struct CMUnitTest upgrade_tests[] = {
    cmocka_unit_test(test_upgrade_v1_dir_restores_and_upgrades),
    cmocka_unit_test(test_upgrade_v1_dir_snapshot_fails),
    cmocka_unit_test(test_upgrade_v1_dir_daemon),
};
const size_t upgrade_tests_count = sizeof upgrade_tests / sizeof upgrade_tests[0];
