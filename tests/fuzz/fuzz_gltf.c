/*
 * fuzz_gltf.c — libFuzzer target for the level import (client/import/:
 * import_walk.c, import_memio.c):
 * the input is a level file in memory, read by assimp and converted by
 * imp_level_import_mem exactly as `vantage sublevel load` converts a file
 * (glTF binary when it starts with the "glTF" magic, else glTF JSON).
 *
 * Properties (a broken one calls abort()):
 *   1. a refused file has a message (not empty, ended within err) and the
 *      level comes back all zero;
 *   2. an accepted level holds something (an entity, occluder, light or
 *      the sun) and its counts agree: every entity's class exists and every
 *      class is some entity's; an entity's material is its mesh's and is 0
 *      or a material of the level, whose textures are the level's (ids 1..n
 *      in order, PNG or JPEG by their first bytes); an entity's occluder
 *      and an occluder's entity point at each other; no class, occluder or
 *      light is empty;
 *   3. every number is finite and in range: class vertices and entity
 *      boxes within +-1e12 m with min <= max, indices below the vertex
 *      count, normals, tangents and light directions of unit length,
 *      tangent handedness +-1, transforms as vp_trs_check takes them,
 *      light colours in 0..1 (the largest 1), intensity > 0, range
 *      0.01..1e6 m, spot cones -1 <= outer <= inner <= 1;
 *   4. the wire takes all of it, as the load sends it: each class mesh
 *      with its UVs and tangents (MESH_PUT), the textures (TEXTURE_PUT),
 *      the materials (MATERIAL_PUT), the entities as transform records
 *      (ENTITY_ADD), each occluder (OCCLUDER_PUT), the lights (LIGHT_PUT)
 *      and the sun in an environment (ENV_SET) encode and decode with
 *      VP_OK.
 *
 * assimp is the system's build, not instrumented: libFuzzer's coverage
 * comes from the importer and this file only, and ASan sees assimp's memory
 * errors only where they reach an intercepted call (memcpy, free, ...).
 */
#include "import.h"
#include "protocol.h"

#define FUZZ_NAME "fuzz_gltf"
#include "fuzz_check.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

const char *__lsan_default_suppressions(void);
const char *__lsan_default_options(void);
const char *__asan_default_options(void);

/* LeakSanitizer leaves out what assimp leaks: the library leaks on some
 * broken files (a data: URI that is not base64 leaks its buffer, assimp
 * issue 6508), and its frames have no symbols to name one leak by. A leak
 * whose stack has assimp in it, or stops in libstdc++'s operator new (clang
 * links ASan's operator new only for C++, and the unwinder stops in
 * libstdc++), is assimp's: this C code allocates with malloc. */
const char *__lsan_default_suppressions(void)
{
    return "leak:libassimp.so\nleak:libstdc++.so\n";
}

/* and does not list the suppression after every input */
const char *__lsan_default_options(void)
{
    return "print_suppressions=0";
}

/* An allocation too big for ASan fails as it does without it: assimp asks
 * for 64 GiB on some files, and the bad_alloc fails the import. (So in the
 * libFuzzer build; gcc's ASan in the replay has its own operator new, which
 * reports it.) */
const char *__asan_default_options(void)
{
    return "allocator_may_return_null=1";
}

#define MAX_COORD 1e12
#define ERR_LEN 512 /* cli_sublevel.c's */

static bool all_zero(const void *p, size_t n)
{
    const uint8_t *b = p;
    for (size_t i = 0; i < n; i++)
        if (b[i]) return false;
    return true;
}

static bool in_range(double x) { return fabs(x) <= MAX_COORD; } /* false for NaN */

static bool unit(double x, double y, double z)
{
    double l = sqrt(x * x + y * y + z * z);
    return fabs(l - 1) < 1e-3;
}

static bool name_ok(const char *name) { return memchr(name, 0, LVL_NAME) != NULL; }

/* ---- 4: through the protocol ----------------------------------------------------- */

