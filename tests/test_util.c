/*
 * test_util.c — helpers more than one test file needs.
 */
#include "test_util.h"
#include "vt_err.h" /* the writers' codes the helpers below assert */

#include <dirent.h>
#include <errno.h>
#include <pthread.h>
#include <signal.h>
#include <stdio.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>


void test_view_everything(cull_view *v)
{
    cull_view_desc d = {.viewport_w = 100, .viewport_h = 100};
    cull_mat_ortho(d.view_proj, -1e13, 1e13, -1e13, 1e13, -1e13, 1e13, CULL_DEPTH_GL);
    assert_int_equal(cull_view_init(v, &d), CULL_OK);
}

void test_view_look(cull_view *v, const double origin[3], const double dir[3], uint32_t w, uint32_t h)
{
    test_view_look_range(v, origin, dir, w, h, 0.1, 1000);
}

void test_view_look_range(cull_view *v, const double origin[3], const double dir[3], uint32_t w, uint32_t h,
                          double near, double far)
{
    cull_view_desc d = {.origin = {origin[0], origin[1], origin[2]}, .viewport_w = w, .viewport_h = h};
    double proj[16], view[16], up[3] = {0, 1, 0};
    cull_mat_perspective(proj, 1.0, (double)w / h, near, far, CULL_DEPTH_GL);
    cull_mat_look_dir(view, dir, up);
    cull_mat_mul(d.view_proj, proj, view);
    assert_int_equal(cull_view_init(v, &d), CULL_OK);
}

size_t test_query_everything(const cull_world *w, cull_ctx *c, cull_result **out)
{
    cull_ctx *own = NULL;
    if (!c) {
        assert_int_equal(cull_ctx_create(NULL, &own), CULL_OK);
        c = own;
    }
    cull_view v;
    test_view_everything(&v);
    size_t cap = cull_query_bound(w), n = 0;
    *out = malloc(cap * sizeof **out);
    assert_non_null(*out);
    assert_int_equal(cull_query(w, c, &(cull_query_desc){.views = &v, .view_count = 1}, *out, cap, &n, NULL),
                     CULL_OK);
    cull_ctx_destroy(own);
    return n;
}

static int cmp_handle(const void *a, const void *b)
{
    cull_handle x = *(const cull_handle *)a, y = *(const cull_handle *)b;
    return x < y ? -1 : x > y;
}

void test_assert_same_handles(const cull_handle *want, size_t n, const cull_result *res, size_t got)
{
    assert_int_equal(got, n);
    cull_handle *a = malloc((n + 1) * sizeof *a), *b = malloc((n + 1) * sizeof *b);
    memcpy(a, want, n * sizeof *a);
    for (size_t i = 0; i < n; i++) b[i] = res[i].handle;
    qsort(a, n, sizeof *a, cmp_handle);
    qsort(b, n, sizeof *b, cmp_handle);
    assert_memory_equal(a, b, n * sizeof *a);
    free(a);
    free(b);
}

void tdir_make(tdir *t, const char *prefix)
{
    const char *base = getenv("TMPDIR");
    snprintf(t->dir, sizeof t->dir, "%s/%s.XXXXXX", base && base[0] ? base : "/tmp", prefix);
    assert_non_null(mkdtemp(t->dir));
}

const char *tdir_file(tdir *t, const char *name)
{
    snprintf(t->path, sizeof t->path, "%s/%s", t->dir, name);
    return t->path;
}

int tdir_count(const tdir *t)
{
    DIR *d = opendir(t->dir);
    assert_non_null(d);
    int n = 0;
    for (struct dirent *e; (e = readdir(d));)
        if (strcmp(e->d_name, ".") && strcmp(e->d_name, "..")) n++;
    closedir(d);
    return n;
}

void tdir_remove(tdir *t)
{
    DIR *d = opendir(t->dir);
    assert_non_null(d);
    for (struct dirent *e; (e = readdir(d));) {
        if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, "..")) continue;
        char p[600];
        snprintf(p, sizeof p, "%s/%s", t->dir, e->d_name);
        if (unlink(p) != 0) rmdir(p);
    }
    closedir(d);
    assert_int_equal(rmdir(t->dir), 0);
}

uint8_t *test_slurp(const char *path, size_t *len)
{
    FILE *f = fopen(path, "rb");
    assert_non_null(f);
    assert_int_equal(fseek(f, 0, SEEK_END), 0);
    long n = ftell(f);
    assert_true(n >= 0);
    rewind(f);
    uint8_t *p = malloc((size_t)n + 1);
    assert_non_null(p);
    assert_int_equal(fread(p, 1, (size_t)n, f), (size_t)n);
    fclose(f);
    *len = (size_t)n;
    return p;
}

void dir_unlink_files(const char *dir)
{
    DIR *d = opendir(dir);
    struct dirent *e;
    char p[600];
    while (d && (e = readdir(d))) {
        if (e->d_name[0] == '.') continue;
        snprintf(p, sizeof p, "%s/%s", dir, e->d_name);
        unlink(p);
    }
    if (d) closedir(d);
}

int test_run_cmd(const char *cmd, char *out, size_t cap)
{
    FILE *p = popen(cmd, "r");
    assert_non_null(p);
    size_t n = fread(out, 1, cap - 1, p);
    out[n] = 0;
    return pclose(p);
}

int test_rows_marker(void **state)
{
    (void)state;
    print_error("a TEST_ROWS entry ran unexpanded (tests/test_main.c expands them)\n");
    return -1;
}

