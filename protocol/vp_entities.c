/*
 * vp_entities.c — the entity messages of the protocol (see protocol.h and
 * PROTOCOL.md): ENTITY_ADD / UPDATE batches and their records, id batches
 * (REMOVE, GET, OCCLUDER_REMOVE, LIGHT_REMOVE), ENTITY_ADD_REPLY and
 * ENTITY_LIST with its reply.
 */
#include "vp_internal.h"
#include "vp_layout.h"

#include <math.h>

/* One entity record, VP_ENTITY_REC_SIZE bytes. */
#define ENTITY_FIELDS(X)                                                                                      \
    X(u64, id) X(u32, handle) X(u16, class_id) X(u16, sublevel) X(u32, flags) X(u32, material) X(f64a, pos) \
    X(f32a, rot) X(f32a, scale) X(pad32, pad1) X(f64a, sphere) X(f64a, aabb)
/* its own checks (the transform's are vp_trs_check; ranges are the scene's) */
#define ENTITY_CHECKS(X)                                                                                      \
    X(range, sphere, "sphere", "x,y,z,radius", -INFINITY, INFINITY)                                         \
    X(range, aabb, "aabb", "min x,min y,min z,max x,max y,max z", -INFINITY, INFINITY)                      \
    X(mask, flags, "flags", "0x1 dynamic and 0x2 transform are defined", 0, VP_ENT_FLAGS)
VP_LAYOUT_CHECKED(entity, vp_entity, ENTITY_FIELDS, ENTITY_CHECKS)
_Static_assert(VP_ENTITY_REC_SIZE == 160, "entity record");

/* Version 1's record, VP_ENTITY_REC_SIZE_V1 bytes (the reserved word after
 * flags is written 0 and not read): journals and snapshots of version 1. */
#define ENTITY_V1_FIELDS(X)                                                                                  \
    X(u64, id) X(u32, handle) X(u16, class_id) X(u16, sublevel) X(u32, flags) X(rsv32, pad1) X(f64a, sphere)  \
    X(f64a, aabb)
VP_LAYOUT(entity_v1, vp_entity, ENTITY_V1_FIELDS)

/* TRANSFORM_SET's record, VP_TRANSFORM_REC_SIZE bytes. */
#define TRANSFORM_FIELDS(X) X(u64, id) X(u32, handle) X(f64a, pos) X(f32a, rot) X(f32a, scale)
VP_LAYOUT(transform, vp_transform, TRANSFORM_FIELDS)

#define LIST_FIELDS(X) X(u64, cursor) X(u32, max)
VP_LAYOUT(list, vp_list, LIST_FIELDS)

/* the fixed parts before the records */
#define LIST_REPLY_FIELDS(X) X(u64, next_cursor) X(u64, epoch)
VP_LAYOUT(list_reply, vp_list_reply, LIST_REPLY_FIELDS)
#define ADD_REPLY_FIELDS(X) X(u64, epoch) X(u32, count)
VP_LAYOUT(add_reply, vp_add_reply, ADD_REPLY_FIELDS)

size_t vp_size_entities(uint32_t n)
{
    return VP_HEADER_SIZE + 4 + (size_t)n * entity_size();
}

size_t vp_size_ids(uint32_t n)
{
    return VP_HEADER_SIZE + 4 + (size_t)n * 8;
}

static void put_entities(vp_writer *w, const vp_entity *e, uint32_t n)
{
    vp_put_u32(w, n);
    for (uint32_t i = 0; i < n; i++) entity_put(w, &e[i]);
}

void vp_enc_entities(vp_writer *w, uint16_t type, uint32_t req, const vp_entity *e, uint32_t n)
{
    vp_frame_begin(w, type, req);
    put_entities(w, e, n);
    vp_frame_end(w);
}

/* Record i of a batch whose size the decoder checked. */
static size_t entity_rec_size(const vp_entity_batch *b)
{
    return b->version == 1 ? VP_ENTITY_REC_SIZE_V1 : VP_ENTITY_REC_SIZE;
}

/* Record i of a batch whose size the decoder checked; a version 1 record
 * as the bounds entity it was (material 0, no transform). Returns the
 * OR of its pad bytes (non-zero: INVALID). */
static uint32_t entity_read(const vp_entity_batch *b, uint32_t i, vp_entity *e)
{
    vp_reader r;
    size_t rs = entity_rec_size(b);
    vp_reader_init(&r, b->recs + (size_t)i * rs, rs);
    if (b->version != 1) return entity_get(&r, e);
    memset(e, 0, sizeof *e);
    (void)entity_v1_get(&r, e);
    e->flags &= ~VP_ENT_TRANSFORM; /* version 1 defined bit 0 only (checked below) */
    return 0;
}

