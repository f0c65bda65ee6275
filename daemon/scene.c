/*
 * scene.c — see scene.h. Validation first (ids, handles, values through
 * cull_entity_check), then application; the only failure left after
 * validation is running out of memory, which is rolled back.
 */
#include "scene.h"
#include "errmap.h"
#include "log.h"
#include "vp_grow.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define SLOT(h) ((h) & (CULL_MAX_ENTITIES - 1u))

#include <stdarg.h>
int scene_fail(scene_err *e, int code, uint32_t index, const char *fmt, ...)
{
    e->code = code;
    e->index = index;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(e->msg, sizeof e->msg, fmt, ap);
    va_end(ap);
    return code;
}

int scene_init(scene *s, double cell_size, const scene_limits *lim)
{
    memset(s, 0, sizeof *s);
    s->lim = *lim;
    vp_env_default(&s->env);
    s->sl_entities = calloc(CULL_SUBLEVELS, sizeof *s->sl_entities);
    s->class_owner = calloc(65536, sizeof *s->class_owner);
    s->class_entities = calloc(65536, sizeof *s->class_entities);
    if (!s->sl_entities || !s->class_owner || !s->class_entities) {
        free(s->sl_entities);
        free(s->class_owner);
        free(s->class_entities);
        return CULL_ERR_NOMEM;
    }
    int rc = cull_world_create(&(cull_world_desc){.cell_size = cell_size, .max_entities = lim->max_entities},
                               &s->world);
    return rc ? rc : 0;
}

void scene_free(scene *s)
{
    cull_world_destroy(s->world);
    idmap_free(&s->ids);
    free(s->id_of_slot);
    for (uint32_t i = 0; i < 65536; i++) {
        if (!s->meshes[i].pos && !s->meshes[i].nrm && !s->meshes[i].idx) continue; /* 196k free(NULL): 0.6 ms */
        free(s->meshes[i].pos);
        free(s->meshes[i].nrm);
        free(s->meshes[i].idx);
    }
    for (size_t i = 0; i < s->occluders.cap; i++) {
        if (!s->occluders.used[i]) continue;
        scene_occluder *o = (scene_occluder *)(uintptr_t)s->occluders.vals[i];
        free(o->verts);
        free(o);
    }
    for (size_t i = 0; i < s->lights.cap; i++)
        if (s->lights.used[i]) free((void *)(uintptr_t)s->lights.vals[i]);
    idmap_free(&s->occluders);
    idmap_free(&s->lights);
    scene_destruct_free_all(s);
    scene_textures_free(s);
    for (uint32_t i = 1; i <= s->nsublevels; i++) {
        free(s->sl[i].name);
        free(s->sl[i].doomed);
        free(s->sl[i].members);
    }
    free(s->sl_entities);
    free(s->class_owner);
    free(s->class_entities);
    memset(s, 0, sizeof *s);
}

uint64_t scene_id_of(const scene *s, cull_handle h)
{
    uint32_t slot = SLOT(h);
    return slot < s->id_cap ? s->id_of_slot[slot] : 0;
}

static void to_desc(const vp_entity *e, cull_entity_desc *d)
{
    memset(d, 0, sizeof *d);
    for (int a = 0; a < 3; a++) {
        d->center[a] = e->sphere[a];
        d->aabb_min[a] = e->aabb[a];
        d->aabb_max[a] = e->aabb[3 + a];
    }
    d->radius = e->sphere[3];
    d->class_id = e->class_id;
    d->sublevel = e->sublevel;
    d->flags = (e->flags & VP_ENT_DYNAMIC) ? CULL_ENTITY_DYNAMIC : 0;
}

void scene_entity_record(const scene *s, cull_handle h, vp_entity *out)
{
    cull_entity_desc d;
    memset(out, 0, sizeof *out);
    if (cull_entity_get(s->world, h, &d)) return;
    out->id = scene_id_of(s, h);
    out->handle = h;
    out->class_id = d.class_id;
    out->sublevel = d.sublevel;
    out->flags = (d.flags & CULL_ENTITY_DYNAMIC) ? VP_ENT_DYNAMIC : 0;
    for (int a = 0; a < 3; a++) {
        out->sphere[a] = d.center[a];
        out->aabb[a] = d.aabb_min[a];
        out->aabb[3 + a] = d.aabb_max[a];
    }
    out->sphere[3] = d.radius;
}

static int cmp_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

/* Index of the first id that appears twice in ids[0..n) (in batch order
 * of its second appearance), or UINT32_MAX. */
