/*
 * snapshot.c — the scene written whole and read back exactly (snapshot.h).
 *
 * The body of format 3 ("VNTSNAP3"), in order (integers and floats
 * little-endian, vp_bytes.h; the arrays of floats and ids copied as they
 * are, the host being little-endian):
 *   u64 epoch, edits, debris_next; u32 sub-levels
 *   per sub-level 1..n: u8 name length, name, u8 state, u32 owner,
 *     u16 class base, u16 classes, u32 members capacity, u32 members, u64
 *     ids; u32 doomed, u32 doomed done, u64 ids
 *   u32 hidden words, per: u32 word index, u64 bits (the non-zero words of
 *     hidden[CULL_SUBLEVEL_WORDS]); u32 hidden count, u32 unloading
 *   u32 reserved classes, per: u16 class, u16 owner (the non-zero ones)
 *   u32 textures (by id); per: u32 length, a whole TEXTURE_PUT payload
 *     (offset 0: id, format, flags and the bytes as uploaded)
 *   u32 materials (by id); per chunk of up to 4096: u32 length, a
 *     MATERIAL_PUT payload
 *   the environment: a 120-byte ENV_SET payload
 *   u32 meshes; per: u32 length, a MESH_PUT payload (UVs, tangents)
 *   u32 slots, u16 generation each, u32 free, u32 free list
 *   u32 entities; per chunk of up to 4096: an ENTITY_ADD payload (160-byte
 *     records: material, transform), u32 handles
 *   u32 destruction volumes; per: u64 entity id, f64 origin[3], step[3],
 *     u32 n[3], u64 version, u32 spheres, f64 x4 each, f32 d, px, py, pz,
 *     u8 local spheres (1: f64 x4 per sphere follow: the destruction of a
 *     transform entity, in its local space)
 *   u32 occluders; per: u64 id, u16 sub-level, u32 flags (VP_OCC_*), f64
 *     origin[3], u32 triangles, f32 x9 each
 *   u32 lights; per: u16 sub-level, an 80-byte LIGHT_PUT record
 * Textures, materials, the environment and meshes are restored through
 * the live path (edit_decode / edit_apply of their payloads), so a texture
 * is decoded and its mips built as an upload's are, and every check and
 * count (users) is the live one's; textures before the materials naming
 * them, both before the environment and the entities using them.
 *
 * Older formats, still read (a version 1 daemon wrote them):
 *   format 2 ("VNTSNAP2"): no textures, materials, environment; meshes as
 *     u16 class, u32 vertices, u32 indices, f32 pos, u8 has normals, f32
 *     normals, u32 indices; entities in 104-byte records (bounds entities,
 *     material 0); no local spheres; occluders without flags;
 *   format 1 ("VNTSNAP1"): format 2 with u64 hidden[CULL_SUBLEVEL_WORDS],
 *     u32 hidden count, u32 unloading, u16 class owner[65536], whole.
 * The child of a fork writes it (journal.c), so everything here reads the
 * scene without locks and allocates only its own buffers.
 */
#include "snapshot.h"
#include "edit.h"
#include "vp_err.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <zlib.h>

_Static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__, "snapshots are written in the host's order: little-endian");

#define HDR 40u
#define CHUNK 4096u
/* by format - 1; the last is written, the others read */
static const char MAGIC[SNAPSHOT_FORMAT][8] = {
    {'V', 'N', 'T', 'S', 'N', 'A', 'P', '1'}, /* dense arrays */
    {'V', 'N', 'T', 'S', 'N', 'A', 'P', '2'}, /* protocol version 1's records */
    {'V', 'N', 'T', 'S', 'N', 'A', 'P', '3'},
};

/* ---- writing: a buffered stream with a running CRC ---------------------------------------- */

typedef struct out {
    int fd;
    vp_writer w;    /* over a buffer of its own, written out when full */
    uint64_t total; /* bytes written out */
    uLong crc;      /* of them */
    int err;
} out;

static void flush(out *o)
{
    if (o->w.len) {
        o->crc = crc32(o->crc, o->w.p, (uInt)o->w.len); /* the buffer is < 4 GiB */
        o->total += o->w.len;
    }
    size_t done = 0;
    while (!o->err && done < o->w.len) {
        ssize_t w = write(o->fd, o->w.p + done, o->w.len - done);
        if (w > 0) done += (size_t)w;
        else if (w < 0 && errno == EINTR) continue;
        else o->err = w < 0 ? errno : ENOSPC;
    }
    o->w.len = 0;
}

/* The writer, with room for one more scalar (8 bytes). */
static vp_writer *wr(out *o)
{
    if (o->w.cap - o->w.len < 8) flush(o);
    return &o->w;
}

/* n bytes as they are (host order: the arrays of floats and ids), streamed
 * through the buffer; p may be NULL when n is 0 (a sub-level with no
 * members yet). */
