/*
 * web.c — `vantaged --web [ADDR:]PORT`: browsers. Over HTTP/1.x (httpd.c,
 * the daemon's one HTTP connection code and parser) it serves the viewer
 * and commander pages from the web root, and upgrades `GET /ws` to a
 * WebSocket (RFC 6455), framed by Debian's libwslay on the daemon's own
 * loop. The WebSocket is one more transport for the binary protocol, as
 * TCP and the Unix socket are: its binary messages carry the protocol's
 * byte stream both ways (a message may hold several protocol frames, or a
 * part of one), so a page says HELLO with its token, subscribes to frames,
 * queries, marks and destroys as any client does, under the same roles,
 * limits and latest-frame-wins rules (server.c: conn_read / conn_flush
 * hand a WebSocket connection's bytes here).
 *
 * Static files: GET and HEAD of names made of [A-Za-z0-9._-] segments
 * (none starting with a dot) under the root, `/` = /index.html, at most
 * WEB_FILE_MAX bytes; anything else is 404, other methods 405. Pages carry
 * no data (the scene comes over the WebSocket, after HELLO), so they need
 * no token.
 *
 * The upgrade: GET, `Upgrade: websocket`, `Connection: upgrade`,
 * `Sec-WebSocket-Version: 13` (else 426 naming it) and a key of 16 bytes
 * in base64. A browser sends Origin: it must name this daemon's own host
 * (the Host header), else 403: otherwise any site the user visits could
 * open the loopback daemon's WebSocket and edit the scene where no tokens
 * are needed (cross-site WebSocket hijacking). Clients that send no Origin
 * (scripts) are let through: they could reach the TCP port anyway.
 *
 * Outgoing: the connection's reply queue (server.c's out blocks) stays
 * the one backlog; a block is handed to wslay as one binary message only
 * when wslay holds nothing else, so --out-limit, the daemon-wide cap and
 * the frames' drain rule see every unsent byte (wslay holds one message
 * at most). Incoming: whole messages (wslay reassembles fragments), at
 * most --max-payload + a frame header each (1009 past it); a text message
 * is closed with 1003 (the protocol is binary), or by wslay with 1007 when
 * it is not UTF-8. Bad framing is wslay's: an unmasked client frame, a reserved
 * bit or opcode, a stray continuation get 1002; what its frame parser
 * itself refuses (a fragmented or over-125-byte control frame, a length
 * not in its shortest form) gets a close with no status code (1005 to the
 * peer), then the hang-up.
 *
 * TLS (--web-cert/--web-key): tls.c, under both the HTTP connections
 * (httpd.c) and the WebSocket's reads and writes here.
 */
#include "httpd.h"
#include "server_internal.h"
#include "tls.h"
#include "vp_grow.h"
#include "web.h"

#include <wslay/wslay.h>

#include <errno.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <openssl/evp.h>
#include <openssl/sha.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#define WEB_MAX_CONNS 64u          /* HTTP connections at once (pages, upgrades); more get 503 */
#define WEB_FILE_MAX (4u << 20)    /* a static file's size at most */
#define WS_QUEUE_MAX 1024u         /* messages wslay may hold for a client (its pongs, past one data message) */

struct wsio {
    wslay_event_context_ptr ctx;
    server *s;
    conn *c;
    SSL *ssl;                    /* TLS (--web-cert), NULL: plain */
    uint8_t pre[HTTPD_HEAD_MAX]; /* bytes read with the HTTP head, handed to wslay first */
    size_t pre_len, pre_pos;
    bool failed;                 /* a callback could not go on (no memory): end the connection */
    bool close_queued;
    bool peer_gone;              /* its socket ended (EOF or an error) */
};

/* ---- static files --------------------------------------------------------------------- */

static const struct {
    const char *ext, *type;
} types[] = {
    {".html", "text/html; charset=utf-8"}, {".js", "text/javascript; charset=utf-8"},
    {".mjs", "text/javascript; charset=utf-8"}, {".css", "text/css; charset=utf-8"},
    {".json", "application/json"}, {".png", "image/png"}, {".jpg", "image/jpeg"},
    {".svg", "image/svg+xml"}, {".ico", "image/x-icon"}, {".txt", "text/plain; charset=utf-8"},
    {".wasm", "application/wasm"}, /* the commander's rules (cmdr.wasm: the C of pad_map.c) */
};

