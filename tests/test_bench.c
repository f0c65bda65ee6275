/*
 * test_bench.c — the load generator itself (issue 9): the log-bucket
 * histogram against exact percentiles of known distributions, the
 * scenario format (the shipped ones, and errors that name line and field),
 * camera paths and the open-loop schedule against their formulas, and
 * `vantage bench --scenario` against a real daemon: an open-loop run keeps
 * its rate, a daemon that goes away ends the run with a partial report.
 */
#include "test_util.h"
#include "test_daemon.h"

#include "lat_hist.h"
#include "scenario.h"

#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

static int cmp_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

/* The exact percentile by the same rank rule (the ceil(q n)-th smallest). */
static uint64_t exact_pct(const uint64_t *sorted, size_t n, double q)
{
    if (q >= 100) return sorted[n - 1];
    double r = q / 100.0 * (double)n;
    size_t rank = (size_t)r;
    if ((double)rank < r) rank++;
    if (rank < 1) rank = 1;
    return sorted[rank - 1];
}

static void test_bench_hist_distributions(void **state)
{
    (void)state;
    rng r = {test_seed()};
    enum { N = 200000 };
    uint64_t *v = malloc(sizeof *v * N);
    scn_hist *h = malloc(sizeof *h);
    assert_non_null(v);
    assert_non_null(h);
    const char *names[] = {"uniform", "exponential", "lognormal", "bimodal"};
    for (int d = 0; d < 4; d++) {
        scn_hist_init(h);
        double sum = 0;
        for (size_t i = 0; i < N; i++) {
            double x;
            if (d == 0) x = rng_range(&r, 1, 1e6);                         /* 1 ns .. 1 ms */
            else if (d == 1) x = -log(1 - rng_f(&r)) * 2e5;                /* mean 200 us */
            else if (d == 2) x = exp(11 + 1.5 * sqrt(-2 * log(1 - rng_f(&r))) * cos(2 * M_PI * rng_f(&r)));
            else x = rng_f(&r) < 0.99 ? rng_range(&r, 5e4, 6e4) : rng_range(&r, 5e7, 6e7); /* a 1 % tail */
            v[i] = (uint64_t)x;
            sum += (double)v[i];
            scn_hist_record(h, v[i]);
        }
        qsort(v, N, sizeof *v, cmp_u64);
        assert_int_equal(h->count, N);
        assert_int_equal(h->min, v[0]);
        assert_int_equal(h->max, v[N - 1]);
        assert_true(fabs(scn_hist_mean(h) - sum / N) <= 1e-9 * sum / N);
        const double qs[] = {0, 1, 10, 25, 50, 75, 90, 99, 99.9, 99.99, 100};
        for (size_t k = 0; k < sizeof qs / sizeof qs[0]; k++) {
            uint64_t want = exact_pct(v, N, qs[k]), got = scn_hist_percentile(h, qs[k]);
            /* the middle of the value's bucket: within half a bucket, 1/256 of it */
            double tol = ldexp((double)want, -(int)SCN_HIST_SUB_BITS - 1) + 0.5;
            if (fabs((double)got - (double)want) > tol)
                fail_msg("%s p%g: histogram %llu, exact %llu (tolerance %.1f)", names[d], qs[k],
                         (unsigned long long)got, (unsigned long long)want, tol);
        }
    }
    free(v);
    free(h);
}

