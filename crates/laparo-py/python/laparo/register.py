"""RODS-MPM deformable registration (thesis Ch. 5): an organ (mesh file or particles, mm), source
landmark groups and their targets → optimised initial velocities v₀ of the MPM simulation whose
final particles match the targets (loss eq. 5.10), with the Neo-Hookean material of eq. 5.3.

* :func:`register` — in memory: the registered particle positions, v₀, J = det F, history;
* :func:`run` — ``laparo register``: every output file of the CLI in ``out`` and ``report.json``.

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
    crack: Optional[Union[PathLike, Tuple[np.ndarray, np.ndarray]]] = None,
    crack_band_mm: Optional[float] = None,
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
    ``kinetic_weight`` κ adds the least-action prior κ · mean |v₀ T Δt|² / (2 Δx) to eq. 5.10).

    ``crack``: an incision the organ is cut along, as a triangle mesh file or (vertices (N, 3) mm, faces
    (F, 3)) in the organ's frame, normals from one lip to the other. Particles within ``crack_band_mm``
    (default 3 Δx) take side ±1 and get their own grid velocity field (laparo-mpm's two-field grid), so the
    lips can separate; ``crack`` in the result gives the particle count per side, ``crack_side`` the labels.

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
        _opt_float(max_step_dx), float(target_mean_mm), memory_gb, float(kinetic_weight), _crack(crack),
        _opt_float(crack_band_mm),
    )


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
    crack: Optional[Union[PathLike, Tuple[np.ndarray, np.ndarray]]] = None,
    crack_band_mm: Optional[float] = None,
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
        float(kinetic_weight), _crack(crack), _opt_float(crack_band_mm),
    )
