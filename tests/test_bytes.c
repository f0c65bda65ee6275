/*
 * test_bytes.c — the one byte serializer (protocol/vp_bytes.h) and the one
 * grow rule (protocol/vp_grow.h), each beside a model: the writer's bytes
 * against little-endian layouts written out by hand, the reader's sticky
 * failure, the capacity rule against a slow model in 128-bit arithmetic
 * (the guard rows near SIZE_MAX and 2^31 included), and the importer's pipe
 * (client/import/import_pack.c) read back whole and refused at every cut.
 */
#include "test_util.h"

#include "import_internal.h"
#include "vp_bytes.h"
#include "vp_grow.h"

#include <stdio.h>
#include <string.h>

/* ---- the writer and the reader ------------------------------------------------------------- */

/* Every put against the bytes PROTOCOL.md's little-endian rule gives. */
static void test_bytes_layout(void **state)
{
    (void)state;
    uint8_t buf[64];
    vp_writer w;
    vp_writer_init(&w, buf, sizeof buf);
    vp_put_u8(&w, 0xA1);
    vp_put_u16(&w, 0xB2C3);
    vp_put_u32(&w, 0xD4E5F607u);
    vp_put_u64(&w, 0x0102030405060708ull);
    vp_put_i32(&w, -2);
    vp_put_f32(&w, 1.0f);   /* 0x3F800000 */
    vp_put_f64(&w, -2.0);   /* 0xC000000000000000 */
    vp_put_bytes(&w, "xy", 2);
    vp_put_bytes(&w, NULL, 0);
    static const uint8_t want[] = {0xA1, 0xC3, 0xB2, 0x07, 0xF6, 0xE5, 0xD4, 0x08, 0x07, 0x06, 0x05, 0x04, 0x03,
                                   0x02, 0x01, 0xFE, 0xFF, 0xFF, 0xFF, 0x00, 0x00, 0x80, 0x3F, 0, 0, 0,
                                   0,    0,    0,    0,    0xC0, 'x',  'y'};
    assert_false(w.overflow);
    assert_int_equal(w.len, sizeof want);
    assert_memory_equal(buf, want, sizeof want);
    vp_reader r;
    vp_reader_init(&r, buf, w.len);
    assert_int_equal(vp_get_u8(&r), 0xA1);
    assert_int_equal(vp_get_u16(&r), 0xB2C3);
    assert_int_equal(vp_get_u32(&r), 0xD4E5F607u);
    assert_true(vp_get_u64(&r) == 0x0102030405060708ull);
    assert_int_equal(vp_get_i32(&r), -2);
    assert_true(vp_get_f32(&r) == 1.0f);
    assert_true(vp_get_f64(&r) == -2.0);
    assert_memory_equal(vp_get_bytes(&r, 2), "xy", 2);
    assert_int_equal(vp_remaining(&r), 0);
    assert_false(r.short_read);
    /* the loads and stores at a pointer are the same bytes */
    uint8_t p[8];
    vp_st_u16(p, 0xB2C3);
    assert_memory_equal(p, want + 1, 2);
    vp_st_u32(p, 0xD4E5F607u);
    assert_memory_equal(p, want + 3, 4);
    vp_st_u64(p, 0x0102030405060708ull);
    assert_memory_equal(p, want + 7, 8);
    assert_int_equal(vp_ld_u16(want + 1), 0xB2C3);
    assert_true(vp_ld_f64(want + 23) == -2.0);
}

/* A fixed writer: the put that does not fit writes nothing, and nothing
 * after it is written either, even what would fit. */
static void test_bytes_writer_overflow_sticks(void **state)
{
    (void)state;
    uint8_t buf[8];
    memset(buf, 0xEE, sizeof buf);
    vp_writer w;
    vp_writer_init(&w, buf, 6);
    vp_put_u32(&w, 0x11223344u);
    vp_put_u32(&w, 0x55667788u); /* 2 bytes of room: refused */
    assert_true(w.overflow);
    assert_int_equal(w.len, 4);
    vp_put_u8(&w, 0x99); /* would fit, but the writer has failed */
    vp_put_bytes(&w, "z", 1);
    assert_int_equal(w.len, 4);
    static const uint8_t want[8] = {0x44, 0x33, 0x22, 0x11, 0xEE, 0xEE, 0xEE, 0xEE};
    assert_memory_equal(buf, want, 8);
    /* a size that would wrap len + n is refused, not wrapped */
    vp_writer_init(&w, buf, sizeof buf);
    vp_put_u8(&w, 1);
    assert_null(vp_reserve(&w, SIZE_MAX));
    assert_true(w.overflow);
}

