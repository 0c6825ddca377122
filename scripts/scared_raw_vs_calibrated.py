#!/usr/bin/env python3
"""Agreement of two disparity maps of the same raw left frame (issue 14, SCARED ds1-3 check).

    python scripts/scared_raw_vs_calibrated.py RAW/disparity.pfm CAL/disparity_raw.pfm

RAW: `laparo stereo match` on the raw pair (disparity.pfm, raw left frame). CAL: the calibrated
pipeline (`--calib ...`), whose disparity_raw.pfm is mapped back to the raw left frame. Invalid
pixels are non-finite in both. Prints the share of the image valid in each and in both, and,
over pixels valid in both, the share with |d_raw - d_cal| <= 1 px and the median |difference|.
No matcher code is shared with laparo: this only reads the two PFM files.
"""
import json
import sys

import numpy as np


def read_pfm(path):
    with open(path, "rb") as f:
        kind = f.readline().strip()
        if kind not in (b"Pf", b"PF"):
            raise SystemExit(f"{path}: not a PFM file ({kind!r})")
        w, h = map(int, f.readline().split())
        scale = float(f.readline())
        data = np.fromfile(f, dtype="<f4" if scale < 0 else ">f4")
    ch = 3 if kind == b"PF" else 1
    return np.flipud(data.reshape(h, w, ch)[..., 0])  # PFM rows run bottom to top


def main():
    if len(sys.argv) != 3:
        raise SystemExit(__doc__)
    a, b = read_pfm(sys.argv[1]), read_pfm(sys.argv[2])
    if a.shape != b.shape:
        raise SystemExit(f"size mismatch: {a.shape} vs {b.shape}")
    va, vb = np.isfinite(a), np.isfinite(b)
    both = va & vb
    diff = np.abs(a[both].astype(np.float64) - b[both].astype(np.float64))
    n = a.size
    out = {
        "valid_first_pct": 100.0 * va.sum() / n,
        "valid_second_pct": 100.0 * vb.sum() / n,
        "valid_both_pct": 100.0 * both.sum() / n,
        "within_1px_pct_of_both": 100.0 * (diff <= 1.0).mean() if diff.size else float("nan"),
        "median_abs_diff_px": float(np.median(diff)) if diff.size else float("nan"),
        "p95_abs_diff_px": float(np.percentile(diff, 95)) if diff.size else float("nan"),
        # Where the second map is invalid but the first is valid: by column band (left strip?).
        "lost_in_second_by_column_fifth_pct": [
            100.0 * (va & ~vb)[:, i * a.shape[1] // 5:(i + 1) * a.shape[1] // 5].sum() / n for i in range(5)
        ],
    }
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
