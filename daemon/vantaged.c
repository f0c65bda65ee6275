/*
 * vantaged.c — the daemon's entry point: options, the scene, the server.
 */
#include "auth.h"
#include "cluster.h"
#include "log.h"
#include "server.h"
#include "ae.h"
#include "vt_image.h"
#include "vt_lut.h"

#include <arpa/inet.h>
#include <errno.h>
#include <getopt.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static void usage(FILE *f)
{
    fprintf(f,
            "usage: vantaged [options]\n"
            "\n"
            "Keeps a live 3D scene and answers visibility queries over the Vantage\n"
            "protocol (protocol/PROTOCOL.md) on TCP and a Unix socket.\n"
            "\n"
            "  --bind ADDR          TCP address (default 127.0.0.1; \"\" for none)\n"
            "  --port N             TCP port (default %d)\n"
            "  --unix PATH          Unix socket (default /tmp/vantaged.sock; \"\" for none)\n"
            "  --scene demo|empty   starting scene (default demo: a procedural city)\n"
            "  --props N            cars in the demo city (default 3000)\n"
            "  --env day|night      set the environment at start (sun, sky, fog, exposure presets;\n"
            "                       default: a fresh scene has the day preset)\n"
            "  --cell-size M        culling grid cell, metres (default 64)\n"
            "  --max-clients N      connections (default 1024)\n"
            "  --max-payload BYTES  largest request frame (default 16777216)\n"
            "  --max-batch N        records per edit message (default 65536)\n"
            "  --max-entities N     entities in the scene (default 4194304)\n"
            "  --max-texture-size N largest texture side, pixels (default 8192)\n"
            "  --max-texture-mem BYTES\n"
            "                       textures together: encoded uploads, decoded pixels and mip chains,\n"
            "                       and uploads under way (default 1073741824)\n"
            "  --out-limit BYTES    unread reply bytes before a client is dropped (default 268435456)\n"
            "  --out-limit-total BYTES\n"
            "                       output buffer bytes of all clients together; past it the client\n"
            "                       with the largest backlog is dropped first (default: an eighth of\n"
            "                       physical memory, at least 64 MiB; 0 for no limit)\n"
            "  --threads N          query worker threads (default: cores)\n"
            "  --destruct-res N     destruction distance volumes: N^3 samples over an entity's box (default 8)\n"
            "  --render soft|gl     renderer for frames that name none (default soft; gl: headless\n"
            "                       OpenGL through EGL, and the daemon will not start without it)\n"
            "  --fx-off LIST        turn frame effects off for every frame: shadows,ssao,ibl,fxaa\n"
            "                       (any of them; a request may turn more off, never one back on)\n"
            "  --lut FILE           grade JPEG frames with this 3D LUT (.cube, LUT_3D_SIZE 2..128)\n"
            "                       after the ACES tone map; the daemon will not start on a bad file\n"
            "  --tokens FILE        roles need tokens: lines \"viewer|commander|editor TOKEN\" in a\n"
            "                       file only its owner can read (chmod 600); without it every\n"
            "                       client may edit, and only loopback is served\n"
            "  --insecure           serve a non-loopback --bind (or --metrics) without --tokens\n"
            "                       (anyone who can connect may edit, or read the metrics)\n"
            "  --metrics [ADDR:]PORT\n"
            "                       serve Prometheus metrics over HTTP at /metrics (off by default;\n"
            "                       ADDR 127.0.0.1 unless given; with --tokens a request needs\n"
            "                       \"Authorization: Bearer TOKEN\" of a viewer, as HELLO does)\n"
            "  --web [ADDR:]PORT    serve the browser viewer and commander at http://ADDR:PORT/ and\n"
            "                       the protocol over a WebSocket at /ws (off by default; ADDR\n"
            "                       127.0.0.1 unless given; other addresses need --tokens or --insecure)\n"
            "  --web-root DIR       the pages served (default: PREFIX/share/vantage/web when\n"
            "                       installed, else the source tree's web/)\n"
            "  --web-cert FILE      serve --web over TLS (https://, wss://) with this PEM certificate\n"
            "                       chain: browsers decode video only on https or localhost\n"
            "  --web-key FILE       the certificate's private key (PEM); both or neither\n"
            "  --max-video N        H.264 frame streams at once (16; 0: none); an encoder holds about\n"
            "                       15 MB at 1280x720, 29 MB at 1920x1080\n"
            "  --motion-ms MS       dynamic resolution: a stream that asks for it (the web pages do)\n"
            "                       is drawn, while its camera moves, at the largest scale (1/4..1 of\n"
            "                       each side) whose render fits MS (default 12; 0: always full size);\n"
            "                       a full-size frame follows when the camera rests\n"
            "  --hello-timeout MS   a client must finish HELLO this soon after connecting (10000);\n"
            "                       a metrics scraper its request head\n"
            "  --frame-timeout MS   a frame begun must arrive whole this soon (30000; slow-loris)\n"
            "  --data-dir DIR       keep the scene in DIR (journal + snapshots) and restore it on start\n"
            "  --durability P       always: an edit is on disk before its answer (group commit);\n"
            "                       everysec (default): synced once a second; off: the OS decides\n"
            "  --compact-mb N       write a snapshot when the journal passes N MB and twice the\n"
            "                       last snapshot (default 64); with --cluster, the writer publishes\n"
            "                       one every N MB of records and trims the stream behind it\n"
            "  --cluster URLS       share the scene through NATS JetStream (nats://HOST:PORT, comma-\n"
            "                       separated; nats://USER:PASS@HOST:PORT with a password; - reads\n"
            "                       them from VANTAGE_CLUSTER_URLS); with --scene-name or --follow\n"
            "  --scene-name NAME    with --cluster: this daemon writes scene NAME when the writer's\n"
            "                       lease is free, else it joins as a replica\n"
            "  --follow NAME        with --cluster: a replica of scene NAME (promoted when the writer\n"
            "                       is gone); edits sent to a replica are answered NOT_WRITER\n"
            "  --advertise ENDPOINT what clients are sent to when this daemon writes (HOST:PORT or a\n"
            "                       Unix socket path; default the --bind address and --port)\n"
            "  --stream-replicas N  with --cluster: copies of the stream and the lease (1..5, default 1)\n"
            "  --lease-ms MS        with --cluster: the writer's lease (default 3000; a dead writer is\n"
            "                       replaced within about that)\n"
            "  --cluster-ca FILE    with --cluster: speak TLS to NATS, verifying the servers against\n"
            "                       these PEM CA certificates\n"
            "                       With --cluster, --durability is replicated (default: an edit is\n"
            "                       answered once the stream stored it) or off (answered at once)\n"
            "  --log-level L        error|warn|info|debug (default info)\n"
            "  --help               this text\n",
            VP_DEFAULT_PORT);
}

