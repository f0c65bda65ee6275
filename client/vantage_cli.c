/*
 * vantage_cli.c — the `vantage` command line tool, in the manner of
 * redis-cli: connection flags, then a command.
 *
 *   vantage [-h HOST] [-p PORT] [-s SOCKET] [--token T] COMMAND [ARGS]
 *
 * Exit status: 0 ok, 1 the server refused (its message on stderr), 2 bad
 * usage, 3 cannot connect or the connection failed.
 */
#include "vantage.h"

#include <errno.h>
#include <getopt.h>
#include <json-c/json.h>
#include <math.h>
#include <poll.h>
#include <pthread.h>
#include <signal.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

typedef struct cli {
    vt_connect_opts co;
    vt_client *c;
} cli;

static const char *g_prog = "vantage";

static void usage(FILE *f)
{
    fprintf(f,
            "usage: vantage [-h HOST] [-p PORT] [-s SOCKET] [--token T] [--timeout MS] COMMAND [ARGS]\n"
            "\n"
            "commands:\n"
            "  ping [-c N]                      round trip to the daemon (N times, prints latency)\n"
            "  stats [--json]                   scene and server counters\n"
            "  add ID X,Y,Z R [--class N] [--sublevel N] [--dynamic] [--aabb X0,Y0,Z0,X1,Y1,Z1]\n"
            "  move ID X,Y,Z [--radius R]       move an entity (its AABB moves with it)\n"
            "  remove ID [ID...]                remove entities\n"
            "  get ID [ID...]                   print entities as JSON lines\n"
            "  import FILE.jsonl                add entities, one JSON object per line\n"
            "  export FILE.jsonl                write every entity, same format (- = stdout)\n"
            "  query --eye X,Y,Z --at X,Y,Z [--up X,Y,Z] [--fov DEG | --ortho W,H] [--near N]\n"
            "        [--far F] [--size WxH] [--min-area PX] [--exact-area] [--no-occlusion] [--json]\n"
            "  watch [--count N]                print scene-changed events as they happen\n"
            "  bench [--test query|edit|ping] [--clients N] [--threads T] [--requests N] [--pipeline P]\n"
            "        [--views K] [--batch B] [--count-only] [--json]   load test: rate and latency percentiles\n"
            "\n"
            "connection: -h HOST (127.0.0.1), -p PORT (%d), -s SOCKET (Unix socket instead of TCP)\n"
            "JSON lines: {\"id\": 64-bit id, \"class\": n, \"sphere\": [x,y,z,r],\n"
            "             \"aabb\": [minx,miny,minz,maxx,maxy,maxz], \"sublevel\": n, \"dynamic\": false}\n"
            "COMMAND --help prints that command's usage.\n",
            VT_DEFAULT_PORT);
}

