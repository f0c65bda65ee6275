/*
 * test_persist.c — vantaged --data-dir end to end: the scene restored
 * exactly after kill -9 (compared with a daemon that never crashed and got
 * the same edits), acknowledged edits surviving 20 kill -9 cycles under a
 * stream of pipelined edits (policy always), a damaged journal tail cut and
 * reported, and a write error (RLIMIT_FSIZE: the kernel refuses the write)
 * refusing edits while queries go on.
 */
#include "test_daemon.h"
#include "test_util.h"

#include <dirent.h>
#include <errno.h>
#include <math.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <poll.h>
#include <pthread.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

/* ---- helpers ----------------------------------------------------------------------- */

static void start_dd(daemon_proc *d, const char *dir, const char *policy, const char *compact_mb)
{
    const char *extra[] = {"--data-dir", dir, "--durability", policy, "--compact-mb", compact_mb, NULL};
    daemon_start_args(d, extra);
}

/* start_dd with the snapshot child held back delay_ms first (a snapshot
 * that ends while the daemon is idle, or outlives it) */
static void start_dd_slow_snapshot(daemon_proc *d, const char *dir, const char *delay_ms)
{
    setenv("VANTAGED_SNAPSHOT_DELAY_MS", delay_ms, 1);
    start_dd(d, dir, "always", "1");
    unsetenv("VANTAGED_SNAPSHOT_DELAY_MS");
}

/* A temporary directory named prefix.*, and dir = its "data" (the
 * daemon's --data-dir, made by the daemon). */
static void data_dir_make(tdir *td, const char *prefix, char dir[320])
{
    tdir_make(td, prefix);
    snprintf(dir, 320, "%s", tdir_file(td, "data"));
}

static void kill9(daemon_proc *d)
{
    kill(d->pid, SIGKILL);
    int st;
    waitpid(d->pid, &st, 0);
    assert_true(WIFSIGNALED(st));
    unlink(d->sock);
}

static vp_entity ent(uint64_t id, double x, double z, double r, uint16_t sub, uint16_t cls)
{
    return (vp_entity){.id = id, .class_id = cls, .sublevel = sub, .sphere = {x, r, z, r}};
}

/* What a client can see of a scene. */
typedef struct dump {
    vp_entity *e;
    uint32_t n;
    uint64_t epoch;
    char sl[4096];      /* sub-level infos, as text */
    uint64_t vis[3][4]; /* per view: records, sum of ids, xor of handles, sum of masks */
    uint64_t lights[2]; /* a light query: per tile, its light ids summed and xor'ed (order-free) */
    float *px;          /* a RAW software render (meshes, destruction, lights): RGBA + depth */
    uint32_t npx;
} dump;

static int cmp_ent(const void *a, const void *b)
{
    const vp_entity *x = a, *y = b;
    return (x->id > y->id) - (x->id < y->id);
}

/* take_dump adds a light query and a render (the every-point test) */
static bool full_dumps;

static void take_dump(vtc_client *c, dump *out)
{
    memset(out, 0, sizeof *out);
    uint32_t cap = 1024;
    out->e = malloc(cap * sizeof *out->e);
    uint64_t cur = 0;
    do {
        vp_list_reply lr;
        assert_int_equal(vtc_list(c, cur, 4096, &lr), VP_OK);
        for (uint32_t i = 0; i < lr.batch.count; i++) {
            if (out->n == cap) out->e = realloc(out->e, (cap *= 2) * sizeof *out->e);
            vp_entity_get(&lr.batch, i, &out->e[out->n++]);
        }
        cur = lr.next_cursor;
    } while (cur);
    qsort(out->e, out->n, sizeof *out->e, cmp_ent);
    vp_stats_reply st;
    assert_int_equal(vtc_stats(c, &st), VP_OK);
    out->epoch = st.epoch;
    vp_sublevel_infos li;
    assert_int_equal(vtc_sublevel_info(c, &li), VP_OK);
    size_t pos = 0, k = 0;
    vp_sublevel_info in;
    while (vp_sublevel_info_next(&li, &pos, &in) && k < sizeof out->sl - 128)
        k += (size_t)snprintf(out->sl + k, sizeof out->sl - k, "%u %.*s st%u e%u o%u l%u c%u+%u; ", in.id,
                              (int)in.name_len, (const char *)in.name, in.state, in.entities, in.occluders,
                              in.lights, in.class_base, in.classes);
    const double eyes[3][3] = {{0, 5, -120}, {80, 40, 80}, {-30, 2, 10}};
    for (int v = 0; v < 3; v++) {
        vp_view view;
        assert_true(vtc_view_perspective(&view, eyes[v], (double[]){0, 0, 0}, NULL, 70, 256, 114, 0.1, 1000));
        vp_vis_result res;
        assert_int_equal(vtc_query(c, &view, 1, 0, 0, &res), VP_OK);
        out->vis[v][0] = res.count;
        for (uint32_t i = 0; i < res.count; i++) {
            vp_vis_rec x;
            vp_vis_rec_get(&res, i, &x);
            out->vis[v][1] += x.id;
            out->vis[v][2] ^= x.handle;
            out->vis[v][3] += x.view_mask;
        }
    }
    if (!full_dumps) return;
    vp_light_query lq = {.flags = 0};
    assert_true(vtc_view_perspective(&lq.view, eyes[0], (double[]){0, 0, 0}, NULL, 70, 256, 144, 0.1, 1000));
    vp_light_tiles lt;
    assert_int_equal(vtc_light_query(c, &lq, &lt), VP_OK);
    uint32_t ntiles = (uint32_t)lt.tiles_x * lt.tiles_y;
    for (uint32_t t = 0; t < ntiles; t++) {
        uint32_t a, b;
        memcpy(&a, lt.offsets + 4 * t, 4);
        memcpy(&b, lt.offsets + 4 * (t + 1), 4);
        for (uint32_t q = a; q < b; q++) {
            uint64_t id;
            memcpy(&id, lt.ids + 8 * q, 8);
            out->lights[0] += id * (t + 1);
            out->lights[1] ^= id << (t % 13);
        }
    }
    vp_render rm = {.format = VP_FRAME_RAW, .renderer = VP_RENDERER_SOFT};
    assert_true(vtc_view_perspective(&rm.view, (double[]){0, 8, -40}, (double[]){0, 2, 0}, NULL, 60, 96, 64, 0.1, 500));
    vp_frame f;
    assert_int_equal(vtc_render(c, &rm, &f), VP_OK);
    out->npx = (uint32_t)f.width * f.height * 5;
    assert_int_equal(f.data_len, out->npx * 4);
    out->px = malloc(f.data_len);
    memcpy(out->px, f.data, f.data_len);
}

static bool ent_eq(const vp_entity *a, const vp_entity *b)
{
    return a->id == b->id && a->handle == b->handle && a->class_id == b->class_id && a->sublevel == b->sublevel &&
           a->flags == b->flags && !memcmp(a->sphere, b->sphere, sizeof a->sphere) &&
           !memcmp(a->aabb, b->aabb, sizeof a->aabb);
}

/* A record as sent (no AABB: the daemon derives it) against as stored. */
static bool sent_eq(const vp_entity *stored, const vp_entity *sent)
{
    return stored->id == sent->id && stored->class_id == sent->class_id && stored->sublevel == sent->sublevel &&
           stored->flags == sent->flags && !memcmp(stored->sphere, sent->sphere, sizeof sent->sphere);
}

