"""CATS — camera augmentation for uncalibrated stereo laparoscopes (thesis §3.3.3–3.3.5,
eqs. 3.5–3.9): each view is re-imaged by a randomly rotated camera, p' ~ K_rel H_R p with
H_R = K R K⁻¹ (eq. 3.6), R = Rz(ψ) Ry(θ) Rx(φ) with Euler angles ~ the Gaussians of Table 3.6,
and the right principal point shifted by Δx_right ~ U(−100, 0) px (added to every disparity).

Determinism: the parameters of a sample depend only on (seed, sample id, epoch). Epoch 0 uses
the generator of ``laparo cats augment --seed seed`` for that sample id, so it reproduces the
CLI's files; epoch e > 0 uses the id ``"<id>#epoch<e>"``.
"""
from __future__ import annotations

import os
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np

from . import _laparo
from .shard import ShardLike, parse as _parse_shard, indices as _shard_indices

CatsConfig = _laparo.CatsConfig
CatsConfig.__doc__ = """A CATS configuration (TOML of ``laparo cats config``).

Build with ``CatsConfig.thesis(row="SCARED+StMIS")``, ``CatsConfig.from_toml(text)`` or
``CatsConfig.from_file(path)``; ``to_toml()`` / ``to_dict()`` give it back."""


def thesis_config(row: str = "SCARED+StMIS") -> "CatsConfig":
    """The thesis' configuration for a Table 3.6 row (SCARED, StereoMIS, RIS2017, SCARED+StMIS)."""
    return CatsConfig.thesis(row)


def sample_params(
    config: "CatsConfig",
    width: int,
    height: int,
    seed: int,
    sample_id: str,
    epoch: int = 0,
    k_left: Optional[np.ndarray] = None,
    k_right: Optional[np.ndarray] = None,
) -> Dict[str, Any]:
    """Draw the augmentation parameters of one sample (eqs. 3.7–3.9).

    Source cameras: ``k_left``/``k_right`` (3×3, px) when given, else the config's ``[camera]``,
    else SceneFlow's (f = 1050 px, centred principal point). Returns the dict of a sidecar's
    ``params`` (``left``/``right`` camera augmentations with ``euler_deg``, ``rotation``,
    ``k_rel``; ``dx_right_px``), plus ``homography_left``/``homography_right``, ``seed`` and
    ``sample_seed``.
    """
    return _laparo.cats_sample_params(config, int(width), int(height), int(seed), sample_id, int(epoch), k_left, k_right)


def augment(
    left: np.ndarray,
    right: np.ndarray,
    disp_left: Optional[np.ndarray] = None,
    disp_right: Optional[np.ndarray] = None,
    params: Optional[Dict[str, Any]] = None,
    config: Optional["CatsConfig"] = None,
    seed: int = 0,
    sample_id: str = "sample",
    epoch: int = 0,
    k_left: Optional[np.ndarray] = None,
    k_right: Optional[np.ndarray] = None,
    gt_rule: str = "exact",
) -> Dict[str, Any]:
    """Augment one stereo sample.

    Args:
        left, right: uint8 images (H, W) or (H, W, C), same shape.
        disp_left: optional (H, W) float32/float64 left disparity (px, x_R = x − d; non-finite =
            unknown). disp_right: optional right disparity (x_L = x + d).
        params: explicit parameters (a sidecar's ``params``, :func:`sample_params`' output, or the
            hand-written JSON of ``laparo cats apply``); otherwise drawn from ``config`` (default:
            the thesis') with (seed, sample_id, epoch).
        gt_rule: ``"exact"`` (correspondences through both cameras) or ``"thesis"`` (§3.3.5).

    Returns:
        dict with ``left``, ``right`` (uint8), ``valid_left``, ``valid_right`` (bool),
        ``disp_left`` (float32, +inf where unknown), ``disp_left_valid``,
        ``disp_left_vertical_residual`` (exact rule), the same for ``disp_right`` when given,
        and ``params``.
    """
    return _laparo.cats_augment(
        left, right, disp_left, disp_right, params, config, int(seed), sample_id, int(epoch), k_left, k_right, gt_rule
    )


def discover(root: Union[str, os.PathLike], layout: str) -> List[Dict[str, Any]]:
    """The samples of a dataset folder (``sceneflow``, ``middlebury`` or ``generic`` layout), sorted
    by id, as ``laparo cats augment`` finds them: dicts with id, left, right, disp_left,
    disp_right, calib."""
    return _laparo.cats_discover(os.fspath(root), layout)


def augment_folder_sample(
    root: Union[str, os.PathLike],
    layout: str,
    index: int,
    config: Optional["CatsConfig"] = None,
    seed: int = 0,
    epoch: int = 0,
    gt_rule: str = "exact",
) -> Dict[str, Any]:
    """Load sample ``index`` of a dataset folder and augment it (the arrays of :func:`augment`,
    plus ``id``). Epoch 0 gives the arrays ``laparo cats augment`` writes for the same seed."""
    return _laparo.cats_augment_folder_sample(os.fspath(root), layout, int(index), config, int(seed), int(epoch), gt_rule)


