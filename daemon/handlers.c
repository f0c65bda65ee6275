/*
 * handlers.c — vantaged's messages: each request decoded, checked against
 * the client's role, applied to the scene (edits under the scene lock,
 * exclusive) or handed to the query workers (shared), and answered.
 */
#include "server_internal.h"
#include "cluster.h"
#include "errmap.h"
#include "vt_soft.h"

#include <errno.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* ---- handlers ---------------------------------------------------------------- */

bool editor(server *s, conn *c, uint32_t req)
{
    if (c->role >= VP_ROLE_EDITOR) return true;
    send_error(s, c, req, VP_ERR_AUTH, UINT32_MAX, "editing needs the editor role");
    return false;
}

/* Commands (DESTROY, MARK): a commander's, and an editor's. */
static bool commander(server *s, conn *c, uint32_t req)
{
    if (c->role >= VP_ROLE_COMMANDER) return true;
    send_error(s, c, req, VP_ERR_AUTH, UINT32_MAX, "commands need the commander role");
    return false;
}

/* MARK: pushed as MARKED to every connection subscribed to marks, and
 * kept for the frames to draw (frame_marks.h). Each copy goes through
 * that connection's output limit: a subscriber that does not read is
 * dropped by it, as for any reply. */
static void on_mark(server *s, conn *c, const vp_header *h, const uint8_t *p)
{
    if (!commander(s, c, h->req)) return;
    vp_marked m = {.client_id = c->id};
    int rc = vp_dec_mark(p, h->len, &m.m);
    if (rc) {
        send_error(s, c, h->req, rc, UINT32_MAX, vp_strerror(rc));
        return;
    }
    mark_store_add(&s->marks, &m, now_ns()); /* drawn into frames while it lives */
    uint32_t sent = 0;
    for (uint32_t i = 0; i < s->nconns; i++) {
        conn *o = s->live[i];
        vp_writer w;
        if (!(o->sub_kinds & VP_EVENT_MARKS) || o->closing) continue;
        if (!out_reserve(o, VP_HEADER_SIZE + VP_MARKED_SIZE, &w)) {
            o->closing = true;
            continue;
        }
        vp_enc_marked(&w, &m);
        out_commit(o, &w);
        sent++;
    }
    reply_ack(c, h->req, s->sc->epoch, sent);
}

/* The shared selection as SELECTED to o (subscribed to it): false when
 * o's output limit drops it. Loop thread (the selection's only writer). */
static bool push_selected(server *s, conn *o)
{
    vp_writer w;
    if (!out_reserve(o, vp_size_selected(s->marks.selected.count), &w)) {
        o->closing = true;
        return false;
    }
    vp_enc_selected(&w, &s->marks.selected, s->marks.sel);
    out_commit(o, &w);
    return true;
}

/* SELECT: the scene's shared selection replaced, pushed as SELECTED to
 * every connection subscribed to it (the sender's too: every client shows
 * the same), and outlined in frames (frame_marks.h). */
static void on_select(server *s, conn *c, const vp_header *h, const uint8_t *p)
{
    if (!commander(s, c, h->req)) return;
    vp_select sel;
    char why[160];
    int rc = vp_dec_select(p, h->len, &sel, why, sizeof why);
    if (rc) {
        send_error(s, c, h->req, rc, UINT32_MAX, why[0] ? why : vp_strerror(rc));
        return;
    }
    mark_store_select(&s->marks, c->id, &sel);
    uint32_t sent = 0;
    for (uint32_t i = 0; i < s->nconns; i++) {
        conn *o = s->live[i];
        if ((o->sub_kinds & VP_EVENT_SELECTION) && !o->closing) sent += push_selected(s, o);
    }
    reply_ack(c, h->req, s->sc->epoch, sent);
}

void reply_ack(conn *c, uint32_t req, uint64_t epoch, uint32_t count)
{
    vp_writer w;
    if (!out_reserve(c, VP_HEADER_SIZE + 12, &w)) {
        c->closing = true;
        return;
    }
    vp_enc_ack(&w, req, &(vp_ack){.epoch = epoch, .count = count});
    out_commit(c, &w);
}

