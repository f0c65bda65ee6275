/*
 * pad_fake.c — the fake hidapi and libusb of pad_fake.h: every pad_ops
 * entry over an array of fake devices under one mutex.
 */
#include "test_util.h"

#include "pad_fake.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

struct fake fake = {.mu = PTHREAD_MUTEX_INITIALIZER, .cv = PTHREAD_COND_INITIALIZER};

void fake_reset(bool hotplug)
{
    pthread_mutex_lock(&fake.mu);
    memset(fake.dev, 0, sizeof fake.dev);
    fake.hotplug = hotplug;
    fake.cb = NULL;
    fake.registered = false;
    fake.nnotes = 0;
    fake.usb_init_fails = false;
    fake.hid_inits = fake.usb_inits = fake.handles = fake.lists = fake.cfgs = 0;
    pthread_mutex_unlock(&fake.mu);
}

static fake_dev *fake_new(bool usb, uint16_t vid, uint16_t pid)
{
    pthread_mutex_lock(&fake.mu);
    fake_dev *d = NULL;
    for (int i = 0; i < FAKE_DEVS && !d; i++)
        if (!fake.dev[i].used) d = &fake.dev[i];
    assert_non_null(d);
    memset(d, 0, sizeof *d);
    d->used = true;
    d->usb = usb;
    d->vid = vid;
    d->pid = pid;
    d->ud.d = d;
    int idx = (int)(d - fake.dev);
    snprintf(d->path, sizeof d->path, "/dev/hidraw%d", idx);
    d->addr = (uint8_t)(10 + idx);
    d->port = (uint8_t)(1 + idx);
    pthread_mutex_unlock(&fake.mu);
    return d;
}

fake_dev *fake_hid(uint16_t vid, uint16_t pid)
{
    fake_dev *d = fake_new(false, vid, pid);
    d->present = true;
    return d;
}

fake_dev *fake_usb(uint16_t vid, uint16_t pid, bool gip)
{
    fake_dev *d = fake_new(true, vid, pid);
    d->cls[0] = 0xFF;
    d->cls[1] = gip ? 0x47 : 0x5D;
    d->cls[2] = gip ? 0xD0 : 0x01;
    d->needs_poweron = gip;
    d->present = true;
    return d;
}

void fake_push(fake_dev *d, const uint8_t *b, int n)
{
    pthread_mutex_lock(&fake.mu);
    assert_true(d->qt - d->qh < FAKE_QUEUE);
    fake_pkt *p = &d->q[d->qt++ % FAKE_QUEUE];
    memcpy(p->b, b, (size_t)n);
    p->n = n;
    pthread_cond_broadcast(&fake.cv);
    pthread_mutex_unlock(&fake.mu);
}

static void fake_note_add(fake_dev *d, bool arrived)
{
    if (!d->usb || !fake.hotplug || !fake.registered) return;
    assert_true(fake.nnotes < 32);
    fake.notes[fake.nnotes].d = d;
    fake.notes[fake.nnotes].arrived = arrived;
    fake.nnotes++;
}

void fake_unplug(fake_dev *d)
{
    pthread_mutex_lock(&fake.mu);
    d->present = false;
    d->qh = d->qt;
    fake_note_add(d, false);
    pthread_cond_broadcast(&fake.cv);
    pthread_mutex_unlock(&fake.mu);
}

void fake_plug(fake_dev *d)
{
    pthread_mutex_lock(&fake.mu);
    d->present = true;
    d->powered = false;
    d->nout = 0;
    d->reads = d->reads_before_write = d->consumed = 0;
    fake_note_add(d, true);
    pthread_cond_broadcast(&fake.cv);
    pthread_mutex_unlock(&fake.mu);
}

long fake_consumed(fake_dev *d)
{
    pthread_mutex_lock(&fake.mu);
    long n = d->consumed;
    pthread_mutex_unlock(&fake.mu);
    return n;
}

static struct timespec abs_in(int ms)
{
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    ts.tv_sec += ms / 1000;
    ts.tv_nsec += (long)(ms % 1000) * 1000000L;
    if (ts.tv_nsec >= 1000000000L) {
        ts.tv_sec++;
        ts.tv_nsec -= 1000000000L;
    }
    return ts;
}

/* A blocking read as the libraries do it: a report, or 0 after ms, or
 * gone. Under fake.mu. */
