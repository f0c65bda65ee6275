/*
 * pad_parse.c — the five report parsers behind pad_parse (pad.h): raw
 * reports as hidraw or the interrupt endpoint hand them over, to the one
 * normalized pad_state. Pure: no I/O, no allocation, no state of their own
 * besides the pad_parser; any bytes are fine (a report is read only within
 * buf[0..len), and its length is checked against its id first).
 *
 * Cost: a few dozen loads and float multiplies a report, plus a table
 * CRC-32 over 75 bytes for PlayStation Bluetooth reports; well under 1 us
 * (bench_pad measures it; the target is >= 10^6 reports/s a parser, a pad
 * sends at most 1000/s).
 *
 * What each parser accepts (report id first; other ids are
 * PAD_ERR_REPORT_ID, lengths outside the range PAD_ERR_SHORT / _LONG):
 *   ds4        0x01, 64 bytes (USB; also the USB wireless adaptor, whose
 *              byte 31 bit 2 set means no pad behind it: connected false,
 *              the rest neutral); 0x01, 10 bytes (Bluetooth before the
 *              calibration feature report is read: sticks, buttons,
 *              triggers only); 0x11, 78 bytes (Bluetooth, CRC-32 checked;
 *              byte 1 bit 7 clear: no input in it, PAD_OK_NONE).
 *   dualsense  0x01, 64 bytes (USB); 0x01, 10 bytes (Bluetooth simple
 *              mode, as SDL reads it); 0x31, 78 bytes (Bluetooth, CRC-32).
 *   switch-pro 0x30, 49..64 bytes (the full report; the IMU block when it is
 *              not all zero); 0x3F, 12..64 (the simple HID-mode report);
 *              0x21 subcommand replies, 0x23, 0x31..0x33 MCU/NFC/IR reports
 *              and 0x81 USB command acks are PAD_OK_NONE (up to 362 bytes).
 *   xbox360    message type 0x00 with length byte 0x14, 20..32 bytes; other
 *              message types (LED, rumble status, ...) are PAD_OK_NONE.
 *   xboxone    GIP: command, options, sequence, then the payload length as a
 *              LEB128 varint (MS-GIPUSB; one byte below 128, at most two
 *              here: 16383 bytes) and the payload, 4..64 bytes in all. Input
 *              0x20 (payload >= 14 bytes), guide 0x07 (payload >= 1, bit 0);
 *              other commands and fragments (options bit 7) are
 *              PAD_OK_NONE. A message with options bit 4 (acknowledge me)
 *              that parsed is acknowledged through p->out, as SDL's GIP
 *              driver does (the guide's 0x30 message is the one xpad and
 *              SDL's older driver ack; the pad repeats it until it is).
 *
 * Scales, without the pads' factory calibration (we read none):
 *   8-bit sticks (PlayStation): centre 0x80, (v - 128) / 127, clamped;
 *   their Y is +down on the wire and flipped here. 8-bit triggers v / 255.
 *   16-bit sticks (Xbox): v / 32767, clamped; +Y up on the wire. Xbox One
 *   triggers are 10-bit: v / 1023, clamped.
 *   Switch full report: 12-bit sticks, +Y up, hid-nintendo's fallback
 *   calibration (centre 2000, 500..3500: +-1500) since SDL's (centre 2048,
 *   range grown from ~1000 as the stick moves) needs state we do not keep.
 *   Switch simple report: 16-bit, centre 0x8000, +Y down, SDL's starting
 *   range of +-16384 (the stick does not reach the ends of the 16 bits).
 *   PlayStation motion: gyro 16 LSB per deg/s and accel 8192 LSB per g
 *   (SDL's defaults for DS4 without calibration; its DualSense path without
 *   calibration is the same 1/16 deg/s), axes as the pad reports them,
 *   which are SDL's and ours (x right, y up, z towards the player).
 *   Switch motion: accel 4096 LSB per g, gyro 14.2842 LSB per deg/s (SDL's
 *   defaults), axes turned to the PlayStation ones as SDL does:
 *   (x, y, z) = (-raw y, raw z, -raw x); the newest of the three samples.
 *   Touch: DS4 1920 x 942, DualSense 1920 x 1080 points, to 0..1.
 *   Battery: PlayStation level*10+5 capped at 100 (hid-playstation), full
 *   100, error states -1; Switch level 0..4 to 0..100 in quarters; the Xbox
 *   pads here are wired: -1.
 */
#include "pad.h"

#include <string.h>

/* ---- shared pieces -------------------------------------------------------------------- */