/* A growing writer holds what a model buffer holds, put by put, across
 * many regrowths; a size past SIZE_MAX fails it cleanly. */
static void test_bytes_writer_grows(void **state)
{
    (void)state;
    rng r = {test_seed() ^ 0xB17E5ull};
    enum { TOTAL = 1 << 20 };
    uint8_t *model = malloc(TOTAL);
    assert_non_null(model);
    size_t n = 0;
    vp_writer w;
    vp_writer_init_grow(&w);
    while (n + 64 <= TOTAL) {
        uint32_t k = rng_below(&r, 4);
        uint64_t v = rng_u64(&r);
        if (k == 0) {
            vp_put_u8(&w, (uint8_t)v);
            model[n++] = (uint8_t)v;
        } else if (k == 1) {
            vp_put_u32(&w, (uint32_t)v);
            for (int i = 0; i < 4; i++) model[n++] = (uint8_t)(v >> (8 * i));
        } else if (k == 2) {
            vp_put_u64(&w, v);
            for (int i = 0; i < 8; i++) model[n++] = (uint8_t)(v >> (8 * i));
        } else {
            size_t m = rng_below(&r, 48);
            uint8_t b[48];
            for (size_t i = 0; i < m; i++) b[i] = (uint8_t)rng_u64(&r);
            vp_put_bytes(&w, b, m);
            memcpy(model + n, b, m);
            n += m;
        }
        assert_false(w.overflow);
        assert_true(w.cap >= w.len);
    }
    assert_int_equal(w.len, n);
    assert_memory_equal(w.p, model, n);
    assert_null(vp_reserve(&w, SIZE_MAX - 2));
    assert_true(w.overflow);
    assert_int_equal(w.len, n); /* nothing of it counted */
    vp_writer_free(&w);
    assert_null(w.p);
    free(model);
}

/* The reader: a read past the end returns zeros and fails every read
 * after it, even one that would fit; counts whose byte size wraps are
 * refused by division. */
static void test_bytes_reader_short_read_sticks(void **state)
{
    (void)state;
    static const uint8_t b[6] = {1, 0, 0, 0, 0xAA, 0xBB};
    vp_reader r;
    vp_reader_init(&r, b, sizeof b);
    assert_int_equal(vp_get_u32(&r), 1);
    assert_int_equal(vp_get_u32(&r), 0); /* 2 left: short */
    assert_true(r.short_read);
    assert_int_equal(vp_get_u8(&r), 0);  /* would fit: still failed */
    assert_null(vp_get_bytes(&r, 1));
    assert_int_equal(vp_remaining(&r), 0);
    uint8_t dst[4] = {9, 9, 9, 9};
    vp_get_copy(&r, dst, sizeof dst);
    static const uint8_t zero[4] = {0};
    assert_memory_equal(dst, zero, 4);

    vp_reader_init(&r, b, sizeof b);
    assert_null(vp_get_array(&r, SIZE_MAX / 4 + 2, 4)); /* 4 n wraps to 4 */
    assert_true(r.short_read);
    vp_reader_init(&r, b, sizeof b);
    const uint8_t *a = vp_get_array(&r, 3, 2);
    assert_ptr_equal(a, b);
    assert_int_equal(vp_remaining(&r), 0);
    assert_null(vp_get_array(&r, 1, 1));
}

/* ---- the grow rule -------------------------------------------------------------------------------- */

/* The rule, slowly, in 128-bit arithmetic where nothing wraps: the first of
 * cap (first when 0), 2x, 4x, ... that holds need, if it is at most max
 * and its bytes at most SIZE_MAX; else 0. */
