//! The ground-truth matching protocol of thesis §4.5.1 (see `shared/spec/features.md` §1, §5).
//!
//! A match (p₁, p₂) is **correct** iff its transfer error, averaged over both directions,
//! e = ½ (‖T₁₂(p₁) − p₂‖ + ‖T₂₁(p₂) − p₁‖), is below ε (default 3 px, strict `<` as in
//! `features_ref.py`). T is a known homography or depth + intrinsics + poses (z-depth in mm,
//! bilinear without interpolating across the ROI edge or a depth step, occlusion test against
//! the other view's depth). A match whose transfer is undefined in either direction (no depth,
//! outside the image or ROI, behind the camera, occluded) is **unverifiable**: counted
//! separately, never as correct or wrong.
//!
//! Definitions (per image pair):
//! - `precision` = #correct / #matches (Table 4.1's #C.Crsp / #Crsp, unverifiable matches in the
//!   denominator); `precision_verifiable` = #correct / (#matches − #unverifiable).
//! - `n_matchable` = number of **GT-matchable pairs among the detected keypoints**: pairs (i, j)
//!   with both transfers defined, j the nearest image-2 keypoint to T₁₂(p₁ᵢ), i the nearest
//!   image-1 keypoint to T₂₁(p₂ⱼ) (mutual nearest), and two-way transfer error < ε
//!   (SuperGlue-style labelling; one-to-one by construction).
//! - `recall` = #correct matches that are GT-matchable pairs / `n_matchable` (≤ 1).
//! - `matching_score` = #correct / #image-1 keypoints whose transfer is defined (the "common
//!   area" of `features_ref.py`).
//! - `repeatability` (SuperPoint definition, as `features_ref.py`): with C₁ = image-1 keypoints
//!   with a defined T₁₂ and C₂ = image-2 keypoints with a defined T₂₁, measured in image 2's
//!   frame: ½ (share of C₁ whose T₁₂(p) has a C₂ keypoint within ε + share of C₂ having a
//!   transferred C₁ keypoint within ε); 0 if either set is empty.
use crate::error::{FeaturesError, Result};
use crate::keypoint::{Keypoint, Match};
use laparo_core::image::{Image, Mask};
use laparo_core::{Intrinsics, Se3};
use nalgebra::{Matrix3, Point3, Vector3};
use rayon::prelude::*;

/// One view with depth for the depth + pose transfer.
#[derive(Clone, Copy, Debug)]
pub struct DepthView<'a> {
    /// z-depth along the optical axis, mm; ≤ 0 or +∞ = no depth; NaN is rejected (error).
    pub depth_mm: &'a Image<f64>,
    /// Pinhole intrinsics (px), image size = depth size.
    pub intrinsics: &'a Intrinsics,
    /// World → camera transform (mm).
    pub cam_from_world: Se3,
    /// Region of interest: depth is used only inside it (no interpolation across its edge).
    pub roi: Option<&'a Mask>,
}

impl<'a> DepthView<'a> {
    /// Build and validate a view; `name` (e.g. "view 1" or a file name) is used in errors.
    /// A missing pose (`None`) is an error naming the view.
    pub fn new(
        name: &str,
        depth_mm: &'a Image<f64>,
        intrinsics: &'a Intrinsics,
        cam_from_world: Option<Se3>,
        roi: Option<&'a Mask>,
    ) -> Result<Self> {
        let cam_from_world = cam_from_world
            .ok_or_else(|| FeaturesError::invalid(format!("{name} pose"), "missing pose (cam_from_world)"))?;
        let v = DepthView { depth_mm, intrinsics, cam_from_world, roi };
        v.validate(name)?;
        Ok(v)
    }

