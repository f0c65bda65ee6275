/*
 * test_cluster_rec.c — a replica's stream messages made records again
 * (daemon/cluster_rec.c): what a cluster's stream may carry, good and bad.
 * The model: a record is the journal's (journal_rec_header + payload); a
 * stream is those records cut into messages of at most `part` bytes, in
 * order, under non-decreasing leases. Every way of cutting a good stream
 * must give the records back byte for byte; every corruption of one message
 * (its order, lease, part header, a byte) must be refused with a reason, or
 * give records that still pass their CRC; nothing may crash (ASan build).
 */
#include "cluster_rec.h"
#include "journal.h"
#include "splitmix.h"
#include "test_util.h"

#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct rec {
    uint8_t *b;
    size_t n;
} rec;

static rec make_rec(uint64_t num, uint32_t len, uint64_t *seed)
{
    rec r = {.n = JOURNAL_REC_HDR + len};
    r.b = malloc(r.n);
    assert_non_null(r.b);
    for (uint32_t i = 0; i < len; i++) r.b[JOURNAL_REC_HDR + i] = (uint8_t)splitmix64(seed);
    journal_rec_header(r.b, num, 0x0101, 0, 0, r.b + JOURNAL_REC_HDR, len);
    return r;
}

typedef struct msg {
    uint64_t seq;
    char lease[24], part[48];
    bool has_part;
    const uint8_t *d;
    size_t n;
} msg;

/* The records cut into messages of at most cut bytes (leases rising every
 * seventh message): how many messages. */
static size_t cut_stream(const rec *rs, size_t nr, size_t cut, msg *out, size_t max)
{
    size_t nm = 0;
    uint64_t lease = 5;
    for (size_t i = 0; i < nr; i++) {
        size_t parts = (rs[i].n + cut - 1) / cut;
        for (size_t p = 0; p < parts; p++) {
            assert_true(nm < max);
            msg *m = &out[nm++];
            m->seq = nm;
            if (nm % 7 == 0) lease += 3;
            snprintf(m->lease, sizeof m->lease, "%" PRIu64, lease);
            m->has_part = parts > 1;
            snprintf(m->part, sizeof m->part, "%zu/%zu", p + 1, parts);
            m->d = rs[i].b + p * cut;
            m->n = rs[i].n - p * cut < cut ? rs[i].n - p * cut : cut;
        }
    }
    return nm;
}

static int take(cl_asm *a, const msg *m, const uint8_t **r, size_t *rn, char *why)
{
    return cl_asm_take(a, m->seq, m->lease, m->has_part ? m->part : NULL, m->d, m->n, r, rn, why, 300);
}

/* Every cut of a good stream gives the records back, in order. */
static void test_cluster_rec_roundtrip(void **state)
{
    (void)state;
    uint64_t seed = 0x5eed;
    rec rs[40];
    for (size_t i = 0; i < 40; i++) rs[i] = make_rec(i + 1, (uint32_t)(splitmix64(&seed) % 3000), &seed);
    static msg ms[200000];
    const size_t cuts[] = {1, 7, 24, 25, 100, 1024, 1 << 20};
    for (size_t c = 0; c < sizeof cuts / sizeof cuts[0]; c++) {
        size_t nm = cut_stream(rs, 40, cuts[c], ms, sizeof ms / sizeof ms[0]);
        cl_asm a = {0};
        size_t got = 0;
        char why[300];
        for (size_t i = 0; i < nm; i++) {
            const uint8_t *r;
            size_t rn;
            int k = take(&a, &ms[i], &r, &rn, why);
            if (k == CL_ASM_BAD) fail_msg("cut %zu, message %zu: %s", cuts[c], i + 1, why);
            assert_true(k == CL_ASM_PART || k == CL_ASM_RECORD);
            if (k == CL_ASM_RECORD) {
                assert_int_equal(rn, rs[got].n);
                assert_memory_equal(r, rs[got].b, rn);
                got++;
                assert_int_equal(a.recs, got);
            }
        }
        assert_int_equal(got, 40);
        assert_int_equal(a.applied, nm);
        cl_asm_free(&a);
    }
    for (size_t i = 0; i < 40; i++) free(rs[i].b);
}

