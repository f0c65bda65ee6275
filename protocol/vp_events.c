/*
 * vp_events.c — the event messages of the protocol (see protocol.h and
 * PROTOCOL.md): MARK / MARKED, a commander's pings, SELECT / SELECTED,
 * the scene's shared selection, and DESTROY / DESTROYED, destruction
 * events.
 */
#include "vp_internal.h"
#include "vp_layout.h"

#include <math.h>

/* ---- marks -------------------------------------------------------------------------- */

#define MARK_FIELDS(X) X(f64a, pos) X(u64, entity) X(u8, kind) X(pad8, pad1) X(pad16, pad2) X(u32, ttl_ms)
#define MARK_CHECKS(X) X(range, pos, "position", "x,y,z", -1e12, 1e12) X(irange, ttl_ms, "ttl", "", 1, 600000)
VP_LAYOUT_CHECKED(mark, vp_mark, MARK_FIELDS, MARK_CHECKS)

/* MARKED's fields before the mark */
#define MARKED_FIELDS(X) X(u32, client_id) X(pad32, pad1)
VP_LAYOUT(marked_head, vp_marked, MARKED_FIELDS)

/* A mark read to the end of the payload; pad is non-zero when a pad
 * before it is. */
static int mark_read(vp_reader *r, uint32_t pad, vp_mark *m)
{
    uint32_t mpad = mark_get(r, m);
    int rc = vp_reader_finish(r);
    if (rc) return rc;
    if (pad) return VP_ERR_INVALID;
    return mark_check_fields(m, mpad, "", NULL, 0);
}

VP_MESSAGE(mark, vp_mark, VP_MARK)

int vp_dec_mark(const uint8_t *p, size_t len, vp_mark *m)
{
    vp_reader r;
    vp_reader_init(&r, p, len);
    return mark_read(&r, 0, m);
}

size_t vp_size_marked(void)
{
    return VP_HEADER_SIZE + marked_head_size() + mark_size();
}

void vp_enc_marked(vp_writer *w, const vp_marked *m)
{
    vp_frame_begin(w, VP_MARKED, 0);
    marked_head_put(w, m);
    mark_put(w, &m->m);
    vp_frame_end(w);
}

int vp_dec_marked(const uint8_t *p, size_t len, vp_marked *m)
{
    vp_reader r;
    vp_reader_init(&r, p, len);
    uint32_t pad = marked_head_get(&r, m);
    return mark_read(&r, pad, &m->m);
}

/* ---- the shared selection ------------------------------------------------------------ */

#define SELECT_FIELDS(X) X(u32, count) X(u32, flags)
#define SELECT_CHECKS(X) \
    X(count, count, "count", "", 0, VP_SELECT_MAX) X(mask, flags, "flags", "none are defined", 0, 0)
VP_LAYOUT_CHECKED(select_head, vp_select, SELECT_FIELDS, SELECT_CHECKS)

#define SELECTED_FIELDS(X) X(u32, client_id) X(u32, count) X(u64, serial)
VP_LAYOUT(selected_head, vp_selected, SELECTED_FIELDS)

uint64_t vp_id_at(const uint8_t *ids, uint32_t n, uint32_t i)
{
    return i < n ? rd64(ids + (size_t)i * 8) : 0;
}

size_t vp_size_select(uint32_t n)
{
    return VP_HEADER_SIZE + select_head_size() + (size_t)n * 8;
}

void vp_enc_select(vp_writer *w, uint32_t req, const uint64_t *ids, uint32_t n)
{
    vp_frame_begin(w, VP_SELECT, req);
    select_head_put(w, &(vp_select){.count = n});
    for (uint32_t i = 0; i < n; i++) vp_put_u64(w, ids[i]);
    vp_frame_end(w);
}

static int cmp_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return (x > y) - (x < y);
}

int vp_dec_select(const uint8_t *p, size_t len, vp_select *m, char *why, size_t whylen)
{
    vp_reader r;
    if (why && whylen) why[0] = 0;
    int rc = select_head_head(&r, p, len, m);
    if (rc || (rc = select_head_check_fields(m, 0, "", why, whylen))) return rc;
    if ((rc = vp_take_rest(&r, m->count, 8, VP_SELECT_MAX, &m->ids))) {
        if (rc == VP_ERR_COUNT && why)
            snprintf(why, whylen, "count %u does not match the %zu bytes of ids", m->count, len - select_head_size());
        return rc;
    }
    /* none 0, none twice: sorted, each next to its equal (256 at most) */
    uint64_t v[VP_SELECT_MAX];
    for (uint32_t i = 0; i < m->count; i++) {
        v[i] = vp_id_at(m->ids, m->count, i);
        if (!v[i]) return vp_errf(why, whylen, VP_ERR_INVALID, "id %u is 0: no entity has it", i);
    }
    qsort(v, m->count, sizeof *v, cmp_u64);
    for (uint32_t i = 1; i < m->count; i++)
        if (v[i] == v[i - 1])
            return vp_errf(why, whylen, VP_ERR_DUPLICATE, "id %llu is selected twice", (unsigned long long)v[i]);
    return VP_OK;
}

size_t vp_size_selected(uint32_t n)
{
    return VP_HEADER_SIZE + selected_head_size() + (size_t)n * 8;
}

void vp_enc_selected(vp_writer *w, const vp_selected *m, const uint64_t *ids)
{
    vp_frame_begin(w, VP_SELECTED, 0);
    selected_head_put(w, m);
    for (uint32_t i = 0; i < m->count; i++) vp_put_u64(w, ids[i]);
    vp_frame_end(w);
}

int vp_dec_selected(const uint8_t *p, size_t len, vp_selected *m)
{
    vp_reader r;
    int rc = selected_head_head(&r, p, len, m);
    return rc ? rc : vp_take_rest(&r, m->count, 8, VP_SELECT_MAX, &m->ids);
}

/* ---- destruction --------------------------------------------------------------- */

#define DESTROY_FIELDS(X) \
    X(u64, id) X(u32, handle) X(u8, debris) X(pad8, pad1) X(pad16, pad2) X(f64a, center) X(f64, radius)
/* the world's bounds and the sphere's fit are the scene's (daemon/edit.c) */
#define DESTROY_CHECKS(X)                                                                                  \
    X(range, center, "centre", "x,y,z", -INFINITY, INFINITY) X(range, radius, "radius", "", -INFINITY, INFINITY) \
    X(max, debris, "debris", "0..64 are allowed", 0, VP_MAX_DEBRIS)
VP_LAYOUT_CHECKED(destroy, vp_destroy, DESTROY_FIELDS, DESTROY_CHECKS)

#define DESTROYED_FIELDS(X) X(u64, epoch) X(u32, spheres) X(u32, occluder_tris) X(u32, debris) X(u32, cut_us)
VP_LAYOUT(destroyed, vp_destroyed, DESTROYED_FIELDS)

VP_MESSAGE(destroy, vp_destroy, VP_DESTROY)

int vp_dec_destroy(const uint8_t *p, size_t len, vp_destroy *m)
{
    vp_reader r;
    vp_reader_init(&r, p, len);
    uint32_t pad = destroy_get(&r, m);
    int rc = vp_reader_finish(&r);
    if (rc || (rc = destroy_check_fields(m, pad, "", NULL, 0))) return rc;
    return m->radius > 0 ? VP_OK : VP_ERR_INVALID;
}

VP_MESSAGE(destroyed, vp_destroyed, VP_DESTROYED)
VP_MESSAGE_DEC(destroyed, vp_destroyed)
