//! Compressible Neo-Hookean material of eq. 5.3, ψ(F) = μ/2 (tr FᵀF − 3) − μ ln J + λ/2 (ln J)²,
//! with its first Piola–Kirchhoff stress and its tangent, shared by the FEM ground truth
//! ([`crate::solid`]) and the mesh-based baselines of `laparo-register`.
//!
//! Units: with lengths in mm and moduli in kPa, ψ is in kPa = mN/mm² (energy density, µJ/mm³ … ×1e-3:
//! 1 kPa·mm³ = 1 µJ), P is in kPa, and nodal forces ∫ P ∇N dV are in mN.
use crate::error::{FemError, Result};
use nalgebra::{Matrix3, SMatrix};

/// 9×9 tangent ∂P/∂F; row `3 i + j` is P_ij, column `3 k + l` is F_kl.
pub type Tangent = SMatrix<f64, 9, 9>;

/// Neo-Hookean parameters as Lamé constants (kPa).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NeoHookean {
    /// Shear modulus μ (kPa).
    pub mu_kpa: f64,
    /// First Lamé parameter λ (kPa).
    pub lambda_kpa: f64,
}

impl NeoHookean {
    /// From Young's modulus E (kPa) and Poisson's ratio ν: μ = E / (2(1+ν)), λ = E ν / ((1+ν)(1−2ν)).
    pub fn from_young_poisson(e_kpa: f64, nu: f64) -> Result<Self> {
        if !(e_kpa.is_finite() && e_kpa > 0.0) {
            return Err(FemError::param("E (kPa)", e_kpa, "must be finite and > 0"));
        }
        if !(nu.is_finite() && nu > -1.0 && nu < 0.5) {
            return Err(FemError::param("nu", nu, "must lie in (-1, 0.5)"));
        }
        Ok(Self { mu_kpa: e_kpa / (2.0 * (1.0 + nu)), lambda_kpa: e_kpa * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)) })
    }

    /// The thesis' liver (§5.4.2): E = 4.1 kPa, ν = 0.49.
    pub fn liver() -> Self {
        Self::from_young_poisson(4.1, 0.49).expect("valid constants")
    }

    /// Energy density ψ(F) (eq. 5.3), kPa; `None` when J = det F ≤ 0 (inverted element).
    pub fn energy_density(&self, f: &Matrix3<f64>) -> Option<f64> {
        let j = f.determinant();
        if !(j > 0.0 && j.is_finite()) {
            return None;
        }
        let lj = j.ln();
        Some(0.5 * self.mu_kpa * (f.norm_squared() - 3.0) - self.mu_kpa * lj + 0.5 * self.lambda_kpa * lj * lj)
    }

    /// First Piola–Kirchhoff stress P = μ (F − F⁻ᵀ) + λ ln J F⁻ᵀ (kPa); `None` when J ≤ 0.
    pub fn pk1(&self, f: &Matrix3<f64>) -> Option<Matrix3<f64>> {
        let j = f.determinant();
        if !(j > 0.0 && j.is_finite()) {
            return None;
        }
        let f_inv_t = f.try_inverse()?.transpose();
        Some(f * self.mu_kpa + f_inv_t * (self.lambda_kpa * j.ln() - self.mu_kpa))
    }

    /// Tangent ∂P/∂F: A_ijkl = μ δ_ik δ_jl + (μ − λ ln J) F⁻¹_jk F⁻¹_li + λ F⁻¹_ji F⁻¹_lk; `None` when J ≤ 0.
    pub fn tangent(&self, f: &Matrix3<f64>) -> Option<Tangent> {
        let j = f.determinant();
        if !(j > 0.0 && j.is_finite()) {
            return None;
        }
        let fi = f.try_inverse()?;
        let (mu, la) = (self.mu_kpa, self.lambda_kpa);
        let c1 = mu - la * j.ln();
        let mut a = Tangent::zeros();
        for i in 0..3 {
            for jj in 0..3 {
                for k in 0..3 {
                    for l in 0..3 {
                        let mut v = c1 * fi[(jj, k)] * fi[(l, i)] + la * fi[(jj, i)] * fi[(l, k)];
                        if i == k && jj == l {
                            v += mu;
                        }
                        a[(3 * i + jj, 3 * k + l)] = v;
                    }
                }
            }
        }
        Some(a)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample_f() -> Matrix3<f64> {
        Matrix3::new(1.1, 0.2, -0.05, 0.03, 0.93, 0.1, -0.07, 0.04, 1.05)
    }

    #[test]
    fn lame_constants_match_closed_form() {
        let m = NeoHookean::liver();
        assert!((m.mu_kpa - 4.1 / 2.98).abs() < 1e-12);
        assert!((m.lambda_kpa - 4.1 * 0.49 / (1.49 * 0.02)).abs() < 1e-9);
    }

    #[test]
    fn rest_state_is_stress_free() {
        let m = NeoHookean::liver();
        assert_eq!(m.energy_density(&Matrix3::identity()), Some(0.0));
        assert!(m.pk1(&Matrix3::identity()).unwrap().norm() < 1e-14);
    }

    #[test]
    fn pk1_is_the_derivative_of_psi() {
        let m = NeoHookean::from_young_poisson(4.1, 0.45).unwrap();
        let f = sample_f();
        let p = m.pk1(&f).unwrap();
        let h = 1e-6;
        for i in 0..3 {
            for j in 0..3 {
                let (mut fp, mut fm) = (f, f);
                fp[(i, j)] += h;
                fm[(i, j)] -= h;
                let fd = (m.energy_density(&fp).unwrap() - m.energy_density(&fm).unwrap()) / (2.0 * h);
                assert!((fd - p[(i, j)]).abs() < 1e-6 * (1.0 + p[(i, j)].abs()), "P[{i}{j}] {fd} vs {}", p[(i, j)]);
            }
        }
    }

    #[test]
    fn tangent_is_the_derivative_of_pk1() {
        let m = NeoHookean::from_young_poisson(4.1, 0.45).unwrap();
        let f = sample_f();
        let a = m.tangent(&f).unwrap();
        let h = 1e-6;
        for k in 0..3 {
            for l in 0..3 {
                let (mut fp, mut fm) = (f, f);
                fp[(k, l)] += h;
                fm[(k, l)] -= h;
                let d = (m.pk1(&fp).unwrap() - m.pk1(&fm).unwrap()) / (2.0 * h);
                for i in 0..3 {
                    for j in 0..3 {
                        let an = a[(3 * i + j, 3 * k + l)];
                        assert!(
                            (d[(i, j)] - an).abs() < 1e-5 * (1.0 + an.abs()),
                            "A[{i}{j}{k}{l}] {} vs {an}",
                            d[(i, j)]
                        );
                    }
                }
            }
        }
        assert!((a - a.transpose()).norm() < 1e-10, "the tangent of a hyperelastic law is symmetric");
    }

    #[test]
    fn inverted_is_rejected_and_bad_constants_named() {
        let m = NeoHookean::liver();
        let mut f = Matrix3::identity();
        f[(2, 2)] = -1.0;
        assert!(m.energy_density(&f).is_none() && m.pk1(&f).is_none() && m.tangent(&f).is_none());
        let e = NeoHookean::from_young_poisson(4.1, 0.5).unwrap_err().to_string();
        assert!(e.contains("nu"), "{e}");
    }
}
