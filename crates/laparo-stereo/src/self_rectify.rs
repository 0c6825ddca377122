//! Self-rectification of a raw stereo pair without a calibration (issue 14 item 3; thesis §3.3:
//! raw laparoscope pairs have small rotations and principal-point offsets).
//!
//! From matches: a robust fundamental matrix (laparo-features RANSAC), then one of
//! - [`RectifyMethod::QuasiEuclidean`] (Fusiello & Irsara, MVA 2011): H_L = K R_L K⁻¹,
//!   H_R = K R_R K_R⁻¹ with K = [f 0 c_x; 0 f c_y; 0 0 1] (c = image centre) and
//!   K_R = K with c_y + δ (a vertical principal-point offset of the right camera, which
//!   rotations represent only approximately). Unknowns: left Y, Z angles; right X, Y, Z angles
//!   (left X = 0 is the gauge: a common rotation about the baseline keeps a pair rectified); δ;
//!   the focal length f, searched over a grid of fields of view, then refined jointly.
//!   Minimised by Levenberg–Marquardt: the rectified vertical disparity y(H_L x_L) − y(H_R x_R)
//!   of the F-inliers (the quantity that must vanish; Fusiello minimises the Sampson error of
//!   the induced F, which equals it to first order for near-rectified pairs).
//! - [`RectifyMethod::Hartley`] (Hartley 1999; H&Z §11.12, OpenCV `stereoRectifyUncalibrated`):
//!   H_R = G R T sends the right epipole to infinity, H_L = H_A H_R M with M from F = [e']× M and
//!   H_A the x-affine least-squares fit. Projective, no distortion control (kept for comparison).
//!
//! Disparities are reported in the **raw left frame** with CATS' convention d = x_L − x_R
//! ([`SelfRectification::disparity_to_raw_left`]). A failed fit is an error, never a silent
//! identity.
use crate::error::{Result, StereoError};
use laparo_core::image::{Image, Mask};
use laparo_core::remap::{self, Interp, Texel};
use laparo_core::se3::rotation_zyx;
use laparo_features::ransac::{find_fundamental, RansacParams};
use laparo_features::FeaturesError;
use nalgebra::{DMatrix, DVector, Matrix3, Vector3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// A [`StereoError::Features`] naming the step.
fn features(what: &str, source: FeaturesError) -> StereoError {
    StereoError::Features { what: what.into(), source }
}

fn invalid(what: impl Into<String>, msg: impl Into<String>) -> StereoError {
    StereoError::invalid(what, msg)
}

/// A rectified image and its validity mask.
pub type Rectified<T> = (Image<T>, Mask);
/// Left and right points `[x, y]`, px.
pub type PointPairs = (Vec<[f64; 2]>, Vec<[f64; 2]>);

/// Which rectification to compute from F.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum RectifyMethod {
    /// Fusiello-style rotational (quasi-Euclidean) rectification (default).
    QuasiEuclidean,
    /// Hartley's projective rectification.
    Hartley,
}

/// Which keypoint matches [`match_self_rectified_with`] fits the rectification to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum FeatureKind {
    /// [`fast_matches`]: ORB (FAST + rotated BRIEF, 3 levels) on the full-resolution pair, Hamming
    /// 2-NN (Lowe 0.8 + mutual) guided by a coarse F, each match refined to sub-pixel by NCC.
    Fast,
    /// [`sift_matches`]: SIFT with OpenCV's 2× upsampled first octave, L2 brute force (slow).
    Sift,
}

impl std::str::FromStr for FeatureKind {
    type Err = StereoError;
    fn from_str(s: &str) -> Result<Self> {
        match s.to_ascii_lowercase().as_str() {
            "fast" | "orb" => Ok(FeatureKind::Fast),
            "sift" => Ok(FeatureKind::Sift),
            o => Err(invalid("self-rectify features", format!("'{o}' (expected fast or sift)"))),
        }
    }
}

/// Options of [`self_rectify`].
#[derive(Clone, Debug, PartialEq)]
pub struct SelfRectifyOptions {
    /// Keypoint matches used by [`match_self_rectified_with`] (not by [`self_rectify`], which takes matches).
    pub features: FeatureKind,
    /// RANSAC for F (threshold in px, Sampson distance).
    pub ransac: RansacParams,
    /// Fewer F-inliers than this is an error.
    pub min_inliers: usize,
    /// Rectification method.
    pub method: RectifyMethod,
    /// Horizontal fields of view (degrees) tried as starting focal lengths.
    pub fov_grid_deg: Vec<f64>,
    /// Largest acceptable rectifying rotation, degrees (beyond: error, the pair is not near-rectified).
    pub max_angle_deg: f64,
    /// Largest acceptable inlier median |dy| after rectification, px (beyond: error).
    pub max_median_dy_px: f64,
}

impl Default for SelfRectifyOptions {
    fn default() -> Self {
        SelfRectifyOptions {
            features: FeatureKind::Fast,
            // 0.3 px: the refined matches are accurate to ≈ 0.1 px; a looser threshold lets
            // 0.3–3 px mismatches bias the least-squares fit (CATS Motorcycle: median |dy| 0.15
            // at 1 px, 0.07 at 0.3 px with fast matches; 0.040 → 0.024 with SIFT)
            ransac: RansacParams { threshold_px: 0.3, confidence: 0.999, max_iters: 5000, seed: 0 },
            min_inliers: 20,
            method: RectifyMethod::QuasiEuclidean,
            fov_grid_deg: vec![20.0, 40.0, 60.0, 80.0, 100.0, 120.0],
            max_angle_deg: 15.0,
            max_median_dy_px: 1.0,
        }
    }
}

/// |dy| statistics of correspondences, px.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct DyStats {
    /// Number of correspondences.
    pub n: usize,
    /// Median |dy|.
    pub median_abs: f64,
    /// 95th percentile of |dy|.
    pub p95_abs: f64,
    /// Largest |dy|.
    pub max_abs: f64,
    /// Mean signed dy (y_R − y_L).
    pub mean: f64,
}

impl DyStats {
    /// Statistics of signed vertical offsets (y_R − y_L), px. Empty input: all NaN, n = 0.
    pub fn of(dy: &[f64]) -> DyStats {
        if dy.is_empty() {
            return DyStats { n: 0, median_abs: f64::NAN, p95_abs: f64::NAN, max_abs: f64::NAN, mean: f64::NAN };
        }
        let mut a: Vec<f64> = dy.iter().map(|v| v.abs()).collect();
        a.sort_by(f64::total_cmp);
        let q = |p: f64| {
            let t = p * (a.len() - 1) as f64;
            let i = t.floor() as usize;
            let j = (i + 1).min(a.len() - 1);
            a[i] + (a[j] - a[i]) * (t - i as f64)
        };
        DyStats {
            n: dy.len(),
            median_abs: laparo_core::stats::median(&mut a.clone()),
            p95_abs: q(0.95),
            max_abs: a[a.len() - 1],
            mean: dy.iter().sum::<f64>() / dy.len() as f64,
        }
    }
}

