/*
 * test_commander.c — the commander's mapping and camera against direct
 * formulas, its config file's errors, the daemon side of commands (MARK,
 * DESTROY by role, view_seq, re-aims that do not starve the stream), and
 * `vantage commander` end to end: a replayed DualShock 4 capture drives
 * the view of a real daemon's demo city, headless (the frames and the
 * camera path checked), and in a window under Xvfb (a screenshot checked:
 * the city, the reticle, the overlay).
 */
#include "test_util.h"

#include "commander.h"
#include "test_daemon.h"
#include "vantage.h"
#include "vt_image.h"

#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <fcntl.h>
#include <unistd.h>

/* The commander tests count frames and time the camera's path: their
 * daemons draw without the two costliest effects (vantaged --fx-off), so
 * a frame under ASan on a loaded machine still takes well under the
 * tests' margins; the effects have tests of their own. */
#define CMDR_FX_OFF "shadows,ssao"

/* ---- shaping ------------------------------------------------------------------------- */

static void test_commander_stick_shape(void **state)
{
    (void)state;
    cmdr_map_cfg c;
    cmdr_map_defaults(&c);
    float x, y;
    /* inside the inner radius: nothing, whatever the direction */
    for (int i = 0; i < 64; i++) {
        double a = i * M_PI / 32, r = 0.149;
        cmdr_stick_shape(&c, (float)(r * cos(a)), (float)(r * sin(a)), &x, &y);
        assert_true(x == 0 && y == 0);
    }
    cmdr_stick_shape(&c, NAN, 0, &x, &y);
    assert_true(x == 0 && y == 0);
    /* past the outer radius: magnitude 1; the direction kept (radial: a
       diagonal pans diagonally, no axis snaps) */
    for (int i = 0; i < 64; i++) {
        double a = i * M_PI / 32;
        cmdr_stick_shape(&c, (float)(0.97 * cos(a)), (float)(0.97 * sin(a)), &x, &y);
        assert_float_equal(hypot(x, y), 1, 1e-5);
        assert_float_equal(atan2(y, x), atan2(sin(a), cos(a)), 1e-4);
    }
    /* between: ((m - inner) / (outer - inner))^curve, rising */
    double last = -1;
    for (int i = 0; i <= 100; i++) {
        double m = 0.15 + 0.8 * i / 100.0;
        cmdr_stick_shape(&c, (float)m, 0, &x, &y);
        double want = pow((m - 0.15) / 0.8, 1.7);
        assert_float_equal(x, want, 2e-5);
        assert_true(x >= last);
        last = x;
    }
    /* triggers: dead travel, then linear; hysteresis as a button */
    assert_true(cmdr_trigger_shape(&c, 0.04f) == 0);
    assert_float_equal(cmdr_trigger_shape(&c, 0.525f), 0.5, 1e-6);
    assert_true(cmdr_trigger_shape(&c, 1.0f) == 1);
    bool down = false;
    const float ramp[] = {0.3f, 0.5f, 0.56f, 0.5f, 0.46f, 0.44f, 0.5f, 0.56f};
    const bool want[] = {false, false, true, true, true, false, false, true};
    for (size_t i = 0; i < sizeof ramp / sizeof ramp[0]; i++) {
        down = cmdr_trigger_button(&c, ramp[i], down);
        assert_int_equal(down, want[i]);
    }
}

static void test_commander_config(void **state)
{
    (void)state;
    cmdr_map_cfg c, d;
    cmdr_map_defaults(&c);
    char err[256];
    const char *good = "# my pad\n dz_inner = 0.2\ncurve=2 # steeper\n\nping = west+rshoulder\nselect = none\n"
                       "destroy = rtrigger_d\ntick_hz = 240\n";
    assert_int_equal(cmdr_map_parse(&c, good, strlen(good), err, sizeof err), 0);
    assert_float_equal(c.dz_inner, 0.2, 1e-7);
    assert_float_equal(c.curve, 2, 0);
    assert_float_equal(c.tick_hz, 240, 0);
    assert_int_equal(c.bind[CMDR_PING], PAD_WEST | PAD_RSHOULDER);
    assert_int_equal(c.bind[CMDR_SELECT], 0);
    assert_int_equal(c.bind[CMDR_DESTROY], PAD_RTRIGGER_D);
    assert_int_equal(cmdr_map_load(&d, "/nonexistent/commander.conf", err, sizeof err), -1);
    assert_non_null(strstr(err, "No such file"));
}

