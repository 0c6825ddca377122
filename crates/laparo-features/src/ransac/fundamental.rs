//! Fundamental matrix x₂ᵀ F x₁ = 0: 7-point minimal solver (Hartley & Zisserman §11.1.2, up to
//! three solutions from det(αF₁ + (1−α)F₂) = 0) in RANSAC, refined by the normalised 8-point
//! algorithm (H&Z alg. 11.1) with Sampson reweighting, rank 2 enforced by SVD.
//! Residual: Sampson distance (first-order geometric error, H&Z eq. 11.9), px.
use super::linalg::{accumulate, apply, cubic_roots, mat3, normalisation, null_space_7x9, null_vector9, symmetrise};
use super::{check_points, run, Estimator, RansacParams, RobustFit};
use crate::error::{FeaturesError, Result};
use nalgebra::{Matrix3, SMatrix, Vector3};

/// Squared Sampson distance of (x₁, x₂) to F, px² (H&Z eq. 11.9).
#[inline]
pub fn sampson_distance_sq(f: &Matrix3<f64>, p1: [f64; 2], p2: [f64; 2]) -> f64 {
    let x1 = Vector3::new(p1[0], p1[1], 1.0);
    let x2 = Vector3::new(p2[0], p2[1], 1.0);
    let fx1 = f * x1;
    let ftx2 = f.transpose() * x2;
    let e = x2.dot(&fx1);
    let d = fx1[0] * fx1[0] + fx1[1] * fx1[1] + ftx2[0] * ftx2[0] + ftx2[1] * ftx2[1];
    if d <= 0.0 {
        return if e == 0.0 { 0.0 } else { f64::INFINITY };
    }
    e * e / d
}

/// Mean of the two point-to-epipolar-line distances, px: ½ (d(x₂, F x₁) + d(x₁, Fᵀ x₂)).
pub fn symmetric_epipolar_distance(f: &Matrix3<f64>, p1: [f64; 2], p2: [f64; 2]) -> f64 {
    let x1 = Vector3::new(p1[0], p1[1], 1.0);
    let x2 = Vector3::new(p2[0], p2[1], 1.0);
    let l2 = f * x1;
    let l1 = f.transpose() * x2;
    let e = x2.dot(&l2).abs();
    0.5 * (e / l2.fixed_rows::<2>(0).norm() + e / l1.fixed_rows::<2>(0).norm())
}

/// Enforce rank 2 (zero the smallest singular value) and scale to ‖F‖_F = 1.
pub(crate) fn rank2(f: &Matrix3<f64>) -> Option<Matrix3<f64>> {
    let mut svd = f.svd(true, true);
    let (mut imin, mut vmin) = (0, f64::INFINITY);
    for k in 0..3 {
        if svd.singular_values[k] < vmin {
            vmin = svd.singular_values[k];
            imin = k;
        }
    }
    svd.singular_values[imin] = 0.0;
    let g = svd.recompose().ok()?;
    let n = g.norm();
    (n > 0.0 && n.is_finite()).then(|| g / n)
}

fn epipolar_row(a: [f64; 2], b: [f64; 2]) -> [f64; 9] {
    let [x, y] = a;
    let [u, v] = b;
    [u * x, u * y, u, v * x, v * y, v, x, y, 1.0]
}

/// Normalised 8-point on `idx` (≥ 8) with optional per-correspondence weights.
pub(crate) fn eight_point(p1: &[[f64; 2]], p2: &[[f64; 2]], idx: &[usize], w: Option<&[f64]>) -> Option<Matrix3<f64>> {
    let t1 = normalisation(p1, idx)?;
    let t2 = normalisation(p2, idx)?;
    let mut ata = SMatrix::<f64, 9, 9>::zeros();
    for (k, &i) in idx.iter().enumerate() {
        let r = epipolar_row(apply(&t1, p1[i]), apply(&t2, p2[i]));
        accumulate(&mut ata, &r, w.map_or(1.0, |w| w[k]));
    }
    symmetrise(&mut ata);
    let (f, _, l1) = null_vector9(ata);
    if !(l1 > 1e-14 * ata.trace()) {
        return None; // two-dimensional null space: degenerate configuration
    }
    let fnorm = rank2(&mat3(&f))?;
    rank2(&(t2.transpose() * fnorm * t1))
}