static void assert_same(const dump *a, const dump *b)
{
    assert_int_equal(a->n, b->n);
    for (uint32_t i = 0; i < a->n; i++)
        if (!ent_eq(&a->e[i], &b->e[i]))
            fail_msg("entity %u differs: id %llu handle %u vs id %llu handle %u", i, (unsigned long long)a->e[i].id,
                     a->e[i].handle, (unsigned long long)b->e[i].id, b->e[i].handle);
    assert_int_equal(a->epoch, b->epoch);
    assert_string_equal(a->sl, b->sl);
    assert_memory_equal(a->vis, b->vis, sizeof a->vis);
    assert_memory_equal(a->lights, b->lights, sizeof a->lights);
    assert_int_equal(a->npx, b->npx);
    /* (lights are summed in the daemon's order, which a restore may change:
       a last-bit difference is not a different scene) */
    for (uint32_t i = 0; i < a->npx; i++)
        if (!(fabsf(a->px[i] - b->px[i]) <= 1e-4f * (1 + fabsf(a->px[i]))) && !(isinf(a->px[i]) && a->px[i] == b->px[i]))
            fail_msg("rendered value %u differs: %g vs %g", i, a->px[i], b->px[i]);
}

static void dump_free(dump *d)
{
    free(d->e);
    free(d->px);
}

/* Removes a data directory (its files, then it). */
static void rm_data(const char *dir)
{
    dir_unlink_files(dir);
    rmdir(dir);
}

static bool has_file(const char *dir, const char *prefix)
{
    DIR *d = opendir(dir);
    bool found = false;
    struct dirent *e;
    while (d && (e = readdir(d)))
        if (!strncmp(e->d_name, prefix, strlen(prefix))) found = true;
    if (d) closedir(d);
    return found;
}

/* ---- the same edits to two daemons ------------------------------------------------------ */

static void add_many(vtc_client *c, uint64_t first, uint32_t n, uint16_t sub, uint32_t *handles)
{
    vp_entity *e = malloc(n * sizeof *e);
    for (uint32_t i = 0; i < n; i++)
        e[i] = ent(first + i, (double)(i % 200) * 3 - 300, (double)(i / 200) * 3 - 150, 0.5 + (i % 7) * 0.1, sub,
                   (uint16_t)(1 + i % 3));
    assert_int_equal(vtc_add(c, e, n, handles, NULL), VP_OK);
    free(e);
}

/* Part one of the script: entities (some removed, so the free list has
 * holes), meshes, occluders, lights, a committed sub-level, a destruction. */
static void script_a(vtc_client *c, uint32_t *handles)
{
    add_many(c, 1, 12000, 0, handles);
    uint64_t gone[500];
    for (int i = 0; i < 500; i++) gone[i] = 1 + (uint64_t)i * 23;
    assert_int_equal(vtc_remove(c, gone, 500, NULL), VP_OK);
    vp_entity up[50];
    for (int i = 0; i < 50; i++) up[i] = ent(2 + (uint64_t)i * 23, i, 40, 2.5, 0, 2);
    assert_int_equal(vtc_update(c, up, 50, NULL), VP_OK);
    float pos[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0}, nrm[9] = {0, 0, 1, 0, 0, 1, 0, 0, 1};
    uint32_t idx[3] = {0, 1, 2};
    assert_int_equal(vtc_put_mesh(c, 1, pos, nrm, 3, idx, 3), VP_OK);
    /* a wall, its occluder, and a destruction in it */
    vp_entity wall = {.id = 900000, .aabb = {-20, 0, -1, 20, 10, 1}};
    assert_int_equal(vtc_add(c, &wall, 1, NULL, NULL), VP_OK);
    float quad[18] = {0, 0, 0, 40, 0, 0, 40, 10, 0, 0, 0, 0, 40, 10, 0, 0, 10, 0};
    assert_int_equal(vtc_put_occluder(c, 900000, (double[]){-20, 0, 0}, quad, 2), VP_OK);
    vp_light l[3];
    for (int i = 0; i < 3; i++)
        l[i] = (vp_light){.id = 70 + (uint64_t)i, .kind = VP_LIGHT_POINT, .pos = {i * 10.0, 5, 0}, .color = {1, 1, 1},
                          .intensity = 100, .range = 20};
    assert_int_equal(vtc_put_lights(c, l, 3), VP_OK);
    vp_sublevel_begun b;
    assert_int_equal(vtc_sublevel_begin(c, "town", 2, &b), VP_OK);
    add_many(c, 500000, 3000, 0, NULL);
    assert_int_equal(vtc_put_mesh(c, b.class_base, pos, nrm, 3, idx, 3), VP_OK);
    vp_ack ack;
    assert_int_equal(vtc_sublevel_commit(c, &ack), VP_OK);
    vp_destroyed dd;
    assert_int_equal(vtc_send_destruction(c, &(vp_destroy){.id = 900000, .debris = 6, .center = {0, 5, 0}, .radius = 3}, &dd),
                     VP_OK);
}

/* Part two, after a snapshot: more of everything, a second sub-level
 * loaded, and one unload left running. */
static void script_b(vtc_client *c)
{
    add_many(c, 20000, 4000, 0, NULL);
    uint64_t gone[300];
    for (int i = 0; i < 300; i++) gone[i] = 20000 + (uint64_t)i * 7;
    assert_int_equal(vtc_remove(c, gone, 300, NULL), VP_OK);
    vp_destroyed dd;
    assert_int_equal(vtc_send_destruction(c, &(vp_destroy){.id = 900000, .debris = 2, .center = {8, 3, 0}, .radius = 2}, &dd),
                     VP_OK);
    vp_sublevel_begun b;
    assert_int_equal(vtc_sublevel_begin(c, "harbour", 1, &b), VP_OK);
    add_many(c, 600000, 5000, 0, NULL);
    vp_ack ack;
    assert_int_equal(vtc_sublevel_commit(c, &ack), VP_OK);
    assert_int_equal(vtc_sublevel_unload(c, "town", &ack), VP_OK);
}

/* Waits until no sub-level is unloading. */
static void settle(vtc_client *c)
{
    for (int i = 0; i < 500; i++) {
        vp_sublevel_infos li;
        assert_int_equal(vtc_sublevel_info(c, &li), VP_OK);
        size_t pos = 0;
        vp_sublevel_info in;
        bool busy = false;
        while (vp_sublevel_info_next(&li, &pos, &in)) busy |= in.state == VP_SL_UNLOADING;
        if (!busy) return;
        usleep(10000);
    }
    fail_msg("an unload did not finish");
}

