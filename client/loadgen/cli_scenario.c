/*
 * cli_scenario.c — `vantage bench --scenario FILE`: runs a scripted mix of
 * clients (scenario.h) against a daemon and reports, per operation,
 * throughput and latency percentiles from log-bucket histograms (lat_hist.h).
 *
 * Threads: the load threads each drive their share of the clients from one
 * poll() loop (requests pipelined or scheduled, frames received, commander
 * re-aims); the probe thread measures edit -> visible in a query and in a
 * frame on connections of its own; the events thread runs the timeline
 * (sub-level loads and unloads, destruction); the main thread prints the
 * progress line, samples the daemon's memory, and stops everything at the
 * end, or when the daemon goes away (the report is then marked partial).
 * This file: the command and the load threads; the probe and events
 * threads are in scenario_events.c, the report in scenario_report.c.
 */
#include "scenario_run.h"
#include "vp_grow.h"

#include <errno.h>
#include <math.h>
#include <poll.h>
#include <stdarg.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#ifndef VANTAGE_SCENARIO_DIR
#define VANTAGE_SCENARIO_DIR "client/loadgen/scenarios"
#endif

#define RING 4096 /* requests in flight per connection (open loop: beyond it, counted as not sent) */

typedef struct lconn {
    vtc_client *c;
    const scn_group *g;
    int gi, idx;
    scn_sched sched;
    uint64_t sent;
    uint32_t inflight;
    double t_int[RING];     /* the request's intended (open) or actual (closed) send time, by req % RING */
    uint32_t req_of[RING];
    vp_entity *ents;        /* edit: its own */
    uint8_t *out;
    size_t outlen, outcap;
    /* frames */
    uint32_t sub_req;
    double last_frame, next_reaim;
    uint16_t seq, shown_seq;
    bool shown_any;
    double seq_t[256];
} lconn;

typedef struct lthread {
    run *r;
    lconn *cs;
    int n;
    rows *rw;
    pthread_t th;
} lthread;

void fail_run(run *r, bool gone, const char *fmt, ...)
{
    pthread_mutex_lock(&r->mu);
    if (!r->why[0]) {
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(r->why, sizeof r->why, fmt, ap);
        va_end(ap);
    }
    pthread_mutex_unlock(&r->mu);
    if (gone) atomic_store(&r->gone, 1);
    atomic_store(&r->stop, 1);
}

bool stopping(run *r)
{
    return atomic_load_explicit(&r->stop, memory_order_relaxed);
}

int rows_init(rows *w, int n)
{
    memset(w, 0, sizeof *w);
    w->n = n;
    w->h = malloc(sizeof *w->h * (size_t)n);
    w->win = malloc(sizeof *w->win * (size_t)n * WINDOWS);
    if (!w->h || !w->win) return -1;
    for (int i = 0; i < n; i++) scn_hist_init(&w->h[i]);
    for (int i = 0; i < n * WINDOWS; i++) scn_hist_init(&w->win[i]);
    return 0;
}

void rows_free(rows *w)
{
    free(w->h);
    free(w->win);
}

void rows_merge(rows *into, const rows *from)
{
    for (int j = 0; j < into->n; j++) {
        scn_hist_merge(&into->h[j], &from->h[j]);
        into->errors[j] += from->errors[j];
        into->unsent[j] += from->unsent[j];
        into->pending[j] += from->pending[j];
    }
    for (int j = 0; j < into->n * WINDOWS; j++) scn_hist_merge(&into->win[j], &from->win[j]);
}

void note(run *r, rows *w, int row, double t_begin, double secs)
{
    if (t_begin < r->t_meas) return;
    uint64_t ns = secs > 0 ? (uint64_t)(secs * 1e9) : 0;
    scn_hist_record(&w->h[row], ns);
    double span = r->t_end - r->t_meas;
    int win = span > 0 ? (int)((t_begin - r->t_meas) / span * WINDOWS) : 0;
    scn_hist_record(&w->win[row * WINDOWS + (win < 0 ? 0 : win >= WINDOWS ? WINDOWS - 1 : win)], ns);
}

static vtc_connect_opts conn_opts(run *r, int role, const char *name)
{
    vtc_connect_opts o = r->k->co;
    o.role = role;
    o.name = name;
    return o;
}

