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
 * table calls the real libraries.
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

/* `vantage pad list`: the pads present now, without opening them. */
typedef struct pad_found {
    const pad_device_info *info;
    char where[128];         /* "/dev/hidraw3" or "usb 1-2 (bus 1, address 5)" */
    char product[128];       /* the device's own product string where it has one */
} pad_found;
/* Up to max pads into out; returns how many were found (may exceed max),
 * or -1 and err. */
int  pad_enumerate(const pad_ops *ops, pad_found *out, size_t max, char *err, size_t errlen);

/* ---- the library calls, for fakes ------------------------------------------------------ */

/*
 * (Written with the hub: the hidapi and libusb functions the hub calls,
 * as function pointers with the libraries' own signatures, plus `ctx` for
 * a fake's state. pad_ops_real() returns the table of the real ones.)
 */
const pad_ops *pad_ops_real(void);

#endif
