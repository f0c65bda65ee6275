/*
 * test_material.c — materials (MATERIAL_PUT / MATERIAL_REMOVE): in-process
 * through edit_decode / edit_apply (the path both a request and a journal
 * record take), the reference counts against a plain model (users of each
 * material = entities naming it; users of each texture = slots naming it),
 * the limit, all-or-nothing batches; over the wire, the messages and each
 * bad input's code, record and field.
 */
#include "test_util.h"

#include "edit.h"
#include "test_daemon.h"
#include "vantage.h"
#include "vt_image.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static vp_material mat(uint32_t id)
{
    vp_material m = {.id = id, .base_color = {0.5f, 0.5f, 0.5f, 1}, .roughness = 0.5f, .normal_scale = 1};
    for (int k = 0; k < VP_TEX_SLOTS; k++) m.tex[k].scale[0] = m.tex[k].scale[1] = 1;
    return m;
}

/* Encodes (enc fills w) and applies one edit of type to s, as a journal
 * replay would: the code, and err. */
typedef struct one_edit {
    uint16_t type;
    const vp_material *m;
    const vp_entity *e;
    const uint64_t *ids;
    uint32_t n;
} one_edit;

static int apply(scene *s, one_edit x, scene_err *err)
{
    size_t cap = 65536;
    uint8_t *buf = malloc(cap);
    vp_writer w;
    vp_writer_init(&w, buf, cap);
    if (x.type == VP_MATERIAL_PUT) vp_enc_materials(&w, 1, x.m, x.n);
    else if (x.type == VP_MATERIAL_REMOVE || x.type == VP_ENTITY_REMOVE) vp_enc_ids(&w, x.type, 1, x.ids, x.n);
    else vp_enc_entities(&w, x.type, 1, x.e, x.n);
    assert_false(w.overflow);
    edit e;
    int rc = edit_decode(x.type, buf + VP_HEADER_SIZE, (uint32_t)(w.len - VP_HEADER_SIZE), 0, EDIT_LAYOUT, &e);
    if (rc) {
        edit_explain(&e, rc, err);
    } else {
        edit_result r;
        rc = edit_apply(s, &e, &r, err);
        if (!rc) edit_result_free(&r);
    }
    free(buf);
    return rc;
}

static void add_texture(scene *s, uint32_t id)
{
    scene_texture *t = calloc(1, sizeof *t);
    t->id = id;
    assert_true(idmap_reserve(&s->textures, s->textures.count + 1));
    idmap_put(&s->textures, id, (uint64_t)(uintptr_t)t);
}

static void drop_textures(scene *s)
{
    for (uint32_t id = 1; id <= 10; id++) {
        scene_texture *t = scene_texture_find(s, id);
        if (!t) continue;
        idmap_del(&s->textures, id);
        free(t);
    }
}

/* The model's users of texture id: slots of live materials naming it. */
static uint32_t model_tex_users(const vp_material *live, const bool *alive, int n, uint32_t id)
{
    uint32_t u = 0;
    for (int i = 0; i < n; i++)
        for (int k = 0; alive[i] && k < VP_TEX_SLOTS; k++) u += live[i].tex[k].texture == id;
    return u;
}

