//! Stereo calibration statistics (thesis §3.3.4, Table 3.6): how far a real stereo laparoscope
//! is from the ideal rectified, principal-point-aligned configuration.
//!
//! # The ideal rectified stereo frame S
//! A calibration gives `R`, `T` of the right camera with respect to the left one, OpenCV
//! `stereoCalibrate` convention: `X_right = R X_left + T` (T in mm). The right optical centre in
//! left-camera coordinates is `C = −Rᵀ T`, the baseline is `b = |T|` and its direction `ĉ = C / |C|`.
//!
//! S has its origin at the left optical centre and its X axis along the baseline,
//! `x_s = sign(ĉ_x) ĉ` (the sign keeps X pointing "to the right" of the left camera, as
//! OpenCV's `stereoRectify` does with `uu = (±1, 0, 0)`). Its Y and Z axes are those of the left
//! camera carried by the *minimal* rotation that takes the left camera's X axis onto `x_s`:
//! the rotation about the axis `e_x × x_s` by the angle `acos(e_x · x_s)` (the geodesic of SO(3)).
//! This is exactly the rectified frame of Bouguet's algorithm (OpenCV `stereoRectify`, `R1`)
//! without the half-rotation split, i.e. with `r_r = I` and the translation expressed in the
//! left frame: OpenCV's `wR` maps left coordinates to S, `X_s = wR X_left`.
//!
//! # Per-camera rotations (eq. 3.7–3.8)
//! For each camera c the rotation *from* the ideal frame is `R_c` with `X_c = R_c X_s`:
//! `R_left = wRᵀ` and `R_right = R · wRᵀ`. This is the rotation CATS samples: a camera rotated
//! by `R_c` from the ideal one sees an ideal pixel p at `p' ~ K R_c K⁻¹ p` (eq. 3.8). Its Euler
//! angles are reported as `[x, y, z]` in degrees with `R_c = Rz(z) Ry(y) Rx(x)` (eq. 3.7). The
//! transposed convention (`X_s = R X_c`, camera-to-stereo) negates the angles to first order.
//! With this convention, a right camera that sits slightly below the left one
//! (`C_y > 0`, image y points down) gives a positive z angle for both cameras, and a right camera
//! behind the left one (`C_z < 0`) a positive y angle.
//!
//! # Other quantities
//! Principal-point offset `c_x^L − c_x^R` (px; the disparity offset of §3.3.8, negative for the
//! da Vinci laparoscopes), baseline (mm), and the largest displacement (px) that lens distortion
//! causes inside the image: `max |D(p) − p|` over a grid of pixels p of the image (at most
//! [`DISTORTION_GRID`] + 1 samples per side, always including the border rows and columns where
//! radial distortion peaks), D the distortion of an ideal pixel
//! ([`laparo_core::camera::Distortion::max_displacement_px`]).
use crate::cats_params::{CameraDist, CatsConfig, DisparityOffsetDist, Dist, EulerDist};
use crate::error::{Result, StereoError};
use laparo_core::calib::StereoCalibration;
use laparo_core::se3::euler_zyx;
use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};

/// Euler angles (deg) above which a rectifying rotation is flagged as odd. The thesis measures
/// rotations "well below 1°" on da Vinci laparoscopes (§3.3.4).
pub const LARGE_ROTATION_DEG: f64 = 5.0;
/// Lens-distortion displacement (px) above which a calibration is flagged. The thesis measures
/// "consistently below half a pixel" (§3.3.4); over the whole image, corners included, the real
/// SCARED and EndoVis calibrations reach 0.24–0.76 px, so laparo flags only what exceeds 1 px.
pub const LARGE_DISTORTION_PX: f64 = 1.0;
/// Tolerance on `|RᵀR − I|` (max abs entry) before R is called "not a rotation".
pub const ROTATION_TOLERANCE: f64 = 1e-3;

/// The ideal rectified stereo frame of a calibrated pair (see the module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct IdealStereoFrame {
    /// `R_left`: `X_left = R_left X_s` (the minimal rotation taking e_x to the baseline).
    pub r_left: Matrix3<f64>,
    /// `R_right`: `X_right = R_right (X_s − b e_x)`.
    pub r_right: Matrix3<f64>,
    /// Unit baseline direction (left centre → right centre) in left-camera coordinates.
    pub baseline_dir_left: Vector3<f64>,
    /// Baseline length (mm).
    pub baseline_mm: f64,
    /// True when the "right" camera lies on the left (negative x of the baseline).
    pub swapped: bool,
}

