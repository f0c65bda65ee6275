/*
 * scenario_events.c — the parts of a `bench --scenario` run that make
 * blocking calls on connections of their own: the setup entities, the
 * timeline (sub-level loads and unloads, destruction barrages) and the
 * end-to-end probes (edit -> visible in a query, in a frame).
 */
#include "scenario_run.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

int add_many(vtc_client *c, uint64_t base, uint32_t n, double spread, double height, uint16_t sublevel,
             uint64_t seed)
{
    uint32_t max = vtc_server(c)->max_batch, step = max < 4096 ? max : 4096;
    vp_entity *b = calloc(step, sizeof *b);
    if (!b) return VTC_ERR_IO;
    uint64_t x = seed;
    int rc = 0;
    for (uint32_t i = 0; i < n && rc == 0; i += step) {
        uint32_t k = n - i < step ? n - i : step;
        for (uint32_t j = 0; j < k; j++) {
            double px = (splitmix_unit(&x) - 0.5) * spread, pz = (splitmix_unit(&x) - 0.5) * spread, h = 1 + splitmix_unit(&x) * height;
            double hw = 1 + splitmix_unit(&x) * 4;
            b[j] = (vp_entity){.id = base + i + j, .sublevel = sublevel, .flags = VP_ENT_DYNAMIC,
                               .aabb = {px - hw, 0, pz - hw, px + hw, h, pz + hw}};
        }
        rc = vtc_add(c, b, k, NULL, NULL);
    }
    free(b);
    return rc;
}

int remove_range(vtc_client *c, uint64_t base, uint32_t n)
{
    uint32_t max = vtc_server(c)->max_batch, step = max < 4096 ? max : 4096;
    uint64_t *ids = malloc(sizeof *ids * step);
    if (!ids) return VTC_ERR_IO;
    int rc = 0;
    for (uint32_t i = 0; i < n && rc == 0; i += step) {
        uint32_t k = n - i < step ? n - i : step;
        for (uint32_t j = 0; j < k; j++) ids[j] = base + i + j;
        rc = vtc_remove(c, ids, k, NULL);
        if (rc == VP_ERR_UNKNOWN_ID) /* a batch with one missing is refused whole: one by one */
            for (uint32_t j = 0; j < k && rc != VTC_ERR_IO; j++) rc = vtc_remove(c, ids + j, 1, NULL);
        if (rc == VP_ERR_UNKNOWN_ID) rc = 0;
    }
    free(ids);
    return rc;
}

static void sleep_until(run *r, double t)
{
    while (!stopping(r)) {
        double d = t - now_s();
        if (d <= 0) return;
        if (d > 0.05) d = 0.05;
        struct timespec ts = {0, (long)(d * 1e9)};
        nanosleep(&ts, NULL);
    }
}

void *events_thread(void *arg)
{
    events_arg *ea = arg;
    run *r = ea->r;
    const scenario *s = r->s;
    int order[SCN_MAX_EVENTS];
    for (int i = 0; i < s->nev; i++) order[i] = i;
    for (int i = 1; i < s->nev; i++) /* by time, stable */
        for (int j = i; j > 0 && s->ev[order[j]].at < s->ev[order[j - 1]].at; j--) {
            int tmp = order[j];
            order[j] = order[j - 1];
            order[j - 1] = tmp;
        }
    uint64_t x = s->seed ^ 0xE7E47ull;
    for (int oi = 0; oi < s->nev && !stopping(r); oi++) {
        const scn_event *e = &s->ev[order[oi]];
        sleep_until(r, r->t0 + e->at);
        if (stopping(r)) break;
        int rc = 0;
        double t1 = now_s();
        if (e->kind == SCN_EV_LOAD) {
            vp_sublevel_begun b;
            vp_ack a;
            rc = vtc_sublevel_begin(ea->c, e->name, 0, &b);
            if (!rc) rc = add_many(ea->c, LOAD_BASE + ((uint64_t)b.id << 24), e->n, e->spread, 20, b.id, x + (uint64_t)oi);
            if (!rc) rc = vtc_sublevel_commit(ea->c, &a);
            else (void)vtc_sublevel_abort(ea->c, &a);
            if (!rc) ea->loaded[order[oi]] = true;
            if (rc) r->ev_rows->errors[R_SL_LOAD]++;
            else note(r, r->ev_rows, R_SL_LOAD, t1, now_s() - t1);
        } else if (e->kind == SCN_EV_UNLOAD) {
            vp_ack a;
            rc = vtc_sublevel_unload(ea->c, e->name, &a);
            if (rc) r->ev_rows->errors[R_SL_UNLOAD]++;
            else note(r, r->ev_rows, R_SL_UNLOAD, t1, now_s() - t1);
            for (int j = 0; !rc && j < s->nev; j++)
                if (s->ev[j].kind == SCN_EV_LOAD && !strcmp(s->ev[j].name, e->name)) ea->loaded[j] = false;
        } else {
            double period = e->rate > 0 ? 1.0 / e->rate : 0;
            for (uint32_t i = 0; i < e->n && !stopping(r); i++) {
                if (period > 0) sleep_until(r, t1 + i * period);
                uint64_t id = SETUP_BASE + splitmix64(&x) % s->setup_n;
                vp_list_reply got;
                vp_destroy d = {.id = id, .radius = e->radius, .debris = e->debris};
                double ts = now_s();
                rc = vtc_get(ea->c, &id, 1, &got);
                vp_entity ent;
                if (rc == 0 && got.batch.count == 1 && vp_entity_get(&got.batch, 0, &ent) == 0) {
                    double diag2 = 0;
                    for (int a = 0; a < 3; a++) {
                        d.center[a] = ent.aabb[a] + splitmix_unit(&x) * (ent.aabb[3 + a] - ent.aabb[a]);
                        diag2 += (ent.aabb[3 + a] - ent.aabb[a]) * (ent.aabb[3 + a] - ent.aabb[a]);
                    }
                    /* a point of the entity's box; the daemon refuses a
                       sphere that misses the entity or is larger than its
                       diagonal (it would cover it all): a small entity
                       gets one that size */
                    if (diag2 > 0 && d.radius * d.radius > diag2) d.radius = sqrt(diag2);
                    ts = now_s();
                    vp_destroyed out;
                    rc = vtc_send_destruction(ea->c, &d, &out);
                }
                if (rc) r->ev_rows->errors[R_DESTROY]++;
                else note(r, r->ev_rows, R_DESTROY, ts, now_s() - ts);
                if (rc == VTC_ERR_IO) break;
                rc = 0;
            }
        }
        if (rc == VTC_ERR_IO) {
            fail_run(r, true, "events: %s", vtc_last_error(ea->c)->msg);
            break;
        }
    }
    return NULL;
}

