/*
 * cluster_rec.c — stream messages to records (cluster_rec.h).
 */
#include "cluster_rec.h"
#include "journal.h"
#include "vp_bytes.h"

#include <errno.h>
#include <inttypes.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int bad(char *why, size_t whylen, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
static int bad(char *why, size_t whylen, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(why, whylen, fmt, ap);
    va_end(ap);
    return CL_ASM_BAD;
}

/* A decimal number and nothing else (no sign, no space): false otherwise. */
static bool number(const char *s, const char **end, uint64_t *out)
{
    if (*s < '0' || *s > '9') return false;
    uint64_t v = 0;
    for (; *s >= '0' && *s <= '9'; s++) {
        if (v > (UINT64_MAX - (uint64_t)(*s - '0')) / 10) return false;
        v = v * 10 + (uint64_t)(*s - '0');
    }
    *end = s;
    *out = v;
    return true;
}

int cl_asm_take(cl_asm *a, uint64_t seq, const char *lease, const char *part, const uint8_t *d, size_t n,
                const uint8_t **rec, size_t *rlen, char *why, size_t whylen)
{
    if (seq > a->applied + 1) return CL_ASM_GAP;
    if (seq != a->applied + 1)
        return bad(why, whylen, "stream message %" PRIu64 " came after %" PRIu64 " (out of order)", seq, a->applied);
    const char *e;
    uint64_t l;
    if (!lease || !number(lease, &e, &l) || *e)
        return bad(why, whylen, "stream message %" PRIu64 ": no Vantage-Lease header: not a Vantage record", seq);
    if (l < a->max_lease)
        return bad(why, whylen, "stream message %" PRIu64 ": written under lease %" PRIu64 " after one under lease %" PRIu64
                   ": a fenced writer's record", seq, l, a->max_lease);
    uint64_t i = 1, of = 1;
    if (part && (!number(part, &e, &i) || *e != '/' || !number(e + 1, &e, &of) || *e || !i || i > of ||
                 of > UINT32_MAX))
        return bad(why, whylen, "stream message %" PRIu64 ": a bad Vantage-Part header \"%.40s\"", seq, part);
    if (i != (uint64_t)a->got + 1 || (a->got && of != a->parts))
        return bad(why, whylen, "stream message %" PRIu64 ": part %" PRIu64 " of %" PRIu64 " where part %u of %" PRIu64
                   " was due", seq, i, of, a->got + 1, a->got ? (uint64_t)a->parts : of);
    const uint8_t *r = d;
    size_t rn = n;
    if (of > 1) {
        if (a->len + n > a->cap) {
            size_t cap = (a->len + n) * 2;
            uint8_t *b = realloc(a->buf, cap ? cap : 1);
            if (!b) return bad(why, whylen, "stream message %" PRIu64 ": out of memory for a record's parts", seq);
            a->buf = b;
            a->cap = cap;
        }
        if (n) memcpy(a->buf + a->len, d, n);
        if (i < of) { /* kept: the message is taken */
            a->len += n;
            a->got = (uint32_t)i;
            a->parts = (uint32_t)of;
            a->applied = seq;
            a->max_lease = l;
            return CL_ASM_PART;
        }
        r = a->buf;
        rn = a->len + n;
    }
    const char *w = journal_rec_check(r, rn, a->recs + 1);
    if (!w && rn != JOURNAL_REC_HDR + (size_t)vp_ld_u32(r)) w = "bytes after the record";
    if (w) return bad(why, whylen, "stream message %" PRIu64 " (record %" PRIu64 "): %s", seq, a->recs + 1, w);
    a->len = 0;
    a->got = a->parts = 0;
    a->applied = seq;
    a->max_lease = l;
    a->recs++;
    *rec = r;
    *rlen = rn;
    return CL_ASM_RECORD;
}

void cl_asm_reset(cl_asm *a, uint64_t applied, uint64_t recs, uint64_t max_lease)
{
    a->applied = applied;
    a->recs = recs;
    a->max_lease = max_lease;
    a->len = 0;
    a->got = a->parts = 0;
}

void cl_asm_free(cl_asm *a)
{
    free(a->buf);
    *a = (cl_asm){0};
}
