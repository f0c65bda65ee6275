/*
 * destruct.c — destruction events (see scene.h, scene_destroy).
 *
 * An entity hit by DESTROY gets a distance volume (culling/cull_dvol: the
 * signed distance to its sphere set on an n^3 grid over its box), kept
 * until the entity goes. If an occluder has the entity's id (the demo
 * city's buildings, an imported entity's OCC_ node), its triangles as sent
 * are cut again with the whole sphere set (cull_occ_cut, widened by
 * vt_mask_margin: the volume's bound plus the renderers' detail amplitude,
 * so the occluder's hole holds every point the renderers may draw as
 * destroyed) and the culling world's copy replaced: the next query
 * sees through the hole. The cut is a cache of (triangles as sent, sphere
 * set): an OCCLUDER_PUT of that id is cut the same way before it is drawn.
 *
 * Entities with a transform: the spheres are also kept in the entity's
 * local space (scene_destruct.local), and a move rebuilds the volume from
 * them under the new transform, radius times the largest |scale| (a
 * bigger hole is the safe side: the occluder hides less). An attached
 * occluder (VP_OCC_ATTACHED) is drawn as its local triangles under the
 * entity's transform, cut the same way, again on every move.
 */
#include "scene.h"
#include "errmap.h"
#include "log.h"
#include "vt_mask.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define CUT_MIN_EDGE 0.25      /* metres: the smallest pieces around a hole's rim are at least this */
#define CUT_MAX_PIECES 65536u  /* past this an occluder is dropped whole (safe: it hides less); it
                                  also bounds a cut's work (cull_occ_cut): 65536 * 512 piece-sphere
                                  tests, about 0.6 s, for any DESTROY or OCCLUDER_PUT */
#define DEBRIS_ID_BASE (1ull << 62)
#define SLOT(h) ((h) & (CULL_MAX_ENTITIES - 1u))

const scene_destruct *scene_destruct_of(const scene *s, uint64_t id)
{
    uint64_t v;
    return s->destruct.count && idmap_get(&s->destruct, id, &v) ? (const scene_destruct *)(uintptr_t)v : NULL;
}

void scene_destruct_forget(scene *s, uint64_t id)
{
    uint64_t v;
    if (!s->destruct.count || !idmap_get(&s->destruct, id, &v)) return;
    scene_destruct *d = (scene_destruct *)(uintptr_t)v;
    cull_dvol_free(&d->v);
    free(d->local);
    free(d);
    idmap_del(&s->destruct, id);
}

void scene_destruct_moved(scene *s, uint64_t id, const cull_entity_desc *from, const cull_entity_desc *to)
{
    uint64_t v;
    if (!s->destruct.count || !idmap_get(&s->destruct, id, &v)) return;
    if (!memcmp(from->aabb_min, to->aabb_min, sizeof to->aabb_min) &&
        !memcmp(from->aabb_max, to->aabb_max, sizeof to->aabb_max))
        return;
    /* the damage moves with the entity: its spheres by the box's corner,
       and the volume with them (only a resized box samples it again) */
    scene_destruct *d = (scene_destruct *)(uintptr_t)v;
    bool same_size = true;
    for (int a = 0; a < 3; a++)
        same_size &= to->aabb_max[a] - to->aabb_min[a] == from->aabb_max[a] - from->aabb_min[a];
    if (same_size) {
        for (int a = 0; a < 3; a++) {
            double t = to->aabb_min[a] - from->aabb_min[a];
            d->v.origin[a] += t;
            for (uint32_t k = 0; k < d->v.nsph; k++) d->v.sph[k][a] += t;
        }
        d->v.version++;
        return;
    }
    cull_dvol nv;
    uint32_t res = d->v.n[0] > d->v.n[1] ? d->v.n[0] : d->v.n[1];
    res = res > d->v.n[2] ? res : d->v.n[2];
    if (cull_dvol_init(&nv, to->aabb_min, to->aabb_max, res) != CULL_OK) {
        LOGW("entity %llu moved: its destruction could not follow (out of memory), dropped", (unsigned long long)id);
        scene_destruct_forget(s, id);
        return;
    }
    for (uint32_t k = 0; k < d->v.nsph; k++) {
        double c[3];
        for (int a = 0; a < 3; a++) c[a] = d->v.sph[k][a] + (to->aabb_min[a] - from->aabb_min[a]);
        cull_dvol_add_sphere(&nv, c, d->v.sph[k][3]);
    }
    cull_dvol_free(&d->v);
    d->v = nv;
}