/// The nearest rotation matrix (polar decomposition by SVD, det = +1).
pub fn nearest_rotation(m: &Matrix3<f64>) -> Matrix3<f64> {
    let svd = m.svd(true, true);
    let (u, vt) = (svd.u.unwrap(), svd.v_t.unwrap());
    let mut d = Matrix3::identity();
    if (u * vt).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    u * d * vt
}

/// Largest absolute entry of `RᵀR − I`, and det R: how far `r` is from a rotation.
pub fn rotation_defect(r: &Matrix3<f64>) -> (f64, f64) {
    ((r.transpose() * r - Matrix3::identity()).abs().max(), r.determinant())
}

/// The minimal (geodesic) rotation taking unit vector `a` onto unit vector `b`:
/// `R = I + [v]× + [v]×² / (1 + c)`, `v = a × b`, `c = a · b` (Rodrigues; requires `c > −1`).
pub fn minimal_rotation(a: &Vector3<f64>, b: &Vector3<f64>) -> Matrix3<f64> {
    let v = a.cross(b);
    let c = a.dot(b);
    let vx = v.cross_matrix();
    Matrix3::identity() + vx + vx * vx / (1.0 + c)
}

/// The ideal rectified stereo frame of `X_right = R X_left + T` (see the module docs).
/// `R` must be a rotation within [`ROTATION_TOLERANCE`] (it is re-orthonormalised) and `T` non-zero.
pub fn ideal_stereo_frame(r: &Matrix3<f64>, t_mm: &Vector3<f64>) -> Result<IdealStereoFrame> {
    if r.iter().any(|v| !v.is_finite()) {
        return Err(StereoError::invalid("R", "non-finite entry"));
    }
    if t_mm.iter().any(|v| !v.is_finite()) {
        return Err(StereoError::invalid("T", "non-finite entry"));
    }
    let (defect, det) = rotation_defect(r);
    if defect > ROTATION_TOLERANCE || det <= 0.0 {
        return Err(StereoError::invalid(
            "R",
            format!("not a rotation matrix (max |RᵀR − I| = {defect:.3e}, det = {det:.6})"),
        ));
    }
    let baseline_mm = t_mm.norm();
    if baseline_mm <= 0.0 {
        return Err(StereoError::invalid("T", "zero baseline"));
    }
    let r = nearest_rotation(r);
    let c = -(r.transpose() * t_mm) / baseline_mm;
    let swapped = c.x < 0.0;
    let x_s = if swapped { -c } else { c };
    let r_left = minimal_rotation(&Vector3::x(), &x_s);
    let r_right = r * r_left;
    Ok(IdealStereoFrame { r_left, r_right, baseline_dir_left: c, baseline_mm, swapped })
}

/// `[x, y, z]` Euler angles in degrees of `R = Rz(z) Ry(y) Rx(x)` (eq. 3.7).
pub fn euler_deg(r: &Matrix3<f64>) -> [f64; 3] {
    let (x, y, z) = euler_zyx(r);
    [x.to_degrees(), y.to_degrees(), z.to_degrees()]
}

/// Statistics of one stereo calibration.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CalibStats {
    /// Image size (px) used for the distortion displacement.
    pub width: usize,
    /// Image height (px).
    pub height: usize,
    /// Euler angles `[x, y, z]` (deg) of the left camera's rotation from the ideal frame.
    pub left_euler_deg: [f64; 3],
    /// Euler angles `[x, y, z]` (deg) of the right camera's rotation from the ideal frame.
    pub right_euler_deg: [f64; 3],
    /// `c_x^L − c_x^R` (px): the disparity offset of §3.3.8.
    pub principal_point_offset_px: f64,
    /// `c_y^L − c_y^R` (px) before rectification.
    pub principal_point_offset_y_px: f64,
    /// `|T|` (mm).
    pub baseline_mm: f64,
    /// Unit baseline direction in left-camera coordinates.
    pub baseline_dir_left: [f64; 3],
    /// Rotation angle (deg) of R, the relative rotation between the two cameras.
    pub relative_rotation_deg: f64,
    /// Largest distortion displacement inside the left / right image (px).
    pub left_max_distortion_px: f64,
    /// Largest distortion displacement inside the right image (px).
    pub right_max_distortion_px: f64,
    /// Max of the two.
    pub max_distortion_px: f64,
    /// Left and right focal lengths fx (px).
    pub focal_px: [f64; 2],
    /// Odd features of the calibration (large rotations, swapped cameras, strong distortion, ...).
    pub warnings: Vec<String>,
}