/* The file's type by its extension; NULL: not one served. */
static const char *type_of(const char *name, size_t n)
{
    for (size_t i = 0; i < sizeof types / sizeof types[0]; i++) {
        size_t e = strlen(types[i].ext);
        if (n > e && !memcmp(name + n - e, types[i].ext, e)) return types[i].type;
    }
    return NULL;
}

/* Whether the path is one this endpoint may name: "/" segments of
 * [A-Za-z0-9._-], none empty or starting with a dot ("..", ".git"). */
static bool path_ok(const char *p, size_t n)
{
    if (!n || p[0] != '/') return false;
    size_t seg = 0; /* length of the segment so far */
    for (size_t i = 1; i < n; i++) {
        char ch = p[i];
        if (ch == '/') {
            if (!seg) return false;
            seg = 0;
            continue;
        }
        bool okc = (ch >= 'a' && ch <= 'z') || (ch >= 'A' && ch <= 'Z') || (ch >= '0' && ch <= '9') || ch == '_' ||
                   ch == '-' || ch == '.';
        if (!okc || (!seg && ch == '.')) return false;
        seg++;
    }
    return seg > 0;
}

/* GET or HEAD of a file under the root. */
static void serve_file(server *s, hconn *h, const http_req *rq)
{
    bool head_only = rq->head;
    char rel[256];
    const char *p = rq->path.p;
    size_t n = rq->path.n;
    if (n == 1 && p[0] == '/') p = "/index.html", n = 11;
    const char *type = path_ok(p, n) && n < sizeof rel ? type_of(p, n) : NULL;
    if (!type) {
        httpd_error(h, HS_404, NULL, "not found\n", head_only);
        return;
    }
    if (!head_only && !(rq->method.n == 3 && !memcmp(rq->method.p, "GET", 3))) {
        httpd_error(h, HS_405, "Allow: GET, HEAD\r\n", "only GET and HEAD are allowed\n", false);
        return;
    }
    memcpy(rel, p + 1, n - 1);
    rel[n - 1] = 0;
    int fd = openat(s->web_root_fd, rel, O_RDONLY | O_CLOEXEC | O_NOFOLLOW);
    struct stat st;
    if (fd < 0 || fstat(fd, &st) || !S_ISREG(st.st_mode) || st.st_size > WEB_FILE_MAX) {
        if (fd >= 0) close(fd);
        httpd_error(h, HS_404, NULL, "not found\n", head_only);
        return;
    }
    size_t len = (size_t)st.st_size, got = 0;
    uint8_t *body = malloc(len ? len : 1);
    while (body && got < len) {
        ssize_t r = read(fd, body + got, len - got);
        if (r < 0 && errno == EINTR) continue;
        if (r <= 0) break;
        got += (size_t)r;
    }
    close(fd);
    if (!body || got != len) {
        free(body);
        httpd_error(h, HS_500, NULL, "the file could not be read\n", head_only);
        return;
    }
    /* the pages load only their own scripts (and the commander's WebAssembly) and talk only to this daemon */
    httpd_answer(h, HS_200, type,
                 "X-Content-Type-Options: nosniff\r\n"
                 "Content-Security-Policy: default-src 'self'; script-src 'self' 'wasm-unsafe-eval'; "
                 "img-src 'self' blob: data:; connect-src 'self'\r\n",
                 body, len, head_only);
    free(body);
}

/* ---- the upgrade ------------------------------------------------------------------------ */

/* Whether Origin (scheme://host[:port]) names the Host header's host:port. */
static bool same_origin(http_span origin, http_span host)
{
    const char *sep = origin.n > 3 ? memchr(origin.p, ':', origin.n) : NULL;
    if (!sep || (size_t)(origin.p + origin.n - sep) < 3 || memcmp(sep, "://", 3)) return false;
    const char *o = sep + 3;
    size_t on = (size_t)(origin.p + origin.n - o);
    return host.p && on == host.n && !strncasecmp(o, host.p, on);
}