/// A self-rectification: homographies raw → rectified for both images, and its diagnostics.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SelfRectification {
    /// Method used.
    pub method: RectifyMethod,
    /// Raw image size (width, height), px.
    pub size: (usize, usize),
    /// Rectified canvas size (width, height), px: large enough for both rectified images (the
    /// homographies include the canvas offset), so no raw pixel is cropped away.
    pub rectified_size: (usize, usize),
    /// Left raw → rectified homography, row-major.
    pub h_left: [[f64; 3]; 3],
    /// Right raw → rectified homography, row-major.
    pub h_right: [[f64; 3]; 3],
    /// Robust fundamental matrix of the raw pair, x_Rᵀ F x_L = 0, row-major.
    pub fundamental: [[f64; 3]; 3],
    /// Quasi-Euclidean only: focal length, px.
    pub focal_px: Option<f64>,
    /// Quasi-Euclidean only: Z-Y-X Euler angles [x, y, z] of R_L, degrees (x = 0, gauge).
    pub left_euler_deg: Option<[f64; 3]>,
    /// Quasi-Euclidean only: Z-Y-X Euler angles [x, y, z] of R_R, degrees.
    pub right_euler_deg: Option<[f64; 3]>,
    /// Quasi-Euclidean only: vertical principal-point offset δ of the right camera, px.
    pub right_cy_offset_px: Option<f64>,
    /// Matches given.
    pub n_matches: usize,
    /// F-inliers used for the rectification.
    pub n_inliers: usize,
    /// Inlier flags (F-RANSAC inliers that also survived the rectification fit).
    pub inliers: Vec<bool>,
    /// Inliers' raw vertical offsets y_R − y_L before rectification.
    pub dy_raw: DyStats,
    /// Inliers' vertical offsets after rectification.
    pub dy_rectified: DyStats,
    /// Largest displacement of an image corner by H_L or H_R, px (distortion indicator).
    pub max_corner_shift_px: f64,
}

fn rows(m: &Matrix3<f64>) -> [[f64; 3]; 3] {
    [[m[(0, 0)], m[(0, 1)], m[(0, 2)]], [m[(1, 0)], m[(1, 1)], m[(1, 2)]], [m[(2, 0)], m[(2, 1)], m[(2, 2)]]]
}
fn mat(r: &[[f64; 3]; 3]) -> Matrix3<f64> {
    Matrix3::new(r[0][0], r[0][1], r[0][2], r[1][0], r[1][1], r[1][2], r[2][0], r[2][1], r[2][2])
}
#[inline]
fn hp(h: &Matrix3<f64>, x: f64, y: f64) -> Option<[f64; 2]> {
    let w = h[(2, 0)] * x + h[(2, 1)] * y + h[(2, 2)];
    if w.abs() < 1e-12 {
        return None;
    }
    Some([(h[(0, 0)] * x + h[(0, 1)] * y + h[(0, 2)]) / w, (h[(1, 0)] * x + h[(1, 1)] * y + h[(1, 2)]) / w])
}

impl SelfRectification {
    /// H_L (raw left → rectified).
    pub fn h_left(&self) -> Matrix3<f64> {
        mat(&self.h_left)
    }
    /// H_R (raw right → rectified).
    pub fn h_right(&self) -> Matrix3<f64> {
        mat(&self.h_right)
    }
    /// Raw left px → rectified px.
    pub fn rectify_left(&self, x: f64, y: f64) -> Option<[f64; 2]> {
        hp(&self.h_left(), x, y)
    }
    /// Raw right px → rectified px.
    pub fn rectify_right(&self, x: f64, y: f64) -> Option<[f64; 2]> {
        hp(&self.h_right(), x, y)
    }
    /// Rectified left px → raw left px.
    pub fn raw_left(&self, u: f64, v: f64) -> Option<[f64; 2]> {
        hp(&self.h_left().try_inverse()?, u, v)
    }
    /// Rectified right px → raw right px.
    pub fn raw_right(&self, u: f64, v: f64) -> Option<[f64; 2]> {
        hp(&self.h_right().try_inverse()?, u, v)
    }

    /// A rectified left pixel (u, v) with rectified disparity d_rect (u_R = u − d_rect) mapped to
    /// the raw frames: (raw left x, raw left y, raw d = x_L − x_R, raw dy = y_R − y_L), px.
    pub fn to_raw(&self, u: f64, v: f64, d_rect: f64) -> Option<[f64; 4]> {
        let l = self.raw_left(u, v)?;
        let r = self.raw_right(u - d_rect, v)?;
        Some([l[0], l[1], l[0] - r[0], r[1] - l[1]])
    }

    /// Map a disparity map computed on the rectified pair (indexed by the rectified left pixel,
    /// u_R = u − d; non-finite = invalid) to the raw left frame: for every raw left pixel p the
    /// rectified disparity at H_L p ([`sample_disparity`]: bilinear inside a smooth 2 × 2 cell,
    /// nearest across a disparity edge) gives the raw right point; returns
    /// (raw disparity x_L − x_R, raw vertical offset y_R − y_L), +inf / NaN where invalid or where
    /// the raw right point falls outside the right image (a match against the warp's fill).
    pub fn disparity_to_raw_left(&self, d_rect: &Image<f32>) -> Result<(Image<f32>, Image<f32>)> {
        if d_rect.channels != 1 {
            return Err(invalid("rectified disparity", format!("{} channels (need 1)", d_rect.channels)));
        }
        let (w, h) = self.size;
        let hl = self.h_left();
        let hri = self.h_right().try_inverse().ok_or_else(|| invalid("h_right", "singular"))?;
        let mut d = Image::filled(w, h, 1, f32::INFINITY);
        let mut dy = Image::filled(w, h, 1, f32::NAN);
        d.data.par_chunks_mut(w).zip(dy.data.par_chunks_mut(w)).enumerate().for_each(|(y, (dr, yr))| {
            for x in 0..w {
                let Some(q) = hp(&hl, x as f64, y as f64) else { continue };
                let Some(v) = sample_disparity(d_rect, q[0], q[1]) else { continue };
                let Some(r) = hp(&hri, q[0] - v as f64, q[1]) else { continue };
                // a match outside the raw right image is a match against the warp's fill
                if !(r[0] >= 0.0 && r[0] <= (w - 1) as f64 && r[1] >= 0.0 && r[1] <= (h - 1) as f64) {
                    continue;
                }
                dr[x] = (x as f64 - r[0]) as f32;
                yr[x] = (r[1] - y as f64) as f32;
            }
        });
        Ok((d, dy))
    }

