/*
 * city.c — the demo city on the scene model (`vantaged --scene demo`): a
 * 12 x 12 grid of blocks with pavements, streets with lane markings,
 * buildings placed from shared prototype meshes, textured facades with
 * windows that glow at night, glass towers, parks with trees, street lamps
 * (a pole, an emissive head and a point light each) and cars.
 *
 * It is built the way an editor would build it: every piece is a protocol
 * message (MESH_PUT, TEXTURE_PUT, MATERIAL_PUT, ENTITY_ADD with
 * transforms, attached OCCLUDER_PUT, LIGHT_PUT, ENV_SET: the day preset) applied through
 * edit_decode / edit_apply, so the city exercises the same checks as a
 * client's scene and a snapshot of it is an ordinary snapshot. The whole
 * city is one journal record (EDIT_CITY, aux = props): deterministic
 * from its seed, so a replay rebuilds it identically.
 *
 * Textures are made here, in a few kilobytes of code, and PNG-encoded
 * (vt_png_encode), as if uploaded: a facade tile (wall and window), a
 * window-light mask (one in three windows lit, 8 x 8 windows a tile,
 * mapped with KHR_texture_transform), and pavement slabs.
 *
 * Version 1's city (scene_build_demo, EDIT_DEMO) stays for journals that
 * recorded it; for the same reason a different city must be a new edit
 * kind, never a change to this one (a journal's EDIT_CITY replays this
 * code).
 */
#include "edit.h"
#include "vt_image.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define BLOCKS 12
#define BLOCK 60.0
#define STREET 16.0
#define FLOOR_H 3.5 /* metres a storey: one window row */
#define BAY_W 4.0   /* metres a window column */

/* mesh classes */
enum { C_BOX = 1, C_TREE = 2, C_PROTO = 16, N_PROTO = 24 };
/* textures */
enum { T_FACADE = 1, T_LIGHTS, T_PAVING };
/* materials */
enum {
    M_PAVEMENT = 1, M_PAINT, M_ROOF, M_GLASS, M_POLE, M_LAMP, M_GRASS, M_BARK, M_LEAVES,
    M_FACADE = 16, N_FACADE = 4, /* 16..19 */
    M_CAR = 32, N_CAR = 6,       /* 32..37 */
};
/* entity id ranges */
#define ID_BUILDING 1ull
#define ID_ROOF 100000ull
#define ID_BLOCK 200000ull
#define ID_DASH 300000ull
#define ID_TREE 400000ull
#define ID_LAMP 500000ull
#define ID_PROP 1000000ull

typedef struct city {
    scene *s;
    uint64_t rng;
    vp_entity *ents; /* the pending entity batch */
    uint32_t n, cap;
    int rc;
    scene_err err;
} city;

static double crand(city *c)
{
    return scene_rand(&c->rng);
}

/* Applies one encoded message (a frame from the encoders) as an edit. */
static void apply(city *c, const uint8_t *frame, size_t len)
{
    if (c->rc) return;
    edit e;
    edit_result r;
    const uint8_t *p = frame + VP_HEADER_SIZE;
    uint16_t type = (uint16_t)(frame[4] | frame[5] << 8);
    int rc = edit_decode(type, p, (uint32_t)(len - VP_HEADER_SIZE), 0, EDIT_LAYOUT, &e);
    if (rc) {
        edit_explain(&e, rc, &c->err);
        c->rc = rc;
        return;
    }
    c->rc = edit_apply(c->s, &e, &r, &c->err);
    edit_result_free(&r);
}

/* A writer of n bytes for one message; NULL (and c->rc) when out of memory. */
static uint8_t *wbuf(city *c, vp_writer *w, size_t n)
{
    uint8_t *b = c->rc ? NULL : malloc(n);
    if (!b && !c->rc) c->rc = scene_fail(&c->err, VP_ERR_BUSY, UINT32_MAX, "out of memory for the city");
    if (b) vp_writer_init(w, b, n);
    return b;
}

static void send_and_free(city *c, uint8_t *b, const vp_writer *w)
{
    if (b && !w->overflow) apply(c, b, w->len);
    else if (b && !c->rc) c->rc = scene_fail(&c->err, VP_ERR_INTERNAL, UINT32_MAX, "city message overflowed");
    free(b);
}