    /// Check sizes, the pose and the depth values (NaN → error naming the first NaN pixel).
    pub fn validate(&self, name: &str) -> Result<()> {
        let d = self.depth_mm;
        if d.channels != 1 {
            return Err(FeaturesError::invalid(format!("{name} depth"), format!("{} channels (need 1)", d.channels)));
        }
        let k = self.intrinsics;
        if (k.width, k.height) != (d.width, d.height) {
            return Err(FeaturesError::invalid(
                format!("{name} depth"),
                format!("size {}x{} differs from the intrinsics' {}x{}", d.width, d.height, k.width, k.height),
            ));
        }
        k.validate().map_err(|e| FeaturesError::invalid(format!("{name} intrinsics"), e.to_string()))?;
        if let Some(r) = self.roi {
            if (r.width, r.height) != (d.width, d.height) {
                return Err(FeaturesError::invalid(
                    format!("{name} roi"),
                    format!("size {}x{} differs from the depth's {}x{}", r.width, r.height, d.width, d.height),
                ));
            }
        }
        let m = self.cam_from_world.to_homogeneous();
        if m.iter().any(|v| !v.is_finite()) {
            return Err(FeaturesError::invalid(format!("{name} pose"), "not finite (missing pose?)"));
        }
        if let Some(i) = d.data.iter().position(|v| v.is_nan()) {
            return Err(FeaturesError::invalid(
                format!("{name} depth"),
                format!("NaN at pixel (x {}, y {}); mark missing depth with 0 or +inf", i % d.width, i / d.width),
            ));
        }
        Ok(())
    }

    fn valid_px(&self, x: usize, y: usize) -> Option<f64> {
        let z = self.depth_mm.data[y * self.depth_mm.width + x];
        let in_roi = self.roi.is_none_or(|r| r.data[y * r.width + x]);
        (in_roi && z > 0.0 && z.is_finite()).then_some(z)
    }

    /// Depth at a real position: bilinear if the 4 neighbours are valid, inside the ROI and within
    /// `step_mm` of each other, else the nearest pixel's depth (if valid), else None.
    pub fn depth_at(&self, x: f64, y: f64, step_mm: f64) -> Option<f64> {
        let (w, h) = (self.depth_mm.width, self.depth_mm.height);
        laparo_core::remap::sample_smooth(w, h, x, y, step_mm, |i, j| self.valid_px(i, j))
    }
}

/// The ground truth relating image 1 and image 2.
#[derive(Clone, Copy, Debug)]
pub enum GroundTruth<'a> {
    /// x₂ ~ H x₁ (px), unbounded plane: every finite transfer is defined.
    Homography(Matrix3<f64>),
    /// x₂ ~ H x₁ with image sizes (width, height): a transfer landing outside the other image
    /// (pixel centres at integers, rounded as `features_ref.py`) is undefined.
    HomographyBounded {
        /// Image 1 → image 2, px.
        h: Matrix3<f64>,
        /// Image 1 size (width, height).
        size1: (usize, usize),
        /// Image 2 size (width, height).
        size2: (usize, usize),
    },
    /// Depth + intrinsics + poses of both views.
    DepthPose(DepthView<'a>, DepthView<'a>),
}

fn apply_h(h: &Matrix3<f64>, p: [f64; 2]) -> Option<[f64; 2]> {
    let v = h * Vector3::new(p[0], p[1], 1.0);
    if v[2].abs() < 1e-300 {
        return None;
    }
    let q = [v[0] / v[2], v[1] / v[2]];
    (q[0].is_finite() && q[1].is_finite()).then_some(q)
}

fn in_image(p: [f64; 2], size: (usize, usize)) -> bool {
    let (x, y) = (p[0].round(), p[1].round());
    x >= 0.0 && y >= 0.0 && x < size.0 as f64 && y < size.1 as f64
}

/// Depth-based transfer from `a` to `b` with the occlusion test.
fn transfer_depth(a: &DepthView, b: &DepthView, p: [f64; 2], tol_mm: f64) -> Option<[f64; 2]> {
    let z = a.depth_at(p[0], p[1], tol_mm)?;
    let xa = a.intrinsics.backproject(p[0], p[1], z);
    let xw = a.cam_from_world.inverse_transform_point(&Point3::from(xa));
    let xb = b.cam_from_world.transform_point(&xw);
    let (u, v) = b.intrinsics.project(&xb.coords)?;
    let zb = b.depth_at(u, v, tol_mm)?; // outside, outside the ROI or no depth: undefined
    if (zb - xb.z).abs() > tol_mm {
        return None; // occluded (or inconsistent depth)
    }
    Some([u, v])
}

