/*
 * import_internal.h — what the level importer's files share (import.h is
 * the public side). import_walk.c turns assimp's scene into a imp_level;
 * import_memio.c reads a file in memory, in this process; import_child.c
 * reads a file on disk in a forked child; import_pack.c is the level's
 * byte form on the pipe between the two.
 */
#ifndef VANTAGE_IMPORT_INTERNAL_H
#define VANTAGE_IMPORT_INTERNAL_H

#include "import.h"

#include <assimp/postprocess.h>

#include <stdbool.h>

struct aiScene;

/* What assimp does before import_walk.c sees the scene (see its top). */
#define IMP_FLAGS                                                                                                    \
    (aiProcess_Triangulate | aiProcess_SortByPType | aiProcess_GenNormals | aiProcess_JoinIdenticalVertices |       \
     aiProcess_ValidateDataStructure)

/* The level in assimp's scene sc into *out (zeroed first by the caller),
 * releasing sc; `what` names the file in messages, dir is the directory
 * its external images are read from (NULL: none is read, one is an
 * error), json[0..jsonlen) the file's glTF JSON (imp_gltf_json; NULL for
 * an OBJ) for what assimp does not carry. 0, or -1 with err filled and
 * *out freed. */
int imp_level_from_scene(const struct aiScene *sc, const char *what, const char *dir, const char *json,
                         size_t jsonlen, imp_level *out, char *err, size_t errlen);

/* import_material.c: the materials the scene's meshes use and the
 * textures they name into lv->mat / lv->tex (ids: import.h); *ids (to
 * free) maps assimp's material index to the id, 0 for one no mesh uses.
 * 0, or -1 with err filled. */
int imp_materials(const struct aiScene *sc, const char *dir, const char *json, size_t jsonlen, imp_level *lv,
                  uint32_t **ids, char *err, size_t errlen);
/* The glTF JSON of a level file's bytes: a .glb's JSON chunk, else the
 * whole text; false for neither (an OBJ, or a .glb cut short). */
bool imp_gltf_json(const uint8_t *p, size_t n, const char **json, size_t *jsonlen);

/* A file extension (no dot) Vantage imports: gltf, glb, obj (any case). */
bool imp_known_format(const char *ext);

/* The level as bytes on w (a growing vp_writer; w->overflow when memory
 * ran out). */
void imp_level_pack(vp_writer *w, const imp_level *lv);
/* The level back from all of r's bytes, every count and index checked:
 * true, or false with *lv holding what was read so far (imp_level_free it). */
bool imp_level_unpack(vp_reader *r, imp_level *lv);

#endif
