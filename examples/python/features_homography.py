"""SIFT (or ORB) matching of two images and a robust homography (thesis §4.2, §4.5).

    python examples/python/features_homography.py [IMAGE1.npy IMAGE2.npy] [--detector orb]

Without image arguments it builds a texture and a copy rotated by 10° and scaled by 1.1 (a known
homography), matches them, estimates H by RANSAC and scores the matches against the truth with
the two-way transfer error of §4.5.1.
"""
import argparse

import numpy as np

import laparo


def demo_pair(w=320, h=240):
    yy, xx = np.mgrid[0:h, 0:w].astype(float)
    a, s = np.radians(10.0), 1.1
    c = np.array([(w - 1) / 2, (h - 1) / 2])
    # H maps image 1 → image 2: similarity about the centre.
    hm = np.array([[s * np.cos(a), -s * np.sin(a), 0], [s * np.sin(a), s * np.cos(a), 0], [0, 0, 1.0]])
    t = np.eye(3)
    t[:2, 2] = c
    ti = np.eye(3)
    ti[:2, 2] = -c
    h_true = t @ hm @ ti

    rng = np.random.default_rng(0)
    grids = [(rng.random((h // c + 3, w // c + 3)), c) for c in (4, 9, 23)]   # random blobs at 3 scales

    def tex(x, y):
        """Sum of bilinearly interpolated random grids (a continuous, non-repeating texture)."""
        out = np.zeros_like(x)
        for g, c in grids:
            u, v = np.clip(x / c + 1, 0, g.shape[1] - 2), np.clip(y / c + 1, 0, g.shape[0] - 2)
            i, j = np.floor(u).astype(int), np.floor(v).astype(int)
            a, b = u - i, v - j
            out += (1 - b) * ((1 - a) * g[j, i] + a * g[j, i + 1]) + b * ((1 - a) * g[j + 1, i] + a * g[j + 1, i + 1])
        return 255 * out / len(grids)

    img1 = tex(xx, yy)
    q = np.stack([xx, yy, np.ones_like(xx)], -1) @ np.linalg.inv(h_true).T  # image 2 pixel → image 1
    img2 = tex(q[..., 0] / q[..., 2], q[..., 1] / q[..., 2])
    return img1.clip(0, 255).astype(np.uint8), img2.clip(0, 255).astype(np.uint8), h_true


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("images", nargs="*")
    ap.add_argument("--detector", default="sift")
    a = ap.parse_args()
    if a.images:
        img1, img2, h_true = np.load(a.images[0]), np.load(a.images[1]), None
    else:
        img1, img2, h_true = demo_pair()
    m = laparo.features.match_images(img1, img2, detector=a.detector, homography=h_true)
    print(f"{m['n_keypoints1']} / {m['n_keypoints2']} keypoints, {m['n_matches']} matches")
    if h_true is not None:
        print(f"correct matches (two-way transfer error < 3 px): {m['n_correct']} (precision {m['precision']:.3f})")
    fit = laparo.features.find_homography(m["points1"], m["points2"], threshold_px=2.0, seed=0)
    print(f"RANSAC homography: {fit['n_inliers']} inliers in {fit['iterations']} hypotheses, RMS {fit['rms_px']:.3f} px")
    h = fit["model"] / fit["model"][2, 2]
    print(np.array2string(h, precision=5))
    if h_true is not None:
        corners = np.array([[0, 0], [319, 0], [0, 239], [319, 239]], float)
        pe = np.c_[corners, np.ones(4)] @ h.T
        pt = np.c_[corners, np.ones(4)] @ h_true.T
        err = np.linalg.norm(pe[:, :2] / pe[:, 2:] - pt[:, :2] / pt[:, 2:], axis=1)
        print(f"corner error of the estimate against the true H: max {err.max():.3f} px")


if __name__ == "__main__":
    main()
