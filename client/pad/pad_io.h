/*
 * pad_io.h — finding, opening and reading pads: hidapi (hidraw) for the
 * PlayStation and Switch pads, libusb for the Xbox pads (vendor-class
 * interfaces), hotplug (libusb's callbacks for USB, re-enumeration for
 * hidraw), a replay backend reading hid-recorder files, and --record.
 *
 * A pad_hub owns every pad it finds; its reader threads parse reports
 * (pad.h) and queue events; the caller's loop polls pad_hub_fd() beside
 * its socket and drains pad_hub_next(). Every hidapi and libusb call goes
 * through a pad_ops table so tests can put a fake behind the hub; the real
 * table calls the real libraries. Implemented by pad_hub.c and one file
 * per backend (pad_io_internal.h lists them).
 */
#ifndef VANTAGE_PAD_IO_H
#define VANTAGE_PAD_IO_H

#include "pad.h"

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

typedef struct pad_hub pad_hub;
typedef struct pad_ops pad_ops;   /* defined below the hub API */

typedef enum pad_event_kind {
    PAD_EV_ADDED = 1,        /* a pad was found and opened */
    PAD_EV_REMOVED,          /* unplugged (or its reads failed): msg says why */
    PAD_EV_STATE,            /* a report changed the pad's state */
    PAD_EV_ERROR,            /* a report was refused, a device could not be opened, ... (msg); the hub goes on */
    PAD_EV_END,              /* replay: the file is done (not with replay_loop) */
} pad_event_kind;

typedef struct pad_event {
    pad_event_kind kind;
    uint32_t pad;            /* the hub's id of the pad: 1, 2, ...; a pad plugged back gets a new id */
    const pad_device_info *info; /* NULL for PAD_EV_ERROR not tied to a pad, and PAD_EV_END */
    pad_state state;         /* PAD_EV_STATE: the whole new state */
    double t_report;         /* CLOCK_MONOTONIC seconds when the report was read (replay: delivered) */
    double t_file;           /* replay: the report's time in the file; live: seconds since the pad was opened */
    char msg[200];           /* ADDED: "DualShock 4 v2, hidraw /dev/hidraw3"; REMOVED / ERROR: why */
} pad_event;

typedef struct pad_hub_opts {
    const pad_ops *ops;      /* NULL = the real hidapi and libusb */
    const char *replay;      /* a hid-recorder file instead of devices (no library is touched) */
    double replay_speed;     /* 1 (0 means 1) = the file's timing; < 0 = as fast as the reader takes them */
    bool replay_loop;        /* start the file again at its end */
    const char *record;      /* also write every report of live pads to this file (hid-recorder format) */
    int rescan_ms;           /* hidraw re-enumeration period; 0 = 1000 */
} pad_hub_opts;

/* Opens the backends and starts finding pads (the ones present now come as
 * PAD_EV_ADDED events). 0, or -1 and err (a replay file that cannot be
 * opened or whose first bad line is named; libusb that will not
 * initialise is not an error: hidraw pads still work, and an ERROR event
 * says so). */
int  pad_hub_open(const pad_hub_opts *o, pad_hub **out, char *err, size_t errlen);
/* Stops the threads, closes every device. NULL is fine. */
void pad_hub_close(pad_hub *h);
/* Readable when events are waiting (an eventfd or pipe). */
int  pad_hub_fd(const pad_hub *h);
/* The next event: 1 and *ev filled, 0 none waiting. Events of one pad
 * come in order; STATE events of a pad the caller is slow to drain are
 * merged (the newest state wins, t_report is the newest report's). */
int  pad_hub_next(pad_hub *h, pad_event *ev);

/* A pad's counts so far, for `pad dump --stats`. */
typedef struct pad_counts {
    uint64_t reports;        /* reports read (replay: delivered) */
    uint64_t ignored;        /* valid but changed nothing (PAD_OK_NONE) */
    uint64_t errors;         /* refused by the parser, or failed reads */
    uint64_t states;         /* STATE events made, before merging */
    uint64_t merged;         /* of those, merged into an unread one (the caller was slower than the pad) */
} pad_counts;
/* 0 and *out filled, or -1 when the hub has no such pad (never had, or
 * unplugged and gone: its REMOVED message carries its last counts). Any
 * thread; takes the hub's lock for a moment. */
int  pad_hub_counts(pad_hub *h, uint32_t pad, pad_counts *out);

/* `vantage pad list`: the pads present now, without opening them. */
typedef struct pad_found {
    const pad_device_info *info;
    char where[128];         /* "/dev/hidraw3" or "usb 1-2 (bus 1, address 5)" */
    char product[128];       /* the device's own product string where it has one */
} pad_found;
/* Up to max pads into out; returns how many were found (may exceed max),
 * or -1 and err (neither library would start). When only one of them
 * would, the count stands and err says which is missing ("" otherwise). */
