#!/usr/bin/env python3
"""Reference PSNR and SSIM values for spibench's metrics module (src/metrics).

How to rerun (from the repository root; nothing runs this automatically, and the Rust test
suite only reads its output):

    pip install numpy scikit-image
    python3 validation/metrics/make_reference.py

It rewrites, in validation/metrics/:
  - <case>_truth.npy / <case>_test.npy: small image pairs (uint8, float32 or float64), made
    from scenes/images/*.png by exact area-average resizing to 48x48, 96x96, 128x128 (and one
    non-square 48x80) and deterministic distortions (seeded noise, Gaussian blur, gain and
    offset, quantisation, inversion), plus edge cases (uniform vs uniform, identical images,
    the smallest 11x11 images);
  - reference.json: for each pair, PSNR (data_range 255) and SSIM from scikit-image with
    structural_similarity(..., gaussian_weights=True, sigma=1.5, use_sample_covariance=False,
    data_range=255), which is Wang et al. (2004): 11x11 Gaussian window (truncate 3.5 gives
    radius int(3.5*1.5 + 0.5) = 5), K1 = 0.01, K2 = 0.03, population (biased) variances;
    plus the versions of Python, numpy, scipy and scikit-image.

Both images are converted to float64 before scoring: scikit-image keeps float32 inputs in
float32, which would limit the reference to ~1e-7.

skimage vs Wang's 'valid' map: skimage filters the whole image (mode 'reflect') and then
averages the SSIM map over the image cropped by (win_size - 1)/2 = 5 pixels on every side.
At a pixel at least 5 pixels from every border the 11x11 window lies entirely inside the
image, so the reflected border values never enter, and the cropped map is exactly Wang's
filter2(..., 'valid') map of (H-10) x (W-10) pixels. This script checks it: it recomputes
the valid-map mean independently (a direct 2-D window sum in numpy) and stores the largest
difference as "max_abs_skimage_minus_valid_map" (round-off only, ~1e-16).

PSNR of identical images is +inf, stored as null.
"""

import json
import platform
import sys
from pathlib import Path

import numpy as np
import scipy
import scipy.ndimage
import skimage
from skimage.io import imread
from skimage.metrics import peak_signal_noise_ratio, structural_similarity

HERE = Path(__file__).resolve().parent
IMAGES = HERE.parent.parent / "scenes" / "images"