static int proto_role(enum scn_role r)
{
    return r == SCN_ROLE_EDITOR ? VP_ROLE_EDITOR : r == SCN_ROLE_COMMANDER ? VP_ROLE_COMMANDER : VP_ROLE_VIEWER;
}


/* ---- the view of a client ---------------------------------------------------------- */

static bool make_view(const scn_group *g, double t, int idx, uint16_t w, uint16_t h, vp_view *v)
{
    double eye[3], at[3];
    scn_camera_at(&g->cam, t, idx, (int)g->clients, eye, at);
    if (g->cam.kind == SCN_CAM_PAN) {
        const double up[3] = {0, 0, 1};
        double hh = g->cam.height * 0.5; /* half the height seen: a 53-degree field */
        return vtc_view_ortho(v, eye, at, up, 2 * hh * w / h, 2 * hh, w, h, 0.5, g->cam.height * 2 + 100);
    }
    const double up[3] = {0, 1, 0};
    return vtc_view_perspective(v, eye, at, up, 60, w, h, 0.5, 3000);
}

/* ---- load threads ------------------------------------------------------------------- */

static uint8_t *out_room(lconn *lc, size_t n)
{
    if (lc->outcap - lc->outlen < n) {
        size_t cap = n <= SIZE_MAX - lc->outlen ? vp_grow_cap(lc->outcap, lc->outlen + n, 4096, 1, SIZE_MAX) : 0;
        uint8_t *p = cap ? realloc(lc->out, cap) : NULL;
        if (!p) return NULL;
        lc->out = p;
        lc->outcap = cap;
    }
    return lc->out + lc->outlen;
}

/* Encodes one request of lc's op, to be sent at the next flush. t_int is
 * when it counts from. */
static int queue_request(run *r, lconn *lc, double t_int)
{
    const scn_group *g = lc->g;
    size_t need = VP_HEADER_SIZE + 64;
    if (g->op == SCN_EDIT) need += vp_size_entities(g->batch);
    if (g->op == SCN_QUERY) need += (size_t)g->views * VP_VIEW_SIZE;
    uint8_t *p = out_room(lc, need);
    if (!p) return -1;
    vp_writer w;
    vp_writer_init(&w, p, need);
    uint32_t req = vtc_next_req(lc->c);
    if (g->op == SCN_EDIT) {
        for (uint32_t e = 0; e < g->batch; e++) lc->ents[e].sphere[1] = 1 + (double)(lc->sent % 100) * 0.1;
        vp_enc_entities(&w, VP_ENTITY_UPDATE, req, lc->ents, g->batch);
    } else if (g->op == SCN_PING) {
        vp_enc_ping(&w, VP_PING, req, (const uint8_t *)"b", 1);
    } else {
        vp_view views[VP_MAX_VIEWS];
        double t = t_int - r->t0;
        for (uint32_t v = 0; v < g->views; v++)
            if (!make_view(g, t + v * 0.37, lc->idx, 1280, 720, &views[v])) return -1;
        vp_enc_vis_query(&w, req, g->qflags, 0, views, g->views);
    }
    lc->outlen += w.len;
    lc->t_int[req % RING] = t_int;
    lc->req_of[req % RING] = req;
    lc->inflight++;
    lc->sent++;
    return 0;
}

static int queue_subscribe(run *r, lconn *lc, double now)
{
    const scn_group *g = lc->g;
    vp_frame_sub fs = {.r = {.format = g->format, .quality = g->format == VP_FRAME_JPEG ? g->quality : 0,
                             .renderer = g->renderer},
                       .max_fps = g->fps, .view_seq = ++lc->seq};
    if (!make_view(g, now - r->t0, lc->idx, g->w, g->h, &fs.r.view)) return -1;
    uint8_t *p = out_room(lc, VP_HEADER_SIZE + VP_FRAME_SUB_SIZE);
    if (!p) return -1;
    vp_writer w;
    vp_writer_init(&w, p, VP_HEADER_SIZE + VP_FRAME_SUB_SIZE);
    lc->sub_req = vtc_next_req(lc->c);
    vp_enc_frame_sub(&w, lc->sub_req, &fs);
    lc->outlen += w.len;
    lc->seq_t[lc->seq % 256] = now;
    return 0;
}

/* May a new request begin (the `requests` limit)? */
static bool may_issue(run *r)
{
    if (!r->s->requests) return true;
    if (atomic_fetch_add(&r->issued, 1) < r->s->requests) return true;
    atomic_fetch_sub(&r->issued, 1);
    return false;
}

