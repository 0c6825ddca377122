//! Camera augmentation (thesis §3.3.3, eqs. 3.5–3.6) of single images and of stereo samples
//! (§3.3.5, eqs. 3.7–3.9) with their disparity ground truth.
//!
//! One camera: p' ~ D_{K',θ'}( Π( K_rel H_R Γ( D⁻¹_{K,θ}(p) ) ) ) with H_R = K R K⁻¹ and
//! K' = K_rel K (eq. 3.5); without distortion p' ~ K_rel H_R p (eq. 3.6). Every output image is
//! produced by **inverse mapping**: each augmented pixel p' is pulled from the source at
//! A⁻¹(p') (bilinear for images, nearest for disparities and masks), never by splatting.
//!
//! Stereo ground truth, two rules ([`GtRule`]):
//! - `Thesis`: d'(p') = d(nearest(A_L⁻¹ p')) + Δx_right ("apply the same homography as for the
//!   left image to the disparity GT, then add Δx_right").
//! - `Exact`: p = A_L⁻¹(p'), p_R = (p_x − d(p), p_y), p'_R = A_R(p_R), d' = p'_x − p'_R,x; the
//!   vertical residual p'_R,y − p'_y is reported (0 for a rectified result).
use laparo_core::image::Mask;
use laparo_core::remap::{self, Interp, Texel};
use laparo_core::se3::{euler_zyx, rotation_zyx};
use laparo_core::{Distortion, Image, Intrinsics};
use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::{Result, StereoError};

fn invalid(what: impl Into<String>, msg: impl Into<String>) -> StereoError {
    StereoError::invalid(what, msg)
}

/// Row-major 3×3 matrix as stored in JSON sidecars.
pub type Mat3Rows = [[f64; 3]; 3];

fn to_rows(m: &Matrix3<f64>) -> Mat3Rows {
    [[m[(0, 0)], m[(0, 1)], m[(0, 2)]], [m[(1, 0)], m[(1, 1)], m[(1, 2)]], [m[(2, 0)], m[(2, 1)], m[(2, 2)]]]
}
fn from_rows(r: &Mat3Rows) -> Matrix3<f64> {
    Matrix3::new(r[0][0], r[0][1], r[0][2], r[1][0], r[1][1], r[1][2], r[2][0], r[2][1], r[2][2])
}

/// The parameters of one camera augmentation (eq. 3.5): source camera K, θ; rotation R;
/// relative intrinsics K_rel = K' K⁻¹; output distortion θ'.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CameraAugmentation {
    /// Source intrinsics K (and image size, which the augmented image keeps).
    pub k: Intrinsics,
    /// Source lens distortion θ (0 for synthetic datasets).
    #[serde(default)]
    pub distortion: Distortion,
    /// Z-Y-X Euler angles of R in degrees, `[x, y, z]` with R = Rz(z) Ry(y) Rx(x) (eq. 3.7).
    pub euler_deg: [f64; 3],
    /// R, row-major (authoritative; `euler_deg` is derived from it).
    pub rotation: Mat3Rows,
    /// K_rel = K' K⁻¹, row-major.
    pub k_rel: Mat3Rows,
    /// Output lens distortion θ' (applied with K').
    #[serde(default)]
    pub distortion_out: Distortion,
}

impl CameraAugmentation {
    /// The identity augmentation of camera `k`.
    pub fn identity(k: Intrinsics) -> Self {
        Self::from_rotation(k, Distortion::default(), Matrix3::identity(), Matrix3::identity(), Distortion::default())
    }

    /// From Euler angles in degrees `[x, y, z]` (R = Rz(z) Ry(y) Rx(x)).
    pub fn from_euler_deg(
        k: Intrinsics,
        distortion: Distortion,
        euler_deg: [f64; 3],
        k_rel: Matrix3<f64>,
        distortion_out: Distortion,
    ) -> Self {
        let r = rotation_zyx(euler_deg[0].to_radians(), euler_deg[1].to_radians(), euler_deg[2].to_radians());
        CameraAugmentation { k, distortion, euler_deg, rotation: to_rows(&r), k_rel: to_rows(&k_rel), distortion_out }
    }

    /// From a rotation matrix (Euler angles derived).
    pub fn from_rotation(
        k: Intrinsics,
        distortion: Distortion,
        r: Matrix3<f64>,
        k_rel: Matrix3<f64>,
        distortion_out: Distortion,
    ) -> Self {
        let (x, y, z) = euler_zyx(&r);
        CameraAugmentation {
            k,
            distortion,
            euler_deg: [x.to_degrees(), y.to_degrees(), z.to_degrees()],
            rotation: to_rows(&r),
            k_rel: to_rows(&k_rel),
            distortion_out,
        }
    }

    /// R.
    pub fn r(&self) -> Matrix3<f64> {
        from_rows(&self.rotation)
    }
    /// K_rel.
    pub fn k_rel_matrix(&self) -> Matrix3<f64> {
        from_rows(&self.k_rel)
    }
    /// K' = K_rel K, the augmented camera's intrinsics.
    pub fn k_out(&self) -> Result<Intrinsics> {
        Intrinsics::from_matrix(&(self.k_rel_matrix() * self.k.matrix()), self.k.width, self.k.height)
            .map_err(StereoError::rejected("K' = K_rel K"))
    }

    /// H_R = K R K⁻¹ (eq. 3.8); exactly the identity when R is.
    pub fn h_r(&self) -> Matrix3<f64> {
        let r = self.r();
        if r == Matrix3::identity() {
            return r;
        }
        let k = self.k.matrix();
        k * r * k.try_inverse().expect("validated K is invertible")
    }