/* Each way a message can be wrong, refused with its reason and nothing
 * taken (the next good message is still taken after a refusal). */
static void test_cluster_rec_refusals(void **state)
{
    (void)state;
    uint64_t seed = 7;
    rec r1 = make_rec(1, 50, &seed), r2 = make_rec(2, 50, &seed);
    const uint8_t *r;
    size_t rn;
    char why[300];
    cl_asm a = {0};
    struct {
        uint64_t seq;
        const char *lease, *part;
        const uint8_t *d;
        size_t n;
        int want;
        const char *says;
    } rows[] = {
        {2, "5", NULL, r1.b, r1.n, CL_ASM_GAP, NULL},                 /* past the next one */
        {1, NULL, NULL, r1.b, r1.n, CL_ASM_BAD, "no Vantage-Lease"},  /* a foreign message */
        {1, "", NULL, r1.b, r1.n, CL_ASM_BAD, "no Vantage-Lease"},
        {1, "-5", NULL, r1.b, r1.n, CL_ASM_BAD, "no Vantage-Lease"},
        {1, "5x", NULL, r1.b, r1.n, CL_ASM_BAD, "no Vantage-Lease"},
        {1, "99999999999999999999999", NULL, r1.b, r1.n, CL_ASM_BAD, "no Vantage-Lease"},
        {1, "5", "0/2", r1.b, 10, CL_ASM_BAD, "bad Vantage-Part"},
        {1, "5", "3/2", r1.b, 10, CL_ASM_BAD, "bad Vantage-Part"},
        {1, "5", "1/", r1.b, 10, CL_ASM_BAD, "bad Vantage-Part"},
        {1, "5", "1/2x", r1.b, 10, CL_ASM_BAD, "bad Vantage-Part"},
        {1, "5", " 1/2", r1.b, 10, CL_ASM_BAD, "bad Vantage-Part"},
        {1, "5", "1/99999999999", r1.b, 10, CL_ASM_BAD, "bad Vantage-Part"},
        {1, "5", "2/2", r1.b, 10, CL_ASM_BAD, "part 2 of 2 where part 1"},
        {1, "5", NULL, r1.b, r1.n - 1, CL_ASM_BAD, "torn record"},    /* short */
        {1, "5", NULL, r2.b, r2.n, CL_ASM_BAD, "out of sequence"},    /* record 2 first */
        {1, "5", NULL, r1.b, JOURNAL_REC_HDR - 1, CL_ASM_BAD, "torn record header"},
        {1, "5", NULL, r1.b, 0, CL_ASM_BAD, "torn record header"},
        {1, "5", NULL, r1.b, r1.n, CL_ASM_RECORD, NULL},              /* the good one */
        {1, "5", NULL, r1.b, r1.n, CL_ASM_BAD, "out of order"},       /* delivered twice */
        {2, "4", NULL, r2.b, r2.n, CL_ASM_BAD, "fenced writer"},       /* an older lease */
        {2, "5", "1/2", r2.b, 30, CL_ASM_PART, NULL},
        {3, "5", "1/2", r2.b + 30, r2.n - 30, CL_ASM_BAD, "part 1 of 2 where part 2"},
        {3, "5", "2/3", r2.b + 30, r2.n - 30, CL_ASM_BAD, "part 2 of 3 where part 2 of 2"},
        {3, "5", NULL, r2.b + 30, r2.n - 30, CL_ASM_BAD, "where part 2"},
        {3, "6", "2/2", r2.b + 30, r2.n - 30, CL_ASM_RECORD, NULL},
    };
    for (size_t i = 0; i < sizeof rows / sizeof rows[0]; i++) {
        uint64_t applied = a.applied, recs = a.recs;
        why[0] = 0;
        int k = cl_asm_take(&a, rows[i].seq, rows[i].lease, rows[i].part, rows[i].d, rows[i].n, &r, &rn, why,
                            sizeof why);
        if (k != rows[i].want) fail_msg("row %zu: %d, wanted %d (%s)", i, k, rows[i].want, why);
        if (rows[i].says && !strstr(why, rows[i].says)) fail_msg("row %zu says \"%s\", wanted \"%s\"", i, why, rows[i].says);
        if (k == CL_ASM_BAD || k == CL_ASM_GAP) {
            assert_int_equal(a.applied, applied); /* nothing taken */
            assert_int_equal(a.recs, recs);
        }
    }
    assert_int_equal(a.recs, 2);
    assert_memory_equal(r, r2.b, r2.n);
    /* trailing bytes after a whole record: refused */
    uint8_t *longer = malloc(r1.n + 3);
    assert_non_null(longer);
    cl_asm b = {0};
    memcpy(longer, r1.b, r1.n);
    assert_int_equal(cl_asm_take(&b, 1, "1", "1/2", longer, 20, &r, &rn, why, sizeof why), CL_ASM_PART);
    assert_int_equal(cl_asm_take(&b, 2, "1", "2/2", longer + 20, r1.n + 3 - 20, &r, &rn, why, sizeof why), CL_ASM_BAD);
    assert_non_null(strstr(why, "bytes after the record"));
    free(longer);
    cl_asm_free(&a);
    cl_asm_free(&b);
    free(r1.b);
    free(r2.b);
}

