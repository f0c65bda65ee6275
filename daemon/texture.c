/*
 * texture.c — the scene's textures: uploaded images (PNG, JPEG, OpenEXR),
 * decoded once, kept with their mip chain and their encoded bytes.
 */
#include "scene.h"

scene_texture *scene_texture_find(const scene *s, uint32_t id)
{
    uint64_t v;
    if (!id || !idmap_get(&s->textures, id, &v)) return NULL;
    return (scene_texture *)(uintptr_t)v;
}
