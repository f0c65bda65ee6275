/*
 * debris.c — where a destruction's debris comes to rest (issue 20: debris
 * settles on the ground, it does not float where the blast threw it).
 *
 * Each piece falls straight down from where the blast threw it onto the
 * highest surface under its footprint that is not above its bottom: the
 * environment's ground plane, the top of an entity's box, or a piece of
 * the same blast that landed before it (pieces stack). With nothing under
 * it (no ground plane, no entity) it stays where it was thrown. An
 * entity's box stands for its shape, as everywhere in the culling core: a
 * piece may rest on the box of a curved roof.
 *
 * The entities under the blast's spread come from one frustum-only query
 * of an orthographic view looking straight down over it (no occlusion: a
 * support hidden from above still holds), so the cost is the query's
 * (microseconds for the city) plus the entities found, not the scene's
 * size. The result buffer is sized as cull_query requires (every entity),
 * but a large malloc is mapped lazily: only the results written are
 * touched. It runs when the blast is applied, live and on replay alike,
 * so a journal replays the same resting places.
 */
#include "scene.h"
#include "cull_mat.h"
#include "errmap.h"

#include <math.h>
#include <stdlib.h>

int scene_debris_settle(const scene *s, uint32_t n, double (*c)[3], const double *half, scene_err *err)
{
    if (!n) return VP_OK;
    bool ground = s->env.flags & VP_ENV_GROUND;
    double gy = ground ? s->env.ground_height : -INFINITY;
    /* the spread: every piece's footprint, from the highest top down */
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (uint32_t i = 0; i < n; i++)
        for (int a = 0; a < 3; a++) {
            lo[a] = fmin(lo[a], c[i][a] - half[i]);
            hi[a] = fmax(hi[a], c[i][a] + half[i]);
        }
    /* nothing can hold a piece whose bottom is under the ground: the
       ground itself does (below it the column is empty) */
    double bottom = ground ? fmax(gy, -CULL_MAX_COORD) : -CULL_MAX_COORD;
    if (!(hi[1] > bottom)) bottom = hi[1] - 1;
    double top = fmin(hi[1] + 1, CULL_MAX_COORD);
    double ox = 0.5 * (lo[0] + hi[0]), oz = 0.5 * (lo[2] + hi[2]);
    double hx = 0.5 * (hi[0] - lo[0]) + 0.01, hz = 0.5 * (hi[2] - lo[2]) + 0.01;
    cull_view_desc vd = {.origin = {ox, top, oz}, .depth_mode = CULL_DEPTH_ZERO_ONE, .viewport_w = 64,
                         .viewport_h = 64};
    double look[16], proj[16];
    cull_mat_look_dir(look, (const double[3]){0, -1, 0}, (const double[3]){0, 0, -1});
    cull_mat_ortho(proj, -hx, hx, -hz, hz, 0, top - bottom, CULL_DEPTH_ZERO_ONE);
    cull_mat_mul(vd.view_proj, proj, look);
    cull_view v;
    cull_ctx *ctx = NULL;
    size_t cap = cull_query_bound(s->world), found = 0;
    cull_result *res = NULL;
    int rc = cull_view_init(&v, &vd);
    if (rc) /* a spread the view cannot hold (out of the world): no supports but the ground */
        goto land;
    if (cull_ctx_create(NULL, &ctx) || !(res = malloc(cap * sizeof *res))) {
        rc = scene_fail(err, VP_ERR_BUSY, UINT32_MAX, "out of memory for the debris' resting places");
        goto out;
    }
    cull_query_desc q = {.views = &v, .view_count = 1, .flags = CULL_Q_NO_OCCLUSION, .threads = 1};
    if ((rc = cull_query(s->world, ctx, &q, res, cap, &found, NULL))) {
        rc = scene_fail(err, vp_code_from_cull(rc), UINT32_MAX, "debris: %s", cull_strerror(rc));
        goto out;
    }
land:
    for (uint32_t i = 0; i < n; i++) {
        double b = c[i][1] - half[i], rest = gy; /* under the ground: lifted onto it */
        for (size_t k = 0; k < found; k++) {
            cull_entity_desc e;
            if (cull_entity_get(s->world, res[k].handle, &e)) continue;
            double t = e.aabb_max[1];
            if (t > b || t <= rest) continue;
            if (e.aabb_max[0] <= c[i][0] - half[i] || e.aabb_min[0] >= c[i][0] + half[i] ||
                e.aabb_max[2] <= c[i][2] - half[i] || e.aabb_min[2] >= c[i][2] + half[i])
                continue;
            rest = t;
        }
        for (uint32_t j = 0; j < i; j++) { /* the pieces already down */
            double t = c[j][1] + half[j];
            if (t > b || t <= rest || fabs(c[j][0] - c[i][0]) >= half[i] + half[j] ||
                fabs(c[j][2] - c[i][2]) >= half[i] + half[j])
                continue;
            rest = t;
        }
        if (rest > -INFINITY) c[i][1] = rest + half[i];
    }
    rc = VP_OK;
out:
    free(res);
    cull_ctx_destroy(ctx);
    return rc;
}
