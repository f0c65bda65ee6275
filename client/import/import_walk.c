/*
 * import_walk.c — assimp's scene to a imp_level (import.h): the node walk,
 * the classes, entities, occluders and lights, and imp_level_free.
 *
 * assimp reads the file (triangulated, primitives sorted by type, missing
 * normals generated, identical vertices joined, the data structure
 * validated: IMP_FLAGS); this file walks the node tree with world matrices
 * in double, decomposes each into the entity's position, rotation and
 * scale, applies the conventions and checks every number. Materials and
 * textures are import_material.c's. Where the file comes from is
 * import_child.c's (on disk) and import_memio.c's (in memory). Cost: one
 * pass over the nodes, and over each used mesh's vertices once however
 * many nodes use it (an instance costs its 8 box corners).
 */
#include "import_internal.h"
#include "vp_grow.h"

#include <assimp/cimport.h>
#include <assimp/scene.h>

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#define MAX_COORD 1e12 /* the culling core's range */
#define SHEAR_TOLERANCE 1e-4 /* |R^T R - I| of a decomposed rotation, per element */

typedef struct mat {
    double m[4][4]; /* row-major, column vectors: p' = m p */
} mat;

/* Names to indices: open addressing over (bytes, length) keys that live
 * in assimp's scene (node and light names, matched whole). */
typedef struct name_map {
    const struct aiString **key;
    uint32_t *val;
    uint32_t cap;           /* a power of two, or 0 */
} name_map;

typedef struct importer {
    const struct aiScene *sc;
    imp_level *lv;
    uint32_t *mesh_cls;     /* per assimp mesh: its class + 1, 0 = not met yet */
    uint32_t *mat_ids;      /* per assimp material: its id (import_material.c) */
    float cbox[LVL_MAX_CLASSES][6]; /* each class mesh's bounds: lo xyz, hi xyz */
    uint32_t ent_cap, occ_cap;
    const struct aiString **ent_name, **occ_name; /* full names, for OCC_ matching */
    name_map lights;        /* light name -> light index */
    mat *light_w;           /* per light: its node's world matrix, */
    const struct aiNode **light_node; /* and its node (NULL: none met) */
    char *err;
    size_t errlen;
} importer;

static int fail(importer *im, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static int fail(importer *im, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(im->err, im->errlen, fmt, ap);
    va_end(ap);
    return -1;
}


static mat mat_from(const struct aiMatrix4x4 *a)
{
    mat r = {{{a->a1, a->a2, a->a3, a->a4}, {a->b1, a->b2, a->b3, a->b4},
              {a->c1, a->c2, a->c3, a->c4}, {a->d1, a->d2, a->d3, a->d4}}};
    return r;
}

static mat mat_mul(const mat *a, const mat *b)
{
    mat r;
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++) {
            double s = 0;
            for (int k = 0; k < 4; k++) s += a->m[i][k] * b->m[k][j];
            r.m[i][j] = s;
        }
    return r;
}

static void xform(const mat *m, const double p[3], double o[3])
{
    for (int i = 0; i < 3; i++) o[i] = m->m[i][0] * p[0] + m->m[i][1] * p[1] + m->m[i][2] * p[2] + m->m[i][3];
}

static double det3(const mat *a)
{
    const double(*m)[4] = a->m;
    return m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
           m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
}

static void copy_name(char *dst, const struct aiString *s)
{
    size_t n = s->length < LVL_NAME - 1 ? s->length : LVL_NAME - 1;
    memcpy(dst, s->data, n);
    dst[n] = 0;
    for (size_t i = 0; i < n; i++)
        if ((unsigned char)dst[i] < 32) dst[i] = '?';
}

static bool meta_true(const struct aiNode *n, const char *key)
{
    const struct aiMetadata *md = n->mMetaData;
    for (unsigned i = 0; md && i < md->mNumProperties; i++) {
        if (strcmp(md->mKeys[i].data, key)) continue;
        const struct aiMetadataEntry *e = &md->mValues[i];
        if (e->mType == AI_BOOL) return *(const bool *)e->mData;
        if (e->mType == AI_INT32) return *(const int32_t *)e->mData != 0;
    }
    return false;
}