static void test_bench_hist_buckets(void **state)
{
    (void)state;
    /* buckets tile the range without gaps: low(i+1) = low(i) + width(i) */
    for (uint32_t i = 0; i + 1 < SCN_HIST_BUCKETS; i++)
        assert_int_equal(scn_hist_bucket_low(i + 1), scn_hist_bucket_low(i) + scn_hist_bucket_width(i));
    assert_int_equal(scn_hist_bucket_low(SCN_HIST_BUCKETS - 1) + scn_hist_bucket_width(SCN_HIST_BUCKETS - 1), 1ull << SCN_HIST_MAX_BITS);
    rng r = {test_seed() ^ 5};
    for (int k = 0; k < 100000; k++) {
        uint64_t x = (uint64_t)rng_log(&r, 1, 0x1p40) - (k & 1); /* 0 too */
        if (x >= (1ull << SCN_HIST_MAX_BITS)) x = (1ull << SCN_HIST_MAX_BITS) - 1;
        uint32_t i = scn_hist_index(x);
        assert_true(i < SCN_HIST_BUCKETS);
        assert_true(scn_hist_bucket_low(i) <= x && x - scn_hist_bucket_low(i) < scn_hist_bucket_width(i));
        /* relative width: 1/128 at most above the exact range */
        if (x >= 2 * SCN_HIST_SUB) assert_true(scn_hist_bucket_width(i) * SCN_HIST_SUB <= x);
    }
    scn_hist *a = malloc(sizeof *a), *b = malloc(sizeof *b), *u = malloc(sizeof *u);
    assert_non_null(a);
    assert_non_null(b);
    assert_non_null(u);
    scn_hist_init(a);
    assert_int_equal(scn_hist_percentile(a, 50), 0); /* empty */
    assert_int_equal(scn_hist_mean(a), 0);
    scn_hist_init(b);
    scn_hist_init(u);
    for (int k = 0; k < 5000; k++) {
        uint64_t x = (uint64_t)rng_log(&r, 10, 1e9);
        scn_hist_record(k % 3 ? a : b, x);
        scn_hist_record(u, x);
    }
    scn_hist_merge(a, b); /* merging equals recording the union */
    assert_int_equal(a->count, u->count);
    assert_int_equal(a->min, u->min);
    assert_int_equal(a->max, u->max);
    assert_memory_equal(a->counts, u->counts, sizeof a->counts);
    /* below 2 SCN_HIST_SUB the histogram is exact */
    scn_hist_init(a);
    for (uint64_t x = 0; x < 2 * SCN_HIST_SUB; x++) scn_hist_record(a, x);
    assert_int_equal(scn_hist_percentile(a, 50), SCN_HIST_SUB - 1);
    /* past the range: clamped, counted */
    scn_hist_record_n(a, 1ull << 50, 3);
    assert_int_equal(a->clamped, 3);
    assert_int_equal(a->max, (1ull << SCN_HIST_MAX_BITS) - 1);
    assert_int_equal(scn_hist_percentile(a, 100), (1ull << SCN_HIST_MAX_BITS) - 1);
    free(a);
    free(b);
    free(u);
}

static const char *scn_dir(void)
{
    const char *d = getenv("VANTAGE_SCENARIOS");
    return d ? d : "client/loadgen/scenarios";
}

static void test_bench_scenarios_shipped(void **state)
{
    (void)state;
    const char *names[] = {"editor-live-link", "many-viewers", "query-storm", "destruction-barrage"};
    char path[512], err[512];
    for (int i = 0; i < 4; i++) {
        scenario s;
        snprintf(path, sizeof path, "%s/%s.scn", scn_dir(), names[i]);
        if (scn_load(path, &s, err, sizeof err)) fail_msg("%s", err);
        assert_string_equal(s.name, names[i]);
        assert_true(s.ng >= 1);
    }
    /* the soak of the issue: 64 viewers, 10 editors, 10 minutes */
    scenario s;
    snprintf(path, sizeof path, "%s/many-viewers.scn", scn_dir());
    assert_int_equal(scn_load(path, &s, err, sizeof err), 0);
    assert_int_equal(s.duration, 600);
    assert_int_equal(s.ng, 2);
    assert_int_equal(s.g[0].clients, 64);
    assert_int_equal(s.g[0].op, SCN_FRAMES);
    assert_int_equal(s.g[1].clients, 10);
    assert_int_equal(s.g[1].op, SCN_EDIT);
    assert_true(s.g[1].rate == 20);
    snprintf(path, sizeof path, "%s/destruction-barrage.scn", scn_dir());
    assert_int_equal(scn_load(path, &s, err, sizeof err), 0);
    assert_int_equal(s.nev, 3);
    assert_int_equal(s.ev[0].kind, SCN_EV_DESTROY);
    assert_int_equal(s.ev[0].n, 1000);
    assert_true(s.ev[0].rate == 100);
    assert_int_equal(s.ev[1].kind, SCN_EV_LOAD);
    assert_string_equal(s.ev[1].name, "bench-rubble");
    assert_int_equal(s.g[0].op, SCN_COMMANDER);
    assert_int_equal(s.g[0].cam.kind, SCN_CAM_PAN);
}