static uint32_t first_duplicate(const uint64_t *ids, uint32_t n, bool *nomem)
{
    *nomem = false;
    if (n < 2) return UINT32_MAX;
    uint64_t *sorted = malloc((size_t)n * sizeof *sorted);
    if (!sorted) {
        *nomem = true;
        return UINT32_MAX;
    }
    memcpy(sorted, ids, (size_t)n * sizeof *sorted);
    qsort(sorted, n, sizeof *sorted, cmp_u64);
    uint64_t dup = 0;
    bool found = false;
    for (uint32_t i = 1; i < n && !found; i++)
        if (sorted[i] == sorted[i - 1]) dup = sorted[i], found = true;
    free(sorted);
    if (!found) return UINT32_MAX;
    bool seen = false;
    for (uint32_t i = 0; i < n; i++) {
        if (ids[i] != dup) continue;
        if (seen) return i;
        seen = true;
    }
    return UINT32_MAX;
}

static bool grow_id_of_slot(scene *s, uint32_t need)
{
    if (need <= s->id_cap) return true;
    uint32_t cap = (uint32_t)vp_grow_cap(s->id_cap, need, 1024, sizeof(uint64_t), (size_t)1 << 31);
    uint64_t *n = cap ? realloc(s->id_of_slot, (size_t)cap * sizeof *n) : NULL;
    if (!n) return false;
    memset(n + s->id_cap, 0, (size_t)(cap - s->id_cap) * sizeof *n);
    s->id_of_slot = n;
    s->id_cap = cap;
    return true;
}

/* Record i of a batch as a normalised culling desc, or an error. */
static int record_desc(const scene *s, const vp_entity_batch *b, uint32_t i, vp_entity *e, cull_entity_desc *out,
                       scene_err *err)
{
    int rc = vp_entity_get(b, i, e);
    if (rc) return scene_fail(err, rc, i, "record %u: %s", i, vp_strerror(rc));
    cull_entity_desc d;
    to_desc(e, &d);
    int crc = cull_entity_check(s->world, &d, out);
    if (crc)
        return scene_fail(err, vp_code_from_cull(crc), i, "record %u (id %llu): %s", i, (unsigned long long)e->id,
                          cull_strerror(crc));
    return VP_OK;
}

/* VP_OK when no id appears twice in ids[0..n), else the error. */
static int check_unique(const uint64_t *ids, uint32_t n, scene_err *err)
{
    bool nomem;
    uint32_t dup = first_duplicate(ids, n, &nomem);
    if (nomem) return scene_fail(err, VP_ERR_BUSY, UINT32_MAX, "out of memory checking ids");
    if (dup != UINT32_MAX)
        return scene_fail(err, VP_ERR_DUPLICATE, dup, "record %u: id %llu twice in the batch", dup,
                    (unsigned long long)ids[dup]);
    return VP_OK;
}

void scene_entity_gone(scene *s, uint64_t id, cull_handle h, const cull_entity_desc *d)
{
    cull_entity_remove(s->world, h);
    idmap_del(&s->ids, id);
    s->id_of_slot[SLOT(h)] = 0;
    s->sl_entities[d->sublevel]--;
    s->class_entities[d->class_id]--;
    scene_destruct_forget(s, id);
}

/* The end of an applied edit of n records, `seen` of them in visible
 * sub-levels: only what queries can see moves the epoch and the events
 * (a load's hidden batches do not; its commit does, once). */
static void edit_done(scene *s, uint32_t n, uint32_t seen, uint32_t *ev)
{
    s->edits += n;
    if (!seen) return;
    s->epoch++;
    *ev += seen;
}

/* scene_add, or with `at` the restore of a snapshot: handles[] are given
 * (slots the world has reserved) instead of handed out. */
