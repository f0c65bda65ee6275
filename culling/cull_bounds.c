/*
 * cull_bounds.c — an entity's culling bounds derived from a mesh's local
 * box and a transform (position, unit quaternion, scale): the AABB by
 * Arvo's method ("Transforming Axis-Aligned Bounding Boxes", Graphics Gems,
 * 1990: world centre = pos + M*c, half extents = |M|*h), the sphere around
 * that AABB. Everything in double, rounded outward so the result contains
 * the exact transformed box; the bound and its proof are in culling.h,
 * "Derived bounds".
 *
 * What it owns: the checks of a transform (finite, unit quaternion within
 * 1e-3, at most one zero scale axis) and the arithmetic. It stores nothing;
 * the caller gives the result to cull_entity_add/update.
 */
#include "culling.h"

#include <float.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

#if FLT_EVAL_METHOD != 0
#error "the rounding proof in culling.h assumes double arithmetic rounds to double (FLT_EVAL_METHOD 0)"
#endif

/* The neighbours of a finite double: the proof's one-ulp steps. Bit
 * arithmetic, not nextafter(): no libm call, no errno, a few cycles. */
static inline double next_up(double x)
{
    if (x == 0) return 0x1p-1074;
    uint64_t b;
    memcpy(&b, &x, sizeof b);
    b += x > 0 ? 1 : (uint64_t)-1;
    memcpy(&x, &b, sizeof x);
    return x;
}

static inline double next_down(double x) { return -next_up(-x); }

/* fmax without the libm call (GCC does not inline it at -O2); the
 * arguments here are never NaN */
static inline double max2(double a, double b) { return a > b ? a : b; }

static const char axis_name[4] = {'x', 'y', 'z', 'w'};

/* The field checks, each naming the field; on failure d is untouched. */
static int check_trs(const double lmin[3], const double lmax[3], const cull_trs *t, char *err, size_t errlen)
{
    for (int a = 0; a < 3; a++) {
        if (!isfinite(t->pos[a]))
            return vp_errf(err, errlen, CULL_ERR_NONFINITE, "position %c is %g: NaN or infinite", axis_name[a],
                           t->pos[a]);
        if (fabs(t->pos[a]) > CULL_MAX_COORD)
            return vp_errf(err, errlen, CULL_ERR_RANGE, "position %c is %g m, beyond the world's +-%g m",
                           axis_name[a], t->pos[a], CULL_MAX_COORD);
    }
    for (int a = 0; a < 4; a++)
        if (!isfinite(t->rot[a]))
            return vp_errf(err, errlen, CULL_ERR_NONFINITE, "rotation %c is %g: NaN or infinite", axis_name[a],
                           t->rot[a]);
    int zeros = 0;
    for (int a = 0; a < 3; a++) {
        if (!isfinite(t->scale[a]))
            return vp_errf(err, errlen, CULL_ERR_NONFINITE, "scale %c is %g: NaN or infinite", axis_name[a],
                           (double)t->scale[a]);
        zeros += t->scale[a] == 0;
    }
    for (int a = 0; a < 3; a++) {
        if (!isfinite(lmin[a]) || !isfinite(lmax[a]))
            return vp_errf(err, errlen, CULL_ERR_NONFINITE, "local %s %c is %g: NaN or infinite",
                           isfinite(lmin[a]) ? "max" : "min", axis_name[a], isfinite(lmin[a]) ? lmax[a] : lmin[a]);
        if (fabs(lmin[a]) > CULL_MAX_COORD || fabs(lmax[a]) > CULL_MAX_COORD)
            return vp_errf(err, errlen, CULL_ERR_RANGE, "local bounds %c (%g..%g m) beyond +-%g m", axis_name[a],
                           lmin[a], lmax[a], CULL_MAX_COORD);
        if (lmin[a] > lmax[a])
            return vp_errf(err, errlen, CULL_ERR_AABB, "local min %c %g > max %g", axis_name[a], lmin[a], lmax[a]);
    }
    if (zeros > 1)
        return vp_errf(err, errlen, CULL_ERR_INVALID, "scale (%g, %g, %g) is 0 on %d axes; at most one may be 0",
                       (double)t->scale[0], (double)t->scale[1], (double)t->scale[2], zeros);
    /* |q| within the tolerance of 1, tested on |q|^2: no root on the way */
    const double *q = t->rot;
    double n2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
    if (!(n2 >= (1 - CULL_QUAT_TOLERANCE) * (1 - CULL_QUAT_TOLERANCE) &&
          n2 <= (1 + CULL_QUAT_TOLERANCE) * (1 + CULL_QUAT_TOLERANCE)))
        return vp_errf(err, errlen, CULL_ERR_INVALID,
                       "rotation (%g, %g, %g, %g) has length %.9g, not within %g of 1 (a unit quaternion)", q[0], q[1],
                       q[2], q[3], sqrt(n2), CULL_QUAT_TOLERANCE);
    return CULL_OK;
}

