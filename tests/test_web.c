/*
 * test_web.c — `vantaged --web` (daemon/web.c, issue 21) against a real
 * daemon, with this file's own WebSocket client: RFC 6455 frames built and
 * read here byte by byte (masking, lengths, opcodes), so the daemon's
 * framing (libwslay) and upgrade are checked against the RFC, not against
 * themselves. The pages come from a web root made here, holding what an
 * attacker would reach for (a dotfile, a symlink out of the root).
 *
 * What the browser tests (tests/web, headless Chromium) cover is the
 * pages; this is the endpoint: static files, the upgrade's refusals, the
 * protocol's stream over WebSocket messages, bad frames and floods, and
 * many viewers at once.
 */
#include "test_daemon.h"
#include "test_util.h"

#include "h264_ref.h"
#include "protocol.h"
#include "vt_image.h"

#include <openssl/err.h>
#include <openssl/ssl.h>

#include <arpa/inet.h>
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <time.h>
#include <netinet/in.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

/* ---- the web root and the daemon ------------------------------------------------------- */

static char root[128];
static int web_port;

static void write_file(const char *dir, const char *name, const char *text)
{
    char p[256];
    snprintf(p, sizeof p, "%s/%s", dir, name);
    FILE *f = fopen(p, "w");
    assert_non_null(f);
    fputs(text, f);
    fclose(f);
}

static void make_root(void)
{
    snprintf(root, sizeof root, "/tmp/vantage-web-%d", (int)getpid());
    char p[256];
    mkdir(root, 0700);
    snprintf(p, sizeof p, "%s/js", root);
    mkdir(p, 0700);
    write_file(root, "index.html", "<!doctype html><title>vantage</title>\n");
    write_file(root, "js/a.js", "export const a = 1;\n");
    write_file(root, ".secret.txt", "hidden\n");
    snprintf(p, sizeof p, "%s/passwd.txt", root);
    unlink(p);
    assert_int_equal(symlink("/etc/passwd", p), 0);
}

static void drop_root(void)
{
    const char *names[] = {"index.html", "js/a.js", ".secret.txt", "passwd.txt", "js", ""};
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++) {
        char p[256];
        snprintf(p, sizeof p, "%s/%s", root, names[i]);
        if (remove(p)) rmdir(p);
    }
}

/* A daemon with --web on a free port (and more arguments, NULL-ended). */
static void web_start(daemon_proc *d, const char *const *more)
{
    make_root();
    web_port = free_port();
    static char port[16];
    snprintf(port, sizeof port, "%d", web_port);
    const char *extra[16] = {"--web", port, "--web-root", root};
    int n = 4;
    for (int i = 0; more && more[i]; i++) extra[n++] = more[i];
    daemon_start_args(d, extra);
}

static void web_stop(daemon_proc *d)
{
    daemon_stop(d);
    drop_root();
}

static int web_connect(void)
{
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    struct sockaddr_in sa = {.sin_family = AF_INET, .sin_port = htons((uint16_t)web_port)};
    sa.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    assert_int_equal(connect(fd, (struct sockaddr *)&sa, sizeof sa), 0);
    struct timeval tv = {.tv_sec = 10};
    setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    return fd;
}

static void send_all(int fd, const void *p, size_t n)
{
    assert_int_equal(send(fd, p, n, MSG_NOSIGNAL), (ssize_t)n);
}

/* One HTTP exchange: the whole answer (to the daemon's close) in out. */
static size_t http_get(const char *req, char *out, size_t cap)
{
    int fd = web_connect();
    send_all(fd, req, strlen(req));
    size_t have = 0;
    ssize_t n;
    while (have < cap - 1 && (n = read(fd, out + have, cap - 1 - have)) > 0) have += (size_t)n;
    out[have] = 0;
    close(fd);
    return have;
}

/* ---- static files ------------------------------------------------------------------------ */

typedef struct file_row {
    const char *name, *req;
    const char *status; /* the status line's start */
    const char *has;    /* in the answer */
} file_row;

#define GET(path) "GET " path " HTTP/1.1\r\nHost: x\r\n\r\n"
static const file_row files[] = {
    {"index", GET("/"), "HTTP/1.1 200 ", "<title>vantage</title>"},
    {"index_by_name", GET("/index.html"), "HTTP/1.1 200 ", "Content-Type: text/html"},
    {"script", GET("/js/a.js"), "HTTP/1.1 200 ", "Content-Type: text/javascript"},
    {"nosniff", GET("/js/a.js"), "HTTP/1.1 200 ", "X-Content-Type-Options: nosniff"},
    {"head", "HEAD /js/a.js HTTP/1.1\r\nHost: x\r\n\r\n", "HTTP/1.1 200 ", "Content-Length: 20\r\n"},
    {"query_ignored", GET("/js/a.js?v=2"), "HTTP/1.1 200 ", "export const a"},
    {"missing", GET("/nope.html"), "HTTP/1.1 404 ", "not found"},
    {"dot_dot", GET("/../etc/passwd"), "HTTP/1.1 404 ", "not found"},
    {"dot_dot_inside", GET("/js/../index.html"), "HTTP/1.1 404 ", "not found"},
    {"dotfile", GET("/.secret.txt"), "HTTP/1.1 404 ", "not found"},
    {"symlink_out", GET("/passwd.txt"), "HTTP/1.1 404 ", "not found"},
    {"double_slash", GET("//index.html"), "HTTP/1.1 404 ", "not found"},
    {"percent", GET("/%2e%2e/x.html"), "HTTP/1.1 404 ", "not found"},
    {"directory", GET("/js"), "HTTP/1.1 404 ", "not found"},
    {"type_not_served", GET("/index.exe"), "HTTP/1.1 404 ", "not found"},
    {"post", "POST /index.html HTTP/1.1\r\nHost: x\r\nContent-Length: 0\r\n\r\n", "HTTP/1.1 405 ", "Allow: GET, HEAD"},
    {"garbage", "\x16\x03\x01\x02\x01\x01\x01\x01\xfc\x03\x03\r\n\r\n", "HTTP/1.1 400 ", "malformed"},
    {"http2", "GET / HTTP/2.0\r\nHost: x\r\n\r\n", "HTTP/1.1 505 ", "HTTP/1.1"},
};

static void test_web_files(void **state)
{
    (void)state;
    daemon_proc d;
    web_start(&d, NULL);
    char out[8192];
    for (size_t i = 0; i < sizeof files / sizeof files[0]; i++) {
        http_get(files[i].req, out, sizeof out);
        if (strncmp(out, files[i].status, strlen(files[i].status)) || !strstr(out, files[i].has))
            fail_msg("%s: wanted '%s' with '%s', got:\n%s", files[i].name, files[i].status, files[i].has, out);
    }
    http_get("HEAD / HTTP/1.1\r\nHost: x\r\n\r\n", out, sizeof out);
    assert_null(strstr(out, "<title>")); /* HEAD: no body */
    web_stop(&d);
}

/* ---- the upgrade ---------------------------------------------------------------------------- */

/* RFC 6455 1.3's example key and its accept value (from the RFC, not
 * computed here). */
