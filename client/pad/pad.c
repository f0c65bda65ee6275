/*
 * pad.c — the table of known pads (INPUT.md), names and error strings,
 * pad_parse's dispatch by protocol with its counts, the Xbox One power-on,
 * and a pad state as one JSON line for `vantage pad dump`. The parsers
 * themselves are in pad_parse.c, hid-recorder's lines in pad_line.c.
 *
 * Cost: the lookup is a linear scan of 14 entries (once per device found);
 * pad_parse adds a switch and three counters to the parser it calls;
 * pad_state_json is a handful of snprintf calls (a dump line, not a hot
 * path).
 */
#include "pad.h"

#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

/* ---- devices -------------------------------------------------------------------------- */

static const pad_device_info devices[] = {
    {0x054c, 0x05c4, PAD_PROTO_DS4, PAD_PATH_HIDRAW, "DualShock 4 v1", 0},
    {0x054c, 0x09cc, PAD_PROTO_DS4, PAD_PATH_HIDRAW, "DualShock 4 v2", 0},
    {0x054c, 0x0ba0, PAD_PROTO_DS4, PAD_PATH_HIDRAW, "DualShock 4 USB wireless adaptor", PAD_DEV_ADAPTOR},
    {0x054c, 0x0ce6, PAD_PROTO_DUALSENSE, PAD_PATH_HIDRAW, "DualSense", 0},
    {0x054c, 0x0df2, PAD_PROTO_DUALSENSE, PAD_PATH_HIDRAW, "DualSense Edge", 0},
    {0x057e, 0x2009, PAD_PROTO_SWITCH_PRO, PAD_PATH_HIDRAW, "Switch Pro Controller", 0},
    {0x045e, 0x028e, PAD_PROTO_XBOX360, PAD_PATH_LIBUSB, "Xbox 360 Controller", 0},
    {0x046d, 0xc21d, PAD_PROTO_XBOX360, PAD_PATH_LIBUSB, "Logitech F310", 0},
    {0x045e, 0x02d1, PAD_PROTO_XBOXONE, PAD_PATH_LIBUSB, "Xbox One Controller", 0},
    {0x045e, 0x02dd, PAD_PROTO_XBOXONE, PAD_PATH_LIBUSB, "Xbox One Controller (2015)", 0},
    {0x045e, 0x02e3, PAD_PROTO_XBOXONE, PAD_PATH_LIBUSB, "Xbox One Elite Controller", 0},
    {0x045e, 0x02ea, PAD_PROTO_XBOXONE, PAD_PATH_LIBUSB, "Xbox One S Controller", 0},
    {0x045e, 0x0b00, PAD_PROTO_XBOXONE, PAD_PATH_LIBUSB, "Xbox Elite Series 2 Controller", 0},
    {0x045e, 0x0b12, PAD_PROTO_XBOXONE, PAD_PATH_LIBUSB, "Xbox Series X|S Controller", 0},
};

const pad_device_info *pad_device_lookup(uint16_t vid, uint16_t pid)
{
    for (size_t i = 0; i < sizeof devices / sizeof devices[0]; i++)
        if (devices[i].vid == vid && devices[i].pid == pid) return &devices[i];
    return NULL;
}

const pad_device_info *pad_device_table(size_t *n)
{
    if (n) *n = sizeof devices / sizeof devices[0];
    return devices;
}

const char *pad_proto_name(pad_proto p)
{
    switch (p) {
    case PAD_PROTO_NONE: return "none";
    case PAD_PROTO_DS4: return "ds4";
    case PAD_PROTO_DUALSENSE: return "dualsense";
    case PAD_PROTO_SWITCH_PRO: return "switch-pro";
    case PAD_PROTO_XBOX360: return "xbox360";
    case PAD_PROTO_XBOXONE: return "xboxone";
    default: return "unknown";
    }
}

const char *const pad_button_names[PAD_BUTTON_COUNT] = {
    "south", "east", "west", "north", "back", "guide", "start", "lstick", "rstick", "lshoulder",
    "rshoulder", "dpad_up", "dpad_down", "dpad_left", "dpad_right", "misc", "touchpad", "ltrigger_d",
    "rtrigger_d",
};

/* ---- errors ----------------------------------------------------------------------------- */

#define PAD_RESULTS(X)                                                                        \
    X(PAD_OK_STATE, "the state changed")                                                      \
    X(PAD_OK_NONE, "no new input")                                                            \
    X(PAD_ERR_SHORT, "report shorter than its id needs")                                      \
    X(PAD_ERR_LONG, "report longer than any of this protocol")                                \
    X(PAD_ERR_REPORT_ID, "report id (or GIP command) unknown to this protocol")               \
    X(PAD_ERR_CRC, "Bluetooth report with a wrong CRC-32")                                    \
    X(PAD_ERR_PROTO, "no parser for this protocol")

const char *pad_strerror(int rc)
{
#define PAD_RESULT_CASE(code, msg) \
    case code: return msg;
    switch (rc) {
        PAD_RESULTS(PAD_RESULT_CASE)
    default: return "unknown pad result";
    }
#undef PAD_RESULT_CASE
}

