/*
 * test_image.c — tone mapping, PNG and JPEG (render/vt_image.h) against
 * slow references: the sRGB8 encoding equals a long double powl
 * evaluation of the IEC 61966-2-1 formula on a dense sweep of 65536
 * values, at every rounding threshold (recomputed here by bisection) and
 * the floats either side of it, around the 0.0031308 breakpoint, and on
 * every float in [2^-14, 1]; the ACES curve is monotone and matches its
 * formula; layouts (planar, interleaved, bottom-up, grey, repeated) and
 * NaN / inf pixels tone-map as documented; PNG round-trips exactly (with
 * and without alpha, odd sizes, padded rows, every level) and an
 * independent zlib-based reader in Python agrees byte for byte; the PNG
 * reader converts grey, 16-bit and palette files built here by hand; JPEG
 * of a smooth gradient comes back at the right size within a PSNR bound
 * (>= 44 dB at quality 85, >= 46 dB at 95), and in-memory bytes equal the
 * file's; bad arguments, paths and sizes fail with nothing left on disk;
 * a write cut short (RLIMIT_FSIZE) keeps the old file; threads keep their
 * own error messages.
 *
 * Compiles to nothing until the build puts render/ on the include path
 * (as test_exr.c does); once test_main.c lists image_tests, a missing
 * include path is a link error, not a silent skip.
 */
#include "test_util.h"

#if defined(__has_include)
#if __has_include("vt_image.h")
#define VT_TEST_IMAGE 1
#endif
#endif

#ifdef VT_TEST_IMAGE
#include "vt_image.h"

#include <dirent.h>
#include <errno.h>
#include <pthread.h>
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <signal.h>
#include <stdbool.h>
#include <stdio.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

TEST_GROUP(image_tests)

/* ---- reference sRGB ----------------------------------------------------- */

/* IEC 61966-2-1, in long double. */
static long double ref_oetf(long double x)
{
    return x <= 0.0031308L ? 12.92L * x : 1.055L * powl(x, 1.0L / 2.4L) - 0.055L;
}

/* round(255 * oetf(v)), half up, v clamped to [0, 1], NaN -> 0. */
static int ref_srgb8(float v)
{
    if (!(v > 0)) return 0;
    if (v >= 1) return 255;
    return (int)floorl(255.0L * ref_oetf(v) + 0.5L);
}

static float float_of(uint32_t bits)
{
    float f;
    memcpy(&f, &bits, sizeof f);
    return f;
}

static uint32_t bits_of(float f)
{
    uint32_t b;
    memcpy(&b, &f, sizeof b);
    return b;
}

/* t[k], k = 1..255: the smallest float v in (0, 1] with ref_srgb8(v) >= k,
 * by bisection over bit patterns (ref_srgb8 is monotone on them). */
static void ref_thresholds(float t[256])
{
    t[0] = 0.0f;
    for (int k = 1; k < 256; k++) {
        uint32_t lo = 0, hi = bits_of(1.0f);
        while (hi - lo > 1) {
            uint32_t mid = lo + (hi - lo) / 2;
            if (ref_srgb8(float_of(mid)) >= k) hi = mid;
            else lo = mid;
        }
        t[k] = float_of(hi);
    }
}

static void write_bytes(const char *path, const void *p, size_t n)
{
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(p, 1, n, f), n);
    assert_int_equal(fclose(f), 0);
}

/* ---- image helpers ------------------------------------------------------ */

/* h rows of stride random bytes (padding included) */
static uint8_t *random_rgba(rng *r, uint32_t h, size_t stride)
{
    uint8_t *p = malloc(stride * h);
    assert_non_null(p);
    for (size_t i = 0; i < stride * h; i++) p[i] = (uint8_t)rng_u64(r);
    return p;
}

/* A smooth gradient, RGB or RGBX (X = 0x5a). */
static uint8_t *gradient(uint32_t w, uint32_t h, uint32_t bpp)
{
    uint8_t *p = malloc((size_t)w * h * bpp);
    assert_non_null(p);
    for (uint32_t y = 0; y < h; y++)
        for (uint32_t x = 0; x < w; x++) {
            uint8_t *q = p + ((size_t)y * w + x) * bpp;
            double u = w > 1 ? (double)x / (w - 1) : 0, v = h > 1 ? (double)y / (h - 1) : 0;
            q[0] = (uint8_t)lround(255 * u);
            q[1] = (uint8_t)lround(255 * v);
            q[2] = (uint8_t)lround(255 * (0.25 + 0.5 * u * v));
            if (bpp == 4) q[3] = 0x5a;
        }
    return p;
}

static void png_write_ok(const char *path, uint32_t w, uint32_t h, const uint8_t *px, size_t stride,
                         bool alpha, int level)
{
    char err[512];
    int rc = vt_png_write(path, w, h, px, stride, alpha, level, err, sizeof err);
    if (rc) print_message("png write: %d %s\n", rc, err);
    assert_int_equal(rc, 0);
    assert_string_equal(err, "");
}

/* Reads path back and checks it equals px (alpha, or A = 255). */
static void png_check(const char *path, uint32_t w, uint32_t h, const uint8_t *px, size_t stride,
                      bool alpha)
{
    uint8_t *got = NULL;
    uint32_t rw = 0, rh = 0;
    bool ra = !alpha;
    char err[512];
    int rc = vt_png_read(path, &got, &rw, &rh, &ra, err, sizeof err);
    if (rc) print_message("png read: %d %s\n", rc, err);
    assert_int_equal(rc, 0);
    assert_string_equal(err, "");
    assert_int_equal(rw, w);
    assert_int_equal(rh, h);
    assert_int_equal(ra, alpha);
    for (uint32_t y = 0; y < h; y++)
        for (uint32_t x = 0; x < w; x++) {
            const uint8_t *s = px + (size_t)y * stride + (size_t)x * 4, *g = got + ((size_t)y * w + x) * 4;
            assert_memory_equal(g, s, 3);
            assert_int_equal(g[3], alpha ? s[3] : 255);
        }
    free(got);
}

static double psnr_rgb(const uint8_t *a, const uint8_t *b, size_t n_bytes)
{
    double se = 0;
    for (size_t i = 0; i < n_bytes; i++) se += ((double)a[i] - b[i]) * ((double)a[i] - b[i]);
    return se == 0 ? INFINITY : 10 * log10(255.0 * 255.0 * (double)n_bytes / se);
}

/* ---- tools that may be absent ------------------------------------------------ */

static bool have_tool(const char *name)
{
    char cmd[128];
    snprintf(cmd, sizeof cmd, "command -v %s >/dev/null 2>&1", name);
    return system(cmd) == 0;
}

/* `file -b path` contains want (skipped, saying so, without file(1)). */
static void check_file_says(const char *path, const char *want)
{
    if (!have_tool("file") || strchr(path, '\'')) {
        print_message("file(1) not usable: type check skipped\n");
        return;
    }
    char cmd[700], line[512] = "";
    snprintf(cmd, sizeof cmd, "file -b '%s'", path);
    FILE *p = popen(cmd, "r");
    assert_non_null(p);
    if (!fgets(line, sizeof line, p)) line[0] = '\0';
    assert_int_equal(pclose(p), 0);
    if (!strstr(line, want)) print_message("file says '%s', want '%s'\n", line, want);
    assert_non_null(strstr(line, want));
}

/* A PNG reader in Python with only zlib: checks the signature and every
 * chunk's CRC, undoes the five filters, writes the raw rows to argv[2] and
 * prints "width height colour-type chunk-names". */
static const char py_png[] =
    "import sys, zlib, struct\n"
    "d = open(sys.argv[1], 'rb').read()\n"
    "assert d[:8] == b'\\x89PNG\\r\\n\\x1a\\n'\n"
    "pos, idat, names, ihdr = 8, b'', [], None\n"
    "while pos < len(d):\n"
    "    n, = struct.unpack('>I', d[pos:pos+4]); t = d[pos+4:pos+8]; body = d[pos+8:pos+8+n]\n"
    "    crc, = struct.unpack('>I', d[pos+8+n:pos+12+n])\n"
    "    assert zlib.crc32(t + body) & 0xffffffff == crc, 'crc'\n"
    "    names.append(t.decode())\n"
    "    if t == b'IHDR': ihdr = struct.unpack('>IIBBBBB', body)\n"
    "    if t == b'IDAT': idat += body\n"
    "    pos += 12 + n\n"
    "    if t == b'IEND': break\n"
    "assert pos == len(d), 'trailing bytes'\n"
    "w, h, depth, ct, comp, filt, inter = ihdr\n"
    "assert depth == 8 and ct in (2, 6) and comp == 0 and filt == 0 and inter == 0\n"
    "bpp = 4 if ct == 6 else 3\n"
    "raw = zlib.decompress(idat); stride = w * bpp\n"
    "assert len(raw) == h * (stride + 1), 'size'\n"
    "out = bytearray(); prev = bytearray(stride)\n"
    "for y in range(h):\n"
    "    f = raw[y * (stride + 1)]; line = bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])\n"
    "    for i in range(stride):\n"
    "        a = line[i - bpp] if i >= bpp else 0; b = prev[i]; c = prev[i - bpp] if i >= bpp else 0\n"
    "        if f == 0: p = 0\n"
    "        elif f == 1: p = a\n"
    "        elif f == 2: p = b\n"
    "        elif f == 3: p = (a + b) // 2\n"
    "        elif f == 4:\n"
    "            pa, pb, pc = abs(b - c), abs(a - c), abs(a + b - 2 * c)\n"
    "            p = a if pa <= pb and pa <= pc else (b if pb <= pc else c)\n"
    "        else: raise SystemExit('filter %d' % f)\n"
    "        line[i] = (line[i] + p) & 255\n"
    "    out += line; prev = line\n"
    "open(sys.argv[2], 'wb').write(out)\n"
    "print(w, h, ct, ' '.join(names))\n";

/* Python's reading of path must equal px (RGB or RGBA rows). */
static void check_python_png(tdir *t, const char *path, uint32_t w, uint32_t h, const uint8_t *px,
                             size_t stride, bool alpha)
{
    if (!have_tool("python3") || strchr(path, '\'') || strchr(t->dir, '\'')) {
        print_message("python3 not usable: independent PNG check skipped\n");
        return;
    }
    char script[400], raw[400], cmd[1400], line[512] = "";
    snprintf(script, sizeof script, "%s/png_check.py", t->dir);
    snprintf(raw, sizeof raw, "%s/png_check.raw", t->dir);
    write_bytes(script, py_png, sizeof py_png - 1);
    snprintf(cmd, sizeof cmd, "python3 '%s' '%s' '%s' 2>&1", script, path, raw);
    FILE *p = popen(cmd, "r");
    assert_non_null(p);
    if (!fgets(line, sizeof line, p)) line[0] = '\0';
    int status = pclose(p);
    if (status != 0) print_message("python: %s\n", line);
    assert_int_equal(status, 0);
    unsigned pw = 0, ph = 0, ct = 0;
    assert_int_equal(sscanf(line, "%u %u %u", &pw, &ph, &ct), 3);
    assert_int_equal(pw, w);
    assert_int_equal(ph, h);
    assert_int_equal(ct, alpha ? 6 : 2);
    assert_non_null(strstr(line, "IHDR sRGB IDAT"));
    size_t n = 0;
    uint8_t *got = test_slurp(raw, &n);
    uint32_t bpp = alpha ? 4 : 3;
    assert_int_equal(n, (size_t)w * h * bpp);
    for (uint32_t y = 0; y < h; y++)
        for (uint32_t x = 0; x < w; x++)
            assert_memory_equal(got + ((size_t)y * w + x) * bpp, px + (size_t)y * stride + x * 4, bpp);
    free(got);
    unlink(script);
    unlink(raw);
}

