/*
 * test_exr.c — the OpenEXR writer (render/vt_exr.c) against a reference
 * model: float channels come back bit for bit; half channels come back as
 * a slow, obviously-correct float->half (binary search over every finite
 * half, ties to even) says, on every halfway point between two halves and
 * the floats either side of it, and on all 65536 halves; planar,
 * interleaved and bottom-up layouts; every compression on sizes that end in
 * a partial chunk; 1x1 to 8192 wide and tall; bad arguments and paths fail
 * with nothing left on disk, and a write cut short (RLIMIT_FSIZE in a child
 * process) leaves the old file intact; errors go to the calling thread's
 * buffer while other threads write; `exrheader` (Debian: openexr) agrees on
 * the data window, the channels and their sorted order.
 *
 * Compiles to nothing until the build puts render/ on the include path, so
 * that adding this file does not break a build that does not link
 * OpenEXRCore yet; once test_main.c lists exr_tests, a missing include path
 * is a link error, not a silent skip.
 */
#include "test_util.h"

#if defined(__has_include)
#if __has_include("vt_exr.h")
#define VT_TEST_EXR 1
#endif
#endif

#ifdef VT_TEST_EXR
#include "vt_exr.h"

#include <dirent.h>
#include <errno.h>
#include <float.h>
#include <signal.h>
#include <stdbool.h>
#include <stdio.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

TEST_GROUP(exr_tests)

/* ---- reference half (IEEE 754 binary16) ---------------------------------- */

/* Value of a finite half, exactly, in double. */
static double ref_half_value(uint16_t h)
{
    int e = (h >> 10) & 31, m = h & 1023;
    double v = e ? ldexp(1024 + m, e - 25) : ldexp(m, -24);
    return (h & 0x8000) ? -v : v;
}

static float ref_half_to_float(uint16_t h)
{
    if ((h & 0x7c00) == 0x7c00) {
        if (h & 0x3ff) return NAN;
        return (h & 0x8000) ? -INFINITY : INFINITY;
    }
    return (float)ref_half_value(h);
}

/* Round to nearest, ties to even. Finite magnitudes 0x0000..0x7bff are
 * ordered like their values: binary-search the largest not above |f|, then
 * step up if the next is nearer, or as near and even. 65520 is halfway
 * from the largest half (65504, odd) to 65536, so it and above go to inf. */
static uint16_t ref_float_to_half(float f)
{
    if (isnan(f)) return 0x7e00;
    uint16_t sign = signbit(f) ? 0x8000 : 0;
    double a = fabs((double)f);
    if (a >= 65520.0) return sign | 0x7c00;
    uint16_t lo = 0, hi = 0x7bff;
    while (lo < hi) {
        uint16_t mid = (uint16_t)((lo + hi + 1) / 2);
        if (ref_half_value(mid) <= a) lo = mid;
        else hi = (uint16_t)(mid - 1);
    }
    if (lo < 0x7bff) {
        double below = a - ref_half_value(lo), above = ref_half_value((uint16_t)(lo + 1)) - a;
        if (above < below || (above == below && (lo & 1))) lo++;
    }
    return sign | lo;
}

/* What a half channel must read back as. */
static float ref_round(float f)
{
    return ref_half_to_float(ref_float_to_half(f));
}

/* Same bits, or both NaN. */
static bool same_float(float a, float b)
{
    if (isnan(a) || isnan(b)) return isnan(a) && isnan(b);
    return memcmp(&a, &b, sizeof a) == 0;
}

static float *read_all(const char *path, const char *name, uint32_t w, uint32_t h)
{
    char err[512];
    float *out = malloc((size_t)w * h * sizeof *out);
    assert_non_null(out);
    int rc = vt_exr_read_channel(path, name, out, w, h, err, sizeof err);
    if (rc) print_message("read %s: %d %s\n", name, rc, err);
    assert_int_equal(rc, 0);
    assert_string_equal(err, "");
    return out;
}

