/*
 * cli_jsonl.c — `vantage import` and `vantage export`: entities as JSON
 * lines (json-c parses them), with named sub-levels resolved through the
 * daemon. A bad line stops the import with its line number; a batch the
 * daemon rejects is rejected whole.
 */
#include "cli.h"

#include <errno.h>
#include <json-c/json.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* ---- JSON lines ---------------------------------------------------------------- */

void cli_entity_json(FILE *f, const vp_entity *e, bool handle, const char *sublevel_name)
{
    char hd[32] = "", sub[600];
    if (handle) snprintf(hd, sizeof hd, "\"handle\": %u, ", e->handle);
    if (sublevel_name) snprintf(sub, sizeof sub, "\"%s\"", sublevel_name);
    else snprintf(sub, sizeof sub, "%u", e->sublevel);
    fprintf(f,
            "{\"id\": %llu, %s\"class\": %u, \"sphere\": [%.17g, %.17g, %.17g, %.17g], "
            "\"aabb\": [%.17g, %.17g, %.17g, %.17g, %.17g, %.17g], \"sublevel\": %s, \"dynamic\": %s}\n",
            (unsigned long long)e->id, hd, e->class_id, e->sphere[0], e->sphere[1], e->sphere[2], e->sphere[3],
            e->aabb[0], e->aabb[1], e->aabb[2], e->aabb[3], e->aabb[4], e->aabb[5], sub,
            (e->flags & VP_ENT_DYNAMIC) ? "true" : "false");
}

static bool json_num_array(json_object *a, double *out, size_t n)
{
    if (!a || !json_object_is_type(a, json_type_array) || json_object_array_length(a) != n) return false;
    for (size_t i = 0; i < n; i++) {
        json_object *x = json_object_array_get_idx(a, i);
        if (!x || !(json_object_is_type(x, json_type_double) || json_object_is_type(x, json_type_int)))
            return false;
        out[i] = json_object_get_double(x);
        if (!isfinite(out[i])) return false;
    }
    return true;
}

/* One line of an import file to a record; a message in err on failure. */
static bool entity_from_json(const char *line, vp_entity *e, char *sub, char *err, size_t errlen)
{
    memset(e, 0, sizeof *e);
    sub[0] = 0;
    json_tokener *tok = json_tokener_new();
    json_object *o = json_tokener_parse_ex(tok, line, (int)strlen(line));
    enum json_tokener_error je = json_tokener_get_error(tok);
    json_tokener_free(tok);
    if (!o || je != json_tokener_success) {
        snprintf(err, errlen, "not JSON: %s", json_tokener_error_desc(je));
        if (o) json_object_put(o);
        return false;
    }
    bool ok = false;
    json_object *v;
    if (!json_object_is_type(o, json_type_object)) {
        snprintf(err, errlen, "not a JSON object");
        goto out;
    }
    if (!json_object_object_get_ex(o, "id", &v) || !json_object_is_type(v, json_type_int)) {
        snprintf(err, errlen, "\"id\" must be an integer");
        goto out;
    }
    e->id = json_object_get_uint64(v);
    if (json_object_object_get_ex(o, "class", &v)) {
        int64_t cl = json_object_get_int64(v);
        if (!json_object_is_type(v, json_type_int) || cl < 0 || cl > 65535) {
            snprintf(err, errlen, "\"class\" must be 0..65535");
            goto out;
        }
        e->class_id = (uint16_t)cl;
    }
    if (json_object_object_get_ex(o, "sublevel", &v)) {
        if (json_object_is_type(v, json_type_string)) {
            const char *nm = json_object_get_string(v);
            size_t l = strlen(nm);
            bool clean = l >= 1 && l <= VP_MAX_NAME;
            for (size_t i = 0; clean && i < l; i++) clean = (unsigned char)nm[i] >= 32 && nm[i] != 127;
            if (!clean) {
                snprintf(err, errlen, "\"sublevel\" names are 1..255 bytes without control characters");
                goto out;
            }
            memcpy(sub, nm, l + 1); /* resolved to an id before sending */
        } else {
            int64_t sl = json_object_get_int64(v);
            if (!json_object_is_type(v, json_type_int) || sl < 0 || sl > 65535) {
                snprintf(err, errlen, "\"sublevel\" must be a name or 0..65535");
                goto out;
            }
            e->sublevel = (uint16_t)sl;
        }
    }
    if (json_object_object_get_ex(o, "dynamic", &v)) {
        if (!json_object_is_type(v, json_type_boolean)) {
            snprintf(err, errlen, "\"dynamic\" must be true or false");
            goto out;
        }
        if (json_object_get_boolean(v)) e->flags |= VP_ENT_DYNAMIC;
    }
    bool has_sphere = json_object_object_get_ex(o, "sphere", &v);
    if (has_sphere && !json_num_array(v, e->sphere, 4)) {
        snprintf(err, errlen, "\"sphere\" must be [x, y, z, r] of finite numbers");
        goto out;
    }
    bool has_aabb = json_object_object_get_ex(o, "aabb", &v);
    if (has_aabb && !json_num_array(v, e->aabb, 6)) {
        snprintf(err, errlen, "\"aabb\" must be [minx, miny, minz, maxx, maxy, maxz] of finite numbers");
        goto out;
    }
    if (!has_sphere && !has_aabb) {
        snprintf(err, errlen, "needs \"sphere\" or \"aabb\"");
        goto out;
    }
    ok = true;
out:
    json_object_put(o);
    return ok;
}