def augment_dataset(
    input: Union[str, os.PathLike],
    layout: str,
    out: Union[str, os.PathLike],
    config: Optional["CatsConfig"] = None,
    seed: int = 0,
    gt_rule: str = "exact",
    shard: ShardLike = None,
) -> int:
    """Write the files of ``laparo cats augment`` for the samples of ``shard`` (``"I/N"``;
    all when None) into ``out``: N processes with shards 0..N-1 write exactly the files of one
    run. Returns the number of samples written; raises ``RuntimeError`` listing failures."""
    i, n = _parse_shard(shard)
    done, failures = _laparo.cats_augment_dataset(
        os.fspath(input), layout, os.fspath(out), config, int(seed), gt_rule, i, n
    )
    if failures:
        raise RuntimeError(f"{len(failures)} sample(s) failed:\n  " + "\n  ".join(failures[:20]))
    return done


def sample_seed(seed: int, sample_id: str) -> int:
    """The seed of a sample's generator (FNV-1a of the id mixed with the run seed)."""
    return _laparo.cats_sample_seed(int(seed), sample_id)


class CatsDataset:
    """A map-style PyTorch dataset (``__len__`` + ``__getitem__``, what
    ``torch.utils.data.DataLoader`` takes) applying CATS on the fly in DataLoader workers.
    It does not import torch (``import laparo`` stays fast); wrap it in anything that takes a
    map-style dataset.

    Sample ``index`` of epoch ``e`` is augmented with the generator of (seed, sample id, e), so
    the stream is identical whatever the number of workers, their scheduling or the machine.
    Call :meth:`set_epoch` before each epoch (DataLoader workers get a fresh copy of the dataset
    at each epoch unless ``persistent_workers=True``; with persistent workers pass the epoch
    through the index with :class:`EpochIndex` instead).

    Sources: a dataset folder (``root`` + ``layout``, as ``laparo cats augment`` reads it), or
    ``samples``: a sequence of dicts/tuples (left, right[, disp_left[, disp_right]]) of NumPy
    arrays with ``ids`` naming them (default ``str(index)``); then give the camera with
    ``k_left``/``k_right`` or the config's ``[camera]``.

    Items: dicts of NumPy arrays (see :func:`augment`) plus ``index``, ``epoch`` and ``id``;
    ``transform`` (e.g. conversion to tensors) is applied last. ``shard="I/N"`` restricts the
    dataset to the items ``i % N == I``.
    """

    def __init__(
        self,
        root: Optional[Union[str, os.PathLike]] = None,
        layout: str = "generic",
        samples: Optional[Sequence[Any]] = None,
        ids: Optional[Sequence[str]] = None,
        config: Optional["CatsConfig"] = None,
        seed: int = 0,
        gt_rule: str = "exact",
        k_left: Optional[np.ndarray] = None,
        k_right: Optional[np.ndarray] = None,
        transform: Optional[Callable[[Dict[str, Any]], Any]] = None,
        shard: ShardLike = None,
    ) -> None:
        if (root is None) == (samples is None):
            raise ValueError("CatsDataset: give root (a dataset folder) or samples (arrays), not both")
        self.root = None if root is None else os.fspath(root)
        self.layout = layout
        self.samples = samples
        self.config = config if config is not None else CatsConfig.thesis()
        self.seed = int(seed)
        self.gt_rule = gt_rule
        self.k_left, self.k_right = k_left, k_right
        self.transform = transform
        self.epoch = 0
        self._files = discover(self.root, layout) if self.root is not None else None
        n_all = len(self._files) if self._files is not None else len(samples)  # type: ignore[arg-type]
        if ids is not None and len(ids) != n_all:
            raise ValueError(f"ids: {len(ids)} ids for {n_all} samples")
        self.ids = list(ids) if ids is not None else None
        self._items = _shard_indices(n_all, shard)

    def set_epoch(self, epoch: int) -> None:
        """Select the epoch whose augmentation parameters the next items use."""
        self.epoch = int(epoch)

    def __len__(self) -> int:
        return len(self._items)

    def __getitem__(self, index: Any) -> Any:
        epoch = self.epoch
        if isinstance(index, EpochIndex):
            index, epoch = index.index, index.epoch
        k = self._items[int(index)]
        if self.root is not None:
            out = _laparo.cats_augment_sample_files(self._files[k], self.layout, self.config, self.seed, epoch, self.gt_rule)
        else:
            s = self.samples[k]  # type: ignore[index]
            if isinstance(s, dict):
                parts = (s["left"], s["right"], s.get("disp_left"), s.get("disp_right"))
            else:
                parts = tuple(s) + (None,) * (4 - len(s))
            sid = self.ids[k] if self.ids is not None else str(k)
            out = augment(
                parts[0], parts[1], parts[2], parts[3], config=self.config, seed=self.seed, sample_id=sid,
                epoch=epoch, k_left=self.k_left, k_right=self.k_right, gt_rule=self.gt_rule,
            )
            out["id"] = sid
        out["index"] = int(index)
        out["epoch"] = epoch
        return self.transform(out) if self.transform is not None else out


class EpochIndex:
    """An (index, epoch) pair a sampler can yield to :class:`CatsDataset` (for persistent workers)."""

    __slots__ = ("index", "epoch")

    def __init__(self, index: int, epoch: int) -> None:
        self.index, self.epoch = int(index), int(epoch)

    def __index__(self) -> int:
        return self.index

    def __repr__(self) -> str:
        return f"EpochIndex({self.index}, {self.epoch})"
