/*
 * make_fixture.c — the edits that made tests/data/upgrade_v1 (a data
 * directory written by protocol version 1's vantaged, main at ad84e3d).
 * Built against THAT tree's libvantage, not this one (make_fixture.sh
 * does it); not part of the build. tests/test_upgrade.c holds its own copy
 * of what these edits put in, as the expectation the upgrade must meet:
 * change one, change the other.
 *
 *   make_fixture PORT a   part one: sub-level names, meshes, entities,
 *                         occluders, lights, a committed sub-level load
 *                         (run with VANTAGED_SNAPSHOT_EACH_TURN: it ends
 *                         in the snapshot)
 *   make_fixture PORT b   part two: adds, an update, a remove, a mesh,
 *                         occluders (one replaced), lights (one removed),
 *                         a second load, a destruction (it ends in the
 *                         journal, in version 1's record layouts)
 */
#include "vantage.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static vtc_client *c;

static void check(int rc, const char *what)
{
    if (rc == VP_OK) return;
    fprintf(stderr, "make_fixture: %s: %s (%s)\n", what, vtc_strerror(rc), vtc_last_error(c)->msg);
    exit(1);
}

/* id, class, sub-level, flags, sphere x y z r, aabb (all 0: derived) */
static void add(uint64_t id, uint16_t cls, uint16_t sub, uint32_t flags, double x, double y, double z, double r,
                const double *aabb)
{
    vp_entity e = {.id = id, .class_id = cls, .sublevel = sub, .flags = flags, .sphere = {x, y, z, r}};
    if (aabb) memcpy(e.aabb, aabb, sizeof e.aabb);
    uint32_t h;
    uint64_t epoch;
    check(vtc_add(c, &e, 1, &h, &epoch), "add");
}

/* A quad of w x h metres in the plane z = 0, from the origin (2 triangles). */
static void quad(uint64_t id, double x, double y, double z, float w, float h)
{
    float t[18] = {0, 0, 0, w, 0, 0, w, h, 0, 0, 0, 0, w, h, 0, 0, h, 0};
    check(vtc_put_occluder(c, id, (double[]){x, y, z}, t, 2), "occluder");
}

/* LIGHT_REMOVE (version 1's library has no call for it): sent, ACK awaited. */
static void remove_light(uint64_t id)
{
    uint8_t buf[64];
    vp_writer w;
    vp_writer_init(&w, buf, sizeof buf);
    vp_enc_ids(&w, VP_LIGHT_REMOVE, vtc_next_req(c), &id, 1);
    check(vtc_send(c, buf, w.len), "send light remove");
    vp_header h;
    const uint8_t *p;
    check(vtc_recv(c, &h, &p, 5000), "light remove reply");
    if (h.type != VP_ACK) {
        fprintf(stderr, "make_fixture: light remove answered with type 0x%04x\n", h.type);
        exit(1);
    }
}

static void light(uint64_t id, uint8_t kind, double x, double y, double z, float intensity, float range)
{
    vp_light l = {.id = id, .kind = kind, .pos = {x, y, z}, .dir = {0, -1, 0}, .color = {1, 0.75f, 0.5f},
                  .intensity = intensity, .range = range, .inner_cos = 0.9f, .outer_cos = 0.8f};
    check(vtc_put_lights(c, &l, 1), "light");
}

/* A tetrahedron with per-vertex normals (class cls), scaled by k. */
static void tetra(uint16_t cls, float k)
{
    float pos[12] = {0, 0, 0, k, 0, 0, 0, k, 0, 0, 0, k};
    float nrm[12] = {-0.57735f, -0.57735f, -0.57735f, 1, 0, 0, 0, 1, 0, 0, 0, 1};
    uint32_t idx[12] = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
    check(vtc_put_mesh(c, cls, pos, nrm, 4, idx, 12), "mesh");
}

