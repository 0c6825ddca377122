#!/usr/bin/env python3
"""Check `laparo depth eval-pair` against the numpy reference ../shared/bench/depth_eval_ref.py.

Generates random prediction/ground-truth pairs (disparity and depth predictions, holes in the
GT, invalid predictions, GT in mm, ROI masks, clamping at both ends, even/odd valid counts, a
constant prediction), runs both, and compares every metric of the three alignments to 1e-6
relative. Exit status 0 when all agree.

    python3 scripts/check_depth_ref.py [--laparo target/release/laparo] [--cases 20] [--seed 1]
    python3 scripts/check_depth_ref.py --write-fixtures crates/laparo-depth/tests/fixtures

Needs numpy (e.g. python3 -m venv /tmp/venv-depth && /tmp/venv-depth/bin/pip install numpy).
"""
import argparse, json, math, os, subprocess, sys, tempfile

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
REF_DIR = os.path.normpath(os.path.join(HERE, "..", "..", "shared", "bench"))
ALIGNMENTS = ("none", "scale", "scale_shift")
KEYS = ("abs_rel", "sq_rel", "rmse", "rmse_log", "silog", "delta_0.25", "delta_0.5", "delta_1", "delta_2",
        "delta_3", "scale", "shift")


def make_case(rng, k, max_side=60):
    """Case k: (name, pred, gt_m, pred_kind, gt_unit, mask or None)."""
    h, w = int(rng.integers(5, max_side)), int(rng.integers(5, max_side))
    z = rng.uniform(0.005, 0.6, (h, w))  # beyond both clamp ends
    z[rng.random((h, w)) < 0.15] = 0.0
    z[rng.random((h, w)) < 0.02] = np.nan
    inv = 1.0 / np.where(z > 0, z, 1.0)
    kind = ("disparity", "depth", "disparity_mm", "depth_mask", "constant")[k % 5]
    mask = None
    gt_unit = "m"
    if kind.startswith("disparity"):
        a, b = rng.uniform(-3, 3), rng.uniform(-5, 5)
        pred = a * inv + b + rng.normal(0, rng.uniform(0.01, 3.0), (h, w))
        if kind == "disparity_mm":
            gt_unit = "mm"
        kind_arg = "disparity"
    elif kind.startswith("depth"):
        pred = z * rng.uniform(0.2, 5.0) * np.exp(rng.normal(0, 0.2, (h, w)))
        bad = rng.random((h, w)) < 0.05
        pred[bad] = np.where(rng.random(bad.sum()) < 0.5, 0.0, np.nan)  # invalid predicted depth
        if kind == "depth_mask":
            mask = rng.random((h, w)) < 0.7
        kind_arg = "depth"
    else:
        pred = np.full((h, w), 2.0)
        kind_arg = "disparity"
    return f"case{k:02d}_{kind}", pred, z, kind_arg, gt_unit, mask


def reference(evaluate, pred, z, kind, mask):
    gt = z.copy()
    if mask is not None:
        gt[~mask] = np.nan
    return evaluate(pred, gt, pred_is_depth=(kind == "depth"))


def run_laparo(laparo, d, name, pred, z, kind, gt_unit, mask):
    p, g = os.path.join(d, name + "_pred.npy"), os.path.join(d, name + "_gt.npy")
    np.save(p, pred)
    np.save(g, z * (1000.0 if gt_unit == "mm" else 1.0))
    cmd = [laparo, "depth", "eval-pair", "--pred", p, "--gt", g, "--pred-kind", kind, "--gt-unit", gt_unit, "--json"]
    if mask is not None:
        mp = os.path.join(d, name + "_mask.npy")
        np.save(mp, mask.astype(np.uint8))
        cmd += ["--mask", mp]
    out = subprocess.run(cmd, capture_output=True, text=True)
    if out.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed: {out.stderr}")
    return json.loads(out.stdout)


def compare(a, b, tol):
    """Largest relative difference of laparo result a vs reference b."""
    worst = 0.0
    if a["n_valid"] != b["n_valid"]:
        return math.inf
    for al in ALIGNMENTS:
        for k in KEYS:
            x, y = a[al][k], b[al][k]
            if x is None or y is None or (isinstance(y, float) and math.isnan(y)):
                if not (x is None and (y is None or math.isnan(y))):
                    return math.inf
                continue
            worst = max(worst, abs(x - y) / max(abs(y), 1e-12))
    return worst


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--laparo", default=os.path.join(HERE, "..", "target", "release", "laparo"))
    ap.add_argument("--reference-dir", default=REF_DIR)
    ap.add_argument("--cases", type=int, default=20)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--tol", type=float, default=1e-6)
    ap.add_argument("--write-fixtures", metavar="DIR", help="write small .npy inputs + reference JSON for the Rust test")
    args = ap.parse_args()
    sys.path.insert(0, args.reference_dir)
    from depth_eval_ref import evaluate

    rng = np.random.default_rng(args.seed)
    if args.write_fixtures:
        os.makedirs(args.write_fixtures, exist_ok=True)
        index = []
        for k in range(5):
            name, pred, z, kind, gt_unit, mask = make_case(rng, k, max_side=20)
            np.save(os.path.join(args.write_fixtures, name + "_pred.npy"), pred)
            np.save(os.path.join(args.write_fixtures, name + "_gt.npy"), z * (1000.0 if gt_unit == "mm" else 1.0))
            entry = {"name": name, "pred_kind": kind, "gt_unit": gt_unit, "mask": None,
                     "reference": reference(evaluate, pred, z, kind, mask)}
            if mask is not None:
                np.save(os.path.join(args.write_fixtures, name + "_mask.npy"), mask.astype(np.uint8))
                entry["mask"] = name + "_mask.npy"
            index.append(entry)
        with open(os.path.join(args.write_fixtures, "reference.json"), "w") as f:
            json.dump({"generator": "scripts/check_depth_ref.py --write-fixtures", "seed": args.seed,
                       "reference": "shared/bench/depth_eval_ref.py", "cases": index}, f, indent=1)
        print(f"wrote {len(index)} cases to {args.write_fixtures}")
        return 0

    failures = 0
    overall = 0.0
    with tempfile.TemporaryDirectory() as d:
        for k in range(args.cases):
            name, pred, z, kind, gt_unit, mask = make_case(rng, k)
            ref = reference(evaluate, pred, z, kind, mask)
            got = run_laparo(args.laparo, d, name, pred, z, kind, gt_unit, mask)
            worst = compare(got, ref, args.tol)
            overall = max(overall, worst)
            ok = worst <= args.tol
            failures += not ok
            print(f"{name:24s} n_valid={ref['n_valid']:5d} max rel diff {worst:.2e} {'ok' if ok else 'FAIL'}")
    print(f"{args.cases - failures}/{args.cases} cases agree to {args.tol:g} (max rel diff {overall:.2e})")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