static void test_persist_restore_exact(void **state)
{
    (void)state;
    tdir td;
    char dir[320];
    data_dir_make(&td, "persist", dir);
    daemon_proc a, ref;
    start_dd(&a, dir, "always", "1"); /* a snapshot once the journal passes 1 MB */
    daemon_start(&ref, NULL);
    vtc_client *ca = connect_role(&a, VP_ROLE_EDITOR, true), *cr = connect_role(&ref, VP_ROLE_EDITOR, true);
    uint32_t *ha = malloc(12000 * sizeof *ha), *hr = malloc(12000 * sizeof *hr);
    script_a(ca, ha);
    script_a(cr, hr);
    assert_memory_equal(ha, hr, 12000 * sizeof *ha);
    /* the journal passed 1 MB: a snapshot is written by a child, fsync'ed
       (slow on this shared disk at times), and put in place when the child
       ends, even if this client sends nothing more (see
       test_persist_snapshot_while_idle): the wait is a liveness bound */
    int waited = 0;
    for (; waited < 2000 && !has_file(dir, "snapshot.000002"); waited++) usleep(10000);
    if (waited > 300) print_message("persist: the snapshot took %.1f s to appear\n", waited / 100.0);
    assert_true(has_file(dir, "snapshot.000002"));
    script_b(ca);
    script_b(cr);
    /* a load left open by a client that is then killed with the daemon */
    vtc_client *la = connect_role(&a, VP_ROLE_EDITOR, true), *lr = connect_role(&ref, VP_ROLE_EDITOR, true);
    vp_sublevel_begun b;
    assert_int_equal(vtc_sublevel_begin(la, "limbo", 0, &b), VP_OK);
    assert_int_equal(vtc_sublevel_begin(lr, "limbo", 0, &b), VP_OK);
    add_many(la, 800000, 100, 0, NULL);
    add_many(lr, 800000, 100, 0, NULL);
    kill9(&a);
    vtc_close(ca);
    vtc_close(la);
    vtc_close(lr); /* the reference drops its load as the restart does */
    struct timespec t0, t1;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    start_dd(&a, dir, "always", "1");
    clock_gettime(CLOCK_MONOTONIC, &t1);
    ca = connect_role(&a, VP_ROLE_EDITOR, true);
    settle(ca);
    settle(cr);
    dump da, dr;
    take_dump(ca, &da);
    take_dump(cr, &dr);
    printf("persist: %u entities restored exactly after kill -9 (snapshot + journal), daemon up in %.0f ms\n", da.n,
           (t1.tv_sec - t0.tv_sec) * 1e3 + (t1.tv_nsec - t0.tv_nsec) / 1e6);
    assert_same(&da, &dr);
    /* the next handles handed out are the same too */
    add_many(ca, 700000, 1000, 0, ha);
    add_many(cr, 700000, 1000, 0, hr);
    assert_memory_equal(ha, hr, 1000 * sizeof *ha);
    free(da.e);
    free(dr.e);
    /* and a clean stop + start restores the same again */
    take_dump(ca, &dr);
    vtc_close(ca);
    daemon_stop(&a);
    start_dd(&a, dir, "everysec", "1");
    ca = connect_role(&a, VP_ROLE_EDITOR, true);
    take_dump(ca, &da);
    assert_same(&da, &dr);
    free(da.e);
    free(dr.e);
    free(ha);
    free(hr);
    vtc_close(ca);
    vtc_close(cr);
    daemon_stop(&a);
    daemon_stop(&ref);
    rm_data(dir);
    tdir_remove(&td);
}

/* Issue 18, item 2, as it was found: one sub-level name defined, entities
 * added until a compaction snapshot is written, a clean stop, a restart.
 * The restart refused ("snapshot: body CRC mismatch") for every snapshot
 * holding a sub-level with no members; now it restores the same scene. */
static void test_persist_snapshot_with_sublevel_name(void **state)
{
    (void)state;
    tdir td;
    char dir[320];
    data_dir_make(&td, "persist-slname", dir);
    daemon_proc a;
    start_dd(&a, dir, "always", "1");
    vtc_client *c = connect_role(&a, VP_ROLE_EDITOR, true);
    const char *names[1] = {"alpha"};
    uint16_t id;
    assert_int_equal(vtc_sublevel_ids(c, names, 1, &id), VP_OK);
    for (uint32_t k = 0; k < 5 && !has_file(dir, "snapshot."); k++) add_many(c, 1 + k * 4000, 4000, 0, NULL);
    for (int waited = 0; waited < 2000 && !has_file(dir, "snapshot.000002"); waited++) usleep(10000);
    assert_true(has_file(dir, "snapshot.000002"));
    dump before, after;
    take_dump(c, &before);
    vtc_close(c);
    daemon_stop(&a);
    start_dd(&a, dir, "always", "1");
    c = connect_role(&a, VP_ROLE_EDITOR, true);
    take_dump(c, &after);
    assert_same(&before, &after);
    free(before.e);
    free(after.e);
    vtc_close(c);
    daemon_stop(&a);
    rm_data(dir);
    tdir_remove(&td);
}

/* ---- a snapshot at every point ------------------------------------------------------------------ */

typedef struct side {
    vtc_client *ed, *ld; /* an editor, and a second editor that loads sub-levels */
    uint16_t class_base;
} side;

#define STEPS 21

/* Step i of a session touching every kind of state. */
static void step(side *s, int i)
{
    float pos[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0}, nrm[9] = {0, 0, 1, 0, 0, 1, 0, 0, 1};
    uint32_t idx[3] = {0, 1, 2};
    float quad[18] = {0, 0, 0, 40, 0, 0, 40, 10, 0, 0, 0, 0, 40, 10, 0, 0, 10, 0};
    vp_ack ack;
    vp_sublevel_begun b;
    vp_destroyed dd;
    switch (i) {
    case 0: {
        const char *names[2] = {"alpha", "beta"};
        uint16_t ids[2];
        assert_int_equal(vtc_sublevel_ids(s->ed, names, 2, ids), VP_OK);
        break;
    }
    case 1: add_many(s->ed, 1, 600, 0, NULL); break;
    case 2: {
        uint64_t gone[40];
        for (int k = 0; k < 40; k++) gone[k] = 1 + (uint64_t)k * 13;
        assert_int_equal(vtc_remove(s->ed, gone, 40, NULL), VP_OK);
        break;
    }
    case 3: {
        vp_entity up[10];
        for (int k = 0; k < 10; k++) up[k] = ent(3 + (uint64_t)k * 13, k, 30, 2.5, 0, 2);
        assert_int_equal(vtc_update(s->ed, up, 10, NULL), VP_OK);
        break;
    }
    case 4: assert_int_equal(vtc_put_mesh(s->ed, 1, pos, nrm, 3, idx, 3), VP_OK); break;
    case 5: {
        vp_entity wall = {.id = 900000, .aabb = {-20, 0, -1, 20, 10, 1}};
        assert_int_equal(vtc_add(s->ed, &wall, 1, NULL, NULL), VP_OK);
        assert_int_equal(vtc_put_occluder(s->ed, 900000, (double[]){-20, 0, 0}, quad, 2), VP_OK);
        break;
    }
    case 6: {
        vp_light l[3];
        for (int k = 0; k < 3; k++)
            l[k] = (vp_light){.id = 70 + (uint64_t)k, .kind = VP_LIGHT_POINT, .pos = {k * 10.0 - 10, 5, -5},
                              .color = {1, 1, 1}, .intensity = 100, .range = 30};
        assert_int_equal(vtc_put_lights(s->ed, l, 3), VP_OK);
        break;
    }
    case 7: {
        uint64_t id = 71;
        vp_writer w;
        uint8_t buf[64];
        vp_writer_init(&w, buf, sizeof buf);
        vp_enc_ids(&w, VP_LIGHT_REMOVE, 1, &id, 1);
        vp_header h;
        const uint8_t *p;
        assert_int_equal(vtc_send(s->ed, buf, w.len), 0);
        assert_int_equal(vtc_recv(s->ed, &h, &p, 5000), 0);
        assert_int_equal(h.type, VP_ACK);
        break;
    }
    case 8:
        assert_int_equal(vtc_sublevel_begin(s->ld, "town", 2, &b), VP_OK);
        s->class_base = b.class_base;
        break;
    case 9: add_many(s->ld, 500000, 300, 0, NULL); break;
    case 10: assert_int_equal(vtc_put_mesh(s->ld, s->class_base, pos, nrm, 3, idx, 3), VP_OK); break;
    case 11: {
        assert_int_equal(vtc_put_occluder(s->ld, 500001, (double[]){30, 0, 5}, quad, 2), VP_OK);
        vp_light l = {.id = 80, .kind = VP_LIGHT_SPOT, .pos = {0, 8, -8}, .dir = {0, -1, 0}, .color = {1, 0.5f, 0.2f},
                      .intensity = 80, .range = 25, .inner_cos = 0.9f, .outer_cos = 0.7f};
        assert_int_equal(vtc_put_lights(s->ld, &l, 1), VP_OK);
        break;
    }
    case 12: assert_int_equal(vtc_sublevel_commit(s->ld, &ack), VP_OK); break;
    case 13:
        assert_int_equal(vtc_send_destruction(s->ed, &(vp_destroy){.id = 900000, .debris = 4, .center = {0, 5, 0}, .radius = 3},
                                    &dd),
                         VP_OK);
        break;
    case 14: assert_int_equal(vtc_remove_occluders(s->ed, (uint64_t[]){500001}, 1, NULL), VP_OK); break;
    case 15:
        assert_int_equal(vtc_sublevel_begin(s->ld, "harbour", 0, &b), VP_OK);
        add_many(s->ld, 600000, 200, 0, NULL);
        break;
    case 16: assert_int_equal(vtc_sublevel_commit(s->ld, &ack), VP_OK); break;
    case 17: assert_int_equal(vtc_sublevel_unload(s->ed, "town", &ack), VP_OK); break;
    case 18: add_many(s->ed, 20000, 300, 1, NULL); break;
    case 19:
        assert_int_equal(vtc_send_destruction(s->ed, &(vp_destroy){.id = 900000, .debris = 0, .center = {8, 3, 0}, .radius = 2},
                                    &dd),
                         VP_OK);
        break;
    case 20:
        assert_int_equal(vtc_sublevel_begin(s->ld, "limbo", 1, &b), VP_OK);
        add_many(s->ld, 800000, 50, 0, NULL);
        break;
    }
}

