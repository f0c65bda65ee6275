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
    X(f32a, scale) X(f32, rotation) X(u8, texcoord) X(pad8, _) X(pad16, _)
VP_LAYOUT(texref, vp_texref, TEXREF_FIELDS)

#define MATERIAL_FIELDS(X)                                                                                \
    X(u32, id) X(u32, flags) X(u8, alpha_mode) X(pad8, _) X(pad16, _) X(f32, alpha_cutoff)              \
    X(f32a, base_color) X(f32, metallic) X(f32, roughness) X(f32a, emissive) X(f32, emissive_strength)  \
    X(f32, normal_scale)
VP_LAYOUT(material, vp_material, MATERIAL_FIELDS)

static void material_put_all(vp_writer *w, const vp_material *m)
{
    material_put(w, m);
    for (int k = 0; k < VP_TEX_SLOTS; k++) texref_put(w, &m->tex[k]);
}

size_t vp_size_materials(uint32_t n)
{
    _Static_assert(VP_MATERIAL_SIZE == 188 && VP_TEXREF_SIZE == 32, "material record");
    return VP_HEADER_SIZE + 4 + (size_t)n * (material_size() + VP_TEX_SLOTS * texref_size());
}

void vp_enc_materials(vp_writer *w, uint32_t req, const vp_material *m, uint32_t n)
{
    vp_frame_begin(w, VP_MATERIAL_PUT, req);
    vp_put_u32(w, n);
    for (uint32_t i = 0; i < n; i++) material_put_all(w, &m[i]);
    vp_frame_end(w);
}

void vp_put_material(vp_writer *w, const vp_material *m)
{
    material_put_all(w, m);
}

/* Record i (size checked by the decoder); returns the OR of its pads. */
static uint32_t material_read(const uint8_t *recs, uint32_t i, vp_material *m)
{
    vp_reader r;
    vp_reader_init(&r, recs + (size_t)i * VP_MATERIAL_SIZE, VP_MATERIAL_SIZE);
    uint32_t pad = material_get(&r, m);
    for (int k = 0; k < VP_TEX_SLOTS; k++) pad |= texref_get(&r, &m->tex[k]);
    return pad;
}

static const char *const slot_name[VP_TEX_SLOTS] = {"base colour texture", "metallic-roughness texture",
                                                     "normal texture", "emissive texture"};

/* one float in [lo, hi] (finite first), naming it */
static int in_range(float v, double lo, double hi, const char *name, char *why, size_t whylen)
{
    if (!isfinite(v)) return vp_errf(why, whylen, VP_ERR_NONFINITE, "%s is %g: NaN or infinite", name, (double)v);
    if (!(v >= lo && v <= hi))
        return vp_errf(why, whylen, VP_ERR_INVALID, "%s %g is outside %g..%g", name, (double)v, lo, hi);
    return VP_OK;
}

static int texref_check(const vp_texref *t, const char *slot, char *why, size_t whylen)
{
    char name[80];
    const float f[5] = {t->offset[0], t->offset[1], t->scale[0], t->scale[1], t->rotation};
    static const char *const fname[5] = {"offset u", "offset v", "scale u", "scale v", "rotation"};
    for (int k = 0; k < 5; k++) {
        snprintf(name, sizeof name, "%s %s", slot, fname[k]);
        int rc = in_range(f[k], -1e6, 1e6, name, why, whylen);
        if (rc) return rc;
    }
    if (t->wrap_s > VP_WRAP_MIRROR || t->wrap_t > VP_WRAP_MIRROR)
        return vp_errf(why, whylen, VP_ERR_INVALID, "%s wrap (%u, %u): 0 repeat, 1 clamp, 2 mirror are defined", slot,
                       t->wrap_s, t->wrap_t);
    if (t->min_filter > VP_FILTER_LINEAR_MIP_LINEAR)
        return vp_errf(why, whylen, VP_ERR_INVALID, "%s min filter %u: 0..5 are defined", slot, t->min_filter);
    if (t->mag_filter > VP_FILTER_LINEAR)
        return vp_errf(why, whylen, VP_ERR_INVALID, "%s mag filter %u: 0 nearest, 1 linear are defined", slot,
                       t->mag_filter);
    if (t->texcoord)
        return vp_errf(why, whylen, VP_ERR_INVALID, "%s texcoord %u: only set 0 exists", slot, t->texcoord);
    return VP_OK;
}

