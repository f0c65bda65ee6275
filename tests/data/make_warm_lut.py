#!/usr/bin/env python3
"""Writes tests/data/warm.cube: a mild warm grade as a 9^3 .cube LUT (Adobe's
format; its input and output are display values, sRGB-encoded 0..1), the
LUT shipped as an example of `vantaged --lut` and read by
tests/test_post.c.

The grade: a warm white balance (red x1.05, blue x0.90 in linear light,
renormalised so white stays white's luminance), then a gentle S-curve on
the encoded values (contrast 1.08 about mid grey 0.5), clamped to 0..1.
Smooth and monotone: slopes between nodes stay near 1, so trilinear
interpolation at 9 nodes is within a code of the exact function.

Run: python3 tests/data/make_warm_lut.py > tests/data/warm.cube
"""
N = 9

def dec(v):  # sRGB EOTF
    return v / 12.92 if v <= 0.04045 else ((v + 0.055) / 1.055) ** 2.4

def enc(v):  # sRGB OETF
    v = min(max(v, 0.0), 1.0)
    return 12.92 * v if v <= 0.0031308 else 1.055 * v ** (1 / 2.4) - 0.055

GAIN = (1.05, 1.0, 0.90)
Y = 0.2126 * GAIN[0] + 0.7152 * GAIN[1] + 0.0722 * GAIN[2]

def grade(r, g, b):
    out = []
    for c, k in zip((r, g, b), GAIN):
        e = enc(dec(c) * k / Y)
        e = 0.5 + (e - 0.5) * 1.08
        out.append(min(max(e, 0.0), 1.0))
    return out

print('# a mild warm grade for vantaged --lut (tests/data/make_warm_lut.py)')
print('TITLE "Vantage warm"')
print('LUT_3D_SIZE %d' % N)
print('DOMAIN_MIN 0 0 0')
print('DOMAIN_MAX 1 1 1')
for b in range(N):
    for g in range(N):
        for r in range(N):  # red fastest
            o = grade(r / (N - 1), g / (N - 1), b / (N - 1))
            print('%.6f %.6f %.6f' % tuple(o))
