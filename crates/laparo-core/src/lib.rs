//! laparo-core: the plain data types and file formats shared by every laparo module.
//!
//! Camera models (pinhole intrinsics, Brown–Conrady distortion), rigid transforms (SE(3)),
//! homographies, image and depth containers, meshes, colour maps and readers/writers for the
//! formats surgical-vision users exchange (PNG 8/16-bit, JPEG, .npy/.npz, PFM, float TIFF,
//! OpenCV FileStorage YAML, JSON, OBJ/PLY/STL, Gmsh .msh, legacy VTK), and PNG/SVG figures with a
//! bundled font. See the crate README for the format conventions.

pub mod atomic;
pub mod calib;
pub mod camera;
pub mod colormap;
pub mod depth;
pub mod error;
pub mod homography;
pub mod image;
pub mod io;
pub mod mesh;
pub mod par;
pub mod plot;
pub mod remap;
pub mod se3;

pub use calib::StereoCalibration;
pub use camera::{Distortion, Intrinsics};
pub use colormap::Colormap;
pub use depth::{DepthMap, DepthUnit};
pub use error::{CoreError, Result};
pub use homography::Homography;
pub use image::Image;
pub use se3::Se3;