/* The newest journal holds no record and its snapshot is in place: dir's
 * scene is all in snapshot.<gen>. */
static bool all_in_snapshot(const char *dir, unsigned *gen)
{
    DIR *d = opendir(dir);
    struct dirent *e;
    unsigned g = 0, v;
    bool tmp = false;
    while (d && (e = readdir(d))) {
        tmp |= !strncmp(e->d_name, "snapshot.tmp", 12);
        int end = 0;
        if (sscanf(e->d_name, "journal.%u%n", &v, &end) == 1 && !e->d_name[end] && v > g) g = v;
    }
    if (d) closedir(d);
    char p[400];
    struct stat st;
    snprintf(p, sizeof p, "%s/journal.%06u", dir, g);
    if (tmp || !g || stat(p, &st) || st.st_size != 32) return false;
    snprintf(p, sizeof p, "%s/snapshot.%06u", dir, g);
    *gen = g;
    return !stat(p, &st);
}

static void copy_file(const char *from, const char *to)
{
    int in = open(from, O_RDONLY), out = open(to, O_WRONLY | O_CREAT | O_TRUNC, 0600);
    assert_true(in >= 0 && out >= 0);
    char buf[65536];
    ssize_t n;
    while ((n = read(in, buf, sizeof buf)) > 0) assert_int_equal(write(out, buf, (size_t)n), n);
    close(in);
    close(out);
}

/* Snapshot-then-restore is exact for every kind of state: a daemon that
 * snapshots after every turn with an edit (VANTAGED_SNAPSHOT_EACH_TURN)
 * runs a session of 21 steps (sub-level names, entities with holes in the
 * handle table, updates, meshes, occluders, lights, a light removed, a
 * load with classes, a mesh, an occluder and a light in it, committed, a
 * destruction, an occluder removed, an unload, a load left open). After
 * each step, once the whole scene is in a snapshot (the journal after it
 * empty), a second daemon starts from a copy of those two files alone; it
 * must serve what a daemon that never crashed serves after the same steps
 * and its open load dropped: entities and handles, the epoch, sub-levels
 * (states, counts, classes), visibility with occlusion, the lights per
 * tile, a software render, and the next handles handed out. */
static void test_persist_snapshot_every_point(void **state)
{
    (void)state;
    tdir td, tc;
    char dir[320], cdir[320];
    data_dir_make(&td, "persist-every", dir);
    data_dir_make(&tc, "persist-every-copy", cdir);
    full_dumps = true;
    daemon_proc a;
    setenv("VANTAGED_SNAPSHOT_EACH_TURN", "1", 1);
    start_dd(&a, dir, "always", "64");
    unsetenv("VANTAGED_SNAPSHOT_EACH_TURN");
    side sa = {connect_role(&a, VP_ROLE_EDITOR, true), connect_role(&a, VP_ROLE_EDITOR, true), 0};
    uint32_t ha[100], hr[100];
    unsigned snaps = 0;
    for (int i = 0; i < STEPS; i++) {
        step(&sa, i);
        unsigned gen = 0;
        int waited = 0;
        for (; waited < 2000 && !all_in_snapshot(dir, &gen); waited++) usleep(5000);
        if (!gen) fail_msg("step %d: no snapshot holds the whole scene after 10 s", i);
        snaps++;
        /* a daemon on the snapshot alone */
        char from[400], to[400];
        mkdir(cdir, 0700);
        snprintf(from, sizeof from, "%s/snapshot.%06u", dir, gen);
        snprintf(to, sizeof to, "%s/snapshot.%06u", cdir, gen);
        copy_file(from, to);
        snprintf(from, sizeof from, "%s/journal.%06u", dir, gen);
        snprintf(to, sizeof to, "%s/journal.%06u", cdir, gen);
        copy_file(from, to);
        daemon_proc c, ref;
        start_dd(&c, cdir, "off", "64");
        daemon_start(&ref, NULL);
        side sr = {connect_role(&ref, VP_ROLE_EDITOR, true), connect_role(&ref, VP_ROLE_EDITOR, true), 0};
        for (int k = 0; k <= i; k++) step(&sr, k);
        vtc_close(sr.ld); /* a load left open is dropped, as the restart drops it */
        vtc_client *cc = connect_role(&c, VP_ROLE_EDITOR, true);
        settle(cc);
        settle(sr.ed);
        dump dc, dr;
        take_dump(cc, &dc);
        take_dump(sr.ed, &dr);
        if (dc.n != dr.n || dc.epoch != dr.epoch || strcmp(dc.sl, dr.sl))
            fail_msg("step %d: restored %u entities, epoch %llu, sub-levels %s; the reference %u, %llu, %s", i, dc.n,
                     (unsigned long long)dc.epoch, dc.sl, dr.n, (unsigned long long)dr.epoch, dr.sl);
        assert_same(&dc, &dr);
        if (i == STEPS - 1) { /* the lights and the render see something */
            uint32_t lit = 0;
            for (uint32_t k = 0; k < dr.npx / 5; k++) lit += dr.px[4 * k] > 0;
            assert_true(dr.lights[0] != 0 && lit > 100);
        }
        add_many(cc, 990000, 100, 0, ha);
        add_many(sr.ed, 990000, 100, 0, hr);
        assert_memory_equal(ha, hr, sizeof ha);
        dump_free(&dc);
        dump_free(&dr);
        vtc_close(cc);
        vtc_close(sr.ed);
        daemon_stop(&c);
        daemon_stop(&ref);
        rm_data(cdir);
    }
    printf("persist: %u snapshots, one after each step of the session, each restored exactly\n", snaps);
    full_dumps = false;
    vtc_close(sa.ed);
    vtc_close(sa.ld);
    daemon_stop(&a);
    rm_data(dir);
    tdir_remove(&td);
    tdir_remove(&tc);
}

