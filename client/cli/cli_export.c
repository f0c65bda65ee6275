/*
 * cli_export.c — `vantage export FILE.glb`: the live scene as glTF 2.0
 * binary, read back through the protocol (ENTITY_LIST, MESH_GET per used
 * class, MATERIAL_LIST, TEXTURE_GET for the textures the materials name,
 * LIGHT_LIST, ENV_GET) and written as one .glb: the JSON (built with
 * json-c) and one binary buffer in the GLB container, written here.
 *
 * What becomes what:
 *  - each entity one node named entity_<id> with its translation, rotation
 *    and scale; a dynamic one has extras {"vantage_dynamic": true};
 *  - each class mesh one glTF mesh per material its entities use
 *    (POSITION with min/max, NORMAL, TEXCOORD_0, TANGENT, 32-bit indices;
 *    the accessors shared), named class_<c>;
 *  - an entity without a transform (culling-only bounds) is a unit box
 *    mesh (-1..1) placed and stretched onto its AABB;
 *  - materials (material_<id>, in id order) with their textures, samplers,
 *    KHR_texture_transform and KHR_materials_emissive_strength; images
 *    are the original PNG/JPEG bytes the daemon stored, one per texture
 *    (texture_<id>, in id order);
 *  - lights and the environment's sun through KHR_lights_punctual (point,
 *    spot, and the sun as a directional light on a node named sun).
 * Reading the file back with `vantage sublevel load` gives the same
 * entities, transforms, meshes, materials and texture bytes (tests:
 * test_import.c's round trip). Cost: the scene's meshes and textures
 * held in memory once, plus the file.
 */
#include "cli.h"
#include "vp_grow.h"

#include <json-c/json.h>

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define GLB_MAGIC 0x46546c67u /* "glTF" */
#define GLB_JSON 0x4e4f534au  /* "JSON" */
#define GLB_BIN 0x004e4942u   /* "BIN\0" */

typedef struct ex_mesh {
    uint16_t class_id;
    uint32_t nv, ni;
    float *pos, *nrm, *uv, *tan;
    uint32_t *idx;
    int acc_pos, acc_nrm, acc_uv, acc_tan, acc_idx; /* accessors, -1 = none */
} ex_mesh;

typedef struct ex_tex {
    uint32_t id;
    uint8_t format;
    uint8_t *bytes;
    uint32_t n;
} ex_tex;

typedef struct exporter {
    cli *k;
    vp_entity *ent;
    uint32_t nent;
    ex_mesh *mesh;          /* the classes the entities use, by class id */
    uint32_t nmesh;
    vp_material *mat;
    uint32_t nmat;
    ex_tex *tex;
    uint32_t ntex;
    vp_light *light;
    uint32_t nlight;
    bool has_env;
    vp_env env;
    vp_writer bin;          /* the binary chunk */
    json_object *root, *views, *accessors, *meshes, *samplers, *textures;
    int (*mesh_of)[2];      /* (class index, material id) -> glTF mesh, found by scan */
    int *mesh_idx;
    uint32_t nmesh_of;
    bool used_tt, used_es;  /* KHR_texture_transform, KHR_materials_emissive_strength */
} exporter;

/* ---- reading the scene ------------------------------------------------------------ */

static int cmp_entity(const void *a, const void *b)
{
    uint64_t x = ((const vp_entity *)a)->id, y = ((const vp_entity *)b)->id;
    return (x > y) - (x < y);
}

static int cmp_light(const void *a, const void *b)
{
    uint64_t x = ((const vp_light *)a)->id, y = ((const vp_light *)b)->id;
    return (x > y) - (x < y);
}

static int read_entities(exporter *x)
{
    uint32_t page = vtc_server(x->k->c)->max_batch < 4096 ? vtc_server(x->k->c)->max_batch : 4096;
    uint64_t cursor = 0;
    uint32_t cap = 0;
    do {
        vp_list_reply lr;
        int rc = vtc_list(x->k->c, cursor, page, &lr);
        if (rc) return server_fail(x->k, "export", rc);
        if (!vp_grow32((void **)&x->ent, &cap, x->nent + lr.batch.count, sizeof *x->ent)) goto nomem;
        for (uint32_t i = 0; i < lr.batch.count; i++)
            if (vp_entity_get(&lr.batch, i, &x->ent[x->nent++])) return server_fail(x->k, "export", VP_ERR_INVALID);
        cursor = lr.next_cursor;
    } while (cursor);
    /* in id order: the file reads back (sublevel load) in the same order */
    qsort(x->ent, x->nent, sizeof *x->ent, cmp_entity);
    return 0;
nomem:
    fprintf(stderr, "%s: export: out of memory\n", g_prog);
    return 1;
}