/// Samples per image side of the distortion-displacement grid (the cost is bounded whatever the
/// image size: 513² evaluations at most, plus the border).
pub const DISTORTION_GRID: usize = 512;

/// Grid step (px) of the distortion statistics for camera `k`: 1 px up to 512 px, then coarser.
pub fn distortion_grid_step(k: &laparo_core::camera::Intrinsics) -> usize {
    k.width.max(k.height).div_ceil(DISTORTION_GRID).max(1)
}

/// Compute the statistics of one calibration. Never fails on an odd but valid calibration (the
/// oddities go to `warnings`); fails on invalid intrinsics, a non-rotation R or a zero baseline.
pub fn calib_stats(c: &StereoCalibration) -> Result<CalibStats> {
    c.left.validate().map_err(StereoError::rejected("left intrinsics"))?;
    c.right.validate().map_err(StereoError::rejected("right intrinsics"))?;
    let frame = ideal_stereo_frame(&c.r, &c.t_mm)?;
    let mut warnings = Vec::new();
    let (defect, _) = rotation_defect(&c.r);
    if defect > 1e-5 {
        warnings
            .push(format!("R is not orthonormal to 1e-5 (max |RᵀR − I| = {defect:.2e}); used the nearest rotation"));
    }
    if frame.swapped {
        warnings.push(
            "the right camera lies to the LEFT of the left camera (baseline x < 0): left/right swapped?".to_string(),
        );
    }
    let left_euler_deg = euler_deg(&frame.r_left);
    let right_euler_deg = euler_deg(&frame.r_right);
    for (name, e) in [("left", left_euler_deg), ("right", right_euler_deg)] {
        let m = e.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        if m > LARGE_ROTATION_DEG {
            warnings.push(format!(
                "large rectifying rotation of the {name} camera: Euler [x, y, z] = [{:.2}, {:.2}, {:.2}] deg \
                 (> {LARGE_ROTATION_DEG} deg; da Vinci laparoscopes are well below 1 deg)",
                e[0], e[1], e[2]
            ));
        }
    }
    let rel = nearest_rotation(&c.r);
    let relative_rotation_deg = ((rel.trace() - 1.0) / 2.0).clamp(-1.0, 1.0).acos().to_degrees();
    let left_max = c.left_dist.max_displacement_px(&c.left, distortion_grid_step(&c.left));
    let right_max = c.right_dist.max_displacement_px(&c.right, distortion_grid_step(&c.right));
    for (name, v) in [("left", left_max), ("right", right_max)] {
        if !v.is_finite() {
            warnings.push(format!("{name} lens distortion is not finite inside the image (degenerate model)"));
        } else if v > LARGE_DISTORTION_PX {
            warnings.push(format!(
                "{name} lens distortion moves pixels by up to {v:.2} px inside the image (> {LARGE_DISTORTION_PX} px)"
            ));
        }
    }
    if (c.left.width, c.left.height) != (c.right.width, c.right.height) {
        warnings.push(format!(
            "left and right image sizes differ ({}x{} vs {}x{})",
            c.left.width, c.left.height, c.right.width, c.right.height
        ));
    }
    let pp = c.left.cx - c.right.cx;
    if pp > 0.0 {
        warnings.push(format!(
            "positive principal-point offset c_x^L − c_x^R = {pp:.2} px (stereo laparoscopes usually have it negative)"
        ));
    }
    Ok(CalibStats {
        width: c.left.width,
        height: c.left.height,
        left_euler_deg,
        right_euler_deg,
        principal_point_offset_px: pp,
        principal_point_offset_y_px: c.left.cy - c.right.cy,
        baseline_mm: frame.baseline_mm,
        baseline_dir_left: [frame.baseline_dir_left.x, frame.baseline_dir_left.y, frame.baseline_dir_left.z],
        relative_rotation_deg,
        left_max_distortion_px: left_max,
        right_max_distortion_px: right_max,
        max_distortion_px: left_max.max(right_max),
        focal_px: [c.left.fx, c.right.fx],
        warnings,
    })
}