static int add_batch(scene *s, uint16_t loading, const vp_entity_batch *b, uint32_t *handles, bool at, scene_err *err)
{
    uint32_t n = b->count;
    cull_world_info info;
    cull_world_info_get(s->world, &info);
    if ((uint64_t)info.entities + n > s->lim.max_entities)
        return scene_fail(err, VP_ERR_LIMIT, UINT32_MAX, "scene holds %u entities, limit %u", info.entities,
                    s->lim.max_entities);
    uint64_t *ids = calloc((size_t)n + 1, sizeof *ids);
    cull_entity_desc *descs = malloc(((size_t)n + 1) * sizeof *descs);
    if (!ids || !descs) {
        free(ids);
        free(descs);
        return scene_fail(err, VP_ERR_BUSY, UINT32_MAX, "out of memory for a batch of %u", n);
    }
    int rc = VP_OK;
    for (uint32_t i = 0; i < n; i++) {
        vp_entity e;
        if ((rc = record_desc(s, b, i, &e, &descs[i], err))) goto out;
        if ((rc = scene_sublevel_target(s, loading, &descs[i].sublevel, i, err))) goto out;
        ids[i] = e.id;
        if (idmap_get(&s->ids, e.id, NULL)) {
            rc = scene_fail(err, VP_ERR_DUPLICATE, i, "record %u: id %llu already exists", i, (unsigned long long)e.id);
            goto out;
        }
    }
    if ((rc = check_unique(ids, n, err))) goto out;
    /* room in the id map only for a batch that is going in: a rejected one
       must not rehash it (ENTITY_LIST cursors are slots) */
    if (!scene_members_reserve(s, descs, n) || !idmap_reserve(&s->ids, s->ids.count + n)) {
        rc = scene_fail(err, VP_ERR_BUSY, UINT32_MAX, "out of memory for a batch of %u", n);
        goto out;
    }
    /* apply */
    for (uint32_t i = 0; i < n; i++) {
        cull_handle h = at ? handles[i] : 0;
        int crc = at ? cull_entity_add_at(s->world, &descs[i], h) : cull_entity_add(s->world, &descs[i], &h);
        if (!crc && !grow_id_of_slot(s, SLOT(h) + 1)) {
            cull_entity_remove(s->world, h);
            crc = CULL_ERR_NOMEM;
        }
        if (crc) {
            for (uint32_t k = 0; k < i; k++) scene_entity_gone(s, ids[k], handles[k], &descs[k]); /* roll back */
            rc = scene_fail(err, vp_code_from_cull(crc), i, "record %u: %s", i, cull_strerror(crc));
            goto out;
        }
        handles[i] = h;
        idmap_put(&s->ids, ids[i], h);
        s->id_of_slot[SLOT(h)] = ids[i];
        s->sl_entities[descs[i].sublevel]++;
        s->class_entities[descs[i].class_id]++;
        scene_members_add(s, descs[i].sublevel, ids[i]);
    }
    uint32_t seen = 0;
    for (uint32_t i = 0; i < n; i++) seen += !scene_sublevel_hidden(s, descs[i].sublevel);
    edit_done(s, n, seen, &s->ev_added);
out:
    free(ids);
    free(descs);
    return rc;
}

int scene_add(scene *s, uint16_t loading, const vp_entity_batch *b, uint32_t *handles, scene_err *err)
{
    return add_batch(s, loading, b, handles, false, err);
}

int scene_add_at(scene *s, const vp_entity_batch *b, const uint32_t *handles, scene_err *err)
{
    return add_batch(s, 0, b, (uint32_t *)handles, true, err);
}

