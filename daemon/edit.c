/*
 * edit.c — scene edits decoded and applied (see edit.h): the one place
 * both a live request and a journal record become a scene change.
 */
#include "edit.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

bool edit_is(uint16_t type)
{
    switch (type) {
    case VP_ENTITY_ADD:
    case VP_ENTITY_UPDATE:
    case VP_ENTITY_REMOVE:
    case VP_MESH_PUT:
    case VP_OCCLUDER_PUT:
    case VP_OCCLUDER_REMOVE:
    case VP_LIGHT_PUT:
    case VP_LIGHT_REMOVE:
    case VP_SUBLEVEL_NAMES:
    case VP_SUBLEVEL_BEGIN:
    case VP_SUBLEVEL_COMMIT:
    case VP_SUBLEVEL_ABORT:
    case VP_SUBLEVEL_UNLOAD:
    case VP_DESTROY:
    case VP_TRANSFORM_SET:
    case VP_MATERIAL_PUT:
    case VP_MATERIAL_REMOVE:
    case VP_TEXTURE_PUT:
    case VP_TEXTURE_REMOVE:
    case VP_ENV_SET:
        return true;
    default:
        return false;
    }
}

int edit_decode(uint16_t type, const uint8_t *p, uint32_t len, uint32_t max_batch, unsigned layout, edit *e)
{
    bool v1 = layout == EDIT_LAYOUT_V1;
    memset(e, 0, sizeof *e);
    e->type = type;
    e->count = 1;
    int rc;
    switch (type) {
    case VP_ENTITY_ADD:
    case VP_ENTITY_UPDATE:
        rc = v1 ? vp_dec_entities_v1(p, len, max_batch, &e->u.ents) : vp_dec_entities(p, len, max_batch, &e->u.ents);
        e->count = e->u.ents.count;
        break;
    case VP_TRANSFORM_SET:
        rc = vp_dec_transforms(p, len, max_batch, &e->u.xf);
        e->count = e->u.xf.count;
        break;
    case VP_MATERIAL_PUT:
        rc = vp_dec_materials(p, len, max_batch, &e->u.mats.recs, &e->u.mats.n);
        e->count = e->u.mats.n;
        break;
    case VP_ENTITY_REMOVE:
    case VP_OCCLUDER_REMOVE:
    case VP_LIGHT_REMOVE:
    case VP_MATERIAL_REMOVE:
    case VP_TEXTURE_REMOVE:
        rc = vp_dec_ids(p, len, max_batch, &e->u.ids);
        e->count = e->u.ids.count;
        break;
    case VP_MESH_PUT:
        return vp_dec_mesh(p, len, 0, &e->u.mesh);
    case VP_OCCLUDER_PUT:
        return v1 ? vp_dec_occluder_v1(p, len, 0, &e->u.occ) : vp_dec_occluder(p, len, 0, &e->u.occ);
    case VP_LIGHT_PUT:
        rc = vp_dec_lights(p, len, max_batch, &e->u.lights.recs, &e->u.lights.n);
        e->count = e->u.lights.n;
        break;
    case VP_SUBLEVEL_NAMES:
        rc = vp_dec_names(p, len, false, &e->u.names);
        e->count = e->u.names.count;
        return rc;
    case VP_SUBLEVEL_BEGIN:
        return vp_dec_sublevel_begin(p, len, &e->u.begin);
    case VP_SUBLEVEL_COMMIT:
    case VP_SUBLEVEL_ABORT:
        return vp_dec_empty(p, len);
    case VP_SUBLEVEL_UNLOAD:
        return vp_dec_sublevel_name(p, len, &e->u.name);
    case VP_DESTROY:
        return vp_dec_destroy(p, len, &e->u.destroy);
    case VP_TEXTURE_PUT:
        return vp_dec_texture_put(p, len, &e->u.tex);
    case VP_ENV_SET:
        return vp_dec_env(p, len, &e->u.env);
    case EDIT_DEMO:
    case EDIT_WORK:
    case EDIT_CITY:
        return len ? VP_ERR_TRAILING : VP_OK;
    default:
        return VP_ERR_TYPE;
    }
    /* batches hold 1..max_batch records (the decoders check the top) */
    return rc ? rc : e->count ? VP_OK : VP_ERR_COUNT;
}

