/*
 * scenario.c — parsing `vantage bench` scenarios, camera paths and the
 * open-loop schedule (scenario.h). A rejected file gives one message
 * naming the line and the field; nothing is half-filled (the caller's
 * struct is written only on success).
 */
#include "scenario.h"

#include "protocol.h"
#include "vp_grow.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define MAX_WORDS 48

typedef struct pctx {
    const char *file;
    int line;
    char *err;
    size_t errlen;
} pctx;

__attribute__((format(printf, 3, 4))) static int fail(pctx *p, const char *field, const char *fmt, ...)
{
    char what[256];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(what, sizeof what, fmt, ap);
    va_end(ap);
    snprintf(p->err, p->errlen, "%s:%d: field '%s': %s", p->file, p->line, field, what);
    return -1;
}

static int num(pctx *p, const char *field, const char *w, double lo, double hi, double *out)
{
    if (!w) return fail(p, field, "a number is missing");
    char *end;
    errno = 0;
    double v = strtod(w, &end);
    if (end == w || *end || errno || !isfinite(v)) return fail(p, field, "expected a number, got '%s'", w);
    if (v < lo || v > hi) return fail(p, field, "%s is outside %g..%g", w, lo, hi);
    *out = v;
    return 0;
}

static int count(pctx *p, const char *field, const char *w, double lo, double hi, uint32_t *out)
{
    double v;
    if (num(p, field, w, lo, hi, &v)) return -1;
    if (v != floor(v)) return fail(p, field, "expected a whole number, got '%s'", w);
    *out = (uint32_t)v;
    return 0;
}

static int vec3(pctx *p, const char *field, const char *w, double out[3])
{
    if (!w) return fail(p, field, "a point x,y,z is missing");
    char *end;
    const char *s = w;
    for (int i = 0; i < 3; i++) {
        errno = 0;
        out[i] = strtod(s, &end);
        if (end == s || errno || !isfinite(out[i]) || fabs(out[i]) > 1e9) return fail(p, field, "expected x,y,z, got '%s'", w);
        if (i < 2 && *end != ',') return fail(p, field, "expected x,y,z, got '%s'", w);
        s = end + (i < 2);
    }
    if (*end) return fail(p, field, "expected x,y,z, got '%s'", w);
    return 0;
}

static int split(char *line, char **w)
{
    int n = 0;
    char *hash = strchr(line, '#');
    if (hash) *hash = 0;
    for (char *t = strtok(line, " \t\r\n"); t; t = strtok(NULL, " \t\r\n")) {
        if (n == MAX_WORDS) return -1;
        w[n++] = t;
    }
    return n;
}

static int name_copy(pctx *p, const char *field, const char *w, char *dst, size_t cap)
{
    if (!w) return fail(p, field, "a name is missing");
    size_t n = strlen(w);
    if (n >= cap) return fail(p, field, "'%s' is longer than %zu bytes", w, cap - 1);
    for (size_t i = 0; i < n; i++)
        if ((unsigned char)w[i] < 0x21 || (unsigned char)w[i] > 0x7e)
            return fail(p, field, "'%s': names are printable ASCII without spaces", w);
    memcpy(dst, w, n + 1);
    return 0;
}

