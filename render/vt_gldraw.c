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
 */
#include "vt_gldraw.h"
#include "vt_picture.h"

#include <epoxy/gl.h>
#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define TILE VT_TILE
#define EMPTY VT_EMPTY
#define IV 10                /* floats an instance: scale, shift, albedo, mask */
#define MASK_TEXELS 5        /* RGBA texels a mask header */

/* One mesh's share of the frame's buffers. */
typedef struct mesh_draw {
    uint32_t vfirst, nvx;   /* its vertices (expanded per index without normals) */
    uint32_t efirst, nel;   /* its indices (0: drawn from the expanded vertices) */
    uint32_t ifirst, ninst; /* instances: the intact ones first */
    uint32_t nmasked;       /* the last nmasked are damaged: drawn two-sided */
    uint32_t pi, pm;        /* placing: intact and damaged instances so far */
    float b[6];             /* the mesh's bounds */
} mesh_draw;

struct vt_gldraw {
    vt_gl *g;
    unsigned prog, vao;
    int loc_vp, loc_d, loc_pass, loc_tiles_x;
    int max_texels;          /* GL_MAX_TEXTURE_BUFFER_SIZE */
    unsigned tex[5], buf[5]; /* buffer textures: lights, tile offsets, tile indices,
                                mask headers, mask fields */
    unsigned vbuf, ibuf, ebuf; /* this frame's vertices, instances and indices, all meshes */
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
    float (*range)[2];
    size_t range_cap;
    cull_light_tiles tiles;
    cull_light *cl;
    size_t cl_cap;
};

static const char *vs_src =
    "#version 330 core\n"
    "layout(location = 0) in vec3 a_pos;\n"
    "layout(location = 1) in vec3 a_nrm;\n"
    "layout(location = 2) in vec3 a_scale;\n"
    "layout(location = 3) in vec3 a_shift;\n"
    "layout(location = 4) in vec3 a_albedo;\n"
    "layout(location = 5) in float a_mask;\n"
    "uniform mat4 u_vp;\n"
    "uniform vec4 u_d;\n" /* nearness numerator row */
    "invariant gl_Position;\n" /* pass 2 tests against pass 1's depth */
    "invariant out vec3 v_p;\n"
    "out vec3 v_n;\n"
    "flat out vec3 v_albedo;\n"
    "flat out int v_mask;\n"
    "out float v_dp;\n"
    "void main() {\n"
    "  vec3 p = a_pos * a_scale + a_shift;\n"
    "  vec3 s = vec3(a_scale.x > 0.0 ? a_scale.x : 1.0, a_scale.y > 0.0 ? a_scale.y : 1.0,\n"
    "                a_scale.z > 0.0 ? a_scale.z : 1.0);\n"
    "  v_p = p;\n"
    "  v_n = a_nrm / s;\n"
    "  v_albedo = a_albedo;\n"
    "  v_mask = int(a_mask);\n"
    "  vec4 c = u_vp * vec4(p, 1.0);\n"
    "  v_dp = dot(u_d, vec4(p, 1.0));\n"
    "  gl_Position = c;\n"
    "}\n";