/* Pad configuration files refused: the message names the line and the
 * setting, and a refused file changes nothing. */
typedef struct bad_config {
    const char *name, *text, *says;
} bad_config;

static const bad_config bad_configs[] = {
    {"unknown setting", "dz_inner = 0.2\nspeed = 3\n", "line 2: unknown setting \"speed\""},
    {"curve out of range", "curve = 9\n", "line 1: curve: 9 is outside 0.2..5"},
    {"curve not a number", "curve = fast\n", "line 1: curve: not a number"},
    {"no value", "curve\n", "line 1: expected NAME = VALUE"},
    {"unknown button", "ping = thumb\n", "line 1: unknown button"},
    {"a chord cut short", "ping = west+\n", "line 1: unknown button"},
    {"dead zones crossed", "dz_inner = 0.6\ndz_outer = 0.5\n", "dz_inner must be below dz_outer"},
    {"trigger hysteresis inverted", "trig_press = 0.3\n", "trig_release must be below trig_press"},
    {"empty value", "tick_hz =\n", "line 1: tick_hz: no value"},
};

static void test_commander_config_refused(void **state)
{
    const bad_config *t = *state;
    cmdr_map_cfg d;
    cmdr_map_defaults(&d);
    cmdr_map_cfg before = d;
    char err[256] = "";
    assert_int_equal(cmdr_map_parse(&d, t->text, strlen(t->text), err, sizeof err), -1);
    if (!strstr(err, t->says)) fail_msg("\"%s\": \"%s\" does not say \"%s\"", t->text, err, t->says);
    assert_memory_equal(&d, &before, sizeof d); /* a bad file changes nothing */
}

/* ---- the camera ------------------------------------------------------------------------- */

static void run_steps(const cmdr_map_cfg *c, cmdr_camera *cam, cmdr_input *in, const pad_state *s, double secs)
{
    int n = (int)lround(secs * c->tick_hz);
    cmdr_step_out o;
    for (int i = 0; i < n; i++) cmdr_step(c, cam, in, s, 1.0 / c->tick_hz, &o);
}