static void check_wire(const imp_level *lv)
{
    size_t len;
    for (uint32_t i = 0; i < lv->nmesh; i++) {
        const lvl_mesh *m = &lv->mesh[i];
        fuzz_wbuf b;
        fuzz_wopen(&b, vp_size_mesh_uv(m->nv, m->ni, true, m->uv != NULL, m->tan != NULL));
        vp_enc_mesh_uv(&b.w, 1, (uint16_t)i, m->pos, m->nrm, m->uv, m->tan, m->nv, m->idx, m->ni);
        const uint8_t *p = fuzz_wframe(&b, VP_MESH_PUT, &len);
        vp_mesh dm;
        CHECK(vp_dec_mesh(p, len, 0, &dm) == VP_OK);
        CHECK(dm.vertex_count == m->nv && dm.index_count == m->ni && (dm.uvs != NULL) == (m->uv != NULL));
        fuzz_wclose(&b);
    }
    for (uint32_t i = 0; i < lv->ntex; i++) {
        const lvl_texture *t = &lv->tex[i];
        fuzz_wbuf b;
        fuzz_wopen(&b, vp_size_texture_put(t->nbytes));
        vp_enc_texture_put(&b.w, 1, &(vp_texture_put){.id = t->id, .format = t->format, .flags = t->flags,
                                                      .total = t->nbytes, .len = t->nbytes, .data = t->bytes});
        const uint8_t *p = fuzz_wframe(&b, VP_TEXTURE_PUT, &len);
        vp_texture_put dt;
        CHECK(vp_dec_texture_put(p, len, &dt) == VP_OK && dt.len == t->nbytes);
        fuzz_wclose(&b);
    }
    if (lv->nmat) {
        fuzz_wbuf b;
        fuzz_wopen(&b, vp_size_materials(lv->nmat));
        vp_enc_materials(&b.w, 1, lv->mat, lv->nmat);
        const uint8_t *p = fuzz_wframe(&b, VP_MATERIAL_PUT, &len), *recs;
        uint32_t n;
        CHECK(vp_dec_materials(p, len, 0, &recs, &n) == VP_OK && n == lv->nmat);
        fuzz_wclose(&b);
    }
    if (lv->has_sun) {
        vp_env e;
        vp_env_default(&e);
        memcpy(e.sun_dir, lv->sun_dir, sizeof e.sun_dir);
        memcpy(e.sun_color, lv->sun_color, sizeof e.sun_color);
        e.sun_lux = lv->sun_lux;
        fuzz_wbuf b;
        fuzz_wopen(&b, vp_size_env());
        vp_enc_env(&b.w, VP_ENV_SET, 1, &e);
        const uint8_t *p = fuzz_wframe(&b, VP_ENV_SET, &len);
        vp_env de;
        CHECK(vp_dec_env(p, len, &de) == VP_OK);
        fuzz_wclose(&b);
    }
    if (lv->nent) {
        vp_entity *rec = calloc(lv->nent, sizeof *rec);
        CHECK(rec != NULL);
        for (uint32_t i = 0; i < lv->nent; i++) {
            const lvl_entity *e = &lv->ent[i];
            rec[i].id = 1ull << 63 | i;
            rec[i].class_id = (uint16_t)e->cls;
            rec[i].material = e->material;
            rec[i].flags = VP_ENT_TRANSFORM | (e->dynamic ? VP_ENT_DYNAMIC : 0);
            memcpy(rec[i].pos, e->pos, sizeof rec[i].pos);
            memcpy(rec[i].rot, e->rot, sizeof rec[i].rot);
            memcpy(rec[i].scale, e->scale, sizeof rec[i].scale);
            /* the scene's transform rules */
            double pos[3] = {e->pos[0], e->pos[1], e->pos[2]};
            float rot[4] = {e->rot[0], e->rot[1], e->rot[2], e->rot[3]}, sc[3] = {e->scale[0], e->scale[1], e->scale[2]};
            CHECK(vp_trs_check(pos, rot, sc, NULL, 0) == VP_OK);
        }
        fuzz_wbuf b;
        fuzz_wopen(&b, vp_size_entities(lv->nent));
        vp_enc_entities(&b.w, VP_ENTITY_ADD, 1, rec, lv->nent);
        const uint8_t *p = fuzz_wframe(&b, VP_ENTITY_ADD, &len);
        vp_entity_batch eb;
        CHECK(vp_dec_entities(p, len, 0, &eb) == VP_OK && eb.count == lv->nent);
        fuzz_wclose(&b);
        free(rec);
    }
    for (uint32_t i = 0; i < lv->nocc; i++) {
        const lvl_occluder *o = &lv->occ[i];
        fuzz_wbuf b;
        fuzz_wopen(&b, vp_size_occluder(o->ntri));
        vp_enc_occluder(&b.w, 1, 1ull << 63 | i, o->origin, o->tri, o->ntri);
        const uint8_t *p = fuzz_wframe(&b, VP_OCCLUDER_PUT, &len);
        vp_occluder dec;
        CHECK(vp_dec_occluder(p, len, 0, &dec) == VP_OK && dec.tri_count == o->ntri);
        fuzz_wclose(&b);
    }
    if (lv->nlight) {
        fuzz_wbuf b;
        fuzz_wopen(&b, VP_HEADER_SIZE + 4 + (size_t)VP_LIGHT_SIZE * lv->nlight);
        vp_enc_lights(&b.w, 1, lv->light, lv->nlight);
        const uint8_t *p = fuzz_wframe(&b, VP_LIGHT_PUT, &len);
        const uint8_t *recs;
        uint32_t n;
        CHECK(vp_dec_lights(p, len, 0, &recs, &n) == VP_OK && n == lv->nlight);
        fuzz_wclose(&b);
    }
}