    /// Warp a raw image pair to the rectified canvas (`rectified_size`; bilinear, laparo-core's
    /// sampler, as OpenCV's `warpPerspective` with `INTER_LINEAR`): for display and saving.
    pub fn rectify_images<T: Texel + Default>(
        &self,
        left: &Image<T>,
        right: &Image<T>,
    ) -> Result<(Rectified<T>, Rectified<T>)> {
        self.rectify_images_with(left, right, Interp::Bilinear)
    }

    /// [`Self::rectify_images`] with a chosen interpolation. The matcher
    /// ([`match_self_rectified_with`]) warps its grey inputs bicubically ([`MATCH_INTERP`]).
    pub fn rectify_images_with<T: Texel + Default>(
        &self,
        left: &Image<T>,
        right: &Image<T>,
        interp: Interp,
    ) -> Result<(Rectified<T>, Rectified<T>)> {
        let (w, h) = self.size;
        let (rw, rh) = self.rectified_size;
        for (name, img) in [("left image", left), ("right image", right)] {
            if (img.width, img.height) != (w, h) {
                return Err(StereoError::SizeMismatch(format!(
                    "{name} is {}x{}, the rectification was fitted for {w}x{h}",
                    img.width, img.height
                )));
            }
        }
        let il = self.h_left().try_inverse().ok_or_else(|| invalid("h_left", "singular"))?;
        let ir = self.h_right().try_inverse().ok_or_else(|| invalid("h_right", "singular"))?;
        let l = remap::warp_homography(left, &rows(&il), rw, rh, interp, T::default())?;
        let r = remap::warp_homography(right, &rows(&ir), rw, rh, interp, T::default())?;
        Ok((l, r))
    }
}

/// The interpolation of the matcher's rectification warps: Keys bicubic. A CATS-perturbed pair has
/// already been resampled once; a second bilinear pass blurs the texture census compares, and
/// costs 3–8 % EPE against bicubic on the Middlebury CATS pairs (BENCHMARKS.md, issue 14, stop 25).
/// Grey `u8` bicubic has a fused AVX2 path in laparo-core (1.04–1.07× OpenCV's `INTER_CUBIC`).
pub const MATCH_INTERP: Interp = Interp::Bicubic;

/// A disparity map sampled at (x, y) by the core's edge-aware lookup
/// (`laparo_core::remap::sample_smooth`, span 1 px): bilinear when the four surrounding samples are
/// valid and within 1 px of each other, otherwise the nearest sample (no blending across a
/// disparity edge); `None` outside the map or where the chosen sample is invalid.
pub fn sample_disparity(d: &Image<f32>, x: f64, y: f64) -> Option<f32> {
    let w = d.width;
    remap::sample_smooth(w, d.height, x, y, 1.0f32, |i, j| {
        let v = d.data[j * w + i];
        v.is_finite().then_some(v)
    })
    .map(|v| v as f32)
}

/// Quasi-Euclidean model parameters: [yL, zL, xR, yR, zR] (rad), δ (px), ln(f / f0).
#[derive(Clone, Copy, Debug)]
struct Model {
    p: [f64; 7],
    f0: f64,
    c: [f64; 2],
}

impl Model {
    fn f(&self) -> f64 {
        self.f0 * self.p[6].exp()
    }
    fn k(&self, dcy: f64) -> Matrix3<f64> {
        let f = self.f();
        Matrix3::new(f, 0.0, self.c[0], 0.0, f, self.c[1] + dcy, 0.0, 0.0, 1.0)
    }
    fn kinv(&self, dcy: f64) -> Matrix3<f64> {
        let f = self.f();
        Matrix3::new(1.0 / f, 0.0, -self.c[0] / f, 0.0, 1.0 / f, -(self.c[1] + dcy) / f, 0.0, 0.0, 1.0)
    }
    fn hl(&self) -> Matrix3<f64> {
        self.k(0.0) * rotation_zyx(0.0, self.p[0], self.p[1]) * self.kinv(0.0)
    }
    fn hr(&self) -> Matrix3<f64> {
        self.k(0.0) * rotation_zyx(self.p[2], self.p[3], self.p[4]) * self.kinv(self.p[5])
    }
}

fn residuals(hl: &Matrix3<f64>, hr: &Matrix3<f64>, pl: &[[f64; 2]], pr: &[[f64; 2]], idx: &[usize], out: &mut [f64]) {
    for (k, &i) in idx.iter().enumerate() {
        let a = hp(hl, pl[i][0], pl[i][1]);
        let b = hp(hr, pr[i][0], pr[i][1]);
        out[k] = match (a, b) {
            (Some(a), Some(b)) => a[1] - b[1],
            _ => 1e6,
        };
    }
}

/// Corner displacement terms of [`model_residuals`]: 4 corners × 2 images × (x, y).
const DISTORTION_TERMS: usize = 16;

/// Weight of the distortion terms (per px of corner displacement): the rotational model has
/// directions the matches do not observe (f, a common yaw, pitch against δ for a near-rectified
/// pair); these terms pick, among rectifications of equal |dy|, the one closest to the raw images.
/// 1e-2: a 100 px corner displacement costs as much as 1 px of dy on one match (the fits use hundreds).
const DISTORTION_WEIGHT: f64 = 1e-2;

/// The rectified dy of the matches `idx`, then the weighted displacements of the image corners by
/// H_L and H_R.
fn model_residuals(m: &Model, pl: &[[f64; 2]], pr: &[[f64; 2]], idx: &[usize], out: &mut [f64]) {
    let (hl, hr) = (m.hl(), m.hr());
    residuals(&hl, &hr, pl, pr, idx, &mut out[..idx.len()]);
    let (w, h) = (2.0 * m.c[0], 2.0 * m.c[1]);
    let mut k = idx.len();
    for hh in [&hl, &hr] {
        for c in [[0.0, 0.0], [w, 0.0], [0.0, h], [w, h]] {
            let q = hp(hh, c[0], c[1]).unwrap_or([1e6, 1e6]);
            out[k] = DISTORTION_WEIGHT * (q[0] - c[0]);
            out[k + 1] = DISTORTION_WEIGHT * (q[1] - c[1]);
            k += 2;
        }
    }
}