static float *copy_floats(const uint8_t *p, size_t n)
{
    if (!p) return NULL;
    float *f = malloc(n * sizeof *f + 1);
    for (size_t i = 0; f && i < n; i++) f[i] = vp_ld_f32(p + 4 * i);
    return f;
}

/* MESH_GET of every class a transform entity uses */
static int read_meshes(exporter *x)
{
    static uint8_t seen[65536];
    memset(seen, 0, sizeof seen);
    for (uint32_t i = 0; i < x->nent; i++)
        if (x->ent[i].flags & VP_ENT_TRANSFORM) seen[x->ent[i].class_id] = 1;
    uint32_t n = 0;
    for (uint32_t c = 0; c < 65536; c++) n += seen[c];
    x->mesh = calloc((size_t)n + 1, sizeof *x->mesh);
    if (!x->mesh) return fprintf(stderr, "%s: export: out of memory\n", g_prog), 1;
    for (uint32_t c = 0; c < 65536; c++) {
        if (!seen[c]) continue;
        vp_mesh m;
        int rc = vtc_mesh_get(x->k->c, (uint16_t)c, &m);
        if (rc) return server_fail(x->k, "export", rc);
        ex_mesh *e = &x->mesh[x->nmesh++];
        e->class_id = (uint16_t)c;
        e->nv = m.vertex_count;
        e->ni = m.index_count;
        e->pos = copy_floats(m.positions, 3 * (size_t)e->nv);
        e->nrm = copy_floats(m.normals, 3 * (size_t)e->nv);
        e->uv = copy_floats(m.uvs, 2 * (size_t)e->nv);
        e->tan = copy_floats(m.tangents, 4 * (size_t)e->nv);
        e->idx = malloc((size_t)e->ni * 4 + 1);
        if (!e->pos || (m.normals && !e->nrm) || (m.uvs && !e->uv) || (m.tangents && !e->tan) || !e->idx)
            return fprintf(stderr, "%s: export: out of memory\n", g_prog), 1;
        for (uint32_t k = 0; k < e->ni; k++) e->idx[k] = vp_ld_u32(m.indices + 4 * (size_t)k);
    }
    return 0;
}

static int read_materials(exporter *x)
{
    uint32_t cursor = 0, cap = 0, page = vtc_server(x->k->c)->max_batch;
    do {
        vp_page_reply r;
        int rc = vtc_material_list(x->k->c, cursor, page, &r);
        if (rc == VP_ERR_TYPE) return 0; /* a daemon without materials */
        if (rc) return server_fail(x->k, "export", rc);
        if (!vp_grow32((void **)&x->mat, &cap, x->nmat + r.count, sizeof *x->mat))
            return fprintf(stderr, "%s: export: out of memory\n", g_prog), 1;
        for (uint32_t i = 0; i < r.count; i++)
            if (vp_material_get(r.recs, r.count, i, &x->mat[x->nmat++]))
                return server_fail(x->k, "export", VP_ERR_INVALID);
        cursor = r.next_cursor;
    } while (cursor);
    return 0;
}

/* TEXTURE_GET of every texture a material names, whole, in id order */
static int read_textures(exporter *x)
{
    uint32_t cap = 0;
    for (uint32_t i = 0; i < x->nmat; i++)
        for (int s = 0; s < VP_TEX_SLOTS; s++) {
            uint32_t id = x->mat[i].tex[s].texture;
            bool have = !id;
            for (uint32_t t = 0; t < x->ntex && !have; t++) have = x->tex[t].id == id;
            if (have) continue;
            if (!vp_grow32((void **)&x->tex, &cap, x->ntex + 1, sizeof *x->tex))
                return fprintf(stderr, "%s: export: out of memory\n", g_prog), 1;
            ex_tex *t = &x->tex[x->ntex++];
            *t = (ex_tex){.id = id};
            uint32_t off = 0;
            do {
                vp_texture_put r;
                int rc = vtc_texture_get(x->k->c, id, off, UINT32_MAX, &r);
                if (rc) return server_fail(x->k, "export", rc);
                if (!t->bytes && !(t->bytes = malloc(r.total)))
                    return fprintf(stderr, "%s: export: out of memory\n", g_prog), 1;
                if (off == 0) t->n = r.total, t->format = r.format;
                if (r.total != t->n) return server_fail(x->k, "export", VP_ERR_INVALID);
                memcpy(t->bytes + off, r.data, r.len);
                off += r.len;
            } while (off < t->n);
        }
    for (uint32_t i = 1; i < x->ntex; i++) /* id order (few: insertion) */
        for (uint32_t j = i; j > 0 && x->tex[j - 1].id > x->tex[j].id; j--) {
            ex_tex tmp = x->tex[j];
            x->tex[j] = x->tex[j - 1];
            x->tex[j - 1] = tmp;
        }
    return 0;
}

