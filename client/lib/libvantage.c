/*
 * libvantage.c — see vantage.h. Blocking sockets with poll() timeouts; one
 * growing receive buffer; each call encodes into a growing send buffer.
 */
#include "vantage.h"
#include "vtc_endpoints.h"
#include "vp_grow.h"

#include <arpa/inet.h>
#include <errno.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <time.h>
#include <unistd.h>

struct vtc_client {
    int fd;
    int timeout_ms;
    uint32_t next_req;
    vp_hello_ok server;
    vtc_error err;
    uint8_t *in;            /* received bytes; [in_pos, in_len) unread */
    size_t in_len, in_pos, in_cap;
    size_t consumed;        /* the frame handed out last, released on next recv */
    uint8_t *out;
    size_t out_cap;
    vp_writer w;            /* the request being encoded into out */
    bool out_nomem;         /* request() could not make room: VTC_ERR_IO */
    uint32_t stream_req;    /* the frame stream's req, 0 = none */
    vtc_error stream_err;    /* code != 0: an ERROR ended the stream during another call */
    vtc_connect_opts opts;  /* how it connected (NOT_WRITER's redirect connects the same way) */
    char *token, *name;     /* opts' strings, owned */
    char endpoint[256];     /* where it is connected */
};

const char *vtc_strerror(int code)
{
    switch (code) {
        VTC_ERRORS(VP_ERR_MSG_ROW_)
    }
    return vp_strerror(code);
}

static int set_err(vtc_client *c, int code, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
static int set_err(vtc_client *c, int code, const char *fmt, ...)
{
    c->err.code = code;
    c->err.index = UINT32_MAX;
    c->err.timed_out = false;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(c->err.msg, sizeof c->err.msg, fmt, ap);
    va_end(ap);
    return code;
}

static int timed_out(vtc_client *c, const char *what)
{
    set_err(c, VTC_ERR_IO, "%s", what);
    c->err.timed_out = true;
    return VTC_ERR_IO;
}

const vtc_error *vtc_last_error(const vtc_client *c) { return &c->err; }
const vp_hello_ok *vtc_server(const vtc_client *c) { return &c->server; }
int vtc_fd(const vtc_client *c) { return c->fd; }
uint32_t vtc_next_req(vtc_client *c) { return ++c->next_req ? c->next_req : ++c->next_req; }

int vtc_send(vtc_client *c, const uint8_t *data, size_t len)
{
    size_t off = 0;
    while (off < len) {
        ssize_t n = send(c->fd, data + off, len - off, MSG_NOSIGNAL);
        if (n > 0) {
            off += (size_t)n;
            continue;
        }
        if (n < 0 && errno == EINTR) continue;
        if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) return timed_out(c, "send: timed out"); /* SO_SNDTIMEO */
        return set_err(c, VTC_ERR_IO, "send: %s", n < 0 ? strerror(errno) : "connection closed");
    }
    return VP_OK;
}

int vtc_recv(vtc_client *c, vp_header *h, const uint8_t **payload, int timeout_ms)
{
    if (timeout_ms < 0) timeout_ms = c->timeout_ms;
    c->in_pos += c->consumed;
    c->consumed = 0;
    for (;;) {
        size_t fs;
        int rc = vp_frame_check(c->in + c->in_pos, c->in_len - c->in_pos, VTC_MAX_REPLY, h, &fs);
        if (rc == VP_OK) {
            *payload = c->in + c->in_pos + VP_HEADER_SIZE;
            c->consumed = fs;
            return VP_OK;
        }
        if (rc != VP_NEED_MORE) return set_err(c, VTC_ERR_IO, "bad frame from the server: %s", vp_strerror(rc));
        /* make room: compact, then grow */
        if (c->in_pos) {
            memmove(c->in, c->in + c->in_pos, c->in_len - c->in_pos);
            c->in_len -= c->in_pos;
            c->in_pos = 0;
        }
        if (c->in_cap - c->in_len < 65536) {
            size_t cap = vp_grow_cap(c->in_cap, c->in_len + 65536, 1u << 17, 1, SIZE_MAX);
            uint8_t *n = cap ? realloc(c->in, cap) : NULL;
            if (!n) return set_err(c, VTC_ERR_IO, "out of memory");
            c->in = n;
            c->in_cap = cap;
        }
        struct pollfd p = {.fd = c->fd, .events = POLLIN};
        int r = poll(&p, 1, timeout_ms);
        if (r == 0 && timeout_ms == 0) return VP_NEED_MORE; /* a poll, not a wait */
        if (r == 0) return timed_out(c, "timed out waiting for the server");
        if (r < 0) {
            if (errno == EINTR) continue;
            return set_err(c, VTC_ERR_IO, "poll: %s", strerror(errno));
        }
        ssize_t n = recv(c->fd, c->in + c->in_len, c->in_cap - c->in_len, 0);
        if (n > 0) {
            c->in_len += (size_t)n;
            continue;
        }
        if (n < 0 && errno == EINTR) continue;
        return set_err(c, VTC_ERR_IO, "connection closed by the server%s%s", n < 0 ? ": " : "",
                       n < 0 ? strerror(errno) : "");
    }
}

/* Starts a request: a writer over the client's send buffer with room for
 * size bytes (the encoder's vp_size_*), and the request's id in *req.
 * When the buffer cannot grow the writer has no room (the encoder only
 * sets overflow) and the call that sends it answers VTC_ERR_IO, out of
 * memory, so a caller encodes and calls without a check in between. */
