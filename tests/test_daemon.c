/*
 * test_daemon.c — see test_daemon.h.
 */
#include "test_util.h"
#include "test_daemon.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <signal.h>
#include <stdio.h>
#include <string.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

const char *bin_dir(void)
{
    const char *d = getenv("VANTAGE_BIN_DIR");
    return d ? d : "build/release";
}

int free_port(void)
{
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    struct sockaddr_in sa = {.sin_family = AF_INET, .sin_addr.s_addr = htonl(INADDR_LOOPBACK)};
    socklen_t len = sizeof sa;
    assert_int_equal(bind(fd, (struct sockaddr *)&sa, sizeof sa), 0);
    assert_int_equal(getsockname(fd, (struct sockaddr *)&sa, &len), 0);
    close(fd);
    return ntohs(sa.sin_port);
}

vtc_client *connect_role(const daemon_proc *d, int role, bool use_unix)
{
    vtc_client *c = NULL;
    char err[256];
    vtc_connect_opts o = {.port = d->port, .role = role, .unix_path = use_unix ? d->sock : NULL,
                         .timeout_ms = 20000};
    int rc = vtc_connect(&o, &c, err, sizeof err);
    if (rc) fprintf(stderr, "connect: %s\n", err);
    assert_int_equal(rc, VP_OK);
    return c;
}

void daemon_start(daemon_proc *d, const char *out_limit)
{
    const char *extra[3] = {NULL};
    if (out_limit) {
        extra[0] = "--out-limit";
        extra[1] = out_limit;
    }
    daemon_start_args(d, extra);
}

long daemon_fsize_limit;

void daemon_start_args(daemon_proc *d, const char *const *extra)
{
    memset(d, 0, sizeof d[0]);
    d->port = free_port();
    snprintf(d->sock, sizeof d->sock, "/tmp/vantage-test-%d-%d.sock", (int)getpid(), d->port);
    snprintf(d->bin, sizeof d->bin, "%s/vantaged", bin_dir());
    char port[16];
    snprintf(port, sizeof port, "%d", d->port);
    d->pid = fork();
    assert_true(d->pid >= 0);
    if (d->pid == 0) {
        prctl(PR_SET_PDEATHSIG, SIGTERM); /* a failed test never leaves a daemon behind */
        if (daemon_fsize_limit) {
            struct rlimit rl = {(rlim_t)daemon_fsize_limit, (rlim_t)daemon_fsize_limit};
            setrlimit(RLIMIT_FSIZE, &rl);
        }
        const char *argv[32] = {d->bin, "--scene", "empty", "--port", port, "--unix", d->sock, "--log-level",
                                "warn", "--threads", "2"};
        int n = 11;
        for (int i = 0; extra && extra[i] && n < 30; i++) argv[n++] = extra[i];
        argv[n] = NULL;
        execv(d->bin, (char *const *)argv);
        _exit(127);
    }
    /* wait until it answers (a refusal of the token-less viewer is an
       answer: a daemon with --tokens) */
    for (int i = 0; i < 500; i++) {
        vtc_client *c = NULL;
        int rc = vtc_connect(&(vtc_connect_opts){.port = d->port, .timeout_ms = 2000}, &c, NULL, 0);
        if (rc == VP_OK || rc == VP_ERR_AUTH) {
            vtc_close(c);
            return;
        }
        usleep(10000);
    }
    fail_msg("vantaged (%s) did not start", d->bin);
}

void daemon_stop(daemon_proc *d)
{
    kill(d->pid, SIGTERM);
    int st;
    waitpid(d->pid, &st, 0);
    if (!WIFEXITED(st)) fail_msg("vantaged %d: %s %d", (int)d->pid, WIFSIGNALED(st) ? "killed by signal" : "status", WIFSIGNALED(st) ? WTERMSIG(st) : st);
    assert_int_equal(WEXITSTATUS(st), 0); /* clean shutdown on SIGTERM */
    assert_true(access(d->sock, F_OK) != 0); /* and the socket is gone */
}

int daemon_setup(void **state)
{
    daemon_proc *d = malloc(sizeof *d);
    assert_non_null(d);
    *state = d;
    daemon_start(d, NULL);
    return 0;
}

int daemon_teardown(void **state)
{
    daemon_proc *d = *state;
    if (d) daemon_stop(d);
    free(d);
    return 0;
}

vtc_client *daemon_open(daemon_proc *d, int role)
{
    daemon_start(d, NULL);
    return connect_role(d, role, false);
}

void daemon_close(daemon_proc *d, vtc_client *c)
{
    vtc_close(c);
    daemon_stop(d);
}

int vantage_run(const daemon_proc *d, char *out, size_t cap, const char *fmt, ...)
{
    char args[2048], cmd[3072], port[24] = "";
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(args, sizeof args, fmt, ap);
    va_end(ap);
    assert_true(n >= 0 && (size_t)n < sizeof args);
    if (d) snprintf(port, sizeof port, "-p %d ", d->port);
    n = snprintf(cmd, sizeof cmd, "%s/vantage %s%s 2>&1", bin_dir(), port, args);
    assert_true(n >= 0 && (size_t)n < sizeof cmd);
    int st = test_run_cmd(cmd, out, cap);
    return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

int daemon_run_to_exit(const char *args, char *out, size_t outlen)
{
    char cmd[1024];
    snprintf(cmd, sizeof cmd, "timeout 20 %s/vantaged --scene empty --unix '' --log-level warn %s 2>&1", bin_dir(),
             args);
    int st = test_run_cmd(cmd, out, outlen);
    return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}
