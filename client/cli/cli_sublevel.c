/*
 * cli_sublevel.c — `vantage sublevel load NAME FILE`, `unload NAME`,
 * `list`: a level file imported here (client/import, assimp) and pushed as one
 * sub-level load: BEGIN, the class meshes, the textures and materials,
 * the entities (each placed by its transform) in batches, the occluders and
 * lights, the sun (ENV_SET, only when the file has one), COMMIT. Nothing of it is visible to anyone before
 * the commit; if anything fails the load is aborted (and the daemon drops
 * it by itself if this process dies).
 *
 * Ids (documented in README): entity i of sub-level S is
 * 2^63 | S << 32 | i; an occluder attached to an entity has that entity's
 * id, a free one 2^63 | S << 32 | 2^31 | k; light k 2^63 | S << 32 | k.
 * Materials and textures are global, with the ids the importer gives them
 * (import.h): a second level with the same ids replaces them.
 */
#include "cli.h"
#include "import.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define LOAD_BATCH 512u /* entities a message: each holds the daemon's scene lock about half a millisecond */

static uint64_t level_id(uint16_t sub, uint32_t i)
{
    return 1ull << 63 | (uint64_t)sub << 32 | i;
}

static void progress(bool tty, const char *name, uint32_t done, uint32_t total, double t0)
{
    if (!tty) return;
    double dt = now_s() - t0;
    fprintf(stderr, "\r%s: %u / %u entities  %.0f/s   ", name, done, total, dt > 0 ? done / dt : 0.0);
    fflush(stderr);
}

#define PUSH_NOMEM 1 /* push: out of memory here, not the server's refusal */

/* The level's global assets: textures (vtc_texture_put sends each in
 * chunks that fit the server's frames), then the materials that name
 * them, step records a message. */
static int push_assets(cli *k, const imp_level *lv, uint32_t step)
{
    int rc;
    for (uint32_t i = 0; i < lv->ntex; i++) {
        const lvl_texture *t = &lv->tex[i];
        if ((rc = vtc_texture_put(k->c, t->id, t->format, t->flags, t->bytes, t->nbytes, NULL))) return rc;
    }
    for (uint32_t i = 0; i < lv->nmat; i += step)
        if ((rc = vtc_material_put(k->c, lv->mat + i, lv->nmat - i < step ? lv->nmat - i : step, NULL))) return rc;
    return VP_OK;
}

/* The sun of the file, if it has one, into the environment (the rest of
 * the environment as it is). */
static int push_sun(cli *k, const imp_level *lv)
{
    if (!lv->has_sun) return VP_OK;
    vp_env env;
    int rc = vtc_env_get(k->c, &env);
    if (rc) return rc;
    for (int a = 0; a < 3; a++) {
        env.sun_dir[a] = lv->sun_dir[a];
        env.sun_color[a] = lv->sun_color[a];
    }
    env.sun_lux = lv->sun_lux;
    return vtc_env_set(k->c, &env, NULL);
}

/* The level, as the load's messages: meshes, textures, materials,
 * entities, occluders, lights, the sun; VP_OK, a code from the server or
 * the connection, or PUSH_NOMEM. Batches stay within the server's
 * max_batch. */