/* d's volume rebuilt over the entity's new box `to` from its local spheres
 * under transform x. false (d unchanged): out of memory, or a sphere the
 * volume refuses (beyond the world's range). */
static bool rebuild_local(scene_destruct *d, const scene_xform *x, const cull_entity_desc *to)
{
    double smax = fmax(fabs(x->scale[0]), fmax(fabs(x->scale[1]), fabs(x->scale[2])));
    uint32_t res = d->v.n[0] > d->v.n[1] ? d->v.n[0] : d->v.n[1];
    res = res > d->v.n[2] ? res : d->v.n[2];
    cull_dvol nv;
    if (cull_dvol_init(&nv, to->aabb_min, to->aabb_max, res) != CULL_OK) return false;
    for (uint32_t k = 0; k < d->v.nsph; k++) {
        double c[3];
        scene_xform_apply(x, d->local[k], c);
        if (cull_dvol_add_sphere(&nv, c, fmin(d->local[k][3] * smax, CULL_MAX_RADIUS)) != CULL_OK) {
            cull_dvol_free(&nv);
            return false;
        }
    }
    nv.version = d->v.version + 1;
    cull_dvol_free(&d->v);
    d->v = nv;
    return true;
}

void scene_destruct_follow(scene *s, uint64_t id, const scene_xform *x, const cull_entity_desc *from,
                           const cull_entity_desc *to)
{
    uint64_t v;
    bool lost = false;
    if (s->destruct.count && idmap_get(&s->destruct, id, &v)) {
        scene_destruct *d = (scene_destruct *)(uintptr_t)v;
        if (d->local && !(x->flags & VP_ENT_TRANSFORM)) { /* a bounds entity now: its box carries it */
            free(d->local);
            d->local = NULL;
        }
        if (!d->local) {
            scene_destruct_moved(s, id, from, to);
        } else if (!rebuild_local(d, x, to)) {
            LOGW("entity %llu moved: its destruction could not follow (out of memory or out of range), dropped",
                 (unsigned long long)id);
            scene_destruct_forget(s, id);
            lost = true;
        }
    }
    scene_occluder *o = scene_attached_occluder(s, id);
    if (!o) return;
    if (o->sublevel != to->sublevel) { /* it is in its entity's sub-level */
        s->sl[o->sublevel].occluders--;
        s->sl[to->sublevel].occluders++;
        o->sublevel = to->sublevel;
    }
    /* without its holes (lost) or on failure it goes from the world whole:
       an occluder drawn where its entity is no longer would hide what the
       entity no longer does; hiding less is always safe */
    int crc = lost ? CULL_ERR_NOMEM : scene_occluder_draw(s, o, NULL);
    if (crc) {
        LOGW("attached occluder %llu: cannot follow its entity (%s), taken out of the world until its next move",
             (unsigned long long)id, cull_strerror(crc));
        if (o->h) cull_occluder_remove(s->world, o->h);
        o->h = 0;
    }
}

void scene_destruct_free_all(scene *s)
{
    for (size_t i = 0; i < s->destruct.cap; i++) {
        if (!s->destruct.used[i]) continue;
        scene_destruct *d = (scene_destruct *)(uintptr_t)s->destruct.vals[i];
        cull_dvol_free(&d->v);
        free(d->local);
        free(d);
    }
    idmap_free(&s->destruct);
}

static int occluder_draw(scene *s, scene_occluder *o, uint32_t *kept);