static vp_writer *request(vtc_client *c, size_t size, uint32_t *req)
{
    *req = vtc_next_req(c);
    c->out_nomem = false;
    if (c->out_cap < size) {
        size_t cap = vp_grow_cap(c->out_cap, size, 4096, 1, SIZE_MAX);
        uint8_t *n = cap ? realloc(c->out, cap) : NULL;
        if (!n) {
            set_err(c, VTC_ERR_IO, "out of memory for a request of %zu bytes", size);
            c->out_nomem = true;
            vp_writer_init(&c->w, c->out, 0);
            return &c->w;
        }
        c->out = n;
        c->out_cap = cap;
    }
    vp_writer_init(&c->w, c->out, c->out_cap);
    return &c->w;
}

/* The server's ERROR frame as a vtc_error; returns its (negative) code. */
static int error_from(vtc_error *out, const uint8_t *p, uint32_t len)
{
    vp_error e;
    if (vp_dec_error(p, len, &e)) {
        *out = (vtc_error){.code = VTC_ERR_IO, .index = UINT32_MAX};
        snprintf(out->msg, sizeof out->msg, "malformed ERROR from the server");
    } else {
        *out = (vtc_error){.code = e.code < 0 ? e.code : VP_ERR_INTERNAL, .index = e.index};
        snprintf(out->msg, sizeof out->msg, "%.*s", (int)e.msg_len, (const char *)e.msg);
    }
    return out->code;
}

/* Sends what w holds and reads the reply to req: an ERROR becomes the
 * return value; another type than want is a protocol error. EVENT frames
 * and the frame stream's frames arriving in between are skipped. */
static int roundtrip(vtc_client *c, vp_writer *w, uint32_t req, uint16_t want, const uint8_t **p, uint32_t *len)
{
    if (c->out_nomem) return VTC_ERR_IO; /* request() said why */
    if (w->overflow) return set_err(c, VP_ERR_LIMIT, "request too large for the send buffer");
    /* a frame past the server's limit would only get the connection closed:
       refuse it here, with the sizes, and keep the connection */
    if (c->server.max_payload && w->len - VP_HEADER_SIZE > c->server.max_payload)
        return set_err(c, VP_ERR_TOO_LARGE, "a %s request of %zu bytes, the server takes at most %u",
                       vp_type_name((uint16_t)(w->p[4] | w->p[5] << 8)), w->len - VP_HEADER_SIZE,
                       c->server.max_payload);
    int rc = vtc_send(c, w->p, w->len);
    if (rc) return rc;
    for (;;) {
        vp_header h;
        if ((rc = vtc_recv(c, &h, p, -1))) return rc;
        if (h.type == VP_EVENT || h.type == VP_MARKED || h.type == VP_SELECTED)
            continue; /* pushed: vtc_recv's callers see them */
        /* a frame kept across a re-aim carries the req it started under */
        if (c->stream_req && h.req != req && (h.req == c->stream_req || h.type == VP_FRAME)) {
            /* the frame stream's: a frame is dropped (the next one is
               newer); an error ends the stream and waits for vtc_wait_frame */
            if (h.type == VP_ERROR) {
                error_from(&c->stream_err, *p, h.len);
                c->stream_req = 0;
            }
            continue;
        }
        if (h.type == VP_ERROR) return error_from(&c->err, *p, h.len);
        if (h.req != req || h.type != want)
            return set_err(c, VTC_ERR_IO, "unexpected reply %s (req %u) to request %u", vp_type_name(h.type), h.req,
                           req);
        *len = h.len;
        return VP_OK;
    }
}

/* A reply the client cannot decode keeps the decoder's code, and says
 * which reply and why; VP_OK passes through. */
static int decoded(vtc_client *c, uint16_t type, int rc)
{
    if (rc == VP_OK) return VP_OK;
    return set_err(c, rc, "malformed %s from the server: %s", vp_type_name(type), vp_strerror(rc));
}

/* Decodes a reply payload into out (adapters: one signature for call). */
typedef int (*reply_dec)(const uint8_t *p, uint32_t len, void *out);

/* The one blocking call: sends the request encoded into w (see request),
 * waits for its reply of type want and decodes it into out with dec
 * (NULL: the reply's type alone is checked). Returns VP_OK, the server's
 * ERROR code, the decoder's code (decoded) or VTC_ERR_IO. */
static int redirect(vtc_client *c, const char *endpoint);

static int call(vtc_client *c, vp_writer *w, uint32_t req, uint16_t want, reply_dec dec, void *out)
{
    const uint8_t *p;
    uint32_t len;
    int rc = roundtrip(c, w, req, want, &p, &len);
    /* a replica's NOT_WRITER names the writer first: the same request
       again, there (its bytes kept: the new connection's HELLO reuses the
       send buffer). While no writer is known ("-"), or the one named cannot
       be reached (it died and the replica has not seen it yet), the request
       is asked again here every 100 ms: a failover takes about the lease's
       TTL, and the call waits it out (up to its timeout, 10 s at most) */
    uint8_t *copy = NULL;
    size_t clen = 0;
    struct timespec t0;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    long budget_ms = c->timeout_ms > 0 && c->timeout_ms < 10000 ? c->timeout_ms : 10000;
    for (int hop = 0; rc == VP_ERR_NOT_WRITER && !c->opts.no_follow && hop < 3;) {
        if (!copy) {
            if (!(copy = malloc(w->len))) break;
            memcpy(copy, w->p, w->len);
            clen = w->len;
        }
        char ep[256];
        int n = 0;
        while (n < (int)sizeof ep - 1 && c->err.msg[n] && c->err.msg[n] != ' ') ep[n] = c->err.msg[n], n++;
        ep[n] = 0;
        bool named = n && strcmp(ep, "-") && strcmp(ep, c->endpoint);
        if (named && redirect(c, ep) == VP_OK) {
            hop++;
        } else {
            struct timespec t;
            clock_gettime(CLOCK_MONOTONIC, &t);
            long ms = (long)(t.tv_sec - t0.tv_sec) * 1000 + (t.tv_nsec - t0.tv_nsec) / 1000000;
            if (ms + 100 > budget_ms) break; /* c->err says why: NOT_WRITER, or the writer unreachable */
            nanosleep(&(struct timespec){.tv_nsec = 100000000}, NULL);
        }
        vp_writer again;
        vp_writer_init(&again, copy, clen);
        again.len = clen;
        rc = roundtrip(c, &again, req, want, &p, &len);
    }
    free(copy);
    if (rc || !dec) return rc;
    return decoded(c, want, dec(p, len, out));
}

