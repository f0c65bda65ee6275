/*
 * server.c — vantaged's network side (see server.h): listeners,
 * connections, the loop's tick, the query workers' start and stop.
 *
 * One event loop thread owns every socket and applies every edit. A
 * connection keeps its own input buffer, so a frame may arrive a byte at a
 * time; the frame's length is checked against the limit from the header
 * alone, before its payload is buffered. Frames go to handlers.c; queries
 * go on to the worker threads, which read the scene under the shared scene
 * lock, so every query sees every edit acknowledged before it and none
 * half-applied. Replies go to a per-connection queue of output blocks (a
 * worker's reply linked in by pointer, not copied), written before the
 * loop sleeps for the connections on the pending list only; a client that
 * leaves more than out_limit bytes unread is disconnected, and while all
 * the output blocks together hold more than out_limit_total, the client
 * with the largest backlog is. A connection ended anywhere is freed at one
 * point, the end of before_sleep.
 */
#include "server_internal.h"
#include "cluster.h"
#include "vp_grow.h"
#include "web.h"

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
#include <sys/file.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/uio.h>
#include <sys/un.h>
#include <time.h>
#include <unistd.h>

/* ---- output: the reply queue -------------------------------------------------- */

/* A connection's output is a queue of blocks (out_block), in the manner of
 * Redis's reply list (_addReplyProtoToList): a reply the loop encodes goes
 * into the tail block when it fits, else into a new block of OUT_BLOCK
 * bytes (or of its own size, when larger); a worker's reply is linked in
 * as a block by pointer, so a RAW frame (W x H x 20 bytes) is written to
 * the socket from the buffer it was drawn into, never copied (it was
 * copied into one contiguous buffer, compacted and regrown, before). The
 * queue leaves through writev. A block written out is freed at once; the
 * last small one stays as the next replies' tail (16 KiB a connection at
 * rest; the daemon-wide cap takes it back first). server.out_held sums every block's memory: what
 * --out-limit-total bounds and the metrics report. */
#define OUT_BLOCK 16384u  /* a tail block: a few hundred small replies */
#define OUT_COPY_MAX 1024u /* a worker's reply up to this is copied into the tail block: cheaper
                              than a block header and an iovec of its own */
#define OUT_IOV 64         /* blocks per writev */

/* The pending list (server.pend): connections with output to write, an
 * event to send or an answer held for the journal. before_sleep visits
 * these only, as Redis's clients_pending_write, not every connection. */
static void pend_add(server *s, conn *c)
{
    if (c->pend_pos != UINT32_MAX || c->dead) return;
    c->pend_pos = s->npend;
    s->pend[s->npend++] = c;
}

static void pend_del(server *s, conn *c)
{
    if (c->pend_pos == UINT32_MAX) return;
    conn *last = s->pend[--s->npend];
    s->pend[c->pend_pos] = last;
    last->pend_pos = c->pend_pos;
    c->pend_pos = UINT32_MAX;
}

static void block_link(conn *c, out_block *b)
{
    if (c->out_tail) c->out_tail->next = b;
    else c->out_head = b;
    c->out_tail = b;
    c->out_mem += b->mem;
    c->srv->out_held += b->mem;
}

/* b, out of c's queue (or never in it), freed and uncounted. */
static void block_free(conn *c, out_block *b)
{
    c->out_mem -= b->mem;
    c->srv->out_held -= b->mem;
    if (b->p != b->data) free(b->p);
    free(b);
}

/* c's output given back (its bytes all sent, or c going). */
static void out_release(conn *c)
{
    for (out_block *b = c->out_head, *n; b; b = n) {
        n = b->next;
        block_free(c, b);
    }
    c->out_head = c->out_tail = NULL;
    c->out_pos = c->out_bytes = 0;
}

/* A tail block with room for need bytes (a new one past the tail's room). */
static out_block *out_tail_room(conn *c, size_t need)
{
    out_block *t = c->out_tail;
    if (t && t->p == t->data && t->cap - t->len >= need) return t;
    size_t cap = need > OUT_BLOCK ? need : OUT_BLOCK;
    if (cap > SIZE_MAX - sizeof *t) return NULL;
    t = malloc(sizeof *t + cap);
    if (!t) return NULL;
    *t = (out_block){.p = t->data, .cap = cap, .mem = sizeof *t + cap};
    block_link(c, t);
    return t;
}

static void out_queued(conn *c, size_t n)
{
    c->out_bytes += n;
    pend_add(c->srv, c);
}

