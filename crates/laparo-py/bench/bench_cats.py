"""CATS augmentation throughput per core at 1280×1024: `laparo.cats.augment` (Rust, via the
Python package) against the NumPy/OpenCV implementation of the same work
(`benchmarks/cats_reference.py`: both views warped bilinearly by H = K_rel K R K⁻¹ with inverse
mapping, validity masks, the left disparity by the exact rule), in the same run, alternating
rounds, one thread each (`laparo.set_num_threads(1)`, `cv2.setNumThreads(1)`,
`OPENBLAS_NUM_THREADS=1`).

    python crates/laparo-py/bench/bench_cats.py [--n 6] [--rounds 5] [--rule exact|thesis]
    (needs numpy and opencv-python-headless in the environment of the laparo package)

Prints the CPU model, the load average, the median time per sample of each, the ratio per round
and its median, and the agreement of both on the same parameters.
"""
from __future__ import annotations

import argparse
import os

# One thread for NumPy's BLAS too (the reference's coordinate products), before NumPy loads.
for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import platform  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

REPO = Path(__file__).resolve().parents[3]
sys.path.insert(0, str(REPO / "benchmarks"))
import cats_reference as ref  # noqa: E402
import cv2  # noqa: E402

import laparo  # noqa: E402


def make_samples(n, w, h, seed=0):
    """Textured RGB pairs whose right view is the left shifted by a smooth disparity (px)."""
    rng = np.random.default_rng(seed)
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float64)
    out = []
    for i in range(n):
        disp = (20.0 + 30.0 * xs / w + 5.0 * np.sin(ys / 40.0 + i)).astype(np.float32)
        tex = lambda x, y: 127.5 + 60 * np.sin(0.11 * x + i) * np.cos(0.07 * y) + 30 * np.sin(0.013 * x * y / 9.0)  # noqa: E731
        noise = rng.normal(0, 8, (h, w, 3))
        left = np.stack([tex(xs, ys), tex(xs + 5, ys), tex(xs, ys + 3)], -1) + noise
        right = np.stack([tex(xs + disp, ys), tex(xs + disp + 5, ys), tex(xs + disp, ys + 3)], -1) + noise
        out.append((left.clip(0, 255).astype(np.uint8), right.clip(0, 255).astype(np.uint8), disp))
    return out


def cpu_model():
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor()


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=6)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--width", type=int, default=1280)
    ap.add_argument("--height", type=int, default=1024)
    ap.add_argument("--rule", default="exact", choices=["exact", "thesis"])
    a = ap.parse_args()
    laparo.set_num_threads(1)
    cv2.setNumThreads(1)
    w, h = a.width, a.height
    samples = make_samples(a.n, w, h)
    cfg = laparo.cats.thesis_config()
    k = np.array([[1050.0, 0, (w - 1) / 2], [0, 1050.0, (h - 1) / 2], [0, 0, 1.0]])

    # Agreement on the same parameters.
    l, r, d = samples[0]
    got = laparo.cats.augment(l, r, d, config=cfg, seed=1, sample_id="0", k_left=k, gt_rule=a.rule)
    hl, hr = np.array(got["params"]["homography_left"]), np.array(got["params"]["homography_right"])
    dx0 = got["params"]["dx_right_px"]
    mine = ref.augment(l, r, d, hl, hr) if a.rule == "exact" else ref.augment_thesis(l, r, d, hl, hr, dx0)
    both = got["valid_left"] & mine["valid_left"]
    img_diff = np.abs(got["left"].astype(float) - mine["left"].astype(float))[both].mean()
    dv = got["disp_left_valid"] & mine["disp_left_valid"]
    interior = np.zeros_like(dv)
    interior[2:-2, 2:-2] = True
    with np.errstate(invalid="ignore"):
        disp_diff = np.abs(got["disp_left"] - mine["disp_left"])[dv & interior].max()

    t_l, t_r = [], []
    rng = np.random.default_rng(1)
    for rnd in range(a.rounds):
        t0 = time.perf_counter()
        for i, (l, r, d) in enumerate(samples):
            laparo.cats.augment(l, r, d, config=cfg, seed=rnd, sample_id=str(i), k_left=k, gt_rule=a.rule)
        t_l.append((time.perf_counter() - t0) / len(samples))
        t0 = time.perf_counter()
        for l, r, d in samples:
            hl, hr, dx = ref.sample_homographies(rng, k)
            ref.augment(l, r, d, hl, hr) if a.rule == "exact" else ref.augment_thesis(l, r, d, hl, hr, dx)
        t_r.append((time.perf_counter() - t0) / len(samples))
    ml, mr = statistics.median(t_l), statistics.median(t_r)
    print(f"CPU: {cpu_model()} ({os.cpu_count()} logical); load average {os.getloadavg()}")
    print(f"laparo {laparo.__version__}, NumPy {np.__version__}, OpenCV {cv2.__version__}, Python {platform.python_version()}")
    print("1 thread each (laparo.set_num_threads(1), cv2.setNumThreads(1), OPENBLAS_NUM_THREADS=1)")
    print(f"samples {w}x{h} RGB + disparity, {a.rule} rule, {len(samples)} samples x {a.rounds} alternating rounds")
    print("laparo       s/sample: " + " ".join(f"{t:.4f}" for t in t_l) + f"  median {ml:.4f}")
    print("NumPy/OpenCV s/sample: " + " ".join(f"{t:.4f}" for t in t_r) + f"  median {mr:.4f}")
    print("ratio (reference / laparo): " + " ".join(f"{b / a_:.2f}" for a_, b in zip(t_l, t_r)) + f"  median {mr / ml:.2f}x")
    print(f"agreement on the same parameters: mean |left diff| {img_diff:.3f} grey levels, max |disparity diff| "
          f"{disp_diff:.2e} px (interior pixels valid in both)")


if __name__ == "__main__":
    main()
