/*
 * commander.h — `vantage commander`, the tablet-commander thin client
 * ("Battlefield 4 Commander": a top-down view of the battlefield driven by
 * a pad, issuing orders), and its input mapping.
 *
 * The mapping (pad_map.c) is pure and runs at a fixed rate (120 Hz by
 * default), independent of when reports arrive: a scaled radial dead zone
 * and a response curve on the sticks, hysteresis on triggers used as
 * buttons, bindings from a small config file, and the camera: left stick
 * pans (speed scaled by zoom), right stick rotates (x) and tilts (y),
 * triggers zoom exponentially, face buttons select / ping / cancel,
 * shoulders cycle groups. commander.c owns the connection, the frame
 * stream and the commands; commander_sdl.c the window.
 */
#ifndef VANTAGE_COMMANDER_H
#define VANTAGE_COMMANDER_H

#include "pad.h"
#include "protocol.h"

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

/* ---- actions and their bindings -------------------------------------------------- */

typedef enum cmdr_action {
    CMDR_SELECT = 0,         /* the entity under the reticle (a visibility query, then a ray against boxes) */
    CMDR_PING,               /* MARK the place under the reticle for every commander */
    CMDR_CANCEL,             /* drop the selection */
    CMDR_DESTROY,            /* a destruction sphere where the reticle meets the selected entity */
    CMDR_GROUP_PREV,         /* cycle the selection groups (1..CMDR_GROUPS) */
    CMDR_GROUP_NEXT,
    CMDR_TOGGLE_PERSPECTIVE, /* top-down orthographic <-> tilted perspective */
    CMDR_RESET_VIEW,
    CMDR_ACTION_COUNT
} cmdr_action;

#define CMDR_GROUPS 4

extern const char *const cmdr_action_names[CMDR_ACTION_COUNT]; /* "select", "ping", ... */

/* The mapping's settings; cmdr_map_defaults fills INPUT.md's. */
typedef struct cmdr_map_cfg {
    float dz_inner, dz_outer;    /* radial dead zone on stick magnitude: 0.15, 0.95 */
    float curve;                 /* response exponent after the dead zone: 1.7 */
    float trig_press, trig_release; /* a trigger as a button: 0.55 / 0.45 */
    float trig_dead;             /* trigger travel ignored at rest: 0.05 */
    float tick_hz;               /* fixed processing rate: 120 */
    float pan_speed;             /* view heights per second at full deflection: 1.2 */
    float rot_speed;             /* radians per second (yaw): 2.0 */
    float tilt_speed;            /* radians per second (pitch): 1.2 */
    float zoom_rate;             /* e-folds per second at a full trigger: 1.6 */
    float invert_tilt;           /* 1 or -1 */
    uint32_t bind[CMDR_ACTION_COUNT]; /* pad buttons (enum pad_button bits) that fire each action */
} cmdr_map_cfg;

void cmdr_map_defaults(cmdr_map_cfg *c);
/* Reads a config file of "name = value" lines ('#' comments): the floats
 * by their field names above (dz_inner, curve, tick_hz, ...), and actions
 * bound to buttons ("ping = west", "destroy = north+rshoulder" for a
 * chord, "select = none"). 0, or -1 and err naming the line and field.
 * Unset names keep their values. */
int cmdr_map_load(cmdr_map_cfg *c, const char *path, char *err, size_t errlen);
/* The same over text in memory (what cmdr_map_load reads), for tests. */
int cmdr_map_parse(cmdr_map_cfg *c, const char *text, size_t len, char *err, size_t errlen);

/* ---- shaping ------------------------------------------------------------------------- */

/* Scaled radial dead zone then the response curve: |v| below inner is 0,
 * inner..outer maps onto 0..1 and is raised to curve, the direction kept
 * (no per-axis snapping: diagonals pan diagonally). */
void cmdr_stick_shape(const cmdr_map_cfg *c, float x, float y, float *ox, float *oy);
/* A trigger, 0..1 after trig_dead. */
float cmdr_trigger_shape(const cmdr_map_cfg *c, float t);
/* Hysteresis: pressed above press, released below release. */
bool cmdr_trigger_button(const cmdr_map_cfg *c, float t, bool was);