static int fake_read_locked(fake_dev *d, unsigned char *data, size_t length, int ms, bool *gone)
{
    struct timespec until = abs_in(ms);
    d->reads++;
    if (!d->nout) d->reads_before_write++;
    for (;;) {
        *gone = !d->present;
        if (*gone) return -1;
        if (d->qh < d->qt && (!d->needs_poweron || d->powered)) {
            fake_pkt *p = &d->q[d->qh++ % FAKE_QUEUE];
            int n = p->n < (int)length ? p->n : (int)length;
            memcpy(data, p->b, (size_t)n);
            d->consumed++;
            pthread_cond_broadcast(&fake.cv);
            return n;
        }
        if (pthread_cond_timedwait(&fake.cv, &fake.mu, &until) == ETIMEDOUT) return 0;
    }
}

static void fake_log_out(fake_dev *d, const unsigned char *data, size_t n)
{
    assert_true(d->nout < FAKE_OUTS && n <= 64);
    memcpy(d->out[d->nout].b, data, n);
    d->out[d->nout].n = (int)n;
    d->nout++;
    if (n >= 2 && data[0] == 0x05 && data[1] == 0x20) d->powered = true;
}

/* hidapi */
static wchar_t fake_hid_err[64] = L"";

static int f_hid_init(void)
{
    pthread_mutex_lock(&fake.mu);
    fake.hid_inits++;
    pthread_mutex_unlock(&fake.mu);
    return 0;
}

static int f_hid_exit(void)
{
    pthread_mutex_lock(&fake.mu);
    fake.hid_inits--;
    pthread_mutex_unlock(&fake.mu);
    return 0;
}

static struct hid_device_info *f_hid_enumerate(unsigned short vid, unsigned short pid)
{
    (void)vid;
    (void)pid;
    struct hid_device_info *head = NULL;
    pthread_mutex_lock(&fake.mu);
    for (int i = FAKE_DEVS - 1; i >= 0; i--) {
        fake_dev *d = &fake.dev[i];
        if (!d->used || d->usb || !d->present) continue;
        /* hidapi 0.13 lists a node once per top-level usage: twice here */
        for (int k = 0; k < 2; k++) {
            struct hid_device_info *e = calloc(1, sizeof *e);
            assert_non_null(e);
            e->path = strdup(d->path);
            e->vendor_id = d->vid;
            e->product_id = d->pid;
            e->product_string = wcsdup(L"Wireless Controller");
            e->bus_type = d->bluetooth ? HID_API_BUS_BLUETOOTH : HID_API_BUS_USB;
            e->next = head;
            head = e;
        }
    }
    if (head) fake.lists++;
    pthread_mutex_unlock(&fake.mu);
    return head;
}

static void f_hid_free_enumeration(struct hid_device_info *e)
{
    if (e) {
        pthread_mutex_lock(&fake.mu);
        fake.lists--;
        pthread_mutex_unlock(&fake.mu);
    }
    while (e) {
        struct hid_device_info *n = e->next;
        free(e->path);
        free(e->product_string);
        free(e);
        e = n;
    }
}

static hid_device *f_hid_open_path(const char *path)
{
    pthread_mutex_lock(&fake.mu);
    fake_dev *d = NULL;
    for (int i = 0; i < FAKE_DEVS && !d; i++) {
        fake_dev *c = &fake.dev[i];
        if (c->used && !c->usb && c->present && !strcmp(c->path, path)) d = c;
    }
    hid_device *h = NULL;
    if (!d) {
        swprintf(fake_hid_err, 64, L"No such device");
    } else if (d->fail_open) {
        d->opens++;
        swprintf(fake_hid_err, 64, L"Failed to open a device: Permission denied");
    } else {
        h = malloc(sizeof *h);
        assert_non_null(h);
        h->d = d;
        d->opens++;
        d->is_open++;
        fake.handles++;
    }
    pthread_mutex_unlock(&fake.mu);
    return h;
}

static int f_hid_read_timeout(hid_device *h, unsigned char *data, size_t length, int ms)
{
    bool gone;
    pthread_mutex_lock(&fake.mu);
    int n = fake_read_locked(h->d, data, length, ms, &gone);
    pthread_mutex_unlock(&fake.mu);
    return n;
}

