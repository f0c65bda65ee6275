/*
 * vp_readback.c — the read-back messages of the protocol (see protocol.h
 * and PROTOCOL.md, "Read-back"): MESH_GET, MATERIAL_LIST, TEXTURE_GET and
 * LIGHT_LIST with their replies, what `vantage export` reads of the live
 * scene. The replies reuse the put messages' layouts (MESH_PUT,
 * MATERIAL_PUT's records, TEXTURE_PUT, LIGHT_PUT's records), so a reply's
 * records are checked by the same code that checks an upload of them.
 */
#include "vp_internal.h"
#include "vp_layout.h"

/* ---- requests: fixed layouts --------------------------------------------------- */

#define MESH_GET_FIELDS(X) X(u16, class_id)
VP_LAYOUT(mesh_get, vp_mesh_get, MESH_GET_FIELDS)
VP_MESSAGE(mesh_get, vp_mesh_get, VP_MESH_GET)
VP_MESSAGE_DEC(mesh_get, vp_mesh_get)

#define MATERIAL_LIST_FIELDS(X) X(u32, cursor) X(u32, max)
VP_LAYOUT(material_list, vp_material_list, MATERIAL_LIST_FIELDS)
VP_MESSAGE(material_list, vp_material_list, VP_MATERIAL_LIST)

#define TEXTURE_GET_FIELDS(X) X(u32, id) X(u32, offset) X(u32, max_len)
VP_LAYOUT(texture_get, vp_texture_get, TEXTURE_GET_FIELDS)
VP_MESSAGE(texture_get, vp_texture_get, VP_TEXTURE_GET)

#define LIGHT_LIST_FIELDS(X) X(u64, cursor) X(u32, max)
VP_LAYOUT(light_list, vp_light_list, LIGHT_LIST_FIELDS)
VP_MESSAGE(light_list, vp_light_list, VP_LIGHT_LIST)

/* a page of 1..max_batch records (0 = no limit), as ENTITY_LIST's */
static int page_max(uint32_t max, uint32_t max_batch)
{
    return (max == 0 || (max_batch && max > max_batch)) ? VP_ERR_COUNT : VP_OK;
}

int vp_dec_material_list(const uint8_t *p, size_t len, uint32_t max_batch, vp_material_list *m)
{
    int rc = material_list_dec(p, len, m);
    return rc ? rc : page_max(m->max, max_batch);
}

int vp_dec_texture_get(const uint8_t *p, size_t len, vp_texture_get *m)
{
    int rc = texture_get_dec(p, len, m);
    if (rc) return rc;
    return m->id == 0 ? VP_ERR_INVALID : m->max_len == 0 ? VP_ERR_COUNT : VP_OK;
}

int vp_dec_light_list(const uint8_t *p, size_t len, uint32_t max_batch, vp_light_list *m)
{
    int rc = light_list_dec(p, len, m);
    return rc ? rc : page_max(m->max, max_batch);
}

/* ---- replies: a cursor, then the put message's count and records ----------------- */

size_t vp_size_material_list_reply(uint32_t n)
{
    return vp_size_materials(n) + 4;
}

void vp_enc_material_list_reply(vp_writer *w, uint32_t req, uint32_t next_cursor, const vp_material *m, uint32_t n)
{
    vp_frame_begin(w, VP_MATERIAL_LIST_REPLY, req);
    vp_put_u32(w, next_cursor);
    vp_put_u32(w, n);
    for (uint32_t i = 0; i < n; i++) vp_put_material(w, &m[i]);
    vp_frame_end(w);
}

int vp_dec_material_list_reply(const uint8_t *p, size_t len, vp_material_list_reply *m)
{
    if (len < 4) return VP_ERR_TRUNCATED;
    m->next_cursor = rd32(p);
    /* the rest is MATERIAL_PUT's payload, every record checked */
    return vp_dec_materials(p + 4, len - 4, 0, &m->recs, &m->count);
}

size_t vp_size_light_list_reply(uint32_t n)
{
    return vp_size_lights(n) + 8;
}

void vp_enc_light_list_reply(vp_writer *w, uint32_t req, uint64_t next_cursor, const vp_light *l, uint32_t n)
{
    vp_frame_begin(w, VP_LIGHT_LIST_REPLY, req);
    vp_put_u64(w, next_cursor);
    vp_put_u32(w, n);
    for (uint32_t i = 0; i < n; i++) vp_put_light(w, &l[i]);
    vp_frame_end(w);
}

int vp_dec_light_list_reply(const uint8_t *p, size_t len, vp_light_list_reply *m)
{
    if (len < 8) return VP_ERR_TRUNCATED;
    m->next_cursor = rd64(p);
    /* the rest is LIGHT_PUT's payload, every record checked */
    return vp_dec_lights(p + 8, len - 8, 0, &m->recs, &m->count);
}