def area_resize(img, height, width):
    """Exact area-average (box) resampling, as src/objects/image_file.rs::resize_area."""

    def weights(src, dst):
        m = np.zeros((dst, src))
        for j in range(dst):
            lo, hi = j * src, (j + 1) * src  # units of 1/dst source pixel
            for k in range(lo // dst, -(-hi // dst)):
                ov = min(hi, (k + 1) * dst) - max(lo, k * dst)
                if ov > 0:
                    m[j, k] = ov / src
        return m

    img = np.asarray(img, dtype=np.float64)
    return weights(img.shape[0], height) @ img @ weights(img.shape[1], width).T


def load(name, height, width):
    img = imread(IMAGES / f"{name}.png")
    assert img.dtype == np.uint8 and img.ndim == 2, (name, img.dtype, img.shape)
    return area_resize(img, height, width)


def to_u8(a):
    return np.clip(np.rint(a), 0, 255).astype(np.uint8)


def wang_valid_mssim(x, y):
    """Wang et al. 2004 by a direct 2-D 'valid' window sum (independent of skimage)."""
    x = x.astype(np.float64)
    y = y.astype(np.float64)
    i = np.arange(11) - 5
    w = np.exp(-(i[:, None] ** 2 + i[None, :] ** 2) / (2 * 1.5**2))
    w /= w.sum()

    def filt(a):
        h, wd = a.shape
        out = np.zeros((h - 10, wd - 10))
        for dr in range(11):
            for dc in range(11):
                out += w[dr, dc] * a[dr : dr + h - 10, dc : dc + wd - 10]
        return out

    c1, c2 = (0.01 * 255) ** 2, (0.03 * 255) ** 2
    mx, my = filt(x), filt(y)
    sxx = filt(x * x) - mx * mx
    syy = filt(y * y) - my * my
    sxy = filt(x * y) - mx * my
    s = ((2 * mx * my + c1) * (2 * sxy + c2)) / ((mx**2 + my**2 + c1) * (sxx + syy + c2))
    return float(s.mean())


def cases():
    rng = np.random.default_rng(20220524)  # fixed seed: the files are reproducible
    out = []

    t = to_u8(load("astronaut", 48, 48))
    out.append(("astronaut48_noise", t, to_u8(t + rng.normal(0.0, 12.0, t.shape))))
    out.append(("astronaut48_identical", t, t.copy()))

    t = to_u8(load("coffee", 96, 96))
    blurred = scipy.ndimage.gaussian_filter(t.astype(np.float64), 1.2, mode="reflect")
    out.append(("coffee96_blur", t, blurred.astype(np.float32)))

    t = to_u8(load("chelsea", 128, 128))
    out.append(("chelsea128_gain_offset", t, to_u8(0.8 * t.astype(np.float64) + 30.0)))

    t = to_u8(load("rocket", 128, 128))
    y = scipy.ndimage.gaussian_filter(t.astype(np.float64), 0.8, mode="reflect")
    y += rng.normal(0.0, 5.0, t.shape)
    out.append(("rocket128_blur_noise", t, y.astype(np.float32)))

    t = to_u8(load("hubble_deep_field", 96, 96))
    out.append(("hubble96_quantised", t, to_u8(np.floor(t / 32.0) * 32.0 + 16.0)))

    t = to_u8(load("hubble_deep_field", 48, 48))
    out.append(("hubble48_inverted", t, 255.0 - t.astype(np.float64) + rng.normal(0, 3, t.shape)))

    t = to_u8(load("coffee", 48, 80))
    y = t.astype(np.float64) + 20.0 + rng.normal(0.0, 8.0, t.shape)
    out.append(("coffee48x80_offset_noise", t, y.astype(np.float32)))

    out.append(
        (
            "uniform32",
            np.full((32, 32), 100, np.uint8),
            np.full((32, 32), 140, np.uint8),
        )
    )

    out.append(("random11", rng.uniform(0, 255, (11, 11)), rng.uniform(0, 255, (11, 11))))
    return out


def main():
    records = []
    worst = 0.0
    for name, truth, test in cases():
        tf, sf = f"{name}_truth.npy", f"{name}_test.npy"
        np.save(HERE / tf, truth)
        if name == "astronaut48_identical":
            sf = tf  # the same file on both sides
        else:
            np.save(HERE / sf, test)
        x = truth.astype(np.float64)
        y = test.astype(np.float64)
        ssim = structural_similarity(
            x,
            y,
            gaussian_weights=True,
            sigma=1.5,
            use_sample_covariance=False,
            data_range=255,
        )
        valid = wang_valid_mssim(x, y)
        worst = max(worst, abs(ssim - valid))
        assert abs(ssim - valid) < 1e-12, (name, ssim, valid)
        with np.errstate(divide="ignore"):
            psnr = peak_signal_noise_ratio(x, y, data_range=255)
        records.append(
            {
                "name": name,
                "truth": tf,
                "test": sf,
                "shape": list(truth.shape),
                "dtypes": [str(truth.dtype), str(test.dtype)],
                "psnr_db": None if np.isinf(psnr) else float(psnr),
                "ssim": float(ssim),
            }
        )
        print(f"{name:28s} PSNR {psnr:10.6f} dB  SSIM {ssim:.12f}")
    doc = {
        "generator": "validation/metrics/make_reference.py",
        "python": platform.python_version(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "scikit-image": skimage.__version__,
        "ssim_call": "structural_similarity(truth.astype(float64), test.astype(float64), "
        "gaussian_weights=True, sigma=1.5, use_sample_covariance=False, data_range=255)",
        "psnr_call": "peak_signal_noise_ratio(truth.astype(float64), test.astype(float64), "
        "data_range=255); null means +inf (identical images)",
        "max_abs_skimage_minus_valid_map": worst,
        "cases": records,
    }
    with open(HERE / "reference.json", "w") as f:
        json.dump(doc, f, indent=1)
        f.write("\n")
    print(f"max |skimage - valid-map mean| = {worst:.3e}", file=sys.stderr)


if __name__ == "__main__":
    main()