static void test_commander_camera(void **state)
{
    (void)state;
    cmdr_map_cfg c;
    cmdr_map_defaults(&c);
    cmdr_camera cam;
    cmdr_input in = {0};
    cam.perspective = false;
    cmdr_camera_reset(&cam, 16.0 / 9);
    /* pan: full right for 1 s moves the target pan_speed view heights
       along the screen's right, at any zoom */
    pad_state s = {.lx = 1};
    run_steps(&c, &cam, &in, &s, 1.0);
    assert_float_equal(cam.target[0], -1.2 * 320, 1e-6); /* right = (-cos yaw, 0, sin yaw) at yaw 0 */
    assert_float_equal(cam.target[2], 0, 1e-9);
    cmdr_camera_reset(&cam, 16.0 / 9);
    cam.half_h = 40;
    run_steps(&c, &cam, &in, &s, 1.0);
    assert_float_equal(cam.target[0], -1.2 * 80, 1e-6);
    /* zoom: exponential, right trigger in: e^-1.6 a second, clamped */
    cmdr_camera_reset(&cam, 16.0 / 9);
    s = (pad_state){.rt = 1};
    run_steps(&c, &cam, &in, &s, 1.0);
    assert_float_equal(cam.half_h, 160 * exp(-1.6), 1e-6);
    run_steps(&c, &cam, &in, &s, 10.0);
    assert_float_equal(cam.half_h, CMDR_MIN_ZOOM, 0);
    /* rotate and tilt, clamped to 0..60 degrees */
    cmdr_camera_reset(&cam, 16.0 / 9);
    s = (pad_state){.rx = 1};
    run_steps(&c, &cam, &in, &s, 0.5);
    assert_float_equal(cam.yaw, -1.0, 1e-9);
    s = (pad_state){.ry = 1};
    run_steps(&c, &cam, &in, &s, 0.5);
    assert_float_equal(cam.pitch, 0.6, 1e-9);
    run_steps(&c, &cam, &in, &s, 2.0);
    assert_float_equal(cam.pitch, CMDR_MAX_PITCH, 0);
    /* no pad, or a pad at rest inside the dead zone: nothing moves */
    cmdr_camera before = cam;
    cmdr_step_out o;
    cmdr_step(&c, &cam, &in, NULL, 1.0 / 120, &o);
    s = (pad_state){.lx = 0.1f, .ly = -0.1f, .lt = 0.04f};
    cmdr_step(&c, &cam, &in, &s, 1.0 / 120, &o);
    assert_false(o.moved);
    assert_memory_equal(&cam, &before, sizeof cam);
    /* actions fire on the edge, chords when all are held */
    c.bind[CMDR_PING] = PAD_WEST | PAD_RSHOULDER;
    memset(&in, 0, sizeof in);
    s = (pad_state){.buttons = PAD_SOUTH};
    cmdr_step(&c, &cam, &in, &s, 1.0 / 120, &o);
    assert_int_equal(o.fired, 1u << CMDR_SELECT);
    cmdr_step(&c, &cam, &in, &s, 1.0 / 120, &o);
    assert_int_equal(o.fired, 0); /* held: no repeat */
    s.buttons = PAD_WEST;
    cmdr_step(&c, &cam, &in, &s, 1.0 / 120, &o);
    assert_int_equal(o.fired, 0);
    s.buttons = PAD_WEST | PAD_RSHOULDER;
    cmdr_step(&c, &cam, &in, &s, 1.0 / 120, &o);
    assert_int_equal(o.fired, (1u << CMDR_PING) | (1u << CMDR_GROUP_NEXT));
    /* a trigger bound as a button, with hysteresis */
    c.bind[CMDR_DESTROY] = PAD_RTRIGGER_D;
    s = (pad_state){.rt = 0.6f};
    cmdr_step(&c, &cam, &in, &s, 1.0 / 120, &o);
    assert_true(o.fired & 1u << CMDR_DESTROY);
    s.rt = 0.5f;
    cmdr_step(&c, &cam, &in, &s, 1.0 / 120, &o);
    s.rt = 0.6f;
    cmdr_step(&c, &cam, &in, &s, 1.0 / 120, &o);
    assert_false(o.fired & 1u << CMDR_DESTROY); /* 0.5 did not release it */

    /* the view: the target projects to the frame's centre, in both modes;
       the pick box holds the reticle's ray; a box under it is hit first
       at its top */
    for (int persp = 0; persp < 2; persp++) {
        cmdr_camera_reset(&cam, 16.0 / 9);
        cam.perspective = persp;
        cam.target[0] = 120;
        cam.target[2] = -40;
        cam.yaw = 0.7;
        cam.pitch = persp ? 0.5 : 0;
        double px, py;
        assert_true(cmdr_camera_project(&cam, 1280, 720, cam.target, &px, &py));
        assert_float_equal(px, 640, 1e-6);
        assert_float_equal(py, 360, 1e-6);
        /* a point 10 m along the screen's up lands above the centre */
        double up[3] = {cam.target[0] + 10 * sin(cam.yaw), 0, cam.target[2] + 10 * cos(cam.yaw)};
        assert_true(cmdr_camera_project(&cam, 1280, 720, up, &px, &py));
        assert_float_equal(px, 640, 1e-6);
        assert_true(py < 360);
        double eye[3], dir[3], t;
        cmdr_camera_ray(&cam, eye, dir);
        double lo[3] = {cam.target[0] - 1, 0, cam.target[2] - 1}, hi[3] = {cam.target[0] + 1, 7, cam.target[2] + 1};
        assert_true(cmdr_ray_box(eye, dir, lo, hi, &t));
        double hit_y = eye[1] + t * dir[1];
        if (!persp) assert_float_equal(hit_y, 7, 1e-6); /* straight down: the roof */
        double far_lo[3] = {cam.target[0] + 50, 0, cam.target[2] + 50}, far_hi[3] = {cam.target[0] + 52, 7, cam.target[2] + 52};
        assert_false(cmdr_ray_box(eye, dir, far_lo, far_hi, &t));
        vp_view v;
        assert_true(cmdr_pick_view(&cam, 2, &v));
        assert_true(cmdr_camera_view(&cam, 1280, 720, &v));
    }
    /* latency percentiles, nearest rank */
    static cmdr_lat l;
    memset(&l, 0, sizeof l);
    assert_true(isnan(cmdr_lat_pct(&l, 50)));
    for (int i = 1; i <= 100; i++) cmdr_lat_add(&l, i);
    assert_float_equal(cmdr_lat_pct(&l, 50), 50, 0);
    assert_float_equal(cmdr_lat_pct(&l, 95), 95, 0);
    assert_float_equal(cmdr_lat_pct(&l, 100), 100, 0);
}