static int dec_ack(const uint8_t *p, uint32_t len, void *out)
{
    vp_ack a;
    return vp_dec_ack(p, len, out ? out : &a);
}
static int dec_hello_ok(const uint8_t *p, uint32_t len, void *out) { return vp_dec_hello_ok(p, len, out); }
static int dec_stats_reply(const uint8_t *p, uint32_t len, void *out) { return vp_dec_stats_reply(p, len, out); }
static int dec_metrics_reply(const uint8_t *p, uint32_t len, void *out) { return vp_dec_metrics_reply(p, len, out); }
static int dec_add_reply(const uint8_t *p, uint32_t len, void *out) { return vp_dec_add_reply(p, len, out); }
static int dec_list_reply(const uint8_t *p, uint32_t len, void *out) { return vp_dec_list_reply(p, len, out); }
static int dec_vis_result(const uint8_t *p, uint32_t len, void *out) { return vp_dec_vis_result(p, len, out); }
static int dec_frame(const uint8_t *p, uint32_t len, void *out) { return vp_dec_frame(p, len, out); }
static int dec_light_tiles(const uint8_t *p, uint32_t len, void *out) { return vp_dec_light_tiles(p, len, out); }
static int dec_list_names(const uint8_t *p, uint32_t len, void *out) { return vp_dec_names(p, len, true, out); }
static int dec_begun(const uint8_t *p, uint32_t len, void *out) { return vp_dec_sublevel_begun(p, len, out); }
static int dec_infos(const uint8_t *p, uint32_t len, void *out) { return vp_dec_sublevel_infos(p, len, out); }
static int dec_destroyed(const uint8_t *p, uint32_t len, void *out) { return vp_dec_destroyed(p, len, out); }

/* SUBLEVEL_IDS as the ids view and its count */
typedef struct ids_reply {
    uint32_t n;
    const uint8_t *ids;
} ids_reply;
static int dec_sublevel_ids(const uint8_t *p, uint32_t len, void *out)
{
    ids_reply *r = out;
    return vp_dec_sublevel_ids(p, len, &r->n, &r->ids);
}

/* A request with an empty payload (type) and its reply. */
static int empty_call(vtc_client *c, uint16_t type, uint16_t want, reply_dec dec, void *out)
{
    uint32_t req;
    vp_writer *w = request(c, vp_size_empty(), &req);
    vp_enc_empty(w, type, req);
    return call(c, w, req, want, dec, out);
}

/* An edit answered with ACK: its epoch in *epoch (may be NULL). */
static int ack_epoch(vtc_client *c, vp_writer *w, uint32_t req, uint64_t *epoch)
{
    vp_ack a;
    int rc = call(c, w, req, VP_ACK, dec_ack, &a);
    if (!rc && epoch) *epoch = a.epoch;
    return rc;
}

static int connect_one(const vtc_connect_opts *o, vtc_client **out, char *err, size_t errlen);

int vtc_connect(const vtc_connect_opts *o, vtc_client **out, char *err, size_t errlen)
{
    char tmp[256];
    if (!err) {
        err = tmp;
        errlen = sizeof tmp;
    }
    *out = NULL;
    vtc_connect_opts d = o ? *o : (vtc_connect_opts){0};
    if (!d.endpoints) return connect_one(&d, out, err, errlen);
    /* a list: the endpoints in turn, from a random one for viewers */
    const char *eps[64];
    size_t lens[64], n = vtc_endpoint_split(d.endpoints, eps, lens, 64);
    if (!n) {
        snprintf(err, errlen, "no endpoint in \"%.100s\"", d.endpoints);
        return VTC_ERR_IO;
    }
    for (size_t i = 0; i < n; i++) { /* a malformed entry is refused before any is tried */
        char host[256], path[256];
        vtc_connect_opts one = d;
        if (!vtc_endpoint_parse(eps[i], lens[i], &one, host, sizeof host, path, sizeof path)) {
            snprintf(err, errlen, "bad endpoint \"%.*s\": use HOST:PORT, [IPv6]:PORT or a socket path", (int)lens[i],
                     eps[i]);
            return VTC_ERR_IO;
        }
    }
    size_t first = 0;
    if (d.role != VP_ROLE_EDITOR) {
        struct timespec t;
        clock_gettime(CLOCK_REALTIME, &t);
        first = (size_t)(t.tv_nsec ^ getpid()) % n;
    }
    int rc = VTC_ERR_IO;
    for (size_t k = 0; k < n; k++) {
        size_t i = (first + k) % n;
        char host[256], path[256];
        vtc_connect_opts one = d;
        vtc_endpoint_parse(eps[i], lens[i], &one, host, sizeof host, path, sizeof path);
        if ((rc = connect_one(&one, out, err, errlen)) == VP_OK) return VP_OK;
        if (rc == VP_ERR_AUTH) return rc; /* the token is wrong everywhere */
    }
    return rc;
}