static int material_check(const vp_material *m, uint32_t pad, char *why, size_t whylen)
{
    static const char *const cname[4] = {"base colour r", "base colour g", "base colour b", "base colour a"};
    static const char *const ename[3] = {"emissive r", "emissive g", "emissive b"};
    int rc;
    if (m->id == 0) return vp_errf(why, whylen, VP_ERR_INVALID, "%s", "id 0 is the default material's");
    if (m->flags & ~VP_MAT_DOUBLE_SIDED)
        return vp_errf(why, whylen, VP_ERR_INVALID, "flags 0x%x has undefined bits (0x1 double-sided is defined)",
                       m->flags);
    if (m->alpha_mode > VP_ALPHA_MASK)
        return vp_errf(why, whylen, VP_ERR_INVALID, "alpha mode %u: 0 opaque and 1 mask are defined", m->alpha_mode);
    if (pad) return vp_errf(why, whylen, VP_ERR_INVALID, "%s", "pad bytes must be zero");
    for (int k = 0; k < 4; k++)
        if ((rc = in_range(m->base_color[k], 0, 1, cname[k], why, whylen))) return rc;
    if ((rc = in_range(m->alpha_cutoff, 0, 1, "alpha cutoff", why, whylen)) ||
        (rc = in_range(m->metallic, 0, 1, "metallic", why, whylen)) ||
        (rc = in_range(m->roughness, 0, 1, "roughness", why, whylen)))
        return rc;
    for (int k = 0; k < 3; k++)
        if ((rc = in_range(m->emissive[k], 0, 1, ename[k], why, whylen))) return rc;
    if ((rc = in_range(m->emissive_strength, 0, 1e6, "emissive strength", why, whylen)) ||
        (rc = in_range(m->normal_scale, -1e3, 1e3, "normal scale", why, whylen)))
        return rc;
    for (int k = 0; k < VP_TEX_SLOTS; k++)
        if ((rc = texref_check(&m->tex[k], slot_name[k], why, whylen))) return rc;
    return VP_OK;
}

int vp_material_rec_check(const uint8_t *recs, uint32_t n, uint32_t i, char *why, size_t whylen)
{
    if (i >= n) return VP_ERR_COUNT;
    vp_material m;
    uint32_t pad = material_read(recs, i, &m);
    return material_check(&m, pad, why, whylen);
}

