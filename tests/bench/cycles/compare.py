#!/usr/bin/env python3
"""compare.py — the Cycles comparison's numbers and pictures, numpy only.

  compare.py DIR...        each DIR holds vantage.npy and cycles.npy (linear
                           RGB, exposed, rows top-down, from cycles_render.py);
                           prints one table row per DIR and writes
                           DIR/side_by_side.png: vantage | cycles | difference
  compare.py --self-check  the SSIM against independent references (below)

Per scene:
  * SSIM (Wang, Bovik, Sheikh, Simoncelli, "Image quality assessment: from
    error visibility to structural similarity", IEEE TIP 13(4), 2004): an
    11x11 Gaussian window, sigma 1.5, normalised; K1 0.01, K2 0.03, L 1;
    statistics over the 'valid' windows (as the authors' ssim.m does with
    filter2 'valid'); the mean of the map. It is taken on the luma of the
    displayed pictures: both linear frames through the daemon's tone map
    (Narkowicz's ACES fit, input capped at 16, render/vt_tonemap.c) and the
    sRGB OETF, then Y' = 0.2126 R' + 0.7152 G' + 0.0722 B'. ssim.m's
    automatic downsampling (by round(min(H, W) / 256)) is 1 at 480x270 and
    is not applied at any size here: the window is in pixels of these frames.
  * the noise ceiling: SSIM of Cycles against Cycles with another seed
    (cycles_b.npy), the best a noise-free renderer could score against it;
  * MAD: the mean absolute difference of linear luminance (Rec. 709
    weights), and the same over the mean of Cycles' luminance (relative);
    mean luminance of each (their ratio says which way the frame is off).
FLIP is not computed: a faithful implementation (CSF filtering in YyCxCz,
the Hunt-adjusted L*a*b*, HyAB distance, feature detection) is a project of
its own; SSIM is the one perceptual figure.
"""
import os
import struct
import sys
import zlib

import numpy as np

K1, K2, L = 0.01, 0.03, 1.0
C1, C2 = (K1 * L) ** 2, (K2 * L) ** 2


def gauss_window(size=11, sigma=1.5):
    x = np.arange(size) - (size - 1) / 2
    g = np.exp(-x * x / (2 * sigma * sigma))
    return g / g.sum()


def _filt_valid(img, g):
    """separable 'valid' correlation with the 1-D window g (symmetric)"""
    n = len(g)
    h, w = img.shape
    t = sum(g[k] * img[:, k:w - n + 1 + k] for k in range(n))
    return sum(g[k] * t[k:h - n + 1 + k, :] for k in range(n))


def ssim_map(a, b):
    """a, b: 2-D float64 in [0, L]; the SSIM map over the valid windows"""
    g = gauss_window()
    a, b = a.astype(np.float64), b.astype(np.float64)
    mu_a, mu_b = _filt_valid(a, g), _filt_valid(b, g)
    saa = _filt_valid(a * a, g) - mu_a * mu_a
    sbb = _filt_valid(b * b, g) - mu_b * mu_b
    sab = _filt_valid(a * b, g) - mu_a * mu_b
    return ((2 * mu_a * mu_b + C1) * (2 * sab + C2)) / ((mu_a ** 2 + mu_b ** 2 + C1) * (saa + sbb + C2))


def ssim(a, b):
    return float(ssim_map(a, b).mean())


def ssim_slow(a, b):
    """the definition, window by window, two-pass statistics: its own 2-D
    window (the paper's 11x11, sigma 1.5, written out here), independent of
    gauss_window, the separable filter and E[x^2] - E[x]^2"""
    yy, xx = np.mgrid[-5:6, -5:6]
    w2 = np.exp(-(xx * xx + yy * yy) / (2 * 1.5 * 1.5))
    w2 /= w2.sum()
    h, w = a.shape
    tot, n = 0.0, 0
    for y in range(h - 10):
        for x in range(w - 10):
            pa, pb = a[y:y + 11, x:x + 11], b[y:y + 11, x:x + 11]
            ma, mb = (w2 * pa).sum(), (w2 * pb).sum()
            va, vb = (w2 * (pa - ma) ** 2).sum(), (w2 * (pb - mb) ** 2).sum()
            cab = (w2 * (pa - ma) * (pb - mb)).sum()
            tot += ((2 * ma * mb + C1) * (2 * cab + C2)) / ((ma * ma + mb * mb + C1) * (va + vb + C2))
            n += 1
    return tot / n


def aces(x):
    """render/vt_tonemap.c's ACES curve (per channel, exposure already applied)"""
    x = np.clip(np.nan_to_num(x, nan=0.0), 0, 16.0)
    return np.minimum((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), 1.0)


def srgb(x):
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(np.maximum(x, 0.0031308), 1 / 2.4) - 0.055)


def display(rgb):
    return srgb(aces(rgb))


def luma(rgb):
    return rgb[..., 0] * 0.2126 + rgb[..., 1] * 0.7152 + rgb[..., 2] * 0.0722