/// Levenberg–Marquardt on the rectified dy over `idx`; `free` selects the parameters.
/// f stays within `f_range` (px): a step leaving it counts as a failed step.
fn lm(m0: Model, pl: &[[f64; 2]], pr: &[[f64; 2]], idx: &[usize], free: &[usize], f_range: (f64, f64)) -> (Model, f64) {
    let n = idx.len() + DISTORTION_TERMS;
    let mut m = m0;
    let mut r = vec![0.0; n];
    model_residuals(&m, pl, pr, idx, &mut r);
    let mut cost: f64 = r.iter().map(|v| v * v).sum();
    let mut lambda = 1e-3;
    let steps = [1e-6, 1e-6, 1e-6, 1e-6, 1e-6, 1e-3, 1e-6];
    let mut rp = vec![0.0; n];
    for _ in 0..100 {
        let mut j = DMatrix::<f64>::zeros(n, free.len());
        for (c, &k) in free.iter().enumerate() {
            let mut mp = m;
            mp.p[k] += steps[k];
            model_residuals(&mp, pl, pr, idx, &mut rp);
            for i in 0..n {
                j[(i, c)] = (rp[i] - r[i]) / steps[k];
            }
        }
        let jt = j.transpose();
        let jtj = &jt * &j;
        let g = &jt * DVector::from_column_slice(&r);
        let mut improved = false;
        for _ in 0..10 {
            let mut a = jtj.clone();
            for d in 0..free.len() {
                a[(d, d)] += lambda * jtj[(d, d)].max(1e-12);
            }
            let Some(delta) = a.cholesky().map(|ch| ch.solve(&(-&g))) else {
                lambda *= 10.0;
                continue;
            };
            let mut mt = m;
            for (c, &k) in free.iter().enumerate() {
                mt.p[k] += delta[c];
            }
            if !(f_range.0..=f_range.1).contains(&mt.f()) {
                lambda *= 10.0;
                continue;
            }
            model_residuals(&mt, pl, pr, idx, &mut rp);
            let ct: f64 = rp.iter().map(|v| v * v).sum();
            if ct < cost {
                let rel = (cost - ct) / cost.max(1e-300);
                m = mt;
                std::mem::swap(&mut r, &mut rp);
                cost = ct;
                lambda = (lambda * 0.3).max(1e-12);
                improved = rel > 1e-12;
                break;
            }
            lambda *= 10.0;
        }
        if !improved {
            break;
        }
    }
    (m, cost)
}

fn check_matches(pl: &[[f64; 2]], pr: &[[f64; 2]], size: (usize, usize)) -> Result<()> {
    if pl.len() != pr.len() {
        return Err(StereoError::SizeMismatch(format!("{} left points vs {} right points", pl.len(), pr.len())));
    }
    if size.0 < 2 || size.1 < 2 {
        return Err(invalid("image size", format!("{}x{} (need at least 2x2)", size.0, size.1)));
    }
    Ok(())
}

/// (H_L, H_R, canvas size) of [`canvas`].
type Canvas = (Matrix3<f64>, Matrix3<f64>, (usize, usize));

/// The rectified canvas: both raw images' corners mapped by their homography, the union of the two
/// boxes (rows are shared, so the vertical extent is common); the homographies are shifted by a whole
/// number of pixels so the canvas starts at (0, 0). Errors when the canvas would exceed 2× the raw size
/// (the pair is not near-rectified).
fn canvas(hl: &Matrix3<f64>, hr: &Matrix3<f64>, size: (usize, usize)) -> Result<Canvas> {
    let (w, h) = (size.0 as f64 - 1.0, size.1 as f64 - 1.0);
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for hh in [hl, hr] {
        for c in [[0.0, 0.0], [w, 0.0], [0.0, h], [w, h]] {
            let q = hp(hh, c[0], c[1]).ok_or_else(|| invalid("self-rectification", "a corner maps to infinity"))?;
            for k in 0..2 {
                lo[k] = lo[k].min(q[k]);
                hi[k] = hi[k].max(q[k]);
            }
        }
    }
    let (x0, y0) = (lo[0].ceil(), lo[1].ceil());
    let (cw, ch) = ((hi[0].floor() - x0) as usize + 1, (hi[1].floor() - y0) as usize + 1);
    if cw > 2 * size.0 || ch > 2 * size.1 {
        return Err(invalid(
            "self-rectification",
            format!(
                "the rectified canvas would be {cw}x{ch} px for {}x{} images: not a near-rectified pair",
                size.0, size.1
            ),
        ));
    }
    let t = Matrix3::new(1.0, 0.0, -x0, 0.0, 1.0, -y0, 0.0, 0.0, 1.0);
    Ok((t * hl, t * hr, (cw, ch)))
}

