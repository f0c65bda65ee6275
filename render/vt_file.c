/*
 * vt_file.c — see vt_file.h.
 */
#include "vt_file.h"

#include <errno.h>
#include <fcntl.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/random.h>
#include <time.h>
#include <unistd.h>

int vt_temp_open(const char *path, char **tmp, int *fd, char *msg, size_t msglen)
{
    size_t n = strlen(path) + 22;
    char *name = malloc(n);
    if (!name) {
        snprintf(msg, msglen, "out of memory");
        return -ENOMEM;
    }
    for (unsigned attempt = 0; attempt < 16; attempt++) {
        uint64_t salt;
        if (getrandom(&salt, sizeof salt, GRND_NONBLOCK) != (ssize_t)sizeof salt) {
            struct timespec ts;
            clock_gettime(CLOCK_REALTIME, &ts);
            salt = ((uint64_t)ts.tv_sec << 32) ^ (uint64_t)ts.tv_nsec ^ (uintptr_t)&salt ^
                   ((uint64_t)getpid() << 20) ^ (uint64_t)attempt * 0x9E3779B97F4A7C15ull;
        }
        snprintf(name, n, "%s.%016llx.tmp", path, (unsigned long long)salt);
        *fd = open(name, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
        if (*fd >= 0) {
            *tmp = name;
            return 0;
        }
        if (errno != EEXIST) break;
    }
    int e = errno;
    char buf[128];
    snprintf(msg, msglen, "cannot create temporary file %s: %s", name, strerror_r(e, buf, sizeof buf));
    free(name);
    return -e;
}

void vt_file_msgv(char *err, size_t errlen, bool *have, const char *where, const char *fmt, va_list ap)
{
    if (*have || !err || errlen == 0) return;
    *have = true;
    int n = snprintf(err, errlen, "%s: ", where);
    if (n < 0 || (size_t)n >= errlen) return;
    vsnprintf(err + n, errlen - (size_t)n, fmt, ap);
}

int vt_temp_finish(const char *path, char *tmp, int fd, int rc, char *msg, size_t msglen)
{
    char buf[128];
    if (fd >= 0 && close(fd) != 0 && rc == 0) {
        rc = -errno;
        snprintf(msg, msglen, "close: %s", strerror_r(-rc, buf, sizeof buf));
    }
    if (rc == 0 && rename(tmp, path) != 0) {
        rc = -errno;
        snprintf(msg, msglen, "rename from %s: %s", tmp, strerror_r(-rc, buf, sizeof buf));
    }
    if (rc != 0 && tmp) unlink(tmp);
    free(tmp);
    return rc;
}

const char *vt_strerror(int e, char *buf, size_t n)
{
    return strerror_r(e, buf, n); /* GNU: returns the message, maybe not buf */
}
