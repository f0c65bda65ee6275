/*
 * test_util.h — what every test file shares: cmocka, a seeded RNG, the
 * run-size scale (VANTAGE_TEST_SCALE) and the seed (VANTAGE_SEED).
 */
#ifndef VANTAGE_TEST_UTIL_H
#define VANTAGE_TEST_UTIL_H

#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <math.h>
#include <stdlib.h>
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

static inline uint64_t test_seed(void)
{
    const char *s = getenv("VANTAGE_SEED");
    return s ? strtoull(s, NULL, 0) : 0x5EED2011ull;
}

#include "culling.h"

/* A view that sees everything within ±1e13 m. */
void test_view_everything(cull_view *v);
/* A perspective view (GL depth, 1 rad vertical, near 0.1, far 1000) from
 * origin looking along dir (y up), w x h pixels. */
void test_view_look(cull_view *v, const double origin[3], const double dir[3], uint32_t w, uint32_t h);
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
/* Unlinks the files of dir (not its subfolders, not dir). */
void dir_unlink_files(const char *dir);

/* Runs cmd with popen; its stdout (up to cap - 1 bytes, NUL-ended) in
 * out; pclose's status. */
int test_run_cmd(const char *cmd, char *out, size_t cap);

void test_assert_same_handles(const cull_handle *want, size_t n, const cull_result *res, size_t got);

#define TEST_GROUP(name) \
    extern const struct CMUnitTest name[]; \
    extern const size_t name##_count;

TEST_GROUP(world_tests)
TEST_GROUP(mask_tests)
TEST_GROUP(auth_tests)
TEST_GROUP(persist_tests)
TEST_GROUP(recover_tests)
TEST_GROUP(pad_tests)
TEST_GROUP(pad_io_tests)
TEST_GROUP(commander_tests)
TEST_GROUP(metrics_tests)
TEST_GROUP(sched_tests)
TEST_GROUP(bench_tests)
TEST_GROUP(cli_tests)
TEST_GROUP(view_tests)
TEST_GROUP(query_tests)
TEST_GROUP(alloc_tests)
TEST_GROUP(protocol_tests)
TEST_GROUP(e2e_tests)
TEST_GROUP(occlusion_tests)
TEST_GROUP(light_tests)
TEST_GROUP(render_tests)
TEST_GROUP(image_tests)
TEST_GROUP(exr_tests)
TEST_GROUP(gl_tests)
TEST_GROUP(sublevel_tests)
TEST_GROUP(destruct_tests)
TEST_GROUP(validate_tests)
TEST_GROUP(errmap_tests)

#endif
