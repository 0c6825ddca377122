//! Pinhole intrinsics K and the Brown–Conrady lens distortion model (OpenCV's convention:
//! k1, k2, p1, p2, k3 and the optional rational k4, k5, k6 and thin-prism s1..s4).
//!
//! Pixel coordinates: x to the right, y down, pixel centres at integers.
use crate::error::{CoreError, Result};
use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};

/// Pinhole intrinsics: focal lengths and principal point in px, image size in px.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Intrinsics {
    /// Focal length along x (px).
    pub fx: f64,
    /// Focal length along y (px).
    pub fy: f64,
    /// Principal point x (px; pixel centres at integers).
    pub cx: f64,
    /// Principal point y (px).
    pub cy: f64,
    /// Skew (K[0,1]); 0 for nearly every camera.
    #[serde(default)]
    pub skew: f64,
    /// Image width (px).
    pub width: usize,
    /// Image height (px).
    pub height: usize,
}

impl Intrinsics {
    /// Intrinsics without skew; fails on non-positive or non-finite focal lengths.
    pub fn new(fx: f64, fy: f64, cx: f64, cy: f64, width: usize, height: usize) -> Result<Self> {
        let k = Intrinsics { fx, fy, cx, cy, skew: 0.0, width, height };
        k.validate()?;
        Ok(k)
    }

    /// Check that focal lengths are finite and > 0, the principal point finite, the size non-zero.
    pub fn validate(&self) -> Result<()> {
        if !(self.fx.is_finite() && self.fx > 0.0 && self.fy.is_finite() && self.fy > 0.0) {
            return Err(CoreError::invalid(
                "focal length",
                format!("fx = {}, fy = {} (must be finite and > 0)", self.fx, self.fy),
            ));
        }
        if !(self.cx.is_finite() && self.cy.is_finite() && self.skew.is_finite()) {
            return Err(CoreError::invalid("principal point", format!("cx = {}, cy = {}", self.cx, self.cy)));
        }
        crate::io::check_image_size(self.width as u64, self.height as u64, "image size")?;
        Ok(())
    }

    /// From a 3×3 camera matrix K.
    pub fn from_matrix(k: &Matrix3<f64>, width: usize, height: usize) -> Result<Self> {
        let i =
            Intrinsics { fx: k[(0, 0)], fy: k[(1, 1)], cx: k[(0, 2)], cy: k[(1, 2)], skew: k[(0, 1)], width, height };
        i.validate()?;
        Ok(i)
    }

    /// The camera matrix K.
    pub fn matrix(&self) -> Matrix3<f64> {
        Matrix3::new(self.fx, self.skew, self.cx, 0.0, self.fy, self.cy, 0.0, 0.0, 1.0)
    }

    /// Normalised image coordinates (x/z, y/z) → pixel.
    #[inline]
    pub fn normalized_to_pixel(&self, xn: f64, yn: f64) -> (f64, f64) {
        (self.fx * xn + self.skew * yn + self.cx, self.fy * yn + self.cy)
    }

    /// Pixel → normalised image coordinates.
    #[inline]
    pub fn pixel_to_normalized(&self, u: f64, v: f64) -> (f64, f64) {
        let yn = (v - self.cy) / self.fy;
        ((u - self.cx - self.skew * yn) / self.fx, yn)
    }

    /// Project a camera-frame 3D point (z > 0) to pixels; `None` if z <= 0.
    #[inline]
    pub fn project(&self, p: &Vector3<f64>) -> Option<(f64, f64)> {
        if p.z <= 0.0 {
            return None;
        }
        Some(self.normalized_to_pixel(p.x / p.z, p.y / p.z))
    }

    /// Back-project pixel (u, v) at depth z (along the optical axis, same unit as the result).
    #[inline]
    pub fn backproject(&self, u: f64, v: f64, z: f64) -> Vector3<f64> {
        let (xn, yn) = self.pixel_to_normalized(u, v);
        Vector3::new(xn * z, yn * z, z)
    }

