//! Essential matrix x̂₂ᵀ E x̂₁ = 0 on normalised camera coordinates (x̂ = K⁻¹ x).
//!
//! Solver: NOT Nistér's 5-point. The minimal sample is 8 correspondences, solved by the linear
//! 8-point algorithm (Hartley-normalised) and projected onto the essential manifold (singular
//! values (1, 1, 0), H&Z result 9.18); local optimisation = Sampson-reweighted 8-point on the
//! inliers, projected again. Well-posed for ≥ 8 points in general position, but it needs
//! (1−w⁸) instead of (1−w⁵) per hypothesis, i.e. more iterations at high outlier rates
//! (50 % outliers, 99.9 %: ≈ 1,765 vs 218 hypotheses).
//! Residual: Sampson distance in normalised units (threshold = px threshold / focal length).
use super::fundamental::{eight_point, sampson_distance_sq, sampson_reweighted};
use super::{check_points, run, Estimator, RansacParams, RobustFit};
use crate::error::{FeaturesError, Result};
use nalgebra::Matrix3;

/// Project onto the essential manifold: singular values (1, 1, 0) (H&Z result 9.18).
pub fn project_to_essential(e: &Matrix3<f64>) -> Option<Matrix3<f64>> {
    let mut svd = e.svd(true, true);
    let mut order = [0usize, 1, 2];
    order.sort_by(|&a, &b| svd.singular_values[b].total_cmp(&svd.singular_values[a]));
    svd.singular_values[order[0]] = 1.0;
    svd.singular_values[order[1]] = 1.0;
    svd.singular_values[order[2]] = 0.0;
    let g = svd.recompose().ok()?;
    let g = g / g.norm() * std::f64::consts::SQRT_2;
    g.iter().all(|v| v.is_finite()).then_some(g)
}

struct EEst<'a> {
    p1: &'a [[f64; 2]],
    p2: &'a [[f64; 2]],
}

impl Estimator for EEst<'_> {
    type Model = Matrix3<f64>;
    const SAMPLE: usize = 8;
    const NAME: &'static str = "essential matrix";
    fn minimal(&self, idx: &[usize]) -> Vec<Matrix3<f64>> {
        eight_point(self.p1, self.p2, idx, None).and_then(|e| project_to_essential(&e)).into_iter().collect()
    }
    fn residual_sq(&self, m: &Matrix3<f64>, i: usize) -> f64 {
        sampson_distance_sq(m, self.p1[i], self.p2[i])
    }
    fn refit(&self, idx: &[usize]) -> Option<Matrix3<f64>> {
        sampson_reweighted(self.p1, self.p2, idx).and_then(|e| project_to_essential(&e))
    }
    fn len(&self) -> usize {
        self.p1.len()
    }
}

/// Robust essential matrix from normalised camera coordinates (x̂ = K⁻¹ x; pass
/// `threshold_px / f` as the threshold). E has singular values (1, 1, 0).
/// Errors: fewer than 8 correspondences, non-finite coordinates, length mismatch, degenerate set.
pub fn find_essential(p1n: &[[f64; 2]], p2n: &[[f64; 2]], prm: &RansacParams) -> Result<RobustFit<Matrix3<f64>>> {
    check_points(p1n, p2n, 8, "essential matrix")?;
    let fit = run(&EEst { p1: p1n, p2: p2n }, prm)?;
    if fit.n_inliers < 8 {
        return Err(FeaturesError::Estimation(format!(
            "essential matrix: only {} inliers (need at least 8)",
            fit.n_inliers
        )));
    }
    Ok(fit)
}
