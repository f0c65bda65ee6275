/*
 * vp_assets.c — the scene asset messages of the protocol (see protocol.h
 * and PROTOCOL.md): MESH_PUT, OCCLUDER_PUT and LIGHT_PUT with its light
 * records and their checks.
 */
#include "vp_internal.h"
#include "vp_layout.h"

#include <math.h>

/* ---- meshes ----------------------------------------------------------------------- */

/* MESH_PUT's fields before the arrays */
#define MESH_FIELDS(X) X(u16, class_id) X(u16, flags) X(u32, vertex_count) X(u32, index_count)
VP_LAYOUT(mesh, vp_mesh, MESH_FIELDS)

size_t vp_size_mesh(uint32_t nv, uint32_t ni, bool normals)
{
    return VP_HEADER_SIZE + mesh_size() + (size_t)nv * (normals ? 24 : 12) + (size_t)ni * 4;
}

/* nrm NULL: VP_MESH_NO_NORMALS and no normals block (drawn flat). */

void vp_enc_mesh(vp_writer *w, uint32_t req, uint16_t class_id, const float *pos, const float *nrm, uint32_t nv,
                 const uint32_t *idx, uint32_t ni)
{
    vp_frame_begin(w, VP_MESH_PUT, req);
    mesh_put(w, &(vp_mesh){.class_id = class_id, .flags = nrm ? 0 : VP_MESH_NO_NORMALS, .vertex_count = nv,
                           .index_count = ni});
    for (uint32_t i = 0; i < 3 * nv; i++) vp_put_f32(w, pos[i]);
    for (uint32_t i = 0; nrm && i < 3 * nv; i++) vp_put_f32(w, nrm[i]);
    for (uint32_t i = 0; i < ni; i++) vp_put_u32(w, idx[i]);
    vp_frame_end(w);
}

int vp_dec_mesh(const uint8_t *p, size_t len, uint32_t max_batch, vp_mesh *m)
{
    vp_reader r;
    int rc = mesh_head(&r, p, len, m);
    if (rc) return rc;
    if (m->flags & ~VP_MESH_NO_NORMALS) return VP_ERR_INVALID;
    if (m->index_count % 3) return VP_ERR_COUNT;
    bool normals = !(m->flags & VP_MESH_NO_NORMALS);
    m->normals = NULL;
    if ((rc = vp_take_array(&r, m->vertex_count, 12, max_batch, &m->positions)) ||
        (normals && (rc = vp_take_array(&r, m->vertex_count, 12, max_batch, &m->normals))) ||
        (rc = vp_take_array(&r, m->index_count, 4,
                         max_batch ? (uint32_t)(max_batch > UINT32_MAX / 3 ? UINT32_MAX : 3 * max_batch) : 0,
                         &m->indices)))
        return rc;
    if ((rc = vp_reader_finish(&r))) return rc == VP_ERR_TRAILING ? VP_ERR_COUNT : rc;
    for (uint32_t i = 0; i < 3 * m->vertex_count; i++) {
        float f[2] = {rdf32(m->positions + 4 * (size_t)i), normals ? rdf32(m->normals + 4 * (size_t)i) : 0};
        if (!vp_finite_nf(f, 2)) return VP_ERR_NONFINITE;
    }
    for (uint32_t i = 0; i < m->index_count; i++)
        if (rd32(m->indices + 4 * (size_t)i) >= m->vertex_count) return VP_ERR_INVALID;
    return VP_OK;
}

size_t vp_size_occluder(uint32_t ntris)
{
    return VP_HEADER_SIZE + 36 + (size_t)ntris * 36;
}

void vp_enc_occluder(vp_writer *w, uint32_t req, uint64_t id, const double origin[3], const float *verts,
                     uint32_t ntris)
{
    vp_frame_begin(w, VP_OCCLUDER_PUT, req);
    vp_put_u64(w, id);
    for (int k = 0; k < 3; k++) vp_put_f64(w, origin[k]);
    vp_put_u32(w, ntris);
    for (uint32_t i = 0; i < 9 * ntris; i++) vp_put_f32(w, verts[i]);
    vp_frame_end(w);
}

int vp_dec_occluder(const uint8_t *p, size_t len, uint32_t max_batch, vp_occluder *m)
{
    vp_reader r;
    vp_reader_init(&r, p, len);
    m->id = vp_get_u64(&r);
    for (int k = 0; k < 3; k++) m->origin[k] = vp_get_f64(&r);
    m->tri_count = vp_get_u32(&r);
    if (r.short_read) return VP_ERR_TRUNCATED;
    if (!vp_finite_n(m->origin, 3)) return VP_ERR_NONFINITE;
    int rc = vp_take_rest(&r, m->tri_count, 36, max_batch, &m->verts);
    if (rc) return rc;
    for (uint32_t i = 0; i < 9 * m->tri_count; i++) {
        float f = rdf32(m->verts + 4 * (size_t)i);
        if (!isfinite(f)) return VP_ERR_NONFINITE;
    }
    return VP_OK;
}