/* ---- hand-made PNGs (stored deflate) for the reader ------------------------- */

static uint32_t crc32_of(uint32_t crc, const uint8_t *p, size_t n)
{
    crc = ~crc;
    for (size_t i = 0; i < n; i++) {
        crc ^= p[i];
        for (int k = 0; k < 8; k++) crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1)));
    }
    return ~crc;
}

typedef struct bytes {
    uint8_t b[1 << 16];
    size_t n;
} bytes;

static void put(bytes *o, const void *p, size_t n)
{
    assert_true(o->n + n <= sizeof o->b);
    if (n) memcpy(o->b + o->n, p, n);
    o->n += n;
}

static void put32(bytes *o, uint32_t v)
{
    uint8_t b[4] = {(uint8_t)(v >> 24), (uint8_t)(v >> 16), (uint8_t)(v >> 8), (uint8_t)v};
    put(o, b, 4);
}

static void chunk(bytes *o, const char *type, const uint8_t *data, size_t n)
{
    put32(o, (uint32_t)n);
    size_t at = o->n;
    put(o, type, 4);
    put(o, data, n);
    put32(o, crc32_of(0, o->b + at, n + 4));
}

/* A PNG of the given header whose image data are `raw` (filter bytes
 * included), deflated as stored blocks. */
