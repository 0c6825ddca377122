"""Stereo geometry and evaluation (thesis §3.3.7–3.3.8, Tables 3.7–3.8).

Calibrations are dicts with ``width``, ``height``, ``k_left``, ``k_right`` (3×3, px),
``dist_left``, ``dist_right`` (OpenCV order k1 k2 p1 p2 k3, optional), ``r`` (3×3) and
``t_mm`` (3,) with X_right = R X_left + t; :func:`read_calibration` returns one from a file.

Matching: :func:`match` is semi-global matching (census cost, 4 or 8 paths, signed range
d = x_L − x_R ∈ [d_min, d_max), optional vertical tolerance for raw near-rectified pairs) — the
computation of ``laparo stereo match``; :func:`self_rectify` rectifies a raw pair without a
calibration from SIFT matches (quasi-Euclidean or Hartley).
"""
from __future__ import annotations

import os
from typing import Any, Dict, Optional, Sequence, Tuple, Union

import numpy as np

from . import _laparo


def read_calibration(
    path: Union[str, os.PathLike],
    path2: Optional[Union[str, os.PathLike]] = None,
    width: Optional[int] = None,
    height: Optional[int] = None,
) -> Dict[str, Any]:
    """Read a stereo calibration (laparo JSON, OpenCV FileStorage YAML/JSON, EndoVis txt; or two
    files) as a calibration dict."""
    return _laparo.stereo_read_calibration(os.fspath(path), None if path2 is None else os.fspath(path2), width, height)


def rectify(
    left: np.ndarray,
    right: np.ndarray,
    calib: Dict[str, Any],
    alpha: float = 0.0,
    align_principal_points: bool = True,
) -> Dict[str, Any]:
    """Rectify a calibrated pair (uint8 or float images). Returns ``left``, ``right``,
    ``valid_left``, ``valid_right`` and ``info`` (rectified K, R1, R2, P1, P2, Q, focal,
    baseline, doffs — the ``rectification.json`` of ``laparo stereo rectify``)."""
    return _laparo.stereo_rectify(left, right, calib, float(alpha), bool(align_principal_points))


def disparity_to_depth(
    disparity: np.ndarray, f_px: float, baseline_mm: float, cx_left: float = 0.0, cx_right: float = 0.0
) -> np.ndarray:
    """Depth (mm) z = f b / (d − (c_x^L − c_x^R)) (§3.3.8); NaN where d is not finite or the
    point is at/behind infinity. Same shape as ``disparity``."""
    return _laparo.stereo_disparity_to_depth(disparity, float(f_px), float(baseline_mm), float(cx_left), float(cx_right))


def depth_to_disparity(
    depth_mm: np.ndarray, f_px: float, baseline_mm: float, cx_left: float = 0.0, cx_right: float = 0.0
) -> np.ndarray:
    """Disparity (px) d = f b / z + (c_x^L − c_x^R) (§3.3.8); NaN where z ≤ 0 or not finite."""
    return _laparo.stereo_depth_to_disparity(depth_mm, float(f_px), float(baseline_mm), float(cx_left), float(cx_right))


def evaluate(
    pred: np.ndarray,
    gt: np.ndarray,
    mask: Optional[np.ndarray] = None,
    f_px: Optional[float] = None,
    baseline_mm: Optional[float] = None,
    cx_left: Optional[float] = None,
    cx_right: Optional[float] = None,
    bad_thresholds_px: Sequence[float] = (1.0, 2.0, 3.0),
    depth_range_mm: Optional[Tuple[float, float]] = (10.0, 500.0),
    zero_is_invalid: bool = False,
) -> Dict[str, Any]:
    """EPE and Bad-k (px) of a predicted left disparity against GT (non-finite GT = invalid), and
    with ``f_px`` and ``baseline_mm`` the depth MAE/RMSE (mm), AbsRel and δ_0.25 (Tables 3.7–3.8).
    Returns the dict ``laparo stereo eval --json`` reports."""
    return _laparo.stereo_evaluate(
        pred, gt, mask, f_px, baseline_mm, cx_left, cx_right, [float(b) for b in bad_thresholds_px],
        None if depth_range_mm is None else (float(depth_range_mm[0]), float(depth_range_mm[1])), bool(zero_is_invalid),
    )


def match(
    left: np.ndarray,
    right: np.ndarray,
    d_min: int,
    d_max: int,
    mode: str = "default",
    vertical_tol: int = 0,
    p1: Optional[int] = None,
    p2: Optional[int] = None,
    uniqueness: Optional[int] = None,
    lr_max_diff: Optional[int] = None,
    speckle_window: Optional[int] = None,
    fill_holes: bool = False,
    self_rectify: bool = False,
) -> Dict[str, Any]:
    """Semi-global matching of a pair (uint8 grey/RGB/RGBA, same size) over [d_min, d_max) px.

    Args:
        d_min, d_max: disparity range, d = x_L − x_R, either sign (raw SCARED pairs ≈ −48..0).
        mode: ``"default"`` (4 paths, P1 = 5, P2 = 60) or ``"accurate"`` (8 paths, P1 = 7, P2 = 100).
        vertical_tol: search rows y ± k in the right image (k ≤ 8) and report the offset ``dy``.
        p1, p2, uniqueness (%), lr_max_diff (px, negative = no check), speckle_window (px, 0 = off):
            override the mode's values.
        fill_holes: also return ``disparity_filled`` (invalid pixels filled with the row background).
        self_rectify: rectify the raw pair from SIFT matches first (``d_min``/``d_max`` is the raw
            range), match, and map the result back to the raw left frame.

    Returns:
        dict with ``disparity`` (H, W) float32 (+inf where invalid), ``confidence`` (float32 in
        [0, 1], 0 where invalid), ``dy`` (float32 px, NaN where invalid; with ``vertical_tol > 0``
        or ``self_rectify``), ``stats`` (valid / rejected counts), ``params``; with
        ``self_rectify`` also ``rectification``, ``left_rectified``, ``right_rectified``,
        ``disparity_rectified``, ``rectified_range_px``, ``n_matches``.
    """
    return _laparo.stereo_match(
        left, right, int(d_min), int(d_max), mode, int(vertical_tol), p1, p2, uniqueness, lr_max_diff, speckle_window,
        bool(fill_holes), bool(self_rectify),
    )


def self_rectify(
    left: np.ndarray,
    right: np.ndarray,
    points_left: Optional[np.ndarray] = None,
    points_right: Optional[np.ndarray] = None,
    method: str = "quasi-euclidean",
    threshold_px: float = 1.0,
    min_inliers: int = 20,
    seed: int = 0,
) -> Dict[str, Any]:
    """Rectify a raw pair without a calibration (robust F, then Fusiello-style quasi-Euclidean
    or Hartley rectification), from (N, 2) px ``points_left``/``points_right`` or SIFT matches.

    Returns ``rectification`` (``h_left``, ``h_right`` raw → rectified, ``fundamental``,
    ``focal_px``, Euler angles, ``inliers``, ``dy_raw`` / ``dy_rectified`` statistics, …),
    the rectified ``left``/``right`` images (on the canvas ``rectification["rectified_size"]`` =
    (width, height), which holds both whole) with ``valid_left``/``valid_right`` and the points.
    Raises ``ValueError`` when the pair cannot be rectified (too few inliers, large rotations)."""
    return _laparo.stereo_self_rectify(
        left, right, points_left, points_right, method, float(threshold_px), int(min_inliers), int(seed)
    )
