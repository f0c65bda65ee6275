/*
 * transform.c — entities placed by a transform (VP_ENT_TRANSFORM): a class
 * mesh, a position (f64), a unit quaternion and a per-axis scale. What it
 * owns: the derivation of their culling bounds (cull_bounds_from_trs over
 * the class mesh's local box, computed once per MESH_PUT), TRANSFORM_SET,
 * and the re-derivation a new mesh forces on every entity of its class.
 *
 * Storage: s->xf, one scene_xform (64 bytes) per handle slot, grown with
 * s->id_of_slot; the culling world keeps only the derived bounds. Cost per
 * TRANSFORM_SET record: an id lookup, the derivation and the culling
 * world's update, 519-565 ns decoded, checked and applied against 491-525
 * for an ENTITY_UPDATE record (BENCHMARKS.md, "Transforms"). A new mesh
 * finds its class's entities by a pass over the handle slots (O(slots)).
 */
#include "scene.h"
#include "errmap.h"
#include "log.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define SLOT(h) ((h) & (CULL_MAX_ENTITIES - 1u))

void scene_mesh_bounds(scene_mesh *m)
{
    for (int a = 0; a < 3; a++) m->lo[a] = m->hi[a] = m->nv ? m->pos[a] : 0;
    for (uint32_t v = 1; v < m->nv; v++)
        for (int a = 0; a < 3; a++) {
            double p = m->pos[3 * v + a];
            m->lo[a] = p < m->lo[a] ? p : m->lo[a];
            m->hi[a] = p > m->hi[a] ? p : m->hi[a];
        }
}

void scene_mesh_release(scene_mesh *m)
{
    free(m->pos);
    free(m->nrm);
    free(m->uv);
    free(m->tan);
    free(m->idx);
    memset(m, 0, sizeof *m);
}

/* x's rotation as a matrix, R(q/|q|) formed as cull_bounds_from_trs forms it. */
static void rotation(const scene_xform *x, double r[3][3])
{
    double qx = x->rot[0], qy = x->rot[1], qz = x->rot[2], qw = x->rot[3];
    double s = 2 / (qx * qx + qy * qy + qz * qz + qw * qw);
    r[0][0] = 1 - s * (qy * qy + qz * qz), r[0][1] = s * (qx * qy - qz * qw), r[0][2] = s * (qx * qz + qy * qw);
    r[1][0] = s * (qx * qy + qz * qw), r[1][1] = 1 - s * (qx * qx + qz * qz), r[1][2] = s * (qy * qz - qx * qw);
    r[2][0] = s * (qx * qz - qy * qw), r[2][1] = s * (qy * qz + qx * qw), r[2][2] = 1 - s * (qx * qx + qy * qy);
}

void scene_xform_apply(const scene_xform *x, const double p[3], double out[3])
{
    double r[3][3];
    rotation(x, r);
    double q[3] = {p[0] * x->scale[0], p[1] * x->scale[1], p[2] * x->scale[2]};
    for (int a = 0; a < 3; a++) out[a] = x->pos[a] + r[a][0] * q[0] + r[a][1] * q[1] + r[a][2] * q[2];
}

void scene_xform_local(const scene_xform *x, const double p[3], double out[3])
{
    double r[3][3], d[3] = {p[0] - x->pos[0], p[1] - x->pos[1], p[2] - x->pos[2]};
    rotation(x, r);
    for (int a = 0; a < 3; a++) {
        double q = r[0][a] * d[0] + r[1][a] * d[1] + r[2][a] * d[2]; /* R^T d */
        out[a] = x->scale[a] != 0 ? q / x->scale[a] : 0;
    }
}

/* Bounds of class c's mesh under (pos, rot, scale) into d (class, sub-level
 * and flags kept), checked by the culling world; an error names record i. */
static int derive(const scene *s, uint16_t c, const double lo[3], const double hi[3], const double pos[3],
                  const float rot[4], const float scale[3], uint64_t id, uint32_t i, cull_entity_desc *d,
                  scene_err *err)
{
    cull_trs t;
    memcpy(t.pos, pos, sizeof t.pos);
    for (int a = 0; a < 4; a++) t.rot[a] = rot[a];
    memcpy(t.scale, scale, sizeof t.scale);
    char why[120];
    int crc = cull_bounds_from_trs(lo, hi, &t, d, why, sizeof why);
    if (!crc && (crc = cull_entity_check(s->world, d, d)))
        snprintf(why, sizeof why, "derived bounds: %s", cull_strerror(crc));
    if (!crc) return VP_OK;
    /* named as a record of the batch, or (a new mesh's check) as the entity */
    if (i == UINT32_MAX)
        return scene_fail(err, vp_code_from_cull(crc), i, "entity %llu (class %u): %s", (unsigned long long)id, c,
                          why);
    return scene_fail(err, vp_code_from_cull(crc), i, "record %u (id %llu, class %u): %s", i,
                      (unsigned long long)id, c, why);
}

