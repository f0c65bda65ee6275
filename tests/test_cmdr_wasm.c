/*
 * test_cmdr_wasm.c — the browser's commander rules are the native ones:
 * web/js/cmdr.js over web/js/cmdr.wasm (pad_map.c and what it calls,
 * compiled by clang to WebAssembly) against pad_map.c as this binary links
 * it, the independent model. One scripted session of ops (the defaults,
 * then configs with rebinds, chords and bad lines; sticks swept in and out
 * of the dead zone at many angles, diagonals, triggers walked across the
 * hysteresis band, chords held and released, steps of odd lengths, the
 * mouse's wheel and clicks, toggles and resets, views of many sizes, pick
 * views, rays, projections, ray-box hits and misses, latency rings) goes
 * to `node tests/cmdr_wasm.mjs` and is run here; every result line must
 * agree: integers, actions and error texts exactly, doubles by their bits
 * or within CMDR_WASM_TOL (the two libms' sin, cos, tan and exp).
 * The view bytes are checked against vp_view's fields laid out as
 * PROTOCOL.md's view record (not the protocol's encoder, which the wasm
 * uses). The gamepad ops give a standard-mapping Gamepad object to
 * cmdr.js's adapter; the model maps it with the W3C table written here.
 * The key ops give KeyboardEvent.code names to cmdr.js; the model steps
 * what the SDL window's keys make of them (cmdr_key_table, checked against
 * the HID usage numbers in test_cmdr_wasm_keys_table). Bad values (NaN,
 * infinities, sizes out of range, a config over 16 KiB, hostile Gamepad
 * objects) get null or an error, never a trap or a non-finite camera.
 *
 * Skips when node or cmdr.wasm is missing (make deps, make all). About
 * 4,000 ops: ~0.2 s (node's start and the compile of the module dominate).
 */
#include "test_util.h"
#include "commander.h"
#include "vp_bytes.h"

#include <inttypes.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

/* How far a double of the wasm's may be from the native one. wasi-libc
 * is musl, whose sin, cos, tan and exp are within 1 ulp as glibc's are
 * but not always the same ulp: over 200,000 random arguments in the ranges
 * pad_map.c uses, sin differed in 3.0 %, cos 3.1 %, tan 3.6 %, exp 0.06 %,
 * each by 1 ulp; pow (0.85^n), powf, sqrtf and remainder never (they are
 * exact, or the same ARM code in both). An ulp in sin(yaw) moves each
 * later pan by an ulp of the step, so the target drifts by the sum; and a
 * view coefficient that cancels to 0 on one side may be 1e-18 on the
 * other. So: |a - b| <= 1e-11 max(1, |a|), metres, radians, pixels or
 * matrix coefficients alike. Over nine seeds the worst was 5.7e-14 (1 to
 * 3 % of the lines differ at all; the test prints the worst), so this is
 * 175 times that, and 10^4 below what any change of a rule makes (a float
 * for a double is 1e-7; a constant, a sign, a clamp far more); integers,
 * actions, flags and error texts must agree exactly. */
#define CMDR_WASM_TOL 1e-11

typedef struct model {
    cmdr_map_cfg cfg;
    cmdr_camera cam;
    cmdr_input in;
    cmdr_lat lat[8];
    FILE *ops;            /* to node */
    char *want;           /* the expected lines */
    size_t len, cap;
    rng r;
} model;