#define STR_(x) #x
#define STR(x) STR_(x)
static const char *fs_src =
    "#version 330 core\n"
    "#define VT_MASK_INTERIOR " STR(VT_MASK_INTERIOR) "\n"
    "#define VT_MASK_CHAR " STR(VT_MASK_CHAR) "\n"
    "invariant in vec3 v_p;\n"
    "in vec3 v_n;\n"
    "flat in vec3 v_albedo;\n"
    "flat in int v_mask;\n"
    "in float v_dp;\n"
    "uniform int u_pass;\n"
    "uniform int u_tiles_x;\n"
    "uniform samplerBuffer u_lights;\n"   /* 4 texels a light */
    "uniform usamplerBuffer u_offset;\n"
    "uniform usamplerBuffer u_index;\n"
    "uniform usamplerBuffer u_mhead;\n"  /* MASK_TEXELS texels a mask: float bits, then integers */
    "uniform samplerBuffer u_mfield;\n"
    "out vec4 o_color;\n"
    /* the destruction mask of vt_mask.h, operation for operation */
    "float lattice(ivec3 c) {\n"
    "  uvec3 u = uvec3(c);\n"
    "  uint h = u.x * 0x8da6b343u ^ u.y * 0xd8163841u ^ u.z * 0xcb1ab31fu;\n"
    "  h ^= h >> 16u; h *= 0x7feb352du; h ^= h >> 15u; h *= 0x846ca68bu; h ^= h >> 16u;\n"
    "  return float(h >> 8u) * (1.0 / 8388607.5) - 1.0;\n"
    "}\n"
    "float vnoise(vec3 p) {\n"
    "  vec3 f = floor(p);\n"
    "  ivec3 i = ivec3(f);\n"
    "  vec3 t = p - f;\n"
    "  t = t * t * (3.0 - 2.0 * t);\n"
    "  float c00 = lattice(i) + t.x * (lattice(i + ivec3(1, 0, 0)) - lattice(i));\n"
    "  float c10 = lattice(i + ivec3(0, 1, 0)) + t.x * (lattice(i + ivec3(1, 1, 0)) - lattice(i + ivec3(0, 1, 0)));\n"
    "  float c01 = lattice(i + ivec3(0, 0, 1)) + t.x * (lattice(i + ivec3(1, 0, 1)) - lattice(i + ivec3(0, 0, 1)));\n"
    "  float c11 = lattice(i + ivec3(0, 1, 1)) + t.x * (lattice(i + ivec3(1, 1, 1)) - lattice(i + ivec3(0, 1, 1)));\n"
    "  float c0 = c00 + t.y * (c10 - c00), c1 = c01 + t.y * (c11 - c01);\n"
    "  return c0 + t.z * (c1 - c0);\n"
    "}\n"
    "float field(int k) { return texelFetch(u_mfield, k).r; }\n"
    "float mask_eval(int m, vec3 p, out float ib) {\n"
    "  vec4 h0 = uintBitsToFloat(texelFetch(u_mhead, 5 * m)), h1 = uintBitsToFloat(texelFetch(u_mhead, 5 * m + 1));\n"
    "  vec4 h2 = uintBitsToFloat(texelFetch(u_mhead, 5 * m + 2)), h3 = uintBitsToFloat(texelFetch(u_mhead, 5 * m + 3));\n"
    "  uvec4 q = texelFetch(u_mhead, 5 * m + 4);\n"
    "  ib = h1.w;\n"
    "  vec3 u = clamp((p - h0.xyz) * h1.xyz, vec3(0.0), h2.xyz);\n"
    "  vec3 fl = min(floor(u), h2.xyz - 1.0);\n"
    "  vec3 t = u - fl;\n"
    "  int sy = int(q.y), sz = int(q.z);\n"
    "  int b = int(q.x) + int(fl.x) + int(fl.y) * sy + int(fl.z) * sz;\n"
    "  float c00 = field(b) + t.x * (field(b + 1) - field(b));\n"
    "  float c10 = field(b + sy) + t.x * (field(b + sy + 1) - field(b + sy));\n"
    "  float c01 = field(b + sz) + t.x * (field(b + sz + 1) - field(b + sz));\n"
    "  float c11 = field(b + sz + sy) + t.x * (field(b + sz + sy + 1) - field(b + sz + sy));\n"
    "  float c0 = c00 + t.y * (c10 - c00), c1 = c01 + t.y * (c11 - c01);\n"
    "  float f = c0 + t.z * (c1 - c0);\n"
    "  if (f < -h0.w || f >= h2.w) return f;\n"
    "  vec3 c = u * h3.xyz;\n"
    "  return f + h0.w * (0.6 * vnoise(c) + 0.4 * vnoise(2.0 * c + 17.0));\n"
    "}\n"
    "void main() {\n"
    "  float v_near = v_dp * gl_FragCoord.w;\n"
    "  vec3 albedo = v_albedo, nv = v_n;\n"
    "  if (v_mask >= 0) {\n"
    "    float ib, e = mask_eval(v_mask, v_p, ib);\n"
    "    if (e < 0.0) discard;\n"
    "    if (u_pass == 0) { o_color = vec4(0.0, 0.0, 0.0, v_near); return; }\n"
    "    float k = e * ib;\n"
    "    if (!gl_FrontFacing) { nv = -nv; albedo *= VT_MASK_INTERIOR; }\n"
    "    if (k < 1.0) {\n"
    "      k = max(k, 0.0);\n"
    "      albedo *= VT_MASK_CHAR + (1.0 - VT_MASK_CHAR) * (k * k * (3.0 - 2.0 * k));\n"
    "    }\n"
    "  }\n"
    "  if (u_pass == 0) { o_color = vec4(0.0, 0.0, 0.0, v_near); return; }\n"
    "  vec3 n = normalize(nv);\n"
    "  vec3 vd = normalize(-v_p);\n"
    "  vec3 c = 0.03 * albedo;\n"
    "  ivec2 tp = ivec2(gl_FragCoord.xy) / 16;\n"
    "  int t = tp.y * u_tiles_x + tp.x;\n"
    "  int k0 = int(texelFetch(u_offset, t).r), k1 = int(texelFetch(u_offset, t + 1).r);\n"
    "  for (int k = k0; k < k1; k++) {\n"
    "    int li = int(texelFetch(u_index, k).r) * 4;\n"
    "    vec4 q0 = texelFetch(u_lights, li), q1 = texelFetch(u_lights, li + 1);\n"
    "    vec4 q2 = texelFetch(u_lights, li + 2), q3 = texelFetch(u_lights, li + 3);\n"
    "    vec3 l = q0.xyz - v_p;\n"
    "    float d2 = dot(l, l);\n"
    "    if (d2 >= q0.w || d2 <= 0.0) continue;\n"
    "    l *= inversesqrt(d2);\n"
    "    float ndl = dot(n, l);\n"
    "    if (ndl <= 0.0) continue;\n"
    "    float qq = d2 / q0.w, win = 1.0 - qq * qq;\n"
    "    float att = win * win / (d2 + 0.01);\n"
    "    if (q1.w > 0.5) {\n"
    "      float cd = -dot(l, q2.xyz);\n"
    "      float s = clamp((cd - q2.w) / (q3.x - q2.w), 0.0, 1.0);\n"
    "      att *= s * s * (3.0 - 2.0 * s);\n"
    "    }\n"
    "    if (att <= 0.0) continue;\n"
    "    vec3 h = l + vd;\n"
    "    float hl = length(h);\n"
    "    float ndh = hl > 0.0 ? max(dot(n, h) / hl, 0.0) : 0.0;\n"
    "    float spec = 0.04 * 40.0 / (8.0 * 3.14159265) * pow(ndh, 32.0);\n"
    "    c += q1.xyz * att * ndl * (albedo / 3.14159265 + spec);\n"
    "  }\n"
    "  o_color = vec4(c, v_near);\n"
    "}\n";

