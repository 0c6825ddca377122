//! The protocol of the OpenCV peer `shared/bench/features_ref.py` (features.md §2), so laparo's
//! detectors can be compared with OpenCV's on the same textures: a 640×480 grey crop, image 2 =
//! the crop warped by a similarity (rotation 30°, scale 0.8 about the centre), repeatability
//! (SuperPoint definition, both directions averaged), ratio + mutual matching, correct iff the
//! two-way averaged transfer error (thesis §4.5.1) is below ε, matching score = correct /
//! image-1 keypoints in the common area.
use std::path::Path;

use laparo_core::image::{Image, Mask};
use laparo_core::remap::{warp_homography, Interp};
use serde::{Deserialize, Serialize};

use crate::detect::{detect_and_describe, to_gray_u8, DetectorConfig};
use crate::error::{FeaturesError, Result};
use crate::keypoint::{Features, MatchConfig};
use crate::matching::match_features;

/// Read an image, convert it to grey, resize it to cover `w`×`h` (Catmull–Rom, the `image`
/// crate; the peer uses OpenCV's cubic / area) and centre-crop it to `w`×`h`.
pub fn load_gray_crop(path: &Path, w: usize, h: usize) -> Result<Image<u8>> {
    let img = to_gray_u8(&laparo_core::io::read_image(path)?);
    let s = (w as f64 / img.width as f64).max(h as f64 / img.height as f64);
    let (rw, rh) = ((img.width as f64 * s).round() as u32, (img.height as f64 * s).round() as u32);
    let buf = image::GrayImage::from_raw(img.width as u32, img.height as u32, img.data)
        .ok_or_else(|| FeaturesError::invalid("image", format!("{}: bad buffer", path.display())))?;
    let r = image::imageops::resize(&buf, rw, rh, image::imageops::FilterType::CatmullRom);
    let (x0, y0) = ((rw as usize - w) / 2, (rh as usize - h) / 2);
    let mut out = Image::filled(w, h, 1, 0u8);
    for y in 0..h {
        for x in 0..w {
            out.data[y * w + x] = r.get_pixel((x + x0) as u32, (y + y0) as u32).0[0];
        }
    }
    Ok(out)
}

/// Similarity about (cx, cy): rotation `angle_deg`, scale `scale` (row-major H, image 1 → 2).
pub fn similarity_h(angle_deg: f64, scale: f64, cx: f64, cy: f64) -> [[f64; 3]; 3] {
    let a = angle_deg.to_radians();
    let (c, s) = (a.cos() * scale, a.sin() * scale);
    [[c, -s, cx - c * cx + s * cy], [s, c, cy - s * cx - c * cy], [0.0, 0.0, 1.0]]
}

/// Apply a row-major homography to a point.
pub fn apply_h(h: &[[f64; 3]; 3], p: [f64; 2]) -> [f64; 2] {
    let z = h[2][0] * p[0] + h[2][1] * p[1] + h[2][2];
    [(h[0][0] * p[0] + h[0][1] * p[1] + h[0][2]) / z, (h[1][0] * p[0] + h[1][1] * p[1] + h[1][2]) / z]
}

/// Inverse of a row-major 3×3 matrix.
pub fn invert_h(h: &[[f64; 3]; 3]) -> Result<[[f64; 3]; 3]> {
    let m = nalgebra::Matrix3::from_fn(|i, j| h[i][j]);
    let inv = m.try_inverse().ok_or_else(|| FeaturesError::invalid("homography", "is singular"))?;
    Ok(std::array::from_fn(|i| std::array::from_fn(|j| inv[(i, j)])))
}

fn erode(mask: &Mask, r: usize) -> Mask {
    let (w, h) = (mask.width, mask.height);
    let mut tmp = Mask::filled(w, h, 1, false);
    for y in 0..h {
        for x in 0..w {
            let (a, b) = (x.saturating_sub(r), (x + r).min(w - 1));
            tmp.data[y * w + x] = x >= r && x + r < w && (a..=b).all(|i| mask.data[y * w + i]);
        }
    }
    let mut out = Mask::filled(w, h, 1, false);
    for y in 0..h {
        for x in 0..w {
            let (a, b) = (y.saturating_sub(r), (y + r).min(h - 1));
            out.data[y * w + x] = y >= r && y + r < h && (a..=b).all(|j| tmp.data[j * w + x]);
        }
    }
    out
}

