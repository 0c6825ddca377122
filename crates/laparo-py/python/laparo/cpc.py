"""Conformal Perspective Correction (thesis Ch. 4): warp a frame using its depth so that the
surface appears locally fronto-parallel (cost C = λ C_persp + (1 − λ) C_res, eq. 4.1; convex
solve eq. 4.11; automatic λ §4.5.4), then map keypoints between the two images.

>>> r = laparo.cpc.warp(image, depth_mm, K, mask)        # doctest: +SKIP
>>> kp_orig = r.warped_to_original(kp_warped)              # doctest: +SKIP
"""
from __future__ import annotations

from typing import Any, Dict, Optional, Tuple, Union

import numpy as np

from . import _laparo

CpcWarp = _laparo.CpcWarp


class CpcResult:
    """Output of :func:`warp`: ``warped`` (uint8 canvas), ``mask`` (bool canvas), ``stats``
    (the ``stats.json`` of ``laparo cpc warp`` without its file fields), ``sweep`` (λ sweep when
    ``lam="auto"``), ``warp`` (:class:`CpcWarp`) and the point mappings."""

    def __init__(self, d: Dict[str, Any]) -> None:
        self.warped: np.ndarray = d["warped"]
        self.mask: np.ndarray = d["mask"]
        self.stats: Dict[str, Any] = d["stats"]
        self.sweep: Optional[Dict[str, Any]] = d.get("sweep")
        self.warp: Any = d["warp"]

    @property
    def lam(self) -> float:
        """The λ used."""
        return float(self.stats["lambda"])

    def original_to_warped(self, points: np.ndarray) -> np.ndarray:
        """Canvas (x, y) of original-image points (N, 2); NaN outside the mesh."""
        return self.warp.original_to_warped(np.ascontiguousarray(points, dtype=np.float64))

    def warped_to_original(self, points: np.ndarray) -> np.ndarray:
        """Original-image (x, y) of canvas points (N, 2); NaN outside the flattened mesh."""
        return self.warp.warped_to_original(np.ascontiguousarray(points, dtype=np.float64))

    def maps(self) -> Tuple[np.ndarray, np.ndarray]:
        """(backward (Hc, Wc, 2): canvas pixel → original (x, y); forward (H, W, 2): original
        pixel → canvas (x, y)), float64, NaN where invalid (``map_*.npy`` of the CLI, in f64)."""
        return self.warp.maps()

    def __repr__(self) -> str:
        h, w = self.warped.shape[:2]
        return f"CpcResult(canvas={w}x{h}, lambda={self.lam:.4g}, n_flipped={self.stats['n_flipped']})"


def warp(
    image: np.ndarray,
    depth: np.ndarray,
    K: np.ndarray,
    mask: Optional[np.ndarray] = None,
    lam: Union[None, float, str] = None,
    depth_unit: str = "mm",
    grid_step_px: int = 4,
    max_view_angle_deg: float = 85.0,
    max_depth_jump: float = 0.1,
    theta_deg: float = 90.0,
    equiareal: bool = False,
) -> CpcResult:
    """CPC-warp one frame.

    Args:
        image: uint8 (H, W) or (H, W, C).
        depth: (H, W) float depth along the optical axis in ``depth_unit``; NaN/0 = invalid.
        K: 3×3 intrinsics (px) of a distortion-free camera.
        mask: optional (H, W) ROI (default: every pixel with valid depth).
        lam: None (λ = 0.95), a float in [0, 1), or ``"auto"`` (§4.5.4).
        grid_step_px, max_view_angle_deg, max_depth_jump, theta_deg, equiareal: as the options of
            ``laparo cpc warp`` (``--grid-step`` …).
    """
    return CpcResult(
        _laparo.cpc_warp_frame(
            image, depth, K, mask, lam, depth_unit, int(grid_step_px), float(max_view_angle_deg),
            float(max_depth_jump), float(theta_deg), bool(equiareal),
        )
    )