static void make_png(bytes *o, uint32_t w, uint32_t h, uint8_t depth, uint8_t ctype,
                     const uint8_t *plte, size_t nplte, const uint8_t *trns, size_t ntrns,
                     const uint8_t *raw, size_t nraw)
{
    static const uint8_t sig[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
    uint8_t ihdr[13] = {(uint8_t)(w >> 24), (uint8_t)(w >> 16), (uint8_t)(w >> 8), (uint8_t)w,
                        (uint8_t)(h >> 24), (uint8_t)(h >> 16), (uint8_t)(h >> 8), (uint8_t)h,
                        depth, ctype, 0, 0, 0};
    o->n = 0;
    put(o, sig, 8);
    chunk(o, "IHDR", ihdr, 13);
    if (plte) chunk(o, "PLTE", plte, nplte);
    if (trns) chunk(o, "tRNS", trns, ntrns);
    static uint8_t z[1 << 15];
    size_t zn = 0;
    z[zn++] = 0x78;
    z[zn++] = 0x01;
    assert_true(nraw < 65535 && nraw + 16 < sizeof z);
    z[zn++] = 1; /* final stored block */
    z[zn++] = (uint8_t)nraw;
    z[zn++] = (uint8_t)(nraw >> 8);
    z[zn++] = (uint8_t)~nraw;
    z[zn++] = (uint8_t)(~nraw >> 8);
    memcpy(z + zn, raw, nraw);
    zn += nraw;
    uint32_t s1 = 1, s2 = 0;
    for (size_t i = 0; i < nraw; i++) {
        s1 = (s1 + raw[i]) % 65521;
        s2 = (s2 + s1) % 65521;
    }
    uint32_t adler = s2 << 16 | s1;
    uint8_t ab[4] = {(uint8_t)(adler >> 24), (uint8_t)(adler >> 16), (uint8_t)(adler >> 8), (uint8_t)adler};
    memcpy(z + zn, ab, 4);
    zn += 4;
    chunk(o, "IDAT", z, zn);
    chunk(o, "IEND", NULL, 0);
}

/* ---- sRGB tests --------------------------------------------------------------- */

/* 65536 evenly spaced values in [0, 1], 65536 log-spaced over [1e-7, 2],
 * and the special values. */
static void test_image_srgb_sweep(void **state)
{
    (void)state;
    size_t bad = 0;
    for (uint32_t i = 0; i < 65536; i++) {
        float v[2] = {(float)i / 65535.0f, (float)(1e-7 * pow(2e7, i / 65535.0))};
        for (int j = 0; j < 2; j++)
            if (vt_srgb8_from_linear(v[j]) != ref_srgb8(v[j]) && bad++ < 5)
                print_message("%a -> %d, reference %d\n", (double)v[j], vt_srgb8_from_linear(v[j]),
                              ref_srgb8(v[j]));
    }
    assert_int_equal(bad, 0);
    const struct { float v; int want; } special[] = {
        {NAN, 0}, {-NAN, 0}, {INFINITY, 255}, {-INFINITY, 0}, {0.0f, 0}, {-0.0f, 0},
        {-1.0f, 0}, {-FLT_MAX, 0}, {FLT_TRUE_MIN, 0}, {FLT_MIN, 0}, {1.0f, 255},
        {nextafterf(1.0f, 0), 255}, {1.5f, 255}, {FLT_MAX, 255}, {0.5f, 188},
        {0.18f, 118}, {0.0031308f, 10}, {0.21586f, 128}, /* mid grey */
    };
    for (size_t i = 0; i < sizeof special / sizeof special[0]; i++) {
        assert_int_equal(vt_srgb8_from_linear(special[i].v), special[i].want);
        assert_int_equal(ref_srgb8(special[i].v), special[i].want);
    }
}

/* Every rounding threshold and the float below it; floats around the
 * linear/power breakpoint; then every float in [2^-14, 1] (every 61st
 * under VANTAGE_TEST_SCALE < 1) against the thresholds. */
static void test_image_srgb_thresholds(void **state)
{
    (void)state;
    float t[256];
    ref_thresholds(t);
    for (int k = 1; k < 256; k++) {
        assert_int_equal(vt_srgb8_from_linear(t[k]), k);
        assert_int_equal(vt_srgb8_from_linear(nextafterf(t[k], 0)), k - 1);
        assert_true(t[k] > t[k - 1]);
    }
    float bp = 0.0031308f;
    for (int i = 0; i < 64; i++) {
        assert_int_equal(vt_srgb8_from_linear(bp), ref_srgb8(bp));
        bp = nextafterf(bp, 1.0f);
    }
    bp = 0.0031308f;
    for (int i = 0; i < 64; i++) {
        assert_int_equal(vt_srgb8_from_linear(bp), ref_srgb8(bp));
        bp = nextafterf(bp, 0.0f);
    }
    /* exhaustive: code(v) = number of thresholds <= v */
    uint32_t step = test_scale() >= 1 ? 1 : 61;
    uint32_t lo = bits_of(0x1p-14f), hi = bits_of(1.0f);
    int k = 0;
    size_t bad = 0;
    for (uint32_t b = lo; b <= hi; b += step) {
        float v = float_of(b);
        while (k < 255 && v >= t[k + 1]) k++;
        if (vt_srgb8_from_linear(v) != k && bad++ < 5)
            print_message("%a -> %d, want %d\n", (double)v, vt_srgb8_from_linear(v), k);
    }
    assert_int_equal(bad, 0);
    assert_int_equal(k, 255);
}

/* ---- tone curve tests --------------------------------------------------------- */

static long double ref_aces(long double x)
{
    long double y = (x * (2.51L * x + 0.03L)) / (x * (2.43L * x + 0.59L) + 0.14L);
    return y < 0 ? 0 : y > 1 ? 1 : y;
}

static void test_image_tonemap_curve(void **state)
{
    (void)state;
    /* known values */
    assert_true(vt_tonemap_curve(VT_TONEMAP_ACES, 0.0f) == 0.0f);
    assert_true(fabs(vt_tonemap_curve(VT_TONEMAP_ACES, 1.0f) - 2.54 / 3.16) < 1e-7);
    assert_true(fabs(vt_tonemap_curve(VT_TONEMAP_ACES, 0.18f) - 0.2669) < 1e-3);
    assert_true(vt_tonemap_curve(VT_TONEMAP_ACES, 7.25f) == 1.0f);
    assert_true(vt_tonemap_curve(VT_TONEMAP_ACES, 7.2f) < 1.0f);
    assert_true(vt_tonemap_curve(VT_TONEMAP_ACES, 1e30f) == 1.0f);
    const vt_tonemap_op ops[2] = {VT_TONEMAP_CLAMP, VT_TONEMAP_ACES};
    for (int o = 0; o < 2; o++) {
        assert_true(vt_tonemap_curve(ops[o], NAN) == 0.0f);
        assert_true(vt_tonemap_curve(ops[o], INFINITY) == 1.0f);
        assert_true(vt_tonemap_curve(ops[o], -INFINITY) == 0.0f);
        assert_true(vt_tonemap_curve(ops[o], -0.5f) == 0.0f);
        assert_true(vt_tonemap_curve(ops[o], FLT_MAX) == 1.0f);
    }
    rng r = {test_seed() ^ 0xAC35};
    for (int i = 0; i < 100000; i++) {
        float x = (float)rng_range(&r, 0, 1.5);
        assert_true(vt_tonemap_curve(VT_TONEMAP_CLAMP, x) == (x > 1 ? 1.0f : x));
        x = (float)rng_log(&r, 1e-9, 1e3);
        long double want = ref_aces(x);
        assert_true(fabsl(vt_tonemap_curve(VT_TONEMAP_ACES, x) - want) <= want * 0x1p-23L + 1e-45L);
    }
    /* monotone over a log sweep, float outputs and 8-bit codes */
    float prev = 0.0f;
    int prev8 = 0;
    for (int i = 0; i <= 200000; i++) {
        float x = (float)(1e-8 * pow(1e11, i / 200000.0));
        float y = vt_tonemap_curve(VT_TONEMAP_ACES, x);
        int y8 = vt_srgb8_from_linear(y);
        assert_true(y >= prev);
        assert_true(y8 >= prev8);
        prev = y;
        prev8 = y8;
    }
    assert_int_equal(prev8, 255);
}

/* ---- tone mapping tests -------------------------------------------------------- */

static void tonemap_ok(uint32_t w, uint32_t h, const vt_image_src *src, const vt_tonemap_desc *d,
                       uint8_t *out, size_t stride)
{
    assert_int_equal(vt_image_tonemap(w, h, src, d, out, stride), 0);
}

/* Interleaved RGBA, CLAMP at 0 EV: each byte is vt_srgb8_from_linear of
 * the sample, alpha rounded; NaN / inf handled; row padding untouched. */
static void test_image_tonemap_exact(void **state)
{
    (void)state;
    rng r = {test_seed() ^ 0x70E};
    uint32_t w = 67, h = 29;
    size_t stride = (size_t)w * 4 + 9;
    float *px = malloc((size_t)w * h * 4 * sizeof *px);
    uint8_t *out = malloc(stride * h);
    assert_true(px && out);
    static const float odd[] = {NAN, INFINITY, -INFINITY, -0.0f, -1.0f, 2.0f, FLT_MAX, FLT_TRUE_MIN};
    for (size_t i = 0; i < (size_t)w * h * 4; i++)
        px[i] = rng_below(&r, 8) == 0 ? odd[rng_below(&r, 8)] : (float)rng_range(&r, -0.1, 1.1);
    /* alpha exactly at k/255 and at the halfway points either side */
    for (int k = 0; k < 255 && (size_t)k * 3 + 2 < (size_t)w * h; k++) {
        float mid = (float)((k + 0.5) / 255);
        px[((size_t)k * 3) * 4 + 3] = (float)k / 255.0f;
        px[((size_t)k * 3 + 1) * 4 + 3] = nextafterf(mid, 0);
        px[((size_t)k * 3 + 2) * 4 + 3] = nextafterf(mid, 1);
    }
    memset(out, 0xEE, stride * h);
    vt_image_src src = {
        .r = {px + 0, 4, 4 * (ptrdiff_t)w}, .g = {px + 1, 4, 4 * (ptrdiff_t)w},
        .b = {px + 2, 4, 4 * (ptrdiff_t)w}, .a = {px + 3, 4, 4 * (ptrdiff_t)w},
    };
    tonemap_ok(w, h, &src, NULL, out, stride);
    for (uint32_t y = 0; y < h; y++) {
        for (uint32_t x = 0; x < w; x++) {
            const float *s = px + ((size_t)y * w + x) * 4;
            const uint8_t *o = out + y * stride + x * 4;
            for (int c = 0; c < 3; c++) assert_int_equal(o[c], ref_srgb8(s[c]));
            float a = s[3];
            int want = !(a > 0) ? 0 : a >= 1 ? 255 : (int)floorl((long double)a * 255 + 0.5L);
            assert_int_equal(o[3], want);
        }
        for (size_t p = (size_t)w * 4; p < stride; p++) assert_int_equal(out[y * stride + p], 0xEE);
    }
    for (int k = 0; k < 255 && (size_t)k * 3 + 2 < (size_t)w * h; k++) {
        assert_int_equal(out[(k * 3) / w * stride + (k * 3) % w * 4 + 3], k);
        assert_int_equal(out[(k * 3 + 1) / w * stride + (k * 3 + 1) % w * 4 + 3], k);
        assert_int_equal(out[(k * 3 + 2) / w * stride + (k * 3 + 2) % w * 4 + 3], k + 1);
    }
    free(out);
    free(px);
}

/* The bits of the first float in [lo, hi) whose ACES code (the curve,
 * then the exact sRGB table) is >= k, by bisection. */
static uint32_t aces_first_bits(unsigned k, uint32_t lo, uint32_t hi)
{
    while (lo < hi) {
        uint32_t m = lo + (hi - lo) / 2;
        float x;
        memcpy(&x, &m, sizeof x);
        if (vt_srgb8_from_linear(vt_tonemap_curve(VT_TONEMAP_ACES, x)) >= k) hi = m;
        else lo = m + 1;
    }
    return lo;
}

/* ACES at 0 EV through the image path (a threshold table) equals the curve
 * then the sRGB table, code for code, for floats spread over every
 * exponent from 2^-14 to 32 (each threshold's neighbours included). */
static void test_image_tonemap_aces_table(void **state)
{
    (void)state;
    const uint32_t lo = 0x38800000u, hi = 0x42000000u, step = 61, w = 4096;
    uint32_t n = ((hi - lo) / step + 1) / w * w;
    float *px = malloc((size_t)n * sizeof *px);
    uint8_t *out = malloc((size_t)n * 4);
    assert_true(px && out);
    for (uint32_t i = 0; i < n; i++) {
        uint32_t bits = lo + i * step;
        memcpy(&px[i], &bits, sizeof bits);
    }
    vt_image_src src = {.r = {px, 1, w}};
    tonemap_ok(w, n / w, &src, &(vt_tonemap_desc){.op = VT_TONEMAP_ACES}, out, (size_t)w * 4);
    uint32_t bad = 0;
    for (uint32_t i = 0; i < n; i++)
        bad += out[i * 4] != vt_srgb8_from_linear(vt_tonemap_curve(VT_TONEMAP_ACES, px[i]));
    /* and around each code's first float, found by bisection here */
    for (unsigned k = 1; k < 256; k++) {
        uint32_t a = aces_first_bits(k, lo, hi);
        float t[3];
        uint32_t tb[3] = {a - 1, a, a + 1};
        memcpy(t, tb, sizeof t);
        uint8_t o3[12];
        vt_image_src s3 = {.r = {t, 1, 0}};
        tonemap_ok(3, 1, &s3, &(vt_tonemap_desc){.op = VT_TONEMAP_ACES}, o3, 12);
        for (int j = 0; j < 3; j++) bad += o3[j * 4] != vt_srgb8_from_linear(vt_tonemap_curve(VT_TONEMAP_ACES, t[j]));
        bad += o3[0] != k - 1 || o3[4] != k;
    }
    assert_int_equal(bad, 0);
    free(px);
    free(out);
}

/* The daemon's layout (interleaved RGB in RGBA floats, no alpha, ACES,
 * bottom-up rows) has its own lanes path: the same bytes as the planar
 * path (aces8 per channel, which test_image_tonemap_aces_table checks
 * against the curve) on a sweep of float bit patterns over every code's
 * range, specials (NaN, infinities, negatives, 0, the clamp's ends) and
 * three exposures; the buffer ends at the last pixel's blue (ASan: the
 * unused fourth float is never read). Then every code's first float and
 * its neighbours in that layout against the curve itself. */
static void test_image_tonemap_rgbx(void **state)
{
    (void)state;
    const uint32_t w = 97, h = 41, n = w * h;
    float *il = malloc(((size_t)n * 4 - 1) * sizeof *il), *pl = malloc((size_t)n * 3 * sizeof *pl);
    uint8_t *a = malloc((size_t)n * 4), *b = malloc((size_t)n * 4);
    assert_true(il && pl && a && b);
    const float specials[] = {NAN, INFINITY, -INFINITY, -1.0f, 0.0f, -0.0f, 0x1p-12f, 0x1.fffffep3f, 16.0f, 1e30f};
    const uint32_t lo = 0x38800000u, hi = 0x42000000u, step = (hi - lo) / (3 * n);
    for (uint32_t i = 0; i < 3 * n; i++) {
        uint32_t bits = lo + i * step;
        float v;
        memcpy(&v, &bits, sizeof v);
        if (i % 101 < sizeof specials / sizeof specials[0]) v = specials[i % 101];
        uint32_t y = i / 3 / w, x = i / 3 % w, c = i % 3;
        size_t at = ((size_t)(h - 1 - y) * w + x) * 4; /* bottom-up, as rendered */
        il[at + c] = v;
        if (c == 2 && at + 3 < (size_t)n * 4 - 1) il[at + 3] = NAN; /* x: ignored (none after the buffer's last) */
        pl[(size_t)c * n + (size_t)y * w + x] = v;
    }
    const float *top = il + (size_t)(h - 1) * w * 4;
    vt_image_src isrc = {.r = {top, 4, -4 * (ptrdiff_t)w}, .g = {top + 1, 4, -4 * (ptrdiff_t)w},
                         .b = {top + 2, 4, -4 * (ptrdiff_t)w}};
    vt_image_src psrc = {.r = {pl, 1, w}, .g = {pl + n, 1, w}, .b = {pl + 2 * (size_t)n, 1, w}};
    const float evs[] = {0, 3.7f, -5.25f};
    for (size_t e = 0; e < sizeof evs / sizeof evs[0]; e++) {
        vt_tonemap_desc d = {.op = VT_TONEMAP_ACES, .exposure_ev = evs[e]};
        tonemap_ok(w, h, &isrc, &d, a, (size_t)w * 4);
        tonemap_ok(w, h, &psrc, &d, b, (size_t)w * 4);
        assert_memory_equal(a, b, (size_t)n * 4);
    }
    /* each code's first float and its neighbours (the lanes' one
       comparison per bucket decides exactly there), in the interleaved
       layout, against the curve then the sRGB table; 8 a step plus a
       tail, so both the AVX2 rows and the SSE2 tail see them */
    const uint32_t nt = 3 * 255, wt = 101;
    float *t = calloc((size_t)4 * (nt + 2 * wt), sizeof *t);
    uint8_t *o = malloc((size_t)4 * (nt + 2 * wt));
    assert_true(t && o);
    uint32_t bad = 0, m = 0;
    for (unsigned k = 1; k < 256; k++) {
        uint32_t x0 = aces_first_bits(k, 0x38800000u, 0x42000000u);
        for (uint32_t dj = 0; dj < 3; dj++, m++) {
            uint32_t bits = x0 - 1 + dj;
            memcpy(&t[4 * (m / 3) + m % 3], &bits, sizeof bits);
        }
    }
    uint32_t rows = (nt / 3 + wt - 1) / wt;
    vt_image_src tsrc = {.r = {t, 4, 4 * (ptrdiff_t)wt}, .g = {t + 1, 4, 4 * (ptrdiff_t)wt}, .b = {t + 2, 4, 4 * (ptrdiff_t)wt}};
    tonemap_ok(wt, rows, &tsrc, &(vt_tonemap_desc){.op = VT_TONEMAP_ACES}, o, (size_t)wt * 4);
    for (uint32_t i = 0; i < (size_t)wt * rows; i++)
        for (int c = 0; c < 3; c++)
            bad += o[4 * i + c] != vt_srgb8_from_linear(vt_tonemap_curve(VT_TONEMAP_ACES, t[4 * i + c])) ||
                   o[4 * i + 3] != 255;
    assert_int_equal(bad, 0);
    free(t);
    free(o);
    free(il);
    free(pl);
    free(a);
    free(b);
}

/* Planar bottom-up source, grey, repeated rows, exposure, ACES and
 * premultiplied alpha give what the per-pixel formula says. */
static void test_image_tonemap_layouts(void **state)
{
    (void)state;
    uint32_t w = 13, h = 7;
    float *plane = malloc((size_t)w * h * 4 * sizeof *plane);
    uint8_t *a = malloc((size_t)w * h * 4), *b = malloc((size_t)w * h * 4);
    assert_true(plane && a && b);
    rng r = {test_seed() ^ 0x1A7};
    /* interleaved reference image */
    float *il = malloc((size_t)w * h * 4 * sizeof *il);
    assert_non_null(il);
    for (size_t i = 0; i < (size_t)w * h * 4; i++) il[i] = (float)rng_log(&r, 1e-4, 20);
    vt_image_src isrc = {.r = {il + 0, 4, 4 * (ptrdiff_t)w}, .g = {il + 1, 4, 4 * (ptrdiff_t)w},
                         .b = {il + 2, 4, 4 * (ptrdiff_t)w}, .a = {il + 3, 4, 4 * (ptrdiff_t)w}};
    /* the same as four bottom-up planes: image row y in memory row h-1-y */
    for (uint32_t y = 0; y < h; y++)
        for (uint32_t x = 0; x < w; x++)
            for (int c = 0; c < 4; c++)
                plane[(size_t)c * w * h + (size_t)(h - 1 - y) * w + x] = il[((size_t)y * w + x) * 4 + c];
    vt_image_src psrc;
    vt_image_channel *pc[4] = {&psrc.r, &psrc.g, &psrc.b, &psrc.a};
    for (int c = 0; c < 4; c++)
        *pc[c] = (vt_image_channel){plane + (size_t)c * w * h + (size_t)(h - 1) * w, 1, -(ptrdiff_t)w};
    const vt_tonemap_desc descs[] = {
        {0}, {.exposure_ev = 1.5f}, {.op = VT_TONEMAP_ACES}, {.op = VT_TONEMAP_ACES, .exposure_ev = -2.25f},
        {.op = VT_TONEMAP_ACES, .premultiplied = true},
    };
    for (size_t d = 0; d < sizeof descs / sizeof descs[0]; d++) {
        tonemap_ok(w, h, &isrc, &descs[d], a, (size_t)w * 4);
        tonemap_ok(w, h, &psrc, &descs[d], b, (size_t)w * 4);
        assert_memory_equal(a, b, (size_t)w * h * 4);
        for (size_t i = 0; i < (size_t)w * h; i++) {
            double k = exp2(descs[d].exposure_ev);
            if (descs[d].premultiplied) k /= il[i * 4 + 3];
            for (int c = 0; c < 3; c++) {
                float v = vt_tonemap_curve(descs[d].op, (float)((double)il[i * 4 + c] * k));
                /* the curve's float input may round differently from the
                 * double the pipeline uses: allow one code */
                assert_true(abs(a[i * 4 + c] - ref_srgb8(v)) <= 1);
            }
        }
    }
    /* exact exposure: +1 EV on x equals 0 EV on 2x (powers of two are exact) */
    for (size_t i = 0; i < (size_t)w * h * 4; i++) plane[i] = il[i] * 2;
    vt_image_src dbl = isrc;
    dbl.r.data = plane + 0, dbl.g.data = plane + 1, dbl.b.data = plane + 2, dbl.a.data = plane + 3;
    for (size_t i = 0; i < (size_t)w * h; i++) plane[i * 4 + 3] = il[i * 4 + 3];
    tonemap_ok(w, h, &isrc, &(vt_tonemap_desc){.exposure_ev = 1, .op = VT_TONEMAP_ACES}, a, (size_t)w * 4);
    tonemap_ok(w, h, &dbl, &(vt_tonemap_desc){.op = VT_TONEMAP_ACES}, b, (size_t)w * 4);
    assert_memory_equal(a, b, (size_t)w * h * 4);
    /* grey from R alone, one row repeated (y_stride 0), no alpha */
    vt_image_src grey = {.r = {il, 4, 0}};
    tonemap_ok(w, h, &grey, NULL, a, (size_t)w * 4);
    for (uint32_t y = 0; y < h; y++)
        for (uint32_t x = 0; x < w; x++) {
            const uint8_t *o = a + ((size_t)y * w + x) * 4;
            int want = ref_srgb8(il[x * 4]);
            assert_int_equal(o[0], want);
            assert_int_equal(o[1], want);
            assert_int_equal(o[2], want);
            assert_int_equal(o[3], 255);
        }
    /* premultiplied: 0.25 at alpha 0.5 is 0.5; alpha 0 and NaN give 0 */
    float pm[12] = {0.25f, 0.25f, 0.25f, 0.5f, 1.0f, 1.0f, 1.0f, 0.0f, 0.5f, 0.5f, 0.5f, NAN};
    vt_image_src ps = {.r = {pm + 0, 4, 12}, .g = {pm + 1, 4, 12}, .b = {pm + 2, 4, 12},
                       .a = {pm + 3, 4, 12}};
    uint8_t o3[12];
    tonemap_ok(3, 1, &ps, &(vt_tonemap_desc){.premultiplied = true}, o3, sizeof o3);
    const uint8_t want3[12] = {188, 188, 188, 128, 0, 0, 0, 0, 0, 0, 0, 0};
    assert_memory_equal(o3, want3, 12);
    free(il);
    free(a);
    free(b);
    free(plane);
}

static void test_image_tonemap_bad_args(void **state)
{
    (void)state;
    float v[4] = {0};
    uint8_t out[64];
    vt_image_src ok = {.r = {v, 1, 2}};
    vt_image_src only_g = {.r = {v, 1, 2}, .g = {v, 1, 2}};
    vt_image_src no_r = {.g = {v, 1, 2}, .b = {v, 1, 2}};
    assert_int_equal(vt_image_tonemap(2, 2, &ok, NULL, out, 8), 0);
    assert_int_equal(vt_image_tonemap(0, 2, &ok, NULL, out, 8), VT_ERR_INVALID);
    assert_int_equal(vt_image_tonemap(2, 0, &ok, NULL, out, 8), VT_ERR_INVALID);
    assert_int_equal(vt_image_tonemap(VT_IMAGE_MAX_DIM + 1, 1, &ok, NULL, out, 1 << 20), VT_ERR_INVALID);
    assert_int_equal(vt_image_tonemap(1, VT_IMAGE_MAX_DIM + 1, &ok, NULL, out, 8), VT_ERR_INVALID);
    assert_int_equal(vt_image_tonemap(2, 2, NULL, NULL, out, 8), VT_ERR_INVALID);
    assert_int_equal(vt_image_tonemap(2, 2, &ok, NULL, NULL, 8), VT_ERR_INVALID);
    assert_int_equal(vt_image_tonemap(2, 2, &ok, NULL, out, 7), VT_ERR_INVALID);
    assert_int_equal(vt_image_tonemap(2, 2, &only_g, NULL, out, 8), VT_ERR_INVALID);
    assert_int_equal(vt_image_tonemap(2, 2, &no_r, NULL, out, 8), VT_ERR_INVALID);
    vt_tonemap_desc bad_op = {.op = (vt_tonemap_op)2};
    assert_int_equal(vt_image_tonemap(2, 2, &ok, &bad_op, out, 8), VT_ERR_INVALID);
    assert_int_equal(vt_image_tonemap(2, 2, &ok, &(vt_tonemap_desc){.exposure_ev = NAN}, out, 8), VT_ERR_INVALID);
    assert_int_equal(vt_image_tonemap(2, 2, &ok, &(vt_tonemap_desc){.exposure_ev = 65}, out, 8), VT_ERR_INVALID);
    assert_int_equal(vt_image_rgba8_size(3, 5), 60);
    assert_int_equal(vt_image_rgba8_size(0, 5), 0);
    assert_int_equal(vt_image_rgba8_size(VT_IMAGE_MAX_DIM, VT_IMAGE_MAX_DIM),
                     (size_t)VT_IMAGE_MAX_DIM * VT_IMAGE_MAX_DIM * 4);
    assert_int_equal(vt_image_rgba8_size(VT_IMAGE_MAX_DIM + 1, 1), 0);
}

/* ---- PNG tests ----------------------------------------------------------------- */

static void test_image_png_roundtrip(void **state)
{
    (void)state;
    rng r = {test_seed() ^ 0x9A6};
    const uint32_t sizes[][2] = {{1, 1}, {2, 3}, {37, 23}, {255, 1}, {1, 300}, {129, 65}};
    const int levels[] = {-1, 0, 1, 6, 9};
    tdir t;
    tdir_make(&t, "vt_image_test");
    for (size_t s = 0; s < sizeof sizes / sizeof sizes[0]; s++) {
        uint32_t w = sizes[s][0], h = sizes[s][1];
        size_t stride = (size_t)w * 4 + (s % 2 ? 5 : 0); /* padded rows too */
        uint8_t *px = random_rgba(&r, h, stride);
        for (int alpha = 0; alpha < 2; alpha++) {
            int level = levels[(s + (size_t)alpha) % 5];
            png_write_ok(tdir_file(&t, "rt.png"), w, h, px, stride, alpha, level);
            assert_int_equal(tdir_count(&t), 1);
            png_check(t.path, w, h, px, stride, alpha);
            if (s == 2) check_file_says(t.path, alpha ? "PNG image data, 37 x 23, 8-bit/color RGBA"
                                                      : "PNG image data, 37 x 23, 8-bit/color RGB,");
        }
        free(px);
    }
    tdir_remove(&t);
}

/* vt_png_encode's stream is the file vt_png_write writes, byte for byte,
 * and reads back as the pixels (the memory sink against the file sink). */
static void test_image_png_encode_memory(void **state)
{
    (void)state;
    rng r = {test_seed() ^ 0x9A7};
    tdir t;
    tdir_make(&t, "vt_image_test");
    const uint32_t w = 300, h = 257; /* larger than the first 64 KiB guess after filtering: it must grow */
    uint8_t *px = random_rgba(&r, h, (size_t)w * 4);
    for (int alpha = 0; alpha < 2; alpha++) {
        uint8_t *mem = NULL;
        size_t len = 0;
        char err[256];
        assert_int_equal(vt_png_encode(w, h, px, (size_t)w * 4, alpha, 6, &mem, &len, err, sizeof err), 0);
        png_write_ok(tdir_file(&t, "file.png"), w, h, px, (size_t)w * 4, alpha, 6);
        FILE *f = fopen(t.path, "rb");
        assert_non_null(f);
        uint8_t *disk = malloc(len + 1);
        assert_non_null(disk);
        assert_int_equal(fread(disk, 1, len + 1, f), len);
        fclose(f);
        assert_memory_equal(disk, mem, len);
        png_check(t.path, w, h, px, (size_t)w * 4, alpha);
        free(disk);
        free(mem);
    }
    uint8_t *mem = (uint8_t *)1;
    size_t len = 1;
    char err[256];
    assert_int_equal(vt_png_encode(0, 1, px, 4, true, 6, &mem, &len, err, sizeof err), VT_ERR_INVALID);
    assert_null(mem);
    assert_int_equal(len, 0);
    free(px);
    tdir_remove(&t);
}

/* A tone-mapped bottom-up HDR buffer written as PNG reads back as the
 * tone map of the top-down one, and Python's zlib reader agrees. */
static void test_image_png_from_hdr(void **state)
{
    (void)state;
    uint32_t w = 41, h = 19;
    float *up = malloc((size_t)w * h * 3 * sizeof *up), *down = malloc((size_t)w * h * 3 * sizeof *down);
    uint8_t *a = malloc((size_t)w * h * 4), *b = malloc((size_t)w * h * 4);
    assert_true(up && down && a && b);
    for (uint32_t y = 0; y < h; y++)
        for (uint32_t x = 0; x < w; x++)
            for (int c = 0; c < 3; c++) {
                float v = (float)(0.02 * (x + 1) * (c + 1) + 0.3 * y) * (x == 20 && y == 9 ? 50 : 1);
                down[((size_t)y * w + x) * 3 + c] = v;
                up[((size_t)(h - 1 - y) * w + x) * 3 + c] = v;
            }
    ptrdiff_t s3 = 3 * (ptrdiff_t)w;
    vt_image_src sd = {.r = {down, 3, s3}, .g = {down + 1, 3, s3}, .b = {down + 2, 3, s3}};
    const float *top = up + (size_t)(h - 1) * w * 3;
    vt_image_src su = {.r = {top, 3, -s3}, .g = {top + 1, 3, -s3}, .b = {top + 2, 3, -s3}};
    vt_tonemap_desc d = {.op = VT_TONEMAP_ACES, .exposure_ev = -0.5f};
    tonemap_ok(w, h, &sd, &d, a, (size_t)w * 4);
    tonemap_ok(w, h, &su, &d, b, (size_t)w * 4);
    assert_memory_equal(a, b, (size_t)w * h * 4);
    tdir t;
    tdir_make(&t, "vt_image_test");
    png_write_ok(tdir_file(&t, "hdr.png"), w, h, b, (size_t)w * 4, false, 9);
    png_check(t.path, w, h, a, (size_t)w * 4, false);
    check_python_png(&t, t.path, w, h, a, (size_t)w * 4, false);
    png_write_ok(tdir_file(&t, "hdr_a.png"), w, h, b, (size_t)w * 4, true, 1);
    check_python_png(&t, t.path, w, h, a, (size_t)w * 4, true);
    free(up);
    free(down);
    free(a);
    free(b);
    tdir_remove(&t);
}

/* The reader on files made here: 8-bit grey, 16-bit RGBA, palette with
 * transparency, 2-bit grey; and an IHDR beyond VT_IMAGE_MAX_DIM. */
static void test_image_png_reader_formats(void **state)
{
    (void)state;
    static bytes o;
    tdir t;
    tdir_make(&t, "vt_image_test");
    uint8_t *got;
    uint32_t w, h;
    bool alpha;
    char err[512];
    /* grey 8, 3x2 */
    const uint8_t g8[] = {0, 10, 20, 30, 0, 40, 50, 60};
    make_png(&o, 3, 2, 8, 0, NULL, 0, NULL, 0, g8, sizeof g8);
    write_bytes(tdir_file(&t, "g8.png"), o.b, o.n);
    assert_int_equal(vt_png_read(t.path, &got, &w, &h, &alpha, err, sizeof err), 0);
    assert_true(w == 3 && h == 2 && !alpha);
    const uint8_t g8_want[] = {10, 10, 10, 255, 20, 20, 20, 255, 30, 30, 30, 255,
                               40, 40, 40, 255, 50, 50, 50, 255, 60, 60, 60, 255};
    assert_memory_equal(got, g8_want, sizeof g8_want);
    free(got);
    /* RGBA 16, 2x1: scaled to 8 bits with rounding (x * 255 / 65535) */
    const uint8_t r16[] = {0, 0x12, 0x34, 0xff, 0xff, 0x80, 0x7f, 0x00, 0x80,
                           0x01, 0x00, 0x00, 0x01, 0x7f, 0x80, 0x80, 0x80};
    make_png(&o, 2, 1, 16, 6, NULL, 0, NULL, 0, r16, sizeof r16);
    write_bytes(tdir_file(&t, "r16.png"), o.b, o.n);
    assert_int_equal(vt_png_read(t.path, &got, &w, &h, &alpha, err, sizeof err), 0);
    assert_true(w == 2 && h == 1 && alpha);
    const uint16_t s16[8] = {0x1234, 0xffff, 0x807f, 0x0080, 0x0100, 0x0001, 0x7f80, 0x8080};
    for (int i = 0; i < 8; i++) assert_int_equal(got[i], (s16[i] * 255 + 32767) / 65535);
    free(got);
    /* palette 8-bit with tRNS, 4x1 */
    const uint8_t plte[9] = {255, 0, 0, 0, 255, 0, 0, 0, 255}, trns[2] = {0, 128};
    const uint8_t p8[] = {0, 0, 1, 2, 1};
    make_png(&o, 4, 1, 8, 3, plte, 9, trns, 2, p8, sizeof p8);
    write_bytes(tdir_file(&t, "p8.png"), o.b, o.n);
    assert_int_equal(vt_png_read(t.path, &got, &w, &h, &alpha, err, sizeof err), 0);
    assert_true(w == 4 && h == 1 && alpha);
    const uint8_t p8_want[] = {255, 0, 0, 0, 0, 255, 0, 128, 0, 0, 255, 255, 0, 255, 0, 128};
    assert_memory_equal(got, p8_want, sizeof p8_want);
    free(got);
    /* grey 2-bit, 4x1: 0,1,2,3 -> 0, 85, 170, 255 */
    const uint8_t g2[] = {0, 0x1b};
    make_png(&o, 4, 1, 2, 0, NULL, 0, NULL, 0, g2, sizeof g2);
    write_bytes(tdir_file(&t, "g2.png"), o.b, o.n);
    assert_int_equal(vt_png_read(t.path, &got, &w, &h, NULL, err, sizeof err), 0);
    for (int i = 0; i < 4; i++) assert_int_equal(got[i * 4], i * 85);
    free(got);
    /* too big: VT_ERR_TOO_LARGE before any allocation (the IDAT is not even valid) */
    make_png(&o, VT_IMAGE_MAX_DIM + 1, 1, 8, 0, NULL, 0, NULL, 0, g8, 2);
    write_bytes(tdir_file(&t, "big.png"), o.b, o.n);
    got = (uint8_t *)1;
    assert_int_equal(vt_png_read(t.path, &got, &w, &h, &alpha, err, sizeof err), VT_ERR_TOO_LARGE);
    assert_null(got);
    assert_true(w == 0 && h == 0);
    assert_non_null(strstr(err, t.path));
    /* a broken CRC in IHDR */
    make_png(&o, 3, 2, 8, 0, NULL, 0, NULL, 0, g8, sizeof g8);
    o.b[8 + 8 + 13] ^= 1;
    write_bytes(tdir_file(&t, "crc.png"), o.b, o.n);
    assert_int_equal(vt_png_read(t.path, &got, &w, &h, &alpha, err, sizeof err), VT_ERR_CORRUPT);
    tdir_remove(&t);
}

/* ---- JPEG tests ---------------------------------------------------------------- */

/* Gradients at quality 85 and 95, RGB and RGBX input, odd sizes: the
 * right size back; PSNR over R, G, B >= 44 dB (q85) and >= 46 dB (q95) on
 * smooth ones (64 pixels or more each way; measured 47.7-50.4), >= 28 dB
 * on steep small ones; RGB and RGBX give the same bytes; file and memory
 * give the same bytes and the same pixels. */
static void test_image_jpeg_roundtrip(void **state)
{
    (void)state;
    const uint32_t sizes[][2] = {{1, 1}, {8, 8}, {161, 97}, {320, 240}, {17, 300}};
    tdir t;
    tdir_make(&t, "vt_image_test");
    char err[512];
    for (size_t s = 0; s < sizeof sizes / sizeof sizes[0]; s++) {
        uint32_t w = sizes[s][0], h = sizes[s][1];
        uint8_t *rgb = gradient(w, h, 3), *rgbx = gradient(w, h, 4);
        const int qs[2] = {85, 95};
        /* smooth: at most 4 levels per pixel; steeper ramps lose to 4:2:0
         * chroma (measured 30.4 dB for 8x8 at q85; a swapped or shifted
         * channel gives under 15) */
        bool smooth = w >= 64 && h >= 64;
        const double bound[2] = {smooth ? 44 : 28, smooth ? 46 : 28};
        for (int qi = 0; qi < 2; qi++) {
            uint8_t *m3 = NULL, *m4 = NULL, *dec = NULL, *fdec = NULL, *file = NULL;
            size_t n3 = 0, n4 = 0, nf = 0;
            assert_int_equal(vt_jpeg_encode(w, h, rgb, (size_t)w * 3, 3, qs[qi], &m3, &n3, err,
                                            sizeof err), 0);
            assert_string_equal(err, "");
            assert_int_equal(vt_jpeg_encode(w, h, rgbx, (size_t)w * 4, 4, qs[qi], &m4, &n4, err,
                                            sizeof err), 0);
            assert_int_equal(n3, n4);
            assert_memory_equal(m3, m4, n3);
            assert_true(n3 > 4 && m3[0] == 0xFF && m3[1] == 0xD8 && m3[n3 - 2] == 0xFF && m3[n3 - 1] == 0xD9);
            assert_int_equal(vt_jpeg_write(tdir_file(&t, "g.jpg"), w, h, rgbx, (size_t)w * 4, 4, qs[qi],
                                           err, sizeof err), 0);
            assert_string_equal(err, "");
            assert_int_equal(tdir_count(&t), 1);
            file = test_slurp(t.path, &nf);
            assert_int_equal(nf, n3);
            assert_memory_equal(file, m3, n3);
            uint32_t rw = 0, rh = 0, fw = 0, fh = 0;
            assert_int_equal(vt_jpeg_decode(m3, n3, &dec, &rw, &rh, err, sizeof err), 0);
            assert_string_equal(err, "");
            assert_int_equal(vt_jpeg_read(t.path, &fdec, &fw, &fh, err, sizeof err), 0);
            assert_true(rw == w && rh == h && fw == w && fh == h);
            assert_memory_equal(dec, fdec, (size_t)w * h * 3);
            double p = psnr_rgb(rgb, dec, (size_t)w * h * 3);
            if (p < bound[qi]) print_message("%ux%u q%d: PSNR %.2f dB\n", w, h, qs[qi], p);
            assert_true(p >= bound[qi]);
            if (s == 2 && qi == 0) check_file_says(t.path, "JPEG image data, JFIF standard");
            if (s == 2 && qi == 0) check_file_says(t.path, "161x97, components 3");
            free(m3);
            free(m4);
            free(dec);
            free(fdec);
            free(file);
        }
        free(rgb);
        free(rgbx);
    }
    tdir_remove(&t);
}

/* Padded rows are skipped; quality changes the stream; every quality is
 * accepted; the decoder rejects damage. */
static void test_image_jpeg_details(void **state)
{
    (void)state;
    uint32_t w = 50, h = 30;
    size_t stride = (size_t)w * 3 + 11;
    uint8_t *packed = gradient(w, h, 3), *padded = malloc(stride * h);
    assert_non_null(padded);
    memset(padded, 0xA5, stride * h);
    for (uint32_t y = 0; y < h; y++) memcpy(padded + y * stride, packed + (size_t)y * w * 3, (size_t)w * 3);
    uint8_t *a = NULL, *b = NULL, *dec = NULL;
    size_t na, nb;
    uint32_t rw, rh;
    char err[512];
    assert_int_equal(vt_jpeg_encode(w, h, packed, (size_t)w * 3, 3, 70, &a, &na, err, sizeof err), 0);
    assert_int_equal(vt_jpeg_encode(w, h, padded, stride, 3, 70, &b, &nb, err, sizeof err), 0);
    assert_true(na == nb && memcmp(a, b, na) == 0);
    free(b);
    size_t prev = 0;
    for (int q = 1; q <= 100; q++) {
        assert_int_equal(vt_jpeg_encode(w, h, packed, (size_t)w * 3, 3, q, &b, &nb, NULL, 0), 0);
        if (q % 10 == 0) {
            assert_true(nb >= prev); /* more quality, more bytes (on this image) */
            prev = nb;
        }
        free(b);
    }
    /* truncated: libjpeg would warn and pad with grey; here it is an error */
    for (size_t cut = 2; cut < na; cut += na / 7) {
        dec = (uint8_t *)1;
        assert_int_equal(vt_jpeg_decode(a, cut, &dec, &rw, &rh, err, sizeof err), VT_ERR_CORRUPT);
        assert_null(dec);
        assert_true(strncmp(err, "<memory>: ", 10) == 0);
    }
    /* random bytes, a bad marker, empty input */
    rng r = {test_seed() ^ 0x1BE6};
    uint8_t junk[600];
    for (size_t i = 0; i < sizeof junk; i++) junk[i] = (uint8_t)rng_u64(&r);
    assert_int_equal(vt_jpeg_decode(junk, sizeof junk, &dec, &rw, &rh, err, sizeof err), VT_ERR_CORRUPT);
    junk[0] = 0xFF, junk[1] = 0xD8;
    assert_int_equal(vt_jpeg_decode(junk, sizeof junk, &dec, &rw, &rh, err, sizeof err), VT_ERR_CORRUPT);
    assert_int_equal(vt_jpeg_decode(a, 0, &dec, &rw, &rh, err, sizeof err), VT_ERR_CORRUPT);
    /* corrupt entropy-coded data somewhere in the middle */
    uint8_t *c = malloc(na);
    assert_non_null(c);
    memcpy(c, a, na);
    for (size_t i = na / 2; i < na / 2 + 40; i++) c[i] = 0xFF;
    int rc = vt_jpeg_decode(c, na, &dec, &rw, &rh, err, sizeof err);
    assert_true(rc == VT_ERR_CORRUPT);
    assert_null(dec);
    free(c);
    free(a);
    free(packed);
    free(padded);
}

/* ---- JPEG in bands (vt_jpeg_encode_par) ---- */

/* A runner on real threads, one a job (the daemon's is its cull_pool). */
typedef struct band_thread {
    pthread_t th;
    vt_jpeg_job_fn fn;
    void *arg;
    uint32_t t;
} band_thread;

static void *band_thread_main(void *p)
{
    band_thread *b = p;
    b->fn(b->arg, b->t);
    return NULL;
}

static void threads_run(void *ctx, vt_jpeg_job_fn fn, void *arg, uint32_t n)
{
    int *calls = ctx;
    band_thread b[VT_JPEG_MAX_BANDS];
    assert_true(n >= 2 && n <= VT_JPEG_MAX_BANDS);
    (*calls)++;
    for (uint32_t t = 0; t < n; t++) {
        b[t] = (band_thread){.fn = fn, .arg = arg, .t = t};
        assert_int_equal(pthread_create(&b[t].th, NULL, band_thread_main, &b[t]), 0);
    }
    for (uint32_t t = 0; t < n; t++) pthread_join(b[t].th, NULL);
}

/* A runner that runs one job whatever n, as a pool of one thread clamps
 * n: the bands left are the caller's. */
static void one_job_run(void *ctx, vt_jpeg_job_fn fn, void *arg, uint32_t n)
{
    (void)n;
    (*(int *)ctx)++;
    fn(arg, 0);
}

/* vt_tonemap_frame (H.264 frames' tone map) in bands is one
 * vt_image_tonemap of the bottom-up frame, whatever the bands and however
 * many jobs the runner starts: one (a pool of one thread clamps n), or one
 * thread a band. The runner starting fewer jobs than bands once left the
 * bottom half of every H.264 frame black. */
static void test_image_tonemap_frame_bands(void **state)
{
    (void)state;
    enum { W = 37, H = 29 };
    static float rgba[W * H * 4];
    rng r = {test_seed() ^ 0x70E};
    for (size_t i = 0; i < sizeof rgba / sizeof rgba[0]; i++) rgba[i] = (float)rng_range(&r, -0.5, 8);
    rgba[5] = NAN, rgba[6] = INFINITY, rgba[9] = -INFINITY;
    vt_tonemap_desc td = {.exposure_ev = -0.5f, .op = VT_TONEMAP_ACES};
    static uint8_t ref[W * H * 4], got[W * H * 4];
    const float *top = rgba + (size_t)(H - 1) * W * 4;
    vt_image_src src = {.r = {top, 4, -W * 4}, .g = {top + 1, 4, -W * 4}, .b = {top + 2, 4, -W * 4}};
    assert_int_equal(vt_image_tonemap(W, H, &src, &td, ref, 4 * W), 0);
    static const uint32_t bands[] = {1, 2, 3, 4, 16};
    for (size_t b = 0; b < sizeof bands / sizeof bands[0]; b++)
        for (int runner = 0; runner < 3; runner++) {
            int calls = 0;
            memset(got, 0xAB, sizeof got);
            void (*run)(void *, vt_jpeg_job_fn, void *, uint32_t) =
                runner == 0 ? NULL : runner == 1 ? one_job_run : threads_run;
            if (runner == 2 && bands[b] < 2) continue; /* threads_run wants 2 or more */
            assert_int_equal(vt_tonemap_frame(W, H, rgba, W, &td, got, bands[b], run, &calls), 0);
            if (memcmp(got, ref, sizeof ref)) fail_msg("bands %u, runner %d: not the one-pass tone map", bands[b], runner);
        }
    assert_int_equal(vt_tonemap_frame(W, H, NULL, W, &td, got, 2, NULL, NULL), VT_ERR_INVALID);
    assert_int_equal(vt_tonemap_frame(W, H, rgba, W - 1, &td, got, 2, NULL, NULL), VT_ERR_INVALID);
}

/* The exact bilinear value of channel c at output (x, y), from the
 * definition: input (x + 0.5) sw / dw - 0.5, clamped to the edge centres. */
static double resize_ref(const uint8_t *src, uint32_t sw, uint32_t sh, size_t stride, uint32_t dw, uint32_t dh,
                         uint32_t x, uint32_t y, int c)
{
    double u = (x + 0.5) * sw / dw - 0.5, v = (y + 0.5) * sh / dh - 0.5;
    u = u < 0 ? 0 : u > sw - 1 ? sw - 1 : u;
    v = v < 0 ? 0 : v > sh - 1 ? sh - 1 : v;
    uint32_t x0 = (uint32_t)u, y0 = (uint32_t)v;
    uint32_t x1 = x0 + 1 < sw ? x0 + 1 : x0, y1 = y0 + 1 < sh ? y0 + 1 : y0;
    double fx = u - x0, fy = v - y0;
#define PX(xx, yy) ((double)src[(size_t)(yy) * stride + 4 * (xx) + c])
    return (PX(x0, y0) * (1 - fx) + PX(x1, y0) * fx) * (1 - fy) + (PX(x0, y1) * (1 - fx) + PX(x1, y1) * fx) * fy;
#undef PX
}

/* vt_image_resize_rgba8 against the definition: every channel of every
 * output pixel within 1.5 of the exact bilinear value (the weights are
 * 1/256ths: at most half a 256th off in each direction, and a rounding), up, down and 1:1 (a copy), odd sizes and strides, in any
 * number of bands on any runner (the same bytes); the bad arguments
 * refused. */
static void test_image_resize(void **state)
{
    (void)state;
    static const uint32_t sizes[][4] = {{640, 360, 1280, 720}, {427, 240, 1280, 720}, {33, 17, 100, 61},
                                        {1, 1, 9, 5}, {9, 5, 1, 1}, {64, 48, 31, 23}, {20, 20, 20, 20},
                                        {3, 200, 7, 7}};
    rng r = {test_seed() ^ 0x8E5};
    for (size_t k = 0; k < sizeof sizes / sizeof sizes[0]; k++) {
        const uint32_t sw = sizes[k][0], sh = sizes[k][1], dw = sizes[k][2], dh = sizes[k][3];
        const size_t ss = 4 * (size_t)sw + 12, ds = 4 * (size_t)dw + 4;
        uint8_t *src = malloc(ss * sh), *ref = malloc(ds * dh), *got = malloc(ds * dh);
        assert_non_null(src), assert_non_null(ref), assert_non_null(got);
        for (size_t i = 0; i < ss * sh; i++) src[i] = (uint8_t)rng_range(&r, 0, 256);
        if (k == 0) /* hard edges: black and white columns and rows */
            for (uint32_t y = 0; y < sh; y++)
                for (uint32_t x = 0; x < sw; x++) memset(src + y * ss + 4 * x, ((x / 3 + y / 2) & 1) * 255, 4);
        memset(ref, 0xCD, ds * dh);
        assert_int_equal(vt_image_resize_rgba8(sw, sh, src, ss, dw, dh, ref, ds, 1, NULL, NULL), 0);
        double worst = 0;
        for (uint32_t y = 0; y < dh; y++) {
            for (uint32_t x = 0; x < dw; x++)
                for (int c = 0; c < 4; c++) {
                    double e = fabs(ref[y * ds + 4 * x + c] - resize_ref(src, sw, sh, ss, dw, dh, x, y, c));
                    if (e > worst) worst = e;
                }
            assert_int_equal(ref[y * ds + 4 * dw], 0xCD); /* the stride's padding is not written */
        }
        if (worst > 1.5) fail_msg("%ux%u -> %ux%u: off the bilinear value by %.3f", sw, sh, dw, dh, worst);
        if (sw == dw && sh == dh)
            for (uint32_t y = 0; y < dh; y++) assert_memory_equal(ref + y * ds, src + y * ss, 4 * (size_t)dw);
        static const uint32_t bands[] = {2, 3, 16};
        for (size_t b = 0; b < sizeof bands / sizeof bands[0]; b++)
            for (int runner = 0; runner < 3; runner++) {
                int calls = 0;
                memset(got, 0xCD, ds * dh);
                void (*run)(void *, vt_jpeg_job_fn, void *, uint32_t) =
                    runner == 0 ? NULL : runner == 1 ? one_job_run : threads_run;
                if (runner == 2 && (bands[b] > dh || dh < 2)) continue; /* threads_run wants 2..n jobs */
                assert_int_equal(vt_image_resize_rgba8(sw, sh, src, ss, dw, dh, got, ds, bands[b], run, &calls), 0);
                if (memcmp(got, ref, ds * dh)) fail_msg("%ux%u -> %ux%u, bands %u, runner %d: not the one-band bytes", sw, sh, dw, dh, bands[b], runner);
            }
        free(src), free(ref), free(got);
    }
    uint8_t px[64] = {0};
    assert_int_equal(vt_image_resize_rgba8(2, 2, NULL, 8, 2, 2, px, 8, 1, NULL, NULL), VT_ERR_INVALID);
    assert_int_equal(vt_image_resize_rgba8(2, 2, px, 8, 2, 2, NULL, 8, 1, NULL, NULL), VT_ERR_INVALID);
    assert_int_equal(vt_image_resize_rgba8(0, 2, px, 8, 2, 2, px + 32, 8, 1, NULL, NULL), VT_ERR_INVALID);
    assert_int_equal(vt_image_resize_rgba8(2, 2, px, 8, 2, 0, px + 32, 8, 1, NULL, NULL), VT_ERR_INVALID);
    assert_int_equal(vt_image_resize_rgba8(2, 2, px, 7, 2, 2, px + 32, 8, 1, NULL, NULL), VT_ERR_INVALID);
    assert_int_equal(vt_image_resize_rgba8(2, 2, px, 8, 2, 2, px + 32, 7, 1, NULL, NULL), VT_ERR_INVALID);
    assert_int_equal(vt_image_resize_rgba8(VT_IMAGE_MAX_DIM + 1, 1, px, 1u << 20, 2, 2, px + 32, 8, 1, NULL, NULL),
                     VT_ERR_INVALID);
}

/* The rows hook: copies rows [y0, y1) of src into dst and marks them. */
typedef struct band_fill {
    const uint8_t *src;
    uint8_t *dst;
    size_t stride;
    uint8_t seen[300]; /* rows filled (each once), for h <= 300 */
    int fail_at;       /* a band starting at this row fails, -1 none */
} band_fill;

static int band_fill_rows(void *ctx, uint32_t y0, uint32_t y1)
{
    band_fill *f = ctx;
    if ((int)y0 == f->fail_at) return VT_ERR_NOMEM;
    for (uint32_t y = y0; y < y1; y++) {
        f->seen[y]++;
        memcpy(f->dst + y * f->stride, f->src + y * f->stride, f->stride);
    }
    return 0;
}

/* The banded stream decodes (libjpeg, which treats a wrong or missing
 * restart marker as corrupt) to exactly the pixels of one vt_jpeg_encode
 * of the picture: a restart resets only the DC prediction. Sizes with a
 * last band short (17, 250 rows), bands past 8 (the RSTn numbers wrap),
 * more bands asked than MCU rows, odd widths (partial MCUs at the right). */
static void test_image_jpeg_bands(void **state)
{
    (void)state;
    static const struct { uint32_t w, h, bands, n; } cases[] = {
        {333, 250, 2, 2}, {40, 17, 2, 2}, {64, 32, 2, 2}, {333, 250, 3, 3},
        {97, 250, 16, 16}, {50, 40, 16, 3}, {21, 16, 2, 1}, {1, 1, 4, 1},
    };
    rng r = {test_seed() ^ 0xBA4D};
    char err[512];
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        uint32_t w = cases[c].w, h = cases[c].h;
        size_t stride = (size_t)w * 4;
        /* a gradient with noisy blocks: DC differences between blocks matter */
        uint8_t *px = gradient(w, h, 4), *dst = malloc(stride * h);
        assert_non_null(dst);
        for (size_t i = 0; i < stride * h; i++)
            if ((i / 4 / 24 + i / stride / 24) % 3 == 0) px[i] = (uint8_t)rng_u64(&r);
        memset(dst, 0, stride * h);
        for (int q = 50; q <= 95; q += 45) {
            uint8_t *one = NULL, *par = NULL, *d1 = NULL, *d2 = NULL;
            size_t n1, n2;
            uint32_t rw, rh;
            assert_int_equal(vt_jpeg_encode(w, h, px, stride, 4, q, &one, &n1, err, sizeof err), 0);
            int calls = 0;
            band_fill f = {.src = px, .dst = dst, .stride = stride, .fail_at = -1};
            vt_jpeg_par pp = {.bands = cases[c].bands, .run = threads_run, .run_ctx = &calls,
                              .rows_hook = band_fill_rows, .hook_ctx = &f};
            assert_int_equal(vt_jpeg_encode_par(w, h, dst, stride, 4, q, &pp, &par, &n2, err, sizeof err), 0);
            assert_int_equal(calls, cases[c].n > 1);
            for (uint32_t y = 0; y < h; y++) assert_int_equal(f.seen[y], 1);
            /* the restart markers: n - 1 of them, RST0.. in order (the
               scan's own FF bytes are stuffed, FF 00) */
            uint32_t rst = 0;
            for (size_t i = 2; i + 1 < n2; i++)
                if (par[i] == 0xFF && par[i + 1] >= 0xD0 && par[i + 1] <= 0xD7) {
                    assert_int_equal(par[i + 1], 0xD0 + rst % 8);
                    rst++;
                }
            assert_int_equal(rst, cases[c].n - 1);
            /* the same size within what a band costs: the DRI segment
               (6 bytes), then a band's marker (2), padding (< 1) and its
               first MCU's DC differences coded from 0, not from the MCU
               above (3 components, each a code of <= 9 bits and <= 11
               bits of value: < 8 bytes either way) */
            size_t slack = 6 + 11 * (size_t)(cases[c].n - 1);
            assert_true(n2 <= n1 + slack && n2 + slack >= n1);
            assert_int_equal(vt_jpeg_decode(one, n1, &d1, &rw, &rh, err, sizeof err), 0);
            assert_int_equal(vt_jpeg_decode(par, n2, &d2, &rw, &rh, err, sizeof err), 0);
            assert_int_equal(rw, w);
            assert_int_equal(rh, h);
            assert_memory_equal(d1, d2, (size_t)w * h * 3);
            /* a stream whose RSTn is wrong is refused (the check above has teeth) */
            if (rst) {
                for (size_t i = 2; i + 1 < n2; i++)
                    if (par[i] == 0xFF && par[i + 1] == 0xD0) par[i + 1] = 0xD3;
                free(d2);
                d2 = (uint8_t *)1;
                assert_int_equal(vt_jpeg_decode(par, n2, &d2, &rw, &rh, err, sizeof err), VT_ERR_CORRUPT);
                assert_null(d2);
            }
            free(one), free(par), free(d1), free(d2);
        }
        /* a band's hook failing fails the call, nothing returned */
        int calls = 0;
        band_fill f = {.src = px, .dst = dst, .stride = stride, .fail_at = 0};
        vt_jpeg_par pp = {.bands = cases[c].bands, .run = threads_run, .run_ctx = &calls,
                          .rows_hook = band_fill_rows, .hook_ctx = &f};
        uint8_t *out = (uint8_t *)1;
        size_t n = 7;
        assert_int_equal(vt_jpeg_encode_par(w, h, dst, stride, 4, 85, &pp, &out, &n, err, sizeof err), VT_ERR_NOMEM);
        assert_null(out);
        assert_int_equal(n, 0);
        assert_true(strstr(err, "rows 0..") != NULL);
        free(px), free(dst);
    }
}