static bool parse_u64(const char *s, uint64_t lo, uint64_t hi, uint64_t *out)
{
    char *end;
    errno = 0;
    unsigned long long v = strtoull(s, &end, 10);
    if (!*s || *s == '-' || *end || errno || v < lo || v > hi) return false;
    *out = v;
    return true;
}

static bool parse_u32(const char *s, uint32_t lo, uint32_t hi, uint32_t *out)
{
    uint64_t v;
    if (!parse_u64(s, lo, hi, &v)) return false;
    *out = (uint32_t)v;
    return true;
}

/* parse_u32, and want says what it accepts (the error names it) */
static bool num32(char *want, size_t wantlen, const char *s, uint32_t lo, uint32_t hi, uint32_t *out)
{
    snprintf(want, wantlen, "an integer, %lu..%lu", (unsigned long)lo, (unsigned long)hi);
    return parse_u32(s, lo, hi, out);
}

/* --out-limit-total's default: an eighth of physical memory (3 GiB on a
 * 24 GiB machine), at least 64 MiB: room for the scene, the journal's
 * snapshot fork and the workers' frames beside the clients' backlogs. */
static uint64_t default_out_limit_total(void)
{
    long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGESIZE);
    uint64_t phys = pages > 0 && page > 0 ? (uint64_t)pages * (uint64_t)page : 0;
    return phys / 8 > (64u << 20) ? phys / 8 : 64u << 20;
}

/* The pages --web serves when --web-root is not given: installed, next
 * to bin/ (PREFIX/share/vantage/web), else the source tree's. */