static size_t grow_model(size_t cap, size_t need, size_t first, size_t elem, size_t max)
{
    if (cap && need <= cap) return cap;
    unsigned __int128 c = cap ? cap : first;
    while (c < need) c *= 2;
    if (c > max || c * elem > SIZE_MAX) return 0;
    return (size_t)c;
}

static void test_grow_against_model(void **state)
{
    (void)state;
    /* the guard's rows: near SIZE_MAX and near 2^31 */
    static const struct { size_t cap, need, first, elem, max; } row[] = {
        {0, 1, 8, 1, SIZE_MAX},
        {8, 9, 8, 4, SIZE_MAX},
        {(size_t)1 << 62, ((size_t)1 << 62) + 1, 8, 1, SIZE_MAX},       /* 2^63: fits */
        {(size_t)1 << 63, ((size_t)1 << 63) + 1, 8, 1, SIZE_MAX},       /* 2^64 wraps: refused */
        {SIZE_MAX / 2 + 1, SIZE_MAX, 8, 1, SIZE_MAX},
        {0, SIZE_MAX, 8, 1, SIZE_MAX},
        {0, SIZE_MAX / 8 + 1, 8, 8, SIZE_MAX},                           /* bytes past SIZE_MAX */
        {0, (size_t)1 << 31, 8, 36, (size_t)1 << 31},                    /* vp_grow32's last */
        {(size_t)1 << 31, ((size_t)1 << 31) + 1, 8, 36, (size_t)1 << 31}, /* past it */
        {64, 0x80000001u, 64, 36, UINT32_MAX},                           /* import.c's old spin */
        {0, 100, 16, 8, UINT32_MAX},
        {0, 0, 16, 4, UINT32_MAX}, /* an empty table still gets its first size */
        {0, 0, 64, 4, 32},         /* unless that is past the maximum */
    };
    for (size_t i = 0; i < sizeof row / sizeof row[0]; i++) {
        size_t got = vp_grow_cap(row[i].cap, row[i].need, row[i].first, row[i].elem, row[i].max);
        size_t want = grow_model(row[i].cap, row[i].need, row[i].first, row[i].elem, row[i].max);
        if (got != want) fail_msg("row %zu: %zu, the model says %zu", i, got, want);
    }
    assert_int_equal(vp_grow_cap((size_t)1 << 63, ((size_t)1 << 63) + 1, 8, 1, SIZE_MAX), 0);
    assert_int_equal(vp_grow_cap(0, 0, 16, 4, UINT32_MAX), 16);
    rng r = {test_seed() ^ 0x6E0ull};
    int iters = (int)(20000 * test_scale());
    for (int it = 0; it < iters; it++) {
        size_t first = (size_t)1 << rng_below(&r, 8);
        size_t cap = rng_below(&r, 4) ? first << rng_below(&r, 60) : 0;
        size_t need = rng_below(&r, 2) ? (size_t)(rng_u64(&r) >> rng_below(&r, 64)) : cap + rng_below(&r, 3);
        size_t elem = 1 + rng_below(&r, 64);
        size_t max = rng_below(&r, 2) ? SIZE_MAX : (size_t)(rng_u64(&r) >> rng_below(&r, 64));
        size_t got = vp_grow_cap(cap, need, first, elem, max);
        size_t want = grow_model(cap, need, first, elem, max);
        if (got != want)
            fail_msg("cap %zu need %zu first %zu elem %zu max %zu: %zu, the model says %zu", cap, need, first, elem,
                     max, got, want);
    }
}

/* vp_grow and vp_grow32 past the guard: false, the array as it was. */
static void test_grow_refusal_keeps_the_array(void **state)
{
    (void)state;
    uint32_t *a = NULL;
    size_t cap = 0;
    assert_true(vp_grow((void **)&a, &cap, 3, sizeof *a));
    assert_int_equal(cap, 8);
    a[0] = 7;
    uint32_t *keep = a;
    assert_false(vp_grow((void **)&a, &cap, SIZE_MAX / 2, sizeof *a));
    assert_ptr_equal(a, keep);
    assert_int_equal(cap, 8);
    uint32_t c32 = 8;
    assert_false(vp_grow32((void **)&a, &c32, ((size_t)1 << 31) + 1, sizeof *a));
    assert_false(vp_grow32((void **)&a, &c32, (size_t)UINT32_MAX + 17, sizeof *a)); /* a wrapped sum, widened */
    assert_ptr_equal(a, keep);
    assert_int_equal(c32, 8);
    assert_int_equal(a[0], 7);
    assert_true(vp_grow32((void **)&a, &c32, 100, sizeof *a));
    assert_int_equal(c32, 128);
    assert_int_equal(a[0], 7);
    free(a);
}

