/*
 * cli_scene.c — `vantage add`, `move` and `material`: entities as a mesh
 * placed by a transform (or a bounding sphere, the culling-only form), and
 * materials. Rotations are given as yaw, pitch, roll in degrees (about +Y,
 * then +X, then +Z, each about the axes already turned: q = yaw * pitch *
 * roll, Y up, as in most Y-up engines) or as a quaternion x,y,z,w.
 */
#include "cli.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* q = a * b (Hamilton product, x y z w). */
static void quat_mul(const double a[4], const double b[4], double q[4])
{
    q[0] = a[3] * b[0] + a[0] * b[3] + a[1] * b[2] - a[2] * b[1];
    q[1] = a[3] * b[1] - a[0] * b[2] + a[1] * b[3] + a[2] * b[0];
    q[2] = a[3] * b[2] + a[0] * b[1] - a[1] * b[0] + a[2] * b[3];
    q[3] = a[3] * b[3] - a[0] * b[0] - a[1] * b[1] - a[2] * b[2];
}

/* "YAW,PITCH,ROLL" in degrees as a unit quaternion. */
static bool parse_ypr(const char *s, float rot[4])
{
    double ypr[3];
    if (!parse_vec(s, ypr, 3)) return false;
    double h[3];
    for (int k = 0; k < 3; k++) h[k] = ypr[k] * (M_PI / 360.0); /* half angles, radians */
    double qy[4] = {0, sin(h[0]), 0, cos(h[0])}, qx[4] = {sin(h[1]), 0, 0, cos(h[1])},
           qz[4] = {0, 0, sin(h[2]), cos(h[2])}, t[4], q[4];
    quat_mul(qy, qx, t);
    quat_mul(t, qz, q);
    for (int k = 0; k < 4; k++) rot[k] = (float)q[k];
    return true;
}

/* "X,Y,Z,W", normalised (the daemon takes |q| within 1e-3 of 1). */
static bool parse_quat(const char *s, float rot[4])
{
    double q[4], n = 0;
    if (!parse_vec(s, q, 4)) return false;
    for (int k = 0; k < 4; k++) n += q[k] * q[k];
    if (!(n > 0)) return false;
    for (int k = 0; k < 4; k++) rot[k] = (float)(q[k] / sqrt(n));
    return true;
}

/* "S" (uniform) or "SX,SY,SZ". */
static bool parse_scale(const char *s, float scale[3])
{
    double v[3];
    if (parse_vec(s, v, 1)) v[1] = v[2] = v[0];
    else if (!parse_vec(s, v, 3)) return false;
    for (int k = 0; k < 3; k++) scale[k] = (float)v[k];
    return true;
}

/* The transform options at argv[*i] (and its value): --pos, --rotate,
 * --quat, --scale. 1 taken, 0 not one of them, -1 a bad value (reported). */
static int trs_opt(const char *cmd, int argc, char **argv, int *i, double pos[3], float rot[4], float scale[3],
                   bool *given)
{
    const char *o = argv[*i];
    bool p = !strcmp(o, "--pos"), r = !strcmp(o, "--rotate"), q = !strcmp(o, "--quat"), s = !strcmp(o, "--scale");
    if (!p && !r && !q && !s) return 0;
    if (*i + 1 >= argc) return die_missing(cmd, o, "it takes a value"), -1;
    const char *v = argv[++*i];
    bool ok = p ? parse_vec(v, pos, 3) : r ? parse_ypr(v, rot) : q ? parse_quat(v, rot) : parse_scale(v, scale);
    if (!ok)
        return die_bad_value(cmd, o, v,
                             p ? "X,Y,Z" : r ? "YAW,PITCH,ROLL in degrees" : q ? "X,Y,Z,W (not all 0)" : "S or X,Y,Z"),
               -1;
    if (given) *given = true;
    return 1;
}

