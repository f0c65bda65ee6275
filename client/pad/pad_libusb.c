/*
 * pad_libusb.c — the libusb backend: the Xbox 360 (XInput) and Xbox One /
 * Series (GIP) pads, whose vendor-class interfaces no HID driver exposes
 * (every call through the hub's pad_ops). Devices are found by libusb's
 * hotplug callbacks (queued as notes, handled in the hub thread) and by a
 * rescan every rescan_ms (the retry path for a device that would not open,
 * and the only path where libusb has no hotplug). Opening claims the
 * interface with the kernel's xpad auto-detached (attached again on
 * release); each open pad has a reader thread (pad_usb_reader): one
 * interrupt transfer of one packet at a time, READ_MS at most, the pad
 * ended on LIBUSB_ERROR_NO_DEVICE, on hotplug's DEVICE_LEFT, or after
 * USB_ERR_MAX failed reads in a row. Also the USB half of `pad list`.
 */
#include "pad_io_internal.h"
#include "vp_grow.h"

#include <stdlib.h>
#include <string.h>

static void usb_where(const pad_ops *o, libusb_device *dev, char *key, size_t keylen, char *where, size_t wlen)
{
    uint8_t ports[8];
    int n = o->libusb_get_port_numbers(dev, ports, (int)sizeof ports);
    unsigned bus = o->libusb_get_bus_number(dev), addr = o->libusb_get_device_address(dev);
    char path[40] = "";
    size_t k = 0;
    for (int i = 0; i < n && k + 5 < sizeof path; i++)
        k += (size_t)snprintf(path + k, sizeof path - k, "%s%u", i ? "." : "", ports[i]);
    if (n <= 0) snprintf(path, sizeof path, "a%u", addr); /* no port path (a root hub): the address */
    snprintf(key, keylen, "usb:%u-%s", bus, path);
    snprintf(where, wlen, "usb %u-%s (bus %u, address %u)", bus, path, bus, addr);
}

/* The pad a USB device is, when it is one read through libusb. */
static const pad_device_info *usb_pad(const pad_ops *o, libusb_device *dev)
{
    struct libusb_device_descriptor dd;
    if (o->libusb_get_device_descriptor(dev, &dd) < 0) return NULL;
    const pad_device_info *info = pad_device_lookup(dd.idVendor, dd.idProduct);
    return info && info->path == PAD_PATH_LIBUSB ? info : NULL;
}

/* The XInput / GIP interface and its interrupt endpoints. */
static bool usb_find_iface(const struct libusb_config_descriptor *cfg, pad_proto proto, int *iface, uint8_t *ep_in,
                           uint8_t *ep_out, int *in_size)
{
    uint8_t sub = proto == PAD_PROTO_XBOXONE ? 0x47 : 0x5D, pro = proto == PAD_PROTO_XBOXONE ? 0xD0 : 0x01;
    for (int i = 0; cfg && i < cfg->bNumInterfaces; i++) {
        const struct libusb_interface *it = &cfg->interface[i];
        if (it->num_altsetting < 1 || !it->altsetting) continue;
        const struct libusb_interface_descriptor *a = &it->altsetting[0];
        if (a->bInterfaceClass != 0xFF || a->bInterfaceSubClass != sub || a->bInterfaceProtocol != pro) continue;
        *ep_in = *ep_out = 0;
        for (int e = 0; e < a->bNumEndpoints && a->endpoint; e++) {
            const struct libusb_endpoint_descriptor *ep = &a->endpoint[e];
            if ((ep->bmAttributes & LIBUSB_TRANSFER_TYPE_MASK) != LIBUSB_TRANSFER_TYPE_INTERRUPT) continue;
            if ((ep->bEndpointAddress & LIBUSB_ENDPOINT_DIR_MASK) == LIBUSB_ENDPOINT_IN) {
                if (!*ep_in) {
                    *ep_in = ep->bEndpointAddress;
                    *in_size = ep->wMaxPacketSize & 0x7FF;
                }
            } else if (!*ep_out) {
                *ep_out = ep->bEndpointAddress;
            }
        }
        if (!*ep_in) continue;
        /* exactly one packet a transfer: a longer buffer would wait for a
           second packet after a full-size one */
        if (*in_size < 8) *in_size = 64;
        if (*in_size > PAD_REPORT_MAX) *in_size = PAD_REPORT_MAX;
        *iface = a->bInterfaceNumber;
        return true;
    }
    return false;
}