#define DEG2RAD 0.017453292519943295f
#define PS_GYRO_SCALE (DEG2RAD / 16.0f)   /* rad/s per LSB */
#define PS_ACCEL_SCALE (1.0f / 8192.0f)   /* g per LSB */
#define SW_GYRO_SCALE (DEG2RAD / 14.2842f)
#define SW_ACCEL_SCALE (1.0f / 4096.0f)
#define SW_STICK_CENTRE 2000
#define SW_STICK_RANGE 1500.0f
#define SW_SIMPLE_RANGE 16384.0f

static inline uint16_t le16(const uint8_t *b) { return (uint16_t)(b[0] | b[1] << 8); }
static inline int16_t les16(const uint8_t *b) { return (int16_t)le16(b); }

static inline float clamp1(float v) { return v < -1.0f ? -1.0f : v > 1.0f ? 1.0f : v; }
static inline float clamp01(float v) { return v < 0.0f ? 0.0f : v > 1.0f ? 1.0f : v; }

/* 0x00 .. 0xFF, centre 0x80; _inv for an axis whose + is the other way
 * (written as 128 - v, not -(v - 128): the centre is +0, not -0) */
static inline float axis_u8(uint8_t v) { return clamp1((float)((int)v - 128) * (1.0f / 127.0f)); }
static inline float axis_u8_inv(uint8_t v) { return clamp1((float)(128 - (int)v) * (1.0f / 127.0f)); }
static inline float axis_s16(int16_t v) { return clamp1((float)v * (1.0f / 32767.0f)); }

/* Hat 0 = N, clockwise to 7 = NW; 8..15 none. */
static const uint32_t hat_bits[16] = {
    PAD_DPAD_UP,
    PAD_DPAD_UP | PAD_DPAD_RIGHT,
    PAD_DPAD_RIGHT,
    PAD_DPAD_DOWN | PAD_DPAD_RIGHT,
    PAD_DPAD_DOWN,
    PAD_DPAD_DOWN | PAD_DPAD_LEFT,
    PAD_DPAD_LEFT,
    PAD_DPAD_UP | PAD_DPAD_LEFT,
};

/* Everything but counter: the input the caller acts on. */
static bool same_input(const pad_state *a, const pad_state *b)
{
    if (a->lx != b->lx || a->ly != b->ly || a->rx != b->rx || a->ry != b->ry || a->lt != b->lt ||
        a->rt != b->rt || a->buttons != b->buttons || a->has_motion != b->has_motion ||
        a->has_touch != b->has_touch || a->battery != b->battery || a->connected != b->connected)
        return false;
    for (int k = 0; k < 3; k++)
        if (a->gyro[k] != b->gyro[k] || a->accel[k] != b->accel[k]) return false;
    for (int k = 0; k < PAD_MAX_TOUCH; k++) {
        const pad_touch *s = &a->touch[k], *t = &b->touch[k];
        if (s->down != t->down || s->id != t->id || s->x != t->x || s->y != t->y) return false;
    }
    return true;
}

/* The new state n in, unless it is the old one again. */
static int finish(pad_state *out, const pad_state *n)
{
    if (same_input(out, n)) return PAD_OK_NONE;
    *out = *n;
    return PAD_OK_STATE;
}