int scene_update(scene *s, uint16_t loading, const vp_entity_batch *b, scene_err *err)
{
    uint32_t n = b->count;
    uint64_t *ids = calloc((size_t)n + 1, sizeof *ids);
    cull_handle *hs = malloc(((size_t)n + 1) * sizeof *hs);
    cull_entity_desc *descs = malloc(((size_t)n + 1) * sizeof *descs);
    cull_entity_desc *old = malloc(((size_t)n + 1) * sizeof *old);
    int rc = VP_OK;
    if (!ids || !hs || !descs || !old) {
        rc = scene_fail(err, VP_ERR_BUSY, UINT32_MAX, "out of memory for a batch of %u", n);
        goto out;
    }
    for (uint32_t i = 0; i < n; i++) {
        vp_entity e;
        if ((rc = record_desc(s, b, i, &e, &descs[i], err))) goto out;
        uint64_t h;
        if (!idmap_get(&s->ids, e.id, &h)) {
            rc = scene_fail(err, VP_ERR_UNKNOWN_ID, i, "record %u: no entity with id %llu", i, (unsigned long long)e.id);
            goto out;
        }
        if (e.handle && e.handle != (uint32_t)h) {
            rc = scene_fail(err, VP_ERR_STALE, i, "record %u: handle %u is not id %llu's (%u)", i, e.handle,
                      (unsigned long long)e.id, (uint32_t)h);
            goto out;
        }
        ids[i] = e.id;
        hs[i] = (cull_handle)h;
        cull_entity_get(s->world, hs[i], &old[i]);
        /* what it leaves and where it goes must be writable; and nothing
           moves into or out of a sub-level no query sees (it would appear
           or vanish on its own, before the commit or after the unload) */
        uint16_t from = old[i].sublevel, to = descs[i].sublevel;
        if ((rc = scene_sublevel_writable(s, loading, from, i, err)) || (rc = scene_sublevel_writable(s, loading, to, i, err)))
            goto out;
        if (from != to && (scene_sublevel_hidden(s, from) || scene_sublevel_hidden(s, to))) {
            rc = scene_fail(err, VP_ERR_STATE, i, "record %u: entity %llu cannot move between sub-levels %u and %u while "
                            "one is being loaded or unloaded", i, (unsigned long long)e.id, from, to);
            goto out;
        }
    }
    if ((rc = check_unique(ids, n, err))) goto out;
    if (!scene_members_reserve(s, descs, n)) {
        rc = scene_fail(err, VP_ERR_BUSY, UINT32_MAX, "out of memory for a batch of %u", n);
        goto out;
    }
    for (uint32_t i = 0; i < n; i++) {
        int crc = cull_entity_update(s->world, hs[i], &descs[i]);
        if (crc) {
            for (uint32_t k = 0; k < i; k++) cull_entity_update(s->world, hs[k], &old[k]);
            rc = scene_fail(err, vp_code_from_cull(crc), i, "record %u: %s", i, cull_strerror(crc));
            goto out;
        }
    }
    for (uint32_t i = 0; i < n; i++) {
        s->sl_entities[old[i].sublevel]--;
        s->sl_entities[descs[i].sublevel]++;
        s->class_entities[old[i].class_id]--;
        s->class_entities[descs[i].class_id]++;
        if (old[i].sublevel != descs[i].sublevel) scene_members_add(s, descs[i].sublevel, ids[i]);
        scene_destruct_moved(s, ids[i], &old[i], &descs[i]);
    }
    uint32_t seen = 0;
    for (uint32_t i = 0; i < n; i++) seen += !scene_sublevel_hidden(s, descs[i].sublevel);
    edit_done(s, n, seen, &s->ev_updated);
out:
    free(ids);
    free(hs);
    free(descs);
    free(old);
    return rc;
}

int scene_remove(scene *s, uint16_t loading, const vp_id_batch *b, scene_err *err)
{
    uint32_t n = b->count, seen = 0;
    uint64_t *ids = calloc((size_t)n + 1, sizeof *ids);
    if (!ids) return scene_fail(err, VP_ERR_BUSY, UINT32_MAX, "out of memory for a batch of %u", n);
    int rc = VP_OK;
    for (uint32_t i = 0; i < n; i++) {
        ids[i] = vp_id_get(b, i);
        uint64_t h;
        cull_entity_desc d;
        if (!idmap_get(&s->ids, ids[i], &h)) {
            rc = scene_fail(err, VP_ERR_UNKNOWN_ID, i, "record %u: no entity with id %llu", i, (unsigned long long)ids[i]);
            goto out;
        }
        cull_entity_get(s->world, (cull_handle)h, &d);
        if ((rc = scene_sublevel_writable(s, loading, d.sublevel, i, err))) goto out;
        seen += !scene_sublevel_hidden(s, d.sublevel);
    }
    if ((rc = check_unique(ids, n, err))) goto out;
    for (uint32_t i = 0; i < n; i++) { /* removal cannot fail once validated */
        uint64_t h;
        cull_entity_desc d;
        idmap_get(&s->ids, ids[i], &h);
        cull_entity_get(s->world, (cull_handle)h, &d);
        scene_entity_gone(s, ids[i], (cull_handle)h, &d);
    }
    edit_done(s, n, seen, &s->ev_removed);
out:
    free(ids);
    return rc;
}