static bool meta_float(const struct aiNode *n, const char *key, double *out)
{
    const struct aiMetadata *md = n->mMetaData;
    for (unsigned i = 0; md && i < md->mNumProperties; i++) {
        if (strcmp(md->mKeys[i].data, key)) continue;
        const struct aiMetadataEntry *e = &md->mValues[i];
        if (e->mType == AI_FLOAT) *out = *(const float *)e->mData;
        else if (e->mType == AI_DOUBLE) *out = *(const double *)e->mData;
        else return false;
        return true;
    }
    return false;
}

static uint32_t name_hash(const struct aiString *k)
{
    uint32_t h = 2166136261u;
    for (uint32_t i = 0; i < k->length; i++) h = (h ^ (uint8_t)k->data[i]) * 16777619u;
    return h;
}

static bool name_eq(const struct aiString *a, const struct aiString *b)
{
    return a->length == b->length && !memcmp(a->data, b->data, a->length);
}

/* Room for n names; false when out of memory. */
static bool name_map_init(name_map *m, uint32_t n)
{
    /* at most half full; a power of two (the probe masks with cap - 1) */
    size_t cap = vp_grow_cap(0, 2 * (size_t)n, 16, sizeof *m->key, UINT32_MAX);
    if (!cap) return false;
    m->cap = (uint32_t)cap;
    m->key = calloc(m->cap, sizeof *m->key);
    m->val = calloc(m->cap, sizeof *m->val);
    return m->key && m->val;
}

static void name_map_free(name_map *m)
{
    free(m->key);
    free(m->val);
}

/* Adds k -> v unless k is there (the first one keeps it). */
static void name_map_put(name_map *m, const struct aiString *k, uint32_t v)
{
    for (uint32_t i = name_hash(k) & (m->cap - 1);; i = (i + 1) & (m->cap - 1)) {
        if (!m->key[i]) {
            m->key[i] = k;
            m->val[i] = v;
            return;
        }
        if (name_eq(m->key[i], k)) return;
    }
}

static bool name_map_get(const name_map *m, const struct aiString *k, uint32_t *v)
{
    if (!m->cap) return false;
    for (uint32_t i = name_hash(k) & (m->cap - 1); m->key[i]; i = (i + 1) & (m->cap - 1))
        if (name_eq(m->key[i], k)) {
            *v = m->val[i];
            return true;
        }
    return false;
}

/* The node has triangles (its point and line primitives are counted and
 * dropped): 0, or -1 with the error. */
static int node_meshes(importer *im, const struct aiNode *n, const char *name)
{
    bool any = false;
    for (unsigned k = 0; k < n->mNumMeshes; k++) {
        const struct aiMesh *m = im->sc->mMeshes[n->mMeshes[k]];
        if (m->mPrimitiveTypes & aiPrimitiveType_TRIANGLE) any |= m->mNumFaces > 0;
        else im->lv->skipped_prims += m->mNumFaces;
    }
    return any ? 0 : fail(im, "node '%s': its meshes have no triangles (points or lines only)", name);
}

static int bad_vertex(importer *im, const char *name, const struct aiMesh *m, unsigned v, double x)
{
    return isfinite(x) ? fail(im, "node '%s': bounds beyond +-1e12 m (mesh '%s', vertex %u)", name, m->mName.data, v)
                       : fail(im, "node '%s': mesh '%s' has a non-finite vertex (%u)", name, m->mName.data, v);
}

/* Appends the node's triangles in world space to occluder o, each vertex
 * checked (finite, within range). */
