/*
 * vt_scene.c — the scene model's checks and shared shading (vt_scene.h,
 * vt_surface.h): glTF metallic-roughness evaluated per pixel (the kernels
 * of vt_shade.inl light it), Preetham's analytic clear sky, the ground
 * plane, height fog and exposure. vt_gldraw_glsl.c is the same formulas
 * in GLSL.
 *
 * Cost: per shaded pixel a textured material samples up to 4 slots (8
 * texels each, trilinear: vt_texsample.c); the sky costs three Perez evaluations per sky
 * pixel; the ambient is 128 sky samples a frame.
 */
#include "vt_surface.h"
#include "vt_brdf.h"
#include "vt_err.h"
#include "vt_shade.h"

#include <math.h>
#include <string.h>

#define PI_F 3.14159265f

/* ---- checks --------------------------------------------------------------------- */

static bool fin_in(float x, float lo, float hi)
{
    return isfinite(x) && x >= lo && x <= hi;
}

int vt_texview_check(const vt_texview *t, char *err, size_t errlen)
{
    if (!t) return vp_errf(err, errlen, VT_ERR_INVALID, "texture: NULL");
    if (t->w < 1 || t->h < 1 || t->w > VT_TEX_MAX_DIM || t->h > VT_TEX_MAX_DIM)
        return vp_errf(err, errlen, VT_ERR_INVALID, "texture %u: size %ux%u outside 1..%u", t->id, t->w, t->h,
                       VT_TEX_MAX_DIM);
    if (!t->mip == !t->hdr)
        return vp_errf(err, errlen, VT_ERR_INVALID, "texture %u: needs RGBA8 levels or float pixels, one of them",
                       t->id);
    if (t->hdr && t->levels != 1)
        return vp_errf(err, errlen, VT_ERR_INVALID, "texture %u: a float texture has 1 level, not %u", t->id,
                       t->levels);
    uint32_t full = 1;
    while (((t->w > t->h ? t->w : t->h) >> full) > 0) full++;
    if (t->levels < 1 || t->levels > full)
        return vp_errf(err, errlen, VT_ERR_INVALID, "texture %u: %u levels, outside 1..%u for %ux%u", t->id,
                       t->levels, full, t->w, t->h);
    for (uint32_t k = 0; t->mip && k < t->levels; k++)
        if (!t->mip[k]) return vp_errf(err, errlen, VT_ERR_INVALID, "texture %u: level %u missing", t->id, k);
    return 0;
}

static int texref_check(const vt_texref *r, const char *slot, char *err, size_t errlen)
{
    if (!r->tex) return 0;
    char why[120];
    if (vt_texview_check(r->tex, why, sizeof why)) return vp_errf(err, errlen, VT_ERR_INVALID, "%s: %s", slot, why);
    if (r->tex->hdr) return vp_errf(err, errlen, VT_ERR_INVALID, "%s: a float (EXR) texture is for the sky only", slot);
    if (r->wrap_s > VT_WRAP_MIRROR || r->wrap_t > VT_WRAP_MIRROR)
        return vp_errf(err, errlen, VT_ERR_INVALID, "%s: wrap mode %u/%u undefined", slot, r->wrap_s, r->wrap_t);
    if (r->min_filter > VT_FILTER_LINEAR_MIP_LINEAR || r->mag_filter > VT_FILTER_LINEAR)
        return vp_errf(err, errlen, VT_ERR_INVALID, "%s: filter %u/%u undefined", slot, r->min_filter, r->mag_filter);
    for (int k = 0; k < 2; k++)
        if (!fin_in(r->offset[k], -1e6f, 1e6f) || !fin_in(r->scale[k], -1e6f, 1e6f))
            return vp_errf(err, errlen, VT_ERR_INVALID, "%s: offset or scale not finite or beyond 1e6", slot);
    if (!fin_in(r->rotation, -1e3f, 1e3f))
        return vp_errf(err, errlen, VT_ERR_INVALID, "%s: rotation not finite or beyond 1e3", slot);
    return 0;
}

