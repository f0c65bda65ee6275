/*
 * vt_lut.c — the .cube reader and the 3D LUT's interpolation (vt_lut.h).
 * A file is read once, at the daemon's start; the table is then read-only
 * and shared by every frame's tone map (one trilinear lookup, 8 rows, per
 * pixel: about as much as the tone map itself).
 */
#include "vt_lut.h"

#include "vt_err.h"
#include "vt_file.h"
#include "vp_err.h"

#include <ctype.h>
#include <errno.h>
#include <float.h>
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

void vt_lut_free(vt_lut3d *l)
{
    if (!l) return;
    free(l->rgb);
    *l = (vt_lut3d){0};
}

/* An error: the message formatted (from *out's fields, still there), then
 * the table freed and *out zeroed; rc (a constant). */
#define fail(out, rc, err, errlen, ...) (vp_errf(err, errlen, rc, __VA_ARGS__), vt_lut_free(out), (rc))

/* k finite floats separated by blanks, nothing after: 0, else -1. */
static int numbers(const char *s, int k, float *v)
{
    for (int i = 0; i < k; i++) {
        char *end;
        errno = 0;
        double d = strtod(s, &end);
        if (end == s || !(fabs(d) <= FLT_MAX) || (*end && !isspace((unsigned char)*end))) return -1;
        v[i] = (float)d;
        s = end;
    }
    while (isspace((unsigned char)*s)) s++;
    return *s ? -1 : 0;
}

int vt_lut_parse(const char *text, size_t len, vt_lut3d *out, char *err, size_t errlen)
{
    *out = (vt_lut3d){.dmax = {1, 1, 1}};
    if (err && errlen) *err = 0;
    if (len > VT_LUT_MAX_FILE)
        return fail(out, VT_ERR_TOO_LARGE, err, errlen, "%zu bytes, over the limit of %u", len, VT_LUT_MAX_FILE);
    size_t pos = 0, rows = 0, want = 0;
    unsigned line = 0, domain_line = 0;
    bool title = false, dmin = false, dmax = false;
    char buf[VT_LUT_MAX_LINE + 1];
    while (pos < len) {
        line++;
        size_t end = pos;
        while (end < len && text[end] != '\n' && text[end] != '\r') end++;
        size_t l = end - pos;
        if (l > VT_LUT_MAX_LINE)
            return fail(out, VT_ERR_CORRUPT, err, errlen, "line %u: longer than %u bytes", line, VT_LUT_MAX_LINE);
        memcpy(buf, text + pos, l);
        buf[l] = 0;
        if (memchr(buf, 0, l))
            return fail(out, VT_ERR_CORRUPT, err, errlen, "line %u: a NUL byte (not a text file)", line);
        if (end < len && text[end] == '\r' && end + 1 < len && text[end + 1] == '\n') end++;
        pos = end + 1;
        char *s = buf;
        while (isspace((unsigned char)*s)) s++;
        if (!*s || *s == '#') continue;
        if (isalpha((unsigned char)*s)) {
            char *a = s;
            while (*a && !isspace((unsigned char)*a)) a++;
            size_t kl = (size_t)(a - s);
            while (isspace((unsigned char)*a)) a++;
#define KW(w) (kl == sizeof(w) - 1 && !memcmp(s, w, kl))
            if (rows)
                return fail(out, VT_ERR_CORRUPT, err, errlen, "line %u: keyword %.*s after the table's rows", line,
                            (int)kl, s);
            if (KW("TITLE")) {
                char *q = a[0] == '"' ? strrchr(a + 1, '"') : NULL;
                if (title || !q || q[1])
                    return fail(out, VT_ERR_CORRUPT, err, errlen,
                                title ? "line %u: a second TITLE" : "line %u: TITLE wants one \"quoted text\"", line);
                snprintf(out->title, sizeof out->title, "%.*s", (int)(q - a - 1), a + 1);
                title = true;
            } else if (KW("LUT_3D_SIZE")) {
                char *e;
                errno = 0;
                unsigned long n = strtoul(a, &e, 10);
                while (isspace((unsigned char)*e)) e++;
                if (out->n) return fail(out, VT_ERR_CORRUPT, err, errlen, "line %u: a second LUT_3D_SIZE", line);
                if (!isdigit((unsigned char)*a) || *e || errno || n < 2 || n > VT_LUT_MAX_SIZE)
                    return fail(out, VT_ERR_CORRUPT, err, errlen, "line %u: LUT_3D_SIZE wants a number 2..%u", line,
                                VT_LUT_MAX_SIZE);
                out->n = (uint32_t)n;
            } else if (KW("LUT_1D_SIZE") || KW("LUT_1D_INPUT_RANGE")) {
                return fail(out, VT_ERR_UNSUPPORTED, err, errlen, "line %u: a 1D LUT (%.*s); only 3D LUTs are read",
                            line, (int)kl, s);
            } else if (KW("DOMAIN_MIN") || KW("DOMAIN_MAX")) {
                bool mn = KW("DOMAIN_MIN");
                if (mn ? dmin : dmax)
                    return fail(out, VT_ERR_CORRUPT, err, errlen, "line %u: a second %.*s", line, (int)kl, s);
                if (numbers(a, 3, mn ? out->dmin : out->dmax))
                    return fail(out, VT_ERR_CORRUPT, err, errlen, "line %u: %.*s wants three finite numbers", line,
                                (int)kl, s);
                *(mn ? &dmin : &dmax) = true;
                domain_line = line;
            } else if (KW("LUT_3D_INPUT_RANGE")) {
                float r[2];
                if (dmin || dmax)
                    return fail(out, VT_ERR_CORRUPT, err, errlen, "line %u: a second input domain", line);
                if (numbers(a, 2, r))
                    return fail(out, VT_ERR_CORRUPT, err, errlen,
                                "line %u: LUT_3D_INPUT_RANGE wants two finite numbers", line);
                for (int k = 0; k < 3; k++) {
                    out->dmin[k] = r[0];
                    out->dmax[k] = r[1];
                }
                dmin = dmax = true;
                domain_line = line;
            } else {
                return fail(out, VT_ERR_CORRUPT, err, errlen, "line %u: unknown keyword %.*s", line,
                            (int)(kl < 40 ? kl : 40), s);
            }
#undef KW
            continue;
        }
        /* a row of the table */
        if (!out->n)
            return fail(out, VT_ERR_CORRUPT, err, errlen, "line %u: a table row before LUT_3D_SIZE", line);
        if (!out->rgb) {
            for (int k = 0; k < 3; k++)
                if (!(out->dmin[k] < out->dmax[k]))
                    return fail(out, VT_ERR_CORRUPT, err, errlen,
                                "line %u: DOMAIN_MIN is not below DOMAIN_MAX (channel %d: %g, %g)", domain_line, k,
                                (double)out->dmin[k], (double)out->dmax[k]);
            want = (size_t)out->n * out->n * out->n;
            if (!(out->rgb = malloc(want * 3 * sizeof *out->rgb)))
                return fail(out, VT_ERR_NOMEM, err, errlen, "out of memory for %zu rows", want);
        }
        if (rows == want)
            return fail(out, VT_ERR_CORRUPT, err, errlen, "line %u: more than the %zu rows of a %u^3 table", line,
                        want, out->n);
        if (numbers(s, 3, out->rgb + 3 * rows))
            return fail(out, VT_ERR_CORRUPT, err, errlen, "line %u: a row wants three finite numbers", line);
        rows++;
    }
    if (!out->n) return fail(out, VT_ERR_CORRUPT, err, errlen, "line %u: no LUT_3D_SIZE (not a 3D .cube)", line);
    if (rows < (want ? want : 1))
        return fail(out, VT_ERR_CORRUPT, err, errlen, "line %u: the table ends after %zu of %zu rows", line, rows,
                    (size_t)out->n * out->n * out->n);
    return 0;
}

