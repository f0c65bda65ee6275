/*
 * test_http.c — the daemon's HTTP/1.x head parser (daemon/http.c) against
 * what RFC 9112 and RFC 6455 say, case by case: heads it must take, with
 * the fields read from them written out by hand here; heads it must
 * refuse, one named test each, with the status an origin server answers;
 * where a head ends, fed a byte at a time; the token lists of Connection
 * and Upgrade. (The metrics endpoint's end-to-end answers are in
 * test_metrics.c; the fuzz target tests/fuzz/fuzz_http.c checks that every
 * span lies inside the head.)
 */
#include "test_util.h"

#include "http.h"

#include <stdlib.h>
#include <string.h>

static bool span_eq(http_span s, const char *want)
{
    if (!want) return s.p == NULL;
    return s.p && s.n == strlen(want) && !memcmp(s.p, want, s.n);
}

/* Parses a whole head (its end found first). */
static int parse(const char *head, http_req *r, const char **why)
{
    size_t start, end = http_head_end(head, strlen(head), &start);
    if (!end) fail_msg("the head did not end: %s", head);
    return http_parse(head, start, end, r, why);
}

typedef struct good_row {
    const char *name, *head;
    const char *method, *path, *bearer, *ws_key, *ws_version;
    bool http11, head_only, host, upgrade, conn_upgrade;
} good_row;

static const good_row good[] = {
    {"get_11", "GET /metrics HTTP/1.1\r\nHost: x\r\n\r\n", "GET", "/metrics", NULL, NULL, NULL, true, false, true,
     false, false},
    {"get_10_no_host", "GET / HTTP/1.0\r\n\r\n", "GET", "/", NULL, NULL, NULL, false, false, false, false, false},
    /* bare LF line ends and empty lines before the request line (RFC 9112 2.2) */
    {"lf_and_leading_crlf", "\r\n\nHEAD /a?b=1 HTTP/1.1\nhost:h\n\n", "HEAD", "/a", NULL, NULL, NULL, true, true, true,
     false, false},
    /* header names case-insensitive, OWS around the value trimmed */
    {"bearer", "GET /x HTTP/1.1\r\nHOST: h\r\nauthorization: \t bearer  tok-1.2 \t\r\n\r\n", "GET", "/x", "tok-1.2",
     NULL, NULL, true, false, true, false, false},
    /* another scheme is no token; the first Bearer credential is */
    {"first_bearer",
     "GET / HTTP/1.1\r\nHost: h\r\nAuthorization: Basic YTpi\r\nAuthorization: Bearer t2\r\nAuthorization: Bearer t3\r\n\r\n",
     "GET", "/", "t2", NULL, NULL, true, false, true, false, false},
    {"basic_only", "GET / HTTP/1.1\r\nHost: h\r\nAuthorization: Basic YTpi\r\n\r\n", "GET", "/", NULL, NULL, NULL,
     true, false, true, false, false},
    /* a WebSocket opening handshake (RFC 6455 4.1's example) */
    {"websocket",
     "GET /chat HTTP/1.1\r\nHost: server.example.com\r\nUpgrade: websocket\r\nConnection: keep-alive, Upgrade\r\n"
     "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n",
     "GET", "/chat", NULL, "dGhlIHNhbXBsZSBub25jZQ==", "13", true, false, true, true, true},
    /* tokens, not substrings: "upgrade-insecure" is not "upgrade" */
    {"not_a_token", "GET / HTTP/1.1\r\nHost: h\r\nConnection: upgrade-insecure\r\nUpgrade: websockets\r\n\r\n", "GET",
     "/", NULL, NULL, NULL, true, false, true, false, false},
    {"extension_method", "M-SEARCH * HTTP/1.1\r\nHost: h\r\n\r\n", "M-SEARCH", "*", NULL, NULL, NULL, true, false,
     true, false, false},
};

static void test_http_parse_good(void **state)
{
    (void)state;
    for (size_t i = 0; i < sizeof good / sizeof good[0]; i++) {
        const good_row *g = &good[i];
        http_req r;
        const char *why;
        int st = parse(g->head, &r, &why);
        if (st) fail_msg("%s: refused with %d: %s", g->name, st, why);
        if (!span_eq(r.method, g->method) || !span_eq(r.path, g->path) || !span_eq(r.bearer, g->bearer) ||
            !span_eq(r.ws_key, g->ws_key) || !span_eq(r.ws_version, g->ws_version) || r.http11 != g->http11 ||
            r.head != g->head_only || r.host != g->host || r.upgrade_websocket != g->upgrade ||
            r.connection_upgrade != g->conn_upgrade)
            fail_msg("%s: fields differ from the head's", g->name);
        /* the target keeps its query */
        if (r.target.p != r.path.p || r.target.n < r.path.n) fail_msg("%s: target", g->name);
    }
}

typedef struct bad_row {
    const char *name, *head;
    int status;
    const char *why; /* a part of the reason */
    size_t len;      /* the head's bytes (0: up to its NUL) */
} bad_row;