    /// H = K_rel H_R (eq. 3.6).
    pub fn homography(&self) -> Matrix3<f64> {
        self.k_rel_matrix() * self.h_r()
    }

    /// H⁻¹ = K Rᵀ K⁻¹ K_rel⁻¹ (no generic inversion of H, which keeps integer shifts exact).
    pub fn homography_inverse(&self) -> Result<Matrix3<f64>> {
        let kri = self.k_rel_matrix().try_inverse().ok_or_else(|| invalid("K_rel", "singular"))?;
        let r = self.r();
        if r == Matrix3::identity() {
            return Ok(kri);
        }
        let k = self.k.matrix();
        Ok(k * r.transpose() * k.try_inverse().expect("validated K is invertible") * kri)
    }

    /// Check K, R ∈ SO(3) (|RᵀR − I| < 1e-6, det > 0), K_rel (finite, last row 0 0 1, invertible,
    /// positive focal ratios) and the distortion coefficients.
    pub fn validate(&self, what: &str) -> Result<()> {
        self.k.validate().map_err(StereoError::rejected(format!("{what}.k")))?;
        let r = self.r();
        if r.iter().any(|v| !v.is_finite())
            || (r.transpose() * r - Matrix3::identity()).norm() > 1e-6
            || r.determinant() <= 0.0
        {
            return Err(invalid(format!("{what}.rotation"), format!("not a rotation matrix: {:?}", self.rotation)));
        }
        let kr = self.k_rel_matrix();
        if kr.iter().any(|v| !v.is_finite())
            || kr[(2, 0)] != 0.0
            || kr[(2, 1)] != 0.0
            || kr[(2, 2)] != 1.0
            || kr[(0, 0)] <= 0.0
            || kr[(1, 1)] <= 0.0
            || kr[(1, 0)] != 0.0
        {
            return Err(invalid(
                format!("{what}.k_rel"),
                format!("must be [[s_x, skew, t_x], [0, s_y, t_y], [0, 0, 1]] with s > 0: {:?}", self.k_rel),
            ));
        }
        for (n, d) in [("distortion", &self.distortion), ("distortion_out", &self.distortion_out)] {
            if d.to_opencv().iter().any(|v| !v.is_finite()) {
                return Err(invalid(format!("{what}.{n}"), "non-finite coefficient"));
            }
        }
        if self.euler_deg.iter().any(|v| !v.is_finite()) {
            return Err(invalid(format!("{what}.euler_deg"), "non-finite angle"));
        }
        Ok(())
    }

    /// Precompute the coordinate maps of this augmentation.
    pub fn map(&self) -> Result<CameraMap> {
        self.validate("camera augmentation")?;
        let h = self.homography();
        let h_inv = self.homography_inverse()?;
        Ok(CameraMap {
            h,
            h_inv,
            k: self.k,
            k_out: self.k_out()?,
            dist_in: (!self.distortion.is_zero()).then_some(self.distortion),
            dist_out: (!self.distortion_out.is_zero()).then_some(self.distortion_out),
            width: self.k.width,
            height: self.k.height,
        })
    }
}

#[inline]
fn apply_h(h: &Matrix3<f64>, x: f64, y: f64) -> Option<(f64, f64)> {
    let p = h * Vector3::new(x, y, 1.0);
    // Points mapped to or behind the plane at infinity are outside the augmented view.
    if p.z.is_nan() || p.z <= 1e-12 {
        return None;
    }
    Some((p.x / p.z, p.y / p.z))
}

/// Precomputed forward and inverse coordinate maps of one camera augmentation (eq. 3.5).
#[derive(Clone, Debug)]
pub struct CameraMap {
    /// H = K_rel K R K⁻¹.
    pub h: Matrix3<f64>,
    /// H⁻¹.
    pub h_inv: Matrix3<f64>,
    k: Intrinsics,
    k_out: Intrinsics,
    dist_in: Option<Distortion>,
    dist_out: Option<Distortion>,
    /// Image size (source and augmented).
    pub width: usize,
    /// Image height (px).
    pub height: usize,
}

impl CameraMap {
    /// True when the map is a plain homography (no distortion on either side).
    pub fn is_homography(&self) -> bool {
        self.dist_in.is_none() && self.dist_out.is_none()
    }

    /// Eq. 3.5: source pixel p → augmented pixel p' (`None` if undistortion fails or the point
    /// leaves the front half-space).
    pub fn forward(&self, x: f64, y: f64) -> Option<(f64, f64)> {
        let (u, v) = match &self.dist_in {
            Some(d) => d.undistort_pixel(&self.k, x, y)?,
            None => (x, y),
        };
        let (u, v) = apply_h(&self.h, u, v)?;
        Some(match &self.dist_out {
            Some(d) => d.distort_pixel(&self.k_out, u, v),
            None => (u, v),
        })
    }

    /// Inverse of eq. 3.5: augmented pixel p' → source pixel p.
    pub fn inverse(&self, x: f64, y: f64) -> Option<(f64, f64)> {
        let (u, v) = match &self.dist_out {
            Some(d) => d.undistort_pixel(&self.k_out, x, y)?,
            None => (x, y),
        };
        let (u, v) = apply_h(&self.h_inv, u, v)?;
        Some(match &self.dist_in {
            Some(d) => d.distort_pixel(&self.k, u, v),
            None => (u, v),
        })
    }

