"""RODS-MPM deformable registration (thesis Ch. 5): an organ (mesh file or particles, mm), source
landmark groups and their targets → optimised initial velocities v₀ of the MPM simulation whose
final particles match the targets (loss eq. 5.10), with the Neo-Hookean material of eq. 5.3.

* :func:`register` — in memory: the registered particle positions, v₀, J = det F, history;
* :func:`run` — ``laparo register``: every output file of the CLI in ``out`` and ``report.json``;
* :func:`arap`, :func:`drbc`, :func:`lddmm` — the mesh-based baselines of the incision benchmark
  (§5.4.2, Table 5.1) on a tetrahedral mesh, scored with the same eq. 5.10 distance.

Landmarks: a file (JSON ``{"groups": [...]}`` or CSV ``group,x,y,z``), a dict ``name → (K, 3)``
array, or a list of dicts ``{"name", "points", "weight"}``. Targets: a file (JSON groups matched by
name, or a PLY/OBJ surface / point cloud shared by every group), a dict ``name → (K, 3)`` array
(paired points, one per landmark), or a list of dicts ``{"name", "type": "points" | "polyline" |
"cloud" | "surface", "points", "faces"}``.
"""
from __future__ import annotations

import os
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from . import _laparo
from .fem import _idx

PathLike = Union[str, "os.PathLike[str]"]
Landmarks = Union[PathLike, Mapping[str, Any], Sequence[Mapping[str, Any]]]
Targets = Union[PathLike, Mapping[str, Any], Sequence[Mapping[str, Any]]]


def _is_path(x: Any) -> bool:
    return isinstance(x, (str, os.PathLike))


def _points(p: Any, what: str) -> np.ndarray:
    a = np.asarray(p, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"{what}: expected (K, 3) points in mm, got shape {a.shape}")
    return np.ascontiguousarray(a)


def _opt_float(v: Optional[float]) -> Optional[float]:
    return None if v is None else float(v)


def _landmarks(lm: Landmarks) -> Any:
    if _is_path(lm):
        return os.fspath(lm)
    if isinstance(lm, Mapping):
        return [(str(k), _points(v, f"landmarks[{k!r}]"), 1.0) for k, v in lm.items()]
    out = []
    for i, g in enumerate(lm):
        name = str(g.get("name", f"group{i}"))
        out.append((name, _points(g["points"], f"landmarks[{name!r}]"), float(g.get("weight", 1.0))))
    return out


def _targets(tg: Targets) -> Any:
    if _is_path(tg):
        return os.fspath(tg)
    if isinstance(tg, Mapping):
        return [(str(k), "points", _points(v, f"targets[{k!r}]"), None) for k, v in tg.items()]
    out = []
    for i, g in enumerate(tg):
        name = str(g.get("name", f"group{i}"))
        faces = g.get("faces")
        if faces is not None:
            faces = np.ascontiguousarray(np.asarray(faces, dtype=np.float64))
        out.append((name, str(g.get("type", "points")), _points(g["points"], f"targets[{name!r}]"), faces))
    return out


def _crack(crack):
    """A crack surface as the extension takes it: a path, or (vertices float64 (N, 3), faces (F, 3))."""
    if crack is None:
        return None
    if isinstance(crack, (str, os.PathLike)):
        return os.fspath(crack)
    try:
        vertices, faces = crack
    except (TypeError, ValueError):
        raise TypeError("crack: expected a path or (vertices, faces)") from None
    return (_points(vertices, "crack vertices"), np.ascontiguousarray(np.asarray(faces, dtype=np.float64)))


