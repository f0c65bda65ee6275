/*
 * fuzz_scene.h — fuzz_protocol.c's checks of version 2's scene messages
 * (included by it, after its helpers): TRANSFORM_SET, MATERIAL_PUT,
 * TEXTURE_PUT, ENV_SET / ENV_REPLY, and the version 1 records (entity,
 * occluder) that journals still hold. For each accepted payload:
 *   - every getter accepts every record the decoder accepted, and the
 *     record check (the daemon's why-message) agrees with the decoder:
 *     the first record it refuses has the decoder's code, with a message;
 *   - decode -> encode gives the same bytes, unless the decoder changed a
 *     value on the way in (a quaternion or sun direction renormalised);
 *   - decode(encode(x)) == x, bit for bit: renormalising is idempotent.
 */
#ifndef FUZZ_SCENE_H
#define FUZZ_SCENE_H

static bool same_f32s(const float *a, const float *b, int n)
{
    for (int k = 0; k < n; k++)
        if (!same_f32(a[k], b[k])) return false;
    return true;
}

static bool same_f64s(const double *a, const double *b, int n)
{
    for (int k = 0; k < n; k++)
        if (!same_f64(a[k], b[k])) return false;
    return true;
}

/* A batch decoder refused the payload: if the count fitted, the record
 * check names the first bad record with the decoder's code. check(i, why)
 * is the record check of record i of n records at recs. */
/* A batch decoded with no limit (rc, n records) and with limit (rcl, ln
 * records): a limit can only turn an accept into COUNT. */
static void check_limit(int rc, uint32_t n, int rcl, uint32_t ln, uint32_t limit)
{
    check_code(rc);
    check_code(rcl);
    if (rcl == VP_OK) CHECK(rc == VP_OK && (limit == 0 || ln <= limit));
    if (rc == VP_OK && rcl != VP_OK) CHECK(rcl == VP_ERR_COUNT && limit && n > limit);
}

/* A decoder's code and its why-variant's agree, and only a refusal has a why. */
static void check_why(int rc, int rc_why, const char *why)
{
    check_code(rc);
    CHECK(rc_why == rc && (rc == VP_OK ? why[0] == 0 : why[0] != 0));
}

typedef int (*rec_check_fn)(const uint8_t *recs, uint32_t n, uint32_t i, char *why, size_t whylen);

static void check_refusal(int rc, const uint8_t *p, size_t len, size_t rec, rec_check_fn check)
{
    if (rc == VP_OK || rc == VP_ERR_COUNT || rc == VP_ERR_TRUNCATED || len < 4) return;
    uint32_t n = vp_ld_u32(p);
    CHECK((len - 4) / rec == n && (len - 4) % rec == 0);
    for (uint32_t i = 0; i < n; i++) {
        char why[256] = "";
        int r = check(p + 4, n, i, why, sizeof why);
        if (r == VP_OK) continue;
        CHECK(r == rc && why[0] != 0);
        return;
    }
    CHECK(!"the decoder refused a batch whose records all pass their check");
}

/* ---- TRANSFORM_SET -------------------------------------------------------------- */

static int xf_check(const uint8_t *recs, uint32_t n, uint32_t i, char *why, size_t whylen)
{
    vp_transform_batch b = {.count = n, .recs = recs};
    return vp_transform_rec_check(&b, i, why, whylen);
}

static bool same_transform(const vp_transform *a, const vp_transform *b)
{
    return a->id == b->id && a->handle == b->handle && same_f64s(a->pos, b->pos, 3) && same_f32s(a->rot, b->rot, 4) &&
           same_f32s(a->scale, b->scale, 3);
}