/* ---- kill -9 under a stream of edits ------------------------------------------------------- */

typedef struct sent_rec {
    vp_entity e;
    bool acked;
} sent_rec;

/* Pipelines single-record ENTITY_ADDs (window 128) for ms milliseconds or
 * until the connection dies; returns the records sent (acked marked). */
static uint32_t stream_adds(vtc_client *c, uint64_t first, sent_rec *out, uint32_t max, int ms, double *rate)
{
    struct timespec t0, t;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    uint32_t sent = 0, acked = 0;
    uint8_t buf[VP_HEADER_SIZE + 4 + VP_ENTITY_REC_SIZE];
    bool dead = false;
    for (;;) {
        clock_gettime(CLOCK_MONOTONIC, &t);
        double el = (t.tv_sec - t0.tv_sec) * 1e3 + (t.tv_nsec - t0.tv_nsec) / 1e6;
        bool more = el < ms && sent < max && !dead;
        if (!more && acked == sent) break;
        while (more && sent - acked < 128 && sent < max) {
            out[sent].e = ent(first + sent, (double)(sent % 300), (double)(sent / 300), 0.75, 0, 1);
            out[sent].acked = false;
            vp_writer w;
            vp_writer_init(&w, buf, sizeof buf);
            vp_enc_entities(&w, VP_ENTITY_ADD, sent + 1, &out[sent].e, 1);
            if (vtc_send(c, buf, w.len)) {
                dead = true;
                break;
            }
            sent++;
        }
        if (dead) break;
        vp_header h;
        const uint8_t *p;
        int rc = vtc_recv(c, &h, &p, 2000);
        if (rc) break; /* the daemon is gone: what was not acked is unknown */
        assert_int_equal(h.type, VP_ENTITY_ADD_REPLY);
        assert_true(h.req >= 1 && h.req <= sent);
        out[h.req - 1].acked = true;
        acked++;
    }
    clock_gettime(CLOCK_MONOTONIC, &t);
    double el = (t.tv_sec - t0.tv_sec) + (t.tv_nsec - t0.tv_nsec) / 1e9;
    *rate = acked / el;
    return sent;
}

typedef struct killer {
    pid_t pid;
    int after_ms;
} killer;

static void *killer_main(void *arg)
{
    killer *k = arg;
    usleep((useconds_t)k->after_ms * 1000);
    kill(k->pid, SIGKILL);
    return NULL;
}

static void test_persist_kill9_keeps_acked(void **state)
{
    (void)state;
    tdir td;
    char dir[320];
    data_dir_make(&td, "persist-kill", dir);
    const uint32_t max = 200000;
    sent_rec *recs = malloc(max * sizeof *recs);
    uint64_t seed = 0x5eed2011;
    uint32_t total_acked = 0, total_unacked_present = 0, total_unacked = 0;
    double rates[20];
    int cycles = test_scale() >= 1 ? 20 : 10; /* make test's scalar and ASan runs: 10 */
    vp_entity *kept = NULL; /* every acked record of the earlier cycles */
    uint32_t nkept = 0;
    for (int cyc = 0; cyc < cycles; cyc++) {
        daemon_proc d;
        start_dd(&d, dir, "always", "4");
        vtc_client *c = connect_role(&d, VP_ROLE_EDITOR, true);
        /* what earlier cycles acknowledged is all there, exactly */
        for (uint32_t i = 0; i < nkept; i += 4096) {
            uint32_t n = nkept - i < 4096 ? nkept - i : 4096;
            uint64_t *ids = malloc(n * sizeof *ids);
            for (uint32_t k = 0; k < n; k++) ids[k] = kept[i + k].id;
            vp_list_reply lr;
            int rc = vtc_get(c, ids, n, &lr);
            if (rc) fail_msg("cycle %d: an acknowledged entity is missing (%s)", cyc, vp_strerror(rc));
            for (uint32_t k = 0; k < n; k++) {
                vp_entity e;
                vp_entity_get(&lr.batch, k, &e);
                if (!sent_eq(&e, &kept[i + k])) fail_msg("cycle %d: entity %llu differs", cyc, (unsigned long long)e.id);
            }
            free(ids);
        }
        seed = seed * 6364136223846793005ull + 1442695040888963407ull;
        killer k = {.pid = d.pid, .after_ms = 60 + (int)((seed >> 33) % 140)};
        pthread_t th;
        pthread_create(&th, NULL, killer_main, &k);
        uint32_t sent = stream_adds(c, 1 + (uint64_t)cyc * 1000000, recs, max, 10000, &rates[cyc]);
        pthread_join(th, NULL);
        int st;
        waitpid(d.pid, &st, 0);
        assert_true(WIFSIGNALED(st));
        unlink(d.sock);
        vtc_close(c);
        /* restart: acked ones present, unacked ones whole or absent */
        daemon_proc d2;
        start_dd(&d2, dir, "always", "4");
        c = connect_role(&d2, VP_ROLE_EDITOR, true);
        kept = realloc(kept, (nkept + sent + 1) * sizeof *kept);
        for (uint32_t i = 0; i < sent; i++) {
            vp_list_reply lr;
            int rc = vtc_get(c, &recs[i].e.id, 1, &lr);
            if (recs[i].acked) {
                if (rc) fail_msg("cycle %d: acknowledged entity %llu lost", cyc, (unsigned long long)recs[i].e.id);
                total_acked++;
            } else {
                total_unacked++;
                if (rc) {
                    assert_int_equal(rc, VP_ERR_UNKNOWN_ID);
                    continue;
                }
                total_unacked_present++;
            }
            vp_entity e;
            vp_entity_get(&lr.batch, 0, &e);
            if (!sent_eq(&e, &recs[i].e)) fail_msg("cycle %d: entity %llu half-applied", cyc, (unsigned long long)e.id);
            kept[nkept++] = recs[i].e;
        }
        vtc_close(c);
        daemon_stop(&d2);
    }
    double r[20];
    memcpy(r, rates, sizeof r);
    for (int i = 0; i < cycles; i++)
        for (int j = i + 1; j < cycles; j++)
            if (r[j] < r[i]) {
                double t = r[i];
                r[i] = r[j];
                r[j] = t;
            }
    printf("kill -9: %d cycles, %u acked edits all kept, %u unacked (%u of them present whole), "
           "acked rate median %.0f edits/s (policy always)\n",
           cycles, total_acked, total_unacked, total_unacked_present, r[cycles / 2]);
    free(recs);
    free(kept);
    rm_data(dir);
    tdir_remove(&td);
}

