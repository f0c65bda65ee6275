/*
 * vantage_cli.c — the `vantage` command line tool, in the manner of
 * redis-cli: connection flags, then a command.
 *
 *   vantage [-h HOST] [-p PORT] [-s SOCKET] [--token T] COMMAND [ARGS]
 *
 * Exit status: 0 ok, 1 the server refused (its message on stderr), 2 bad
 * usage, 3 cannot connect or the connection failed.
 *
 * Every command's forms and help live in one table here (forms[]):
 * `vantage --help`, `vantage COMMAND --help` and README.md's CLI block
 * (held to it by tests/test_cli.c) all come from or match it.
 */
#include "cli.h"

#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <signal.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

const char *g_prog = "vantage";

/* ---- the commands' help --------------------------------------------------------------
 * Every form of every command, described once: `vantage --help` lists the
 * synopses (and the brief), `vantage COMMAND [...] --help` prints the
 * forms of COMMAND that its arguments name (`bench --scenario --help`:
 * the scenario form) with their details, and README.md's CLI block repeats
 * the synopses (tests/test_cli.c holds the two lists to each other).
 * A synopsis starts with the command and the words that pick its form;
 * lines after the first are indented 8 spaces. */
typedef struct cli_form {
    const char *cmd;      /* the command word */
    const char *synopsis; /* "cmd [form words] options" */
    const char *brief;    /* one line for vantage --help */
    const char *about;    /* the details for COMMAND --help; lines indented 2 */
} cli_form;

