"""Evaluate a monocular depth network's predictions with the RoDEM metrics (thesis §3.2.7).

    python examples/python/depth_eval_predictions.py PRED_DIR GT_DIR [--pred-kind disparity] [--gt-unit mm]
    python examples/python/depth_eval_predictions.py            # demo on generated data

PRED_DIR holds <stem>.npy predictions (any scale; disparity or depth), GT_DIR <stem>.npy ground
truth. Prints per-image Abs Rel / δ_0.25 after scale-and-shift alignment and the means; the
numbers are those of `laparo depth eval-pair --json` on the same files.
"""
import argparse
import sys
from pathlib import Path

import numpy as np

import laparo


def demo_data(n=6, h=96, w=128, seed=0):
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:h, 0:w]
    gts, preds = [], []
    for i in range(n):
        gt_mm = 60.0 + 120.0 * xx / w + 30.0 * np.sin(yy / 15.0 + i)
        # A "network" predicting affine-invariant disparity with 5 % noise.
        preds.append(2.5 / gt_mm * (1 + 0.05 * rng.standard_normal((h, w))) + 0.001)
        gts.append(gt_mm)
    return [f"demo{i}" for i in range(n)], preds, gts


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("pred_dir", nargs="?")
    ap.add_argument("gt_dir", nargs="?")
    ap.add_argument("--pred-kind", default="disparity")
    ap.add_argument("--gt-unit", default="mm")
    a = ap.parse_args()
    if a.pred_dir is None:
        names, preds, gts = demo_data()
    else:
        names = sorted(p.stem for p in Path(a.pred_dir).glob("*.npy"))
        if not names:
            sys.exit(f"no .npy predictions in {a.pred_dir}")
        preds = [np.load(Path(a.pred_dir) / f"{n}.npy").astype(np.float64) for n in names]
        gts = [np.load(Path(a.gt_dir) / f"{n}.npy").astype(np.float64) for n in names]
    # One call, all images in parallel (GIL released).
    results = laparo.depth.evaluate_batch(preds, gts, pred_kind=a.pred_kind, gt_unit=a.gt_unit)
    print(f"{'image':12} {'AbsRel':>8} {'δ0.25':>8} {'RMSE mm':>8}  (scale & shift aligned)")
    for n, r in zip(names, results):
        m = r["scale_shift"]
        print(f"{n:12} {m['abs_rel']:8.4f} {m['delta_0.25']:8.4f} {1000 * m['rmse']:8.2f}")
    print(f"{'mean':12} {np.mean([r['scale_shift']['abs_rel'] for r in results]):8.4f} "
          f"{np.mean([r['scale_shift']['delta_0.25'] for r in results]):8.4f}")


if __name__ == "__main__":
    main()
