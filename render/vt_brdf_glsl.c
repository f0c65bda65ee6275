/*
 * vt_brdf_glsl.c — the shading model of vt_brdf.h in GLSL for the OpenGL
 * renderer: one fragment-shader object (vt_brdf_fs) that vt_gldraw links
 * into its scene and background programs, and what it reads: the SH
 * irradiance as uniforms, the prefiltered levels (one RGBA32F texture,
 * the levels stacked: VT_IBL_RES x VT_IBL_RES * VT_IBL_LEVELS) and the
 * DFG table (VT_DFG_N^2 RGBA32F) on texture units VT_BRDF_UNIT_SPEC and
 * VT_BRDF_UNIT_DFG, both read with texelFetch and filtered by hand as
 * vt_brdf.c filters them, operation for operation, and vt_shade.inl's
 * formulas for the lights (in float, camera-relative).
 * The prefiltered texture is uploaded again only when the vt_ibl was
 * remade (its gen), the DFG table once.
 */
#include "vt_brdf.h"

#include <epoxy/gl.h>

#define STR_(x) #x
#define STR(x) STR_(x)

const char *const vt_brdf_fs =
    "#version 330 core\n"
    "#define PI 3.14159265\n"
    "#define DFG_N " STR(VT_DFG_N) "\n"
    "#define IBL_RES " STR(VT_IBL_RES) "\n"
    "#define IBL_LEVELS " STR(VT_IBL_LEVELS) "\n"
    "uniform vec3 u_sh[9];\n"
    "uniform sampler2D u_ibl_spec, u_dfg;\n"
    /* vt_brdf_rough */
    "float vt_rough(float r) { return r >= 0.045 ? min(r, 1.0) : (r < 0.045 ? 0.045 : 1.0); }\n"
    /* vt_shade.inl's half_terms + ggx_dv + the channels: (1 - F) c_diff / pi + F D V, for n.l > 0 */
    "vec3 vt_pbr_brdf(vec3 n, vec3 v, vec3 l, vec3 diffuse, vec3 f0, float a2) {\n"
    "  float ndl = max(dot(n, l), 0.0), nv = abs(dot(n, v));\n"
    "  vec3 h = l + v;\n"
    "  float hl2 = dot(h, h), ih = hl2 > 0.0 ? 1.0 / sqrt(hl2) : 0.0;\n"
    "  float ndh = max(dot(n, h) * ih, 0.0), vh = clamp(dot(v, h) * ih, 0.0, 1.0);\n"
    "  float f1 = 1.0 - vh, f2 = f1 * f1, f5 = f2 * f2 * f1;\n"
    "  float t = (ndh * ndh) * a2 + (1.0 - ndh) * (1.0 + ndh);\n"
    "  float gl = ndl + sqrt((1.0 - a2) * (ndl * ndl) + a2);\n"
    "  float vv = 1.0 / max(nv + sqrt((1.0 - a2) * (nv * nv) + a2), 1e-6);\n"
    "  float dv = a2 * (1.0 / PI) * vv / ((t * t) * gl);\n"
    "  vec3 F = (1.0 - f0) * f5 + f0, cd = diffuse * (1.0 / PI);\n"
    "  return F * (dv - cd) + cd;\n"
    "}\n"
    /* vt_dfg */
    "vec3 vt_dfg_at(float ndv, float rough) {\n"
    "  float m = float(DFG_N - 1), x = clamp(ndv, 0.0, 1.0) * m, y = vt_rough(rough) * m;\n"
    "  int i = min(int(x), DFG_N - 2), j = min(int(y), DFG_N - 2);\n"
    "  float ax = x - float(i), ay = y - float(j);\n"
    "  vec3 a = texelFetch(u_dfg, ivec2(i, j), 0).rgb, b = texelFetch(u_dfg, ivec2(i + 1, j), 0).rgb;\n"
    "  vec3 c = texelFetch(u_dfg, ivec2(i, j + 1), 0).rgb, d = texelFetch(u_dfg, ivec2(i + 1, j + 1), 0).rgb;\n"
    "  vec3 top = a + ax * (b - a), bot = c + ax * (d - c);\n"
    "  return top + ay * (bot - top);\n"
    "}\n"
    /* vt_oct_uv */
    "vec2 vt_oct_uv(vec3 d) {\n"
    "  float s = abs(d.x) + abs(d.y) + abs(d.z);\n"
    "  float px = s > 0.0 ? d.x / s : 0.0, pz = s > 0.0 ? d.z / s : 0.0;\n"
    "  if (d.y < 0.0) {\n"
    "    float qx = (1.0 - abs(pz)) * (px < 0.0 ? -1.0 : 1.0), qz = (1.0 - abs(px)) * (pz < 0.0 ? -1.0 : 1.0);\n"
    "    px = qx; pz = qz;\n"
    "  }\n"
    "  return vec2(0.5 * px + 0.5, 0.5 * pz + 0.5);\n"
    "}\n"
    /* vt_brdf.c's oct_sample */
    "vec3 vt_oct_at(int lv, vec2 uv) {\n"
    "  float m = float(IBL_RES), x = clamp(uv.x * m - 0.5, 0.0, m - 1.0), y = clamp(uv.y * m - 0.5, 0.0, m - 1.0);\n"
    "  int i = min(int(x), IBL_RES - 2), j = min(int(y), IBL_RES - 2);\n"
    "  float ax = x - float(i), ay = y - float(j);\n"
    "  int o = lv * IBL_RES;\n"
    "  vec3 a = texelFetch(u_ibl_spec, ivec2(i, o + j), 0).rgb, b = texelFetch(u_ibl_spec, ivec2(i + 1, o + j), 0).rgb;\n"
    "  vec3 c = texelFetch(u_ibl_spec, ivec2(i, o + j + 1), 0).rgb;\n"
    "  vec3 d = texelFetch(u_ibl_spec, ivec2(i + 1, o + j + 1), 0).rgb;\n"
    "  vec3 top = a + ax * (b - a), bot = c + ax * (d - c);\n"
    "  return top + ay * (bot - top);\n"
    "}\n"
    /* vt_shade.inl's env_light, image-based: the ambient before the occlusion */
    "vec3 vt_pbr_ambient(vec3 n, vec3 v, vec3 diffuse, vec3 f0, float rough) {\n"
    "  float d = dot(n, v);\n"
    "  vec3 r = 2.0 * d * n - v;\n"
    "  float f = vt_rough(rough) * float(IBL_LEVELS - 1);\n"
    "  int k = min(int(f), IBL_LEVELS - 2);\n"
    "  float t = f - float(k);\n"
    "  vec2 uv = vt_oct_uv(r);\n"
    "  if (!(uv.x >= 0.0 && uv.x <= 1.0 && uv.y >= 0.0 && uv.y <= 1.0)) uv = vec2(0.5);\n"
    "  vec3 sp = (1.0 - t) * vt_oct_at(k, uv) + t * vt_oct_at(k + 1, uv);\n"
    "  vec3 g = vt_dfg_at(abs(d), rough);\n"
    "  float xy = n.x * n.y, yz = n.y * n.z, xz = n.x * n.z, z3 = 3.0 * (n.z * n.z) - 1.0;\n"
    "  float x2y2 = n.x * n.x - n.y * n.y;\n"
    "  vec3 e = u_sh[1] * n.y + (u_sh[2] * n.z + (u_sh[3] * n.x + u_sh[0]));\n"
    "  e = u_sh[4] * xy + (u_sh[5] * yz + (u_sh[6] * z3 + e));\n"
    "  e = max(u_sh[7] * xz + (u_sh[8] * x2y2 + e), vec3(0.0));\n"
    "  return diffuse * ((1.0 - f0) * g.z) * e + sp * (f0 * g.x + g.y);\n"
    "}\n";