/// Self-rectify a raw pair from matched points (left `[x, y]` ↔ right `[x, y]`, px) of images of
/// `size` = (width, height). Errors (naming the input): too few matches or F-inliers, a
/// degenerate F, a rectification needing rotations beyond `max_angle_deg`, or a residual median
/// |dy| above `max_median_dy_px`.
pub fn self_rectify(
    pl: &[[f64; 2]],
    pr: &[[f64; 2]],
    size: (usize, usize),
    opts: &SelfRectifyOptions,
) -> Result<SelfRectification> {
    check_matches(pl, pr, size)?;
    if pl.len() < opts.min_inliers.max(8) {
        return Err(invalid(
            "self-rectification matches",
            format!("too few matches: {} (need at least {})", pl.len(), opts.min_inliers.max(8)),
        ));
    }
    let fit = find_fundamental(pl, pr, &opts.ransac).map_err(|e| features("self-rectification matches", e))?;
    if fit.n_inliers < opts.min_inliers {
        return Err(invalid(
            "self-rectification matches",
            format!("only {} F-inliers of {} matches (need {})", fit.n_inliers, pl.len(), opts.min_inliers),
        ));
    }
    let idx: Vec<usize> = (0..pl.len()).filter(|&i| fit.inliers[i]).collect();
    let dy_raw: Vec<f64> = idx.iter().map(|&i| pr[i][1] - pl[i][1]).collect();
    let (w, h) = (size.0 as f64, size.1 as f64);
    let corners = [[0.0, 0.0], [w - 1.0, 0.0], [0.0, h - 1.0], [w - 1.0, h - 1.0]];
    let (hl, hr, extra, kept) = match opts.method {
        RectifyMethod::QuasiEuclidean => {
            let c = [(w - 1.0) / 2.0, (h - 1.0) / 2.0];
            for &fov in &opts.fov_grid_deg {
                if !(fov > 1.0 && fov < 179.0) {
                    return Err(invalid("fov_grid_deg", format!("{fov} (need 1 < fov < 179)")));
                }
            }
            // focal search on a subsample (≤ 400 inliers, evenly spaced), in parallel; the best
            // start by (cost, grid index) is then refined on all inliers (thread-count independent)
            let sub: Vec<usize> = idx.iter().copied().step_by(idx.len().div_ceil(400).max(1)).collect();
            let (f_lo, f_hi) = (0.5 * w / 70f64.to_radians().tan(), 0.5 * w / 5f64.to_radians().tan());
            let cands: Vec<(Model, f64, bool)> = opts
                .fov_grid_deg
                .par_iter()
                .map(|&fov| {
                    let f0 = 0.5 * w / (0.5 * fov.to_radians()).tan();
                    let m0 = Model { p: [0.0; 7], f0, c };
                    // f stays within the plausible focal range (field of view 10°..140°)
                    let (m1, c1) = lm(m0, pl, pr, &sub, &[0, 1, 2, 3, 4, 5], (f_lo, f_hi));
                    let (m2, c2) = lm(m1, pl, pr, &sub, &[0, 1, 2, 3, 4, 5, 6], (f_lo, f_hi));
                    // f joins the model only when the data support it (BIC: the cost must drop by
                    // more than ln n noise variances); on a near-rectified pair it is unobservable and
                    // a free f drifts to a bound, which distorts the rectified images for nothing
                    let n = sub.len() as f64;
                    if c1 - c2 <= n.ln() * c2 / (n - 7.0).max(1.0) {
                        (m1, c1, true)
                    } else {
                        (m2, c2, true)
                    }
                })
                .collect();
            let mut best: Option<(Model, f64, bool)> = None;
            for cnd in cands {
                if best.as_ref().is_none_or(|b| cnd.1 < b.1) {
                    best = Some(cnd);
                }
            }
            let Some((m, _, _)) = best else { return Err(invalid("fov_grid_deg", "empty")) };
            // final fit on all inliers at the chosen focal length
            let all: &[usize] = &[0, 1, 2, 3, 4, 5];
            let best = Some(lm(m, pl, pr, &idx, all, (f_lo, f_hi)));
            let Some((mut m, _)) = best else { return Err(invalid("fov_grid_deg", "empty")) };
            // drop F-inliers the rectification does not explain (> 3 × threshold) and refit once
            let mut r = vec![0.0; idx.len()];
            residuals(&m.hl(), &m.hr(), pl, pr, &idx, &mut r);
            let t = 3.0 * opts.ransac.threshold_px;
            let kept: Vec<usize> = idx.iter().zip(&r).filter(|(_, v)| v.abs() < t).map(|(&i, _)| i).collect();
            if kept.len() < opts.min_inliers {
                return Err(invalid(
                    "self-rectification matches",
                    format!("the rotational model explains only {} of {} F-inliers", kept.len(), idx.len()),
                ));
            }
            if kept.len() < idx.len() {
                m = lm(m, pl, pr, &kept, all, (f_lo, f_hi)).0;
            }
            let deg = |v: f64| v.to_degrees();
            let big = m.p[..5].iter().map(|v| deg(v.abs())).fold(0.0, f64::max);
            if big > opts.max_angle_deg {
                return Err(invalid(
                    "self-rectification",
                    format!(
                        "needs a rotation of {big:.2}° (> max_angle_deg {}): not a near-rectified pair",
                        opts.max_angle_deg
                    ),
                ));
            }
            let extra = (
                Some(m.f()),
                Some([0.0, deg(m.p[0]), deg(m.p[1])]),
                Some([deg(m.p[2]), deg(m.p[3]), deg(m.p[4])]),
                Some(m.p[5]),
            );
            (m.hl(), m.hr(), extra, kept)
        }
        RectifyMethod::Hartley => {
            let (hl, hr) = hartley(&fit.model, pl, pr, &idx, size)?;
            (hl, hr, (None, None, None, None), idx.clone())
        }
    };
    let mut dy = vec![0.0; kept.len()];
    residuals(&hl, &hr, pl, pr, &kept, &mut dy);
    dy.iter_mut().for_each(|v| *v = -*v); // y_R − y_L
    let dy_rectified = DyStats::of(&dy);
    if dy_rectified.median_abs.is_nan() || dy_rectified.median_abs > opts.max_median_dy_px {
        return Err(invalid(
            "self-rectification",
            format!(
                "residual median |dy| {:.3} px exceeds max_median_dy_px {} ({} inliers)",
                dy_rectified.median_abs,
                opts.max_median_dy_px,
                kept.len()
            ),
        ));
    }
    let mut shift: f64 = 0.0;
    for hh in [&hl, &hr] {
        for c in corners {
            let q = hp(hh, c[0], c[1]).ok_or_else(|| invalid("self-rectification", "a corner maps to infinity"))?;
            shift = shift.max((q[0] - c[0]).hypot(q[1] - c[1]));
        }
    }
    let (hl, hr, rectified_size) = canvas(&hl, &hr, size)?;
    let mut inliers = vec![false; pl.len()];
    for &i in &kept {
        inliers[i] = true;
    }
    Ok(SelfRectification {
        method: opts.method,
        size,
        rectified_size,
        h_left: rows(&hl),
        h_right: rows(&hr),
        fundamental: rows(&fit.model),
        focal_px: extra.0,
        left_euler_deg: extra.1,
        right_euler_deg: extra.2,
        right_cy_offset_px: extra.3,
        n_matches: pl.len(),
        n_inliers: kept.len(),
        inliers,
        dy_raw: DyStats::of(&dy_raw),
        dy_rectified,
        max_corner_shift_px: shift,
    })
}

/// Hartley's rectification (H&Z §11.12.2) from F (x_Rᵀ F x_L = 0) and inliers.
fn hartley(
    f: &Matrix3<f64>,
    pl: &[[f64; 2]],
    pr: &[[f64; 2]],
    idx: &[usize],
    size: (usize, usize),
) -> Result<(Matrix3<f64>, Matrix3<f64>)> {
    let svd = f.svd(true, true);
    let u = svd.u.ok_or_else(|| invalid("fundamental matrix", "SVD failed"))?;
    let mut k = 0;
    for i in 1..3 {
        if svd.singular_values[i] < svd.singular_values[k] {
            k = i;
        }
    }
    let e: Vector3<f64> = u.column(k).into(); // right epipole: eᵀ F = 0
    let (cx, cy) = ((size.0 as f64 - 1.0) / 2.0, (size.1 as f64 - 1.0) / 2.0);
    let t = Matrix3::new(1.0, 0.0, -cx, 0.0, 1.0, -cy, 0.0, 0.0, 1.0);
    let et = t * e;
    // rotate the epipole onto the x axis with the smaller of the two possible angles
    let mut ang = et[1].atan2(et[0]);
    if ang > std::f64::consts::FRAC_PI_2 {
        ang -= std::f64::consts::PI;
    } else if ang < -std::f64::consts::FRAC_PI_2 {
        ang += std::f64::consts::PI;
    }
    let (s, c) = ang.sin_cos();
    let r = Matrix3::new(c, s, 0.0, -s, c, 0.0, 0.0, 0.0, 1.0);
    let er = r * et; // (ex, ~0, ez)
    if er[0].abs() < 1e-12 * er.norm() {
        return Err(invalid("fundamental matrix", "epipole at the image centre: Hartley rectification undefined"));
    }
    let g = Matrix3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, -er[2] / er[0], 0.0, 1.0);
    let hr = t.try_inverse().unwrap_or(Matrix3::identity()) * g * r * t;
    // M with F ∝ [e]× M: M = [e]× F + e vᵀ
    let ex = e.cross_matrix();
    let mm = ex * f + e * Vector3::new(1.0, 1.0, 1.0).transpose();
    let h0 = hr * mm;
    // H_A = [a b c; 0 1 0; 0 0 1] minimising Σ (a x̂ + b ŷ + c − x̂')²
    let mut ata = nalgebra::Matrix3::<f64>::zeros();
    let mut atb = Vector3::zeros();
    let mut dy0 = 0.0;
    for &i in idx {
        let (Some(a), Some(b)) = (hp(&h0, pl[i][0], pl[i][1]), hp(&hr, pr[i][0], pr[i][1])) else { continue };
        let row = Vector3::new(a[0], a[1], 1.0);
        ata += row * row.transpose();
        atb += row * b[0];
        dy0 += (a[1] - b[1]).abs();
    }
    let _ = dy0;
    let sol = ata.lu().solve(&atb).ok_or_else(|| invalid("self-rectification matches", "Hartley x-fit is singular"))?;
    let ha = Matrix3::new(sol[0], sol[1], sol[2], 0.0, 1.0, 0.0, 0.0, 0.0, 1.0);
    // translate back so the image centre stays near the centre (same shift for both views)
    let hl = ha * h0;
    Ok((hl, hr))
}