static void want(model *m, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void want(model *m, const char *fmt, ...)
{
    va_list ap;
    for (;;) {
        va_start(ap, fmt);
        int n = vsnprintf(m->want + m->len, m->cap - m->len, fmt, ap);
        va_end(ap);
        assert_true(n >= 0);
        if ((size_t)n < m->cap - m->len) {
            m->len += (size_t)n;
            return;
        }
        m->cap = m->cap * 2 + (size_t)n + 1;
        m->want = realloc(m->want, m->cap);
        assert_non_null(m->want);
    }
}

/* A number's bits, through the protocol's little-endian byte writer */
static uint64_t bits64(double d)
{
    uint8_t b[8];
    vp_st_f64(b, d);
    return vp_ld_u64(b);
}

static uint32_t bits32(float f)
{
    uint8_t b[4];
    vp_st_f32(b, f);
    return vp_ld_u32(b);
}

static void want_cam(model *m)
{
    const cmdr_camera *c = &m->cam;
    want(m, " %016" PRIx64 " %016" PRIx64 " %016" PRIx64 " %016" PRIx64 " %016" PRIx64 " %016" PRIx64 " %d %016" PRIx64 "\n",
         bits64(c->target[0]), bits64(c->target[1]), bits64(c->target[2]), bits64(c->yaw), bits64(c->pitch),
         bits64(c->half_h), c->perspective ? 1 : 0, bits64(c->aspect));
}

/* A view as PROTOCOL.md lays the record out: origin and view_proj as
 * little-endian doubles (their bits here), then depth_mode, a pad byte,
 * viewport_w and viewport_h (u16 LE) and two pad bytes. */
static void want_view(model *m, bool ok, const vp_view *v)
{
    if (!ok) {
        want(m, "V -\n");
        return;
    }
    want(m, "V");
    for (int i = 0; i < 3; i++) want(m, " %016" PRIx64, bits64(v->origin[i]));
    for (int i = 0; i < 16; i++) want(m, " %016" PRIx64, bits64(v->view_proj[i]));
    want(m, " t%02x00%02x%02x%02x%02x0000\n", v->depth_mode, v->viewport_w & 0xff, v->viewport_w >> 8,
         v->viewport_h & 0xff, v->viewport_h >> 8);
}

/* ---- the ops: each written for node and run on the model -------------------------------- */

static void op_init(model *m, double aspect)
{
    fprintf(m->ops, "I %016" PRIx64 "\n", bits64(aspect));
    cmdr_map_defaults(&m->cfg);
    m->cam = (cmdr_camera){0};
    cmdr_camera_reset(&m->cam, aspect);
    m->in = (cmdr_input){0};
    memset(m->lat, 0, sizeof m->lat);
    want(m, "I");
    want_cam(m);
}

static void op_config(model *m, const char *text, size_t len)
{
    fprintf(m->ops, "C ");
    for (size_t i = 0; i < len; i++) fprintf(m->ops, "%02x", (unsigned char)text[i]);
    fprintf(m->ops, "%s\n", len ? "" : "-");
    char err[256] = "";
    int rc = cmdr_map_parse(&m->cfg, text, len, err, sizeof err);
    want(m, "C %d %016" PRIx64, rc, bits64(m->cfg.tick_hz));
    for (int a = 0; a < CMDR_ACTION_COUNT; a++) want(m, " %" PRIu32, m->cfg.bind[a]);
    want(m, "%s%s\n", rc ? " " : "", rc ? err : "");
}

static void step_model(model *m, const pad_state *s, double dt)
{
    cmdr_step_out o;
    cmdr_step(&m->cfg, &m->cam, &m->in, s, dt, &o);
    want(m, "S %" PRIu32 " %d", o.fired, o.moved ? 1 : 0);
    want_cam(m);
}

static void op_step(model *m, uint32_t buttons, float lx, float ly, float rx, float ry, float lt, float rt, double dt)
{
    fprintf(m->ops, "S %" PRIx32 " %08" PRIx32 " %08" PRIx32 " %08" PRIx32 " %08" PRIx32 " %08" PRIx32 " %08" PRIx32
                    " %016" PRIx64 "\n",
            buttons, bits32(lx), bits32(ly), bits32(rx), bits32(ry), bits32(lt), bits32(rt), bits64(dt));
    pad_state s;
    pad_state_init(&s);
    s.buttons = buttons;
    s.lx = lx, s.ly = ly, s.rx = rx, s.ry = ry, s.lt = lt, s.rt = rt;
    step_model(m, &s, dt);
}

/* The W3C Gamepad "standard" layout (w3c.github.io/gamepad, "Remapping"):
 * button index -> pad.h's button by position; 17 is Chromium's touchpad. */
static const uint32_t w3c_standard[18] = {
    PAD_SOUTH,      PAD_EAST,      PAD_WEST,     PAD_NORTH,  PAD_LSHOULDER,  PAD_RSHOULDER,
    PAD_LTRIGGER_D, PAD_RTRIGGER_D, PAD_BACK,    PAD_START,  PAD_LSTICK,     PAD_RSTICK,
    PAD_DPAD_UP,    PAD_DPAD_DOWN, PAD_DPAD_LEFT, PAD_DPAD_RIGHT, PAD_GUIDE, PAD_TOUCHPAD,
};

/* A standard Gamepad: pressed (bit i = button i), axes as the browser
 * gives them (y down), the triggers' values. */
static void op_gamepad(model *m, uint32_t pressed, const float ax[4], float v6, float v7, double dt)
{
    fprintf(m->ops, "G %" PRIx32 " %08" PRIx32 " %08" PRIx32 " %08" PRIx32 " %08" PRIx32 " %08" PRIx32 " %08" PRIx32
                    " %016" PRIx64 "\n",
            pressed, bits32(ax[0]), bits32(ax[1]), bits32(ax[2]), bits32(ax[3]), bits32(v6), bits32(v7), bits64(dt));
    pad_state s;
    pad_state_init(&s);
    for (int i = 0; i < 18; i++)
        if (pressed & (1u << i)) s.buttons |= w3c_standard[i];
    s.lx = ax[0], s.ly = -ax[1], s.rx = ax[2], s.ry = -ax[3], s.lt = v6, s.rt = v7;
    step_model(m, &s, dt);
}

/* Held keys by their KeyboardEvent.code through cmdr.js's padFromKeys;
 * the model as commander.c steps the SDL window's keys (NULL: none held). */
static void op_keys(model *m, uint32_t down, double dt)
{
    fprintf(m->ops, "Y %016" PRIx64, bits64(dt));
    bool d[CMDR_KEYS];
    for (int i = 0; i < CMDR_KEYS; i++) {
        d[i] = (down >> i) & 1;
        if (d[i]) fprintf(m->ops, " %s", cmdr_key_table[i].code);
    }
    fprintf(m->ops, "\n");
    pad_state s;
    bool any = cmdr_keys_pad(d, &s);
    step_model(m, any ? &s : NULL, dt);
}

static void op_none(model *m, double dt)
{
    fprintf(m->ops, "N %016" PRIx64 "\n", bits64(dt));
    step_model(m, NULL, dt);
}

static void op_view(model *m, uint32_t w, uint32_t h)
{
    fprintf(m->ops, "V %" PRIu32 " %" PRIu32 "\n", w, h);
    vp_view v;
    bool ok = cmdr_camera_view(&m->cam, w, h, &v);
    want_view(m, ok, &v);
}

static void op_pick(model *m, double size)
{
    fprintf(m->ops, "P %016" PRIx64 "\n", bits64(size));
    vp_view v;
    bool ok = size > 0 && cmdr_pick_view(&m->cam, size, &v);
    want_view(m, ok, &v);
}

static void op_ray(model *m)
{
    fprintf(m->ops, "R\n");
    double e[3], d[3];
    cmdr_camera_ray(&m->cam, e, d);
    want(m, "R");
    for (int i = 0; i < 3; i++) want(m, " %016" PRIx64, bits64(e[i]));
    for (int i = 0; i < 3; i++) want(m, " %016" PRIx64, bits64(d[i]));
    want(m, "\n");
}

static void op_project(model *m, const double p[3], uint32_t w, uint32_t h)
{
    fprintf(m->ops, "J %016" PRIx64 " %016" PRIx64 " %016" PRIx64 " %" PRIu32 " %" PRIu32 "\n", bits64(p[0]),
            bits64(p[1]), bits64(p[2]), w, h);
    double x, y;
    if (cmdr_camera_project(&m->cam, w, h, p, &x, &y)) want(m, "J %016" PRIx64 " %016" PRIx64 "\n", bits64(x), bits64(y));
    else want(m, "J -\n");
}

static void op_ray_box(model *m, const double o[3], const double d[3], const double lo[3], const double hi[3])
{
    fprintf(m->ops, "B");
    const double *v[4] = {o, d, lo, hi};
    for (int k = 0; k < 4; k++)
        for (int i = 0; i < 3; i++) fprintf(m->ops, " %016" PRIx64, bits64(v[k][i]));
    fprintf(m->ops, "\n");
    double t;
    if (cmdr_ray_box(o, d, lo, hi, &t)) want(m, "B %016" PRIx64 "\n", bits64(t));
    else want(m, "B -\n");
}

static void op_wheel(model *m, int n)
{
    fprintf(m->ops, "W %d\n", n);
    cmdr_camera_wheel(&m->cam, n);
    want(m, "K");
    want_cam(m);
}

static void op_click(model *m, uint32_t w, uint32_t h, double x, double y)
{
    fprintf(m->ops, "K %" PRIu32 " %" PRIu32 " %016" PRIx64 " %016" PRIx64 "\n", w, h, bits64(x), bits64(y));
    cmdr_camera_click(&m->cam, w, h, x, y);
    want(m, "K");
    want_cam(m);
}

static void op_toggle(model *m)
{
    fprintf(m->ops, "T\n");
    cmdr_camera_toggle(&m->cam);
    want(m, "K");
    want_cam(m);
}

static void op_reset(model *m, double aspect)
{
    fprintf(m->ops, "Z %016" PRIx64 "\n", bits64(aspect));
    cmdr_camera_reset(&m->cam, aspect > 0 ? aspect : m->cam.aspect);
    want(m, "K");
    want_cam(m);
}

static void op_lat(model *m, uint32_t ring, double ms)
{
    fprintf(m->ops, "L %" PRIu32 " %016" PRIx64 "\n", ring, bits64(ms));
    if (ring < 8) cmdr_lat_add(&m->lat[ring], ms);
}

static void op_pct(model *m, uint32_t ring, double p)
{
    fprintf(m->ops, "Q %" PRIu32 " %016" PRIx64 "\n", ring, bits64(p));
    double v = ring < 8 ? cmdr_lat_pct(&m->lat[ring], p) : NAN;
    if (isnan(v)) v = NAN; /* one NaN's bits: JavaScript's */
    want(m, "Q %016" PRIx64 " %" PRIu32 "\n", bits64(v), ring < 8 ? m->lat[ring].n : 0);
}

/* Bad values on an instance of their own (cmdr_wasm.mjs's hostile()). */
static void op_hostile(model *m)
{
    fprintf(m->ops, "X\n");
    want(m, "X ok\n");
}

/* ---- the script ----------------------------------------------------------------------------- */

/* After a step now and then: the queries a page makes. */
static void queries(model *m)
{
    rng *r = &m->r;
    op_view(m, 1280, 720);
    op_view(m, 1 + rng_below(r, 4096), 1 + rng_below(r, 4096));
    op_pick(m, rng_log(r, 0.01, 500));
    op_ray(m);
    double p[3] = {m->cam.target[0] + rng_range(r, -300, 300), rng_range(r, -20, 80),
                   m->cam.target[2] + rng_range(r, -300, 300)};
    op_project(m, p, 1280, 720);
    double e[3], d[3];
    cmdr_camera_ray(&m->cam, e, d);
    double lo[3], hi[3];
    for (int i = 0; i < 3; i++) {
        double c = m->cam.target[i] + rng_range(r, -30, 30), s = rng_range(r, 0.5, 40);
        lo[i] = c - s, hi[i] = c + s;
    }
    op_ray_box(m, e, d, lo, hi);
}

static float axis(rng *r) { return (float)rng_range(r, -1, 1); }

static void sweep_sticks(model *m, double dt)
{
    /* magnitudes across the dead zone (inner 0.15/0.2, outer 0.9/0.95) at
       angles all round, diagonals included (|v| up to sqrt 2 where both
       axes are at 1) */
    for (int k = 0; k < 240; k++) {
        double ang = k * 2.399963, mag = 0.05 + 1.35 * (k % 24) / 23.0; /* golden angle */
        float x = (float)fmax(-1, fmin(1, mag * cos(ang))), y = (float)fmax(-1, fmin(1, mag * sin(ang)));
        if (k % 2) op_step(m, 0, x, y, 0, 0, 0, 0, dt);
        else op_step(m, 0, 0, 0, x, y, 0, 0, dt);
        if (k % 7 == 0) queries(m);
    }
    const float diag[][2] = {{1, 1}, {-1, 1}, {0.7071f, -0.7071f}, {0.1f, 0.1f}, {0.11f, 0.11f}, {0.15f, 0}, {0.1501f, 0}};
    for (size_t i = 0; i < sizeof diag / sizeof diag[0]; i++) {
        op_step(m, 0, diag[i][0], diag[i][1], diag[i][1], diag[i][0], 0, 0, dt);
        queries(m);
    }
}

static void walk_triggers(model *m, double dt)
{
    /* across the band (release 0.45, press 0.55 by default) and back, with
       values at and about the edges, each trigger alone and both */
    const float walk[] = {0, 0.04f, 0.05f, 0.06f, 0.3f, 0.44f, 0.45f, 0.5f, 0.55f, 0.56f, 0.5f, 0.46f, 0.45f,
                          0.449f, 0.5f, 0.551f, 1, 0.7f, 0.5f, 0.44f, 0.2f, 0};
    for (int which = 0; which < 3; which++)
        for (size_t i = 0; i < sizeof walk / sizeof walk[0]; i++) {
            float l = which != 1 ? walk[i] : 0, rr = which != 0 ? walk[(i + 3) % (sizeof walk / sizeof walk[0])] : 0;
            op_step(m, 0, 0, 0, 0, 0, l, rr, dt);
            if (i % 5 == 0) queries(m);
        }
}

static void press_chords(model *m, double dt)
{
    /* chords pressed one button at a time and together, held, released in
       parts; every action's binding down at once */
    const uint32_t seq[] = {PAD_NORTH, PAD_NORTH | PAD_RSHOULDER, PAD_NORTH | PAD_RSHOULDER, PAD_RSHOULDER,
                            PAD_NORTH | PAD_RSHOULDER, 0, PAD_SOUTH | PAD_WEST, PAD_SOUTH, PAD_SOUTH | PAD_WEST | PAD_EAST,
                            PAD_BACK, 0, PAD_BACK, PAD_RSTICK, 0, PAD_DPAD_UP, PAD_DPAD_UP | PAD_LTRIGGER_D, 0,
                            (1u << PAD_BUTTON_COUNT) - 1, 0, PAD_LSHOULDER, PAD_RSHOULDER, PAD_LSHOULDER | PAD_RSHOULDER};
    for (size_t i = 0; i < sizeof seq / sizeof seq[0]; i++) {
        op_step(m, seq[i], 0.3f, 0, 0, 0, 0, 0, dt);
        op_step(m, seq[i], 0, 0, 0, 0, 0, 0, dt);
    }
    queries(m);
}

/* The clamps: tilted to the limit and back to top-down, zoomed to the
 * nearest and the farthest, panned and turned at full deflection. */
static void hold_extremes(model *m, double dt)
{
    const struct { float lx, ly, rx, ry, lt, rt, secs; } hold[] = {
        {0, 0, 0, 1, 0, 0, 1.2f},  {0, 0, 0, -1, 0, 0, 1.2f}, {0, 0, 0, 0, 0, 1, 2.6f},
        {1, 1, 1, 0, 0, 0, 0.8f},  {0, 0, 0, 0, 1, 0, 2.4f},  {-1, 0.3f, -1, 0.5f, 0, 0, 1.0f},
    };
    for (size_t k = 0; k < sizeof hold / sizeof hold[0]; k++) {
        int n = (int)(hold[k].secs / dt);
        for (int i = 0; i < n; i++) {
            op_step(m, 0, hold[k].lx, hold[k].ly, hold[k].rx, hold[k].ry, hold[k].lt, hold[k].rt, dt);
            if (i % 30 == 0) queries(m);
        }
        queries(m);
    }
}

static void random_session(model *m, int n, double dt)
{
    rng *r = &m->r;
    uint32_t held = 0;
    float lx = 0, ly = 0, rx = 0, ry = 0, lt = 0, rt = 0;
    for (int i = 0; i < n; i++) {
        /* inputs change now and then, as a hand does: held for some ticks */
        if (rng_below(r, 4) == 0) lx = axis(r), ly = axis(r);
        if (rng_below(r, 5) == 0) rx = axis(r), ry = axis(r);
        if (rng_below(r, 6) == 0) lt = (float)rng_f(r), rt = rng_below(r, 2) ? (float)rng_f(r) : 0;
        if (rng_below(r, 8) == 0) held ^= 1u << rng_below(r, PAD_BUTTON_COUNT);
        double d = rng_below(r, 10) ? dt : rng_range(r, 0, 0.05); /* a late tick, a short one */
        if (rng_below(r, 8) == 0) {
            op_keys(m, (uint32_t)rng_u64(r) & (uint32_t)rng_u64(r) & ((1u << CMDR_KEYS) - 1), d); /* a few keys */
        } else if (rng_below(r, 3) == 0) {
            float ax[4] = {axis(r), axis(r), axis(r), axis(r)};
            op_gamepad(m, (uint32_t)rng_below(r, 1u << 18), ax, (float)rng_f(r), (float)rng_f(r), d);
        } else if (rng_below(r, 40) == 0) {
            op_none(m, d);
        } else {
            op_step(m, held, lx, ly, rx, ry, lt, rt, d);
        }
        switch (rng_below(r, 60)) {
        case 0: op_wheel(m, (int)rng_below(r, 9) - 4); break;
        case 1: op_click(m, 1280, 720, rng_range(r, 0, 1280), rng_range(r, 0, 720)); break;
        case 2: op_toggle(m); break;
        case 3: op_reset(m, rng_below(r, 2) ? rng_range(r, 0.5, 3) : 0); break;
        case 4: op_lat(m, rng_below(r, 9), rng_log(r, 0.5, 200)); break;
        case 5: op_pct(m, rng_below(r, 9), rng_range(r, 0, 100)); break;
        default: break;
        }
        if (i % 9 == 0) queries(m);
    }
}

/* Good and bad configs: each bad one must leave the settings as they were,
 * with the same error text on both sides. */
static void configs(model *m)
{
    static const char *const bad[] = {
        "dz_inner = 0.2\nspeed = 3\n", "curve = 9\n", "curve = fast\n", "curve\n", "ping = thumb\n", "ping = west+\n",
        "dz_inner = 0.6\ndz_outer = 0.5\n", "trig_press = 0.3\n", "tick_hz =\n", "= 4\n", "invert_tilt = 0.5\n",
        "curve = 1e999\n", "curve = nan\n", "curve = inf\n", "pan_speed = 1.5x\n", "select = south++north\n",
        "select = +south\n", "tick_hz = 9.99999\n", "rot_speed = -0\n", "trig_release = 0.95000001\n",
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) op_config(m, bad[i], strlen(bad[i]));
    char nul[] = "curve = 2\0\n";
    op_config(m, nul, sizeof nul - 1);
    char lng[400];
    memset(lng, 'x', sizeof lng);
    op_config(m, lng, sizeof lng); /* a line too long */
    static const char good[] =
        "# a rebinding, the stick rules tightened, another tick rate\n"
        "ping = north+rshoulder   # a chord\n"
        "select = ltrigger_d\n"
        "destroy = none\n"
        "reset_view = south+dpad_down\n"
        "toggle_perspective = dpad_up\n"
        "  curve = 2.5\n"
        "dz_inner = 0x1p-3\n" /* hex floats: both libcs' strtod */
        "dz_outer=0.9\n"
        "trig_press = 0.6\r\n"
        "trig_release = 0.3\n"
        "invert_tilt = -1\n"
        "tick_hz = 60\n"
        "zoom_rate = 3e0";
    op_config(m, good, sizeof good - 1);
    op_config(m, "", 0);
}

static void test_cmdr_wasm_same_rules(void **state)
{
    (void)state;
    if (system("command -v node >/dev/null 2>&1")) {
        print_message("node is missing (make deps installs it): the wasm's rules are not checked\n");
        skip();
    }
    if (access("web/js/cmdr.wasm", R_OK)) {
        print_message("web/js/cmdr.wasm is missing (make all builds it)\n");
        skip();
    }
    tdir td;
    tdir_make(&td, "cmdr_wasm");
    char in[400], out[400];
    snprintf(in, sizeof in, "%s", tdir_file(&td, "ops"));
    snprintf(out, sizeof out, "%s", tdir_file(&td, "got"));
    model m = {.ops = fopen(in, "w"), .r = {test_seed()}};
    assert_non_null(m.ops);

    op_init(&m, 16.0 / 9);
    queries(&m);
    sweep_sticks(&m, 1.0 / 120);
    walk_triggers(&m, 1.0 / 120);
    press_chords(&m, 1.0 / 120);
    hold_extremes(&m, 1.0 / 120);
    random_session(&m, 600, 1.0 / 120);
    configs(&m); /* a rebinding at 60 Hz with other dead zones, hysteresis, curve */
    sweep_sticks(&m, 1.0 / 60);
    walk_triggers(&m, 1.0 / 60);
    press_chords(&m, 1.0 / 60);
    hold_extremes(&m, 1.0 / 60);
    random_session(&m, 1200, 1.0 / 60);
    op_hostile(&m);
    op_init(&m, 4.0 / 3); /* a fresh instance: back to the defaults */
    op_view(&m, 0, 720), op_view(&m, 4097, 1), op_view(&m, 1, 4096), op_pick(&m, 0), op_pick(&m, -1);
    for (int i = 0; i < 30; i++) op_lat(&m, (uint32_t)i % 3, 1 + i * 0.5);
    for (int p = 0; p <= 100; p += 25) op_pct(&m, 0, p), op_pct(&m, 3, p);
    random_session(&m, 300, 1.0 / 120);
    assert_int_equal(fclose(m.ops), 0);

    char cmd[1000];
    snprintf(cmd, sizeof cmd, "node tests/cmdr_wasm.mjs '%s' '%s'", in, out);
    double t0 = test_now_s();
    assert_int_equal(system(cmd), 0);
    double secs = test_now_s() - t0;
    size_t glen;
    char *got = (char *)test_slurp(out, &glen);

    /* line by line; a difference is allowed only in a double, by at most
       CMDR_WASM_ULPS */
    size_t lines = 0, inexact = 0;
    double worst = 0, worst_at = 0; /* the largest difference (as compared), of the native value worst_at */
    size_t worst_line = 0;
    const char *a = m.want, *b = got, *ae = m.want + m.len, *be = got + glen;
    while (a < ae && b < be) {
        const char *an = memchr(a, '\n', (size_t)(ae - a)), *bn = memchr(b, '\n', (size_t)(be - b));
        assert_non_null(an);
        assert_non_null(bn);
        lines++;
        if ((size_t)(an - a) != (size_t)(bn - b) || memcmp(a, b, (size_t)(an - a))) {
            /* token by token */
            const char *x = a, *y = b;
            bool ok = true;
            while (ok && x < an && y < bn) {
                size_t xl = strcspn(x, " \n"), yl = strcspn(y, " \n");
                if (xl == yl && !memcmp(x, y, xl)) {
                } else if (xl == 16 && yl == 16) {
                    uint64_t u = strtoull(x, NULL, 16), v = strtoull(y, NULL, 16);
                    double p, q;
                    memcpy(&p, &u, sizeof p);
                    memcpy(&q, &v, sizeof q);
                    double d = fabs(p - q) / fmax(1, fabs(p));
                    if (!(d <= CMDR_WASM_TOL)) ok = false;
                    if (d > worst) worst = d, worst_line = lines, worst_at = p;
                } else {
                    ok = false;
                }
                x += xl + (x[xl] == ' '), y += yl + (y[yl] == ' ');
            }
            if (!ok || x < an || y < bn)
                fail_msg("line %zu differs (seed %" PRIu64 "):\n native %.*s\n wasm   %.*s", lines, test_seed(),
                         (int)(an - a), a, (int)(bn - b), b);
            inexact++;
        }
        a = an + 1, b = bn + 1;
    }
    assert_true(a == ae && b == be); /* as many lines */
    print_message("%zu results: %zu bit for bit, %zu with doubles apart by at most %.2g (line %zu, of %.3g); "
                  "node %.2f s\n", lines, lines - inexact, inexact, worst, worst_line, worst_at, secs);
    free(got);
    free(m.want);
    tdir_remove(&td);
}

/* The keyboard table both windows read: each usage is the HID Usage
 * Tables' number for the key its KeyboardEvent.code names (letters are
 * 4 + their place in the alphabet; the others from the tables), and the
 * pad state follows commander_sdl.c's old rules: + and - cancel, any one
 * of two keys is enough, the buttons OR. */
static void test_cmdr_wasm_keys_table(void **state)
{
    (void)state;
    static const struct { const char *code; uint16_t usage; } hid[] = {
        {"Enter", 40},     {"Tab", 43},       {"Space", 44},     {"BracketLeft", 47}, {"BracketRight", 48},
        {"Home", 74},      {"PageUp", 75},    {"Delete", 76},    {"PageDown", 78},    {"ArrowRight", 79},
        {"ArrowLeft", 80}, {"ArrowDown", 81}, {"ArrowUp", 82},
    };
    for (int i = 0; i < CMDR_KEYS; i++) {
        const cmdr_key *k = &cmdr_key_table[i];
        int want = -1;
        if (!strncmp(k->code, "Key", 3) && strlen(k->code) == 4) want = 4 + (k->code[3] - 'A');
        for (size_t j = 0; j < sizeof hid / sizeof hid[0]; j++)
            if (!strcmp(k->code, hid[j].code)) want = hid[j].usage;
        if (want != k->usage) fail_msg("%s: usage %u, the HID tables say %d", k->code, k->usage, want);
        for (int j = 0; j < i; j++) assert_string_not_equal(k->code, cmdr_key_table[j].code);
    }
    struct { const char *keys; float lx, ly, rx, ry, lt, rt; uint32_t buttons; bool any; } cases[] = {
        {"", 0, 0, 0, 0, 0, 0, 0, false},
        {"KeyW", 0, 1, 0, 0, 0, 0, 0, true},
        {"KeyW ArrowUp", 0, 1, 0, 0, 0, 0, 0, true},
        {"KeyW KeyS", 0, 0, 0, 0, 0, 0, 0, false},
        {"KeyA ArrowRight", 0, 0, 0, 0, 0, 0, 0, false},
        {"ArrowLeft ArrowDown KeyE KeyF", -1, -1, 1, -1, 0, 0, 0, true},
        {"KeyQ KeyR PageDown KeyX", 0, 0, -1, 1, 1, 1, 0, true},
        {"Space Enter", 0, 0, 0, 0, 0, 0, PAD_SOUTH, true},
        {"KeyP KeyC Delete BracketLeft BracketRight Tab Home", 0, 0, 0, 0, 0, 0,
         PAD_WEST | PAD_EAST | PAD_NORTH | PAD_LSHOULDER | PAD_RSHOULDER | PAD_BACK | PAD_RSTICK, true},
    };
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        bool down[CMDR_KEYS] = {false};
        for (int i = 0; i < CMDR_KEYS; i++) {
            const char *p = strstr(cases[c].keys, cmdr_key_table[i].code);
            size_t n = strlen(cmdr_key_table[i].code);
            down[i] = p && (p[n] == ' ' || !p[n]) && (p == cases[c].keys || p[-1] == ' ');
        }
        pad_state s;
        bool any = cmdr_keys_pad(down, &s);
        if (any != cases[c].any || s.lx != cases[c].lx || s.ly != cases[c].ly || s.rx != cases[c].rx ||
            s.ry != cases[c].ry || s.lt != cases[c].lt || s.rt != cases[c].rt || s.buttons != cases[c].buttons)
            fail_msg("\"%s\": any %d lx %g ly %g rx %g ry %g lt %g rt %g buttons %#x", cases[c].keys, any, (double)s.lx,
                     (double)s.ly, (double)s.rx, (double)s.ry, (double)s.lt, (double)s.rt, s.buttons);
        assert_int_equal(s.battery, -1); /* a pad state as pad_state_init makes it */
    }
}

const struct CMUnitTest cmdr_wasm_tests[] = {
    cmocka_unit_test(test_cmdr_wasm_keys_table),
    cmocka_unit_test(test_cmdr_wasm_same_rules),
};
const size_t cmdr_wasm_tests_count = sizeof cmdr_wasm_tests / sizeof cmdr_wasm_tests[0];