int  pad_enumerate(const pad_ops *ops, pad_found *out, size_t max, char *err, size_t errlen);

/* ---- the library calls, for fakes ------------------------------------------------------ */

/*
 * The hidapi and libusb functions the hub and pad_enumerate call, each a
 * pointer with the library's own signature, so a test can put a fake
 * device behind every one of them (the fake completes the libraries'
 * opaque structs, struct hid_device_ and struct libusb_device, with its
 * own). The libraries' headers come in here, by their Debian paths, because
 * the hotplug callback's type names libusb's anonymous event enum; a file
 * that includes pad_io.h needs no extra -I for them. Costs nothing at run
 * time beyond an indirect call per library call (a few per report).
 *
 * The hub calls every pointer listed (none may be NULL); ctx is the fake's
 * own state, never touched by the hub (the real table leaves it NULL).
 * Threads: a pad's reader thread reads, writes (acks) and, when the pad
 * is unplugged, closes it (hid_read_timeout, hid_write, hid_error(dev),
 * hid_close; libusb_interrupt_transfer, libusb_strerror,
 * libusb_release_interface, libusb_close); everything else runs in the
 * hub's thread or in pad_hub_open / pad_hub_close / pad_enumerate. The
 * hotplug callback may run in any thread that handles libusb events (the
 * hub only queues from it). A fake must be as thread-safe as the
 * libraries are.
 */
#include <hidapi/hidapi.h>
#include <libusb-1.0/libusb.h>

struct pad_ops {
    void *ctx;

    /* hidapi (hidraw): PlayStation and Switch pads */
    int (*hid_init)(void);
    int (*hid_exit)(void);
    struct hid_device_info *(*hid_enumerate)(unsigned short vendor_id, unsigned short product_id);
    void (*hid_free_enumeration)(struct hid_device_info *devs);
    hid_device *(*hid_open_path)(const char *path);
    int (*hid_read_timeout)(hid_device *dev, unsigned char *data, size_t length, int milliseconds);
    int (*hid_write)(hid_device *dev, const unsigned char *data, size_t length);
    void (*hid_close)(hid_device *dev);
    const wchar_t *(*hid_error)(hid_device *dev); /* NULL: the last open's error */

    /* libusb: the Xbox pads' vendor-class interfaces */
    int (*libusb_init)(libusb_context **ctx);
    void (*libusb_exit)(libusb_context *ctx);
    int (*libusb_has_capability)(uint32_t capability);
    const char *(*libusb_strerror)(int errcode);
    ssize_t (*libusb_get_device_list)(libusb_context *ctx, libusb_device ***list);
    void (*libusb_free_device_list)(libusb_device **list, int unref_devices);
    libusb_device *(*libusb_ref_device)(libusb_device *dev);
    void (*libusb_unref_device)(libusb_device *dev);
    int (*libusb_get_device_descriptor)(libusb_device *dev, struct libusb_device_descriptor *desc);
    int (*libusb_get_active_config_descriptor)(libusb_device *dev, struct libusb_config_descriptor **config);
    void (*libusb_free_config_descriptor)(struct libusb_config_descriptor *config);
    uint8_t (*libusb_get_bus_number)(libusb_device *dev);
    uint8_t (*libusb_get_device_address)(libusb_device *dev);
    int (*libusb_get_port_numbers)(libusb_device *dev, uint8_t *port_numbers, int port_numbers_len);
    int (*libusb_open)(libusb_device *dev, libusb_device_handle **dev_handle);
    void (*libusb_close)(libusb_device_handle *dev_handle);
    int (*libusb_set_auto_detach_kernel_driver)(libusb_device_handle *dev_handle, int enable);
    int (*libusb_claim_interface)(libusb_device_handle *dev_handle, int interface_number);
    int (*libusb_release_interface)(libusb_device_handle *dev_handle, int interface_number);
    int (*libusb_interrupt_transfer)(libusb_device_handle *dev_handle, unsigned char endpoint, unsigned char *data,
                                     int length, int *actual_length, unsigned int timeout);
    int (*libusb_hotplug_register_callback)(libusb_context *ctx, int events, int flags, int vendor_id,
                                            int product_id, int dev_class, libusb_hotplug_callback_fn cb_fn,
                                            void *user_data, libusb_hotplug_callback_handle *callback_handle);
    void (*libusb_hotplug_deregister_callback)(libusb_context *ctx, libusb_hotplug_callback_handle callback_handle);
    int (*libusb_handle_events_timeout_completed)(libusb_context *ctx, struct timeval *tv, int *completed);
};

/* The table of the real libraries (static, never NULL). */
const pad_ops *pad_ops_real(void);

#endif
