/*
 * test_brdf.c — the shading model (render/vt_brdf.[ch], vt_shade.inl,
 * vt_brdf_glsl.c) against independent models:
 *   - D, V, F and the whole BRDF f against the glTF 2.0 specification's
 *     Appendix B written out here in long double, over random inputs with
 *     grazing angles and the rough and smooth extremes;
 *   - the split-sum DFG table against a slow quadrature over the
 *     hemisphere of that long-double BRDF;
 *   - the sun and a point light on a flat quad through both renderers,
 *     each pixel against the reference BRDF at its own view direction;
 *   - the white furnace: a white, fully rough quad under a uniform white
 *     sky (no sun, no ground, no fog, a fixed exposure undone) returns <= 1
 *     and within 3 % of the hemispherical integral of the BRDF (the
 *     quadrature; a Lambert surface checks the quadrature itself), in both
 *     renderers; a smooth and a half-rough metal under the same sky
 *     against F(n.v) and the quadrature (energy).
 */
#include "test_util.h"

#include "occ_ref.h"
#include "vt_brdf.h"
#include "vt_gldraw.h"
#include "vt_soft.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

typedef long double ld;
#define PI_L 3.141592653589793238462643383279502884L

/* ---- the reference: the specification's Appendix B, in long double ------------------ */

/* D = alpha^2 chi(n.h) / (pi ((n.h)^2 (alpha^2 - 1) + 1)^2) */
static ld ref_d(ld ndh, ld a2)
{
    if (!(ndh > 0)) return 0;
    ld t = ndh * ndh * (a2 - 1) + 1;
    return a2 / (PI_L * t * t);
}

/* V = chi(h.l) chi(h.v) / ((|n.l| + sqrt(a2 + (1 - a2)(n.l)^2)) (|n.v| + sqrt(a2 + (1 - a2)(n.v)^2))) */
static ld ref_v(ld ndl, ld ndv, ld a2)
{
    ndl = fabsl(ndl), ndv = fabsl(ndv);
    return 1 / ((ndl + sqrtl(a2 + (1 - a2) * ndl * ndl)) * (ndv + sqrtl(a2 + (1 - a2) * ndv * ndv)));
}

/* F = f0 + (1 - f0)(1 - |v.h|)^5 */
static ld ref_f(ld f0, ld vdh)
{
    ld k = 1 - fabsl(vdh);
    return f0 + (1 - f0) * (k * k * k * k * k);
}

static ld dotl(const ld a[3], const ld b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* The implementation section: c_diff = lerp(base, black, metallic),
   f0 = lerp(0.04, base, metallic), alpha = roughness^2,
   f = (1 - F) c_diff / pi + F D V, for n.l > 0; from its dot products. */
static ld ref_brdf_dots(ld ndl, ld ndv, ld ndh, ld vdh, ld base, ld metal, ld rough)
{
    ld a = rough * rough, a2 = a * a;
    if (!(ndl > 0)) return 0;
    ld f0 = 0.04L + (base - 0.04L) * metal, F = ref_f(f0, vdh);
    return (1 - F) * base * (1 - metal) / PI_L + F * ref_d(ndh, a2) * ref_v(ndl, ndv, a2);
}

static void ref_brdf(const ld n[3], const ld v[3], const ld l[3], const ld base[3], ld metal, ld rough, ld out[3])
{
    ld h[3] = {l[0] + v[0], l[1] + v[1], l[2] + v[2]}, hl = sqrtl(dotl(h, h));
    for (int c = 0; c < 3; c++) out[c] = 0;
    if (!(hl > 0)) return;
    for (int k = 0; k < 3; k++) h[k] /= hl;
    for (int c = 0; c < 3; c++) out[c] = ref_brdf_dots(dotl(n, l), dotl(n, v), dotl(n, h), dotl(v, h), base[c], metal, rough);
}

/* The integral of f(v, l) (n.l) over the hemisphere about n (channel 0; a
   grey base): the midpoint rule in (theta, phi) with n_t x 2 n_t cells,
   in double for speed (the cells' sums are far below double's 1e-16).
   lambert: a Lambert BRDF of albedo 1 instead, whose integral is 1. */
static double env_grad(const double d[3]);
static double hemi_integral_env(const double n[3], const double v[3], double base, double metal, double rough,
                                int n_t, bool lambert, bool grad);
static double hemi_integral(const double n[3], const double v[3], double base, double metal, double rough, int n_t,
                            bool lambert)
{
    return hemi_integral_env(n, v, base, metal, rough, n_t, lambert, false);
}

/* The same under the environment env_grad where grad. */
static double hemi_integral_env(const double n[3], const double v[3], double base, double metal, double rough,
                                int n_t, bool lambert, bool grad)
{
    /* a frame about n */
    double t[3] = {1, 0, 0};
    if (fabs(n[0]) > 0.9) t[0] = 0, t[1] = 1;
    double d = t[0] * n[0] + t[1] * n[1] + t[2] * n[2];
    for (int k = 0; k < 3; k++) t[k] -= d * n[k];
    double tl = sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]);
    for (int k = 0; k < 3; k++) t[k] /= tl;
    double b[3] = {n[1] * t[2] - n[2] * t[1], n[2] * t[0] - n[0] * t[2], n[0] * t[1] - n[1] * t[0]};
    const int n_p = 2 * n_t;
    const double dt = M_PI / 2 / n_t, dp = 2 * M_PI / n_p;
    ld nl[3] = {n[0], n[1], n[2]}, vl[3] = {v[0], v[1], v[2]}, bl[3] = {base, base, base};
    double sum = 0;
    for (int i = 0; i < n_t; i++) {
        double th = (i + 0.5) * dt, st = sin(th), ct = cos(th), row = 0;
        for (int j = 0; j < n_p; j++) {
            double ph = (j + 0.5) * dp, cp = cos(ph), sp = sin(ph);
            ld l[3], o[3];
            for (int k = 0; k < 3; k++) l[k] = st * cp * t[k] + st * sp * b[k] + ct * n[k];
            double L = 1;
            if (grad) {
                double ld3[3] = {(double)l[0], (double)l[1], (double)l[2]};
                L = env_grad(ld3);
            }
            if (lambert) {
                row += L * ct / M_PI;
                continue;
            }
            ref_brdf(nl, vl, l, bl, metal, rough, o);
            row += (double)o[0] * ct * L;
        }
        sum += row * st * dt * dp;
    }
    return sum;
}

