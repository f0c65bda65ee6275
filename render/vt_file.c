/*
 * vt_file.c — see vt_file.h: the call context the file formats share, the
 * temporary file and its rename, errno's text.
 */
#include "vt_file.h"

#include <errno.h>
#include <fcntl.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/random.h>
#include <time.h>
#include <unistd.h>

vt_call vt_call_begin(const char *path, char *err, size_t errlen)
{
    if (err && errlen) err[0] = '\0';
    return (vt_call){.path = path, .err = err, .errlen = errlen};
}

void vt_call_msg(vt_call *c, const char *fmt, ...)
{
    if (!c || c->have || !c->err || c->errlen == 0) return;
    c->have = true;
    int n = snprintf(c->err, c->errlen, "%s: ", c->path ? c->path : "(no path)");
    if (n < 0 || (size_t)n >= c->errlen) return;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(c->err + n, c->errlen - (size_t)n, fmt, ap);
    va_end(ap);
}

int vt_call_end(vt_call *c, int rc)
{
    if (rc == 0 && c->err && c->errlen) c->err[0] = '\0';
    return rc;
}

int vt_temp_open(vt_call *c, const char *path, char **tmp, int *fd)
{
    size_t n = strlen(path) + 22;
    char *name = malloc(n);
    if (!name) {
        vt_call_msg(c, "out of memory");
        return VT_ERR_NOMEM;
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
    vt_call_msg(c, "cannot create temporary file %s: %s", name, vt_errno_text(e, buf, sizeof buf));
    free(name);
    return vt_err_from_errno(e);
}

int vt_temp_finish(vt_call *c, const char *path, char *tmp, int fd, int rc)
{
    char buf[128];
    if (fd >= 0 && close(fd) != 0 && rc == 0) {
        int e = errno;
        rc = vt_err_from_errno(e);
        vt_call_msg(c, "close: %s", vt_errno_text(e, buf, sizeof buf));
    }
    if (rc == 0 && rename(tmp, path) != 0) {
        int e = errno;
        rc = vt_err_from_errno(e);
        vt_call_msg(c, "rename from %s: %s", tmp, vt_errno_text(e, buf, sizeof buf));
    }
    if (rc != 0 && tmp) unlink(tmp);
    free(tmp);
    return rc;
}

const char *vt_errno_text(int e, char *buf, size_t n)
{
    return strerror_r(e, buf, n); /* GNU: returns the message, maybe not buf */
}
