/*
 * vp_scene.c — the scene model's messages of the protocol (version 2, see
 * protocol.h and PROTOCOL.md): MATERIAL_PUT records with their texture
 * slots, TEXTURE_PUT chunks, and the environment (ENV_SET / ENV_REPLY),
 * each a layout described once with its checks next to it.
 */
#include "vp_internal.h"
#include "vp_layout.h"

#include <math.h>

/* ---- materials ---------------------------------------------------------------- */

#define TEXREF_FIELDS(X)                                                                                  \
    X(u32, texture) X(u8, wrap_s) X(u8, wrap_t) X(u8, min_filter) X(u8, mag_filter) X(f32a, offset)     \
    X(f32a, scale) X(f32, rotation) X(u8, texcoord) X(pad8, pad1) X(pad16, pad2)
#define TEXREF_CHECKS(X)                                                                                  \
    X(range, offset, "offset", "u,v", -1e6, 1e6) X(range, scale, "scale", "u,v", -1e6, 1e6)              \
    X(range, rotation, "rotation", "", -1e6, 1e6)                                                        \
    X(max, wrap_s, "wrap s", "0 repeat, 1 clamp, 2 mirror are defined", 0, VP_WRAP_MIRROR)               \
    X(max, wrap_t, "wrap t", "0 repeat, 1 clamp, 2 mirror are defined", 0, VP_WRAP_MIRROR)               \
    X(max, min_filter, "min filter", "0..5 are defined", 0, VP_FILTER_LINEAR_MIP_LINEAR)                 \
    X(max, mag_filter, "mag filter", "0 nearest, 1 linear are defined", 0, VP_FILTER_LINEAR)             \
    X(max, texcoord, "texcoord", "only set 0 exists", 0, 0)
VP_LAYOUT_CHECKED(texref, vp_texref, TEXREF_FIELDS, TEXREF_CHECKS)

#define MATERIAL_FIELDS(X)                                                                                \
    X(u32, id) X(u32, flags) X(u8, alpha_mode) X(pad8, pad1) X(pad16, pad2) X(f32, alpha_cutoff)        \
    X(f32a, base_color) X(f32, metallic) X(f32, roughness) X(f32a, emissive) X(f32, emissive_strength)  \
    X(f32, normal_scale)
#define MATERIAL_CHECKS(X)                                                                                \
    X(nonzero, id, "id", "0 is the default material's", 0, 0)                                           \
    X(mask, flags, "flags", "0x1 double-sided is defined", 0, VP_MAT_DOUBLE_SIDED)                      \
    X(max, alpha_mode, "alpha mode", "0 opaque and 1 mask are defined", 0, VP_ALPHA_MASK)               \
    X(range, alpha_cutoff, "alpha cutoff", "", 0, 1) X(range, base_color, "base colour", "r,g,b,a", 0, 1) \
    X(range, metallic, "metallic", "", 0, 1) X(range, roughness, "roughness", "", 0, 1)                 \
    X(range, emissive, "emissive", "r,g,b", 0, 1) X(range, emissive_strength, "emissive strength", "", 0, 1e6) \
    X(range, normal_scale, "normal scale", "", -1e3, 1e3)
VP_LAYOUT_CHECKED(material, vp_material, MATERIAL_FIELDS, MATERIAL_CHECKS)

static void material_put_all(vp_writer *w, const vp_material *m)
{
    material_put(w, m);
    for (int k = 0; k < VP_TEX_SLOTS; k++) texref_put(w, &m->tex[k]);
}

_Static_assert(VP_MATERIAL_SIZE == 188 && VP_TEXREF_SIZE == 32, "material record");
VP_BATCH_MESSAGE(materials, vp_material, VP_MATERIAL_PUT, material_put_all, VP_MATERIAL_SIZE)

void vp_put_material(vp_writer *w, const vp_material *m)
{
    material_put_all(w, m);
}

/* Record i (size checked by the decoder); the pads of its head and of
 * each texture slot (name_get's: 0, or 1 + the first bad pad's offset). */
typedef struct material_pads {
    uint32_t head, tex[VP_TEX_SLOTS];
} material_pads;

static void material_read(const uint8_t *recs, uint32_t i, vp_material *m, material_pads *pad)
{
    vp_reader r;
    vp_reader_init(&r, recs + (size_t)i * VP_MATERIAL_SIZE, VP_MATERIAL_SIZE);
    pad->head = material_get(&r, m);
    for (int k = 0; k < VP_TEX_SLOTS; k++) pad->tex[k] = texref_get(&r, &m->tex[k]);
}

