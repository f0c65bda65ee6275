/*
 * vt_gldraw_glsl.c — the OpenGL renderer's shaders (vt_gldraw.c builds
 * them): the scene's vertex and fragment shaders and the background pass
 * (the ground plane solved per pixel, the sky), over one shared part: the
 * material of vt_scene.c's vt_surface_params, the sky's ambient and the
 * sun of vt_shade.inl's env_light, the sky (an environment map or the
 * analytic sky's table), fog, operation for operation as the software
 * renderer computes them (in float, camera-relative).
 */
#include "vt_gldraw_internal.h"

#define STR_(x) #x
#define STR(x) STR_(x)

/* What both fragment shaders share: the environment and the surface. */
#define COMMON                                                                                                 \
    "#define PI 3.14159265\n"                                                                                  \
    "uniform int u_env_on, u_sun_on, u_sky_mode;\n"                                                            \
    "uniform vec3 u_sun_dir, u_sun, u_amb_up, u_amb_down, u_fog, u_sky;\n"                                     \
    "uniform float u_fog_density, u_fog_falloff, u_fog_y0, u_sky_rot;\n"                                       \
    "uniform sampler2D u_sky_tex;\n"                                                                           \
    "float ambient_occlusion();\n"                                                                             \
    "uniform int u_mat_on, u_alpha_mask, u_tex_on, u_has_uv, u_has_t;\n"                                       \
    "uniform vec4 u_base;\n"                                                                                   \
    "uniform vec2 u_mr;\n"                                                                                     \
    "uniform vec3 u_em;\n"                                                                                     \
    "uniform float u_nscale, u_cutoff;\n"                                                                      \
    "uniform vec4 u_txm[4];\n"                                                                                 \
    "uniform vec2 u_txo[4];\n"                                                                                 \
    "uniform sampler2D u_tex0, u_tex1, u_tex2, u_tex3;\n"                                                      \
    /* vt_brdf_glsl.c's object */                                                                             \
    "uniform int u_ibl_on;\n"                                                                                  \
    "float vt_rough(float r);\n"                                                                               \
    "vec3 vt_pbr_brdf(vec3 n, vec3 v, vec3 l, vec3 diffuse, vec3 f0, float a2);\n"                             \
    "vec3 vt_pbr_ambient(vec3 n, vec3 v, vec3 diffuse, vec3 f0, float rough);\n"                               \
    "vec2 txf(int k, vec2 uv) {\n"                                                                             \
    "  return u_txo[k] + vec2(u_txm[k].x * uv.x + u_txm[k].y * uv.y, u_txm[k].z * uv.x + u_txm[k].w * uv.y);\n" \
    "}\n"                                                                                                      \
    "vec3 sky_radiance(vec3 d) {\n"                                                                            \
    "  if (u_sky_mode == 0) return u_sky;\n"                                                                   \
    /* the environment map or the analytic sky's table, bilinear as vt_sky_radiance */                       \
    "  {\n"                                                                                                    \
    "    ivec2 sz = textureSize(u_sky_tex, 0);\n"                                                              \
    "    float u = 0.5 + (atan(d.x, -d.z) + u_sky_rot) * (0.5 / PI);\n"                                        \
    "    float v = acos(clamp(d.y, -1.0, 1.0)) * (1.0 / PI);\n"                                                \
    "    u -= floor(u);\n"                                                                                     \
    "    float x = u * float(sz.x) - 0.5, y = v * float(sz.y) - 0.5, x0 = floor(x), y0 = floor(y);\n"          \
    "    float ax = x - x0, ay = y - y0;\n"                                                                    \
    "    int i0 = int(x0), i1 = i0 + 1, j0 = clamp(int(y0), 0, sz.y - 1), j1 = clamp(int(y0) + 1, 0, sz.y - 1);\n" \
    "    i0 = ((i0 % sz.x) + sz.x) % sz.x; i1 = ((i1 % sz.x) + sz.x) % sz.x;\n"                                \
    "    vec3 a = texelFetch(u_sky_tex, ivec2(i0, j0), 0).rgb, b = texelFetch(u_sky_tex, ivec2(i1, j0), 0).rgb;\n" \
    "    vec3 e = texelFetch(u_sky_tex, ivec2(i0, j1), 0).rgb, f = texelFetch(u_sky_tex, ivec2(i1, j1), 0).rgb;\n" \
    "    vec3 top = a + ax * (b - a), bot = e + ax * (f - e);\n"                                               \
    "    return (top + ay * (bot - top)) * u_sky;\n"                                                           \
    "  }\n"                                                                                                    \
    "}\n"                                                                                                      \
    "vec3 fog_apply(vec3 p, vec3 c) {\n"                                                                       \
    "  if (u_env_on == 0 || !(u_fog_density > 0.0)) return c;\n"                                              \
    "  float L = length(p), k = u_fog_falloff, od;\n"                                                          \
    "  if (k > 0.0) {\n"                                                                                       \
    "    float e0 = exp(min(k * u_fog_y0, 80.0)), kd = k * p.y;\n"                                             \
    "    float g = abs(kd) > 1e-4 ? (1.0 - exp(-kd)) / kd : 1.0 - 0.5 * kd;\n"                                 \
    "    od = u_fog_density * e0 * L * g;\n"                                                                   \
    "  } else od = u_fog_density * L;\n"                                                                       \
    "  float T = exp(-max(od, 0.0));\n"                                                                        \
    "  return c * T + u_fog * (1.0 - T);\n"                                                                    \
    "}\n"                                                                                                      \
    "float base_alpha(vec2 uv) {\n"                                                                            \
    "  float a = u_mat_on != 0 ? u_base.a : 1.0;\n"                                                            \
    "  if ((u_tex_on & 1) != 0 && u_has_uv != 0) a *= texture(u_tex0, txf(0, uv)).a;\n"                        \
    "  return a;\n"                                                                                            \
    "}\n"                                                                                                      \
    /* vt_surface_params: the material at a point (n normalised and mapped) */                                \
    "void params(inout vec3 n, vec4 t, vec2 uv, vec3 albedo, out vec3 diffuse, out vec3 f0, out vec3 em,\n"     \
    "            out float a2, out float ro) {\n"                                                               \
    "  vec4 base = u_mat_on != 0 ? u_base : vec4(albedo, 1.0);\n"                                              \
    "  float metal = u_mat_on != 0 ? u_mr.x : 0.0, rough = u_mat_on != 0 ? u_mr.y : 0.6;\n"                    \
    "  em = u_mat_on != 0 ? u_em : vec3(0.0);\n"                                                               \
    "  float nl = length(n);\n"                                                                                \
    "  n = nl > 0.0 ? n / nl : vec3(0.0);\n"                                                                   \
    "  if (u_mat_on != 0 && u_has_uv != 0) {\n"                                                                \
    "    if ((u_tex_on & 1) != 0) base *= texture(u_tex0, txf(0, uv));\n"                                      \
    "    if ((u_tex_on & 2) != 0) { vec4 m = texture(u_tex1, txf(1, uv)); rough *= m.g; metal *= m.b; }\n"     \
    "    if ((u_tex_on & 8) != 0) em *= texture(u_tex3, txf(3, uv)).rgb;\n"                                    \
    "    if ((u_tex_on & 4) != 0 && u_has_t != 0) {\n"                                                         \
    "      vec4 sm = texture(u_tex2, txf(2, uv));\n"                                                           \
    "      vec3 tn = vec3((2.0 * sm.r - 1.0) * u_nscale, (2.0 * sm.g - 1.0) * u_nscale, 2.0 * sm.b - 1.0);\n" \
    "      vec3 T = t.xyz - dot(t.xyz, n) * n;\n"                                                              \
    "      float tl = length(T);\n"                                                                            \
    "      T = tl > 0.0 ? T / tl : vec3(0.0);\n"                                                               \
    "      vec3 B = (t.w < 0.0 ? -1.0 : 1.0) * cross(n, T);\n"                                                 \
    "      vec3 nn = tn.x * T + tn.y * B + tn.z * n;\n"                                                        \
    "      float l2 = length(nn);\n"                                                                           \
    "      if (l2 > 0.0) n = nn / l2;\n"                                                                       \
    "    }\n"                                                                                                  \
    "  }\n"                                                                                                    \
    "  diffuse = base.rgb * (1.0 - metal);\n"                                                                  \
    "  f0 = 0.04 * (1.0 - metal) + base.rgb * metal;\n"                                                        \
    "  ro = vt_rough(rough);\n"                                                                                \
    "  float a = ro * ro;\n"                                                                                   \
    "  a2 = a * a;\n"                                                                                          \
    "}\n"                                                                                                      \
    /* vt_shade.inl's env_light: the sky's ambient and the sun */                                             \
    "float sun_visibility(vec3 p, vec3 n);\n" /* the shadow cascades (vt_shadow_gl.c) */                     \
    "vec3 env_light(vec3 p, vec3 n, vec3 diffuse, vec3 f0, vec3 em, float a2, float ro) {\n"                   \
    "  if (u_env_on == 0) return " STR(VT_AMBIENT) " * diffuse + em;\n"                                        \
    "  float pl = length(p);\n"                                                                                \
    "  vec3 v = pl > 0.0 ? -p / pl : vec3(0.0);\n"                                                             \
    "  float ao = ambient_occlusion();\n" /* vt_ssao_gl.c: 1 without the pass */                                \
    "  vec3 c;\n"                                                                                              \
    "  if (u_ibl_on != 0) c = vt_pbr_ambient(n, v, diffuse, f0, ro) * ao + em;\n"                              \
    "  else {\n"                                                                                               \
    "    float nv = dot(n, v), ry = 2.0 * nv * n.y - v.y, g = 1.0 - ro;\n"                                     \
    "    float ka = 0.5 * n.y + 0.5, kr = 0.5 * clamp(ry, -1.0, 1.0) + 0.5;\n"                                 \
    "    float fv = 1.0 - max(nv, 0.0), fv2 = fv * fv, wf = fv2 * fv2 * fv * (g * g);\n"                       \
    "    vec3 d = u_amb_up - u_amb_down, la = ka * d + u_amb_down, lr = kr * d + u_amb_down;\n"                 \
    "    vec3 fr = (1.0 - f0) * wf + f0;\n"                                                                    \
    "    c = diffuse * la * ao + (fr * lr * ao + em);\n"                                                       \
    "  }\n"                                                                                                    \
    "  if (u_sun_on == 0) return c;\n"                                                                         \
    "  return c + u_sun * (max(dot(n, u_sun_dir), 0.0) * sun_visibility(p, n)) * vt_pbr_brdf(n, v, u_sun_dir, diffuse, f0, a2);\n" \
    "}\n"