/* Names of sub-levels in a batch to their ids (defined on first use). */
static int resolve_sublevels(cli *k, vp_entity *batch, char (*subs)[VP_MAX_NAME + 1], uint32_t n)
{
    const char **names = malloc((size_t)n * sizeof *names);
    uint16_t *ids = malloc((size_t)n * sizeof *ids);
    uint32_t *which = malloc((size_t)n * sizeof *which);
    uint32_t nn = 0;
    int rc = 0;
    for (uint32_t i = 0; i < n; i++) {
        if (!subs[i][0]) continue;
        uint32_t j = 0;
        while (j < nn && strcmp(names[j], subs[i])) j++;
        if (j == nn) names[nn++] = subs[i];
        which[i] = j;
    }
    if (nn && (rc = vt_sublevel_ids(k->c, names, nn, ids))) rc = server_fail(k, "import", rc);
    for (uint32_t i = 0; !rc && i < n; i++)
        if (subs[i][0]) batch[i].sublevel = ids[which[i]];
    free(names);
    free(ids);
    free(which);
    return rc;
}

int cmd_import(cli *k, int argc, char **argv)
{
    if (argc != 2) return die_usage("import FILE.jsonl");
    FILE *f = strcmp(argv[1], "-") ? fopen(argv[1], "r") : stdin;
    if (!f) {
        fprintf(stderr, "%s: %s: %s\n", g_prog, argv[1], strerror(errno));
        return 2;
    }
    int rc = connect_cli(k, VP_ROLE_EDITOR);
    if (rc) {
        if (f != stdin) fclose(f);
        return rc;
    }
    uint32_t cap = vt_server(k->c)->max_batch;
    if (cap > 8192) cap = 8192;
    vp_entity *batch = malloc((size_t)cap * sizeof *batch);
    uint32_t *handles = malloc((size_t)cap * sizeof *handles);
    char (*subs)[VP_MAX_NAME + 1] = malloc((size_t)cap * sizeof *subs); /* sub-level name per record */
    char *line = NULL;
    size_t lcap = 0, lineno = 0, total = 0;
    uint32_t n = 0;
    size_t first_line = 1;
    double t0 = now_s();
    ssize_t len;
    while (rc == 0 && (len = getline(&line, &lcap, f)) >= 0) {
        lineno++;
        while (len > 0 && (line[len - 1] == '\n' || line[len - 1] == '\r')) line[--len] = 0;
        if (len == 0) continue;
        char err[160];
        if (!entity_from_json(line, &batch[n], subs[n], err, sizeof err)) {
            fprintf(stderr, "%s: %s:%zu: %s\n", g_prog, argv[1], lineno, err);
            rc = 2;
            break;
        }
        if (n == 0) first_line = lineno;
        if (++n == cap) {
            if ((rc = resolve_sublevels(k, batch, subs, n))) break;
            if ((rc = vt_add(k->c, batch, n, handles, NULL))) {
                fprintf(stderr, "%s: %s: the batch starting at line %zu was rejected whole\n", g_prog, argv[1],
                        first_line);
                rc = server_fail(k, "import", rc);
            }
            total += n;
            n = 0;
            if (isatty(2)) fprintf(stderr, "\rimported %zu entities", total);
        }
    }
    if (rc == 0 && n) rc = resolve_sublevels(k, batch, subs, n);
    if (rc == 0 && n) {
        if ((rc = vt_add(k->c, batch, n, handles, NULL))) {
            fprintf(stderr, "%s: %s: the batch starting at line %zu was rejected whole\n", g_prog, argv[1], first_line);
            rc = server_fail(k, "import", rc);
        }
        total += n;
    }
    if (rc == 0) {
        if (isatty(2)) fprintf(stderr, "\r");
        printf("imported %zu entities in %.2f s\n", total, now_s() - t0);
    }
    free(line);
    free(batch);
    free(handles);
    free(subs);
    if (f != stdin) fclose(f);
    return rc;
}

