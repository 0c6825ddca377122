"""laparo.fem against independent numbers: the volume and dihedral angles of hand-computed meshes
(numpy), the exact finite-strain solution of a bar in uniaxial tension (ν = 0, where the clamped end
constrains nothing), the CLI on the same problem, and errors that name the argument."""
import itertools
import json
import math

import numpy as np
import pytest

import laparo
from conftest import REPO

F = laparo.fem


def box_surface(lo, hi):
    """Closed, outward-oriented triangle surface of an axis-aligned box."""
    v = np.array([[hi[0] if i & 1 else lo[0], hi[1] if i & 2 else lo[1], hi[2] if i & 4 else lo[2]] for i in range(8)], float)
    quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]]
    f = np.array([t for q in quads for t in ([q[0], q[1], q[2]], [q[0], q[2], q[3]])], np.int64)
    return v, f


def signed_volume(v, f):
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    return np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0


def tet_volumes(nodes, tets):
    p = nodes[tets]
    return np.linalg.det(np.stack([p[:, 1] - p[:, 0], p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]], axis=1)) / 6.0


def box_tets(n, h):
    """Structured mesh of [0, n0 h] × [0, n1 h] × [0, n2 h]: each cube split into 6 Kuhn tetrahedra."""
    idx = lambda i, j, k: i + (n[0] + 1) * (j + (n[1] + 1) * k)  # noqa: E731
    nodes = np.array([[i * h, j * h, k * h] for k in range(n[2] + 1) for j in range(n[1] + 1) for i in range(n[0] + 1)])
    tets = []
    for i, j, k in itertools.product(range(n[0]), range(n[1]), range(n[2])):
        for perm in itertools.permutations(range(3)):
            c = [i, j, k]
            path = [idx(*c)]
            for d in perm:
                c[d] += 1
                path.append(idx(*c))
            tets.append(path)
    tets = np.array(tets, np.int64)
    neg = tet_volumes(nodes, tets) < 0
    tets[neg] = tets[neg][:, [0, 2, 1, 3]]
    return nodes, tets


def test_tetrahedralize_a_box_against_numpy():
    v, f = box_surface([0, 0, 0], [20, 16, 12])
    assert signed_volume(v, f) == pytest.approx(3840.0)
    nodes, tets, rep = F.tetrahedralize(v, f, edge_mm=4.0)
    assert nodes.dtype == np.float64 and tets.dtype == np.int64 and tets.shape[1] == 4
    vol = tet_volumes(nodes, tets)
    assert (vol > 0).all()
    assert rep["tets"] == len(tets) and rep["nodes"] == len(nodes) and rep["inverted"] == 0
    assert rep["volume_mm3"] == pytest.approx(vol.sum(), rel=1e-12)
    assert rep["surface_volume_mm3"] == pytest.approx(3840.0, rel=1e-12)
    assert rep["volume_rel_error"] == pytest.approx((vol.sum() - 3840.0) / 3840.0, rel=1e-9)
    # the box's sharp edges are cut by the lattice: a first-order volume error that halves with the edge
    errs = [abs(F.tetrahedralize(v, f, edge_mm=h)[2]["volume_rel_error"]) for h in (2.0, 1.0)]
    assert errs[0] < abs(rep["volume_rel_error"]) / 1.5 and errs[1] < errs[0] / 1.5 and errs[1] < 0.01
    assert rep["min_dihedral_deg"] >= 10.0 - 1e-9
    # every node inside the box (snapping moves boundary nodes onto the surface, never beyond it by more than round-off)
    assert (nodes >= -1e-9).all() and (nodes <= np.array([20, 16, 12]) + 1e-9).all()
    # quality() on the same mesh and surface gives the same report
    assert F.quality(nodes, tets, surface=(v, f)) == rep


def test_quality_of_a_regular_tetrahedron_by_hand():
    a = 3.0
    nodes = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], float) * a / (2 * math.sqrt(2))
    tets = np.array([[0, 1, 2, 3]])
    if tet_volumes(nodes, tets)[0] < 0:
        tets = tets[:, [0, 2, 1, 3]]
    r = F.quality(nodes, tets)
    assert r["tets"] == 1 and r["nodes"] == 4 and r["inverted"] == 0
    assert r["min_dihedral_deg"] == pytest.approx(math.degrees(math.acos(1 / 3)), abs=1e-9)
    assert r["max_dihedral_deg"] == pytest.approx(math.degrees(math.acos(1 / 3)), abs=1e-9)
    assert r["volume_mm3"] == pytest.approx(a**3 / (6 * math.sqrt(2)), rel=1e-12)
    assert r["edge_min_mm"] == pytest.approx(a) and r["edge_max_mm"] == pytest.approx(a)
    assert r["surface_volume_mm3"] is None


