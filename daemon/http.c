/*
 * http.c — HTTP/1.x request heads (http.h): the daemon's one parser for
 * its HTTP endpoints, pure functions over a buffer.
 */
#include "http.h"

#include <string.h>
#include <strings.h>

/* RFC 9110 5.6.2: tchar */
static bool tchar(unsigned char c)
{
    return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') ||
           (c && strchr("!#$%&'*+-.^_`|~", c));
}

/* The next line of buf[0, len) from *pos, without its LF (and a CR just
 * before it); false at the end (no LF). A CR left inside it sets *bad_cr. */
static bool next_line(const char *buf, size_t len, size_t *pos, http_span *out, bool *bad_cr)
{
    const char *lf = memchr(buf + *pos, '\n', len - *pos);
    if (!lf) return false;
    out->p = buf + *pos;
    out->n = (size_t)(lf - out->p);
    if (out->n && out->p[out->n - 1] == '\r') out->n--;
    if (memchr(out->p, '\r', out->n)) *bad_cr = true;
    *pos = (size_t)(lf - buf) + 1;
    return true;
}

size_t http_head_end(const char *buf, size_t len, size_t *start)
{
    size_t pos = 0;
    while (pos < len && (buf[pos] == '\r' || buf[pos] == '\n')) pos++;
    *start = pos;
    http_span l;
    bool cr = false;
    while (next_line(buf, len, &pos, &l, &cr))
        if (l.n == 0) return pos;
    return 0;
}

static bool span_is(http_span s, const char *t)
{
    return s.n == strlen(t) && !strncasecmp(s.p, t, s.n);
}

bool http_list_has(http_span v, const char *t)
{
    size_t i = 0;
    while (v.p && i < v.n) {
        while (i < v.n && (v.p[i] == ' ' || v.p[i] == '\t' || v.p[i] == ',')) i++;
        size_t b = i;
        while (i < v.n && v.p[i] != ',') i++;
        size_t e = i;
        while (e > b && (v.p[e - 1] == ' ' || v.p[e - 1] == '\t')) e--;
        if (e > b && span_is((http_span){v.p + b, e - b}, t)) return true;
    }
    return false;
}

static int fail(const char **why, int status, const char *reason)
{
    *why = reason;
    return status;
}

/* The request line: METHOD SP TARGET SP HTTP/x.y. */
static int request_line(http_span rl, bool cr, http_req *r, const char **why)
{
    const char *end = rl.p + rl.n;
    const char *sp1 = memchr(rl.p, ' ', rl.n);
    const char *sp2 = sp1 ? memchr(sp1 + 1, ' ', (size_t)(end - sp1 - 1)) : NULL;
    if (!sp1 || !sp2 || sp1 == rl.p || sp2 == sp1 + 1 || memchr(sp2 + 1, ' ', (size_t)(end - sp2 - 1)) || cr)
        return fail(why, 400, "malformed request line\n");
    r->method = (http_span){rl.p, (size_t)(sp1 - rl.p)};
    r->target = (http_span){sp1 + 1, (size_t)(sp2 - sp1 - 1)};
    http_span version = {sp2 + 1, (size_t)(end - sp2 - 1)};
    for (size_t i = 0; i < r->method.n; i++)
        if (!tchar((unsigned char)r->method.p[i])) return fail(why, 400, "malformed method\n");
    for (size_t i = 0; i < r->target.n; i++)
        if ((unsigned char)r->target.p[i] <= 32 || (unsigned char)r->target.p[i] >= 127)
            return fail(why, 400, "malformed request target\n");
    const char *q = memchr(r->target.p, '?', r->target.n);
    r->path = (http_span){r->target.p, q ? (size_t)(q - r->target.p) : r->target.n};
    const char *v = version.p;
    if (version.n == 8 && !memcmp(v, "HTTP/1.1", 8)) {
        r->http11 = true;
    } else if (version.n == 8 && !memcmp(v, "HTTP/1.0", 8)) {
        r->http11 = false;
    } else if (version.n == 8 && !memcmp(v, "HTTP/", 5) && v[5] >= '0' && v[5] <= '9' && v[6] == '.' && v[7] >= '0' &&
               v[7] <= '9') {
        return fail(why, 505, "only HTTP/1.0 and HTTP/1.1 are spoken here\n");
    } else {
        return fail(why, 400, "malformed HTTP version\n");
    }
    r->head = r->method.n == 4 && !memcmp(r->method.p, "HEAD", 4);
    return 0;
}

/* One header line NAME ":" OWS VALUE OWS into r (the fields it keeps). */
static int header(http_span l, bool cr, http_req *r, const char **why)
{
    const char *colon = memchr(l.p, ':', l.n);
    if (cr || !colon || colon == l.p) return fail(why, 400, "malformed header line\n");
    http_span name = {l.p, (size_t)(colon - l.p)};
    for (size_t i = 0; i < name.n; i++)
        if (!tchar((unsigned char)name.p[i])) return fail(why, 400, "malformed header name\n");
    size_t v = name.n + 1, ve = l.n;
    for (size_t i = v; i < ve; i++) {
        unsigned char c = (unsigned char)l.p[i];
        if ((c < 32 && c != '\t') || c == 127) return fail(why, 400, "control byte in a header value\n");
    }
    while (v < ve && (l.p[v] == ' ' || l.p[v] == '\t')) v++;
    while (ve > v && (l.p[ve - 1] == ' ' || l.p[ve - 1] == '\t')) ve--;
    http_span val = {l.p + v, ve - v};
    if (span_is(name, "host")) {
        if (r->host) return fail(why, 400, "more than one Host header\n"); /* RFC 9112 3.2 */
        r->host = true;
        r->host_value = val;
    } else if (span_is(name, "origin")) {
        r->origin = val;
    } else if (span_is(name, "authorization") && !r->bearer.p) {
        /* "Bearer" 1*SP token */
        size_t t = 0;
        while (t < val.n && val.p[t] != ' ') t++;
        if (span_is((http_span){val.p, t}, "bearer")) {
            while (t < val.n && val.p[t] == ' ') t++;
            r->bearer = (http_span){val.p + t, val.n - t};
        }
    } else if (span_is(name, "upgrade")) {
        r->upgrade_websocket |= http_list_has(val, "websocket");
    } else if (span_is(name, "connection")) {
        r->connection_upgrade |= http_list_has(val, "upgrade");
    } else if (span_is(name, "sec-websocket-key")) {
        r->ws_key = val;
    } else if (span_is(name, "sec-websocket-version")) {
        r->ws_version = val;
    }
    return 0;
}

int http_parse(const char *buf, size_t start, size_t end, http_req *r, const char **why)
{
    *r = (http_req){0};
    *why = "";
    size_t pos = start;
    http_span l;
    bool cr = false;
    if (!next_line(buf, end, &pos, &l, &cr)) return fail(why, 400, "malformed request line\n");
    int st = request_line(l, cr, r, why);
    if (st) return st;
    /* headers up to the empty line: no folding (a line starting with white
       space is no header name), no control bytes */
    while (next_line(buf, end, &pos, &l, &cr) && l.n)
        if ((st = header(l, cr, r, why))) return st;
    if (r->http11 && !r->host) return fail(why, 400, "HTTP/1.1 needs a Host header\n");
    return 0;
}