/// Build `R`, `T` of a stereo pair from its cameras' rotations from the ideal frame and the
/// baseline: `R = R_right R_leftᵀ`, `T = −b R_right e_x` (inverse of [`ideal_stereo_frame`] when
/// `R_left` is a minimal rotation, i.e. its rotation axis is orthogonal to e_x).
pub fn stereo_extrinsics_from_rotations(
    r_left: &Matrix3<f64>,
    r_right: &Matrix3<f64>,
    baseline_mm: f64,
) -> (Matrix3<f64>, Vector3<f64>) {
    (r_right * r_left.transpose(), -baseline_mm * (r_right * Vector3::x()))
}

/// Mean and standard deviation.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct MeanStd {
    /// Mean.
    pub mean: f64,
    /// Population standard deviation (divide by n, the maximum-likelihood Gaussian fit; numpy's default).
    pub std: f64,
    /// Minimum.
    pub min: f64,
    /// Maximum.
    pub max: f64,
}

impl MeanStd {
    /// Statistics of `v` (NaN when empty; non-finite values are skipped).
    pub fn of(v: &[f64]) -> MeanStd {
        let f: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
        if f.is_empty() {
            return MeanStd { mean: f64::NAN, std: f64::NAN, min: f64::NAN, max: f64::NAN };
        }
        let n = f.len() as f64;
        let mean = f.iter().sum::<f64>() / n;
        let var = f.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n;
        MeanStd {
            mean,
            std: var.sqrt(),
            min: f.iter().copied().fold(f64::INFINITY, f64::min),
            max: f.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        }
    }
}

/// Summary statistics over a set of calibrations (one row pair of Table 3.6, plus offsets).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StatsSummary {
    /// Number of calibrations.
    pub n: usize,
    /// Per angle `[x, y, z]`.
    pub left_euler_deg: [MeanStd; 3],
    /// Right camera Euler angles `[x, y, z]` (deg).
    pub right_euler_deg: [MeanStd; 3],
    /// `c_x^L − c_x^R` (px).
    pub principal_point_offset_px: MeanStd,
    /// `|T|` (mm).
    pub baseline_mm: MeanStd,
    /// Largest distortion displacement of either image (px).
    pub max_distortion_px: MeanStd,
}

/// Summarise per-calibration statistics (mean, population σ, min, max).
pub fn summarize(stats: &[CalibStats]) -> StatsSummary {
    let col = |f: &dyn Fn(&CalibStats) -> f64| MeanStd::of(&stats.iter().map(f).collect::<Vec<_>>());
    StatsSummary {
        n: stats.len(),
        left_euler_deg: [col(&|s| s.left_euler_deg[0]), col(&|s| s.left_euler_deg[1]), col(&|s| s.left_euler_deg[2])],
        right_euler_deg: [
            col(&|s| s.right_euler_deg[0]),
            col(&|s| s.right_euler_deg[1]),
            col(&|s| s.right_euler_deg[2]),
        ],
        principal_point_offset_px: col(&|s| s.principal_point_offset_px),
        baseline_mm: col(&|s| s.baseline_mm),
        max_distortion_px: col(&|s| s.max_distortion_px),
    }
}

/// A markdown table shaped like thesis Table 3.6 (μ, σ of the six Euler angles, degrees), one row
/// per `(label, summary)`.
pub fn table_3_6_markdown(rows: &[(String, StatsSummary)]) -> String {
    table_3_6(rows).to_markdown()
}

/// Table 3.6 as data (rendered by [`table_3_6_markdown`], or to HTML with
/// [`laparo_core::table::Table::to_html`]).
pub fn table_3_6(rows: &[(String, StatsSummary)]) -> laparo_core::table::Table {
    let mut t = laparo_core::table::Table::new([
        "",
        "n",
        "R_x^l2s μ",
        "σ",
        "R_y^l2s μ",
        "σ",
        "R_z^l2s μ",
        "σ",
        "R_x^r2s μ",
        "σ",
        "R_y^r2s μ",
        "σ",
        "R_z^r2s μ",
        "σ",
    ]);
    for (label, m) in rows {
        let mut r = vec![label.clone(), m.n.to_string()];
        for a in m.left_euler_deg.iter().chain(m.right_euler_deg.iter()) {
            r.push(format!("{:.4}", a.mean));
            r.push(format!("{:.4}", a.std));
        }
        t.push_row(r);
    }
    t
}

