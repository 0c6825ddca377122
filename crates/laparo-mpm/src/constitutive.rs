//! Constitutive models behind one trait: the Kirchhoff stress τ = P Fᵀ used by the P2G transfer
//! (eq. 5.6: ∂ψ/∂F Fᵀ) and its vector–Jacobian product for the adjoint.
use crate::linalg::Matrix;

/// An elastic constitutive model ψ(F; μ, λ).
pub trait ConstitutiveModel<const D: usize>: Sync + Send {
    /// Strain energy density ψ(F) (energy per reference volume).
    fn energy_density(&self, f: &Matrix<D>, mu: f64, lambda: f64) -> f64;
    /// Kirchhoff stress τ = ∂ψ/∂F Fᵀ (the stress term of eq. 5.6). `None` when F is inverted (J ≤ 0).
    fn kirchhoff(&self, f: &Matrix<D>, mu: f64, lambda: f64) -> Option<Matrix<D>>;
    /// Reverse mode of [`Self::kirchhoff`]: given G = ∂L/∂τ return (∂L/∂F, ∂L/∂μ, ∂L/∂λ).
    fn kirchhoff_vjp(&self, f: &Matrix<D>, mu: f64, lambda: f64, g: &Matrix<D>) -> (Matrix<D>, f64, f64);
    /// τ(F) (zero when F is inverted), then `body(τ)` → (G = ∂L/∂τ, r), then the VJP of G: returns
    /// (∂L/∂F, ∂L/∂μ, ∂L/∂λ, r). Same values as [`Self::kirchhoff`] + [`Self::kirchhoff_vjp`]; a
    /// model may override it to share work (J, ln J) between the two.
    #[inline(always)]
    fn kirchhoff_then_vjp<R>(
        &self,
        f: &Matrix<D>,
        mu: f64,
        lambda: f64,
        body: impl FnOnce(&Matrix<D>) -> (Matrix<D>, R),
    ) -> (Matrix<D>, f64, f64, R)
    where
        Self: Sized,
    {
        let tau = self.kirchhoff(f, mu, lambda).unwrap_or_else(Matrix::<D>::zeros);
        let (g, r) = body(&tau);
        let (gf, gmu, gla) = self.kirchhoff_vjp(f, mu, lambda, &g);
        (gf, gmu, gla, r)
    }
}

/// Lamé parameters (μ, λ) from Young's modulus E and Poisson's ratio ν (eq. 5.4).
pub fn lame(youngs_modulus: f64, poisson_ratio: f64) -> (f64, f64) {
    let (e, nu) = (youngs_modulus, poisson_ratio);
    (e / (2.0 * (1.0 + nu)), e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)))
}

