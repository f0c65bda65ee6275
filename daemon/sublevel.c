/*
 * sublevel.c — named sub-levels: loads that appear at one epoch, unloads
 * that vanish at one epoch and are freed in slices (see scene.h).
 *
 * A load is a connection's: BEGIN marks the sub-level hidden (no query,
 * frame or light list sees it), the connection's edits fill it, COMMIT
 * clears the mark. Unload (or abort) sets the mark again at once, frees
 * its occluders, lights and reserved meshes, and leaves its entities to
 * scene_sublevel_work, a few thousand per loop turn, so the scene lock is
 * never held long. Everything here runs on the loop thread under the
 * scene lock (exclusive).
 */
#include "scene.h"
#include "vp_grow.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void hide(scene *s, uint16_t id, bool on)
{
    uint64_t bit = 1ull << (id & 63), *w = &s->hidden[id >> 6];
    if (on && !(*w & bit)) {
        *w |= bit;
        s->nhidden++;
    } else if (!on && (*w & bit)) {
        *w &= ~bit;
        s->nhidden--;
    }
}

/* Whether entity `eid` is still in sub-level id (its handle in *h). */
static bool member_live(const scene *s, uint16_t id, uint64_t eid, uint64_t *h)
{
    cull_entity_desc d;
    return idmap_get(&s->ids, eid, h) && cull_entity_get(s->world, (cull_handle)*h, &d) == CULL_OK && d.sublevel == id;
}

static const char *sl_name(const scene *s, uint16_t id)
{
    return id <= s->nsublevels && s->sl[id].name ? s->sl[id].name : "(unnamed)";
}

uint16_t scene_sublevel_find(const scene *s, const uint8_t *name, uint8_t len)
{
    for (uint32_t i = 1; i <= s->nsublevels; i++)
        if (strlen(s->sl[i].name) == len && !memcmp(s->sl[i].name, name, len)) return (uint16_t)i;
    return 0;
}

/* Defines a name; 0 when the table is full or memory is out. */
static uint16_t define(scene *s, const uint8_t *name, uint8_t len)
{
    if (s->nsublevels >= SCENE_MAX_SUBLEVELS) return 0;
    uint16_t id = (uint16_t)(s->nsublevels + 1);
    scene_sublevel *l = &s->sl[id];
    memset(l, 0, sizeof *l);
    /* entities may carry the id from before it had a name: list them (the
       one pass over every entity a sub-level ever needs, and only then) */
    uint32_t n = s->sl_entities[id];
    l->name = malloc((size_t)len + 1);
    l->members = n ? malloc((size_t)n * sizeof *l->members) : NULL;
    if (!l->name || (n && !l->members)) {
        free(l->name);
        free(l->members);
        memset(l, 0, sizeof *l);
        return 0;
    }
    memcpy(l->name, name, len);
    l->name[len] = 0;
    for (size_t i = 0; n && i < s->ids.cap; i++) {
        uint64_t h;
        if (s->ids.used[i] && member_live(s, id, s->ids.keys[i], &h)) l->members[l->nmembers++] = s->ids.keys[i];
    }
    l->members_cap = n;
    s->nsublevels = id;
    return id;
}

/* Takes back the newest names, down to id `keep`. */
static void undefine_to(scene *s, uint32_t keep)
{
    for (; s->nsublevels > keep; s->nsublevels--) {
        free(s->sl[s->nsublevels].name);
        free(s->sl[s->nsublevels].members);
        memset(&s->sl[s->nsublevels], 0, sizeof s->sl[0]);
    }
}

/* A name the spec allows: UTF-8 (the decoder already refused control
 * bytes). Checked here, not in the decoder, so a journal written before
 * the check still replays (s->replaying); the name is quoted escaped. */