int vt_gldraw_create(vt_gl *g, vt_gldraw **out, char *err, size_t errlen)
{
    if (!g || !out) return vp_errf(err, errlen, VT_ERR_INVALID, "missing argument");
    vt_gldraw *r = calloc(1, sizeof *r);
    if (!r) return vp_errf(err, errlen, VT_ERR_NOMEM, "out of memory");
    r->g = g;
    int rc = vt_gl_program_build(g, vs_src, fs_src, &r->prog, err, errlen);
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
    glGetIntegerv(GL_MAX_TEXTURE_BUFFER_SIZE, &r->max_texels);
    if (r->max_texels <= 0) r->max_texels = 65536; /* the GL 3.3 minimum */
    r->loc_vp = glGetUniformLocation(r->prog, "u_vp");
    r->loc_d = glGetUniformLocation(r->prog, "u_d");
    r->loc_pass = glGetUniformLocation(r->prog, "u_pass");
    r->loc_tiles_x = glGetUniformLocation(r->prog, "u_tiles_x");
    glUseProgram(r->prog); /* the samplers' units never change */
    glUniform1i(glGetUniformLocation(r->prog, "u_lights"), 0);
    glUniform1i(glGetUniformLocation(r->prog, "u_offset"), 1);
    glUniform1i(glGetUniformLocation(r->prog, "u_index"), 2);
    glUniform1i(glGetUniformLocation(r->prog, "u_mhead"), 3);
    glUniform1i(glGetUniformLocation(r->prog, "u_mfield"), 4);
    *out = r;
    return 0;
}