void edit_explain(const edit *e, int rc, scene_err *err)
{
    char why[120];
    err->code = rc;
    err->index = UINT32_MAX;
    snprintf(err->msg, sizeof err->msg, "%s", vp_strerror(rc));
    if (rc != VP_ERR_NONFINITE && rc != VP_ERR_INVALID) return;
    if (e->type == VP_DESTROY) { /* the decoder's checks, in its order */
        const vp_destroy *d = &e->u.destroy;
        static const char axis[3] = {'x', 'y', 'z'};
        for (int a = 0; a < 3; a++)
            if (!isfinite(d->center[a])) {
                scene_fail(err, rc, UINT32_MAX, "centre %c is %g: NaN or infinite", axis[a], d->center[a]);
                return;
            }
        if (!isfinite(d->radius)) scene_fail(err, rc, UINT32_MAX, "radius is %g: NaN or infinite", d->radius);
        else if (!(d->radius > 0)) scene_fail(err, rc, UINT32_MAX, "radius %g m is not > 0", d->radius);
        else if (d->debris > VP_MAX_DEBRIS)
            scene_fail(err, rc, UINT32_MAX, "debris %u is more than %u", d->debris, VP_MAX_DEBRIS);
        else scene_fail(err, rc, UINT32_MAX, "pad bytes 13..15 must be zero");
        return;
    }
    if (e->type == VP_ENV_SET) { /* the decoder's check again, for its words */
        vp_env env = e->u.env;
        if (vp_env_check(&env, why, sizeof why)) scene_fail(err, rc, UINT32_MAX, "environment: %s", why);
        return;
    }
    if (e->type == VP_TEXTURE_PUT) {
        const vp_texture_put *t = &e->u.tex;
        if (!t->id) scene_fail(err, rc, UINT32_MAX, "texture id 0: texture ids start at 1");
        else if (t->format > VP_TEX_EXR)
            scene_fail(err, rc, UINT32_MAX, "texture %u: format %u: 0 PNG, 1 JPEG, 2 EXR are defined", t->id,
                       t->format);
        else if (t->flags & ~VP_TEX_SRGB)
            scene_fail(err, rc, UINT32_MAX, "texture %u: flags 0x%x: only 0x1 (sRGB) is defined", t->id, t->flags);
        else scene_fail(err, rc, UINT32_MAX, "texture %u: pad bytes 6..7 must be zero", t->id);
        return;
    }
    /* a batch whose structure held but a record did not: the first such
       record, by the decoder's own per-record check */
    for (uint32_t i = 0;; i++) {
        int r;
        if (e->type == VP_ENTITY_ADD || e->type == VP_ENTITY_UPDATE) {
            if (i >= e->u.ents.count || !e->u.ents.recs) return;
            r = vp_entity_rec_check(&e->u.ents, i, why, sizeof why);
        } else if (e->type == VP_LIGHT_PUT) {
            if (i >= e->u.lights.n || !e->u.lights.recs) return;
            r = vp_light_rec_check(e->u.lights.recs, e->u.lights.n, i, why, sizeof why);
        } else if (e->type == VP_TRANSFORM_SET) {
            if (i >= e->u.xf.count || !e->u.xf.recs) return;
            r = vp_transform_rec_check(&e->u.xf, i, why, sizeof why);
        } else if (e->type == VP_MATERIAL_PUT) {
            if (i >= e->u.mats.n || !e->u.mats.recs) return;
            r = vp_material_rec_check(e->u.mats.recs, e->u.mats.n, i, why, sizeof why);
        } else {
            return;
        }
        if (r) {
            scene_fail(err, r, i, "record %u: %s", i, why);
            return;
        }
    }
}

/* SUBLEVEL_UNLOAD of a named sub-level: it must exist, be loaded, and not
 * be in some connection's load. */
static int unload(scene *sc, const vp_name *nm, uint32_t *n, scene_err *err)
{
    uint16_t id = scene_sublevel_find(sc, nm->name, nm->len);
    if (!id) {
        char esc[4 * 255 + 1];
        vp_escape(esc, sizeof esc, nm->name, nm->len);
        return scene_fail(err, VP_ERR_NOT_FOUND, UINT32_MAX, "no sub-level named \"%.100s\"", esc);
    }
    const scene_sublevel *l = &sc->sl[id];
    if (l->state == VP_SL_LOADING)
        return scene_fail(err, VP_ERR_STATE, UINT32_MAX, "sub-level %s is being loaded by client %u", l->name, l->owner);
    if (scene_sublevel_state(sc, id) == VP_SL_EMPTY)
        return scene_fail(err, VP_ERR_STATE, UINT32_MAX, "sub-level %s is not loaded", l->name);
    return scene_sublevel_drop(sc, id, n, err);
}

