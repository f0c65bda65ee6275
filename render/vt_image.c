/*
 * vt_image.c — tone mapping to sRGB8, PNG (libpng 1.6) and JPEG (the
 * libjpeg API of libjpeg-turbo 2.1) for vt_image.h.
 *
 * What it owns: the sRGB8 encoding tables, the output sink (a file
 * descriptor behind a 64 KiB staging buffer, or a growing memory buffer)
 * that both encoders write through, the temporary-file-and-rename, and the
 * translation of library failures into errno values.
 *
 * sRGB8: a 256-entry table of thresholds, srgb_t[k] being the smallest
 * float whose exact OETF, times 255, is >= k - 0.5, so code(v) = the
 * number of thresholds <= v, for every float. Finding k: the float's
 * exponent and top 7 mantissa bits index 1664 buckets covering [2^-13, 1),
 * each holding the code of its lowest float; no bucket spans more than one
 * threshold, so one comparison finishes. Both tables were generated with
 * long double powl, binary-searching float bit patterns; every threshold
 * clears k - 0.5 by at least 2.2e-9 codes on both sides, ten orders of
 * magnitude above powl's error, so the rounding is exact, not "within an
 * ulp". The tests rebuild the thresholds from their own reference and
 * check every float in [2^-14, 1] against them.
 *
 * libpng and libjpeg report fatal errors by longjmp. The rule here: the
 * function that calls setjmp does nothing else (png_guarded, jpg_guarded:
 * no locals change after setjmp, so none is left indeterminate and none
 * needs volatile), and every resource the longjmp could strand lives in a
 * job struct owned by the caller, which frees it on either path. Bodies
 * store each allocation in the job before the next library call.
 *
 * Measured on the development machine (one core of a 2-core AMD EPYC VM,
 * gcc 12 -O2, medians of 15), a 1280x720 frame of an HDR ramp with a
 * bright spot, smooth / with 8% grain: ACES tone map of interleaved float
 * RGBA 15 / 16 ms (about 16 ns a pixel, the same for CLAMP; scalar code,
 * the first thing to vectorise if it matters); PNG RGB level 1 37 / 56 ms
 * (424 / 892 KB), level 6 136 / 294 ms (276 / 754 KB), RGBA level 1 45 /
 * 70 ms; JPEG q85 2-3 ms either way (31 / 39 KB), memory or file; JPEG
 * decode 2 ms, PNG read 8 / 14 ms. 16384x16384: PNG level 1 9.5 s, JPEG
 * q85 0.6 s. libpng's adaptive filter choice costs about a third of the
 * level-1 time; a fixed SUB filter was faster and no larger on these
 * images, but that depends on content, so the default stays.
 */
#ifndef _GNU_SOURCE
#define _GNU_SOURCE /* GNU strerror_r */
#endif
#include "vt_image.h"
#include "vt_file.h"

#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <math.h>
#include <pthread.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stdio.h> /* before jpeglib.h, which uses FILE */
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include <jerror.h>
#include <jpeglib.h>
#include <png.h>

/* ---- sRGB8 ----------------------------------------------------------------- */

