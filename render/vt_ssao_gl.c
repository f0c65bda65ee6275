/*
 * vt_ssao_gl.c — the GL path's ambient occlusion (vt_ssao.h's rules, the
 * software pass' operations in GLSL): after the nearness pass (pass 1)
 * one half-resolution pass (GTAO per half texel: its AO and nearness)
 * and one full-resolution pass (the depth-aware tent upsample) into a
 * texture the shading passes read through `float ambient_occlusion()`,
 * a fragment-shader object of this file linked into vt_gldraw's two
 * programs (vt_glssao_program). Costs two RGBA32F targets (20 bytes a
 * pixel, 20 a half texel) and two full-screen triangles a frame.
 */
#include "vt_glssao.h"
#include "vt_gl_internal.h"
#include "vt_gldraw_internal.h"

#include <epoxy/gl.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define STR_(x) #x
#define STR(x) STR_(x)
#define AO_UNIT 11u          /* the shading passes read the AO here (10: the shadow maps, 14, 15: the BRDF's) */
#define IN_UNIT 12u          /* the passes' inputs: nearness, then the half texels */
#define HALF_UNIT 13u

/* The shading passes' half: 1 without the pass. */
const char *const vt_glssao_fs =
    "#version 330 core\n"
    "uniform sampler2D u_ao_tex;\n"
    "uniform int u_ao_on;\n"
    "float ambient_occlusion() {\n"
    "  return u_ao_on != 0 ? texelFetch(u_ao_tex, ivec2(gl_FragCoord.xy), 0).r : 1.0;\n"
    "}\n";

#define COMMON                                                                                                  \
    "#version 330 core\n"                                                                                       \
    "#define EMPTY " STR(VT_EMPTY_GLSL) "\n"                                                                    \
    "#define PI 3.14159265\n"                                                                                   \
    "uniform sampler2D u_near;\n" /* pass 1's colour: alpha is nearness */                                      \
    "uniform ivec2 u_size, u_hsize;\n"                                                                          \
    "uniform int u_ortho;\n"                                                                                    \
    "out vec4 o_color;\n"