/* Scenario files the parser refuses: a row is the message it must give
 * (its name) and the text; a refused file changes nothing. */
typedef struct bad_scenario {
    const char *want, *text;
} bad_scenario;

static const bad_scenario bad_scenarios[] = {
    {"t:1: field 'op': group 'a' has no op", "group a\n role viewer\n clients 2\n"},
    {"t:1: field 'clients'", "group a\n op query\n"},
    {"t:1: field 'duration': expected a number, got 'abc'", "duration abc\ngroup a\n op ping\n clients 1\n"},
    {"t:1: field 'duration': -3 is outside", "duration -3\n"},
    {"t:5: field 'views': 33 is outside 1..32", "\n\ngroup a\n clients 1\n op query views 33\n"},
    {"t:2: field 'clients': expected a whole number", "group a\n clients 2.5\n"},
    {"t:1: field 'role': group 'a': op edit needs role editor", "group a\n clients 1\n op edit\n"},
    {"t:3: field 'size'", "group a\n clients 1\n op frames size 10x10\n"},
    {"field 'rate'", "group a\n clients 1\n op frames\n rate 5\n"},
    {"t:4: field 'op': group 'a' has an op already", "group a\n clients 1\n op ping\n op query\n"},
    {"t:3: field 'op': 'teleport'", "group a\n clients 1\n op teleport\n"},
    {"t:3: field 'frobnicate': not an option of op query", "group a\n clients 1\n op query frobnicate\n"},
    {"t:4: field 'center': expected x,y,z", "group a\n clients 1\n op ping\n camera orbit 0,0 1 2 3\n"},
    {"t:4: field 'camera path'", "group a\n clients 1\n op ping\n camera path 5 1,2,3\n"},
    {"t:4: field 'duration': a top-level setting inside group", "group a\n clients 1\n op ping\n duration 5\n"},
    {"t:1: field 'colour': unknown", "colour blue\n"},
    {"field 'group': no groups", ""},
    {"t:2: field 'at': 7 s is at or after", "duration 5\nat 7 sublevel load x\ngroup a\n clients 1\n op ping\n"},
    {"t:1: field 'at': 12 s is at or after the end of the run (duration 10 s)", "at 12 sublevel load x\ngroup a\n clients 1\n op ping\n"},
    {"t:1: field 'destroy': destruction needs entities", "at 1 destroy 5\ngroup a\n clients 1\n op ping\n"},
    {"t:1: field 'sublevel name': 'x' is unloaded before", "at 1 sublevel unload x\ngroup a\n clients 1\n op ping\n"},
    {"t:4: field 'group': 'a' is named twice", "group a\n clients 1\n op ping\ngroup a\n"},
    {"t:2: field 'role': expected editor, viewer, commander or query", "group a\n role admin\n"},
    {"t:5: field 'op'", "group a\n clients 1\n op ping\n role commander\n op x\n"},
    {"t:1: field 'probe': 'edit-to-dinner'", "probe edit-to-dinner\n"},
    {"t:1: field 'line': a control byte 0x01", "group a\x01\n"},
    {"field 'warmup': 20 s is not shorter", "warmup 20\nduration 10\ngroup a\n clients 1\n op ping\n"},
};

static void test_bench_scenario_errors(void **state)
{
    const bad_scenario *t = *state;
    scenario s;
    memset(&s, 0x5a, sizeof s);
    scenario before = s;
    char err[512] = "";
    int rc = scn_parse("t", t->text, strlen(t->text), &s, err, sizeof err);
    if (rc == 0) fail_msg("parsed: %s", t->text);
    if (!strstr(err, t->want)) fail_msg("'%s' does not contain '%s'", err, t->want);
    assert_memory_equal(&s, &before, sizeof s); /* a rejected file changes nothing */
}