/* vt_jpeg_encode_frame: the frame (floats, bottom-up, a wider stride)
 * tone-mapped in bands gives the bytes of one vt_image_tonemap of the
 * whole and a stream that decodes as one vt_jpeg_encode of them. */
static void test_image_jpeg_frame(void **state)
{
    (void)state;
    uint32_t w = 75, h = 70, stride = 80;
    rng r = {test_seed() ^ 0xF4A3E};
    float *f = malloc((size_t)stride * h * 4 * sizeof *f);
    uint8_t *a = malloc((size_t)w * h * 4), *b = malloc((size_t)w * h * 4);
    assert_true(f && a && b);
    for (size_t i = 0; i < (size_t)stride * h * 4; i++) f[i] = (float)rng_log(&r, 1e-3, 40.0);
    const float *top = f + (size_t)(h - 1) * stride * 4;
    vt_image_src src = {.r = {top, 4, -(ptrdiff_t)stride * 4}, .g = {top + 1, 4, -(ptrdiff_t)stride * 4},
                        .b = {top + 2, 4, -(ptrdiff_t)stride * 4}};
    vt_tonemap_desc td = {.op = VT_TONEMAP_ACES, .exposure_ev = -1.5f};
    assert_int_equal(vt_image_tonemap(w, h, &src, &td, a, (size_t)w * 4), 0);
    uint8_t *one = NULL, *par = NULL, *d1 = NULL, *d2 = NULL;
    size_t n1, n2;
    uint32_t rw, rh;
    char err[512];
    assert_int_equal(vt_jpeg_encode(w, h, a, (size_t)w * 4, 4, 85, &one, &n1, err, sizeof err), 0);
    int calls = 0;
    assert_int_equal(vt_jpeg_encode_frame(w, h, f, stride, &td, b, 85, 3, threads_run, &calls, &par, &n2, err,
                                          sizeof err), 0);
    assert_int_equal(calls, 1);
    assert_memory_equal(a, b, (size_t)w * h * 4);
    assert_int_equal(vt_jpeg_decode(one, n1, &d1, &rw, &rh, err, sizeof err), 0);
    assert_int_equal(vt_jpeg_decode(par, n2, &d2, &rw, &rh, err, sizeof err), 0);
    assert_memory_equal(d1, d2, (size_t)w * h * 3);
    free(par), free(d2);
    /* more bands than the runner runs jobs: the same stream */
    memset(b, 0, (size_t)w * h * 4);
    calls = 0;
    uint8_t *par3 = NULL;
    size_t n3;
    assert_int_equal(vt_jpeg_encode_frame(w, h, f, stride, &td, b, 85, 3, threads_run, &calls, &par, &n2, err,
                                          sizeof err), 0);
    assert_int_equal(vt_jpeg_encode_frame(w, h, f, stride, &td, b, 85, 3, one_job_run, &calls, &par3, &n3, err,
                                          sizeof err), 0);
    assert_int_equal(calls, 2);
    assert_memory_equal(a, b, (size_t)w * h * 4);
    assert_true(n2 == n3 && memcmp(par, par3, n2) == 0);
    free(one), free(par), free(par3), free(d1);
    /* no frame: refused */
    assert_int_equal(vt_jpeg_encode_frame(w, h, NULL, stride, &td, b, 85, 3, threads_run, &calls, &par, &n2, err,
                                          sizeof err), VT_ERR_INVALID);
    assert_null(par);
    free(f), free(a), free(b);
}