int vt_material_check(const vt_material *m, char *err, size_t errlen)
{
    static const char *const slot[VT_SLOTS] = {"base colour texture", "metallic-roughness texture", "normal texture",
                                               "emissive texture"};
    if (!m) return vp_errf(err, errlen, VT_ERR_INVALID, "material: NULL");
    for (int k = 0; k < 4; k++)
        if (!fin_in(m->base[k], 0, 1)) return vp_errf(err, errlen, VT_ERR_INVALID, "base colour %d outside 0..1", k);
    for (int k = 0; k < 3; k++)
        if (!fin_in(m->emissive[k], 0, 1)) return vp_errf(err, errlen, VT_ERR_INVALID, "emissive %d outside 0..1", k);
    if (!fin_in(m->metallic, 0, 1) || !fin_in(m->roughness, 0, 1))
        return vp_errf(err, errlen, VT_ERR_INVALID, "metallic or roughness outside 0..1");
    if (!fin_in(m->emissive_strength, 0, 1e6f))
        return vp_errf(err, errlen, VT_ERR_INVALID, "emissive strength outside 0..1e6");
    if (!fin_in(m->normal_scale, -1e3f, 1e3f))
        return vp_errf(err, errlen, VT_ERR_INVALID, "normal scale not finite or beyond 1e3");
    if (m->alpha_mode > VT_ALPHA_MASK || !fin_in(m->alpha_cutoff, 0, 1))
        return vp_errf(err, errlen, VT_ERR_INVALID, "alpha mode %u / cutoff outside 0..1", m->alpha_mode);
    for (int k = 0; k < VT_SLOTS; k++) {
        int rc = texref_check(&m->tex[k], slot[k], err, errlen);
        if (rc) return rc;
    }
    return 0;
}

int vt_env_check(const vt_env *e, char *err, size_t errlen)
{
    if (!e) return 0;
    double n2 = 0;
    for (int k = 0; k < 3; k++) {
        if (!fin_in(e->sun_dir[k], -2, 2)) return vp_errf(err, errlen, VT_ERR_INVALID, "env: sun direction not finite");
        n2 += (double)e->sun_dir[k] * e->sun_dir[k];
        if (!fin_in(e->sun[k], 0, 1e6f)) return vp_errf(err, errlen, VT_ERR_INVALID, "env: sun outside 0..1e6 lux");
        if (!fin_in(e->sky[k], 0, 1e9f)) return vp_errf(err, errlen, VT_ERR_INVALID, "env: sky outside 0..1e9");
        if (!fin_in(e->ground_albedo[k], 0, 1))
            return vp_errf(err, errlen, VT_ERR_INVALID, "env: ground albedo outside 0..1");
        if (!fin_in(e->fog_color[k], 0, 1e6f)) return vp_errf(err, errlen, VT_ERR_INVALID, "env: fog colour outside 0..1e6");
    }
    if (n2 != 0 && !(fabs(sqrt(n2) - 1) <= 1e-3))
        return vp_errf(err, errlen, VT_ERR_INVALID, "env: sun direction of length %g, not unit nor 0", sqrt(n2));
    if (e->sky_mode > VT_SKY_TEXTURE) return vp_errf(err, errlen, VT_ERR_INVALID, "env: sky mode %u", e->sky_mode);
    if (e->sky_mode == VT_SKY_ANALYTIC && !fin_in(e->turbidity, 1, 10))
        return vp_errf(err, errlen, VT_ERR_INVALID, "env: turbidity outside 1..10");
    if (e->sky_mode == VT_SKY_TEXTURE) {
        char why[120];
        if (!e->sky_tex) return vp_errf(err, errlen, VT_ERR_INVALID, "env: sky mode texture without a texture");
        if (vt_texview_check(e->sky_tex, why, sizeof why))
            return vp_errf(err, errlen, VT_ERR_INVALID, "env: sky %s", why);
        if (!fin_in(e->sky_rotation, -1e3f, 1e3f))
            return vp_errf(err, errlen, VT_ERR_INVALID, "env: sky rotation not finite or beyond 1e3");
    }
    if (e->ground && !(isfinite(e->ground_height) && fabs(e->ground_height) <= 1e12))
        return vp_errf(err, errlen, VT_ERR_INVALID, "env: ground height not finite or beyond 1e12 m");
    if (e->ground && e->ground_mat) {
        char why[160];
        if (vt_material_check(e->ground_mat, why, sizeof why))
            return vp_errf(err, errlen, VT_ERR_INVALID, "env: ground material: %s", why);
    }
    if (!fin_in(e->fog_density, 0, 1) || !fin_in(e->fog_falloff, 0, 10))
        return vp_errf(err, errlen, VT_ERR_INVALID, "env: fog density outside 0..1 or falloff outside 0..10");
    if (e->exposure_mode > VT_EXPOSURE_AUTO)
        return vp_errf(err, errlen, VT_ERR_INVALID, "env: exposure mode %u", e->exposure_mode);
    if (!fin_in(e->exposure_ev, -10, 30) || !fin_in(e->exposure_comp, -10, 10))
        return vp_errf(err, errlen, VT_ERR_INVALID, "env: exposure EV outside -10..30 or compensation outside -10..10");
    return 0;
}