/* The words after "camera". */
static int parse_camera(pctx *p, char **w, int n, scn_camera *c)
{
    if (n < 1) return fail(p, "camera", "expected fixed, orbit, path or pan");
    memset(c, 0, sizeof *c);
    if (!strcmp(w[0], "fixed")) {
        if (n != 3) return fail(p, "camera fixed", "expected: camera fixed EYE AT (points x,y,z)");
        c->kind = SCN_CAM_FIXED;
        if (vec3(p, "camera fixed eye", w[1], c->a) || vec3(p, "camera fixed at", w[2], c->b)) return -1;
        double d[3] = {c->b[0] - c->a[0], c->b[1] - c->a[1], c->b[2] - c->a[2]};
        if (d[0] * d[0] + d[1] * d[1] + d[2] * d[2] < 1e-12) return fail(p, "camera fixed at", "the same point as the eye");
        return 0;
    }
    if (!strcmp(w[0], "orbit") || !strcmp(w[0], "pan")) {
        const char *what = w[0][0] == 'o' ? "camera orbit" : "camera pan";
        if (n != 5) return fail(p, what, "expected: %s CENTER RADIUS HEIGHT PERIOD", what);
        c->kind = w[0][0] == 'o' ? SCN_CAM_ORBIT : SCN_CAM_PAN;
        if (vec3(p, "center", w[1], c->a) || num(p, "radius", w[2], 0, 1e6, &c->radius) ||
            num(p, "height", w[3], 1e-3, 1e6, &c->height) || num(p, "period", w[4], 1e-3, 1e6, &c->period))
            return -1;
        if (c->kind == SCN_CAM_ORBIT && c->radius <= 0) return fail(p, "radius", "an orbit needs a radius above 0");
        return 0;
    }
    if (!strcmp(w[0], "path")) {
        c->kind = SCN_CAM_PATH;
        if (n < 4) return fail(p, "camera path", "expected: camera path PERIOD P1 P2 ... (two points at least)");
        if (n - 2 > SCN_MAX_PATH) return fail(p, "camera path", "at most %d points", SCN_MAX_PATH);
        if (num(p, "period", w[1], 1e-3, 1e6, &c->period)) return -1;
        for (int i = 2; i < n; i++)
            if (vec3(p, "camera path point", w[i], c->pts[c->npts++])) return -1;
        for (int i = 0; i < c->npts; i++) {
            const double *a = c->pts[i], *b = c->pts[(i + 1) % c->npts];
            if (fabs(a[0] - b[0]) + fabs(a[1] - b[1]) + fabs(a[2] - b[2]) < 1e-9)
                return fail(p, "camera path point", "point %d repeats the one before it", (i + 1) % c->npts + 1);
        }
        return 0;
    }
    return fail(p, "camera", "'%s': expected fixed, orbit, path or pan", w[0]);
}

static int parse_op(pctx *p, char **w, int n, scn_group *g)
{
    if (n < 1) return fail(p, "op", "expected query, edit, ping, frames or commander");
    static const char *ops[] = {"query", "edit", "ping", "frames", "commander"};
    int k = -1;
    for (int i = 0; i < 5; i++)
        if (!strcmp(w[0], ops[i])) k = i;
    if (k < 0) return fail(p, "op", "'%s': expected query, edit, ping, frames or commander", w[0]);
    if (g->have_op) return fail(p, "op", "group '%s' has an op already (one per group)", g->name);
    g->op = (enum scn_op)k;
    g->have_op = true;
    for (int i = 1; i < n; i++) {
        const char *key = w[i], *val = i + 1 < n ? w[i + 1] : NULL;
        uint32_t u;
        double d;
        if (g->op == SCN_QUERY && !strcmp(key, "count-only")) {
            g->qflags |= VP_Q_COUNT_ONLY;
        } else if (g->op == SCN_QUERY && !strcmp(key, "no-occlusion")) {
            g->qflags |= VP_Q_NO_OCCLUSION;
        } else if (g->op == SCN_QUERY && !strcmp(key, "views")) {
            if (count(p, "views", val, 1, VP_MAX_VIEWS, &g->views)) return -1;
            i++;
        } else if (g->op == SCN_EDIT && !strcmp(key, "batch")) {
            if (count(p, "batch", val, 1, 65536, &g->batch)) return -1;
            i++;
        } else if ((g->op == SCN_FRAMES || g->op == SCN_COMMANDER) && !strcmp(key, "size")) {
            unsigned fw = 0, fh = 0;
            char tail;
            if (!val || sscanf(val, "%ux%u%c", &fw, &fh, &tail) != 2 || fw < 16 || fh < 16 || fw > 4096 || fh > 4096)
                return fail(p, "size", "expected WxH, 16..4096 each, got '%s'", val ? val : "");
            g->w = (uint16_t)fw;
            g->h = (uint16_t)fh;
            i++;
        } else if ((g->op == SCN_FRAMES || g->op == SCN_COMMANDER) && !strcmp(key, "fps")) {
            if (count(p, "fps", val, 1, VP_FRAME_SUB_MAX_FPS, &u)) return -1;
            g->fps = (uint16_t)u;
            i++;
        } else if ((g->op == SCN_FRAMES || g->op == SCN_COMMANDER) && !strcmp(key, "quality")) {
            if (count(p, "quality", val, 1, 100, &u)) return -1;
            g->quality = (uint8_t)u;
            i++;
        } else if (g->op == SCN_FRAMES && !strcmp(key, "format")) {
            if (!val || (strcmp(val, "jpeg") && strcmp(val, "raw")))
                return fail(p, "format", "expected jpeg or raw, got '%s'", val ? val : "");
            g->format = !strcmp(val, "raw") ? VP_FRAME_RAW : VP_FRAME_JPEG;
            i++;
        } else if ((g->op == SCN_FRAMES || g->op == SCN_COMMANDER) && !strcmp(key, "renderer")) {
            if (!val || (strcmp(val, "soft") && strcmp(val, "gl")))
                return fail(p, "renderer", "expected soft or gl, got '%s'", val ? val : "");
            g->renderer = !strcmp(val, "gl") ? VP_RENDERER_GL : VP_RENDERER_SOFT;
            i++;
        } else if (g->op == SCN_COMMANDER && !strcmp(key, "reaim")) {
            if (num(p, "reaim", val, 0.1, 1000, &d)) return -1;
            g->reaim_hz = d;
            i++;
        } else {
            return fail(p, key, "not an option of op %s", ops[k]);
        }
    }
    return 0;
}

