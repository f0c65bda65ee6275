/*
 * web.h — `vantaged --web`: the pages and the WebSocket transport (web.c).
 */
#ifndef VANTAGE_WEB_H
#define VANTAGE_WEB_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

struct server;
struct conn;
struct wsio;

/* Listens on cfg.web_bind:web_port, pages from cfg.web_root. 0, or -1 (logged). */
int  web_open(struct server *s);
void web_close(struct server *s);

/* Sec-WebSocket-Accept for the key key[0, n): base64(SHA-1(key + GUID)), 28
 * characters and a NUL (RFC 6455 4.2.2). */
void web_accept_key(const char *key, size_t n, char out[29]);

/* The transport, for server.c. web_ws_init makes c a WebSocket connection
 * (c->ws = w; w then belongs to c, freed by web_ws_free). The others
 * return MD_NONE, or why the connection is over (metrics.h MD_*). */
int  web_ws_init(struct server *s, struct conn *c, struct wsio *w);
void web_ws_free(struct conn *c);
/* Frees a framing not (or no longer) a connection's: its wslay context
 * and TLS session. NULL is fine. */
void web_wsio_free(struct wsio *w);
/* Reads what the socket has: binary messages' bytes appended to c->in. */
int  web_ws_recv(struct conn *c);
/* Whether wslay holds no message to send (the next block may go). */
bool web_ws_idle(const struct conn *c);
/* Queues p[0, n) as one binary message (copied). 0, or -1: no memory. */
int  web_ws_queue(struct conn *c, const uint8_t *p, size_t n);
/* Sends what the socket takes. */
int  web_ws_send(struct conn *c);
/* Queues a close (code, reason) and sends what the socket takes. */
int  web_ws_end(struct conn *c, uint16_t code, const char *why);

#endif