void vt_material_default(const float albedo[3], vt_material *out)
{
    *out = (vt_material){.base = {albedo[0], albedo[1], albedo[2], 1}, .roughness = VT_DEFAULT_ROUGHNESS,
                         .normal_scale = 1};
}

/* ---- the sky ------------------------------------------------------------------------- */

static float perez(const float c[5], float cos_theta, float gamma)
{
    float cg = cosf(gamma);
    return (1 + c[0] * expf(c[1] / cos_theta)) * (1 + c[2] * expf(c[3] * gamma) + c[4] * cg * cg);
}

/* Preetham, Shirley and Smits, "A practical analytic model for daylight"
 * (1999): Perez's distribution for luminance and chromaticity, the zenith
 * values from the turbidity and the sun's zenith angle. */
static void preetham_make(vt_penv *pe, float T)
{
    static const float k[3][5][2] = {
        {{0.1787f, -1.4630f}, {-0.3554f, 0.4275f}, {-0.0227f, 5.3251f}, {0.1206f, -2.5771f}, {-0.0670f, 0.3703f}},
        {{-0.0193f, -0.2592f}, {-0.0665f, 0.0008f}, {-0.0004f, 0.2125f}, {-0.0641f, -0.8989f}, {-0.0033f, 0.0452f}},
        {{-0.0167f, -0.2608f}, {-0.0950f, 0.0092f}, {-0.0079f, 0.2102f}, {-0.0441f, -1.6537f}, {-0.0109f, 0.0529f}}};
    for (int c = 0; c < 3; c++)
        for (int i = 0; i < 5; i++) pe->perez[c][i] = k[c][i][0] * T + k[c][i][1];
    /* the sun at most just below the horizon for the model (it is
       undefined past 90 degrees); the twilight dimming is applied after */
    float th = pe->theta_s < 1.5f ? pe->theta_s : 1.5f, t2 = th * th, t3 = t2 * th;
    float chi = (4.0f / 9.0f - T / 120.0f) * (PI_F - 2 * th);
    pe->zenith[0] = ((4.0453f * T - 4.9710f) * tanf(chi) - 0.2155f * T + 2.4192f) * 1000.0f; /* cd/m2 */
    pe->zenith[1] = T * T * (0.00166f * t3 - 0.00375f * t2 + 0.00209f * th) +
                    T * (-0.02903f * t3 + 0.06377f * t2 - 0.03202f * th + 0.00394f) +
                    (0.11693f * t3 - 0.21196f * t2 + 0.06052f * th + 0.25886f);
    pe->zenith[2] = T * T * (0.00275f * t3 - 0.00610f * t2 + 0.00317f * th) +
                    T * (-0.04214f * t3 + 0.08970f * t2 - 0.04153f * th + 0.00516f) +
                    (0.15346f * t3 - 0.26756f * t2 + 0.06670f * th + 0.26688f);
    for (int c = 0; c < 3; c++) pe->inv_f0[c] = 1.0f / perez(pe->perez[c], 1.0f, th);
    pe->theta_s = th;
}

void vt_sky_uv(const vt_penv *pe, const float d[3], float uv[2])
{
    /* equirectangular: u from the azimuth (0.5 towards -Z), v 0 at the zenith */
    float u = 0.5f + (atan2f(d[0], -d[2]) + pe->sky_rot) * (0.5f / PI_F);
    uv[0] = u - floorf(u);
    uv[1] = acosf(d[1] < -1 ? -1 : d[1] > 1 ? 1 : d[1]) * (1 / PI_F);
}