/* CRC-32 (IEEE 802.3, reflected, as zlib's crc32), table-driven. */
static const uint32_t crc_table[256] = {
    0x00000000, 0x77073096, 0xee0e612c, 0x990951ba, 0x076dc419, 0x706af48f,
    0xe963a535, 0x9e6495a3, 0x0edb8832, 0x79dcb8a4, 0xe0d5e91e, 0x97d2d988,
    0x09b64c2b, 0x7eb17cbd, 0xe7b82d07, 0x90bf1d91, 0x1db71064, 0x6ab020f2,
    0xf3b97148, 0x84be41de, 0x1adad47d, 0x6ddde4eb, 0xf4d4b551, 0x83d385c7,
    0x136c9856, 0x646ba8c0, 0xfd62f97a, 0x8a65c9ec, 0x14015c4f, 0x63066cd9,
    0xfa0f3d63, 0x8d080df5, 0x3b6e20c8, 0x4c69105e, 0xd56041e4, 0xa2677172,
    0x3c03e4d1, 0x4b04d447, 0xd20d85fd, 0xa50ab56b, 0x35b5a8fa, 0x42b2986c,
    0xdbbbc9d6, 0xacbcf940, 0x32d86ce3, 0x45df5c75, 0xdcd60dcf, 0xabd13d59,
    0x26d930ac, 0x51de003a, 0xc8d75180, 0xbfd06116, 0x21b4f4b5, 0x56b3c423,
    0xcfba9599, 0xb8bda50f, 0x2802b89e, 0x5f058808, 0xc60cd9b2, 0xb10be924,
    0x2f6f7c87, 0x58684c11, 0xc1611dab, 0xb6662d3d, 0x76dc4190, 0x01db7106,
    0x98d220bc, 0xefd5102a, 0x71b18589, 0x06b6b51f, 0x9fbfe4a5, 0xe8b8d433,
    0x7807c9a2, 0x0f00f934, 0x9609a88e, 0xe10e9818, 0x7f6a0dbb, 0x086d3d2d,
    0x91646c97, 0xe6635c01, 0x6b6b51f4, 0x1c6c6162, 0x856530d8, 0xf262004e,
    0x6c0695ed, 0x1b01a57b, 0x8208f4c1, 0xf50fc457, 0x65b0d9c6, 0x12b7e950,
    0x8bbeb8ea, 0xfcb9887c, 0x62dd1ddf, 0x15da2d49, 0x8cd37cf3, 0xfbd44c65,
    0x4db26158, 0x3ab551ce, 0xa3bc0074, 0xd4bb30e2, 0x4adfa541, 0x3dd895d7,
    0xa4d1c46d, 0xd3d6f4fb, 0x4369e96a, 0x346ed9fc, 0xad678846, 0xda60b8d0,
    0x44042d73, 0x33031de5, 0xaa0a4c5f, 0xdd0d7cc9, 0x5005713c, 0x270241aa,
    0xbe0b1010, 0xc90c2086, 0x5768b525, 0x206f85b3, 0xb966d409, 0xce61e49f,
    0x5edef90e, 0x29d9c998, 0xb0d09822, 0xc7d7a8b4, 0x59b33d17, 0x2eb40d81,
    0xb7bd5c3b, 0xc0ba6cad, 0xedb88320, 0x9abfb3b6, 0x03b6e20c, 0x74b1d29a,
    0xead54739, 0x9dd277af, 0x04db2615, 0x73dc1683, 0xe3630b12, 0x94643b84,
    0x0d6d6a3e, 0x7a6a5aa8, 0xe40ecf0b, 0x9309ff9d, 0x0a00ae27, 0x7d079eb1,
    0xf00f9344, 0x8708a3d2, 0x1e01f268, 0x6906c2fe, 0xf762575d, 0x806567cb,
    0x196c3671, 0x6e6b06e7, 0xfed41b76, 0x89d32be0, 0x10da7a5a, 0x67dd4acc,
    0xf9b9df6f, 0x8ebeeff9, 0x17b7be43, 0x60b08ed5, 0xd6d6a3e8, 0xa1d1937e,
    0x38d8c2c4, 0x4fdff252, 0xd1bb67f1, 0xa6bc5767, 0x3fb506dd, 0x48b2364b,
    0xd80d2bda, 0xaf0a1b4c, 0x36034af6, 0x41047a60, 0xdf60efc3, 0xa867df55,
    0x316e8eef, 0x4669be79, 0xcb61b38c, 0xbc66831a, 0x256fd2a0, 0x5268e236,
    0xcc0c7795, 0xbb0b4703, 0x220216b9, 0x5505262f, 0xc5ba3bbe, 0xb2bd0b28,
    0x2bb45a92, 0x5cb36a04, 0xc2d7ffa7, 0xb5d0cf31, 0x2cd99e8b, 0x5bdeae1d,
    0x9b64c2b0, 0xec63f226, 0x756aa39c, 0x026d930a, 0x9c0906a9, 0xeb0e363f,
    0x72076785, 0x05005713, 0x95bf4a82, 0xe2b87a14, 0x7bb12bae, 0x0cb61b38,
    0x92d28e9b, 0xe5d5be0d, 0x7cdcefb7, 0x0bdbdf21, 0x86d3d2d4, 0xf1d4e242,
    0x68ddb3f8, 0x1fda836e, 0x81be16cd, 0xf6b9265b, 0x6fb077e1, 0x18b74777,
    0x88085ae6, 0xff0f6a70, 0x66063bca, 0x11010b5c, 0x8f659eff, 0xf862ae69,
    0x616bffd3, 0x166ccf45, 0xa00ae278, 0xd70dd2ee, 0x4e048354, 0x3903b3c2,
    0xa7672661, 0xd06016f7, 0x4969474d, 0x3e6e77db, 0xaed16a4a, 0xd9d65adc,
    0x40df0b66, 0x37d83bf0, 0xa9bcae53, 0xdebb9ec5, 0x47b2cf7f, 0x30b5ffe9,
    0xbdbdf21c, 0xcabac28a, 0x53b39330, 0x24b4a3a6, 0xbad03605, 0xcdd70693,
    0x54de5729, 0x23d967bf, 0xb3667a2e, 0xc4614ab8, 0x5d681b02, 0x2a6f2b94,
    0xb40bbe37, 0xc30c8ea1, 0x5a05df1b, 0x2d02ef8d,
};

