/*
 * journal.h — vantaged's persistence (--data-dir): an append-only journal
 * of the edits the daemon applied, in the manner of Redis's AOF, plus
 * snapshots that let it start over short (journal.c, snapshot.c).
 *
 * Every edit is written (write(2), whole or not at all) before it is
 * applied; if the write fails the edit is refused and the scene is
 * untouched, and an edit the scene rejects is cut back off the file. When
 * the record reaches the disk depends on the policy:
 *   always    the loop syncs (fdatasync) once per turn, before any reply of
 *             that turn leaves (every reply, not only the edits' answers:
 *             no one sees an edit before it is on disk): group commit, an
 *             ACK means on disk;
 *   everysec  a thread syncs once a second: a crash of the machine loses
 *             at most about a second of edits, a crash of the daemon none;
 *   off       the kernel writes back when it likes (a daemon crash loses
 *             nothing, a machine crash what the page cache held).
 *
 * Files in the directory: journal.<gen> (records since snapshot.<gen>),
 * snapshot.<gen> (the scene as of the start of journal.<gen>), LOCK. On
 * open the newest complete snapshot is loaded and every journal from its
 * generation on is replayed through edit_apply. A torn end of the last
 * journal (a record that is incomplete or fails its CRC, with no intact
 * record anywhere after it) is cut off (the bytes are kept in
 * journal.<gen>.cut-<offset>) and reported; any other damage (a damaged
 * record with an intact one after it, a bad header, a damaged snapshot)
 * stops the daemon with the file and offset named (journal.c, replay_file).
 *
 * Formats: journals are format 2 ("VNTJRNL2"), snapshots format 3
 * (snapshot.h). A directory an older daemon wrote (a format 1 journal,
 * protocol version 1's payloads; a snapshot of format 1 or 2) is read and
 * upgraded on open: a snapshot of the restored scene in the current format
 * and a new journal after it (journal.c, upgrade()).
 */
#ifndef VANTAGE_JOURNAL_H
#define VANTAGE_JOURNAL_H

#include "edit.h"
#include "scene.h"

#include <stdbool.h>
#include <stdint.h>

enum { JOURNAL_OFF, JOURNAL_EVERYSEC, JOURNAL_ALWAYS };

typedef struct journal journal;

typedef struct journal_report {
    uint64_t ms;            /* recovery, wall time */
    uint64_t snapshot_gen;  /* 0: none loaded */
    uint64_t snapshot_bytes;
    uint64_t records;       /* journal records replayed */
    uint64_t bytes;         /* journal bytes replayed */
    uint64_t cut_bytes;     /* cut off a damaged tail (0: none) */
    char cut[700];          /* what was cut, where, why, and where it is kept */
    uint32_t loads_dropped; /* sub-level loads left open by the crash, dropped */
    bool fresh;             /* the directory held no scene */
    uint64_t upgrade_gen;   /* an older daemon's directory was upgraded: the generation
                               written in the current formats (0: none, or its snapshot
                               failed: then edits go to a new journal all the same) */
} journal_report;

/* Opens (creating) dir with the policy, takes its lock, and restores sc
 * (empty on entry) from it. 0, or -1 with err naming the file and why. */
int journal_open(const char *dir, int policy, scene *sc, journal **out, journal_report *rep, char *err,
                 size_t errlen);
/* Waits for a snapshot in flight, syncs and closes (NULL: nothing). 0, or
 * -errno when the final sync failed. */
int journal_close(journal *j);

/* Applies e to sc, journaled first when j is not NULL (p, len: the
 * request's payload). A journal that cannot take it refuses it (VP_ERR_IO,
 * err says why) and nothing changes; an edit the scene refuses is cut back
 * off the journal. The one way an edit reaches the scene (handlers.c,
 * vantaged.c, recovery's own drops). */
int journal_apply(journal *j, scene *sc, const edit *e, const uint8_t *p, uint32_t len, edit_result *r,
                  scene_err *err);
/* Records written since the last sync (the always policy syncs them). */
bool journal_dirty(const journal *j);
/* Syncs now: 0, or -errno. A failed sync is final: the journal turns
 * read-only, the records since the last good sync are cut back off the
 * file (best effort), and journal_sync_error says why; the daemon must
 * then stop rather than serve a scene the disk may not hold (server.c).
 * The everysec thread's failed sync ends the process itself. */
int journal_sync(journal *j);
/* errno of a failed sync of the journal (the loop's, a snapshot's), 0 = none. */
int journal_sync_error(const journal *j);
/* Non-NULL while the journal takes no more edits: why. */
const char *journal_broken(const journal *j);
/* Marks it read-only (a change could not be journaled and was applied). */
void journal_break(journal *j, const char *why);
int journal_policy(const journal *j);
/* Compaction: true when the journal has grown past its limit and no
 * snapshot is being written (the loop then calls journal_snapshot). */
bool journal_wants_snapshot(const journal *j);
/* Starts a snapshot of sc (a forked child writes it; the journal moves on
 * to a new generation now). 0, or -errno. */
int journal_snapshot(journal *j, const scene *sc);
/* The loop polls the child: finishes a snapshot that completed. */
void journal_poll(journal *j);
/* Snapshot threshold in bytes of journal (tests lower it). */
void journal_set_limit(journal *j, uint64_t bytes);

/* One record, as the journal files hold it and the cluster's stream
 * carries it (cluster.c): a 24-byte header (payload length, CRC-32 of
 * what follows the CRC, sequence number, type, sub-level, aux) and the
 * request's payload. */
#define JOURNAL_REC_HDR 24u
#define JOURNAL_REC_MAX (1u << 30) /* no payload is this big: a bad length */
/* CRC-32 of a[0..na) then b[0..nb) (zlib's): records and file headers. */
uint32_t journal_crc(const uint8_t *a, size_t na, const uint8_t *b, size_t nb);
void journal_rec_header(uint8_t h[JOURNAL_REC_HDR], uint64_t seq, uint16_t type, uint16_t load, uint32_t aux,
                        const uint8_t *p, uint32_t len);
/* Whether the left bytes at r begin with a whole, intact record numbered
 * seq: NULL, or why not. */
const char *journal_rec_check(const uint8_t *r, size_t left, uint64_t seq);
/* Applies a checked record (decoded in the payload layout of journal
 * format `format`, edit_apply): VP_OK, or the error with se saying why. */
int journal_rec_apply(scene *sc, const uint8_t *r, unsigned format, scene_err *se);

#endif
