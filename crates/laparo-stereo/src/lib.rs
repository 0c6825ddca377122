//! laparo-stereo — CATS camera augmentation for uncalibrated stereo laparoscopes, stereo
//! calibration statistics, rectification and stereo evaluation (thesis §2.2, §3.3).

// Calibration statistics, rectification, disparity<->depth, evaluation.
pub mod calib_stats;
pub mod disparity;
pub mod error;
pub mod eval;
pub mod rectify;

// Semi-global matching with signed ranges and vertical tolerance (issue 14).
pub mod sgm;

// CATS camera augmentation (eqs. 3.5-3.9), its configuration and dataset layouts.
pub mod augment;
pub mod cats_params;
pub mod dataset;
pub mod synthetic;

// Middlebury calib.txt reader (stereo calibration statistics / evaluation).
pub mod middlebury;

pub use error::StereoError;
