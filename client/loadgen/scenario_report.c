/*
 * scenario_report.c — what a `bench --scenario` run prints: the table,
 * the drift and memory lines, JSON and CSV; and the daemon's memory.
 */
#include "scenario_run.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>

/* ---- the daemon's memory ------------------------------------------------------------ */

/* The daemon's pid from a Unix socket's peer credentials (0 over TCP). */
int daemon_pid(vtc_client *c)
{
    struct ucred cr;
    socklen_t n = sizeof cr;
    if (getsockopt(vtc_fd(c), SOL_SOCKET, SO_PEERCRED, &cr, &n) == 0 && cr.pid > 0) return cr.pid;
    return 0;
}

double rss_mib(int pid)
{
    char path[64], line[256];
    snprintf(path, sizeof path, "/proc/%d/status", pid);
    FILE *f = fopen(path, "r");
    if (!f) return -1;
    double kib = -1;
    while (fgets(line, sizeof line, f))
        if (sscanf(line, "VmRSS: %lf", &kib) == 1) break;
    fclose(f);
    return kib < 0 ? -1 : kib / 1024;
}

/* ---- the report -------------------------------------------------------------------- */

void row_names(const scenario *s, report *rp)
{
    static const char *fixed[R_FIXED] = {"edit_to_query", "edit_to_frame", "sublevel_load", "sublevel_unload",
                                         "destroy"};
    for (int i = 0; i < R_FIXED; i++) snprintf(rp->name[i], sizeof rp->name[i], "%s", fixed[i]);
    for (int g = 0; g < s->ng; g++) {
        enum scn_op op = s->g[g].op;
        snprintf(rp->name[R_MAIN(g)], sizeof rp->name[0], "%s.%s", s->g[g].name,
                 op >= SCN_FRAMES ? "frame_interval" : scn_op_name(op));
        snprintf(rp->name[R_INPUT(g)], sizeof rp->name[0], "%s.input_to_frame", s->g[g].name);
    }
}

static bool row_used(const report *rp, int i)
{
    return rp->all.h[i].count || rp->all.errors[i] || rp->all.unsent[i] || rp->all.pending[i];
}

static double ms(uint64_t ns)
{
    return ns / 1e6;
}

/* One row's figures, as every output prints them. */
typedef struct row_stat {
    unsigned long long count, errors, unsent, pending;
    double per_s, mean_ms, pct_ms[5]; /* p50, p90, p99, p99.9, max */
} row_stat;

static row_stat stat_of(const report *rp, int i)
{
    const scn_hist *h = &rp->all.h[i];
    row_stat st = {.count = h->count, .errors = rp->all.errors[i], .unsent = rp->all.unsent[i],
                   .pending = rp->all.pending[i], .per_s = rp->secs > 0 ? h->count / rp->secs : 0,
                   .mean_ms = scn_hist_mean(h) / 1e6};
    const double q[5] = {50, 90, 99, 99.9, 100};
    for (int k = 0; k < 5; k++) st.pct_ms[k] = ms(scn_hist_percentile(h, q[k]));
    return st;
}

void print_table(FILE *o, const run *r, const report *rp)
{
    const scenario *s = r->s;
    uint32_t clients = 0;
    for (int i = 0; i < s->ng; i++) clients += s->g[i].clients;
    fprintf(o, "scenario %s: %u clients in %d groups, %.1f s measured%s%s\n", s->name, clients, s->ng, rp->secs,
            s->warmup > 0 ? " (after the warm-up)" : "", rp->partial ? "  ** PARTIAL **" : "");
    if (rp->partial) fprintf(o, "partial: %s\n", r->why);
    fprintf(o, "%-32s %9s %10s %7s %7s %7s %9s %9s %9s %9s %9s\n", "ms", "count", "per_s", "errors", "unsent",
            "pending", "p50", "p90", "p99", "p99.9", "max");
    for (int i = 0; i < rp->all.n; i++) {
        if (!row_used(rp, i)) continue;
        row_stat st = stat_of(rp, i);
        fprintf(o, "%-32s %9llu %10.1f %7llu %7llu %7llu", rp->name[i], st.count, st.per_s, st.errors, st.unsent,
                st.pending);
        for (int k = 0; k < 5; k++) fprintf(o, " %9.3f", st.pct_ms[k]);
        fprintf(o, "\n");
    }
    bool head = false;
    for (int i = 0; i < rp->all.n && !s->requests; i++) { /* a count has no tenths known in advance */
        if (rp->all.h[i].count < 100) continue;
        if (!head) fprintf(o, "drift, p99 ms per tenth of the run:\n");
        head = true;
        fprintf(o, "  %-30s", rp->name[i]);
        for (int w = 0; w < WINDOWS; w++) { /* '-': nothing measured in that tenth */
            const scn_hist *h = &rp->all.win[i * WINDOWS + w];
            if (h->count) fprintf(o, " %7.2f", ms(scn_hist_percentile(h, 99)));
            else fprintf(o, " %7s", "-");
        }
        fprintf(o, "\n");
    }
    if (rp->nrss) {
        fprintf(o, "daemon memory (RSS, sampled every second): start %.1f MiB, end %.1f MiB, max %.1f MiB\n", rp->rss0,
                rp->rss1, rp->rssmax);
        if (!s->requests) {
            fprintf(o, "  %-30s", "max MiB per tenth");
            /* '-': no sample fell in that tenth (one a second: a run
               under ten seconds has tenths without one) */
            for (int w = 0; w < WINDOWS; w++) {
                if (rp->rss_win[w] > 0) fprintf(o, " %7.1f", rp->rss_win[w]);
                else fprintf(o, " %7s", "-");
            }
            fprintf(o, "\n");
        }
    }
}