/* ---- (a) the BRDF against the reference ------------------------------------------- */

static void unit_near(rng *r, const double n[3], double min_cos, double out[3])
{
    /* a random unit vector within the hemisphere of n, n.out >= min_cos;
       a third of them grazing (n.out < 0.02) */
    for (;;) {
        double c = rng_f(r) < 0.33 ? rng_range(r, min_cos, 0.02) : rng_range(r, min_cos, 1), s = sqrt(1 - c * c);
        double t[3] = {rng_range(r, -1, 1), rng_range(r, -1, 1), rng_range(r, -1, 1)};
        double d = t[0] * n[0] + t[1] * n[1] + t[2] * n[2];
        for (int k = 0; k < 3; k++) t[k] -= d * n[k];
        double tl = sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]);
        if (tl < 1e-3) continue;
        for (int k = 0; k < 3; k++) out[k] = c * n[k] + s * t[k] / tl;
        return;
    }
}

static void test_brdf_terms_against_spec(void **state)
{
    (void)state;
    rng r = {test_seed() ^ 0xB4DFu};
    /* D, V, F from float inputs, the reference in long double from the same
       floats: what is left is the float evaluation's rounding. D's t is
       (1 - n.h)(1 + n.h) + n.h^2 a2 in float: (1 - n.h) exact (Sterbenz)
       where n.h >= 0.5 (t >= 0.75 below), each other step one rounding of
       a positive term: t within 4 ulp, t^2 8, the quotient 10: 1e-6 < 2e-6.
       V: sums of positives and square roots, 8 roundings: 2e-6. F: 1 -
       |v.h| exact for v.h >= 0.5 else well away from 0, then 6 roundings. */
    double worst[3] = {0, 0, 0};
    for (int i = 0; i < 200000; i++) {
        int kind = i % 4; /* the smooth and rough extremes, and between */
        float rough = kind == 0 ? VT_MIN_ROUGHNESS : kind == 1 ? 1.0f : (float)rng_range(&r, VT_MIN_ROUGHNESS, 1);
        float a = rough * rough, a2 = a * a;
        float ndh = (float)(i % 3 == 0 ? 1 - rng_log(&r, 1e-7, 1) : rng_f(&r));
        float ndl = (float)(i % 5 == 0 ? rng_log(&r, 1e-6, 0.02) : rng_f(&r));
        float ndv = (float)(i % 7 == 0 ? rng_log(&r, 1e-6, 0.02) : rng_f(&r));
        float vdh = (float)rng_f(&r), f0 = (float)rng_f(&r);
        ld d = ref_d(ndh, a2), v = ref_v(ndl, ndv, a2), f = ref_f(f0, vdh);
        double e[3] = {d > 0 ? (double)fabsl((vt_brdf_d(ndh, a2) - d) / d) : fabs(vt_brdf_d(ndh, a2)),
                       (double)fabsl((vt_brdf_v(ndl, ndv, a2) - v) / v), (double)fabsl((vt_brdf_f(f0, vdh) - f) / f)};
        for (int k = 0; k < 3; k++)
            if (e[k] > worst[k]) worst[k] = e[k];
    }
    fprintf(stderr, "BRDF terms against the spec in long double (200000 inputs): D %.3g, V %.3g, F %.3g relative\n",
            worst[0], worst[1], worst[2]);
    assert_true(worst[0] < 2e-6);
    assert_true(worst[1] < 2e-6);
    assert_true(worst[2] < 2e-6);
}