    /// Source coordinates of every pixel of augmented row `y` (NaN when undefined).
    #[inline]
    fn row_sources(&self, y: usize, buf: &mut [(f64, f64)]) {
        let yf = y as f64;
        if self.is_homography() {
            let h = &self.h_inv;
            let (c0, c1, c2) = (h[(0, 1)] * yf + h[(0, 2)], h[(1, 1)] * yf + h[(1, 2)], h[(2, 1)] * yf + h[(2, 2)]);
            let (a0, a1, a2) = (h[(0, 0)], h[(1, 0)], h[(2, 0)]);
            if a2 == 0.0 && c2 == 1.0 {
                for (x, b) in buf.iter_mut().enumerate() {
                    let xf = x as f64;
                    *b = (a0 * xf + c0, a1 * xf + c1);
                }
            } else {
                for (x, b) in buf.iter_mut().enumerate() {
                    let xf = x as f64;
                    let w = a2 * xf + c2;
                    *b = if w > 1e-12 {
                        let iw = 1.0 / w;
                        ((a0 * xf + c0) * iw, (a1 * xf + c1) * iw)
                    } else {
                        (f64::NAN, f64::NAN)
                    };
                }
            }
        } else {
            for (x, b) in buf.iter_mut().enumerate() {
                *b = self.inverse(x as f64, yf).unwrap_or((f64::NAN, f64::NAN));
            }
        }
    }

    /// Source coordinates of augmented row `y` in f32 (the sampler's row callback).
    #[inline]
    fn row_sources_f32(&self, y: usize, sx: &mut [f32], sy: &mut [f32]) {
        if self.is_homography() {
            let (a, c) = remap::homography_row_coeffs(&to_rows(&self.h_inv), y);
            remap::homography_row(a, c, sx, sy);
        } else {
            let yf = y as f64;
            for (x, (a, b)) in sx.iter_mut().zip(sy.iter_mut()).enumerate() {
                let (u, v) = self.inverse(x as f64, yf).unwrap_or((f64::NAN, f64::NAN));
                *a = u as f32;
                *b = v as f32;
            }
        }
    }

    /// Inverse-mapping warp through [`laparo_core::remap`] (fused homography rows when possible).
    fn warp<T: Texel>(&self, img: &Image<T>, interp: Interp, fill: T, what: &str) -> Result<Warped<T>> {
        self.check_size(img.width, img.height, what)?;
        let (w, h) = (self.width, self.height);
        let r = if self.is_homography() {
            remap::warp_homography(img, &to_rows(&self.h_inv), w, h, interp, fill)
        } else {
            remap::remap_rows(img, w, h, interp, fill, |y, sx, sy| self.row_sources_f32(y, sx, sy))
        };
        let (image, valid) = r.map_err(StereoError::rejected(what))?;
        Ok(Warped { image, valid })
    }

    /// Source coordinates of every augmented pixel (row-major, NaN when undefined).
    pub fn source_coords(&self) -> Vec<(f64, f64)> {
        let mut out = vec![(0.0, 0.0); self.width * self.height];
        out.par_chunks_mut(self.width).enumerate().for_each(|(y, row)| self.row_sources(y, row));
        out
    }

    /// Bilinear warp of an 8-bit image (any channel count) by inverse mapping. Pixels whose
    /// source lies outside the convex hull of pixel centres are 0 and invalid in the mask.
    pub fn warp_bilinear_u8(&self, img: &Image<u8>) -> Result<Warped<u8>> {
        self.warp(img, Interp::Bilinear, 0, "image")
    }

    /// Nearest-neighbour warp of a float map (disparity): invalid where the source is outside
    /// the image or not finite; invalid output pixels are `fill`. Source positions round half up.
    pub fn warp_nearest_f32(&self, img: &Image<f32>, fill: f32) -> Result<Warped<f32>> {
        self.warp(img, Interp::Nearest, fill, "float map")
    }

    /// Nearest-neighbour warp of a mask (e.g. an occlusion mask); outside → `false`.
    pub fn warp_nearest_mask(&self, m: &Mask) -> Result<Mask> {
        let f = m.map(|b| if b { 1.0f32 } else { 0.0 });
        let w = self.warp_nearest_f32(&f, 0.0)?;
        Ok(w.image.map(|v| v > 0.5))
    }

    fn check_size(&self, w: usize, h: usize, what: &str) -> Result<()> {
        if w != self.width || h != self.height {
            return Err(StereoError::SizeMismatch(format!(
                "{what} is {w}x{h}, the augmentation's camera is {}x{}",
                self.width, self.height
            )));
        }
        Ok(())
    }
}

/// A warped image with its validity mask (true where the source pixel existed).
#[derive(Clone, Debug, PartialEq)]
pub struct Warped<T> {
    /// The warped image.
    pub image: Image<T>,
    /// True where the source pixel existed.
    pub valid: Mask,
}

/// Augment one image (eq. 3.5 / 3.6): bilinear, by inverse mapping.
pub fn augment_image(img: &Image<u8>, aug: &CameraAugmentation) -> Result<Warped<u8>> {
    aug.map()?.warp_bilinear_u8(img)
}

/// Parameters of one augmented stereo sample (eqs. 3.7–3.9).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StereoAugmentation {
    /// Left camera augmentation.
    pub left: CameraAugmentation,
    /// Right camera augmentation.
    pub right: CameraAugmentation,
    /// Δx_right, px, the value the thesis rule adds to every disparity. With K_rel,right's
    /// shift t_x,R and K_rel,left's t_x,L: Δx_right = t_x,L − t_x,R (see `cats_params` docs).
    pub dx_right_px: f64,
}