static void test_material_refs_against_model(void **state)
{
    (void)state;
    scene *s = calloc(1, sizeof *s);
    scene_limits lim = {.max_entities = 1000, .max_lights = 10, .max_occluders = 10, .max_occluder_tris = 100,
                        .max_mesh_verts = 100, .max_materials = 6};
    assert_int_equal(scene_init(s, 64, &lim), 0);
    for (uint32_t t = 1; t <= 4; t++) add_texture(s, t);
    rng r = {test_seed() ^ 0x3A7u};
    enum { NM = 6, NE = 20 };
    vp_material live[NM + 1];
    bool alive[NM + 1] = {0};
    uint32_t ent_mat[NE] = {0}; /* model: each entity's material (0 = none / gone) */
    bool ent_alive[NE] = {0};
    scene_err err;
    for (int step = 0; step < 400; step++) {
        int op = (int)rng_below(&r, 4);
        if (op == 0) { /* put 1..3 materials, some textured */
            vp_material b[3];
            uint32_t n = 1 + rng_below(&r, 3);
            for (uint32_t i = 0; i < n; i++) {
                b[i] = mat(1 + (i + rng_below(&r, NM)) % NM);
                for (int k = 0; k < VP_TEX_SLOTS; k++) b[i].tex[k].texture = rng_below(&r, 3) ? 0 : rng_below(&r, 5);
            }
            bool dup = n > 1 && (b[0].id == b[1].id || (n > 2 && (b[2].id == b[0].id || b[2].id == b[1].id)));
            int rc = apply(s, (one_edit){VP_MATERIAL_PUT, b, NULL, NULL, n}, &err);
            assert_int_equal(rc, dup ? VP_ERR_DUPLICATE : VP_OK);
            for (uint32_t i = 0; !dup && i < n; i++) live[b[i].id] = b[i], alive[b[i].id] = true;
        } else if (op == 1) { /* remove a material: refused while used */
            uint64_t id = 1 + rng_below(&r, NM);
            uint32_t users = 0;
            for (int e = 0; e < NE; e++) users += ent_alive[e] && ent_mat[e] == id;
            int rc = apply(s, (one_edit){VP_MATERIAL_REMOVE, NULL, NULL, &id, 1}, &err);
            int want = !alive[id] ? VP_ERR_UNKNOWN_ID : users ? VP_ERR_STATE : VP_OK;
            assert_int_equal(rc, want);
            if (!rc) alive[id] = false;
        } else if (op == 2) { /* add or update an entity with a material */
            int e = (int)rng_below(&r, NE);
            uint32_t m = rng_below(&r, NM + 1);
            vp_entity rec = {.id = 100 + (uint64_t)e, .aabb = {0, 0, 0, 1, 1, 1}, .material = m};
            int rc = apply(s, (one_edit){ent_alive[e] ? VP_ENTITY_UPDATE : VP_ENTITY_ADD, NULL, &rec, NULL, 1}, &err);
            assert_int_equal(rc, m && !alive[m] ? VP_ERR_UNKNOWN_ID : VP_OK);
            if (!rc) ent_alive[e] = true, ent_mat[e] = m;
        } else { /* remove an entity */
            int e = (int)rng_below(&r, NE);
            if (!ent_alive[e]) continue;
            uint64_t id = 100 + (uint64_t)e;
            assert_int_equal(apply(s, (one_edit){VP_ENTITY_REMOVE, NULL, NULL, &id, 1}, &err), VP_OK);
            ent_alive[e] = false;
        }
        /* the counts against the model */
        for (uint32_t id = 1; id <= NM; id++) {
            scene_material *m = scene_material_find(s, id);
            assert_int_equal(m != NULL, alive[id]);
            if (!m) continue;
            uint32_t users = 0;
            for (int e = 0; e < NE; e++) users += ent_alive[e] && ent_mat[e] == id;
            assert_int_equal(m->users, users);
            assert_memory_equal(&m->m, &live[id], sizeof m->m);
        }
        for (uint32_t t = 1; t <= 4; t++) assert_int_equal(scene_texture_find(s, t)->users, model_tex_users(live, alive, NM + 1, t));
    }
    drop_textures(s);
    scene_free(s);
    free(s);
}

