/*
 * vp_internal.h — what the protocol's two source files share: byte-level
 * little-endian reads and writes, and the checks every decoder uses.
 */
#ifndef VANTAGE_VP_INTERNAL_H
#define VANTAGE_VP_INTERNAL_H

#include "protocol.h"

#include <string.h>

/* ---- little-endian primitives ------------------------------------------------ */

static inline uint16_t rd16(const uint8_t *p) { return (uint16_t)(p[0] | p[1] << 8); }
static inline uint32_t rd32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}
static inline uint64_t rd64(const uint8_t *p) { return (uint64_t)rd32(p) | (uint64_t)rd32(p + 4) << 32; }
static inline float rdf32(const uint8_t *p)
{
    uint32_t u = rd32(p);
    float f;
    memcpy(&f, &u, sizeof f);
    return f;
}
static inline double rdf64(const uint8_t *p)
{
    uint64_t u = rd64(p);
    double d;
    memcpy(&d, &u, sizeof d);
    return d;
}
static inline void wr16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
}
static inline void wr32(uint8_t *p, uint32_t v)
{
    for (int i = 0; i < 4; i++) p[i] = (uint8_t)(v >> (8 * i));
}
static inline void wr64(uint8_t *p, uint64_t v)
{
    for (int i = 0; i < 8; i++) p[i] = (uint8_t)(v >> (8 * i));
}

/* Room for n more bytes in w, or NULL (and w->overflow). */
uint8_t *vp_reserve(vp_writer *w, size_t n);
/* A counted array of n records of size rec: the count is checked against
 * the limit (0 = none) and the bytes left before the records are taken. */
int vp_take_array(vp_reader *r, uint32_t n, size_t rec, uint32_t max, const uint8_t **out);
/* The same for records that end the payload: bytes left after them are a
 * count that disagrees (VP_ERR_COUNT); a read already short is TRUNCATED. */
int vp_take_rest(vp_reader *r, uint32_t n, size_t rec, uint32_t max, const uint8_t **out);
bool vp_finite_n(const double *v, int n);
bool vp_finite_nf(const float *v, int n);

#endif