/* d (o's triangles as sent) with the holes of v cut in: *pieces
 * (malloc'ed, or NULL when nothing is cut) holds what d then points to. */
static int occluder_cut(const scene_occluder *o, const cull_dvol *v, cull_occluder_desc *d, float **pieces)
{
    *pieces = NULL;
    if (!v || !v->nsph) return CULL_OK;
    /* pieces around a rim about a tenth of the smallest widened radius (at
       least CUT_MIN_EDGE): some 60 a hole, whatever its size */
    double margin = vt_mask_margin(v), rmin = INFINITY;
    for (uint32_t k = 0; k < v->nsph; k++) rmin = fmin(rmin, v->sph[k][3] + margin);
    double edge = fmax(CUT_MIN_EDGE, 0.1 * rmin);
    uint32_t n;
    int rc = cull_occ_cut(o->verts, o->ntris, o->origin, v, margin, edge, CUT_MAX_PIECES, pieces, NULL, &n);
    if (rc == CULL_ERR_CAPACITY) {
        LOGW("occluder cut: more than %u pieces or %llu piece-sphere tests (%u triangles, %u spheres), the "
             "occluder is dropped whole",
             CUT_MAX_PIECES, (unsigned long long)CUT_MAX_PIECES * CULL_CUT_WORK_PER_PIECE, o->ntris, v->nsph);
        n = 0;
        rc = CULL_OK;
    }
    if (rc) return rc;
    d->vertices = *pieces;
    d->vertex_count = 3 * n;
    return CULL_OK;
}

/* An attached occluder in world space: *w is o with its triangles under
 * its entity's transform (in double, stored as floats relative to the
 * entity's position: *verts, malloc'ed) and origin that position. A
 * mirroring transform (negative determinant) reverses each triangle's
 * corners, so front faces still look out of the solid: the rasterizer
 * draws front faces only, and a mirrored shell drawn as sent would hide
 * what stands inside it. */
static int attached_world(const scene *s, const scene_occluder *o, scene_occluder *w, float **verts)
{
    uint64_t h;
    *w = *o;
    *verts = NULL;
    if (!idmap_get(&s->ids, o->id, &h)) return CULL_ERR_HANDLE; /* (checked at OCCLUDER_PUT; the entity owns it) */
    scene_xform x = s->xf[SLOT(h)];
    memcpy(w->origin, x.pos, sizeof w->origin);
    memset(x.pos, 0, sizeof x.pos);
    float *v = malloc((size_t)o->ntris * 36 + 1);
    if (!v) return CULL_ERR_NOMEM;
    bool flip = (double)x.scale[0] * x.scale[1] * x.scale[2] < 0;
    for (uint32_t t = 0; t < o->ntris; t++)
        for (int c = 0; c < 3; c++) {
            const float *p = &o->verts[9 * t + 3 * c];
            double l[3] = {o->origin[0] + p[0], o->origin[1] + p[1], o->origin[2] + p[2]}, g[3];
            scene_xform_apply(&x, l, g);
            int k = flip && c ? 3 - c : c;
            for (int a = 0; a < 3; a++) v[9 * t + 3 * k + a] = (float)g[a];
        }
    w->verts = *verts = v;
    return CULL_OK;
}

int scene_occluder_draw(scene *s, scene_occluder *o, uint32_t *kept)
{
    float *world = NULL;
    scene_occluder wo;
    if (o->flags & VP_OCC_ATTACHED) {
        int rc = attached_world(s, o, &wo, &world);
        if (rc) return rc;
    }
    int rc = occluder_draw(s, world ? &wo : o, kept);
    o->h = world ? wo.h : o->h;
    free(world);
    return rc;
}

