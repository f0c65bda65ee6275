/*
 * vt_tonemap.c — tone mapping of HDR floats to sRGB8 for vt_image.h: the
 * exact sRGB encoding tables, the CLAMP and ACES curves, vt_image_tonemap.
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
 * Measured on the development machine (one core of a 2-core AMD EPYC VM,
 * gcc 12 -O2, medians of 15), a 1280x720 frame of an HDR ramp with a
 * bright spot, smooth / with 8% grain: ACES tone map of interleaved float
 * RGBA 15 / 16 ms (about 16 ns a pixel, the same for CLAMP). The
 * daemon's JPEG frames (interleaved RGB, ACES, no LUT) take a lanes row
 * with the same codes: AVX2, 8 pixels a step, one gathered bucket entry
 * per channel (vt_tonemap_avx2.c), the SSE2 row (aces_row_rgbx) for the
 * row's last pixels and CPUs without AVX2: 74 -> 10 M instructions a
 * 1280x720 city frame (callgrind), 6.4 -> ~2 ms on 2 threads.
 */
#include "vt_image.h"
#include "vt_lut.h"
#include "vt_tonemap_kern.h"

#include <math.h>
#include <pthread.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>

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
 * float and where in the bucket the next code starts (aces_tab,
 * vt_tonemap_kern.h): no bucket holds two thresholds (the steepest part
 * of the curve is ~0.6 code a bucket; aces_init checks it, and the loop
 * in aces8 keeps the scalar path exact were it ever not so). It replaces
 * a double division per channel: a 1280x720 frame of random HDR values
 * (1e-3..10) went from 17.7 to 8.3 ms (medians of 21, one run),
 * bench_render's coherent frame from 7.6 to 5.4 ms. */
#define ACES_LO_BITS VT_ACES_LO_BITS
#define ACES_HI_BITS VT_ACES_HI_BITS
#define ACES_NBUCKETS VT_ACES_NBUCKETS
static float aces_t[257];
static float aces_rw[256]; /* 1 / (aces_t[k + 1] - aces_t[k]), 0 for the last */
static uint32_t aces_tab[ACES_NBUCKETS]; /* vt_tonemap_kern.h: code + 1 << 16 | the next threshold's offset */
static vt_aces_rgbx_fn aces_lanes;       /* the AVX2 row, where the CPU has it and every bucket is simple */
static pthread_once_t aces_once = PTHREAD_ONCE_INIT;

static inline unsigned aces_code_slow(float x)
{
    return srgb8(tonemap_curve(VT_TONEMAP_ACES, (double)x));
}

static inline uint32_t bits_of(float x)
{
    uint32_t b;
    memcpy(&b, &x, sizeof b);
    return b;
}

/* The lanes instance unless VANTAGE_ISA names a narrower one (the image
 * files do not link culling/'s cull_isa_default; the same variable). */
static vt_aces_rgbx_fn aces_pick(void)
{
#if defined(__x86_64__) || defined(__i386__)
    const char *isa = getenv("VANTAGE_ISA");
    if (isa && (!strcmp(isa, "scalar") || !strcmp(isa, "sse41"))) return NULL;
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2") ? vt_aces_rgbx_avx2() : NULL;
#else
    return NULL;
#endif
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
    for (unsigned k = 0; k < 256; k++) aces_rw[k] = k < 255 ? 1 / (aces_t[k + 1] - aces_t[k]) : 0;
    bool simple = true;
    for (uint32_t i = 0; i < ACES_NBUCKETS; i++) {
        uint32_t bits = ACES_LO_BITS + (i << 15);
        float x;
        memcpy(&x, &bits, sizeof x);
        unsigned k = aces_code_slow(x);
        uint32_t off = 0x8000;
        if (k < 255 && bits_of(aces_t[k + 1]) - bits < 0x8000) {
            off = bits_of(aces_t[k + 1]) - bits;
            /* two thresholds in one bucket: aces8's loop finds the code,
               the lanes (one comparison) would not */
            if (k < 254 && bits_of(aces_t[k + 2]) - bits < 0x8000) simple = false;
        }
        aces_tab[i] = (uint32_t)(k + 1) << 16 | off;
    }
    aces_lanes = simple ? aces_pick() : NULL;
}