static int die_usage(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
static int die_usage(const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    fprintf(stderr, "%s: ", g_prog);
    vfprintf(stderr, fmt, ap);
    va_end(ap);
    fprintf(stderr, " (vantage --help)\n");
    return 2;
}

static int server_fail(cli *k, const char *what, int rc)
{
    const vt_error *e = vt_last_error(k->c);
    if (rc == VT_ERR_IO) {
        fprintf(stderr, "%s: %s: %s\n", g_prog, what, e->msg);
        return 3;
    }
    if (e->index != UINT32_MAX)
        fprintf(stderr, "%s: %s: error %d (%s), record %u: %s\n", g_prog, what, rc, vp_strerror(rc), e->index,
                e->msg);
    else
        fprintf(stderr, "%s: %s: error %d (%s): %s\n", g_prog, what, rc, vp_strerror(rc), e->msg);
    return 1;
}

static int connect_cli(cli *k, int role)
{
    char err[256];
    k->co.role = role;
    k->co.name = "vantage-cli";
    if (vt_connect(&k->co, &k->c, err, sizeof err)) {
        fprintf(stderr, "%s: cannot connect: %s\n", g_prog, err);
        return 3;
    }
    return 0;
}

static bool parse_vec(const char *s, double *v, int n)
{
    char *end;
    for (int i = 0; i < n; i++) {
        errno = 0;
        v[i] = strtod(s, &end);
        if (end == s || errno || !isfinite(v[i])) return false;
        s = end;
        if (i + 1 < n) {
            if (*s != ',') return false;
            s++;
        }
    }
    return *s == 0;
}

static bool parse_u64(const char *s, uint64_t *v)
{
    char *end;
    errno = 0;
    unsigned long long x = strtoull(s, &end, 0);
    if (!*s || *end || errno || *s == '-') return false;
    *v = x;
    return true;
}

/* ---- JSON lines ---------------------------------------------------------------- */

static void print_entity_json(FILE *f, const vp_entity *e)
{
    fprintf(f,
            "{\"id\": %llu, \"handle\": %u, \"class\": %u, \"sphere\": [%.17g, %.17g, %.17g, %.17g], "
            "\"aabb\": [%.17g, %.17g, %.17g, %.17g, %.17g, %.17g], \"sublevel\": %u, \"dynamic\": %s}\n",
            (unsigned long long)e->id, e->handle, e->class_id, e->sphere[0], e->sphere[1], e->sphere[2], e->sphere[3],
            e->aabb[0], e->aabb[1], e->aabb[2], e->aabb[3], e->aabb[4], e->aabb[5], e->sublevel,
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

/* ---- commands ---------------------------------------------------------------- */

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + ts.tv_nsec * 1e-9;
}

static int cmd_ping(cli *k, int argc, char **argv)
{
    long n = 1;
    if (argc >= 3 && !strcmp(argv[1], "-c")) n = strtol(argv[2], NULL, 10);
    else if (argc > 1) return die_usage("ping [-c N]");
    if (n < 1) return die_usage("ping: -c needs a positive count");
    int rc = connect_cli(k, VP_ROLE_VIEWER);
    if (rc) return rc;
    for (long i = 0; i < n; i++) {
        double t0 = now_s();
        if ((rc = vt_ping(k->c))) return server_fail(k, "ping", rc);
        if (n == 1) printf("PONG\n");
        else printf("PONG %.1f us\n", (now_s() - t0) * 1e6);
    }
    return 0;
}

static int cmd_stats(cli *k, int argc, char **argv)
{
    bool json = argc == 2 && !strcmp(argv[1], "--json");
    if (argc > 1 && !json) return die_usage("stats [--json]");
    int rc = connect_cli(k, VP_ROLE_VIEWER);
    if (rc) return rc;
    vp_stats_reply s;
    if ((rc = vt_stats(k->c, &s))) return server_fail(k, "stats", rc);
    if (json) {
        printf("{\"epoch\": %llu, \"uptime_ms\": %llu, \"entities\": %u, \"static_entities\": %u, "
               "\"dynamic_entities\": %u, \"regions\": %u, \"cells\": %u, \"connections\": %u, \"meshes\": %u, "
               "\"occluders\": %u, \"lights\": %u, \"queries\": %llu, \"edits\": %llu, \"bytes_in\": %llu, "
               "\"bytes_out\": %llu, \"errors\": %llu}\n",
               (unsigned long long)s.epoch, (unsigned long long)s.uptime_ms, s.entities, s.static_entities,
               s.dynamic_entities, s.regions, s.cells, s.connections, s.meshes, s.occluders, s.lights,
               (unsigned long long)s.queries, (unsigned long long)s.edits, (unsigned long long)s.bytes_in,
               (unsigned long long)s.bytes_out, (unsigned long long)s.errors);
    } else {
        printf("epoch        %llu\nuptime       %.1f s\nentities     %u (%u static, %u dynamic)\n"
               "cells        %u in %u regions\nconnections  %u\nmeshes       %u\noccluders    %u\nlights       %u\n"
               "queries      %llu\nedits        %llu\nbytes in     %llu\nbytes out    %llu\nerrors       %llu\n",
               (unsigned long long)s.epoch, s.uptime_ms / 1000.0, s.entities, s.static_entities, s.dynamic_entities,
               s.cells, s.regions, s.connections, s.meshes, s.occluders, s.lights, (unsigned long long)s.queries,
               (unsigned long long)s.edits, (unsigned long long)s.bytes_in, (unsigned long long)s.bytes_out,
               (unsigned long long)s.errors);
    }
    return 0;
}

static int cmd_add(cli *k, int argc, char **argv)
{
    const char *use = "add ID X,Y,Z R [--class N] [--sublevel N] [--dynamic] [--aabb X0,Y0,Z0,X1,Y1,Z1]";
    if (argc < 4) return die_usage("%s", use);
    vp_entity e = {0};
    if (!parse_u64(argv[1], &e.id)) return die_usage("add: bad id %s", argv[1]);
    if (!parse_vec(argv[2], e.sphere, 3) || !parse_vec(argv[3], &e.sphere[3], 1))
        return die_usage("add: bad position or radius");
    for (int i = 4; i < argc; i++) {
        uint64_t v;
        if (!strcmp(argv[i], "--dynamic")) e.flags |= VP_ENT_DYNAMIC;
        else if (!strcmp(argv[i], "--class") && i + 1 < argc && parse_u64(argv[++i], &v) && v <= 65535)
            e.class_id = (uint16_t)v;
        else if (!strcmp(argv[i], "--sublevel") && i + 1 < argc && parse_u64(argv[++i], &v) && v <= 65535)
            e.sublevel = (uint16_t)v;
        else if (!strcmp(argv[i], "--aabb") && i + 1 < argc && parse_vec(argv[++i], e.aabb, 6))
            ;
        else
            return die_usage("%s", use);
    }
    int rc = connect_cli(k, VP_ROLE_EDITOR);
    if (rc) return rc;
    uint32_t h;
    uint64_t epoch;
    if ((rc = vt_add(k->c, &e, 1, &h, &epoch))) return server_fail(k, "add", rc);
    printf("added id %llu handle %u at epoch %llu\n", (unsigned long long)e.id, h, (unsigned long long)epoch);
    return 0;
}

static int cmd_move(cli *k, int argc, char **argv)
{
    const char *use = "move ID X,Y,Z [--radius R]";
    uint64_t id;
    double pos[3], r = -1;
    if (argc < 3 || !parse_u64(argv[1], &id) || !parse_vec(argv[2], pos, 3)) return die_usage("%s", use);
    if (argc == 5 && !strcmp(argv[3], "--radius")) {
        if (!parse_vec(argv[4], &r, 1) || r < 0) return die_usage("%s", use);
    } else if (argc != 3) {
        return die_usage("%s", use);
    }
    int rc = connect_cli(k, VP_ROLE_EDITOR);
    if (rc) return rc;
    vp_list_reply lr;
    if ((rc = vt_get(k->c, &id, 1, &lr))) return server_fail(k, "move", rc);
    vp_entity e;
    vp_entity_get(&lr.batch, 0, &e);
    double d[3] = {pos[0] - e.sphere[0], pos[1] - e.sphere[1], pos[2] - e.sphere[2]};
    for (int a = 0; a < 3; a++) {
        e.sphere[a] = pos[a];
        e.aabb[a] += d[a];
        e.aabb[3 + a] += d[a];
    }
    if (r >= 0) { /* a new radius: the AABB follows the sphere */
        e.sphere[3] = r;
        for (int a = 0; a < 6; a++) e.aabb[a] = 0;
    }
    uint64_t epoch;
    if ((rc = vt_update(k->c, &e, 1, &epoch))) return server_fail(k, "move", rc);
    printf("moved id %llu at epoch %llu\n", (unsigned long long)id, (unsigned long long)epoch);
    return 0;
}

static int cmd_remove(cli *k, int argc, char **argv)
{
    if (argc < 2) return die_usage("remove ID [ID...]");
    uint64_t *ids = calloc((size_t)argc, sizeof *ids);
    for (int i = 1; i < argc; i++)
        if (!parse_u64(argv[i], &ids[i - 1])) {
            free(ids);
            return die_usage("remove: bad id %s", argv[i]);
        }
    int rc = connect_cli(k, VP_ROLE_EDITOR);
    uint64_t epoch;
    if (!rc && (rc = vt_remove(k->c, ids, (uint32_t)(argc - 1), &epoch))) rc = server_fail(k, "remove", rc);
    else if (!rc) printf("removed %d at epoch %llu\n", argc - 1, (unsigned long long)epoch);
    free(ids);
    return rc;
}

static int cmd_get(cli *k, int argc, char **argv)
{
    if (argc < 2) return die_usage("get ID [ID...]");
    uint64_t *ids = calloc((size_t)argc, sizeof *ids);
    for (int i = 1; i < argc; i++)
        if (!parse_u64(argv[i], &ids[i - 1])) {
            free(ids);
            return die_usage("get: bad id %s", argv[i]);
        }
    int rc = connect_cli(k, VP_ROLE_VIEWER);
    vp_list_reply lr;
    if (!rc && (rc = vt_get(k->c, ids, (uint32_t)(argc - 1), &lr))) rc = server_fail(k, "get", rc);
    for (uint32_t i = 0; !rc && i < lr.batch.count; i++) {
        vp_entity e;
        vp_entity_get(&lr.batch, i, &e);
        print_entity_json(stdout, &e);
    }
    free(ids);
    return rc;
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

static int cmd_import(cli *k, int argc, char **argv)
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

static int cmd_export(cli *k, int argc, char **argv)
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
        char *q = malloc(2 * (size_t)nm.len + 1), *o = q; /* JSON-escaped */
        for (uint8_t i = 0; i < nm.len; i++) {
            if (nm.name[i] == '"' || nm.name[i] == '\\') *o++ = '\\';
            *o++ = (char)nm.name[i];
        }
        *o = 0;
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
            char sub[600];
            if (names[e.sublevel]) snprintf(sub, sizeof sub, "\"%s\"", names[e.sublevel]);
            else snprintf(sub, sizeof sub, "%u", e.sublevel);
            fprintf(f, "{\"id\": %llu, \"class\": %u, \"sphere\": [%.17g, %.17g, %.17g, %.17g], "
                       "\"aabb\": [%.17g, %.17g, %.17g, %.17g, %.17g, %.17g], \"sublevel\": %s, \"dynamic\": %s}\n",
                    (unsigned long long)e.id, e.class_id, e.sphere[0], e.sphere[1], e.sphere[2], e.sphere[3],
                    e.aabb[0], e.aabb[1], e.aabb[2], e.aabb[3], e.aabb[4], e.aabb[5], sub,
                    (e.flags & VP_ENT_DYNAMIC) ? "true" : "false");
        }
        total += lr.batch.count;
        cursor = lr.next_cursor;
    } while (cursor);
    bool to_stdout = f == stdout;
    if (!to_stdout) fclose(f);
    for (size_t i = 0; i < 65536; i++) {
        free(names[i]);
        names[i] = NULL;
    }
    if (!rc) fprintf(to_stdout ? stderr : stdout, "exported %zu entities at epoch %llu\n", total,
                     (unsigned long long)epoch0);
    return rc;
}

