"""Volume meshing and the quasi-static Neo-Hookean FEM of the in-silico incision benchmark (thesis
§5.4.2, eq. 5.3), on NumPy arrays in mm:

* :func:`tetrahedralize` — a closed triangle surface → tetrahedra on a body-centred cubic lattice with
  boundary snapping (licence-clean; min dihedral ≥ ``min_dihedral_deg``) and a quality report;
* :func:`quality` — the quality report of any tetrahedral mesh (dihedral angles, edges, volume; with
  the surface: volume error and boundary distances);
* :func:`cut` — an incision: crack the mesh along a blade swept inward from a mouth polyline on the
  surface (crack nodes duplicated, so the two lips are disconnected), with lip polylines and landmarks;
  :func:`crack_pressure` — the equal and opposite pressure on the two crack faces that opens it;
* :func:`solve` — static equilibrium of a nearly incompressible Neo-Hookean solid (E kPa, ν) on the
  quadratic (TET10) tetrahedra of a linear mesh: fixed vertices, dead face tractions (kPa) and nodal
  forces (mN) ramped over load increments, Newton with a line search to ‖residual‖ ≤ ``rel_tol`` of
  the load. TET10 does not lock at ν = 0.49 (linear tetrahedra are ≈ 2.6× too stiff there).

Units: lengths mm, stresses and tractions kPa (= mN/mm²), forces mN. The same library calls as
``laparo mesh tetra`` and ``laparo fem solve``.
"""
from __future__ import annotations

from typing import Any, Dict, Optional, Sequence, Tuple, Union

import numpy as np

from . import _laparo


def _f64(a: Any, what: str, cols: Optional[int] = None) -> np.ndarray:
    x = np.ascontiguousarray(np.asarray(a, dtype=np.float64))
    if cols is not None and (x.ndim != 2 or x.shape[1] != cols):
        raise ValueError(f"{what}: expected shape (N, {cols}), got {x.shape}")
    return x


def _idx(a: Any, what: str, cols: Optional[int] = None) -> np.ndarray:
    x = np.asarray(a)
    if x.size and x.dtype.kind not in "iu":
        raise TypeError(f"{what}: expected integer indices, got dtype {x.dtype}")
    if cols is not None and (x.ndim != 2 or x.shape[1] != cols):
        raise ValueError(f"{what}: expected shape (M, {cols}), got {x.shape}")
    return np.ascontiguousarray(x, dtype=np.float64)


def tetrahedralize(
    vertices: np.ndarray,
    faces: np.ndarray,
    edge_mm: float = 6.0,
    min_dihedral_deg: float = 10.0,
    snap_passes: int = 4,
) -> Tuple[np.ndarray, np.ndarray, Dict[str, Any]]:
    """Tetrahedralise the closed, consistently oriented surface (``vertices`` (N, 3) mm, ``faces``
    (F, 3) int) with target edge ``edge_mm``. Returns ``(nodes (M, 3) float64 mm, tets (T, 4) int64,
    report)``; every tetrahedron is positively oriented. ``report``: nodes, tets, inverted,
    min_dihedral_deg, dihedral percentiles and histogram, edge lengths, volume_mm3 and
    volume_rel_error against the surface, boundary distances. An open surface raises ValueError."""
    return _laparo.fem_tetrahedralize(
        _f64(vertices, "vertices", 3), _idx(faces, "faces", 3), float(edge_mm), float(min_dihedral_deg), int(snap_passes)
    )


def quality(
    nodes: np.ndarray, tets: np.ndarray, surface: Optional[Tuple[np.ndarray, np.ndarray]] = None
) -> Dict[str, Any]:
    """Quality report of the tetrahedral mesh (``nodes`` (N, 3) mm, ``tets`` (T, 4) int); with
    ``surface`` = (vertices, faces) of the closed surface it approximates, also its volume error and
    the boundary nodes' distances to it."""
    sv = sf = None
    if surface is not None:
        sv, sf = surface
        sv, sf = _f64(sv, "surface vertices", 3), _idx(sf, "surface faces", 3)
    return _laparo.fem_quality(_f64(nodes, "nodes", 3), _idx(tets, "tets", 4), sv, sf)


