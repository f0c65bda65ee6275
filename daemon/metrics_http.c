/*
 * metrics_http.c — `vantaged --metrics [ADDR:]PORT`: the metrics (see
 * metrics.h) over HTTP/1.x for Prometheus, served from the daemon's own
 * loop by a small responder written for this one job (the request head
 * parsed by http.c, the daemon's one HTTP parser).
 *
 *   GET /metrics (or HEAD)  200, text/plain; version=0.0.4
 *   another path            404
 *   another method          405 (Allow: GET, HEAD)
 *   a head over 8 KiB       431; a malformed one 400; HTTP/2.0 and the like 505
 *   no `Authorization: Bearer TOKEN` where one is needed  401
 *
 * Who may read: whoever the daemon lets view. Without --tokens everyone
 * (vantaged.c then allows only a loopback address, unless --insecure, as
 * for --bind); with --tokens a token that grants the viewer role, unless
 * the token file has no viewer line (public viewing).
 *
 * Every answer says `Connection: close`: one request a connection, then the
 * daemon shuts its side and reads until the client closes (so the answer
 * is not lost to a reset if the client sent more than its head). At most
 * METRICS_HTTP_MAX_CONNS connections at once (more get 503 at once); the
 * whole head must arrive within --hello-timeout of the accept (slow-loris:
 * 408, closed), and a connection is gone at most 2 s after its answer was
 * written. The exposition is built on the loop (tens of microseconds);
 * protocol clients wait for nothing else: a metrics client's bytes are read
 * and written without blocking, like theirs.
 */
#include "http.h"
#include "server_internal.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#define LINGER_MS 2000u

typedef struct hconn {
    server *s;
    int fd;
    uint64_t deadline_ms;
    bool answered;       /* an answer is queued or sent: input is drained and dropped */
    bool peer_done;      /* the client has shut its side: free once the answer is out */
    char *out;
    size_t out_len, out_pos;
    size_t in_len;
    char in[METRICS_HTTP_HEAD_MAX];
} hconn;

struct mhttp {
    int lfd;
    hconn *c[METRICS_HTTP_MAX_CONNS];
    uint32_t n;
};

static const struct { int code; const char *reason; } statuses[MH_COUNT] = {
    [MH_200] = {200, "OK"},
    [MH_400] = {400, "Bad Request"},
    [MH_401] = {401, "Unauthorized"},
    [MH_404] = {404, "Not Found"},
    [MH_405] = {405, "Method Not Allowed"},
    [MH_408] = {408, "Request Timeout"},
    [MH_431] = {431, "Request Header Fields Too Large"},
    [MH_500] = {500, "Internal Server Error"},
    [MH_503] = {503, "Service Unavailable"},
    [MH_505] = {505, "HTTP Version Not Supported"},
};

static void hconn_free(hconn *h)
{
    struct mhttp *m = h->s->http;
    ae_del(h->s->loop, h->fd, AE_READABLE | AE_WRITABLE);
    close(h->fd);
    for (uint32_t i = 0; i < m->n; i++)
        if (m->c[i] == h) {
            m->c[i] = m->c[--m->n];
            break;
        }
    free(h->out);
    free(h);
}

/* The status line and headers (and body unless head_only) into a new
 * buffer; false: out of memory. */
static bool build(hconn *h, int slot, const char *extra, const char *body, size_t body_len, bool head_only)
{
    char hd[512];
    const char *type = slot == MH_200 ? "text/plain; version=0.0.4; charset=utf-8" : "text/plain; charset=utf-8";
    int n = snprintf(hd, sizeof hd,
                     "HTTP/1.1 %d %s\r\nContent-Type: %s\r\nContent-Length: %zu\r\nCache-Control: no-store\r\n"
                     "Connection: close\r\n%s\r\n",
                     statuses[slot].code, statuses[slot].reason, type, body_len, extra ? extra : "");
    if (n < 0 || (size_t)n >= sizeof hd) return false;
    size_t len = (size_t)n + (head_only ? 0 : body_len);
    h->out = malloc(len ? len : 1);
    if (!h->out) return false;
    memcpy(h->out, hd, (size_t)n);
    if (!head_only && body_len) memcpy(h->out + n, body, body_len);
    h->out_len = len;
    h->out_pos = 0;
    return true;
}

