/*
 * pad_line.c — hid-recorder's text format (pad.h): one line in, one parsed
 * line out; one report out as an E: line. hid-tools writes
 *   E: %06d.%06d <len> %02x %02x ...      (seconds.microseconds, decimal length)
 *   I: %x %04x %04x                       (bus, vendor, product, hex)
 *   R: <len> %02x ...                     (the report descriptor)
 * and reads them back with loose patterns (hid-replay); we are strict
 * where a mistake would feed a parser wrong bytes (length against the
 * bytes, each byte two hex digits at most) and say which field is wrong.
 *
 * Pure: the line is read only within line[0..n) (no NUL needed), nothing
 * is allocated. Cost: one pass over the line, a few ns a byte; a replay of
 * a 1000 Hz recording spends microseconds a second here.
 */
#include "pad.h"
#include "protocol.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#define RDESC_MAX 4096 /* HID_MAX_DESCRIPTOR_SIZE */
#define SEC_LIMIT 1000000000ull /* times below 10^9 s keep microseconds exactly in a double */


typedef struct cursor {
    const char *p, *end;
} cursor;

static bool is_space(char c) { return c == ' ' || c == '\t'; }
static bool is_digit(char c) { return c >= '0' && c <= '9'; }
static int hex_val(char c)
{
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
}

static void skip_space(cursor *c)
{
    while (c->p < c->end && is_space(*c->p)) c->p++;
}

/* The next whitespace-separated token, [*tok, *tok + *tlen); false at the
 * end of the line. */
static bool next_token(cursor *c, const char **tok, size_t *tlen)
{
    skip_space(c);
    if (c->p >= c->end) return false;
    const char *s = c->p;
    while (c->p < c->end && !is_space(*c->p)) c->p++;
    *tok = s;
    *tlen = (size_t)(c->p - s);
    return true;
}

/* A token for a message: at most 16 bytes, bytes outside ' '..'~' as \xNN. */
static const char *show(const char *tok, size_t tlen, char out[80])
{
    size_t o = 0;
    for (size_t i = 0; i < tlen && i < 16; i++) {
        unsigned char ch = (unsigned char)tok[i];
        if (ch >= 32 && ch < 127 && ch != '\'') out[o++] = (char)ch;
        else o += (size_t)snprintf(out + o, 5, "\\x%02x", ch);
    }
    if (tlen > 16) {
        memcpy(out + o, "...", 3);
        o += 3;
    }
    out[o] = 0;
    return out;
}

/* An unsigned decimal token, <= max. */
static bool parse_dec(const char *tok, size_t tlen, uint64_t max, uint64_t *v)
{
    if (tlen == 0 || tlen > 20) return false;
    uint64_t x = 0;
    for (size_t i = 0; i < tlen; i++) {
        if (!is_digit(tok[i])) return false;
        x = x * 10 + (uint64_t)(tok[i] - '0');
        if (x > max) return false;
    }
    *v = x;
    return true;
}

/* A hex token of 1..maxdig digits. */
static bool parse_hex(const char *tok, size_t tlen, size_t maxdig, uint32_t *v)
{
    if (tlen == 0 || tlen > maxdig) return false;
    uint32_t x = 0;
    for (size_t i = 0; i < tlen; i++) {
        int h = hex_val(tok[i]);
        if (h < 0) return false;
        x = x << 4 | (uint32_t)h;
    }
    *v = x;
    return true;
}