static void put(out *o, const void *p, size_t n)
{
    const uint8_t *b = p;
    while (n) {
        if (o->w.len == o->w.cap) flush(o);
        size_t k = n < o->w.cap - o->w.len ? n : o->w.cap - o->w.len;
        vp_put_bytes(&o->w, b, k);
        b += k;
        n -= k;
    }
}

/* A sub-level's fixed fields, in file order, written from a scene_sublevel
 * and read into a sl_saved (the same names): one list for both ways. */
#define SL_FIELDS(X) X(u8, state) X(u32, owner) X(u16, class_base) X(u16, classes) X(u32, members_cap) X(u32, nmembers)

static void write_sublevels(out *o, const scene *s)
{
    vp_put_u32(wr(o), s->nsublevels);
    for (uint32_t id = 1; id <= s->nsublevels; id++) {
        const scene_sublevel *l = &s->sl[id];
        size_t nl = strlen(l->name);
        vp_put_u8(wr(o), (uint8_t)nl);
        put(o, l->name, nl);
#define SL_PUT(t, f) vp_put_##t(wr(o), l->f);
        SL_FIELDS(SL_PUT)
#undef SL_PUT
        put(o, l->members, (size_t)l->nmembers * 8);
        vp_put_u32(wr(o), l->ndoomed);
        vp_put_u32(wr(o), l->doomed_pos);
        put(o, l->doomed, (size_t)l->ndoomed * 8);
    }
    /* the hidden bitmap and the class owners, sparse (version 2): a
       small scene's snapshot is a few kB, not the 136 kB of the two
       arrays whole (version 1, still read) */
    uint32_t n = 0;
    for (uint32_t i = 0; i < CULL_SUBLEVEL_WORDS; i++) n += s->hidden[i] != 0;
    vp_put_u32(wr(o), n);
    for (uint32_t i = 0; i < CULL_SUBLEVEL_WORDS; i++)
        if (s->hidden[i]) {
            vp_put_u32(wr(o), i);
            vp_put_u64(wr(o), s->hidden[i]);
        }
    vp_put_u32(wr(o), s->nhidden);
    vp_put_u32(wr(o), s->unloading);
    n = 0;
    for (uint32_t c = 0; c < 65536; c++) n += s->class_owner[c] != 0;
    vp_put_u32(wr(o), n);
    for (uint32_t c = 0; c < 65536; c++)
        if (s->class_owner[c]) {
            vp_put_u16(wr(o), (uint16_t)c);
            vp_put_u16(wr(o), s->class_owner[c]);
        }
}

typedef struct kv {
    uint64_t k, v;
} kv;

static int cmp_key(const void *a, const void *b)
{
    uint64_t x = ((const kv *)a)->k, y = ((const kv *)b)->k;
    return (x > y) - (x < y);
}

/* The entries of map m by id, ascending (a snapshot does not depend on the
 * map's history); NULL when out of memory (*n = SIZE_MAX) or empty. */
static kv *sorted_entries(const idmap *m, size_t *n)
{
    *n = 0;
    kv *e = m->count ? malloc(m->count * sizeof *e) : NULL;
    if (m->count && !e) {
        *n = SIZE_MAX;
        return NULL;
    }
    for (size_t i = 0; i < m->cap; i++)
        if (m->used[i]) e[(*n)++] = (kv){m->keys[i], m->vals[i]};
    if (*n > 1) qsort(e, *n, sizeof *e, cmp_key);
    return e;
}

/* Textures, materials and the environment: payloads of the messages that
 * make them (snapshot_load applies them as they came). 0, or -ENOMEM. */
static int write_model(out *o, const scene *s)
{
    size_t nt, nm;
    kv *tex = sorted_entries(&s->textures, &nt), *mat = sorted_entries(&s->materials, &nm);
    vp_material *recs = malloc(CHUNK * sizeof *recs);
    size_t bufsz = vp_size_materials(CHUNK) > vp_size_env() ? vp_size_materials(CHUNK) : vp_size_env();
    uint8_t *buf = malloc(bufsz);
    int rc = nt == SIZE_MAX || nm == SIZE_MAX || !recs || !buf ? -ENOMEM : 0;
    vp_writer w;
    if (!rc) vp_put_u32(wr(o), (uint32_t)nt);
    for (size_t i = 0; !rc && i < nt; i++) {
        /* the TEXTURE_PUT header as its encoder writes it, then the bytes
           streamed (a texture is up to 64 MiB: not copied) */
        const scene_texture *t = (const scene_texture *)(uintptr_t)tex[i].v;
        vp_writer_init(&w, buf, bufsz);
        vp_enc_texture_put(&w, 0, &(vp_texture_put){.id = t->id, .format = t->format, .flags = t->flags,
                                                      .total = t->nbytes});
        vp_put_u32(wr(o), (uint32_t)(w.len - VP_HEADER_SIZE + t->nbytes));
        put(o, buf + VP_HEADER_SIZE, w.len - VP_HEADER_SIZE);
        put(o, t->bytes, t->nbytes);
    }
    if (!rc) vp_put_u32(wr(o), (uint32_t)nm);
    for (size_t i = 0; !rc && i < nm;) {
        uint32_t k = 0;
        for (; k < CHUNK && i < nm; i++) recs[k++] = ((const scene_material *)(uintptr_t)mat[i].v)->m;
        vp_writer_init(&w, buf, bufsz);
        vp_enc_materials(&w, 0, recs, k);
        vp_put_u32(wr(o), (uint32_t)(w.len - VP_HEADER_SIZE));
        put(o, buf + VP_HEADER_SIZE, w.len - VP_HEADER_SIZE);
    }
    if (!rc) {
        vp_writer_init(&w, buf, bufsz);
        vp_enc_env(&w, VP_ENV_SET, 0, &s->env);
        put(o, buf + VP_HEADER_SIZE, w.len - VP_HEADER_SIZE);
    }
    free(tex);
    free(mat);
    free(recs);
    free(buf);
    return rc;
}