/* ---- the daemon side of commands ------------------------------------------------------ */

static void test_commander_daemon_commands(void **state)
{
    daemon_proc *d = *state;
    vtc_client *ed = connect_role(d, VP_ROLE_EDITOR, false);
    vp_entity e = {.id = 7, .aabb = {0, 0, 0, 10, 10, 10}};
    uint32_t h;
    assert_int_equal(vtc_add(ed, &e, 1, &h, NULL), VP_OK);
    vtc_client *view = connect_role(d, VP_ROLE_VIEWER, false), *cmd = connect_role(d, VP_ROLE_COMMANDER, true),
              *other = connect_role(d, VP_ROLE_COMMANDER, false);
    /* a viewer may neither mark nor destroy */
    vp_mark mk = {.pos = {5, 10, 5}, .entity = 7, .kind = 0, .ttl_ms = 1000};
    assert_int_equal(vtc_mark(view, &mk, NULL), VP_ERR_AUTH);
    vp_destroy ds = {.id = 7, .center = {5, 10, 5}, .radius = 2};
    vp_destroyed dd;
    assert_int_equal(vtc_send_destruction(view, &ds, &dd), VP_ERR_AUTH);
    /* a commander may; marks reach the subscribers, the sender's own included */
    assert_int_equal(vtc_subscribe(cmd, VP_EVENT_MARKS), VP_OK);
    assert_int_equal(vtc_subscribe(other, VP_EVENT_MARKS | VP_EVENT_SCENE), VP_OK);
    uint32_t sent = 0;
    assert_int_equal(vtc_mark(cmd, &mk, &sent), VP_OK);
    assert_int_equal(sent, 2);
    vp_header hd;
    const uint8_t *p;
    assert_int_equal(vtc_recv(other, &hd, &p, 5000), VP_OK);
    assert_int_equal(hd.type, VP_MARKED);
    vp_marked got;
    assert_int_equal(vp_dec_marked(p, hd.len, &got), VP_OK);
    assert_int_equal(got.client_id, vtc_server(cmd)->client_id);
    assert_memory_equal(got.m.pos, mk.pos, sizeof mk.pos);
    assert_true(got.m.entity == 7 && got.m.ttl_ms == 1000);
    assert_int_equal(vtc_send_destruction(cmd, &ds, &dd), VP_OK);
    assert_int_equal(dd.spheres, 1);
    /* bad marks are refused with the code, the connection stays */
    vp_mark bad = mk;
    bad.ttl_ms = 0;
    assert_int_equal(vtc_mark(cmd, &bad, NULL), VP_ERR_INVALID);
    assert_int_equal(vtc_ping(cmd), VP_OK);
    vtc_close(view);
    vtc_close(cmd);
    vtc_close(other);
    vtc_close(ed);
}

