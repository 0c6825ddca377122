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
    let mut out = Image::filled(img.width, img.height, 1, 0u8);
    match img.channels {
        1 => return img.clone(),
        3 => luma_dispatch::<3>(&img.data, &mut out.data),
        4 => luma_dispatch::<4>(&img.data, &mut out.data),
        _ => {
            let g = img.to_gray_f32();
            out.data = g.data.iter().map(|&v| v.round().clamp(0.0, 255.0) as u8).collect();
        }
    }
    out
}

/// f32 luma 0.299 R + 0.587 G + 0.114 B, `f32::round` (half away from zero): the arithmetic of
/// `Image::to_gray_f32` then rounding, with the channel count fixed so the loop vectorises.
#[inline(always)]
fn luma<const C: usize>(data: &[u8], out: &mut [u8]) {
    for (o, p) in out.iter_mut().zip(data.chunks_exact(C)) {
        let v = 0.299 * p[0] as f32 + 0.587 * p[1] as f32 + 0.114 * p[2] as f32;
        *o = v.round().clamp(0.0, 255.0) as u8;
    }
}

/// The same loop compiled for AVX2 (no FMA contraction: bit-identical to [`luma`]).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn luma_avx2<const C: usize>(data: &[u8], out: &mut [u8]) {
    luma::<C>(data, out)
}

fn luma_dispatch<const C: usize>(data: &[u8], out: &mut [u8]) {
    #[cfg(target_arch = "x86_64")]
    if is_x86_feature_detected!("avx2") {
        // SAFETY: AVX2 is present (checked just above).
        return unsafe { luma_avx2::<C>(data, out) };
    }
    luma::<C>(data, out)
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The fixed-channel (and AVX2) luma equals `Image::to_gray_f32` rounded, and its scalar path.
    #[test]
    fn gray_u8_equals_the_f32_luma_rounded_and_the_scalar_path() {
        let mut st = 12345u32;
        for ch in [3usize, 4] {
            let data: Vec<u8> = (0..97 * 31 * ch)
                .map(|_| {
                    st = st.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                    (st >> 24) as u8
                })
                .collect();
            let img = Image::from_vec(97, 31, ch, data).unwrap();
            let want: Vec<u8> = img.to_gray_f32().data.iter().map(|&v| v.round().clamp(0.0, 255.0) as u8).collect();
            assert_eq!(to_gray_u8(&img).data, want);
            let mut scalar = vec![0u8; 97 * 31];
            match ch {
                3 => luma::<3>(&img.data, &mut scalar),
                _ => luma::<4>(&img.data, &mut scalar),
            }
            assert_eq!(scalar, want);
        }
    }
}