static char *name_dup(const char *a, const char *b)
{
    size_t la = strlen(a), lb = b ? strlen(b) + 1 : 0;
    char *s = malloc(la + lb + 1);
    if (!s) abort();
    memcpy(s, a, la);
    if (b) {
        s[la] = '/';
        memcpy(s + la + 1, b, lb - 1);
    }
    s[la + lb] = 0;
    return s;
}

size_t test_rows_expand(const struct CMUnitTest *tests, size_t n, struct CMUnitTest *out)
{
    size_t k = 0;
    for (size_t i = 0; i < n; i++) {
        const struct CMUnitTest *t = &tests[i];
        if (t->setup_func != test_rows_marker) {
            if (out) out[k] = *t, out[k].name = name_dup(t->name, NULL);
            k++;
            continue;
        }
        const test_rows *r = t->initial_state;
        for (size_t j = 0; j < r->count; j++, k++) {
            const void *row = (const char *)r->rows + j * r->size;
            if (!out) continue;
            /* the row's first member is its name */
            out[k] = (struct CMUnitTest){.name = name_dup(t->name, *(const char *const *)row),
                                         .test_func = t->test_func,
                                         .initial_state = (void *)(uintptr_t)row};
        }
    }
    return k;
}

const char *tdir_path_arg(tdir *t, test_path k, const char *name)
{
    return k == TPATH_NULL ? NULL : k == TPATH_EMPTY ? "" : tdir_file(t, name);
}

void test_unwritable_paths(tdir *t, test_write_fn write, void *ctx, const char *ext)
{
    char err[512], name[64];
    snprintf(t->path, sizeof t->path, "%s/missing/x%s", t->dir, ext);
    assert_int_equal(write(t->path, err, sizeof err, ctx), VT_ERR_NOT_FOUND);
    assert_non_null(strstr(err, t->path));
    /* the parent is a file */
    snprintf(name, sizeof name, "f%s", ext);
    assert_int_equal(write(tdir_file(t, name), err, sizeof err, ctx), 0);
    snprintf(t->path, sizeof t->path, "%s/f%s/x%s", t->dir, ext, ext);
    assert_int_equal(write(t->path, err, sizeof err, ctx), VT_ERR_FILE);
    assert_non_null(strstr(err, strerror(ENOTDIR))); /* errno's text names the cause */
    /* the target is a directory: written, then the rename fails */
    snprintf(name, sizeof name, "d%s", ext);
    assert_int_equal(mkdir(tdir_file(t, name), 0700), 0);
    assert_int_equal(write(t->path, err, sizeof err, ctx), VT_ERR_FILE);
    assert_non_null(strstr(err, strerror(EISDIR)));
    assert_true(strlen(err) > 0);
    assert_int_equal(tdir_count(t), 2); /* f, d: no temporary left */
    assert_int_equal(rmdir(t->path), 0);
    snprintf(name, sizeof name, "f%s", ext);
    assert_int_equal(unlink(tdir_file(t, name)), 0);
}

void test_write_past_fsize(test_write_fn write, const char *path, void *ctx)
{
    fflush(NULL);
    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        struct rlimit lim = {64 << 10, 64 << 10};
        signal(SIGXFSZ, SIG_IGN);
        char err[512] = "";
        /* the file system's EFBIG: VT_ERR_FILE, its text in the message */
        int ok = setrlimit(RLIMIT_FSIZE, &lim) == 0 && write(path, err, sizeof err, ctx) == VT_ERR_FILE &&
                 strstr(err, strerror(EFBIG)) != NULL;
        _exit(ok ? 0 : 1);
    }
    int status = 0;
    assert_int_equal(waitpid(pid, &status, 0), pid);
    assert_true(WIFEXITED(status) && WEXITSTATUS(status) == 0);
}

bool test_refused_naming(int rc, const char *err, const char *path)
{
    return rc == VT_ERR_CORRUPT && strncmp(err, path, strlen(path)) == 0;
}

void test_threads_in_tdir(const char *prefix, const char *ext, void *(*fn)(void *), int n, int per_thread)
{
    tdir t;
    tdir_make(&t, prefix);
    for (int i = 0; i < n; i++) {
        char p[400];
        snprintf(p, sizeof p, "%s/junk%d%s", t.dir, i, ext);
        FILE *f = fopen(p, "w");
        assert_non_null(f);
        fprintf(f, "junk %d: not an image, long enough for a magic number and flags\n", i);
        assert_int_equal(fclose(f), 0);
    }
    assert_true(n > 0);
    size_t cnt = (size_t)(n > 0 ? n : 1); /* (the range GCC can see: -Walloc-size-larger-than) */
    pthread_t *th = calloc(cnt, sizeof *th);
    test_thread *args = calloc(cnt, sizeof *args);
    assert_true(th && args);
    for (int i = 0; i < n; i++) {
        args[i] = (test_thread){.t = &t, .id = i};
        assert_int_equal(pthread_create(&th[i], NULL, fn, &args[i]), 0);
    }
    for (int i = 0; i < n; i++) assert_int_equal(pthread_join(th[i], NULL), 0);
    for (int i = 0; i < n; i++) assert_int_equal(args[i].failures, 0);
    assert_int_equal(tdir_count(&t), per_thread * n);
    free(args);
    free(th);
    tdir_remove(&t);
}

vt_gldraw *test_gldraw_or_null(vt_gl **g)
{
    char err[512];
    vt_gldraw *gr = NULL;
    if (vt_gl_open(g, NULL, err, sizeof err) != 0) {
        fprintf(stderr, "no GL here: %s\n", err);
        *g = NULL;
        return NULL;
    }
    assert_int_equal(vt_gldraw_create(*g, &gr, err, sizeof err), 0);
    return gr;
}
