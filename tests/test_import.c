/*
 * test_import.c — the scene model through import and export (issue 19,
 * item 7).
 *
 * The fixture is written here (so every number it holds is known): a glTF
 * level of one box mesh (positions, normals, UVs, tangents) placed by 50
 * nodes with rotations and scales, two of them mirrored, plus one in a
 * turned group, a quad mesh on three nodes, two materials with a PNG (a
 * file next to the level) and a JPEG (in the level's buffer), samplers,
 * KHR_texture_transform and KHR_materials_emissive_strength, and
 * KHR_lights_punctual's directional (the sun) and point lights.
 *
 * Import: the level against the fixture's own numbers (each entity's
 * matrix, rebuilt from its position, rotation and scale, against the
 * node's; the mesh uploaded once; materials, samplers, texture transforms
 * undone from assimp's convention; the texture bytes against the files);
 * bad files name the node or the material. Round trip, end to end:
 * `vantage sublevel load` into a daemon, `vantage export out.glb` (its GLB
 * container and JSON checked by hand with json-c, its images' bytes
 * against the originals), `sublevel load out.glb` into a second, empty
 * daemon: both scenes the same, read back through the protocol.
 */
#include "test_util.h"

#include "import.h"
#include "import_internal.h" /* the pipe's pack and unpack */
#include "test_daemon.h"
#include "vantage.h"
#include "vt_image.h"

#include <json-c/json.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define FX_BOXES 50
#define FX_QUADS 3
#define FX_ENTITIES (FX_BOXES + 1 + FX_QUADS)

/* ---- the fixture ---------------------------------------------------------------------- */

typedef struct fx_trs {
    double t[3], q[4], s[3];
} fx_trs;

/* node i's transform: turns about changing axes, scales, two mirrors */
static fx_trs box_trs(int i)
{
    fx_trs r = {.t = {i * 3.0 - 75, (i % 5) * 0.5, (i % 7) * 2.0},
                .s = {1 + (i % 3) * 0.5, 1 + (i % 4) * 0.25, 0.5 + (i % 2)}};
    double ax[3] = {1, (double)(i % 3), 2}, l = sqrt(ax[0] * ax[0] + ax[1] * ax[1] + ax[2] * ax[2]);
    double a = i * 0.37;
    for (int k = 0; k < 3; k++) r.q[k] = sin(a / 2) * ax[k] / l;
    r.q[3] = cos(a / 2);
    if (i == 7) r.s[0] = -1, r.s[1] = 1, r.s[2] = 1; /* mirrored in x */
    if (i == 11) r.s[1] = -2;                       /* in y: read back as a mirror in x, turned */
    return r;
}

/* The matrix of a TRS (row-major, p' = M p), in double. */
static void trs_matrix(const double t[3], const double q[4], const double s[3], double m[3][4])
{
    double x = q[0], y = q[1], z = q[2], w = q[3];
    double r[3][3] = {{1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)},
                      {2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)},
                      {2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)}};
    for (int i = 0; i < 3; i++) {
        for (int j = 0; j < 3; j++) m[i][j] = r[i][j] * s[j];
        m[i][3] = t[i];
    }
}

static void mat_mul34(const double a[3][4], const double b[3][4], double o[3][4])
{
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 4; j++) {
            double v = j == 3 ? a[i][3] : 0;
            for (int k = 0; k < 3; k++) v += a[i][k] * b[k][j];
            o[i][j] = v;
        }
}

/* the group: turned 0.5 rad about y at (0, 0, 100); its child box */
static const fx_trs fx_group = {.t = {0, 0, 100}, .q = {0, 0.24740395925452294, 0, 0.9689124217106447}, .s = {1, 1, 1}};
static const fx_trs fx_child = {.t = {5, 1, 0}, .q = {0, 0, 0, 1}, .s = {2, 3, 4}};

static fx_trs quad_trs(int i)
{
    return (fx_trs){.t = {i * 10.0, 0, -50}, .q = {0, 0, 0, 1}, .s = {4, 4, 1}};
}

/* node k of the scene's entities (the order the walk meets them) as a matrix */
static void fx_matrix(int k, double m[3][4])
{
    if (k < FX_BOXES) {
        fx_trs r = box_trs(k);
        trs_matrix(r.t, r.q, r.s, m);
    } else if (k == FX_BOXES) {
        double g[3][4], c[3][4];
        trs_matrix(fx_group.t, fx_group.q, fx_group.s, g);
        trs_matrix(fx_child.t, fx_child.q, fx_child.s, c);
        mat_mul34(g, c, m);
    } else {
        fx_trs r = quad_trs(k - FX_BOXES - 1);
        trs_matrix(r.t, r.q, r.s, m);
    }
}

/* the box: 24 vertices, face normals, UVs 0.25 / 0.75 (exact in float
   either way up), tangents along each face's u with handedness +-1 */
static void fx_box(float pos[72], float nrm[72], float uv[48], float tan[96], uint32_t idx[36])
{
    static const int ax[6][3][3] = {{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}},  {{-1, 0, 0}, {0, 0, 1}, {0, 1, 0}},
                                    {{0, 1, 0}, {0, 0, 1}, {1, 0, 0}},  {{0, -1, 0}, {1, 0, 0}, {0, 0, 1}},
                                    {{0, 0, 1}, {1, 0, 0}, {0, 1, 0}},  {{0, 0, -1}, {0, 1, 0}, {1, 0, 0}}};
    static const int su[4] = {-1, 1, 1, -1}, sv[4] = {-1, -1, 1, 1};
    for (int f = 0; f < 6; f++) {
        for (int c = 0; c < 4; c++) {
            int v = 4 * f + c;
            for (int k = 0; k < 3; k++) {
                pos[3 * v + k] = (float)(ax[f][0][k] + su[c] * ax[f][1][k] + sv[c] * ax[f][2][k]);
                nrm[3 * v + k] = (float)ax[f][0][k];
                tan[4 * v + k] = (float)ax[f][1][k];
            }
            tan[4 * v + 3] = f % 2 ? -1.0f : 1.0f;
            uv[2 * v] = su[c] < 0 ? 0.25f : 0.75f;
            uv[2 * v + 1] = sv[c] < 0 ? 0.75f : 0.25f;
        }
        const uint32_t b = 4 * (uint32_t)f, t[6] = {b, b + 1, b + 2, b, b + 2, b + 3};
        memcpy(idx + 6 * f, t, sizeof t);
    }
}

