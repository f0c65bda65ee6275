/*
 * vp_layout.h — a fixed-size wire layout described once. A message or a
 * record whose fields all have a fixed size is one field list of
 * X(kind, field) in wire order; VP_LAYOUT(name, type, FIELDS) makes from
 * it, so the three can never disagree:
 *
 *   name_put(w, m)     writes the fields (vp_put_*; overflow is the writer's);
 *   name_get(r, m)     reads them (vp_get_*; a short read is the reader's)
 *                      and returns the OR of the pad bytes, non-zero when a
 *                      pad that must be 0 is not (the decoder says INVALID);
 *   name_size()        the bytes on the wire;
 *   name_enc(w, type, req, m) the whole frame of a message of that layout;
 *   name_head(r, p, len, m) the same layout heading a longer payload
 *                      (VP_LAYOUT_HEAD below);
 *   name_dec(p, len, m) a whole payload of exactly that layout: VP_OK,
 *                      VP_ERR_TRUNCATED, VP_ERR_TRAILING, or VP_ERR_INVALID
 *                      for a pad that is not 0 (in that order).
 *
 *   name_desc()        the machine-readable description (vp_layout_desc,
 *                      protocol.h): every field's name, kind, byte offset
 *                      and size, and the checks below; vp_desc_<name>()
 *                      exports it, vp_layout_find() finds it by name, and
 *                      tests/test_protocol_doc.c checks PROTOCOL.md's byte
 *                      tables against it.
 *
 * VP_LAYOUT_CHECKED(name, type, FIELDS, CHECKS) adds the field checks,
 * a list of X(op, field, label, elems, lo, hi) next to the field list, so
 * a decoder's limits are stated once beside the bytes they apply to:
 *
 *   name_check_fields(m, pad, pre, why, whylen) runs them in list order, then the
 *                      pad check; VP_OK or the first failure's code with the
 *                      field named in why (prefixed by pre, "" for none:
 *                      "sphere x is nan: NaN or infinite", "pad bytes 76..79
 *                      must be zero"). No allocation.
 *
 * Check ops (label names the field in messages):
 *   range    f32/f64 field or array: each element finite (else NONFINITE)
 *            and in lo..hi (else INVALID); elems names the elements,
 *            comma-separated ("x,y,z,radius"; "" for a scalar); bounds
 *            +-INFINITY: finite only;
 *   max      integer <= hi, else INVALID "label v: <elems>" (elems says
 *            which values are defined);
 *   mask     integer with no bit outside hi, else INVALID;
 *   nonzero  integer != 0, else INVALID "label is 0: <elems>";
 *   count    integer in lo..hi, else COUNT;
 *   irange   integer in lo..hi, else INVALID.
 * Checks that span fields (a unit quaternion, a chunk inside its image)
 * stay hand-written next to the list.
 *
 * Kinds: u8 u16 u32 u64 i32 f32 f64 (one field of that type); u32a u64a
 * f32a f64a (a C array of that type, every element in order); pad8 pad16 pad32
 * (written 0, must read 0); rsv8 rsv16 rsv32 (reserved: written 0,
 * ignored on read, as the layouts that predate the pad check have them).
 * Every field name in a list is distinct (pads: pad1, pad2, ...): the
 * description's offsets come from a struct of the fields' wire bytes.
 * Used by protocol/vp_*.c only; variable parts (counted records, names)
 * stay hand-written next to the list. A new layout's name goes in
 * VP_LAYOUT_NAMES (protocol/vp_layout.c), which the doc test holds to
 * every VP_LAYOUT in protocol/.
 */
#ifndef VANTAGE_VP_LAYOUT_H
#define VANTAGE_VP_LAYOUT_H

#include "protocol.h"

#include <math.h>
#include <stddef.h>

/* a field's wire size is its C size: IEEE single and double, fixed ints */
_Static_assert(sizeof(float) == 4 && sizeof(double) == 8, "IEEE float and double");

#define VP_ALEN_(a) (sizeof(a) / sizeof((a)[0]))

