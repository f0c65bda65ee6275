/*
 * cull_isa.c — picks the kernel instance: CPUID (with the OS's XSAVE state
 * for AVX), overridable by VANTAGE_ISA=scalar|sse41|avx2. Builds with
 * CULL_SCALAR_ONLY (CONFIG=scalar) carry the scalar kernel alone.
 */
#include "cull_internal.h"
#include "cull_occ.h"

#include <stdio.h>
#include <string.h>
#include <stdlib.h>
#if defined(__x86_64__) || defined(__i386__)
#include <cpuid.h>
#define CULL_X86 1
#endif

static const char *const isa_names[CULL_ISA_COUNT] = {"scalar", "sse41", "avx2"};

const char *cull_isa_name(uint32_t isa)
{
    return isa < CULL_ISA_COUNT ? isa_names[isa] : "unknown";
}

static uint32_t cpu_probe(void)
{
#if defined(CULL_X86) && !defined(CULL_SCALAR_ONLY)
    unsigned a, b, c, d;
    if (!__get_cpuid(1, &a, &b, &c, &d)) return CULL_ISA_SCALAR;
    bool sse41 = c & bit_SSE4_1;
    bool fma = c & bit_FMA, osxsave = c & bit_OSXSAVE, avx = c & bit_AVX;
    bool f16c = c & bit_F16C; /* the AVX2 kernels widen half floats (every AVX2 CPU has it) */
    bool avx2 = false;
    if (osxsave && avx && fma && f16c) {
        unsigned lo, hi;
        __asm__ volatile("xgetbv" : "=a"(lo), "=d"(hi) : "c"(0));
        if ((lo & 6u) == 6u && __get_cpuid_count(7, 0, &a, &b, &c, &d))
            avx2 = b & bit_AVX2;
    }
    return avx2 ? CULL_ISA_AVX2 : sse41 ? CULL_ISA_SSE41 : CULL_ISA_SCALAR;
#else
    return CULL_ISA_SCALAR;
#endif
}

/* CPUID once: the answer cannot change while the process runs */
static uint32_t cpu_best(void)
{
    static _Atomic uint32_t best = UINT32_MAX;
    uint32_t v = atomic_load_explicit(&best, memory_order_relaxed);
    if (v == UINT32_MAX) {
        v = cpu_probe();
        atomic_store_explicit(&best, v, memory_order_relaxed);
    }
    return v;
}

/* AVX-512 F, VL, DQ and BW with the OS saving the opmask and upper ZMM
 * state (XCR0 bits 5-7 besides 1-2): what the AVX2 kernels' EVEX builds
 * need (their 256-bit code then has 32 vector registers and mask
 * registers; the same operations, the same bits) */
static bool cpu_evex(void)
{
#if defined(CULL_X86) && !defined(CULL_SCALAR_ONLY)
    unsigned a, b, c, d;
    if (cpu_best() != CULL_ISA_AVX2 || !__get_cpuid(1, &a, &b, &c, &d) || !(c & bit_OSXSAVE)) return false;
    unsigned lo, hi;
    __asm__ volatile("xgetbv" : "=a"(lo), "=d"(hi) : "c"(0));
    if ((lo & 0xE6u) != 0xE6u || !__get_cpuid_count(7, 0, &a, &b, &c, &d)) return false;
    return (b & bit_AVX512F) && (b & bit_AVX512VL) && (b & bit_AVX512DQ) && (b & bit_AVX512BW);
#else
    return false;
#endif
}

int cull_isa_evex(void)
{
    static _Atomic int cpu = -1; /* CPUID once; the environment at each call (a renderer's creation) */
    int c = atomic_load_explicit(&cpu, memory_order_relaxed);
    if (c < 0) {
        c = cpu_evex();
        atomic_store_explicit(&cpu, c, memory_order_relaxed);
    }
    const char *env = getenv("VANTAGE_EVEX");
    return c && !(env && !strcmp(env, "0"));
}

int cull_isa_supported(uint32_t isa)
{
    return isa <= cpu_best();
}

uint32_t cull_isa_default(void)
{
    uint32_t best = cpu_best();
    const char *env = getenv("VANTAGE_ISA");
    if (!env || !*env) return best;
    for (uint32_t i = 0; i < CULL_ISA_COUNT; i++) {
        if (strcmp(env, isa_names[i]) == 0) {
            if (i <= best) return i;
            fprintf(stderr, "vantage: VANTAGE_ISA=%s not supported here, using %s\n",
                    env, isa_names[best]);
            return best;
        }
    }
    fprintf(stderr, "vantage: VANTAGE_ISA=%s unknown (scalar|sse41|avx2), using %s\n",
            env, isa_names[best]);
    return best;
}

cull_block_fn cull_isa_kernel(uint32_t isa)
{
    switch (isa) {
#ifndef CULL_SCALAR_ONLY
    case CULL_ISA_AVX2: return cull_block_avx2;
    case CULL_ISA_SSE41: return cull_block_sse41;
#endif
    default: return cull_block_scalar;
    }
}

cull_cells_fn cull_isa_cells(uint32_t isa)
{
    switch (isa) {
#ifndef CULL_SCALAR_ONLY
    case CULL_ISA_AVX2: return cull_cells_avx2;
    case CULL_ISA_SSE41: return cull_cells_sse41;
#endif
    default: return cull_cells_scalar;
    }
}

cull_occ_fns cull_occ_fns_for(uint32_t isa)
{
    switch (isa) {
#ifndef CULL_SCALAR_ONLY
    case CULL_ISA_AVX2: return (cull_occ_fns){cull_occ_span_avx2, cull_occ_spans_avx2, cull_occ_any_le_avx2, cull_occ_tiles_avx2, cull_occ_fill_avx2, cull_occ_max2_avx2,
                                  cull_occ_rect_visible_avx2, cull_occ_lanes_avx2, cull_occ_rows_avx2, cull_occ_project_avx2};
    case CULL_ISA_SSE41: return (cull_occ_fns){cull_occ_span_sse41, cull_occ_spans_sse41, cull_occ_any_le_sse41, cull_occ_tiles_sse41, cull_occ_fill_sse41, cull_occ_max2_sse41,
                                  cull_occ_rect_visible_sse41, cull_occ_lanes_sse41, cull_occ_rows_scalar, cull_occ_project_scalar};
#endif
    default: return (cull_occ_fns){cull_occ_span_scalar, cull_occ_spans_scalar, cull_occ_any_le_scalar, cull_occ_tiles_scalar, cull_occ_fill_scalar, cull_occ_max2_scalar,
                                  cull_occ_rect_visible_scalar, cull_occ_lanes_scalar, cull_occ_rows_scalar, cull_occ_project_scalar};
    }
}