static void test_brdf_against_spec(void **state)
{
    (void)state;
    rng r = {test_seed() ^ 0xB4E0u};
    /* the whole f from float unit vectors: the reference takes the same
       floats, so the only differences are the float evaluation's (1e-6,
       above) and its dot products: a float dot product of unit vectors is
       within 3 roundings of 1 (3 x 6e-8: 3e-7 taken), n.h and v.h of the
       float-normalised h within 4e-7 more where |l + v| is small (l + v
       cancels). D is steep in n.h where it peaks on a smooth surface (d
       ln D / d n.h up to 1e6), V in a grazing n.l or n.v (about -1 / x):
       the bound is 1e-5 relative plus twice the reference's own spread
       over those errors in each dot product. */
    double worst = 0;
    uint32_t n = 0;
    for (int i = 0; i < 100000; i++) {
        double nd[3] = {rng_range(&r, -1, 1), rng_range(&r, -1, 1), rng_range(&r, -1, 1)};
        double nl = sqrt(nd[0] * nd[0] + nd[1] * nd[1] + nd[2] * nd[2]);
        if (nl < 0.1) continue;
        for (int k = 0; k < 3; k++) nd[k] /= nl;
        double vd[3], ldir[3];
        unit_near(&r, nd, 1e-4, vd);
        if (i % 8 == 0) { /* near the mirror direction: the smooth peak */
            double c = vd[0] * nd[0] + vd[1] * nd[1] + vd[2] * nd[2];
            for (int k = 0; k < 3; k++) ldir[k] = 2 * c * nd[k] - vd[k] + rng_range(&r, -1e-3, 1e-3);
            double ll = sqrt(ldir[0] * ldir[0] + ldir[1] * ldir[1] + ldir[2] * ldir[2]);
            for (int k = 0; k < 3; k++) ldir[k] /= ll;
        } else {
            unit_near(&r, nd, 1e-4, ldir);
        }
        int kind = i % 4;
        float rough = kind == 0 ? VT_MIN_ROUGHNESS : kind == 1 ? 1.0f : (float)rng_range(&r, VT_MIN_ROUGHNESS, 1);
        float metal = i % 3 == 0 ? 0.0f : i % 3 == 1 ? 1.0f : (float)rng_f(&r);
        float base[3] = {(float)rng_f(&r), (float)rng_f(&r), (float)rng_f(&r)};
        float fn[3], fv[3], fl[3], out[3];
        ld Ln[3], Lv[3], Ll[3], Lb[3], want[3];
        for (int k = 0; k < 3; k++) {
            fn[k] = (float)nd[k], fv[k] = (float)vd[k], fl[k] = (float)ldir[k];
            Ln[k] = fn[k], Lv[k] = fv[k], Ll[k] = fl[k], Lb[k] = base[k];
        }
        if (!(dotl(Ln, Ll) > 1e-5L)) continue;
        vt_brdf_eval(fn, fv, fl, base, metal, rough, out);
        ref_brdf(Ln, Lv, Ll, Lb, metal, rough, want);
        /* the reference's sensitivity to each dot product: the spread of
           f over +-delta in each (delta: 3e-7 for n.l, n.v; 4e-7 over
           |l + v| / 2 for n.h, v.h through the float-normalised h) */
        ld h[3] = {Ll[0] + Lv[0], Ll[1] + Lv[1], Ll[2] + Lv[2]}, hl = sqrtl(dotl(h, h));
        for (int k = 0; k < 3; k++) h[k] /= hl;
        ld dots[4] = {dotl(Ln, Ll), dotl(Ln, Lv), dotl(Ln, h), dotl(Lv, h)};
        ld dh = 4e-7L * (hl < 2 ? 2 / hl : 1), delta[4] = {3e-7L, 3e-7L, dh, dh};
        for (int c = 0; c < 3; c++) {
            ld spread = 0;
            for (int k = 0; k < 4; k++) {
                ld up[4], dn[4];
                memcpy(up, dots, sizeof up);
                memcpy(dn, dots, sizeof dn);
                up[k] = fminl(up[k] + delta[k], 1), dn[k] -= delta[k]; /* one-sided: n.h may be at D's peak */
                ld fu = ref_brdf_dots(up[0], up[1], up[2], up[3], Lb[c], metal, rough);
                ld fd = ref_brdf_dots(dn[0], dn[1], dn[2], dn[3], Lb[c], metal, rough);
                spread += fmaxl(fabsl(fu - want[c]), fabsl(fd - want[c]));
            }
            ld tol = 1e-5L * want[c] + 2 * spread + 1e-30L;
            double e = (double)(fabsl(out[c] - want[c]) / tol);
            if (e > worst) worst = e;
        }
        n++;
    }
    fprintf(stderr, "BRDF f against the spec in long double (%u inputs): worst error %.3g of the bound\n", n, worst);
    assert_true(n > 50000);
    assert_true(worst <= 1);
}

/* ---- the DFG table against quadrature ---------------------------------------------- */

static void test_brdf_dfg_table(void **state)
{
    (void)state;
    /* f0 A + B is the integral of F D V cos: with a grey base, metallic 1
       and base 0 / 1 the quadrature gives B and A + B; C is the diffuse's
       integral with c_diff = 1: metallic 0, base 1 gives 0.96 C + 0.04 A +
       B. The table's 1024 importance samples and the bilinear lookup
       between grid points: within 0.01 absolute (a quadrature of 200 x
       400 cells: 1e-4 on these smooth, rough >= 0.3 integrands). */
    const float pts[][2] = {{1, 0.3f}, {0.9f, 0.5f}, {0.5f, 0.5f}, {0.2f, 0.7f}, {0.7f, 1}, {0.1f, 1}, {0.35f, 0.85f}};
    double worst = 0;
    for (size_t i = 0; i < sizeof pts / sizeof pts[0]; i++) {
        double nv = pts[i][0], n[3] = {0, 0, 1}, v[3] = {sqrt(1 - nv * nv), 0, nv};
        double B = hemi_integral(n, v, 0, 1, pts[i][1], 200, false);
        double AB = hemi_integral(n, v, 1, 1, pts[i][1], 200, false);
        double W = hemi_integral(n, v, 1, 0, pts[i][1], 200, false);
        float t[3];
        vt_dfg((float)nv, pts[i][1], t);
        double e[3] = {fabs(t[1] - B), fabs(t[0] + t[1] - AB), fabs(0.96 * t[2] + 0.04 * t[0] + t[1] - W)};
        fprintf(stderr, "DFG at n.v %.2f, roughness %.2f: A %.4f B %.4f C %.4f; quadrature A %.4f B %.4f, white %.4f\n",
                nv, pts[i][1], t[0], t[1], t[2], AB - B, B, W);
        for (int k = 0; k < 3; k++)
            if (e[k] > worst) worst = e[k];
    }
    assert_true(worst < 0.01);
}

/* ---- renders --------------------------------------------------------------------- */

static const float quad_pos[12] = {-1, -1, 0, 1, -1, 0, 1, 1, 0, -1, 1, 0};
static const float quad_nrm[12] = {0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1};
static const uint32_t quad_idx[6] = {0, 1, 2, 0, 2, 3};

#define RW 48u
#define RH 36u

typedef struct rig {
    cull_view v;
    occ_ref ref;
    double pos[3], n[3], u[3];   /* the quad's centre, normal, horizontal axis */
    double half;                 /* its half size */
    float rgba[RW * RH * 4], depth[RW * RH];
} rig;

/* A camera at the origin looking down -z at a 2 half-wide quad 5 m away
   turned by tilt about y: n.v about cos(tilt) at its centre. */