/* Sec-WebSocket-Key: base64 of 16 bytes (RFC 6455 4.1): 22 characters and "==". */
static bool key_ok(http_span k)
{
    if (k.n != 24 || k.p[22] != '=' || k.p[23] != '=') return false;
    for (size_t i = 0; i < 22; i++) {
        char ch = k.p[i];
        if (!((ch >= 'a' && ch <= 'z') || (ch >= 'A' && ch <= 'Z') || (ch >= '0' && ch <= '9') || ch == '+' ||
              ch == '/'))
            return false;
    }
    return true;
}

void web_accept_key(const char *key, size_t n, char out[29])
{
    static const char guid[] = "258EAFA5-E914-47DA-95CA-C5AB0DC85B11";
    char buf[128];
    unsigned char sha[SHA_DIGEST_LENGTH];
    if (n > sizeof buf - sizeof guid) n = sizeof buf - sizeof guid;
    memcpy(buf, key, n);
    memcpy(buf + n, guid, sizeof guid - 1);
    SHA1((const unsigned char *)buf, n + sizeof guid - 1, sha);
    EVP_EncodeBlock((unsigned char *)out, sha, SHA_DIGEST_LENGTH);
}

static void upgrade(server *s, hconn *h, const http_req *rq)
{
    if (!(rq->method.n == 3 && !memcmp(rq->method.p, "GET", 3))) {
        httpd_error(h, HS_405, "Allow: GET\r\n", "the WebSocket is opened with GET\n", rq->head);
        return;
    }
    if (!rq->upgrade_websocket || !rq->connection_upgrade) {
        httpd_error(h, HS_426, "Upgrade: websocket\r\nConnection: Upgrade\r\n",
                    "this is the daemon's WebSocket: open it with Upgrade: websocket\n", false);
        return;
    }
    if (rq->ws_version.n != 2 || memcmp(rq->ws_version.p, "13", 2)) {
        httpd_error(h, HS_426, "Sec-WebSocket-Version: 13\r\n", "only WebSocket version 13 is spoken here\n", false);
        return;
    }
    if (!key_ok(rq->ws_key)) {
        httpd_error(h, HS_400, NULL, "Sec-WebSocket-Key must be 16 bytes in base64\n", false);
        return;
    }
    if (rq->origin.p && !same_origin(rq->origin, rq->host_value)) {
        LOGW("web: a WebSocket from another origin refused (%.*s)", (int)(rq->origin.n > 80 ? 80 : rq->origin.n),
             rq->origin.p);
        httpd_error(h, HS_403, NULL, "a page from another origin may not open this daemon's WebSocket\n", false);
        return;
    }
    if (!server_has_room(s)) {
        httpd_error(h, HS_503, "Retry-After: 1\r\n", "too many connections now\n", false);
        return;
    }
    char acc[29];
    web_accept_key(rq->ws_key.p, rq->ws_key.n, acc);
    struct wsio *w = calloc(1, sizeof *w);
    if (!w) {
        httpd_error(h, HS_500, NULL, "out of memory\n", false);
        return;
    }
    s->m.web_http[HS_101]++;
    int fd = httpd_take(h, w->pre, &w->pre_len, &w->ssl);
    char hd[256];
    int n = snprintf(hd, sizeof hd,
                     "HTTP/1.1 101 Switching Protocols\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                     "Sec-WebSocket-Accept: %s\r\n\r\n",
                     acc);
    /* a fresh socket takes these ~130 bytes at once; if not, the client is
       not worth a queue for them */
    bool ww;
    if (tls_write(w->ssl, fd, hd, (size_t)n, &ww) != n) {
        web_wsio_free(w);
        close(fd);
        return;
    }
    (void)server_adopt_ws(s, fd, w);
}

static void serve(server *s, hconn *h, const http_req *rq)
{
    if (rq->path.n == 3 && !memcmp(rq->path.p, "/ws", 3)) upgrade(s, h, rq);
    else serve_file(s, h, rq);
}