int scene_mesh_put(scene *s, uint16_t loading, const vp_mesh *m, scene_err *err)
{
    uint16_t owner = s->class_owner[m->class_id];
    if (owner && owner != loading)
        return scene_fail(err, VP_ERR_STATE, UINT32_MAX, "class %u is reserved for sub-level %s", m->class_id,
                          s->sl[owner].name ? s->sl[owner].name : "?");
    if (m->vertex_count > s->lim.max_mesh_verts)
        return scene_fail(err, VP_ERR_LIMIT, UINT32_MAX, "mesh of %u vertices, limit %u", m->vertex_count,
                    s->lim.max_mesh_verts);
    scene_mesh n = {.nv = m->vertex_count, .ni = m->index_count};
    n.pos = malloc((size_t)n.nv * 12 + 1);
    /* no normals on the wire (VP_MESH_NO_NORMALS): NULL, drawn flat */
    n.nrm = m->normals ? malloc((size_t)n.nv * 12 + 1) : NULL;
    n.idx = malloc((size_t)n.ni * 4 + 1);
    if (!n.pos || (m->normals && !n.nrm) || !n.idx) {
        free(n.pos);
        free(n.nrm);
        free(n.idx);
        return scene_fail(err, VP_ERR_BUSY, UINT32_MAX, "out of memory for a mesh");
    }
    vp_reader r;
    vp_reader_init(&r, m->positions, (size_t)n.nv * 12);
    for (uint32_t i = 0; i < 3 * n.nv; i++) n.pos[i] = vp_get_f32(&r);
    vp_reader_init(&r, m->normals, n.nrm ? (size_t)n.nv * 12 : 0);
    for (uint32_t i = 0; n.nrm && i < 3 * n.nv; i++) n.nrm[i] = vp_get_f32(&r);
    vp_reader_init(&r, m->indices, (size_t)n.ni * 4);
    for (uint32_t i = 0; i < n.ni; i++) n.idx[i] = vp_get_u32(&r);
    scene_mesh *slot = &s->meshes[m->class_id];
    if (!slot->pos) s->nmeshes++;
    free(slot->pos);
    free(slot->nrm);
    free(slot->idx);
    *slot = n;
    if (!owner || !scene_sublevel_hidden(s, owner)) s->epoch++; /* a hidden load's mesh shows at its commit */
    return VP_OK;
}

int scene_occluder_put(scene *s, uint16_t loading, const vp_occluder *o, scene_err *err)
{
    uint16_t sub = 0;
    int src = scene_sublevel_target(s, loading, &sub, UINT32_MAX, err);
    if (src) return src;
    /* the cost bound of one OCCLUDER_PUT: the build is O(n log n) in its
       triangles (cull_occluder.c), n at most the limit, and at most what
       the culling core takes as a triangle list (CULL_OCC_MAX_VERTICES / 3
       = 349,525 triangles: about 1.1 s of random soup on one core of the
       2-core test machine, 0.04 s of identical triangles) */
    uint32_t max_tris = s->lim.max_occluder_tris < CULL_OCC_MAX_VERTICES / 3 ? s->lim.max_occluder_tris
                                                                              : CULL_OCC_MAX_VERTICES / 3;
    if (o->tri_count > max_tris)
        return scene_fail(err, VP_ERR_LIMIT, UINT32_MAX, "occluder of %u triangles, limit %u", o->tri_count,
                          max_tris);
    uint64_t prev;
    bool exists = idmap_get(&s->occluders, o->id, &prev);
    if (exists && ((const scene_occluder *)(uintptr_t)prev)->sublevel != sub)
        return scene_fail(err, VP_ERR_STATE, UINT32_MAX, "occluder %llu belongs to another sub-level",
                          (unsigned long long)o->id);
    if (!exists && s->occluders.count >= s->lim.max_occluders)
        return scene_fail(err, VP_ERR_LIMIT, UINT32_MAX, "%zu occluders, limit %u", s->occluders.count,
                    s->lim.max_occluders);
    scene_occluder *n = malloc(sizeof *n);
    float *v = malloc((size_t)o->tri_count * 36 + 1);
    if (!n || !v || !idmap_reserve(&s->occluders, s->occluders.count + 1)) {
        free(n);
        free(v);
        return scene_fail(err, VP_ERR_BUSY, UINT32_MAX, "out of memory for an occluder");
    }
    memcpy(n->origin, o->origin, sizeof n->origin);
    n->ntris = o->tri_count;
    n->sublevel = sub;
    n->flags = o->flags;
    vp_reader r;
    vp_reader_init(&r, o->verts, (size_t)o->tri_count * 36);
    for (uint32_t i = 0; i < 9 * o->tri_count; i++) v[i] = vp_get_f32(&r);
    n->verts = v;
    n->id = o->id;
    /* the culling world draws it: added, or the old one's geometry replaced
       in place (failure-atomic: on error the old one stands) */
    scene_occluder *old = exists ? (scene_occluder *)(uintptr_t)prev : NULL;
    n->h = old ? old->h : 0;
    int crc = scene_occluder_draw(s, n, NULL);
    if (crc != CULL_OK) {
        free(n);
        free(v);
        return scene_fail(err, vp_code_from_cull(crc), UINT32_MAX, "occluder %llu: %s",
                          (unsigned long long)o->id, cull_strerror(crc));
    }
    if (old) {
        free(old->verts);
        free(old);
    }
    cull_occluder_info info;
    if (n->h && cull_occluder_get_info(s->world, n->h, &info) == CULL_OK && info.dropped)
        LOGW("occluder %llu: %u of %u triangles degenerate (zero area) or repeated, dropped", (unsigned long long)o->id,
             info.dropped, o->tri_count);
    idmap_put(&s->occluders, o->id, (uint64_t)(uintptr_t)n);
    if (!exists) s->sl[sub].occluders++;
    if (!scene_sublevel_hidden(s, sub)) s->epoch++;
    return VP_OK;
}