impl StereoAugmentation {
    /// No augmentation for cameras `kl`, `kr`.
    pub fn identity(kl: Intrinsics, kr: Intrinsics) -> Self {
        StereoAugmentation {
            left: CameraAugmentation::identity(kl),
            right: CameraAugmentation::identity(kr),
            dx_right_px: 0.0,
        }
    }

    /// Validate both cameras.
    pub fn validate(&self) -> Result<()> {
        self.left.validate("left")?;
        self.right.validate("right")?;
        if !self.dx_right_px.is_finite() {
            return Err(invalid("dx_right_px", "not finite"));
        }
        if (self.left.k.width, self.left.k.height) != (self.right.k.width, self.right.k.height) {
            return Err(StereoError::SizeMismatch(format!(
                "left camera {}x{} vs right camera {}x{}",
                self.left.k.width, self.left.k.height, self.right.k.width, self.right.k.height
            )));
        }
        Ok(())
    }
}

/// The disparity ground-truth rule.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum GtRule {
    /// Thesis §3.3.5: warp the disparity with the left homography (nearest), add Δx_right.
    Thesis,
    /// Exact correspondence through both augmentations (and the vertical residual).
    Exact,
}

impl std::str::FromStr for GtRule {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s {
            "thesis" => Ok(GtRule::Thesis),
            "exact" => Ok(GtRule::Exact),
            _ => Err(format!("unknown GT rule '{s}' (thesis|exact)")),
        }
    }
}

/// A stereo sample: left and right images, optional left/right disparity GT (px, left: x_R = x − d;
/// right: x_L = x + d; non-finite = unknown) and optional occlusion masks.
#[derive(Clone, Debug)]
pub struct StereoSample {
    /// Left image (8-bit).
    pub left: Image<u8>,
    /// Right image (8-bit).
    pub right: Image<u8>,
    /// Left disparity GT (px; x_R = x − d; non-finite = unknown).
    pub disp_left: Option<Image<f32>>,
    /// Right disparity GT (px; x_L = x + d; non-finite = unknown).
    pub disp_right: Option<Image<f32>>,
    /// Left occlusion mask (true = occluded).
    pub occ_left: Option<Mask>,
    /// Right occlusion mask (true = occluded).
    pub occ_right: Option<Mask>,
}

/// An augmented disparity map: +inf where unknown; `vertical_residual` (exact rule only) is
/// y of the correspondence in the other augmented view minus y of the pixel, px (NaN if unknown).
#[derive(Clone, Debug)]
pub struct AugmentedDisparity {
    /// Disparity (px), +inf where unknown.
    pub disparity: Image<f32>,
    /// True where the disparity is known.
    pub valid: Mask,
    /// Vertical residual (px) of the exact rule; NaN where unknown.
    pub vertical_residual: Option<Image<f32>>,
}

/// An augmented stereo sample.
#[derive(Clone, Debug)]
pub struct AugmentedStereo {
    /// Augmented left image and its validity.
    pub left: Warped<u8>,
    /// Augmented right image and its validity.
    pub right: Warped<u8>,
    /// Augmented left disparity.
    pub disp_left: Option<AugmentedDisparity>,
    /// Augmented right disparity.
    pub disp_right: Option<AugmentedDisparity>,
    /// Warped left occlusion mask.
    pub occ_left: Option<Mask>,
    /// Warped right occlusion mask.
    pub occ_right: Option<Mask>,
}

/// Largest span (px) of the four disparities around a sample that the exact rule still
/// interpolates (a smooth surface); across larger jumps it takes the nearest value.
const SMOOTH_SPAN_PX: f32 = 1.0;

/// Disparity at a real source position for the exact rule: bilinear when the 4 neighbours are
/// finite and within 1 px of each other (a smooth surface), otherwise the nearest value
/// (`laparo_core::remap::sample_smooth`).
#[inline]
fn sample_disparity(d: &Image<f32>, x: f64, y: f64) -> Option<f64> {
    let w = d.width;
    remap::sample_smooth(w, d.height, x, y, SMOOTH_SPAN_PX, |i, j| {
        let v = d.data[j * w + i];
        v.is_finite().then_some(v)
    })
}

/// One row of the exact rule when both maps are plain homographies: the arithmetic of
/// [`sample_disparity`] and [`CameraMap::forward`] (bit for bit), in two passes: the disparity
/// samples (gathers and branches), then the other view's homography over the whole row, branch-free
/// so that it vectorises (the two divisions per pixel were the rule's bottleneck).
#[allow(clippy::too_many_arguments)]
#[inline(never)]
fn exact_row_homography(
    h_other: &Matrix3<f64>,
    d: &Image<f32>,
    sign: f64,
    y: usize,
    src: &[(f64, f64)],
    dbuf: &mut [f64],
    drow: &mut [f32],
    rrow: &mut [f32],
    vrow: &mut [bool],
    allow_simd: bool,
) {
    let (w, hgt) = (d.width, d.height);
    let hh: [f64; 9] = h_other.as_slice().try_into().expect("3x3");
    #[cfg(target_arch = "x86_64")]
    {
        // i32 gather indices: the whole disparity map must be addressable with them.
        if allow_simd
            && w >= 2
            && hgt >= 2
            && w * hgt < (i32::MAX as usize)
            && std::arch::is_x86_feature_detected!("avx2")
        {
            let n = src.len().min(drow.len()).min(rrow.len()).min(vrow.len());
            // SAFETY: the CPU supports AVX2 (checked above); sizes checked inside.
            unsafe {
                if sign < 0.0 {
                    simd::exact_row_avx2::<true>(&hh, sign, y as f64, &d.data, w, hgt, &src[..n], drow, rrow, vrow)
                } else {
                    simd::exact_row_avx2::<false>(&hh, sign, y as f64, &d.data, w, hgt, &src[..n], drow, rrow, vrow)
                }
            }
            return;
        }
    }
    // Pass 1: the disparity samples; NaN = none.
    sample_row_scalar(&d.data, w, hgt, src, dbuf);
    // Pass 2: CameraMap::forward of the other view (apply_h, nalgebra's evaluation order).
    if sign < 0.0 {
        forward_row::<true>(&hh, sign, y as f64, 0, src, dbuf, drow, rrow, vrow);
    } else {
        forward_row::<false>(&hh, sign, y as f64, 0, src, dbuf, drow, rrow, vrow);
    }
}

