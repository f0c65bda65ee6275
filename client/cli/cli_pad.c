/*
 * cli_pad.c — `vantage pad list` (the game controllers present, not
 * opened) and `vantage pad dump` (one JSON line of normalized state per
 * state change, from live pads or a hid-recorder file, optionally
 * recording what live pads send). Neither talks to the daemon.
 *
 * The dump's loop is the one the commander uses: poll the hub's fd, drain
 * pad_hub_next. It wakes at most every 200 ms (Ctrl-C, --seconds) besides
 * the events; a line is written and flushed per state change (a pad at
 * 1000 reports a second that changes state on each is 1000 lines a
 * second: stdout is the limit, and the hub merges what it cannot take).
 */
#include "cli.h"
#include "pad.h"
#include "pad_io.h"
#include "vp_grow.h"

#include <errno.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define PAD_LIST_MAX 64 /* pads shown by pad list: more than anyone plugs in */

/* the usage and --help: vantage_cli.c, forms[] */
static const char *const no_access_hint =
    "no controllers found\n"
    "a pad that is plugged in but not listed is usually one you may not open: PlayStation and Switch\n"
    "pads need read/write access to their /dev/hidraw* node, Xbox pads to their /dev/bus/usb/BUS/DEV\n"
    "node (a udev rule with TAG+=\"uaccess\", or MODE=\"0660\" and a group you are in); Bluetooth pads\n"
    "must be paired and connected first\n";

static int pad_list(int argc, char **argv)
{
    bool json = false;
    for (int i = 2; i < argc; i++) {
        if (!strcmp(argv[i], "--json")) json = true;
        else return die_usage("pad list [--json]");
    }
    pad_found *found = calloc(PAD_LIST_MAX, sizeof *found);
    if (!found) {
        fprintf(stderr, "%s: pad list: out of memory\n", g_prog);
        return 1;
    }
    char err[256];
    int n = pad_enumerate(NULL, found, PAD_LIST_MAX, err, sizeof err);
    if (n < 0) {
        fprintf(stderr, "%s: pad list: %s\n", g_prog, err);
        free(found);
        return 1;
    }
    if (err[0]) fprintf(stderr, "%s: pad list: %s\n", g_prog, err); /* one backend missing: said, not fatal */
    int shown = n < PAD_LIST_MAX ? n : PAD_LIST_MAX;
    if (!json && shown) printf("%-9s  %-28s %-11s %-7s %s\n", "vid:pid", "name", "protocol", "path", "where");
    for (int i = 0; i < shown; i++) {
        const pad_found *f = &found[i];
        const char *path = f->info->path == PAD_PATH_HIDRAW ? "hidraw" : "libusb";
        if (json) {
            printf("{\"vid\": \"%04x\", \"pid\": \"%04x\", \"name\": ", f->info->vid, f->info->pid);
            cli_json_str(stdout, f->info->name, strlen(f->info->name));
            printf(", \"protocol\": \"%s\", \"path\": \"%s\", \"where\": ", pad_proto_name(f->info->proto), path);
            cli_json_str(stdout, f->where, strlen(f->where));
            printf(", \"product\": ");
            cli_json_str(stdout, f->product, strlen(f->product));
            printf("}\n");
        } else {
            char name[160];
            if (f->product[0] && strcmp(f->product, f->info->name))
                snprintf(name, sizeof name, "%s (%s)", f->info->name, f->product);
            else
                snprintf(name, sizeof name, "%s", f->info->name);
            printf("%04x:%04x  %-28s %-11s %-7s %s\n", f->info->vid, f->info->pid, name,
                   pad_proto_name(f->info->proto), path, f->where);
        }
    }
    if (n > shown) fprintf(stderr, "%s: pad list: %d more not shown\n", g_prog, n - shown);
    if (n == 0) fputs(no_access_hint, json ? stderr : stdout);
    free(found);
    return 0;
}

/* The pads dump has seen, for --stats (counts taken while each is there). */
typedef struct seen_pad {
    uint32_t id;
    const pad_device_info *info;
    pad_counts c;
    uint64_t lines;
    bool gone;
} seen_pad;

typedef struct dump_stats {
    seen_pad *p;
    size_t n, cap;
} dump_stats;

static seen_pad *stats_pad(dump_stats *s, uint32_t id, const pad_device_info *info)
{
    for (size_t i = 0; i < s->n; i++)
        if (s->p[i].id == id) return &s->p[i];
    if (!vp_grow((void **)&s->p, &s->cap, s->n + 1, sizeof *s->p)) return NULL;
    seen_pad *p = &s->p[s->n++];
    memset(p, 0, sizeof *p);
    p->id = id;
    p->info = info;
    return p;
}

static void stats_refresh(pad_hub *h, dump_stats *s)
{
    for (size_t i = 0; i < s->n; i++)
        if (!s->p[i].gone) pad_hub_counts(h, s->p[i].id, &s->p[i].c);
}