/* Each mesh as a MESH_PUT payload, streamed: its 12-byte head (u16 class,
 * u16 VP_MESH_* flags, u32 vertices, u32 indices: protocol.h's layout,
 * which the decoder checks on the way back), then the arrays. */
static void write_meshes(out *o, const scene *s)
{
    uint32_t n = 0;
    for (uint32_t c = 0; c < 65536; c++) n += s->meshes[c].pos != NULL;
    vp_put_u32(wr(o), n);
    for (uint32_t c = 0; c < 65536; c++) {
        const scene_mesh *m = &s->meshes[c];
        if (!m->pos) continue;
        const float *tan = m->uv ? m->tan : NULL;
        uint16_t flags = (uint16_t)((m->nrm ? 0 : VP_MESH_NO_NORMALS) | (m->uv ? VP_MESH_UVS : 0) |
                                    (tan ? VP_MESH_TANGENTS : 0));
        size_t per = 12 + (m->nrm ? 12 : 0) + (m->uv ? 8 : 0) + (tan ? 16 : 0);
        vp_put_u32(wr(o), (uint32_t)(12 + (size_t)m->nv * per + (size_t)m->ni * 4));
        vp_put_u16(wr(o), (uint16_t)c);
        vp_put_u16(wr(o), flags);
        vp_put_u32(wr(o), m->nv);
        vp_put_u32(wr(o), m->ni);
        put(o, m->pos, (size_t)m->nv * 12);
        if (m->nrm) put(o, m->nrm, (size_t)m->nv * 12);
        if (m->uv) put(o, m->uv, (size_t)m->nv * 8);
        if (tan) put(o, tan, (size_t)m->nv * 16);
        put(o, m->idx, (size_t)m->ni * 4);
    }
}

static int write_entities(out *o, const scene *s)
{
    uint32_t nslots = cull_world_slots(s->world);
    uint16_t *gens = malloc(((size_t)nslots + 1) * sizeof *gens);
    uint32_t *fl = malloc(((size_t)nslots + 1) * sizeof *fl);
    vp_entity *recs = malloc(CHUNK * sizeof *recs);
    uint32_t *hs = malloc(CHUNK * sizeof *hs);
    size_t bufsz = VP_HEADER_SIZE + 4 + (size_t)CHUNK * VP_ENTITY_REC_SIZE;
    uint8_t *buf = malloc(bufsz);
    if (!gens || !fl || !recs || !hs || !buf) {
        free(gens);
        free(fl);
        free(recs);
        free(hs);
        free(buf);
        return -ENOMEM;
    }
    uint32_t live = 0;
    for (uint32_t i = 0; i < nslots; i++) {
        bool on;
        gens[i] = (uint16_t)cull_world_slot_gen(s->world, i, &on);
        live += on;
    }
    uint32_t nfree = cull_world_free_list(s->world, fl, nslots);
    vp_put_u32(wr(o), nslots);
    put(o, gens, (size_t)nslots * 2);
    vp_put_u32(wr(o), nfree);
    put(o, fl, (size_t)nfree * 4);
    vp_put_u32(wr(o), live);
    uint32_t k = 0;
    for (uint32_t i = 0; i <= nslots; i++) {
        bool on = false;
        uint32_t g = i < nslots ? cull_world_slot_gen(s->world, i, &on) : 0;
        if (on) {
            cull_handle h = (g << CULL_HANDLE_SLOT_BITS) | i;
            scene_entity_record(s, h, &recs[k]);
            hs[k++] = h;
        }
        if (k == CHUNK || (i == nslots && k)) {
            vp_writer w;
            vp_writer_init(&w, buf, bufsz);
            vp_enc_entities(&w, VP_ENTITY_ADD, 0, recs, k);
            vp_put_u32(wr(o), (uint32_t)(w.len - VP_HEADER_SIZE));
            put(o, buf + VP_HEADER_SIZE, w.len - VP_HEADER_SIZE);
            put(o, hs, (size_t)k * 4);
            k = 0;
        }
    }
    free(gens);
    free(fl);
    free(recs);
    free(hs);
    free(buf);
    return 0;
}