static int name_ok(const scene *s, const uint8_t *name, uint8_t len, uint32_t index, scene_err *err)
{
    const char *why;
    size_t at = vp_utf8_check(name, len, &why);
    if (at == len || s->replaying) return VP_OK;
    char esc[4 * 255 + 1];
    vp_escape(esc, sizeof esc, name, len);
    if (index == UINT32_MAX)
        return scene_fail(err, VP_ERR_INVALID, index, "name \"%.80s\" is not UTF-8: %s at byte %zu", esc, why, at);
    return scene_fail(err, VP_ERR_INVALID, index, "name %u \"%.80s\" is not UTF-8: %s at byte %zu", index, esc, why,
                      at);
}

int scene_sublevel_ids(scene *s, const vp_name_list *names, uint16_t *ids, scene_err *err)
{
    uint32_t first_new = s->nsublevels + 1, i = 0;
    size_t pos = 0;
    vp_name nm;
    for (uint32_t k = 0; vp_name_next(names, &pos, &nm); k++) {
        int rc = name_ok(s, nm.name, nm.len, k, err);
        if (rc) return rc;
    }
    pos = 0;
    while (vp_name_next(names, &pos, &nm)) {
        uint16_t id = scene_sublevel_find(s, nm.name, nm.len);
        if (!id && !(id = define(s, nm.name, nm.len))) {
            undefine_to(s, first_new - 1); /* all or nothing */
            return scene_fail(err, VP_ERR_LIMIT, i, "name %u: %u sub-level names, limit %u", i, s->nsublevels,
                              SCENE_MAX_SUBLEVELS);
        }
        ids[i++] = id;
    }
    return VP_OK;
}

/* "record N: " for an error about record index, "" for none. */
static const char *at_record(uint32_t index, char buf[32])
{
    if (index == UINT32_MAX) buf[0] = 0;
    else snprintf(buf, 32, "record %u: ", index);
    return buf;
}

int scene_sublevel_writable(const scene *s, uint16_t loading, uint16_t sub, uint32_t index, scene_err *err)
{
    if (!sub || sub > s->nsublevels || sub == loading) return VP_OK;
    const scene_sublevel *l = &s->sl[sub];
    char at[32];
    if (l->state == VP_SL_LOADING)
        return scene_fail(err, VP_ERR_STATE, index, "%ssub-level %s is being loaded by client %u", at_record(index, at),
                          l->name, l->owner);
    if (l->state == VP_SL_UNLOADING)
        return scene_fail(err, VP_ERR_BUSY, index, "%ssub-level %s is being unloaded, retry", at_record(index, at),
                          l->name);
    return VP_OK;
}

int scene_sublevel_target(const scene *s, uint16_t loading, uint16_t *sub, uint32_t index, scene_err *err)
{
    if (loading && *sub == 0) *sub = loading;
    if (loading && *sub != loading) {
        char at[32];
        return scene_fail(err, VP_ERR_INVALID, index, "%ssub-level %u, but this connection is loading %s",
                          at_record(index, at), *sub, sl_name(s, loading));
    }
    return scene_sublevel_writable(s, loading, *sub, index, err);
}

uint8_t scene_sublevel_state(const scene *s, uint16_t id)
{
    const scene_sublevel *l = &s->sl[id];
    if (l->state) return l->state;
    return s->sl_entities[id] || l->occluders || l->lights ? VP_SL_LOADED : VP_SL_EMPTY;
}

/* A free run of n classes (no mesh, no entity, not reserved) in
 * 1..65535; 0 if none. */
static uint32_t find_classes(const scene *s, uint32_t n)
{
    uint32_t run = 0;
    for (uint32_t c = 1; c < 65536; c++) {
        run = (!s->meshes[c].pos && !s->class_owner[c] && !s->class_entities[c]) ? run + 1 : 0;
        if (run == n) return c - n + 1;
    }
    return 0;
}