#define RFC_KEY "dGhlIHNhbXBsZSBub25jZQ=="
#define RFC_ACCEPT "s3pPLMBiTxaQ9kYGzzhZRbK+xOo="

static int ws_open_with(const char *extra_headers, char *answer, size_t cap)
{
    int fd = web_connect();
    char req[1024];
    int n = snprintf(req, sizeof req,
                     "GET /ws HTTP/1.1\r\nHost: 127.0.0.1:%d\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                     "Sec-WebSocket-Key: " RFC_KEY "\r\nSec-WebSocket-Version: 13\r\n%s\r\n",
                     web_port, extra_headers);
    send_all(fd, req, (size_t)n);
    /* the answer's head, byte by byte (WebSocket frames follow it) */
    size_t have = 0;
    while (have < cap - 1 && (have < 4 || memcmp(answer + have - 4, "\r\n\r\n", 4))) {
        ssize_t r = read(fd, answer + have, 1);
        if (r <= 0) break;
        have++;
    }
    answer[have] = 0;
    return fd;
}

/* An open WebSocket (asserts the 101 and the accept value). */
static int ws_open(void)
{
    char ans[1024], origin[128];
    snprintf(origin, sizeof origin, "Origin: http://127.0.0.1:%d\r\n", web_port);
    int fd = ws_open_with(origin, ans, sizeof ans);
    if (strncmp(ans, "HTTP/1.1 101 ", 13)) fail_msg("no upgrade: %s", ans);
    return fd;
}

static void test_web_upgrade(void **state)
{
    (void)state;
    daemon_proc d;
    web_start(&d, NULL);
    char ans[1024], origin[128];
    snprintf(origin, sizeof origin, "Origin: http://127.0.0.1:%d\r\n", web_port);
    int fd = ws_open_with(origin, ans, sizeof ans);
    if (strncmp(ans, "HTTP/1.1 101 ", 13) || !strstr(ans, "Sec-WebSocket-Accept: " RFC_ACCEPT "\r\n"))
        fail_msg("no upgrade: %s", ans);
    close(fd);
    fd = ws_open_with("", ans, sizeof ans); /* a script: no Origin */
    assert_int_equal(strncmp(ans, "HTTP/1.1 101 ", 13), 0);
    close(fd);
    web_stop(&d);
}

typedef struct up_row {
    const char *name, *req, *status, *has;
} up_row;

#define UP_HEAD "Host: 127.0.0.1\r\nSec-WebSocket-Key: " RFC_KEY "\r\n"
static const up_row refusals[] = {
    {"no_upgrade", "GET /ws HTTP/1.1\r\n" UP_HEAD "Sec-WebSocket-Version: 13\r\n\r\n", "HTTP/1.1 426 ",
     "Upgrade: websocket"},
    {"version_8",
     "GET /ws HTTP/1.1\r\n" UP_HEAD "Upgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Version: 8\r\n\r\n",
     "HTTP/1.1 426 ", "Sec-WebSocket-Version: 13"},
    {"short_key",
     "GET /ws HTTP/1.1\r\nHost: h\r\nUpgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Key: abc==\r\n"
     "Sec-WebSocket-Version: 13\r\n\r\n",
     "HTTP/1.1 400 ", "16 bytes"},
    {"no_key", "GET /ws HTTP/1.1\r\nHost: h\r\nUpgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Version: 13\r\n\r\n",
     "HTTP/1.1 400 ", "16 bytes"},
    /* cross-site WebSocket hijacking: a page elsewhere may not drive the daemon */
    {"other_origin",
     "GET /ws HTTP/1.1\r\n" UP_HEAD "Upgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Version: 13\r\n"
     "Origin: https://evil.example\r\n\r\n",
     "HTTP/1.1 403 ", "another origin"},
    {"origin_other_port",
     "GET /ws HTTP/1.1\r\nHost: 127.0.0.1:1\r\nSec-WebSocket-Key: " RFC_KEY "\r\nUpgrade: websocket\r\n"
     "Connection: Upgrade\r\nSec-WebSocket-Version: 13\r\nOrigin: http://127.0.0.1:2\r\n\r\n",
     "HTTP/1.1 403 ", "another origin"},
    {"post", "POST /ws HTTP/1.1\r\n" UP_HEAD "Upgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Version: 13\r\n\r\n",
     "HTTP/1.1 405 ", "GET"},
};

static void test_web_upgrade_refused(void **state)
{
    (void)state;
    daemon_proc d;
    web_start(&d, NULL);
    char out[4096];
    for (size_t i = 0; i < sizeof refusals / sizeof refusals[0]; i++) {
        http_get(refusals[i].req, out, sizeof out);
        if (strncmp(out, refusals[i].status, strlen(refusals[i].status)) || !strstr(out, refusals[i].has))
            fail_msg("%s: wanted '%s' with '%s', got:\n%s", refusals[i].name, refusals[i].status, refusals[i].has, out);
    }
    web_stop(&d);
}

/* ---- frames of RFC 6455, this side's ------------------------------------------------------ */

/* A client frame: FIN as fin, opcode op, masked (unless !mask) with a
 * fixed key, rsv bits as given. */
static size_t ws_build_frame(uint8_t *f, int op, const void *p, size_t n, bool fin, bool mask, int rsv)
{
    size_t h = 0;
    f[h++] = (uint8_t)((fin ? 0x80 : 0) | (rsv << 4) | op);
    uint8_t mb = mask ? 0x80 : 0;
    if (n < 126) {
        f[h++] = (uint8_t)(mb | n);
    } else if (n < 65536) {
        f[h++] = mb | 126;
        f[h++] = (uint8_t)(n >> 8);
        f[h++] = (uint8_t)n;
    } else {
        f[h++] = mb | 127;
        for (int i = 7; i >= 0; i--) f[h++] = (uint8_t)((uint64_t)n >> (8 * i));
    }
    static const uint8_t key[4] = {0x37, 0xfa, 0x21, 0x3d};
    if (mask) memcpy(f + h, key, 4), h += 4;
    for (size_t i = 0; i < n; i++) f[h + i] = ((const uint8_t *)p)[i] ^ (mask ? key[i & 3] : 0);
    return h + n;
}

static void ws_send_frame(int fd, int op, const void *p, size_t n, bool fin, bool mask, int rsv)
{
    uint8_t *f = malloc(n + 14);
    send_all(fd, f, ws_build_frame(f, op, p, n, fin, mask, rsv));
    free(f);
}

static void ws_send(int fd, const void *p, size_t n)
{
    ws_send_frame(fd, 2, p, n, true, true, 0);
}

static bool read_n(int fd, uint8_t *p, size_t n)
{
    for (size_t got = 0; got < n;) {
        ssize_t r = read(fd, p + got, n - got);
        if (r <= 0) return false;
        got += (size_t)r;
    }
    return true;
}

/* The next server frame: its opcode (-1 at the end of the stream), its
 * payload in *p (malloc'ed, the caller frees), its length in *n. A server
 * frame must not be masked (RFC 6455 5.1): asserted. */
