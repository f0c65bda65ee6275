/*
 * server.c — vantaged's network side (see server.h).
 *
 * One event loop thread owns every socket and the scene. A connection
 * keeps its own input buffer, so a frame may arrive a byte at a time; the
 * frame's length is checked against the limit from the header alone, before
 * its payload is buffered. Edits are applied as they are decoded (a batch
 * is all or nothing, see scene.c); queries run on the scene as it stands,
 * on the culling pool's threads, so every query sees every edit
 * acknowledged before it and none half-applied. Replies go to a per-
 * connection output buffer flushed before the loop sleeps; a client that
 * leaves more than out_limit bytes unread is disconnected.
 */
#include "server.h"

#include "ae.h"
#include "log.h"

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <arpa/inet.h>
#include <pthread.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/eventfd.h>
#include <sys/signalfd.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <time.h>
#include <unistd.h>

typedef struct conn {
    int fd;
    uint32_t id;
    int role;
    bool hello, closing, subscribed;
    bool busy;          /* a query is with a worker: later frames wait */
    uint8_t *in;
    size_t in_len, in_cap;
    uint8_t *out;
    size_t out_len, out_pos, out_cap;
    uint32_t ev_added, ev_updated, ev_removed; /* coalesced, not yet sent */
    char name[64];
} conn;

struct server {
    server_config cfg;
    ae_loop *loop;
    int tcp_fd, unix_fd, sig_fd;
    conn **conns;           /* by fd */
    int conns_cap;
    uint32_t nconns, next_id;
    scene *sc;
    uint64_t start_ms, queries, bytes_in, bytes_out, errors;
    /* query workers: they read the scene under scene_lock (shared); the
       loop thread takes it exclusively to apply edits */
    pthread_rwlock_t scene_lock;
    pthread_mutex_t mu;
    pthread_cond_t cv;
    struct job *jobs_head, *jobs_tail;      /* to the workers */
    struct job *done_head, *done_tail;      /* back to the loop */
    int done_fd;                            /* eventfd: results are waiting */
    pthread_t *workers;
    uint32_t nworkers;
    bool stopping;
};

/* A query handed to a worker, and its reply coming back. */
typedef struct job {
    struct job *next;
    int fd;
    uint32_t conn_id;
    vp_header h;
    uint8_t *payload;   /* a copy of the request's payload */
    uint8_t *reply;     /* the encoded reply frame (VIS_RESULT or ERROR) */
    size_t reply_len;
    bool ok;
} job;

static uint64_t now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000000ull + (uint64_t)ts.tv_nsec;
}

/* ---- output ------------------------------------------------------------------ */

/* A writer over the connection's output buffer with room for need bytes. */
static bool out_reserve(conn *c, size_t need, vp_writer *w)
{
    if (c->out_pos == c->out_len) c->out_pos = c->out_len = 0;
    if (c->out_cap - c->out_len < need) {
        if (c->out_pos) { /* compact first */
            memmove(c->out, c->out + c->out_pos, c->out_len - c->out_pos);
            c->out_len -= c->out_pos;
            c->out_pos = 0;
        }
        if (c->out_cap - c->out_len < need) {
            size_t cap = c->out_cap ? c->out_cap : 4096;
            while (cap - c->out_len < need) cap *= 2;
            uint8_t *n = realloc(c->out, cap);
            if (!n) return false;
            c->out = n;
            c->out_cap = cap;
        }
    }
    vp_writer_init(w, c->out + c->out_len, c->out_cap - c->out_len);
    return true;
}

static void out_commit(conn *c, const vp_writer *w)
{
    if (!w->overflow) c->out_len += w->len;
}

static void send_error(server *s, conn *c, uint32_t req, int code, uint32_t index, const char *msg)
{
    vp_writer w;
    s->errors++;
    if (!out_reserve(c, VP_HEADER_SIZE + 10 + VP_MAX_ERROR_MSG, &w)) {
        c->closing = true;
        return;
    }
    vp_enc_error(&w, req, code, index, msg);
    out_commit(c, &w);
    LOGD("client %u: error %d (%s): %s", c->id, code, vp_strerror(code), msg ? msg : "");
}

