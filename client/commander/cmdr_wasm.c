/*
 * cmdr_wasm.c — the commander's rules for the browser: a flat API over
 * pad_map.c, built to WebAssembly (web/js/cmdr.wasm, `make all`) with the
 * same pad_map.c, client/lib/vtc_view.c, protocol/ and pad.c the native
 * `vantage commander` links, so the page's mapping, dead zones, config
 * rules, camera and view bytes are the SDL client's by construction.
 * web/js/cmdr.js wraps it (client/commander/README.md, "In the browser").
 *
 * Compiled only for wasm32 (the native client calls pad_map.c itself).
 * State is static: one commander per WebAssembly instance (cmdr.js makes
 * one instance per Commander); nothing allocates. Results that are more
 * than a number go to static buffers the page reads through the returned
 * pointer (an offset into the instance's memory), valid until the next
 * call that writes the same buffer. Every input is checked: a bad value
 * gives an error result, never a trap.
 *
 * Cost: a step is the native cmdr_step (well under a microsecond); a view
 * is two matrix products and 160 bytes written.
 */
#include "commander.h"
#include "vantage.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#define EXPORT(name) __attribute__((export_name(#name)))

#define CMDR_W_TEXT_MAX 16384u     /* a config text, as cmdr_map_load's limit */
#define CMDR_W_MOVED (1u << 31)    /* cmdr_w_step: the camera changed */
#define CMDR_W_LAT_RINGS 8u        /* latency rings the page may keep */

/* ---- the API (all exported under these names) ------------------------------------------ */

/* INPUT.md's mapping (cmdr_map_defaults), the camera reset for frames of
 * aspect (width / height; <= 0 or not finite: 16/9), top-down, nothing
 * held, the latency rings empty. */
EXPORT(cmdr_w_init) void cmdr_w_init(double aspect);
/* CMDR_W_TEXT_MAX bytes the page writes a config text into. */
EXPORT(cmdr_w_text) char *cmdr_w_text(void);
EXPORT(cmdr_w_text_max) uint32_t cmdr_w_text_max(void);
/* cmdr_map_parse over cmdr_w_text()[0..len): 0 (the settings replaced), or
 * -1 (nothing changed) and cmdr_w_error() says why, in the native text. */
EXPORT(cmdr_w_parse) int cmdr_w_parse(uint32_t len);
/* The last error, NUL-terminated ("" when none). */
EXPORT(cmdr_w_error) const char *cmdr_w_error(void);
/* The settings the page needs: the fixed tick rate (Hz) and action a's
 * buttons (enum pad_button bits; 0 for an unknown action). */
EXPORT(cmdr_w_tick_hz) double cmdr_w_tick_hz(void);
EXPORT(cmdr_w_binding) uint32_t cmdr_w_binding(uint32_t action);
/* The names of the C tables ("select", ...; "south", ...); NULL past the end. */
EXPORT(cmdr_w_action_name) const char *cmdr_w_action_name(uint32_t action);
EXPORT(cmdr_w_button_name) const char *cmdr_w_button_name(uint32_t bit);

/* The keyboard (cmdr_key_table): key i's KeyboardEvent.code (NULL past
 * the end), and the pad state of the keys held (bit i of down: key i) as
 * 8 doubles: any (0 or 1), buttons, lx, ly, rx, ry, lt, rt. */
EXPORT(cmdr_w_key_code) const char *cmdr_w_key_code(uint32_t i);
EXPORT(cmdr_w_keys_pad) const double *cmdr_w_keys_pad(uint32_t down);

/* One fixed step of dt seconds (cmdr_step) with the pad state: buttons
 * (enum pad_button bits; others dropped), sticks -1..1 (+y up), triggers
 * 0..1 (clamped there, NaN as 0, as the pad parsers give them). Returns the
 * actions fired (1 << cmdr_action) | CMDR_W_MOVED when the camera changed.
 * A dt that is not finite or outside 0..1 s steps by 0. */
EXPORT(cmdr_w_step) uint32_t cmdr_w_step(uint32_t buttons, float lx, float ly, float rx, float ry, float lt, float rt,
                                         double dt);
/* The camera as 8 doubles: target x, y, z, yaw, pitch, half_h, perspective
 * (0 or 1), aspect. */
EXPORT(cmdr_w_camera) const double *cmdr_w_camera(void);
/* The camera's own rules outside a step: reset (aspect as cmdr_w_init's;
 * <= 0 keeps the current one), the perspective toggle, the mouse wheel
 * (notches, + zooms in) and a click at pixel (x, y) of a w x h frame (pans
 * there; w or h 0 does nothing). */
EXPORT(cmdr_w_reset) void cmdr_w_reset(double aspect);
EXPORT(cmdr_w_toggle_perspective) void cmdr_w_toggle_perspective(void);
EXPORT(cmdr_w_wheel) void cmdr_w_wheel(int notches);
EXPORT(cmdr_w_click) void cmdr_w_click(uint32_t w, uint32_t h, double x, double y);

