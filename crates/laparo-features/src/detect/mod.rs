//! Detectors and descriptors: SIFT (Lowe 2004, thesis §4.2; laparo's, after `cv::SIFT`) and ORB
//! (Rublee 2011; laparo's port of `cv::ORB`), with kornia-imgproc's versions as alternatives.
use laparo_core::image::{Image, Mask};
use serde::{Deserialize, Serialize};

use crate::error::{FeaturesError, Result};
use crate::keypoint::Features;

mod lowe;
pub mod orb;
mod orb_cv;
mod orb_pattern;
pub mod sift;

pub use orb::{OrbBackend, OrbParams};
pub use sift::{SiftBackend, SiftParams};

/// Which detector + descriptor to run (`Default` impls are OpenCV's defaults).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum DetectorConfig {
    /// SIFT, 128-D float descriptors.
    Sift(SiftParams),
    /// ORB, 256-bit binary descriptors.
    Orb(OrbParams),
}

impl DetectorConfig {
    /// The detector by name (`sift` or `orb`) with default parameters.
    pub fn by_name(name: &str) -> Result<Self> {
        match name.to_ascii_lowercase().as_str() {
            "sift" => Ok(DetectorConfig::Sift(SiftParams::default())),
            "orb" => Ok(DetectorConfig::Orb(OrbParams::default())),
            other => Err(FeaturesError::invalid("detector", format!("'{other}' (expected sift or orb)"))),
        }
    }

    /// Short lower-case name.
    pub fn name(&self) -> &'static str {
        match self {
            DetectorConfig::Sift(_) => "sift",
            DetectorConfig::Orb(_) => "orb",
        }
    }
}

/// Convert an 8-bit image (grey, RGB or RGBA) to one grey channel (Rec. 601 luma, rounded).
pub fn to_gray_u8(img: &Image<u8>) -> Image<u8> {
    if img.channels == 1 {
        return img.clone();
    }
    let g = img.to_gray_f32();
    Image {
        width: g.width,
        height: g.height,
        channels: 1,
        data: g.data.iter().map(|&v| v.round().clamp(0.0, 255.0) as u8).collect(),
    }
}

/// Detect keypoints and compute descriptors on a grey 8-bit image (colour input is converted);
/// with `mask`, only keypoints whose rounded position is `true` in the mask are kept.
pub fn detect_and_describe(gray: &Image<u8>, cfg: &DetectorConfig, mask: Option<&Mask>) -> Result<Features> {
    let gray = to_gray_u8(gray);
    if gray.width == 0 || gray.height == 0 {
        return Err(FeaturesError::invalid("image", "is empty (0 pixels)"));
    }
    if let Some(m) = mask {
        if m.width != gray.width || m.height != gray.height {
            return Err(FeaturesError::invalid(
                "mask",
                format!("is {}x{}, image is {}x{}", m.width, m.height, gray.width, gray.height),
            ));
        }
    }
    let feats = match cfg {
        DetectorConfig::Sift(p) => sift::detect_and_describe(&gray, p)?,
        DetectorConfig::Orb(p) => orb::detect_and_describe(&gray, p)?,
    };
    Ok(match mask {
        None => feats,
        Some(m) => apply_mask(feats, m),
    })
}

/// Keep the keypoints whose rounded position lies inside `mask` (and inside the image).
pub fn apply_mask(f: Features, mask: &Mask) -> Features {
    let keep: Vec<usize> = f
        .keypoints
        .iter()
        .enumerate()
        .filter(|(_, k)| {
            let (x, y) = (k.x.round(), k.y.round());
            x >= 0.0
                && y >= 0.0
                && (x as usize) < mask.width
                && (y as usize) < mask.height
                && mask.get(x as usize, y as usize, 0)
        })
        .map(|(i, _)| i)
        .collect();
    Features { keypoints: keep.iter().map(|&i| f.keypoints[i]).collect(), descriptors: f.descriptors.select(&keep) }
}