static const float srgb_t[257] = {
    0x0p+0f, 0x1.3e4568p-13f, 0x1.dd681cp-12f, 0x1.8dd6c2p-11f, 0x1.167cbcp-10f,
    0x1.660e16p-10f, 0x1.b59f7p-10f, 0x1.029866p-9f, 0x1.2a6112p-9f, 0x1.5229bep-9f,
    0x1.79f26cp-9f, 0x1.a1e5a2p-9f, 0x1.cbf736p-9f, 0x1.f86806p-9f, 0x1.13a0cp-8f,
    0x1.2c4666p-8f, 0x1.46297ap-8f, 0x1.614e62p-8f, 0x1.7db96ep-8f, 0x1.9b6edap-8f,
    0x1.ba72cep-8f, 0x1.dac95ep-8f, 0x1.fc768cp-8f, 0x1.0fbf22p-7f, 0x1.21f236p-7f,
    0x1.34d664p-7f, 0x1.486d9p-7f, 0x1.5cb98ep-7f, 0x1.71bc34p-7f, 0x1.877748p-7f,
    0x1.9dec9p-7f, 0x1.b51dc8p-7f, 0x1.cd0ca8p-7f, 0x1.e5bae2p-7f, 0x1.ff2a1ep-7f,
    0x1.0cae04p-6f, 0x1.1a291ep-6f, 0x1.28072cp-6f, 0x1.3648f8p-6f, 0x1.44ef4cp-6f,
    0x1.53fafp-6f, 0x1.636ca6p-6f, 0x1.73453p-6f, 0x1.838552p-6f, 0x1.942dc6p-6f,
    0x1.a53f48p-6f, 0x1.b6ba96p-6f, 0x1.c8a064p-6f, 0x1.daf16ap-6f, 0x1.edae5cp-6f,
    0x1.006bf8p-5f, 0x1.0a3768p-5f, 0x1.1439d8p-5f, 0x1.1e73ap-5f, 0x1.28e514p-5f,
    0x1.338e8ap-5f, 0x1.3e7058p-5f, 0x1.498acep-5f, 0x1.54de44p-5f, 0x1.606b08p-5f,
    0x1.6c316ep-5f, 0x1.7831c8p-5f, 0x1.846c64p-5f, 0x1.90e194p-5f, 0x1.9d91a4p-5f,
    0x1.aa7ce6p-5f, 0x1.b7a3a6p-5f, 0x1.c5063p-5f, 0x1.d2a4d4p-5f, 0x1.e07fdcp-5f,
    0x1.ee9794p-5f, 0x1.fcec48p-5f, 0x1.05bf2p-4f, 0x1.0d26e4p-4f, 0x1.14ad96p-4f,
    0x1.1c5356p-4f, 0x1.24184ep-4f, 0x1.2bfc9ep-4f, 0x1.34006ap-4f, 0x1.3c23d8p-4f,
    0x1.446708p-4f, 0x1.4cca2p-4f, 0x1.554d4p-4f, 0x1.5df08ep-4f, 0x1.66b42ap-4f,
    0x1.6f9836p-4f, 0x1.789cd6p-4f, 0x1.81c228p-4f, 0x1.8b0852p-4f, 0x1.946f72p-4f,
    0x1.9df7acp-4f, 0x1.a7a11ep-4f, 0x1.b16beap-4f, 0x1.bb5832p-4f, 0x1.c56614p-4f,
    0x1.cf95b2p-4f, 0x1.d9e72ap-4f, 0x1.e45aap-4f, 0x1.eef02ep-4f, 0x1.f9a7f8p-4f,
    0x1.02410ep-3f, 0x1.07bf5cp-3f, 0x1.0d4ef6p-3f, 0x1.12efecp-3f, 0x1.18a24cp-3f,
    0x1.1e6628p-3f, 0x1.243b8ap-3f, 0x1.2a2286p-3f, 0x1.301b2ap-3f, 0x1.362584p-3f,
    0x1.3c41a2p-3f, 0x1.426f96p-3f, 0x1.48af6cp-3f, 0x1.4f0132p-3f, 0x1.5564fap-3f,
    0x1.5bdadp-3f, 0x1.6262c2p-3f, 0x1.68fcep-3f, 0x1.6fa938p-3f, 0x1.7667d8p-3f,
    0x1.7d38cep-3f, 0x1.841c2ap-3f, 0x1.8b11f6p-3f, 0x1.921a44p-3f, 0x1.99352p-3f,
    0x1.a06298p-3f, 0x1.a7a2bap-3f, 0x1.aef594p-3f, 0x1.b65b34p-3f, 0x1.bdd3a8p-3f,
    0x1.c55efcp-3f, 0x1.ccfd3ep-3f, 0x1.d4ae7cp-3f, 0x1.dc72c4p-3f, 0x1.e44a22p-3f,
    0x1.ec34a4p-3f, 0x1.f43258p-3f, 0x1.fc434ap-3f, 0x1.0233c4p-2f, 0x1.064f8ep-2f,
    0x1.0a750cp-2f, 0x1.0ea444p-2f, 0x1.12dd3ap-2f, 0x1.171ff8p-2f, 0x1.1b6c82p-2f,
    0x1.1fc2ep-2f, 0x1.242316p-2f, 0x1.288d2cp-2f, 0x1.2d012ap-2f, 0x1.317f12p-2f,
    0x1.3606eep-2f, 0x1.3a98c4p-2f, 0x1.3f3498p-2f, 0x1.43da7p-2f, 0x1.488a56p-2f,
    0x1.4d444cp-2f, 0x1.52085cp-2f, 0x1.56d688p-2f, 0x1.5baedap-2f, 0x1.609154p-2f,
    0x1.657ep-2f, 0x1.6a74e2p-2f, 0x1.6f76p-2f, 0x1.748162p-2f, 0x1.79970ap-2f,
    0x1.7eb702p-2f, 0x1.83e14ep-2f, 0x1.8915f2p-2f, 0x1.8e54f8p-2f, 0x1.939e64p-2f,
    0x1.98f23cp-2f, 0x1.9e5084p-2f, 0x1.a3b944p-2f, 0x1.a92c82p-2f, 0x1.aeaa42p-2f,
    0x1.b4328cp-2f, 0x1.b9c564p-2f, 0x1.bf62dp-2f, 0x1.c50ad4p-2f, 0x1.cabd7ap-2f,
    0x1.d07ac6p-2f, 0x1.d642bap-2f, 0x1.dc1562p-2f, 0x1.e1f2bep-2f, 0x1.e7dad6p-2f,
    0x1.edcdbp-2f, 0x1.f3cb5p-2f, 0x1.f9d3bcp-2f, 0x1.ffe6fcp-2f, 0x1.03028ap-1f,
    0x1.061704p-1f, 0x1.0930eep-1f, 0x1.0c504ep-1f, 0x1.0f7524p-1f, 0x1.129f72p-1f,
    0x1.15cf3ep-1f, 0x1.190488p-1f, 0x1.1c3f54p-1f, 0x1.1f7fa4p-1f, 0x1.22c57cp-1f,
    0x1.2610dcp-1f, 0x1.2961c8p-1f, 0x1.2cb844p-1f, 0x1.301452p-1f, 0x1.3375f4p-1f,
    0x1.36dd2cp-1f, 0x1.3a49fep-1f, 0x1.3dbc6cp-1f, 0x1.413478p-1f, 0x1.44b226p-1f,
    0x1.483578p-1f, 0x1.4bbe7p-1f, 0x1.4f4d12p-1f, 0x1.52e15ep-1f, 0x1.567b5ap-1f,
    0x1.5a1b06p-1f, 0x1.5dc064p-1f, 0x1.616b7ap-1f, 0x1.651c48p-1f, 0x1.68d2dp-1f,
    0x1.6c8f16p-1f, 0x1.70511ep-1f, 0x1.7418e6p-1f, 0x1.77e674p-1f, 0x1.7bb9cap-1f,
    0x1.7f92eap-1f, 0x1.8371d6p-1f, 0x1.87569p-1f, 0x1.8b411ep-1f, 0x1.8f317ep-1f,
    0x1.9327b6p-1f, 0x1.9723c6p-1f, 0x1.9b25bp-1f, 0x1.9f2d7ap-1f, 0x1.a33b24p-1f,
    0x1.a74ebp-1f, 0x1.ab6822p-1f, 0x1.af877cp-1f, 0x1.b3acbep-1f, 0x1.b7d7eep-1f,
    0x1.bc090cp-1f, 0x1.c0401cp-1f, 0x1.c47d2p-1f, 0x1.c8c018p-1f, 0x1.cd090ap-1f,
    0x1.d157f6p-1f, 0x1.d5acep-1f, 0x1.da07cap-1f, 0x1.de68b4p-1f, 0x1.e2cfa4p-1f,
    0x1.e73c9ap-1f, 0x1.ebaf98p-1f, 0x1.f028a2p-1f, 0x1.f4a7bap-1f, 0x1.f92ce2p-1f,
    0x1.fdb81cp-1f, 2.0f, /* sentinel: above every clamped input */
};
static const uint8_t srgb_bucket[1664] = {
      0,  0,  0,  0,  0,  0,  0,  0,  0,  0,  0,  0,  0,  0,  0,  0,  0,  0,  0,  0,  0,  0,  0,  0,
      0,  0,  0,  0,  0,  0,  0,  0,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,
      1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,
      1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,
      1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,
      1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,
      1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,
      1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,
      1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,
      1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  1,  2,
      2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,
      2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,
      2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,
      2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  2,  3,  3,  3,  3,  3,  3,  3,  3,  3,
      3,  3,  3,  3,  3,  3,  3,  3,  3,  3,  3,  3,  3,  3,  3,  3,  3,  3,  3,  3,  3,  3,  3,  3,
      3,  3,  3,  3,  3,  3,  3,  3,  3,  3,  3,  3,  3,  3,  3,  3,  3,  3,  3,  3,  3,  3,  3,  3,
      3,  3,  3,  3,  3,  3,  3,  3,  3,  3,  3,  3,  4,  4,  4,  4,  4,  4,  4,  4,  4,  4,  4,  4,
      4,  4,  4,  4,  4,  4,  4,  4,  4,  4,  4,  4,  4,  4,  4,  4,  4,  4,  4,  4,  4,  4,  4,  4,
      4,  4,  4,  4,  5,  5,  5,  5,  5,  5,  5,  5,  5,  5,  5,  5,  5,  5,  5,  5,  5,  5,  5,  5,
      5,  5,  5,  5,  5,  5,  5,  5,  5,  5,  5,  5,  5,  5,  5,  5,  5,  5,  5,  6,  6,  6,  6,  6,
      6,  6,  6,  6,  6,  6,  6,  6,  6,  6,  6,  6,  6,  6,  6,  6,  6,  6,  6,  6,  6,  6,  6,  6,
      6,  6,  6,  6,  6,  6,  6,  6,  6,  6,  7,  7,  7,  7,  7,  7,  7,  7,  7,  7,  7,  7,  7,  7,
      7,  7,  7,  7,  7,  7,  8,  8,  8,  8,  8,  8,  8,  8,  8,  8,  8,  8,  8,  8,  8,  8,  8,  8,
      8,  8,  9,  9,  9,  9,  9,  9,  9,  9,  9,  9,  9,  9,  9,  9,  9,  9,  9,  9,  9, 10, 10, 10,
     10, 10, 10, 10, 10, 10, 10, 10, 10, 10, 10, 10, 10, 10, 10, 10, 10, 11, 11, 11, 11, 11, 11, 11,
     11, 11, 11, 11, 11, 11, 11, 11, 11, 11, 11, 11, 11, 11, 12, 12, 12, 12, 12, 12, 12, 12, 12, 12,
     12, 12, 12, 12, 12, 12, 12, 12, 12, 12, 12, 12, 12, 13, 13, 13, 13, 13, 13, 13, 13, 13, 13, 13,
     13, 13, 14, 14, 14, 14, 14, 14, 14, 14, 14, 14, 14, 14, 14, 15, 15, 15, 15, 15, 15, 15, 15, 15,
     15, 15, 15, 15, 16, 16, 16, 16, 16, 16, 16, 16, 16, 16, 16, 16, 16, 17, 17, 17, 17, 17, 17, 17,
     17, 17, 17, 17, 17, 17, 17, 18, 18, 18, 18, 18, 18, 18, 18, 18, 18, 18, 18, 18, 18, 18, 19, 19,
     19, 19, 19, 19, 19, 19, 19, 19, 19, 19, 19, 19, 19, 19, 20, 20, 20, 20, 20, 20, 20, 20, 20, 20,
     20, 20, 20, 20, 20, 20, 21, 21, 21, 21, 21, 21, 21, 21, 21, 21, 21, 21, 21, 21, 21, 21, 21, 22,
     22, 22, 22, 22, 22, 22, 22, 22, 23, 23, 23, 23, 23, 23, 23, 23, 23, 24, 24, 24, 24, 24, 24, 24,
     24, 24, 24, 25, 25, 25, 25, 25, 25, 25, 25, 25, 25, 26, 26, 26, 26, 26, 26, 26, 26, 26, 26, 27,
     27, 27, 27, 27, 27, 27, 27, 27, 27, 28, 28, 28, 28, 28, 28, 28, 28, 28, 28, 28, 29, 29, 29, 29,
     29, 29, 29, 29, 29, 29, 29, 30, 30, 30, 30, 30, 30, 30, 30, 30, 30, 30, 30, 31, 31, 31, 31, 31,
     31, 31, 31, 31, 31, 31, 31, 32, 32, 32, 32, 32, 32, 32, 32, 32, 32, 32, 32, 33, 33, 33, 33, 33,
     33, 33, 33, 33, 33, 33, 33, 33, 34, 34, 34, 34, 34, 34, 34, 35, 35, 35, 35, 35, 35, 35, 36, 36,
     36, 36, 36, 36, 36, 37, 37, 37, 37, 37, 37, 37, 38, 38, 38, 38, 38, 38, 38, 39, 39, 39, 39, 39,
     39, 39, 40, 40, 40, 40, 40, 40, 40, 40, 41, 41, 41, 41, 41, 41, 41, 41, 42, 42, 42, 42, 42, 42,
     42, 42, 43, 43, 43, 43, 43, 43, 43, 43, 43, 44, 44, 44, 44, 44, 44, 44, 44, 45, 45, 45, 45, 45,
     45, 45, 45, 45, 46, 46, 46, 46, 46, 46, 46, 46, 46, 47, 47, 47, 47, 47, 47, 47, 47, 47, 48, 48,
     48, 48, 48, 48, 48, 48, 48, 49, 49, 49, 49, 49, 49, 49, 49, 49, 49, 50, 50, 50, 50, 50, 51, 51,
     51, 51, 51, 52, 52, 52, 52, 52, 53, 53, 53, 53, 53, 54, 54, 54, 54, 54, 55, 55, 55, 55, 55, 55,
     56, 56, 56, 56, 56, 57, 57, 57, 57, 57, 57, 58, 58, 58, 58, 58, 58, 59, 59, 59, 59, 59, 59, 60,
     60, 60, 60, 60, 60, 61, 61, 61, 61, 61, 61, 62, 62, 62, 62, 62, 62, 63, 63, 63, 63, 63, 63, 64,
     64, 64, 64, 64, 64, 64, 65, 65, 65, 65, 65, 65, 66, 66, 66, 66, 66, 66, 66, 67, 67, 67, 67, 67,
     67, 67, 68, 68, 68, 68, 68, 68, 68, 69, 69, 69, 69, 69, 69, 69, 70, 70, 70, 70, 70, 70, 70, 71,
     71, 71, 71, 72, 72, 72, 72, 73, 73, 73, 73, 74, 74, 74, 74, 75, 75, 75, 75, 76, 76, 76, 77, 77,
     77, 77, 77, 78, 78, 78, 78, 79, 79, 79, 79, 80, 80, 80, 80, 81, 81, 81, 81, 82, 82, 82, 82, 83,
     83, 83, 83, 83, 84, 84, 84, 84, 85, 85, 85, 85, 85, 86, 86, 86, 86, 87, 87, 87, 87, 87, 88, 88,
     88, 88, 88, 89, 89, 89, 89, 90, 90, 90, 90, 90, 91, 91, 91, 91, 91, 92, 92, 92, 92, 92, 93, 93,
     93, 93, 93, 94, 94, 94, 94, 94, 95, 95, 95, 95, 95, 96, 96, 96, 96, 96, 96, 97, 97, 97, 97, 97,
     98, 98, 98, 98, 98, 99, 99, 99, 99, 99,100,100,101,101,101,102,102,102,103,103,103,104,104,104,
    105,105,105,106,106,106,107,107,107,108,108,108,109,109,109,110,110,110,111,111,111,112,112,112,
    113,113,113,114,114,114,115,115,115,115,116,116,116,117,117,117,118,118,118,118,119,119,119,120,
    120,120,120,121,121,121,122,122,122,122,123,123,123,124,124,124,124,125,125,125,126,126,126,126,
    127,127,127,127,128,128,128,129,129,129,129,130,130,130,130,131,131,131,131,132,132,132,132,133,
    133,133,133,134,134,134,134,135,135,135,135,136,136,136,136,137,137,137,138,138,139,139,140,140,
    141,141,142,142,143,143,144,144,145,145,145,146,146,147,147,148,148,149,149,149,150,150,151,151,
    152,152,153,153,153,154,154,155,155,155,156,156,157,157,158,158,158,159,159,160,160,160,161,161,
    162,162,162,163,163,164,164,164,165,165,166,166,166,167,167,167,168,168,169,169,169,170,170,170,
    171,171,172,172,172,173,173,173,174,174,174,175,175,176,176,176,177,177,177,178,178,178,179,179,
    179,180,180,180,181,181,181,182,182,183,183,183,184,184,184,185,185,185,186,186,186,187,187,187,
    188,188,189,189,190,191,191,192,193,193,194,195,195,196,196,197,198,198,199,199,200,201,201,202,
    202,203,204,204,205,205,206,207,207,208,208,209,209,210,211,211,212,212,213,213,214,214,215,216,
    216,217,217,218,218,219,219,220,220,221,221,222,223,223,224,224,225,225,226,226,227,227,228,228,
    229,229,230,230,231,231,232,232,233,233,234,234,235,235,236,236,237,237,238,238,239,239,239,240,
    240,241,241,242,242,243,243,244,244,245,245,246,246,246,247,247,248,248,249,249,250,250,251,251,
    251,252,252,253,253,254,254,255,
};