/* A NUL byte says which line; a missing file says so. */
static void test_bench_scenario_nul_and_missing(void **state)
{
    (void)state;
    scenario s;
    char err[256];
    assert_int_equal(scn_parse("t", "name a\nname\0b\n", 14, &s, err, sizeof err), -1);
    assert_non_null(strstr(err, "t:2: field 'line': a NUL byte"));
    assert_int_equal(scn_load("/nonexistent/x.scn", &s, err, sizeof err), -1);
    assert_non_null(strstr(err, "No such file"));
}

static void test_bench_camera_and_schedule(void **state)
{
    (void)state;
    scenario s;
    char err[256];
    const char *text = "group a\n clients 4\n op ping\n camera orbit 10,0,-5 100 50 8\n"
                       "group b\n clients 1\n op ping\n camera path 10 0,0,0 30,0,0 30,0,40\n";
    assert_int_equal(scn_parse("t", text, strlen(text), &s, err, sizeof err), 0);
    double eye[3], at[3];
    /* orbit: client 1 of 4 starts a quarter turn on; at t = 2 s (a quarter period) it is half a turn on */
    scn_camera_at(&s.g[0].cam, 2, 1, 4, eye, at);
    assert_true(fabs(eye[0] - (10 - 100)) < 1e-9 && fabs(eye[1] - 50) < 1e-9 && fabs(eye[2] - -5) < 1e-9);
    assert_true(at[0] == 10 && at[1] == 0 && at[2] == -5);
    /* path: perimeter 30 + 40 + 50 = 120 m in 10 s; at 7.5 s, 90 m on: 20 m into the third leg */
    scn_camera_at(&s.g[1].cam, 7.5, 0, 1, eye, at);
    assert_true(fabs(eye[0] - (30 - 30 * 20.0 / 50)) < 1e-9 && fabs(eye[2] - (40 - 40 * 20.0 / 50)) < 1e-9);
    assert_true(at[0] < eye[0] && at[2] < eye[2]); /* looking along the leg, back to the start */

    /* open loop: request k is due at t0 + k / rate, however late the sender is */
    scn_sched sc;
    scn_sched_init(&sc, 10, 1000);
    assert_int_equal(scn_sched_due(&sc, 9.9), 0);
    assert_int_equal(scn_sched_due(&sc, 10), 1);
    assert_int_equal(scn_sched_due(&sc, 10.0995), 100);
    sc.next += 100;
    assert_int_equal(scn_sched_due(&sc, 10.0995), 0);
    /* the sender stalls 1 s: every request of the stall is due, each with its own time */
    uint64_t due = scn_sched_due(&sc, 11.0995);
    assert_int_equal(due, 1000);
    for (uint64_t k = 0; k < due; k++) assert_true(fabs(scn_sched_time(&sc, sc.next + k) - (10.1 + k * 1e-3)) < 1e-9);
}

/* `vantage bench --scenario` against a daemon; the CSV's row op. */
typedef struct csv_row {
    char op[64];
    double count, per_s, errors, unsent, pending, p50, p99;
} csv_row;

static bool csv_find(const char *path, const char *op, csv_row *out)
{
    FILE *f = fopen(path, "r");
    if (!f) return false;
    char line[512];
    bool found = false;
    while (!found && fgets(line, sizeof line, f)) {
        double mean, p90, p999, mx;
        if (sscanf(line, "%63[^,],%lf,%lf,%lf,%lf,%lf,%lf,%lf,%lf,%lf,%lf,%lf", out->op, &out->count, &out->per_s,
                   &out->errors, &out->unsent, &out->pending, &mean, &out->p50, &p90, &out->p99, &p999, &mx) == 12 &&
            !strcmp(out->op, op))
            found = true;
    }
    fclose(f);
    return found;
}

static void write_text(const char *path, const char *text)
{
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs(text, f);
    assert_int_equal(fclose(f), 0);
}

/* A bench run's files in a folder of their own: the scenario (its text
 * written) and the report that --json or --csv writes. */
typedef struct bench_files {
    tdir td;
    char scn[600], report[600];
} bench_files;

