/*
 * test_daemon.h — the end-to-end tests' harness: the real vantaged of this
 * configuration (VANTAGE_BIN_DIR, set by the Makefile) on a free port and
 * a temporary Unix socket, with the empty scene and two query workers.
 */
#ifndef VANTAGE_TEST_DAEMON_H
#define VANTAGE_TEST_DAEMON_H

#include "vantage.h"

#include <stdbool.h>
#include <sys/types.h>

typedef struct daemon_proc {
    pid_t pid;
    int port;
    char sock[108];
    char bin[512];
} daemon_proc;

/* The directory of this configuration's binaries. */
const char *bin_dir(void);
int free_port(void);
/* Connects with a role (over the Unix socket if use_unix); asserts success. */
vtc_client *connect_role(const daemon_proc *d, int role, bool use_unix);
/* Starts vantaged (--out-limit out_limit if not NULL) and waits until it answers. */
void daemon_start(daemon_proc *d, const char *out_limit);
/* The same with extra arguments (NULL-terminated). */
void daemon_start_args(daemon_proc *d, const char *const *extra);
/* A test's own daemon as a cmocka fixture: DAEMON_TEST(fn) in a group's
 * array starts vantaged (no extra arguments) before fn, whose *state is
 * then its daemon_proc *, and stops it after fn (asserting a clean exit),
 * also when fn failed half-way (a failed test left its daemon running to
 * the end of the run before). */
int daemon_setup(void **state);
int daemon_teardown(void **state);
#define DAEMON_TEST(fn) cmocka_unit_test_setup_teardown(fn, daemon_setup, daemon_teardown)
/* What most end-to-end tests begin and end with: daemon_open starts
 * vantaged (no extra arguments) and connects one client of role over TCP;
 * daemon_close closes that client, then stops the daemon as daemon_stop. */
vtc_client *daemon_open(daemon_proc *d, int role);
void daemon_close(daemon_proc *d, vtc_client *c);
/* Runs this configuration's vantage against d (d NULL: no -p) with the
 * printf-formatted arguments, its stderr with its stdout in out (up to
 * cap - 1 bytes, NUL-ended): its exit status, -1 if it did not exit. */
int vantage_run(const daemon_proc *d, char *out, size_t cap, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));
/* When not 0, the next daemon_start* runs vantaged with RLIMIT_FSIZE at
 * this many bytes (its writes past it fail with EFBIG: a full disk). */
extern long daemon_fsize_limit;
/* Runs vantaged with args (after the binary; empty scene, no Unix socket)
 * to its exit (20 s at most): its exit status, what it printed in out. */
int daemon_run_to_exit(const char *args, char *out, size_t outlen);
/* SIGTERM; asserts a clean exit and the socket removed. */
void daemon_stop(daemon_proc *d);

#endif
