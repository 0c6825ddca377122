//! Small fixed-size linear algebra for D = 2 or 3, written against `const D: usize` without the
//! nalgebra trait bounds that generic determinants/inverses would require.
use nalgebra::{SMatrix, SVector};

/// A D-vector of f64.
pub type Vector<const D: usize> = SVector<f64, D>;
/// A D×D matrix of f64.
pub type Matrix<const D: usize> = SMatrix<f64, D, D>;

/// Number of grid nodes a quadratic B-spline touches: 3^D.
#[cfg(test)]
pub const fn stencil_len(d: usize) -> usize {
    let mut n = 1;
    let mut i = 0;
    while i < d {
        n *= 3;
        i += 1;
    }
    n
}

/// Whether every entry is finite (x − x is 0 for finite x and NaN otherwise; one branch instead of
/// one per entry).
#[inline(always)]
#[allow(clippy::eq_op)]
pub fn all_finite(v: &[f64]) -> bool {
    let mut s = 0.0;
    for &x in v {
        s += x - x;
    }
    s == 0.0
}

/// Determinant J = det F (D = 2 or 3).
#[inline(always)]
pub fn det<const D: usize>(m: &Matrix<D>) -> f64 {
    match D {
        1 => m[(0, 0)],
        2 => m[(0, 0)] * m[(1, 1)] - m[(0, 1)] * m[(1, 0)],
        3 => {
            m[(0, 0)] * (m[(1, 1)] * m[(2, 2)] - m[(1, 2)] * m[(2, 1)])
                - m[(0, 1)] * (m[(1, 0)] * m[(2, 2)] - m[(1, 2)] * m[(2, 0)])
                + m[(0, 2)] * (m[(1, 0)] * m[(2, 1)] - m[(1, 1)] * m[(2, 0)])
        }
        _ => unreachable!("laparo-mpm supports D = 2 and 3"),
    }
}

/// Cofactor matrix cof(F) = det(F) F^{-T} = ∂J/∂F.
#[inline(always)]
pub fn cofactor<const D: usize>(m: &Matrix<D>) -> Matrix<D> {
    let mut c = Matrix::<D>::zeros();
    match D {
        1 => c[(0, 0)] = 1.0,
        2 => {
            c[(0, 0)] = m[(1, 1)];
            c[(0, 1)] = -m[(1, 0)];
            c[(1, 0)] = -m[(0, 1)];
            c[(1, 1)] = m[(0, 0)];
        }
        3 => {
            for i in 0..3 {
                for j in 0..3 {
                    let (i1, i2) = ((i + 1) % 3, (i + 2) % 3);
                    let (j1, j2) = ((j + 1) % 3, (j + 2) % 3);
                    c[(i, j)] = m[(i1, j1)] * m[(i2, j2)] - m[(i1, j2)] * m[(i2, j1)];
                }
            }
        }
        _ => unreachable!("laparo-mpm supports D = 2 and 3"),
    }
    c
}

/// Inverse transpose F^{-T} (None when singular).
#[inline(always)]
pub fn inverse_transpose<const D: usize>(m: &Matrix<D>) -> Option<Matrix<D>> {
    let j = det(m);
    if j == 0.0 || !j.is_finite() {
        return None;
    }
    Some(cofactor(m) / j)
}

/// Skew-symmetric matrix from its axial part: D = 2 → [[0,-w],[w,0]] (w = a[0]); D = 3 → hat(a).
#[inline(always)]
pub fn hat<const D: usize>(a: &[f64; 3]) -> Matrix<D> {
    let mut h = Matrix::<D>::zeros();
    match D {
        2 => {
            h[(0, 1)] = -a[0];
            h[(1, 0)] = a[0];
        }
        3 => {
            h[(0, 1)] = -a[2];
            h[(1, 0)] = a[2];
            h[(0, 2)] = a[1];
            h[(2, 0)] = -a[1];
            h[(1, 2)] = -a[0];
            h[(2, 1)] = a[0];
        }
        _ => unreachable!("laparo-mpm supports D = 2 and 3"),
    }
    h
}

/// Axial part of M − Mᵀ (the inverse of [`hat`] applied to M − Mᵀ).
#[inline(always)]
pub fn vee_antisym<const D: usize>(m: &Matrix<D>) -> [f64; 3] {
    match D {
        2 => [m[(1, 0)] - m[(0, 1)], 0.0, 0.0],
        3 => [m[(2, 1)] - m[(1, 2)], m[(0, 2)] - m[(2, 0)], m[(1, 0)] - m[(0, 1)]],
        _ => unreachable!("laparo-mpm supports D = 2 and 3"),
    }
}

/// Polar decomposition F = R S (R rotation, S symmetric positive definite) for det F > 0, by the
/// scaled Newton iteration R ← (ζR + ζ⁻¹R⁻ᵀ)/2 (Higham 1986), iterated to round-off.
pub fn polar<const D: usize>(f: &Matrix<D>) -> Option<(Matrix<D>, Matrix<D>)> {
    let mut r = *f;
    for it in 0..100 {
        let it_inv = inverse_transpose(&r)?;
        // Frobenius-norm scaling for fast early convergence; unscaled near convergence.
        let zeta = if it < 6 { ((it_inv.norm()) / r.norm()).sqrt() } else { 1.0 };
        let next = (r * zeta + it_inv / zeta) * 0.5;
        let diff = (next - r).norm();
        r = next;
        if diff <= 1e-15 * r.norm() {
            break;
        }
    }
    let s = r.transpose() * f;
    let s = (s + s.transpose()) * 0.5;
    Some((r, s))
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn det_cofactor_inverse_3d() {
        let m = Matrix::<3>::new(2.0, 0.3, -0.1, 0.2, 1.5, 0.4, -0.3, 0.1, 0.9);
        let d = det(&m);
        let n = m.try_inverse().unwrap();
        assert!((d - m.determinant()).abs() < 1e-12);
        assert!((inverse_transpose(&m).unwrap() - n.transpose()).norm() < 1e-12);
        let (r, s) = polar(&m).unwrap();
        assert!((r * s - m).norm() < 1e-12);
        assert!((r.transpose() * r - Matrix::<3>::identity()).norm() < 1e-12);
        assert!((det(&r) - 1.0).abs() < 1e-12);
        let a = [0.3, -0.7, 1.1];
        let h = hat::<3>(&a);
        let v = vee_antisym(&h);
        for k in 0..3 {
            assert!((v[k] - 2.0 * a[k]).abs() < 1e-15);
        }
    }
}
