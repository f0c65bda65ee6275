/*
 * import_material.c — a level's materials and textures (import.h): each
 * aiMaterial as a vp_material (glTF 2.0 metallic-roughness: factors,
 * alpha mode, double-sided, the four texture slots with their samplers
 * and KHR_texture_transform), each image it names as the original PNG or
 * JPEG bytes (assimp's embedded copy, or the file next to the level).
 *
 * Ids (stable: the same file gives the same ids): the materials some mesh
 * uses, 1, 2, ... in the file's order; a mesh that names none (assimp
 * gives it a default material of its own) gets the daemon's default, 0;
 * textures 1, 2, ... in the order the materials, by id and
 * then slot, first name them (the same image named twice is one texture).
 * A file exported by `vantage export` has exactly its materials, all
 * used, in id order: read back, each keeps its id.
 *
 * assimp 5.2 drops KHR_materials_emissive_strength: it is read from the
 * file's JSON here (json-c), by the glTF material's index, which is
 * assimp's.
 *
 * assimp's glTF reader turns KHR_texture_transform into its own UV
 * transform (rotation about the image centre, V flipped: glTF2Importer,
 * "a change of coordinates"); mat_texref undoes that, so the offset,
 * scale and rotation are glTF's again. Cost: one pass over the
 * materials; each image's bytes copied once.
 */
#include "import_internal.h"

#include <assimp/GltfMaterial.h>
#include <assimp/material.h>
#include <assimp/scene.h>

#include <json-c/json.h>

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* the key strings of assimp's macros, for calls with our own type/index */
#define KEY_MAPMODE_U "$tex.mapmodeu"
#define KEY_MAPMODE_V "$tex.mapmodev"
#define KEY_UVTRANSFORM "$tex.uvtrafo"
#define KEY_FILTER_MAG "$tex.mappingfiltermag"
#define KEY_FILTER_MIN "$tex.mappingfiltermin"
#define KEY_TEX_SCALE "$tex.scale"

/* a texture being collected: where its bytes come from */
typedef struct tex_src {
    struct aiString key;    /* the material's path: "*N" (embedded) or a file */
} tex_src;

typedef struct mat_ctx {
    const struct aiScene *sc;
    json_object *gltf;      /* the file's glTF JSON when it has what assimp drops, or NULL */
    bool is_gltf;
    const char *dir;
    imp_level *lv;
    tex_src *src;           /* per texture, lv->tex's order */
    char *err;
    size_t errlen;
} mat_ctx;

/* PNG or JPEG by the first bytes (the file's name may say anything) */
static int image_format(const uint8_t *p, size_t n)
{
    if (n >= 8 && !memcmp(p, "\x89PNG\r\n\x1a\n", 8)) return VP_TEX_PNG;
    if (n >= 3 && p[0] == 0xff && p[1] == 0xd8 && p[2] == 0xff) return VP_TEX_JPEG;
    return -1;
}

