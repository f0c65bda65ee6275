/*
 * test_protocol_doc.c — PROTOCOL.md's byte tables against the protocol's
 * own description of its layouts (vp_layout_find, made from the same
 * field lists as the encoders and decoders), so the specification cannot
 * drift from the code:
 *   - every table marked `<!-- layout: name -->` (or `... at N`: the
 *     layout starts at byte N of the table) lists the layout's fields in
 *     order with their offset, size, type and name (adjacent pads as one
 *     `pad` row), and the row after them, if any, starts where the layout
 *     ends (or at "..."): no field left out, none made up;
 *   - a field with a range check (range, count, irange) states its bounds in its
 *     row ("0..1", "-1e6..1e6");
 *   - every layout has a table, every table names a layout, and every
 *     VP_LAYOUT in protocol/ is in the list (vp_layout.c).
 * The description itself is checked against the wire: its sizes add up,
 * offsets are contiguous, and each layout's size is what the encoder of
 * the message writes (records read back at those offsets).
 */
#include "test_util.h"

#include "protocol.h"

#include <ctype.h>
#include <glob.h>
#include <math.h>

#define DOC_PATH "protocol/PROTOCOL.md"
#define MAX_ROWS 64
#define MAX_CELL 512

typedef struct doc_row {
    char cell[4][MAX_CELL]; /* offset, size, type, field */
    char all[4 * MAX_CELL]; /* the whole row, for the checks column */
} doc_row;

typedef struct doc_table {
    char name[64];
    unsigned base;
    int line;
    int nrows;
    doc_row rows[MAX_ROWS];
} doc_table;

static char *read_all(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (!f) fail_msg("cannot open %s (tests run from the repository root)", path);
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    char *s = malloc((size_t)n + 1);
    assert_non_null(s);
    assert_int_equal(fread(s, 1, (size_t)n, f), (size_t)n);
    s[n] = 0;
    fclose(f);
    return s;
}

static void trim_copy(char *dst, size_t cap, const char *a, const char *b)
{
    while (a < b && isspace((unsigned char)*a)) a++;
    while (b > a && isspace((unsigned char)b[-1])) b--;
    size_t n = (size_t)(b - a) < cap - 1 ? (size_t)(b - a) : cap - 1;
    memcpy(dst, a, n);
    dst[n] = 0;
}

/* The tables of the document (at most cap), parsed. */
static int parse_doc(const char *doc, doc_table *t, int cap)
{
    int n = 0, line = 1;
    for (const char *p = doc; *p;) {
        const char *eol = strchr(p, '\n');
        if (!eol) eol = p + strlen(p);
        char name[64];
        unsigned base = 0;
        int got = 0;
        if (!strncmp(p, "<!-- layout: ", 13)) {
            got = sscanf(p, "<!-- layout: %63[a-z_0-9] at %u", name, &base);
            if (got < 1) fail_msg("%s:%d: a layout mark without a name", DOC_PATH, line);
        }
        p = *eol ? eol + 1 : eol;
        line++;
        if (got < 1) continue;
        assert_true(n < cap);
        doc_table *d = &t[n++];
        memset(d, 0, sizeof *d);
        snprintf(d->name, sizeof d->name, "%s", name);
        d->base = got == 2 ? base : 0;
        d->line = line - 1;
        /* header and separator rows, then the rows up to the first non-row */
        for (int k = 0; *p == '|'; k++) {
            eol = strchr(p, '\n');
            if (!eol) eol = p + strlen(p);
            if (k >= 2) {
                if (d->nrows == MAX_ROWS) fail_msg("%s:%d: table too long", DOC_PATH, line);
                doc_row *r = &d->rows[d->nrows++];
                trim_copy(r->all, sizeof r->all, p, eol);
                const char *c = p + 1;
                for (int j = 0; j < 4; j++) {
                    const char *e = memchr(c, '|', (size_t)(eol - c));
                    if (!e) fail_msg("%s:%d: a row of fewer than 4 cells", DOC_PATH, line);
                    trim_copy(r->cell[j], MAX_CELL, c, e);
                    c = e + 1;
                }
            }
            p = *eol ? eol + 1 : eol;
            line++;
        }
        if (!d->nrows) fail_msg("%s:%d: layout %s marks no table", DOC_PATH, d->line, d->name);
    }
    return n;
}