static const float fx_qpos[12] = {-1, -1, 0, 1, -1, 0, 1, 1, 0, -1, 1, 0}, fx_qnrm[12] = {0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1},
                   fx_quv[8] = {0, 1, 1, 1, 1, 0, 0, 0};
static const uint32_t fx_qidx[6] = {0, 1, 2, 0, 2, 3};

/* The materials the fixture's JSON says, as the importer should give them. */
static void fx_materials(vp_material m[2])
{
    memset(m, 0, 2 * sizeof *m);
    m[0] = (vp_material){.id = 1, .flags = VP_MAT_DOUBLE_SIDED, .alpha_mode = VP_ALPHA_MASK, .alpha_cutoff = 0.25f,
                         .base_color = {0.5f, 0.25f, 1, 1}, .metallic = 0.25f, .roughness = 0.75f,
                         .emissive = {1, 0.5f, 0}, .emissive_strength = 4, .normal_scale = 0.5f};
    m[0].tex[VP_TEX_BASE] = (vp_texref){.texture = 1, .wrap_s = VP_WRAP_CLAMP, .wrap_t = VP_WRAP_MIRROR,
                                        .min_filter = VP_FILTER_NEAREST_MIP_LINEAR, .mag_filter = VP_FILTER_NEAREST,
                                        .offset = {0.25f, 0.5f}, .scale = {2, 3}, .rotation = 0.5f};
    m[0].tex[VP_TEX_NORMAL] = (vp_texref){.texture = 2, .min_filter = VP_FILTER_LINEAR,
                                          .mag_filter = VP_FILTER_LINEAR, .scale = {1, 1}};
    m[1] = (vp_material){.id = 2, .alpha_cutoff = 0.5f, .base_color = {1, 1, 1, 1}, .metallic = 1, .roughness = 0.5f,
                         .emissive_strength = 1, .normal_scale = 1};
    m[1].tex[VP_TEX_BASE] = m[0].tex[VP_TEX_NORMAL];
    m[1].tex[VP_TEX_MR] = m[0].tex[VP_TEX_BASE];
    m[1].tex[VP_TEX_MR].offset[0] = m[1].tex[VP_TEX_MR].offset[1] = 0;
    m[1].tex[VP_TEX_MR].scale[0] = m[1].tex[VP_TEX_MR].scale[1] = 1;
    m[1].tex[VP_TEX_MR].rotation = 0;
    m[1].tex[VP_TEX_EMISSIVE] = m[0].tex[VP_TEX_NORMAL];
}

typedef enum { FX_GOOD, FX_SHEAR, FX_NOT_IMAGE, FX_NO_IMAGE } fx_kind;

/* A whole file (malloc'ed), or NULL. */
static uint8_t *read_file(const char *path, size_t *n)
{
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    fseek(f, 0, SEEK_END);
    long len = ftell(f);
    fseek(f, 0, SEEK_SET);
    uint8_t *b = len >= 0 ? malloc((size_t)len + 1) : NULL;
    *n = b ? fread(b, 1, (size_t)len, f) : 0;
    fclose(f);
    return b;
}

typedef struct fx_files {
    char gltf[512];
    uint8_t *png, *jpg;
    size_t npng, njpg;
} fx_files;

static void put_floats(FILE *f, const float *v, size_t n)
{
    fwrite(v, sizeof *v, n, f); /* little-endian machines only, as glTF's buffers */
}

