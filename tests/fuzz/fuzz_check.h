/*
 * fuzz_check.h — what every fuzz target shares: the entry point's
 * prototype and CHECK, which reports a broken property with the target's
 * name (FUZZ_NAME, defined before this include) and calls abort(), so the
 * fuzzer and the replay driver (replay_main.c) report it like a sanitizer
 * crash. Targets that encode protocol messages (protocol.h included
 * first) also get a writer over an exact heap buffer.
 */
#ifndef VANTAGE_FUZZ_CHECK_H
#define VANTAGE_FUZZ_CHECK_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

#define CHECK(cond)                                                                                        \
    do {                                                                                                   \
        if (!(cond)) {                                                                                     \
            fprintf(stderr, "%s: property failed at %s:%d: %s\n", FUZZ_NAME, __FILE__, __LINE__, #cond);   \
            abort();                                                                                       \
        }                                                                                                  \
    } while (0)

#ifdef VANTAGE_PROTOCOL_H
/* A writer over a heap buffer of exactly cap bytes: an overrun is ASan's,
 * a short one ours. */
typedef struct fuzz_wbuf {
    uint8_t *mem;
    vp_writer w;
} fuzz_wbuf;

static inline void fuzz_wopen(fuzz_wbuf *b, size_t cap)
{
    b->mem = malloc(cap ? cap : 1);
    CHECK(b->mem != NULL);
    vp_writer_init(&b->w, b->mem, cap);
}

/* The payload of the one frame written, which must be of the type wanted
 * and fill what was written; its length in *len. */
static inline const uint8_t *fuzz_wframe(fuzz_wbuf *b, uint16_t type, size_t *len)
{
    vp_header h;
    size_t fs = 0;
    CHECK(!b->w.overflow);
    CHECK(vp_frame_check(b->mem, b->w.len, UINT32_MAX, &h, &fs) == VP_OK);
    CHECK(fs == b->w.len && h.type == type);
    *len = h.len;
    return b->mem + VP_HEADER_SIZE;
}

static inline void fuzz_wclose(fuzz_wbuf *b) { free(b->mem); }

/* Two entity records, field for field, their numbers compared by eq. */
static inline bool fuzz_same_entity(const vp_entity *a, const vp_entity *b, bool (*eq)(double, double))
{
    if (a->id != b->id || a->handle != b->handle || a->class_id != b->class_id || a->sublevel != b->sublevel ||
        a->flags != b->flags || a->material != b->material)
        return false;
    for (int k = 0; k < 3; k++)
        if (!eq(a->pos[k], b->pos[k]) || !eq(a->scale[k], b->scale[k])) return false;
    for (int k = 0; k < 4; k++)
        if (!eq(a->rot[k], b->rot[k])) return false;
    for (int k = 0; k < 4; k++)
        if (!eq(a->sphere[k], b->sphere[k])) return false;
    for (int k = 0; k < 6; k++)
        if (!eq(a->aabb[k], b->aabb[k])) return false;
    return true;
}
#endif

#endif