int cmd_add(cli *k, int argc, char **argv)
{
    const char *use = "add ID X,Y,Z R [--class N] [--sublevel N] [--dynamic] [--aabb X0,Y0,Z0,X1,Y1,Z1] [--material M]\n"
                      "   or: add ID --mesh C [--pos X,Y,Z] [--rotate YAW,PITCH,ROLL | --quat X,Y,Z,W] "
                      "[--scale S|X,Y,Z] [--material M] [--sublevel N] [--dynamic]";
    if (argc < 3) return die_usage("%s", use);
    vp_entity e = {.rot = {0, 0, 0, 1}, .scale = {1, 1, 1}};
    if (!parse_u64(argv[1], &e.id)) return die_usage("add: bad id %s", argv[1]);
    bool mesh = !strcmp(argv[2], "--mesh");
    int i = 2;
    if (!mesh) {
        if (argc < 4 || !parse_vec(argv[2], e.sphere, 3) || !parse_vec(argv[3], &e.sphere[3], 1))
            return die_usage("add: bad position or radius; %s", use);
        i = 4;
    }
    for (; i < argc; i++) {
        uint64_t v;
        int t = mesh ? trs_opt("add", argc, argv, &i, e.pos, e.rot, e.scale, NULL) : 0;
        if (t < 0) return 2;
        if (t) continue;
        if (!strcmp(argv[i], "--dynamic")) e.flags |= VP_ENT_DYNAMIC;
        else if (!strcmp(argv[i], mesh ? "--mesh" : "--class") && i + 1 < argc && parse_u64(argv[++i], &v) &&
                 v <= 65535)
            e.class_id = (uint16_t)v;
        else if (!strcmp(argv[i], "--sublevel") && i + 1 < argc && parse_u64(argv[++i], &v) && v <= 65535)
            e.sublevel = (uint16_t)v;
        else if (!strcmp(argv[i], "--material") && i + 1 < argc && parse_u64(argv[++i], &v) && v <= UINT32_MAX)
            e.material = (uint32_t)v;
        else if (!mesh && !strcmp(argv[i], "--aabb") && i + 1 < argc && parse_vec(argv[++i], e.aabb, 6))
            ;
        else
            return die_usage("add: unexpected %s; %s", argv[i], use);
    }
    if (mesh) e.flags |= VP_ENT_TRANSFORM;
    else memset(e.rot, 0, sizeof e.rot), memset(e.scale, 0, sizeof e.scale); /* not read: 0 on the wire */
    int rc = connect_cli(k, VP_ROLE_EDITOR);
    if (rc) return rc;
    uint32_t h;
    uint64_t epoch;
    if ((rc = vtc_add(k->c, &e, 1, &h, &epoch))) return server_fail(k, "add", rc);
    printf("added id %llu handle %u at epoch %llu\n", (unsigned long long)e.id, h, (unsigned long long)epoch);
    return 0;
}

/* move of an entity with a transform: TRANSFORM_SET, what is not given kept. */
static int move_trs(cli *k, const vp_entity *e, int argc, char **argv, const double *pos)
{
    vp_transform t = {.id = e->id, .handle = e->handle};
    memcpy(t.pos, pos ? pos : e->pos, sizeof t.pos);
    memcpy(t.rot, e->rot, sizeof t.rot);
    memcpy(t.scale, e->scale, sizeof t.scale);
    for (int i = pos ? 3 : 2; i < argc; i++) {
        int r = trs_opt("move", argc, argv, &i, t.pos, t.rot, t.scale, NULL);
        if (r < 0) return 2;
        if (!r) return die_usage("move: unexpected %s (an entity with a transform takes --pos, --rotate, --quat, "
                                 "--scale)", argv[i]);
    }
    uint64_t epoch;
    int rc = vtc_transform_set(k->c, &t, 1, &epoch);
    if (rc) return server_fail(k, "move", rc);
    printf("moved id %llu at epoch %llu\n", (unsigned long long)e->id, (unsigned long long)epoch);
    return 0;
}

int cmd_move(cli *k, int argc, char **argv)
{
    const char *use = "move ID X,Y,Z [--radius R]\n"
                      "   or: move ID [X,Y,Z] [--pos X,Y,Z] [--rotate YAW,PITCH,ROLL | --quat X,Y,Z,W] [--scale S|X,Y,Z]";
    uint64_t id;
    double pos[3], r = -1;
    if (argc < 2 || !parse_u64(argv[1], &id)) return die_usage("%s", use);
    bool has_pos = argc > 2 && parse_vec(argv[2], pos, 3);
    int rc = connect_cli(k, VP_ROLE_EDITOR);
    if (rc) return rc;
    vp_list_reply lr;
    if ((rc = vtc_get(k->c, &id, 1, &lr))) return server_fail(k, "move", rc);
    vp_entity e;
    vp_entity_get(&lr.batch, 0, &e);
    if (e.flags & VP_ENT_TRANSFORM) return move_trs(k, &e, argc, argv, has_pos ? pos : NULL);
    if (!has_pos) return die_usage("%s", use);
    if (argc == 5 && !strcmp(argv[3], "--radius")) {
        if (!parse_vec(argv[4], &r, 1) || r < 0) return die_usage("%s", use);
    } else if (argc != 3) {
        return die_usage("move: entity %llu has no transform: it takes X,Y,Z [--radius R]", (unsigned long long)id);
    }
    double d[3] = {pos[0] - e.sphere[0], pos[1] - e.sphere[1], pos[2] - e.sphere[2]};
    for (int a = 0; a < 3; a++) {
        e.sphere[a] = pos[a];
        e.aabb[a] += d[a];
        e.aabb[3 + a] += d[a];
    }
    if (r >= 0) { /* a new radius: the AABB follows the sphere */
        e.sphere[3] = r;
        for (int a = 0; a < 6; a++) e.aabb[a] = 0;
    }
    uint64_t epoch;
    if ((rc = vtc_update(k->c, &e, 1, &epoch))) return server_fail(k, "move", rc);
    printf("moved id %llu at epoch %llu\n", (unsigned long long)id, (unsigned long long)epoch);
    return 0;
}

/* ---- material put | rm ------------------------------------------------------------ */

