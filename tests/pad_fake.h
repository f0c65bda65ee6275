/*
 * pad_fake.h — a fake hidapi and libusb for the pad hub's tests
 * (tests/test_pad_io.c): a pad_ops table (fake_ops) whose devices live in
 * this fake, so the hub's discovery, hotplug, reads, writes and cleanup
 * run without hardware.
 *
 * The fake completes the libraries' opaque structs (struct hid_device_,
 * struct libusb_device, ...) with its own, keeps every report it is given
 * in a per-device queue that its blocking reads pop (with the caller's
 * timeout, as the real reads), logs what is written to each device, counts
 * libusb references, and delivers hotplug news from inside
 * libusb_handle_events_timeout_completed, as libusb does. It models the
 * libraries, not the hub: it knows nothing of pad_hub's internals, and
 * every fact the tests check about the hub (states, events, messages)
 * they check against their own reference model (pad_parse run directly),
 * never against the fake. What only real hardware shows: the kernel's
 * timing of unplug errors, the real pads' report contents
 * (tests/test_pad.c has captured layouts), xpad detaching, udev
 * permissions.
 *
 * Threads: every entry point that reads or changes a device's queue,
 * handles or references takes fake.mu (the rest read fields set before
 * the hub opens); a test that reads the fake's fields takes it too.
 */
#ifndef VANTAGE_PAD_FAKE_H
#define VANTAGE_PAD_FAKE_H

#include "pad_io.h"

#include <pthread.h>
#include <stdbool.h>
#include <stdint.h>
#include <wchar.h>

#define FAKE_DEVS 8
#define FAKE_QUEUE 512
#define FAKE_OUTS 64

typedef struct fake_pkt {
    uint8_t b[64];
    int n;
} fake_pkt;

typedef struct fake_dev fake_dev;

struct hid_device_ { fake_dev *d; };
struct libusb_device { fake_dev *d; };
struct libusb_device_handle { fake_dev *d; };
struct libusb_context { int unused; };

struct fake_dev {
    bool used, usb, present;
    char path[32];
    uint16_t vid, pid;
    bool bluetooth;
    bool fail_open;           /* hid_open_path / libusb_open fail (permission) */
    bool silent_leave;        /* usb: unplugged, reads time out instead of NO_DEVICE (only hotplug says it) */
    bool needs_poweron;       /* GIP: nothing is read before 05 20 .. is written */
    bool powered;
    uint8_t cls[3];           /* usb: the interface's class, subclass, protocol */
    uint8_t addr, port;
    int opens, is_open, refs;
    bool detach, claimed;     /* auto-detach asked before the claim */
    bool claim_before_detach;
    fake_pkt q[FAKE_QUEUE];
    int qh, qt;
    long consumed;            /* reports the hub has read */
    long reads;               /* read calls */
    long reads_before_write;  /* read calls before the first write */
    fake_pkt out[FAKE_OUTS];
    int nout;
    struct libusb_device ud;
};

typedef struct fake_note {
    fake_dev *d;
    bool arrived;
} fake_note;

struct fake {
    pthread_mutex_t mu;
    pthread_cond_t cv;
    fake_dev dev[FAKE_DEVS];
    bool hotplug;             /* LIBUSB_CAP_HAS_HOTPLUG */
    libusb_hotplug_callback_fn cb;
    void *cb_user;
    bool registered;
    bool usb_init_fails;      /* libusb_init refuses (no usbfs, say) */
    fake_note notes[32];
    int nnotes;
    int hid_inits, usb_inits; /* init minus exit */
    int handles;              /* hid and usb handles open */
    int lists, cfgs;          /* enumerations, device lists and config descriptors not freed */
    struct libusb_context ctx;
};

/* The fake's one state (tests run one at a time). */
extern struct fake fake;
/* The table that puts the fake behind a hub (pad_hub_opts.ops) or pad_enumerate. */
extern const pad_ops fake_ops;

/* Empties the fake: no devices, nothing open, libusb with hotplug or not. */
void fake_reset(bool hotplug);
/* A hidraw device present now (DualShock 4, DualSense, Switch Pro ids). */
fake_dev *fake_hid(uint16_t vid, uint16_t pid);
/* An Xbox 360 (0xFF/0x5D/0x01) or GIP (0xFF/0x47/0xD0) interface, present now. */
fake_dev *fake_usb(uint16_t vid, uint16_t pid, bool gip);
/* Queues a report for the device's reads (n <= 64). */
void fake_push(fake_dev *d, const uint8_t *b, int n);
/* Unplugged (reads fail, or time out with silent_leave; hotplug news
 * queued) and plugged back (a fresh device: unpowered, no writes logged). */
void fake_unplug(fake_dev *d);
void fake_plug(fake_dev *d);
/* Reports the hub has read so far. */
long fake_consumed(fake_dev *d);
/* After pad_hub_close: every handle closed, every reference, list and
 * descriptor given back, both libraries exited. */
void fake_assert_clean(void);

#endif