static void conn_free(server *s, conn *c)
{
    ae_del(s->loop, c->fd, AE_READABLE | AE_WRITABLE);
    close(c->fd);
    s->conns[c->fd] = NULL;
    s->nconns--;
    LOGD("client %u (%s) disconnected, %u connected", c->id, c->name, s->nconns);
    free(c->in);
    free(c->out);
    free(c);
}

static void conn_event(ae_loop *l, int fd, void *data, int mask);

/* Writes what the socket takes now. false if the connection died. */
static bool conn_flush(server *s, conn *c)
{
    while (c->out_pos < c->out_len) {
        ssize_t n = write(c->fd, c->out + c->out_pos, c->out_len - c->out_pos);
        if (n > 0) {
            c->out_pos += (size_t)n;
            s->bytes_out += (uint64_t)n;
            continue;
        }
        if (n < 0 && errno == EINTR) continue;
        if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) break;
        return false;
    }
    if (c->out_pos == c->out_len) {
        c->out_pos = c->out_len = 0;
        if (ae_mask(s->loop, c->fd) & AE_WRITABLE) ae_del(s->loop, c->fd, AE_WRITABLE);
        return !c->closing;
    }
    if (c->out_len - c->out_pos > s->cfg.out_limit) {
        LOGW("client %u: %zu bytes unread, over the output limit: disconnecting", c->id, c->out_len - c->out_pos);
        return false;
    }
    if (!(ae_mask(s->loop, c->fd) & AE_WRITABLE)) ae_add(s->loop, c->fd, AE_WRITABLE, conn_event, s);
    return true;
}

static void conn_write(server *s, int fd)
{
    conn *c = s->conns[fd];
    if (c && !conn_flush(s, c)) conn_free(s, c);
}

/* ---- handlers ---------------------------------------------------------------- */

static bool editor(server *s, conn *c, uint32_t req)
{
    if (c->role >= VP_ROLE_EDITOR) return true;
    send_error(s, c, req, VP_ERR_AUTH, UINT32_MAX, "editing needs the editor role");
    return false;
}

static void reply_ack(conn *c, uint32_t req, uint64_t epoch, uint32_t count)
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
    if (rc) {
        send_error(s, c, h->req, rc, UINT32_MAX, vp_strerror(rc));
        c->closing = true; /* not our protocol, or not this version */
        return;
    }
    /* roles and tokens: the reliability issue adds token files; until then
       every role is granted (the default bind is loopback) */
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

/* Worker side: decodes, culls and encodes one query into a new frame. The
 * caller holds scene_lock shared. */
static void run_query(const scene *sc, cull_ctx *ctx, cull_result **res, size_t *res_cap, job *j)
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
        cull_view_desc d = {.depth_mode = v.depth_mode, .viewport_w = v.viewport_w, .viewport_h = v.viewport_h};
        memcpy(d.origin, v.origin, sizeof d.origin);
        memcpy(d.view_proj, v.view_proj, sizeof d.view_proj);
        int crc = cull_view_init(&views[i], &d);
        if (crc) {
            code = crc == CULL_ERR_VIEWPORT ? VP_ERR_INVALID : VP_ERR_MATRIX;
            index = i;
            snprintf(msg, sizeof msg, "view %u: %s", i, cull_strerror(crc));
            goto error;
        }
    }
    size_t need = cull_query_bound(sc->world);
    if (need > *res_cap) {
        cull_result *r = realloc(*res, need * sizeof *r);
        if (!r) {
            code = VP_ERR_BUSY;
            snprintf(msg, sizeof msg, "out of memory for results");
            goto error;
        }
        *res = r;
        *res_cap = need;
    }
    uint32_t flags = 0;
    if (q.flags & VP_Q_NO_AABB) flags |= CULL_Q_NO_AABB;
    if (q.flags & VP_Q_WANT_AREA) flags |= CULL_Q_WANT_AREA;
    if (q.flags & VP_Q_STATIC_ONLY) flags |= CULL_Q_STATIC_ONLY;
    if (q.flags & VP_Q_DYNAMIC_ONLY) flags |= CULL_Q_DYNAMIC_ONLY;
    uint64_t t1 = now_ns();
    rc = cull_query(sc->world, ctx,
                    &(cull_query_desc){.views = views, .view_count = q.view_count, .flags = flags,
                                       .min_screen_area = q.min_area},
                    *res, *res_cap, &n, &st);
    uint64_t t2 = now_ns();
    if (rc) {
        code = VP_ERR_INTERNAL;
        snprintf(msg, sizeof msg, "%s", cull_strerror(rc));
        goto error;
    }
    uint32_t count = (q.flags & VP_Q_COUNT_ONLY) ? 0 : (uint32_t)n;
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
    vp_enc_vis_result_begin(&w, h->req, &m);
    for (uint32_t i = 0; i < count; i++) {
        const cull_result *r = &(*res)[i];
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
    j->ok = true;
    return;
error:
    j->reply_len = VP_HEADER_SIZE + 10 + strlen(msg);
    j->reply = malloc(j->reply_len);
    if (j->reply) {
        vp_writer_init(&w, j->reply, j->reply_len);
        vp_enc_error(&w, h->req, code, index, msg);
    }
}