static const bad_row bad[] = {
    {"no_target", "GET HTTP/1.1\r\nHost: h\r\n\r\n", 400, "request line", 0},
    {"two_spaces", "GET  / HTTP/1.1\r\nHost: h\r\n\r\n", 400, "request line", 0},
    {"trailing_space", "GET / HTTP/1.1 \r\nHost: h\r\n\r\n", 400, "request line", 0},
    {"cr_inside_line", "GET /\r HTTP/1.1\r\nHost: h\r\n\r\n", 400, "request line", 0},
    {"method_not_token", "G(T / HTTP/1.1\r\nHost: h\r\n\r\n", 400, "method", 0},
    {"target_control", "GET /\x01 HTTP/1.1\r\nHost: h\r\n\r\n", 400, "target", 0},
    {"target_8bit", "GET /\xc3\xa9 HTTP/1.1\r\nHost: h\r\n\r\n", 400, "target", 0},
    {"http2", "GET / HTTP/2.0\r\nHost: h\r\n\r\n", 505, "HTTP/1.0 and HTTP/1.1", 0},
    {"http09_like", "GET / HTTP/1\r\n\r\n", 400, "version", 0},
    {"lowercase_version", "GET / http/1.1\r\nHost: h\r\n\r\n", 400, "version", 0},
    {"no_host_11", "GET / HTTP/1.1\r\nAccept: */*\r\n\r\n", 400, "Host", 0},
    {"no_colon", "GET / HTTP/1.1\r\nHost h\r\n\r\n", 400, "header line", 0},
    {"empty_name", "GET / HTTP/1.1\r\n: v\r\nHost: h\r\n\r\n", 400, "header line", 0},
    /* obsolete line folding (RFC 9112 5.2): a server must refuse it or
       unfold it; this one refuses (the name would hold a space) */
    {"folding", "GET / HTTP/1.1\r\nHost: h\r\nX-A: 1\r\n  2\r\n\r\n", 400, "header", 0},
    {"space_before_colon", "GET / HTTP/1.1\r\nHost : h\r\n\r\n", 400, "header name", 0},
    {"control_in_value", "GET / HTTP/1.1\r\nHost: h\x7f\r\n\r\n", 400, "control byte", 0},
    {"nul_in_value", "GET / HTTP/1.1\r\nHost: h\r\nX: a\0b\r\n\r\n", 400, "control byte",
     sizeof "GET / HTTP/1.1\r\nHost: h\r\nX: a\0b\r\n\r\n" - 1},
    {"cr_in_header", "GET / HTTP/1.1\r\nHost: h\rX: y\r\n\r\n", 400, "header line", 0},
    /* RFC 9112 3.2: a request with more than one Host is refused (which
       one names the origin would be a guess) */
    {"two_hosts", "GET / HTTP/1.1\r\nHost: a\r\nHost: b\r\n\r\n", 400, "more than one Host", 0},
};

static void test_http_parse_refused(void **state)
{
    const bad_row *b = *state;
    size_t len = b->len ? b->len : strlen(b->head);
    size_t start, end = http_head_end(b->head, len, &start);
    assert_true(end > 0);
    http_req r;
    const char *why = NULL;
    int st = http_parse(b->head, start, end, &r, &why);
    if (st != b->status || !why || !strstr(why, b->why))
        fail_msg("%s: got %d (%s), want %d (%s)", b->name, st, why ? why : "-", b->status, b->why);
    assert_true(why[strlen(why) - 1] == '\n');
}

/* A head fed a byte at a time ends exactly at its empty line, never
 * before; what follows it (a body, a pipelined request) is not read. */
static void test_http_head_end_bytewise(void **state)
{
    (void)state;
    const char *head = "\r\nGET / HTTP/1.1\r\nHost: h\nX: y\r\n\r\n";
    const char *more = "GET /next HTTP/1.1\r\n\r\n";
    size_t hl = strlen(head);
    char *buf = malloc(hl + strlen(more) + 1);
    strcpy(buf, head);
    strcat(buf, more);
    for (size_t n = 0; n <= strlen(buf); n++) {
        char *exact = malloc(n + 1); /* exact size: ASan sees any overread */
        memcpy(exact, buf, n);
        size_t start = 99, end = http_head_end(exact, n, &start);
        if (n < hl) assert_int_equal(end, 0);
        else assert_int_equal(end, hl);
        if (n >= 2) assert_int_equal(start, 2);
        free(exact);
    }
    free(buf);
}

static void test_http_list_has(void **state)
{
    (void)state;
    struct {
        const char *v, *t;
        bool want;
    } rows[] = {
        {"Upgrade", "upgrade", true},
        {"keep-alive, Upgrade", "upgrade", true},
        {" ,, keep-alive ,\tupgrade\t, ", "upgrade", true},
        {"upgrade-insecure", "upgrade", false},
        {"keep-alive", "upgrade", false},
        {"", "upgrade", false},
        {"up grade", "upgrade", false},
        {"websocket", "websocket", true},
    };
    for (size_t i = 0; i < sizeof rows / sizeof rows[0]; i++) {
        http_span v = {rows[i].v, strlen(rows[i].v)};
        if (http_list_has(v, rows[i].t) != rows[i].want) fail_msg("'%s' has '%s': wrong", rows[i].v, rows[i].t);
    }
    assert_false(http_list_has((http_span){NULL, 0}, "upgrade"));
}

/* The Host and Origin values a WebSocket upgrade is checked with (web.c:
 * a page from another site may not open the daemon's WebSocket). */
static void test_http_host_origin(void **state)
{
    (void)state;
    http_req r;
    const char *why;
    assert_int_equal(parse("GET /ws HTTP/1.1\r\nHost:  localhost:8080 \r\nOrigin: http://localhost:8080\r\n\r\n", &r,
                           &why),
                     0);
    assert_true(span_eq(r.host_value, "localhost:8080"));
    assert_true(span_eq(r.origin, "http://localhost:8080"));
    assert_int_equal(parse("GET / HTTP/1.0\r\n\r\n", &r, &why), 0);
    assert_false(r.host);
    assert_null(r.origin.p);
}

const struct CMUnitTest http_tests[] = {
    cmocka_unit_test(test_http_host_origin),
    cmocka_unit_test(test_http_parse_good),
    TEST_ROWS(test_http_parse_refused, bad),
    cmocka_unit_test(test_http_head_end_bytewise),
    cmocka_unit_test(test_http_list_has),
};
const size_t http_tests_count = sizeof http_tests / sizeof http_tests[0];
