/*
 * test_errmap.c — the error spaces (docs/ARCHITECTURE.md, "Error spaces"):
 * every row of every module's table has a message, and the daemon's one
 * translation (daemon/errmap.c) sends each to a defined protocol code; the
 * mapping decisions clients rely on, written out here as the spec; the one
 * formatter, vp_errf.
 */
#include "test_util.h"

#include "culling.h"
#include "errmap.h"
#include "protocol.h"
#include "vantage.h"
#include "vt_err.h"

#include <string.h>

typedef struct row {
    const char *name;
    int         value;
    const char *msg;
} row;

#define ROW(name, value, msg) {#name, value, msg},
static const row cull_rows[] = {CULL_ERRORS(ROW)};
static const row vt_rows[] = {VT_ERRORS(ROW)};
static const row vp_rows[] = {VP_ERRORS(ROW)};
static const row vtc_rows[] = {VTC_ERRORS(ROW)};
#undef ROW

typedef struct table {
    const char *module;
    const row  *rows;
    size_t      n;
    const char *(*msg)(int);
    int (*to_vp)(int); /* NULL: the protocol's own table */
} table;

static const table tables[] = {
    {"culling", cull_rows, sizeof cull_rows / sizeof cull_rows[0], cull_strerror, vp_code_from_cull},
    {"render", vt_rows, sizeof vt_rows / sizeof vt_rows[0], vt_strerror, vp_code_from_vt},
    {"protocol", vp_rows, sizeof vp_rows / sizeof vp_rows[0], vp_strerror, NULL},
    {"client library", vtc_rows, sizeof vtc_rows / sizeof vtc_rows[0], vtc_strerror, NULL},
};

static bool vp_defined(int code)
{
    for (size_t i = 0; i < sizeof vp_rows / sizeof vp_rows[0]; i++)
        if (vp_rows[i].value == code) return true;
    return false;
}

/* Every row: a unique value and name, its own message back from the
 * module's strerror; every module row maps to a protocol row that is an
 * error (negative) exactly when the module's is, never to NEED_MORE. */
static void test_errmap_every_code(void **state)
{
    (void)state;
    for (size_t t = 0; t < sizeof tables / sizeof tables[0]; t++) {
        const table *tb = &tables[t];
        assert_true(tb->n >= (tb->rows == vtc_rows ? 1u : 2u)); /* the client library has one code */
        for (size_t i = 0; i < tb->n; i++) {
            const row *r = &tb->rows[i];
            if (strcmp(tb->msg(r->value), r->msg) != 0 || !r->msg[0] || !strcmp(r->msg, "unknown error"))
                fail_msg("%s: %s (%d) has message '%s', strerror says '%s'", tb->module, r->name, r->value, r->msg,
                         tb->msg(r->value));
            for (size_t k = 0; k < i; k++)
                if (tb->rows[k].value == r->value || !strcmp(tb->rows[k].name, r->name))
                    fail_msg("%s: %s and %s share a value or a name", tb->module, tb->rows[k].name, r->name);
            if (!tb->to_vp) continue;
            int vp = tb->to_vp(r->value);
            if (!vp_defined(vp) || vp == VP_NEED_MORE || (vp == VP_OK) != (r->value == 0) || vp > 0)
                fail_msg("%s: %s (%d) maps to %d (%s)", tb->module, r->name, r->value, vp, vp_strerror(vp));
        }
        /* a value in no row: "unknown error", and the daemon calls it internal */
        assert_string_equal(tb->msg(-12345), "unknown error");
        if (tb->to_vp) assert_int_equal(tb->to_vp(-12345), VP_ERR_INTERNAL);
    }
}

