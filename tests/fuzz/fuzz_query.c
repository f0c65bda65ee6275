/*
 * fuzz_query.c — libFuzzer target for the whole query path of the culling
 * core (culling/): what a decoded-valid but hostile VIS_QUERY, RENDER,
 * LIGHT_QUERY or frame stream hands it after the protocol's decoders
 * (fuzz_protocol.c) let it through. The crash of issue 18 (an eye level
 * with an occluder's base, a 1e-30 cross term: write_span far outside the
 * occlusion buffer) lived here, past every decoder.
 *
 * The input (fuzz_geom.h decodes numbers, views and lights): a header byte
 * (counts), then occluders (unit boxes under a transform from the bytes,
 * triangle soups, small height fields: through cull_occluder_add and
 * cull_terrain_add, as the daemon's OCCLUDER_PUT and demo scene do),
 * entities (cull_entity_add), lights, and 1..3 views on small buffers
 * (8..64 pixels a side, so one execution is fast). Refused descs are
 * skipped: the validators are not under test here, what they accept is.
 * Then:
 *   1. cull_query without and with occlusion (both coverages, the buffer
 *      size from the bytes): CULL_OK, the results with occlusion are a
 *      subset of those without, each entity at most once, masks within
 *      the views;
 *   2. cull_occ_render per view into its own buffer, then
 *      cull_occ_test_aabb on every entity, the query with that buffer
 *      (a subset again), and the buffer's pixels: no NaN, padding
 *      columns untouched (FLT_MAX);
 *   3. cull_lights_bin with and without the buffer's depth ranges:
 *      CULL_OK, CULL_ERR_INVALID (a light it refuses) or CULL_ERR_MATRIX
 *      (a view it cannot bin for), the CSR lists
 *      well formed (offsets non-decreasing, indices ascending, < n).
 * ASan and UBSan (make fuzz) catch the rest: any write outside a buffer,
 * any out-of-range conversion or signed overflow. A broken property
 * calls abort().
 */
#include "culling.h"
#include "fuzz_geom.h"

#define FUZZ_NAME "fuzz_query"
#include "fuzz_check.h"

#include <float.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { MAX_ENT = 24, MAX_LIGHTS = 6, MAX_VIEWS = 3 };

/* The 12 triangles of [-1, 1]^3, counter-clockwise from outside. */
static void unit_box(float v[108])
{
    static const int face[6][4] = {{0, 4, 6, 2}, {1, 3, 7, 5}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 2, 3, 1}, {4, 5, 7, 6}};
    int k = 0;
    for (int f = 0; f < 6; f++) {
        const int tri[6] = {face[f][0], face[f][1], face[f][2], face[f][0], face[f][2], face[f][3]};
        for (int i = 0; i < 6; i++)
            for (int a = 0; a < 3; a++) v[k++] = (tri[i] >> a) & 1 ? 1.0f : -1.0f;
    }
}

static void add_occluder(fz *f, cull_world *w)
{
    uint8_t kind = fz_u8(f) % 3;
    if (kind == 2) { /* a height field */
        float h[25];
        cull_terrain_desc t = {.heights = h, .nx = 2 + fz_u8(f) % 4, .nz = 2 + fz_u8(f) % 4};
        for (uint32_t i = 0; i < t.nx * t.nz; i++) h[i] = (float)fz_num(f, 10);
        for (int a = 0; a < 3; a++) t.origin[a] = fz_num(f, 50);
        t.spacing = fz_num(f, 10);
        cull_occluder o;
        (void)cull_terrain_add(w, &t, &o);
        return;
    }
    float v[108];
    cull_occluder_desc d = {.vertices = v};
    if (kind == 0) { /* a box: scale, cross terms, translation */
        unit_box(v);
        d.vertex_count = 36;
        uint8_t m = fz_u8(f);
        for (int a = 0; a < 3; a++) {
            d.transform[a * 5] = (m & 1) ? fz_num(f, 20) : (double)(1 + fz_u8(f) % 16);
            d.transform[12 + a] = (m & 2) ? fz_num(f, 60) : (double)((int)fz_u8(f) - 128);
        }
        if (m & 4) d.transform[fz_u8(f) % 12] += fz_num(f, 1);
        d.transform[15] = 1;
    } else { /* a soup of up to 8 triangles, on integers or not */
        uint32_t nt = 1 + fz_u8(f) % 8;
        for (uint32_t i = 0; i < 9 * nt; i++) v[i] = (float)fz_num(f, 40);
        d.vertex_count = 3 * nt;
    }
    cull_occluder o;
    (void)cull_occluder_add(w, &d, &o);
}