static int pad_dump(int argc, char **argv)
{
    const char *use = "pad dump [--replay FILE [--speed X] [--loop]] [--record FILE] [--count N] [--seconds S] "
                      "[--stats]";
    pad_hub_opts o = {0};
    uint64_t count = 0;
    double seconds = 0, speed = 1;
    bool stats = false, have_speed = false;
    for (int i = 2; i < argc; i++) {
        const char *a = argv[i];
        if (!strcmp(a, "--stats")) {
            stats = true;
            continue;
        }
        if (!strcmp(a, "--loop")) {
            o.replay_loop = true;
            continue;
        }
        /* the rest take a value */
        const char *v = i + 1 < argc ? argv[++i] : NULL;
        bool ok;
        if (!v) return die_usage("%s", use);
        if (!strcmp(a, "--replay")) ok = (o.replay = v) != NULL;
        else if (!strcmp(a, "--record")) ok = (o.record = v) != NULL;
        else if (!strcmp(a, "--count")) ok = parse_u64(v, &count) && count > 0;
        else if (!strcmp(a, "--seconds")) ok = parse_vec(v, &seconds, 1) && seconds > 0;
        else if (!strcmp(a, "--speed")) ok = (have_speed = true) && parse_vec(v, &speed, 1) && speed != 0;
        else return die_usage("%s", use);
        if (!ok) return die_usage("pad dump: bad value %s for %s", v, a);
    }
    if ((have_speed || o.replay_loop) && !o.replay) return die_usage("pad dump: --speed and --loop go with --replay");
    o.replay_speed = speed;
    pad_hub *h = NULL;
    char err[512];
    if (pad_hub_open(&o, &h, err, sizeof err)) {
        fprintf(stderr, "%s: pad dump: %s\n", g_prog, err);
        return 1;
    }
    catch_sigint();
    if (!o.replay) fprintf(stderr, "reading pads (plug one in; Ctrl-C to stop)\n");
    dump_stats st = {0};
    double t0 = now_s();
    uint64_t lines = 0;
    int rc = 0;
    bool end = false;
    char buf[1024];
    while (!g_stop && !end && (!count || lines < count)) {
        int wait_ms = 200;
        if (seconds > 0) {
            double left = seconds - (now_s() - t0);
            if (left <= 0) break;
            if (left * 1000 < wait_ms) wait_ms = (int)(left * 1000) + 1;
        }
        struct pollfd pfd = {.fd = pad_hub_fd(h), .events = POLLIN};
        if (poll(&pfd, 1, wait_ms) < 0 && errno != EINTR) {
            fprintf(stderr, "%s: pad dump: poll: %s\n", g_prog, strerror(errno));
            rc = 1;
            break;
        }
        pad_event ev;
        while (!end && (!count || lines < count) && pad_hub_next(h, &ev)) {
            seen_pad *sp = ev.pad ? stats_pad(&st, ev.pad, ev.info) : NULL;
            switch (ev.kind) {
            case PAD_EV_ADDED: fprintf(stderr, "pad %u added: %s\n", ev.pad, ev.msg); break;
            case PAD_EV_REMOVED:
                if (sp) {
                    pad_hub_counts(h, ev.pad, &sp->c); /* if it is still there: its message has the rest */
                    sp->gone = true;
                }
                fprintf(stderr, "pad %u removed: %s\n", ev.pad, ev.msg);
                break;
            case PAD_EV_ERROR:
                if (ev.pad) fprintf(stderr, "pad %u error: %s\n", ev.pad, ev.msg);
                else fprintf(stderr, "error: %s\n", ev.msg);
                break;
            case PAD_EV_END: end = true; break;
            case PAD_EV_STATE: {
                int n = pad_state_json(&ev.state, ev.t_file, buf, sizeof buf);
                if (n < 2 || (size_t)n >= sizeof buf || buf[0] != '{') break; /* cannot happen: the state is bounded */
                /* the pad's id first, so several pads' lines can be told apart */
                printf("{\"pad\":%u,%s\n", ev.pad, buf + 1);
                if (sp) sp->lines++;
                lines++;
                break;
            }
            }
        }
        if (fflush(stdout)) {
            fprintf(stderr, "%s: pad dump: stdout: %s\n", g_prog, strerror(errno));
            rc = 1;
            break;
        }
        if (stats) stats_refresh(h, &st);
    }
    if (stats && st.n) {
        stats_refresh(h, &st);
        fprintf(stderr, "%-4s %-24s %10s %10s %8s %10s %8s %10s\n", "pad", "name", "reports", "ignored", "refused",
                "changes", "merged", "lines");
        for (size_t i = 0; i < st.n; i++) {
            const seen_pad *p = &st.p[i];
            fprintf(stderr, "%-4u %-24s %10llu %10llu %8llu %10llu %8llu %10llu\n", p->id,
                    p->info ? p->info->name : "?", (unsigned long long)p->c.reports, (unsigned long long)p->c.ignored,
                    (unsigned long long)p->c.errors, (unsigned long long)p->c.states, (unsigned long long)p->c.merged,
                    (unsigned long long)p->lines);
        }
    }
    if (stats) {
        double dt = now_s() - t0;
        fprintf(stderr, "%llu lines in %.2f s (%.0f/s)\n", (unsigned long long)lines, dt, dt > 0 ? lines / dt : 0.0);
    }
    free(st.p);
    pad_hub_close(h);
    return rc;
}

int cmd_pad(cli *k, int argc, char **argv)
{
    (void)k; /* no daemon: pads are local */
    if (argc < 2) return die_usage("pad list | pad dump: which one?");
    if (!strcmp(argv[1], "list")) return pad_list(argc, argv);
    if (!strcmp(argv[1], "dump")) return pad_dump(argc, argv);
    return die_usage("pad %s: not list or dump", argv[1]);
}
