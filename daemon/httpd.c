/*
 * httpd.c — the daemon's HTTP/1.x connections on its own loop (httpd.h):
 * accepting, reading a head (parsed by http.c), answering from an
 * endpoint's serve callback, the deadlines, and handing a connection over
 * for a WebSocket. A client's bytes are read and written without
 * blocking, as protocol clients' are; no endpoint makes the loop wait.
 */
#include "httpd.h"
#include "server_internal.h"
#include "tls.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#define LINGER_MS 2000u

struct hconn {
    httpd *d;
    int fd;
    SSL *ssl;            /* TLS (--web-cert), NULL: plain */
    bool handshaking;    /* TLS: the handshake is not done yet */
    uint64_t deadline_ms;
    bool answered;       /* an answer is queued or sent: input is drained and dropped */
    bool peer_done;      /* the client has shut its side: free once the answer is out */
    char *out;
    size_t out_len, out_pos;
    size_t in_len, head_end; /* head_end: where the head ended (while serve runs) */
    char in[HTTPD_HEAD_MAX];
};

struct httpd {
    server *s;
    const httpd_ops *ops;
    uint64_t *counts;
    SSL_CTX *tls;        /* NULL: plain HTTP */
    int lfd;
    uint32_t n, max;
    hconn **c;
};

const char *const httpd_codes[HS_COUNT] = {"101", "200", "400", "401", "403", "404", "405",
                                           "408", "426", "431", "500", "503", "505"};
static const char *const reasons[HS_COUNT] = {
    "Switching Protocols", "OK", "Bad Request", "Unauthorized", "Forbidden", "Not Found", "Method Not Allowed",
    "Request Timeout", "Upgrade Required", "Request Header Fields Too Large", "Internal Server Error",
    "Service Unavailable", "HTTP Version Not Supported",
};

/* Out of the table and the loop; the fd stays open (the caller's). */
static void hconn_unlink(hconn *h)
{
    httpd *d = h->d;
    ae_del(d->s->loop, h->fd, AE_READABLE | AE_WRITABLE);
    for (uint32_t i = 0; i < d->n; i++)
        if (d->c[i] == h) {
            d->c[i] = d->c[--d->n];
            break;
        }
    free(h->out);
    free(h);
}

static void hconn_free(hconn *h)
{
    int fd = h->fd;
    tls_free(h->ssl);
    hconn_unlink(h);
    close(fd);
}

static void on_conn(ae_loop *l, int fd, void *data, int mask);

/* Whether the connection waits for the socket to be writable (an answer
 * being written, or a TLS step that must write first). */
static void want_write(hconn *h, bool on)
{
    ae_loop *l = h->d->s->loop;
    bool has = ae_mask(l, h->fd) & AE_WRITABLE;
    if (on && !has) ae_add(l, h->fd, AE_WRITABLE, on_conn, h);
    else if (!on && has && !(h->out && h->out_pos < h->out_len)) ae_del(l, h->fd, AE_WRITABLE);
}

/* An answer in one write, best effort, for a connection about to be closed
 * (503 at the accept, 408 at the deadline): no buffer, no waiting. */
static void say_now(SSL *ssl, int fd, int slot, const char *extra, const char *msg)
{
    char buf[512];
    int n = snprintf(buf, sizeof buf,
                     "HTTP/1.1 %s %s\r\nContent-Type: text/plain; charset=utf-8\r\nContent-Length: %zu\r\n"
                     "Connection: close\r\n%s\r\n%s",
                     httpd_codes[slot], reasons[slot], strlen(msg), extra ? extra : "", msg);
    bool ww;
    if (n > 0 && (size_t)n < sizeof buf) (void)tls_write(ssl, fd, buf, (size_t)n, &ww);
}

/* Writes what the socket takes; when all is out, shuts the sending side and
 * waits (reading) for the client to close. false: h was freed. */