static int push(cli *k, const char *name, imp_level *lv, const vp_sublevel_begun *b, bool tty, double *t_ent)
{
    int rc;
    uint32_t max = vtc_server(k->c)->max_batch, step = max < LOAD_BATCH ? max : LOAD_BATCH;
    for (uint32_t i = 0; i < lv->nmesh; i++) {
        const lvl_mesh *m = &lv->mesh[i];
        if ((rc = vtc_put_mesh_uv(k->c, (uint16_t)(b->class_base + i), m->pos, m->nrm, m->uv, m->tan, m->nv, m->idx,
                                  m->ni)))
            return rc;
    }
    if ((rc = push_assets(k, lv, step))) return rc;
    vp_entity *batch = calloc(step, sizeof *batch);
    if (!batch) return PUSH_NOMEM;
    double t0 = now_s();
    for (uint32_t i = 0; i < lv->nent; i += step) {
        uint32_t n = lv->nent - i < step ? lv->nent - i : step;
        for (uint32_t j = 0; j < n; j++) {
            const lvl_entity *e = &lv->ent[i + j];
            vp_entity *o = &batch[j];
            memset(o, 0, sizeof *o);
            o->id = level_id(b->id, i + j);
            o->class_id = (uint16_t)(b->class_base + e->cls);
            o->sublevel = b->id;
            o->material = e->material;
            o->flags = VP_ENT_TRANSFORM | (e->dynamic ? VP_ENT_DYNAMIC : 0);
            memcpy(o->pos, e->pos, sizeof o->pos);
            memcpy(o->rot, e->rot, sizeof o->rot);
            memcpy(o->scale, e->scale, sizeof o->scale);
        }
        if ((rc = vtc_add(k->c, batch, n, NULL, NULL))) {
            free(batch);
            return rc;
        }
        progress(tty, name, i + n, lv->nent, t0);
    }
    free(batch);
    *t_ent = now_s() - t0;
    if (tty && lv->nent) fputc('\n', stderr);
    for (uint32_t i = 0; i < lv->nocc; i++) {
        const lvl_occluder *o = &lv->occ[i];
        uint64_t id = o->entity >= 0 ? level_id(b->id, (uint32_t)o->entity) : level_id(b->id, 1u << 31 | i);
        if ((rc = vtc_put_occluder(k->c, id, o->origin, o->tri, o->ntri))) return rc;
    }
    for (uint32_t i = 0; i < lv->nlight; i++) lv->light[i].id = level_id(b->id, i);
    for (uint32_t i = 0; i < lv->nlight; i += step)
        if ((rc = vtc_put_lights(k->c, lv->light + i, lv->nlight - i < step ? lv->nlight - i : step))) return rc;
    return push_sun(k, lv);
}

static int sub_load(cli *k, int argc, char **argv)
{
    const char *use = "sublevel load NAME FILE [--dry-run] [--json]";
    bool dry = false, json = false;
    const char *args[2];
    int na = 0;
    for (int i = 2; i < argc; i++) {
        if (!strcmp(argv[i], "--dry-run")) dry = true;
        else if (!strcmp(argv[i], "--json")) json = true;
        else if (!strcmp(argv[i], "--help")) return printf("usage: vantage %s\n", use), 0;
        else if (argv[i][0] == '-' || na == 2) return die_usage("%s", use);
        else args[na++] = argv[i];
    }
    if (na != 2) return die_usage("%s", use);
    const char *name = args[0], *path = args[1];
    size_t nl = strlen(name);
    if (nl == 0 || nl > VP_MAX_NAME) return die_usage("sublevel: names are 1..255 bytes");
    for (size_t i = 0; i < nl; i++)
        if ((unsigned char)name[i] < 32 || name[i] == 127) return die_usage("sublevel: no control characters in names");
    double t0 = now_s();
    imp_level lv;
    char err[512];
    if (imp_level_import(path, &lv, err, sizeof err)) {
        fprintf(stderr, "%s: %s\n", g_prog, err);
        return 1;
    }
    double t_import = now_s() - t0;
    uint32_t tris = 0;
    for (uint32_t i = 0; i < lv.nocc; i++) tris += lv.occ[i].ntri;
    if (!json)
        fprintf(stderr,
                "%s: %u entities, %u meshes, %u materials, %u textures, %u occluders (%u triangles), %u lights (%u "
                "skipped)%s, %u point and line primitives skipped, in %.0f ms\n",
                path, lv.nent, lv.nmesh, lv.nmat, lv.ntex, lv.nocc, tris, lv.nlight, lv.skipped_lights,
                lv.has_sun ? ", a sun" : "", lv.skipped_prims, t_import * 1e3);
    int rc = 0;
    if (dry) goto out;
    if ((rc = connect_cli(k, VP_ROLE_EDITOR))) goto out;
    vp_sublevel_begun b;
    if ((rc = vtc_sublevel_begin(k->c, name, (uint16_t)lv.nmesh, &b))) {
        rc = server_fail(k, "sublevel load", rc);
        goto out;
    }
    double t1 = now_s(), t_ent = 0;
    bool tty = !json && isatty(2);
    if ((rc = push(k, name, &lv, &b, tty, &t_ent))) {
        if (rc == PUSH_NOMEM) {
            fprintf(stderr, "%s: sublevel load: out of memory\n", g_prog);
            rc = 1;
        } else {
            rc = server_fail(k, "sublevel load", rc);
        }
        if (rc != 3) vtc_sublevel_abort(k->c, NULL); /* a lost connection aborts by itself */
        goto out;
    }
    vp_ack a;
    if ((rc = vtc_sublevel_commit(k->c, &a))) {
        rc = server_fail(k, "sublevel load", rc);
        goto out;
    }
    double t_push = now_s() - t1;
    if (json) {
        printf("{\"sublevel\": ");
        cli_json_str(stdout, name, strlen(name));
        printf(", \"id\": %u, \"epoch\": %llu, \"entities\": %u, \"classes\": %u, \"occluders\": %u, "
               "\"lights\": %u, \"import_ms\": %.1f, \"load_ms\": %.1f, \"entities_per_s\": %.0f}\n",
               b.id, (unsigned long long)a.epoch, a.count, lv.nmesh, lv.nocc, lv.nlight, t_import * 1e3, t_push * 1e3,
               t_ent > 0 ? lv.nent / t_ent : 0.0);
    }
    else
        printf("sub-level %s (id %u) loaded at epoch %llu: %u entities, %u occluders, %u lights in %.0f ms\n", name,
               b.id, (unsigned long long)a.epoch, a.count, lv.nocc, lv.nlight, t_push * 1e3);
out:
    imp_level_free(&lv);
    return rc;
}