def uniaxial_stretch(t_kpa, e_kpa):
    """ν = 0 (λ = 0): F = diag(1, 1, s) is in equilibrium with P_zz = μ (s − 1/s) = t, P_xx = P_yy = 0."""
    mu = e_kpa / 2.0
    r = t_kpa / mu
    return (r + math.sqrt(r * r + 4.0)) / 2.0


def end_faces(nodes, tets, z):
    faces = set()
    for t in tets:
        for f in itertools.combinations(t, 3):
            if np.all(np.abs(nodes[list(f), 2] - z) < 1e-12):
                faces.add(tuple(f))
    return np.array(sorted(faces), np.int64)


@pytest.mark.parametrize("form", ["vector", "normal"])
def test_bar_in_uniaxial_tension_matches_the_closed_form(form):
    nodes, tets = box_tets([2, 2, 4], 2.5)  # 5 × 5 × 10 mm
    top = end_faces(nodes, tets, 10.0)
    assert len(top) == 8
    fixed = np.flatnonzero(np.abs(nodes[:, 2]) < 1e-12)
    e_kpa, t_kpa = 4.1, 1.5
    if form == "vector":
        tr = np.tile([0.0, 0.0, t_kpa], (len(top), 1))
    else:  # pressure along (b − a) × (c − a): flip faces so that the normal is +z
        a, b, c = (nodes[top[:, i]] for i in range(3))
        up = np.cross(b - a, c - a)[:, 2] > 0
        top = np.where(up[:, None], top, top[:, [0, 2, 1]])
        tr = np.full(len(top), t_kpa)
    out = F.solve(nodes, tets, fixed, face_tractions=(top, tr), young_kpa=e_kpa, poisson=0.0, steps=4)
    s = uniaxial_stretch(t_kpa, e_kpa)
    assert s > 1.3  # a finite strain, not the linear regime
    want = np.zeros_like(nodes)
    want[:, 2] = (s - 1.0) * nodes[:, 2]
    u = out["displacement"]
    assert u.shape == nodes.shape
    assert np.abs(u - want).max() < 1e-7 * 10.0 * (s - 1.0)
    rep = out["report"]
    assert rep["min_j"] == pytest.approx(s, rel=1e-7)
    assert rep["max_displacement_mm"] == pytest.approx(10.0 * (s - 1.0), rel=1e-7)
    # mid-edge nodes of the quadratic mesh follow the same linear field
    x10, u10 = out["tet10_nodes"], out["displacement_tet10"]
    assert x10.shape == u10.shape and len(x10) > len(nodes)
    assert np.abs(x10[: len(nodes)] - nodes).max() == 0.0
    assert np.abs(u10[:, 2] - (s - 1.0) * x10[:, 2]).max() < 1e-6
    assert np.abs(u10[:, :2]).max() < 1e-6


def test_solve_matches_the_cli(tmp_path, cli):
    nodes, tets = box_tets([1, 1, 3], 4.0)
    top = end_faces(nodes, tets, 12.0)
    fixed = np.flatnonzero(np.abs(nodes[:, 2]) < 1e-12)
    tip = int(np.flatnonzero((np.abs(nodes[:, 2] - 12.0) < 1e-12))[0])
    vec = np.tile([0.02, 0.0, 0.05], (len(top), 1))
    out = F.solve(nodes, tets, fixed, face_tractions=(top, vec), nodal_forces=([tip], [[0.0, 0.3, 0.0]]), steps=5)
    # the same problem through `laparo fem solve` (legacy VTK in, displacement.npy out)
    vtk = tmp_path / "bar.vtk"
    lines = ["# vtk DataFile Version 3.0", "bar", "ASCII", "DATASET UNSTRUCTURED_GRID", f"POINTS {len(nodes)} double"]
    lines += [" ".join(repr(float(c)) for c in p) for p in nodes]
    lines += [f"CELLS {len(tets)} {5 * len(tets)}"] + ["4 " + " ".join(map(str, t)) for t in tets]
    lines += [f"CELL_TYPES {len(tets)}"] + ["10"] * len(tets)
    vtk.write_text("\n".join(lines) + "\n")
    (tmp_path / "fixed.json").write_text(json.dumps({"vertices": fixed.tolist()}))
    loads = {
        "face_tractions": [{"face": f.tolist(), "traction_kpa": t.tolist()} for f, t in zip(top, vec)],
        "nodal_forces": [{"vertex": tip, "force_mn": [0.0, 0.3, 0.0]}],
    }
    (tmp_path / "loads.json").write_text(json.dumps(loads))
    cli("fem", "solve", "--mesh", vtk, "--fixed", tmp_path / "fixed.json", "--loads", tmp_path / "loads.json",
        "--steps", "5", "--out", tmp_path / "out")
    u_cli = np.load(tmp_path / "out" / "displacement.npy").reshape(-1, 3)
    assert np.abs(out["displacement"]).max() > 0.1
    np.testing.assert_allclose(out["displacement"], u_cli, rtol=0, atol=1e-12)


