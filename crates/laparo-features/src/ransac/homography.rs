//! Homography x₂ ~ H x₁: normalised 4-point DLT (Hartley & Zisserman alg. 4.2) in RANSAC,
//! refined by normalised DLT on the inliers; residual = forward transfer error ‖x₂ − H x₁‖, px.
use super::linalg::{accumulate, apply, mat3, normalisation, null_vector9, symmetrise};
use super::{check_points, run, Estimator, RansacParams, RobustFit};
use crate::error::{FeaturesError, Result};
use nalgebra::{Matrix3, SMatrix};

/// Squared forward transfer error ‖x₂ − H x₁‖², px² (∞ when x₁ maps to infinity).
#[inline]
pub fn transfer_error_sq(h: &Matrix3<f64>, p1: [f64; 2], p2: [f64; 2]) -> f64 {
    let w = h[(2, 0)] * p1[0] + h[(2, 1)] * p1[1] + h[(2, 2)];
    if w.abs() < 1e-15 {
        return f64::INFINITY;
    }
    let x = (h[(0, 0)] * p1[0] + h[(0, 1)] * p1[1] + h[(0, 2)]) / w;
    let y = (h[(1, 0)] * p1[0] + h[(1, 1)] * p1[1] + h[(1, 2)]) / w;
    (x - p2[0]).powi(2) + (y - p2[1]).powi(2)
}

/// Twice the signed area of a triangle.
#[inline]
fn cross(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
}

/// Normalised DLT on the correspondences `idx` (≥ 4), H scaled to ‖H‖_F = 1, h₃₃ ≥ 0.
pub(crate) fn dlt(p1: &[[f64; 2]], p2: &[[f64; 2]], idx: &[usize]) -> Option<Matrix3<f64>> {
    let t1 = normalisation(p1, idx)?;
    let t2 = normalisation(p2, idx)?;
    let mut ata = SMatrix::<f64, 9, 9>::zeros();
    for &i in idx {
        let [x, y] = apply(&t1, p1[i]);
        let [u, v] = apply(&t2, p2[i]);
        accumulate(&mut ata, &[-x, -y, -1.0, 0.0, 0.0, 0.0, u * x, u * y, u], 1.0);
        accumulate(&mut ata, &[0.0, 0.0, 0.0, -x, -y, -1.0, v * x, v * y, v], 1.0);
    }
    symmetrise(&mut ata);
    let (h, l0, l1) = null_vector9(ata);
    if idx.len() > 4 && !(l1 > 1e-14 * ata.trace()) {
        return None; // rank-deficient (all points collinear)
    }
    let _ = l0;
    let hn = mat3(&h);
    let h = t2.try_inverse()? * hn * t1;
    let n = h.norm();
    if !(n > 0.0 && n.is_finite()) {
        return None;
    }
    let h = h / n;
    Some(if h[(2, 2)] < 0.0 { -h } else { h })
}

struct HEst<'a> {
    p1: &'a [[f64; 2]],
    p2: &'a [[f64; 2]],
}

impl Estimator for HEst<'_> {
    type Model = Matrix3<f64>;
    const SAMPLE: usize = 4;
    const NAME: &'static str = "homography";
    fn minimal(&self, idx: &[usize]) -> Vec<Matrix3<f64>> {
        // reject samples with three collinear points in either image, or inconsistent
        // orientation (a homography of a visible plane preserves the triangles' orientation)
        let tri = [[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]];
        for p in [self.p1, self.p2] {
            let scale = idx.iter().map(|&i| p[i][0].abs() + p[i][1].abs()).fold(1.0, f64::max);
            for t in tri {
                if cross(p[idx[t[0]]], p[idx[t[1]]], p[idx[t[2]]]).abs() < 1e-9 * scale * scale {
                    return vec![];
                }
            }
        }
        for t in tri {
            let a = cross(self.p1[idx[t[0]]], self.p1[idx[t[1]]], self.p1[idx[t[2]]]);
            let b = cross(self.p2[idx[t[0]]], self.p2[idx[t[1]]], self.p2[idx[t[2]]]);
            if a * b < 0.0 {
                return vec![];
            }
        }
        dlt(self.p1, self.p2, idx).into_iter().collect()
    }
    fn residual_sq(&self, m: &Matrix3<f64>, i: usize) -> f64 {
        transfer_error_sq(m, self.p1[i], self.p2[i])
    }
    fn refit(&self, idx: &[usize]) -> Option<Matrix3<f64>> {
        dlt(self.p1, self.p2, idx)
    }
    fn len(&self) -> usize {
        self.p1.len()
    }
}

/// Robust homography x₂ ~ H x₁ (H maps image-1 px to image-2 px), normalised so ‖H‖_F = 1.
/// Errors: fewer than 4 correspondences, non-finite coordinates, length mismatch, or a
/// degenerate configuration (e.g. all points collinear).
pub fn find_homography(p1: &[[f64; 2]], p2: &[[f64; 2]], prm: &RansacParams) -> Result<RobustFit<Matrix3<f64>>> {
    check_points(p1, p2, 4, "homography")?;
    let fit = run(&HEst { p1, p2 }, prm)?;
    if fit.model.iter().any(|v| !v.is_finite()) || fit.model.determinant().abs() < 1e-30 {
        return Err(FeaturesError::Estimation("homography: degenerate (singular) result".into()));
    }
    Ok(fit)
}