int scene_entity_desc(const scene *s, const vp_entity *e, uint32_t i, cull_entity_desc *d, scene_err *err)
{
    if (e->material && !scene_material_find(s, e->material))
        return scene_fail(err, VP_ERR_UNKNOWN_ID, i, "record %u (id %llu): material %u does not exist", i,
                          (unsigned long long)e->id, e->material);
    memset(d, 0, sizeof *d);
    d->class_id = e->class_id;
    d->sublevel = e->sublevel;
    d->flags = (e->flags & VP_ENT_DYNAMIC) ? CULL_ENTITY_DYNAMIC : 0;
    if (e->flags & VP_ENT_TRANSFORM) {
        const scene_mesh *m = &s->meshes[e->class_id];
        if (!m->pos)
            return scene_fail(err, VP_ERR_UNKNOWN_ID, i, "record %u (id %llu): mesh class %u has no mesh", i,
                              (unsigned long long)e->id, e->class_id);
        return derive(s, e->class_id, m->lo, m->hi, e->pos, e->rot, e->scale, e->id, i, d, err);
    }
    for (int a = 0; a < 3; a++) {
        d->center[a] = e->sphere[a];
        d->aabb_min[a] = e->aabb[a];
        d->aabb_max[a] = e->aabb[3 + a];
    }
    d->radius = e->sphere[3];
    int crc = cull_entity_check(s->world, d, d);
    if (crc)
        return scene_fail(err, vp_code_from_cull(crc), i, "record %u (id %llu): %s", i, (unsigned long long)e->id,
                          cull_strerror(crc));
    return VP_OK;
}

scene_occluder *scene_attached_occluder(const scene *s, uint64_t id)
{
    uint64_t v;
    if (!s->occluders.count || !idmap_get(&s->occluders, id, &v)) return NULL;
    scene_occluder *o = (scene_occluder *)(uintptr_t)v;
    return (o->flags & VP_OCC_ATTACHED) ? o : NULL;
}

/* Handles, old and new bounds and the new transforms of a batch that
 * moves entities; applied in one pass (cull_entity_update per record,
 * rolled back on failure), then each entity's destruction and attached
 * occluder follow. */
typedef struct moves {
    uint32_t n;
    uint64_t *ids;
    cull_handle *hs;
    cull_entity_desc *from, *to;
    scene_xform *xf;
} moves;

static bool moves_alloc(moves *m, uint32_t n)
{
    memset(m, 0, sizeof *m);
    m->ids = malloc(((size_t)n + 1) * sizeof *m->ids);
    m->hs = malloc(((size_t)n + 1) * sizeof *m->hs);
    m->from = malloc(((size_t)n + 1) * sizeof *m->from);
    m->to = malloc(((size_t)n + 1) * sizeof *m->to);
    m->xf = malloc(((size_t)n + 1) * sizeof *m->xf);
    return m->ids && m->hs && m->from && m->to && m->xf;
}

static void moves_free(moves *m)
{
    free(m->ids);
    free(m->hs);
    free(m->from);
    free(m->to);
    free(m->xf);
}

int scene_moves_apply(scene *s, uint32_t n, const cull_handle *hs, const cull_entity_desc *from,
                      const cull_entity_desc *to, scene_err *err)
{
    for (uint32_t i = 0; i < n; i++) {
        int crc = cull_entity_update(s->world, hs[i], &to[i]);
        if (crc) {
            for (uint32_t k = 0; k < i; k++) cull_entity_update(s->world, hs[k], &from[k]);
            return scene_fail(err, vp_code_from_cull(crc), i, "record %u: %s", i, cull_strerror(crc));
        }
    }
    return VP_OK;
}

static int moves_apply(scene *s, const moves *m, scene_err *err)
{
    int rc = scene_moves_apply(s, m->n, m->hs, m->from, m->to, err);
    if (rc) return rc;
    bool follow = s->destruct.count || s->occluders.count;
    for (uint32_t i = 0; i < m->n; i++) {
        s->xf[SLOT(m->hs[i])] = m->xf[i];
        if (follow) scene_destruct_follow(s, m->ids[i], &m->xf[i], &m->from[i], &m->to[i]);
    }
    return VP_OK;
}