/// Chain rule of eq. 5.4: (∂L/∂E, ∂L/∂ν) from (∂L/∂μ, ∂L/∂λ).
pub fn lame_vjp(youngs_modulus: f64, poisson_ratio: f64, d_mu: f64, d_lambda: f64) -> (f64, f64) {
    let (e, nu) = (youngs_modulus, poisson_ratio);
    let dmu_de = 1.0 / (2.0 * (1.0 + nu));
    let dmu_dnu = -e / (2.0 * (1.0 + nu) * (1.0 + nu));
    let q = (1.0 + nu) * (1.0 - 2.0 * nu); // = 1 − ν − 2ν²
    let dla_de = nu / q;
    let dla_dnu = e * (q - nu * (-1.0 - 4.0 * nu)) / (q * q);
    (d_mu * dmu_de + d_lambda * dla_de, d_mu * dmu_dnu + d_lambda * dla_dnu)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixed_corotated::FixedCorotated;
    use crate::linalg::Matrix;
    use crate::neo_hookean::NeoHookean;

    fn check_vjp<const D: usize, M: ConstitutiveModel<D>>(m: &M, f: Matrix<D>) {
        let (mu, la) = (1.3, 4.7);
        let g = Matrix::<D>::from_fn(|i, j| ((i * 7 + j * 3) as f64 * 0.37).sin());
        let (gf, gmu, gla) = m.kirchhoff_vjp(&f, mu, la, &g);
        let h = 1e-6;
        let phi = |f: &Matrix<D>, mu: f64, la: f64| m.kirchhoff(f, mu, la).unwrap().component_mul(&g).sum();
        let dir = Matrix::<D>::from_fn(|i, j| ((i * 5 + j * 11) as f64 * 0.91).cos());
        let fd = (phi(&(f + dir * h), mu, la) - phi(&(f - dir * h), mu, la)) / (2.0 * h);
        let an = gf.component_mul(&dir).sum();
        assert!((fd - an).abs() < 1e-7 * (1.0 + an.abs()), "dF: fd {fd} vs {an}");
        let fd = (phi(&f, mu + h, la) - phi(&f, mu - h, la)) / (2.0 * h);
        assert!((fd - gmu).abs() < 1e-7 * (1.0 + gmu.abs()), "dmu: fd {fd} vs {gmu}");
        let fd = (phi(&f, mu, la + h) - phi(&f, mu, la - h)) / (2.0 * h);
        assert!((fd - gla).abs() < 1e-7 * (1.0 + gla.abs()), "dla: fd {fd} vs {gla}");
    }

    #[test]
    fn kirchhoff_vjp_matches_finite_differences() {
        let f3 = Matrix::<3>::new(1.4, 0.3, -0.1, 0.2, 0.8, 0.4, -0.3, 0.1, 1.2);
        let f2 = Matrix::<2>::new(1.5, 0.4, -0.2, 0.7);
        check_vjp(&NeoHookean, f3);
        check_vjp(&NeoHookean, f2);
        check_vjp(&FixedCorotated, f3);
        check_vjp(&FixedCorotated, f2);
    }

    #[test]
    fn kirchhoff_then_vjp_matches_separate_calls() {
        let f = Matrix::<3>::new(1.4, 0.3, -0.1, 0.2, 0.8, 0.4, -0.3, 0.1, 1.2);
        let f2 = Matrix::<2>::new(1.5, 0.4, -0.2, 0.7);
        let (mu, la) = (1.3, 4.7);
        fn check<const D: usize, M: ConstitutiveModel<D>>(m: &M, f: Matrix<D>, mu: f64, la: f64) {
            let g = |t: &Matrix<D>| t * t.transpose() * 0.3 + Matrix::<D>::identity();
            let tau = m.kirchhoff(&f, mu, la).unwrap();
            let (gf, gmu, gla) = m.kirchhoff_vjp(&f, mu, la, &g(&tau));
            let (gf2, gmu2, gla2, t2) = m.kirchhoff_then_vjp(&f, mu, la, |t| (g(t), *t));
            assert_eq!((gf, gmu, gla, tau), (gf2, gmu2, gla2, t2));
        }
        check(&NeoHookean, f, mu, la);
        check(&NeoHookean, f2, mu, la);
        check(&FixedCorotated, f, mu, la);
        check(&FixedCorotated, f2, mu, la);
    }

    #[test]
    fn kirchhoff_is_energy_derivative() {
        // τ = ∂ψ/∂F Fᵀ: check ∂ψ/∂F by finite differences against τ F⁻ᵀ.
        let f = Matrix::<3>::new(1.4, 0.3, -0.1, 0.2, 0.8, 0.4, -0.3, 0.1, 1.2);
        let (mu, la) = (1.3, 4.7);
        for m in [&NeoHookean as &dyn ConstitutiveModel<3>, &FixedCorotated] {
            let p = m.kirchhoff(&f, mu, la).unwrap() * f.transpose().try_inverse().unwrap();
            for i in 0..3 {
                for j in 0..3 {
                    let mut e = Matrix::<3>::zeros();
                    e[(i, j)] = 1e-6;
                    let fd = (m.energy_density(&(f + e), mu, la) - m.energy_density(&(f - e), mu, la)) / 2e-6;
                    assert!((fd - p[(i, j)]).abs() < 1e-7, "{i}{j}: {fd} vs {}", p[(i, j)]);
                }
            }
        }
    }

    #[test]
    fn lame_chain_rule() {
        let (e, nu) = (4.1, 0.45);
        let (dm, dl) = (0.7, -1.3);
        let (ge, gn) = lame_vjp(e, nu, dm, dl);
        let f = |e: f64, nu: f64| {
            let (m, l) = lame(e, nu);
            dm * m + dl * l
        };
        let h = 1e-6;
        assert!((ge - (f(e + h, nu) - f(e - h, nu)) / (2.0 * h)).abs() < 1e-6);
        assert!((gn - (f(e, nu + h) - f(e, nu - h)) / (2.0 * h)).abs() < 1e-4 * gn.abs());
    }
}
