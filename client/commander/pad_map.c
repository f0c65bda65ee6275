/*
 * pad_map.c — the commander's input mapping and camera (commander.h):
 * pure functions, run at the fixed tick rate; no I/O but cmdr_map_load's
 * one read of the config file.
 *
 * Conventions: world Y up, the ground at y = 0; the camera looks at its
 * target from above, tilted back by pitch; the screen's up direction on
 * the ground is (sin yaw, 0, cos yaw) and its right (-cos yaw, 0, sin yaw),
 * what gluLookAt makes of up = that forward direction.
 */
#include "commander.h"
#include "vantage.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

const char *const cmdr_action_names[CMDR_ACTION_COUNT] = {
    "select", "ping", "cancel", "destroy", "group_prev", "group_next", "toggle_perspective", "reset_view",
};

void cmdr_map_defaults(cmdr_map_cfg *c)
{
    *c = (cmdr_map_cfg){.dz_inner = 0.15f, .dz_outer = 0.95f, .curve = 1.7f, .trig_press = 0.55f,
                       .trig_release = 0.45f, .trig_dead = 0.05f, .tick_hz = 120, .pan_speed = 1.2f,
                       .rot_speed = 2.0f, .tilt_speed = 1.2f, .zoom_rate = 1.6f, .invert_tilt = 1};
    c->bind[CMDR_SELECT] = PAD_SOUTH;
    c->bind[CMDR_PING] = PAD_WEST;
    c->bind[CMDR_CANCEL] = PAD_EAST;
    c->bind[CMDR_DESTROY] = PAD_NORTH;
    c->bind[CMDR_GROUP_PREV] = PAD_LSHOULDER;
    c->bind[CMDR_GROUP_NEXT] = PAD_RSHOULDER;
    c->bind[CMDR_TOGGLE_PERSPECTIVE] = PAD_BACK;
    c->bind[CMDR_RESET_VIEW] = PAD_RSTICK;
}

/* ---- the config file ------------------------------------------------------------------- */

typedef struct float_field {
    const char *name;
    size_t off;
    float lo, hi;
} float_field;

#define FF(n, l, h) {#n, offsetof(cmdr_map_cfg, n), l, h}
static const float_field float_fields[] = {
    FF(dz_inner, 0, 0.9f),   FF(dz_outer, 0.1f, 1),   FF(curve, 0.2f, 5),         FF(trig_press, 0.05f, 1),
    FF(trig_release, 0, 0.95f), FF(trig_dead, 0, 0.5f), FF(tick_hz, 10, 1000),    FF(pan_speed, 0.01f, 100),
    FF(rot_speed, 0.01f, 100), FF(tilt_speed, 0.01f, 100), FF(zoom_rate, 0.01f, 100), FF(invert_tilt, -1, 1),
};
#undef FF

static int cfg_fail(char *err, size_t errlen, unsigned line, const char *fmt, ...) __attribute__((format(printf, 4, 5)));
static int cfg_fail(char *err, size_t errlen, unsigned line, const char *fmt, ...)
{
    char what[200];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(what, sizeof what, fmt, ap);
    va_end(ap);
    snprintf(err, errlen, "line %u: %s", line, what);
    return -1;
}

/* "south+rshoulder" -> bits; "none" -> 0. */
static bool parse_buttons(const char *v, uint32_t *out)
{
    *out = 0;
    if (!strcmp(v, "none")) return true;
    while (*v) {
        const char *e = strchr(v, '+');
        size_t n = e ? (size_t)(e - v) : strlen(v);
        int b = -1;
        for (int i = 0; i < PAD_BUTTON_COUNT; i++)
            if (strlen(pad_button_names[i]) == n && !strncmp(v, pad_button_names[i], n)) b = i;
        if (b < 0) return false;
        *out |= 1u << b;
        v += n;
        if (*v == '+' && !*++v) return false; /* a trailing '+' */
    }
    return *out != 0;
}