static int occ_append(importer *im, lvl_occluder *o, const struct aiNode *n, const mat *w)
{
    for (unsigned k = 0; k < n->mNumMeshes; k++) {
        const struct aiMesh *m = im->sc->mMeshes[n->mMeshes[k]];
        if (!(m->mPrimitiveTypes & aiPrimitiveType_TRIANGLE)) continue;
        if (!vp_grow32((void **)&o->tri, &o->cap, (size_t)o->ntri + m->mNumFaces, 9 * sizeof(float)))
            return fail(im, "out of memory for occluder '%s'", o->name);
        for (unsigned f = 0; f < m->mNumFaces; f++) {
            const struct aiFace *face = &m->mFaces[f];
            if (face->mNumIndices != 3) continue;
            float *t = o->tri + 9 * (size_t)o->ntri++;
            for (int v = 0; v < 3; v++) {
                const struct aiVector3D *p = &m->mVertices[face->mIndices[v]];
                double q[3] = {p->x, p->y, p->z}, r[3];
                xform(w, q, r);
                for (int a = 0; a < 3; a++) {
                    if (!(fabs(r[a]) <= MAX_COORD)) return bad_vertex(im, o->name, m, face->mIndices[v], r[a]);
                    t[3 * v + a] = (float)(r[a] - o->origin[a]);
                }
            }
        }
    }
    return 0;
}

static int new_occluder(importer *im, const struct aiString *full, const char *name, const mat *w, int32_t entity,
                        lvl_occluder **out)
{
    imp_level *lv = im->lv;
    uint32_t cap = im->occ_cap;
    if (!vp_grow32((void **)&lv->occ, &im->occ_cap, lv->nocc + 1, sizeof *lv->occ) ||
        !vp_grow32((void **)&im->occ_name, &cap, lv->nocc + 1, sizeof *im->occ_name))
        return fail(im, "out of memory for occluders");
    im->occ_name[lv->nocc] = full;
    lvl_occluder *o = &lv->occ[lv->nocc++];
    memset(o, 0, sizeof *o);
    snprintf(o->name, sizeof o->name, "%s", name);
    for (int a = 0; a < 3; a++) o->origin[a] = w->m[a][3];
    o->entity = entity;
    *out = o;
    return 0;
}

static void mesh_free(lvl_mesh *m)
{
    free(m->pos);
    free(m->nrm);
    free(m->uv);
    free(m->tan);
    free(m->idx);
    memset(m, 0, sizeof *m);
}

/* One vertex of assimp mesh m into class mesh out (v): its position
 * checked, its normal kept (made unit if it is not: a normal already unit
 * is kept bit for bit, so a level exported and read again has the same
 * bytes), its UV in glTF's convention (assimp turned v up), its tangent's
 * handedness from assimp's bitangent. */
static int copy_vertex(importer *im, const struct aiMesh *m, unsigned v, lvl_mesh *out, const char *name)
{
    const struct aiVector3D *p = &m->mVertices[v];
    const double q[3] = {p->x, p->y, p->z};
    for (int i = 0; i < 3; i++) {
        if (!(fabs(q[i]) <= MAX_COORD)) return bad_vertex(im, name, m, v, q[i]);
        out->pos[3 * v + i] = (float)q[i];
    }
    double n[3] = {0, 0, 0}, l = 0;
    if (m->mNormals) {
        n[0] = m->mNormals[v].x, n[1] = m->mNormals[v].y, n[2] = m->mNormals[v].z;
        l = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    }
    for (int i = 0; i < 3; i++)
        out->nrm[3 * v + i] = !(l > 0 && isfinite(l)) ? (i == 1 ? 1.0f : 0.0f)
                              : fabs(l - 1) <= 1e-5  ? (float)n[i]
                                                     : (float)(n[i] / l);
    if (out->uv) {
        const struct aiVector3D *t = &m->mTextureCoords[0][v];
        if (!isfinite(t->x) || !isfinite(t->y))
            return fail(im, "node '%s': mesh '%s' has a non-finite texture coordinate (%u)", name, m->mName.data, v);
        out->uv[2 * v] = t->x;
        out->uv[2 * v + 1] = (float)(1.0 - (double)t->y);
    }
    if (out->tan) {
        const struct aiVector3D *t = &m->mTangents[v], *b = &m->mBitangents[v], *nn = &m->mNormals[v];
        double c[3] = {nn->y * t->z - nn->z * t->y, nn->z * t->x - nn->x * t->z, nn->x * t->y - nn->y * t->x};
        double w = c[0] * b->x + c[1] * b->y + c[2] * b->z;
        const float tv[4] = {t->x, t->y, t->z, w < 0 ? -1.0f : 1.0f};
        for (int i = 0; i < 4; i++) {
            if (!isfinite(tv[i]))
                return fail(im, "node '%s': mesh '%s' has a non-finite tangent (%u)", name, m->mName.data, v);
            out->tan[4 * v + i] = tv[i];
        }
    }
    return 0;
}

