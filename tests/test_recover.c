/*
 * test_recover.c — the journal and snapshots driven in-process (journal.c,
 * snapshot.c linked into the tests): a scripted session that touches every
 * kind of state, journaled and snapshotted as the daemon does it, then
 *   - a snapshot holding a sub-level name restores (issue 18, item 2);
 *   - every bit of every file of its data directory flipped, one at a
 *     time, and every truncation: recovery either restores exactly the
 *     state before the damaged record (only a torn end cut) or refuses,
 *     naming the file and the offset. The model: the state recovered from
 *     the undamaged files cut at each record boundary.
 * Recovery runs in this process (journal_open on a copy of the files in
 * tmpfs): tens of thousands of restarts in seconds, where spawning a
 * daemon for each would take an hour.
 */
#include "test_util.h"

#include "edit.h"
#include "journal.h"
#include "log.h"
#include "snapshot.h"
#include "vt_image.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>
#include <zlib.h>

#if defined(__SANITIZE_ADDRESS__)
#define UNDER_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define UNDER_ASAN 1
#endif
#endif

static const scene_limits LIMITS = {.max_entities = 1u << 20, .max_lights = 65536, .max_occluders = 1u << 20,
                                    .max_occluder_tris = 1u << 20, .max_mesh_verts = 1u << 20,
                                    .max_materials = 1u << 16, .max_texture_size = 4096,
                                    .max_texture_mem = 1ull << 28};

/* ---- a session: edits through journal_apply, as handlers.c makes them ------------------- */

typedef struct sess {
    journal *j;
    scene sc;
    uint16_t sublevel; /* the sub-level the one editing connection is loading, 0 = none */
    bool v1_scene;     /* what protocol version 1 had only (no model edits) */
    uint8_t buf[1 << 16];
} sess;

/* Applies the message encoded in s->buf (w: its writer) as the daemon does. */
static edit_result apply_w(sess *s, const vp_writer *w, uint32_t aux)
{
    uint16_t type = (uint16_t)(s->buf[4] | s->buf[5] << 8);
    const uint8_t *p = s->buf + VP_HEADER_SIZE;
    uint32_t len = (uint32_t)(w->len - VP_HEADER_SIZE);
    edit e;
    int drc = edit_decode(type, p, len, 0, EDIT_LAYOUT, &e);
    if (drc) fail_msg("edit 0x%04x does not decode: %s", type, vp_strerror(drc));
    e.sublevel = s->sublevel;
    e.aux = aux;
    edit_result r;
    scene_err err = {0};
    int rc = journal_apply(s->j, &s->sc, &e, p, len, &r, &err);
    if (rc) fail_msg("edit 0x%04x refused: %s", type, err.msg);
    if (type == VP_SUBLEVEL_BEGIN) s->sublevel = r.begun.id;
    if (type == VP_SUBLEVEL_COMMIT || type == VP_SUBLEVEL_ABORT) s->sublevel = 0;
    return r;
}

static void ap(sess *s, const vp_writer *w, uint32_t aux)
{
    edit_result r = apply_w(s, w, aux);
    edit_result_free(&r);
}

static vp_writer wr(sess *s)
{
    vp_writer w;
    vp_writer_init(&w, s->buf, sizeof s->buf);
    return w;
}

static void s_add(sess *s, uint64_t first, uint32_t n, uint16_t sub)
{
    vp_entity e[64];
    for (uint32_t i = 0; i < n; i++)
        e[i] = (vp_entity){.id = first + i, .class_id = (uint16_t)(1 + i % 3), .sublevel = sub,
                           .sphere = {(double)i * 3 - 20, 1, (double)(i % 5) * 2, 0.5 + i * 0.1}};
    vp_writer w = wr(s);
    vp_enc_entities(&w, VP_ENTITY_ADD, 1, e, n);
    ap(s, &w, 0);
}

static void s_names(sess *s, const char *a, const char *b)
{
    const char *names[2] = {a, b};
    vp_writer w = wr(s);
    vp_enc_names(&w, VP_SUBLEVEL_NAMES, 1, names, NULL, b ? 2 : 1);
    ap(s, &w, 0);
}

static void s_begin(sess *s, const char *name, uint16_t classes)
{
    vp_writer w = wr(s);
    vp_enc_sublevel_begin(&w, 1, &(vp_sublevel_begin){.classes = classes, .name_len = (uint8_t)strlen(name),
                                                       .name = (const uint8_t *)name});
    ap(s, &w, 7 /* the connection's id */);
}

static void s_end(sess *s, uint16_t type)
{
    vp_writer w = wr(s);
    vp_enc_empty(&w, type, 1);
    ap(s, &w, 0);
}

static void s_mesh(sess *s, uint16_t cls)
{
    float pos[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0}, nrm[9] = {0, 0, 1, 0, 0, 1, 0, 0, 1};
    uint32_t idx[3] = {0, 1, 2};
    vp_writer w = wr(s);
    vp_enc_mesh(&w, 1, cls, pos, nrm, 3, idx, 3);
    ap(s, &w, 0);
}

static void s_occluder(sess *s, uint64_t id, double x)
{
    float quad[18] = {0, 0, 0, 8, 0, 0, 8, 4, 0, 0, 0, 0, 8, 4, 0, 0, 4, 0};
    vp_writer w = wr(s);
    vp_enc_occluder(&w, 1, id, (double[]){x, 0, 0}, quad, 2);
    ap(s, &w, 0);
}

static void s_lights(sess *s, uint64_t first, uint32_t n)
{
    vp_light l[4];
    for (uint32_t i = 0; i < n; i++)
        l[i] = (vp_light){.id = first + i, .kind = i & 1 ? VP_LIGHT_SPOT : VP_LIGHT_POINT, .pos = {i * 3.0, 4, 1},
                          .dir = {0, -1, 0}, .color = {1, 0.5f, 0.25f}, .intensity = 50, .range = 12,
                          .inner_cos = 0.9f, .outer_cos = 0.8f};
    vp_writer w = wr(s);
    vp_enc_lights(&w, 1, l, n);
    ap(s, &w, 0);
}

static void s_ids(sess *s, uint16_t type, const uint64_t *ids, uint32_t n)
{
    vp_writer w = wr(s);
    vp_enc_ids(&w, type, 1, ids, n);
    ap(s, &w, 0);
}

static void s_work(sess *s, uint32_t budget)
{
    edit_result r;
    scene_err err;
    assert_int_equal(journal_apply(s->j, &s->sc, &(edit){.type = EDIT_WORK, .aux = budget}, NULL, 0, &r, &err), 0);
    edit_result_free(&r);
}