static void write_ok(const char *path, uint32_t w, uint32_t h, const vt_exr_channel *ch, uint32_t n,
                     vt_exr_compression comp)
{
    char err[512];
    int rc = vt_exr_write(path, w, h, ch, n, comp, err, sizeof err);
    if (rc) print_message("write: %d %s\n", rc, err);
    assert_int_equal(rc, 0);
    assert_string_equal(err, "");
}

/* Planar channel: (x, y) at x + y * w. */
static vt_exr_channel planar(const char *name, vt_exr_type type, const float *data, uint32_t w)
{
    return (vt_exr_channel){.name = name, .type = type, .data = data, .x_stride = 1,
                            .y_stride = (ptrdiff_t)w};
}

/* One planar channel of w x h floats, written with comp into a fresh
 * directory, its size read back, then its values: what came back
 * (malloc'ed; the directory is gone). */
static float *round_trip(const char *name, vt_exr_type type, const float *src, uint32_t w, uint32_t h,
                         vt_exr_compression comp)
{
    tdir t;
    tdir_make(&t, "vt_exr_test");
    vt_exr_channel ch = planar(name, type, src, w);
    write_ok(tdir_file(&t, "rt.exr"), w, h, &ch, 1, comp);
    uint32_t rw = 0, rh = 0;
    char err[256];
    assert_int_equal(vt_exr_size(t.path, &rw, &rh, err, sizeof err), 0);
    assert_int_equal(rw, w);
    assert_int_equal(rh, h);
    float *out = read_all(t.path, name, w, h);
    tdir_remove(&t);
    return out;
}

/* Floats of every kind: wide magnitudes, both signs, zeros, denormals,
 * inf, NaN, the largest float. */
static float any_float(rng *r)
{
    switch (rng_below(r, 16)) {
    case 0: return 0.0f;
    case 1: return -0.0f;
    case 2: return INFINITY;
    case 3: return -INFINITY;
    case 4: return NAN;
    case 5: return FLT_MAX;
    case 6: return (float)rng_log(r, 1e-45, 1e-38) * (rng_below(r, 2) ? 1 : -1);
    default: return (float)rng_log(r, 1e-12, 1e12) * (rng_below(r, 2) ? 1 : -1);
    }
}

/* ---- exrheader ------------------------------------------------------------- */

/* Runs exrheader on path and checks the data window, the compression (as
 * exrheader names it) and that the channel lines come in `sorted` order
 * with the given types. Skips, saying so, when
 * exrheader is not installed (Debian package openexr). */
static void check_exrheader(const char *path, uint32_t w, uint32_t h, const char *const *sorted,
                            const vt_exr_type *types, uint32_t n, const char *compression)
{
    if (system("command -v exrheader >/dev/null 2>&1") != 0) {
        print_message("exrheader not found (Debian package openexr): header check skipped\n");
        return;
    }
    if (strchr(path, '\'')) {
        print_message("path has a quote: header check skipped\n");
        return;
    }
    char cmd[700], line[512], want[128], want_comp[128];
    snprintf(cmd, sizeof cmd, "exrheader '%s' 2>&1", path);
    FILE *p = popen(cmd, "r");
    assert_non_null(p);
    bool window = false, comp = false;
    uint32_t next = 0;
    snprintf(want, sizeof want, "dataWindow (type box2i): (0 0) - (%u %u)\n", w - 1, h - 1);
    snprintf(want_comp, sizeof want_comp, "compression (type compression): %s\n", compression);
    while (fgets(line, sizeof line, p)) {
        if (strcmp(line, want) == 0) window = true;
        if (strcmp(line, want_comp) == 0) comp = true;
        /* channel lines: "    NAME, 16-bit floating-point, sampling 1 1" */
        char name[64], type[64];
        if (sscanf(line, " %63[^,], %63[^,], sampling 1 1", name, type) == 2 && next < n &&
            strcmp(name, sorted[next]) == 0) {
            assert_string_equal(type, types[next] == VT_EXR_HALF ? "16-bit floating-point"
                                                                 : "32-bit floating-point");
            next++;
        }
    }
    assert_int_equal(pclose(p), 0);
    assert_true(window);
    assert_true(comp);
    assert_int_equal(next, n);
}

/* ---- tests ----------------------------------------------------------------- */