/* ---- the camera ------------------------------------------------------------------------- */

typedef struct cmdr_camera {
    double target[3];        /* the ground point at the screen's centre (the reticle), world metres, Y up */
    double yaw;              /* radians: the screen's up direction on the ground is (sin yaw, 0, cos yaw) */
    double pitch;            /* radians from straight down: 0 top-down .. CMDR_MAX_PITCH */
    double half_h;           /* the view's half height at the target, metres (the zoom): CMDR_MIN_ZOOM.. */
    bool perspective;        /* false: orthographic */
    double aspect;           /* width / height of the frames */
} cmdr_camera;

#define CMDR_MAX_PITCH 1.0472 /* 60 degrees */
#define CMDR_MIN_ZOOM 4.0
#define CMDR_MAX_ZOOM 4000.0
#define CMDR_FOVY_DEG 50.0   /* the perspective mode's vertical field of view */

void cmdr_camera_reset(cmdr_camera *cam, double aspect);
/* Top-down orthographic <-> tilted perspective (CMDR_TOGGLE_PERSPECTIVE):
 * a perspective view tilted less than 0.3 rad is tilted to 0.6. */
void cmdr_camera_toggle(cmdr_camera *cam);

/* What one fixed step produced: the actions whose bindings went down this
 * step (edges, not levels). */
typedef struct cmdr_step_out {
    bool moved;              /* the camera changed */
    uint32_t fired;          /* 1 << cmdr_action */
} cmdr_step_out;

/* The mapping's memory between steps: buttons held, triggers as buttons. */
typedef struct cmdr_input {
    uint32_t held;           /* buttons (and trigger buttons) after the previous step */
    bool lt_down, rt_down;
} cmdr_input;

/* One step of dt seconds with the pad state s (NULL = no pad: nothing
 * held). Pure. */
void cmdr_step(const cmdr_map_cfg *c, cmdr_camera *cam, cmdr_input *in, const pad_state *s, double dt,
              cmdr_step_out *out);

/* The mouse (the keyboard-and-mouse fallback; the browser's page uses
 * these too): the wheel zooms by 0.85 a notch (notches > 0: away from the
 * user, in), within CMDR_MIN_ZOOM..CMDR_MAX_ZOOM; a click at pixel (x, y)
 * (x right, y down) of a w x h frame pans the target by the click's offset
 * from the centre at the target's scale (exact top-down orthographic, the
 * footprint at the target otherwise). w and h >= 1. */
void cmdr_camera_wheel(cmdr_camera *cam, int notches);
void cmdr_camera_click(cmdr_camera *cam, uint32_t w, uint32_t h, double x, double y);

/* The camera as a query/render view of w x h pixels. */
bool cmdr_camera_view(const cmdr_camera *cam, uint32_t w, uint32_t h, vp_view *out);
/* The eye and the direction the screen's centre looks along (unit). */
void cmdr_camera_ray(const cmdr_camera *cam, double eye[3], double dir[3]);
/* A narrow view around the reticle's ray (for CMDR_SELECT's query): an
 * orthographic pick box of size metres across (orthographic mode) or a
 * 1-degree cone (perspective). */
bool cmdr_pick_view(const cmdr_camera *cam, double size, vp_view *out);
/* World point -> pixel (x right, y down) in a w x h frame of the camera;
 * false when behind the eye. */
bool cmdr_camera_project(const cmdr_camera *cam, uint32_t w, uint32_t h, const double p[3], double *px, double *py);

/* Ray against a box: true and *t (>= 0, the entry distance along dir)
 * when o + t dir enters [lo, hi]. */
bool cmdr_ray_box(const double o[3], const double dir[3], const double lo[3], const double hi[3], double *t);

/* ---- the keyboard ----------------------------------------------------------------------- */

/* The keyboard fallback's keys, one table for the SDL window and the
 * browser's page: each key by its USB HID usage (keyboard page 7, which
 * SDL's scancodes number alike) and by its KeyboardEvent.code (the UI
 * Events name of the same physical key), and what it drives: an axis of
 * the pad state at +1 or -1 (a trigger at 1), or buttons. */