/* ---- the scene model: textures, materials, the environment, transforms ---------------------- */

/* Whether this build applies the scene model's edits (the daemon's part of
 * issue 19 lands separately from its persistence: until it does, the
 * sessions leave them out and the campaign covers the rest). */
static bool model_ready(void)
{
    return edit_is(VP_TRANSFORM_SET) && edit_is(VP_MATERIAL_PUT) && edit_is(VP_TEXTURE_PUT) && edit_is(VP_ENV_SET);
}

/* TEXTURE_PUT of a w x h PNG (a gradient, seeded), whole. */
static void s_texture(sess *s, uint32_t id, uint32_t w, uint32_t h, uint8_t seed)
{
    uint8_t px[16 * 16 * 4];
    for (uint32_t i = 0; i < w * h * 4; i++) px[i] = (uint8_t)(seed + i * 7);
    char path[] = "/tmp/recover-tex.XXXXXX";
    int fd = mkstemp(path);
    assert_true(fd >= 0);
    close(fd);
    char err[200];
    if (vt_png_write(path, w, h, px, w * 4, true, 6, err, sizeof err)) fail_msg("png: %s", err);
    static uint8_t png[8192];
    fd = open(path, O_RDONLY);
    ssize_t n = read(fd, png, sizeof png);
    assert_true(n > 0 && n < (ssize_t)sizeof png);
    close(fd);
    unlink(path);
    vp_writer w0;
    vp_writer_init(&w0, s->buf, sizeof s->buf);
    vp_enc_texture_put(&w0, 1, &(vp_texture_put){.id = id, .format = VP_TEX_PNG, .flags = VP_TEX_SRGB,
                                                  .total = (uint32_t)n, .len = (uint32_t)n, .data = png});
    ap(s, &w0, 0);
}

static void s_material(sess *s, uint32_t id, uint32_t tex, float rough)
{
    vp_material m = {.id = id, .base_color = {0.8f, 0.5f, 0.25f, 1}, .metallic = 0.25f, .roughness = rough,
                     .emissive = {0.1f, 0, 0}, .emissive_strength = 2, .normal_scale = 1};
    m.tex[VP_TEX_BASE] = (vp_texref){.texture = tex, .min_filter = VP_FILTER_LINEAR_MIP_LINEAR,
                                     .mag_filter = VP_FILTER_LINEAR, .scale = {1, 1}};
    vp_writer w = wr(s);
    vp_enc_materials(&w, 1, &m, 1);
    ap(s, &w, 0);
}

static void s_env(sess *s, float sun_y, float ev)
{
    vp_env e;
    vp_env_default(&e);
    double n = sqrt(0.09 + (double)sun_y * sun_y + 0.04);
    e.sun_dir[0] = (float)(0.3 / n);
    e.sun_dir[1] = (float)(sun_y / n);
    e.sun_dir[2] = (float)(0.2 / n);
    e.exposure_mode = VP_EXPOSURE_FIXED;
    e.exposure_ev = ev;
    vp_writer w = wr(s);
    vp_enc_env(&w, VP_ENV_SET, 1, &e);
    ap(s, &w, 0);
}

/* A quad mesh with UVs and tangents. */
static void s_mesh_uv(sess *s, uint16_t cls)
{
    float pos[12] = {-1, 0, -1, 1, 0, -1, 1, 0, 1, -1, 0, 1}, nrm[12] = {0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0};
    float uv[8] = {0, 0, 1, 0, 1, 1, 0, 1}, tan[16] = {1, 0, 0, 1, 1, 0, 0, 1, 1, 0, 0, 1, 1, 0, 0, 1};
    uint32_t idx[6] = {0, 2, 1, 0, 3, 2};
    vp_writer w = wr(s);
    vp_enc_mesh_uv(&w, 1, cls, pos, nrm, uv, tan, 4, idx, 6);
    ap(s, &w, 0);
}

/* Entities with a transform (class cls, material mat), rotations not unit
 * to the last bit (renormalised on the way in). */
static void s_add_trs(sess *s, uint64_t first, uint32_t n, uint16_t cls, uint32_t mat, uint16_t type)
{
    vp_entity e[4];
    for (uint32_t i = 0; i < n; i++) {
        float a = 0.3f + 0.7f * (float)i;
        e[i] = (vp_entity){.id = first + i, .class_id = cls, .flags = VP_ENT_TRANSFORM, .material = mat,
                           .pos = {5.0 * i - 3, 1.5, -7.25 + i}, .rot = {0, sinf(a / 2), 0.0001f, cosf(a / 2)},
                           .scale = {1.5f, 2, i ? -1.0f : 1.0f}};
    }
    vp_writer w = wr(s);
    vp_enc_entities(&w, type, 1, e, n);
    ap(s, &w, 0);
}

static void s_transform(sess *s, uint64_t id, double x)
{
    vp_transform t = {.id = id, .pos = {x, 2, -3}, .rot = {0.1f, 0.2f, 0.3f, 0.9273618f}, .scale = {1, 1, 3}};
    vp_writer w = wr(s);
    vp_enc_transforms(&w, 1, &t, 1);
    ap(s, &w, 0);
}

/* Part one of the model: every kind of its state, into the snapshot. */
static void script_model_a(sess *s)
{
    s_texture(s, 1, 4, 4, 1);
    s_texture(s, 2, 8, 2, 50);
    s_material(s, 1, 1, 0.5f);
    s_material(s, 2, 0, 0.9f);
    s_env(s, 0.8f, 12);
    s_mesh_uv(s, 20);
    s_add_trs(s, 600, 2, 20, 1, VP_ENTITY_ADD);
    float quad[18] = {-1, 0, 0, 1, 0, 0, 1, 2, 0, -1, 0, 0, 1, 2, 0, -1, 2, 0};
    vp_writer w = wr(s);
    vp_enc_occluder_flags(&w, 1, 600, VP_OCC_ATTACHED, (double[]){0, 0, 0}, quad, 2);
    ap(s, &w, 0);
    s_transform(s, 600, 4);
    vp_destroy d = {.id = 601, .center = {2, 1.5, -6.25}, .radius = 0.5};
    w = wr(s);
    vp_enc_destroy(&w, 1, &d);
    ap(s, &w, 4);
}

