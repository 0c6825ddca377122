//! laparo-stereo — CATS camera augmentation for uncalibrated stereo laparoscopes, stereo
//! calibration statistics, rectification, semi-global matching, self-rectification and stereo
//! evaluation (thesis §2.2, §3.3).
//!
//! The modules are private; everything public is re-exported here (the list below, grouped by
//! topic) and the most used names are in [`prelude`]. Every fallible function returns
//! [`StereoError`].
//!
//! Disparity and depth with the principal-point offset of §3.3.8 (`d = f b / z + (c_x^L − c_x^R)`),
//! on Middlebury Motorcycle's calibration (f = 3979.911 px, b = 193.001 mm, doffs = 124.343 px),
//! and semi-global matching of a pair whose right image is the left one moved 5 columns:
//!
//! ```
//! use laparo_stereo::prelude::*;
//! use laparo_core::Image;
//!
//! let g = DisparityGeometry::middlebury(3979.911, 193.001, 124.343, 1244.772, 1019.507);
//! // doffs = c_x^R − c_x^L, so the offset c_x^L − c_x^R is −doffs.
//! assert!((g.offset_px() + 124.343).abs() < 1e-9);
//! let z_mm = 2000.0;
//! let d = g.disparity_px(z_mm);
//! assert!((d - (3979.911 * 193.001 / 2000.0 - 124.343)).abs() < 1e-9);
//! assert!((g.depth_mm(d) - z_mm).abs() < 1e-9);
//! // Beyond infinity (d < c_x^L − c_x^R) there is no depth.
//! assert!(g.depth_mm(-130.0).is_nan());
//!
//! // A random texture; the right view sees every scene point 5 px further left (d = x_L − x_R = 5).
//! let (w, h) = (96, 48);
//! let texel = |x: i64, y: i64| ((x * 7919 + y * 104729).wrapping_mul(2654435761) >> 13 & 255) as u8;
//! let view = |shift: i64| -> Vec<u8> {
//!     (0..h as i64).flat_map(|y| (0..w as i64).map(move |x| texel(x + shift, y))).collect()
//! };
//! let (left, right) = (Image::from_vec(w, h, 1, view(0))?, Image::from_vec(w, h, 1, view(5))?);
//! let out = match_pair(&left, &right, &SgmParams::new(0, 16))?;
//! // Away from the left border strip (no match in the right image) every pixel is valid, and its
//! // disparity is 5 up to the sub-pixel parabola's offset.
//! let inner: Vec<f32> = (8..h - 8)
//!     .flat_map(|y| (24..w - 8).map(move |x| (x, y)))
//!     .map(|(x, y)| out.disparity.get(x, y, 0))
//!     .collect();
//! assert!(inner.iter().all(|&d| (d - 5.0).abs() < 0.5), "{inner:?}");
//! # Ok::<(), StereoError>(())
//! ```
#![warn(missing_docs)]

mod augment;
mod calib_stats;
mod cats_params;
mod dataset;
mod disparity;
mod error;
mod eval;
mod middlebury;
mod rectify;
mod self_rectify;
mod sgm;
mod synthetic;

pub use error::{Result, StereoError};

// Calibration statistics (§3.3.4, Table 3.6).
pub use calib_stats::{
    calib_stats, euler_deg, fitted_cats_config, fitted_dx_right_range, ideal_stereo_frame, offsets_markdown,
    per_file_markdown, stereo_extrinsics_from_rotations, summarize, table_3_6, table_3_6_markdown, CalibStats,
    IdealStereoFrame, MeanStd, StatsSummary, ROTATION_TOLERANCE,
};
// Rectification, disparity ↔ depth, evaluation (Tables 3.7–3.8), Middlebury calib.txt.
pub use disparity::DisparityGeometry;
pub use eval::{evaluate, evaluate_maps, BadK, DepthMetrics, EvalMaps, EvalOptions, StereoMetrics};
pub use middlebury::read_middlebury_calib;
pub use rectify::{Rectification, RectificationInfo, RectifyOptions, Side};
// Semi-global matching with signed ranges and a vertical tolerance.
pub use sgm::{
    avx2_available, extend_rows, fill_background, match_gray_with, match_masked, match_masked_with, match_pair,
    match_pair_with, to_gray_u8, Kernel, Paths, SgmOutput, SgmParams, SgmStats, SgmWorkspace, MAX_DISPARITIES,
    MAX_VERTICAL_TOL,
};
// Self-rectification without a calibration and its keypoint matchers.
pub use self_rectify::{
    exact_correspondences, fast_detect, fast_match_stage, fast_matches, fast_matches_with, fast_refine,
    feature_matches, match_self_rectified, match_self_rectified_with, perturbation, rectified_disparity_shift,
    sample_disparity, self_rectify, sift_matches, DyStats, FastFeatures, FastParams, FeatureKind, MatchRoute,
    PointPairs, Rectified, RectifyMethod, SelfRectification, SelfRectifiedMatch, SelfRectifyOptions, MATCH_INTERP,
};
// CATS camera augmentation (eqs. 3.5–3.9), its configuration and dataset layouts.
pub use augment::{
    augment_image, augment_stereo, disparity_difference, AugmentedDisparity, AugmentedStereo, CameraAugmentation,
    CameraMap, GtRule, Mat3Rows, StereoAugmentation, StereoSample, Warped,
};
pub use cats_params::{
    sample_rng, sample_seed, CameraDist, CatsConfig, DisparityOffsetDist, Dist, DistortionDist, EulerDist,
    SourceCamera, TABLE_3_6,
};
pub use dataset::{
    augment_sample, check_homographies, discover, load_sample, parse_params, read_disparity, resume_state,
    run_params_hash, source_cameras, Layout, ResumeState, SampleFiles, SampleStats, Sidecar,
};
pub use synthetic::{default_camera, Scene};

/// The types and functions most programs need: `use laparo_stereo::prelude::*;`.
pub mod prelude {
    pub use crate::augment::{augment_stereo, CameraAugmentation, GtRule, StereoAugmentation, StereoSample};
    pub use crate::calib_stats::{calib_stats, CalibStats};
    pub use crate::cats_params::{sample_rng, CatsConfig};
    pub use crate::disparity::DisparityGeometry;
    pub use crate::error::{Result, StereoError};
    pub use crate::eval::{evaluate, evaluate_maps, EvalOptions, StereoMetrics};
    pub use crate::middlebury::read_middlebury_calib;
    pub use crate::rectify::{Rectification, RectifyOptions, Side};
    pub use crate::self_rectify::{match_self_rectified, self_rectify, SelfRectification, SelfRectifyOptions};
    pub use crate::sgm::{match_pair, match_pair_with, SgmOutput, SgmParams, SgmWorkspace};
}