const char *const vt_gldraw_vs =
    "#version 330 core\n"
    "layout(location = 0) in vec3 a_pos;\n"
    "layout(location = 1) in vec3 a_nrm;\n"
    "layout(location = 2) in vec3 a_scale;\n"
    "layout(location = 3) in vec3 a_shift;\n"
    "layout(location = 4) in vec3 a_albedo;\n"
    "layout(location = 5) in float a_mask;\n"
    "layout(location = 6) in vec4 a_quat;\n"
    "layout(location = 7) in vec2 a_uv;\n"
    "layout(location = 8) in vec4 a_tan;\n"
    "uniform mat4 u_vp;\n"
    "uniform vec4 u_d;\n" /* nearness numerator row */
    "invariant gl_Position;\n" /* pass 2 tests against pass 1's depth */
    "invariant out vec3 v_p;\n"
    "out vec3 v_n;\n"
    "out vec4 v_t;\n"
    "out vec2 v_uv;\n"
    "flat out vec3 v_albedo;\n"
    "flat out int v_mask;\n"
    "out float v_dp;\n"
    "vec3 qrot(vec4 q, vec3 v) { vec3 t = 2.0 * cross(q.xyz, v); return v + q.w * t + cross(q.xyz, t); }\n"
    "void main() {\n"
    "  vec3 p = qrot(a_quat, a_pos * a_scale) + a_shift;\n"
    "  vec3 s = vec3(a_scale.x != 0.0 ? a_scale.x : 1.0, a_scale.y != 0.0 ? a_scale.y : 1.0,\n"
    "                a_scale.z != 0.0 ? a_scale.z : 1.0);\n"
    "  v_p = p;\n"
    "  v_n = qrot(a_quat, a_nrm / s);\n"
    "  vec3 tt = qrot(a_quat, a_tan.xyz * a_scale);\n"
    "  float tl = length(tt);\n"
    "  bool mir = a_scale.x * a_scale.y * a_scale.z < 0.0;\n"
    "  v_t = vec4(tl > 0.0 ? tt / tl : vec3(0.0), (a_tan.w < 0.0) != mir ? -1.0 : 1.0);\n"
    "  v_uv = a_uv;\n"
    "  v_albedo = a_albedo;\n"
    "  v_mask = int(a_mask);\n"
    "  vec4 c = u_vp * vec4(p, 1.0);\n"
    "  v_dp = dot(u_d, vec4(p, 1.0));\n"
    "  gl_Position = c;\n"
    "}\n";