static const struct { const char *name; int slot; } slots[] = {
    {"base", VP_TEX_BASE},     {"metallic-roughness", VP_TEX_MR}, {"mr", VP_TEX_MR},
    {"normal", VP_TEX_NORMAL}, {"emissive", VP_TEX_EMISSIVE}};

/* "SLOT=ID" into m's texture slot. */
static bool parse_texture(const char *s, vp_material *m)
{
    const char *eq = strchr(s, '=');
    uint64_t id;
    if (!eq || !parse_u64(eq + 1, &id) || id > UINT32_MAX) return false;
    for (size_t k = 0; k < sizeof slots / sizeof slots[0]; k++)
        if (strlen(slots[k].name) == (size_t)(eq - s) && !strncmp(s, slots[k].name, (size_t)(eq - s))) {
            m->tex[slots[k].slot].texture = (uint32_t)id;
            return true;
        }
    return false;
}

static int material_put(cli *k, int argc, char **argv)
{
    vp_material m = {.base_color = {1, 1, 1, 1}, .metallic = 0, .roughness = 1, .normal_scale = 1,
                     .emissive_strength = 1};
    for (int s = 0; s < VP_TEX_SLOTS; s++) {
        m.tex[s].scale[0] = m.tex[s].scale[1] = 1;
        m.tex[s].min_filter = VP_FILTER_LINEAR_MIP_LINEAR;
        m.tex[s].mag_filter = VP_FILTER_LINEAR;
    }
    uint64_t id;
    if (argc < 3 || !parse_u64(argv[2], &id) || !id || id > UINT32_MAX)
        return die_usage("material put: expected an id 1..4294967295");
    m.id = (uint32_t)id;
    for (int i = 3; i < argc; i++) {
        const char *o = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        double d[4];
        bool ok = true, takes = true;
        if (!strcmp(o, "--double-sided")) {
            m.flags |= VP_MAT_DOUBLE_SIDED;
            takes = false;
        } else if (!v) {
            return die_missing("material put", o, "it takes a value");
        } else if (!strcmp(o, "--base")) {
            d[3] = 1;
            ok = parse_vec(v, d, 4) || parse_vec(v, d, 3);
            for (int c = 0; ok && c < 4; c++) m.base_color[c] = (float)d[c];
        } else if (!strcmp(o, "--emissive")) {
            ok = parse_vec(v, d, 3);
            for (int c = 0; ok && c < 3; c++) m.emissive[c] = (float)d[c];
        } else if (!strcmp(o, "--metallic") || !strcmp(o, "--roughness") || !strcmp(o, "--emissive-strength") ||
                   !strcmp(o, "--alpha-mask") || !strcmp(o, "--normal-scale")) {
            ok = parse_vec(v, d, 1);
            float f = (float)d[0];
            if (!strcmp(o, "--metallic")) m.metallic = f;
            else if (!strcmp(o, "--roughness")) m.roughness = f;
            else if (!strcmp(o, "--emissive-strength")) m.emissive_strength = f;
            else if (!strcmp(o, "--normal-scale")) m.normal_scale = f;
            else m.alpha_mode = VP_ALPHA_MASK, m.alpha_cutoff = f;
        } else if (!strcmp(o, "--texture")) {
            ok = parse_texture(v, &m);
            if (!ok) return die_bad_value("material put", o, v, "SLOT=ID, SLOT base, mr, normal or emissive");
        } else {
            return die_usage("material put: unexpected %s", o);
        }
        if (!ok) return die_bad_value("material put", o, v, "numbers");
        i += takes;
    }
    int rc = connect_cli(k, VP_ROLE_EDITOR);
    if (rc) return rc;
    uint64_t epoch;
    if ((rc = vtc_material_put(k->c, &m, 1, &epoch))) return server_fail(k, "material put", rc);
    printf("material %u put at epoch %llu\n", m.id, (unsigned long long)epoch);
    return 0;
}

int cmd_material(cli *k, int argc, char **argv)
{
    if (argc >= 2 && !strcmp(argv[1], "put")) return material_put(k, argc, argv);
    if (argc < 3 || (strcmp(argv[1], "rm") && strcmp(argv[1], "remove")))
        return die_usage("material put ID [options] | material rm ID [ID...]");
    uint32_t n = (uint32_t)argc - 2;
    uint64_t *ids = malloc(n * sizeof *ids);
    if (!ids) return die_usage("material rm: out of memory");
    for (uint32_t i = 0; i < n; i++)
        if (!parse_u64(argv[2 + i], &ids[i])) {
            free(ids);
            return die_usage("material rm: bad id %s", argv[2 + i]);
        }
    int rc = connect_cli(k, VP_ROLE_EDITOR);
    uint64_t epoch = 0;
    if (!rc && (rc = vtc_material_remove(k->c, ids, n, &epoch))) rc = server_fail(k, "material rm", rc);
    else if (!rc) printf("removed %u materials at epoch %llu\n", n, (unsigned long long)epoch);
    free(ids);
    return rc;
}
