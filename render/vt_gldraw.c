/*
 * vt_gldraw.c — the OpenGL renderer (see vt_gldraw.h).
 *
 * Per frame: one vertex buffer for every mesh (positions and normals, with
 * an index buffer; a mesh without normals is expanded to flat-shaded
 * triangles, as the software path shades it), one instance buffer (the
 * mesh's bounds onto
 * the instance's box as a scale and a camera-relative shift, computed in
 * double as vt_soft does, the albedo and a damaged instance's mask index),
 * the masks in two buffer textures, a float view-projection. A mesh's
 * damaged instances get their own draw, two-sided, the fragment shader
 * discarding where vt_mask.h's mask is negative. Pass 1 draws nearness
 * (d . p, interpolated perspective-correct, times gl_FragCoord.w = 1 / w:
 * a noperspective d / w gave NaN on llvmpipe for near, large triangles)
 * into alpha; the per-tile nearness ranges give
 * cull_lights_bin its depth planes; the lights and lists go to buffer
 * textures; pass 2 shades. Colour alpha carries nearness on the way out
 * and is turned into coverage and depth on the CPU, as vt_soft does.
 *
 * The scene model (issue 19): instances carry a rotation (quaternion) as
 * well as a scale and shift; draws are grouped by (mesh, material,
 * damaged, mirrored): a material's factors are uniforms and its textures
 * GL textures (kept by texture id and generation across frames,
 * vt_gltex.c) with sampler objects set from its slots; mirrored
 * instances are drawn with clockwise front faces, double-sided materials
 * without culling. With an environment, a background pass (a triangle
 * over the viewport) solves the ground plane per pixel and writes its
 * depth (gl_FragDepth), else the sky at the far plane; fog is applied in
 * the shaders; exposure and FXAA on the CPU after the readback
 * (vt_post_apply, the software renderer's code: one set of rules). The shaders are in vt_gldraw_glsl.c.
 */
#include "vt_brdf.h"
#include "vt_gldraw.h"
#include "vt_gldraw_internal.h"
#include "vt_glssao.h"
#include "vt_picture.h"
#include "vt_post.h"
#include "vt_shadow_gl.h"

#include <epoxy/gl.h>
#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define TILE VT_TILE
#define EMPTY VT_EMPTY
#define IV 14                /* floats an instance: scale, shift, albedo, mask, rotation */
#define MASK_TEXELS 5        /* RGBA texels a mask header */

/* One mesh's share of the frame's vertex buffer. */
typedef struct mesh_draw {
    uint32_t vfirst, nvx;   /* its vertices (expanded per index without normals) */
    uint32_t efirst, nel;   /* its indices (0: drawn from the expanded vertices) */
    uint32_t ninst;         /* instances of it this frame */
    float b[6];             /* the mesh's bounds */
} mesh_draw;

/* A run of instances drawn with one call: same mesh, material, damage
 * and handedness. */
typedef struct group {
    uint32_t mesh, ifirst, n;
    const vt_material *mat;
    bool masked, mirror;
} group;

#define VF 12               /* floats a vertex: position, normal, uv, tangent */

/* The programs' uniforms, by name (UNIFORMS order). */
#define UNIFORMS(X)                                                                                  \
    X(u_vp) X(u_d) X(u_pass) X(u_tiles_x) X(u_two_sided) X(u_mat_on) X(u_alpha_mask) X(u_tex_on)     \
    X(u_has_uv) X(u_has_t) X(u_base) X(u_mr) X(u_em) X(u_nscale) X(u_cutoff) X(u_txm) X(u_txo)       \
    X(u_env_on) X(u_sun_on) X(u_sky_mode) X(u_sun_dir) X(u_sun) X(u_amb_up) X(u_amb_down) X(u_fog)   \
    X(u_sky) X(u_fog_density) X(u_fog_falloff) X(u_fog_y0) X(u_sky_rot) X(u_ground)                   \
    X(u_depth_half) X(u_reversed) X(u_size) X(u_rx) X(u_ry) X(u_rz) X(u_rw)                          \
    X(u_rn) X(u_rd) X(u_ground_y) X(u_ground_albedo) X(u_ground_uv0)
#define U_ENUM(n) n,
enum { UNIFORMS(U_ENUM) U_COUNT };
#define U_NAME(n) #n,
static const char *const u_names[U_COUNT] = {UNIFORMS(U_NAME)};

struct vt_gldraw {
    vt_gl *g;
    unsigned prog, bg, vao;
    int loc[2][U_COUNT];     /* [main, background] */
    int max_texels;          /* GL_MAX_TEXTURE_BUFFER_SIZE */
    unsigned tex[5], buf[5]; /* buffer textures: lights, tile offsets, tile indices,
                                mask headers, mask fields */
    unsigned vbuf, ibuf, ebuf; /* this frame's vertices, instances and indices, all meshes */
    unsigned samp[4];        /* the material slots' sampler objects (units 5..8) */
    vt_gltex tc;             /* textures */
    vt_gl_target *target;
    /* per frame, grown as needed */
    float *pix;              /* readback */
    size_t pix_cap;
    float *vx, *iv, *ld;     /* vertices, instances, lights as uploaded */
    size_t vx_cap, iv_cap, ld_cap;
    float *mh, *mf;          /* mask headers (MASK_TEXELS RGBA32UI texels each: float bits, then
                                integers), fields */
    size_t mh_cap, mf_cap;
    uint32_t *el;            /* indices as uploaded */
    size_t el_cap;
    mesh_draw *md;
    size_t md_cap;
    struct dkey *key;        /* instances in draw order */
    size_t key_cap;
    vt_post post;            /* exposure and FXAA on the readback (vt_post.h) */
    group *gr;
    size_t ngr, gr_cap;
    float (*range)[2];
    size_t range_cap;
    cull_light_tiles tiles;
    cull_light *cl;
    size_t cl_cap;
    vt_skytab sky;          /* the analytic sky's table */
    vt_shadow_gl *shadow;   /* the sun's cascades */
    vt_ibl ibl;             /* the image-based ambient (vt_brdf.h) */
    vt_brdf_gl brdf;        /* its textures */
    vt_glssao *ao;          /* the ambient occlusion pass (vt_ssao_gl.c) */
};