static void rig_make(rig *g, double tilt)
{
    cull_view_desc d = {.depth_mode = CULL_DEPTH_ZERO_ONE, .viewport_w = RW, .viewport_h = RH};
    double proj[16], view[16], dir[3] = {0, 0, -1}, up[3] = {0, 1, 0};
    cull_mat_perspective(proj, 0.8, (double)RW / RH, 0.1, 100, CULL_DEPTH_ZERO_ONE);
    cull_mat_look_dir(view, dir, up);
    cull_mat_mul(d.view_proj, proj, view);
    assert_int_equal(cull_view_init(&g->v, &d), CULL_OK);
    assert_int_equal(occ_ref_init(&g->ref, &g->v, RW, RH), 0);
    g->pos[0] = 0, g->pos[1] = 0, g->pos[2] = -5;
    g->n[0] = sin(tilt), g->n[1] = 0, g->n[2] = cos(tilt);
    g->u[0] = cos(tilt), g->u[1] = 0, g->u[2] = -sin(tilt);
    g->half = 2;
}

/* A rig at tilt (calloc'ed: the caller frees it after occ_ref_free) and
   the material of a grey base. */
static rig *rig_new(double tilt, float base, float metal, float rough, vt_material *m)
{
    rig *g = calloc(1, sizeof *g);
    assert_non_null(g);
    rig_make(g, tilt);
    *m = (vt_material){.base = {base, base, base, 1}, .metallic = metal, .roughness = rough, .normal_scale = 1};
    return g;
}

/* Pixel px's view direction (unit, towards the eye) where its ray meets
   the quad at least 2 px inside its edge (false elsewhere). */
static bool rig_view(const rig *g, size_t px, double v[3])
{
    const double *ray = g->ref.ray + 6 * px;
    double den = g->n[0] * ray[3] + g->n[1] * ray[4] + g->n[2] * ray[5];
    if (!(fabs(den) > 1e-12)) return false;
    double t = (g->n[0] * (g->pos[0] - ray[0]) + g->n[1] * (g->pos[1] - ray[1]) + g->n[2] * (g->pos[2] - ray[2])) / den;
    if (!(t > 0)) return false;
    double p[3], a = 0, b;
    for (int k = 0; k < 3; k++) p[k] = ray[k] + t * ray[3 + k] - g->pos[k];
    for (int k = 0; k < 3; k++) a += p[k] * g->u[k];
    b = p[1];
    if (fabs(a) > g->half * 0.85 || fabs(b) > g->half * 0.85) return false;
    double dl = sqrt(ray[3] * ray[3] + ray[4] * ray[4] + ray[5] * ray[5]);
    for (int k = 0; k < 3; k++) v[k] = -ray[3 + k] / dl;
    return true;
}

/* Draws the quad with material m under env (and lights) with soft (gr
   NULL) or GL; the exposure (EV100 0: x 1 / 1.2) undone. */
static void rig_draw(rig *g, vt_gldraw *gr, const vt_material *m, const vt_env *env, const vt_light *L, uint32_t nl)
{
    vt_mesh quad = {.pos = quad_pos, .nrm = quad_nrm, .idx = quad_idx, .nv = 4, .ni = 6};
    double tilt = atan2(g->n[0], g->n[2]);
    vt_instance in = {.place = VT_PLACE_TRS, .pos = {g->pos[0], g->pos[1], g->pos[2]},
                      .rot = {0, (float)sin(tilt / 2), 0, (float)cos(tilt / 2)}, .scale = {2, 2, 1}, .mat = m};
    vt_frame f = {.view = &g->v, .width = RW, .height = RH, .meshes = &quad, .nmesh = 1, .inst = &in, .ninst = 1,
                  .lights = L, .nl = nl, .env = env, .rgba = g->rgba, .depth = g->depth, .stride = RW};
    char err[256];
    vt_soft *sr = NULL;
    int rc;
    if (gr) {
        rc = vt_gldraw_draw(gr, &f, NULL, err, sizeof err);
    } else {
        assert_int_equal(vt_soft_create(NULL, 0, &sr), 0);
        rc = vt_soft_draw(sr, &f, NULL, err, sizeof err);
        vt_soft_destroy(sr);
    }
    if (rc) fprintf(stderr, "%s\n", err);
    assert_int_equal(rc, 0);
    for (size_t i = 0; i < (size_t)RW * RH * 4; i++)
        if (i % 4 != 3) g->rgba[i] *= 1.2f;
}

/* The sun and a point light on a flat quad: each pixel is sun x n.l x f
   + light x att x n.l x f (the reference f at the pixel's view
   direction), with no sky (black) and no ground. The renderers' n, v, l
   and the light's falloff are float: 1e-3 relative plus 2e-3 of the
   pixel's largest term. */
