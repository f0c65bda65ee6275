/*
 * import.h — a level file (glTF 2.0 .gltf/.glb, or OBJ+MTL) read through
 * assimp's C API into what a sub-level load sends: class meshes,
 * materials, textures, entities, occluders, lights and the sun, in world
 * metres. Pure reading: no connection.
 *
 * The scene model (README, "Authoring levels"):
 *  - each assimp mesh a node uses is one class mesh in its own space
 *    (positions, normals, UV set 0 and tangents when the file has them),
 *    sent once however many nodes use it; classes are numbered in the
 *    order the node walk first meets them;
 *  - every node with a triangle mesh is an entity per mesh, placed by the
 *    node's world transform decomposed (in double) into position, unit
 *    rotation and scale (a negative determinant mirrors the x axis); a
 *    matrix with shear or a zero scale fails naming the node;
 *  - materials (glTF metallic-roughness, or an OBJ's MTL diffuse colour and
 *    texture as base colour): material id = the file's material index + 1
 *    (assimp's own default material is id 0, the daemon's default);
 *    textures: the original PNG/JPEG bytes (embedded, or the file next to
 *    the level), id = 1, 2, ... in the order the materials (in id order,
 *    slots base colour, metallic-roughness, normal, emissive) first name
 *    them;
 *  - a node named OCC_<name> is an occluder only, attached to the entity
 *    node named <name> if there is one (destroying that entity cuts its
 *    occluder); glTF extras {"vantage_occluder": true} make a node both an
 *    entity and its own occluder; {"vantage_dynamic": true} a dynamic one;
 *  - KHR_lights_punctual point and spot lights (range from the light's
 *    range, else where its intensity falls to 1/20 candela); the first
 *    directional light is the sun (direction towards it, colour,
 *    intensity as lux); other directional, ambient and area lights are
 *    skipped (counted).
 * Whole file or nothing: a NaN or out-of-range coordinate, a zero scale, a
 * mesh without triangles, a texture that is not PNG or JPEG fails the
 * import, naming the node (or the material).
 */
#ifndef VANTAGE_IMPORT_H
#define VANTAGE_IMPORT_H

#include "protocol.h"

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#define LVL_NAME 64
#define LVL_MAX_CLASSES 4096u

#define LVL_MAX_TEXTURES 4096u

typedef struct lvl_mesh {
    float *pos, *nrm;       /* 3 per vertex, the mesh's own space */
    float *uv;              /* 2 per vertex (set 0; glTF's convention: v down), or NULL */
    float *tan;             /* 4 per vertex (xyz, w handedness), or NULL (only with uv) */
    uint32_t *idx;          /* 3 per triangle */
    uint32_t nv, ni;
    uint32_t material;      /* its material id, 0 = the default */
} lvl_mesh;

typedef struct lvl_entity {
    uint32_t cls;           /* index into meshes */
    uint32_t material;      /* its mesh's */
    double pos[3];          /* the node's world transform: position, */
    float rot[4];           /* unit quaternion x y z w, */
    float scale[3];         /* scale (x negative: mirrored) */
    double lo[3], hi[3];    /* world AABB of the mesh's box under the transform */
    bool dynamic;
    int32_t occluder;       /* its occluder's index, -1 = none */
    char name[LVL_NAME];
} lvl_entity;

typedef struct lvl_occluder {
    double origin[3];       /* vertices relative to it */
    float *tri;             /* 9 per triangle */
    uint32_t ntri, cap;
    int32_t entity;         /* the entity it belongs to, -1 = none */
    char name[LVL_NAME];
} lvl_occluder;

typedef struct lvl_texture {
    uint32_t id;            /* 1.. */
    uint8_t format, flags;  /* VP_TEX_PNG / JPEG; VP_TEX_SRGB for colour slots */
    uint8_t *bytes;         /* the image file's bytes, as they were */
    uint32_t nbytes;
} lvl_texture;

typedef struct imp_level {
    lvl_mesh *mesh;
    uint32_t nmesh;
    vp_material *mat;       /* ids 1.. (the file's index + 1) */
    uint32_t nmat;
    lvl_texture *tex;
    uint32_t ntex;
    lvl_entity *ent;
    uint32_t nent;
    lvl_occluder *occ;
    uint32_t nocc;
    vp_light *light;        /* ids 0: the loader gives them */
    uint32_t nlight;
    bool has_sun;           /* the file had a directional light: */
    float sun_dir[3];       /* towards the sun (unit), */
    float sun_color[3];     /* linear RGB, the largest 1, */
    float sun_lux;          /* illuminance */
    uint32_t skipped_lights; /* directional past the first, ambient, area */
    uint32_t skipped_prims;  /* point and line primitives dropped */
} imp_level;

/* 0, or -1 with err filled (the file, the node, what is wrong). assimp
 * runs in a forked child that sends the level back over a pipe, so a file
 * that crashes assimp is an error here, not a crash of the caller (whose
 * threads other than the caller's do not run in the child). */
int  imp_level_import(const char *path, imp_level *out, char *err, size_t errlen);
/* The same for a file in memory, buf[0..len), of the type hint names
 * ("gltf", "glb" or "obj"; it is called memory.<hint> in messages). It
 * reads no other file: a glTF buffer or image must be a data: URI (an
 * external image fails the import), an OBJ's .mtl is not read. In this process: a file that crashes assimp
 * crashes the caller. (The fuzz target's entry: tests/fuzz.) */
int  imp_level_import_mem(const void *buf, size_t len, const char *hint, imp_level *out, char *err, size_t errlen);
void imp_level_free(imp_level *lv);

#endif