int cmdr_map_parse(cmdr_map_cfg *c, const char *text, size_t len, char *err, size_t errlen)
{
    cmdr_map_cfg n = *c; /* whole file or nothing */
    unsigned line = 0;
    const char *p = text, *end = text + len;
    while (p < end) {
        const char *nl = memchr(p, '\n', (size_t)(end - p));
        size_t ll = nl ? (size_t)(nl - p) : (size_t)(end - p);
        line++;
        char buf[256];
        if (ll >= sizeof buf) return cfg_fail(err, errlen, line, "%s", "line too long");
        memcpy(buf, p, ll);
        buf[ll] = 0;
        p += ll + (nl ? 1 : 0);
        if (memchr(buf, 0, ll)) return cfg_fail(err, errlen, line, "%s", "a NUL byte");
        char *hash = strchr(buf, '#');
        if (hash) *hash = 0;
        char *s = buf;
        while (isspace((unsigned char)*s)) s++;
        char *e = s + strlen(s);
        while (e > s && isspace((unsigned char)e[-1])) *--e = 0;
        if (!*s) continue;
        char *eq = strchr(s, '=');
        if (!eq) return cfg_fail(err, errlen, line, "expected NAME = VALUE, got \"%s\"", s);
        char *k = s, *ke = eq, *v = eq + 1;
        while (ke > k && isspace((unsigned char)ke[-1])) ke--;
        *ke = 0;
        while (isspace((unsigned char)*v)) v++;
        if (!*v) return cfg_fail(err, errlen, line, "%s: no value", k);
        bool known = false;
        for (size_t i = 0; i < sizeof float_fields / sizeof float_fields[0]; i++) {
            const float_field *f = &float_fields[i];
            if (strcmp(k, f->name)) continue;
            char *q;
            errno = 0;
            double d = strtod(v, &q);
            if (q == v || *q || errno || !isfinite(d)) return cfg_fail(err, errlen, line, "%s: not a number", k);
            if (d < f->lo || d > f->hi)
                return cfg_fail(err, errlen, line, "%s: %g is outside %g..%g", k, d, (double)f->lo, (double)f->hi);
            *(float *)(void *)((char *)&n + f->off) = (float)d;
            known = true;
        }
        for (int a = 0; a < CMDR_ACTION_COUNT && !known; a++) {
            if (strcmp(k, cmdr_action_names[a])) continue;
            if (!parse_buttons(v, &n.bind[a]))
                return cfg_fail(err, errlen, line, "%s", "unknown button (south east west north back guide start "
                                                         "lstick rstick lshoulder rshoulder dpad_up ... or none)");
            known = true;
        }
        if (!known) return cfg_fail(err, errlen, line, "unknown setting \"%s\"", k);
    }
    if (!(n.dz_inner < n.dz_outer)) return cfg_fail(err, errlen, line, "%s", "dz_inner must be below dz_outer");
    if (!(n.trig_release < n.trig_press))
        return cfg_fail(err, errlen, line, "%s", "trig_release must be below trig_press");
    if (n.invert_tilt != 1 && n.invert_tilt != -1) return cfg_fail(err, errlen, line, "%s", "invert_tilt is 1 or -1");
    *c = n;
    return 0;
}

int cmdr_map_load(cmdr_map_cfg *c, const char *path, char *err, size_t errlen)
{
    FILE *f = fopen(path, "rb");
    if (!f) {
        snprintf(err, errlen, "%s: %s", path, strerror(errno));
        return -1;
    }
    char buf[16384];
    size_t n = fread(buf, 1, sizeof buf, f);
    bool big = n == sizeof buf, bad = ferror(f);
    fclose(f);
    if (bad || big) {
        snprintf(err, errlen, "%s: %s", path, big ? "larger than 16 KiB" : "read error");
        return -1;
    }
    char e[240];
    if (cmdr_map_parse(c, buf, n, e, sizeof e)) {
        snprintf(err, errlen, "%s: %s", path, e);
        return -1;
    }
    return 0;
}

/* ---- shaping ------------------------------------------------------------------------- */

void cmdr_stick_shape(const cmdr_map_cfg *c, float x, float y, float *ox, float *oy)
{
    float m = sqrtf(x * x + y * y);
    if (!(m > c->dz_inner)) { /* NaN too */
        *ox = *oy = 0;
        return;
    }
    float s = (m - c->dz_inner) / (c->dz_outer - c->dz_inner);
    if (s > 1) s = 1;
    s = powf(s, c->curve);
    *ox = x / m * s;
    *oy = y / m * s;
}

float cmdr_trigger_shape(const cmdr_map_cfg *c, float t)
{
    if (!(t > c->trig_dead)) return 0;
    float s = (t - c->trig_dead) / (1 - c->trig_dead);
    return s > 1 ? 1 : s;
}