/* GTAO at half texel gl_FragCoord - 0.5 (vt_ssao.c's gtao) */
static const char *const ao_fs =
    COMMON
    "uniform mat4 u_inv;\n"
    "uniform vec3 u_ex, u_ey, u_vdir;\n"
    "uniform float u_texel1;\n"
    "uniform vec2 u_dir[" STR(VT_SSAO_SLICES) " * 4];\n"
    "float acos_f(float x) {\n"
    "  float a = min(abs(x), 1.0);\n"
    "  float r = ((-0.0187293 * a + 0.0742610) * a - 0.2121144) * a + 1.5707288;\n"
    "  r *= sqrt(max(1.0 - a, 0.0));\n"
    "  return x < 0.0 ? PI - r : r;\n"
    "}\n"
    "float arc(float h, float ch, float sh, float cn, float sn) {\n"
    "  float c2h = 2.0 * ch * ch - 1.0, s2h = 2.0 * sh * ch;\n"
    "  return 0.25 * (-(c2h * cn + s2h * sn) + cn + 2.0 * h * sn);\n"
    "}\n"
    "bool texel(ivec2 t, out vec4 q) {\n"
    "  q = vec4(0.0);\n"
    "  if (any(lessThan(t, ivec2(0))) || any(greaterThanEqual(t, u_hsize))) return false;\n"
    "  float N = texelFetch(u_near, 2 * t, 0).a;\n"
    "  if (!(N > EMPTY) || isinf(N) || isnan(N)) return false;\n"
    "  vec2 ndc = (vec2(4 * t) + 1.0) / vec2(u_size) - 1.0;\n"
    "  vec4 h = u_inv * vec4(ndc, N, 1.0);\n"
    "  q = vec4(h.xyz / h.w, N);\n"
    "  return !any(isinf(q.xyz)) && !any(isnan(q.xyz));\n"
    "}\n"
    /* the side whose two texels extrapolate to P's nearness (vt_ssao.c) */
    "bool side_step(ivec2 ij, ivec2 e, vec4 P, out vec3 d) {\n"
    "  vec4 l, l2, h, h2;\n"
    "  bool hl = texel(ij - e, l), hl2 = texel(ij - 2 * e, l2), hh = texel(ij + e, h), hh2 = texel(ij + 2 * e, h2);\n"
    "  float el = !hl ? 3e38 : hl2 ? abs(2.0 * l.w - l2.w - P.w) : 1e37;\n" /* C: INFINITY, FLT_MAX */
    "  float eh = !hh ? 3e38 : hh2 ? abs(2.0 * h.w - h2.w - P.w) : 1e37;\n"
    "  d = eh < el || (eh == el && hh) ? h.xyz - P.xyz : P.xyz - l.xyz;\n"
    "  return hl || hh;\n"
    "}\n"
    "float gtao(ivec2 ij, out float near) {\n"
    "  vec4 P;\n"
    "  near = EMPTY;\n"
    "  if (!texel(ij, P)) return 1.0;\n"
    "  near = P.w;\n"
    "  const float R = " STR(VT_SSAO_RADIUS) ", inv_fade = 1.0 / (" STR(VT_SSAO_FADE) " * " STR(VT_SSAO_RADIUS) ");\n"
    "  float rpx = R * (u_ortho != 0 ? 1.0 : P.w) / u_texel1;\n"
    "  if (!(rpx >= 1.0)) return 1.0;\n"
    "  rpx = min(rpx, " STR(VT_SSAO_MAX_PX) ");\n"
    "  int nst = rpx < " STR(VT_SSAO_STEPS) ".0 ? int(rpx) : " STR(VT_SSAO_STEPS) ";\n"
    "  float inv_nst = 1.0 / float(nst);\n"
    "  vec3 dx, dy;\n"
    "  if (!side_step(ij, ivec2(1, 0), P, dx) || !side_step(ij, ivec2(0, 1), P, dy)) return 1.0;\n"
    "  vec3 n = cross(dx, dy), V = u_ortho != 0 ? u_vdir : -P.xyz;\n"
    "  float nl = length(n), vl = length(V);\n"
    "  if (!(nl > 0.0) || !(vl > 0.0) || isinf(nl) || isinf(vl)) return 1.0;\n"
    "  n *= dot(n, V) < 0.0 ? -1.0 / nl : 1.0 / nl;\n"
    "  V /= vl;\n"
    "  int turn = (ij.x & 1) + 2 * (ij.y & 1);\n"
    "  float num = 0.0, den = 0.0;\n"
    "  for (int sl = 0; sl < " STR(VT_SSAO_SLICES) "; sl++) {\n"
    "    vec2 cs = u_dir[turn * " STR(VT_SSAO_SLICES) " + sl];\n"
    "    vec3 T = cs.x * u_ex + cs.y * u_ey;\n"
    "    T -= dot(T, V) * V;\n"
    "    float tl = length(T);\n"
    "    if (!(tl > 0.0)) continue;\n"
    "    float a = dot(n, V), b = dot(n, T) / tl, pl = sqrt(a * a + b * b);\n"
    "    if (!(pl > 0.0)) continue;\n"
    "    float cn = a / pl, sn = b / pl, na = acos_f(cn);\n"
    "    na = sn < 0.0 ? -na : na;\n"
    "    float hc[2] = float[2](sn, -sn);\n"
    "    bool up[2] = bool[2](false, false);\n"
    "    for (int side = 0; side < 2; side++) {\n"
    "      float sg = side != 0 ? 1.0 : -1.0, lo = hc[side];\n"
    "      for (int st = 0; st < nst; st++) {\n"
    "        float tt = rpx * (float(st) + 0.5) * inv_nst;\n"
    "        vec4 S;\n"
    "        if (!texel(ij + ivec2(floor(sg * cs * tt + 0.5)), S)) continue;\n"
    "        vec3 dd = S.xyz - P.xyz;\n"
    "        float l2 = dot(dd, dd), hn = dot(dd, n);\n"
    "        if (!(l2 > 0.0) || !(l2 < R * R) || !(hn > 0.0) || hn * hn < " STR(VT_SSAO_BIAS) " * " STR(VT_SSAO_BIAS) " * l2) continue;\n"
    "        float il = 1.0 / sqrt(l2), dist = l2 * il;\n"
    "        float wf = (R - dist) * inv_fade, cv = dot(dd, V) * il;\n"
    "        cv = lo + (cv - lo) * min(wf, 1.0);\n"
    "        if (cv > hc[side]) { hc[side] = cv; up[side] = true; }\n"
    "      }\n"
    "    }\n"
    "    float h0 = up[0] ? -acos_f(hc[0]) : na - PI / 2.0, s0 = up[0] ? -sqrt(max(1.0 - hc[0] * hc[0], 0.0)) : -cn;\n"
    "    float h1 = up[1] ? acos_f(hc[1]) : na + PI / 2.0, s1 = up[1] ? sqrt(max(1.0 - hc[1] * hc[1], 0.0)) : cn;\n"
    "    float e0 = arc(na - PI / 2.0, sn, -cn, cn, sn), e1 = arc(na + PI / 2.0, -sn, cn, cn, sn);\n"
    "    num += pl * (arc(h0, hc[0], s0, cn, sn) + arc(h1, hc[1], s1, cn, sn));\n"
    "    den += pl * (e0 + e1);\n"
    "  }\n"
    "  return den > 0.0 ? clamp(num / den, 0.0, 1.0) : 1.0;\n"
    "}\n"
    "void main() {\n"
    "  float near, ao = gtao(ivec2(gl_FragCoord.xy), near);\n"
    "  o_color = vec4(ao, 0.0, 0.0, near);\n"
    "}\n";