static void *worker_main(void *arg)
{
    server *s = arg;
    cull_ctx *ctx = NULL;
    cull_result *res = NULL;
    size_t res_cap = 0;
    if (cull_ctx_create(NULL, &ctx)) return NULL;
    for (;;) {
        pthread_mutex_lock(&s->mu);
        while (!s->jobs_head && !s->stopping) pthread_cond_wait(&s->cv, &s->mu);
        if (!s->jobs_head) {
            pthread_mutex_unlock(&s->mu);
            break;
        }
        job *j = s->jobs_head;
        s->jobs_head = j->next;
        if (!s->jobs_head) s->jobs_tail = NULL;
        pthread_mutex_unlock(&s->mu);

        pthread_rwlock_rdlock(&s->scene_lock);
        run_query(s->sc, ctx, &res, &res_cap, j);
        pthread_rwlock_unlock(&s->scene_lock);

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
    free(res);
    cull_ctx_destroy(ctx);
    return NULL;
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
    *j = (job){.fd = c->fd, .conn_id = c->id, .h = *h, .payload = copy};
    c->busy = true;
    pthread_mutex_lock(&s->mu);
    if (s->jobs_tail) s->jobs_tail->next = j;
    else s->jobs_head = j;
    s->jobs_tail = j;
    pthread_cond_signal(&s->cv);
    pthread_mutex_unlock(&s->mu);
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

static void on_get(server *s, conn *c, const vp_header *h, const uint8_t *p)
{
    vp_id_batch b;
    int rc = vp_dec_ids(p, h->len, s->cfg.max_batch, &b);
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

static void on_sublevel_names(server *s, conn *c, const vp_header *h, const uint8_t *p)
{
    vp_name_list nl;
    int rc = vp_dec_names(p, h->len, false, &nl);
    if (rc) {
        send_error(s, c, h->req, rc, UINT32_MAX, vp_strerror(rc));
        return;
    }
    uint16_t *ids = malloc(((size_t)nl.count + 1) * sizeof *ids);
    scene_err err;
    if (!ids) {
        send_error(s, c, h->req, VP_ERR_BUSY, UINT32_MAX, "out of memory");
        return;
    }
    pthread_rwlock_wrlock(&s->scene_lock);
    rc = scene_sublevel_ids(s->sc, &nl, ids, &err);
    pthread_rwlock_unlock(&s->scene_lock);
    vp_writer w;
    if (rc) send_error(s, c, h->req, rc, err.index, err.msg);
    else if (out_reserve(c, VP_HEADER_SIZE + 4 + 2 * (size_t)nl.count, &w)) {
        vp_enc_sublevel_ids(&w, h->req, ids, nl.count);
        out_commit(c, &w);
    } else {
        c->closing = true;
    }
    free(ids);
}

static void on_sublevel_list(server *s, conn *c, uint32_t req)
{
    uint32_t n = s->sc->nsublevels;
    const char **names = malloc(((size_t)n + 1) * sizeof *names);
    uint16_t *ids = malloc(((size_t)n + 1) * sizeof *ids);
    vp_writer w;
    if (names && ids && out_reserve(c, VP_HEADER_SIZE + 4 + (size_t)n * 258, &w)) {
        for (uint32_t i = 0; i < n; i++) {
            names[i] = s->sc->sublevel_name[i + 1];
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

static void after_edit(server *s, conn *c, uint32_t req, int rc, const scene_err *err, uint32_t count)
{
    if (rc) send_error(s, c, req, rc, err->index, err->msg);
    else reply_ack(c, req, s->sc->epoch, count);
}

static void dispatch(server *s, conn *c, const vp_header *h, const uint8_t *p)
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
    scene_err err = {0};
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
    case VP_SUBSCRIBE: {
        uint32_t kinds;
        if ((rc = vp_dec_subscribe(p, h->len, &kinds))) break;
        c->subscribed = kinds != 0;
        reply_ack(c, h->req, s->sc->epoch, 0);
        return;
    }
    case VP_VIS_QUERY:
        on_query(s, c, h, p);
        return;
    case VP_ENTITY_LIST:
        on_list(s, c, h, p);
        return;
    case VP_ENTITY_GET:
        on_get(s, c, h, p);
        return;
    case VP_SUBLEVEL_NAMES:
        if (!editor(s, c, h->req)) return;
        on_sublevel_names(s, c, h, p);
        return;
    case VP_SUBLEVEL_LIST:
        if ((rc = vp_dec_empty(p, h->len))) break;
        on_sublevel_list(s, c, h->req);
        return;
    case VP_ENTITY_ADD: {
        if (!editor(s, c, h->req)) return;
        vp_entity_batch b;
        if ((rc = vp_dec_entities(p, h->len, s->cfg.max_batch, &b))) break;
        if (!b.count) {
            rc = VP_ERR_COUNT; /* an empty batch: the spec says 1..max_batch */
            break;
        }
        uint32_t *handles = malloc(((size_t)b.count + 1) * sizeof *handles);
        if (!handles) {
            send_error(s, c, h->req, VP_ERR_BUSY, UINT32_MAX, "out of memory");
            return;
        }
        pthread_rwlock_wrlock(&s->scene_lock);
        rc = scene_add(s->sc, &b, handles, &err);
        pthread_rwlock_unlock(&s->scene_lock);
        if (rc) {
            send_error(s, c, h->req, rc, err.index, err.msg);
        } else {
            vp_writer w;
            if (out_reserve(c, VP_HEADER_SIZE + 12 + 4 * (size_t)b.count, &w)) {
                vp_enc_add_reply(&w, h->req, s->sc->epoch, handles, b.count);
                out_commit(c, &w);
            } else {
                c->closing = true;
            }
        }
        free(handles);
        return;
    }
    case VP_ENTITY_UPDATE: {
        if (!editor(s, c, h->req)) return;
        vp_entity_batch b;
        if ((rc = vp_dec_entities(p, h->len, s->cfg.max_batch, &b))) break;
        if (!b.count) {
            rc = VP_ERR_COUNT;
            break;
        }
        pthread_rwlock_wrlock(&s->scene_lock);
        rc = scene_update(s->sc, &b, &err);
        pthread_rwlock_unlock(&s->scene_lock);
        after_edit(s, c, h->req, rc, &err, b.count);
        return;
    }
    case VP_ENTITY_REMOVE:
    case VP_OCCLUDER_REMOVE:
    case VP_LIGHT_REMOVE: {
        if (!editor(s, c, h->req)) return;
        vp_id_batch b;
        if ((rc = vp_dec_ids(p, h->len, s->cfg.max_batch, &b))) break;
        if (!b.count) {
            rc = VP_ERR_COUNT;
            break;
        }
        pthread_rwlock_wrlock(&s->scene_lock);
        if (h->type == VP_ENTITY_REMOVE) rc = scene_remove(s->sc, &b, &err);
        else rc = scene_remove_ids(s->sc, h->type == VP_LIGHT_REMOVE ? &s->sc->lights : &s->sc->occluders, &b, &err);
        pthread_rwlock_unlock(&s->scene_lock);
        after_edit(s, c, h->req, rc, &err, b.count);
        return;
    }
    case VP_MESH_PUT: {
        if (!editor(s, c, h->req)) return;
        vp_mesh m;
        if ((rc = vp_dec_mesh(p, h->len, 0, &m))) break;
        pthread_rwlock_wrlock(&s->scene_lock);
        rc = scene_mesh_put(s->sc, &m, &err);
        pthread_rwlock_unlock(&s->scene_lock);
        after_edit(s, c, h->req, rc, &err, 1);
        return;
    }
    case VP_OCCLUDER_PUT: {
        if (!editor(s, c, h->req)) return;
        vp_occluder o;
        if ((rc = vp_dec_occluder(p, h->len, 0, &o))) break;
        pthread_rwlock_wrlock(&s->scene_lock);
        rc = scene_occluder_put(s->sc, &o, &err);
        pthread_rwlock_unlock(&s->scene_lock);
        after_edit(s, c, h->req, rc, &err, 1);
        return;
    }
    case VP_LIGHT_PUT: {
        if (!editor(s, c, h->req)) return;
        const uint8_t *recs;
        uint32_t n;
        if ((rc = vp_dec_lights(p, h->len, s->cfg.max_batch, &recs, &n))) break;
        pthread_rwlock_wrlock(&s->scene_lock);
        rc = scene_lights_put(s->sc, recs, n, &err);
        pthread_rwlock_unlock(&s->scene_lock);
        after_edit(s, c, h->req, rc, &err, n);
        return;
    }
    default: {
        char msg[80];
        snprintf(msg, sizeof msg, "type 0x%04x (%s) is not a request", h->type, vp_type_name(h->type));
        send_error(s, c, h->req, VP_ERR_TYPE, UINT32_MAX, msg);
        return;
    }
    }
    send_error(s, c, h->req, rc, UINT32_MAX, vp_strerror(rc));
}

/* ---- reading -------------------------------------------------------------------- */

static void conn_read(server *s, int fd);
static void conn_write(server *s, int fd);

/* One proc per fd in ae: readiness goes to the reader or the writer. */
static void conn_event(ae_loop *l, int fd, void *data, int mask)
{
    (void)l;
    if (mask & AE_READABLE) conn_read(data, fd);
    else if (mask & AE_WRITABLE) conn_write(data, fd);
}

/* Dispatches the whole frames buffered on c (until a query goes to a
 * worker), then flushes. May free c. */
static void conn_process(server *s, conn *c)
{
    size_t pos = 0;
    while (!c->closing && !c->busy) {
        vp_header h;
        size_t fs;
        uint32_t limit = c->hello ? s->cfg.max_payload : VANTAGED_PREHELLO_MAX;
        int rc = vp_frame_check(c->in + pos, c->in_len - pos, limit, &h, &fs);
        if (rc == VP_NEED_MORE) break;
        if (rc != VP_OK) {
            char msg[96];
            snprintf(msg, sizeof msg, "%s (payload %u bytes, limit %u)", vp_strerror(rc), h.len, limit);
            send_error(s, c, h.req, rc, UINT32_MAX, msg);
            c->closing = true; /* the stream can no longer be trusted */
            break;
        }
        dispatch(s, c, &h, c->in + pos + VP_HEADER_SIZE);
        pos += fs;
    }
    memmove(c->in, c->in + pos, c->in_len - pos);
    c->in_len -= pos;
    if (c->closing && !c->busy) {
        (void)conn_flush(s, c); /* best effort: let the client read why */
        conn_free(s, c);
        return;
    }
    if (!conn_flush(s, c)) conn_free(s, c);
}

/* Replies from the workers: append, then go on with the connection's input. */
static void on_done(ae_loop *l, int fd, void *data, int mask)
{
    (void)l;
    (void)mask;
    server *s = data;
    uint64_t v;
    ssize_t ignored = read(fd, &v, sizeof v);
    (void)ignored;
    pthread_mutex_lock(&s->mu);
    job *j = s->done_head;
    s->done_head = s->done_tail = NULL;
    pthread_mutex_unlock(&s->mu);
    while (j) {
        job *next = j->next;
        conn *c = s->conns[j->fd];
        if (c && c->id == j->conn_id) { /* still the same client */
            vp_writer w;
            if (!j->reply || !out_reserve(c, j->reply_len, &w)) {
                c->closing = true;
            } else {
                vp_put_bytes(&w, j->reply, j->reply_len);
                out_commit(c, &w);
                if (j->ok) s->queries++;
                else s->errors++;
            }
            c->busy = false;
            if (!(ae_mask(s->loop, c->fd) & AE_READABLE)) ae_add(s->loop, c->fd, AE_READABLE, conn_event, s);
            conn_process(s, c);
        }
        free(j->payload);
        free(j->reply);
        free(j);
        j = next;
    }
}

static void conn_read(server *s, int fd)
{
    conn *c = s->conns[fd];
    if (!c) return;
    uint32_t limit = c->hello ? s->cfg.max_payload : VANTAGED_PREHELLO_MAX;
    for (;;) {
        if (c->busy && c->in_len >= (size_t)limit + VP_HEADER_SIZE) {
            /* a query is out and a whole frame waits behind it: stop
               reading this client until the reply is back */
            ae_del(s->loop, fd, AE_READABLE);
            return;
        }
        if (c->in_cap - c->in_len < 65536) {
            size_t cap = c->in_cap ? c->in_cap * 2 : 65536;
            size_t most = (size_t)limit + VP_HEADER_SIZE + 65536;
            if (cap > most) cap = most;
            if (cap <= c->in_cap) break; /* full: parse what is there first */
            uint8_t *n = realloc(c->in, cap);
            if (!n) {
                conn_free(s, c);
                return;
            }
            c->in = n;
            c->in_cap = cap;
        }
        ssize_t n = read(fd, c->in + c->in_len, c->in_cap - c->in_len);
        if (n > 0) {
            c->in_len += (size_t)n;
            s->bytes_in += (uint64_t)n;
            if ((size_t)n < c->in_cap - c->in_len) break;
            continue;
        }
        if (n < 0 && errno == EINTR) continue;
        if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) break;
        conn_free(s, c); /* closed by the peer, or an error */
        return;
    }
    conn_process(s, c);
}

static void on_accept(ae_loop *l, int lfd, void *data, int mask)
{
    (void)mask;
    server *s = data;
    for (;;) {
        int fd = accept4(lfd, NULL, NULL, SOCK_NONBLOCK | SOCK_CLOEXEC);
        if (fd < 0) {
            if (errno == EINTR) continue;
            if (errno != EAGAIN && errno != EWOULDBLOCK) LOGW("accept: %s", strerror(errno));
            return;
        }
        if (s->nconns >= s->cfg.max_clients || fd >= s->conns_cap) {
            /* tell it why, best effort, and hang up */
            uint8_t buf[256];
            vp_writer w;
            vp_writer_init(&w, buf, sizeof buf);
            vp_enc_error(&w, 0, VP_ERR_LIMIT, UINT32_MAX, "too many connections");
            ssize_t ignored = write(fd, buf, w.len);
            (void)ignored;
            close(fd);
            LOGW("connection refused: %u connected, limit %u", s->nconns, s->cfg.max_clients);
            continue;
        }
        int one = 1;
        setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
        conn *c = calloc(1, sizeof *c);
        if (!c || ae_add(l, fd, AE_READABLE, conn_event, s) < 0) {
            free(c);
            close(fd);
            continue;
        }
        c->fd = fd;
        c->id = ++s->next_id;
        strcpy(c->name, "?");
        s->conns[fd] = c;
        s->nconns++;
        LOGD("client %u connected (fd %d), %u connected", c->id, fd, s->nconns);
    }
}

/* ---- the tick -------------------------------------------------------------------- */

static void before_sleep(ae_loop *l, void *data)
{
    (void)l;
    server *s = data;
    scene *sc = s->sc;
    bool changed = sc->ev_added || sc->ev_updated || sc->ev_removed;
    if (changed) {
        pthread_rwlock_wrlock(&s->scene_lock);
        cull_world_commit(sc->world);
        pthread_rwlock_unlock(&s->scene_lock);
    }
    for (int fd = 0; fd < s->conns_cap; fd++) {
        conn *c = s->conns[fd];
        if (!c) continue;
        if (changed && c->subscribed) {
            c->ev_added += sc->ev_added;
            c->ev_updated += sc->ev_updated;
            c->ev_removed += sc->ev_removed;
        }
        /* events coalesce while a subscriber is behind */
        if ((c->ev_added || c->ev_updated || c->ev_removed) && c->out_len - c->out_pos < 65536) {
            vp_writer w;
            if (out_reserve(c, VP_HEADER_SIZE + 28, &w)) {
                vp_enc_event(&w, &(vp_event){.kind = VP_EVENT_SCENE, .epoch = sc->epoch, .added = c->ev_added,
                                             .updated = c->ev_updated, .removed = c->ev_removed});
                out_commit(c, &w);
                c->ev_added = c->ev_updated = c->ev_removed = 0;
            }
        }
        if (c->out_len > c->out_pos && !conn_flush(s, c)) conn_free(s, c);
    }
    sc->ev_added = sc->ev_updated = sc->ev_removed = 0;
}

static void on_signal(ae_loop *l, int fd, void *data, int mask)
{
    (void)mask;
    (void)data;
    struct signalfd_siginfo si;
    if (read(fd, &si, sizeof si) == (ssize_t)sizeof si) {
        LOGI("signal %u: shutting down", si.ssi_signo);
        ae_stop(l);
    }
}

/* ---- listeners ------------------------------------------------------------------- */

static int listen_tcp(const char *addr, int port)
{
    struct sockaddr_in sa = {.sin_family = AF_INET, .sin_port = htons((uint16_t)port)};
    if (inet_pton(AF_INET, addr, &sa.sin_addr) != 1) {
        LOGE("--bind %s: not an IPv4 address", addr);
        return -1;
    }
    int fd = socket(AF_INET, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
    if (fd < 0) return -1;
    int one = 1;
    setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    if (bind(fd, (struct sockaddr *)&sa, sizeof sa) < 0 || listen(fd, 512) < 0) {
        LOGE("tcp %s:%d: %s", addr, port, strerror(errno));
        close(fd);
        return -1;
    }
    return fd;
}

static int listen_unix(const char *path)
{
    struct sockaddr_un sa = {.sun_family = AF_UNIX};
    if (strlen(path) >= sizeof sa.sun_path) {
        LOGE("unix socket path too long: %s", path);
        return -1;
    }
    strcpy(sa.sun_path, path);
    int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
    if (fd < 0) return -1;
    unlink(path); /* a stale socket from a previous run */
    if (bind(fd, (struct sockaddr *)&sa, sizeof sa) < 0 || listen(fd, 512) < 0) {
        LOGE("unix %s: %s", path, strerror(errno));
        close(fd);
        return -1;
    }
    return fd;
}

server *server_create(const server_config *cfg, scene *sc)
{
    server *s = calloc(1, sizeof *s);
    if (!s) return NULL;
    s->cfg = *cfg;
    s->sc = sc;
    s->tcp_fd = s->unix_fd = s->sig_fd = s->done_fd = -1;
    /* SIGINT and SIGTERM arrive through a signalfd on the loop: block them
       before any thread starts, so no worker inherits them unblocked */
    sigset_t set;
    sigemptyset(&set);
    sigaddset(&set, SIGINT);
    sigaddset(&set, SIGTERM);
    pthread_sigmask(SIG_BLOCK, &set, NULL);
    signal(SIGPIPE, SIG_IGN);
    s->conns_cap = (int)cfg->max_clients + 64;
    s->conns = calloc((size_t)s->conns_cap, sizeof *s->conns);
    s->loop = ae_create(s->conns_cap);
    s->done_fd = eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
    if (!s->conns || !s->loop || s->done_fd < 0 || s->done_fd >= s->conns_cap ||
        ae_add(s->loop, s->done_fd, AE_READABLE, on_done, s))
        goto fail;
    pthread_rwlockattr_t ra;
    pthread_rwlockattr_init(&ra);
    /* edits must not starve behind a steady stream of queries */
    pthread_rwlockattr_setkind_np(&ra, PTHREAD_RWLOCK_PREFER_WRITER_NONRECURSIVE_NP);
    pthread_rwlock_init(&s->scene_lock, &ra);
    pthread_rwlockattr_destroy(&ra);
    pthread_mutex_init(&s->mu, NULL);
    pthread_cond_init(&s->cv, NULL);
    s->nworkers = cfg->threads ? cfg->threads : (uint32_t)sysconf(_SC_NPROCESSORS_ONLN);
    if (s->nworkers < 1) s->nworkers = 1;
    s->workers = calloc(s->nworkers, sizeof *s->workers);
    if (!s->workers) goto fail;
    for (uint32_t i = 0; i < s->nworkers; i++) {
        if (pthread_create(&s->workers[i], NULL, worker_main, s)) {
            s->nworkers = i;
            goto fail;
        }
    }
    if (cfg->bind && *cfg->bind) {
        if ((s->tcp_fd = listen_tcp(cfg->bind, cfg->port)) < 0) goto fail;
        if (s->tcp_fd >= s->conns_cap || ae_add(s->loop, s->tcp_fd, AE_READABLE, on_accept, s)) goto fail;
    }
    if (cfg->unix_path && *cfg->unix_path) {
        if ((s->unix_fd = listen_unix(cfg->unix_path)) < 0) goto fail;
        if (s->unix_fd >= s->conns_cap || ae_add(s->loop, s->unix_fd, AE_READABLE, on_accept, s)) goto fail;
    }
    s->sig_fd = signalfd(-1, &set, SFD_NONBLOCK | SFD_CLOEXEC);
    if (s->sig_fd < 0 || s->sig_fd >= s->conns_cap || ae_add(s->loop, s->sig_fd, AE_READABLE, on_signal, s)) goto fail;
    ae_set_before_sleep(s->loop, before_sleep, s);
    s->start_ms = ae_now_ms();
    return s;
fail:
    LOGE("cannot start the server: %s", strerror(errno));
    server_destroy(s);
    return NULL;
}

void server_run(server *s)
{
    ae_run(s->loop);
}

void server_stop(server *s)
{
    ae_stop(s->loop);
}

void server_destroy(server *s)
{
    if (!s) return;
    for (int fd = 0; s->conns && fd < s->conns_cap; fd++)
        if (s->conns[fd]) conn_free(s, s->conns[fd]);
    if (s->tcp_fd >= 0) close(s->tcp_fd);
    if (s->unix_fd >= 0) {
        close(s->unix_fd);
        unlink(s->cfg.unix_path);
    }
    if (s->sig_fd >= 0) close(s->sig_fd);
    if (s->workers) {
        pthread_mutex_lock(&s->mu);
        s->stopping = true;
        pthread_cond_broadcast(&s->cv);
        pthread_mutex_unlock(&s->mu);
        for (uint32_t i = 0; i < s->nworkers; i++) pthread_join(s->workers[i], NULL);
        free(s->workers);
        pthread_rwlock_destroy(&s->scene_lock);
        pthread_mutex_destroy(&s->mu);
        pthread_cond_destroy(&s->cv);
    }
    for (job *lists[2] = {s->jobs_head, s->done_head}, **l = lists; l < lists + 2; l++) {
        for (job *j = *l, *n; j; j = n) {
            n = j->next;
            free(j->payload);
            free(j->reply);
            free(j);
        }
    }
    if (s->done_fd >= 0) close(s->done_fd);
    ae_destroy(s->loop);
    free(s->conns);
    free(s);
}