static int read_lights(exporter *x)
{
    uint64_t cursor = 0;
    uint32_t cap = 0, page = vtc_server(x->k->c)->max_batch;
    do {
        vp_page_reply r;
        int rc = vtc_light_list(x->k->c, cursor, page, &r);
        if (rc) return server_fail(x->k, "export", rc);
        if (!vp_grow32((void **)&x->light, &cap, x->nlight + r.count, sizeof *x->light))
            return fprintf(stderr, "%s: export: out of memory\n", g_prog), 1;
        for (uint32_t i = 0; i < r.count; i++)
            if (vp_light_get(r.recs, r.count, i, &x->light[x->nlight++]))
                return server_fail(x->k, "export", VP_ERR_INVALID);
        cursor = r.next_cursor;
    } while (cursor);
    qsort(x->light, x->nlight, sizeof *x->light, cmp_light);
    int rc = vtc_env_get(x->k->c, &x->env);
    if (rc == VP_ERR_TYPE) return 0; /* a daemon without an environment: no sun */
    if (rc) return server_fail(x->k, "export", rc);
    double l2 = 0;
    for (int a = 0; a < 3; a++) l2 += (double)x->env.sun_dir[a] * x->env.sun_dir[a];
    x->has_env = l2 > 0 && x->env.sun_lux > 0;
    return 0;
}

/* ---- the JSON ---------------------------------------------------------------------- */

static json_object *jnum(double v)
{
    return json_object_new_double(v);
}

static json_object *jarr(const double *v, int n)
{
    json_object *a = json_object_new_array();
    for (int i = 0; i < n; i++) json_object_array_add(a, jnum(v[i]));
    return a;
}

static json_object *jarrf(const float *v, int n)
{
    double d[4];
    for (int i = 0; i < n; i++) d[i] = v[i];
    return jarr(d, n);
}

static void jset(json_object *o, const char *k, json_object *v)
{
    json_object_object_add(o, k, v);
}

/* A bufferView of data[0..n) (4-byte aligned in the buffer): its index. */
static int add_view(exporter *x, const void *data, size_t n, int target)
{
    while (x->bin.len % 4) vp_put_u8(&x->bin, 0);
    size_t off = x->bin.len;
    vp_put_bytes(&x->bin, data, n);
    json_object *v = json_object_new_object();
    jset(v, "buffer", json_object_new_int(0));
    jset(v, "byteOffset", json_object_new_int64((int64_t)off));
    jset(v, "byteLength", json_object_new_int64((int64_t)n));
    if (target) jset(v, "target", json_object_new_int(target));
    json_object_array_add(x->views, v);
    return (int)json_object_array_length(x->views) - 1;
}

/* little-endian copies of the arrays (the file's byte order) */
static int add_f32_accessor(exporter *x, const float *f, uint32_t count, int comps, const char *type, bool minmax)
{
    size_t n = (size_t)count * comps;
    uint8_t *b = malloc(4 * n + 1);
    if (!b) return -1;
    for (size_t i = 0; i < n; i++) {
        uint32_t u;
        memcpy(&u, &f[i], 4);
        vp_st_u32(b + 4 * i, u);
    }
    int view = add_view(x, b, 4 * n, 34962);
    free(b);
    json_object *a = json_object_new_object();
    jset(a, "bufferView", json_object_new_int(view));
    jset(a, "componentType", json_object_new_int(5126));
    jset(a, "count", json_object_new_int64(count));
    jset(a, "type", json_object_new_string(type));
    if (minmax) {
        float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
        for (uint32_t v = 0; v < count; v++)
            for (int c = 0; c < 3; c++) lo[c] = fminf(lo[c], f[3 * v + c]), hi[c] = fmaxf(hi[c], f[3 * v + c]);
        jset(a, "min", jarrf(lo, 3));
        jset(a, "max", jarrf(hi, 3));
    }
    json_object_array_add(x->accessors, a);
    return (int)json_object_array_length(x->accessors) - 1;
}

