/*
 * journal.c — the edit journal: records, the sync policies, recovery and
 * its tail check, compaction (see journal.h).
 *
 * A journal file: a 32-byte header (magic "VNTJRNL2", u64 generation, u64
 * sequence number of its first record, u32 reserved, u32 CRC-32 of the 28
 * bytes before), then records:
 *
 *   u32 len      payload bytes
 *   u32 crc      CRC-32 (zlib) of the 16 bytes from seq on, then the payload
 *   u64 seq      one more than the record before it
 *   u16 type     the request type (VP_*) or EDIT_*
 *   u16 load     the editing connection's open load
 *   u32 aux      edit.h
 *   len bytes    the request's payload as it came off the socket
 *
 * all little-endian (vp_bytes.h). A record is written with one writev; a
 * short write is cut back, so the file never ends inside a record the
 * daemon knows of.
 *
 * Format 1 ("VNTJRNL1", protocol version 1's daemons) is the same file
 * with version 1's payloads (edit.h, EDIT_LAYOUT_V1). It is replayed, never
 * appended to: a start whose current journal is format 1, or whose
 * snapshot is an older format, upgrades the directory (upgrade()).
 */
#include "journal.h"
#include "log.h"
#include "snapshot.h"
#include "vp_bytes.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <pthread.h>
#include <signal.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/mman.h>
#include <sys/prctl.h>
#include <sys/stat.h>
#include <sys/uio.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>
#include <zlib.h>

#define HDR_SIZE 32u
#define REC_HDR JOURNAL_REC_HDR
#define DEFAULT_LIMIT (64ull << 20)     /* a snapshot once the journal passes this... */

static const char MAGIC[8] = {'V', 'N', 'T', 'J', 'R', 'N', 'L', '2'};
static const char MAGIC_V1[8] = {'V', 'N', 'T', 'J', 'R', 'N', 'L', '1'}; /* version 1 payloads; read, not written */

struct journal {
    char *dir;
    int policy;
    int fd, lock_fd;
    uint64_t gen;           /* of the journal being written */
    uint64_t seq;           /* the next record's */
    uint64_t size;          /* bytes in the file */
    uint64_t synced;        /* of them known on disk (the last sync that succeeded) */
    uint64_t last_start;    /* where the last append began (journal_cancel) */
    uint64_t base_bytes;    /* the last snapshot's size: compaction waits for 2x it */
    uint64_t limit;
    bool each_turn;         /* VANTAGED_SNAPSHOT_EACH_TURN: a snapshot after every turn with records */
    bool dirty;
    char broken[300];
    /* everysec: a thread syncs the current file once a second */
    pthread_t syncer;
    bool syncer_on, stop;
    pthread_mutex_t mu;
    pthread_cond_t cv;
    atomic_int sync_err;    /* errno of a failed sync (the loop's, the thread's), 0 = none */
    /* a snapshot being written by a child */
    pid_t child;
    uint64_t child_gen;
};

static uint64_t mono_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000u + (uint64_t)ts.tv_nsec / 1000000u;
}

static char *path_of(const journal *j, const char *kind, uint64_t gen)
{
    char *p = NULL;
    if (asprintf(&p, "%s/%s.%06" PRIu64, j->dir, kind, gen) < 0) return NULL;
    return p;
}