/* ---- meshes ------------------------------------------------------------------ */

/* A box w x h x d standing on its base centre (x, z in -w/2..w/2, y in
 * 0..h), 24 vertices, flat normals, tangents along u. uv_metric: UVs in
 * window bays and storeys (sides) and bays (top), else 0..1 a face. */
static void put_box(city *c, uint16_t cls, double w, double h, double d, bool uv_metric)
{
    float pos[24 * 3], nrm[24 * 3], uv[24 * 2], tan[24 * 4];
    uint32_t idx[36];
    /* per face: normal, u axis, v axis (unit), and the extents along them */
    static const int face[6][3][3] = {
        {{0, 0, 1}, {1, 0, 0}, {0, 1, 0}},   {{0, 0, -1}, {-1, 0, 0}, {0, 1, 0}}, {{1, 0, 0}, {0, 0, -1}, {0, 1, 0}},
        {{-1, 0, 0}, {0, 0, 1}, {0, 1, 0}},  {{0, 1, 0}, {1, 0, 0}, {0, 0, -1}},  {{0, -1, 0}, {1, 0, 0}, {0, 0, 1}}};
    const double half[3] = {w / 2, h / 2, d / 2}, centre[3] = {0, h / 2, 0};
    for (int f = 0; f < 6; f++) {
        const int *n = face[f][0], *u = face[f][1], *v = face[f][2];
        double eu = 0, ev = 0; /* half extents along u and v */
        for (int a = 0; a < 3; a++) eu += abs(u[a]) * half[a], ev += abs(v[a]) * half[a];
        for (int k = 0; k < 4; k++) {
            int su = (k == 1 || k == 2) ? 1 : -1, sv = k >= 2 ? 1 : -1;
            int vi = f * 4 + k;
            for (int a = 0; a < 3; a++) {
                pos[vi * 3 + a] = (float)(centre[a] + n[a] * half[a] + su * u[a] * eu + sv * v[a] * ev);
                nrm[vi * 3 + a] = (float)n[a];
                tan[vi * 4 + a] = (float)u[a];
            }
            tan[vi * 4 + 3] = 1;
            double us = uv_metric ? 2 * eu / BAY_W : 1, vs = uv_metric ? 2 * ev / (f < 4 ? FLOOR_H : BAY_W) : 1;
            uv[vi * 2] = (float)((su + 1) / 2 * us);
            uv[vi * 2 + 1] = (float)((1 - sv) / 2 * vs); /* v down the face, as images are stored */
        }
        const uint32_t q[6] = {0, 1, 2, 0, 2, 3};
        for (int k = 0; k < 6; k++) idx[f * 6 + k] = (uint32_t)(f * 4) + q[k];
    }
    vp_writer wr;
    uint8_t *b = wbuf(c, &wr, vp_size_mesh_uv(24, 36, true, true, true));
    if (b) vp_enc_mesh_uv(&wr, 0, cls, pos, nrm, uv, tan, 24, idx, 36);
    send_and_free(c, b, &wr);
}

/* A tree's canopy: an octahedron-based sphere, radius 1, centre at y = 1
 * (scaled per tree), smooth normals, UVs from longitude and latitude. */
static void put_tree(city *c)
{
    enum { LON = 12, LAT = 7, NV = (LON + 1) * (LAT + 1), NI = LON * (LAT - 1) * 6 };
    float pos[NV * 3], nrm[NV * 3], uv[NV * 2];
    uint32_t idx[NI], ni = 0;
    for (int j = 0; j <= LAT; j++)
        for (int i = 0; i <= LON; i++) {
            double th = M_PI * j / LAT, ph = 2 * M_PI * i / LON;
            double n[3] = {sin(th) * cos(ph), cos(th), -sin(th) * sin(ph)};
            int v = j * (LON + 1) + i;
            for (int a = 0; a < 3; a++) nrm[v * 3 + a] = (float)n[a], pos[v * 3 + a] = (float)(n[a] + (a == 1));
            uv[v * 2] = (float)i / LON;
            uv[v * 2 + 1] = (float)j / LAT;
        }
    for (int j = 0; j < LAT; j++)
        for (int i = 0; i < LON; i++) {
            uint32_t a = (uint32_t)(j * (LON + 1) + i), b = a + LON + 1;
            if (j) idx[ni++] = a, idx[ni++] = b, idx[ni++] = a + 1;         /* no slivers at the poles */
            if (j < LAT - 1) idx[ni++] = a + 1, idx[ni++] = b, idx[ni++] = b + 1;
        }
    vp_writer w;
    uint8_t *b = wbuf(c, &w, vp_size_mesh_uv(NV, ni, true, true, false));
    if (b) vp_enc_mesh_uv(&w, 0, C_TREE, pos, nrm, uv, NULL, NV, idx, ni);
    send_and_free(c, b, &w);
}