static void on_hello(server *s, conn *c, const vp_header *h, const uint8_t *p)
{
    vp_hello m;
    int rc = vp_dec_hello(p, h->len, &m);
    if (rc == VP_ERR_VERSION) {
        /* say both sides' versions, so an old client's user knows what to upgrade */
        char msg[160];
        if (VP_VERSION_MIN == VP_VERSION)
            snprintf(msg, sizeof msg, "unsupported protocol version %u: this server speaks version %u only",
                     m.version, VP_VERSION);
        else
            snprintf(msg, sizeof msg, "unsupported protocol version %u: this server speaks versions %u..%u",
                     m.version, VP_VERSION_MIN, VP_VERSION);
        send_error(s, c, h->req, rc, UINT32_MAX, msg);
        c->closing = true;
        return;
    }
    if (rc) {
        send_error(s, c, h->req, rc, UINT32_MAX, vp_strerror(rc));
        c->closing = true; /* not our protocol, or a malformed HELLO */
        return;
    }
    /* roles and tokens (auth.h): with a token file, a role needs a token
       of it or a higher one; without one every role is granted (the
       daemon then listens on loopback only, unless --insecure) */
    if (s->cfg.tokens && !auth_grants(s->cfg.tokens, m.role, m.token, m.token_len)) {
        static const char *const names[] = {"viewer", "commander", "editor"};
        s->m.auth_failures++;
        LOGW("client %u: refused the %s role (%s token)", c->id, names[m.role], m.token_len ? "wrong" : "no");
        send_error(s, c, h->req, VP_ERR_AUTH, UINT32_MAX,
                   m.token_len ? "that token does not grant this role"
                               : "this daemon needs a token for this role (vantage --token, or VANTAGE_TOKEN)");
        c->closing = true;
        return;
    }
    c->role = m.role;
    c->hello = true;
    size_t n = m.name_len < sizeof c->name - 1 ? m.name_len : sizeof c->name - 1;
    for (size_t i = 0; i < n; i++) c->name[i] = (m.name[i] >= 32 && m.name[i] < 127) ? (char)m.name[i] : '?';
    c->name[n] = 0;
    vp_writer w;
    if (!out_reserve(c, VP_HEADER_SIZE + 28, &w)) {
        c->closing = true;
        return;
    }
    vp_enc_hello_ok(&w, h->req,
                    &(vp_hello_ok){.version = VP_VERSION, .role = (uint8_t)c->role, .max_payload = s->cfg.max_payload,
                                   .max_batch = s->cfg.max_batch, .max_views = VP_MAX_VIEWS,
                                   .epoch = s->sc->epoch, .client_id = c->id});
    out_commit(c, &w);
    LOGD("client %u (%s) hello, role %d", c->id, c->name, c->role);
}

static void on_stats(server *s, conn *c, uint32_t req)
{
    cull_world_info info;
    cull_world_info_get(s->sc->world, &info);
    vp_stats_reply m = {.epoch = s->sc->epoch, .uptime_ms = ae_now_ms() - s->start_ms, .entities = info.entities,
                        .static_entities = info.static_entities, .dynamic_entities = info.dynamic_entities,
                        .regions = info.regions, .cells = info.cells, .connections = s->nconns,
                        .meshes = s->sc->nmeshes, .occluders = (uint32_t)s->sc->occluders.count,
                        .lights = (uint32_t)s->sc->lights.count, .queries = s->queries, .edits = s->sc->edits,
                        .bytes_in = s->bytes_in, .bytes_out = s->bytes_out, .errors = s->errors};
    vp_writer w;
    if (!out_reserve(c, VP_HEADER_SIZE + 92, &w)) {
        c->closing = true;
        return;
    }
    vp_enc_stats_reply(&w, req, &m);
    out_commit(c, &w);
}

/* ---- the workers' side ---------------------------------------------------------- */

void job_error(job *j, int code, uint32_t index, const char *msg)
{
    j->code = code;
    j->reply_len = VP_HEADER_SIZE + 10 + VP_MAX_ERROR_MSG; /* the escaped message may be longer */
    j->reply = malloc(j->reply_len);
    if (j->reply) {
        vp_writer w;
        vp_writer_init(&w, j->reply, j->reply_len);
        vp_enc_error(&w, j->h.req, code, index, msg);
        j->reply_len = w.len;
    }
}

int view_from(const vp_view *pv, uint32_t index, cull_view *v, char *msg, size_t msglen)
{
    cull_view_desc d = {.depth_mode = pv->depth_mode, .viewport_w = pv->viewport_w, .viewport_h = pv->viewport_h};
    memcpy(d.origin, pv->origin, sizeof d.origin);
    memcpy(d.view_proj, pv->view_proj, sizeof d.view_proj);
    int rc = cull_view_init(v, &d);
    if (!rc) return VP_OK;
    if (index == UINT32_MAX) snprintf(msg, msglen, "view: %s", cull_strerror(rc));
    else snprintf(msg, msglen, "view %u: %s", index, cull_strerror(rc));
    return vp_code_from_cull(rc);
}

