/*
 * pad_replay.c — the replay backend: a hid-recorder file (pad_line.c reads
 * its lines) delivered through the hub's report path as if its pads were
 * plugged in, at the file's timing scaled by replay_speed, or as fast as
 * the caller drains the queue (speed < 0), looped on request. No library
 * is touched, so a replay works where no pad could.
 *
 * pad_hub_open checks the whole file first (pad_replay_load: a bad line
 * fails the open, naming it, instead of a replay half done); the replay
 * thread then reads it again line by line as it delivers. Memory: the
 * devices only. Each device's times are placed on one replay clock from
 * its first report (and again when they go back), so our --record files
 * (each pad from 0) and hid-recorder's (one shared origin) both replay.
 */
#include "pad_io_internal.h"
#include "protocol.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

/* One line of the file into *buf (its newline and CRs before it cut); -1 at
 * the end. *buf grows as getline's does. */
static ssize_t next_line(FILE *f, char **buf, size_t *cap)
{
    ssize_t n = getline(buf, cap, f);
    if (n < 0) return -1;
    while (n > 0 && ((*buf)[n - 1] == '\n' || (*buf)[n - 1] == '\r')) n--;
    return n;
}

static pad_replay_dev *rdev_find(pad_hub *h, uint32_t index)
{
    for (size_t i = 0; i < h->nrdev; i++)
        if (h->rdev[i].index == index) return &h->rdev[i];
    return NULL;
}

/* found or made (NULL: out of memory); pad_replay_load's alone */
static pad_replay_dev *rdev_get(pad_hub *h, uint32_t index)
{
    pad_replay_dev *r = rdev_find(h, index);
    if (r) return r;
    r = realloc(h->rdev, (h->nrdev + 1) * sizeof *r);
    if (!r) return NULL;
    h->rdev = r;
    pad_replay_dev *d = &h->rdev[h->nrdev++];
    memset(d, 0, sizeof *d);
    d->index = index;
    return d;
}

/* The whole file checked before anything is delivered: a bad line fails
 * pad_hub_open naming it, not a replay half done. Memory: the devices
 * only; the reports are read again as they are delivered. */
int pad_replay_load(pad_hub *h, char *err, size_t errlen)
{
    const char *path = h->replay;
    h->rf = fopen(path, "r");
    if (!h->rf) {
        vp_errf(err, errlen, -1, "%s: %s", path, strerror(errno));
        return -1;
    }
    char *line = NULL;
    size_t cap = 0;
    ssize_t n;
    unsigned long lineno = 0;
    int rc = -1;
    pad_line *pl = malloc(sizeof *pl);
    if (!pl) {
        vp_errf(err, errlen, -1, "%s: out of memory", path);
        goto out;
    }
    pad_replay_dev *cur = NULL;
    while ((n = next_line(h->rf, &line, &cap)) >= 0) {
        lineno++;
        char why[160] = "";
        if (pad_line_parse(line, (size_t)n, pl, why, sizeof why)) {
            vp_errf(err, errlen, -1, "%s:%lu: %s", path, lineno, why[0] ? why : "malformed line");
            goto out;
        }
        if (pl->kind == PAD_LINE_DEVICE || (!cur && pl->kind != PAD_LINE_BLANK && pl->kind != PAD_LINE_OTHER)) {
            /* lines before the first D: belong to device 0, as hid-recorder's single-device files */
            if (!(cur = rdev_get(h, pl->kind == PAD_LINE_DEVICE ? pl->device : 0))) {
                vp_errf(err, errlen, -1, "%s: out of memory", path);
                goto out;
            }
        }
        switch (pl->kind) {
        case PAD_LINE_INFO:
            cur->info = pad_device_lookup(pl->vid, pl->pid);
            if (!cur->info) {
                vp_errf(err, errlen, -1, "%s:%lu: unknown device %04x:%04x (not a pad this build reads)", path, lineno,
                        pl->vid, pl->pid);
                goto out;
            }
            cur->have_info = true;
            cur->bus = pl->bus;
            cur->vid = pl->vid;
            cur->pid = pl->pid;
            break;
        case PAD_LINE_NAME: snprintf(cur->name, sizeof cur->name, "%s", pl->name); break;
        case PAD_LINE_EVENT:
            if (!cur->have_info) {
                vp_errf(err, errlen, -1, "%s:%lu: a report before device %u's I: line (which pad it is)", path, lineno,
                        cur->index);
                goto out;
            }
            break;
        default: break;
        }
    }
    if (ferror(h->rf)) {
        vp_errf(err, errlen, -1, "%s: %s", path, strerror(errno));
        goto out;
    }
    rc = 0;
out:
    free(line);
    free(pl);
    return rc;
}

