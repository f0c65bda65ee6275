/*
 * test_cli.c — the `vantage` CLI as a new user meets it (issue 26): every
 * command's --help is its own, README.md's command list and vantaged's
 * options agree with the binaries' help, errors name the option and what
 * it accepts, and the figures printed are not quiet lies (no area column
 * that was never measured, watch --orbit keeps --fps, bench runs exactly
 * --requests, the commander without a display says so and fails). The
 * real binaries (VANTAGE_BIN_DIR) against a real daemon (test_daemon.h).
 */
#include "test_util.h"
#include "test_daemon.h"

#include <ctype.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

/* Runs cmd (stderr joined to stdout): its exit status, -1 if it did not exit. */
static int run(const char *cmd, char *out, size_t cap)
{
    char full[4096];
    snprintf(full, sizeof full, "%s 2>&1", cmd);
    int st = test_run_cmd(full, out, cap);
    return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

static char *read_text(const char *path)
{
    FILE *f = fopen(path, "r");
    if (!f) return NULL;
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    char *s = malloc((size_t)n + 1);
    if (s && fread(s, 1, (size_t)n, f) != (size_t)n) n = 0;
    if (s) s[n] = 0;
    fclose(f);
    return s;
}

static const char *src_dir(void)
{
    const char *d = getenv("VANTAGE_SRC_DIR");
    return d ? d : ".";
}

/* ---- the command list: a form is a command and the words that pick it
 * ("bench --test frames", "sublevel load"), with the options its synopsis
 * names. Both lists are read with the same rules: a line indented 2
 * spaces starts a form (several, split at '|' outside brackets), one
 * indented 8 continues its synopsis, others (the brief) are skipped.
 * " | " outside brackets separates forms on one line ("FILE.gltf|glb" does not). */

#define MAX_FORMS 64
typedef struct form {
    char key[96];
    char opts[1024]; /* " --a --b " */
} form;

typedef struct forms {
    form f[MAX_FORMS];
    int n;
} forms;

static bool literal(const char *t, size_t n)
{
    if (!n || !(t[0] == '-' || islower((unsigned char)t[0]))) return false;
    for (size_t i = 0; i < n; i++)
        if (!(islower((unsigned char)t[i]) || t[i] == '-')) return false;
    return true;
}

static void add_opts(form *f, const char *s, size_t n)
{
    for (size_t i = 0; i + 1 < n; i++) {
        if (s[i] != '-' || (i && !strchr(" [|", s[i - 1]))) continue;
        size_t j = i;
        while (j < n && (s[j] == '-' || islower((unsigned char)s[j]))) j++;
        if (j - i < 2 || s[j - 1] == '-') continue;
        char opt[64];
        snprintf(opt, sizeof opt, " %.*s ", (int)(j - i), s + i);
        if (!strstr(f->opts, opt) && strlen(f->opts) + strlen(opt) < sizeof f->opts)
            strcat(f->opts[0] ? f->opts : strcpy(f->opts, " "), opt + 1);
        i = j;
    }
}

/* One form from its synopsis text s[0..n). */
static void new_form(forms *fs, const char *s, size_t n)
{
    while (n && *s == ' ') s++, n--;
    while (n && s[n - 1] == ' ') n--;
    if (!n) return;
    if (fs->n == MAX_FORMS) fail_msg("more than %d forms", MAX_FORMS);
    form *f = &fs->f[fs->n++];
    memset(f, 0, sizeof *f);
    size_t i = 0, k = 0;
    for (int w = 0; i < n; w++) {
        size_t l = 0;
        while (i + l < n && s[i + l] != ' ') l++;
        if (w > 0 && !literal(s + i, l)) break;
        k += (size_t)snprintf(f->key + k, sizeof f->key - k, "%s%.*s", w ? " " : "", (int)l, s + i);
        i += l;
        while (i < n && s[i] == ' ') i++;
    }
    add_opts(f, s, n);
}

static int indent(const char *l)
{
    int i = 0;
    while (l[i] == ' ') i++;
    return i;
}

/* The lines of text[0..len) read as above. */
static void parse_forms(const char *text, size_t len, forms *fs)
{
    fs->n = 0;
    for (const char *l = text; l < text + len;) {
        const char *e = memchr(l, '\n', (size_t)(text + len - l));
        size_t n = e ? (size_t)(e - l) : (size_t)(text + len - l);
        int in = indent(l);
        if (in == 2 && islower((unsigned char)l[2])) {
            int depth = 0;
            size_t start = 0;
            for (size_t i = 0; i <= n; i++) {
                if (i < n && (l[i] == '[' || l[i] == '(')) depth++;
                else if (i < n && (l[i] == ']' || l[i] == ')')) depth--;
                else if (i == n || (l[i] == '|' && depth == 0 && l[i - 1] == ' ' && l[i + 1] == ' ')) {
                    new_form(fs, l + start, i - start);
                    start = i + 1;
                }
            }
        } else if (in == 8 && fs->n) {
            add_opts(&fs->f[fs->n - 1], l, n);
        }
        l += n + 1;
    }
}

/* The nth form (0: the first) keyed key: a command may have several forms
 * with the same literal words ("add ID --mesh C ..." and "add ID X,Y,Z
 * R ..."), matched in order. */
static const form *find_form(const forms *fs, const char *key, int nth)
{
    for (int i = 0; i < fs->n; i++)
        if (!strcmp(fs->f[i].key, key) && nth-- == 0) return &fs->f[i];
    return NULL;
}

/* Every option of x (" --a --b ") is in y, or the test fails naming it. */
static void opts_within(const char *key, const char *x, const char *xn, const char *y, const char *yn)
{
    for (const char *p = x; (p = strchr(p, '-'));) {
        size_t l = strcspn(p, " ");
        char opt[72];
        snprintf(opt, sizeof opt, " %.*s ", (int)l, p);
        if (!strstr(y, opt)) fail_msg("'%s': option %.*s is in %s but not in %s", key, (int)l, p, xn, yn);
        p += l;
    }
}

/* Every form of a is in b with the same options. */
static void forms_within(const forms *a, const char *an, const forms *b, const char *bn)
{
    for (int i = 0; i < a->n; i++) {
        int nth = 0;
        for (int j = 0; j < i; j++) nth += !strcmp(a->f[j].key, a->f[i].key);
        const form *o = find_form(b, a->f[i].key, nth);
        if (!o) fail_msg("'%s' is in %s but not in %s", a->f[i].key, an, bn);
        opts_within(a->f[i].key, a->f[i].opts, an, o->opts, bn);
        opts_within(a->f[i].key, o->opts, bn, a->f[i].opts, an);
    }
}

/* The lines between "commands:" and the next empty line of vantage --help. */
static void help_forms(forms *fs, char *out, size_t cap)
{
    assert_int_equal(vantage_run(NULL, out, cap, "--help"), 0);
    const char *a = strstr(out, "\ncommands:\n");
    assert_non_null(a);
    a += strlen("\ncommands:\n");
    const char *b = strstr(a, "\n\n");
    assert_non_null(b);
    parse_forms(a, (size_t)(b - a + 1), fs);
}

/* README.md's CLI block: the fenced block after "## vantage (the CLI)", its
 * first line (the connection flags) left out. */
static void readme_forms(forms *fs, char **readme)
{
    char path[600];
    snprintf(path, sizeof path, "%s/README.md", src_dir());
    *readme = read_text(path);
    if (!*readme) fail_msg("%s: cannot read it (VANTAGE_SRC_DIR)", path);
    const char *sec = strstr(*readme, "\n## vantage (the CLI)\n");
    assert_non_null(sec);
    const char *a = strstr(sec, "\n```\n");
    assert_non_null(a);
    a = strchr(a + 5, '\n'); /* past "vantage [-h HOST] ..." */
    assert_non_null(a);
    const char *b = strstr(a, "\n```");
    assert_non_null(b);
    parse_forms(a + 1, (size_t)(b - a), fs);
}

/* The output holds a usage line for key: "usage: vantage KEY ..." or
 * "   or: vantage KEY ...". */
static bool names_usage(const char *out, const char *key)
{
    char want[160];
    int n = snprintf(want, sizeof want, "vantage %s", key);
    for (const char *l = out; l && *l; l = strchr(l, '\n') ? strchr(l, '\n') + 1 : NULL) {
        const char *p = l;
        while (*p == ' ') p++;
        if (!strncmp(p, "usage:", 6)) p += 6;
        else if (!strncmp(p, "or:", 3)) p += 3;
        else continue;
        while (*p == ' ') p++;
        if (!strncmp(p, want, (size_t)n) && (p[n] == ' ' || p[n] == '\n' || !p[n])) return true;
    }
    return false;
}

static void test_cli_help_every_command(void **state)
{
    (void)state;
    static forms help, readme;
    static char out[32768];
    help_forms(&help, out, sizeof out);
    char *text;
    readme_forms(&readme, &text);
    assert_true(help.n >= 20);
    /* the README's list and the CLI's, both ways, options included */
    forms_within(&help, "vantage --help", &readme, "README.md");
    forms_within(&readme, "README.md", &help, "vantage --help");
    free(text);
    /* each command and each form: its own usage, not the global one */
    static char cmds[MAX_FORMS][96];
    int ncmds = 0;
    for (int i = 0; i < help.n; i++) {
        char word[96];
        snprintf(word, sizeof word, "%.*s", (int)strcspn(help.f[i].key, " "), help.f[i].key);
        bool seen = false;
        for (int k = 0; k < ncmds; k++) seen |= !strcmp(cmds[k], word);
        if (!seen) snprintf(cmds[ncmds++], sizeof cmds[0], "%s", word);
    }
    for (int pass = 0; pass < 2; pass++) {
        int n = pass ? help.n : ncmds;
        for (int i = 0; i < n; i++) {
            const char *key = pass ? help.f[i].key : cmds[i];
            int rc = vantage_run(NULL, out, sizeof out, "%.96s --help", key);
            if (rc != 0) fail_msg("vantage %s --help: exit %d: %s", key, rc, out);
            if (strstr(out, "\ncommands:\n")) fail_msg("vantage %s --help: the global help:\n%s", key, out);
            if (!names_usage(out, key)) fail_msg("vantage %s --help: no usage line for '%s':\n%s", key, key, out);
        }
    }
    /* the forms the issue named */
    assert_non_null(find_form(&help, "bench --scenario", 0));
    assert_non_null(find_form(&help, "bench --test frames", 0));
    for (const char *const *w = (const char *const[]){"ping", "stats", "add", "move", "remove", "get", "import",
                                                     "export", "destroy", "watch", "bench", NULL};
         *w; w++) {
        bool found = false;
        for (int k = 0; k < ncmds; k++) found |= !strcmp(cmds[k], *w);
        if (!found) fail_msg("%s is not in vantage --help", *w);
    }
}

/* vantaged --help and README's vantaged block name the same options. */
static void test_cli_vantaged_help_readme(void **state)
{
    (void)state;
    static char out[32768];
    char cmd[600];
    snprintf(cmd, sizeof cmd, "%s/vantaged --help", bin_dir());
    assert_int_equal(run(cmd, out, sizeof out), 0);
    static form h, r;
    for (const char *l = out; l; l = strchr(l, '\n') ? strchr(l, '\n') + 1 : NULL)
        if (!strncmp(l, "  --", 4)) add_opts(&h, l + 2, strcspn(l + 2, " \n"));
    char path[600];
    snprintf(path, sizeof path, "%s/README.md", src_dir());
    char *text = read_text(path);
    assert_non_null(text);
    const char *a = strstr(text, "\n## vantaged\n");
    assert_non_null(a);
    a = strstr(a, "\n```\n");
    assert_non_null(a);
    const char *b = strstr(a + 5, "\n```");
    assert_non_null(b);
    add_opts(&r, a, (size_t)(b - a));
    free(text);
    assert_non_null(strstr(h.opts, " --out-limit-total "));
    assert_true(strlen(h.opts) > 100);
    forms fh = {.n = 1}, fr = {.n = 1};
    fh.f[0] = h, fr.f[0] = r;
    snprintf(fh.f[0].key, sizeof fh.f[0].key, "vantaged");
    snprintf(fr.f[0].key, sizeof fr.f[0].key, "vantaged");
    forms_within(&fh, "vantaged --help", &fr, "README.md");
}

/* Usage errors name the option, what it accepts, or what is missing; a
 * row is the command's arguments (its name) and what the error says. */
typedef struct usage_case {
    const char *args;
    const char *want[3];
} usage_case;

static const usage_case usage_cases[] = {
    {"render --eye 1,2,3 --at 0,0,0 --size 500 -o x.png", {"--size 500", "WxH"}},
    {"render --eye 1,2,3 --at 0,0,0 --size 0x0 -o x.png", {"--size 0x0", "1..4096"}},
    {"render --eye 1,2,3 --at 0,0,0 --renderer vulkan -o x.png", {"--renderer vulkan", "soft or gl"}},
    {"render --eye 1,2,3 --at 0,0,0 --fov 200 -o x.png", {"--fov 200", "180"}},
    {"render --eye 1,2,3 --at 0,0,0 -o x.tiff", {"-o x.tiff", ".png"}},
    {"render --eye 1,2,3 --at 0,0,0", {"-o FILE", "missing"}},
    {"render --eye 1,2,3 -o x.png", {"--at X,Y,Z is missing"}},
    {"render --at 1,2,3 -o x.png", {"--eye X,Y,Z is missing"}},
    {"query --eye 1,2,3", {"--at X,Y,Z is missing"}},
    {"query --eye 1,2,3 --at 0,0,0 --ortho 0,1", {"--ortho 0,1", "> 0"}},
    {"lights --eye 1,2,3 --at 0,0,0 --size 9x", {"--size 9x", "WxH"}},
    {"watch --frames d --eye 1,2,3 --at 0,0,0 --fps 0", {"--fps 0", "1..240"}},
    {"watch --frames d --eye 1,2,3 --at 0,0,0 --format gif", {"--format gif", "jpg, png or exr"}},
    {"watch --eye 1,2,3 --at 0,0,0 --frames", {"--frames"}},
    {"destroy 5 0,0,0 0", {"radius 0", "more than 0"}},
    {"destroy 5 0,0,0 -2", {"radius -2", "more than 0"}},
    {"destroy 5 0,0 1", {"centre 0,0", "X,Y,Z"}},
    {"destroy 5 0,0,0 1 --debris 999", {"--debris 999", "0..64"}},
    {"bench --test ping --requests 10 --clients 64", {"--requests 10 is fewer than --clients 64"}},
    {"bench --clients 0", {"--clients 0", "1..1000"}},
    {"bench --test fast", {"--test fast", "query, edit, transform, ping or frames"}},
    {"add 1 --mesh 2 --rotate 1,2", {"--rotate 1,2", "YAW,PITCH,ROLL"}},
    {"add 1 --mesh 2 --scale x", {"--scale x", "S or X,Y,Z"}},
    {"material put 1 --texture roof=1", {"--texture roof=1", "SLOT=ID"}},
    {"bench --test frames --fps 0", {"--fps", "1..240"}},
    {"bench --test frames --viewers x", {"--viewers x"}},
};

static void test_cli_errors_name_the_option(void **state)
{
    const usage_case *t = *state;
    char out[4096];
    /* port 1: nothing listens; every case is refused before connecting */
    int rc = vantage_run(NULL, out, sizeof out, "-p 1 %s", t->args);
    if (rc != 2) fail_msg("%s: exit %d, want 2 (bad usage): %s", t->args, rc, out);
    for (int k = 0; k < 3 && t->want[k]; k++)
        if (!strstr(out, t->want[k])) fail_msg("%s: \"%s\" does not say \"%s\"", t->args, out, t->want[k]);
    /* one line, the command's own help pointed to */
    char hint[64];
    snprintf(hint, sizeof hint, "(vantage %.*s --help)", (int)strcspn(t->args, " "), t->args);
    if (!strstr(out, hint)) fail_msg("%s: \"%s\" does not point to %s", t->args, out, hint);
}

/* The server's refusals of an id that names nothing: the record named
 * once, and what is missing. A row is the command. */
typedef struct refusal {
    const char *op;
} refusal;

static const refusal refusals[] = {{"move 123456789 1,2,3"}, {"remove 123456789"}, {"get 123456789"}};

static void test_cli_server_errors(void **state)
{
    const refusal *t = *state;
    daemon_proc d;
    daemon_start(&d, NULL);
    char out[4096];
    assert_int_equal(vantage_run(&d, out, sizeof out, "%s", t->op), 1);
    const char *r = strstr(out, "record 0");
    if (!r || strstr(r + 1, "record 0")) fail_msg("%s: the record once: %s", t->op, out);
    assert_non_null(strstr(out, "no entity with id 123456789"));
    daemon_stop(&d);
}

/* A sub-level name that names nothing: its own code, no entity named. */
static void test_cli_unload_unknown(void **state)
{
    daemon_proc *d = *state;
    char out[4096];
    assert_int_equal(vantage_run(d, out, sizeof out, "sublevel unload nosuch"), 1);
    if (!strstr(out, "no sub-level named \"nosuch\"") || strstr(out, "no entity") || !strstr(out, "error -23"))
        fail_msg("sublevel unload nosuch: %s", out);
}

/* query prints an area only where it was measured (--exact-area). */
static void test_cli_query_area(void **state)
{
    daemon_proc *d = *state;
    char cmd[800], out[8192];
    snprintf(cmd, sizeof cmd, "%s/vantage -p %d add 7 0,0,20 1 && %s/vantage -p %d add 8 2,0,30 1", bin_dir(), d->port,
             bin_dir(), d->port);
    assert_int_equal(run(cmd, out, sizeof out), 0);
    const char *q = "query --eye 0,0,0 --at 0,0,10 --size 640x480";
    snprintf(cmd, sizeof cmd, "%s/vantage -p %d %s && %s/vantage -p %d %s --json", bin_dir(), d->port, q, bin_dir(),
             d->port, q);
    assert_int_equal(run(cmd, out, sizeof out), 0);
    assert_non_null(strstr(out, "id 7 "));
    assert_non_null(strstr(out, "\"id\": 8, "));
    if (strstr(out, "area")) fail_msg("an area that was not measured: %s", out);
    snprintf(cmd, sizeof cmd, "%s/vantage -p %d %s --exact-area && %s/vantage -p %d %s --exact-area --json",
             bin_dir(), d->port, q, bin_dir(), d->port, q);
    assert_int_equal(run(cmd, out, sizeof out), 0);
    /* a unit sphere 20 m away in a 60-degree, 480-pixel-high view: about
       pi (480 / (2 tan 30) / 20)^2 = 1,380 pixels */
    const char *a = strstr(out, "area ");
    assert_non_null(a);
    double area = atof(a + 5);
    if (!(area > 700 && area < 2800)) fail_msg("area %.1f: %s", area, out);
    a = strstr(out, "\"area\": ");
    assert_non_null(a);
    assert_true(atof(a + 8) > 0);
    assert_null(strstr(out, "-1"));
}

/* watch --orbit keeps --fps: frames counted over a window, bounds wide
 * enough for a loaded machine (a miss only lowers the count). */
static void test_cli_watch_orbit_fps(void **state)
{
    daemon_proc *d = *state;
    tdir td;
    tdir_make(&td, "vt-cli-watch");
    static char out[65536];
    assert_int_equal(vantage_run(d, out, sizeof out, "add 7 0,0,0 5"), 0);
    const struct { int fps; double secs; } runs[] = {{5, 3}, {10, 2}};
    for (size_t i = 0; i < 2; i++) {
        /* the frames written are counted (not the lines: an uncapped run
           prints more than a pipe is read here) */
        assert_int_equal(vantage_run(d, out, sizeof out,
                                     "watch --frames %s --eye 50,20,0 --at 0,0,0 --size 96x64 --orbit 30 --fps %d "
                                     "--seconds %g > /dev/null",
                                     td.dir, runs[i].fps, runs[i].secs),
                         0);
        int frames = tdir_count(&td);
        double want = runs[i].fps * runs[i].secs;
        print_message("watch --orbit 30 --fps %d for %g s: %d frames (%g at the cap)\n", runs[i].fps, runs[i].secs,
                      frames, want);
        if (frames > want + 2 || frames < want / 3)
            fail_msg("--fps %d for %g s: %d frames, want about %g", runs[i].fps, runs[i].secs, frames, want);
        tdir_remove(&td);
        tdir_make(&td, "vt-cli-watch");
    }
    tdir_remove(&td);
}

/* bench runs exactly --requests, the remainder spread over the clients. */
static void test_cli_bench_exact_requests(void **state)
{
    daemon_proc *d = *state;
    char out[4096];
    const struct { int requests, clients; } runs[] = {{1000, 64}, {101, 7}, {64, 64}};
    for (size_t i = 0; i < 3; i++) {
        assert_int_equal(vantage_run(d, out, sizeof out, "bench --test ping --requests %d --clients %d --threads 2 --json",
                                     runs[i].requests, runs[i].clients),
                         0);
        char want[64];
        snprintf(want, sizeof want, "\"requests\": %d, \"failed_threads\": 0", runs[i].requests);
        if (!strstr(out, want)) fail_msg("%d requests over %d clients: %s", runs[i].requests, runs[i].clients, out);
    }
}

/* The commander without a display: says why, suggests --headless, fails. */
static void test_cli_commander_no_display(void **state)
{
    daemon_proc *d = *state;
    char cmd[1200], out[8192];
    const char *envs[] = {"env -u DISPLAY -u WAYLAND_DISPLAY -u SDL_VIDEODRIVER", "env SDL_VIDEODRIVER=nosuch"};
    for (int i = 0; i < 2; i++) {
        snprintf(cmd, sizeof cmd, "%s ASAN_OPTIONS=\"$ASAN_OPTIONS:detect_leaks=0\" timeout 20 %s/vantage -p %d commander --seconds 2",
                 envs[i], bin_dir(), d->port);
        int rc = run(cmd, out, sizeof out);
        if (rc == 0 || rc == 124) fail_msg("%s: exit %d: %s", envs[i], rc, out);
        if (!strstr(out, "cannot open a window") || !strstr(out, "--headless"))
            fail_msg("%s: \"%s\" does not say why or suggest --headless", envs[i], out);
    }
}

/* The commander's --stats with no latency sample: '-' and null, never
 * nan; its frame rate is frames shown over the run. */
static void test_cli_commander_stats_no_samples(void **state)
{
    daemon_proc *d = *state;
    tdir td;
    tdir_make(&td, "vt-cli-cmd");
    static char out[16384];
    for (int json = 0; json < 2; json++) {
        /* no pad, no replay, no window: nothing moves the view */
        int rc = vantage_run(d, out, sizeof out, "commander --headless %s --size 64x48 --seconds 1.5 --stats%s", td.dir,
                             json ? " --json" : "");
        if (rc) fail_msg("commander --stats%s: exit %d: %s", json ? " --json" : "", rc, out);
        if (strstr(out, "nan") || strstr(out, "NaN")) fail_msg("nan printed: %s", out);
        if (json) {
            assert_non_null(strstr(out, "\"input_to_photon_ms\":{\"p50\":null"));
            double secs = atof(strstr(out, "\"seconds\":") + 10), fps = atof(strstr(out, "\"fps\":") + 6);
            unsigned long long frames = strtoull(strstr(out, "\"frames\":") + 9, NULL, 10);
            assert_true(frames >= 1);
            assert_float_equal(fps, frames / secs, 0.02 * fps + 0.01);
        } else {
            const char *row = strstr(out, "input_to_photon");
            assert_non_null(row);
            char first[64];
            assert_int_equal(sscanf(row, "input_to_photon %63s", first), 1);
            assert_string_equal(first, "-");
        }
    }
    tdir_remove(&td);
}

/* vantaged's bad option values name the option and what it accepts (they
 * only named the option) and exit 2. A row is the arguments. */
typedef struct daemon_usage_case {
    const char *args, *want;
} daemon_usage_case;

static const daemon_usage_case daemon_usage_cases[] = {
    {"--out-limit-total 100", "bad value for --out-limit-total: 100 (expected bytes, 0 (no limit) or at least 65536)"},
    {"--port 0", "bad value for --port: 0 (expected an integer, 1..65535)"},
    {"--threads 999", "bad value for --threads: 999 (expected an integer, 0..256)"},
    {"--durability sometimes", "(expected always, everysec, off, or replicated (with --cluster))"},
    {"--render vulkan", "(expected soft or gl)"},
    {"--fx-off shadows,bloom", "bad value for --fx-off: shadows,bloom (expected shadows, ssao, ibl, fxaa, comma-separated)"},
    {"--cell-size 0", "(expected metres, 0.01..1e5)"},
    {"--log-level loud", "(expected error, warn, info or debug)"},
};

static void test_vantaged_errors_name_what_is_accepted(void **state)
{
    const daemon_usage_case *t = *state;
    char out[2048];
    int rc = daemon_run_to_exit(t->args, out, sizeof out);
    if (rc != 2 || !strstr(out, t->want)) fail_msg("vantaged %s: exit %d: %s", t->args, rc, out);
}

const struct CMUnitTest cli_tests[] = {
    TEST_ROWS(test_vantaged_errors_name_what_is_accepted, daemon_usage_cases),
    cmocka_unit_test(test_cli_help_every_command),
    cmocka_unit_test(test_cli_vantaged_help_readme),
    TEST_ROWS(test_cli_errors_name_the_option, usage_cases),
    TEST_ROWS(test_cli_server_errors, refusals),
    DAEMON_TEST(test_cli_unload_unknown),
    DAEMON_TEST(test_cli_query_area),
    DAEMON_TEST(test_cli_watch_orbit_fps),
    DAEMON_TEST(test_cli_bench_exact_requests),
    DAEMON_TEST(test_cli_commander_no_display),
    DAEMON_TEST(test_cli_commander_stats_no_samples),
};
const size_t cli_tests_count = sizeof cli_tests / sizeof cli_tests[0];
