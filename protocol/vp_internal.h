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
bool vp_finite_n(const double *v, int n);
bool vp_finite_nf(const float *v, int n);

#endif