/* PlayStation Bluetooth input reports: CRC-32 over the HID transaction
 * header 0xA1 and bytes 0..len-5, stored little-endian in the last four. */
static bool ps_crc_ok(const uint8_t *b, size_t len)
{
    uint32_t c = ~0u;
    c = crc_table[(c ^ 0xA1u) & 0xFF] ^ (c >> 8);
    for (size_t i = 0; i + 4 < len; i++) c = crc_table[(c ^ b[i]) & 0xFF] ^ (c >> 8);
    c = ~c;
    uint32_t got = (uint32_t)b[len - 4] | (uint32_t)b[len - 3] << 8 | (uint32_t)b[len - 2] << 16 |
                   (uint32_t)b[len - 1] << 24;
    return c == got;
}

/* ---- PlayStation ---------------------------------------------------------------------- */

/* Byte 5 of a DS4 report (8 of a DualSense): hat and face buttons. */
static uint32_t ps_face(uint8_t v)
{
    uint32_t b = hat_bits[v & 0x0F];
    if (v & 0x10) b |= PAD_WEST;  /* Square */
    if (v & 0x20) b |= PAD_SOUTH; /* Cross */
    if (v & 0x40) b |= PAD_EAST;  /* Circle */
    if (v & 0x80) b |= PAD_NORTH; /* Triangle */
    return b;
}

/* Byte 6 (9): L1 R1 L2 R2 Share/Create Options L3 R3. */
static uint32_t ps_shoulders(uint8_t v)
{
    uint32_t b = 0;
    if (v & 0x01) b |= PAD_LSHOULDER;
    if (v & 0x02) b |= PAD_RSHOULDER;
    if (v & 0x04) b |= PAD_LTRIGGER_D;
    if (v & 0x08) b |= PAD_RTRIGGER_D;
    if (v & 0x10) b |= PAD_BACK;
    if (v & 0x20) b |= PAD_START;
    if (v & 0x40) b |= PAD_LSTICK;
    if (v & 0x80) b |= PAD_RSTICK;
    return b;
}

/* Analog trigger; a pad that sends only the digital bit (some fight sticks,
 * SDL's note) reads as fully pressed. */
static float ps_trigger(uint8_t v, bool digital)
{
    return (v == 0 && digital) ? 1.0f : (float)v * (1.0f / 255.0f);
}

static void ps_sticks(pad_state *n, const uint8_t *s)
{
    n->lx = axis_u8(s[0]);
    n->ly = axis_u8_inv(s[1]);
    n->rx = axis_u8(s[2]);
    n->ry = axis_u8_inv(s[3]);
}

static void ps_motion(pad_state *n, const uint8_t *gyro, const uint8_t *accel)
{
    n->has_motion = true;
    for (int k = 0; k < 3; k++) {
        n->gyro[k] = (float)les16(gyro + 2 * k) * PS_GYRO_SCALE;
        n->accel[k] = (float)les16(accel + 2 * k) * PS_ACCEL_SCALE;
    }
}

/* A touch point: contact byte (bit 7 set = not touching, low 7 bits the
 * finger id), then 12-bit X and Y packed in three bytes. */
static void ps_touch(pad_touch *t, const uint8_t *p, float xmax, float ymax)
{
    t->down = !(p[0] & 0x80);
    t->id = p[0] & 0x7F;
    unsigned x = p[1] | (unsigned)(p[2] & 0x0F) << 8;
    unsigned y = (unsigned)(p[2] >> 4) | (unsigned)p[3] << 4;
    t->x = clamp01((float)x / xmax);
    t->y = clamp01((float)y / ymax);
}

/* hid-playstation's reading of the status nibbles. */
static int8_t ds4_battery(uint8_t v)
{
    unsigned level = v & 0x0F;
    if (!(v & 0x10)) return (int8_t)(level < 10 ? level * 10 + 5 : 100); /* on battery */
    if (level < 10) return (int8_t)(level * 10 + 5);                       /* charging */
    if (level <= 11) return 100;                                           /* 10, 11 full */
    return -1;                                                             /* 14, 15: errors */
}

static int8_t ds_battery(uint8_t v)
{
    unsigned level = v & 0x0F, status = v >> 4;
    unsigned pct = level * 10 + 5;
    switch (status) {
    case 0x0: /* discharging */
    case 0x1: /* charging */
        return (int8_t)(pct > 100 ? 100 : pct);
    case 0x2: return 100; /* full */
    default: return -1;   /* 0xa/0xb out of range, 0xf charge error */
    }
}

/* The 10-byte report both pads send over Bluetooth in simple mode: sticks,
 * hat+face, shoulders, PS/pad + 6-bit counter, triggers (DS4's USB layout,
 * bytes 1..9). */