/// Pass 1 of the exact rule's fast path: [`sample_disparity`] at every source position of a row
/// (bilinear on smooth 2×2 neighbourhoods, else nearest; NaN = none). `data` is the w × h map.
fn sample_row_scalar(data: &[f32], w: usize, hgt: usize, src: &[(f64, f64)], dbuf: &mut [f64]) {
    let data = &data[..w * hgt];
    let value = |i: usize, j: usize| {
        let v = data[j * w + i];
        v.is_finite().then_some(v)
    };
    for (dv_out, &(sx, sy)) in dbuf.iter_mut().zip(src) {
        *dv_out = remap::sample_smooth(w, hgt, sx, sy, SMOOTH_SPAN_PX, value).unwrap_or(f64::NAN);
    }
}

/// Pass 2 of [`exact_row_homography`] (scalar; the AVX2 kernel fuses both passes); `LEFT`:
/// d = x − x_other (else x_other − x); `x_offset` is the column of `src[0]`.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn forward_row<const LEFT: bool>(
    h: &[f64; 9],
    sign: f64,
    yf: f64,
    x_offset: usize,
    src: &[(f64, f64)],
    dbuf: &[f64],
    drow: &mut [f32],
    rrow: &mut [f32],
    vrow: &mut [bool],
) {
    let [h00, h10, h20, h01, h11, h21, h02, h12, h22] = *h;
    let n = src.len().min(dbuf.len()).min(drow.len()).min(rrow.len()).min(vrow.len());
    for x in 0..n {
        let (sx, sy) = src[x];
        let dv = dbuf[x];
        let u = sx + sign * dv;
        let pz = h20 * u + h21 * sy + h22;
        let ox = (h00 * u + h01 * sy + h02) / pz;
        let oy = (h10 * u + h11 * sy + h12) / pz;
        // NaN dv makes pz NaN, and NaN fails the comparison.
        let ok = pz > 1e-12;
        let xf = (x + x_offset) as f64;
        let dd = if LEFT { xf - ox } else { ox - xf };
        drow[x] = if ok { dd as f32 } else { f32::INFINITY };
        rrow[x] = if ok { (oy - yf) as f32 } else { f32::NAN };
        vrow[x] = ok;
    }
}

/// AVX2 kernel of the exact rule's homography fast path (runtime-dispatched; the scalar
/// [`exact_row_homography`] passes are the reference and the output is bit-identical: same
/// operations in the same order, no FMA contraction, IEEE min/max with the scalar's NaN-free
/// semantics).
#[cfg(target_arch = "x86_64")]
mod simd {
    use laparo_core::remap::simd::bilerp_pd;
    use std::arch::x86_64::*;

    /// Four i32 lane masks (all ones / zero) widened to four f64 lane masks.
    #[inline(always)]
    unsafe fn widen(m: __m128) -> __m256d {
        _mm256_castsi256_pd(_mm256_cvtepi32_epi64(_mm_castps_si128(m)))
    }