/* Part two: each changed again, in the journal. */
static void script_model_b(sess *s)
{
    s_texture(s, 3, 4, 2, 9);
    s_material(s, 2, 3, 0.125f); /* replaced */
    s_env(s, 0.5f, 9);
    s_transform(s, 601, -2);
    s_add_trs(s, 600, 1, 20, 2, VP_ENTITY_UPDATE);
    s_ids(s, VP_TEXTURE_REMOVE, (uint64_t[]){2}, 1);
    s_mesh_uv(s, 21);
    s_add_trs(s, 610, 1, 21, 0, VP_ENTITY_ADD);
}

/* Part one: sub-level names only (no members, no classes), entities with
 * holes in the handle table, an update, meshes, a wall with its occluder,
 * lights (one removed), a committed load with classes, a destruction. */
static void script_a(sess *s)
{
    s_names(s, "alpha", "beta");
    s_add(s, 1, 6, 0);
    s_ids(s, VP_ENTITY_REMOVE, (uint64_t[]){2, 5}, 2);
    vp_entity up = {.id = 4, .class_id = 2, .sphere = {4, 2, 4, 1.5}};
    vp_writer w = wr(s);
    vp_enc_entities(&w, VP_ENTITY_UPDATE, 1, &up, 1);
    ap(s, &w, 0);
    s_mesh(s, 1);
    s_mesh(s, 2);
    vp_entity wall = {.id = 900, .aabb = {-4, 0, -1, 4, 4, 1}};
    w = wr(s);
    vp_enc_entities(&w, VP_ENTITY_ADD, 1, &wall, 1);
    ap(s, &w, 0);
    s_occluder(s, 900, -4);
    s_lights(s, 70, 3);
    s_ids(s, VP_LIGHT_REMOVE, (uint64_t[]){71}, 1);
    s_begin(s, "town", 2);
    s_add(s, 100, 2, 0);
    s_mesh(s, s->sc.sl[s->sublevel].class_base);
    s_occluder(s, 901, 20);
    s_lights(s, 80, 1);
    s_end(s, VP_SUBLEVEL_COMMIT);
    vp_destroy d = {.id = 900, .debris = 2, .center = {0, 2, 0}, .radius = 1.5};
    w = wr(s);
    vp_enc_destroy(&w, 1, &d);
    ap(s, &w, 4 /* the volume resolution */);
    if (model_ready() && !s->v1_scene) script_model_a(s);
}

/* Part two: more of each, an aborted load, an unload left half done, a
 * load left open (recovery drops it). */
static void script_b(sess *s)
{
    s_add(s, 200, 2, 1 /* "alpha" */);
    s_mesh(s, 3);
    vp_entity up = {.id = 6, .class_id = 3, .sphere = {-6, 1, 2, 0.75}};
    vp_writer w0 = wr(s);
    vp_enc_entities(&w0, VP_ENTITY_UPDATE, 1, &up, 1);
    ap(s, &w0, 0);
    s_names(s, "gamma", NULL);
    s_ids(s, VP_OCCLUDER_REMOVE, (uint64_t[]){901}, 1);
    vp_destroy d = {.id = 900, .debris = 1, .center = {2, 1, 0}, .radius = 1};
    vp_writer w = wr(s);
    vp_enc_destroy(&w, 1, &d);
    ap(s, &w, 4);
    s_begin(s, "gone", 1);
    s_add(s, 300, 2, 0);
    s_end(s, VP_SUBLEVEL_ABORT);
    s_begin(s, "harbour", 0);
    s_add(s, 400, 2, 0);
    s_end(s, VP_SUBLEVEL_COMMIT);
    w = wr(s);
    vp_enc_sublevel_name(&w, VP_SUBLEVEL_UNLOAD, 1, "town");
    ap(s, &w, 0);
    s_work(s, 1);
    s_work(s, 1);
    s_lights(s, 90, 2);
    if (model_ready() && !s->v1_scene) script_model_b(s);
    s_begin(s, "limbo", 1);
    s_add(s, 500, 1, 0);
}

/* ---- files ------------------------------------------------------------------------------------ */

/* A directory in tmpfs when there is one (recovery syncs what it cuts). */
static void scratch_make(char dir[256], const char *prefix)
{
    struct stat st;
    const char *base = !stat("/dev/shm", &st) && S_ISDIR(st.st_mode) && !access("/dev/shm", W_OK) ? "/dev/shm"
                       : getenv("TMPDIR") ? getenv("TMPDIR")
                                          : "/tmp";
    snprintf(dir, 256, "%s/%s.XXXXXX", base, prefix);
    assert_non_null(mkdtemp(dir));
}

static void dir_remove(const char *dir)
{
    dir_unlink_files(dir);
    rmdir(dir);
}

typedef struct blob {
    uint8_t *p;
    size_t n;
} blob;

static blob slurp(const char *dir, const char *name)
{
    char p[600];
    snprintf(p, sizeof p, "%s/%s", dir, name);
    int fd = open(p, O_RDONLY);
    if (fd < 0) fail_msg("%s: %s", p, strerror(errno));
    struct stat st;
    assert_int_equal(fstat(fd, &st), 0);
    blob b = {malloc((size_t)st.st_size + 1), (size_t)st.st_size};
    assert_int_equal(pread(fd, b.p, b.n, 0), (ssize_t)b.n);
    close(fd);
    return b;
}

static void spit(const char *dir, const char *name, const uint8_t *p, size_t n)
{
    char path[600];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    int fd = open(path, O_WRONLY | O_CREAT | O_TRUNC, 0600);
    assert_true(fd >= 0);
    assert_int_equal(write(fd, p, n), (ssize_t)n);
    close(fd);
}

/* The scene as bytes: snapshot_write's body (every piece of state it keeps,
 * in a fixed order), which two scenes share exactly when they hold the same. */
static blob scene_bytes(const scene *sc)
{
    int fd = memfd_create("scene", MFD_CLOEXEC);
    assert_true(fd >= 0);
    assert_int_equal(snapshot_write(fd, sc, 0, 0), 0);
    off_t end = lseek(fd, 0, SEEK_END);
    blob b = {malloc((size_t)end), (size_t)end - 40};
    assert_int_equal(pread(fd, b.p, b.n, 40), (ssize_t)b.n);
    close(fd);
    return b;
}

/* ---- item 2: a sub-level name in a snapshot ----------------------------------------------------- */

/* Restores dir into a fresh scene: 0 and *out (the scene's bytes), or -1
 * and err. */