/* srgb_bucket[i] covers the floats whose bits >> 16 are SRGB_BUCKET_BASE + i:
 * base is 2^-13 (below srgb_t[1] = 1.52e-4), the last bucket ends at 1. */
#define SRGB_BUCKET_BASE (0x39000000u >> 16)

/* Clamp, then look up: one path for every input. Inputs below 2^-13
 * (NaN too) share bucket 0, whose code is 0 (srgb_t[1] is above 2^-13);
 * inputs >= 1 become the float below 1, whose code is 255. About 3 ns per
 * channel; gcc 12 turns the clamps into branches, and SSE min/max
 * intrinsics instead were 25% faster on random data, no faster on
 * coherent images, so the portable form stays. */
static inline uint8_t srgb8(float v)
{
    float c = v >= 0x1p-13f ? v : 0x1p-13f; /* NaN and negatives too */
    c = c < 0x1.fffffep-1f ? c : 0x1.fffffep-1f;
    uint32_t bits;
    memcpy(&bits, &c, sizeof bits);
    unsigned k = srgb_bucket[(bits >> 16) - SRGB_BUCKET_BASE];
    return (uint8_t)(k + (c >= srgb_t[k + 1]));
}

uint8_t vt_srgb8_from_linear(float v)
{
    return srgb8(v);
}