static int ws_recv(int fd, uint8_t **p, size_t *n)
{
    uint8_t h[10];
    *p = NULL;
    *n = 0;
    if (!read_n(fd, h, 2)) return -1;
    assert_int_equal(h[1] & 0x80, 0);
    uint64_t len = h[1] & 127;
    if (len == 126) {
        if (!read_n(fd, h + 2, 2)) return -1;
        len = (uint64_t)h[2] << 8 | h[3];
    } else if (len == 127) {
        if (!read_n(fd, h + 2, 8)) return -1;
        len = 0;
        for (int i = 0; i < 8; i++) len = len << 8 | h[2 + i];
    }
    assert_true(len < (64u << 20));
    *p = malloc(len + 1);
    if (!read_n(fd, *p, (size_t)len)) {
        free(*p);
        *p = NULL;
        return -1;
    }
    *n = (size_t)len;
    return h[0] & 15;
}

/* Reads to the close: its status code (1005, RFC 6455 7.1.5: a close
 * with none; -1: the stream ended without a close). */
static int ws_close_code(int fd)
{
    for (;;) {
        uint8_t *p;
        size_t n;
        int op = ws_recv(fd, &p, &n);
        int code = op == 8 ? (n >= 2 ? p[0] << 8 | p[1] : 1005) : -1;
        free(p);
        if (op == 8 || op < 0) return code;
    }
}

/* The protocol's bytes over the WebSocket: a stream, whatever the messages. */
typedef struct pstream {
    uint8_t *b;
    size_t n;
} pstream;

/* One WebSocket message: a binary one's bytes appended to s. Its opcode
 * (-1: none, the read timed out or failed). */
static int pstream_fill(int fd, pstream *s)
{
    uint8_t *p;
    size_t n;
    int op = ws_recv(fd, &p, &n);
    if (op == 2) {
        s->b = realloc(s->b, s->n + n);
        memcpy(s->b + s->n, p, n);
        s->n += n;
    }
    free(p);
    return op;
}

/* The first whole protocol frame in s: its header in *h, its payload at
 * s->b + VP_HEADER_SIZE, and its size in *fs (pstream_drop's), or false. */
static bool pstream_peek(const pstream *s, vp_header *h, size_t *fs)
{
    return s->n >= VP_HEADER_SIZE && vp_frame_check(s->b, s->n, 64u << 20, h, fs) == VP_OK;
}

static void pstream_drop(pstream *s, size_t fs)
{
    memmove(s->b, s->b + fs, s->n - fs);
    s->n -= fs;
}

/* The next protocol frame from the WebSocket's binary messages: its type
 * (or -1), its payload copied to pl (at most cap bytes) with *len. */
static int proto_next(int fd, pstream *s, uint8_t *pl, size_t cap, uint32_t *len)
{
    for (;;) {
        vp_header h;
        size_t fs;
        if (pstream_peek(s, &h, &fs)) {
            size_t k = h.len < cap ? h.len : cap;
            if (pl) memcpy(pl, s->b + VP_HEADER_SIZE, k);
            if (len) *len = h.len;
            pstream_drop(s, fs);
            return h.type;
        }
        int op = pstream_fill(fd, s);
        if (op < 0 || op == 8) return -1;
    }
}

static size_t enc_hello(uint8_t *buf, size_t cap, int role, const char *token)
{
    vp_writer w;
    vp_writer_init(&w, buf, cap);
    vp_hello h = {.magic = VP_MAGIC, .version = VP_VERSION, .role = (uint8_t)role,
                  .token_len = (uint8_t)(token ? strlen(token) : 0), .token = (const uint8_t *)token,
                  .name_len = 4, .name = (const uint8_t *)"test"};
    vp_enc_hello(&w, 1, &h);
    return w.len;
}

/* ---- the protocol over WebSocket ---------------------------------------------------------- */

/* HELLO cut into three messages at odd places, then two PINGs in one
 * message: the replies as over TCP (the messages are a byte stream). */
static void test_web_protocol_stream(void **state)
{
    (void)state;
    daemon_proc d;
    web_start(&d, NULL);
    int fd = ws_open();
    uint8_t hb[128], pl[256];
    size_t hn = enc_hello(hb, sizeof hb, VP_ROLE_VIEWER, NULL);
    ws_send(fd, hb, 3);
    ws_send(fd, hb + 3, 9);
    ws_send(fd, hb + 12, hn - 12);
    pstream s = {0};
    uint32_t len;
    assert_int_equal(proto_next(fd, &s, pl, sizeof pl, &len), VP_HELLO_OK);
    vp_hello_ok ok;
    assert_int_equal(vp_dec_hello_ok(pl, len, &ok), VP_OK);
    assert_int_equal(ok.role, VP_ROLE_VIEWER);
    uint8_t two[2 * VP_HEADER_SIZE];
    vp_writer w;
    vp_writer_init(&w, two, sizeof two);
    vp_enc_empty(&w, VP_PING, 7);
    vp_enc_empty(&w, VP_PING, 8);
    ws_send(fd, two, w.len);
    assert_int_equal(proto_next(fd, &s, NULL, 0, NULL), VP_PONG);
    assert_int_equal(proto_next(fd, &s, NULL, 0, NULL), VP_PONG);
    /* a WebSocket ping is answered with a pong carrying its bytes */
    ws_send_frame(fd, 9, "abc", 3, true, true, 0);
    uint8_t *p;
    size_t n;
    assert_int_equal(ws_recv(fd, &p, &n), 10);
    assert_int_equal(n, 3);
    assert_memory_equal(p, "abc", 3);
    free(p);
    /* a normal close is answered with a close */
    uint8_t bye[2] = {0x03, 0xe8};
    ws_send_frame(fd, 8, bye, 2, true, true, 0);
    assert_int_equal(ws_close_code(fd), 1000);
    close(fd);
    free(s.b);
    web_stop(&d);
}

/* A bad token is refused as over TCP: ERROR AUTH, then a close. */
static void test_web_bad_token(void **state)
{
    (void)state;
    char tok[] = "/tmp/vantage-web-tokens-XXXXXX";
    int tfd = mkstemp(tok);
    const char *lines = "viewer good-viewer-token\neditor good-editor-token\n";
    assert_int_equal(write(tfd, lines, strlen(lines)), (ssize_t)strlen(lines));
    close(tfd);
    daemon_proc d;
    const char *more[] = {"--tokens", tok, NULL};
    web_start(&d, more);
    int fd = ws_open();
    uint8_t hb[128], pl[512];
    ws_send(fd, hb, enc_hello(hb, sizeof hb, VP_ROLE_VIEWER, "wrong-token"));
    pstream s = {0};
    uint32_t len;
    assert_int_equal(proto_next(fd, &s, pl, sizeof pl, &len), VP_ERROR);
    vp_error e;
    assert_int_equal(vp_dec_error(pl, len, &e), VP_OK);
    assert_int_equal(e.code, VP_ERR_AUTH);
    assert_int_equal(ws_close_code(fd), 1008);
    close(fd);
    fd = ws_open();
    ws_send(fd, hb, enc_hello(hb, sizeof hb, VP_ROLE_VIEWER, "good-viewer-token"));
    assert_int_equal(proto_next(fd, &s, pl, sizeof pl, &len), VP_HELLO_OK);
    close(fd);
    free(s.b);
    web_stop(&d);
    unlink(tok);
}

