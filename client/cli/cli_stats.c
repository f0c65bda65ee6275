/*
 * cli_stats.c — `vantage stats`: the daemon's figures (STATS), and its
 * metrics read back from their exposition (METRICS): p50/p99 per request
 * type estimated from the histogram buckets as Prometheus's
 * histogram_quantile does (linear within the bucket), clients by role,
 * frame streams, the cluster's role and lag (vantaged --cluster).
 */
#include "cli.h"

#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define XS_TYPES 48
#define XS_BUCKETS 32
typedef struct xhist {
    char key[40];
    double count, errors;
    int nb;
    double le[XS_BUCKETS], cum[XS_BUCKETS];
} xhist;

typedef struct xstats {
    xhist req[XS_TYPES], stage[8];
    int nreq, nstage;
    double clients[4]; /* handshake, viewer, commander, editor */
    double streams, sent, dropped, discarded;
    char role[40];                /* --cluster: writer, promoting or replica ("": none) */
    double seq_applied, seq_stored, seq_last, lag;
} xstats;

/* The value of label key in labels[0..n) ("k=\"v\",..."), unescaped. */
static bool xlabel(const char *p, size_t n, const char *key, char *out, size_t outlen)
{
    size_t i = 0, kl = strlen(key);
    while (i < n) {
        size_t k0 = i;
        while (i < n && p[i] != '=') i++;
        if (i + 1 >= n || p[i + 1] != '"') return false;
        bool match = i - k0 == kl && !memcmp(p + k0, key, kl);
        size_t o = 0;
        for (i += 2; i < n && p[i] != '"'; i++) {
            char ch = p[i];
            if (ch == '\\' && i + 1 < n) ch = p[++i] == 'n' ? '\n' : p[i];
            if (match && o + 1 < outlen) out[o++] = ch;
        }
        if (match) {
            out[o] = 0;
            return true;
        }
        i += 2; /* the quote and the comma */
    }
    return false;
}

static xhist *xfind(xhist *a, int *n, int cap, const char *key)
{
    for (int i = 0; i < *n; i++)
        if (!strcmp(a[i].key, key)) return &a[i];
    if (*n == cap) return NULL;
    xhist *h = &a[(*n)++];
    memset(h, 0, sizeof *h);
    snprintf(h->key, sizeof h->key, "%s", key);
    return h;
}

static void xbucket(xhist *h, const char *labels, size_t ln, double v)
{
    char le[32];
    if (h && h->nb < XS_BUCKETS && xlabel(labels, ln, "le", le, sizeof le)) {
        h->le[h->nb] = strtod(le, NULL);
        h->cum[h->nb++] = v;
    }
}

static void xparse(const char *t, size_t len, xstats *x)
{
    memset(x, 0, sizeof *x);
    for (size_t pos = 0; pos < len;) {
        const char *l = t + pos, *nl = memchr(l, '\n', len - pos);
        size_t n = nl ? (size_t)(nl - l) : len - pos;
        pos += n + 1;
        if (!n || l[0] == '#') continue;
        size_t ne = 0;
        while (ne < n && l[ne] != '{' && l[ne] != ' ') ne++;
        const char *labels = "";
        size_t ln = 0, ve = ne;
        if (ne < n && l[ne] == '{') {
            labels = l + ne + 1;
            bool q = false;
            for (ve = ne + 1; ve < n && (q || l[ve] != '}'); ve++) {
                if (l[ve] == '\\') ve++;
                else if (l[ve] == '"') q = !q;
            }
            ln = ve - ne - 1;
            ve++;
        }
        char name[96], v[64], key[40];
        if (ne >= sizeof name || ve >= n) continue;
        memcpy(name, l, ne);
        name[ne] = 0;
        size_t vl = n - ve - 1 < sizeof v - 1 ? n - ve - 1 : sizeof v - 1;
        memcpy(v, l + ve + 1, vl);
        v[vl] = 0;
        double val = strtod(v, NULL);
        bool typed = xlabel(labels, ln, "type", key, sizeof key);
        if (!strcmp(name, "vantage_requests_total") && typed) {
            xhist *h = xfind(x->req, &x->nreq, XS_TYPES, key);
            if (h) h->count = val;
        } else if (!strcmp(name, "vantage_request_errors_total") && typed) {
            xhist *h = xfind(x->req, &x->nreq, XS_TYPES, key);
            if (h) h->errors += val;
        } else if (!strcmp(name, "vantage_request_duration_seconds_bucket") && typed) {
            xbucket(xfind(x->req, &x->nreq, XS_TYPES, key), labels, ln, val);
        } else if (!strcmp(name, "vantage_query_stage_seconds_bucket") &&
                   xlabel(labels, ln, "stage", key, sizeof key)) {
            xbucket(xfind(x->stage, &x->nstage, 8, key), labels, ln, val);
        } else if (!strcmp(name, "vantage_clients") && xlabel(labels, ln, "role", key, sizeof key)) {
            static const char *const roles[4] = {"handshake", "viewer", "commander", "editor"};
            for (int i = 0; i < 4; i++)
                if (!strcmp(key, roles[i])) x->clients[i] = val;
        } else if (!strcmp(name, "vantage_frame_streams")) {
            x->streams = val;
        } else if (!strcmp(name, "vantage_frames_sent_total")) {
            x->sent = val;
        } else if (!strcmp(name, "vantage_frames_dropped_total")) {
            x->dropped = val;
        } else if (!strcmp(name, "vantage_frames_discarded_total")) {
            x->discarded = val;
        } else if (!strcmp(name, "vantage_cluster_role") && val == 1 && xlabel(labels, ln, "role", key, sizeof key)) {
            snprintf(x->role, sizeof x->role, "%s", key);
        } else if (!strcmp(name, "vantage_cluster_stream_sequence") && xlabel(labels, ln, "kind", key, sizeof key)) {
            if (!strcmp(key, "applied")) x->seq_applied = val;
            else if (!strcmp(key, "stored")) x->seq_stored = val;
            else if (!strcmp(key, "last")) x->seq_last = val;
        } else if (!strcmp(name, "vantage_cluster_lag_messages")) {
            x->lag = val;
        }
    }
}