static const cli_form forms[] = {
    {"ping", "ping [-c N]", "round trip to the daemon (N times, prints latency)",
     "  Sends PING and waits for PONG; with -c N, N times, each round trip printed in microseconds.\n"},
    {"stats", "stats [--json | --metrics]",
     "scene and server counters, clients by role, latency per request type, frames dropped",
     "  The daemon's figures (entities, cells, epoch, queries, clients), and from its metrics: clients\n"
     "  by role, frame streams, p50/p99 per request type and per query stage (estimated from the\n"
     "  histogram buckets). --json: one JSON object; --metrics: the Prometheus text as the daemon\n"
     "  sends it.\n"},
    {"add", "add ID --mesh C [--pos X,Y,Z] [--rotate YAW,PITCH,ROLL | --quat X,Y,Z,W] [--scale S|X,Y,Z]\n"
     "        [--material M] [--sublevel N] [--dynamic]",
     "add an entity: mesh class C placed by a transform (its bounds derived from the mesh)",
     "  --pos in metres (0,0,0); --rotate in degrees about +Y, then +X, then +Z (Y up), or --quat a\n"
     "  unit quaternion; --scale one factor or one per axis (1; negative mirrors, 0 on one axis at\n"
     "  most). Class C must hold a mesh; material M (0) must exist. Needs the editor role.\n"},
    {"add", "add ID X,Y,Z R [--class N] [--sublevel N] [--dynamic] [--aabb X0,Y0,Z0,X1,Y1,Z1] [--material M]",
     "add a culling-only entity: a sphere (centre, radius), and a box (derived unless --aabb)",
     "  ID is a 64-bit id (decimal or 0x hex); --class and --sublevel are 0..65535; --dynamic marks\n"
     "  an entity that moves often. Needs the editor role.\n"},
    {"move", "move ID [X,Y,Z] [--pos X,Y,Z] [--rotate YAW,PITCH,ROLL | --quat X,Y,Z,W] [--scale S|X,Y,Z]",
     "move an entity with a transform (TRANSFORM_SET)", "  What is not given is kept.\n"},
    {"move", "move ID X,Y,Z [--radius R]", "move a culling-only entity (its AABB moves with it)",
     "  The entity's sphere is centred on X,Y,Z and its box moves with it; --radius R (>= 0) gives it\n"
     "  a new radius and a box derived from the sphere.\n"},
    {"material",
     "material put ID [--base R,G,B[,A]] [--metallic M] [--roughness R] [--emissive R,G,B]\n"
     "        [--emissive-strength S] [--alpha-mask CUTOFF] [--double-sided] [--normal-scale S]\n"
     "        [--texture SLOT=ID]...",
     "add or replace a material (glTF metallic-roughness); entities using it see the change",
     "  Colours linear, 0..1 (base 1,1,1,1; metallic 0; roughness 1; emissive 0, strength 1).\n"
     "  SLOT: base, mr (metallic-roughness), normal or emissive; ID an uploaded texture.\n"},
    {"material", "material rm ID [ID...]", "remove materials (refused while an entity uses one)", ""},
    {"remove", "remove ID [ID...]", "remove entities",
     "  All or nothing: an id that does not exist refuses the whole batch, naming it.\n"},
    {"get", "get ID [ID...]", "print entities as JSON lines", "  One JSON line per entity, with its handle.\n"},
    {"import", "import FILE.jsonl", "add entities, one JSON object per line (- = stdin)",
     "  {\"id\": 64-bit id, \"class\": n, \"sphere\": [x,y,z,r], \"aabb\": [minx,miny,minz,maxx,maxy,maxz],\n"
     "   \"sublevel\": \"name\" or n, \"dynamic\": false}; sphere or aabb may be left out. A bad line stops\n"
     "  the import with its line number (exit 2); a batch the daemon refuses is refused whole.\n"},
    {"import", "import FILE.gltf|glb|obj", "load a level file as the sub-level named after it",
     "  As sublevel load NAME FILE with NAME the file's name without its extension (README: Authoring\n"
     "  levels).\n"},
    {"export", "export FILE.jsonl", "write every entity, same format (- = stdout)",
     "  Sub-levels with names are written by name. Fails if the scene changes during the export.\n"},
    {"export", "export FILE.glb", "write the live scene as glTF 2.0 binary (Blender, any glTF viewer)",
     "  Entities as nodes with their transforms, meshes, materials with their textures (the uploaded\n"
     "  PNG/JPEG bytes), lights and the sun (KHR_lights_punctual). Any role.\n"},
    {"query",
     "query --eye X,Y,Z --at X,Y,Z [--up X,Y,Z] [--fov DEG | --ortho W,H] [--near N] [--far F]\n"
     "        [--size WxH] [--min-area PX] [--exact-area] [--no-occlusion | --occ-centre] [--json]",
     "the entities a view sees: counts, timings, the first 20 (--json: all)",
     "  --fov DEG 0..180 exclusive (60) or --ortho W,H (metres); --size WxH 1..65535 each (1920x1080);\n"
     "  --min-area PX culls what covers fewer pixels; --exact-area reports each entity's screen area\n"
     "  (the area column appears only then); --no-occlusion keeps what occluders hide; --occ-centre\n"
     "  culls by pixel-centre coverage.\n"},
    {"render",
     "render --eye X,Y,Z --at X,Y,Z [--up X,Y,Z] [--fov DEG] [--near N] [--far F] [--size WxH]\n"
     "        [--exposure EV] [--quality Q] [--no-occlusion] [--renderer soft|gl] [--highlight ID[,ID..]]\n"
     "        [--fx-off shadows,ssao,ibl,fxaa] -o FILE.exr|png|jpg",
     "one frame from the daemon, written by the file's extension",
     "  -o FILE (required): .exr (half RGBA + float Z), .png (tone mapped here, ACES after --exposure),\n"
     "  .jpg (encoded by the daemon at --quality 1..100, 85). --size WxH 1..4096 each (1280x720);\n"
     "  --fov 0..180 exclusive (60); --exposure -64..64 EV (0); --renderer soft or gl; --highlight: up to\n"
     "  8 entities outlined (ids not drawn are ignored); the live marks (vantage mark) are drawn as icons.\n"},
    {"lights",
     "lights --eye X,Y,Z --at X,Y,Z [--up X,Y,Z] [--fov DEG] [--near N] [--far F] [--size WxH]\n"
     "        [--no-depth] [--json]",
     "the view's Forward+ tile light lists (a heat map, or JSON)",
     "  Lights per 16x16-pixel tile, binned against each tile's depth range (--no-depth: the whole\n"
     "  frustum); --json: every tile's light ids.\n"},
    {"sublevel", "sublevel load NAME FILE.gltf|glb|obj [--dry-run] [--json]",
     "import a glTF or OBJ level and load it as one sub-level",
     "  Nothing of it is seen before all of it is, at one epoch (README: Authoring levels); --dry-run\n"
     "  only imports and prints what the file holds.\n"},
    {"sublevel", "sublevel unload NAME", "hide a sub-level at one epoch and free it",
     "  A name that names no sub-level is refused with NOT_FOUND; one not loaded with STATE.\n"},
    {"sublevel", "sublevel list [--json]", "sub-levels with their state and counts", ""},
    {"texture", "texture put ID FILE [--srgb]", "upload a PNG, JPEG or EXR file (by its bytes) as a texture", ""},
    {"texture", "texture rm ID [ID...]", "remove textures (refused while a material or the sky uses one)", ""},
    {"env",
     "env [--day | --night] [--sun AZ,EL[,LUX] | --sun off] [--sun-color R,G,B] [--sky analytic|color:R,G,B|exr:ID]\n"
     "        [--sky-intensity X] [--sky-rotation DEG] [--turbidity T] [--ground HEIGHT|off] [--ground-color R,G,B]\n"
     "        [--ground-material ID] [--fog DENSITY[,R,G,B]] [--exposure auto[:COMP]|EV]",
     "print the environment (sun, sky, ground, fog, exposure); options change it",
     "  AZ from +Z towards +X, EL above the horizon (degrees); options apply in the order given.\n"},
    {"destroy", "destroy ID X,Y,Z RADIUS [--debris N] [--handle H] [--json]",
     "a destruction sphere on an entity: its occluder is cut open for the next query",
     "  RADIUS in metres, > 0; --debris N (0..64) small dynamic entities around the hole; --handle H:\n"
     "  refused if the entity's handle is not H. Needs the editor role.\n"},
    {"mark", "mark X,Y,Z [--kind K] [--ttl MS] [--entity ID]",
     "a commander's mark: pushed to mark subscribers, drawn as an icon in frames while it lives",
     "  --kind 0 ping (a diamond, the default), 1 select (a square), others a disc; --ttl 1..600000 ms\n"
     "  (10000). Needs the commander role.\n"},
    {"select", "select ID[,ID..] [ID...]",
     "set the scene's shared selection: pushed to selection subscribers, outlined in every frame",
     "  At most 256 ids (an editor's selection, e.g. Blender's through the live-link; the last SELECT\n"
     "  wins). Frames outline the first 64 in cyan. Needs the commander role.\n"},
    {"select", "select --clear", "clear the scene's shared selection", "  Needs the commander role.\n"},
    {"watch", "watch [--count N] [--selection]", "print scene-changed events as they happen",
     "  One JSON line per coalesced scene change (epoch, added, updated, removed); Ctrl-C stops.\n"
     "  --selection: the shared selection instead, one line per change (serial, client, ids), the\n"
     "  first where it stands now.\n"},
    {"watch",
     "watch --frames DIR --eye X,Y,Z --at X,Y,Z [--up X,Y,Z] [--fov DEG] [--near N] [--far F]\n"
     "        [--size WxH] [--exposure EV] [--quality Q] [--no-occlusion] [--renderer soft|gl]\n"
     "        [--highlight ID[,ID..]] [--fx-off LIST] [--format jpg|png|exr] [--fps N] [--count N] [--seconds S]\n"
     "        [--orbit DEG_PER_S]",
     "write the frames pushed as the scene changes (latest-frame-wins), one JSON line each",
     "  DIR/frame-NNNNNN.jpg (or .png, .exr); at most --fps N frames a second (1..240, 30).\n"
     "  --orbit D turns the camera D degrees a second around --at, re-aimed after each frame,\n"
     "  at most --fps times a second. The camera options are render's.\n"},
    {"bench",
     "bench [--test query|edit|transform|ping] [--clients N] [--threads T] [--requests N] [--pipeline P]\n"
     "        [--views K] [--batch B] [--count-only] [--no-occlusion] [--json]",
     "load test: rate and latency percentiles",
     "  Exactly --requests N requests (100000), spread over --clients N connections (64, 1..1000;\n"
     "  at most N) driven by --threads T (2); --pipeline P in flight per connection (1); --views K\n"
     "  per query (1..32); --batch B entities per edit (1000). transform: TRANSFORM_SET batches\n"
     "  of B transform entities (a 0.5 m cube mesh on class 65000).\n"},
    {"bench",
     "bench --test frames [--viewers N] [--stalled S] [--seconds T] [--size WxH] [--fps F]\n"
     "        [--edits-per-s R] [--quality Q] [--renderer soft|gl] [--eye X,Y,Z] [--at X,Y,Z] [--json]",
     "frame streams while the scene is edited",
     "  N viewers (1) subscribe to one view and count their frames, S more never read (stalled), and\n"
     "  an editor moves an entity R times a second (100) for T seconds (5): frames/s per viewer and\n"
     "  the spread of frame intervals.\n"},
    {"bench",
     "bench --scenario FILE|NAME [--seconds S] [--requests N] [--threads T] [--json FILE|-]\n"
     "        [--csv FILE|-] [--progress|--no-progress] [--daemon-pid PID]",
     "the load generator: a scripted mix of clients (README: Load testing)",
     "  A scenario file, or one shipped (editor-live-link, many-viewers, query-storm,\n"
     "  destruction-barrage). --seconds or --requests override the file's length; the report gives\n"
     "  per group count, rate, errors and p50..max, the p99 of each tenth of the run, and the\n"
     "  daemon's memory (its pid from the Unix socket, or --daemon-pid); '-' marks a tenth with no\n"
     "  sample. Exit 2 for a bad file, 3 if the daemon goes away (a PARTIAL report).\n"},
    {"pad", "pad list [--json]", "game controllers found (hidraw and USB), not opened",
     "  vid:pid, name, protocol and where, for each pad present; --json: one object a line.\n"},
    {"pad", "pad dump [--replay FILE [--speed X] [--loop]] [--record FILE] [--count N] [--seconds S] [--stats]",
     "one JSON line of normalized state per report (a live pad, or a hid-recorder file)",
     "  Pads added, removed and errors on stderr; Ctrl-C stops.\n"
     "    --replay FILE   a hid-recorder file (hid-tools' hid-recorder, or --record's) instead of pads\n"
     "    --speed X       the file's timing scaled (2: twice as fast); negative: as fast as possible\n"
     "    --loop          start the file again at its end\n"
     "    --record FILE   also write every report of the live pads to FILE (hid-recorder's format)\n"
     "    --count N, --seconds S   stop after N state lines or S seconds\n"
     "    --stats         per pad on stderr at the end: reports read, ignored, refused, changes\n"
     "  Supported: DualShock 4, DualSense (Edge), Switch Pro (hidraw); Xbox 360 and Xbox One /\n"
     "  Series wired (libusb).\n"},
    {"commander",
     "commander [--replay FILE [--speed X] [--loop]] [--record FILE] [--headless DIR] [--size WxH]\n"
     "        [--quality Q] [--fps N] [--renderer soft|gl] [--config FILE] [--seconds S] [--frames N]\n"
     "        [--screenshot FILE.png] [--stats] [--json] [--destroy-radius M] [--exposure EV] [--perspective]\n"
     "        [--full-size]",
     "the tablet-commander thin client: a pad (or keyboard and mouse) drives its own view",
     "  A view of the daemon's scene from above, driven by a game pad (hidraw and USB pads are found\n"
     "  and hot-plugged; `vantage pad list`), a recorded capture (--replay, hid-recorder format), or\n"
     "  keyboard and mouse in the window:\n"
     "    left stick / WASD pan, right stick / Q E rotate, R F tilt, triggers / Z X / wheel zoom,\n"
     "    south (A, Cross) / Space select, west / P ping, east / C cancel, north / Delete destroy,\n"
     "    shoulders / [ ] groups, back / Tab perspective, R3 / Home reset, Escape quits.\n"
     "  It needs a display for its window (X11 or Wayland; exit 1 saying why when there is none):\n"
     "  --headless DIR      no window: frames go to DIR/frame-NNNNNN.jpg, one JSON line each in\n"
     "                      DIR/frames.jsonl\n"
     "  --config FILE       dead zone, curve, speeds, tick rate and bindings (README: Commander)\n"
     "  --stats             at exit: frames shown and their rate over the run, input-to-photon\n"
     "                      latency p50/p95/p99/max and its parts ('-': no sample); --json as JSON\n"
     "                      (null: no sample). The overlay's fps is the same count, frames shown,\n"
     "                      over the last second\n"
     "  --screenshot FILE   the window with its overlay as a PNG, at exit\n"
     "  --seconds S, --frames N   stop after S seconds or N frames shown (else Escape / Ctrl-C)\n"
     "  --size WxH (1280x720), --quality Q (80), --fps N (the daemon's cap, 1..240), --speed X (replay\n"
     "  time scale, 1), --destroy-radius M (3), --exposure EV (1.5), --perspective (start tilted)\n"
     "  --full-size         every frame at full size: by default frames are drawn smaller while the\n"
     "                      camera moves and full size when it rests (vantaged --motion-ms)\n"},
};