/// Exact correspondences of an augmented (CATS, exact rule) left disparity: every `step`-th
/// valid left pixel (x, y) ↔ (x − d, y + vertical residual). For evaluating self-rectification.
pub fn exact_correspondences(disp: &crate::augment::AugmentedDisparity, step: usize) -> Result<PointPairs> {
    let res = disp
        .vertical_residual
        .as_ref()
        .ok_or_else(|| invalid("augmented disparity", "no vertical residual (use the exact GT rule)"))?;
    if step == 0 {
        return Err(invalid("step", "0 (need at least 1)"));
    }
    let d = &disp.disparity;
    let (mut pl, mut pr) = (vec![], vec![]);
    for y in (0..d.height).step_by(step) {
        for x in (0..d.width).step_by(step) {
            let (v, r) = (d.get(x, y, 0), res.get(x, y, 0));
            if disp.valid.get(x, y, 0) && v.is_finite() && r.is_finite() {
                pl.push([x as f64, y as f64]);
                pr.push([x as f64 - v as f64, y as f64 + r as f64]);
            }
        }
    }
    Ok((pl, pr))
}

/// A CATS-style perturbation of a rectified pair for tests and benchmarks: per camera a rotation
/// (Z-Y-X Euler angles, degrees) and a principal-point shift (t_x, t_y), px (K_rel = [1 0 t_x;
/// 0 1 t_y; 0 0 1]).
pub fn perturbation(
    kl: laparo_core::Intrinsics,
    kr: laparo_core::Intrinsics,
    euler_left_deg: [f64; 3],
    euler_right_deg: [f64; 3],
    shift_left_px: [f64; 2],
    shift_right_px: [f64; 2],
) -> crate::augment::StereoAugmentation {
    use crate::augment::CameraAugmentation;
    use laparo_core::Distortion;
    let kr_of = |s: [f64; 2]| Matrix3::new(1.0, 0.0, s[0], 0.0, 1.0, s[1], 0.0, 0.0, 1.0);
    crate::augment::StereoAugmentation {
        left: CameraAugmentation::from_euler_deg(
            kl,
            Distortion::default(),
            euler_left_deg,
            kr_of(shift_left_px),
            Distortion::default(),
        ),
        right: CameraAugmentation::from_euler_deg(
            kr,
            Distortion::default(),
            euler_right_deg,
            kr_of(shift_right_px),
            Distortion::default(),
        ),
        dx_right_px: shift_left_px[0] - shift_right_px[0],
    }
}

/// SIFT keypoints of both images matched with Lowe 0.8 + mutual check (laparo-features defaults).
pub fn sift_matches(left: &Image<u8>, right: &Image<u8>) -> Result<PointPairs> {
    use laparo_features::DetectorConfig;
    let feat = |e| features("SIFT matching", e);
    let sift = DetectorConfig::by_name("sift").map_err(feat)?;
    detect_and_match(left, right, &sift).map_err(feat)
}

/// Keypoints of both images (`det`, in parallel) matched with Lowe 0.8 + mutual check, as point pairs.
fn detect_and_match(
    left: &Image<u8>,
    right: &Image<u8>,
    det: &laparo_features::DetectorConfig,
) -> std::result::Result<PointPairs, FeaturesError> {
    use laparo_features::{detect_and_describe, match_features, MatchConfig};
    let (fl, fr) = rayon::join(|| detect_and_describe(left, det, None), || detect_and_describe(right, det, None));
    let (fl, fr) = (fl?, fr?);
    let m = match_features(&fl, &fr, &MatchConfig::default())?;
    Ok(m.iter()
        .map(|m| {
            let (a, b) = (&fl.keypoints[m.i1 as usize], &fr.keypoints[m.i2 as usize]);
            ([a.x, a.y], [b.x, b.y])
        })
        .unzip())
}

/// Keypoint matches of a raw pair by `kind` ([`fast_matches`] or [`sift_matches`]).
pub fn feature_matches(left: &Image<u8>, right: &Image<u8>, kind: FeatureKind) -> Result<PointPairs> {
    match kind {
        FeatureKind::Fast => fast_matches(left, right),
        FeatureKind::Sift => sift_matches(left, right),
    }
}

/// Options of the fast matcher ([`fast_matches_with`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FastParams {
    /// ORB keypoints per image (laparo's port of `cv::ORB`).
    pub n_features: usize,
    /// ORB pyramid levels (× 1.2): a stereo pair has no scale change, so few levels suffice.
    pub n_levels: usize,
    /// Strongest keypoints per image (by ORB response) brute-force matched in the coarse stage.
    pub coarse_n: usize,
    /// RANSAC threshold of the coarse F, px (unrefined ORB positions).
    pub coarse_threshold_px: f64,
    /// Fewest coarse F-inliers (and at least 30 % of the coarse matches) for the guided stage;
    /// otherwise every keypoint is brute-force matched.
    pub min_coarse_inliers: usize,
    /// Half-width of the epipolar band of the guided stage, px.
    pub band_px: f64,
    /// Margin added on both sides of the coarse inliers' x_R − x_L range in the guided stage, px.
    pub dx_margin_px: f64,
}

impl Default for FastParams {
    fn default() -> Self {
        FastParams {
            n_features: 4000,
            n_levels: 3,
            coarse_n: 600,
            coarse_threshold_px: 1.0,
            min_coarse_inliers: 40,
            band_px: 3.0,
            dx_margin_px: 16.0,
        }
    }
}