fn inside(mask: &Mask, p: [f64; 2]) -> bool {
    let (x, y) = (p[0].round(), p[1].round());
    x >= 0.0
        && y >= 0.0
        && (x as usize) < mask.width
        && (y as usize) < mask.height
        && mask.data[y as usize * mask.width + x as usize]
}

/// The figures `features_ref.py` prints for one image and detector.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RefFigures {
    /// Keypoints in image 1 / image 2.
    pub kp1: usize,
    /// Keypoints in image 2.
    pub kp2: usize,
    /// Image-1 keypoints whose transfer lands in the common area.
    pub kp1_common: usize,
    /// Repeatability (both directions averaged).
    pub repeatability: f64,
    /// Matches after ratio + mutual check.
    pub matches: usize,
    /// Matches with two-way transfer error < ε.
    pub correct: usize,
    /// correct / matches.
    pub precision: f64,
    /// correct / kp1_common.
    pub matching_score: f64,
}

/// Warp `img1` by `h` (image 1 → 2; bilinear, black border) and return image 2 and its valid
/// area eroded by 3 px (the peer's 7×7 erosion).
pub fn warp_pair(img1: &Image<u8>, h: &[[f64; 3]; 3]) -> Result<(Image<u8>, Mask)> {
    let hinv = invert_h(h)?;
    let (img2, valid) = warp_homography(img1, &hinv, img1.width, img1.height, Interp::Bilinear, 0u8)?;
    Ok((img2, erode(&valid, 3)))
}

/// Detect in `img1` and its warp by `h`, match, and score as `features_ref.py` does.
pub fn evaluate_homography(
    img1: &Image<u8>,
    det: &DetectorConfig,
    h: &[[f64; 3]; 3],
    mcfg: &MatchConfig,
    eps_px: f64,
) -> Result<RefFigures> {
    let (img2, valid2) = warp_pair(img1, h)?;
    let f1 = detect_and_describe(img1, det, None)?;
    let f2 = detect_and_describe(&img2, det, None)?;
    score_homography(&f1, &f2, &valid2, h, mcfg, eps_px)
}

/// Score two feature sets under the known homography `h` (image 1 → 2).
pub fn score_homography(
    f1: &Features,
    f2: &Features,
    valid2: &Mask,
    h: &[[f64; 3]; 3],
    mcfg: &MatchConfig,
    eps_px: f64,
) -> Result<RefFigures> {
    let hinv = invert_h(h)?;
    let (w, hh) = (valid2.width as f64, valid2.height as f64);
    let in_img1 = |p: [f64; 2]| {
        let (x, y) = (p[0].round(), p[1].round());
        x >= 0.0 && y >= 0.0 && x < w && y < hh
    };
    let p1 = f1.points();
    let p2 = f2.points();
    let c1: Vec<[f64; 2]> = p1.iter().map(|&p| apply_h(h, p)).filter(|&q| inside(valid2, q)).collect();
    let c2: Vec<[f64; 2]> = p2.iter().copied().filter(|&q| in_img1(apply_h(&hinv, q)) && inside(valid2, q)).collect();
    let repeatability = if c1.is_empty() || c2.is_empty() {
        0.0
    } else {
        let near = |a: &[[f64; 2]], b: &[[f64; 2]]| {
            a.iter().filter(|p| b.iter().any(|q| (p[0] - q[0]).hypot(p[1] - q[1]) < eps_px)).count() as f64
                / a.len() as f64
        };
        0.5 * (near(&c1, &c2) + near(&c2, &c1))
    };
    let m = match_features(f1, f2, mcfg)?;
    let correct = m
        .iter()
        .filter(|m| {
            let (a, b) = (p1[m.i1 as usize], p2[m.i2 as usize]);
            let (ta, tb) = (apply_h(h, a), apply_h(&hinv, b));
            0.5 * ((ta[0] - b[0]).hypot(ta[1] - b[1]) + (tb[0] - a[0]).hypot(tb[1] - a[1])) < eps_px
        })
        .count();
    Ok(RefFigures {
        kp1: f1.len(),
        kp2: f2.len(),
        kp1_common: c1.len(),
        repeatability,
        matches: m.len(),
        correct,
        precision: if m.is_empty() { 0.0 } else { correct as f64 / m.len() as f64 },
        matching_score: correct as f64 / c1.len().max(1) as f64,
    })
}
