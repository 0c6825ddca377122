//! Calibrated stereo pipeline (thesis §2.2.2, §3.3.6 "calibrated scenario", §3.3.8): undistortion
//! and Bouguet rectification with principal points aligned, remapping by inverse mapping with
//! bilinear sampling, disparity ↔ depth with the principal-point offset term, point clouds.
//!
//! # Rectification (as OpenCV `stereoRectify`, Bouguet's algorithm)
//! With `X_right = R X_left + T`, `om = log(R)` (axis–angle) and `r_r = exp(−om / 2)`, each camera
//! is first rotated half-way towards the other; `t = r_r T` is then carried onto the X axis by the
//! minimal rotation `wR` (axis `t × u`, `u = (sign t_x, 0, 0)`, angle `acos(|t_x| / |t|)`). The
//! rectifying rotations are `R1 = wR r_rᵀ`, `R2 = wR r_r` (`X_rect,c = R_c X_c`), so that
//! `X_rect,right = X_rect,left − b e_x`, b = |T| (mm). Only horizontal pairs (`|t_x| ≥ |t_y|`)
//! are supported.
//!
//! # New camera matrix
//! Both rectified cameras get f' = (f_y,left + f_y,right) / 2 (OpenCV's choice for horizontal pairs)
//! and principal points chosen like OpenCV: for each camera the four undistorted, rotated image
//! corners are centred, then with [`RectifyOptions::align_principal_points`] (default, OpenCV's
//! `CALIB_ZERO_DISPARITY`, the thesis' "principal point-aligned" images) both cameras share
//! (c'_x, c'_y) — so `doffs = 0` and d = f' b / z — otherwise only c'_y is shared.
//! Then, when `alpha >= 0`, f' is scaled about the principal points exactly as OpenCV's `alpha`:
//! `alpha = 0` (laparo's default) zooms in until every rectified pixel of both images comes from
//! inside the source images (no black border), `alpha = 1` zooms out until every source pixel is
//! visible; a negative alpha keeps f' unscaled (OpenCV's `alpha = −1`). The inner and outer
//! rectangles are computed from every 8th pixel of the source image border (OpenCV uses a 9×9 grid).
//!
//! # Disparity and depth (§3.3.8)
//! For a rectified pair, or a near-rectified raw pair "for reference only" (Table 3.7):
//! `d = f b / z + (c_x^L − c_x^R)`, so `z = f b / (d − (c_x^L − c_x^R))`. Middlebury calls
//! `doffs = c_x^R − c_x^L` (then `z = f b / (d + doffs)`); laparo stores `doffs` with that sign.
pub use crate::disparity::DisparityGeometry;
use crate::error::{Result, StereoError};
use laparo_core::calib::StereoCalibration;
use laparo_core::camera::{Distortion, Intrinsics};
use laparo_core::image::{Image, Mask};
use laparo_core::remap::{remap, CoordMap, Interp, Texel};
use nalgebra::{Matrix3, Matrix3x4, Matrix4, Rotation3, Vector3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Options of [`Rectification::new`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct RectifyOptions {
    /// OpenCV's free scaling parameter: 0 = only valid pixels (default), 1 = all source pixels,
    /// negative = no scaling (f' = mean f_y).
    pub alpha: f64,
    /// Give both cameras the same principal point (doffs = 0; OpenCV `CALIB_ZERO_DISPARITY`).
    pub align_principal_points: bool,
}

impl Default for RectifyOptions {
    fn default() -> Self {
        RectifyOptions { alpha: 0.0, align_principal_points: true }
    }
}

/// Which camera of the pair.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Side {
    /// The left camera.
    Left,
    /// The right camera.
    Right,
}

/// A rectification of a calibrated stereo pair (see the module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct Rectification {
    /// The source calibration.
    pub calib: StereoCalibration,
    /// Rectifying rotations: `X_rect,left = r1 X_left`, `X_rect,right = r2 X_right`.
    pub r1: Matrix3<f64>,
    /// Right rectifying rotation.
    pub r2: Matrix3<f64>,
    /// New (rectified) cameras: same f, same c_y; same c_x when principal points are aligned.
    pub k1: Intrinsics,
    /// New right camera.
    pub k2: Intrinsics,
    /// |T| (mm).
    pub baseline_mm: f64,
    /// Options used.
    pub options: RectifyOptions,
}