int vp_material_get(const uint8_t *recs, uint32_t n, uint32_t i, vp_material *out)
{
    if (i >= n) return VP_ERR_COUNT;
    uint32_t pad = material_read(recs, i, out);
    return material_check(out, pad, NULL, 0);
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

#define TEXTURE_PUT_FIELDS(X) X(u32, id) X(u8, format) X(u8, flags) X(pad16, _) X(u32, total) X(u32, offset)
VP_LAYOUT(texture_put, vp_texture_put, TEXTURE_PUT_FIELDS)

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

int vp_dec_texture_put(const uint8_t *p, size_t len, vp_texture_put *m)
{
    vp_reader r;
    int rc = texture_put_head(&r, p, len, m);
    if (rc) return rc;
    m->len = (uint32_t)(len - VP_TEXTURE_PUT_HEADER);
    m->data = p + VP_TEXTURE_PUT_HEADER;
    if (m->id == 0 || m->format > VP_TEX_EXR || (m->flags & ~VP_TEX_SRGB)) return VP_ERR_INVALID;
    if (m->total == 0 || m->total > VP_MAX_TEXTURE_BYTES) return VP_ERR_COUNT;
    if (m->len == 0 || m->offset > m->total || m->len > m->total - m->offset) return VP_ERR_COUNT;
    return VP_OK;
}

/* ---- environment ------------------------------------------------------------------ */

#define ENV_FIELDS(X)                                                                                       \
    X(f32a, sun_dir) X(f32a, sun_color) X(f32, sun_lux) X(u8, sky_mode) X(u8, flags) X(u8, exposure_mode) \
    X(pad8, _) X(f32a, sky_color) X(f32, sky_intensity) X(f32, turbidity) X(u32, sky_texture)            \
    X(f32, sky_rotation) X(pad32, _) X(f64, ground_height) X(f32a, ground_color) X(u32, ground_material) \
    X(f32, fog_density) X(f32a, fog_color) X(f32, fog_height_falloff) X(f32, exposure_ev)                \
    X(f32, exposure_comp) X(pad32, _)
VP_LAYOUT(env, vp_env, ENV_FIELDS)

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

size_t vp_size_env(void)
{
    _Static_assert(VP_ENV_SIZE == 120, "env record");
    return VP_HEADER_SIZE + env_size();
}

void vp_enc_env(vp_writer *w, uint16_t type, uint32_t req, const vp_env *m)
{
    env_enc(w, type, req, m);
}

int vp_env_check(vp_env *m, char *why, size_t whylen)
{
    int rc;
    static const char *const d[3] = {"sun direction x", "sun direction y", "sun direction z"};
    static const char *const sc[3] = {"sun colour r", "sun colour g", "sun colour b"};
    static const char *const kc[3] = {"sky colour r", "sky colour g", "sky colour b"};
    static const char *const gc[3] = {"ground colour r", "ground colour g", "ground colour b"};
    static const char *const fc[3] = {"fog colour r", "fog colour g", "fog colour b"};
    for (int k = 0; k < 3; k++)
        if ((rc = in_range(m->sun_dir[k], -2, 2, d[k], why, whylen)) ||
            (rc = in_range(m->sun_color[k], 0, 1, sc[k], why, whylen)) ||
            (rc = in_range(m->sky_color[k], 0, 1e6, kc[k], why, whylen)) ||
            (rc = in_range(m->ground_color[k], 0, 1, gc[k], why, whylen)) ||
            (rc = in_range(m->fog_color[k], 0, 1e6, fc[k], why, whylen)))
            return rc;
    if ((rc = in_range(m->sun_lux, 0, 200000, "sun illuminance", why, whylen)) ||
        (rc = in_range(m->sky_intensity, 0, 1e6, "sky intensity", why, whylen)) ||
        (rc = in_range(m->turbidity, m->sky_mode == VP_SKY_ANALYTIC ? 1 : -1e6,
                       m->sky_mode == VP_SKY_ANALYTIC ? 10 : 1e6, "turbidity", why, whylen)) ||
        (rc = in_range(m->sky_rotation, -1e3, 1e3, "sky rotation", why, whylen)) ||
        (rc = in_range(m->fog_density, 0, 1, "fog density", why, whylen)) ||
        (rc = in_range(m->fog_height_falloff, 0, 10, "fog height falloff", why, whylen)) ||
        (rc = in_range(m->exposure_ev, -10, 30, "exposure EV", why, whylen)) ||
        (rc = in_range(m->exposure_comp, -10, 10, "exposure compensation", why, whylen)))
        return rc;
    if (!isfinite(m->ground_height))
        return vp_errf(why, whylen, VP_ERR_NONFINITE, "ground height is %g: NaN or infinite", m->ground_height);
    if (!(fabs(m->ground_height) <= 1e12))
        return vp_errf(why, whylen, VP_ERR_INVALID, "ground height %g m is beyond +-1e12 m", m->ground_height);
    if (m->sky_mode > VP_SKY_TEXTURE)
        return vp_errf(why, whylen, VP_ERR_INVALID, "sky mode %u: 0 colour, 1 analytic, 2 texture are defined",
                       m->sky_mode);
    if (m->sky_mode == VP_SKY_TEXTURE && !m->sky_texture)
        return vp_errf(why, whylen, VP_ERR_INVALID, "%s", "sky mode 2 (texture) needs a sky texture id");
    if (m->flags & ~VP_ENV_GROUND)
        return vp_errf(why, whylen, VP_ERR_INVALID, "flags 0x%x has undefined bits (0x1 ground is defined)", m->flags);
    if (m->exposure_mode > VP_EXPOSURE_AUTO)
        return vp_errf(why, whylen, VP_ERR_INVALID, "exposure mode %u: 0 fixed and 1 auto are defined",
                       m->exposure_mode);
    double n2 = 0;
    for (int k = 0; k < 3; k++) n2 += (double)m->sun_dir[k] * m->sun_dir[k];
    if (n2 != 0) {
        double n = sqrt(n2);
        if (!(fabs(n - 1) <= VP_QUAT_TOLERANCE))
            return vp_errf(why, whylen, VP_ERR_INVALID,
                           "sun direction (%g, %g, %g) has length %.6g: not a unit vector (1 +- %g) nor 0",
                           (double)m->sun_dir[0], (double)m->sun_dir[1], (double)m->sun_dir[2], n, VP_QUAT_TOLERANCE);
        for (int k = 0; k < 3; k++) m->sun_dir[k] = (float)(m->sun_dir[k] / n);
    }
    return VP_OK;
}

int vp_dec_env(const uint8_t *p, size_t len, vp_env *m)
{
    int rc = env_dec(p, len, m);
    return rc ? rc : vp_env_check(m, NULL, 0);
}