static void bench_files_make(bench_files *b, const char *text)
{
    tdir_make(&b->td, "vt-bench");
    snprintf(b->scn, sizeof b->scn, "%s", tdir_file(&b->td, "bench.scn"));
    write_text(b->scn, text);
    snprintf(b->report, sizeof b->report, "%s", tdir_file(&b->td, "report.out"));
}

/* Runs the scenario text against d (over its Unix socket if use_unix: the
 * daemon's pid comes from the peer credentials) with its report in
 * b->report (format: --json or --csv); what it printed in out; asserts
 * exit 0. */
static void bench_run(bench_files *b, const daemon_proc *d, bool use_unix, const char *text, const char *format,
                      char *out, size_t cap)
{
    bench_files_make(b, text);
    int rc = use_unix ? vantage_run(NULL, out, cap, "-s %s bench --scenario %s %s %s", d->sock, b->scn, format, b->report)
                      : vantage_run(d, out, cap, "bench --scenario %s %s %s", b->scn, format, b->report);
    if (rc != 0) fail_msg("bench: exit %d: %s", rc, out);
}

static void test_bench_open_loop_keeps_rate(void **state)
{
    char out[8192];
    bench_files b;
    /* 4 clients x 250/s for 3 s after a 0.5 s warm-up; a closed-loop group beside them */
    bench_run(&b, *state, false,
              "name rate\nduration 3.5\nwarmup 0.5\n"
              "group fixed\n role query\n clients 4\n op ping\n rate 250\n"
              "group busy\n role query\n clients 2\n op query views 2 count-only\n pipeline 2\n",
              "--csv", out, sizeof out);
    const char *csv = b.report;
    assert_non_null(strstr(out, "fixed.ping"));
    csv_row row;
    assert_true(csv_find(csv, "fixed.ping", &row));
    /* requests are due at fixed times: the measured 3 s hold 3000 of them, answered or still pending */
    double asked = row.count + row.pending + row.unsent;
    if (fabs(asked - 3000) > 3000 * 0.02 || row.errors != 0)
        fail_msg("open loop: %.0f asked (%.0f answered, %.0f pending), want 3000 +- 2 %%\n%s", asked, row.count,
                 row.pending, out);
    assert_true(row.per_s > 900 && row.per_s < 1100);
    assert_true(csv_find(csv, "busy.query", &row));
    assert_true(row.count > 0 && row.errors == 0);
    tdir_remove(&b.td);
}

static void test_bench_daemon_goes_away(void **state)
{
    (void)state;
    daemon_proc d;
    daemon_start(&d, NULL);
    char cmd[2048], out[8192];
    bench_files b;
    bench_files_make(&b,
                     "name gone\nduration 30\nsetup entities 100\nprobe edit-to-query every 0.1\n"
                     "group q\n role query\n clients 2\n op ping\n rate 100\n"
                     "group v\n role viewer\n clients 1\n op frames size 64x64 fps 30\n");
    const char *js = b.report;
    snprintf(cmd, sizeof cmd, "%s/vantage -p %d bench --scenario %s --json %s 2>&1", bin_dir(), d.port, b.scn, js);
    double t0 = test_now_s();
    FILE *p = popen(cmd, "r");
    assert_non_null(p);
    usleep(1500 * 1000);
    kill(d.pid, SIGKILL);
    int st;
    waitpid(d.pid, &st, 0);
    unlink(d.sock);
    size_t n = fread(out, 1, sizeof out - 1, p);
    out[n] = 0;
    st = pclose(p);
    double took = test_now_s() - t0;
    /* it ends at once, not at 30 s, with what it measured, marked partial, exit 3 (the connection) */
    if (took > 10) fail_msg("bench took %.1f s after its daemon went away", took);
    assert_true(WIFEXITED(st));
    assert_int_equal(WEXITSTATUS(st), 3);
    assert_non_null(strstr(out, "PARTIAL"));
    assert_non_null(strstr(out, "q.ping"));
    FILE *f = fopen(js, "r");
    assert_non_null(f);
    char j[8192];
    n = fread(j, 1, sizeof j - 1, f);
    j[n] = 0;
    fclose(f);
    assert_non_null(strstr(j, "\"partial\": true"));
    assert_non_null(strstr(j, "\"q.ping\""));
    tdir_remove(&b.td);
}

