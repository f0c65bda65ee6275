/*
 * material.c — the scene's materials (glTF 2.0 metallic-roughness, see
 * protocol.h vp_material): stored by id, shared by any number of entities,
 * global (not in sub-levels). What it owns: MATERIAL_PUT and
 * MATERIAL_REMOVE, and the reference counts that keep a texture while a
 * material names it and a material while an entity uses it (env.c counts
 * the environment's ground). A material is 188 bytes; at most lim.max_materials.
 */
#include "scene.h"

#include <stdlib.h>
#include <string.h>

static const char *const slot_name[VP_TEX_SLOTS] = {"base colour", "metallic-roughness", "normal", "emissive"};

scene_material *scene_material_find(const scene *s, uint32_t id)
{
    uint64_t v;
    if (!id || !idmap_get(&s->materials, id, &v)) return NULL;
    return (scene_material *)(uintptr_t)v;
}

/* Adds d (+1 or -1) to the users of every texture m names. */
static void texture_users(const scene *s, const vp_material *m, int d)
{
    for (int k = 0; k < VP_TEX_SLOTS; k++) {
        scene_texture *t = scene_texture_find(s, m->tex[k].texture);
        if (t) t->users += (uint32_t)d;
    }
}

int scene_materials_put(scene *s, const uint8_t *recs, uint32_t n, scene_err *err)
{
    uint64_t *ids = calloc((size_t)n + 1, sizeof *ids);
    scene_material **mem = calloc((size_t)n + 1, sizeof *mem);
    int rc = VP_OK;
    size_t fresh = 0;
    if (!ids || !mem) {
        rc = scene_fail(err, VP_ERR_BUSY, UINT32_MAX, "out of memory for materials");
        goto out;
    }
    for (uint32_t i = 0; i < n; i++) {
        vp_material m;
        char why[120];
        if ((rc = vp_material_get(recs, n, i, &m))) {
            vp_material_rec_check(recs, n, i, why, sizeof why);
            rc = scene_fail(err, rc, i, "record %u: %s", i, why);
            goto out;
        }
        for (int k = 0; k < VP_TEX_SLOTS; k++)
            if (m.tex[k].texture && !scene_texture_find(s, m.tex[k].texture)) {
                rc = scene_fail(err, VP_ERR_UNKNOWN_ID, i, "record %u (material %u): %s texture %u does not exist",
                                i, m.id, slot_name[k], m.tex[k].texture);
                goto out;
            }
        ids[i] = m.id;
        fresh += !scene_material_find(s, m.id);
    }
    if ((rc = scene_check_unique(ids, n, err))) goto out;
    if (s->materials.count + fresh > s->lim.max_materials) {
        rc = scene_fail(err, VP_ERR_LIMIT, UINT32_MAX, "%zu materials with this batch, limit %u",
                        s->materials.count + fresh, s->lim.max_materials);
        goto out;
    }
    bool ok = idmap_reserve(&s->materials, s->materials.count + fresh);
    for (uint32_t i = 0; ok && i < n; i++)
        ok = scene_material_find(s, (uint32_t)ids[i]) || (mem[i] = calloc(1, sizeof **mem)) != NULL;
    if (!ok) {
        rc = scene_fail(err, VP_ERR_BUSY, UINT32_MAX, "out of memory for materials");
        goto out;
    }
    /* apply: a replaced material keeps its users (entities see the change) */
    for (uint32_t i = 0; i < n; i++) {
        scene_material *m = scene_material_find(s, (uint32_t)ids[i]);
        if (m) {
            texture_users(s, &m->m, -1);
        } else {
            m = mem[i];
            mem[i] = NULL;
            idmap_put(&s->materials, ids[i], (uint64_t)(uintptr_t)m);
        }
        vp_material_get(recs, n, i, &m->m);
        texture_users(s, &m->m, +1);
    }
    s->epoch++;
out:
    for (uint32_t i = 0; mem && i < n; i++) free(mem[i]);
    free(mem);
    free(ids);
    return rc;
}

int scene_materials_remove(scene *s, const vp_id_batch *b, scene_err *err)
{
    uint64_t *ids = malloc(((size_t)b->count + 1) * sizeof *ids);
    if (!ids) return scene_fail(err, VP_ERR_BUSY, UINT32_MAX, "out of memory");
    int rc = VP_OK;
    for (uint32_t i = 0; i < b->count; i++) {
        ids[i] = vp_id_get(b, i);
        const scene_material *m = ids[i] <= UINT32_MAX ? scene_material_find(s, (uint32_t)ids[i]) : NULL;
        if (!m) {
            rc = scene_fail(err, VP_ERR_UNKNOWN_ID, i, "record %u: no material %llu", i, (unsigned long long)ids[i]);
            goto out;
        }
        bool ground = s->env.ground_material == ids[i]; /* (counted in users too, by env.c) */
        if (ground || m->users) {
            rc = ground ? scene_fail(err, VP_ERR_STATE, i, "record %u: material %llu is the environment's ground", i,
                                     (unsigned long long)ids[i])
                        : scene_fail(err, VP_ERR_STATE, i, "record %u: material %llu is used by %u entities", i,
                                     (unsigned long long)ids[i], m->users);
            goto out;
        }
    }
    if ((rc = scene_check_unique(ids, b->count, err))) goto out;
    for (uint32_t i = 0; i < b->count; i++) {
        scene_material *m = scene_material_find(s, (uint32_t)ids[i]);
        texture_users(s, &m->m, -1);
        idmap_del(&s->materials, ids[i]);
        free(m);
    }
    s->epoch++;
out:
    free(ids);
    return rc;
}

void scene_materials_free(scene *s)
{
    for (size_t i = 0; i < s->materials.cap; i++)
        if (s->materials.used[i]) free((void *)(uintptr_t)s->materials.vals[i]);
    idmap_free(&s->materials);
}
