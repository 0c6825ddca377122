"""The incision benchmark's tools in Python, in miniature (thesis §5.4.2): mesh a closed surface, make
a ground truth with the Neo-Hookean FEM, and score the mesh baselines (ARAP, DRBC, LDDMM) by their
target registration error (TRE) at every node.

    python examples/python/fem_baselines.py [--surface liver.obj --scale 10] [--edge-mm 5] [--noise-mm 1]

Default surface: the SOFA liver of ../shared/data (cm, ×10 → mm), else a 100×80×60 mm box. The lowest
15 % of the nodes (z) are held fixed, a shear traction (kPa) along +x acts on the top 15 % of the
boundary faces; 20 boundary nodes of the loaded region are the landmarks, their FEM positions plus
Gaussian noise the (paired) targets.
"""
import argparse
import time
from pathlib import Path

import numpy as np

import laparo

DATA = Path(__file__).resolve().parents[2] / ".." / "shared" / "data" / "meshes" / "sofa_liver" / "liver-smooth.obj"


def read_obj(path, scale):
    v, f = [], []
    for line in Path(path).read_text().splitlines():
        p = line.split()
        if p and p[0] == "v":
            v.append([float(c) * scale for c in p[1:4]])
        elif p and p[0] == "f":
            idx = [int(c.split("/")[0]) - 1 for c in p[1:]]
            f += [[idx[0], idx[k], idx[k + 1]] for k in range(1, len(idx) - 1)]
    return np.array(v), np.array(f, np.int64)


def box(lo=(0.0, 0.0, 0.0), hi=(100.0, 80.0, 60.0)):
    v = np.array([[hi[0] if i & 1 else lo[0], hi[1] if i & 2 else lo[1], hi[2] if i & 4 else lo[2]] for i in range(8)])
    quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]]
    return v, np.array([t for q in quads for t in ([q[0], q[1], q[2]], [q[0], q[2], q[3]])], np.int64)


def boundary_faces(tets):
    """Faces used by one tetrahedron only."""
    faces = np.concatenate([tets[:, [1, 2, 3]], tets[:, [0, 3, 2]], tets[:, [0, 1, 3]], tets[:, [0, 2, 1]]])
    key = np.sort(faces, axis=1)
    _, inv, count = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    return faces[count[inv.ravel()] == 1]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--surface")
    ap.add_argument("--scale", type=float, default=10.0)
    ap.add_argument("--edge-mm", type=float, default=5.0)
    ap.add_argument("--traction-kpa", type=float, default=0.1)
    ap.add_argument("--noise-mm", type=float, default=1.0)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()
    if a.surface or DATA.is_file():
        v, f = read_obj(a.surface or DATA, a.scale)
    else:
        v, f = box()
    t0 = time.perf_counter()
    nodes, tets, q = laparo.fem.tetrahedralize(v, f, edge_mm=a.edge_mm)
    print(f"mesh: {q['nodes']} nodes, {q['tets']} tets, min dihedral {q['min_dihedral_deg']:.1f}°, "
          f"volume error {100 * q['volume_rel_error']:+.2f} % ({time.perf_counter() - t0:.2f} s)")

    z = nodes[:, 2]
    fixed = np.flatnonzero(z <= np.quantile(z, 0.15))
    bf = boundary_faces(tets)
    zc = nodes[bf].mean(axis=1)[:, 2]
    loaded = bf[zc >= np.quantile(zc, 0.85)]
    t0 = time.perf_counter()
    gt = laparo.fem.solve(nodes, tets, fixed, face_tractions=(loaded, np.tile([a.traction_kpa, 0.0, 0.0], (len(loaded), 1))),
                          steps=10)
    u = gt["displacement"]
    rep = gt["report"]
    print(f"FEM (TET10 Neo-Hookean, E 4.1 kPa, ν 0.49): max |u| {rep['max_displacement_mm']:.2f} mm, "
          f"min J {rep['min_j']:.3f}, {rep['free_dofs']} free DOFs ({time.perf_counter() - t0:.2f} s)")

    rng = np.random.default_rng(a.seed)
    cand = np.unique(loaded)
    ids = np.sort(rng.choice(cand, size=min(20, len(cand)), replace=False))
    targets = {"lm": nodes[ids] + u[ids] + rng.normal(0.0, a.noise_mm, size=(len(ids), 3))}
    truth = nodes + u
    print(f"{len(ids)} landmarks, noise σ {a.noise_mm} mm; TRE over all {len(nodes)} nodes (mm):")
    tre = np.linalg.norm(nodes - truth, axis=1)
    print(f"  {'none (rest)':<14} {tre.mean():6.2f} ± {tre.std():5.2f}")
    runs = {
        "ARAP": lambda: laparo.register.arap(nodes, tets, {"lm": ids}, targets, fixed=fixed),
        "DRBC": lambda: laparo.register.drbc(nodes, tets, {"lm": ids}, targets, fixed=fixed),
        "LDDMM": lambda: laparo.register.lddmm(nodes, tets, {"lm": ids}, targets, sigma_mm=20.0),
    }
    for name, run in runs.items():
        r = run()
        tre = np.linalg.norm(r["positions"] - truth, axis=1)
        print(f"  {name:<14} {tre.mean():6.2f} ± {tre.std():5.2f}   (landmark distance "
              f"{r['report']['mean_distance_mm']:.2f} mm, {r['report']['seconds']:.2f} s)")


if __name__ == "__main__":
    main()