static void test_brdf_lights_through_renderers(void **state)
{
    (void)state;
    vt_gl *glc = NULL;
    vt_gldraw *gr = test_gldraw_or_null(&glc);
    static const struct { float base, metal, rough; } mats[] = {{0.8f, 0, 0.6f}, {0.9f, 1, 0.3f}, {0.5f, 0.5f, 0.15f}};
    for (size_t mi = 0; mi < sizeof mats / sizeof mats[0]; mi++)
        for (int which = 0; which < (gr ? 2 : 1); which++) {
            vt_material m;
            rig *g = rig_new(0.5, mats[mi].base, mats[mi].metal, mats[mi].rough, &m);
            /* the sun from up right and behind the eye: its highlight on the quad */
            double s[3] = {0.35, 0.3, 1}, sl = sqrt(s[0] * s[0] + s[1] * s[1] + s[2] * s[2]);
            vt_env env = {.sun_dir = {(float)(s[0] / sl), (float)(s[1] / sl), (float)(s[2] / sl)}, .sun = {1, 1, 1},
                          .sky_mode = VT_SKY_COLOR, .exposure_mode = VT_EXPOSURE_FIXED, .exposure_ev = 0};
            vt_light L = {.l = {.pos = {-1, 0.5, -3}, .radius = 20}, .color = {2, 2, 2}};
            rig_draw(g, which ? gr : NULL, &m, &env, &L, 1);
            double worst = 0;
            uint32_t judged = 0;
            for (size_t px = 0; px < (size_t)RW * RH; px++) {
                double v[3];
                if (!rig_view(g, px, v)) continue;
                const double *ray = g->ref.ray + 6 * px;
                double den = g->n[0] * ray[3] + g->n[1] * ray[4] + g->n[2] * ray[5];
                double t = (g->n[0] * (g->pos[0] - ray[0]) + g->n[1] * (g->pos[1] - ray[1]) +
                            g->n[2] * (g->pos[2] - ray[2])) / den, p[3];
                for (int k = 0; k < 3; k++) p[k] = ray[k] + t * ray[3 + k];
                ld Ln[3] = {g->n[0], g->n[1], g->n[2]}, Lv[3] = {v[0], v[1], v[2]}, Ls[3], Lb[3], fs[3], fl[3];
                for (int k = 0; k < 3; k++) Ls[k] = env.sun_dir[k], Lb[k] = m.base[k];
                ref_brdf(Ln, Lv, Ls, Lb, m.metallic, m.roughness, fs);
                /* the point light: vt_shade.inl's falloff, (1 - (d^2/r^2)^2)^2 / (d^2 + 0.01) */
                ld Ll[3], d2 = 0;
                for (int k = 0; k < 3; k++) Ll[k] = L.l.pos[k] - p[k], d2 += Ll[k] * Ll[k];
                for (int k = 0; k < 3; k++) Ll[k] /= sqrtl(d2);
                ld q = d2 / (L.l.radius * L.l.radius), win = 1 - q * q, att = win * win / (d2 + 0.01L);
                ref_brdf(Ln, Lv, Ll, Lb, m.metallic, m.roughness, fl);
                ld es = dotl(Ln, Ls) * fs[0], el = 2 * att * dotl(Ln, Ll) * fl[0];
                ld want = es + el, big = es > el ? es : el;
                double e = fabs(g->rgba[4 * px] - (double)want) / (double)(1e-3L * want + 2e-3L * big);
                if (e > worst) worst = e;
                judged++;
            }
            fprintf(stderr, "sun and point light, base %.2f metallic %.1f roughness %.2f (%s): %u pixels, worst %.3g of "
                            "the bound\n",
                    mats[mi].base, mats[mi].metal, mats[mi].rough, which ? "gl" : "soft", judged, worst);
            assert_true(judged > 300);
            assert_true(worst <= 1);
            occ_ref_free(&g->ref);
            free(g);
        }
    vt_gldraw_destroy(gr);
    vt_gl_close(glc);
}

/* The white furnace and the energy of metals: a uniform sky of radiance
   1 all round (VT_SKY_COLOR, no ground), no sun, no fog. The image-based
   ambient of a uniform sky is exact in its irradiance (the SH of a
   constant) and prefiltered radiance (normalised weights); what is left
   is the split sum's DFG table against the integral itself. */
static void test_brdf_white_furnace(void **state)
{
    (void)state;
    /* the quadrature first: a Lambert BRDF of albedo 1 integrates to 1 */
    double n0[3] = {0, 0, 1}, v0[3] = {0.6, 0, 0.8};
    double lam = hemi_integral(n0, v0, 1, 0, 1, 200, true);
    fprintf(stderr, "quadrature of a Lambert BRDF under a uniform sky: %.6f (analytic 1)\n", lam);
    assert_true(fabs(lam - 1) < 1e-4);
    vt_gl *glc = NULL;
    vt_gldraw *gr = test_gldraw_or_null(&glc);
    static const struct {
        const char *name;
        float base, metal, rough;
        double tol;
    } cases[] = {
        /* the furnace: within 3 % (the bound) */
        {"white, fully rough", 1, 0, 1, 0.03},
        /* a smooth metal: f0 0.9, its reflectance F(n.v) x ~1 (the
           quadrature cannot resolve a lobe 0.1 degrees wide: the mirror's
           limit instead) */
        {"smooth metal", 0.9f, 1, 0, 0.02},
        {"half-rough metal", 0.9f, 1, 0.5f, 0.03},
        /* the default material's roughness on white */
        {"white, roughness 0.6", 1, 0, 0.6f, 0.03},
    };
    const double tilts[] = {0, 1.0, 1.35};
    for (size_t ci = 0; ci < sizeof cases / sizeof cases[0]; ci++)
        for (size_t ti = 0; ti < sizeof tilts / sizeof tilts[0]; ti++)
            for (int which = 0; which < (gr ? 2 : 1); which++) {
                vt_material m;
                rig *g = rig_new(tilts[ti], cases[ci].base, cases[ci].metal, cases[ci].rough, &m);
                vt_env env = {.sky_mode = VT_SKY_COLOR, .sky = {1, 1, 1}, .exposure_mode = VT_EXPOSURE_FIXED,
                              .exposure_ev = 0};
                rig_draw(g, which ? gr : NULL, &m, &env, NULL, 0);
                /* the reference at a few pixels spread over the quad */
                double worst = 0, hi = 0;
                uint32_t judged = 0;
                for (size_t px = 0; px < (size_t)RW * RH; px += 37) {
                    double v[3];
                    if (!rig_view(g, px, v)) continue;
                    /* the soft pass integrates, the GL pass (the same pixels
                       and rays) reuses it */
                    static double cache[RW * RH];
                    double want = cache[px];
                    if (!which && cases[ci].rough == 0) {
                        double nv = v[0] * g->n[0] + v[1] * g->n[1] + v[2] * g->n[2];
                        want = cache[px] = 0.9 + 0.1 * pow(1 - nv, 5);
                    } else if (!which) {
                        want = cache[px] = hemi_integral(g->n, v, cases[ci].base, cases[ci].metal, cases[ci].rough, 120, false);
                    }
                    for (int c = 0; c < 3; c++) {
                        double got = g->rgba[4 * px + c], e = fabs(got - want) / want;
                        if (e > worst) worst = e;
                        if (got > hi) hi = got;
                    }
                    judged++;
                }
                fprintf(stderr, "furnace, %s, tilt %.2f (%s): %u pixels, worst relative %.4f (of %.2f), brightest %.4f\n",
                        cases[ci].name, tilts[ti], which ? "gl" : "soft", judged, worst, cases[ci].tol, hi);
                assert_true(judged >= 5);
                assert_true(worst <= cases[ci].tol);
                /* <= 1: the furnace. The specification's BRDF itself
                   returns up to 1 % more than 1 at middle roughness seen
                   obliquely (the quadrature: 1.011 at n.v 0.5, roughness
                   0.5; its diffuse's 1 - F(v.h) does not take back what
                   masking took from the specular lobe), so the others are
                   held to the reference only */
                if (cases[ci].rough == 1 || cases[ci].metal == 1) assert_true(hi <= 1.0);
                occ_ref_free(&g->ref);
                free(g);
            }
    vt_gldraw_destroy(gr);
    vt_gl_close(glc);
}