static void test_exr_float_exact(void **state)
{
    (void)state;
    rng r = {test_seed() ^ 0xE1};
    uint32_t w = 97, h = 61;
    float *src = malloc((size_t)w * h * sizeof *src);
    assert_non_null(src);
    for (size_t i = 0; i < (size_t)w * h; i++) src[i] = any_float(&r);
    float *out = round_trip("Z", VT_EXR_FLOAT, src, w, h, VT_EXR_ZIP);
    assert_memory_equal(out, src, (size_t)w * h * sizeof *src); /* NaN payloads too */
    free(out);
    free(src);
}

/* Every halfway point between adjacent finite halves, the floats just
 * below and above it, both signs, and the edges of the range. */
static void test_exr_half_rounding(void **state)
{
    (void)state;
    static const float edges[] = {0.0f, -0.0f, INFINITY, -INFINITY, NAN, FLT_MAX, -FLT_MAX,
                                  65504.0f, 65519.99f, 65520.0f, -65520.0f, 65536.0f, 1e-8f,
                                  0x1p-24f, 0x1p-25f, 0x1.000002p-25f, 0x3p-25f, 0x1p-26f,
                                  0x1p-14f, 0x1.ffcp-15f, FLT_MIN, FLT_TRUE_MIN, 1.0f, 1.0009765625f};
    size_t n = sizeof edges / sizeof edges[0] + 6 * 0x7bff;
    uint32_t w = 1024, h = (uint32_t)((n + w - 1) / w);
    float *src = calloc((size_t)w * h, sizeof *src);
    assert_non_null(src);
    size_t k = 0;
    for (size_t i = 0; i < sizeof edges / sizeof edges[0]; i++) src[k++] = edges[i];
    for (uint16_t hv = 0; hv < 0x7bff; hv++) {
        /* exact in float: halves have 11 significant bits */
        float mid = (float)((ref_half_value(hv) + ref_half_value((uint16_t)(hv + 1))) / 2);
        const float v[3] = {mid, nextafterf(mid, 0), nextafterf(mid, INFINITY)};
        for (int j = 0; j < 3; j++) {
            src[k++] = v[j];
            src[k++] = -v[j];
        }
    }
    assert_int_equal(k, n);
    float *out = round_trip("Y", VT_EXR_HALF, src, w, h, VT_EXR_PIZ);
    size_t bad = 0;
    for (size_t i = 0; i < (size_t)w * h; i++) {
        if (!same_float(out[i], ref_round(src[i])) && bad++ < 5)
            print_message("%a -> %a, reference %a\n", (double)src[i], (double)out[i],
                          (double)ref_round(src[i]));
    }
    assert_int_equal(bad, 0);
    free(out);
    free(src);
}

/* All 65536 halves, as floats, come back bit for bit (NaNs as NaN). */
static void test_exr_half_representable_exact(void **state)
{
    (void)state;
    uint32_t w = 256, h = 256;
    float *src = malloc((size_t)w * h * sizeof *src);
    assert_non_null(src);
    for (uint32_t i = 0; i < w * h; i++) src[i] = ref_half_to_float((uint16_t)i);
    float *out = round_trip("H", VT_EXR_HALF, src, w, h, VT_EXR_NONE);
    for (uint32_t i = 0; i < w * h; i++) assert_true(same_float(out[i], src[i]));
    free(out);
    free(src);
}

/* Random values across the half range: within half an ulp, relative 2^-11
 * for normals, 2^-25 absolute below 2^-14. */
static void test_exr_half_precision(void **state)
{
    (void)state;
    rng r = {test_seed() ^ 0x4A1F};
    uint32_t w = 211, h = 83;
    float *src = malloc((size_t)w * h * sizeof *src);
    assert_non_null(src);
    for (size_t i = 0; i < (size_t)w * h; i++)
        src[i] = (float)(rng_log(&r, 1e-9, 6.5e4) * (rng_below(&r, 2) ? 1 : -1));
    float *out = round_trip("L", VT_EXR_HALF, src, w, h, VT_EXR_ZIPS);
    for (size_t i = 0; i < (size_t)w * h; i++) {
        double a = fabs((double)src[i]), e = fabs((double)out[i] - src[i]);
        assert_true(a < 0x1p-14 ? e <= 0x1p-25 : e <= a * 0x1p-11);
        assert_true(same_float(out[i], ref_round(src[i])));
    }
    free(out);
    free(src);
}