static void fx_write(tdir *td, fx_kind kind, fx_files *out)
{
    char err[256];
    uint8_t rgba[4 * 4 * 4], rgb[8 * 8 * 3];
    for (int i = 0; i < 64; i++) rgba[i] = (uint8_t)(i * 4 + (i % 4 == 3 ? 255 : 0));
    for (int i = 0; i < 192; i++) rgb[i] = (uint8_t)(i * 7);
    snprintf(out->gltf, sizeof out->gltf, "%s", tdir_file(td, "a.png"));
    if (kind == FX_NOT_IMAGE) {
        FILE *f = fopen(out->gltf, "wb");
        fputs("GIF89a not really", f);
        fclose(f);
    } else if (kind != FX_NO_IMAGE) {
        assert_int_equal(vt_png_write(out->gltf, 4, 4, rgba, 16, true, 6, err, sizeof err), 0);
    }
    out->npng = 0;
    out->png = kind == FX_GOOD ? read_file(out->gltf, &out->npng) : NULL;
    assert_int_equal(vt_jpeg_encode(8, 8, rgb, 24, 3, 90, &out->jpg, &out->njpg, err, sizeof err), 0);
    /* the buffer: box, quad, then the JPEG */
    float pos[72], nrm[72], uv[48], tan[96];
    uint32_t idx[36];
    fx_box(pos, nrm, uv, tan, idx);
    FILE *b = fopen(tdir_file(td, "level.bin"), "wb");
    assert_non_null(b);
    put_floats(b, pos, 72);   /* 0: 288 */
    put_floats(b, nrm, 72);   /* 288: 288 */
    put_floats(b, uv, 48);    /* 576: 192 */
    put_floats(b, tan, 96);   /* 768: 384 */
    fwrite(idx, 4, 36, b);    /* 1152: 144 */
    put_floats(b, fx_qpos, 12); /* 1296: 48 */
    put_floats(b, fx_qnrm, 12); /* 1344: 48 */
    put_floats(b, fx_quv, 8);   /* 1392: 32 */
    fwrite(fx_qidx, 4, 6, b);   /* 1424: 24 */
    fwrite(out->jpg, 1, out->njpg, b); /* 1448 */
    fclose(b);
    size_t blen = 1448 + out->njpg;
    snprintf(out->gltf, sizeof out->gltf, "%s", tdir_file(td, "level.gltf"));
    FILE *f = fopen(out->gltf, "w");
    assert_non_null(f);
    fprintf(f, "{\"asset\": {\"version\": \"2.0\"}, \"scene\": 0,\n"
               "\"extensionsUsed\": [\"KHR_lights_punctual\", \"KHR_texture_transform\", "
               "\"KHR_materials_emissive_strength\"],\n"
               "\"buffers\": [{\"uri\": \"level.bin\", \"byteLength\": %zu}],\n"
               "\"bufferViews\": [{\"buffer\": 0, \"byteOffset\": 0, \"byteLength\": 288},\n"
               " {\"buffer\": 0, \"byteOffset\": 288, \"byteLength\": 288}, {\"buffer\": 0, \"byteOffset\": 576, "
               "\"byteLength\": 192},\n"
               " {\"buffer\": 0, \"byteOffset\": 768, \"byteLength\": 384}, {\"buffer\": 0, \"byteOffset\": 1152, "
               "\"byteLength\": 144},\n"
               " {\"buffer\": 0, \"byteOffset\": 1296, \"byteLength\": 48}, {\"buffer\": 0, \"byteOffset\": 1344, "
               "\"byteLength\": 48},\n"
               " {\"buffer\": 0, \"byteOffset\": 1392, \"byteLength\": 32}, {\"buffer\": 0, \"byteOffset\": 1424, "
               "\"byteLength\": 24},\n"
               " {\"buffer\": 0, \"byteOffset\": 1448, \"byteLength\": %zu}],\n",
            blen, out->njpg);
    fprintf(f, "\"accessors\": [{\"bufferView\": 0, \"componentType\": 5126, \"count\": 24, \"type\": \"VEC3\", "
               "\"min\": [-1, -1, -1], \"max\": [1, 1, 1]},\n"
               " {\"bufferView\": 1, \"componentType\": 5126, \"count\": 24, \"type\": \"VEC3\"},\n"
               " {\"bufferView\": 2, \"componentType\": 5126, \"count\": 24, \"type\": \"VEC2\"},\n"
               " {\"bufferView\": 3, \"componentType\": 5126, \"count\": 24, \"type\": \"VEC4\"},\n"
               " {\"bufferView\": 4, \"componentType\": 5125, \"count\": 36, \"type\": \"SCALAR\"},\n"
               " {\"bufferView\": 5, \"componentType\": 5126, \"count\": 4, \"type\": \"VEC3\", "
               "\"min\": [-1, -1, 0], \"max\": [1, 1, 0]},\n"
               " {\"bufferView\": 6, \"componentType\": 5126, \"count\": 4, \"type\": \"VEC3\"},\n"
               " {\"bufferView\": 7, \"componentType\": 5126, \"count\": 4, \"type\": \"VEC2\"},\n"
               " {\"bufferView\": 8, \"componentType\": 5125, \"count\": 6, \"type\": \"SCALAR\"}],\n");
    fprintf(f, "\"images\": [{\"uri\": \"a.png\"}, {\"bufferView\": 9, \"mimeType\": \"image/jpeg\"}],\n"
               "\"samplers\": [{\"wrapS\": 33071, \"wrapT\": 33648, \"minFilter\": 9986, \"magFilter\": 9728},\n"
               " {\"wrapS\": 10497, \"wrapT\": 10497, \"minFilter\": 9729, \"magFilter\": 9729}],\n"
               "\"textures\": [{\"source\": 0, \"sampler\": 0}, {\"source\": 1, \"sampler\": 1}],\n"
               "\"materials\": [{\"name\": \"painted\", \"pbrMetallicRoughness\": {\"baseColorFactor\": [0.5, 0.25, "
               "1, 1], \"metallicFactor\": 0.25, \"roughnessFactor\": 0.75,\n"
               "   \"baseColorTexture\": {\"index\": 0, \"extensions\": {\"KHR_texture_transform\": {\"offset\": "
               "[0.25, 0.5], \"scale\": [2, 3], \"rotation\": 0.5}}}},\n"
               "  \"normalTexture\": {\"index\": 1, \"scale\": 0.5}, \"emissiveFactor\": [1, 0.5, 0],\n"
               "  \"extensions\": {\"KHR_materials_emissive_strength\": {\"emissiveStrength\": 4}},\n"
               "  \"alphaMode\": \"MASK\", \"alphaCutoff\": 0.25, \"doubleSided\": true},\n"
               " {\"name\": \"stone\", \"pbrMetallicRoughness\": {\"baseColorTexture\": {\"index\": 1}, "
               "\"roughnessFactor\": 0.5, \"metallicRoughnessTexture\": {\"index\": 0}},\n"
               "  \"emissiveTexture\": {\"index\": 1}}],\n");
    fprintf(f, "\"meshes\": [{\"name\": \"box\", \"primitives\": [{\"attributes\": {\"POSITION\": 0, \"NORMAL\": 1, "
               "\"TEXCOORD_0\": 2, \"TANGENT\": 3}, \"indices\": 4, \"material\": 0}]},\n"
               " {\"name\": \"quad\", \"primitives\": [{\"attributes\": {\"POSITION\": 5, \"NORMAL\": 6, "
               "\"TEXCOORD_0\": 7}, \"indices\": 8, \"material\": 1}]}],\n"
               "\"extensions\": {\"KHR_lights_punctual\": {\"lights\": [\n"
               " {\"name\": \"sunlight\", \"type\": \"directional\", \"color\": [1, 0.9, 0.8], \"intensity\": 50000},\n"
               " {\"name\": \"bulb\", \"type\": \"point\", \"color\": [0.5, 1, 0.25], \"intensity\": 80, \"range\": 30}]}},\n"
               "\"nodes\": [\n");
    int n = 0;
    for (int i = 0; i < FX_BOXES; i++, n++) {
        fx_trs r = box_trs(i);
        fprintf(f, " {\"name\": \"box_%d\", \"mesh\": 0, \"translation\": [%.17g, %.17g, %.17g], \"rotation\": [%.17g, "
                   "%.17g, %.17g, %.17g], \"scale\": [%.17g, %.17g, %.17g]%s},\n",
                i, r.t[0], r.t[1], r.t[2], r.q[0], r.q[1], r.q[2], r.q[3], r.s[0], r.s[1], r.s[2],
                i == 3 ? ", \"extras\": {\"vantage_dynamic\": true}" : "");
    }
    /* n = 50: the child, 51: its group */
    fprintf(f, " {\"name\": \"child\", \"mesh\": 0, \"translation\": [5, 1, 0], \"scale\": [2, 3, 4]},\n"
               " {\"name\": \"group\", \"children\": [%d], \"translation\": [0, 0, 100], \"rotation\": [0, %.17g, 0, "
               "%.17g]},\n",
            n, fx_group.q[1], fx_group.q[3]);
    n += 2;
    for (int i = 0; i < FX_QUADS; i++) {
        fx_trs r = quad_trs(i);
        fprintf(f, " {\"name\": \"quad_%d\", \"mesh\": 1, \"translation\": [%g, %g, %g], \"scale\": [%g, %g, %g]},\n",
                i, r.t[0], r.t[1], r.t[2], r.s[0], r.s[1], r.s[2]);
    }
    /* the sun tilted 60 degrees down from -z (about x), the bulb up high */
    fprintf(f, " {\"name\": \"sunlight\", \"rotation\": [-0.5, 0, 0, 0.86602540378443865], \"extensions\": "
               "{\"KHR_lights_punctual\": {\"light\": 0}}},\n"
               " {\"name\": \"bulb\", \"translation\": [3, 8, -2], \"extensions\": {\"KHR_lights_punctual\": "
               "{\"light\": 1}}}%s\n",
            kind == FX_SHEAR ? "," : "");
    if (kind == FX_SHEAR) fprintf(f, " {\"name\": \"sheared\", \"mesh\": 0, \"matrix\": [1,0,0,0, 0.5,1,0,0, 0,0,1,0, 0,0,0,1]}\n");
    fprintf(f, "],\n\"scenes\": [{\"nodes\": [");
    for (int i = 0; i < FX_BOXES; i++) fprintf(f, "%d, ", i);
    fprintf(f, "%d", FX_BOXES + 1);
    for (int i = 0; i < FX_QUADS + 2; i++) fprintf(f, ", %d", FX_BOXES + 2 + i);
    if (kind == FX_SHEAR) fprintf(f, ", %d", FX_BOXES + 4 + FX_QUADS);
    fprintf(f, "]}]}\n");
    fclose(f);
}

