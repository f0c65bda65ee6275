/*
 * scene_file.h — reader for the test scenes (the .txt files in tests/data/scenes, the
 * format in each file's header): a camera, occluder triangles, object AABBs.
 * Used by tests and benchmarks; the daemon's own formats live in daemon/.
 */
#ifndef VANTAGE_SCENE_FILE_H
#define VANTAGE_SCENE_FILE_H

#include <stddef.h>

typedef struct scene_file {
    double eye[3], target[3], up[3];
    double fovy_deg, znear, zfar, aspect;
    size_t ntris;
    float *tris;      /* ntris * 9: x0 y0 z0 x1 y1 z1 x2 y2 z2, world */
    size_t nobjects;
    double *objects;  /* nobjects * 6: minx miny minz maxx maxy maxz */
} scene_file;

/* Reads path into *s. Returns 0, or -1 with a message in err (line number
 * included). Free with scene_file_free (accepts a zeroed struct). */
int  scene_file_load(const char *path, scene_file *s, char *err, size_t errlen);
void scene_file_free(scene_file *s);

#endif
