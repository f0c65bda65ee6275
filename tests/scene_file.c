/*
 * scene_file.c — see scene_file.h. Line-oriented, strict: counts must match,
 * numbers must be finite, sizes are checked before allocating.
 */
#include "scene_file.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define MAX_ITEMS 50000000u

static int fail(char *err, size_t n, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(err, n, fmt, ap);
    va_end(ap);
    return -1;
}

/* Reads the next non-comment, non-blank line. */
static char *next_line(FILE *f, char *buf, size_t n, unsigned *lineno)
{
    while (fgets(buf, (int)n, f)) {
        (*lineno)++;
        char *p = buf;
        while (*p == ' ' || *p == '\t') p++;
        if (*p == '#' || *p == '\n' || *p == '\r' || *p == 0) continue;
        return p;
    }
    return NULL;
}

static int parse_doubles(const char *p, double *out, int n)
{
    for (int i = 0; i < n; i++) {
        char *end;
        errno = 0;
        out[i] = strtod(p, &end);
        if (end == p || errno == ERANGE || !isfinite(out[i])) return -1;
        p = end;
    }
    while (*p == ' ' || *p == '\t' || *p == '\r' || *p == '\n') p++;
    return *p ? -1 : 0;
}

/* The line "KEY N" that form names (N at most MAX_ITEMS) into *count:
 * room for that many records of size bytes (one at least), or NULL with
 * the message in err. */
static void *read_section(FILE *f, char *buf, size_t n, unsigned *ln, const char *path, const char *form, size_t size,
                          unsigned long *count, char *err, size_t errlen)
{
    char scan[64];
    snprintf(scan, sizeof scan, "%.*s %%lu", (int)strcspn(form, " "), form);
    char *p = next_line(f, buf, n, ln);
    if (!p || sscanf(p, scan, count) != 1 || *count > MAX_ITEMS) {
        fail(err, errlen, "%s:%u: expected '%s'", path, *ln, form);
        return NULL;
    }
    void *mem = malloc((*count ? *count : 1) * size);
    if (!mem) fail(err, errlen, "%s: out of memory", path);
    return mem;
}

int scene_file_load(const char *path, scene_file *s, char *err, size_t errlen)
{
    memset(s, 0, sizeof *s);
    FILE *f = fopen(path, "r");
    if (!f) return fail(err, errlen, "%s: %s", path, strerror(errno));
    char buf[1024];
    unsigned ln = 0;
    char *p;
    int rc = -1;
    if (!(p = next_line(f, buf, sizeof buf, &ln)) || strncmp(p, "camera ", 7) != 0) {
        fail(err, errlen, "%s:%u: expected 'camera'", path, ln);
        goto out;
    }
    double cam[13];
    if (parse_doubles(p + 7, cam, 13)) {
        fail(err, errlen, "%s:%u: camera needs 13 finite numbers", path, ln);
        goto out;
    }
    memcpy(s->eye, cam, sizeof s->eye);
    memcpy(s->target, cam + 3, sizeof s->target);
    memcpy(s->up, cam + 6, sizeof s->up);
    s->fovy_deg = cam[9];
    s->znear = cam[10];
    s->zfar = cam[11];
    s->aspect = cam[12];
    unsigned long n;
    s->tris = read_section(f, buf, sizeof buf, &ln, path, "occluder_triangles N", 9 * sizeof *s->tris, &n, err, errlen);
    if (!s->tris) goto out;
    s->ntris = n;
    for (size_t i = 0; i < n; i++) {
        double v[9];
        if (!(p = next_line(f, buf, sizeof buf, &ln)) || parse_doubles(p, v, 9)) {
            fail(err, errlen, "%s:%u: triangle %zu needs 9 finite numbers", path, ln, i);
            goto out;
        }
        for (int k = 0; k < 9; k++) s->tris[i * 9 + k] = (float)v[k];
    }
    s->objects = read_section(f, buf, sizeof buf, &ln, path, "objects M", 6 * sizeof *s->objects, &n, err, errlen);
    if (!s->objects) goto out;
    s->nobjects = n;
    for (size_t i = 0; i < n; i++) {
        if (!(p = next_line(f, buf, sizeof buf, &ln)) || parse_doubles(p, s->objects + i * 6, 6)) {
            fail(err, errlen, "%s:%u: object %zu needs 6 finite numbers", path, ln, i);
            goto out;
        }
    }
    if (!(p = next_line(f, buf, sizeof buf, &ln)) || strncmp(p, "end", 3) != 0) {
        fail(err, errlen, "%s:%u: expected 'end'", path, ln);
        goto out;
    }
    rc = 0;
out:
    fclose(f);
    if (rc) scene_file_free(s);
    return rc;
}

void scene_file_free(scene_file *s)
{
    free(s->tris);
    free(s->objects);
    memset(s, 0, sizeof *s);
}