static void write_items(out *o, const scene *s)
{
    vp_put_u32(wr(o), (uint32_t)s->destruct.count);
    for (size_t i = 0; i < s->destruct.cap; i++) {
        if (!s->destruct.used[i]) continue;
        const cull_dvol *v = &((const scene_destruct *)(uintptr_t)s->destruct.vals[i])->v;
        size_t total = (size_t)v->n[0] * v->n[1] * v->n[2];
        vp_put_u64(wr(o), s->destruct.keys[i]);
        put(o, v->origin, sizeof v->origin);
        put(o, v->step, sizeof v->step);
        put(o, v->n, sizeof v->n);
        vp_put_u64(wr(o), v->version);
        vp_put_u32(wr(o), v->nsph);
        put(o, v->sph, (size_t)v->nsph * sizeof *v->sph);
        put(o, v->d, total * 4);
        put(o, v->px, total * 4);
        put(o, v->py, total * 4);
        put(o, v->pz, total * 4);
        const double(*local)[4] = ((const scene_destruct *)(uintptr_t)s->destruct.vals[i])->local;
        vp_put_u8(wr(o), local != NULL);
        if (local) put(o, local, (size_t)v->nsph * sizeof *local);
    }
    vp_put_u32(wr(o), (uint32_t)s->occluders.count);
    for (size_t i = 0; i < s->occluders.cap; i++) {
        if (!s->occluders.used[i]) continue;
        const scene_occluder *oc = (const scene_occluder *)(uintptr_t)s->occluders.vals[i];
        vp_put_u64(wr(o), oc->id);
        vp_put_u16(wr(o), oc->sublevel);
        vp_put_u32(wr(o), oc->flags);
        put(o, oc->origin, sizeof oc->origin);
        vp_put_u32(wr(o), oc->ntris);
        put(o, oc->verts, (size_t)oc->ntris * 36);
    }
    vp_put_u32(wr(o), (uint32_t)s->lights.count);
    for (size_t i = 0; i < s->lights.cap; i++) {
        if (!s->lights.used[i]) continue;
        const scene_light *l = (const scene_light *)(uintptr_t)s->lights.vals[i];
        uint8_t buf[VP_HEADER_SIZE + 4 + VP_LIGHT_SIZE];
        vp_writer w;
        vp_writer_init(&w, buf, sizeof buf);
        vp_enc_lights(&w, 0, &l->l, 1);
        vp_put_u16(wr(o), l->sublevel);
        put(o, buf + VP_HEADER_SIZE + 4, VP_LIGHT_SIZE);
    }
}

int snapshot_write(int fd, const scene *s, uint64_t gen, uint64_t seq)
{
    out o = {.fd = fd, .crc = crc32(0L, Z_NULL, 0)};
    size_t cap = 1u << 20;
    uint8_t *buf = malloc(cap);
    if (!buf) return -ENOMEM;
    vp_writer_init(&o.w, buf, cap);
    if (lseek(fd, HDR, SEEK_SET) != (off_t)HDR) {
        free(buf);
        return -errno;
    }
    vp_put_u64(wr(&o), s->epoch);
    vp_put_u64(wr(&o), s->edits);
    vp_put_u64(wr(&o), s->debris_next);
    write_sublevels(&o, s);
    int rc = write_model(&o, s);
    write_meshes(&o, s);
    if (!rc) rc = write_entities(&o, s);
    write_items(&o, s);
    flush(&o);
    free(buf);
    if (rc) return rc;
    if (o.err) return -o.err;
    uint8_t h[HDR];
    vp_writer hw;
    vp_writer_init(&hw, h, sizeof h);
    vp_put_bytes(&hw, MAGIC[SNAPSHOT_FORMAT - 1], 8);
    vp_put_u64(&hw, gen);
    vp_put_u64(&hw, seq);
    vp_put_u64(&hw, o.total);
    vp_put_u32(&hw, (uint32_t)o.crc);
    vp_put_u32(&hw, (uint32_t)crc32(crc32(0L, Z_NULL, 0), h, 36));
    if (pwrite(fd, h, HDR, 0) != (ssize_t)HDR) return errno ? -errno : -EIO;
    return 0;
}

/* ---- reading: vp_bytes.h's checked reader ------------------------------------------------------ */

/* r->short_read is the reader's sticky failure: set by a read past the end
 * and, here, by an inconsistent record too, it stops every later read.
 *
 * A fresh array of n elements of size sz copied from the stream (NULL when
 * n is 0 or the stream is short / memory out: *nomem set for the latter). */
static void *take_array(vp_reader *r, size_t n, size_t sz, bool *nomem)
{
    if (!n) return NULL;
    const uint8_t *p = vp_get_array(r, n, sz);
    if (!p) return NULL;
    void *m = malloc(n * sz);
    if (!m) {
        *nomem = true;
        return NULL;
    }
    memcpy(m, p, n * sz);
    return m;
}