impl GroundTruth<'_> {
    fn h_inv(&self) -> Option<Matrix3<f64>> {
        match self {
            GroundTruth::Homography(h) | GroundTruth::HomographyBounded { h, .. } => h.try_inverse(),
            GroundTruth::DepthPose(..) => None,
        }
    }

    /// Validate the ground truth (finite invertible homography; depth views as [`DepthView::validate`]).
    pub fn validate(&self) -> Result<()> {
        match self {
            GroundTruth::Homography(h) | GroundTruth::HomographyBounded { h, .. } => {
                if h.iter().any(|v| !v.is_finite()) || h.try_inverse().is_none() {
                    return Err(FeaturesError::invalid(
                        "ground-truth homography",
                        format!("not finite or singular: {h}"),
                    ));
                }
                Ok(())
            }
            GroundTruth::DepthPose(a, b) => {
                a.validate("view 1")?;
                b.validate("view 2")
            }
        }
    }

    fn transfer(&self, p: [f64; 2], forward: bool, hinv: Option<&Matrix3<f64>>, tol: f64) -> Option<[f64; 2]> {
        if !(p[0].is_finite() && p[1].is_finite()) {
            return None;
        }
        match self {
            GroundTruth::Homography(h) => apply_h(if forward { h } else { hinv? }, p),
            GroundTruth::HomographyBounded { h, size1, size2 } => {
                let (src, dst) = if forward { (*size1, *size2) } else { (*size2, *size1) };
                if !in_image(p, src) {
                    return None;
                }
                let q = apply_h(if forward { h } else { hinv? }, p)?;
                in_image(q, dst).then_some(q)
            }
            GroundTruth::DepthPose(a, b) => {
                if forward {
                    transfer_depth(a, b, p, tol)
                } else {
                    transfer_depth(b, a, p, tol)
                }
            }
        }
    }

    /// Transfer an image-1 point into image 2 (None = unverifiable). Depth route: occlusion
    /// tolerance [`EvalConfig::default`]'s `occlusion_tol_mm`.
    pub fn transfer_1to2(&self, p: [f64; 2]) -> Option<[f64; 2]> {
        self.transfer(p, true, self.h_inv().as_ref(), EvalConfig::default().occlusion_tol_mm)
    }

    /// Transfer an image-2 point into image 1 (None = unverifiable).
    pub fn transfer_2to1(&self, p: [f64; 2]) -> Option<[f64; 2]> {
        self.transfer(p, false, self.h_inv().as_ref(), EvalConfig::default().occlusion_tol_mm)
    }
}

/// Evaluation settings.
#[derive(Clone, Debug, PartialEq)]
pub struct EvalConfig {
    /// Correctness (and repeatability) radius ε, px (thesis: 3).
    pub eps_px: f64,
    /// Depth tolerance of the occlusion test and of the depth-step test of the interpolation, mm.
    pub occlusion_tol_mm: f64,
}

impl Default for EvalConfig {
    fn default() -> Self {
        EvalConfig { eps_px: 3.0, occlusion_tol_mm: 5.0 }
    }
}

/// The label of one match.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MatchLabel {
    /// Two-way transfer error < ε.
    Correct,
    /// Two-way transfer error ≥ ε.
    Wrong,
    /// A transfer is undefined (no depth, outside, occluded).
    Unverifiable,
}