static const char *default_web_root(void)
{
    static char share[1024];
    ssize_t n = readlink("/proc/self/exe", share, sizeof share - 40);
    if (n > 0) {
        share[n] = 0;
        char *slash = strrchr(share, '/');
        if (slash) strcpy(slash, "/../share/vantage/web");
        if (access(share, F_OK) == 0) return share;
    }
    return VANTAGE_WEB_DIR;
}

/* --metrics and --web [ADDR:]PORT: ADDR an IPv4 address or localhost
 * (default 127.0.0.1), PORT 1..65535. */
static bool parse_addr_port(const char *arg, char *addr, size_t addrlen, int *port)
{
    const char *colon = strrchr(arg, ':');
    const char *p = colon ? colon + 1 : arg;
    size_t n = colon ? (size_t)(colon - arg) : 0;
    uint32_t v;
    if (!parse_u32(p, 1, 65535, &v) || n >= addrlen || (colon && !n)) return false;
    if (colon) {
        memcpy(addr, arg, n);
        addr[n] = 0;
    }
    if (!colon || !strcmp(addr, "localhost")) snprintf(addr, addrlen, "127.0.0.1");
    struct in_addr a;
    if (inet_pton(AF_INET, addr, &a) != 1) return false;
    *port = (int)v;
    return true;
}