/* A record's own checks (what no scene state decides), with the field and
 * the cause in why (may be NULL). The range checks are the scene's. */
static int entity_check(vp_entity *e, uint32_t pad, char *why, size_t whylen)
{
    int rc = entity_check_fields(e, pad, "", why, whylen);
    if (rc) return rc;
    if (e->flags & VP_ENT_TRANSFORM) return vp_trs_check(e->pos, e->rot, e->scale, why, whylen);
    return VP_OK;
}

int vp_entity_rec_check(const vp_entity_batch *b, uint32_t i, char *why, size_t whylen)
{
    if (i >= b->count) return VP_ERR_COUNT;
    vp_entity e;
    uint32_t pad = entity_read(b, i, &e);
    return entity_check(&e, pad, why, whylen);
}

/* count + records (of layout version) to the end of the payload */
static int get_entities(vp_reader *rd, uint32_t max_batch, uint8_t version, vp_entity_batch *m)
{
    vp_reader r = *rd;
    m->version = version;
    m->count = vp_get_u32(&r);
    int rc = vp_take_rest(&r, m->count, entity_rec_size(m), max_batch, &m->recs);
    if (rc) return rc;
    for (uint32_t i = 0; i < m->count; i++) {
        vp_entity e;
        uint32_t pad = entity_read(m, i, &e);
        if ((rc = entity_check(&e, pad, NULL, 0))) return rc;
    }
    *rd = r;
    return VP_OK;
}

int vp_dec_entities(const uint8_t *p, size_t len, uint32_t max_batch, vp_entity_batch *m)
{
    vp_reader r;
    vp_reader_init(&r, p, len);
    return get_entities(&r, max_batch, 2, m);
}

int vp_dec_entities_v1(const uint8_t *p, size_t len, uint32_t max_batch, vp_entity_batch *m)
{
    vp_reader r;
    vp_reader_init(&r, p, len);
    int rc = get_entities(&r, max_batch, 1, m);
    if (rc) return rc;
    /* version 1 defined the dynamic bit only */
    for (uint32_t i = 0; i < m->count; i++)
        if (rd32(m->recs + (size_t)i * VP_ENTITY_REC_SIZE_V1 + 16) & ~VP_ENT_DYNAMIC) return VP_ERR_INVALID;
    return VP_OK;
}

/* ---- transforms ----------------------------------------------------------------- */

int vp_trs_check(double pos[3], float rot[4], float scale[3], char *why, size_t whylen)
{
    static const char axis[4] = {'x', 'y', 'z', 'w'};
    for (int a = 0; a < 3; a++)
        if (!isfinite(pos[a]))
            return vp_errf(why, whylen, VP_ERR_NONFINITE, "position %c is %g: NaN or infinite", axis[a], pos[a]);
    for (int a = 0; a < 4; a++)
        if (!isfinite(rot[a]))
            return vp_errf(why, whylen, VP_ERR_NONFINITE, "rotation %c is %g: NaN or infinite", axis[a],
                           (double)rot[a]);
    for (int a = 0; a < 3; a++)
        if (!isfinite(scale[a]))
            return vp_errf(why, whylen, VP_ERR_NONFINITE, "scale %c is %g: NaN or infinite", axis[a],
                           (double)scale[a]);
    double n2 = 0;
    for (int a = 0; a < 4; a++) n2 += (double)rot[a] * rot[a];
    double n = sqrt(n2);
    if (!(fabs(n - 1) <= VP_QUAT_TOLERANCE))
        return vp_errf(why, whylen, VP_ERR_INVALID,
                       "rotation (%g, %g, %g, %g) has length %.6g: not a unit quaternion (1 +- %g)", (double)rot[0],
                       (double)rot[1], (double)rot[2], (double)rot[3], n, VP_QUAT_TOLERANCE);
    int zeros = (scale[0] == 0) + (scale[1] == 0) + (scale[2] == 0);
    if (zeros > 1)
        return vp_errf(why, whylen, VP_ERR_INVALID, "scale (%g, %g, %g) is 0 on %d axes; at most one may be 0",
                       (double)scale[0], (double)scale[1], (double)scale[2], zeros);
    if (fabs(n - 1) > VP_UNIT_EXACT)
        for (int a = 0; a < 4; a++) rot[a] = (float)(rot[a] / n);
    return VP_OK;
}

VP_BATCH_MESSAGE(transforms, vp_transform, VP_TRANSFORM_SET, transform_put, transform_size())

static void transform_read(const vp_transform_batch *b, uint32_t i, vp_transform *t)
{
    vp_reader r;
    vp_reader_init(&r, b->recs + (size_t)i * VP_TRANSFORM_REC_SIZE, VP_TRANSFORM_REC_SIZE);
    (void)transform_get(&r, t);
}