bool worker_res_reserve(worker *wk, size_t need)
{
    if (need <= wk->res_cap) return true;
    cull_result *r = realloc(wk->res, need * sizeof *r);
    if (!r) return false;
    wk->res = r;
    wk->res_cap = need;
    return true;
}

/* Decodes, culls and encodes one query into a new frame. The caller holds
 * scene_lock shared. */
static void run_query(const scene *sc, worker *wk, job *j)
{
    uint64_t t0 = now_ns();
    const vp_header *h = &j->h;
    char msg[96] = "";
    int code = VP_OK;
    uint32_t index = UINT32_MAX;
    vp_writer w;
    vp_vis_query q;
    cull_view views[VP_MAX_VIEWS];
    size_t n = 0;
    cull_query_stats st;
    int rc = vp_dec_vis_query(j->payload, h->len, &q);
    if (rc) {
        code = rc;
        snprintf(msg, sizeof msg, "%s", vp_strerror(rc));
        goto error;
    }
    for (uint32_t i = 0; i < q.view_count; i++) {
        vp_view v;
        vp_view_get(&q, i, &v);
        if ((code = view_from(&v, i, &views[i], msg, sizeof msg))) {
            index = i;
            goto error;
        }
    }
    bool count_only = (q.flags & VP_Q_COUNT_ONLY) != 0;
    if (!count_only && !worker_res_reserve(wk, cull_query_bound(sc->world))) {
        code = VP_ERR_BUSY;
        snprintf(msg, sizeof msg, "out of memory for results");
        goto error;
    }
    /* the sub-levels it sees: the visible ones, within its own list */
    const uint64_t *only = NULL;
    if (q.nsub) {
        memset(wk->only, 0, sizeof wk->only);
        for (uint32_t i = 0; i < q.nsub; i++) {
            uint16_t id = vp_query_sublevel_get(&q, i);
            wk->only[id >> 6] |= 1ull << (id & 63);
        }
        only = wk->only;
    }
    const uint64_t *subs = scene_visible(sc, only, wk->vis);
    uint32_t flags = 0;
    if (q.flags & VP_Q_NO_AABB) flags |= CULL_Q_NO_AABB;
    if (q.flags & VP_Q_WANT_AREA) flags |= CULL_Q_WANT_AREA;
    if (q.flags & VP_Q_STATIC_ONLY) flags |= CULL_Q_STATIC_ONLY;
    if (q.flags & VP_Q_DYNAMIC_ONLY) flags |= CULL_Q_DYNAMIC_ONLY;
    if (q.flags & VP_Q_NO_OCCLUSION) flags |= CULL_Q_NO_OCCLUSION;
    if (q.flags & VP_Q_OCC_CENTRE) flags |= CULL_Q_OCC_CENTRE;
    if (count_only) flags |= CULL_Q_COUNT_ONLY;
    uint64_t t1 = now_ns();
    rc = cull_query(sc->world, wk->ctx,
                    &(cull_query_desc){.views = views, .view_count = q.view_count, .flags = flags,
                                       .min_screen_area = q.min_area, .sublevels = subs},
                    count_only ? NULL : wk->res, count_only ? 0 : wk->res_cap, &n, &st);
    uint64_t t2 = now_ns();
    if (rc) {
        code = vp_code_from_cull(rc);
        snprintf(msg, sizeof msg, "%s", cull_strerror(rc));
        goto error;
    }
    uint32_t count = count_only ? 0 : (uint32_t)n;
    j->reply_len = vp_size_vis_result(count);
    j->reply = malloc(j->reply_len);
    if (!j->reply) {
        code = VP_ERR_BUSY;
        snprintf(msg, sizeof msg, "out of memory for the reply");
        goto error;
    }
    vp_writer_init(&w, j->reply, j->reply_len);
    vp_vis_result m = {.epoch = sc->epoch, .tested = st.entities_tested, .visible = (uint32_t)n, .count = count};
    m.stage_ns[1] = (uint32_t)(t2 - t1); /* cells and entities: one fused pass */
    m.stage_ns[4] = (uint32_t)(t1 - t0); /* decode and view set-up */
    m.stage_ns[5] = (uint32_t)st.occ_raster_ns; /* part of [1] */
    vp_enc_vis_result_begin(&w, h->req, &m);
    for (uint32_t i = 0; i < count; i++) {
        const cull_result *r = &wk->res[i];
        vp_put_vis_rec(&w, &(vp_vis_rec){.id = scene_id_of(sc, r->handle), .handle = r->handle,
                                         .view_mask = r->view_mask, .class_id = r->class_id,
                                         .sublevel = r->sublevel, .area = r->screen_area});
    }
    vp_frame_end(&w);
    /* the writing and total times are known only now: patch them in */
    uint64_t t3 = now_ns();
    uint8_t *ns = j->reply + VP_HEADER_SIZE + 16;
    uint32_t write_ns = (uint32_t)(t3 - t2), total = (uint32_t)(t3 - t0);
    for (int k = 0; k < 4; k++) {
        ns[2 * 4 + k] = (uint8_t)(write_ns >> (8 * k));
        ns[3 * 4 + k] = (uint8_t)(total >> (8 * k));
    }
    /* metrics: recorded on the loop when the reply is queued */
    uint32_t cull_ns = (uint32_t)(t2 - t1), raster_ns = (uint32_t)st.occ_raster_ns;
    j->has_query = true;
    j->mq = (metrics_query){
        .stage_ns = {(uint32_t)(t1 - t0), cull_ns > raster_ns ? cull_ns - raster_ns : 0, raster_ns, write_ns},
        .total_ns = total,
        .entities = {st.entities_tested, st.after_spheres, st.after_aabb, st.after_area, st.after_occlusion,
                     (uint32_t)n},
        .cells = {st.cells, st.cells_culled, st.cells_filtered, st.cells_occluded},
        .occ_kept = st.occ_reused,
        .occ_rendered = st.occ_rendered};
    j->ok = true;
    return;
error:
    job_error(j, code, index, msg);
}