static void usage(FILE *f)
{
    fprintf(f, "usage: vantage [-h HOST] [-p PORT] [-s SOCKET] [--token T] [--timeout MS] COMMAND [ARGS]\n"
               "\n"
               "commands:\n");
    for (size_t i = 0; i < sizeof forms / sizeof forms[0]; i++)
        fprintf(f, "  %s\n      %s\n", forms[i].synopsis, forms[i].brief);
    fprintf(f,
            "\n"
            "connection: -h HOST (127.0.0.1), -p PORT (%d), -s SOCKET (Unix socket instead of TCP),\n"
            "            --token T (or VANTAGE_TOKEN) where the daemon has --tokens;\n"
            "            a cluster (vantaged --cluster): -h HOST:PORT,HOST:PORT,/SOCKET... (or\n"
            "            VANTAGE_ENDPOINTS), tried in turn (viewers from a random one); an edit a\n"
            "            replica refuses (NOT_WRITER) goes on to the writer it names\n"
            "exit status: 0 ok, 1 refused (the server's code and message on stderr), 2 bad usage, 3 cannot\n"
            "             connect. COMMAND --help prints that command's usage.\n",
            VTC_DEFAULT_PORT);
}

/* The words after the command that pick a form ("--test frames",
 * "load"): the synopsis's tokens up to the first that is not a literal
 * (a lowercase word or an --option). n words at most; returns the count. */