static void test_bench_cli_errors(void **state)
{
    daemon_proc *d = *state;
    tdir td;
    tdir_make(&td, "vt-bench");
    char scn[600], out[8192];
    snprintf(scn, sizeof scn, "%s", tdir_file(&td, "bad.scn"));
    write_text(scn, "name bad\ngroup a\n role viewer\n clients 3\n op query views 0\n");
    assert_int_equal(vantage_run(d, out, sizeof out, "bench --scenario %s", scn), 2);
    if (!strstr(out, "bad.scn:5: field 'views': 0 is outside 1..32")) fail_msg("%s", out);
    assert_int_equal(vantage_run(d, out, sizeof out, "bench --scenario no-such-scenario"), 2);
    assert_non_null(strstr(out, "no-such-scenario: no such file"));
    /* a shipped scenario by name, cut short; the scene is left as it was found */
    vtc_client *c = connect_role(d, VP_ROLE_VIEWER, false);
    vp_stats_reply before, after;
    assert_int_equal(vtc_stats(c, &before), 0);
    int rc = vantage_run(d, out, sizeof out, "bench --scenario destruction-barrage --seconds 3");
    if (rc != 0) fail_msg("bench: exit %d: %s", rc, out);
    assert_non_null(strstr(out, "destroy "));
    assert_non_null(strstr(out, "commanders.input_to_frame"));
    assert_int_equal(vtc_stats(c, &after), 0);
    assert_int_equal(after.entities, before.entities);
    vtc_close(c);
    tdir_remove(&td);
}

/* The daemon's memory per tenth of a short run: sampled once a second, so
 * most tenths of a 2 s run have no sample; they print '-' (null in JSON),
 * not 0.0 as if the daemon had given its memory back. */
static void test_bench_memory_tenths_unsampled(void **state)
{
    char out[8192];
    bench_files b;
    bench_run(&b, *state, true, "name mem\nduration 2\ngroup q\n role query\n clients 1\n op ping\n rate 50\n", "--json",
              out, sizeof out);
    const char *js = b.report;
    const char *row = strstr(out, "max MiB per tenth");
    if (!row) fail_msg("no memory row: %s", out);
    int dashes = 0, samples = 0;
    const char *p = row + strlen("max MiB per tenth");
    for (int w = 0; w < 10; w++) {
        char tok[32];
        int n = 0;
        if (sscanf(p, " %31s%n", tok, &n) != 1) fail_msg("the row has %d tenths: %s", w, row);
        p += n;
        if (!strcmp(tok, "-")) dashes++;
        else if (atof(tok) > 0) samples++;
        else fail_msg("tenth %d: '%s' (no sample must print '-'): %s", w, tok, row);
    }
    assert_true(dashes >= 5 && samples >= 1); /* one sample a second over 2 s */
    FILE *f = fopen(js, "r");
    assert_non_null(f);
    char j[8192];
    size_t n = fread(j, 1, sizeof j - 1, f);
    j[n] = 0;
    fclose(f);
    const char *m = strstr(j, "\"max_by_tenth\": [");
    assert_non_null(m);
    assert_non_null(strstr(m, "null"));
    assert_null(strstr(m, " 0.00"));
    tdir_remove(&b.td);
}

const struct CMUnitTest bench_tests[] = {
    cmocka_unit_test(test_bench_hist_distributions),
    cmocka_unit_test(test_bench_hist_buckets),
    cmocka_unit_test(test_bench_scenarios_shipped),
    TEST_ROWS(test_bench_scenario_errors, bad_scenarios),
    cmocka_unit_test(test_bench_scenario_nul_and_missing),
    cmocka_unit_test(test_bench_camera_and_schedule),
    DAEMON_TEST(test_bench_open_loop_keeps_rate),
    cmocka_unit_test(test_bench_daemon_goes_away),
    DAEMON_TEST(test_bench_cli_errors),
    DAEMON_TEST(test_bench_memory_tenths_unsampled),
};
const size_t bench_tests_count = sizeof bench_tests / sizeof bench_tests[0];