static void fx_free(fx_files *fx)
{
    free(fx->png);
    free(fx->jpg);
}

/* ---- import ---------------------------------------------------------------------------- */

/* An entity's matrix rebuilt from its position, rotation and scale. */
static void entity_matrix(const double pos[3], const float rot[4], const float scale[3], double m[3][4])
{
    const double q[4] = {rot[0], rot[1], rot[2], rot[3]}, s[3] = {scale[0], scale[1], scale[2]};
    trs_matrix(pos, q, s, m);
}

static void assert_matrix(const char *what, const double got[3][4], const double want[3][4], double tol)
{
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 4; j++)
            if (!(fabs(got[i][j] - want[i][j]) <= tol * (1 + fabs(want[i][j]))))
                fail_msg("%s: matrix [%d][%d] is %.9g, want %.9g", what, i, j, got[i][j], want[i][j]);
}

static void assert_near(const char *what, double got, double want, double tol)
{
    if (!(fabs(got - want) <= tol)) fail_msg("%s is %.9g, want %.9g", what, got, want);
}

/* Two materials the same: every field, the texture transforms within tol. */
static void assert_material(const vp_material *got, const vp_material *want, double tol)
{
    char what[64];
    assert_int_equal(got->id, want->id);
    assert_int_equal(got->flags, want->flags);
    assert_int_equal(got->alpha_mode, want->alpha_mode);
    const float *g = &got->alpha_cutoff, *w = &want->alpha_cutoff;
    (void)g, (void)w;
    assert_near("alpha cutoff", got->alpha_cutoff, want->alpha_cutoff, 1e-6);
    for (int k = 0; k < 4; k++) assert_near("base colour", got->base_color[k], want->base_color[k], 1e-6);
    for (int k = 0; k < 3; k++) assert_near("emissive", got->emissive[k], want->emissive[k], 1e-6);
    assert_near("metallic", got->metallic, want->metallic, 1e-6);
    assert_near("roughness", got->roughness, want->roughness, 1e-6);
    assert_near("emissive strength", got->emissive_strength, want->emissive_strength, 1e-6);
    assert_near("normal scale", got->normal_scale, want->normal_scale, 1e-6);
    for (int s = 0; s < VP_TEX_SLOTS; s++) {
        const vp_texref *a = &got->tex[s], *b = &want->tex[s];
        snprintf(what, sizeof what, "material %u slot %d", want->id, s);
        if (a->texture != b->texture || a->wrap_s != b->wrap_s || a->wrap_t != b->wrap_t ||
            a->min_filter != b->min_filter || a->mag_filter != b->mag_filter || a->texcoord != b->texcoord)
            fail_msg("%s: texture %u wrap %u,%u filters %u,%u; want %u wrap %u,%u filters %u,%u", what, a->texture,
                     a->wrap_s, a->wrap_t, a->min_filter, a->mag_filter, b->texture, b->wrap_s, b->wrap_t,
                     b->min_filter, b->mag_filter);
        if (!b->texture) continue;
        for (int k = 0; k < 2; k++) {
            assert_near(what, a->offset[k], b->offset[k], tol);
            assert_near(what, a->scale[k], b->scale[k], tol);
        }
        assert_near(what, a->rotation, b->rotation, tol);
    }
}

/* The level through the import child's pipe: its bytes unpacked into a
 * level equal to it (true), or refused (false). */
static bool through_pipe(const imp_level *lv)
{
    vp_writer w;
    vp_writer_init_grow(&w);
    imp_level_pack(&w, lv);
    vp_reader r;
    vp_reader_init(&r, w.p, w.len);
    imp_level back;
    memset(&back, 0, sizeof back);
    bool ok = imp_level_unpack(&r, &back);
    if (ok) test_level_equal(lv, &back);
    imp_level_free(&back);
    vp_writer_free(&w);
    return ok;
}