/* ---- bad frames --------------------------------------------------------------------------- */

typedef struct frame_row {
    const char *name;
    int op;
    const char *payload;
    size_t n;
    bool fin, mask;
    int rsv;
    int code; /* the close code the daemon must answer with */
} frame_row;

static const frame_row bad_frames[] = {
    /* RFC 6455 5.1: a client's frames are masked; the server closes (1002) */
    {"unmasked", 2, "abcd", 4, true, false, 0, 1002},
    {"reserved_bit", 2, "abcd", 4, true, true, 4, 1002},
    {"reserved_opcode", 3, "abcd", 4, true, true, 0, 1002},
    /* refused by wslay's frame parser itself: a close without a code */
    {"fragmented_ping", 9, "ab", 2, false, true, 0, 1005},
    {"continuation_first", 0, "ab", 2, true, true, 0, 1002},
    {"bad_utf8_text", 1, "a\xc3\x28z", 4, true, true, 0, 1007},
    {"overlong_utf8", 1, "\xc0\xaf", 2, true, true, 0, 1007},
    {"surrogate_utf8", 1, "\xed\xa0\x80", 3, true, true, 0, 1007},
    {"text_not_binary", 1, "{\"hello\":1}", 11, true, true, 0, 1003},
};

static void test_web_bad_frames(void **state)
{
    (void)state;
    daemon_proc d;
    web_start(&d, NULL);
    /* a good client beside the bad ones is served throughout */
    int good = ws_open();
    uint8_t hb[128];
    ws_send(good, hb, enc_hello(hb, sizeof hb, VP_ROLE_VIEWER, NULL));
    pstream s = {0};
    assert_int_equal(proto_next(good, &s, NULL, 0, NULL), VP_HELLO_OK);
    for (size_t i = 0; i < sizeof bad_frames / sizeof bad_frames[0]; i++) {
        const frame_row *r = &bad_frames[i];
        int fd = ws_open();
        ws_send_frame(fd, r->op, r->payload, r->n, r->fin, r->mask, r->rsv);
        int code = ws_close_code(fd);
        if (code != r->code) fail_msg("%s: close %d, wanted %d", r->name, code, r->code);
        close(fd);
        uint8_t ping[VP_HEADER_SIZE];
        vp_writer w;
        vp_writer_init(&w, ping, sizeof ping);
        vp_enc_empty(&w, VP_PING, (uint32_t)i);
        ws_send(good, ping, w.len);
        assert_int_equal(proto_next(good, &s, NULL, 0, NULL), VP_PONG);
    }
    close(good);
    free(s.b);
    web_stop(&d);
}

/* A message over --max-payload + a header is closed with 1009 (too big)
 * before the daemon holds it; one under it reaches the protocol, which
 * refuses an oversized frame with ERROR TOO_LARGE as over TCP. */
static void test_web_oversized(void **state)
{
    (void)state;
    daemon_proc d;
    const char *more[] = {"--max-payload", "65536", NULL};
    web_start(&d, more);
    int fd = ws_open();
    size_t big = 65536 + VP_HEADER_SIZE + 1;
    uint8_t *junk = calloc(1, big);
    ws_send(fd, junk, big);
    assert_int_equal(ws_close_code(fd), 1009);
    close(fd);
    fd = ws_open();
    uint8_t hb[128], pl[512];
    ws_send(fd, hb, enc_hello(hb, sizeof hb, VP_ROLE_EDITOR, NULL));
    pstream s = {0};
    assert_int_equal(proto_next(fd, &s, NULL, 0, NULL), VP_HELLO_OK);
    /* a frame header claiming 1 MiB (len, type, flags, req; little-endian) */
    uint8_t fh[VP_HEADER_SIZE] = {0, 0, 0x10, 0, (uint8_t)VP_ENTITY_ADD, (uint8_t)(VP_ENTITY_ADD >> 8), 0, 0, 5, 0, 0, 0};
    ws_send(fd, fh, sizeof fh);
    uint32_t len;
    assert_int_equal(proto_next(fd, &s, pl, sizeof pl, &len), VP_ERROR);
    vp_error e;
    assert_int_equal(vp_dec_error(pl, len, &e), VP_OK);
    assert_int_equal(e.code, VP_ERR_TOO_LARGE);
    assert_int_equal(ws_close_code(fd), 1008);
    close(fd);
    free(junk);
    free(s.b);
    web_stop(&d);
}

/* A client that floods pings and never reads is dropped (its pongs pile
 * up); another client is served meanwhile. */
static void test_web_ping_flood(void **state)
{
    (void)state;
    daemon_proc d;
    web_start(&d, NULL);
    /* (its receive buffer as the kernel sizes it: a tiny one made loopback
       drop segments, and the test then measured TCP's retransmit backoff) */
    int flood = ws_open();
    uint8_t payload[125];
    memset(payload, 'p', sizeof payload);
    int fl = fcntl(flood, F_GETFL);
    fcntl(flood, F_SETFL, fl | O_NONBLOCK);
    bool dropped = false;
    uint8_t f[6 + 125] = {0x89, 0x80 | 125, 0, 0, 0, 0};
    memcpy(f + 6, payload, 125);
    size_t at = 0; /* of the ping being sent: a non-blocking send may take part of it */
    for (int i = 0; i < 400000 && !dropped;) {
        ssize_t n = send(flood, f + at, sizeof f - at, MSG_NOSIGNAL);
        if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
            struct pollfd p = {.fd = flood, .events = POLLOUT};
            if (poll(&p, 1, 2000) <= 0) break;
            continue;
        }
        dropped = n < 0; /* EPIPE / ECONNRESET: the daemon hung up */
        if (n > 0 && (at += (size_t)n) == sizeof f) at = 0, i++;
    }
    assert_true(dropped);
    close(flood);
    int fd = ws_open();
    uint8_t hb[128];
    ws_send(fd, hb, enc_hello(hb, sizeof hb, VP_ROLE_VIEWER, NULL));
    pstream s = {0};
    assert_int_equal(proto_next(fd, &s, NULL, 0, NULL), VP_HELLO_OK);
    close(fd);
    free(s.b);
    web_stop(&d);
}

/* Slow-loris on the web port: a head not sent within --hello-timeout gets 408. */
static void test_web_slowloris(void **state)
{
    (void)state;
    daemon_proc d;
    const char *more[] = {"--hello-timeout", "300", NULL};
    web_start(&d, more);
    int fd = web_connect();
    send_all(fd, "GET / HTTP/1.1\r\nHo", 18);
    char out[1024];
    size_t have = 0;
    ssize_t n;
    while ((n = read(fd, out + have, sizeof out - 1 - have)) > 0) have += (size_t)n;
    out[have] = 0;
    assert_int_equal(strncmp(out, "HTTP/1.1 408 ", 13), 0);
    close(fd);
    web_stop(&d);
}