static void ps_simple(pad_state *n, const uint8_t *s)
{
    ps_sticks(n, s);
    n->buttons = ps_face(s[4]) | ps_shoulders(s[5]);
    if (s[6] & 0x01) n->buttons |= PAD_GUIDE;
    if (s[6] & 0x02) n->buttons |= PAD_TOUCHPAD;
    n->lt = ps_trigger(s[7], s[5] & 0x04);
    n->rt = ps_trigger(s[8], s[5] & 0x08);
    n->counter = s[6] >> 2;
    n->connected = true;
}

/* DS4 state from s = the byte after the report id (USB) or after the two
 * Bluetooth header bytes; s[0..61] are readable. */
static void ds4_full(pad_state *n, const uint8_t *s)
{
    ps_simple(n, s);
    ps_motion(n, s + 12, s + 18);
    n->battery = ds4_battery(s[29]);
    /* up to three touch reports of 9 bytes (a timestamp, two points); the
     * last one is the newest. None: the points keep their values. */
    n->has_touch = true;
    unsigned reports = s[32] > 3 ? 3 : s[32];
    if (reports) {
        const uint8_t *r = s + 33 + 9 * (reports - 1);
        ps_touch(&n->touch[0], r + 1, 1919.0f, 941.0f);
        ps_touch(&n->touch[1], r + 5, 1919.0f, 941.0f);
    }
}

/* How a PlayStation pad's reports differ: the Bluetooth full report's id
 * and where its state bytes start, and the DS4's two special cases. */
typedef struct ps_layout {
    uint8_t bt_id;            /* 0x11 DS4, 0x31 DualSense (78 bytes, CRC-32) */
    uint8_t bt_state;         /* the state's first byte in it */
    bool bt_data_flag;        /* DS4: byte 1 bit 7 clear means no input in it */
    bool usb_adaptor;         /* DS4: USB byte 31 bit 2, the wireless adaptor with no pad */
    void (*full)(pad_state *n, const uint8_t *s);
} ps_layout;

/* 0x01 of 10 bytes (Bluetooth before the full reports: sticks, buttons,
 * triggers), 0x01 of 64 (USB), the Bluetooth full report (78). */
static int ps_parse(pad_parser *p, const uint8_t *buf, size_t len, pad_state *out, const ps_layout *L)
{
    if (len == 0) return PAD_ERR_SHORT;
    pad_state n = *out;
    if (buf[0] == 0x01) {
        if (len == 10) {
            ps_simple(&n, buf + 1);
            p->bluetooth = true;
            return finish(out, &n);
        }
        if (len < 64) return PAD_ERR_SHORT;
        if (len > 64) return PAD_ERR_LONG;
        if (L->usb_adaptor && (buf[31] & 0x04)) {
            /* the USB wireless adaptor with no pad paired: the rest of the
             * report is whatever the adaptor holds; report a neutral pad */
            pad_state_init(&n);
            n.connected = false;
            n.counter = out->counter;
            return finish(out, &n);
        }
        L->full(&n, buf + 1);
        return finish(out, &n);
    }
    if (buf[0] != L->bt_id) return PAD_ERR_REPORT_ID;
    if (len < 78) return PAD_ERR_SHORT;
    if (len > 78) return PAD_ERR_LONG;
    if (!ps_crc_ok(buf, len)) return PAD_ERR_CRC;
    p->bluetooth = true;
    if (L->bt_data_flag && !(buf[1] & 0x80)) return PAD_OK_NONE; /* no HID data in this one */
    L->full(&n, buf + L->bt_state);
    return finish(out, &n);
}

int pad_parse_ds4(pad_parser *p, const uint8_t *buf, size_t len, pad_state *out)
{
    static const ps_layout ds4 = {.bt_id = 0x11, .bt_state = 3, .bt_data_flag = true, .usb_adaptor = true,
                                  .full = ds4_full};
    return ps_parse(p, buf, len, out, &ds4);
}

/* DualSense state from s = the byte after the report id (USB) or after
 * the Bluetooth sequence byte; s[0..62] are readable. */
static void ds_full(pad_state *n, const uint8_t *s)
{
    ps_sticks(n, s);
    n->buttons = ps_face(s[7]) | ps_shoulders(s[8]);
    if (s[9] & 0x01) n->buttons |= PAD_GUIDE;
    if (s[9] & 0x02) n->buttons |= PAD_TOUCHPAD;
    if (s[9] & 0x04) n->buttons |= PAD_MISC; /* mute */
    n->lt = ps_trigger(s[4], s[8] & 0x04);
    n->rt = ps_trigger(s[5], s[8] & 0x08);
    n->counter = s[6];
    ps_motion(n, s + 15, s + 21);
    n->has_touch = true;
    ps_touch(&n->touch[0], s + 32, 1919.0f, 1079.0f);
    ps_touch(&n->touch[1], s + 36, 1919.0f, 1079.0f);
    n->battery = ds_battery(s[52]);
    n->connected = true;
}

