/*
 * vt_shadow_gl.c — the sun's shadow cascades in the GL renderer (see
 * vt_shadow_gl.h). The maps are vt_shadow.c's, drawn on the CPU (one
 * thread) and uploaded each frame (4 x size^2 floats: 16 MB at 720p);
 * a GL depth pass of its own would need the casters' geometry uploaded
 * apart from the view's instances, and would rasterise with GL's rules:
 * one rasterizer gives both renderers the same depths to compare with.
 */
#include "vt_shadow_gl.h"

#include "vt_picture.h"
#include "vt_shadow.h"

#include <epoxy/gl.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#define STR_(x) #x
#define STR(x) STR_(x)

/* vt_shadow_lookup, in GLSL */
const char *const vt_shadow_gl_fs =
    "#version 330 core\n"
    "uniform int u_sh_on, u_sh_n, u_sh_size;\n"
    "uniform vec3 u_sh_s, u_sh_u, u_sh_v;\n"
    "uniform vec4 u_sh_drow;\n"
    "uniform float u_sh_split[" STR(VT_SHADOW_CASCADES) " + 1];\n"
    "uniform float u_sh_scale[" STR(VT_SHADOW_CASCADES) "], u_sh_texel[" STR(VT_SHADOW_CASCADES) "];\n"
    "uniform vec2 u_sh_off[" STR(VT_SHADOW_CASCADES) "];\n"
    "uniform sampler2DArray u_sh_map;\n"
    "float sh_cascade(int i, vec3 p, vec3 n, float ndl) {\n"
    "  float tx = u_sh_texel[i];\n"
    "  float sn = sqrt(max(1.0 - ndl * ndl, 0.0)), tn = min(sn / ndl, 8.0);\n"
    "  float o = " STR(VT_SHADOW_NOFS) " * tx * sn;\n"
    "  vec3 q = p + n * o;\n"
    "  float dref = u_sh_s.x * q.x + u_sh_s.y * q.y + u_sh_s.z * q.z + tx * (" STR(VT_SHADOW_BIAS_C) " + "
    STR(VT_SHADOW_BIAS_S) " * tn);\n"
    "  float mx = (u_sh_u.x * q.x + u_sh_u.y * q.y + u_sh_u.z * q.z) * u_sh_scale[i] + u_sh_off[i].x;\n"
    "  float my = (u_sh_v.x * q.x + u_sh_v.y * q.y + u_sh_v.z * q.z) * u_sh_scale[i] + u_sh_off[i].y;\n"
    "  float sz = float(u_sh_size);\n"
    "  if (!(mx > -2.0 && mx < sz + 2.0 && my > -2.0 && my < sz + 2.0)) return 1.0;\n"
    "  float X = mx - 0.5, Y = my - 0.5, fx0 = floor(X), fy0 = floor(Y), fx = X - fx0, fy = Y - fy0;\n"
    "  int x0 = int(fx0) - 1, y0 = int(fy0) - 1;\n"
    "  float wx[4] = float[4](1.0 - fx, 1.0, 1.0, fx), wy[4] = float[4](1.0 - fy, 1.0, 1.0, fy);\n"
    "  float lit = 0.0;\n"
    "  for (int b = 0; b < 4; b++) {\n"
    "    int y = y0 + b;\n"
    "    if (y < 0 || y >= u_sh_size) { lit += wy[b] * 3.0; continue; }\n"
    "    float r = 0.0;\n"
    "    for (int a = 0; a < 4; a++) {\n"
    "      int x = x0 + a;\n"
    "      r += (x < 0 || x >= u_sh_size || texelFetch(u_sh_map, ivec3(x, y, i), 0).r <= dref) ? wx[a] : 0.0;\n"
    "    }\n"
    "    lit += wy[b] * r;\n"
    "  }\n"
    "  return lit * (1.0 / 9.0);\n"
    "}\n"
    "float sun_visibility(vec3 p, vec3 n) {\n"
    "  if (u_sh_on == 0) return 1.0;\n"
    "  float ndl = u_sh_s.x * n.x + u_sh_s.y * n.y + u_sh_s.z * n.z;\n"
    "  if (!(ndl > 0.0)) return 1.0;\n"
    "  float d = u_sh_drow.x * p.x + u_sh_drow.y * p.y + u_sh_drow.z * p.z + u_sh_drow.w;\n"
    "  if (!(d < u_sh_split[u_sh_n])) return 1.0;\n"
    "  int i = 0;\n"
    "  while (i + 1 < u_sh_n && d >= u_sh_split[i + 1]) i++;\n"
    "  float vis = sh_cascade(i, p, n, ndl);\n"
    "  float band = " STR(VT_SHADOW_BLEND) " * (u_sh_split[i + 1] - u_sh_split[i]);\n"
    "  float t = (d - (u_sh_split[i + 1] - band)) / band;\n"
    "  if (t > 0.0) {\n"
    "    float v2 = i + 1 < u_sh_n ? sh_cascade(i + 1, p, n, ndl) : 1.0;\n"
    "    vis += (v2 - vis) * min(t, 1.0);\n"
    "  }\n"
    "  return vis;\n"
    "}\n";