static int parse_event(pctx *p, char **w, int n, scenario *s)
{
    if (s->nev == SCN_MAX_EVENTS) return fail(p, "at", "more than %d events", SCN_MAX_EVENTS);
    scn_event e = {.line = p->line, .spread = 100, .radius = 2, .rate = 0};
    if (n < 3) return fail(p, "at", "expected: at SECONDS sublevel load|unload NAME ... or at SECONDS destroy N ...");
    if (num(p, "at", w[1], 0, 1e6, &e.at)) return -1;
    int i;
    if (!strcmp(w[2], "sublevel")) {
        if (n < 5 || (strcmp(w[3], "load") && strcmp(w[3], "unload")))
            return fail(p, "sublevel", "expected: sublevel load NAME [entities N] [spread M] or sublevel unload NAME");
        e.kind = w[3][0] == 'l' ? SCN_EV_LOAD : SCN_EV_UNLOAD;
        if (name_copy(p, "sublevel name", w[4], e.name, sizeof e.name)) return -1;
        e.n = e.kind == SCN_EV_LOAD ? 1000 : 0;
        i = 5;
    } else if (!strcmp(w[2], "destroy")) {
        e.kind = SCN_EV_DESTROY;
        if (count(p, "destroy", n > 3 ? w[3] : NULL, 1, 1e6, &e.n)) return -1;
        i = 4;
    } else {
        return fail(p, "at", "'%s': expected sublevel or destroy", w[2]);
    }
    for (; i < n; i += 2) {
        const char *key = w[i], *val = i + 1 < n ? w[i + 1] : NULL;
        uint32_t u;
        if (e.kind == SCN_EV_LOAD && !strcmp(key, "entities")) {
            if (count(p, "entities", val, 1, 1e6, &e.n)) return -1;
        } else if (e.kind == SCN_EV_LOAD && !strcmp(key, "spread")) {
            if (num(p, "spread", val, 1, 1e6, &e.spread)) return -1;
        } else if (e.kind == SCN_EV_DESTROY && !strcmp(key, "rate")) {
            if (num(p, "rate", val, 0.01, 1e6, &e.rate)) return -1;
        } else if (e.kind == SCN_EV_DESTROY && !strcmp(key, "radius")) {
            if (num(p, "radius", val, 0.01, 1000, &e.radius)) return -1;
        } else if (e.kind == SCN_EV_DESTROY && !strcmp(key, "debris")) {
            if (count(p, "debris", val, 0, 64, &u)) return -1;
            e.debris = (uint8_t)u;
        } else {
            return fail(p, key, "not an option of this event");
        }
    }
    s->ev[s->nev++] = e;
    return 0;
}

static int check_group(pctx *p, const scn_group *g)
{
    p->line = g->line;
    if (!g->have_op) return fail(p, "op", "group '%s' has no op", g->name);
    if (!g->clients) return fail(p, "clients", "group '%s' has no clients line", g->name);
    if (g->op == SCN_EDIT && g->role != SCN_ROLE_EDITOR) return fail(p, "role", "group '%s': op edit needs role editor", g->name);
    if (g->role == SCN_ROLE_QUERY && g->op != SCN_QUERY && g->op != SCN_PING)
        return fail(p, "role", "group '%s': role query only queries (op query or ping)", g->name);
    if (g->op == SCN_COMMANDER && g->role == SCN_ROLE_VIEWER)
        return fail(p, "role", "group '%s': op commander needs role commander or editor (its own camera)", g->name);
    if ((g->op == SCN_FRAMES || g->op == SCN_COMMANDER) && g->rate > 0)
        return fail(p, "rate", "group '%s': frames come at the subscription's fps; use fps, not rate", g->name);
    return 0;
}