def solve(
    nodes: np.ndarray,
    tets: np.ndarray,
    fixed: Union[np.ndarray, Sequence[int]],
    face_tractions: Optional[Tuple[np.ndarray, np.ndarray]] = None,
    nodal_forces: Optional[Tuple[np.ndarray, np.ndarray]] = None,
    young_kpa: float = 4.1,
    poisson: float = 0.49,
    steps: int = 20,
    rel_tol: float = 1e-8,
    quadrature: str = "degree2",
    solver: str = "auto",
) -> Dict[str, Any]:
    """Equilibrium displacement of the Neo-Hookean solid (eq. 5.3, ``young_kpa``, ``poisson``) on the
    TET10 mesh of (``nodes`` (N, 3) mm, ``tets`` (T, 4) int), with the vertices ``fixed`` held at rest.

    Loads (dead, reference configuration, scaled together over ``steps`` increments):
    ``face_tractions`` = (faces (F, 3) int, tractions) with tractions (F, 3) kPa vectors or (F,)
    pressures along each face's normal (b − a) × (c − a); ``nodal_forces`` = (vertices (K,) int,
    forces (K, 3) mN). ``solver``: ``auto`` (sparse Cholesky when its factor is small, else two-level
    conjugate gradients), ``direct`` or ``two-level``; ``quadrature``: ``degree2`` or ``degree5``.

    Returns ``displacement`` (N, 3) mm at the vertices, ``tet10_nodes`` and ``displacement_tet10``
    (M, 3) mm (vertices first, then one node per edge), and ``report`` (per-increment Newton
    residuals, min_j, max_displacement_mm, free_dofs, timings). Raises ValueError naming the
    argument on bad input, and when an increment cannot converge (e.g. loads that invert elements).
    """
    ff = ft = fv = fm = None
    if face_tractions is not None:
        f, t = face_tractions
        ff, ft = _idx(f, "face_tractions faces", 3), _f64(t, "face_tractions tractions")
    if nodal_forces is not None:
        v, m = nodal_forces
        fv, fm = _idx(v, "nodal_forces vertices"), _f64(m, "nodal_forces forces", 3)
    return _laparo.fem_solve(
        _f64(nodes, "nodes", 3), _idx(tets, "tets", 4), _idx(fixed, "fixed"), ff, ft, fv, fm, float(young_kpa),
        float(poisson), int(steps), float(rel_tol), str(quadrature), str(solver),
    )


def cut(
    nodes: np.ndarray,
    tets: np.ndarray,
    mouth: np.ndarray,
    directions: np.ndarray,
    depths_mm: Union[float, np.ndarray],
    overshoot_mm: float = 2.0,
    landmarks: int = 0,
) -> Dict[str, Any]:
    """Crack the tetrahedral mesh (``nodes`` (N, 3) mm, ``tets`` (T, 4) int, positively oriented, e.g.
    from :func:`tetrahedralize`) along the blade swept from ``mouth`` (P, 3) mm, the incision's polyline on
    the organ surface, inward along ``directions`` ((3,) or (P, 3)) to ``depths_mm`` (scalar or (P,)),
    extended ``overshoot_mm`` outward. Faces between tetrahedra on opposite sides of the blade separate;
    crack nodes move onto the blade where that keeps the min dihedral ≥ 10°.

    Returns ``nodes`` / ``tets`` (the cut mesh), ``crack_faces_a`` / ``crack_faces_b`` (F, 3) (wound
    outward from their own side), ``lips`` (two arrays of node ids: the mouth on side A and B),
    ``original_node`` (cut node → input node), ``tet_side`` (0, or 1 / 2 for a tet owning a crack face of
    side A / B), ``front_nodes``, ``blade_vertices`` / ``blade_faces``; with ``landmarks`` = L > 0, L lip
    landmarks (L/2 per lip, at arc lengths (k + ½) ℓ / (L/2)): ``landmark_side``, ``landmark_nodes``
    (L, 2) and ``landmark_t`` (the point (1 − t) x[a] + t x[b]), ``landmark_positions`` (L, 3) mm.
    A blade that misses the mesh raises ValueError."""
    d = depths_mm if np.isscalar(depths_mm) else _f64(depths_mm, "depths_mm")
    return _laparo.fem_cut(
        _f64(nodes, "nodes", 3), _idx(tets, "tets", 4), _f64(mouth, "mouth", 3), _f64(directions, "directions"),
        float(d) if np.isscalar(d) else d, float(overshoot_mm), int(landmarks),
    )


def crack_pressure(cut_mesh: Dict[str, Any], p_kpa: float) -> Tuple[np.ndarray, np.ndarray]:
    """Equal and opposite pressure ``p_kpa`` on the two crack faces of a :func:`cut` result, each pushing
    into its own side (the forces that open the incision, thesis §5.4.2), as ``face_tractions`` for
    :func:`solve`: (faces (F, 3), pressures (F,) along (b − a) × (c − a), i.e. −p on the outward faces)."""
    faces = np.concatenate([cut_mesh["crack_faces_a"], cut_mesh["crack_faces_b"]])
    return faces, np.full(len(faces), -float(p_kpa))
