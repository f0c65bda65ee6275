/*
 * test_util.h — what every test file shares: cmocka, a seeded RNG, the
 * run-size scale (VANTAGE_TEST_SCALE) and the seed (VANTAGE_SEED).
 */
#ifndef VANTAGE_TEST_UTIL_H
#define VANTAGE_TEST_UTIL_H

#include <setjmp.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include "splitmix.h"

typedef struct rng { uint64_t s; } rng;

static inline uint64_t rng_u64(rng *r) { return splitmix64(&r->s); }
/* uniform in [0,1) */
static inline double rng_f(rng *r) { return splitmix_unit(&r->s); }
static inline double rng_range(rng *r, double a, double b) { return a + (b - a) * rng_f(r); }
/* log-uniform in [a,b], a > 0 */
static inline double rng_log(rng *r, double a, double b) { return a * pow(b / a, rng_f(r)); }
static inline uint32_t rng_below(rng *r, uint32_t n) { return (uint32_t)(rng_u64(r) % n); }

static inline double test_scale(void)
{
    const char *s = getenv("VANTAGE_TEST_SCALE");
    double v = s ? atof(s) : 1.0;
    return v > 0 ? v : 1.0;
}

/* Seconds on the monotonic clock. */
static inline double test_now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + ts.tv_nsec * 1e-9;
}

/* An environment variable's value kept to put back later (the tests that
 * set VANTAGE_ISA or VANTAGE_EVEX for a while), NULL if it is unset; then
 * the variable set back to it (NULL: unset) and the copy freed. */
static inline char *test_env_keep(const char *name)
{
    const char *v = getenv(name);
    return v ? strdup(v) : NULL;
}

static inline void test_env_restore(const char *name, char *kept)
{
    if (kept) setenv(name, kept, 1);
    else unsetenv(name);
    free(kept);
}

static inline uint64_t test_seed(void)
{
    const char *s = getenv("VANTAGE_SEED");
    return s ? strtoull(s, NULL, 0) : 0x5EED2011ull;
}

#include "culling.h"
#include "vt_gldraw.h"

/* A GL renderer on a new context, or NULL (and *g NULL) where this
 * machine has no GL: the tests that compare with it skip that half. */
vt_gldraw *test_gldraw_or_null(vt_gl **g);

/* A view that sees everything within ±1e13 m. */
void test_view_everything(cull_view *v);
/* A perspective view (GL depth, 1 rad vertical, near 0.1, far 1000) from
 * origin looking along dir (y up), w x h pixels. */
void test_view_look(cull_view *v, const double origin[3], const double dir[3], uint32_t w, uint32_t h);
/* The same with the near and far planes given. */
void test_view_look_range(cull_view *v, const double origin[3], const double dir[3], uint32_t w, uint32_t h,
                          double near, double far);
/* Queries w with that view (ctx may be NULL); *out is malloc'ed. */
size_t test_query_everything(const cull_world *w, cull_ctx *ctx, cull_result **out);
/* res[0..got) holds exactly the n handles of want, in any order. */
/* A temporary directory for file tests: made under $TMPDIR (or /tmp) with
 * the given name prefix; tdir_file names a file in it; tdir_count counts
 * its entries; tdir_remove deletes its files, then it. */
typedef struct tdir {
    char dir[256];
    char path[320];
} tdir;
void tdir_make(tdir *t, const char *prefix);
const char *tdir_file(tdir *t, const char *name);
int tdir_count(const tdir *t);
void tdir_remove(tdir *t);
/* The whole file at path, malloc'ed (*len bytes; asserts it reads). */
uint8_t *test_slurp(const char *path, size_t *len);
/* Unlinks the files of dir (not its subfolders, not dir). */
void dir_unlink_files(const char *dir);

/* The path a bad-argument row passes: none, an empty one, or a file in
 * the test's fresh folder. */
typedef enum test_path { TPATH_NULL, TPATH_EMPTY, TPATH_FILE } test_path;
const char *tdir_path_arg(tdir *t, test_path k, const char *name);

/* A writer of one small file under test (an image, an EXR): 0 or -errno,
 * a message in err. */
typedef int (*test_write_fn)(const char *path, char *err, size_t errlen, void *ctx);
/* Places a writer cannot write fail with the file system's errno and
 * leave nothing behind: a missing folder (VT_ERR_NOT_FOUND, the message
 * names the path), a parent that is a file (VT_ERR_FILE, strerror(ENOTDIR)
 * in the message), a target that is a folder (VT_ERR_FILE, EISDIR's text:
 * written, then the rename fails; no temporary left). The
 * files are f<ext>, d<ext> and x<ext>; t is empty again after. */
void test_unwritable_paths(tdir *t, test_write_fn write, void *ctx, const char *ext);

