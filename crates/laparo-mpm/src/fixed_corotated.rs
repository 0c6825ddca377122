//! Fixed-corotated model (Stomakhin et al. 2012): ψ = μ ‖F − R‖² + λ/2 (J − 1)², F = R S polar.
use crate::constitutive::ConstitutiveModel;
use crate::linalg::{cofactor, det, hat, polar, vee_antisym, Matrix};

/// Fixed-corotated elasticity, τ = 2μ (F − R) Fᵀ + λ (J − 1) J I.
#[derive(Clone, Copy, Debug, Default)]
pub struct FixedCorotated;

impl<const D: usize> ConstitutiveModel<D> for FixedCorotated {
    fn energy_density(&self, f: &Matrix<D>, mu: f64, lambda: f64) -> f64 {
        let j = det(f);
        let r = polar(f).map(|(r, _)| r).unwrap_or_else(Matrix::<D>::identity);
        mu * (f - r).norm_squared() + 0.5 * lambda * (j - 1.0) * (j - 1.0)
    }

    fn kirchhoff(&self, f: &Matrix<D>, mu: f64, lambda: f64) -> Option<Matrix<D>> {
        let j = det(f);
        if j <= 0.0 || !j.is_finite() {
            return None;
        }
        let (r, _) = polar(f)?;
        let mut tau = (f - r) * f.transpose() * (2.0 * mu);
        for d in 0..D {
            tau[(d, d)] += lambda * (j - 1.0) * j;
        }
        Some(tau)
    }

    fn kirchhoff_vjp(&self, f: &Matrix<D>, mu: f64, lambda: f64, g: &Matrix<D>) -> (Matrix<D>, f64, f64) {
        let j = det(f);
        let (r, s) = polar(f).unwrap_or((Matrix::<D>::identity(), *f));
        let tr = g.trace();
        let fmr = f - r;
        let mut gf = (g * f + g.transpose() * fmr) * (2.0 * mu) + cofactor(f) * (lambda * (2.0 * j - 1.0) * tr);
        // Differential of the polar rotation: Rᵀ dR = hat(ω), (tr S · I − S) ω = axial(Rᵀ dF − dFᵀ R) / 2.
        let m = g * f * (2.0 * mu);
        let a = vee_antisym(&(r.transpose() * m));
        let b = match D {
            2 => [a[0] / s.trace(), 0.0, 0.0],
            _ => {
                let mut am = Matrix::<3>::zeros();
                let ts = s.trace();
                for i in 0..3 {
                    for k in 0..3 {
                        am[(i, k)] = if i == k { ts } else { 0.0 } - s[(i, k)];
                    }
                }
                let inv = cofactor(&am).transpose() / det(&am);
                let bv = inv * nalgebra::Vector3::new(a[0], a[1], a[2]);
                [bv[0], bv[1], bv[2]]
            }
        };
        gf -= r * hat::<D>(&b);
        let gmu = 2.0 * g.component_mul(&(fmr * f.transpose())).sum();
        let gla = (j - 1.0) * j * tr;
        (gf, gmu, gla)
    }
}