bool out_reserve(conn *c, size_t need, vp_writer *w)
{
    out_block *t = out_tail_room(c, need);
    if (!t) return false;
    vp_writer_init(w, t->p + t->len, t->cap - t->len);
    return true;
}

void out_commit(conn *c, const vp_writer *w)
{
    if (w->overflow || !w->len) return;
    c->out_tail->len += w->len;
    out_queued(c, w->len);
}

bool out_take_reply(conn *c, job *j)
{
    metrics *m = &c->srv->m;
    if (j->reply_len <= OUT_COPY_MAX) {
        out_block *t = out_tail_room(c, j->reply_len);
        if (!t) return false;
        memcpy(t->p + t->len, j->reply, j->reply_len);
        t->len += j->reply_len;
        m->out_copied += j->reply_len;
    } else {
        out_block *b = malloc(sizeof *b);
        if (!b) return false;
        *b = (out_block){.p = j->reply, .len = j->reply_len, .cap = j->reply_len, .mem = sizeof *b + j->reply_len};
        block_link(c, b);
        j->reply = NULL; /* c's now */
        m->out_linked += j->reply_len;
    }
    out_queued(c, j->reply_len);
    return true;
}

/* n bytes written: the blocks they emptied go (the last small one stays
 * as the tail, emptied, for the next replies). */
static void out_consume(conn *c, size_t n)
{
    c->out_bytes -= n;
    n += c->out_pos;
    c->out_pos = 0;
    for (out_block *b; (b = c->out_head);) {
        if (n < b->len) {
            c->out_pos = n;
            return;
        }
        n -= b->len;
        if (b == c->out_tail) {
            if (b->p == b->data && b->cap == OUT_BLOCK) {
                b->len = 0; /* kept */
                return;
            }
            c->out_tail = NULL;
        }
        c->out_head = b->next;
        block_free(c, b);
    }
}

/* Input buffers a burst grew are given back once they go unused (as
 * Redis's clientsCron resizes client buffers): at a sweep, an input buffer
 * over its resting size that is empty and held at most a quarter of
 * itself since the last sweep shrinks to its resting size. A client that
 * just sent 100 MB of entities keeps the buffer while it keeps sending;
 * one that went quiet costs 64 KiB again. Output blocks are not the
 * sweep's: they go as soon as they are written, but for the one small tail
 * block kept for the connection's life (out_consume). The loop keeps
 * sweeping while an input buffer is over its resting size, even when idle,
 * so a burst's memory is given back within ~0.5 s. */
#define IN_REST 65536u   /* conn_read's first buffer */

static void conn_trim(conn *c)
{
    if (!c->in_len && c->in_cap > IN_REST && c->in_peak <= c->in_cap / 4) {
        uint8_t *n = realloc(c->in, IN_REST);
        if (n) c->in = n, c->in_cap = IN_REST;
    }
    c->in_peak = c->in_len;
}

void send_error(server *s, conn *c, uint32_t req, int code, uint32_t index, const char *msg)
{
    vp_writer w;
    s->errors++;
    metrics_error(&s->m, s->m.cur, code);
    if (!out_reserve(c, VP_HEADER_SIZE + 10 + VP_MAX_ERROR_MSG, &w)) {
        c->closing = true;
        return;
    }
    vp_enc_error(&w, req, code, index, msg);
    out_commit(c, &w);
    LOGD("client %u: error %d (%s): %s", c->id, code, vp_strerror(code), msg ? msg : "");
}

/* ---- ending connections ----------------------------------------------------------- */

/* Ends c; why: MD_* (metrics: disconnects by reason). c is only marked
 * (Redis's freeClientAsync): its events stop, its output is given back
 * now (the daemon-wide cap sees it at once), and it is freed
 * with its fd at one safe point, the end of before_sleep (conns_free_dead).
 * Until then every pointer to it stays good, so no caller between here
 * and there can touch freed memory, and its fd, still open, cannot be
 * reused by a new connection: a worker's reply still on its way (jobs
 * name a connection by fd and id, never by pointer) finds it dead and is
 * dropped. */
static void conn_kill(server *s, conn *c, int why)
{
    if (c->dead) return;
    c->dead = (uint8_t)why;
    c->closing = true;
    s->m.disconnects[why]++;
    ae_del(s->loop, c->fd, AE_READABLE | AE_WRITABLE);
    pend_del(s, c);
    out_release(c);
    s->dead[s->ndead++] = c;
}