/* The upsample (vt_ssao.c's job_up) */
static const char *const up_fs =
    COMMON
    "uniform sampler2D u_half;\n" /* AO, -, -, nearness */
    "uniform float u_ntol;\n"
    "int taps(int x, int hn, out int idx[3], out float wt[3]) {\n"
    "  int k = 0;\n"
    "  idx = int[3](0, 0, 0); wt = float[3](0.0, 0.0, 0.0);\n"
    "  if ((x & 1) != 0) {\n"
    "    idx[k] = (x - 1) / 2; wt[k] = 0.5; k++;\n"
    "    if ((x + 1) / 2 < hn) { idx[k] = (x + 1) / 2; wt[k] = 0.5; k++; }\n"
    "    return k;\n"
    "  }\n"
    "  if (x >= 2) { idx[k] = x / 2 - 1; wt[k] = 0.25; k++; }\n"
    "  idx[k] = x / 2; wt[k] = 0.5; k++;\n"
    "  if (x / 2 + 1 < hn) { idx[k] = x / 2 + 1; wt[k] = 0.25; k++; }\n"
    "  return k;\n"
    "}\n"
    "void main() {\n"
    "  ivec2 p = ivec2(gl_FragCoord.xy);\n"
    "  float N = texelFetch(u_near, p, 0).a;\n"
    "  float tol = u_ortho != 0 ? u_ntol : " STR(VT_SSAO_DEPTH_TOL) " * N;\n"
    "  o_color = vec4(1.0, 0.0, 0.0, 1.0);\n"
    "  if (!(N > EMPTY) || !(tol > 0.0) || isinf(tol) || isnan(tol)) return;\n"
    "  float k = 1.0 / tol, sum = 0.0, acc = 0.0;\n"
    "  int jy[3], ix[3];\n"
    "  float wy[3], wx[3];\n"
    "  int ny = taps(p.y, u_hsize.y, jy, wy), nx = taps(p.x, u_hsize.x, ix, wx);\n"
    "  for (int a = 0; a < ny; a++)\n"
    "    for (int c = 0; c < nx; c++) {\n"
    "      vec4 h = texelFetch(u_half, ivec2(ix[c], jy[a]), 0);\n"
    "      if (h.w == EMPTY) continue;\n"
    "      float wd = 1.0 - abs(h.w - N) * k;\n"
    "      if (!(wd > 0.0)) continue;\n"
    "      float wt = wy[a] * wx[c] * wd;\n"
    "      sum += wt;\n"
    "      acc += wt * h.x;\n"
    "    }\n"
    "  if (sum > 0.0) o_color.x = clamp(acc / sum, 0.0, 1.0);\n"
    "}\n";

struct vt_glssao {
    vt_gl *g;
    unsigned ao, up;        /* the two passes' programs */
    vt_gl_target *half, *full;
};

void vt_glssao_program_init(unsigned prog)
{
    glUseProgram(prog);
    glUniform1i(glGetUniformLocation(prog, "u_ao_tex"), AO_UNIT);
    glUniform1i(glGetUniformLocation(prog, "u_ao_on"), 0);
}

int vt_glssao_create(vt_gl *g, vt_glssao **out, char *err, size_t errlen)
{
    vt_glssao *s = calloc(1, sizeof *s);
    if (!s) return vp_errf(err, errlen, VT_ERR_NOMEM, "out of memory");
    s->g = g;
    int rc = vt_gl_program_build(g, vt_gldraw_bg_vs, ao_fs, &s->ao, err, errlen);
    if (!rc) rc = vt_gl_program_build(g, vt_gldraw_bg_vs, up_fs, &s->up, err, errlen);
    if (rc) {
        vt_glssao_destroy(s);
        return rc;
    }
    for (int p = 0; p < 2; p++) {
        unsigned prog = p ? s->up : s->ao;
        glUseProgram(prog);
        glUniform1i(glGetUniformLocation(prog, "u_near"), IN_UNIT);
        glUniform1i(glGetUniformLocation(prog, "u_half"), HALF_UNIT);
    }
    *out = s;
    return 0;
}

