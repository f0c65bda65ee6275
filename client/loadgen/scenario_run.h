/*
 * scenario_run.h — what the parts of `vantage bench --scenario` share: the
 * run (its clock, stop flag, failure), the per-thread histogram rows, the
 * report. cli_scenario.c: the command and the load threads;
 * scenario_events.c: setup, the timeline and the end-to-end probes;
 * scenario_report.c: the daemon's memory and the tables, JSON and CSV.
 */
#ifndef VANTAGE_SCENARIO_RUN_H
#define VANTAGE_SCENARIO_RUN_H

#include "cli.h"
#include "lat_hist.h"
#include "scenario.h"
#include "splitmix.h" /* entity placement, destruction targets */

#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>

/* What the tables have a row for: the probes and events, then two per
 * group: its requests' latency (query, edit, ping) or its frames'
 * interval, and for commanders input -> frame. */
enum row { R_EDIT_QUERY, R_EDIT_FRAME, R_SL_LOAD, R_SL_UNLOAD, R_DESTROY, R_FIXED };
#define R_MAIN(g) (R_FIXED + 2 * (g))
#define R_INPUT(g) (R_FIXED + 2 * (g) + 1)
#define R_MAX (R_FIXED + 2 * SCN_MAX_GROUPS)
#define WINDOWS 10 /* for the drift: each row also per tenth of the measured time */

/* Histograms of one thread (merged at the end); n rows. */
typedef struct rows {
    int n;
    scn_hist *h;   /* [n] */
    scn_hist *win; /* [n][WINDOWS] */
    uint64_t errors[R_MAX], unsent[R_MAX], pending[R_MAX]; /* pending: no reply by the end */
} rows;

typedef struct run run;

struct run {
    cli *k;
    const scenario *s;
    double t0, t_meas, t_end; /* start, start of measuring (after warm-up), planned end */
    atomic_int stop;          /* 1: end; set by the main thread or on a failure */
    atomic_int gone;          /* the daemon went away */
    char why[400];            /* the first failure */
    pthread_mutex_t mu;
    atomic_uint_fast64_t issued;            /* request ops begun (for `requests`) */
    atomic_uint_fast64_t done[SCN_MAX_GROUPS], errs[SCN_MAX_GROUPS], frames[SCN_MAX_GROUPS];
    rows *ev_rows, *probe_rows;
};

typedef struct report {
    rows all;
    char name[R_MAX][48];
    double secs;
    double rss0, rss1, rssmax;
    double rss_win[WINDOWS]; /* the largest sample in each tenth (0: none) */
    int nrss;
    bool partial;
} report;

typedef struct events_arg {
    run *r;
    vtc_client *c;
    bool loaded[SCN_MAX_EVENTS];
} events_arg;

typedef struct probe_arg {
    run *r;
    vtc_client *ed, *q, *fr; /* editor, query, frames (each NULL when its probe is off) */
} probe_arg;

#define SETUP_BASE 0x7C0000000000ull
#define LOAD_BASE 0x7D0000000000ull
#define PROBE_ID 0x7E0000000001ull


/* cli_scenario.c */
void fail_run(run *r, bool gone, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
bool stopping(run *r);
int rows_init(rows *w, int n);
void rows_free(rows *w);
void rows_merge(rows *into, const rows *from);
/* A latency (seconds) of row for an operation that began at t_begin. */
void note(run *r, rows *w, int row, double t_begin, double secs);

/* scenario_events.c */
int add_many(vtc_client *c, uint64_t base, uint32_t n, double spread, double height, uint16_t sublevel, uint64_t seed);
int remove_range(vtc_client *c, uint64_t base, uint32_t n);
void *events_thread(void *arg); /* events_arg */
void *probe_thread(void *arg);  /* probe_arg */
void probe_view(vp_view *v, uint16_t w, uint16_t h);

/* scenario_report.c */
int daemon_pid(vtc_client *c);
double rss_mib(int pid);
void row_names(const scenario *s, report *rp);
void print_table(FILE *o, const run *r, const report *rp);
int write_out(const char *path, const run *r, const report *rp, bool json);

#endif