/* ---- tone mapping ---------------------------------------------------------- */

/* Narkowicz's ACES fit reaches 1 at x = 7.2417 (the positive root of
 * 0.08x^2 - 0.56x - 0.14) and stays above it; inputs are capped here
 * before evaluating (inf / inf would be NaN), and the curve there, 1.018,
 * still clamps to 1. */
#define ACES_WHITE 16.0

/* Scene-linear x (exposure applied) to display-linear [0, 1]. Double:
 * the ratio is then monotone to within double rounding, and the float it
 * is rounded to is what the exact OETF table sees. */
static inline float tonemap_curve(vt_tonemap_op op, double x)
{
    x = x > 0 ? x : 0.0; /* NaN and negatives: 0 */
    if (op == VT_TONEMAP_ACES) {
        /* K. Narkowicz, "ACES Filmic Tone Mapping Curve", blog post,
         * 2016-01-06: a rational fit of ODT(RRT(x)) for Rec.709, per
         * channel, input pre-exposed so 1 maps to ~0.8 (max fit error
         * 0.0138). Written here from the published formula. */
        x = x < ACES_WHITE ? x : ACES_WHITE; /* +inf too */
        x = (x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14);
    }
    return (float)(x < 1.0 ? x : 1.0);
}

float vt_tonemap_curve(vt_tonemap_op op, float x)
{
    return tonemap_curve(op, (double)x);
}

/* round(255 a) for a in [0, 1], half up (the only tie is a = 0.5 -> 128):
 * a * 255 is exact in double, and adding 0.5 rounds only for tiny a,
 * whose answer is 0 either way, so this is the real rounding. */
static inline uint8_t alpha8(float a)
{
    a = a > 0 ? a : 0.0f; /* NaN: 0 */
    a = a < 1 ? a : 1.0f;
    return (uint8_t)((double)a * 255.0 + 0.5);
}

/* ACES straight to sRGB8 without evaluating the curve: both steps are
 * monotone, so code(x) = the number of thresholds aces_t[1..255] <= x,
 * aces_t[k] being the smallest float x with srgb8(tonemap_curve(x)) >= k,
 * found once by binary search over float bit patterns (so it agrees with
 * the two-step path for every float x, not within a code). Finding k:
 * buckets of 2^-8 octave over [2^-12, 16) hold the code of their lowest
 * float; a bucket may span a threshold or two, hence the loop. It replaces
 * a double division per channel: a 1280x720 frame of random HDR values
 * (1e-3..10) went from 17.7 to 8.3 ms (medians of 21, one run),
 * bench_render's coherent frame from 7.6 to 5.4 ms. */
#define ACES_LO_BITS 0x39800000u /* 2^-12 */
#define ACES_HI_BITS 0x41800000u /* 16 */
#define ACES_NBUCKETS ((ACES_HI_BITS - ACES_LO_BITS) >> 15)
static float aces_t[257];
static uint8_t aces_bucket[ACES_NBUCKETS];
static pthread_once_t aces_once = PTHREAD_ONCE_INIT;

static inline unsigned aces_code_slow(float x)
{
    return srgb8(tonemap_curve(VT_TONEMAP_ACES, (double)x));
}

static void aces_init(void)
{
    /* thresholds: the first float (from 2^-12 up) with code >= k */
    aces_t[0] = 0;
    for (unsigned k = 1; k < 256; k++) {
        uint32_t lo = ACES_LO_BITS, hi = ACES_HI_BITS; /* code(hi) = 255 >= k */
        while (lo < hi) {
            uint32_t mid = lo + (hi - lo) / 2;
            float x;
            memcpy(&x, &mid, sizeof x);
            if (aces_code_slow(x) >= k) hi = mid;
            else lo = mid + 1;
        }
        memcpy(&aces_t[k], &lo, sizeof lo);
    }
    aces_t[256] = INFINITY;
    for (uint32_t i = 0; i < ACES_NBUCKETS; i++) {
        uint32_t bits = ACES_LO_BITS + (i << 15);
        float x;
        memcpy(&x, &bits, sizeof x);
        aces_bucket[i] = (uint8_t)aces_code_slow(x);
    }
}

/* x already scaled by the exposure; NaN and anything below 2^-12 is code
 * 0 (aces_t[1] is about 7e-4), 16 and above is 255. */
static inline uint8_t aces8(float x)
{
    float c = x >= 0x1p-12f ? x : 0x1p-12f;
    c = c < 0x1.fffffep3f ? c : 0x1.fffffep3f;
    uint32_t bits;
    memcpy(&bits, &c, sizeof bits);
    unsigned k = aces_bucket[(bits - ACES_LO_BITS) >> 15];
    while (c >= aces_t[k + 1]) k++;
    return (uint8_t)k;
}

size_t vt_image_rgba8_size(uint32_t width, uint32_t height)
{
    if (width < 1 || height < 1 || width > VT_IMAGE_MAX_DIM || height > VT_IMAGE_MAX_DIM) return 0;
    return (size_t)width * height * 4;
}

int vt_image_tonemap(uint32_t width, uint32_t height, const vt_image_src *src,
                     const vt_tonemap_desc *desc, uint8_t *out, size_t out_stride_bytes)
{
    vt_tonemap_desc d = desc ? *desc : (vt_tonemap_desc){0};
    if (!vt_image_rgba8_size(width, height) || !src || !out || !src->r.data ||
        !src->g.data != !src->b.data || out_stride_bytes < (size_t)width * 4 ||
        (d.op != VT_TONEMAP_CLAMP && d.op != VT_TONEMAP_ACES) ||
        !(d.exposure_ev >= -64.0f && d.exposure_ev <= 64.0f))
        return VT_ERR_INVALID;
    const vt_image_channel *r = &src->r;
    const vt_image_channel *g = src->g.data ? &src->g : r, *b = src->b.data ? &src->b : r;
    const vt_image_channel *a = src->a.data ? &src->a : NULL;
    const ptrdiff_t rx = r->x_stride, gx = g->x_stride, bx = b->x_stride, ax = a ? a->x_stride : 0;
    static const float opaque = 1.0f; /* alpha of a source without one (ax = 0) */
    const double scale = exp2((double)d.exposure_ev); /* 1 exactly for 0 EV */
    if (d.op == VT_TONEMAP_ACES) pthread_once(&aces_once, aces_init);
    for (uint32_t y = 0; y < height; y++) {
        const float *pr = r->data + (ptrdiff_t)y * r->y_stride;
        const float *pg = g->data + (ptrdiff_t)y * g->y_stride;
        const float *pb = b->data + (ptrdiff_t)y * b->y_stride;
        const float *pa = a ? a->data + (ptrdiff_t)y * a->y_stride : &opaque;
        uint8_t *o = out + (size_t)y * out_stride_bytes;
        for (uint32_t x = 0; x < width; x++, o += 4) {
            ptrdiff_t i = (ptrdiff_t)x;
            float al = pa[i * ax];
            double k = scale;
            if (d.premultiplied) k = al > 0 ? scale / (double)al : 0.0; /* NaN alpha: 0 */
            /* inf * 0 is NaN, which the curve makes 0 */
            if (d.op == VT_TONEMAP_ACES) {
                o[0] = aces8((float)((double)pr[i * rx] * k));
                o[1] = aces8((float)((double)pg[i * gx] * k));
                o[2] = aces8((float)((double)pb[i * bx] * k));
            } else {
                o[0] = srgb8(tonemap_curve(d.op, (double)pr[i * rx] * k));
                o[1] = srgb8(tonemap_curve(d.op, (double)pg[i * gx] * k));
                o[2] = srgb8(tonemap_curve(d.op, (double)pb[i * bx] * k));
            }
            o[3] = alpha8(al);
        }
    }
    return 0;
}

