/*
 * commander.c — `vantage commander`: the tablet-commander thin client.
 *
 * One thread, one loop (ppoll on the daemon's socket and the pad hub's
 * fd, timed to the mapping's fixed tick):
 *   pad reports (pad_io.h: hidraw, libusb, or a replayed capture) and the
 *   keyboard/mouse fallback -> the newest pad state;
 *   every 1/tick_hz s: cmdr_step (dead zone, curve, camera, actions); a
 *   camera that moved is sent as a FRAME_SUBSCRIBE re-aim with the next
 *   view_seq (the daemon keeps drawing, latest-frame-wins);
 *   FRAMEs (JPEG) are decoded and shown (SDL2 window with the overlay, or
 *   written to --headless DIR), MARKED pushes become marks on the overlay;
 *   select / ping / destroy run as asynchronous requests (a narrow
 *   visibility query, ENTITY_GET of the candidates, a ray against their
 *   boxes; MARK; DESTROY at the hit point).
 * A daemon that goes away leaves the last frame up; the client reconnects
 * with backoff (0.25 s doubling to 5 s) and resubscribes.
 *
 * Latency, input to photon: a pad report's time (the hub's read time) ->
 * the tick that consumed it and sent the view (tick wait) -> the first
 * FRAME whose view_seq is that view or later, received (daemon: queue,
 * cull, render, encode, network) -> decoded and presented (show). The
 * overlay and --stats print p50/p95 of the whole and of the parts.
 *
 * Frame rate: frames shown (presented, or written headless) divided by
 * the seconds since the start, the same figure in the overlay and in
 * --stats; the overlay adds the frames shown in the last second.
 */
#include "cli.h"
#include "commander.h"
#include "pad_io.h"
#include "vt_image.h"

#include <errno.h>
#include <stdarg.h>
#include <math.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

#define SENT_RING 1024 /* view updates remembered for latency (> updates in flight) */
#define MAX_PICK 256   /* candidates fetched for a pick */

typedef struct sent_view {
    uint16_t seq;
    double t_input;          /* the oldest report this view answers (0: none, a continued motion) */
    double t_sent;
} sent_view;

typedef struct mark {
    double pos[3];
    uint8_t kind;
    bool own;
    double until, ttl;       /* now_s() */
} mark;

enum pick_state { PICK_IDLE, PICK_QUERY, PICK_GET };

typedef struct commander {
    cli *k;
    vtc_client *c;
    /* options */
    const char *headless, *shot, *config;
    uint32_t w, h;
    int quality, max_fps;
    uint8_t renderer;
    double seconds, destroy_radius;
    float exposure;          /* EV for the JPEG tone map: a view from above sees mostly unlit roofs */
    uint64_t max_frames;
    bool stats, json;
    bool full_size;          /* --full-size: no dynamic resolution while the camera moves */
    pad_hub_opts hub_opts;
    /* input and camera */
    cmdr_map_cfg map;
    cmdr_camera cam;
    cmdr_input in;
    pad_hub *hub;
    pad_state pad;
    uint32_t pad_id;         /* the pad driving the view, 0 = none */
    char pad_name[96];
    double pending_input;    /* the oldest report not yet consumed by a tick (0 = none) */
    double next_tick;
    bool need_view;          /* send the view at the next chance (reconnects) */
    bool replay_done;
    bool replay_wait;        /* a replay starts at the first frame shown (opened once to check it) */
    /* the stream */
    uint16_t seq, shown_seq;
    bool shown_any;
    sent_view sent[SENT_RING];
    uint32_t sub_req, mark_sub_req, mark_req, destroy_req;
    double t_sub_sent;       /* for the rtt: FRAME_SUBSCRIBE -> its ACK */
    uint8_t *jpeg;           /* the newest frame's bytes */
    size_t jpeg_len, jpeg_cap;
    vp_frame fr;             /* its header */
    double fr_recv;
    bool fr_new;
    uint64_t frames, frame_errors;
    double shown_at[256];    /* the last frames' show times, a ring (> the 240 fps cap) */
    cmdr_lat lat, lat_tick, lat_daemon, lat_show, rtt;
    cmdr_lat fr_render, fr_encode; /* the daemon's own times per frame received */
    double ov_p50, ov_p95, ov_rtt, ov_next; /* the overlay's percentiles, refreshed 4 times a second */
    /* commands */
    enum pick_state pick;
    uint32_t pick_req;
    bool pick_destroy;       /* the pick is for a destroy */
    double pick_o[3], pick_d[3];
    bool have_sel;
    uint64_t sel_id;
    int group;
    mark marks[CMDR_OVERLAY_MARKS];
    uint32_t nmarks;
    uint32_t client_id;
    char status[160];
    double status_until;
    /* connection */
    double next_connect, backoff;
    bool ever_connected;
    /* output */
    cmdr_display *disp;
    FILE *log;               /* headless: frames.jsonl */
    double t_start;
} commander;