int scn_parse(const char *name, const char *text, size_t n, scenario *out, char *err, size_t errlen)
{
    scenario *s = calloc(1, sizeof *s);
    char *buf = malloc(n + 1);
    if (!s || !buf) {
        free(s);
        free(buf);
        snprintf(err, errlen, "%s: out of memory", name);
        return -1;
    }
    memcpy(buf, text, n);
    buf[n] = 0;
    pctx p = {.file = name, .err = err, .errlen = errlen};
    int rc = 0;
    s->duration = 10;
    snprintf(s->name, sizeof s->name, "scenario");
    scn_group *g = NULL;
    const char *nul = memchr(buf, 0, n);
    if (nul) {
        for (const char *c = buf; c < nul; c++) p.line += *c == '\n';
        p.line++;
        rc = fail(&p, "line", "a NUL byte: not a text file");
    }
    char *line = rc ? NULL : buf;
    for (char *next; line && rc == 0; line = next) {
        p.line++;
        next = strchr(line, '\n');
        if (next) *next++ = 0;
        if (strlen(line) > 4096) {
            rc = fail(&p, "line", "longer than 4096 bytes");
            break;
        }
        for (char *c = line; *c; c++)
            if ((unsigned char)*c < 0x20 && *c != '\t' && *c != '\r') {
                rc = fail(&p, "line", "a control byte 0x%02x", (unsigned char)*c);
                break;
            }
        if (rc) break;
        char *w[MAX_WORDS];
        int nw = split(line, w);
        if (nw < 0) {
            rc = fail(&p, "line", "more than %d words", MAX_WORDS);
            break;
        }
        if (nw == 0) continue;
        const char *k = w[0], *v = nw > 1 ? w[1] : NULL;
        if (!strcmp(k, "group")) {
            if (nw != 2) {
                rc = fail(&p, "group", "expected: group NAME");
            } else if (s->ng == SCN_MAX_GROUPS) {
                rc = fail(&p, "group", "more than %d groups", SCN_MAX_GROUPS);
            } else {
                g = &s->g[s->ng++];
                *g = (scn_group){.line = p.line, .role = SCN_ROLE_VIEWER, .pipeline = 1, .batch = 100, .views = 1,
                                 .w = 320, .h = 180, .fps = 10, .quality = 75, .format = VP_FRAME_JPEG,
                                 .renderer = VP_RENDERER_SOFT, .reaim_hz = 60,
                                 .cam = {.kind = SCN_CAM_ORBIT, .radius = 300, .height = 120, .period = 30}};
                rc = name_copy(&p, "group", v, g->name, sizeof g->name);
                for (int i = 0; rc == 0 && i < s->ng - 1; i++)
                    if (!strcmp(s->g[i].name, g->name)) rc = fail(&p, "group", "'%s' is named twice", g->name);
            }
        } else if (g && !strcmp(k, "role")) {
            static const char *roles[] = {"viewer", "commander", "editor", "query"};
            int r = -1;
            for (int i = 0; v && i < 4; i++)
                if (!strcmp(v, roles[i])) r = i;
            if (r < 0 || nw != 2) rc = fail(&p, "role", "expected editor, viewer, commander or query, got '%s'", v ? v : "");
            else g->role = (enum scn_role)r;
        } else if (g && !strcmp(k, "clients")) {
            rc = nw != 2 ? fail(&p, "clients", "expected: clients N") : count(&p, "clients", v, 1, 1000, &g->clients);
        } else if (g && !strcmp(k, "op")) {
            rc = parse_op(&p, w + 1, nw - 1, g);
        } else if (g && !strcmp(k, "rate")) {
            rc = nw != 2 ? fail(&p, "rate", "expected: rate PER_SECOND") : num(&p, "rate", v, 0.01, 1e6, &g->rate);
        } else if (g && !strcmp(k, "pipeline")) {
            rc = nw != 2 ? fail(&p, "pipeline", "expected: pipeline N") : count(&p, "pipeline", v, 1, 1000, &g->pipeline);
        } else if (g && !strcmp(k, "camera")) {
            rc = parse_camera(&p, w + 1, nw - 1, &g->cam);
        } else if (!g && !strcmp(k, "name")) {
            rc = nw != 2 ? fail(&p, "name", "expected: name NAME") : name_copy(&p, "name", v, s->name, sizeof s->name);
        } else if (!g && !strcmp(k, "duration")) {
            rc = nw != 2 ? fail(&p, "duration", "expected: duration SECONDS")
                         : num(&p, "duration", v, 0.1, 7 * 86400.0, &s->duration);
        } else if (!g && !strcmp(k, "requests")) {
            double d = 0;
            rc = nw != 2 ? fail(&p, "requests", "expected: requests N") : num(&p, "requests", v, 1, 1e12, &d);
            s->requests = (uint64_t)d;
        } else if (!g && !strcmp(k, "warmup")) {
            rc = nw != 2 ? fail(&p, "warmup", "expected: warmup SECONDS") : num(&p, "warmup", v, 0, 3600, &s->warmup);
        } else if (!g && !strcmp(k, "seed")) {
            double d = 0;
            rc = nw != 2 ? fail(&p, "seed", "expected: seed N") : num(&p, "seed", v, 0, 9007199254740992.0, &d);
            s->seed = (uint64_t)d;
        } else if (!g && !strcmp(k, "setup")) {
            if (nw < 3 || strcmp(w[1], "entities")) {
                rc = fail(&p, "setup", "expected: setup entities N [spread M] [height H]");
            } else {
                s->setup_spread = 200;
                s->setup_height = 20;
                rc = count(&p, "entities", w[2], 1, 1e6, &s->setup_n);
                for (int i = 3; rc == 0 && i < nw; i += 2) {
                    if (!strcmp(w[i], "spread")) rc = num(&p, "spread", i + 1 < nw ? w[i + 1] : NULL, 1, 1e6, &s->setup_spread);
                    else if (!strcmp(w[i], "height")) rc = num(&p, "height", i + 1 < nw ? w[i + 1] : NULL, 0, 1e6, &s->setup_height);
                    else rc = fail(&p, w[i], "not an option of setup entities (spread, height)");
                }
            }
        } else if (!g && !strcmp(k, "probe")) {
            double every = 0.5;
            if (nw != 2 && !(nw == 4 && !strcmp(w[2], "every"))) {
                rc = fail(&p, "probe", "expected: probe edit-to-query|edit-to-frame [every SECONDS]");
            } else if (nw == 4 && num(&p, "every", w[3], 0.01, 3600, &every)) {
                rc = -1;
            } else if (!strcmp(v, "edit-to-query")) {
                s->probe_query = every;
            } else if (!strcmp(v, "edit-to-frame")) {
                s->probe_frame = every;
            } else {
                rc = fail(&p, "probe", "'%s': expected edit-to-query or edit-to-frame", v);
            }
        } else if (!g && !strcmp(k, "at")) {
            rc = parse_event(&p, w, nw, s);
        } else if (g && (!strcmp(k, "name") || !strcmp(k, "duration") || !strcmp(k, "requests") ||
                         !strcmp(k, "warmup") || !strcmp(k, "seed") || !strcmp(k, "setup") ||
                         !strcmp(k, "probe") || !strcmp(k, "at"))) {
            rc = fail(&p, k, "a top-level setting inside group '%s' (put it before the first group)", g->name);
        } else {
            rc = fail(&p, k, g ? "not a group setting (role, clients, op, rate, pipeline, camera)"
                               : "unknown (name, duration, requests, warmup, seed, setup, probe, at, group)");
        }
    }
    if (rc == 0 && s->ng == 0) {
        p.line = 0;
        rc = fail(&p, "group", "no groups: a scenario needs at least one");
    }
    for (int i = 0; rc == 0 && i < s->ng; i++) rc = check_group(&p, &s->g[i]);
    for (int i = 0; rc == 0 && i < s->nev; i++) {
        scn_event *e = &s->ev[i];
        p.line = e->line;
        if (!s->requests && e->at >= s->duration) /* the file's duration, or the default 10 s */
            rc = fail(&p, "at", "%g s is at or after the end of the run (duration %g s)", e->at, s->duration);
        if (rc == 0 && e->kind == SCN_EV_DESTROY && !s->setup_n)
            rc = fail(&p, "destroy", "destruction needs entities: add 'setup entities N'");
        if (rc == 0 && e->kind == SCN_EV_UNLOAD) {
            bool loaded = false;
            for (int j = 0; j < s->nev; j++)
                if (s->ev[j].kind == SCN_EV_LOAD && !strcmp(s->ev[j].name, e->name) && s->ev[j].at <= e->at) loaded = true;
            if (!loaded) rc = fail(&p, "sublevel name", "'%s' is unloaded before any load of it", e->name);
        }
    }
    if (rc == 0 && s->warmup >= s->duration && !s->requests) {
        p.line = 0;
        rc = fail(&p, "warmup", "%g s is not shorter than the run (%g s)", s->warmup, s->duration);
    }
    if (rc == 0) *out = *s;
    free(s);
    free(buf);
    return rc;
}