/* The decisions, one per line: what a client sees for each cause. */
static void test_errmap_decisions(void **state)
{
    (void)state;
    static const struct {
        int (*to_vp)(int);
        int code, want;
        const char *why;
    } spec[] = {
        {vp_code_from_cull, CULL_ERR_NOMEM, VP_ERR_BUSY, "out of memory is the server's state: retry"},
        {vp_code_from_vt, VT_ERR_NOMEM, VP_ERR_BUSY, "out of memory, the same from every module"},
        {vp_code_from_cull, CULL_ERR_CAPACITY, VP_ERR_LIMIT, "entity capacity is a fixed limit"},
        {vp_code_from_vt, VT_ERR_RANGE, VP_ERR_LIMIT, "a frame beyond the GL limits"},
        {vp_code_from_vt, VT_ERR_TOO_LARGE, VP_ERR_LIMIT, "an image beyond the size limit"},
        {vp_code_from_cull, CULL_ERR_HANDLE, VP_ERR_STALE, "a stale handle"},
        {vp_code_from_cull, CULL_ERR_MATRIX, VP_ERR_MATRIX, "a degenerate view"},
        {vp_code_from_cull, CULL_ERR_NONFINITE, VP_ERR_NONFINITE, "NaN or infinity"},
        {vp_code_from_cull, CULL_ERR_RANGE, VP_ERR_INVALID, "beyond the world: a bad value, not a scene state"},
        {vp_code_from_cull, CULL_ERR_VIEWPORT, VP_ERR_INVALID, "a bad viewport"},
        {vp_code_from_cull, CULL_ERR_VIEWS, VP_ERR_COUNT, "too many views"},
        {vp_code_from_vt, VT_ERR_INVALID, VP_ERR_INVALID, "both renderers refuse bad input alike"},
        {vp_code_from_vt, VT_ERR_NO_DISPLAY, VP_ERR_UNSUPPORTED, "no GL here"},
        {vp_code_from_vt, VT_ERR_NO_CONTEXT, VP_ERR_UNSUPPORTED, "no GL 3.3 core here"},
        {vp_code_from_vt, VT_ERR_GL, VP_ERR_INTERNAL, "a GL call failed"},
        {vp_code_from_vt, VT_ERR_CODEC, VP_ERR_INTERNAL, "the JPEG encoder failed"},
        {vp_code_from_vt, VT_ERR_CANCELLED, VP_ERR_BUSY, "a picture stopped: the server's state, not the request"},
        {vp_code_from_cull, CULL_ERR_OUTPUT, VP_ERR_INTERNAL, "the daemon sized a buffer wrong"},
    };
    for (size_t i = 0; i < sizeof spec / sizeof spec[0]; i++) {
        int got = spec[i].to_vp(spec[i].code);
        if (got != spec[i].want)
            fail_msg("%s: %d maps to %s, want %s", spec[i].why, spec[i].code, vp_strerror(got),
                     vp_strerror(spec[i].want));
    }
    assert_int_equal(vp_code_from_cull(CULL_OK), VP_OK);
    /* the client library's codes sit beside the protocol's, none shared:
       vtc_strerror names both */
    for (size_t i = 0; i < sizeof vtc_rows / sizeof vtc_rows[0]; i++)
        if (vp_defined(vtc_rows[i].value)) fail_msg("%s shares a protocol code", vtc_rows[i].name);
    for (size_t i = 0; i < sizeof vp_rows / sizeof vp_rows[0]; i++)
        assert_string_equal(vtc_strerror(vp_rows[i].value), vp_rows[i].msg);
    assert_int_equal(vp_code_from_vt(VT_OK), VP_OK);
}

/* The one formatter: returns its code, writes at most errlen bytes with
 * a NUL, and writes nothing without a buffer. */
static void test_errmap_errf(void **state)
{
    (void)state;
    char buf[8];
    memset(buf, 'x', sizeof buf);
    assert_int_equal(vp_errf(buf, sizeof buf, CULL_ERR_RANGE, "%s %d", "value", 12345), CULL_ERR_RANGE);
    assert_string_equal(buf, "value 1"); /* cut to 7 bytes and the NUL */
    assert_int_equal(vp_errf(NULL, 100, VT_ERR_GL, "%s", "nothing"), VT_ERR_GL);
    memset(buf, 'x', sizeof buf);
    assert_int_equal(vp_errf(buf, 0, -1, "%s", "nothing"), -1);
    assert_int_equal(buf[0], 'x');
    assert_int_equal(vp_errf(buf, sizeof buf, 0, "ok"), 0);
    assert_string_equal(buf, "ok");
}

const struct CMUnitTest errmap_tests[] = {
    cmocka_unit_test(test_errmap_every_code),
    cmocka_unit_test(test_errmap_decisions),
    cmocka_unit_test(test_errmap_errf),
};
const size_t errmap_tests_count = sizeof errmap_tests / sizeof errmap_tests[0];