static int form_words(const cli_form *fm, const char *w[], size_t len[], int n)
{
    const char *p = fm->synopsis + strlen(fm->cmd);
    int k = 0;
    while (k < n) {
        while (*p == ' ') p++;
        size_t l = strcspn(p, " \n");
        if (!l || !(p[0] == '-' || (p[0] >= 'a' && p[0] <= 'z'))) break;
        bool lit = true;
        for (size_t i = 0; i < l; i++) lit &= (p[i] >= 'a' && p[i] <= 'z') || p[i] == '-';
        if (!lit) break;
        w[k] = p;
        len[k++] = l;
        p += l;
    }
    return k;
}

static bool has_arg(int argc, char **argv, const char *w, size_t len)
{
    for (int i = 1; i < argc; i++)
        if (strlen(argv[i]) == len && !memcmp(argv[i], w, len)) return true;
    return false;
}

/* `vantage COMMAND ... --help`: the forms of the command whose words the
 * arguments hold (the most specific), or all of its forms. */
static int command_help(int argc, char **argv)
{
    enum { NF = sizeof forms / sizeof forms[0] };
    int score[NF], best = 0;
    for (size_t i = 0; i < NF; i++) {
        score[i] = -1;
        if (strcmp(forms[i].cmd, argv[0])) continue;
        const char *w[4];
        size_t len[4];
        int n = form_words(&forms[i], w, len, 4), hit = 0;
        while (hit < n && has_arg(argc, argv, w[hit], len[hit])) hit++;
        score[i] = hit == n ? n : 0;
        if (score[i] > best) best = score[i];
    }
    bool first = true;
    for (size_t i = 0; i < NF; i++) {
        if (score[i] < 0 || (best > 0 && score[i] != best)) continue;
        printf("%s", first ? "" : "\n");
        /* the synopsis, its continuation lines under the command */
        const char *s = forms[i].synopsis;
        printf("%s vantage ", first ? "usage:" : "   or:");
        for (; *s; s++) {
            putchar(*s);
            if (*s == '\n') printf("       ");
        }
        printf("\n\n  %s\n%s", forms[i].brief, forms[i].about);
        first = false;
    }
    printf("\n(connection options go before COMMAND: vantage --help)\n");
    return 0;
}

