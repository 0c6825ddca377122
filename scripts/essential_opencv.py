#!/usr/bin/env python3
"""OpenCV peer for laparo's essential-matrix RANSAC (issue 11; not run in CI).

Usage: essential_opencv.py INPUT.json   (written by `laparo-bench geo --peer-python PY`)

INPUT holds the synthetic correspondences in px (p1, p2), the true-inlier flags, focal and
principal point, the threshold (px), the true (R, t) and laparo's (R, t, inlier mask). Runs
cv2.findEssentialMat (RANSAC, prob 0.999, same threshold) + cv2.recoverPose on the same points,
times findEssentialMat (min / median of `runs` after one warm-up) and prints JSON: OpenCV's
inlier recall, rotation / translation-direction errors to the truth, and its agreement with
laparo (angle between the two rotations and translations, inlier-mask agreement); the same for
cv2.USAC_ACCURATE and cv2.USAC_MAGSAC (with local optimisation) for reference.
"""
import json
import sys
import time

import cv2
import numpy as np


def rot_err_deg(a, b):
    c = (np.trace(a.T @ b) - 1.0) / 2.0
    return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))


def dir_err_deg(a, b):
    a = np.asarray(a, float).ravel()
    b = np.asarray(b, float).ravel()
    c = a @ b / (np.linalg.norm(a) * np.linalg.norm(b))
    return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))


def main():
    d = json.load(open(sys.argv[1]))
    cv2.setNumThreads(int(d.get("threads", 1)))
    p1 = np.asarray(d["p1"], np.float64)
    p2 = np.asarray(d["p2"], np.float64)
    f = float(d["focal"])
    cx, cy = d["pp"]
    k = np.array([[f, 0, cx], [0, f, cy], [0, 0, 1]], np.float64)
    thr = float(d["threshold_px"])
    ok = np.asarray(d["true_inlier"], bool)

    def fit():
        return cv2.findEssentialMat(p1, p2, k, method=cv2.RANSAC, prob=0.999, threshold=thr)

    fit()
    ts = []
    for _ in range(max(1, int(d.get("runs", 10)))):
        t0 = time.perf_counter()
        e, mask = fit()
        ts.append((time.perf_counter() - t0) * 1e3)
    e, mask = fit()
    if e.shape[0] > 3:  # several stacked solutions: OpenCV returns them all; take the first
        e = e[:3]
    n_in, r, t, pmask = cv2.recoverPose(e, p1, p2, k, mask=mask.copy())
    inl = mask.ravel() > 0
    r_true = np.asarray(d["r_true"])
    t_true = np.asarray(d["t_true"])
    out = {
        "opencv_version": cv2.__version__,
        "ms_min": float(min(ts)),
        "ms_median": float(np.median(ts)),
        "n_inliers": int(inl.sum()),
        "inlier_recall": float((inl & ok).sum() / ok.sum()),
        "rotation_error_deg": rot_err_deg(r, r_true),
        "translation_error_deg": dir_err_deg(t, t_true),
        "recover_pose_in_front": int(n_in),
    }
    # USAC with local optimisation (closer to laparo's LO-RANSAC), for reference
    for name, method in (("usac_accurate", cv2.USAC_ACCURATE), ("usac_magsac", cv2.USAC_MAGSAC)):
        ts = []
        for _ in range(max(1, int(d.get("runs", 10)))):
            t0 = time.perf_counter()
            eu, mu = cv2.findEssentialMat(p1, p2, k, method=method, prob=0.999, threshold=thr)
            ts.append((time.perf_counter() - t0) * 1e3)
        _, ru, tu, _ = cv2.recoverPose(eu[:3], p1, p2, k, mask=mu.copy())
        iu = mu.ravel() > 0
        out[name] = {
            "ms_min": float(min(ts)),
            "ms_median": float(np.median(ts)),
            "n_inliers": int(iu.sum()),
            "inlier_recall": float((iu & ok).sum() / ok.sum()),
            "rotation_error_deg": rot_err_deg(ru, r_true),
            "translation_error_deg": dir_err_deg(tu, t_true),
        }
    lap = d.get("laparo")
    if lap is not None:
        lin = np.asarray(lap["inliers"], bool)
        out["vs_laparo"] = {
            "rotation_angle_deg": rot_err_deg(r, np.asarray(lap["r"])),
            "translation_angle_deg": dir_err_deg(t, lap["t"]),
            "inlier_mask_agreement": float((lin == inl).mean()),
            "laparo_rotation_error_deg": rot_err_deg(np.asarray(lap["r"]), r_true),
            "laparo_translation_error_deg": dir_err_deg(lap["t"], t_true),
        }
    json.dump(out, sys.stdout, indent=1)
    print()


if __name__ == "__main__":
    main()