static int add_index_accessor(exporter *x, const uint32_t *idx, uint32_t count)
{
    uint8_t *b = malloc(4 * (size_t)count + 1);
    if (!b) return -1;
    for (uint32_t i = 0; i < count; i++) vp_st_u32(b + 4 * (size_t)i, idx[i]);
    int view = add_view(x, b, 4 * (size_t)count, 34963);
    free(b);
    json_object *a = json_object_new_object();
    jset(a, "bufferView", json_object_new_int(view));
    jset(a, "componentType", json_object_new_int(5125));
    jset(a, "count", json_object_new_int64(count));
    jset(a, "type", json_object_new_string("SCALAR"));
    json_object_array_add(x->accessors, a);
    return (int)json_object_array_length(x->accessors) - 1;
}

static int mesh_accessors(exporter *x, ex_mesh *m)
{
    m->acc_pos = add_f32_accessor(x, m->pos, m->nv, 3, "VEC3", true);
    m->acc_nrm = m->nrm ? add_f32_accessor(x, m->nrm, m->nv, 3, "VEC3", false) : -1;
    m->acc_uv = m->uv ? add_f32_accessor(x, m->uv, m->nv, 2, "VEC2", false) : -1;
    m->acc_tan = m->tan ? add_f32_accessor(x, m->tan, m->nv, 4, "VEC4", false) : -1;
    m->acc_idx = add_index_accessor(x, m->idx, m->ni);
    return m->acc_pos < 0 || m->acc_idx < 0 || (m->nrm && m->acc_nrm < 0) || (m->uv && m->acc_uv < 0) ||
                   (m->tan && m->acc_tan < 0)
               ? -1
               : 0;
}

/* the unit box (-1..1, 24 vertices with face normals) a bounds entity is drawn as */
static void box_mesh(ex_mesh *m, float pos[72], float nrm[72], uint32_t idx[36])
{
    static const int axes[6][3][3] = {{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}},  {{-1, 0, 0}, {0, 0, 1}, {0, 1, 0}},
                                      {{0, 1, 0}, {0, 0, 1}, {1, 0, 0}},  {{0, -1, 0}, {1, 0, 0}, {0, 0, 1}},
                                      {{0, 0, 1}, {1, 0, 0}, {0, 1, 0}},  {{0, 0, -1}, {0, 1, 0}, {1, 0, 0}}};
    static const int su[4] = {-1, 1, 1, -1}, sv[4] = {-1, -1, 1, 1};
    for (int f = 0; f < 6; f++) {
        for (int c = 0; c < 4; c++)
            for (int k = 0; k < 3; k++) {
                pos[3 * (4 * f + c) + k] = (float)(axes[f][0][k] + su[c] * axes[f][1][k] + sv[c] * axes[f][2][k]);
                nrm[3 * (4 * f + c) + k] = (float)axes[f][0][k];
            }
        const uint32_t b = 4 * (uint32_t)f, tri[6] = {b, b + 1, b + 2, b, b + 2, b + 3};
        memcpy(idx + 6 * f, tri, sizeof tri);
    }
    *m = (ex_mesh){.class_id = 0, .nv = 24, .ni = 36, .pos = pos, .nrm = nrm, .idx = idx};
}

/* The glTF mesh of (class mesh m, material id): made on first use. */
static int gltf_mesh(exporter *x, ex_mesh *m, int mi, uint32_t material, const char *name)
{
    for (uint32_t i = 0; i < x->nmesh_of; i++)
        if (x->mesh_of[i][0] == mi && (uint32_t)x->mesh_of[i][1] == material) return x->mesh_idx[i];
    if (m->acc_pos < 0 && mesh_accessors(x, m)) return -1;
    json_object *attr = json_object_new_object(), *prim = json_object_new_object();
    jset(attr, "POSITION", json_object_new_int(m->acc_pos));
    if (m->acc_nrm >= 0) jset(attr, "NORMAL", json_object_new_int(m->acc_nrm));
    if (m->acc_uv >= 0) jset(attr, "TEXCOORD_0", json_object_new_int(m->acc_uv));
    if (m->acc_tan >= 0) jset(attr, "TANGENT", json_object_new_int(m->acc_tan));
    jset(prim, "attributes", attr);
    jset(prim, "indices", json_object_new_int(m->acc_idx));
    jset(prim, "mode", json_object_new_int(4));
    for (uint32_t i = 0; material && i < x->nmat; i++)
        if (x->mat[i].id == material) jset(prim, "material", json_object_new_int((int)i));
    json_object *mesh = json_object_new_object(), *prims = json_object_new_array();
    json_object_array_add(prims, prim);
    jset(mesh, "name", json_object_new_string(name));
    jset(mesh, "primitives", prims);
    json_object_array_add(x->meshes, mesh);
    int idx = (int)json_object_array_length(x->meshes) - 1;
    x->mesh_of[x->nmesh_of][0] = mi;
    x->mesh_of[x->nmesh_of][1] = (int)material;
    x->mesh_idx[x->nmesh_of++] = idx;
    return idx;
}

