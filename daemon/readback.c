/*
 * readback.c — vantaged's read-back requests (PROTOCOL.md, "Read-back"):
 * MESH_GET, MATERIAL_LIST, TEXTURE_GET and LIGHT_LIST, what `vantage
 * export` reads of the live scene. Any role may read. They run on the
 * event loop's thread, which is the only thread that changes the scene
 * (under the write lock), so reading here needs no lock, as ENTITY_LIST.
 * Cost: MATERIAL_LIST sorts the material ids once a page (materials are
 * few: max_materials); the others are proportional to what they send.
 */
#include "server_internal.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void on_mesh_get(server *s, conn *c, const vp_header *h, const uint8_t *p)
{
    vp_mesh_get m;
    int rc = vp_dec_mesh_get(p, h->len, &m);
    if (rc) {
        send_error(s, c, h->req, rc, UINT32_MAX, vp_strerror(rc));
        return;
    }
    const scene_mesh *sm = &s->sc->meshes[m.class_id];
    if (!sm->pos) {
        char msg[64];
        snprintf(msg, sizeof msg, "class %u has no mesh", m.class_id);
        send_error(s, c, h->req, VP_ERR_NOT_FOUND, UINT32_MAX, msg);
        return;
    }
    size_t need = vp_size_mesh_uv(sm->nv, sm->ni, sm->nrm != NULL, sm->uv != NULL, sm->uv && sm->tan);
    if (need - VP_HEADER_SIZE > s->cfg.max_payload) {
        char msg[96];
        snprintf(msg, sizeof msg, "class %u's mesh is %zu bytes, more than max_payload", m.class_id, need);
        send_error(s, c, h->req, VP_ERR_LIMIT, UINT32_MAX, msg);
        return;
    }
    vp_writer w;
    if (!out_reserve(c, need, &w)) {
        c->closing = true;
        return;
    }
    vp_enc_mesh_as(&w, VP_MESH_REPLY, h->req, m.class_id, sm->pos, sm->nrm, sm->uv, sm->tan, sm->nv, sm->idx, sm->ni);
    out_commit(c, &w);
}

static int cmp_u32(const void *a, const void *b)
{
    uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
    return (x > y) - (x < y);
}

static void on_material_list(server *s, conn *c, const vp_header *h, const uint8_t *p)
{
    vp_page m;
    int rc = vp_dec_material_list(p, h->len, s->cfg.max_batch, &m);
    if (rc) {
        send_error(s, c, h->req, rc, UINT32_MAX, vp_strerror(rc));
        return;
    }
    const idmap *mm = &s->sc->materials;
    /* the ids after the cursor, ascending: a stable order however the map
       is laid out, so a page boundary never skips or repeats one */
    uint32_t *ids = malloc((mm->count + 1) * sizeof *ids);
    /* what fits a frame the size of max_payload, at least one (a page
       of none would never move on) */
    size_t room = (s->cfg.max_payload - 8) / VP_MATERIAL_SIZE;
    uint32_t want = m.max < room ? m.max : room ? (uint32_t)room : 1;
    vp_material *recs = malloc(((size_t)want + 1) * sizeof *recs);
    if (!ids || !recs) {
        free(ids);
        free(recs);
        send_error(s, c, h->req, VP_ERR_BUSY, UINT32_MAX, "out of memory");
        return;
    }
    size_t n = 0;
    for (size_t i = 0; i < mm->cap; i++)
        if (mm->used[i] && mm->keys[i] > m.cursor) ids[n++] = (uint32_t)mm->keys[i];
    qsort(ids, n, sizeof *ids, cmp_u32);
    uint32_t count = n < want ? (uint32_t)n : want;
    for (uint32_t i = 0; i < count; i++) recs[i] = scene_material_find(s->sc, ids[i])->m;
    uint32_t next = count < n ? ids[count - 1] : 0;
    vp_writer w;
    if (out_reserve(c, vp_size_material_list_reply(count), &w)) {
        vp_enc_material_list_reply(&w, h->req, next, recs, count);
        out_commit(c, &w);
    } else {
        c->closing = true;
    }
    free(ids);
    free(recs);
}