/* write(path, ctx) in a child process whose files may grow to 64 KiB
 * (RLIMIT_FSIZE, SIGXFSZ ignored: a full disk); asserts that it failed
 * with VT_ERR_FILE and strerror(EFBIG) in the message. */
void test_write_past_fsize(test_write_fn write, const char *path, void *ctx);

/* Threads writing and failing at once in one fresh folder (named after
 * prefix): n files junk<i><ext> of text that is no image, then fn on n
 * threads, each with its own test_thread (t, id i, failures 0); asserts
 * that none failed and that the folder then holds per_thread * n files. */
typedef struct test_thread {
    const tdir *t;
    int id;
    int failures;
} test_thread;
void test_threads_in_tdir(const char *prefix, const char *ext, void *(*fn)(void *), int n, int per_thread);
/* A refusal of a file that is no image, as the threads must see it:
 * VT_ERR_CORRUPT, and the message begins with the file's path. */
bool test_refused_naming(int rc, const char *err, const char *path);

/* Runs cmd with popen; its stdout (up to cap - 1 bytes, NUL-ended) in
 * out; pclose's status. */
int test_run_cmd(const char *cmd, char *out, size_t cap);

void test_assert_same_handles(const cull_handle *want, size_t n, const cull_result *res, size_t got);

/* One named test per row of a table (malformed inputs above all, so that
 * the first failure hides none of the others, as Redis's
 * tests/unit/protocol.tcl sends one raw input per named test).
 * TEST_ROWS(fn, rows) in a group's CMUnitTest array stands for one test
 * per row of the static array rows, named "fn/<row name>", whose state is
 * the row (`const T *row = *state;`); a row is a struct whose first member
 * is `const char *name`. tests/test_main.c expands the rows before
 * VANTAGE_TEST_ONLY filters the names, so a substring can pick one row. */
typedef struct test_rows {
    const void *rows;
    size_t count, size;
} test_rows;
/* The setup TEST_ROWS marks its entry with; it fails the test if it ever
 * runs (an entry nobody expanded). */
int test_rows_marker(void **state);
#define TEST_ROWS(fn, rows_) \
    {#fn, fn, test_rows_marker, NULL, &(test_rows){rows_, sizeof rows_ / sizeof rows_[0], sizeof rows_[0]}}
/* Copies tests[0..n) into out (NULL: only counts), one entry per row for
 * TEST_ROWS entries; every name in out is malloc'ed (free them). Returns
 * the number of entries. */
size_t test_rows_expand(const struct CMUnitTest *tests, size_t n, struct CMUnitTest *out);

#define TEST_GROUP(name) \
    extern const struct CMUnitTest name[]; \
    extern const size_t name##_count;

TEST_GROUP(world_tests)
TEST_GROUP(bounds_tests)
TEST_GROUP(mask_tests)
TEST_GROUP(auth_tests)
TEST_GROUP(http_tests)
TEST_GROUP(web_tests)
TEST_GROUP(persist_tests)
TEST_GROUP(transform_tests)
TEST_GROUP(material_tests)
TEST_GROUP(recover_tests)
TEST_GROUP(cluster_rec_tests)
TEST_GROUP(upgrade_tests)
TEST_GROUP(pad_tests)
TEST_GROUP(pad_io_tests)
TEST_GROUP(commander_tests)
TEST_GROUP(cmdr_wasm_tests)
TEST_GROUP(metrics_tests)
TEST_GROUP(sched_tests)
TEST_GROUP(bench_tests)
TEST_GROUP(cli_tests)
TEST_GROUP(view_tests)
TEST_GROUP(query_tests)
TEST_GROUP(alloc_tests)
TEST_GROUP(protocol_tests)
TEST_GROUP(texture_tests)
TEST_GROUP(texsample_tests)
TEST_GROUP(env_tests)
TEST_GROUP(bytes_tests)
TEST_GROUP(protocol_size_tests)
TEST_GROUP(protocol_doc_tests)
TEST_GROUP(e2e_tests)
TEST_GROUP(occlusion_tests)
TEST_GROUP(light_tests)
TEST_GROUP(render_tests)
TEST_GROUP(scene_render_tests)
TEST_GROUP(post_tests)
TEST_GROUP(shadow_tests)
TEST_GROUP(brdf_tests)
TEST_GROUP(ssao_tests)
TEST_GROUP(image_tests)
TEST_GROUP(h264_tests)
TEST_GROUP(exr_tests)
TEST_GROUP(gl_tests)
TEST_GROUP(overlay_tests)
TEST_GROUP(sublevel_tests)
TEST_GROUP(destruct_tests)
TEST_GROUP(validate_tests)
TEST_GROUP(errmap_tests)
TEST_GROUP(import_tests)

/* test_bytes.c: two imported levels are the same, field for field */
struct imp_level;
void test_level_equal(const struct imp_level *a, const struct imp_level *b);

#endif