static int recover(const char *dir, blob *out, journal_report *rep, char *err, size_t errlen)
{
    scene *sc = malloc(sizeof *sc); /* 2.6 MB: not on the stack */
    assert_non_null(sc);
    assert_int_equal(scene_init(sc, 64, &LIMITS), 0);
    journal *j = NULL;
    journal_report r0;
    int rc = journal_open(dir, JOURNAL_OFF, sc, &j, rep ? rep : &r0, err, errlen);
    if (!rc) {
        if (out) *out = scene_bytes(sc);
        journal_close(j);
    }
    scene_free(sc);
    free(sc);
    return rc;
}

static void sess_open(sess *s, const char *dir)
{
    memset(s, 0, sizeof *s);
    assert_int_equal(scene_init(&s->sc, 64, &LIMITS), 0);
    journal_report rep;
    char err[400];
    if (journal_open(dir, JOURNAL_OFF, &s->sc, &s->j, &rep, err, sizeof err)) fail_msg("%s", err);
}

static void sess_close(sess *s)
{
    journal_close(s->j);
    scene_free(&s->sc);
}

/* A snapshot of a scene whose only sub-level state is a name (no members,
 * no classes: arrays of length 0) reads back: its CRC was computed over
 * other bytes than written ("body CRC mismatch" at every restart) when a
 * zero-length piece restarted zlib's running CRC. */
static void test_recover_snapshot_sublevel_name(void **state)
{
    (void)state;
    int lvl = g_log_level;
    g_log_level = LOG_ERROR;
    char dir[256], err[400];
    scratch_make(dir, "recover-name");
    sess *s = malloc(sizeof *s);
    sess_open(s, dir);
    s_names(s, "alpha", NULL);
    s_add(s, 1, 10, 0);
    blob want = scene_bytes(&s->sc);
    assert_int_equal(journal_snapshot(s->j, &s->sc), 0);
    sess_close(s); /* waits for the child, puts the snapshot in place */
    free(s);
    blob jr = slurp(dir, "journal.000002");
    assert_int_equal(jr.n, 32); /* no record after the snapshot: it holds everything */
    blob got;
    journal_report rep;
    if (recover(dir, &got, &rep, err, sizeof err)) fail_msg("restart refused: %s", err);
    assert_int_equal(rep.snapshot_gen, 2);
    assert_int_equal(got.n, want.n);
    assert_memory_equal(got.p, want.p, want.n);
    free(got.p);
    free(want.p);
    free(jr.p);
    dir_remove(dir);
    g_log_level = lvl;
}

/* Everything of sc that a snapshot's bytes do not show (it is derived on
 * the way back) equals in want: per handle slot the transform and
 * material (scene_xform), the users of materials and textures, the
 * texture memory, every texture's decoded levels. */
static void assert_same_derived(const scene *want, const scene *got)
{
    assert_int_equal(cull_world_slots(want->world), cull_world_slots(got->world));
    for (uint32_t i = 0; i < cull_world_slots(want->world); i++) {
        bool on;
        cull_world_slot_gen(want->world, i, &on);
        if (on && want->xf && memcmp(&want->xf[i], &got->xf[i], sizeof want->xf[i]))
            fail_msg("slot %u: transform or material differs after the restore", i);
    }
    assert_int_equal(want->materials.count, got->materials.count);
    for (size_t i = 0; i < want->materials.cap; i++) {
        if (!want->materials.used[i]) continue;
        const scene_material *a = (const scene_material *)(uintptr_t)want->materials.vals[i];
        uint64_t v;
        assert_true(idmap_get(&got->materials, want->materials.keys[i], &v));
        const scene_material *b = (const scene_material *)(uintptr_t)v;
        assert_memory_equal(&a->m, &b->m, sizeof a->m);
        assert_int_equal(a->users, b->users);
    }
    assert_int_equal(want->textures.count, got->textures.count);
    assert_int_equal(want->texture_mem, got->texture_mem);
    for (size_t i = 0; i < want->textures.cap; i++) {
        if (!want->textures.used[i]) continue;
        const scene_texture *a = (const scene_texture *)(uintptr_t)want->textures.vals[i];
        uint64_t v;
        assert_true(idmap_get(&got->textures, a->id, &v));
        const scene_texture *b = (const scene_texture *)(uintptr_t)v;
        assert_true(a->format == b->format && a->flags == b->flags && a->w == b->w && a->h == b->h);
        assert_int_equal(a->levels, b->levels);
        assert_int_equal(a->users, b->users);
        assert_int_equal(a->mem, b->mem);
        assert_int_equal(a->nbytes, b->nbytes);
        assert_memory_equal(a->bytes, b->bytes, a->nbytes);
        for (uint32_t l = 0; a->mip && l < a->levels; l++) {
            uint32_t w = a->w >> l ? a->w >> l : 1, h = a->h >> l ? a->h >> l : 1;
            assert_memory_equal(a->mip[l], b->mip[l], (size_t)w * h * 4);
        }
    }
    assert_memory_equal(&want->env, &got->env, sizeof want->env);
}

/* The whole session (script_a, script_b; v1_scene: only what protocol
 * version 1 had) in dir: *want gets its scene's bytes, *out the open
 * session (sess_close, free); returns a snapshot file of it (generation
 * 5, sequence 77). */
static blob session_snapshot(const char *dir, bool v1_scene, sess **out, blob *want)
{
    sess *s = malloc(sizeof *s);
    sess_open(s, dir);
    s->v1_scene = v1_scene;
    script_a(s);
    script_b(s); /* an unload half done, a load open: both in the bitmap */
    assert_true(s->sc.nhidden > 0 && s->sc.unloading > 0);
    *want = scene_bytes(&s->sc);
    int fd = memfd_create("snapshot", MFD_CLOEXEC);
    assert_int_equal(snapshot_write(fd, &s->sc, 5, 77), 0);
    off_t end = lseek(fd, 0, SEEK_END);
    blob f = {malloc((size_t)end), (size_t)end};
    assert_int_equal(pread(fd, f.p, f.n, 0), end);
    close(fd);
    *out = s;
    return f;
}

/* Snapshot f (generation 5, sequence 77) loaded into a fresh scene. */
static scene *load_scene(const blob *f, const char *what)
{
    scene *sc = malloc(sizeof *sc);
    assert_int_equal(scene_init(sc, 64, &LIMITS), 0);
    uint64_t seq = 0;
    char err[400];
    if (snapshot_load(f->p, f->n, sc, 5, &seq, err, sizeof err)) fail_msg("%s: %s", what, err);
    assert_int_equal(seq, 77);
    return sc;
}

/* A snapshot of the whole session (every kind of state: the scene
 * model's too when this build applies its edits) restores the same scene:
 * its bytes, and what is derived from them on the way back (transforms
 * per slot, users, decoded textures with their mips). */