static void fuzz_transforms(const uint8_t *p, size_t len, uint32_t limit)
{
    vp_transform_batch m = {0}, lim = {0};
    int rc = vp_dec_transforms(p, len, 0, &m), rcl = vp_dec_transforms(p, len, limit, &lim);
    check_limit(rc, m.count, rcl, lim.count, limit);
    check_refusal(rc, p, len, VP_TRANSFORM_REC_SIZE, xf_check);
    if (rc) return;
    CHECK(len == 4 + (size_t)m.count * VP_TRANSFORM_REC_SIZE);
    vp_transform *t = malloc(((size_t)m.count ? m.count : 1) * sizeof *t), past;
    CHECK(t != NULL);
    bool changed = false;
    for (uint32_t i = 0; i < m.count; i++) {
        CHECK(vp_transform_get(&m, i, &t[i]) == VP_OK);
        for (int k = 0; k < 4; k++) changed |= !same_f32(t[i].rot[k], vp_ld_f32(m.recs + 64 * (size_t)i + 36 + 4 * k));
    }
    CHECK(vp_transform_get(&m, m.count, &past) == VP_ERR_COUNT);
    fuzz_wbuf b;
    fuzz_wopen(&b, vp_size_transforms(m.count));
    vp_enc_transforms(&b.w, 4, t, m.count);
    const uint8_t *q = enc_payload(&b, VP_TRANSFORM_SET, len);
    CHECK(changed || memcmp(q, p, len) == 0);
    vp_transform_batch r;
    CHECK(vp_dec_transforms(q, len, 0, &r) == VP_OK && r.count == m.count);
    for (uint32_t i = 0; i < r.count; i++) {
        vp_transform x;
        CHECK(vp_transform_get(&r, i, &x) == VP_OK && same_transform(&x, &t[i]));
    }
    fuzz_wclose(&b);
    free(t);
}

/* ---- MATERIAL_PUT ------------------------------------------------------------------ */

static bool same_material(const vp_material *a, const vp_material *b)
{
    if (a->id != b->id || a->flags != b->flags || a->alpha_mode != b->alpha_mode ||
        !same_f32(a->alpha_cutoff, b->alpha_cutoff) || !same_f32s(a->base_color, b->base_color, 4) ||
        !same_f32(a->metallic, b->metallic) || !same_f32(a->roughness, b->roughness) ||
        !same_f32s(a->emissive, b->emissive, 3) || !same_f32(a->emissive_strength, b->emissive_strength) ||
        !same_f32(a->normal_scale, b->normal_scale))
        return false;
    for (int k = 0; k < VP_TEX_SLOTS; k++) {
        const vp_texref *x = &a->tex[k], *y = &b->tex[k];
        if (x->texture != y->texture || x->wrap_s != y->wrap_s || x->wrap_t != y->wrap_t ||
            x->min_filter != y->min_filter || x->mag_filter != y->mag_filter || x->texcoord != y->texcoord ||
            !same_f32s(x->offset, y->offset, 2) || !same_f32s(x->scale, y->scale, 2) ||
            !same_f32(x->rotation, y->rotation))
            return false;
    }
    return true;
}

static void fuzz_materials(const uint8_t *p, size_t len, uint32_t limit)
{
    const uint8_t *recs, *lrecs;
    uint32_t n = 0, ln = 0;
    int rc = vp_dec_materials(p, len, 0, &recs, &n), rcl = vp_dec_materials(p, len, limit, &lrecs, &ln);
    check_limit(rc, n, rcl, ln, limit);
    check_refusal(rc, p, len, VP_MATERIAL_SIZE, vp_material_rec_check);
    if (rc) return;
    CHECK(len == 4 + (size_t)n * VP_MATERIAL_SIZE);
    vp_material *m = malloc(((size_t)n ? n : 1) * sizeof *m), past;
    CHECK(m != NULL);
    for (uint32_t i = 0; i < n; i++) CHECK(vp_material_get(recs, n, i, &m[i]) == VP_OK);
    CHECK(vp_material_get(recs, n, n, &past) == VP_ERR_COUNT);
    fuzz_wbuf b;
    fuzz_wopen(&b, vp_size_materials(n));
    vp_enc_materials(&b.w, 5, m, n);
    const uint8_t *q = enc_payload(&b, VP_MATERIAL_PUT, len);
    CHECK(memcmp(q, p, len) == 0); /* nothing is changed on the way in */
    const uint8_t *rrecs;
    uint32_t rn;
    CHECK(vp_dec_materials(q, len, 0, &rrecs, &rn) == VP_OK && rn == n);
    for (uint32_t i = 0; i < n; i++) {
        vp_material x;
        CHECK(vp_material_get(rrecs, rn, i, &x) == VP_OK && same_material(&x, &m[i]));
    }
    fuzz_wclose(&b);
    free(m);
}