/* The class of assimp mesh k: found, or made when the walk first meets
 * it (its vertices copied and checked, naming the node that met it). */
static int mesh_class(importer *im, unsigned k, const char *name, uint32_t *cls)
{
    if (im->mesh_cls[k]) {
        *cls = im->mesh_cls[k] - 1;
        return 0;
    }
    imp_level *lv = im->lv;
    if (lv->nmesh >= LVL_MAX_CLASSES) return fail(im, "node '%s': more than %u meshes", name, LVL_MAX_CLASSES);
    const struct aiMesh *m = im->sc->mMeshes[k];
    uint32_t nv = m->mNumVertices, ni = 0;
    for (unsigned f = 0; f < m->mNumFaces; f++) ni += m->mFaces[f].mNumIndices == 3 ? 3 : 0;
    bool uv = m->mTextureCoords[0] && m->mNumUVComponents[0] >= 2;
    bool tan = uv && m->mNormals && m->mTangents && m->mBitangents;
    lvl_mesh *out = &lv->mesh[lv->nmesh];
    memset(out, 0, sizeof *out);
    out->pos = malloc((size_t)nv * 3 * sizeof(float) + 1);
    out->nrm = malloc((size_t)nv * 3 * sizeof(float) + 1);
    out->uv = uv ? malloc((size_t)nv * 2 * sizeof(float) + 1) : NULL;
    out->tan = tan ? malloc((size_t)nv * 4 * sizeof(float) + 1) : NULL;
    out->idx = malloc((size_t)ni * sizeof(uint32_t) + 1);
    if (!out->pos || !out->nrm || (uv && !out->uv) || (tan && !out->tan) || !out->idx) {
        mesh_free(out);
        return fail(im, "out of memory for the mesh of node '%s'", name);
    }
    for (unsigned v = 0; v < nv; v++)
        if (copy_vertex(im, m, v, out, name)) {
            mesh_free(out);
            return -1;
        }
    out->nv = nv;
    for (unsigned f = 0; f < m->mNumFaces; f++) {
        const struct aiFace *face = &m->mFaces[f];
        if (face->mNumIndices != 3) continue;
        for (int v = 0; v < 3; v++) out->idx[out->ni++] = face->mIndices[v];
    }
    out->material = m->mMaterialIndex < im->sc->mNumMaterials ? im->mat_ids[m->mMaterialIndex] : 0;
    float *box = im->cbox[lv->nmesh];
    for (int i = 0; i < 3; i++) box[i] = INFINITY, box[3 + i] = -INFINITY;
    for (uint32_t v = 0; v < out->nv; v++)
        for (int i = 0; i < 3; i++) {
            box[i] = fminf(box[i], out->pos[3 * v + i]);
            box[3 + i] = fmaxf(box[3 + i], out->pos[3 * v + i]);
        }
    im->mesh_cls[k] = ++lv->nmesh;
    *cls = lv->nmesh - 1;
    return 0;
}

/* The node's world matrix w as the entity's position, unit rotation and
 * scale, in double: scale = the columns' lengths (x negative when w
 * mirrors), rotation = the columns over them, which must be orthonormal
 * (else w has shear, which an entity cannot carry). 0, or -1 naming the
 * node. */