static pad_dev *pad_by_udev(pad_hub *h, libusb_device *dev)
{
    for (pad_dev *d = h->pads; d; d = d->next)
        if (d->bk == BK_USB && d->udev == dev) return d;
    return NULL;
}

void *pad_usb_reader(void *arg)
{
    pad_dev *d = arg;
    const pad_ops *o = d->h->ops;
    uint8_t buf[PAD_REPORT_MAX];
    while (!atomic_load(&d->stop)) {
        if (atomic_load(&d->gone)) {
            pad_dev_removed(d, "unplugged (USB hotplug)");
            break;
        }
        int got = 0;
        int rc = o->libusb_interrupt_transfer(d->uh, d->ep_in, buf, d->in_size, &got, READ_MS);
        if (rc == 0 || (rc == LIBUSB_ERROR_TIMEOUT && got > 0)) {
            d->usb_errs = 0;
            double now = pad_mono_now();
            if (got > 0) pad_dev_report(d, buf, (size_t)got, now, now - d->t_open);
        } else if (rc == LIBUSB_ERROR_TIMEOUT || rc == LIBUSB_ERROR_INTERRUPTED) {
            continue;
        } else if (rc == LIBUSB_ERROR_NO_DEVICE) {
            pad_dev_removed(d, "unplugged (%s)", o->libusb_strerror(rc));
            break;
        } else if (++d->usb_errs >= USB_ERR_MAX) {
            pad_dev_removed(d, "%d reads in a row failed: %s", d->usb_errs, o->libusb_strerror(rc));
            break;
        } else {
            atomic_fetch_add_explicit(&d->c_errors, 1, memory_order_relaxed);
            char more[48];
            if (pad_dev_err_allowed(d, pad_mono_now(), more, sizeof more))
                pad_push_msg(d->h, d, PAD_EV_ERROR, "%s: read failed: %s%s", d->info->name, o->libusb_strerror(rc),
                             more);
            struct timespec ts = {0, 20 * 1000000L}; /* a stalled endpoint must not spin */
            nanosleep(&ts, NULL);
        }
    }
    atomic_store(&d->done, true);
    return NULL;
}

void pad_usb_send(pad_dev *d, size_t n)
{
    pad_hub *h = d->h;
    int sent = 0;
    int rc = d->ep_out ? h->ops->libusb_interrupt_transfer(d->uh, d->ep_out, d->parser.out, (int)n, &sent, 250)
                       : LIBUSB_ERROR_NOT_SUPPORTED;
    if (rc < 0)
        pad_push_msg(h, d, PAD_EV_ERROR, "%s: write of %zu bytes failed: %s", d->info->name, n,
                     h->ops->libusb_strerror(rc));
}

void pad_usb_close(pad_dev *d)
{
    const pad_ops *o = d->h->ops;
    if (d->uh) {
        o->libusb_release_interface(d->uh, d->iface); /* the kernel's driver comes back (auto-detach) */
        o->libusb_close(d->uh);
    }
    d->uh = NULL;
}