/* ---- lights ----------------------------------------------------------------------- */

/* One light record, VP_LIGHT_SIZE bytes (reserved bytes written 0, not read). */
#define LIGHT_FIELDS(X)                                                                                   \
    X(u64, id) X(u8, kind) X(rsv8, _) X(rsv16, _) X(f32, intensity) X(f64a, pos) X(f32a, dir)          \
    X(f32a, color) X(f32, range) X(f32, inner_cos) X(f32, outer_cos) X(rsv32, _)
VP_LAYOUT(light, vp_light, LIGHT_FIELDS)

size_t vp_size_lights(uint32_t n)
{
    return VP_HEADER_SIZE + 4 + (size_t)n * light_size();
}

void vp_enc_lights(vp_writer *w, uint32_t req, const vp_light *l, uint32_t n)
{
    vp_frame_begin(w, VP_LIGHT_PUT, req);
    vp_put_u32(w, n);
    for (uint32_t i = 0; i < n; i++) light_put(w, &l[i]);
    vp_frame_end(w);
}

/* Record i of recs, whose size the decoder checked. */
static void light_read(const uint8_t *recs, uint32_t i, vp_light *l)
{
    vp_reader r;
    vp_reader_init(&r, recs + (size_t)i * VP_LIGHT_SIZE, VP_LIGHT_SIZE);
    (void)light_get(&r, l);
}

/* A light record's own checks, the field and cause in why (may be NULL).
 * What a renderer can draw (position, range, colour and direction bounds)
 * is the culling module's cull_light_validate, which the daemon runs too. */
static int light_check(const vp_light *l, char *why, size_t whylen)
{
    static const char *const pname[3] = {"position x", "position y", "position z"};
    const struct { const char *name; float v; } f[] = {
        {"intensity", l->intensity}, {"direction x", l->dir[0]}, {"direction y", l->dir[1]},
        {"direction z", l->dir[2]},  {"colour r", l->color[0]},  {"colour g", l->color[1]},
        {"colour b", l->color[2]},   {"range", l->range},        {"inner cosine", l->inner_cos},
        {"outer cosine", l->outer_cos}};
    for (int k = 0; k < 3; k++)
        if (!isfinite(l->pos[k]))
            return vp_errf(why, whylen, VP_ERR_NONFINITE, "%s is %g: NaN or infinite", pname[k], l->pos[k]);
    for (size_t k = 0; k < sizeof f / sizeof f[0]; k++)
        if (!isfinite(f[k].v))
            return vp_errf(why, whylen, VP_ERR_NONFINITE, "%s is %g: NaN or infinite", f[k].name, (double)f[k].v);
    if (l->kind > VP_LIGHT_SPOT)
        return vp_errf(why, whylen, VP_ERR_INVALID, "kind %u is neither 0 (point) nor 1 (spot)", l->kind);
    if (!(l->range > 0)) return vp_errf(why, whylen, VP_ERR_INVALID, "range %g is not > 0", (double)l->range);
    if (l->intensity < 0)
        return vp_errf(why, whylen, VP_ERR_INVALID, "intensity %g is negative", (double)l->intensity);
    for (int k = 0; k < 3; k++)
        if (l->color[k] < 0)
            return vp_errf(why, whylen, VP_ERR_INVALID, "%s %g is negative", f[4 + k].name, (double)l->color[k]);
    if (l->kind == VP_LIGHT_SPOT && !(l->outer_cos <= l->inner_cos && l->outer_cos >= -1 && l->inner_cos <= 1))
        return vp_errf(why, whylen, VP_ERR_INVALID, "spot cone: need -1 <= outer cosine (%g) <= inner cosine (%g) <= 1",
                       (double)l->outer_cos, (double)l->inner_cos);
    return VP_OK;
}

int vp_light_rec_check(const uint8_t *recs, uint32_t n, uint32_t i, char *why, size_t whylen)
{
    if (i >= n) return VP_ERR_COUNT;
    vp_light l;
    light_read(recs, i, &l);
    return light_check(&l, why, whylen);
}

int vp_dec_lights(const uint8_t *p, size_t len, uint32_t max_batch, const uint8_t **recs, uint32_t *n)
{
    vp_reader r;
    vp_reader_init(&r, p, len);
    *n = vp_get_u32(&r);
    int rc = vp_take_rest(&r, *n, VP_LIGHT_SIZE, max_batch, recs);
    if (rc) return rc;
    for (uint32_t i = 0; i < *n; i++) {
        vp_light l;
        light_read(*recs, i, &l);
        if ((rc = light_check(&l, NULL, 0))) return rc;
    }
    return VP_OK;
}

int vp_light_get(const uint8_t *recs, uint32_t n, uint32_t i, vp_light *out)
{
    if (i >= n) return VP_ERR_COUNT;
    light_read(recs, i, out);
    return light_check(out, NULL, 0);
}