/* ---- a damaged tail -------------------------------------------------------------------------- */

static void test_persist_torn_tail_cut(void **state)
{
    (void)state;
    tdir td;
    char dir[320], jr[400];
    data_dir_make(&td, "persist-tail", dir);
    daemon_proc d;
    start_dd(&d, dir, "always", "64");
    vtc_client *c = connect_role(&d, VP_ROLE_EDITOR, true);
    add_many(c, 1, 100, 0, NULL);
    add_many(c, 1000, 50, 0, NULL);
    dump before;
    take_dump(c, &before);
    vtc_close(c);
    daemon_stop(&d);
    snprintf(jr, sizeof jr, "%s/journal.000001", dir);
    struct stat st;
    assert_int_equal(stat(jr, &st), 0);
    /* 1: a torn last record (the last 30 bytes of a 3rd add lost) */
    int fd = open(jr, O_WRONLY | O_APPEND);
    uint8_t junk[5000];
    memset(junk, 0, sizeof junk);
    junk[0] = 0xFF; /* a record length, then zeros: CRC mismatch */
    junk[1] = 0x10;
    assert_int_equal(write(fd, junk, 4000), 4000);
    close(fd);
    start_dd(&d, dir, "always", "64");
    c = connect_role(&d, VP_ROLE_EDITOR, true);
    dump after;
    take_dump(c, &after);
    assert_same(&before, &after);
    free(after.e);
    assert_true(has_file(dir, "journal.000001.cut-"));
    /* the cut file has exactly the bytes cut; the journal is back to size */
    struct stat st2;
    assert_int_equal(stat(jr, &st2), 0);
    assert_int_equal(st2.st_size, st.st_size);
    /* 2: edits go on after the cut; then one bit flipped inside the last
       record: its CRC fails and it is cut, nothing before it */
    add_many(c, 5000, 10, 0, NULL);
    vtc_close(c);
    daemon_stop(&d);
    assert_int_equal(stat(jr, &st2), 0);
    fd = open(jr, O_RDWR);
    uint8_t b;
    assert_int_equal(pread(fd, &b, 1, st.st_size + 40), 1);
    b ^= 0x20;
    assert_int_equal(pwrite(fd, &b, 1, st.st_size + 40), 1);
    close(fd);
    start_dd(&d, dir, "always", "64");
    c = connect_role(&d, VP_ROLE_EDITOR, true);
    take_dump(c, &after);
    assert_int_equal(after.n, before.n); /* the last add, damaged, is gone; nothing else */
    free(after.e);
    free(before.e);
    vtc_close(c);
    daemon_stop(&d);
    rm_data(dir);
    tdir_remove(&td);
}

/* A kill between a new journal file's creation and its header's write
 * left journal.<gen> shorter than its header, and the daemon refused to
 * start (seen once in CI's kill -9 test). The header now goes through
 * journal.tmp.<gen> and a rename; a torn header that an older daemon left
 * on the last file (it holds no record) is written anew, and a leftover
 * journal.tmp is removed. */
static void test_persist_torn_header_rewritten(void **state)
{
    (void)state;
    tdir td;
    char dir[320], p[400];
    data_dir_make(&td, "persist-hdr", dir);
    daemon_proc d;
    start_dd(&d, dir, "always", "64");
    vtc_client *c = connect_role(&d, VP_ROLE_EDITOR, true);
    add_many(c, 1, 100, 0, NULL);
    dump before, after;
    take_dump(c, &before);
    vtc_close(c);
    daemon_stop(&d);
    snprintf(p, sizeof p, "%s/journal.000001", dir);
    assert_int_equal(access(p, F_OK), 0);
    static const size_t torn[] = {0, 17};
    for (int k = 0; k < 2; k++) {
        snprintf(p, sizeof p, "%s/journal.%06d", dir, 2 + k);
        int fd = open(p, O_WRONLY | O_CREAT | O_TRUNC, 0600);
        uint8_t junk[32] = "VNTJRNL";
        assert_int_equal(write(fd, junk, torn[k]), (ssize_t)torn[k]);
        close(fd);
        snprintf(p, sizeof p, "%s/journal.tmp.%06d", dir, 3 + k);
        fd = open(p, O_WRONLY | O_CREAT | O_TRUNC, 0600);
        close(fd);
        start_dd(&d, dir, "always", "64");
        c = connect_role(&d, VP_ROLE_EDITOR, true);
        take_dump(c, &after);
        assert_same(&before, &after);
        free(after.e);
        assert_false(has_file(dir, "journal.tmp."));
        /* edits go on into the file whose header was written anew, and
           come back after a restart */
        add_many(c, 1000 + 100 * (uint64_t)k, 10, 0, NULL);
        free(before.e);
        take_dump(c, &before);
        vtc_close(c);
        daemon_stop(&d);
        start_dd(&d, dir, "always", "64");
        c = connect_role(&d, VP_ROLE_EDITOR, true);
        take_dump(c, &after);
        assert_same(&before, &after);
        free(after.e);
        vtc_close(c);
        daemon_stop(&d);
    }
    assert_int_equal(before.n, 120);
    free(before.e);
    rm_data(dir);
    tdir_remove(&td);
}

/* Issue 18, item 3, as it was found: 1,000 one-entity adds, one bit
 * flipped in record 10 (0-based). The daemon started with 10 entities,
 * cut the 989 acknowledged records after it as "a damaged end", and
 * appended after the cut. Now it refuses to start, naming the file and
 * the damaged record's offset, and leaves the files as they are; with the
 * bit put back, all 1,000 are there. */
static void test_persist_mid_journal_flip_refused(void **state)
{
    (void)state;
    tdir td;
    char dir[320], jr[400], args[800], out[4096];
    data_dir_make(&td, "persist-flip", dir);
    daemon_proc d;
    start_dd(&d, dir, "everysec", "64");
    vtc_client *c = connect_role(&d, VP_ROLE_EDITOR, true);
    for (uint64_t i = 0; i < 1000; i++) {
        vp_entity e = ent(1 + i, (double)(i % 40), (double)(i / 40), 0.5, 0, 1);
        assert_int_equal(vtc_add(c, &e, 1, NULL, NULL), VP_OK);
    }
    vtc_close(c);
    daemon_stop(&d);
    snprintf(jr, sizeof jr, "%s/journal.000001", dir);
    struct stat st;
    assert_int_equal(stat(jr, &st), 0);
    assert_int_equal((st.st_size - 32) % 1000, 0); /* 1,000 records of one size */
    long rec = (st.st_size - 32) / 1000, at = 32 + 10 * rec;
    int fd = open(jr, O_RDWR);
    uint8_t b;
    assert_int_equal(pread(fd, &b, 1, at + rec / 2), 1);
    b ^= 0x08;
    assert_int_equal(pwrite(fd, &b, 1, at + rec / 2), 1);
    snprintf(args, sizeof args, "--data-dir %s --durability always", dir);
    int rc = daemon_run_to_exit(args, out, sizeof out);
    char want[64];
    snprintf(want, sizeof want, "at offset %ld", at);
    printf("persist: a bit flipped in record 10 of 1,000: exit %d: %.300s\n", rc, out);
    assert_int_equal(rc, 1);
    assert_non_null(strstr(out, "journal.000001"));
    assert_non_null(strstr(out, want));
    struct stat st2;
    assert_int_equal(stat(jr, &st2), 0);
    assert_int_equal(st2.st_size, st.st_size); /* nothing cut */
    assert_false(has_file(dir, "journal.000001.cut-"));
    b ^= 0x08;
    assert_int_equal(pwrite(fd, &b, 1, at + rec / 2), 1);
    close(fd);
    start_dd(&d, dir, "always", "64");
    c = connect_role(&d, VP_ROLE_EDITOR, true);
    vp_stats_reply sr;
    assert_int_equal(vtc_stats(c, &sr), VP_OK);
    assert_int_equal(sr.entities, 1000);
    vtc_close(c);
    daemon_stop(&d);
    rm_data(dir);
    tdir_remove(&td);
}

