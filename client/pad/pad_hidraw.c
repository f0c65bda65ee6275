/*
 * pad_hidraw.c — the hidraw backend: PlayStation and Switch pads through
 * hidapi's hidraw flavour (every call through the hub's pad_ops). hidapi
 * has no hotplug, so the hub thread re-enumerates every rescan_ms
 * (pad_hid_scan: a udev scan, about a millisecond) and opens the pads not
 * open yet; each open pad has a reader thread (pad_hid_reader) that blocks
 * in hid_read_timeout for READ_MS at most, so close is prompt, and ends
 * the pad when a read fails (unplugged). Also the hidraw half of `pad list`.
 */
#include "pad_io_internal.h"

#include <string.h>

void pad_hid_init(pad_hub *h)
{
    const pad_ops *ops = h->ops;
    if (ops->hid_init() == 0) {
        h->hid_ok = true;
        return;
    }
    char why[160];
    pad_wcs_ascii(ops->hid_error(NULL), why, sizeof why);
    pad_push_msg(h, NULL, PAD_EV_ERROR, "hidapi would not start (%s): PlayStation and Switch pads are not read",
                 why[0] ? why : "no reason given");
}

void *pad_hid_reader(void *arg)
{
    pad_dev *d = arg;
    const pad_ops *o = d->h->ops;
    /* one more than a line can carry: hidraw cuts a longer report to
       this, and the parser refuses it as too long */
    uint8_t buf[PAD_REPORT_MAX + 1];
    while (!atomic_load(&d->stop)) {
        int n = o->hid_read_timeout(d->hid, buf, sizeof buf, READ_MS);
        if (n > 0) {
            double now = pad_mono_now();
            pad_dev_report(d, buf, (size_t)n, now, now - d->t_open);
        } else if (n < 0) {
            char why[128];
            pad_wcs_ascii(o->hid_error(d->hid), why, sizeof why);
            pad_dev_removed(d, "read failed (unplugged?): %s", why[0] ? why : "no reason given");
            break;
        }
    }
    atomic_store(&d->done, true);
    return NULL;
}

void pad_hid_send(pad_dev *d, size_t n)
{
    pad_hub *h = d->h;
    if (h->ops->hid_write(d->hid, d->parser.out, n) < 0) {
        char why[128];
        pad_wcs_ascii(h->ops->hid_error(d->hid), why, sizeof why);
        pad_push_msg(h, d, PAD_EV_ERROR, "%s: write of %zu bytes failed: %s", d->info->name, n, why);
    }
}

void pad_hid_close(pad_dev *d)
{
    if (d->hid) d->h->ops->hid_close(d->hid);
    d->hid = NULL;
}

static void hid_open_one(pad_hub *h, const struct hid_device_info *i, const pad_device_info *info, pad_seen *s)
{
    const pad_ops *o = h->ops;
    hid_device *dev = o->hid_open_path(i->path);
    if (!dev) {
        char why[160];
        pad_wcs_ascii(o->hid_error(NULL), why, sizeof why);
        pad_open_failed(h, s, info, i->path, why[0] ? why : "hid_open_path failed",
                        strstr(why, "ermission") ? " (no access: a udev rule must give you /dev/hidraw*)" : "");
        return;
    }
    pad_open_worked(s);
    pad_dev *d = pad_dev_new(h, info, BK_HID, i->path, i->path);
    if (!d) {
        o->hid_close(dev);
        pad_open_failed(h, s, info, i->path, "out of memory", "");
        return;
    }
    d->hid = dev;
    d->bus = i->bus_type == HID_API_BUS_BLUETOOTH ? 5 : 3;
    d->parser.bluetooth = d->bus == 5;
    pad_wcs_ascii(i->product_string, d->product, sizeof d->product);
    pad_dev_start(h, d, "hidraw");
}

/* A hidraw node hidapi lists that is a pad read through hidraw. */
static const pad_device_info *hid_pad(const struct hid_device_info *i)
{
    const pad_device_info *info = i->path ? pad_device_lookup(i->vendor_id, i->product_id) : NULL;
    return info && info->path == PAD_PATH_HIDRAW ? info : NULL; /* else not a pad, or one read through libusb */
}

void pad_hid_scan(pad_hub *h)
{
    const pad_ops *o = h->ops;
    struct hid_device_info *list = o->hid_enumerate(0, 0);
    pad_seen_absent(h, BK_HID, NULL);
    double now = pad_mono_now();
    for (struct hid_device_info *i = list; i; i = i->next) {
        const pad_device_info *info = hid_pad(i);
        if (!info) continue;
        pad_seen *s = pad_seen_get(h, BK_HID, i->path);
        if (s) s->present = true;
        /* hidapi 0.13 lists a node once per top-level usage: one open */
        pthread_mutex_lock(&h->mu);
        bool open = pad_by_key(h, BK_HID, i->path) != NULL;
        pthread_mutex_unlock(&h->mu);
        if (open || (s && now < s->retry_at)) continue;
        hid_open_one(h, i, info, s);
    }
    pad_seen_prune(h, BK_HID);
    if (list) o->hid_free_enumeration(list);
}

bool pad_hid_list(const pad_ops *ops, pad_found *out, size_t max, size_t *n, char *why, size_t whylen)
{
    if (ops->hid_init() != 0) {
        pad_wcs_ascii(ops->hid_error(NULL), why, whylen);
        return false;
    }
    struct hid_device_info *list = ops->hid_enumerate(0, 0);
    for (struct hid_device_info *i = list; i; i = i->next) {
        const pad_device_info *info = hid_pad(i);
        if (!info) continue;
        bool dup = false; /* one node, listed once per top-level usage */
        for (struct hid_device_info *j = list; j != i; j = j->next) dup |= j->path && !strcmp(j->path, i->path);
        if (dup) continue;
        if (*n < max) {
            out[*n].info = info;
            snprintf(out[*n].where, sizeof out[*n].where, "%s%s", i->path,
                     i->bus_type == HID_API_BUS_BLUETOOTH ? " (Bluetooth)" : "");
            pad_wcs_ascii(i->product_string, out[*n].product, sizeof out[*n].product);
        }
        (*n)++;
    }
    if (list) ops->hid_free_enumeration(list);
    ops->hid_exit();
    return true;
}