/* ---- textures ------------------------------------------------------------------ */

static void put_texture(city *c, uint32_t id, uint32_t w, uint32_t h, const uint8_t *rgba)
{
    uint8_t *png = NULL;
    size_t len = 0;
    char why[200];
    if (c->rc) return;
    if (vt_png_encode(w, h, rgba, (size_t)w * 4, false, 6, &png, &len, why, sizeof why)) {
        c->rc = scene_fail(&c->err, VP_ERR_BUSY, UINT32_MAX, "city texture %u: %s", id, why);
        return;
    }
    vp_writer wr;
    uint8_t *b = wbuf(c, &wr, vp_size_texture_put((uint32_t)len));
    if (b)
        vp_enc_texture_put(&wr, 0, &(vp_texture_put){.id = id, .format = VP_TEX_PNG, .flags = VP_TEX_SRGB,
                                                     .total = (uint32_t)len, .len = (uint32_t)len, .data = png});
    send_and_free(c, b, &wr);
    free(png);
}

static void px(uint8_t *img, uint32_t w, uint32_t x, uint32_t y, int r, int g, int b)
{
    uint8_t *p = img + ((size_t)y * w + x) * 4;
    p[0] = (uint8_t)(r < 0 ? 0 : r > 255 ? 255 : r);
    p[1] = (uint8_t)(g < 0 ? 0 : g > 255 ? 255 : g);
    p[2] = (uint8_t)(b < 0 ? 0 : b > 255 ? 255 : b);
    p[3] = 255;
}

static void put_textures(city *c)
{
    enum { F = 64, L = 256, P = 64 };
    uint8_t *img = malloc((size_t)L * L * 4);
    if (!img) {
        c->rc = scene_fail(&c->err, VP_ERR_BUSY, UINT32_MAX, "out of memory for the city's textures");
        return;
    }
    /* facade bay, 4 m x 3.5 m: light wall (tinted by each material's base
       colour), a recessed window with a frame, a sill below it */
    for (uint32_t y = 0; y < F; y++)
        for (uint32_t x = 0; x < F; x++) {
            int n = (int)(crand(c) * 10) - 5;
            bool win = x >= 12 && x < 52 && y >= 12 && y < 50, frame = x >= 10 && x < 54 && y >= 10 && y < 52;
            bool sill = x >= 8 && x < 56 && y >= 52 && y < 55;
            if (win) px(img, F, x, y, 46 + n / 2 + (int)(y / 4), 58 + n / 2 + (int)(y / 4), 72 + (int)(y / 3));
            else if (frame) px(img, F, x, y, 70, 70, 72);
            else if (sill) px(img, F, x, y, 150, 150, 150);
            else px(img, F, x, y, 225 + n, 222 + n, 215 + n);
        }
    put_texture(c, T_FACADE, F, F, img);
    /* window lights: 8 x 8 bays a tile, one in three lit, warm, of
       varying brightness; the window area of each bay as above */
    memset(img, 0, (size_t)L * L * 4);
    for (uint32_t by = 0; by < 8; by++)
        for (uint32_t bx = 0; bx < 8; bx++) {
            bool lit = crand(c) < 0.33;
            double k = 0.45 + 0.55 * crand(c), cool = crand(c) < 0.2;
            for (uint32_t y = 0; y < 32; y++)
                for (uint32_t x = 0; x < 32; x++) {
                    bool win = x >= 6 && x < 26 && y >= 6 && y < 25;
                    double v = lit && win ? k : 0;
                    px(img, L, bx * 32 + x, by * 32 + y, (int)(v * (cool ? 200 : 255)), (int)(v * (cool ? 220 : 190)),
                       (int)(v * (cool ? 255 : 120)));
                }
        }
    put_texture(c, T_LIGHTS, L, L, img);
    /* pavement: 1 m slabs (32 px each) with grout, a little noise */
    for (uint32_t y = 0; y < P; y++)
        for (uint32_t x = 0; x < P; x++) {
            int n = (int)(crand(c) * 16) - 8;
            bool grout = x % 32 == 0 || y % 32 == 0;
            int g = grout ? 110 : 170 + n;
            px(img, P, x, y, g, g - 2, g - 6);
        }
    put_texture(c, T_PAVING, P, P, img);
    free(img);
}