/* vs + fs + vt_brdf_fs (the shading model's functions) as one program. */
/* A shading program: vs and fs linked with the fragment-shader objects
 * that define what fs declares (the BRDF and image-based ambient, the
 * shadow cascades' lookup, the ambient occlusion's). */
enum { NSRC = 5 };
static int build(vt_gl *g, const char *vs, const char *fs, unsigned *out, char *err, size_t errlen)
{
    static const unsigned stage[NSRC] = {GL_VERTEX_SHADER, GL_FRAGMENT_SHADER, GL_FRAGMENT_SHADER, GL_FRAGMENT_SHADER,
                                           GL_FRAGMENT_SHADER};
    const char *src[NSRC] = {vs, fs, vt_brdf_fs, vt_shadow_gl_fs, vt_glssao_fs};
    unsigned sh[NSRC] = {0};
    int rc = 0;
    for (int k = 0; k < NSRC && !rc; k++) rc = vt_gl_shader_compile(g, stage[k], src[k], &sh[k], err, errlen);
    if (!rc) rc = vt_gl_program_link(g, sh, NSRC, out, err, errlen);
    for (int k = 0; k < NSRC; k++)
        if (sh[k]) glDeleteShader(sh[k]);
    if (!rc) {
        vt_shadow_gl_program_init(*out);
        vt_glssao_program_init(*out);
    }
    return rc;
}

int vt_gldraw_create(vt_gl *g, vt_gldraw **out, char *err, size_t errlen)
{
    if (!g || !out) return vp_errf(err, errlen, VT_ERR_INVALID, "missing argument");
    vt_gldraw *r = calloc(1, sizeof *r);
    if (!r) return vp_errf(err, errlen, VT_ERR_NOMEM, "out of memory");
    r->g = g;
    int rc = build(g, vt_gldraw_vs, vt_gldraw_fs, &r->prog, err, errlen);
    if (!rc && (rc = build(g, vt_gldraw_bg_vs, vt_gldraw_bg_fs, &r->bg, err, errlen)))
        glDeleteProgram(r->prog);
    if (!rc && (rc = vt_glssao_create(g, &r->ao, err, errlen))) {
        glDeleteProgram(r->prog);
        glDeleteProgram(r->bg);
    }
    if (!rc && (rc = vt_shadow_gl_create(&r->shadow))) {
        vt_glssao_destroy(r->ao);
        glDeleteProgram(r->prog);
        glDeleteProgram(r->bg);
    }
    if (rc) {
        free(r);
        return rc;
    }
    glGenVertexArrays(1, &r->vao);
    glGenTextures(5, r->tex);
    glGenBuffers(5, r->buf);
    glGenBuffers(1, &r->vbuf);
    glGenBuffers(1, &r->ibuf);
    glGenBuffers(1, &r->ebuf);
    glGenSamplers(4, r->samp);
    vt_brdf_gl_init(&r->brdf);
    glGetIntegerv(GL_MAX_TEXTURE_BUFFER_SIZE, &r->max_texels);
    if (r->max_texels <= 0) r->max_texels = 65536; /* the GL 3.3 minimum */
    for (int p = 0; p < 2; p++) {
        unsigned prog = p ? r->bg : r->prog;
        for (int u = 0; u < U_COUNT; u++) r->loc[p][u] = glGetUniformLocation(prog, u_names[u]);
        glUseProgram(prog); /* the samplers' units never change */
        glUniform1i(glGetUniformLocation(prog, "u_lights"), 0);
        glUniform1i(glGetUniformLocation(prog, "u_offset"), 1);
        glUniform1i(glGetUniformLocation(prog, "u_index"), 2);
        glUniform1i(glGetUniformLocation(prog, "u_mhead"), 3);
        glUniform1i(glGetUniformLocation(prog, "u_mfield"), 4);
        static const char *const slot[4] = {"u_tex0", "u_tex1", "u_tex2", "u_tex3"};
        for (int k = 0; k < 4; k++) glUniform1i(glGetUniformLocation(prog, slot[k]), 5 + k);
        glUniform1i(glGetUniformLocation(prog, "u_sky_tex"), 9);
    }
    *out = r;
    return 0;
}