#define VP_W_u8(f)    vp_put_u8(w_, m_->f);
#define VP_W_u16(f)   vp_put_u16(w_, m_->f);
#define VP_W_u32(f)   vp_put_u32(w_, m_->f);
#define VP_W_u64(f)   vp_put_u64(w_, m_->f);
#define VP_W_i32(f)   vp_put_i32(w_, m_->f);
#define VP_W_f32(f)   vp_put_f32(w_, m_->f);
#define VP_W_f64(f)   vp_put_f64(w_, m_->f);
#define VP_W_u32a(f)  for (size_t k_ = 0; k_ < VP_ALEN_(m_->f); k_++) vp_put_u32(w_, m_->f[k_]);
#define VP_W_u64a(f)  for (size_t k_ = 0; k_ < VP_ALEN_(m_->f); k_++) vp_put_u64(w_, m_->f[k_]);
#define VP_W_f32a(f)  for (size_t k_ = 0; k_ < VP_ALEN_(m_->f); k_++) vp_put_f32(w_, m_->f[k_]);
#define VP_W_f64a(f)  for (size_t k_ = 0; k_ < VP_ALEN_(m_->f); k_++) vp_put_f64(w_, m_->f[k_]);
#define VP_W_pad8(f)  vp_put_u8(w_, 0);
#define VP_W_pad16(f) vp_put_u16(w_, 0);
#define VP_W_pad32(f) vp_put_u32(w_, 0);
#define VP_W_rsv8(f)  vp_put_u8(w_, 0);
#define VP_W_rsv16(f) vp_put_u16(w_, 0);
#define VP_W_rsv32(f) vp_put_u32(w_, 0);

#define VP_R_u8(f)    m_->f = vp_get_u8(r_);
#define VP_R_u16(f)   m_->f = vp_get_u16(r_);
#define VP_R_u32(f)   m_->f = vp_get_u32(r_);
#define VP_R_u64(f)   m_->f = vp_get_u64(r_);
#define VP_R_i32(f)   m_->f = vp_get_i32(r_);
#define VP_R_f32(f)   m_->f = vp_get_f32(r_);
#define VP_R_f64(f)   m_->f = vp_get_f64(r_);
#define VP_R_u32a(f)  for (size_t k_ = 0; k_ < VP_ALEN_(m_->f); k_++) m_->f[k_] = vp_get_u32(r_);
#define VP_R_u64a(f)  for (size_t k_ = 0; k_ < VP_ALEN_(m_->f); k_++) m_->f[k_] = vp_get_u64(r_);
#define VP_R_f32a(f)  for (size_t k_ = 0; k_ < VP_ALEN_(m_->f); k_++) m_->f[k_] = vp_get_f32(r_);
#define VP_R_f64a(f)  for (size_t k_ = 0; k_ < VP_ALEN_(m_->f); k_++) m_->f[k_] = vp_get_f64(r_);
/* the first pad that is not 0: 1 + its offset (vp_check_pad names it) */
#define VP_R_PAD_(f, v)                                                                                       \
    if ((v) && !pad_) pad_ = 1 + (uint32_t)offsetof(struct vp_wire_, f);
#define VP_R_pad8(f)  VP_R_PAD_(f, vp_get_u8(r_))
#define VP_R_pad16(f) VP_R_PAD_(f, vp_get_u16(r_))
#define VP_R_pad32(f) VP_R_PAD_(f, vp_get_u32(r_))
#define VP_R_rsv8(f)  (void)vp_get_u8(r_);
#define VP_R_rsv16(f) (void)vp_get_u16(r_);
#define VP_R_rsv32(f) (void)vp_get_u32(r_);

#define VP_S_u8(f)    + sizeof m_->f
#define VP_S_u16(f)   + sizeof m_->f
#define VP_S_u32(f)   + sizeof m_->f
#define VP_S_u64(f)   + sizeof m_->f
#define VP_S_i32(f)   + sizeof m_->f
#define VP_S_f32(f)   + sizeof m_->f
#define VP_S_f64(f)   + sizeof m_->f
#define VP_S_u32a(f)  + sizeof m_->f
#define VP_S_u64a(f)  + sizeof m_->f
#define VP_S_f32a(f)  + sizeof m_->f
#define VP_S_f64a(f)  + sizeof m_->f
#define VP_S_pad8(f)  + 1
#define VP_S_pad16(f) + 2
#define VP_S_pad32(f) + 4
#define VP_S_rsv8(f)  + 1
#define VP_S_rsv16(f) + 2
#define VP_S_rsv32(f) + 4