int cull_bounds_from_trs(const double local_min[3], const double local_max[3], const cull_trs *t,
                         cull_entity_desc *d, char *err, size_t errlen)
{
    if (!local_min || !local_max || !t || !d)
        return vp_errf(err, errlen, CULL_ERR_INVALID, "no %s", !t ? "transform" : !d ? "output" : "local bounds");
    int rc = check_trs(local_min, local_max, t, err, errlen);
    if (rc) return rc;

    /* R of q/|q| without renormalising q: 2/n2 in place of 2 (culling.h) */
    const double x = t->rot[0], y = t->rot[1], z = t->rot[2], w = t->rot[3];
    const double s = 2 / (x * x + y * y + z * z + w * w);
    const double r[3][3] = {
        {1 - s * (y * y + z * z), s * (x * y - z * w), s * (x * z + y * w)},
        {s * (x * y + z * w), 1 - s * (x * x + z * z), s * (y * z - x * w)},
        {s * (x * z - y * w), s * (y * z + x * w), 1 - s * (x * x + y * y)},
    };
    double c[3], h[3], mag = 0; /* local centre, half extents; A of the proof */
    for (int j = 0; j < 3; j++) {
        c[j] = (local_min[j] + local_max[j]) * 0.5;
        h[j] = (local_max[j] - local_min[j]) * 0.5;
        mag += fabs((double)t->scale[j]) * max2(fabs(local_min[j]), fabs(local_max[j]));
    }
    /* W = 2^-46 A + 2^-900: covers every rounding before the last add */
    const double widen = mag * 0x1p-46 + 0x1p-900;
    double lo[3], hi[3];
    for (int i = 0; i < 3; i++) {
        double mc = 0, mh = 0;
        for (int j = 0; j < 3; j++) {
            double m = r[i][j] * (double)t->scale[j];
            mc += m * c[j];
            mh += fabs(m) * h[j];
        }
        double ext = mh + widen;
        lo[i] = next_down(t->pos[i] + (mc - ext));
        hi[i] = next_up(t->pos[i] + (mc + ext));
    }
    /* sphere: any centre inside; radius >= the distance to the AABB's
     * farthest corner, each difference and the root rounded up */
    double ctr[3], e[3], emax = 0;
    for (int i = 0; i < 3; i++) {
        ctr[i] = lo[i] * 0.5 + hi[i] * 0.5;
        e[i] = max2(next_up(ctr[i] - lo[i]), next_up(hi[i] - ctr[i]));
        emax = max2(emax, e[i]);
    }
    double rad;
    if (emax < 0x1p-500) /* squares would underflow: 2 max e >= sqrt(3) max e */
        rad = 2 * emax;
    else
        rad = next_up(sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]) * (1 + 0x1p-48));
    for (int i = 0; i < 3; i++) {
        d->center[i] = ctr[i];
        d->aabb_min[i] = lo[i];
        d->aabb_max[i] = hi[i];
    }
    d->radius = rad;
    return CULL_OK;
}