/* Sends what is due on lc at now. */
static int pump(run *r, lthread *t, lconn *lc, double now)
{
    const scn_group *g = lc->g;
    if (g->op == SCN_FRAMES) return 0;
    if (g->op == SCN_COMMANDER) {
        if (now >= lc->next_reaim) {
            lc->next_reaim += 1.0 / g->reaim_hz;
            if (lc->next_reaim < now) lc->next_reaim = now + 1.0 / g->reaim_hz; /* late: no burst */
            return queue_subscribe(r, lc, now);
        }
        return 0;
    }
    if (g->rate > 0) {
        uint64_t due = scn_sched_due(&lc->sched, now);
        for (uint64_t i = 0; i < due; i++) {
            double ti = scn_sched_time(&lc->sched, lc->sched.next++);
            if (lc->inflight >= RING) {
                if (ti >= r->t_meas) t->rw->unsent[R_MAIN(lc->gi)]++;
                continue;
            }
            if (!may_issue(r)) break;
            if (queue_request(r, lc, ti)) return -1;
        }
        return 0;
    }
    while (lc->inflight < g->pipeline && may_issue(r))
        if (queue_request(r, lc, now)) return -1;
    return 0;
}

static int flush(lconn *lc)
{
    if (!lc->outlen) return 0;
    int rc = vtc_send(lc->c, lc->out, lc->outlen);
    lc->outlen = 0;
    return rc;
}

/* A frame came: interval, and for a commander the input -> frame latency
 * of every view up to the one it was drawn for. */
static void got_frame(run *r, lthread *t, lconn *lc, const vp_frame *f, double now)
{
    if (lc->last_frame > 0) note(r, t->rw, R_MAIN(lc->gi), lc->last_frame, now - lc->last_frame);
    lc->last_frame = now;
    atomic_fetch_add_explicit(&r->frames[lc->gi], 1, memory_order_relaxed);
    if (lc->g->op != SCN_COMMANDER) return;
    if (!lc->shown_any) {
        lc->shown_any = true;
        lc->shown_seq = (uint16_t)(f->view_seq - 1);
    }
    uint16_t ahead = (uint16_t)(f->view_seq - lc->shown_seq);
    if (ahead == 0 || ahead > 255) return;
    for (uint16_t i = 0; i < ahead; i++) {
        uint16_t s = (uint16_t)(f->view_seq - i);
        double ts = lc->seq_t[s % 256];
        if (ts > 0) note(r, t->rw, R_INPUT(lc->gi), ts, now - ts);
        lc->seq_t[s % 256] = 0;
    }
    lc->shown_seq = f->view_seq;
}

/* Reads what lc has. -1: the connection failed (the daemon went away). */
static int drain(run *r, lthread *t, lconn *lc)
{
    for (;;) {
        vp_header h;
        const uint8_t *pl;
        int rc = vtc_recv(lc->c, &h, &pl, 0);
        if (rc == VP_NEED_MORE) return 0;
        if (rc) {
            fail_run(r, true, "group %s client %d: %s", lc->g->name, lc->idx, vtc_last_error(lc->c)->msg);
            return -1;
        }
        double now = now_s();
        if (h.type == VP_FRAME) {
            vp_frame f;
            if (vp_dec_frame(pl, h.len, &f) == 0) got_frame(r, t, lc, &f, now);
            continue;
        }
        if (h.type == VP_EVENT || h.type == VP_MARKED) continue;
        if (lc->g->op == SCN_FRAMES || lc->g->op == SCN_COMMANDER) {
            if (h.type == VP_ERROR) {
                vp_error e;
                int ml = 1;
                const char *m = "?";
                if (vp_dec_error(pl, h.len, &e) == 0) m = (const char *)e.msg, ml = e.msg_len;
                t->rw->errors[lc->g->op == SCN_COMMANDER ? R_INPUT(lc->gi) : R_MAIN(lc->gi)]++;
                atomic_fetch_add_explicit(&r->errs[lc->gi], 1, memory_order_relaxed);
                if (h.req == lc->sub_req || lc->g->op == SCN_FRAMES) {
                    fail_run(r, false, "group %s client %d: the frame stream ended: %.*s", lc->g->name, lc->idx, ml < 300 ? ml : 300, m);
                    return -1;
                }
            }
            continue; /* ACKs of the subscription */
        }
        uint32_t slot = h.req % RING;
        if (lc->req_of[slot] != h.req || !lc->inflight) continue; /* not ours */
        lc->req_of[slot] = 0;
        lc->inflight--;
        int row = R_MAIN(lc->gi);
        if (h.type == VP_ERROR) {
            if (lc->t_int[slot] >= r->t_meas) t->rw->errors[row]++;
            atomic_fetch_add_explicit(&r->errs[lc->gi], 1, memory_order_relaxed);
        } else {
            note(r, t->rw, row, lc->t_int[slot], now - lc->t_int[slot]);
        }
        atomic_fetch_add_explicit(&r->done[lc->gi], 1, memory_order_relaxed);
    }
}