static json_object *node_trs(const char *name, const double pos[3], const float rot[4], const float scale[3])
{
    json_object *n = json_object_new_object();
    jset(n, "name", json_object_new_string(name));
    jset(n, "translation", jarr(pos, 3));
    if (rot) jset(n, "rotation", jarrf(rot, 4));
    if (scale) jset(n, "scale", jarrf(scale, 3));
    return n;
}

static int entity_nodes(exporter *x, json_object *nodes, json_object *scene_nodes)
{
    static float bpos[72], bnrm[72];
    static uint32_t bidx[36];
    ex_mesh box;
    box_mesh(&box, bpos, bnrm, bidx);
    box.acc_pos = -1;
    x->mesh_of = calloc((size_t)x->nent + 1, sizeof *x->mesh_of);
    x->mesh_idx = calloc((size_t)x->nent + 1, sizeof *x->mesh_idx);
    if (!x->mesh_of || !x->mesh_idx) return -1;
    for (uint32_t i = 0; i < x->nmesh; i++) x->mesh[i].acc_pos = -1;
    for (uint32_t i = 0; i < x->nent; i++) {
        const vp_entity *e = &x->ent[i];
        char name[40];
        snprintf(name, sizeof name, "entity_%llu", (unsigned long long)e->id);
        json_object *n;
        int mesh;
        if (e->flags & VP_ENT_TRANSFORM) {
            int mi = 0;
            while (x->mesh[mi].class_id != e->class_id) mi++;
            char mname[32];
            snprintf(mname, sizeof mname, "class_%u", e->class_id);
            mesh = gltf_mesh(x, &x->mesh[mi], mi, e->material, mname);
            n = node_trs(name, e->pos, e->rot, e->scale);
        } else {
            /* the unit box on the AABB: centre and half extents */
            double c[3];
            float s[3];
            for (int a = 0; a < 3; a++) {
                c[a] = (e->aabb[a] + e->aabb[3 + a]) / 2;
                s[a] = (float)((e->aabb[3 + a] - e->aabb[a]) / 2);
                if (!(s[a] > 0)) s[a] = 1e-6f; /* a flat box: glTF takes no zero scale */
            }
            mesh = gltf_mesh(x, &box, -1, e->material, "bounds_box");
            n = node_trs(name, c, NULL, s);
        }
        if (mesh < 0) return -1;
        jset(n, "mesh", json_object_new_int(mesh));
        if (e->flags & VP_ENT_DYNAMIC) {
            json_object *ex = json_object_new_object();
            jset(ex, "vantage_dynamic", json_object_new_boolean(1));
            jset(n, "extras", ex);
        }
        json_object_array_add(nodes, n);
        json_object_array_add(scene_nodes, json_object_new_int((int)json_object_array_length(nodes) - 1));
    }
    return 0;
}

/* The rotation taking glTF's light axis (0, 0, -1) to unit d. */
static void light_rotation(const double d[3], float q[4])
{
    /* axis (0,0,-1) x d, angle from the dot product -d.z (half-angle form) */
    double w = 1 - d[2], v[3] = {d[1], -d[0], 0};
    if (w < 1e-9) {
        q[0] = 1, q[1] = q[2] = q[3] = 0; /* straight back: half a turn about x */
        return;
    }
    double l = sqrt(v[0] * v[0] + v[1] * v[1] + w * w);
    q[0] = (float)(v[0] / l), q[1] = (float)(v[1] / l), q[2] = 0, q[3] = (float)(w / l);
}

static json_object *light_color(const float c[3])
{
    return jarrf(c, 3);
}