/* A directional environment: radiance 1 + 0.8 d.x (brighter towards +x),
   as an equirectangular HDR map laid out as vt_sky_uv reads it (u 0.5
   towards -z, v 0 at the zenith). Linear in d: its irradiance is exact in
   the SH's first two bands, E / pi = 1 + 0.8 (2 / 3) n.x. */
static double env_grad(const double d[3])
{
    return 1 + 0.8 * d[0];
}

/* A random unit direction (false: too short a draw to normalise). */
static bool rand_dir(rng *r, float d[3])
{
    for (int k = 0; k < 3; k++) d[k] = (float)rng_range(r, -1, 1);
    float l = sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    if (l < 0.1f) return false;
    for (int k = 0; k < 3; k++) d[k] /= l;
    return true;
}

static void test_brdf_directional_sky(void **state)
{
    (void)state;
    enum { EW = 128, EH = 64 };
    float *px = malloc(sizeof(float) * 4 * EW * EH);
    assert_non_null(px);
    for (int j = 0; j < EH; j++)
        for (int i = 0; i < EW; i++) {
            double th = (j + 0.5) * M_PI / EH, ph = ((i + 0.5) / EW - 0.5) * 2 * M_PI;
            double d[3] = {sin(th) * sin(ph), cos(th), -sin(th) * cos(ph)};
            float *o = px + 4 * ((size_t)j * EW + i);
            o[0] = o[1] = o[2] = (float)env_grad(d), o[3] = 1;
        }
    vt_texview sky = {.w = EW, .h = EH, .levels = 1, .hdr = px, .id = 77, .gen = 1};
    vt_env env = {.sky_mode = VT_SKY_TEXTURE, .sky = {1, 1, 1}, .sky_tex = &sky, .exposure_mode = VT_EXPOSURE_FIXED,
                  .exposure_ev = 0};
    /* the irradiance: the SH of the map against the closed form (the
       64 x 32 grid's projection and the map's bilinear reading: 0.5 %) */
    double origin[3] = {0, 0, 0};
    vt_penv pe;
    vt_penv_make(&env, origin, NULL, &pe);
    vt_ibl *ibl = calloc(1, sizeof *ibl);
    assert_non_null(ibl);
    assert_true(vt_ibl_update(ibl, &pe));
    assert_false(vt_ibl_update(ibl, &pe)); /* kept while the sky is the same */
    rng r = {test_seed() ^ 0x5CA1u};
    double worst_e = 0;
    for (int i = 0; i < 200; i++) {
        float n[3], e[3];
        if (!rand_dir(&r, n)) continue;
        vt_ibl_irradiance(ibl, n, e);
        double want = 1 + 0.8 * (2.0 / 3.0) * n[0];
        if (fabs(e[0] - want) / want > worst_e) worst_e = fabs(e[0] - want) / want;
    }
    fprintf(stderr, "SH irradiance of 1 + 0.8 d.x against the closed form: worst relative %.4f\n", worst_e);
    assert_true(worst_e < 0.005);
    /* the prefiltered levels against their definition, the GGX lobe about
       r (n = v = r) weighted by r.l, integrated here on 200 x 400 cells:
       32 x 32 octahedral texels (2.7 % at the nadir, where the square's
       corners are clamped), linear in roughness between the 5 levels
       while the lobe is not (0.01 at roughness 0.16 towards -x, where the
       sky is darkest: 4 % there): within 0.035 of the sky's mean (1) */
    double worst_s = 0;
    for (int i = 0; i < 40; i++) {
        float d[3], o[3];
        if (!rand_dir(&r, d)) continue;
        float rough = (float)rng_f(&r), rr = rough > VT_MIN_ROUGHNESS ? rough : VT_MIN_ROUGHNESS;
        vt_ibl_specular(ibl, d, rough, o);
        double a2 = pow(rr, 4), num = 0, den = 0;
        for (int a = 0; a < 200; a++)
            for (int b = 0; b < 400; b++) {
                double th = (a + 0.5) * M_PI / 200, ph = (b + 0.5) * M_PI / 200;
                double q[3] = {sin(th) * cos(ph), cos(th), sin(th) * sin(ph)}, c = q[0] * d[0] + q[1] * d[1] + q[2] * d[2];
                if (c <= 0) continue;
                double t = 0.5 * (1 + c) * (a2 - 1) + 1, w = c / (t * t) * sin(th);
                num += w * env_grad(q);
                den += w;
            }
        if (fabs(o[0] - num / den) > worst_s) worst_s = fabs(o[0] - num / den);
    }
    fprintf(stderr, "prefiltered sky against the lobe integrated: worst %.4f of the sky's mean\n", worst_s);
    assert_true(worst_s < 0.035);
    free(ibl);
    /* rendered: a quad facing +x somewhat (tilt 1: n.x 0.84) and one
       facing -x, each pixel against the quadrature of f L cos, under a
       sky varying by a factor 9 from -x to +x. The split sum takes the
       lobe's lighting and its Fresnel-masking weight apart and
       prefilters with n = v = r (its lobe centred on r, not leaning
       towards n): small for dielectrics, whose ambient is mostly the
       (exact) irradiance: 1.5 % (measured 0.6 %); for a half-rough metal
       seen at 57 degrees with the dim side in its mirror direction 18 %
       (4.6 % facing the bright side): Karis's approximation, not the
       tables (checked above): 20 %. */
    vt_gl *glc = NULL;
    vt_gldraw *gr = test_gldraw_or_null(&glc);
    static const struct { float base, metal, rough; } mats[] = {{1, 0, 1}, {0.9f, 1, 0.5f}, {0.8f, 0, 0.6f}};
    const double tilts[] = {1.0, -1.0};
    for (size_t mi = 0; mi < sizeof mats / sizeof mats[0]; mi++)
        for (size_t ti = 0; ti < 2; ti++)
            for (int which = 0; which < (gr ? 2 : 1); which++) {
                vt_material m;
                rig *g = rig_new(tilts[ti], mats[mi].base, mats[mi].metal, mats[mi].rough, &m);
                rig_draw(g, which ? gr : NULL, &m, &env, NULL, 0);
                double w = 0;
                uint32_t judged = 0;
                for (size_t p = 0; p < (size_t)RW * RH; p += 53) {
                    double v[3];
                    if (!rig_view(g, p, v)) continue;
                    static double cache[RW * RH]; /* the soft pass integrates, GL reuses */
                    if (!which) cache[p] = hemi_integral_env(g->n, v, mats[mi].base, mats[mi].metal, mats[mi].rough, 120, false, true);
                    double want = cache[p];
                    double e = fabs(g->rgba[4 * p] - want) / want;
                    if (e > w) w = e;
                    judged++;
                }
                fprintf(stderr, "sky 1 + 0.8 d.x, base %.1f metallic %.0f roughness %.1f, tilt %+.0f (%s): %u pixels, "
                                "worst relative %.4f\n",
                        mats[mi].base, mats[mi].metal, mats[mi].rough, tilts[ti], which ? "gl" : "soft", judged, w);
                assert_true(judged >= 5);
                assert_true(w < (mats[mi].metal == 1 ? 0.2 : 0.015));
                occ_ref_free(&g->ref);
                free(g);
            }
    vt_gldraw_destroy(gr);
    vt_gl_close(glc);
    free(px);
}