static int lconn_open(run *r, lconn *lc)
{
    const scn_group *g = lc->g;
    char err[300];
    vtc_connect_opts o = conn_opts(r, proto_role(g->role), "vantage-bench");
    if (vtc_connect(&o, &lc->c, err, sizeof err)) {
        fail_run(r, true, "group %s: cannot connect: %s", g->name, err);
        return -1;
    }
    if (g->op == SCN_EDIT) {
        uint64_t base = 0x7B0000000000ull + (uint64_t)lc->gi * 0x100000000ull + (uint64_t)lc->idx * 0x100000ull;
        lc->ents = calloc(g->batch, sizeof *lc->ents);
        if (!lc->ents) return fail_run(r, false, "out of memory"), -1;
        uint64_t x = base;
        for (uint32_t e = 0; e < g->batch; e++)
            lc->ents[e] = (vp_entity){.id = base + e, .flags = VP_ENT_DYNAMIC,
                                      .sphere = {(splitmix_unit(&x) - 0.5) * 400, 1, (splitmix_unit(&x) - 0.5) * 400, 0.5}};
        uint32_t max = vtc_server(lc->c)->max_batch;
        for (uint32_t i = 0; i < g->batch; i += max) {
            uint32_t n = g->batch - i < max ? g->batch - i : max;
            if (vtc_add(lc->c, lc->ents + i, n, NULL, NULL)) {
                fail_run(r, false, "group %s: adding its entities: %s", g->name, vtc_last_error(lc->c)->msg);
                return -1;
            }
        }
    }
    return 0;
}

static void lconn_close(lconn *lc)
{
    if (lc->c && lc->ents && lc->g->op == SCN_EDIT) {
        uint64_t *ids = malloc(sizeof *ids * lc->g->batch);
        if (ids) {
            for (uint32_t e = 0; e < lc->g->batch; e++) ids[e] = lc->ents[e].id;
            uint32_t max = vtc_server(lc->c)->max_batch;
            for (uint32_t i = 0; i < lc->g->batch; i += max)
                (void)vtc_remove(lc->c, ids + i, lc->g->batch - i < max ? lc->g->batch - i : max, NULL);
            free(ids);
        }
    }
    vtc_close(lc->c);
    free(lc->ents);
    free(lc->out);
}