/// A markdown table of the other quantities (principal-point offset, baseline, distortion).
pub fn offsets_markdown(rows: &[(String, StatsSummary)]) -> String {
    let mut s = String::new();
    s.push_str("| | c_x^L − c_x^R μ (px) | σ | min | max | baseline μ (mm) | σ | max distortion μ (px) | max |\n");
    s.push_str("|---|---|---|---|---|---|---|---|---|\n");
    for (label, m) in rows {
        let (p, b, d) = (&m.principal_point_offset_px, &m.baseline_mm, &m.max_distortion_px);
        s.push_str(&format!(
            "| {label} | {:.2} | {:.2} | {:.2} | {:.2} | {:.4} | {:.4} | {:.3} | {:.3} |\n",
            p.mean, p.std, p.min, p.max, b.mean, b.std, d.mean, d.max
        ));
    }
    s
}

/// A markdown table with one row per calibration.
pub fn per_file_markdown(rows: &[(String, CalibStats)]) -> String {
    let mut s = String::new();
    s.push_str("| calibration | left [x, y, z] (deg) | right [x, y, z] (deg) | c_x^L − c_x^R (px) | baseline (mm) | max distortion (px) |\n");
    s.push_str("|---|---|---|---|---|---|\n");
    for (name, c) in rows {
        let (l, r) = (c.left_euler_deg, c.right_euler_deg);
        s.push_str(&format!(
            "| {name} | [{:.4}, {:.4}, {:.4}] | [{:.4}, {:.4}, {:.4}] | {:.2} | {:.4} | {:.3} |\n",
            l[0], l[1], l[2], r[0], r[1], r[2], c.principal_point_offset_px, c.baseline_mm, c.max_distortion_px
        ));
    }
    s
}

/// The range of the right principal-point shift Δx_right (px) fitted to observed offsets
/// `c_x^L − c_x^R`: the uniform law U(lo, hi) whose support covers every observed offset and 0
/// (the ideal, aligned case), as the thesis' U(−100, 0) does for SCARED's −91…−99 px.
pub fn fitted_dx_right_range(s: &StatsSummary) -> (f64, f64) {
    let p = &s.principal_point_offset_px;
    if !(p.min.is_finite() && p.max.is_finite()) {
        return (-100.0, 0.0);
    }
    (p.min.min(0.0), p.max.max(0.0))
}

