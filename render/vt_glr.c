/*
 * vt_glr.c — the OpenGL renderer (see vt_glr.h).
 *
 * Per frame: one vertex buffer per mesh (positions and normals; a mesh
 * without normals is expanded to flat-shaded triangles, as the software
 * path shades it), one instance buffer per mesh (the mesh's bounds onto
 * the instance's box as a scale and a camera-relative shift, computed in
 * double as vt_soft does, and the albedo), a float view-projection.
 * Pass 1 draws nearness (d / w, interpolated without perspective: it is
 * affine in screen space) into alpha; the per-tile nearness ranges give
 * cull_lights_bin its depth planes; the lights and lists go to buffer
 * textures; pass 2 shades. Colour alpha carries nearness on the way out
 * and is turned into coverage and depth on the CPU, as vt_soft does.
 */
#include "vt_glr.h"

#include <epoxy/gl.h>
#include <errno.h>
#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define TILE CULL_LIGHT_TILE
#define EMPTY (-FLT_MAX)

struct vt_glr {
    vt_gl *g;
    unsigned prog, vao;
    unsigned tex[3], buf[3]; /* buffer textures: lights, tile offsets, tile indices */
    vt_gl_target *target;
    uint32_t tw, th;
    float *pix;              /* readback */
    size_t pix_cap;
    cull_light_tiles tiles;
    cull_light *cl;
    size_t cl_cap;
};

static int fail(char *err, size_t errlen, int code, const char *fmt, ...)
{
    if (err && errlen) {
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(err, errlen, fmt, ap);
        va_end(ap);
    }
    return code;
}

static const char *vs_src =
    "#version 330 core\n"
    "layout(location = 0) in vec3 a_pos;\n"
    "layout(location = 1) in vec3 a_nrm;\n"
    "layout(location = 2) in vec3 a_scale;\n"
    "layout(location = 3) in vec3 a_shift;\n"
    "layout(location = 4) in vec3 a_albedo;\n"
    "uniform mat4 u_vp;\n"
    "uniform vec4 u_d;\n" /* nearness numerator row */
    "invariant gl_Position;\n" /* pass 2 tests against pass 1's depth */
    "out vec3 v_p;\n"
    "out vec3 v_n;\n"
    "flat out vec3 v_albedo;\n"
    "noperspective out float v_near;\n"
    "void main() {\n"
    "  vec3 p = a_pos * a_scale + a_shift;\n"
    "  vec3 s = vec3(a_scale.x > 0.0 ? a_scale.x : 1.0, a_scale.y > 0.0 ? a_scale.y : 1.0,\n"
    "                a_scale.z > 0.0 ? a_scale.z : 1.0);\n"
    "  v_p = p;\n"
    "  v_n = a_nrm / s;\n"
    "  v_albedo = a_albedo;\n"
    "  vec4 c = u_vp * vec4(p, 1.0);\n"
    "  v_near = dot(u_d, vec4(p, 1.0)) / c.w;\n"
    "  gl_Position = c;\n"
    "}\n";

static const char *fs_src =
    "#version 330 core\n"
    "in vec3 v_p;\n"
    "in vec3 v_n;\n"
    "flat in vec3 v_albedo;\n"
    "noperspective in float v_near;\n"
    "uniform int u_pass;\n"
    "uniform int u_tiles_x;\n"
    "uniform samplerBuffer u_lights;\n"   /* 4 texels a light */
    "uniform usamplerBuffer u_offset;\n"
    "uniform usamplerBuffer u_index;\n"
    "out vec4 o_color;\n"
    "void main() {\n"
    "  if (u_pass == 0) { o_color = vec4(0.0, 0.0, 0.0, v_near); return; }\n"
    "  vec3 n = normalize(v_n);\n"
    "  vec3 vd = normalize(-v_p);\n"
    "  vec3 c = 0.03 * v_albedo;\n"
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
    "    c += q1.xyz * att * ndl * (v_albedo / 3.14159265 + spec);\n"
    "  }\n"
    "  o_color = vec4(c, v_near);\n"
    "}\n";

