/*
 * import_pack.c — a imp_level as bytes, written by the import child and read
 * back by its parent (import_child.c), on vp_bytes.h's writer and reader:
 *
 *   u32 magic "LVLV", meshes, entities, occluders, lights, skipped lights,
 *       skipped primitives
 *   per mesh:     u32 vertices, u32 indices, f32 positions[3 v],
 *                 f32 normals[3 v], u32 indices[i]
 *   per entity:   u32 class, f64 lo[3], f64 hi[3], u8 dynamic,
 *                 i32 occluder, u8 name length, name
 *   per occluder: f64 origin[3], i32 entity, u8 name length, name,
 *                 u32 triangles, f32 vertices[9 t]
 *   the lights:   one LIGHT_PUT frame (PROTOCOL.md), checked as the
 *                 daemon checks it
 *
 * all little-endian. Both ends are this program, but the child is the side
 * that ran assimp on an untrusted file, so the reader trusts nothing: every
 * count is checked against the bytes left before anything is allocated,
 * and every index (a class, an occluder, an entity, a mesh index) against
 * what it points into. Cost: one pass over the level each way.
 */
#include "import_internal.h"

#include <stdlib.h>
#include <string.h>

#define PACK_MAGIC 0x564c564cu /* "LVLV" */

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
    const uint32_t head[7] = {PACK_MAGIC, lv->nmesh, lv->nent, lv->nocc, lv->nlight, lv->skipped_lights,
                              lv->skipped_prims};
    put_32s(w, head, 7);
    for (uint32_t i = 0; i < lv->nmesh; i++) {
        const lvl_mesh *m = &lv->mesh[i];
        vp_put_u32(w, m->nv);
        vp_put_u32(w, m->ni);
        put_32s(w, m->pos, (size_t)m->nv * 3);
        put_32s(w, m->nrm, (size_t)m->nv * 3);
        put_32s(w, m->idx, m->ni);
    }
    for (uint32_t i = 0; i < lv->nent; i++) {
        const lvl_entity *e = &lv->ent[i];
        vp_put_u32(w, e->cls);
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

bool imp_level_unpack(vp_reader *r, imp_level *lv)
{
    uint32_t head[7];
    for (int i = 0; i < 7; i++) head[i] = vp_get_u32(r);
    if (r->short_read || head[0] != PACK_MAGIC || head[1] > LVL_MAX_CLASSES) return false;
    lv->mesh = calloc((size_t)head[1] + 1, sizeof *lv->mesh);
    if (!lv->mesh) return false;
    for (uint32_t i = 0; i < head[1]; i++) {
        lvl_mesh *m = &lv->mesh[i];
        uint32_t nv = vp_get_u32(r), ni = vp_get_u32(r);
        lv->nmesh = i + 1; /* what imp_level_free walks */
        if (!(m->pos = get_32s(r, (size_t)nv * 3)) || !(m->nrm = get_32s(r, (size_t)nv * 3)) ||
            !(m->idx = get_32s(r, ni)))
            return false;
        m->nv = nv;
        m->ni = ni;
        for (uint32_t k = 0; k < ni; k++)
            if (m->idx[k] >= nv) return false;
    }
    /* each entity takes at least 58 bytes: the count is checked before the
       array is allocated */
    if (head[2] > vp_remaining(r) / 58 || !(lv->ent = calloc((size_t)head[2] + 1, sizeof *lv->ent))) return false;
    for (uint32_t i = 0; i < head[2]; i++) {
        lvl_entity *e = &lv->ent[i];
        e->cls = vp_get_u32(r);
        for (int a = 0; a < 3; a++) e->lo[a] = vp_get_f64(r);
        for (int a = 0; a < 3; a++) e->hi[a] = vp_get_f64(r);
        e->dynamic = vp_get_u8(r) != 0;
        e->occluder = vp_get_i32(r);
        if (!get_name(r, e->name)) return false;
    }
    lv->nent = head[2];
    /* and each occluder at least 33 */
    if (head[3] > vp_remaining(r) / 33 || !(lv->occ = calloc((size_t)head[3] + 1, sizeof *lv->occ))) return false;
    for (uint32_t i = 0; i < head[3]; i++) {
        lvl_occluder *o = &lv->occ[i];
        for (int a = 0; a < 3; a++) o->origin[a] = vp_get_f64(r);
        o->entity = vp_get_i32(r);
        lv->nocc = i + 1;
        if (!get_name(r, o->name)) return false;
        uint32_t ntri = vp_get_u32(r);
        if (!(o->tri = get_32s(r, (size_t)ntri * 9))) return false;
        o->ntri = o->cap = ntri;
        if (o->entity < -1 || o->entity >= (int64_t)head[2]) return false;
    }
    for (uint32_t i = 0; i < lv->nent; i++) {
        const lvl_entity *e = &lv->ent[i];
        if (e->cls >= lv->nmesh || e->occluder < -1 || e->occluder >= (int64_t)lv->nocc) return false;
    }
    /* the lights: one LIGHT_PUT frame, the rest of the bytes */
    vp_header h;
    size_t frame = 0;
    const uint8_t *recs;
    uint32_t n;
    if (r->short_read || vp_frame_check(r->p + r->pos, vp_remaining(r), UINT32_MAX, &h, &frame) != VP_OK ||
        h.type != VP_LIGHT_PUT || frame != vp_remaining(r) ||
        vp_dec_lights(r->p + r->pos + VP_HEADER_SIZE, h.len, 0, &recs, &n) || n != head[4])
        return false;
    vp_get_bytes(r, frame);
    if (!(lv->light = calloc((size_t)n + 1, sizeof *lv->light))) return false;
    for (uint32_t i = 0; i < n; i++)
        if (vp_light_get(recs, n, i, &lv->light[i])) return false;
    lv->nlight = n;
    lv->skipped_lights = head[5];
    lv->skipped_prims = head[6];
    return true;
}
