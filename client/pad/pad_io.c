/*
 * pad_io.c — the pad hub (pad_io.h): finds pads through hidapi (hidraw)
 * and libusb, opens them, reads them in one thread each, parses their
 * reports (pad.h) and queues events for the caller's loop; the replay
 * backend reads a hid-recorder file through the same report path; --record
 * writes what live pads send in the same format.
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
#include "pad_io.h"
#include "protocol.h"

#include <errno.h>
#include <math.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/eventfd.h>
#include <time.h>
#include <unistd.h>

#define READ_MS 100           /* a reader's read timeout: how long close waits for it */
#define TICK_MS 100           /* the hub thread's wake-up: reaping, hotplug events */
#define RETRY_MAX_S 30.0      /* the longest wait before opening a failing device again */
#define FLAP_S 2.0            /* a pad removed sooner than this after opening counts as a flap */
#define PARSE_ERR_BURST 5.0   /* ERROR events a pad may send at once, then 1 a second */
#define QUEUE_SOFT_CAP 1024   /* queued events past which ERRORs are dropped and STATEs always merge */
#define USB_ERR_MAX 10        /* consecutive failed USB reads that count as removal */

/* ---- small helpers ------------------------------------------------------------------- */

static double mono_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

static struct timespec mono_at(double t)
{
    struct timespec ts;
    if (t < 0) t = 0;
    ts.tv_sec = (time_t)t;
    ts.tv_nsec = (long)((t - (double)ts.tv_sec) * 1e9);
    if (ts.tv_nsec >= 1000000000L) ts.tv_nsec = 999999999L;
    return ts;
}

/* hidapi's wide strings as printable ASCII ('?' for the rest): the
 * messages and the record file's N: line need no locale. */
static void wcs_ascii(const wchar_t *w, char *out, size_t cap)
{
    size_t n = 0;
    if (cap == 0) return;
    for (; w && *w && n + 1 < cap; w++) out[n++] = *w >= 32 && *w < 127 ? (char)*w : '?';
    out[n] = 0;
}

static int cond_init_mono(pthread_cond_t *c)
{
    pthread_condattr_t a;
    if (pthread_condattr_init(&a)) return -1;
    pthread_condattr_setclock(&a, CLOCK_MONOTONIC);
    int rc = pthread_cond_init(c, &a);
    pthread_condattr_destroy(&a);
    return rc ? -1 : 0;
}

/* ---- the hub ---------------------------------------------------------------------------- */

typedef enum backend { BK_HID, BK_USB, BK_REPLAY } backend;

typedef struct pad_dev pad_dev;
struct pad_dev {
    pad_hub *h;
    pad_dev *next;            /* the hub's list, under h->mu */
    uint32_t id;
    const pad_device_info *info;
    backend bk;
    char key[160];            /* what identifies it between scans: the hidraw path, "usb:BUS-PORTS" */
    char where[128];          /* for messages: "/dev/hidraw3", "usb 1-2 (bus 1, address 5)" */
    char product[128];        /* the record file's N: line */
    uint16_t bus;             /* hid-recorder's: 3 USB, 5 Bluetooth */
    double t_open;            /* CLOCK_MONOTONIC seconds */

    hid_device *hid;
    libusb_device *udev;      /* a reference held while the pad lives */
    libusb_device_handle *uh;
    int iface;
    uint8_t ep_in, ep_out;    /* ep_out 0: none */
    int in_size;              /* the IN endpoint's max packet: one report a transfer */
    bool closed;              /* the device is closed (the reader did it on removal) */

    pad_parser parser;        /* the reader's (or the replay thread's) alone */
    pad_state state;
    int rec_index;            /* D: index in the record file, -1 before its header is written */

    /* parse errors: a token bucket */
    double err_tokens, err_t;
    unsigned err_suppressed;
    int usb_errs;             /* consecutive failed USB reads */
    _Atomic uint64_t c_reports, c_ignored, c_errors, c_states, c_merged; /* pad_counts, relaxed */

    pthread_t thread;
    bool thread_started;
    atomic_bool stop;         /* hub_close: leave the loop */
    atomic_bool gone;         /* libusb said it left */
    atomic_bool done;         /* the reader has finished: the hub thread may join it */

    /* queue bookkeeping, under h->qmu: 1 + the sequence numbers of this
     * pad's newest queued event and newest queued STATE (0: none) */
    uint64_t q_last, q_state;
};

/* what the hub remembers of a device between scans: whether it is still
 * there, and when to try it again after it failed to open or flapped */
typedef struct seen {
    char key[160];
    backend bk;
    bool present;             /* in the last scan */
    bool reported;            /* its open failure was said once */
    unsigned fails;
    double retry_at;
} seen;

typedef struct usb_note {     /* a hotplug callback's news, for the hub thread */
    libusb_device *dev;       /* referenced */
    bool arrived;
} usb_note;

typedef struct replay_dev {
    uint32_t index;           /* D: */
    uint16_t bus, vid, pid;
    bool have_info;
    const pad_device_info *info;
    char name[128];
    pad_dev *pad;             /* once its first report is delivered */
    bool anchored;
    double offset, t_last;    /* its times on the replay's clock: t + offset */
} replay_dev;

struct pad_hub {
    const pad_ops *ops;
    int rescan_ms;
    atomic_bool stop;

    pthread_mutex_t mu;       /* pads (written by the hub thread, read by pad_hub_counts), the wake-up cond */
    pthread_cond_t wake;
    pad_dev *pads;
    seen *seen;               /* the hub thread's alone */
    size_t nseen, capseen;
    atomic_uint next_id;

    /* the event queue: a ring of sequence numbers [head, tail) */
    pthread_mutex_t qmu;
    pthread_cond_t drained;   /* the queue became empty (replay at speed < 0 waits for it) */
    pad_event *ring;
    size_t cap;               /* a power of two */
    uint64_t head, tail;
    unsigned dropped;         /* ERROR events dropped at the soft cap, said in the next one */
    int efd;

    /* live backends */
    pthread_t hub_thread;
    bool hub_started;
    bool hid_ok;
    libusb_context *usb;
    bool hotplug;
    libusb_hotplug_callback_handle hp;
    pthread_mutex_t pmu;      /* notes from the hotplug callback */
    usb_note *notes;
    size_t nnotes, capnotes;
    bool usb_list_failed;

