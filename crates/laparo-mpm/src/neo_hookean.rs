//! Compressible Neo-Hookean model (eq. 5.3): ψ = μ/2 (tr FᵀF − D) − μ ln J + λ/2 (ln J)².
use crate::constitutive::ConstitutiveModel;
use crate::linalg::{cofactor, det, Matrix};

/// Neo-Hookean elasticity, τ = μ (F Fᵀ − I) + λ ln J I (as in Diff_taichi's MLS-MPM).
#[derive(Clone, Copy, Debug, Default)]
pub struct NeoHookean;

impl<const D: usize> ConstitutiveModel<D> for NeoHookean {
    fn energy_density(&self, f: &Matrix<D>, mu: f64, lambda: f64) -> f64 {
        let j = det(f);
        let lj = j.ln();
        0.5 * mu * (f.norm_squared() - D as f64) - mu * lj + 0.5 * lambda * lj * lj
    }

    #[inline(always)]
    fn kirchhoff(&self, f: &Matrix<D>, mu: f64, lambda: f64) -> Option<Matrix<D>> {
        let j = det(f);
        if j <= 0.0 || !j.is_finite() {
            return None;
        }
        let mut tau = (f * f.transpose() - Matrix::<D>::identity()) * mu;
        let l = lambda * j.ln();
        for d in 0..D {
            tau[(d, d)] += l;
        }
        Some(tau)
    }

    #[inline(always)]
    fn kirchhoff_vjp(&self, f: &Matrix<D>, mu: f64, lambda: f64, g: &Matrix<D>) -> (Matrix<D>, f64, f64) {
        let j = det(f);
        let tr = g.trace();
        let ff_t = f * f.transpose();
        let gf = (g + g.transpose()) * f * mu + cofactor(f) * (lambda * tr / j);
        let gmu = g.component_mul(&ff_t).sum() - tr;
        let gla = j.ln() * tr;
        (gf, gmu, gla)
    }

    #[inline(always)]
    fn kirchhoff_then_vjp<R>(
        &self,
        f: &Matrix<D>,
        mu: f64,
        lambda: f64,
        body: impl FnOnce(&Matrix<D>) -> (Matrix<D>, R),
    ) -> (Matrix<D>, f64, f64, R) {
        // The expressions of `kirchhoff` and `kirchhoff_vjp` with J, ln J and F Fᵀ computed once.
        let j = det(f);
        let lj = j.ln();
        let ff_t = f * f.transpose();
        let tau = if j <= 0.0 || !j.is_finite() {
            Matrix::<D>::zeros()
        } else {
            let mut tau = (ff_t - Matrix::<D>::identity()) * mu;
            let l = lambda * lj;
            for d in 0..D {
                tau[(d, d)] += l;
            }
            tau
        };
        let (g, r) = body(&tau);
        let tr = g.trace();
        let gf = (g + g.transpose()) * f * mu + cofactor(f) * (lambda * tr / j);
        let gmu = g.component_mul(&ff_t).sum() - tr;
        let gla = lj * tr;
        (gf, gmu, gla, r)
    }
}