/* Replaces c's connection by one to endpoint, with the same role, token
 * and name (NOT_WRITER's redirect). VP_OK, or the error in c->err. */
static int redirect(vtc_client *c, const char *endpoint)
{
    vtc_connect_opts d = c->opts;
    char host[256], path[256];
    if (!vtc_endpoint_parse(endpoint, strlen(endpoint), &d, host, sizeof host, path, sizeof path))
        return set_err(c, VTC_ERR_IO, "the writer's endpoint \"%.200s\" is not HOST:PORT or a socket path", endpoint);
    d.endpoints = NULL;
    vtc_client *n = NULL;
    char err[600];
    int rc = connect_one(&d, &n, err, sizeof err);
    if (rc) return set_err(c, rc, "redirected to the writer at %s: %s", endpoint, err);
    /* n takes c's place: c's pointer stays valid for the caller */
    close(c->fd);
    free(c->in);
    free(c->out);
    free(c->token);
    free(c->name);
    *c = *n;
    c->opts.token = c->token;
    c->opts.name = c->name;
    free(n);
    return VP_OK;
}

static int connect_one(const vtc_connect_opts *o, vtc_client **out, char *err, size_t errlen)
{
    vtc_connect_opts d = *o;
    vtc_client *c = calloc(1, sizeof *c);
    if (!c) {
        snprintf(err, errlen, "out of memory");
        return VTC_ERR_IO;
    }
    c->timeout_ms = d.timeout_ms == 0 ? 10000 : d.timeout_ms < 0 ? -1 : d.timeout_ms;
    if ((c->fd = vtc_connect_fd(&d, err, errlen)) < 0) {
        free(c);
        return VTC_ERR_IO;
    }
    if (c->timeout_ms > 0) {
        /* the per-call timeout holds for sending too: a server that stops
           reading makes send() give up with EAGAIN */
        struct timeval tv = {.tv_sec = c->timeout_ms / 1000, .tv_usec = (c->timeout_ms % 1000) * 1000};
        setsockopt(c->fd, SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof tv);
    }
    const char *name = d.name ? d.name : "libvantage";
    size_t tl = d.token ? strlen(d.token) : 0, nl = strlen(name);
    vp_hello hi = {.magic = VP_MAGIC, .version = VP_VERSION, .role = (uint8_t)d.role,
                   .token_len = (uint8_t)(tl > VP_MAX_TOKEN ? VP_MAX_TOKEN : tl), .token = (const uint8_t *)d.token,
                   .name_len = (uint8_t)(nl > VP_MAX_NAME ? VP_MAX_NAME : nl), .name = (const uint8_t *)name};
    uint32_t req;
    vp_writer *w = request(c, vp_size_hello(&hi), &req);
    vp_enc_hello(w, req, &hi);
    int rc = call(c, w, req, VP_HELLO_OK, dec_hello_ok, &c->server);
    if (rc) {
        snprintf(err, errlen, "handshake: %s", c->err.msg);
        vtc_close(c);
        return rc;
    }
    c->opts = d;
    c->opts.endpoints = NULL;
    c->token = d.token ? strdup(d.token) : NULL;
    c->name = strdup(name);
    c->opts.token = c->token;
    c->opts.name = c->name;
    if (d.unix_path && *d.unix_path) snprintf(c->endpoint, sizeof c->endpoint, "%s", d.unix_path);
    else snprintf(c->endpoint, sizeof c->endpoint, "%s:%d", d.host && *d.host ? d.host : "127.0.0.1",
                  d.port ? d.port : VTC_DEFAULT_PORT);
    *out = c;
    return VP_OK;
}

void vtc_close(vtc_client *c)
{
    if (!c) return;
    if (c->fd >= 0) close(c->fd);
    free(c->in);
    free(c->out);
    free(c->token);
    free(c->name);
    free(c);
}

int vtc_ping(vtc_client *c)
{
    const uint8_t *p;
    uint32_t len, req;
    vp_writer *w = request(c, vp_size_ping(7), &req);
    vp_enc_ping(w, VP_PING, req, (const uint8_t *)"vantage", 7);
    int rc = roundtrip(c, w, req, VP_PONG, &p, &len);
    if (rc) return rc;
    return len == 7 && !memcmp(p, "vantage", 7) ? VP_OK : set_err(c, VTC_ERR_IO, "PONG did not echo the PING");
}

int vtc_stats(vtc_client *c, vp_stats_reply *out)
{
    return empty_call(c, VP_STATS, VP_STATS_REPLY, dec_stats_reply, out);
}

int vtc_metrics(vtc_client *c, const char **text, size_t *text_len)
{
    vp_metrics_reply m;
    int rc = empty_call(c, VP_METRICS, VP_METRICS_REPLY, dec_metrics_reply, &m);
    if (rc) return rc;
    *text = (const char *)m.text;
    *text_len = m.text_len;
    return VP_OK;
}