static void light_nodes(exporter *x, json_object *nodes, json_object *scene_nodes)
{
    json_object *lights = json_object_new_array();
    if (x->has_env) {
        json_object *l = json_object_new_object();
        jset(l, "name", json_object_new_string("sun"));
        jset(l, "type", json_object_new_string("directional"));
        jset(l, "color", light_color(x->env.sun_color));
        jset(l, "intensity", jnum(x->env.sun_lux)); /* lux */
        json_object_array_add(lights, l);
        double d[3] = {-x->env.sun_dir[0], -x->env.sun_dir[1], -x->env.sun_dir[2]}, o[3] = {0, 0, 0};
        float q[4];
        light_rotation(d, q);
        json_object *n = node_trs("sun", o, q, NULL), *ext = json_object_new_object(),
                    *kl = json_object_new_object();
        jset(kl, "light", json_object_new_int(0));
        jset(ext, "KHR_lights_punctual", kl);
        jset(n, "extensions", ext);
        json_object_array_add(nodes, n);
        json_object_array_add(scene_nodes, json_object_new_int((int)json_object_array_length(nodes) - 1));
    }
    for (uint32_t i = 0; i < x->nlight; i++) {
        const vp_light *L = &x->light[i];
        char name[40];
        snprintf(name, sizeof name, "light_%llu", (unsigned long long)L->id);
        json_object *l = json_object_new_object();
        jset(l, "name", json_object_new_string(name));
        jset(l, "type", json_object_new_string(L->kind == VP_LIGHT_SPOT ? "spot" : "point"));
        jset(l, "color", light_color(L->color));
        jset(l, "intensity", jnum(L->intensity)); /* candela */
        jset(l, "range", jnum(L->range));
        if (L->kind == VP_LIGHT_SPOT) {
            json_object *s = json_object_new_object();
            jset(s, "innerConeAngle", jnum(acos(fmin(fmax(L->inner_cos, -1), 1))));
            jset(s, "outerConeAngle", jnum(acos(fmin(fmax(L->outer_cos, -1), 1))));
            jset(l, "spot", s);
        }
        json_object_array_add(lights, l);
        double d[3] = {L->dir[0], L->dir[1], L->dir[2]};
        float q[4];
        light_rotation(d, q);
        json_object *n = node_trs(name, L->pos, L->kind == VP_LIGHT_SPOT ? q : NULL, NULL),
                    *ext = json_object_new_object(), *kl = json_object_new_object();
        jset(kl, "light", json_object_new_int((int)json_object_array_length(lights) - 1));
        jset(ext, "KHR_lights_punctual", kl);
        jset(n, "extensions", ext);
        json_object_array_add(nodes, n);
        json_object_array_add(scene_nodes, json_object_new_int((int)json_object_array_length(nodes) - 1));
    }
    if (json_object_array_length(lights)) {
        json_object *ext = json_object_new_object(), *kl = json_object_new_object();
        jset(kl, "lights", lights);
        jset(ext, "KHR_lights_punctual", kl);
        jset(x->root, "extensions", ext);
    } else {
        json_object_put(lights);
    }
}

/* glTF's sampler enums from VP_WRAP_* / VP_FILTER_* (the same order) */
static const int gl_wrap[3] = {10497, 33071, 33648};
static const int gl_filter[6] = {9728, 9729, 9984, 9985, 9986, 9987};

/* A textureInfo for slot t: the glTF texture (image, sampler) found or made. */
static json_object *texture_info(exporter *x, const vp_texref *t)
{
    int image = 0;
    while ((uint32_t)image < x->ntex && x->tex[image].id != t->texture) image++;
    json_object *s = json_object_new_object();
    jset(s, "wrapS", json_object_new_int(gl_wrap[t->wrap_s]));
    jset(s, "wrapT", json_object_new_int(gl_wrap[t->wrap_t]));
    jset(s, "minFilter", json_object_new_int(gl_filter[t->min_filter]));
    jset(s, "magFilter", json_object_new_int(gl_filter[t->mag_filter]));
    int sampler = -1;
    for (size_t i = 0; i < json_object_array_length(x->samplers) && sampler < 0; i++)
        if (json_object_equal(json_object_array_get_idx(x->samplers, i), s)) sampler = (int)i;
    if (sampler < 0) {
        json_object_array_add(x->samplers, s);
        sampler = (int)json_object_array_length(x->samplers) - 1;
    } else {
        json_object_put(s);
    }
    int tex = -1;
    for (size_t i = 0; i < json_object_array_length(x->textures) && tex < 0; i++) {
        json_object *o = json_object_array_get_idx(x->textures, i), *a, *b;
        if (json_object_object_get_ex(o, "source", &a) && json_object_object_get_ex(o, "sampler", &b) &&
            json_object_get_int(a) == image && json_object_get_int(b) == sampler)
            tex = (int)i;
    }
    if (tex < 0) {
        json_object *o = json_object_new_object();
        jset(o, "source", json_object_new_int(image));
        jset(o, "sampler", json_object_new_int(sampler));
        json_object_array_add(x->textures, o);
        tex = (int)json_object_array_length(x->textures) - 1;
    }
    json_object *info = json_object_new_object();
    jset(info, "index", json_object_new_int(tex));
    if (t->offset[0] || t->offset[1] || t->scale[0] != 1 || t->scale[1] != 1 || t->rotation) {
        json_object *tt = json_object_new_object(), *ext = json_object_new_object();
        jset(tt, "offset", jarrf(t->offset, 2));
        jset(tt, "scale", jarrf(t->scale, 2));
        jset(tt, "rotation", jnum(t->rotation));
        jset(ext, "KHR_texture_transform", tt);
        jset(info, "extensions", ext);
        x->used_tt = true;
    }
    return info;
}

