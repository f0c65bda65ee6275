/*
 * ae.h — the daemon's event loop, in the manner of Redis's ae: one epoll
 * instance, file events with read/write callbacks, one timer, and a
 * before-sleep hook where the tick's work is committed and output flushed.
 * Single-threaded: every callback runs on the loop's thread.
 */
#ifndef VANTAGE_AE_H
#define VANTAGE_AE_H

#include <stdbool.h>
#include <stdint.h>

#define AE_READABLE 1
#define AE_WRITABLE 2

typedef struct ae_loop ae_loop;
typedef void (*ae_file_proc)(ae_loop *l, int fd, void *data, int mask);
typedef void (*ae_hook)(ae_loop *l, void *data);

/* setsize: the largest fd + 1 the loop can watch. NULL on failure. */
ae_loop *ae_create(int setsize);
void     ae_destroy(ae_loop *l);
/* Adds mask to fd's watched events with proc (one proc per fd). 0 or -1. */
int  ae_add(ae_loop *l, int fd, int mask, ae_file_proc proc, void *data);
/* Removes mask from fd's watched events; mask 3 forgets the fd. */
void ae_del(ae_loop *l, int fd, int mask);
int  ae_mask(const ae_loop *l, int fd);
void ae_set_before_sleep(ae_loop *l, ae_hook hook, void *data);
/* A periodic callback every period_ms (0 = none). */
void ae_set_timer(ae_loop *l, int period_ms, ae_hook hook, void *data);
/* Runs until ae_stop (0), or until epoll_wait fails with anything but
 * EINTR: -errno (the loop cannot wait for events any more; the caller
 * says so and ends). Blocks in epoll_wait when idle: no busy loop. */
int  ae_run(ae_loop *l);
void ae_stop(ae_loop *l);
uint64_t ae_now_ms(void);

#endif
