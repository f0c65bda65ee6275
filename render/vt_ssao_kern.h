/*
 * vt_ssao_kern.h — the SSAO pass' lane kernels (internal to vt_ssao*.c):
 * vt_ssao.inl compiled once per ISA (vt_ssao_base.c: one lane, and the
 * choice; vt_ssao_sse41.c: 4; vt_ssao_avx2.c: 8), each doing the same
 * float operations in the same order as the one-lane instance, so every
 * instance gives the same AO bit for bit (no FMA contraction: the build
 * is ISO C, -ffp-contract=off).
 */
#ifndef VANTAGE_VT_SSAO_KERN_H
#define VANTAGE_VT_SSAO_KERN_H

#include "vt_ssao.h"
#include "vt_shade.h"

/* One frame's pass as the kernels read it. */
typedef struct vt_ssao_kjob {
    const vt_ssao_view *sv;
    const float *near;          /* full resolution, w x h */
    /* half texels' nearness (texel j hw + i; VT_EMPTY: sky or a point that
       is not finite), with VT_SSAO_PAD (hw) floats before and after it, so
       a step's neighbours two rows or columns away are contiguous loads
       wherever it is (the lanes off the image masked) */
    float *pn;
    int32_t *cs;                /* VT_SSAO_CBLKS (hw) x (hh + 1): the count of crease texels
                                   (vt_ssao.inl's crease kernel) in texels [0, 8 b) x [0, j) at
                                   j VT_SSAO_CBLKS (hw) + b */
    float crease_tol;           /* the crease test's tolerance (vt_ssao.c) */
    bool no_skip;               /* vt_ssao_no_skip */
    float *hao;                 /* half texels' AO */
    const int32_t *cx;          /* 3 planes of w + 8 (padded): each full column's tap half columns */
    const float *cw;            /* their weights, likewise */
    float *ao;                  /* full pixels */
    float dir[4 * VT_SSAO_SLICES][2]; /* vt_ssao_dirs */
} vt_ssao_kjob;

#define VT_SSAO_PAD(hw) (2 * (size_t)(hw) + 16)
/* the crease counts' blocks of texels along a row, and their count + 1
   (the same in every instance: the skip must be, for the same bits) */
#define VT_SSAO_CBLK 8u
#define VT_SSAO_CBLKS(hw) (((size_t)(hw) + VT_SSAO_CBLK - 1) / VT_SSAO_CBLK + 1)

typedef void (*vt_ssao_row_fn)(const vt_ssao_kjob *k, uint32_t row);

typedef struct vt_ssao_kern {
    vt_ssao_row_fn pos;  /* half row j: pn */
    vt_ssao_row_fn crease; /* half row j: cs's row j + 1, counted along the row only */
    vt_ssao_row_fn gtao; /* half row j: hao, hnear */
    vt_ssao_row_fn up;   /* full rows 2 m, 2 m + 1: ao */
} vt_ssao_kern;

void vt_ssao_pos_scalar(const vt_ssao_kjob *k, uint32_t j);
void vt_ssao_pos_sse41(const vt_ssao_kjob *k, uint32_t j);
void vt_ssao_pos_avx2(const vt_ssao_kjob *k, uint32_t j);
void vt_ssao_crease_scalar(const vt_ssao_kjob *k, uint32_t j);
void vt_ssao_crease_sse41(const vt_ssao_kjob *k, uint32_t j);
void vt_ssao_crease_avx2(const vt_ssao_kjob *k, uint32_t j);
void vt_ssao_gtao_scalar(const vt_ssao_kjob *k, uint32_t j);
void vt_ssao_up_scalar(const vt_ssao_kjob *k, uint32_t y);
void vt_ssao_gtao_sse41(const vt_ssao_kjob *k, uint32_t j);
void vt_ssao_up_sse41(const vt_ssao_kjob *k, uint32_t y);
void vt_ssao_gtao_avx2(const vt_ssao_kjob *k, uint32_t j);
void vt_ssao_up_avx2(const vt_ssao_kjob *k, uint32_t y);
void vt_ssao_pos_avx2_evex(const vt_ssao_kjob *k, uint32_t j);
void vt_ssao_crease_avx2_evex(const vt_ssao_kjob *k, uint32_t j);
void vt_ssao_gtao_avx2_evex(const vt_ssao_kjob *k, uint32_t j);
void vt_ssao_up_avx2_evex(const vt_ssao_kjob *k, uint32_t y);
/* The AVX2 kernels' EVEX build (vt_ssao_avx2_evex.c: the same bits, 32
 * registers), or NULLs where this build has none. */
vt_ssao_kern vt_ssao_kern_evex(void);

/* The instance of isa (enum cull_isa) where this build and CPU run it,
 * else the default one (cull_isa_default: the widest, or VANTAGE_ISA);
 * AVX2's EVEX build where cull_isa_evex() allows it. */
vt_ssao_kern vt_ssao_kern_pick(uint32_t isa);

#endif