/* Seconds as digits[.digits], rounded to the microsecond, below 10^9. */
static int parse_time(const char *tok, size_t tlen, double *t, char *err, size_t errlen)
{
    char sh[80];
    if (tlen && tok[0] == '-') return vp_errf(err, errlen, -1, "E: the time is negative: '%s'", show(tok, tlen, sh));
    size_t i = 0;
    uint64_t sec = 0;
    while (i < tlen && is_digit(tok[i])) {
        sec = sec * 10 + (uint64_t)(tok[i] - '0');
        if (sec >= SEC_LIMIT) return vp_errf(err, errlen, -1, "E: the time is too large (at most 999999999.999999 s)");
        i++;
    }
    if (i == 0) return vp_errf(err, errlen, -1, "E: the time is not a number of seconds: '%s'", show(tok, tlen, sh));
    uint32_t usec = 0;
    if (i < tlen && tok[i] == '.') {
        i++;
        size_t first = i;
        int digits = 0;
        bool round_up = false;
        while (i < tlen && is_digit(tok[i])) {
            if (digits < 6) usec = usec * 10 + (uint32_t)(tok[i] - '0');
            else if (digits == 6) round_up = tok[i] >= '5';
            digits++;
            i++;
        }
        if (i == first)
            return vp_errf(err, errlen, -1, "E: the time has no digits after '.': '%s'", show(tok, tlen, sh));
        for (; digits < 6; digits++) usec *= 10;
        if (round_up && ++usec == 1000000) {
            usec = 0;
            if (++sec >= SEC_LIMIT)
                return vp_errf(err, errlen, -1, "E: the time is too large (at most 999999999.999999 s)");
        }
    }
    if (i != tlen) return vp_errf(err, errlen, -1, "E: the time is not a number of seconds: '%s'", show(tok, tlen, sh));
    *t = (double)sec + (double)usec / 1e6;
    return 0;
}

/* "<len> <hex bytes>": into data (when not NULL) up to max bytes. */
static int parse_bytes(cursor *c, char tag, size_t max, uint8_t *data, uint16_t *lenp, char *err, size_t errlen)
{
    char sh[80];
    const char *tok;
    size_t tlen;
    uint64_t want;
    if (!next_token(c, &tok, &tlen)) return vp_errf(err, errlen, -1, "%c: the length is missing", tag);
    if (!parse_dec(tok, tlen, UINT64_MAX / 16, &want))
        return vp_errf(err, errlen, -1, "%c: the length is not a decimal number: '%s'", tag, show(tok, tlen, sh));
    if (want > max)
        return vp_errf(err, errlen, -1, "%c: the length %llu is over %zu", tag, (unsigned long long)want, max);
    if (want == 0 && tag == 'E') return vp_errf(err, errlen, -1, "E: the length is 0 (a report has at least one byte)");
    size_t got = 0;
    while (next_token(c, &tok, &tlen)) {
        uint32_t v;
        if (!parse_hex(tok, tlen, 2, &v))
            return vp_errf(err, errlen, -1, "%c: byte %zu is not a hex byte: '%s'", tag, got + 1, show(tok, tlen, sh));
        if (got == want)
            return vp_errf(err, errlen, -1, "%c: the length is %llu but more bytes follow",
                           tag, (unsigned long long)want);
        if (data) data[got] = (uint8_t)v;
        got++;
    }
    if (got != want)
        return vp_errf(err, errlen, -1, "%c: the length is %llu but %zu %s", tag, (unsigned long long)want, got,
                    got == 1 ? "byte follows" : "bytes follow");
    *lenp = (uint16_t)want;
    return 0;
}

