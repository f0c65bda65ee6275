/*
 * cli_jsonl.c — `vantage import` and `vantage export`: entities as JSON
 * lines (jsonl.c parses and writes one, through json-c), with named
 * sub-levels resolved through the daemon. A bad line stops the import with
 * its line number; a batch the daemon rejects is rejected whole.
 */
#include "cli.h"
#include "jsonl.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <unistd.h>

/* FILE's extension is ext (any case) */
static bool has_ext(const char *file, const char *ext)
{
    const char *dot = strrchr(file, '.');
    return dot && !strcasecmp(dot + 1, ext);
}

/* ---- JSON lines ---------------------------------------------------------------- */

void cli_entity_json(FILE *f, const vp_entity *e, bool handle, const char *sublevel_name)
{
    char line[JSONL_LINE_MAX];
    int n = jsonl_entity_format(line, sizeof line, e, handle, sublevel_name);
    if (n < 0) return;
    if ((size_t)n < sizeof line) {
        fwrite(line, 1, (size_t)n, f);
        return;
    }
    char *big = malloc((size_t)n + 1); /* not for names the protocol allows */
    if (big && jsonl_entity_format(big, (size_t)n + 1, e, handle, sublevel_name) == n) fwrite(big, 1, (size_t)n, f);
    free(big);
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
    if (nn && (rc = vtc_sublevel_ids(k->c, names, nn, ids))) rc = server_fail(k, "import", rc);
    for (uint32_t i = 0; !rc && i < n; i++)
        if (subs[i][0]) batch[i].sublevel = ids[which[i]];
    free(names);
    free(ids);
    free(which);
    return rc;
}

int cmd_import(cli *k, int argc, char **argv)
{
    if (argc != 2) return die_usage("import FILE.jsonl | FILE.gltf|glb|obj");
    if (has_ext(argv[1], "gltf") || has_ext(argv[1], "glb") || has_ext(argv[1], "obj")) {
        /* a level: loaded as the sub-level named after the file (cli_sublevel.c) */
        char name[VP_MAX_NAME + 1];
        const char *base = strrchr(argv[1], '/') ? strrchr(argv[1], '/') + 1 : argv[1];
        snprintf(name, sizeof name, "%.*s", (int)(strrchr(base, '.') - base), base);
        char *sub[] = {"sublevel", "load", name[0] ? name : "level", argv[1]};
        return cmd_sublevel(k, 4, sub);
    }
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
    uint32_t cap = vtc_server(k->c)->max_batch;
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
        if (!jsonl_entity_parse(line, (size_t)len, &batch[n], subs[n], err, sizeof err)) {
            fprintf(stderr, "%s: %s:%zu: %s\n", g_prog, argv[1], lineno, err);
            rc = 2;
            break;
        }
        if (n == 0) first_line = lineno;
        if (++n == cap) {
            if ((rc = resolve_sublevels(k, batch, subs, n))) break;
            if ((rc = vtc_add(k->c, batch, n, handles, NULL))) {
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
        if ((rc = vtc_add(k->c, batch, n, handles, NULL))) {
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
    if (argc != 2) return die_usage("export FILE.jsonl | FILE.glb");
    if (has_ext(argv[1], "glb")) return cmd_export_glb(k, argv[1]); /* cli_export.c */
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
    if ((rc = vtc_sublevel_list(k->c, &nl))) {
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
    uint32_t page = vtc_server(k->c)->max_batch < 4096 ? vtc_server(k->c)->max_batch : 4096;
    do {
        vp_list_reply lr;
        if ((rc = vtc_list(k->c, cursor, page, &lr))) {
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