static void test_material_limit_and_batches(void **state)
{
    (void)state;
    scene *s = calloc(1, sizeof *s);
    scene_limits lim = {.max_entities = 100, .max_mesh_verts = 100, .max_materials = 3};
    assert_int_equal(scene_init(s, 64, &lim), 0);
    add_texture(s, 1);
    scene_err err;
    vp_material b[4] = {mat(1), mat(2), mat(3), mat(4)};
    /* the limit: a batch that would pass it is refused whole */
    assert_int_equal(apply(s, (one_edit){VP_MATERIAL_PUT, b, NULL, NULL, 4}, &err), VP_ERR_LIMIT);
    assert_non_null(strstr(err.msg, "limit 3"));
    assert_int_equal(s->materials.count, 0);
    assert_int_equal(apply(s, (one_edit){VP_MATERIAL_PUT, b, NULL, NULL, 3}, &err), VP_OK);
    assert_int_equal(apply(s, (one_edit){VP_MATERIAL_PUT, &b[3], NULL, NULL, 1}, &err), VP_ERR_LIMIT);
    /* replacing is no new material */
    b[0].roughness = 0.9f;
    b[0].tex[VP_TEX_BASE].texture = 1;
    assert_int_equal(apply(s, (one_edit){VP_MATERIAL_PUT, b, NULL, NULL, 3}, &err), VP_OK);
    assert_true(scene_material_find(s, 1)->m.roughness == 0.9f);
    assert_int_equal(scene_texture_find(s, 1)->users, 1);
    /* a missing texture in the middle of a batch: nothing applied */
    vp_material c[3] = {mat(1), mat(2), mat(3)};
    c[1].tex[VP_TEX_NORMAL].texture = 9;
    assert_int_equal(apply(s, (one_edit){VP_MATERIAL_PUT, c, NULL, NULL, 3}, &err), VP_ERR_UNKNOWN_ID);
    assert_int_equal(err.index, 1);
    assert_non_null(strstr(err.msg, "record 1"));
    assert_non_null(strstr(err.msg, "normal texture 9"));
    assert_true(scene_material_find(s, 1)->m.roughness == 0.9f);
    assert_int_equal(scene_texture_find(s, 1)->users, 1);
    /* a removal batch with one in use: nothing removed */
    vp_entity e = {.id = 5, .aabb = {0, 0, 0, 1, 1, 1}, .material = 3};
    assert_int_equal(apply(s, (one_edit){VP_ENTITY_ADD, NULL, &e, NULL, 1}, &err), VP_OK);
    uint64_t rm[3] = {1, 3, 2};
    assert_int_equal(apply(s, (one_edit){VP_MATERIAL_REMOVE, NULL, NULL, rm, 3}, &err), VP_ERR_STATE);
    assert_int_equal(err.index, 1);
    assert_non_null(strstr(err.msg, "material 3 is used by 1"));
    assert_int_equal(s->materials.count, 3);
    uint64_t rm2[2] = {1, 1};
    assert_int_equal(apply(s, (one_edit){VP_MATERIAL_REMOVE, NULL, NULL, rm2, 2}, &err), VP_ERR_DUPLICATE);
    assert_int_equal(err.index, 1);
    assert_int_equal(apply(s, (one_edit){VP_MATERIAL_REMOVE, NULL, NULL, rm2, 1}, &err), VP_OK);
    assert_int_equal(scene_texture_find(s, 1)->users, 0);
    drop_textures(s);
    scene_free(s);
    free(s);
}

/* Over the wire: a bad MATERIAL_PUT / MATERIAL_REMOVE in the middle of a
 * batch, the code, record and field. */
typedef struct mat_row {
    const char *name;
    int what;          /* 0 put [ok, m, ok]; 1 remove [1, id, 2] */
    vp_material m;
    uint64_t id;
    int code;
    uint32_t index;
    const char *field;
} mat_row;

/* a material record: id, roughness, base colour g, emissive strength */
#define MAT(id_, rough, g, es) \
    .id = id_, .base_color = {1, g, 1, 1}, .roughness = rough, .emissive_strength = es, .normal_scale = 1
static const mat_row mat_rows[] = {
    {"id 0", 0, {MAT(0, 1, 1, 0)}, 0, VP_ERR_INVALID, 1, "default material"},
    {"roughness 2", 0, {MAT(8, 2, 1, 0)}, 0, VP_ERR_INVALID, 1, "roughness"},
    {"base colour NaN", 0, {MAT(8, 1, NAN, 0)}, 0, VP_ERR_NONFINITE, 1, "base colour g"},
    {"emissive strength negative", 0, {MAT(8, 1, 1, -1)}, 0, VP_ERR_INVALID, 1, "emissive strength"},
    {"missing base texture", 0, {MAT(8, 1, 1, 0), .tex = {[VP_TEX_BASE] = {.texture = 77}}}, 0, VP_ERR_UNKNOWN_ID, 1,
     "base colour texture 77"},
    {"missing emissive texture", 0, {MAT(8, 1, 1, 0), .tex = {[VP_TEX_EMISSIVE] = {.texture = 5}}}, 0,
     VP_ERR_UNKNOWN_ID, 1, "emissive texture 5"},
    {"same id twice", 0, {MAT(1, 1, 1, 0)}, 0, VP_ERR_DUPLICATE, 1, "twice"},
    {"remove unknown", 1, {0}, 99, VP_ERR_UNKNOWN_ID, 1, "no material 99"},
    {"remove in use", 1, {0}, 3, VP_ERR_STATE, 1, "used by 1"},
};

