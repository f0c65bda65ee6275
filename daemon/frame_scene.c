/*
 * frame_scene.c — see frame_scene.h. Per frame: O(materials met) work;
 * the texture views point into the scene's own mip chains.
 */
#include "frame_scene.h"

#include <stdlib.h>
#include <string.h>

_Static_assert(VT_WRAP_MIRROR == VP_WRAP_MIRROR && VT_FILTER_LINEAR_MIP_LINEAR == VP_FILTER_LINEAR_MIP_LINEAR &&
                   (int)VT_SLOT_EMISSIVE == (int)VP_TEX_EMISSIVE && VT_ALPHA_MASK == VP_ALPHA_MASK &&
                   VT_SKY_TEXTURE == VP_SKY_TEXTURE && VT_EXPOSURE_AUTO == VP_EXPOSURE_AUTO,
               "render/ and protocol/ number samplers, slots and modes alike");

/* The view of texture id (NULL: none, or not drawable in a material
 * slot: an EXR is the sky's). */
static const vt_texview *frame_tex(frame_scene *fs, const scene *sc, uint32_t id, bool hdr)
{
    uint64_t v;
    if (!id) return NULL;
    if (idmap_get(&fs->tex_ix, id, &v)) return fs->texs[v].hdr && !hdr ? NULL : &fs->texs[v];
    const scene_texture *st = scene_texture_find(sc, id);
    if (!st || (!st->mip && !st->hdr)) return NULL;
    vt_texview *t = &fs->texs[fs->ntexs];
    *t = (vt_texview){.w = st->w, .h = st->h, .levels = st->hdr ? 1 : st->levels,
                      .mip = st->hdr ? NULL : (const uint8_t *const *)st->mip, .hdr = st->hdr, .id = id,
                      .gen = st->gen}; /* a texture replaced under its id has a new gen */
    idmap_put(&fs->tex_ix, id, fs->ntexs++);
    return t->hdr && !hdr ? NULL : t;
}

static void material_of(frame_scene *fs, const scene *sc, const vp_material *m, vt_material *o)
{
    *o = (vt_material){.metallic = m->metallic, .roughness = m->roughness, .emissive_strength = m->emissive_strength,
                       .normal_scale = m->normal_scale, .alpha_mode = m->alpha_mode, .alpha_cutoff = m->alpha_cutoff,
                       .double_sided = (m->flags & VP_MAT_DOUBLE_SIDED) != 0};
    memcpy(o->base, m->base_color, sizeof o->base);
    memcpy(o->emissive, m->emissive, sizeof o->emissive);
    for (int k = 0; k < VT_SLOTS; k++) {
        const vp_texref *r = &m->tex[k];
        o->tex[k] = (vt_texref){.tex = frame_tex(fs, sc, r->texture, false), .wrap_s = r->wrap_s, .wrap_t = r->wrap_t,
                                .min_filter = r->min_filter, .mag_filter = r->mag_filter, .rotation = r->rotation};
        memcpy(o->tex[k].offset, r->offset, sizeof r->offset);
        memcpy(o->tex[k].scale, r->scale, sizeof r->scale);
    }
}

const vt_material *frame_scene_material(frame_scene *fs, const scene *sc, uint32_t id)
{
    uint64_t v;
    if (!id) return NULL;
    if (idmap_get(&fs->mat_ix, id, &v)) return &fs->mats[v];
    const scene_material *sm = scene_material_find(sc, id);
    if (!sm) return NULL;
    material_of(fs, sc, &sm->m, &fs->mats[fs->nmats]);
    /* MATERIAL_PUT checked it; one the renderers would still refuse (a
       journal of an older daemon) is drawn with the default material
       rather than failing every frame */
    if (vt_material_check(&fs->mats[fs->nmats], NULL, 0)) return NULL;
    idmap_put(&fs->mat_ix, id, fs->nmats);
    return &fs->mats[fs->nmats++];
}

bool frame_scene_init(frame_scene *fs, const scene *sc)
{
    memset(fs, 0, sizeof *fs);
    size_t nm = sc->materials.count + 1, nt = sc->textures.count + 1;
    fs->mats = malloc(nm * sizeof *fs->mats);
    fs->texs = malloc(nt * sizeof *fs->texs);
    if (!fs->mats || !fs->texs || !idmap_reserve(&fs->mat_ix, nm) || !idmap_reserve(&fs->tex_ix, nt)) {
        frame_scene_free(fs);
        return false;
    }
    const vp_env *e = &sc->env;
    vt_env *o = &fs->env;
    *o = (vt_env){.sky_mode = e->sky_mode, .turbidity = e->turbidity, .sky_rotation = e->sky_rotation,
                  .ground = (e->flags & VP_ENV_GROUND) != 0, .ground_height = e->ground_height,
                  .fog_density = e->fog_density, .fog_falloff = e->fog_height_falloff,
                  .exposure_mode = e->exposure_mode, .exposure_ev = e->exposure_ev, .exposure_comp = e->exposure_comp};
    for (int k = 0; k < 3; k++) {
        o->sun_dir[k] = e->sun_dir[k];
        o->sun[k] = e->sun_color[k] * e->sun_lux;
        float sky = e->sky_mode == VP_SKY_COLOR ? e->sky_color[k] * e->sky_intensity : e->sky_intensity;
        o->sky[k] = sky < 1e9f ? sky : 1e9f;
        o->ground_albedo[k] = e->ground_color[k];
        o->fog_color[k] = e->fog_color[k];
    }
    if (e->sky_mode == VP_SKY_TEXTURE && !(o->sky_tex = frame_tex(fs, sc, e->sky_texture, true))) {
        /* the sky's texture is gone (or is not a float image): the
           analytic sky rather than no picture */
        o->sky_mode = VT_SKY_ANALYTIC;
        o->turbidity = 2.5f;
    }
    if (o->sky_tex && !o->sky_tex->hdr) { /* an 8-bit image as the sky: not an environment map */
        o->sky_tex = NULL;
        o->sky_mode = VT_SKY_ANALYTIC;
        o->turbidity = 2.5f;
    }
    if (o->ground) o->ground_mat = frame_scene_material(fs, sc, e->ground_material);
    fs->env_ok = vt_env_check(o, NULL, 0) == 0;
    return true;
}

void frame_scene_free(frame_scene *fs)
{
    free(fs->mats);
    free(fs->texs);
    idmap_free(&fs->mat_ix);
    idmap_free(&fs->tex_ix);
    memset(fs, 0, sizeof *fs);
}
