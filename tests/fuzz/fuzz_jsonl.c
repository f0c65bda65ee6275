/*
 * fuzz_jsonl.c — libFuzzer target for the JSON lines parser behind
 * `vantage import` (jsonl_entity_parse, client/import/jsonl.c).
 *
 * The input is an import file. It is cut into lines as cmd_import cuts it
 * (at '\n', trailing '\r's dropped, empty lines skipped) and each line goes
 * to the parser from a heap block of exactly its length, with no NUL after
 * it, so ASan sees any read past the line. Properties:
 *   1. a refused line has a message (not empty, ended within err), and the
 *      record and the sub-level name come back cleared;
 *   2. an accepted record is what jsonl.h promises: handle 0, flags 0 or
 *      VP_ENT_DYNAMIC (and VP_ENT_TRANSFORM with a finite pos, rot and
 *      scale and a zero sphere and aabb), ten finite numbers, and either a
 *      sub-level name of
 *      1..255 bytes without control bytes (sublevel 0, the name decides) or
 *      no name;
 *   3. the wire takes it: an ENTITY_ADD frame of the record decodes
 *      (vp_dec_entities, vp_entity_get) to the same record, bit for bit
 *      (a transform's rotation renormalised as vp_trs_check does; one
 *      vp_trs_check refuses, the daemon's to refuse, is not sent);
 *   4. export -> import: the line jsonl_entity_format writes for it (the
 *      name escaped as `vantage export` escapes it), and the line with the
 *      handle that `vantage get` writes, parse back to the same record and
 *      name (numbers compared by value: a -0 comes back as 0).
 * The scene's record rules (r >= 0, min <= max, |x| <= 1e12, r <= 1e9) are
 * the daemon's to check, not the parser's, so nothing is asserted of them.
 * A broken property calls abort().
 */
#include "jsonl.h"
#include "protocol.h"

#define FUZZ_NAME "fuzz_jsonl"
#include "fuzz_check.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define ERR_LEN 160 /* cmd_import's */

static bool same_f64(double a, double b) { return memcmp(&a, &b, sizeof a) == 0; }

/* By value, as text can carry it: equal, and a 0 of either sign for a 0. */
static bool same_value(double a, double b) { return same_f64(a, b) || (a == 0 && b == 0); }

static bool all_zero(const void *p, size_t n)
{
    const uint8_t *b = p;
    for (size_t i = 0; i < n; i++)
        if (b[i]) return false;
    return true;
}

/* Parses line[0..len) from an exact heap copy; the parser's result. */
static bool parse_exact(const char *line, size_t len, vp_entity *e, char *sub, char *err)
{
    char *copy = malloc(len ? len : 1);
    CHECK(copy != NULL);
    memcpy(copy, line, len);
    memset(err, 0x55, ERR_LEN);
    bool ok = jsonl_entity_parse(copy, len, e, sub, err, ERR_LEN);
    free(copy);
    return ok;
}

/* The scene model's fields of a and b the same (eq on the position). */
static bool same_model(const vp_entity *a, const vp_entity *b, bool (*eq)(double, double))
{
    for (int k = 0; k < 3; k++)
        if (!eq(a->pos[k], b->pos[k]) || !eq(a->scale[k], b->scale[k])) return false;
    for (int k = 0; k < 4; k++)
        if (!eq(a->rot[k], b->rot[k])) return false;
    return a->material == b->material;
}

/* 3: ENTITY_ADD with the one record, through the decoder and the getter. */
static void check_wire(const vp_entity *rec)
{
    vp_entity copy = *rec, *e = &copy;
    if ((e->flags & VP_ENT_TRANSFORM) && vp_trs_check(e->pos, e->rot, e->scale, NULL, 0) != VP_OK) return;
    size_t cap = vp_size_entities(1), len;
    fuzz_wbuf w;
    fuzz_wopen(&w, cap);
    vp_enc_entities(&w.w, VP_ENTITY_ADD, 1, e, 1);
    CHECK(w.w.len == cap);
    const uint8_t *p = fuzz_wframe(&w, VP_ENTITY_ADD, &len);
    vp_entity_batch b;
    CHECK(vp_dec_entities(p, len, 0, &b) == VP_OK);
    CHECK(b.count == 1);
    vp_entity back;
    CHECK(vp_entity_get(&b, 0, &back) == VP_OK);
    CHECK(fuzz_same_entity(e, &back, same_f64));
    if (e->flags & VP_ENT_TRANSFORM) CHECK(vp_trs_check(e->pos, e->rot, e->scale, NULL, 0) == VP_OK);
    CHECK(same_model(e, &back, same_f64)); /* (renormalising twice may move a bit: the getter's rot is e's, checked) */
    fuzz_wclose(&w);
}