static int decompose(importer *im, const mat *w, const char *name, lvl_entity *e)
{
    const double(*a)[4] = w->m;
    double s[3], r[3][3];
    for (int j = 0; j < 3; j++) s[j] = sqrt(a[0][j] * a[0][j] + a[1][j] * a[1][j] + a[2][j] * a[2][j]);
    if (det3(w) < 0) s[0] = -s[0];
    for (int j = 0; j < 3; j++) {
        if (!(fabs(s[j]) > 0 && isfinite(s[j])))
            return fail(im, "node '%s': its transform has zero scale on axis %c", name, "xyz"[j]);
        for (int i = 0; i < 3; i++) r[i][j] = a[i][j] / s[j];
    }
    for (int p = 0; p < 3; p++)
        for (int q = 0; q < 3; q++) {
            double d = r[0][p] * r[0][q] + r[1][p] * r[1][q] + r[2][p] * r[2][q] - (p == q);
            if (!(fabs(d) <= SHEAR_TOLERANCE))
                return fail(im, "node '%s': its transform has shear (columns %c and %c: %.3g off a rotation and "
                            "a scale per axis)", name, "xyz"[p], "xyz"[q], d);
        }
    /* Shepperd's method: the largest of w, x, y, z first, for accuracy */
    double q[4], tr = r[0][0] + r[1][1] + r[2][2];
    if (tr > 0) {
        double k = 2 * sqrt(tr + 1);
        q[3] = k / 4, q[0] = (r[2][1] - r[1][2]) / k, q[1] = (r[0][2] - r[2][0]) / k, q[2] = (r[1][0] - r[0][1]) / k;
    } else if (r[0][0] > r[1][1] && r[0][0] > r[2][2]) {
        double k = 2 * sqrt(1 + r[0][0] - r[1][1] - r[2][2]);
        q[3] = (r[2][1] - r[1][2]) / k, q[0] = k / 4, q[1] = (r[0][1] + r[1][0]) / k, q[2] = (r[0][2] + r[2][0]) / k;
    } else if (r[1][1] > r[2][2]) {
        double k = 2 * sqrt(1 + r[1][1] - r[0][0] - r[2][2]);
        q[3] = (r[0][2] - r[2][0]) / k, q[0] = (r[0][1] + r[1][0]) / k, q[1] = k / 4, q[2] = (r[1][2] + r[2][1]) / k;
    } else {
        double k = 2 * sqrt(1 + r[2][2] - r[0][0] - r[1][1]);
        q[3] = (r[1][0] - r[0][1]) / k, q[0] = (r[0][2] + r[2][0]) / k, q[1] = (r[1][2] + r[2][1]) / k, q[2] = k / 4;
    }
    /* one of q and -q: w >= 0, so a file read twice gives the same one */
    double l = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]) * (q[3] < 0 ? -1 : 1);
    for (int i = 0; i < 4; i++) e->rot[i] = (float)(q[i] / l);
    for (int i = 0; i < 3; i++) {
        e->pos[i] = a[i][3];
        e->scale[i] = (float)s[i];
    }
    char why[160];
    if (vp_trs_check(e->pos, e->rot, e->scale, why, sizeof why)) return fail(im, "node '%s': %s", name, why);
    return 0;
}

/* An entity of the node's mesh k (class cls) placed by w. */
static int mesh_entity(importer *im, const struct aiNode *n, const mat *w, const char *name, uint32_t cls)
{
    imp_level *lv = im->lv;
    uint32_t cap = im->ent_cap;
    if (!vp_grow32((void **)&lv->ent, &im->ent_cap, lv->nent + 1, sizeof *lv->ent) ||
        !vp_grow32((void **)&im->ent_name, &cap, lv->nent + 1, sizeof *im->ent_name))
        return fail(im, "out of memory for entities");
    im->ent_name[lv->nent] = &n->mName;
    lvl_entity *e = &lv->ent[lv->nent];
    memset(e, 0, sizeof *e);
    e->cls = cls;
    e->material = lv->mesh[cls].material;
    e->dynamic = meta_true(n, "vantage_dynamic");
    e->occluder = -1;
    snprintf(e->name, sizeof e->name, "%s", name);
    if (decompose(im, w, name, e)) return -1;
    /* the world box: the mesh's box corners placed (instances never walk
       their vertices) */
    const float *b = im->cbox[cls];
    for (int a = 0; a < 3; a++) e->lo[a] = INFINITY, e->hi[a] = -INFINITY;
    for (int c = 0; c < 8; c++) {
        double p[3] = {b[(c & 1) ? 3 : 0], b[(c & 2) ? 4 : 1], b[(c & 4) ? 5 : 2]}, o[3];
        xform(w, p, o);
        for (int a = 0; a < 3; a++) e->lo[a] = fmin(e->lo[a], o[a]), e->hi[a] = fmax(e->hi[a], o[a]);
    }
    for (int a = 0; a < 3; a++)
        if (!(fabs(e->lo[a]) <= MAX_COORD && fabs(e->hi[a]) <= MAX_COORD))
            return fail(im, "node '%s': bounds beyond +-1e12 m (or not finite)", name);
    lv->nent++;
    return 0;
}