/* ---- the importer's pipe ---------------------------------------------------------------------- */

/* Two levels hold the same, field for field (the pipe's bytes and the
 * child's isolation must change nothing). */
void test_level_equal(const imp_level *a, const imp_level *b)
{
    assert_int_equal(a->nmesh, b->nmesh);
    assert_int_equal(a->nent, b->nent);
    assert_int_equal(a->nocc, b->nocc);
    assert_int_equal(a->nlight, b->nlight);
    assert_int_equal(a->skipped_lights, b->skipped_lights);
    assert_int_equal(a->skipped_prims, b->skipped_prims);
    for (uint32_t i = 0; i < a->nmesh; i++) {
        assert_int_equal(a->mesh[i].nv, b->mesh[i].nv);
        assert_int_equal(a->mesh[i].ni, b->mesh[i].ni);
        assert_memory_equal(a->mesh[i].pos, b->mesh[i].pos, a->mesh[i].nv * 3 * sizeof(float));
        assert_memory_equal(a->mesh[i].nrm, b->mesh[i].nrm, a->mesh[i].nv * 3 * sizeof(float));
        assert_memory_equal(a->mesh[i].idx, b->mesh[i].idx, a->mesh[i].ni * sizeof(uint32_t));
        assert_int_equal(a->mesh[i].material, b->mesh[i].material);
        assert_int_equal(!a->mesh[i].uv, !b->mesh[i].uv);
        assert_int_equal(!a->mesh[i].tan, !b->mesh[i].tan);
        if (a->mesh[i].uv) assert_memory_equal(a->mesh[i].uv, b->mesh[i].uv, a->mesh[i].nv * 2 * sizeof(float));
        if (a->mesh[i].tan) assert_memory_equal(a->mesh[i].tan, b->mesh[i].tan, a->mesh[i].nv * 4 * sizeof(float));
    }
    assert_int_equal(a->nmat, b->nmat);
    for (uint32_t i = 0; i < a->nmat; i++) assert_memory_equal(&a->mat[i], &b->mat[i], sizeof a->mat[i]);
    assert_int_equal(a->ntex, b->ntex);
    for (uint32_t i = 0; i < a->ntex; i++) {
        assert_true(a->tex[i].id == b->tex[i].id && a->tex[i].format == b->tex[i].format &&
                    a->tex[i].flags == b->tex[i].flags && a->tex[i].nbytes == b->tex[i].nbytes);
        assert_memory_equal(a->tex[i].bytes, b->tex[i].bytes, a->tex[i].nbytes);
    }
    assert_int_equal(a->has_sun, b->has_sun);
    assert_memory_equal(a->sun_dir, b->sun_dir, sizeof a->sun_dir);
    assert_memory_equal(a->sun_color, b->sun_color, sizeof a->sun_color);
    assert_true(a->sun_lux == b->sun_lux);
    for (uint32_t i = 0; i < a->nent; i++) {
        assert_int_equal(a->ent[i].cls, b->ent[i].cls);
        assert_int_equal(a->ent[i].material, b->ent[i].material);
        assert_memory_equal(a->ent[i].pos, b->ent[i].pos, sizeof a->ent[i].pos);
        assert_memory_equal(a->ent[i].rot, b->ent[i].rot, sizeof a->ent[i].rot);
        assert_memory_equal(a->ent[i].scale, b->ent[i].scale, sizeof a->ent[i].scale);
        assert_memory_equal(a->ent[i].lo, b->ent[i].lo, sizeof a->ent[i].lo);
        assert_memory_equal(a->ent[i].hi, b->ent[i].hi, sizeof a->ent[i].hi);
        assert_int_equal(a->ent[i].dynamic, b->ent[i].dynamic);
        assert_int_equal(a->ent[i].occluder, b->ent[i].occluder);
        assert_string_equal(a->ent[i].name, b->ent[i].name);
    }
    for (uint32_t i = 0; i < a->nocc; i++) {
        assert_memory_equal(a->occ[i].origin, b->occ[i].origin, sizeof a->occ[i].origin);
        assert_int_equal(a->occ[i].ntri, b->occ[i].ntri);
        assert_memory_equal(a->occ[i].tri, b->occ[i].tri, a->occ[i].ntri * 9 * sizeof(float));
        assert_int_equal(a->occ[i].entity, b->occ[i].entity);
        assert_string_equal(a->occ[i].name, b->occ[i].name);
    }
    for (uint32_t i = 0; i < a->nlight; i++) {
        const vp_light *x = &a->light[i], *y = &b->light[i];
        assert_true(x->id == y->id && x->kind == y->kind);
        assert_memory_equal(x->pos, y->pos, sizeof x->pos);
        assert_memory_equal(x->dir, y->dir, sizeof x->dir);
        assert_memory_equal(x->color, y->color, sizeof x->color);
        assert_true(x->intensity == y->intensity && x->range == y->range && x->inner_cos == y->inner_cos &&
                    x->outer_cos == y->outer_cos);
    }
}