/// ORB features of both grey images (the inputs of [`fast_match_stage`]).
pub struct FastFeatures {
    /// Left image, grey.
    pub left_gray: Image<u8>,
    /// Right image, grey.
    pub right_gray: Image<u8>,
    /// Left ORB keypoints and descriptors.
    pub left: laparo_features::Features,
    /// Right ORB keypoints and descriptors.
    pub right: laparo_features::Features,
}

/// How [`fast_match_stage`] matched.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum MatchRoute {
    /// Coarse brute force on the strongest keypoints, a coarse F, then matching along its
    /// epipolar bands.
    Guided {
        /// Coarse matches.
        coarse_matches: usize,
        /// Coarse F-inliers.
        coarse_inliers: usize,
        /// x_R − x_L range searched, px.
        dx_range_px: [f64; 2],
    },
    /// Brute force over all keypoints (the coarse fit failed or was too weak).
    Full,
}

fn feat_err(e: FeaturesError) -> StereoError {
    features("ORB matching", e)
}

/// Stage 1 of the fast matcher: grey conversion and ORB (`p.n_features`, `p.n_levels` × 1.2) of
/// both images, the two images concurrently.
pub fn fast_detect(left: &Image<u8>, right: &Image<u8>, p: &FastParams) -> Result<FastFeatures> {
    use laparo_features::{detect_and_describe, DetectorConfig, OrbParams};
    if left.size() != right.size() {
        return Err(StereoError::SizeMismatch(format!(
            "left image is {}x{}, right image is {}x{}",
            left.width, left.height, right.width, right.height
        )));
    }
    let orb = DetectorConfig::Orb(OrbParams { n_features: p.n_features, n_levels: p.n_levels, ..OrbParams::default() });
    let one = |img: &Image<u8>| {
        let g = laparo_features::detect::to_gray_u8(img);
        let f = detect_and_describe(&g, &orb, None);
        (g, f)
    };
    let ((gl, fl), (gr, fr)) = rayon::join(|| one(left), || one(right));
    Ok(FastFeatures { left_gray: gl, right_gray: gr, left: fl.map_err(feat_err)?, right: fr.map_err(feat_err)? })
}

/// The `n` strongest keypoints (ORB response descending, then index): their indices, ascending.
fn strongest(f: &laparo_features::Features, n: usize) -> Vec<usize> {
    let mut idx: Vec<usize> = (0..f.len()).collect();
    idx.sort_by(|&a, &b| f.keypoints[b].response.total_cmp(&f.keypoints[a].response).then(a.cmp(&b)));
    idx.truncate(n);
    idx.sort_unstable();
    idx
}

fn subset(f: &laparo_features::Features, idx: &[usize]) -> laparo_features::Features {
    laparo_features::Features {
        keypoints: idx.iter().map(|&i| f.keypoints[i]).collect(),
        descriptors: f.descriptors.select(idx),
    }
}

/// Stage 2 of the fast matcher: Lowe 0.8 + mutual Hamming matching. Coarse: brute force on the
/// `p.coarse_n` strongest keypoints of each image, refined ([`fast_refine`]), and a RANSAC F on
/// them (`p.coarse_threshold_px`); if it has ≥ `p.min_coarse_inliers` inliers and ≥ 30 % of the
/// coarse matches, every keypoint is matched only within `p.band_px` of its epipolar line and
/// within the inliers' x_R − x_L range ± `p.dx_margin_px` ([`laparo_features::guided`]), otherwise
/// by brute force over all keypoints ([`MatchRoute::Full`]). Returns unrefined point pairs.
pub fn fast_match_stage(ff: &FastFeatures, p: &FastParams) -> Result<(PointPairs, MatchRoute)> {
    use laparo_features::guided::match_features_guided;
    use laparo_features::{match_features, MatchConfig};
    let cfg = MatchConfig::default();
    let (fl, fr) = (&ff.left, &ff.right);
    let pairs = |m: &[laparo_features::Match], a: &laparo_features::Features, b: &laparo_features::Features| {
        m.iter()
            .map(|m| {
                let (k, l) = (&a.keypoints[m.i1 as usize], &b.keypoints[m.i2 as usize]);
                ([k.x, k.y], [l.x, l.y])
            })
            .unzip::<_, _, Vec<[f64; 2]>, Vec<[f64; 2]>>()
    };
    let (il, ir) = (strongest(fl, p.coarse_n), strongest(fr, p.coarse_n));
    let (cl, cr) = (subset(fl, &il), subset(fr, &ir));
    let coarse = match_features(&cl, &cr, &cfg).map_err(feat_err)?;
    // the coarse matches refined to sub-pixel (as the final ones) so that the coarse F is accurate
    let (ql, qr) = fast_refine(ff, &pairs(&coarse, &cl, &cr))?;
    let prm = RansacParams { threshold_px: p.coarse_threshold_px, confidence: 0.999, max_iters: 2000, seed: 0 };
    let fit = if ql.len() >= p.min_coarse_inliers.max(8) { find_fundamental(&ql, &qr, &prm).ok() } else { None };
    let m = match fit {
        Some(fit) if fit.n_inliers >= p.min_coarse_inliers && 10 * fit.n_inliers >= 3 * coarse.len() => {
            // disparity prior: the coarse inliers' x_R − x_L range widened by `dx_margin_px`
            let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
            for (i, (a, b)) in ql.iter().zip(&qr).enumerate() {
                if fit.inliers[i] {
                    lo = lo.min(b[0] - a[0]);
                    hi = hi.max(b[0] - a[0]);
                }
            }
            let dx = [lo - p.dx_margin_px, hi + p.dx_margin_px];
            let m = match_features_guided(fl, fr, &fit.model, p.band_px, Some(dx), &cfg).map_err(feat_err)?;
            let route =
                MatchRoute::Guided { coarse_matches: coarse.len(), coarse_inliers: fit.n_inliers, dx_range_px: dx };
            return Ok((pairs(&m, fl, fr), route));
        }
        _ => match_features(fl, fr, &cfg).map_err(feat_err)?,
    };
    Ok((pairs(&m, fl, fr), MatchRoute::Full))
}

/// Stage 3 of the fast matcher: every match refined at full resolution by an 11 × 11 NCC search
/// (±3 px) with a parabola fit and Lucas–Kanade steps (laparo-features `refine`; peak NCC ≥ 0.8):
/// the left point becomes its pixel, the right point sub-pixel. ORB positions of coarse pyramid
/// levels are only pixel-accurate at that level; this restores the sub-pixel accuracy the
/// rectification fit needs.
pub fn fast_refine(ff: &FastFeatures, m: &PointPairs) -> Result<PointPairs> {
    use laparo_features::refine::{refine_matches_ncc, RefineParams};
    let refined =
        refine_matches_ncc(&ff.left_gray, &ff.right_gray, &m.0, &m.1, &RefineParams::default()).map_err(feat_err)?;
    Ok(refined.into_iter().flatten().map(|r| (r.left, r.right)).unzip())
}