    /* replay */
    char *replay;
    FILE *rf;
    double speed;             /* > 0 scale, < 0 as fast as drained */
    bool loop;
    replay_dev *rdev;
    size_t nrdev;
    pthread_t replay_thread;
    bool replay_started;

    /* record */
    pthread_mutex_t rmu;
    FILE *rec;
    char *rec_path;
    int rec_next, rec_last;   /* the next D: index, the last one written */
    bool rec_failed;
};

/* ---- the event queue ------------------------------------------------------------------ */

static pad_event *slot(pad_hub *h, uint64_t seq)
{
    return &h->ring[seq & (h->cap - 1)];
}

static bool queue_grow(pad_hub *h)
{
    size_t ncap = h->cap ? h->cap * 2 : 64;
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
static void push(pad_hub *h, pad_dev *d, const pad_event *ev)
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

static void push_msg(pad_hub *h, pad_dev *d, pad_event_kind kind, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));
static void push_msg(pad_hub *h, pad_dev *d, pad_event_kind kind, const char *fmt, ...)
{
    pad_event ev;
    memset(&ev, 0, sizeof ev);
    ev.kind = kind;
    ev.pad = d ? d->id : 0;
    ev.info = d ? d->info : NULL;
    ev.t_report = mono_now();
    ev.t_file = d ? ev.t_report - d->t_open : 0;
    if (d) ev.state = d->state;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(ev.msg, sizeof ev.msg, fmt, ap);
    va_end(ap);
    push(h, d, &ev);
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

/* ---- recording ------------------------------------------------------------------------- */

/* one line of the header, the name cut at anything a line cannot hold */
static void rec_clean(char *s)
{
    for (; *s; s++)
        if (*s == '\n' || *s == '\r') *s = ' ';
}

/* The pad's D:/N:/P:/I: header; under rmu. */
static bool rec_header_locked(pad_hub *h, pad_dev *d)
{
    d->rec_index = h->rec_next++;
    char name[128];
    snprintf(name, sizeof name, "%s", d->product[0] ? d->product : d->info->name);
    rec_clean(name);
    char where[128];
    snprintf(where, sizeof where, "%s", d->where);
    rec_clean(where);
    h->rec_last = d->rec_index;
    return fprintf(h->rec, "D: %d\nN: %s\nP: %s\nI: %x %04x %04x\n", d->rec_index, name, where, d->bus, d->info->vid,
                   d->info->pid) > 0 &&
           fflush(h->rec) == 0;
}

static void rec_report(pad_hub *h, pad_dev *d, const uint8_t *buf, size_t len, double t)
{
    if (!h->rec || len > PAD_REPORT_MAX) return; /* a line could not hold it: the parser refuses it anyway */
    char line[16 + 3 * PAD_REPORT_MAX + 32];
    int n = pad_line_format_event(t, buf, len, line, sizeof line);
    if (n <= 0 || (size_t)n >= sizeof line) return;
    int e = 0;
    pthread_mutex_lock(&h->rmu);
    if (!h->rec_failed) {
        bool ok = true;
        if (d->rec_index < 0) ok = rec_header_locked(h, d);
        else if (h->rec_last != d->rec_index) {
            ok = fprintf(h->rec, "D: %d\n", d->rec_index) > 0;
            h->rec_last = d->rec_index;
        }
        /* flushed per line: a killed dump keeps everything up to its last report */
        errno = 0;
        if (!ok || fwrite(line, 1, (size_t)n, h->rec) != (size_t)n || fflush(h->rec)) e = errno ? errno : EIO;
        if (e) h->rec_failed = true;
    }
    pthread_mutex_unlock(&h->rmu);
    if (e) push_msg(h, NULL, PAD_EV_ERROR, "recording to %s stopped: %s", h->rec_path, strerror(e));
}

/* ---- the report path ------------------------------------------------------------------ */

/* Sends the parser's output to the device (an Xbox One ack or power-on);
 * the reader's thread. */
static void send_out(pad_dev *d)
{
    pad_hub *h = d->h;
    size_t n = d->parser.out_len;
    d->parser.out_len = 0;
    if (!n || n > sizeof d->parser.out) return;
    if (d->bk == BK_HID) {
        if (h->ops->hid_write(d->hid, d->parser.out, n) < 0) {
            char why[128];
            wcs_ascii(h->ops->hid_error(d->hid), why, sizeof why);
            push_msg(h, d, PAD_EV_ERROR, "%s: write of %zu bytes failed: %s", d->info->name, n, why);
        }
    } else if (d->bk == BK_USB) {
        int sent = 0;
        int rc = d->ep_out ? h->ops->libusb_interrupt_transfer(d->uh, d->ep_out, d->parser.out, (int)n, &sent, 250)
                           : LIBUSB_ERROR_NOT_SUPPORTED;
        if (rc < 0)
            push_msg(h, d, PAD_EV_ERROR, "%s: write of %zu bytes failed: %s", d->info->name, n,
                     h->ops->libusb_strerror(rc));
    }
    /* replay: nothing to send it to */
}

/* A pad's errors through a token bucket (PARSE_ERR_BURST, then one a
 * second): true when this one may be said; more then tells how many were
 * not since the last that was. */
static bool err_allowed(pad_dev *d, double now, char *more, size_t morelen)
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
    if (!err_allowed(d, now, more, sizeof more)) return;
    push_msg(d->h, d, PAD_EV_ERROR, "%s: report 0x%02x of %zu bytes refused: %s%s", d->info->name, len ? buf[0] : 0,
             len, pad_strerror(rc), more);
}

/* One report from the device (or the file): recorded, parsed, its output
 * sent, a STATE queued when the state changed. */
static void pad_report(pad_dev *d, const uint8_t *buf, size_t len, double t_report, double t_file)
{
    pad_hub *h = d->h;
    rec_report(h, d, buf, len, t_file);
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
        push(h, d, &ev);
    } else if (rc < 0) {
        parse_error(d, rc, buf, len, t_report);
    }
}

static pad_dev *pad_new(pad_hub *h, const pad_device_info *info, backend bk, const char *key, const char *where)
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
    d->t_open = d->err_t = mono_now();
    pad_state_init(&d->state);
    pad_parser_init(&d->parser, info->proto);
    atomic_init(&d->stop, false);
    atomic_init(&d->gone, false);
    atomic_init(&d->done, false);
    d->id = atomic_fetch_add(&h->next_id, 1);
    return d;
}

