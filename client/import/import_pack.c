/*
 * import_pack.c — a imp_level as bytes, written by the import child and read
 * back by its parent (import_child.c), on vp_bytes.h's writer and reader:
 *
 *   u32 magic "LVL2", meshes, entities, occluders, lights, skipped lights,
 *       skipped primitives, materials, textures, has sun
 *   per mesh:     u32 vertices, u32 indices, u8 arrays (1 UVs, 2 tangents),
 *                 u32 material, f32 positions[3 v], f32 normals[3 v],
 *                 f32 uvs[2 v] if any, f32 tangents[4 v] if any,
 *                 u32 indices[i]
 *   per entity:   u32 class, u32 material, f64 pos[3], f32 rot[4],
 *                 f32 scale[3], f64 lo[3], f64 hi[3], u8 dynamic,
 *                 i32 occluder, u8 name length, name
 *   per occluder: f64 origin[3], i32 entity, u8 name length, name,
 *                 u32 triangles, f32 vertices[9 t]
 *   per texture:  u32 id, u8 format, u8 flags, u32 bytes, the bytes
 *   the sun:      f32 direction[3], f32 colour[3], f32 lux
 *   the materials: one MATERIAL_PUT frame (PROTOCOL.md), checked as the
 *                 daemon checks it
 *   the lights:   one LIGHT_PUT frame, checked as the daemon checks it
 *
 * all little-endian. Both ends are this program, but the child is the side
 * that ran assimp on an untrusted file, so the reader trusts nothing: every
 * count is checked against the bytes left before anything is allocated,
 * and every index or id (a class, a material, a texture, an occluder, an
 * entity, a mesh index) against what it points into; transforms get
 * vp_trs_check. Cost: one pass over the level each way.
 */
#include "import_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define PACK_MAGIC 0x324c564cu /* "LVL2" */
#define HEAD_WORDS 10

/* n 32-bit values (floats by their bits, or integers) from v. */
static void put_32s(vp_writer *w, const void *v, size_t n)
{
    if (!n) return;
    uint8_t *p = n <= SIZE_MAX / 4 ? vp_reserve(w, 4 * n) : NULL;
    if (!p) {
        w->overflow = true;
        return;
    }
    for (size_t i = 0; i < n; i++) {
        uint32_t u;
        memcpy(&u, (const uint8_t *)v + 4 * i, 4);
        vp_st_u32(p + 4 * i, u);
    }
}

static void put_name(vp_writer *w, const char *name)
{
    size_t n = strnlen(name, LVL_NAME - 1);
    vp_put_u8(w, (uint8_t)n);
    vp_put_bytes(w, name, n);
}

void imp_level_pack(vp_writer *w, const imp_level *lv)
{
    const uint32_t head[HEAD_WORDS] = {PACK_MAGIC, lv->nmesh, lv->nent, lv->nocc, lv->nlight, lv->skipped_lights,
                                       lv->skipped_prims, lv->nmat, lv->ntex, lv->has_sun};
    put_32s(w, head, HEAD_WORDS);
    for (uint32_t i = 0; i < lv->nmesh; i++) {
        const lvl_mesh *m = &lv->mesh[i];
        vp_put_u32(w, m->nv);
        vp_put_u32(w, m->ni);
        vp_put_u8(w, (uint8_t)((m->uv ? 1 : 0) | (m->uv && m->tan ? 2 : 0)));
        vp_put_u32(w, m->material);
        put_32s(w, m->pos, (size_t)m->nv * 3);
        put_32s(w, m->nrm, (size_t)m->nv * 3);
        if (m->uv) put_32s(w, m->uv, (size_t)m->nv * 2);
        if (m->uv && m->tan) put_32s(w, m->tan, (size_t)m->nv * 4);
        put_32s(w, m->idx, m->ni);
    }
    for (uint32_t i = 0; i < lv->nent; i++) {
        const lvl_entity *e = &lv->ent[i];
        vp_put_u32(w, e->cls);
        vp_put_u32(w, e->material);
        for (int a = 0; a < 3; a++) vp_put_f64(w, e->pos[a]);
        put_32s(w, e->rot, 4);
        put_32s(w, e->scale, 3);
        for (int a = 0; a < 3; a++) vp_put_f64(w, e->lo[a]);
        for (int a = 0; a < 3; a++) vp_put_f64(w, e->hi[a]);
        vp_put_u8(w, e->dynamic);
        vp_put_i32(w, e->occluder);
        put_name(w, e->name);
    }
    for (uint32_t i = 0; i < lv->nocc; i++) {
        const lvl_occluder *o = &lv->occ[i];
        for (int a = 0; a < 3; a++) vp_put_f64(w, o->origin[a]);
        vp_put_i32(w, o->entity);
        put_name(w, o->name);
        vp_put_u32(w, o->ntri);
        put_32s(w, o->tri, (size_t)o->ntri * 9);
    }
    for (uint32_t i = 0; i < lv->ntex; i++) {
        const lvl_texture *t = &lv->tex[i];
        vp_put_u32(w, t->id);
        vp_put_u8(w, t->format);
        vp_put_u8(w, t->flags);
        vp_put_u32(w, t->nbytes);
        vp_put_bytes(w, t->bytes, t->nbytes);
    }
    put_32s(w, lv->sun_dir, 3);
    put_32s(w, lv->sun_color, 3);
    put_32s(w, &lv->sun_lux, 1);
    vp_enc_materials(w, 0, lv->mat, lv->nmat);
    vp_enc_lights(w, 0, lv->light, lv->nlight);
}

