/*
 * pad_hub.c — the pad hub (pad_io.h): what every backend shares. Opening
 * and closing the hub and its threads, the event queue the caller drains,
 * the report path every backend feeds (record, parse, send the parser's
 * output back, queue a STATE), what the hub remembers of devices between
 * scans (retries with a growing wait, flapping pads), and pad_enumerate.
 * The backends have a file each (pad_io_internal.h lists them): hidraw
 * (pad_hidraw.c), libusb (pad_libusb.c), replay (pad_replay.c); --record
 * is pad_record.c.
 *
 * Threads:
 *   - the hub thread finds pads: hid_enumerate every rescan_ms (hidapi has
 *     no hotplug), libusb hotplug callbacks (queued, handled here) and a
 *     libusb rescan at the same period (the retry path for a device that
 *     would not open, and the only path where libusb has no hotplug); it
 *     reaps the readers of unplugged pads.
 *   - one reader per open pad: a blocking read with a READ_MS timeout (so
 *     close is prompt), pad_parse, the parser's output sent back (the Xbox
 *     One's acks), events queued. A failed read closes the device and says
 *     REMOVED; the hub thread joins the reader and frees the pad.
 *   - replay: one thread that delivers the file's reports at its timing.
 * The caller's thread only drains the queue (pad_hub_next).
 *
 * Load: a pad sends 250..1000 reports a second; each costs a parse (well
 * under 1 us), a mutex and, when the state changed, an event copy (~300
 * bytes). STATE events of a pad the caller has not read yet are merged in
 * place, so a slow caller costs memory only for other kinds of event, and
 * ERROR events are rate-limited per pad (PARSE_ERR_BURST, then 1 a second)
 * and dropped beyond QUEUE_SOFT_CAP queued. Idle, the hub thread wakes
 * every TICK_MS and re-enumerates hidraw once a rescan_ms (a udev scan:
 * about a millisecond).
 */
#include "pad_io_internal.h"
#include "protocol.h"
#include "vp_grow.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <sys/eventfd.h>
#include <unistd.h>

/* ---- small helpers ------------------------------------------------------------------- */

double pad_mono_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

struct timespec pad_mono_at(double t)
{
    struct timespec ts;
    if (t < 0) t = 0;
    ts.tv_sec = (time_t)t;
    ts.tv_nsec = (long)((t - (double)ts.tv_sec) * 1e9);
    if (ts.tv_nsec >= 1000000000L) ts.tv_nsec = 999999999L;
    return ts;
}

void pad_wcs_ascii(const wchar_t *w, char *out, size_t cap)
{
    size_t n = 0;
    if (cap == 0) return;
    for (; w && *w && n + 1 < cap; w++) out[n++] = *w >= 32 && *w < 127 ? (char)*w : '?';
    out[n] = 0;
}

/* A cond whose timed waits take CLOCK_MONOTONIC times (pad_mono_at). */
static int cond_init_mono(pthread_cond_t *c)
{
    pthread_condattr_t a;
    if (pthread_condattr_init(&a)) return -1;
    pthread_condattr_setclock(&a, CLOCK_MONOTONIC);
    int rc = pthread_cond_init(c, &a);
    pthread_condattr_destroy(&a);
    return rc ? -1 : 0;
}
/* ---- the event queue ------------------------------------------------------------------ */

static pad_event *slot(pad_hub *h, uint64_t seq)
{
    return &h->ring[seq & (h->cap - 1)];
}

static bool queue_grow(pad_hub *h)
{
    /* doubled (a power of two: slot() masks), never past SIZE_MAX bytes */
    size_t ncap = vp_grow_cap(h->cap, h->cap + 1, 64, sizeof(pad_event), SIZE_MAX);
    if (!ncap) return false;
    pad_event *r = malloc(ncap * sizeof *r);
    if (!r) return false;
    for (uint64_t s = h->head; s < h->tail; s++) r[s & (ncap - 1)] = *slot(h, s);
    free(h->ring);
    h->ring = r;
    h->cap = ncap;
    return true;
}

/* Queues ev (d: the pad it is about, or NULL). A STATE merges into the
 * pad's unread STATE when that is the pad's newest queued event (or, past
 * the soft cap, wherever it is): the order of one pad's events holds. */
