//! Disparity ↔ depth for a (near-)rectified pair (thesis §3.3.8): `d = f b / z + (c_x^L − c_x^R)`,
//! so `z = f b / (d − (c_x^L − c_x^R))`; Middlebury's `doffs = c_x^R − c_x^L`. Disparities may be
//! negative (principal points offset); depth in the baseline's unit (mm).
use crate::error::{Result, StereoError};
use laparo_core::calib::StereoCalibration;
use laparo_core::depth::{DepthMap, DepthUnit};
use laparo_core::image::Image;
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// The disparity ↔ depth geometry of a (near-)rectified pair (§3.3.8):
/// `d = f b / z + (c_x^L − c_x^R)`. Depth in the baseline's unit (mm).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct DisparityGeometry {
    /// Focal length along x (px).
    pub f_px: f64,
    /// Focal length along y (px), for back-projection.
    pub fy_px: f64,
    /// Baseline (mm).
    pub baseline_mm: f64,
    /// Principal points (px).
    pub cx_left: f64,
    /// Right principal point x (px).
    pub cx_right: f64,
    /// Principal point y (px; both cameras after rectification).
    pub cy: f64,
}

impl DisparityGeometry {
    /// From a calibration used as is ("static calibration parameters", Table 3.7): f = left f_x,
    /// b = |T|, the two principal points. Exact only for a rectified pair; for a raw
    /// near-rectified pair it is the §3.3.8 approximation.
    pub fn from_calibration(c: &StereoCalibration) -> Result<Self> {
        c.left.validate()?;
        c.right.validate()?;
        let b = c.t_mm.norm();
        if !(b.is_finite() && b > 0.0) {
            return Err(StereoError::invalid("T", format!("baseline |T| = {b} mm")));
        }
        Ok(DisparityGeometry {
            f_px: c.left.fx,
            fy_px: c.left.fy,
            baseline_mm: b,
            cx_left: c.left.cx,
            cx_right: c.right.cx,
            cy: c.left.cy,
        })
    }

    /// Middlebury-style parameters: f, baseline (mm), `doffs = c_x^R − c_x^L`, left c_x, c_y.
    pub fn middlebury(f_px: f64, baseline_mm: f64, doffs_px: f64, cx_left: f64, cy: f64) -> Self {
        DisparityGeometry { f_px, fy_px: f_px, baseline_mm, cx_left, cx_right: cx_left + doffs_px, cy }
    }

    /// `c_x^L − c_x^R` (px).
    pub fn offset_px(&self) -> f64 {
        self.cx_left - self.cx_right
    }

    /// Depth (mm) of disparity `d` (px): `z = f b / (d − (c_x^L − c_x^R))`; NaN when `d` is not
    /// finite or the point would be at or beyond infinity (`d ≤ c_x^L − c_x^R`).
    #[inline]
    pub fn depth_mm(&self, d: f64) -> f64 {
        let den = d - self.offset_px();
        if d.is_finite() && den > 0.0 {
            self.f_px * self.baseline_mm / den
        } else {
            f64::NAN
        }
    }

    /// Disparity (px) of depth `z` (mm): `d = f b / z + (c_x^L − c_x^R)` (§3.3.8); NaN when z ≤ 0.
    #[inline]
    pub fn disparity_px(&self, z_mm: f64) -> f64 {
        if z_mm.is_finite() && z_mm > 0.0 {
            self.f_px * self.baseline_mm / z_mm + self.offset_px()
        } else {
            f64::NAN
        }
    }

    /// Depth map (mm) of a left disparity map (channel 0).
    pub fn depth_map(&self, disp: &Image<f64>) -> DepthMap {
        let data: Vec<f64> = (0..disp.n_pixels()).map(|i| self.depth_mm(disp.data[i * disp.channels])).collect();
        DepthMap { width: disp.width, height: disp.height, unit: DepthUnit::Mm, data }
    }

    /// Left disparity map (px) of a depth map (any unit; converted to mm).
    pub fn disparity_map(&self, depth: &DepthMap) -> Image<f64> {
        let s = depth.unit.to_metres() * 1e3;
        Image {
            width: depth.width,
            height: depth.height,
            channels: 1,
            data: depth.data.iter().map(|&z| self.disparity_px(z * s)).collect(),
        }
    }

    /// Left-camera 3D point (mm) of left pixel (x, y) with disparity d:
    /// `X = (x − c_x^L) z / f`, `Y = (y − c_y) z / f_y`, `Z = z`. `None` when the depth is invalid.
    pub fn point_mm(&self, x: f64, y: f64, d: f64) -> Option<Vector3<f64>> {
        let z = self.depth_mm(d);
        if !z.is_finite() {
            return None;
        }
        Some(Vector3::new((x - self.cx_left) * z / self.f_px, (y - self.cy) * z / self.fy_px, z))
    }

    /// Point cloud (mm) of every valid pixel of a left disparity map: `(x, y, point)`.
    pub fn point_cloud(&self, disp: &Image<f64>) -> Vec<(usize, usize, Vector3<f64>)> {
        let mut out = Vec::new();
        for y in 0..disp.height {
            for x in 0..disp.width {
                if let Some(p) = self.point_mm(x as f64, y as f64, disp.get(x, y, 0)) {
                    out.push((x, y, p));
                }
            }
        }
        out
    }
}