static void test_import_scene_model(void **state)
{
    (void)state;
    tdir td;
    tdir_make(&td, "vantage_import_model");
    fx_files fx;
    fx_write(&td, FX_GOOD, &fx);
    imp_level lv;
    char err[512];
    if (imp_level_import(fx.gltf, &lv, err, sizeof err)) fail_msg("%s", err);
    /* the box mesh once for its 51 nodes, the quad once for its 3 */
    assert_int_equal(lv.nmesh, 2);
    assert_int_equal(lv.nent, FX_ENTITIES);
    float pos[72], nrm[72], uv[48], tan[96];
    uint32_t idx[36];
    fx_box(pos, nrm, uv, tan, idx);
    const lvl_mesh *box = &lv.mesh[0], *quad = &lv.mesh[1];
    assert_int_equal(box->nv, 24);
    assert_int_equal(box->ni, 36);
    assert_memory_equal(box->pos, pos, sizeof pos);
    assert_memory_equal(box->nrm, nrm, sizeof nrm);
    assert_non_null(box->uv);
    assert_memory_equal(box->uv, uv, sizeof uv);
    assert_non_null(box->tan);
    assert_memory_equal(box->tan, tan, sizeof tan);
    assert_memory_equal(box->idx, idx, sizeof idx);
    assert_int_equal(box->material, 1);
    assert_memory_equal(quad->uv, fx_quv, sizeof fx_quv);
    assert_null(quad->tan);
    assert_int_equal(quad->material, 2);
    /* every entity's matrix is its node's (world) matrix */
    for (int k = 0; k < FX_ENTITIES; k++) {
        const lvl_entity *e = &lv.ent[k];
        double got[3][4], want[3][4];
        fx_matrix(k, want);
        entity_matrix(e->pos, e->rot, e->scale, got);
        assert_matrix(e->name, got, want, 1e-6);
        assert_int_equal(e->cls, k < FX_BOXES + 1 ? 0 : 1);
        assert_int_equal(e->material, k < FX_BOXES + 1 ? 1 : 2);
        assert_int_equal(e->dynamic, k == 3);
    }
    assert_true(lv.ent[7].scale[0] < 0 && lv.ent[11].scale[0] < 0); /* the mirrors, as x */
    vp_material want[2];
    fx_materials(want);
    if (lv.nmat != 2) fail_msg("%u materials (ids %u, %u, %u)", lv.nmat, lv.mat[0].id, lv.mat[1].id, lv.mat[2].id);
    for (int i = 0; i < 2; i++) assert_material(&lv.mat[i], &want[i], 1e-5);
    /* textures in first-named order: the PNG (material 1's base colour,
       sRGB), the JPEG (its normal map: linear), bytes as the files hold */
    assert_int_equal(lv.ntex, 2);
    assert_true(lv.tex[0].id == 1 && lv.tex[0].format == VP_TEX_PNG && lv.tex[0].flags == VP_TEX_SRGB);
    assert_true(lv.tex[0].nbytes == fx.npng);
    assert_memory_equal(lv.tex[0].bytes, fx.png, fx.npng);
    assert_true(lv.tex[1].id == 2 && lv.tex[1].format == VP_TEX_JPEG && lv.tex[1].flags == 0);
    assert_true(lv.tex[1].nbytes == fx.njpg);
    assert_memory_equal(lv.tex[1].bytes, fx.jpg, fx.njpg);
    /* the sun: a node turned -60 degrees about x shines along
       (0, -sin 60, -cos 60); the sun is the other way */
    assert_true(lv.has_sun);
    assert_near("sun x", lv.sun_dir[0], 0, 1e-6);
    assert_near("sun y", lv.sun_dir[1], sin(M_PI / 3), 1e-6);
    assert_near("sun z", lv.sun_dir[2], cos(M_PI / 3), 1e-6);
    assert_near("sun lux", lv.sun_lux, 50000, 1e-2);
    assert_near("sun green", lv.sun_color[1], 0.9, 1e-6);
    assert_int_equal(lv.nlight, 1);
    assert_near("bulb y", lv.light[0].pos[1], 8, 1e-9);
    assert_near("bulb intensity", lv.light[0].intensity, 80, 1e-4);
    assert_near("bulb range", lv.light[0].range, 30, 1e-4);
    assert_near("bulb blue", lv.light[0].color[2], 0.25, 1e-6);
    /* the pipe's bytes carry all of it; a material naming a texture the
       level does not have is refused by the parent */
    assert_true(through_pipe(&lv));
    lv.mat[0].tex[VP_TEX_EMISSIVE].texture = 3;
    assert_false(through_pipe(&lv));
    imp_level_free(&lv);
    fx_free(&fx);
    tdir_remove(&td);
}

typedef struct bad_fixture {
    const char *name;
    fx_kind kind;
    const char *says;
} bad_fixture;

static const bad_fixture bad_fixtures[] = {
    {"shear", FX_SHEAR, "node 'sheared': its transform has shear"},
    {"not an image", FX_NOT_IMAGE, "material 1: texture 'a.png' is neither PNG nor JPEG"},
    {"missing image", FX_NO_IMAGE, "a.png: No such file or directory"},
};

static void test_import_bad_model(void **state)
{
    const bad_fixture *t = *state;
    tdir td;
    tdir_make(&td, "vantage_import_bad");
    fx_files fx;
    fx_write(&td, t->kind, &fx);
    imp_level lv;
    char err[512] = "";
    assert_int_equal(imp_level_import(fx.gltf, &lv, err, sizeof err), -1);
    if (!strstr(err, t->says)) fail_msg("\"%s\" does not say \"%s\"", err, t->says);
    assert_int_equal(lv.nent, 0);
    fx_free(&fx);
    tdir_remove(&td);
}

/* OBJ + MTL through assimp: the diffuse colour and map_Kd as the base
 * colour, the texture the PNG next to it, Ke as emissive. */
