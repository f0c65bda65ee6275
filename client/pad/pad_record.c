/*
 * pad_record.c — --record: every report of live pads written to a file in
 * hid-recorder's text format (pad_line.c formats the lines), so that
 * pad_replay.c, hid-replay and the tests read it back. Each pad gets a
 * D:/N:/P:/I: header when it is opened (its index, product, where, bus and
 * ids), and a D: line again whenever another pad wrote since; times are
 * seconds since the pad was opened. Lines are flushed one by one: a killed
 * dump keeps everything up to its last report. The first failed write
 * stops the recording and one ERROR event says why; the pads go on.
 *
 * Threads: every reader writes; the file is under the hub's rmu.
 */
#include "pad_io_internal.h"
#include "protocol.h"

#include <errno.h>
#include <string.h>

/* one line of the header, the name cut at anything a line cannot hold */
static void rec_clean(char *s)
{
    for (; *s; s++)
        if (*s == '\n' || *s == '\r') *s = ' ';
}

/* The pad's D:/N:/P:/I: header; under rmu. */
static bool rec_header_locked(pad_hub *h, pad_dev *d)
{
    d->rec_index = h->rec_next++;
    char name[128];
    snprintf(name, sizeof name, "%s", d->product[0] ? d->product : d->info->name);
    rec_clean(name);
    char where[128];
    snprintf(where, sizeof where, "%s", d->where);
    rec_clean(where);
    h->rec_last = d->rec_index;
    return fprintf(h->rec, "D: %d\nN: %s\nP: %s\nI: %x %04x %04x\n", d->rec_index, name, where, d->bus, d->info->vid,
                   d->info->pid) > 0 &&
           fflush(h->rec) == 0;
}

/* The recording stops at its first failed write (e: its errno): said once,
 * outside rmu. */
static void rec_stopped(pad_hub *h, int e)
{
    pad_push_msg(h, NULL, PAD_EV_ERROR, "recording to %s stopped: %s", h->rec_path, strerror(e));
}

int pad_rec_open(pad_hub *h, const char *path, char *err, size_t errlen)
{
    if (!(h->rec_path = strdup(path))) {
        vp_errf(err, errlen, -1, "out of memory");
        return -1;
    }
    if (!(h->rec = fopen(path, "w"))) {
        vp_errf(err, errlen, -1, "%s: %s", path, strerror(errno));
        return -1;
    }
    fprintf(h->rec, "# vantage pad dump --record: hid-recorder's format, times in seconds since each pad "
                    "was opened\n");
    fflush(h->rec);
    return 0;
}

void pad_rec_pad(pad_hub *h, pad_dev *d)
{
    if (!h->rec) return;
    int e = 0;
    pthread_mutex_lock(&h->rmu);
    errno = 0;
    if (!h->rec_failed && !rec_header_locked(h, d)) {
        e = errno ? errno : EIO;
        h->rec_failed = true;
    }
    pthread_mutex_unlock(&h->rmu);
    if (e) rec_stopped(h, e);
}

void pad_rec_report(pad_hub *h, pad_dev *d, const uint8_t *buf, size_t len, double t)
{
    if (!h->rec || len > PAD_REPORT_MAX) return; /* a line could not hold it: the parser refuses it anyway */
    char line[16 + 3 * PAD_REPORT_MAX + 32];
    int n = pad_line_format_event(t, buf, len, line, sizeof line);
    if (n <= 0 || (size_t)n >= sizeof line) return;
    int e = 0;
    pthread_mutex_lock(&h->rmu);
    if (!h->rec_failed) {
        bool ok = true;
        if (d->rec_index < 0) ok = rec_header_locked(h, d);
        else if (h->rec_last != d->rec_index) {
            ok = fprintf(h->rec, "D: %d\n", d->rec_index) > 0;
            h->rec_last = d->rec_index;
        }
        /* flushed per line: a killed dump keeps everything up to its last report */
        errno = 0;
        if (!ok || fwrite(line, 1, (size_t)n, h->rec) != (size_t)n || fflush(h->rec)) e = errno ? errno : EIO;
        if (e) h->rec_failed = true;
    }
    pthread_mutex_unlock(&h->rmu);
    if (e) rec_stopped(h, e);
}