static const char *g_cmd; /* the command being run, for die_usage's hint */

int die_usage(const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    fprintf(stderr, "%s: ", g_prog);
    vfprintf(stderr, fmt, ap);
    va_end(ap);
    fprintf(stderr, " (vantage %s%s--help)\n", g_cmd ? g_cmd : "", g_cmd ? " " : "");
    return 2;
}

int die_bad_value(const char *cmd, const char *opt, const char *value, const char *expected)
{
    return die_usage("%s: %s %s: expected %s", cmd, opt, value, expected);
}

int die_missing(const char *cmd, const char *opt, const char *why)
{
    return die_usage("%s: %s is missing (%s)", cmd, opt, why);
}

int die_bad_opt(const char *cmd, const cli_opt_doc *docs, size_t n, int code, const char *value)
{
    for (size_t i = 0; i < n; i++)
        if (docs[i].code == code) return die_bad_value(cmd, docs[i].name, value, docs[i].expected);
    return die_usage("%s: bad value %s", cmd, value);
}

int server_fail(cli *k, const char *what, int rc)
{
    const vtc_error *e = vtc_last_error(k->c);
    if (rc == VTC_ERR_IO) {
        fprintf(stderr, "%s: %s: %s\n", g_prog, what, e->msg);
        return 3;
    }
    /* the daemon's messages for a batch begin "record N": the index is
       added here only when the message does not name it already */
    char pre[24];
    int pl = snprintf(pre, sizeof pre, "record %u", e->index);
    bool named = !strncmp(e->msg, pre, (size_t)pl) && (e->msg[pl] == ':' || e->msg[pl] == ' ');
    if (e->index != UINT32_MAX && !named)
        fprintf(stderr, "%s: %s: error %d (%s), record %u: %s\n", g_prog, what, rc, vp_strerror(rc), e->index,
                e->msg);
    else
        fprintf(stderr, "%s: %s: error %d (%s): %s\n", g_prog, what, rc, vp_strerror(rc), e->msg);
    return 1;
}

int connect_cli(cli *k, int role)
{
    char err[256];
    k->co.role = role;
    k->co.name = "vantage-cli";
    if (vtc_connect(&k->co, &k->c, err, sizeof err)) {
        fprintf(stderr, "%s: cannot connect: %s\n", g_prog, err);
        return 3;
    }
    return 0;
}

bool parse_vec(const char *s, double *v, int n)
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

bool parse_u64(const char *s, uint64_t *v)
{
    char *end;
    errno = 0;
    bool hex = s[0] == '0' && (s[1] == 'x' || s[1] == 'X');
    unsigned long long x = strtoull(s, &end, hex ? 16 : 10); /* never octal: 010 is ten */
    if (!*s || *end || errno || *s == '-' || *s == '+' || *s == ' ' || (hex && !s[2])) return false;
    *v = x;
    return true;
}

bool parse_size(const char *s, unsigned max, unsigned *w, unsigned *h)
{
    const char *x = strchr(s, 'x');
    if (!x || x - s > 10) return false;
    char a[12];
    memcpy(a, s, (size_t)(x - s));
    a[x - s] = 0;
    uint64_t W, H;
    if (!parse_u64(a, &W) || !parse_u64(x + 1, &H) || !W || !H || W > max || H > max) return false;
    *w = (unsigned)W;
    *h = (unsigned)H;
    return true;
}

bool parse_renderer(const char *s, uint8_t *r)
{
    if (!strcmp(s, "gl")) *r = VP_RENDERER_GL;
    else if (!strcmp(s, "soft")) *r = VP_RENDERER_SOFT;
    else return false;
    return true;
}

int cmp_dbl(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

volatile sig_atomic_t g_stop;
static void on_sigint(int sig)
{
    (void)sig;
    g_stop = 1;
}

void catch_sigint(void)
{
    signal(SIGINT, on_sigint);
}

/* ---- commands ---------------------------------------------------------------- */

void cli_json_str(FILE *f, const char *src, size_t n)
{
    char *buf = malloc(6 * n + 1);
    if (!buf) {
        fputs("\"\"", f);
        return;
    }
    cli_json_escape(buf, src, n);
    fprintf(f, "\"%s\"", buf);
    free(buf);
}

double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + ts.tv_nsec * 1e-9;
}

