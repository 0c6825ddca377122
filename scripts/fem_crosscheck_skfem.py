#!/usr/bin/env python3
"""Cross-check `laparo fem solve` (TET10 Neo-Hookean, eq. 5.3) against scikit-fem (ElementTetP2).

Not run in CI. Set-up (thesis §5.4.2 material): the SOFA liver (`liver.msh`, x10 -> mm), the bottom 15 %
of the vertices by z clamped (with the mid-edge nodes of edges between two clamped vertices), a uniform
dead traction on the boundary triangles whose three vertices are in the top 15 % by z, E = 4.1 kPa,
nu = 0.49, the same load increments, Newton to ||r|| <= 1e-8 ||f||. Prints max nodal difference of the
vertex displacements / max displacement (goal <= 1 %).

    python3 -m venv /work/venv-skfem && /work/venv-skfem/bin/pip install scikit-fem meshio numpy
    cargo build --release -p laparo
    /work/venv-skfem/bin/python scripts/fem_crosscheck_skfem.py [--mesh PATH] [--steps 20] [--force-mn 20]
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np


def read_legacy_vtk(path):
    """Points, tets and point-data displacement of the VTK written by `laparo fem solve`."""
    tok = open(path).read().split("\n")
    i = 0
    pts = tets = disp = None
    while i < len(tok):
        line = tok[i].split()
        if line and line[0] == "POINTS":
            n = int(line[1])
            pts = np.array([[float(x) for x in tok[i + 1 + k].split()] for k in range(n)])
            i += n
        elif line and line[0] == "CELLS":
            n = int(line[1])
            tets = np.array([[int(x) for x in tok[i + 1 + k].split()[1:]] for k in range(n)])
            i += n
        elif line and line[0] == "VECTORS":
            n = len(pts)
            disp = np.array([[float(x) for x in tok[i + 1 + k].split()] for k in range(n)])
            i += n
        i += 1
    return pts, tets, disp


def skfem_solve(pts, tets, fixed, top_faces, traction, steps, E=4.1, nu=0.49, intorder=4):
    from skfem import Basis, BilinearForm, ElementTetP2, ElementVector, FacetBasis, LinearForm, MeshTet, asm, condense, solve
    from skfem.helpers import ddot, det, grad, inv, mul, trace, transpose

    mu = E / (2 * (1 + nu))
    lam = E * nu / ((1 + nu) * (1 - 2 * nu))
    mesh = MeshTet(pts.T.copy(), tets.T.copy())
    e = ElementVector(ElementTetP2())
    basis = Basis(mesh, e, intorder=intorder)

    def kin(w):
        G = grad(w["u"])
        F = G + np.eye(3)[:, :, None, None]
        J = det(F)
        Finv = inv(F)
        return F, J, Finv, transpose(Finv)

    @LinearForm
    def f_int(v, w):
        F, J, Finv, FinvT = kin(w)
        P = mu * (F - FinvT) + lam * np.log(J) * FinvT
        return ddot(P, grad(v))

    @BilinearForm
    def k_tan(du, v, w):
        F, J, Finv, FinvT = kin(w)
        dF = grad(du)
        dP = mu * dF + (mu - lam * np.log(J)) * mul(FinvT, mul(transpose(dF), FinvT)) + lam * trace(mul(Finv, dF)) * FinvT
        return ddot(dP, grad(v))

    # Boundary facets whose three vertices are in the top set.
    facets = mesh.facets
    bf = mesh.boundary_facets()
    top_keys = {tuple(sorted(f)) for f in top_faces}
    sel = np.array([f for f in bf if tuple(sorted(facets[:, f])) in top_keys])
    fb = FacetBasis(mesh, e, facets=sel, intorder=intorder)
    t = np.asarray(traction)

    @LinearForm
    def f_trac(v, w):
        return t[0] * v[0] + t[1] * v[1] + t[2] * v[2]

    f_ext = asm(f_trac, fb)
    fixed_set = set(int(i) for i in fixed)
    edges = mesh.edges
    fixed_edges = [k for k in range(edges.shape[1]) if edges[0, k] in fixed_set and edges[1, k] in fixed_set]
    D = np.concatenate([basis.nodal_dofs[:, sorted(fixed_set)].ravel(), basis.edge_dofs[:, fixed_edges].ravel()])
    x = np.zeros(basis.N)
    iters = []
    for k in range(1, steps + 1):
        lf = k / steps
        for it in range(30):
            r = asm(f_int, basis, u=basis.interpolate(x)) - lf * f_ext
            r[D] = 0.0
            if np.linalg.norm(r) <= 1e-8 * np.linalg.norm(lf * f_ext):
                break
            K = asm(k_tan, basis, u=basis.interpolate(x))
            dx = solve(*condense(K, -r, D=D))
            # Backtracking until J > 0 everywhere.
            a = 1.0
            while True:
                xt = x + a * dx
                F = grad(basis.interpolate(xt)) + np.eye(3)[:, :, None, None]
                if np.min(det(F)) > 0 or a < 1e-6:
                    break
                a *= 0.5
            x = xt
        iters.append(it)
    u_vert = x[basis.nodal_dofs].T  # (nverts, 3)
    return u_vert, iters, basis.N


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    ap.add_argument("--mesh", default=os.path.join(root, "..", "shared", "data", "meshes", "sofa_liver", "liver.msh"))
    ap.add_argument("--scale", type=float, default=10.0, help="mesh units -> mm (SOFA liver is in cm)")
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--force-mn", type=float, default=20.0, help="total traction force on the top set (mN)")
    ap.add_argument("--laparo", default=os.path.join(root, "target", "release", "laparo"))
    a = ap.parse_args()
    if not os.path.exists(a.mesh):
        sys.exit(f"mesh {a.mesh} not found (real data absent)")
    with tempfile.TemporaryDirectory() as tmp:
        # 1) Geometry as laparo reads it: a zero-load run writes the scaled mesh to VTK... but a zero
        # load with empty loads is cheap, so run once to get the vertices and tets.
        fixed0 = os.path.join(tmp, "fixed0.json")
        loads0 = os.path.join(tmp, "loads0.json")
        json.dump({"vertices": [0, 1, 2, 3]}, open(fixed0, "w"))
        json.dump({}, open(loads0, "w"))
        # Any three non-collinear vertices suffice for a zero-load run; retry with more if collinear.
        out0 = os.path.join(tmp, "geom")
        subprocess.run([a.laparo, "fem", "solve", "--mesh", a.mesh, "--scale", str(a.scale), "--fixed", fixed0,
                        "--loads", loads0, "--steps", "1", "--out", out0], check=True, capture_output=True)
        pts, tets, _ = read_legacy_vtk(os.path.join(out0, "displacement.vtk"))
        z = pts[:, 2]
        zlo, zhi = np.quantile(z, 0.15), np.quantile(z, 0.85)
        fixed = np.nonzero(z <= zlo)[0]
        top = z >= zhi
        # Boundary triangles of the tets with all three vertices in the top set, outward order irrelevant.
        from collections import Counter
        cnt = Counter()
        for t in tets:
            for f in ((t[1], t[2], t[3]), (t[0], t[2], t[3]), (t[0], t[1], t[3]), (t[0], t[1], t[2])):
                cnt[tuple(sorted(int(i) for i in f))] += 1
        top_faces = [f for f, c in cnt.items() if c == 1 and all(top[i] for i in f)]
        area = sum(0.5 * np.linalg.norm(np.cross(pts[f[1]] - pts[f[0]], pts[f[2]] - pts[f[0]])) for f in top_faces)
        direction = np.array([1.0, 0.0, -1.0]) / np.sqrt(2.0)
        traction = direction * a.force_mn / area  # kPa = mN/mm^2
        print(f"mesh {a.mesh}: {len(pts)} vertices, {len(tets)} tets (x{a.scale} -> mm); {len(fixed)} clamped "
              f"(z <= {zlo:.2f} mm); {len(top_faces)} top faces (z >= {zhi:.2f} mm, area {area:.1f} mm^2), "
              f"traction {traction.round(5).tolist()} kPa, total {a.force_mn} mN")
        fixed_json = os.path.join(tmp, "fixed.json")
        loads_json = os.path.join(tmp, "loads.json")
        json.dump({"vertices": fixed.tolist()}, open(fixed_json, "w"))
        json.dump({"face_tractions": [{"face": list(f), "traction_kpa": traction.tolist()} for f in top_faces]},
                  open(loads_json, "w"))
        out = os.path.join(tmp, "laparo")
        t0 = time.time()
        r = subprocess.run([a.laparo, "fem", "solve", "--mesh", a.mesh, "--scale", str(a.scale), "--fixed", fixed_json,
                            "--loads", loads_json, "--steps", str(a.steps), "--quadrature", "degree5", "--out", out],
                           check=True, capture_output=True, text=True)
        t_laparo = time.time() - t0
        print("laparo:", r.stdout.strip())
        u_l = np.load(os.path.join(out, "displacement.npy"))
        t0 = time.time()
        u_s, iters, ndof = skfem_solve(pts, tets, fixed, top_faces, traction, a.steps)
        t_skfem = time.time() - t0
        print(f"scikit-fem P2: {ndof} DOFs, Newton iterations per step {iters}, {t_skfem:.1f} s (laparo {t_laparo:.2f} s)")
        umax = np.linalg.norm(u_s, axis=1).max()
        diff = np.linalg.norm(u_l - u_s, axis=1).max()
        print(f"max |u| scikit-fem {umax:.5f} mm, laparo {np.linalg.norm(u_l, axis=1).max():.5f} mm; "
              f"max nodal |u_laparo - u_skfem| {diff:.3e} mm = {100 * diff / umax:.4f} % of max |u| "
              f"-> {'OK (<= 1 %)' if diff <= 0.01 * umax else 'MISMATCH'}")
        try:
            import laparo  # the Python package (maturin develop -m crates/laparo-py/Cargo.toml), in this process
        except ImportError:
            print("laparo's Python package is not installed here: in-process timing skipped")
            return
        t0 = time.time()
        faces = np.array(top_faces, dtype=np.int64)
        r = laparo.fem.solve(pts, tets.astype(np.int64), fixed.astype(np.int64),
                             face_tractions=(faces, np.tile(traction, (len(faces), 1))), steps=a.steps,
                             quadrature="degree5")
        t_py = time.time() - t0
        dpy = np.linalg.norm(r["displacement"] - u_l, axis=1).max()
        print(f"in-process laparo.fem.solve: {t_py:.2f} s (NumPy in and out), scikit-fem / laparo = {t_skfem / t_py:.1f}; "
              f"max nodal difference to the CLI {dpy:.1e} mm")


if __name__ == "__main__":
    main()
