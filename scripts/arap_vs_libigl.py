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


def polar(m):
    u, _, vt = np.linalg.svd(m)
    r = u @ vt
    if np.linalg.det(r) < 0:
        u[:, -1] *= -1
        r = u @ vt
    return r


def reference_arap(V, T, b, bc, U0, energy, iterations):
    """Plain local-global ARAP in double precision (same energies as laparo's `ArapEnergy`)."""
    import scipy.sparse.linalg as spla
    t0 = time.perf_counter()
    K = -igl.cotmatrix(V, T).tocsc()  # P1 stiffness = cotangent weights
    n = len(V)
    free = np.setdiff1d(np.arange(n), b)
    G, vol = [], []
    for t in T:
        dm = (V[t[1:]] - V[t[0]]).T
        inv = np.linalg.inv(dm)
        G.append(np.vstack([-inv.sum(0), inv]))
        vol.append(abs(np.linalg.det(dm)) / 6)
    Kc = K.tocoo()
    edges = [(i, j, -w) for i, j, w in zip(Kc.row, Kc.col, Kc.data) if i < j]
    solve = spla.factorized(K[free][:, free].tocsc())
    Kfc = K[free][:, b]
    U = U0.copy()
    for _ in range(iterations):
        rhs = np.zeros((n, 3))
        if energy == "elements":
            for t, g, v in zip(T, G, vol):
                r = polar(U[t].T @ g)  # F = sum_a x_a g_a^T
                rhs[t] += v * (g @ r.T)
        else:
            S = np.zeros((n, 3, 3))
            for i, j, w in edges:
                m = w * np.outer(V[i] - V[j], U[i] - U[j])
                S[i] += m
                S[j] += m
            R = np.array([polar(s.T) for s in S])
            for i, j, w in edges:
                e = w * 0.5 * (R[i] + R[j]) @ (V[i] - V[j])
                rhs[i] += e
                rhs[j] -= e
        x = np.column_stack([solve(rhs[free, c] - Kfc @ bc[:, c]) for c in range(3)])
        U[free] = x
        U[b] = bc
    return U, time.perf_counter() - t0


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
    # independent double-precision reference of the same energy (numpy SVD, scipy sparse solve, libigl's
    # cotangent matrix): separates laparo's correctness from libigl's single-precision rotation fit
    Uref, tref = reference_arap(V, T, b, bc, U0, a.energy, a.iterations)
    disp = np.linalg.norm(U - V, axis=1).max()
    diff = np.linalg.norm(U - ours, axis=1)
    print(f"{len(V)} nodes, {len(T)} tets, {len(b)} fixed, energy {a.energy}, {a.iterations} iterations")
    print(f"max displacement (libigl) {disp:.4f} mm; laparo vs libigl: max node difference {diff.max():.3e} mm "
          f"(mean {diff.mean():.3e}), relative {diff.max() / disp:.3e}")
    dref = np.linalg.norm(Uref - ours, axis=1).max()
    dref_igl = np.linalg.norm(Uref - U, axis=1).max()
    print(f"double-precision numpy reference: vs laparo {dref:.3e} mm (relative {dref / disp:.3e}), "
          f"vs libigl {dref_igl:.3e} mm (relative {dref_igl / disp:.3e}); reference time {tref:.3f} s")
    print(f"time: laparo {d['laparo_seconds']:.4f} s, libigl {best:.4f} s, libigl/laparo = {best / d['laparo_seconds']:.2f}")
    try:
        import laparo  # the Python package (maturin develop -m crates/laparo-py/Cargo.toml), in this process
    except ImportError:
        print("laparo's Python package is not installed here: in-process timing skipped")
        return
    best_py = float("inf")
    for _ in range(3):
        t0 = time.perf_counter()
        r = laparo.register.arap(V, T, fixed=b.astype(np.int64), fixed_positions=bc, energy=a.energy,
                                 iterations=a.iterations, tolerance_mm=0.0)
        best_py = min(best_py, time.perf_counter() - t0)
    dpy = np.linalg.norm(r["positions"] - ours, axis=1).max()
    print(f"in-process laparo.register.arap: {best_py:.4f} s (wall, NumPy in and out), libigl/laparo = "
          f"{best / best_py:.2f}; max node difference to the CLI example {dpy:.1e} mm")


if __name__ == "__main__":
    main()
