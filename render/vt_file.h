/*
 * vt_file.h — what the image writers share: a temporary file beside the
 * target, created exclusively, to be renamed into place when complete (so
 * a failed write never leaves a partial file where the caller asked).
 */
#ifndef VANTAGE_VT_FILE_H
#define VANTAGE_VT_FILE_H

#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>

/* Creates "path.<16 hex>.tmp" (O_EXCL, 0666 less umask): *tmp is malloc'ed,
 * *fd open for writing. 0, or a negative errno with a message in msg. */
int vt_temp_open(const char *path, char **tmp, int *fd, char *msg, size_t msglen);

/* Finishes what vt_temp_open began, given the writer's result rc: closes
 * fd (when >= 0), renames tmp over path when all went well, removes tmp
 * otherwise, frees tmp. Returns rc, or a new negative errno (close or
 * rename failed) with a message in msg. */
int vt_temp_finish(const char *path, char *tmp, int fd, int rc, char *msg, size_t msglen);

/* strerror_r's message for errno e (GNU: maybe not in buf). */
const char *vt_strerror(int e, char *buf, size_t n);

/* The writers' error message: "WHERE: message" into err, the first call
 * only (*have records it: the first failure is the cause, later ones are
 * consequences). Nothing when err is NULL or errlen 0. */
void vt_file_msgv(char *err, size_t errlen, bool *have, const char *where, const char *fmt, va_list ap);

#endif
