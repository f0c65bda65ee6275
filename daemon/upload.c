/*
 * upload.c — texture uploads in chunks (TEXTURE_PUT, protocol.h) and the
 * environment's reply (ENV_GET).
 *
 * An image larger than a frame (max_payload) comes in chunks, in order, on
 * one connection: each carries the id, format, flags and total size and
 * its offset. The connection holds one upload at a time (tex_upload):
 * the whole TEXTURE_PUT payload it will become, allocated at the first
 * chunk (its 16 header bytes, offset 0, are that chunk's own) and filled
 * chunk by chunk. Chunks before the last are not edits: ACK count 0, not
 * journaled, nothing in the scene changes. The last makes the payload an
 * edit (on_edit: journaled whole, decoded, applied), exactly as an image
 * sent in one frame. A chunk that does not continue the upload (another
 * id, format, flags or total, or an offset other than the bytes so far)
 * is refused (STATE) and the upload dropped; so is a closed connection's.
 *
 * Memory: an upload holds its total size from its first chunk; the
 * uploads together (server.upload_bytes) and the textures
 * (scene.texture_mem) stay under lim.max_texture_mem, so neither many
 * slow uploads nor one abandoned half can hold more than the limit.
 */
#include "server_internal.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

void upload_drop(server *s, conn *c)
{
    tex_upload *u = c->upload;
    if (!u) return;
    s->upload_bytes -= u->total;
    free(u->payload);
    free(u);
    c->upload = NULL;
}

/* A chunk refused: the upload (if any) is dropped with it. */
static void refuse(server *s, conn *c, uint32_t req, int code, const char *msg)
{
    upload_drop(s, c);
    send_error(s, c, req, code, UINT32_MAX, msg);
}

/* Opens an upload for first chunk m (payload p): its limits, its buffer. */
static tex_upload *upload_open(server *s, conn *c, uint32_t req, const vp_texture_put *m, const uint8_t *p)
{
    char msg[200];
    const scene_limits *lim = &s->sc->lim;
    uint64_t held = s->sc->texture_mem + s->upload_bytes;
    if (m->total > lim->max_texture_mem || held > lim->max_texture_mem - m->total) {
        snprintf(msg, sizeof msg,
                 "texture %u: an upload of %u bytes does not fit: textures hold %llu bytes and uploads under way "
                 "%llu, the limit is %llu (--max-texture-mem)",
                 m->id, m->total, (unsigned long long)s->sc->texture_mem, (unsigned long long)s->upload_bytes,
                 (unsigned long long)lim->max_texture_mem);
        refuse(s, c, req, VP_ERR_LIMIT, msg);
        return NULL;
    }
    tex_upload *u = calloc(1, sizeof *u);
    uint8_t *payload = malloc((size_t)VP_TEXTURE_PUT_HEADER + m->total);
    if (!u || !payload) {
        free(u);
        free(payload);
        refuse(s, c, req, VP_ERR_BUSY, "out of memory for the upload");
        return NULL;
    }
    memcpy(payload, p, VP_TEXTURE_PUT_HEADER); /* offset 0: the whole image's header as it is */
    *u = (tex_upload){.id = m->id, .total = m->total, .format = m->format, .flags = m->flags, .payload = payload};
    c->upload = u;
    s->upload_bytes += m->total;
    return u;
}

void upload_chunk(server *s, conn *c, const vp_header *h, const uint8_t *p)
{
    vp_texture_put m;
    char msg[200];
    if (vp_dec_texture_put(p, h->len, &m)) {
        upload_drop(s, c);
        on_edit(s, c, h, p); /* refuses it, naming the field */
        return;
    }
    tex_upload *u = c->upload;
    if (!u && m.offset == 0 && m.len == m.total) {
        on_edit(s, c, h, p); /* whole in one frame */
        return;
    }
    if (!u && m.offset != 0) {
        snprintf(msg, sizeof msg,
                 "texture %u: a chunk at offset %u, but no upload is open on this connection (the first chunk "
                 "has offset 0)",
                 m.id, m.offset);
        refuse(s, c, h->req, VP_ERR_STATE, msg);
        return;
    }
    if (u && (m.id != u->id || m.format != u->format || m.flags != u->flags || m.total != u->total ||
              m.offset != u->got)) {
        snprintf(msg, sizeof msg,
                 "texture %u: chunk (format %u, flags 0x%x, %u bytes at offset %u of %u) does not continue the "
                 "upload of texture %u (format %u, flags 0x%x, %u of %u bytes so far): upload dropped",
                 m.id, m.format, m.flags, m.len, m.offset, m.total, u->id, u->format, u->flags, u->got, u->total);
        refuse(s, c, h->req, VP_ERR_STATE, msg);
        return;
    }
    if (!u && !(u = upload_open(s, c, h->req, &m, p))) return;
    memcpy(u->payload + VP_TEXTURE_PUT_HEADER + m.offset, m.data, m.len);
    u->got += m.len;
    if (u->got < u->total) {
        reply_ack(c, h->req, s->sc->epoch, 0);
        return;
    }
    /* complete: the assembled payload is the edit, as if sent whole */
    vp_header whole = *h;
    whole.len = VP_TEXTURE_PUT_HEADER + u->total;
    uint8_t *payload = u->payload;
    u->payload = NULL;
    upload_drop(s, c);
    on_edit(s, c, &whole, payload);
    free(payload);
}

void on_env_get(server *s, conn *c, uint32_t req)
{
    vp_writer w;
    if (!out_reserve(c, vp_size_env(), &w)) {
        c->closing = true;
        return;
    }
    vp_enc_env(&w, VP_ENV_REPLY, req, &s->sc->env);
    out_commit(c, &w);
}