int cmd_export(cli *k, int argc, char **argv)
{
    if (argc != 2) return die_usage("export FILE.jsonl");
    int rc = connect_cli(k, VP_ROLE_VIEWER);
    if (rc) return rc;
    FILE *f = strcmp(argv[1], "-") ? fopen(argv[1], "w") : stdout;
    if (!f) {
        fprintf(stderr, "%s: %s: %s\n", g_prog, argv[1], strerror(errno));
        return 2;
    }
    /* sub-level ids that have names are written as their names */
    static char *names[65536];
    vp_name_list nl;
    if ((rc = vt_sublevel_list(k->c, &nl))) {
        if (f != stdout) fclose(f);
        return server_fail(k, "export", rc);
    }
    size_t pos = 0;
    vp_name nm;
    while (vp_name_next(&nl, &pos, &nm)) {
        char *q = malloc(6 * (size_t)nm.len + 1); /* JSON-escaped */
        if (q) cli_json_escape(q, (const char *)nm.name, nm.len);
        free(names[nm.id]);
        names[nm.id] = q;
    }
    uint64_t cursor = 0, epoch0 = 0;
    size_t total = 0;
    uint32_t page = vt_server(k->c)->max_batch < 4096 ? vt_server(k->c)->max_batch : 4096;
    do {
        vp_list_reply lr;
        if ((rc = vt_list(k->c, cursor, page, &lr))) {
            rc = server_fail(k, "export", rc);
            break;
        }
        if (total == 0) epoch0 = lr.epoch;
        else if (lr.epoch != epoch0) {
            fprintf(stderr, "%s: export: the scene changed during the export (epoch %llu -> %llu); retry\n",
                    g_prog, (unsigned long long)epoch0, (unsigned long long)lr.epoch);
            rc = 1;
            break;
        }
        for (uint32_t i = 0; i < lr.batch.count; i++) {
            vp_entity e;
            vp_entity_get(&lr.batch, i, &e);
            cli_entity_json(f, &e, false, names[e.sublevel]);
        }
        total += lr.batch.count;
        cursor = lr.next_cursor;
    } while (cursor);
    bool to_stdout = f == stdout;
    /* a full disk shows only at the flush: the export is not done unless
       every byte got out */
    if ((to_stdout ? fflush(f) : fclose(f)) != 0 || (to_stdout && ferror(f))) {
        fprintf(stderr, "%s: export: %s\n", g_prog, strerror(errno));
        if (!rc) rc = 1;
    }
    for (size_t i = 0; i < 65536; i++) {
        free(names[i]);
        names[i] = NULL;
    }
    if (!rc) fprintf(to_stdout ? stderr : stdout, "exported %zu entities at epoch %llu\n", total,
                     (unsigned long long)epoch0);
    return rc;
}