/* scene_occluder_draw of an occluder in world space. */
static int occluder_draw(scene *s, scene_occluder *o, uint32_t *kept)
{
    const scene_destruct *sd = scene_destruct_of(s, o->id);
    /* cut open: the far walls' insides, seen through a hole, hide what is
       behind them (a 5 m hole in demo building 103 showed 44 entities
       behind its intact back wall) */
    cull_occluder_desc d = {.vertices = o->verts, .vertex_count = 3 * o->ntris, .sublevel = o->sublevel,
                            .flags = sd ? CULL_OCC_TWO_SIDED : 0};
    d.transform[0] = d.transform[5] = d.transform[10] = d.transform[15] = 1;
    memcpy(d.transform + 12, o->origin, sizeof o->origin);
    float *pieces;
    int rc = occluder_cut(o, sd ? &sd->v : NULL, &d, &pieces);
    if (rc) return rc;
    if (!d.vertex_count) {
        if (o->h) rc = cull_occluder_remove(s->world, o->h);
        if (!rc) o->h = 0;
    } else if (o->h) {
        rc = cull_occluder_update(s->world, o->h, &d);
    } else {
        rc = cull_occluder_add(s->world, &d, &o->h);
    }
    free(pieces);
    if (kept) *kept = d.vertex_count / 3;
    return rc;
}

static int spawn_debris(scene *s, const vp_destroy *m, uint16_t sub, uint32_t nsph, scene_err *err)
{
    uint32_t n = m->debris;
    size_t len = VP_HEADER_SIZE + 4 + (size_t)n * VP_ENTITY_REC_SIZE;
    uint8_t *buf = malloc(len);
    vp_entity *e = calloc(n, sizeof *e);
    uint32_t *h = malloc(n * sizeof *h);
    int rc = VP_OK;
    if (!buf || !e || !h) {
        rc = scene_fail(err, VP_ERR_BUSY, UINT32_MAX, "out of memory for debris");
        goto out;
    }
    uint64_t st = m->id * 31 + nsph, next = s->debris_next;
    /* thrown out of the sphere, then fallen to rest (debris.c) */
    double c[VP_MAX_DEBRIS][3] = {{0}}, half[VP_MAX_DEBRIS] = {0};
    for (uint32_t i = 0; i < n; i++) {
        double dir[3], l = 0;
        half[i] = 0.1 + 0.3 * scene_rand(&st);
        for (int a = 0; a < 3; a++) {
            dir[a] = scene_rand(&st) * 2 - 1;
            l += dir[a] * dir[a];
        }
        l = l > 1e-12 ? sqrt(l) : 1;
        double dist = m->radius * (1 + 0.5 * scene_rand(&st));
        for (int a = 0; a < 3; a++) c[i][a] = m->center[a] + dir[a] / l * dist;
    }
    if ((rc = scene_debris_settle(s, n, c, half, err))) goto out;
    for (uint32_t i = 0; i < n; i++) {
        while (idmap_get(&s->ids, DEBRIS_ID_BASE + next, NULL)) next++; /* an editor's id there: skip it */
        e[i] = (vp_entity){.id = DEBRIS_ID_BASE + next++, .sublevel = sub, .flags = VP_ENT_DYNAMIC};
        for (int a = 0; a < 3; a++) {
            e[i].aabb[a] = c[i][a] - half[i];
            e[i].aabb[3 + a] = c[i][a] + half[i];
        }
    }
    vp_writer w;
    vp_writer_init(&w, buf, len);
    vp_enc_entities(&w, VP_ENTITY_ADD, 0, e, n);
    vp_entity_batch b;
    if (vp_dec_entities(buf + VP_HEADER_SIZE, w.len - VP_HEADER_SIZE, 0, &b)) {
        rc = scene_fail(err, VP_ERR_INTERNAL, UINT32_MAX, "debris records");
        goto out;
    }
    if ((rc = scene_add(s, 0, &b, h, err)) == VP_OK) s->debris_next = next;
out:
    free(buf);
    free(e);
    free(h);
    return rc;
}

/* Why cull_dvol_add_sphere refused m's sphere, naming the field, its
 * value and the bound it broke (its checks, in its order). */