struct vt_shadow_gl {
    vt_shadow *sh;
    unsigned tex;
    uint32_t tsize, tn;     /* the texture's size and layers */
    float (*mb)[6];
    size_t mb_cap;
    bool on;                /* this frame has cascades */
};

void vt_shadow_gl_program_init(unsigned prog)
{
    glUseProgram(prog);
    glUniform1i(glGetUniformLocation(prog, "u_sh_map"), VT_SHADOW_GL_UNIT);
}

int vt_shadow_gl_create(vt_shadow_gl **out)
{
    vt_shadow_gl *s = calloc(1, sizeof *s);
    if (!s || vt_shadow_create(&s->sh)) {
        free(s);
        return VT_ERR_NOMEM;
    }
    *out = s;
    return 0;
}

void vt_shadow_gl_destroy(vt_shadow_gl *s)
{
    if (!s) return;
    if (s->tex) glDeleteTextures(1, &s->tex);
    vt_shadow_destroy(s->sh);
    free(s->mb);
    free(s);
}

static uint64_t now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000000ull + (uint64_t)ts.tv_nsec;
}

int vt_shadow_gl_frame(vt_shadow_gl *s, const vt_frame *f, uint32_t *tris, uint64_t *ns, char *err, size_t errlen)
{
    *tris = 0;
    *ns = 0;
    uint64_t t0 = now_ns();
    s->on = false;
    vt_shadow_fit fit;
    if (!vt_shadow_fit_frame(f, &fit)) return 0;
    if (!vp_grow((void **)&s->mb, &s->mb_cap, (size_t)f->nmesh + 1, sizeof *s->mb))
        return vp_errf(err, errlen, VT_ERR_NOMEM, "out of memory");
    for (uint32_t i = 0; i < f->nmesh; i++) vt_mesh_bounds(&f->meshes[i], s->mb[i]);
    int rc = vt_shadow_draw(s->sh, NULL, 1, &fit, f->view->origin, f->meshes, (const float(*)[6])s->mb,
                            f->casters ? f->casters : f->inst, f->casters ? f->ncasters : f->ninst, tris, err, errlen);
    if (rc) return rc;
    glActiveTexture(GL_TEXTURE0 + VT_SHADOW_GL_UNIT);
    if (!s->tex) glGenTextures(1, &s->tex);
    glBindTexture(GL_TEXTURE_2D_ARRAY, s->tex);
    if (s->tsize != fit.size || s->tn != fit.n) {
        glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
        glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
        glTexImage3D(GL_TEXTURE_2D_ARRAY, 0, GL_R32F, (GLsizei)fit.size, (GLsizei)fit.size, (GLsizei)fit.n, 0, GL_RED,
                     GL_FLOAT, vt_shadow_maps(s->sh));
        s->tsize = fit.size;
        s->tn = fit.n;
    } else {
        glTexSubImage3D(GL_TEXTURE_2D_ARRAY, 0, 0, 0, 0, (GLsizei)fit.size, (GLsizei)fit.size, (GLsizei)fit.n, GL_RED,
                        GL_FLOAT, vt_shadow_maps(s->sh));
    }
    glActiveTexture(GL_TEXTURE0);
    GLenum e = glGetError();
    if (e != GL_NO_ERROR) {
        s->tsize = 0;
        return vp_errf(err, errlen, VT_ERR_GL, "shadow maps: GL error 0x%x", e);
    }
    s->on = true;
    *ns = now_ns() - t0;
    return 0;
}

void vt_shadow_gl_uniforms(const vt_shadow_gl *s, unsigned prog)
{
    glUniform1i(glGetUniformLocation(prog, "u_sh_on"), s && s->on);
    if (!s || !s->on) return;
    const vt_shadow_fit *f = vt_shadow_fit_of(s->sh);
    glUniform1i(glGetUniformLocation(prog, "u_sh_n"), (int)f->n);
    glUniform1i(glGetUniformLocation(prog, "u_sh_size"), (int)f->size);
    glUniform3fv(glGetUniformLocation(prog, "u_sh_s"), 1, f->s);
    glUniform3fv(glGetUniformLocation(prog, "u_sh_u"), 1, f->u);
    glUniform3fv(glGetUniformLocation(prog, "u_sh_v"), 1, f->v);
    glUniform4fv(glGetUniformLocation(prog, "u_sh_drow"), 1, f->drow);
    glUniform1fv(glGetUniformLocation(prog, "u_sh_split"), VT_SHADOW_CASCADES + 1, f->split);
    glUniform1fv(glGetUniformLocation(prog, "u_sh_scale"), VT_SHADOW_CASCADES, f->scale);
    glUniform1fv(glGetUniformLocation(prog, "u_sh_texel"), VT_SHADOW_CASCADES, f->texel);
    glUniform2fv(glGetUniformLocation(prog, "u_sh_off"), VT_SHADOW_CASCADES, &f->off[0][0]);
}