int vtc_add(vtc_client *c, const vp_entity *e, uint32_t n, uint32_t *handles, uint64_t *epoch)
{
    uint32_t req;
    vp_writer *w = request(c, vp_size_entities(n), &req);
    vp_enc_entities(w, VP_ENTITY_ADD, req, e, n);
    vp_add_reply r;
    int rc = call(c, w, req, VP_ENTITY_ADD_REPLY, dec_add_reply, &r);
    if (rc) return rc;
    if (r.count != n)
        return set_err(c, VP_ERR_COUNT, "malformed entity_add_reply from the server: %u handles for %u records",
                       r.count, n);
    for (uint32_t i = 0; handles && i < n; i++) handles[i] = vp_handle_get(&r, i);
    if (epoch) *epoch = r.epoch;
    return VP_OK;
}

int vtc_update(vtc_client *c, const vp_entity *e, uint32_t n, uint64_t *epoch)
{
    uint32_t req;
    vp_writer *w = request(c, vp_size_entities(n), &req);
    vp_enc_entities(w, VP_ENTITY_UPDATE, req, e, n);
    return ack_epoch(c, w, req, epoch);
}

/* An id batch of type answered with reply (dec into out). */
static int ids_call(vtc_client *c, uint16_t type, const uint64_t *ids, uint32_t n, uint16_t reply, reply_dec dec,
                    void *out)
{
    uint32_t req;
    vp_writer *w = request(c, vp_size_ids(n), &req);
    vp_enc_ids(w, type, req, ids, n);
    return call(c, w, req, reply, dec, out);
}

static int remove_ids(vtc_client *c, uint16_t type, const uint64_t *ids, uint32_t n, uint64_t *epoch)
{
    vp_ack a;
    int rc = ids_call(c, type, ids, n, VP_ACK, dec_ack, &a);
    if (!rc && epoch) *epoch = a.epoch;
    return rc;
}

int vtc_remove(vtc_client *c, const uint64_t *ids, uint32_t n, uint64_t *epoch)
{
    return remove_ids(c, VP_ENTITY_REMOVE, ids, n, epoch);
}

int vtc_remove_occluders(vtc_client *c, const uint64_t *ids, uint32_t n, uint64_t *epoch)
{
    return remove_ids(c, VP_OCCLUDER_REMOVE, ids, n, epoch);
}

int vtc_get(vtc_client *c, const uint64_t *ids, uint32_t n, vp_list_reply *out)
{
    return ids_call(c, VP_ENTITY_GET, ids, n, VP_ENTITY_LIST_REPLY, dec_list_reply, out);
}

int vtc_list(vtc_client *c, uint64_t cursor, uint32_t max, vp_list_reply *out)
{
    uint32_t req;
    vp_writer *w = request(c, vp_size_list(), &req);
    vp_enc_list(w, req, &(vp_list){.cursor = cursor, .max = max});
    return call(c, w, req, VP_ENTITY_LIST_REPLY, dec_list_reply, out);
}

int vtc_query(vtc_client *c, const vp_view *views, uint32_t nviews, uint8_t flags, float min_area, vp_vis_result *out)
{
    return vtc_query_sub(c, views, nviews, flags, min_area, NULL, 0, out);
}

int vtc_query_sub(vtc_client *c, const vp_view *views, uint32_t nviews, uint8_t flags, float min_area,
                  const uint16_t *subs, uint32_t nsub, vp_vis_result *out)
{
    flags &= (uint8_t)~VP_Q_SUBLEVELS; /* the list is there iff subs is */
    uint32_t req;
    vp_writer *w = request(c, vp_size_vis_query_sub(flags, nviews, subs, nsub), &req);
    vp_enc_vis_query_sub(w, req, flags, min_area, views, nviews, subs, nsub);
    return call(c, w, req, VP_VIS_RESULT, dec_vis_result, out);
}

int vtc_render(vtc_client *c, const vp_render *m, vp_frame *out)
{
    uint32_t req;
    vp_writer *w = request(c, vp_size_render(), &req);
    vp_enc_render(w, req, m);
    return call(c, w, req, VP_FRAME, dec_frame, out);
}

int vtc_light_query(vtc_client *c, const vp_light_query *m, vp_light_tiles *out)
{
    uint32_t req;
    vp_writer *w = request(c, vp_size_light_query(), &req);
    vp_enc_light_query(w, req, m);
    return call(c, w, req, VP_LIGHT_TILES, dec_light_tiles, out);
}

int vtc_frame_subscribe(vtc_client *c, const vp_frame_sub *m)
{
    uint32_t req;
    vp_writer *w = request(c, vp_size_frame_sub(), &req);
    vp_enc_frame_sub(w, req, m);
    int rc = call(c, w, req, VP_ACK, dec_ack, NULL);
    if (rc) return rc;
    /* frames of the old view already on their way (old req) are still
       handed out by vtc_wait_frame: they are the latest there is */
    c->stream_req = req;
    c->stream_err.code = 0;
    return VP_OK;
}

int vtc_frame_unsubscribe(vtc_client *c)
{
    int rc = empty_call(c, VP_FRAME_UNSUBSCRIBE, VP_ACK, dec_ack, NULL);
    c->stream_req = 0;
    return rc;
}

int vtc_wait_frame(vtc_client *c, vp_frame *out, int timeout_ms)
{
    for (;;) {
        if (c->stream_err.code) {
            c->err = c->stream_err;
            c->stream_err.code = 0;
            return c->err.code;
        }
        if (!c->stream_req) return set_err(c, VP_ERR_STATE, "no frame stream (vtc_frame_subscribe first)");
        vp_header h;
        const uint8_t *p;
        int rc = vtc_recv(c, &h, &p, timeout_ms);
        if (rc) return rc;
        if (h.type == VP_ERROR && h.req == c->stream_req) {
            error_from(&c->stream_err, p, h.len);
            c->stream_req = 0;
            continue;
        }
        if (h.type != VP_FRAME) continue; /* events, or a stray reply: not ours to keep */
        return decoded(c, VP_FRAME, vp_dec_frame(p, h.len, out));
    }
}