int vt_glr_create(vt_gl *g, vt_glr **out, char *err, size_t errlen)
{
    if (!g || !out) return fail(err, errlen, VT_GL_ERR_INVALID, "missing argument");
    vt_glr *r = calloc(1, sizeof *r);
    if (!r) return fail(err, errlen, VT_GL_ERR_NOMEM, "out of memory");
    r->g = g;
    int rc = vt_gl_program_build(g, vs_src, fs_src, &r->prog, err, errlen);
    if (rc) {
        free(r);
        return rc;
    }
    glGenVertexArrays(1, &r->vao);
    glGenTextures(3, r->tex);
    glGenBuffers(3, r->buf);
    *out = r;
    return 0;
}

void vt_glr_destroy(vt_glr *r)
{
    if (!r) return;
    vt_gl_target_destroy(r->target);
    glDeleteTextures(3, r->tex);
    glDeleteBuffers(3, r->buf);
    glDeleteVertexArrays(1, &r->vao);
    glDeleteProgram(r->prog);
    cull_light_tiles_free(&r->tiles);
    free(r->pix);
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

/* Draws every instance, mesh by mesh. */
static int draw_all(const vt_mesh *meshes, uint32_t nmesh, const vt_instance *inst, uint32_t ninst,
                    const double origin[3], char *err, size_t errlen)
{
    unsigned vb[2];
    glGenBuffers(2, vb);
    float *iv = malloc(((size_t)ninst + 1) * 9 * sizeof *iv);
    if (!iv) {
        glDeleteBuffers(2, vb);
        return fail(err, errlen, -ENOMEM, "out of memory");
    }
    int rc = 0;
    for (uint32_t mi = 0; mi < nmesh && !rc; mi++) {
        const vt_mesh *m = &meshes[mi];
        /* the mesh's bounds, and its instances' scale and shift (double) */
        float lo[3] = {FLT_MAX, FLT_MAX, FLT_MAX}, hi[3] = {-FLT_MAX, -FLT_MAX, -FLT_MAX};
        for (uint32_t k = 0; k < m->nv; k++)
            for (int a = 0; a < 3; a++) {
                lo[a] = fminf(lo[a], m->pos[3 * k + a]);
                hi[a] = fmaxf(hi[a], m->pos[3 * k + a]);
            }
        uint32_t n = 0;
        for (uint32_t i = 0; i < ninst; i++) {
            if (inst[i].mesh != mi) continue;
            float *q = iv + 9 * (size_t)n++;
            for (int a = 0; a < 3; a++) {
                double ext = (double)hi[a] - lo[a];
                double scale = ext > 0 ? (inst[i].bmax[a] - inst[i].bmin[a]) / ext : 0;
                double shift = ext > 0 ? inst[i].bmin[a] - origin[a] - lo[a] * scale
                                       : 0.5 * (inst[i].bmin[a] + inst[i].bmax[a]) - origin[a];
                q[a] = (float)scale;
                q[3 + a] = (float)shift;
                q[6 + a] = inst[i].albedo[a];
            }
        }
        if (!n) continue;
        /* vertices: positions and normals per index, so a mesh without
           normals gets its faces' (what vt_soft shades with) */
        size_t nvx = m->ni;
        float *vx = malloc(nvx * 6 * sizeof *vx);
        if (!vx) {
            rc = fail(err, errlen, -ENOMEM, "out of memory");
            break;
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
        glBindBuffer(GL_ARRAY_BUFFER, vb[0]);
        glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)(nvx * 6 * sizeof *vx), vx, GL_STREAM_DRAW);
        free(vx);
        glEnableVertexAttribArray(0);
        glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 24, (void *)0);
        glVertexAttribDivisor(0, 0);
        glEnableVertexAttribArray(1);
        glVertexAttribPointer(1, 3, GL_FLOAT, GL_FALSE, 24, (void *)12);
        glVertexAttribDivisor(1, 0);
        glBindBuffer(GL_ARRAY_BUFFER, vb[1]);
        glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)((size_t)n * 9 * sizeof *iv), iv, GL_STREAM_DRAW);
        for (int a = 0; a < 3; a++) {
            glEnableVertexAttribArray(2 + (unsigned)a);
            glVertexAttribPointer(2 + (unsigned)a, 3, GL_FLOAT, GL_FALSE, 36, (void *)(uintptr_t)(12 * a));
            glVertexAttribDivisor(2 + (unsigned)a, 1);
        }
        glDrawArraysInstanced(GL_TRIANGLES, 0, (GLsizei)nvx, (GLsizei)n);
    }
    free(iv);
    glDeleteBuffers(2, vb);
    GLenum e = glGetError();
    if (!rc && e != GL_NO_ERROR) rc = fail(err, errlen, VT_GL_ERR_GL, "draw: GL error 0x%x", e);
    return rc;
}