static int sub_unload(cli *k, int argc, char **argv)
{
    if (argc != 3) return die_usage("sublevel unload NAME");
    int rc = connect_cli(k, VP_ROLE_EDITOR);
    if (rc) return rc;
    vp_ack a;
    if ((rc = vtc_sublevel_unload(k->c, argv[2], &a))) return server_fail(k, "sublevel unload", rc);
    printf("sub-level %s unloaded at epoch %llu: %u entities\n", argv[2], (unsigned long long)a.epoch, a.count);
    return 0;
}

static int sub_list(cli *k, int argc, char **argv)
{
    bool json = argc == 3 && !strcmp(argv[2], "--json");
    if (argc > 2 && !json) return die_usage("sublevel list [--json]");
    int rc = connect_cli(k, VP_ROLE_VIEWER);
    if (rc) return rc;
    vp_sublevel_infos in;
    if ((rc = vtc_sublevel_info(k->c, &in))) return server_fail(k, "sublevel list", rc);
    static const char *const states[] = {"empty", "loaded", "loading", "unloading"};
    if (!json) printf("%-5s %-10s %10s %9s %7s  %s\n", "id", "state", "entities", "occluders", "lights", "name");
    size_t pos = 0;
    vp_sublevel_info s;
    while (vp_sublevel_info_next(&in, &pos, &s)) {
        if (json) {
            printf("{\"id\": %u, \"name\": ", s.id);
            cli_json_str(stdout, (const char *)s.name, s.name_len);
            printf(", \"state\": \"%s\", \"entities\": %u, \"occluders\": %u, \"lights\": %u, \"classes\": %u, "
                   "\"epoch\": %llu}\n",
                   states[s.state], s.entities, s.occluders, s.lights, s.classes, (unsigned long long)in.epoch);
        } else {
            printf("%-5u %-10s %10u %9u %7u  %.*s\n", s.id, states[s.state], s.entities, s.occluders, s.lights,
                   s.name_len, (const char *)s.name);
        }
    }
    return 0;
}

int cmd_sublevel(cli *k, int argc, char **argv)
{
    if (argc >= 2 && !strcmp(argv[1], "load")) return sub_load(k, argc, argv);
    if (argc >= 2 && !strcmp(argv[1], "unload")) return sub_unload(k, argc, argv);
    if (argc >= 2 && !strcmp(argv[1], "list")) return sub_list(k, argc, argv);
    return die_usage("sublevel load NAME FILE [--dry-run] [--json] | sublevel unload NAME | sublevel list [--json]");
}
