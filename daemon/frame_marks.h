/*
 * frame_marks.h — what a frame draws over its picture for commanders
 * (issue 20 item 8): the recent marks (MARK) as icons, and the entities a
 * RENDER or a stream names as highlighted, outlined (render/vt_overlay.h).
 *
 * The marks are transient: the last MARK_KEEP of them, each until its
 * ttl_ms runs out, in memory only (not journaled, not in snapshots; a
 * restart forgets them, as it forgets MARKED's subscribers). So is the
 * scene's shared selection (SELECT: the last one wins, outlined in every
 * frame that does not opt out; its first VT_OVERLAY_MAX_HL ids). Written
 * on the loop thread (MARK, SELECT, expiry), read by the workers' frames:
 * a mutex, held for a copy of at most MARK_KEEP marks and
 * VT_OVERLAY_MAX_HL ids.
 */
#ifndef VANTAGE_FRAME_MARKS_H
#define VANTAGE_FRAME_MARKS_H

#include "culling.h"
#include "protocol.h"
#include "scene.h"
#include "vt_overlay.h"

#include <pthread.h>
#include <stdint.h>

#define MARK_KEEP 64u

typedef struct mark_store {
    pthread_mutex_t mu;
    vp_marked m[MARK_KEEP]; /* a ring: the oldest first from head */
    uint64_t until_ns[MARK_KEEP]; /* now_ns clock */
    uint32_t head, n;
    uint64_t gen;           /* bumped when a mark arrives or expires, or the
                               selection changes: streams redraw */
    uint64_t sel[VP_SELECT_MAX]; /* the shared selection, as SELECT sent it */
    vp_selected selected;   /* its SELECTED head (client, count, serial) */
} mark_store;

void mark_store_init(mark_store *ms);
void mark_store_fini(mark_store *ms);
/* Keeps m (the oldest dropped when MARK_KEEP are kept). Loop thread. */
void mark_store_add(mark_store *ms, const vp_marked *m, uint64_t now);
/* Drops the marks expired at now (gen bumped if any); the time the next
 * one expires (UINT64_MAX: none). Loop thread. */
uint64_t mark_store_expire(mark_store *ms, uint64_t now);

/* Replaces the shared selection with sel's (its ids checked by
 * vp_dec_select) from client, and bumps the serial. Loop thread. */
void mark_store_select(mark_store *ms, uint32_t client, const vp_select *sel);

/* A frame's overlay, as the renderers take it (fixed size: nothing to
 * allocate or free). */
typedef struct frame_overlay {
    vt_overlay ov;
    uint32_t hl[VT_OUTLINES][VT_OVERLAY_MAX_HL];
    vt_instance extra[VT_OUTLINES][VT_OVERLAY_MAX_HL];
    vt_icon icons[MARK_KEEP];
} frame_overlay;

/* The overlay of a frame of request m whose instance i is the entity of
 * res[i] (i < n): two outlines, m's highlighted ids and (unless m opts
 * out with VP_RENDER_NO_SELECTION) the shared selection's. A listed entity
 * the query culled (hidden, or out of view) is outlined by its box (mesh
 * 0: the frame's unit box, as gather puts it first), dim where the
 * picture covers it; an id that is 0 or unknown, or in a sub-level not
 * shown (not in subs, the frame's scene_visible; NULL: all), outlines
 * nothing (a frame is never refused for it). And an icon per mark of ms
 * live at now. Any thread, under the scene lock. */
void frame_overlay_make(frame_overlay *o, const scene *sc, const uint64_t *subs, const cull_result *res, uint32_t n,
                        const vp_render *m, mark_store *ms, uint64_t now);
/* o's overlay for vt_frame.overlay: NULL when it draws nothing. */
const vt_overlay *frame_overlay_get(const frame_overlay *o);
#endif
