/*
 * pad_io_internal.h — what the files of the pad hub share, private to
 * client/pad: the hub's and a pad's structs, the event queue and report
 * path every backend feeds (pad_hub.c), and each backend's entry points.
 *
 *   pad_hub.c     the hub: open / close, the event queue, the report path,
 *                 what it remembers of devices between scans, the hub
 *                 thread, pad_enumerate
 *   pad_hidraw.c  hidapi (hidraw flavour): PlayStation and Switch pads
 *   pad_libusb.c  libusb: the Xbox pads' vendor-class interfaces, hotplug
 *   pad_replay.c  a hid-recorder file delivered at its timing
 *   pad_record.c  --record: what live pads send, in the same format
 *
 * Threads, locks and load are described once, in pad_hub.c's header.
 */
#ifndef VANTAGE_PAD_IO_INTERNAL_H
#define VANTAGE_PAD_IO_INTERNAL_H

#include "pad_io.h"

#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <time.h>

#define READ_MS 100           /* a reader's read timeout: how long close waits for it */
#define TICK_MS 100           /* the hub thread's wake-up: reaping, hotplug events */
#define RETRY_MAX_S 30.0      /* the longest wait before opening a failing device again */
#define FLAP_S 2.0            /* a pad removed sooner than this after opening counts as a flap */
#define PARSE_ERR_BURST 5.0   /* ERROR events a pad may send at once, then 1 a second */
#define QUEUE_SOFT_CAP 1024   /* queued events past which ERRORs are dropped and STATEs always merge */
#define USB_ERR_MAX 10        /* consecutive failed USB reads that count as removal */

typedef enum pad_backend { BK_HID, BK_USB, BK_REPLAY } pad_backend;

typedef struct pad_dev pad_dev;
struct pad_dev {
    pad_hub *h;
    pad_dev *next;            /* the hub's list, under h->mu */
    uint32_t id;
    const pad_device_info *info;
    pad_backend bk;
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
typedef struct pad_seen {
    char key[160];
    pad_backend bk;
    bool present;             /* in the last scan */
    bool reported;            /* its open failure was said once */
    unsigned fails;
    double retry_at;
} pad_seen;

typedef struct pad_usb_note { /* a hotplug callback's news, for the hub thread */
    libusb_device *dev;       /* referenced */
    bool arrived;
} pad_usb_note;

typedef struct pad_replay_dev {
    uint32_t index;           /* D: */
    uint16_t bus, vid, pid;
    bool have_info;
    const pad_device_info *info;
    char name[128];
    pad_dev *pad;             /* once its first report is delivered */
    bool anchored;
    double offset, t_last;    /* its times on the replay's clock: t + offset */
} pad_replay_dev;

struct pad_hub {
    const pad_ops *ops;
    int rescan_ms;
    atomic_bool stop;

    pthread_mutex_t mu;       /* pads (written by the hub thread, read by pad_hub_counts), the wake-up cond */
    pthread_cond_t wake;
    pad_dev *pads;
    pad_seen *seen;           /* the hub thread's alone */
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

    /* the hub's one thread: the hub thread that finds live pads, or the
       replay thread (a replay touches no library) */
    pthread_t thread;
    bool thread_started;

    /* live backends */
    bool hid_ok;
    libusb_context *usb;
    bool hotplug;
    libusb_hotplug_callback_handle hp;
    pthread_mutex_t pmu;      /* notes from the hotplug callback */
    pad_usb_note *notes;
    size_t nnotes, capnotes;
    bool usb_list_failed;

    /* replay */
    char *replay;
    FILE *rf;
    double speed;             /* > 0 scale, < 0 as fast as drained */
    bool loop;
    pad_replay_dev *rdev;
    size_t nrdev;

    /* record */
    pthread_mutex_t rmu;
    FILE *rec;
    char *rec_path;
    int rec_next, rec_last;   /* the next D: index, the last one written */
    bool rec_failed;
};

/* ---- pad_hub.c: time, text, the queue, the report path --------------------------------- */

double pad_mono_now(void);                 /* CLOCK_MONOTONIC seconds */
struct timespec pad_mono_at(double t);     /* for pthread_cond_timedwait on a CLOCK_MONOTONIC cond */
/* hidapi's wide strings as printable ASCII ('?' for the rest): the
 * messages and the record file's N: line need no locale. */
void pad_wcs_ascii(const wchar_t *w, char *out, size_t cap);

/* Queues ev (d: the pad it is about, or NULL); push_msg builds the event
 * (d's id, info, state and times) around a formatted msg. Any thread. */
void pad_push(pad_hub *h, pad_dev *d, const pad_event *ev);
void pad_push_msg(pad_hub *h, pad_dev *d, pad_event_kind kind, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));