static bool cell_uint(const char *c, unsigned *v)
{
    char *end;
    if (!isdigit((unsigned char)c[0])) return false;
    unsigned long x = strtoul(c, &end, 10);
    *v = (unsigned)x;
    return *end == 0;
}

/* A field of the layout as a table row shows it: adjacent pads are one row. */
typedef struct doc_field {
    const char *name;
    unsigned offset, size;
    char type[24];
    bool pad;
} doc_field;

static int doc_fields(const vp_layout_desc *d, doc_field *out, int cap)
{
    int n = 0;
    for (uint32_t i = 0; i < d->nfields; i++) {
        const vp_field_desc *f = &d->fields[i];
        bool pad = f->kind == VP_KIND_PAD || f->kind == VP_KIND_RSV;
        if (pad && n && out[n - 1].pad) {
            out[n - 1].size += f->size;
            continue;
        }
        assert_true(n < cap);
        doc_field *o = &out[n++];
        o->name = f->name;
        o->offset = f->offset;
        o->size = f->size;
        o->pad = pad;
        if (pad) snprintf(o->type, sizeof o->type, "pad");
        else if (f->count > 1) snprintf(o->type, sizeof o->type, "%s[%u]", vp_kind_name(f->kind), f->count);
        else snprintf(o->type, sizeof o->type, "%s", vp_kind_name(f->kind));
    }
    return n;
}

/* The ways a bound may be written: "1000000", "1e6", "1e+06", "0.001". */
static int bound_forms(double v, char out[4][32])
{
    int n = 0;
    snprintf(out[n++], 32, "%g", v);
    if (v == floor(v) && fabs(v) < 1e15) snprintf(out[n++], 32, "%.0f", v);
    double a = fabs(v);
    if (a >= 10) {
        int e = (int)lround(log10(a));
        for (double m = 1; m < 10; m++)
            if (fabs(m * pow(10, e) - a) < 1e-9 * a || fabs(m * pow(10, e - 1) - a) < 1e-9 * a) {
                int ee = fabs(m * pow(10, e) - a) < 1e-9 * a ? e : e - 1;
                if (m == 1) snprintf(out[n++], 32, "%s1e%d", v < 0 ? "-" : "", ee);
                else snprintf(out[n++], 32, "%s%.0fe%d", v < 0 ? "-" : "", m, ee);
                break;
            }
    }
    return n;
}

static bool row_states_range(const char *row, double lo, double hi)
{
    char l[4][32], h[4][32], want[160];
    int nl = bound_forms(lo, l), nh = bound_forms(hi, h);
    for (int i = 0; i < nl; i++)
        for (int j = 0; j < nh; j++) {
            snprintf(want, sizeof want, "%.31s..%.31s", l[i], h[j]);
            if (strstr(row, want)) return true;
        }
    return false;
}