/* A bottom-up buffer: memory row 0 is the image's bottom row. */
static void test_exr_negative_stride(void **state)
{
    (void)state;
    uint32_t w = 33, h = 47;
    float *buf = malloc((size_t)w * h * sizeof *buf);
    assert_non_null(buf);
    for (uint32_t y = 0; y < h; y++) /* image row y lives in memory row h-1-y */
        for (uint32_t x = 0; x < w; x++) buf[(size_t)(h - 1 - y) * w + x] = (float)(y * 1000 + x);
    vt_exr_channel ch[2] = {
        {.name = "G", .type = VT_EXR_FLOAT, .data = buf + (size_t)(h - 1) * w, .x_stride = 1,
         .y_stride = -(ptrdiff_t)w},
        {.name = "H", .type = VT_EXR_HALF, .data = buf + (size_t)(h - 1) * w, .x_stride = 1,
         .y_stride = -(ptrdiff_t)w},
    };
    tdir t;
    tdir_make(&t, "vt_exr_test");
    write_ok(tdir_file(&t, "up.exr"), w, h, ch, 2, VT_EXR_ZIP);
    float *g = read_all(t.path, "G", w, h), *hh = read_all(t.path, "H", w, h);
    for (uint32_t y = 0; y < h; y++)
        for (uint32_t x = 0; x < w; x++) {
            float want = (float)(y * 1000 + x);
            assert_true(g[(size_t)y * w + x] == want);
            assert_true(same_float(hh[(size_t)y * w + x], ref_round(want)));
        }
    free(g);
    free(hh);
    free(buf);
    tdir_remove(&t);
}

/* Interleaved RGBA given as R, G, B, A; the file lists A, B, G, R. */
static void test_exr_interleaved_rgba(void **state)
{
    (void)state;
    rng r = {test_seed() ^ 0x46BA};
    uint32_t w = 64, h = 40;
    float *px = malloc((size_t)w * h * 4 * sizeof *px);
    assert_non_null(px);
    for (size_t i = 0; i < (size_t)w * h * 4; i++) px[i] = (float)rng_range(&r, -4, 4);
    const char *names[4] = {"R", "G", "B", "A"};
    const vt_exr_type types[4] = {VT_EXR_HALF, VT_EXR_HALF, VT_EXR_HALF, VT_EXR_FLOAT};
    vt_exr_channel ch[4];
    for (int c = 0; c < 4; c++)
        ch[c] = (vt_exr_channel){.name = names[c], .type = types[c], .data = px + c, .x_stride = 4,
                                 .y_stride = 4 * (ptrdiff_t)w};
    tdir t;
    tdir_make(&t, "vt_exr_test");
    write_ok(tdir_file(&t, "rgba.exr"), w, h, ch, 4, VT_EXR_PIZ);
    for (int c = 0; c < 4; c++) {
        float *out = read_all(t.path, names[c], w, h);
        for (size_t i = 0; i < (size_t)w * h; i++) {
            float s = px[i * 4 + (size_t)c];
            assert_true(same_float(out[i], types[c] == VT_EXR_HALF ? ref_round(s) : s));
        }
        free(out);
    }
    const char *sorted[4] = {"A", "B", "G", "R"};
    const vt_exr_type sorted_types[4] = {VT_EXR_FLOAT, VT_EXR_HALF, VT_EXR_HALF, VT_EXR_HALF};
    check_exrheader(t.path, w, h, sorted, sorted_types, 4, "piz");
    free(px);
    tdir_remove(&t);
}

/* Each compression, half and float, on sizes that end in a partial chunk
 * (ZIP groups 16 rows, PIZ 32), seven channels in reverse name order. */
