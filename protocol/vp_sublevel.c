/*
 * vp_sublevel.c — the sub-level messages of the protocol (see protocol.h
 * and PROTOCOL.md): names on the wire, SUBLEVEL_NAMES / IDS / LIST_REPLY,
 * the loads (BEGIN, BEGUN, UNLOAD) and SUBLEVEL_INFO_REPLY.
 */
#include "vp_internal.h"
#include "vp_layout.h"

/* ---- sub-level names ------------------------------------------------------------ */

/* A name on the wire: 1..255 bytes, no control bytes. */
static int name_take(vp_reader *r, uint8_t *len, const uint8_t **name)
{
    *len = vp_get_u8(r);
    *name = vp_get_bytes(r, *len);
    if (r->short_read) return VP_ERR_TRUNCATED;
    if (*len == 0) return VP_ERR_INVALID;
    for (uint8_t k = 0; k < *len; k++)
        if ((*name)[k] < 32 || (*name)[k] == 127) return VP_ERR_INVALID;
    return VP_OK;
}

/* A name's bytes on the wire: longer names are cut to VP_MAX_NAME. */
static size_t name_wire(size_t l)
{
    return l > VP_MAX_NAME ? VP_MAX_NAME : l;
}

static void name_put(vp_writer *w, const uint8_t *name, size_t l)
{
    l = name_wire(l);
    vp_put_u8(w, (uint8_t)l);
    vp_put_bytes(w, name, l);
}

size_t vp_size_names(const char *const *names, const uint16_t *ids, uint32_t n)
{
    size_t s = VP_HEADER_SIZE + 4;
    for (uint32_t i = 0; i < n; i++) s += (ids ? 2 : 0) + 1 + name_wire(strlen(names[i]));
    return s;
}

void vp_enc_names(vp_writer *w, uint16_t type, uint32_t req, const char *const *names, const uint16_t *ids,
                  uint32_t n)
{
    vp_frame_begin(w, type, req);
    vp_put_u32(w, n);
    for (uint32_t i = 0; i < n; i++) {
        if (ids) vp_put_u16(w, ids[i]);
        name_put(w, (const uint8_t *)names[i], strlen(names[i]));
    }
    vp_frame_end(w);
}

int vp_dec_names(const uint8_t *p, size_t len, bool with_ids, vp_name_list *m)
{
    vp_reader r;
    vp_reader_init(&r, p, len);
    m->count = vp_get_u32(&r);
    m->with_ids = with_ids;
    if (r.short_read) return VP_ERR_TRUNCATED;
    if (m->count > VP_MAX_SUBLEVELS) return VP_ERR_COUNT;
    m->p = p + r.pos;
    m->len = len - r.pos;
    for (uint32_t i = 0; i < m->count; i++) {
        if (with_ids) (void)vp_get_u16(&r);
        uint8_t l;
        const uint8_t *name;
        int rc = name_take(&r, &l, &name);
        if (rc) return rc == VP_ERR_TRUNCATED ? VP_ERR_COUNT : rc;
    }
    int rc = vp_reader_finish(&r);
    return rc == VP_ERR_TRAILING ? VP_ERR_COUNT : rc;
}

bool vp_name_next(const vp_name_list *l, size_t *pos, vp_name *out)
{
    if (*pos >= l->len) return false;
    const uint8_t *p = l->p + *pos;
    out->id = 0;
    if (l->with_ids) {
        out->id = rd16(p);
        p += 2;
    }
    out->len = p[0];
    out->name = p + 1;
    *pos += (l->with_ids ? 2u : 0u) + 1u + out->len;
    return true;
}

size_t vp_size_sublevel_ids(uint32_t n)
{
    return VP_HEADER_SIZE + 4 + 2 * (size_t)n;
}

void vp_enc_sublevel_ids(vp_writer *w, uint32_t req, const uint16_t *ids, uint32_t n)
{
    vp_frame_begin(w, VP_SUBLEVEL_IDS, req);
    vp_put_u32(w, n);
    for (uint32_t i = 0; i < n; i++) vp_put_u16(w, ids[i]);
    vp_frame_end(w);
}

int vp_dec_sublevel_ids(const uint8_t *p, size_t len, uint32_t *n, const uint8_t **ids)
{
    vp_reader r;
    vp_reader_init(&r, p, len);
    *n = vp_get_u32(&r);
    return vp_take_rest(&r, *n, 2, VP_MAX_SUBLEVELS, ids);
}

uint16_t vp_sublevel_id_get(const uint8_t *ids, uint32_t n, uint32_t i)
{
    return i < n ? rd16(ids + 2 * (size_t)i) : 0;
}

/* ---- sub-level loads ----------------------------------------------------------- */

/* SUBLEVEL_BEGIN's fields before the name */
#define BEGIN_FIELDS(X) X(u16, classes)
VP_LAYOUT(sublevel_begin, vp_sublevel_begin, BEGIN_FIELDS)