/* Re-aims at 120 Hz for 1.5 s on a daemon whose frames take longer than
 * that: frames keep coming (a re-aim keeps the frame being drawn), each
 * carrying the view_seq it was drawn for, never falling. At least 5
 * frames come while the re-aims go on: in 1.5 s in a release build
 * (about 40), in up to 6 s where frames are slow (ASan on a loaded
 * machine: about 0.5 s a frame); a stream that re-aims starve shows none
 * after the first. */
static void test_commander_reaim_keeps_frames(void **state)
{
    (void)state;
    daemon_proc d;
    daemon_start_args(&d, (const char *const[]){"--scene", "demo", "--props", "2000", "--fx-off", CMDR_FX_OFF, NULL});
    vtc_client *c = connect_role(&d, VP_ROLE_COMMANDER, false);
    cmdr_camera cam;
    cam.perspective = false;
    cmdr_camera_reset(&cam, 16.0 / 9);
    vp_frame_sub fs = {.r = {.format = VP_FRAME_JPEG, .quality = 80}, .max_fps = 240};
    uint8_t buf[VP_HEADER_SIZE + VP_FRAME_SUB_SIZE];
    uint16_t seq = 0, last_seen = 0;
    uint32_t frames = 0, acks = 0, sent = 0;
    double t0 = test_now_s(), next = t0;
    while (test_now_s() - t0 < 1.5 || (frames < 5 && test_now_s() - t0 < 6)) {
        if (test_now_s() >= next) {
            cam.target[0] += 2;
            assert_true(cmdr_camera_view(&cam, 480, 270, &fs.r.view)); /* small: ASan's frames */
            fs.view_seq = ++seq;
            vp_writer w;
            vp_writer_init(&w, buf, sizeof buf);
            vp_enc_frame_sub(&w, vtc_next_req(c), &fs);
            assert_int_equal(vtc_send(c, buf, w.len), VP_OK);
            sent++;
            next += 1.0 / 120;
        }
        vp_header h;
        const uint8_t *p;
        int rc = vtc_recv(c, &h, &p, 1);
        if (rc == VP_NEED_MORE || (rc == VTC_ERR_IO && vtc_last_error(c)->timed_out)) continue;
        assert_int_equal(rc, VP_OK);
        if (h.type == VP_ACK) acks++;
        if (h.type != VP_FRAME) continue;
        vp_frame f;
        assert_int_equal(vp_dec_frame(p, h.len, &f), VP_OK);
        assert_true(f.view_seq >= last_seen && f.view_seq <= seq);
        last_seen = f.view_seq;
        frames++;
    }
    print_message("re-aims %u, acks %u, frames %u in %.1f s, last view_seq %u of %u\n", sent, acks, frames,
                  test_now_s() - t0, last_seen, seq);
    assert_true(frames >= 5);
    assert_true(last_seen > seq / 2);
    daemon_close(&d, c);
}

/* ---- vantage commander, end to end ---------------------------------------------------- */

static const char *capture(void)
{
    static char path[512];
    const char *dd = getenv("VANTAGE_DATA_DIR");
    snprintf(path, sizeof path, "%s/pads/ds4_commander_walk.hidrec", dd ? dd : "tests/data");
    return path;
}

/* The camera state of frames.jsonl's line for the frame nearest t. */
typedef struct fr_line {
    double t, target[3], yaw, pitch, half_h;
    unsigned view_seq;
} fr_line;