static void usb_open_one(pad_hub *h, libusb_device *dev, const pad_device_info *info, const char *key,
                         const char *where, pad_seen *s)
{
    const pad_ops *o = h->ops;
    struct libusb_config_descriptor *cfg = NULL;
    int iface = 0, in_size = 64;
    uint8_t ep_in = 0, ep_out = 0;
    int rc = o->libusb_get_active_config_descriptor(dev, &cfg);
    if (rc < 0) {
        pad_open_failed(h, s, info, where, o->libusb_strerror(rc), " (reading its configuration)");
        return;
    }
    bool found = usb_find_iface(cfg, info->proto, &iface, &ep_in, &ep_out, &in_size);
    o->libusb_free_config_descriptor(cfg);
    if (!found) {
        pad_open_failed(h, s, info, where, "it has no XInput / GIP interface with an interrupt IN endpoint", "");
        return;
    }
    if (info->proto == PAD_PROTO_XBOXONE && !ep_out) {
        pad_open_failed(h, s, info, where, "its GIP interface has no OUT endpoint for the power-on", "");
        return;
    }
    libusb_device_handle *uh = NULL;
    if ((rc = o->libusb_open(dev, &uh)) < 0) {
        pad_open_failed(h, s, info, where, o->libusb_strerror(rc),
                        rc == LIBUSB_ERROR_ACCESS ? " (no access: a udev rule must give you /dev/bus/usb/...)" : "");
        return;
    }
    /* the kernel's xpad holds the interface: detached while we claim it,
       attached again on release */
    rc = o->libusb_set_auto_detach_kernel_driver(uh, 1);
    if (rc < 0 && rc != LIBUSB_ERROR_NOT_SUPPORTED) {
        o->libusb_close(uh);
        pad_open_failed(h, s, info, where, o->libusb_strerror(rc), " (detaching the kernel's driver)");
        return;
    }
    if ((rc = o->libusb_claim_interface(uh, iface)) < 0) {
        o->libusb_close(uh);
        pad_open_failed(h, s, info, where, o->libusb_strerror(rc),
                        rc == LIBUSB_ERROR_BUSY ? " (another program has claimed it)" : " (claiming its interface)");
        return;
    }
    pad_dev *d = pad_dev_new(h, info, BK_USB, key, where);
    if (!d) {
        o->libusb_release_interface(uh, iface);
        o->libusb_close(uh);
        pad_open_failed(h, s, info, where, "out of memory", "");
        return;
    }
    pad_open_worked(s);
    d->udev = o->libusb_ref_device(dev);
    d->uh = uh;
    d->iface = iface;
    d->ep_in = ep_in;
    d->ep_out = ep_out;
    d->in_size = in_size;
    pad_dev_start(h, d, "libusb");
}

/* A USB device seen by a scan or the hotplug callback: opened if it is a
 * pad not open yet and not waiting for a retry. */
static void usb_consider(pad_hub *h, libusb_device *dev)
{
    const pad_ops *o = h->ops;
    const pad_device_info *info = usb_pad(o, dev);
    if (!info) return;
    char key[64], where[128];
    usb_where(o, dev, key, sizeof key, where, sizeof where);
    pthread_mutex_lock(&h->mu);
    bool open = pad_by_udev(h, dev) != NULL;
    pthread_mutex_unlock(&h->mu);
    pad_seen *s = pad_seen_get(h, BK_USB, key);
    if (s) s->present = true;
    if (open || (s && pad_mono_now() < s->retry_at)) return;
    usb_open_one(h, dev, info, key, where, s);
}

void pad_usb_scan(pad_hub *h)
{
    const pad_ops *o = h->ops;
    libusb_device **list = NULL;
    ssize_t n = o->libusb_get_device_list(h->usb, &list);
    if (n < 0) {
        if (!h->usb_list_failed)
            pad_push_msg(h, NULL, PAD_EV_ERROR, "listing USB devices failed: %s", o->libusb_strerror((int)n));
        h->usb_list_failed = true;
        return;
    }
    h->usb_list_failed = false;
    pad_seen_absent(h, BK_USB, NULL);
    for (ssize_t i = 0; i < n; i++) usb_consider(h, list[i]);
    pad_seen_prune(h, BK_USB);
    o->libusb_free_device_list(list, 1);
}

/* libusb's hotplug callback: runs in whichever thread handles libusb's
 * events (the hub's, or a reader inside a transfer), so it only queues. */
static int hotplug_cb(libusb_context *ctx, libusb_device *dev, libusb_hotplug_event event, void *user)
{
    (void)ctx;
    pad_hub *h = user;
    pthread_mutex_lock(&h->pmu);
    if (!vp_grow((void **)&h->notes, &h->capnotes, h->nnotes + 1, sizeof *h->notes)) {
        /* out of memory: the news is lost, the periodic rescan still finds the device */
        pthread_mutex_unlock(&h->pmu);
        return 0;
    }
    h->notes[h->nnotes].dev = h->ops->libusb_ref_device(dev);
    h->notes[h->nnotes].arrived = event == LIBUSB_HOTPLUG_EVENT_DEVICE_ARRIVED;
    h->nnotes++;
    pthread_mutex_unlock(&h->pmu);
    return 0; /* stay registered */
}