/* Sleeps until CLOCK_MONOTONIC t or the hub closes; false when it closed. */
static bool sleep_until(pad_hub *h, double t)
{
    struct timespec ts = pad_mono_at(t);
    pthread_mutex_lock(&h->mu);
    while (!atomic_load(&h->stop) && pad_mono_now() < t)
        if (pthread_cond_timedwait(&h->wake, &h->mu, &ts) == ETIMEDOUT) break;
    pthread_mutex_unlock(&h->mu);
    return !atomic_load(&h->stop);
}

/* Waits until the caller has read every event (speed < 0). */
static bool wait_drained(pad_hub *h)
{
    pthread_mutex_lock(&h->qmu);
    while (!atomic_load(&h->stop) && h->head != h->tail) pthread_cond_wait(&h->drained, &h->qmu);
    pthread_mutex_unlock(&h->qmu);
    return !atomic_load(&h->stop);
}

void *pad_replay_main(void *arg)
{
    pad_hub *h = arg;
    char *line = NULL;
    size_t cap = 0;
    pad_line *pl = malloc(sizeof *pl);
    if (!pl) {
        pad_push_msg(h, NULL, PAD_EV_ERROR, "replay of %s: out of memory", h->replay);
        goto end;
    }
    /* the file's clock: each device's times are placed on it from its
       first report (and again when its times go back: a loop, or a file
       of concatenated captures), so devices recorded with their own
       origins (our --record) and hid-recorder's shared one both replay */
    double clock = 0, t0 = pad_mono_now();
    for (;;) {
        rewind(h->rf);
        pad_replay_dev *cur = NULL;
        unsigned long lineno = 0, reports = 0;
        ssize_t n;
        for (size_t i = 0; i < h->nrdev; i++) h->rdev[i].anchored = false;
        while ((n = next_line(h->rf, &line, &cap)) >= 0) {
            if (atomic_load(&h->stop)) goto end;
            lineno++;
            char why[160] = "";
            if (pad_line_parse(line, (size_t)n, pl, why, sizeof why)) {
                /* it passed at open: the file changed under us */
                pad_push_msg(h, NULL, PAD_EV_ERROR, "%s:%lu: %s (the file changed during the replay)", h->replay,
                             lineno, why);
                goto end;
            }
            /* found, never made: the table is fixed once the thread runs (pad_hub_counts reads it) */
            if (pl->kind == PAD_LINE_DEVICE || (!cur && pl->kind != PAD_LINE_BLANK && pl->kind != PAD_LINE_OTHER))
                cur = rdev_find(h, pl->kind == PAD_LINE_DEVICE ? pl->device : 0);
            if (pl->kind != PAD_LINE_EVENT) continue;
            if (!cur || !cur->have_info) {
                pad_push_msg(h, NULL, PAD_EV_ERROR, "%s:%lu: a report of an unknown device (the file changed during "
                             "the replay)", h->replay, lineno);
                goto end;
            }
            if (!cur->anchored || pl->t < cur->t_last) {
                cur->offset = clock - pl->t;
                cur->anchored = true;
            }
            cur->t_last = pl->t;
            if (pl->t + cur->offset > clock) clock = pl->t + cur->offset;
            if (h->speed > 0) {
                if (!sleep_until(h, t0 + clock / h->speed)) goto end;
            } else if (!wait_drained(h)) {
                goto end;
            }
            if (!cur->pad) {
                char where[200];
                snprintf(where, sizeof where, "%s device %u", h->replay, cur->index);
                pad_dev *d = pad_dev_new(h, cur->info, BK_REPLAY, where, where);
                if (!d) {
                    pad_push_msg(h, NULL, PAD_EV_ERROR, "replay of %s: out of memory", h->replay);
                    goto end;
                }
                d->bus = cur->bus;
                d->parser.bluetooth = cur->bus == 5;
                snprintf(d->product, sizeof d->product, "%s", cur->name);
                d->t_open = t0;
                pthread_mutex_lock(&h->mu); /* pad_hub_counts looks */
                cur->pad = d;
                pthread_mutex_unlock(&h->mu);
                pad_parser_start(&d->parser);
                d->parser.out_len = 0; /* nothing to send the power-on to */
                pad_push_msg(h, d, PAD_EV_ADDED, "%s, replay of %s%s", d->info->name, where,
                             cur->bus == 5 ? " (Bluetooth)" : "");
            }
            reports++;
            pad_dev_report(cur->pad, pl->data, pl->len, pad_mono_now(), pl->t);
        }
        if (!h->loop || !reports) break;
        /* a file whose reports all carry one time would loop without a pause */
        if (h->speed > 0 && !sleep_until(h, pad_mono_now() + 0.001)) goto end;
    }
    {
        pad_event ev;
        memset(&ev, 0, sizeof ev);
        ev.kind = PAD_EV_END;
        ev.t_report = pad_mono_now();
        snprintf(ev.msg, sizeof ev.msg, "end of %s", h->replay);
        pad_push(h, NULL, &ev);
    }
end:
    free(line);
    free(pl);
    return NULL;
}
