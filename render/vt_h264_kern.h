/*
 * vt_h264_kern.h — the RGB -> I420 conversion's coefficients and its lane
 * kernel (internal to vt_h264*.c). Both paths compute the same integer
 * sums with the same coefficients, so the AVX2 rows are the scalar rows
 * bit for bit (test_h264_convert_isa).
 */
#ifndef VANTAGE_VT_H264_KERN_H
#define VANTAGE_VT_H264_KERN_H

#include <stdint.h>

/* BT.709: Kr 0.2126, Kb 0.0722. Limited range: luma 219 codes over 255,
 * chroma 224 over the span of B - Y (2 (1 - Kb)) and R - Y (2 (1 - Kr)).
 * Coefficients are 2^-16 fractions rounded to nearest; luma's G (0.614)
 * is the only one over 2^15, which the lanes split as 2^15 + the rest
 * (their products are 16-bit). */
#define VT_H264_KR 0.2126
#define VT_H264_KB 0.0722
#define VT_H264_KG (1.0 - VT_H264_KR - VT_H264_KB)
#define VT_H264_YS (219.0 / 255.0)
#define VT_H264_US (224.0 / 255.0 / (2.0 * (1.0 - VT_H264_KB)))
#define VT_H264_VS (224.0 / 255.0 / (2.0 * (1.0 - VT_H264_KR)))
#define VT_H264_FIX(x) ((int32_t)((x) * 65536.0 + ((x) < 0 ? -0.5 : 0.5)))
#define VT_H264_CY_R VT_H264_FIX(VT_H264_YS * VT_H264_KR)
#define VT_H264_CY_G VT_H264_FIX(VT_H264_YS * VT_H264_KG)
#define VT_H264_CY_B VT_H264_FIX(VT_H264_YS * VT_H264_KB)
#define VT_H264_CU_R VT_H264_FIX(-VT_H264_US * VT_H264_KR)
#define VT_H264_CU_G VT_H264_FIX(-VT_H264_US * VT_H264_KG)
#define VT_H264_CU_B VT_H264_FIX(VT_H264_US * (1.0 - VT_H264_KB))
#define VT_H264_CV_R VT_H264_FIX(VT_H264_VS * (1.0 - VT_H264_KR))
#define VT_H264_CV_G VT_H264_FIX(-VT_H264_VS * VT_H264_KG)
#define VT_H264_CV_B VT_H264_FIX(-VT_H264_VS * VT_H264_KB)
/* 16 (luma) and 128 (chroma) plus the rounding half, at the sums' scale:
 * luma 2^16, chroma 2^19 (the filter's eight weights are summed, not averaged) */
#define VT_H264_Y_ADD ((16 << 16) + (1 << 15))
#define VT_H264_C_ADD ((128 << 19) + (1 << 18))

/* A row pair of padded RGBA rows to I420, columns [0, n), n a multiple of
 * 16: r0 and r1 point at column 0, 4 bytes a pixel (R G B X), and the
 * pixels at columns -1 and n are readable (the caller's padding: the edge
 * repeated). Luma of column x: (CY_R R + CY_G G + CY_B B + Y_ADD) >> 16;
 * chroma of columns 2i (i < n / 2): S = the [1 2 1] sums over columns
 * 2i-1..2i+1 of both rows, (CU_R S_R + CU_G S_G + CU_B S_B + C_ADD) >> 19. */
typedef void (*vt_i420_rows_fn)(const uint8_t *r0, const uint8_t *r1, uint32_t n, uint8_t *y0, uint8_t *y1,
                                uint8_t *u, uint8_t *v);

/* The AVX2 instance, or NULL where this build has none (CONFIG=scalar). */
vt_i420_rows_fn vt_i420_rows_avx2(void);

#endif