/* ---- TEXTURE_PUT ------------------------------------------------------------------- */

static void fuzz_texture_put(const uint8_t *p, size_t len)
{
    vp_texture_put m, w;
    char why[256] = "";
    int rc = vp_dec_texture_put(p, len, &m);
    check_why(rc, vp_dec_texture_put_why(p, len, &w, why, sizeof why), why);
    if (rc) return;
    CHECK(vp_texture_put_check(&m, NULL, 0) == VP_OK);
    CHECK(m.id && m.format <= VP_TEX_EXR && m.total >= 1 && m.total <= VP_MAX_TEXTURE_BYTES);
    CHECK(m.len >= 1 && m.len == len - VP_TEXTURE_PUT_HEADER && m.data == p + VP_TEXTURE_PUT_HEADER);
    CHECK((uint64_t)m.offset + m.len <= m.total);
    fuzz_wbuf b;
    fuzz_wopen(&b, vp_size_texture_put(m.len));
    vp_enc_texture_put(&b.w, 6, &m);
    const uint8_t *q = enc_payload(&b, VP_TEXTURE_PUT, len);
    CHECK(memcmp(q, p, len) == 0);
    vp_texture_put r;
    CHECK(vp_dec_texture_put(q, len, &r) == VP_OK);
    CHECK(r.id == m.id && r.format == m.format && r.flags == m.flags && r.total == m.total && r.offset == m.offset &&
          r.len == m.len);
    fuzz_wclose(&b);
}

/* ---- ENV_SET / ENV_REPLY ----------------------------------------------------------- */

static bool same_env(const vp_env *a, const vp_env *b)
{
    return same_f32s(a->sun_dir, b->sun_dir, 3) && same_f32s(a->sun_color, b->sun_color, 3) &&
           same_f32(a->sun_lux, b->sun_lux) && a->sky_mode == b->sky_mode && a->flags == b->flags &&
           a->exposure_mode == b->exposure_mode && same_f32s(a->sky_color, b->sky_color, 3) &&
           same_f32(a->sky_intensity, b->sky_intensity) && same_f32(a->turbidity, b->turbidity) &&
           a->sky_texture == b->sky_texture && same_f32(a->sky_rotation, b->sky_rotation) &&
           same_f64(a->ground_height, b->ground_height) && same_f32s(a->ground_color, b->ground_color, 3) &&
           a->ground_material == b->ground_material && same_f32(a->fog_density, b->fog_density) &&
           same_f32s(a->fog_color, b->fog_color, 3) && same_f32(a->fog_height_falloff, b->fog_height_falloff) &&
           same_f32(a->exposure_ev, b->exposure_ev) && same_f32(a->exposure_comp, b->exposure_comp);
}

static void fuzz_env(const uint8_t *p, size_t len, uint16_t type)
{
    vp_env m, w;
    char why[256] = "";
    int rc = vp_dec_env(p, len, &m);
    check_why(rc, vp_dec_env_why(p, len, &w, why, sizeof why), why);
    if (rc) return;
    CHECK(len == VP_ENV_SIZE);
    vp_env c = m;
    CHECK(vp_env_check(&c, NULL, 0) == VP_OK && same_env(&c, &m)); /* checking again changes nothing */
    bool changed = false;
    for (int k = 0; k < 3; k++) changed |= !same_f32(m.sun_dir[k], vp_ld_f32(p + 4 * k));
    fuzz_wbuf b;
    fuzz_wopen(&b, vp_size_env());
    vp_enc_env(&b.w, type, 7, &m);
    const uint8_t *q = enc_payload(&b, type, len);
    CHECK(changed || memcmp(q, p, len) == 0);
    vp_env r;
    CHECK(vp_dec_env(q, len, &r) == VP_OK && same_env(&r, &m));
    fuzz_wclose(&b);
}

