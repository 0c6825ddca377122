//! laparo-stereo — CATS camera augmentation for uncalibrated stereo laparoscopes, stereo
//! calibration statistics, rectification and stereo evaluation (thesis §2.2, §3.3).
//!
//! Disparity and depth with the principal-point offset of §3.3.8 (`d = f b / z + (c_x^L − c_x^R)`),
//! on Middlebury Motorcycle's calibration (f = 3979.911 px, b = 193.001 mm, doffs = 124.343 px):
//!
//! ```
//! use laparo_stereo::disparity::DisparityGeometry;
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
//! ```
#![warn(missing_docs)]

// Calibration statistics, rectification, disparity<->depth, evaluation.
pub mod calib_stats;
pub mod disparity;
pub mod error;
pub mod eval;
pub mod rectify;
// Self-rectification without a calibration (issue 14 item 3).
pub mod self_rectify;

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