static int read_frames(const char *path, fr_line *out, int max)
{
    FILE *f = fopen(path, "r");
    assert_non_null(f);
    char line[1024];
    int n = 0;
    while (n < max && fgets(line, sizeof line, f)) {
        fr_line *l = &out[n];
        const char *q;
        if (!(q = strstr(line, "\"t\":")) || sscanf(q, "\"t\":%lf", &l->t) != 1) continue;
        if (!(q = strstr(line, "\"view_seq\":")) || sscanf(q, "\"view_seq\":%u", &l->view_seq) != 1) continue;
        if (!(q = strstr(line, "\"target\":")) ||
            sscanf(q, "\"target\":[%lf,%lf,%lf]", &l->target[0], &l->target[1], &l->target[2]) != 3)
            continue;
        if (!(q = strstr(line, "\"yaw\":")) || sscanf(q, "\"yaw\":%lf", &l->yaw) != 1) continue;
        if (!(q = strstr(line, "\"half_h\":")) || sscanf(q, "\"half_h\":%lf", &l->half_h) != 1) continue;
        n++;
    }
    fclose(f);
    return n;
}

static void test_commander_replay_headless(void **state)
{
    (void)state;
    daemon_proc d;
    daemon_start_args(&d, (const char *const[]){"--scene", "demo", "--props", "2000", "--fx-off", CMDR_FX_OFF, NULL});
    tdir td;
    tdir_make(&td, "vantage_commander");
    const char *dir = td.dir; /* the frames and frames.jsonl go here */
    char out[8192];
    /* 480x270: the scene model's textured city costs about 1 s a 1280x720
       frame under ASan; the camera path does not depend on the size */
    int st = vantage_run(&d, out, sizeof out, "commander --replay %s --headless %s --seconds 7 --size 480x270 --json",
                         capture(), dir);
    if (st) fail_msg("commander --replay %s: exit %d: %s", capture(), st, out);
    /* the stats: frames shown, latency samples taken */
    const char *js = strstr(out, "{\"seconds\"");
    if (!js) fail_msg("no stats: %s", out);
    unsigned long long frames = 0, samples = 0;
    assert_int_equal(sscanf(strstr(js, "\"frames\":"), "\"frames\":%llu", &frames), 1);
    assert_int_equal(sscanf(strstr(js, "\"samples\":"), "\"samples\":%llu", &samples), 1);
    print_message("%s", js);
    assert_true(frames >= 20);
    /* a sample per report that changed the pad and moved the view: the
       walk's four starts of motion at least (a held stick sends the same
       state; the latency bench's capture varies every report) */
    assert_true(samples >= 4);
    /* the camera path in frames.jsonl follows the capture: pan right 0.5 s
       (-x at yaw 0: 1.2 view heights a second, 320 m high: -192 m), then
       forward 0.5 s (+z, 192 m), zoom in 1 s (x e^-1.6), rotate 1 s (-2
       rad), zoom out 0.5 s (x e^0.8) */
    static fr_line fl[4096];
    char path[600];
    snprintf(path, sizeof path, "%s/frames.jsonl", dir);
    int n = read_frames(path, fl, 4096);
    assert_true(n >= 20);
    const fr_line *last = &fl[n - 1];
    print_message("last frame: target %.1f %.1f %.1f yaw %.3f half_h %.1f\n", last->target[0], last->target[1],
                  last->target[2], last->yaw, last->half_h);
    /* each leg within 6 % (the replay's and the tick's timing on a busy machine) */
    assert_float_equal(last->target[0], -192, 0.06 * 192);
    assert_float_equal(last->target[2], 192, 0.06 * 192);
    assert_float_equal(last->yaw, remainder(-2.0, 2 * M_PI), 0.06 * 2);
    /* zoomed in for 1 s and out for 0.5 s: 160 e^(-1.6 + 0.8) */
    assert_float_equal(last->half_h, 160 * exp(-0.8), 0.1 * 160 * exp(-0.8));
    /* frames arrive in view order and the first is the start position */
    for (int i = 1; i < n; i++) assert_true(fl[i].view_seq >= fl[i - 1].view_seq);
    assert_float_equal(fl[0].target[0], 0, 1e-9);
    /* the last frame decodes and is not one flat colour: the city */
    snprintf(path, sizeof path, "%s/frame-%06d.jpg", dir, n - 1);
    uint8_t *rgb;
    uint32_t w, h;
    char err[256];
    if (vt_jpeg_read(path, &rgb, &w, &h, err, sizeof err)) fail_msg("%s", err);
    assert_int_equal(w, 480);
    assert_int_equal(h, 270);
    uint32_t lo = 255, hi = 0;
    for (size_t i = 0; i < (size_t)w * h * 3; i += 3 * 97) {
        lo = rgb[i] < lo ? rgb[i] : lo;
        hi = rgb[i] > hi ? rgb[i] : hi;
    }
    free(rgb);
    assert_true(hi - lo > 40);
    /* bad input: a capture with a malformed line is refused, naming it */
    char bad[400];
    snprintf(bad, sizeof bad, "%s/bad.hidrec", dir);
    FILE *f = fopen(bad, "w");
    fprintf(f, "I: 3 054c 09cc\nE: 0.000000 64 01 80\n");
    fclose(f);
    st = vantage_run(&d, out, sizeof out, "commander --replay %s --headless %s --seconds 1", bad, dir);
    assert_int_not_equal(st, 0);
    if (!strstr(out, "bad.hidrec:2:")) fail_msg("\"%s\" does not name the line", out);
    daemon_stop(&d);
    tdir_remove(&td);
}

