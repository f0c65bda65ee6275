/*
 * cluster_rec.h — a replica's stream messages made records again
 * (cluster.c), kept free of NATS so the tests can feed it any bytes
 * (tests/test_cluster_rec.c).
 *
 * A message is a record in the journal's format (journal.h), or one part
 * of one (header Vantage-Part "i/n"), and carries the lease revision it
 * was written under (Vantage-Lease). Messages must come in stream order,
 * each the one after the last; leases never go back; parts come in order,
 * all of the same count; the record put together must be whole, carry the
 * next record number and its CRC, and end where its length says.
 */
#ifndef VANTAGE_CLUSTER_REC_H
#define VANTAGE_CLUSTER_REC_H

#include <stddef.h>
#include <stdint.h>

typedef struct cl_asm {
    uint64_t applied;   /* the stream sequence of the last message taken */
    uint64_t recs;      /* the last record's number */
    uint64_t max_lease; /* the highest lease revision taken */
    uint8_t *buf;       /* the parts of a record so far */
    size_t len, cap;
    uint32_t got, parts;
} cl_asm;

enum { CL_ASM_BAD = -1, CL_ASM_GAP = -2, CL_ASM_PART = 0, CL_ASM_RECORD = 1 };

/* Takes message seq (lease, part: its headers' values, part NULL when it
 * has none; d[0..n): its data). CL_ASM_RECORD: *rec, *rlen is a whole,
 * checked record (valid until the next call), numbered recs (already
 * counted); CL_ASM_PART: a part kept; CL_ASM_GAP: seq is past the next one
 * (the stream was trimmed past this daemon), nothing taken; CL_ASM_BAD: why
 * says what is wrong, nothing taken. */
int cl_asm_take(cl_asm *a, uint64_t seq, const char *lease, const char *part, const uint8_t *d, size_t n,
                const uint8_t **rec, size_t *rlen, char *why, size_t whylen);
/* Empties a: a scene made anew starts from applied, recs, max_lease. */
void cl_asm_reset(cl_asm *a, uint64_t applied, uint64_t recs, uint64_t max_lease);
void cl_asm_free(cl_asm *a);

#endif
