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
vt_client *connect_role(const daemon_proc *d, int role, bool use_unix);
/* Starts vantaged (--out-limit out_limit if not NULL) and waits until it answers. */
void daemon_start(daemon_proc *d, const char *out_limit);
/* The same with extra arguments (NULL-terminated). */
void daemon_start_args(daemon_proc *d, const char *const *extra);
/* When not 0, the next daemon_start* runs vantaged with RLIMIT_FSIZE at
 * this many bytes (its writes past it fail with EFBIG: a full disk). */
extern long daemon_fsize_limit;
/* Runs vantaged with args (after the binary; empty scene, no Unix socket)
 * to its exit (20 s at most): its exit status, what it printed in out. */
int daemon_run_to_exit(const char *args, char *out, size_t outlen);
/* SIGTERM; asserts a clean exit and the socket removed. */
void daemon_stop(daemon_proc *d);

#endif
