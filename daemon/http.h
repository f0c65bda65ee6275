/*
 * http.h — HTTP/1.x request heads (RFC 9112), the daemon's one parser for
 * its HTTP endpoints (`--metrics` today; the web viewer of issue 21 next).
 * Pure functions over bytes: no sockets, no allocation, no server state,
 * so the fuzzer (tests/fuzz/fuzz_http.c) drives them alone.
 *
 * What is accepted: a request line METHOD SP TARGET SP HTTP/1.0|1.1 (the
 * method a token, the target visible ASCII), header lines NAME ":" OWS
 * VALUE OWS (the name a token; no obsolete line folding, no control bytes
 * but TAB in a value), CRLF or a bare LF at line ends, empty lines before
 * the request line ignored (RFC 9112 2.2). HTTP/1.1 needs a Host header.
 * Everything else is refused with the status an origin server answers
 * (400, or 505 for another HTTP version) and a one-line reason.
 */
#ifndef VANTAGE_HTTP_H
#define VANTAGE_HTTP_H

#include <stdbool.h>
#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Bytes of the head being parsed (p NULL: absent). */
typedef struct http_span {
    const char *p;
    size_t n;
} http_span;

/* A parsed head: spans into the caller's buffer, valid while it is. */
typedef struct http_req {
    http_span method, target;
    http_span path;            /* the target up to its '?' */
    bool http11;               /* HTTP/1.1 (else 1.0) */
    bool head;                 /* the method is HEAD: answers carry no body */
    bool host;                 /* a Host header came (a second one is refused) */
    http_span host_value;      /* its value, trimmed */
    http_span origin;          /* Origin, trimmed (browsers send it with a WebSocket upgrade) */
    http_span bearer;          /* the first `Authorization: Bearer TOKEN`'s token */
    bool upgrade_websocket;    /* Upgrade lists the token "websocket" */
    bool connection_upgrade;   /* Connection lists the token "upgrade" */
    http_span ws_key;          /* Sec-WebSocket-Key, trimmed */
    http_span ws_version;      /* Sec-WebSocket-Version, trimmed */
} http_req;

/* Where the head in buf[0, len) ends, just past its empty line, after
 * the empty lines before the request line (*start: where it begins); 0
 * while it has not ended. */
size_t http_head_end(const char *buf, size_t len, size_t *start);

/* Parses the head buf[start, end) (http_head_end's) into r. Returns 0, or
 * the status to answer (400, 505) with *why a reason ending in a newline;
 * r->head is set once the request line is whole and well formed, so an
 * error in a HEAD request's headers goes without a body. */
int http_parse(const char *buf, size_t start, size_t end, http_req *r, const char **why);

/* Whether the comma-separated list v (a header value) holds token t,
 * case-insensitively, with optional spaces around the commas. */
bool http_list_has(http_span v, const char *t);

#ifdef __cplusplus
}
#endif

#endif