/* The sub-level of an occluder or light (values of either map). */
static uint16_t item_sublevel(const scene *s, const idmap *which, uint64_t v)
{
    return which == &s->occluders ? ((const scene_occluder *)(uintptr_t)v)->sublevel
                                  : ((const scene_light *)(uintptr_t)v)->sublevel;
}

int scene_remove_ids(scene *s, uint16_t loading, idmap *which, const vp_id_batch *b, scene_err *err)
{
    bool seen = false;
    for (uint32_t i = 0; i < b->count; i++) {
        uint64_t v;
        if (!idmap_get(which, vp_id_get(b, i), &v))
            return scene_fail(err, VP_ERR_UNKNOWN_ID, i, "record %u: no such id %llu", i,
                        (unsigned long long)vp_id_get(b, i));
        uint16_t sub = item_sublevel(s, which, v);
        int rc = scene_sublevel_writable(s, loading, sub, i, err);
        if (rc) return rc;
        seen |= !scene_sublevel_hidden(s, sub);
    }
    uint64_t *ids = malloc(((size_t)b->count + 1) * sizeof *ids);
    if (!ids) return scene_fail(err, VP_ERR_BUSY, UINT32_MAX, "out of memory");
    for (uint32_t i = 0; i < b->count; i++) ids[i] = vp_id_get(b, i);
    int rc = check_unique(ids, b->count, err);
    free(ids);
    if (rc) return rc;
    for (uint32_t i = 0; i < b->count; i++) {
        uint64_t v;
        idmap_get(which, vp_id_get(b, i), &v);
        scene_sublevel *l = &s->sl[item_sublevel(s, which, v)];
        if (which == &s->occluders) {
            scene_occluder *o = (scene_occluder *)(uintptr_t)v;
            if (o->h) cull_occluder_remove(s->world, o->h);
            free(o->verts);
            l->occluders--;
        } else {
            l->lights--;
        }
        free((void *)(uintptr_t)v);
        idmap_del(which, vp_id_get(b, i));
    }
    if (seen) s->epoch++;
    return VP_OK;
}

void scene_light_cull(const vp_light *l, cull_light *cl, double radiance[3])
{
    memset(cl, 0, sizeof *cl);
    memcpy(cl->pos, l->pos, sizeof l->pos);
    cl->radius = l->range;
    cl->type = l->kind == VP_LIGHT_SPOT ? CULL_LIGHT_SPOT : CULL_LIGHT_POINT;
    memcpy(cl->dir, l->dir, sizeof l->dir);
    cl->cos_outer = l->outer_cos;
    for (int a = 0; a < 3; a++) radiance[a] = (double)l->color[a] * l->intensity;
}

int scene_light_check(vp_light *l, char *why, size_t whylen)
{
    if (l->kind == VP_LIGHT_SPOT) {
        /* any finite non-zero float axis normalises exactly enough in
           double (its squares stay within 1e-90..1e78) */
        double n = 0;
        for (int a = 0; a < 3; a++) n += (double)l->dir[a] * l->dir[a];
        if (!(n > 0)) {
            if (why && whylen) snprintf(why, whylen, "spot direction is (0, 0, 0): it has no axis");
            return VP_ERR_INVALID;
        }
        n = sqrt(n);
        for (int a = 0; a < 3; a++) l->dir[a] = (float)(l->dir[a] / n);
    }
    cull_light cl;
    double rad[3];
    scene_light_cull(l, &cl, rad);
    int crc = cull_light_validate(&cl, rad, why, whylen);
    return vp_code_from_cull(crc);
}

