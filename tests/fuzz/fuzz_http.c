/*
 * fuzz_http.c — libFuzzer target for the daemon's HTTP/1.x head parser
 * (daemon/http.c): what any client of `--metrics` (and of the web viewer
 * to come) can send. The input is the bytes a connection sends, copied to
 * a heap block of exactly their length (ASan sees any read past it).
 * Properties:
 *   1. http_head_end finds the same end whatever follows it: cutting the
 *      input anywhere before the end gives 0, at or past it the same end,
 *      and start <= end;
 *   2. http_parse answers 0, 400 or 505, with a reason ending in a newline
 *      when it refuses;
 *   3. on 0 every span lies inside the head, the path is the target's
 *      start (up to any '?'), the method and target are non-empty, and
 *      HTTP/1.1 came with a Host;
 *   4. parsing is a function of the bytes: twice gives the same result.
 * A broken property calls abort().
 */
#include "http.h"

#define FUZZ_NAME "fuzz_http"
#include "fuzz_check.h"

static bool inside(http_span s, const char *b, size_t start, size_t end)
{
    return !s.p || (s.p >= b + start && s.p + s.n <= b + end);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    char *b = malloc(size ? size : 1);
    CHECK(b != NULL);
    memcpy(b, data, size);
    size_t start, end = http_head_end(b, size, &start);
    CHECK(start <= size && end <= size);
    if (end) {
        CHECK(start < end);
        /* 1: the end does not depend on what comes after it, nor on a cut before it */
        for (size_t cut = end > 64 ? end - 64 : 0; cut <= end; cut++) {
            size_t s2, e2 = http_head_end(b, cut, &s2);
            CHECK(cut < end ? e2 == 0 : e2 == end);
        }
        http_req r, r2;
        const char *why = NULL, *why2 = NULL;
        int st = http_parse(b, start, end, &r, &why);
        CHECK(st == 0 || st == 400 || st == 505);
        CHECK(why != NULL);
        if (st) {
            CHECK(why[0] && why[strlen(why) - 1] == '\n');
        } else {
            const http_span all[] = {r.method, r.target, r.path, r.bearer, r.ws_key, r.ws_version};
            for (size_t i = 0; i < sizeof all / sizeof all[0]; i++) CHECK(inside(all[i], b, start, end));
            CHECK(r.method.n > 0 && r.target.n > 0);
            CHECK(r.path.p == r.target.p && r.path.n <= r.target.n);
            CHECK(r.path.n == r.target.n || r.target.p[r.path.n] == '?');
            CHECK(!r.http11 || r.host);
        }
        /* 4 */
        int st2 = http_parse(b, start, end, &r2, &why2);
        CHECK(st2 == st && why2 == why && !memcmp(&r, &r2, sizeof r));
    }
    free(b);
    return 0;
}