/* the messages' prefix of each slot's fields */
static const char *const slot_name[VP_TEX_SLOTS] = {"base colour texture ", "metallic-roughness texture ",
                                                     "normal texture ", "emissive texture "};

static int material_check(const vp_material *m, const material_pads *pad, char *why, size_t whylen)
{
    int rc = material_check_fields(m, pad->head, "", why, whylen);
    for (int k = 0; !rc && k < VP_TEX_SLOTS; k++)
        rc = texref_check_fields(&m->tex[k], pad->tex[k], slot_name[k], why, whylen);
    return rc;
}

int vp_material_rec_check(const uint8_t *recs, uint32_t n, uint32_t i, char *why, size_t whylen)
{
    if (i >= n) return VP_ERR_COUNT;
    vp_material m;
    material_pads pad;
    material_read(recs, i, &m, &pad);
    return material_check(&m, &pad, why, whylen);
}

int vp_material_get(const uint8_t *recs, uint32_t n, uint32_t i, vp_material *out)
{
    if (i >= n) return VP_ERR_COUNT;
    material_pads pad;
    material_read(recs, i, out, &pad);
    return material_check(out, &pad, NULL, 0);
}

int vp_dec_materials(const uint8_t *p, size_t len, uint32_t max_batch, const uint8_t **recs, uint32_t *n)
{
    vp_reader r;
    vp_reader_init(&r, p, len);
    *n = vp_get_u32(&r);
    int rc = vp_take_rest(&r, *n, VP_MATERIAL_SIZE, max_batch, recs);
    if (rc) return rc;
    for (uint32_t i = 0; i < *n; i++)
        if ((rc = vp_material_rec_check(*recs, *n, i, NULL, 0))) return rc;
    return VP_OK;
}

/* ---- textures ------------------------------------------------------------------- */

#define TEXTURE_PUT_FIELDS(X) X(u32, id) X(u8, format) X(u8, flags) X(pad16, pad1) X(u32, total) X(u32, offset)
#define TEXTURE_PUT_CHECKS(X)                                                                             \
    X(nonzero, id, "id", "texture ids are 1..4294967295", 0, 0)                                         \
    X(max, format, "format", "0 PNG, 1 JPEG, 2 OpenEXR are defined", 0, VP_TEX_EXR)                     \
    X(mask, flags, "flags", "0x1 sRGB is defined", 0, VP_TEX_SRGB)                                      \
    X(count, total, "total bytes", "", 1, VP_MAX_TEXTURE_BYTES)
VP_LAYOUT_CHECKED(texture_put, vp_texture_put, TEXTURE_PUT_FIELDS, TEXTURE_PUT_CHECKS)

size_t vp_size_texture_put(uint32_t len)
{
    _Static_assert(VP_TEXTURE_PUT_HEADER == 16, "texture header");
    return VP_HEADER_SIZE + texture_put_size() + len;
}

void vp_enc_texture_put(vp_writer *w, uint32_t req, const vp_texture_put *m)
{
    vp_enc_texture_as(w, VP_TEXTURE_PUT, req, m);
}

/* TEXTURE_PUT's layout under type (TEXTURE_REPLY: a chunk read back) */
void vp_enc_texture_as(vp_writer *w, uint16_t type, uint32_t req, const vp_texture_put *m)
{
    vp_frame_begin(w, type, req);
    texture_put_put(w, m);
    vp_put_bytes(w, m->data, m->len);
    vp_frame_end(w);
}

/* the header's fields, then the chunk inside the image */
static int texture_put_check(const vp_texture_put *m, uint32_t pad, char *why, size_t whylen)
{
    int rc = texture_put_check_fields(m, pad, "", why, whylen);
    if (rc) return rc;
    if (m->len == 0) return vp_errf(why, whylen, VP_ERR_COUNT, "%s", "chunk of 0 bytes: a chunk carries 1 or more");
    if (m->offset > m->total || m->len > m->total - m->offset)
        return vp_errf(why, whylen, VP_ERR_COUNT, "chunk at offset %u of %u bytes ends past the total, %u bytes",
                       m->offset, m->len, m->total);
    return VP_OK;
}

int vp_texture_put_check(const vp_texture_put *m, char *why, size_t whylen)
{
    return texture_put_check(m, 0, why, whylen);
}