/// The fast matcher with default [`FastParams`]: [`fast_detect`] → [`fast_match_stage`] →
/// [`fast_refine`].
pub fn fast_matches(left: &Image<u8>, right: &Image<u8>) -> Result<PointPairs> {
    fast_matches_with(left, right, &FastParams::default()).map(|(m, _)| m)
}

/// [`fast_matches`] with explicit parameters; also returns the matching route taken.
pub fn fast_matches_with(left: &Image<u8>, right: &Image<u8>, p: &FastParams) -> Result<(PointPairs, MatchRoute)> {
    let ff = fast_detect(left, right, p)?;
    let (m, route) = fast_match_stage(&ff, p)?;
    Ok((fast_refine(&ff, &m)?, route))
}

/// Median over the inlier matches of how much the self-rectification changes their disparity
/// (rectified x_L − x_R minus raw x_L − x_R), px; 0 without inliers. A raw disparity range shifted by it
/// is the range to search on the rectified pair.
pub fn rectified_disparity_shift(sr: &SelfRectification, pl: &[[f64; 2]], pr: &[[f64; 2]]) -> f64 {
    let mut shift: Vec<f64> = pl
        .iter()
        .zip(pr)
        .zip(&sr.inliers)
        .filter(|(_, i)| **i)
        .filter_map(|((l, r), _)| {
            let (lr, rr) = (sr.rectify_left(l[0], l[1])?, sr.rectify_right(r[0], r[1])?);
            Some((lr[0] - rr[0]) - (l[0] - r[0]))
        })
        .collect();
    if shift.is_empty() {
        0.0
    } else {
        laparo_core::stats::median(&mut shift)
    }
}

/// Everything [`match_self_rectified`] computes.
pub struct SelfRectifiedMatch {
    /// Disparity (d = x_L − x_R, +inf invalid), vertical offset and confidence in the raw left frame.
    pub output: crate::sgm::SgmOutput,
    /// The rectification.
    pub rectification: SelfRectification,
    /// Keypoint matches used.
    pub n_matches: usize,
    /// Range searched on the rectified pair, [lo, hi) px.
    pub rectified_range_px: (i32, i32),
    /// The median disparity shift of the rectification (px), see [`rectified_disparity_shift`].
    pub median_disparity_shift_px: f64,
    /// The rectified left image (input channels, bilinear, for display; the matcher used a bicubic
    /// grey warp, [`MATCH_INTERP`]).
    pub left_rectified: Image<u8>,
    /// The rectified right image (as `left_rectified`).
    pub right_rectified: Image<u8>,
    /// The disparity on the rectified pair.
    pub disparity_rectified: Image<f32>,
}

/// A raw, uncalibrated pair → keypoint matches ([`FeatureKind::Fast`] by default) → self-rectification → SGM over the raw range
/// [`p.d_min`, `p.d_max`) shifted by the rectification (± 2 px) → disparity, dy and confidence mapped back
/// to the raw left frame (§3.3, CATS' convention).
pub fn match_self_rectified(
    left: &Image<u8>,
    right: &Image<u8>,
    p: &crate::sgm::SgmParams,
) -> Result<SelfRectifiedMatch> {
    match_self_rectified_with(left, right, p, &SelfRectifyOptions::default())
}

/// [`match_self_rectified`] with explicit options (keypoint matcher `opts.features`, RANSAC, method).
pub fn match_self_rectified_with(
    left: &Image<u8>,
    right: &Image<u8>,
    p: &crate::sgm::SgmParams,
    opts: &SelfRectifyOptions,
) -> Result<SelfRectifiedMatch> {
    let (w, h) = left.size();
    if right.size() != (w, h) {
        return Err(StereoError::SizeMismatch(format!(
            "left image is {w}x{h}, right image is {}x{}",
            right.width, right.height
        )));
    }
    let (pl, pr) = feature_matches(left, right, opts.features)?;
    let mut sr = self_rectify(&pl, &pr, (w, h), opts)?;
    let off = rectified_disparity_shift(&sr, &pl, &pr);
    let (lo, hi) = ((p.d_min as f64 + off).floor() as i32 - 2, (p.d_max as f64 + off).ceil() as i32 + 2);
    // centre the rectified disparity range on 0: shift the right image by the middle of the range
    // (a whole number of pixels) and refit the canvas; the left border strip SGM cannot match is then
    // half the range wide instead of its far end
    let mid = (lo + hi).div_euclid(2);
    let (lo, hi) = {
        let t = Matrix3::new(1.0, 0.0, mid as f64, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0);
        let (hl, hr, size2) = canvas(&sr.h_left(), &(t * sr.h_right()), (w, h))?;
        sr.h_left = rows(&hl);
        sr.h_right = rows(&hr);
        sr.rectified_size = size2;
        (lo - mid, hi - mid)
    };
    // the matcher warps the grey images bicubically (MATCH_INTERP); the images returned for display
    // keep their channels (bilinear, as `rectify_images`)
    let grey = |img: &Image<u8>| Image::from_vec(w, h, 1, crate::sgm::to_gray_u8(img));
    let (gl, gr) = (grey(left)?, grey(right)?);
    let ((lg, ml), (rg, mr)) = sr.rectify_images_with(&gl, &gr, MATCH_INTERP)?;
    let ((l, _), (r, _)) = sr.rectify_images(left, right)?;
    // SGM sees the canvas outside each raw image as the row's nearest image pixel, not as black:
    // a black wedge has census codes that match each other and pulls paths astray near it
    let (lm_, rm_) = (crate::sgm::extend_rows(&lg, &ml), crate::sgm::extend_rows(&rg, &mr));
    let o = crate::sgm::match_pair(&lm_, &rm_, &crate::sgm::SgmParams { d_min: lo, d_max: hi, ..p.clone() })?;
    let (d, dy) = sr.disparity_to_raw_left(&o.disparity)?;
    let hl = sr.h_left();
    let mut conf = Image::filled(w, h, 1, 0f32);
    for y in 0..h {
        for x in 0..w {
            if d.get(x, y, 0).is_finite() {
                let q = hl * Vector3::new(x as f64, y as f64, 1.0);
                if let Some(c) = o.confidence.sample_nearest(q.x / q.z, q.y / q.z, 0) {
                    conf.set(x, y, 0, c);
                }
            }
        }
    }
    let n_valid = d.data.iter().filter(|v| v.is_finite()).count();
    let stats = crate::sgm::SgmStats { n_valid, ..o.stats.clone() };
    Ok(SelfRectifiedMatch {
        output: crate::sgm::SgmOutput { disparity: d, confidence: conf, dy: Some(dy), stats },
        rectification: sr,
        n_matches: pl.len(),
        rectified_range_px: (lo, hi),
        median_disparity_shift_px: off,
        left_rectified: l,
        right_rectified: r,
        disparity_rectified: o.disparity,
    })
}