static int cmd_ping(cli *k, int argc, char **argv)
{
    uint64_t n = 1;
    if (argc == 3 && !strcmp(argv[1], "-c")) {
        if (!parse_u64(argv[2], &n) || !n) return die_usage("ping: -c needs a positive count");
    } else if (argc > 1) {
        return die_usage("ping [-c N]");
    }
    int rc = connect_cli(k, VP_ROLE_VIEWER);
    if (rc) return rc;
    for (uint64_t i = 0; i < n; i++) {
        double t0 = now_s();
        if ((rc = vtc_ping(k->c))) return server_fail(k, "ping", rc);
        if (n == 1) printf("PONG\n");
        else printf("PONG %.1f us\n", (now_s() - t0) * 1e6);
    }
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
    if (!rc && (rc = vtc_remove(k->c, ids, (uint32_t)(argc - 1), &epoch))) rc = server_fail(k, "remove", rc);
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
    if (!rc && (rc = vtc_get(k->c, ids, (uint32_t)(argc - 1), &lr))) rc = server_fail(k, "get", rc);
    for (uint32_t i = 0; !rc && i < lr.batch.count; i++) {
        vp_entity e;
        vp_entity_get(&lr.batch, i, &e);
        cli_entity_json(stdout, &e, true, NULL);
    }
    free(ids);
    return rc;
}

static int cmd_query(cli *k, int argc, char **argv)
{
    double eye[3], at[3], up[3] = {0, 1, 0}, fov = 60, ortho[2] = {0, 0}, znear = 0.1, zfar = 10000;
    bool have_eye = false, have_at = false, have_fov = false, json = false;
    unsigned w = 1920, h = 1080;
    float min_area = 0;
    uint8_t flags = 0;
    static const struct option opts[] = {
        {"eye", 1, 0, 'e'}, {"at", 1, 0, 'a'}, {"up", 1, 0, 'u'}, {"fov", 1, 0, 'f'}, {"ortho", 1, 0, 'o'},
        {"near", 1, 0, 'n'}, {"far", 1, 0, 'F'}, {"size", 1, 0, 's'}, {"min-area", 1, 0, 'm'},
        {"exact-area", 0, 0, 'x'}, {"no-occlusion", 0, 0, 'N'}, {"occ-centre", 0, 0, 'C'}, {"json", 0, 0, 'j'},
        {0, 0, 0, 0}};
    const char *use = "query --eye X,Y,Z --at X,Y,Z [--up X,Y,Z] [--fov DEG | --ortho W,H] [--near N] [--far F] "
                      "[--size WxH] [--min-area PX] [--exact-area] [--no-occlusion | --occ-centre] [--json]";
    optind = 1;
    int o;
    while ((o = getopt_long(argc, argv, "", opts, NULL)) != -1) {
        bool ok = true;
        switch (o) {
        case 'e': ok = have_eye = parse_vec(optarg, eye, 3); break;
        case 'a': ok = have_at = parse_vec(optarg, at, 3); break;
        case 'u': ok = parse_vec(optarg, up, 3); break;
        case 'f': ok = have_fov = parse_vec(optarg, &fov, 1) && fov > 0 && fov < 180; break;
        case 'o': ok = parse_vec(optarg, ortho, 2) && ortho[0] > 0 && ortho[1] > 0; break;
        case 'n': ok = parse_vec(optarg, &znear, 1); break;
        case 'F': ok = parse_vec(optarg, &zfar, 1); break;
        case 's': ok = parse_size(optarg, 65535, &w, &h); break;
        case 'm': {
            double m;
            ok = parse_vec(optarg, &m, 1) && m >= 0;
            min_area = (float)m;
            break;
        }
        case 'x': flags |= VP_Q_WANT_AREA; break;
        case 'N': flags |= VP_Q_NO_OCCLUSION; break;
        case 'C': flags |= VP_Q_OCC_CENTRE; break;
        case 'j': json = true; break;
        default: return die_usage("%s", use);
        }
        if (!ok) {
            static const cli_opt_doc docs[] = {
                {'e', "--eye", "X,Y,Z (three finite numbers)"}, {'a', "--at", "X,Y,Z (three finite numbers)"},
                {'u', "--up", "X,Y,Z (three finite numbers)"},  {'f', "--fov", "degrees, more than 0 and less than 180"},
                {'o', "--ortho", "W,H in metres, both > 0"},    {'n', "--near", "a finite number"},
                {'F', "--far", "a finite number"},              {'s', "--size", "WxH, each 1..65535"},
                {'m', "--min-area", "pixels, >= 0"}};
            return die_bad_opt("query", docs, sizeof docs / sizeof docs[0], o, optarg);
        }
    }
    if (optind != argc) return die_usage("query: unexpected argument %s", argv[optind]);
    if (!have_eye) return die_missing("query", "--eye X,Y,Z", "where the camera is");
    if (!have_at) return die_missing("query", "--at X,Y,Z", "the point the camera looks at");
    if ((flags & VP_Q_NO_OCCLUSION) && (flags & VP_Q_OCC_CENTRE))
        return die_usage("query: --no-occlusion and --occ-centre exclude each other");
    if (have_fov && ortho[0] > 0) return die_usage("query: --fov and --ortho exclude each other");
    vp_view v;
    bool ok = ortho[0] > 0 ? vtc_view_ortho(&v, eye, at, up, ortho[0], ortho[1], (uint16_t)w, (uint16_t)h, znear, zfar)
                           : vtc_view_perspective(&v, eye, at, up, fov, (uint16_t)w, (uint16_t)h, znear, zfar);
    if (!ok) return die_usage("query: degenerate camera (eye == at, up parallel to the view, or near/far)");
    int rc = connect_cli(k, VP_ROLE_VIEWER);
    if (rc) return rc;
    double t0 = now_s();
    vp_vis_result r;
    if ((rc = vtc_query(k->c, &v, 1, flags, min_area, &r))) return server_fail(k, "query", rc);
    double rtt = now_s() - t0;
    if (json) {
        for (uint32_t i = 0; i < r.count; i++) {
            vp_vis_rec x;
            vp_vis_rec_get(&r, i, &x);
            /* the area only where it was measured (--exact-area): the daemon sends -1 otherwise */
            printf("{\"id\": %llu, \"handle\": %u, \"views\": %u, \"class\": %u", (unsigned long long)x.id,
                   x.handle, x.view_mask, x.class_id);
            if (flags & VP_Q_WANT_AREA) printf(", \"area\": %.6g", x.area);
            printf("}\n");
        }
        printf("{\"epoch\": %llu, \"tested\": %u, \"visible\": %u, \"stage_ns\": {\"cull\": %u, "
               "\"occlusion_raster\": %u, \"write\": %u, \"total\": %u, \"setup\": %u}, \"round_trip_us\": %.1f}\n",
               (unsigned long long)r.epoch, r.tested, r.visible, r.stage_ns[1], r.stage_ns[5], r.stage_ns[2],
               r.stage_ns[3], r.stage_ns[4], rtt * 1e6);
    } else {
        printf("%u visible of %u tested at epoch %llu; cull %.1f us (occluder raster %.1f), server total %.1f us, "
               "round trip %.1f us\n",
               r.visible, r.tested, (unsigned long long)r.epoch, r.stage_ns[1] / 1e3, r.stage_ns[5] / 1e3,
               r.stage_ns[3] / 1e3, rtt * 1e6);
        uint32_t show = r.count < 20 ? r.count : 20;
        for (uint32_t i = 0; i < show; i++) {
            vp_vis_rec x;
            vp_vis_rec_get(&r, i, &x);
            printf("  id %-10llu handle %-8u class %-5u", (unsigned long long)x.id, x.handle, x.class_id);
            if (flags & VP_Q_WANT_AREA) printf(" area %.1f", x.area);
            printf("\n");
        }
        if (r.count > show) printf("  ... %u more (--json for all)\n", r.count - show);
    }
    return 0;
}

