/*
 * journal_rec.c — one journal record (journal.h): its header written, a
 * record checked and applied. The journal files (journal.c) and the
 * cluster's stream (cluster.c) hold the same records.
 */
#include "journal.h"
#include "vp_bytes.h"

#include <stdio.h>
#include <zlib.h>

uint32_t journal_crc(const uint8_t *a, size_t na, const uint8_t *b, size_t nb)
{
    uLong c = crc32(0L, Z_NULL, 0);
    c = crc32(c, a, (uInt)na);
    while (nb) { /* zlib takes uInt lengths */
        uInt n = nb > (1u << 30) ? (1u << 30) : (uInt)nb;
        c = crc32(c, b, n);
        b += n;
        nb -= n;
    }
    return (uint32_t)c;
}

void journal_rec_header(uint8_t h[JOURNAL_REC_HDR], uint64_t seq, uint16_t type, uint16_t load, uint32_t aux,
                        const uint8_t *p, uint32_t len)
{
    vp_writer hw;
    vp_writer_init(&hw, h, JOURNAL_REC_HDR);
    vp_put_u32(&hw, len);
    vp_put_u32(&hw, 0); /* the CRC, of what follows it: patched below */
    vp_put_u64(&hw, seq);
    vp_put_u16(&hw, type);
    vp_put_u16(&hw, load);
    vp_put_u32(&hw, aux);
    vp_st_u32(h + 4, journal_crc(h + 8, 16, p, len));
}

const char *journal_rec_check(const uint8_t *r, size_t left, uint64_t seq)
{
    uint32_t len = left >= JOURNAL_REC_HDR ? vp_ld_u32(r) : 0;
    if (left < JOURNAL_REC_HDR) return "a torn record header";
    if (len > JOURNAL_REC_MAX) return "a record length no record has";
    if (left - JOURNAL_REC_HDR < len) return "a torn record (shorter than its length)";
    if (vp_ld_u32(r + 4) != journal_crc(r + 8, 16, r + JOURNAL_REC_HDR, len)) return "a record CRC mismatch";
    if (vp_ld_u64(r + 8) != seq) return "a record out of sequence";
    return NULL;
}

int journal_rec_apply(scene *sc, const uint8_t *r, unsigned format, scene_err *se)
{
    edit e;
    edit_result res;
    uint16_t type = vp_ld_u16(r + 16);
    int rc = edit_decode(type, r + JOURNAL_REC_HDR, vp_ld_u32(r), 0, format == 1 ? EDIT_LAYOUT_V1 : EDIT_LAYOUT, &e);
    if (!rc) {
        e.sublevel = vp_ld_u16(r + 18);
        e.aux = vp_ld_u32(r + 20);
        rc = edit_apply(sc, &e, &res, se);
        if (!rc) edit_result_free(&res);
    } else {
        snprintf(se->msg, sizeof se->msg, "%s", vp_strerror(rc));
    }
    return rc;
}

