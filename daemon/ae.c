/*
 * ae.c — see ae.h. Level-triggered epoll; the timer is the epoll_wait
 * timeout, so an idle loop sleeps until a socket or the timer wakes it.
 */
#include "ae.h"

#include <errno.h>
#include <stdlib.h>
#include <sys/epoll.h>
#include <time.h>
#include <unistd.h>

typedef struct ae_file {
    int mask;
    ae_file_proc proc;
    void *data;
} ae_file;

struct ae_loop {
    int epfd, setsize;
    ae_file *files;
    struct epoll_event *fired;
    bool stop;
    ae_hook before_sleep;
    void *before_sleep_data;
    ae_hook timer;
    void *timer_data;
    int period_ms;
    uint64_t next_timer;
};

uint64_t ae_now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000 + (uint64_t)ts.tv_nsec / 1000000;
}

ae_loop *ae_create(int setsize)
{
    ae_loop *l = calloc(1, sizeof *l);
    if (!l) return NULL;
    l->setsize = setsize;
    l->files = calloc((size_t)setsize, sizeof *l->files);
    l->fired = calloc((size_t)setsize, sizeof *l->fired);
    l->epfd = epoll_create1(EPOLL_CLOEXEC);
    if (!l->files || !l->fired || l->epfd < 0) {
        ae_destroy(l);
        return NULL;
    }
    return l;
}

void ae_destroy(ae_loop *l)
{
    if (!l) return;
    if (l->epfd >= 0) close(l->epfd);
    free(l->files);
    free(l->fired);
    free(l);
}

int ae_add(ae_loop *l, int fd, int mask, ae_file_proc proc, void *data)
{
    if (fd < 0 || fd >= l->setsize) {
        errno = ERANGE;
        return -1;
    }
    ae_file *f = &l->files[fd];
    int op = f->mask ? EPOLL_CTL_MOD : EPOLL_CTL_ADD;
    int m = f->mask | mask;
    struct epoll_event ev = {.data.fd = fd};
    if (m & AE_READABLE) ev.events |= EPOLLIN;
    if (m & AE_WRITABLE) ev.events |= EPOLLOUT;
    if (epoll_ctl(l->epfd, op, fd, &ev) < 0) return -1;
    f->mask = m;
    f->proc = proc;
    f->data = data;
    return 0;
}

void ae_del(ae_loop *l, int fd, int mask)
{
    if (fd < 0 || fd >= l->setsize) return;
    ae_file *f = &l->files[fd];
    if (!f->mask) return;
    int m = f->mask & ~mask;
    struct epoll_event ev = {.data.fd = fd};
    if (m & AE_READABLE) ev.events |= EPOLLIN;
    if (m & AE_WRITABLE) ev.events |= EPOLLOUT;
    epoll_ctl(l->epfd, m ? EPOLL_CTL_MOD : EPOLL_CTL_DEL, fd, &ev);
    f->mask = m;
}

int ae_mask(const ae_loop *l, int fd)
{
    return (fd >= 0 && fd < l->setsize) ? l->files[fd].mask : 0;
}

void ae_set_before_sleep(ae_loop *l, ae_hook hook, void *data)
{
    l->before_sleep = hook;
    l->before_sleep_data = data;
}

void ae_set_timer(ae_loop *l, int period_ms, ae_hook hook, void *data)
{
    l->timer = hook;
    l->timer_data = data;
    l->period_ms = period_ms;
    l->next_timer = ae_now_ms() + (uint64_t)period_ms;
}

void ae_stop(ae_loop *l)
{
    l->stop = true;
}

int ae_run(ae_loop *l)
{
    l->stop = false;
    while (!l->stop) {
        if (l->before_sleep) l->before_sleep(l, l->before_sleep_data);
        if (l->stop) break;
        int timeout = -1;
        if (l->timer && l->period_ms > 0) {
            uint64_t now = ae_now_ms();
            timeout = l->next_timer > now ? (int)(l->next_timer - now) : 0;
        }
        int n = epoll_wait(l->epfd, l->fired, l->setsize, timeout);
        if (n < 0 && errno != EINTR) return -errno; /* it ran silently out of the loop before */
        for (int i = 0; i < n; i++) {
            int fd = l->fired[i].data.fd;
            uint32_t ev = l->fired[i].events;
            ae_file *f = &l->files[fd];
            /* errors and hang-ups are reported as readable: read() says */
            if ((ev & (EPOLLIN | EPOLLERR | EPOLLHUP)) && (f->mask & AE_READABLE))
                f->proc(l, fd, f->data, AE_READABLE);
            f = &l->files[fd]; /* the callback may have removed it */
            if ((ev & (EPOLLOUT | EPOLLERR | EPOLLHUP)) && (f->mask & AE_WRITABLE))
                f->proc(l, fd, f->data, AE_WRITABLE);
        }
        if (l->timer && l->period_ms > 0 && ae_now_ms() >= l->next_timer) {
            l->next_timer = ae_now_ms() + (uint64_t)l->period_ms;
            l->timer(l, l->timer_data);
        }
    }
    return 0;
}