/* The probe's own corner: 5 km below the scene, looking down. */
void probe_view(vp_view *v, uint16_t w, uint16_t h)
{
    const double eye[3] = {0, -5000, 0}, at[3] = {0, -5100, 0}, up[3] = {0, 0, 1};
    vtc_view_perspective(v, eye, at, up, 40, w, h, 1, 500);
}

static int probe_move(probe_arg *pa, bool in, uint64_t *epoch)
{
    vp_entity e = {.id = PROBE_ID, .flags = VP_ENT_DYNAMIC, .sphere = {in ? 0 : 30000, -5200, 0, 5}};
    return vtc_update(pa->ed, &e, 1, epoch);
}

void *probe_thread(void *arg)
{
    probe_arg *pa = arg;
    run *r = pa->r;
    const scenario *s = r->s;
    vp_view v;
    probe_view(&v, 64, 64);
    double next_q = r->t0 + (s->probe_query > 0 ? s->probe_query : 1e30);
    double next_f = r->t0 + (s->probe_frame > 0 ? s->probe_frame * 0.5 : 1e30);
    bool in = false;
    while (!stopping(r)) {
        bool frame = next_f < next_q;
        sleep_until(r, frame ? next_f : next_q);
        if (stopping(r)) break;
        in = !in;
        uint64_t epoch = 0;
        double t1 = now_s();
        int rc = probe_move(pa, in, &epoch);
        if (rc == 0 && !frame) {
            /* queried right after the ack: it must be in (PROTOCOL: acknowledged edits are in) */
            bool seen = false;
            for (int tries = 0; rc == 0 && !seen && tries < 1000; tries++) {
                vp_vis_result res;
                rc = vtc_query(pa->q, &v, 1, VP_Q_COUNT_ONLY, 0, &res);
                seen = rc == 0 && res.epoch >= epoch && (res.visible == 1) == in;
            }
            if (rc == 0 && !seen) rc = -1;
            if (rc) r->probe_rows->errors[R_EDIT_QUERY]++;
            else note(r, r->probe_rows, R_EDIT_QUERY, t1, now_s() - t1);
            next_q += s->probe_query;
        } else if (rc == 0) {
            for (;;) {
                vp_frame f;
                double left = t1 + 5 - now_s();
                if (left <= 0) {
                    rc = -1; /* not seen in 5 s: an error, not the end */
                    break;
                }
                rc = vtc_wait_frame(pa->fr, &f, (int)(left * 1e3) + 1);
                if (rc == VTC_ERR_IO && vtc_last_error(pa->fr)->timed_out) rc = -1;
                if (rc || (f.epoch >= epoch && (f.visible == 1) == in)) break;
            }
            if (rc) r->probe_rows->errors[R_EDIT_FRAME]++;
            else note(r, r->probe_rows, R_EDIT_FRAME, t1, now_s() - t1);
            next_f += s->probe_frame;
        }
        if (rc == VTC_ERR_IO) {
            fail_run(r, true, "probe: %s", vtc_last_error(frame ? pa->fr : pa->q)->msg);
            break;
        }
        double now = now_s();
        if (next_q < now) next_q = now; /* late: no catching up in a burst */
        if (next_f < now) next_f = now;
    }
    return NULL;
}