/* Seconds at quantile q of a histogram (NAN when empty). */
static double xquantile(const xhist *h, double q)
{
    if (!h->nb || h->cum[h->nb - 1] <= 0) return NAN;
    double rank = q * h->cum[h->nb - 1];
    for (int i = 0; i < h->nb; i++) {
        if (h->cum[i] < rank) continue;
        if (isinf(h->le[i])) return i ? h->le[i - 1] : NAN; /* past the last bound: that bound */
        double lo = i ? h->le[i - 1] : 0, clo = i ? h->cum[i - 1] : 0;
        return h->cum[i] > clo ? lo + (h->le[i] - lo) * (rank - clo) / (h->cum[i] - clo) : h->le[i];
    }
    return NAN;
}

static const char *xdur(double sec, char *buf, size_t n)
{
    if (isnan(sec)) snprintf(buf, n, "-");
    else if (sec < 1e-5) snprintf(buf, n, "%.1f us", sec * 1e6);
    else if (sec < 1e-3) snprintf(buf, n, "%.0f us", sec * 1e6);
    else if (sec < 1) snprintf(buf, n, "%.2f ms", sec * 1e3);
    else snprintf(buf, n, "%.2f s", sec);
    return buf;
}

static int xcmp_count(const void *a, const void *b)
{
    double x = ((const xhist *)a)->count, y = ((const xhist *)b)->count;
    return x < y ? 1 : x > y ? -1 : 0;
}

static void xjson_ms(double sec)
{
    if (isnan(sec)) printf("null");
    else printf("%.4f", sec * 1e3);
}