/* ---- materials ------------------------------------------------------------------- */

static vp_material mat(uint32_t id, float r, float g, float b, float metallic, float rough)
{
    vp_material m = {.id = id, .base_color = {r, g, b, 1}, .metallic = metallic, .roughness = rough,
                     .emissive_strength = 1, .normal_scale = 1};
    for (int k = 0; k < VP_TEX_SLOTS; k++)
        m.tex[k] = (vp_texref){.wrap_s = VP_WRAP_REPEAT, .wrap_t = VP_WRAP_REPEAT,
                               .min_filter = VP_FILTER_LINEAR_MIP_LINEAR, .mag_filter = VP_FILTER_LINEAR,
                               .scale = {1, 1}};
    return m;
}

static void put_materials(city *c)
{
    vp_material m[64];
    uint32_t n = 0;
    m[n] = mat(M_PAVEMENT, 1, 1, 1, 0, 0.85f);
    m[n].tex[VP_TEX_BASE].texture = T_PAVING;
    m[n].tex[VP_TEX_BASE].scale[0] = m[n].tex[VP_TEX_BASE].scale[1] = 30; /* a tile (two 1 m slabs) every 2 m of the 60 m block */
    n++;
    m[n++] = mat(M_PAINT, 0.8f, 0.8f, 0.75f, 0, 0.6f);
    m[n++] = mat(M_ROOF, 0.18f, 0.18f, 0.2f, 0, 0.95f);
    m[n] = mat(M_GLASS, 0.05f, 0.08f, 0.11f, 0.0f, 0.08f);
    m[n].emissive[0] = 1, m[n].emissive[1] = 1, m[n].emissive[2] = 1;
    m[n].emissive_strength = 60; /* office lights behind the glass, cd/m2 */
    m[n].tex[VP_TEX_EMISSIVE].texture = T_LIGHTS;
    m[n].tex[VP_TEX_EMISSIVE].scale[0] = m[n].tex[VP_TEX_EMISSIVE].scale[1] = 0.125f;
    n++;
    m[n++] = mat(M_POLE, 0.35f, 0.36f, 0.38f, 1, 0.45f);
    m[n] = mat(M_LAMP, 1, 1, 1, 0, 0.5f);
    m[n].emissive[0] = 1, m[n].emissive[1] = 0.8f, m[n].emissive[2] = 0.55f;
    m[n].emissive_strength = 5000; /* a lamp's glowing head, cd/m2 */
    n++;
    m[n++] = mat(M_GRASS, 0.12f, 0.28f, 0.07f, 0, 0.95f);
    m[n++] = mat(M_BARK, 0.18f, 0.12f, 0.07f, 0, 0.9f);
    m[n++] = mat(M_LEAVES, 0.08f, 0.22f, 0.05f, 0, 0.8f);
    static const float tint[N_FACADE][3] = {{0.62f, 0.3f, 0.22f}, {0.85f, 0.75f, 0.6f}, {0.62f, 0.63f, 0.66f},
                                            {0.92f, 0.91f, 0.88f}};
    for (int k = 0; k < N_FACADE; k++) {
        m[n] = mat(M_FACADE + (uint32_t)k, tint[k][0], tint[k][1], tint[k][2], 0, 0.8f);
        m[n].tex[VP_TEX_BASE].texture = T_FACADE;
        m[n].emissive[0] = m[n].emissive[1] = m[n].emissive[2] = 1;
        m[n].emissive_strength = 25; /* lit rooms seen through the windows, cd/m2 */
        m[n].tex[VP_TEX_EMISSIVE].texture = T_LIGHTS;
        m[n].tex[VP_TEX_EMISSIVE].scale[0] = m[n].tex[VP_TEX_EMISSIVE].scale[1] = 0.125f;
        n++;
    }
    static const float paint[N_CAR][3] = {{0.6f, 0.04f, 0.03f}, {0.05f, 0.12f, 0.45f}, {0.85f, 0.85f, 0.85f},
                                          {0.03f, 0.03f, 0.03f}, {0.5f, 0.5f, 0.52f},   {0.7f, 0.55f, 0.1f}};
    for (int k = 0; k < N_CAR; k++) m[n++] = mat(M_CAR + (uint32_t)k, paint[k][0], paint[k][1], paint[k][2], 0.6f, 0.3f);
    vp_writer w;
    uint8_t *b = wbuf(c, &w, vp_size_materials(n));
    if (b) vp_enc_materials(&w, 0, m, n);
    send_and_free(c, b, &w);
}