/* The image's bytes into t (format checked): 0, or -1 with the error. */
static int load_image(mat_ctx *x, const struct aiString *key, uint32_t mat_id, lvl_texture *t)
{
    const uint8_t *p = NULL;
    size_t n = 0;
    uint8_t *file = NULL;
    if (key->data[0] == '*') {
        char *end;
        unsigned long k = strtoul(key->data + 1, &end, 10);
        if (*end || end == key->data + 1 || k >= x->sc->mNumTextures) {
            snprintf(x->err, x->errlen, "material %u: texture '%s' is not in the file", mat_id, key->data);
            return -1;
        }
        const struct aiTexture *at = x->sc->mTextures[k];
        if (at->mHeight != 0) {
            snprintf(x->err, x->errlen, "material %u: texture '%s' is raw pixels, not a PNG or JPEG file", mat_id,
                     key->data);
            return -1;
        }
        p = (const uint8_t *)at->pcData;
        n = at->mWidth;
    } else {
        if (!x->dir) {
            snprintf(x->err, x->errlen,
                     "material %u: texture '%s' is a file of its own (a level in memory reads no other file)",
                     mat_id, key->data);
            return -1;
        }
        char path[4096];
        snprintf(path, sizeof path, "%s/%s", x->dir, key->data);
        FILE *f = fopen(path, "rb");
        long len = -1;
        if (f && !fseek(f, 0, SEEK_END)) len = ftell(f);
        if (!f || len < 0 || fseek(f, 0, SEEK_SET)) {
            snprintf(x->err, x->errlen, "material %u: texture %s: %s", mat_id, path, strerror(errno));
            if (f) fclose(f);
            return -1;
        }
        if ((unsigned long)len > VP_MAX_TEXTURE_BYTES) {
            fclose(f);
            snprintf(x->err, x->errlen, "material %u: texture %s is %ld bytes, more than %u", mat_id, path, len,
                     VP_MAX_TEXTURE_BYTES);
            return -1;
        }
        file = malloc((size_t)len + 1);
        n = file ? fread(file, 1, (size_t)len, f) : 0;
        fclose(f);
        if (!file || n != (size_t)len) {
            free(file);
            snprintf(x->err, x->errlen, "material %u: cannot read texture %s", mat_id, path);
            return -1;
        }
        p = file;
    }
    int fmt = image_format(p, n);
    if (fmt < 0 || n > VP_MAX_TEXTURE_BYTES) {
        free(file);
        snprintf(x->err, x->errlen, "material %u: texture '%s' is %s", mat_id, key->data,
                 fmt < 0 ? "neither PNG nor JPEG" : "too large");
        return -1;
    }
    t->format = (uint8_t)fmt;
    t->nbytes = (uint32_t)n;
    if (file) {
        t->bytes = file;
    } else if ((t->bytes = malloc(n + 1))) {
        memcpy(t->bytes, p, n);
    } else {
        snprintf(x->err, x->errlen, "out of memory for texture '%s'", key->data);
        return -1;
    }
    return 0;
}

/* The id of the texture the material names by key, loading it on first use. */
static int texture_id(mat_ctx *x, const struct aiString *key, uint32_t mat_id, bool srgb, uint32_t *id)
{
    imp_level *lv = x->lv;
    for (uint32_t i = 0; i < lv->ntex; i++)
        if (x->src[i].key.length == key->length && !memcmp(x->src[i].key.data, key->data, key->length)) {
            *id = lv->tex[i].id;
            return 0;
        }
    if (lv->ntex >= LVL_MAX_TEXTURES) {
        snprintf(x->err, x->errlen, "more than %u textures", LVL_MAX_TEXTURES);
        return -1;
    }
    lvl_texture *t = &lv->tex[lv->ntex];
    memset(t, 0, sizeof *t);
    if (load_image(x, key, mat_id, t)) return -1;
    t->id = lv->ntex + 1;
    t->flags = srgb ? VP_TEX_SRGB : 0;
    x->src[lv->ntex++].key = *key;
    *id = t->id;
    return 0;
}

static uint8_t wrap_of(int mode)
{
    return mode == aiTextureMapMode_Clamp ? VP_WRAP_CLAMP : mode == aiTextureMapMode_Mirror ? VP_WRAP_MIRROR
                                                                                            : VP_WRAP_REPEAT;
}

/* glTF's (OpenGL's) filter enums, 9728.., as VP_FILTER_* (in the same order) */
static uint8_t filter_of(int gl, uint8_t dflt, uint8_t top)
{
    static const int gl_filters[] = {9728, 9729, 9984, 9985, 9986, 9987};
    for (uint8_t k = 0; k <= top; k++)
        if (gl_filters[k] == gl) return k;
    return dflt;
}