int cmd_stats(cli *k, int argc, char **argv)
{
    const char *use = "stats [--json | --metrics]";
    bool json = argc == 2 && !strcmp(argv[1], "--json"), prom = argc == 2 && !strcmp(argv[1], "--metrics");
    if (argc > 1 && !json && !prom) return die_usage("%s", use);
    int rc = connect_cli(k, VP_ROLE_VIEWER);
    if (rc) return rc;
    const char *text = NULL;
    size_t tlen = 0;
    if (prom) {
        if ((rc = vtc_metrics(k->c, &text, &tlen))) return server_fail(k, "stats --metrics", rc);
        fwrite(text, 1, tlen, stdout);
        return 0;
    }
    vp_stats_reply s;
    if ((rc = vtc_stats(k->c, &s))) return server_fail(k, "stats", rc);
    /* a daemon from before METRICS answers ERROR TYPE: its figures only */
    rc = vtc_metrics(k->c, &text, &tlen);
    if (rc && rc != VP_ERR_TYPE) return server_fail(k, "stats (metrics)", rc);
    xstats *x = calloc(1, sizeof *x);
    if (!x) return server_fail(k, "stats", VTC_ERR_IO);
    if (!rc) xparse(text, tlen, x);
    bool have = !rc;
    int nreq = 0;
    for (int i = 0; i < x->nreq; i++)
        if (x->req[i].count > 0 || x->req[i].errors > 0) x->req[nreq++] = x->req[i];
    qsort(x->req, (size_t)nreq, sizeof x->req[0], xcmp_count);
    if (json) {
        printf("{\"epoch\": %llu, \"uptime_ms\": %llu, \"entities\": %u, \"static_entities\": %u, "
               "\"dynamic_entities\": %u, \"regions\": %u, \"cells\": %u, \"connections\": %u, \"meshes\": %u, "
               "\"occluders\": %u, \"lights\": %u, \"queries\": %llu, \"edits\": %llu, \"bytes_in\": %llu, "
               "\"bytes_out\": %llu, \"errors\": %llu",
               (unsigned long long)s.epoch, (unsigned long long)s.uptime_ms, s.entities, s.static_entities,
               s.dynamic_entities, s.regions, s.cells, s.connections, s.meshes, s.occluders, s.lights,
               (unsigned long long)s.queries, (unsigned long long)s.edits, (unsigned long long)s.bytes_in,
               (unsigned long long)s.bytes_out, (unsigned long long)s.errors);
        if (have) {
            if (x->role[0])
                printf(", \"cluster\": {\"role\": \"%s\", \"applied\": %.0f, \"stored\": %.0f, \"last\": %.0f, "
                       "\"lag\": %.0f}",
                       x->role, x->seq_applied, x->seq_stored, x->seq_last, x->lag);
            printf(", \"clients\": {\"handshake\": %.0f, \"viewer\": %.0f, \"commander\": %.0f, \"editor\": %.0f}, "
                   "\"frames\": {\"streams\": %.0f, \"sent\": %.0f, \"dropped\": %.0f, \"discarded\": %.0f}, "
                   "\"requests\": {",
                   x->clients[0], x->clients[1], x->clients[2], x->clients[3], x->streams, x->sent, x->dropped,
                   x->discarded);
            for (int i = 0; i < nreq; i++) {
                printf("%s\"%s\": {\"count\": %.0f, \"errors\": %.0f, \"p50_ms\": ", i ? ", " : "", x->req[i].key,
                       x->req[i].count, x->req[i].errors);
                xjson_ms(xquantile(&x->req[i], 0.5));
                printf(", \"p99_ms\": ");
                xjson_ms(xquantile(&x->req[i], 0.99));
                printf("}");
            }
            printf("}, \"query_stages\": {");
            for (int i = 0; i < x->nstage; i++) {
                printf("%s\"%s\": {\"p50_ms\": ", i ? ", " : "", x->stage[i].key);
                xjson_ms(xquantile(&x->stage[i], 0.5));
                printf(", \"p99_ms\": ");
                xjson_ms(xquantile(&x->stage[i], 0.99));
                printf("}");
            }
            printf("}");
        }
        printf("}\n");
    } else {
        printf("epoch        %llu\nuptime       %.1f s\nentities     %u (%u static, %u dynamic)\n"
               "cells        %u in %u regions\nconnections  %u\nmeshes       %u\noccluders    %u\nlights       %u\n"
               "queries      %llu\nedits        %llu\nbytes in     %llu\nbytes out    %llu\nerrors       %llu\n",
               (unsigned long long)s.epoch, s.uptime_ms / 1000.0, s.entities, s.static_entities, s.dynamic_entities,
               s.cells, s.regions, s.connections, s.meshes, s.occluders, s.lights, (unsigned long long)s.queries,
               (unsigned long long)s.edits, (unsigned long long)s.bytes_in, (unsigned long long)s.bytes_out,
               (unsigned long long)s.errors);
        if (have) {
            char a[24], b[24];
            printf("clients      %.0f viewer, %.0f commander, %.0f editor, %.0f in handshake\n", x->clients[1],
                   x->clients[2], x->clients[3], x->clients[0]);
            printf("frames       %.0f sent, %.0f dropped (viewer behind), %.0f discarded; %.0f stream%s\n", x->sent,
                   x->dropped, x->discarded, x->streams, x->streams == 1 ? "" : "s");
            if (!strcmp(x->role, "writer"))
                printf("cluster      writer; stream message %.0f published, %.0f stored; %.0f not yet stored\n",
                       x->seq_applied, x->seq_stored, x->lag);
            else if (x->role[0])
                printf("cluster      %s; stream message %.0f applied of %.0f; lag %.0f\n", x->role, x->seq_applied,
                       x->seq_last, x->lag);
            printf("\nrequests (p50, p99: from taking a request to its reply queued, estimated from buckets)\n");
            printf("  %-20s %12s %10s %10s %10s\n", "type", "count", "errors", "p50", "p99");
            for (int i = 0; i < nreq; i++) {
                printf("  %-20s %12.0f %10.0f %10s", x->req[i].key, x->req[i].count, x->req[i].errors,
                       xdur(xquantile(&x->req[i], 0.5), a, sizeof a));
                printf(" %10s\n", xdur(xquantile(&x->req[i], 0.99), b, sizeof b));
            }
            printf("\nquery stages on the workers (p50, p99)\n");
            for (int i = 0; i < x->nstage; i++) {
                printf("  %-20s %10s", x->stage[i].key, xdur(xquantile(&x->stage[i], 0.5), a, sizeof a));
                printf(" %10s\n", xdur(xquantile(&x->stage[i], 0.99), b, sizeof b));
            }
        }
    }
    free(x);
    return 0;
}