typedef struct sl_saved {
    uint8_t state;
    uint32_t owner, members_cap, nmembers, ndoomed, doomed_pos;
    uint16_t class_base, classes;
    uint64_t *members, *doomed;
} sl_saved;

/* Restores one piece through the live path: payload p (len bytes) of
 * request type, applied as connection loading `load` would apply it (e
 * the decoded edit). VP_OK, or the code with why saying what was refused. */
static int restore_edit(scene *s, uint16_t type, const uint8_t *p, uint32_t len, uint16_t load, edit *e, char *why,
                        size_t whylen)
{
    int rc = edit_decode(type, p, len, 0, EDIT_LAYOUT, e);
    if (rc) return vp_errf(why, whylen, rc, "%s: %s", vp_type_name(type), vp_strerror(rc));
    e->sublevel = load;
    edit_result res;
    scene_err se = {0};
    rc = edit_apply(s, e, &res, &se);
    if (rc) return vp_errf(why, whylen, rc, "%s: %s", vp_type_name(type), se.msg);
    edit_result_free(&res);
    return VP_OK;
}

/* Format 3's textures, materials and environment (in that order: each
 * may name the ones before). 0, or -1 with why. */
static int load_model(vp_reader *r, scene *s, char *why, size_t whylen)
{
    char msg[200];
    edit e;
    uint32_t nt = vp_get_u32(r);
    for (uint32_t i = 0; i < nt && !r->short_read; i++) {
        uint32_t len = vp_get_u32(r);
        const uint8_t *p = vp_get_bytes(r, len);
        vp_texture_put t;
        if (!p) break;
        if (vp_dec_texture_put(p, len, &t) || t.offset || t.len != t.total)
            return vp_errf(why, whylen, -1, "texture %u of %u is not a whole TEXTURE_PUT", i, nt);
        if (restore_edit(s, VP_TEXTURE_PUT, p, len, 0, &e, msg, sizeof msg))
            return vp_errf(why, whylen, -1, "texture %u cannot be restored: %s", t.id, msg);
    }
    uint32_t nm = vp_get_u32(r);
    for (uint32_t done = 0; done < nm && !r->short_read;) {
        uint32_t len = vp_get_u32(r);
        const uint8_t *p = vp_get_bytes(r, len);
        if (!p) break;
        if (restore_edit(s, VP_MATERIAL_PUT, p, len, 0, &e, msg, sizeof msg))
            return vp_errf(why, whylen, -1, "materials cannot be restored: %s", msg);
        if (e.count > nm - done) return vp_errf(why, whylen, -1, "%s", "more materials than the snapshot holds");
        done += e.count;
    }
    const uint8_t *env = vp_get_bytes(r, VP_ENV_SIZE);
    if (r->short_read) return vp_errf(why, whylen, -1, "%s", "truncated or corrupt");
    /* the environment a fresh scene has (most scenes') is not set again */
    uint8_t cur[VP_HEADER_SIZE + VP_ENV_SIZE];
    vp_writer w;
    vp_writer_init(&w, cur, sizeof cur);
    vp_enc_env(&w, VP_ENV_SET, 0, &s->env);
    if (memcmp(cur + VP_HEADER_SIZE, env, VP_ENV_SIZE) &&
        restore_edit(s, VP_ENV_SET, env, VP_ENV_SIZE, 0, &e, msg, sizeof msg))
        return vp_errf(why, whylen, -1, "the environment cannot be restored: %s", msg);
    return 0;
}

/* A mesh of format 1 or 2 (u16 class, u32 vertices, u32 indices, f32 pos,
 * u8 has normals, f32 normals, u32 indices) as the MESH_PUT it was made
 * by, applied. 0, or -1 with why (the reader stopped). */
static int load_mesh_v2(vp_reader *r, scene *s, char *why, size_t whylen)
{
    bool nomem = false;
    uint16_t c = vp_get_u16(r);
    uint32_t nv = vp_get_u32(r), ni = vp_get_u32(r);
    float *pos = take_array(r, nv, 12, &nomem), *nrm = vp_get_u8(r) ? take_array(r, nv, 12, &nomem) : NULL;
    uint32_t *idx = take_array(r, ni, 4, &nomem);
    size_t sz = r->short_read || nomem ? 0 : vp_size_mesh(nv, ni, nrm != NULL);
    uint8_t *buf = sz ? malloc(sz) : NULL;
    int rc = -1;
    if (r->short_read) vp_errf(why, whylen, -1, "%s", "truncated or corrupt");
    else if (nomem || !buf) vp_errf(why, whylen, -1, "%s", "out of memory");
    else if (s->meshes[c].pos) vp_errf(why, whylen, -1, "%s", "a mesh class twice");
    else {
        vp_writer w;
        vp_writer_init(&w, buf, sz);
        vp_enc_mesh(&w, 0, c, pos, nrm, nv, idx, ni);
        edit e;
        rc = restore_edit(s, VP_MESH_PUT, buf + VP_HEADER_SIZE, (uint32_t)(w.len - VP_HEADER_SIZE),
                          s->class_owner[c], &e, why, whylen) ? -1 : 0;
    }
    free(pos);
    free(nrm);
    free(idx);
    free(buf);
    return rc;
}