bool cmdr_trigger_button(const cmdr_map_cfg *c, float t, bool was)
{
    return was ? !(t < c->trig_release) : t > c->trig_press;
}

/* ---- the camera ------------------------------------------------------------------------- */

void cmdr_camera_reset(cmdr_camera *cam, double aspect)
{
    bool persp = cam->perspective;
    *cam = (cmdr_camera){.half_h = 160, .aspect = aspect > 0 ? aspect : 16.0 / 9, .perspective = persp};
    if (persp) cam->pitch = 0.6;
}

void cmdr_camera_toggle(cmdr_camera *cam)
{
    cam->perspective = !cam->perspective;
    if (cam->perspective && cam->pitch < 0.3) cam->pitch = 0.6; /* a tilted view, as the name says */
}

void cmdr_step(const cmdr_map_cfg *c, cmdr_camera *cam, cmdr_input *in, const pad_state *s, double dt,
              cmdr_step_out *out)
{
    *out = (cmdr_step_out){0};
    pad_state none = {0};
    if (!s) s = &none;
    cmdr_camera before = *cam;
    float lx, ly, rx, ry;
    cmdr_stick_shape(c, s->lx, s->ly, &lx, &ly);
    cmdr_stick_shape(c, s->rx, s->ry, &rx, &ry);
    float lt = cmdr_trigger_shape(c, s->lt), rt = cmdr_trigger_shape(c, s->rt);

    /* pan: view heights per second, so the picture moves at one speed at any zoom */
    double fwd[3] = {sin(cam->yaw), 0, cos(cam->yaw)}, right[3] = {-cos(cam->yaw), 0, sin(cam->yaw)};
    double step = c->pan_speed * 2 * cam->half_h * dt;
    for (int a = 0; a < 3; a += 2) cam->target[a] += step * (lx * right[a] + ly * fwd[a]);
    for (int a = 0; a < 3; a += 2)
        if (cam->target[a] > 1e9) cam->target[a] = 1e9;
        else if (cam->target[a] < -1e9) cam->target[a] = -1e9;
    /* rotate: stick right turns the view right (the ground turns left) */
    cam->yaw = remainder(cam->yaw - rx * c->rot_speed * dt, 2 * M_PI);
    cam->pitch += c->invert_tilt * ry * c->tilt_speed * dt;
    if (cam->pitch < 0) cam->pitch = 0;
    if (cam->pitch > CMDR_MAX_PITCH) cam->pitch = CMDR_MAX_PITCH;
    /* zoom: exponential, right trigger in */
    cam->half_h *= exp((double)(lt - rt) * c->zoom_rate * dt);
    if (cam->half_h < CMDR_MIN_ZOOM) cam->half_h = CMDR_MIN_ZOOM;
    if (cam->half_h > CMDR_MAX_ZOOM) cam->half_h = CMDR_MAX_ZOOM;

    /* buttons: the pad's, with the triggers' digital bits from hysteresis */
    in->lt_down = cmdr_trigger_button(c, s->lt, in->lt_down);
    in->rt_down = cmdr_trigger_button(c, s->rt, in->rt_down);
    uint32_t held = (s->buttons & ~(uint32_t)(PAD_LTRIGGER_D | PAD_RTRIGGER_D)) | (in->lt_down ? PAD_LTRIGGER_D : 0) |
                    (in->rt_down ? PAD_RTRIGGER_D : 0);
    for (int a = 0; a < CMDR_ACTION_COUNT; a++) {
        uint32_t b = c->bind[a];
        if (b && (held & b) == b && (in->held & b) != b) out->fired |= 1u << a;
    }
    in->held = held;
    if (out->fired & (1u << CMDR_TOGGLE_PERSPECTIVE)) cmdr_camera_toggle(cam);
    if (out->fired & (1u << CMDR_RESET_VIEW)) cmdr_camera_reset(cam, cam->aspect);
    out->moved = memcmp(&before, cam, sizeof before) != 0;
}

void cmdr_camera_wheel(cmdr_camera *cam, int notches)
{
    cam->half_h = fmin(CMDR_MAX_ZOOM, fmax(CMDR_MIN_ZOOM, cam->half_h * pow(0.85, notches)));
}