void vt_gldraw_destroy(vt_gldraw *r)
{
    if (!r) return;
    vt_gl_target_destroy(r->target);
    glDeleteTextures(5, r->tex);
    glDeleteBuffers(5, r->buf);
    glDeleteBuffers(1, &r->vbuf);
    glDeleteBuffers(1, &r->ibuf);
    glDeleteBuffers(1, &r->ebuf);
    glDeleteVertexArrays(1, &r->vao);
    glDeleteProgram(r->prog);
    cull_light_tiles_free(&r->tiles);
    free(r->pix);
    free(r->vx);
    free(r->el);
    free(r->iv);
    free(r->ld);
    free(r->mh);
    free(r->mf);
    free(r->md);
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

/* Uploads the frame's geometry once for both passes: every drawn mesh's
 * vertices (positions and normals) into one buffer and its indices into
 * another (a mesh without normals instead gets one vertex per index with
 * its face's normal, the one vt_soft shades with), and the instances,
 * grouped by mesh, intact ones first (scale, camera-relative shift,
 * albedo, mask index or -1; the transform in double, as vt_soft computes
 * it), into a third; the damaged instances' masks (vt_mask.h) into two
 * buffer textures. */
static int upload(vt_gldraw *r, const vt_mesh *meshes, uint32_t nmesh, const vt_instance *inst, uint32_t ninst,
                  const double origin[3], char *err, size_t errlen)
{
    size_t nvx = 0, nel = 0;
    if (!vp_grow((void **)&r->md, &r->md_cap, (size_t)nmesh + 1, sizeof *r->md) ||
        !vp_grow((void **)&r->iv, &r->iv_cap, ((size_t)ninst + 1) * IV, sizeof *r->iv))
        return vp_errf(err, errlen, VT_ERR_NOMEM, "out of memory");
    memset(r->md, 0, (size_t)nmesh * sizeof *r->md);
    size_t nmask = 0, nfield = 0;
    for (uint32_t i = 0; i < ninst; i++) {
        r->md[inst[i].mesh].ninst++;
        const cull_dvol *dv = inst[i].dvol;
        if (!vt_dvol_live(dv)) continue;
        r->md[inst[i].mesh].nmasked++;
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
    for (uint32_t mi = 0, first = 0; mi < nmesh; mi++) {
        mesh_draw *d = &r->md[mi];
        d->ifirst = first;
        first += d->ninst;
        d->vfirst = (uint32_t)nvx;
        d->efirst = (uint32_t)nel;
        bool indexed = meshes[mi].nrm != NULL;
        d->nvx = !d->ninst ? 0 : indexed ? meshes[mi].nv : meshes[mi].ni;
        d->nel = d->ninst && indexed ? meshes[mi].ni : 0;
        if (d->ninst) vt_mesh_bounds(&meshes[mi], d->b);
        nvx += d->nvx;
        nel += d->nel;
        d->pi = d->pm = 0;
    }
    if (!vp_grow((void **)&r->vx, &r->vx_cap, (nvx + 1) * 6, sizeof *r->vx) ||
        !vp_grow((void **)&r->el, &r->el_cap, nel + 1, sizeof *r->el))
        return vp_errf(err, errlen, VT_ERR_NOMEM, "out of memory");
    for (uint32_t mi = 0; mi < nmesh; mi++) {
        const vt_mesh *m = &meshes[mi];
        if (!r->md[mi].nvx) continue;
        float *vx = r->vx + 6 * (size_t)r->md[mi].vfirst;
        if (r->md[mi].nel) { /* as given: each vertex once, the indices beside */
            for (uint32_t k = 0; k < m->nv; k++) {
                memcpy(vx + 6 * (size_t)k, m->pos + 3 * (size_t)k, 3 * sizeof *vx);
                memcpy(vx + 6 * (size_t)k + 3, m->nrm + 3 * (size_t)k, 3 * sizeof *vx);
            }
            memcpy(r->el + r->md[mi].efirst, m->idx, (size_t)m->ni * sizeof *r->el);
            continue;
        }
        for (uint32_t t = 0; t < m->ni / 3; t++) {
            const float *p0 = m->pos + 3 * m->idx[3 * t], *p1 = m->pos + 3 * m->idx[3 * t + 1],
                        *p2 = m->pos + 3 * m->idx[3 * t + 2];
            float fn[3] = {0, 0, 0};
            if (!m->nrm) {
                /* the model-space face normal: the shader divides by the
                   scale, which gives the stretched face's normal (M^-T n),
                   the one vt_soft shades with */
                float u[3] = {p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]};
                float w[3] = {p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2]};
                fn[0] = u[1] * w[2] - u[2] * w[1];
                fn[1] = u[2] * w[0] - u[0] * w[2];
                fn[2] = u[0] * w[1] - u[1] * w[0];
            }
            for (int k = 0; k < 3; k++) {
                uint32_t vi = m->idx[3 * t + k];
                float *o = vx + 6 * ((size_t)3 * t + k);
                memcpy(o, m->pos + 3 * vi, 3 * sizeof *o);
                if (m->nrm) memcpy(o + 3, m->nrm + 3 * vi, 3 * sizeof *o);
                else memcpy(o + 3, fn, sizeof fn);
            }
        }
    }
    nmask = nfield = 0;
    for (uint32_t i = 0; i < ninst; i++) {
        mesh_draw *d = &r->md[inst[i].mesh];
        double scale[3], shift[3];
        vt_instance_xform(&inst[i], d->b, origin, scale, shift);
        const cull_dvol *dv = inst[i].dvol;
        bool damaged = vt_dvol_live(dv);
        size_t at = damaged ? d->ifirst + (d->ninst - d->nmasked) + d->pm++ : d->ifirst + d->pi++;
        float *q = r->iv + IV * at;
        for (int a = 0; a < 3; a++) {
            q[a] = (float)scale[a];
            q[3 + a] = (float)shift[a];
            q[6 + a] = inst[i].albedo[a];
        }
        q[9] = damaged ? (float)nmask : -1.0f;
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
    glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)((nvx ? nvx : 1) * 6 * sizeof *r->vx), r->vx, GL_STREAM_DRAW);
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

