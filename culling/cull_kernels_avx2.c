/*
 * cull_kernels_avx2.c — the block kernel, 8 lanes (AVX2 + FMA). Compiled
 * with -mavx2 -mfma; called only after CPUID says both are there.
 */
#include "cull_internal.h"
#include "cull_occ.h"
#include <math.h>
#if defined(__AVX2__) && defined(__FMA__)
#define CULL_SIMD_ISA 3
#include "cull_simd.h"
#define CULL_KERNEL_NAME cull_block_avx2
#include "cull_kernel.inl"
#define CULL_CELLS_NAME cull_cells_avx2
#include "cull_cells.inl"
#include "cull_occ_rows.h"
#define CULL_OCC_SUFFIX avx2
#include "cull_occ_kern.inl"
#endif
