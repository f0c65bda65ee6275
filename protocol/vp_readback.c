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

/* MATERIAL_LIST's cursor is a material id, u32 on the wire: its layout
 * has a struct of its own, and vp_page is converted at the edges */
typedef struct material_list_wire {
    uint32_t cursor, max;
} material_list_wire;
#define MATERIAL_LIST_FIELDS(X) X(u32, cursor) X(u32, max)
VP_LAYOUT(material_list, material_list_wire, MATERIAL_LIST_FIELDS)

size_t vp_size_material_list(void)
{
    return VP_HEADER_SIZE + material_list_size();
}

void vp_enc_material_list(vp_writer *w, uint32_t req, const vp_page *m)
{
    material_list_enc(w, VP_MATERIAL_LIST, req, &(material_list_wire){.cursor = (uint32_t)m->cursor, .max = m->max});
}

#define TEXTURE_GET_FIELDS(X) X(u32, id) X(u32, offset) X(u32, max_len)
VP_LAYOUT(texture_get, vp_texture_get, TEXTURE_GET_FIELDS)
VP_MESSAGE(texture_get, vp_texture_get, VP_TEXTURE_GET)

#define LIGHT_LIST_FIELDS(X) X(u64, cursor) X(u32, max)
VP_LAYOUT(light_list, vp_page, LIGHT_LIST_FIELDS)
VP_MESSAGE(light_list, vp_page, VP_LIGHT_LIST)

/* a page of 1..max_batch records (0 = no limit), as ENTITY_LIST's */
static int page_max(uint32_t max, uint32_t max_batch)
{
    return (max == 0 || (max_batch && max > max_batch)) ? VP_ERR_COUNT : VP_OK;
}

int vp_dec_material_list(const uint8_t *p, size_t len, uint32_t max_batch, vp_page *m)
{
    material_list_wire w;
    int rc = material_list_dec(p, len, &w);
    *m = (vp_page){.cursor = w.cursor, .max = w.max};
    return rc ? rc : page_max(m->max, max_batch);
}

int vp_dec_texture_get(const uint8_t *p, size_t len, vp_texture_get *m)
{
    int rc = texture_get_dec(p, len, m);
    if (rc) return rc;
    return m->id == 0 ? VP_ERR_INVALID : m->max_len == 0 ? VP_ERR_COUNT : VP_OK;
}

int vp_dec_light_list(const uint8_t *p, size_t len, uint32_t max_batch, vp_page *m)
{
    int rc = light_list_dec(p, len, m);
    return rc ? rc : page_max(m->max, max_batch);
}

/* ---- replies: a cursor, then the put message's count and records ----------------- */

typedef void (*put_fn)(vp_writer *w, const void *rec);
static void put_material_rec(vp_writer *w, const void *m) { vp_put_material(w, m); }
static void put_light_rec(vp_writer *w, const void *l) { vp_put_light(w, l); }

/* A reply: the cursor in cursor_size bytes (4 or 8), the count, n records
 * of recs (stride bytes apart in memory) put by put. */
static void page_enc(vp_writer *w, uint16_t type, uint32_t req, uint64_t next, size_t cursor_size, const void *recs,
                     size_t stride, uint32_t n, put_fn put)
{
    vp_frame_begin(w, type, req);
    if (cursor_size == 4) vp_put_u32(w, (uint32_t)next);
    else vp_put_u64(w, next);
    vp_put_u32(w, n);
    for (uint32_t i = 0; i < n; i++) put(w, (const uint8_t *)recs + i * stride);
    vp_frame_end(w);
}

/* The put message's decoder of what follows the cursor (count, records). */
typedef int (*recs_dec)(const uint8_t *p, size_t len, uint32_t max_batch, const uint8_t **recs, uint32_t *n);

static int page_dec(const uint8_t *p, size_t len, size_t cursor_size, recs_dec dec, vp_page_reply *m)
{
    if (len < cursor_size) return VP_ERR_TRUNCATED;
    m->next_cursor = cursor_size == 4 ? rd32(p) : rd64(p);
    /* every record checked as the put message's */
    return dec(p + cursor_size, len - cursor_size, 0, &m->recs, &m->count);
}

size_t vp_size_material_list_reply(uint32_t n)
{
    return vp_size_materials(n) + 4;
}

size_t vp_size_light_list_reply(uint32_t n)
{
    return vp_size_lights(n) + 8;
}

void vp_enc_material_list_reply(vp_writer *w, uint32_t req, uint32_t next_cursor, const vp_material *m, uint32_t n)
{
    page_enc(w, VP_MATERIAL_LIST_REPLY, req, next_cursor, 4, m, sizeof *m, n, put_material_rec);
}

void vp_enc_light_list_reply(vp_writer *w, uint32_t req, uint64_t next_cursor, const vp_light *l, uint32_t n)
{
    page_enc(w, VP_LIGHT_LIST_REPLY, req, next_cursor, 8, l, sizeof *l, n, put_light_rec);
}

int vp_dec_material_list_reply(const uint8_t *p, size_t len, vp_page_reply *m)
{
    return page_dec(p, len, 4, vp_dec_materials, m);
}

int vp_dec_light_list_reply(const uint8_t *p, size_t len, vp_page_reply *m)
{
    return page_dec(p, len, 8, vp_dec_lights, m);
}
