/*
 * metrics_http.c — `vantaged --metrics [ADDR:]PORT`: the metrics (see
 * metrics.h) over HTTP/1.x for Prometheus, served from the daemon's own
 * loop by httpd.c (the connections, their deadlines; the head parsed by
 * http.c, the daemon's one HTTP parser). This file says only what to
 * answer:
 *
 *   GET /metrics (or HEAD)  200, text/plain; version=0.0.4
 *   another path            404
 *   another method          405 (Allow: GET, HEAD)
 *   a head over 8 KiB       431; a malformed one 400; HTTP/2.0 and the like 505
 *   no `Authorization: Bearer TOKEN` where one is needed  401
 *
 * Who may read: whoever the daemon lets view. Without --tokens everyone
 * (vantaged.c then allows only a loopback address, unless --insecure, as
 * for --bind); with --tokens a token that grants the viewer role, unless
 * the token file has no viewer line (public viewing). The exposition is
 * built on the loop (tens of microseconds).
 */
#include "httpd.h"
#include "server_internal.h"

#include <string.h>

static void serve(server *s, hconn *h, const http_req *rq)
{
    bool head_only = rq->head;
    if (s->cfg.tokens && !auth_grants(s->cfg.tokens, VP_ROLE_VIEWER, (const uint8_t *)rq->bearer.p, rq->bearer.n)) {
        httpd_error(h, HS_401, "WWW-Authenticate: Bearer realm=\"vantaged\"\r\n",
                    "this daemon needs a token that grants the viewer role: Authorization: Bearer TOKEN\n",
                    head_only);
        return;
    }
    if (rq->path.n != 8 || memcmp(rq->path.p, "/metrics", 8)) {
        httpd_error(h, HS_404, NULL, "not found: the metrics are at /metrics\n", head_only);
        return;
    }
    if (!head_only && !(rq->method.n == 3 && !memcmp(rq->method.p, "GET", 3))) {
        httpd_error(h, HS_405, "Allow: GET, HEAD\r\n", "only GET and HEAD are allowed\n", false);
        return;
    }
    if (!metrics_expose(s, &s->mtext)) {
        httpd_error(h, HS_500, NULL, "out of memory\n", head_only);
        return;
    }
    httpd_answer(h, HS_200, "text/plain; version=0.0.4; charset=utf-8", NULL, s->mtext.p, s->mtext.len, head_only);
}

static const httpd_ops metrics_ops = {.name = "metrics", .serve = serve};

int metrics_http_open(server *s)
{
    s->http = httpd_open(s, s->cfg.metrics_bind, s->cfg.metrics_port, METRICS_HTTP_MAX_CONNS, &metrics_ops,
                         s->m.http, NULL);
    if (!s->http) return -1;
    LOGI("metrics on http://%s:%d/metrics", s->cfg.metrics_bind, s->cfg.metrics_port);
    return 0;
}
