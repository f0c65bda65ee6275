/*
 * cull_kernels_sse41.c — the block kernel, 4 lanes (SSE4.1; no FMA, so a
 * multiply and an add). Compiled with -msse4.1; called only after CPUID.
 */
#include "cull_internal.h"
#include "cull_occ.h"
#include <math.h>
#if defined(__SSE4_1__)
#define CULL_SIMD_ISA 2
#include "cull_simd.h"
#define CULL_KERNEL_NAME cull_block_sse41
#include "cull_kernel.inl"
#define CULL_CELLS_NAME cull_cells_sse41
#include "cull_cells.inl"
#define CULL_OCC_SUFFIX sse41
#include "cull_occ_kern.inl"
#endif