int vt_lut_load(const char *path, vt_lut3d *out, char *err, size_t errlen)
{
    *out = (vt_lut3d){0};
    char ebuf[256], tbuf[128];
    FILE *fp = fopen(path, "rb");
    if (!fp) {
        int e = errno;
        snprintf(err, errlen, "%s: %s", path, vt_errno_text(e, tbuf, sizeof tbuf));
        return vt_err_from_errno(e);
    }
    size_t cap = 1 << 16, len = 0;
    char *text = malloc(cap);
    int rc = 0;
    while (text) {
        if (len == cap) {
            if (cap > VT_LUT_MAX_FILE) break;
            char *t = realloc(text, cap * 2);
            if (!t) {
                free(text);
                text = NULL;
                break;
            }
            text = t;
            cap *= 2;
        }
        size_t got = fread(text + len, 1, cap - len, fp);
        len += got;
        if (got == 0) break;
    }
    if (!text) {
        rc = VT_ERR_NOMEM;
        snprintf(err, errlen, "%s: out of memory", path);
    } else if (ferror(fp)) {
        rc = VT_ERR_FILE;
        snprintf(err, errlen, "%s: read failed", path);
    } else if ((rc = vt_lut_parse(text, len, out, ebuf, sizeof ebuf))) {
        snprintf(err, errlen, "%s: %s", path, ebuf);
    }
    free(text);
    fclose(fp);
    return rc;
}

void vt_lut_apply(const vt_lut3d *l, const float in[3], float out[3])
{
    float k[3];
    vt_lut_scale(l, k);
    vt_lut_sample(l, k, in, out);
}
