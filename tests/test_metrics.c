/*
 * test_metrics.c — the daemon's metrics (issue 9): `vantaged --metrics`
 * over HTTP and the METRICS message, against the real daemon.
 *
 * The model is this file's own strict reader of the Prometheus text
 * format 0.0.4 (written from the format's description, sharing nothing
 * with daemon/metrics.c): every line parses, `# TYPE` comes before its
 * family's samples and once, a family's samples are contiguous, no series
 * twice, label values escaped, counters end in _total and are >= 0,
 * histograms have increasing `le`, cumulative non-decreasing buckets, a
 * +Inf bucket equal to _count, and _sum. Then the figures are checked
 * against what the test did: N requests counted exactly (and their latency
 * samples), bytes in and out equal to the bytes the test's socket sent and
 * read, query entity counts equal to the sums of the replies' own counts,
 * errors by type and code, clients by role following connects and
 * disconnects, frames dropped for a viewer that stopped reading; HTTP bad
 * input (404, 405, 400, 431, 505, 503 past the connection limit, 401
 * without a token, a slow-loris request closed at its deadline while a
 * protocol client keeps being served); the METRICS message gives the same
 * families as HTTP.
 */
#include "test_util.h"
#include "test_daemon.h"
#include "vt_image.h"

#include <arpa/inet.h>
#include <errno.h>
#include <netinet/in.h>
#include <poll.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

/* ---- the model: a strict reader of the text exposition format ------------------------ */

typedef struct xsample {
    char name[128];
    char labels[512]; /* canonical: "k=v" pairs sorted by key, joined by \x01, values unescaped */
    double v;
    int fam;
} xsample;

typedef struct xfam {
    char name[128];
    char type[16];
    bool help, typed, closed;
    int samples;
} xfam;

typedef struct expo {
    xsample *s;
    size_t n, cap;
    xfam f[128];
    int nf;
    char err[512]; /* why the text was refused */
} expo;

static void expo_free(expo *e)
{
    free(e->s);
    memset(e, 0, sizeof *e);
}