static void test_recover_snapshot_model_exact(void **state)
{
    (void)state;
    int lvl = g_log_level;
    g_log_level = LOG_ERROR;
    char dir[256];
    scratch_make(dir, "recover-model");
    sess *s;
    blob want, f = session_snapshot(dir, false, &s, &want);
    if (model_ready()) {
        assert_true(s->sc.textures.count >= 2 && s->sc.materials.count >= 2);
        assert_non_null(s->sc.meshes[20].uv);
        assert_non_null(s->sc.meshes[20].tan);
    } else {
        printf("recover: the scene model's edits are not in this build: left out\n");
    }
    scene *sc = load_scene(&f, "format 3");
    blob got = scene_bytes(sc);
    assert_int_equal(got.n, want.n);
    assert_memory_equal(got.p, want.p, want.n);
    assert_same_derived(&s->sc, sc);
    scene_free(sc);
    free(sc);
    sess_close(s);
    free(s);
    free(got.p);
    free(want.p);
    free(f.p);
    dir_remove(dir);
    g_log_level = lvl;
}

/* ---- format 1 and 2 snapshots --------------------------------------------------------------------- */

/* A byte cursor over a snapshot body (the layouts in snapshot.c's header,
 * read here independently of its reader). */
typedef struct cur {
    const uint8_t *p;
    size_t at;
} cur;

static uint32_t cur_u32(cur *c)
{
    uint32_t v;
    memcpy(&v, c->p + c->at, 4);
    c->at += 4;
    return v;
}

/* Appends n bytes to b (grown as needed; b->n is the length). */
static void cat(blob *b, const void *p, size_t n)
{
    b->p = realloc(b->p, b->n + n + 1);
    memcpy(b->p + b->n, p, n);
    b->n += n;
}

static void cat_u32(blob *b, uint32_t v)
{
    cat(b, &v, 4);
}

/* Seals a body as a whole snapshot of the given magic (hdr: the 40-byte
 * header to take the generation and sequence number from). */
static blob sealed(const uint8_t *hdr, const char *magic, const blob *body)
{
    blob f = {malloc(40 + body->n), 40 + body->n};
    memcpy(f.p, hdr, 40);
    memcpy(f.p, magic, 8);
    uint64_t bl = body->n;
    memcpy(f.p + 24, &bl, 8);
    memcpy(f.p + 40, body->p, body->n);
    uint32_t bc = (uint32_t)crc32(crc32(0L, Z_NULL, 0), body->p, (uInt)body->n);
    memcpy(f.p + 32, &bc, 4);
    uint32_t hc = (uint32_t)crc32(crc32(0L, Z_NULL, 0), f.p, 36);
    memcpy(f.p + 36, &hc, 4);
    return f;
}

/* Rewrites a format 3 snapshot of a version 1 scene (no textures,
 * materials, environment, transforms, UVs, local spheres, occluder flags)
 * as format 2 wrote it: meshes in their old layout, entities in 104-byte
 * records (id..flags, a zero word, sphere, aabb: the 160-byte record's
 * bytes 0..20 and 80..160). */
static blob snapshot_v2(const blob *v3)
{
    cur c = {v3->p + 40, 24};
    uint32_t nsl = cur_u32(&c);
    for (uint32_t i = 0; i < nsl; i++) {
        c.at += 1 + c.p[c.at];      /* name */
        c.at += 1 + 4 + 2 + 2 + 4; /* state, owner, class base, classes, capacity */
        c.at += 8 * (size_t)cur_u32(&c);     /* members */
        uint32_t nd = cur_u32(&c);
        c.at += 4 + (size_t)nd * 8; /* doomed done, ids */
    }
    c.at += 12 * (size_t)cur_u32(&c) + 8; /* hidden words, hidden count, unloading */
    c.at += 4 * (size_t)cur_u32(&c);      /* class owners */
    blob b = {0};
    cat(&b, c.p, c.at); /* the same in both */
    assert_int_equal(cur_u32(&c), 0); /* textures */
    assert_int_equal(cur_u32(&c), 0); /* materials */
    c.at += VP_ENV_SIZE;
    uint32_t nm = cur_u32(&c);
    cat_u32(&b, nm);
    for (uint32_t i = 0; i < nm; i++) { /* MESH_PUT payloads to the old layout */
        uint32_t len = cur_u32(&c);
        uint16_t cls, flags;
        uint32_t nv, ni;
        memcpy(&cls, c.p + c.at, 2);
        memcpy(&flags, c.p + c.at + 2, 2);
        memcpy(&nv, c.p + c.at + 4, 4);
        memcpy(&ni, c.p + c.at + 8, 4);
        assert_int_equal(flags & ~VP_MESH_NO_NORMALS, 0);
        uint8_t has = !(flags & VP_MESH_NO_NORMALS);
        const uint8_t *arr = c.p + c.at + 12;
        cat(&b, &cls, 2);
        cat(&b, &nv, 4);
        cat(&b, &ni, 4);
        cat(&b, arr, (size_t)nv * 12);
        cat(&b, &has, 1);
        cat(&b, arr + (size_t)nv * 12, (size_t)nv * 12 * has + (size_t)ni * 4);
        c.at += len;
    }
    uint32_t nslots = cur_u32(&c);
    size_t from = c.at - 4;
    c.at += (size_t)nslots * 2;
    c.at += 4 * (size_t)cur_u32(&c); /* free list */
    uint32_t live = cur_u32(&c);
    cat(&b, c.p + from, c.at - from); /* the handle table, the entity count */
    for (uint32_t done = 0; done < live;) { /* ENTITY_ADD payloads of 104-byte records */
        c.at += 4;
        uint32_t n = cur_u32(&c);
        cat_u32(&b, 4 + n * 104);
        cat_u32(&b, n);
        for (uint32_t k = 0; k < n; k++, c.at += 160) {
            static const uint8_t zero[4] = {0};
            cat(&b, c.p + c.at, 20);
            cat(&b, zero, 4);
            cat(&b, c.p + c.at + 80, 80);
        }
        cat(&b, c.p + c.at, (size_t)n * 4); /* handles */
        c.at += (size_t)n * 4;
        done += n;
    }
    uint32_t nd = cur_u32(&c);
    cat_u32(&b, nd);
    for (uint32_t i = 0; i < nd; i++) { /* volumes: without the local-spheres byte */
        size_t start = c.at;
        uint32_t n[3];
        memcpy(n, c.p + c.at + 56, 12);
        c.at += 8 + 48 + 12 + 8;
        uint32_t nsph = cur_u32(&c);
        c.at += (size_t)nsph * 32 + (size_t)n[0] * n[1] * n[2] * 16;
        cat(&b, c.p + start, c.at - start);
        assert_int_equal(c.p[c.at++], 0);
    }
    uint32_t no = cur_u32(&c);
    cat_u32(&b, no);
    for (uint32_t i = 0; i < no; i++) { /* occluders: without flags */
        cat(&b, c.p + c.at, 10);
        c.at += 10;
        assert_int_equal(cur_u32(&c), 0);
        uint32_t nt;
        memcpy(&nt, c.p + c.at + 24, 4);
        cat(&b, c.p + c.at, 28 + (size_t)nt * 36);
        c.at += 28 + (size_t)nt * 36;
    }
    cat(&b, c.p + c.at, v3->n - 40 - c.at); /* lights */
    blob f = sealed(v3->p, "VNTSNAP2", &b);
    free(b.p);
    return f;
}