static void test_import_obj_mtl(void **state)
{
    (void)state;
    tdir td;
    tdir_make(&td, "vantage_import_obj");
    char err[256];
    uint8_t rgba[16];
    for (int i = 0; i < 16; i++) rgba[i] = (uint8_t)(i * 16 + 15);
    assert_int_equal(vt_png_write(tdir_file(&td, "brick.png"), 2, 2, rgba, 8, true, 6, err, sizeof err), 0);
    FILE *f = fopen(tdir_file(&td, "shed.mtl"), "w");
    fprintf(f, "newmtl brick\nKd 0.5 0.25 0.125\nKe 0 0 0\nd 1\nmap_Kd brick.png\n");
    fclose(f);
    f = fopen(tdir_file(&td, "shed.obj"), "w");
    fprintf(f, "mtllib shed.mtl\no shed\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
               "vn 0 0 1\nusemtl brick\nf 1/1/1 2/2/1 3/3/1 4/4/1\n");
    fclose(f);
    imp_level lv;
    if (imp_level_import(tdir_file(&td, "shed.obj"), &lv, err, sizeof err)) fail_msg("%s", err);
    assert_int_equal(lv.nent, 1);
    assert_int_equal(lv.nmat, 1);
    const vp_material *m = &lv.mat[0];
    assert_int_equal(lv.ent[0].material, m->id);
    assert_near("Kd r", m->base_color[0], 0.5, 1e-6);
    assert_near("Kd g", m->base_color[1], 0.25, 1e-6);
    assert_near("Kd b", m->base_color[2], 0.125, 1e-6);
    assert_near("metallic", m->metallic, 0, 0); /* an OBJ's material: a dielectric */
    assert_int_equal(m->tex[VP_TEX_BASE].texture, 1);
    assert_int_equal(lv.ntex, 1);
    size_t n;
    uint8_t *png = read_file(tdir_file(&td, "brick.png"), &n);
    assert_true(lv.tex[0].nbytes == n && lv.tex[0].format == VP_TEX_PNG);
    assert_memory_equal(lv.tex[0].bytes, png, n);
    /* OBJ's v is up: in glTF's convention (down) the corner (0,0) is v = 1 */
    assert_non_null(lv.mesh[0].uv);
    bool corner = false;
    for (uint32_t v = 0; v < lv.mesh[0].nv; v++)
        corner |= lv.mesh[0].pos[3 * v] == 0 && lv.mesh[0].pos[3 * v + 1] == 0 && lv.mesh[0].uv[2 * v + 1] == 1;
    assert_true(corner);
    free(png);
    imp_level_free(&lv);
    tdir_remove(&td);
}

/* ---- the .glb, read by hand ------------------------------------------------------------- */

static json_object *jget(json_object *o, const char *k)
{
    json_object *v = NULL;
    if (!json_object_object_get_ex(o, k, &v)) fail_msg("no \"%s\" in the glTF JSON", k);
    return v;
}

/* The container (glTF 2.0, "Binary glTF Layout") and what the JSON says
 * of the buffer; the images' bytes are the originals. */
static void check_glb(const char *path, const fx_files *fx)
{
    size_t n;
    uint8_t *b = read_file(path, &n);
    assert_non_null(b);
    assert_true(n >= 28);
    assert_memory_equal(b, "glTF", 4);
    assert_int_equal(vp_ld_u32(b + 4), 2);
    assert_int_equal(vp_ld_u32(b + 8), n);
    uint32_t jl = vp_ld_u32(b + 12);
    assert_memory_equal(b + 16, "JSON", 4);
    assert_int_equal(jl % 4, 0);
    assert_true(20 + (size_t)jl + 8 <= n);
    json_tokener *tok = json_tokener_new();
    json_object *root = json_tokener_parse_ex(tok, (const char *)b + 20, (int)jl);
    assert_non_null(root); /* the padding spaces are whitespace after it */
    json_tokener_free(tok);
    const uint8_t *bin_h = b + 20 + jl;
    uint32_t bl = vp_ld_u32(bin_h);
    assert_memory_equal(bin_h + 4, "BIN\0", 4);
    assert_int_equal(bl % 4, 0);
    assert_int_equal(20 + (size_t)jl + 8 + bl, n);
    const uint8_t *bin = bin_h + 8;
    json_object *bufs = jget(root, "buffers");
    assert_int_equal(json_object_array_length(bufs), 1);
    assert_int_equal(json_object_get_int64(jget(json_object_array_get_idx(bufs, 0), "byteLength")), bl);
    json_object *views = jget(root, "bufferViews");
    for (size_t i = 0; i < json_object_array_length(views); i++) {
        json_object *v = json_object_array_get_idx(views, i);
        int64_t off = json_object_get_int64(jget(v, "byteOffset")), len = json_object_get_int64(jget(v, "byteLength"));
        assert_true(off >= 0 && len > 0 && off + len <= bl && off % 4 == 0);
    }
    /* the images: the PNG and the JPEG, byte for byte */
    json_object *images = jget(root, "images");
    assert_int_equal(json_object_array_length(images), 2);
    for (int i = 0; i < 2; i++) {
        json_object *im = json_object_array_get_idx(images, (size_t)i);
        json_object *v = json_object_array_get_idx(views, (size_t)json_object_get_int(jget(im, "bufferView")));
        const uint8_t *want = i ? fx->jpg : fx->png;
        size_t wn = i ? fx->njpg : fx->npng;
        assert_string_equal(json_object_get_string(jget(im, "mimeType")), i ? "image/jpeg" : "image/png");
        assert_int_equal(json_object_get_int64(jget(v, "byteLength")), wn);
        assert_memory_equal(bin + json_object_get_int64(jget(v, "byteOffset")), want, wn);
    }
    /* every POSITION accessor has min and max */
    json_object *meshes = jget(root, "meshes"), *acc = jget(root, "accessors");
    for (size_t i = 0; i < json_object_array_length(meshes); i++) {
        json_object *p = json_object_array_get_idx(jget(json_object_array_get_idx(meshes, i), "primitives"), 0);
        json_object *a = json_object_array_get_idx(acc, (size_t)json_object_get_int(jget(jget(p, "attributes"),
                                                                                           "POSITION")));
        jget(a, "min");
        jget(a, "max");
    }
    const char *used = json_object_to_json_string(jget(root, "extensionsUsed"));
    assert_non_null(strstr(used, "KHR_lights_punctual"));
    assert_non_null(strstr(used, "KHR_texture_transform"));
    assert_non_null(strstr(used, "KHR_materials_emissive_strength"));
    /* entities, the sun and the bulb */
    assert_int_equal(json_object_array_length(jget(root, "nodes")), FX_ENTITIES + 2);
    json_object_put(root);
    free(b);
}