static int cmd_destroy(cli *k, int argc, char **argv)
{
    const char *use = "destroy ID X,Y,Z RADIUS [--debris N] [--handle H] [--json]";
    vp_destroy m = {0};
    bool json = false;
    if (argc < 4) return die_usage("%s", use);
    if (!parse_u64(argv[1], &m.id)) return die_usage("destroy: bad id %s: expected a 64-bit id (decimal or 0x hex)", argv[1]);
    if (!parse_vec(argv[2], m.center, 3))
        return die_usage("destroy: bad centre %s: expected X,Y,Z (three finite numbers)", argv[2]);
    if (!parse_vec(argv[3], &m.radius, 1) || !(m.radius > 0))
        return die_usage("destroy: bad radius %s: expected metres, more than 0", argv[3]);
    for (int i = 4; i < argc; i++) {
        uint64_t v;
        if (!strcmp(argv[i], "--debris") && i + 1 < argc && parse_u64(argv[i + 1], &v) && v <= VP_MAX_DEBRIS)
            m.debris = (uint8_t)v, i++;
        else if (!strcmp(argv[i], "--handle") && i + 1 < argc && parse_u64(argv[i + 1], &v) && v <= UINT32_MAX)
            m.handle = (uint32_t)v, i++;
        else if (!strcmp(argv[i], "--json"))
            json = true;
        else if (!strcmp(argv[i], "--debris"))
            return die_bad_value("destroy", "--debris", i + 1 < argc ? argv[i + 1] : "(none)", "0..64 entities");
        else if (!strcmp(argv[i], "--handle"))
            return die_bad_value("destroy", "--handle", i + 1 < argc ? argv[i + 1] : "(none)", "a handle, 0..4294967295");
        else
            return die_usage("destroy: unexpected %s; %s", argv[i], use);
    }
    int rc = connect_cli(k, VP_ROLE_EDITOR);
    if (rc) return rc;
    vp_destroyed out;
    if ((rc = vtc_send_destruction(k->c, &m, &out))) return server_fail(k, "destroy", rc);
    if (json)
        printf("{\"id\": %llu, \"epoch\": %llu, \"spheres\": %u, \"occluder_triangles\": %u, \"debris\": %u, "
               "\"cut_us\": %u}\n",
               (unsigned long long)m.id, (unsigned long long)out.epoch, out.spheres, out.occluder_tris, out.debris,
               out.cut_us);
    else
        printf("entity %llu: %u destruction sphere%s, its occluder %u triangles, %u debris; epoch %llu (%u us)\n",
               (unsigned long long)m.id, out.spheres, out.spheres == 1 ? "" : "s", out.occluder_tris, out.debris,
               (unsigned long long)out.epoch, out.cut_us);
    return 0;
}