static void test_exr_every_compression(void **state)
{
    (void)state;
    static const struct { vt_exr_compression c; const char *name; } comps[] = {
        {VT_EXR_NONE, "none"},
        {VT_EXR_ZIP, "zip, multi-scanline blocks"},
        {VT_EXR_ZIPS, "zip, individual scanlines"},
        {VT_EXR_PIZ, "piz"},
        {VT_EXR_RLE, "run-length encoding"},
    };
    static const uint32_t sizes[][2] = {{1, 1}, {3, 50}, {131, 67}};
    static const char *names[7] = {"c6", "c5", "c4", "c3", "c2", "c1", "c0"};
    rng r = {test_seed() ^ 0xC0DE};
    for (size_t s = 0; s < sizeof sizes / sizeof sizes[0]; s++) {
        uint32_t w = sizes[s][0], h = sizes[s][1];
        float *data = malloc((size_t)w * h * 7 * sizeof *data);
        assert_non_null(data);
        /* smooth, flat and noisy planes so every coder has work */
        for (uint32_t c = 0; c < 7; c++)
            for (size_t i = 0; i < (size_t)w * h; i++)
                data[c * (size_t)w * h + i] = c % 3 == 0   ? (float)(i % w) * 0.25f
                                              : c % 3 == 1 ? 1.5f
                                                           : any_float(&r);
        vt_exr_channel ch[7];
        vt_exr_type types[7];
        for (uint32_t c = 0; c < 7; c++) {
            types[c] = c % 2 ? VT_EXR_HALF : VT_EXR_FLOAT;
            ch[c] = planar(names[c], types[c], data + c * (size_t)w * h, w);
        }
        for (size_t k = 0; k < sizeof comps / sizeof comps[0]; k++) {
            tdir t;
            tdir_make(&t, "vt_exr_test");
            write_ok(tdir_file(&t, "c.exr"), w, h, ch, 7, comps[k].c);
            assert_int_equal(tdir_count(&t), 1);
            for (uint32_t c = 0; c < 7; c++) {
                float *out = read_all(t.path, names[c], w, h);
                for (size_t i = 0; i < (size_t)w * h; i++) {
                    float v = ch[c].data[i];
                    assert_true(same_float(out[i], types[c] == VT_EXR_HALF ? ref_round(v) : v));
                }
                free(out);
            }
            if (s == 2) {
                const char *sorted[7];
                vt_exr_type st[7];
                for (int c = 0; c < 7; c++) {
                    sorted[c] = names[6 - c];
                    st[c] = types[6 - c];
                }
                check_exrheader(t.path, w, h, sorted, st, 7, comps[k].name);
            }
            tdir_remove(&t);
        }
        free(data);
    }
}

/* 8192 wide, 8192 tall and (scale >= 1) 8192 x 8192, from one row
 * repeated (y_stride 0) so the source stays small. */
static void test_exr_large(void **state)
{
    (void)state;
    const uint32_t big = 8192;
    float *row = malloc(big * sizeof *row);
    assert_non_null(row);
    for (uint32_t x = 0; x < big; x++) row[x] = (float)x * 0.125f;
    const uint32_t dims[][2] = {{big, 3}, {2, big}, {big, test_scale() >= 1 ? big : 64}};
    for (size_t d = 0; d < 3; d++) {
        uint32_t w = dims[d][0], h = dims[d][1];
        vt_exr_channel ch = {.name = "Y", .type = VT_EXR_HALF, .data = row, .x_stride = 1, .y_stride = 0};
        tdir t;
        tdir_make(&t, "vt_exr_test");
        write_ok(tdir_file(&t, "big.exr"), w, h, &ch, 1, VT_EXR_ZIP);
        uint32_t rw, rh;
        assert_int_equal(vt_exr_size(t.path, &rw, &rh, NULL, 0), 0);
        assert_int_equal(rw, w);
        assert_int_equal(rh, h);
        float *out = read_all(t.path, "Y", w, h);
        for (uint32_t y = 0; y < h; y += (h > 64 ? 97 : 1))
            for (uint32_t x = 0; x < w; x++) assert_true(out[(size_t)y * w + x] == ref_round(row[x]));
        assert_true(out[(size_t)w * h - 1] == ref_round(row[w - 1]));
        free(out);
        tdir_remove(&t);
    }
    free(row);
}