/* wire bytes of a field (vp_ct_: the layout's C type, in scope) */
#define VP_B_u8(f)    1
#define VP_B_u16(f)   2
#define VP_B_u32(f)   4
#define VP_B_u64(f)   8
#define VP_B_i32(f)   4
#define VP_B_f32(f)   4
#define VP_B_f64(f)   8
#define VP_B_u32a(f)  sizeof(((vp_ct_ *)0)->f)
#define VP_B_u64a(f)  sizeof(((vp_ct_ *)0)->f)
#define VP_B_f32a(f)  sizeof(((vp_ct_ *)0)->f)
#define VP_B_f64a(f)  sizeof(((vp_ct_ *)0)->f)
#define VP_B_pad8(f)  1
#define VP_B_pad16(f) 2
#define VP_B_pad32(f) 4
#define VP_B_rsv8(f)  1
#define VP_B_rsv16(f) 2
#define VP_B_rsv32(f) 4

/* an element's kind and bytes, for the description */
#define VP_K_u8    VP_KIND_U8, 1
#define VP_K_u16   VP_KIND_U16, 2
#define VP_K_u32   VP_KIND_U32, 4
#define VP_K_u64   VP_KIND_U64, 8
#define VP_K_i32   VP_KIND_I32, 4
#define VP_K_f32   VP_KIND_F32, 4
#define VP_K_f64   VP_KIND_F64, 8
#define VP_K_u32a  VP_KIND_U32, 4
#define VP_K_u64a  VP_KIND_U64, 8
#define VP_K_f32a  VP_KIND_F32, 4
#define VP_K_f64a  VP_KIND_F64, 8
#define VP_K_pad8  VP_KIND_PAD, 1
#define VP_K_pad16 VP_KIND_PAD, 2
#define VP_K_pad32 VP_KIND_PAD, 4
#define VP_K_rsv8  VP_KIND_RSV, 1
#define VP_K_rsv16 VP_KIND_RSV, 2
#define VP_K_rsv32 VP_KIND_RSV, 4
#define VP_KIND_OF_(k, n) (k)
#define VP_EBYTES_(k, n) (n)
#define VP_KIND_OF(...) VP_KIND_OF_(__VA_ARGS__)
#define VP_EBYTES_OF(...) VP_EBYTES_(__VA_ARGS__)

/* The fields' wire bytes as a struct of byte arrays: no padding (all
 * alignment 1), so offsetof is the wire offset and sizeof the wire size. */
#define VP_WIRE_FIELD_(kind, f) uint8_t f[VP_B_##kind(f)];
#define VP_WIRE_(type, FIELDS)                                                                          \
    typedef type vp_ct_ __attribute__((unused));                                                         \
    struct vp_wire_ {                                                                                    \
        FIELDS(VP_WIRE_FIELD_)                                                                           \
    };