/// Rectification parameters in a file-friendly form (row-major matrices), as written by
/// `laparo stereo rectify` next to the rectified calibration.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RectificationInfo {
    /// Image width (px).
    pub width: usize,
    /// Image height (px).
    pub height: usize,
    /// New camera matrices (3×3, row-major).
    pub k_left: [[f64; 3]; 3],
    /// New right camera matrix (3×3, row-major).
    pub k_right: [[f64; 3]; 3],
    /// Rectified focal length (px).
    pub focal_px: f64,
    /// Baseline (mm).
    pub baseline_mm: f64,
    /// Middlebury `doffs = c_x^R − c_x^L` (px) of the rectified pair: z = f b / (d + doffs).
    pub doffs_px: f64,
    /// `R1`, `R2`, `P1`, `P2`, `Q` as OpenCV's `stereoRectify` (T in mm).
    pub r1: [[f64; 3]; 3],
    /// OpenCV `R2`.
    pub r2: [[f64; 3]; 3],
    /// OpenCV `P1` (3×4).
    pub p1: [[f64; 4]; 3],
    /// OpenCV `P2` (3×4).
    pub p2: [[f64; 4]; 3],
    /// OpenCV `Q` (4×4, T in mm).
    pub q: [[f64; 4]; 4],
    /// Free scaling α of `stereoRectify` (0 = only valid pixels, 1 = all source pixels).
    pub alpha: f64,
    /// Whether c_x of both rectified cameras was made equal.
    pub align_principal_points: bool,
}

/// Undistort a source pixel to normalised coordinates; `None` when Newton does not converge.
fn undistort_to_ray(k: &Intrinsics, d: &Distortion, u: f64, v: f64) -> Option<Vector3<f64>> {
    let (xd, yd) = k.pixel_to_normalized(u, v);
    let (x, y) = d.undistort_normalized(xd, yd)?;
    Some(Vector3::new(x, y, 1.0))
}

fn rows3(m: &Matrix3<f64>) -> [[f64; 3]; 3] {
    [[m[(0, 0)], m[(0, 1)], m[(0, 2)]], [m[(1, 0)], m[(1, 1)], m[(1, 2)]], [m[(2, 0)], m[(2, 1)], m[(2, 2)]]]
}

/// Points along the image border, every `step` px plus the corners, tagged by edge
/// (0 = left, 1 = right, 2 = top, 3 = bottom).
fn border_points(w: usize, h: usize, step: usize) -> Vec<(f64, f64, u8)> {
    let (wf, hf) = ((w - 1) as f64, (h - 1) as f64);
    let mut xs: Vec<f64> = (0..w).step_by(step).map(|v| v as f64).collect();
    if *xs.last().unwrap() != wf {
        xs.push(wf);
    }
    let mut ys: Vec<f64> = (0..h).step_by(step).map(|v| v as f64).collect();
    if *ys.last().unwrap() != hf {
        ys.push(hf);
    }
    let mut p = Vec::new();
    for &y in &ys {
        p.push((0.0, y, 0));
        p.push((wf, y, 1));
    }
    for &x in &xs {
        p.push((x, 0.0, 2));
        p.push((x, hf, 3));
    }
    p
}