int vp_dec_texture_put_why(const uint8_t *p, size_t len, vp_texture_put *m, char *why, size_t whylen)
{
    vp_reader r;
    uint32_t pad = 0;
    vp_reader_init(&r, p, len);
    pad = texture_put_get(&r, m);
    if (r.short_read) return vp_errf(why, whylen, VP_ERR_TRUNCATED, "%u bytes: the header alone is %u", (unsigned)len,
                                     VP_TEXTURE_PUT_HEADER);
    m->len = (uint32_t)(len - VP_TEXTURE_PUT_HEADER);
    m->data = p + VP_TEXTURE_PUT_HEADER;
    return texture_put_check(m, pad, why, whylen);
}

int vp_dec_texture_put(const uint8_t *p, size_t len, vp_texture_put *m)
{
    return vp_dec_texture_put_why(p, len, m, NULL, 0);
}

/* ---- environment ------------------------------------------------------------------ */

#define ENV_FIELDS(X)                                                                                       \
    X(f32a, sun_dir) X(f32a, sun_color) X(f32, sun_lux) X(u8, sky_mode) X(u8, flags) X(u8, exposure_mode) \
    X(pad8, pad1) X(f32a, sky_color) X(f32, sky_intensity) X(f32, turbidity) X(u32, sky_texture)            \
    X(f32, sky_rotation) X(pad32, pad2) X(f64, ground_height) X(f32a, ground_color) X(u32, ground_material) \
    X(f32, fog_density) X(f32a, fog_color) X(f32, fog_height_falloff) X(f32, exposure_ev)                \
    X(f32, exposure_comp) X(pad32, pad3)
#define ENV_CHECKS(X)                                                                                       \
    X(range, sun_dir, "sun direction", "x,y,z", -INFINITY, INFINITY)                                     \
    X(range, sun_color, "sun colour", "r,g,b", 0, 1)                                                     \
    X(range, sun_lux, "sun illuminance", "", 0, 200000)                                                  \
    X(max, sky_mode, "sky mode", "0 colour, 1 analytic, 2 texture are defined", 0, VP_SKY_TEXTURE)       \
    X(mask, flags, "flags", "0x1 ground is defined", 0, VP_ENV_GROUND)                                   \
    X(max, exposure_mode, "exposure mode", "0 fixed and 1 auto are defined", 0, VP_EXPOSURE_AUTO)        \
    X(range, sky_color, "sky colour", "r,g,b", 0, 1e6) X(range, sky_intensity, "sky intensity", "", 0, 1e6) \
    X(range, turbidity, "turbidity", "", -1e6, 1e6) X(range, sky_rotation, "sky rotation", "", -1e3, 1e3) \
    X(range, ground_height, "ground height", "", -1e12, 1e12)                                            \
    X(range, ground_color, "ground colour", "r,g,b", 0, 1) X(range, fog_density, "fog density", "", 0, 1) \
    X(range, fog_color, "fog colour", "r,g,b", 0, 1e6)                                                   \
    X(range, fog_height_falloff, "fog height falloff", "", 0, 10)                                        \
    X(range, exposure_ev, "exposure EV", "", -10, 30) X(range, exposure_comp, "exposure compensation", "", -10, 10)
VP_LAYOUT_CHECKED(env, vp_env, ENV_FIELDS, ENV_CHECKS)

void vp_env_default(vp_env *e)
{
    /* sun 50 degrees up, from the south-west; a clear sky; grey ground */
    *e = (vp_env){.sun_color = {1.0f, 0.96f, 0.9f}, .sun_lux = 100000.0f, .sky_mode = VP_SKY_ANALYTIC,
                  .flags = VP_ENV_GROUND, .exposure_mode = VP_EXPOSURE_AUTO, .sky_color = {0.3f, 0.5f, 0.9f},
                  .sky_intensity = 1.0f, .turbidity = 2.5f, .ground_color = {0.25f, 0.25f, 0.25f},
                  .fog_density = 0.0005f, .fog_color = {0.6f, 0.7f, 0.8f}, .exposure_ev = 14.0f};
    double el = 50 * M_PI / 180, az = 225 * M_PI / 180;
    e->sun_dir[0] = (float)(cos(el) * sin(az));
    e->sun_dir[1] = (float)sin(el);
    e->sun_dir[2] = (float)(cos(el) * cos(az));
}