/// The figures of one image pair (definitions in the module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct MatchEval {
    /// Matches evaluated (#Crsp).
    pub n_matches: usize,
    /// Correct matches (#C.Crsp).
    pub n_correct: usize,
    /// Matches whose transfer is undefined.
    pub n_unverifiable: usize,
    /// #correct / #matches (Table 4.1).
    pub precision: f64,
    /// #correct / verifiable matches.
    pub precision_verifiable: f64,
    /// Correct matches that are GT-matchable pairs / `n_matchable`.
    pub recall: f64,
    /// GT-matchable pairs among the detected keypoints (mutual nearest, two-way error < ε).
    pub n_matchable: usize,
    /// #correct / image-1 keypoints with a defined transfer.
    pub matching_score: f64,
    /// SuperPoint repeatability (both directions averaged).
    pub repeatability: f64,
    /// Image-1 keypoints with a defined transfer into image 2.
    pub n_kp1_common: usize,
    /// Image-2 keypoints with a defined transfer into image 1.
    pub n_kp2_common: usize,
    /// Label per match (same order as the input).
    pub labels: Vec<MatchLabel>,
    /// Two-way transfer error per match, px (NaN if unverifiable).
    pub transfer_error_px: Vec<f64>,
}

/// Index of the nearest point of `set` to `p` and its distance.
fn nearest(p: [f64; 2], set: &[(usize, [f64; 2])]) -> Option<(usize, f64)> {
    let mut best: Option<(usize, f64)> = None;
    for &(i, q) in set {
        let d = (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2);
        if best.is_none_or(|b| d < b.1) {
            best = Some((i, d));
        }
    }
    best.map(|(i, d)| (i, d.sqrt()))
}

/// Evaluate matches between `kp1` and `kp2` against the ground truth (thesis §4.5.1).
/// Errors: invalid ground truth (NaN depth, missing/non-finite pose, size mismatch, singular
/// homography), a non-positive ε, or a match index out of range.
pub fn evaluate_matches(
    kp1: &[Keypoint],
    kp2: &[Keypoint],
    matches: &[Match],
    gt: &GroundTruth,
    cfg: &EvalConfig,
) -> Result<MatchEval> {
    let p1: Vec<[f64; 2]> = kp1.iter().map(|k| [k.x, k.y]).collect();
    let p2: Vec<[f64; 2]> = kp2.iter().map(|k| [k.x, k.y]).collect();
    let pairs: Vec<(usize, usize)> = matches.iter().map(|m| (m.i1 as usize, m.i2 as usize)).collect();
    evaluate_points(&p1, &p2, &pairs, gt, cfg)
}

