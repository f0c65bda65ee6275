/*
 * fuzz_pad.c — libFuzzer target for the game-pad report parsers
 * (pad_parse, client/pad/pad_parse.c): what a pad, a broken cable or a
 * malicious USB device can hand the reader threads.
 *
 * The input: byte 0 picks the protocol (1 + byte % 5: ds4, dualsense,
 * switch-pro, xbox360, xboxone); the rest is a sequence of reports, each a
 * length byte and that many bytes (the last one cut to what is left). One
 * parser and one state go through the whole sequence, as for a real pad.
 * Each report is copied to a heap block of exactly its length, so ASan sees
 * any read past it. Properties, after every report:
 *   1. the result is one of pad.h's (never PAD_ERR_PROTO here); a refusal
 *      (< 0) and PAD_OK_NONE leave the state bit for bit as it was, a
 *      refusal queues nothing to send; PAD_OK_STATE changes some input
 *      field (not only the counter);
 *   2. the state is in range: sticks -1..1, triggers 0..1, touch points
 *      0..1, every float finite, gyro within 45 rad/s and accel within 8 g
 *      (the largest raw values at the nominal scales), battery -1..100,
 *      no button bit past PAD_BUTTON_COUNT;
 *   3. parsing is idempotent: the same report again gives PAD_OK_NONE (or
 *      the same refusal) and the same state;
 *   4. what the parser wants sent is nothing, or for the Xbox One a 13-byte
 *      GIP acknowledgement of this report's command and sequence (the I/O
 *      layer sends it and clears out_len, as done here);
 *   5. the counts add up (reports, ignored, errors), and the state's JSON
 *      line has the length pad_state_json says, no NaN or infinity.
 * A broken property calls abort().
 */
#include "pad.h"

#define FUZZ_NAME "fuzz_pad"
#include "fuzz_check.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static bool in(float v, float lo, float hi) { return isfinite(v) && v >= lo && v <= hi; }

/* Every field but the counter, as pad.h defines "changed". */
static bool same_input(const pad_state *a, const pad_state *b)
{
    pad_state x = *a, y = *b;
    x.counter = y.counter = 0;
    if (x.lx != y.lx || x.ly != y.ly || x.rx != y.rx || x.ry != y.ry || x.lt != y.lt || x.rt != y.rt ||
        x.buttons != y.buttons || x.has_motion != y.has_motion || x.has_touch != y.has_touch ||
        x.battery != y.battery || x.connected != y.connected)
        return false;
    for (int k = 0; k < 3; k++)
        if (x.gyro[k] != y.gyro[k] || x.accel[k] != y.accel[k]) return false;
    for (int k = 0; k < PAD_MAX_TOUCH; k++)
        if (x.touch[k].down != y.touch[k].down || x.touch[k].id != y.touch[k].id || x.touch[k].x != y.touch[k].x ||
            x.touch[k].y != y.touch[k].y)
            return false;
    return true;
}

static void check_state(const pad_state *s)
{
    CHECK(in(s->lx, -1, 1) && in(s->ly, -1, 1) && in(s->rx, -1, 1) && in(s->ry, -1, 1));
    CHECK(in(s->lt, 0, 1) && in(s->rt, 0, 1));
    CHECK((s->buttons >> PAD_BUTTON_COUNT) == 0);
    for (int k = 0; k < 3; k++) {
        CHECK(in(s->gyro[k], -45, 45));
        CHECK(in(s->accel[k], -8, 8));
    }
    for (int k = 0; k < PAD_MAX_TOUCH; k++) {
        CHECK(in(s->touch[k].x, 0, 1) && in(s->touch[k].y, 0, 1));
        CHECK(s->touch[k].id < 128);
    }
    CHECK(s->battery >= -1 && s->battery <= 100);
}

/* 5: the dump line (once an input: snprintf of ~20 floats costs more than
 * the parsing) */
static void check_json(const pad_state *s)
{
    char json[1024];
    int n = pad_state_json(s, 1.0, json, sizeof json);
    CHECK(n > 0 && (size_t)n < sizeof json && strlen(json) == (size_t)n);
    CHECK(!strstr(json, "nan") && !strstr(json, "inf"));
}

/* One report through the parser, from an exact heap copy. */
static int parse_exact(pad_parser *p, const uint8_t *rep, size_t len, pad_state *st)
{
    uint8_t *copy = malloc(len ? len : 1);
    CHECK(copy != NULL);
    if (len) memcpy(copy, rep, len);
    int rc = pad_parse(p, len ? copy : NULL, len, st);
    free(copy);
    return rc;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1) return 0;
    pad_proto proto = (pad_proto)(1 + data[0] % 5);
    pad_parser p;
    pad_parser_init(&p, proto);
    pad_parser_start(&p);
    CHECK(p.out_len == (proto == PAD_PROTO_XBOXONE ? 5u : 0u));
    p.out_len = 0;
    pad_state st;
    pad_state_init(&st);
    uint32_t calls = 0, ignored = 0, errors = 0;
    size_t i = 1;
    while (i < size) {
        size_t len = data[i++];
        if (len > size - i) len = size - i;
        const uint8_t *rep = data + i;
        i += len;

        pad_state before;
        memcpy(&before, &st, sizeof st);
        int rc = parse_exact(&p, rep, len, &st);
        calls++;
        /* 1 */
        CHECK(rc == PAD_OK_STATE || rc == PAD_OK_NONE || rc == PAD_ERR_SHORT || rc == PAD_ERR_LONG ||
              rc == PAD_ERR_REPORT_ID || rc == PAD_ERR_CRC);
        if (rc <= 0) CHECK(memcmp(&before, &st, sizeof st) == 0);
        if (rc < 0) CHECK(p.out_len == 0);
        if (rc > 0) CHECK(!same_input(&before, &st));
        ignored += rc == PAD_OK_NONE;
        errors += rc < 0;
        /* 2 */
        check_state(&st);
        /* 4 */
        if (p.out_len) {
            CHECK(proto == PAD_PROTO_XBOXONE && rc >= 0);
            CHECK(p.out_len == 13 && p.out[0] == 0x01 && (p.out[1] & 0xF8) == 0x20 && p.out[3] == 0x09);
            CHECK(p.out[2] == rep[2] && p.out[5] == rep[0] && (rep[1] & 0x10));
        }
        p.out_len = 0;
        /* 3 */
        pad_state once;
        memcpy(&once, &st, sizeof st);
        int again = parse_exact(&p, rep, len, &st);
        calls++;
        CHECK(again == (rc < 0 ? rc : PAD_OK_NONE));
        CHECK(memcmp(&once, &st, sizeof st) == 0);
        ignored += again == PAD_OK_NONE;
        errors += again < 0;
        p.out_len = 0;
    }
    /* 5 */
    CHECK(p.reports == calls && p.ignored == ignored && p.errors == errors);
    check_json(&st);
    return 0;
}