/* ---- output sink ----------------------------------------------------------- */

/* Staging buffer for files and the first allocation for memory streams. */
#define SINK_CHUNK ((size_t)64 << 10)

typedef struct sink {
    int       fd;   /* >= 0: a file, buf stages writes; < 0: memory, buf is
                       the stream so far */
    uint8_t  *buf;  /* malloc'ed */
    size_t    len;  /* bytes in buf */
    size_t    cap;  /* bytes allocated */
    int       err;  /* first failure: a write's errno, or ENOMEM */
    vt_call *call;
} sink;

static bool sink_fail(sink *s, int e, const char *what)
{
    char buf[128];
    if (!s->err) s->err = e;
    vt_call_msg(s->call, "%s: %s", what, vt_errno_text(e, buf, sizeof buf));
    return false;
}

/* File: writes buf[0..len) out. */
static bool sink_flush(sink *s)
{
    size_t done = 0;
    while (done < s->len) {
        ssize_t n = write(s->fd, s->buf + done, s->len - done);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) return sink_fail(s, n < 0 ? errno : EIO, "write");
        done += (size_t)n;
    }
    s->len = 0;
    return true;
}

/* Makes cap - len > 0: a file is flushed, memory doubles. */
static bool sink_room(sink *s)
{
    if (s->err) return false;
    if (s->fd >= 0) return s->len < s->cap || sink_flush(s);
    if (s->len < s->cap) return true;
    size_t cap = s->cap < SINK_CHUNK ? SINK_CHUNK : s->cap;
    if (cap > SIZE_MAX / 2) return sink_fail(s, ENOMEM, "out of memory");
    cap *= 2;
    uint8_t *b = realloc(s->buf, cap);
    if (!b) return sink_fail(s, ENOMEM, "out of memory");
    s->buf = b;
    s->cap = cap;
    return true;
}

static bool sink_put(sink *s, const void *p, size_t n)
{
    const uint8_t *q = p;
    while (n > 0) {
        if (!sink_room(s)) return false;
        size_t k = s->cap - s->len < n ? s->cap - s->len : n;
        memcpy(s->buf + s->len, q, k);
        s->len += k;
        q += k;
        n -= k;
    }
    return true;
}

/* ---- files --------------------------------------------------------------- */

/* Runs enc(job, sink) into a temporary file beside path and renames it
 * into place; on failure the temporary is removed and path untouched. */
static int write_file(vt_call *c, const char *path, int (*enc)(void *job, sink *s), void *job)
{
    sink s = {.fd = -1, .call = c};
    char *tmp = NULL;
    int rc = vt_temp_open(c, path, &tmp, &s.fd);
    if (rc == 0 && !(s.buf = malloc(SINK_CHUNK))) {
        vt_call_msg(c, "out of memory");
        rc = VT_ERR_NOMEM;
    }
    s.cap = SINK_CHUNK;
    if (rc == 0) rc = enc(job, &s);
    if (rc == 0 && !sink_flush(&s)) rc = vt_err_from_errno(s.err);
    rc = vt_temp_finish(c, path, tmp, s.fd, rc);
    free(s.buf);
    return rc;
}

/* Checks an 8-bit image argument set. */
static int check_pixels(vt_call *c, uint32_t width, uint32_t height, const uint8_t *pix,
                        size_t stride, uint32_t pixel_bytes)
{
    if (width < 1 || height < 1 || width > VT_IMAGE_MAX_DIM || height > VT_IMAGE_MAX_DIM) {
        vt_call_msg(c, "image size %ux%u outside 1x1..%ux%u", width, height, VT_IMAGE_MAX_DIM,
                 VT_IMAGE_MAX_DIM);
        return VT_ERR_INVALID;
    }
    if (!pix) {
        vt_call_msg(c, "no pixels");
        return VT_ERR_INVALID;
    }
    if (stride < (size_t)width * pixel_bytes) {
        vt_call_msg(c, "row stride %zu below %u x %u bytes", stride, width, pixel_bytes);
        return VT_ERR_INVALID;
    }
    return 0;
}

static int check_path(vt_call *c, const char *path)
{
    if (path && path[0]) return 0;
    vt_call_msg(c, "no path");
    return VT_ERR_INVALID;
}

/* ---- PNG ------------------------------------------------------------------- */

typedef struct png_job {
    vt_call     *c;
    png_structp   png;
    png_infop     info;
    bool          nomem;   /* an allocation failed: the likely cause */
    bool          too_big; /* reading: larger than VT_IMAGE_MAX_DIM */
    /* writing */
    sink         *out;
    const uint8_t *px;
    size_t        stride;
    bool          alpha;
    int           level;
    /* reading */
    int           fd;
    int           io_err;  /* errno of a failed read */
    uint8_t      *pix;     /* the decoded image, malloc'ed */
    png_bytep    *rows;    /* row pointers into pix, malloc'ed */
    bool          has_alpha;
    uint32_t      w, h;
} png_job;

static void png_on_error(png_structp png, png_const_charp msg)
{
    png_job *j = png_get_error_ptr(png);
    vt_call_msg(j->c, "%s", msg ? msg : "libpng error");
    png_longjmp(png, 1);
}

/* Warnings (ancillary chunks dropped, CRCs of unknown chunks) change no
 * pixel; they are not printed either. */
static void png_on_warning(png_structp png, png_const_charp msg)
{
    (void)png;
    (void)msg;
}

static png_voidp png_on_malloc(png_structp png, png_alloc_size_t n)
{
    void *p = malloc(n);
    png_job *j = png_get_mem_ptr(png);
    if (!p && j) j->nomem = true;
    return p;
}

static void png_on_free(png_structp png, png_voidp p)
{
    (void)png;
    free(p);
}

static void png_on_write(png_structp png, png_bytep data, size_t n)
{
    png_job *j = png_get_io_ptr(png);
    if (!sink_put(j->out, data, n)) png_error(png, "write failed");
}

static void png_on_flush(png_structp png)
{
    (void)png; /* the sink is flushed once, at the end */
}

static void png_on_read(png_structp png, png_bytep data, size_t n)
{
    png_job *j = png_get_io_ptr(png);
    char buf[128];
    while (n > 0) {
        ssize_t got = read(j->fd, data, n);
        if (got < 0 && errno == EINTR) continue;
        if (got < 0) {
            j->io_err = errno;
            vt_call_msg(j->c, "read: %s", vt_errno_text(errno, buf, sizeof buf));
            png_error(png, "read failed");
        }
        if (got == 0) png_error(png, "unexpected end of file");
        data += got;
        n -= (size_t)got;
    }
}

/* The only function that calls setjmp for libpng (see the top). */
static int png_guarded(png_job *j, void (*body)(png_job *))
{
    if (setjmp(png_jmpbuf(j->png))) return -1;
    body(j);
    return 0;
}