static int sphere_refused(scene_err *err, int crc, const vp_destroy *m)
{
    static const char axis[3] = {'x', 'y', 'z'};
    int code = vp_code_from_cull(crc);
    switch (crc) {
    case CULL_ERR_RADIUS:
        if (!isfinite(m->radius)) break;
        if (!(m->radius > 0))
            return scene_fail(err, code, UINT32_MAX, "destruction sphere: radius %g m is not > 0", m->radius);
        return scene_fail(err, code, UINT32_MAX, "destruction sphere: radius %g m is larger than the limit %g m",
                          m->radius, (double)CULL_MAX_RADIUS);
    case CULL_ERR_RANGE:
        for (int a = 0; a < 3; a++)
            if (fabs(m->center[a]) > CULL_MAX_COORD)
                return scene_fail(err, code, UINT32_MAX,
                                  "destruction sphere: centre %c is %g m, beyond the world's +-%g m", axis[a],
                                  m->center[a], (double)CULL_MAX_COORD);
        break;
    case CULL_ERR_CAPACITY:
        return scene_fail(err, code, UINT32_MAX, "destruction sphere: the entity already has %u spheres, the limit",
                          CULL_DVOL_MAX_SPHERES);
    default: break;
    }
    return scene_fail(err, code, UINT32_MAX, "destruction sphere: %s", cull_strerror(crc));
}

/* A sphere must touch the entity it destroys (its centre at most radius
 * from the entity's box) and be at most the box's diagonal in radius: one
 * that size centred anywhere on the box covers all of it, so a larger one
 * cuts nothing more and only throws its debris farther (a radius of 1e9
 * erased a building and left its debris in mid-air; a sphere 1 km away
 * was taken silently). Values the sphere's own checks refuse (non-finite,
 * out of the world, radius <= 0 or past CULL_MAX_RADIUS) are left to them,
 * so each message names its own cause. */
static int sphere_fits_entity(const cull_entity_desc *e, const vp_destroy *m, scene_err *err)
{
    double r = m->radius, d2 = 0, diag2 = 0;
    if (!(r > 0 && r <= CULL_MAX_RADIUS)) return VP_OK;
    for (int a = 0; a < 3; a++) {
        if (!(fabs(m->center[a]) <= CULL_MAX_COORD)) return VP_OK;
        double lo = e->aabb_min[a], hi = e->aabb_max[a], c = m->center[a];
        double out = c < lo ? lo - c : c > hi ? c - hi : 0;
        d2 += out * out;
        diag2 += (hi - lo) * (hi - lo);
    }
    if (d2 > r * r)
        return scene_fail(err, VP_ERR_INVALID, UINT32_MAX,
                          "destruction sphere (radius %g m) does not touch entity %llu: its centre is %g m from the "
                          "entity's bounds",
                          r, (unsigned long long)m->id, sqrt(d2));
    if (r * r > diag2)
        return scene_fail(err, VP_ERR_INVALID, UINT32_MAX,
                          "destruction sphere: radius %g m is larger than entity %llu's diagonal, %g m (a sphere that "
                          "size already covers all of it)",
                          r, (unsigned long long)m->id, sqrt(diag2));
    return VP_OK;
}

