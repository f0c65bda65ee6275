/*
 * httpd.h — the daemon's HTTP/1.x connections, on its own event loop: one
 * piece of code for every HTTP endpoint it serves (`--metrics`, `--web`).
 * The head is parsed by http.c (the one parser, fuzzed); an endpoint says
 * only what to answer, in its serve callback.
 *
 * One request a connection: every answer says `Connection: close`; then
 * the daemon shuts its side and reads until the client closes (so the
 * answer is not lost to a reset if the client sent more than its head).
 * At most max_conns connections at once (more get 503 at once); the whole
 * head must arrive within --hello-timeout of the accept (slow-loris: 408,
 * closed), and a connection is gone at most 2 s after its answer was
 * written. A WebSocket upgrade takes its connection out of here
 * (httpd_take): from then on it is the protocol's (web.c, server.c).
 */
#ifndef VANTAGE_HTTPD_H
#define VANTAGE_HTTPD_H

#include "http.h"

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

struct server;
typedef struct ssl_st SSL;
typedef struct ssl_ctx_st SSL_CTX;
typedef struct httpd httpd;
typedef struct hconn hconn;

#define HTTPD_HEAD_MAX 8192u  /* request line + headers; more get 431 */

/* Answers, counted per endpoint by slot (the metrics name the codes). */
enum { HS_101, HS_200, HS_400, HS_401, HS_403, HS_404, HS_405, HS_408, HS_426, HS_431, HS_500, HS_503, HS_505,
       HS_COUNT };
extern const char *const httpd_codes[HS_COUNT]; /* "101", "200", ... */

typedef struct httpd_ops {
    const char *name;  /* "metrics", "web": in logs */
    /* A whole, well-formed head rq (its spans point into the connection's
       buffer): answer with httpd_answer/httpd_error, or take the
       connection with httpd_take. */
    void (*serve)(struct server *s, hconn *h, const http_req *rq);
} httpd_ops;

/* Listens on addr:port and serves from the server's loop, over TLS when
 * tls is not NULL (the caller's, kept); counts answers into
 * counts[HS_COUNT]. NULL: it could not (logged). */
httpd *httpd_open(struct server *s, const char *addr, int port, uint32_t max_conns, const httpd_ops *ops,
                  uint64_t *counts, SSL_CTX *tls);
/* Ends every connection and the listener. NULL: nothing. */
void httpd_close(httpd *d);
/* Ends the connections past their time (the loop's sweep). */
void httpd_sweep(httpd *d, uint64_t now_ms);
/* Connections open now (0 for NULL). */
uint32_t httpd_conns(const httpd *d);

/* Queues the answer (status slot, Content-Type type, extra header lines
 * each ending in CRLF or NULL, the body unless head_only) and sends what
 * the socket takes. false: h is gone (out of memory, or the peer). */
bool httpd_answer(hconn *h, int slot, const char *type, const char *extra, const void *body, size_t len,
                  bool head_only);
/* An answer with a one-line text body (errors). */
bool httpd_error(hconn *h, int slot, const char *extra, const char *msg, bool head_only);
/* Takes the connection out of HTTP (a WebSocket upgrade): its events
 * stop, h is freed, and its fd is returned, the caller's to close, with
 * its TLS session in *ssl (NULL: plain; the caller's to free). The bytes
 * that came after the head (a client may send before it is answered) are
 * copied to rest (at most HTTPD_HEAD_MAX), *rest_len says how many. */
int httpd_take(hconn *h, uint8_t *rest, size_t *rest_len, SSL **ssl);

#endif