static void on_conn(ae_loop *l, int fd, void *data, int mask);

/* An answer in one write, best effort, for a connection about to be closed
 * (503 at the accept, 408 at the deadline): no buffer, no waiting. */
static void say_now(int fd, int slot, const char *extra, const char *msg)
{
    char buf[512];
    int n = snprintf(buf, sizeof buf,
                     "HTTP/1.1 %d %s\r\nContent-Type: text/plain; charset=utf-8\r\nContent-Length: %zu\r\n"
                     "Connection: close\r\n%s\r\n%s",
                     statuses[slot].code, statuses[slot].reason, strlen(msg), extra ? extra : "", msg);
    if (n > 0 && (size_t)n < sizeof buf) {
        ssize_t ignored = write(fd, buf, (size_t)n);
        (void)ignored;
    }
}

/* Writes what the socket takes; when all is out, shuts the sending side and
 * waits (reading) for the client to close. false: h was freed. */
static bool flush(hconn *h)
{
    while (h->out_pos < h->out_len) {
        ssize_t n = write(h->fd, h->out + h->out_pos, h->out_len - h->out_pos);
        if (n > 0) {
            h->out_pos += (size_t)n;
            continue;
        }
        if (n < 0 && errno == EINTR) continue;
        if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
            if (!(ae_mask(h->s->loop, h->fd) & AE_WRITABLE)) ae_add(h->s->loop, h->fd, AE_WRITABLE, on_conn, h);
            return true;
        }
        hconn_free(h);
        return false;
    }
    if (ae_mask(h->s->loop, h->fd) & AE_WRITABLE) ae_del(h->s->loop, h->fd, AE_WRITABLE);
    if (h->peer_done) {
        hconn_free(h);
        return false;
    }
    shutdown(h->fd, SHUT_WR);
    uint64_t linger = ae_now_ms() + LINGER_MS;
    if (linger < h->deadline_ms) h->deadline_ms = linger;
    return true;
}

/* Queues an answer with a one-line text body (errors) and sends it. */
static bool answer_text(hconn *h, int slot, const char *extra, const char *msg, bool head_only)
{
    h->answered = true;
    h->s->m.http[slot]++;
    if (!build(h, slot, extra, msg, strlen(msg), head_only)) {
        hconn_free(h);
        return false;
    }
    return flush(h);
}

/* Parses (http.h) and answers a whole head in h->in[start, end). */
static bool respond(hconn *h, size_t start, size_t end)
{
    server *s = h->s;
    http_req rq;
    const char *why;
    int st = http_parse(h->in, start, end, &rq, &why);
    if (st) return answer_text(h, st == 505 ? MH_505 : MH_400, NULL, why, rq.head);
    bool head_only = rq.head;
    if (s->cfg.tokens && !auth_grants(s->cfg.tokens, VP_ROLE_VIEWER, (const uint8_t *)rq.bearer.p, rq.bearer.n))
        return answer_text(h, MH_401, "WWW-Authenticate: Bearer realm=\"vantaged\"\r\n",
                           "this daemon needs a token that grants the viewer role: Authorization: Bearer TOKEN\n",
                           head_only);
    if (rq.path.n != 8 || memcmp(rq.path.p, "/metrics", 8))
        return answer_text(h, MH_404, NULL, "not found: the metrics are at /metrics\n", head_only);
    if (!head_only && !(rq.method.n == 3 && !memcmp(rq.method.p, "GET", 3)))
        return answer_text(h, MH_405, "Allow: GET, HEAD\r\n", "only GET and HEAD are allowed\n", false);
    if (!metrics_expose(s, &s->mtext)) return answer_text(h, MH_500, NULL, "out of memory\n", head_only);
    h->answered = true;
    s->m.http[MH_200]++;
    if (!build(h, MH_200, NULL, s->mtext.p, s->mtext.len, head_only)) {
        hconn_free(h);
        return false;
    }
    return flush(h);
}

/* ---- events ---------------------------------------------------------------------------- */