static int cmd_query(cli *k, int argc, char **argv)
{
    double eye[3], at[3], up[3] = {0, 1, 0}, fov = 60, ortho[2] = {0, 0}, znear = 0.1, zfar = 10000;
    bool have_eye = false, have_at = false, json = false;
    unsigned w = 1920, h = 1080;
    float min_area = 0;
    uint8_t flags = 0;
    static const struct option opts[] = {
        {"eye", 1, 0, 'e'}, {"at", 1, 0, 'a'}, {"up", 1, 0, 'u'}, {"fov", 1, 0, 'f'}, {"ortho", 1, 0, 'o'},
        {"near", 1, 0, 'n'}, {"far", 1, 0, 'F'}, {"size", 1, 0, 's'}, {"min-area", 1, 0, 'm'},
        {"exact-area", 0, 0, 'x'}, {"no-occlusion", 0, 0, 'N'}, {"json", 0, 0, 'j'}, {"help", 0, 0, 'h'},
        {0, 0, 0, 0}};
    const char *use = "query --eye X,Y,Z --at X,Y,Z [--up X,Y,Z] [--fov DEG | --ortho W,H] [--near N] [--far F] "
                      "[--size WxH] [--min-area PX] [--exact-area] [--no-occlusion] [--json]";
    optind = 1;
    int o;
    while ((o = getopt_long(argc, argv, "", opts, NULL)) != -1) {
        bool ok = true;
        switch (o) {
        case 'e': ok = have_eye = parse_vec(optarg, eye, 3); break;
        case 'a': ok = have_at = parse_vec(optarg, at, 3); break;
        case 'u': ok = parse_vec(optarg, up, 3); break;
        case 'f': ok = parse_vec(optarg, &fov, 1) && fov > 0 && fov < 180; break;
        case 'o': ok = parse_vec(optarg, ortho, 2) && ortho[0] > 0 && ortho[1] > 0; break;
        case 'n': ok = parse_vec(optarg, &znear, 1); break;
        case 'F': ok = parse_vec(optarg, &zfar, 1); break;
        case 's': ok = sscanf(optarg, "%ux%u", &w, &h) == 2 && w && h && w <= 65535 && h <= 65535; break;
        case 'm': {
            double m;
            ok = parse_vec(optarg, &m, 1) && m >= 0;
            min_area = (float)m;
            break;
        }
        case 'x': flags |= VP_Q_WANT_AREA; break;
        case 'N': flags |= VP_Q_NO_OCCLUSION; break;
        case 'j': json = true; break;
        case 'h': printf("usage: vantage %s\n", use); return 0;
        default: return die_usage("%s", use);
        }
        if (!ok) return die_usage("query: bad value %s", optarg);
    }
    if (!have_eye || !have_at || optind != argc) return die_usage("%s", use);
    vp_view v;
    bool ok = ortho[0] > 0 ? vt_view_ortho(&v, eye, at, up, ortho[0], ortho[1], (uint16_t)w, (uint16_t)h, znear, zfar)
                           : vt_view_perspective(&v, eye, at, up, fov, (uint16_t)w, (uint16_t)h, znear, zfar);
    if (!ok) return die_usage("query: degenerate camera (eye == at, up parallel to the view, or near/far)");
    int rc = connect_cli(k, VP_ROLE_VIEWER);
    if (rc) return rc;
    double t0 = now_s();
    vp_vis_result r;
    if ((rc = vt_query(k->c, &v, 1, flags, min_area, &r))) return server_fail(k, "query", rc);
    double rtt = now_s() - t0;
    if (json) {
        for (uint32_t i = 0; i < r.count; i++) {
            vp_vis_rec x;
            vp_vis_rec_get(&r, i, &x);
            printf("{\"id\": %llu, \"handle\": %u, \"views\": %u, \"class\": %u, \"area\": %.6g}\n",
                   (unsigned long long)x.id, x.handle, x.view_mask, x.class_id, x.area);
        }
        printf("{\"epoch\": %llu, \"tested\": %u, \"visible\": %u, \"stage_ns\": {\"cull\": %u, \"write\": %u, "
               "\"total\": %u, \"setup\": %u}, \"round_trip_us\": %.1f}\n",
               (unsigned long long)r.epoch, r.tested, r.visible, r.stage_ns[1], r.stage_ns[2], r.stage_ns[3],
               r.stage_ns[4], rtt * 1e6);
    } else {
        printf("%u visible of %u tested at epoch %llu; cull %.1f us, server total %.1f us, round trip %.1f us\n",
               r.visible, r.tested, (unsigned long long)r.epoch, r.stage_ns[1] / 1e3, r.stage_ns[3] / 1e3, rtt * 1e6);
        uint32_t show = r.count < 20 ? r.count : 20;
        for (uint32_t i = 0; i < show; i++) {
            vp_vis_rec x;
            vp_vis_rec_get(&r, i, &x);
            printf("  id %-10llu handle %-8u class %-5u area %.1f\n", (unsigned long long)x.id, x.handle, x.class_id,
                   x.area);
        }
        if (r.count > show) printf("  ... %u more (--json for all)\n", r.count - show);
    }
    return 0;
}