void vt_gldraw_destroy(vt_gldraw *r)
{
    if (!r) return;
    vt_gl_target_destroy(r->target);
    vt_glssao_destroy(r->ao);
    vt_gltex_free(&r->tc);
    vt_shadow_gl_destroy(r->shadow);
    glDeleteSamplers(4, r->samp);
    glDeleteTextures(5, r->tex);
    vt_brdf_gl_free(&r->brdf);
    glDeleteBuffers(5, r->buf);
    glDeleteBuffers(1, &r->vbuf);
    glDeleteBuffers(1, &r->ibuf);
    glDeleteBuffers(1, &r->ebuf);
    glDeleteVertexArrays(1, &r->vao);
    glDeleteProgram(r->prog);
    glDeleteProgram(r->bg);
    cull_light_tiles_free(&r->tiles);
    vt_post_free(&r->post);
    free(r->pix);
    free(r->vx);
    free(r->el);
    free(r->iv);
    free(r->ld);
    free(r->mh);
    free(r->mf);
    free(r->md);
    free(r->key);
    free(r->gr);
    free(r->range);
    free(r->cl);
    free(r);
}

/* A buffer texture of n texels of `format` from data. */
static void tbo(unsigned tex, unsigned buf, GLenum format, const void *data, size_t bytes)
{
    glBindBuffer(GL_TEXTURE_BUFFER, buf);
    glBufferData(GL_TEXTURE_BUFFER, (GLsizeiptr)(bytes ? bytes : 16), data, GL_STREAM_DRAW);
    glBindTexture(GL_TEXTURE_BUFFER, tex);
    glTexBuffer(GL_TEXTURE_BUFFER, format, buf);
}

/* An instance's place in the draw order. */
typedef struct dkey {
    uint32_t mesh;
    uintptr_t mat;
    uint8_t masked, mirror;
    uint32_t i;
} dkey;

static int dkey_cmp(const void *pa, const void *pb)
{
    const dkey *a = pa, *b = pb;
    if (a->mesh != b->mesh) return a->mesh < b->mesh ? -1 : 1;
    if (a->mat != b->mat) return a->mat < b->mat ? -1 : 1;
    if (a->masked != b->masked) return a->masked < b->masked ? -1 : 1;
    if (a->mirror != b->mirror) return a->mirror < b->mirror ? -1 : 1;
    return a->i < b->i ? -1 : a->i > b->i;
}

static bool trs_mirrored(const vt_instance *in)
{
    return in->place == VT_PLACE_TRS && (in->scale[0] < 0) ^ (in->scale[1] < 0) ^ (in->scale[2] < 0);
}

/* One mesh's vertices as uploaded (VF floats each: position, normal, uv,
 * tangent): as given, indexed, where it has normals; else one vertex per
 * index with its face's normal (the model-space face normal: the shader
 * divides by the scale and rotates, which gives the placed face's normal,
 * M^-T n, the one vt_soft shades with). */
static void mesh_vertices(const vt_mesh *m, const mesh_draw *d, float *vx, uint32_t *el)
{
    for (uint32_t k = 0; k < d->nvx; k++) {
        uint32_t vi = d->nel ? k : m->idx[k];
        float *o = vx + VF * (size_t)k;
        memcpy(o, m->pos + 3 * (size_t)vi, 3 * sizeof *o);
        if (m->nrm) {
            memcpy(o + 3, m->nrm + 3 * (size_t)vi, 3 * sizeof *o);
        } else {
            const uint32_t *t = m->idx + 3 * (k / 3);
            const float *p0 = m->pos + 3 * t[0], *p1 = m->pos + 3 * t[1], *p2 = m->pos + 3 * t[2];
            float u[3] = {p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]};
            float w[3] = {p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2]};
            o[3] = u[1] * w[2] - u[2] * w[1];
            o[4] = u[2] * w[0] - u[0] * w[2];
            o[5] = u[0] * w[1] - u[1] * w[0];
        }
        o[6] = m->uv ? m->uv[2 * (size_t)vi] : 0;
        o[7] = m->uv ? m->uv[2 * (size_t)vi + 1] : 0;
        for (int a = 0; a < 4; a++) o[8 + a] = m->tan ? m->tan[4 * (size_t)vi + a] : 0;
    }
    if (d->nel) memcpy(el, m->idx, (size_t)m->ni * sizeof *el);
}

/* Uploads the frame's geometry once for both passes: every drawn mesh's
 * vertices into one buffer and its indices into another (mesh_vertices),
 * the instances in draw order (sorted by mesh, material, damage and
 * handedness: one draw per run) into a third (scale, camera-relative
 * shift, albedo, mask index or -1, rotation; the placement in double, as
 * vt_soft computes it), and the damaged instances' masks (vt_mask.h)
 * into two buffer textures. */