def register(
    landmarks: Landmarks,
    targets: Targets,
    organ: Optional[PathLike] = None,
    particles: Optional[np.ndarray] = None,
    spacing_mm: float = 3.0,
    dx_mm: Optional[float] = None,
    optimizer: str = "lbfgs",
    iterations: Optional[int] = None,
    roi: Optional[str] = None,
    youngs_modulus_kpa: float = 4.1,
    poisson_ratio: float = 0.49,
    density_kg_m3: float = 1000.0,
    steps: int = 200,
    dt_s: Optional[float] = None,
    region_weight: float = 0.0,
    joint_e: bool = False,
    smoothing_dx: Optional[float] = None,
    max_step_dx: Optional[float] = None,
    target_mean_mm: float = 0.0,
    memory_gb: Optional[float] = None,
    kinetic_weight: float = 0.0,
    at_rest_weight: float = 0.0,
    crack: Optional[Union[PathLike, Tuple[np.ndarray, np.ndarray]]] = None,
    crack_band_mm: Optional[float] = None,
    unknown: str = "velocity",
    damping_per_horizon: float = 10.0,
    thesis_landmarks: bool = False,
) -> Dict[str, Any]:
    """Register in memory (nothing is written).

    The organ is a closed surface (OBJ/PLY/STL) or tetrahedral mesh (.msh/.vtk) file ``organ``,
    sampled at ``spacing_mm``, or ``particles`` (N, 3) mm already sampled at ``spacing_mm``. The
    options are those of ``laparo register`` (grid cell ``dx_mm`` = 2 × spacing by default; Δt
    from the CFL condition unless ``dt_s``; ``roi`` = ``"ball:x,y,z,r"`` or
    ``"box:x0,y0,z0,x1,y1,z1"`` mm, its boundary particles fixed; ``optimizer`` = ``lbfgs``,
    ``tear`` (unsmoothed, strong Wolfe, distance continuation: targets that pull neighbouring
    particles apart), ``adam`` or ``thesis-gd``; ``smoothing_dx`` and ``max_step_dx`` default to
    the optimiser's preset: 2 and 0.5 Δx for ``lbfgs``/``adam``, 0 and 16 Δx for ``tear``;
    ``kinetic_weight`` κ adds the least-action prior κ · mean |v₀ T Δt|² / (2 Δx) to eq. 5.10;
    ``at_rest_weight`` λ the at-rest prior λ · Σ m |v_T T Δt|² / (2 M Δx) on the final kinetic energy).

    ``crack``: an incision the organ is cut along, as a triangle mesh file or (vertices (N, 3) mm, faces
    (F, 3)) in the organ's frame, normals from one lip to the other. Particles within ``crack_band_mm``
    (default 3 Δx) take side ±1 and get their own grid velocity field (laparo-mpm's two-field grid), so the
    lips can separate; ``crack`` in the result gives the particle count per side, ``crack_side`` the labels.
    :func:`assumed_cut` builds one from a lip polyline alone.

    ``unknown``: what RODS-MPM solves for (§5.3.1): ``"velocity"`` (v₀, the thesis) or ``"loads"`` (a
    time-constant, self-equilibrated force density on the particles the crack labels, or on every free
    particle without a crack, from rest with mass-proportional damping ζ T Δt = ``damping_per_horizon``, so the
    registered shape is an equilibrium: rung L3 of the ladder; ``kinetic_weight`` is then the loads' L2 prior;
    the result's ``loads`` holds them). Landmarks are scored at their own material points (nearest particle +
    rest offset) unless ``thesis_landmarks`` (the nearest particle itself, as the thesis).

    Returns ``positions`` (registered particles, N×3 mm, model coordinates), ``rest_positions``,
    ``velocities`` (v₀, mm/s), ``final_velocities``, ``j`` (det F), ``history`` (per iteration:
    loss, mean_distance mm, …), ``mean_distance_mm`` (before, after), ``residual_before`` /
    ``residual_after`` per group, ``stop_reason``, ``youngs_modulus_kpa`` and the set-up
    (``dx_mm``, ``dt_s``, ``n_grid``, ``steps``, ``offset_mm``: grid = model + offset).
    """
    return _laparo.register_arrays(
        _landmarks(landmarks), _targets(targets), None if organ is None else os.fspath(organ), particles,
        float(spacing_mm), dx_mm, optimizer, iterations, roi, float(youngs_modulus_kpa), float(poisson_ratio),
        float(density_kg_m3), int(steps), dt_s, float(region_weight), bool(joint_e), _opt_float(smoothing_dx),
        _opt_float(max_step_dx), float(target_mean_mm), memory_gb, float(kinetic_weight), float(at_rest_weight), _crack(crack),
        _opt_float(crack_band_mm), str(unknown), float(damping_per_horizon), bool(thesis_landmarks),
    )


def assumed_cut(organ: PathLike, lip: Any, depth_mm: float) -> Tuple[np.ndarray, np.ndarray]:
    """The cut surface a system can assume from one lip alone (what François et al. assume): the lip's
    source polyline ``lip`` ((K, 3) mm, on the organ's surface) swept along the surface's inward normal to
    ``depth_mm`` (from 2 mm outside), as ``(vertices (2K, 3) mm, faces (2K-2, 3))``, ready for ``crack=``.
    ``organ`` is the organ's closed surface or tetrahedral mesh file (its boundary gives the normals)."""
    return _laparo.register_assumed_cut(os.fspath(organ), _points(lip, "lip"), float(depth_mm))