static void check_tiles(const cull_light_tiles *t, uint32_t n)
{
    uint32_t nt = t->tiles_x * t->tiles_y;
    CHECK(t->offset[0] == 0);
    for (uint32_t i = 0; i < nt; i++) {
        CHECK(t->offset[i] <= t->offset[i + 1]);
        for (uint32_t k = t->offset[i]; k < t->offset[i + 1]; k++) {
            CHECK(t->index[k] < n);
            if (k > t->offset[i]) CHECK(t->index[k - 1] < t->index[k]);
        }
    }
    CHECK(t->in_view <= n);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fz f = {data, size};
    uint8_t head = fz_u8(&f);
    cull_world *w;
    if (cull_world_create(NULL, &w) != CULL_OK) abort();
    for (uint32_t i = 1 + head % 4; i > 0; i--) add_occluder(&f, w);
    cull_entity_desc ent[MAX_ENT];
    cull_handle eh[MAX_ENT];
    uint32_t ne = 0;
    for (uint32_t i = fz_u8(&f) % MAX_ENT; i > 0; i--) {
        cull_entity_desc e = {0};
        for (int a = 0; a < 3; a++) {
            double c = fz_num(&f, 60), h = fabs(fz_num(&f, 5));
            e.aabb_min[a] = c - h;
            e.aabb_max[a] = c + h;
        }
        if (fz_u8(&f) & 1) e.flags = CULL_ENTITY_DYNAMIC;
        if (cull_entity_add(w, &e, &eh[ne]) != CULL_OK) continue;
        CHECK(cull_entity_get(w, eh[ne], &ent[ne]) == CULL_OK);
        ne++;
    }
    cull_world_commit(w);
    cull_light lights[MAX_LIGHTS];
    uint32_t nl = fz_u8(&f) % (MAX_LIGHTS + 1);
    for (uint32_t i = 0; i < nl; i++) fz_light(&f, &lights[i]);

    cull_view views[MAX_VIEWS];
    uint32_t nv = 0, vw[MAX_VIEWS], vh[MAX_VIEWS];
    for (uint32_t i = 1 + (head >> 2) % MAX_VIEWS; i > 0; i--) {
        uint32_t bw = 8 + fz_u8(&f) % 57, bh = 8 + fz_u8(&f) % 57;
        cull_view_desc d;
        fz_view_desc(&f, &d, bw, bh);
        if (cull_view_init(&views[nv], &d) != CULL_OK) continue;
        vw[nv] = bw;
        vh[nv++] = bh;
    }
    if (!nv) goto done;

    /* 1. the query, without and with occlusion */
    cull_ctx *c;
    CHECK(cull_ctx_create(NULL, &c) == CULL_OK);
    size_t cap = cull_query_bound(w), n0, n1;
    cull_result *r0 = malloc(cap * sizeof *r0), *r1 = malloc(cap * sizeof *r1);
    CHECK(r0 && r1);
    cull_query_desc q = {.views = views, .view_count = nv, .flags = CULL_Q_NO_OCCLUSION, .threads = 1};
    if (head & 0x20) q.flags |= CULL_Q_WANT_AREA;
    CHECK(cull_query(w, c, &q, r0, cap, &n0, NULL) == CULL_OK);
    q.flags &= ~CULL_Q_NO_OCCLUSION;
    if (head & 0x40) q.flags |= CULL_Q_OCC_CENTRE;
    q.occ_w = vw[0];
    q.occ_h = vh[0];
    CHECK(cull_query(w, c, &q, r1, cap, &n1, NULL) == CULL_OK);
    CHECK(n0 <= (size_t)ne && n1 <= n0);
    uint32_t m0[MAX_ENT] = {0}, m1[MAX_ENT] = {0};
    for (size_t i = 0; i < n0; i++) {
        uint32_t k;
        for (k = 0; k < ne && eh[k] != r0[i].handle; k++) {}
        CHECK(k < ne && m0[k] == 0 && r0[i].view_mask && r0[i].view_mask >> nv == 0);
        m0[k] = r0[i].view_mask;
    }
    for (size_t i = 0; i < n1; i++) {
        uint32_t k;
        for (k = 0; k < ne && eh[k] != r1[i].handle; k++) {}
        CHECK(k < ne && m1[k] == 0 && r1[i].view_mask);
        m1[k] = r1[i].view_mask;
        CHECK((m1[k] & ~m0[k]) == 0); /* occlusion only removes */
    }

    /* 2. each view's buffer rendered directly, tested, inspected */
    for (uint32_t v = 0; v < nv; v++) {
        cull_occ_buffer *b;
        CHECK(cull_occ_buffer_create(vw[v], vh[v], &b) == CULL_OK);
        CHECK(cull_occ_buffer_set_cover(b, (head >> 6) & 1) == CULL_OK);
        CHECK(cull_occ_render(w, &views[v], b, NULL, 1, NULL) == CULL_OK);
        cull_occ_buffer *const bufs[1] = {b};
        cull_query_desc qb = {.views = &views[v], .view_count = 1, .threads = 1, .occ_buffers = bufs};
        CHECK(cull_query(w, c, &qb, r1, cap, &n1, NULL) == CULL_OK);
        CHECK(n1 <= n0);
        for (uint32_t e = 0; e < ne; e++) {
            int vis = cull_occ_test_aabb(b, ent[e].aabb_min, ent[e].aabb_max);
            CHECK(vis == 0 || vis == 1);
        }
        uint32_t bw, bh;
        size_t stride;
        const float *z = cull_occ_depth(b, &bw, &bh, &stride);
        CHECK(z && bw == vw[v] && bh == vh[v] && stride >= bw);
        for (uint32_t y = 0; y < bh; y++)
            for (size_t x = 0; x < stride; x++) {
                float p = z[y * stride + x];
                CHECK(x < bw ? p == p : p == FLT_MAX);
            }

        /* 3. the light tiles, over the whole frustum and the buffer's depth */
        cull_light_tiles t = {0};
        int rc = cull_lights_bin(&views[v], vw[v], vh[v], lights, nl, NULL, &t);
        /* CULL_ERR_MATRIX: an orthographic view with w <= 0 (not usable
           for binning; culling.h's list of returns omits it) */
        CHECK(rc == CULL_OK || rc == CULL_ERR_INVALID || rc == CULL_ERR_MATRIX);
        if (rc == CULL_OK) {
            check_tiles(&t, nl);
            /* per 16x16 tile, the buffer's nearness range (nearest,
               farthest; none: nearest < farthest) */
            uint32_t tx = (bw + 15) / 16, ty = (bh + 15) / 16;
            float (*range)[2] = malloc((size_t)tx * ty * sizeof *range);
            CHECK(range != NULL);
            for (uint32_t i = 0; i < tx * ty; i++) range[i][0] = -FLT_MAX, range[i][1] = FLT_MAX;
            for (uint32_t y = 0; y < bh; y++)
                for (uint32_t x = 0; x < bw; x++) {
                    float p = z[y * stride + x], *rg = range[(y / 16) * tx + x / 16];
                    if (p == -FLT_MAX) continue;
                    rg[0] = p > rg[0] ? p : rg[0];
                    rg[1] = p < rg[1] ? p : rg[1];
                }
            CHECK(cull_lights_bin(&views[v], vw[v], vh[v], lights, nl, (const float(*)[2])range, &t) == CULL_OK);
            check_tiles(&t, nl);
            free(range);
        }
        cull_light_tiles_free(&t);
        cull_occ_buffer_destroy(b);
    }
    free(r0);
    free(r1);
    cull_ctx_destroy(c);
done:
    cull_world_destroy(w);
    return 0;
}