/* ---- parsing ---------------------------------------------------------------------------- */

void pad_state_init(pad_state *s)
{
    memset(s, 0, sizeof *s);
    s->battery = -1;
    s->connected = true;
}

void pad_parser_init(pad_parser *p, pad_proto proto)
{
    memset(p, 0, sizeof *p);
    p->proto = proto;
    p->gip_seq = 1; /* SDL starts its GIP sequence at 1 */
}

/* GIP sequence numbers run 1..255; 0 is left out, as SDL's GIP driver
 * does. */
static uint8_t gip_next(uint8_t s) { return s == 255 ? 1 : (uint8_t)(s + 1); }

void pad_parser_start(pad_parser *p)
{
    p->out_len = 0;
    if (p->proto != PAD_PROTO_XBOXONE) return;
    /* set device state: start (0x00), system message, our sequence, one
     * byte of payload. Until the pad gets it, it sends nothing. */
    if (p->gip_seq == 0) p->gip_seq = 1;
    p->out[0] = 0x05;
    p->out[1] = 0x20;
    p->out[2] = p->gip_seq;
    p->out[3] = 0x01;
    p->out[4] = 0x00;
    p->out_len = 5;
    p->gip_seq = gip_next(p->gip_seq);
}

int pad_parse(pad_parser *p, const uint8_t *buf, size_t len, pad_state *out)
{
    int rc;
    switch (p->proto) {
    case PAD_PROTO_DS4: rc = pad_parse_ds4(p, buf, len, out); break;
    case PAD_PROTO_DUALSENSE: rc = pad_parse_dualsense(p, buf, len, out); break;
    case PAD_PROTO_SWITCH_PRO: rc = pad_parse_switch_pro(p, buf, len, out); break;
    case PAD_PROTO_XBOX360: rc = pad_parse_xbox360(p, buf, len, out); break;
    case PAD_PROTO_XBOXONE: rc = pad_parse_xboxone(p, buf, len, out); break;
    default: rc = PAD_ERR_PROTO; break;
    }
    p->reports++;
    if (rc == PAD_OK_NONE) p->ignored++;
    else if (rc < 0) p->errors++;
    return rc;
}

/* ---- JSON ------------------------------------------------------------------------------- */

/* snprintf into buf at *pos, keeping the length it would have had. */
static void jput(char *buf, size_t len, size_t *pos, const char *fmt, ...) __attribute__((format(printf, 4, 5)));
static void jput(char *buf, size_t len, size_t *pos, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    char *at = (buf && *pos < len) ? buf + *pos : NULL;
    size_t room = (buf && *pos < len) ? len - *pos : 0;
    int n = vsnprintf(at, room, fmt, ap);
    va_end(ap);
    if (n > 0) *pos += (size_t)n;
}

/* JSON has no NaN or infinity (the parsers never make one, a caller
 * might); and a -0 would print as "-0.0000" */
static double fin(double v) { return isfinite(v) && v != 0 ? v : 0.0; }

int pad_state_json(const pad_state *s, double t, char *buf, size_t len)
{
    size_t pos = 0;
    if (buf && len) buf[0] = 0;
    jput(buf, len, &pos, "{\"t\":%.6f,\"lx\":%.4f,\"ly\":%.4f,\"rx\":%.4f,\"ry\":%.4f,\"lt\":%.4f,\"rt\":%.4f,\"buttons\":[",
         fin(t), fin(s->lx), fin(s->ly), fin(s->rx), fin(s->ry), fin(s->lt), fin(s->rt));
    bool first = true;
    for (int i = 0; i < PAD_BUTTON_COUNT; i++) {
        if (!(s->buttons & (1u << i))) continue;
        jput(buf, len, &pos, "%s\"%s\"", first ? "" : ",", pad_button_names[i]);
        first = false;
    }
    jput(buf, len, &pos, "]");
    if (s->has_motion)
        jput(buf, len, &pos, ",\"gyro\":[%.4f,%.4f,%.4f],\"accel\":[%.4f,%.4f,%.4f]", fin(s->gyro[0]),
             fin(s->gyro[1]), fin(s->gyro[2]), fin(s->accel[0]), fin(s->accel[1]), fin(s->accel[2]));
    if (s->has_touch) {
        jput(buf, len, &pos, ",\"touch\":[");
        for (int k = 0; k < PAD_MAX_TOUCH; k++) {
            const pad_touch *p = &s->touch[k];
            jput(buf, len, &pos, "%s{\"id\":%u,\"down\":%s,\"x\":%.4f,\"y\":%.4f}", k ? "," : "", p->id,
                 p->down ? "true" : "false", fin(p->x), fin(p->y));
        }
        jput(buf, len, &pos, "]");
    }
    if (s->battery >= 0) jput(buf, len, &pos, ",\"battery\":%d", s->battery);
    if (!s->connected) jput(buf, len, &pos, ",\"connected\":false");
    jput(buf, len, &pos, "}");
    return pos > (size_t)INT_MAX ? INT_MAX : (int)pos;
}