int scene_sublevel_begin(scene *s, const vp_sublevel_begin *m, uint32_t owner, vp_sublevel_begun *out,
                         scene_err *err)
{
    int nrc = name_ok(s, m->name, m->name_len, UINT32_MAX, err);
    if (nrc) return nrc;
    uint16_t id = scene_sublevel_find(s, m->name, m->name_len);
    bool fresh = !id;
    if (fresh && !(id = define(s, m->name, m->name_len)))
        return scene_fail(err, VP_ERR_LIMIT, UINT32_MAX, "%u sub-level names, limit %u", s->nsublevels,
                          SCENE_MAX_SUBLEVELS);
    scene_sublevel *l = &s->sl[id];
    int rc = scene_sublevel_writable(s, 0, id, UINT32_MAX, err);
    if (!rc && scene_sublevel_state(s, id) == VP_SL_LOADED)
        rc = scene_fail(err, VP_ERR_DUPLICATE, UINT32_MAX,
                        "sub-level %s is loaded (%u entities, %u occluders, %u lights): unload it first", l->name,
                        s->sl_entities[id], l->occluders, l->lights);
    uint32_t base = 0;
    if (!rc && m->classes && !(base = find_classes(s, m->classes)))
        rc = scene_fail(err, VP_ERR_LIMIT, UINT32_MAX, "no run of %u free mesh classes", m->classes);
    if (rc) {
        if (fresh) undefine_to(s, id - 1u);
        return rc;
    }
    for (uint32_t c = base; c < base + m->classes; c++) s->class_owner[c] = id;
    l->state = VP_SL_LOADING;
    l->owner = owner;
    l->class_base = (uint16_t)base;
    l->classes = m->classes;
    hide(s, id, true);
    *out = (vp_sublevel_begun){.id = id, .class_base = (uint16_t)base, .epoch = s->epoch};
    return VP_OK;
}

int scene_sublevel_commit(scene *s, uint16_t id, uint32_t *entities, scene_err *err)
{
    if (!id || id > s->nsublevels || s->sl[id].state != VP_SL_LOADING)
        return scene_fail(err, VP_ERR_STATE, UINT32_MAX, "no load open on this connection");
    s->sl[id].state = 0;
    hide(s, id, false);
    *entities = s->sl_entities[id];
    s->epoch++;
    s->ev_added += *entities;
    return VP_OK;
}

/* The members that are still members, in order. */
static void members_compact(scene *s, scene_sublevel *l, uint16_t id)
{
    uint32_t k = 0;
    uint64_t h;
    for (uint32_t i = 0; i < l->nmembers; i++)
        if (member_live(s, id, l->members[i], &h)) l->members[k++] = l->members[i];
    l->nmembers = k;
}

bool scene_members_reserve(scene *s, const cull_entity_desc *descs, uint32_t n)
{
    for (uint32_t i = 0; i < n; i++) {
        uint16_t id = descs[i].sublevel;
        if (!id || id > s->nsublevels) continue;
        scene_sublevel *l = &s->sl[id];
        if ((size_t)l->nmembers + n <= l->members_cap) continue;
        /* entities leave without telling the list: drop those first when
           it has grown well past the sub-level */
        if (l->nmembers > 2 * s->sl_entities[id] + 1024) members_compact(s, l, id);
        size_t cap = vp_grow_cap(l->members_cap, (size_t)l->nmembers + n, 1024, sizeof(uint64_t), (size_t)1 << 31);
        if (!cap) return false;
        uint64_t *m = realloc(l->members, cap * sizeof *m);
        if (!m) return false;
        l->members = m;
        l->members_cap = (uint32_t)cap;
    }
    return true;
}

void scene_members_add(scene *s, uint16_t sub, uint64_t id)
{
    if (!sub || sub > s->nsublevels) return;
    scene_sublevel *l = &s->sl[sub];
    if (l->nmembers < l->members_cap) l->members[l->nmembers++] = id;
}