    /// The intrinsics of the same camera after resizing the image by (sx, sy).
    pub fn scaled(&self, sx: f64, sy: f64) -> Intrinsics {
        Intrinsics {
            fx: self.fx * sx,
            fy: self.fy * sy,
            cx: (self.cx + 0.5) * sx - 0.5,
            cy: (self.cy + 0.5) * sy - 0.5,
            skew: self.skew * sx,
            width: (self.width as f64 * sx).round() as usize,
            height: (self.height as f64 * sy).round() as usize,
        }
    }
}

/// Brown–Conrady distortion coefficients in OpenCV order
/// (k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4); unused ones are 0.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Distortion {
    /// Radial coefficient k1.
    pub k1: f64,
    /// Radial coefficient k2.
    pub k2: f64,
    /// Tangential coefficient p1.
    pub p1: f64,
    /// Tangential coefficient p2.
    pub p2: f64,
    /// Radial coefficient k3.
    pub k3: f64,
    /// Rational-model denominator coefficient k4 (OpenCV rational model).
    #[serde(default)]
    pub k4: f64,
    /// Rational-model denominator coefficient k5.
    #[serde(default)]
    pub k5: f64,
    /// Rational-model denominator coefficient k6.
    #[serde(default)]
    pub k6: f64,
    /// Thin-prism coefficient s1.
    #[serde(default)]
    pub s1: f64,
    /// Thin-prism coefficient s2.
    #[serde(default)]
    pub s2: f64,
    /// Thin-prism coefficient s3.
    #[serde(default)]
    pub s3: f64,
    /// Thin-prism coefficient s4.
    #[serde(default)]
    pub s4: f64,
}

impl Distortion {
    /// Brown–Conrady with five coefficients (k1, k2, p1, p2, k3).
    pub fn brown_conrady(k1: f64, k2: f64, p1: f64, p2: f64, k3: f64) -> Self {
        Distortion { k1, k2, p1, p2, k3, ..Default::default() }
    }

    /// From an OpenCV coefficient vector of length 4, 5, 8, 12 or 14 (tilt τx, τy must be 0).
    pub fn from_opencv(c: &[f64]) -> Result<Self> {
        let n = c.len();
        if ![0, 4, 5, 8, 12, 14].contains(&n) {
            return Err(CoreError::invalid("distortion", format!("{n} coefficients (expected 4, 5, 8, 12 or 14)")));
        }
        if c.iter().any(|v| !v.is_finite()) {
            return Err(CoreError::invalid("distortion", "non-finite coefficient"));
        }
        if n == 14 && (c[12] != 0.0 || c[13] != 0.0) {
            return Err(CoreError::invalid(
                "distortion",
                "tilted-sensor coefficients (tau_x, tau_y) are not supported",
            ));
        }
        let g = |i: usize| if i < n { c[i] } else { 0.0 };
        Ok(Distortion {
            k1: g(0),
            k2: g(1),
            p1: g(2),
            p2: g(3),
            k3: g(4),
            k4: g(5),
            k5: g(6),
            k6: g(7),
            s1: g(8),
            s2: g(9),
            s3: g(10),
            s4: g(11),
        })
    }

    /// OpenCV order, length 5 when only Brown–Conrady terms are used, else 8 or 12.
    pub fn to_opencv(&self) -> Vec<f64> {
        let all = [
            self.k1, self.k2, self.p1, self.p2, self.k3, self.k4, self.k5, self.k6, self.s1, self.s2, self.s3, self.s4,
        ];
        let n = if all[8..].iter().any(|&v| v != 0.0) {
            12
        } else if all[5..8].iter().any(|&v| v != 0.0) {
            8
        } else {
            5
        };
        all[..n].to_vec()
    }

    /// True when every coefficient is zero.
    pub fn is_zero(&self) -> bool {
        self.to_opencv().iter().all(|&v| v == 0.0)
    }

