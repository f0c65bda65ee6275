/*
 * listen.c — the daemon's listening sockets: TCP (the protocol's --bind,
 * --metrics, --web) and the Unix socket with its lock file.
 */
#include "server_internal.h"

#include <arpa/inet.h>
#include <errno.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <stdio.h>
#include <string.h>
#include <sys/file.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

int listen_tcp(const char *addr, int port)
{
    struct sockaddr_in sa = {.sin_family = AF_INET, .sin_port = htons((uint16_t)port)};
    if (inet_pton(AF_INET, addr, &sa.sin_addr) != 1) {
        LOGE("--bind %s: not an IPv4 address", addr);
        return -1;
    }
    int fd = socket(AF_INET, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
    if (fd < 0) {
        LOGE("tcp %s:%d: socket: %s", addr, port, strerror(errno));
        return -1;
    }
    int one = 1;
    setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    if (bind(fd, (struct sockaddr *)&sa, sizeof sa) < 0 || listen(fd, 512) < 0) {
        LOGE("tcp %s:%d: %s", addr, port, strerror(errno));
        close(fd);
        return -1;
    }
    return fd;
}

/* The Unix socket, taken only from no one: PATH.lock (flock, held for the
 * daemon's life, with its pid in it) says whether another vantaged serves
 * PATH. Without it a second daemon would unlink the live socket, bind its
 * own, and remove it on exit: the first would lose its Unix clients
 * silently (TCP refuses the same clash with EADDRINUSE). Under the lock a
 * socket file left at PATH is stale (its daemon died) and is replaced; a
 * file that is not a socket is never removed. -1 (with a log line) on
 * failure; *lock_fd is the held lock. */
int listen_unix(const char *path, int *lock_fd)
{
    struct sockaddr_un sa = {.sun_family = AF_UNIX};
    char lock[sizeof sa.sun_path + 8];
    if (strlen(path) >= sizeof sa.sun_path) {
        LOGE("--unix %s: the path is too long (at most %zu bytes)", path, sizeof sa.sun_path - 1);
        return -1;
    }
    snprintf(lock, sizeof lock, "%s.lock", path);
    int lfd = open(lock, O_RDWR | O_CREAT | O_CLOEXEC, 0600);
    if (lfd < 0) {
        LOGE("--unix %s: cannot open its lock file %s: %s", path, lock, strerror(errno));
        return -1;
    }
    if (flock(lfd, LOCK_EX | LOCK_NB) < 0) {
        char pid[32] = "";
        ssize_t n = pread(lfd, pid, sizeof pid - 1, 0);
        pid[n > 0 ? n : 0] = 0;
        pid[strcspn(pid, "\n")] = 0;
        LOGE("--unix %s: another vantaged%s%s%s serves it (it holds %s): stop it or give another --unix", path,
             *pid ? " (pid " : "", pid, *pid ? ")" : "", lock);
        close(lfd);
        return -1;
    }
    char pid[32];
    int pn = snprintf(pid, sizeof pid, "%d\n", (int)getpid());
    if (ftruncate(lfd, 0) == 0) { /* the pid is for the message only */
        ssize_t ignored = pwrite(lfd, pid, (size_t)pn, 0);
        (void)ignored;
    }
    struct stat st;
    if (lstat(path, &st) == 0 && !S_ISSOCK(st.st_mode)) {
        LOGE("--unix %s: a file that is not a socket is there: not removing it", path);
        goto fail;
    }
    strcpy(sa.sun_path, path);
    int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
    if (fd < 0) {
        LOGE("--unix %s: socket: %s", path, strerror(errno));
        goto fail;
    }
    unlink(path); /* a stale socket: its daemon died (it would hold the lock) */
    if (bind(fd, (struct sockaddr *)&sa, sizeof sa) < 0 || listen(fd, 512) < 0) {
        LOGE("--unix %s: %s", path, strerror(errno));
        close(fd);
        goto fail;
    }
    *lock_fd = lfd;
    return fd;
fail:
    unlink(lock);
    close(lfd);
    return -1;
}