static int f_hid_write(hid_device *h, const unsigned char *data, size_t length)
{
    pthread_mutex_lock(&fake.mu);
    int rc = h->d->present ? (fake_log_out(h->d, data, length), (int)length) : -1;
    pthread_mutex_unlock(&fake.mu);
    return rc;
}

/* a hid_device or libusb_device_handle of d given back */
static void fake_handle_free(fake_dev *d, void *handle)
{
    pthread_mutex_lock(&fake.mu);
    d->is_open--;
    fake.handles--;
    pthread_mutex_unlock(&fake.mu);
    free(handle);
}

static void f_hid_close(hid_device *h)
{
    fake_handle_free(h->d, h);
}

static const wchar_t *f_hid_error(hid_device *h)
{
    return h ? L"Device disconnected" : fake_hid_err;
}

/* libusb */
static int f_usb_init(libusb_context **ctx)
{
    if (fake.usb_init_fails) return LIBUSB_ERROR_OTHER;
    pthread_mutex_lock(&fake.mu);
    fake.usb_inits++;
    pthread_mutex_unlock(&fake.mu);
    *ctx = &fake.ctx;
    return 0;
}

static void f_usb_exit(libusb_context *ctx)
{
    assert_ptr_equal(ctx, &fake.ctx);
    pthread_mutex_lock(&fake.mu);
    fake.usb_inits--;
    pthread_mutex_unlock(&fake.mu);
}

static int f_has_capability(uint32_t cap)
{
    return cap == LIBUSB_CAP_HAS_HOTPLUG && fake.hotplug;
}

static ssize_t f_get_device_list(libusb_context *ctx, libusb_device ***list)
{
    (void)ctx;
    pthread_mutex_lock(&fake.mu);
    libusb_device **l = calloc(FAKE_DEVS + 1, sizeof *l);
    assert_non_null(l);
    ssize_t n = 0;
    for (int i = 0; i < FAKE_DEVS; i++) {
        fake_dev *d = &fake.dev[i];
        if (!d->used || !d->usb || !d->present) continue;
        d->refs++;
        l[n++] = &d->ud;
    }
    fake.lists++;
    pthread_mutex_unlock(&fake.mu);
    *list = l;
    return n;
}

static void f_free_device_list(libusb_device **list, int unref)
{
    pthread_mutex_lock(&fake.mu);
    for (libusb_device **p = list; unref && *p; p++) (*p)->d->refs--;
    fake.lists--;
    pthread_mutex_unlock(&fake.mu);
    free(list);
}

static libusb_device *f_ref_device(libusb_device *dev)
{
    pthread_mutex_lock(&fake.mu);
    dev->d->refs++;
    pthread_mutex_unlock(&fake.mu);
    return dev;
}

static void f_unref_device(libusb_device *dev)
{
    pthread_mutex_lock(&fake.mu);
    dev->d->refs--;
    assert_true(dev->d->refs >= 0);
    pthread_mutex_unlock(&fake.mu);
}

static int f_get_device_descriptor(libusb_device *dev, struct libusb_device_descriptor *dd)
{
    memset(dd, 0, sizeof *dd);
    dd->bLength = sizeof *dd;
    dd->bDeviceClass = 0xFF;
    dd->idVendor = dev->d->vid;
    dd->idProduct = dev->d->pid;
    dd->bNumConfigurations = 1;
    return 0;
}

typedef struct fake_cfg {
    struct libusb_config_descriptor c; /* first: the pointer freed is this */
    struct libusb_interface i;
    struct libusb_interface_descriptor a;
    struct libusb_endpoint_descriptor e[2];
} fake_cfg;

static int f_get_active_config_descriptor(libusb_device *dev, struct libusb_config_descriptor **out)
{
    fake_cfg *f = calloc(1, sizeof *f);
    assert_non_null(f);
    f->c.bNumInterfaces = 1;
    f->c.interface = &f->i;
    f->i.num_altsetting = 1;
    f->i.altsetting = &f->a;
    f->a.bInterfaceNumber = 0;
    f->a.bInterfaceClass = dev->d->cls[0];
    f->a.bInterfaceSubClass = dev->d->cls[1];
    f->a.bInterfaceProtocol = dev->d->cls[2];
    f->a.bNumEndpoints = 2;
    f->a.endpoint = f->e;
    f->e[0].bEndpointAddress = 0x81;
    f->e[0].bmAttributes = LIBUSB_TRANSFER_TYPE_INTERRUPT;
    f->e[0].wMaxPacketSize = dev->d->needs_poweron ? 64 : 32;
    f->e[1].bEndpointAddress = 0x02;
    f->e[1].bmAttributes = LIBUSB_TRANSFER_TYPE_INTERRUPT;
    f->e[1].wMaxPacketSize = 64;
    pthread_mutex_lock(&fake.mu);
    fake.cfgs++;
    pthread_mutex_unlock(&fake.mu);
    *out = &f->c;
    return 0;
}