/* The packed tables the software kernels gather (vt_brdf.h): the
 * shared-exponent radiance against the exact value (each channel within
 * half a mantissa step, 1/1024 of the largest channel, or 1/512 where the
 * largest rounds up to the next exponent: EXT_texture_shared_exponent's
 * rounding; at the bottom of the range the least steps), the ends (0, NaN, above the range, below it) and the 10-bit DFG table against the float one. */
static void test_brdf_packed_tables(void **state)
{
    (void)state;
    rng r = {test_seed() ^ 0xE5u};
    double worst = 0;
    for (int i = 0; i < 200000; i++) {
        float c[3], d[3];
        double e = rng_range(&r, -18, 20);
        for (int k = 0; k < 3; k++) c[k] = (float)(pow(2, e) * (rng_f(&r) < 0.2 ? rng_log(&r, 1e-4, 1) : rng_f(&r)));
        vt_rgb_e5_decode(vt_rgb_e5(c), d);
        double mx = fmax(c[0], fmax(c[1], c[2]));
        /* below 2^-bias the exponent stays at its least: a fixed step of
           2^(-bias - 9), half of it at most off */
        bool low = mx < ldexp(1, -VT_E5_BIAS);
        for (int k = 0; k < 3; k++) {
            double err = fabs(d[k] - c[k]);
            if (low) assert_true(err <= ldexp(1, -VT_E5_BIAS - 9) * 1.0001);
            else worst = err / mx > worst ? err / mx : worst;
        }
    }
    fprintf(stderr, "shared-exponent RGB: worst error %.3g of the largest channel\n", worst);
    assert_true(worst <= 1.0 / 512 * 1.0001);
    float d[3];
    vt_rgb_e5_decode(vt_rgb_e5((float[3]){0, 0, 0}), d);
    assert_true(d[0] == 0 && d[1] == 0 && d[2] == 0);
    vt_rgb_e5_decode(vt_rgb_e5((float[3]){NAN, -1, INFINITY}), d);
    assert_true(d[0] == 0 && d[1] == 0 && d[2] > 2e6 && isfinite(d[2]));
    vt_rgb_e5_decode(vt_rgb_e5((float[3]){1e-9f, 1e-9f, 1e-9f}), d);
    assert_true(d[0] < 3e-6f);
    const float *t = vt_dfg_table();
    const uint32_t *t10 = vt_dfg_table10();
    for (int i = 0; i < VT_DFG_N * VT_DFG_N; i++)
        for (int k = 0; k < 3; k++) assert_true(fabsf((float)(t10[i] >> (10 * k) & 1023) / 1023 - t[4 * i + k]) <= 0.5f / 1023 + 1e-6f);
}

/* The per-roughness entries the kernels look up a group of one
 * material's pixels in (vt_ibl_rough_frame): under a sky varying in
 * colour and direction, each entry's texels against the blend of the
 * two float levels it falls between, computed here in double (the
 * levels themselves are checked against the lobe's integral above):
 * within the shared exponent's 1/512 of the largest channel; its DFG
 * row against vt_dfg at the grid's n.v (the float table, bilinear):
 * within the 10-bit rounding. The default material and a metallic-
 * roughness-textured one (none: its roughness varies); more roughnesses
 * in a frame than entries: the rest found nowhere (the kernels take the
 * levels); the next frame's replace those no frame asked for since. */