/* A pad of the hub's, not yet started (calloc'd, parser and state set, an
 * id taken), or NULL (out of memory). */
pad_dev *pad_dev_new(pad_hub *h, const pad_device_info *info, pad_backend bk, const char *key, const char *where);
/* The parser's start packet sent, recorded, ADDED queued, its reader
 * started; on failure the device is closed and the pad freed. */
void pad_dev_start(pad_hub *h, pad_dev *d, const char *how);
/* One report from the device (or the file): recorded, parsed, its output
 * sent, a STATE queued when the state changed. */
void pad_dev_report(pad_dev *d, const uint8_t *buf, size_t len, double t_report, double t_file);
/* The reader's end: the device closed, REMOVED queued with why. */
void pad_dev_removed(pad_dev *d, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
/* A pad's error messages through its token bucket: true when this one may
 * be said (more: how many were not since the last that was). */
bool pad_dev_err_allowed(pad_dev *d, double now, char *more, size_t morelen);

/* The hub thread's memory of devices: found or made (NULL: out of memory);
 * every entry of a backend marked absent before a scan; those still absent
 * (and held by no pad) forgotten after it (takes h->mu). */
pad_seen *pad_seen_get(pad_hub *h, pad_backend bk, const char *key);
void pad_seen_absent(pad_hub *h, pad_backend bk, const char *key); /* key NULL: all of bk */
void pad_seen_prune(pad_hub *h, pad_backend bk);
/* The open pad of that backend and key, or NULL; under h->mu. */
pad_dev *pad_by_key(pad_hub *h, pad_backend bk, const char *key);
/* An open that failed: said once while the device stays, tried again
 * after a growing wait; one that worked clears that. */
void pad_open_failed(pad_hub *h, pad_seen *s, const pad_device_info *info, const char *where, const char *why,
                     const char *hint);
void pad_open_worked(pad_seen *s);

/* ---- pad_hidraw.c ------------------------------------------------------------------------- */

void pad_hid_init(pad_hub *h);              /* hid_ok, or an ERROR event saying why not */
void pad_hid_scan(pad_hub *h);              /* the hub thread: open the pads not open yet */
void *pad_hid_reader(void *arg);            /* a pad's reader thread */
void pad_hid_send(pad_dev *d, size_t n);    /* the parser's output to the device */
void pad_hid_close(pad_dev *d);
/* pad_enumerate's hidraw half: pads appended to out from *n (counting past
 * max), false and why when hidapi would not start. */
bool pad_hid_list(const pad_ops *ops, pad_found *out, size_t max, size_t *n, char *why, size_t whylen);

/* ---- pad_libusb.c ------------------------------------------------------------------------- */

void pad_usb_init(pad_hub *h);              /* h->usb and hotplug, or an ERROR event saying why not */
void pad_usb_scan(pad_hub *h);
void pad_usb_notes(pad_hub *h);             /* the hotplug callback's news, in the hub thread */
void *pad_usb_reader(void *arg);
void pad_usb_send(pad_dev *d, size_t n);
void pad_usb_close(pad_dev *d);
void pad_usb_exit(pad_hub *h);              /* hotplug deregistered, notes dropped, libusb closed */
bool pad_usb_list(const pad_ops *ops, pad_found *out, size_t max, size_t *n, char *why, size_t whylen);

/* ---- pad_replay.c ------------------------------------------------------------------------- */

/* The whole file checked (a bad line named in err), the devices noted. */
int pad_replay_load(pad_hub *h, char *err, size_t errlen);
void *pad_replay_main(void *arg);           /* the replay thread */

/* ---- pad_record.c ------------------------------------------------------------------------- */

/* Creates the record file and writes its comment line; 0, or -1 and err. */
int pad_rec_open(pad_hub *h, const char *path, char *err, size_t errlen);
void pad_rec_pad(pad_hub *h, pad_dev *d);   /* a new pad's D:/N:/P:/I: header */
void pad_rec_report(pad_hub *h, pad_dev *d, const uint8_t *buf, size_t len, double t);

#endif