/* Queries a worker takes in a row, at most, while frames wait. */
#define FAST_RUN 8u

void *worker_main(void *arg)
{
    server *s = arg;
    worker wk = {0};
    if (cull_ctx_create(NULL, &wk.ctx)) return NULL;
    for (;;) {
        pthread_mutex_lock(&s->mu);
        while (!s->jobs_head && !s->fast_head && !s->stopping) pthread_cond_wait(&s->cv, &s->mu);
        if (!s->jobs_head && !s->fast_head) {
            pthread_mutex_unlock(&s->mu);
            break;
        }
        /* queries (tens of microseconds to a few ms) before frames (several
           ms each, and 64 viewers queue 64 of them): a query no longer waits
           behind every frame due. A frame still goes after FAST_RUN queries
           in a row, so a query storm slows streams but cannot stop them. */
        job *j;
        if (s->fast_head && (!s->jobs_head || wk.fast_run < FAST_RUN)) {
            j = s->fast_head;
            s->fast_head = j->next;
            if (!s->fast_head) s->fast_tail = NULL;
            wk.fast_run = s->jobs_head ? wk.fast_run + 1 : 0;
        } else {
            j = s->jobs_head;
            s->jobs_head = j->next;
            if (!s->jobs_head) s->jobs_tail = NULL;
            wk.fast_run = 0;
        }
        pthread_mutex_unlock(&s->mu);

        pthread_rwlock_rdlock(&s->scene_lock);
        if (j->h.type == VP_RENDER) run_render(s, &wk, j);
        else if (j->h.type == VP_LIGHT_QUERY) run_light_query(s, &wk, j);
        else run_query(s->sc, &wk, j);
        if (!wk.scene_released) pthread_rwlock_unlock(&s->scene_lock);
        wk.scene_released = false;

        j->next = NULL;
        pthread_mutex_lock(&s->mu);
        if (s->done_tail) s->done_tail->next = j;
        else s->done_head = j;
        s->done_tail = j;
        pthread_mutex_unlock(&s->mu);
        uint64_t one = 1;
        ssize_t ignored = write(s->done_fd, &one, sizeof one);
        (void)ignored;
    }
    free(wk.res);
    free(wk.mesh_of);
    vt_soft_destroy(wk.soft);
    cull_pool_destroy(wk.pool);
    cull_ctx_destroy(wk.ctx);
    return NULL;
}

void job_submit(server *s, job *j)
{
    s->m.jobs_submitted++; /* on the loop: every job is submitted from it */
    pthread_mutex_lock(&s->mu);
    job **head = &s->jobs_head, **tail = &s->jobs_tail;
    if (j->h.type != VP_RENDER) head = &s->fast_head, tail = &s->fast_tail; /* frames (streams too) are RENDERs */
    if (*tail) (*tail)->next = j;
    else *head = j;
    *tail = j;
    pthread_cond_signal(&s->cv);
    pthread_mutex_unlock(&s->mu);
}

/* Loop side: hands the query to the workers; the connection reads no
 * further frames until its reply is back, so replies keep request order. */