static bool flush(hconn *h)
{
    while (h->out_pos < h->out_len) {
        bool ww;
        ssize_t n = tls_write(h->ssl, h->fd, h->out + h->out_pos, h->out_len - h->out_pos, &ww);
        if (n > 0) {
            h->out_pos += (size_t)n;
            continue;
        }
        if (n < 0 && errno == EINTR) continue;
        if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
            want_write(h, true);
            return true;
        }
        hconn_free(h);
        return false;
    }
    want_write(h, false);
    if (h->peer_done) {
        hconn_free(h);
        return false;
    }
    tls_close_notify(h->ssl);
    shutdown(h->fd, SHUT_WR);
    uint64_t linger = ae_now_ms() + LINGER_MS;
    if (linger < h->deadline_ms) h->deadline_ms = linger;
    return true;
}

bool httpd_answer(hconn *h, int slot, const char *type, const char *extra, const void *body, size_t len,
                  bool head_only)
{
    char hd[768];
    h->answered = true;
    h->d->counts[slot]++;
    int n = snprintf(hd, sizeof hd,
                     "HTTP/1.1 %s %s\r\nContent-Type: %s\r\nContent-Length: %zu\r\nCache-Control: no-store\r\n"
                     "Connection: close\r\n%s\r\n",
                     httpd_codes[slot], reasons[slot], type, len, extra ? extra : "");
    size_t all = n > 0 && (size_t)n < sizeof hd ? (size_t)n + (head_only ? 0 : len) : 0;
    if (all) h->out = malloc(all);
    if (!all || !h->out) {
        hconn_free(h);
        return false;
    }
    memcpy(h->out, hd, (size_t)n);
    if (!head_only && len) memcpy(h->out + n, body, len);
    h->out_len = all;
    h->out_pos = 0;
    return flush(h);
}

bool httpd_error(hconn *h, int slot, const char *extra, const char *msg, bool head_only)
{
    return httpd_answer(h, slot, "text/plain; charset=utf-8", extra, msg, strlen(msg), head_only);
}

int httpd_take(hconn *h, uint8_t *rest, size_t *rest_len, SSL **ssl)
{
    int fd = h->fd;
    *ssl = h->ssl;
    h->ssl = NULL;
    size_t n = h->in_len - h->head_end;
    memcpy(rest, h->in + h->head_end, n);
    *rest_len = n;
    hconn_unlink(h);
    return fd;
}

/* Parses (http.h) and answers a whole head in h->in[start, end). */
static void respond(hconn *h, size_t start, size_t end)
{
    http_req rq;
    const char *why;
    int st = http_parse(h->in, start, end, &rq, &why);
    if (st) {
        httpd_error(h, st == 505 ? HS_505 : HS_400, NULL, why, rq.head);
        return;
    }
    h->head_end = end;
    h->d->ops->serve(h->d->s, h, &rq);
}

/* ---- events ---------------------------------------------------------------------------- */

static void on_read(hconn *h)
{
    if (h->answered) {
        /* after the answer: drop what comes until the client closes */
        char junk[4096];
        bool ww;
        ssize_t n = tls_read(h->ssl, h->fd, junk, sizeof junk, &ww);
        if (n == 0 && h->out_pos < h->out_len) {
            /* a client that shut its side after the request (nc -N): the
               answer still goes out, then the connection is freed */
            h->peer_done = true;
            ae_del(h->d->s->loop, h->fd, AE_READABLE);
        } else if (n == 0 || (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR)) {
            hconn_free(h);
        }
        return;
    }
    /* to EAGAIN: TLS may hold decrypted bytes the socket no longer signals */
    for (;;) {
        bool ww;
        ssize_t n = tls_read(h->ssl, h->fd, h->in + h->in_len, sizeof h->in - h->in_len, &ww);
        if (n < 0 && errno == EINTR) continue;
        if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
            want_write(h, ww);
            return;
        }
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
        if (h->in_len == sizeof h->in) {
            httpd_error(h, HS_431, NULL, "request head over 8 KiB\n", false);
            return;
        }
    }
}

/* TLS: the handshake a step at a time; the request head after it. */
static void handshake(hconn *h)
{
    bool ww;
    int rc = tls_handshake(h->ssl, &ww);
    if (rc < 0) { /* not TLS (plain HTTP to the TLS port), or a bad client hello */
        LOGD("%s: TLS handshake failed", h->d->ops->name);
        hconn_free(h);
        return;
    }
    want_write(h, rc == 0 && ww);
    if (rc == 0) return;
    h->handshaking = false;
    on_read(h); /* the request may have come with the handshake's last flight */
}