void pad_push(pad_hub *h, pad_dev *d, const pad_event *ev)
{
    pthread_mutex_lock(&h->qmu);
    size_t queued = (size_t)(h->tail - h->head);
    if (ev->kind == PAD_EV_STATE && d && d->q_state && d->q_state - 1 >= h->head &&
        (d->q_last == d->q_state || queued >= QUEUE_SOFT_CAP)) {
        *slot(h, d->q_state - 1) = *ev;
        atomic_fetch_add_explicit(&d->c_merged, 1, memory_order_relaxed);
        pthread_mutex_unlock(&h->qmu);
        return;
    }
    if (ev->kind == PAD_EV_ERROR && queued >= QUEUE_SOFT_CAP) {
        h->dropped++;
        pthread_mutex_unlock(&h->qmu);
        return;
    }
    if (queued == h->cap && !queue_grow(h)) {
        h->dropped++; /* out of memory: the event is lost, said in the next one that fits */
        pthread_mutex_unlock(&h->qmu);
        return;
    }
    pad_event *e = slot(h, h->tail);
    *e = *ev;
    if (h->dropped && ev->kind == PAD_EV_ERROR) {
        size_t n = strlen(e->msg);
        snprintf(e->msg + n, sizeof e->msg - n, " (%u events dropped before this)", h->dropped);
        h->dropped = 0;
    }
    h->tail++;
    if (d) {
        d->q_last = h->tail;
        if (ev->kind == PAD_EV_STATE) d->q_state = h->tail;
    }
    if (queued == 0) {
        uint64_t one = 1;
        ssize_t w = write(h->efd, &one, sizeof one);
        (void)w; /* the counter cannot overflow: it is read back to 0 when the queue empties */
    }
    pthread_mutex_unlock(&h->qmu);
}

void pad_push_msg(pad_hub *h, pad_dev *d, pad_event_kind kind, const char *fmt, ...)
{
    pad_event ev;
    memset(&ev, 0, sizeof ev);
    ev.kind = kind;
    ev.pad = d ? d->id : 0;
    ev.info = d ? d->info : NULL;
    ev.t_report = pad_mono_now();
    ev.t_file = d ? ev.t_report - d->t_open : 0;
    if (d) ev.state = d->state;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(ev.msg, sizeof ev.msg, fmt, ap);
    va_end(ap);
    pad_push(h, d, &ev);
}

int pad_hub_fd(const pad_hub *h)
{
    return h ? h->efd : -1;
}

int pad_hub_next(pad_hub *h, pad_event *ev)
{
    if (!h) return 0;
    pthread_mutex_lock(&h->qmu);
    if (h->head == h->tail) {
        pthread_mutex_unlock(&h->qmu);
        return 0;
    }
    *ev = *slot(h, h->head);
    h->head++;
    if (h->head == h->tail) {
        uint64_t v;
        ssize_t r = read(h->efd, &v, sizeof v);
        (void)r; /* EAGAIN at worst: then it was already 0 */
        pthread_cond_broadcast(&h->drained);
    }
    pthread_mutex_unlock(&h->qmu);
    return 1;
}
/* ---- the report path ------------------------------------------------------------------ */

/* Sends the parser's output to the device (an Xbox One ack or power-on);
 * the reader's thread. */
static void send_out(pad_dev *d)
{
    size_t n = d->parser.out_len;
    d->parser.out_len = 0;
    if (!n || n > sizeof d->parser.out) return;
    if (d->bk == BK_HID) pad_hid_send(d, n);
    else if (d->bk == BK_USB) pad_usb_send(d, n);
    /* replay: nothing to send it to */
}

/* A pad's errors through a token bucket (PARSE_ERR_BURST, then one a
 * second): true when this one may be said; more then tells how many were
 * not since the last that was. */
bool pad_dev_err_allowed(pad_dev *d, double now, char *more, size_t morelen)
{
    d->err_tokens += now - d->err_t;
    if (d->err_tokens > PARSE_ERR_BURST) d->err_tokens = PARSE_ERR_BURST;
    d->err_t = now;
    if (d->err_tokens < 1) {
        d->err_suppressed++;
        return false;
    }
    d->err_tokens -= 1;
    more[0] = 0;
    if (d->err_suppressed) snprintf(more, morelen, " (and %u more since the last said)", d->err_suppressed);
    d->err_suppressed = 0;
    return true;
}