static bool name_start(char c) { return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_' || c == ':'; }
static bool name_char(char c) { return name_start(c) || (c >= '0' && c <= '9'); }

/* Refuses the text: the reason in e->err; false. */
static bool xerr(expo *e, int ln, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
static bool xerr(expo *e, int ln, const char *fmt, ...)
{
    int o = snprintf(e->err, sizeof e->err, "line %d: ", ln);
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(e->err + o, sizeof e->err - (size_t)o, fmt, ap);
    va_end(ap);
    return false;
}
#define XFAIL(ln, ...) return xerr(e, ln, __VA_ARGS__)

/* A metric name at p[*i..]; its length (0 if none). */
static size_t read_name(const char *p, size_t n, size_t i)
{
    size_t k = i;
    if (k < n && name_start(p[k]))
        while (++k < n && name_char(p[k])) {
        }
    return k - i;
}

static int fam_find(expo *e, const char *name)
{
    for (int i = 0; i < e->nf; i++)
        if (!strcmp(e->f[i].name, name)) return i;
    return -1;
}

static int fam_get(expo *e, const char *name, int ln)
{
    int i = fam_find(e, name);
    if (i >= 0) return i;
    if (e->nf == 128) return xerr(e, ln, "too many families"), -1;
    xfam *f = &e->f[e->nf];
    memset(f, 0, sizeof *f);
    snprintf(f->name, sizeof f->name, "%s", name);
    return e->nf++;
}

/* A float as the format writes it (Go's ParseFloat: also NaN, +Inf, -Inf). */
static bool read_float(const char *s, double *v)
{
    if (!strcmp(s, "+Inf") || !strcmp(s, "Inf")) return *v = INFINITY, true;
    if (!strcmp(s, "-Inf")) return *v = -INFINITY, true;
    if (!strcmp(s, "NaN")) return *v = NAN, true;
    if (!*s) return false;
    for (const char *c = s; *c; c++)
        if (!strchr("0123456789+-.eE", *c)) return false;
    char *end;
    errno = 0;
    *v = strtod(s, &end);
    return !*end && !errno;
}

typedef struct kv {
    char k[64], v[256];
} kv;

static int kv_cmp(const void *a, const void *b)
{
    return strcmp(((const kv *)a)->k, ((const kv *)b)->k);
}

static void canon(kv *l, int nl, char *out, size_t outlen, const char *skip)
{
    qsort(l, (size_t)nl, sizeof *l, kv_cmp);
    size_t o = 0;
    out[0] = 0;
    for (int i = 0; i < nl; i++) {
        if (skip && !strcmp(l[i].k, skip)) continue;
        o += (size_t)snprintf(out + o, outlen - o, "%s%s=%s", o ? "\x01" : "", l[i].k, l[i].v);
        assert_true(o < outlen);
    }
}

static bool parse_sample(expo *e, const char *p, size_t n, int ln)
{
    size_t nl = read_name(p, n, 0);
    if (!nl) XFAIL(ln, "no metric name");
    xsample s = {0};
    if (nl >= sizeof s.name) XFAIL(ln, "name too long");
    memcpy(s.name, p, nl);
    size_t i = nl;
    kv l[8];
    int nlab = 0;
    if (i < n && p[i] == '{') {
        i++;
        while (i < n && p[i] != '}') {
            size_t kl = 0;
            if (i < n && ((p[i] >= 'a' && p[i] <= 'z') || (p[i] >= 'A' && p[i] <= 'Z') || p[i] == '_'))
                while (i + ++kl < n && (name_char(p[i + kl]) && p[i + kl] != ':')) {
                }
            if (!kl || kl >= sizeof l[0].k) XFAIL(ln, "bad label name");
            if (nlab == 8) XFAIL(ln, "too many labels");
            kv *L = &l[nlab++];
            memcpy(L->k, p + i, kl);
            L->k[kl] = 0;
            if (!strncmp(L->k, "__", 2)) XFAIL(ln, "reserved label name %s", L->k);
            for (int j = 0; j < nlab - 1; j++)
                if (!strcmp(l[j].k, L->k)) XFAIL(ln, "label %s twice", L->k);
            i += kl;
            if (i + 1 >= n || p[i] != '=' || p[i + 1] != '"') XFAIL(ln, "label %s: no =\"", L->k);
            i += 2;
            size_t o = 0;
            for (;; i++) {
                if (i >= n) XFAIL(ln, "unterminated label value");
                char c = p[i];
                if (c == '"') break;
                if (c == '\\') {
                    if (i + 1 >= n) XFAIL(ln, "escape at the end");
                    c = p[++i];
                    if (c == 'n') c = '\n';
                    else if (c != '\\' && c != '"') XFAIL(ln, "bad escape \\%c", c);
                }
                if (o + 1 >= sizeof L->v) XFAIL(ln, "label value too long");
                L->v[o++] = c;
            }
            L->v[o] = 0;
            i++; /* the quote */
            if (i < n && p[i] == ',') i++;
            else if (i < n && p[i] != '}') XFAIL(ln, "expected , or }");
        }
        if (i >= n) XFAIL(ln, "unterminated label set");
        i++;
    }
    if (i >= n || p[i] != ' ') XFAIL(ln, "no space before the value");
    i++;
    char v[64];
    size_t vl = n - i;
    if (!vl || vl >= sizeof v || memchr(p + i, ' ', vl)) XFAIL(ln, "bad value (or a timestamp: the daemon writes none)");
    memcpy(v, p + i, vl);
    v[vl] = 0;
    if (!read_float(v, &s.v)) XFAIL(ln, "value %s is no float", v);
    canon(l, nlab, s.labels, sizeof s.labels, NULL);

    /* its family: the name itself, a histogram's _bucket/_sum/_count or a
       summary's _sum/_count (the daemon's summaries have no quantiles) */
    int fi = fam_find(e, s.name);
    if (fi < 0 || !e->f[fi].typed) {
        static const char *const suf[] = {"_bucket", "_sum", "_count"};
        for (int k = 0; k < 3; k++) {
            size_t sl = strlen(suf[k]);
            if (nl > sl && !strcmp(s.name + nl - sl, suf[k])) {
                char base[128];
                memcpy(base, s.name, nl - sl);
                base[nl - sl] = 0;
                int b = fam_find(e, base);
                if (b >= 0 && (!strcmp(e->f[b].type, "histogram") || (k > 0 && !strcmp(e->f[b].type, "summary"))))
                    fi = b;
            }
        }
    }
    if (fi < 0 || !e->f[fi].typed) XFAIL(ln, "sample %s before its # TYPE", s.name);
    xfam *f = &e->f[fi];
    if ((!strcmp(f->type, "histogram") || !strcmp(f->type, "summary")) && !strcmp(f->name, s.name))
        XFAIL(ln, "%s sample without a suffix", f->type);
    if (f->closed) XFAIL(ln, "family %s not contiguous", f->name);
    for (int k = 0; k < e->nf; k++)
        if (k != fi && e->f[k].samples) e->f[k].closed = true;
    f->samples++;
    s.fam = fi;
    if (!strcmp(f->type, "counter") && !(s.v >= 0)) XFAIL(ln, "counter %s below 0", s.name);
    bool is_bucket = !strcmp(f->type, "histogram") && strstr(s.name, "_bucket") == s.name + strlen(f->name);
    bool has_le = false;
    for (int k = 0; k < nlab; k++) has_le |= !strcmp(l[k].k, "le");
    if (is_bucket != has_le) XFAIL(ln, "le on %s", s.name);
    for (size_t k = 0; k < e->n; k++)
        if (!strcmp(e->s[k].name, s.name) && !strcmp(e->s[k].labels, s.labels)) XFAIL(ln, "series twice");
    if (e->n == e->cap) {
        e->cap = e->cap ? 2 * e->cap : 256;
        e->s = realloc(e->s, e->cap * sizeof *e->s);
        assert_non_null(e->s);
    }
    e->s[e->n++] = s;
    return true;
}

/* Checks every histogram series: buckets as the format wants them. */
static bool check_histograms(expo *e)
{
    for (int fi = 0; fi < e->nf; fi++) {
        const xfam *f = &e->f[fi];
        if (strcmp(f->type, "histogram")) continue;
        char bn[160], sn[160], cn[160];
        snprintf(bn, sizeof bn, "%s_bucket", f->name);
        snprintf(sn, sizeof sn, "%s_sum", f->name);
        snprintf(cn, sizeof cn, "%s_count", f->name);
        for (size_t i = 0; i < e->n; i++) {
            if (strcmp(e->s[i].name, cn)) continue;
            /* the series: its labels; its buckets in order of appearance */
            const char *series = e->s[i].labels;
            double last_le = -INFINITY, last = 0, inf = -1, sum = NAN;
            int nb = 0;
            for (size_t k = 0; k < e->n; k++) {
                const xsample *b = &e->s[k];
                if (!strcmp(b->name, sn) && !strcmp(b->labels, series)) sum = b->v;
                if (strcmp(b->name, bn)) continue;
                /* the bucket's labels without le must be the series' */
                kv l[8];
                int nl = 0;
                char tmp[512];
                snprintf(tmp, sizeof tmp, "%s", b->labels);
                double le = NAN;
                for (char *tok = strtok(tmp, "\x01"); tok; tok = strtok(NULL, "\x01")) {
                    char *eq = strchr(tok, '=');
                    assert_non_null(eq);
                    *eq = 0;
                    if (!strcmp(tok, "le")) {
                        if (!read_float(eq + 1, &le)) return xerr(e, 0, "%s: le %s", bn, eq + 1);
                        continue;
                    }
                    snprintf(l[nl].k, sizeof l[nl].k, "%s", tok);
                    snprintf(l[nl].v, sizeof l[nl].v, "%s", eq + 1);
                    nl++;
                }
                char c[512];
                canon(l, nl, c, sizeof c, NULL);
                if (strcmp(c, series)) continue;
                if (!(le > last_le)) return xerr(e, 0, "%s{%s}: le not increasing", bn, series);
                if (b->v < last || b->v != floor(b->v)) return xerr(e, 0, "%s{%s}: buckets not cumulative", bn, series);
                last_le = le;
                last = b->v;
                if (isinf(le)) inf = b->v;
                nb++;
            }
            if (!isinf(last_le) || inf < 0) return xerr(e, 0, "%s{%s}: no +Inf bucket last", bn, series);
            if (inf != e->s[i].v) return xerr(e, 0, "%s{%s}: +Inf %g != _count %g", bn, series, inf, e->s[i].v);
            if (isnan(sum) || sum < 0) return xerr(e, 0, "%s{%s}: no _sum", sn, series);
            if (nb < 2) return xerr(e, 0, "%s{%s}: %d buckets", bn, series, nb);
        }
    }
    return true;
}

/* Reads text strictly: false (and e->err) on any deviation. */
static bool expo_read(const char *t, size_t len, expo *e)
{
    memset(e, 0, sizeof *e);
    if (!len || t[len - 1] != '\n') return xerr(e, 0, "empty, or not ended with a line feed");
    int ln = 0;
    for (size_t pos = 0; pos < len;) {
        const char *p = t + pos, *nlp = memchr(p, '\n', len - pos);
        size_t n = (size_t)(nlp - p);
        pos += n + 1;
        ln++;
        if (memchr(p, '\r', n) || memchr(p, 0, n)) XFAIL(ln, "CR or NUL in a line");
        if (!n) XFAIL(ln, "empty line");
        if (p[0] != '#') {
            if (!parse_sample(e, p, n, ln)) return false;
            continue;
        }
        bool help = n > 7 && !strncmp(p, "# HELP ", 7), type = n > 7 && !strncmp(p, "# TYPE ", 7);
        if (!help && !type) XFAIL(ln, "a comment that is neither HELP nor TYPE");
        size_t nl = read_name(p, n, 7);
        if (!nl || 7 + nl >= n || p[7 + nl] != ' ') XFAIL(ln, "HELP/TYPE without a name and text");
        char name[128];
        if (nl >= sizeof name) XFAIL(ln, "name too long");
        memcpy(name, p + 7, nl);
        name[nl] = 0;
        int fi = fam_get(e, name, ln);
        if (fi < 0) return false;
        xfam *f = &e->f[fi];
        const char *rest = p + 7 + nl + 1;
        size_t rl = n - 7 - nl - 1;
        if (f->samples) XFAIL(ln, "%s of %s after its samples", help ? "HELP" : "TYPE", name);
        if (help) {
            if (f->help) XFAIL(ln, "HELP %s twice", name);
            f->help = true;
            for (size_t i = 0; i < rl; i++)
                if (rest[i] == '\\' && (i + 1 >= rl || (rest[i + 1] != '\\' && rest[i + 1] != 'n')))
                    XFAIL(ln, "bad escape in HELP");
                else if (rest[i] == '\\')
                    i++;
        } else {
            if (f->typed) XFAIL(ln, "TYPE %s twice", name);
            if (rl >= sizeof f->type) XFAIL(ln, "bad type");
            memcpy(f->type, rest, rl);
            f->type[rl] = 0;
            if (strcmp(f->type, "counter") && strcmp(f->type, "gauge") && strcmp(f->type, "histogram") &&
                strcmp(f->type, "summary") && strcmp(f->type, "untyped"))
                XFAIL(ln, "unknown type %s", f->type);
            f->typed = true;
            /* this daemon's conventions (Prometheus's naming guide) */
            size_t L = strlen(name);
            if (strncmp(name, "vantage_", 8)) XFAIL(ln, "%s: not vantage_", name);
            if (!strcmp(f->type, "counter") && (L < 6 || strcmp(name + L - 6, "_total")))
                XFAIL(ln, "counter %s does not end in _total", name);
            if (!strcmp(f->type, "histogram") && (L < 8 || strcmp(name + L - 8, "_seconds")))
                XFAIL(ln, "histogram %s is not in seconds", name);
        }
    }
    for (int i = 0; i < e->nf; i++)
        if (!e->f[i].help || !e->f[i].typed) return xerr(e, 0, "family %s without HELP or TYPE", e->f[i].name);
    return check_histograms(e);
}

/* The same, failing the test on any deviation. */
static void expo_parse(const char *t, size_t len, expo *e)
{
    if (!expo_read(t, len, e)) fail_msg("exposition refused: %s", e->err);
}

/* A sample's value: NAN when there is none. Labels k1=v1 (and k2=v2). */
static double xv(const expo *e, const char *name, const char *k1, const char *v1, const char *k2, const char *v2)
{
    kv l[2];
    int nl = 0;
    if (k1) snprintf(l[nl].k, sizeof l[nl].k, "%s", k1), snprintf(l[nl].v, sizeof l[nl].v, "%s", v1), nl++;
    if (k2) snprintf(l[nl].k, sizeof l[nl].k, "%s", k2), snprintf(l[nl].v, sizeof l[nl].v, "%s", v2), nl++;
    char c[512];
    canon(l, nl, c, sizeof c, NULL);
    for (size_t i = 0; i < e->n; i++)
        if (!strcmp(e->s[i].name, name) && !strcmp(e->s[i].labels, c)) return e->s[i].v;
    return NAN;
}

/* The same, 0 when the series is not there (error pairs appear when seen). */
static double xv0(const expo *e, const char *name, const char *k1, const char *v1, const char *k2, const char *v2)
{
    double v = xv(e, name, k1, v1, k2, v2);
    return isnan(v) ? 0 : v;
}

/* A value that must be there. */
static double xget(const expo *e, const char *name, const char *k1, const char *v1)
{
    double v = xv(e, name, k1, v1, NULL, NULL);
    if (isnan(v)) fail_msg("no sample %s{%s=\"%s\"}", name, k1 ? k1 : "", v1 ? v1 : "");
    return v;
}

/* ---- HTTP by hand ---------------------------------------------------------------------- */

#define HTTP_MAX_CONNS 16 /* daemon/metrics.h: METRICS_HTTP_MAX_CONNS */

static int tcp_connect(int port)
{
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    struct sockaddr_in sa = {.sin_family = AF_INET, .sin_port = htons((uint16_t)port),
                             .sin_addr.s_addr = htonl(INADDR_LOOPBACK)};
    assert_int_equal(connect(fd, (struct sockaddr *)&sa, sizeof sa), 0);
    struct timeval tv = {.tv_sec = 10};
    setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    return fd;
}

typedef struct hresp {
    int status;
    char head[2048];
    char *body;
    size_t body_len;
} hresp;

/* Reads an HTTP answer to EOF from fd and closes it. */
static void http_read(int fd, hresp *r)
{
    size_t cap = 1 << 16, len = 0;
    char *buf = malloc(cap);
    assert_non_null(buf);
    for (;;) {
        if (cap - len < 4096) buf = realloc(buf, cap *= 2);
        assert_non_null(buf);
        ssize_t n = read(fd, buf + len, cap - len);
        if (n < 0 && errno == EINTR) continue;
        if (n < 0) fail_msg("http read: %s", strerror(errno));
        if (n == 0) break;
        len += (size_t)n;
    }
    close(fd);
    memset(r, 0, sizeof *r);
    char *end = NULL;
    for (size_t i = 0; i + 3 < len && !end; i++)
        if (!memcmp(buf + i, "\r\n\r\n", 4)) end = buf + i;
    if (!end) fail_msg("no HTTP head in %zu bytes", len);
    size_t hl = (size_t)(end - buf);
    assert_true(hl < sizeof r->head);
    memcpy(r->head, buf, hl);
    r->head[hl] = 0;
    assert_int_equal(sscanf(r->head, "HTTP/1.1 %d", &r->status), 1);
    r->body_len = len - hl - 4;
    r->body = malloc(r->body_len + 1);
    memcpy(r->body, end + 4, r->body_len);
    r->body[r->body_len] = 0;
    free(buf);
    /* the head says the body's length, and the connection's end */
    assert_non_null(strstr(r->head, "\r\nContent-Length: "));
    assert_non_null(strstr(r->head, "\r\nConnection: close"));
}

static void http_send(int port, const char *req, size_t n, hresp *r)
{
    int fd = tcp_connect(port);
    assert_int_equal(write(fd, req, n), (ssize_t)n);
    http_read(fd, r);
}

static void http_free(hresp *r)
{
    free(r->body);
    r->body = NULL;
}

static size_t content_length(const hresp *r)
{
    const char *cl = strstr(r->head, "\r\nContent-Length: ");
    return cl ? (size_t)strtoul(cl + 18, NULL, 10) : (size_t)-1;
}

/* GET /metrics: 200, the right type, a body as long as said; parsed. */
static void scrape(int port, expo *e)
{
    char req[128];
    int n = snprintf(req, sizeof req, "GET /metrics HTTP/1.1\r\nHost: 127.0.0.1:%d\r\n\r\n", port);
    hresp r;
    http_send(port, req, (size_t)n, &r);
    if (r.status != 200) fail_msg("GET /metrics: %d %s", r.status, r.body);
    assert_non_null(strstr(r.head, "\r\nContent-Type: text/plain; version=0.0.4"));
    assert_int_equal(content_length(&r), r.body_len);
    expo_parse(r.body, r.body_len, e);
    http_free(&r);
}

/* Scrapes until name{k=v} == want (gauges follow events the loop may take
 * a turn to see), at most 3 s; returns the scrapes it took. */
static int wait_value(int port, const char *name, const char *k, const char *v, double want)
{
    double got = NAN;
    for (int i = 0; i < 300; i++) {
        expo e;
        scrape(port, &e);
        got = xv(&e, name, k, v, NULL, NULL);
        expo_free(&e);
        if (got == want) return i + 1;
        usleep(10000);
    }
    fail_msg("%s{%s=\"%s\"} is %g, want %g", name, k ? k : "", v ? v : "", got, want);
    return 0;
}

static void daemon_with_metrics(daemon_proc *d, int *mport, const char *const *more)
{
    static char arg[32];
    *mport = free_port();
    snprintf(arg, sizeof arg, "%d", *mport);
    const char *extra[16] = {"--metrics", arg};
    int n = 2;
    for (int i = 0; more && more[i] && n < 15; i++) extra[n++] = more[i];
    extra[n] = NULL;
    daemon_start_args(d, extra);
}

/* ---- raw protocol bytes, counted ------------------------------------------------------- */

typedef struct rawc {
    int fd;
    uint64_t sent, got;
    uint8_t buf[1 << 16];
    size_t have;
} rawc;

static void raw_open(rawc *r, const daemon_proc *d)
{
    memset(r, 0, sizeof *r);
    r->fd = socket(AF_UNIX, SOCK_STREAM, 0);
    struct sockaddr_un sa = {.sun_family = AF_UNIX};
    snprintf(sa.sun_path, sizeof sa.sun_path, "%s", d->sock);
    assert_int_equal(connect(r->fd, (struct sockaddr *)&sa, sizeof sa), 0);
    struct timeval tv = {.tv_sec = 10};
    setsockopt(r->fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
}

static void raw_write(rawc *r, const uint8_t *p, size_t n)
{
    assert_int_equal(write(r->fd, p, n), (ssize_t)n);
    r->sent += n;
}

/* The next frame's type (its payload read and dropped); -1 at EOF. */
static int raw_frame(rawc *r, vp_header *h)
{
    for (;;) {
        size_t fs = 0;
        int rc = vp_frame_check(r->buf, r->have, UINT32_MAX, h, &fs);
        if (rc == VP_OK) {
            memmove(r->buf, r->buf + fs, r->have - fs);
            r->have -= fs;
            return h->type;
        }
        assert_int_equal(rc, VP_NEED_MORE);
        if (r->have >= VP_HEADER_SIZE && fs > sizeof r->buf) {
            /* bigger than the buffer (a raw frame): read it through */
            size_t left = fs - r->have;
            while (left) {
                ssize_t n = read(r->fd, r->buf, left < sizeof r->buf ? left : sizeof r->buf);
                if (n <= 0) return -1;
                left -= (size_t)n;
                r->got += (uint64_t)n;
            }
            r->have = 0;
            return h->type;
        }
        ssize_t n = read(r->fd, r->buf + r->have, sizeof r->buf - r->have);
        if (n <= 0) return -1;
        r->have += (size_t)n;
        r->got += (uint64_t)n;
    }
}

/* Reads exactly n bytes (what raw_frame left buffered first); false at EOF. */
static bool raw_read_full(rawc *r, uint8_t *p, size_t n)
{
    size_t k = r->have < n ? r->have : n;
    memcpy(p, r->buf, k);
    memmove(r->buf, r->buf + k, r->have - k);
    r->have -= k;
    while (k < n) {
        ssize_t m = read(r->fd, p + k, n - k);
        if (m <= 0) return false;
        k += (size_t)m;
        r->got += (uint64_t)m;
    }
    return true;
}

/* The next frame's header, its payload into p (room for cap bytes). */
static int raw_reply(rawc *r, vp_header *h, uint8_t *p, size_t cap)
{
    uint8_t hb[VP_HEADER_SIZE];
    if (!raw_read_full(r, hb, sizeof hb)) return -1;
    size_t fs = 0;
    vp_frame_check(hb, sizeof hb, UINT32_MAX, h, &fs);
    assert_true(h->len <= cap);
    if (!raw_read_full(r, p, h->len)) return -1;
    return h->type;
}

static void raw_hello_as(rawc *r, const daemon_proc *d, int role)
{
    uint8_t buf[256];
    vp_writer w;
    raw_open(r, d);
    vp_writer_init(&w, buf, sizeof buf);
    vp_enc_hello(&w, 1, &(vp_hello){.magic = VP_MAGIC, .version = VP_VERSION, .role = (uint8_t)role});
    raw_write(r, buf, w.len);
    vp_header h;
    assert_int_equal(raw_frame(r, &h), VP_HELLO_OK);
}

/* ---- the tests ------------------------------------------------------------------------- */

static const char model_good[] =
    "# HELP vantage_x_total A counter with \\\\ and \\n in its help.\n"
    "# TYPE vantage_x_total counter\n"
    "vantage_x_total{type=\"a\\\"b\\\\c\\nd\",code=\"X\"} 3\n"
    "vantage_x_total{code=\"Y\",type=\"e\"} 0\n"
    "# TYPE vantage_g gauge\n"
    "# HELP vantage_g A gauge.\n"
    "vantage_g -1.5e-3\n"
    "# HELP vantage_h_seconds A histogram.\n"
    "# TYPE vantage_h_seconds histogram\n"
    "vantage_h_seconds_bucket{le=\"1e-06\"} 1\n"
    "vantage_h_seconds_bucket{le=\"0.5\"} 1\n"
    "vantage_h_seconds_bucket{le=\"+Inf\"} 4\n"
    "vantage_h_seconds_sum 7.25\n"
    "vantage_h_seconds_count 4\n";

/* The model itself: a text written by hand per the format passes; each
 * way of breaking it is refused (so a pass below means something). */
static void test_metrics_model(void **state)
{
    (void)state;
    expo e;
    assert_true(expo_read(model_good, sizeof model_good - 1, &e));
    assert_true(xv(&e, "vantage_x_total", "type", "a\"b\\c\nd", "code", "X") == 3);
    assert_true(xv(&e, "vantage_g", NULL, NULL, NULL, NULL) == -1.5e-3);
    assert_int_equal(e.nf, 3);
    expo_free(&e);
    assert_false(expo_read("vantage_g 1", 11, &e)); /* no final line feed */
    expo_free(&e);
}

/* One line of the good text replaced (or one added): a row is what
 * breaks, the line, what replaces it, and whether the model accepts it
 * (the control only). */
typedef struct model_case {
    const char *name, *from, *to;
    bool accepted;
} model_case;

static const model_case model_cases[] = {
    {"a timestamp", "vantage_g -1.5e-3\n", "vantage_g -1.5e-3 1700000000\n", false},
    {"two spaces before the value", "vantage_g -1.5e-3\n", "vantage_g  1\n", false},
    {"a word for the value", "vantage_g -1.5e-3\n", "vantage_g one\n", false},
    {"empty labels, no value", "vantage_g -1.5e-3\n", "vantage_g{} \n", false},
    {"unterminated label value", "vantage_g -1.5e-3\n", "vantage_g{a=\"b} 1\n", false},
    {"bad escape in a label value", "vantage_g -1.5e-3\n", "vantage_g{a=\"\\t\"} 1\n", false},
    {"a label twice", "vantage_g -1.5e-3\n", "vantage_g{a=\"1\",a=\"2\"} 1\n", false},
    {"reserved label name", "vantage_g -1.5e-3\n", "vantage_g{__a=\"1\"} 1\n", false},
    {"label name starting with a digit", "vantage_g -1.5e-3\n", "vantage_g{1a=\"1\"} 1\n", false},
    {"CR before the line feed", "vantage_g -1.5e-3\n", "vantage_g -1.5e-3\r\n", false},
    {"an empty line", "vantage_g -1.5e-3\n", "vantage_g 1\n\n", false},
    {"a series twice", "vantage_g -1.5e-3\n", "vantage_g 1\nvantage_g 2\n", false},
    {"a series with no TYPE", "vantage_g -1.5e-3\n", "vantage_g 1\nvantage_y 2\n", false},
    {"a comment other than HELP or TYPE", "vantage_g -1.5e-3\n", "vantage_g 1\n# a comment\n", false},
    {"TYPE after samples", "vantage_g -1.5e-3\n", "vantage_g 1\n# TYPE vantage_g gauge\n", false},
    {"counter below 0", "vantage_x_total{code=\"Y\",type=\"e\"} 0\n", "vantage_x_total{code=\"Y\",type=\"e\"} -1\n", false},
    {"the control: a zero counter sample removed", "vantage_x_total{code=\"Y\",type=\"e\"} 0\n", "", true},
    {"counter TYPE misspelt", "# TYPE vantage_x_total counter\n", "# TYPE vantage_x_total counte\n", false},
    {"counter TYPE of another name", "# TYPE vantage_x_total counter\n", "# TYPE vantage_x counter\n", false},
    {"HELP escape", "# HELP vantage_g A gauge.\n", "# HELP vantage_g A \\gauge.\n", false},
    {"no HELP", "# HELP vantage_g A gauge.\n", "", false},
    {"buckets not cumulative", "vantage_h_seconds_bucket{le=\"0.5\"} 1\n", "vantage_h_seconds_bucket{le=\"0.5\"} 0\n", false},
    {"le out of order", "vantage_h_seconds_bucket{le=\"0.5\"} 1\n", "vantage_h_seconds_bucket{le=\"1e-07\"} 1\n", false},
    {"+Inf bucket other than the count", "vantage_h_seconds_bucket{le=\"+Inf\"} 4\n", "vantage_h_seconds_bucket{le=\"+Inf\"} 5\n", false},
    {"no +Inf", "vantage_h_seconds_bucket{le=\"+Inf\"} 4\n", "", false},
    {"no _sum", "vantage_h_seconds_sum 7.25\n", "", false},
    {"a sample of another series inside the histogram", "vantage_h_seconds_sum 7.25\n", "vantage_h_seconds_sum 7.25\nvantage_h_seconds 1\n", false},
    {"histogram not contiguous", "vantage_h_seconds_count 4\n", "vantage_h_seconds_count 4\nvantage_x_total{type=\"z\"} 1\n", false},
};

static void test_metrics_model_refuses(void **state)
{
    const model_case *c = *state;
    char t[2048];
    const char *at = strstr(model_good, c->from);
    assert_non_null(at);
    size_t pre = (size_t)(at - model_good);
    snprintf(t, sizeof t, "%.*s%s%s", (int)pre, model_good, c->to, at + strlen(c->from));
    expo e;
    bool ok = expo_read(t, strlen(t), &e);
    if (ok != c->accepted) fail_msg("%s (%s)", ok ? "accepted" : "refused", e.err);
    expo_free(&e);
}

/* METRICS_REPLY on the wire: round trip, every prefix and one-byte
 * extension refused, each bad field with its code. */
static void test_metrics_message_codec(void **state)
{
    (void)state;
    static const char text[] = "# HELP vantage_g A gauge.\n# TYPE vantage_g gauge\nvantage_g 1\n";
    uint8_t buf[256];
    vp_writer w;
    vp_writer_init(&w, buf, sizeof buf);
    vp_enc_metrics_reply(&w, 42, &(vp_metrics_reply){.format = VP_METRICS_PROMETHEUS, .text_len = sizeof text - 1,
                                                     .text = (const uint8_t *)text});
    assert_false(w.overflow);
    assert_int_equal(w.len, vp_size_metrics_reply(sizeof text - 1));
    vp_header h;
    size_t fs;
    assert_int_equal(vp_frame_check(buf, w.len, 1u << 20, &h, &fs), VP_OK);
    assert_int_equal(h.type, VP_METRICS_REPLY);
    assert_int_equal(h.req, 42);
    assert_string_equal(vp_type_name(VP_METRICS), "metrics");
    assert_true(vp_type_known(VP_METRICS_REPLY));
    uint8_t *p = buf + VP_HEADER_SIZE;
    size_t len = h.len;
    vp_metrics_reply m;
    assert_int_equal(vp_dec_metrics_reply(p, len, &m), VP_OK);
    assert_int_equal(m.text_len, sizeof text - 1);
    assert_memory_equal(m.text, text, m.text_len);
    for (size_t n = 0; n < len; n++) assert_int_equal(vp_dec_metrics_reply(p, n, &m), VP_ERR_TRUNCATED);
    buf[w.len] = 'x';
    assert_int_equal(vp_dec_metrics_reply(p, len + 1, &m), VP_ERR_TRAILING);
    static const struct {
        size_t off;
        uint8_t v;
        int code;
    } bad[] = {{0, 1, VP_ERR_INVALID}, {1, 1, VP_ERR_INVALID}, {3, 1, VP_ERR_INVALID}, {8 + 5, 0, VP_ERR_INVALID},
               {4, 0xff, VP_ERR_TRUNCATED}, {4, 0, VP_ERR_TRAILING}};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        uint8_t c[256];
        memcpy(c, p, len);
        c[bad[i].off] = bad[i].v;
        assert_int_equal(vp_dec_metrics_reply(c, len, &m), bad[i].code);
    }
    /* an empty text is a reply too */
    vp_writer_init(&w, buf, sizeof buf);
    vp_enc_metrics_reply(&w, 1, &(vp_metrics_reply){.format = VP_METRICS_PROMETHEUS});
    assert_int_equal(vp_dec_metrics_reply(buf + VP_HEADER_SIZE, w.len - VP_HEADER_SIZE, &m), VP_OK);
    assert_int_equal(m.text_len, 0);
}

/* Counts against what the test did: requests and latency samples per type,
 * bytes in and out to the byte, queries' entities, errors by code. */
static void test_metrics_counts(void **state)
{
    (void)state;
    daemon_proc d;
    int mport;
    daemon_with_metrics(&d, &mport, NULL);
    expo a, b;
    scrape(mport, &a);

    /* a raw client: HELLO then 25 PINGs of 0..24 bytes, every byte counted */
    enum { NPING = 25 };
    rawc r;
    raw_open(&r, &d);
    uint8_t buf[4096];
    vp_writer w;
    vp_writer_init(&w, buf, sizeof buf);
    vp_enc_hello(&w, 1, &(vp_hello){.magic = VP_MAGIC, .version = VP_VERSION, .role = VP_ROLE_VIEWER});
    raw_write(&r, buf, w.len);
    vp_header h;
    assert_int_equal(raw_frame(&r, &h), VP_HELLO_OK);
    for (int i = 0; i < NPING; i++) {
        uint8_t data[32] = {0};
        vp_writer_init(&w, buf, sizeof buf);
        vp_enc_ping(&w, VP_PING, 10 + (uint32_t)i, data, (uint32_t)i);
        raw_write(&r, buf, w.len);
    }
    for (int i = 0; i < NPING; i++) assert_int_equal(raw_frame(&r, &h), VP_PONG);
    scrape(mport, &b);
    assert_true(xget(&b, "vantage_requests_total", "type", "ping") - xget(&a, "vantage_requests_total", "type", "ping") ==
                NPING);
    assert_true(xget(&b, "vantage_requests_total", "type", "hello") -
                    xget(&a, "vantage_requests_total", "type", "hello") ==
                1);
    assert_true(xget(&b, "vantage_request_duration_seconds_count", "type", "ping") -
                    xv0(&a, "vantage_request_duration_seconds_count", "type", "ping", NULL, NULL) ==
                NPING);
    /* the scrapes are HTTP, not protocol bytes: the deltas are the raw client's */
    double in = xget(&b, "vantage_received_bytes_total", NULL, NULL) - xget(&a, "vantage_received_bytes_total", NULL, NULL);
    double out = xget(&b, "vantage_sent_bytes_total", NULL, NULL) - xget(&a, "vantage_sent_bytes_total", NULL, NULL);
    fprintf(stderr, "metrics: raw client sent %llu bytes, read %llu; the daemon counted %.0f in, %.0f out\n",
            (unsigned long long)r.sent, (unsigned long long)r.got, in, out);
    assert_true(in == (double)r.sent);
    assert_true(out == (double)r.got);
    expo_free(&a);
    expo_free(&b);

    /* queries: counted, their stages timed, their entities summed */
    vtc_client *ed = connect_role(&d, VP_ROLE_EDITOR, false);
    vtc_client *v = connect_role(&d, VP_ROLE_VIEWER, true);
    vp_entity e[300];
    rng rg = {test_seed() ^ 0x3E7};
    for (int i = 0; i < 300; i++) {
        double x = rng_range(&rg, -100, 100), y = rng_range(&rg, -10, 10), z = rng_range(&rg, -200, 200);
        e[i] = (vp_entity){.id = (uint64_t)i + 1, .aabb = {x - 1, y - 1, z - 1, x + 1, y + 1, z + 1}};
    }
    assert_int_equal(vtc_add(ed, e, 300, NULL, NULL), VP_OK);
    scrape(mport, &a);
    enum { NQ = 12 };
    double tested = 0, visible = 0;
    for (int i = 0; i < NQ; i++) {
        vp_view view;
        const double eye[3] = {0, 0, 0}, at[3] = {cos(i * 0.5), 0, sin(i * 0.5)};
        assert_true(vtc_view_perspective(&view, eye, at, NULL, 60, 640, 360, 0.1, 500));
        vp_vis_result res;
        assert_int_equal(vtc_query(v, &view, 1, i % 2 ? VP_Q_COUNT_ONLY : 0, 0, &res), VP_OK);
        tested += res.tested;
        visible += res.visible;
    }
    /* errors by type and code: a singular matrix, an oversized PING, an unknown type */
    vp_view bad = {.viewport_w = 64, .viewport_h = 64};
    vp_vis_result res;
    assert_int_equal(vtc_query(v, &bad, 1, 0, 0, &res), VP_ERR_MATRIX);
    {
        static uint8_t big[VP_HEADER_SIZE + 2000], data[2000];
        vp_writer_init(&w, big, sizeof big);
        vp_enc_ping(&w, VP_PING, vtc_next_req(v), data, sizeof data);
        assert_int_equal(vtc_send(v, big, w.len), VP_OK);
        const uint8_t *p;
        assert_int_equal(vtc_recv(v, &h, &p, -1), VP_OK);
        assert_int_equal(h.type, VP_ERROR);
        vp_writer_init(&w, buf, sizeof buf);
        vp_frame_begin(&w, 0x0777, vtc_next_req(v));
        vp_frame_end(&w);
        assert_int_equal(vtc_send(v, buf, w.len), VP_OK);
        assert_int_equal(vtc_recv(v, &h, &p, -1), VP_OK);
        assert_int_equal(h.type, VP_ERROR);
    }
    scrape(mport, &b);
    assert_true(xget(&b, "vantage_requests_total", "type", "vis_query") -
                    xget(&a, "vantage_requests_total", "type", "vis_query") ==
                NQ + 1);
    assert_true(xget(&b, "vantage_request_duration_seconds_count", "type", "vis_query") -
                    xv0(&a, "vantage_request_duration_seconds_count", "type", "vis_query", NULL, NULL) ==
                NQ + 1);
    /* the worker's own times: the NQ that were culled, not the refused one */
    assert_true(xget(&b, "vantage_query_seconds_count", NULL, NULL) - xget(&a, "vantage_query_seconds_count", NULL, NULL) ==
                NQ);
    static const char *const stages[] = {"decode", "cull", "occlusion_raster", "write"};
    for (int i = 0; i < 4; i++)
        assert_true(xget(&b, "vantage_query_stage_seconds_count", "stage", stages[i]) -
                        xget(&a, "vantage_query_stage_seconds_count", "stage", stages[i]) ==
                    NQ);
    static const char *const ent[] = {"tested", "sphere", "aabb", "area", "occlusion", "visible"};
    double prev = INFINITY;
    for (int i = 0; i < 6; i++) {
        double dlt = xget(&b, "vantage_query_entities_total", "stage", ent[i]) -
                     xget(&a, "vantage_query_entities_total", "stage", ent[i]);
        assert_true(dlt <= prev); /* each stage keeps at most what came in */
        prev = dlt;
        if (i == 0) assert_true(dlt == tested);
        if (i == 5) assert_true(dlt == visible);
    }
    assert_true(visible > 0);
    assert_true(xv0(&b, "vantage_request_errors_total", "type", "vis_query", "code", "MATRIX") -
                    xv0(&a, "vantage_request_errors_total", "type", "vis_query", "code", "MATRIX") ==
                1);
    assert_true(xv0(&b, "vantage_request_errors_total", "type", "ping", "code", "COUNT") == 1);
    assert_true(xv0(&b, "vantage_request_errors_total", "type", "other", "code", "TYPE") == 1);
    assert_true(xget(&b, "vantage_requests_total", "type", "other") == 1);
    assert_true(xget(&b, "vantage_worker_jobs", NULL, NULL) == 0);
    assert_true(xget(&b, "vantage_scene_entities", "kind", "static") == 300);
    expo_free(&a);
    expo_free(&b);

    /* the METRICS message: the same families as HTTP, and it is counted */
    const char *text;
    size_t tlen;
    assert_int_equal(vtc_metrics(v, &text, &tlen), VP_OK);
    expo pm, ph;
    expo_parse(text, tlen, &pm);
    scrape(mport, &ph);
    assert_int_equal(pm.nf, ph.nf);
    for (int i = 0; i < pm.nf; i++) {
        int j = fam_find(&ph, pm.f[i].name);
        assert_true(j >= 0);
        assert_string_equal(pm.f[i].type, ph.f[j].type);
    }
    assert_true(xget(&ph, "vantage_requests_total", "type", "metrics") == 1);
    expo_free(&pm);
    expo_free(&ph);
    close(r.fd);
    vtc_close(ed);
    daemon_close(&d, v);
}

/* Clients by role follow connects and disconnects; a connection that has
 * not said HELLO is in the handshake. */
static void test_metrics_clients(void **state)
{
    (void)state;
    daemon_proc d;
    int mport;
    daemon_with_metrics(&d, &mport, NULL);
    wait_value(mport, "vantage_clients", "role", "viewer", 0); /* daemon_start's own probe is gone */
    expo a;
    scrape(mport, &a);
    vtc_client *v = connect_role(&d, VP_ROLE_VIEWER, false);
    vtc_client *c = connect_role(&d, VP_ROLE_COMMANDER, true);
    vtc_client *e1 = connect_role(&d, VP_ROLE_EDITOR, false);
    vtc_client *e2 = connect_role(&d, VP_ROLE_EDITOR, true);
    rawc mute;
    raw_open(&mute, &d); /* says nothing */
    wait_value(mport, "vantage_clients", "role", "handshake", 1);
    expo b;
    scrape(mport, &b);
    assert_true(xget(&b, "vantage_clients", "role", "viewer") == 1);
    assert_true(xget(&b, "vantage_clients", "role", "commander") == 1);
    assert_true(xget(&b, "vantage_clients", "role", "editor") == 2);
    assert_true(xget(&b, "vantage_connections_accepted_total", NULL, NULL) -
                    xget(&a, "vantage_connections_accepted_total", NULL, NULL) ==
                5);
    vtc_close(c);
    wait_value(mport, "vantage_clients", "role", "commander", 0);
    vtc_close(e1);
    wait_value(mport, "vantage_clients", "role", "editor", 1);
    close(mute.fd);
    wait_value(mport, "vantage_clients", "role", "handshake", 0);
    expo z;
    scrape(mport, &z);
    assert_true(xget(&z, "vantage_disconnects_total", "reason", "peer") -
                    xget(&b, "vantage_disconnects_total", "reason", "peer") ==
                3);
    assert_true(xget(&z, "vantage_clients", "role", "viewer") == 1);
    vtc_close(v);
    vtc_close(e2);
    wait_value(mport, "vantage_clients", "role", "editor", 0);
    expo_free(&a);
    expo_free(&b);
    expo_free(&z);
    daemon_stop(&d);
}

/* Client buffers a burst grew are given back once unused, even by an idle
 * daemon: an editor sends 60,000 entities in one message (~3 MB in, 240 kB
 * of handles out), then nothing; the buffers gauge falls back to what two
 * resting connections hold, and the connection still works. */
static void test_metrics_buffers_shrink(void **state)
{
    (void)state;
    daemon_proc d;
    int mport;
    daemon_with_metrics(&d, &mport, NULL);
    vtc_client *ed = connect_role(&d, VP_ROLE_EDITOR, false);
    vtc_client *idle = connect_role(&d, VP_ROLE_VIEWER, false);
    enum { N = 60000 };
    vp_entity *e = calloc(N, sizeof *e);
    uint32_t *h = calloc(N, sizeof *h);
    for (uint32_t i = 0; i < N; i++)
        e[i] = (vp_entity){.id = i + 1, .sphere = {(double)(i % 300), 1, (double)(i / 300), 1}};
    assert_int_equal(vtc_add(ed, e, N, h, NULL), VP_OK);
    expo a;
    scrape(mport, &a);
    double burst = xget(&a, "vantage_client_buffer_bytes", NULL, NULL);
    /* quiet: the loop sleeps but for the sweeps the big buffers ask for */
    usleep(1000000);
    expo b;
    scrape(mport, &b);
    double rest = xget(&b, "vantage_client_buffer_bytes", NULL, NULL);
    fprintf(stderr, "metrics: client buffers %.0f kB after a 60,000-entity add, %.0f kB after 1 s idle\n",
            burst / 1024, rest / 1024);
    assert_true(burst > 3e6);
    assert_true(rest <= 2 * (64 + 64) * 1024);
    /* and it still takes a burst */
    for (uint32_t i = 0; i < N; i++) e[i].id += N;
    assert_int_equal(vtc_add(ed, e, N, h, NULL), VP_OK);
    vp_stats_reply st;
    assert_int_equal(vtc_stats(idle, &st), VP_OK);
    assert_int_equal(st.entities, 2 * N);
    free(e);
    free(h);
    expo_free(&a);
    expo_free(&b);
    vtc_close(ed);
    daemon_close(&d, idle);
}

/* The daemon's peak resident memory (VmHWM), bytes. */
static double daemon_peak_rss(const daemon_proc *d)
{
    char path[64], line[256];
    snprintf(path, sizeof path, "/proc/%d/status", (int)d->pid);
    FILE *f = fopen(path, "r");
    assert_non_null(f);
    double kb = -1;
    while (fgets(line, sizeof line, f))
        if (sscanf(line, "VmHWM: %lf kB", &kb) == 1) break;
    fclose(f);
    assert_true(kb > 0);
    return kb * 1024;
}

/* --out-limit-total: four viewers pipeline raw 800x400 RENDERs (6.4 MB
 * each, 51 MB a viewer: each alone under --out-limit) and read nothing.
 * Together they would pile up 205 MB; with a 64 MiB cap the largest
 * backlogs are dropped until the buffers fit, every viewer left gets all
 * its frames, a viewer with one frame waiting (the smallest backlog) is
 * never the one dropped, a client that reads is served throughout, and
 * the daemon's peak memory grows by about the cap, not by what was asked. */
static void test_metrics_output_limit_total(void **state)
{
    (void)state;
    enum { NV = 4, K = 8, W = 800, H = 400 };
    const double cap = 64.0 * 1024 * 1024, frame = (double)W * H * 20;
    daemon_proc d;
    int mport;
    daemon_with_metrics(&d, &mport, (const char *const[]){"--out-limit-total", "67108864", NULL});
    vtc_client *ok = connect_role(&d, VP_ROLE_VIEWER, false);
    vp_render m = {.format = VP_FRAME_RAW};
    assert_true(vtc_view_perspective(&m.view, (double[]){0, 0, 0}, (double[]){0, 0, -10}, NULL, 60, W, H, 0.1, 100));
    /* the baseline: after frames of this size (the renderers' own buffers) */
    vp_frame f;
    for (int i = 0; i < 4; i++) assert_int_equal(vtc_render(ok, &m, &f), VP_OK);
    double base = daemon_peak_rss(&d);
    /* a raw frame whose buffer alone would pass the cap is refused up front */
    vp_render big = m;
    big.view.viewport_w = big.view.viewport_h = 1400; /* 39 MB: over half of 64 MiB */
    assert_int_equal(vtc_render(ok, &big, &f), VP_ERR_LIMIT);
    assert_non_null(strstr(vtc_last_error(ok)->msg, "--out-limit-total"));
    static rawc r[NV + 1]; /* r[NV]: a viewer with one frame waiting, the smallest backlog */
    uint8_t buf[1024];
    vp_writer w;
    for (int i = 0; i <= NV; i++) {
        raw_open(&r[i], &d);
        vp_writer_init(&w, buf, sizeof buf);
        vp_enc_hello(&w, 1, &(vp_hello){.magic = VP_MAGIC, .version = VP_VERSION, .role = VP_ROLE_VIEWER});
        raw_write(&r[i], buf, w.len);
        vp_header h;
        assert_int_equal(raw_frame(&r[i], &h), VP_HELLO_OK);
    }
    vp_writer_init(&w, buf, sizeof buf);
    vp_enc_render(&w, 100, &m);
    raw_write(&r[NV], buf, w.len);
    for (int i = 0;; i++) { /* drawn and queued (the kernel takes a few hundred kB of it) */
        expo e;
        scrape(mport, &e);
        double q = xget(&e, "vantage_output_buffered_bytes", NULL, NULL);
        expo_free(&e);
        if (q > frame / 2) break;
        assert_true(i < 2000);
        usleep(10000);
    }
    for (int k = 0; k < K; k++)
        for (int i = 0; i < NV; i++) {
            vp_writer_init(&w, buf, sizeof buf);
            vp_enc_render(&w, (uint32_t)(100 + k), &m);
            raw_write(&r[i], buf, w.len);
        }
    /* the reading client is answered while the others pile up */
    for (int i = 0; i < 20; i++) assert_int_equal(vtc_ping(ok), VP_OK);
    /* at least one viewer is dropped for the total (the buffers could not
       otherwise hold 205 MB under 64 MiB) */
    double dropped = 0;
    for (int i = 0; i < 2000 && dropped < 1; i++) {
        expo e;
        scrape(mport, &e);
        dropped = xget(&e, "vantage_disconnects_total", "reason", "output_limit_total");
        expo_free(&e);
        if (dropped < 1) usleep(10000);
    }
    assert_true(dropped >= 1);
    /* every viewer reads now: a survivor gets its K frames in order, a
       dropped one a prefix of them and then the hang-up */
    int survivors = 0, got_total = 0;
    for (int i = NV; i >= 0; i--) {
        int got = 0, t;
        vp_header h;
        while ((t = raw_frame(&r[i], &h)) >= 0) {
            assert_int_equal(t, VP_FRAME);
            assert_int_equal(h.req, (uint32_t)(100 + got));
            got++;
        }
        if (i == NV) { /* never the largest backlog: kept, with its frame */
            assert_int_equal(got, 1);
            continue;
        }
        survivors += got == K;
        got_total += got;
        close(r[i].fd);
    }
    expo e;
    scrape(mport, &e);
    double drops = xget(&e, "vantage_disconnects_total", "reason", "output_limit_total");
    double held = xget(&e, "vantage_client_output_buffer_bytes", NULL, NULL);
    assert_true(xget(&e, "vantage_client_output_buffer_limit_bytes", NULL, NULL) == cap);
    expo_free(&e);
    double peak = daemon_peak_rss(&d) - base;
    print_message("out-limit-total 64 MiB: %d of %d viewers dropped, %d survived with all %d frames (%d frames "
                  "delivered); daemon peak memory +%.0f MB for %.0f MB asked\n",
                  (int)drops, NV, survivors, K, got_total, peak / 1e6, NV * K * frame / 1e6);
    assert_int_equal((int)drops + survivors, NV);
    assert_true(held <= cap);
#ifndef __SANITIZE_ADDRESS__ /* ASan's quarantine keeps freed buffers resident */
    /* the cap, plus replies in flight (two workers' frames and one over
       the cap before the drop) and the allocator's slack; without the cap
       it is +230 MB */
    assert_true(peak < cap + 8 * frame);
#endif
    assert_int_equal(vtc_ping(ok), VP_OK);
    daemon_close(&d, ok);
}

/* A viewer that stops reading its raw frames while the scene changes:
 * frames are dropped (latest-frame-wins), and every frame counted as sent
 * is one it gets when it reads again. */
static void test_metrics_dropped_frames(void **state)
{
    (void)state;
    daemon_proc d;
    int mport;
    daemon_with_metrics(&d, &mport, NULL);
    vtc_client *ed = connect_role(&d, VP_ROLE_EDITOR, false);
    vp_entity e[50];
    for (int i = 0; i < 50; i++) {
        double x = -25 + i, z = -30;
        e[i] = (vp_entity){.id = (uint64_t)i + 1, .aabb = {x - 0.4, -1, z - 0.4, x + 0.4, 1, z + 0.4}};
    }
    assert_int_equal(vtc_add(ed, e, 50, NULL, NULL), VP_OK);
    rawc r;
    raw_open(&r, &d);
    uint8_t buf[512];
    vp_writer w;
    vp_writer_init(&w, buf, sizeof buf);
    vp_enc_hello(&w, 1, &(vp_hello){.magic = VP_MAGIC, .version = VP_VERSION, .role = VP_ROLE_VIEWER});
    vp_frame_sub sub = {.r = {.format = VP_FRAME_RAW}, .max_fps = VP_FRAME_SUB_MAX_FPS};
    const double eye[3] = {0, 0, 0}, at[3] = {0, 0, -10};
    assert_true(vtc_view_perspective(&sub.r.view, eye, at, NULL, 70, 480, 270, 0.1, 200)); /* 2.6 MB a frame */
    vp_enc_frame_sub(&w, 9, &sub);
    raw_write(&r, buf, w.len);
    vp_header h;
    assert_int_equal(raw_frame(&r, &h), VP_HELLO_OK);
    assert_int_equal(raw_frame(&r, &h), VP_ACK);
    /* it reads nothing more while the scene changes 10 times, 25 ms apart,
       once its first frame has been drawn and queued */
    wait_value(mport, "vantage_frames_sent_total", NULL, NULL, 1);
    for (int i = 0; i < 10; i++) {
        e[i].aabb[1] += 0.5, e[i].aabb[4] += 0.5;
        assert_int_equal(vtc_update(ed, &e[i], 1, NULL), VP_OK);
        usleep(25000);
    }
    expo a;
    scrape(mport, &a);
    double dropped = xget(&a, "vantage_frames_dropped_total", NULL, NULL);
    fprintf(stderr, "metrics: stalled viewer: %.0f frames sent, %.0f dropped during 10 edits\n",
            xget(&a, "vantage_frames_sent_total", NULL, NULL), dropped);
    assert_true(dropped >= 5 && dropped <= 10);
    assert_true(xget(&a, "vantage_frame_streams", NULL, NULL) == 1);
    assert_true(xget(&a, "vantage_output_buffered_bytes", NULL, NULL) > 0);
    /* now it reads: every frame sent arrives, then quiet */
    int frames = 0;
    for (;;) {
        struct pollfd p = {.fd = r.fd, .events = POLLIN};
        if (!r.have && poll(&p, 1, 600) == 0) break;
        int t = raw_frame(&r, &h);
        assert_int_equal(t, VP_FRAME);
        frames++;
    }
    expo b;
    scrape(mport, &b);
    fprintf(stderr, "metrics: the viewer read %d frames; sent %.0f, dropped %.0f, discarded %.0f\n", frames,
            xget(&b, "vantage_frames_sent_total", NULL, NULL), xget(&b, "vantage_frames_dropped_total", NULL, NULL),
            xget(&b, "vantage_frames_discarded_total", NULL, NULL));
    assert_true(xget(&b, "vantage_frames_sent_total", NULL, NULL) == frames);
    assert_true(frames >= 2);
    assert_true(xget(&b, "vantage_frame_render_seconds_count", NULL, NULL) >= frames);
    assert_true(xget(&b, "vantage_request_duration_seconds_count", "type", "frame_subscribe") == 1);
    expo_free(&a);
    expo_free(&b);
    close(r.fd);
    daemon_close(&d, ed);
}

/* A JPEG frame's pixels (RGB8), checked to be W x H; malloc'ed. */
static uint8_t *frame_rgb(const vp_frame *f, uint32_t W, uint32_t H)
{
    uint8_t *rgb = NULL;
    uint32_t w = 0, h = 0;
    char err[256];
    assert_int_equal(f->format, VP_FRAME_JPEG);
    if (vt_jpeg_decode(f->data, f->data_len, &rgb, &w, &h, err, sizeof err)) fail_msg("a frame's JPEG: %s", err);
    assert_int_equal(w, W);
    assert_int_equal(h, H);
    return rgb;
}

/* The mean absolute difference of two RGB8 pictures of n pixels. */
static double rgb_mae(const uint8_t *a, const uint8_t *b, size_t n)
{
    double s = 0;
    for (size_t i = 0; i < 3 * n; i++) s += abs((int)a[i] - (int)b[i]);
    return s / (3.0 * (double)n);
}

/* Dynamic resolution (VP_RENDER_MOTION, --motion-ms): a stream re-aimed
 * every 15 ms is drawn smaller (the metric counts it) and scaled up to its
 * size; once the view rests, a full-size frame of the last view follows,
 * the same picture RENDER draws of that view; a stream that does not ask,
 * or a daemon run with --motion-ms 0, draws every frame full size. */
static void test_metrics_motion_frames(void **state)
{
    (void)state;
    enum { W = 320, H = 180, MOVES = 12 };
    for (int run = 0; run < 2; run++) {
        daemon_proc d;
        int mport;
        const char *more[] = {"--motion-ms", run ? "0" : "1", NULL}; /* 1 ms: always smaller, down to 1/4 */
        daemon_with_metrics(&d, &mport, more);
        vtc_client *ed = connect_role(&d, VP_ROLE_EDITOR, false);
        vp_entity e[60];
        for (int i = 0; i < 60; i++) { /* boxes of 0.8 m, 1 m apart: hard edges a smaller frame blurs */
            double x = -30 + i, z = -20 - (i % 7) * 3;
            e[i] = (vp_entity){.id = (uint64_t)i + 1, .aabb = {x - 0.4, -1 - i % 3, z - 0.4, x + 0.4, 1 + i % 5, z + 0.4}};
        }
        assert_int_equal(vtc_add(ed, e, 60, NULL, NULL), VP_OK);
        /* a fixed exposure: a stream's eye adaptation would otherwise make
           its frames differ from RENDER's */
        vp_env env;
        assert_int_equal(vtc_env_get(ed, &env), VP_OK);
        env.exposure_mode = VP_EXPOSURE_FIXED;
        assert_int_equal(vtc_env_set(ed, &env, NULL), VP_OK);
        vtc_client *v = connect_role(&d, VP_ROLE_VIEWER, false);
        for (int ask = 1; ask >= 0; ask--) {
            vp_frame_sub sub = {.r = {.format = VP_FRAME_JPEG, .quality = 95, .flags = ask ? VP_RENDER_MOTION : 0},
                                .max_fps = VP_FRAME_SUB_MAX_FPS};
            const double eye[3] = {0, 2, 0};
            double at[3] = {-4, 0, -10};
            assert_true(vtc_view_perspective(&sub.r.view, eye, at, NULL, 70, W, H, 0.1, 200));
            assert_int_equal(vtc_frame_subscribe(v, &sub), VP_OK);
            vp_frame f;
            assert_int_equal(vtc_wait_frame(v, &f, 10000), VP_OK); /* the first: the view has not moved */
            expo a;
            scrape(mport, &a);
            const double scaled0 = xget(&a, "vantage_frames_scaled_total", NULL, NULL);
            expo_free(&a);
            assert_true(scaled0 == 0 || !ask);
            /* the camera turns: a re-aim every 15 ms */
            for (int k = 1; k <= MOVES; k++) {
                at[0] = -4 + 0.5 * k;
                sub.r.view = (vp_view){0};
                assert_true(vtc_view_perspective(&sub.r.view, eye, at, NULL, 70, W, H, 0.1, 200));
                sub.view_seq = (uint16_t)k;
                assert_int_equal(vtc_frame_subscribe(v, &sub), VP_OK);
                usleep(15000);
            }
            /* frames until quiet for 600 ms: the last is the last view's */
            int got = 0;
            uint8_t *last = NULL, *moving = NULL; /* the last frame; one of the last view before it */
            uint16_t last_seq = 0;
            while (vtc_wait_frame(v, &f, 600) == VP_OK) {
                assert_int_equal(f.width, W); /* every frame at the stream's size */
                assert_int_equal(f.height, H);
                if (last && !moving && f.view_seq == MOVES && last_seq == MOVES) moving = last;
                else free(last);
                last = frame_rgb(&f, W, H);
                last_seq = f.view_seq;
                got++;
            }
            assert_true(got >= 1);
            assert_int_equal(f.view_seq, MOVES);
            scrape(mport, &a);
            const double scaled = xget(&a, "vantage_frames_scaled_total", NULL, NULL) - scaled0;
            const double msum = xget(&a, "vantage_frame_motion_scale_sum", NULL, NULL),
                         mcount = xget(&a, "vantage_frame_motion_scale_count", NULL, NULL);
            expo_free(&a);
            /* the moving frames' scales: each within 1/4..1, the smaller ones among them */
            assert_true(mcount >= scaled && msum <= mcount && msum >= 0.25 * mcount);
            if (scaled) assert_true(msum < mcount);
            fprintf(stderr, "motion: --motion-ms %s, %s: %d frames after %d moves, %.0f drawn smaller\n",
                    run ? "0" : "1", ask ? "asked" : "not asked", got, MOVES, scaled);
            if (!run && ask) assert_true(scaled >= 1);
            else assert_true(scaled == 0);
            /* the last frame is full size: RENDER's picture of that view */
            vp_render rm = sub.r;
            rm.flags = 0;
            vp_frame rf;
            assert_int_equal(vtc_render(ed, &rm, &rf), VP_OK);
            uint8_t *ref = frame_rgb(&rf, W, H);
            double mae = rgb_mae(last, ref, (size_t)W * H);
            fprintf(stderr, "motion: the resting frame against RENDER: mean abs error %.3f\n", mae);
            assert_true(mae < 0.5);
            /* a frame of the last view drawn while it moved (before the
               resting one) is not the full-size picture: drawn smaller,
               scaled up, it is softer */
            if (moving) {
                double to_full = rgb_mae(moving, ref, (size_t)W * H);
                fprintf(stderr, "motion: a moving frame of that view against full size: mean abs error %.3f\n", to_full);
                assert_true(!run && ask);
                assert_true(to_full > 0.5);
            }
            free(ref);
            free(last);
            free(moving);
        }
        vtc_close(v);
        daemon_close(&d, ed);
    }
}

/* The endpoint's answers to bad requests; the connection limit; a slow-
 * loris request closed at its deadline while protocol clients are served. */
static void test_metrics_http_bad_input(void **state)
{
    (void)state;
    daemon_proc d;
    int mport;
    const char *more[] = {"--hello-timeout", "500", NULL};
    daemon_with_metrics(&d, &mport, more);
    static const struct {
        const char *req;
        int status;
    } cases[] = {
        {"GET /nope HTTP/1.1\r\nHost: x\r\n\r\n", 404},
        {"GET / HTTP/1.0\r\n\r\n", 404},
        {"POST /metrics HTTP/1.1\r\nHost: x\r\nContent-Length: 3\r\n\r\nabc", 405},
        {"DELETE /metrics HTTP/1.1\r\nHost: x\r\n\r\n", 405},
        {"GET /metrics HTTP/1.1\r\n\r\n", 400},              /* HTTP/1.1 without Host */
        {"GET /metrics HTTP/2.0\r\nHost: x\r\n\r\n", 505},
        {"GET /metrics\r\n\r\n", 400},                       /* HTTP/0.9 */
        {"GET  /metrics HTTP/1.1\r\nHost: x\r\n\r\n", 400},  /* two spaces */
        {"GET /metrics HTTP/1.1\r\nHost : x\r\n\r\n", 400},  /* space before the colon */
        {"GET /metrics HTTP/1.1\r\nHost: x\r\n folded\r\n\r\n", 400},
        {"GET /metrics HTTP/1.1\r\nHost: x\rY: z\r\n\r\n", 400}, /* a bare CR */
        {"\x16\x03\x01\x02\x05\x01\x07\x01\xfc\x03\x03\r\n\r\n", 400}, /* TLS, say */
        {"GET /metrics?name=x HTTP/1.1\r\nHost: x\r\n\r\n", 200},
        {"\r\nGET /metrics HTTP/1.0\n\n", 200},              /* a blank line first; bare LFs */
    };
    int want[600] = {0};
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        hresp r;
        http_send(mport, cases[i].req, strlen(cases[i].req), &r);
        if (r.status != cases[i].status) fail_msg("case %zu: %d, want %d (%s)", i, r.status, cases[i].status, r.body);
        assert_int_equal(content_length(&r), r.body_len);
        if (r.status == 405) assert_non_null(strstr(r.head, "\r\nAllow: GET, HEAD"));
        want[r.status]++;
        http_free(&r);
    }
    /* a NUL inside the request line */
    {
        static const char nul[] = "GET /met\0rics HTTP/1.1\r\nHost: x\r\n\r\n";
        hresp r;
        http_send(mport, nul, sizeof nul - 1, &r);
        assert_int_equal(r.status, 400);
        want[400]++;
        http_free(&r);
    }
    /* a client that shuts its sending side after the request still gets
       the whole answer */
    {
        int fd = tcp_connect(mport);
        const char *req = "GET /metrics HTTP/1.0\r\n\r\n";
        assert_int_equal(write(fd, req, strlen(req)), (ssize_t)strlen(req));
        assert_int_equal(shutdown(fd, SHUT_WR), 0);
        hresp r;
        http_read(fd, &r);
        assert_int_equal(r.status, 200);
        assert_int_equal(content_length(&r), r.body_len);
        want[200]++;
        http_free(&r);
    }
    /* HEAD: the head of a 200 with its length, no body */
    {
        hresp r;
        const char *req = "HEAD /metrics HTTP/1.1\r\nHost: x\r\n\r\n";
        http_send(mport, req, strlen(req), &r);
        assert_int_equal(r.status, 200);
        assert_int_equal(r.body_len, 0);
        assert_true(content_length(&r) > 1000);
        want[200]++;
        http_free(&r);
    }
    /* a head over 8 KiB: 431 (the rest of it read and dropped, so the
       answer arrives whole) */
    {
        size_t n = 20000;
        char *big = malloc(n + 64);
        int k = snprintf(big, n, "GET /metrics HTTP/1.1\r\nHost: x\r\nX-Pad: ");
        memset(big + k, 'a', n - (size_t)k - 4);
        memcpy(big + n - 4, "\r\n\r\n", 4);
        hresp r;
        http_send(mport, big, n, &r);
        assert_int_equal(r.status, 431);
        want[431]++;
        http_free(&r);
        free(big);
    }
    /* the connection limit: 16 answered and kept open (the daemon waits
       up to 2 s for the client's close), the 17th gets 503 at once; first
       the daemon must have seen the earlier ones close */
    want[200] += wait_value(mport, "vantage_metrics_http_connections", NULL, NULL, 1);
    {
        int fds[HTTP_MAX_CONNS];
        for (int i = 0; i < HTTP_MAX_CONNS; i++) {
            fds[i] = tcp_connect(mport);
            const char *req = "GET /metrics HTTP/1.0\r\n\r\n";
            assert_int_equal(write(fds[i], req, strlen(req)), (ssize_t)strlen(req));
        }
        for (int i = 0; i < HTTP_MAX_CONNS; i++) { /* answered, and the daemon's side shut */
            char junk[65536];
            ssize_t n;
            while ((n = read(fds[i], junk, sizeof junk)) > 0) {
            }
            assert_int_equal(n, 0);
            want[200]++;
        }
        int extra = tcp_connect(mport);
        hresp r;
        http_read(extra, &r);
        assert_int_equal(r.status, 503);
        want[503]++;
        http_free(&r);
        for (int i = 0; i < HTTP_MAX_CONNS; i++) close(fds[i]);
    }
    /* slow-loris: half a request line, then nothing; protocol clients are
       served meanwhile; it gets 408 and is closed at its deadline (500 ms
       after the accept, swept every 250 ms) */
    {
        vtc_client *v = connect_role(&d, VP_ROLE_VIEWER, false);
        int slow = tcp_connect(mport);
        assert_int_equal(write(slow, "GET /metr", 9), 9);
        struct timespec t0, t1;
        clock_gettime(CLOCK_MONOTONIC, &t0);
        double worst = 0;
        bool closed = false;
        while (!closed) {
            struct timespec a, b;
            clock_gettime(CLOCK_MONOTONIC, &a);
            assert_int_equal(vtc_ping(v), VP_OK);
            clock_gettime(CLOCK_MONOTONIC, &b);
            double ms = (b.tv_sec - a.tv_sec) * 1e3 + (b.tv_nsec - a.tv_nsec) / 1e6;
            if (ms > worst) worst = ms;
            struct pollfd p = {.fd = slow, .events = POLLIN};
            closed = poll(&p, 1, 10) == 1;
            double since = (b.tv_sec - t0.tv_sec) * 1e3 + (b.tv_nsec - t0.tv_nsec) / 1e6;
            if (since > 5000) fail_msg("the slow request was not closed in 5 s");
        }
        hresp r;
        http_read(slow, &r);
        clock_gettime(CLOCK_MONOTONIC, &t1);
        double ms = (t1.tv_sec - t0.tv_sec) * 1e3 + (t1.tv_nsec - t0.tv_nsec) / 1e6;
        fprintf(stderr, "metrics: slow-loris request closed after %.0f ms (deadline 500); pings meanwhile at most %.1f ms\n",
                ms, worst);
        assert_int_equal(r.status, 408);
        want[408]++;
        assert_true(ms >= 400 && ms < 2500);
        assert_true(worst < 250);
        http_free(&r);
        vtc_close(v);
    }
    /* every answer counted by its code (this scrape's own 200 not yet) */
    expo e;
    scrape(mport, &e);
    static const int codes[] = {200, 400, 401, 404, 405, 408, 431, 500, 503, 505};
    for (size_t i = 0; i < sizeof codes / sizeof codes[0]; i++) {
        char c[8];
        snprintf(c, sizeof c, "%d", codes[i]);
        double got = xget(&e, "vantage_metrics_http_responses_total", "code", c);
        if (got != want[codes[i]]) fail_msg("responses{code=%s}: %g, want %d", c, got, want[codes[i]]);
    }
    /* none of it touched the protocol's counters */
    assert_true(xget(&e, "vantage_requests_total", "type", "other") == 0);
    expo_free(&e);
    daemon_stop(&d);
}

#define VIEW_TOK "metrics-viewer-token-0123456789"
#define EDIT_TOK "metrics-editor-token-0123456789"

/* Who may read: the protocol's rule. A non-loopback address without tokens
 * does not start; with tokens a scraper needs a viewer's token. */
static void test_metrics_access(void **state)
{
    (void)state;
    char out[2048], args[256];
    snprintf(args, sizeof args, "--port %d --metrics 0.0.0.0:%d", free_port(), free_port());
    assert_int_equal(daemon_run_to_exit(args, out, sizeof out), 2);
    assert_non_null(strstr(out, "--insecure"));
    static const char *const bad[] = {"--metrics 0", "--metrics 70000", "--metrics :9100", "--metrics x.y.z:9100",
                                      "--metrics 127.0.0.1:"};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        snprintf(args, sizeof args, "--port %d %s", free_port(), bad[i]);
        assert_int_equal(daemon_run_to_exit(args, out, sizeof out), 2);
        assert_non_null(strstr(out, "bad value for --metrics"));
    }
    char path[64];
    snprintf(path, sizeof path, "/tmp/vantage-mtokens-%d-XXXXXX", (int)getpid());
    int fd = mkstemp(path);
    const char *text = "viewer " VIEW_TOK "\neditor " EDIT_TOK "\n";
    assert_int_equal(write(fd, text, strlen(text)), (ssize_t)strlen(text));
    close(fd);
    assert_int_equal(chmod(path, 0600), 0);
    daemon_proc d;
    int mport;
    const char *more[] = {"--tokens", path, NULL};
    daemon_with_metrics(&d, &mport, more);
    static const struct {
        const char *auth;
        int status;
    } cases[] = {
        {"", 401},
        {"Authorization: Bearer not-a-token-of-this-daemon\r\n", 401},
        {"Authorization: Basic " VIEW_TOK "\r\n", 401},
        {"Authorization: Bearer " VIEW_TOK "\r\n", 200},
        {"authorization: bearer   " EDIT_TOK "  \r\n", 200},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        char req[256];
        int n = snprintf(req, sizeof req, "GET /metrics HTTP/1.1\r\nHost: x\r\n%s\r\n", cases[i].auth);
        hresp r;
        http_send(mport, req, (size_t)n, &r);
        if (r.status != cases[i].status) fail_msg("auth case %zu: %d, want %d", i, r.status, cases[i].status);
        if (r.status == 401) {
            assert_non_null(strstr(r.head, "\r\nWWW-Authenticate: Bearer"));
            assert_null(strstr(r.body, "vantage_")); /* nothing of the metrics */
        } else {
            expo e;
            expo_parse(r.body, r.body_len, &e);
            assert_true(xget(&e, "vantage_auth_failures_total", NULL, NULL) >= 1); /* daemon_start's probe */
            expo_free(&e);
        }
        http_free(&r);
    }
    /* over the protocol, a viewer's token is enough */
    vtc_client *c = NULL;
    char err[256];
    assert_int_equal(vtc_connect(&(vtc_connect_opts){.port = d.port, .token = VIEW_TOK}, &c, err, sizeof err), VP_OK);
    const char *t;
    size_t tl;
    assert_int_equal(vtc_metrics(c, &t, &tl), VP_OK);
    expo e;
    expo_parse(t, tl, &e);
    assert_true(xget(&e, "vantage_clients", "role", "viewer") == 1);
    expo_free(&e);
    vtc_close(c);
    daemon_stop(&d);
    unlink(path);
}