static int upload(vt_gldraw *r, const vt_frame *f, char *err, size_t errlen)
{
    const vt_mesh *meshes = f->meshes;
    const vt_instance *inst = f->inst;
    const uint32_t nmesh = f->nmesh, ninst = f->ninst;
    const double *origin = f->view->origin;
    size_t nvx = 0, nel = 0;
    if (!vp_grow((void **)&r->md, &r->md_cap, (size_t)nmesh + 1, sizeof *r->md) ||
        !vp_grow((void **)&r->iv, &r->iv_cap, ((size_t)ninst + 1) * IV, sizeof *r->iv) ||
        !vp_grow((void **)&r->key, &r->key_cap, (size_t)ninst + 1, sizeof *r->key) ||
        !vp_grow((void **)&r->gr, &r->gr_cap, (size_t)ninst + 1, sizeof *r->gr))
        return vp_errf(err, errlen, VT_ERR_NOMEM, "out of memory");
    memset(r->md, 0, (size_t)nmesh * sizeof *r->md);
    size_t nmask = 0, nfield = 0;
    dkey *key = r->key;
    for (uint32_t i = 0; i < ninst; i++) {
        r->md[inst[i].mesh].ninst++;
        const cull_dvol *dv = inst[i].dvol;
        bool damaged = vt_dvol_live(dv);
        key[i] = (dkey){.mesh = inst[i].mesh, .mat = (uintptr_t)inst[i].mat, .masked = damaged,
                        .mirror = trs_mirrored(&inst[i]), .i = i};
        if (!damaged) continue;
        nmask++;
        nfield += (size_t)dv->n[0] * dv->n[1] * dv->n[2];
    }
    if (nmask > (1u << 24) || nfield > (size_t)r->max_texels || nmask * MASK_TEXELS > (size_t)r->max_texels)
        return vp_errf(err, errlen, VT_ERR_RANGE,
                       "%zu damaged instances (%zu field samples) are past this GL's texture buffer limit (%d texels)",
                       nmask, nfield, r->max_texels);
    if (!vp_grow((void **)&r->mh, &r->mh_cap, (nmask + 1) * 4 * MASK_TEXELS, sizeof *r->mh) ||
        !vp_grow((void **)&r->mf, &r->mf_cap, nfield + 1, sizeof *r->mf))
        return vp_errf(err, errlen, VT_ERR_NOMEM, "out of memory");
    qsort(key, ninst, sizeof *key, dkey_cmp);
    r->ngr = 0;
    for (uint32_t k = 0; k < ninst; k++) {
        group *g = r->ngr ? &r->gr[r->ngr - 1] : NULL;
        if (!g || g->mesh != key[k].mesh || (uintptr_t)g->mat != key[k].mat || g->masked != key[k].masked ||
            g->mirror != key[k].mirror)
            r->gr[r->ngr++] = (group){.mesh = key[k].mesh, .ifirst = k, .mat = inst[key[k].i].mat,
                                      .masked = key[k].masked, .mirror = key[k].mirror};
        r->gr[r->ngr - 1].n++;
    }
    for (uint32_t mi = 0; mi < nmesh; mi++) {
        mesh_draw *d = &r->md[mi];
        d->vfirst = (uint32_t)nvx;
        d->efirst = (uint32_t)nel;
        bool indexed = meshes[mi].nrm != NULL;
        d->nvx = !d->ninst ? 0 : indexed ? meshes[mi].nv : meshes[mi].ni;
        d->nel = d->ninst && indexed ? meshes[mi].ni : 0;
        if (d->ninst) vt_mesh_bounds(&meshes[mi], d->b);
        nvx += d->nvx;
        nel += d->nel;
    }
    if (!vp_grow((void **)&r->vx, &r->vx_cap, (nvx + 1) * VF, sizeof *r->vx) ||
        !vp_grow((void **)&r->el, &r->el_cap, nel + 1, sizeof *r->el))
        return vp_errf(err, errlen, VT_ERR_NOMEM, "out of memory");
    for (uint32_t mi = 0; mi < nmesh; mi++)
        if (r->md[mi].nvx)
            mesh_vertices(&meshes[mi], &r->md[mi], r->vx + VF * (size_t)r->md[mi].vfirst, r->el + r->md[mi].efirst);
    nmask = nfield = 0;
    for (uint32_t k = 0; k < ninst; k++) {
        uint32_t i = key[k].i;
        vt_place pl;
        vt_instance_place(&inst[i], r->md[inst[i].mesh].b, origin, &pl);
        const cull_dvol *dv = inst[i].dvol;
        bool damaged = vt_dvol_live(dv);
        float *q = r->iv + IV * (size_t)k;
        for (int a = 0; a < 3; a++) {
            q[a] = (float)pl.s[a];
            q[3 + a] = (float)pl.t[a];
            q[6 + a] = inst[i].albedo[a];
        }
        q[9] = damaged ? (float)nmask : -1.0f;
        for (int a = 0; a < 4; a++) q[10 + a] = (float)pl.q[a];
        if (!damaged) continue;
        vt_mask m;
        vt_mask_make(dv, origin, &m);
        size_t ns = (size_t)dv->n[0] * dv->n[1] * dv->n[2];
        uint32_t bits[3] = {(uint32_t)nfield, m.n0, m.n01};
        float *h = r->mh + 4 * MASK_TEXELS * nmask++;
        memcpy(h, (float[20]){m.o[0], m.o[1], m.o[2], m.amp, m.is[0], m.is[1], m.is[2], m.ib, m.hi[0], m.hi[1],
                              m.hi[2], m.reach, m.cs[0], m.cs[1], m.cs[2], 0, 0, 0, 0, 0},
               20 * sizeof *h);
        memcpy(h + 16, bits, sizeof bits);
        memcpy(r->mf + nfield, dv->d, ns * sizeof *r->mf);
        nfield += ns;
    }
    glBindBuffer(GL_ARRAY_BUFFER, r->vbuf);
    glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)((nvx ? nvx : 1) * VF * sizeof *r->vx), r->vx, GL_STREAM_DRAW);
    glBindBuffer(GL_ARRAY_BUFFER, r->ibuf);
    glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)(((size_t)ninst + 1) * IV * sizeof *r->iv), r->iv, GL_STREAM_DRAW);
    glActiveTexture(GL_TEXTURE3);
    tbo(r->tex[3], r->buf[3], GL_RGBA32UI, r->mh, nmask * 4 * MASK_TEXELS * sizeof *r->mh);
    glActiveTexture(GL_TEXTURE4);
    tbo(r->tex[4], r->buf[4], GL_R32F, r->mf, nfield * sizeof *r->mf);
    glBindVertexArray(r->vao); /* the element buffer binding is the vertex array's */
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, r->ebuf);
    glBufferData(GL_ELEMENT_ARRAY_BUFFER, (GLsizeiptr)((nel + 1) * sizeof *r->el), r->el, GL_STREAM_DRAW);
    GLenum e = glGetError();
    return e == GL_NO_ERROR ? 0 : vp_errf(err, errlen, VT_ERR_GL, "upload: GL error 0x%x", e);
}