int vtc_subscribe(vtc_client *c, uint32_t kinds)
{
    uint32_t req;
    vp_writer *w = request(c, vp_size_subscribe(), &req);
    vp_enc_subscribe(w, req, kinds);
    return call(c, w, req, VP_ACK, dec_ack, NULL);
}

int vtc_sublevel_ids(vtc_client *c, const char *const *names, uint32_t n, uint16_t *ids)
{
    uint32_t req;
    vp_writer *w = request(c, vp_size_names(names, NULL, n), &req);
    vp_enc_names(w, VP_SUBLEVEL_NAMES, req, names, NULL, n);
    ids_reply r;
    int rc = call(c, w, req, VP_SUBLEVEL_IDS, dec_sublevel_ids, &r);
    if (rc) return rc;
    if (r.n != n)
        return set_err(c, VP_ERR_COUNT, "malformed sublevel_ids from the server: %u ids for %u names", r.n, n);
    for (uint32_t i = 0; i < n; i++) ids[i] = vp_sublevel_id_get(r.ids, r.n, i);
    return VP_OK;
}

int vtc_sublevel_list(vtc_client *c, vp_name_list *out)
{
    return empty_call(c, VP_SUBLEVEL_LIST, VP_SUBLEVEL_LIST_REPLY, dec_list_names, out);
}

/* The next pushed frame of type (others, stray replies, are dropped). */
static int wait_pushed(vtc_client *c, uint16_t type, int timeout_ms, const uint8_t **p, uint32_t *len)
{
    for (;;) {
        vp_header h;
        int rc = vtc_recv(c, &h, p, timeout_ms);
        if (rc) return rc;
        if (h.type != type) continue; /* not ours to keep */
        *len = h.len;
        return VP_OK;
    }
}

int vtc_wait_event(vtc_client *c, vp_event *out, int timeout_ms)
{
    const uint8_t *p;
    uint32_t len;
    int rc = wait_pushed(c, VP_EVENT, timeout_ms, &p, &len);
    return rc ? rc : decoded(c, VP_EVENT, vp_dec_event(p, len, out));
}

int vtc_wait_selected(vtc_client *c, vp_selected *out, int timeout_ms)
{
    const uint8_t *p;
    uint32_t len;
    int rc = wait_pushed(c, VP_SELECTED, timeout_ms, &p, &len);
    return rc ? rc : decoded(c, VP_SELECTED, vp_dec_selected(p, len, out));
}

int vtc_put_lights(vtc_client *c, const vp_light *l, uint32_t n)
{
    uint32_t req;
    vp_writer *w = request(c, vp_size_lights(n), &req);
    vp_enc_lights(w, req, l, n);
    return call(c, w, req, VP_ACK, dec_ack, NULL);
}

int vtc_put_occluder(vtc_client *c, uint64_t id, const double origin[3], const float *verts, uint32_t ntris)
{
    uint32_t req;
    vp_writer *w = request(c, vp_size_occluder(ntris), &req);
    vp_enc_occluder(w, req, id, origin, verts, ntris);
    return call(c, w, req, VP_ACK, dec_ack, NULL);
}

int vtc_put_mesh(vtc_client *c, uint16_t class_id, const float *pos, const float *nrm, uint32_t nv,
                 const uint32_t *idx, uint32_t ni)
{
    uint32_t req;
    vp_writer *w = request(c, vp_size_mesh(nv, ni, nrm != NULL), &req);
    vp_enc_mesh(w, req, class_id, pos, nrm, nv, idx, ni);
    return call(c, w, req, VP_ACK, dec_ack, NULL);
}

/* ---- the scene model --------------------------------------------------------------- */

void vtc_entity_trs(vp_entity *e, uint64_t id, uint16_t class_id, const double pos[3], const float rot[4],
                    const float scale[3])
{
    memset(e, 0, sizeof *e);
    e->id = id;
    e->class_id = class_id;
    e->flags = VP_ENT_TRANSFORM;
    memcpy(e->pos, pos, sizeof e->pos);
    memcpy(e->rot, rot, sizeof e->rot);
    memcpy(e->scale, scale, sizeof e->scale);
}

int vtc_transform_set(vtc_client *c, const vp_transform *t, uint32_t n, uint64_t *epoch)
{
    uint32_t req;
    vp_writer *w = request(c, vp_size_transforms(n), &req);
    vp_enc_transforms(w, req, t, n);
    return ack_epoch(c, w, req, epoch);
}

int vtc_material_put(vtc_client *c, const vp_material *m, uint32_t n, uint64_t *epoch)
{
    uint32_t req;
    vp_writer *w = request(c, vp_size_materials(n), &req);
    vp_enc_materials(w, req, m, n);
    return ack_epoch(c, w, req, epoch);
}

int vtc_material_remove(vtc_client *c, const uint64_t *ids, uint32_t n, uint64_t *epoch)
{
    return remove_ids(c, VP_MATERIAL_REMOVE, ids, n, epoch);
}

int vtc_put_occluder_flags(vtc_client *c, uint64_t id, uint32_t flags, const double origin[3], const float *verts,
                           uint32_t ntris)
{
    uint32_t req;
    vp_writer *w = request(c, vp_size_occluder(ntris), &req);
    vp_enc_occluder_flags(w, req, id, flags, origin, verts, ntris);
    return call(c, w, req, VP_ACK, dec_ack, NULL);
}