static void parse_error(pad_dev *d, int rc, const uint8_t *buf, size_t len, double now)
{
    char more[48];
    if (!pad_dev_err_allowed(d, now, more, sizeof more)) return;
    pad_push_msg(d->h, d, PAD_EV_ERROR, "%s: report 0x%02x of %zu bytes refused: %s%s", d->info->name, len ? buf[0] : 0,
                 len, pad_strerror(rc), more);
}

void pad_dev_report(pad_dev *d, const uint8_t *buf, size_t len, double t_report, double t_file)
{
    pad_hub *h = d->h;
    pad_rec_report(h, d, buf, len, t_file);
    pad_state st = d->state;
    int rc = pad_parse(&d->parser, buf, len, &st);
    if (d->parser.out_len) send_out(d);
    atomic_fetch_add_explicit(&d->c_reports, 1, memory_order_relaxed);
    atomic_fetch_add_explicit(rc > 0 ? &d->c_states : rc == 0 ? &d->c_ignored : &d->c_errors, 1,
                              memory_order_relaxed);
    if (rc > 0) {
        d->state = st;
        pad_event ev;
        memset(&ev, 0, sizeof ev);
        ev.kind = PAD_EV_STATE;
        ev.pad = d->id;
        ev.info = d->info;
        ev.state = st;
        ev.t_report = t_report;
        ev.t_file = t_file;
        pad_push(h, d, &ev);
    } else if (rc < 0) {
        parse_error(d, rc, buf, len, t_report);
    }
}

pad_dev *pad_dev_new(pad_hub *h, const pad_device_info *info, pad_backend bk, const char *key, const char *where)
{
    pad_dev *d = calloc(1, sizeof *d);
    if (!d) return NULL;
    d->h = h;
    d->info = info;
    d->bk = bk;
    snprintf(d->key, sizeof d->key, "%s", key);
    snprintf(d->where, sizeof d->where, "%s", where);
    d->bus = 3;
    d->rec_index = -1;
    d->err_tokens = PARSE_ERR_BURST;
    d->t_open = d->err_t = pad_mono_now();
    pad_state_init(&d->state);
    pad_parser_init(&d->parser, info->proto);
    atomic_init(&d->stop, false);
    atomic_init(&d->gone, false);
    atomic_init(&d->done, false);
    d->id = atomic_fetch_add(&h->next_id, 1);
    return d;
}

static void pad_dev_close(pad_dev *d)
{
    if (d->closed) return;
    d->closed = true;
    if (d->bk == BK_HID) pad_hid_close(d);
    if (d->bk == BK_USB) pad_usb_close(d);
}

/* A closed pad's memory, and the libusb device reference it held. */
static void pad_dev_free(pad_dev *d)
{
    if (d->udev) d->h->ops->libusb_unref_device(d->udev);
    free(d);
}

/* The reader's end on a failed read: the device closed, REMOVED queued; the
 * hub thread joins it and frees the pad. */
void pad_dev_removed(pad_dev *d, const char *fmt, ...)
{
    char why[160];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(why, sizeof why, fmt, ap);
    va_end(ap);
    pad_dev_close(d);
    pad_push_msg(d->h, d, PAD_EV_REMOVED, "%s at %s: %s; closed after %llu reports (%llu refused)", d->info->name,
                 d->where, why, (unsigned long long)atomic_load(&d->c_reports),
             (unsigned long long)atomic_load(&d->c_errors));
}

/* Starts a freshly opened pad: the parser's start packet (before any read:
 * the Xbox One sends nothing until it has it), ADDED, its reader. On
 * failure the device is closed and the pad freed (an ERROR queued). */
void pad_dev_start(pad_hub *h, pad_dev *d, const char *how)
{
    pad_parser_start(&d->parser);
    if (d->parser.out_len) send_out(d);
    pad_rec_pad(h, d);
    pad_push_msg(h, d, PAD_EV_ADDED, "%s, %s %s%s", d->info->name, how, d->where, d->bus == 5 ? " (Bluetooth)" : "");
    int rc = pthread_create(&d->thread, NULL, d->bk == BK_HID ? pad_hid_reader : pad_usb_reader, d);
    if (rc) {
        pad_dev_close(d);
        pad_push_msg(h, d, PAD_EV_REMOVED, "%s at %s: no reader thread: %s; closed", d->info->name, d->where,
                     strerror(rc));
        pad_dev_free(d);
        return;
    }
    d->thread_started = true;
    pthread_mutex_lock(&h->mu);
    d->next = h->pads;
    h->pads = d;
    pthread_mutex_unlock(&h->mu);
}

