/*
 * bench_pad.c — reports per second of each pad parser (a benchmark: it
 * fails on nothing).
 *
 *   bench_pad [--json] [--quick] [--smoke] [--reports N] [--runs R]
 *
 * For each protocol and transport, 4096 varied reports with the real
 * layout (sticks, triggers, buttons, hat, motion and touch where the pad
 * has them, Bluetooth reports with their CRC-32) are parsed in turn into
 * one state, as a pad's reader thread does: N reports a run (10^6), R runs
 * (7), the median run reported as reports/s and ns a report. A pad sends at
 * most 1000 reports/s; the target is >= 10^6/s a parser (a report costs
 * under 1 us), so parsing is never what limits the input path.
 *
 * --quick: 2*10^5 reports, 3 runs; --smoke: 10^4, 1 run (make test).
 * --json: one object a row, {parser, report_bytes, reports, runs,
 * median_reports_per_s, median_ns}.
 */
#include "bench_util.h"
#include "pad.h"

#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define VARIANTS 4096
#define MAXLEN 80

static uint8_t rnd8(void) { return (uint8_t)(bench_frand() * 256); }
static int rnd16(void) { return (int)(bench_frand() * 65536) - 32768; }

static void put16(uint8_t *b, int v)
{
    b[0] = (uint8_t)(v & 0xFF);
    b[1] = (uint8_t)((v >> 8) & 0xFF);
}

/* The PlayStation Bluetooth CRC-32 (0xA1, then the report), bit by bit:
 * only for making the reports. */
static void ps_crc(uint8_t *b, size_t len)
{
    uint32_t c = ~0u;
    for (size_t i = 0; i < len - 3; i++) {
        c ^= i == 0 ? 0xA1u : b[i - 1];
        for (int k = 0; k < 8; k++) c = (c & 1) ? (c >> 1) ^ 0xEDB88320u : c >> 1;
    }
    c = ~c;
    for (int k = 0; k < 4; k++) b[len - 4 + k] = (uint8_t)(c >> (8 * k));
}

/* A DS4 report's state bytes from s (USB byte 1 = s[0]): sticks, hat and
 * face, buttons, counter, triggers, motion, battery, one touch report. */
static void ds4_state(uint8_t *s, unsigned i)
{
    for (int k = 0; k < 4; k++) s[k] = rnd8();
    s[4] = (uint8_t)((i % 9) | (rnd8() & 0xF0));
    s[5] = rnd8();
    s[6] = (uint8_t)(((i & 63) << 2) | (rnd8() & 3));
    s[7] = rnd8();
    s[8] = rnd8();
    for (int k = 0; k < 6; k++) put16(s + 12 + 2 * k, rnd16() / 8);
    s[29] = (uint8_t)(rnd8() % 12);
    s[32] = 1;
    s[34] = rnd8();
    s[35] = rnd8();
    s[36] = rnd8();
    s[37] = rnd8();
    s[38] = 0x80;
}

/* A PlayStation report over USB: 64 bytes, id 0x01, the state after it. */
static size_t ps_usb(uint8_t *b, unsigned i, void (*state)(uint8_t *, unsigned))
{
    memset(b, 0, 64);
    b[0] = 0x01;
    state(b + 1, i);
    return 64;
}

/* Over Bluetooth: 78 bytes, the report id and its second byte, the state
 * at offset at, a CRC-32 at the end. */
static size_t ps_bt(uint8_t *b, unsigned i, uint8_t id, uint8_t b1, size_t at, void (*state)(uint8_t *, unsigned))
{
    memset(b, 0, 78);
    b[0] = id;
    b[1] = b1;
    state(b + at, i);
    ps_crc(b, 78);
    return 78;
}

static size_t make_ds4_usb(uint8_t *b, unsigned i) { return ps_usb(b, i, ds4_state); }
static size_t make_ds4_bt(uint8_t *b, unsigned i) { return ps_bt(b, i, 0x11, 0xC0, 3, ds4_state); }

static void ds_state(uint8_t *s, unsigned i)
{
    for (int k = 0; k < 6; k++) s[k] = rnd8();
    s[6] = (uint8_t)i;
    s[7] = (uint8_t)((i % 9) | (rnd8() & 0xF0));
    s[8] = rnd8();
    s[9] = rnd8() & 0x07;
    for (int k = 0; k < 6; k++) put16(s + 15 + 2 * k, rnd16() / 8);
    for (int k = 32; k < 40; k++) s[k] = rnd8();
    s[52] = (uint8_t)(rnd8() % 11);
}

static size_t make_ds_usb(uint8_t *b, unsigned i) { return ps_usb(b, i, ds_state); }
static size_t make_ds_bt(uint8_t *b, unsigned i) { return ps_bt(b, i, 0x31, (uint8_t)(i << 4), 2, ds_state); }

static size_t make_switch_full(uint8_t *b, unsigned i)
{
    memset(b, 0, 64);
    b[0] = 0x30;
    b[1] = (uint8_t)i;
    b[2] = 0x8E;
    b[3] = rnd8();
    b[4] = rnd8() & 0x3F;
    b[5] = rnd8();
    for (int k = 6; k < 12; k++) b[k] = rnd8();
    b[12] = 0x80;
    for (int k = 0; k < 18; k++) put16(b + 13 + 2 * k, rnd16() / 8);
    return 64;
}