const char *const vt_gldraw_fs =
    "#version 330 core\n"
    "#define VT_MASK_INTERIOR " STR(VT_MASK_INTERIOR) "\n"
    "#define VT_MASK_CHAR " STR(VT_MASK_CHAR) "\n"
    "invariant in vec3 v_p;\n"
    "in vec3 v_n;\n"
    "in vec4 v_t;\n"
    "in vec2 v_uv;\n"
    "flat in vec3 v_albedo;\n"
    "flat in int v_mask;\n"
    "in float v_dp;\n"
    "uniform int u_pass;\n"
    "uniform int u_tiles_x;\n"
    "uniform int u_two_sided;\n"
    "uniform samplerBuffer u_lights;\n"   /* 4 texels a light */
    "uniform usamplerBuffer u_offset;\n"
    "uniform usamplerBuffer u_index;\n"
    "uniform usamplerBuffer u_mhead;\n"  /* MASK_TEXELS texels a mask: float bits, then integers */
    "uniform samplerBuffer u_mfield;\n"
    "out vec4 o_color;\n"
    COMMON
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
    "  if (u_alpha_mask != 0 && base_alpha(v_uv) < u_cutoff) discard;\n"
    "  float k = 1.0;\n"
    "  if (v_mask >= 0) {\n"
    "    float ib, e = mask_eval(v_mask, v_p, ib);\n"
    "    if (e < 0.0) discard;\n"
    "    if (u_pass == 0) { o_color = vec4(0.0, 0.0, 0.0, v_near); return; }\n"
    "    k = e * ib;\n"
    "    if (!gl_FrontFacing) { nv = -nv; if (u_env_on == 0) albedo *= VT_MASK_INTERIOR; }\n"
    "    if (k < 1.0) {\n"
    "      k = max(k, 0.0);\n"
    "      k = VT_MASK_CHAR + (1.0 - VT_MASK_CHAR) * (k * k * (3.0 - 2.0 * k));\n"
    "    } else k = 1.0;\n"
    "    albedo *= k;\n"
    "  } else if (u_two_sided != 0 && !gl_FrontFacing) nv = -nv;\n"
    "  if (u_pass == 0) { o_color = vec4(0.0, 0.0, 0.0, v_near); return; }\n"
    "  vec3 n = nv, diffuse, f0, em;\n"
    "  float a2, ro;\n"
    "  params(n, v_t, v_uv, albedo, diffuse, f0, em, a2, ro);\n"
    "  if (u_mat_on != 0) { diffuse *= k; f0 *= k; em *= k; }\n"
    "  vec3 c = env_light(v_p, n, diffuse, f0, em, a2, ro);\n"
    "  vec3 vd = normalize(-v_p);\n"
    "  ivec2 tp = ivec2(gl_FragCoord.xy) / 16;\n"
    "  int t = tp.y * u_tiles_x + tp.x;\n"
    "  int k0 = int(texelFetch(u_offset, t).r), k1 = int(texelFetch(u_offset, t + 1).r);\n"
    "  for (int q = k0; q < k1; q++) {\n"
    "    int li = int(texelFetch(u_index, q).r) * 4;\n"
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
    "    c += q1.xyz * (att * ndl) * vt_pbr_brdf(n, vd, l, diffuse, f0, a2);\n"
    "  }\n"
    "  o_color = vec4(fog_apply(v_p, c), v_near);\n"
    "}\n";