/* 4: the export line (and the `get` line, with the handle) parse back. */
static void check_export(const vp_entity *e, const char *sub)
{
    char esc[6 * VP_MAX_NAME + 1];
    size_t sl = strlen(sub);
    CHECK(sl <= VP_MAX_NAME);
    if (sl) cli_json_escape(esc, sub, sl);
    for (int handle = 0; handle < 2; handle++) {
        char line[JSONL_LINE_MAX];
        int n = jsonl_entity_format(line, sizeof line, e, handle, sl ? esc : NULL);
        CHECK(n > 1 && (size_t)n < sizeof line);
        CHECK(line[n - 1] == '\n' && strchr(line, '\n') == line + n - 1);
        vp_entity back;
        char bsub[VP_MAX_NAME + 1], err[ERR_LEN];
        bool ok = parse_exact(line, (size_t)n - 1, &back, bsub, err);
        if (!ok) fprintf(stderr, "fuzz_jsonl: the export line is refused: %s\n%s", err, line);
        CHECK(ok);
        CHECK(fuzz_same_entity(e, &back, same_value));
        CHECK(same_model(e, &back, same_value));
        CHECK(strcmp(sub, bsub) == 0);
    }
}

static void check_line(const char *line, size_t len)
{
    vp_entity e;
    char sub[VP_MAX_NAME + 1], err[ERR_LEN];
    memset(&e, 0xA5, sizeof e);
    memset(sub, 0xA5, sizeof sub);
    bool ok = parse_exact(line, len, &e, sub, err);
    if (!ok) {
        /* 1 */
        CHECK(memchr(err, 0, ERR_LEN) != NULL);
        CHECK(err[0] != 0);
        CHECK(all_zero(&e, sizeof e));
        CHECK(sub[0] == 0);
        return;
    }
    /* 2 */
    CHECK(e.handle == 0);
    CHECK((e.flags & ~(VP_ENT_DYNAMIC | VP_ENT_TRANSFORM)) == 0);
    for (int k = 0; k < 3; k++) CHECK(isfinite(e.pos[k]) && isfinite(e.scale[k]));
    for (int k = 0; k < 4; k++) CHECK(isfinite(e.rot[k]));
    if (e.flags & VP_ENT_TRANSFORM) {
        CHECK(all_zero(e.sphere, sizeof e.sphere));
        CHECK(all_zero(e.aabb, sizeof e.aabb));
    }
    for (int k = 0; k < 4; k++) CHECK(isfinite(e.sphere[k]));
    for (int k = 0; k < 6; k++) CHECK(isfinite(e.aabb[k]));
    size_t sl = strnlen(sub, sizeof sub);
    CHECK(sl < sizeof sub);
    if (sl) {
        CHECK(e.sublevel == 0);
        for (size_t i = 0; i < sl; i++) CHECK((unsigned char)sub[i] >= 32 && sub[i] != 127);
    }
    check_wire(&e);
    check_export(&e, sub);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    const char *p = (const char *)data, *end = p + size;
    while (p < end) {
        const char *nl = memchr(p, '\n', (size_t)(end - p));
        size_t len = nl ? (size_t)(nl - p) : (size_t)(end - p);
        size_t l = len;
        while (l > 0 && (p[l - 1] == '\r' || p[l - 1] == '\n')) l--;
        if (l) check_line(p, l);
        p += len + (nl != NULL);
    }
    return 0;
}