/* The daemon goes away and comes back: the client keeps running, says so,
 * reconnects with backoff and frames come again. */
static void test_commander_reconnects(void **state)
{
    (void)state;
    daemon_proc d;
    daemon_start_args(&d, (const char *const[]){"--scene", "demo", "--props", "200", "--fx-off", CMDR_FX_OFF, NULL});
    tdir td;
    tdir_make(&td, "vantage_commander_rc");
    char cmd[2048], outp[400];
    snprintf(outp, sizeof outp, "%s/out.txt", td.dir);
    snprintf(cmd, sizeof cmd,
             "%s/vantage -p %d commander --replay %s --loop --headless %s --seconds 6 --size 480x270 --json > %s 2>&1",
             bin_dir(), d.port, capture(), td.dir, outp);
    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        execl("/bin/sh", "sh", "-c", cmd, (char *)NULL);
        _exit(127);
    }
    sleep(2);
    int port = d.port;
    daemon_stop(&d);
    sleep(1);
    /* the same port again */
    daemon_proc d2;
    for (int tries = 0;; tries++) {
        daemon_start_args(&d2, (const char *const[]){"--scene", "demo", "--props", "200", "--fx-off", CMDR_FX_OFF, NULL});
        if (d2.port == port || tries > 50) break;
        daemon_stop(&d2);
    }
    int st;
    waitpid(pid, &st, 0);
    char out[8192];
    FILE *f = fopen(outp, "r");
    size_t n = fread(out, 1, sizeof out - 1, f);
    out[n] = 0;
    fclose(f);
    if (!WIFEXITED(st) || WEXITSTATUS(st)) fail_msg("commander: status %d: %s", st, out);
    assert_non_null(strstr(out, "connection lost"));
    if (d2.port == port) assert_non_null(strstr(out, "connected (client"));
    daemon_stop(&d2);
    tdir_remove(&td);
}

/* Under Xvfb, a window: the screenshot shows the city with the reticle and
 * the overlay's text. Skipped where there is no Xvfb. */
