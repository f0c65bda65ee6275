/*
 * cull_kernels_scalar.c — the block kernel at one lane per step: the
 * portable fallback and the float reference the SIMD instances are compared
 * with. Compiled with auto-vectorisation off so "scalar" means scalar.
 */
#include "cull_internal.h"
#include "cull_occ.h"
#include <math.h>
#define CULL_SIMD_ISA 1
#include "cull_simd.h"
#define CULL_KERNEL_NAME cull_block_scalar
#include "cull_kernel.inl"
#define CULL_CELLS_NAME cull_cells_scalar
#include "cull_cells.inl"
#define CULL_OCC_SUFFIX scalar
#include "cull_occ_kern.inl"