/* 16384 wide and tall (the largest size), from one row repeated. */
static void test_image_large(void **state)
{
    (void)state;
    const uint32_t big = VT_IMAGE_MAX_DIM;
    uint8_t *row = malloc((size_t)big * 4);
    assert_non_null(row);
    for (uint32_t x = 0; x < big; x++) {
        row[x * 4 + 0] = (uint8_t)(x >> 6);
        row[x * 4 + 1] = (uint8_t)(255 - (x >> 6));
        row[x * 4 + 2] = (uint8_t)x;
        row[x * 4 + 3] = (uint8_t)(x * 3);
    }
    tdir t;
    tdir_make(&t, "vt_image_test");
    char err[512];
    const uint32_t dims[][2] = {{big, 3}, {2, big}};
    for (int d = 0; d < 2; d++) {
        uint32_t w = dims[d][0], h = dims[d][1];
        /* rows of the 2-wide image all start at the row's first pixels */
        size_t stride = (size_t)w * 4;
        uint8_t *px = malloc(stride * h);
        assert_non_null(px);
        for (uint32_t y = 0; y < h; y++)
            memcpy(px + y * stride, row + (d ? (size_t)y % 4096 * 4 : 0), stride);
        png_write_ok(tdir_file(&t, "big.png"), w, h, px, stride, true, 1);
        png_check(t.path, w, h, px, stride, true);
        uint8_t *dec = NULL;
        uint32_t rw, rh;
        assert_int_equal(vt_jpeg_write(tdir_file(&t, "big.jpg"), w, h, px, stride, 4, 90, err,
                                       sizeof err), 0);
        assert_int_equal(vt_jpeg_read(t.path, &dec, &rw, &rh, err, sizeof err), 0);
        assert_true(rw == w && rh == h);
        free(dec);
        free(px);
    }
    assert_int_equal(tdir_count(&t), 2);
    free(row);
    tdir_remove(&t);
}