    /// One row: sample the disparity at the source positions `src` and map through the other
    /// view's homography `h` (column-major 3×3). `data` is the w × h disparity map (w, h ≥ 2,
    /// w·h < 2³¹).
    #[allow(clippy::too_many_arguments)]
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn exact_row_avx2<const LEFT: bool>(
        h: &[f64; 9],
        sign: f64,
        yf: f64,
        data: &[f32],
        w: usize,
        hgt: usize,
        src: &[(f64, f64)],
        drow: &mut [f32],
        rrow: &mut [f32],
        vrow: &mut [bool],
    ) {
        assert!(w >= 2 && hgt >= 2 && data.len() >= w * hgt && w * hgt < i32::MAX as usize);
        let n = src.len();
        assert!(drow.len() >= n && rrow.len() >= n && vrow.len() >= n);
        let [h00, h10, h20, h01, h11, h21, h02, h12, h22] = h.map(|v| _mm256_set1_pd(v));
        let (wf, hf) = (w as f64, hgt as f64);
        let lo_out = _mm256_set1_pd(-0.5);
        let (hi_x, hi_y) = (_mm256_set1_pd(wf - 0.5), _mm256_set1_pd(hf - 0.5));
        let zero = _mm256_setzero_pd();
        let (xmax, ymax) = (_mm256_set1_pd((w - 1) as f64), _mm256_set1_pd((hgt - 1) as f64));
        let (wm2, hm2) = (_mm_set1_epi32(w as i32 - 2), _mm_set1_epi32(hgt as i32 - 2));
        let wi = _mm_set1_epi32(w as i32);
        let one_i = _mm_set1_epi32(1);
        let half = _mm256_set1_pd(0.5);
        let one_f32 = _mm_set1_ps(1.0);
        let (vsign, vy, eps) = (_mm256_set1_pd(sign), _mm256_set1_pd(yf), _mm256_set1_pd(1e-12));
        let (inf, nan) = (_mm_set1_ps(f32::INFINITY), _mm_set1_ps(f32::NAN));
        let dp = data.as_ptr();
        let mut x = 0;
        while x + 4 <= n {
            let p = src.as_ptr().add(x) as *const f64;
            let (a, b) = (_mm256_loadu_pd(p), _mm256_loadu_pd(p.add(4)));
            // [x0 y0 x1 y1] [x2 y2 x3 y3] -> [x0 x2 x1 x3] -> [x0 x1 x2 x3].
            let sx = _mm256_permute4x64_pd::<0b11_01_10_00>(_mm256_unpacklo_pd(a, b));
            let sy = _mm256_permute4x64_pd::<0b11_01_10_00>(_mm256_unpackhi_pd(a, b));
            let outer = _mm256_and_pd(
                _mm256_and_pd(_mm256_cmp_pd::<_CMP_GE_OQ>(sx, lo_out), _mm256_cmp_pd::<_CMP_GE_OQ>(sy, lo_out)),
                _mm256_and_pd(_mm256_cmp_pd::<_CMP_LT_OQ>(sx, hi_x), _mm256_cmp_pd::<_CMP_LT_OQ>(sy, hi_y)),
            );
            let inner = _mm256_and_pd(
                _mm256_and_pd(
                    outer,
                    _mm256_and_pd(_mm256_cmp_pd::<_CMP_GE_OQ>(sx, zero), _mm256_cmp_pd::<_CMP_GE_OQ>(sy, zero)),
                ),
                _mm256_and_pd(_mm256_cmp_pd::<_CMP_LE_OQ>(sx, xmax), _mm256_cmp_pd::<_CMP_LE_OQ>(sy, ymax)),
            );
            // Bilinear candidate (indices forced to 0 outside `inner`, so every gather is in bounds).
            let sxi = _mm256_and_pd(sx, inner);
            let syi = _mm256_and_pd(sy, inner);
            let x0 = _mm_min_epi32(_mm256_cvttpd_epi32(sxi), wm2);
            let y0 = _mm_min_epi32(_mm256_cvttpd_epi32(syi), hm2);
            let i00 = _mm_add_epi32(_mm_mullo_epi32(y0, wi), x0);
            let i01 = _mm_add_epi32(i00, wi);
            let p00 = _mm_i32gather_ps::<4>(dp, i00);
            let p10 = _mm_i32gather_ps::<4>(dp, _mm_add_epi32(i00, one_i));
            let p01 = _mm_i32gather_ps::<4>(dp, i01);
            let p11 = _mm_i32gather_ps::<4>(dp, _mm_add_epi32(i01, one_i));
            let fin = _mm_add_ps(
                _mm_add_ps(_mm_add_ps(_mm_sub_ps(p00, p00), _mm_sub_ps(p10, p10)), _mm_sub_ps(p01, p01)),
                _mm_sub_ps(p11, p11),
            );
            let finite = _mm_cmp_ps::<_CMP_EQ_OQ>(fin, _mm_setzero_ps());
            let lo = _mm_min_ps(_mm_min_ps(p00, p10), _mm_min_ps(p01, p11));
            let hi = _mm_max_ps(_mm_max_ps(p00, p10), _mm_max_ps(p01, p11));
            let smooth = _mm_cmp_ps::<_CMP_LE_OQ>(_mm_sub_ps(hi, lo), one_f32);
            let bil_ok = _mm256_and_pd(inner, widen(_mm_and_ps(finite, smooth)));
            let ax = _mm256_sub_pd(sx, _mm256_cvtepi32_pd(x0));
            let ay = _mm256_sub_pd(sy, _mm256_cvtepi32_pd(y0));
            let (q00, q10) = (_mm256_cvtps_pd(p00), _mm256_cvtps_pd(p10));
            let (q01, q11) = (_mm256_cvtps_pd(p01), _mm256_cvtps_pd(p11));
            let bil = bilerp_pd(q00, q10, q01, q11, ax, ay);
            // Nearest candidate (inside `outer`).
            let nx = _mm256_cvttpd_epi32(_mm256_and_pd(_mm256_add_pd(sx, half), outer));
            let ny = _mm256_cvttpd_epi32(_mm256_and_pd(_mm256_add_pd(sy, half), outer));
            let vn = _mm_i32gather_ps::<4>(dp, _mm_add_epi32(_mm_mullo_epi32(ny, wi), nx));
            let vn_ok = _mm256_and_pd(outer, widen(_mm_cmp_ps::<_CMP_EQ_OQ>(_mm_sub_ps(vn, vn), _mm_setzero_ps())));
            let dnear = _mm256_blendv_pd(_mm256_set1_pd(f64::NAN), _mm256_cvtps_pd(vn), vn_ok);
            let dv = _mm256_blendv_pd(dnear, bil, bil_ok);
            // CameraMap::forward of the other view.
            let u = _mm256_add_pd(sx, _mm256_mul_pd(vsign, dv));
            let pz = _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(h20, u), _mm256_mul_pd(h21, sy)), h22);
            let ox =
                _mm256_div_pd(_mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(h00, u), _mm256_mul_pd(h01, sy)), h02), pz);
            let oy =
                _mm256_div_pd(_mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(h10, u), _mm256_mul_pd(h11, sy)), h12), pz);
            let ok = _mm256_cmp_pd::<_CMP_GT_OQ>(pz, eps);
            let xf = _mm256_setr_pd(x as f64, (x + 1) as f64, (x + 2) as f64, (x + 3) as f64);
            let dd = if LEFT { _mm256_sub_pd(xf, ox) } else { _mm256_sub_pd(ox, xf) };
            let ok4 = _mm256_castps256_ps128(low_lanes(ok));
            _mm_storeu_ps(drow.as_mut_ptr().add(x), _mm_blendv_ps(inf, _mm256_cvtpd_ps(dd), ok4));
            _mm_storeu_ps(rrow.as_mut_ptr().add(x), _mm_blendv_ps(nan, _mm256_cvtpd_ps(_mm256_sub_pd(oy, vy)), ok4));
            let m = _mm256_movemask_pd(ok);
            for k in 0..4 {
                vrow[x + k] = (m >> k) & 1 == 1;
            }
            x += 4;
        }
        // Tail: the scalar kernel on the last < 4 pixels.
        if x < n {
            let mut dbuf = [0.0f64; 4];
            super::sample_row_scalar(data, w, hgt, &src[x..n], &mut dbuf[..n - x]);
            super::forward_row::<LEFT>(
                h,
                sign,
                yf,
                x,
                &src[x..n],
                &dbuf[..n - x],
                &mut drow[x..n],
                &mut rrow[x..n],
                &mut vrow[x..n],
            );
        }
    }

    /// Compress the four 64-bit lane masks of `m` into the low four 32-bit lanes.
    #[inline(always)]
    unsafe fn low_lanes(m: __m256d) -> __m256 {
        _mm256_permutevar8x32_ps(_mm256_castpd_ps(m), _mm256_setr_epi32(0, 2, 4, 6, 0, 2, 4, 6))
    }
}