/// [`evaluate_matches`] on plain points `[x, y]` (px) and index pairs (i in p1, j in p2).
pub fn evaluate_points(
    p1: &[[f64; 2]],
    p2: &[[f64; 2]],
    pairs: &[(usize, usize)],
    gt: &GroundTruth,
    cfg: &EvalConfig,
) -> Result<MatchEval> {
    if !(cfg.eps_px.is_finite() && cfg.eps_px > 0.0) {
        return Err(FeaturesError::invalid("eps_px", format!("{} (need a finite value > 0)", cfg.eps_px)));
    }
    if !(cfg.occlusion_tol_mm.is_finite() && cfg.occlusion_tol_mm > 0.0) {
        return Err(FeaturesError::invalid(
            "occlusion_tol_mm",
            format!("{} (need a finite value > 0)", cfg.occlusion_tol_mm),
        ));
    }
    gt.validate()?;
    for (k, &(i, j)) in pairs.iter().enumerate() {
        if i >= p1.len() || j >= p2.len() {
            return Err(FeaturesError::invalid(
                format!("match {k}"),
                format!("indices ({i}, {j}) out of range ({} and {} keypoints)", p1.len(), p2.len()),
            ));
        }
    }
    let hinv = gt.h_inv();
    let tol = cfg.occlusion_tol_mm;
    let t12: Vec<Option<[f64; 2]>> = p1.par_iter().map(|&p| gt.transfer(p, true, hinv.as_ref(), tol)).collect();
    let t21: Vec<Option<[f64; 2]>> = p2.par_iter().map(|&p| gt.transfer(p, false, hinv.as_ref(), tol)).collect();
    let dist = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).hypot(a[1] - b[1]);
    let two_way = |i: usize, j: usize| -> Option<f64> {
        let (a, b) = (t12[i]?, t21[j]?);
        Some(0.5 * (dist(a, p2[j]) + dist(b, p1[i])))
    };
    // labels
    let mut labels = Vec::with_capacity(pairs.len());
    let mut errs = Vec::with_capacity(pairs.len());
    for &(i, j) in pairs {
        match two_way(i, j) {
            Some(e) => {
                labels.push(if e < cfg.eps_px { MatchLabel::Correct } else { MatchLabel::Wrong });
                errs.push(e);
            }
            None => {
                labels.push(MatchLabel::Unverifiable);
                errs.push(f64::NAN);
            }
        }
    }
    let n_correct = labels.iter().filter(|&&l| l == MatchLabel::Correct).count();
    let n_unverifiable = labels.iter().filter(|&&l| l == MatchLabel::Unverifiable).count();
    // common sets: C1 in image 2's frame (transferred), C2 as detected
    let c1: Vec<(usize, [f64; 2])> = (0..p1.len()).filter_map(|i| t12[i].map(|q| (i, q))).collect();
    let c2: Vec<(usize, [f64; 2])> = (0..p2.len()).filter_map(|j| t21[j].map(|_| (j, p2[j]))).collect();
    let c2_in1: Vec<(usize, [f64; 2])> = (0..p2.len()).filter_map(|j| t21[j].map(|q| (j, q))).collect();
    let c1_in1: Vec<(usize, [f64; 2])> = c1.iter().map(|&(i, _)| (i, p1[i])).collect();
    // repeatability (SuperPoint / features_ref.py): distances in image 2's frame
    let repeatability = if c1.is_empty() || c2.is_empty() {
        0.0
    } else {
        let eps = cfg.eps_px;
        let r1 = c1.par_iter().filter(|&&(_, q)| nearest(q, &c2).is_some_and(|(_, d)| d < eps)).count();
        let r2 = c2.par_iter().filter(|&&(_, q)| nearest(q, &c1).is_some_and(|(_, d)| d < eps)).count();
        0.5 * (r1 as f64 / c1.len() as f64 + r2 as f64 / c2.len() as f64)
    };
    // GT-matchable pairs: mutual nearest under transfer, two-way error < ε
    let nn12: Vec<Option<usize>> = c1.par_iter().map(|&(_, q)| nearest(q, &c2).map(|(j, _)| j)).collect();
    let mut nn21 = vec![usize::MAX; p2.len()];
    let nn21v: Vec<(usize, Option<usize>)> =
        c2_in1.par_iter().map(|&(j, q)| (j, nearest(q, &c1_in1).map(|(i, _)| i))).collect();
    for (j, i) in nn21v {
        if let Some(i) = i {
            nn21[j] = i;
        }
    }
    let mut matchable = std::collections::HashSet::new();
    for (k, &(i, _)) in c1.iter().enumerate() {
        if let Some(j) = nn12[k] {
            if nn21[j] == i && two_way(i, j).is_some_and(|e| e < cfg.eps_px) {
                matchable.insert((i, j));
            }
        }
    }
    let n_matchable = matchable.len();
    let correct_matchable = pairs
        .iter()
        .zip(&labels)
        .filter(|(p, &l)| l == MatchLabel::Correct && matchable.contains(p))
        .map(|(p, _)| *p)
        .collect::<std::collections::HashSet<_>>()
        .len();
    let ratio = |a: usize, b: usize| if b == 0 { 0.0 } else { a as f64 / b as f64 };
    Ok(MatchEval {
        n_matches: pairs.len(),
        n_correct,
        n_unverifiable,
        precision: ratio(n_correct, pairs.len()),
        precision_verifiable: ratio(n_correct, pairs.len() - n_unverifiable),
        recall: ratio(correct_matchable, n_matchable),
        n_matchable,
        matching_score: ratio(n_correct, c1.len()),
        repeatability,
        n_kp1_common: c1.len(),
        n_kp2_common: c2.len(),
        labels,
        transfer_error_px: errs,
    })
}
