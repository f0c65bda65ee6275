/*
 * env.c — the scene's environment (s->env, protocol.h vp_env): the sun,
 * the sky, the ground plane, fog and exposure. One record, replaced whole
 * by ENV_SET (journaled, snapshotted); ENV_GET reads it.
 *
 * Beyond vp_env_check (fields, ranges, modes), the scene's checks: a
 * texture sky names an EXR texture that is lat-long (width = 2 x height;
 * finite, as every stored EXR is: texture.c refuses others), and a ground
 * material is 0 or exists. What the environment names counts as a user of
 * it (scene_texture.users, scene_material.users), so neither can be removed
 * from under it: the sky texture while the sky mode is TEXTURE, the ground
 * material while it is not 0.
 */
#include "scene.h"

#include <math.h>
#include <stdio.h>

int scene_env_sky_check(const scene *s, const scene_texture *t, scene_err *err)
{
    (void)s;
    if (t->format != VP_TEX_EXR)
        return scene_fail(err, VP_ERR_INVALID, UINT32_MAX,
                          "sky texture %u is a %s image: the sky needs an EXR (linear HDR)", t->id,
                          t->format == VP_TEX_PNG ? "PNG" : "JPEG");
    if (t->w != 2u * (uint64_t)t->h)
        return scene_fail(err, VP_ERR_INVALID, UINT32_MAX,
                          "sky texture %u is %ux%u: a lat-long (equirectangular) map is twice as wide as high",
                          t->id, t->w, t->h);
    return VP_OK;
}

/* What an environment holds on to: its sky texture and ground material. */
static scene_texture *sky_of(const scene *s, const vp_env *e)
{
    return e->sky_mode == VP_SKY_TEXTURE ? scene_texture_find(s, e->sky_texture) : NULL;
}

static scene_material *ground_of(const scene *s, const vp_env *e)
{
    return e->ground_material ? scene_material_find(s, e->ground_material) : NULL;
}

int scene_env_set(scene *s, const vp_env *in, scene_err *err)
{
    vp_env e = *in;
    char why[120];
    int rc = vp_env_check(&e, why, sizeof why);
    if (rc) return scene_fail(err, rc, UINT32_MAX, "environment: %s", why);
    scene_texture *sky = sky_of(s, &e);
    if (e.sky_mode == VP_SKY_TEXTURE) {
        if (!sky)
            return scene_fail(err, VP_ERR_UNKNOWN_ID, UINT32_MAX,
                              "sky texture %u: no such texture (TEXTURE_PUT it first)", e.sky_texture);
        if ((rc = scene_env_sky_check(s, sky, err))) return rc;
    }
    scene_material *ground = ground_of(s, &e);
    if (e.ground_material && !ground)
        return scene_fail(err, VP_ERR_UNKNOWN_ID, UINT32_MAX, "ground material %u: no such material",
                          e.ground_material);
    /* users: the new one's first, so a texture kept across the change never drops to 0 */
    if (sky) sky->users++;
    if (ground) ground->users++;
    scene_texture *old_sky = sky_of(s, &s->env);
    scene_material *old_ground = ground_of(s, &s->env);
    if (old_sky && old_sky->users) old_sky->users--;
    if (old_ground && old_ground->users) old_ground->users--;
    s->env = e;
    s->epoch++;
    return VP_OK;
}
