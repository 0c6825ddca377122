"""Type stubs of the compiled extension ``laparo._laparo`` (use the documented wrappers in
``laparo.depth``, ``laparo.cats``, ``laparo.stereo``, ``laparo.cpc``, ``laparo.mpm``)."""
from os import PathLike
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

__version__: str

_Path = Union[str, PathLike]

def depth_evaluate_pair(
    pred: npt.NDArray[np.floating], gt: npt.NDArray[np.floating], mask: Optional[np.ndarray], pred_kind: str,
    gt_unit: str, alignments: str, depth_min_m: float, depth_max_m: float, invalid_pred: str,
) -> Dict[str, Any]: ...
def depth_evaluate_batch(
    preds: Sequence[np.ndarray], gts: Sequence[np.ndarray], masks: Optional[Sequence[Optional[np.ndarray]]],
    pred_kind: str, gt_unit: str, alignments: str, depth_min_m: float, depth_max_m: float, invalid_pred: str,
) -> List[Dict[str, Any]]: ...
def depth_perturb(image: npt.NDArray[np.uint8], kind: str, severity: int, seed: int) -> npt.NDArray[np.uint8]: ...
def depth_item_seed(base: int, name: str, kind: str) -> int: ...
def depth_perturbation_kinds() -> List[str]: ...

class CatsConfig:
    @staticmethod
    def thesis(row: str = "SCARED+StMIS") -> CatsConfig: ...
    @staticmethod
    def from_toml(text: str) -> CatsConfig: ...
    @staticmethod
    def from_file(path: _Path) -> CatsConfig: ...
    def to_toml(self) -> str: ...
    def to_dict(self) -> Dict[str, Any]: ...

def cats_sample_params(
    config: CatsConfig, width: int, height: int, seed: int, sample_id: str, epoch: int = 0,
    k_left: Optional[np.ndarray] = None, k_right: Optional[np.ndarray] = None,
) -> Dict[str, Any]: ...
def cats_augment(
    left: npt.NDArray[np.uint8], right: npt.NDArray[np.uint8], disp_left: Optional[np.ndarray] = None,
    disp_right: Optional[np.ndarray] = None, params: Optional[Dict[str, Any]] = None,
    config: Optional[CatsConfig] = None, seed: int = 0, sample_id: str = "sample", epoch: int = 0,
    k_left: Optional[np.ndarray] = None, k_right: Optional[np.ndarray] = None, gt_rule: str = "exact",
) -> Dict[str, Any]: ...
def cats_discover(root: _Path, layout: str) -> List[Dict[str, Any]]: ...
def cats_augment_folder_sample(
    root: _Path, layout: str, index: int, config: Optional[CatsConfig] = None, seed: int = 0, epoch: int = 0,
    gt_rule: str = "exact",
) -> Dict[str, Any]: ...
def cats_augment_sample_files(
    sample: Dict[str, Any], layout: str, config: Optional[CatsConfig] = None, seed: int = 0, epoch: int = 0,
    gt_rule: str = "exact",
) -> Dict[str, Any]: ...
def cats_sample_seed(seed: int, sample_id: str) -> int: ...
def cats_augment_dataset(
    input: _Path, layout: str, out: _Path, config: Optional[CatsConfig] = None, seed: int = 0,
    gt_rule: str = "exact", shard_index: int = 0, shard_count: int = 1,
) -> Tuple[int, List[str]]: ...

def stereo_read_calibration(
    path: _Path, path2: Optional[_Path] = None, width: Optional[int] = None, height: Optional[int] = None
) -> Dict[str, Any]: ...
def stereo_rectify(
    left: np.ndarray, right: np.ndarray, calib: Dict[str, Any], alpha: float = 0.0, align_principal_points: bool = True
) -> Dict[str, Any]: ...
def stereo_disparity_to_depth(
    disparity: np.ndarray, f_px: float, baseline_mm: float, cx_left: float, cx_right: float
) -> npt.NDArray[np.float64]: ...
def stereo_depth_to_disparity(
    depth_mm: np.ndarray, f_px: float, baseline_mm: float, cx_left: float, cx_right: float
) -> npt.NDArray[np.float64]: ...
def stereo_evaluate(
    pred: np.ndarray, gt: np.ndarray, mask: Optional[np.ndarray] = None, f_px: Optional[float] = None,
    baseline_mm: Optional[float] = None, cx_left: Optional[float] = None, cx_right: Optional[float] = None,
    bad_thresholds_px: Sequence[float] = ..., depth_range_mm: Optional[Tuple[float, float]] = ...,
    zero_is_invalid: bool = False,
) -> Dict[str, Any]: ...

class CpcWarp:
    canvas_size: Tuple[int, int]
    canvas_origin: Tuple[float, float]
    def original_to_warped(self, points: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]: ...
    def warped_to_original(self, points: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]: ...
    def maps(self) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...

def cpc_warp_frame(
    image: npt.NDArray[np.uint8], depth: np.ndarray, k: np.ndarray, mask: Optional[np.ndarray] = None,
    lam: Union[None, float, str] = None, depth_unit: str = "mm", grid_step_px: int = 4,
    max_view_angle_deg: float = 85.0, max_depth_jump: float = 0.1, theta_deg: float = 90.0, equiareal: bool = False,
) -> Dict[str, Any]: ...

class MpmScene:
    dim: int
    n_particles: int
    positions: npt.NDArray[np.float64]
    velocities: npt.NDArray[np.float64]
    youngs_modulus: float
    poisson_ratio: float
    steps: int
    dt: float
    def __init__(
        self, positions: npt.NDArray[np.float64], particle_volume: float, youngs_modulus: float, poisson_ratio: float,
        density: float = 1.0, n_grid: int = 64, dx: Optional[float] = None, dt: float = 1e-4, steps: int = 100,
        velocities: Optional[np.ndarray] = None, model: str = "neo_hookean", walls: str = "sticky",
        wall_thickness: int = 3, gravity: Optional[Sequence[float]] = None, fixed: Optional[np.ndarray] = None,
        external_forces: Optional[np.ndarray] = None,
    ) -> None: ...
    def with_state(
        self, velocities: Optional[np.ndarray] = None, positions: Optional[np.ndarray] = None,
        youngs_modulus: Optional[float] = None, poisson_ratio: Optional[float] = None,
    ) -> MpmScene: ...
    def simulate(self) -> Dict[str, Any]: ...
    def simulate_with_gradient(
        self, indices: Optional[Sequence[int]] = None, targets: Optional[np.ndarray] = None,
        weights: Optional[np.ndarray] = None,
    ) -> Dict[str, Any]: ...

def mpm_box_lattice(lo: Sequence[float], hi: Sequence[float], spacing: float) -> npt.NDArray[np.float64]: ...
def mpm_cfl_dt(youngs_modulus: float, poisson_ratio: float, density: float, dx: float, cfl: float) -> float: ...

def set_num_threads(n: int) -> None: ...
def get_num_threads() -> int: ...