/* Slot k of material m from the aiMaterial's texture of type (the first). */
static int mat_texref(mat_ctx *x, const struct aiMaterial *am, enum aiTextureType type, bool srgb, vp_material *m,
                      int k)
{
    vp_texref *t = &m->tex[k];
    memset(t, 0, sizeof *t); /* an empty slot is all 0 */
    struct aiString path;
    if (aiGetMaterialString(am, _AI_MATKEY_TEXTURE_BASE, type, 0, &path) != AI_SUCCESS || !path.length) return 0;
    /* glTF's defaults: repeat, filters the viewer's choice (trilinear) */
    *t = (vp_texref){.min_filter = VP_FILTER_LINEAR_MIP_LINEAR, .mag_filter = VP_FILTER_LINEAR, .scale = {1, 1}};
    if (texture_id(x, &path, m->id, srgb, &t->texture)) return -1;
    int v;
    if (aiGetMaterialIntegerArray(am, KEY_MAPMODE_U, type, 0, &v, NULL) == AI_SUCCESS) t->wrap_s = wrap_of(v);
    if (aiGetMaterialIntegerArray(am, KEY_MAPMODE_V, type, 0, &v, NULL) == AI_SUCCESS) t->wrap_t = wrap_of(v);
    if (aiGetMaterialIntegerArray(am, KEY_FILTER_MAG, type, 0, &v, NULL) == AI_SUCCESS)
        t->mag_filter = filter_of(v, VP_FILTER_LINEAR, VP_FILTER_LINEAR);
    if (aiGetMaterialIntegerArray(am, KEY_FILTER_MIN, type, 0, &v, NULL) == AI_SUCCESS)
        t->min_filter = filter_of(v, VP_FILTER_LINEAR_MIP_LINEAR, VP_FILTER_LINEAR_MIP_LINEAR);
    struct aiUVTransform tr;
    if (aiGetMaterialUVTransform(am, KEY_UVTRANSFORM, type, 0, &tr) == AI_SUCCESS) {
        /* assimp: R = -rotation, T.x = S.x/2 (1 - cos + sin) + offset.x,
           T.y = S.y/2 (sin + cos - 1) + 1 - S.y - offset.y; undone in double */
        double rot = -(double)tr.mRotation, c = cos(rot), s = sin(rot);
        double sx = tr.mScaling.x, sy = tr.mScaling.y;
        t->rotation = (float)rot;
        t->scale[0] = (float)sx;
        t->scale[1] = (float)sy;
        t->offset[0] = (float)(tr.mTranslation.x - 0.5 * sx * (1 - c + s));
        t->offset[1] = (float)(0.5 * sy * (s + c - 1) + 1 - sy - tr.mTranslation.y);
    }
    return 0;
}

/* glTF material i's KHR_materials_emissive_strength (1: none, or no JSON) */
static float gltf_emissive_strength(json_object *root, unsigned i)
{
    json_object *mats, *m, *ext, *es, *v;
    if (!root || !json_object_object_get_ex(root, "materials", &mats) || !json_object_is_type(mats, json_type_array) ||
        i >= json_object_array_length(mats) || !(m = json_object_array_get_idx(mats, i)) ||
        !json_object_object_get_ex(m, "extensions", &ext) ||
        !json_object_object_get_ex(ext, "KHR_materials_emissive_strength", &es) ||
        !json_object_object_get_ex(es, "emissiveStrength", &v) ||
        !(json_object_is_type(v, json_type_double) || json_object_is_type(v, json_type_int)))
        return 1;
    return (float)json_object_get_double(v); /* checked with the rest of the material */
}

/* Whether material i is the one assimp adds for meshes that name none
 * (the last one of a glTF file's, after the file's own: assimp 5.2's
 * glTF 2 reader always adds it; an OBJ's "DefaultMaterial"): those meshes
 * get the daemon's default material, id 0. */
static bool assimp_default(const mat_ctx *x, unsigned i)
{
    /* assimp's glTF 2 reader appends its default after the file's own */
    if (x->is_gltf) return i + 1 == x->sc->mNumMaterials;
    struct aiString name;
    return aiGetMaterialString(x->sc->mMaterials[i], AI_MATKEY_NAME, &name) == AI_SUCCESS &&
           !strcmp(name.data, AI_DEFAULT_MATERIAL_NAME);
}