int scene_transform_set(scene *s, uint16_t loading, const vp_transform_batch *b, scene_err *err)
{
    moves m;
    int rc = VP_OK;
    if (!moves_alloc(&m, b->count)) {
        rc = scene_fail(err, VP_ERR_BUSY, UINT32_MAX, "out of memory for a batch of %u", b->count);
        goto out;
    }
    uint32_t seen = 0;
    for (uint32_t i = 0; i < b->count; i++) {
        vp_transform t;
        char why[120];
        if ((rc = vp_transform_get(b, i, &t))) {
            vp_transform_rec_check(b, i, why, sizeof why);
            rc = scene_fail(err, rc, i, "record %u: %s", i, why);
            goto out;
        }
        uint64_t h;
        if (!idmap_get(&s->ids, t.id, &h)) {
            rc = scene_fail(err, VP_ERR_UNKNOWN_ID, i, "record %u: no entity with id %llu", i,
                            (unsigned long long)t.id);
            goto out;
        }
        if (t.handle && t.handle != (uint32_t)h) {
            rc = scene_fail(err, VP_ERR_STALE, i, "record %u: handle %u is not id %llu's (%u)", i, t.handle,
                            (unsigned long long)t.id, (uint32_t)h);
            goto out;
        }
        const scene_xform *x = &s->xf[SLOT(h)];
        if (!(x->flags & VP_ENT_TRANSFORM)) {
            rc = scene_fail(err, VP_ERR_STATE, i, "record %u: entity %llu has no transform (added without "
                            "VP_ENT_TRANSFORM): move it with ENTITY_UPDATE", i, (unsigned long long)t.id);
            goto out;
        }
        m.ids[i] = t.id;
        m.hs[i] = (cull_handle)h;
        cull_entity_get(s->world, m.hs[i], &m.from[i]);
        if ((rc = scene_sublevel_writable(s, loading, m.from[i].sublevel, i, err))) goto out;
        const scene_mesh *mesh = &s->meshes[m.from[i].class_id];
        if (!mesh->pos) { /* its class's mesh went with an unloaded sub-level */
            rc = scene_fail(err, VP_ERR_STATE, i, "record %u (id %llu): mesh class %u has no mesh", i,
                            (unsigned long long)t.id, m.from[i].class_id);
            goto out;
        }
        m.to[i] = m.from[i];
        if ((rc = derive(s, m.from[i].class_id, mesh->lo, mesh->hi, t.pos, t.rot, t.scale, t.id, i, &m.to[i], err)))
            goto out;
        m.xf[i] = *x;
        memcpy(m.xf[i].pos, t.pos, sizeof t.pos);
        memcpy(m.xf[i].rot, t.rot, sizeof t.rot);
        memcpy(m.xf[i].scale, t.scale, sizeof t.scale);
        seen += !scene_sublevel_hidden(s, m.from[i].sublevel);
        m.n = i + 1;
    }
    if ((rc = scene_check_unique(m.ids, m.n, err)) || (rc = moves_apply(s, &m, err))) goto out;
    s->edits += m.n;
    if (seen) {
        s->epoch++;
        s->ev_updated += seen;
    }
out:
    moves_free(&m);
    return rc;
}

int scene_mesh_rederive(scene *s, uint16_t c, const double lo[3], const double hi[3], scene_err *err)
{
    uint32_t n = s->class_entities[c];
    if (!n) return VP_OK;
    moves m;
    int rc = VP_OK;
    if (!moves_alloc(&m, n)) {
        rc = scene_fail(err, VP_ERR_BUSY, UINT32_MAX, "out of memory for the %u entities of class %u", n, c);
        goto out;
    }
    /* the class's entities, found by slot (O(slots), once per mesh of a
       class that has entities) */
    for (uint32_t slot = 0; slot < s->id_cap && m.n < n; slot++) {
        uint64_t id = s->id_of_slot[slot], h;
        if (!id || !(s->xf[slot].flags & VP_ENT_TRANSFORM) || !idmap_get(&s->ids, id, &h)) continue;
        cull_entity_desc d;
        if (cull_entity_get(s->world, (cull_handle)h, &d) || d.class_id != c) continue;
        const scene_xform *x = &s->xf[slot];
        m.ids[m.n] = id;
        m.hs[m.n] = (cull_handle)h;
        m.from[m.n] = m.to[m.n] = d;
        m.xf[m.n] = *x;
        if ((rc = derive(s, c, lo, hi, x->pos, x->rot, x->scale, id, UINT32_MAX, &m.to[m.n], err))) {
            /* the mesh is refused: say which entity it would break */
            char msg[sizeof err->msg];
            snprintf(msg, sizeof msg, "%s", err->msg);
            rc = scene_fail(err, rc, UINT32_MAX, "mesh of class %u refused: %s", c, msg);
            goto out;
        }
        m.n++;
    }
    rc = moves_apply(s, &m, err);
out:
    moves_free(&m);
    return rc;
}