bool scene_light_drawable(const vp_light *l)
{
    cull_light cl;
    double rad[3];
    scene_light_cull(l, &cl, rad);
    return cull_light_validate(&cl, rad, NULL, 0) == CULL_OK;
}

int scene_lights_put(scene *s, uint16_t loading, const uint8_t *recs, uint32_t n, scene_err *err)
{
    size_t fresh = 0;
    uint16_t sub = 0;
    int src = scene_sublevel_target(s, loading, &sub, UINT32_MAX, err);
    if (src) return src;
    uint64_t *ids = malloc(((size_t)n + 1) * sizeof *ids);
    if (!ids) return scene_fail(err, VP_ERR_BUSY, UINT32_MAX, "out of memory for lights");
    for (uint32_t i = 0; i < n; i++) {
        vp_light l;
        char why[120];
        int rc = vp_light_get(recs, n, i, &l);
        if (rc) vp_light_rec_check(recs, n, i, why, sizeof why);
        else if ((rc = scene_light_check(&l, why, sizeof why)) && s->replaying) {
            /* acknowledged before lights were checked: kept (a later
               record may name it), never drawn (scene_light_drawable) */
            LOGW("light %llu replayed as acknowledged but not drawn: %s", (unsigned long long)l.id, why);
            rc = VP_OK;
        }
        if (rc) {
            free(ids);
            return scene_fail(err, rc, i, "record %u: %s", i, why);
        }
        uint64_t prev;
        ids[i] = l.id;
        if (!idmap_get(&s->lights, l.id, &prev)) fresh++;
        else if (((const scene_light *)(uintptr_t)prev)->sublevel != sub) {
            free(ids);
            return scene_fail(err, VP_ERR_STATE, i, "light %u: id %llu belongs to another sub-level", i,
                              (unsigned long long)l.id);
        }
    }
    int urc = check_unique(ids, n, err);
    free(ids);
    if (urc) return urc;
    if (s->lights.count + fresh > s->lim.max_lights)
        return scene_fail(err, VP_ERR_LIMIT, UINT32_MAX, "%zu lights, limit %u", s->lights.count + fresh,
                    s->lim.max_lights);
    scene_light **mem = calloc((size_t)n + 1, sizeof *mem);
    bool ok = mem && idmap_reserve(&s->lights, s->lights.count + n);
    for (uint32_t i = 0; ok && i < n; i++) ok = (mem[i] = malloc(sizeof **mem)) != NULL;
    if (!ok) {
        for (uint32_t i = 0; mem && i < n; i++) free(mem[i]);
        free(mem);
        return scene_fail(err, VP_ERR_BUSY, UINT32_MAX, "out of memory for lights");
    }
    for (uint32_t i = 0; i < n; i++) {
        vp_light_get(recs, n, i, &mem[i]->l);
        scene_light_check(&mem[i]->l, NULL, 0); /* stored with its spot axis normalised */
        mem[i]->sublevel = sub;
        uint64_t prev;
        if (idmap_get(&s->lights, mem[i]->l.id, &prev)) free((void *)(uintptr_t)prev);
        else s->sl[sub].lights++;
        idmap_put(&s->lights, mem[i]->l.id, (uint64_t)(uintptr_t)mem[i]);
    }
    free(mem);
    if (!scene_sublevel_hidden(s, sub)) s->epoch++;
    return VP_OK;
}

/* ---- the demo city ------------------------------------------------------------- */

static uint64_t demo_rng = 0x5EED2011;
static double drand(void)
{
    return scene_rand(&demo_rng);
}

/* 12 triangles of an axis-aligned box, counter-clockwise from outside,
 * relative to lo. */
static void box_tris(const double lo[3], const double hi[3], float *t)
{
    float X = (float)(hi[0] - lo[0]), Y = (float)(hi[1] - lo[1]), Z = (float)(hi[2] - lo[2]);
    const float c[8][3] = {{0, 0, 0}, {X, 0, 0}, {X, Y, 0}, {0, Y, 0}, {0, 0, Z}, {X, 0, Z}, {X, Y, Z}, {0, Y, Z}};
    static const int f[12][3] = {{0, 3, 2}, {0, 2, 1}, {4, 5, 6}, {4, 6, 7}, {0, 1, 5}, {0, 5, 4},
                                 {3, 7, 6}, {3, 6, 2}, {0, 4, 7}, {0, 7, 3}, {1, 2, 6}, {1, 6, 5}};
    for (int i = 0; i < 12; i++)
        for (int v = 0; v < 3; v++)
            for (int a = 0; a < 3; a++) t[i * 9 + v * 3 + a] = c[f[i][v]][a];
}