bool imp_gltf_json(const uint8_t *p, size_t n, const char **json, size_t *jsonlen)
{
    if (n >= 4 && !memcmp(p, "glTF", 4)) {
        /* 12-byte header, then the JSON chunk: u32 length, "JSON" */
        if (n < 20 || memcmp(p + 16, "JSON", 4)) return false;
        uint32_t len = vp_ld_u32(p + 12);
        if (len > n - 20) return false;
        *json = (const char *)p + 20;
        *jsonlen = len;
        return true;
    }
    size_t i = 0;
    while (i < n && (p[i] == ' ' || p[i] == '\t' || p[i] == '\r' || p[i] == '\n')) i++;
    if (i == n || p[i] != '{') return false;
    *json = (const char *)p;
    *jsonlen = n;
    return true;
}

static float clamp01(float v)
{
    return v < 0 ? 0 : v > 1 ? 1 : v;
}

/* aiMaterial i as material id (see the top), checked as MATERIAL_PUT is. */
static int convert(mat_ctx *x, unsigned i, uint32_t id, vp_material *m)
{
    const struct aiMaterial *am = x->sc->mMaterials[i];
    /* glTF's defaults; an OBJ's material has no metallic factor: a dielectric */
    *m = (vp_material){.id = id, .alpha_cutoff = 0.5f, .base_color = {1, 1, 1, 1}, .metallic = 1, .roughness = 1,
                       .emissive_strength = 1, .normal_scale = 1};
    struct aiColor4D c;
    if (aiGetMaterialColor(am, AI_MATKEY_BASE_COLOR, &c) == AI_SUCCESS ||
        aiGetMaterialColor(am, AI_MATKEY_COLOR_DIFFUSE, &c) == AI_SUCCESS) {
        m->base_color[0] = c.r;
        m->base_color[1] = c.g;
        m->base_color[2] = c.b;
        m->base_color[3] = c.a;
    }
    float f;
    if (aiGetMaterialFloatArray(am, AI_MATKEY_OPACITY, &f, NULL) == AI_SUCCESS &&
        aiGetMaterialColor(am, AI_MATKEY_BASE_COLOR, &c) != AI_SUCCESS)
        m->base_color[3] = f; /* OBJ's d */
    if (aiGetMaterialFloatArray(am, AI_MATKEY_METALLIC_FACTOR, &f, NULL) == AI_SUCCESS) m->metallic = f;
    else m->metallic = 0;
    if (aiGetMaterialFloatArray(am, AI_MATKEY_ROUGHNESS_FACTOR, &f, NULL) == AI_SUCCESS) m->roughness = f;
    /* an OBJ's colours may be a little past 1 (exported renders): kept in range */
    for (int k = 0; k < 4; k++) m->base_color[k] = clamp01(m->base_color[k]);
    if (aiGetMaterialColor(am, AI_MATKEY_COLOR_EMISSIVE, &c) == AI_SUCCESS) {
        m->emissive[0] = c.r;
        m->emissive[1] = c.g;
        m->emissive[2] = c.b;
    }
    if (aiGetMaterialFloatArray(am, AI_MATKEY_EMISSIVE_INTENSITY, &f, NULL) == AI_SUCCESS) m->emissive_strength = f;
    else m->emissive_strength = gltf_emissive_strength(x->gltf, i);
    /* an emissive colour past 1 (OBJ's Ke) is carried by the strength */
    float big = fmaxf(m->emissive[0], fmaxf(m->emissive[1], m->emissive[2]));
    if (big > 1 && isfinite(big)) {
        for (int k = 0; k < 3; k++) m->emissive[k] /= big;
        m->emissive_strength *= big;
    }
    struct aiString s;
    if (aiGetMaterialString(am, AI_MATKEY_GLTF_ALPHAMODE, &s) == AI_SUCCESS && !strcmp(s.data, "MASK"))
        m->alpha_mode = VP_ALPHA_MASK; /* BLEND is drawn opaque: the renderers have no blending */
    if (aiGetMaterialFloatArray(am, AI_MATKEY_GLTF_ALPHACUTOFF, &f, NULL) == AI_SUCCESS) m->alpha_cutoff = f;
    int two = 0;
    if (aiGetMaterialIntegerArray(am, AI_MATKEY_TWOSIDED, &two, NULL) == AI_SUCCESS && two)
        m->flags |= VP_MAT_DOUBLE_SIDED;
    if (aiGetMaterialFloatArray(am, KEY_TEX_SCALE, aiTextureType_NORMALS, 0, &f, NULL) == AI_SUCCESS)
        m->normal_scale = f;
    /* base colour: glTF's BASE_COLOR, else (OBJ's map_Kd) DIFFUSE */
    struct aiString probe;
    enum aiTextureType base =
        aiGetMaterialString(am, _AI_MATKEY_TEXTURE_BASE, aiTextureType_BASE_COLOR, 0, &probe) == AI_SUCCESS
            ? aiTextureType_BASE_COLOR
            : aiTextureType_DIFFUSE;
    if (mat_texref(x, am, base, true, m, VP_TEX_BASE) ||
        mat_texref(x, am, aiTextureType_UNKNOWN /* glTF metallic-roughness */, false, m, VP_TEX_MR) ||
        mat_texref(x, am, aiTextureType_NORMALS, false, m, VP_TEX_NORMAL) ||
        mat_texref(x, am, aiTextureType_EMISSIVE, true, m, VP_TEX_EMISSIVE))
        return -1;
    /* the checks MATERIAL_PUT's records get, here, naming the material */
    vp_writer w;
    uint8_t rec[VP_MATERIAL_SIZE];
    vp_writer_init(&w, rec, sizeof rec);
    vp_put_material(&w, m);
    char why[160];
    if (vp_material_rec_check(rec, 1, 0, why, sizeof why)) {
        struct aiString name = {0};
        aiGetMaterialString(am, AI_MATKEY_NAME, &name);
        snprintf(x->err, x->errlen, "material '%s' (id %u): %s", name.data, id, why);
        return -1;
    }
    return 0;
}

