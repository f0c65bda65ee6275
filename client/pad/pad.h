/*
 * pad.h — game controllers for `vantage commander` and `vantage pad`:
 * the device table, one pure parser per report protocol into one
 * normalized pad state, and hid-recorder's text format for recording and
 * replaying reports. No I/O here (pad_io.h finds and reads devices).
 *
 * Facts: docs/INPUT.md (report layouts from SDL's HIDAPI drivers, the
 * kernel's hid-sony / hid-playstation / hid-nintendo / xpad, MS-GIPUSB).
 *
 * Load: a pad sends 250..1000 reports/s; a parser costs well under 1 us a
 * report, so it is never the bottleneck (BENCHMARKS.md, "Pads").
 */
#ifndef VANTAGE_PAD_H
#define VANTAGE_PAD_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

/* ---- the normalized state ------------------------------------------------------------ */

/* Buttons by position, as SDL's game controller names them: SOUTH is
 * Cross / A (Xbox) / B (Nintendo, whose A is EAST). */
enum pad_button {
    PAD_SOUTH = 1u << 0,
    PAD_EAST = 1u << 1,
    PAD_WEST = 1u << 2,
    PAD_NORTH = 1u << 3,
    PAD_BACK = 1u << 4,      /* Share / View / Back / Minus */
    PAD_GUIDE = 1u << 5,     /* PS / Xbox / Home */
    PAD_START = 1u << 6,     /* Options / Menu / Start / Plus */
    PAD_LSTICK = 1u << 7,    /* L3 */
    PAD_RSTICK = 1u << 8,    /* R3 */
    PAD_LSHOULDER = 1u << 9, /* L1 / LB / L */
    PAD_RSHOULDER = 1u << 10,
    PAD_DPAD_UP = 1u << 11,
    PAD_DPAD_DOWN = 1u << 12,
    PAD_DPAD_LEFT = 1u << 13,
    PAD_DPAD_RIGHT = 1u << 14,
    PAD_MISC = 1u << 15,     /* Mute (DualSense) / Capture (Switch) */
    PAD_TOUCHPAD = 1u << 16, /* touchpad click */
    PAD_LTRIGGER_D = 1u << 17, /* the triggers' digital bits where the pad reports them (L2/R2, ZL/ZR) */
    PAD_RTRIGGER_D = 1u << 18,
};
#define PAD_BUTTON_COUNT 19

/* Names for JSON and config files ("south", "east", ... "rtrigger_d"),
 * indexed by bit number. */
extern const char *const pad_button_names[PAD_BUTTON_COUNT];

#define PAD_MAX_TOUCH 2

typedef struct pad_touch {
    bool down;
    uint8_t id;              /* the pad's finger id */
    float x, y;              /* 0..1 across the pad, y = 0 at the top */
} pad_touch;

typedef struct pad_state {
    float lx, ly, rx, ry;    /* sticks -1..1, +x right, +y up, no dead zone applied */
    float lt, rt;            /* triggers 0..1 (digital-only triggers: 0 or 1) */
    uint32_t buttons;        /* enum pad_button bits */
    bool has_motion;         /* gyro and accel are filled */
    float gyro[3];           /* rad/s, pad's x right, y up, z towards the player */
    float accel[3];          /* in g, same axes */
    bool has_touch;
    pad_touch touch[PAD_MAX_TOUCH];
    int8_t battery;          /* 0..100 percent, -1 unknown */
    bool connected;          /* false: a wireless adaptor with no pad behind it */
    uint32_t counter;        /* the pad's own report counter where it has one, else 0:
                                that of the last report that changed the state (it is
                                not input: a report that moves only the counter is
                                PAD_OK_NONE) */
} pad_state;

/* The state before any report: all zero, battery -1 (unknown), connected. */
void pad_state_init(pad_state *s);

/* ---- the devices ------------------------------------------------------------------- */

typedef enum pad_proto {
    PAD_PROTO_NONE = 0,
    PAD_PROTO_DS4,           /* DualShock 4 (and its USB wireless adaptor) */
    PAD_PROTO_DUALSENSE,     /* DualSense, DualSense Edge */
    PAD_PROTO_SWITCH_PRO,    /* Switch Pro (0x30 full and 0x3F simple reports) */
    PAD_PROTO_XBOX360,       /* Xbox 360 wired and XInput pads, libusb */
    PAD_PROTO_XBOXONE,       /* Xbox One / Series, GIP over USB, libusb */
    PAD_PROTO_COUNT
} pad_proto;

typedef enum pad_path { PAD_PATH_HIDRAW = 0, PAD_PATH_LIBUSB = 1 } pad_path;

typedef struct pad_device_info {
    uint16_t vid, pid;
    pad_proto proto;
    pad_path path;
    const char *name;        /* "DualShock 4 v2" */
    uint8_t flags;           /* PAD_DEV_* */
} pad_device_info;

#define PAD_DEV_ADAPTOR 0x01 /* a wireless adaptor: a pad may or may not be behind it */

/* The table of INPUT.md; NULL when vid:pid is not a known pad. */
const pad_device_info *pad_device_lookup(uint16_t vid, uint16_t pid);
/* The whole table, *n entries. */
const pad_device_info *pad_device_table(size_t *n);
const char *pad_proto_name(pad_proto p); /* "ds4", "dualsense", "switch-pro", "xbox360", "xboxone" */

/* ---- parsers ------------------------------------------------------------------------- */

/* What a parser keeps between reports of one device, and what it wants
 * sent to the device (a GIP acknowledgement, ...): the I/O layer sends
 * out[0..out_len) after pad_parse returns and then sets out_len = 0. */