/* x already scaled by the exposure; NaN and anything below 2^-12 is code
 * 0 (aces_t[1] is about 7e-4), 16 and above is 255. */
static inline uint8_t aces8(float x)
{
    float c = x >= 0x1p-12f ? x : 0x1p-12f;
    c = c < 0x1.fffffep3f ? c : 0x1.fffffep3f;
    uint32_t d = bits_of(c) - ACES_LO_BITS, e = aces_tab[d >> 15];
    unsigned k = (e >> 16) - 1 + ((d & 0x7fffu) >= (e & 0xffffu));
    while (c >= aces_t[k + 1]) k++; /* never taken while every bucket is simple */
    return (uint8_t)k;
}

#ifdef __SSE2__
#include <emmintrin.h>
/* aces8 of an interleaved row of RGB(x) floats (x_stride 4, no alpha: 255),
 * the daemon's JPEG frame: the exposure's product in double, the clamp
 * and the bucket index in lanes, 4 channels at a time (the fourth, x,
 * is computed and dropped: p[3] of the last pixel is never read); the
 * bucket's entry and its one comparison (the loop after it only for
 * safety). The same codes as aces8, bit for bit. */

static void aces_row_rgbx(const float *p, uint32_t width, double scale, uint8_t *o)
{
    const __m128d k = _mm_set1_pd(scale);
    const __m128 lo = _mm_set1_ps(0x1p-12f), hi = _mm_set1_ps(0x1.fffffep3f);
    const __m128i base = _mm_set1_epi32((int)ACES_LO_BITS);
    for (uint32_t x = 0; x < width; x++, p += 4, o += 4) {
        __m128 v = x + 1 < width ? _mm_loadu_ps(p) : _mm_setr_ps(p[0], p[1], p[2], 0);
        __m128 e = _mm_movelh_ps(_mm_cvtpd_ps(_mm_mul_pd(_mm_cvtps_pd(v), k)),
                                 _mm_cvtpd_ps(_mm_mul_pd(_mm_cvtps_pd(_mm_movehl_ps(v, v)), k)));
        e = _mm_min_ps(_mm_max_ps(e, lo), hi); /* max first: a NaN becomes 2^-12 (code 0), as aces8 */
        __m128i bi = _mm_srli_epi32(_mm_sub_epi32(_mm_castps_si128(e), base), 15);
        float c[4];
        uint32_t b[4];
        _mm_storeu_ps(c, e);
        _mm_storeu_si128((__m128i *)b, bi);
        for (int ch = 0; ch < 3; ch++) {
            uint32_t t = aces_tab[b[ch]];
            unsigned kk = (t >> 16) - 1 + (((bits_of(c[ch]) - ACES_LO_BITS) & 0x7fffu) >= (t & 0xffffu));
            while (c[ch] >= aces_t[kk + 1]) kk++;
            o[ch] = (uint8_t)kk;
        }
        o[3] = 255;
    }
}
#endif

/* ACES then sRGB-encoded, as a float for the LUT: code k of aces8 spans
 * the encoded values [k - 1/2, k + 1/2) / 255 between thresholds aces_t[k]
 * and aces_t[k + 1]; where x lies between them, linearly, gives the
 * fraction. Exact at the thresholds, within a fraction of a code between
 * them (the curve is smooth over one code): enough for a LUT of slope
 * about 1, and an identity LUT gives back aces8's code exactly. */
static inline float aces_encoded(float x)
{
    unsigned k = aces8(x);
    if (k == 255) return 1.0f;
    float c = x >= 0x1p-12f ? x : 0.0f; /* NaN: 0 */
    float lo = aces_t[k];
    float fr = c > lo ? (c - lo) * aces_rw[k] : 0.0f;
    fr = fr < 1 ? fr : 1.0f;
    float v = ((float)k - 0.5f + fr) / 255.0f;
    return v > 0 ? v : 0.0f;
}