/* A good stream with one byte of one message flipped (data or headers,
 * seeded): refused with a reason, or (a flip in a lease to a larger
 * number) taken with every record still the original; never a crash, and
 * never a record that is not one of the originals. */
static void test_cluster_rec_flips(void **state)
{
    (void)state;
    uint64_t seed = 0xf11b;
    rec rs[12];
    for (size_t i = 0; i < 12; i++) rs[i] = make_rec(i + 1, (uint32_t)(splitmix64(&seed) % 200), &seed);
    msg ms[4000];
    size_t nm = cut_stream(rs, 12, 64, ms, 4000);
    uint8_t *copy = malloc(4096);
    assert_non_null(copy);
    for (int round = 0; round < 3000; round++) {
        size_t at = (size_t)(splitmix64(&seed) % nm);
        int what = (int)(splitmix64(&seed) % 3);
        cl_asm a = {0};
        size_t got = 0;
        bool refused = false;
        for (size_t i = 0; i < nm && !refused; i++) {
            msg m = ms[i];
            if (i == at) {
                uint64_t x = splitmix64(&seed);
                if (what == 0 && m.n) {
                    memcpy(copy, m.d, m.n);
                    copy[x % m.n] ^= (uint8_t)(1u << (x >> 8) % 8);
                    m.d = copy;
                } else if (what == 1) {
                    m.lease[x % strlen(m.lease)] ^= (char)(1u << (x >> 8) % 7);
                } else if (m.has_part) {
                    m.part[x % strlen(m.part)] ^= (char)(1u << (x >> 8) % 7);
                } else {
                    m.seq += 1 + x % 3;
                }
            }
            const uint8_t *r;
            size_t rn;
            char why[300] = "";
            int k = take(&a, &m, &r, &rn, why);
            if (k == CL_ASM_BAD || k == CL_ASM_GAP) {
                assert_true(k == CL_ASM_GAP || why[0]);
                refused = true;
            } else if (k == CL_ASM_RECORD) {
                assert_true(got < 12);
                assert_int_equal(rn, rs[got].n);
                assert_memory_equal(r, rs[got].b, rn); /* a flipped byte never gets through its CRC */
                got++;
            }
        }
        cl_asm_free(&a);
    }
    free(copy);
    for (size_t i = 0; i < 12; i++) free(rs[i].b);
}

const struct CMUnitTest cluster_rec_tests[] = {
    cmocka_unit_test(test_cluster_rec_roundtrip),
    cmocka_unit_test(test_cluster_rec_refusals),
    cmocka_unit_test(test_cluster_rec_flips),
};
const size_t cluster_rec_tests_count = sizeof cluster_rec_tests / sizeof cluster_rec_tests[0];