/* ---- what the hub remembers of devices (the hub thread's) ------------------------------ */

pad_seen *pad_seen_get(pad_hub *h, pad_backend bk, const char *key)
{
    for (size_t i = 0; i < h->nseen; i++)
        if (h->seen[i].bk == bk && !strcmp(h->seen[i].key, key)) return &h->seen[i];
    if (!vp_grow((void **)&h->seen, &h->capseen, h->nseen + 1, sizeof *h->seen)) return NULL;
    pad_seen *s = &h->seen[h->nseen++];
    memset(s, 0, sizeof *s);
    snprintf(s->key, sizeof s->key, "%s", key);
    s->bk = bk;
    return s;
}

static double backoff(const pad_hub *h, unsigned fails)
{
    double t = h->rescan_ms / 1000.0 * (double)(1u << (fails < 6 ? fails : 6));
    return t < RETRY_MAX_S ? t : RETRY_MAX_S;
}

void pad_open_failed(pad_hub *h, pad_seen *s, const pad_device_info *info, const char *where, const char *why,
                     const char *hint)
{
    if (s) {
        s->fails++;
        s->retry_at = pad_mono_now() + backoff(h, s->fails);
        if (s->reported) return;
        s->reported = true;
    }
    pad_event ev;
    memset(&ev, 0, sizeof ev);
    ev.kind = PAD_EV_ERROR; /* no pad of the hub's yet: pad 0, info NULL, the device named in msg */
    ev.t_report = pad_mono_now();
    snprintf(ev.msg, sizeof ev.msg, "cannot open %s at %s: %s%s", info->name, where, why, hint);
    pad_push(h, NULL, &ev);
}

void pad_open_worked(pad_seen *s)
{
    if (!s) return;
    s->reported = false;
    s->retry_at = 0;
}

pad_dev *pad_by_key(pad_hub *h, pad_backend bk, const char *key)
{
    for (pad_dev *d = h->pads; d; d = d->next)
        if (d->bk == bk && !strcmp(d->key, key)) return d;
    return NULL;
}

void pad_seen_absent(pad_hub *h, pad_backend bk, const char *key)
{
    for (size_t k = 0; k < h->nseen; k++)
        if (h->seen[k].bk == bk && (!key || !strcmp(h->seen[k].key, key))) h->seen[k].present = false;
}

/* forget the devices the last scan did not see (and no open pad holds) */
void pad_seen_prune(pad_hub *h, pad_backend bk)
{
    pthread_mutex_lock(&h->mu);
    size_t k = 0;
    for (size_t i = 0; i < h->nseen; i++) {
        pad_seen *s = &h->seen[i];
        bool keep = s->bk != bk || s->present || pad_by_key(h, s->bk, s->key);
        if (keep) h->seen[k++] = *s;
    }
    h->nseen = k;
    pthread_mutex_unlock(&h->mu);
}

/* Joins the readers that have finished and frees their pads; a pad that
 * lived less than FLAP_S is opened again only after a growing wait. */
static void reap(pad_hub *h)
{
    pthread_mutex_lock(&h->mu);
    pad_dev **pp = &h->pads;
    while (*pp) {
        pad_dev *d = *pp;
        if (!atomic_load(&d->done)) {
            pp = &d->next;
            continue;
        }
        *pp = d->next;
        pthread_join(d->thread, NULL);
        pad_dev_close(d);
        pad_seen *s = pad_seen_get(h, d->bk, d->key);
        if (s) {
            double now = pad_mono_now();
            s->fails = now - d->t_open < FLAP_S ? s->fails + 1 : 0;
            /* the first removal of a pad is a plug-out: plugged back it comes back at once */
            s->retry_at = s->fails <= 1 ? 0 : now + backoff(h, s->fails - 1);
        }
        pad_dev_free(d);
    }
    pthread_mutex_unlock(&h->mu);
}
/* ---- the hub thread ------------------------------------------------------------------------ */