int scene_destroy(scene *s, const vp_destroy *m, uint32_t res, vp_destroyed *out, scene_err *err)
{
    uint64_t hv;
    memset(out, 0, sizeof *out);
    if (!idmap_get(&s->ids, m->id, &hv))
        return scene_fail(err, VP_ERR_UNKNOWN_ID, UINT32_MAX, "no entity with id %llu", (unsigned long long)m->id);
    cull_handle h = (cull_handle)hv;
    if (m->handle && m->handle != h)
        return scene_fail(err, VP_ERR_STALE, UINT32_MAX, "handle %u is not entity %llu's (%u)", m->handle,
                          (unsigned long long)m->id, h);
    cull_entity_desc e;
    cull_entity_get(s->world, h, &e);
    /* records acknowledged by older daemons, which took any sphere, replay */
    int rc = s->replaying ? VP_OK : sphere_fits_entity(&e, m, err);
    if (rc) return rc;
    uint16_t sub = e.sublevel;
    if ((rc = scene_sublevel_target(s, 0, &sub, UINT32_MAX, err))) return rc;
    if (m->debris && s->ids.count + m->debris > s->lim.max_entities)
        return scene_fail(err, VP_ERR_LIMIT, UINT32_MAX, "no room for %u debris entities", m->debris);
    /* the volume: made over the entity's box on its first destruction */
    uint64_t dv;
    scene_destruct *d = NULL;
    bool fresh = !idmap_get(&s->destruct, m->id, &dv);
    if (fresh) {
        if (!idmap_reserve(&s->destruct, s->destruct.count + 1) || !(d = calloc(1, sizeof *d)))
            return scene_fail(err, VP_ERR_BUSY, UINT32_MAX, "out of memory for a distance volume");
        int crc = cull_dvol_init(&d->v, e.aabb_min, e.aabb_max, res);
        if (crc) {
            free(d);
            return scene_fail(err, vp_code_from_cull(crc), UINT32_MAX,
                              "distance volume: %s", cull_strerror(crc));
        }
    } else {
        d = (scene_destruct *)(uintptr_t)dv;
    }
    /* a transform entity's spheres are kept in its local space too (room
       made first: nothing to take back after the sphere is in) */
    const scene_xform *x = &s->xf[SLOT(h)];
    bool local = (x->flags & VP_ENT_TRANSFORM) && (fresh || d->local);
    double(*nl)[4] = local ? realloc(d->local, ((size_t)d->v.nsph + 1) * sizeof *nl) : NULL;
    if (local && !nl) {
        if (fresh) {
            cull_dvol_free(&d->v);
            free(d);
        }
        return scene_fail(err, VP_ERR_BUSY, UINT32_MAX, "out of memory for a destruction sphere");
    }
    if (nl) d->local = nl;
    int crc = cull_dvol_add_sphere(&d->v, m->center, m->radius);
    if (crc) {
        if (fresh) {
            cull_dvol_free(&d->v);
            free(d->local);
            free(d);
        }
        return sphere_refused(err, crc, m);
    }
    if (local) { /* the radius over the smallest non-zero |scale|: the local set holds the world sphere */
        double smin = INFINITY;
        for (int a = 0; a < 3; a++)
            if (x->scale[a] != 0) smin = fmin(smin, fabs(x->scale[a]));
        scene_xform_local(x, m->center, d->local[d->v.nsph - 1]);
        d->local[d->v.nsph - 1][3] = m->radius / smin;
    }
    /* debris now, so a failure can still take the sphere back */
    if (m->debris && (rc = spawn_debris(s, m, sub, d->v.nsph, err)) != VP_OK) {
        if (fresh) {
            cull_dvol_free(&d->v);
            free(d->local);
            free(d);
        } else {
            d->v.nsph--;
            cull_dvol_rebuild(&d->v);
        }
        return rc;
    }
    if (fresh) idmap_put(&s->destruct, m->id, (uint64_t)(uintptr_t)d);
    /* its occluder, cut again from the triangles as sent */
    uint64_t ov;
    if (idmap_get(&s->occluders, m->id, &ov)) {
        scene_occluder *o = (scene_occluder *)(uintptr_t)ov;
        uint32_t kept;
        crc = scene_occluder_draw(s, o, &kept);
        if (crc) {
            /* out of memory in the culling world: the occluder goes whole
               (hiding less is always safe) */
            LOGW("occluder %llu: cut failed (%s), removed", (unsigned long long)m->id, cull_strerror(crc));
            if (o->h) cull_occluder_remove(s->world, o->h);
            o->h = 0;
            kept = 0;
        }
        out->occluder_tris = kept;
    }
    out->spheres = d->v.nsph;
    out->debris = m->debris;
    if (!m->debris) s->epoch++; /* (debris came with an epoch of their own) */
    out->epoch = s->epoch;
    return VP_OK;
}
