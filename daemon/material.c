/*
 * material.c — the scene's materials (glTF 2.0 metallic-roughness, see
 * protocol.h vp_material): stored by id, shared by any number of entities.
 */
#include "scene.h"

scene_material *scene_material_find(const scene *s, uint32_t id)
{
    uint64_t v;
    if (!id || !idmap_get(&s->materials, id, &v)) return NULL;
    return (scene_material *)(uintptr_t)v;
}