static void *hub_main(void *arg)
{
    pad_hub *h = arg;
    double period = h->rescan_ms / 1000.0, next_scan = 0;
    while (!atomic_load(&h->stop)) {
        reap(h);
        double now = pad_mono_now();
        if (now >= next_scan) {
            if (h->hid_ok) pad_hid_scan(h);
            if (h->usb) pad_usb_scan(h);
            next_scan = now + period;
        }
        int rc = -1;
        if (h->usb && h->hotplug) {
            /* waits for hotplug news (and serves any transfer's events) */
            struct timeval tv = {0, TICK_MS * 1000};
            rc = h->ops->libusb_handle_events_timeout_completed(h->usb, &tv, NULL);
            pad_usb_notes(h);
        }
        if (rc < 0) { /* no hotplug, or libusb failed at once: a timed wait, never a spin */
            double until = pad_mono_now() + TICK_MS / 1000.0;
            if (until > next_scan) until = next_scan;
            struct timespec ts = pad_mono_at(until);
            pthread_mutex_lock(&h->mu);
            if (!atomic_load(&h->stop)) pthread_cond_timedwait(&h->wake, &h->mu, &ts);
            pthread_mutex_unlock(&h->mu);
        }
    }
    return NULL;
}
/* ---- open / close ---------------------------------------------------------------------- */

/* Wakes every waiter on c, under its mutex m (so none misses it between
 * its check of stop and its wait). */
static void wake_all(pthread_mutex_t *m, pthread_cond_t *c)
{
    pthread_mutex_lock(m);
    pthread_cond_broadcast(c);
    pthread_mutex_unlock(m);
}

void pad_hub_close(pad_hub *h)
{
    if (!h) return;
    atomic_store(&h->stop, true);
    wake_all(&h->mu, &h->wake);   /* the hub thread's and the replay's timed waits */
    wake_all(&h->qmu, &h->drained); /* the replay waiting for the caller to drain */
    /* every reader told first, then joined: one READ_MS in all, not one
       each, and while the hub thread finishes its own wait (told again
       after: it may have opened one more) */
    pthread_mutex_lock(&h->mu);
    for (pad_dev *d = h->pads; d; d = d->next) atomic_store(&d->stop, true);
    pthread_mutex_unlock(&h->mu);
    if (h->thread_started) pthread_join(h->thread, NULL);
    for (pad_dev *d = h->pads; d; d = d->next) atomic_store(&d->stop, true);
    while (h->pads) {
        pad_dev *d = h->pads;
        h->pads = d->next;
        if (d->thread_started) pthread_join(d->thread, NULL);
        pad_dev_close(d);
        pad_dev_free(d);
    }
    for (size_t i = 0; i < h->nrdev; i++) free(h->rdev[i].pad);
    free(h->rdev);
    pad_usb_exit(h);
    free(h->notes);
    if (h->hid_ok) h->ops->hid_exit();
    if (h->rf) fclose(h->rf);
    if (h->rec) fclose(h->rec);
    free(h->replay);
    free(h->rec_path);
    free(h->seen);
    free(h->ring);
    if (h->efd >= 0) close(h->efd);
    pthread_mutex_destroy(&h->mu);
    pthread_mutex_destroy(&h->qmu);
    pthread_mutex_destroy(&h->pmu);
    pthread_mutex_destroy(&h->rmu);
    pthread_cond_destroy(&h->wake);
    pthread_cond_destroy(&h->drained);
    free(h);
}