/* ---- 2 and 3 ------------------------------------------------------------------- */

/* a material id of the level, or 0 */
static bool material_known(const imp_level *lv, uint32_t id)
{
    for (uint32_t i = 0; id && i < lv->nmat; i++)
        if (lv->mat[i].id == id) return true;
    return id == 0;
}

static void check_materials(const imp_level *lv)
{
    CHECK(lv->nmat == 0 || lv->mat);
    CHECK(lv->ntex == 0 || lv->tex);
    for (uint32_t i = 0; i < lv->nmat; i++) {
        CHECK(lv->mat[i].id == i + 1); /* the used ones, 1.. in order */
        for (int k = 0; k < VP_TEX_SLOTS; k++) CHECK(lv->mat[i].tex[k].texture <= lv->ntex);
    }
    for (uint32_t i = 0; i < lv->ntex; i++) {
        const lvl_texture *t = &lv->tex[i];
        CHECK(t->id == i + 1 && t->nbytes >= 3 && t->bytes);
        CHECK(t->format == VP_TEX_PNG ? !memcmp(t->bytes, "\x89PNG", 4)
                                      : t->format == VP_TEX_JPEG && t->bytes[0] == 0xff && t->bytes[1] == 0xd8);
    }
    if (lv->has_sun) {
        CHECK(unit(lv->sun_dir[0], lv->sun_dir[1], lv->sun_dir[2]));
        CHECK(lv->sun_lux > 0 && lv->sun_lux <= 200000);
        CHECK(fmaxf(lv->sun_color[0], fmaxf(lv->sun_color[1], lv->sun_color[2])) == 1);
    }
}

