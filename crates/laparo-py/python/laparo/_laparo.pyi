"""Type stubs of the compiled extension ``laparo._laparo`` (use the documented wrappers in
``laparo.depth``, ``laparo.cats``, ``laparo.stereo``, ``laparo.cpc``, ``laparo.mpm``,
``laparo.features``, ``laparo.register``)."""
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

def stereo_match(
    left: npt.NDArray[np.uint8], right: npt.NDArray[np.uint8], d_min: int, d_max: int, mode: str = "default",
    vertical_tol: int = 0, p1: Optional[int] = None, p2: Optional[int] = None, uniqueness: Optional[int] = None,
    lr_max_diff: Optional[int] = None, speckle_window: Optional[int] = None, fill_holes: bool = False,
    self_rectify: bool = False,
) -> Dict[str, Any]: ...
def stereo_self_rectify(
    left: npt.NDArray[np.uint8], right: npt.NDArray[np.uint8], points_left: Optional[np.ndarray] = None,
    points_right: Optional[np.ndarray] = None, method: str = "quasi-euclidean", threshold_px: float = 1.0,
    min_inliers: int = 20, seed: int = 0,
) -> Dict[str, Any]: ...

def features_detect(
    image: npt.NDArray[np.uint8], detector: Union[None, str, Dict[str, Any]] = None, mask: Optional[np.ndarray] = None
) -> Dict[str, Any]: ...
def features_match(
    descriptors1: np.ndarray, descriptors2: np.ndarray, ratio: str = "lowe:0.8", mutual: bool = True
) -> Tuple[npt.NDArray[np.int64], npt.NDArray[np.float32]]: ...
def features_match_images(
    image1: npt.NDArray[np.uint8], image2: npt.NDArray[np.uint8], detector: Union[None, str, Dict[str, Any]] = None,
    ratio: str = "lowe:0.8", mutual: bool = True, mask1: Optional[np.ndarray] = None, mask2: Optional[np.ndarray] = None,
    homography: Optional[np.ndarray] = None, eps_px: float = 3.0,
) -> Dict[str, Any]: ...
def features_find_homography(
    p1: np.ndarray, p2: np.ndarray, threshold_px: float = 1.0, confidence: float = 0.999, max_iters: int = 10000,
    seed: int = 0,
) -> Dict[str, Any]: ...
def features_find_fundamental(
    p1: np.ndarray, p2: np.ndarray, threshold_px: float = 1.0, confidence: float = 0.999, max_iters: int = 10000,
    seed: int = 0,
) -> Dict[str, Any]: ...
def features_find_essential(
    p1: np.ndarray, p2: np.ndarray, threshold: float = 1e-3, confidence: float = 0.999, max_iters: int = 10000,
    seed: int = 0,
) -> Dict[str, Any]: ...
def features_transfer_error(homography: np.ndarray, p1: np.ndarray, p2: np.ndarray) -> npt.NDArray[np.float64]: ...