/* A fresh array of the next n 32-bit values (floats or integers; at least
 * one byte, so that malloc(0) never reads as failure), or NULL: too few
 * bytes left (checked before allocating) or out of memory. */
static void *get_32s(vp_reader *r, size_t n)
{
    const uint8_t *p = vp_get_array(r, n, 4);
    uint8_t *v = p ? malloc(4 * n + 1) : NULL;
    for (size_t i = 0; v && i < n; i++) {
        uint32_t u = vp_ld_u32(p + 4 * i);
        memcpy(v + 4 * i, &u, 4);
    }
    return v;
}

static bool get_name(vp_reader *r, char name[LVL_NAME])
{
    uint8_t n = vp_get_u8(r);
    const uint8_t *p = vp_get_bytes(r, n);
    if (!p || n >= LVL_NAME) return false;
    memcpy(name, p, n);
    name[n] = 0;
    return true;
}

/* The frame of type at r (its payload to *p, *len; r past it): false if
 * there is none whole. */
static bool get_frame(vp_reader *r, uint16_t type, const uint8_t **p, uint32_t *len)
{
    vp_header h;
    size_t frame = 0;
    if (r->short_read || vp_frame_check(r->p + r->pos, vp_remaining(r), UINT32_MAX, &h, &frame) != VP_OK ||
        h.type != type)
        return false;
    *p = r->p + r->pos + VP_HEADER_SIZE;
    *len = h.len;
    vp_get_bytes(r, frame);
    return true;
}

static bool unpack_meshes(vp_reader *r, imp_level *lv, uint32_t n)
{
    if (n > LVL_MAX_CLASSES || !(lv->mesh = calloc((size_t)n + 1, sizeof *lv->mesh))) return false;
    for (uint32_t i = 0; i < n; i++) {
        lvl_mesh *m = &lv->mesh[i];
        uint32_t nv = vp_get_u32(r), ni = vp_get_u32(r);
        uint8_t arrays = vp_get_u8(r);
        m->material = vp_get_u32(r);
        lv->nmesh = i + 1; /* what imp_level_free walks */
        if (arrays > 3 || arrays == 2 || !(m->pos = get_32s(r, (size_t)nv * 3)) ||
            !(m->nrm = get_32s(r, (size_t)nv * 3)) || ((arrays & 1) && !(m->uv = get_32s(r, (size_t)nv * 2))) ||
            ((arrays & 2) && !(m->tan = get_32s(r, (size_t)nv * 4))) || !(m->idx = get_32s(r, ni)))
            return false;
        m->nv = nv;
        m->ni = ni;
        for (uint32_t k = 0; k < ni; k++)
            if (m->idx[k] >= nv) return false;
    }
    return true;
}

static bool unpack_entities(vp_reader *r, imp_level *lv, uint32_t n)
{
    /* each entity takes at least 114 bytes: the count is checked before the
       array is allocated */
    if (n > vp_remaining(r) / 114 || !(lv->ent = calloc((size_t)n + 1, sizeof *lv->ent))) return false;
    for (uint32_t i = 0; i < n; i++) {
        lvl_entity *e = &lv->ent[i];
        e->cls = vp_get_u32(r);
        e->material = vp_get_u32(r);
        for (int a = 0; a < 3; a++) e->pos[a] = vp_get_f64(r);
        for (int a = 0; a < 4; a++) e->rot[a] = vp_get_f32(r);
        for (int a = 0; a < 3; a++) e->scale[a] = vp_get_f32(r);
        for (int a = 0; a < 3; a++) e->lo[a] = vp_get_f64(r);
        for (int a = 0; a < 3; a++) e->hi[a] = vp_get_f64(r);
        e->dynamic = vp_get_u8(r) != 0;
        e->occluder = vp_get_i32(r);
        if (!get_name(r, e->name) || vp_trs_check(e->pos, e->rot, e->scale, NULL, 0)) return false;
    }
    lv->nent = n;
    return true;
}

