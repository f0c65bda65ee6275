/*
 * test_pad_io.c — the pad hub (client/pad/pad_hub.c and its backends)
 * behind a fake hidapi and libusb (tests/pad_fake.h), the replay and
 * record backends, and `vantage pad` end to end.
 *
 * Expected states come from running the same reports through pad_parse
 * directly (the reference model): the hub must neither lose nor invent a
 * change. The fake models the libraries only; what only real hardware
 * shows is listed in pad_fake.h.
 */
#include "test_util.h"
#include "test_daemon.h"

#include "pad.h"
#include "pad_fake.h"
#include "pad_io.h"

#include <errno.h>
#include <poll.h>
#include <pthread.h>
#include <stdio.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>
#include <wchar.h>

static double now_mono(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

static void sleep_ms(int ms)
{
    struct timespec ts = {ms / 1000, (long)(ms % 1000) * 1000000L};
    nanosleep(&ts, NULL);
}


/* ---- reports (pad.h's layouts, INPUT.md) ----------------------------------------------------- */

static int ds4_usb(uint8_t *b, uint8_t lx, uint8_t face, uint8_t counter)
{
    memset(b, 0, 64);
    b[0] = 0x01;
    b[1] = lx;
    b[2] = b[3] = b[4] = 0x80;
    b[5] = (uint8_t)(0x08 | face << 4); /* hat: none */
    b[7] = (uint8_t)(counter << 2);
    b[30] = 0x1b;
    return 64;
}

static int x360(uint8_t *b, int16_t lx, uint8_t buttons3)
{
    memset(b, 0, 20);
    b[1] = 0x14;
    b[3] = buttons3;
    b[6] = (uint8_t)lx;
    b[7] = (uint8_t)((uint16_t)lx >> 8);
    return 20;
}

static int gip_input(uint8_t *b, uint8_t seq, int16_t lx, uint8_t buttons0)
{
    memset(b, 0, 18);
    b[0] = 0x20;
    b[2] = seq;
    b[3] = 0x0e;
    b[4] = buttons0;
    b[10] = (uint8_t)lx;
    b[11] = (uint8_t)((uint16_t)lx >> 8);
    return 18;
}

static int gip_guide(uint8_t *b, uint8_t seq, bool down)
{
    const uint8_t g[6] = {0x07, 0x30, seq, 0x02, down ? 0x01 : 0x00, 0x5b};
    memcpy(b, g, sizeof g);
    return 6;
}

/* The reference: the same reports through pad_parse, the states it says
 * changed, and what the parser asked to send (the start packet first). */
typedef struct ref_run {
    pad_parser p;
    pad_state s;              /* the parser's running state */
    pad_state st[256];
    int n;
    fake_pkt out[FAKE_OUTS];
    int nout;
} ref_run;

/* what the parser asked to send, logged */
static void ref_take_out(ref_run *r)
{
    if (!r->p.out_len) return;
    assert_true(r->nout < FAKE_OUTS);
    memcpy(r->out[r->nout].b, r->p.out, r->p.out_len);
    r->out[r->nout++].n = (int)r->p.out_len;
    r->p.out_len = 0;
}

static void ref_begin(ref_run *r, pad_proto proto)
{
    memset(r, 0, sizeof *r);
    pad_parser_init(&r->p, proto);
    pad_state_init(&r->s);
    pad_parser_start(&r->p);
    ref_take_out(r);
}

static void ref_feed(ref_run *r, const uint8_t *b, int n)
{
    int rc = pad_parse(&r->p, b, (size_t)n, &r->s);
    ref_take_out(r);
    if (rc > 0) {
        assert_true(r->n < 256);
        r->st[r->n++] = r->s;
    }
}

static void assert_same_state(const pad_state *a, const pad_state *b)
{
    /* compared through their JSON (every field pad dump shows) and the raw fields */
    char ja[1024], jb[1024];
    pad_state_json(a, 0, ja, sizeof ja);
    pad_state_json(b, 0, jb, sizeof jb);
    assert_string_equal(ja, jb);
    assert_int_equal(a->buttons, b->buttons);
    assert_true(a->lx == b->lx && a->ly == b->ly && a->rx == b->rx && a->ry == b->ry);
    assert_true(a->lt == b->lt && a->rt == b->rt);
    assert_int_equal(a->counter, b->counter);
}

/* ---- hub helpers ----------------------------------------------------------------------------- */

/* The next event within timeout_s (waiting on the hub's fd): 1, or 0. */
static int next_ev(pad_hub *h, pad_event *ev, double timeout_s)
{
    double until = now_mono() + timeout_s;
    for (;;) {
        if (pad_hub_next(h, ev)) return 1;
        double left = until - now_mono();
        if (left <= 0) return 0;
        struct pollfd p = {.fd = pad_hub_fd(h), .events = POLLIN};
        poll(&p, 1, (int)(left * 1000) + 1);
    }
}

/* The next event of this kind within timeout_s (events of other kinds
 * skipped): 1, or 0. */
static int wait_kind(pad_hub *h, pad_event_kind kind, pad_event *ev, double timeout_s)
{
    double until = now_mono() + timeout_s;
    while (next_ev(h, ev, until - now_mono()))
        if (ev->kind == kind) return 1;
    return 0;
}

static pad_hub *open_fake(int rescan_ms, const char *record)
{
    pad_hub_opts o = {.ops = &fake_ops, .rescan_ms = rescan_ms, .record = record};
    pad_hub *h = NULL;
    char err[256];
    int rc = pad_hub_open(&o, &h, err, sizeof err);
    if (rc) fprintf(stderr, "pad_hub_open: %s\n", err);
    assert_int_equal(rc, 0);
    assert_non_null(h);
    assert_true(pad_hub_fd(h) >= 0);
    return h;
}

/* A fresh fake with one DualShock 4 v2 on hidraw, a hub over it
 * (rescanning every 50 ms), and the pad's ADDED read into *ev. */
static pad_hub *open_fake_ds4(fake_dev **ds, pad_event *ev)
{
    fake_reset(false);
    *ds = fake_hid(0x054c, 0x09cc);
    pad_hub *h = open_fake(50, NULL);
    assert_true(wait_kind(h, PAD_EV_ADDED, ev, 5));
    return h;
}

/* A pad's counts (the hub must know it). */
static pad_counts counts_of(pad_hub *h, uint32_t pad)
{
    pad_counts c;
    assert_int_equal(pad_hub_counts(h, pad, &c), 0);
    return c;
}

/* Closed, and the fake holds nothing the hub took. */
static void close_clean(pad_hub *h)
{
    pad_hub_close(h);
    fake_assert_clean();
}

static void wait_consumed(fake_dev *d, long n)
{
    double until = now_mono() + 10;
    while (fake_consumed(d) < n && now_mono() < until) sleep_ms(2);
    assert_int_equal(fake_consumed(d), n);
}

/* ---- discovery ------------------------------------------------------------------------------- */

static void test_pad_io_hidraw_discovery(void **state)
{
    (void)state;
    fake_reset(false);
    fake_dev *ds4 = fake_hid(0x054c, 0x09cc);
    fake_dev *unknown = fake_hid(0x1234, 0x5678);
    fake_dev *x360_on_hid = fake_hid(0x045e, 0x028e); /* an Xbox id is read through libusb, never hidraw */
    pad_hub *h = open_fake(50, NULL);
    pad_event ev;
    assert_true(wait_kind(h, PAD_EV_ADDED, &ev, 5));
    assert_int_equal(ev.pad, 1);
    assert_non_null(ev.info);
    assert_int_equal(ev.info->proto, PAD_PROTO_DS4);
    assert_non_null(strstr(ev.msg, ds4->path));
    assert_non_null(strstr(ev.msg, "hidraw"));
    /* the fd says when events wait: none now */
    struct pollfd p = {.fd = pad_hub_fd(h), .events = POLLIN};
    assert_int_equal(poll(&p, 1, 0), 0);

    ref_run ref;
    ref_begin(&ref, PAD_PROTO_DS4);
    uint8_t b[64];
    for (int i = 0; i < 20; i++) {
        int n = ds4_usb(b, (uint8_t)(100 + i), (uint8_t)(i & 3), (uint8_t)i);
        ref_feed(&ref, b, n);
        fake_push(ds4, b, n);
        /* one at a time: no merging here */
        wait_consumed(ds4, i + 1);
        assert_true(wait_kind(h, PAD_EV_STATE, &ev, 5));
        assert_int_equal(ev.pad, 1);
        assert_same_state(&ev.state, &ref.st[ref.n - 1]);
        assert_true(ev.t_file >= 0 && ev.t_file < 30);
    }
    /* a report that changes nothing makes no event */
    int n = ds4_usb(b, 119, 3, 19);
    fake_push(ds4, b, n);
    wait_consumed(ds4, 21);
    assert_int_equal(next_ev(h, &ev, 0.3), 0);
    /* the unknown device and the Xbox id on hidraw were never opened */
    sleep_ms(150); /* a few rescans */
    pthread_mutex_lock(&fake.mu);
    assert_int_equal(unknown->opens, 0);
    assert_int_equal(x360_on_hid->opens, 0);
    assert_int_equal(ds4->opens, 1); /* listed twice an enumeration (two usages), opened once */
    pthread_mutex_unlock(&fake.mu);
    pad_counts c = counts_of(h, 1);
    assert_int_equal(c.reports, 21);
    assert_int_equal(c.states, 20);
    assert_int_equal(c.ignored, 1);
    assert_int_equal(pad_hub_counts(h, 99, &c), -1);
    close_clean(h);
}

static void test_pad_io_usb_xbox(void **state)
{
    (void)state;
    fake_reset(false); /* no hotplug: the periodic libusb scan finds them */
    fake_dev *d360 = fake_usb(0x045e, 0x028e, false);
    fake_dev *one = fake_usb(0x045e, 0x02ea, true);
    /* queued before the hub starts: the GIP pad hands nothing over before its power-on */
    uint8_t b[64];
    int n = gip_input(b, 1, 1000, 0x10);
    fake_push(one, b, n);
    pad_hub *h = open_fake(50, NULL);
    pad_event ev;
    uint32_t id360 = 0, idone = 0;
    for (int i = 0; i < 2; i++) {
        assert_true(wait_kind(h, PAD_EV_ADDED, &ev, 5));
        assert_non_null(strstr(ev.msg, "libusb usb 1-"));
        if (ev.info->proto == PAD_PROTO_XBOX360) id360 = ev.pad;
        if (ev.info->proto == PAD_PROTO_XBOXONE) idone = ev.pad;
    }
    assert_true(id360 && idone && id360 != idone);

    /* Xbox One: power-on first, the queued input after it, the guide acknowledged */
    ref_run ref;
    ref_begin(&ref, PAD_PROTO_XBOXONE);
    assert_int_equal(ref.nout, 1); /* the power-on */
    ref_feed(&ref, b, n);
    assert_true(wait_kind(h, PAD_EV_STATE, &ev, 5));
    assert_int_equal(ev.pad, idone);
    assert_same_state(&ev.state, &ref.st[0]);
    n = gip_guide(b, 2, true);
    ref_feed(&ref, b, n);
    assert_int_equal(ref.nout, 2); /* the guide's ack */
    fake_push(one, b, n);
    assert_true(wait_kind(h, PAD_EV_STATE, &ev, 5));
    assert_true(ev.state.buttons & PAD_GUIDE);
    assert_same_state(&ev.state, &ref.st[1]);
    wait_consumed(one, 2);
    sleep_ms(50); /* the ack is written after the parse that queued the STATE */
    pthread_mutex_lock(&fake.mu);
    assert_int_equal(one->reads_before_write, 0);
    assert_int_equal(one->nout, ref.nout);
    for (int i = 0; i < ref.nout; i++) {
        assert_int_equal(one->out[i].n, ref.out[i].n);
        assert_memory_equal(one->out[i].b, ref.out[i].b, (size_t)ref.out[i].n);
    }
    assert_int_equal(one->out[0].b[0], 0x05);
    assert_int_equal(one->out[1].b[0], 0x01);
    assert_true(one->claimed && !one->claim_before_detach);
    assert_true(d360->claimed && !d360->claim_before_detach);
    assert_int_equal(d360->nout, 0); /* nothing is sent to a 360 pad */
    pthread_mutex_unlock(&fake.mu);

    /* Xbox 360 input */
    ref_begin(&ref, PAD_PROTO_XBOX360);
    n = x360(b, -20000, 0x10); /* A */
    ref_feed(&ref, b, n);
    fake_push(d360, b, n);
    assert_true(wait_kind(h, PAD_EV_STATE, &ev, 5));
    assert_int_equal(ev.pad, id360);
    assert_true(ev.state.buttons & PAD_SOUTH);
    assert_same_state(&ev.state, &ref.st[0]);
    close_clean(h);
}

static void test_pad_io_unknown_ignored(void **state)
{
    (void)state;
    fake_reset(false);
    fake_dev *u1 = fake_hid(0x046d, 0xc52b);          /* a receiver */
    fake_dev *u2 = fake_usb(0x1234, 0x5678, false);    /* XInput-looking, not in the table */
    fake_dev *ds4_usb_id = fake_usb(0x054c, 0x09cc, false); /* a hidraw pad seen by libusb: hidraw's */
    fake_dev *bad = fake_usb(0x045e, 0x028e, false);
    bad->cls[1] = 0x42; /* an Xbox 360 id without the XInput interface */
    pad_hub *h = open_fake(50, NULL);
    pad_event ev;
    assert_true(wait_kind(h, PAD_EV_ERROR, &ev, 5));
    assert_non_null(strstr(ev.msg, "XInput"));
    assert_int_equal(wait_kind(h, PAD_EV_ADDED, &ev, 0.5), 0);
    pthread_mutex_lock(&fake.mu);
    assert_int_equal(u1->opens + u2->opens + ds4_usb_id->opens + bad->opens, 0);
    pthread_mutex_unlock(&fake.mu);
    /* pad list with the same fake: none of them either */
    pad_found f[4];
    char err[128];
    assert_int_equal(pad_enumerate(&fake_ops, f, 4, err, sizeof err), 1); /* the 360 id is listed: not opened */
    assert_int_equal(f[0].info->proto, PAD_PROTO_XBOX360);
    close_clean(h);
}

static void test_pad_io_enumerate(void **state)
{
    (void)state;
    fake_reset(false);
    fake_hid(0x054c, 0x0ce6)->bluetooth = true;
    fake_hid(0x057e, 0x2009);
    fake_hid(0x1234, 0x0001);
    fake_usb(0x045e, 0x0b12, true);
    pad_found f[8];
    char err[128] = "x";
    int n = pad_enumerate(&fake_ops, f, 8, err, sizeof err);
    assert_int_equal(n, 3);
    assert_string_equal(err, "");
    int seen = 0;
    for (int i = 0; i < n; i++) {
        if (f[i].info->proto == PAD_PROTO_DUALSENSE) {
            seen |= 1;
            assert_non_null(strstr(f[i].where, "/dev/hidraw"));
            assert_non_null(strstr(f[i].where, "Bluetooth"));
            assert_string_equal(f[i].product, "Wireless Controller");
        }
        if (f[i].info->proto == PAD_PROTO_SWITCH_PRO) seen |= 2;
        if (f[i].info->proto == PAD_PROTO_XBOXONE) {
            seen |= 4;
            assert_non_null(strstr(f[i].where, "usb 1-"));
        }
    }
    assert_int_equal(seen, 7);
    /* more than max: the count, max filled */
    assert_int_equal(pad_enumerate(&fake_ops, f, 1, err, sizeof err), 3);
    fake_assert_clean();
    for (int i = 0; i < FAKE_DEVS; i++) assert_int_equal(fake.dev[i].opens, 0); /* listed, not opened */
}

/* ---- unplug, plug back, hotplug --------------------------------------------------------------- */

static void test_pad_io_hidraw_replug(void **state)
{
    (void)state;
    fake_reset(false);
    fake_dev *ds = fake_hid(0x054c, 0x0ce6);
    pad_hub *h = open_fake(100, NULL);
    pad_event ev;
    assert_true(wait_kind(h, PAD_EV_ADDED, &ev, 5));
    uint32_t first = ev.pad;
    double took[2];
    for (int cycle = 0; cycle < 2; cycle++) {
        fake_unplug(ds);
        assert_true(wait_kind(h, PAD_EV_REMOVED, &ev, 5));
        assert_int_equal(ev.pad, first);
        assert_non_null(strstr(ev.msg, "unplugged"));
        assert_non_null(strstr(ev.msg, "closed"));
        pthread_mutex_lock(&fake.mu);
        assert_int_equal(ds->is_open, 0); /* closed by the time REMOVED is read */
        pthread_mutex_unlock(&fake.mu);
        double t0 = now_mono();
        fake_plug(ds);
        assert_true(wait_kind(h, PAD_EV_ADDED, &ev, 5));
        double dt = now_mono() - t0;
        took[cycle] = dt;
        assert_true(ev.pad > first); /* a new id */
        first = ev.pad;
        /* the second cycle is a quick flap: allowed a longer wait, still well under 3 s */
        assert_true(dt < 3.0);
    }
    printf("hidraw replug picked up in %.0f ms, then %.0f ms as a quick flap (rescan 100 ms)\n", took[0] * 1e3,
           took[1] * 1e3);
    /* and it reads */
    uint8_t b[64] = {0x01, 0x00, 0x80, 0x80, 0x80};
    fake_push(ds, b, 64);
    assert_true(wait_kind(h, PAD_EV_STATE, &ev, 5));
    assert_int_equal(ev.pad, first);
    close_clean(h);
}

static void test_pad_io_usb_hotplug(void **state)
{
    (void)state;
    fake_reset(true);
    fake_dev *x = fake_usb(0x046d, 0xc21d, false); /* F310 */
    x->present = false;
    /* a long rescan (60 s): only the hotplug callback can find it within
       the 20 s waited here (a liveness bound far above the milliseconds it
       takes, so a loaded machine cannot fail it; the times are printed) */
    pad_hub *h = open_fake(60000, NULL);
    pad_event ev;
    assert_int_equal(next_ev(h, &ev, 0.3), 0);
    double t0 = now_mono();
    fake_plug(x);
    assert_true(wait_kind(h, PAD_EV_ADDED, &ev, 20));
    double dt_add = now_mono() - t0;
    uint32_t id = ev.pad;
    /* it leaves without its reads failing: the LEFT news alone removes it */
    pthread_mutex_lock(&fake.mu);
    x->silent_leave = true;
    pthread_mutex_unlock(&fake.mu);
    t0 = now_mono();
    fake_unplug(x);
    assert_true(wait_kind(h, PAD_EV_REMOVED, &ev, 20));
    double dt_rm = now_mono() - t0;
    assert_int_equal(ev.pad, id);
    assert_non_null(strstr(ev.msg, "hotplug"));
    pthread_mutex_lock(&fake.mu);
    x->silent_leave = false;
    pthread_mutex_unlock(&fake.mu);
    sleep_ms(150); /* reaped */
    t0 = now_mono();
    fake_plug(x);
    assert_true(wait_kind(h, PAD_EV_ADDED, &ev, 20));
    double dt_add2 = now_mono() - t0;
    assert_true(ev.pad > id);
    printf("usb hotplug: added in %.0f ms, removed in %.0f ms, added again in %.0f ms\n", dt_add * 1e3, dt_rm * 1e3,
           dt_add2 * 1e3);
    assert_true(dt_add < 20.0 && dt_add2 < 20.0); /* not the 60 s rescan */
    /* plugged out with failing reads: REMOVED by the reader, whichever comes first */
    fake_unplug(x);
    assert_true(wait_kind(h, PAD_EV_REMOVED, &ev, 20));
    assert_int_equal(wait_kind(h, PAD_EV_REMOVED, &ev, 0.3), 0); /* once */
    close_clean(h);
}

static void test_pad_io_open_failure(void **state)
{
    (void)state;
    fake_reset(false);
    fake_dev *locked = fake_hid(0x054c, 0x05c4);
    locked->fail_open = true;
    fake_dev *ok = fake_hid(0x057e, 0x2009);
    fake_dev *ulocked = fake_usb(0x045e, 0x02d1, true);
    ulocked->fail_open = true;
    pad_hub *h = open_fake(50, NULL);
    pad_event ev;
    int errors = 0, added = 0, hid_err = 0, usb_err = 0;
    double until = now_mono() + 1.0; /* twenty rescans */
    while (next_ev(h, &ev, until - now_mono())) {
        if (ev.kind == PAD_EV_ERROR) {
            errors++;
            assert_int_equal(ev.pad, 0); /* no pad of the hub's: the device is named in msg */
            assert_null(ev.info);
            if (strstr(ev.msg, locked->path)) {
                hid_err++;
                assert_non_null(strstr(ev.msg, "Permission denied"));
                assert_non_null(strstr(ev.msg, "udev"));
            } else {
                usb_err++;
                assert_non_null(strstr(ev.msg, "usb 1-"));
                assert_non_null(strstr(ev.msg, "udev"));
            }
        }
        if (ev.kind == PAD_EV_ADDED) {
            added++;
            assert_int_equal(ev.info->proto, PAD_PROTO_SWITCH_PRO);
        }
    }
    /* said once each, while the hub goes on */
    assert_int_equal(hid_err, 1);
    assert_int_equal(usb_err, 1);
    assert_int_equal(errors, 2);
    assert_int_equal(added, 1);
    pthread_mutex_lock(&fake.mu);
    assert_true(locked->opens >= 2 && locked->opens <= 8); /* tried again, with a growing wait */
    locked->fail_open = false;
    ulocked->fail_open = false;
    pthread_mutex_unlock(&fake.mu);
    /* the permission fixed: both come within the (capped) retry wait */
    for (int i = 0; i < 2; i++) assert_true(wait_kind(h, PAD_EV_ADDED, &ev, 8));
    /* a report the Switch parser refuses (a DS4 one): an ERROR tied to the pad */
    uint8_t b[64];
    ds4_usb(b, 3, 0, 0);
    fake_push(ok, b, 49);
    assert_true(wait_kind(h, PAD_EV_ERROR, &ev, 5));
    assert_int_not_equal(ev.pad, 0);
    assert_non_null(strstr(ev.msg, "refused"));
    close_clean(h);
}

/* libusb that will not start: an ERROR says so, hidraw pads still come. */
static void test_pad_io_no_libusb(void **state)
{
    (void)state;
    fake_reset(true);
    fake.usb_init_fails = true;
    fake_hid(0x054c, 0x09cc);
    fake_usb(0x045e, 0x028e, false);
    pad_hub *h = open_fake(50, NULL);
    pad_event ev;
    assert_true(next_ev(h, &ev, 5));
    assert_int_equal(ev.kind, PAD_EV_ERROR);
    assert_non_null(strstr(ev.msg, "libusb"));
    assert_non_null(strstr(ev.msg, "Xbox"));
    assert_true(wait_kind(h, PAD_EV_ADDED, &ev, 5));
    assert_int_equal(ev.info->proto, PAD_PROTO_DS4);
    assert_int_equal(wait_kind(h, PAD_EV_ADDED, &ev, 0.3), 0);
    close_clean(h);
    /* pad list: the count stands, err says what is missing */
    pad_found f[4];
    char err[160];
    assert_int_equal(pad_enumerate(&fake_ops, f, 4, err, sizeof err), 1);
    assert_non_null(strstr(err, "libusb"));
    fake_assert_clean();
}

/* A pad that sends garbage: ERROR events, but PARSE_ERR_BURST and then about one a second. */
static void test_pad_io_error_rate_limit(void **state)
{
    (void)state;
    fake_dev *ds;
    pad_event ev;
    pad_hub *h = open_fake_ds4(&ds, &ev);
    uint8_t junk[64];
    memset(junk, 0xEE, sizeof junk);
    for (int i = 0; i < 300; i++) fake_push(ds, junk, 7);
    wait_consumed(ds, 300);
    int errs = 0;
    while (next_ev(h, &ev, 0.2)) errs += ev.kind == PAD_EV_ERROR;
    assert_true(errs >= 1 && errs <= 7);
    pad_counts c = counts_of(h, 1);
    assert_int_equal(c.errors, 300);
    close_clean(h);
}

static void test_pad_io_merge_slow_consumer(void **state)
{
    (void)state;
    fake_dev *ds;
    pad_event ev;
    pad_hub *h = open_fake_ds4(&ds, &ev);
    ref_run ref;
    ref_begin(&ref, PAD_PROTO_DS4);
    uint8_t b[64];
    for (int i = 0; i < 200; i++) {
        int n = ds4_usb(b, (uint8_t)i, (uint8_t)(i % 16), (uint8_t)i);
        ref_feed(&ref, b, n);
        fake_push(ds, b, n);
    }
    assert_int_equal(ref.n, 200);
    /* nothing read while the pad sends: one STATE, the newest */
    wait_consumed(ds, 200);
    sleep_ms(20);
    int states = 0;
    pad_state last;
    while (next_ev(h, &ev, 0.2)) {
        assert_int_equal(ev.kind, PAD_EV_STATE);
        states++;
        last = ev.state;
    }
    assert_int_equal(states, 1);
    assert_same_state(&last, &ref.st[199]);
    pad_counts c = counts_of(h, 1);
    assert_int_equal(c.states, 200);
    assert_int_equal(c.merged, 199);
    /* an event of another kind between STATEs keeps the order: STATE, REMOVED */
    int n = ds4_usb(b, 7, 1, 1);
    fake_push(ds, b, n);
    wait_consumed(ds, 201);
    fake_unplug(ds);
    assert_true(next_ev(h, &ev, 5));
    assert_int_equal(ev.kind, PAD_EV_STATE);
    assert_true(wait_kind(h, PAD_EV_REMOVED, &ev, 5));
    close_clean(h);
}

static void test_pad_io_close_while_blocked(void **state)
{
    (void)state;
    fake_reset(true);
    fake_hid(0x054c, 0x09cc);
    fake_hid(0x054c, 0x0ce6);
    fake_hid(0x057e, 0x2009);
    fake_usb(0x045e, 0x028e, false);
    fake_usb(0x045e, 0x0b12, true);
    pad_hub *h = open_fake(50, NULL);
    pad_event ev;
    for (int i = 0; i < 5; i++) assert_true(wait_kind(h, PAD_EV_ADDED, &ev, 5));
    sleep_ms(150); /* every reader inside its blocking read, half-way through its timeout */
    double t0 = now_mono();
    pad_hub_close(h);
    double dt = now_mono() - t0;
    printf("close with 5 readers blocked: %.0f ms\n", dt * 1e3);
    assert_true(dt < 1.5); /* one read timeout (100 ms), not one each */
    fake_assert_clean();
    pad_hub_close(NULL);
}

/* The real libraries on this machine: whatever is plugged in, the hub
 * opens, finds what there is, and closes cleanly. */
static void test_pad_io_real_libraries(void **state)
{
    (void)state;
    char err[256];
    pad_found f[8];
    int n = pad_enumerate(NULL, f, 8, err, sizeof err);
    printf("real libraries: %d pads present%s%s\n", n, err[0] ? ": " : "", err);
    assert_true(n >= 0);
    if (n > 0) skip(); /* a test must not take a user's pads away (xpad detached) */
    pad_hub_opts o = {.rescan_ms = 100};
    pad_hub *h = NULL;
    assert_int_equal(pad_hub_open(&o, &h, err, sizeof err), 0);
    pad_event ev;
    double until = now_mono() + 0.4;
    while (next_ev(h, &ev, until - now_mono())) {
        if (ev.kind == PAD_EV_ERROR) printf("real libraries: %s\n", ev.msg);
        assert_int_not_equal(ev.kind, PAD_EV_STATE);
    }
    pad_hub_close(h);
}

/* ---- a folder per test (the replay, record and CLI tests' files) ------------------------------ */

/* cmocka fixtures: *state is a fresh tdir, removed after the test even
 * when it fails. */
static int padio_dir(void **state)
{
    tdir *td = malloc(sizeof *td);
    assert_non_null(td);
    tdir_make(td, "padio");
    *state = td;
    return 0;
}

static int padio_dir_remove(void **state)
{
    tdir_remove(*state);
    free(*state);
    return 0;
}

/* ---- replay ------------------------------------------------------------------------------------- */

static void write_file(const char *path, const char *text)
{
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs(text, f);
    fclose(f);
}

static void write_event(FILE *f, double t, const uint8_t *b, int n)
{
    char line[2048];
    int k = pad_line_format_event(t, b, (size_t)n, line, sizeof line);
    assert_true(k > 0 && (size_t)k < sizeof line);
    fputs(line, f);
}

/* A DS4 recording: n reports at t = i * dt, LX = 10 * i. */
static void write_ds4_file(const char *path, int n, double dt, ref_run *ref)
{
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fprintf(f, "# a test recording\nD: 0\nR: 3 05 01 09\nN: Sony Interactive Entertainment Wireless Controller\n"
               "P: usb-0000:00:14.0-2/input3\nI: 3 054c 09cc\n");
    ref_begin(ref, PAD_PROTO_DS4);
    uint8_t b[64];
    for (int i = 0; i < n; i++) {
        int k = ds4_usb(b, (uint8_t)(10 * i), (uint8_t)(i & 1), (uint8_t)i);
        ref_feed(ref, b, k);
        write_event(f, i * dt, b, k);
    }
    fclose(f);
}

static pad_hub *open_replay(const char *path, double speed, bool loop)
{
    pad_hub_opts o = {.replay = path, .replay_speed = speed, .replay_loop = loop};
    pad_hub *h = NULL;
    char err[256];
    int rc = pad_hub_open(&o, &h, err, sizeof err);
    if (rc) fprintf(stderr, "pad_hub_open: %s\n", err);
    assert_int_equal(rc, 0);
    return h;
}

static void test_pad_io_replay_timing(void **state)
{
    tdir *td = *state; /* padio_dir */
    const char *path = tdir_file(td, "ds4.txt");
    ref_run ref;
    write_ds4_file(path, 6, 0.1, &ref); /* 0.5 s of file */
    assert_int_equal(ref.n, 6);
    double t_open = now_mono();
    pad_hub *h = open_replay(path, 2.0, false);
    pad_event ev;
    assert_true(next_ev(h, &ev, 5));
    assert_int_equal(ev.kind, PAD_EV_ADDED);
    assert_non_null(strstr(ev.msg, "DualShock 4"));
    double t_last = 0;
    for (int i = 0; i < 6; i++) {
        assert_true(next_ev(h, &ev, 5));
        assert_int_equal(ev.kind, PAD_EV_STATE);
        assert_same_state(&ev.state, &ref.st[i]);
        assert_true(fabs(ev.t_file - 0.1 * i) < 1e-6);
        /* never early: report i is due 0.05 * i s after the open (a loaded machine only ever adds) */
        assert_true(ev.t_report - t_open >= 0.05 * i - 0.002);
        t_last = ev.t_report;
    }
    assert_true(next_ev(h, &ev, 5));
    assert_int_equal(ev.kind, PAD_EV_END);
    double span = t_last - t_open;
    printf("replay at speed 2: 0.5 s of file in %.3f s\n", span);
    assert_true(span < 0.25 + 0.75);
    pad_hub_close(h);

    /* speed < 0: as fast as drained, every state kept even when drained late */
    h = open_replay(path, -1, false);
    sleep_ms(100);
    int k = 0;
    while (next_ev(h, &ev, 5) && ev.kind != PAD_EV_END) {
        if (ev.kind != PAD_EV_STATE) continue;
        assert_same_state(&ev.state, &ref.st[k]);
        k++;
        sleep_ms(5);
    }
    assert_int_equal(k, 6);
    assert_int_equal(ev.kind, PAD_EV_END);
    pad_hub_close(h);
}

static void expect_open_error(const char *path, const char *text, const char *want1, const char *want2)
{
    write_file(path, text);
    pad_hub_opts o = {.replay = path};
    pad_hub *h = (pad_hub *)1;
    char err[256] = "";
    assert_int_equal(pad_hub_open(&o, &h, err, sizeof err), -1);
    assert_null(h);
    if (!strstr(err, want1) || (want2 && !strstr(err, want2))) fprintf(stderr, "error was: %s\n", err);
    assert_non_null(strstr(err, want1));
    if (want2) assert_non_null(strstr(err, want2));
}

static void test_pad_io_replay_errors(void **state)
{
    tdir *td = *state; /* padio_dir */
    const char *path = tdir_file(td, "bad.txt");
    char want[400];
    snprintf(want, sizeof want, "%s:6:", path);
    expect_open_error(path, "D: 0\nN: pad\nI: 3 054c 09cc\nE: 0.000000 3 01 80 80\nE: 0.100000 3 01 80 80\n"
                            "E: 0.200000 3 01 8x 80\n",
                      want, NULL);
    snprintf(want, sizeof want, "%s:3:", path);
    expect_open_error(path, "D: 0\nN: pad\nI: 3 1234 5678\nE: 0.000000 3 01 80 80\n", want, "1234:5678");
    snprintf(want, sizeof want, "%s:2:", path);
    expect_open_error(path, "D: 0\nE: 0.000000 3 01 80 80\nI: 3 054c 09cc\n", want, "I:");
    snprintf(want, sizeof want, "%s:1:", path);
    expect_open_error(path, "this is not a recording\n", want, NULL);
    pad_hub_opts o = {.replay = tdir_file(td, "missing.txt")};
    pad_hub *h;
    char err[256];
    assert_int_equal(pad_hub_open(&o, &h, err, sizeof err), -1);
    assert_non_null(strstr(err, "missing.txt"));
    assert_non_null(strstr(err, strerror(ENOENT)));
}

static void test_pad_io_replay_loop_devices(void **state)
{
    tdir *td = *state; /* padio_dir */
    const char *path = tdir_file(td, "two.txt");
    /* two devices, the second over Bluetooth, their lines interleaved with D: */
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fprintf(f, "D: 0\nN: pad one\nI: 3 054c 09cc\nD: 1\nN: pad two\nI: 5 057e 2009\n");
    ref_run r0, r1;
    ref_begin(&r0, PAD_PROTO_DS4);
    ref_begin(&r1, PAD_PROTO_SWITCH_PRO);
    uint8_t b[64];
    for (int i = 0; i < 4; i++) {
        int k = ds4_usb(b, (uint8_t)(50 + i), 0, (uint8_t)i);
        ref_feed(&r0, b, k);
        fprintf(f, "D: 0\n");
        write_event(f, 0.01 * i, b, k);
        memset(b, 0, 12);
        b[0] = 0x3F;
        b[1] = (uint8_t)(1 << i); /* a button each */
        b[3] = 0x08;
        b[5] = b[7] = b[9] = b[11] = 0x80;
        ref_feed(&r1, b, 12);
        fprintf(f, "D: 1\n");
        write_event(f, 0.01 * i + 0.005, b, 12);
    }
    fclose(f);
    assert_int_equal(r0.n, 4);
    assert_true(r1.n >= 3);

    /* once: both pads, their states in order, then END */
    pad_hub *h = open_replay(path, -1, false);
    pad_event ev;
    int k0 = 0, k1 = 0, added = 0;
    uint32_t id0 = 0, id1 = 0;
    while (next_ev(h, &ev, 5) && ev.kind != PAD_EV_END) {
        if (ev.kind == PAD_EV_ADDED) {
            added++;
            if (ev.info->proto == PAD_PROTO_DS4) id0 = ev.pad;
            else {
                id1 = ev.pad;
                assert_non_null(strstr(ev.msg, "Bluetooth"));
            }
            continue;
        }
        assert_int_equal(ev.kind, PAD_EV_STATE);
        if (ev.pad == id0) assert_same_state(&ev.state, &r0.st[k0++]);
        else if (ev.pad == id1) assert_same_state(&ev.state, &r1.st[k1++]);
        else fail();
    }
    assert_int_equal(ev.kind, PAD_EV_END);
    assert_int_equal(added, 2);
    assert_int_equal(k0, r0.n);
    assert_int_equal(k1, r1.n);
    pad_hub_close(h);

    /* looped: the file again and again, the same pads, no END */
    h = open_replay(path, -1, true);
    int states = 0;
    added = 0;
    while (states < 3 * (r0.n + r1.n) && next_ev(h, &ev, 5)) {
        assert_int_not_equal(ev.kind, PAD_EV_END);
        if (ev.kind == PAD_EV_ADDED) added++;
        if (ev.kind == PAD_EV_STATE) states++;
    }
    assert_int_equal(states, 3 * (r0.n + r1.n));
    assert_int_equal(added, 2);
    pad_hub_close(h);

    /* looped at the file's speed: time goes on, never back */
    h = open_replay(path, 1, true);
    double last = -1;
    states = 0;
    while (states < 20 && next_ev(h, &ev, 5)) {
        if (ev.kind != PAD_EV_STATE) continue;
        assert_true(ev.t_report >= last);
        last = ev.t_report;
        states++;
    }
    assert_int_equal(states, 20);
    pad_hub_close(h);
}

/* ---- record -------------------------------------------------------------------------------------- */

static void test_pad_io_record_roundtrip(void **state)
{
    tdir *td = *state; /* padio_dir */
    const char *path = tdir_file(td, "rec.txt");
    fake_reset(false);
    fake_dev *ds = fake_hid(0x054c, 0x09cc);
    fake_dev *one = fake_usb(0x045e, 0x02ea, true);
    pad_hub *h = open_fake(50, path);
    pad_event ev;
    uint32_t id_ds = 0, id_one = 0;
    for (int i = 0; i < 2; i++) {
        assert_true(wait_kind(h, PAD_EV_ADDED, &ev, 5));
        if (ev.info->proto == PAD_PROTO_DS4) id_ds = ev.pad;
        else id_one = ev.pad;
    }
    assert_true(id_ds && id_one);
    /* the live states, one report at a time, interleaved between the pads */
    pad_state live_ds[16], live_one[16];
    int nds = 0, none = 0;
    uint8_t b[64];
    for (int i = 0; i < 12; i++) {
        fake_dev *d = i % 2 ? one : ds;
        int n;
        if (d == ds) n = ds4_usb(b, (uint8_t)(30 * i), (uint8_t)(i & 3), (uint8_t)i);
        else if (i % 4 == 1) n = gip_guide(b, (uint8_t)i, i % 8 == 1); /* guide down, up, down */
        else n = gip_input(b, (uint8_t)i, (int16_t)(500 * i), 0x20);
        fake_push(d, b, n);
        assert_true(wait_kind(h, PAD_EV_STATE, &ev, 5));
        if (ev.pad == id_ds) live_ds[nds++] = ev.state;
        else live_one[none++] = ev.state;
    }
    close_clean(h);
    assert_int_equal(nds, 6);
    assert_int_equal(none, 6);

    /* the file: a header per device, flushed lines */
    FILE *f = fopen(path, "r");
    assert_non_null(f);
    char line[2048];
    int heads = 0, events = 0, switches = 0;
    while (fgets(line, sizeof line, f)) {
        heads += !strncmp(line, "I: ", 3);
        events += !strncmp(line, "E: ", 3);
        switches += !strncmp(line, "D: ", 3);
    }
    fclose(f);
    assert_int_equal(heads, 2);
    assert_int_equal(events, 12);
    assert_true(switches >= 12); /* interleaved: a D: before every report of the other pad */

    /* replayed: the same states for each pad */
    h = open_replay(path, -1, false);
    int kds = 0, kone = 0;
    id_ds = id_one = 0;
    while (next_ev(h, &ev, 5) && ev.kind != PAD_EV_END) {
        if (ev.kind == PAD_EV_ADDED) {
            if (ev.info->proto == PAD_PROTO_DS4) id_ds = ev.pad;
            else id_one = ev.pad;
            continue;
        }
        assert_int_equal(ev.kind, PAD_EV_STATE);
        if (ev.pad == id_ds) assert_same_state(&ev.state, &live_ds[kds++]);
        else if (ev.pad == id_one) assert_same_state(&ev.state, &live_one[kone++]);
        else fail();
    }
    assert_int_equal(ev.kind, PAD_EV_END);
    assert_int_equal(kds, 6);
    assert_int_equal(kone, 6);
    pad_hub_close(h);
}

/* ---- vantage pad ------------------------------------------------------------------------------- */

/* test_run_cmd, its status as an exit code (128: killed) */
static int run_cmd(const char *cmd, char *out, size_t cap)
{
    int st = test_run_cmd(cmd, out, cap);
    return WIFEXITED(st) ? WEXITSTATUS(st) : 128;
}

static void test_pad_io_cli_dump(void **state)
{
    tdir *td = *state; /* padio_dir */
    char path[320], errpath[320];
    snprintf(path, sizeof path, "%s", tdir_file(td, "ds4.txt"));
    snprintf(errpath, sizeof errpath, "%s", tdir_file(td, "stderr.txt"));
    ref_run ref;
    write_ds4_file(path, 25, 0.004, &ref);
    char cmd[1200];
    static char out[1 << 16];
    snprintf(cmd, sizeof cmd, "%s/vantage pad dump --replay %s --speed -1 2>%s", bin_dir(), path, errpath);
    assert_int_equal(run_cmd(cmd, out, sizeof out), 0);
    /* one line a state change, the parser's JSON with the pad's id in front and t from the file */
    char *line = out;
    for (int i = 0; i < ref.n; i++) {
        char want[1100], js[1024];
        pad_state_json(&ref.st[i], 0.004 * i, js, sizeof js);
        snprintf(want, sizeof want, "{\"pad\":1,%s\n", js + 1);
        assert_true(strlen(line) >= strlen(want));
        if (strncmp(line, want, strlen(want))) fprintf(stderr, "line %d:\n got  %s want %s", i, line, want);
        assert_memory_equal(line, want, strlen(want));
        line += strlen(want);
    }
    assert_string_equal(line, "");
    FILE *e = fopen(errpath, "r");
    assert_non_null(e);
    size_t n = fread(out, 1, sizeof out - 1, e);
    out[n] = 0;
    fclose(e);
    assert_non_null(strstr(out, "pad 1 added: DualShock 4"));

    /* --count, --stats */
    snprintf(cmd, sizeof cmd, "%s/vantage pad dump --replay %s --speed -1 --count 3 --stats 2>%s", bin_dir(), path,
             errpath);
    assert_int_equal(run_cmd(cmd, out, sizeof out), 0);
    int lines = 0;
    for (char *c = out; *c; c++) lines += *c == '\n';
    assert_int_equal(lines, 3);
    /* a malformed file: exit 1, the line named */
    write_file(path, "D: 0\nI: 3 054c 09cc\nE: 0.0 2 01\n");
    snprintf(cmd, sizeof cmd, "%s/vantage pad dump --replay %s 2>&1", bin_dir(), path);
    assert_int_equal(run_cmd(cmd, out, sizeof out), 1);
    char want[400];
    snprintf(want, sizeof want, "%s:3:", path);
    assert_non_null(strstr(out, want));
    /* usage */
    snprintf(cmd, sizeof cmd, "%s/vantage pad dump --speed 2 2>&1", bin_dir());
    assert_int_equal(run_cmd(cmd, out, sizeof out), 2);
    snprintf(cmd, sizeof cmd, "%s/vantage pad dump --count x --replay %s 2>&1", bin_dir(), path);
    assert_int_equal(run_cmd(cmd, out, sizeof out), 2);
    snprintf(cmd, sizeof cmd, "%s/vantage pad frobnicate 2>&1", bin_dir());
    assert_int_equal(run_cmd(cmd, out, sizeof out), 2);
    snprintf(cmd, sizeof cmd, "%s/vantage pad --help", bin_dir());
    assert_int_equal(run_cmd(cmd, out, sizeof out), 0);
    assert_non_null(strstr(out, "pad list [--json]"));
    assert_non_null(strstr(out, "--record FILE"));
    assert_non_null(strstr(out, "--stats"));
}

/* A capture of a few seconds (the commander's, tests/data/pads): the
 * CLI's lines against the parser run over the file's lines here. */
static void test_pad_io_cli_capture(void **state)
{
    char cap[512];
    const char *dd = getenv("VANTAGE_DATA_DIR");
    snprintf(cap, sizeof cap, "%s/pads/ds4_commander_walk.hidrec", dd ? dd : "tests/data");
    FILE *f = fopen(cap, "r");
    if (!f) skip();
    tdir *td = *state; /* padio_dir */
    char outpath[320];
    snprintf(outpath, sizeof outpath, "%s", tdir_file(td, "out.jsonl"));
    char cmd[1400];
    snprintf(cmd, sizeof cmd, "%s/vantage pad dump --replay %s --speed -1 >%s 2>/dev/null", bin_dir(), cap, outpath);
    int st = system(cmd);
    assert_true(WIFEXITED(st) && WEXITSTATUS(st) == 0);
    FILE *o = fopen(outpath, "r");
    assert_non_null(o);
    pad_line *pl = malloc(sizeof *pl);
    assert_non_null(pl);
    pad_parser p;
    pad_state s;
    pad_parser_init(&p, PAD_PROTO_NONE);
    pad_state_init(&s);
    char *line = NULL, got[2048], js[1024], want[1100];
    size_t capn = 0;
    ssize_t n;
    long reports = 0, changes = 0;
    while ((n = getline(&line, &capn, f)) >= 0) {
        while (n > 0 && (line[n - 1] == '\n' || line[n - 1] == '\r')) n--;
        char err[160];
        assert_int_equal(pad_line_parse(line, (size_t)n, pl, err, sizeof err), 0);
        if (pl->kind == PAD_LINE_INFO) {
            const pad_device_info *info = pad_device_lookup(pl->vid, pl->pid);
            assert_non_null(info);
            pad_parser_init(&p, info->proto);
        }
        if (pl->kind != PAD_LINE_EVENT) continue;
        reports++;
        if (pad_parse(&p, pl->data, pl->len, &s) <= 0) continue;
        p.out_len = 0;
        changes++;
        pad_state_json(&s, pl->t, js, sizeof js);
        snprintf(want, sizeof want, "{\"pad\":1,%s\n", js + 1);
        assert_non_null(fgets(got, sizeof got, o));
        assert_string_equal(got, want);
    }
    assert_null(fgets(got, sizeof got, o)); /* nothing more */
    printf("capture: %ld reports, %ld state lines, all as the parser says\n", reports, changes);
    assert_true(changes > 0);
    free(line);
    free(pl);
    fclose(f);
    fclose(o);
}

static void test_pad_io_cli_list(void **state)
{
    (void)state;
    char cmd[600];
    static char out[8192];
    /* this machine has no pads (no hidraw, no USB): says so, exits 0 */
    snprintf(cmd, sizeof cmd, "%s/vantage pad list 2>&1", bin_dir());
    assert_int_equal(run_cmd(cmd, out, sizeof out), 0);
    if (!strstr(out, "no controllers found")) {
        printf("pad list found pads here:\n%s", out);
        skip();
    }
    assert_non_null(strstr(out, "/dev/hidraw"));
    snprintf(cmd, sizeof cmd, "%s/vantage pad list --json 2>/dev/null", bin_dir());
    assert_int_equal(run_cmd(cmd, out, sizeof out), 0);
    assert_string_equal(out, "");
    snprintf(cmd, sizeof cmd, "%s/vantage pad list --bogus 2>&1", bin_dir());
    assert_int_equal(run_cmd(cmd, out, sizeof out), 2);
}

const struct CMUnitTest pad_io_tests[] = {
    cmocka_unit_test(test_pad_io_hidraw_discovery),
    cmocka_unit_test(test_pad_io_usb_xbox),
    cmocka_unit_test(test_pad_io_unknown_ignored),
    cmocka_unit_test(test_pad_io_enumerate),
    cmocka_unit_test(test_pad_io_hidraw_replug),
    cmocka_unit_test(test_pad_io_usb_hotplug),
    cmocka_unit_test(test_pad_io_open_failure),
    cmocka_unit_test(test_pad_io_no_libusb),
    cmocka_unit_test(test_pad_io_error_rate_limit),
    cmocka_unit_test(test_pad_io_merge_slow_consumer),
    cmocka_unit_test(test_pad_io_close_while_blocked),
    cmocka_unit_test(test_pad_io_real_libraries),
    cmocka_unit_test_setup_teardown(test_pad_io_replay_timing, padio_dir, padio_dir_remove),
    cmocka_unit_test_setup_teardown(test_pad_io_replay_errors, padio_dir, padio_dir_remove),
    cmocka_unit_test_setup_teardown(test_pad_io_replay_loop_devices, padio_dir, padio_dir_remove),
    cmocka_unit_test_setup_teardown(test_pad_io_record_roundtrip, padio_dir, padio_dir_remove),
    cmocka_unit_test_setup_teardown(test_pad_io_cli_dump, padio_dir, padio_dir_remove),
    cmocka_unit_test_setup_teardown(test_pad_io_cli_capture, padio_dir, padio_dir_remove),
    cmocka_unit_test(test_pad_io_cli_list),
};
const size_t pad_io_tests_count = sizeof pad_io_tests / sizeof pad_io_tests[0];