static void part_a(void)
{
    const char *names[2] = {"harbour", "park"};
    uint16_t ids[2];
    check(vtc_sublevel_ids(c, names, 2, ids), "sub-level names"); /* 1, 2 */
    tetra(1, 1.0f);
    float tri[9] = {0, 0, 0, 2, 0, 0, 0, 2, 0};
    uint32_t tidx[3] = {0, 1, 2};
    check(vtc_put_mesh(c, 2, tri, NULL, 3, tidx, 3), "mesh 2");
    add(1, 1, 0, 0, 0, 1, 0, 1, NULL);
    add(2, 1, 0, VP_ENT_DYNAMIC, 10, 1, 0, 1.5, NULL);
    add(3, 2, 0, 0, 0, 0, 0, 0, (double[]){-2, 0, 20, 2, 4, 22});
    add(4, 0, 2, 0, 5, 2, -5, 0.5, NULL);
    add(5, 0, 0, 0, 0, 0, 0, 0, (double[]){-4, 0, 30, 4, 4, 31});
    add(6, 1, 0, 0, -6, 1, -6, 1, NULL);
    quad(5, -4, 0, 30.5, 8, 4);
    quad(100, 20, 0, 0, 6, 3);
    light(10, VP_LIGHT_POINT, 0, 3, 0, 100, 15);
    light(11, VP_LIGHT_SPOT, 5, 4, 5, 200, 20);
    vp_sublevel_begun b;
    check(vtc_sublevel_begin(c, "harbour", 2, &b), "begin harbour");
    tetra(b.class_base, 2.0f);
    add(20, b.class_base, 0, 0, 40, 1, 40, 2, NULL);
    add(21, b.class_base, 0, 0, 44, 1, 40, 2, NULL);
    quad(200, 38, 0, 45, 10, 5);
    light(12, VP_LIGHT_POINT, 42, 5, 42, 300, 25);
    check(vtc_sublevel_commit(c, NULL), "commit harbour");
}

static void part_b(void)
{
    add(7, 1, 0, 0, -10, 1, 5, 2, NULL);
    add(8, 2, 0, 0, 3, 3, 3, 4, (double[]){0, 0, 0, 6, 6, 6});
    vp_entity up = {.id = 2, .class_id = 1, .flags = VP_ENT_DYNAMIC, .sphere = {12, 1, 3, 1.5}};
    uint64_t epoch;
    check(vtc_update(c, &up, 1, &epoch), "update");
    check(vtc_remove(c, (uint64_t[]){6}, 1, &epoch), "remove");
    tetra(9, 0.5f);
    quad(101, -20, 0, 0, 4, 4);
    quad(100, 20, 0, 1, 5, 2); /* replaced */
    light(13, VP_LIGHT_SPOT, -5, 6, -5, 150, 18);
    remove_light(11);
    vp_sublevel_begun b;
    check(vtc_sublevel_begin(c, "docks", 1, &b), "begin docks");
    tetra(b.class_base, 3.0f);
    add(30, b.class_base, 0, 0, -40, 1, -40, 3, NULL);
    quad(300, -45, 0, -35, 10, 6);
    light(14, VP_LIGHT_POINT, -40, 8, -40, 400, 30);
    check(vtc_sublevel_commit(c, NULL), "commit docks");
    vp_destroyed d;
    check(vtc_send_destruction(c, &(vp_destroy){.id = 5, .center = {0, 2, 30.5}, .radius = 1.5}, &d), "destroy");
    if (d.spheres != 1 || !d.occluder_tris) {
        fprintf(stderr, "make_fixture: the destruction did not cut the wall (%u spheres, %u triangles)\n",
                d.spheres, d.occluder_tris);
        exit(1);
    }
}

int main(int argc, char **argv)
{
    if (argc != 3 || (strcmp(argv[2], "a") && strcmp(argv[2], "b"))) {
        fprintf(stderr, "usage: make_fixture PORT a|b\n");
        return 2;
    }
    char err[300];
    vtc_connect_opts o = {.port = atoi(argv[1]), .role = VP_ROLE_EDITOR, .name = "make_fixture"};
    if (vtc_connect(&o, &c, err, sizeof err)) {
        fprintf(stderr, "make_fixture: %s\n", err);
        return 1;
    }
    if (!strcmp(argv[2], "a")) part_a();
    else part_b();
    vtc_close(c);
    return 0;
}