static bool unpack_occluders(vp_reader *r, imp_level *lv, uint32_t n)
{
    /* each occluder takes at least 33 bytes */
    if (n > vp_remaining(r) / 33 || !(lv->occ = calloc((size_t)n + 1, sizeof *lv->occ))) return false;
    for (uint32_t i = 0; i < n; i++) {
        lvl_occluder *o = &lv->occ[i];
        for (int a = 0; a < 3; a++) o->origin[a] = vp_get_f64(r);
        o->entity = vp_get_i32(r);
        lv->nocc = i + 1;
        if (!get_name(r, o->name)) return false;
        uint32_t ntri = vp_get_u32(r);
        if (!(o->tri = get_32s(r, (size_t)ntri * 9))) return false;
        o->ntri = o->cap = ntri;
        if (o->entity < -1 || o->entity >= (int64_t)lv->nent) return false;
    }
    return true;
}

static bool unpack_textures(vp_reader *r, imp_level *lv, uint32_t n)
{
    /* each texture takes at least 11 bytes */
    if (n > LVL_MAX_TEXTURES || n > vp_remaining(r) / 11 || !(lv->tex = calloc((size_t)n + 1, sizeof *lv->tex)))
        return false;
    for (uint32_t i = 0; i < n; i++) {
        lvl_texture *t = &lv->tex[i];
        t->id = vp_get_u32(r);
        t->format = vp_get_u8(r);
        t->flags = vp_get_u8(r);
        uint32_t len = vp_get_u32(r);
        const uint8_t *p = vp_get_bytes(r, len);
        /* ids 1, 2, ... in order (import_material.c) */
        if (!p || t->id != i + 1 || t->format > VP_TEX_JPEG || (t->flags & ~VP_TEX_SRGB) || !len ||
            len > VP_MAX_TEXTURE_BYTES || !(t->bytes = malloc(len)))
            return false;
        memcpy(t->bytes, p, len);
        t->nbytes = len;
        lv->ntex = i + 1;
    }
    return true;
}

/* a material id of the level (0 = the default) */
static bool material_known(const imp_level *lv, uint32_t id)
{
    for (uint32_t i = 0; id && i < lv->nmat; i++)
        if (lv->mat[i].id == id) return true;
    return id == 0;
}

static bool unpack_materials(vp_reader *r, imp_level *lv, uint32_t n)
{
    const uint8_t *p, *recs;
    uint32_t len, got;
    if (!get_frame(r, VP_MATERIAL_PUT, &p, &len) || vp_dec_materials(p, len, 0, &recs, &got) || got != n ||
        !(lv->mat = calloc((size_t)n + 1, sizeof *lv->mat)))
        return false;
    for (uint32_t i = 0; i < n; i++) {
        if (vp_material_get(recs, n, i, &lv->mat[i])) return false;
        for (int k = 0; k < VP_TEX_SLOTS; k++)
            if (lv->mat[i].tex[k].texture > lv->ntex) return false;
    }
    lv->nmat = n;
    return true;
}

bool imp_level_unpack(vp_reader *r, imp_level *lv)
{
    uint32_t head[HEAD_WORDS];
    for (int i = 0; i < HEAD_WORDS; i++) head[i] = vp_get_u32(r);
    if (r->short_read || head[0] != PACK_MAGIC || head[9] > 1) return false;
    if (!unpack_meshes(r, lv, head[1]) || !unpack_entities(r, lv, head[2]) || !unpack_occluders(r, lv, head[3]) ||
        !unpack_textures(r, lv, head[8]))
        return false;
    float sun[7];
    for (int a = 0; a < 7; a++) {
        sun[a] = vp_get_f32(r);
        if (!isfinite(sun[a])) return false;
    }
    lv->has_sun = head[9];
    memcpy(lv->sun_dir, sun, sizeof lv->sun_dir);
    memcpy(lv->sun_color, sun + 3, sizeof lv->sun_color);
    lv->sun_lux = sun[6];
    if (!unpack_materials(r, lv, head[7])) return false;
    for (uint32_t i = 0; i < lv->nmesh; i++)
        if (!material_known(lv, lv->mesh[i].material)) return false;
    for (uint32_t i = 0; i < lv->nent; i++) {
        const lvl_entity *e = &lv->ent[i];
        if (e->cls >= lv->nmesh || e->material != lv->mesh[e->cls].material || e->occluder < -1 ||
            e->occluder >= (int64_t)lv->nocc)
            return false;
    }
    /* the lights: one LIGHT_PUT frame, the rest of the bytes */
    const uint8_t *p, *recs;
    uint32_t len, n;
    if (!get_frame(r, VP_LIGHT_PUT, &p, &len) || vp_remaining(r) || vp_dec_lights(p, len, 0, &recs, &n) ||
        n != head[4])
        return false;
    if (!(lv->light = calloc((size_t)n + 1, sizeof *lv->light))) return false;
    for (uint32_t i = 0; i < n; i++)
        if (vp_light_get(recs, n, i, &lv->light[i])) return false;
    lv->nlight = n;
    lv->skipped_lights = head[5];
    lv->skipped_prims = head[6];
    return true;
}