int pad_hub_open(const pad_hub_opts *o, pad_hub **out, char *err, size_t errlen)
{
    static const pad_hub_opts none;
    if (!o) o = &none;
    *out = NULL;
    vp_errf(err, errlen, -1, "%s", "");
    pad_hub *h = calloc(1, sizeof *h);
    if (!h) {
        vp_errf(err, errlen, -1, "out of memory");
        return -1;
    }
    h->efd = -1;
    pthread_mutex_init(&h->mu, NULL);
    pthread_mutex_init(&h->qmu, NULL);
    pthread_mutex_init(&h->pmu, NULL);
    pthread_mutex_init(&h->rmu, NULL);
    if (cond_init_mono(&h->wake) || cond_init_mono(&h->drained)) {
        vp_errf(err, errlen, -1, "pthread_cond_init failed");
        free(h);
        return -1;
    }
    atomic_init(&h->stop, false);
    atomic_init(&h->next_id, 1);
    h->ops = o->ops ? o->ops : pad_ops_real();
    h->rescan_ms = o->rescan_ms > 0 ? o->rescan_ms : 1000;
    h->speed = o->replay_speed == 0 || !isfinite(o->replay_speed) ? 1 : o->replay_speed;
    h->loop = o->replay_loop;
    h->rec_last = -1;
    if (!queue_grow(h)) {
        vp_errf(err, errlen, -1, "out of memory");
        goto fail;
    }
    h->efd = eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
    if (h->efd < 0) {
        vp_errf(err, errlen, -1, "eventfd: %s", strerror(errno));
        goto fail;
    }
    if (o->replay) {
        /* no library is touched: a replay works where no pad could */
        if (!(h->replay = strdup(o->replay))) {
            vp_errf(err, errlen, -1, "out of memory");
            goto fail;
        }
        if (o->record && !strcmp(o->record, o->replay)) {
            vp_errf(err, errlen, -1, "%s: recording into the file being replayed", o->record);
            goto fail;
        }
        if (pad_replay_load(h, err, errlen)) goto fail;
    }
    /* after the replay file is known good: a failed open leaves no empty recording behind */
    if (o->record && pad_rec_open(h, o->record, err, errlen)) goto fail;
    if (!h->replay) {
        pad_hid_init(h);
        pad_usb_init(h);
    }
    int rc = pthread_create(&h->thread, NULL, h->replay ? pad_replay_main : hub_main, h);
    if (rc) {
        vp_errf(err, errlen, -1, "%s thread: %s", h->replay ? "replay" : "hub", strerror(rc));
        goto fail;
    }
    h->thread_started = true;
    *out = h;
    return 0;
fail:
    pad_hub_close(h);
    return -1;
}

int pad_hub_counts(pad_hub *h, uint32_t pad, pad_counts *out)
{
    if (!h || !pad) return -1;
    int rc = -1;
    pthread_mutex_lock(&h->mu);
    pad_dev *d = h->pads;
    while (d && d->id != pad) d = d->next;
    for (size_t i = 0; !d && i < h->nrdev; i++)
        if (h->rdev[i].pad && h->rdev[i].pad->id == pad) d = h->rdev[i].pad;
    if (d) {
        out->reports = atomic_load_explicit(&d->c_reports, memory_order_relaxed);
        out->ignored = atomic_load_explicit(&d->c_ignored, memory_order_relaxed);
        out->errors = atomic_load_explicit(&d->c_errors, memory_order_relaxed);
        out->states = atomic_load_explicit(&d->c_states, memory_order_relaxed);
        out->merged = atomic_load_explicit(&d->c_merged, memory_order_relaxed);
        rc = 0;
    }
    pthread_mutex_unlock(&h->mu);
    return rc;
}

/* ---- pad list ------------------------------------------------------------------------- */

int pad_enumerate(const pad_ops *ops, pad_found *out, size_t max, char *err, size_t errlen)
{
    if (!ops) ops = pad_ops_real();
    vp_errf(err, errlen, -1, "%s", "");
    size_t n = 0;
    char hid_why[128] = "", usb_why[128] = "";
    bool hid_ok = pad_hid_list(ops, out, max, &n, hid_why, sizeof hid_why);
    bool usb_ok = pad_usb_list(ops, out, max, &n, usb_why, sizeof usb_why);
    if (!hid_ok && !usb_ok) {
        vp_errf(err, errlen, -1, "neither hidapi (%s) nor libusb (%s) would start",
                hid_why[0] ? hid_why : "?", usb_why);
        return -1;
    }
    if (!hid_ok)
        vp_errf(err, errlen, -1, "hidapi would not start (%s): hidraw pads not listed", hid_why[0] ? hid_why : "?");
    if (!usb_ok) vp_errf(err, errlen, -1, "libusb would not start (%s): USB (Xbox) pads not listed", usb_why);
    return n > (size_t)INT32_MAX ? INT32_MAX : (int)n;
}