static void on_query(server *s, conn *c, const vp_header *h, const uint8_t *p)
{
    job *j = calloc(1, sizeof *j);
    uint8_t *copy = malloc(h->len ? h->len : 1);
    if (!j || !copy) {
        free(j);
        free(copy);
        send_error(s, c, h->req, VP_ERR_BUSY, UINT32_MAX, "out of memory");
        return;
    }
    memcpy(copy, p, h->len);
    *j = (job){.fd = c->fd, .conn_id = c->id, .h = *h, .payload = copy, .t0 = s->m.cur_t0};
    c->busy = true;
    job_submit(s, j);
}

static void on_list(server *s, conn *c, const vp_header *h, const uint8_t *p)
{
    vp_list m;
    int rc = vp_dec_list(p, h->len, s->cfg.max_batch, &m);
    if (rc) {
        send_error(s, c, h->req, rc, UINT32_MAX, vp_strerror(rc));
        return;
    }
    /* the cursor is a slot index in the id map + 1; stable while the scene
       does not change between pages (the reply's epoch tells) */
    const idmap *ids = &s->sc->ids;
    vp_entity *e = malloc((size_t)m.max * sizeof *e);
    if (!e) {
        send_error(s, c, h->req, VP_ERR_BUSY, UINT32_MAX, "out of memory");
        return;
    }
    size_t i = m.cursor ? (size_t)(m.cursor - 1) : 0;
    uint32_t n = 0;
    for (; i < ids->cap && n < m.max; i++)
        if (ids->used[i]) scene_entity_record(s->sc, (cull_handle)ids->vals[i], &e[n++]);
    while (i < ids->cap && !ids->used[i]) i++;
    uint64_t next = i < ids->cap ? i + 1 : 0;
    vp_writer w;
    if (out_reserve(c, VP_HEADER_SIZE + 20 + (size_t)n * VP_ENTITY_REC_SIZE, &w)) {
        vp_enc_list_reply(&w, h->req, next, s->sc->epoch, e, n);
        out_commit(c, &w);
    } else {
        c->closing = true;
    }
    free(e);
}

/* Edit and lookup batches hold 1..max_batch records (the decoder checks
 * the top). */
static int batch_count(uint32_t n)
{
    return n ? VP_OK : VP_ERR_COUNT;
}

static void on_get(server *s, conn *c, const vp_header *h, const uint8_t *p)
{
    vp_id_batch b;
    int rc = vp_dec_ids(p, h->len, s->cfg.max_batch, &b);
    if (!rc) rc = batch_count(b.count);
    if (rc) {
        send_error(s, c, h->req, rc, UINT32_MAX, vp_strerror(rc));
        return;
    }
    vp_entity *e = malloc(((size_t)b.count + 1) * sizeof *e);
    if (!e) {
        send_error(s, c, h->req, VP_ERR_BUSY, UINT32_MAX, "out of memory");
        return;
    }
    for (uint32_t i = 0; i < b.count; i++) {
        uint64_t hd;
        if (!idmap_get(&s->sc->ids, vp_id_get(&b, i), &hd)) {
            char msg[96];
            snprintf(msg, sizeof msg, "record %u: no entity with id %llu", i, (unsigned long long)vp_id_get(&b, i));
            send_error(s, c, h->req, VP_ERR_UNKNOWN_ID, i, msg);
            free(e);
            return;
        }
        scene_entity_record(s->sc, (cull_handle)hd, &e[i]);
    }
    vp_writer w;
    if (out_reserve(c, VP_HEADER_SIZE + 20 + (size_t)b.count * VP_ENTITY_REC_SIZE, &w)) {
        vp_enc_list_reply(&w, h->req, 0, s->sc->epoch, e, b.count);
        out_commit(c, &w);
    } else {
        c->closing = true;
    }
    free(e);
}

static void on_sublevel_list(server *s, conn *c, uint32_t req)
{
    uint32_t n = s->sc->nsublevels;
    const char **names = malloc(((size_t)n + 1) * sizeof *names);
    uint16_t *ids = malloc(((size_t)n + 1) * sizeof *ids);
    vp_writer w;
    if (names && ids && out_reserve(c, VP_HEADER_SIZE + 4 + (size_t)n * 258, &w)) {
        for (uint32_t i = 0; i < n; i++) {
            names[i] = s->sc->sl[i + 1].name;
            ids[i] = (uint16_t)(i + 1);
        }
        vp_enc_names(&w, VP_SUBLEVEL_LIST_REPLY, req, names, ids, n);
        out_commit(c, &w);
    } else {
        send_error(s, c, req, VP_ERR_BUSY, UINT32_MAX, "out of memory");
    }
    free(names);
    free(ids);
}