/* The node's entities: one per triangle mesh, all with the node's
 * transform; with vantage_occluder the first also owns the node's
 * occluder. */
static int node_entity(importer *im, const struct aiNode *n, const mat *w, const char *name)
{
    imp_level *lv = im->lv;
    uint32_t first = lv->nent;
    for (unsigned k = 0; k < n->mNumMeshes; k++) {
        const struct aiMesh *m = im->sc->mMeshes[n->mMeshes[k]];
        if (!(m->mPrimitiveTypes & aiPrimitiveType_TRIANGLE) || !m->mNumFaces) continue;
        uint32_t cls = 0;
        if (mesh_class(im, n->mMeshes[k], name, &cls) || mesh_entity(im, n, w, name, cls)) return -1;
    }
    if (meta_true(n, "vantage_occluder")) {
        lvl_occluder *o;
        if (new_occluder(im, &n->mName, name, w, (int32_t)first, &o) || occ_append(im, o, n, w)) return -1;
        lv->ent[first].occluder = (int32_t)lv->nocc - 1;
    }
    return 0;
}
static int walk(importer *im, const struct aiNode *n, const mat *parent, unsigned depth)
{
    if (depth > 256) return fail(im, "node tree deeper than 256");
    mat local = mat_from(&n->mTransformation), w = mat_mul(parent, &local);
    char name[LVL_NAME];
    copy_name(name, &n->mName);
    if (n->mNumMeshes) {
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 4; j++)
                if (!isfinite(w.m[i][j])) return fail(im, "node '%s': its transform is not finite", name);
        double d = det3(&w);
        if (!(fabs(d) > 1e-18)) return fail(im, "node '%s': its transform has zero scale (determinant %g)", name, d);
        if (node_meshes(im, n, name)) return -1;
        if (!strncasecmp(name, "OCC_", 4)) {
            lvl_occluder *o;
            if (new_occluder(im, &n->mName, name, &w, -1, &o) || occ_append(im, o, n, &w)) return -1;
        } else if (node_entity(im, n, &w, name)) {
            return -1;
        }
    }
    uint32_t li;
    if (name_map_get(&im->lights, &n->mName, &li) && !im->light_node[li]) {
        im->light_w[li] = w;
        im->light_node[li] = n;
    }
    for (unsigned c = 0; c < n->mNumChildren; c++)
        if (walk(im, n->mChildren[c], &w, depth + 1)) return -1;
    return 0;
}

/* Before the walk: the light names it looks for (each light sits at the
 * node of its name, whose world matrix the walk records). */
static int lights_prepare(importer *im)
{
    uint32_t n = im->sc->mNumLights;
    im->light_w = calloc((size_t)n + 1, sizeof *im->light_w);
    im->light_node = calloc((size_t)n + 1, sizeof *im->light_node);
    if (!im->light_w || !im->light_node || (n && !name_map_init(&im->lights, n)))
        return fail(im, "out of memory for lights");
    for (uint32_t i = 0; i < n; i++) name_map_put(&im->lights, &im->sc->mLights[i]->mName, i);
    return 0;
}