/* The connections conn_kill marked, freed: the one place a conn is freed. */
static void conns_free_dead(server *s)
{
    bool loads = false;
    /* in the order they ended (oldest first, as they mostly were
       accepted): freed high to low, the small structs the allocator keeps
       for reuse were the highest and pinned a burst's heap (5,000 churned
       connections kept 6 MB more resident) */
    for (uint32_t i = 0; i < s->ndead; i++) {
        conn *c = s->dead[i];
        frames_conn_gone(s, c);
        loads |= c->sublevel != 0;
        sublevel_conn_gone(s, c);
        upload_drop(s, c);
        close(c->fd);
        s->conns[c->fd] = NULL;
        if (c->sub_kinds & VP_EVENT_SCENE) s->nev_subs--;
        conn *last = s->live[--s->nconns];
        s->live[c->live_pos] = last;
        last->live_pos = c->live_pos;
        LOGD("client %u (%s) disconnected, %u connected; %llu frames streamed", c->id, c->name, s->nconns,
             (unsigned long long)c->fsub.frames);
        web_ws_free(c);
        free(c->in);
        free(c);
    }
    s->ndead = 0;
    if (loads) {
        /* a load dropped here is journaled after this turn's sync and may
           start an unload: one more turn does both */
        uint64_t one = 1;
        ssize_t ignored = write(s->done_fd, &one, sizeof one);
        (void)ignored;
    }
}

/* The daemon-wide output cap (--out-limit-total): while the connections'
 * output blocks together hold more than it, the client with the largest
 * backlog (unread bytes) is dropped, and the tail blocks with nothing in
 * them are given back first. Each client is still held to --out-limit
 * alone; this bounds what max_clients of them can pile up together (4
 * viewers pipelining raw 1080p frames took 1.1 GB before). Returns true
 * when cur (may be NULL) was the one dropped. O(connections) per drop,
 * O(1) while under the cap. */
static bool out_total_enforce(server *s, conn *cur)
{
    uint64_t limit = s->cfg.out_limit_total;
    if (!limit || s->out_held <= limit) return false;
    /* empty blocks cost no one anything: given back first */
    for (uint32_t i = 0; i < s->nconns; i++) {
        conn *c = s->live[i];
        if (!c->out_bytes && c->out_head) out_release(c);
    }
    while (s->out_held > limit) {
        conn *worst = NULL;
        size_t most = 0;
        for (uint32_t i = 0; i < s->nconns; i++) {
            conn *c = s->live[i];
            if (!c->dead && c->out_bytes > most) most = c->out_bytes, worst = c;
        }
        if (!worst) break; /* nothing queued anywhere: nothing to drop */
        LOGW("client %u: dropped with the largest backlog (%zu bytes unread): the clients' output blocks hold "
             "%zu bytes, over --out-limit-total %llu", worst->id, most, s->out_held, (unsigned long long)limit);
        conn_kill(s, worst, MD_OUTPUT_TOTAL);
        if (worst == cur) return true;
    }
    return false;
}

static void conn_event(ae_loop *l, int fd, void *data, int mask);

/* conn_flush's writer for a WebSocket (web.c): the reply queue leaves a
 * block at a time, each block one binary message, handed to wslay only
 * when it holds nothing else (so the queue stays the one backlog the
 * limits and the frames' drain rule look at). */
static int ws_write(server *s, conn *c)
{
    (void)s;
    int why;
    for (;;) {
        if (c->out_bytes && web_ws_idle(c)) {
            size_t at = c->out_pos;
            out_block *b = c->out_head;
            while (b->len <= at) b = b->next, at = 0; /* an emptied tail block kept at the head */
            if (web_ws_queue(c, b->p + at, b->len - at)) return MD_ERROR;
            out_consume(c, b->len - at);
        }
        if ((why = web_ws_send(c))) return why;
        if (!c->out_bytes || !web_ws_idle(c)) return MD_NONE;
    }
}

/* conn_flush's writer for a socket: the queue's blocks through writev. */
static int sock_write(server *s, conn *c)
{
    while (c->out_bytes) {
        struct iovec iov[OUT_IOV];
        int k = 0;
        size_t at = c->out_pos;
        for (out_block *b = c->out_head; b && k < OUT_IOV; b = b->next, at = 0)
            if (b->len > at) iov[k++] = (struct iovec){.iov_base = b->p + at, .iov_len = b->len - at};
        ssize_t n = writev(c->fd, iov, k);
        if (n > 0) {
            out_consume(c, (size_t)n);
            s->bytes_out += (uint64_t)n;
            continue;
        }
        if (n < 0 && errno == EINTR) continue;
        if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) break;
        return MD_PEER;
    }
    return MD_NONE;
}

/* Writes what the socket takes now. MD_NONE, or why the connection is
 * over (the caller ends it). */