void cmdr_camera_click(cmdr_camera *cam, uint32_t w, uint32_t h, double x, double y)
{
    double dx = (x / w - 0.5) * 2 * cam->half_h * w / h, dy = (0.5 - y / h) * 2 * cam->half_h;
    double right[3] = {-cos(cam->yaw), 0, sin(cam->yaw)}, fwd[3] = {sin(cam->yaw), 0, cos(cam->yaw)};
    for (int a = 0; a < 3; a += 2) cam->target[a] += dx * right[a] + dy * fwd[a];
}

/* The view direction (unit, from the eye to the target) and the eye's
 * distance from the target. */
static void eye_of(const cmdr_camera *cam, double eye[3], double dir[3], double *dist)
{
    double fwd[3] = {sin(cam->yaw), 0, cos(cam->yaw)};
    double cp = cos(cam->pitch), sp = sin(cam->pitch);
    for (int a = 0; a < 3; a++) dir[a] = sp * fwd[a];
    dir[1] = -cp;
    /* perspective: the distance at which the view is half_h high at the
       target; orthographic: high above anything a level holds */
    double d = cam->perspective ? cam->half_h / tan(CMDR_FOVY_DEG * M_PI / 360) : 3000;
    for (int a = 0; a < 3; a++) eye[a] = cam->target[a] - d * dir[a];
    *dist = d;
}

void cmdr_camera_ray(const cmdr_camera *cam, double eye[3], double dir[3])
{
    double d;
    eye_of(cam, eye, dir, &d);
}

static bool view_of(const cmdr_camera *cam, double ortho_w, double ortho_h, double fovy, uint32_t w, uint32_t h,
                    vp_view *out)
{
    double eye[3], dir[3], d;
    eye_of(cam, eye, dir, &d);
    double up[3] = {sin(cam->yaw), 0, cos(cam->yaw)};
    if (w < 1 || h < 1 || w > 4096 || h > 4096) return false;
    if (cam->perspective)
        return vtc_view_perspective(out, eye, cam->target, up, fovy, (uint16_t)w, (uint16_t)h, d * 0.02, d + 5000);
    return vtc_view_ortho(out, eye, cam->target, up, ortho_w, ortho_h, (uint16_t)w, (uint16_t)h, 1, d + 3000);
}

bool cmdr_camera_view(const cmdr_camera *cam, uint32_t w, uint32_t h, vp_view *out)
{
    double hh = 2 * cam->half_h;
    return view_of(cam, hh * w / h, hh, CMDR_FOVY_DEG, w, h, out);
}

bool cmdr_pick_view(const cmdr_camera *cam, double size, vp_view *out)
{
    return view_of(cam, size, size, 1.0, 64, 64, out);
}

bool cmdr_camera_project(const cmdr_camera *cam, uint32_t w, uint32_t h, const double p[3], double *px, double *py)
{
    vp_view v;
    if (!cmdr_camera_view(cam, w, h, &v)) return false;
    double r[4] = {p[0] - v.origin[0], p[1] - v.origin[1], p[2] - v.origin[2], 1}, c[4] = {0, 0, 0, 0};
    for (int i = 0; i < 4; i++)
        for (int k = 0; k < 4; k++) c[i] += v.view_proj[k * 4 + i] * r[k];
    if (!(c[3] > 1e-9)) return false;
    *px = (c[0] / c[3] * 0.5 + 0.5) * w;
    *py = (0.5 - c[1] / c[3] * 0.5) * h;
    return isfinite(*px) && isfinite(*py);
}

bool cmdr_ray_box(const double o[3], const double dir[3], const double lo[3], const double hi[3], double *t)
{
    double t0 = 0, t1 = INFINITY;
    for (int a = 0; a < 3; a++) {
        if (dir[a] == 0) {
            if (o[a] < lo[a] || o[a] > hi[a]) return false;
            continue;
        }
        double inv = 1 / dir[a], u = (lo[a] - o[a]) * inv, v = (hi[a] - o[a]) * inv;
        if (u > v) {
            double x = u;
            u = v;
            v = x;
        }
        if (u > t0) t0 = u;
        if (v < t1) t1 = v;
        if (t0 > t1) return false;
    }
    *t = t0;
    return true;
}

/* ---- the keyboard ----------------------------------------------------------------------- */