/* Rewrites a format 2 snapshot as format 1 wrote it (the hidden bitmap and
 * the class owners whole), from the layout in snapshot.c's header. */
static blob snapshot_v1(const blob *v2)
{
    const uint8_t *p = v2->p + 40;
    size_t at = 24;
    uint32_t nsl;
    memcpy(&nsl, p + at, 4);
    at += 4;
    for (uint32_t i = 0; i < nsl; i++) {
        uint32_t n;
        at += 1 + p[at];      /* name */
        at += 1 + 4 + 2 + 2 + 4; /* state, owner, class base, classes, capacity */
        memcpy(&n, p + at, 4);
        at += 4 + (size_t)n * 8; /* members */
        memcpy(&n, p + at, 4);
        at += 8 + (size_t)n * 8; /* doomed, doomed done, ids */
    }
    size_t sl_end = at; /* format 1 and 2 differ from here to the meshes */
    uint64_t hidden[CULL_SUBLEVEL_WORDS] = {0};
    uint16_t *owner = calloc(65536, 2);
    uint32_t n, nhidden, unloading;
    memcpy(&n, p + at, 4);
    at += 4;
    for (uint32_t i = 0; i < n; i++, at += 12) {
        uint32_t w;
        memcpy(&w, p + at, 4);
        memcpy(&hidden[w], p + at + 4, 8);
    }
    memcpy(&nhidden, p + at, 4);
    memcpy(&unloading, p + at + 4, 4);
    memcpy(&n, p + at + 8, 4);
    at += 12;
    for (uint32_t i = 0; i < n; i++, at += 4) {
        uint16_t c;
        memcpy(&c, p + at, 2);
        memcpy(&owner[c], p + at + 2, 2);
    }
    size_t rest = v2->n - 40 - at;
    size_t body = sl_end + sizeof hidden + 8 + 65536 * 2 + rest;
    blob b = {malloc(40 + body), 40 + body};
    uint8_t *q = b.p + 40;
    memcpy(q, p, sl_end);
    memcpy(q + sl_end, hidden, sizeof hidden);
    memcpy(q + sl_end + sizeof hidden, &nhidden, 4);
    memcpy(q + sl_end + sizeof hidden + 4, &unloading, 4);
    memcpy(q + sl_end + sizeof hidden + 8, owner, 65536 * 2);
    memcpy(q + sl_end + sizeof hidden + 8 + 65536 * 2, p + at, rest);
    free(owner);
    memcpy(b.p, v2->p, 40);
    memcpy(b.p, "VNTSNAP1", 8);
    uint64_t bl = body;
    memcpy(b.p + 24, &bl, 8);
    uint32_t bc = (uint32_t)crc32(crc32(0L, Z_NULL, 0), q, (uInt)body);
    memcpy(b.p + 32, &bc, 4);
    uint32_t hc = (uint32_t)crc32(crc32(0L, Z_NULL, 0), b.p, 36);
    memcpy(b.p + 36, &hc, 4);
    return b;
}

/* Loads snapshot f (generation 5, sequence 77) into a fresh scene: its bytes. */
static blob load_as_scene(const blob *f, const char *what)
{
    scene *sc = load_scene(f, what);
    blob got = scene_bytes(sc);
    scene_free(sc);
    free(sc);
    return got;
}

/* Format 1 and format 2 snapshots (what protocol version 1's daemons
 * wrote) are still read, into the same scene: the session's snapshot,
 * with sub-levels, classes reserved, hidden (loading) and unloading
 * sub-levels, meshes, entities, a destruction, occluders and lights,
 * rewritten as format 2 wrote it (entities in 104-byte records), and that
 * as format 1 wrote it. */
static void test_recover_snapshot_format1(void **state)
{
    (void)state;
    int lvl = g_log_level;
    g_log_level = LOG_ERROR;
    char dir[256];
    scratch_make(dir, "recover-v1");
    sess *s;
    blob want, v3 = session_snapshot(dir, true, &s, &want);
    sess_close(s);
    free(s);
    assert_memory_equal(v3.p, "VNTSNAP3", 8);
    blob v2 = snapshot_v2(&v3);
    blob v1 = snapshot_v1(&v2);
    assert_true(v2.n < v3.n && v1.n > v2.n + 130000);
    const blob *old[2] = {&v2, &v1};
    for (int k = 0; k < 2; k++) {
        blob got = load_as_scene(old[k], k ? "format 1" : "format 2");
        assert_int_equal(got.n, want.n);
        assert_memory_equal(got.p, want.p, want.n);
        free(got.p);
    }
    free(want.p);
    free(v1.p);
    free(v2.p);
    free(v3.p);
    dir_remove(dir);
    g_log_level = lvl;
}

/* ---- every bit, every truncation -------------------------------------------------------------- */

typedef struct damage_run {
    char src[256], dir[256];    /* the undamaged data dir; the one each trial recovers */
    blob snap, jr;              /* its files (snap.n == 0: none) */
    char snap_name[32], jr_name[32];
    size_t *rec;                /* record k at rec[k], rec[nrec] = jr.n */
    uint32_t nrec;
    blob *want;                 /* the scene after records 0..k-1, and the open load dropped */
    uint64_t trials, cut, refused;
    uint64_t gen;               /* of the snapshot */
} damage_run;

/* Writes the trial's files: the snapshot, then the journal (p, n). */
static void trial_files(damage_run *d, const uint8_t *sp, size_t sn, const uint8_t *jp, size_t jn)
{
    dir_unlink_files(d->dir);
    if (d->snap.n) spit(d->dir, d->snap_name, sp, sn);
    spit(d->dir, d->jr_name, jp, jn);
}