/* Output as reply blocks (issue 25): a worker's reply is linked into the
 * connection's queue by pointer, never copied, except a small one, which
 * is copied into the queue's tail block. The model: K raw frames of W x H
 * (vp_size_frame(W * H * 20) bytes each) are linked, every byte of them,
 * and none copied; a count-only query's VIS_RESULT (vp_size_vis_result(0)
 * bytes) is copied; the frames arrive whole. */
static void test_metrics_output_frames_linked_not_copied(void **state)
{
    (void)state;
    enum { W = 320, H = 200, K = 3 };
    vp_render m = {.format = VP_FRAME_RAW};
    assert_true(vtc_view_perspective(&m.view, (double[]){0, 0, 0}, (double[]){0, 0, -10}, NULL, 60, W, H, 0.1, 100));
    daemon_proc d;
    int mport;
    daemon_with_metrics(&d, &mport, NULL);
    vtc_client *v = connect_role(&d, VP_ROLE_VIEWER, false);
    expo a, b, c;
    scrape(mport, &a);
    for (int k = 0; k < K; k++) {
        vp_frame f;
        assert_int_equal(vtc_render(v, &m, &f), VP_OK);
        assert_int_equal(f.width, W);
        assert_int_equal(f.data_len, (uint32_t)W * H * 20);
    }
    scrape(mport, &b);
    double frame = (double)vp_size_frame(W * H * 20);
    double linked = xget(&b, "vantage_output_reply_bytes_total", "how", "linked") -
                    xget(&a, "vantage_output_reply_bytes_total", "how", "linked");
    double copied = xget(&b, "vantage_output_reply_bytes_total", "how", "copied") -
                    xget(&a, "vantage_output_reply_bytes_total", "how", "copied");
    fprintf(stderr, "metrics: %d raw %ux%u frames: %.0f bytes linked, %.0f copied\n", K, W, H, linked, copied);
    assert_true(linked == K * frame);
    assert_true(copied == 0);
    vp_vis_result q;
    assert_int_equal(vtc_query(v, &m.view, 1, VP_Q_COUNT_ONLY, 0, &q), VP_OK);
    scrape(mport, &c);
    assert_true(xget(&c, "vantage_output_reply_bytes_total", "how", "copied") -
                    xget(&b, "vantage_output_reply_bytes_total", "how", "copied") ==
                (double)vp_size_vis_result(0));
    assert_true(xget(&c, "vantage_output_reply_bytes_total", "how", "linked") ==
                xget(&b, "vantage_output_reply_bytes_total", "how", "linked"));
    expo_free(&a);
    expo_free(&b);
    expo_free(&c);
    vtc_close(v);
    daemon_stop(&d);
}

