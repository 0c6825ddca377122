#!/usr/bin/env python3
"""OpenCV peer of laparo's self-rectification (issue 14 item 3): cv2.findFundamentalMat (RANSAC)
+ cv2.stereoRectifyUncalibrated (Hartley 1999) on the same matches, then the |dy| of exact
correspondences after rectification, the largest image-corner shift, and timings.

Input: a JSON file written by `laparo-bench geo --peer-python ...`:
  {"width": W, "height": H, "fit_left": [[x, y], ...], "fit_right": [...],
   "eval_left": [...], "eval_right": [...], "threshold_px": 1.0, "runs": 5, "threads": 2}
Output (stdout): JSON with "opencv", "n_inliers", "dy_raw", "dy_rectified" (median/p95/max of
|dy|), "max_corner_shift_px", "ms_fit_min", "ms_fit_median", "ms_fit_warp_min" (F + rectify +
warpPerspective of two RGB images of the given size).
Needs numpy and opencv-python-headless; not a test dependency.
"""
import json
import sys
import time

import cv2
import numpy as np


def stats(dy):
    a = np.abs(np.asarray(dy, float))
    return {"n": int(a.size), "median_abs": float(np.median(a)), "p95_abs": float(np.percentile(a, 95)),
            "max_abs": float(a.max())}


def apply_h(h, p):
    q = np.c_[p, np.ones(len(p))] @ h.T
    return q[:, :2] / q[:, 2:3]


def main():
    cfg = json.load(open(sys.argv[1]))
    w, h = cfg["width"], cfg["height"]
    fl, fr = np.array(cfg["fit_left"], np.float64), np.array(cfg["fit_right"], np.float64)
    el, er = np.array(cfg["eval_left"], np.float64), np.array(cfg["eval_right"], np.float64)
    thr = cfg.get("threshold_px", 1.0)
    cv2.setNumThreads(cfg.get("threads", 2))

    def fit():
        F, mask = cv2.findFundamentalMat(fl, fr, cv2.FM_RANSAC, thr, 0.999, 5000)
        inl = mask.ravel().astype(bool)
        ok, h1, h2 = cv2.stereoRectifyUncalibrated(fl[inl], fr[inl], F, (w, h))
        return F, inl, ok, h1, h2

    F, inl, ok, h1, h2 = fit()
    out = {"opencv": cv2.__version__, "ok": bool(ok), "n_inliers": int(inl.sum()), "n_matches": len(fl)}
    if ok:
        out["dy_raw"] = stats(er[:, 1] - el[:, 1])
        out["dy_rectified"] = stats(apply_h(h2, er)[:, 1] - apply_h(h1, el)[:, 1])
        corners = np.array([[0, 0], [w - 1, 0], [0, h - 1], [w - 1, h - 1]], float)
        out["max_corner_shift_px"] = float(max(np.linalg.norm(apply_h(m, corners) - corners, axis=1).max()
                                               for m in (h1, h2)))
    runs = cfg.get("runs", 5)
    ts = []
    for _ in range(runs):
        t = time.perf_counter()
        fit()
        ts.append(1e3 * (time.perf_counter() - t))
    out["ms_fit_min"], out["ms_fit_median"] = float(min(ts)), float(np.median(ts))
    rng = np.random.default_rng(0)
    img = rng.integers(0, 255, (h, w, 3), dtype=np.uint8)
    tw = []
    for _ in range(runs):
        t = time.perf_counter()
        F, inl, ok, a, b = fit()
        cv2.warpPerspective(img, a, (w, h), flags=cv2.INTER_LINEAR)
        cv2.warpPerspective(img, b, (w, h), flags=cv2.INTER_LINEAR)
        tw.append(1e3 * (time.perf_counter() - t))
    out["ms_fit_warp_min"] = float(min(tw))
    json.dump(out, sys.stdout)


if __name__ == "__main__":
    main()