/// Thesis rule (a): d'(p') = d(nearest(A⁻¹ p')) + offset.
fn disparity_thesis(map: &CameraMap, d: &Image<f32>, offset: f64) -> Result<AugmentedDisparity> {
    let w = map.warp_nearest_f32(d, f32::INFINITY)?;
    let mut out = w.image;
    for (v, &ok) in out.data.iter_mut().zip(&w.valid.data) {
        if ok {
            *v = (*v as f64 + offset) as f32;
        }
    }
    Ok(AugmentedDisparity { disparity: out, valid: w.valid, vertical_residual: None })
}

/// Exact rule (b). `sign` = −1 for a left map (x_R = x − d), +1 for a right map (x_L = x + d);
/// the disparity stays x_L − x_R in both cases.
fn disparity_exact(own: &CameraMap, other: &CameraMap, d: &Image<f32>, sign: f64) -> Result<AugmentedDisparity> {
    disparity_exact_with(own, other, d, sign, true, true)
}

/// [`disparity_exact`], with the homography fast path allowed or not (tests compare both).
fn disparity_exact_with(
    own: &CameraMap,
    other: &CameraMap,
    d: &Image<f32>,
    sign: f64,
    allow_fast: bool,
    allow_simd: bool,
) -> Result<AugmentedDisparity> {
    own.check_size(d.width, d.height, "disparity")?;
    let (w, h) = (own.width, own.height);
    let mut disp = Image::filled(w, h, 1, f32::INFINITY);
    let mut res = Image::filled(w, h, 1, f32::NAN);
    let mut valid = Image::filled(w, h, 1, false);
    let fast = allow_fast && own.is_homography() && other.is_homography();
    disp.data
        .par_chunks_mut(w)
        .zip(res.data.par_chunks_mut(w))
        .zip(valid.data.par_chunks_mut(w))
        .enumerate()
        .for_each_init(
            || (vec![(0.0, 0.0); w], vec![0.0; w]),
            |(buf, dbuf), (y, ((drow, rrow), vrow))| {
                own.row_sources(y, buf);
                if fast {
                    exact_row_homography(&other.h, d, sign, y, buf, dbuf, drow, rrow, vrow, allow_simd);
                    return;
                }
                for (x, &(sx, sy)) in buf.iter().enumerate() {
                    let Some(dv) = sample_disparity(d, sx, sy) else { continue };
                    let Some((ox, oy)) = other.forward(sx + sign * dv, sy) else { continue };
                    let dd = if sign < 0.0 { x as f64 - ox } else { ox - x as f64 };
                    drow[x] = dd as f32;
                    rrow[x] = (oy - y as f64) as f32;
                    vrow[x] = true;
                }
            },
        );
    Ok(AugmentedDisparity { disparity: disp, valid, vertical_residual: Some(res) })
}

/// Augment a stereo sample (eqs. 3.7–3.9) with the given disparity rule.
pub fn augment_stereo(s: &StereoSample, p: &StereoAugmentation, rule: GtRule) -> Result<AugmentedStereo> {
    p.validate()?;
    s.left.check_same_size(&s.right, "left vs right image")?;
    if s.left.channels != s.right.channels {
        return Err(StereoError::SizeMismatch(format!(
            "left image has {} channels, right {}",
            s.left.channels, s.right.channels
        )));
    }
    let ml = p.left.map()?;
    let mr = p.right.map()?;
    let left = ml.warp_bilinear_u8(&s.left)?;
    let right = mr.warp_bilinear_u8(&s.right)?;
    let disp = |d: &Option<Image<f32>>, own: &CameraMap, other: &CameraMap, sign: f64, what: &str| {
        d.as_ref()
            .map(|d| {
                if d.channels != 1 {
                    return Err(invalid(what, format!("{} channels (need 1)", d.channels)));
                }
                match rule {
                    GtRule::Thesis => disparity_thesis(own, d, p.dx_right_px),
                    GtRule::Exact => disparity_exact(own, other, d, sign),
                }
            })
            .transpose()
    };
    let disp_left = disp(&s.disp_left, &ml, &mr, -1.0, "left disparity")?;
    let disp_right = disp(&s.disp_right, &mr, &ml, 1.0, "right disparity")?;
    let occ_left = s.occ_left.as_ref().map(|m| ml.warp_nearest_mask(m)).transpose()?;
    let occ_right = s.occ_right.as_ref().map(|m| mr.warp_nearest_mask(m)).transpose()?;
    Ok(AugmentedStereo { left, right, disp_left, disp_right, occ_left, occ_right })
}