/* Recovery of the trial dir must give want[k] having cut exactly `cut`
 * bytes (k < 0: it must refuse, naming file and "offset off"). */
static void trial_check(damage_run *d, long k, size_t cut, const char *file, size_t off, const char *what,
                        size_t where)
{
    char err[1000] = "";
    blob got = {0};
    journal_report rep;
    int rc = recover(d->dir, &got, &rep, err, sizeof err);
    d->trials++;
    if (k < 0) {
        char o[64];
        snprintf(o, sizeof o, "offset %zu", off);
        if (!rc) fail_msg("%s at byte %zu of %s: recovered (%llu records, %llu cut) where it must refuse", what,
                          where, file, (unsigned long long)rep.records, (unsigned long long)rep.cut_bytes);
        if (!strstr(err, file) || !strstr(err, o))
            fail_msg("%s at byte %zu of %s: refused, but not naming %s and %s: %s", what, where, file, file, o, err);
        d->refused++;
        return;
    }
    if (rc) fail_msg("%s at byte %zu of %s: refused where a torn end is cut: %s", what, where, file, err);
    if (rep.cut_bytes != cut)
        fail_msg("%s at byte %zu of %s: %llu bytes cut, want %zu", what, where, file,
                 (unsigned long long)rep.cut_bytes, cut);
    const blob *w = &d->want[k];
    if (got.n != w->n || memcmp(got.p, w->p, w->n))
        fail_msg("%s at byte %zu of %s: the scene is not the one after record %ld", what, where, file, k);
    d->cut += cut != 0;
    free(got.p);
}

/* The record of journal byte b (-1: the header). */
static long record_of(const damage_run *d, size_t b)
{
    if (b < d->rec[0]) return -1;
    long lo = 0, hi = (long)d->nrec - 1;
    while (lo < hi) {
        long mid = (lo + hi + 1) / 2;
        if (d->rec[mid] <= b) lo = mid;
        else hi = mid - 1;
    }
    return lo;
}

static void damage_all(damage_run *d, uint32_t stride)
{
    /* the journal's records, from its format: u32 length, 20 more header
       bytes, the payload (journal.c) */
    d->rec = malloc((d->jr.n / 24 + 2) * sizeof *d->rec);
    size_t off = 32;
    d->nrec = 0;
    while (off < d->jr.n) {
        d->rec[d->nrec++] = off;
        uint32_t len = (uint32_t)d->jr.p[off] | (uint32_t)d->jr.p[off + 1] << 8 | (uint32_t)d->jr.p[off + 2] << 16 |
                       (uint32_t)d->jr.p[off + 3] << 24;
        off += 24 + len;
    }
    assert_int_equal(off, d->jr.n);
    d->rec[d->nrec] = d->jr.n;
    assert_true(d->nrec >= 10);
    /* the model: the undamaged files cut at each record boundary */
    d->want = calloc(d->nrec + 1, sizeof *d->want);
    for (uint32_t k = 0; k <= d->nrec; k++) {
        trial_files(d, d->snap.p, d->snap.n, d->jr.p, d->rec[k]);
        char err[1000];
        if (recover(d->dir, &d->want[k], NULL, err, sizeof err)) fail_msg("undamaged, %u records: %s", k, err);
    }
    /* (a record inside a load left open changes nothing: recovery drops
       the load; every other one changes the scene) */
    uint32_t distinct = 0;
    for (uint32_t k = 1; k <= d->nrec; k++)
        distinct += d->want[k].n != d->want[k - 1].n || memcmp(d->want[k].p, d->want[k - 1].p, d->want[k].n);
    assert_true(distinct >= d->nrec / 2);
    /* every bit of the journal */
    uint8_t *j = malloc(d->jr.n);
    memcpy(j, d->jr.p, d->jr.n);
    for (size_t b = 0; b < d->jr.n; b += stride) {
        long k = record_of(d, b);
        for (int bit = 0; bit < 8; bit++) {
            j[b] ^= (uint8_t)(1u << bit);
            trial_files(d, d->snap.p, d->snap.n, j, d->jr.n);
            if (k < 0) trial_check(d, -1, 0, d->jr_name, 0, "a flipped bit", b);
            else if ((uint32_t)k + 1 == d->nrec) trial_check(d, k, d->jr.n - d->rec[k], d->jr_name, 0, "a flipped bit", b);
            else trial_check(d, -1, 0, d->jr_name, d->rec[k], "a flipped bit", b);
            j[b] ^= (uint8_t)(1u << bit);
        }
    }
    /* every truncation of the journal */
    for (size_t len = 0; len < d->jr.n; len += stride) {
        trial_files(d, d->snap.p, d->snap.n, d->jr.p, len);
        long k = record_of(d, len);
        /* inside the header: the file's creation cut short (no record in
           it), as an older daemon killed there left it: written anew */
        if (k < 0 && len < d->rec[0]) trial_check(d, 0, len, d->jr_name, 0, "a truncation", len);
        else if (k < 0) trial_check(d, -1, 0, d->jr_name, 0, "a truncation", len);
        else trial_check(d, k, len - d->rec[k], d->jr_name, 0, "a truncation", len);
    }
    free(j);
    if (!d->snap.n) return;
    /* every bit and truncation of the snapshot: it has no torn end (it is
       renamed into place once whole and synced), so each must be refused.
       snapshot_load in memory for each; through journal_open (the file
       and offset named) for every 97th */
    scene *sc = malloc(sizeof *sc);
    assert_non_null(sc);
    assert_int_equal(scene_init(sc, 64, &LIMITS), 0);
    uint8_t *sp = malloc(d->snap.n);
    memcpy(sp, d->snap.p, d->snap.n);
    char err[1000];
    uint64_t seq, n = 0;
    for (size_t b = 0; b < d->snap.n; b += stride) {
        for (int bit = 0; bit < 8; bit++, n++) {
            sp[b] ^= (uint8_t)(1u << bit);
            if (!snapshot_load(sp, d->snap.n, sc, d->gen, &seq, err, sizeof err))
                fail_msg("a flipped bit at byte %zu of the snapshot was loaded", b);
            d->trials++;
            d->refused++;
            if (n % 97 == 0) {
                trial_files(d, sp, d->snap.n, d->jr.p, d->jr.n);
                trial_check(d, -1, 0, d->snap_name, b < 40 ? 0 : 40, "a flipped bit", b);
            }
            sp[b] ^= (uint8_t)(1u << bit);
        }
    }
    for (size_t len = 0; len < d->snap.n; len += stride) {
        if (!snapshot_load(sp, len, sc, d->gen, &seq, err, sizeof err))
            fail_msg("the snapshot cut to %zu bytes was loaded", len);
        d->trials++;
        d->refused++;
        if (len % 97 == 0) {
            trial_files(d, sp, len, d->jr.p, d->jr.n);
            trial_check(d, -1, 0, d->snap_name, len < 40 ? 0 : len, "a truncation", len);
        }
    }
    free(sp);
    scene_free(sc);
    free(sc);
}