void pad_usb_notes(pad_hub *h)
{
    pthread_mutex_lock(&h->pmu);
    pad_usb_note *notes = h->notes;
    size_t n = h->nnotes;
    h->notes = NULL;
    h->nnotes = h->capnotes = 0;
    pthread_mutex_unlock(&h->pmu);
    for (size_t i = 0; i < n; i++) {
        libusb_device *dev = notes[i].dev;
        if (notes[i].arrived) {
            usb_consider(h, dev);
        } else {
            pthread_mutex_lock(&h->mu);
            pad_dev *d = pad_by_udev(h, dev);
            if (d) atomic_store(&d->gone, true); /* its reader says REMOVED at its next timeout */
            pthread_mutex_unlock(&h->mu);
            char key[64], where[128];
            usb_where(h->ops, dev, key, sizeof key, where, sizeof where);
            pad_seen_absent(h, BK_USB, key);
            pad_seen_prune(h, BK_USB);
        }
        h->ops->libusb_unref_device(dev);
    }
    free(notes);
}

void pad_usb_init(pad_hub *h)
{
    const pad_ops *ops = h->ops;
    int rc = ops->libusb_init(&h->usb);
    if (rc < 0) {
        h->usb = NULL;
        pad_push_msg(h, NULL, PAD_EV_ERROR, "libusb would not start (%s): Xbox pads are not read",
                     ops->libusb_strerror(rc));
        return;
    }
    if (!ops->libusb_has_capability(LIBUSB_CAP_HAS_HOTPLUG)) return; /* the periodic rescan is the only path */
    /* ENUMERATE: the devices present now come through the callback too
       (queued; the hub thread's first scan finds them anyway) */
    int events = LIBUSB_HOTPLUG_EVENT_DEVICE_ARRIVED | LIBUSB_HOTPLUG_EVENT_DEVICE_LEFT;
    rc = ops->libusb_hotplug_register_callback(h->usb, events, LIBUSB_HOTPLUG_ENUMERATE, LIBUSB_HOTPLUG_MATCH_ANY,
                                               LIBUSB_HOTPLUG_MATCH_ANY, LIBUSB_HOTPLUG_MATCH_ANY, hotplug_cb, h,
                                               &h->hp);
    h->hotplug = rc == LIBUSB_SUCCESS; /* else the periodic rescan is the only path */
}

void pad_usb_exit(pad_hub *h)
{
    if (!h->usb) return;
    if (h->hotplug) h->ops->libusb_hotplug_deregister_callback(h->usb, h->hp);
    for (size_t i = 0; i < h->nnotes; i++) h->ops->libusb_unref_device(h->notes[i].dev);
    h->ops->libusb_exit(h->usb);
}

bool pad_usb_list(const pad_ops *ops, pad_found *out, size_t max, size_t *n, char *why, size_t whylen)
{
    libusb_context *ctx = NULL;
    int rc = ops->libusb_init(&ctx);
    if (rc != 0) {
        snprintf(why, whylen, "%s", ops->libusb_strerror(rc));
        return false;
    }
    libusb_device **list = NULL;
    ssize_t k = ops->libusb_get_device_list(ctx, &list);
    if (k < 0) {
        snprintf(why, whylen, "%s", ops->libusb_strerror((int)k));
        ops->libusb_exit(ctx);
        return false;
    }
    for (ssize_t i = 0; i < k; i++) {
        const pad_device_info *info = usb_pad(ops, list[i]);
        if (!info) continue;
        if (*n < max) {
            char key[64];
            out[*n].info = info;
            usb_where(ops, list[i], key, sizeof key, out[*n].where, sizeof out[*n].where);
            out[*n].product[0] = 0; /* its string needs the device opened */
        }
        (*n)++;
    }
    ops->libusb_free_device_list(list, 1);
    ops->libusb_exit(ctx);
    return true;
}
