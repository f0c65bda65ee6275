/*
 * frame_marks.c — see frame_marks.h.
 */
#include "frame_marks.h"

#include "scene.h"

#include <string.h>

void mark_store_init(mark_store *ms)
{
    memset(ms, 0, sizeof *ms);
    pthread_mutex_init(&ms->mu, NULL);
}

void mark_store_fini(mark_store *ms)
{
    pthread_mutex_destroy(&ms->mu);
}

void mark_store_add(mark_store *ms, const vp_marked *m, uint64_t now)
{
    pthread_mutex_lock(&ms->mu);
    uint32_t at = (ms->head + ms->n) % MARK_KEEP;
    if (ms->n == MARK_KEEP) ms->head = (ms->head + 1) % MARK_KEEP; /* the oldest gives way */
    else ms->n++;
    ms->m[at] = *m;
    ms->until_ns[at] = now + (uint64_t)m->m.ttl_ms * 1000000u;
    ms->gen++;
    pthread_mutex_unlock(&ms->mu);
}

uint64_t mark_store_expire(mark_store *ms, uint64_t now)
{
    uint64_t next = UINT64_MAX;
    pthread_mutex_lock(&ms->mu);
    /* ttls differ: compact the ring in order, keeping the live ones */
    uint32_t kept = 0, n = ms->n;
    for (uint32_t k = 0; k < n; k++) {
        uint32_t from = (ms->head + k) % MARK_KEEP, to = (ms->head + kept) % MARK_KEEP;
        if (ms->until_ns[from] <= now) continue;
        if (ms->until_ns[from] < next) next = ms->until_ns[from];
        ms->m[to] = ms->m[from];
        ms->until_ns[to] = ms->until_ns[from];
        kept++;
    }
    if (kept != n) ms->gen++;
    ms->n = kept;
    pthread_mutex_unlock(&ms->mu);
    return next;
}

void frame_overlay_make(frame_overlay *o, const scene *sc, const cull_result *res, uint32_t n, const vp_render *m,
                        mark_store *ms, uint64_t now)
{
    memset(&o->ov, 0, sizeof o->ov);
    o->ov.hl = o->hl;
    o->ov.icons = o->icons;
    o->ov.extra = o->extra;
    /* at most 8 ids against the frame's instances: one pass, 8 compares */
    bool found[VP_RENDER_MAX_HIGHLIGHT] = {false};
    if (m->nhighlight)
        for (uint32_t i = 0; i < n && o->ov.nhl < VP_RENDER_MAX_HIGHLIGHT; i++) {
            uint64_t id = scene_id_of(sc, res[i].handle);
            for (uint32_t k = 0; k < m->nhighlight; k++)
                if (id && m->highlight[k] == id && !found[k]) {
                    o->hl[o->ov.nhl++] = i;
                    found[k] = true;
                    break;
                }
        }
    /* the culled ones by their boxes: behind a building, the commander
       still sees where the selection is */
    uint64_t vis[CULL_SUBLEVEL_WORDS];
    const uint64_t *subs = m->nhighlight ? scene_visible(sc, NULL, vis) : NULL;
    for (uint32_t k = 0; k < m->nhighlight; k++) {
        uint64_t h;
        cull_entity_desc e;
        bool dup = false;
        for (uint32_t j = 0; j < k; j++) dup = dup || m->highlight[j] == m->highlight[k];
        if (found[k] || dup || !m->highlight[k] || !idmap_get(&sc->ids, m->highlight[k], &h) ||
            cull_entity_get(sc->world, (cull_handle)h, &e) != CULL_OK || !cull_sublevel_in(subs, e.sublevel))
            continue;
        vt_instance *in = &o->extra[o->ov.nextra++];
        *in = (vt_instance){.mesh = 0, .place = VT_PLACE_BOUNDS};
        memcpy(in->bmin, e.aabb_min, sizeof in->bmin);
        memcpy(in->bmax, e.aabb_max, sizeof in->bmax);
    }
    pthread_mutex_lock(&ms->mu);
    for (uint32_t k = 0; k < ms->n; k++) {
        uint32_t at = (ms->head + k) % MARK_KEEP;
        if (ms->until_ns[at] <= now) continue;
        vt_icon *ic = &o->icons[o->ov.nicons++];
        memset(ic, 0, sizeof *ic);
        memcpy(ic->pos, ms->m[at].m.pos, sizeof ic->pos);
        ic->kind = ms->m[at].m.kind; /* the colour: the kind's (vt_overlay.c) */
    }
    pthread_mutex_unlock(&ms->mu);
}

const vt_overlay *frame_overlay_get(const frame_overlay *o)
{
    return o->ov.nhl || o->ov.nextra || o->ov.nicons ? &o->ov : NULL;
}
