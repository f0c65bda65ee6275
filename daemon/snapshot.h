/*
 * snapshot.h — the scene written whole, and read back exactly: what the
 * journal starts from after compaction (journal.h).
 *
 * "Exactly" means the restored scene answers and behaves as the saved one
 * would: entity handles (the culling world's slot generations and its free
 * list order, so the next handle handed out is the same), sub-level member
 * lists in order (an unload frees in that order), unloads in progress, mesh
 * class reservations, destruction volumes sample for sample, the epoch.
 *
 * A file: a 40-byte header (magic "VNTSNAP3", u64 generation, u64 sequence
 * number of the first journal record after it, u64 body length, u32 CRC-32
 * of the body, u32 CRC-32 of the 36 header bytes before), then the body
 * (snapshot.c). Formats 1 and 2 ("VNTSNAP1", "VNTSNAP2": protocol version
 * 1's scene) are still read; a start on one upgrades the directory
 * (journal.h).
 */
#ifndef VANTAGE_SNAPSHOT_H
#define VANTAGE_SNAPSHOT_H

#include "scene.h"

#include <stddef.h>
#include <stdint.h>

#define SNAPSHOT_FORMAT 3u /* the format written */

/* Writes sc to fd (positioned at 0). 0, or -errno. */
int snapshot_write(int fd, const scene *sc, uint64_t gen, uint64_t seq);
/* The format of the snapshot p[0..n) by its magic: 1..SNAPSHOT_FORMAT, 0
 * if it is not one. */
unsigned snapshot_format(const uint8_t *p, size_t n);
/* Restores p[0..n) into sc (empty, initialised); *seq = the first journal
 * record to replay after it. 0, or -1 with err saying what is wrong. */
int snapshot_load(const uint8_t *p, size_t n, scene *sc, uint64_t gen, uint64_t *seq, char *err, size_t errlen);

#endif