static volatile sig_atomic_t g_stop;
static void on_sigint(int sig)
{
    (void)sig;
    g_stop = 1;
}

static int cmd_watch(cli *k, int argc, char **argv)
{
    long count = -1;
    if (argc == 3 && !strcmp(argv[1], "--count")) count = strtol(argv[2], NULL, 10);
    else if (argc != 1) return die_usage("watch [--count N]");
    int rc = connect_cli(k, VP_ROLE_VIEWER);
    if (rc) return rc;
    if ((rc = vt_subscribe(k->c, VP_EVENT_SCENE))) return server_fail(k, "watch", rc);
    signal(SIGINT, on_sigint);
    fprintf(stderr, "watching scene changes (Ctrl-C to stop)\n");
    for (long n = 0; !g_stop && (count < 0 || n < count);) {
        vp_event ev;
        rc = vt_wait_event(k->c, &ev, 500);
        if (rc == VT_ERR_IO && strstr(vt_last_error(k->c)->msg, "timed out")) continue;
        if (rc) return server_fail(k, "watch", rc);
        printf("{\"epoch\": %llu, \"added\": %u, \"updated\": %u, \"removed\": %u}\n", (unsigned long long)ev.epoch,
               ev.added, ev.updated, ev.removed);
        fflush(stdout);
        n++;
    }
    return 0;
}