/* ---- a write error ------------------------------------------------------------------------------ */

static void test_persist_write_error(void **state)
{
    (void)state;
    tdir td;
    char dir[320];
    data_dir_make(&td, "persist-full", dir);
    daemon_proc d;
    /* the kernel refuses writes past 200 kB in this daemon (RLIMIT_FSIZE,
       EFBIG): a disk that fills up while journaling */
    daemon_fsize_limit = 200000;
    start_dd(&d, dir, "always", "64");
    daemon_fsize_limit = 0;
    vtc_client *c = connect_role(&d, VP_ROLE_EDITOR, true), *q = connect_role(&d, VP_ROLE_VIEWER, true);
    uint32_t ok = 0, refused = 0;
    int code = 0;
    for (uint64_t i = 0; i < 400; i++) {
        vp_entity e[10];
        for (int k = 0; k < 10; k++) e[k] = ent(1 + i * 10 + (uint64_t)k, (double)k, (double)i, 0.5, 0, 1);
        int rc = vtc_add(c, e, 10, NULL, NULL);
        if (rc == VP_OK) {
            assert_int_equal(refused, 0); /* once full, full */
            ok++;
        } else {
            code = rc;
            refused++;
        }
    }
    assert_int_equal(code, VP_ERR_IO);
    assert_true(ok > 50 && refused > 50);
    /* nothing refused went in; reads go on */
    vp_stats_reply st;
    assert_int_equal(vtc_stats(q, &st), VP_OK);
    assert_int_equal(st.entities, ok * 10);
    dump live;
    take_dump(q, &live);
    printf("write error: %u batches stored, then %u refused with IO; %u entities served\n", ok, refused, live.n);
    vtc_close(c);
    vtc_close(q);
    daemon_stop(&d);
    /* a restart with room: exactly the acknowledged batches */
    start_dd(&d, dir, "always", "64");
    c = connect_role(&d, VP_ROLE_EDITOR, true);
    dump back;
    take_dump(c, &back);
    assert_same(&live, &back);
    free(live.e);
    free(back.e);
    vtc_close(c);
    daemon_stop(&d);
    rm_data(dir);
    tdir_remove(&td);
}

/* ---- a failed sync ------------------------------------------------------------------------------ */

typedef struct watcher {
    vtc_client *c;
    volatile bool stop;
    uint32_t most, replies; /* entities, the most any reply showed; replies */
} watcher;

static void *watcher_main(void *arg)
{
    watcher *w = arg;
    vp_stats_reply st;
    while (!w->stop && vtc_stats(w->c, &st) == VP_OK) {
        if (st.entities > w->most) w->most = st.entities;
        w->replies++;
    }
    return NULL;
}

/* Issue 18, item 8, last bullet: a failed fdatasync (policy always; the
 * 3rd sync fails with EIO through the VANTAGED_FAIL_SYNC knob) left the
 * edit unacknowledged, but visible to readers and there after a restart,
 * and the daemon serving on. Now (PostgreSQL's rule: a failed fsync is not
 * retried, the pages may be gone): no reader ever sees the edit (replies
 * wait for the turn's sync), its record is cut back off the journal, and
 * the daemon exits with status 1; the restart has exactly the synced
 * edits. */
static void test_persist_sync_failure_stops(void **state)
{
    (void)state;
    tdir td;
    char dir[320];
    data_dir_make(&td, "persist-sync", dir);
    daemon_proc d;
    setenv("VANTAGED_FAIL_SYNC", "3", 1);
    start_dd(&d, dir, "always", "64");
    unsetenv("VANTAGED_FAIL_SYNC");
    vtc_client *c = connect_role(&d, VP_ROLE_EDITOR, true);
    watcher w = {.c = connect_role(&d, VP_ROLE_VIEWER, true)};
    vp_entity e[10];
    for (uint64_t b = 0; b < 2; b++) {
        for (int k = 0; k < 10; k++) e[k] = ent(1 + b * 10 + (uint64_t)k, (double)k, (double)b, 0.5, 0, 1);
        assert_int_equal(vtc_add(c, e, 10, NULL, NULL), VP_OK);
    }
    pthread_t th;
    pthread_create(&th, NULL, watcher_main, &w);
    usleep(20000);
    for (int k = 0; k < 10; k++) e[k] = ent(21 + (uint64_t)k, (double)k, 2, 0.5, 0, 1);
    int rc = vtc_add(c, e, 10, NULL, NULL); /* its sync fails */
    int st = 0, waited = 0;
    pid_t r = 0;
    for (; waited < 500 && (r = waitpid(d.pid, &st, WNOHANG)) == 0; waited++) usleep(10000);
    w.stop = true;
    pthread_join(th, NULL);
    printf("persist: a failed sync: the edit answered %s; %u viewer replies, the most entities any showed %u; "
           "daemon %s %d\n", vp_strerror(rc), w.replies, w.most, r > 0 && WIFEXITED(st) ? "exited" : "still up or killed",
           r > 0 && WIFEXITED(st) ? WEXITSTATUS(st) : -1);
    if (r == 0) { /* the old daemon served on: stop it for the next test */
        kill(d.pid, SIGKILL);
        waitpid(d.pid, &st, 0);
    }
    unlink(d.sock);
    assert_int_not_equal(rc, VP_OK);
    assert_true(w.replies > 0);
    assert_int_equal(w.most, 20); /* no reader saw the unsynced edit */
    assert_true(r > 0 && WIFEXITED(st) && WEXITSTATUS(st) == 1);
    vtc_close(c);
    vtc_close(w.c);
    /* the restart: the two synced batches, not the third */
    start_dd(&d, dir, "always", "64");
    c = connect_role(&d, VP_ROLE_EDITOR, true);
    vp_stats_reply sr;
    assert_int_equal(vtc_stats(c, &sr), VP_OK);
    assert_int_equal(sr.entities, 20);
    vp_list_reply lr;
    assert_int_equal(vtc_get(c, (uint64_t[]){21}, 1, &lr), VP_ERR_UNKNOWN_ID);
    /* and it takes edits again */
    assert_int_equal(vtc_add(c, e, 10, NULL, NULL), VP_OK);
    vtc_close(c);
    daemon_stop(&d);
    /* everysec: the thread's first sync fails: the daemon exits too (its
       edits were acknowledged before the sync, by the policy's promise;
       a daemon's exit loses nothing of what the kernel took) */
    setenv("VANTAGED_FAIL_SYNC", "1", 1);
    start_dd(&d, dir, "everysec", "64");
    unsetenv("VANTAGED_FAIL_SYNC");
    c = connect_role(&d, VP_ROLE_EDITOR, true);
    for (int k = 0; k < 10; k++) e[k] = ent(31 + (uint64_t)k, (double)k, 3, 0.5, 0, 1);
    assert_int_equal(vtc_add(c, e, 10, NULL, NULL), VP_OK);
    for (waited = 0; waited < 500 && (r = waitpid(d.pid, &st, WNOHANG)) == 0; waited++) usleep(10000);
    if (r == 0) {
        kill(d.pid, SIGKILL);
        waitpid(d.pid, &st, 0);
    }
    unlink(d.sock);
    assert_true(r > 0 && WIFEXITED(st) && WEXITSTATUS(st) == 1);
    vtc_close(c);
    start_dd(&d, dir, "always", "64");
    c = connect_role(&d, VP_ROLE_EDITOR, true);
    assert_int_equal(vtc_stats(c, &sr), VP_OK);
    assert_int_equal(sr.entities, 40);
    vtc_close(c);
    daemon_stop(&d);
    rm_data(dir);
    tdir_remove(&td);
}

