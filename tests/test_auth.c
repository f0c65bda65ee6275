/*
 * test_auth.c — roles and tokens: the token file parser (errors name the
 * line), the grant rule (a token of the role or a higher one; public
 * viewing only without a viewer line), the loopback test; end to end, the
 * real daemon with a token file: wrong or missing tokens refused with
 * AUTH and the connection closed, a viewer token cannot edit, an editor
 * token can; a token file others can read, and a non-loopback bind
 * without tokens, stop the daemon from starting with a clear message.
 */
#include "test_util.h"

#include "auth.h"
#include "test_daemon.h"

#include <fcntl.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#define EDIT_TOK "editor-token-0123456789abcdef"
#define VIEW_TOK "viewer-token-0123456789abcdef"
#define CMD_TOK "commander-token-0123456789ab"

static void test_auth_parse(void **state)
{
    (void)state;
    auth_tokens t;
    char err[256];
    const char *good = "# tokens\n\neditor " EDIT_TOK "\r\n  viewer\t" VIEW_TOK "  \ncommander " CMD_TOK;
    assert_int_equal(auth_parse(good, strlen(good), &t, err, sizeof err), 0);
    assert_int_equal(t.n, 3);
    assert_false(t.public_viewer);
    assert_int_equal(t.role[0], VP_ROLE_EDITOR);
    assert_int_equal(t.role[1], VP_ROLE_VIEWER);
    assert_int_equal(t.len[1], strlen(VIEW_TOK));
}

/* Token files refused: the text and what the message says. */
typedef struct bad_tokens {
    const char *name, *text, *want;
} bad_tokens;

static const bad_tokens bad_token_files[] = {
    {"empty", "", "no tokens"},
    {"a comment only", "# only a comment\n", "no tokens"},
    {"role admin", "editor " EDIT_TOK "\nadmin " VIEW_TOK "\n", "line 2: the role"},
    {"short token", "viewer short\n", "line 1: a token is 16 to 255"},
    {"a space in the token", "\n\neditor " EDIT_TOK " more\n", "line 3: a token is printable"},
    {"no token", "editor\n", "line 1: a token is 16"},
    {"UTF-8 in the token", "viewer caf\xc3\xa9-0123456789abcdef\n", "line 1: a token is printable"},
};

static void test_auth_parse_refused(void **state)
{
    const bad_tokens *t = *state;
    auth_tokens tk;
    char err[256] = "";
    assert_int_equal(auth_parse(t->text, strlen(t->text), &tk, err, sizeof err), -1);
    if (!strstr(err, t->want)) fail_msg("\"%s\" lacks \"%s\"", err, t->want);
}

static void test_auth_grants(void **state)
{
    (void)state;
    auth_tokens t;
    const char *f = "editor " EDIT_TOK "\ncommander " CMD_TOK "\n";
    assert_int_equal(auth_parse(f, strlen(f), &t, NULL, 0), 0);
    assert_true(t.public_viewer); /* no viewer line */
    const uint8_t *e = (const uint8_t *)EDIT_TOK, *c = (const uint8_t *)CMD_TOK;
    size_t el = strlen(EDIT_TOK), cl = strlen(CMD_TOK);
    assert_true(auth_grants(&t, VP_ROLE_VIEWER, NULL, 0));
    assert_true(auth_grants(&t, VP_ROLE_EDITOR, e, el));
    assert_true(auth_grants(&t, VP_ROLE_COMMANDER, e, el)); /* a higher role's token */
    assert_true(auth_grants(&t, VP_ROLE_COMMANDER, c, cl));
    assert_false(auth_grants(&t, VP_ROLE_EDITOR, c, cl));
    assert_false(auth_grants(&t, VP_ROLE_EDITOR, NULL, 0));
    assert_false(auth_grants(&t, VP_ROLE_EDITOR, e, el - 1));  /* a prefix */
    uint8_t longer[64];
    memcpy(longer, e, el);
    longer[el] = 'x';
    assert_false(auth_grants(&t, VP_ROLE_EDITOR, longer, el + 1));
    uint8_t flip[64];
    memcpy(flip, e, el);
    flip[el / 2] ^= 1;
    assert_false(auth_grants(&t, VP_ROLE_EDITOR, flip, el));
    uint8_t a[AUTH_TOKEN_CAP] = {0}, b[AUTH_TOKEN_CAP] = {0};
    assert_true(auth_ct_equal(a, b));
    b[AUTH_TOKEN_CAP - 1] = 1;
    assert_false(auth_ct_equal(a, b));

    assert_true(auth_loopback("127.0.0.1"));
    assert_true(auth_loopback("127.8.9.10"));
    assert_true(auth_loopback("::1"));
    assert_true(auth_loopback("localhost"));
    assert_true(auth_loopback(""));
    assert_false(auth_loopback("0.0.0.0"));
    assert_false(auth_loopback("10.1.2.3"));
    assert_false(auth_loopback("::"));
    assert_false(auth_loopback("example.org"));
}

