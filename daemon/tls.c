/*
 * tls.c — the daemon's TLS (tls.h) over OpenSSL 3. Errors of the library's
 * queue are drained at each failure so one connection's never shows up as
 * another's.
 */
#include "tls.h"

#include <errno.h>
#include <openssl/err.h>
#include <openssl/ssl.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

/* The library's last error as text, its queue emptied. */
static void ssl_why(char *err, size_t errlen, const char *what, const char *path)
{
    unsigned long e = ERR_peek_last_error();
    char lib[256] = "unknown error";
    if (e) ERR_error_string_n(e, lib, sizeof lib);
    ERR_clear_error();
    snprintf(err, errlen, "%s %s: %s", what, path, lib);
}

SSL_CTX *tls_server_ctx(const char *cert, const char *key, char *err, size_t errlen)
{
    SSL_CTX *ctx = SSL_CTX_new(TLS_server_method());
    if (!ctx) {
        ssl_why(err, errlen, "TLS", "context");
        return NULL;
    }
    SSL_CTX_set_min_proto_version(ctx, TLS1_2_VERSION);
    /* wslay and httpd retry a write with the same bytes, perhaps from
       another address, and take partial writes */
    SSL_CTX_set_mode(ctx, SSL_MODE_ENABLE_PARTIAL_WRITE | SSL_MODE_ACCEPT_MOVING_WRITE_BUFFER);
    if (SSL_CTX_use_certificate_chain_file(ctx, cert) != 1) {
        ssl_why(err, errlen, "--web-cert", cert);
        goto fail;
    }
    if (SSL_CTX_use_PrivateKey_file(ctx, key, SSL_FILETYPE_PEM) != 1) {
        ssl_why(err, errlen, "--web-key", key);
        goto fail;
    }
    if (SSL_CTX_check_private_key(ctx) != 1) {
        ssl_why(err, errlen, "--web-key", "does not match --web-cert");
        goto fail;
    }
    return ctx;
fail:
    SSL_CTX_free(ctx);
    return NULL;
}

void tls_ctx_free(SSL_CTX *ctx)
{
    SSL_CTX_free(ctx);
}

SSL *tls_new(SSL_CTX *ctx, int fd)
{
    SSL *ssl = SSL_new(ctx);
    if (ssl && SSL_set_fd(ssl, fd) != 1) {
        SSL_free(ssl);
        ssl = NULL;
    }
    if (ssl) SSL_set_accept_state(ssl);
    ERR_clear_error();
    return ssl;
}

void tls_free(SSL *ssl)
{
    SSL_free(ssl);
}

/* After a failed SSL call: 0 (not now, errno EAGAIN) or -1 (errno set). */
static int after(SSL *ssl, int rc, bool *want_write)
{
    int e = SSL_get_error(ssl, rc);
    int saved = errno;
    ERR_clear_error();
    *want_write = e == SSL_ERROR_WANT_WRITE;
    if (e == SSL_ERROR_WANT_READ || e == SSL_ERROR_WANT_WRITE) {
        errno = EAGAIN;
        return 0;
    }
    errno = e == SSL_ERROR_SYSCALL && saved ? saved : ECONNRESET;
    return -1;
}

int tls_handshake(SSL *ssl, bool *want_write)
{
    int rc = SSL_do_handshake(ssl);
    if (rc == 1) return 1;
    return after(ssl, rc, want_write) == 0 ? 0 : -1;
}

ssize_t tls_read(SSL *ssl, int fd, void *buf, size_t n, bool *want_write)
{
    *want_write = false;
    if (!ssl) return read(fd, buf, n);
    size_t got = 0;
    int rc = SSL_read_ex(ssl, buf, n, &got);
    if (rc == 1) return (ssize_t)got;
    if (SSL_get_error(ssl, rc) == SSL_ERROR_ZERO_RETURN) { /* close_notify */
        ERR_clear_error();
        return 0;
    }
    return after(ssl, rc, want_write) == 0 ? -1 : (errno == ECONNRESET ? 0 : -1);
}

ssize_t tls_write(SSL *ssl, int fd, const void *buf, size_t n, bool *want_write)
{
    *want_write = false;
    if (!ssl) return send(fd, buf, n, MSG_NOSIGNAL);
    size_t put = 0;
    int rc = SSL_write_ex(ssl, buf, n, &put);
    if (rc == 1) return (ssize_t)put;
    after(ssl, rc, want_write);
    return -1;
}

void tls_close_notify(SSL *ssl)
{
    if (!ssl) return;
    (void)SSL_shutdown(ssl);
    ERR_clear_error();
}
