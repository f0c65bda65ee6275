/*
 * vtc_endpoints.h — libvantage's endpoint lists (vtc_endpoints.c), inside
 * the library.
 */
#ifndef VANTAGE_VTC_ENDPOINTS_H
#define VANTAGE_VTC_ENDPOINTS_H

#include "vantage.h"

#include <stdbool.h>
#include <stddef.h>

/* The non-empty comma-separated entries of list (at most max): eps[i] and
 * lens[i] each entry's start and length; returns how many. */
size_t vtc_endpoint_split(const char *list, const char **eps, size_t *lens, size_t max);
/* One entry ep[0..n): "HOST:PORT", "[V6]:PORT", or a socket path (it has a
 * '/'), into d's host and port or unix_path (host and path: the buffers
 * they point into). false: not one of those. */
bool vtc_endpoint_parse(const char *ep, size_t n, vtc_connect_opts *d, char *host, size_t hostlen, char *path,
                        size_t pathlen);

/* A connected socket to o's unix_path, or host:port (TCP_NODELAY), or -1
 * with err saying why. */
int vtc_connect_fd(const vtc_connect_opts *o, char *err, size_t errlen);

#endif