def test_errors_name_the_argument():
    v, f = box_surface([0, 0, 0], [10, 10, 10])
    with pytest.raises(ValueError, match="surface"):
        F.tetrahedralize(v, f[:-1], edge_mm=2.0)  # a missing triangle: not closed
    with pytest.raises(ValueError, match="edge_mm"):
        F.tetrahedralize(v, f, edge_mm=0.0)
    with pytest.raises(TypeError, match="faces"):
        F.tetrahedralize(v, f.astype(float))
    nodes, tets = box_tets([1, 1, 2], 2.0)
    with pytest.raises(ValueError, match="tets"):
        F.quality(nodes, np.where(tets == 3, 99, tets))
    fixed = np.flatnonzero(nodes[:, 2] == 0)
    with pytest.raises(ValueError, match="fixed"):
        F.solve(nodes, tets, [len(nodes)])
    with pytest.raises(ValueError, match="solver"):
        F.solve(nodes, tets, fixed, solver="lu")
    with pytest.raises(ValueError, match="forces_mn"):
        F.solve(nodes, tets, fixed, nodal_forces=([0, 1], [[0.0, 0.0, 1.0]]))
    with pytest.raises(ValueError, match="face_tractions_kpa"):
        F.solve(nodes, tets, fixed, face_tractions=(tets[:2, :3], np.zeros(5)))
    with pytest.raises(ValueError, match="E|young|kPa"):
        F.solve(nodes, tets, fixed, young_kpa=-1.0)
    # a load that would invert elements: an error, no panic, no half answer
    top = end_faces(nodes, tets, 4.0)
    with pytest.raises(ValueError):
        F.solve(nodes, tets, fixed, face_tractions=(top, np.tile([0.0, 0.0, -50.0], (len(top), 1))), steps=2)


def test_cut_a_box_along_a_node_plane_by_hand():
    """A blade in the node plane x = 10 of a 20 × 10 × 10 mm box (2.5 mm cells), from the top face down to
    z = 5: crack area 10 × 5 mm², the plane's nodes above the front duplicated, the lips, their landmarks by
    arc length; the crack pressure opens it."""
    nodes, tets = box_tets([8, 4, 4], 2.5)
    c = F.cut(nodes, tets, mouth=[[10.0, -1.0, 10.0], [10.0, 11.0, 10.0]], directions=[0.0, 0.0, -1.0],
              depths_mm=5.0, landmarks=4)
    n2, t2 = c["nodes"], c["tets"]
    assert len(t2) == len(tets) and (tet_volumes(n2, t2) > 0).all()
    # nodes of the plane strictly above the front (z = 7.5, 10), 5 per row: 10 duplicated
    assert len(n2) == len(nodes) + 10
    # positions unchanged up to round-off of the snap: the plane already holds the nodes
    np.testing.assert_allclose(nodes[c["original_node"]], n2, rtol=0, atol=1e-12)
    for k in ("crack_faces_a", "crack_faces_b"):
        f = c[k]
        a, b, cc = (n2[f[:, i]] for i in range(3))
        assert np.abs(n2[f][:, :, 0] - 10.0).max() < 1e-12
        assert 0.5 * np.linalg.norm(np.cross(b - a, cc - a), axis=1).sum() == pytest.approx(50.0, rel=1e-12)
    # side A is the side of (mouth tangent) × (direction) = (0, 1, 0) × (0, 0, −1) = −x: its faces point +x (outward)
    fa = c["crack_faces_a"]
    na = np.cross(n2[fa[:, 1]] - n2[fa[:, 0]], n2[fa[:, 2]] - n2[fa[:, 0]])
    assert (na[:, 0] > 0).all()
    # each lip is where the crack meets the outer surface: down the side y = 0 from the front (z = 5), along the
    # top edge, down the side y = 10: a U of 5 + 10 + 5 = 20 mm through 9 nodes, its two ends the shared front nodes
    u_path = np.array([[10, 0, 5], [10, 0, 7.5], [10, 0, 10], [10, 2.5, 10], [10, 5, 10], [10, 7.5, 10], [10, 10, 10],
                       [10, 10, 7.5], [10, 10, 5]], float)
    for lip in c["lips"]:
        np.testing.assert_allclose(n2[lip], u_path, rtol=0, atol=1e-12)
    assert set(c["lips"][0]) & set(c["lips"][1]) == {c["lips"][0][0], c["lips"][0][-1]}
    assert set(c["front_nodes"]) == set(np.flatnonzero((np.abs(n2[:, 0] - 10.0) < 1e-12) & (np.abs(n2[:, 2] - 5.0) < 1e-12)))
    # 2 landmarks per lip at arc lengths (k + 1/2) 20 / 2 = 5 and 15 mm: the two top corners
    want = np.array([[10.0, 0.0, 10.0], [10.0, 10.0, 10.0]] * 2)
    np.testing.assert_allclose(c["landmark_positions"], want, atol=1e-12)
    np.testing.assert_array_equal(c["landmark_side"], [0, 0, 1, 1])
    # open it: fixed bottom, equal and opposite pressure on the crack faces
    fixed = np.flatnonzero(n2[:, 2] == 0.0)
    out = F.solve(n2, t2, fixed, face_tractions=F.crack_pressure(c, 0.2), steps=4)
    u = out["displacement"]
    ua, ub = u[c["lips"][0][1:-1]], u[c["lips"][1][1:-1]]  # without the shared front nodes at the ends
    assert (ua[:, 0] < -0.3).all() and (ub[:, 0] > 0.3).all()  # side A (−x) and side B (+x) pushed apart
    assert out["report"]["min_j"] > 0