static void f_free_config_descriptor(struct libusb_config_descriptor *c)
{
    pthread_mutex_lock(&fake.mu);
    fake.cfgs--;
    pthread_mutex_unlock(&fake.mu);
    free(c);
}

static uint8_t f_get_bus_number(libusb_device *dev)
{
    (void)dev;
    return 1;
}

static uint8_t f_get_device_address(libusb_device *dev)
{
    return dev->d->addr;
}

static int f_get_port_numbers(libusb_device *dev, uint8_t *ports, int len)
{
    if (len < 1) return LIBUSB_ERROR_OVERFLOW;
    ports[0] = dev->d->port;
    return 1;
}

static int f_usb_open(libusb_device *dev, libusb_device_handle **out)
{
    pthread_mutex_lock(&fake.mu);
    fake_dev *d = dev->d;
    int rc = 0;
    d->opens++;
    if (!d->present) rc = LIBUSB_ERROR_NO_DEVICE;
    else if (d->fail_open) rc = LIBUSB_ERROR_ACCESS;
    else {
        libusb_device_handle *h = malloc(sizeof *h);
        assert_non_null(h);
        h->d = d;
        d->is_open++;
        d->detach = d->claimed = false;
        fake.handles++;
        *out = h;
    }
    pthread_mutex_unlock(&fake.mu);
    return rc;
}

static void f_usb_close(libusb_device_handle *h)
{
    fake_handle_free(h->d, h);
}

static int f_set_auto_detach(libusb_device_handle *h, int enable)
{
    h->d->detach = enable != 0;
    return 0;
}

static int f_claim(libusb_device_handle *h, int iface)
{
    assert_int_equal(iface, 0);
    if (!h->d->detach) h->d->claim_before_detach = true;
    h->d->claimed = true;
    return 0;
}

static int f_release(libusb_device_handle *h, int iface)
{
    assert_int_equal(iface, 0);
    h->d->claimed = false;
    return 0;
}

static int f_interrupt_transfer(libusb_device_handle *h, unsigned char ep, unsigned char *data, int length,
                                int *actual, unsigned int timeout)
{
    fake_dev *d = h->d;
    int rc;
    *actual = 0;
    pthread_mutex_lock(&fake.mu);
    if (ep & 0x80) {
        bool gone;
        int n = fake_read_locked(d, data, (size_t)length, (int)timeout, &gone);
        if (gone && d->silent_leave) {
            pthread_mutex_unlock(&fake.mu);
            struct timespec ts = {(time_t)(timeout / 1000), (long)(timeout % 1000) * 1000000L};
            nanosleep(&ts, NULL); /* the whole timeout, as a read that never completes */
            return LIBUSB_ERROR_TIMEOUT;
        }
        rc = gone ? LIBUSB_ERROR_NO_DEVICE : n == 0 ? LIBUSB_ERROR_TIMEOUT : 0;
        if (n > 0) *actual = n;
    } else if (!d->present) {
        rc = LIBUSB_ERROR_NO_DEVICE;
    } else {
        fake_log_out(d, data, (size_t)length);
        *actual = length;
        rc = 0;
    }
    pthread_mutex_unlock(&fake.mu);
    return rc;
}

static int f_hotplug_register(libusb_context *ctx, int events, int flags, int vid, int pid, int cls,
                              libusb_hotplug_callback_fn cb, void *user, libusb_hotplug_callback_handle *hp)
{
    (void)events;
    (void)vid;
    (void)pid;
    (void)cls;
    pthread_mutex_lock(&fake.mu);
    fake.cb = cb;
    fake.cb_user = user;
    fake.registered = true;
    *hp = 7;
    libusb_device *now[FAKE_DEVS];
    int n = 0;
    for (int i = 0; i < FAKE_DEVS; i++)
        if (fake.dev[i].used && fake.dev[i].usb && fake.dev[i].present) now[n++] = &fake.dev[i].ud;
    pthread_mutex_unlock(&fake.mu);
    /* as libusb: ENUMERATE calls back for the devices present, before returning */
    for (int i = 0; (flags & LIBUSB_HOTPLUG_ENUMERATE) && i < n; i++)
        cb(ctx, now[i], LIBUSB_HOTPLUG_EVENT_DEVICE_ARRIVED, user);
    return 0;
}