static void *load_thread(void *arg)
{
    lthread *t = arg;
    run *r = t->r;
    struct pollfd *pf = calloc((size_t)t->n, sizeof *pf);
    if (!pf) {
        fail_run(r, false, "out of memory");
        return NULL;
    }
    double start = r->t0;
    for (int i = 0; i < t->n; i++) {
        lconn *lc = &t->cs[i];
        /* open-loop clients of a group spread over one period; re-aims too */
        double phase = lc->g->clients ? (double)lc->idx / lc->g->clients : 0;
        scn_sched_init(&lc->sched, start + (lc->g->rate > 0 ? phase / lc->g->rate : 0), lc->g->rate);
        lc->next_reaim = start + phase / lc->g->reaim_hz;
        pf[i] = (struct pollfd){.fd = vtc_fd(lc->c), .events = POLLIN};
        if (lc->g->op == SCN_FRAMES && (queue_subscribe(r, lc, now_s()) || flush(lc))) {
            fail_run(r, true, "group %s: subscribing: %s", lc->g->name, vtc_last_error(lc->c)->msg);
            break;
        }
    }
    while (!stopping(r)) {
        double now = now_s(), wake = now + 0.05;
        for (int i = 0; i < t->n && !stopping(r); i++) {
            lconn *lc = &t->cs[i];
            if (pump(r, t, lc, now) || flush(lc)) {
                fail_run(r, true, "group %s client %d: sending: %s", lc->g->name, lc->idx, vtc_last_error(lc->c)->msg);
                break;
            }
            if (lc->g->op == SCN_COMMANDER && lc->next_reaim < wake) wake = lc->next_reaim;
            if (lc->g->rate > 0) {
                double nt = scn_sched_time(&lc->sched, lc->sched.next);
                if (nt < wake) wake = nt;
            }
        }
        if (r->s->requests) { /* all issued and answered: the run is over */
            bool idle = atomic_load(&r->issued) >= r->s->requests;
            for (int i = 0; idle && i < t->n; i++) idle = t->cs[i].inflight == 0 || t->cs[i].g->op >= SCN_FRAMES;
            if (idle) break;
        }
        int ms = (int)ceil((wake - now_s()) * 1e3);
        int pr = poll(pf, (nfds_t)t->n, ms < 0 ? 0 : ms);
        if (pr < 0 && errno != EINTR) {
            fail_run(r, false, "poll: %s", strerror(errno));
            break;
        }
        for (int i = 0; pr > 0 && i < t->n; i++)
            if (pf[i].revents && drain(r, t, &t->cs[i])) break;
    }
    for (int i = 0; i < t->n; i++) /* asked, not answered: reported, not forgotten */
        for (uint32_t k = 0; t->cs[i].inflight && k < RING; k++)
            if (t->cs[i].req_of[k] && t->cs[i].t_int[k] >= r->t_meas) t->rw->pending[R_MAIN(t->cs[i].gi)]++;
    free(pf);
    return NULL;
}

/* ---- the command ------------------------------------------------------------------- */

/* FILE as given, else NAME or NAME.scn among the scenarios shipped. */
static int find_scenario(const char *arg, scenario *s, char *err, size_t errlen)
{
    if (access(arg, F_OK) == 0) return scn_load(arg, s, err, errlen);
    const char *base = strrchr(arg, '/') ? strrchr(arg, '/') + 1 : arg;
    char share[1024] = "";
    ssize_t n = readlink("/proc/self/exe", share, sizeof share - 40);
    if (n > 0) { /* PREFIX/bin/vantage -> PREFIX/share/vantage/scenarios */
        share[n] = 0;
        char *slash = strrchr(share, '/');
        if (slash) strcpy(slash, "/../share/vantage/scenarios");
    }
    const char *dirs[] = {getenv("VANTAGE_SCENARIOS"), share, VANTAGE_SCENARIO_DIR};
    for (int d = 0; d < 3; d++) {
        if (!dirs[d] || !*dirs[d]) continue;
        char path[1024];
        snprintf(path, sizeof path, "%s/%s", dirs[d], base);
        if (access(path, F_OK) == 0) return scn_load(path, s, err, errlen);
        snprintf(path, sizeof path, "%s/%s.scn", dirs[d], base);
        if (access(path, F_OK) == 0) return scn_load(path, s, err, errlen);
    }
    snprintf(err, errlen, "%s: no such file, and no scenario of that name in %s", arg, VANTAGE_SCENARIO_DIR);
    return -1;
}