/* ---- edits ----------------------------------------------------------------------------- */

/* An applied edit goes down the cluster's stream (the writer); one that
 * cannot is fatal: the scene holds what the stream does not, and no
 * answer may leave. Returns the stream sequence its answer waits for (0:
 * no cluster, or the answer waits for nothing). */
static uint64_t cluster_record(server *s, const edit *e, const uint8_t *p, uint32_t len)
{
    if (!s->cluster) return 0;
    uint64_t seq = cluster_publish(s->cluster, e, p, len);
    if (!seq) {
        LOGE("an applied edit (%s) could not be published to the cluster's stream: exiting (a restart joins the "
             "cluster from the stream)", vp_type_name(e->type));
        _exit(3);
    }
    return cluster_waits(s->cluster) ? seq : 0;
}

/* A change the daemon makes itself (a loading connection gone) goes
 * through the journal too; one that cannot be journaled is still made, and
 * the journal stops taking edits (replay would miss it). */
static int internal_edit(server *s, uint16_t type, uint16_t sublevel, uint32_t aux, edit_result *r, scene_err *err)
{
    edit e = {.type = type, .sublevel = sublevel, .aux = aux};
    int code;
    if (s->cluster && !cluster_writable(s->cluster, &code, err->msg, sizeof err->msg)) {
        err->code = code;
        return code; /* a replica's scene changes only down the stream */
    }
    pthread_rwlock_wrlock(&s->scene_lock);
    int rc = journal_apply(s->journal, s->sc, &e, NULL, 0, r, err);
    if (rc == VP_ERR_IO && s->journal) {
        journal_break(s->journal, "a change could not be journaled");
        rc = edit_apply(s->sc, &e, r, err);
    }
    pthread_rwlock_unlock(&s->scene_lock);
    if (!rc) cluster_record(s, &e, NULL, 0);
    return rc;
}

void sublevel_conn_gone(server *s, conn *c)
{
    if (!c->sublevel) return;
    edit_result r;
    scene_err err;
    if (internal_edit(s, VP_SUBLEVEL_ABORT, c->sublevel, 0, &r, &err))
        LOGW("client %u: its load could not be dropped: %s", c->id, err.msg);
    else
        LOGI("client %u gone while loading sub-level %s: %u entities thrown away", c->id, s->sc->sl[c->sublevel].name,
             r.n);
    edit_result_free(&r);
    c->sublevel = 0;
}

bool server_unload_slice(server *s, uint32_t budget)
{
    edit_result r;
    scene_err err;
    pthread_rwlock_wrlock(&s->scene_lock);
    /* a slice not journaled is not done (replay must free what this did) */
    edit work = {.type = EDIT_WORK, .aux = budget};
    bool done = journal_apply(s->journal, s->sc, &work, NULL, 0, &r, &err) == VP_OK;
    bool more = s->sc->unloading > 0;
    if (done && !more) cull_world_commit(s->sc->world);
    pthread_rwlock_unlock(&s->scene_lock);
    if (done) cluster_record(s, &work, NULL, 0);
    return done && more; /* a read-only journal stalls the unload: no busy wake-ups */
}