static int conn_flush(server *s, conn *c)
{
    if (c->held) return MD_NONE; /* an edit's answer waits for the journal's sync */
    if (c->held_seq) { /* replicated: it waits for the stream to store its record */
        if (!cluster_stored(s->cluster, c->held_seq)) return MD_NONE;
        c->held_seq = 0;
    }
    /* always: no reply leaves while the journal holds unsynced records (a
       query's answer may show them): before_sleep syncs, then flushes */
    if (s->journal && journal_policy(s->journal) == JOURNAL_ALWAYS && journal_dirty(s->journal)) return MD_NONE;
    int why = c->ws ? ws_write(s, c) : sock_write(s, c);
    if (why) return why;
    if (!c->out_bytes && (!c->ws || web_ws_idle(c))) { /* all out, wslay's framing included */
        if (ae_mask(s->loop, c->fd) & AE_WRITABLE) ae_del(s->loop, c->fd, AE_WRITABLE);
        if (!c->closing) return MD_NONE;
        /* the ERROR that ended it has left; a WebSocket's close says the same */
        if (c->ws && (why = web_ws_end(c, 1008, "protocol error: see the ERROR message"))) return why;
        return MD_ERROR;
    }
    if (c->out_bytes > s->cfg.out_limit) {
        LOGW("client %u: %zu bytes unread, over the output limit: disconnecting", c->id, c->out_bytes);
        return MD_OUTPUT_LIMIT;
    }
    if (!(ae_mask(s->loop, c->fd) & AE_WRITABLE)) ae_add(s->loop, c->fd, AE_WRITABLE, conn_event, s);
    return MD_NONE;
}

static void conn_write(server *s, int fd)
{
    conn *c = s->conns[fd];
    int why;
    if (c && !c->dead && (why = conn_flush(s, c))) conn_kill(s, c, why);
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
 * worker), then flushes. May end c (conn_kill: it stays readable). */
static void conn_process(server *s, conn *c)
{
    size_t pos = 0;
    while (!c->closing && !c->busy) {
        if (c->out_bytes > s->cfg.out_limit) {
            /* replies pile up faster than the client reads (a pipeline of
               big ENTITY_LISTs, say): the same limit as conn_flush's,
               checked before answering more */
            LOGW("client %u: %zu bytes of replies unread, over the output limit: disconnecting", c->id,
                 c->out_bytes);
            conn_kill(s, c, MD_OUTPUT_LIMIT);
            return;
        }
        if (out_total_enforce(s, c)) return;
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
        /* metrics: the request is taken now; its reply is queued when
           dispatch returns, or by on_done when it went to a worker */
        uint64_t t0 = now_ns();
        int mt = metrics_type(h.type);
        s->m.requests[mt]++;
        s->m.cur = mt;
        s->m.cur_t0 = t0;
        dispatch(s, c, &h, c->in + pos + VP_HEADER_SIZE);
        s->m.cur = MT_NONE;
        if (!c->busy) mhist_add(&s->m.latency[mt], now_ns() - t0);
        pos += fs;
    }
    if (pos) memmove(c->in, c->in + pos, c->in_len - pos); /* a WebSocket's buffer may not be yet */
    c->in_len -= pos;
    /* a frame begun and not finished: its clock (the timer drops clients
       that trickle one in too slowly) */
    if (!c->in_len) c->since_ms = 0;
    else if (pos || !c->since_ms) c->since_ms = ae_now_ms(), s->clocks = true;
    if (c->closing && !c->busy) {
        int why = conn_flush(s, c); /* best effort: let the client read why */
        conn_kill(s, c, why == MD_PEER || why == MD_OUTPUT_LIMIT ? why : MD_ERROR);
        return;
    }
    int why = conn_flush(s, c);
    if (why) conn_kill(s, c, why);
}

/* News from the cluster (cluster.c): before_sleep takes it, every turn. */
static void on_cluster(ae_loop *l, int fd, void *data, int mask)
{
    (void)l;
    (void)fd;
    (void)data;
    (void)mask;
}