int bench_scenario(cli *k, int argc, char **argv)
{
    const char *file = NULL, *json_path = NULL, *csv_path = NULL;
    double seconds = 0;
    uint64_t threads = 1, pid = 0, requests = 0;
    int progress = -1;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (!strcmp(a, "--scenario") && v) file = v, i++;
        else if (!strcmp(a, "--json") && v) json_path = v, i++;
        else if (!strcmp(a, "--csv") && v) csv_path = v, i++;
        else if (!strcmp(a, "--progress")) progress = 1;
        else if (!strcmp(a, "--no-progress")) progress = 0;
        else if (!strcmp(a, "--seconds") && v) {
            char *end;
            seconds = strtod(v, &end);
            if (*end || !(seconds >= 0.1 && seconds <= 7 * 86400)) return die_usage("bench: --seconds %s: expected 0.1..604800", v);
            i++;
        } else if (!strcmp(a, "--threads") && v) {
            if (!parse_u64(v, &threads) || threads < 1 || threads > 64) return die_usage("bench: --threads %s: expected 1..64", v);
            i++;
        } else if (!strcmp(a, "--requests") && v) {
            if (!parse_u64(v, &requests) || requests < 1) return die_usage("bench: --requests %s: expected a count", v);
            i++;
        } else if (!strcmp(a, "--daemon-pid") && v) {
            if (!parse_u64(v, &pid) || pid < 1 || pid > 1u << 30) return die_usage("bench: --daemon-pid %s: expected a pid", v);
            i++;
        } else {
            return die_usage("bench --scenario FILE [--seconds S] [--requests N] [--threads T] [--json FILE|-] "
                             "[--csv FILE|-] [--progress|--no-progress] [--daemon-pid PID]: unexpected %s", a);
        }
    }
    scenario *s = calloc(1, sizeof *s);
    run *r = calloc(1, sizeof *r);
    report *rp = calloc(1, sizeof *rp);
    rows *rw = calloc(threads + 2, sizeof *rw);
    uint64_t nthreads_rows = threads + 2;
    lconn *cs = NULL;
    lthread *ts = calloc(threads, sizeof *ts);
    if (!s || !r || !rp || !rw || !ts) {
        fprintf(stderr, "%s: bench: out of memory\n", g_prog);
        free(s), free(r), free(rp), free(rw), free(ts);
        return 1;
    }
    char err[600];
    int rc = 0;
    uint32_t total = 0;
    vtc_client *setup = NULL, *evc = NULL;
    probe_arg pa = {.r = r};
    events_arg *ea = calloc(1, sizeof *ea);
    if (!ea || find_scenario(file, s, err, sizeof err)) {
        fprintf(stderr, "%s: bench: %s\n", g_prog, ea ? err : "out of memory");
        rc = 2;
        goto out;
    }
    if (seconds > 0) s->duration = seconds, s->requests = 0;
    if (requests) s->requests = requests;
    if (s->requests) {
        bool any = false;
        for (int g = 0; g < s->ng; g++) any |= s->g[g].op <= SCN_PING;
        if (!any) {
            fprintf(stderr, "%s: bench: %s: a request count counts query, edit and ping operations; this scenario "
                            "has none (give it a duration)\n", g_prog, file);
            rc = 2;
            goto out;
        }
    }
    if (s->requests && s->warmup > 0) s->warmup = 0; /* a count is all measured */
    if (s->warmup >= s->duration) { /* --seconds shorter than the file's warm-up */
        fprintf(stderr, "%s: bench: the warm-up (%g s) is not shorter than the run: measuring all of it\n", g_prog,
                s->warmup);
        s->warmup = 0;
    }
    r->k = k;
    r->s = s;
    pthread_mutex_init(&r->mu, NULL);
    int nrows = R_FIXED + 2 * s->ng;
    for (uint64_t i = 0; i < nthreads_rows; i++)
        if (rows_init(&rw[i], nrows)) {
            fprintf(stderr, "%s: bench: out of memory\n", g_prog);
            rc = 1;
            goto out;
        }
    row_names(s, rp);
    r->ev_rows = &rw[threads];
    r->probe_rows = &rw[threads + 1];

    /* setup: the entities edits and destruction work on; the probe entity */
    vtc_connect_opts so = conn_opts(r, VP_ROLE_EDITOR, "vantage-bench-setup");
    bool need_editor = s->setup_n || s->nev || s->probe_query > 0 || s->probe_frame > 0;
    if (need_editor && vtc_connect(&so, &setup, err, sizeof err)) {
        fprintf(stderr, "%s: bench: cannot connect: %s\n", g_prog, err);
        rc = 3;
        goto out;
    }
    double ts0 = now_s();
    if (s->setup_n && (rc = add_many(setup, SETUP_BASE, s->setup_n, s->setup_spread, s->setup_height, 0, s->seed))) {
        rc = server_fail(&(cli){.c = setup}, "bench setup", rc);
        goto out;
    }
    if (s->setup_n) fprintf(stderr, "setup: %u entities in %.2f s\n", s->setup_n, now_s() - ts0);
    if (s->probe_query > 0 || s->probe_frame > 0) {
        vp_entity pe = {.id = PROBE_ID, .flags = VP_ENT_DYNAMIC, .sphere = {30000, -5200, 0, 5}};
        if ((rc = vtc_add(setup, &pe, 1, NULL, NULL))) {
            rc = server_fail(&(cli){.c = setup}, "bench probe", rc);
            goto out;
        }
        pa.ed = setup;
        vtc_connect_opts po = conn_opts(r, VP_ROLE_VIEWER, "vantage-bench-probe");
        if ((s->probe_query > 0 && vtc_connect(&po, &pa.q, err, sizeof err)) ||
            (s->probe_frame > 0 && vtc_connect(&po, &pa.fr, err, sizeof err))) {
            fprintf(stderr, "%s: bench: cannot connect: %s\n", g_prog, err);
            rc = 3;
            goto out;
        }
        if (pa.fr) {
            vp_frame_sub fs = {.r = {.format = VP_FRAME_JPEG, .quality = 50, .renderer = VP_RENDERER_SOFT},
                               .max_fps = VP_FRAME_SUB_MAX_FPS};
            probe_view(&fs.r.view, 64, 64);
            if ((rc = vtc_frame_subscribe(pa.fr, &fs))) {
                rc = server_fail(&(cli){.c = pa.fr}, "bench probe", rc);
                goto out;
            }
        }
    }
    if (s->nev) {
        vtc_connect_opts eo = conn_opts(r, VP_ROLE_EDITOR, "vantage-bench-events");
        if (vtc_connect(&eo, &evc, err, sizeof err)) {
            fprintf(stderr, "%s: bench: cannot connect: %s\n", g_prog, err);
            rc = 3;
            goto out;
        }
    }

    /* the clients, dealt round-robin over the load threads */
    for (int g = 0; g < s->ng; g++) total += s->g[g].clients;
    cs = calloc(total, sizeof *cs);
    if (!cs) {
        fprintf(stderr, "%s: bench: out of memory\n", g_prog);
        rc = 1;
        goto out;
    }
    uint32_t n = 0;
    for (int g = 0; g < s->ng; g++)
        for (uint32_t i = 0; i < s->g[g].clients; i++) cs[n++] = (lconn){.g = &s->g[g], .gi = g, .idx = (int)i};
    if (threads > total) threads = total;
    for (uint32_t i = 0; i < total && !stopping(r); i++) lconn_open(r, &cs[i]);
    if (stopping(r)) {
        fprintf(stderr, "%s: bench: %s\n", g_prog, r->why);
        rc = atomic_load(&r->gone) ? 3 : 1;
        goto out;
    }
    /* group the connections per thread: thread t takes every threads-th */
    lconn *sorted = calloc(total, sizeof *sorted);
    if (!sorted) {
        rc = 1;
        goto out;
    }
    uint32_t m = 0;
    for (uint64_t t = 0; t < threads; t++) {
        ts[t] = (lthread){.r = r, .cs = sorted + m, .rw = &rw[t]};
        for (uint32_t i = (uint32_t)t; i < total; i += (uint32_t)threads) sorted[m++] = cs[i], ts[t].n++;
    }
    free(cs);
    cs = sorted;

    int dpid = pid ? (int)pid : daemon_pid(cs[0].c);
    if (progress < 0) progress = isatty(2);
    r->t0 = now_s();
    r->t_meas = r->t0 + s->warmup;
    r->t_end = s->requests ? r->t0 + 7 * 86400.0 : r->t0 + s->duration;
    for (uint64_t t = 0; t < threads; t++) pthread_create(&ts[t].th, NULL, load_thread, &ts[t]);
    pthread_t pth, eth;
    bool probing = pa.q || pa.fr, eventing = evc != NULL;
    ea->r = r;
    ea->c = evc;
    if (probing) pthread_create(&pth, NULL, probe_thread, &pa);
    if (eventing) pthread_create(&eth, NULL, events_thread, ea);
    catch_sigint();
    double next_tick = r->t0 + 1;
    uint64_t last_done[SCN_MAX_GROUPS] = {0}, last_frames[SCN_MAX_GROUPS] = {0};
    double last_t = r->t0;
    rp->rssmax = 0;
    if (dpid) {
        rp->rss0 = rp->rssmax = rss_mib(dpid);
        if (rp->rss0 < 0) dpid = 0;
    }
    while (!stopping(r)) {
        double now = now_s();
        if (g_stop) fail_run(r, false, "interrupted");
        if (!s->requests && now >= r->t_end) break;
        if (s->requests) {
            bool all = atomic_load(&r->issued) >= s->requests;
            uint64_t done = 0;
            for (int g = 0; g < s->ng; g++) done += atomic_load(&r->done[g]);
            if (all && done >= s->requests) break;
        }
        if (now >= next_tick) {
            next_tick += 1;
            if (dpid) {
                double mb = rss_mib(dpid);
                if (mb >= 0) {
                    rp->rss1 = mb;
                    if (mb > rp->rssmax) rp->rssmax = mb;
                    rp->nrss++;
                    int w = (int)((now - r->t_meas) / (r->t_end - r->t_meas) * WINDOWS);
                    if (w >= 0 && w < WINDOWS && mb > rp->rss_win[w]) rp->rss_win[w] = mb;
                }
            }
            if (progress) {
                char line[512];
                int o = snprintf(line, sizeof line, "\r[%5.0f s%s]", now - r->t0, now < r->t_meas ? " warm-up" : "");
                uint64_t errs = 0;
                for (int g = 0; g < s->ng && o < (int)sizeof line - 64; g++) {
                    uint64_t d = atomic_load(&r->done[g]), f = atomic_load(&r->frames[g]);
                    errs += atomic_load(&r->errs[g]);
                    double dt = now - last_t;
                    if (s->g[g].op >= SCN_FRAMES)
                        o += snprintf(line + o, sizeof line - o, "  %s %.0f frames/s", s->g[g].name, (f - last_frames[g]) / dt);
                    else
                        o += snprintf(line + o, sizeof line - o, "  %s %.0f/s", s->g[g].name, (d - last_done[g]) / dt);
                    last_done[g] = d;
                    last_frames[g] = f;
                }
                if (o < (int)sizeof line - 40) snprintf(line + o, sizeof line - o, "  errors %llu   ", (unsigned long long)errs);
                fputs(line, stderr);
                fflush(stderr);
                last_t = now;
            }
        }
        double wake = next_tick < r->t_end ? next_tick : r->t_end;
        double d = wake - now_s();
        if (d > 0.05) d = 0.05;
        if (d > 0) nanosleep(&(struct timespec){0, (long)(d * 1e9)}, NULL);
    }
    double t_stop = now_s();
    atomic_store(&r->stop, 1);
    if (progress) fputs("\n", stderr);
    for (uint64_t t = 0; t < threads; t++) pthread_join(ts[t].th, NULL);
    if (probing) pthread_join(pth, NULL);
    if (eventing) pthread_join(eth, NULL);
    rp->partial = r->why[0] != 0;
    rp->secs = t_stop - r->t_meas;
    if (dpid && !rp->nrss) rp->rss1 = rp->rss0;
    if (dpid) rp->nrss++;
    if (rows_init(&rp->all, nrows)) {
        fprintf(stderr, "%s: bench: out of memory\n", g_prog);
        rc = 1;
        goto out;
    }
    for (uint64_t i = 0; i < nthreads_rows; i++) rows_merge(&rp->all, &rw[i]); /* threads may have shrunk */
    print_table(stdout, r, rp);
    if (json_path && write_out(json_path, r, rp, true)) rc = 1;
    if (csv_path && write_out(csv_path, r, rp, false)) rc = 1;
    if (!rc && rp->partial) rc = atomic_load(&r->gone) ? 3 : 1;
    if (!atomic_load(&r->gone)) { /* leave the scene as it was */
        for (int i = 0; evc && i < s->nev; i++) {
            vp_ack a;
            if (ea->loaded[i]) (void)vtc_sublevel_unload(evc, s->ev[i].name, &a);
        }
        if (setup && s->setup_n) (void)remove_range(setup, SETUP_BASE, s->setup_n);
        if (setup && (pa.q || pa.fr)) (void)remove_range(setup, PROBE_ID, 1);
    }
out:
    for (uint32_t i = 0; cs && i < total; i++) lconn_close(&cs[i]);
    free(cs);
    vtc_close(pa.q);
    vtc_close(pa.fr);
    vtc_close(setup);
    vtc_close(evc);
    if (r->s) pthread_mutex_destroy(&r->mu);
    free(ea);
    free(ts);
    for (uint64_t i = 0; rw && i < nthreads_rows; i++) rows_free(&rw[i]);
    rows_free(&rp->all);
    free(rw);
    free(rp);
    free(r);
    free(s);
    return rc;
}