/* One table against its layout; a failure names the line and the field. */
static void check_table(const doc_table *t, const vp_layout_desc *d)
{
    doc_field f[64];
    int nf = doc_fields(d, f, 64), start = -1;
    for (int i = 0; i < t->nrows && start < 0; i++) {
        unsigned off;
        if (cell_uint(t->rows[i].cell[0], &off) && off == t->base) start = i;
    }
    if (start < 0) fail_msg("%s:%d: %s: no row at offset %u", DOC_PATH, t->line, t->name, t->base);
    if (start + nf > t->nrows)
        fail_msg("%s:%d: %s has %d fields, the table %d rows from offset %u", DOC_PATH, t->line, t->name, nf,
                 t->nrows - start, t->base);
    for (int j = 0; j < nf; j++) {
        const doc_row *r = &t->rows[start + j];
        unsigned off = 0, size = 0;
        char want_name[160];
        snprintf(want_name, sizeof want_name, "`%s`", f[j].name);
        if (!cell_uint(r->cell[0], &off) || off != t->base + f[j].offset)
            fail_msg("%s:%d: %s field %s: offset '%s', the layout says %u", DOC_PATH, t->line, t->name, f[j].name,
                     r->cell[0], t->base + f[j].offset);
        if (!cell_uint(r->cell[1], &size) || size != f[j].size)
            fail_msg("%s:%d: %s field %s: size '%s', the layout says %u", DOC_PATH, t->line, t->name, f[j].name,
                     r->cell[1], f[j].size);
        if (strcmp(r->cell[2], f[j].type))
            fail_msg("%s:%d: %s field %s: type '%s', the layout says %s", DOC_PATH, t->line, t->name, f[j].name,
                     r->cell[2], f[j].type);
        if (!f[j].pad && strncmp(r->cell[3], want_name, strlen(want_name)))
            fail_msg("%s:%d: %s at offset %u: field '%s', the layout says %s", DOC_PATH, t->line, t->name, off,
                     r->cell[3], want_name);
    }
    if (start + nf < t->nrows) {
        unsigned off;
        const char *c = t->rows[start + nf].cell[0];
        if (cell_uint(c, &off) && off != t->base + d->size)
            fail_msg("%s:%d: %s ends at %u, the next row is at %s", DOC_PATH, t->line, t->name, t->base + d->size, c);
    }
    for (uint32_t k = 0; k < d->nchecks; k++) {
        const vp_check_desc *c = &d->checks[k];
        bool ranged = c->op == VP_CHECK_RANGE || c->op == VP_CHECK_COUNT || c->op == VP_CHECK_IRANGE;
        if (!ranged || !isfinite(c->lo) || !isfinite(c->hi)) continue;
        const doc_row *row = NULL;
        char want_name[160];
        snprintf(want_name, sizeof want_name, "`%s`", c->field);
        for (int j = start; j < start + nf; j++)
            if (!strncmp(t->rows[j].cell[3], want_name, strlen(want_name))) row = &t->rows[j];
        assert_non_null(row);
        if (!row_states_range(row->all, c->lo, c->hi))
            fail_msg("%s:%d: %s field %s: the row does not state its range %g..%g: %s", DOC_PATH, t->line, t->name,
                     c->field, c->lo, c->hi, row->all);
    }
}

static void test_doc_tables_match_layouts(void **state)
{
    (void)state;
    char *doc = read_all(DOC_PATH);
    doc_table *t = calloc(64, sizeof *t);
    assert_non_null(t);
    int n = parse_doc(doc, t, 64);
    for (int i = 0; i < n; i++) {
        const vp_layout_desc *d = vp_layout_find(t[i].name);
        if (!d) fail_msg("%s:%d: no layout named %s (vp_layout_find)", DOC_PATH, t[i].line, t[i].name);
        check_table(&t[i], d);
    }
    for (size_t k = 0; k < vp_layout_count(); k++) {
        const char *name = vp_layout_at(k)->name;
        int found = 0;
        for (int i = 0; i < n; i++) found += !strcmp(t[i].name, name);
        if (!found) fail_msg("layout %s has no byte table in %s (<!-- layout: %s -->)", name, DOC_PATH, name);
    }
    printf("%d tables of %zu layouts checked against %s\n", n, vp_layout_count(), DOC_PATH);
    free(t);
    free(doc);
}

/* Every VP_LAYOUT / VP_LAYOUT_CHECKED in protocol/ is in the list. */
static void test_every_layout_listed(void **state)
{
    (void)state;
    glob_t g;
    assert_int_equal(glob("protocol/*.c", 0, NULL, &g), 0);
    size_t seen = 0;
    for (size_t i = 0; i < g.gl_pathc; i++) {
        char *src = read_all(g.gl_pathv[i]);
        for (char *p = src; (p = strstr(p, "\nVP_LAYOUT")); p++) {
            char name[64];
            if (sscanf(p, "\nVP_LAYOUT(%63[a-z_0-9],", name) != 1 &&
                sscanf(p, "\nVP_LAYOUT_CHECKED(%63[a-z_0-9],", name) != 1)
                continue;
            seen++;
            if (!vp_layout_find(name)) fail_msg("%s: layout %s is not in VP_LAYOUT_NAMES (protocol/vp_layout.c)",
                                                g.gl_pathv[i], name);
        }
        free(src);
    }
    globfree(&g);
    assert_int_equal(seen, vp_layout_count());
}

/* The description is the wire: contiguous fields whose sizes add up, and
 * a record's bytes read back at the described offsets. */