int edit_apply(scene *sc, const edit *e, edit_result *r, scene_err *err)
{
    memset(r, 0, sizeof *r);
    r->n = e->count;
    int rc;
    switch (e->type) {
    case VP_ENTITY_ADD:
        if (!(r->handles = malloc((size_t)e->count * sizeof *r->handles)))
            return scene_fail(err, VP_ERR_BUSY, UINT32_MAX, "out of memory");
        rc = scene_add(sc, e->sublevel, &e->u.ents, r->handles, err);
        break;
    case VP_ENTITY_UPDATE:
        rc = scene_update(sc, e->sublevel, &e->u.ents, err);
        break;
    case VP_ENTITY_REMOVE:
        rc = scene_remove(sc, e->sublevel, &e->u.ids, err);
        break;
    case VP_OCCLUDER_REMOVE:
    case VP_LIGHT_REMOVE:
        rc = scene_remove_ids(sc, e->sublevel, e->type == VP_LIGHT_REMOVE ? &sc->lights : &sc->occluders, &e->u.ids, err);
        break;
    case VP_MESH_PUT:
        rc = scene_mesh_put(sc, e->sublevel, &e->u.mesh, err);
        break;
    case VP_OCCLUDER_PUT:
        rc = scene_occluder_put(sc, e->sublevel, &e->u.occ, err);
        break;
    case VP_LIGHT_PUT:
        rc = scene_lights_put(sc, e->sublevel, e->u.lights.recs, e->u.lights.n, err);
        break;
    case VP_SUBLEVEL_NAMES:
        if (!(r->ids = malloc(((size_t)e->count + 1) * sizeof *r->ids)))
            return scene_fail(err, VP_ERR_BUSY, UINT32_MAX, "out of memory");
        rc = scene_sublevel_ids(sc, &e->u.names, r->ids, err);
        break;
    case VP_SUBLEVEL_BEGIN:
        if (e->sublevel)
            return scene_fail(err, VP_ERR_STATE, UINT32_MAX, "this connection is already loading a sub-level");
        rc = scene_sublevel_begin(sc, &e->u.begin, e->aux, &r->begun, err);
        break;
    case VP_SUBLEVEL_COMMIT:
    case VP_SUBLEVEL_ABORT:
        if (!e->sublevel) return scene_fail(err, VP_ERR_STATE, UINT32_MAX, "no load open on this connection");
        r->n = 0;
        rc = e->type == VP_SUBLEVEL_COMMIT ? scene_sublevel_commit(sc, e->sublevel, &r->n, err)
                                           : scene_sublevel_drop(sc, e->sublevel, &r->n, err);
        break;
    case VP_SUBLEVEL_UNLOAD:
        r->n = 0;
        rc = unload(sc, &e->u.name, &r->n, err);
        break;
    case VP_DESTROY:
        rc = scene_destroy(sc, &e->u.destroy, e->aux, &r->destroyed, err);
        break;
    case VP_TRANSFORM_SET:
        rc = scene_transform_set(sc, e->sublevel, &e->u.xf, err);
        break;
    case VP_MATERIAL_PUT:
        rc = scene_materials_put(sc, e->u.mats.recs, e->u.mats.n, err);
        break;
    case VP_MATERIAL_REMOVE:
        rc = scene_materials_remove(sc, &e->u.ids, err);
        break;
    case VP_TEXTURE_PUT: /* global, as materials: a loading connection's goes in at once */
        rc = scene_texture_put(sc, &e->u.tex, err);
        break;
    case VP_TEXTURE_REMOVE:
        rc = scene_textures_remove(sc, &e->u.ids, err);
        break;
    case VP_ENV_SET:
        rc = scene_env_set(sc, &e->u.env, err);
        break;
    case EDIT_DEMO:
        rc = scene_build_demo(sc, e->aux) ? scene_fail(err, VP_ERR_BUSY, UINT32_MAX, "cannot build the demo city")
                                          : VP_OK;
        break;
    case EDIT_CITY:
        rc = scene_build_city(sc, e->aux, err);
        break;
    case EDIT_WORK:
        (void)scene_sublevel_work(sc, e->aux);
        rc = VP_OK;
        break;
    default:
        return scene_fail(err, VP_ERR_TYPE, UINT32_MAX, "type 0x%04x is not an edit", e->type);
    }
    if (rc) edit_result_free(r);
    return rc;
}

void edit_result_free(edit_result *r)
{
    free(r->handles);
    free(r->ids);
    r->handles = NULL;
    r->ids = NULL;
}
