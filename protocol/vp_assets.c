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
#define MESH_CHECKS(X) X(mask, flags, "flags", "0x1 no normals, 0x2 UVs, 0x4 tangents are defined", 0, VP_MESH_FLAGS)
VP_LAYOUT_CHECKED(mesh, vp_mesh, MESH_FIELDS, MESH_CHECKS)

size_t vp_size_mesh_uv(uint32_t nv, uint32_t ni, bool normals, bool uvs, bool tangents)
{
    size_t per = 12 + (normals ? 12 : 0) + (uvs ? 8 : 0) + (uvs && tangents ? 16 : 0);
    return VP_HEADER_SIZE + mesh_size() + (size_t)nv * per + (size_t)ni * 4;
}

size_t vp_size_mesh(uint32_t nv, uint32_t ni, bool normals)
{
    return vp_size_mesh_uv(nv, ni, normals, false, false);
}

static void put_f32s(vp_writer *w, const float *f, size_t n)
{
    for (size_t i = 0; f && i < n; i++) vp_put_f32(w, f[i]);
}

/* nrm NULL: VP_MESH_NO_NORMALS and no normals block (drawn flat); uv and
 * tan NULL: not sent (tan only with uv). */
void vp_enc_mesh_uv(vp_writer *w, uint32_t req, uint16_t class_id, const float *pos, const float *nrm,
                    const float *uv, const float *tan, uint32_t nv, const uint32_t *idx, uint32_t ni)
{
    vp_enc_mesh_as(w, VP_MESH_PUT, req, class_id, pos, nrm, uv, tan, nv, idx, ni);
}

/* MESH_PUT's layout under type (MESH_REPLY: the same bytes read back) */
void vp_enc_mesh_as(vp_writer *w, uint16_t type, uint32_t req, uint16_t class_id, const float *pos, const float *nrm,
                    const float *uv, const float *tan, uint32_t nv, const uint32_t *idx, uint32_t ni)
{
    if (!uv) tan = NULL;
    uint16_t flags = (uint16_t)((nrm ? 0 : VP_MESH_NO_NORMALS) | (uv ? VP_MESH_UVS : 0) | (tan ? VP_MESH_TANGENTS : 0));
    vp_frame_begin(w, type, req);
    mesh_put(w, &(vp_mesh){.class_id = class_id, .flags = flags, .vertex_count = nv, .index_count = ni});
    put_f32s(w, pos, 3 * (size_t)nv);
    put_f32s(w, nrm, 3 * (size_t)nv);
    put_f32s(w, uv, 2 * (size_t)nv);
    put_f32s(w, tan, 4 * (size_t)nv);
    for (uint32_t i = 0; i < ni; i++) vp_put_u32(w, idx[i]);
    vp_frame_end(w);
}

void vp_enc_mesh(vp_writer *w, uint32_t req, uint16_t class_id, const float *pos, const float *nrm, uint32_t nv,
                 const uint32_t *idx, uint32_t ni)
{
    vp_enc_mesh_uv(w, req, class_id, pos, nrm, NULL, NULL, nv, idx, ni);
}

/* Every float of an array of n x k is finite. */
static bool finite_block(const uint8_t *p, uint32_t n, uint32_t k)
{
    for (size_t i = 0; p && i < (size_t)n * k; i++)
        if (!isfinite(rdf32(p + 4 * i))) return false;
    return true;
}

int vp_dec_mesh(const uint8_t *p, size_t len, uint32_t max_batch, vp_mesh *m)
{
    vp_reader r;
    int rc = mesh_head(&r, p, len, m);
    if (rc || (rc = mesh_check_fields(m, 0, "", NULL, 0))) return rc;
    if ((m->flags & VP_MESH_TANGENTS) && !(m->flags & VP_MESH_UVS)) return VP_ERR_INVALID;
    if (m->index_count % 3) return VP_ERR_COUNT;
    bool normals = !(m->flags & VP_MESH_NO_NORMALS);
    bool uvs = m->flags & VP_MESH_UVS, tangents = m->flags & VP_MESH_TANGENTS;
    m->normals = m->uvs = m->tangents = NULL;
    if ((rc = vp_take_array(&r, m->vertex_count, 12, max_batch, &m->positions)) ||
        (normals && (rc = vp_take_array(&r, m->vertex_count, 12, max_batch, &m->normals))) ||
        (uvs && (rc = vp_take_array(&r, m->vertex_count, 8, max_batch, &m->uvs))) ||
        (tangents && (rc = vp_take_array(&r, m->vertex_count, 16, max_batch, &m->tangents))) ||
        (rc = vp_take_array(&r, m->index_count, 4,
                         max_batch ? (uint32_t)(max_batch > UINT32_MAX / 3 ? UINT32_MAX : 3 * max_batch) : 0,
                         &m->indices)))
        return rc;
    if ((rc = vp_reader_finish(&r))) return rc == VP_ERR_TRAILING ? VP_ERR_COUNT : rc;
    if (!finite_block(m->positions, m->vertex_count, 3) || !finite_block(m->normals, m->vertex_count, 3) ||
        !finite_block(m->uvs, m->vertex_count, 2) || !finite_block(m->tangents, m->vertex_count, 4))
        return VP_ERR_NONFINITE;
    for (uint32_t i = 0; i < m->index_count; i++)
        if (rd32(m->indices + 4 * (size_t)i) >= m->vertex_count) return VP_ERR_INVALID;
    return VP_OK;
}