def run(
    organ: PathLike,
    landmarks: Landmarks,
    targets: Targets,
    out: PathLike,
    spacing_mm: float = 3.0,
    dx_mm: Optional[float] = None,
    optimizer: str = "lbfgs",
    iterations: Optional[int] = None,
    roi: Optional[str] = None,
    tumour: Optional[PathLike] = None,
    image: Optional[PathLike] = None,
    camera: Optional[PathLike] = None,
    youngs_modulus_kpa: float = 4.1,
    poisson_ratio: float = 0.49,
    density_kg_m3: float = 1000.0,
    steps: int = 200,
    dt_s: Optional[float] = None,
    region_weight: float = 0.0,
    joint_e: bool = False,
    smoothing_dx: Optional[float] = None,
    max_step_dx: Optional[float] = None,
    target_mean_mm: float = 0.0,
    resume: bool = False,
    checkpoint_every: int = 5,
    memory_gb: Optional[float] = None,
    kinetic_weight: float = 0.0,
    at_rest_weight: float = 0.0,
    crack: Optional[Union[PathLike, Tuple[np.ndarray, np.ndarray]]] = None,
    crack_band_mm: Optional[float] = None,
    unknown: str = "velocity",
    damping_per_horizon: float = 10.0,
    thesis_landmarks: bool = False,
) -> Dict[str, Any]:
    """``laparo register --organ … --landmarks … --target … --out …``: writes
    particles_registered.ply, particles_rest.ply, surface_registered.ply, organ_deformed.obj
    (surface organs), tumour_deformed.obj, overlay.png (``image`` + ``camera``), loss.csv,
    loss.png, checkpoint_v0.json and report.json into ``out``; returns report.json as a dict.
    Arguments as :func:`register` and the CLI's options."""
    p = lambda x: None if x is None else os.fspath(x)  # noqa: E731
    return _laparo.register_run(
        os.fspath(organ), _landmarks(landmarks), _targets(targets), os.fspath(out), float(spacing_mm), dx_mm, optimizer,
        iterations, roi, p(tumour), p(image), p(camera), float(youngs_modulus_kpa), float(poisson_ratio),
        float(density_kg_m3), int(steps), dt_s, float(region_weight), bool(joint_e), _opt_float(smoothing_dx),
        _opt_float(max_step_dx), float(target_mean_mm), bool(resume), int(checkpoint_every), memory_gb,
        float(kinetic_weight), float(at_rest_weight), _crack(crack), _opt_float(crack_band_mm), str(unknown),
        float(damping_per_horizon), bool(thesis_landmarks),
    )


def _opt_targets(tg: Any) -> Any:
    return None if tg is None else _targets(tg)


def _opt_points(p: Any) -> Optional[np.ndarray]:
    return None if p is None else _points(p, "fixed_positions")


def _mesh_landmarks(lm: Any, nodes: np.ndarray) -> Any:
    """Landmarks of a mesh baseline: as :func:`register`'s, and in a dict a group may also be a 1-D
    integer array of node ids (those nodes' rest positions)."""
    if lm is None:
        return None
    if isinstance(lm, Mapping):
        out = {}
        for k, v in lm.items():
            a = np.asarray(v)
            if a.ndim == 1 and a.dtype.kind in "iu":
                if a.size and (a.min() < 0 or a.max() >= len(nodes)):
                    raise ValueError(f"landmarks[{k!r}]: node ids must be in 0..{len(nodes)}")
                out[k] = nodes[a]
            else:
                out[k] = v
        lm = out
    return _landmarks(lm)


def _mesh(nodes: Any, tets: Any) -> Tuple[np.ndarray, np.ndarray]:
    return _points(nodes, "nodes"), _idx(tets, "tets", 4)


def _fixed(fixed: Any) -> Optional[np.ndarray]:
    return None if fixed is None else _idx(np.asarray(fixed).reshape(-1), "fixed")


