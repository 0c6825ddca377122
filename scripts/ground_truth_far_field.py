#!/usr/bin/env python3
"""Where a ground truth's far field moves: its |u| by distance from the crack, and how much of it a
rigid turn of each side explains (issue 13's "|u| farther than 60 mm from the cut < 1 mm" line).

Reads the `<scenario>/ground_truth.vtk` files that `laparo register benchmark` writes (legacy VTK,
linear tetrahedra, crack nodes duplicated, `displacement_mm` point vectors). Crack nodes are the
coincident node pairs; the sides are split by the plane that best fits them (PCA); each side's
nodes farther than 60 mm from the nearest crack node get a least-squares rigid motion (Kabsch, no
scale). Needs numpy and scipy; not part of the test suite.

    python3 scripts/ground_truth_far_field.py DIR/anatomical/ground_truth.vtk [...]
"""
import sys

import numpy as np
from scipy.spatial import cKDTree

BINS_MM = ((40, 50), (50, 60), (60, 70), (70, 80), (80, 100), (100, 160))


def read_vtk(path):
    """Points (n, 3), tetrahedra (m, 4) and displacement (n, 3) of a legacy ASCII VTK file."""
    lines = open(path).read().split("\n")
    i = next(k for k, line in enumerate(lines) if line.startswith("POINTS"))
    n = int(lines[i].split()[1])

    def floats(i, count):
        vals = []
        while len(vals) < count:
            vals += lines[i].split()
            i += 1
        return np.array(vals, float), i

    x, i = floats(i + 1, 3 * n)
    i = next(k for k in range(i, len(lines)) if lines[k].startswith("CELLS"))
    m = int(lines[i].split()[1])
    tets = np.array([[int(v) for v in lines[i + 1 + k].split()[1:]] for k in range(m)])
    i = next(k for k in range(i, len(lines)) if lines[k].startswith("VECTORS displacement_mm"))
    u, _ = floats(i + 1, 3 * n)
    return x.reshape(n, 3), tets, u.reshape(n, 3)


def kabsch(p, q):
    """Rotation r and translation t minimising |r p + t - q|."""
    cp, cq = p.mean(0), q.mean(0)
    a, _, bt = np.linalg.svd((p - cp).T @ (q - cq))
    d = np.sign(np.linalg.det(bt.T @ a.T))
    r = bt.T @ np.diag([1.0, 1.0, d]) @ a.T
    return r, cq - r @ cp


def report(path):
    x, _, u = read_vtk(path)
    crack = np.array(sorted({i for pair in cKDTree(x).query_pairs(1e-9) for i in pair}))
    if crack.size == 0:
        raise SystemExit(f"{path}: no duplicated (crack) nodes")
    dist, _ = cKDTree(x[crack]).query(x)
    norm = np.linalg.norm(u, axis=1)
    print(f"{path}: {len(x)} nodes, {len(crack)} crack nodes, max |u| {norm.max():.2f} mm")
    print("  |u| by distance from the crack (mm): bin  p95  max  nodes")
    for lo, hi in BINS_MM:
        s = (dist >= lo) & (dist < hi)
        if s.any():
            print(f"    {lo:>3}-{hi:<3} {np.percentile(norm[s], 95):6.3f} {norm[s].max():6.3f} {s.sum():6d}")
    c = x[crack]
    normal = np.linalg.eigh(np.cov((c - c.mean(0)).T))[1][:, 0]
    side = (x - c.mean(0)) @ normal
    for name, mask in (("A", side < 0), ("B", side > 0)):
        far = mask & (dist > 60)
        if far.sum() < 10:
            continue
        r, t = kabsch(x[far], x[far] + u[far])
        res = np.linalg.norm(x[far] @ r.T + t - (x[far] + u[far]), axis=1)
        angle = np.degrees(np.arccos(np.clip((np.trace(r) - 1) / 2, -1, 1)))
        print(
            f"  side {name}, beyond 60 mm: {far.sum()} nodes, |u| max {norm[far].max():.2f} rms "
            f"{np.sqrt((norm[far] ** 2).mean()):.2f} mm; rigid turn {angle:.2f}°, residual rms "
            f"{np.sqrt((res ** 2).mean()):.2f} max {res.max():.2f} mm"
        )


if __name__ == "__main__":
    if len(sys.argv) < 2:
        raise SystemExit(__doc__)
    for p in sys.argv[1:]:
        report(p)
