//! Plane-to-plane homographies acting on pixel coordinates (x, y, 1).
use crate::error::{CoreError, Result};
use nalgebra::{DMatrix, Matrix3, Vector3};

/// A 3×3 homography `p' ~ H p` on homogeneous pixel coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Homography(pub Matrix3<f64>);

impl Homography {
    /// The identity.
    pub fn identity() -> Self {
        Homography(Matrix3::identity())
    }

    /// Map a point; `None` when it maps to infinity (w ≈ 0) or behind (w < 0 is allowed; caller decides).
    #[inline]
    pub fn apply(&self, x: f64, y: f64) -> Option<(f64, f64)> {
        let p = self.0 * Vector3::new(x, y, 1.0);
        if p.z.abs() < 1e-300 {
            return None;
        }
        Some((p.x / p.z, p.y / p.z))
    }

    /// The inverse homography.
    pub fn inverse(&self) -> Result<Self> {
        self.0.try_inverse().map(Homography).ok_or_else(|| CoreError::invalid("homography", "singular matrix"))
    }

    /// `self ∘ other` (apply `other` first).
    pub fn compose(&self, other: &Homography) -> Homography {
        Homography(self.0 * other.0)
    }

    /// Scale so that H[2,2] = 1 when possible.
    pub fn normalized(&self) -> Homography {
        let s = self.0[(2, 2)];
        if s.abs() > 1e-300 {
            Homography(self.0 / s)
        } else {
            *self
        }
    }

    /// Direct linear transform from ≥ 4 correspondences `src[i] -> dst[i]`
    /// (Hartley-normalised, solved by SVD).
    pub fn from_points(src: &[(f64, f64)], dst: &[(f64, f64)]) -> Result<Self> {
        if src.len() != dst.len() || src.len() < 4 {
            return Err(CoreError::invalid(
                "correspondences",
                format!("need >= 4 pairs, got {} and {}", src.len(), dst.len()),
            ));
        }
        let (ts, ns) = normalisation(src);
        let (td, nd) = normalisation(dst);
        let n = src.len();
        let mut a = DMatrix::<f64>::zeros(2 * n, 9);
        for i in 0..n {
            let (x, y) = ns[i];
            let (u, v) = nd[i];
            let r0 = [-x, -y, -1.0, 0.0, 0.0, 0.0, u * x, u * y, u];
            let r1 = [0.0, 0.0, 0.0, -x, -y, -1.0, v * x, v * y, v];
            for j in 0..9 {
                a[(2 * i, j)] = r0[j];
                a[(2 * i + 1, j)] = r1[j];
            }
        }
        let ata = a.transpose() * &a;
        let eig = ata.symmetric_eigen();
        let (imin, _) =
            eig.eigenvalues
                .iter()
                .enumerate()
                .fold((0, f64::INFINITY), |acc, (i, &v)| if v < acc.1 { (i, v) } else { acc });
        let h = eig.eigenvectors.column(imin);
        let hn = Matrix3::new(h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7], h[8]);
        let td_inv = td.try_inverse().ok_or_else(|| CoreError::invalid("correspondences", "degenerate"))?;
        Ok(Homography(td_inv * hn * ts).normalized())
    }
}

fn normalisation(p: &[(f64, f64)]) -> (Matrix3<f64>, Vec<(f64, f64)>) {
    let n = p.len() as f64;
    let (mx, my) = p.iter().fold((0.0, 0.0), |a, q| (a.0 + q.0 / n, a.1 + q.1 / n));
    let md = p.iter().map(|q| ((q.0 - mx).powi(2) + (q.1 - my).powi(2)).sqrt()).sum::<f64>() / n;
    let s = if md > 0.0 { std::f64::consts::SQRT_2 / md } else { 1.0 };
    let t = Matrix3::new(s, 0.0, -s * mx, 0.0, s, -s * my, 0.0, 0.0, 1.0);
    (t, p.iter().map(|q| (s * (q.0 - mx), s * (q.1 - my))).collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn dlt_recovers_homography() {
        let h = Homography(Matrix3::new(1.1, 0.05, 3.0, -0.02, 0.95, -4.0, 1e-4, -2e-4, 1.0));
        let src: Vec<_> = [(0.0, 0.0), (100.0, 0.0), (0.0, 80.0), (100.0, 80.0), (50.0, 30.0)].to_vec();
        let dst: Vec<_> = src.iter().map(|&(x, y)| h.apply(x, y).unwrap()).collect();
        let e = Homography::from_points(&src, &dst).unwrap();
        assert!((e.0 - h.0).norm() < 1e-8, "{}", e.0);
        let (x, y) = h.inverse().unwrap().apply(dst[4].0, dst[4].1).unwrap();
        assert!((x - 50.0).abs() < 1e-9 && (y - 30.0).abs() < 1e-9);
    }
}