def register_run(
    organ: _Path, landmarks: Any, targets: Any, out: _Path, spacing_mm: float = 3.0, dx_mm: Optional[float] = None,
    optimizer: str = "lbfgs", iterations: Optional[int] = None, roi: Optional[str] = None,
    tumour: Optional[_Path] = None, image: Optional[_Path] = None, camera: Optional[_Path] = None,
    youngs_modulus_kpa: float = 4.1, poisson_ratio: float = 0.49, density_kg_m3: float = 1000.0, steps: int = 200,
    dt_s: Optional[float] = None, region_weight: float = 0.0, joint_e: bool = False, smoothing_dx: Optional[float] = None,
    max_step_dx: Optional[float] = None, target_mean_mm: float = 0.0, resume: bool = False, checkpoint_every: int = 5,
    memory_gb: Optional[float] = None, kinetic_weight: float = 0.0, at_rest_weight: float = 0.0, crack: Any = None, crack_band_mm: Optional[float] = None,
    unknown: str = "velocity", damping_per_horizon: float = 10.0, thesis_landmarks: bool = False,
) -> Dict[str, Any]: ...
def register_arrays(
    landmarks: Any, targets: Any, organ: Optional[_Path] = None, particles: Optional[np.ndarray] = None,
    spacing_mm: float = 3.0, dx_mm: Optional[float] = None, optimizer: str = "lbfgs", iterations: Optional[int] = None,
    roi: Optional[str] = None, youngs_modulus_kpa: float = 4.1, poisson_ratio: float = 0.49,
    density_kg_m3: float = 1000.0, steps: int = 200, dt_s: Optional[float] = None, region_weight: float = 0.0,
    joint_e: bool = False, smoothing_dx: Optional[float] = None, max_step_dx: Optional[float] = None, target_mean_mm: float = 0.0,
    memory_gb: Optional[float] = None, kinetic_weight: float = 0.0, at_rest_weight: float = 0.0, crack: Any = None, crack_band_mm: Optional[float] = None,
    unknown: str = "velocity", damping_per_horizon: float = 10.0, thesis_landmarks: bool = False,
) -> Dict[str, Any]: ...
def register_assumed_cut(organ: _Path, lip: np.ndarray, depth_mm: float) -> Tuple[np.ndarray, np.ndarray]: ...

def register_arap(
    nodes: np.ndarray, tets: np.ndarray, landmarks: Any = None, targets: Any = None, fixed: Optional[np.ndarray] = None,
    fixed_positions: Optional[np.ndarray] = None,
    energy: str = "spokes", weights: str = "cotangent", landmark_weight: Optional[float] = None, iterations: int = 200,
    tolerance_mm: float = 1e-3, outside_tolerance_mm: float = 1.0,
) -> Dict[str, Any]: ...

def register_drbc(
    nodes: np.ndarray, tets: np.ndarray, landmarks: Any = None, targets: Any = None, fixed: Optional[np.ndarray] = None,
    fixed_positions: Optional[np.ndarray] = None,
    young_kpa: float = 4.1, poisson: float = 0.49, lam: Optional[float] = None, iterations: int = 50,
    outside_tolerance_mm: float = 1.0,
) -> Dict[str, Any]: ...

def register_lddmm(
    nodes: np.ndarray, tets: np.ndarray, landmarks: Any = None, targets: Any = None, fixed: Optional[np.ndarray] = None,
    fixed_positions: Optional[np.ndarray] = None,
    sigma_mm: float = 20.0, steps: int = 10, gamma: float = 0.01, iterations: int = 300,
    outside_tolerance_mm: float = 1.0,
) -> Dict[str, Any]: ...

def fem_tetrahedralize(
    vertices: np.ndarray, faces: np.ndarray, edge_mm: float = 6.0, min_dihedral_deg: float = 10.0, snap_passes: int = 4,
) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.int64], Dict[str, Any]]: ...

def fem_quality(
    nodes: np.ndarray, tets: np.ndarray, surface_vertices: Optional[np.ndarray] = None,
    surface_faces: Optional[np.ndarray] = None,
) -> Dict[str, Any]: ...

def fem_solve(
    nodes: np.ndarray, tets: np.ndarray, fixed: np.ndarray, face_faces: Optional[np.ndarray] = None,
    face_tractions_kpa: Optional[np.ndarray] = None, force_vertices: Optional[np.ndarray] = None,
    forces_mn: Optional[np.ndarray] = None, young_kpa: float = 4.1, poisson: float = 0.49, steps: int = 20,
    rel_tol: float = 1e-8, quadrature: str = "degree2", solver: str = "auto",
) -> Dict[str, Any]: ...

def fem_cut(
    nodes: np.ndarray, tets: np.ndarray, mouth: np.ndarray, directions: np.ndarray, depths_mm: Any,
    overshoot_mm: float = 2.0, landmarks: int = 0,
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
def set_buffer_cache_mb(mb: int) -> None: ...