/* A level packed and unpacked is the level; every proper prefix of its
 * bytes, and the bytes with one more, are refused (ASan watches the
 * reads), and what a refusal leaves is freed by imp_level_free. */
static void test_import_pack_round_trip_and_cuts(void **state)
{
    (void)state;
    const char *dir = getenv("VANTAGE_DATA_DIR");
    char path[512];
    snprintf(path, sizeof path, "%s/level_small.gltf", dir ? dir : "tests/data");
    FILE *f = fopen(path, "rb");
    assert_non_null(f);
    static char file[1 << 20];
    size_t fn = fread(file, 1, sizeof file, f);
    fclose(f);
    imp_level lv, back;
    char err[512];
    if (imp_level_import_mem(file, fn, "gltf", &lv, err, sizeof err)) fail_msg("%s", err);
    assert_true(lv.nmesh && lv.nent && lv.nocc && lv.nlight);
    vp_writer w;
    vp_writer_init_grow(&w);
    imp_level_pack(&w, &lv);
    assert_false(w.overflow);
    vp_reader r;
    vp_reader_init(&r, w.p, w.len);
    memset(&back, 0, sizeof back);
    assert_true(imp_level_unpack(&r, &back));
    test_level_equal(&lv, &back);
    imp_level_free(&back);
    for (size_t cut = 0; cut < w.len; cut++) {
        uint8_t *exact = malloc(cut + 1); /* exact size: ASan sees any overread */
        memcpy(exact, w.p, cut);
        vp_reader_init(&r, exact, cut);
        memset(&back, 0, sizeof back);
        if (imp_level_unpack(&r, &back)) fail_msg("a level cut at %zu of %zu bytes was taken", cut, w.len);
        imp_level_free(&back);
        free(exact);
    }
    vp_put_u8(&w, 0);
    vp_reader_init(&r, w.p, w.len);
    memset(&back, 0, sizeof back);
    assert_false(imp_level_unpack(&r, &back));
    imp_level_free(&back);
    vp_writer_free(&w);
    imp_level_free(&lv);
}

const struct CMUnitTest bytes_tests[] = {
    cmocka_unit_test(test_bytes_layout),
    cmocka_unit_test(test_bytes_writer_overflow_sticks),
    cmocka_unit_test(test_bytes_writer_grows),
    cmocka_unit_test(test_bytes_reader_short_read_sticks),
    cmocka_unit_test(test_grow_against_model),
    cmocka_unit_test(test_grow_refusal_keeps_the_array),
    cmocka_unit_test(test_import_pack_round_trip_and_cuts),
};
const size_t bytes_tests_count = sizeof bytes_tests / sizeof bytes_tests[0];
