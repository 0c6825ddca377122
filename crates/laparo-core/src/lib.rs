//! laparo-core: the plain data types and file formats shared by every laparo module.
//!
//! Camera models (pinhole intrinsics, Brown–Conrady distortion), rigid transforms (SE(3)),
//! homographies, image and depth containers, meshes, colour maps and readers/writers for the
//! formats surgical-vision users exchange (PNG 8/16-bit, JPEG, .npy/.npz, PFM, float TIFF,
//! OpenCV FileStorage YAML, JSON, OBJ/PLY/STL, Gmsh .msh, legacy VTK), and PNG/SVG figures with a
//! bundled font. See the crate README for the format conventions.
#![warn(missing_docs)]

pub mod atomic;
pub mod calib;
pub mod camera;
pub mod colormap;
pub mod depth;
pub mod error;
pub mod geometry;
pub mod homography;
pub mod image;
pub mod io;
pub mod mesh;
pub mod par;
pub mod plot;
pub mod remap;
pub mod se3;
pub mod shard;
pub mod stats;
pub mod table;

pub use calib::StereoCalibration;
pub use camera::{Distortion, Intrinsics};
pub use colormap::Colormap;
pub use depth::{DepthMap, DepthUnit};
pub use error::{CoreError, Result};
pub use homography::Homography;
pub use image::Image;
pub use se3::Se3;

/// The types and functions most programs need: `use laparo_core::prelude::*;`.
///
/// ```
/// use laparo_core::prelude::*;
/// let k = Intrinsics::new(500.0, 500.0, 320.0, 240.0, 640, 480).unwrap();
/// assert_eq!(k.width, 640);
/// assert_eq!(median(&mut [3.0, 1.0, 2.0, 10.0]), 2.5);
/// ```
pub mod prelude {
    pub use crate::atomic::write_atomic;
    pub use crate::calib::StereoCalibration;
    pub use crate::camera::{Distortion, Intrinsics};
    pub use crate::colormap::{colorize, Colormap};
    pub use crate::depth::{DepthMap, DepthUnit};
    pub use crate::error::{CoreError, Result};
    pub use crate::homography::Homography;
    pub use crate::image::{Image, Mask};
    pub use crate::plot::with_colorbar;
    pub use crate::se3::Se3;
    pub use crate::stats::{fast_median, median};
    pub use crate::table::Table;
}
