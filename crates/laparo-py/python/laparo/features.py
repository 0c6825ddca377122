"""Keypoints, descriptors, matching and robust two-view geometry (thesis §4.2, §4.5).

* :func:`detect` — SIFT (128-D float32 descriptors) or ORB (32-byte binary descriptors) of one
  8-bit image; keypoints as an (N, 6) float64 array with columns :data:`KEYPOINT_COLUMNS`
  (x, y in px with pixel centres at integers, size px, angle rad, response, octave);
* :func:`match` — 2-NN matching with Lowe's ratio (``"lowe:0.8"``), VLFeat's ``vl_ubcmatch``
  (``"ubc:2.8"``, the thesis' setting) or none, and an optional mutual check;
* :func:`match_images` — detect + match two images, as ``laparo features match`` (with a
  ground-truth homography: the two-way transfer error of §4.5.1, correctness, precision);
* :func:`find_homography`, :func:`find_fundamental`, :func:`find_essential` — RANSAC with MSAC
  scoring, adaptive stopping, local optimisation; deterministic for a ``seed`` whatever the
  thread count;
* :func:`transfer_error` — ½(‖H p1 − p2‖ + ‖H⁻¹ p2 − p1‖) per correspondence (px).
"""
from __future__ import annotations

from typing import Any, Dict, Optional, Tuple, Union

import numpy as np

from . import _laparo

KEYPOINT_COLUMNS = ("x", "y", "size_px", "angle_rad", "response", "octave")
"""Columns of the (N, 6) keypoint arrays."""

Detector = Union[str, Dict[str, Any]]


def detect(image: np.ndarray, detector: Detector = "sift", mask: Optional[np.ndarray] = None) -> Dict[str, Any]:
    """Detect keypoints and compute descriptors.

    Args:
        image: uint8 (H, W), (H, W, 3) or (H, W, 4); colour is converted to Rec. 601 luma.
        detector: ``"sift"`` or ``"orb"`` (OpenCV's default parameters), or a configuration dict
            as returned in ``["detector"]`` (e.g. ``{"Sift": {...}}``) with changed parameters.
        mask: optional (H, W) bool/uint8: keypoints are kept where it is true.

    Returns:
        dict with ``keypoints`` (N, 6) float64 (:data:`KEYPOINT_COLUMNS`), ``descriptors``
        (N, 128) float32 for SIFT or (N, 32) uint8 for ORB, ``detector`` (the configuration).
    """
    return _laparo.features_detect(image, detector, mask)


def match(
    descriptors1: np.ndarray, descriptors2: np.ndarray, ratio: str = "lowe:0.8", mutual: bool = True
) -> Tuple[np.ndarray, np.ndarray]:
    """Match descriptors of image 1 to image 2 (brute-force 2-NN).

    ``ratio``: ``"lowe:R"`` (accept d₁ < R·d₂), ``"ubc:T"`` (VLFeat: T·d₁² < d₂²) or ``"none"``;
    ``mutual``: keep only mutual nearest neighbours. Returns ``(indices, distances)``: (M, 2) int64
    rows (i1, i2) sorted by i1, and (M,) float32 distances (L2 for float descriptors, Hamming bits
    for binary ones)."""
    return _laparo.features_match(descriptors1, descriptors2, ratio, bool(mutual))


def match_images(
    image1: np.ndarray,
    image2: np.ndarray,
    detector: Detector = "sift",
    ratio: str = "lowe:0.8",
    mutual: bool = True,
    mask1: Optional[np.ndarray] = None,
    mask2: Optional[np.ndarray] = None,
    homography: Optional[np.ndarray] = None,
    eps_px: float = 3.0,
) -> Dict[str, Any]:
    """Detect in both images and match them: the computation of ``laparo features match``.

    Returns ``n_keypoints1``, ``n_keypoints2``, ``n_matches``, ``matches`` (M, 2), ``points1``,
    ``points2`` (M, 2) px, ``distances`` (M,), ``features1``/``features2`` (as :func:`detect`),
    ``detector``, ``match``, ``eps_px``; with a ground-truth ``homography`` (3×3, image 1 → 2) also
    ``transfer_error_px`` (M,), ``correct`` (M,) bool (error < ``eps_px``), ``n_correct`` and
    ``precision`` (otherwise None)."""
    return _laparo.features_match_images(
        image1, image2, detector, ratio, bool(mutual), mask1, mask2, homography, float(eps_px)
    )


def find_homography(
    p1: np.ndarray, p2: np.ndarray, threshold_px: float = 1.0, confidence: float = 0.999, max_iters: int = 10000,
    seed: int = 0,
) -> Dict[str, Any]:
    """Robust homography p2 ~ H p1 from (N, 2) px correspondences (N ≥ 4), forward transfer error.

    Returns ``model`` (3×3), ``inliers`` (N,) bool, ``rms_px``, ``n_inliers``, ``iterations``."""
    return _laparo.features_find_homography(p1, p2, float(threshold_px), float(confidence), int(max_iters), int(seed))


def find_fundamental(
    p1: np.ndarray, p2: np.ndarray, threshold_px: float = 1.0, confidence: float = 0.999, max_iters: int = 10000,
    seed: int = 0,
) -> Dict[str, Any]:
    """Robust fundamental matrix (x2ᵀ F x1 = 0) from (N, 2) px correspondences (N ≥ 8), Sampson
    distance. Same keys as :func:`find_homography`."""
    return _laparo.features_find_fundamental(p1, p2, float(threshold_px), float(confidence), int(max_iters), int(seed))


def find_essential(
    p1: np.ndarray, p2: np.ndarray, threshold: float = 1e-3, confidence: float = 0.999, max_iters: int = 10000,
    seed: int = 0,
) -> Dict[str, Any]:
    """Robust essential matrix from N ≥ 5 *normalised* (N, 2) points (K⁻¹ x), 5-point minimal
    solver (Stewénius–Engels–Nistér); ``threshold`` is in normalised units (≈ px / f). Same keys
    as :func:`find_homography`."""
    return _laparo.features_find_essential(p1, p2, float(threshold), float(confidence), int(max_iters), int(seed))


def transfer_error(homography: np.ndarray, p1: np.ndarray, p2: np.ndarray) -> np.ndarray:
    """Two-way averaged transfer error (px) of (N, 2) correspondences under ``homography``
    (image 1 → 2): ½(‖H p1 − p2‖ + ‖H⁻¹ p2 − p1‖) (thesis §4.5.1)."""
    return _laparo.features_transfer_error(homography, p1, p2)