/* A token file with mode `mode` in a fresh temporary path (static). */
static const char *token_file(const char *text, mode_t mode)
{
    static char path[64];
    snprintf(path, sizeof path, "/tmp/vantage-tokens-%d-XXXXXX", (int)getpid());
    int fd = mkstemp(path);
    assert_true(fd >= 0);
    assert_int_equal(write(fd, text, strlen(text)), (ssize_t)strlen(text));
    close(fd);
    assert_int_equal(chmod(path, mode), 0);
    return path;
}

static int try_connect(const daemon_proc *d, int role, const char *token, vtc_client **out)
{
    char err[256] = "";
    vtc_connect_opts o = {.port = d->port, .role = role, .token = token, .timeout_ms = 20000};
    *out = NULL;
    int rc = vtc_connect(&o, out, err, sizeof err);
    if (rc) fprintf(stderr, "auth e2e: role %d refused: %s\n", role, err);
    return rc;
}

static void test_auth_end_to_end(void **state)
{
    (void)state;
    char out[2048];
    /* a token file others can read: no start */
    const char *loose = token_file("editor " EDIT_TOK "\n", 0644);
    char args[512];
    snprintf(args, sizeof args, "--port %d --tokens %s", free_port(), loose);
    assert_int_equal(daemon_run_to_exit(args, out, sizeof out), 2);
    assert_non_null(strstr(out, "chmod 600"));
    unlink(loose);
    /* a symbolic link to a good file: no start (the mode checked would be
       the target's, the name the link's) */
    const char *target = token_file("editor " EDIT_TOK "\n", 0600);
    char link[80];
    snprintf(link, sizeof link, "%s.link", target);
    assert_int_equal(symlink(target, link), 0);
    snprintf(args, sizeof args, "--port %d --tokens %s", free_port(), link);
    assert_int_equal(daemon_run_to_exit(args, out, sizeof out), 2);
    assert_non_null(strstr(out, "symbolic link"));
    unlink(link);
    unlink(target);
    /* a non-loopback bind without tokens: no start */
    snprintf(args, sizeof args, "--bind 0.0.0.0 --port %d", free_port());
    assert_int_equal(daemon_run_to_exit(args, out, sizeof out), 2);
    assert_non_null(strstr(out, "--insecure"));

    /* the real thing: viewer and editor tokens */
    const char *f = token_file("viewer " VIEW_TOK "\neditor " EDIT_TOK "\n", 0600);
    const char *extra[] = {"--tokens", f, NULL};
    daemon_proc d;
    /* daemon_start_args waits with a token-less viewer, which this file
       refuses: it polls until the daemon answers at all, refusals too */
    daemon_start_args(&d, extra);
    vtc_client *c;
    assert_int_equal(try_connect(&d, VP_ROLE_VIEWER, NULL, &c), VP_ERR_AUTH);
    assert_int_equal(try_connect(&d, VP_ROLE_VIEWER, "not-the-viewer-token-at-all", &c), VP_ERR_AUTH);
    assert_int_equal(try_connect(&d, VP_ROLE_EDITOR, VIEW_TOK, &c), VP_ERR_AUTH);
    /* a viewer sees, and cannot edit */
    assert_int_equal(try_connect(&d, VP_ROLE_VIEWER, VIEW_TOK, &c), VP_OK);
    vp_entity e = {.id = 1, .aabb = {0, 0, 0, 1, 1, 1}};
    assert_int_equal(vtc_add(c, &e, 1, NULL, NULL), VP_ERR_AUTH);
    vp_stats_reply st;
    assert_int_equal(vtc_stats(c, &st), VP_OK);
    assert_int_equal(st.entities, 0);
    vtc_close(c);
    /* the editor token edits, and serves as a viewer's too */
    assert_int_equal(try_connect(&d, VP_ROLE_EDITOR, EDIT_TOK, &c), VP_OK);
    assert_int_equal(vtc_add(c, &e, 1, NULL, NULL), VP_OK);
    vtc_close(c);
    assert_int_equal(try_connect(&d, VP_ROLE_VIEWER, EDIT_TOK, &c), VP_OK);
    assert_int_equal(vtc_stats(c, &st), VP_OK);
    assert_int_equal(st.entities, 1);
    vtc_close(c);
    /* the CLI takes the token from the environment */
    char cmd[512];
    snprintf(cmd, sizeof cmd, "VANTAGE_TOKEN=%s %s/vantage -p %d add 2 5,0,0 1 >/dev/null 2>&1", EDIT_TOK, bin_dir(),
             d.port);
    assert_int_equal(system(cmd), 0);
    snprintf(cmd, sizeof cmd, "VANTAGE_TOKEN=%s %s/vantage -p %d add 3 6,0,0 1 >/dev/null 2>&1", VIEW_TOK, bin_dir(),
             d.port);
    assert_true(system(cmd) != 0);
    daemon_stop(&d);
    unlink(f);
}

const struct CMUnitTest auth_tests[] = {
    cmocka_unit_test(test_auth_parse),
    TEST_ROWS(test_auth_parse_refused, bad_token_files),
    cmocka_unit_test(test_auth_grants),
    cmocka_unit_test(test_auth_end_to_end),
};
const size_t auth_tests_count = sizeof auth_tests / sizeof auth_tests[0];