static void png_write_body(png_job *j)
{
    png_structp png = j->png;
    png_infop info = j->info;
    png_uint_32 w = j->w, h = j->h;
    png_set_write_fn(png, j, png_on_write, png_on_flush);
    if (j->level >= 0) png_set_compression_level(png, j->level);
    png_set_IHDR(png, info, w, h, 8, j->alpha ? PNG_COLOR_TYPE_RGB_ALPHA : PNG_COLOR_TYPE_RGB,
                 PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    png_set_sRGB(png, info, PNG_sRGB_INTENT_PERCEPTUAL);
    png_write_info(png, info);
    if (!j->alpha) png_set_filler(png, 0, PNG_FILLER_AFTER); /* rows stay RGBA: skip A */
    for (png_uint_32 y = 0; y < h; y++) png_write_row(png, j->px + (size_t)y * j->stride);
    png_write_end(png, NULL);
}

static int png_encode(void *job, sink *s)
{
    png_job *j = job;
    j->out = s;
    j->png = png_create_write_struct_2(PNG_LIBPNG_VER_STRING, j, png_on_error, png_on_warning, j,
                                       png_on_malloc, png_on_free);
    if (j->png) j->info = png_create_info_struct(j->png);
    int rc = j->info ? png_guarded(j, png_write_body) : -1;
    if (rc != 0) {
        rc = s->err ? vt_err_from_errno(s->err) : j->nomem || !j->info ? VT_ERR_NOMEM : VT_ERR_CODEC;
        vt_call_msg(j->c, "libpng failed");
    }
    png_destroy_write_struct(&j->png, &j->info);
    return rc;
}

int vt_png_write(const char *path, uint32_t width, uint32_t height, const uint8_t *rgba8,
                 size_t row_stride_bytes, bool alpha, int compression_level, char *err,
                 size_t errlen)
{
    vt_call c = vt_call_begin(path, err, errlen);
    int rc = check_path(&c, path);
    if (rc == 0) rc = check_pixels(&c, width, height, rgba8, row_stride_bytes, 4);
    if (rc == 0 && (compression_level < -1 || compression_level > 9)) {
        vt_call_msg(&c, "compression level %d outside -1..9", compression_level);
        rc = VT_ERR_INVALID;
    }
    if (rc != 0) return vt_call_end(&c, rc);
    png_job j = {.c = &c, .px = rgba8, .stride = row_stride_bytes, .alpha = alpha,
                 .level = compression_level, .w = width, .h = height, .fd = -1};
    return vt_call_end(&c, write_file(&c, path, png_encode, &j));
}

static void png_read_body(png_job *j)
{
    png_structp png = j->png;
    png_infop info = j->info;
    png_uint_32 w = 0, h = 0;
    int depth = 0, ctype = 0;
    png_set_read_fn(png, j, png_on_read);
    png_read_info(png, info);
    png_get_IHDR(png, info, &w, &h, &depth, &ctype, NULL, NULL, NULL);
    if (w > VT_IMAGE_MAX_DIM || h > VT_IMAGE_MAX_DIM) {
        j->too_big = true;
        vt_call_msg(j->c, "image %ux%u larger than %ux%u", (unsigned)w, (unsigned)h, VT_IMAGE_MAX_DIM,
                 VT_IMAGE_MAX_DIM);
        png_error(png, "image too large");
    }
    bool trns = png_get_valid(png, info, PNG_INFO_tRNS) != 0;
    j->has_alpha = (ctype & PNG_COLOR_MASK_ALPHA) || trns;
    if (ctype == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(png);
    if (ctype == PNG_COLOR_TYPE_GRAY && depth < 8) png_set_expand_gray_1_2_4_to_8(png);
    if (trns) png_set_tRNS_to_alpha(png);
    if (depth == 16) png_set_scale_16(png);
    if (!(ctype & PNG_COLOR_MASK_COLOR)) png_set_gray_to_rgb(png);
    if (!j->has_alpha) png_set_filler(png, 0xff, PNG_FILLER_AFTER);
    png_set_interlace_handling(png);
    png_read_update_info(png, info);
    if (png_get_rowbytes(png, info) != (size_t)w * 4 || png_get_bit_depth(png, info) != 8)
        png_error(png, "unexpected row layout after conversion to RGBA8");
    j->pix = malloc((size_t)w * h * 4);
    j->rows = malloc((size_t)h * sizeof *j->rows);
    if (!j->pix || !j->rows) {
        j->nomem = true;
        png_error(png, "out of memory for the image");
    }
    for (png_uint_32 y = 0; y < h; y++) j->rows[y] = j->pix + (size_t)y * w * 4;
    png_read_image(png, j->rows);
    png_read_end(png, NULL); /* the rest of the file: CRCs, IEND */
    j->w = w;
    j->h = h;
}

int vt_png_read(const char *path, uint8_t **rgba8, uint32_t *width, uint32_t *height,
                bool *has_alpha, char *err, size_t errlen)
{
    vt_call c = vt_call_begin(path, err, errlen);
    char buf[128];
    if (rgba8) *rgba8 = NULL;
    if (width) *width = 0;
    if (height) *height = 0;
    if (has_alpha) *has_alpha = false;
    int rc = check_path(&c, path);
    if (rc == 0 && (!rgba8 || !width || !height)) {
        vt_call_msg(&c, "no output for the image or its size");
        rc = VT_ERR_INVALID;
    }
    if (rc != 0) return vt_call_end(&c, rc);
    png_job j = {.c = &c, .fd = open(path, O_RDONLY | O_CLOEXEC)};
    if (j.fd < 0) {
        int e = errno;
        rc = vt_err_from_errno(e);
        vt_call_msg(&c, "open: %s", vt_errno_text(e, buf, sizeof buf));
        return vt_call_end(&c, rc);
    }
    j.png = png_create_read_struct_2(PNG_LIBPNG_VER_STRING, &j, png_on_error, png_on_warning, &j,
                                     png_on_malloc, png_on_free);
    if (j.png) j.info = png_create_info_struct(j.png);
    rc = j.info ? png_guarded(&j, png_read_body) : -1;
    if (rc != 0) {
        rc = j.io_err ? vt_err_from_errno(j.io_err) : j.nomem || !j.info ? VT_ERR_NOMEM : j.too_big ? VT_ERR_TOO_LARGE : VT_ERR_CORRUPT;
        vt_call_msg(&c, "libpng failed");
    }
    png_destroy_read_struct(&j.png, &j.info, NULL);
    close(j.fd);
    free(j.rows);
    if (rc != 0) {
        free(j.pix);
        return vt_call_end(&c, rc);
    }
    *rgba8 = j.pix;
    *width = j.w;
    *height = j.h;
    if (has_alpha) *has_alpha = j.has_alpha;
    return vt_call_end(&c, 0);
}

/* ---- JPEG ------------------------------------------------------------------ */

typedef struct jpg_err {
    struct jpeg_error_mgr pub; /* first: libjpeg's cinfo->err points here */
    jmp_buf    jump;
    vt_call  *c;
    int        code; /* a negative errno chosen here before jumping, or 0 */
} jpg_err;

static void jpg_on_error(j_common_ptr ci)
{
    jpg_err *e = (jpg_err *)ci->err;
    char msg[JMSG_LENGTH_MAX];
    (*ci->err->format_message)(ci, msg);
    vt_call_msg(e->c, "%s", msg);
    longjmp(e->jump, 1);
}

/* Warnings (msg_level < 0) mean corrupt or truncated data, which libjpeg
 * would paper over with grey: an error here. Trace messages are dropped. */
static void jpg_on_message(j_common_ptr ci, int msg_level)
{
    if (msg_level >= 0) return;
    ci->err->num_warnings++;
    jpg_on_error(ci);
}

static void jpg_on_output(j_common_ptr ci)
{
    (void)ci; /* never print to stderr */
}

/* Fails the running body with a code of our choosing. */
#if defined(__GNUC__)
__attribute__((noreturn, format(printf, 3, 4)))
#endif
static void jpg_abort(j_common_ptr ci, int code, const char *fmt, ...)
{
    jpg_err *e = (jpg_err *)ci->err;
    char msg[256];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    vt_call_msg(e->c, "%s", msg);
    e->code = code;
    longjmp(e->jump, 1);
}

static void jpg_err_init(jpg_err *e, vt_call *c)
{
    jpeg_std_error(&e->pub);
    e->pub.error_exit = jpg_on_error;
    e->pub.emit_message = jpg_on_message;
    e->pub.output_message = jpg_on_output;
    e->c = c;
    e->code = 0;
}

/* The errno for a failed body. */
static int jpg_code(const jpg_err *e, const sink *s, int otherwise)
{
    if (e->code) return e->code;
    if (s && s->err) return vt_err_from_errno(s->err);
    if (e->pub.msg_code == JERR_OUT_OF_MEMORY) return VT_ERR_NOMEM;
    return otherwise;
}

typedef struct jpg_dest {
    struct jpeg_destination_mgr pub; /* first: cinfo->dest points here */
    sink *s;
} jpg_dest;

static void jpg_dest_init(j_compress_ptr ci)
{
    jpg_dest *d = (jpg_dest *)ci->dest;
    d->pub.next_output_byte = d->s->buf + d->s->len;
    d->pub.free_in_buffer = d->s->cap - d->s->len;
}

/* Called with the buffer full, whatever the pointers say (libjpeg.txt). */
static boolean jpg_dest_empty(j_compress_ptr ci)
{
    jpg_dest *d = (jpg_dest *)ci->dest;
    d->s->len = d->s->cap;
    if (!sink_room(d->s)) {
        if (d->s->err == ENOMEM) ERREXIT1(ci, JERR_OUT_OF_MEMORY, 0);
        ERREXIT(ci, JERR_FILE_WRITE);
    }
    jpg_dest_init(ci);
    return TRUE;
}

static void jpg_dest_term(j_compress_ptr ci)
{
    jpg_dest *d = (jpg_dest *)ci->dest;
    d->s->len = d->s->cap - d->pub.free_in_buffer;
}

typedef struct jpg_job {
    jpg_err        err;
    /* compressing */
    struct jpeg_compress_struct   ci;
    jpg_dest       dest;
    const uint8_t *px;
    size_t         stride;
    uint32_t       pixel_bytes;
    int            quality;
    /* decompressing */
    struct jpeg_decompress_struct di;
    const uint8_t *data;
    size_t         len;
    uint8_t       *pix; /* the decoded image, malloc'ed */
    uint32_t       w, h;
} jpg_job;

/* The only function that calls setjmp for libjpeg (see the top). */
static int jpg_guarded(jpg_job *j, void (*body)(jpg_job *))
{
    if (setjmp(j->err.jump)) return -1;
    body(j);
    return 0;
}

/* Rows handed to libjpeg per call: fewer calls, and a multiple of the 16
 * rows of a 4:2:0 MCU row. */
#define JPG_ROWS 16

static void jpg_compress_body(jpg_job *j)
{
    struct jpeg_compress_struct *ci = &j->ci;
    jpeg_create_compress(ci); /* keeps ->err, zeroes the rest */
    ci->dest = &j->dest.pub;
    ci->image_width = j->w;
    ci->image_height = j->h;
    ci->input_components = (int)j->pixel_bytes;
    ci->in_color_space = j->pixel_bytes == 4 ? JCS_EXT_RGBX : JCS_RGB;
    jpeg_set_defaults(ci); /* YCbCr 4:2:0, JFIF, ISLOW, standard Huffman tables */
    jpeg_set_quality(ci, j->quality, TRUE);
    jpeg_start_compress(ci, TRUE);
    JSAMPROW rows[JPG_ROWS];
    while (ci->next_scanline < ci->image_height) {
        JDIMENSION n = ci->image_height - ci->next_scanline;
        if (n > JPG_ROWS) n = JPG_ROWS;
        for (JDIMENSION i = 0; i < n; i++) /* libjpeg only reads the rows */
            rows[i] = (JSAMPROW)(uintptr_t)(j->px + (size_t)(ci->next_scanline + i) * j->stride);
        jpeg_write_scanlines(ci, rows, n);
    }
    jpeg_finish_compress(ci);
}

/* Compresses into s (file or memory). */
static int jpg_encode_to(void *job, sink *s)
{
    jpg_job *j = job;
    j->dest = (jpg_dest){.pub = {.init_destination = jpg_dest_init,
                                 .empty_output_buffer = jpg_dest_empty,
                                 .term_destination = jpg_dest_term},
                         .s = s};
    memset(&j->ci, 0, sizeof j->ci); /* ->mem NULL: destroy is safe if create fails */
    j->ci.err = &j->err.pub;
    int rc = jpg_guarded(j, jpg_compress_body);
    if (rc != 0) rc = jpg_code(&j->err, s, VT_ERR_CODEC);
    jpeg_destroy_compress(&j->ci);
    return rc;
}

static int jpg_check(vt_call *c, uint32_t width, uint32_t height, const uint8_t *pix,
                     size_t stride, uint32_t pixel_bytes, int quality)
{
    if (pixel_bytes != 3 && pixel_bytes != 4) {
        vt_call_msg(c, "pixel_bytes %u: must be 3 (RGB) or 4 (RGBA)", pixel_bytes);
        return VT_ERR_INVALID;
    }
    int rc = check_pixels(c, width, height, pix, stride, pixel_bytes);
    if (rc == 0 && (quality < 1 || quality > 100)) {
        vt_call_msg(c, "quality %d outside 1..100", quality);
        rc = VT_ERR_INVALID;
    }
    return rc;
}

int vt_jpeg_write(const char *path, uint32_t width, uint32_t height, const uint8_t *pix,
                  size_t row_stride_bytes, uint32_t pixel_bytes, int quality, char *err,
                  size_t errlen)
{
    vt_call c = vt_call_begin(path, err, errlen);
    int rc = check_path(&c, path);
    if (rc == 0) rc = jpg_check(&c, width, height, pix, row_stride_bytes, pixel_bytes, quality);
    if (rc != 0) return vt_call_end(&c, rc);
    jpg_job *j = calloc(1, sizeof *j); /* ~2 KiB of libjpeg structs: not on the stack */
    if (!j) {
        vt_call_msg(&c, "out of memory");
        return vt_call_end(&c, VT_ERR_NOMEM);
    }
    *j = (jpg_job){.px = pix, .stride = row_stride_bytes, .pixel_bytes = pixel_bytes,
                   .quality = quality, .w = width, .h = height};
    jpg_err_init(&j->err, &c);
    rc = write_file(&c, path, jpg_encode_to, j);
    free(j);
    return vt_call_end(&c, rc);
}

int vt_jpeg_encode(uint32_t width, uint32_t height, const uint8_t *pix, size_t row_stride_bytes,
                   uint32_t pixel_bytes, int quality, uint8_t **out, size_t *out_len, char *err,
                   size_t errlen)
{
    vt_call c = vt_call_begin("<memory>", err, errlen);
    if (out) *out = NULL;
    if (out_len) *out_len = 0;
    int rc = jpg_check(&c, width, height, pix, row_stride_bytes, pixel_bytes, quality);
    if (rc == 0 && (!out || !out_len)) {
        vt_call_msg(&c, "no output for the stream");
        rc = VT_ERR_INVALID;
    }
    if (rc != 0) return vt_call_end(&c, rc);
    jpg_job *j = calloc(1, sizeof *j);
    /* first guess 1/4 byte per pixel (2 bits: q85 on rendered frames);
     * doubling from there */
    size_t guess = (size_t)width * height / 4;
    sink s = {.fd = -1, .call = &c, .cap = guess < SINK_CHUNK ? SINK_CHUNK : guess};
    if (j) s.buf = malloc(s.cap);
    if (!j || !s.buf) {
        vt_call_msg(&c, "out of memory");
        rc = VT_ERR_NOMEM;
    }
    if (rc == 0) {
        *j = (jpg_job){.px = pix, .stride = row_stride_bytes, .pixel_bytes = pixel_bytes,
                       .quality = quality, .w = width, .h = height};
        jpg_err_init(&j->err, &c);
        rc = jpg_encode_to(j, &s);
    }
    free(j);
    if (rc != 0) {
        free(s.buf);
        return vt_call_end(&c, rc);
    }
    uint8_t *fit = s.len < s.cap ? realloc(s.buf, s.len) : NULL; /* give back the slack */
    *out = fit ? fit : s.buf;
    *out_len = s.len;
    return vt_call_end(&c, 0);
}

static void jpg_decompress_body(jpg_job *j)
{
    struct jpeg_decompress_struct *di = &j->di;
    j_common_ptr cp = (j_common_ptr)di;
    jpeg_create_decompress(di);
    jpeg_mem_src(di, j->data, (unsigned long)j->len); /* no allocation; empty: an error */
    jpeg_read_header(di, TRUE);
    if (di->image_width > VT_IMAGE_MAX_DIM || di->image_height > VT_IMAGE_MAX_DIM)
        jpg_abort(cp, VT_ERR_TOO_LARGE, "image %ux%u larger than %ux%u", di->image_width, di->image_height,
                  VT_IMAGE_MAX_DIM, VT_IMAGE_MAX_DIM);
    if (di->jpeg_color_space != JCS_GRAYSCALE && di->jpeg_color_space != JCS_YCbCr &&
        di->jpeg_color_space != JCS_RGB)
        jpg_abort(cp, VT_ERR_UNSUPPORTED, "colour space %d (CMYK / YCCK?) not supported",
                  (int)di->jpeg_color_space);
    di->out_color_space = JCS_RGB;
    di->dct_method = JDCT_ISLOW;
    jpeg_start_decompress(di);
    if (di->output_components != 3 || di->output_width != di->image_width ||
        di->output_height != di->image_height || di->output_width < 1 || di->output_height < 1)
        jpg_abort(cp, VT_ERR_CODEC, "libjpeg output %ux%ux%d, expected %ux%ux3", di->output_width,
                  di->output_height, di->output_components, di->image_width, di->image_height);
    size_t row = (size_t)di->output_width * 3;
    j->pix = malloc(row * di->output_height);
    if (!j->pix)
        jpg_abort(cp, VT_ERR_NOMEM, "out of memory for %ux%u", di->output_width, di->output_height);
    JSAMPROW rows[JPG_ROWS];
    while (di->output_scanline < di->output_height) {
        JDIMENSION n = di->output_height - di->output_scanline;
        if (n > JPG_ROWS) n = JPG_ROWS;
        for (JDIMENSION i = 0; i < n; i++)
            rows[i] = j->pix + (size_t)(di->output_scanline + i) * row;
        jpeg_read_scanlines(di, rows, n);
    }
    jpeg_finish_decompress(di);
    j->w = di->output_width;
    j->h = di->output_height;
}

static int jpg_decode(vt_call *c, const uint8_t *data, size_t len, uint8_t **rgb8,
                      uint32_t *width, uint32_t *height)
{
    if (!data || !rgb8 || !width || !height) {
        vt_call_msg(c, "no input, or no output for the image or its size");
        return VT_ERR_INVALID;
    }
    if (len == 0 || len > ULONG_MAX) {
        vt_call_msg(c, "stream of %zu bytes", len);
        return len ? VT_ERR_TOO_LARGE : VT_ERR_CORRUPT;
    }
    jpg_job *j = calloc(1, sizeof *j);
    if (!j) {
        vt_call_msg(c, "out of memory");
        return VT_ERR_NOMEM;
    }
    j->data = data;
    j->len = len;
    jpg_err_init(&j->err, c);
    j->di.err = &j->err.pub;
    int rc = jpg_guarded(j, jpg_decompress_body);
    if (rc != 0) rc = jpg_code(&j->err, NULL, VT_ERR_CORRUPT);
    jpeg_destroy_decompress(&j->di);
    if (rc == 0) {
        *rgb8 = j->pix;
        *width = j->w;
        *height = j->h;
    } else {
        free(j->pix);
    }
    free(j);
    return rc;
}

int vt_jpeg_decode(const uint8_t *data, size_t len, uint8_t **rgb8, uint32_t *width,
                   uint32_t *height, char *err, size_t errlen)
{
    vt_call c = vt_call_begin("<memory>", err, errlen);
    if (rgb8) *rgb8 = NULL;
    if (width) *width = 0;
    if (height) *height = 0;
    return vt_call_end(&c, jpg_decode(&c, data, len, rgb8, width, height));
}

/* Largest file vt_jpeg_read loads. */
#define JPG_MAX_FILE ((size_t)1 << 30)

int vt_jpeg_read(const char *path, uint8_t **rgb8, uint32_t *width, uint32_t *height, char *err,
                 size_t errlen)
{
    vt_call c = vt_call_begin(path, err, errlen);
    char buf[128];
    if (rgb8) *rgb8 = NULL;
    if (width) *width = 0;
    if (height) *height = 0;
    int rc = check_path(&c, path);
    if (rc != 0) return vt_call_end(&c, rc);
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0) {
        int e = errno;
        rc = vt_err_from_errno(e);
        vt_call_msg(&c, "open: %s", vt_errno_text(e, buf, sizeof buf));
        return vt_call_end(&c, rc);
    }
    struct stat st;
    uint8_t *data = NULL;
    size_t len = 0;
    if (fstat(fd, &st) != 0) {
        int e = errno;
        rc = vt_err_from_errno(e);
        vt_call_msg(&c, "stat: %s", vt_errno_text(e, buf, sizeof buf));
    } else if (!S_ISREG(st.st_mode) || st.st_size < 0 || (uint64_t)st.st_size > JPG_MAX_FILE) {
        vt_call_msg(&c, "not a regular file of at most %zu bytes", JPG_MAX_FILE);
        rc = S_ISREG(st.st_mode) ? VT_ERR_TOO_LARGE : VT_ERR_INVALID;
    } else if (!(data = malloc(st.st_size ? (size_t)st.st_size : 1))) {
        vt_call_msg(&c, "out of memory");
        rc = VT_ERR_NOMEM;
    }
    while (rc == 0 && len < (size_t)st.st_size) { /* a file that shrinks meanwhile ends early */
        ssize_t n = read(fd, data + len, (size_t)st.st_size - len);
        if (n < 0 && errno == EINTR) continue;
        if (n < 0) {
            int e = errno;
            rc = vt_err_from_errno(e);
            vt_call_msg(&c, "read: %s", vt_errno_text(e, buf, sizeof buf));
        }
        if (n <= 0) break;
        len += (size_t)n;
    }
    close(fd);
    if (rc == 0) rc = jpg_decode(&c, data, len, rgb8, width, height);
    free(data);
    return vt_call_end(&c, rc);
}