static void test_brdf_rough_entries(void **state)
{
    (void)state;
    enum { EW = 64, EH = 32 };
    float *px = malloc(sizeof(float) * 4 * EW * EH);
    vt_ibl *ibl = calloc(1, sizeof *ibl);
    assert_true(px && ibl);
    for (int j = 0; j < EH; j++)
        for (int i = 0; i < EW; i++) {
            double th = (j + 0.5) * M_PI / EH, ph = ((i + 0.5) / EW - 0.5) * 2 * M_PI;
            double d[3] = {sin(th) * sin(ph), cos(th), -sin(th) * cos(ph)};
            float *o = px + 4 * ((size_t)j * EW + i);
            o[0] = (float)env_grad(d), o[1] = (float)(1 + 0.9 * d[1]), o[2] = (float)(0.3 + 0.25 * d[2]), o[3] = 1;
        }
    vt_texview sky = {.w = EW, .h = EH, .levels = 1, .hdr = px, .id = 78, .gen = 1};
    vt_env env = {.sky_mode = VT_SKY_TEXTURE, .sky = {1, 1, 1}, .sky_tex = &sky, .exposure_mode = VT_EXPOSURE_FIXED};
    double origin[3] = {0, 0, 0};
    vt_penv pe;
    vt_penv_make(&env, origin, NULL, &pe);
    assert_true(vt_ibl_update(ibl, &pe));
    static const float rough[] = {0.08f, 0.3f, 0.55f, 0.85f, 1.0f, 0.0f};
    enum { NM = sizeof rough / sizeof rough[0] };
    vt_material m[NM + 1];
    vt_instance in[NM + 2];
    memset(in, 0, sizeof in);
    for (int i = 0; i < NM; i++) m[i] = (vt_material){.base = {1, 1, 1, 1}, .roughness = rough[i]}, in[i].mat = &m[i];
    uint8_t mr_px[4] = {0, 128, 255, 255};
    const uint8_t *mr_lv[1] = {mr_px};
    vt_texview mr = {.w = 1, .h = 1, .levels = 1, .mip = mr_lv, .id = 79, .gen = 1};
    m[NM] = (vt_material){.base = {1, 1, 1, 1}, .roughness = 0.42f};
    m[NM].tex[VT_SLOT_MR].tex = &mr;
    in[NM].mat = &m[NM];
    in[NM + 1].mat = NULL; /* the default material */
    vt_ibl_rough_frame(ibl, in, NM + 2, NULL);
    assert_int_equal(ibl->nr, NM + 1);
    assert_true(vt_ibl_rough_find(ibl, vt_brdf_rough(0.42f)) < 0);
    double worst_s = 0, worst_d = 0;
    for (int q = 0; q <= NM; q++) {
        float r = vt_brdf_rough(q < NM ? rough[q] : VT_DEFAULT_ROUGHNESS);
        int k = vt_ibl_rough_find(ibl, r);
        assert_true(k >= 0);
        double f = r * (VT_IBL_LEVELS - 1);
        int lv = f < VT_IBL_LEVELS - 2 ? (int)f : VT_IBL_LEVELS - 2;
        double t = f - lv;
        for (int i = 0; i < VT_IBL_RES * VT_IBL_RES; i++) {
            float got[3];
            vt_rgb_e5_decode(ibl->rspec[k][i], got);
            double want[3], mx = 0;
            for (int c = 0; c < 3; c++) {
                want[c] = (1 - t) * ibl->spec[lv][4 * i + c] + t * ibl->spec[lv + 1][4 * i + c];
                mx = fmax(mx, want[c]);
            }
            for (int c = 0; c < 3; c++) worst_s = fmax(worst_s, fabs(got[c] - want[c]) / mx);
        }
        for (int i = 0; i < VT_DFG_N; i++) {
            float want[3];
            vt_dfg((float)i / (VT_DFG_N - 1), r, want);
            for (int c = 0; c < 3; c++)
                worst_d = fmax(worst_d, fabs((double)(ibl->rdfg[k][i] >> (10 * c) & 1023) / 1023 - want[c]));
        }
    }
    fprintf(stderr, "roughness entries: prefiltered blend worst %.3g of the largest channel, DFG row worst %.3g\n", worst_s,
            worst_d);
    assert_true(worst_s <= 1.0 / 512 * 1.0001);
    assert_true(worst_d <= 0.5 / 1023 + 1e-6);
    /* a frame of more roughnesses than entries, then one of others */
    vt_material many[VT_IBL_NR + 4];
    vt_instance mi[VT_IBL_NR + 4];
    memset(mi, 0, sizeof mi);
    for (int pass = 0; pass < 2; pass++) {
        uint32_t n = pass ? 3 : VT_IBL_NR + 4;
        for (uint32_t i = 0; i < n; i++) {
            many[i] = (vt_material){.base = {1, 1, 1, 1}, .roughness = 0.1f + 0.04f * (float)i + 0.013f * (float)pass};
            mi[i].mat = &many[i];
        }
        vt_ibl_rough_frame(ibl, mi, n, NULL);
        uint32_t found = 0;
        for (uint32_t i = 0; i < n; i++) found += vt_ibl_rough_find(ibl, vt_brdf_rough(many[i].roughness)) >= 0;
        assert_int_equal(found, pass ? n : VT_IBL_NR);
        assert_true(ibl->nr <= VT_IBL_NR);
    }
    free(ibl);
    free(px);
}

const struct CMUnitTest brdf_tests[] = {
    cmocka_unit_test(test_brdf_terms_against_spec),
    cmocka_unit_test(test_brdf_against_spec),
    cmocka_unit_test(test_brdf_dfg_table),
    cmocka_unit_test(test_brdf_packed_tables),
    cmocka_unit_test(test_brdf_rough_entries),
    cmocka_unit_test(test_brdf_lights_through_renderers),
    cmocka_unit_test(test_brdf_white_furnace),
    cmocka_unit_test(test_brdf_directional_sky),
};
const size_t brdf_tests_count = sizeof brdf_tests / sizeof brdf_tests[0];
