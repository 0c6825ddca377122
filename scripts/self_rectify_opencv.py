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
With "e2e": [{"name", "left", "right"[, "eval_left", "eval_right", "orb_features", "orb_levels"]}] also an end-to-end timing from
the image files (ORB + BFMatcher + the above + warps), output under "e2e".
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
    out["e2e"] = {e["name"]: e2e(e, thr, runs) for e in cfg.get("e2e", [])}
    json.dump(out, sys.stdout)


def e2e(e, thr, runs):
    """End to end from image files: ORB (4000) + BFMatcher Hamming (Lowe 0.8 + cross check as
    laparo's matcher) + findFundamentalMat + stereoRectifyUncalibrated + warps; min / median ms."""
    left, right = cv2.imread(e["left"], cv2.IMREAD_COLOR), cv2.imread(e["right"], cv2.IMREAD_COLOR)
    h, w = left.shape[:2]
    orb = cv2.ORB_create(nfeatures=e.get("orb_features", 4000), nlevels=e.get("orb_levels", 8))
    bf = cv2.BFMatcher(cv2.NORM_HAMMING)

    def matches():
        gl, gr = cv2.cvtColor(left, cv2.COLOR_BGR2GRAY), cv2.cvtColor(right, cv2.COLOR_BGR2GRAY)
        kl, dl = orb.detectAndCompute(gl, None)
        kr, dr = orb.detectAndCompute(gr, None)
        fw = bf.knnMatch(dl, dr, k=2)
        bw = {m[0].queryIdx: m[0].trainIdx for m in bf.knnMatch(dr, dl, k=1) if m}
        good = [m[0] for m in fw if len(m) == 2 and m[0].distance < 0.8 * m[1].distance and bw.get(m[0].trainIdx) == m[0].queryIdx]
        pl = np.float64([kl[m.queryIdx].pt for m in good])
        pr = np.float64([kr[m.trainIdx].pt for m in good])
        return pl, pr

    def fit(pl, pr):
        F, mask = cv2.findFundamentalMat(pl, pr, cv2.FM_RANSAC, thr, 0.999, 5000)
        inl = mask.ravel().astype(bool)
        ok, h1, h2 = cv2.stereoRectifyUncalibrated(pl[inl], pr[inl], F, (w, h))
        return inl, ok, h1, h2

    tm, tf, tw = [], [], []
    cpu0 = time.process_time()
    for _ in range(max(runs, 5)):
        t = time.perf_counter()
        pl, pr = matches()
        tm.append(1e3 * (time.perf_counter() - t))
        t = time.perf_counter()
        inl, ok, h1, h2 = fit(pl, pr)
        tf.append(1e3 * (time.perf_counter() - t))
        t = time.perf_counter()
        cv2.warpPerspective(left, h1, (w, h), flags=cv2.INTER_LINEAR)
        cv2.warpPerspective(right, h2, (w, h), flags=cv2.INTER_LINEAR)
        tw.append(1e3 * (time.perf_counter() - t))
    cpu_per_pair = 1e3 * (time.process_time() - cpu0) / max(runs, 5)
    tot = [a + b + c for a, b, c in zip(tm, tf, tw)]
    o = {"n_matches": int(len(pl)), "n_inliers": int(inl.sum()), "ok": bool(ok),
         "ms_matches_min": float(min(tm)), "ms_matches_median": float(np.median(tm)),
         "ms_fit_min": float(min(tf)), "ms_warps_min": float(min(tw)),
         "ms_matches_fit_min": float(min(a + b for a, b in zip(tm, tf))),
         "ms_total_min": float(min(tot)), "ms_total_median": float(np.median(tot)),
         "cpu_ms_total_per_pair": float(cpu_per_pair)}
    if ok and "eval_left" in e:
        el, er = np.array(e["eval_left"], float), np.array(e["eval_right"], float)
        o["exact_dy_rectified"] = stats(apply_h(h2, er)[:, 1] - apply_h(h1, el)[:, 1])
    return o


if __name__ == "__main__":
    main()