/* ---- failures -------------------------------------------------------------------- */

/* Bad arguments to the writers: VT_ERR_INVALID, a message, nothing on disk. A
 * row: the path, the size, the pixels (or none), the stride, and the PNG
 * level or the JPEG bytes a pixel and quality. */
#define M VT_IMAGE_MAX_DIM
typedef struct bad_png_args {
    const char *name;
    test_path path;
    uint32_t w, h;
    bool no_px;
    size_t stride;
    int level;
} bad_png_args;

static const bad_png_args bad_png_rows[] = {
    {"no path", TPATH_NULL, 2, 2, false, 8, 6},
    {"empty path", TPATH_EMPTY, 2, 2, false, 8, 6},
    {"width 0", TPATH_FILE, 0, 2, false, 8, 6},
    {"height 0", TPATH_FILE, 2, 0, false, 8, 6},
    {"width past the limit", TPATH_FILE, M + 1, 1, false, 4 * (M + 1), 6},
    {"height past the limit", TPATH_FILE, 1, M + 1, false, 4, 6},
    {"width 2^32 - 1", TPATH_FILE, UINT32_MAX, 1, false, SIZE_MAX, 6},
    {"no pixels", TPATH_FILE, 2, 2, true, 8, 6},
    {"stride short of a row", TPATH_FILE, 2, 2, false, 7, 6},
    {"level 10", TPATH_FILE, 2, 2, false, 8, 10},
    {"level -2", TPATH_FILE, 2, 2, false, 8, -2},
};