/* A material's uniforms and textures on program p (0 main, 1 background;
 * NULL: the default material of each instance's albedo). false: nothing
 * of it is drawn (a MASK material whose constant alpha is below its
 * cutoff), or a texture could not be made (*rc set). */
static bool set_material(vt_gldraw *r, int p, const vt_material *m, bool has_uv, bool has_t, int *rc, char *err,
                         size_t errlen)
{
    const int *L = r->loc[p];
    glUniform1i(L[u_mat_on], m != NULL);
    glUniform1i(L[u_has_uv], has_uv);
    glUniform1i(L[u_has_t], has_t);
    if (!m) {
        glUniform1i(L[u_tex_on], 0);
        glUniform1i(L[u_alpha_mask], 0);
        glUniform1i(L[u_two_sided], 0);
        return true;
    }
    bool test = m->alpha_mode == VT_ALPHA_MASK && m->tex[VT_SLOT_BASE].tex && has_uv;
    if (m->alpha_mode == VT_ALPHA_MASK && !test && m->base[3] < m->alpha_cutoff) return false;
    glUniform4fv(L[u_base], 1, m->base);
    glUniform2f(L[u_mr], m->metallic, m->roughness);
    glUniform3f(L[u_em], m->emissive[0] * m->emissive_strength, m->emissive[1] * m->emissive_strength,
                m->emissive[2] * m->emissive_strength);
    glUniform1f(L[u_nscale], m->normal_scale);
    glUniform1i(L[u_alpha_mask], test);
    glUniform1f(L[u_cutoff], m->alpha_cutoff);
    glUniform1i(L[u_two_sided], m->double_sided);
    int on = 0;
    float txm[16], txo[8];
    for (int k = 0; k < VT_SLOTS; k++) {
        const vt_texref *t = &m->tex[k];
        /* vt_tex_xform's matrix: columns of the unit vectors' images */
        float e[2][2], o0[2], zero[2] = {0, 0};
        vt_tex_xform(t, (const float[2]){1, 0}, true, e[0]);
        vt_tex_xform(t, (const float[2]){0, 1}, true, e[1]);
        vt_tex_xform(t, zero, false, o0);
        txm[4 * k] = e[0][0];
        txm[4 * k + 1] = e[1][0];
        txm[4 * k + 2] = e[0][1];
        txm[4 * k + 3] = e[1][1];
        txo[2 * k] = o0[0];
        txo[2 * k + 1] = o0[1];
        if (!t->tex || !has_uv) continue;
        glActiveTexture(GL_TEXTURE5 + (unsigned)k);
        if (!vt_gltex_get(&r->tc, t->tex, k == VT_SLOT_BASE || k == VT_SLOT_EMISSIVE)) {
            *rc = vp_errf(err, errlen, VT_ERR_GL, "texture %u (%ux%u) could not be uploaded", t->tex->id, t->tex->w,
                          t->tex->h);
            return false;
        }
        glBindSampler(5 + (unsigned)k, r->samp[k]);
        vt_gltex_sampler(r->samp[k], t);
        on |= 1 << k;
    }
    glUniform4fv(L[u_txm], 4, txm);
    glUniform2fv(L[u_txo], 4, txo);
    glUniform1i(L[u_tex_on], on);
    return true;
}

/* Draws what upload put in the buffers: per group one instanced draw,
 * back faces culled unless damaged (their insides show through their
 * holes) or double-sided; mirrored groups with clockwise front faces. */