int pad_parse_dualsense(pad_parser *p, const uint8_t *buf, size_t len, pad_state *out)
{
    static const ps_layout ds = {.bt_id = 0x31, .bt_state = 2, .full = ds_full};
    return ps_parse(p, buf, len, out, &ds);
}

/* ---- Switch Pro ----------------------------------------------------------------------- */

static float sw_axis12(unsigned v) { return clamp1((float)((int)v - SW_STICK_CENTRE) * (1.0f / SW_STICK_RANGE)); }
static float sw_axis16(uint16_t v) { return clamp1((float)((int)v - 0x8000) * (1.0f / SW_SIMPLE_RANGE)); }
static float sw_axis16_inv(uint16_t v) { return clamp1((float)(0x8000 - (int)v) * (1.0f / SW_SIMPLE_RANGE)); }

/* 0x30: 1 timer, 2 battery/connection, 3..5 buttons, 6..8 and 9..11 the
 * sticks (two 12-bit values each), 12 vibrator, 13..48 three IMU samples
 * (accel x y z, gyro x y z, s16), newest first. */
static void sw_full(pad_state *n, const uint8_t *b)
{
    uint32_t bt = 0;
    uint8_t r = b[3], m = b[4], l = b[5];
    if (r & 0x01) bt |= PAD_WEST;  /* Y */
    if (r & 0x02) bt |= PAD_NORTH; /* X */
    if (r & 0x04) bt |= PAD_SOUTH; /* B */
    if (r & 0x08) bt |= PAD_EAST;  /* A */
    if (r & 0x40) bt |= PAD_RSHOULDER;
    if (r & 0x80) bt |= PAD_RTRIGGER_D;
    if (m & 0x01) bt |= PAD_BACK;  /* - */
    if (m & 0x02) bt |= PAD_START; /* + */
    if (m & 0x04) bt |= PAD_RSTICK;
    if (m & 0x08) bt |= PAD_LSTICK;
    if (m & 0x10) bt |= PAD_GUIDE; /* Home */
    if (m & 0x20) bt |= PAD_MISC;  /* Capture */
    if (l & 0x01) bt |= PAD_DPAD_DOWN;
    if (l & 0x02) bt |= PAD_DPAD_UP;
    if (l & 0x04) bt |= PAD_DPAD_RIGHT;
    if (l & 0x08) bt |= PAD_DPAD_LEFT;
    if (l & 0x40) bt |= PAD_LSHOULDER;
    if (l & 0x80) bt |= PAD_LTRIGGER_D;
    n->buttons = bt;
    n->lt = (l & 0x80) ? 1.0f : 0.0f;
    n->rt = (r & 0x80) ? 1.0f : 0.0f;
    n->lx = sw_axis12(b[6] | (unsigned)(b[7] & 0x0F) << 8);
    n->ly = sw_axis12((unsigned)(b[7] >> 4) | (unsigned)b[8] << 4);
    n->rx = sw_axis12(b[9] | (unsigned)(b[10] & 0x0F) << 8);
    n->ry = sw_axis12((unsigned)(b[10] >> 4) | (unsigned)b[11] << 4);
    unsigned level = b[2] >> 5; /* 0 empty .. 4 full */
    n->battery = (int8_t)(level >= 4 ? 100 : level * 25);
    n->counter = b[1];
    n->connected = true;
    /* the IMU block is zero until the host enables it (subcommand 0x40);
     * a pad that reports gravity never sends all zeros */
    bool imu = false;
    for (int i = 13; i < 49; i++) imu |= b[i] != 0;
    if (imu) {
        const uint8_t *a = b + 13, *g = b + 19;
        n->has_motion = true;
        n->accel[0] = -(float)les16(a + 2) * SW_ACCEL_SCALE;
        n->accel[1] = (float)les16(a + 4) * SW_ACCEL_SCALE;
        n->accel[2] = -(float)les16(a + 0) * SW_ACCEL_SCALE;
        n->gyro[0] = -(float)les16(g + 2) * SW_GYRO_SCALE;
        n->gyro[1] = (float)les16(g + 4) * SW_GYRO_SCALE;
        n->gyro[2] = -(float)les16(g + 0) * SW_GYRO_SCALE;
    }
}

/* 0x3F: 1 B A Y X L R ZL ZR, 2 - + LS RS Home Capture, 3 hat, 4..11 sticks
 * u16 LE (X, Y, X, Y; +Y down). */