int vt_glr_render(vt_glr *r, const cull_view *v, uint32_t width, uint32_t height, const vt_mesh *meshes,
                  uint32_t nmesh, const vt_instance *inst, uint32_t ninst, const vt_light *lights, uint32_t nl,
                  float *rgba, float *depth, size_t stride, vt_soft_stats *st, char *err, size_t errlen)
{
    if (st) memset(st, 0, sizeof *st);
    if (!r || !v || !rgba || !depth || (ninst && (!inst || !meshes)) || (nl && !lights))
        return fail(err, errlen, -EINVAL, "missing argument");
    if (width < 1 || height < 1 || width > 16384 || height > 16384 || stride < width)
        return fail(err, errlen, -EINVAL, "size %ux%u (stride %zu) outside 1..16384", width, height, stride);
    for (uint32_t i = 0; i < ninst; i++)
        if (inst[i].mesh >= nmesh) return fail(err, errlen, -EINVAL, "instance %u: no mesh %u", i, inst[i].mesh);
    int rc = vt_gl_make_current(r->g, err, errlen);
    if (rc) return rc;
    cull_view_rows vr;
    cull_view_rows_get(v, &vr);
    bool reversed = v->depth_mode == CULL_DEPTH_REVERSED;
    if (v->depth_mode != CULL_DEPTH_GL) {
        if ((rc = vt_gl_clip_control(r->g, true, err, errlen))) return rc;
    } else if (vt_gl_get_info(r->g)->clip_control) {
        vt_gl_clip_control(r->g, false, NULL, 0);
    }
    if (!r->target || r->tw != width || r->th != height) {
        vt_gl_target_destroy(r->target);
        r->target = NULL;
        vt_gl_target_desc td = {.color = VT_GL_RGBA32F};
        if ((rc = vt_gl_target_create(r->g, width, height, &td, &r->target, err, errlen))) return rc;
        r->tw = width;
        r->th = height;
    }
    size_t npx = (size_t)width * height;
    if (npx * 4 > r->pix_cap) {
        float *p = realloc(r->pix, npx * 4 * sizeof *p);
        if (!p) return fail(err, errlen, -ENOMEM, "out of memory");
        r->pix = p;
        r->pix_cap = npx * 4;
    }
    float vp[16], d4[4];
    for (int i = 0; i < 16; i++) vp[i] = (float)v->clip[i];
    for (int i = 0; i < 4; i++) d4[i] = (float)vr.d[i];
    glUseProgram(r->prog);
    glUniformMatrix4fv(glGetUniformLocation(r->prog, "u_vp"), 1, GL_FALSE, vp);
    glUniform4fv(glGetUniformLocation(r->prog, "u_d"), 1, d4);
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
    uint32_t tx = (width + TILE - 1) / TILE, ty = (height + TILE - 1) / TILE;
    float(*range)[2] = NULL;
    if (nl) {
        glUniform1i(glGetUniformLocation(r->prog, "u_pass"), 0);
        if ((rc = draw_all(meshes, nmesh, inst, ninst, v->origin, err, errlen))) return rc;
        if ((rc = vt_gl_readback(r->target, r->pix, NULL, NULL, err, errlen))) return rc;
        range = malloc((size_t)tx * ty * sizeof *range);
        if (!range) return fail(err, errlen, -ENOMEM, "out of memory");
        for (size_t t = 0; t < (size_t)tx * ty; t++) {
            range[t][0] = -FLT_MAX;
            range[t][1] = FLT_MAX;
        }
        for (uint32_t y = 0; y < height; y++)
            for (uint32_t x = 0; x < width; x++) {
                float z = r->pix[4 * ((size_t)y * width + x) + 3];
                if (z == EMPTY) continue;
                float(*q)[2] = &range[(y / TILE) * tx + x / TILE];
                if (z > (*q)[0]) (*q)[0] = z;
                if (z < (*q)[1]) (*q)[1] = z;
            }
    }
    if ((size_t)nl + 1 > r->cl_cap) {
        cull_light *p = realloc(r->cl, ((size_t)nl + 1) * sizeof *p);
        if (!p) {
            free(range);
            return fail(err, errlen, -ENOMEM, "out of memory");
        }
        r->cl = p;
        r->cl_cap = (size_t)nl + 1;
    }
    float *ld = malloc(((size_t)nl + 1) * 16 * sizeof *ld);
    if (!ld) {
        free(range);
        return fail(err, errlen, -ENOMEM, "out of memory");
    }
    for (uint32_t i = 0; i < nl; i++) {
        const vt_light *L = &lights[i];
        float *q = ld + 16 * (size_t)i;
        r->cl[i] = L->l;
        for (int a = 0; a < 3; a++) {
            q[a] = (float)(L->l.pos[a] - v->origin[a]);
            q[4 + a] = L->color[a];
            q[8 + a] = L->l.dir[a];
        }
        q[3] = (float)(L->l.radius * L->l.radius);
        q[7] = L->l.type == CULL_LIGHT_SPOT ? 1.0f : 0.0f;
        q[11] = L->l.cos_outer;
        q[12] = L->cos_inner > L->l.cos_outer ? L->cos_inner : L->l.cos_outer + 1e-4f;
        q[13] = q[14] = q[15] = 0;
    }
    int lrc = cull_lights_bin(v, width, height, r->cl, nl, (const float(*)[2])range, &r->tiles);
    free(range);
    if (lrc != CULL_OK) {
        free(ld);
        return fail(err, errlen, -EINVAL, "lights: %s", cull_strerror(lrc));
    }
    /* pass 2: shading with the tile lists */
    glActiveTexture(GL_TEXTURE0);
    tbo(r->tex[0], r->buf[0], GL_RGBA32F, ld, (size_t)nl * 16 * sizeof *ld);
    glActiveTexture(GL_TEXTURE1);
    tbo(r->tex[1], r->buf[1], GL_R32UI, r->tiles.offset, ((size_t)tx * ty + 1) * sizeof(uint32_t));
    glActiveTexture(GL_TEXTURE2);
    tbo(r->tex[2], r->buf[2], GL_R32UI, r->tiles.index, (size_t)r->tiles.offset[tx * ty] * sizeof(uint32_t));
    free(ld);
    glUniform1i(glGetUniformLocation(r->prog, "u_lights"), 0);
    glUniform1i(glGetUniformLocation(r->prog, "u_offset"), 1);
    glUniform1i(glGetUniformLocation(r->prog, "u_index"), 2);
    glUniform1i(glGetUniformLocation(r->prog, "u_tiles_x"), (int)tx);
    glUniform1i(glGetUniformLocation(r->prog, "u_pass"), 1);
    if (nl) {
        /* the depth of pass 1 stays: each pixel is shaded once, by the
           surface pass 1 found there (the same positions: invariant) */
        vt_gl_target_clear(r->target, clear, NAN); /* colour only */
        glDepthFunc(reversed ? GL_GEQUAL : GL_LEQUAL);
        glDepthMask(GL_FALSE);
    }
    rc = draw_all(meshes, nmesh, inst, ninst, v->origin, err, errlen);
    glDepthMask(GL_TRUE);
    if (rc) return rc;
    if ((rc = vt_gl_readback(r->target, r->pix, NULL, NULL, err, errlen))) return rc;
    /* alpha: nearness -> coverage, and depth as vt_soft gives it */
    for (uint32_t y = 0; y < height; y++)
        for (uint32_t x = 0; x < width; x++) {
            const float *p = r->pix + 4 * ((size_t)y * width + x);
            float *c = rgba + 4 * ((size_t)y * stride + x), *dz = depth + (size_t)y * stride + x;
            float nz = p[3];
            if (nz == EMPTY) {
                c[0] = c[1] = c[2] = c[3] = 0;
                *dz = INFINITY;
                continue;
            }
            c[0] = p[0];
            c[1] = p[1];
            c[2] = p[2];
            c[3] = 1;
            *dz = !vr.ortho ? 1.0f / nz : v->depth_mode == CULL_DEPTH_GL ? 1.0f - 0.5f * nz : 1.0f - nz;
        }
    if (st) {
        st->lights_in_view = r->tiles.in_view;
        st->max_lights_per_tile = r->tiles.max_per_tile;
        st->threads = 1;
    }
    return 0;
}
