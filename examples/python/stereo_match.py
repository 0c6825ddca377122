"""Semi-global stereo matching of a raw pair (thesis §3.3), optionally self-rectified.

    python examples/python/stereo_match.py [LEFT.npy RIGHT.npy --range -48:0] [--self-rectify]

Without image arguments it builds a textured pair whose right view is the left shifted by a
smooth disparity of 6–12 px, matches it and reports the error against the known disparity.
"""
import argparse

import numpy as np

import laparo


def demo_pair(w=320, h=240, seed=0):
    rng = np.random.default_rng(seed)
    big = np.kron(rng.random((h // 2 + 2, w // 2 + 40)), np.ones((2, 2)))
    big = (30 + 200 * big).astype(np.float64)
    yy, xx = np.mgrid[0:h, 0:w].astype(float)
    d = 6.0 + 6.0 * xx / w                        # left x ↔ right x − d
    left = big[:h, 20:20 + w]
    # right(x, y) = left(x + d(x + d)) ≈ sample the big texture at x + 20 + d, linear interpolation
    xs = xx + 20 + 6.0 + 6.0 * (xx + 9.0) / w
    x0 = np.floor(xs).astype(int)
    t = xs - x0
    right = (1 - t) * big[:h][yy.astype(int), x0] + t * big[:h][yy.astype(int), x0 + 1]
    return left.astype(np.uint8), right.clip(0, 255).astype(np.uint8), d


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("images", nargs="*")
    ap.add_argument("--range", default="0:24")
    ap.add_argument("--self-rectify", action="store_true")
    a = ap.parse_args()
    lo, hi = (int(v) for v in a.range.split(":"))
    if a.images:
        left, right, truth = np.load(a.images[0]), np.load(a.images[1]), None
    else:
        left, right, truth = demo_pair()
    r = laparo.stereo.match(left, right, lo, hi, mode="accurate", self_rectify=a.self_rectify)
    d = r["disparity"]
    ok = np.isfinite(d)
    print(f"{ok.mean() * 100:.1f} % valid; disparity p1/p50/p99 = {np.percentile(d[ok], [1, 50, 99]).round(2)} px")
    print(f"counts: {r['stats']}")
    if truth is not None:
        err = np.abs(d[ok] - truth[ok])
        print(f"error against the known disparity: median {np.median(err):.3f} px, {100 * (err > 1).mean():.2f} % > 1 px")
    if a.self_rectify:
        info = r["rectification"]
        print(f"self-rectification: {info['n_inliers']} inliers, median |dy| {info['dy_raw']['median_abs']:.2f} → "
              f"{info['dy_rectified']['median_abs']:.2f} px")


if __name__ == "__main__":
    main()