size_t vp_size_sublevel_begin(const vp_sublevel_begin *m)
{
    return VP_HEADER_SIZE + sublevel_begin_size() + 1 + (size_t)m->name_len;
}

void vp_enc_sublevel_begin(vp_writer *w, uint32_t req, const vp_sublevel_begin *m)
{
    vp_frame_begin(w, VP_SUBLEVEL_BEGIN, req);
    sublevel_begin_put(w, m);
    name_put(w, m->name, m->name_len);
    vp_frame_end(w);
}

int vp_dec_sublevel_begin(const uint8_t *p, size_t len, vp_sublevel_begin *m)
{
    vp_reader r;
    int rc = sublevel_begin_head(&r, p, len, m);
    if (rc || (rc = name_take(&r, &m->name_len, &m->name))) return rc;
    if (m->classes > 4096) return VP_ERR_LIMIT;
    return vp_reader_finish(&r);
}

#define BEGUN_FIELDS(X) X(u16, id) X(u16, class_base) X(pad32, pad1) X(u64, epoch)
VP_LAYOUT(sublevel_begun, vp_sublevel_begun, BEGUN_FIELDS)
VP_MESSAGE(sublevel_begun, vp_sublevel_begun, VP_SUBLEVEL_BEGUN)
VP_MESSAGE_DEC(sublevel_begun, vp_sublevel_begun)

size_t vp_size_sublevel_name(const char *name)
{
    return VP_HEADER_SIZE + 1 + name_wire(strlen(name));
}

void vp_enc_sublevel_name(vp_writer *w, uint16_t type, uint32_t req, const char *name)
{
    vp_frame_begin(w, type, req);
    name_put(w, (const uint8_t *)name, strlen(name));
    vp_frame_end(w);
}

int vp_dec_sublevel_name(const uint8_t *p, size_t len, vp_name *m)
{
    vp_reader r;
    vp_reader_init(&r, p, len);
    m->id = 0;
    int rc = name_take(&r, &m->len, &m->name);
    return rc ? rc : vp_reader_finish(&r);
}

/* An info entry before its name (VP_SUBLEVEL_INFO_SIZE - 1 bytes). */
#define INFO_FIELDS(X)                                                                                      \
    X(u16, id) X(u8, state) X(u32, entities) X(u32, occluders) X(u32, lights) X(u16, class_base)          \
    X(u16, classes)
VP_LAYOUT(info, vp_sublevel_info, INFO_FIELDS)

/* SUBLEVEL_INFO_REPLY's fields before the entries */
#define INFOS_FIELDS(X) X(u64, epoch) X(u32, count)
VP_LAYOUT(infos, vp_sublevel_infos, INFOS_FIELDS)

size_t vp_size_sublevel_infos(const vp_sublevel_info *infos, uint32_t n)
{
    size_t s = VP_HEADER_SIZE + infos_size();
    for (uint32_t i = 0; i < n; i++) s += info_size() + 1 + (size_t)infos[i].name_len;
    return s;
}

void vp_enc_sublevel_infos_begin(vp_writer *w, uint32_t req, uint64_t epoch, uint32_t n)
{
    vp_frame_begin(w, VP_SUBLEVEL_INFO_REPLY, req);
    infos_put(w, &(vp_sublevel_infos){.epoch = epoch, .count = n});
}

void vp_put_sublevel_info(vp_writer *w, const vp_sublevel_info *m)
{
    info_put(w, m);
    name_put(w, m->name, m->name_len);
}

int vp_dec_sublevel_infos(const uint8_t *p, size_t len, vp_sublevel_infos *m)
{
    vp_reader r;
    int rc = infos_head(&r, p, len, m);
    if (rc) return rc;
    if (m->count > VP_MAX_SUBLEVELS) return VP_ERR_COUNT;
    m->p = p + r.pos;
    m->len = len - r.pos;
    for (uint32_t i = 0; i < m->count; i++) {
        vp_sublevel_info e;
        (void)info_get(&r, &e);
        if (r.short_read) return VP_ERR_COUNT;
        if (e.state > VP_SL_UNLOADING) return VP_ERR_INVALID;
        if ((rc = name_take(&r, &e.name_len, &e.name))) return rc == VP_ERR_TRUNCATED ? VP_ERR_COUNT : rc;
    }
    rc = vp_reader_finish(&r);
    return rc == VP_ERR_TRAILING ? VP_ERR_COUNT : rc;
}

bool vp_sublevel_info_next(const vp_sublevel_infos *l, size_t *pos, vp_sublevel_info *out)
{
    if (*pos >= l->len) return false;
    vp_reader r;
    vp_reader_init(&r, l->p + *pos, l->len - *pos);
    (void)info_get(&r, out);
    out->name_len = vp_get_u8(&r);
    out->name = vp_get_bytes(&r, out->name_len);
    *pos += VP_SUBLEVEL_INFO_SIZE + out->name_len;
    return true;
}