/* Replies from the workers: queued (linked, not copied), then the
 * connection's input goes on. A reply for a connection that ended, or
 * whose fd a new one took, is dropped. */
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
        /* what the worker measured counts whether or not its client is still there */
        s->m.jobs_done++;
        if (j->has_query) metrics_query_add(&s->m, &j->mq);
        if (j->has_frame) {
            mhist_add(&s->m.frame_render, j->render_ns);
            mhist_add(&s->m.frame_encode, j->encode_ns);
        }
        bool same = c && c->id == j->conn_id && !c->dead; /* still the same client */
        if (same && j->stream) {
            frames_done(s, c, j); /* the connection's own requests go on regardless */
        } else if (same) {
            if (!j->reply || !out_take_reply(c, j)) {
                c->closing = true;
            } else {
                int mt = metrics_type(j->h.type);
                if (j->ok) {
                    s->queries++;
                } else {
                    s->errors++;
                    metrics_error(&s->m, mt, j->code);
                }
                mhist_add(&s->m.latency[mt], now_ns() - j->t0);
            }
            c->busy = false;
            if (!(ae_mask(s->loop, c->fd) & AE_READABLE)) ae_add(s->loop, c->fd, AE_READABLE, conn_event, s);
            conn_process(s, c);
        } else if (j->stream && j->ok) {
            s->m.frames_discarded++; /* drawn for a connection now gone */
        }
        frames_job_free(j);
        free(j->payload);
        free(j->reply);
        free(j);
        j = next;
    }
}

static void conn_read(server *s, int fd)
{
    conn *c = s->conns[fd];
    if (!c || c->dead) return;
    uint32_t limit = c->hello ? s->cfg.max_payload : VANTAGED_PREHELLO_MAX;
    for (;;) {
        if (c->busy && c->in_len >= (size_t)limit + VP_HEADER_SIZE) {
            /* a query is out and a whole frame waits behind it: stop
               reading this client until the reply is back */
            ae_del(s->loop, fd, AE_READABLE);
            return;
        }
        if (c->ws) { /* wslay reads what the socket has, its messages' bytes into c->in */
            int why = web_ws_recv(c);
            /* a pong or a close wslay queued goes out; the protocol's bytes on */
            if (!why && !web_ws_idle(c)) why = web_ws_send(c);
            if (why) {
                conn_kill(s, c, why);
                return;
            }
            break;
        }
        if (c->in_cap - c->in_len < 65536) {
            size_t cap = vp_grow_cap(c->in_cap, c->in_len + 65536, 65536, 1, SIZE_MAX);
            size_t most = (size_t)limit + VP_HEADER_SIZE + 65536;
            if (cap > most) cap = most;
            if (cap <= c->in_cap) break; /* full: parse what is there first */
            uint8_t *n = realloc(c->in, cap);
            if (!n) {
                conn_kill(s, c, MD_ERROR);
                return;
            }
            c->in = n;
            c->in_cap = cap;
            if (cap > IN_REST) s->clocks = true; /* the sweeps that give it back */
        }
        ssize_t n = read(fd, c->in + c->in_len, c->in_cap - c->in_len);
        if (n > 0) {
            c->in_len += (size_t)n;
            if (c->in_len > c->in_peak) c->in_peak = c->in_len;
            s->bytes_in += (uint64_t)n;
            if ((size_t)n < c->in_cap - c->in_len) break;
            continue;
        }
        if (n < 0 && errno == EINTR) continue;
        if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) break;
        conn_kill(s, c, MD_PEER); /* closed by the peer, or an error */
        return;
    }
    conn_process(s, c);
}

/* A new connection on fd, registered and counted. */
static void conn_init(server *s, conn *c, int fd)
{
    s->m.accepted++;
    c->srv = s;
    c->fd = fd;
    c->id = ++s->next_id;
    c->born_ms = ae_now_ms();
    c->pend_pos = UINT32_MAX;
    s->clocks = true; /* its HELLO clock */
    strcpy(c->name, "?");
    s->conns[fd] = c;
    c->live_pos = s->nconns;
    s->live[s->nconns++] = c;
    LOGD("client %u connected (fd %d%s), %u connected", c->id, fd, c->ws ? ", WebSocket" : "", s->nconns);
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
            s->m.rejected++;
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
        conn_init(s, c, fd);
    }
}

bool server_has_room(const server *s)
{
    return s->nconns < s->cfg.max_clients;
}

int server_adopt_ws(server *s, int fd, struct wsio *w)
{
    conn *c = NULL;
    if (!server_has_room(s) || fd >= s->conns_cap || !(c = calloc(1, sizeof *c)) || web_ws_init(s, c, w)) {
        web_wsio_free(w); /* its TLS session too */
        goto fail;
    }
    if (ae_add(s->loop, fd, AE_READABLE, conn_event, s) < 0) {
        web_ws_free(c); /* w with it */
        goto fail;
    }
    int one = 1;
    setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    conn_init(s, c, fd);
    snprintf(c->name, sizeof c->name, "?(ws)");
    conn_read(s, fd); /* bytes that came with the head: the socket may stay quiet */
    return 0;
fail:
    free(c);
    close(fd);
    return -1;
}