impl Rectification {
    /// Compute the rectification of `calib` (see the module docs). Fails on non-rotation R,
    /// zero baseline, a vertical pair, different image sizes or an undistortion that does not
    /// converge at the image border.
    pub fn new(calib: &StereoCalibration, options: RectifyOptions) -> Result<Self> {
        calib.left.validate()?;
        calib.right.validate()?;
        let (w, h) = (calib.left.width, calib.left.height);
        if (w, h) != (calib.right.width, calib.right.height) {
            return Err(StereoError::SizeMismatch(format!(
                "left camera {}x{}, right camera {}x{}",
                w, h, calib.right.width, calib.right.height
            )));
        }
        if w < 2 || h < 2 {
            return Err(StereoError::invalid("image size", format!("{w}x{h}")));
        }
        if !options.alpha.is_finite() || options.alpha > 1.0 {
            return Err(StereoError::invalid(
                "alpha",
                format!("{} (must be <= 1; negative = no scaling)", options.alpha),
            ));
        }
        // Validates R and T (rotation, finite, non-zero baseline).
        crate::calib_stats::ideal_stereo_frame(&calib.r, &calib.t_mm)?;
        let r = crate::calib_stats::nearest_rotation(&calib.r);
        let t = calib.t_mm;
        let om = Rotation3::from_matrix_unchecked(r).scaled_axis();
        let r_r = Rotation3::new(-0.5 * om).into_inner();
        let tt = r_r * t;
        if tt.x.abs() < tt.y.abs() {
            return Err(StereoError::invalid("T", "vertical stereo pair (|t_y| > |t_x|) is not supported"));
        }
        let uu = Vector3::new(if tt.x > 0.0 { 1.0 } else { -1.0 }, 0.0, 0.0);
        let ww = tt.cross(&uu);
        let nw = ww.norm();
        let w_r = if nw > 0.0 {
            Rotation3::new(ww * ((tt.x.abs() / tt.norm()).clamp(-1.0, 1.0).acos() / nw)).into_inner()
        } else {
            Matrix3::identity()
        };
        let r1 = w_r * r_r.transpose();
        let r2 = w_r * r_r;
        let mut f_new = 0.5 * (calib.left.fy + calib.right.fy);
        // Principal points from the centred, undistorted, rotated corners (OpenCV).
        let corners = [(0.0, 0.0), ((w - 1) as f64, 0.0), (0.0, (h - 1) as f64), ((w - 1) as f64, (h - 1) as f64)];
        let mut cc = [[0.0f64; 2]; 2];
        for (k, (kk, dd, rr)) in
            [(&calib.left, &calib.left_dist, &r1), (&calib.right, &calib.right_dist, &r2)].into_iter().enumerate()
        {
            let mut avg = [0.0; 2];
            for &(u, v) in &corners {
                let ray = undistort_to_ray(kk, dd, u, v).ok_or_else(|| {
                    StereoError::invalid("distortion", format!("undistortion does not converge at corner ({u}, {v})"))
                })?;
                let q = rr * ray;
                if q.z <= 0.0 {
                    return Err(StereoError::invalid(
                        "R",
                        "rectifying rotation sends an image corner behind the camera",
                    ));
                }
                avg[0] += f_new * q.x / q.z / 4.0;
                avg[1] += f_new * q.y / q.z / 4.0;
            }
            cc[k] = [(w - 1) as f64 / 2.0 - avg[0], (h - 1) as f64 / 2.0 - avg[1]];
        }
        if options.align_principal_points {
            let m = [(cc[0][0] + cc[1][0]) / 2.0, (cc[0][1] + cc[1][1]) / 2.0];
            cc = [m, m];
        } else {
            let my = (cc[0][1] + cc[1][1]) / 2.0;
            cc[0][1] = my;
            cc[1][1] = my;
        }
        if options.alpha >= 0.0 {
            // Inner and outer rectangles of each rectified image (unscaled f_new).
            let pts = border_points(w, h, 8);
            let (mut s0, mut s1) = (f64::NEG_INFINITY, f64::INFINITY);
            for (k, (kk, dd, rr)) in
                [(&calib.left, &calib.left_dist, &r1), (&calib.right, &calib.right_dist, &r2)].into_iter().enumerate()
            {
                let (mut ix0, mut ix1, mut iy0, mut iy1) =
                    (f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY);
                let (mut ox0, mut ox1, mut oy0, mut oy1) =
                    (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
                for &(u, v, edge) in &pts {
                    let ray = undistort_to_ray(kk, dd, u, v).ok_or_else(|| {
                        StereoError::invalid("distortion", format!("undistortion does not converge at ({u}, {v})"))
                    })?;
                    let q = rr * ray;
                    if q.z <= 0.0 {
                        return Err(StereoError::invalid(
                            "R",
                            "rectifying rotation sends the image border behind the camera",
                        ));
                    }
                    let (x, y) = (f_new * q.x / q.z + cc[k][0], f_new * q.y / q.z + cc[k][1]);
                    ox0 = ox0.min(x);
                    ox1 = ox1.max(x);
                    oy0 = oy0.min(y);
                    oy1 = oy1.max(y);
                    match edge {
                        0 => ix0 = ix0.max(x),
                        1 => ix1 = ix1.min(x),
                        2 => iy0 = iy0.max(y),
                        _ => iy1 = iy1.min(y),
                    }
                }
                let (cx, cy) = (cc[k][0], cc[k][1]);
                let (wm, hm) = ((w - 1) as f64, (h - 1) as f64);
                s0 = s0.max(
                    (cx / (cx - ix0)).max(cy / (cy - iy0)).max((wm - cx) / (ix1 - cx)).max((hm - cy) / (iy1 - cy)),
                );
                s1 = s1.min(
                    (cx / (cx - ox0)).min(cy / (cy - oy0)).min((wm - cx) / (ox1 - cx)).min((hm - cy) / (oy1 - cy)),
                );
            }
            let s = s0 * (1.0 - options.alpha) + s1 * options.alpha;
            if !(s.is_finite() && s > 0.0) {
                return Err(StereoError::invalid(
                    "alpha",
                    format!("no valid scaling (s0 = {s0}, s1 = {s1}): the principal point leaves the valid region"),
                ));
            }
            f_new *= s;
        }
        let k1 = Intrinsics::new(f_new, f_new, cc[0][0], cc[0][1], w, h)?;
        let k2 = Intrinsics::new(f_new, f_new, cc[1][0], cc[1][1], w, h)?;
        Ok(Rectification { calib: calib.clone(), r1, r2, k1, k2, baseline_mm: t.norm(), options })
    }

    /// The source camera, its distortion, its rectifying rotation and its new camera.
    fn side(&self, s: Side) -> (&Intrinsics, &Distortion, &Matrix3<f64>, &Intrinsics) {
        match s {
            Side::Left => (&self.calib.left, &self.calib.left_dist, &self.r1, &self.k1),
            Side::Right => (&self.calib.right, &self.calib.right_dist, &self.r2, &self.k2),
        }
    }

    /// Rectified focal length f' (px).
    pub fn focal_px(&self) -> f64 {
        self.k1.fx
    }

    /// `c_x^L − c_x^R` of the rectified pair (px): d = f' b / z + this (§3.3.8).
    pub fn disparity_offset_px(&self) -> f64 {
        self.k1.cx - self.k2.cx
    }

    /// Middlebury's `doffs = c_x^R − c_x^L` (px).
    pub fn doffs_px(&self) -> f64 {
        self.k2.cx - self.k1.cx
    }

    /// Map a pixel of the source (distorted) image of camera `s` to the rectified image.
    /// `None` when undistortion does not converge or the point goes behind the camera.
    pub fn rectify_point(&self, s: Side, u: f64, v: f64) -> Option<(f64, f64)> {
        let (k, d, r, kn) = self.side(s);
        let q = r * undistort_to_ray(k, d, u, v)?;
        if q.z <= 0.0 {
            return None;
        }
        Some(kn.normalized_to_pixel(q.x / q.z, q.y / q.z))
    }

    /// Map a rectified pixel of camera `s` to its source (distorted) image position (the inverse
    /// map used by [`Self::remap_table`]). `None` when the ray goes behind the source camera.
    #[inline]
    pub fn source_point(&self, s: Side, u: f64, v: f64) -> Option<(f64, f64)> {
        let (k, d, r, kn) = self.side(s);
        let (x, y) = kn.pixel_to_normalized(u, v);
        let q = r.transpose() * Vector3::new(x, y, 1.0);
        if q.z <= 0.0 {
            return None;
        }
        let (xd, yd) = d.distort_normalized(q.x / q.z, q.y / q.z);
        Some(k.normalized_to_pixel(xd, yd))
    }

    /// The inverse map of camera `s`: for every rectified pixel, its source image position
    /// (f32 like OpenCV's `CV_32FC1` maps; NaN when the ray goes behind the camera). The ray
    /// `R_sᵀ K'⁻¹ (u, v, 1)` is affine in u, so each row is built incrementally; parallel over rows.
    pub fn remap_table(&self, s: Side) -> CoordMap {
        let (k, d, r, kn) = self.side(s);
        let (w, h) = (kn.width, kn.height);
        let rt = r.transpose();
        // K'⁻¹ (u, v, 1) = ((u − c'x − skew·yn)/f'x, (v − c'y)/f'y, 1), skew = 0 for rectified cameras.
        let du = rt * Vector3::new(1.0 / kn.fx, 0.0, 0.0);
        let rational = d.k4 != 0.0 || d.k5 != 0.0 || d.k6 != 0.0;
        let mut xy = vec![[f32::NAN; 2]; w * h];
        xy.par_chunks_mut(w).enumerate().for_each_init(
            || (vec![0.0f64; w], vec![0.0f64; w], vec![true; w]),
            |(xs, ys, front), (y, row)| {
                let (x0n, y0n) = kn.pixel_to_normalized(0.0, y as f64);
                let r0 = rt * Vector3::new(x0n, y0n, 1.0);
                // Pass 1 (branch-free, vectorisable): normalised coordinates of every ray.
                for (x, ((a, b), f)) in xs.iter_mut().zip(ys.iter_mut()).zip(front.iter_mut()).enumerate() {
                    let xf = x as f64;
                    let (qx, qy, qz) = (r0.x + du.x * xf, r0.y + du.y * xf, r0.z + du.z * xf);
                    let iz = 1.0 / qz;
                    *a = qx * iz;
                    *b = qy * iz;
                    *f = qz > 0.0;
                }
                // Pass 2: distortion and camera matrix.
                if rational {
                    for (((o, &a), &b), &f) in row.iter_mut().zip(xs.iter()).zip(ys.iter()).zip(front.iter()) {
                        if f {
                            let (xd, yd) = d.distort_normalized(a, b);
                            let (u, v) = k.normalized_to_pixel(xd, yd);
                            *o = [u as f32, v as f32];
                        }
                    }
                } else {
                    let (k1, k2, k3, p1, p2) = (d.k1, d.k2, d.k3, d.p1, d.p2);
                    let (s1, s2, s3, s4) = (d.s1, d.s2, d.s3, d.s4);
                    let (fx, fy, cx, cy, skew) = (k.fx, k.fy, k.cx, k.cy, k.skew);
                    for (((o, &xn), &yn), &f) in row.iter_mut().zip(xs.iter()).zip(ys.iter()).zip(front.iter()) {
                        let r2 = xn * xn + yn * yn;
                        let radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
                        let xy2 = 2.0 * xn * yn;
                        let xd = xn * radial + p1 * xy2 + p2 * (r2 + 2.0 * xn * xn) + s1 * r2 + s2 * r2 * r2;
                        let yd = yn * radial + p1 * (r2 + 2.0 * yn * yn) + p2 * xy2 + s3 * r2 + s4 * r2 * r2;
                        let u = fx * xd + skew * yd + cx;
                        let v = fy * yd + cy;
                        *o = if f { [u as f32, v as f32] } else { [f32::NAN; 2] };
                    }
                }
            },
        );
        CoordMap { width: w, height: h, xy }
    }

    /// 3×4 projection matrices of the rectified cameras in the rectified left frame (OpenCV P1, P2):
    /// `P2 = K2 [I | (−b, 0, 0)ᵀ]`.
    pub fn projections(&self) -> (Matrix3x4<f64>, Matrix3x4<f64>) {
        let mut p1 = Matrix3x4::zeros();
        p1.fixed_view_mut::<3, 3>(0, 0).copy_from(&self.k1.matrix());
        let mut p2 = Matrix3x4::zeros();
        p2.fixed_view_mut::<3, 3>(0, 0).copy_from(&self.k2.matrix());
        p2[(0, 3)] = -self.baseline_mm * self.k2.fx;
        (p1, p2)
    }

    /// OpenCV's disparity-to-depth matrix Q (mm): `[X Y Z W]ᵀ = Q [u v d 1]ᵀ`.
    pub fn q_matrix(&self) -> Matrix4<f64> {
        let f = self.focal_px();
        let tx = -self.baseline_mm;
        Matrix4::new(
            1.0,
            0.0,
            0.0,
            -self.k1.cx,
            0.0,
            1.0,
            0.0,
            -self.k1.cy,
            0.0,
            0.0,
            0.0,
            f,
            0.0,
            0.0,
            -1.0 / tx,
            (self.k1.cx - self.k2.cx) / tx,
        )
    }

    /// The calibration of the rectified pair: new K's, no distortion, R = I, T = (−b, 0, 0).
    pub fn rectified_calibration(&self) -> StereoCalibration {
        StereoCalibration {
            width: self.k1.width,
            height: self.k1.height,
            left: self.k1,
            left_dist: Distortion::default(),
            right: self.k2,
            right_dist: Distortion::default(),
            r: Matrix3::identity(),
            t_mm: Vector3::new(-self.baseline_mm, 0.0, 0.0),
        }
    }

    /// The disparity geometry of the rectified pair.
    pub fn geometry(&self) -> DisparityGeometry {
        DisparityGeometry {
            f_px: self.k1.fx,
            fy_px: self.k1.fy,
            baseline_mm: self.baseline_mm,
            cx_left: self.k1.cx,
            cx_right: self.k2.cx,
            cy: self.k1.cy,
        }
    }

    /// File-friendly summary (R1, R2, P1, P2, Q, new K's, f, b, doffs).
    pub fn info(&self) -> RectificationInfo {
        let (p1, p2) = self.projections();
        let q = self.q_matrix();
        let r34 = |p: &Matrix3x4<f64>| {
            let mut o = [[0.0; 4]; 3];
            for (i, row) in o.iter_mut().enumerate() {
                for (j, v) in row.iter_mut().enumerate() {
                    *v = p[(i, j)];
                }
            }
            o
        };
        let mut qq = [[0.0; 4]; 4];
        for (i, row) in qq.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v = q[(i, j)];
            }
        }
        RectificationInfo {
            width: self.k1.width,
            height: self.k1.height,
            k_left: rows3(&self.k1.matrix()),
            k_right: rows3(&self.k2.matrix()),
            focal_px: self.focal_px(),
            baseline_mm: self.baseline_mm,
            doffs_px: self.doffs_px(),
            r1: rows3(&self.r1),
            r2: rows3(&self.r2),
            p1: r34(&p1),
            p2: r34(&p2),
            q: qq,
            alpha: self.options.alpha,
            align_principal_points: self.options.align_principal_points,
        }
    }

    /// Rectify an image of camera `s` (bilinear, the contract of [`laparo_core::remap`]; pixels
    /// without source are 0) and return it with its validity mask. The image must have the
    /// calibration's size. For many frames, build [`Self::remap_table`] once and call
    /// [`laparo_core::remap::remap`] per frame.
    pub fn rectify_image<T: Texel + Default>(&self, s: Side, img: &Image<T>) -> Result<(Image<T>, Mask)> {
        if (img.width, img.height) != (self.calib.left.width, self.calib.left.height) {
            return Err(StereoError::SizeMismatch(format!(
                "{} image is {}x{}, the calibration is {}x{}",
                if s == Side::Left { "left" } else { "right" },
                img.width,
                img.height,
                self.calib.left.width,
                self.calib.left.height
            )));
        }
        Ok(remap(img, &self.remap_table(s), Interp::Bilinear, T::default())?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn depth_disparity_hand_values() {
        // f = 1000 px, b = 4 mm, c_x^L − c_x^R = −90 px: z = 50 mm → d = 80 − 90 = −10 px.
        let g = DisparityGeometry {
            f_px: 1000.0,
            fy_px: 1000.0,
            baseline_mm: 4.0,
            cx_left: 600.0,
            cx_right: 690.0,
            cy: 500.0,
        };
        assert!((g.disparity_px(50.0) + 10.0).abs() < 1e-12);
        assert!((g.depth_mm(-10.0) - 50.0).abs() < 1e-12);
        assert!(g.depth_mm(-90.0).is_nan() && g.depth_mm(-100.0).is_nan());
        let p = g.point_mm(700.0, 400.0, -10.0).unwrap();
        assert!((p - Vector3::new(5.0, -5.0, 50.0)).norm() < 1e-12);
    }

    /// Two identical distortion-free cameras, the right one 5 mm along +x.
    fn parallel_pair(k: Intrinsics) -> StereoCalibration {
        StereoCalibration {
            width: k.width,
            height: k.height,
            left: k,
            left_dist: Distortion::default(),
            right: k,
            right_dist: Distortion::default(),
            r: Matrix3::identity(),
            t_mm: Vector3::new(-5.0, 0.0, 0.0),
        }
    }

    #[test]
    fn identity_pair_keeps_cameras() {
        let c = parallel_pair(Intrinsics::new(1000.0, 1000.0, 319.5, 239.5, 640, 480).unwrap());
        let r = Rectification::new(&c, RectifyOptions { alpha: -1.0, align_principal_points: true }).unwrap();
        assert!((r.r1 - Matrix3::identity()).norm() < 1e-15 && (r.r2 - Matrix3::identity()).norm() < 1e-15);
        assert!((r.k1.cx - 319.5).abs() < 1e-12 && (r.k1.cy - 239.5).abs() < 1e-12 && r.k1.fx == 1000.0);
        // alpha = 0 on a distortion-free, unrotated pair: nothing to crop, s = 1.
        let r0 = Rectification::new(&c, RectifyOptions::default()).unwrap();
        assert!((r0.k1.fx - 1000.0).abs() < 1e-9, "{}", r0.k1.fx);
        let t = r0.remap_table(Side::Left);
        assert!(t.xy.iter().enumerate().all(|(i, p)| {
            (p[0] as f64 - (i % 640) as f64).abs() < 1e-4 && (p[1] as f64 - (i / 640) as f64).abs() < 1e-4
        }));
    }

    #[test]
    fn rectifying_an_unrotated_distortion_free_pair_copies_the_image() {
        let c = parallel_pair(Intrinsics::new(1000.0, 1000.0, 18.0, 11.0, 37, 23).unwrap());
        let r = Rectification::new(&c, RectifyOptions { alpha: -1.0, align_principal_points: true }).unwrap();
        let data: Vec<u8> = (0..37 * 23 * 3).map(|i| ((i * 7919) % 256) as u8).collect();
        let img = Image::from_vec(37, 23, 3, data).unwrap();
        let (out, mask) = r.rectify_image(Side::Left, &img).unwrap();
        assert_eq!(out, img);
        assert!(mask.data.iter().all(|&v| v));
        let wrong = Image::filled(36, 23, 3, 0u8);
        assert!(r.rectify_image(Side::Left, &wrong).is_err());
    }
}