/* Bad arguments: VT_ERR_INVALID, a message, nothing on disk. A row: the path,
 * the size, which channels (a good one, or one with a bad field), how
 * many, the compression. */
enum { CH_OK, CH_NONE, CH_DUP, CH_NONAME, CH_EMPTY_NAME, CH_LONG_NAME, CH_NODATA, CH_BADTYPE };

typedef struct bad_exr_args {
    const char *name;
    test_path path;
    uint32_t w, h;
    int ch, n, comp;
} bad_exr_args;

static const bad_exr_args bad_exr_args_rows[] = {
    {"no path", TPATH_NULL, 2, 2, CH_OK, 1, 0},
    {"empty path", TPATH_EMPTY, 2, 2, CH_OK, 1, 0},
    {"width 0", TPATH_FILE, 0, 2, CH_OK, 1, 0},
    {"height 0", TPATH_FILE, 2, 0, CH_OK, 1, 0},
    {"width past the limit", TPATH_FILE, VT_EXR_MAX_WIDTH + 1u, 2, CH_OK, 1, 0},
    {"no channels", TPATH_FILE, 2, 2, CH_NONE, 1, 0},
    {"0 channels", TPATH_FILE, 2, 2, CH_OK, 0, 0},
    {"the same channel twice", TPATH_FILE, 2, 2, CH_DUP, 2, 0},
    {"a channel without a name", TPATH_FILE, 2, 2, CH_NONAME, 1, 0},
    {"an empty channel name", TPATH_FILE, 2, 2, CH_EMPTY_NAME, 1, 0},
    {"a channel name of 32 bytes", TPATH_FILE, 2, 2, CH_LONG_NAME, 1, 0},
    {"a channel without data", TPATH_FILE, 2, 2, CH_NODATA, 1, 0},
    {"channel type 7", TPATH_FILE, 2, 2, CH_BADTYPE, 1, 0},
    {"compression 99", TPATH_FILE, 2, 2, CH_OK, 1, 99},
    {"compression -1", TPATH_FILE, 2, 2, CH_OK, 1, -1},
};

static void test_exr_bad_args(void **state)
{
    const bad_exr_args *r = *state;
    float v[4] = {1, 2, 3, 4};
    vt_exr_channel ch[2] = {planar("R", VT_EXR_HALF, v, 2), planar("R", VT_EXR_HALF, v, 2)};
    if (r->ch == CH_NONAME) ch[0].name = NULL;
    if (r->ch == CH_EMPTY_NAME) ch[0].name = "";
    if (r->ch == CH_LONG_NAME) ch[0].name = "abcdefghijklmnopqrstuvwxyz012345"; /* 32 bytes */
    if (r->ch == CH_NODATA) ch[0].data = NULL;
    if (r->ch == CH_BADTYPE) ch[0].type = (vt_exr_type)7;
    tdir t;
    tdir_make(&t, "vt_exr_test");
    char err[256] = "unchanged";
    int rc = vt_exr_write(tdir_path_arg(&t, r->path, "bad.exr"), r->w, r->h, r->ch == CH_NONE ? NULL : ch,
                          (uint32_t)r->n, (vt_exr_compression)r->comp, err, sizeof err);
    assert_int_equal(rc, VT_ERR_INVALID);
    assert_true(strlen(err) > 0 && strcmp(err, "unchanged") != 0);
    assert_int_equal(tdir_count(&t), 0);
    tdir_remove(&t);
}