int imp_materials(const struct aiScene *sc, const char *dir, const char *json, size_t jsonlen, imp_level *lv,
                  uint32_t **ids, char *err, size_t errlen)
{
    mat_ctx x = {.sc = sc, .dir = dir, .lv = lv, .err = err, .errlen = errlen, .is_gltf = json != NULL};
    /* parsed only when it holds what is read from it (json-c takes about
       60 ms a megabyte: a 10k-node level's 1.8 MB would double the import) */
    if (json && jsonlen <= INT32_MAX && memmem(json, jsonlen, "KHR_materials_emissive_strength", 31)) {
        json_tokener *tok = json_tokener_new();
        if (tok) x.gltf = json_tokener_parse_ex(tok, json, (int)jsonlen);
        json_tokener_free(tok);
    }
    lv->mat = calloc((size_t)sc->mNumMaterials + 1, sizeof *lv->mat);
    *ids = calloc((size_t)sc->mNumMaterials + 1, sizeof **ids);
    /* at most 4 textures a material */
    size_t maxtex = 4 * (size_t)sc->mNumMaterials < LVL_MAX_TEXTURES ? 4 * (size_t)sc->mNumMaterials : LVL_MAX_TEXTURES;
    lv->tex = calloc(maxtex + 1, sizeof *lv->tex);
    x.src = calloc(maxtex + 1, sizeof *x.src);
    int rc = -1;
    if (!lv->mat || !*ids || !lv->tex || !x.src) {
        snprintf(err, errlen, "out of memory for materials");
        goto done;
    }
    for (unsigned k = 0; k < sc->mNumMeshes; k++)
        if (sc->mMeshes[k]->mMaterialIndex < sc->mNumMaterials) (*ids)[sc->mMeshes[k]->mMaterialIndex] = 1;
    for (unsigned i = 0; i < sc->mNumMaterials; i++) {
        if (!(*ids)[i] || assimp_default(&x, i)) {
            (*ids)[i] = 0;
            continue;
        }
        (*ids)[i] = lv->nmat + 1;
        if (convert(&x, i, lv->nmat + 1, &lv->mat[lv->nmat])) goto done;
        lv->nmat++;
    }
    rc = 0;
done:
    free(x.src);
    if (x.gltf) json_object_put(x.gltf);
    return rc;
}