/* ---- the round trip --------------------------------------------------------------------- */

static int cmp_id(const void *a, const void *b)
{
    uint64_t x = ((const vp_entity *)a)->id, y = ((const vp_entity *)b)->id;
    return (x > y) - (x < y);
}

/* Every entity of the scene, by id. */
static vp_entity *all_entities(vtc_client *c, uint32_t *n)
{
    vp_list_reply lr;
    assert_int_equal(vtc_list(c, 0, 4096, &lr), VP_OK);
    assert_int_equal(lr.next_cursor, 0);
    vp_entity *e = calloc((size_t)lr.batch.count + 1, sizeof *e);
    for (uint32_t i = 0; i < lr.batch.count; i++) assert_int_equal(vp_entity_get(&lr.batch, i, &e[i]), VP_OK);
    qsort(e, lr.batch.count, sizeof *e, cmp_id);
    *n = lr.batch.count;
    return e;
}

static void mesh_equal(vtc_client *a, uint16_t ca, vtc_client *b, uint16_t cb)
{
    vp_mesh ma, mb;
    assert_int_equal(vtc_mesh_get(a, ca, &ma), VP_OK);
    assert_int_equal(vtc_mesh_get(b, cb, &mb), VP_OK); /* each client's own buffer: both stay valid */
    assert_int_equal(ma.flags, mb.flags);
    assert_int_equal(ma.vertex_count, mb.vertex_count);
    assert_int_equal(ma.index_count, mb.index_count);
    size_t nv = ma.vertex_count;
    assert_memory_equal(ma.positions, mb.positions, 12 * nv);
    if (ma.normals) assert_memory_equal(ma.normals, mb.normals, 12 * nv);
    if (ma.uvs) assert_memory_equal(ma.uvs, mb.uvs, 8 * nv);
    if (ma.tangents) assert_memory_equal(ma.tangents, mb.tangents, 16 * nv);
    assert_memory_equal(ma.indices, mb.indices, 4 * (size_t)ma.index_count);
}

/* ENV_GET (libvantage has no call for it on this branch) */
static void env_get(vtc_client *c, vp_env *out)
{
    uint8_t buf[64];
    vp_writer w;
    vp_writer_init(&w, buf, sizeof buf);
    uint32_t req = vtc_next_req(c);
    vp_enc_empty(&w, VP_ENV_GET, req);
    assert_int_equal(vtc_send(c, w.p, w.len), VP_OK);
    vp_header h;
    const uint8_t *p;
    do assert_int_equal(vtc_recv(c, &h, &p, -1), VP_OK);
    while (h.req != req);
    assert_int_equal(h.type, VP_ENV_REPLY);
    assert_int_equal(vp_dec_env(p, h.len, out), VP_OK);
}

static vp_material *all_materials(vtc_client *c, uint32_t *n)
{
    vp_page_reply r;
    /* pages of one: the cursor walks them in id order */
    vp_material *m = calloc(64, sizeof *m);
    uint32_t cursor = 0;
    *n = 0;
    do {
        assert_int_equal(vtc_material_list(c, cursor, 1, &r), VP_OK);
        for (uint32_t i = 0; i < r.count; i++) assert_int_equal(vp_material_get(r.recs, r.count, i, &m[(*n)++]), 0);
        cursor = r.next_cursor;
    } while (cursor && *n < 64);
    return m;
}

static uint8_t *texture_bytes(vtc_client *c, uint32_t id, uint32_t *n, uint8_t *format)
{
    vp_texture_put t;
    uint8_t *out = NULL;
    uint32_t off = 0;
    do {
        assert_int_equal(vtc_texture_get(c, id, off, 100, &t), VP_OK); /* small pieces: offsets exercised */
        if (!out) out = malloc(t.total);
        memcpy(out + off, t.data, t.len);
        off += t.len;
        *format = t.format;
    } while (off < t.total);
    *n = off;
    return out;
}