static void on_texture_get(server *s, conn *c, const vp_header *h, const uint8_t *p)
{
    vp_texture_get m;
    int rc = vp_dec_texture_get(p, h->len, &m);
    if (rc) {
        send_error(s, c, h->req, rc, UINT32_MAX, vp_strerror(rc));
        return;
    }
    const scene_texture *t = scene_texture_find(s->sc, m.id);
    char msg[96];
    if (!t || !t->nbytes) {
        snprintf(msg, sizeof msg, "no texture with id %u", m.id);
        send_error(s, c, h->req, VP_ERR_NOT_FOUND, UINT32_MAX, msg);
        return;
    }
    if (m.offset >= t->nbytes) {
        snprintf(msg, sizeof msg, "offset %u is past texture %u's %u bytes", m.offset, m.id, t->nbytes);
        send_error(s, c, h->req, VP_ERR_INVALID, UINT32_MAX, msg);
        return;
    }
    uint32_t len = t->nbytes - m.offset, room = s->cfg.max_payload - VP_TEXTURE_PUT_HEADER;
    if (len > m.max_len) len = m.max_len;
    if (len > room) len = room;
    vp_writer w;
    if (!out_reserve(c, vp_size_texture_put(len), &w)) {
        c->closing = true;
        return;
    }
    vp_enc_texture_as(&w, VP_TEXTURE_REPLY, h->req,
                      &(vp_texture_put){.id = m.id, .format = t->format, .flags = t->flags, .total = t->nbytes,
                                        .offset = m.offset, .len = len, .data = t->bytes + m.offset});
    out_commit(c, &w);
}

static void on_light_list(server *s, conn *c, const vp_header *h, const uint8_t *p)
{
    vp_page m;
    int rc = vp_dec_light_list(p, h->len, s->cfg.max_batch, &m);
    if (rc) {
        send_error(s, c, h->req, rc, UINT32_MAX, vp_strerror(rc));
        return;
    }
    /* the cursor is a slot of the lights map + 1, as ENTITY_LIST's */
    const idmap *lm = &s->sc->lights;
    size_t room = (s->cfg.max_payload - 12) / VP_LIGHT_SIZE;
    uint32_t want = m.max < room ? m.max : room ? (uint32_t)room : 1;
    vp_light *l = malloc(((size_t)want + 1) * sizeof *l);
    if (!l) {
        send_error(s, c, h->req, VP_ERR_BUSY, UINT32_MAX, "out of memory");
        return;
    }
    size_t i = m.cursor && m.cursor <= lm->cap ? (size_t)(m.cursor - 1) : m.cursor ? lm->cap : 0;
    uint32_t n = 0;
    for (; i < lm->cap && n < want; i++)
        if (lm->used[i]) l[n++] = ((const scene_light *)(uintptr_t)lm->vals[i])->l;
    while (i < lm->cap && !lm->used[i]) i++;
    uint64_t next = i < lm->cap ? i + 1 : 0;
    vp_writer w;
    if (out_reserve(c, vp_size_light_list_reply(n), &w)) {
        vp_enc_light_list_reply(&w, h->req, next, l, n);
        out_commit(c, &w);
    } else {
        c->closing = true;
    }
    free(l);
}

bool readback_dispatch(server *s, conn *c, const vp_header *h, const uint8_t *p)
{
    switch (h->type) {
    case VP_MESH_GET:
        on_mesh_get(s, c, h, p);
        return true;
    case VP_MATERIAL_LIST:
        on_material_list(s, c, h, p);
        return true;
    case VP_TEXTURE_GET:
        on_texture_get(s, c, h, p);
        return true;
    case VP_LIGHT_LIST:
        on_light_list(s, c, h, p);
        return true;
    default:
        return false;
    }
}