/* Format 3's meshes: MESH_PUT payloads. 0, or -1 with why. */
static int load_meshes(vp_reader *r, scene *s, unsigned fmt, char *why, size_t whylen)
{
    uint32_t nm = vp_get_u32(r);
    for (uint32_t i = 0; i < nm && !r->short_read; i++) {
        if (fmt < 3) {
            if (load_mesh_v2(r, s, why, whylen)) return -1;
            continue;
        }
        uint32_t len = vp_get_u32(r);
        const uint8_t *p = vp_get_bytes(r, len);
        if (!p) break;
        uint16_t c = len >= 2 ? vp_ld_u16(p) : 0;
        edit e;
        if (s->meshes[c].pos) return vp_errf(why, whylen, -1, "%s", "a mesh class twice");
        if (restore_edit(s, VP_MESH_PUT, p, len, s->class_owner[c], &e, why, whylen)) return -1;
    }
    return r->short_read ? vp_errf(why, whylen, -1, "%s", "truncated or corrupt") : 0;
}

static int load_body(vp_reader *r, unsigned fmt, scene *s, char *err, size_t errlen)
{
    char whybuf[240];
    bool nomem = false;
    uint64_t epoch = vp_get_u64(r), edits = vp_get_u64(r), debris = vp_get_u64(r);
    uint32_t nsl = vp_get_u32(r);
    if (nsl > SCENE_MAX_SUBLEVELS) return vp_errf(err, errlen, -1, "%s", "more sub-levels than a scene holds");
    sl_saved *sv = calloc((size_t)nsl + 1, sizeof *sv);
    if (!sv) return vp_errf(err, errlen, -1, "%s", "out of memory");
    int ret = -1;
    const char *why = "truncated or corrupt";
    for (uint32_t id = 1; id <= nsl && !r->short_read; id++) {
        uint8_t nl = vp_get_u8(r);
        const char *name = (const char *)vp_get_bytes(r, nl);
        if (!name) break;
        s->sl[id].name = strndup(name, nl);
        s->nsublevels = id;
        sl_saved *v = &sv[id];
#define SL_GET(t, f) v->f = vp_get_##t(r);
        SL_FIELDS(SL_GET)
#undef SL_GET
        v->members = take_array(r, v->nmembers, 8, &nomem);
        v->ndoomed = vp_get_u32(r);
        v->doomed_pos = vp_get_u32(r);
        v->doomed = take_array(r, v->ndoomed, 8, &nomem);
        if (!s->sl[id].name || nomem) goto out_nomem;
        if (v->nmembers > v->members_cap || v->doomed_pos > v->ndoomed ||
            (v->state && v->state != VP_SL_LOADING && v->state != VP_SL_UNLOADING)) {
            why = "a sub-level record is inconsistent";
            r->short_read = true;
        }
    }
    uint64_t hidden[CULL_SUBLEVEL_WORDS] = {0};
    uint32_t nhidden, unloading;
    if (fmt == 1) {
        vp_get_copy(r, hidden, sizeof hidden);
        nhidden = vp_get_u32(r);
        unloading = vp_get_u32(r);
        vp_get_copy(r, s->class_owner, 65536 * sizeof *s->class_owner);
    } else {
        uint32_t n = vp_get_u32(r);
        for (uint32_t i = 0; i < n && !r->short_read; i++) {
            uint32_t w = vp_get_u32(r);
            uint64_t bits = vp_get_u64(r);
            if (w >= CULL_SUBLEVEL_WORDS || hidden[w] || !bits) {
                why = "the hidden sub-levels are inconsistent";
                r->short_read = true;
            } else {
                hidden[w] = bits;
            }
        }
        nhidden = vp_get_u32(r);
        unloading = vp_get_u32(r);
        n = vp_get_u32(r);
        for (uint32_t i = 0; i < n && !r->short_read; i++) {
            uint16_t c = vp_get_u16(r), owner = vp_get_u16(r);
            if (s->class_owner[c] || !owner) {
                why = "the class reservations are inconsistent";
                r->short_read = true;
            } else {
                s->class_owner[c] = owner;
            }
        }
    }
    if (r->short_read) goto out;
    /* what the entities name, then the meshes */
    if ((fmt >= 3 && load_model(r, s, whybuf, sizeof whybuf)) || load_meshes(r, s, fmt, whybuf, sizeof whybuf)) {
        why = whybuf;
        r->short_read = true;
        goto out;
    }
    /* the handle allocator, then the entities at their handles */
    uint32_t nslots = vp_get_u32(r);
    if (nslots > CULL_MAX_ENTITIES) {
        r->short_read = true;
        goto out;
    }
    uint16_t *gens = take_array(r, nslots, 2, &nomem);
    uint32_t nfree = vp_get_u32(r);
    uint32_t *fl = take_array(r, nfree, 4, &nomem);
    int crc = r->short_read || nomem ? CULL_ERR_INVALID : cull_world_slots_restore(s->world, nslots, gens, fl, nfree);
    free(gens);
    free(fl);
    if (nomem) goto out_nomem;
    if (crc) {
        why = crc == CULL_ERR_NOMEM ? "out of memory" : "the handle table is inconsistent";
        r->short_read = true;
        goto out;
    }
    uint32_t live = vp_get_u32(r);
    for (uint32_t done = 0; done < live && !r->short_read;) {
        uint32_t len = vp_get_u32(r);
        const uint8_t *payload = vp_get_bytes(r, len);
        vp_entity_batch b;
        int drc = !payload ? VP_ERR_TRUNCATED
                  : fmt >= 3 ? vp_dec_entities(payload, len, 0, &b)
                             : vp_dec_entities_v1(payload, len, 0, &b);
        if (drc || b.count > live - done) {
            r->short_read = true;
            break;
        }
        const uint8_t *hs = vp_get_bytes(r, (size_t)b.count * 4);
        uint32_t *h = hs ? malloc((size_t)b.count * 4) : NULL;
        if (!hs) break;
        if (!h) goto out_nomem;
        memcpy(h, hs, (size_t)b.count * 4);
        scene_err se;
        int rc = scene_add_at(s, &b, h, &se);
        free(h);
        if (rc) {
            snprintf(err, errlen, "an entity cannot be restored: %s", se.msg);
            goto out_free;
        }
        done += b.count;
    }
    if (r->short_read) goto out;
    /* destruction volumes before the occluders (they are drawn cut) */
    uint32_t nd = vp_get_u32(r);
    for (uint32_t i = 0; i < nd && !r->short_read; i++) {
        uint64_t eid = vp_get_u64(r);
        scene_destruct *d = calloc(1, sizeof *d);
        if (!d || !idmap_reserve(&s->destruct, s->destruct.count + 1)) {
            free(d);
            goto out_nomem;
        }
        cull_dvol *v = &d->v;
        vp_get_copy(r, v->origin, sizeof v->origin);
        vp_get_copy(r, v->step, sizeof v->step);
        vp_get_copy(r, v->n, sizeof v->n);
        v->version = vp_get_u64(r);
        v->nsph = vp_get_u32(r);
        size_t total = (size_t)v->n[0] * v->n[1] * v->n[2];
        if (v->n[0] < 2 || v->n[1] < 2 || v->n[2] < 2 || v->n[0] > CULL_DVOL_MAX_RES || v->n[1] > CULL_DVOL_MAX_RES ||
            v->n[2] > CULL_DVOL_MAX_RES) {
            free(d);
            r->short_read = true;
            break;
        }
        v->sph = take_array(r, v->nsph, sizeof *v->sph, &nomem);
        v->cap = v->nsph;
        v->d = take_array(r, total, 4, &nomem);
        v->px = take_array(r, total, 4, &nomem);
        v->py = take_array(r, total, 4, &nomem);
        v->pz = take_array(r, total, 4, &nomem);
        uint8_t local = fmt >= 3 ? vp_get_u8(r) : 0;
        if (local == 1) d->local = take_array(r, v->nsph, sizeof *d->local, &nomem);
        idmap_put(&s->destruct, eid, (uint64_t)(uintptr_t)d); /* freed with the scene from here on */
        if (nomem) goto out_nomem;
        if (local > 1) r->short_read = true;
    }
    if (r->short_read) goto out;
    uint32_t no = vp_get_u32(r);
    for (uint32_t i = 0; i < no && !r->short_read; i++) {
        scene_occluder *oc = calloc(1, sizeof *oc);
        if (!oc || !idmap_reserve(&s->occluders, s->occluders.count + 1)) {
            free(oc);
            goto out_nomem;
        }
        oc->id = vp_get_u64(r);
        oc->sublevel = vp_get_u16(r);
        oc->flags = fmt >= 3 ? vp_get_u32(r) : 0;
        vp_get_copy(r, oc->origin, sizeof oc->origin);
        oc->ntris = vp_get_u32(r);
        oc->verts = take_array(r, (size_t)oc->ntris * 9, 4, &nomem);
        if (r->short_read || nomem || oc->sublevel > s->nsublevels || (oc->flags & ~VP_OCC_ATTACHED) ||
            idmap_get(&s->occluders, oc->id, NULL)) {
            free(oc->verts);
            free(oc);
            if (nomem) goto out_nomem;
            r->short_read = true;
            break;
        }
        idmap_put(&s->occluders, oc->id, (uint64_t)(uintptr_t)oc);
        s->sl[oc->sublevel].occluders++;
        if ((crc = scene_occluder_draw(s, oc, NULL)) != CULL_OK) {
            snprintf(err, errlen, "occluder %llu cannot be drawn: %s", (unsigned long long)oc->id,
                     cull_strerror(crc));
            goto out_free;
        }
    }
    uint32_t nli = vp_get_u32(r);
    for (uint32_t i = 0; i < nli && !r->short_read; i++) {
        uint16_t sub = vp_get_u16(r);
        const uint8_t *rec = vp_get_bytes(r, VP_LIGHT_SIZE);
        scene_light *l = malloc(sizeof *l);
        if (!l || !idmap_reserve(&s->lights, s->lights.count + 1)) {
            free(l);
            goto out_nomem;
        }
        if (!rec || sub > s->nsublevels || vp_light_get(rec, 1, 0, &l->l) || idmap_get(&s->lights, l->l.id, NULL)) {
            free(l);
            r->short_read = true;
            break;
        }
        l->sublevel = sub;
        idmap_put(&s->lights, l->l.id, (uint64_t)(uintptr_t)l);
        s->sl[sub].lights++;
    }
    if (r->short_read) goto out;
    if (r->pos != r->len) {
        why = "bytes after its end";
        goto out;
    }
    /* the sub-levels' own state, now that their content is back */
    for (uint32_t id = 1; id <= nsl; id++) {
        scene_sublevel *l = &s->sl[id];
        sl_saved *v = &sv[id];
        uint64_t *m = v->members_cap ? realloc(v->members, (size_t)v->members_cap * 8) : NULL;
        if (v->members_cap && !m) goto out_nomem;
        free(l->members);
        l->members = m;
        v->members = NULL;
        l->members_cap = v->members_cap;
        l->nmembers = v->nmembers;
        l->doomed = v->doomed;
        v->doomed = NULL;
        l->ndoomed = v->ndoomed;
        l->doomed_pos = v->doomed_pos;
        l->state = v->state;
        l->owner = v->owner;
        l->class_base = v->class_base;
        l->classes = v->classes;
    }
    memcpy(s->hidden, hidden, sizeof hidden);
    s->nhidden = nhidden;
    s->unloading = unloading;
    s->epoch = epoch;
    s->edits = edits;
    s->debris_next = debris;
    s->ev_added = s->ev_updated = s->ev_removed = 0;
    cull_world_commit(s->world);
    ret = 0;
    goto out_free;
out_nomem:
    why = "out of memory";
    r->short_read = true;
out:
    snprintf(err, errlen, "%s (at offset %zu)", why, r->pos + HDR);
out_free:
    for (uint32_t id = 0; id <= nsl; id++) {
        free(sv[id].members);
        free(sv[id].doomed);
    }
    free(sv);
    return ret;
}