/* ---- occluders ----------------------------------------------------------------------- */

#define OCCLUDER_FIELDS(X) X(u64, id) X(u32, flags) X(f64a, origin) X(u32, tri_count)
#define OCCLUDER_CHECKS(X)                                                                                 \
    X(mask, flags, "flags", "0x1 attached is defined", 0, VP_OCC_ATTACHED)                               \
    X(range, origin, "origin", "x,y,z", -INFINITY, INFINITY)
VP_LAYOUT_CHECKED(occluder, vp_occluder, OCCLUDER_FIELDS, OCCLUDER_CHECKS)
#define OCCLUDER_V1_FIELDS(X) X(u64, id) X(f64a, origin) X(u32, tri_count)
#define OCCLUDER_V1_CHECKS(X) X(range, origin, "origin", "x,y,z", -INFINITY, INFINITY)
VP_LAYOUT_CHECKED(occluder_v1, vp_occluder, OCCLUDER_V1_FIELDS, OCCLUDER_V1_CHECKS)

size_t vp_size_occluder(uint32_t ntris)
{
    return VP_HEADER_SIZE + occluder_size() + (size_t)ntris * 36;
}

void vp_enc_occluder_flags(vp_writer *w, uint32_t req, uint64_t id, uint32_t flags, const double origin[3],
                           const float *verts, uint32_t ntris)
{
    vp_frame_begin(w, VP_OCCLUDER_PUT, req);
    vp_occluder o = {.id = id, .flags = flags, .tri_count = ntris};
    memcpy(o.origin, origin, sizeof o.origin);
    occluder_put(w, &o);
    put_f32s(w, verts, 9 * (size_t)ntris);
    vp_frame_end(w);
}

void vp_enc_occluder(vp_writer *w, uint32_t req, uint64_t id, const double origin[3], const float *verts,
                     uint32_t ntris)
{
    vp_enc_occluder_flags(w, req, id, 0, origin, verts, ntris);
}

/* the triangles after the fixed part, checked */
static int occluder_rest(vp_reader *r, uint32_t max_batch, vp_occluder *m)
{
    int rc = vp_take_rest(r, m->tri_count, 36, max_batch, &m->verts);
    if (rc) return rc;
    return finite_block(m->verts, m->tri_count, 9) ? VP_OK : VP_ERR_NONFINITE;
}

int vp_dec_occluder(const uint8_t *p, size_t len, uint32_t max_batch, vp_occluder *m)
{
    vp_reader r;
    int rc = occluder_head(&r, p, len, m);
    if (rc || (rc = occluder_check_fields(m, 0, "", NULL, 0))) return rc;
    return occluder_rest(&r, max_batch, m);
}

int vp_dec_occluder_v1(const uint8_t *p, size_t len, uint32_t max_batch, vp_occluder *m)
{
    vp_reader r;
    int rc = occluder_v1_head(&r, p, len, m);
    m->flags = 0;
    if (rc || (rc = occluder_v1_check_fields(m, 0, "", NULL, 0))) return rc;
    return occluder_rest(&r, max_batch, m);
}

/* ---- lights ----------------------------------------------------------------------- */

/* One light record, VP_LIGHT_SIZE bytes (reserved bytes written 0, not read). */
#define LIGHT_FIELDS(X)                                                                                   \
    X(u64, id) X(u8, kind) X(rsv8, pad1) X(rsv16, pad2) X(f32, intensity) X(f64a, pos) X(f32a, dir)          \
    X(f32a, color) X(f32, range) X(f32, inner_cos) X(f32, outer_cos) X(rsv32, pad3)
VP_LAYOUT(light, vp_light, LIGHT_FIELDS)

VP_BATCH_MESSAGE(lights, vp_light, VP_LIGHT_PUT, light_put, light_size())

void vp_put_light(vp_writer *w, const vp_light *l)
{
    light_put(w, l);
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