static void say(commander *m, double secs, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
static void say(commander *m, double secs, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(m->status, sizeof m->status, fmt, ap);
    va_end(ap);
    m->status_until = now_s() + secs;
    if (!m->disp) fprintf(stderr, "vantage commander: %s\n", m->status);
}

/* ---- the connection --------------------------------------------------------------------- */

static void disconnect(commander *m, const char *why)
{
    if (!m->c) return;
    say(m, 5, "daemon connection lost (%s); reconnecting", why);
    vtc_close(m->c);
    m->c = NULL;
    m->k->c = NULL;
    m->backoff = 0.25;
    m->next_connect = now_s() + m->backoff;
    m->pick = PICK_IDLE;
}

/* Encodes with enc into a buffer of size bytes and sends it; false when the
 * connection failed (it is dropped). */
static bool send_msg(commander *m, size_t size, void (*enc)(vp_writer *, uint32_t, const void *), uint32_t req,
                     const void *arg)
{
    uint8_t buf[512];
    vp_writer w;
    vp_writer_init(&w, buf, size <= sizeof buf ? size : sizeof buf);
    enc(&w, req, arg);
    if (w.overflow || vtc_send(m->c, buf, w.len)) {
        disconnect(m, w.overflow ? "message too large" : vtc_last_error(m->c)->msg);
        return false;
    }
    return true;
}

static void enc_frame_sub(vp_writer *w, uint32_t req, const void *a) { vp_enc_frame_sub(w, req, a); }
static void enc_subscribe(vp_writer *w, uint32_t req, const void *a) { vp_enc_subscribe(w, req, *(const uint32_t *)a); }
static void enc_mark(vp_writer *w, uint32_t req, const void *a) { vp_enc_mark(w, req, a); }
static void enc_destroy(vp_writer *w, uint32_t req, const void *a) { vp_enc_destroy(w, req, a); }
static void enc_query(vp_writer *w, uint32_t req, const void *a) { vp_enc_vis_query(w, req, 0, 0, a, 1); }

/* The camera as the stream's view, with the next view_seq. */
static void send_view(commander *m, double t_input)
{
    if (!m->c) {
        m->need_view = true;
        return;
    }
    /* the selection rides with the view: the daemon outlines it in the
       frames (its silhouette, dimmer where hidden), so the window draws
       no box of its own */
    vp_frame_sub fs = {.r = {.format = VP_FRAME_JPEG, .quality = (uint8_t)m->quality, .renderer = m->renderer,
                             .flags = m->full_size ? 0 : VP_RENDER_MOTION, /* smaller while the camera moves */
                             .exposure_ev = m->exposure, .nhighlight = m->have_sel,
                             .highlight = {m->have_sel ? m->sel_id : 0}},
                       .max_fps = (uint16_t)m->max_fps};
    if (!cmdr_camera_view(&m->cam, m->w, m->h, &fs.r.view)) {
        say(m, 3, "the camera is degenerate; view not sent");
        return;
    }
    fs.view_seq = ++m->seq;
    double now = now_s();
    m->sent[m->seq % SENT_RING] = (sent_view){.seq = m->seq, .t_input = t_input, .t_sent = now};
    m->sub_req = vtc_next_req(m->c);
    m->t_sub_sent = now;
    if (send_msg(m, VP_HEADER_SIZE + VP_FRAME_SUB_SIZE, enc_frame_sub, m->sub_req, &fs)) m->need_view = false;
}

static void try_connect(commander *m)
{
    double now = now_s();
    if (m->c || now < m->next_connect) return;
    vtc_connect_opts o = m->k->co;
    o.role = VP_ROLE_COMMANDER;
    o.name = "vantage commander";
    char err[256];
    if (vtc_connect(&o, &m->c, err, sizeof err)) {
        if (!m->ever_connected || m->backoff >= 5) say(m, 5, "cannot reach the daemon: %s (retrying)", err);
        m->backoff = m->backoff ? fmin(m->backoff * 2, 5) : 0.25;
        m->next_connect = now + m->backoff;
        return;
    }
    m->k->c = m->c;
    m->client_id = vtc_server(m->c)->client_id;
    m->ever_connected = true;
    m->backoff = 0;
    say(m, 3, "connected (client %u, role %s)", m->client_id,
        vtc_server(m->c)->role >= VP_ROLE_COMMANDER ? "commander" : "viewer");
    uint32_t kinds = VP_EVENT_MARKS;
    m->mark_sub_req = vtc_next_req(m->c);
    if (!send_msg(m, 64, enc_subscribe, m->mark_sub_req, &kinds)) return;
    send_view(m, 0);
}

/* ---- commands ------------------------------------------------------------------------------ */

static void start_pick(commander *m, bool destroy)
{
    if (!m->c) {
        say(m, 3, "not connected");
        return;
    }
    if (m->pick != PICK_IDLE) return; /* one at a time */
    vp_view q;
    /* an orthographic box 1.5 % of the view across around the reticle (a
       1-degree cone in perspective): what the query sees there, occlusion
       included, are the candidates; the ray picks the nearest */
    if (!cmdr_pick_view(&m->cam, fmax(0.5, 0.03 * m->cam.half_h), &q)) return;
    cmdr_camera_ray(&m->cam, m->pick_o, m->pick_d);
    m->pick_req = vtc_next_req(m->c);
    m->pick_destroy = destroy;
    if (send_msg(m, VP_HEADER_SIZE + 8 + VP_VIEW_SIZE, enc_query, m->pick_req, &q)) m->pick = PICK_QUERY;
}

static void on_vis_result(commander *m, const uint8_t *p, uint32_t len)
{
    vp_vis_result r;
    if (vp_dec_vis_result(p, len, &r)) {
        m->pick = PICK_IDLE;
        say(m, 3, "malformed VIS_RESULT");
        return;
    }
    if (!r.count) {
        m->pick = PICK_IDLE;
        if (m->pick_destroy) say(m, 2, "nothing under the reticle to destroy");
        else {
            m->have_sel = false;
            say(m, 2, "nothing under the reticle");
        }
        return;
    }
    uint64_t ids[MAX_PICK];
    uint32_t n = 0;
    vp_vis_rec rec;
    for (uint32_t i = 0; i < r.count && n < MAX_PICK; i++) {
        vp_vis_rec_get(&r, i, &rec);
        ids[n++] = rec.id;
    }
    uint8_t buf[VP_HEADER_SIZE + 4 + 8 * MAX_PICK];
    vp_writer w;
    vp_writer_init(&w, buf, sizeof buf);
    m->pick_req = vtc_next_req(m->c);
    vp_enc_ids(&w, VP_ENTITY_GET, m->pick_req, ids, n);
    if (vtc_send(m->c, buf, w.len)) {
        disconnect(m, vtc_last_error(m->c)->msg);
        return;
    }
    m->pick = PICK_GET;
}

static void on_picked(commander *m, const uint8_t *p, uint32_t len)
{
    m->pick = PICK_IDLE;
    vp_list_reply lr;
    if (vp_dec_list_reply(p, len, &lr)) {
        say(m, 3, "malformed ENTITY_LIST_REPLY");
        return;
    }
    double best = INFINITY;
    vp_entity e, hit = {0};
    for (uint32_t i = 0; i < lr.batch.count; i++) {
        vp_entity_get(&lr.batch, i, &e);
        double t, lo[3] = {e.aabb[0], e.aabb[1], e.aabb[2]}, hi[3] = {e.aabb[3], e.aabb[4], e.aabb[5]};
        if (cmdr_ray_box(m->pick_o, m->pick_d, lo, hi, &t) && t < best) {
            best = t;
            hit = e;
        }
    }
    if (!isfinite(best)) {
        say(m, 2, "nothing under the reticle");
        if (!m->pick_destroy) m->have_sel = false;
        return;
    }
    double at[3];
    for (int a = 0; a < 3; a++) at[a] = m->pick_o[a] + best * m->pick_d[a];
    if (m->pick_destroy) {
        vp_destroy d = {.id = hit.id, .center = {at[0], at[1], at[2]}, .radius = m->destroy_radius};
        m->destroy_req = vtc_next_req(m->c);
        if (send_msg(m, VP_HEADER_SIZE + VP_DESTROY_SIZE, enc_destroy, m->destroy_req, &d))
            say(m, 3, "destroy #%llu at (%.1f, %.1f, %.1f), radius %.1f m", (unsigned long long)hit.id, at[0], at[1],
                at[2], m->destroy_radius);
        return;
    }
    m->have_sel = true;
    m->sel_id = hit.id;
    m->need_view = true; /* the stream outlines the new selection */
    say(m, 4, "selected #%llu (group %d), %.0f x %.0f x %.0f m", (unsigned long long)hit.id, m->group + 1,
        hit.aabb[3] - hit.aabb[0], hit.aabb[4] - hit.aabb[1], hit.aabb[5] - hit.aabb[2]);
    /* a select is a mark of kind 1 for the other commanders */
    vp_mark mk = {.pos = {at[0], at[1], at[2]}, .entity = hit.id, .kind = 1, .ttl_ms = 4000};
    m->mark_req = vtc_next_req(m->c);
    send_msg(m, VP_HEADER_SIZE + VP_MARK_SIZE, enc_mark, m->mark_req, &mk);
}

static void ping(commander *m)
{
    if (!m->c) {
        say(m, 3, "not connected");
        return;
    }
    vp_mark mk = {.pos = {m->cam.target[0], m->cam.target[1], m->cam.target[2]}, .kind = 0, .ttl_ms = 6000};
    m->mark_req = vtc_next_req(m->c);
    send_msg(m, VP_HEADER_SIZE + VP_MARK_SIZE, enc_mark, m->mark_req, &mk);
}

static void add_mark(commander *m, const vp_marked *mk)
{
    double now = now_s();
    uint32_t slot = 0;
    for (uint32_t i = 0; i < CMDR_OVERLAY_MARKS; i++) { /* a free or the oldest slot */
        if (i >= m->nmarks) {
            slot = i;
            m->nmarks = i + 1;
            break;
        }
        if (m->marks[i].until < m->marks[slot].until) slot = i;
    }
    m->marks[slot] = (mark){.pos = {mk->m.pos[0], mk->m.pos[1], mk->m.pos[2]}, .kind = mk->m.kind,
                            .own = mk->client_id == m->client_id, .until = now + mk->m.ttl_ms / 1e3,
                            .ttl = mk->m.ttl_ms / 1e3};
}

static void run_actions(commander *m, uint32_t fired)
{
    if (fired & 1u << CMDR_SELECT) start_pick(m, false);
    if (fired & 1u << CMDR_DESTROY) start_pick(m, true);
    if (fired & 1u << CMDR_PING) ping(m);
    if (fired & 1u << CMDR_CANCEL) {
        m->have_sel = false;
        m->need_view = true;
        say(m, 2, "selection cleared");
    }
    if (fired & 1u << CMDR_GROUP_PREV) m->group = (m->group + CMDR_GROUPS - 1) % CMDR_GROUPS;
    if (fired & 1u << CMDR_GROUP_NEXT) m->group = (m->group + 1) % CMDR_GROUPS;
    if (fired & (1u << CMDR_GROUP_PREV | 1u << CMDR_GROUP_NEXT)) say(m, 2, "group %d", m->group + 1);
    if (fired & 1u << CMDR_TOGGLE_PERSPECTIVE)
        say(m, 2, "%s view", m->cam.perspective ? "tilted perspective" : "top-down orthographic");
}

/* ---- frames ----------------------------------------------------------------------------------- */

static void on_frame(commander *m, const uint8_t *p, uint32_t len)
{
    vp_frame f;
    if (vp_dec_frame(p, len, &f) || f.format != VP_FRAME_JPEG) {
        m->frame_errors++;
        return;
    }
    if (f.data_len > m->jpeg_cap) {
        uint8_t *n = realloc(m->jpeg, f.data_len);
        if (!n) {
            m->frame_errors++;
            return;
        }
        m->jpeg = n;
        m->jpeg_cap = f.data_len;
    }
    memcpy(m->jpeg, f.data, f.data_len); /* latest wins: only the newest of a drain is shown */
    m->jpeg_len = f.data_len;
    cmdr_lat_add(&m->fr_render, f.render_ns / 1e6);
    cmdr_lat_add(&m->fr_encode, f.encode_ns / 1e6);
    m->fr = f;
    m->fr.data = m->jpeg;
    m->fr_recv = now_s();
    m->fr_new = true;
}

/* Latency samples for every view up to seq shown at t_shown. */
static void account(commander *m, uint16_t seq, double t_recv, double t_shown)
{
    if (!m->shown_any) {
        m->shown_any = true;
        m->shown_seq = (uint16_t)(seq - 1);
    }
    uint16_t ahead = (uint16_t)(seq - m->shown_seq);
    if (ahead == 0 || ahead > 32768) return; /* an older view than one shown already */
    if (ahead > SENT_RING) ahead = SENT_RING;
    for (uint16_t i = 0; i < ahead; i++) {
        uint16_t s = (uint16_t)(seq - i);
        sent_view *v = &m->sent[s % SENT_RING];
        if (v->seq != s || !(v->t_input > 0)) continue;
        cmdr_lat_add(&m->lat, (t_shown - v->t_input) * 1e3);
        cmdr_lat_add(&m->lat_tick, (v->t_sent - v->t_input) * 1e3);
        cmdr_lat_add(&m->lat_daemon, (t_recv - v->t_sent) * 1e3);
        cmdr_lat_add(&m->lat_show, (t_shown - t_recv) * 1e3);
        v->t_input = 0;
    }
    m->shown_seq = seq;
}

/* Frames shown a second since the start: the overlay's and --stats' figure. */
static double run_fps(const commander *m, double now)
{
    return now > m->t_start ? m->frames / (now - m->t_start) : 0;
}

/* Frames shown in the last second before now. */
static unsigned last_second(const commander *m, double now)
{
    unsigned n = 0, ring = sizeof m->shown_at / sizeof m->shown_at[0];
    for (uint64_t i = 0; i < m->frames && i < ring; i++) n += m->shown_at[(m->frames - 1 - i) % ring] > now - 1;
    return n;
}

/* A latency figure for the overlay: "-" without samples. */
static const char *ms_or_dash(double v, char *buf, size_t n)
{
    if (isnan(v)) snprintf(buf, n, "-");
    else snprintf(buf, n, "%.1f ms", v);
    return buf;
}

static void fill_overlay(commander *m, cmdr_overlay *ov)
{
    memset(ov, 0, sizeof *ov);
    double now = now_s();
    if (now >= m->ov_next) { /* each is a sort of up to 4096 samples: not on every frame */
        m->ov_p50 = cmdr_lat_pct(&m->lat, 50);
        m->ov_p95 = cmdr_lat_pct(&m->lat, 95);
        m->ov_rtt = cmdr_lat_pct(&m->rtt, 50);
        m->ov_next = now + 0.25;
    }
    char a[24], b[24], c[24];
    snprintf(ov->text[0], sizeof ov->text[0], "%.1f fps (last s %u)   input->photon p50 %s  p95 %s   rtt %s",
             run_fps(m, now), last_second(m, now), ms_or_dash(m->ov_p50, a, sizeof a),
             ms_or_dash(m->ov_p95, b, sizeof b), ms_or_dash(m->ov_rtt, c, sizeof c));
    snprintf(ov->text[1], sizeof ov->text[1], "%s  %.0f m  yaw %.0f  tilt %.0f  group %d  %s%s",
             m->cam.perspective ? "perspective" : "top-down", 2 * m->cam.half_h, m->cam.yaw * 180 / M_PI,
             m->cam.pitch * 180 / M_PI, m->group + 1, m->pad_id ? m->pad_name : "keyboard/mouse",
             m->c ? "" : "   [disconnected]");
    if (m->have_sel) snprintf(ov->text[2], sizeof ov->text[2], "selected #%llu", (unsigned long long)m->sel_id);
    if (now < m->status_until) snprintf(ov->text[3], sizeof ov->text[3], "%s", m->status);
    for (uint32_t i = 0; i < m->nmarks; i++) {
        const mark *k = &m->marks[i];
        if (now >= k->until) continue;
        double x, y;
        if (!cmdr_camera_project(&m->cam, m->w, m->h, k->pos, &x, &y)) continue;
        uint32_t j = ov->nmarks++;
        ov->mark[j].x = x;
        ov->mark[j].y = y;
        ov->mark[j].alpha = (float)fmin(1, (k->until - now) / fmin(k->ttl, 1.5));
        ov->mark[j].kind = k->kind;
        ov->mark[j].own = k->own;
    }
}

/* The newest frame to the window or the folder. */
static void show_frame(commander *m)
{
    if (!m->fr_new) return;
    m->fr_new = false;
    double t_shown;
    if (m->disp) {
        uint8_t *rgb = NULL;
        uint32_t w, h;
        char err[200];
        if (vt_jpeg_decode(m->jpeg, m->jpeg_len, &rgb, &w, &h, err, sizeof err)) {
            m->frame_errors++;
            say(m, 3, "a frame did not decode: %s", err);
            return;
        }
        cmdr_display_frame(m->disp, rgb, w, h);
        free(rgb);
        cmdr_overlay ov;
        fill_overlay(m, &ov);
        cmdr_display_present(m->disp, &ov);
        t_shown = now_s();
    } else {
        char path[4200];
        snprintf(path, sizeof path, "%s/frame-%06llu.jpg", m->headless, (unsigned long long)m->frames);
        FILE *f = fopen(path, "wb");
        if (!f || fwrite(m->jpeg, 1, m->jpeg_len, f) != m->jpeg_len) {
            if (f) fclose(f);
            say(m, 5, "%s: %s", path, strerror(errno));
            m->frame_errors++;
            return;
        }
        fclose(f);
        t_shown = now_s();
        if (m->log)
            fprintf(m->log,
                    "{\"frame\":%llu,\"t\":%.6f,\"epoch\":%llu,\"view_seq\":%u,\"visible\":%u,\"render_ms\":%.3f,"
                    "\"encode_ms\":%.3f,\"bytes\":%zu,\"target\":[%.3f,%.3f,%.3f],\"yaw\":%.5f,\"pitch\":%.5f,"
                    "\"half_h\":%.4f}\n",
                    (unsigned long long)m->frames, t_shown - m->t_start, (unsigned long long)m->fr.epoch,
                    m->fr.view_seq, m->fr.visible, m->fr.render_ns / 1e6, m->fr.encode_ns / 1e6, m->jpeg_len,
                    m->cam.target[0], m->cam.target[1], m->cam.target[2], m->cam.yaw, m->cam.pitch, m->cam.half_h);
    }
    m->shown_at[m->frames % (sizeof m->shown_at / sizeof m->shown_at[0])] = t_shown;
    m->frames++;
    account(m, m->fr.view_seq, m->fr_recv, t_shown);
}

/* ---- the loop ------------------------------------------------------------------------------- */

static void drain_socket(commander *m)
{
    while (m->c) {
        vp_header h;
        const uint8_t *p;
        int rc = vtc_recv(m->c, &h, &p, 0);
        if (rc == VP_NEED_MORE) return;
        if (rc) {
            disconnect(m, vtc_last_error(m->c)->msg);
            return;
        }
        switch (h.type) {
        case VP_FRAME: on_frame(m, p, h.len); break;
        case VP_MARKED: {
            vp_marked mk;
            if (!vp_dec_marked(p, h.len, &mk)) add_mark(m, &mk);
            break;
        }
        case VP_ACK:
            if (h.req == m->sub_req) cmdr_lat_add(&m->rtt, (now_s() - m->t_sub_sent) * 1e3);
            if (h.req == m->mark_req) {
                vp_ack a;
                if (!vp_dec_ack(p, h.len, &a)) say(m, 2, "mark sent to %u commanders", a.count);
            }
            break;
        case VP_VIS_RESULT:
            if (m->pick == PICK_QUERY && h.req == m->pick_req) on_vis_result(m, p, h.len);
            break;
        case VP_ENTITY_LIST_REPLY:
            if (m->pick == PICK_GET && h.req == m->pick_req) on_picked(m, p, h.len);
            break;
        case VP_DESTROYED: {
            vp_destroyed d;
            if (!vp_dec_destroyed(p, h.len, &d))
                say(m, 3, "destroyed: %u spheres on it, its occluder %u triangles", d.spheres, d.occluder_tris);
            break;
        }
        case VP_ERROR: {
            vp_error e;
            if (vp_dec_error(p, h.len, &e)) break;
            if (h.req == m->pick_req && m->pick != PICK_IDLE) m->pick = PICK_IDLE;
            if (e.code == VP_ERR_AUTH && h.req == m->destroy_req)
                say(m, 4, "destroy refused: this token's role cannot send commands");
            else
                say(m, 4, "daemon: %s: %.*s", vp_strerror(e.code), (int)e.msg_len, (const char *)e.msg);
            break;
        }
        default: break; /* EVENT, replies to nothing we track */
        }
    }
}

static void drain_pads(commander *m)
{
    pad_event ev;
    while (m->hub && pad_hub_next(m->hub, &ev) == 1) {
        switch (ev.kind) {
        case PAD_EV_ADDED:
            say(m, 3, "pad %u: %s", ev.pad, ev.msg);
            if (!m->pad_id) {
                m->pad_id = ev.pad;
                snprintf(m->pad_name, sizeof m->pad_name, "%s", ev.info ? ev.info->name : "pad");
            }
            break;
        case PAD_EV_REMOVED:
            say(m, 4, "pad %u removed: %s", ev.pad, ev.msg);
            if (ev.pad == m->pad_id) { /* a pad pulled mid-pan must not keep panning */
                m->pad_id = 0;
                memset(&m->pad, 0, sizeof m->pad);
            }
            break;
        case PAD_EV_STATE:
            if (ev.pad != m->pad_id) { /* the pad someone touches drives */
                bool active = fabsf(ev.state.lx) > 0.3f || fabsf(ev.state.ly) > 0.3f || fabsf(ev.state.rx) > 0.3f ||
                              fabsf(ev.state.ry) > 0.3f || ev.state.lt > 0.3f || ev.state.rt > 0.3f ||
                              ev.state.buttons;
                if (!active && m->pad_id) break;
                m->pad_id = ev.pad;
                snprintf(m->pad_name, sizeof m->pad_name, "%s", ev.info ? ev.info->name : "pad");
            }
            m->pad = ev.state;
            if (!(m->pending_input > 0) || ev.t_report < m->pending_input) m->pending_input = ev.t_report;
            break;
        case PAD_EV_ERROR: say(m, 3, "pads: %s", ev.msg); break;
        case PAD_EV_END:
            m->replay_done = true;
            say(m, 3, "replay finished");
            break;
        }
    }
}

/* The fixed-rate steps that are due. */
static void tick(commander *m, const cmdr_keys *keys)
{
    double now = now_s(), dt = 1.0 / m->map.tick_hz;
    if (now < m->next_tick) return;
    int steps = 0;
    bool moved = false;
    uint32_t fired = 0;
    const pad_state *in = keys && keys->any ? &keys->state : m->pad_id ? &m->pad : NULL;
    while (now >= m->next_tick && steps < 8) {
        cmdr_step_out o;
        cmdr_step(&m->map, &m->cam, &m->in, in, dt, &o);
        moved |= o.moved;
        fired |= o.fired;
        m->next_tick += dt;
        steps++;
    }
    if (now >= m->next_tick) m->next_tick = now + dt; /* far behind (a stall): do not catch up in a burst */
    if (keys && keys->wheel) {
        cmdr_camera_wheel(&m->cam, keys->wheel);
        moved = true;
    }
    run_actions(m, fired);
    if (moved || m->need_view) send_view(m, moved ? m->pending_input : 0);
    m->pending_input = 0;
}

static int parse_args(commander *m, int argc, char **argv)
{
    m->w = 1280;
    m->h = 720;
    m->quality = 80;
    m->max_fps = 240;
    m->destroy_radius = 3;
    m->exposure = 1.5f;
    m->hub_opts.replay_speed = 1;
    bool persp = false;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        const char *v = i + 1 < argc ? argv[i + 1] : NULL;
        uint64_t u;
        double d;
        char *end;
#define NEED()                                                                     \
    do {                                                                           \
        if (!v) return die_usage("commander: %s needs a value", a); \
        i++;                                                                       \
    } while (0)
        if (!strcmp(a, "--replay")) {
            NEED();
            m->hub_opts.replay = v;
        } else if (!strcmp(a, "--record")) {
            NEED();
            m->hub_opts.record = v;
        } else if (!strcmp(a, "--loop")) {
            m->hub_opts.replay_loop = true;
        } else if (!strcmp(a, "--speed")) {
            NEED();
            d = strtod(v, &end);
            if (*end || !(d > 0 && d <= 1000)) return die_usage("commander: --speed is 0..1000 (1 = real time)");
            m->hub_opts.replay_speed = d;
        } else if (!strcmp(a, "--headless")) {
            NEED();
            m->headless = v;
        } else if (!strcmp(a, "--screenshot")) {
            NEED();
            m->shot = v;
        } else if (!strcmp(a, "--config")) {
            NEED();
            m->config = v;
        } else if (!strcmp(a, "--size")) {
            NEED();
            if (!parse_size(v, 4096, &m->w, &m->h)) return die_usage("commander: --size WxH, 1..4096 each");
        } else if (!strcmp(a, "--quality")) {
            NEED();
            if (!parse_u64(v, &u) || u < 1 || u > 100) return die_usage("commander: --quality is 1..100");
            m->quality = (int)u;
        } else if (!strcmp(a, "--fps")) {
            NEED();
            if (!parse_u64(v, &u) || u < 1 || u > VP_FRAME_SUB_MAX_FPS) return die_usage("commander: --fps is 1..240");
            m->max_fps = (int)u;
        } else if (!strcmp(a, "--renderer")) {
            NEED();
            if (!parse_renderer(v, &m->renderer)) return die_usage("commander: --renderer soft|gl");
        } else if (!strcmp(a, "--seconds")) {
            NEED();
            d = strtod(v, &end);
            if (*end || !(d > 0)) return die_usage("commander: --seconds needs a positive number");
            m->seconds = d;
        } else if (!strcmp(a, "--frames")) {
            NEED();
            if (!parse_u64(v, &u) || !u) return die_usage("commander: --frames needs a positive count");
            m->max_frames = u;
        } else if (!strcmp(a, "--destroy-radius")) {
            NEED();
            d = strtod(v, &end);
            if (*end || !(d > 0 && d < 1e6)) return die_usage("commander: --destroy-radius needs metres > 0");
            m->destroy_radius = d;
        } else if (!strcmp(a, "--exposure")) {
            NEED();
            d = strtod(v, &end);
            if (*end || !(fabs(d) <= 64)) return die_usage("commander: --exposure is -64..64 EV");
            m->exposure = (float)d;
        } else if (!strcmp(a, "--stats")) {
            m->stats = true;
        } else if (!strcmp(a, "--json")) {
            m->json = m->stats = true;
        } else if (!strcmp(a, "--perspective")) {
            persp = true;
        } else if (!strcmp(a, "--full-size")) {
            m->full_size = true;
        } else {
            return die_usage("commander: unknown option %s", a);
        }
#undef NEED
    }
    m->cam.perspective = persp;
    cmdr_camera_reset(&m->cam, (double)m->w / m->h);
    return -1; /* go on */
}