static void sw_simple(pad_state *n, const uint8_t *b)
{
    uint32_t bt = hat_bits[b[3] & 0x0F];
    uint8_t f = b[1], m = b[2];
    if (f & 0x01) bt |= PAD_SOUTH; /* B */
    if (f & 0x02) bt |= PAD_EAST;  /* A */
    if (f & 0x04) bt |= PAD_WEST;  /* Y */
    if (f & 0x08) bt |= PAD_NORTH; /* X */
    if (f & 0x10) bt |= PAD_LSHOULDER;
    if (f & 0x20) bt |= PAD_RSHOULDER;
    if (f & 0x40) bt |= PAD_LTRIGGER_D;
    if (f & 0x80) bt |= PAD_RTRIGGER_D;
    if (m & 0x01) bt |= PAD_BACK;
    if (m & 0x02) bt |= PAD_START;
    if (m & 0x04) bt |= PAD_LSTICK;
    if (m & 0x08) bt |= PAD_RSTICK;
    if (m & 0x10) bt |= PAD_GUIDE;
    if (m & 0x20) bt |= PAD_MISC;
    n->buttons = bt;
    n->lt = (f & 0x40) ? 1.0f : 0.0f;
    n->rt = (f & 0x80) ? 1.0f : 0.0f;
    n->lx = sw_axis16(le16(b + 4));
    n->ly = sw_axis16_inv(le16(b + 6));
    n->rx = sw_axis16(le16(b + 8));
    n->ry = sw_axis16_inv(le16(b + 10));
    n->connected = true;
}

int pad_parse_switch_pro(pad_parser *p, const uint8_t *buf, size_t len, pad_state *out)
{
    (void)p;
    if (len == 0) return PAD_ERR_SHORT;
    pad_state n = *out;
    switch (buf[0]) {
    case 0x30:
        if (len < 49) return PAD_ERR_SHORT;
        if (len > 64) return PAD_ERR_LONG;
        sw_full(&n, buf);
        return finish(out, &n);
    case 0x3F:
        if (len < 12) return PAD_ERR_SHORT;
        if (len > 64) return PAD_ERR_LONG;
        sw_simple(&n, buf);
        return finish(out, &n);
    case 0x21: /* subcommand reply */
    case 0x23: /* MCU update state */
    case 0x31: /* full report + NFC/IR data (362 bytes) */
    case 0x32:
    case 0x33:
    case 0x81: /* USB command ack */
        return len > 362 ? PAD_ERR_LONG : PAD_OK_NONE;
    default:
        return PAD_ERR_REPORT_ID;
    }
}

/* ---- Xbox 360 ------------------------------------------------------------------------- */

/* The wired pad's interrupt IN endpoint has wMaxPacketSize 32. */
#define X360_MAX 32

int pad_parse_xbox360(pad_parser *p, const uint8_t *buf, size_t len, pad_state *out)
{
    (void)p;
    if (len == 0) return PAD_ERR_SHORT;
    if (len > X360_MAX) return PAD_ERR_LONG;
    if (buf[0] != 0x00) return PAD_OK_NONE; /* LED state, rumble status, attach */
    if (len < 20 || buf[1] < 20 || buf[1] > len) return PAD_ERR_SHORT;
    pad_state n = *out;
    uint32_t bt = 0;
    uint8_t a = buf[2], c = buf[3];
    if (a & 0x01) bt |= PAD_DPAD_UP;
    if (a & 0x02) bt |= PAD_DPAD_DOWN;
    if (a & 0x04) bt |= PAD_DPAD_LEFT;
    if (a & 0x08) bt |= PAD_DPAD_RIGHT;
    if (a & 0x10) bt |= PAD_START;
    if (a & 0x20) bt |= PAD_BACK;
    if (a & 0x40) bt |= PAD_LSTICK;
    if (a & 0x80) bt |= PAD_RSTICK;
    if (c & 0x01) bt |= PAD_LSHOULDER;
    if (c & 0x02) bt |= PAD_RSHOULDER;
    if (c & 0x04) bt |= PAD_GUIDE;
    if (c & 0x10) bt |= PAD_SOUTH; /* A */
    if (c & 0x20) bt |= PAD_EAST;  /* B */
    if (c & 0x40) bt |= PAD_WEST;  /* X */
    if (c & 0x80) bt |= PAD_NORTH; /* Y */
    n.buttons = bt;
    n.lt = (float)buf[4] * (1.0f / 255.0f);
    n.rt = (float)buf[5] * (1.0f / 255.0f);
    n.lx = axis_s16(les16(buf + 6));
    n.ly = axis_s16(les16(buf + 8));
    n.rx = axis_s16(les16(buf + 10));
    n.ry = axis_s16(les16(buf + 12));
    n.battery = -1;
    n.connected = true;
    return finish(out, &n);
}

/* ---- Xbox One (GIP) ------------------------------------------------------------------- */