int pad_line_parse(const char *line, size_t n, pad_line *out, char *err, size_t errlen)
{
    char sh[80];
    if (err && errlen) err[0] = 0;
    memset(out, 0, offsetof(pad_line, data));
    if (!line) n = 0;
    while (n > 0 && (line[n - 1] == '\r' || line[n - 1] == '\n')) n--;
    cursor c = {line, line + n};
    skip_space(&c);
    if (c.p == c.end || *c.p == '#') {
        out->kind = PAD_LINE_BLANK;
        return 0;
    }
    if (c.end - c.p < 2 || c.p[1] != ':' || (c.end - c.p > 2 && !is_space(c.p[2])))
        return vp_errf(err, errlen, -1, "not a hid-recorder line: no tag such as 'E:' at its start");
    char tag = c.p[0];
    c.p += 2;
    const char *tok;
    size_t tlen;
    switch (tag) {
    case 'D': {
        uint64_t v;
        if (!next_token(&c, &tok, &tlen)) return vp_errf(err, errlen, -1, "D: the device index is missing");
        if (!parse_dec(tok, tlen, UINT32_MAX, &v))
            return vp_errf(err, errlen, -1, "D: the device index is not a number below 2^32: '%s'",
                           show(tok, tlen, sh));
        if (next_token(&c, &tok, &tlen)) return vp_errf(err, errlen, -1, "D: text after the device index");
        out->kind = PAD_LINE_DEVICE;
        out->device = (uint32_t)v;
        return 0;
    }
    case 'I': {
        static const char *const what[3] = {"bus", "vendor id", "product id"};
        uint32_t v[3];
        for (int k = 0; k < 3; k++) {
            if (!next_token(&c, &tok, &tlen)) return vp_errf(err, errlen, -1, "I: the %s is missing", what[k]);
            if (!parse_hex(tok, tlen, 8, &v[k]) || v[k] > 0xFFFF)
                return vp_errf(err, errlen, -1, "I: the %s is not a 16-bit hex number: '%s'",
                               what[k], show(tok, tlen, sh));
        }
        if (next_token(&c, &tok, &tlen)) return vp_errf(err, errlen, -1, "I: text after the product id");
        out->kind = PAD_LINE_INFO;
        out->bus = (uint16_t)v[0];
        out->vid = (uint16_t)v[1];
        out->pid = (uint16_t)v[2];
        return 0;
    }
    case 'N': {
        skip_space(&c);
        size_t len = (size_t)(c.end - c.p);
        if (len > sizeof out->name - 1) len = sizeof out->name - 1;
        memcpy(out->name, c.p, len);
        out->name[len] = 0;
        out->kind = PAD_LINE_NAME;
        return 0;
    }
    case 'P':
        out->kind = PAD_LINE_OTHER;
        return 0;
    case 'R': {
        uint16_t len;
        if (parse_bytes(&c, 'R', RDESC_MAX, NULL, &len, err, errlen)) return -1;
        out->kind = PAD_LINE_OTHER;
        return 0;
    }
    case 'E': {
        double t = 0;
        if (!next_token(&c, &tok, &tlen)) return vp_errf(err, errlen, -1, "E: the time is missing");
        if (parse_time(tok, tlen, &t, err, errlen)) return -1;
        if (parse_bytes(&c, 'E', PAD_REPORT_MAX, out->data, &out->len, err, errlen)) {
            out->len = 0;
            return -1;
        }
        out->kind = PAD_LINE_EVENT;
        out->t = t;
        return 0;
    }
    default:
        return vp_errf(err, errlen, -1, "unknown line tag '%s:'", show(&tag, 1, sh));
    }
}

int pad_line_format_event(double t, const uint8_t *data, size_t len, char *buf, size_t buflen)
{
    static const char hex[] = "0123456789abcdef";
    unsigned long long sec;
    unsigned usec;
    if (!(t >= 0)) t = 0; /* negative or NaN */
    if (t >= (double)SEC_LIMIT) {
        sec = SEC_LIMIT - 1;
        usec = 999999;
    } else {
        sec = (unsigned long long)t;
        long long u = llround((t - (double)sec) * 1e6);
        if (u >= 1000000) {
            sec++;
            u -= 1000000;
        }
        usec = (unsigned)u;
        if (sec >= SEC_LIMIT) {
            sec = SEC_LIMIT - 1;
            usec = 999999;
        }
    }
    char head[64];
    int h = snprintf(head, sizeof head, "E: %06llu.%06u %zu", sec, usec, len);
    size_t total = (size_t)h + 3 * len + 1, pos = 0;
#define PUT(ch)                                 \
    do {                                        \
        if (pos + 1 < buflen) buf[pos] = (ch);  \
        pos++;                                  \
    } while (0)
    for (int i = 0; i < h; i++) PUT(head[i]);
    for (size_t i = 0; i < len; i++) {
        PUT(' ');
        PUT(hex[data[i] >> 4]);
        PUT(hex[data[i] & 15]);
    }
    PUT('\n');
#undef PUT
    if (buflen) buf[pos < buflen ? pos : buflen - 1] = 0;
    return total > (size_t)INT32_MAX ? INT32_MAX : (int)total;
}