/* The camera as a view of w x h pixels (1..4096), as VP_VIEW_SIZE bytes
 * the way FRAME_SUBSCRIBE and VIS_QUERY carry it; NULL when refused. */
EXPORT(cmdr_w_view) const uint8_t *cmdr_w_view(uint32_t w, uint32_t h);
/* cmdr_pick_view's view, the same bytes; NULL when refused (size <= 0). */
EXPORT(cmdr_w_pick_view) const uint8_t *cmdr_w_pick_view(double size);
/* The reticle's ray as 6 doubles: eye x, y, z, unit direction x, y, z. */
EXPORT(cmdr_w_ray) const double *cmdr_w_ray(void);
/* World point -> pixel of a w x h frame as 2 doubles (x right, y down);
 * NULL when behind the eye or the size is refused. */
EXPORT(cmdr_w_project) const double *cmdr_w_project(double x, double y, double z, uint32_t w, uint32_t h);
/* cmdr_ray_box: the entry distance t >= 0, or -1 when the ray misses or
 * a number is not finite. */
EXPORT(cmdr_w_ray_box) double cmdr_w_ray_box(double ox, double oy, double oz, double dx, double dy, double dz,
                                             double lox, double loy, double loz, double hix, double hiy, double hiz);

/* Latency samples (ms) in ring r (0..CMDR_W_LAT_RINGS-1; others ignored):
 * add one (a non-finite one is dropped), a percentile p (0..100; NAN when
 * empty or r is bad), the count
 * kept, and empty it. */
EXPORT(cmdr_w_lat_add) void cmdr_w_lat_add(uint32_t r, double ms);
EXPORT(cmdr_w_lat_pct) double cmdr_w_lat_pct(uint32_t r, double p);
EXPORT(cmdr_w_lat_count) uint32_t cmdr_w_lat_count(uint32_t r);
EXPORT(cmdr_w_lat_clear) void cmdr_w_lat_clear(uint32_t r);

/* ---- the state ------------------------------------------------------------------------- */

static cmdr_map_cfg g_cfg;
static cmdr_camera g_cam;
static cmdr_input g_in;
static char g_text[CMDR_W_TEXT_MAX];
static char g_err[256];
static double g_out[8];
static uint8_t g_view[VP_VIEW_SIZE];
static cmdr_lat g_lat[CMDR_W_LAT_RINGS]; /* 16 KiB each */

void cmdr_w_init(double aspect)
{
    cmdr_map_defaults(&g_cfg);
    g_cam = (cmdr_camera){0};
    cmdr_camera_reset(&g_cam, isfinite(aspect) ? aspect : 0);
    g_in = (cmdr_input){0};
    g_err[0] = 0;
    memset(g_lat, 0, sizeof g_lat);
}

char *cmdr_w_text(void) { return g_text; }
uint32_t cmdr_w_text_max(void) { return CMDR_W_TEXT_MAX; }

int cmdr_w_parse(uint32_t len)
{
    g_err[0] = 0;
    if (len > CMDR_W_TEXT_MAX) {
        snprintf(g_err, sizeof g_err, "%s", "larger than 16 KiB");
        return -1;
    }
    return cmdr_map_parse(&g_cfg, g_text, len, g_err, sizeof g_err);
}

const char *cmdr_w_error(void) { return g_err; }
double cmdr_w_tick_hz(void) { return g_cfg.tick_hz; }
uint32_t cmdr_w_binding(uint32_t action) { return action < CMDR_ACTION_COUNT ? g_cfg.bind[action] : 0; }
const char *cmdr_w_action_name(uint32_t action) { return action < CMDR_ACTION_COUNT ? cmdr_action_names[action] : NULL; }
const char *cmdr_w_button_name(uint32_t bit) { return bit < PAD_BUTTON_COUNT ? pad_button_names[bit] : NULL; }

const char *cmdr_w_key_code(uint32_t i) { return i < CMDR_KEYS ? cmdr_key_table[i].code : NULL; }

const double *cmdr_w_keys_pad(uint32_t down)
{
    bool d[CMDR_KEYS];
    for (int i = 0; i < CMDR_KEYS; i++) d[i] = (down >> i) & 1;
    pad_state s;
    bool any = cmdr_keys_pad(d, &s);
    double v[8] = {any, s.buttons, s.lx, s.ly, s.rx, s.ry, s.lt, s.rt};
    memcpy(g_out, v, sizeof v);
    return g_out;
}

/* v within lo..hi, NaN as 0: what a pad parser guarantees (pad.h), so a
 * page's bad number never reaches the camera as a NaN or an infinity. */
static float clampf(float v, float lo, float hi)
{
    return v > lo ? (v < hi ? v : hi) : v < lo ? lo : v == v ? v : 0;
}

