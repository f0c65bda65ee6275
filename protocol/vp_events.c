/*
 * vp_events.c — the event messages of the protocol (see protocol.h and
 * PROTOCOL.md): MARK / MARKED, a commander's pings, and DESTROY /
 * DESTROYED, destruction events.
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
