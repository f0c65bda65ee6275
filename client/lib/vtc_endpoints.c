/*
 * vtc_endpoints.c — where libvantage connects: one endpoint's socket (TCP
 * or Unix), and endpoint lists (vtc_connect_opts.endpoints, a cluster's
 * daemons) split at commas, each entry made connect options.
 */
#include "vtc_endpoints.h"

#include <errno.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

size_t vtc_endpoint_split(const char *list, const char **eps, size_t *lens, size_t max)
{
    size_t n = 0;
    for (const char *e = list; *e && n < max;) {
        const char *comma = strchr(e, ',');
        size_t l = comma ? (size_t)(comma - e) : strlen(e);
        if (l) eps[n] = e, lens[n++] = l;
        e += l + (comma ? 1 : 0);
    }
    return n;
}

bool vtc_endpoint_parse(const char *ep, size_t n, vtc_connect_opts *d, char *host, size_t hostlen, char *path,
                        size_t pathlen)
{
    if (!n || n >= hostlen || n >= pathlen) return false;
    if (memchr(ep, '/', n)) {
        memcpy(path, ep, n);
        path[n] = 0;
        d->unix_path = path;
        return true;
    }
    const char *colon = NULL;
    for (size_t i = 0; i < n; i++)
        if (ep[i] == ':') colon = ep + i;
    if (!colon || colon == ep + n - 1) return false;
    size_t hl = (size_t)(colon - ep);
    const char *h = ep;
    if (hl >= 2 && h[0] == '[' && h[hl - 1] == ']') h++, hl -= 2;
    memcpy(host, h, hl);
    host[hl] = 0;
    char *end;
    long port = strtol(colon + 1, &end, 10);
    if (end != ep + n || port < 1 || port > 65535) return false;
    d->host = host;
    d->port = (int)port;
    d->unix_path = NULL;
    return true;
}

int vtc_connect_fd(const vtc_connect_opts *o, char *err, size_t errlen)
{
    int fd = -1;
    if (o->unix_path && *o->unix_path) {
        struct sockaddr_un sa = {.sun_family = AF_UNIX};
        if (strlen(o->unix_path) >= sizeof sa.sun_path) {
            snprintf(err, errlen, "socket path too long");
            return -1;
        }
        strcpy(sa.sun_path, o->unix_path);
        fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
        if (fd < 0 || connect(fd, (struct sockaddr *)&sa, sizeof sa) < 0) {
            snprintf(err, errlen, "%s: %s", o->unix_path, strerror(errno));
            if (fd >= 0) close(fd);
            return -1;
        }
        return fd;
    }
    char port[16];
    snprintf(port, sizeof port, "%d", o->port ? o->port : VTC_DEFAULT_PORT);
    struct addrinfo hints = {.ai_family = AF_UNSPEC, .ai_socktype = SOCK_STREAM}, *res = NULL;
    const char *host = o->host && *o->host ? o->host : "127.0.0.1";
    int g = getaddrinfo(host, port, &hints, &res);
    if (g) {
        snprintf(err, errlen, "%s: %s", host, gai_strerror(g));
        return -1;
    }
    for (struct addrinfo *a = res; a; a = a->ai_next) {
        fd = socket(a->ai_family, a->ai_socktype | SOCK_CLOEXEC, a->ai_protocol);
        if (fd < 0) continue;
        if (connect(fd, a->ai_addr, a->ai_addrlen) == 0) break;
        snprintf(err, errlen, "%s:%s: %s", host, port, strerror(errno));
        close(fd);
        fd = -1;
    }
    freeaddrinfo(res);
    if (fd >= 0) {
        int one = 1;
        setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    }
    return fd;
}
