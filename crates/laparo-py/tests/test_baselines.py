"""laparo.register.arap / drbc / lddmm (the incision benchmark's mesh baselines) from Python, against
independent numbers: a rigid motion of the landmarks is recovered at every node (ARAP), zero landmark
displacement is the identity (DRBC), noiseless landmarks are shot onto their targets (LDDMM), landmarks
given as points are reproduced by their barycentric weights, and bad input is named."""
import numpy as np
import pytest

import laparo
from test_fem import box_tets

R = laparo.register


def rigid(th=0.45, t=(3.0, -2.0, 5.0)):
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    rot = np.eye(3) + np.sin(th) * k + (1 - np.cos(th)) * k @ k  # Rodrigues
    return rot, np.array(t)


@pytest.fixture(scope="module")
def mesh():
    return box_tets([4, 3, 3], 5.0)  # 20 × 15 × 15 mm


@pytest.mark.parametrize("energy", ["spokes", "elements"])
def test_arap_recovers_a_rigid_motion(mesh, energy):
    nodes, tets = mesh
    rot, t = rigid()
    ids = np.array([0, 7, 19, 44, 61, 79], np.int64)
    inner = np.array([[3.3, 7.1, 2.2], [17.9, 0.4, 14.6], [10.0, 7.5, 5.0]])  # points, located by barycentric weights
    lm = {"ids": ids, "inner": inner}
    targets = {"ids": nodes[ids] @ rot.T + t, "inner": inner @ rot.T + t}
    out = R.arap(nodes, tets, lm, targets, energy=energy, iterations=500, tolerance_mm=1e-10)
    want = nodes @ rot.T + t
    assert out["positions"].shape == nodes.shape
    assert np.abs(out["positions"] - want).max() < 1e-6
    rep = out["report"]
    assert rep["initial_mean_distance_mm"] > 5.0 and rep["mean_distance_mm"] < 1e-6


def test_drbc_with_zero_landmark_displacement_is_the_identity(mesh):
    nodes, tets = mesh
    ids = np.array([3, 30, 60, 77], np.int64)
    out = R.drbc(nodes, tets, {"a": ids}, {"a": nodes[ids]}, fixed=[0, 1])
    assert np.abs(out["positions"] - nodes).max() < 1e-9
    assert out["report"]["mean_distance_mm"] < 1e-9


def test_drbc_pulls_landmarks_onto_a_polyline_and_respects_fixed_nodes(mesh):
    nodes, tets = mesh
    top = np.flatnonzero((np.abs(nodes[:, 2] - 15.0) < 1e-9) & (np.abs(nodes[:, 1] - 5.0) < 1e-9))
    bottom = np.flatnonzero(np.abs(nodes[:, 2]) < 1e-9)
    line = np.array([[-5.0, 5.0, 17.0], [25.0, 5.0, 17.0]])  # 2 mm above the top row
    out = R.drbc(nodes, tets, {"row": top}, [{"name": "row", "type": "polyline", "points": line}], fixed=bottom)
    x = out["positions"]
    assert np.abs(x[bottom] - nodes[bottom]).max() == 0.0
    rep = out["report"]
    assert rep["initial_mean_distance_mm"] == pytest.approx(2.0, abs=1e-12)
    assert rep["mean_distance_mm"] < 0.5 * rep["initial_mean_distance_mm"]
    # the reported distance is the mean distance of the landmark nodes to the line (numpy)
    d = np.hypot(x[top, 1] - 5.0, x[top, 2] - 17.0)
    assert rep["mean_distance_mm"] == pytest.approx(d.mean(), rel=1e-9)


def test_lddmm_shoots_noiseless_landmarks_onto_their_targets(mesh):
    nodes, tets = mesh
    ids = np.array([5, 22, 48, 66], np.int64)
    shift = np.array([[2.0, 0.0, 1.0], [1.5, -1.0, 0.5], [0.0, 2.0, -1.0], [-1.0, 0.5, 2.0]])
    out = R.lddmm(nodes, tets, {"a": ids}, {"a": nodes[ids] + shift}, sigma_mm=10.0, gamma=1e-6, iterations=500)
    assert np.linalg.norm(out["positions"][ids] - (nodes[ids] + shift), axis=1).max() < 0.01
    # the flow is smooth: a node far from every landmark moves less than the landmarks do
    far = np.argmax(np.linalg.norm(nodes[:, None] - nodes[ids][None], axis=2).min(axis=1))
    assert np.linalg.norm(out["positions"][far] - nodes[far]) < np.linalg.norm(shift, axis=1).max()


@pytest.mark.parametrize("method", ["arap", "drbc"])
def test_prescribed_boundary_in_a_rigid_motion_moves_the_interior_rigidly(mesh, method):
    """Hard constraints only (libigl's b / bc): the boundary nodes placed by a rigid motion leave the interior
    at the zero-energy state, the same motion. DRBC starts from the rest mesh with the fixed nodes moved,
    which must not invert a tetrahedron (a clear error otherwise): a small motion for it."""
    nodes, tets = mesh
    rot, t = rigid() if method == "arap" else rigid(0.05, (0.3, -0.2, 0.5))
    lo, hi = nodes.min(axis=0), nodes.max(axis=0)
    on_box = np.flatnonzero(((np.abs(nodes - lo) < 1e-9) | (np.abs(nodes - hi) < 1e-9)).any(axis=1))
    assert 0 < len(on_box) < len(nodes)
    want = nodes @ rot.T + t
    kw = dict(iterations=500, tolerance_mm=1e-10) if method == "arap" else {}
    out = getattr(R, method)(nodes, tets, fixed=on_box, fixed_positions=want[on_box], **kw)
    assert np.abs(out["positions"][on_box] - want[on_box]).max() == 0.0
    assert np.abs(out["positions"] - want).max() < 1e-6


def test_errors_name_the_argument(mesh):
    nodes, tets = mesh
    lm = {"a": np.array([1, 2], np.int64)}
    tg = {"a": nodes[[1, 2]]}
    with pytest.raises(ValueError, match="outside the mesh"):
        R.arap(nodes, tets, {"a": [[50.0, 0.0, 0.0]]}, {"a": [[51.0, 0.0, 0.0]]})
    with pytest.raises(ValueError, match="landmarks"):
        R.arap(nodes, tets, {"a": np.array([1, 10_000], np.int64)}, tg)
    with pytest.raises(ValueError, match="tets"):
        R.drbc(nodes, tets[:, :3], lm, tg)
    with pytest.raises(ValueError, match="energy"):
        R.arap(nodes, tets, lm, tg, energy="cotan")
    with pytest.raises(ValueError, match="sigma_mm"):
        R.lddmm(nodes, tets, lm, tg, sigma_mm=0.0)
    with pytest.raises(ValueError, match="fixed"):
        R.drbc(nodes, tets, lm, tg, fixed=[len(nodes)])
    with pytest.raises(ValueError, match="targets"):
        R.arap(nodes, tets, lm, {"b": nodes[[1, 2]]})
    with pytest.raises(ValueError, match="inverted"):
        R.drbc(nodes, tets, fixed=[0, 1], fixed_positions=nodes[[1, 0]])
    with pytest.raises(ValueError, match="fixed_positions"):
        R.arap(nodes, tets, fixed=[0, 1], fixed_positions=nodes[:3])
    with pytest.raises(ValueError, match="targets"):
        R.arap(nodes, tets, lm)
    with pytest.raises(ValueError, match="nodes"):
        R.arap(np.where(nodes == 0.0, np.nan, nodes), tets, lm, tg)
