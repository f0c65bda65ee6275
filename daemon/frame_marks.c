/*
 * frame_marks.c — see frame_marks.h.
 */
#include "frame_marks.h"

#include "scene.h"

#include <stdlib.h>
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

void mark_store_select(mark_store *ms, uint32_t client, const vp_select *sel)
{
    pthread_mutex_lock(&ms->mu);
    for (uint32_t i = 0; i < sel->count; i++) ms->sel[i] = vp_id_at(sel->ids, sel->count, i);
    ms->selected.client_id = client;
    ms->selected.count = sel->count;
    ms->selected.serial++;
    ms->gen++;
    pthread_mutex_unlock(&ms->mu);
}

typedef struct hl_key {
    uint32_t handle, k;
} hl_key;

static int cmp_key(const void *a, const void *b)
{
    uint32_t x = ((const hl_key *)a)->handle, y = ((const hl_key *)b)->handle;
    return (x > y) - (x < y);
}

/* Outline g of ids[0..nids) (nids <= VT_OVERLAY_MAX_HL; 0 and repeats
 * skipped): the frame's instances of those entities, found by handle
 * (sorted, then one binary search per instance: n log nids), and the
 * others shown (in a sub-level of subs) by their boxes. */
static void outline_make(frame_overlay *o, int g, const scene *sc, const cull_result *res, uint32_t n,
                         const uint64_t *ids, uint32_t nids, const uint64_t *subs)
{
    vt_outline *l = &o->ov.outline[g];
    *l = (vt_outline){.hl = o->hl[g], .extra = o->extra[g]};
    hl_key key[VT_OVERLAY_MAX_HL];
    cull_entity_desc desc[VT_OVERLAY_MAX_HL];
    bool found[VT_OVERLAY_MAX_HL] = {false};
    uint32_t nk = 0;
    for (uint32_t k = 0; k < nids; k++) {
        uint64_t h;
        bool dup = false;
        for (uint32_t j = 0; j < k && !dup; j++) dup = ids[j] == ids[k];
        if (dup || !ids[k] || !idmap_get(&sc->ids, ids[k], &h) ||
            cull_entity_get(sc->world, (cull_handle)h, &desc[nk]) != CULL_OK ||
            !cull_sublevel_in(subs, desc[nk].sublevel))
            continue;
        key[nk] = (hl_key){.handle = (uint32_t)h, .k = nk};
        nk++;
    }
    if (!nk) return;
    qsort(key, nk, sizeof *key, cmp_key);
    for (uint32_t i = 0; i < n && l->nhl < nk; i++) {
        hl_key *hit = bsearch(&(hl_key){.handle = res[i].handle}, key, nk, sizeof *key, cmp_key);
        if (!hit || found[hit->k]) continue;
        found[hit->k] = true;
        o->hl[g][l->nhl++] = i;
    }
    /* the culled ones by their boxes: behind a building, the commander
       still sees where the selection is */
    for (uint32_t k = 0; k < nk; k++) {
        if (found[k]) continue;
        vt_instance *in = &o->extra[g][l->nextra++];
        *in = (vt_instance){.mesh = 0, .place = VT_PLACE_BOUNDS};
        memcpy(in->bmin, desc[k].aabb_min, sizeof in->bmin);
        memcpy(in->bmax, desc[k].aabb_max, sizeof in->bmax);
    }
}

void frame_overlay_make(frame_overlay *o, const scene *sc, const uint64_t *subs, const cull_result *res, uint32_t n,
                        const vp_render *m, mark_store *ms, uint64_t now)
{
    memset(&o->ov, 0, sizeof o->ov);
    o->ov.icons = o->icons;
    uint64_t sel[VT_OVERLAY_MAX_HL];
    uint32_t nsel = 0;
    pthread_mutex_lock(&ms->mu);
    if (!(m->flags & VP_RENDER_NO_SELECTION)) {
        nsel = ms->selected.count < VT_OVERLAY_MAX_HL ? ms->selected.count : VT_OVERLAY_MAX_HL;
        memcpy(sel, ms->sel, nsel * sizeof *sel);
    }
    for (uint32_t k = 0; k < ms->n; k++) {
        uint32_t at = (ms->head + k) % MARK_KEEP;
        if (ms->until_ns[at] <= now) continue;
        vt_icon *ic = &o->icons[o->ov.nicons++];
        memset(ic, 0, sizeof *ic);
        memcpy(ic->pos, ms->m[at].m.pos, sizeof ic->pos);
        ic->kind = ms->m[at].m.kind; /* the colour: the kind's (vt_overlay.c) */
    }
    pthread_mutex_unlock(&ms->mu);
    outline_make(o, VT_OUTLINE_HIGHLIGHT, sc, res, n, m->highlight, m->nhighlight, subs);
    outline_make(o, VT_OUTLINE_SELECTION, sc, res, n, sel, nsel, subs);
}

const vt_overlay *frame_overlay_get(const frame_overlay *o)
{
    for (int g = 0; g < VT_OUTLINES; g++)
        if (o->ov.outline[g].nhl || o->ov.outline[g].nextra) return &o->ov;
    return o->ov.nicons ? &o->ov : NULL;
}