typedef struct pad_parser {
    pad_proto proto;
    bool bluetooth;          /* set by the parser from what it has seen */
    uint8_t out[64];
    size_t out_len;
    uint8_t gip_seq;         /* Xbox One: our next outgoing sequence number */
    uint32_t reports, ignored, errors; /* counts, for pad dump --stats */
} pad_parser;

/* pad_parse's results: > 0 the state changed (out updated, whole);
 * 0 a valid report that carries no new input (another report id, a GIP
 * status, an unchanged state): out untouched, p->out may hold a reply;
 * < 0 refused, out untouched, nothing to send. */
enum pad_parse_result {
    PAD_OK_STATE = 1,
    PAD_OK_NONE = 0,
    PAD_ERR_SHORT = -1,      /* shorter than its report id needs */
    PAD_ERR_LONG = -2,       /* longer than any report of this protocol */
    PAD_ERR_REPORT_ID = -3,  /* a report id (or GIP command) this protocol does not have */
    PAD_ERR_CRC = -4,        /* a Bluetooth report whose CRC-32 is wrong */
    PAD_ERR_PROTO = -5,      /* no parser for this protocol */
};
const char *pad_strerror(int rc);

void pad_parser_init(pad_parser *p, pad_proto proto);
/* What to send once, after opening, before input arrives (the Xbox One
 * power-on; nothing for the others): fills p->out / p->out_len. */
void pad_parser_start(pad_parser *p);
/* One report, buf[0..len) as hidraw / the interrupt endpoint gave it
 * (report id first where the device has one); *out carries the previous
 * state in and the new one out (fields a report does not carry keep their
 * values). Pure: no I/O, no allocation, any bytes. */
int pad_parse(pad_parser *p, const uint8_t *buf, size_t len, pad_state *out);

/* The protocols' parsers, as pad_parse calls them (pad_parse adds the
 * counts). What each accepts, and the scales, are in pad_parse.c's header:
 * sticks are normalized without the pad's factory calibration (nominal
 * centre and range, clamped), motion with the nominal sensor scales. */
int pad_parse_ds4(pad_parser *p, const uint8_t *buf, size_t len, pad_state *out);
int pad_parse_dualsense(pad_parser *p, const uint8_t *buf, size_t len, pad_state *out);
int pad_parse_switch_pro(pad_parser *p, const uint8_t *buf, size_t len, pad_state *out);
int pad_parse_xbox360(pad_parser *p, const uint8_t *buf, size_t len, pad_state *out);
int pad_parse_xboxone(pad_parser *p, const uint8_t *buf, size_t len, pad_state *out);

/* One JSON object on one line (no newline) for `vantage pad dump`:
 * {"t":..,"lx":..,"ly":..,"rx":..,"ry":..,"lt":..,"rt":..,"buttons":["south",..],
 *  "gyro":[..],"accel":[..],"touch":[..],"battery":..}; fields a pad
 * does not have are left out. Returns the length it would have had
 * (snprintf's rule). */
int pad_state_json(const pad_state *s, double t, char *buf, size_t len);

/* ---- hid-recorder's text format -------------------------------------------------------- */

/*
 * hid-recorder (hid-tools) writes, per device:
 *   D: 0                     device index (files may hold several)
 *   R: 97 05 01 09 05 ...    report descriptor: length, bytes
 *   N: Sony ... Controller   name
 *   P: usb-0000:00:14.0-2/input3
 *   I: 3 054c 09cc           bus (3 USB, 5 Bluetooth), vendor, product (hex)
 *   E: 0.000000 64 01 80 7f ...   an input report: seconds, length, bytes
 * and '#' comment lines. Our --record writes the same (no R: line for
 * libusb devices) so its files replay here and in hid-replay.
 */
#define PAD_REPORT_MAX 512   /* the longest report a line may carry */

typedef enum pad_line_kind {
    PAD_LINE_BLANK = 0,      /* empty or a comment */
    PAD_LINE_DEVICE,         /* D: index */
    PAD_LINE_INFO,           /* I: bus vid pid */
    PAD_LINE_NAME,           /* N: */
    PAD_LINE_EVENT,          /* E: */
    PAD_LINE_OTHER,          /* R:, P: and other known-but-unused lines */
} pad_line_kind;

typedef struct pad_line {
    pad_line_kind kind;
    uint32_t device;         /* D: */
    uint16_t bus, vid, pid;  /* I: */
    char name[128];          /* N: (cut to fit) */
    double t;                /* E: seconds, >= 0 */
    uint16_t len;            /* E: bytes in data */
    uint8_t data[PAD_REPORT_MAX];
} pad_line;

/* One line (any bytes, line[0..n); trailing '\r's and '\n's are
 * dropped). 0 and *out filled, or -1 and err says which field is
 * wrong (the caller adds the line number). A length that disagrees with
 * the bytes, a bad hex byte, a negative or non-finite time, an unknown
 * line tag are errors. E: times are kept to the microsecond (what
 * hid-recorder writes), below 10^9 s; a report has 1..PAD_REPORT_MAX
 * bytes. */
int pad_line_parse(const char *line, size_t n, pad_line *out, char *err, size_t errlen);
/* The E: line for a report, with a newline, as hid-recorder writes it
 * ("E: 000001.250000 3 01 80 7f"); t is rounded to the microsecond (a
 * negative or NaN t is written as 0, one of 10^9 s or more as
 * 999999999.999999). Returns its length (snprintf's rule: >= buflen means
 * cut short; buf may be NULL when buflen is 0). pad_line_parse reads a
 * line of 1..PAD_REPORT_MAX bytes back to the same t, len and bytes. */
int pad_line_format_event(double t, const uint8_t *data, size_t len, char *buf, size_t buflen);

#endif