static void print_stats(commander *m)
{
    double secs = now_s() - m->t_start;
    const cmdr_lat *L[] = {&m->lat, &m->lat_tick, &m->lat_daemon, &m->lat_show, &m->rtt, &m->fr_render, &m->fr_encode};
    const char *names[] = {"input_to_photon", "tick_wait",    "daemon_and_network", "decode_and_show",
                           "rtt",             "frame_render", "frame_encode"};
    enum { NL = sizeof L / sizeof L[0] };
    static const double q[4] = {50, 95, 99, 100};
    /* a figure with no sample is null (JSON) or '-' (text), never nan or 0 */
    if (m->json) {
        printf("{\"seconds\":%.3f,\"frames\":%llu,\"fps\":%.2f,\"frame_errors\":%llu,\"samples\":%llu", secs,
               (unsigned long long)m->frames, run_fps(m, m->t_start + secs), (unsigned long long)m->frame_errors,
               (unsigned long long)m->lat.total);
        static const char *const key[4] = {"p50", "p95", "p99", "max"};
        for (int i = 0; i < NL; i++) {
            printf(",\"%s_ms\":{", names[i]);
            for (int k = 0; k < 4; k++) {
                printf("%s\"%s\":", k ? "," : "", key[k]);
                if (L[i]->n) printf("%.3f", cmdr_lat_pct(L[i], q[k]));
                else printf("null");
            }
            printf("}");
        }
        printf("}\n");
        return;
    }
    printf("frames %llu shown in %.1f s (%.1f/s, the overlay's fps), %llu bad; %llu latency samples\n",
           (unsigned long long)m->frames, secs, run_fps(m, m->t_start + secs), (unsigned long long)m->frame_errors,
           (unsigned long long)m->lat.total);
    printf("%-20s %8s %8s %8s %8s\n", "ms", "p50", "p95", "p99", "max");
    for (int i = 0; i < NL; i++) {
        printf("%-20s", names[i]);
        for (int k = 0; k < 4; k++) {
            if (L[i]->n) printf(" %8.2f", cmdr_lat_pct(L[i], q[k]));
            else printf(" %8s", "-");
        }
        printf("\n");
    }
}