def arap(
    nodes: np.ndarray,
    tets: np.ndarray,
    landmarks: Optional[Landmarks] = None,
    targets: Optional[Targets] = None,
    fixed: Optional[np.ndarray] = None,
    fixed_positions: Optional[np.ndarray] = None,
    energy: str = "spokes",
    weights: str = "cotangent",
    landmark_weight: Optional[float] = None,
    iterations: int = 200,
    tolerance_mm: float = 1e-3,
    outside_tolerance_mm: float = 1.0,
) -> Dict[str, Any]:
    """Volumetric as-rigid-as-possible registration (Sorkine & Alexa 2007) of the tetrahedral mesh
    (``nodes`` (N, 3) mm, ``tets`` (T, 4) int): local–global iterations on the ARAP energy
    (``energy`` = ``spokes``, libigl's ``ARAP_ENERGY_TYPE_SPOKES``, or ``elements``, per-tet rotations)
    plus a soft landmark term w · Σ dist², the closest target points re-linearised every iteration.

    ``landmarks`` as :func:`register`'s (points in mm inside or on the mesh; a point outside by at most
    ``outside_tolerance_mm`` takes the closest mesh point), or per group a 1-D integer array of node
    ids; each point is a material point (barycentric in its tetrahedron; a point on a crack face, where
    the two lips' duplicated nodes coincide, belongs to either side: give lip landmarks as node ids). ``targets`` as
    :func:`register`'s (paired points, polyline, cloud, surface). ``fixed``: node ids held at rest, or at
    ``fixed_positions`` (K, 3) mm when given (hard constraints, libigl's ``b`` / ``bc``); with fixed
    nodes, ``landmarks`` and ``targets`` may be None.
    ``landmark_weight`` None: 100 × E_ARAP(unit stretch) / (K L²).

    Returns ``positions`` (N, 3) mm, the deformed nodes, and ``report`` (iterations,
    initial_mean_distance_mm, mean_distance_mm, history_mm, converged, seconds)."""
    n, t = _mesh(nodes, tets)
    return _laparo.register_arap(
        n, t, _mesh_landmarks(landmarks, n), _opt_targets(targets), _fixed(fixed), _opt_points(fixed_positions), str(energy), str(weights),
        _opt_float(landmark_weight), int(iterations), float(tolerance_mm), float(outside_tolerance_mm),
    )


def drbc(
    nodes: np.ndarray,
    tets: np.ndarray,
    landmarks: Optional[Landmarks] = None,
    targets: Optional[Targets] = None,
    fixed: Optional[np.ndarray] = None,
    fixed_positions: Optional[np.ndarray] = None,
    young_kpa: float = 4.1,
    poisson: float = 0.49,
    lam: Optional[float] = None,
    iterations: int = 50,
    outside_tolerance_mm: float = 1.0,
) -> Dict[str, Any]:
    """DRBC (Collins 2020): minimise Σ dist² + λ Σ_e V_e ψ(F_e) with the Neo-Hookean energy ψ of eq. 5.3
    (``young_kpa``, ``poisson``) on the tetrahedra, by Newton with an exact distance Hessian and an
    inversion-safe line search. ``lam`` None: 0.01 K L² / (V μ). Other arguments and the result as
    :func:`arap`; François et al. [2021] is this on a mesh cut along the assumed resection."""
    n, t = _mesh(nodes, tets)
    return _laparo.register_drbc(
        n, t, _mesh_landmarks(landmarks, n), _opt_targets(targets), _fixed(fixed), _opt_points(fixed_positions), float(young_kpa), float(poisson),
        _opt_float(lam), int(iterations), float(outside_tolerance_mm),
    )


def lddmm(
    nodes: np.ndarray,
    tets: np.ndarray,
    landmarks: Optional[Landmarks] = None,
    targets: Optional[Targets] = None,
    fixed: Optional[np.ndarray] = None,
    fixed_positions: Optional[np.ndarray] = None,
    sigma_mm: float = 20.0,
    steps: int = 10,
    gamma: float = 0.01,
    iterations: int = 300,
    outside_tolerance_mm: float = 1.0,
) -> Dict[str, Any]:
    """Landmark LDDMM (Beg 2005): geodesic shooting of momenta at the source landmarks with a Gaussian
    kernel of width ``sigma_mm`` over ``steps`` Euler steps, minimising Σ dist² + ``gamma`` × the geodesic
    energy by L-BFGS with the adjoint gradient; every node is advected by the same flow. Other arguments
    and the result as :func:`arap`."""
    n, t = _mesh(nodes, tets)
    return _laparo.register_lddmm(
        n, t, _mesh_landmarks(landmarks, n), _opt_targets(targets), _fixed(fixed), _opt_points(fixed_positions), float(sigma_mm), int(steps),
        float(gamma), int(iterations), float(outside_tolerance_mm),
    )