int scene_sublevel_drop(scene *s, uint16_t id, uint32_t *entities, scene_err *err)
{
    if (!id || id > s->nsublevels) return scene_fail(err, VP_ERR_NOT_FOUND, UINT32_MAX, "no sub-level %u", id);
    scene_sublevel *l = &s->sl[id];
    if (l->state == VP_SL_UNLOADING)
        return scene_fail(err, VP_ERR_BUSY, UINT32_MAX, "sub-level %s is already being unloaded", l->name);
    /* its members go, in slices (those that left since are skipped then) */
    uint64_t *doomed = l->members;
    uint32_t k = l->nmembers;
    l->members = NULL;
    l->nmembers = l->members_cap = 0;
    *entities = s->sl_entities[id];
    bool visible = !scene_sublevel_hidden(s, id);
    /* occluders and lights go now: their ids found first, then deleted (the
       maps move entries as they delete) */
    uint32_t nocc = l->occluders, nl = l->lights, ng = 0;
    uint64_t *gone = malloc(((size_t)nocc + nl + 1) * sizeof *gone);
    if (!gone) {
        l->members = doomed;
        l->nmembers = l->members_cap = k;
        return scene_fail(err, VP_ERR_BUSY, UINT32_MAX, "out of memory for an unload");
    }
    hide(s, id, true);
    for (size_t i = 0; i < s->occluders.cap && nocc; i++)
        if (s->occluders.used[i] && ((const scene_occluder *)(uintptr_t)s->occluders.vals[i])->sublevel == id)
            gone[ng++] = s->occluders.keys[i];
    for (uint32_t g = 0; g < ng; g++) {
        uint64_t v;
        idmap_get(&s->occluders, gone[g], &v);
        scene_occluder *o = (scene_occluder *)(uintptr_t)v;
        if (o->h) cull_occluder_remove(s->world, o->h);
        idmap_del(&s->occluders, gone[g]);
        free(o->verts);
        free(o);
    }
    ng = 0;
    for (size_t i = 0; i < s->lights.cap && nl; i++)
        if (s->lights.used[i] && ((const scene_light *)(uintptr_t)s->lights.vals[i])->sublevel == id)
            gone[ng++] = s->lights.keys[i];
    for (uint32_t g = 0; g < ng; g++) {
        uint64_t v;
        idmap_get(&s->lights, gone[g], &v);
        free((void *)(uintptr_t)v);
        idmap_del(&s->lights, gone[g]);
    }
    free(gone);
    l->occluders = l->lights = 0;
    for (uint32_t c = l->class_base; c < (uint32_t)l->class_base + l->classes; c++) {
        scene_mesh *m = &s->meshes[c];
        if (m->pos) s->nmeshes--;
        scene_mesh_release(m);
        s->class_owner[c] = 0;
    }
    l->class_base = l->classes = 0;
    free(l->doomed);
    l->doomed = doomed;
    l->ndoomed = k;
    l->doomed_pos = 0;
    l->state = VP_SL_UNLOADING;
    s->unloading++;
    if (visible) {
        s->epoch++;
        s->ev_removed += *entities;
    }
    return VP_OK;
}

bool scene_sublevel_work(scene *s, uint32_t budget)
{
    for (uint32_t id = 1; id <= s->nsublevels && s->unloading; id++) {
        scene_sublevel *l = &s->sl[id];
        if (l->state != VP_SL_UNLOADING) continue;
        while (l->doomed_pos < l->ndoomed && budget) {
            uint64_t eid = l->doomed[l->doomed_pos++], h;
            cull_entity_desc d;
            /* removed, or moved away, since it joined: not ours */
            if (!idmap_get(&s->ids, eid, &h) || cull_entity_get(s->world, (cull_handle)h, &d) != CULL_OK ||
                d.sublevel != id)
                continue;
            scene_entity_gone(s, eid, (cull_handle)h, &d);
            budget--;
        }
        if (l->doomed_pos < l->ndoomed) return true;
        free(l->doomed);
        l->doomed = NULL;
        l->ndoomed = l->doomed_pos = 0;
        l->state = 0;
        hide(s, id, false);
        s->unloading--;
    }
    return s->unloading > 0;
}

const uint64_t *scene_visible(const scene *s, const uint64_t *only, uint64_t *buf)
{
    if (!s->nhidden && !only) return NULL;
    for (uint32_t i = 0; i < CULL_SUBLEVEL_WORDS; i++) buf[i] = ~s->hidden[i] & (only ? only[i] : ~0ull);
    return buf;
}