static void check_level(const imp_level *lv)
{
    CHECK(lv->nent || lv->nocc || lv->nlight || lv->has_sun);
    check_materials(lv);
    CHECK(lv->nmesh <= LVL_MAX_CLASSES);
    CHECK(lv->nmesh == 0 || lv->mesh);
    CHECK(lv->nent == 0 || lv->ent);
    CHECK(lv->nocc == 0 || lv->occ);
    CHECK(lv->nlight == 0 || lv->light);
    uint8_t *used = calloc((size_t)lv->nmesh + 1, 1);
    CHECK(used != NULL);
    for (uint32_t i = 0; i < lv->nmesh; i++) {
        const lvl_mesh *m = &lv->mesh[i];
        CHECK(m->nv > 0 && m->ni > 0 && m->ni % 3 == 0);
        for (uint32_t k = 0; k < m->ni; k++) CHECK(m->idx[k] < m->nv);
        CHECK(material_known(lv, m->material));
        CHECK(!m->tan || m->uv);
        for (uint32_t v = 0; v < m->nv; v++) {
            const float *p = m->pos + 3 * (size_t)v, *n = m->nrm + 3 * (size_t)v;
            CHECK(in_range(p[0]) && in_range(p[1]) && in_range(p[2]));
            CHECK(isfinite(n[0]) && isfinite(n[1]) && isfinite(n[2]) && unit(n[0], n[1], n[2]));
            if (m->uv) CHECK(isfinite(m->uv[2 * (size_t)v]) && isfinite(m->uv[2 * (size_t)v + 1]));
            if (m->tan) CHECK(fabsf(m->tan[4 * (size_t)v + 3]) == 1);
        }
    }
    for (uint32_t i = 0; i < lv->nent; i++) {
        const lvl_entity *e = &lv->ent[i];
        CHECK(e->cls < lv->nmesh);
        CHECK(e->material == lv->mesh[e->cls].material);
        used[e->cls] = 1;
        for (int a = 0; a < 3; a++) CHECK(in_range(e->lo[a]) && in_range(e->hi[a]) && e->lo[a] <= e->hi[a]);
        CHECK(name_ok(e->name));
        CHECK(e->occluder >= -1 && e->occluder < (int64_t)lv->nocc);
        if (e->occluder >= 0) CHECK(lv->occ[e->occluder].entity == (int32_t)i);
    }
    for (uint32_t i = 0; i < lv->nmesh; i++) CHECK(used[i]);
    free(used);
    for (uint32_t i = 0; i < lv->nocc; i++) {
        const lvl_occluder *o = &lv->occ[i];
        CHECK(o->ntri > 0 && o->tri && o->ntri <= o->cap);
        CHECK(name_ok(o->name));
        for (int a = 0; a < 3; a++) CHECK(in_range(o->origin[a]));
        for (uint32_t t = 0; t < 9 * o->ntri; t++) {
            CHECK(isfinite(o->tri[t]));
            /* the world vertex, give or take the float's rounding */
            CHECK(fabs(o->tri[t] + o->origin[t % 3]) <= MAX_COORD * (1 + 1e-6));
        }
        CHECK(o->entity >= -1 && o->entity < (int64_t)lv->nent);
        if (o->entity >= 0) CHECK(lv->ent[o->entity].occluder == (int32_t)i);
    }
    for (uint32_t i = 0; i < lv->nlight; i++) {
        const vp_light *l = &lv->light[i];
        CHECK(l->id == 0);
        CHECK(l->kind == VP_LIGHT_POINT || l->kind == VP_LIGHT_SPOT);
        for (int a = 0; a < 3; a++) CHECK(in_range(l->pos[a]));
        CHECK(isfinite(l->dir[0]) && isfinite(l->dir[1]) && isfinite(l->dir[2]));
        CHECK(unit(l->dir[0], l->dir[1], l->dir[2]));
        float mx = 0;
        for (int a = 0; a < 3; a++) {
            CHECK(l->color[a] >= 0 && l->color[a] <= 1);
            mx = fmaxf(mx, l->color[a]);
        }
        CHECK(mx == 1);
        CHECK(isfinite(l->intensity) && l->intensity > 0);
        CHECK(l->range >= 0.01f && l->range <= 1e6f);
        if (l->kind == VP_LIGHT_SPOT)
            CHECK(l->outer_cos >= -1 && l->outer_cos <= l->inner_cos && l->inner_cos <= 1);
    }
    check_wire(lv);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    /* an exact copy: assimp reads through import_memio.c's callbacks from it */
    uint8_t *buf = malloc(size ? size : 1);
    CHECK(buf != NULL);
    memcpy(buf, data, size);
    const char *hint = size >= 4 && !memcmp(buf, "glTF", 4) ? "glb" : "gltf";
    imp_level lv;
    char err[ERR_LEN];
    memset(err, 0x55, sizeof err);
    memset(&lv, 0xA5, sizeof lv);
    if (imp_level_import_mem(buf, size, hint, &lv, err, sizeof err) == 0) {
        check_level(&lv);
        imp_level_free(&lv);
    } else {
        CHECK(memchr(err, 0, sizeof err) != NULL && err[0] != 0);
        CHECK(all_zero(&lv, sizeof lv));
    }
    free(buf);
    return 0;
}