void vt_sky_sample(const vt_penv *pe, const float uv[2], float out[3])
{
    const vt_texview *t = pe->sky_img;
    float u = uv[0], v = uv[1];
    if (!(u >= 0 && u <= 1 && v >= 0 && v <= 1)) { /* a NaN direction (a degenerate view): black */
        out[0] = out[1] = out[2] = 0;
        return;
    }
    float x = u * (float)t->w - 0.5f, y = v * (float)t->h - 0.5f, x0 = floorf(x), y0 = floorf(y);
    float ax = x - x0, ay = y - y0;
    int32_t w = (int32_t)t->w, h = (int32_t)t->h;
    int32_t i0 = vt_wrap_i((int32_t)x0, w, VT_WRAP_REPEAT), i1 = vt_wrap_i((int32_t)x0 + 1, w, VT_WRAP_REPEAT);
    int32_t j0 = vt_wrap_i((int32_t)y0, h, VT_WRAP_CLAMP), j1 = vt_wrap_i((int32_t)y0 + 1, h, VT_WRAP_CLAMP);
    for (int c = 0; c < 3; c++) {
        float a = t->hdr[4 * ((size_t)j0 * w + i0) + c], b = t->hdr[4 * ((size_t)j0 * w + i1) + c];
        float e = t->hdr[4 * ((size_t)j1 * w + i0) + c], f = t->hdr[4 * ((size_t)j1 * w + i1) + c];
        float top = a + ax * (b - a), bot = e + ax * (f - e);
        float s = top + ay * (bot - top);
        out[c] = (isfinite(s) ? s : 0) * pe->sky_mul[c];
    }
}

void vt_sky_radiance(const vt_penv *pe, const float d[3], float out[3])
{
    if (pe->sky_mode == VT_SKY_COLOR) {
        memcpy(out, pe->sky, 3 * sizeof *out);
        return;
    }
    if (pe->sky_img) {
        float uv[2];
        vt_sky_uv(pe, d, uv);
        vt_sky_sample(pe, uv, out);
        return;
    }
    /* analytic; below the horizon the horizon's colour */
    float dy = d[1] > 0.01f ? d[1] : 0.01f;
    float cg = d[0] * pe->sun_dir[0] + dy * pe->sun_dir[1] + d[2] * pe->sun_dir[2];
    float gamma = acosf(cg < -1 ? -1 : cg > 1 ? 1 : cg);
    float Y = pe->zenith[0] * perez(pe->perez[0], dy, gamma) * pe->inv_f0[0];
    float x = pe->zenith[1] * perez(pe->perez[1], dy, gamma) * pe->inv_f0[1];
    float y = pe->zenith[2] * perez(pe->perez[2], dy, gamma) * pe->inv_f0[2];
    if (!(y > 1e-4f) || !(Y > 0)) {
        out[0] = out[1] = out[2] = 0;
        return;
    }
    float X = x / y * Y, Z = (1 - x - y) / y * Y;
    /* the sun below the horizon: the sky fades over 6 degrees of twilight */
    float sy = pe->sun_dir[1], fade = sy >= 0 ? 1 : sy <= -0.1f ? 0.001f : 0.001f + 0.999f * (1 + sy * 10);
    float rgb[3] = {3.2406f * X - 1.5372f * Y - 0.4986f * Z, -0.9689f * X + 1.8758f * Y + 0.0415f * Z,
                    0.0557f * X - 0.2040f * Y + 1.0570f * Z};
    for (int c = 0; c < 3; c++) out[c] = (rgb[c] > 0 ? rgb[c] : 0) * fade * pe->sky[c];
}