/* The reply to an applied edit. */
static void edit_reply(server *s, conn *c, const vp_header *h, const edit *e, const edit_result *r)
{
    vp_writer w;
    switch (h->type) {
    case VP_ENTITY_ADD:
        if (!out_reserve(c, VP_HEADER_SIZE + 12 + 4 * (size_t)e->count, &w)) break;
        vp_enc_add_reply(&w, h->req, s->sc->epoch, r->handles, e->count);
        out_commit(c, &w);
        return;
    case VP_SUBLEVEL_NAMES:
        if (!out_reserve(c, VP_HEADER_SIZE + 4 + 2 * (size_t)e->count, &w)) break;
        vp_enc_sublevel_ids(&w, h->req, r->ids, e->count);
        out_commit(c, &w);
        return;
    case VP_SUBLEVEL_BEGIN:
        c->sublevel = r->begun.id;
        LOGI("client %u (%s) loading sub-level %s (id %u, classes %u..%u)", c->id, c->name,
             s->sc->sl[r->begun.id].name, r->begun.id, r->begun.class_base,
             r->begun.class_base + e->u.begin.classes - (e->u.begin.classes ? 1 : 0));
        if (!out_reserve(c, VP_HEADER_SIZE + 16, &w)) break;
        vp_enc_sublevel_begun(&w, h->req, &r->begun);
        out_commit(c, &w);
        return;
    case VP_DESTROY:
        if (!out_reserve(c, VP_HEADER_SIZE + 24, &w)) break;
        vp_enc_destroyed(&w, h->req, &r->destroyed);
        out_commit(c, &w);
        return;
    case VP_SUBLEVEL_COMMIT:
    case VP_SUBLEVEL_ABORT:
        LOGI("client %u: sub-level %s %s, %u entities, epoch %llu", c->id, s->sc->sl[c->sublevel].name,
             h->type == VP_SUBLEVEL_COMMIT ? "loaded" : "load aborted", r->n, (unsigned long long)s->sc->epoch);
        c->sublevel = 0;
        reply_ack(c, h->req, s->sc->epoch, r->n);
        return;
    case VP_SUBLEVEL_UNLOAD:
        LOGI("client %u: sub-level %.*s unloaded at epoch %llu, %u entities to free", c->id, (int)e->u.name.len,
             (const char *)e->u.name.name, (unsigned long long)s->sc->epoch, r->n);
        reply_ack(c, h->req, s->sc->epoch, r->n);
        return;
    default:
        reply_ack(c, h->req, s->sc->epoch, r->n);
        return;
    }
    c->closing = true; /* no memory for the reply */
}

/* An edit: decoded, journaled (written before it is applied: a write that
 * fails refuses it with nothing changed), applied, answered. Under the
 * always policy the answer waits in the connection's buffer (c->held) for
 * the turn's sync. */
void on_edit(server *s, conn *c, const vp_header *h, const uint8_t *p)
{
    /* a destruction event is a command (the commander's "destroy at the
       reticle"); every other edit needs an editor */
    if (!(h->type == VP_DESTROY ? commander(s, c, h->req) : editor(s, c, h->req))) return;
    char why[300];
    int code;
    if (s->cluster && !cluster_writable(s->cluster, &code, why, sizeof why)) {
        send_error(s, c, h->req, code, UINT32_MAX, why); /* NOT_WRITER: the writer's endpoint first */
        return;
    }
    edit e;
    int rc = edit_decode(h->type, p, h->len, s->cfg.max_batch, EDIT_LAYOUT, &e);
    if (rc) {
        scene_err de;
        edit_explain(&e, rc, &de);
        send_error(s, c, h->req, rc, de.index, de.msg);
        return;
    }
    e.sublevel = c->sublevel;
    e.aux = h->type == VP_DESTROY ? s->cfg.destruct_res : h->type == VP_SUBLEVEL_BEGIN ? c->id : 0;
    edit_result r;
    scene_err err = {0};
    uint64_t t0 = now_ns();
    pthread_rwlock_wrlock(&s->scene_lock);
    rc = journal_apply(s->journal, s->sc, &e, p, h->len, &r, &err);
    pthread_rwlock_unlock(&s->scene_lock);
    if (rc) {
        if (rc == VP_ERR_IO) LOGW("client %u: %s", c->id, err.msg);
        send_error(s, c, h->req, rc, err.index, err.msg);
        return;
    }
    uint64_t wait = cluster_record(s, &e, p, h->len);
    if (wait) c->held_seq = wait;
    if (h->type == VP_DESTROY) r.destroyed.cut_us = (uint32_t)((now_ns() - t0) / 1000);
    edit_reply(s, c, h, &e, &r);
    edit_result_free(&r);
    if (s->journal && journal_policy(s->journal) == JOURNAL_ALWAYS) c->held = true;
}

/* METRICS: the exposition, as the HTTP endpoint serves it. */
static void on_metrics(server *s, conn *c, uint32_t req)
{
    vp_writer w;
    if (!metrics_expose(s, &s->mtext) || s->mtext.len > UINT32_MAX) {
        send_error(s, c, req, VP_ERR_BUSY, UINT32_MAX, "out of memory for the metrics");
        return;
    }
    if (!out_reserve(c, vp_size_metrics_reply((uint32_t)s->mtext.len), &w)) {
        c->closing = true;
        return;
    }
    vp_enc_metrics_reply(&w, req,
                         &(vp_metrics_reply){.format = VP_METRICS_PROMETHEUS, .text_len = (uint32_t)s->mtext.len,
                                             .text = (const uint8_t *)s->mtext.p});
    out_commit(c, &w);
}