#define VP_DESC_FIELD_(kind, f)                                                                         \
    {#f, VP_KIND_OF(VP_K_##kind), (uint16_t)offsetof(struct vp_wire_, f), (uint16_t)VP_B_##kind(f),      \
     (uint16_t)(VP_B_##kind(f) / VP_EBYTES_OF(VP_K_##kind))},

/* checks: the description's rows and the code */
#define VP_CKOP_range   VP_CHECK_RANGE
#define VP_CKOP_max     VP_CHECK_MAX
#define VP_CKOP_mask    VP_CHECK_MASK
#define VP_CKOP_nonzero VP_CHECK_NONZERO
#define VP_CKOP_count   VP_CHECK_COUNT
#define VP_CKOP_irange  VP_CHECK_IRANGE
#define VP_DESC_CHECK_(op, f, label, elems, lo, hi) {#f, label, elems, VP_CKOP_##op, (double)(lo), (double)(hi)},
/* bytes of one element of a float field or array (m_ is const) */
#define VP_FBYTES_(x)                                                                                   \
    _Generic((x) + 0, float: 4, double: 8, const float *: 4, const double *: 8, float *: 4, double *: 8)
#define VP_CK_range(f, label, elems, lo, hi)                                                            \
    vp_check_floats(&m_->f, sizeof m_->f, VP_FBYTES_(m_->f), pre_, label, elems, lo, hi, why_, whylen_)
#define VP_CK_max(f, label, elems, lo, hi)     vp_check_max(m_->f, pre_, label, elems, hi, why_, whylen_)
#define VP_CK_mask(f, label, elems, lo, hi)    vp_check_mask(m_->f, pre_, label, elems, hi, why_, whylen_)
#define VP_CK_nonzero(f, label, elems, lo, hi) vp_check_nonzero(m_->f, pre_, label, elems, why_, whylen_)
#define VP_CK_count(f, label, elems, lo, hi)   vp_check_count(m_->f, pre_, label, lo, hi, VP_ERR_COUNT, why_, whylen_)
#define VP_CK_irange(f, label, elems, lo, hi)  vp_check_count(m_->f, pre_, label, lo, hi, VP_ERR_INVALID, why_, whylen_)
#define VP_CHECK_ROW_(op, f, label, elems, lo, hi) \
    if ((rc_ = VP_CK_##op(f, label, elems, lo, hi))) return rc_;
#define VP_NO_CHECKS_(X)

#define VP_PUT_FIELD_(kind, f)  VP_W_##kind(f)
#define VP_GET_FIELD_(kind, f)  VP_R_##kind(f)
#define VP_SIZE_FIELD_(kind, f) VP_S_##kind(f)

/* not every layout uses all five (clang warns of unused static inline) */
#define VP_LAYOUT_FN_ static inline __attribute__((unused))

#define VP_LAYOUT(name, type, FIELDS) VP_LAYOUT_CHECKED(name, type, FIELDS, VP_NO_CHECKS_)

#define VP_LAYOUT_CHECKED(name, type, FIELDS, CHECKS)                                   \
    VP_LAYOUT_FN_ void name##_put(vp_writer *w_, const type *m_) { FIELDS(VP_PUT_FIELD_) } \
    VP_LAYOUT_FN_ uint32_t name##_get(vp_reader *r_, type *m_)                           \
    {                                                                                    \
        VP_WIRE_(type, FIELDS)                                                           \
        uint32_t pad_ = 0;                                                               \
        FIELDS(VP_GET_FIELD_)                                                            \
        return pad_;                                                                     \
    }                                                                                    \
    VP_LAYOUT_FN_ const vp_layout_desc *name##_desc(void)                                \
    {                                                                                    \
        VP_WIRE_(type, FIELDS)                                                           \
        static const vp_field_desc f_[] = {FIELDS(VP_DESC_FIELD_)};                      \
        static const vp_check_desc c_[] = {CHECKS(VP_DESC_CHECK_){NULL, NULL, NULL, 0, 0, 0}}; \
        static const vp_layout_desc d_ = {#name, sizeof(struct vp_wire_), sizeof f_ / sizeof f_[0], \
                                          sizeof c_ / sizeof c_[0] - 1, f_, c_};          \
        return &d_;                                                                      \
    }                                                                                    \
    const vp_layout_desc *vp_desc_##name(void);                                          \
    const vp_layout_desc *vp_desc_##name(void) { return name##_desc(); }                 \
    VP_LAYOUT_FN_ int name##_check_fields(const type *m_, uint32_t pad_, const char *pre_, char *why_, size_t whylen_) \
    {                                                                                    \
        int rc_ = VP_OK;                                                                 \
        (void)m_;                                                                        \
        CHECKS(VP_CHECK_ROW_)                                                            \
        return pad_ ? vp_check_pad(name##_desc(), pad_, pre_, why_, whylen_) : rc_;      \
    }                                                                                    \
    VP_LAYOUT_FN_ size_t name##_size(void)                                               \
    {                                                                                    \
        const type *m_ = NULL;                                                           \
        (void)m_;                                                                        \
        return 0 FIELDS(VP_SIZE_FIELD_);                                                 \
    }                                                                                    \
    VP_LAYOUT_FN_ void name##_enc(vp_writer *w_, uint16_t type_, uint32_t req_, const type *m_) \
    {                                                                                    \
        vp_frame_begin(w_, type_, req_);                                                 \
        name##_put(w_, m_);                                                              \
        vp_frame_end(w_);                                                                \
    }                                                                                    \
    VP_LAYOUT_FN_ int name##_dec(const uint8_t *p_, size_t len_, type *m_)               \
    {                                                                                    \
        vp_reader r_;                                                                    \
        vp_reader_init(&r_, p_, len_);                                                   \
        uint32_t pad_ = name##_get(&r_, m_);                                             \
        int rc_ = vp_reader_finish(&r_);                                                 \
        return rc_ ? rc_ : pad_ ? VP_ERR_INVALID : VP_OK;                                \
    }                                                                                    \
    VP_LAYOUT_HEAD(name, type)

/* The checks' messages (protocol/vp_layout.c); pre and label name the
 * field, why may be NULL. Each returns VP_OK or the code it wrote. */
int vp_check_floats(const void *v, size_t bytes, size_t esize, const char *pre, const char *label, const char *elems,
                    double lo, double hi, char *why, size_t whylen);
int vp_check_max(uint64_t v, const char *pre, const char *label, const char *defined, double hi, char *why,
                 size_t whylen);
int vp_check_mask(uint64_t v, const char *pre, const char *label, const char *defined, double mask, char *why,
                  size_t whylen);
int vp_check_nonzero(uint64_t v, const char *pre, const char *label, const char *why0, char *why, size_t whylen);
/* v in lo..hi, else code (COUNT or INVALID) */
int vp_check_count(uint64_t v, const char *pre, const char *label, double lo, double hi, int code, char *why,
                   size_t whylen);
/* pad: 1 + the offset of the first non-zero pad byte group (name_get). */
int vp_check_pad(const vp_layout_desc *d, uint32_t pad, const char *pre, char *why, size_t whylen);

/* A fixed message's header before variable parts: r over the payload,
 * the fields read; VP_ERR_TRUNCATED if they do not fit, VP_ERR_INVALID
 * for a pad that is not 0. */
#define VP_LAYOUT_HEAD(name, type)                                                                  \
    VP_LAYOUT_FN_ int name##_head(vp_reader *r_, const uint8_t *p_, size_t len_, type *m_)       \
    {                                                                                              \
        vp_reader_init(r_, p_, len_);                                                              \
        uint32_t pad_ = name##_get(r_, m_);                                                        \
        return r_->short_read ? VP_ERR_TRUNCATED : pad_ ? VP_ERR_INVALID : VP_OK;                 \
    }

/* The public vp_size_<msg>(void) and vp_enc_<msg>(w, req, m) of a message
 * that is one layout named msg, of type code; VP_MESSAGE_DEC adds
 * vp_dec_<msg>(p, len, m) for one that has no checks beyond its layout. */
#define VP_MESSAGE(msg, type, code)                                                                \
    size_t vp_size_##msg(void) { return VP_HEADER_SIZE + msg##_size(); }                           \
    void vp_enc_##msg(vp_writer *w, uint32_t req, const type *m) { msg##_enc(w, code, req, m); }
/* The public vp_size_<msg>(n) and vp_enc_<msg>(w, req, recs, n) of a
 * counted batch of records of C type `type` (u32 n, then put_fn of each,
 * rec_size bytes on the wire): vp_enc_batch with put_fn. */
#define VP_BATCH_MESSAGE(msg, type, code, put_fn, rec_size)                                          \
    static void msg##_put_any_(vp_writer *w, const void *r) { put_fn(w, (const type *)r); }          \
    size_t vp_size_##msg(uint32_t n) { return VP_HEADER_SIZE + 4 + (size_t)n * (rec_size); }         \
    void vp_enc_##msg(vp_writer *w, uint32_t req, const type *r, uint32_t n)                           \
    {                                                                                                \
        vp_enc_batch(w, code, req, r, sizeof *r, n, msg##_put_any_);                                 \
    }
#define VP_MESSAGE_DEC(msg, type) \
    int vp_dec_##msg(const uint8_t *p, size_t len, type *m) { return msg##_dec(p, len, m); }

#endif