static void test_import_export_round_trip(void **state)
{
    daemon_proc *d1 = *state, d2;
    tdir td;
    tdir_make(&td, "vantage_roundtrip");
    fx_files fx;
    fx_write(&td, FX_GOOD, &fx);
    static char out[1 << 16];
    if (vantage_run(d1, out, sizeof out, "sublevel load lvl %s", fx.gltf)) fail_msg("load: %s", out);
    char glb[512];
    snprintf(glb, sizeof glb, "%s", tdir_file(&td, "out.glb"));
    if (vantage_run(d1, out, sizeof out, "export %s", glb)) fail_msg("export: %s", out);
    check_glb(glb, &fx);
    daemon_start(&d2, NULL);
    if (vantage_run(&d2, out, sizeof out, "sublevel load lvl %s", glb)) fail_msg("load of the export: %s", out);
    vtc_client *a = connect_role(d1, VP_ROLE_VIEWER, false), *b = connect_role(&d2, VP_ROLE_VIEWER, false);
    uint32_t na, nb;
    vp_entity *ea = all_entities(a, &na), *eb = all_entities(b, &nb);
    assert_int_equal(na, FX_ENTITIES);
    assert_int_equal(nb, na);
    for (uint32_t i = 0; i < na; i++) {
        char what[64];
        snprintf(what, sizeof what, "entity %u", i);
        assert_true(ea[i].id == eb[i].id); /* the same sub-level, the same order */
        assert_int_equal(ea[i].flags, eb[i].flags);
        assert_int_equal(ea[i].material, eb[i].material);
        double ma[3][4], mb[3][4];
        entity_matrix(ea[i].pos, ea[i].rot, ea[i].scale, ma);
        entity_matrix(eb[i].pos, eb[i].rot, eb[i].scale, mb);
        assert_matrix(what, mb, ma, 1e-5); /* assimp reads glTF's numbers as float */
        mesh_equal(a, ea[i].class_id, b, eb[i].class_id);
    }
    uint32_t nma, nmb;
    vp_material *ma = all_materials(a, &nma), *mb = all_materials(b, &nmb);
    assert_int_equal(nma, 2);
    assert_int_equal(nmb, nma);
    for (uint32_t i = 0; i < nma; i++) assert_material(&mb[i], &ma[i], 1e-5);
    for (uint32_t id = 1; id <= 2; id++) {
        uint32_t la, lb;
        uint8_t fa, fb;
        uint8_t *ta = texture_bytes(a, id, &la, &fa), *tb = texture_bytes(b, id, &lb, &fb);
        assert_int_equal(la, lb);
        assert_int_equal(fa, fb);
        assert_memory_equal(ta, tb, la);
        assert_memory_equal(ta, id == 1 ? fx.png : fx.jpg, la); /* and the original file's */
        free(ta);
        free(tb);
    }
    vp_env va, vb;
    env_get(a, &va);
    env_get(b, &vb);
    for (int k = 0; k < 3; k++) {
        assert_near("sun direction", vb.sun_dir[k], va.sun_dir[k], 1e-6);
        assert_near("sun colour", vb.sun_color[k], va.sun_color[k], 1e-6);
    }
    assert_near("sun lux", vb.sun_lux, va.sun_lux, 1e-2);
    vp_page_reply la, lb;
    assert_int_equal(vtc_light_list(a, 0, 100, &la), VP_OK);
    vp_light pa, pb;
    assert_int_equal(la.count, 1);
    assert_int_equal(vp_light_get(la.recs, 1, 0, &pa), VP_OK);
    assert_int_equal(vtc_light_list(b, 0, 100, &lb), VP_OK);
    assert_int_equal(lb.count, 1);
    assert_int_equal(vp_light_get(lb.recs, 1, 0, &pb), VP_OK);
    assert_true(pa.id == pb.id && pa.kind == pb.kind);
    for (int k = 0; k < 3; k++) {
        assert_near("light position", pb.pos[k], pa.pos[k], 1e-5);
        assert_near("light colour", pb.color[k], pa.color[k], 1e-6);
    }
    assert_near("light intensity", pb.intensity, pa.intensity, 1e-4);
    assert_near("light range", pb.range, pa.range, 1e-4);
    free(ea);
    free(eb);
    free(ma);
    free(mb);
    vtc_close(a);
    vtc_close(b);
    daemon_stop(&d2);
    fx_free(&fx);
    tdir_remove(&td);
}

/* The read-back messages on their own: MESH_GET of a class without a
 * mesh is NOT_FOUND, a viewer may read, TEXTURE_GET of no texture is
 * NOT_FOUND, LIGHT_LIST pages through every light once. */
static void test_readback_messages(void **state)
{
    daemon_proc *d = *state;
    vtc_client *ed = connect_role(d, VP_ROLE_EDITOR, false), *v = connect_role(d, VP_ROLE_VIEWER, false);
    const float pos[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0}, nrm[9] = {0, 0, 1, 0, 0, 1, 0, 0, 1};
    const uint32_t idx[3] = {0, 1, 2};
    assert_int_equal(vtc_put_mesh(ed, 9, pos, nrm, 3, idx, 3), VP_OK);
    vp_mesh m;
    assert_int_equal(vtc_mesh_get(v, 9, &m), VP_OK);
    assert_true(m.class_id == 9 && m.vertex_count == 3 && m.index_count == 3 && m.uvs == NULL);
    assert_memory_equal(m.positions, pos, sizeof pos); /* little-endian here */
    assert_memory_equal(m.normals, nrm, sizeof nrm);
    assert_int_equal(vtc_mesh_get(v, 10, &m), VP_ERR_NOT_FOUND);
    vp_texture_put t;
    assert_int_equal(vtc_texture_get(v, 5, 0, 10, &t), VP_ERR_NOT_FOUND);
    /* 37 lights, pages of 5: each once */
    vp_light l[37];
    for (int i = 0; i < 37; i++)
        l[i] = (vp_light){.id = 1000 + (uint64_t)i * 7, .pos = {i, 1, 2}, .dir = {0, -1, 0}, .color = {1, 1, 1},
                          .intensity = 10, .range = 5};
    assert_int_equal(vtc_put_lights(ed, l, 37), VP_OK);
    uint8_t seen[37] = {0};
    uint64_t cursor = 0;
    int pages = 0;
    do {
        vp_page_reply r;
        assert_int_equal(vtc_light_list(v, cursor, 5, &r), VP_OK);
        assert_true(r.count <= 5);
        for (uint32_t i = 0; i < r.count; i++) {
            vp_light x;
            assert_int_equal(vp_light_get(r.recs, r.count, i, &x), VP_OK);
            uint64_t k = (x.id - 1000) / 7;
            assert_true(k < 37 && !seen[k] && x.pos[0] == (double)k);
            seen[k] = 1;
        }
        cursor = r.next_cursor;
        pages++;
    } while (cursor && pages < 100);
    for (int i = 0; i < 37; i++) assert_true(seen[i]);
    /* a page of 0 is refused, as ENTITY_LIST's */
    vp_page_reply r;
    assert_int_equal(vtc_light_list(v, 0, 0, &r), VP_ERR_COUNT);
    vp_page_reply mr;
    assert_int_equal(vtc_material_list(v, 0, 10, &mr), VP_OK);
    assert_int_equal(mr.count, 0);
    assert_int_equal(mr.next_cursor, 0);
    vtc_close(ed);
    vtc_close(v);
}

const struct CMUnitTest import_tests[] = {
    cmocka_unit_test(test_import_scene_model),
    TEST_ROWS(test_import_bad_model, bad_fixtures),
    cmocka_unit_test(test_import_obj_mtl),
    DAEMON_TEST(test_readback_messages),
    DAEMON_TEST(test_import_export_round_trip),
};
const size_t import_tests_count = sizeof import_tests / sizeof import_tests[0];