static int draw(vt_gldraw *r, const vt_frame *f, char *err, size_t errlen)
{
    int rc = 0;
    for (size_t gi = 0; gi < r->ngr; gi++) {
        const group *g = &r->gr[gi];
        const mesh_draw *d = &r->md[g->mesh];
        const vt_mesh *m = &f->meshes[g->mesh];
        if (!set_material(r, 0, g->mat, m->uv != NULL, m->tan != NULL, &rc, err, errlen)) {
            if (rc) return rc;
            continue;
        }
        glBindBuffer(GL_ARRAY_BUFFER, r->vbuf);
        static const struct { unsigned loc, n, off; } va[4] = {{0, 3, 0}, {1, 3, 3}, {7, 2, 6}, {8, 4, 8}};
        for (int a = 0; a < 4; a++) {
            glEnableVertexAttribArray(va[a].loc);
            glVertexAttribPointer(va[a].loc, (GLint)va[a].n, GL_FLOAT, GL_FALSE, 4 * VF,
                                  (void *)(uintptr_t)(4 * VF * (size_t)d->vfirst + 4 * va[a].off));
            glVertexAttribDivisor(va[a].loc, 0);
        }
        glBindBuffer(GL_ARRAY_BUFFER, r->ibuf);
        static const struct { unsigned loc, n, off; } ia[5] = {{2, 3, 0}, {3, 3, 3}, {4, 3, 6}, {5, 1, 9}, {6, 4, 10}};
        for (int a = 0; a < 5; a++) {
            glEnableVertexAttribArray(ia[a].loc);
            glVertexAttribPointer(ia[a].loc, (GLint)ia[a].n, GL_FLOAT, GL_FALSE, 4 * IV,
                                  (void *)(uintptr_t)(4 * IV * (size_t)g->ifirst + 4 * ia[a].off));
            glVertexAttribDivisor(ia[a].loc, 1);
        }
        bool two = g->masked || (g->mat && g->mat->double_sided);
        if (two) glDisable(GL_CULL_FACE);
        glFrontFace(g->mirror ? GL_CW : GL_CCW);
        if (d->nel)
            glDrawElementsInstanced(GL_TRIANGLES, (GLsizei)d->nel, GL_UNSIGNED_INT,
                                    (void *)(uintptr_t)(4 * (size_t)d->efirst), (GLsizei)g->n);
        else
            glDrawArraysInstanced(GL_TRIANGLES, 0, (GLsizei)d->nvx, (GLsizei)g->n);
        if (two) glEnable(GL_CULL_FACE);
    }
    glFrontFace(GL_CCW);
    GLenum e = glGetError();
    return e == GL_NO_ERROR ? 0 : vp_errf(err, errlen, VT_ERR_GL, "draw: GL error 0x%x", e);
}

/* The environment's uniforms on program p (vt_penv: the same values the
 * software renderer shades with) and, on the background program, the
 * view's rows for its rays. */
static void set_env(vt_gldraw *r, int p, const vt_penv *pe, const cull_view_rows *vr, const vt_frame *f)
{
    const int *L = r->loc[p];
    glUniform1i(L[u_env_on], pe->on);
    glUniform1i(L[u_sun_on], pe->sun_on);
    glUniform1i(L[u_sky_mode], pe->sky_img ? 2 : 0);
    glUniform3fv(L[u_sun_dir], 1, pe->sun_dir);
    glUniform3fv(L[u_sun], 1, pe->sun);
    glUniform3fv(L[u_amb_up], 1, pe->amb_up);
    glUniform3fv(L[u_amb_down], 1, pe->amb_down);
    glUniform3fv(L[u_fog], 1, pe->fog);
    glUniform3fv(L[u_sky], 1, pe->sky_img ? pe->sky_mul : pe->sky);
    glUniform1f(L[u_fog_density], pe->fog_density);
    glUniform1f(L[u_fog_falloff], pe->fog_falloff);
    glUniform1f(L[u_fog_y0], pe->fog_y0);
    glUniform1f(L[u_sky_rot], pe->sky_rot);
    vt_shadow_gl_uniforms(r->shadow, p ? r->bg : r->prog);
    vt_brdf_gl_uniforms(p ? r->bg : r->prog, pe);
    if (!p) return;
    const double *rows[6] = {vr->x, vr->y, vr->z, vr->w, vr->nearfn, vr->d};
    for (int k = 0; k < 6; k++)
        glUniform4f(L[u_rx + k], (float)rows[k][0], (float)rows[k][1], (float)rows[k][2], (float)rows[k][3]);
    glUniform1i(L[u_ground], pe->ground);
    glUniform1i(L[u_depth_half], f->view->depth_mode == CULL_DEPTH_GL);
    glUniform1i(L[u_reversed], f->view->depth_mode == CULL_DEPTH_REVERSED);
    glUniform2f(L[u_size], (float)f->width, (float)f->height);
    glUniform1f(L[u_ground_y], pe->ground_y);
    glUniform3fv(L[u_ground_albedo], 1, pe->ground_albedo);
    glUniform2fv(L[u_ground_uv0], 1, pe->ground_uv0);
}

/* The background pass (pass 0: the ground's nearness; 1: the ground shaded
 * and the sky): depth-tested against the scene drawn before it, the sky
 * at the far plane passing only where nothing is. */
static int draw_bg(vt_gldraw *r, int pass, bool reversed, const vt_penv *pe, char *err, size_t errlen)
{
    int rc = 0;
    glUseProgram(r->bg);
    glUniform1i(r->loc[1][u_pass], pass);
    if (pe->ground && !set_material(r, 1, pe->ground_mat, pe->ground_mat != NULL, false, &rc, err, errlen) && rc)
        return rc;
    glDisable(GL_CULL_FACE);
    glDepthFunc(reversed ? GL_GEQUAL : GL_LEQUAL);
    glDrawArrays(GL_TRIANGLES, 0, 3);
    glEnable(GL_CULL_FACE);
    glUseProgram(r->prog);
    GLenum e = glGetError();
    return e == GL_NO_ERROR ? 0 : vp_errf(err, errlen, VT_ERR_GL, "background: GL error 0x%x", e);
}