/* A clean shutdown whose final sync fails exits 1, saying so: a
 * supervisor must not take it for a clean stop (everysec's last second may
 * not be on disk). It exited 0 with a warning. */
static void test_persist_final_sync_failure_exit_status(void **state)
{
    (void)state;
    tdir td;
    char dir[320];
    data_dir_make(&td, "persist-final-sync", dir);
    daemon_proc d;
    setenv("VANTAGED_FAIL_SYNC", "3", 1); /* the two edits' syncs pass, the final one fails */
    start_dd(&d, dir, "always", "64");
    unsetenv("VANTAGED_FAIL_SYNC");
    vtc_client *c = connect_role(&d, VP_ROLE_EDITOR, true);
    vp_entity e[2] = {ent(1, 0, 0, 0.5, 0, 1), ent(2, 1, 0, 0.5, 0, 1)};
    assert_int_equal(vtc_add(c, &e[0], 1, NULL, NULL), VP_OK);
    assert_int_equal(vtc_add(c, &e[1], 1, NULL, NULL), VP_OK);
    vtc_close(c);
    kill(d.pid, SIGTERM);
    int st = 0;
    waitpid(d.pid, &st, 0);
    assert_true(WIFEXITED(st));
    assert_int_equal(WEXITSTATUS(st), 1);
    unlink(d.sock);
    /* both edits were synced when acknowledged: a restart has them */
    start_dd(&d, dir, "always", "64");
    c = connect_role(&d, VP_ROLE_EDITOR, true);
    vp_stats_reply sr;
    assert_int_equal(vtc_stats(c, &sr), VP_OK);
    assert_int_equal(sr.entities, 2);
    vtc_close(c);
    daemon_stop(&d);
    rm_data(dir);
    tdir_remove(&td);
}

/* A snapshot child that ends while the daemon is idle (no client sends a
 * byte after the edit that started it) is put in place all the same: the
 * child's exit wakes the loop. The child is held back 300 ms, so the loop
 * is surely asleep when it ends (a CI run once waited 20 s for it). */
static void test_persist_snapshot_while_idle(void **state)
{
    (void)state;
    tdir td;
    char dir[320];
    data_dir_make(&td, "persist-idle", dir);
    daemon_proc a;
    start_dd_slow_snapshot(&a, dir, "300");
    vtc_client *c = connect_role(&a, VP_ROLE_EDITOR, true);
    add_many(c, 1, 20000, 0, NULL); /* past 1 MB of journal in one edit */
    int waited = 0;
    /* (the snapshot is renamed into place, the directory synced, then the
       old journal removed: the test waits for both) */
    for (; waited < 1000 && (!has_file(dir, "snapshot.000002") || has_file(dir, "journal.000001")); waited++)
        usleep(10000);
    printf("persist: a snapshot finished while the daemon was idle, in place after %d ms (child held 300 ms)\n",
           waited * 10);
    assert_true(has_file(dir, "snapshot.000002"));
    assert_false(has_file(dir, "journal.000001")); /* what it made redundant is gone */
    assert_true(has_file(dir, "journal.000002"));
    vtc_close(c);
    daemon_stop(&a);
    rm_data(dir);
    tdir_remove(&td);
}

/* A daemon killed while its snapshot child writes: the child dies with it
 * and holds none of its descriptors, so the port is free at once (a
 * restart binds it) and the restart restores the scene. The child is held
 * back 5 s: an orphan would keep the listening socket that long. */
static void test_persist_snapshot_child_dies_with_daemon(void **state)
{
    (void)state;
    tdir td;
    char dir[320];
    data_dir_make(&td, "persist-orphan", dir);
    daemon_proc a;
    start_dd_slow_snapshot(&a, dir, "5000");
    vtc_client *c = connect_role(&a, VP_ROLE_EDITOR, true);
    add_many(c, 1, 20000, 0, NULL); /* past 1 MB: the child starts, and waits */
    assert_int_equal(vtc_ping(c), VP_OK);
    kill9(&a);
    /* the client sees the daemon go: its socket is not held open */
    struct pollfd pfd = {.fd = vtc_fd(c), .events = POLLIN};
    assert_int_equal(poll(&pfd, 1, 2000), 1);
    vtc_close(c);
    /* and the port can be bound again (the orphan would hold it 5 s) */
    int fd = socket(AF_INET, SOCK_STREAM, 0), one = 1, bound = -1, tries = 0;
    setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    struct sockaddr_in sa = {.sin_family = AF_INET, .sin_port = htons((uint16_t)a.port),
                             .sin_addr.s_addr = htonl(INADDR_LOOPBACK)};
    for (; tries < 100 && (bound = bind(fd, (struct sockaddr *)&sa, sizeof sa)) != 0; tries++) usleep(10000);
    close(fd);
    printf("persist: daemon killed mid-snapshot: its port free again after %d ms\n", tries * 10);
    assert_int_equal(bound, 0);
    start_dd(&a, dir, "always", "1");
    c = connect_role(&a, VP_ROLE_EDITOR, true);
    vp_stats_reply st;
    assert_int_equal(vtc_stats(c, &st), VP_OK);
    assert_int_equal(st.entities, 20000);
    vtc_close(c);
    daemon_stop(&a);
    rm_data(dir);
    tdir_remove(&td);
}

const struct CMUnitTest persist_tests[] = {
    cmocka_unit_test(test_persist_restore_exact),
    cmocka_unit_test(test_persist_snapshot_with_sublevel_name),
    cmocka_unit_test(test_persist_snapshot_every_point),
    cmocka_unit_test(test_persist_snapshot_while_idle),
    cmocka_unit_test(test_persist_snapshot_child_dies_with_daemon),
    cmocka_unit_test(test_persist_kill9_keeps_acked),
    cmocka_unit_test(test_persist_torn_tail_cut),
    cmocka_unit_test(test_persist_torn_header_rewritten),
    cmocka_unit_test(test_persist_mid_journal_flip_refused),
    cmocka_unit_test(test_persist_write_error),
    cmocka_unit_test(test_persist_sync_failure_stops),
    cmocka_unit_test(test_persist_final_sync_failure_exit_status),
};
const size_t persist_tests_count = sizeof persist_tests / sizeof persist_tests[0];