/* Replies larger than a block (16 KiB): ENTITY_LIST pages of up to 1,000
 * records (104 kB), encoded in place by the loop, with small PONGs and
 * worker replies (raw RENDERs, linked) between them, pipelined in one
 * stream to a client whose receive buffer is small, so that the daemon's
 * writes are partial: each reply arrives whole, in request order, and
 * holds what was asked. The model: a PONG echoes its PING's bytes; a page
 * of max k from the start holds k distinct ids of the N added (all N
 * when k = N). */
static void test_metrics_output_blocks_in_order(void **state)
{
    (void)state;
    static const uint32_t pings[] = {5, 1024, 0, 7, 1000, 1, 333, 12};
    static const uint32_t maxes[] = {1000, 157, 158, 1, 640, 1000, 300, 999};
    enum { N = 1000, R = sizeof pings / sizeof pings[0], W = 64, H = 32 };
    daemon_proc d;
    int mport;
    daemon_with_metrics(&d, &mport, NULL);
    vtc_client *ed = connect_role(&d, VP_ROLE_EDITOR, false);
    vp_entity *e = calloc(N, sizeof *e);
    assert_non_null(e);
    for (uint32_t i = 0; i < N; i++)
        e[i] = (vp_entity){.id = i + 1, .sphere = {(double)(i % 30), 1, (double)(i / 30), 1}};
    assert_int_equal(vtc_add(ed, e, N, NULL, NULL), VP_OK);
    free(e);
    static rawc r;
    memset(&r, 0, sizeof r);
    r.fd = socket(AF_UNIX, SOCK_STREAM, 0);
    int small = 4096;
    setsockopt(r.fd, SOL_SOCKET, SO_RCVBUF, &small, sizeof small);
    struct sockaddr_un sa = {.sun_family = AF_UNIX};
    snprintf(sa.sun_path, sizeof sa.sun_path, "%s", d.sock);
    assert_int_equal(connect(r.fd, (struct sockaddr *)&sa, sizeof sa), 0);
    struct timeval tv = {.tv_sec = 10};
    setsockopt(r.fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    size_t cap = 256 * 1024;
    uint8_t *req = malloc(cap), *got = malloc(cap), data[1024];
    assert_non_null(req);
    assert_non_null(got);
    for (size_t i = 0; i < sizeof data; i++) data[i] = (uint8_t)(i * 131 + 7);
    vp_writer w;
    vp_writer_init(&w, req, cap);
    vp_enc_hello(&w, 1, &(vp_hello){.magic = VP_MAGIC, .version = VP_VERSION, .role = VP_ROLE_VIEWER});
    vp_render m = {.format = VP_FRAME_RAW};
    assert_true(vtc_view_perspective(&m.view, (double[]){0, 0, 0}, (double[]){0, 0, -10}, NULL, 60, W, H, 0.1, 100));
    for (uint32_t i = 0; i < R; i++) {
        vp_enc_ping(&w, VP_PING, 100 + i, data, pings[i]);
        vp_enc_list(&w, 200 + i, &(vp_list){.cursor = 0, .max = maxes[i]});
        if (i % 3 == 1) vp_enc_render(&w, 300 + i, &m); /* a worker's reply after it */
    }
    assert_false(w.overflow);
    raw_write(&r, req, w.len); /* the daemon reads it all: it queues what the client does not take yet */
    vp_header h;
    assert_int_equal(raw_reply(&r, &h, got, cap), VP_HELLO_OK);
    uint8_t seen[N + 1];
    for (uint32_t i = 0; i < R; i++) {
        assert_int_equal(raw_reply(&r, &h, got, cap), VP_PONG);
        assert_int_equal(h.req, 100 + i);
        assert_int_equal(h.len, pings[i]);
        assert_memory_equal(got, data, pings[i]);
        assert_int_equal(raw_reply(&r, &h, got, cap), VP_ENTITY_LIST_REPLY);
        assert_int_equal(h.req, 200 + i);
        vp_list_reply lr;
        assert_int_equal(vp_dec_list_reply(got, h.len, &lr), VP_OK);
        assert_int_equal(lr.batch.count, maxes[i]);
        memset(seen, 0, sizeof seen);
        for (uint32_t k = 0; k < lr.batch.count; k++) {
            vp_entity x;
            assert_int_equal(vp_entity_get(&lr.batch, k, &x), VP_OK);
            assert_true(x.id >= 1 && x.id <= N && !seen[x.id]);
            seen[x.id] = 1;
        }
        if (i % 3 == 1) {
            assert_int_equal(raw_reply(&r, &h, got, cap), VP_FRAME);
            assert_int_equal(h.req, 300 + i);
            assert_int_equal(h.len, vp_size_frame(W * H * 20) - VP_HEADER_SIZE);
        }
    }
    /* nothing left in the daemon */
    wait_value(mport, "vantage_output_buffered_bytes", NULL, NULL, 0);
    free(req);
    free(got);
    close(r.fd);
    vtc_close(ed);
    daemon_stop(&d);
}

/* The pending list (issue 25): the loop visits only the connections with
 * output waiting. Eight idle viewers and one that pipelines 4,096 PINGs
 * of 1,000 bytes and reads nothing: exactly one connection is pending; once it has
 * read every PONG, none is, and the output blocks it held are given back
 * (each connection keeps at most its one small tail block, 16 KiB). */
static void test_metrics_output_pending_list(void **state)
{
    (void)state;
    enum { NIDLE = 8, K = 4096, P = 1000 };
    daemon_proc d;
    int mport;
    daemon_with_metrics(&d, &mport, NULL);
    vtc_client *idle[NIDLE];
    for (int i = 0; i < NIDLE; i++) {
        idle[i] = connect_role(&d, VP_ROLE_VIEWER, false);
        assert_int_equal(vtc_ping(idle[i]), VP_OK);
    }
    wait_value(mport, "vantage_output_pending_clients", NULL, NULL, 0);
    static rawc r;
    raw_hello_as(&r, &d, VP_ROLE_VIEWER);
    uint8_t *buf = malloc(P + 64), *data = calloc(1, P);
    assert_non_null(buf);
    assert_non_null(data);
    for (int k = 0; k < K; k++) {
        vp_writer w;
        vp_writer_init(&w, buf, P + 64);
        vp_enc_ping(&w, VP_PING, (uint32_t)k + 1, data, P);
        raw_write(&r, buf, w.len);
    }
    double q = 0;
    for (int i = 0; i < 500 && q < (double)K * P / 2; i++) {
        expo e;
        scrape(mport, &e);
        q = xget(&e, "vantage_output_buffered_bytes", NULL, NULL);
        expo_free(&e);
        if (q < (double)K * P / 2) usleep(10000);
    }
    assert_true(q >= (double)K * P / 2);
    expo e;
    scrape(mport, &e);
    assert_true(xget(&e, "vantage_output_pending_clients", NULL, NULL) == 1);
    double held = xget(&e, "vantage_client_output_buffer_bytes", NULL, NULL);
    expo_free(&e);
    assert_true(held >= q);
    for (int k = 0; k < K; k++) {
        vp_header h;
        assert_int_equal(raw_frame(&r, &h), VP_PONG);
        assert_int_equal(h.req, (uint32_t)k + 1);
    }
    wait_value(mport, "vantage_output_pending_clients", NULL, NULL, 0);
    expo z;
    scrape(mport, &z);
    double rest = xget(&z, "vantage_client_output_buffer_bytes", NULL, NULL);
    fprintf(stderr, "metrics: output blocks %.0f kB with %.0f kB unread, %.0f kB once read\n", held / 1024, q / 1024,
            rest / 1024);
    assert_true(rest <= (NIDLE + 1) * (16384.0 + 64));
    expo_free(&z);
    free(buf);
    free(data);
    close(r.fd);
    for (int i = 0; i < NIDLE; i++) vtc_close(idle[i]);
    daemon_stop(&d);
}

/* Connections that close while their worker replies are still being drawn
 * (a raw RENDER, a frame stream) are freed at the loop's safe point, and
 * the replies that come back for them are dropped: new connections (which
 * take the freed descriptors) get only their own replies, every job comes
 * back, and under ASan nothing touches freed memory. */
static void test_metrics_output_close_with_reply_in_flight(void **state)
{
    (void)state;
    enum { ROUNDS = 24, W = 400, H = 300 };
    vp_render m = {.format = VP_FRAME_RAW};
    assert_true(vtc_view_perspective(&m.view, (double[]){0, 0, 0}, (double[]){0, 0, -10}, NULL, 60, W, H, 0.1, 100));
    vp_frame_sub sub = {.r = m, .max_fps = VP_FRAME_SUB_MAX_FPS};
    daemon_proc d;
    int mport;
    daemon_with_metrics(&d, &mport, NULL);
    expo a;
    scrape(mport, &a);
    static rawc r, n;
    for (int round = 0; round < ROUNDS; round++) {
        raw_hello_as(&r, &d, VP_ROLE_VIEWER);
        uint8_t buf[1024];
        vp_writer w;
        vp_writer_init(&w, buf, sizeof buf);
        if (round % 2) vp_enc_frame_sub(&w, 5, &sub);
        else vp_enc_render(&w, 5, &m);
        vp_enc_ping(&w, VP_PING, 6, (const uint8_t *)"x", 1);
        raw_write(&r, buf, w.len);
        if (round % 3 == 0) usleep(1000);
        close(r.fd); /* while the frame is drawn */
        raw_hello_as(&n, &d, VP_ROLE_VIEWER);
        vp_writer_init(&w, buf, sizeof buf);
        vp_enc_ping(&w, VP_PING, 77, (const uint8_t *)"mine", 4);
        raw_write(&n, buf, w.len);
        vp_header h;
        assert_int_equal(raw_frame(&n, &h), VP_PONG);
        assert_int_equal(h.req, 77);
        close(n.fd);
    }
    wait_value(mport, "vantage_worker_jobs", NULL, NULL, 0);
    wait_value(mport, "vantage_clients", "role", "viewer", 0);
    expo z;
    scrape(mport, &z);
    assert_true(xget(&z, "vantage_disconnects_total", "reason", "peer") -
                    xget(&a, "vantage_disconnects_total", "reason", "peer") ==
                2 * ROUNDS);
    assert_true(xget(&z, "vantage_frame_streams", NULL, NULL) == 0);
    assert_true(xget(&z, "vantage_output_pending_clients", NULL, NULL) == 0);
    expo_free(&a);
    expo_free(&z);
    /* and it still serves */
    vtc_client *v = connect_role(&d, VP_ROLE_VIEWER, false);
    vp_frame f;
    assert_int_equal(vtc_render(v, &m, &f), VP_OK);
    vtc_close(v);
    daemon_stop(&d);
}

const struct CMUnitTest metrics_tests[] = {
    cmocka_unit_test(test_metrics_buffers_shrink),
    cmocka_unit_test(test_metrics_output_limit_total),
    cmocka_unit_test(test_metrics_output_frames_linked_not_copied),
    cmocka_unit_test(test_metrics_output_blocks_in_order),
    cmocka_unit_test(test_metrics_output_pending_list),
    cmocka_unit_test(test_metrics_output_close_with_reply_in_flight),
    cmocka_unit_test(test_metrics_model),
    TEST_ROWS(test_metrics_model_refuses, model_cases),
    cmocka_unit_test(test_metrics_message_codec),
    cmocka_unit_test(test_metrics_counts),
    cmocka_unit_test(test_metrics_clients),
    cmocka_unit_test(test_metrics_dropped_frames),
    cmocka_unit_test(test_metrics_motion_frames),
    cmocka_unit_test(test_metrics_http_bad_input),
    cmocka_unit_test(test_metrics_access),
};
const size_t metrics_tests_count = sizeof metrics_tests / sizeof metrics_tests[0];
