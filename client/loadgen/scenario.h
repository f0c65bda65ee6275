/*
 * scenario.h — the load-test scenarios of `vantage bench --scenario FILE`:
 * the file format (parsed here, no I/O but reading the file), the camera
 * paths, and the open-loop schedule. The runner is cli_scenario.c.
 *
 * A scenario is lines of words; '#' starts a comment. Top level:
 *
 *   name NAME                      for the report
 *   duration SECONDS               run this long (default 10), or
 *   requests N                     stop after N request/reply operations
 *   warmup SECONDS                 not counted in the tables (default 0)
 *   seed N                         entity placement and camera phases
 *   setup entities N [spread M] [height H]
 *                                  N dynamic boxes the bench adds before the
 *                                  run (its own ids) and removes after:
 *                                  what edits move and destruction hits
 *   probe edit-to-query|edit-to-frame [every SECONDS]
 *                                  end to end: an entity moved into a view
 *                                  of its own, timed until a query / a
 *                                  frame shows it
 *   at SECONDS sublevel load NAME [entities N] [spread M]
 *   at SECONDS sublevel unload NAME
 *   at SECONDS destroy N [rate PER_S] [radius M] [debris K]
 *                                  scripted events on their own connection
 *   group NAME                     starts a group of identical clients:
 *     role editor|viewer|commander|query    (query: a viewer that only queries)
 *     clients N
 *     op query [views K] [count-only] [no-occlusion]
 *     op edit [batch B]            ENTITY_UPDATE of B entities of its own
 *     op ping
 *     op frames [size WxH] [fps F] [quality Q] [format jpeg|raw] [renderer soft|gl]
 *                                  a frame subscription (latest-frame-wins)
 *     op commander [size WxH] [fps F] [quality Q] [reaim HZ]
 *                                  frames, re-aimed along the camera path at
 *                                  HZ: input -> frame latency by view_seq
 *     rate PER_S                   open loop: requests at fixed times per
 *                                  client, latency from the intended time
 *                                  (no coordinated omission); without it,
 *     pipeline P                   closed loop with P requests in flight
 *     camera fixed EYE AT | orbit CENTER RADIUS HEIGHT PERIOD |
 *            path PERIOD P1 P2 ... | pan CENTER RADIUS HEIGHT PERIOD
 *                                  (points x,y,z; pan: top-down orthographic)
 */
#ifndef VANTAGE_SCENARIO_H
#define VANTAGE_SCENARIO_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

enum scn_op { SCN_QUERY, SCN_EDIT, SCN_PING, SCN_FRAMES, SCN_COMMANDER };
enum scn_role { SCN_ROLE_VIEWER, SCN_ROLE_COMMANDER, SCN_ROLE_EDITOR, SCN_ROLE_QUERY };
enum scn_cam { SCN_CAM_FIXED, SCN_CAM_ORBIT, SCN_CAM_PATH, SCN_CAM_PAN };
enum scn_ev { SCN_EV_LOAD, SCN_EV_UNLOAD, SCN_EV_DESTROY };

#define SCN_MAX_GROUPS 16
#define SCN_MAX_EVENTS 64
#define SCN_MAX_PATH 32

typedef struct scn_camera {
    enum scn_cam kind;
    double a[3], b[3];        /* fixed: eye, at; orbit/pan: center */
    double radius, height, period;
    double pts[SCN_MAX_PATH][3];
    int npts;
} scn_camera;

typedef struct scn_group {
    char name[32];
    int line;                 /* where it starts, for messages */
    enum scn_role role;
    enum scn_op op;
    bool have_op;
    uint32_t clients;
    double rate;              /* per client; 0: closed loop */
    uint32_t pipeline;        /* closed loop: in flight per client */
    uint32_t batch, views;
    uint8_t qflags;           /* VP_Q_* */
    uint16_t w, h, fps;
    uint8_t format, quality, renderer;
    double reaim_hz;
    scn_camera cam;
} scn_group;

typedef struct scn_event {
    int line;
    enum scn_ev kind;
    double at;                /* seconds from the start */
    char name[64];            /* sub-level */
    uint32_t n;               /* entities (load) or destruction events */
    double spread, rate, radius;
    uint8_t debris;
} scn_event;

typedef struct scenario {
    char name[64];
    double duration, warmup;
    uint64_t requests;        /* 0: run for duration */
    uint64_t seed;
    uint32_t setup_n;
    double setup_spread, setup_height;
    double probe_query, probe_frame; /* periods in seconds; 0: off */
    scn_group g[SCN_MAX_GROUPS];
    int ng;
    scn_event ev[SCN_MAX_EVENTS];
    int nev;
} scenario;

/* Parses text (n bytes; name is used in messages). 0, or -1 with
 * "NAME:LINE: field 'F': what is wrong" in err. */
int scn_parse(const char *name, const char *text, size_t n, scenario *s, char *err, size_t errlen);
/* Reads and parses a file. */
int scn_load(const char *path, scenario *s, char *err, size_t errlen);

/* The camera at time t (seconds) for client number phase of nphase: eye
 * and target, and whether it is the orthographic top-down kind. */
void scn_camera_at(const scn_camera *c, double t, int phase, int nphase, double eye[3], double at[3]);

/* The open-loop schedule: request k is due at t0 + k period. due() says how
 * many requests are due at now (sending them moves next on); each one's
 * intended time is t0 + k period, from which its latency counts, however
 * late the sender got to it. */
typedef struct scn_sched {
    double t0, period;
    uint64_t next;
} scn_sched;
void scn_sched_init(scn_sched *s, double t0, double rate);
uint64_t scn_sched_due(const scn_sched *s, double now);
double scn_sched_time(const scn_sched *s, uint64_t k);

const char *scn_op_name(enum scn_op op);

#endif