static int lights(importer *im, const mat *id)
{
    imp_level *lv = im->lv;
    lv->light = calloc((size_t)im->sc->mNumLights + 1, sizeof *lv->light);
    if (!lv->light) return fail(im, "out of memory for lights");
    for (unsigned i = 0; i < im->sc->mNumLights; i++) {
        const struct aiLight *L = im->sc->mLights[i];
        char name[LVL_NAME];
        copy_name(name, &L->mName);
        bool sun = L->mType == aiLightSource_DIRECTIONAL && !lv->has_sun;
        if (L->mType != aiLightSource_POINT && L->mType != aiLightSource_SPOT && !sun) {
            lv->skipped_lights++;
            continue;
        }
        /* the first light of a name owns the node's matrix (names repeat rarely) */
        uint32_t li = i;
        name_map_get(&im->lights, &L->mName, &li);
        const struct aiNode *node = im->light_node[li];
        mat w = node ? im->light_w[li] : *id;
        vp_light *o = &lv->light[lv->nlight];
        memset(o, 0, sizeof *o);
        o->kind = L->mType == aiLightSource_SPOT ? VP_LIGHT_SPOT : VP_LIGHT_POINT;
        double p[3] = {L->mPosition.x, L->mPosition.y, L->mPosition.z}, d[3] = {L->mDirection.x, L->mDirection.y,
                                                                               L->mDirection.z};
        xform(&w, p, o->pos);
        /* normalised through its largest component: under parents scaled
           by 1e-180 or 1e180 the squares would underflow to 0 (straight
           down instead of its direction) or overflow (a zero vector) */
        double dw[3], big = 0, l = 0;
        for (int a = 0; a < 3; a++) {
            dw[a] = w.m[a][0] * d[0] + w.m[a][1] * d[1] + w.m[a][2] * d[2];
            big = fmax(big, fabs(dw[a]));
        }
        if (!(big > 0 && isfinite(big))) big = 0;
        for (int a = 0; a < 3 && big > 0; a++) {
            dw[a] /= big;
            l += dw[a] * dw[a];
        }
        l = sqrt(l);
        for (int a = 0; a < 3; a++) o->dir[a] = l > 0 ? (float)(dw[a] / l) : (a == 1 ? -1.0f : 0.0f);
        /* assimp gives colour x intensity */
        double c[3] = {L->mColorDiffuse.r, L->mColorDiffuse.g, L->mColorDiffuse.b};
        double mx = fmax(c[0], fmax(c[1], c[2]));
        if (!(mx > 0) || !isfinite(mx)) {
            lv->skipped_lights++;
            continue;
        }
        for (int a = 0; a < 3; a++) o->color[a] = (float)(c[a] / mx);
        o->intensity = (float)mx;
        if (sun) {
            /* KHR_lights_punctual's directional intensity is lux; the sun
               direction points towards it, against the light's */
            if (!(mx <= 200000))
                return fail(im, "light '%s': a sun of %g lux, more than 200000 (the brightest noon)", name, mx);
            lv->has_sun = true;
            for (int a = 0; a < 3; a++) {
                lv->sun_dir[a] = -o->dir[a];
                lv->sun_color[a] = o->color[a];
            }
            lv->sun_lux = o->intensity;
            continue;
        }
        double range;
        if (!node || !meta_float(node, "PBR_LightRange", &range) || !(range > 0))
            range = sqrt(mx / 0.05); /* where it falls to 1/20 candela */
        o->range = (float)fmin(fmax(range, 0.01), 1e6);
        if (o->kind == VP_LIGHT_SPOT) {
            double inner = fmin(fmax(L->mAngleInnerCone, 0), M_PI / 2), outer = fmin(fmax(L->mAngleOuterCone, 0), M_PI / 2);
            if (inner > outer) inner = outer;
            o->inner_cos = (float)cos(inner);
            o->outer_cos = (float)cos(outer);
        }
        for (int a = 0; a < 3; a++)
            if (!(fabs(o->pos[a]) <= MAX_COORD)) return fail(im, "light '%s': position beyond +-1e12 m", name);
        lv->nlight++;
    }
    return 0;
}

/* OCC_<name> to the entity <name> (whole names, through a hash); two
 * occluders of one entity merge. */
