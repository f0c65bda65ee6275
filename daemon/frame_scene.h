/*
 * frame_scene.h — the scene model (scene.h: materials, textures, the
 * environment) as the renderers take it (vt_scene.h), for one frame:
 * materials converted as the frame's entities meet them, textures as
 * views of the stored mip chains (nothing copied), the environment.
 * Built and read under the shared scene lock; freed with the frame.
 */
#ifndef VANTAGE_FRAME_SCENE_H
#define VANTAGE_FRAME_SCENE_H

#include "scene.h"
#include "vt_scene.h"

typedef struct frame_scene {
    vt_material *mats;      /* room for every material of the scene, + the ground's */
    uint32_t nmats;
    vt_texview *texs;       /* room for every texture of the scene */
    uint32_t ntexs;
    idmap mat_ix, tex_ix;   /* id -> index in mats / texs */
    vt_env env;
    bool env_ok;            /* env passes vt_env_check (else frames draw without one) */
} frame_scene;

/* Prepares fs for sc (the environment converted). false: out of memory
 * (fs is freed). */
bool frame_scene_init(frame_scene *fs, const scene *sc);
void frame_scene_free(frame_scene *fs);
/* The frame's material of id (0 or unknown: NULL, the default material). */
const vt_material *frame_scene_material(frame_scene *fs, const scene *sc, uint32_t id);

#endif
