/*
 * tls.h — TLS for the daemon's HTTP endpoint (`--web-cert/--web-key`), by
 * OpenSSL, non-blocking on the daemon's loop: the same read and write
 * calls serve a plain socket (ssl NULL) and a TLS one, so httpd.c and the
 * WebSocket transport (web.c) have one path for both.
 */
#ifndef VANTAGE_TLS_H
#define VANTAGE_TLS_H

#include <stdbool.h>
#include <stddef.h>
#include <sys/types.h>

typedef struct ssl_st SSL;
typedef struct ssl_ctx_st SSL_CTX;

/* A server context from a PEM certificate chain and its private key
 * (TLS 1.2 at least). NULL, with why in err. */
SSL_CTX *tls_server_ctx(const char *cert, const char *key, char *err, size_t errlen);
void tls_ctx_free(SSL_CTX *ctx);

/* A TLS session on the accepted socket fd, in server mode. NULL: no memory. */
SSL *tls_new(SSL_CTX *ctx, int fd);
void tls_free(SSL *ssl);

/* The handshake, a step: 1 done, 0 not yet (call again when the socket is
 * readable, or writable if *want_write), -1 failed. */
int tls_handshake(SSL *ssl, bool *want_write);

/* read(2) and write(2) over ssl (NULL: fd as it is): n > 0, 0 at the end
 * of the stream, -1 with errno (EAGAIN: not now; *want_write then says
 * whether the session waits for the socket to be writable, as a TLS read
 * can). */
ssize_t tls_read(SSL *ssl, int fd, void *buf, size_t n, bool *want_write);
ssize_t tls_write(SSL *ssl, int fd, const void *buf, size_t n, bool *want_write);

/* Sends close_notify, best effort (no waiting for the peer's). */
void tls_close_notify(SSL *ssl);

#endif