/* ---- entities ------------------------------------------------------------------------ */

static void flush(city *c)
{
    if (!c->n) return;
    vp_writer w;
    uint8_t *b = wbuf(c, &w, vp_size_entities(c->n));
    if (b) vp_enc_entities(&w, VP_ENTITY_ADD, 0, c->ents, c->n);
    send_and_free(c, b, &w);
    c->n = 0;
}

/* Queues an entity: class cls, material, at (x, y, z) turned yaw radians
 * about +Y, scaled. */
static void ent(city *c, uint64_t id, uint16_t cls, uint32_t material, double x, double y, double z, double yaw,
                double sx, double sy, double sz, bool dynamic)
{
    if (c->n == c->cap) flush(c);
    vp_entity *e = &c->ents[c->n++];
    *e = (vp_entity){.id = id, .class_id = cls, .material = material,
                     .flags = VP_ENT_TRANSFORM | (dynamic ? VP_ENT_DYNAMIC : 0), .pos = {x, y, z},
                     .rot = {0, (float)sin(yaw / 2), 0, (float)cos(yaw / 2)},
                     .scale = {(float)sx, (float)sy, (float)sz}};
}

/* The prototype buildings: footprints in whole bays, heights in storeys
 * (most low, a few towers). */
static void put_prototypes(city *c, double dims[N_PROTO][3])
{
    for (int k = 0; k < N_PROTO; k++) {
        double w = BAY_W * (3 + (int)(crand(c) * 5)), d = BAY_W * (3 + (int)(crand(c) * 5));
        int floors = 3 + (int)(crand(c) * crand(c) * 24);
        dims[k][0] = w, dims[k][1] = floors * FLOOR_H, dims[k][2] = d;
        put_box(c, (uint16_t)(C_PROTO + k), w, floors * FLOOR_H, d, true);
    }
}

/* A building's occluder: its box, in its own space (it follows it). */
static void put_occluder(city *c, uint64_t id, const double dim[3])
{
    float t[12 * 9];
    double w = dim[0] / 2, h = dim[1], d = dim[2] / 2;
    const double v[8][3] = {{-w, 0, -d}, {w, 0, -d}, {w, h, -d}, {-w, h, -d},
                            {-w, 0, d},  {w, 0, d},  {w, h, d},  {-w, h, d}};
    static const int f[12][3] = {{0, 3, 2}, {0, 2, 1}, {4, 5, 6}, {4, 6, 7}, {0, 1, 5}, {0, 5, 4},
                                 {3, 7, 6}, {3, 6, 2}, {0, 4, 7}, {0, 7, 3}, {1, 2, 6}, {1, 6, 5}};
    for (int i = 0; i < 12; i++)
        for (int k = 0; k < 3; k++)
            for (int a = 0; a < 3; a++) t[i * 9 + k * 3 + a] = (float)v[f[i][k]][a];
    vp_writer w8;
    uint8_t *b = wbuf(c, &w8, vp_size_occluder(12));
    if (b) vp_enc_occluder_flags(&w8, 0, id, VP_OCC_ATTACHED, (const double[3]){0, 0, 0}, t, 12);
    send_and_free(c, b, &w8);
}