static void test_material_bad_input(void **state)
{
    const mat_row *row = *state;
    daemon_proc d;
    vtc_client *c = daemon_open(&d, VP_ROLE_EDITOR);
    vp_material ok[3] = {mat(1), mat(2), mat(3)};
    assert_int_equal(vtc_material_put(c, ok, 3, NULL), VP_OK);
    const char *text;
    size_t tlen;
    assert_int_equal(vtc_metrics(c, &text, &tlen), VP_OK);
    assert_non_null(memmem(text, tlen, "\nvantage_scene_materials 3\n", 27));
    vp_entity e = {.id = 5, .aabb = {0, 0, 0, 1, 1, 1}, .material = 3};
    assert_int_equal(vtc_add(c, &e, 1, NULL, NULL), VP_OK);
    vp_list_reply lr;
    vp_entity g;
    assert_int_equal(vtc_get(c, &e.id, 1, &lr), VP_OK);
    assert_int_equal(vp_entity_get(&lr.batch, 0, &g), VP_OK);
    assert_int_equal(g.material, 3);
    vp_stats_reply st0, st1;
    assert_int_equal(vtc_stats(c, &st0), VP_OK);
    int rc;
    if (row->what == 0) {
        vp_material b[3] = {mat(1), row->m, mat(2)};
        rc = vtc_material_put(c, b, 3, NULL);
    } else {
        uint64_t ids[3] = {1, row->id, 2};
        rc = vtc_material_remove(c, ids, 3, NULL);
    }
    const vtc_error *er = vtc_last_error(c);
    fprintf(stderr, "%s: %d record %d: %s\n", row->name, rc, (int)er->index, er->msg);
    assert_int_equal(rc, row->code);
    assert_int_equal(er->index, row->index);
    assert_non_null(strstr(er->msg, row->field));
    assert_non_null(strstr(er->msg, "record 1"));
    assert_int_equal(vtc_stats(c, &st1), VP_OK);
    assert_int_equal(st1.epoch, st0.epoch);
    /* all there still: removing 1 and 2 (unused) works */
    uint64_t ids[2] = {1, 2};
    assert_int_equal(vtc_material_remove(c, ids, 2, NULL), VP_OK);
    assert_int_equal(vtc_material_remove(c, ids, 1, NULL), VP_ERR_UNKNOWN_ID);
    daemon_close(&d, c);
}

/* A real texture over the wire: a material naming it keeps it (TEXTURE_REMOVE
 * refused with STATE), a replaced material lets it go. */
static void test_material_keeps_texture(void **state)
{
    daemon_proc *d = *state;
    vtc_client *c = connect_role(d, VP_ROLE_EDITOR, false);
    uint8_t px[4 * 4 * 4];
    for (size_t i = 0; i < sizeof px; i++) px[i] = (uint8_t)(i * 37);
    char path[] = "/tmp/vantage-mat-XXXXXX";
    int fd = mkstemp(path);
    assert_true(fd >= 0);
    close(fd);
    char why[200];
    assert_int_equal(vt_png_write(path, 4, 4, px, 16, true, 1, why, sizeof why), 0);
    assert_int_equal(vtc_texture_put_file(c, 7, -1, VP_TEX_SRGB, path, NULL), VP_OK);
    unlink(path);
    vp_material m = mat(1);
    m.tex[VP_TEX_BASE].texture = 7;
    m.tex[VP_TEX_EMISSIVE].texture = 7;
    assert_int_equal(vtc_material_put(c, &m, 1, NULL), VP_OK);
    uint64_t tex = 7;
    assert_int_equal(vtc_texture_remove(c, &tex, 1, NULL), VP_ERR_STATE);
    fprintf(stderr, "texture in use: %s\n", vtc_last_error(c)->msg);
    m.tex[VP_TEX_BASE].texture = 0;
    assert_int_equal(vtc_material_put(c, &m, 1, NULL), VP_OK);
    assert_int_equal(vtc_texture_remove(c, &tex, 1, NULL), VP_ERR_STATE); /* the emissive slot still */
    m.tex[VP_TEX_EMISSIVE].texture = 0;
    assert_int_equal(vtc_material_put(c, &m, 1, NULL), VP_OK);
    assert_int_equal(vtc_texture_remove(c, &tex, 1, NULL), VP_OK);
    vtc_close(c);
}

const struct CMUnitTest material_tests[] = {
    cmocka_unit_test(test_material_refs_against_model),
    cmocka_unit_test(test_material_limit_and_batches),
    TEST_ROWS(test_material_bad_input, mat_rows),
    DAEMON_TEST(test_material_keeps_texture),
};
const size_t material_tests_count = sizeof material_tests / sizeof material_tests[0];