static void f_hotplug_deregister(libusb_context *ctx, libusb_hotplug_callback_handle hp)
{
    (void)ctx;
    assert_int_equal(hp, 7);
    pthread_mutex_lock(&fake.mu);
    fake.registered = false;
    pthread_mutex_unlock(&fake.mu);
}

static int f_handle_events(libusb_context *ctx, struct timeval *tv, int *completed)
{
    (void)completed;
    pthread_mutex_lock(&fake.mu);
    if (!fake.nnotes) {
        struct timespec until = abs_in((int)(tv->tv_sec * 1000 + tv->tv_usec / 1000));
        pthread_cond_timedwait(&fake.cv, &fake.mu, &until);
    }
    fake_note notes[32];
    int n = fake.nnotes;
    memcpy(notes, fake.notes, sizeof notes);
    fake.nnotes = 0;
    libusb_hotplug_callback_fn cb = fake.cb;
    void *user = fake.cb_user;
    pthread_mutex_unlock(&fake.mu);
    /* the callback runs without the fake's lock: it calls libusb_ref_device */
    for (int i = 0; i < n; i++)
        cb(ctx, &notes[i].d->ud,
           notes[i].arrived ? LIBUSB_HOTPLUG_EVENT_DEVICE_ARRIVED : LIBUSB_HOTPLUG_EVENT_DEVICE_LEFT, user);
    return 0;
}

const pad_ops fake_ops = {
    .ctx = &fake,
    .hid_init = f_hid_init,
    .hid_exit = f_hid_exit,
    .hid_enumerate = f_hid_enumerate,
    .hid_free_enumeration = f_hid_free_enumeration,
    .hid_open_path = f_hid_open_path,
    .hid_read_timeout = f_hid_read_timeout,
    .hid_write = f_hid_write,
    .hid_close = f_hid_close,
    .hid_error = f_hid_error,
    .libusb_init = f_usb_init,
    .libusb_exit = f_usb_exit,
    .libusb_has_capability = f_has_capability,
    .libusb_strerror = libusb_strerror, /* pure: the real one */
    .libusb_get_device_list = f_get_device_list,
    .libusb_free_device_list = f_free_device_list,
    .libusb_ref_device = f_ref_device,
    .libusb_unref_device = f_unref_device,
    .libusb_get_device_descriptor = f_get_device_descriptor,
    .libusb_get_active_config_descriptor = f_get_active_config_descriptor,
    .libusb_free_config_descriptor = f_free_config_descriptor,
    .libusb_get_bus_number = f_get_bus_number,
    .libusb_get_device_address = f_get_device_address,
    .libusb_get_port_numbers = f_get_port_numbers,
    .libusb_open = f_usb_open,
    .libusb_close = f_usb_close,
    .libusb_set_auto_detach_kernel_driver = f_set_auto_detach,
    .libusb_claim_interface = f_claim,
    .libusb_release_interface = f_release,
    .libusb_interrupt_transfer = f_interrupt_transfer,
    .libusb_hotplug_register_callback = f_hotplug_register,
    .libusb_hotplug_deregister_callback = f_hotplug_deregister,
    .libusb_handle_events_timeout_completed = f_handle_events,
};

void fake_assert_clean(void)
{
    pthread_mutex_lock(&fake.mu);
    assert_int_equal(fake.handles, 0);
    assert_int_equal(fake.hid_inits, 0);
    assert_int_equal(fake.usb_inits, 0);
    assert_int_equal(fake.lists, 0);
    assert_int_equal(fake.cfgs, 0);
    assert_false(fake.registered);
    for (int i = 0; i < FAKE_DEVS; i++) {
        assert_int_equal(fake.dev[i].refs, 0);
        assert_int_equal(fake.dev[i].is_open, 0);
        assert_false(fake.dev[i].claimed);
    }
    pthread_mutex_unlock(&fake.mu);
}
