/*
 * vtc_endpoints.c — libvantage's endpoint lists (vtc_connect_opts.endpoints,
 * a cluster's daemons): split at commas, each entry made connect options.
 */
#include "vtc_endpoints.h"

#include <stdlib.h>
#include <string.h>

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

