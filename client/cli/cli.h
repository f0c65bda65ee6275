/*
 * cli.h — what the `vantage` command line tool's files share: the
 * connection, error reporting, argument parsing, and the commands that live
 * in their own files (JSON lines import/export, the load generator).
 */
#ifndef VANTAGE_CLI_H
#define VANTAGE_CLI_H

#include "jsonl.h" /* cli_json_escape, the JSON line of an entity */
#include "vantage.h"

#include <stdbool.h>
#include <stdint.h>
#include <signal.h>
#include <stdio.h>

typedef struct cli {
    vtc_connect_opts co;
    vtc_client *c;
} cli;

extern const char *g_prog;

/* Prints "vantage: MESSAGE (vantage COMMAND --help)" and returns 2. */
int die_usage(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
/* An option's value refused: "CMD: OPT VALUE: expected WHAT"; returns 2. */
int die_bad_value(const char *cmd, const char *opt, const char *value, const char *expected);
/* An option the command needs and did not get: "CMD: OPT is missing (WHY)"; returns 2. */
int die_missing(const char *cmd, const char *opt, const char *why);
/* One option's name and what it accepts, by its getopt code. */
typedef struct cli_opt_doc {
    int code;
    const char *name, *expected;
} cli_opt_doc;
/* The refusal of code's value from docs[0..n) (the code itself if not there). */
int die_bad_opt(const char *cmd, const cli_opt_doc *docs, size_t n, int code, const char *value);
/* Reports a failed call with the server's code, record and message;
 * returns the exit status (1 refused, 3 connection). */
int server_fail(cli *k, const char *what, int rc);
/* Connects and says hello with role; 0 or exit status 3. */
int connect_cli(cli *k, int role);
bool parse_vec(const char *s, double *v, int n);
/* Decimal, or hex with 0x; the whole string. */
bool parse_u64(const char *s, uint64_t *v);
/* "WxH", each 1..max, the whole string. */
bool parse_size(const char *s, unsigned max, unsigned *w, unsigned *h);
/* "soft" or "gl" as VP_RENDERER_*. */
bool parse_renderer(const char *s, uint8_t *r);
double now_s(void);
/* src[0..n) as a quoted JSON string. */
void cli_json_str(FILE *f, const char *src, size_t n);
int cmp_dbl(const void *a, const void *b); /* qsort, ascending */
/* Ctrl-C sets g_stop (for the commands that run until it). */
extern volatile sig_atomic_t g_stop;
void catch_sigint(void);

/* cli_stats.c: `vantage stats [--json | --metrics]`. */
int cmd_stats(cli *k, int argc, char **argv);

/* cli_jsonl.c: one JSON line per entity. sublevel_name NULL writes the
 * number; handle adds the daemon's handle. */
void cli_entity_json(FILE *f, const vp_entity *e, bool handle, const char *sublevel_name);
int cmd_import(cli *k, int argc, char **argv);
int cmd_export(cli *k, int argc, char **argv);

/* cli_render.c */
int cmd_render(cli *k, int argc, char **argv);
int cmd_mark(cli *k, int argc, char **argv);
int cmd_select(cli *k, int argc, char **argv);
int cmd_watch_frames(cli *k, int argc, char **argv);
int cmd_lights(cli *k, int argc, char **argv);

/* cli_frames.c: `bench --test frames` */
int bench_frames(cli *k, int argc, char **argv);

/* cli_sublevel.c: sublevel load | unload | list */
int cmd_sublevel(cli *k, int argc, char **argv);

/* cli_scene.c: add, move, material put | rm */
int cmd_add(cli *k, int argc, char **argv);
int cmd_move(cli *k, int argc, char **argv);
int cmd_material(cli *k, int argc, char **argv);
/* cli_env.c: texture put | rm, env */
int cmd_texture(cli *k, int argc, char **argv);
int cmd_env(cli *k, int argc, char **argv);


/* cli_export.c: `vantage export FILE.glb`, the live scene as glTF 2.0 */
int cmd_export_glb(cli *k, const char *path);

/* cli_bench.c */
int cmd_bench(cli *k, int argc, char **argv);

/* cli_scenario.c: `bench --scenario FILE` (scenario.h) */
int bench_scenario(cli *k, int argc, char **argv);

/* cli_pad.c: pad list | pad dump (game controllers, pad_io.h) */
int cmd_pad(cli *k, int argc, char **argv);

/* commander.c: the tablet-commander thin client */
int cmdr_main(cli *k, int argc, char **argv);

#endif
