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
 * releasing sc; `what` names the file in messages. 0, or -1 with err filled
 * and *out freed. */
int imp_level_from_scene(const struct aiScene *sc, const char *what, imp_level *out, char *err, size_t errlen);

/* A file extension (no dot) Vantage imports: gltf, glb, obj (any case). */
bool imp_known_format(const char *ext);

/* The level as bytes on w (a growing vp_writer; w->overflow when memory
 * ran out). */
void imp_level_pack(vp_writer *w, const imp_level *lv);
/* The level back from all of r's bytes, every count and index checked:
 * true, or false with *lv holding what was read so far (imp_level_free it). */
bool imp_level_unpack(vp_reader *r, imp_level *lv);

#endif