int vtc_put_mesh_uv(vtc_client *c, uint16_t class_id, const float *pos, const float *nrm, const float *uv,
                    const float *tan, uint32_t nv, const uint32_t *idx, uint32_t ni)
{
    uint32_t req;
    vp_writer *w = request(c, vp_size_mesh_uv(nv, ni, nrm != NULL, uv != NULL, tan != NULL), &req);
    vp_enc_mesh_uv(w, req, class_id, pos, nrm, uv, tan, nv, idx, ni);
    return call(c, w, req, VP_ACK, dec_ack, NULL);
}

/* ---- sub-level loads -------------------------------------------------------------- */

/* A sub-level name the wire takes (1..255 bytes), or VP_ERR_INVALID. */
static int sublevel_name_ok(vtc_client *c, const char *name)
{
    size_t l = strlen(name);
    return l == 0 || l > VP_MAX_NAME ? set_err(c, VP_ERR_INVALID, "sub-level names are 1..255 bytes") : VP_OK;
}

int vtc_sublevel_begin(vtc_client *c, const char *name, uint16_t classes, vp_sublevel_begun *out)
{
    if (sublevel_name_ok(c, name)) return VP_ERR_INVALID;
    vp_sublevel_begin m = {.classes = classes, .name_len = (uint8_t)strlen(name), .name = (const uint8_t *)name};
    uint32_t req;
    vp_writer *w = request(c, vp_size_sublevel_begin(&m), &req);
    vp_enc_sublevel_begin(w, req, &m);
    return call(c, w, req, VP_SUBLEVEL_BEGUN, dec_begun, out);
}

int vtc_sublevel_commit(vtc_client *c, vp_ack *out)
{
    return empty_call(c, VP_SUBLEVEL_COMMIT, VP_ACK, dec_ack, out);
}

int vtc_sublevel_abort(vtc_client *c, vp_ack *out)
{
    return empty_call(c, VP_SUBLEVEL_ABORT, VP_ACK, dec_ack, out);
}

int vtc_sublevel_unload(vtc_client *c, const char *name, vp_ack *out)
{
    if (sublevel_name_ok(c, name)) return VP_ERR_INVALID;
    uint32_t req;
    vp_writer *w = request(c, vp_size_sublevel_name(name), &req);
    vp_enc_sublevel_name(w, VP_SUBLEVEL_UNLOAD, req, name);
    return call(c, w, req, VP_ACK, dec_ack, out);
}

int vtc_sublevel_info(vtc_client *c, vp_sublevel_infos *out)
{
    return empty_call(c, VP_SUBLEVEL_INFO, VP_SUBLEVEL_INFO_REPLY, dec_infos, out);
}

int vtc_mark(vtc_client *c, const vp_mark *m, uint32_t *sent)
{
    uint32_t req;
    vp_writer *w = request(c, vp_size_mark(), &req);
    vp_enc_mark(w, req, m);
    vp_ack a;
    int rc = call(c, w, req, VP_ACK, dec_ack, &a);
    if (!rc && sent) *sent = a.count;
    return rc;
}

int vtc_select(vtc_client *c, const uint64_t *ids, uint32_t n, uint32_t *sent)
{
    if (n > VP_SELECT_MAX)
        return set_err(c, VP_ERR_COUNT, "a selection of %u ids (at most %u)", n, VP_SELECT_MAX);
    uint32_t req;
    vp_writer *w = request(c, vp_size_select(n), &req);
    vp_enc_select(w, req, ids, n);
    vp_ack a;
    int rc = call(c, w, req, VP_ACK, dec_ack, &a);
    if (!rc && sent) *sent = a.count;
    return rc;
}

int vtc_send_destruction(vtc_client *c, const vp_destroy *m, vp_destroyed *out)
{
    uint32_t req;
    vp_writer *w = request(c, vp_size_destroy(), &req);
    vp_enc_destroy(w, req, m);
    return call(c, w, req, VP_DESTROYED, dec_destroyed, out);
}

/* ---- textures and the environment ---------------------------------------------- */

int vtc_texture_format(const uint8_t *p, size_t n)
{
    static const uint8_t png[8] = {0x89, 'P', 'N', 'G', 0x0d, 0x0a, 0x1a, 0x0a};
    static const uint8_t jpg[3] = {0xff, 0xd8, 0xff};    /* SOI, then a marker */
    static const uint8_t exr[4] = {0x76, 0x2f, 0x31, 0x01}; /* OpenEXR's magic number 20000630 */
    if (n >= sizeof png && !memcmp(p, png, sizeof png)) return VP_TEX_PNG;
    if (n >= sizeof jpg && !memcmp(p, jpg, sizeof jpg)) return VP_TEX_JPEG;
    if (n >= sizeof exr && !memcmp(p, exr, sizeof exr)) return VP_TEX_EXR;
    return -1;
}

int vtc_texture_put(vtc_client *c, uint32_t id, uint8_t format, uint8_t flags, const uint8_t *data, size_t len,
                    uint64_t *epoch)
{
    if (!len || len > VP_MAX_TEXTURE_BYTES)
        return set_err(c, VP_ERR_COUNT, "a texture of %zu bytes: 1..%u are allowed", len, VP_MAX_TEXTURE_BYTES);
    /* chunks fill the server's frames; the daemon assembles them in order */
    size_t room = c->server.max_payload > VP_TEXTURE_PUT_HEADER ? c->server.max_payload - VP_TEXTURE_PUT_HEADER
                                                                 : len;
    int rc = VP_OK;
    for (size_t off = 0; off < len && !rc;) {
        uint32_t n = (uint32_t)(len - off < room ? len - off : room), req;
        vp_texture_put m = {.id = id, .format = format, .flags = flags, .total = (uint32_t)len,
                            .offset = (uint32_t)off, .len = n, .data = data + off};
        vp_writer *w = request(c, vp_size_texture_put(n), &req);
        vp_enc_texture_put(w, req, &m);
        rc = ack_epoch(c, w, req, epoch);
        off += n;
    }
    return rc;
}