static void pad_close_dev(pad_dev *d)
{
    const pad_ops *o = d->h->ops;
    if (d->closed) return;
    d->closed = true;
    if (d->bk == BK_HID && d->hid) o->hid_close(d->hid);
    if (d->bk == BK_USB && d->uh) {
        o->libusb_release_interface(d->uh, d->iface); /* the kernel's driver comes back (auto-detach) */
        o->libusb_close(d->uh);
    }
    d->hid = NULL;
    d->uh = NULL;
}

/* The reader's end on a failed read: the device closed, REMOVED queued; the
 * hub thread joins it and frees the pad. */
static void pad_removed(pad_dev *d, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void pad_removed(pad_dev *d, const char *fmt, ...)
{
    char why[160];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(why, sizeof why, fmt, ap);
    va_end(ap);
    pad_close_dev(d);
    push_msg(d->h, d, PAD_EV_REMOVED, "%s at %s: %s; closed after %llu reports (%llu refused)", d->info->name,
             d->where, why, (unsigned long long)atomic_load(&d->c_reports),
             (unsigned long long)atomic_load(&d->c_errors));
}

/* ---- readers ------------------------------------------------------------------------------ */

static void *hid_reader(void *arg)
{
    pad_dev *d = arg;
    const pad_ops *o = d->h->ops;
    /* one more than a line can carry: hidraw cuts a longer report to
       this, and the parser refuses it as too long */
    uint8_t buf[PAD_REPORT_MAX + 1];
    while (!atomic_load(&d->stop)) {
        int n = o->hid_read_timeout(d->hid, buf, sizeof buf, READ_MS);
        if (n > 0) {
            double now = mono_now();
            pad_report(d, buf, (size_t)n, now, now - d->t_open);
        } else if (n < 0) {
            char why[128];
            wcs_ascii(o->hid_error(d->hid), why, sizeof why);
            pad_removed(d, "read failed (unplugged?): %s", why[0] ? why : "no reason given");
            break;
        }
    }
    atomic_store(&d->done, true);
    return NULL;
}

static void *usb_reader(void *arg)
{
    pad_dev *d = arg;
    const pad_ops *o = d->h->ops;
    uint8_t buf[PAD_REPORT_MAX];
    while (!atomic_load(&d->stop)) {
        if (atomic_load(&d->gone)) {
            pad_removed(d, "unplugged (USB hotplug)");
            break;
        }
        int got = 0;
        int rc = o->libusb_interrupt_transfer(d->uh, d->ep_in, buf, d->in_size, &got, READ_MS);
        if (rc == 0 || (rc == LIBUSB_ERROR_TIMEOUT && got > 0)) {
            d->usb_errs = 0;
            double now = mono_now();
            if (got > 0) pad_report(d, buf, (size_t)got, now, now - d->t_open);
        } else if (rc == LIBUSB_ERROR_TIMEOUT || rc == LIBUSB_ERROR_INTERRUPTED) {
            continue;
        } else if (rc == LIBUSB_ERROR_NO_DEVICE) {
            pad_removed(d, "unplugged (%s)", o->libusb_strerror(rc));
            break;
        } else if (++d->usb_errs >= USB_ERR_MAX) {
            pad_removed(d, "%d reads in a row failed: %s", d->usb_errs, o->libusb_strerror(rc));
            break;
        } else {
            atomic_fetch_add_explicit(&d->c_errors, 1, memory_order_relaxed);
            char more[48];
            if (err_allowed(d, mono_now(), more, sizeof more))
                push_msg(d->h, d, PAD_EV_ERROR, "%s: read failed: %s%s", d->info->name, o->libusb_strerror(rc), more);
            struct timespec ts = {0, 20 * 1000000L}; /* a stalled endpoint must not spin */
            nanosleep(&ts, NULL);
        }
    }
    atomic_store(&d->done, true);
    return NULL;
}

/* Starts a freshly opened pad: the parser's start packet (before any read:
 * the Xbox One sends nothing until it has it), ADDED, its reader. On
 * failure the device is closed and the pad freed (an ERROR queued). */
static void pad_start(pad_hub *h, pad_dev *d, const char *how)
{
    pad_parser_start(&d->parser);
    if (d->parser.out_len) send_out(d);
    if (h->rec) {
        int e = 0;
        pthread_mutex_lock(&h->rmu);
        errno = 0;
        if (!h->rec_failed && !rec_header_locked(h, d)) {
            e = errno ? errno : EIO;
            h->rec_failed = true;
        }
        pthread_mutex_unlock(&h->rmu);
        if (e) push_msg(h, NULL, PAD_EV_ERROR, "recording to %s stopped: %s", h->rec_path, strerror(e));
    }
    push_msg(h, d, PAD_EV_ADDED, "%s, %s %s%s", d->info->name, how, d->where, d->bus == 5 ? " (Bluetooth)" : "");
    int rc = pthread_create(&d->thread, NULL, d->bk == BK_HID ? hid_reader : usb_reader, d);
    if (rc) {
        pad_close_dev(d);
        push_msg(h, d, PAD_EV_REMOVED, "%s at %s: no reader thread: %s; closed", d->info->name, d->where,
                 strerror(rc));
        if (d->udev) h->ops->libusb_unref_device(d->udev);
        free(d);
        return;
    }
    d->thread_started = true;
    pthread_mutex_lock(&h->mu);
    d->next = h->pads;
    h->pads = d;
    pthread_mutex_unlock(&h->mu);
}

/* ---- what the hub remembers of devices (the hub thread's) ------------------------------ */

static seen *seen_get(pad_hub *h, backend bk, const char *key)
{
    for (size_t i = 0; i < h->nseen; i++)
        if (h->seen[i].bk == bk && !strcmp(h->seen[i].key, key)) return &h->seen[i];
    if (h->nseen == h->capseen) {
        size_t ncap = h->capseen ? h->capseen * 2 : 16;
        seen *s = realloc(h->seen, ncap * sizeof *s);
        if (!s) return NULL;
        h->seen = s;
        h->capseen = ncap;
    }
    seen *s = &h->seen[h->nseen++];
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

/* An open that failed: said once while the device stays, tried again later. */
static void open_failed(pad_hub *h, seen *s, const pad_device_info *info, const char *where, const char *why,
                        const char *hint)
{
    if (s) {
        s->fails++;
        s->retry_at = mono_now() + backoff(h, s->fails);
        if (s->reported) return;
        s->reported = true;
    }
    pad_event ev;
    memset(&ev, 0, sizeof ev);
    ev.kind = PAD_EV_ERROR; /* no pad of the hub's yet: pad 0, info NULL, the device named in msg */
    ev.t_report = mono_now();
    snprintf(ev.msg, sizeof ev.msg, "cannot open %s at %s: %s%s", info->name, where, why, hint);
    push(h, NULL, &ev);
}

static void open_worked(seen *s)
{
    if (!s) return;
    s->reported = false;
    s->retry_at = 0;
}

static pad_dev *pad_by_key(pad_hub *h, backend bk, const char *key)
{
    for (pad_dev *d = h->pads; d; d = d->next)
        if (d->bk == bk && !strcmp(d->key, key)) return d;
    return NULL;
}

static pad_dev *pad_by_udev(pad_hub *h, libusb_device *dev)
{
    for (pad_dev *d = h->pads; d; d = d->next)
        if (d->bk == BK_USB && d->udev == dev) return d;
    return NULL;
}

/* forget the devices the last scan did not see (and no open pad holds) */
static void seen_prune(pad_hub *h, backend bk)
{
    size_t k = 0;
    for (size_t i = 0; i < h->nseen; i++) {
        seen *s = &h->seen[i];
        bool keep = s->bk != bk || s->present || pad_by_key(h, s->bk, s->key);
        if (keep) h->seen[k++] = *s;
    }
    h->nseen = k;
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
        pad_close_dev(d);
        seen *s = seen_get(h, d->bk, d->key);
        if (s) {
            double now = mono_now();
            s->fails = now - d->t_open < FLAP_S ? s->fails + 1 : 0;
            /* the first removal of a pad is a plug-out: plugged back it comes back at once */
            s->retry_at = s->fails <= 1 ? 0 : now + backoff(h, s->fails - 1);
        }
        if (d->udev) h->ops->libusb_unref_device(d->udev);
        free(d);
    }
    pthread_mutex_unlock(&h->mu);
}

/* ---- hidraw ----------------------------------------------------------------------------- */

static void hid_open_one(pad_hub *h, const struct hid_device_info *i, const pad_device_info *info, seen *s)
{
    const pad_ops *o = h->ops;
    hid_device *dev = o->hid_open_path(i->path);
    if (!dev) {
        char why[160];
        wcs_ascii(o->hid_error(NULL), why, sizeof why);
        open_failed(h, s, info, i->path, why[0] ? why : "hid_open_path failed",
                    strstr(why, "ermission") ? " (no access: a udev rule must give you /dev/hidraw*)" : "");
        return;
    }
    open_worked(s);
    pad_dev *d = pad_new(h, info, BK_HID, i->path, i->path);
    if (!d) {
        o->hid_close(dev);
        open_failed(h, s, info, i->path, "out of memory", "");
        return;
    }
    d->hid = dev;
    d->bus = i->bus_type == HID_API_BUS_BLUETOOTH ? 5 : 3;
    d->parser.bluetooth = d->bus == 5;
    wcs_ascii(i->product_string, d->product, sizeof d->product);
    pad_start(h, d, "hidraw");
}

static void scan_hid(pad_hub *h)
{
    const pad_ops *o = h->ops;
    struct hid_device_info *list = o->hid_enumerate(0, 0);
    for (size_t k = 0; k < h->nseen; k++)
        if (h->seen[k].bk == BK_HID) h->seen[k].present = false;
    double now = mono_now();
    for (struct hid_device_info *i = list; i; i = i->next) {
        if (!i->path) continue;
        const pad_device_info *info = pad_device_lookup(i->vendor_id, i->product_id);
        if (!info || info->path != PAD_PATH_HIDRAW) continue; /* not a pad, or one read through libusb */
        seen *s = seen_get(h, BK_HID, i->path);
        if (s) s->present = true;
        /* hidapi 0.13 lists a node once per top-level usage: one open */
        pthread_mutex_lock(&h->mu);
        bool open = pad_by_key(h, BK_HID, i->path) != NULL;
        pthread_mutex_unlock(&h->mu);
        if (open || (s && now < s->retry_at)) continue;
        hid_open_one(h, i, info, s);
    }
    pthread_mutex_lock(&h->mu);
    seen_prune(h, BK_HID);
    pthread_mutex_unlock(&h->mu);
    if (list) o->hid_free_enumeration(list);
}

/* ---- libusb ------------------------------------------------------------------------------- */

static void usb_where(const pad_ops *o, libusb_device *dev, char *key, size_t keylen, char *where, size_t wlen)
{
    uint8_t ports[8];
    int n = o->libusb_get_port_numbers(dev, ports, (int)sizeof ports);
    unsigned bus = o->libusb_get_bus_number(dev), addr = o->libusb_get_device_address(dev);
    char path[40] = "";
    size_t k = 0;
    for (int i = 0; i < n && k + 5 < sizeof path; i++)
        k += (size_t)snprintf(path + k, sizeof path - k, "%s%u", i ? "." : "", ports[i]);
    if (n <= 0) snprintf(path, sizeof path, "a%u", addr); /* no port path (a root hub): the address */
    snprintf(key, keylen, "usb:%u-%s", bus, path);
    snprintf(where, wlen, "usb %u-%s (bus %u, address %u)", bus, path, bus, addr);
}

/* The XInput / GIP interface and its interrupt endpoints. */
static bool usb_find_iface(const struct libusb_config_descriptor *cfg, pad_proto proto, int *iface, uint8_t *ep_in,
                           uint8_t *ep_out, int *in_size)
{
    uint8_t sub = proto == PAD_PROTO_XBOXONE ? 0x47 : 0x5D, pro = proto == PAD_PROTO_XBOXONE ? 0xD0 : 0x01;
    for (int i = 0; cfg && i < cfg->bNumInterfaces; i++) {
        const struct libusb_interface *it = &cfg->interface[i];
        if (it->num_altsetting < 1 || !it->altsetting) continue;
        const struct libusb_interface_descriptor *a = &it->altsetting[0];
        if (a->bInterfaceClass != 0xFF || a->bInterfaceSubClass != sub || a->bInterfaceProtocol != pro) continue;
        *ep_in = *ep_out = 0;
        for (int e = 0; e < a->bNumEndpoints && a->endpoint; e++) {
            const struct libusb_endpoint_descriptor *ep = &a->endpoint[e];
            if ((ep->bmAttributes & LIBUSB_TRANSFER_TYPE_MASK) != LIBUSB_TRANSFER_TYPE_INTERRUPT) continue;
            if ((ep->bEndpointAddress & LIBUSB_ENDPOINT_DIR_MASK) == LIBUSB_ENDPOINT_IN) {
                if (!*ep_in) {
                    *ep_in = ep->bEndpointAddress;
                    *in_size = ep->wMaxPacketSize & 0x7FF;
                }
            } else if (!*ep_out) {
                *ep_out = ep->bEndpointAddress;
            }
        }
        if (!*ep_in) continue;
        /* exactly one packet a transfer: a longer buffer would wait for a
           second packet after a full-size one */
        if (*in_size < 8) *in_size = 64;
        if (*in_size > PAD_REPORT_MAX) *in_size = PAD_REPORT_MAX;
        *iface = a->bInterfaceNumber;
        return true;
    }
    return false;
}

static void usb_open_one(pad_hub *h, libusb_device *dev, const pad_device_info *info, const char *key,
                         const char *where, seen *s)
{
    const pad_ops *o = h->ops;
    struct libusb_config_descriptor *cfg = NULL;
    int iface = 0, in_size = 64;
    uint8_t ep_in = 0, ep_out = 0;
    int rc = o->libusb_get_active_config_descriptor(dev, &cfg);
    if (rc < 0) {
        open_failed(h, s, info, where, o->libusb_strerror(rc), " (reading its configuration)");
        return;
    }
    bool found = usb_find_iface(cfg, info->proto, &iface, &ep_in, &ep_out, &in_size);
    o->libusb_free_config_descriptor(cfg);
    if (!found) {
        open_failed(h, s, info, where, "it has no XInput / GIP interface with an interrupt IN endpoint", "");
        return;
    }
    if (info->proto == PAD_PROTO_XBOXONE && !ep_out) {
        open_failed(h, s, info, where, "its GIP interface has no OUT endpoint for the power-on", "");
        return;
    }
    libusb_device_handle *uh = NULL;
    if ((rc = o->libusb_open(dev, &uh)) < 0) {
        open_failed(h, s, info, where, o->libusb_strerror(rc),
                    rc == LIBUSB_ERROR_ACCESS ? " (no access: a udev rule must give you /dev/bus/usb/...)" : "");
        return;
    }
    /* the kernel's xpad holds the interface: detached while we claim it,
       attached again on release */
    rc = o->libusb_set_auto_detach_kernel_driver(uh, 1);
    if (rc < 0 && rc != LIBUSB_ERROR_NOT_SUPPORTED) {
        o->libusb_close(uh);
        open_failed(h, s, info, where, o->libusb_strerror(rc), " (detaching the kernel's driver)");
        return;
    }
    if ((rc = o->libusb_claim_interface(uh, iface)) < 0) {
        o->libusb_close(uh);
        open_failed(h, s, info, where, o->libusb_strerror(rc),
                    rc == LIBUSB_ERROR_BUSY ? " (another program has claimed it)" : " (claiming its interface)");
        return;
    }
    pad_dev *d = pad_new(h, info, BK_USB, key, where);
    if (!d) {
        o->libusb_release_interface(uh, iface);
        o->libusb_close(uh);
        open_failed(h, s, info, where, "out of memory", "");
        return;
    }
    open_worked(s);
    d->udev = o->libusb_ref_device(dev);
    d->uh = uh;
    d->iface = iface;
    d->ep_in = ep_in;
    d->ep_out = ep_out;
    d->in_size = in_size;
    pad_start(h, d, "libusb");
}

/* A USB device seen by a scan or the hotplug callback: opened if it is a
 * pad not open yet and not waiting for a retry. */
static void usb_consider(pad_hub *h, libusb_device *dev, bool mark_present)
{
    const pad_ops *o = h->ops;
    struct libusb_device_descriptor dd;
    if (o->libusb_get_device_descriptor(dev, &dd) < 0) return;
    const pad_device_info *info = pad_device_lookup(dd.idVendor, dd.idProduct);
    if (!info || info->path != PAD_PATH_LIBUSB) return;
    char key[64], where[128];
    usb_where(o, dev, key, sizeof key, where, sizeof where);
    pthread_mutex_lock(&h->mu);
    bool open = pad_by_udev(h, dev) != NULL;
    pthread_mutex_unlock(&h->mu);
    seen *s = seen_get(h, BK_USB, key);
    if (s && mark_present) s->present = true;
    if (open || (s && mono_now() < s->retry_at)) return;
    usb_open_one(h, dev, info, key, where, s);
}

static void scan_usb(pad_hub *h)
{
    const pad_ops *o = h->ops;
    libusb_device **list = NULL;
    ssize_t n = o->libusb_get_device_list(h->usb, &list);
    if (n < 0) {
        if (!h->usb_list_failed)
            push_msg(h, NULL, PAD_EV_ERROR, "listing USB devices failed: %s", o->libusb_strerror((int)n));
        h->usb_list_failed = true;
        return;
    }
    h->usb_list_failed = false;
    for (size_t k = 0; k < h->nseen; k++)
        if (h->seen[k].bk == BK_USB) h->seen[k].present = false;
    for (ssize_t i = 0; i < n; i++) usb_consider(h, list[i], true);
    pthread_mutex_lock(&h->mu);
    seen_prune(h, BK_USB);
    pthread_mutex_unlock(&h->mu);
    o->libusb_free_device_list(list, 1);
}

/* libusb's hotplug callback: runs in whichever thread handles libusb's
 * events (the hub's, or a reader inside a transfer), so it only queues. */
static int hotplug_cb(libusb_context *ctx, libusb_device *dev, libusb_hotplug_event event, void *user)
{
    (void)ctx;
    pad_hub *h = user;
    pthread_mutex_lock(&h->pmu);
    if (h->nnotes == h->capnotes) {
        size_t ncap = h->capnotes ? h->capnotes * 2 : 16;
        usb_note *n = realloc(h->notes, ncap * sizeof *n);
        if (!n) { /* out of memory: the news is lost, the periodic rescan still finds the device */
            pthread_mutex_unlock(&h->pmu);
            return 0;
        }
        h->notes = n;
        h->capnotes = ncap;
    }
    h->notes[h->nnotes].dev = h->ops->libusb_ref_device(dev);
    h->notes[h->nnotes].arrived = event == LIBUSB_HOTPLUG_EVENT_DEVICE_ARRIVED;
    h->nnotes++;
    pthread_mutex_unlock(&h->pmu);
    return 0; /* stay registered */
}

static void usb_notes(pad_hub *h)
{
    pthread_mutex_lock(&h->pmu);
    usb_note *notes = h->notes;
    size_t n = h->nnotes;
    h->notes = NULL;
    h->nnotes = h->capnotes = 0;
    pthread_mutex_unlock(&h->pmu);
    for (size_t i = 0; i < n; i++) {
        libusb_device *dev = notes[i].dev;
        if (notes[i].arrived) {
            usb_consider(h, dev, true);
        } else {
            pthread_mutex_lock(&h->mu);
            pad_dev *d = pad_by_udev(h, dev);
            if (d) atomic_store(&d->gone, true); /* its reader says REMOVED at its next timeout */
            pthread_mutex_unlock(&h->mu);
            char key[64], where[128];
            usb_where(h->ops, dev, key, sizeof key, where, sizeof where);
            for (size_t k = 0; k < h->nseen; k++)
                if (h->seen[k].bk == BK_USB && !strcmp(h->seen[k].key, key)) h->seen[k].present = false;
            pthread_mutex_lock(&h->mu);
            seen_prune(h, BK_USB);
            pthread_mutex_unlock(&h->mu);
        }
        h->ops->libusb_unref_device(dev);
    }
    free(notes);
}

/* ---- the hub thread ------------------------------------------------------------------------ */

static void *hub_main(void *arg)
{
    pad_hub *h = arg;
    double period = h->rescan_ms / 1000.0, next_scan = 0;
    while (!atomic_load(&h->stop)) {
        reap(h);
        double now = mono_now();
        if (now >= next_scan) {
            if (h->hid_ok) scan_hid(h);
            if (h->usb) scan_usb(h);
            next_scan = now + period;
        }
        int rc = -1;
        if (h->usb && h->hotplug) {
            /* waits for hotplug news (and serves any transfer's events) */
            struct timeval tv = {0, TICK_MS * 1000};
            rc = h->ops->libusb_handle_events_timeout_completed(h->usb, &tv, NULL);
            usb_notes(h);
        }
        if (rc < 0) { /* no hotplug, or libusb failed at once: a timed wait, never a spin */
            double until = mono_now() + TICK_MS / 1000.0;
            if (until > next_scan) until = next_scan;
            struct timespec ts = mono_at(until);
            pthread_mutex_lock(&h->mu);
            if (!atomic_load(&h->stop)) pthread_cond_timedwait(&h->wake, &h->mu, &ts);
            pthread_mutex_unlock(&h->mu);
        }
    }
    return NULL;
}

/* ---- replay ---------------------------------------------------------------------------- */

/* One line of the file into *buf (its newline and CRs before it cut); -1 at
 * the end. *buf grows as getline's does. */
static ssize_t next_line(FILE *f, char **buf, size_t *cap)
{
    ssize_t n = getline(buf, cap, f);
    if (n < 0) return -1;
    while (n > 0 && ((*buf)[n - 1] == '\n' || (*buf)[n - 1] == '\r')) n--;
    return n;
}

static replay_dev *rdev_find(pad_hub *h, uint32_t index)
{
    for (size_t i = 0; i < h->nrdev; i++)
        if (h->rdev[i].index == index) return &h->rdev[i];
    return NULL;
}

static replay_dev *rdev_get(pad_hub *h, uint32_t index)
{
    for (size_t i = 0; i < h->nrdev; i++)
        if (h->rdev[i].index == index) return &h->rdev[i];
    replay_dev *r = realloc(h->rdev, (h->nrdev + 1) * sizeof *r);
    if (!r) return NULL;
    h->rdev = r;
    replay_dev *d = &h->rdev[h->nrdev++];
    memset(d, 0, sizeof *d);
    d->index = index;
    return d;
}

/* The whole file checked before anything is delivered: a bad line fails
 * pad_hub_open naming it, not a replay half done. Memory: the devices
 * only; the reports are read again as they are delivered. */
static int replay_load(pad_hub *h, char *err, size_t errlen)
{
    const char *path = h->replay;
    h->rf = fopen(path, "r");
    if (!h->rf) {
        vp_errf(err, errlen, -1, "%s: %s", path, strerror(errno));
        return -1;
    }
    char *line = NULL;
    size_t cap = 0;
    ssize_t n;
    unsigned long lineno = 0;
    int rc = -1;
    pad_line *pl = malloc(sizeof *pl);
    if (!pl) {
        vp_errf(err, errlen, -1, "%s: out of memory", path);
        goto out;
    }
    replay_dev *cur = NULL;
    while ((n = next_line(h->rf, &line, &cap)) >= 0) {
        lineno++;
        char why[160] = "";
        if (pad_line_parse(line, (size_t)n, pl, why, sizeof why)) {
            vp_errf(err, errlen, -1, "%s:%lu: %s", path, lineno, why[0] ? why : "malformed line");
            goto out;
        }
        if (pl->kind == PAD_LINE_DEVICE || (!cur && pl->kind != PAD_LINE_BLANK && pl->kind != PAD_LINE_OTHER)) {
            /* lines before the first D: belong to device 0, as hid-recorder's single-device files */
            if (!(cur = rdev_get(h, pl->kind == PAD_LINE_DEVICE ? pl->device : 0))) {
                vp_errf(err, errlen, -1, "%s: out of memory", path);
                goto out;
            }
        }
        switch (pl->kind) {
        case PAD_LINE_INFO:
            cur->info = pad_device_lookup(pl->vid, pl->pid);
            if (!cur->info) {
                vp_errf(err, errlen, -1, "%s:%lu: unknown device %04x:%04x (not a pad this build reads)", path, lineno,
                        pl->vid, pl->pid);
                goto out;
            }
            cur->have_info = true;
            cur->bus = pl->bus;
            cur->vid = pl->vid;
            cur->pid = pl->pid;
            break;
        case PAD_LINE_NAME: snprintf(cur->name, sizeof cur->name, "%s", pl->name); break;
        case PAD_LINE_EVENT:
            if (!cur->have_info) {
                vp_errf(err, errlen, -1, "%s:%lu: a report before device %u's I: line (which pad it is)", path, lineno,
                        cur->index);
                goto out;
            }
            break;
        default: break;
        }
    }
    if (ferror(h->rf)) {
        vp_errf(err, errlen, -1, "%s: %s", path, strerror(errno));
        goto out;
    }
    rc = 0;
out:
    free(line);
    free(pl);
    return rc;
}

/* Sleeps until CLOCK_MONOTONIC t or the hub closes; false when it closed. */
static bool sleep_until(pad_hub *h, double t)
{
    struct timespec ts = mono_at(t);
    pthread_mutex_lock(&h->mu);
    while (!atomic_load(&h->stop) && mono_now() < t)
        if (pthread_cond_timedwait(&h->wake, &h->mu, &ts) == ETIMEDOUT) break;
    pthread_mutex_unlock(&h->mu);
    return !atomic_load(&h->stop);
}

/* Waits until the caller has read every event (speed < 0). */
static bool wait_drained(pad_hub *h)
{
    pthread_mutex_lock(&h->qmu);
    while (!atomic_load(&h->stop) && h->head != h->tail) pthread_cond_wait(&h->drained, &h->qmu);
    pthread_mutex_unlock(&h->qmu);
    return !atomic_load(&h->stop);
}

static void *replay_main(void *arg)
{
    pad_hub *h = arg;
    char *line = NULL;
    size_t cap = 0;
    pad_line *pl = malloc(sizeof *pl);
    if (!pl) {
        push_msg(h, NULL, PAD_EV_ERROR, "replay of %s: out of memory", h->replay);
        goto end;
    }
    /* the file's clock: each device's times are placed on it from its
       first report (and again when its times go back: a loop, or a file
       of concatenated captures), so devices recorded with their own
       origins (our --record) and hid-recorder's shared one both replay */
    double clock = 0, t0 = mono_now();
    for (;;) {
        rewind(h->rf);
        replay_dev *cur = NULL;
        unsigned long lineno = 0, reports = 0;
        ssize_t n;
        for (size_t i = 0; i < h->nrdev; i++) h->rdev[i].anchored = false;
        while ((n = next_line(h->rf, &line, &cap)) >= 0) {
            if (atomic_load(&h->stop)) goto end;
            lineno++;
            char why[160] = "";
            if (pad_line_parse(line, (size_t)n, pl, why, sizeof why)) {
                /* it passed at open: the file changed under us */
                push_msg(h, NULL, PAD_EV_ERROR, "%s:%lu: %s (the file changed during the replay)", h->replay,
                         lineno, why);
                goto end;
            }
            /* found, never made: the table is fixed once the thread runs (pad_hub_counts reads it) */
            if (pl->kind == PAD_LINE_DEVICE || (!cur && pl->kind != PAD_LINE_BLANK && pl->kind != PAD_LINE_OTHER))
                cur = rdev_find(h, pl->kind == PAD_LINE_DEVICE ? pl->device : 0);
            if (pl->kind != PAD_LINE_EVENT) continue;
            if (!cur || !cur->have_info) {
                push_msg(h, NULL, PAD_EV_ERROR, "%s:%lu: a report of an unknown device (the file changed during "
                         "the replay)", h->replay, lineno);
                goto end;
            }
            if (!cur->anchored || pl->t < cur->t_last) {
                cur->offset = clock - pl->t;
                cur->anchored = true;
            }
            cur->t_last = pl->t;
            if (pl->t + cur->offset > clock) clock = pl->t + cur->offset;
            if (h->speed > 0) {
                if (!sleep_until(h, t0 + clock / h->speed)) goto end;
            } else if (!wait_drained(h)) {
                goto end;
            }
            if (!cur->pad) {
                char where[200];
                snprintf(where, sizeof where, "%s device %u", h->replay, cur->index);
                pad_dev *d = pad_new(h, cur->info, BK_REPLAY, where, where);
                if (!d) {
                    push_msg(h, NULL, PAD_EV_ERROR, "replay of %s: out of memory", h->replay);
                    goto end;
                }
                d->bus = cur->bus;
                d->parser.bluetooth = cur->bus == 5;
                snprintf(d->product, sizeof d->product, "%s", cur->name);
                d->t_open = t0;
                pthread_mutex_lock(&h->mu); /* pad_hub_counts looks */
                cur->pad = d;
                pthread_mutex_unlock(&h->mu);
                pad_parser_start(&d->parser);
                d->parser.out_len = 0; /* nothing to send the power-on to */
                push_msg(h, d, PAD_EV_ADDED, "%s, replay of %s%s", d->info->name, where,
                         cur->bus == 5 ? " (Bluetooth)" : "");
            }
            reports++;
            pad_report(cur->pad, pl->data, pl->len, mono_now(), pl->t);
        }
        if (!h->loop || !reports) break;
        /* a file whose reports all carry one time would loop without a pause */
        if (h->speed > 0 && !sleep_until(h, mono_now() + 0.001)) goto end;
    }
    {
        pad_event ev;
        memset(&ev, 0, sizeof ev);
        ev.kind = PAD_EV_END;
        ev.t_report = mono_now();
        snprintf(ev.msg, sizeof ev.msg, "end of %s", h->replay);
        push(h, NULL, &ev);
    }
end:
    free(line);
    free(pl);
    return NULL;
}

/* ---- open / close ---------------------------------------------------------------------- */

void pad_hub_close(pad_hub *h)
{
    if (!h) return;
    atomic_store(&h->stop, true);
    pthread_mutex_lock(&h->mu);
    pthread_cond_broadcast(&h->wake);
    pthread_mutex_unlock(&h->mu);
    pthread_mutex_lock(&h->qmu);
    pthread_cond_broadcast(&h->drained);
    pthread_mutex_unlock(&h->qmu);
    /* every reader told first, then joined: one READ_MS in all, not one
       each, and while the hub thread finishes its own wait (told again
       after: it may have opened one more) */
    pthread_mutex_lock(&h->mu);
    for (pad_dev *d = h->pads; d; d = d->next) atomic_store(&d->stop, true);
    pthread_mutex_unlock(&h->mu);
    if (h->hub_started) pthread_join(h->hub_thread, NULL);
    if (h->replay_started) pthread_join(h->replay_thread, NULL);
    for (pad_dev *d = h->pads; d; d = d->next) atomic_store(&d->stop, true);
    while (h->pads) {
        pad_dev *d = h->pads;
        h->pads = d->next;
        if (d->thread_started) pthread_join(d->thread, NULL);
        pad_close_dev(d);
        if (d->udev) h->ops->libusb_unref_device(d->udev);
        free(d);
    }
    for (size_t i = 0; i < h->nrdev; i++) free(h->rdev[i].pad);
    free(h->rdev);
    if (h->usb) {
        if (h->hotplug) h->ops->libusb_hotplug_deregister_callback(h->usb, h->hp);
        for (size_t i = 0; i < h->nnotes; i++) h->ops->libusb_unref_device(h->notes[i].dev);
        h->ops->libusb_exit(h->usb);
    }
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
        if (replay_load(h, err, errlen)) goto fail;
    }
    /* after the replay file is known good: a failed open leaves no empty recording behind */
    if (o->record) {
        if (!(h->rec_path = strdup(o->record))) {
            vp_errf(err, errlen, -1, "out of memory");
            goto fail;
        }
        if (!(h->rec = fopen(o->record, "w"))) {
            vp_errf(err, errlen, -1, "%s: %s", o->record, strerror(errno));
            goto fail;
        }
        fprintf(h->rec, "# vantage pad dump --record: hid-recorder's format, times in seconds since each pad "
                        "was opened\n");
        fflush(h->rec);
    }
    if (h->replay) {
        int rc = pthread_create(&h->replay_thread, NULL, replay_main, h);
        if (rc) {
            vp_errf(err, errlen, -1, "replay thread: %s", strerror(rc));
            goto fail;
        }
        h->replay_started = true;
        *out = h;
        return 0;
    }
    const pad_ops *ops = h->ops;
    if (ops->hid_init() == 0) {
        h->hid_ok = true;
    } else {
        char why[160];
        wcs_ascii(ops->hid_error(NULL), why, sizeof why);
        push_msg(h, NULL, PAD_EV_ERROR, "hidapi would not start (%s): PlayStation and Switch pads are not read",
                 why[0] ? why : "no reason given");
    }
    int rc = ops->libusb_init(&h->usb);
    if (rc < 0) {
        h->usb = NULL;
        push_msg(h, NULL, PAD_EV_ERROR, "libusb would not start (%s): Xbox pads are not read",
                 ops->libusb_strerror(rc));
    } else if (ops->libusb_has_capability(LIBUSB_CAP_HAS_HOTPLUG)) {
        /* ENUMERATE: the devices present now come through the callback too
           (queued; the hub thread's first scan finds them anyway) */
        int events = LIBUSB_HOTPLUG_EVENT_DEVICE_ARRIVED | LIBUSB_HOTPLUG_EVENT_DEVICE_LEFT;
        rc = ops->libusb_hotplug_register_callback(h->usb, events, LIBUSB_HOTPLUG_ENUMERATE, LIBUSB_HOTPLUG_MATCH_ANY,
                                                   LIBUSB_HOTPLUG_MATCH_ANY, LIBUSB_HOTPLUG_MATCH_ANY, hotplug_cb, h,
                                                   &h->hp);
        h->hotplug = rc == LIBUSB_SUCCESS; /* else the periodic rescan is the only path */
    }
    rc = pthread_create(&h->hub_thread, NULL, hub_main, h);
    if (rc) {
        vp_errf(err, errlen, -1, "hub thread: %s", strerror(rc));
        goto fail;
    }
    h->hub_started = true;
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
    bool hid_ok = ops->hid_init() == 0, usb_ok = false;
    char hid_why[128] = "", usb_why[128] = "";
    if (hid_ok) {
        struct hid_device_info *list = ops->hid_enumerate(0, 0);
        for (struct hid_device_info *i = list; i; i = i->next) {
            const pad_device_info *info = i->path ? pad_device_lookup(i->vendor_id, i->product_id) : NULL;
            if (!info || info->path != PAD_PATH_HIDRAW) continue;
            bool dup = false; /* one node, listed once per top-level usage */
            for (struct hid_device_info *j = list; j != i; j = j->next) dup |= j->path && !strcmp(j->path, i->path);
            if (dup) continue;
            if (n < max) {
                out[n].info = info;
                snprintf(out[n].where, sizeof out[n].where, "%s%s", i->path,
                         i->bus_type == HID_API_BUS_BLUETOOTH ? " (Bluetooth)" : "");
                wcs_ascii(i->product_string, out[n].product, sizeof out[n].product);
            }
            n++;
        }
        if (list) ops->hid_free_enumeration(list);
        ops->hid_exit();
    } else {
        wcs_ascii(ops->hid_error(NULL), hid_why, sizeof hid_why);
    }
    libusb_context *ctx = NULL;
    int rc = ops->libusb_init(&ctx);
    if (rc == 0) {
        libusb_device **list = NULL;
        ssize_t k = ops->libusb_get_device_list(ctx, &list);
        if (k >= 0) {
            usb_ok = true;
            for (ssize_t i = 0; i < k; i++) {
                struct libusb_device_descriptor dd;
                if (ops->libusb_get_device_descriptor(list[i], &dd) < 0) continue;
                const pad_device_info *info = pad_device_lookup(dd.idVendor, dd.idProduct);
                if (!info || info->path != PAD_PATH_LIBUSB) continue;
                if (n < max) {
                    char key[64];
                    out[n].info = info;
                    usb_where(ops, list[i], key, sizeof key, out[n].where, sizeof out[n].where);
                    out[n].product[0] = 0; /* its string needs the device opened */
                }
                n++;
            }
            ops->libusb_free_device_list(list, 1);
        } else {
            snprintf(usb_why, sizeof usb_why, "%s", ops->libusb_strerror((int)k));
        }
        ops->libusb_exit(ctx);
    } else {
        snprintf(usb_why, sizeof usb_why, "%s", ops->libusb_strerror(rc));
    }
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