/* NULL arguments, and tiny and absent error buffers. */
static void test_exr_null_args(void **state)
{
    (void)state;
    float v[4] = {1, 2, 3, 4};
    vt_exr_channel ok = planar("R", VT_EXR_HALF, v, 2);
    tdir t;
    tdir_make(&t, "vt_exr_test");
    const char *p = tdir_file(&t, "bad.exr");
    /* tiny and absent error buffers are fine */
    char tiny[4];
    assert_int_equal(vt_exr_write(p, 0, 2, &ok, 1, VT_EXR_NONE, tiny, sizeof tiny), VT_ERR_INVALID);
    assert_true(strlen(tiny) < sizeof tiny);
    assert_int_equal(vt_exr_write(p, 0, 2, &ok, 1, VT_EXR_NONE, NULL, 0), VT_ERR_INVALID);
    assert_int_equal(vt_exr_write(p, 0, 2, &ok, 1, VT_EXR_NONE, tiny, 0), VT_ERR_INVALID);
    float out[4];
    uint32_t w, h;
    assert_int_equal(vt_exr_read_channel(p, NULL, out, 2, 2, NULL, 0), VT_ERR_INVALID);
    assert_int_equal(vt_exr_read_channel(p, "R", NULL, 2, 2, NULL, 0), VT_ERR_INVALID);
    assert_int_equal(vt_exr_read_channel(NULL, "R", out, 2, 2, NULL, 0), VT_ERR_INVALID);
    assert_int_equal(vt_exr_size(p, NULL, &h, NULL, 0), VT_ERR_INVALID);
    assert_int_equal(vt_exr_size(NULL, &w, &h, NULL, 0), VT_ERR_INVALID);
    tdir_remove(&t);
}

static int write_one(const char *path, char *err, size_t errlen, void *ctx)
{
    float v = 1;
    vt_exr_channel ch = planar("R", VT_EXR_FLOAT, &v, 1);
    (void)ctx;
    return vt_exr_write(path, 1, 1, &ch, 1, VT_EXR_ZIP, err, errlen);
}

/* Unwritable places fail with the file system's errno and leave nothing. */
static void test_exr_bad_path(void **state)
{
    (void)state;
    tdir t;
    tdir_make(&t, "vt_exr_test");
    test_unwritable_paths(&t, write_one, NULL, ".exr");
    tdir_remove(&t);
}

typedef struct z_image {
    vt_exr_channel ch;
    uint32_t w, h;
} z_image;

static int write_z(const char *path, char *err, size_t errlen, void *ctx)
{
    const z_image *z = ctx;
    return vt_exr_write(path, z->w, z->h, &z->ch, 1, VT_EXR_NONE, err, errlen);
}

/* A write cut short by RLIMIT_FSIZE (in a child, SIGXFSZ ignored) fails
 * with EFBIG, removes its temporary file and leaves the old file whole. */
static void test_exr_failed_write_keeps_old(void **state)
{
    (void)state;
    uint32_t w = 256, h = 256;
    float *a = malloc((size_t)w * h * sizeof *a);
    assert_non_null(a);
    for (size_t i = 0; i < (size_t)w * h; i++) a[i] = (float)i;
    vt_exr_channel ch = planar("Z", VT_EXR_FLOAT, a, w);
    tdir t;
    tdir_make(&t, "vt_exr_test");
    write_ok(tdir_file(&t, "old.exr"), 4, 4, &ch, 1, VT_EXR_NONE);
    test_write_past_fsize(write_z, t.path, &(z_image){ch, w, h});
    assert_int_equal(tdir_count(&t), 1);
    float *out = read_all(t.path, "Z", 4, 4);
    for (uint32_t y = 0; y < 4; y++)
        for (uint32_t x = 0; x < 4; x++) assert_true(out[y * 4 + x] == a[y * w + x]);
    free(out);
    free(a);
    tdir_remove(&t);
}

/* The reader's errors: no file, not an EXR, truncated, no such channel,
 * wrong size. */