int vt_gldraw_render(vt_gldraw *r, const cull_view *v, uint32_t width, uint32_t height, const vt_mesh *meshes,
                     uint32_t nmesh, const vt_instance *inst, uint32_t ninst, const vt_light *lights, uint32_t nl,
                     float *rgba, float *depth, size_t stride, vt_soft_stats *st, char *err, size_t errlen)
{
    vt_frame f = {.view = v, .width = width, .height = height, .meshes = meshes, .nmesh = nmesh, .inst = inst,
                  .ninst = ninst, .lights = lights, .nl = nl, .rgba = rgba, .depth = depth, .stride = stride};
    return vt_gldraw_draw(r, &f, st, err, errlen);
}

int vt_gldraw_draw(vt_gldraw *r, const vt_frame *f, vt_soft_stats *st, char *err, size_t errlen)
{
    if (st) memset(st, 0, sizeof *st);
    if (!r) return vp_errf(err, errlen, VT_ERR_INVALID, "missing argument");
    cull_view_rows vr;
    int rc = vt_picture_check(f, &vr, err, errlen);
    if (rc) return rc;
    const cull_view *v = f->view;
    const uint32_t width = f->width, height = f->height, nl = f->nl;
    const vt_light *lights = f->lights;
    float *rgba = f->rgba, *depth = f->depth;
    const size_t stride = f->stride;
    if ((rc = vt_gl_make_current(r->g, err, errlen))) return rc;
    bool reversed = v->depth_mode == CULL_DEPTH_REVERSED;
    if (v->depth_mode != CULL_DEPTH_GL) {
        if ((rc = vt_gl_clip_control(r->g, true, err, errlen))) return rc;
    } else if (vt_gl_get_info(r->g)->clip_control) {
        vt_gl_clip_control(r->g, false, NULL, 0);
    }
    if (!r->target) {
        vt_gl_target_desc td = {.color = VT_GL_RGBA32F};
        if ((rc = vt_gl_target_create(r->g, width, height, &td, &r->target, err, errlen))) return rc;
    } else if ((rc = vt_gl_target_resize(r->target, width, height, err, errlen))) {
        vt_gl_target_destroy(r->target); /* after a failed resize it must go */
        r->target = NULL;
        return rc;
    }
    size_t npx = (size_t)width * height;
    uint32_t tx = (width + TILE - 1) / TILE, ty = (height + TILE - 1) / TILE;
    if (!vp_grow((void **)&r->pix, &r->pix_cap, npx * 4, sizeof *r->pix) ||
        !vp_grow((void **)&r->range, &r->range_cap, (size_t)tx * ty, sizeof *r->range) ||
        !vp_grow((void **)&r->cl, &r->cl_cap, (size_t)nl + 1, sizeof *r->cl) ||
        !vp_grow((void **)&r->ld, &r->ld_cap, ((size_t)nl + 1) * 16, sizeof *r->ld))
        return vp_errf(err, errlen, VT_ERR_NOMEM, "out of memory");
    if ((rc = upload(r, f, err, errlen))) return rc;
    /* the sun's shadow cascades: vt_shadow.c's maps, uploaded */
    uint32_t stris = 0;
    uint64_t shadow_ns = 0;
    if ((rc = vt_shadow_gl_frame(r->shadow, f, &stris, &shadow_ns, err, errlen))) return rc;
    vt_penv pe;
    vt_penv_make(f->env, v->origin, &r->sky, &pe);
    if (pe.on && !(f->fx_off & VT_FX_IBL)) { /* remade only when the sky changed */
        vt_ibl_update(&r->ibl, &pe);
        pe.ibl = &r->ibl;
    }
    vt_brdf_gl_frame(&r->brdf, pe.ibl);
    const bool bg = pe.on; /* a background pass: the ground, the sky */
    vt_ssao_view sv = {.ok = false};
    if (bg && !(f->fx_off & VT_FX_SSAO)) vt_ssao_view_make(&vr, width, height, &sv);
    const bool pre = nl || sv.ok; /* pass 1: nearness for the light tiles and the ambient occlusion */
    float vp[16], d4[4];
    for (int i = 0; i < 16; i++) vp[i] = (float)v->clip[i];
    for (int i = 0; i < 4; i++) d4[i] = (float)vr.d[i];
    if (bg) {
        glUseProgram(r->bg);
        set_env(r, 1, &pe, &vr, f);
        if (pe.sky_img) { /* the environment map, or the analytic sky's table (id 0: this frame's) */
            glActiveTexture(GL_TEXTURE9);
            if (!vt_gltex_get(&r->tc, pe.sky_img, false))
                return vp_errf(err, errlen, VT_ERR_GL, "sky texture %u (%ux%u) could not be uploaded", pe.sky_img->id,
                               pe.sky_img->w, pe.sky_img->h);
        }
    }
    glUseProgram(r->prog);
    set_env(r, 0, &pe, &vr, f);
    glUniformMatrix4fv(r->loc[0][u_vp], 1, GL_FALSE, vp);
    glUniform4fv(r->loc[0][u_d], 1, d4);
    glBindVertexArray(r->vao);
    glEnable(GL_CULL_FACE);
    glCullFace(GL_BACK);
    glFrontFace(GL_CCW);
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(reversed ? GL_GREATER : GL_LESS);
    glDisable(GL_BLEND);
    const float clear[4] = {0, 0, 0, EMPTY};

    /* pass 1, only where there are lights to bin or ambient occlusion:
       nearness (and depth) */
    vt_gl_target_clear(r->target, clear, reversed ? 0.0f : 1.0f);
    if (pre) {
        glUniform1i(r->loc[0][u_pass], 0);
        if ((rc = draw(r, f, err, errlen))) return rc;
        if (bg && (rc = draw_bg(r, 0, reversed, &pe, err, errlen))) return rc;
        if (nl && (rc = vt_gl_readback(r->target, r->pix, NULL, NULL, err, errlen))) return rc;
        if (nl) vt_tile_ranges(r->pix + 3, 4, 4 * (size_t)width, width, height, r->range);
    }
    if (sv.ok && (rc = vt_glssao_run(r->ao, vt_gl_target_color_texture(r->target), &sv, err, errlen))) return rc;
    vt_glssao_use(r->bg, sv.ok);
    vt_glssao_use(r->prog, sv.ok);
    float *ld = r->ld;
    for (uint32_t i = 0; i < nl; i++) {
        vt_slight sl;
        vt_light_prepare(&lights[i], v->origin, &sl, &r->cl[i]);
        float *q = ld + 16 * (size_t)i; /* the shader's four vec4 */
        for (int a = 0; a < 3; a++) {
            q[a] = sl.p[a];
            q[4 + a] = sl.color[a];
            q[8 + a] = sl.dir[a];
        }
        q[3] = sl.range2;
        q[7] = sl.spot ? 1.0f : 0.0f;
        q[11] = sl.cos_outer;
        q[12] = sl.cos_inner;
        q[13] = q[14] = q[15] = 0;
    }
    int lrc = cull_lights_bin(v, width, height, r->cl, nl, nl ? (const float(*)[2])r->range : NULL, &r->tiles);
    if (lrc != CULL_OK)
        return vp_errf(err, errlen, lrc == CULL_ERR_NOMEM ? VT_ERR_NOMEM : VT_ERR_INVALID, "lights: %s",
                       cull_strerror(lrc));
    /* pass 2: shading with the tile lists */
    glActiveTexture(GL_TEXTURE0);
    tbo(r->tex[0], r->buf[0], GL_RGBA32F, ld, (size_t)nl * 16 * sizeof *ld);
    glActiveTexture(GL_TEXTURE1);
    tbo(r->tex[1], r->buf[1], GL_R32UI, r->tiles.offset, ((size_t)tx * ty + 1) * sizeof(uint32_t));
    glActiveTexture(GL_TEXTURE2);
    tbo(r->tex[2], r->buf[2], GL_R32UI, r->tiles.index, (size_t)r->tiles.offset[tx * ty] * sizeof(uint32_t));
    glUniform1i(r->loc[0][u_tiles_x], (int)tx);
    glUniform1i(r->loc[0][u_pass], 1);
    if (pre) {
        /* the depth of pass 1 stays: each pixel is shaded once, by the
           surface pass 1 found there (the same positions: invariant) */
        vt_gl_target_clear(r->target, clear, NAN); /* colour only */
        glDepthFunc(reversed ? GL_GEQUAL : GL_LEQUAL);
        glDepthMask(GL_FALSE);
    }
    rc = draw(r, f, err, errlen);
    if (!rc && bg) rc = draw_bg(r, 1, reversed, &pe, err, errlen);
    glDepthMask(GL_TRUE);
    vt_gltex_end_frame(&r->tc);
    if (rc) return rc;
    if ((rc = vt_gl_readback(r->target, r->pix, NULL, NULL, err, errlen))) return rc;
    /* alpha: nearness -> coverage, and depth as vt_soft gives it */
    const vt_depth_rule rule = vt_depth_rule_of(v, &vr);
    for (uint32_t y = 0; y < height; y++)
        for (uint32_t x = 0; x < width; x++) {
            const float *p = r->pix + 4 * ((size_t)y * width + x);
            float *c = rgba + 4 * ((size_t)y * stride + x), *dz = depth + (size_t)y * stride + x;
            float nz = p[3];
            /* a NaN nearness (a view term beyond float range: the matrix
               handed to GL holds an infinity) is no surface, as in
               vt_soft, where it never wins the depth test */
            if (nz == EMPTY || nz != nz) {
                /* the sky's colour with an environment */
                c[0] = bg ? p[0] : 0;
                c[1] = bg ? p[1] : 0;
                c[2] = bg ? p[2] : 0;
                c[3] = bg ? 1 : 0;
                *dz = INFINITY;
                continue;
            }
            c[0] = p[0];
            c[1] = p[1];
            c[2] = p[2];
            c[3] = 1;
            *dz = vt_depth_apply(rule, nz);
        }
    /* the software renderer's post passes, on one thread (no pool here) */
    struct timespec p0, p1;
    clock_gettime(CLOCK_MONOTONIC, &p0);
    float ev;
    if (vt_post_apply(&r->post, NULL, 1, f, &ev)) return vp_errf(err, errlen, VT_ERR_NOMEM, "out of memory");
    clock_gettime(CLOCK_MONOTONIC, &p1);
    /* last: the overlay over the read-back picture, the soft path's own pass */
    if ((rc = vt_overlay_draw(f, &vr, err, errlen))) return rc;
    if (st) {
        st->exposure_ev = ev;
        st->post_ns = (uint64_t)((p1.tv_sec - p0.tv_sec) * 1000000000ll + (p1.tv_nsec - p0.tv_nsec));
        st->lights_in_view = r->tiles.in_view;
        st->max_lights_per_tile = r->tiles.max_per_tile;
        st->threads = 1;
        st->shadow_ns = shadow_ns;
        st->shadow_triangles = stris;
    }
    return 0;
}
