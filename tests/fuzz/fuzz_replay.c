/*
 * fuzz_replay.c — libFuzzer target for hid-recorder's text format
 * (pad_line_parse and pad_line_format_event, client/pad/pad_line.c): the files
 * `vantage pad replay` and `commander --pad-replay` read, which users send
 * in as bug reports.
 *
 * The input is a recording. It is cut into lines at '\n' as the replay
 * reader cuts it, and each line goes to pad_line_parse from a heap block of
 * exactly its length with no NUL after it, so ASan sees any read past the
 * line. As the replay does, D: lines pick the current device, I: lines its
 * parser (pad_device_lookup), and E: lines go to that parser. Properties:
 *   1. a refused line has a message (not empty, ended within err) and the
 *      result is -1; an accepted one is 0 with a known kind;
 *   2. what an accepted line holds is what pad.h promises: a NAME ended
 *      within name[]; an EVENT with 0 <= t < 10^9 and 1..PAD_REPORT_MAX
 *      bytes;
 *   3. E: round trip: the line pad_line_format_event writes for the event
 *      (ending in its one '\n', with the length it returns) parses back to
 *      the same t (exactly), length and bytes, and writing that again gives
 *      the same text; the same line with "\r" after it parses the same;
 *   4. the reports reach the parser of their device without breaking its
 *      promises: a known result, the state in range (sticks -1..1,
 *      triggers 0..1, finite numbers), a refusal leaving it as it was.
 * A broken property calls abort().
 */
#include "pad.h"

#define FUZZ_NAME "fuzz_replay"
#include "fuzz_check.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define ERR_LEN 160
#define MAX_DEVICES 4 /* D: indexes beyond fold onto these */
#define LINE_MAX_OUT (64 + 3 * PAD_REPORT_MAX)

typedef struct dev {
    bool known;
    pad_parser p;
    pad_state s;
} dev;

static bool in(float v, float lo, float hi) { return isfinite(v) && v >= lo && v <= hi; }

/* Parses line[0..len) from an exact heap copy. */
static int parse_exact(const char *line, size_t len, pad_line *l, char *err)
{
    char *copy = malloc(len ? len : 1);
    CHECK(copy != NULL);
    if (len) memcpy(copy, line, len);
    memset(err, 0x55, ERR_LEN);
    int rc = pad_line_parse(copy, len, l, err, ERR_LEN);
    free(copy);
    return rc;
}

/* 3 */
static void check_event(const pad_line *l, const char *line, size_t len)
{
    static char out[LINE_MAX_OUT], out2[LINE_MAX_OUT];
    static pad_line back, cr;
    char err[ERR_LEN];
    int n = pad_line_format_event(l->t, l->data, l->len, out, sizeof out);
    CHECK(n > 0 && (size_t)n < sizeof out && strlen(out) == (size_t)n);
    CHECK(out[n - 1] == '\n' && strchr(out, '\n') == out + n - 1);
    CHECK(parse_exact(out, (size_t)n - 1, &back, err) == 0);
    CHECK(back.kind == PAD_LINE_EVENT && back.t == l->t && back.len == l->len);
    CHECK(memcmp(back.data, l->data, l->len) == 0);
    int n2 = pad_line_format_event(back.t, back.data, back.len, out2, sizeof out2);
    CHECK(n2 == n && memcmp(out, out2, (size_t)n) == 0);
    /* a CRLF file: the same event */
    char *crl = malloc(len + 1);
    CHECK(crl != NULL);
    memcpy(crl, line, len);
    crl[len] = '\r';
    CHECK(pad_line_parse(crl, len + 1, &cr, err, sizeof err) == 0);
    free(crl);
    CHECK(cr.kind == PAD_LINE_EVENT && cr.t == l->t && cr.len == l->len && memcmp(cr.data, l->data, l->len) == 0);
}

/* 4 */
static void feed(dev *d, const pad_line *l)
{
    if (!d->known) return;
    pad_state before = d->s;
    int rc = pad_parse(&d->p, l->data, l->len, &d->s);
    CHECK(rc >= PAD_ERR_CRC && rc <= PAD_OK_STATE);
    if (rc < 0) CHECK(memcmp(&before, &d->s, sizeof before) == 0);
    d->p.out_len = 0;
    const pad_state *s = &d->s;
    CHECK(in(s->lx, -1, 1) && in(s->ly, -1, 1) && in(s->rx, -1, 1) && in(s->ry, -1, 1));
    CHECK(in(s->lt, 0, 1) && in(s->rt, 0, 1));
    for (int k = 0; k < 3; k++) CHECK(isfinite(s->gyro[k]) && isfinite(s->accel[k]));
    for (int k = 0; k < PAD_MAX_TOUCH; k++) CHECK(in(s->touch[k].x, 0, 1) && in(s->touch[k].y, 0, 1));
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static dev devs[MAX_DEVICES];
    static pad_line l;
    memset(devs, 0, sizeof devs);
    size_t cur = 0;
    const char *p = (const char *)data, *end = p + size;
    while (p < end) {
        const char *nl = memchr(p, '\n', (size_t)(end - p));
        size_t len = nl ? (size_t)(nl - p) : (size_t)(end - p);
        char err[ERR_LEN];
        int rc = parse_exact(p, len, &l, err);
        /* 1 */
        CHECK(rc == 0 || rc == -1);
        if (rc) {
            CHECK(memchr(err, 0, ERR_LEN) != NULL && err[0] != 0);
        } else {
            switch (l.kind) {
            case PAD_LINE_BLANK:
            case PAD_LINE_OTHER: break;
            case PAD_LINE_DEVICE: cur = l.device % MAX_DEVICES; break;
            case PAD_LINE_INFO: {
                const pad_device_info *info = pad_device_lookup(l.vid, l.pid);
                devs[cur].known = info != NULL;
                if (info) {
                    pad_parser_init(&devs[cur].p, info->proto);
                    pad_state_init(&devs[cur].s);
                }
                break;
            }
            case PAD_LINE_NAME:
                /* 2 */
                CHECK(memchr(l.name, 0, sizeof l.name) != NULL);
                break;
            case PAD_LINE_EVENT:
                /* 2 */
                CHECK(isfinite(l.t) && l.t >= 0 && l.t < 1e9);
                CHECK(l.len >= 1 && l.len <= PAD_REPORT_MAX);
                check_event(&l, p, len);
                feed(&devs[cur], &l);
                break;
            default: CHECK(!"unknown line kind");
            }
        }
        p += len + (nl != NULL);
    }
    return 0;
}