static int add_one(scene *s, uint64_t id, uint16_t cls, const double lo[3], const double hi[3], bool dynamic)
{
    uint8_t buf[VP_HEADER_SIZE + 4 + VP_ENTITY_REC_SIZE];
    vp_writer w;
    vp_writer_init(&w, buf, sizeof buf);
    vp_entity e = {.id = id, .class_id = cls, .flags = dynamic ? VP_ENT_DYNAMIC : 0};
    for (int a = 0; a < 3; a++) {
        e.aabb[a] = lo[a];
        e.aabb[3 + a] = hi[a];
    }
    vp_enc_entities(&w, VP_ENTITY_ADD, 0, &e, 1);
    vp_entity_batch b;
    if (vp_dec_entities(buf + VP_HEADER_SIZE, w.len - VP_HEADER_SIZE, 0, &b)) return -1;
    uint32_t h;
    scene_err err;
    return scene_add(s, 0, &b, &h, &err);
}

int scene_build_demo(scene *s, uint32_t props)
{
    demo_rng = 0x5EED2011;
    /* classes: 1 buildings, 2 props (their meshes arrive with the renderer) */
    uint64_t next_id = 1;
    const int blocks = 12;           /* 12 x 12 city blocks */
    const double block = 60, street = 16;
    for (int bx = 0; bx < blocks; bx++) {
        for (int bz = 0; bz < blocks; bz++) {
            double x0 = (bx - blocks / 2) * (block + street), z0 = (bz - blocks / 2) * (block + street);
            int nb = 1 + (int)(drand() * 3);
            for (int k = 0; k < nb; k++) {
                double w = 12 + drand() * 20, d = 12 + drand() * 20, h = 8 + drand() * drand() * 80;
                double lo[3] = {x0 + drand() * (block - w), 0, z0 + drand() * (block - d)};
                double hi[3] = {lo[0] + w, h, lo[2] + d};
                if (add_one(s, next_id++, 1, lo, hi, false)) return -1;
                float t[12 * 9];
                box_tris(lo, hi, t);
                uint8_t buf[VP_HEADER_SIZE + 40 + 12 * 36];
                vp_writer wr;
                vp_writer_init(&wr, buf, sizeof buf);
                vp_enc_occluder(&wr, 0, next_id - 1, lo, t, 12);
                vp_occluder o;
                scene_err err;
                if (vp_dec_occluder(buf + VP_HEADER_SIZE, wr.len - VP_HEADER_SIZE, 0, &o) ||
                    scene_occluder_put(s, 0, &o, &err))
                    return -1;
            }
        }
    }
    double span = blocks / 2.0 * (block + street);
    for (uint32_t i = 0; i < props; i++) {
        double r = 0.3 + drand() * 1.5;
        double c[3] = {(drand() * 2 - 1) * span, r, (drand() * 2 - 1) * span};
        double lo[3] = {c[0] - r, 0, c[2] - r}, hi[3] = {c[0] + r, 2 * r, c[2] + r};
        if (add_one(s, 1000000 + i, 2, lo, hi, i % 4 == 0)) return -1;
    }
    /* street lights */
    enum { NL = 64 };
    uint8_t lbuf[VP_HEADER_SIZE + 4 + NL * VP_LIGHT_SIZE];
    vp_light lights[NL];
    for (int i = 0; i < NL; i++) {
        lights[i] = (vp_light){.id = 1 + (uint64_t)i, .kind = VP_LIGHT_POINT, .intensity = 400, .range = 25,
                               .color = {1.0f, 0.85f, 0.6f}};
        lights[i].pos[0] = (drand() * 2 - 1) * span;
        lights[i].pos[1] = 6;
        lights[i].pos[2] = (drand() * 2 - 1) * span;
    }
    vp_writer wl;
    vp_writer_init(&wl, lbuf, sizeof lbuf);
    vp_enc_lights(&wl, 0, lights, NL);
    const uint8_t *recs;
    uint32_t n;
    scene_err err;
    if (vp_dec_lights(lbuf + VP_HEADER_SIZE, wl.len - VP_HEADER_SIZE, 0, &recs, &n) ||
        scene_lights_put(s, 0, recs, n, &err))
        return -1;
    cull_world_commit(s->world);
    s->ev_added = s->ev_updated = s->ev_removed = 0;
    return 0;
}