/* ---- bench ------------------------------------------------------------------------ */

typedef struct bench_conn {
    vt_client *c;
    int idx;            /* client number: ids and camera vary with it */
    long sent, recvd, quota;
    double *sent_at;    /* ring of pipeline send times */
    vp_entity *ents;    /* edit test: the entities this client moves */
} bench_conn;

/* One load-generator thread: several connections driven from one poll()
 * loop, like redis-benchmark, so 64 connections do not need 64 threads
 * competing with the daemon for the cores. */
typedef struct bench_arg {
    cli *k;
    const char *test;
    int first, nconn;
    long per_conn;
    int pipeline, views, batch;
    uint8_t qflags;
    double *lat;        /* seconds per request */
    long done;
    int failed;
    uint64_t records;
} bench_arg;

static int cmp_dbl(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

static void bench_views(vp_view *v, int n, int idx, long i)
{
    for (int k = 0; k < n; k++) {
        double a = 0.01 * (double)i + k * 0.7 + idx;
        double eye[3] = {cos(a) * 200, 2, sin(a) * 200}, at[3] = {0, 2, 0};
        vt_view_perspective(&v[k], eye, at, NULL, 60, 1280, 720, 0.1, 2000);
    }
}

/* Encodes and sends request number bc->sent of this connection. */
static int bench_send(bench_arg *a, bench_conn *bc, uint8_t *buf, size_t cap)
{
    vp_writer w;
    vp_writer_init(&w, buf, cap);
    uint32_t req = vt_next_req(bc->c);
    if (!strcmp(a->test, "edit")) {
        for (int e = 0; e < a->batch; e++) bc->ents[e].sphere[1] = (double)(bc->sent % 100) * 0.1;
        vp_enc_entities(&w, VP_ENTITY_UPDATE, req, bc->ents, (uint32_t)a->batch);
    } else if (!strcmp(a->test, "ping")) {
        vp_enc_ping(&w, VP_PING, req, (const uint8_t *)"b", 1);
    } else {
        vp_view views[VP_MAX_VIEWS];
        bench_views(views, a->views, bc->idx, bc->sent);
        vp_enc_vis_query(&w, req, a->qflags, 0, views, (uint32_t)a->views);
    }
    bc->sent_at[bc->sent % a->pipeline] = now_s();
    bc->sent++;
    return vt_send(bc->c, buf, w.len);
}

static void *bench_worker(void *p)
{
    bench_arg *a = p;
    bench_conn *cs = calloc((size_t)a->nconn, sizeof *cs);
    struct pollfd *pf = calloc((size_t)a->nconn, sizeof *pf);
    size_t cap = vp_size_entities((uint32_t)a->batch) + VP_HEADER_SIZE + 8 + (size_t)a->views * VP_VIEW_SIZE;
    uint8_t *buf = malloc(cap);
    bool edit = !strcmp(a->test, "edit");
    for (int i = 0; i < a->nconn && !a->failed; i++) {
        bench_conn *bc = &cs[i];
        vt_connect_opts o = a->k->co;
        o.role = VP_ROLE_EDITOR;
        o.name = "vantage-bench";
        bc->idx = a->first + i;
        bc->quota = a->per_conn;
        bc->sent_at = calloc((size_t)a->pipeline, sizeof *bc->sent_at);
        if (vt_connect(&o, &bc->c, NULL, 0)) {
            a->failed = 1;
            break;
        }
        if (edit) {
            uint64_t base = 0x7B000000000ull + (uint64_t)bc->idx * 100000000ull;
            bc->ents = calloc((size_t)a->batch, sizeof *bc->ents);
            for (int e = 0; e < a->batch; e++)
                bc->ents[e] = (vp_entity){.id = base + (uint64_t)e, .sphere = {bc->idx * 10.0, 0, e * 0.5, 0.25},
                                          .flags = VP_ENT_DYNAMIC};
            if (vt_add(bc->c, bc->ents, (uint32_t)a->batch, NULL, NULL)) a->failed = 1;
        }
        pf[i] = (struct pollfd){.fd = vt_fd(bc->c), .events = POLLIN};
    }
    /* fill every connection's pipeline, then one new request per reply */
    for (int i = 0; i < a->nconn && !a->failed; i++)
        while (cs[i].sent < cs[i].quota && cs[i].sent < a->pipeline)
            if (bench_send(a, &cs[i], buf, cap)) a->failed = 1;
    long open = a->failed ? 0 : a->nconn;
    while (open > 0 && !a->failed) {
        int r = poll(pf, (nfds_t)a->nconn, 30000);
        if (r <= 0) {
            a->failed = 1;
            break;
        }
        for (int i = 0; i < a->nconn && !a->failed; i++) {
            if (!pf[i].revents) continue;
            bench_conn *bc = &cs[i];
            for (;;) {
                vp_header h;
                const uint8_t *pl;
                int rc = vt_recv(bc->c, &h, &pl, 0);
                if (rc == VP_NEED_MORE) break;
                if (rc || h.type == VP_ERROR) {
                    a->failed = 1;
                    break;
                }
                if (h.type == VP_EVENT) continue;
                if (h.type == VP_VIS_RESULT) {
                    vp_vis_result res;
                    if (!vp_dec_vis_result(pl, h.len, &res)) a->records += res.visible;
                }
                a->lat[a->done++] = now_s() - bc->sent_at[bc->recvd % a->pipeline];
                bc->recvd++;
                if (bc->sent < bc->quota && bench_send(a, bc, buf, cap)) a->failed = 1;
                if (bc->recvd == bc->quota) {
                    pf[i].fd = -1; /* done: poll ignores it */
                    open--;
                    break;
                }
            }
        }
    }
    for (int i = 0; i < a->nconn; i++) {
        vt_close(cs[i].c);
        free(cs[i].sent_at);
        free(cs[i].ents);
    }
    free(cs);
    free(pf);
    free(buf);
    return NULL;
}

static int cmd_bench(cli *k, int argc, char **argv)
{
    const char *use = "bench [--test query|edit|ping] [--clients N] [--threads T] [--requests N] [--pipeline P] "
                      "[--views K] [--batch B] [--count-only] [--json]";
    const char *test = "query";
    long clients = 64, requests = 100000, pipeline = 1, views = 1, batch = 1000, threads = 2;
    bool json = false;
    uint8_t qflags = 0;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--test") && i + 1 < argc) test = argv[++i];
        else if (!strcmp(argv[i], "--clients") && i + 1 < argc) clients = strtol(argv[++i], NULL, 10);
        else if (!strcmp(argv[i], "--requests") && i + 1 < argc) requests = strtol(argv[++i], NULL, 10);
        else if (!strcmp(argv[i], "--threads") && i + 1 < argc) threads = strtol(argv[++i], NULL, 10);
        else if (!strcmp(argv[i], "--pipeline") && i + 1 < argc) pipeline = strtol(argv[++i], NULL, 10);
        else if (!strcmp(argv[i], "--views") && i + 1 < argc) views = strtol(argv[++i], NULL, 10);
        else if (!strcmp(argv[i], "--batch") && i + 1 < argc) batch = strtol(argv[++i], NULL, 10);
        else if (!strcmp(argv[i], "--count-only")) qflags |= VP_Q_COUNT_ONLY;
        else if (!strcmp(argv[i], "--json")) json = true;
        else return die_usage("%s", use);
    }
    if (strcmp(test, "query") && strcmp(test, "edit") && strcmp(test, "ping")) return die_usage("%s", use);
    if (clients < 1 || clients > 1000 || requests < clients || pipeline < 1 || pipeline > 1000 || views < 1 ||
        views > 32 || batch < 1 || batch > 65536 || threads < 1 || threads > 64)
        return die_usage("bench: a value out of range");
    if (threads > clients) threads = clients;
    pthread_t *th = calloc((size_t)threads, sizeof *th);
    bench_arg *args = calloc((size_t)threads, sizeof *args);
    long per = requests / clients;
    double t0 = now_s();
    for (long i = 0, first = 0; i < threads; i++) {
        int nconn = (int)(clients / threads + (i < clients % threads));
        args[i] = (bench_arg){.k = k, .first = (int)first, .nconn = nconn, .test = test, .per_conn = per,
                              .pipeline = (int)pipeline, .views = (int)views, .batch = (int)batch,
                              .qflags = qflags};
        args[i].lat = malloc(sizeof(double) * (size_t)per * (size_t)nconn);
        first += nconn;
        pthread_create(&th[i], NULL, bench_worker, &args[i]);
    }
    long done = 0, failed = 0;
    uint64_t records = 0;
    for (long i = 0; i < threads; i++) {
        pthread_join(th[i], NULL);
        done += args[i].done;
        failed += args[i].failed;
        records += args[i].records;
    }
    double secs = now_s() - t0;
    double *all = malloc(sizeof(double) * (size_t)(done ? done : 1));
    long n = 0;
    for (long i = 0; i < threads; i++) {
        memcpy(all + n, args[i].lat, sizeof(double) * (size_t)args[i].done);
        n += args[i].done;
        free(args[i].lat);
    }
    qsort(all, (size_t)n, sizeof *all, cmp_dbl);
#define PCT(q) (n ? all[(size_t)((double)(n - 1) * (q))] * 1e3 : 0.0)
    double rate = done / secs;
    if (json) {
        printf("{\"test\": \"%s\", \"clients\": %ld, \"pipeline\": %ld, \"views\": %ld, \"batch\": %ld, "
               "\"requests\": %ld, \"failed_threads\": %ld, \"seconds\": %.3f, \"per_second\": %.0f, "
               "\"records_per_second\": %.0f, \"p50_ms\": %.4f, \"p90_ms\": %.4f, \"p99_ms\": %.4f, "
               "\"p999_ms\": %.4f, \"max_ms\": %.4f}\n",
               test, clients, pipeline, views, batch, done, failed, secs, rate,
               !strcmp(test, "edit") ? rate * batch : records / secs, PCT(0.5), PCT(0.9), PCT(0.99), PCT(0.999),
               PCT(1.0));
    } else {
        printf("%s: %ld requests, %ld clients, pipeline %ld: %.2f s, %.0f requests/s", test, done, clients,
               pipeline, secs, rate);
        if (!strcmp(test, "edit")) printf(", %.0f entity updates/s", rate * batch);
        if (!strcmp(test, "query")) printf(", %.0f visible records/s", records / secs);
        printf("\nlatency ms: p50 %.3f  p90 %.3f  p99 %.3f  p99.9 %.3f  max %.3f\n", PCT(0.5), PCT(0.9), PCT(0.99),
               PCT(0.999), PCT(1.0));
        if (failed) printf("%ld load threads failed\n", failed);
    }
#undef PCT
    free(all);
    free(th);
    free(args);
    return failed ? 1 : 0;
}