static void on_read(hconn *h)
{
    if (h->answered) {
        /* after the answer: drop what comes until the client closes */
        char junk[4096];
        ssize_t n = read(h->fd, junk, sizeof junk);
        if (n == 0 && h->out_pos < h->out_len) {
            /* a client that shut its side after the request (nc -N): the
               answer still goes out, then the connection is freed */
            h->peer_done = true;
            ae_del(h->s->loop, h->fd, AE_READABLE);
        } else if (n == 0 || (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR)) {
            hconn_free(h);
        }
        return;
    }
    ssize_t n = read(h->fd, h->in + h->in_len, sizeof h->in - h->in_len);
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR)) return;
    if (n <= 0) { /* gone before its request was whole: nothing to answer */
        hconn_free(h);
        return;
    }
    h->in_len += (size_t)n;
    size_t start, end = http_head_end(h->in, h->in_len, &start);
    if (end) {
        respond(h, start, end);
        return;
    }
    if (h->in_len == sizeof h->in)
        answer_text(h, MH_431, NULL, "request head over 8 KiB\n", false);
}

static void on_conn(ae_loop *l, int fd, void *data, int mask)
{
    (void)l;
    (void)fd;
    hconn *h = data;
    if (mask & AE_READABLE) on_read(h);
    else if (mask & AE_WRITABLE) flush(h);
}

static void on_accept(ae_loop *l, int lfd, void *data, int mask)
{
    (void)mask;
    server *s = data;
    struct mhttp *m = s->http;
    for (;;) {
        int fd = accept4(lfd, NULL, NULL, SOCK_NONBLOCK | SOCK_CLOEXEC);
        if (fd < 0) {
            if (errno == EINTR) continue;
            if (errno != EAGAIN && errno != EWOULDBLOCK) LOGW("metrics: accept: %s", strerror(errno));
            return;
        }
        hconn *h = NULL;
        if (m->n < METRICS_HTTP_MAX_CONNS && fd < s->conns_cap) h = calloc(1, sizeof *h);
        if (!h || ae_add(l, fd, AE_READABLE, on_conn, h) < 0) {
            /* too many at once (or no memory): say so, best effort; what
               the client already sent is read first (closing with unread
               input would reset the connection, the answer lost) */
            char junk[4096];
            for (int k = 0; k < 4 && read(fd, junk, sizeof junk) > 0; k++) {
            }
            say_now(fd, MH_503, "Retry-After: 1\r\n", "too many metrics connections now\n");
            close(fd);
            free(h);
            s->m.http[MH_503]++;
            continue;
        }
        *h = (hconn){.s = s, .fd = fd, .deadline_ms = ae_now_ms() + s->cfg.hello_timeout_ms};
        m->c[m->n++] = h;
    }
}

bool metrics_http_busy(const server *s)
{
    return s->http && s->http->n > 0;
}

uint32_t metrics_http_conns(const server *s)
{
    return s->http ? s->http->n : 0;
}

void metrics_http_sweep(server *s, uint64_t now_ms)
{
    struct mhttp *m = s->http;
    if (!m) return;
    for (uint32_t i = m->n; i-- > 0;) {
        hconn *h = m->c[i];
        if (now_ms < h->deadline_ms) continue;
        if (!h->answered) {
            /* slow-loris: tell it, without waiting for it to read */
            say_now(h->fd, MH_408, NULL, "request head not sent in time\n");
            s->m.http[MH_408]++;
        }
        hconn_free(h);
    }
}

int metrics_http_open(server *s)
{
    s->http = calloc(1, sizeof *s->http);
    if (!s->http) return -1;
    s->http->lfd = listen_tcp(s->cfg.metrics_bind, s->cfg.metrics_port);
    if (s->http->lfd < 0) return -1;
    if (s->http->lfd >= s->conns_cap || ae_add(s->loop, s->http->lfd, AE_READABLE, on_accept, s) < 0) return -1;
    LOGI("metrics on http://%s:%d/metrics", s->cfg.metrics_bind, s->cfg.metrics_port);
    return 0;
}

void metrics_http_close(server *s)
{
    struct mhttp *m = s->http;
    if (!m) return;
    while (m->n) hconn_free(m->c[0]);
    if (m->lfd >= 0) {
        ae_del(s->loop, m->lfd, AE_READABLE);
        close(m->lfd);
    }
    free(m);
    s->http = NULL;
}
