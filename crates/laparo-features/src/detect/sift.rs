//! SIFT (Lowe 2004; thesis §4.2 uses VLFeat's `vl_sift`): laparo's implementation after
//! `cv::SIFT` (module `lowe`, the default) or `kornia_imgproc`'s port of `cv::SIFT`.
use kornia_imgproc::features::{sift_detect_and_compute, FirstOctave, SiftConfig, SiftWorkspace};
use laparo_core::image::Image;
use serde::{Deserialize, Serialize};

use crate::error::{FeaturesError, Result};
use crate::keypoint::{Descriptors, Features, Keypoint};

/// Which SIFT implementation runs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum SiftBackend {
    /// laparo's SIFT after Lowe / OpenCV (AVX2 blur by runtime dispatch): the default.
    #[default]
    Laparo,
    /// kornia-imgproc 0.2's port of `cv::SIFT` (bit-exact on aarch64; scalar `fmaf` calls on
    /// x86-64, 4–9× slower than OpenCV there).
    Kornia,
}

/// SIFT parameters; `Default` = `cv::SIFT_create()` (first octave −1, i.e. 2× upsampling).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SiftParams {
    /// Implementation.
    #[serde(default)]
    pub backend: SiftBackend,
    /// Keep at most this many keypoints (best response first); 0 = all.
    pub n_features: usize,
    /// Scale levels per octave (3).
    pub n_octave_layers: usize,
    /// DoG contrast threshold on [0, 1] intensities, divided by the layers (0.04).
    pub contrast_threshold: f64,
    /// Principal-curvature ratio limit (10).
    pub edge_threshold: f64,
    /// Blur of the octave base, in px of that octave (1.6).
    pub sigma: f64,
    /// Upsample 2× first (OpenCV, VLFeat with first octave −1, COLMAP): true.
    pub upsample: bool,
}

impl Default for SiftParams {
    fn default() -> Self {
        SiftParams {
            backend: SiftBackend::Laparo,
            n_features: 0,
            n_octave_layers: 3,
            contrast_threshold: 0.04,
            edge_threshold: 10.0,
            sigma: 1.6,
            upsample: true,
        }
    }
}

/// SIFT on a grey u8 image: keypoints (OpenCV conventions) and 128-D float descriptors.
#[allow(clippy::neg_cmp_op_on_partial_ord)] // `!(a > b)` also rejects NaN parameters
pub fn detect_and_describe(gray: &Image<u8>, p: &SiftParams) -> Result<Features> {
    if p.n_octave_layers == 0 || !(p.sigma > 0.0) || !(p.contrast_threshold >= 0.0) || !(p.edge_threshold > 0.0) {
        return Err(FeaturesError::invalid(
            "sift parameters",
            format!("need n_octave_layers ≥ 1, sigma > 0, contrast_threshold ≥ 0, edge_threshold > 0 (got {p:?})"),
        ));
    }
    match p.backend {
        SiftBackend::Laparo => Ok(laparo_sift(gray, p)),
        SiftBackend::Kornia => kornia_sift(gray, p),
    }
}

/// laparo's SIFT (`super::lowe`).
fn laparo_sift(gray: &Image<u8>, p: &SiftParams) -> Features {
    let s = super::lowe::Settings {
        n_features: p.n_features,
        layers: p.n_octave_layers,
        contrast: p.contrast_threshold,
        edge: p.edge_threshold,
        sigma: p.sigma,
        upsample: p.upsample,
    };
    let (kps, data) = super::lowe::sift(&gray.data, gray.width, gray.height, &s);
    let keypoints = kps
        .iter()
        .map(|k| Keypoint {
            x: k.x as f64,
            y: k.y as f64,
            size_px: k.size as f64,
            angle_rad: (k.angle as f64).to_radians(),
            response: k.response as f64,
            octave: k.octave,
        })
        .collect();
    Features { keypoints, descriptors: Descriptors::Float { dim: 128, data } }
}

/// kornia-imgproc's port of `cv::SIFT`.
fn kornia_sift(gray: &Image<u8>, p: &SiftParams) -> Result<Features> {
    let cfg = SiftConfig {
        n_features: p.n_features,
        n_octave_layers: p.n_octave_layers,
        contrast_threshold: p.contrast_threshold,
        edge_threshold: p.edge_threshold,
        sigma: p.sigma,
    };
    let src: Vec<f32> = gray.data.iter().map(|&v| v as f32).collect();
    let mut ws = SiftWorkspace::new();
    let fo = if p.upsample { FirstOctave::Double } else { FirstOctave::Native };
    let out = sift_detect_and_compute(&mut ws, &src, gray.width, gray.height, &cfg, fo, usize::MAX, false)
        .map_err(|e| FeaturesError::invalid("sift parameters", e.to_string()))?;
    let keypoints = out
        .keypoints
        .iter()
        .map(|k| {
            // OpenCV packs octave | layer << 8 | ...; the octave is a signed byte (−1 = upsampled).
            let o = k.octave & 255;
            let octave = if o >= 128 { o - 256 } else { o };
            Keypoint {
                x: k.x as f64,
                y: k.y as f64,
                size_px: k.size as f64,
                angle_rad: (k.angle as f64).to_radians(),
                response: k.response as f64,
                octave,
            }
        })
        .collect();
    Ok(Features { keypoints, descriptors: Descriptors::Float { dim: 128, data: out.descriptors } })
}