static void test_exr_reader_errors(void **state)
{
    (void)state;
    uint32_t w = 40, h = 40;
    float *a = calloc((size_t)w * h, sizeof *a), *out = calloc((size_t)w * h, sizeof *out);
    assert_true(a && out);
    for (size_t i = 0; i < (size_t)w * h; i++) a[i] = (float)(i % 17);
    vt_exr_channel ch = planar("Z", VT_EXR_FLOAT, a, w);
    char err[512];
    uint32_t rw, rh;
    tdir t;
    tdir_make(&t, "vt_exr_test");
    assert_int_equal(vt_exr_read_channel(tdir_file(&t, "none.exr"), "Z", out, w, h, err, sizeof err), VT_ERR_NOT_FOUND);
    assert_int_equal(vt_exr_size(t.path, &rw, &rh, err, sizeof err), VT_ERR_NOT_FOUND);
    FILE *f = fopen(tdir_file(&t, "text.exr"), "w");
    assert_non_null(f);
    fputs("this is not an OpenEXR file, just some text long enough to be a header\n", f);
    fclose(f);
    assert_int_equal(vt_exr_size(t.path, &rw, &rh, err, sizeof err), VT_ERR_CORRUPT);
    assert_non_null(strstr(err, t.path));
    write_ok(tdir_file(&t, "z.exr"), w, h, &ch, 1, VT_EXR_ZIPS);
    assert_int_equal(vt_exr_read_channel(t.path, "Q", out, w, h, err, sizeof err), VT_ERR_NOT_FOUND);
    assert_non_null(strstr(err, "'Q'"));
    assert_int_equal(vt_exr_read_channel(t.path, "Z", out, w, h + 1, err, sizeof err), VT_ERR_INVALID);
    /* cut the file in half: an error, never a crash or a read past out */
    struct stat st;
    assert_int_equal(stat(t.path, &st), 0);
    assert_int_equal(truncate(t.path, st.st_size / 2), 0);
    assert_true(vt_exr_read_channel(t.path, "Z", out, w, h, err, sizeof err) < 0);
    assert_true(strlen(err) > 0);
    free(out);
    free(a);
    tdir_remove(&t);
}

/* Threads writing at once, some failing in the library: each error lands in
 * its own thread's buffer, every good file reads back right. (A race here
 * shows only sometimes; a shared error pointer fails about one run in three.) */
static void *exr_thread_main(void *arg)
{
    test_thread *a = arg;
    uint32_t w = 48, h = 37;
    float *px = malloc((size_t)w * h * sizeof *px), *out = malloc((size_t)w * h * sizeof *out);
    char path[400], junk[400], err[512];
    snprintf(path, sizeof path, "%s/t%d.exr", a->t->dir, a->id);
    snprintf(junk, sizeof junk, "%s/junk%d.exr", a->t->dir, a->id);
    if (!px || !out) a->failures++;
    for (int it = 0; it < 20 && px && out; it++) {
        for (size_t i = 0; i < (size_t)w * h; i++) px[i] = (float)(a->id * 100000 + it * 1000) + (float)i;
        vt_exr_channel ch = planar("V", VT_EXR_FLOAT, px, w);
        if (vt_exr_write(path, w, h, &ch, 1, (vt_exr_compression)(it % 5), err, sizeof err) != 0 ||
            vt_exr_read_channel(path, "V", out, w, h, err, sizeof err) != 0 ||
            memcmp(out, px, (size_t)w * h * sizeof *px) != 0)
            a->failures++;
        /* library-reported errors: each message must name this thread's file */
        uint32_t rw, rh;
        for (int k = 0; k < 50; k++)
            a->failures += !test_refused_naming(vt_exr_size(junk, &rw, &rh, err, sizeof err), err, junk);
    }
    free(px);
    free(out);
    return NULL;
}

static void test_exr_threads(void **state)
{
    (void)state;
    test_threads_in_tdir("vt_exr_test", ".exr", exr_thread_main, 4, 2);
}

const struct CMUnitTest exr_tests[] = {
    cmocka_unit_test(test_exr_float_exact),
    cmocka_unit_test(test_exr_half_rounding),
    cmocka_unit_test(test_exr_half_representable_exact),
    cmocka_unit_test(test_exr_half_precision),
    cmocka_unit_test(test_exr_negative_stride),
    cmocka_unit_test(test_exr_interleaved_rgba),
    cmocka_unit_test(test_exr_every_compression),
    cmocka_unit_test(test_exr_large),
    TEST_ROWS(test_exr_bad_args, bad_exr_args_rows),
    cmocka_unit_test(test_exr_null_args),
    cmocka_unit_test(test_exr_bad_path),
    cmocka_unit_test(test_exr_failed_write_keeps_old),
    cmocka_unit_test(test_exr_reader_errors),
    cmocka_unit_test(test_exr_threads),
};
const size_t exr_tests_count = sizeof exr_tests / sizeof exr_tests[0];

#else
typedef int vt_test_exr_not_built; /* render/ not on the include path */
#endif
