//! laparo-features — keypoints, descriptors, matching, robust two-view geometry and the
//! ground-truth matching protocol of thesis §4.5.1.
//!
//! ```
//! use laparo_core::image::Image;
//! use laparo_features::{detect_and_describe, match_features, DetectorConfig, MatchConfig};
//!
//! // A blob pattern and the same pattern shifted by 7 px to the right.
//! let blobs = |dx: f64| {
//!     let mut img = Image::filled(160, 120, 1, 40u8);
//!     for y in 0..120 {
//!         for x in 0..160 {
//!             let (u, v) = (x as f64 - dx, y as f64);
//!             let s = (u * 0.21).sin() * (v * 0.17).cos() + (u * 0.05 + v * 0.11).sin();
//!             img.set(x, y, 0, (128.0 + 60.0 * s) as u8);
//!         }
//!     }
//!     img
//! };
//! let cfg = DetectorConfig::by_name("sift")?;
//! let (a, b) = (detect_and_describe(&blobs(0.0), &cfg, None)?, detect_and_describe(&blobs(7.0), &cfg, None)?);
//! let m = match_features(&a, &b, &MatchConfig::default())?;
//! assert!(!m.is_empty());
//! // Most matches are the 7 px shift.
//! let good = m.iter().filter(|m| {
//!     let (p, q) = (a.keypoints[m.i1 as usize], b.keypoints[m.i2 as usize]);
//!     ((q.x - p.x - 7.0).abs() < 1.0) && (q.y - p.y).abs() < 1.0
//! }).count();
//! assert!(good * 10 >= m.len() * 8, "{good} of {}", m.len());
//! # Ok::<(), laparo_features::FeaturesError>(())
//! ```
#![warn(missing_docs)]

pub mod colmap;
pub mod detect;
pub mod draw;
pub mod error;
pub mod gt;
pub mod guided;
pub mod keypoint;
pub mod matching;
pub mod ransac;
pub mod refcheck;
pub mod refine;

pub use detect::{detect_and_describe, DetectorConfig, OrbParams, SiftParams};
pub use draw::draw_matches;
pub use error::{FeaturesError, Result};
pub use keypoint::{Descriptors, Features, Keypoint, Match, MatchConfig, RatioTest};
pub use matching::match_features;
pub use ransac::{
    find_essential, find_fundamental, find_homography, recover_pose, RansacParams, RelativePose, RobustFit,
};