static int attach(importer *im)
{
    imp_level *lv = im->lv;
    name_map ents = {0};
    if (lv->nocc && !name_map_init(&ents, lv->nent)) return fail(im, "out of memory matching occluders");
    for (uint32_t e = 0; e < lv->nent && lv->nocc; e++) name_map_put(&ents, im->ent_name[e], e);
    for (uint32_t i = 0; i < lv->nocc; i++) {
        lvl_occluder *o = &lv->occ[i];
        const struct aiString *full = im->occ_name[i];
        if (o->entity >= 0 || full->length < 4 || strncasecmp(full->data, "OCC_", 4)) continue;
        struct aiString rest;
        rest.length = full->length - 4;
        memcpy(rest.data, full->data + 4, rest.length);
        rest.data[rest.length] = 0;
        uint32_t e;
        if (!name_map_get(&ents, &rest, &e)) continue;
        o->entity = (int32_t)e;
        int32_t prev = lv->ent[e].occluder;
        if (prev < 0) {
            lv->ent[e].occluder = (int32_t)i;
            continue;
        }
        /* merge into the one it has: re-based to its origin */
        lvl_occluder *p = &lv->occ[prev];
        if (!vp_grow32((void **)&p->tri, &p->cap, (size_t)p->ntri + o->ntri, 9 * sizeof(float))) {
            name_map_free(&ents);
            return fail(im, "out of memory for occluder '%s'", p->name);
        }
        for (uint32_t t = 0; t < 9 * o->ntri; t++)
            p->tri[9 * (size_t)p->ntri + t] = (float)(o->tri[t] + o->origin[t % 3] - p->origin[t % 3]);
        p->ntri += o->ntri;
        o->ntri = 0; /* dropped below */
    }
    name_map_free(&ents);
    /* drop merged (empty) occluders, fixing the entities' indices */
    uint32_t k = 0;
    for (uint32_t i = 0; i < lv->nocc; i++) {
        if (!lv->occ[i].ntri) {
            free(lv->occ[i].tri);
            continue;
        }
        if (lv->occ[i].entity >= 0) lv->ent[lv->occ[i].entity].occluder = (int32_t)k;
        lv->occ[k++] = lv->occ[i];
    }
    lv->nocc = k;
    return 0;
}

int imp_level_from_scene(const struct aiScene *sc, const char *what, const char *dir, const char *json,
                         size_t jsonlen, imp_level *out, char *err, size_t errlen)
{
    importer *im = calloc(1, sizeof *im);
    int rc = -1;
    if (!im) {
        snprintf(err, errlen, "out of memory");
        goto done;
    }
    *im = (importer){.sc = sc, .lv = out, .err = err, .errlen = errlen};
    if (!sc->mRootNode || (sc->mFlags & AI_SCENE_FLAGS_INCOMPLETE)) {
        fail(im, "%s: the file holds no complete scene", what);
        goto done;
    }
    out->mesh = calloc(LVL_MAX_CLASSES, sizeof *out->mesh);
    im->mesh_cls = calloc((size_t)sc->mNumMeshes + 1, sizeof *im->mesh_cls);
    if (!out->mesh || !im->mesh_cls) {
        fail(im, "out of memory");
        goto done;
    }
    mat id = {{{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}, {0, 0, 0, 1}}};
    if (imp_materials(sc, dir, json, jsonlen, out, &im->mat_ids, err, errlen) || lights_prepare(im) || walk(im, sc->mRootNode, &id, 0) ||
        lights(im, &id) || attach(im))
        goto done;
    if (!out->nent && !out->nocc && !out->nlight && !out->has_sun) {
        fail(im, "%s: no meshes or lights in the file", what);
        goto done;
    }
    rc = 0;
done:
    if (im) {
        free(im->mesh_cls);
        free(im->mat_ids);
        free(im->ent_name);
        free(im->occ_name);
        free(im->light_w);
        free(im->light_node);
        name_map_free(&im->lights);
    }
    free(im);
    aiReleaseImport(sc);
    if (rc) imp_level_free(out);
    return rc;
}

bool imp_known_format(const char *ext)
{
    return !strcasecmp(ext, "gltf") || !strcasecmp(ext, "glb") || !strcasecmp(ext, "obj");
}

void imp_level_free(imp_level *lv)
{
    for (uint32_t i = 0; lv->mesh && i < lv->nmesh; i++) mesh_free(&lv->mesh[i]);
    for (uint32_t i = 0; lv->tex && i < lv->ntex; i++) free(lv->tex[i].bytes);
    free(lv->mat);
    free(lv->tex);
    for (uint32_t i = 0; i < lv->nocc; i++) free(lv->occ[i].tri);
    free(lv->mesh);
    free(lv->ent);
    free(lv->occ);
    free(lv->light);
    memset(lv, 0, sizeof *lv);
}
