/*
 * auth.c — token files and role grants (see auth.h).
 */
#include "auth.h"
#include "protocol.h"

#include <arpa/inet.h>
#include <errno.h>
#include <fcntl.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#define TOKEN_FILE_MAX (64u << 10)


static int role_of(const char *s, size_t n)
{
    static const char *const names[] = {"viewer", "commander", "editor"};
    for (int r = 0; r < 3; r++)
        if (strlen(names[r]) == n && !memcmp(s, names[r], n)) return r;
    return -1;
}

int auth_parse(const char *text, size_t len, auth_tokens *t, char *err, size_t errlen)
{
    memset(t, 0, sizeof *t);
    bool viewer_line = false;
    size_t i = 0;
    for (uint32_t line = 1; i < len; line++) {
        size_t e = i;
        while (e < len && text[e] != '\n') e++;
        size_t a = i, b = e;
        i = e + 1;
        if (b > a && text[b - 1] == '\r') b--;
        while (a < b && (text[a] == ' ' || text[a] == '\t')) a++;
        while (b > a && (text[b - 1] == ' ' || text[b - 1] == '\t')) b--;
        if (a == b || text[a] == '#') continue;
        size_t r1 = a;
        while (r1 < b && text[r1] != ' ' && text[r1] != '\t') r1++;
        int role = role_of(text + a, r1 - a);
        if (role < 0) return vp_errf(err, errlen, -1, "line %u: the role must be viewer, commander or editor", line);
        size_t k = r1;
        while (k < b && (text[k] == ' ' || text[k] == '\t')) k++;
        size_t n = b - k;
        if (n < AUTH_MIN_TOKEN || n > VP_MAX_TOKEN)
            return vp_errf(err, errlen, -1, "line %u: a token is %u to %u characters (this one: %zu)", line,
                        AUTH_MIN_TOKEN, VP_MAX_TOKEN, n);
        for (size_t q = k; q < b; q++)
            if ((unsigned char)text[q] <= ' ' || (unsigned char)text[q] >= 127)
                return vp_errf(err, errlen, -1, "line %u: a token is printable ASCII without spaces", line);
        if (t->n == AUTH_MAX_TOKENS)
            return vp_errf(err, errlen, -1, "line %u: more than %u tokens", line, AUTH_MAX_TOKENS);
        t->role[t->n] = (uint8_t)role;
        t->len[t->n] = (uint8_t)n;
        memcpy(t->tok[t->n], text + k, n);
        t->n++;
        viewer_line |= role == VP_ROLE_VIEWER;
    }
    if (!t->n) return vp_errf(err, errlen, -1, "no tokens in it (lines: ROLE TOKEN)");
    t->public_viewer = !viewer_line;
    return 0;
}

int auth_load(const char *path, auth_tokens *t, char *err, size_t errlen)
{
    int fd = open(path, O_RDONLY | O_CLOEXEC | O_NOFOLLOW);
    if (fd < 0 && errno == ELOOP) return vp_errf(err, errlen, -1, "%s: a symbolic link (name the file itself)", path);
    if (fd < 0) return vp_errf(err, errlen, -1, "%s: %s", path, strerror(errno));
    struct stat st;
    char *buf = NULL;
    int rc = -1;
    if (fstat(fd, &st) != 0) {
        vp_errf(err, errlen, -1, "%s: %s", path, strerror(errno));
    } else if (!S_ISREG(st.st_mode)) {
        vp_errf(err, errlen, -1, "%s: not a regular file", path);
    } else if (st.st_mode & 077) {
        vp_errf(err, errlen, -1, "%s: readable or writable by others (mode %04o): chmod 600 it", path,
             (unsigned)(st.st_mode & 07777));
    } else if (st.st_uid != geteuid()) {
        vp_errf(err, errlen, -1, "%s: owned by uid %u, not by this daemon's user (%u)", path, (unsigned)st.st_uid,
             (unsigned)geteuid());
    } else if (st.st_size > (off_t)TOKEN_FILE_MAX) {
        vp_errf(err, errlen, -1, "%s: larger than %u bytes", path, TOKEN_FILE_MAX);
    } else if (!(buf = malloc((size_t)st.st_size + 1))) {
        vp_errf(err, errlen, -1, "%s: out of memory", path);
    } else {
        ssize_t got = 0, n;
        while (got < st.st_size && (n = read(fd, buf + got, (size_t)(st.st_size - got))) > 0) got += n;
        if (got != st.st_size) {
            vp_errf(err, errlen, -1, "%s: short read", path);
        } else {
            char why[200];
            rc = auth_parse(buf, (size_t)got, t, why, sizeof why);
            if (rc) vp_errf(err, errlen, -1, "%s: %s", path, why);
        }
    }
    if (buf) {
        memset(buf, 0, (size_t)st.st_size); /* no copies of tokens left lying in the heap */
        free(buf);
    }
    close(fd);
    return rc;
}

bool auth_ct_equal(const uint8_t *a, const uint8_t *b)
{
    volatile uint8_t d = 0;
    for (size_t i = 0; i < AUTH_TOKEN_CAP; i++) d |= a[i] ^ b[i];
    return d == 0;
}

bool auth_grants(const auth_tokens *t, int role, const uint8_t *tok, size_t len)
{
    if (role == VP_ROLE_VIEWER && t->public_viewer) return true;
    if (len < AUTH_MIN_TOKEN || len > VP_MAX_TOKEN) return false;
    uint8_t given[AUTH_TOKEN_CAP] = {0};
    memcpy(given, tok, len);
    /* every token compared in full, whatever matched before */
    bool ok = false;
    for (uint32_t i = 0; i < t->n; i++) {
        bool same = auth_ct_equal(given, t->tok[i]) & (t->len[i] == len);
        ok |= same & (t->role[i] >= role);
    }
    memset(given, 0, sizeof given);
    return ok;
}

bool auth_loopback(const char *addr)
{
    if (!addr || !*addr) return true; /* no TCP at all */
    if (!strcmp(addr, "localhost")) return true;
    struct in_addr a4;
    if (inet_pton(AF_INET, addr, &a4) == 1) return (ntohl(a4.s_addr) >> 24) == 127;
    struct in6_addr a6;
    if (inet_pton(AF_INET6, addr, &a6) == 1) return IN6_IS_ADDR_LOOPBACK(&a6);
    return false;
}
