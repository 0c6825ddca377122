//! Readers and writers for the raster formats surgical-vision users exchange.
//!
//! | format | read | write | notes |
//! |---|---|---|---|
//! | PNG / JPEG / TIFF 8-bit | [`read_image`], [`read_rgb8`] | [`write_png`] | channels as stored (1/3/4) |
//! | PNG 16-bit | [`read_png16`] | [`write_png16`] | values kept exactly (no rescaling) |
//! | NumPy `.npy` / `.npz` | [`read_npy`], [`read_npz`] | [`write_npy_f32`], [`write_npy_f64`], [`write_npz_f64`] | f32/f64/u8/u16/i32/i64/bool, C or Fortran order |
//! | PFM | [`read_pfm`] | [`write_pfm`] | rows bottom-to-top on disk, top row first in memory |
//! | float TIFF | [`read_tiff_f32`] | [`write_tiff_f32`] | 32-bit float gray (or RGB) |
//! | OpenEXR | [`read_exr`] | [`write_exr`] | one channel (or Y/Z/R), half/float/uint |
//! | masks | [`read_mask`] | [`write_mask_png`] | PNG/JPEG/TIFF: channel 0 non-zero = valid; npy/npz/PFM/EXR: finite and non-zero (or `true`) = valid |
//! | intrinsics | [`read_camera`] | – | JSON, ROS camera_info YAML, OpenCV YAML, COLMAP cameras.txt, EndoVis txt (see [`camera_io`]) |
//! | stereo calibrations | [`read_stereo_calibration`] | [`StereoCalibration::write_json`](crate::calib::StereoCalibration::write_json) | laparo JSON, OpenCV YAML (one file or intrinsics + extrinsics), EndoVis 2017 txt, ROS camera_info pair (see [`calib_formats`]) |
//!
//! These are the **only** readers of each kind of input: every laparo command reads masks,
//! depth/disparity maps, intrinsics and calibrations through them, so a file one command accepts
//! every command accepts. Every error names the file. Every writer is atomic (temporary sibling + rename).
pub mod calib_formats;
pub mod camera_io;
mod depth_io;
mod exr;
mod npy;
mod npy_header;
pub mod opencv_yaml;
mod pfm;
mod png;
mod tiff;

pub use camera_io::{check_image_size, read_camera, CameraFile, MAX_IMAGE_PIXELS, MAX_IMAGE_SIDE};
pub use depth_io::{read_depth, read_float_map, read_mask, write_depth, write_float_map, write_mask_png};
pub use exr::{read_exr, write_exr};
pub use npy::{read_npy, read_npz, read_npz_names, write_npy_f32, write_npy_f64, write_npz_f64};
pub use pfm::{read_pfm, write_pfm};
pub use png::{image_size, read_image, read_png16, read_rgb8, write_jpeg, write_png, write_png16};
pub use tiff::{read_tiff_f32, write_tiff_f32};

use crate::error::{CoreError, Result};
use std::path::Path;

/// Read a stereo calibration from one file (laparo JSON, OpenCV FileStorage YAML/JSON, EndoVis
/// 2017 `camera_calibration.txt`) or two (OpenCV `stereo_calib` intrinsics + extrinsics, or a
/// left + right pair of ROS `camera_info` YAML). `size` (px) is used when the files do not state
/// the image size and must agree when they do.
pub fn read_stereo_calibration(
    files: &[&Path],
    size: Option<(usize, usize)>,
) -> Result<crate::calib::StereoCalibration> {
    use crate::calib::StereoCalibration as S;
    match (files, size) {
        ([a], None) => S::read(a),
        ([a], Some((w, h))) => S::read_with_size(a, w, h),
        ([a, b], None) => S::read_pair(a, b),
        ([a, b], Some((w, h))) => S::read_pair_with_size(a, b, w, h),
        _ => Err(CoreError::invalid("calibration", format!("expected 1 or 2 files, got {}", files.len()))),
    }
}

/// Lower-case extension of `path` without the dot ("" when there is none).
pub fn extension(path: &Path) -> String {
    path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default()
}

/// Read a whole file, naming it in the error.
pub(crate) fn read_bytes(path: &Path) -> Result<Vec<u8>> {
    std::fs::read(path).map_err(|e| CoreError::io(path, e))
}

/// Check that an image to be written is non-empty and has `allowed` channels.
pub(crate) fn check_writable<T>(path: &Path, img: &crate::image::Image<T>, allowed: &[usize]) -> Result<()> {
    if img.width == 0 || img.height == 0 {
        return Err(CoreError::format(path, format!("cannot write an empty {}x{} image", img.width, img.height)));
    }
    if !allowed.contains(&img.channels) {
        return Err(CoreError::format(
            path,
            format!("cannot write {} channels to this format (supported: {allowed:?})", img.channels),
        ));
    }
    if img.data.len() != img.width * img.height * img.channels {
        return Err(CoreError::SizeMismatch(format!(
            "{}: image data has {} values, {}x{}x{} needs {}",
            path.display(),
            img.data.len(),
            img.width,
            img.height,
            img.channels,
            img.width * img.height * img.channels
        )));
    }
    Ok(())
}
