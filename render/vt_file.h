/*
 * vt_file.h — what the image writers share: a temporary file beside the
 * target, created exclusively, to be renamed into place when complete (so
 * a failed write never leaves a partial file where the caller asked).
 */
#ifndef VANTAGE_VT_FILE_H
#define VANTAGE_VT_FILE_H

#include <stddef.h>

/* Creates "path.<16 hex>.tmp" (O_EXCL, 0666 less umask): *tmp is malloc'ed,
 * *fd open for writing. 0, or a negative errno with a message in msg. */
int vt_temp_open(const char *path, char **tmp, int *fd, char *msg, size_t msglen);

#endif