/* ---- slow clients --------------------------------------------------------------- */

/* A client that has not finished HELLO within hello_timeout_ms of its
 * accept, or has left a frame half-sent for frame_timeout_ms (slow-loris),
 * is dropped with a message: true when c was ended. A client whose frames
 * wait behind its own query is not judged. The tick asks at most every
 * SWEEP_MS. */
#define SWEEP_MS 250u

static bool drop_if_slow(server *s, conn *c, uint64_t now)
{
    if (c->busy || c->closing || c->dead) return false;
    const char *why = NULL;
    if (!c->hello && now - c->born_ms > s->cfg.hello_timeout_ms) why = "no HELLO in time";
    else if (c->since_ms && now - c->since_ms > s->cfg.frame_timeout_ms) why = "a frame sent too slowly";
    if (!why) return false;
    LOGW("client %u: %s (%u ms): disconnecting", c->id, why,
         !c->hello ? s->cfg.hello_timeout_ms : s->cfg.frame_timeout_ms);
    send_error(s, c, 0, VP_ERR_TIMEOUT, UINT32_MAX, why);
    (void)conn_flush(s, c);
    conn_kill(s, c, !c->hello ? MD_HELLO_TIMEOUT : MD_FRAME_TIMEOUT);
    return true;
}

/* ---- the tick -------------------------------------------------------------------- */

#define SUBLEVEL_SLICE 2048u /* entities an unload frees per loop turn: ~0.7 ms */

static void timer_noop(ae_loop *l, void *data)
{
    (void)l;
    (void)data;
}