void vt_brdf_gl_init(vt_brdf_gl *b)
{
    glGenTextures(2, b->tex);
    b->gen = 0;
    const float *t = vt_dfg_table();
    glActiveTexture(GL_TEXTURE0 + VT_BRDF_UNIT_DFG);
    glBindTexture(GL_TEXTURE_2D, b->tex[1]);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA32F, VT_DFG_N, VT_DFG_N, 0, GL_RGBA, GL_FLOAT, t);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    glActiveTexture(GL_TEXTURE0 + VT_BRDF_UNIT_SPEC);
    glBindTexture(GL_TEXTURE_2D, b->tex[0]);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA32F, VT_IBL_RES, VT_IBL_RES * VT_IBL_LEVELS, 0, GL_RGBA, GL_FLOAT, NULL);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    glActiveTexture(GL_TEXTURE0);
}

void vt_brdf_gl_free(vt_brdf_gl *b)
{
    glDeleteTextures(2, b->tex);
}

void vt_brdf_gl_frame(vt_brdf_gl *b, const vt_ibl *ibl)
{
    glActiveTexture(GL_TEXTURE0 + VT_BRDF_UNIT_SPEC);
    glBindTexture(GL_TEXTURE_2D, b->tex[0]);
    if (ibl && ibl->gen != b->gen) {
        for (uint32_t k = 0; k < VT_IBL_LEVELS; k++)
            glTexSubImage2D(GL_TEXTURE_2D, 0, 0, (GLint)(k * VT_IBL_RES), VT_IBL_RES, VT_IBL_RES, GL_RGBA, GL_FLOAT,
                            ibl->spec[k]);
        b->gen = ibl->gen;
    }
    glActiveTexture(GL_TEXTURE0 + VT_BRDF_UNIT_DFG);
    glBindTexture(GL_TEXTURE_2D, b->tex[1]);
    glActiveTexture(GL_TEXTURE0);
}

void vt_brdf_gl_uniforms(unsigned prog, const vt_penv *pe)
{
    glUniform1i(glGetUniformLocation(prog, "u_ibl_spec"), VT_BRDF_UNIT_SPEC);
    glUniform1i(glGetUniformLocation(prog, "u_dfg"), VT_BRDF_UNIT_DFG);
    glUniform1i(glGetUniformLocation(prog, "u_ibl_on"), pe->ibl != NULL);
    if (pe->ibl) glUniform3fv(glGetUniformLocation(prog, "u_sh"), 9, &pe->ibl->sh[0][0]);
}