static void damage_free(damage_run *d)
{
    for (uint32_t k = 0; d->want && k <= d->nrec; k++) free(d->want[k].p);
    free(d->want);
    free(d->rec);
    free(d->snap.p);
    free(d->jr.p);
    dir_remove(d->dir);
    dir_remove(d->src);
}

/* Every bit of every file of a small data dir flipped, one at a time, and
 * every truncation: recovery gives exactly the scene before the damaged
 * record, with only a torn end cut (damage in the last record, or a
 * truncation), or refuses, naming the file and the offset (damage in the
 * header or in a record an intact one follows; any damage to the
 * snapshot). Nothing is ever silently dropped from before an intact
 * record, nothing crashes. The dir: a snapshot taken half-way through the
 * session (every kind of state in it) and the journal after it (every
 * kind of edit but the demo city). 0.3-0.6 ms a damaged copy here. */
/* Which bytes a campaign damages: every one with VANTAGE_TEST_EXHAUSTIVE
 * (make test-full; 60-85 s here); else every 3rd in release (make test:
 * 3 is prime to 2, 4 and 8, so every field's every byte position still
 * comes up across the records), every 8th under the sanitizers (file calls
 * there cost 5-10x); a scale below 1 (make test's scalar and ASan runs)
 * every 5th or 16th. */
static uint32_t damage_stride(void)
{
    const char *x = getenv("VANTAGE_TEST_EXHAUSTIVE");
    bool all = x && *x && strcmp(x, "0");
#ifdef UNDER_ASAN
    return all ? 1 : test_scale() >= 1 ? 8 : 16;
#else
    return all ? 1 : test_scale() >= 1 ? 3 : 5;
#endif
}

static void test_recover_every_bit(void **state)
{
    (void)state;
    int lvl = g_log_level;
    g_log_level = -1; /* tens of thousands of recoveries: their logs are noise */
    uint32_t stride = damage_stride();
    damage_run d = {0};
    scratch_make(d.src, "recover-src");
    scratch_make(d.dir, "recover-try");
    sess *s = malloc(sizeof *s); /* a scene is 2.6 MB: not on the stack */
    sess_open(s, d.src);
    script_a(s);
    assert_int_equal(journal_snapshot(s->j, &s->sc), 0);
    script_b(s);
    sess_close(s);
    free(s);
    snprintf(d.jr_name, sizeof d.jr_name, "journal.000002");
    snprintf(d.snap_name, sizeof d.snap_name, "snapshot.000002");
    d.gen = 2;
    d.jr = slurp(d.src, d.jr_name);
    d.snap = slurp(d.src, d.snap_name);
    struct timespec t0, t1;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    damage_all(&d, stride);
    clock_gettime(CLOCK_MONOTONIC, &t1);
    printf("recover: journal %zu bytes (%u records), snapshot %zu bytes: %llu damaged copies (every bit of 1 byte "
           "in %u), "
           "%llu torn ends cut exactly, %llu refused naming file and offset, none lost or crashed, %.1f s\n",
           d.jr.n, d.nrec, d.snap.n, (unsigned long long)d.trials, stride,
           (unsigned long long)d.cut, (unsigned long long)d.refused,
           (t1.tv_sec - t0.tv_sec) + (t1.tv_nsec - t0.tv_nsec) / 1e9);
    damage_free(&d);
    g_log_level = lvl;
}

/* The same campaign over protocol version 1's directory (tests/data/
 * upgrade_v1: a format 2 snapshot, a format 1 journal of version 1's
 * records): every damaged copy recovers exactly the scene before the
 * damage (only a torn end cut), upgraded, or is refused naming the file
 * and the offset. */
static void test_recover_every_bit_v1(void **state)
{
    (void)state;
    int lvl = g_log_level;
    g_log_level = -1;
    uint32_t stride = damage_stride();
    damage_run d = {0};
    scratch_make(d.src, "recover-v1src");
    scratch_make(d.dir, "recover-v1try");
    const char *dd = getenv("VANTAGE_DATA_DIR");
    char fx[512];
    snprintf(fx, sizeof fx, "%s/upgrade_v1", dd ? dd : "tests/data");
    DIR *dir = opendir(fx);
    if (!dir) fail_msg("%s: %s", fx, strerror(errno));
    struct dirent *e;
    while ((e = readdir(dir))) {
        unsigned long long g;
        if (sscanf(e->d_name, "journal.%llu", &g) == 1) snprintf(d.jr_name, sizeof d.jr_name, "%.24s", e->d_name);
        if (sscanf(e->d_name, "snapshot.%llu", &g) == 1) {
            snprintf(d.snap_name, sizeof d.snap_name, "%.24s", e->d_name);
            d.gen = g;
        }
    }
    closedir(dir);
    d.jr = slurp(fx, d.jr_name);
    d.snap = slurp(fx, d.snap_name);
    assert_memory_equal(d.jr.p, "VNTJRNL1", 8);
    assert_memory_equal(d.snap.p, "VNTSNAP2", 8);
    damage_all(&d, stride);
    printf("recover, version 1's directory: journal %zu bytes (%u records), snapshot %zu bytes: %llu damaged copies "
           "(every bit of 1 byte in %u), "
           "%llu torn ends cut exactly, %llu refused naming file and offset\n",
           d.jr.n, d.nrec, d.snap.n, (unsigned long long)d.trials, stride,
           (unsigned long long)d.cut, (unsigned long long)d.refused);
    damage_free(&d);
    g_log_level = lvl;
}

const struct CMUnitTest recover_tests[] = {
    cmocka_unit_test(test_recover_snapshot_sublevel_name),
    cmocka_unit_test(test_recover_snapshot_model_exact),
    cmocka_unit_test(test_recover_snapshot_format1),
    cmocka_unit_test(test_recover_every_bit),
    cmocka_unit_test(test_recover_every_bit_v1),
};
const size_t recover_tests_count = sizeof recover_tests / sizeof recover_tests[0];