static void test_layout_desc_is_the_wire(void **state)
{
    (void)state;
    for (size_t k = 0; k < vp_layout_count(); k++) {
        const vp_layout_desc *d = vp_layout_at(k);
        unsigned at = 0;
        for (uint32_t i = 0; i < d->nfields; i++) {
            assert_int_equal(d->fields[i].offset, at);
            assert_true(d->fields[i].count >= 1);
            at += d->fields[i].size;
        }
        assert_int_equal(at, d->size);
        for (uint32_t i = 0; i < d->nchecks; i++) {
            bool found = false;
            for (uint32_t j = 0; j < d->nfields; j++) found |= !strcmp(d->fields[j].name, d->checks[i].field);
            assert_true(found);
        }
    }
    assert_null(vp_layout_at(vp_layout_count()));
    assert_null(vp_layout_find("no such layout"));
    /* sizes the header states, and one record read at the described offsets */
    assert_int_equal(vp_layout_find("entity")->size, VP_ENTITY_REC_SIZE);
    assert_int_equal(vp_layout_find("entity_v1")->size, VP_ENTITY_REC_SIZE_V1);
    assert_int_equal(vp_layout_find("transform")->size, VP_TRANSFORM_REC_SIZE);
    assert_int_equal(vp_layout_find("material")->size + VP_TEX_SLOTS * vp_layout_find("texref")->size,
                     VP_MATERIAL_SIZE);
    assert_int_equal(vp_layout_find("texref")->size, VP_TEXREF_SIZE);
    assert_int_equal(vp_layout_find("texture_put")->size, VP_TEXTURE_PUT_HEADER);
    assert_int_equal(vp_layout_find("env")->size, VP_ENV_SIZE);
    assert_int_equal(vp_layout_find("light")->size, VP_LIGHT_SIZE);
    assert_int_equal(vp_layout_find("view")->size, VP_VIEW_SIZE);
    assert_int_equal(vp_layout_find("vis_rec")->size, VP_VIS_REC_SIZE);

    uint8_t buf[512];
    vp_writer w;
    vp_env e;
    vp_env_default(&e);
    e.ground_height = -12.5;
    e.sky_texture = 77;
    vp_writer_init(&w, buf, sizeof buf);
    vp_enc_env(&w, VP_ENV_SET, 1, &e);
    const vp_layout_desc *d = vp_layout_find("env");
    for (uint32_t i = 0; i < d->nfields; i++) {
        const vp_field_desc *f = &d->fields[i];
        const uint8_t *p = buf + VP_HEADER_SIZE + f->offset;
        if (!strcmp(f->name, "ground_height")) assert_true(vp_ld_f64(p) == -12.5);
        if (!strcmp(f->name, "sky_texture")) assert_int_equal(vp_ld_u32(p), 77);
        if (!strcmp(f->name, "sun_lux")) assert_true(vp_ld_f32(p) == e.sun_lux);
        if (!strcmp(f->name, "exposure_comp")) assert_true(vp_ld_f32(p) == e.exposure_comp);
    }
    vp_entity ent = {.id = 0x0102030405060708ull, .material = 99, .flags = VP_ENT_TRANSFORM,
                     .rot = {0, 0, 0, 1}, .scale = {1, 2, 3}, .aabb = {[5] = 6.5}};
    vp_writer_init(&w, buf, sizeof buf);
    vp_enc_entities(&w, VP_ENTITY_ADD, 1, &ent, 1);
    d = vp_layout_find("entity");
    for (uint32_t i = 0; i < d->nfields; i++) {
        const vp_field_desc *f = &d->fields[i];
        const uint8_t *p = buf + VP_HEADER_SIZE + 4 + f->offset;
        if (!strcmp(f->name, "material")) assert_int_equal(vp_ld_u32(p), 99);
        if (!strcmp(f->name, "scale")) assert_true(vp_ld_f32(p + 4) == 2.0f);
        if (!strcmp(f->name, "aabb")) assert_true(vp_ld_f64(p + 40) == 6.5);
        if (!strcmp(f->name, "id")) assert_true(vp_ld_u64(p) == ent.id);
    }
}

const struct CMUnitTest protocol_doc_tests[] = {
    cmocka_unit_test(test_layout_desc_is_the_wire),
    cmocka_unit_test(test_every_layout_listed),
    cmocka_unit_test(test_doc_tables_match_layouts),
};
const size_t protocol_doc_tests_count = sizeof protocol_doc_tests / sizeof protocol_doc_tests[0];