static json_object *material_json(exporter *x, const vp_material *m)
{
    json_object *o = json_object_new_object(), *pbr = json_object_new_object();
    char name[32];
    snprintf(name, sizeof name, "material_%u", m->id);
    jset(o, "name", json_object_new_string(name));
    jset(pbr, "baseColorFactor", jarrf(m->base_color, 4));
    jset(pbr, "metallicFactor", jnum(m->metallic));
    jset(pbr, "roughnessFactor", jnum(m->roughness));
    if (m->tex[VP_TEX_BASE].texture) jset(pbr, "baseColorTexture", texture_info(x, &m->tex[VP_TEX_BASE]));
    if (m->tex[VP_TEX_MR].texture) jset(pbr, "metallicRoughnessTexture", texture_info(x, &m->tex[VP_TEX_MR]));
    jset(o, "pbrMetallicRoughness", pbr);
    if (m->tex[VP_TEX_NORMAL].texture) {
        json_object *n = texture_info(x, &m->tex[VP_TEX_NORMAL]);
        jset(n, "scale", jnum(m->normal_scale));
        jset(o, "normalTexture", n);
    }
    if (m->tex[VP_TEX_EMISSIVE].texture) jset(o, "emissiveTexture", texture_info(x, &m->tex[VP_TEX_EMISSIVE]));
    jset(o, "emissiveFactor", jarrf(m->emissive, 3));
    if (m->emissive_strength != 1) {
        json_object *es = json_object_new_object(), *ext = json_object_new_object();
        jset(es, "emissiveStrength", jnum(m->emissive_strength));
        jset(ext, "KHR_materials_emissive_strength", es);
        jset(o, "extensions", ext);
        x->used_es = true;
    }
    jset(o, "alphaMode", json_object_new_string(m->alpha_mode == VP_ALPHA_MASK ? "MASK" : "OPAQUE"));
    if (m->alpha_mode == VP_ALPHA_MASK) jset(o, "alphaCutoff", jnum(m->alpha_cutoff));
    jset(o, "doubleSided", json_object_new_boolean(m->flags & VP_MAT_DOUBLE_SIDED));
    return o;
}

static int build_json(exporter *x)
{
    x->root = json_object_new_object();
    json_object *asset = json_object_new_object();
    jset(asset, "version", json_object_new_string("2.0"));
    jset(asset, "generator", json_object_new_string("vantage export"));
    jset(x->root, "asset", asset);
    x->views = json_object_new_array();
    x->accessors = json_object_new_array();
    x->meshes = json_object_new_array();
    x->samplers = json_object_new_array();
    x->textures = json_object_new_array();
    json_object *nodes = json_object_new_array(), *scene_nodes = json_object_new_array(),
                *materials = json_object_new_array(), *images = json_object_new_array();
    /* images first: their bufferViews, in texture id order */
    for (uint32_t i = 0; i < x->ntex; i++) {
        json_object *im = json_object_new_object();
        char name[32];
        snprintf(name, sizeof name, "texture_%u", x->tex[i].id);
        jset(im, "name", json_object_new_string(name));
        jset(im, "bufferView", json_object_new_int(add_view(x, x->tex[i].bytes, x->tex[i].n, 0)));
        jset(im, "mimeType", json_object_new_string(x->tex[i].format == VP_TEX_JPEG ? "image/jpeg" : "image/png"));
        json_object_array_add(images, im);
    }
    for (uint32_t i = 0; i < x->nmat; i++) json_object_array_add(materials, material_json(x, &x->mat[i]));
    if (entity_nodes(x, nodes, scene_nodes)) return -1;
    light_nodes(x, nodes, scene_nodes);
    json_object *scene = json_object_new_object(), *scenes = json_object_new_array();
    jset(scene, "nodes", scene_nodes);
    json_object_array_add(scenes, scene);
    jset(x->root, "scene", json_object_new_int(0));
    jset(x->root, "scenes", scenes);
    jset(x->root, "nodes", nodes);
    jset(x->root, "meshes", x->meshes);
    jset(x->root, "materials", materials);
    jset(x->root, "textures", x->textures);
    jset(x->root, "samplers", x->samplers);
    jset(x->root, "images", images);
    jset(x->root, "accessors", x->accessors);
    jset(x->root, "bufferViews", x->views);
    json_object *buf = json_object_new_object(), *bufs = json_object_new_array();
    while (x->bin.len % 4) vp_put_u8(&x->bin, 0);
    jset(buf, "byteLength", json_object_new_int64((int64_t)x->bin.len));
    json_object_array_add(bufs, buf);
    jset(x->root, "buffers", bufs);
    json_object *used = json_object_new_array();
    if (x->has_env || x->nlight) json_object_array_add(used, json_object_new_string("KHR_lights_punctual"));
    if (x->used_tt) json_object_array_add(used, json_object_new_string("KHR_texture_transform"));
    if (x->used_es) json_object_array_add(used, json_object_new_string("KHR_materials_emissive_strength"));
    if (json_object_array_length(used)) jset(x->root, "extensionsUsed", used);
    else json_object_put(used);
    return x->bin.overflow ? -1 : 0;
}