/* The background: one triangle over the viewport; per pixel the ground's
 * hit (vt_ground_hit) with its depth, else the sky at the far plane. */
const char *const vt_gldraw_bg_vs =
    "#version 330 core\n"
    "void main() {\n"
    "  vec2 p = vec2(gl_VertexID == 1 ? 3.0 : -1.0, gl_VertexID == 2 ? 3.0 : -1.0);\n"
    "  gl_Position = vec4(p, 0.0, 1.0);\n"
    "}\n";

const char *const vt_gldraw_bg_fs =
    "#version 330 core\n"
    "uniform int u_pass, u_ground, u_depth_half, u_reversed;\n"
    "uniform vec2 u_size;\n"
    "uniform vec4 u_rx, u_ry, u_rz, u_rw, u_rn, u_rd;\n"
    "uniform float u_ground_y;\n"
    "uniform vec3 u_ground_albedo;\n"
    "uniform vec2 u_ground_uv0;\n"
    "out vec4 o_color;\n"
    COMMON
    "bool ground(vec2 ndc, out vec3 q, out float near, out float depth) {\n"
    "  vec4 A = u_rx - ndc.x * u_rw, B = u_ry - ndc.y * u_rw;\n"
    "  float det = A.x * B.z - A.z * B.x, h = u_ground_y;\n"
    "  if (u_ground == 0 || det == 0.0) return false;\n"
    "  float ra = -A.w - A.y * h, rb = -B.w - B.y * h;\n"
    "  q = vec3((ra * B.z - A.z * rb) / det, h, (A.x * rb - ra * B.x) / det);\n"
    "  vec4 q1 = vec4(q, 1.0);\n"
    "  float cz = dot(u_rz, q1), cw = dot(u_rw, q1), nf = dot(u_rn, q1);\n"
    "  if (!(nf >= 0.0) || !(cw > 0.0)) return false;\n"
    "  if (!((u_reversed != 0 ? cz : cw - cz) >= 0.0)) return false;\n"
    "  near = dot(u_rd, q1) / cw;\n"
    "  depth = u_depth_half != 0 ? 0.5 * cz / cw + 0.5 : cz / cw;\n"
    "  return true;\n"
    "}\n"
    "void main() {\n"
    "  vec2 ndc = gl_FragCoord.xy / u_size * 2.0 - 1.0;\n"
    "  vec3 q; float near, depth;\n"
    "  if (ground(ndc, q, near, depth)) {\n"
    "    gl_FragDepth = depth;\n"
    "    if (u_pass == 0) { o_color = vec4(0.0, 0.0, 0.0, near); return; }\n"
    "    vec3 n = vec3(0.0, 1.0, 0.0), diffuse, f0, em;\n"
    "    float a2, ro;\n"
    "    params(n, vec4(0.0), u_ground_uv0 + q.xz, u_ground_albedo, diffuse, f0, em, a2, ro);\n"
    "    vec3 c = env_light(q, n, diffuse, f0, em, a2, ro);\n"
    "    o_color = vec4(fog_apply(q, c), near);\n"
    "    return;\n"
    "  }\n"
    "  if (u_pass == 0) discard;\n"
    "  gl_FragDepth = u_reversed != 0 ? 0.0 : 1.0;\n"
    "  vec3 a = vec3(u_rx.x - ndc.x * u_rw.x, u_rx.y - ndc.x * u_rw.y, u_rx.z - ndc.x * u_rw.z);\n"
    "  vec3 b = vec3(u_ry.x - ndc.y * u_rw.x, u_ry.y - ndc.y * u_rw.y, u_ry.z - ndc.y * u_rw.z);\n"
    "  vec3 d = cross(a, b);\n"
    "  float l = length(d);\n"
    "  d = l > 0.0 ? d / l * (dot(d, u_rn.xyz) < 0.0 ? -1.0 : 1.0) : vec3(0.0);\n"
    "  o_color = vec4(sky_radiance(d), " STR(VT_EMPTY_GLSL) ");\n"
    "}\n";
