/*
 * vp_internal.h — what the protocol's two source files share: short names
 * for vp_bytes.h's little-endian loads and stores, and the checks every
 * decoder uses.
 */
#ifndef VANTAGE_VP_INTERNAL_H
#define VANTAGE_VP_INTERNAL_H

#include "protocol.h"

#include <string.h>

/* The protocol's short names for vp_bytes.h's loads and stores (fields at
 * fixed offsets in a record already bounds-checked as a whole). */
#define rd16 vp_ld_u16
#define rd32 vp_ld_u32
#define rd64 vp_ld_u64
#define rdf32 vp_ld_f32
#define rdf64 vp_ld_f64
#define wr16 vp_st_u16
#define wr32 vp_st_u32
#define wr64 vp_st_u64

/* A counted array of n records of size rec: the count is checked against
 * the limit (0 = none) and the bytes left before the records are taken. */
int vp_take_array(vp_reader *r, uint32_t n, size_t rec, uint32_t max, const uint8_t **out);
/* The same for records that end the payload: bytes left after them are a
 * count that disagrees (VP_ERR_COUNT); a read already short is TRUNCATED. */
int vp_take_rest(vp_reader *r, uint32_t n, size_t rec, uint32_t max, const uint8_t **out);
/* A vector whose length is within this of 1 is unit to float precision
 * and is kept as sent, not renormalised: renormalising leaves |n - 1| <=
 * 2^-24 (each component rounded once), so a value renormalised on the way
 * in passes unchanged the next time (a listed entity sent back, a journal
 * replayed), where renormalising it again would move 1.4 % of them by an
 * ulp (tests/test_protocol.c, test_renormalised). */
#define VP_UNIT_EXACT 0x1p-22
/* A counted batch's frame: u32 n, then put(w, recs + i * stride) for
 * each of the n records (the encoders of LIGHT_PUT, MATERIAL_PUT,
 * TRANSFORM_SET). */
void vp_enc_batch(vp_writer *w, uint16_t type, uint32_t req, const void *recs, size_t stride, uint32_t n,
                  void (*put)(vp_writer *w, const void *rec));
bool vp_finite_n(const double *v, int n);
bool vp_finite_nf(const float *v, int n);

#endif