static void print_json(FILE *o, const run *r, const report *rp)
{
    const scenario *s = r->s;
    fprintf(o, "{\"scenario\": ");
    cli_json_str(o, s->name, strlen(s->name));
    fprintf(o, ", \"seconds\": %.3f, \"partial\": %s", rp->secs, rp->partial ? "true" : "false");
    if (rp->partial) {
        fprintf(o, ", \"why\": ");
        cli_json_str(o, r->why, strlen(r->why));
    }
    fprintf(o, ", \"ops\": {");
    bool first = true;
    for (int i = 0; i < rp->all.n; i++) {
        if (!row_used(rp, i)) continue;
        row_stat st = stat_of(rp, i);
        fprintf(o, "%s", first ? "" : ", ");
        cli_json_str(o, rp->name[i], strlen(rp->name[i]));
        fprintf(o, ": {\"count\": %llu, \"per_second\": %.2f, \"errors\": %llu, \"unsent\": %llu, \"pending\": %llu, "
                   "\"mean_ms\": %.4f",
                st.count, st.per_s, st.errors, st.unsent, st.pending, st.mean_ms);
        static const char *key[5] = {"p50_ms", "p90_ms", "p99_ms", "p999_ms", "max_ms"};
        for (int k = 0; k < 5; k++) fprintf(o, ", \"%s\": %.4f", key[k], st.pct_ms[k]);
        fprintf(o, ", \"p99_ms_by_tenth\": [");
        for (int w = 0; w < WINDOWS && !s->requests; w++) { /* null: nothing measured in that tenth */
            const scn_hist *h = &rp->all.win[i * WINDOWS + w];
            if (h->count) fprintf(o, "%s%.4f", w ? ", " : "", ms(scn_hist_percentile(h, 99)));
            else fprintf(o, "%snull", w ? ", " : "");
        }
        fprintf(o, "]}");
        first = false;
    }
    fprintf(o, "}");
    if (rp->nrss)
    {
        fprintf(o, ", \"daemon_rss_mib\": {\"start\": %.2f, \"end\": %.2f, \"max\": %.2f, \"max_by_tenth\": [",
                rp->rss0, rp->rss1, rp->rssmax);
        for (int w = 0; w < WINDOWS && !s->requests; w++) { /* null: no sample in that tenth */
            if (rp->rss_win[w] > 0) fprintf(o, "%s%.2f", w ? ", " : "", rp->rss_win[w]);
            else fprintf(o, "%snull", w ? ", " : "");
        }
        fprintf(o, "]}");
    }
    fprintf(o, "}\n");
}

static void print_csv(FILE *o, const report *rp)
{
    fprintf(o, "op,count,per_second,errors,unsent,pending,mean_ms,p50_ms,p90_ms,p99_ms,p999_ms,max_ms\n");
    for (int i = 0; i < rp->all.n; i++) {
        if (!row_used(rp, i)) continue;
        row_stat st = stat_of(rp, i);
        fprintf(o, "%s,%llu,%.2f,%llu,%llu,%llu,%.4f", rp->name[i], st.count, st.per_s, st.errors, st.unsent,
                st.pending, st.mean_ms);
        for (int k = 0; k < 5; k++) fprintf(o, ",%.4f", st.pct_ms[k]);
        fprintf(o, "\n");
    }
}

int write_out(const char *path, const run *r, const report *rp, bool json)
{
    FILE *f = !strcmp(path, "-") ? stdout : fopen(path, "w");
    if (!f) return fprintf(stderr, "%s: bench: %s: %s\n", g_prog, path, strerror(errno)), -1;
    if (json) print_json(f, r, rp);
    else print_csv(f, rp);
    bool bad = ferror(f);
    if (f != stdout) bad |= fclose(f) != 0;
    if (bad) return fprintf(stderr, "%s: bench: %s: write error\n", g_prog, path), -1;
    return 0;
}