/* ---- frames to many viewers ---------------------------------------------------------------- */

/* 50 WebSocket viewers at once, each with a stream of small JPEG frames:
 * every one gets frames, and the daemon's memory stays bounded. */
static void test_web_many_viewers(void **state)
{
    (void)state;
    daemon_proc d;
    web_start(&d, NULL);
    enum { N = 50 };
    int fds[N];
    pstream s[N];
    memset(s, 0, sizeof s);
    for (int i = 0; i < N; i++) {
        fds[i] = ws_open();
        uint8_t buf[1024];
        size_t hn = enc_hello(buf, sizeof buf, VP_ROLE_VIEWER, NULL);
        vp_frame_sub sub = {.r = {.format = VP_FRAME_JPEG, .quality = 60}, .max_fps = 30, .view_seq = (uint16_t)i};
        double eye[3] = {0.1 * i, 2, -10}, at[3] = {0, 0, 0};
        assert_true(vtc_view_perspective(&sub.r.view, eye, at, NULL, 60, 96, 64, 0.1, 100));
        vp_writer w;
        vp_writer_init(&w, buf + hn, sizeof buf - hn);
        vp_enc_frame_sub(&w, 2, &sub);
        ws_send(fds[i], buf, hn + w.len); /* HELLO and the subscription in one message */
    }
    for (int i = 0; i < N; i++) {
        uint8_t pl[64];
        uint32_t len;
        int t;
        while ((t = proto_next(fds[i], &s[i], pl, sizeof pl, &len)) == VP_HELLO_OK || t == VP_ACK) {
        }
        if (t != VP_FRAME) fail_msg("viewer %d: message %d, no frame", i, t);
        vp_frame f;
        assert_int_equal(vp_dec_frame(pl, len, &f), VP_OK);
        assert_int_equal(f.view_seq, i);
        assert_int_equal(f.width, 96);
    }
    char path[64], line[256];
    snprintf(path, sizeof path, "/proc/%d/status", (int)d.pid);
    FILE *st = fopen(path, "r");
    long rss_kb = 0;
    while (st && fgets(line, sizeof line, st))
        if (!strncmp(line, "VmRSS:", 6)) rss_kb = strtol(line + 6, NULL, 10);
    if (st) fclose(st);
    print_message("50 WebSocket viewers of 96x64 JPEG frames: daemon RSS %ld KiB\n", rss_kb);
    /* bound: the empty scene's daemon is ~40 MB (renderers' tables, two
       workers); 50 viewers' buffers (64 KiB input, 16 KiB output tail,
       wslay's context) add ~5 MB. 256 MB says "bounded", not a tuning */
    assert_true(rss_kb > 0 && rss_kb < 256 * 1024);
    for (int i = 0; i < N; i++) {
        close(fds[i]);
        free(s[i].b);
    }
    web_stop(&d);
}

/* Frames for one WebSocket viewer re-aimed every 10 ms for ms
 * milliseconds (its own frames read as they come): how many arrived. */
static int frames_while_aiming(int fd, pstream *s, int ms, uint16_t *seq, vtc_client *ed)
{
    struct timeval tv = {.tv_usec = 20000};
    setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    int frames = 0;
    struct timespec a, b;
    clock_gettime(CLOCK_MONOTONIC, &a);
    for (;;) {
        clock_gettime(CLOCK_MONOTONIC, &b);
        if ((b.tv_sec - a.tv_sec) * 1000 + (b.tv_nsec - a.tv_nsec) / 1000000 > ms) break;
        vp_frame_sub sub = {.r = {.format = VP_FRAME_JPEG, .quality = 50}, .max_fps = 240, .view_seq = ++*seq};
        double eye[3] = {10 * sin(*seq * 0.05), 3, 10 * cos(*seq * 0.05)}, at[3] = {0, 0, 0};
        assert_true(vtc_view_perspective(&sub.r.view, eye, at, NULL, 60, 160, 90, 0.1, 100));
        uint8_t buf[512];
        vp_writer w;
        vp_writer_init(&w, buf, sizeof buf);
        vp_enc_frame_sub(&w, 2, &sub);
        ws_send(fd, buf, w.len);
        /* an edit every turn: every stream has a new scene to show */
        vp_entity e = {.id = 1, .sphere = {sin(*seq * 0.1), 1, 0, 1}, .flags = VP_ENT_DYNAMIC};
        assert_int_equal(vtc_update(ed, &e, 1, NULL), VP_OK);
        /* what came meanwhile: frames counted (a read times out after 20 ms) */
        if (pstream_fill(fd, s) == 2) {
            vp_header h;
            size_t fs;
            while (pstream_peek(s, &h, &fs)) {
                frames += h.type == VP_FRAME;
                pstream_drop(s, fs);
            }
        }
        usleep(10000);
    }
    tv = (struct timeval){.tv_sec = 10};
    setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    return frames;
}

/* A WebSocket viewer that stops reading does not slow another: the other's
 * frames in a second, re-aimed all along, before and while a stalled
 * viewer (its receive buffer small and full) is subscribed at 240 fps, the
 * scene edited all the while (every stream has a new frame due).
 * Latest-frame-wins: the stalled one's next frame waits for its last to
 * leave, so it costs no renders. */
static void test_web_stalled_viewer(void **state)
{
    (void)state;
    daemon_proc d;
    web_start(&d, NULL);
    int live = ws_open();
    uint8_t hb[128];
    ws_send(live, hb, enc_hello(hb, sizeof hb, VP_ROLE_VIEWER, NULL));
    pstream s = {0};
    assert_int_equal(proto_next(live, &s, NULL, 0, NULL), VP_HELLO_OK);
    uint16_t seq = 0;
    vtc_client *ed = connect_role(&d, VP_ROLE_EDITOR, false);
    vp_entity e = {.id = 1, .sphere = {0, 1, 0, 1}, .flags = VP_ENT_DYNAMIC};
    assert_int_equal(vtc_add(ed, &e, 1, NULL, NULL), VP_OK);
    int before = frames_while_aiming(live, &s, 1000, &seq, ed);
    int stalled = ws_open();
    int small = 4096;
    setsockopt(stalled, SOL_SOCKET, SO_RCVBUF, &small, sizeof small);
    uint8_t buf[1024];
    size_t hn = enc_hello(buf, sizeof buf, VP_ROLE_VIEWER, NULL);
    vp_frame_sub sub = {.r = {.format = VP_FRAME_JPEG, .quality = 95}, .max_fps = 240};
    double eye[3] = {3, 3, 3}, at[3] = {0, 0, 0};
    assert_true(vtc_view_perspective(&sub.r.view, eye, at, NULL, 60, 640, 360, 0.1, 100));
    vp_writer w;
    vp_writer_init(&w, buf + hn, sizeof buf - hn);
    vp_enc_frame_sub(&w, 2, &sub);
    ws_send(stalled, buf, hn + w.len); /* and never reads again */
    int during = frames_while_aiming(live, &s, 1000, &seq, ed);
    vtc_close(ed);
    print_message("a viewer re-aimed every 10 ms: %d frames in 1 s alone, %d beside a stalled viewer\n", before,
                  during);
    /* not a timing bound: "not slowed" is at least half its frames; a
       stalled viewer that held the loop or a worker would leave it none */
    assert_true(before > 10);
    assert_true(during * 2 >= before);
    close(stalled);
    close(live);
    free(s.b);
    web_stop(&d);
}

