/*
 * import.h — a level file (glTF 2.0 .gltf/.glb, or OBJ) read through
 * assimp's C API into what a sub-level load sends: class meshes, entities,
 * occluders and lights, in world metres. Pure reading: no connection.
 *
 * Conventions (README, "Authoring levels"):
 *  - every node with a triangle mesh is an entity; its bounds are its mesh
 *    transformed to the world. Nodes that share meshes and the same
 *    rotation and scale share one class (a mesh in the node's orientation;
 *    the entity's box places it), so instanced props cost one mesh;
 *  - a node named OCC_<name> is an occluder only, attached to the entity
 *    node named <name> if there is one (destroying that entity cuts its
 *    occluder); glTF extras {"vantage_occluder": true} make a node both an
 *    entity and its own occluder; {"vantage_dynamic": true} a dynamic one;
 *  - KHR_lights_punctual point and spot lights (range from the light's
 *    range, else where its intensity falls to 1/20 candela); directional
 *    lights are skipped (counted).
 * Whole file or nothing: a NaN or out-of-range coordinate, a zero scale, a
 * mesh without triangles fails the import, naming the node.
 */
#ifndef VANTAGE_IMPORT_H
#define VANTAGE_IMPORT_H

#include "protocol.h"

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#define LVL_NAME 64
#define LVL_MAX_CLASSES 4096u

typedef struct lvl_mesh {
    float *pos, *nrm;       /* 3 per vertex; positions in the class's orientation */
    uint32_t *idx;          /* 3 per triangle */
    uint32_t nv, ni;
} lvl_mesh;

typedef struct lvl_entity {
    uint32_t cls;           /* index into meshes */
    double lo[3], hi[3];    /* world AABB */
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

typedef struct imp_level {
    lvl_mesh *mesh;
    uint32_t nmesh;
    lvl_entity *ent;
    uint32_t nent;
    lvl_occluder *occ;
    uint32_t nocc;
    vp_light *light;        /* ids 0: the loader gives them */
    uint32_t nlight;
    uint32_t skipped_lights; /* directional, ambient, area */
    uint32_t skipped_prims;  /* point and line primitives dropped */
} imp_level;

/* 0, or -1 with err filled (the file, the node, what is wrong). assimp
 * runs in a forked child that sends the level back over a pipe, so a file
 * that crashes assimp is an error here, not a crash of the caller (whose
 * threads other than the caller's do not run in the child). */
int  imp_level_import(const char *path, imp_level *out, char *err, size_t errlen);
/* The same for a file in memory, buf[0..len), of the type hint names
 * ("gltf", "glb" or "obj"; it is called memory.<hint> in messages). It
 * reads no other file: a glTF buffer or image must be a data: URI, an
 * OBJ's .mtl is not read. In this process: a file that crashes assimp
 * crashes the caller. (The fuzz target's entry: tests/fuzz.) */
int  imp_level_import_mem(const void *buf, size_t len, const char *hint, imp_level *out, char *err, size_t errlen);
void imp_level_free(imp_level *lv);

#endif
