//! ORB (oriented FAST + rotated BRIEF over a scale pyramid, Rublee et al. 2011; thesis §4.2
//! "ORB+NN"): `kornia_imgproc`'s port of the ORB-SLAM3 extractor.
use kornia_image::{Image as KImage, ImageSize};
use kornia_imgproc::features::OrbDetector;
use laparo_core::image::Image;
use serde::{Deserialize, Serialize};

use crate::error::{FeaturesError, Result};
use crate::keypoint::{Descriptors, Features, Keypoint};

/// Which ORB implementation runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum OrbBackend {
    /// laparo's port of OpenCV's `cv::ORB` (FAST-9 + NMS, Harris ranking per level, intensity
    /// centroid, `bit_pattern_31`): the default.
    OpenCv,
    /// kornia-imgproc's ORB-SLAM3 extractor (quadtree distribution; no Harris response out).
    KorniaOrbSlam3,
}

/// ORB parameters; `Default` = OpenCV's `ORB_create(nfeatures = 2000)` (8 levels × 1.2, FAST 20).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct OrbParams {
    /// Implementation.
    pub backend: OrbBackend,
    /// Keypoints to retain over all levels (2000).
    pub n_features: usize,
    /// Pyramid scale factor between levels (1.2).
    pub scale_factor: f32,
    /// Pyramid levels (8).
    pub n_levels: usize,
    /// FAST threshold, grey levels (20). (Kornia backend: fallback 7 when a level has too few corners.)
    pub fast_threshold: f32,
}

impl Default for OrbParams {
    fn default() -> Self {
        OrbParams {
            backend: OrbBackend::OpenCv,
            n_features: 2000,
            scale_factor: 1.2,
            n_levels: 8,
            fast_threshold: 20.0,
        }
    }
}

/// Diameter of the BRIEF patch at level 0, px (OpenCV `patchSize`).
const PATCH_PX: f64 = 31.0;

/// ORB on a grey u8 image: keypoints at full resolution and 32-byte descriptors.
pub fn detect_and_describe(gray: &Image<u8>, p: &OrbParams) -> Result<Features> {
    if !(p.scale_factor > 1.0) || p.n_levels == 0 || p.n_features == 0 || !(p.fast_threshold >= 0.0) {
        return Err(FeaturesError::invalid(
            "orb parameters",
            format!("need scale_factor > 1, n_levels ≥ 1, n_features ≥ 1, fast_threshold ≥ 0 (got {p:?})"),
        ));
    }
    match p.backend {
        OrbBackend::OpenCv => Ok(super::orb_cv::detect_and_describe(gray, p)),
        OrbBackend::KorniaOrbSlam3 => kornia_orb(gray, p),
    }
}

/// kornia-imgproc's ORB-SLAM3 extractor.
fn kornia_orb(gray: &Image<u8>, p: &OrbParams) -> Result<Features> {
    let det = OrbDetector {
        n_keypoints: p.n_features,
        downscale: p.scale_factor,
        n_scales: p.n_levels,
        ini_fast_threshold: p.fast_threshold / 255.0,
        min_fast_threshold: (p.fast_threshold.min(7.0)) / 255.0,
        ..OrbDetector::default()
    };
    let img = KImage::<u8, 1>::new(ImageSize { width: gray.width, height: gray.height }, gray.data.clone())
        .map_err(|e| FeaturesError::invalid("image", e.to_string()))?;
    let out = det.detect_and_extract_u8(&img).map_err(|e| FeaturesError::invalid("orb input", e.to_string()))?;
    let keypoints = out
        .keypoints_xy
        .iter()
        .zip(&out.orientations)
        .zip(&out.octaves)
        .map(|((xy, &a), &o)| Keypoint {
            x: xy[0] as f64,
            y: xy[1] as f64,
            size_px: PATCH_PX * (p.scale_factor as f64).powi(o as i32),
            angle_rad: a as f64,
            response: 0.0,
            octave: o as i32,
        })
        .collect();
    let data: Vec<u8> = out.descriptors.iter().flat_map(|d| d.iter().copied()).collect();
    let f = Features { keypoints, descriptors: Descriptors::Binary { bytes: 32, data } };
    Ok(cap(f, p.n_features))
}

/// The ORB-SLAM3 quadtree may return a few more keypoints than its per-level budgets (measured:
/// 2067 for 2000); keep exactly `n` by uniform decimation over the list, which spreads the
/// removals over levels and image regions (no response to rank by).
fn cap(f: Features, n: usize) -> Features {
    let total = f.len();
    if total <= n {
        return f;
    }
    let keep: Vec<usize> = (0..total).filter(|&k| (k * n) / total != ((k + 1) * n) / total).collect();
    Features { keypoints: keep.iter().map(|&i| f.keypoints[i]).collect(), descriptors: f.descriptors.select(&keep) }
}