def test_cut_errors_name_the_input():
    nodes, tets = box_tets([2, 2, 2], 2.5)
    with pytest.raises(ValueError, match="blade|miss"):
        F.cut(nodes, tets, mouth=[[50.0, 0.0, 5.0], [50.0, 5.0, 5.0]], directions=[0, 0, -1], depths_mm=2.0)
    with pytest.raises(ValueError, match="directions"):
        F.cut(nodes, tets, mouth=[[2.5, -1.0, 5.0], [2.5, 6.0, 5.0]], directions=[0, 0, 0], depths_mm=2.0)
    with pytest.raises(ValueError, match="depth"):
        F.cut(nodes, tets, mouth=[[2.5, -1.0, 5.0], [2.5, 6.0, 5.0]], directions=[0, 0, -1], depths_mm=-1.0)
    with pytest.raises(ValueError, match="depths_mm"):
        F.cut(nodes, tets, mouth=[[2.5, -1.0, 5.0], [2.5, 6.0, 5.0]], directions=[0, 0, -1], depths_mm=np.ones(3))


P2ILF = REPO.parent / "shared" / "data" / "meshes" / "p2ilf" / "patient2_1_3d-liver-model.obj"


def read_obj(path):
    v, f = [], []
    for line in path.read_text().splitlines():
        p = line.split()
        if p and p[0] == "v":
            v.append([float(c) for c in p[1:4]])
        elif p and p[0] == "f":
            idx = [int(c.split("/")[0]) - 1 for c in p[1:]]
            f += [[idx[0], idx[k], idx[k + 1]] for k in range(1, len(idx) - 1)]
    return np.array(v), np.array(f, np.int64)


def test_tetrahedralize_the_p2ilf_liver():
    """The real patient liver (mm) at 8 mm: the enclosed volume against numpy's divergence-theorem sum, every
    tetrahedron positive, min dihedral ≥ 10°, the volume within 1 % of the surface's."""
    if not P2ILF.is_file():
        pytest.skip(f"SKIP: the P2ILF liver is absent ({P2ILF}); see ../shared/data/README")
    v, f = read_obj(P2ILF)
    vol_surface = abs(signed_volume(v, f))
    assert 2.0e6 < vol_surface < 3.0e6  # ≈ 2,509 cm³
    nodes, tets, rep = F.tetrahedralize(v, f, edge_mm=8.0)
    vol = tet_volumes(nodes, tets)
    assert (vol > 0).all() and rep["inverted"] == 0
    assert rep["surface_volume_mm3"] == pytest.approx(vol_surface, rel=1e-9)
    assert rep["volume_mm3"] == pytest.approx(vol.sum(), rel=1e-12)
    assert abs(vol.sum() / vol_surface - 1.0) < 0.01
    assert rep["min_dihedral_deg"] >= 10.0 - 1e-9
    assert len(nodes) > 5000