static void on_sublevel_info(server *s, conn *c, uint32_t req)
{
    const scene *sc = s->sc;
    vp_writer w;
    if (!out_reserve(c, VP_HEADER_SIZE + 12 + (size_t)sc->nsublevels * (VP_SUBLEVEL_INFO_SIZE + VP_MAX_NAME), &w)) {
        c->closing = true;
        return;
    }
    vp_enc_sublevel_infos_begin(&w, req, sc->epoch, sc->nsublevels);
    for (uint32_t id = 1; id <= sc->nsublevels; id++) {
        const scene_sublevel *l = &sc->sl[id];
        vp_sublevel_info in = {.id = (uint16_t)id, .state = scene_sublevel_state(sc, (uint16_t)id),
                               .entities = sc->sl_entities[id], .occluders = l->occluders, .lights = l->lights,
                               .class_base = l->class_base, .classes = l->classes,
                               .name_len = (uint8_t)strlen(l->name), .name = (const uint8_t *)l->name};
        vp_put_sublevel_info(&w, &in);
    }
    vp_frame_end(&w);
    out_commit(c, &w);
}

void dispatch(server *s, conn *c, const vp_header *h, const uint8_t *p)
{
    if (!c->hello) {
        if (h->type == VP_HELLO) {
            on_hello(s, c, h, p);
        } else {
            send_error(s, c, h->req, VP_ERR_STATE, UINT32_MAX, "the first message must be HELLO");
            c->closing = true;
        }
        return;
    }
    int rc;
    switch (h->type) {
    case VP_HELLO:
        send_error(s, c, h->req, VP_ERR_STATE, UINT32_MAX, "already said hello");
        return;
    case VP_PING: {
        const uint8_t *data;
        uint32_t n;
        if ((rc = vp_dec_ping(p, h->len, &data, &n))) break;
        vp_writer w;
        if (!out_reserve(c, VP_HEADER_SIZE + n, &w)) {
            c->closing = true;
            return;
        }
        vp_enc_ping(&w, VP_PONG, h->req, data, n);
        out_commit(c, &w);
        return;
    }
    case VP_STATS:
        if ((rc = vp_dec_empty(p, h->len))) break;
        on_stats(s, c, h->req);
        return;
    case VP_METRICS:
        if ((rc = vp_dec_empty(p, h->len))) break;
        on_metrics(s, c, h->req);
        return;
    case VP_SUBSCRIBE: {
        uint32_t kinds;
        if ((rc = vp_dec_subscribe(p, h->len, &kinds))) break;
        s->nev_subs += (kinds & VP_EVENT_SCENE ? 1u : 0u) - (c->sub_kinds & VP_EVENT_SCENE ? 1u : 0u);
        c->sub_kinds = kinds;
        reply_ack(c, h->req, s->sc->epoch, 0);
        if (kinds & VP_EVENT_SELECTION) push_selected(s, c); /* where it stands now */
        return;
    }
    case VP_VIS_QUERY:
    case VP_LIGHT_QUERY:
    case VP_RENDER:
        on_query(s, c, h, p);
        return;
    case VP_FRAME_SUBSCRIBE:
        on_frame_subscribe(s, c, h, p);
        return;
    case VP_FRAME_UNSUBSCRIBE:
        on_frame_unsubscribe(s, c, h, p);
        return;
    case VP_MARK:
        on_mark(s, c, h, p);
        return;
    case VP_SELECT:
        on_select(s, c, h, p);
        return;
    case VP_ENTITY_LIST:
        on_list(s, c, h, p);
        return;
    case VP_ENTITY_GET:
        on_get(s, c, h, p);
        return;
    case VP_SUBLEVEL_LIST:
        if ((rc = vp_dec_empty(p, h->len))) break;
        on_sublevel_list(s, c, h->req);
        return;
    case VP_SUBLEVEL_INFO:
        if ((rc = vp_dec_empty(p, h->len))) break;
        on_sublevel_info(s, c, h->req);
        return;
    case VP_TEXTURE_PUT:
        if (editor(s, c, h->req)) upload_chunk(s, c, h, p);
        return;
    case VP_ENV_GET:
        if ((rc = vp_dec_empty(p, h->len))) break;
        on_env_get(s, c, h->req);
        return;
    default: {
        if (readback_dispatch(s, c, h, p)) return;
        if (edit_is(h->type)) {
            on_edit(s, c, h, p);
            return;
        }
        char msg[80];
        snprintf(msg, sizeof msg, "type 0x%04x (%s) is not a request", h->type, vp_type_name(h->type));
        send_error(s, c, h->req, VP_ERR_TYPE, UINT32_MAX, msg);
        return;
    }
    }
    send_error(s, c, h->req, rc, UINT32_MAX, vp_strerror(rc));
}