void vt_penv_make(const vt_env *env, const double origin[3], vt_skytab *tab, vt_penv *pe)
{
    memset(pe, 0, sizeof *pe);
    if (!env) return;
    pe->on = true;
    double n2 = 0;
    for (int k = 0; k < 3; k++) n2 += (double)env->sun_dir[k] * env->sun_dir[k];
    pe->sun_on = n2 > 0;
    for (int k = 0; k < 3; k++) {
        pe->sun_dir[k] = pe->sun_on ? (float)(env->sun_dir[k] / sqrt(n2)) : k == 1;
        pe->sun[k] = pe->sun_on ? env->sun[k] : 0;
        pe->sky[k] = env->sky[k];
        pe->ground_albedo[k] = env->ground_albedo[k];
    }
    pe->sky_mode = env->sky_mode;
    if (pe->sky_mode == VT_SKY_TEXTURE) {
        pe->sky_img = env->sky_tex;
        pe->sky_rot = env->sky_rotation;
        memcpy(pe->sky_mul, pe->sky, sizeof pe->sky_mul);
    }
    if (pe->sky_mode == VT_SKY_ANALYTIC) {
        pe->theta_s = acosf(pe->sun_dir[1] < -1 ? -1 : pe->sun_dir[1] > 1 ? 1 : pe->sun_dir[1]);
        preetham_make(pe, env->turbidity);
    }
    pe->ground = env->ground;
    pe->ground_y = (float)(env->ground_height - origin[1]);
    pe->ground_mat = env->ground_mat;
    pe->ground_uv0[0] = (float)fmod(origin[0], 4096.0);
    pe->ground_uv0[1] = (float)fmod(origin[2], 4096.0);
    pe->fog_density = env->fog_density;
    pe->fog_falloff = env->fog_falloff;
    pe->fog_y0 = (float)((env->ground ? env->ground_height : 0) - origin[1]);
    pe->fog_e0 = expf(fminf(pe->fog_falloff * pe->fog_y0, 80.0f));
    /* the ambient: the sky's cosine-weighted mean over the upper
       hemisphere (8 x 16 directions), and from below the ground's bounce
       of sun and sky (without a ground, the sky's horizon) */
    float up[3] = {0, 0, 0}, wsum = 0, hor[3] = {0, 0, 0};
    for (int i = 0; i < 8; i++) {
        float el = (i + 0.5f) * (PI_F / 16), ce = cosf(el), se = sinf(el);
        for (int j = 0; j < 16; j++) {
            float az = (j + 0.5f) * (PI_F / 8), d[3] = {ce * cosf(az), se, ce * sinf(az)}, L[3];
            vt_sky_radiance(pe, d, L);
            float w = se * ce; /* cos theta x the ring's solid angle */
            for (int c = 0; c < 3; c++) {
                up[c] += w * L[c];
                if (i == 0) hor[c] += L[c] / 16;
            }
            wsum += w;
        }
    }
    float sun_y = pe->sun_dir[1] > 0 ? pe->sun_dir[1] : 0;
    float key[7] = {pe->sun_dir[0], pe->sun_dir[1], pe->sun_dir[2], env->turbidity, pe->sky[0], pe->sky[1], pe->sky[2]};
    if (pe->sky_mode == VT_SKY_ANALYTIC && tab && !(tab->ok && !memcmp(key, tab->key, sizeof key))) {
        memcpy(tab->key, key, sizeof key);
        tab->ok = true;
        /* the table: texel centres of the equirectangular layout */
        for (uint32_t j = 0; j < VT_SKY_TAB_H; j++) {
            float th = (j + 0.5f) * (PI_F / VT_SKY_TAB_H), st = sinf(th), ct = cosf(th);
            for (uint32_t i = 0; i < VT_SKY_TAB_W; i++) {
                float ph = ((i + 0.5f) / VT_SKY_TAB_W - 0.5f) * 2 * PI_F;
                float d[3] = {st * sinf(ph), ct, -st * cosf(ph)};
                float *o = tab->t + 4 * ((size_t)j * VT_SKY_TAB_W + i);
                vt_sky_radiance(pe, d, o);
                o[3] = 1;
            }
        }
    }
    if (pe->sky_mode == VT_SKY_ANALYTIC && tab) {
        pe->sky_tab = (vt_texview){.w = VT_SKY_TAB_W, .h = VT_SKY_TAB_H, .levels = 1, .hdr = tab->t};
        pe->sky_img = &pe->sky_tab;
        pe->sky_mul[0] = pe->sky_mul[1] = pe->sky_mul[2] = 1;
    }
    for (int c = 0; c < 3; c++) {
        pe->amb_up[c] = up[c] / wsum;
        pe->amb_down[c] = env->ground ? env->ground_albedo[c] * (pe->sun[c] * sun_y / PI_F + pe->amb_up[c]) : hor[c];
        pe->fog[c] = env->fog_color[c] * pe->amb_up[c];
    }
}