/// A CATS configuration fitted to the statistics (eq. 3.7): per camera and Euler angle a Gaussian
/// N(μ, σ²) with the summary's mean and population σ; Δx_right ~ U(lo, hi) from
/// [`fitted_dx_right_range`] (Δx_right is the amount added to every disparity, i.e. it plays the
/// role of c_x^L − c_x^R, see `cats_params`); s_x = s_y = 1, c'_y = c_y and no distortion, as in
/// the thesis (distortion is negligible: see `max_distortion_px`).
pub fn fitted_cats_config(s: &StatsSummary, source: &str) -> CatsConfig {
    let cam = |e: &[MeanStd; 3]| CameraDist {
        euler_deg: EulerDist {
            x: Dist::normal(e[0].mean, e[0].std),
            y: Dist::normal(e[1].mean, e[1].std),
            z: Dist::normal(e[2].mean, e[2].std),
        },
        s_x: Dist::fixed(1.0),
        s_y: Dist::fixed(1.0),
        dcx_px: Dist::fixed(0.0),
        dcy_px: Dist::fixed(0.0),
        distortion: None,
    };
    let (lo, hi) = fitted_dx_right_range(s);
    CatsConfig {
        source: source.to_string(),
        left: cam(&s.left_euler_deg),
        right: cam(&s.right_euler_deg),
        disparity_offset: DisparityOffsetDist { dx_right_px: Dist::uniform(lo, hi) },
        camera: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use laparo_core::se3::rotation_zyx;
    use nalgebra::Rotation3;

    #[test]
    fn minimal_rotation_maps_and_is_geodesic() {
        let a = Vector3::x();
        let b = Vector3::new(0.9, 0.3, -0.2).normalize();
        let r = minimal_rotation(&a, &b);
        assert!((r * a - b).norm() < 1e-15);
        assert!((r.transpose() * r - Matrix3::identity()).norm() < 1e-15);
        // nalgebra's rotation_between is the same geodesic rotation.
        let n = Rotation3::rotation_between(&a, &b).unwrap().into_inner();
        assert!((r - n).norm() < 1e-14);
    }

    #[test]
    fn identity_pair_has_zero_angles() {
        let f = ideal_stereo_frame(&Matrix3::identity(), &Vector3::new(-4.0, 0.0, 0.0)).unwrap();
        assert!((f.r_left - Matrix3::identity()).norm() < 1e-15);
        assert!((f.baseline_mm - 4.0).abs() < 1e-15 && !f.swapped);
    }

    #[test]
    fn right_camera_below_gives_positive_z() {
        // Right centre at (4, 0.04, 0) in left coords (y down => below): T = −R C = (−4, −0.04, 0).
        let f = ideal_stereo_frame(&Matrix3::identity(), &Vector3::new(-4.0, -0.04, 0.0)).unwrap();
        let e = euler_deg(&f.r_left);
        assert!((e[2] - (0.01f64).atan().to_degrees()).abs() < 1e-12, "{e:?}");
        assert!(e[0].abs() < 1e-12 && e[1].abs() < 1e-12);
    }

    #[test]
    fn synthetic_round_trip() {
        let r_left = Rotation3::new(Vector3::new(0.0, 0.004, -0.007)).into_inner();
        let r_right = rotation_zyx(0.002, -0.003, 0.005);
        let (r, t) = stereo_extrinsics_from_rotations(&r_left, &r_right, 4.3);
        let f = ideal_stereo_frame(&r, &t).unwrap();
        assert!((f.r_left - r_left).norm() < 1e-14);
        assert!((f.r_right - r_right).norm() < 1e-14);
    }

    #[test]
    fn non_rotation_rejected() {
        let mut r = Matrix3::identity();
        r[(0, 0)] = 1.1;
        let e = ideal_stereo_frame(&r, &Vector3::new(-4.0, 0.0, 0.0)).unwrap_err().to_string();
        assert!(e.contains("R") && e.contains("not a rotation"), "{e}");
        assert!(ideal_stereo_frame(&Matrix3::identity(), &Vector3::zeros()).is_err());
    }

    #[test]
    fn mean_std_population() {
        let m = MeanStd::of(&[1.0, 2.0, 3.0, 4.0]);
        assert!((m.mean - 2.5).abs() < 1e-15);
        assert!((m.std - 1.25f64.sqrt()).abs() < 1e-15);
        assert_eq!((m.min, m.max), (1.0, 4.0));
    }

    /// Regression (issue 10): a 100000² image size made the distortion statistics visit every
    /// pixel (~7 min); the grid bounds the work, and it still finds the corner maximum.
    #[test]
    fn distortion_stats_sample_a_bounded_grid() {
        use laparo_core::camera::{Distortion, Intrinsics};
        let k = Intrinsics::new(1000.0, 1000.0, 639.5, 511.5, 1280, 1024).unwrap();
        assert_eq!(distortion_grid_step(&k), 3);
        let big = Intrinsics::new(1000.0, 1000.0, 32767.5, 32767.5, 65536, 4096).unwrap();
        assert_eq!(distortion_grid_step(&big), 128);
        // Pure radial k1: the displacement grows with r, so the maximum is at a corner, which the
        // grid always contains: r² = (639.5² + 511.5²)/1000², |D(p) − p| = k1 r² · r · f.
        let d = Distortion::brown_conrady(-0.1, 0.0, 0.0, 0.0, 0.0);
        let r2: f64 = (639.5f64.powi(2) + 511.5f64.powi(2)) / 1e6;
        let want = 0.1 * r2 * r2.sqrt() * 1000.0;
        let got = d.max_displacement_px(&k, distortion_grid_step(&k));
        assert!((got - want).abs() < 1e-9, "{got} vs {want}");
    }
}