static int cmd_watch(cli *k, int argc, char **argv)
{
    uint64_t count = UINT64_MAX;
    for (int i = 1; i < argc; i++)
        if (!strncmp(argv[i], "--frames", 8)) return cmd_watch_frames(k, argc, argv);
    bool selection = false;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--selection")) {
            selection = true;
        } else if (!strcmp(argv[i], "--count") && i + 1 < argc) {
            if (!parse_u64(argv[++i], &count) || !count) return die_usage("watch: --count needs a positive count");
        } else {
            return die_usage("watch [--count N] [--selection] | watch --frames DIR ... (watch --frames x --help)");
        }
    }
    int rc = connect_cli(k, VP_ROLE_VIEWER);
    if (rc) return rc;
    if ((rc = vtc_subscribe(k->c, selection ? VP_EVENT_SELECTION : VP_EVENT_SCENE))) return server_fail(k, "watch", rc);
    catch_sigint();
    fprintf(stderr, "watching %s (Ctrl-C to stop)\n", selection ? "the shared selection" : "scene changes");
    for (uint64_t n = 0; !g_stop && n < count;) {
        vp_event ev;
        vp_selected sel;
        rc = selection ? vtc_wait_selected(k->c, &sel, 500) : vtc_wait_event(k->c, &ev, 500);
        if (rc == VTC_ERR_IO && vtc_last_error(k->c)->timed_out) continue;
        if (rc) return server_fail(k, "watch", rc);
        if (selection) {
            /* the first: where it stands when watching starts */
            printf("{\"serial\": %llu, \"client\": %u, \"ids\": [", (unsigned long long)sel.serial, sel.client_id);
            for (uint32_t i = 0; i < sel.count; i++)
                printf("%s%llu", i ? ", " : "", (unsigned long long)vp_id_at(sel.ids, sel.count, i));
            printf("]}\n");
        } else {
            printf("{\"epoch\": %llu, \"added\": %u, \"updated\": %u, \"removed\": %u}\n",
                   (unsigned long long)ev.epoch, ev.added, ev.updated, ev.removed);
        }
        fflush(stdout);
        n++;
    }
    return 0;
}

int main(int argc, char **argv)
{
    cli k = {0};
    static const struct option opts[] = {{"token", 1, 0, 't'}, {"timeout", 1, 0, 'T'}, {"help", 0, 0, 'H'},
                                         {0, 0, 0, 0}};
    int o;
    uint64_t port = VTC_DEFAULT_PORT, to;
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
    if (!k.co.token) k.co.token = getenv("VANTAGE_TOKEN"); /* kept out of the process list */
    /* several daemons (a cluster): -h A:P,B:P,/path or VANTAGE_ENDPOINTS */
    const char *env_eps = getenv("VANTAGE_ENDPOINTS");
    if (k.co.host && strpbrk(k.co.host, ",:/")) k.co.endpoints = k.co.host;
    else if (!k.co.host && !k.co.unix_path && env_eps && *env_eps) k.co.endpoints = env_eps;
    if (optind >= argc) {
        usage(stderr);
        return 2;
    }
    char **av = argv + optind;
    int ac = argc - optind;
    /* COMMAND --help anywhere in its arguments: its own usage, not this one */
    for (int i = 1; i < ac; i++)
        if (!strcmp(av[i], "--help")) {
            for (size_t f = 0; f < sizeof forms / sizeof forms[0]; f++)
                if (!strcmp(forms[f].cmd, av[0])) return command_help(ac, av);
            break;
        }
    static const struct { const char *name; int (*fn)(cli *, int, char **); } cmds[] = {
        {"ping", cmd_ping}, {"stats", cmd_stats}, {"add", cmd_add}, {"move", cmd_move}, {"material", cmd_material}, {"remove", cmd_remove},
        {"get", cmd_get}, {"import", cmd_import}, {"export", cmd_export}, {"query", cmd_query}, {"render", cmd_render}, {"lights", cmd_lights}, {"watch", cmd_watch},
        {"bench", cmd_bench}, {"sublevel", cmd_sublevel}, {"destroy", cmd_destroy}, {"pad", cmd_pad}, {"mark", cmd_mark},
        {"select", cmd_select},
        {"commander", cmdr_main}, {"texture", cmd_texture}, {"env", cmd_env},
    };
    int rc = -1;
    for (size_t i = 0; i < sizeof cmds / sizeof cmds[0]; i++)
        if (!strcmp(av[0], cmds[i].name)) {
            g_cmd = cmds[i].name;
            rc = cmds[i].fn(&k, ac, av);
        }
    if (rc < 0) rc = die_usage("unknown command %s", av[0]);
    vtc_close(k.c);
    return rc;
}