void vt_glssao_destroy(vt_glssao *s)
{
    if (!s) return;
    vt_gl_target_destroy(s->half);
    vt_gl_target_destroy(s->full);
    if (s->ao) glDeleteProgram(s->ao);
    if (s->up) glDeleteProgram(s->up);
    free(s);
}

/* t made or resized to w x h (RGBA32F). */
static int target(vt_gl *g, vt_gl_target **t, uint32_t w, uint32_t h, char *err, size_t errlen)
{
    if (!*t) return vt_gl_target_create(g, w, h, &(vt_gl_target_desc){.color = VT_GL_RGBA32F}, t, err, errlen);
    int rc = vt_gl_target_resize(*t, w, h, err, errlen);
    if (rc) {
        vt_gl_target_destroy(*t);
        *t = NULL;
    }
    return rc;
}

static void set_common(unsigned prog, const vt_ssao_view *sv)
{
    glUseProgram(prog);
    glUniform2i(glGetUniformLocation(prog, "u_size"), (int)sv->w, (int)sv->h);
    glUniform2i(glGetUniformLocation(prog, "u_hsize"), (int)sv->hw, (int)sv->hh);
    glUniform1i(glGetUniformLocation(prog, "u_ortho"), sv->ortho);
}

int vt_glssao_run(vt_glssao *s, unsigned near_tex, const vt_ssao_view *sv, char *err, size_t errlen)
{
    if (!sv->ok) return 0;
    int rc = target(s->g, &s->half, sv->hw, sv->hh, err, errlen);
    if (!rc) rc = target(s->g, &s->full, sv->w, sv->h, err, errlen);
    if (rc) return rc;
    glDisable(GL_DEPTH_TEST);
    glDisable(GL_CULL_FACE);
    glActiveTexture(GL_TEXTURE0 + IN_UNIT);
    glBindTexture(GL_TEXTURE_2D, near_tex);
    /* the half texels */
    set_common(s->ao, sv);
    float inv[16], dir[4 * VT_SSAO_SLICES][2];
    for (int r = 0; r < 4; r++)
        for (int c = 0; c < 4; c++) inv[4 * c + r] = sv->inv[r][c]; /* column-major */
    vt_ssao_dirs(dir);
    glUniformMatrix4fv(glGetUniformLocation(s->ao, "u_inv"), 1, GL_FALSE, inv);
    glUniform3fv(glGetUniformLocation(s->ao, "u_ex"), 1, sv->ex);
    glUniform3fv(glGetUniformLocation(s->ao, "u_ey"), 1, sv->ey);
    glUniform3fv(glGetUniformLocation(s->ao, "u_vdir"), 1, sv->vdir);
    glUniform1f(glGetUniformLocation(s->ao, "u_texel1"), sv->texel1);
    glUniform2fv(glGetUniformLocation(s->ao, "u_dir"), 4 * VT_SSAO_SLICES, &dir[0][0]);
    vt_gl_target_bind(s->half);
    glDrawArrays(GL_TRIANGLES, 0, 3);
    /* the upsample */
    set_common(s->up, sv);
    glUniform1f(glGetUniformLocation(s->up, "u_ntol"), sv->ntol);
    glActiveTexture(GL_TEXTURE0 + HALF_UNIT);
    glBindTexture(GL_TEXTURE_2D, vt_gl_target_color_texture(s->half));
    vt_gl_target_bind(s->full);
    glDrawArrays(GL_TRIANGLES, 0, 3);
    /* the shading passes read the result; the inputs are let go (pass 1's
       colour is drawn into next) */
    glBindTexture(GL_TEXTURE_2D, 0);
    glActiveTexture(GL_TEXTURE0 + IN_UNIT);
    glBindTexture(GL_TEXTURE_2D, 0);
    glActiveTexture(GL_TEXTURE0 + AO_UNIT);
    glBindTexture(GL_TEXTURE_2D, vt_gl_target_color_texture(s->full));
    glEnable(GL_DEPTH_TEST);
    glEnable(GL_CULL_FACE);
    GLenum e = glGetError();
    return e == GL_NO_ERROR ? 0 : vp_errf(err, errlen, VT_ERR_GL, "ambient occlusion: GL error 0x%x", e);
}

void vt_glssao_use(unsigned prog, bool on)
{
    glUseProgram(prog);
    glUniform1i(glGetUniformLocation(prog, "u_ao_on"), on);
}