/* ---- H.264 frames ----------------------------------------------------------------------------- */

/* A frame stream of H.264 (what a browser with WebCodecs asks for) decoded
 * by libavcodec (the tests' independent decoder, tests/h264_ref.c), frame
 * after frame in one decoder as a browser does: the first frame is a key
 * frame with SPS and PPS; a re-aim of the same size continues the chain
 * (delta frames that decode after it); a new size, and a new
 * subscription, start with a key frame; the pictures are the daemon's
 * JPEG of the same view within what the two codecs lose; --max-video
 * refuses one stream too many (LIMIT), which the page answers with JPEG. */
static void test_web_h264_stream(void **state)
{
    (void)state;
    daemon_proc d;
    const char *more[] = {"--max-video", "1", NULL};
    web_start(&d, more);
    vtc_client *ed = connect_role(&d, VP_ROLE_EDITOR, false);
    vp_entity es[3] = {{.id = 1, .sphere = {0, 1, 0, 1}}, {.id = 2, .sphere = {3, 2, -2, 2}}, {.id = 3, .sphere = {-3, 1, 1, 1}}};
    assert_int_equal(vtc_add(ed, es, 3, NULL, NULL), VP_OK);
    vtc_client *v = connect_role(&d, VP_ROLE_VIEWER, false);
    h264_dec dec = {0};
    assert_int_equal(h264_dec_open(&dec), 0);
    enum { W = 160, H = 90 };
    vp_frame_sub sub = {.r = {.format = VP_FRAME_H264}, .max_fps = 60};
    double eye[3] = {8, 5, 10}, at[3] = {0, 1, 0};
    static uint8_t rgb[W * H * 3];
    for (int step = 0; step < 6; step++) {
        uint32_t w = step == 3 ? 96 : W, h = step == 3 ? 64 : H; /* step 3: another size */
        if (step == 4) assert_int_equal(vtc_frame_unsubscribe(v), VP_OK); /* step 4: a new subscription */
        eye[0] = 8 + 0.3 * step;
        assert_true(vtc_view_perspective(&sub.r.view, eye, at, NULL, 60, w, h, 0.1, 100));
        sub.view_seq = (uint16_t)step;
        assert_int_equal(vtc_frame_subscribe(v, &sub), VP_OK);
        vp_frame f;
        do assert_int_equal(vtc_wait_frame(v, &f, 10000), VP_OK);
        while (f.view_seq != step);
        assert_int_equal(f.format, VP_FRAME_H264);
        bool want_key = step == 0 || step == 3 || step == 4 || step == 5;
        if (f.key != want_key) fail_msg("step %d: key %d, wanted %d", step, f.key, want_key);
        int types[32], nt = h264_ref_nal_types(f.data, f.data_len, types, 32);
        bool idr = false, sps = false;
        for (int i = 0; i < nt; i++) idr |= types[i] == 5, sps |= types[i] == 7;
        assert_int_equal(idr, f.key);
        assert_int_equal(sps, f.key);
        if (step == 3) { /* a new size: a new decoder, as the page's reset */
            h264_dec_close(&dec);
            assert_int_equal(h264_dec_open(&dec), 0);
        }
        if (h264_dec_au(&dec, f.data, f.data_len)) fail_msg("step %d: libavcodec refused the frame", step);
        if (step == 5) break;
        if (step == 4) { /* step 5: the size of step 3 again, but of a stream that ended: a key */
            assert_int_equal(vtc_frame_unsubscribe(v), VP_OK);
            continue;
        }
        if (w != W) continue;
        /* against the daemon's JPEG (q95) of the same view */
        h264_ref_frame_rgb(dec.f, (int)w, (int)h, rgb);
        vp_render jr = {.view = sub.r.view, .format = VP_FRAME_JPEG, .quality = 95};
        vp_frame jf;
        vtc_client *v2 = connect_role(&d, VP_ROLE_VIEWER, false);
        assert_int_equal(vtc_render(v2, &jr, &jf), VP_OK);
        uint8_t *jpx = NULL;
        uint32_t jw, jh;
        char err[256];
        assert_int_equal(vt_jpeg_decode(jf.data, jf.data_len, &jpx, &jw, &jh, err, sizeof err), 0);
        double psnr = h264_ref_psnr(rgb, jpx, (size_t)w * 3, 3, w, h);
        print_message("H.264 frame %d (%s, %u bytes) against the JPEG q95 of its view: %.1f dB\n", step,
                      f.key ? "key" : "delta", f.data_len, psnr);
        /* CRF 23 and q95 of a small render: each ~40+ dB from the source;
           30 dB says the same picture, a wrong view or colour falls to ~15 */
        assert_true(psnr > 30);
        free(jpx);
        vtc_close(v2);
    }
    /* one H.264 stream at most here: a second is refused, JPEG is not */
    vtc_client *v3 = connect_role(&d, VP_ROLE_VIEWER, false);
    assert_int_equal(vtc_frame_subscribe(v, &sub), VP_OK);
    assert_int_equal(vtc_frame_subscribe(v3, &sub), VP_ERR_LIMIT);
    assert_non_null(strstr(vtc_last_error(v3)->msg, "--max-video"));
    sub.r.format = VP_FRAME_JPEG;
    sub.r.quality = 80;
    assert_int_equal(vtc_frame_subscribe(v3, &sub), VP_OK);
    assert_int_equal(vtc_frame_unsubscribe(v), VP_OK);
    sub.r.format = VP_FRAME_H264;
    sub.r.quality = 0;
    assert_int_equal(vtc_frame_subscribe(v3, &sub), VP_OK); /* the slot is free again */
    /* a RENDER in H.264 is one key frame */
    vp_render one = {.view = sub.r.view, .format = VP_FRAME_H264, .quality = 30};
    vp_frame kf;
    assert_int_equal(vtc_render(v, &one, &kf), VP_OK);
    assert_int_equal(kf.key, 1);
    h264_dec_close(&dec);
    vtc_close(v3);
    vtc_close(v);
    vtc_close(ed);
    web_stop(&d);
}

/* The frames that came within ms: each H.264 FRAME fed to dec in order
 * (libavcodec must take every one: the chain has no gap); the last one's
 * view_seq and key flag out. The count. */