/* ---- version 1 records, as a journal holds them ------------------------------------ */

/* ENTITY_ADD / UPDATE of 104-byte records: each is a bounds entity of
 * material 0 (no transform), and upgraded to version 2 (the records
 * re-encoded) it decodes to the same entity. */
static void fuzz_entities_v1(const uint8_t *p, size_t len, uint32_t limit)
{
    vp_entity_batch m = {0}, lim = {0};
    int rc = vp_dec_entities_v1(p, len, 0, &m), rcl = vp_dec_entities_v1(p, len, limit, &lim);
    check_limit(rc, m.count, rcl, lim.count, limit);
    if (rc) return;
    CHECK(m.version == 1 && len == 4 + (size_t)m.count * VP_ENTITY_REC_SIZE_V1);
    vp_entity *e = read_entities(&m);
    for (uint32_t i = 0; i < m.count; i++) {
        static const float zero[4];
        const uint8_t *rec = m.recs + (size_t)i * VP_ENTITY_REC_SIZE_V1;
        CHECK(e[i].material == 0 && !(e[i].flags & ~VP_ENT_DYNAMIC) && e[i].flags == vp_ld_u32(rec + 16));
        CHECK(e[i].id == vp_ld_u64(rec) && same_f64(e[i].sphere[0], vp_ld_f64(rec + 24)) &&
              same_f64(e[i].aabb[5], vp_ld_f64(rec + 96)));
        CHECK(same_f32s(e[i].rot, zero, 4) && same_f32s(e[i].scale, zero, 3));
    }
    fuzz_wbuf b;
    fuzz_wopen(&b, vp_size_entities(m.count));
    vp_enc_entities(&b.w, VP_ENTITY_ADD, 6, e, m.count);
    size_t len2 = 4 + (size_t)m.count * VP_ENTITY_REC_SIZE;
    const uint8_t *q = enc_payload(&b, VP_ENTITY_ADD, len2);
    vp_entity_batch r;
    CHECK(vp_dec_entities(q, len2, 0, &r) == VP_OK && r.count == m.count && r.version == 2);
    for (uint32_t i = 0; i < r.count; i++) {
        vp_entity x;
        CHECK(vp_entity_get(&r, i, &x) == VP_OK && same_entity(&x, &e[i]));
    }
    fuzz_wclose(&b);
    free(e);
}

/* OCCLUDER_PUT without flags: flags 0; as version 2 (flags 0) the same. */
static void fuzz_occluder_v1(const uint8_t *p, size_t len, uint32_t limit)
{
    vp_occluder m;
    int rc = vp_dec_occluder_v1(p, len, limit, &m);
    check_code(rc);
    if (rc) return;
    CHECK(m.flags == 0 && len == 36 + (size_t)m.tri_count * 36 && m.verts == p + 36);
    fuzz_wbuf b;
    fuzz_wopen(&b, vp_size_occluder(m.tri_count));
    float *v = malloc(9 * (size_t)m.tri_count * sizeof *v + 1);
    CHECK(v != NULL);
    for (size_t k = 0; k < 9 * (size_t)m.tri_count; k++) v[k] = vp_ld_f32(m.verts + 4 * k);
    vp_enc_occluder_flags(&b.w, 8, m.id, 0, m.origin, v, m.tri_count);
    const uint8_t *q = enc_payload(&b, VP_OCCLUDER_PUT, len + 4);
    CHECK(memcmp(q + 12, p + 8, len - 8) == 0 && vp_ld_u64(q) == m.id && vp_ld_u32(q + 8) == 0);
    vp_occluder r;
    CHECK(vp_dec_occluder(q, len + 4, 0, &r) == VP_OK && r.id == m.id && r.flags == 0 &&
          same_f64s(r.origin, m.origin, 3) && r.tri_count == m.tri_count);
    free(v);
    fuzz_wclose(&b);
}

#endif