int vp_transform_rec_check(const vp_transform_batch *b, uint32_t i, char *why, size_t whylen)
{
    if (i >= b->count) return VP_ERR_COUNT;
    vp_transform t;
    transform_read(b, i, &t);
    return vp_trs_check(t.pos, t.rot, t.scale, why, whylen);
}

int vp_transform_get(const vp_transform_batch *b, uint32_t i, vp_transform *out)
{
    if (i >= b->count) return VP_ERR_COUNT;
    transform_read(b, i, out);
    return vp_trs_check(out->pos, out->rot, out->scale, NULL, 0);
}

int vp_dec_transforms(const uint8_t *p, size_t len, uint32_t max_batch, vp_transform_batch *m)
{
    _Static_assert(VP_TRANSFORM_REC_SIZE == 64, "transform record");
    vp_reader r;
    vp_reader_init(&r, p, len);
    m->count = vp_get_u32(&r);
    int rc = vp_take_rest(&r, m->count, VP_TRANSFORM_REC_SIZE, max_batch, &m->recs);
    if (rc) return rc;
    for (uint32_t i = 0; i < m->count; i++)
        if ((rc = vp_transform_rec_check(m, i, NULL, 0))) return rc;
    return VP_OK;
}

VP_MESSAGE(list, vp_list, VP_ENTITY_LIST)

int vp_dec_list(const uint8_t *p, size_t len, uint32_t max_batch, vp_list *m)
{
    int rc = list_dec(p, len, m);
    if (rc) return rc;
    return (m->max == 0 || (max_batch && m->max > max_batch)) ? VP_ERR_COUNT : VP_OK;
}

size_t vp_size_list_reply(uint32_t n)
{
    return vp_size_entities(n) + list_reply_size();
}

void vp_enc_list_reply(vp_writer *w, uint32_t req, uint64_t next_cursor, uint64_t epoch, const vp_entity *e,
                       uint32_t n)
{
    vp_frame_begin(w, VP_ENTITY_LIST_REPLY, req);
    list_reply_put(w, &(vp_list_reply){.next_cursor = next_cursor, .epoch = epoch});
    put_entities(w, e, n);
    vp_frame_end(w);
}

int vp_dec_list_reply(const uint8_t *p, size_t len, vp_list_reply *m)
{
    vp_reader r;
    int rc = list_reply_head(&r, p, len, m);
    return rc ? rc : get_entities(&r, 0, 2, &m->batch);
}

int vp_entity_get(const vp_entity_batch *b, uint32_t i, vp_entity *out)
{
    if (i >= b->count) return VP_ERR_COUNT;
    uint32_t pad = entity_read(b, i, out);
    return entity_check(out, pad, NULL, 0);
}

void vp_enc_ids(vp_writer *w, uint16_t type, uint32_t req, const uint64_t *ids, uint32_t n)
{
    vp_frame_begin(w, type, req);
    vp_put_u32(w, n);
    for (uint32_t i = 0; i < n; i++) vp_put_u64(w, ids[i]);
    vp_frame_end(w);
}

int vp_dec_ids(const uint8_t *p, size_t len, uint32_t max_batch, vp_id_batch *m)
{
    vp_reader r;
    vp_reader_init(&r, p, len);
    m->count = vp_get_u32(&r);
    return vp_take_rest(&r, m->count, 8, max_batch, &m->ids);
}

uint64_t vp_id_get(const vp_id_batch *b, uint32_t i)
{
    return vp_id_at(b->ids, b->count, i);
}

size_t vp_size_add_reply(uint32_t n)
{
    return VP_HEADER_SIZE + add_reply_size() + (size_t)n * 4;
}

void vp_enc_add_reply(vp_writer *w, uint32_t req, uint64_t epoch, const uint32_t *handles, uint32_t n)
{
    vp_frame_begin(w, VP_ENTITY_ADD_REPLY, req);
    add_reply_put(w, &(vp_add_reply){.epoch = epoch, .count = n});
    for (uint32_t i = 0; i < n; i++) vp_put_u32(w, handles[i]);
    vp_frame_end(w);
}

int vp_dec_add_reply(const uint8_t *p, size_t len, vp_add_reply *m)
{
    vp_reader r;
    int rc = add_reply_head(&r, p, len, m);
    return rc ? rc : vp_take_rest(&r, m->count, 4, 0, &m->handles);
}

uint32_t vp_handle_get(const vp_add_reply *b, uint32_t i)
{
    return i < b->count ? rd32(b->handles + (size_t)i * 4) : 0;
}