static void test_image_png_bad_args(void **state)
{
    const bad_png_args *r = *state;
    uint8_t px[64] = {0};
    tdir t;
    tdir_make(&t, "vt_image_test");
    char err[256] = "unchanged";
    assert_int_equal(vt_png_write(tdir_path_arg(&t, r->path, "bad.img"), r->w, r->h, r->no_px ? NULL : px, r->stride,
                                  true, r->level, err, sizeof err),
                     VT_ERR_INVALID);
    assert_true(strlen(err) > 0 && strcmp(err, "unchanged") != 0);
    assert_int_equal(tdir_count(&t), 0);
    tdir_remove(&t);
}

typedef struct bad_jpeg_args {
    const char *name;
    test_path path;
    uint32_t w, h;
    bool no_px;
    size_t stride;
    uint32_t bpp;
    int q;
} bad_jpeg_args;

static const bad_jpeg_args bad_jpeg_rows[] = {
    {"no path", TPATH_NULL, 2, 2, false, 6, 3, 85},
    {"empty path", TPATH_EMPTY, 2, 2, false, 6, 3, 85},
    {"width 0", TPATH_FILE, 0, 2, false, 6, 3, 85},
    {"height 0", TPATH_FILE, 2, 0, false, 6, 3, 85},
    {"width past the limit", TPATH_FILE, M + 1, 1, false, 3 * (M + 1), 3, 85},
    {"height past the limit", TPATH_FILE, 1, M + 1, false, 3, 3, 85},
    {"no pixels", TPATH_FILE, 2, 2, true, 6, 3, 85},
    {"stride short of a row", TPATH_FILE, 2, 2, false, 5, 3, 85},
    {"stride short of an RGBA row", TPATH_FILE, 2, 2, false, 7, 4, 85},
    {"2 bytes a pixel", TPATH_FILE, 2, 2, false, 8, 2, 85},
    {"1 byte a pixel", TPATH_FILE, 2, 2, false, 8, 1, 85},
    {"quality 0", TPATH_FILE, 2, 2, false, 6, 3, 0},
    {"quality 101", TPATH_FILE, 2, 2, false, 6, 3, 101},
};
#undef M

/* The file writer refuses the row; the memory encoder too (where a path
 * is not what is wrong), handing back nothing. */