/// Per-pixel comparison of two disparity maps over pixels valid in both: (EPE mean, max, count).
pub fn disparity_difference(a: &AugmentedDisparity, b: &AugmentedDisparity) -> (f64, f64, usize) {
    let (mut s, mut m, mut n) = (0.0, 0.0f64, 0usize);
    for i in 0..a.disparity.data.len() {
        if a.valid.data[i] && b.valid.data[i] {
            let e = (a.disparity.data[i] as f64 - b.disparity.data[i] as f64).abs();
            s += e;
            m = m.max(e);
            n += 1;
        }
    }
    (if n > 0 { s / n as f64 } else { f64::NAN }, m, n)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn k() -> Intrinsics {
        Intrinsics::new(500.0, 510.0, 63.5, 47.5, 128, 96).unwrap()
    }

    #[test]
    fn forward_inverse_compose_to_identity_with_distortion() {
        let a = CameraAugmentation::from_euler_deg(
            k(),
            Distortion::brown_conrady(-0.05, 0.01, 0.001, -0.0005, 0.0),
            [0.3, -0.2, 0.5],
            Matrix3::new(1.02, 0.0, -7.0, 0.0, 0.99, 2.0, 0.0, 0.0, 1.0),
            Distortion::brown_conrady(0.08, -0.02, 0.0, 0.0005, 0.0),
        );
        let m = a.map().unwrap();
        let mut worst = 0.0f64;
        for y in (0..96).step_by(5) {
            for x in (0..128).step_by(5) {
                let (u, v) = m.forward(x as f64, y as f64).unwrap();
                let (p, q) = m.inverse(u, v).unwrap();
                worst = worst.max((p - x as f64).hypot(q - y as f64));
                let (p, q) = m
                    .forward(m.inverse(x as f64, y as f64).unwrap().0, m.inverse(x as f64, y as f64).unwrap().1)
                    .unwrap();
                worst = worst.max((p - x as f64).hypot(q - y as f64));
            }
        }
        assert!(worst < 1e-9, "worst {worst} px");
    }

    #[test]
    fn exact_rule_fast_path_is_bit_identical_to_the_general_path() {
        // An odd width exercises the SIMD kernel's scalar tail.
        let (w, h) = (127usize, 96usize);
        let kk = Intrinsics::new(500.0, 510.0, 63.0, 47.5, w, h).unwrap();
        // A smooth surface with a step (nearest fallback), holes and NaN.
        let data: Vec<f32> = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                match (i % 97, x > 70.0) {
                    (0, _) => f32::INFINITY,
                    (13, _) => f32::NAN,
                    (_, true) => 30.0 + 0.05 * x + 0.3 * (y * 0.2).sin(),
                    _ => 12.0 + 0.1 * x - 0.02 * y,
                }
            })
            .collect();
        let d = Image::from_vec(w, h, 1, data).unwrap();
        let cam = |e: [f64; 3], dx: f64| {
            CameraAugmentation::from_euler_deg(
                kk,
                Distortion::default(),
                e,
                Matrix3::new(1.0, 0.0, -dx, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0),
                Distortion::default(),
            )
            .map()
            .unwrap()
        };
        let (l, r) = (cam([0.4, -0.7, 1.5], 0.0), cam([-0.3, 0.9, -2.0], -40.0));
        for (own, other, sign) in [(&l, &r, -1.0), (&r, &l, 1.0)] {
            let b = disparity_exact_with(own, other, &d, sign, false, false).unwrap();
            assert!(b.valid.data.iter().filter(|&&v| v).count() > w * h / 2);
            let bits = |im: &Image<f32>| im.data.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            // Fast path, scalar and (where the CPU has it) AVX2.
            for simd in [false, true] {
                let a = disparity_exact_with(own, other, &d, sign, true, simd).unwrap();
                assert_eq!(a.valid.data, b.valid.data, "simd {simd}");
                assert_eq!(bits(&a.disparity), bits(&b.disparity), "simd {simd}");
                assert_eq!(
                    bits(a.vertical_residual.as_ref().unwrap()),
                    bits(b.vertical_residual.as_ref().unwrap()),
                    "simd {simd}"
                );
            }
        }
    }

    #[test]
    fn homography_is_k_rel_k_r_k_inv() {
        let a = CameraAugmentation::from_euler_deg(
            k(),
            Distortion::default(),
            [1.0, 2.0, 3.0],
            Matrix3::identity(),
            Distortion::default(),
        );
        // A pure rotation maps the ray of p to R times that ray: check on one pixel by hand.
        let kk = k().matrix();
        let ray = kk.try_inverse().unwrap() * Vector3::new(10.0, 20.0, 1.0);
        let r = rotation_zyx(1f64.to_radians(), 2f64.to_radians(), 3f64.to_radians());
        let q = kk * (r * ray);
        let (u, v) = a.map().unwrap().forward(10.0, 20.0).unwrap();
        assert!((u - q.x / q.z).abs() < 1e-10 && (v - q.y / q.z).abs() < 1e-10);
    }
}