/* ---- the GLB container ------------------------------------------------------------- */

/* 12-byte header, the JSON chunk padded with spaces, the BIN chunk padded
 * with zeros (glTF 2.0, "Binary glTF Layout") */
static int write_glb(exporter *x, const char *path)
{
    size_t jl;
    const char *json = json_object_to_json_string_length(x->root, JSON_C_TO_STRING_PLAIN, &jl);
    size_t jpad = (4 - jl % 4) % 4, blen = x->bin.len; /* a multiple of 4 already */
    size_t total = 12 + 8 + jl + jpad + (blen ? 8 + blen : 0);
    if (total > UINT32_MAX) {
        fprintf(stderr, "%s: export: the scene is %zu bytes as a .glb, more than its 4 GiB\n", g_prog, total);
        return 1;
    }
    FILE *f = fopen(path, "wb");
    if (!f) {
        fprintf(stderr, "%s: %s: %s\n", g_prog, path, strerror(errno));
        return 2;
    }
    uint8_t h[20];
    vp_st_u32(h, GLB_MAGIC);
    vp_st_u32(h + 4, 2);
    vp_st_u32(h + 8, (uint32_t)total);
    vp_st_u32(h + 12, (uint32_t)(jl + jpad));
    vp_st_u32(h + 16, GLB_JSON);
    bool ok = fwrite(h, 1, 20, f) == 20 && fwrite(json, 1, jl, f) == jl && fwrite("   ", 1, jpad, f) == jpad;
    if (blen) {
        vp_st_u32(h, (uint32_t)blen);
        vp_st_u32(h + 4, GLB_BIN);
        ok = ok && fwrite(h, 1, 8, f) == 8 && fwrite(x->bin.p, 1, blen, f) == blen;
    }
    if (fclose(f) || !ok) {
        fprintf(stderr, "%s: %s: cannot write: %s\n", g_prog, path, strerror(errno));
        return 2;
    }
    return 0;
}

static void exporter_free(exporter *x)
{
    for (uint32_t i = 0; i < x->nmesh; i++) {
        free(x->mesh[i].pos);
        free(x->mesh[i].nrm);
        free(x->mesh[i].uv);
        free(x->mesh[i].tan);
        free(x->mesh[i].idx);
    }
    for (uint32_t i = 0; i < x->ntex; i++) free(x->tex[i].bytes);
    free(x->ent);
    free(x->mesh);
    free(x->mat);
    free(x->tex);
    free(x->light);
    free(x->mesh_of);
    free(x->mesh_idx);
    vp_writer_free(&x->bin);
    if (x->root) json_object_put(x->root);
}

int cmd_export_glb(cli *k, const char *path)
{
    int rc = connect_cli(k, VP_ROLE_VIEWER);
    if (rc) return rc;
    exporter x = {.k = k};
    vp_writer_init_grow(&x.bin);
    double t0 = now_s();
    if (!(rc = read_entities(&x)) && !(rc = read_meshes(&x)) && !(rc = read_materials(&x)) &&
        !(rc = read_textures(&x)) && !(rc = read_lights(&x))) {
        if (build_json(&x)) {
            fprintf(stderr, "%s: export: out of memory\n", g_prog);
            rc = 1;
        } else if (!(rc = write_glb(&x, path))) {
            printf("%s: %u entities, %u meshes, %u materials, %u textures, %u lights%s in %.0f ms\n", path, x.nent,
                   x.nmesh, x.nmat, x.ntex, x.nlight, x.has_env ? " and the sun" : "", (now_s() - t0) * 1e3);
        }
    }
    exporter_free(&x);
    return rc;
}