/* ---- surfaces ------------------------------------------------------------------------ */

static inline void normalize3(float v[3])
{
    float l = sqrtf(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    float il = l > 0 ? 1 / l : 0;
    v[0] *= il;
    v[1] *= il;
    v[2] *= il;
}

static inline float dot3f(const float a[3], const float b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

float vt_surface_alpha(const vt_material *m, const float uv[2], const float dx[2], const float dy[2])
{
    float a = m->base[3];
    if (m->tex[VT_SLOT_BASE].tex) {
        float t[4];
        vt_tex_sample(&m->tex[VT_SLOT_BASE], uv, dx, dy, true, t);
        a *= t[3];
    }
    return a;
}

void vt_surface_params(const vt_surfin *in, vt_surfout *out)
{
    const vt_material *m = in->mat;
    if (!m) {
        /* the default material (vt_material_default), without making one:
           most pixels of most frames */
        float n[3] = {in->n[0], in->n[1], in->n[2]};
        normalize3(n);
        const float a = VT_DEFAULT_ROUGHNESS * VT_DEFAULT_ROUGHNESS;
        for (int c = 0; c < 3; c++) {
            out->n[c] = n[c];
            out->diffuse[c] = in->albedo[c];
            out->f0[c] = 0.04f;
            out->em[c] = 0;
        }
        out->a2 = a * a;
        out->rough = VT_DEFAULT_ROUGHNESS;
        out->alpha = 1;
        return;
    }
    float base[4] = {m->base[0], m->base[1], m->base[2], m->base[3]};
    float metal = m->metallic, rough = m->roughness;
    for (int c = 0; c < 3; c++) out->em[c] = m->emissive[c] * m->emissive_strength;
    float n[3] = {in->n[0], in->n[1], in->n[2]};
    normalize3(n);
    if (in->has_uv && in->mat) {
        float t[4];
        if (m->tex[VT_SLOT_BASE].tex) {
            vt_tex_sample(&m->tex[VT_SLOT_BASE], in->uv, in->dx, in->dy, true, t);
            for (int c = 0; c < 4; c++) base[c] *= t[c];
        }
        if (m->tex[VT_SLOT_MR].tex) {
            vt_tex_sample(&m->tex[VT_SLOT_MR], in->uv, in->dx, in->dy, false, t);
            rough *= t[1];
            metal *= t[2];
        }
        if (m->tex[VT_SLOT_EMISSIVE].tex) {
            vt_tex_sample(&m->tex[VT_SLOT_EMISSIVE], in->uv, in->dx, in->dy, true, t);
            for (int c = 0; c < 3; c++) out->em[c] *= t[c];
        }
        if (m->tex[VT_SLOT_NORMAL].tex && in->has_t) {
            /* tangent space: T, B = w (N x T), N; xy scaled */
            vt_tex_sample(&m->tex[VT_SLOT_NORMAL], in->uv, in->dx, in->dy, false, t);
            float tx = (2 * t[0] - 1) * m->normal_scale, ty = (2 * t[1] - 1) * m->normal_scale, tz = 2 * t[2] - 1;
            float T[3] = {in->t[0], in->t[1], in->t[2]};
            float d = dot3f(T, n);
            for (int c = 0; c < 3; c++) T[c] -= d * n[c];
            normalize3(T);
            float w = in->t[3] < 0 ? -1.0f : 1.0f;
            float B[3] = {w * (n[1] * T[2] - n[2] * T[1]), w * (n[2] * T[0] - n[0] * T[2]), w * (n[0] * T[1] - n[1] * T[0])};
            float nn[3];
            for (int c = 0; c < 3; c++) nn[c] = tx * T[c] + ty * B[c] + tz * n[c];
            normalize3(nn);
            if (dot3f(nn, nn) > 0) memcpy(n, nn, sizeof n);
        }
    }
    memcpy(out->n, n, sizeof n);
    out->alpha = base[3];
    for (int c = 0; c < 3; c++) {
        out->diffuse[c] = base[c] * (1 - metal);
        out->f0[c] = 0.04f * (1 - metal) + base[c] * metal; /* no cancellation (vt_brdf_eval) */
    }
    /* glTF's alpha = roughness^2, clamped away from the singular D
       (vt_brdf.h) */
    rough = vt_brdf_rough(rough);
    float a = rough * rough;
    out->a2 = a * a;
    out->rough = rough;
}

/* ---- rays: the ground, the sky's direction, fog ------------------------------------- */

void vt_view_dir_row(const cull_view_rows *vr, double Y, float c0[3], float c1[3])
{
    /* the ray: (x - X w) . q = 0 and (y - Y w) . q = 0, its direction the
       cross product of the two rows' xyz: linear in X; turned to point
       into the frustum (the near plane's normal) */
    double b[3], x[3], w[3];
    for (int k = 0; k < 3; k++) {
        b[k] = vr->y[k] - Y * vr->w[k];
        x[k] = vr->x[k];
        w[k] = -vr->w[k];
    }
    double p[3] = {x[1] * b[2] - x[2] * b[1], x[2] * b[0] - x[0] * b[2], x[0] * b[1] - x[1] * b[0]};
    double q[3] = {w[1] * b[2] - w[2] * b[1], w[2] * b[0] - w[0] * b[2], w[0] * b[1] - w[1] * b[0]};
    /* the sign at the view's centre column (X = 0) decides: the ray
       never turns within a view */
    double f = p[0] * vr->nearfn[0] + p[1] * vr->nearfn[1] + p[2] * vr->nearfn[2];
    double s = f < 0 ? -1 : 1;
    for (int k = 0; k < 3; k++) {
        c0[k] = (float)(p[k] * s);
        c1[k] = (float)(q[k] * s);
    }
}

bool vt_ground_hit(const vt_penv *pe, const cull_view_rows *vr, int depth_mode, double X, double Y, double q[3],
                   double *near)
{
    if (!pe->ground) return false;
    /* the ray: (x - X w) . (q, 1) = 0, (y - Y w) . (q, 1) = 0; with
       q.y = h, two equations in q.x, q.z */
    double A[4], B[4], h = pe->ground_y;
    for (int k = 0; k < 4; k++) {
        A[k] = vr->x[k] - X * vr->w[k];
        B[k] = vr->y[k] - Y * vr->w[k];
    }
    double det = A[0] * B[2] - A[2] * B[0];
    if (!(fabs(det) > 1e-300)) return false;
    double ra = -A[3] - A[1] * h, rb = -B[3] - B[1] * h;
    q[0] = (ra * B[2] - A[2] * rb) / det;
    q[1] = h;
    q[2] = (A[0] * rb - ra * B[0]) / det;
    double c[4] = {0, 0, 0, 0};
    for (int k = 0; k < 3; k++) {
        c[2] += vr->z[k] * q[k];
        c[3] += vr->w[k] * q[k];
    }
    c[2] += vr->z[3];
    c[3] += vr->w[3];
    double nf = vr->nearfn[0] * q[0] + vr->nearfn[1] * q[1] + vr->nearfn[2] * q[2] + vr->nearfn[3];
    if (!(nf >= 0) || !(c[3] > 0)) return false;
    /* the far plane in the view's depth convention */
    double zf = depth_mode == CULL_DEPTH_REVERSED ? c[2] : c[3] - c[2];
    if (!(zf >= 0)) return false;
    double d = vr->d[0] * q[0] + vr->d[1] * q[1] + vr->d[2] * q[2] + vr->d[3];
    *near = d / c[3];
    return isfinite(*near) && isfinite(q[0]) && isfinite(q[2]);
}

bool vt_inv4(const double m[4][4], double o[4][4])
{
    double a[4][8];
    for (int r = 0; r < 4; r++)
        for (int c = 0; c < 8; c++) a[r][c] = c < 4 ? m[r][c] : (c - 4 == r);
    for (int c = 0; c < 4; c++) {
        int p = c;
        for (int r = c + 1; r < 4; r++)
            if (fabs(a[r][c]) > fabs(a[p][c])) p = r;
        if (!(fabs(a[p][c]) > 1e-300)) return false;
        for (int k = 0; k < 8; k++) {
            double t = a[c][k];
            a[c][k] = a[p][k];
            a[p][k] = t;
        }
        double iv = 1 / a[c][c];
        for (int k = 0; k < 8; k++) a[c][k] *= iv;
        for (int r = 0; r < 4; r++) {
            if (r == c) continue;
            double f = a[r][c];
            for (int k = 0; k < 8; k++) a[r][k] -= f * a[c][k];
        }
    }
    for (int r = 0; r < 4; r++)
        for (int c = 0; c < 4; c++) o[r][c] = a[r][4 + c];
    for (int r = 0; r < 4; r++)
        for (int c = 0; c < 4; c++)
            if (!isfinite(o[r][c])) return false;
    return true;
}

void vt_ground_make(const vt_penv *pe, const cull_view_rows *vr, int depth_mode, vt_ground *g)
{
    memset(g, 0, sizeof *g);
    if (!pe->ground) return;
    /* R maps (q, 1) to (x, y, d, w); a function f . (q, 1) is
       (f R^-1) . (x, y, d, w), and over w: . (X, Y, N, 1) */
    double R[4][4], Ri[4][4];
    memcpy(R[0], vr->x, sizeof R[0]);
    memcpy(R[1], vr->y, sizeof R[1]);
    memcpy(R[2], vr->d, sizeof R[2]);
    memcpy(R[3], vr->w, sizeof R[3]);
    if (!vt_inv4(R, Ri)) return;
    double far_row[4];
    for (int k = 0; k < 4; k++) far_row[k] = depth_mode == CULL_DEPTH_REVERSED ? vr->z[k] : vr->w[k] - vr->z[k];
    const double plane[4] = {0, 1, 0, -(double)pe->ground_y};
    const double *rows[3] = {plane, vr->nearfn, far_row};
    double co[3][4];
    for (int f = 0; f < 3; f++)
        for (int c = 0; c < 4; c++) {
            co[f][c] = 0;
            for (int k = 0; k < 4; k++) co[f][c] += rows[f][k] * Ri[k][c];
        }
    /* on the plane: co0 . (X, Y, N, 1) = 0, solved for N */
    if (!(fabs(co[0][2]) > 1e-300)) return;
    g->n[0] = -co[0][0] / co[0][2];
    g->n[1] = -co[0][1] / co[0][2];
    g->n[2] = -co[0][3] / co[0][2];
    for (int k = 0; k < 2; k++) memcpy(g->lim[k], co[k + 1], sizeof g->lim[k]);
    memcpy(g->inv, Ri, sizeof Ri);
    g->persp = !vr->ortho;
    g->on = isfinite(g->n[0]) && isfinite(g->n[1]) && isfinite(g->n[2]);
}

void vt_ground_point(const vt_ground *g, double X, double Y, double N, double q[3])
{
    double h[4];
    for (int r = 0; r < 4; r++) h[r] = g->inv[r][0] * X + g->inv[r][1] * Y + g->inv[r][2] * N + g->inv[r][3];
    double iw = h[3] != 0 ? 1 / h[3] : 0;
    for (int k = 0; k < 3; k++) q[k] = h[k] * iw;
}

void vt_fog_apply(const vt_penv *pe, const float p[3], float c[3])
{
    if (!pe->on || !(pe->fog_density > 0)) return;
    float L = sqrtf(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
    /* density(y) = d0 exp(-k (y - y0)) integrated along the segment from
       the eye (y = 0) to p */
    float k = pe->fog_falloff, od;
    if (k > 0) {
        float e0 = pe->fog_e0, kd = k * p[1];
        float g = fabsf(kd) > 1e-4f ? (1 - expf(-kd)) / kd : 1 - 0.5f * kd;
        od = pe->fog_density * e0 * L * g;
    } else {
        od = pe->fog_density * L;
    }
    float T = expf(-(od > 0 ? od : 0));
    for (int i = 0; i < 3; i++) c[i] = c[i] * T + pe->fog[i] * (1 - T);
}
