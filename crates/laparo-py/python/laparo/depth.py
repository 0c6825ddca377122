"""RoDEM depth evaluation (thesis §3.2.7, eqs. 3.1–3.2) and perturbations (§3.2.6).

``evaluate_pair`` returns exactly the JSON object of ``laparo depth eval-pair --json``:
``n_valid``, ``n_invalid_pred`` and, per alignment (``none``, ``scale``, ``scale_shift``), the
metrics ``abs_rel``, ``sq_rel``, ``rmse`` (m), ``rmse_log``, ``silog``, ``delta_0.25`` …
``delta_3``, ``scale``, ``shift`` (``None`` where the CLI prints ``null``).
"""
from __future__ import annotations

from typing import Any, Dict, List, Optional, Sequence

import numpy as np

from . import _laparo
from .shard import ShardLike, indices as _shard_indices

#: The perturbation kinds of ``perturb`` (folder names of ``laparo depth perturb``).
KINDS: List[str] = list(_laparo.depth_perturbation_kinds())


def evaluate_pair(
    pred: np.ndarray,
    gt: np.ndarray,
    mask: Optional[np.ndarray] = None,
    pred_kind: str = "disparity",
    alignments: str = "all",
    gt_unit: str = "mm",
    depth_min_m: float = 0.01,
    depth_max_m: float = 0.5,
    invalid_pred: str = "far",
) -> Dict[str, Any]:
    """Metrics of one prediction against one ground truth.

    Args:
        pred: (H, W) float64/float32 prediction, disparity (any scale/shift) or depth
            (``pred_kind``). Non-finite values are invalid predictions (``invalid_pred``).
        gt: (H, W) ground-truth depth in ``gt_unit`` (``"mm"`` as the CLI's default, or
            ``"m"``); 0 / NaN = invalid pixel.
        mask: optional (H, W) bool/uint8 ROI.
        pred_kind: ``"disparity"`` or ``"depth"``.
        alignments: ``"none"``, ``"s"``, ``"st"``, ``"all"`` or a comma list.
        depth_min_m, depth_max_m: clamp range of aligned depth (m).
        invalid_pred: ``"far"``, ``"exclude"`` or ``"error"``.

    Returns:
        dict with the keys of ``laparo depth eval-pair --json``.
    """
    return _laparo.depth_evaluate_pair(
        pred, gt, mask, pred_kind, gt_unit, alignments, float(depth_min_m), float(depth_max_m), invalid_pred
    )


def _as_list(x: Any, name: str) -> list:
    if isinstance(x, np.ndarray):
        if x.ndim != 3:
            raise ValueError(f"{name}: a stacked batch must have shape (B, H, W), got {x.shape}")
        return [np.ascontiguousarray(x[i]) for i in range(x.shape[0])]
    if isinstance(x, (list, tuple)):
        return list(x)
    raise TypeError(f"{name}: expected a (B, H, W) array or a list of arrays, got {type(x).__name__}")


def evaluate_batch(
    preds: Any,
    gts: Any,
    masks: Any = None,
    pred_kind: str = "disparity",
    alignments: str = "all",
    gt_unit: str = "mm",
    depth_min_m: float = 0.01,
    depth_max_m: float = 0.5,
    invalid_pred: str = "far",
    shard: ShardLike = None,
) -> List[Dict[str, Any]]:
    """``evaluate_pair`` over a batch ((B, H, W) stacks or lists of arrays), in parallel with
    the GIL released. With ``shard="I/N"`` only items ``i % N == I`` are evaluated (the result
    list then holds those items, in order). Returns one dict per evaluated item."""
    p, g = _as_list(preds, "preds"), _as_list(gts, "gts")
    m = None if masks is None else _as_list(masks, "masks")
    if len(p) != len(g):
        raise ValueError(f"preds: {len(p)} predictions for {len(g)} ground truths")
    if m is not None and len(m) != len(g):
        raise ValueError(f"masks: {len(m)} masks for {len(g)} ground truths")
    if shard is not None:
        keep = _shard_indices(len(p), shard)
        p, g = [p[k] for k in keep], [g[k] for k in keep]
        m = None if m is None else [m[k] for k in keep]
    return _laparo.depth_evaluate_batch(
        p, g, m, pred_kind, gt_unit, alignments, float(depth_min_m), float(depth_max_m), invalid_pred
    )


def perturb(image: np.ndarray, kind: str, severity: int, seed: int) -> np.ndarray:
    """Seeded synthetic perturbation of an 8-bit image (H, W[, 1|3|4]) → (H, W, 3) uint8.

    ``kind`` is one of :data:`KINDS` (smoke, blood, bright, dark, defocus, motion, dirt),
    ``severity`` 1..3. Deterministic in (image, kind, severity, seed). ``laparo depth perturb``
    uses ``seed = item_seed(base_seed, file_stem, kind)`` for each image.
    """
    return _laparo.depth_perturb(image, kind, int(severity), int(seed))


def item_seed(base_seed: int, name: str, kind: str) -> int:
    """The seed ``laparo depth perturb --seed base_seed`` uses for image stem ``name``."""
    return _laparo.depth_item_seed(int(base_seed), name, kind)