uint32_t cmdr_w_step(uint32_t buttons, float lx, float ly, float rx, float ry, float lt, float rt, double dt)
{
    pad_state s;
    pad_state_init(&s);
    s.buttons = buttons & ((1u << PAD_BUTTON_COUNT) - 1);
    s.lx = clampf(lx, -1, 1), s.ly = clampf(ly, -1, 1), s.rx = clampf(rx, -1, 1), s.ry = clampf(ry, -1, 1);
    s.lt = clampf(lt, 0, 1), s.rt = clampf(rt, 0, 1);
    if (!(dt >= 0 && dt <= 1)) dt = 0;
    cmdr_step_out o;
    cmdr_step(&g_cfg, &g_cam, &g_in, &s, dt, &o);
    return o.fired | (o.moved ? CMDR_W_MOVED : 0);
}

const double *cmdr_w_camera(void)
{
    double v[8] = {g_cam.target[0], g_cam.target[1], g_cam.target[2], g_cam.yaw,
                   g_cam.pitch,     g_cam.half_h,    g_cam.perspective, g_cam.aspect};
    memcpy(g_out, v, sizeof v);
    return g_out;
}

void cmdr_w_reset(double aspect) { cmdr_camera_reset(&g_cam, isfinite(aspect) && aspect > 0 ? aspect : g_cam.aspect); }
void cmdr_w_toggle_perspective(void) { cmdr_camera_toggle(&g_cam); }
void cmdr_w_wheel(int notches) { cmdr_camera_wheel(&g_cam, notches); }

void cmdr_w_click(uint32_t w, uint32_t h, double x, double y)
{
    if (w && h && isfinite(x) && isfinite(y)) cmdr_camera_click(&g_cam, w, h, x, y);
}

/* The view's bytes as the protocol writes them: VIS_QUERY of one view is
 * the header, its fixed fields, then the view, so the view is the last
 * VP_VIEW_SIZE bytes. The protocol's own encoder (vp_query.c's layout),
 * not a second one. */
static const uint8_t *view_bytes(const vp_view *v)
{
    uint8_t buf[VP_HEADER_SIZE + 64 + VP_VIEW_SIZE];
    size_t n = vp_size_vis_query(1);
    if (n > sizeof buf) return NULL; /* cannot happen: a static layout */
    vp_writer w;
    vp_writer_init(&w, buf, sizeof buf);
    vp_enc_vis_query(&w, 0, 0, 0, v, 1);
    if (w.overflow || w.len != n) return NULL;
    memcpy(g_view, buf + n - VP_VIEW_SIZE, VP_VIEW_SIZE);
    return g_view;
}

const uint8_t *cmdr_w_view(uint32_t w, uint32_t h)
{
    vp_view v;
    return cmdr_camera_view(&g_cam, w, h, &v) ? view_bytes(&v) : NULL;
}

const uint8_t *cmdr_w_pick_view(double size)
{
    vp_view v;
    if (!(size > 0) || !isfinite(size)) return NULL;
    return cmdr_pick_view(&g_cam, size, &v) ? view_bytes(&v) : NULL;
}

const double *cmdr_w_ray(void)
{
    cmdr_camera_ray(&g_cam, g_out, g_out + 3);
    return g_out;
}

const double *cmdr_w_project(double x, double y, double z, uint32_t w, uint32_t h)
{
    double p[3] = {x, y, z};
    return cmdr_camera_project(&g_cam, w, h, p, &g_out[0], &g_out[1]) ? g_out : NULL;
}

double cmdr_w_ray_box(double ox, double oy, double oz, double dx, double dy, double dz, double lox, double loy,
                      double loz, double hix, double hiy, double hiz)
{
    double o[3] = {ox, oy, oz}, d[3] = {dx, dy, dz}, lo[3] = {lox, loy, loz}, hi[3] = {hix, hiy, hiz}, t;
    for (int i = 0; i < 3; i++) /* a NaN would skip its axis's test in cmdr_ray_box */
        if (!isfinite(o[i]) || !isfinite(d[i]) || !isfinite(lo[i]) || !isfinite(hi[i])) return -1;
    return cmdr_ray_box(o, d, lo, hi, &t) ? t : -1;
}

void cmdr_w_lat_add(uint32_t r, double ms)
{
    if (r < CMDR_W_LAT_RINGS && isfinite(ms)) cmdr_lat_add(&g_lat[r], ms);
}

double cmdr_w_lat_pct(uint32_t r, double p) { return r < CMDR_W_LAT_RINGS ? cmdr_lat_pct(&g_lat[r], p) : NAN; }
uint32_t cmdr_w_lat_count(uint32_t r) { return r < CMDR_W_LAT_RINGS ? g_lat[r].n : 0; }

void cmdr_w_lat_clear(uint32_t r)
{
    if (r < CMDR_W_LAT_RINGS) memset(&g_lat[r], 0, sizeof g_lat[r]);
}