int main(int argc, char **argv)
{
    server_config cfg = {
        .bind = "127.0.0.1",
        .port = VP_DEFAULT_PORT,
        .unix_path = "/tmp/vantaged.sock",
        .max_clients = 1024,
        .max_payload = 16u << 20,
        .max_batch = 65536,
        .out_limit = 256u << 20,
        .out_limit_total = default_out_limit_total(),
        .cell_size = 64,
        .renderer = VP_RENDERER_SOFT,
        .destruct_res = 8,
        .hello_timeout_ms = 10000,
        .max_video = 16,
        .motion_ms = 12,
        .frame_timeout_ms = 30000,
        .limits = {.max_entities = CULL_MAX_ENTITIES, .max_lights = 65536, .max_occluders = 1u << 20,
                   .max_occluder_tris = 1u << 20, .max_mesh_verts = 1u << 22,
                   .max_materials = 1u << 20, .max_texture_size = 8192, .max_texture_mem = 1ull << 30},
    };
    const char *scene_kind = "demo";
    const char *env_name = NULL;
    uint32_t props = 3000, port = (uint32_t)cfg.port;
    enum { O_BIND = 256, O_PORT, O_UNIX, O_SCENE, O_ENV, O_PROPS, O_CELL, O_CLIENTS, O_PAYLOAD, O_BATCH, O_ENTITIES,
           O_OUT, O_THREADS, O_RENDER, O_LOG, O_HELP, O_DRES, O_TOKENS, O_INSECURE, O_HELLO_TO, O_FRAME_TO,
           O_DATA, O_DURABILITY, O_COMPACT, O_METRICS, O_OUT_TOTAL, O_TEX_SIZE, O_TEX_MEM, O_LUT, O_FX_OFF, O_WEB, O_WEB_ROOT, O_WEB_CERT, O_WEB_KEY, O_MAX_VIDEO, O_MOTION,
           O_CLUSTER, O_SCENE_NAME, O_FOLLOW, O_ADVERTISE, O_STREAM_REPL, O_LEASE, O_CLUSTER_CA };
    static const struct option opts[] = {
        {"bind", required_argument, 0, O_BIND}, {"port", required_argument, 0, O_PORT},
        {"unix", required_argument, 0, O_UNIX}, {"scene", required_argument, 0, O_SCENE},
        {"env", required_argument, 0, O_ENV},
        {"props", required_argument, 0, O_PROPS}, {"cell-size", required_argument, 0, O_CELL},
        {"max-clients", required_argument, 0, O_CLIENTS}, {"max-payload", required_argument, 0, O_PAYLOAD},
        {"max-batch", required_argument, 0, O_BATCH}, {"max-entities", required_argument, 0, O_ENTITIES},
        {"out-limit", required_argument, 0, O_OUT}, {"threads", required_argument, 0, O_THREADS},
        {"render", required_argument, 0, O_RENDER},
        {"log-level", required_argument, 0, O_LOG}, {"help", no_argument, 0, O_HELP},
        {"destruct-res", required_argument, 0, O_DRES}, {"tokens", required_argument, 0, O_TOKENS},
        {"insecure", no_argument, 0, O_INSECURE}, {"hello-timeout", required_argument, 0, O_HELLO_TO},
        {"frame-timeout", required_argument, 0, O_FRAME_TO}, {"data-dir", required_argument, 0, O_DATA},
        {"durability", required_argument, 0, O_DURABILITY}, {"compact-mb", required_argument, 0, O_COMPACT},
        {"metrics", required_argument, 0, O_METRICS}, {"out-limit-total", required_argument, 0, O_OUT_TOTAL},
        {"max-texture-size", required_argument, 0, O_TEX_SIZE}, {"max-texture-mem", required_argument, 0, O_TEX_MEM},
        {"lut", required_argument, 0, O_LUT}, {"fx-off", required_argument, 0, O_FX_OFF},
        {"web", required_argument, 0, O_WEB}, {"web-root", required_argument, 0, O_WEB_ROOT},
        {"web-cert", required_argument, 0, O_WEB_CERT}, {"web-key", required_argument, 0, O_WEB_KEY},
        {"max-video", required_argument, 0, O_MAX_VIDEO}, {"motion-ms", required_argument, 0, O_MOTION}, {"cluster", required_argument, 0, O_CLUSTER},
        {"scene-name", required_argument, 0, O_SCENE_NAME}, {"follow", required_argument, 0, O_FOLLOW},
        {"advertise", required_argument, 0, O_ADVERTISE}, {"stream-replicas", required_argument, 0, O_STREAM_REPL},
        {"lease-ms", required_argument, 0, O_LEASE}, {"cluster-ca", required_argument, 0, O_CLUSTER_CA},
        {0, 0, 0, 0},
    };
    int o;
    bool ok = true, insecure = false;
    char want[96] = ""; /* what the option being parsed accepts, for its error */
    const char *tokens_path = NULL, *data_dir = NULL, *lut_path = NULL;
    int durability = JOURNAL_EVERYSEC;
    bool durability_set = false, replicated = false;
    cluster_config ccfg = {.replicas = 1, .lease_ms = 3000};
    const char *scene_name = NULL, *follow = NULL;
    static char metrics_addr[64], web_addr[64], advertise[300];
    uint32_t compact_mb = 64;
    while ((o = getopt_long(argc, argv, "", opts, NULL)) != -1) {
        switch (o) {
        case O_BIND: cfg.bind = optarg; break;
        case O_PORT: ok = num32(want, sizeof want, optarg, 1, 65535, &port); break;
        case O_UNIX: cfg.unix_path = optarg; break;
        case O_SCENE: scene_kind = optarg; break;
        case O_ENV: env_name = optarg; break;
        case O_PROPS: ok = num32(want, sizeof want, optarg, 0, 10000000, &props); break;
        case O_CELL:
            cfg.cell_size = atof(optarg);
            ok = cfg.cell_size >= 0.01 && cfg.cell_size <= 1e5;
            snprintf(want, sizeof want, "metres, 0.01..1e5");
            break;
        case O_CLIENTS: ok = num32(want, sizeof want, optarg, 1, 1000000, &cfg.max_clients); break;
        case O_PAYLOAD: ok = num32(want, sizeof want, optarg, 1024, 1u << 30, &cfg.max_payload); break;
        case O_BATCH: ok = num32(want, sizeof want, optarg, 1, 1u << 24, &cfg.max_batch); break;
        case O_ENTITIES: ok = num32(want, sizeof want, optarg, 1, CULL_MAX_ENTITIES, &cfg.limits.max_entities); break;
        case O_OUT: ok = num32(want, sizeof want, optarg, 4096, UINT32_MAX, &cfg.out_limit); break;
        case O_OUT_TOTAL:
            ok = parse_u64(optarg, 0, UINT64_MAX, &cfg.out_limit_total) &&
                 (!cfg.out_limit_total || cfg.out_limit_total >= 65536);
            snprintf(want, sizeof want, "bytes, 0 (no limit) or at least 65536");
            break;
        case O_TEX_SIZE:
            ok = num32(want, sizeof want, optarg, 1, VT_IMAGE_MAX_DIM, &cfg.limits.max_texture_size);
            break;
        case O_TEX_MEM:
            ok = parse_u64(optarg, 0, UINT64_MAX, &cfg.limits.max_texture_mem);
            snprintf(want, sizeof want, "bytes, 0 (no textures) or more");
            break;
        case O_THREADS: ok = num32(want, sizeof want, optarg, 0, 256, &cfg.threads); break;
        case O_DRES: ok = num32(want, sizeof want, optarg, 2, CULL_DVOL_MAX_RES, &cfg.destruct_res); break;
        case O_FX_OFF: {
            uint8_t bits;
            char bad[80];
            ok = vp_render_fx_parse(optarg, &bits, bad, sizeof bad) == 0;
            cfg.fx_off = bits >> 1;
            snprintf(want, sizeof want, "shadows, ssao, ibl, fxaa, comma-separated");
            break;
        }
        case O_RENDER:
            cfg.renderer = !strcmp(optarg, "gl") ? VP_RENDERER_GL : VP_RENDERER_SOFT;
            ok = !strcmp(optarg, "gl") || !strcmp(optarg, "soft");
            snprintf(want, sizeof want, "soft or gl");
            break;
        case O_LOG:
            ok = (g_log_level = log_level_parse(optarg)) >= 0;
            snprintf(want, sizeof want, "error, warn, info or debug");
            break;
        case O_TOKENS: tokens_path = optarg; break;
        case O_DATA:
            data_dir = optarg;
            ok = *optarg != 0;
            snprintf(want, sizeof want, "a directory");
            break;
        case O_DURABILITY:
            durability = !strcmp(optarg, "always") ? JOURNAL_ALWAYS : !strcmp(optarg, "off") ? JOURNAL_OFF : JOURNAL_EVERYSEC;
            replicated = !strcmp(optarg, "replicated");
            durability_set = true;
            ok = replicated || !strcmp(optarg, "always") || !strcmp(optarg, "everysec") || !strcmp(optarg, "off");
            snprintf(want, sizeof want, "always, everysec, off, or replicated (with --cluster)");
            break;
        case O_CLUSTER:
            /* "-": from the environment, so a password stays out of the process list */
            ccfg.urls = strcmp(optarg, "-") ? optarg : getenv("VANTAGE_CLUSTER_URLS");
            ok = ccfg.urls && *ccfg.urls;
            snprintf(want, sizeof want, "nats://HOST:PORT[,nats://HOST:PORT...], or - with VANTAGE_CLUSTER_URLS set");
            break;
        case O_SCENE_NAME: scene_name = optarg; break;
        case O_FOLLOW: follow = optarg; break;
        case O_ADVERTISE:
            ccfg.advertise = optarg;
            ok = *optarg && !strchr(optarg, ' ') && strlen(optarg) < 190;
            snprintf(want, sizeof want, "HOST:PORT or a socket path, no spaces, under 190 bytes");
            break;
        case O_STREAM_REPL: {
            uint32_t r;
            ok = num32(want, sizeof want, optarg, 1, 5, &r);
            ccfg.replicas = (int)r;
            break;
        }
        case O_LEASE: ok = num32(want, sizeof want, optarg, 300, 600000, &ccfg.lease_ms); break;
        case O_CLUSTER_CA:
            ccfg.ca_file = optarg;
            ok = *optarg != 0;
            snprintf(want, sizeof want, "a PEM file of CA certificates");
            break;
        case O_COMPACT: ok = num32(want, sizeof want, optarg, 1, 1u << 20, &compact_mb); break;
        case O_METRICS:
            ok = parse_addr_port(optarg, metrics_addr, sizeof metrics_addr, &cfg.metrics_port);
            snprintf(want, sizeof want, "[ADDR:]PORT, ADDR an IPv4 address or localhost, PORT 1..65535");
            break;
        case O_WEB:
            ok = parse_addr_port(optarg, web_addr, sizeof web_addr, &cfg.web_port);
            snprintf(want, sizeof want, "[ADDR:]PORT, ADDR an IPv4 address or localhost, PORT 1..65535");
            break;
        case O_WEB_ROOT: cfg.web_root = optarg; break;
        case O_WEB_CERT: cfg.web_cert = optarg; break;
        case O_WEB_KEY: cfg.web_key = optarg; break;
        case O_MAX_VIDEO: ok = num32(want, sizeof want, optarg, 0, 4096, &cfg.max_video); break;
        case O_MOTION: ok = num32(want, sizeof want, optarg, 0, 1000, &cfg.motion_ms); break;
        case O_INSECURE: insecure = true; break;
        case O_HELLO_TO: ok = num32(want, sizeof want, optarg, 100, 3600000, &cfg.hello_timeout_ms); break;
        case O_FRAME_TO: ok = num32(want, sizeof want, optarg, 100, 3600000, &cfg.frame_timeout_ms); break;
        case O_LUT: lut_path = optarg; break;
        case O_HELP: usage(stdout); return 0;
        default: usage(stderr); return 2;
        }
        if (!ok) {
            fprintf(stderr, "vantaged: bad value for --%s: %s (expected %s)\n", opts[o - O_BIND].name, optarg, want);
            return 2;
        }
    }
    if (optind < argc) {
        fprintf(stderr, "vantaged: unexpected argument: %s\n", argv[optind]);
        usage(stderr);
        return 2;
    }
    cfg.port = (int)port;
    static vt_lut3d lut; /* read-only once loaded, for the daemon's life */
    if (lut_path) {
        char lerr[300];
        if (vt_lut_load(lut_path, &lut, lerr, sizeof lerr)) {
            fprintf(stderr, "vantaged: --lut %s\n", lerr);
            return 2;
        }
        cfg.lut = &lut;
    }
    if ((!cfg.bind || !*cfg.bind) && (!cfg.unix_path || !*cfg.unix_path)) {
        fprintf(stderr, "vantaged: nothing to listen on (--bind \"\" and --unix \"\")\n");
        return 2;
    }

    /* a file-size limit (ulimit -f) is a write error for the journal, not
       a signal that kills the daemon */
    signal(SIGXFSZ, SIG_IGN);
    static auth_tokens tokens;
    if (tokens_path) {
        char err[400];
        if (auth_load(tokens_path, &tokens, err, sizeof err)) {
            fprintf(stderr, "vantaged: --tokens %s\n", err);
            return 2;
        }
        cfg.tokens = &tokens;
    } else if (!auth_loopback(cfg.bind) && !insecure) {
        fprintf(stderr,
                "vantaged: --bind %s reaches other machines and there is no --tokens file: anyone who can "
                "connect could edit the scene. Give --tokens FILE, or --insecure if that is what you want.\n",
                cfg.bind);
        return 2;
    }
    if (!cfg.tokens && !auth_loopback(cfg.bind)) LOGW("--insecure: %s served without tokens", cfg.bind);
    if (cfg.metrics_port) {
        /* the metrics follow the protocol's rule: whoever may view may read
           them, so without tokens only this machine, unless --insecure */
        cfg.metrics_bind = metrics_addr;
        if (!cfg.tokens && !auth_loopback(metrics_addr) && !insecure) {
            fprintf(stderr,
                    "vantaged: --metrics %s:%d reaches other machines and there is no --tokens file: anyone who "
                    "can connect could read the metrics. Give --tokens FILE (scrapers then send \"Authorization: "
                    "Bearer TOKEN\"), or --insecure if that is what you want.\n",
                    metrics_addr, cfg.metrics_port);
            return 2;
        }
        if (!cfg.tokens && !auth_loopback(metrics_addr))
            LOGW("--insecure: metrics on %s served without tokens", metrics_addr);
    }
    if (!cfg.web_cert != !cfg.web_key || (cfg.web_cert && !cfg.web_port)) {
        fprintf(stderr, "vantaged: --web-cert and --web-key go together, with --web\n");
        return 2;
    }
    if (cfg.web_port) {
        /* the WebSocket speaks the protocol: the same rule as --bind */
        cfg.web_bind = web_addr;
        if (!cfg.web_root) cfg.web_root = default_web_root();
        if (!cfg.tokens && !auth_loopback(web_addr) && !insecure) {
            fprintf(stderr,
                    "vantaged: --web %s:%d reaches other machines and there is no --tokens file: anyone who can "
                    "connect could edit the scene. Give --tokens FILE, or --insecure if that is what you want.\n",
                    web_addr, cfg.web_port);
            return 2;
        }
        if (!cfg.tokens && !auth_loopback(web_addr)) LOGW("--insecure: the web viewer on %s served without tokens", web_addr);
    }

    if (ccfg.urls || scene_name || follow) {
        if (!ccfg.urls || !scene_name == !follow) {
            fprintf(stderr, "vantaged: --cluster URLS goes with one of --scene-name NAME (a writer) or --follow "
                            "NAME (a replica)\n");
            return 2;
        }
        if (data_dir) {
            fprintf(stderr, "vantaged: --data-dir and --cluster: the cluster's stream is the scene's journal "
                            "(give one or the other)\n");
            return 2;
        }
        if (durability_set && durability == JOURNAL_ALWAYS && !replicated) {
            fprintf(stderr, "vantaged: --durability always needs --data-dir; with --cluster use replicated or off\n");
            return 2;
        }
        ccfg.name = scene_name ? scene_name : follow;
        ccfg.snapshot_bytes = (uint64_t)compact_mb << 20;
        ccfg.cell_size = cfg.cell_size;
        ccfg.follow = follow != NULL;
        ccfg.wait_stored = !durability_set || replicated;
        if (!ccfg.advertise) {
            if (cfg.bind && *cfg.bind) snprintf(advertise, sizeof advertise, "%s:%d", cfg.bind, (int)port);
            else snprintf(advertise, sizeof advertise, "%s", cfg.unix_path ? cfg.unix_path : "-");
            ccfg.advertise = advertise;
        }
    } else if (replicated) {
        fprintf(stderr, "vantaged: --durability replicated needs --cluster\n");
        return 2;
    } else if (ccfg.replicas != 1 || ccfg.lease_ms != 3000 || ccfg.advertise || ccfg.ca_file) {
        fprintf(stderr, "vantaged: --stream-replicas, --lease-ms, --advertise and --cluster-ca go with --cluster\n");
        return 2;
    }

    scene *sc = calloc(1, sizeof *sc);
    if (!sc || scene_init(sc, cfg.cell_size, &cfg.limits)) {
        LOGE("cannot create the scene");
        return 1;
    }
    if (strcmp(scene_kind, "demo") && strcmp(scene_kind, "empty")) {
        fprintf(stderr, "vantaged: --scene %s: use demo or empty (load files with `vantage import`)\n", scene_kind);
        return 2;
    }
    bool build_demo = !strcmp(scene_kind, "demo");
    vp_env env_preset;
    if (env_name && vp_env_preset(env_name, &env_preset)) {
        fprintf(stderr, "vantaged: --env %s: use day or night\n", env_name);
        return 2;
    }
    if (data_dir) {
        static const char *const pol[] = {"off", "everysec", "always"};
        journal_report rep;
        char err[800];
        sc->replaying = true; /* records acknowledged by older daemons replay as they were */
        int jrc = journal_open(data_dir, durability, sc, &cfg.journal, &rep, err, sizeof err);
        sc->replaying = false;
        if (jrc) {
            LOGE("--data-dir %s: %s", data_dir, err);
            scene_free(sc); /* what recovery restored before it stopped */
            free(sc);
            return 1;
        }
        journal_set_limit(cfg.journal, (uint64_t)compact_mb << 20);
        if (rep.cut[0]) LOGW("journal: a damaged end was cut, not replayed: %s", rep.cut);
        if (rep.fresh) {
            LOGI("%s: new data directory, durability %s", data_dir, pol[durability]);
        } else {
            cull_world_info info;
            cull_world_info_get(sc->world, &info);
            LOGI("%s: scene restored in %llu ms (snapshot %06llu, %.1f MB; %llu journal records, %.1f MB; "
                 "%u loads left open dropped): %u entities, %zu occluders, %zu lights, epoch %llu; durability %s",
                 data_dir, (unsigned long long)rep.ms, (unsigned long long)rep.snapshot_gen,
                 rep.snapshot_bytes / 1e6, (unsigned long long)rep.records, rep.bytes / 1e6, rep.loads_dropped,
                 info.entities, sc->occluders.count, sc->lights.count, (unsigned long long)sc->epoch,
                 pol[durability]);
            if (build_demo) LOGI("--scene demo not built: the data directory has a scene");
            build_demo = false;
        }
    }
    bool build_env = env_name != NULL;
    if (ccfg.urls) {
        bool fresh = false;
        char err[600];
        uint64_t t0 = ae_now_ms();
        if (cluster_open(&ccfg, sc, &cfg.cluster, &fresh, err, sizeof err)) {
            LOGE("--cluster: %s", err);
            scene_free(sc);
            free(sc);
            return 1;
        }
        cluster_stats cs;
        cluster_stats_get(cfg.cluster, &cs);
        LOGI("cluster %s: %s, %llu records applied in %llu ms, epoch %llu; durability %s", ccfg.name,
             cluster_role_name(cs.role), (unsigned long long)cs.records, (unsigned long long)(ae_now_ms() - t0),
             (unsigned long long)sc->epoch, ccfg.wait_stored ? "replicated" : "off (answered before stored)");
        /* the starting scene is the stream's first records, made by its first writer */
        if (!fresh && !ccfg.follow && (build_demo || build_env))
            LOGI("--scene/--env not applied: %s", cluster_role(cfg.cluster) == CLUSTER_WRITER
                                                      ? "the stream has a scene" : "this daemon is a replica");
        build_demo = build_demo && fresh;
        build_env = build_env && fresh;
    }
    if (build_demo) {
        /* through the journal like any edit, so a restart rebuilds it */
        uint64_t t0 = ae_now_ms();
        edit_result r;
        scene_err err;
        edit city = {.type = EDIT_CITY, .aux = props};
        if (journal_apply(cfg.journal, sc, &city, NULL, 0, &r, &err)) {
            LOGE("cannot build the demo scene: %s", err.msg);
            return 1;
        }
        if (cfg.cluster && !cluster_publish(cfg.cluster, &city, NULL, 0)) {
            LOGE("cannot publish the demo scene to the cluster's stream");
            return 1;
        }
        edit_result_free(&r);
        cull_world_info info;
        cull_world_info_get(sc->world, &info);
        LOGI("demo city: %u entities, %zu occluders, %zu lights, %zu materials, %zu textures in %llu ms",
             info.entities, sc->occluders.count, sc->lights.count, sc->materials.count, sc->textures.count,
             (unsigned long long)(ae_now_ms() - t0));
    }
    if (build_env) {
        /* an ENV_SET like a client's, journalled */
        uint8_t buf[VP_HEADER_SIZE + VP_ENV_SIZE];
        vp_writer w;
        vp_writer_init(&w, buf, sizeof buf);
        vp_enc_env(&w, VP_ENV_SET, 0, &env_preset);
        edit e;
        edit_result r;
        scene_err err;
        int erc = edit_decode(VP_ENV_SET, buf + VP_HEADER_SIZE, VP_ENV_SIZE, 0, EDIT_LAYOUT, &e);
        if (erc) edit_explain(&e, erc, &err);
        else erc = journal_apply(cfg.journal, sc, &e, buf + VP_HEADER_SIZE, VP_ENV_SIZE, &r, &err);
        if (!erc && cfg.cluster && !cluster_publish(cfg.cluster, &e, buf + VP_HEADER_SIZE, VP_ENV_SIZE)) {
            snprintf(err.msg, sizeof err.msg, "cannot publish it to the cluster's stream");
            erc = VP_ERR_IO;
        }
        if (erc) {
            LOGE("--env %s: %s", env_name, err.msg);
            return 1;
        }
        edit_result_free(&r);
    }
    server *srv = server_create(&cfg, sc);
    if (!srv) { /* it said why; it closed the journal, the scene is ours */
        scene_free(sc);
        free(sc);
        return 1;
    }
    if (cfg.bind && *cfg.bind) LOGI("listening on %s:%d", cfg.bind, cfg.port);
    if (cfg.unix_path && *cfg.unix_path) LOGI("listening on %s", cfg.unix_path);
    LOGI("try: vantage -p %d query --eye 0,2,-300 --at 0,2,0", cfg.port);
    int run = server_run(srv); /* it said why */
    int rc = server_destroy(srv);
    scene_free(sc);
    free(sc);
    vt_lut_free(&lut);
    LOGI("bye");
    return rc || run ? 1 : 0;
}