def write_png(path, rgb):
    """rgb: HxWx3 float in [0, 1] -> 8-bit PNG"""
    h, w, _ = rgb.shape
    px = (np.clip(rgb, 0, 1) * 255 + 0.5).astype(np.uint8)
    raw = b"".join(b"\0" + px[y].tobytes() for y in range(h))

    def chunk(t, d):
        return struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d) & 0xffffffff)
    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)) +
                chunk(b"IDAT", zlib.compress(raw, 6)) + chunk(b"IEND", b""))


def heat(d):
    """0..1 -> black, red, yellow, white"""
    d = np.clip(d, 0, 1)[..., None]
    return np.clip(np.concatenate([3 * d, 3 * d - 1, 3 * d - 2], -1), 0, 1)


def compare(dirname):
    v = np.load(os.path.join(dirname, "vantage.npy")).astype(np.float64)
    c = np.load(os.path.join(dirname, "cycles.npy")).astype(np.float64)
    if v.shape != c.shape:
        sys.exit("compare.py: %s: vantage %s and cycles %s differ in size" % (dirname, v.shape, c.shape))
    dv, dc = display(v), display(c)
    s = ssim(luma(dv), luma(dc))
    yv, yc = luma(v), luma(c)
    mad = float(np.abs(yv - yc).mean())
    row = {"scene": os.path.basename(os.path.normpath(dirname)), "ssim": s, "mad": mad,
           "rel": mad / max(float(yc.mean()), 1e-12), "mean_v": float(yv.mean()), "mean_c": float(yc.mean())}
    second = os.path.join(dirname, "cycles_b.npy")
    if os.path.exists(second):  # Cycles against itself with another seed: the noise's ceiling on SSIM
        row["ceiling"] = ssim(luma(dc), luma(display(np.load(second).astype(np.float64))))
    png = os.path.join(dirname, "vantage_png.npy")
    if os.path.exists(png):  # this tone map against the CLI's own PNG of the same frame
        row["png_codes"] = int(np.abs(np.round(dv * 255) - np.round(np.load(png) * 255)).max())
    # the difference panel: |display luma| x 4 (a quarter of full scale is white)
    gap = np.full((v.shape[0], 4, 3), 1.0)
    side = np.concatenate([dv, gap, dc, gap, heat(4 * np.abs(luma(dv) - luma(dc)))], 1)
    write_png(os.path.join(dirname, "side_by_side.png"), side)
    return row


def self_check():
    rng = np.random.default_rng(20)
    ok = True

    def check(name, got, want, tol):
        nonlocal ok
        good = abs(got - want) <= tol
        ok &= good
        print("  %-58s %.12f (want %.12f +- %g) %s" % (name, got, want, tol, "ok" if good else "FAIL"))

    a = rng.random((40, 52))
    check("SSIM(x, x)", ssim(a, a), 1.0, 1e-12)
    # constant images p and q: variances and covariance vanish, so
    # SSIM = (2pq + C1) / (p^2 + q^2 + C1) exactly
    p, q = 0.3, 0.7
    check("SSIM of constants 0.3, 0.7 (closed form)", ssim(np.full((20, 20), p), np.full((20, 20), q)),
          (2 * p * q + C1) / (p * p + q * q + C1), 1e-12)
    # noisy, blurred and inverted copies against the slow definition
    for name, b in (("noise sigma 0.05", np.clip(a + rng.normal(0, 0.05, a.shape), 0, 1)),
                    ("noise sigma 0.2", np.clip(a + rng.normal(0, 0.2, a.shape), 0, 1)),
                    ("blurred + offset", 0.8 * _pad_blur(a) + 0.1),
                    ("inverted", 1 - a)):
        check("SSIM %s vs the window-by-window definition" % name, ssim(a, b), ssim_slow(a, b), 1e-10)
    check("symmetry", ssim(a, 1 - a), ssim(1 - a, a), 1e-12)
    # the tone map's end points and the sRGB knee
    check("display(0)", float(display(np.zeros(1))[0]), 0.0, 0)
    check("display(16) (the ACES cap, 1.018 clamped)", float(display(np.full(1, 16.0))[0]), 1.0, 1e-12)
    print("self-check:", "ok" if ok else "FAILED")
    return 0 if ok else 1


def _pad_blur(a):
    b = a.copy()
    b[1:-1, 1:-1] = (a[:-2, 1:-1] + a[2:, 1:-1] + a[1:-1, :-2] + a[1:-1, 2:] + a[1:-1, 1:-1]) / 5
    return b


def main():
    if sys.argv[1:] == ["--self-check"]:
        return self_check()
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    rows = [compare(d) for d in sys.argv[1:]]
    print("| scene | SSIM vantage/Cycles | SSIM Cycles/Cycles (2 seeds) | MAD linear Y | MAD / mean Y(Cycles) "
          "| mean Y vantage | mean Y Cycles | tone map vs CLI PNG |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        print("| %s | %.4f | %s | %.4f | %.1f %% | %.4f | %.4f | %s |" % (
            r["scene"], r["ssim"], "%.4f" % r["ceiling"] if "ceiling" in r else "-", r["mad"], 100 * r["rel"],
            r["mean_v"], r["mean_c"],
            "max %d codes" % r["png_codes"] if "png_codes" in r else "-"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