#define GIP_MAX 64             /* a GIP message over USB fits one 64-byte packet */
#define GIP_OPT_FRAGMENT 0x80
#define GIP_OPT_SYSTEM 0x20
#define GIP_OPT_ACK 0x10

/* The protocol-control acknowledgement of a whole (unfragmented) message:
 * 01 20 <its sequence> 09 | 00 <its command> <its system bit> <its length
 * as 32-bit LE> <bytes remaining, 16-bit: 0>. For the guide message that is
 * xpad's and SDL's 01 20 ss 09 00 07 20 02 00 00 00 00 00. */
static void gip_ack(pad_parser *p, uint8_t cmd, uint8_t opt, uint8_t seq, uint32_t length)
{
    uint8_t *o = p->out;
    o[0] = 0x01;
    o[1] = (uint8_t)(GIP_OPT_SYSTEM | (opt & 0x07));
    o[2] = seq;
    o[3] = 0x09;
    o[4] = 0x00;
    o[5] = cmd;
    o[6] = opt & GIP_OPT_SYSTEM;
    o[7] = (uint8_t)length;
    o[8] = (uint8_t)(length >> 8);
    o[9] = (uint8_t)(length >> 16);
    o[10] = (uint8_t)(length >> 24);
    o[11] = 0x00;
    o[12] = 0x00;
    p->out_len = 13;
}

int pad_parse_xboxone(pad_parser *p, const uint8_t *buf, size_t len, pad_state *out)
{
    if (len < 4) return PAD_ERR_SHORT;
    if (len > GIP_MAX) return PAD_ERR_LONG;
    uint8_t cmd = buf[0], opt = buf[1], seq = buf[2];
    /* the payload length, LEB128: 7 bits a byte, bit 7 = more */
    uint32_t length = buf[3] & 0x7F;
    size_t hdr = 4;
    if (buf[3] & 0x80) {
        if (len < 5) return PAD_ERR_SHORT;
        if (buf[4] & 0x80) return PAD_ERR_LONG; /* > 16383 bytes: no message is that long */
        length |= (uint32_t)buf[4] << 7;
        hdr = 5;
    }
    if (opt & GIP_OPT_FRAGMENT) return PAD_OK_NONE; /* metadata and the like: not input */
    if (length > len - hdr) return PAD_ERR_SHORT;
    const uint8_t *pl = buf + hdr;
    pad_state n = *out;
    int rc = PAD_OK_NONE;
    switch (cmd) {
    case 0x20: {
        if (length < 14) return PAD_ERR_SHORT;
        uint32_t bt = out->buttons & PAD_GUIDE; /* the guide comes in its own message */
        uint8_t a = pl[0], c = pl[1];
        if (a & 0x04) bt |= PAD_START; /* Menu */
        if (a & 0x08) bt |= PAD_BACK;  /* View */
        if (a & 0x10) bt |= PAD_SOUTH; /* A */
        if (a & 0x20) bt |= PAD_EAST;  /* B */
        if (a & 0x40) bt |= PAD_WEST;  /* X */
        if (a & 0x80) bt |= PAD_NORTH; /* Y */
        if (c & 0x01) bt |= PAD_DPAD_UP;
        if (c & 0x02) bt |= PAD_DPAD_DOWN;
        if (c & 0x04) bt |= PAD_DPAD_LEFT;
        if (c & 0x08) bt |= PAD_DPAD_RIGHT;
        if (c & 0x10) bt |= PAD_LSHOULDER;
        if (c & 0x20) bt |= PAD_RSHOULDER;
        if (c & 0x40) bt |= PAD_LSTICK;
        if (c & 0x80) bt |= PAD_RSTICK;
        n.buttons = bt;
        n.lt = clamp01((float)le16(pl + 2) * (1.0f / 1023.0f));
        n.rt = clamp01((float)le16(pl + 4) * (1.0f / 1023.0f));
        n.lx = axis_s16(les16(pl + 6));
        n.ly = axis_s16(les16(pl + 8));
        n.rx = axis_s16(les16(pl + 10));
        n.ry = axis_s16(les16(pl + 12));
        n.battery = -1;
        n.connected = true;
        n.counter = seq;
        rc = finish(out, &n);
        break;
    }
    case 0x07:
        if (!(opt & GIP_OPT_SYSTEM)) break; /* a vendor message of that number */
        if (length < 1) return PAD_ERR_SHORT;
        n.buttons = (pl[0] & 0x01) ? (n.buttons | PAD_GUIDE) : (n.buttons & ~(uint32_t)PAD_GUIDE);
        n.connected = true;
        n.counter = seq;
        rc = finish(out, &n);
        break;
    default:
        break; /* announce, status, metadata, security, acks: not input */
    }
    if (opt & GIP_OPT_ACK) gip_ack(p, cmd, opt, seq, length);
    return rc;
}