/// 7-point solver: up to three rank-2 F.
pub(crate) fn seven_point(p1: &[[f64; 2]], p2: &[[f64; 2]], idx: &[usize]) -> Vec<Matrix3<f64>> {
    let (Some(t1), Some(t2)) = (normalisation(p1, idx), normalisation(p2, idx)) else { return vec![] };
    let mut rows = [[0.0; 9]; 7];
    for (k, &i) in idx.iter().enumerate() {
        rows[k] = epipolar_row(apply(&t1, p1[i]), apply(&t2, p2[i]));
    }
    let Some((a, b)) = null_space_7x9(&rows) else { return vec![] };
    let (f1, f2) = (mat3(&a), mat3(&b));
    // det(α F1 + (1−α) F2) is a cubic in α: recover its coefficients from 4 samples
    let g = |al: f64| (f1 * al + f2 * (1.0 - al)).determinant();
    let (g0, g1, gm, g2) = (g(0.0), g(1.0), g(-1.0), g(2.0));
    // c3 α³ + c2 α² + c1 α + c0
    let c0 = g0;
    let c2 = 0.5 * (g1 + gm) - g0;
    let c3 = (g2 - 2.0 * g1 + g0 - 2.0 * c2) / 6.0;
    let c1 = g1 - c0 - c2 - c3;
    let mut out = vec![];
    for al in cubic_roots(c3, c2, c1, c0) {
        let fnorm = f1 * al + f2 * (1.0 - al);
        if let Some(f) = rank2(&(t2.transpose() * fnorm * t1)) {
            out.push(f);
        }
    }
    out
}

struct FEst<'a> {
    p1: &'a [[f64; 2]],
    p2: &'a [[f64; 2]],
}

impl Estimator for FEst<'_> {
    type Model = Matrix3<f64>;
    const SAMPLE: usize = 7;
    const NAME: &'static str = "fundamental matrix";
    fn minimal(&self, idx: &[usize]) -> Vec<Matrix3<f64>> {
        seven_point(self.p1, self.p2, idx)
    }
    fn residual_sq(&self, m: &Matrix3<f64>, i: usize) -> f64 {
        sampson_distance_sq(m, self.p1[i], self.p2[i])
    }
    fn refit(&self, idx: &[usize]) -> Option<Matrix3<f64>> {
        if idx.len() < 8 {
            return None;
        }
        sampson_reweighted(self.p1, self.p2, idx)
    }
    fn len(&self) -> usize {
        self.p1.len()
    }
}

/// 8-point followed by a few Sampson-reweighted 8-point passes (weight 1/‖∇‖², an IRLS
/// approximation of minimising the Sampson error).
pub(crate) fn sampson_reweighted(p1: &[[f64; 2]], p2: &[[f64; 2]], idx: &[usize]) -> Option<Matrix3<f64>> {
    let mut f = eight_point(p1, p2, idx, None)?;
    let mut w = vec![0.0; idx.len()];
    for _ in 0..3 {
        for (k, &i) in idx.iter().enumerate() {
            let x1 = Vector3::new(p1[i][0], p1[i][1], 1.0);
            let x2 = Vector3::new(p2[i][0], p2[i][1], 1.0);
            let a = f * x1;
            let b = f.transpose() * x2;
            let d = a[0] * a[0] + a[1] * a[1] + b[0] * b[0] + b[1] * b[1];
            w[k] = if d > 0.0 { 1.0 / d } else { 0.0 };
        }
        // weights are in pixel units; rescale to a mean of 1 for conditioning
        let m = w.iter().sum::<f64>() / w.len() as f64;
        if !(m > 0.0 && m.is_finite()) {
            break;
        }
        w.iter_mut().for_each(|v| *v /= m);
        match eight_point(p1, p2, idx, Some(&w)) {
            Some(g) => f = g,
            None => break,
        }
    }
    Some(f)
}

/// Robust fundamental matrix with x₂ᵀ F x₁ = 0 (px), rank 2, ‖F‖_F = 1.
/// Errors: fewer than 8 correspondences, non-finite coordinates, length mismatch, or a
/// degenerate configuration.
pub fn find_fundamental(p1: &[[f64; 2]], p2: &[[f64; 2]], prm: &RansacParams) -> Result<RobustFit<Matrix3<f64>>> {
    check_points(p1, p2, 8, "fundamental matrix")?;
    let fit = run(&FEst { p1, p2 }, prm)?;
    if fit.n_inliers < 8 {
        return Err(FeaturesError::Estimation(format!(
            "fundamental matrix: only {} inliers (need at least 8)",
            fit.n_inliers
        )));
    }
    Ok(fit)
}