int scn_load(const char *path, scenario *s, char *err, size_t errlen)
{
    FILE *f = fopen(path, "rb");
    if (!f) {
        snprintf(err, errlen, "%s: %s", path, strerror(errno));
        return -1;
    }
    size_t cap = 1 << 16, n = 0;
    char *text = malloc(cap);
    while (text) {
        size_t r = fread(text + n, 1, cap - n, f);
        n += r;
        if (r == 0) break;
        if (n == cap) {
            if (cap >= (1u << 20)) {
                fclose(f);
                free(text);
                snprintf(err, errlen, "%s: over 1 MiB: not a scenario", path);
                return -1;
            }
            if (!vp_grow((void **)&text, &cap, cap + 1, 1)) break;
        }
    }
    bool bad = ferror(f);
    fclose(f);
    if (!text || bad) {
        free(text);
        snprintf(err, errlen, "%s: %s", path, bad ? "read error" : "out of memory");
        return -1;
    }
    int rc = scn_parse(path, text, n, s, err, errlen);
    free(text);
    return rc;
}

static void lerp3(const double *a, const double *b, double f, double *o)
{
    for (int i = 0; i < 3; i++) o[i] = a[i] + (b[i] - a[i]) * f;
}

void scn_camera_at(const scn_camera *c, double t, int phase, int nphase, double eye[3], double at[3])
{
    double ph = nphase > 0 ? (double)phase / nphase : 0.0;
    switch (c->kind) {
    case SCN_CAM_FIXED:
        memcpy(eye, c->a, sizeof c->a);
        memcpy(at, c->b, sizeof c->b);
        return;
    case SCN_CAM_ORBIT:
    case SCN_CAM_PAN: {
        double a = 2 * M_PI * (t / c->period + ph);
        double x = c->a[0] + cos(a) * c->radius, z = c->a[2] + sin(a) * c->radius;
        if (c->kind == SCN_CAM_ORBIT) {
            eye[0] = x, eye[1] = c->a[1] + c->height, eye[2] = z;
            memcpy(at, c->a, sizeof c->a);
        } else { /* straight down over a point circling the centre */
            eye[0] = x, eye[1] = c->a[1] + c->height, eye[2] = z;
            at[0] = x, at[1] = c->a[1], at[2] = z;
        }
        return;
    }
    case SCN_CAM_PATH: {
        /* constant speed along the closed polyline */
        double len[SCN_MAX_PATH], total = 0;
        for (int i = 0; i < c->npts; i++) {
            const double *a = c->pts[i], *b = c->pts[(i + 1) % c->npts];
            len[i] = sqrt((b[0] - a[0]) * (b[0] - a[0]) + (b[1] - a[1]) * (b[1] - a[1]) + (b[2] - a[2]) * (b[2] - a[2]));
            total += len[i];
        }
        double u = fmod(t / c->period + ph, 1.0);
        if (u < 0) u += 1;
        double d = u * total;
        int i = 0;
        while (i < c->npts - 1 && d > len[i]) d -= len[i++];
        const double *a = c->pts[i], *b = c->pts[(i + 1) % c->npts];
        lerp3(a, b, len[i] > 0 ? d / len[i] : 0, eye);
        for (int k = 0; k < 3; k++) at[k] = eye[k] + (b[k] - a[k]);
        return;
    }
    }
}

void scn_sched_init(scn_sched *s, double t0, double rate)
{
    s->t0 = t0;
    s->period = rate > 0 ? 1.0 / rate : 0;
    s->next = 0;
}

uint64_t scn_sched_due(const scn_sched *s, double now)
{
    if (!(s->period > 0) || now < s->t0) return 0;
    uint64_t upto = (uint64_t)floor((now - s->t0) / s->period) + 1; /* requests 0..upto-1 are due */
    return upto > s->next ? upto - s->next : 0;
}

double scn_sched_time(const scn_sched *s, uint64_t k)
{
    return s->t0 + (double)k * s->period;
}

const char *scn_op_name(enum scn_op op)
{
    static const char *n[] = {"query", "edit", "ping", "frames", "commander"};
    return (unsigned)op < 5 ? n[op] : "?";
}