static int motion_drain(int fd, pstream *s, int ms, h264_dec *dec, uint16_t *last_seq, int *keys)
{
    struct timeval tv = {.tv_usec = 2000};
    setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    int frames = 0;
    struct timespec a, b;
    clock_gettime(CLOCK_MONOTONIC, &a);
    do {
        if (pstream_fill(fd, s) == 2) {
            vp_header h;
            size_t fs;
            while (pstream_peek(s, &h, &fs)) {
                if (h.type == VP_FRAME) {
                    vp_frame f;
                    assert_int_equal(vp_dec_frame(s->b + VP_HEADER_SIZE, h.len, &f), VP_OK);
                    assert_int_equal(f.format, VP_FRAME_H264);
                    if (h264_dec_au(dec, f.data, f.data_len))
                        fail_msg("frame %d (view %u, %s): libavcodec refused it: a gap in the chain", frames,
                                 f.view_seq, f.key ? "key" : "delta");
                    *last_seq = f.view_seq;
                    *keys += f.key;
                    frames++;
                } else {
                    assert_int_equal(h.type, VP_ACK); /* the re-aims' */
                }
                pstream_drop(s, fs);
            }
        }
        clock_gettime(CLOCK_MONOTONIC, &b);
    } while ((b.tv_sec - a.tv_sec) * 1000 + (b.tv_nsec - a.tv_nsec) / 1000000 < ms);
    tv = (struct timeval){.tv_sec = 10};
    setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    return frames;
}

/* Dynamic resolution on an H.264 stream, as a page drives it: bursts of
 * re-aims (frames drawn smaller, scaled up), rests of 90..160 ms (the
 * full-size frame starts at 100 ms, and the next burst may stop it half
 * drawn). Whatever was drawn, stopped or sent, libavcodec decodes every
 * frame in one decoder (a stopped frame was never encoded: the chain has
 * no gap, and no key frame is needed after it), and after the last rest
 * the picture is the daemon's JPEG of the last view. */
static void test_web_motion_h264_chain(void **state)
{
    (void)state;
    daemon_proc d;
    const char *more[] = {"--motion-ms", "1", NULL};
    web_start(&d, more);
    vtc_client *ed = connect_role(&d, VP_ROLE_EDITOR, false);
    vp_entity es[80];
    for (int i = 0; i < 80; i++) {
        double x = -20 + (i % 20) * 2, z = -6 - (i / 20) * 4;
        es[i] = (vp_entity){.id = (uint64_t)i + 1, .aabb = {x - 0.6, 0, z - 0.6, x + 0.6, 1 + i % 4, z + 0.6}};
    }
    assert_int_equal(vtc_add(ed, es, 80, NULL, NULL), VP_OK);
    vp_env env;
    assert_int_equal(vtc_env_get(ed, &env), VP_OK);
    env.exposure_mode = VP_EXPOSURE_FIXED; /* no eye adaptation: the last frame is RENDER's picture */
    assert_int_equal(vtc_env_set(ed, &env, NULL), VP_OK);
    int fd = ws_open();
    uint8_t hb[128];
    ws_send(fd, hb, enc_hello(hb, sizeof hb, VP_ROLE_VIEWER, NULL));
    pstream s = {0};
    assert_int_equal(proto_next(fd, &s, NULL, 0, NULL), VP_HELLO_OK);
    h264_dec dec = {0};
    assert_int_equal(h264_dec_open(&dec), 0);
    enum { W = 480, H = 270 };
    vp_frame_sub sub = {.r = {.format = VP_FRAME_H264, .flags = VP_RENDER_MOTION}, .max_fps = 240};
    double eye[3] = {0, 3, 4}, at[3] = {0, 1, -10};
    uint16_t seq = 0, last = UINT16_MAX;
    int frames = 0, keys = 0;
    for (int burst = 0; burst < 8; burst++) {
        for (int k = 0; k < 8; k++, seq++) {
            at[0] = 4 * sin(seq * 0.07);
            sub.r.view = (vp_view){0};
            assert_true(vtc_view_perspective(&sub.r.view, eye, at, NULL, 70, W, H, 0.1, 100));
            sub.view_seq = seq;
            uint8_t buf[512];
            vp_writer w;
            vp_writer_init(&w, buf, sizeof buf);
            vp_enc_frame_sub(&w, 2, &sub);
            ws_send(fd, buf, w.len);
            frames += motion_drain(fd, &s, 10, &dec, &last, &keys);
        }
        frames += motion_drain(fd, &s, 90 + 10 * burst, &dec, &last, &keys);
    }
    frames += motion_drain(fd, &s, 600, &dec, &last, &keys);
    print_message("motion over H.264: %d frames for %u views, %d key frames, every one decoded\n", frames, seq, keys);
    assert_int_equal(last, (uint16_t)(seq - 1));
    assert_int_equal(keys, 1); /* the first only: nothing broke the chain */
    /* the last frame (full size, the view at rest) against the JPEG q95 of its view */
    static uint8_t rgb[W * H * 3];
    h264_ref_frame_rgb(dec.f, W, H, rgb);
    vp_render jr = {.view = sub.r.view, .format = VP_FRAME_JPEG, .quality = 95};
    vp_frame jf;
    assert_int_equal(vtc_render(ed, &jr, &jf), VP_OK);
    uint8_t *jpx = NULL;
    uint32_t jw, jh;
    char err[256];
    assert_int_equal(vt_jpeg_decode(jf.data, jf.data_len, &jpx, &jw, &jh, err, sizeof err), 0);
    double psnr = h264_ref_psnr(rgb, jpx, (size_t)W * 3, 3, W, H);
    print_message("motion over H.264: the resting frame against the JPEG q95 of its view: %.1f dB\n", psnr);
    assert_true(psnr > 30);
    free(jpx);
    h264_dec_close(&dec);
    close(fd);
    free(s.b);
    vtc_close(ed);
    web_stop(&d);
}

/* --web on another address needs --tokens (or --insecure), as --bind does;
 * bad values of the web options are refused before anything starts. */
static void test_web_refuses_open_address(void **state)
{
    (void)state;
    char out[2048], args[128];
    snprintf(args, sizeof args, "--port %d --web 0.0.0.0:%d", free_port(), free_port());
    assert_int_equal(daemon_run_to_exit(args, out, sizeof out), 2);
    assert_non_null(strstr(out, "--web 0.0.0.0"));
    assert_non_null(strstr(out, "--tokens"));
    assert_int_equal(daemon_run_to_exit("--web 70000", out, sizeof out), 2);
    assert_non_null(strstr(out, "bad value for --web"));
    /* the dynamic resolution's budget: 0..1000 ms */
    assert_int_equal(daemon_run_to_exit("--motion-ms 1001", out, sizeof out), 2);
    assert_non_null(strstr(out, "--motion-ms"));
    assert_int_equal(daemon_run_to_exit("--motion-ms -1", out, sizeof out), 2);
    assert_int_equal(daemon_run_to_exit("--motion-ms 12ms", out, sizeof out), 2);
    snprintf(args, sizeof args, "--port %d --web %d --web-root /nonexistent-vantage", free_port(), free_port());
    assert_int_not_equal(daemon_run_to_exit(args, out, sizeof out), 0);
    assert_non_null(strstr(out, "/nonexistent-vantage"));
}

/* ---- TLS ------------------------------------------------------------------------------------- */

/* --web-cert/--web-key: a certificate made by the command docs/WEB.md
 * gives, checked by an OpenSSL client that trusts it (name and chain
 * verified); a page over https and the protocol over wss; plain HTTP to
 * the TLS port gets no answer (the handshake fails), and the plain
 * clients of the same daemon are not disturbed. */
