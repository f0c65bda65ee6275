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
 * Kinds: u8 u16 u32 u64 i32 f32 f64 (one field of that type); u32a f32a
 * f64a (a C array of that type, every element in order); pad8 pad16 pad32
 * (written 0, must read 0; the field name is not used); rsv8 rsv16 rsv32
 * (reserved: written 0, ignored on read, as the layouts that predate the
 * pad check have them). Used by protocol/vp_*.c only; variable parts
 * (counted records, names) stay hand-written next to the list.
 */
#ifndef VANTAGE_VP_LAYOUT_H
#define VANTAGE_VP_LAYOUT_H

#include "protocol.h"

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
#define VP_R_f32a(f)  for (size_t k_ = 0; k_ < VP_ALEN_(m_->f); k_++) m_->f[k_] = vp_get_f32(r_);
#define VP_R_f64a(f)  for (size_t k_ = 0; k_ < VP_ALEN_(m_->f); k_++) m_->f[k_] = vp_get_f64(r_);
#define VP_R_pad8(f)  pad_ |= vp_get_u8(r_);
#define VP_R_pad16(f) pad_ |= vp_get_u16(r_);
#define VP_R_pad32(f) pad_ |= vp_get_u32(r_);
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
#define VP_S_f32a(f)  + sizeof m_->f
#define VP_S_f64a(f)  + sizeof m_->f
#define VP_S_pad8(f)  + 1
#define VP_S_pad16(f) + 2
#define VP_S_pad32(f) + 4
#define VP_S_rsv8(f)  + 1
#define VP_S_rsv16(f) + 2
#define VP_S_rsv32(f) + 4

#define VP_PUT_FIELD_(kind, f)  VP_W_##kind(f)
#define VP_GET_FIELD_(kind, f)  VP_R_##kind(f)
#define VP_SIZE_FIELD_(kind, f) VP_S_##kind(f)

/* not every layout uses all five (clang warns of unused static inline) */
#define VP_LAYOUT_FN_ static inline __attribute__((unused))

#define VP_LAYOUT(name, type, FIELDS)                                                   \
    VP_LAYOUT_FN_ void name##_put(vp_writer *w_, const type *m_) { FIELDS(VP_PUT_FIELD_) } \
    VP_LAYOUT_FN_ uint32_t name##_get(vp_reader *r_, type *m_)                           \
    {                                                                                    \
        uint32_t pad_ = 0;                                                               \
        FIELDS(VP_GET_FIELD_)                                                            \
        return pad_;                                                                     \
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
#define VP_MESSAGE_DEC(msg, type) \
    int vp_dec_##msg(const uint8_t *p, size_t len, type *m) { return msg##_dec(p, len, m); }

#endif
