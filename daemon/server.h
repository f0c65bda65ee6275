/*
 * server.h — vantaged's network side: listeners, connections, framing,
 * dispatch of protocol messages to the scene and the culling core.
 */
#ifndef VANTAGE_SERVER_H
#define VANTAGE_SERVER_H

#include <stdbool.h>
#include <stdint.h>

#include "auth.h"
#include "journal.h"
#include "scene.h"

typedef struct server_config {
    const char *bind;        /* TCP address; NULL or "" = no TCP */
    int port;
    const char *unix_path;   /* NULL or "" = no Unix socket */
    uint32_t max_clients;
    uint32_t max_payload;    /* largest frame payload accepted after HELLO */
    uint32_t max_batch;      /* records per edit message */
    uint32_t out_limit;      /* bytes a client may leave unread before it is dropped */
    uint64_t out_limit_total; /* bytes all clients' output buffers may hold together; past it the
                                client with the largest backlog is dropped first (0: no limit) */
    uint32_t threads;        /* query worker threads, 0 = cores */
    int renderer;            /* VP_RENDERER_SOFT or VP_RENDERER_GL: when a request names none */
    const struct vt_lut3d *lut; /* --lut: JPEG frames' colour grade (vt_lut.h), NULL: none */
    uint32_t fx_off;         /* --fx-off: the frames' effects turned off for all (VT_FX_*) */
    double cell_size;
    uint32_t destruct_res;   /* samples per axis of a destruction volume */
    const auth_tokens *tokens; /* NULL: every role granted (loopback, or --insecure) */
    uint32_t hello_timeout_ms; /* HELLO must complete within this after the accept */
    uint32_t frame_timeout_ms; /* a frame begun must complete within this (slow-loris) */
    scene_limits limits;
    journal *journal;        /* --data-dir: opened (and the scene restored) by the caller; the server closes it */
    struct cluster *cluster; /* --cluster: opened (the scene caught up) by the caller; the server closes it */
    const char *metrics_bind; /* --metrics: the HTTP endpoint's IPv4 address */
    int metrics_port;        /* its port; 0 = no endpoint */
    const char *web_bind;    /* --web: the browser endpoint's IPv4 address */
    int web_port;            /* its port; 0 = none */
    const char *web_root;    /* --web-root: the pages served */
    const char *web_cert, *web_key; /* --web-cert/--web-key: PEM files for TLS; NULL = plain HTTP */
    uint32_t max_video;      /* H.264 frame streams at once (an encoder holds ~15 MB at 720p) */
    uint32_t motion_ms;      /* --motion-ms: a moving stream's render budget a frame (VP_RENDER_MOTION), 0: off */
} server_config;

#define VANTAGED_PREHELLO_MAX 4096u /* frame limit before the handshake */

typedef struct server server;

/* Binds the listeners and builds the scene. NULL (with a log line) on
 * failure. The scene is moved into the server. */
server *server_create(const server_config *cfg, scene *sc);
/* Runs the event loop until server_stop (or SIGINT / SIGTERM): 0; or,
 * logged, -errno when the loop itself failed (epoll_wait): the daemon
 * must end, with a non-zero status. */
int  server_run(server *s);
void server_stop(server *s);
/* Ends the connections, stops the workers, closes the journal. 0, or
 * -errno when the journal's final sync failed (its last edits may be lost). */
int server_destroy(server *s);

#endif