/* Makes a new file's name (or a rename) durable. */
static int sync_dir(const char *dir)
{
    int fd = open(dir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (fd < 0) return -errno;
    int rc = fsync(fd) ? -errno : 0;
    close(fd);
    return rc;
}

/* ---- syncing ------------------------------------------------------------------------ */

/* fdatasync of the journal. A test's knob (as VANTAGED_SNAPSHOT_DELAY_MS):
 * VANTAGED_FAIL_SYNC=N makes the Nth sync of the journal (the loop's, the
 * thread's, a snapshot's) fail with EIO, as a disk that loses a write
 * would; there is no other way to make fdatasync fail without root. */
static atomic_long sync_calls, sync_fail_at; /* set by journal_open, before the syncer thread starts */

static int jsync(int fd)
{
    long at = atomic_load(&sync_fail_at);
    if (at > 0 && atomic_fetch_add(&sync_calls, 1) + 1 == at) {
        errno = EIO;
        return -1;
    }
    return fdatasync(fd);
}

/* ---- the everysec syncer ------------------------------------------------------------ */

static void *syncer_main(void *arg)
{
    journal *j = arg;
    pthread_mutex_lock(&j->mu);
    while (!j->stop) {
        struct timespec until;
        clock_gettime(CLOCK_REALTIME, &until);
        until.tv_sec += 1;
        pthread_cond_timedwait(&j->cv, &j->mu, &until);
        if (j->stop) break;
        /* a duplicate of the descriptor: the loop may move on to a new
           file meanwhile and close the old one */
        int fd = dup(j->fd);
        pthread_mutex_unlock(&j->mu);
        if (fd >= 0 && jsync(fd)) {
            /* what the kernel failed to write it may have dropped (and
               marked clean): retrying could "succeed" over lost pages, and
               the edits are acknowledged and served. Like PostgreSQL's
               PANIC, stop now; the restart replays what the disk holds
               (a torn end cut, a hole refused with its offset) */
            int e = errno ? errno : EIO;
            LOGE("journal: the background sync failed (%s): the journal on disk is in an unknown state; exiting. "
                 "Restart to recover what %s holds",
                 strerror(e), j->dir);
            _exit(1);
        }
        if (fd >= 0) close(fd);
        pthread_mutex_lock(&j->mu);
    }
    pthread_mutex_unlock(&j->mu);
    return NULL;
}

/* ---- writing -------------------------------------------------------------------------- */

/* Creates journal.<gen> (first record seq) with its header, synced, and makes
 * it the one written. The header goes to journal.tmp.<gen> first, which is
 * renamed into place once synced: a crash at any point leaves either no
 * journal.<gen> or one whose header is whole (recovery removes the tmp). */
static int start_file(journal *j, uint64_t gen, uint64_t seq)
{
    char *p = path_of(j, "journal", gen), *tmp = path_of(j, "journal.tmp", gen);
    if (!p || !tmp) {
        free(p);
        free(tmp);
        return -ENOMEM;
    }
    int fd = open(tmp, O_WRONLY | O_CREAT | O_TRUNC | O_APPEND | O_CLOEXEC, 0600);
    int rc = fd < 0 ? -errno : 0;
    if (!rc) {
        uint8_t h[HDR_SIZE] = {0};
        memcpy(h, MAGIC, 8);
        vp_st_u64(h + 8, gen);
        vp_st_u64(h + 16, seq);
        vp_st_u32(h + 28, journal_crc(h, 28, NULL, 0));
        errno = 0;
        if (write(fd, h, HDR_SIZE) != (ssize_t)HDR_SIZE || fdatasync(fd)) rc = errno ? -errno : -EIO;
    }
    if (!rc && rename(tmp, p)) rc = -errno;
    if (!rc) rc = sync_dir(j->dir);
    if (rc) {
        if (fd >= 0) close(fd);
        unlink(tmp);
        free(tmp);
        free(p);
        return rc;
    }
    free(tmp);
    free(p);
    pthread_mutex_lock(&j->mu);
    int old = j->fd;
    j->fd = fd;
    pthread_mutex_unlock(&j->mu);
    if (old >= 0) close(old);
    j->gen = gen;
    j->seq = seq;
    j->size = j->last_start = j->synced = HDR_SIZE;
    j->dirty = false;
    return 0;
}

/* Appends an edit; 0, or -errno (nothing of it is left in the file). */
static int journal_append(journal *j, uint16_t type, uint16_t load, uint32_t aux, const uint8_t *p, uint32_t len)
{
    if (j->broken[0]) return -EROFS;
    uint8_t h[REC_HDR];
    journal_rec_header(h, j->seq, type, load, aux, p, len);
    struct iovec iov[2] = {{h, REC_HDR}, {(void *)p, len}};
    size_t want = REC_HDR + (size_t)len, done = 0;
    int rc = 0;
    while (done < want) {
        /* the rare short write: go on from where it stopped */
        struct iovec v[2];
        int n = 0;
        size_t skip = done;
        for (int i = 0; i < 2; i++) {
            if (skip >= iov[i].iov_len) {
                skip -= iov[i].iov_len;
                continue;
            }
            v[n].iov_base = (uint8_t *)iov[i].iov_base + skip;
            v[n++].iov_len = iov[i].iov_len - skip;
            skip = 0;
        }
        ssize_t w = writev(j->fd, v, n);
        if (w > 0) {
            done += (size_t)w;
        } else if (w < 0 && errno == EINTR) {
            continue;
        } else {
            rc = w < 0 ? -errno : -ENOSPC;
            break;
        }
    }
    if (rc) {
        /* nothing of it may stay: a later record would follow garbage */
        if (done && ftruncate(j->fd, (off_t)j->size)) {
            char why[200];
            snprintf(why, sizeof why, "a failed write could not be cut back: %s", strerror(errno));
            journal_break(j, why);
        }
        return rc;
    }
    j->last_start = j->size;
    j->size += want;
    j->seq++;
    j->dirty = true;
    return 0;
}

/* Takes the last append back (the scene rejected the edit). */
static void journal_cancel(journal *j)
{
    if (ftruncate(j->fd, (off_t)j->last_start)) {
        char why[200];
        snprintf(why, sizeof why, "a refused edit could not be cut back off the journal: %s", strerror(errno));
        journal_break(j, why);
        return;
    }
    j->size = j->last_start;
    j->seq--;
}

int journal_apply(journal *j, scene *sc, const edit *e, const uint8_t *p, uint32_t len, edit_result *r,
                  scene_err *err)
{
    if (j) {
        if (j->broken[0])
            return scene_fail(err, VP_ERR_IO, UINT32_MAX, "the daemon is read-only: %.120s", j->broken);
        int jrc = journal_append(j, e->type, e->sublevel, e->aux, p, len);
        if (jrc)
            return scene_fail(err, VP_ERR_IO, UINT32_MAX,
                              "the edit could not be journaled (%s): refused, nothing changed", strerror(-jrc));
    }
    int rc = edit_apply(sc, e, r, err);
    if (rc && j) journal_cancel(j);
    return rc;
}

bool journal_dirty(const journal *j)
{
    return j->dirty;
}

int journal_sync(journal *j)
{
    if (!j->dirty) return 0;
    if (jsync(j->fd)) {
        int e = errno ? errno : EIO;
        /* the records since the last good sync were answered to no one
           and seen by no one (the loop holds every reply while the
           journal is dirty): they are taken back off the file, best
           effort, so that the restart does not find them either */
        bool cut = !ftruncate(j->fd, (off_t)j->synced) && !fdatasync(j->fd);
        if (cut) j->size = j->last_start = j->synced;
        char why[240];
        snprintf(why, sizeof why, "the journal could not be synced (%s); its unsynced records %s", strerror(e),
                 cut ? "were cut back off it" : "may or may not be on disk");
        snprintf(j->broken, sizeof j->broken, "%s", why); /* the loop exits on it: no "reads go on" log */
        atomic_store(&j->sync_err, e);
        return -e;
    }
    j->dirty = false;
    j->synced = j->size;
    return 0;
}

int journal_sync_error(const journal *j)
{
    return atomic_load(&((journal *)(uintptr_t)j)->sync_err);
}

const char *journal_broken(const journal *j)
{
    return j->broken[0] ? j->broken : NULL;
}

void journal_break(journal *j, const char *why)
{
    if (j->broken[0]) return;
    snprintf(j->broken, sizeof j->broken, "%s", why);
    LOGE("%s: edits are refused from now on (reads go on); restart the daemon to recover from %s", why, j->dir);
}

int journal_policy(const journal *j)
{
    return j->policy;
}

void journal_set_limit(journal *j, uint64_t bytes)
{
    j->limit = bytes;
}

/* ---- compaction ------------------------------------------------------------------------ */

bool journal_wants_snapshot(const journal *j)
{
    uint64_t need = j->limit > 2 * j->base_bytes ? j->limit : 2 * j->base_bytes;
    if (j->each_turn) need = HDR_SIZE;
    return !j->child && !j->broken[0] && j->size > need;
}

/* Writes snapshot.tmp.<gen> (path tmp) of sc, synced: 0, or -errno. */
static int write_tmp(const char *tmp, const scene *sc, uint64_t gen, uint64_t seq)
{
    int fd = open(tmp, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
    if (fd < 0) return -errno;
    int rc = snapshot_write(fd, sc, gen, seq);
    if (!rc && fdatasync(fd)) rc = -errno;
    close(fd);
    return rc;
}

int journal_snapshot(journal *j, const scene *sc)
{
    if (j->child) return -EBUSY;
    /* what the child writes is the scene as of now, which is the journal
       up to here: later records go to the next generation's file */
    if (jsync(j->fd)) {
        int e = errno ? errno : EIO;
        char why[200];
        snprintf(why, sizeof why, "the journal could not be synced before a snapshot: %s", strerror(e));
        snprintf(j->broken, sizeof j->broken, "%s", why); /* the loop exits on it (journal_sync_error) */
        atomic_store(&j->sync_err, e);
        return -e;
    }
    j->dirty = false;
    j->synced = j->size;
    uint64_t gen = j->gen + 1;
    int rc = start_file(j, gen, j->seq);
    if (rc) return rc;
    char *tmp = path_of(j, "snapshot.tmp", gen);
    if (!tmp) return -ENOMEM;
    /* a test's knob (as Redis has rdb-key-save-delay): the child waits this
       long first, so a test can see a snapshot that ends while the loop is
       idle put in place all the same */
    const char *delay = getenv("VANTAGED_SNAPSHOT_DELAY_MS");
    unsigned long delay_ms = delay ? strtoul(delay, NULL, 10) : 0;
    if (delay_ms > 60000) delay_ms = 60000;
    pid_t parent = getpid();
    pid_t pid = fork();
    if (pid < 0) {
        rc = -errno;
        free(tmp);
        return rc;
    }
    if (pid == 0) {
        /* the child: a copy-on-write image of the scene, one thread. It
           dies with the daemon (only the daemon puts a snapshot in place,
           and a restarted one must not meet an orphan still writing), and
           holds none of its descriptors: the listening sockets (a restart
           could not bind its port) and the clients' sockets (a client the
           daemon drops, or a daemon killed, would not be seen to hang up
           until the child ended) */
        prctl(PR_SET_PDEATHSIG, SIGKILL);
        if (getppid() != parent) _exit(1);
        if (close_range(3, ~0u, 0))
            for (long fd = 3, most = sysconf(_SC_OPEN_MAX); fd < most; fd++) close((int)fd);
        if (delay_ms) usleep((useconds_t)(delay_ms * 1000));
        _exit(write_tmp(tmp, sc, gen, j->seq) ? 1 : 0);
    }
    free(tmp);
    j->child = pid;
    j->child_gen = gen;
    LOGI("snapshot %06" PRIu64 " started (child %d); journal %06" PRIu64 " from here", gen, (int)pid, gen);
    return 0;
}

/* Whether name is "<kind>.<generation>" (and nothing more): the kind, g. */
static bool gen_name(const char *name, char kind[16], uint64_t *g)
{
    int end = 0;
    return sscanf(name, "%15[a-z].%" SCNu64 "%n", kind, g, &end) == 2 && !name[end];
}

/* Removes the files of generations before gen. */
static void drop_before(journal *j, uint64_t gen)
{
    DIR *d = opendir(j->dir);
    if (!d) return;
    struct dirent *e;
    while ((e = readdir(d))) {
        uint64_t g;
        char kind[16];
        if (!gen_name(e->d_name, kind, &g) || (strcmp(kind, "journal") && strcmp(kind, "snapshot")) || g >= gen)
            continue;
        char *p = NULL;
        if (asprintf(&p, "%s/%s", j->dir, e->d_name) >= 0) {
            unlink(p);
            free(p);
        }
    }
    closedir(d);
}

/* snapshot.tmp.<gen>, written whole (ok), is renamed into place and what it
 * makes redundant removed (the files of older generations); else, or if
 * that fails, it is dropped and the journals stay (recovery replays across
 * generations). Whether it is in place. */
static bool put_in_place(journal *j, uint64_t gen, bool ok)
{
    char *tmp = path_of(j, "snapshot.tmp", gen), *dst = path_of(j, "snapshot", gen);
    struct stat st;
    if (!tmp || !dst || (ok && (rename(tmp, dst) || sync_dir(j->dir) || stat(dst, &st)))) ok = false;
    if (ok) {
        j->base_bytes = (uint64_t)st.st_size;
        drop_before(j, gen);
        LOGI("snapshot %06" PRIu64 " written: %.1f MB; older journals removed", gen, (double)st.st_size / 1e6);
    } else if (tmp) {
        unlink(tmp);
    }
    free(tmp);
    free(dst);
    return ok;
}

/* The child is done (status from waitpid; r its return): the snapshot is
 * put in place and what it makes redundant removed, or it is dropped. */
static void child_done(journal *j, pid_t r, int status)
{
    uint64_t gen = j->child_gen;
    j->child = 0;
    bool ok = r > 0 && WIFEXITED(status) && WEXITSTATUS(status) == 0;
    if (!put_in_place(j, gen, ok)) {
        LOGW("snapshot %06" PRIu64 " failed; the journals are kept and it is tried again later", gen);
        j->base_bytes = j->size; /* not again at once */
    }
}

void journal_poll(journal *j)
{
    if (!j->child) return;
    int status = 0;
    pid_t r = waitpid(j->child, &status, WNOHANG);
    if (r != 0) child_done(j, r, status);
}

/* ---- recovery -------------------------------------------------------------------------- */

typedef struct gens {
    uint64_t *v;
    size_t n, cap;
} gens;

static int cmp_gen(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return (x > y) - (x < y);
}

/* The generations of `kind` files in dir, ascending. */
static int list_gens(const char *dir, const char *kind, gens *out)
{
    DIR *d = opendir(dir);
    if (!d) return -errno;
    struct dirent *e;
    while ((e = readdir(d))) {
        uint64_t g;
        char k[16];
        if (!gen_name(e->d_name, k, &g) || strcmp(k, kind)) continue;
        if (!vp_grow((void **)&out->v, &out->cap, out->n + 1, sizeof *out->v)) {
            closedir(d);
            return -ENOMEM;
        }
        out->v[out->n++] = g;
    }
    closedir(d);
    if (out->n) qsort(out->v, out->n, sizeof *out->v, cmp_gen);
    return 0;
}

/* A file read whole (mapped). */
typedef struct mapped {
    const uint8_t *p;
    size_t n;
} mapped;

static int map_file(const char *path, mapped *m)
{
    m->p = NULL;
    m->n = 0;
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0) return -errno;
    struct stat st;
    int rc = fstat(fd, &st) ? -errno : 0;
    if (!rc && st.st_size > 0) {
        void *p = mmap(NULL, (size_t)st.st_size, PROT_READ, MAP_PRIVATE, fd, 0);
        if (p == MAP_FAILED) rc = -errno;
        else {
            m->p = p;
            m->n = (size_t)st.st_size;
            madvise(p, m->n, MADV_SEQUENTIAL);
        }
    }
    close(fd);
    return rc;
}

static void unmap_file(mapped *m)
{
    if (m->p) munmap((void *)m->p, m->n);
    m->p = NULL;
}

/* Keeps bytes [off, n) of path in path.cut-<off> and cuts the file there. */
static int cut_tail(const char *path, const mapped *m, size_t off, char *kept, size_t keptlen)
{
    char *cp = NULL;
    if (asprintf(&cp, "%s.cut-%zu", path, off) < 0) return -ENOMEM;
    int fd = open(cp, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
    int rc = fd < 0 ? -errno : 0;
    if (!rc && write(fd, m->p + off, m->n - off) != (ssize_t)(m->n - off)) rc = errno ? -errno : -EIO;
    if (fd >= 0 && (fsync(fd) || close(fd)) && !rc) rc = -errno;
    snprintf(kept, keptlen, "%s", cp);
    free(cp);
    if (rc) return rc;
    int wfd = open(path, O_WRONLY | O_CLOEXEC);
    if (wfd < 0) return -errno;
    rc = ftruncate(wfd, (off_t)off) || fdatasync(wfd) ? -errno : 0;
    close(wfd);
    return rc;
}

/* The upgrade of a directory an older daemon wrote (what: which files,
 * for the log): the scene just restored is written at once as snapshot
 * <gen> in the current format, and edits go on in a new journal <gen> of
 * the current format (nothing is ever appended to an older file). The
 * older generations are then removed, as after any snapshot
 * (put_in_place). Costs one snapshot of the scene, once. If the snapshot
 * cannot be written the old files stay with the new journal after them
 * (a valid directory: recovery replays across formats) and the next start
 * tries again. 0 done; 1 the snapshot failed (the old files kept); -1
 * with err when not even the journal can be started. */
static int upgrade(journal *j, const scene *sc, uint64_t gen, uint64_t seq, const char *what, char *err,
                   size_t errlen)
{
    int rc = start_file(j, gen, seq);
    if (rc) {
        snprintf(err, errlen, "%s/journal.%06" PRIu64 ": %s (upgrading: %s)", j->dir, gen, strerror(-rc), what);
        return -1;
    }
    char *tmp = path_of(j, "snapshot.tmp", gen);
    rc = tmp ? write_tmp(tmp, sc, gen, seq) : -ENOMEM;
    free(tmp);
    if (!put_in_place(j, gen, rc == 0)) {
        LOGW("upgrade: %s; snapshot %06" PRIu64 " could not be written (%s): the old files are kept, edits go to "
             "journal %06" PRIu64 " (format 2), and the next start tries again",
             what, gen, strerror(rc ? -rc : EIO), gen);
        return 1;
    }
    LOGI("upgrade: %s; the scene is now snapshot %06" PRIu64 " (format %u) and edits go to journal %06" PRIu64
         " (format 2); the older files were removed",
         what, gen, SNAPSHOT_FORMAT, gen);
    return 0;
}

/* Whether an intact record with a sequence number of at least seq starts
 * anywhere in p[from, n): a length that fits, the sequence number, the
 * CRC. Every byte offset is tried, so a damaged length field (which puts
 * the next record somewhere the walk does not look) hides nothing. Cost:
 * one compare per byte, a CRC only where an 8-byte sequence number in
 * range sits, so about the file's size in memory reads. */
static bool intact_after(const uint8_t *p, size_t n, size_t from, uint64_t seq, size_t *at, uint64_t *got)
{
    for (size_t q = from; q + REC_HDR <= n; q++) {
        const uint8_t *r = p + q;
        uint64_t s = vp_ld_u64(r + 8);
        uint32_t len = vp_ld_u32(r);
        /* a record's seq is at most one per REC_HDR bytes past seq */
        if (s < seq || s - seq > (n - from) / REC_HDR + 1 || len > JOURNAL_REC_MAX || len > n - q - REC_HDR) continue;
        if (vp_ld_u32(r + 4) != journal_crc(r + 8, 16, r + REC_HDR, len)) continue;
        *at = q;
        *got = s;
        return true;
    }
    return false;
}

/* Replays journal.<gen> into sc. Its first record must be seq *seq; *seq
 * ends one past its last. A record the scene refuses is an error, and so
 * is any damage, except a torn end of the last file, which is cut (rep).
 *
 * What a torn end can look like: the writer appends each record with one
 * writev at the end of the file and never rewrites a byte, so a crash (of
 * the daemon: the page cache keeps every completed write; of the machine:
 * the unsynced end may come back short, zero-filled or with old garbage)
 * leaves intact records, then at most one stretch of bytes that are not a
 * record, reaching to the end of the file. A damaged record that is
 * followed by an intact record (any offset, any later sequence number)
 * is therefore not a torn end: it is damage inside the journal (a flipped
 * bit, a bad sector, a length field hit so that the walk would step over
 * good records), and cutting there would silently drop acknowledged
 * edits. Recovery refuses instead, naming the file and the offset; the
 * operator decides. The one case this refuses that a crash could make: a
 * machine crash under everysec or off whose page writeback reached the
 * disk out of order (a hole, then later records); those records were
 * never synced, and refusing still loses nothing silently. */
static int replay_file(journal *j, uint64_t gen, bool last, scene *sc, uint64_t *seq, unsigned *format,
                       journal_report *rep, char *err, size_t errlen)
{
    char *path = path_of(j, "journal", gen);
    if (!path) return -1;
    mapped m;
    int rc = map_file(path, &m);
    if (rc) {
        snprintf(err, errlen, "%s: %s", path, strerror(-rc));
        free(path);
        return -1;
    }
    const char *why = NULL;
    size_t off = 0;
    *format = m.n >= HDR_SIZE && !memcmp(m.p, MAGIC_V1, 8) ? 1 : 2;
    if (m.n < HDR_SIZE) why = "shorter than its header";
    else if (*format == 2 && memcmp(m.p, MAGIC, 8)) why = "not a Vantage journal (bad magic)";
    else if (vp_ld_u32(m.p + 28) != journal_crc(m.p, 28, NULL, 0)) why = "header CRC mismatch";
    else if (vp_ld_u64(m.p + 8) != gen) why = "header names another generation";
    else if (vp_ld_u64(m.p + 16) != *seq) why = "its first record does not follow the one before";
    if (why && last && m.n < HDR_SIZE) {
        /* the last file's creation was cut short (daemons before the
           header went through journal.tmp.<gen> could leave this after a
           kill): it holds no record, so nothing is lost; written anew */
        snprintf(rep->cut, sizeof rep->cut, "%s: %s (%zu bytes, no record): its header is written anew", path, why,
                 m.n);
        rep->cut_bytes = m.n;
        unmap_file(&m);
        free(path);
        return 1;
    }
    if (why) {
        /* a header is written and synced before any record: a bad one
           means the file is not ours or the disk lied */
        snprintf(err, errlen, "%s: %s (its header, offset 0)", path, why);
        unmap_file(&m);
        free(path);
        return -1;
    }
    off = HDR_SIZE;
    int ret = 0;
    while (off < m.n) {
        const uint8_t *r = m.p + off;
        size_t left = m.n - off;
        if ((why = journal_rec_check(r, left, *seq))) break;
        uint32_t len = vp_ld_u32(r);
        uint16_t type = vp_ld_u16(r + 16);
        scene_err se = {0};
        rc = journal_rec_apply(sc, r, *format, &se);
        if (rc) {
            /* the CRC held: the daemon wrote this and applied it once.
               Refused now means other limits (--max-entities...) or a bug */
            snprintf(err, errlen,
                     "%s: record %" PRIu64 " at offset %zu (%s) cannot be applied again: %s (was the journal "
                     "written with larger limits?)",
                     path, *seq, off, vp_type_name(type), se.msg);
            ret = -1;
            break;
        }
        (*seq)++;
        rep->records++;
        rep->bytes += REC_HDR + len;
        off += REC_HDR + len;
    }
    size_t later_at = 0;
    uint64_t later_seq = 0;
    if (!ret && why && intact_after(m.p, m.n, off + 1, *seq, &later_at, &later_seq)) {
        snprintf(err, errlen,
                 "%s: %s at offset %zu (record %" PRIu64 "), and an intact record (%" PRIu64 ") follows at offset "
                 "%zu: the damage is inside the journal, not a torn end, and cutting it would drop acknowledged "
                 "edits; move the files aside to start anyway",
                 path, why, off, *seq, later_seq, later_at);
        ret = -1;
    } else if (!ret && why) {
        if (!last) {
            snprintf(err, errlen,
                     "%s: %s at offset %zu, and a later journal follows it: the damage is not a torn end; move "
                     "the files aside to start anyway",
                     path, why, off);
            ret = -1;
        } else {
            char kept[300];
            rc = cut_tail(path, &m, off, kept, sizeof kept);
            if (rc) {
                snprintf(err, errlen, "%s: %s at offset %zu, and it cannot be cut: %s", path, why, off,
                         strerror(-rc));
                ret = -1;
            } else {
                rep->cut_bytes = m.n - off;
                snprintf(rep->cut, sizeof rep->cut, "%s: %s at offset %zu: %zu bytes cut after record %" PRIu64
                         " (kept in %s)", path, why, off, m.n - off, *seq - 1, kept);
            }
        }
    }
    if (!ret && last) j->size = j->synced = off;
    unmap_file(&m);
    free(path);
    return ret;
}

int journal_open(const char *dir, int policy, scene *sc, journal **out, journal_report *rep, char *err,
                 size_t errlen)
{
    memset(rep, 0, sizeof *rep);
    uint64_t t0 = mono_ms();
    journal *j = calloc(1, sizeof *j);
    if (!j || !(j->dir = strdup(dir))) {
        free(j);
        snprintf(err, errlen, "out of memory");
        return -1;
    }
    j->policy = policy;
    j->fd = j->lock_fd = -1;
    j->limit = DEFAULT_LIMIT;
    /* tests' knobs (as VANTAGED_SNAPSHOT_DELAY_MS): the Nth sync fails
       (jsync); a snapshot as soon as the journal holds a record and none is
       being written, so a test can restore a snapshot taken at every point
       of a session */
    const char *fail = getenv("VANTAGED_FAIL_SYNC");
    atomic_store(&sync_fail_at, fail ? strtol(fail, NULL, 10) : 0);
    atomic_store(&sync_calls, 0);
    const char *each = getenv("VANTAGED_SNAPSHOT_EACH_TURN");
    j->each_turn = each && *each && strcmp(each, "0");
    pthread_mutex_init(&j->mu, NULL);
    pthread_cond_init(&j->cv, NULL);
    gens snaps = {0}, jrns = {0};
    bool torn_header = false; /* the last journal's header was cut short: written anew */
    int rc = 0;
    char *lock = NULL;
    if (mkdir(dir, 0700) && errno != EEXIST) {
        snprintf(err, errlen, "%s: %s", dir, strerror(errno));
        goto fail;
    }
    /* one daemon per directory */
    if (asprintf(&lock, "%s/LOCK", dir) < 0 ||
        (j->lock_fd = open(lock, O_RDWR | O_CREAT | O_CLOEXEC, 0600)) < 0) {
        snprintf(err, errlen, "%s/LOCK: %s", dir, strerror(errno));
        goto fail;
    }
    if (flock(j->lock_fd, LOCK_EX | LOCK_NB)) {
        snprintf(err, errlen, "%s is in use by another vantaged (%s)", dir,
                 errno == EWOULDBLOCK ? "its LOCK is held" : strerror(errno));
        goto fail;
    }
    if ((rc = list_gens(dir, "snapshot", &snaps)) || (rc = list_gens(dir, "journal", &jrns))) {
        snprintf(err, errlen, "%s: %s", dir, strerror(-rc));
        goto fail;
    }
    uint64_t gen = 1, seq = 1;
    unsigned snap_format = SNAPSHOT_FORMAT, jr_format = 2;
    if (snaps.n) {
        /* the newest snapshot (a complete one: they are renamed into place) */
        gen = snaps.v[snaps.n - 1];
        char *p = path_of(j, "snapshot", gen);
        mapped m;
        rc = p ? map_file(p, &m) : -ENOMEM;
        if (!rc) {
            rc = snapshot_load(m.p, m.n, sc, gen, &seq, err, errlen);
            snap_format = snapshot_format(m.p, m.n);
            rep->snapshot_bytes = m.n;
            unmap_file(&m);
        } else {
            snprintf(err, errlen, "%s: %s", p ? p : dir, strerror(-rc));
        }
        if (rc) {
            if (p && !strstr(err, p)) {
                char tmp[400];
                snprintf(tmp, sizeof tmp, "%s: %s", p, err);
                snprintf(err, errlen, "%s", tmp);
            }
            free(p);
            goto fail;
        }
        free(p);
        rep->snapshot_gen = gen;
        j->base_bytes = rep->snapshot_bytes;
    }
    /* the journals from the snapshot's generation on, in order, no gaps */
    size_t first = 0;
    while (first < jrns.n && jrns.v[first] < gen) first++;
    rep->fresh = !snaps.n && first == jrns.n;
    for (size_t i = first; i < jrns.n; i++) {
        if (jrns.v[i] != gen + (i - first)) {
            snprintf(err, errlen, "%s: journal.%06" PRIu64 " is missing (the next is %06" PRIu64 ")", dir,
                     gen + (i - first), jrns.v[i]);
            goto fail;
        }
        int rrc = replay_file(j, jrns.v[i], i + 1 == jrns.n, sc, &seq, &jr_format, rep, err, errlen);
        if (rrc < 0) goto fail;
        torn_header = rrc > 0;
    }
    if ((first < jrns.n && jr_format == 1) || snap_format < SNAPSHOT_FORMAT) {
        /* an older daemon's directory: written anew in the current formats */
        uint64_t next = (first < jrns.n ? jrns.v[jrns.n - 1] : gen) + 1;
        char what[160];
        snprintf(what, sizeof what, "%s held %s", dir,
                 first < jrns.n && jr_format == 1 ? "a format 1 journal (protocol version 1)"
                                                  : "a snapshot of an older format");
        int urc = upgrade(j, sc, next, seq, what, err, errlen);
        if (urc < 0) goto fail;
        if (urc == 0) rep->upgrade_gen = next;
    } else if (first < jrns.n && !torn_header) {
        /* go on writing the last file */
        uint64_t last = jrns.v[jrns.n - 1];
        char *p = path_of(j, "journal", last);
        j->fd = p ? open(p, O_WRONLY | O_APPEND | O_CLOEXEC) : -1;
        if (j->fd < 0) {
            snprintf(err, errlen, "%s: %s", p ? p : dir, strerror(errno));
            free(p);
            goto fail;
        }
        free(p);
        j->gen = last;
        j->seq = seq;
        j->last_start = j->size;
    } else if ((rc = start_file(j, torn_header ? jrns.v[jrns.n - 1] : gen, seq))) {
        snprintf(err, errlen, "%s/journal.%06" PRIu64 ": %s", dir, torn_header ? jrns.v[jrns.n - 1] : gen,
                 strerror(-rc));
        goto fail;
    }
    /* loads open at the crash: their connections are gone, so they go as
       a dropped connection's would (journaled like any change) */
    for (uint32_t id = 1; id <= sc->nsublevels; id++) {
        if (sc->sl[id].state != VP_SL_LOADING) continue;
        edit e = {.type = VP_SUBLEVEL_ABORT, .sublevel = (uint16_t)id};
        edit_result res;
        scene_err se;
        if (journal_apply(j, sc, &e, NULL, 0, &res, &se)) {
            snprintf(err, errlen, "cannot drop sub-level %s, left loading: %s", sc->sl[id].name, se.msg);
            goto fail;
        }
        edit_result_free(&res);
        rep->loads_dropped++;
    }
    /* leftovers of a snapshot or a journal file's creation that did not finish */
    for (uint64_t g = gen; g <= j->gen + 1; g++) {
        for (int k = 0; k < 2; k++) {
            char *p = path_of(j, k ? "journal.tmp" : "snapshot.tmp", g);
            if (p) unlink(p);
            free(p);
        }
    }
    if (policy == JOURNAL_EVERYSEC) {
        /* signals are the loop's (it reads SIGTERM from a signalfd): the
           thread, started before the loop blocks them, starts with all
           blocked */
        sigset_t all, old;
        sigfillset(&all);
        pthread_sigmask(SIG_BLOCK, &all, &old);
        int trc = pthread_create(&j->syncer, NULL, syncer_main, j);
        pthread_sigmask(SIG_SETMASK, &old, NULL);
        if (trc) {
            snprintf(err, errlen, "cannot start the journal's sync thread");
            goto fail;
        }
        j->syncer_on = true;
    }
    free(lock);
    free(snaps.v);
    free(jrns.v);
    rep->ms = mono_ms() - t0;
    *out = j;
    return 0;
fail:
    free(lock);
    free(snaps.v);
    free(jrns.v);
    journal_close(j);
    return -1;
}

int journal_close(journal *j)
{
    if (!j) return 0;
    int rc = 0;
    if (j->syncer_on) {
        pthread_mutex_lock(&j->mu);
        j->stop = true;
        pthread_cond_signal(&j->cv);
        pthread_mutex_unlock(&j->mu);
        pthread_join(j->syncer, NULL);
    }
    if (j->child) {
        /* a snapshot in flight is let finish: the next start is shorter */
        int status = 0;
        pid_t r;
        while ((r = waitpid(j->child, &status, 0)) < 0 && errno == EINTR) {}
        child_done(j, r, status);
    }
    if (j->fd >= 0) {
        if (j->policy != JOURNAL_OFF && jsync(j->fd)) {
            /* what the last turns acknowledged may not be on disk: the exit
               status says so (a supervisor must not take it as clean) */
            rc = -errno;
            LOGE("journal: the final sync failed: %s; %s", strerror(-rc),
                 j->policy == JOURNAL_EVERYSEC ? "edits acknowledged in the last second may be lost if the machine "
                                                 "goes down now"
                                               : "every acknowledged edit had been synced, but the last writes (a "
                                                 "dropped load, say) may not be on disk");
        }
        close(j->fd);
    }
    if (j->lock_fd >= 0) close(j->lock_fd);
    pthread_mutex_destroy(&j->mu);
    pthread_cond_destroy(&j->cv);
    free(j->dir);
    free(j);
    return rc;
}