static void on_conn(ae_loop *l, int fd, void *data, int mask)
{
    (void)l;
    (void)fd;
    hconn *h = data;
    if (h->handshaking) {
        handshake(h);
        return;
    }
    bool pending = h->out && h->out_pos < h->out_len;
    if ((mask & AE_WRITABLE) && pending && !flush(h)) return; /* freed */
    /* readable, or writable for a TLS read that had to write first */
    if ((mask & AE_READABLE) || ((mask & AE_WRITABLE) && !pending)) on_read(h);
}

static void on_accept(ae_loop *l, int lfd, void *data, int mask)
{
    (void)mask;
    httpd *d = data;
    server *s = d->s;
    for (;;) {
        int fd = accept4(lfd, NULL, NULL, SOCK_NONBLOCK | SOCK_CLOEXEC);
        if (fd < 0) {
            if (errno == EINTR) continue;
            if (errno != EAGAIN && errno != EWOULDBLOCK) LOGW("%s: accept: %s", d->ops->name, strerror(errno));
            return;
        }
        hconn *h = NULL;
        if (d->n < d->max && fd < s->conns_cap) h = calloc(1, sizeof *h);
        if (!h || ae_add(l, fd, AE_READABLE, on_conn, h) < 0) {
            /* too many at once (or no memory): say so, best effort; what
               the client already sent is read first (closing with unread
               input would reset the connection, the answer lost) */
            char junk[4096];
            for (int k = 0; k < 4 && read(fd, junk, sizeof junk) > 0; k++) {
            }
            if (!d->tls) say_now(NULL, fd, HS_503, "Retry-After: 1\r\n", "too many connections now\n");
            close(fd); /* (TLS: no handshake made, nothing can be said) */
            free(h);
            d->counts[HS_503]++;
            continue;
        }
        *h = (hconn){.d = d, .fd = fd, .deadline_ms = ae_now_ms() + s->cfg.hello_timeout_ms};
        d->c[d->n++] = h;
        if (d->tls) {
            h->handshaking = true;
            if (!(h->ssl = tls_new(d->tls, fd))) hconn_free(h);
        }
    }
}

uint32_t httpd_conns(const httpd *d)
{
    return d ? d->n : 0;
}

void httpd_sweep(httpd *d, uint64_t now_ms)
{
    if (!d) return;
    for (uint32_t i = d->n; i-- > 0;) {
        hconn *h = d->c[i];
        if (now_ms < h->deadline_ms) continue;
        if (!h->answered && !h->handshaking) {
            /* slow-loris: tell it, without waiting for it to read */
            say_now(h->ssl, h->fd, HS_408, NULL, "request head not sent in time\n");
            d->counts[HS_408]++;
        }
        hconn_free(h);
    }
}

httpd *httpd_open(server *s, const char *addr, int port, uint32_t max_conns, const httpd_ops *ops,
                  uint64_t *counts, SSL_CTX *tls)
{
    httpd *d = calloc(1, sizeof *d);
    if (!d || !(d->c = calloc(max_conns, sizeof *d->c))) {
        free(d);
        LOGE("%s: out of memory", ops->name);
        return NULL;
    }
    *d = (httpd){.s = s, .ops = ops, .counts = counts, .tls = tls, .max = max_conns, .c = d->c};
    d->lfd = listen_tcp(addr, port);
    if (d->lfd < 0) goto fail; /* said why */
    if (d->lfd >= s->conns_cap || ae_add(s->loop, d->lfd, AE_READABLE, on_accept, d) < 0) {
        LOGE("%s: cannot listen on %s:%d: %s", ops->name, addr, port, strerror(errno));
        goto fail;
    }
    return d;
fail:
    httpd_close(d);
    return NULL;
}

void httpd_close(httpd *d)
{
    if (!d) return;
    while (d->n) hconn_free(d->c[0]);
    if (d->lfd >= 0) {
        ae_del(d->s->loop, d->lfd, AE_READABLE);
        close(d->lfd);
    }
    free(d->c);
    free(d);
}
