#!/usr/bin/env python3
"""Compare laparo's volumetric ARAP (crates/laparo-register/src/baselines/arap.rs) with libigl's igl.arap
on the same tet mesh, the same hard constraints, the same energy, the same initial guess and the same
number of local-global iterations (not run in CI).

Setup: python3 -m venv /work/venv-igl && /work/venv-igl/bin/pip install libigl numpy
Usage:  /work/venv-igl/bin/python scripts/arap_vs_libigl.py [MESH.msh] [--energy elements|spokes]
            [--iterations N] [--scale S]
Default mesh: ../shared/data/meshes/sofa_liver/liver.msh (×10 → mm). The script builds and runs
`cargo run --release -p laparo-register --example arap_mesh -- compare ...` (which writes the problem
and laparo's result to a JSON file), runs libigl on it, and prints the max node difference relative to
the max displacement and the speed ratio (best of 3 for both).
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np
import igl

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("mesh", nargs="?", default=os.path.join(ROOT, "..", "shared", "data", "meshes", "sofa_liver", "liver.msh"))
    ap.add_argument("--energy", default="elements", choices=["elements", "spokes"])
    ap.add_argument("--iterations", type=int, default=50)
    ap.add_argument("--scale", type=float, default=10.0)
    a = ap.parse_args()
    if not os.path.exists(a.mesh):
        sys.exit(f"mesh not found: {a.mesh} (the shared data directory is absent)")
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "arap.json")
        cmd = ["cargo", "run", "--release", "-q", "-p", "laparo-register", "--example", "arap_mesh", "--",
               "compare", a.mesh, out, "--scale", str(a.scale), "--energy", a.energy,
               "--iterations", str(a.iterations)]
        subprocess.run(cmd, cwd=ROOT, check=True)
        with open(out) as f:
            d = json.load(f)
    V = np.array(d["vertices"], dtype=np.float64)
    T = np.array(d["tets"], dtype=np.int64)
    b = np.array(d["fixed"], dtype=np.int32)
    bc = np.array(d["fixed_positions"], dtype=np.float64)
    ours = np.array(d["laparo_positions"], dtype=np.float64)
    U0 = V.copy()
    U0[b] = bc
    best = float("inf")
    for _ in range(3):
        t0 = time.perf_counter()
        data = igl.ARAPData()
        data.energy = igl.ARAP_ENERGY_TYPE_ELEMENTS if a.energy == "elements" else igl.ARAP_ENERGY_TYPE_SPOKES
        data.max_iter = a.iterations
        igl.arap_precomputation(V, T, 3, b, data)
        U = igl.arap_solve(bc, data, U0)
        best = min(best, time.perf_counter() - t0)
    disp = np.linalg.norm(U - V, axis=1).max()
    diff = np.linalg.norm(U - ours, axis=1)
    print(f"{len(V)} nodes, {len(T)} tets, {len(b)} fixed, energy {a.energy}, {a.iterations} iterations")
    print(f"max displacement (libigl) {disp:.4f} mm; laparo vs libigl: max node difference {diff.max():.3e} mm "
          f"(mean {diff.mean():.3e}), relative {diff.max() / disp:.3e}")
    print(f"time: laparo {d['laparo_seconds']:.4f} s, libigl {best:.4f} s, libigl/laparo = {best / d['laparo_seconds']:.2f}")


if __name__ == "__main__":
    main()