/* Draws what upload put in the buffers: per mesh, one instanced draw of
 * its intact instances (back faces culled) and one of its damaged ones
 * (two-sided: their insides show through their holes). */
static int draw(const vt_gldraw *r, uint32_t nmesh, char *err, size_t errlen)
{
    for (uint32_t mi = 0; mi < nmesh; mi++) {
        const mesh_draw *d = &r->md[mi];
        if (!d->ninst) continue;
        glBindBuffer(GL_ARRAY_BUFFER, r->vbuf);
        for (unsigned a = 0; a < 2; a++) {
            glEnableVertexAttribArray(a);
            glVertexAttribPointer(a, 3, GL_FLOAT, GL_FALSE, 24, (void *)(uintptr_t)(24 * (size_t)d->vfirst + 12 * a));
            glVertexAttribDivisor(a, 0);
        }
        uint32_t part[2][2] = {{d->ifirst, d->ninst - d->nmasked}, {d->ifirst + d->ninst - d->nmasked, d->nmasked}};
        for (int p = 0; p < 2; p++) {
            if (!part[p][1]) continue;
            if (p) glDisable(GL_CULL_FACE);
            glBindBuffer(GL_ARRAY_BUFFER, r->ibuf);
            for (unsigned a = 0; a < 4; a++) {
                glEnableVertexAttribArray(2 + a);
                glVertexAttribPointer(2 + a, a < 3 ? 3 : 1, GL_FLOAT, GL_FALSE, 4 * IV,
                                      (void *)(uintptr_t)(4 * IV * (size_t)part[p][0] + 12 * a));
                glVertexAttribDivisor(2 + a, 1);
            }
            if (d->nel)
                glDrawElementsInstanced(GL_TRIANGLES, (GLsizei)d->nel, GL_UNSIGNED_INT,
                                        (void *)(uintptr_t)(4 * (size_t)d->efirst), (GLsizei)part[p][1]);
            else
                glDrawArraysInstanced(GL_TRIANGLES, 0, (GLsizei)d->nvx, (GLsizei)part[p][1]);
            if (p) glEnable(GL_CULL_FACE);
        }
    }
    GLenum e = glGetError();
    return e == GL_NO_ERROR ? 0 : vp_errf(err, errlen, VT_ERR_GL, "draw: GL error 0x%x", e);
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
    const uint32_t width = f->width, height = f->height, nmesh = f->nmesh, ninst = f->ninst, nl = f->nl;
    const vt_mesh *meshes = f->meshes;
    const vt_instance *inst = f->inst;
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
    if ((rc = upload(r, meshes, nmesh, inst, ninst, v->origin, err, errlen))) return rc;
    float vp[16], d4[4];
    for (int i = 0; i < 16; i++) vp[i] = (float)v->clip[i];
    for (int i = 0; i < 4; i++) d4[i] = (float)vr.d[i];
    glUseProgram(r->prog);
    glUniformMatrix4fv(r->loc_vp, 1, GL_FALSE, vp);
    glUniform4fv(r->loc_d, 1, d4);
    glBindVertexArray(r->vao);
    glEnable(GL_CULL_FACE);
    glCullFace(GL_BACK);
    glFrontFace(GL_CCW);
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(reversed ? GL_GREATER : GL_LESS);
    glDisable(GL_BLEND);
    const float clear[4] = {0, 0, 0, EMPTY};

    /* pass 1, only where there are lights to bin: nearness (and depth) */
    vt_gl_target_clear(r->target, clear, reversed ? 0.0f : 1.0f);
    if (nl) {
        glUniform1i(r->loc_pass, 0);
        if ((rc = draw(r, nmesh, err, errlen))) return rc;
        if ((rc = vt_gl_readback(r->target, r->pix, NULL, NULL, err, errlen))) return rc;
        vt_tile_ranges(r->pix + 3, 4, 4 * (size_t)width, width, height, r->range);
    }
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
    glUniform1i(r->loc_tiles_x, (int)tx);
    glUniform1i(r->loc_pass, 1);
    if (nl) {
        /* the depth of pass 1 stays: each pixel is shaded once, by the
           surface pass 1 found there (the same positions: invariant) */
        vt_gl_target_clear(r->target, clear, NAN); /* colour only */
        glDepthFunc(reversed ? GL_GEQUAL : GL_LEQUAL);
        glDepthMask(GL_FALSE);
    }
    rc = draw(r, nmesh, err, errlen);
    glDepthMask(GL_TRUE);
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
                c[0] = c[1] = c[2] = c[3] = 0;
                *dz = INFINITY;
                continue;
            }
            c[0] = p[0];
            c[1] = p[1];
            c[2] = p[2];
            c[3] = 1;
            *dz = vt_depth_apply(rule, nz);
        }
    if (st) {
        st->lights_in_view = r->tiles.in_view;
        st->max_lights_per_tile = r->tiles.max_per_tile;
        st->threads = 1;
    }
    return 0;
}