/* WASD / arrows pan, Q/E rotate, R/F tilt, Z/X or PageDown/PageUp zoom,
 * Space or Enter select, P ping, C cancel, Delete destroy, [ ] groups, Tab
 * perspective, Home reset (the default bindings of the pad buttons they
 * press). Usages: the HID Usage Tables' keyboard page. */
#define AXIS(u, c, to, sg) {u, c, to, sg, 0}
#define BUTTON(u, c, b) {u, c, CMDR_KEY_BUTTON, 0, b}
const cmdr_key cmdr_key_table[CMDR_KEYS] = {
    AXIS(7, "KeyD", CMDR_KEY_LX, 1),        AXIS(79, "ArrowRight", CMDR_KEY_LX, 1),
    AXIS(4, "KeyA", CMDR_KEY_LX, -1),       AXIS(80, "ArrowLeft", CMDR_KEY_LX, -1),
    AXIS(26, "KeyW", CMDR_KEY_LY, 1),       AXIS(82, "ArrowUp", CMDR_KEY_LY, 1),
    AXIS(22, "KeyS", CMDR_KEY_LY, -1),      AXIS(81, "ArrowDown", CMDR_KEY_LY, -1),
    AXIS(8, "KeyE", CMDR_KEY_RX, 1),        AXIS(20, "KeyQ", CMDR_KEY_RX, -1),
    AXIS(21, "KeyR", CMDR_KEY_RY, 1),       AXIS(9, "KeyF", CMDR_KEY_RY, -1),
    AXIS(29, "KeyZ", CMDR_KEY_LT, 1),       AXIS(78, "PageDown", CMDR_KEY_LT, 1),
    AXIS(27, "KeyX", CMDR_KEY_RT, 1),       AXIS(75, "PageUp", CMDR_KEY_RT, 1),
    BUTTON(44, "Space", PAD_SOUTH),         BUTTON(40, "Enter", PAD_SOUTH),
    BUTTON(19, "KeyP", PAD_WEST),           BUTTON(6, "KeyC", PAD_EAST),
    BUTTON(76, "Delete", PAD_NORTH),        BUTTON(47, "BracketLeft", PAD_LSHOULDER),
    BUTTON(48, "BracketRight", PAD_RSHOULDER), BUTTON(43, "Tab", PAD_BACK),
    BUTTON(74, "Home", PAD_RSTICK),
};

bool cmdr_keys_pad(const bool down[CMDR_KEYS], pad_state *s)
{
    pad_state_init(s);
    bool plus[CMDR_KEY_BUTTON] = {false}, minus[CMDR_KEY_BUTTON] = {false};
    for (int i = 0; i < CMDR_KEYS; i++) {
        const cmdr_key *k = &cmdr_key_table[i];
        if (!down[i]) continue;
        if (k->to == CMDR_KEY_BUTTON) s->buttons |= k->button;
        else if (k->sign > 0) plus[k->to] = true;
        else minus[k->to] = true;
    }
    float *axis[CMDR_KEY_BUTTON] = {&s->lx, &s->ly, &s->rx, &s->ry, &s->lt, &s->rt};
    bool any = s->buttons != 0;
    for (int a = 0; a < CMDR_KEY_BUTTON; a++) {
        *axis[a] = (float)(plus[a] - minus[a]);
        any |= *axis[a] != 0;
    }
    return any;
}
#undef AXIS
#undef BUTTON

/* ---- latency samples ------------------------------------------------------------------ */

void cmdr_lat_add(cmdr_lat *l, double ms)
{
    l->v[l->next] = (float)ms;
    l->next = (l->next + 1) % CMDR_LAT_SAMPLES;
    if (l->n < CMDR_LAT_SAMPLES) l->n++;
    l->total++;
}

static int cmp_f(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

double cmdr_lat_pct(const cmdr_lat *l, double p)
{
    if (!l->n) return NAN;
    float s[CMDR_LAT_SAMPLES]; /* 16 KiB */
    memcpy(s, l->v, l->n * sizeof *s);
    qsort(s, l->n, sizeof *s, cmp_f);
    /* nearest rank */
    double r = ceil(p / 100 * l->n);
    size_t i = r < 1 ? 0 : (size_t)r - 1;
    if (i >= l->n) i = l->n - 1;
    return s[i];
}