static void test_image_jpeg_bad_args(void **state)
{
    const bad_jpeg_args *r = *state;
    uint8_t px[64] = {0};
    const uint8_t *src = r->no_px ? NULL : px;
    tdir t;
    tdir_make(&t, "vt_image_test");
    char err[256] = "unchanged";
    assert_int_equal(vt_jpeg_write(tdir_path_arg(&t, r->path, "bad.img"), r->w, r->h, src, r->stride, r->bpp, r->q,
                                   err, sizeof err),
                     VT_ERR_INVALID);
    assert_true(strlen(err) > 0 && strcmp(err, "unchanged") != 0);
    assert_int_equal(tdir_count(&t), 0);
    if (r->path == TPATH_FILE) {
        uint8_t *out = (uint8_t *)1;
        size_t n = 1;
        assert_int_equal(vt_jpeg_encode(r->w, r->h, src, r->stride, r->bpp, r->q, &out, &n, err, sizeof err),
                         VT_ERR_INVALID);
        assert_null(out);
        assert_int_equal(n, 0);
    }
    tdir_remove(&t);
}

/* NULL outputs, tiny and absent error buffers, and the readers' NULLs. */
static void test_image_null_args(void **state)
{
    (void)state;
    uint8_t px[64] = {0};
    tdir t;
    tdir_make(&t, "vt_image_test");
    const char *p = tdir_file(&t, "bad.img");
    uint8_t *out;
    size_t n;
    assert_int_equal(vt_jpeg_encode(2, 2, px, 6, 3, 85, NULL, &n, NULL, 0), VT_ERR_INVALID);
    assert_int_equal(vt_jpeg_encode(2, 2, px, 6, 3, 85, &out, NULL, NULL, 0), VT_ERR_INVALID);
    /* tiny and absent error buffers */
    char tiny[4];
    assert_int_equal(vt_png_write(p, 0, 2, px, 8, true, 6, tiny, sizeof tiny), VT_ERR_INVALID);
    assert_true(strlen(tiny) < sizeof tiny);
    assert_int_equal(vt_png_write(p, 0, 2, px, 8, true, 6, NULL, 0), VT_ERR_INVALID);
    assert_int_equal(vt_jpeg_write(p, 0, 2, px, 8, 3, 85, tiny, 0), VT_ERR_INVALID);
    /* readers */
    uint32_t w, h;
    assert_int_equal(vt_png_read(NULL, &out, &w, &h, NULL, NULL, 0), VT_ERR_INVALID);
    assert_int_equal(vt_png_read(p, NULL, &w, &h, NULL, NULL, 0), VT_ERR_INVALID);
    assert_int_equal(vt_png_read(p, &out, NULL, &h, NULL, NULL, 0), VT_ERR_INVALID);
    assert_int_equal(vt_jpeg_read(NULL, &out, &w, &h, NULL, 0), VT_ERR_INVALID);
    assert_int_equal(vt_jpeg_decode(NULL, 4, &out, &w, &h, NULL, 0), VT_ERR_INVALID);
    assert_int_equal(vt_jpeg_decode(px, 4, NULL, &w, &h, NULL, 0), VT_ERR_INVALID);
    assert_int_equal(tdir_count(&t), 0);
    tdir_remove(&t);
}

/* Writes a 2 x 2 RGBA image as PNG (ctx NULL) or JPEG (ctx not NULL). */
static int write_small(const char *path, char *err, size_t errlen, void *ctx)
{
    static const uint8_t px[16] = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16};
    return ctx ? vt_jpeg_write(path, 2, 2, px, 8, 4, 85, err, errlen)
               : vt_png_write(path, 2, 2, px, 8, true, 6, err, errlen);
}

/* Unwritable places fail with the file system's errno and leave nothing. */
static void test_image_bad_path(void **state)
{
    (void)state;
    char err[512];
    tdir t;
    tdir_make(&t, "vt_image_test");
    test_unwritable_paths(&t, write_small, NULL, ".png");
    test_unwritable_paths(&t, write_small, &t, ".jpg");
    /* readers: missing file, directory, not an image */
    uint8_t *out;
    uint32_t w, h;
    assert_int_equal(vt_png_read(tdir_file(&t, "none.png"), &out, &w, &h, NULL, err, sizeof err), VT_ERR_NOT_FOUND);
    assert_non_null(strstr(err, t.path));
    assert_int_equal(vt_jpeg_read(t.path, &out, &w, &h, err, sizeof err), VT_ERR_NOT_FOUND);
    write_bytes(tdir_file(&t, "text.png"), "this is text, not a PNG or a JPEG\n", 34);
    assert_int_equal(vt_png_read(t.path, &out, &w, &h, NULL, err, sizeof err), VT_ERR_CORRUPT);
    assert_non_null(strstr(err, t.path));
    assert_int_equal(vt_jpeg_read(t.path, &out, &w, &h, err, sizeof err), VT_ERR_CORRUPT);
    write_bytes(tdir_file(&t, "empty"), "", 0);
    assert_int_equal(vt_png_read(t.path, &out, &w, &h, NULL, err, sizeof err), VT_ERR_CORRUPT);
    assert_int_equal(vt_jpeg_read(t.path, &out, &w, &h, err, sizeof err), VT_ERR_CORRUPT);
    tdir_remove(&t);
}

typedef struct noise_image {
    const uint8_t *px;
    uint32_t w, h;
    int jpeg;
} noise_image;

/* The whole of it, as a JPEG of quality 100 or an uncompressed PNG. */
static int write_noise(const char *path, char *err, size_t errlen, void *ctx)
{
    const noise_image *n = ctx;
    return n->jpeg ? vt_jpeg_write(path, n->w, n->h, n->px, (size_t)n->w * 4, 4, 100, err, errlen)
                   : vt_png_write(path, n->w, n->h, n->px, (size_t)n->w * 4, true, 0, err, errlen);
}

/* A write cut short by RLIMIT_FSIZE (in a child, SIGXFSZ ignored) fails
 * with EFBIG, removes its temporary file and leaves the old file whole;
 * a PNG cut short after writing fails to read. */
static void test_image_failed_write_keeps_old(void **state)
{
    (void)state;
    uint32_t w = 512, h = 512;
    rng r = {test_seed() ^ 0xF5};
    uint8_t *noise = random_rgba(&r, h, (size_t)w * 4);
    tdir t;
    tdir_make(&t, "vt_image_test");
    for (int fmt = 0; fmt < 2; fmt++) {
        const char *p = tdir_file(&t, fmt ? "old.jpg" : "old.png");
        char err[512];
        if (fmt) assert_int_equal(vt_jpeg_write(p, 4, 4, noise, (size_t)w * 4, 4, 90, err, sizeof err), 0);
        else png_write_ok(p, 4, 4, noise, (size_t)w * 4, true, 6);
        size_t n0;
        uint8_t *before = test_slurp(p, &n0);
        test_write_past_fsize(write_noise, p, &(noise_image){noise, w, h, fmt});
        assert_int_equal(tdir_count(&t), fmt + 1);
        size_t n1;
        uint8_t *after = test_slurp(p, &n1);
        assert_true(n0 == n1 && memcmp(before, after, n0) == 0);
        free(before);
        free(after);
    }
    /* a PNG missing its tail */
    png_write_ok(tdir_file(&t, "cut.png"), 64, 64, noise, (size_t)w * 4, true, 6);
    struct stat st;
    assert_int_equal(stat(t.path, &st), 0);
    for (off_t keep = st.st_size - 1; keep > 0; keep = keep * 2 / 3) {
        assert_int_equal(truncate(t.path, keep), 0);
        uint8_t *out = (uint8_t *)1;
        uint32_t rw = 1, rh = 1;
        char err[512];
        assert_int_equal(vt_png_read(t.path, &out, &rw, &rh, NULL, err, sizeof err), VT_ERR_CORRUPT);
        assert_true(out == NULL && rw == 0 && rh == 0);
    }
    free(noise);
    tdir_remove(&t);
}

/* Threads writing and failing at once: each error lands in its own
 * thread's buffer, every good file reads back right. */
static void *img_thread_main(void *arg)
{
    test_thread *a = arg;
    uint32_t w = 45, h = 31;
    char png[400], jpg[400], junk[400], err[512];
    snprintf(png, sizeof png, "%s/t%d.png", a->t->dir, a->id);
    snprintf(jpg, sizeof jpg, "%s/t%d.jpg", a->t->dir, a->id);
    snprintf(junk, sizeof junk, "%s/junk%d", a->t->dir, a->id);
    uint8_t *px = malloc((size_t)w * h * 4);
    if (!px) {
        a->failures++;
        return NULL;
    }
    for (int it = 0; it < 20; it++) {
        for (size_t i = 0; i < (size_t)w * h * 4; i++) px[i] = (uint8_t)(a->id * 31 + it * 7 + i);
        uint8_t *got = NULL, *mem = NULL, *file = NULL;
        uint32_t rw, rh;
        size_t nm = 0;
        if (vt_png_write(png, w, h, px, (size_t)w * 4, true, it % 10, err, sizeof err) != 0 ||
            vt_png_read(png, &got, &rw, &rh, NULL, err, sizeof err) != 0 ||
            memcmp(got, px, (size_t)w * h * 4) != 0)
            a->failures++;
        free(got);
        if (vt_jpeg_write(jpg, w, h, px, (size_t)w * 4, 4, 50 + it, err, sizeof err) != 0 ||
            vt_jpeg_encode(w, h, px, (size_t)w * 4, 4, 50 + it, &mem, &nm, err, sizeof err) != 0)
            a->failures++;
        FILE *f = fopen(jpg, "rb");
        file = malloc(nm + 1);
        if (!f || !file || fread(file, 1, nm + 1, f) != nm || memcmp(file, mem, nm) != 0) a->failures++;
        if (f) fclose(f);
        free(file);
        free(mem);
        for (int k = 0; k < 20; k++) {
            a->failures += !test_refused_naming(vt_png_read(junk, &got, &rw, &rh, NULL, err, sizeof err), err, junk);
            a->failures += !test_refused_naming(vt_jpeg_read(junk, &got, &rw, &rh, err, sizeof err), err, junk);
        }
    }
    free(px);
    return NULL;
}

static void test_image_threads(void **state)
{
    (void)state;
    test_threads_in_tdir("vt_image_test", "", img_thread_main, 4, 3);
}

const struct CMUnitTest image_tests[] = {
    cmocka_unit_test(test_image_srgb_sweep),
    cmocka_unit_test(test_image_srgb_thresholds),
    cmocka_unit_test(test_image_tonemap_curve),
    cmocka_unit_test(test_image_tonemap_exact),
    cmocka_unit_test(test_image_tonemap_aces_table),
    cmocka_unit_test(test_image_tonemap_layouts),
    cmocka_unit_test(test_image_tonemap_rgbx),
    cmocka_unit_test(test_image_tonemap_bad_args),
    cmocka_unit_test(test_image_png_roundtrip),
    cmocka_unit_test(test_image_png_encode_memory),
    cmocka_unit_test(test_image_png_from_hdr),
    cmocka_unit_test(test_image_png_reader_formats),
    cmocka_unit_test(test_image_jpeg_roundtrip),
    cmocka_unit_test(test_image_jpeg_details),
    cmocka_unit_test(test_image_jpeg_bands),
    cmocka_unit_test(test_image_tonemap_frame_bands),
    cmocka_unit_test(test_image_resize),
    cmocka_unit_test(test_image_jpeg_frame),
    cmocka_unit_test(test_image_large),
    TEST_ROWS(test_image_png_bad_args, bad_png_rows),
    TEST_ROWS(test_image_jpeg_bad_args, bad_jpeg_rows),
    cmocka_unit_test(test_image_null_args),
    cmocka_unit_test(test_image_bad_path),
    cmocka_unit_test(test_image_failed_write_keeps_old),
    cmocka_unit_test(test_image_threads),
};
const size_t image_tests_count = sizeof image_tests / sizeof image_tests[0];

#else
typedef int vt_test_image_not_built; /* render/ not on the include path */
#endif
