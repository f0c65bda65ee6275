/*
 * cli_level_send.c — the scene-model messages a level load and an export
 * send that libvantage has no call for on this branch: MESH_PUT with UVs
 * and tangents, TEXTURE_PUT in chunks, MATERIAL_PUT, ENV_GET and ENV_SET.
 * Each is encoded with the protocol's vp_enc_* and sent with vtc_send /
 * vtc_recv; when the client library gains its own calls for them these
 * become one-line wrappers (or go). Errors: the code, and the server's
 * message in cli_send_err.
 */
#include "cli.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

char cli_send_err[1100];

/* Sends w's frame (request req) and reads up to its reply: want, or the
 * ERROR's code with its message in cli_send_err; pushed frames between
 * are skipped. *p, *len: the reply's payload (valid until the next call). */
static int raw_call(vtc_client *c, vp_writer *w, uint32_t req, uint16_t want, const uint8_t **p, uint32_t *len)
{
    cli_send_err[0] = 0;
    if (w->overflow) {
        snprintf(cli_send_err, sizeof cli_send_err, "out of memory for a request");
        return VTC_ERR_IO;
    }
    if (w->len - VP_HEADER_SIZE > vtc_server(c)->max_payload) {
        snprintf(cli_send_err, sizeof cli_send_err, "a request of %zu bytes, the server takes at most %u",
                 w->len - VP_HEADER_SIZE, vtc_server(c)->max_payload);
        return VP_ERR_TOO_LARGE;
    }
    int rc = vtc_send(c, w->p, w->len);
    for (;;) {
        vp_header h;
        if (rc || (rc = vtc_recv(c, &h, p, -1))) {
            snprintf(cli_send_err, sizeof cli_send_err, "%s", vtc_last_error(c)->msg);
            return rc;
        }
        if (h.req != req) continue; /* an event */
        *len = h.len;
        if (h.type == VP_ERROR) {
            vp_error e;
            if (vp_dec_error(*p, h.len, &e)) return VP_ERR_INTERNAL;
            snprintf(cli_send_err, sizeof cli_send_err, "error %d (%s): %.*s", e.code, vp_strerror(e.code),
                     (int)e.msg_len, (const char *)e.msg);
            return e.code < 0 ? e.code : VP_ERR_INTERNAL;
        }
        if (h.type != want) {
            snprintf(cli_send_err, sizeof cli_send_err, "unexpected reply %s", vp_type_name(h.type));
            return VTC_ERR_IO;
        }
        return VP_OK;
    }
}

/* One frame encoded by enc into a writer of size bytes, sent, answered
 * with ACK (or want). */
static int ack_call(vtc_client *c, vp_writer *w, uint32_t req)
{
    const uint8_t *p;
    uint32_t len;
    int rc = raw_call(c, w, req, VP_ACK, &p, &len);
    vp_writer_free(w);
    return rc;
}

int cli_put_mesh_uv(vtc_client *c, uint16_t class_id, const float *pos, const float *nrm, const float *uv,
                    const float *tan, uint32_t nv, const uint32_t *idx, uint32_t ni)
{
    vp_writer w;
    vp_writer_init_grow(&w);
    uint32_t req = vtc_next_req(c);
    vp_enc_mesh_uv(&w, req, class_id, pos, nrm, uv, tan, nv, idx, ni);
    return ack_call(c, &w, req);
}

int cli_put_texture(vtc_client *c, uint32_t id, uint8_t format, uint8_t flags, const uint8_t *bytes, uint32_t n)
{
    /* chunks that fit the server's frames, 4 MiB at most (a chunk holds the
       daemon's event loop while it is copied) */
    uint32_t max = vtc_server(c)->max_payload - VP_TEXTURE_PUT_HEADER;
    if (max > 4u << 20) max = 4u << 20;
    for (uint32_t off = 0; off < n;) {
        uint32_t len = n - off < max ? n - off : max;
        vp_writer w;
        vp_writer_init_grow(&w);
        uint32_t req = vtc_next_req(c);
        vp_enc_texture_put(&w, req, &(vp_texture_put){.id = id, .format = format, .flags = flags, .total = n,
                                                      .offset = off, .len = len, .data = bytes + off});
        int rc = ack_call(c, &w, req);
        if (rc) return rc;
        off += len;
    }
    return VP_OK;
}

int cli_put_materials(vtc_client *c, const vp_material *m, uint32_t n)
{
    uint32_t step = vtc_server(c)->max_batch;
    for (uint32_t i = 0; i < n; i += step) {
        uint32_t k = n - i < step ? n - i : step;
        vp_writer w;
        vp_writer_init_grow(&w);
        uint32_t req = vtc_next_req(c);
        vp_enc_materials(&w, req, m + i, k);
        int rc = ack_call(c, &w, req);
        if (rc) return rc;
    }
    return VP_OK;
}

int cli_env_get(vtc_client *c, vp_env *out)
{
    vp_writer w;
    vp_writer_init_grow(&w);
    uint32_t req = vtc_next_req(c);
    vp_enc_empty(&w, VP_ENV_GET, req);
    const uint8_t *p;
    uint32_t len;
    int rc = raw_call(c, &w, req, VP_ENV_REPLY, &p, &len);
    vp_writer_free(&w);
    if (!rc && (rc = vp_dec_env(p, len, out)))
        snprintf(cli_send_err, sizeof cli_send_err, "malformed ENV_REPLY: %s", vp_strerror(rc));
    return rc;
}

int cli_env_set(vtc_client *c, const vp_env *e)
{
    vp_writer w;
    vp_writer_init_grow(&w);
    uint32_t req = vtc_next_req(c);
    vp_enc_env(&w, VP_ENV_SET, req, e);
    return ack_call(c, &w, req);
}

int cli_send_fail(const char *what, int rc)
{
    fprintf(stderr, "%s: %s: %s\n", g_prog, what, cli_send_err[0] ? cli_send_err : vtc_strerror(rc));
    return rc == VTC_ERR_IO ? 3 : 1;
}
