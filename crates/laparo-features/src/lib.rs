//! laparo-features — keypoints, descriptors, matching, robust two-view geometry and the
//! ground-truth matching protocol of thesis §4.5.1.
#![warn(missing_docs)]

pub mod error;
pub mod ransac;

pub use error::{FeaturesError, Result};
pub use ransac::{find_essential, find_fundamental, find_homography, RansacParams, RobustFit};