typedef enum cmdr_key_to {
    CMDR_KEY_LX = 0, CMDR_KEY_LY, CMDR_KEY_RX, CMDR_KEY_RY, CMDR_KEY_LT, CMDR_KEY_RT, CMDR_KEY_BUTTON,
} cmdr_key_to;
typedef struct cmdr_key {
    uint16_t usage;          /* USB HID usage = SDL_Scancode */
    const char *code;        /* KeyboardEvent.code: "KeyW", "ArrowUp", ... */
    uint8_t to;              /* cmdr_key_to */
    int8_t sign;             /* an axis: +1 or -1 */
    uint32_t button;         /* CMDR_KEY_BUTTON: enum pad_button bits */
} cmdr_key;
#define CMDR_KEYS 25
extern const cmdr_key cmdr_key_table[CMDR_KEYS];

/* The pad state of the keys held (down[i] for cmdr_key_table[i]): an axis
 * is 1 when one of its + keys is held, minus 1 when one of its - keys is
 * (both: 0), a trigger 1 when one of its keys is, the buttons OR'ed. s is
 * reset first (pad_state_init). Returns whether anything is non-zero. */
bool cmdr_keys_pad(const bool down[CMDR_KEYS], pad_state *s);

/* ---- the window (commander_sdl.c: SDL2 + SDL_ttf) ------------------------------------- */

typedef struct cmdr_display cmdr_display;

#define CMDR_OVERLAY_LINES 4
#define CMDR_OVERLAY_MARKS 32
typedef struct cmdr_overlay {
    char text[CMDR_OVERLAY_LINES][192]; /* top-left status lines ("" = none) */
    uint32_t nmarks;
    struct {
        double x, y;         /* frame pixels */
        float alpha;         /* 1 new .. 0 expired */
        uint8_t kind;        /* 0 ping, 1 select */
        bool own;            /* this client's */
    } mark[CMDR_OVERLAY_MARKS];
} cmdr_overlay;

/* What the keyboard and mouse did since the last call (the fallback when
 * no pad is present): a pad state from the held keys (cmdr_keys_pad), the
 * wheel, a left click. */
typedef struct cmdr_keys {
    bool any;                /* a key is held: state below is the input */
    pad_state state;
    int wheel;               /* notches, + = away from the user (zoom in) */
    bool click;              /* a left click at (click_x, click_y), frame pixels */
    double click_x, click_y;
    bool quit;               /* window closed, Escape, Ctrl+Q */
    bool changed;            /* any of the above differs from the last call */
} cmdr_keys;

/* A window of w x h (the frames' size) titled title; NULL and err when
 * there is no display (SDL_VIDEODRIVER, DISPLAY). */
cmdr_display *cmdr_display_open(uint32_t w, uint32_t h, const char *title, char *err, size_t errlen);
void cmdr_display_close(cmdr_display *d);
/* The frame to show (RGB8, top row first, w x h as opened; another size
 * is scaled to the window). 0 or -1. */
int cmdr_display_frame(cmdr_display *d, const uint8_t *rgb8, uint32_t w, uint32_t h);
/* Draws the last frame with the overlay and presents it. */
void cmdr_display_present(cmdr_display *d, const cmdr_overlay *ov);
/* Pumps the window's events into *k. */
void cmdr_display_events(cmdr_display *d, cmdr_keys *k);
/* What the window shows with overlay ov, as a PNG. 0, or -1 and err. */
int cmdr_display_screenshot(cmdr_display *d, const cmdr_overlay *ov, const char *path, char *err, size_t errlen);

/* ---- latency samples ------------------------------------------------------------------ */

/* A fixed ring of the last n samples (ms) with their percentiles. */
#define CMDR_LAT_SAMPLES 4096
typedef struct cmdr_lat {
    float v[CMDR_LAT_SAMPLES];
    uint32_t n, next;
    uint64_t total;
} cmdr_lat;
void cmdr_lat_add(cmdr_lat *l, double ms);
/* p in 0..100 over the samples kept; NAN when there are none. */
double cmdr_lat_pct(const cmdr_lat *l, double p);

#endif