int scene_build_city(scene *s, uint32_t props, scene_err *err)
{
    city c = {.s = s, .rng = 0x5EED2019, .cap = 4096};
    c.ents = malloc(c.cap * sizeof *c.ents);
    if (!c.ents) return scene_fail(err, VP_ERR_BUSY, UINT32_MAX, "out of memory for the city");
    put_box(&c, C_BOX, 1, 1, 1, false);
    put_tree(&c);
    double dims[N_PROTO][3];
    put_prototypes(&c, dims);
    put_textures(&c);
    put_materials(&c);

    const double pitch = BLOCK + STREET, span = BLOCKS / 2.0 * pitch;
    uint64_t nb = 0, nd = 0, nt = 0;
    /* buildings: first, so their attached occluders can follow */
    uint64_t *occ_ids = malloc(BLOCKS * BLOCKS * 4 * sizeof *occ_ids);
    int *occ_proto = malloc(BLOCKS * BLOCKS * 4 * sizeof *occ_proto);
    if (!occ_ids || !occ_proto) c.rc = scene_fail(&c.err, VP_ERR_BUSY, UINT32_MAX, "out of memory for the city");
    for (int bx = 0; bx < BLOCKS && !c.rc; bx++)
        for (int bz = 0; bz < BLOCKS; bz++) {
            double x0 = (bx - BLOCKS / 2) * pitch + STREET / 2, z0 = (bz - BLOCKS / 2) * pitch + STREET / 2;
            double cx = x0 + BLOCK / 2, cz = z0 + BLOCK / 2;
            bool park = crand(&c) < 0.1;
            /* the block's pavement: a 20 cm slab */
            ent(&c, ID_BLOCK + (uint64_t)(bx * BLOCKS + bz), C_BOX, park ? M_GRASS : M_PAVEMENT, cx, 0, cz, 0,
                BLOCK, 0.2, BLOCK, false);
            if (park) {
                int trees = 6 + (int)(crand(&c) * 8);
                for (int t = 0; t < trees; t++) {
                    double tx = x0 + 5 + crand(&c) * (BLOCK - 10), tz = z0 + 5 + crand(&c) * (BLOCK - 10);
                    double r = 2 + crand(&c) * 2;
                    ent(&c, ID_TREE + 2 * nt, C_BOX, M_BARK, tx, 0.2, tz, 0, 0.5, 2.5, 0.5, false);
                    ent(&c, ID_TREE + 2 * nt + 1, C_TREE, M_LEAVES, tx, 1.8, tz, crand(&c) * 6.28, r, r * 1.2, r,
                        false);
                    nt++;
                }
                continue;
            }
            /* one to three buildings, on their own quarter of the block */
            int n = 1 + (int)(crand(&c) * 3);
            for (int k = 0; k < n; k++) {
                int p = (int)(crand(&c) * N_PROTO);
                int turn = (int)(crand(&c) * 4);
                double fw = turn & 1 ? dims[p][2] : dims[p][0], fd = turn & 1 ? dims[p][0] : dims[p][2];
                double qx = k == 1 ? BLOCK / 2 : 0, qz = k == 2 ? BLOCK / 2 : 0;
                double room_x = (n == 1 ? BLOCK : BLOCK / 2) - fw - 4, room_z = (n == 1 ? BLOCK : BLOCK / 2) - fd - 4;
                double px0 = x0 + qx + 2 + fw / 2 + (room_x > 0 ? crand(&c) * room_x : 0);
                double pz0 = z0 + qz + 2 + fd / 2 + (room_z > 0 ? crand(&c) * room_z : 0);
                bool glass = crand(&c) < 0.12;
                uint32_t material = glass ? M_GLASS : M_FACADE + (uint32_t)(crand(&c) * N_FACADE);
                uint64_t id = ID_BUILDING + nb;
                ent(&c, id, (uint16_t)(C_PROTO + p), material, px0, 0.2, pz0, turn * M_PI / 2, 1, 1, 1, false);
                /* the roof: a dark parapet slab on top */
                ent(&c, ID_ROOF + nb, C_BOX, M_ROOF, px0, 0.2 + dims[p][1], pz0, turn * M_PI / 2, dims[p][0] - 0.6,
                    0.4, dims[p][2] - 0.6, false);
                occ_ids[nb] = id;
                occ_proto[nb] = p;
                nb++;
            }
        }
    /* lane markings: a 3 m dash every 8 m down the middle of each street */
    for (int line = 0; line <= BLOCKS && !c.rc; line++) {
        double at = (line - BLOCKS / 2) * pitch;
        for (double t = -span + 4; t < span - 4; t += 8) {
            double m = fmod(t + span + pitch, pitch); /* from the last junction's centre */
            if (m < STREET / 2 + 1.5 || m > pitch - STREET / 2 - 1.5) continue; /* not across a junction */
            ent(&c, ID_DASH + nd++, C_BOX, M_PAINT, at, 0.005, t, 0, 0.15, 0.01, 3, false);
            ent(&c, ID_DASH + nd++, C_BOX, M_PAINT, t, 0.005, at, M_PI / 2, 0.15, 0.01, 3, false);
        }
    }
    /* street lamps at the pavement corners of every block, and their lights */
    enum { MAXL = 4 * BLOCKS * BLOCKS };
    vp_light *lights = malloc(MAXL * sizeof *lights);
    uint32_t nl = 0;
    if (!lights && !c.rc) c.rc = scene_fail(&c.err, VP_ERR_BUSY, UINT32_MAX, "out of memory for the city");
    for (int bx = 0; bx < BLOCKS && !c.rc; bx++)
        for (int bz = 0; bz < BLOCKS; bz++) {
            double x0 = (bx - BLOCKS / 2) * pitch + STREET / 2, z0 = (bz - BLOCKS / 2) * pitch + STREET / 2;
            for (int k = 0; k < 2; k++) {
                double lx = x0 + (k ? BLOCK - 1 : 1), lz = z0 + (k ? 1 : BLOCK - 1);
                uint64_t id = ID_LAMP + 2 * nl;
                ent(&c, id, C_BOX, M_POLE, lx, 0.2, lz, 0, 0.18, 6, 0.18, false);
                ent(&c, id + 1, C_BOX, M_LAMP, lx, 6.2, lz, 0, 0.7, 0.25, 0.7, false);
                lights[nl] = (vp_light){.id = 1 + nl, .kind = VP_LIGHT_POINT, .intensity = 2500, .range = 30,
                                        .color = {1.0f, 0.8f, 0.55f}, .pos = {lx, 6.0, lz}};
                nl++;
            }
        }
    /* cars: on the streets, along them, a quarter of them dynamic */
    for (uint32_t i = 0; i < props && !c.rc; i++) {
        int line = (int)(crand(&c) * (BLOCKS + 1));
        double at = (line - BLOCKS / 2) * pitch + (crand(&c) < 0.5 ? -3.5 : 3.5);
        double t = (crand(&c) * 2 - 1) * (span - 6);
        bool along_z = crand(&c) < 0.5;
        double yaw = (along_z ? 0 : M_PI / 2) + (crand(&c) < 0.5 ? M_PI : 0);
        uint32_t paint = M_CAR + (uint32_t)(crand(&c) * N_CAR);
        ent(&c, ID_PROP + i, C_BOX, paint, along_z ? at : t, 0, along_z ? t : at, yaw, 1.8, 1.45, 4.3, i % 4 == 0);
    }
    flush(&c);
    for (uint64_t i = 0; i < nb && !c.rc; i++) put_occluder(&c, occ_ids[i], dims[occ_proto[i]]);
    if (!c.rc && nl) {
        vp_writer w;
        uint8_t *b = wbuf(&c, &w, vp_size_lights(nl));
        if (b) vp_enc_lights(&w, 0, lights, nl);
        send_and_free(&c, b, &w);
    }
    if (!c.rc) { /* the day preset: the default sun and sky over asphalt */
        vp_env env;
        vp_env_preset("day", &env);
        vp_writer w;
        uint8_t *b = wbuf(&c, &w, vp_size_env());
        if (b) vp_enc_env(&w, VP_ENV_SET, 0, &env);
        send_and_free(&c, b, &w);
    }
    free(lights);
    free(occ_ids);
    free(occ_proto);
    free(c.ents);
    if (c.rc) {
        *err = c.err;
        return c.rc;
    }
    cull_world_commit(s->world);
    s->ev_added = s->ev_updated = s->ev_removed = 0;
    return VP_OK;
}