    /// Distort normalised coordinates (x, y) → (x_d, y_d).
    #[inline]
    pub fn distort_normalized(&self, x: f64, y: f64) -> (f64, f64) {
        let r2 = x * x + y * y;
        let r4 = r2 * r2;
        let r6 = r4 * r2;
        let radial =
            (1.0 + self.k1 * r2 + self.k2 * r4 + self.k3 * r6) / (1.0 + self.k4 * r2 + self.k5 * r4 + self.k6 * r6);
        let xd = x * radial + 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x) + self.s1 * r2 + self.s2 * r4;
        let yd = y * radial + self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y + self.s3 * r2 + self.s4 * r4;
        (xd, yd)
    }

    /// Analytic Jacobian [[∂x_d/∂x, ∂x_d/∂y], [∂y_d/∂x, ∂y_d/∂y]] of
    /// [`Self::distort_normalized`] (drives Newton's method in undistortion).
    #[inline]
    fn jacobian(&self, x: f64, y: f64) -> [[f64; 2]; 2] {
        let r2 = x * x + y * y;
        let r4 = r2 * r2;
        let n = 1.0 + self.k1 * r2 + self.k2 * r4 + self.k3 * r4 * r2;
        let d = 1.0 + self.k4 * r2 + self.k5 * r4 + self.k6 * r4 * r2;
        let dn = self.k1 + 2.0 * self.k2 * r2 + 3.0 * self.k3 * r4;
        let dd = self.k4 + 2.0 * self.k5 * r2 + 3.0 * self.k6 * r4;
        let radial = n / d;
        // d(radial)/d(r²)
        let dr = (dn * d - n * dd) / (d * d);
        let xx = radial
            + 2.0 * x * x * dr
            + 2.0 * self.p1 * y
            + 6.0 * self.p2 * x
            + 2.0 * self.s1 * x
            + 4.0 * self.s2 * r2 * x;
        let xy = 2.0 * x * y * dr + 2.0 * self.p1 * x + 2.0 * self.p2 * y + 2.0 * self.s1 * y + 4.0 * self.s2 * r2 * y;
        let yx = 2.0 * x * y * dr + 2.0 * self.p1 * x + 2.0 * self.p2 * y + 2.0 * self.s3 * x + 4.0 * self.s4 * r2 * x;
        let yy = radial
            + 2.0 * y * y * dr
            + 6.0 * self.p1 * y
            + 2.0 * self.p2 * x
            + 2.0 * self.s3 * y
            + 4.0 * self.s4 * r2 * y;
        [[xx, xy], [yx, yy]]
    }

    /// Undistort normalised coordinates by Newton iterations on the forward model
    /// (tolerance 1e-14 in normalised units). Returns `None` if it does not converge.
    pub fn undistort_normalized(&self, xd: f64, yd: f64) -> Option<(f64, f64)> {
        if self.is_zero() {
            return Some((xd, yd));
        }
        let (mut x, mut y) = (xd, yd);
        for _ in 0..50 {
            let (fx, fy) = self.distort_normalized(x, y);
            let (rx, ry) = (fx - xd, fy - yd);
            if rx.abs() < 1e-14 && ry.abs() < 1e-14 {
                return Some((x, y));
            }
            let j = self.jacobian(x, y);
            let det = j[0][0] * j[1][1] - j[0][1] * j[1][0];
            if !det.is_finite() || det.abs() < 1e-12 {
                return None;
            }
            let dx = (j[1][1] * rx - j[0][1] * ry) / det;
            let dy = (-j[1][0] * rx + j[0][0] * ry) / det;
            x -= dx;
            y -= dy;
            if !(x.is_finite() && y.is_finite()) {
                return None;
            }
        }
        let (fx, fy) = self.distort_normalized(x, y);
        if (fx - xd).abs() < 1e-10 && (fy - yd).abs() < 1e-10 {
            Some((x, y))
        } else {
            None
        }
    }

    /// Distort an ideal pixel of camera `k` into the distorted image.
    #[inline]
    pub fn distort_pixel(&self, k: &Intrinsics, u: f64, v: f64) -> (f64, f64) {
        let (x, y) = k.pixel_to_normalized(u, v);
        let (xd, yd) = self.distort_normalized(x, y);
        k.normalized_to_pixel(xd, yd)
    }

    /// Undistort a pixel of the distorted image of camera `k`.
    pub fn undistort_pixel(&self, k: &Intrinsics, u: f64, v: f64) -> Option<(f64, f64)> {
        let (xd, yd) = k.pixel_to_normalized(u, v);
        let (x, y) = self.undistort_normalized(xd, yd)?;
        Some(k.normalized_to_pixel(x, y))
    }

    /// Largest displacement (px) caused by distortion over a grid of image pixels
    /// (every `step` px plus the border), i.e. max |distort(p) − p|.
    pub fn max_displacement_px(&self, k: &Intrinsics, step: usize) -> f64 {
        let step = step.max(1);
        let mut xs: Vec<usize> = (0..k.width).step_by(step).collect();
        xs.push(k.width - 1);
        let mut ys: Vec<usize> = (0..k.height).step_by(step).collect();
        ys.push(k.height - 1);
        let mut m = 0.0f64;
        for &y in &ys {
            for &x in &xs {
                let (u, v) = self.distort_pixel(k, x as f64, y as f64);
                m = m.max(((u - x as f64).powi(2) + (v - y as f64).powi(2)).sqrt());
            }
        }
        m
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distort_hand_value() {
        // r² = 0.01+0.04 = 0.05, radial = 1 + 0.1*0.05 = 1.005
        let d = Distortion::brown_conrady(0.1, 0.0, 0.0, 0.0, 0.0);
        let (x, y) = d.distort_normalized(0.1, 0.2);
        assert!((x - 0.1005).abs() < 1e-15 && (y - 0.201).abs() < 1e-15);
    }

    #[test]
    fn undistort_round_trip_under_1e6_px() {
        // SCARED-like coefficients at 1280x1024.
        let k = Intrinsics::new(1035.0, 1035.0, 597.0, 520.0, 1280, 1024).unwrap();
        let d = Distortion::brown_conrady(-0.33, 0.16, 0.001, -0.0005, 0.05);
        let mut worst = 0.0f64;
        for y in (0..1024).step_by(16) {
            for x in (0..1280).step_by(16) {
                let (u, v) = d.distort_pixel(&k, x as f64, y as f64);
                let (a, b) = d.undistort_pixel(&k, u, v).unwrap();
                worst = worst.max(((a - x as f64).powi(2) + (b - y as f64).powi(2)).sqrt());
            }
        }
        assert!(worst < 1e-6, "worst round trip {worst} px");
    }

    #[test]
    fn analytic_jacobian_matches_finite_differences() {
        let d = Distortion::from_opencv(&[
            -0.3, 0.12, 0.002, -0.001, 0.05, 0.01, -0.02, 0.03, 0.001, -0.002, 0.003, 0.0005,
        ])
        .unwrap();
        for &(x, y) in &[(0.1, -0.2), (-0.4, 0.3), (0.0, 0.0), (0.5, 0.5)] {
            let j = d.jacobian(x, y);
            let h = 1e-6;
            let (a, b) = d.distort_normalized(x + h, y);
            let (c, e) = d.distort_normalized(x - h, y);
            let (f, g) = d.distort_normalized(x, y + h);
            let (k, l) = d.distort_normalized(x, y - h);
            let fd = [[(a - c) / (2.0 * h), (f - k) / (2.0 * h)], [(b - e) / (2.0 * h), (g - l) / (2.0 * h)]];
            for r in 0..2 {
                for c in 0..2 {
                    assert!((j[r][c] - fd[r][c]).abs() < 1e-7, "J[{r}][{c}] at ({x},{y}): {} vs {}", j[r][c], fd[r][c]);
                }
            }
        }
    }

    #[test]
    fn bad_focal_rejected() {
        assert!(Intrinsics::new(0.0, 1.0, 0.0, 0.0, 10, 10).is_err());
        assert!(Intrinsics::new(f64::NAN, 1.0, 0.0, 0.0, 10, 10).is_err());
        assert!(Distortion::from_opencv(&[0.1, 0.2, 0.0]).is_err());
    }

    #[test]
    fn backproject_project_round_trip() {
        let k = Intrinsics::new(500.0, 510.0, 320.0, 240.0, 640, 480).unwrap();
        let p = k.backproject(100.5, 33.25, 0.12);
        let (u, v) = k.project(&p).unwrap();
        assert!((u - 100.5).abs() < 1e-12 && (v - 33.25).abs() < 1e-12);
    }
}