/* The exact OETF in double (the CLAMP curve's path with a LUT: tests,
 * masks; not a hot path). */
static inline float srgb_encoded(double v)
{
    v = v > 0 ? (v < 1 ? v : 1.0) : 0.0;
    return (float)(v <= 0.0031308 ? 12.92 * v : 1.055 * pow(v, 1 / 2.4) - 0.055);
}

static inline uint8_t code_of(float v)
{
    v = v > 0 ? (v < 1 ? v : 1.0f) : 0.0f; /* NaN: 0 */
    return (uint8_t)(v * 255.0f + 0.5f);
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
        !(d.exposure_ev >= -64.0f && d.exposure_ev <= 64.0f) ||
        (d.lut && (!d.lut->rgb || d.lut->n < 2 || d.lut->n > VT_LUT_MAX_SIZE)))
        return VT_ERR_INVALID;
    const vt_image_channel *r = &src->r;
    const vt_image_channel *g = src->g.data ? &src->g : r, *b = src->b.data ? &src->b : r;
    const vt_image_channel *a = src->a.data ? &src->a : NULL;
    const ptrdiff_t rx = r->x_stride, gx = g->x_stride, bx = b->x_stride, ax = a ? a->x_stride : 0;
    static const float opaque = 1.0f; /* alpha of a source without one (ax = 0) */
    const double scale = exp2((double)d.exposure_ev); /* 1 exactly for 0 EV */
    if (d.op == VT_TONEMAP_ACES) pthread_once(&aces_once, aces_init);
    float lk[3] = {0, 0, 0};
    if (d.lut) vt_lut_scale(d.lut, lk);
#ifdef __SSE2__
    const bool rgbx = d.op == VT_TONEMAP_ACES && !d.lut && !a && rx == 4 && gx == 4 && bx == 4 &&
                      g->data == r->data + 1 && b->data == r->data + 2 && g->y_stride == r->y_stride &&
                      b->y_stride == r->y_stride;
#endif
    for (uint32_t y = 0; y < height; y++) {
        const float *pr = r->data + (ptrdiff_t)y * r->y_stride;
#ifdef __SSE2__
        if (rgbx) {
            /* the lanes up to the last pixel (whose fourth float may be
               past the buffer), the SSE2 row for the rest */
            uint32_t n = aces_lanes ? (width - 1) / 8 * 8 : 0;
            uint8_t *o = out + (size_t)y * out_stride_bytes;
            if (y + 1 < height) {
                /* the next row's first KiB asked for now: the daemon's
                   rows go down in memory (bottom-up picture, top row
                   first), and each row began with misses to memory
                   before the hardware's prefetch caught up (the lanes
                   prefetch ahead within a row) */
                const char *nx = (const char *)(r->data + (ptrdiff_t)(y + 1) * r->y_stride);
                for (int k = 0; k < 16; k++) __builtin_prefetch(nx + 64 * k);
            }
            if (n) aces_lanes(pr, n, scale, aces_tab, o);
            aces_row_rgbx(pr + 4 * (size_t)n, width - n, scale, o + 4 * (size_t)n);
            continue;
        }
#endif
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
            if (d.lut) {
                float e[3];
                double v[3] = {(double)pr[i * rx] * k, (double)pg[i * gx] * k, (double)pb[i * bx] * k};
                for (int c = 0; c < 3; c++)
                    e[c] = d.op == VT_TONEMAP_ACES ? aces_encoded((float)v[c])
                                                   : srgb_encoded(tonemap_curve(d.op, v[c]));
                vt_lut_sample(d.lut, lk, e, e);
                o[0] = code_of(e[0]);
                o[1] = code_of(e[1]);
                o[2] = code_of(e[2]);
            } else if (d.op == VT_TONEMAP_ACES) {
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