static void before_sleep(ae_loop *l, void *data)
{
    (void)l;
    server *s = data;
    scene *sc = s->sc;
    uint64_t now_ms = ae_now_ms();
    bool sweep = now_ms >= s->sweep_ms; /* slow clients are looked for this turn */
    if (sweep) s->sweep_ms = now_ms + SWEEP_MS;
    /* the cluster's news: the stream's records applied (a replica), the
       stored acknowledgements counted (the writer), a promotion */
    if (s->cluster) {
        cluster_poll(s->cluster, sc, &s->scene_lock);
        uint64_t stored = cluster_take_dropped(s->cluster);
        for (uint32_t i = 0; stored != UINT64_MAX && i < s->nconns; i++) {
            conn *c = s->live[i];
            if (c->dead || c->held_seq <= stored) continue;
            LOGW("client %u: its edit's answer waited for a stream message this daemon no longer writes: "
                 "disconnected (the edit may or may not be in the scene)", c->id);
            conn_kill(s, c, MD_ERROR);
        }
    }
    bool writes = !s->cluster || cluster_role(s->cluster) == CLUSTER_WRITER;
    /* any edit moves the epoch (meshes, occluders and lights too); entity
       edits also leave counts and bounds to tighten */
    bool changed = sc->epoch != s->ev_epoch;
    s->ev_epoch = sc->epoch;
    /* unloads free their entities a slice a turn (the lock is held for
       under a millisecond), and wake the loop again while any is left; the
       bounds they loosen are tightened once, at the end (queries are right
       with loose bounds, and every slice would tighten the same cells) */
    if (sc->unloading) {
        /* (a replica frees as the writer's slices come down the stream) */
        if (writes && server_unload_slice(s, SUBLEVEL_SLICE)) {
            uint64_t one = 1;
            ssize_t ignored = write(s->done_fd, &one, sizeof one);
            (void)ignored;
        }
    } else if (sc->ev_added || sc->ev_updated || sc->ev_removed) {
        pthread_rwlock_wrlock(&s->scene_lock);
        cull_world_commit(sc->world);
        pthread_rwlock_unlock(&s->scene_lock);
    }
    /* the journal: this turn's records synced before any of their answers
       leave (always: group commit), a snapshot started or finished */
    if (s->journal) {
        journal *j = s->journal;
        journal_poll(j);
        if (journal_policy(j) == JOURNAL_ALWAYS && journal_dirty(j)) (void)journal_sync(j);
        if (journal_wants_snapshot(j)) {
            int rc = journal_snapshot(j, sc);
            if (rc) LOGW("snapshot not started: %s", strerror(-rc));
        }
        if (journal_sync_error(j)) {
            /* a failed fdatasync is final (the kernel may have dropped the
               pages it could not write: PostgreSQL's fsync lesson): the
               scene in memory may hold what the disk does not. Nothing of
               the unsynced edits has left (every reply is held while the
               journal is dirty, and their records were cut back), so stop
               here, before anyone sees them: the restart serves what the
               disk holds */
            LOGE("%s: exiting (a restart recovers the scene from the disk)", journal_broken(j));
            _exit(1);
        }
    }
    /* what stream frames and worker replies added since */
    out_total_enforce(s, NULL);
    /* the sweep (every SWEEP_MS, O(connections)): slow clients, idle
       buffers, and whether any client is still on a clock */
    if (sweep) {
        bool on_clock = false;
        for (uint32_t i = 0; i < s->nconns; i++) {
            conn *c = s->live[i];
            if (c->dead || drop_if_slow(s, c, now_ms)) continue;
            conn_trim(c);
            /* a HELLO or frame clock, or a buffer the next sweeps give back */
            on_clock |= !c->hello || c->since_ms || c->in_cap > IN_REST;
        }
        s->clocks = on_clock;
    }
    /* scene events, marked on their subscribers (only on a turn that
       changed the scene, and only when someone subscribed) */
    if (changed && s->nev_subs) {
        for (uint32_t i = 0; i < s->nconns; i++) {
            conn *c = s->live[i];
            if (c->dead || !(c->sub_kinds & VP_EVENT_SCENE)) continue;
            c->ev_pending = true;
            c->ev_added += sc->ev_added;
            c->ev_updated += sc->ev_updated;
            c->ev_removed += sc->ev_removed;
            pend_add(s, c);
        }
    }
    /* the pending list, not every connection (Redis's
       handleClientsWithPendingWrites): backwards, as one done with (or
       ended) leaves it and the last moves into its place */
    for (uint32_t i = s->npend; i-- > 0;) {
        conn *c = s->pend[i];
        c->held = false;
        /* events coalesce while a subscriber is behind */
        if (c->ev_pending && c->out_bytes < 65536) {
            vp_writer w;
            if (out_reserve(c, VP_HEADER_SIZE + 28, &w)) {
                vp_enc_event(&w, &(vp_event){.kind = VP_EVENT_SCENE, .epoch = sc->epoch, .added = c->ev_added,
                                             .updated = c->ev_updated, .removed = c->ev_removed});
                out_commit(c, &w);
                c->ev_added = c->ev_updated = c->ev_removed = 0;
                c->ev_pending = false;
            }
        }
        int why;
        if (c->out_bytes && (why = conn_flush(s, c))) conn_kill(s, c, why);
        else if (!c->out_bytes && !c->ev_pending) pend_del(s, c);
    }
    /* the metrics endpoint's connections have a deadline too */
    if (sweep) {
        httpd_sweep(s->http, now_ms);
        httpd_sweep(s->web, now_ms);
    }
    bool clocks = s->clocks || httpd_conns(s->http) || httpd_conns(s->web);
    sc->ev_added = sc->ev_updated = sc->ev_removed = 0;
    /* one timer wakes the loop: for the next rate-capped frame, or for the
       next sweep while a client is on a clock (an idle loop sleeps) */
    int ms = frames_schedule(s);
    if (clocks) {
        uint64_t t = ae_now_ms();
        int sw = s->sweep_ms > t ? (int)(s->sweep_ms - t) : 1;
        ms = ms < 0 || sw < ms ? sw : ms;
    }
    ae_set_timer(s->loop, ms < 0 ? 0 : ms, timer_noop, NULL);
    /* the one safe point: the connections ended this turn are freed */
    conns_free_dead(s);
}

static void on_signal(ae_loop *l, int fd, void *data, int mask)
{
    (void)mask;
    (void)data;
    struct signalfd_siginfo si;
    while (read(fd, &si, sizeof si) == (ssize_t)sizeof si) {
        if (si.ssi_signo == SIGCHLD) continue; /* the wake-up is all: before_sleep reaps */
        LOGI("signal %u: shutting down", si.ssi_signo);
        ae_stop(l);
    }
}