static void test_commander_window_xvfb(void **state)
{
    (void)state;
    if (system("command -v Xvfb >/dev/null 2>&1")) skip();
    int disp = 90 + (int)(getpid() % 500);
    char dname[32];
    snprintf(dname, sizeof dname, ":%d", disp);
    pid_t x = fork();
    assert_true(x >= 0);
    if (x == 0) {
        int null = open("/dev/null", O_WRONLY);
        dup2(null, 1);
        dup2(null, 2);
        execlp("Xvfb", "Xvfb", dname, "-screen", "0", "1280x720x24", "-nolisten", "tcp", (char *)NULL);
        _exit(127);
    }
    char lock[64];
    snprintf(lock, sizeof lock, "/tmp/.X11-unix/X%d", disp);
    for (int i = 0; i < 300 && access(lock, F_OK); i++) usleep(10000);
    daemon_proc d;
    daemon_start_args(&d, (const char *const[]){"--scene", "demo", "--props", "2000", "--fx-off", CMDR_FX_OFF, NULL});
    tdir td;
    tdir_make(&td, "vantage_commander_x");
    char png[400];
    snprintf(png, sizeof png, "%s/shot.png", td.dir);
    char cmd[2048], out[8192];
    /* under ASan, no leak check for this run: X11, D-Bus and the GL
       drivers SDL loads keep allocations to exit, some from modules
       already unloaded (no name to suppress by); the headless tests check
       the client's own code for leaks */
    snprintf(cmd, sizeof cmd,
             "DISPLAY=%s SDL_VIDEODRIVER=x11 ASAN_OPTIONS=\"$ASAN_OPTIONS:detect_leaks=0\" "
             "%s/vantage -p %d commander --replay %s --seconds 7 --screenshot %s 2>&1",
             dname, bin_dir(), d.port, capture(), png);
    int st = test_run_cmd(cmd, out, sizeof out);
    kill(x, SIGTERM);
    waitpid(x, NULL, 0);
    if (st) fail_msg("%s: exit %d: %s", cmd, st, out);
    uint8_t *px;
    uint32_t w, h;
    char err[256];
    if (vt_png_read(png, &px, &w, &h, NULL, err, sizeof err)) fail_msg("%s", err);
    assert_int_equal(w, 1280);
    assert_int_equal(h, 720);
    /* the reticle: white arms 6..18 px from the centre */
    const uint8_t *c = px + 4 * ((size_t)360 * w + 640 + 12);
    if (!(c[0] > 200 && c[1] > 200 && c[2] > 200)) fail_msg("no reticle: %u %u %u", c[0], c[1], c[2]);
    /* the overlay's text box in the top left: dark with white glyphs */
    uint32_t bright = 0;
    for (uint32_t y = 8; y < 24; y++)
        for (uint32_t xx = 10; xx < 300; xx++) bright += px[4 * ((size_t)y * w + xx)] > 200;
    assert_true(bright > 50);
    /* the city: many colours across the picture */
    uint32_t lo = 255, hi = 0;
    for (size_t i = 0; i < (size_t)w * h * 4; i += 4 * 101) {
        lo = px[i + 1] < lo ? px[i + 1] : lo;
        hi = px[i + 1] > hi ? px[i + 1] : hi;
    }
    free(px);
    assert_true(hi - lo > 40);
    daemon_stop(&d);
    if (getenv("VANTAGE_KEEP_SHOT")) {
        char keep[600];
        snprintf(keep, sizeof keep, "cp %s %s", png, getenv("VANTAGE_KEEP_SHOT"));
        if (system(keep)) print_message("could not keep the screenshot\n");
    }
    tdir_remove(&td);
}

const struct CMUnitTest commander_tests[] = {
    cmocka_unit_test(test_commander_stick_shape),
    cmocka_unit_test(test_commander_config),
    TEST_ROWS(test_commander_config_refused, bad_configs),
    cmocka_unit_test(test_commander_camera),
    DAEMON_TEST(test_commander_daemon_commands),
    cmocka_unit_test(test_commander_reaim_keeps_frames),
    cmocka_unit_test(test_commander_replay_headless),
    cmocka_unit_test(test_commander_reconnects),
    cmocka_unit_test(test_commander_window_xvfb),
};
const size_t commander_tests_count = sizeof commander_tests / sizeof commander_tests[0];