static const httpd_ops web_ops = {.name = "web", .serve = serve};

int web_open(server *s)
{
    s->web_root_fd = open(s->cfg.web_root, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (s->web_root_fd < 0) {
        LOGE("--web-root %s: %s", s->cfg.web_root, strerror(errno));
        return -1;
    }
    if (s->cfg.web_cert) {
        char err[400];
        if (!(s->web_tls = tls_server_ctx(s->cfg.web_cert, s->cfg.web_key, err, sizeof err))) {
            LOGE("%s", err);
            return -1;
        }
    }
    s->web = httpd_open(s, s->cfg.web_bind, s->cfg.web_port, WEB_MAX_CONNS, &web_ops, s->m.web_http, s->web_tls);
    if (!s->web) return -1;
    LOGI("web viewer on %s://%s:%d/ (pages from %s)", s->web_tls ? "https" : "http", s->cfg.web_bind,
         s->cfg.web_port, s->cfg.web_root);
    return 0;
}

void web_close(server *s)
{
    httpd_close(s->web);
    s->web = NULL;
    if (s->web_root_fd >= 0) close(s->web_root_fd);
    s->web_root_fd = -1;
    tls_ctx_free(s->web_tls);
    s->web_tls = NULL;
}

/* ---- the WebSocket transport --------------------------------------------------------------- */

static ssize_t recv_cb(wslay_event_context_ptr ctx, uint8_t *buf, size_t len, int flags, void *ud)
{
    (void)flags;
    struct wsio *w = ud;
    if (w->pre_pos < w->pre_len) {
        size_t n = w->pre_len - w->pre_pos < len ? w->pre_len - w->pre_pos : len;
        memcpy(buf, w->pre + w->pre_pos, n);
        w->pre_pos += n;
        return (ssize_t)n;
    }
    for (;;) {
        bool ww;
        ssize_t n = tls_read(w->ssl, w->c->fd, buf, len, &ww);
        if (n > 0) {
            w->s->bytes_in += (uint64_t)n;
            return n;
        }
        if (n < 0 && errno == EINTR) continue;
        bool again = n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK);
        w->peer_gone |= !again;
        wslay_event_set_error(ctx, again ? WSLAY_ERR_WOULDBLOCK : WSLAY_ERR_CALLBACK_FAILURE);
        return -1;
    }
}

static ssize_t send_cb(wslay_event_context_ptr ctx, const uint8_t *data, size_t len, int flags, void *ud)
{
    (void)flags;
    struct wsio *w = ud;
    for (;;) {
        bool ww;
        ssize_t n = tls_write(w->ssl, w->c->fd, data, len, &ww);
        if (n >= 0) {
            w->s->bytes_out += (uint64_t)n;
            return n;
        }
        if (errno == EINTR) continue;
        wslay_event_set_error(ctx, errno == EAGAIN || errno == EWOULDBLOCK ? WSLAY_ERR_WOULDBLOCK
                                                                           : WSLAY_ERR_CALLBACK_FAILURE);
        return -1;
    }
}

static void close_with(struct wsio *w, uint16_t code, const char *why)
{
    if (w->close_queued) return;
    w->close_queued = true;
    if (wslay_event_queue_close(w->ctx, code, (const uint8_t *)why, strlen(why))) w->failed = true;
}