static size_t make_switch_simple(uint8_t *b, unsigned i)
{
    memset(b, 0, 12);
    b[0] = 0x3F;
    b[1] = rnd8();
    b[2] = rnd8() & 0x3F;
    b[3] = (uint8_t)(i % 9);
    for (int k = 0; k < 4; k++) put16(b + 4 + 2 * k, rnd16() + 32768);
    return 12;
}

static size_t make_xbox360(uint8_t *b, unsigned i)
{
    (void)i;
    memset(b, 0, 20);
    b[0] = 0x00;
    b[1] = 0x14;
    b[2] = rnd8();
    b[3] = rnd8() & 0xF7;
    b[4] = rnd8();
    b[5] = rnd8();
    for (int k = 0; k < 4; k++) put16(b + 6 + 2 * k, rnd16());
    return 20;
}

static size_t make_xboxone(uint8_t *b, unsigned i)
{
    memset(b, 0, 18);
    b[0] = 0x20;
    b[1] = 0x00;
    b[2] = (uint8_t)i;
    b[3] = 0x0E;
    b[4] = rnd8() & 0xFC;
    b[5] = rnd8();
    put16(b + 6, (int)(bench_frand() * 1024));
    put16(b + 8, (int)(bench_frand() * 1024));
    for (int k = 0; k < 4; k++) put16(b + 10 + 2 * k, rnd16());
    return 18;
}

typedef struct row {
    const char *name;
    pad_proto proto;
    size_t (*make)(uint8_t *b, unsigned i);
} row;

static const row rows[] = {
    {"ds4 usb", PAD_PROTO_DS4, make_ds4_usb},
    {"ds4 bluetooth (crc)", PAD_PROTO_DS4, make_ds4_bt},
    {"dualsense usb", PAD_PROTO_DUALSENSE, make_ds_usb},
    {"dualsense bluetooth (crc)", PAD_PROTO_DUALSENSE, make_ds_bt},
    {"switch-pro full 0x30", PAD_PROTO_SWITCH_PRO, make_switch_full},
    {"switch-pro simple 0x3f", PAD_PROTO_SWITCH_PRO, make_switch_simple},
    {"xbox360", PAD_PROTO_XBOX360, make_xbox360},
    {"xboxone gip input", PAD_PROTO_XBOXONE, make_xboxone},
};

static uint8_t reports[VARIANTS][MAXLEN];
static size_t lens[VARIANTS];

int main(int argc, char **argv)
{
    bool json = false;
    long n = 1000000, runs = 7;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--json")) json = true;
        else if (!strcmp(argv[i], "--quick")) n = 200000, runs = 3;
        else if (!strcmp(argv[i], "--smoke")) n = 10000, runs = 1;
        else if (!strcmp(argv[i], "--reports") && i + 1 < argc) n = atol(argv[++i]);
        else if (!strcmp(argv[i], "--runs") && i + 1 < argc) runs = atol(argv[++i]);
        else {
            fprintf(stderr, "usage: bench_pad [--json] [--quick] [--smoke] [--reports N] [--runs R]\n");
            return 2;
        }
    }
    if (n < 1) n = 1;
    if (runs < 1) runs = 1;
    if (runs > 99) runs = 99;
    if (!json) {
        printf("pad parsers: %ld reports a run (4096 variants in turn), median of %ld run%s\n", n, runs,
               runs == 1 ? "" : "s");
        printf("%-28s %6s %14s %9s %8s %8s\n", "parser", "bytes", "reports/s", "ns/report", "changed", "target");
    }
    int bad = 0;
    for (size_t r = 0; r < sizeof rows / sizeof rows[0]; r++) {
        const row *w = &rows[r];
        for (unsigned i = 0; i < VARIANTS; i++) lens[i] = w->make(reports[i], i);
        double rate[99];
        long changed = 0;
        for (long run = 0; run < runs; run++) {
            pad_parser p;
            pad_parser_init(&p, w->proto);
            pad_state st;
            pad_state_init(&st);
            long ch = 0;
            double t0 = bench_now_ns();
            for (long k = 0; k < n; k++) {
                unsigned v = (unsigned)k & (VARIANTS - 1);
                int rc = pad_parse(&p, reports[v], lens[v], &st);
                ch += rc > 0;
                bad |= rc < 0;
            }
            double dt = bench_now_ns() - t0;
            rate[run] = n / (dt * 1e-9);
            changed = ch;
        }
        qsort(rate, (size_t)runs, sizeof rate[0], bench_cmp_d);
        double med = rate[runs / 2];
        if (json)
            printf("{\"parser\":\"%s\",\"report_bytes\":%zu,\"reports\":%ld,\"runs\":%ld,"
                   "\"median_reports_per_s\":%.0f,\"median_ns\":%.1f}\n",
                   w->name, lens[0], n, runs, med, 1e9 / med);
        else
            printf("%-28s %6zu %14.0f %9.1f %7.1f%% %8s\n", w->name, lens[0], med, 1e9 / med, 100.0 * changed / n,
                   med >= 1e6 ? "ok" : "LOW");
    }
    if (bad) fprintf(stderr, "bench_pad: a generated report was refused (a bug in the generator or a parser)\n");
    return 0;
}
