/*
 * vp_layout.c — what vp_layout.h's layouts share out of line: the list of
 * every layout's description (vp_layout_count / _at / _find, for tools
 * and for tests/test_protocol_doc.c, which checks PROTOCOL.md's byte
 * tables against it) and the field checks' messages, so every decoder
 * names a bad field the same way. No allocation; the messages go to the
 * caller's buffer.
 */
#include "vp_internal.h"
#include "vp_layout.h"

#include <math.h>

/* Every VP_LAYOUT / VP_LAYOUT_CHECKED in protocol/ (tests/test_protocol_doc.c
 * reads the sources and fails for one missing here). */
#define VP_LAYOUT_NAMES(X)                                                                                      \
    X(hello_ok) X(ack) X(stats_reply) X(metrics_head) X(event) X(mesh) X(occluder) X(occluder_v1) X(light)    \
    X(entity) X(entity_v1) X(transform) X(list) X(list_reply) X(add_reply) X(mark) X(marked_head) X(select_head) X(selected_head) X(destroy)  \
    X(destroyed) X(view) X(vis_query) X(vis_result) X(vis_rec) X(render_tail) X(frame) X(light_query_tail)    \
    X(light_tiles) X(texref) X(material) X(texture_put) X(env) X(sublevel_begin) X(sublevel_begun) X(info)     \
    X(infos) X(mesh_get) X(material_list) X(texture_get) X(light_list)

#define VP_DESC_DECL_(name) const vp_layout_desc *vp_desc_##name(void);
VP_LAYOUT_NAMES(VP_DESC_DECL_)
#define VP_DESC_FN_(name) vp_desc_##name,
static const vp_layout_desc *(*const layouts[])(void) = {VP_LAYOUT_NAMES(VP_DESC_FN_)};

size_t vp_layout_count(void) { return sizeof layouts / sizeof layouts[0]; }

const vp_layout_desc *vp_layout_at(size_t i) { return i < vp_layout_count() ? layouts[i]() : NULL; }

const vp_layout_desc *vp_layout_find(const char *name)
{
    for (size_t i = 0; name && i < vp_layout_count(); i++)
        if (!strcmp(layouts[i]()->name, name)) return layouts[i]();
    return NULL;
}

const char *vp_kind_name(unsigned kind)
{
    static const char *const names[] = {"u8", "u16", "u32", "u64", "i32", "f32", "f64", "pad", "rsv"};
    return kind < sizeof names / sizeof names[0] ? names[kind] : "?";
}

/* ---- checks ------------------------------------------------------------------------ */

/* "pre label elem": element k of the comma-separated elems ("" or NULL: none). */
static void field_name(char *out, size_t cap, const char *pre, const char *label, const char *elems, size_t k)
{
    const char *e = elems && *elems ? elems : NULL;
    for (size_t i = 0; e && i < k; i++) {
        e = strchr(e, ',');
        if (e) e++;
    }
    size_t n = e ? strcspn(e, ",") : 0;
    snprintf(out, cap, "%s%s%s%.*s", pre ? pre : "", label, n ? " " : "", (int)n, e ? e : "");
}

int vp_check_floats(const void *v, size_t bytes, size_t esize, const char *pre, const char *label, const char *elems,
                    double lo, double hi, char *why, size_t whylen)
{
    const uint8_t *p = v;
    for (size_t k = 0; k < bytes / esize; k++) {
        double x;
        if (esize == 4) {
            float f;
            memcpy(&f, p + 4 * k, 4);
            x = f;
        } else {
            memcpy(&x, p + 8 * k, 8);
        }
        if (isfinite(x) && x >= lo && x <= hi) continue;
        char name[96];
        field_name(name, sizeof name, pre, label, elems, k);
        if (!isfinite(x)) return vp_errf(why, whylen, VP_ERR_NONFINITE, "%s is %g: NaN or infinite", name, x);
        return vp_errf(why, whylen, VP_ERR_INVALID, "%s %g is outside %g..%g", name, x, lo, hi);
    }
    return VP_OK;
}

int vp_check_max(uint64_t v, const char *pre, const char *label, const char *defined, double hi, char *why,
                 size_t whylen)
{
    if ((double)v <= hi) return VP_OK;
    return vp_errf(why, whylen, VP_ERR_INVALID, "%s%s %llu: %s", pre ? pre : "", label, (unsigned long long)v,
                   defined);
}

int vp_check_mask(uint64_t v, const char *pre, const char *label, const char *defined, double mask, char *why,
                  size_t whylen)
{
    uint64_t bad = v & ~(uint64_t)mask;
    if (!bad) return VP_OK;
    return vp_errf(why, whylen, VP_ERR_INVALID, "%s%s 0x%08llx has undefined bits 0x%08llx (%s)", pre ? pre : "",
                   label, (unsigned long long)v, (unsigned long long)bad, defined);
}

int vp_check_nonzero(uint64_t v, const char *pre, const char *label, const char *why0, char *why, size_t whylen)
{
    if (v) return VP_OK;
    return vp_errf(why, whylen, VP_ERR_INVALID, "%s%s is 0: %s", pre ? pre : "", label, why0);
}

int vp_check_count(uint64_t v, const char *pre, const char *label, double lo, double hi, int code, char *why,
                   size_t whylen)
{
    if ((double)v >= lo && (double)v <= hi) return VP_OK;
    return vp_errf(why, whylen, code, "%s%s %llu is outside %.0f..%.0f", pre ? pre : "", label,
                   (unsigned long long)v, lo, hi);
}

int vp_check_pad(const vp_layout_desc *d, uint32_t pad, const char *pre, char *why, size_t whylen)
{
    /* the run of adjacent pad fields holding the bad byte: "pad bytes 29..31" */
    uint32_t off = pad - 1, lo = off, hi = off, run = 0;
    bool in_run = false;
    for (uint32_t i = 0; i < d->nfields; i++) {
        const vp_field_desc *f = &d->fields[i];
        if (f->kind != VP_KIND_PAD) {
            if (in_run && run <= off && off <= hi) break;
            in_run = false;
            continue;
        }
        if (!in_run) run = f->offset;
        in_run = true;
        hi = f->offset + f->size - 1u;
        lo = run;
    }
    if (!(lo <= off && off <= hi)) lo = hi = off; /* not a described pad: cannot happen */
    return vp_errf(why, whylen, VP_ERR_INVALID, "%spad bytes %u..%u must be zero", pre ? pre : "", lo, hi);
}