static void on_msg(wslay_event_context_ptr ctx, const struct wslay_event_on_msg_recv_arg *a, void *ud)
{
    struct wsio *w = ud;
    conn *c = w->c;
    if (a->opcode == WSLAY_TEXT_FRAME) { /* (one that is not UTF-8 wslay closes itself: 1007) */
        w->s->m.ws_bad++;
        close_with(w, 1003, "the protocol is binary: send binary messages");
        return;
    }
    if (a->opcode == WSLAY_PING && wslay_event_get_queued_msg_count(ctx) > WS_QUEUE_MAX) {
        wslay_event_shutdown_read(ctx); /* a flood: web_ws_recv ends it */
        return;
    }
    if (a->opcode != WSLAY_BINARY_FRAME || c->dead || w->close_queued) return; /* pings are wslay's */
    size_t need = c->in_len + a->msg_length;
    if (need > c->in_cap) { /* grown as conn_read grows a socket's: geometrically, not per message */
        size_t cap = vp_grow_cap(c->in_cap, need, 65536, 1, SIZE_MAX);
        uint8_t *p = cap >= need ? realloc(c->in, cap) : NULL;
        if (!p) {
            w->failed = true;
            return;
        }
        c->in = p;
        c->in_cap = cap;
        w->s->clocks = true; /* the sweeps that give a big buffer back */
    }
    memcpy(c->in + c->in_len, a->msg, a->msg_length);
    c->in_len = need;
    if (c->in_len > c->in_peak) c->in_peak = c->in_len;
}

static const struct wslay_event_callbacks callbacks = {
    .recv_callback = recv_cb,
    .send_callback = send_cb,
    .on_msg_recv_callback = on_msg,
};

int web_ws_init(server *s, conn *c, struct wsio *w)
{
    w->s = s;
    w->c = c;
    if (wslay_event_context_server_init(&w->ctx, &callbacks, w)) {
        w->ctx = NULL;
        return -1;
    }
    wslay_event_config_set_max_recv_msg_length(w->ctx, (uint64_t)s->cfg.max_payload + VP_HEADER_SIZE);
    c->ws = w;
    return 0;
}

void web_wsio_free(struct wsio *w)
{
    if (!w) return;
    if (w->ctx) wslay_event_context_free(w->ctx);
    tls_free(w->ssl);
    free(w);
}

void web_ws_free(conn *c)
{
    web_wsio_free(c->ws);
    c->ws = NULL;
}

/* After wslay ran: MD_NONE, or why the connection is over. */
static int ws_state(struct wsio *w, int rc)
{
    if (w->failed) return MD_ERROR;
    if (rc) return MD_PEER;
    if (!wslay_event_want_read(w->ctx) && !wslay_event_want_write(w->ctx)) return MD_PEER; /* closed */
    /* our close is out (an error's, or a bad message's): done, without
       waiting for the peer's answer */
    if (w->close_queued && wslay_event_get_close_sent(w->ctx) && !wslay_event_get_queued_msg_count(w->ctx))
        return MD_ERROR;
    return MD_NONE;
}

int web_ws_recv(conn *c)
{
    struct wsio *w = c->ws;
    int rc = wslay_event_recv(w->ctx);
    if (rc && !w->peer_gone) {
        /* wslay stops at a frame its parser cannot take (a fragmented or
           oversized control frame, a non-minimal length) and queues a
           close without a status code (the browser reads 1005): sent
           before hanging up, best effort */
        (void)wslay_event_send(w->ctx);
    }
    int why = ws_state(w, rc);
    /* wslay answers each ping with a pong, queued without bound: a client
       that pings and does not read is dropped (data holds one message at
       most, so this many queued can only be its pongs) */
    if (!why && wslay_event_get_queued_msg_count(c->ws->ctx) > WS_QUEUE_MAX) {
        LOGW("client %u: %zu WebSocket messages unread (a ping flood?): disconnecting", c->id,
             wslay_event_get_queued_msg_count(c->ws->ctx));
        why = MD_OUTPUT_LIMIT;
    }
    return why;
}

bool web_ws_idle(const conn *c)
{
    return wslay_event_get_queued_msg_count(c->ws->ctx) == 0;
}

int web_ws_queue(conn *c, const uint8_t *p, size_t n)
{
    struct wslay_event_msg m = {.opcode = WSLAY_BINARY_FRAME, .msg = p, .msg_length = n};
    return wslay_event_queue_msg(c->ws->ctx, &m) ? -1 : 0;
}

int web_ws_send(conn *c)
{
    return ws_state(c->ws, wslay_event_send(c->ws->ctx));
}

int web_ws_end(conn *c, uint16_t code, const char *why)
{
    close_with(c->ws, code, why);
    return web_ws_send(c);
}