int vp_env_preset(const char *name, vp_env *e)
{
    vp_env_default(e);
    /* the city's streets: asphalt (albedo about 0.08) */
    e->ground_color[0] = 0.08f, e->ground_color[1] = 0.08f, e->ground_color[2] = 0.085f;
    if (!strcmp(name, "day")) return VP_OK;
    if (!strcmp(name, "night")) {
        /* a moonlit night as games and films show one (day for night):
           the "sun" is the moon, bluish, high in the south-east, at 1 lux
           (a real full moon gives 0.1-0.3: walls facing away from it went
           black, 10-12 EV under the lit windows, more than one exposure
           fits into the tone curve); a deep blue sky of 0.05-0.16 nits
           whose image-based ambient keeps the shaded walls readable; a
           moonlit haze (the fog 0.7-0.9 of the sky's mean: at 1 % the
           distance went black); auto exposure raised 0.5 EV: the
           histogram meter (render/vt_post.h) averages the brighter half of
           the frame, here the lamps and windows. The demo city's street,
           aerial and top-down views keep >= 95 % of their pixels neither
           black nor clipped (test_post_city_exposure) */
        double el = 55 * M_PI / 180, az = 135 * M_PI / 180;
        e->sun_dir[0] = (float)(cos(el) * sin(az));
        e->sun_dir[1] = (float)sin(el);
        e->sun_dir[2] = (float)(cos(el) * cos(az));
        e->sun_color[0] = 0.6f, e->sun_color[1] = 0.7f, e->sun_color[2] = 1.0f;
        e->sun_lux = 1.0f;
        e->sky_mode = VP_SKY_COLOR;
        e->sky_color[0] = 0.05f, e->sky_color[1] = 0.07f, e->sky_color[2] = 0.16f;
        e->sky_intensity = 1.0f;
        e->fog_density = 0.002f;
        e->fog_color[0] = 0.7f, e->fog_color[1] = 0.75f, e->fog_color[2] = 0.9f;
        e->exposure_comp = 0.5f;
        return VP_OK;
    }
    vp_env_default(e);
    return VP_ERR_NOT_FOUND;
}

size_t vp_size_env(void)
{
    _Static_assert(VP_ENV_SIZE == 120, "env record");
    return VP_HEADER_SIZE + env_size();
}

void vp_enc_env(vp_writer *w, uint16_t type, uint32_t req, const vp_env *m)
{
    env_enc(w, type, req, m);
}

/* the fields' own checks, then what spans fields: the analytic sky's
 * turbidity, a texture sky's texture, the sun's direction */
static int env_check(vp_env *m, uint32_t pad, char *why, size_t whylen)
{
    int rc = env_check_fields(m, pad, "", why, whylen);
    if (rc) return rc;
    if (m->sky_mode == VP_SKY_ANALYTIC && (rc = vp_check_floats(&m->turbidity, 4, 4, "analytic sky ", "turbidity", "",
                                                                1, 10, why, whylen)))
        return rc;
    if (m->sky_mode == VP_SKY_TEXTURE && !m->sky_texture)
        return vp_errf(why, whylen, VP_ERR_INVALID, "%s",
                       "sky texture is 0: sky mode 2 (texture) needs a sky texture id");
    double n2 = 0;
    for (int k = 0; k < 3; k++) n2 += (double)m->sun_dir[k] * m->sun_dir[k];
    if (n2 != 0) {
        double n = sqrt(n2);
        if (!(fabs(n - 1) <= VP_QUAT_TOLERANCE))
            return vp_errf(why, whylen, VP_ERR_INVALID,
                           "sun direction (%g, %g, %g) has length %.6g: not a unit vector (1 +- %g) nor 0",
                           (double)m->sun_dir[0], (double)m->sun_dir[1], (double)m->sun_dir[2], n, VP_QUAT_TOLERANCE);
        if (fabs(n - 1) > VP_UNIT_EXACT)
            for (int k = 0; k < 3; k++) m->sun_dir[k] = (float)(m->sun_dir[k] / n);
    }
    return VP_OK;
}

int vp_env_check(vp_env *m, char *why, size_t whylen)
{
    return env_check(m, 0, why, whylen);
}

int vp_dec_env_why(const uint8_t *p, size_t len, vp_env *m, char *why, size_t whylen)
{
    vp_reader r;
    vp_reader_init(&r, p, len);
    uint32_t pad = env_get(&r, m);
    int rc = vp_reader_finish(&r);
    if (rc) return vp_errf(why, whylen, rc, "%u bytes: the environment record is %u", (unsigned)len, VP_ENV_SIZE);
    return env_check(m, pad, why, whylen);
}

int vp_dec_env(const uint8_t *p, size_t len, vp_env *m)
{
    return vp_dec_env_why(p, len, m, NULL, 0);
}