unsigned snapshot_format(const uint8_t *p, size_t n)
{
    for (unsigned f = 1; n >= 8 && f <= SNAPSHOT_FORMAT; f++)
        if (!memcmp(p, MAGIC[f - 1], 8)) return f;
    return 0;
}

int snapshot_load(const uint8_t *p, size_t n, scene *s, uint64_t gen, uint64_t *seq, char *err, size_t errlen)
{
    char why[160];
    if (n < HDR) {
        snprintf(why, sizeof why, "shorter than its header (%zu bytes, offset 0)", n);
        return vp_errf(err, errlen, -1, "%s", why);
    }
    unsigned fmt = snapshot_format(p, n);
    if (!fmt) return vp_errf(err, errlen, -1, "%s", "not a Vantage snapshot (bad magic at offset 0)");
    vp_reader h;
    vp_reader_init(&h, p + 8, HDR - 8);
    uint64_t g = vp_get_u64(&h), first = vp_get_u64(&h), body = vp_get_u64(&h);
    uint32_t bc = vp_get_u32(&h), hc = vp_get_u32(&h);
    if (hc != (uint32_t)crc32(crc32(0L, Z_NULL, 0), p, 36)) return vp_errf(err, errlen, -1, "%s", "header CRC mismatch: the header (offset 0, 40 bytes) is damaged");
    *seq = first;
    if (g != gen) return vp_errf(err, errlen, -1, "%s", "its header names another generation (offset 8)");
    if (body != n - HDR) {
        snprintf(why, sizeof why, "truncated or extended: %zu bytes, its header says %llu (offset %zu)", n,
                 (unsigned long long)body + HDR, body < n - HDR ? (size_t)body + HDR : n);
        return vp_errf(err, errlen, -1, "%s", why);
    }
    uLong c = crc32(0L, Z_NULL, 0);
    for (size_t off = 0; off < body;) {
        uInt k = body - off > (1u << 30) ? (1u << 30) : (uInt)(body - off);
        c = crc32(c, p + HDR + off, k);
        off += k;
    }
    if ((uint32_t)c != bc) {
        snprintf(why, sizeof why, "body CRC mismatch: the body (offset %u, %llu bytes) is damaged", HDR,
                 (unsigned long long)body);
        return vp_errf(err, errlen, -1, "%s", why);
    }
    vp_reader r;
    vp_reader_init(&r, p + HDR, (size_t)body);
    return load_body(&r, fmt, s, err, errlen);
}