int vtc_texture_put_file(vtc_client *c, uint32_t id, int format, uint8_t flags, const char *path, uint64_t *epoch)
{
    FILE *f = fopen(path, "rb");
    if (!f) return set_err(c, VTC_ERR_IO, "%s: %s", path, strerror(errno));
    uint8_t *data = NULL;
    size_t len = 0, cap = 0;
    int rc = VP_OK;
    for (;;) { /* whole, up to one byte past the protocol's limit (which is then refused) */
        if (len == cap) {
            cap = cap ? cap * 2 : 65536;
            if (cap > (size_t)VP_MAX_TEXTURE_BYTES + 1) cap = (size_t)VP_MAX_TEXTURE_BYTES + 1;
            uint8_t *n = len < cap ? realloc(data, cap) : NULL;
            if (!n) break;
            data = n;
        }
        size_t got = fread(data + len, 1, cap - len, f);
        len += got;
        if (!got) break;
    }
    if (ferror(f)) rc = set_err(c, VTC_ERR_IO, "%s: read failed", path);
    else if (len > VP_MAX_TEXTURE_BYTES || (len == cap && !feof(f)))
        rc = set_err(c, VP_ERR_COUNT, "%s: larger than a texture may be (%u bytes)", path, VP_MAX_TEXTURE_BYTES);
    fclose(f);
    if (!rc && format < 0 && (format = vtc_texture_format(data, len)) < 0)
        rc = set_err(c, VP_ERR_INVALID, "%s: not a PNG, JPEG or EXR file (by its first bytes)", path);
    if (!rc) rc = vtc_texture_put(c, id, (uint8_t)format, flags, data, len, epoch);
    free(data);
    return rc;
}

int vtc_texture_remove(vtc_client *c, const uint64_t *ids, uint32_t n, uint64_t *epoch)
{
    return remove_ids(c, VP_TEXTURE_REMOVE, ids, n, epoch);
}

static int dec_env(const uint8_t *p, uint32_t len, void *out) { return vp_dec_env(p, len, out); }

int vtc_env_set(vtc_client *c, const vp_env *env, uint64_t *epoch)
{
    uint32_t req;
    vp_writer *w = request(c, vp_size_env(), &req);
    vp_enc_env(w, VP_ENV_SET, req, env);
    return ack_epoch(c, w, req, epoch);
}

int vtc_env_get(vtc_client *c, vp_env *out)
{
    return empty_call(c, VP_ENV_GET, VP_ENV_REPLY, dec_env, out);
}

/* ---- read-back (export) ------------------------------------------------------------ */

static int dec_mesh_reply(const uint8_t *p, uint32_t len, void *out) { return vp_dec_mesh(p, len, 0, out); }
static int dec_material_page(const uint8_t *p, uint32_t len, void *out)
{
    return vp_dec_material_list_reply(p, len, out);
}
static int dec_texture_reply(const uint8_t *p, uint32_t len, void *out) { return vp_dec_texture_put(p, len, out); }
static int dec_light_page(const uint8_t *p, uint32_t len, void *out) { return vp_dec_light_list_reply(p, len, out); }

int vtc_mesh_get(vtc_client *c, uint16_t class_id, vp_mesh *out)
{
    uint32_t req;
    vp_writer *w = request(c, vp_size_mesh_get(), &req);
    vp_enc_mesh_get(w, req, &(vp_mesh_get){.class_id = class_id});
    return call(c, w, req, VP_MESH_REPLY, dec_mesh_reply, out);
}

int vtc_material_list(vtc_client *c, uint32_t cursor, uint32_t max, vp_page_reply *out)
{
    uint32_t req;
    vp_writer *w = request(c, vp_size_material_list(), &req);
    vp_enc_material_list(w, req, &(vp_page){.cursor = cursor, .max = max});
    return call(c, w, req, VP_MATERIAL_LIST_REPLY, dec_material_page, out);
}

int vtc_texture_get(vtc_client *c, uint32_t id, uint32_t offset, uint32_t max_len, vp_texture_put *out)
{
    uint32_t req;
    vp_writer *w = request(c, vp_size_texture_get(), &req);
    vp_enc_texture_get(w, req, &(vp_texture_get){.id = id, .offset = offset, .max_len = max_len});
    int rc = call(c, w, req, VP_TEXTURE_REPLY, dec_texture_reply, out);
    if (!rc && (out->id != id || out->offset != offset))
        return set_err(c, VP_ERR_INVALID, "TEXTURE_REPLY for texture %u at %u, asked %u at %u", out->id, out->offset,
                       id, offset);
    return rc;
}

int vtc_light_list(vtc_client *c, uint64_t cursor, uint32_t max, vp_page_reply *out)
{
    uint32_t req;
    vp_writer *w = request(c, vp_size_light_list(), &req);
    vp_enc_light_list(w, req, &(vp_page){.cursor = cursor, .max = max});
    return call(c, w, req, VP_LIGHT_LIST_REPLY, dec_light_page, out);
}