int cmdr_main(cli *k, int argc, char **argv)
{
    commander *m = calloc(1, sizeof *m);
    if (!m) return fprintf(stderr, "%s: out of memory\n", g_prog), 1;
    m->k = k;
    int rc = parse_args(m, argc, argv);
    if (rc >= 0) {
        free(m);
        return rc;
    }
    rc = 1;
    char err[512];
    cmdr_map_defaults(&m->map);
    if (m->config && cmdr_map_load(&m->map, m->config, err, sizeof err)) {
        fprintf(stderr, "%s: commander: %s\n", g_prog, err);
        goto out;
    }
    if (m->headless) {
        if (mkdir(m->headless, 0777) && errno != EEXIST) {
            fprintf(stderr, "%s: commander: %s: %s\n", g_prog, m->headless, strerror(errno));
            goto out;
        }
        char path[4200];
        snprintf(path, sizeof path, "%s/frames.jsonl", m->headless);
        if (!(m->log = fopen(path, "w"))) {
            fprintf(stderr, "%s: commander: %s: %s\n", g_prog, path, strerror(errno));
            goto out;
        }
    } else if (!(m->disp = cmdr_display_open(m->w, m->h, "vantage commander", err, sizeof err))) {
        fprintf(stderr, "%s: commander: %s\n", g_prog, err);
        goto out;
    }
    if (pad_hub_open(&m->hub_opts, &m->hub, err, sizeof err)) {
        if (m->hub_opts.replay || m->hub_opts.record) {
            fprintf(stderr, "%s: commander: %s\n", g_prog, err);
            goto out;
        }
        fprintf(stderr, "%s: commander: no pads (%s); keyboard and mouse only\n", g_prog, err);
        m->hub = NULL;
    }
    /* a replay is checked now (a bad capture is refused, naming its line)
       and played from the first frame shown: its camera path then starts
       from the start position whatever the daemon's first frame costs */
    if (m->hub_opts.replay && !m->hub_opts.record) {
        pad_hub_close(m->hub);
        m->hub = NULL;
        m->replay_wait = true;
    }
    catch_sigint();
    m->t_start = now_s();
    m->next_tick = m->t_start;
    m->next_connect = m->t_start;
    rc = 0;
    cmdr_keys keys = {0};
    double next_overlay = 0;
    while (!g_stop) {
        double now = now_s();
        if (m->seconds > 0 && now - m->t_start >= m->seconds) break;
        if (m->max_frames && m->frames >= m->max_frames) break;
        if (m->replay_wait && m->frames > 0) {
            m->replay_wait = false;
            if (pad_hub_open(&m->hub_opts, &m->hub, err, sizeof err)) {
                fprintf(stderr, "%s: commander: %s\n", g_prog, err);
                rc = 1;
                break;
            }
        }
        try_connect(m);
        /* wait for the socket, the pads, or the next tick (and reconnect) */
        double until = m->next_tick;
        if (!m->c && m->next_connect < until) until = m->next_connect;
        if (m->disp && until > now + 0.004) until = now + 0.004; /* window events have no fd */
        struct pollfd pf[2];
        nfds_t n = 0;
        if (m->c) pf[n++] = (struct pollfd){.fd = vtc_fd(m->c), .events = POLLIN};
        if (m->hub) pf[n++] = (struct pollfd){.fd = pad_hub_fd(m->hub), .events = POLLIN};
        double wait = until - now_s();
        if (wait < 0) wait = 0;
        struct timespec ts = {(time_t)wait, (long)((wait - (time_t)wait) * 1e9)};
        if (ppoll(pf, n, &ts, NULL) < 0 && errno != EINTR) {
            fprintf(stderr, "%s: commander: poll: %s\n", g_prog, strerror(errno));
            rc = 1;
            break;
        }
        drain_pads(m);
        if (m->disp) {
            cmdr_display_events(m->disp, &keys);
            if (keys.quit) break;
            if (keys.changed && keys.any && !(m->pending_input > 0)) m->pending_input = now_s();
            if (keys.click) { /* pan to the clicked point of the ground */
                cmdr_camera_click(&m->cam, m->w, m->h, keys.click_x, keys.click_y);
                m->need_view = true;
            }
        }
        tick(m, m->disp ? &keys : NULL);
        drain_socket(m);
        show_frame(m);
        if (m->disp && now_s() >= next_overlay) { /* marks fade, status expires: redraw now and then */
            cmdr_overlay ov;
            fill_overlay(m, &ov);
            cmdr_display_present(m->disp, &ov);
            next_overlay = now_s() + 0.1;
        }
    }
    if (m->disp && m->shot) {
        cmdr_overlay ov;
        fill_overlay(m, &ov);
        if (cmdr_display_screenshot(m->disp, &ov, m->shot, err, sizeof err)) {
            fprintf(stderr, "%s: commander: %s\n", g_prog, err);
            rc = 1;
        }
    }
    if (m->stats) print_stats(m);
    if (!m->ever_connected) {
        fprintf(stderr, "%s: commander: never reached the daemon\n", g_prog);
        rc = 3;
    }
out:
    pad_hub_close(m->hub);
    cmdr_display_close(m->disp);
    if (m->log) fclose(m->log);
    if (m->c) vtc_close(m->c);
    k->c = NULL;
    free(m->jpeg);
    free(m);
    return rc;
}
