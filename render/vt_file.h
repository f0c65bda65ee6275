/*
 * vt_file.h — what the file writers and readers of render/ (vt_exr.c,
 * vt_png.c, vt_jpeg.c) share: one call's error context, a temporary file
 * beside the target, created exclusively, to be renamed into place when
 * complete (so a failed write never leaves a partial file where the caller
 * asked), and errno's text. Codes are render/'s (vt_err.h).
 */
#ifndef VANTAGE_VT_FILE_H
#define VANTAGE_VT_FILE_H

#include "vt_err.h"

#include <stdbool.h>
#include <stddef.h>

/* One public call's error state: the caller's message buffer and whether a
 * message is in it yet. The first message is the cause; later ones are
 * consequences (a library's "write failed" after our "write: No space left
 * on device") and are dropped. Messages read "WHERE: what", WHERE the path
 * (or what the caller named instead, e.g. "<memory>" for a stream). */
typedef struct vt_call {
    const char *path;     /* WHERE in messages; NULL prints "(no path)" */
    char       *err;      /* the caller's buffer, or NULL */
    size_t      errlen;
    bool        have;     /* a message is set */
    int         lib_code; /* the first code a library's error callback
                             reported (OpenEXRCore), 0 if none */
} vt_call;

/* Starts a call: clears err (when there is one). */
vt_call vt_call_begin(const char *path, char *err, size_t errlen);

/* "WHERE: message" into the call's err, the first call only. c may be NULL. */
void vt_call_msg(vt_call *c, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

/* Ends a call with rc: err is cleared again on success (a library may have
 * warned on the way). Returns rc. */
int vt_call_end(vt_call *c, int rc);

/* Creates "path.<16 hex>.tmp" (O_EXCL, 0666 less umask): *tmp is malloc'ed,
 * *fd open for writing. 0, or a VT_ERRORS code (vt_err_from_errno) with
 * the message in c. */
int vt_temp_open(vt_call *c, const char *path, char **tmp, int *fd);

/* Finishes what vt_temp_open began, given the writer's result rc: closes
 * fd (when >= 0), renames tmp over path when all went well, removes tmp
 * otherwise, frees tmp. Returns rc, or a new code (close or rename failed)
 * with the message in c. */
int vt_temp_finish(vt_call *c, const char *path, char *tmp, int fd, int rc);

/* strerror_r's message for errno e (GNU: maybe not in buf). */
const char *vt_errno_text(int e, char *buf, size_t n);

#endif