int main(int argc, char **argv)
{
    cli k = {0};
    static const struct option opts[] = {{"token", 1, 0, 't'}, {"timeout", 1, 0, 'T'}, {"help", 0, 0, 'H'},
                                         {0, 0, 0, 0}};
    int o;
    uint64_t port = VT_DEFAULT_PORT, to;
    while ((o = getopt_long(argc, argv, "+h:p:s:", opts, NULL)) != -1) {
        switch (o) {
        case 'h': k.co.host = optarg; break;
        case 'p':
            if (!parse_u64(optarg, &port) || !port || port > 65535) return die_usage("bad port %s", optarg);
            break;
        case 's': k.co.unix_path = optarg; break;
        case 't': k.co.token = optarg; break;
        case 'T':
            if (!parse_u64(optarg, &to) || to > 3600000) return die_usage("bad timeout %s", optarg);
            k.co.timeout_ms = (int)to;
            break;
        case 'H': usage(stdout); return 0;
        default: usage(stderr); return 2;
        }
    }
    k.co.port = (int)port;
    if (optind >= argc) {
        usage(stderr);
        return 2;
    }
    char **av = argv + optind;
    int ac = argc - optind;
    if (ac == 2 && !strcmp(av[1], "--help") && strcmp(av[0], "query")) {
        usage(stdout);
        return 0;
    }
    static const struct { const char *name; int (*fn)(cli *, int, char **); } cmds[] = {
        {"ping", cmd_ping}, {"stats", cmd_stats}, {"add", cmd_add}, {"move", cmd_move}, {"remove", cmd_remove},
        {"get", cmd_get}, {"import", cmd_import}, {"export", cmd_export}, {"query", cmd_query}, {"watch", cmd_watch},
        {"bench", cmd_bench},
    };
    int rc = -1;
    for (size_t i = 0; i < sizeof cmds / sizeof cmds[0]; i++)
        if (!strcmp(av[0], cmds[i].name)) rc = cmds[i].fn(&k, ac, av);
    if (rc < 0) rc = die_usage("unknown command %s", av[0]);
    vt_close(k.c);
    return rc;
}