static void test_web_tls(void **state)
{
    (void)state;
    char dir[] = "/tmp/vantage-tls-XXXXXX", cmd[1024], cert[128], key[128];
    assert_non_null(mkdtemp(dir));
    snprintf(cert, sizeof cert, "%s/cert.pem", dir);
    snprintf(key, sizeof key, "%s/key.pem", dir);
    snprintf(cmd, sizeof cmd,
             "openssl req -x509 -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes -days 1 -subj /CN=localhost "
             "-addext subjectAltName=DNS:localhost,IP:127.0.0.1 -keyout %s -out %s 2>/dev/null",
             key, cert);
    assert_int_equal(system(cmd), 0);
    daemon_proc d;
    const char *more[] = {"--web-cert", cert, "--web-key", key, NULL};
    web_start(&d, more);

    SSL_CTX *ctx = SSL_CTX_new(TLS_client_method());
    assert_int_equal(SSL_CTX_load_verify_locations(ctx, cert, NULL), 1);
    SSL_CTX_set_verify(ctx, SSL_VERIFY_PEER, NULL);
    for (int round = 0; round < 2; round++) {
        int fd = web_connect();
        SSL *ssl = SSL_new(ctx);
        SSL_set_fd(ssl, fd);
        SSL_set_tlsext_host_name(ssl, "localhost");
        SSL_set1_host(ssl, "localhost");
        if (SSL_connect(ssl) != 1) fail_msg("TLS handshake: %s", ERR_error_string(ERR_get_error(), NULL));
        assert_int_equal(SSL_get_verify_result(ssl), X509_V_OK);
        char buf[4096];
        int n;
        if (round == 0) { /* a page */
            const char *req = "GET / HTTP/1.1\r\nHost: localhost\r\n\r\n";
            assert_int_equal(SSL_write(ssl, req, (int)strlen(req)), (int)strlen(req));
            size_t have = 0;
            while (have < sizeof buf - 1 && (n = SSL_read(ssl, buf + have, (int)(sizeof buf - 1 - have))) > 0)
                have += (size_t)n;
            buf[have] = 0;
            assert_int_equal(strncmp(buf, "HTTP/1.1 200 ", 13), 0);
            assert_non_null(strstr(buf, "<title>vantage</title>"));
        } else { /* the protocol over wss: upgrade, HELLO, HELLO_OK */
            int rn = snprintf(buf, sizeof buf,
                              "GET /ws HTTP/1.1\r\nHost: localhost:%d\r\nOrigin: https://localhost:%d\r\n"
                              "Upgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Key: " RFC_KEY "\r\n"
                              "Sec-WebSocket-Version: 13\r\n\r\n",
                              web_port, web_port);
            assert_int_equal(SSL_write(ssl, buf, rn), rn);
            uint8_t hb[128], fr[160];
            size_t fn = ws_build_frame(fr, 2, hb, enc_hello(hb, sizeof hb, VP_ROLE_VIEWER, NULL), true, true, 0);
            assert_int_equal(SSL_write(ssl, fr, (int)fn), (int)fn);
            /* the 101's head, then one binary frame: HELLO_OK's 40 bytes */
            size_t have = 0;
            char *end = NULL;
            while (have < sizeof buf - 1 && (n = SSL_read(ssl, buf + have, (int)(sizeof buf - 1 - have))) > 0) {
                have += (size_t)n;
                buf[have] = 0;
                end = strstr(buf, "\r\n\r\n");
                if (end && (size_t)(end + 4 - buf) + 2 + 40 <= have) break;
            }
            assert_non_null(end);
            assert_int_equal(strncmp(buf, "HTTP/1.1 101 ", 13), 0);
            assert_non_null(strstr(buf, "Sec-WebSocket-Accept: " RFC_ACCEPT));
            const uint8_t *f = (const uint8_t *)end + 4;
            assert_int_equal(f[0], 0x82); /* FIN, binary */
            assert_int_equal(f[1], VP_HEADER_SIZE + 28);
            vp_header h;
            size_t fs;
            assert_int_equal(vp_frame_check(f + 2, f[1], 4096, &h, &fs), VP_OK);
            assert_int_equal(h.type, VP_HELLO_OK);
        }
        SSL_free(ssl);
        close(fd);
    }
    SSL_CTX_free(ctx);
    /* plain HTTP to the TLS port: no HTTP answer, the connection ends */
    char out[256];
    size_t got = http_get("GET / HTTP/1.1\r\nHost: x\r\n\r\n", out, sizeof out);
    assert_true(got == 0 || strncmp(out, "HTTP/1.1", 8));
    /* the protocol's own port is as it was */
    vtc_client *c = connect_role(&d, VP_ROLE_VIEWER, false);
    vtc_close(c);
    web_stop(&d);
    /* a key that does not match the certificate, a missing file: the
       daemon does not start, and says which */
    char other[128], args[1024], msg[2048];
    snprintf(other, sizeof other, "%s/other.pem", dir);
    snprintf(cmd, sizeof cmd, "openssl genpkey -algorithm ec -pkeyopt ec_paramgen_curve:prime256v1 -out %s 2>/dev/null",
             other);
    assert_int_equal(system(cmd), 0);
    snprintf(args, sizeof args, "--port %d --web %d --web-root %s --web-cert %s --web-key %s", free_port(), free_port(),
             dir, cert, other);
    assert_int_not_equal(daemon_run_to_exit(args, msg, sizeof msg), 0);
    assert_non_null(strstr(msg, "--web-key")); /* OpenSSL: "key values mismatch" */
    assert_non_null(strstr(msg, "mismatch"));
    snprintf(args, sizeof args, "--port %d --web %d --web-root %s --web-cert %s/none.pem --web-key %s", free_port(),
             free_port(), dir, dir, key);
    assert_int_not_equal(daemon_run_to_exit(args, msg, sizeof msg), 0);
    assert_non_null(strstr(msg, "none.pem"));
    assert_int_equal(daemon_run_to_exit("--web-cert x.pem", msg, sizeof msg), 2);
    assert_non_null(strstr(msg, "go together"));
    unlink(cert);
    unlink(key);
    unlink(other);
    rmdir(dir);
}

const struct CMUnitTest web_tests[] = {
    cmocka_unit_test(test_web_tls),
    cmocka_unit_test(test_web_files),
    cmocka_unit_test(test_web_upgrade),
    cmocka_unit_test(test_web_upgrade_refused),
    cmocka_unit_test(test_web_protocol_stream),
    cmocka_unit_test(test_web_bad_token),
    cmocka_unit_test(test_web_bad_frames),
    cmocka_unit_test(test_web_oversized),
    cmocka_unit_test(test_web_ping_flood),
    cmocka_unit_test(test_web_slowloris),
    cmocka_unit_test(test_web_many_viewers),
    cmocka_unit_test(test_web_stalled_viewer),
    cmocka_unit_test(test_web_h264_stream),
    cmocka_unit_test(test_web_motion_h264_chain),
    cmocka_unit_test(test_web_refuses_open_address),
};
const size_t web_tests_count = sizeof web_tests / sizeof web_tests[0];