server *server_create(const server_config *cfg, scene *sc)
{
    server *s = calloc(1, sizeof *s);
    if (!s) return NULL;
    s->cfg = *cfg;
    s->sc = sc;
    s->journal = cfg->journal;
    s->cluster = cfg->cluster;
    s->ev_epoch = sc->epoch;
    s->tcp_fd = s->unix_fd = s->unix_lock_fd = s->sig_fd = s->done_fd = s->web_root_fd = -1;
    /* SIGINT and SIGTERM arrive through a signalfd on the loop: block them
       before any thread starts, so no worker inherits them unblocked.
       SIGCHLD too: a snapshot child that ends while the loop sleeps wakes
       it, and before_sleep reaps the child and puts its file in place (an
       idle loop sleeps with no timer: without it the snapshot would wait
       for the next client's bytes) */
    sigset_t set;
    sigemptyset(&set);
    sigaddset(&set, SIGINT);
    sigaddset(&set, SIGTERM);
    sigaddset(&set, SIGCHLD);
    pthread_sigmask(SIG_BLOCK, &set, NULL);
    signal(SIGPIPE, SIG_IGN);
    s->conns_cap = (int)cfg->max_clients + 64;
    s->conns = calloc((size_t)s->conns_cap, sizeof *s->conns);
    s->live = calloc((size_t)s->conns_cap, sizeof *s->live);
    s->pend = calloc((size_t)s->conns_cap, sizeof *s->pend);
    s->dead = calloc((size_t)s->conns_cap, sizeof *s->dead);
    s->loop = ae_create(s->conns_cap);
    s->done_fd = eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
    if (!s->conns || !s->live || !s->pend || !s->dead || !s->loop || s->done_fd < 0 || s->done_fd >= s->conns_cap ||
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
    if (frames_init(s)) {
        errno = ENODEV;
        goto fail;
    }
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
        if ((s->tcp_fd = listen_tcp(cfg->bind, cfg->port)) < 0) goto said;
        if (s->tcp_fd >= s->conns_cap || ae_add(s->loop, s->tcp_fd, AE_READABLE, on_accept, s)) goto fail;
    }
    if (cfg->unix_path && *cfg->unix_path) {
        if ((s->unix_fd = listen_unix(cfg->unix_path, &s->unix_lock_fd)) < 0) goto said;
        if (s->unix_fd >= s->conns_cap || ae_add(s->loop, s->unix_fd, AE_READABLE, on_accept, s)) goto fail;
    }
    s->sig_fd = signalfd(-1, &set, SFD_NONBLOCK | SFD_CLOEXEC);
    if (s->sig_fd < 0 || s->sig_fd >= s->conns_cap || ae_add(s->loop, s->sig_fd, AE_READABLE, on_signal, s)) goto fail;
    if (s->cluster && ae_add(s->loop, cluster_fd(s->cluster), AE_READABLE, on_cluster, s)) goto fail;
    if (cfg->metrics_port && metrics_http_open(s)) goto fail;
    if (cfg->web_port && web_open(s)) goto said;
    s->m.cur = MT_NONE;
    ae_set_before_sleep(s->loop, before_sleep, s);
    s->start_ms = ae_now_ms();
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    s->start_unix_ns = (uint64_t)ts.tv_sec * 1000000000ull + (uint64_t)ts.tv_nsec;
    return s;
fail:
    LOGE("cannot start the server: %s", strerror(errno));
said: /* the listener said why */
    server_destroy(s);
    return NULL;
}

int server_run(server *s)
{
    int rc = ae_run(s->loop);
    if (rc) LOGE("the event loop failed: epoll_wait: %s: exiting", strerror(-rc));
    return rc;
}

void server_stop(server *s)
{
    ae_stop(s->loop);
}

int server_destroy(server *s)
{
    if (!s) return 0;
    for (uint32_t i = 0; i < s->nconns; i++) conn_kill(s, s->live[i], MD_SHUTDOWN);
    if (s->nconns) conns_free_dead(s);
    httpd_close(s->http);
    web_close(s);
    if (s->tcp_fd >= 0) close(s->tcp_fd);
    if (s->unix_fd >= 0) {
        close(s->unix_fd);
        unlink(s->cfg.unix_path);
    }
    if (s->unix_lock_fd >= 0) { /* removed while still held: no one is told "taken" by a file going away */
        char lock[128];
        snprintf(lock, sizeof lock, "%s.lock", s->cfg.unix_path);
        unlink(lock);
        close(s->unix_lock_fd);
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
    frames_fini(s); /* after the workers: none is drawing */
    int rc = journal_close(s->journal); /* after the connections: their loads' drops are journaled */
    cluster_close(s->cluster);
    for (job *lists[3] = {s->jobs_head, s->fast_head, s->done_head}, **l = lists; l < lists + 3; l++) {
        for (job *j = *l, *n; j; j = n) {
            n = j->next;
            frames_job_free(j);
            free(j->payload);
            free(j->reply);
            free(j);
        }
    }
    if (s->done_fd >= 0) close(s->done_fd);
    ae_destroy(s->loop);
    mbuf_free(&s->mtext);
    free(s->conns);
    free(s->live);
    free(s->pend);
    free(s->dead);
    free(s);
    return rc;
}
