//! The conformal term of CPC (thesis §4.4.3, eqs. 4.2–4.7) with an orthonormal local basis per
//! 3D triangle.
//!
//! For a 3D triangle ABC with unit normal n = (B−A)×(C−A)/|·| we take Q0 = A, Q1 = B and
//! Q2 = A + R_θ(B−A), where R_θ rotates by θ about n inside the triangle's plane (θ = 90° gives
//! the orthonormal basis of eq. 4.2: |Q1−Q0| = |Q2−Q0|, Q1−Q0 ⟂ Q2−Q0). The barycentric
//! coordinates (α_j, β_j, γ_j) of Q_j w.r.t. ABC applied to the unknown 2D vertices a, b, c give
//! v_j (eq. 4.4), and conformality asks v2 − v0 = R_θ(v1 − v0) in the image (eq. 4.3).
//!
//! Derivation of M_t (θ = 90°). Image coordinates have u right and v down; for a triangle whose
//! image orientation is positive the 3D normal points away from the camera, and the 90° rotation
//! about n maps the 3D basis onto the image rotation Rot90(x, y) = (−y, x). With Δα_k = α_k − α_0
//! (likewise β, γ) and p_t = [x_a, y_a, x_b, y_b, x_c, y_c], eq. 4.3 reads
//! −(v1−v0)_y = (v2−v0)_x and (v1−v0)_x = (v2−v0)_y, i.e.
//!
//! ```text
//! M_t = [ Δα2   Δα1   Δβ2   Δβ1   Δγ2   Δγ1 ]
//!       [ Δα1  −Δα2   Δβ1  −Δβ2   Δγ1  −Δγ2 ]
//! ```
//!
//! The first row is eq. 4.6's; the second row printed in eq. 4.6 lacks the minus signs. As
//! printed, the two rows say (v2−v0) = −swap(v1−v0), a reflection whose image of an edge is not
//! orthogonal to it: the oblique-plane test (`tests/acceptance.rs::eq46_as_printed_is_not_conformal`)
//! shows that the printed rows leave several degrees of angle error where the derived rows reach
//! < 0.5°.
use nalgebra::Vector3;
use serde::Serialize;

/// Which second row of M_t to use (eq. 4.6).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum RowConvention {
    /// Derived from eq. 4.3 (correct; default).
    Derived,
    /// The second row exactly as printed in eq. 4.6 (θ = 90° only), kept to show that it is wrong.
    AsPrinted,
}

/// Options of the conformal term.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct ConformalParams {
    /// Angle θ (rad) between the two basis vectors Q1−Q0 and Q2−Q0 (generalised eq. 4.2); π/2 by
    /// default. Must be in (0, π).
    pub theta_rad: f64,
    /// Second-row convention of eq. 4.6.
    pub convention: RowConvention,
}

impl Default for ConformalParams {
    fn default() -> Self {
        ConformalParams { theta_rad: std::f64::consts::FRAC_PI_2, convention: RowConvention::Derived }
    }
}

/// Barycentric coordinates (α, β, γ) of Q0, Q1, Q2 w.r.t. triangle ABC (eq. 4.4), for the basis
/// Q0 = A, Q1 = B, Q2 = A + R_θ(B − A). `None` for a degenerate triangle.
pub fn basis_barycentrics(a: &Vector3<f64>, b: &Vector3<f64>, c: &Vector3<f64>, theta: f64) -> Option<[[f64; 3]; 3]> {
    basis_barycentrics_cs(a, b, c, theta.cos(), theta.sin())
}

/// [`basis_barycentrics`] with cos θ and sin θ given.
fn basis_barycentrics_cs(
    a: &Vector3<f64>,
    b: &Vector3<f64>,
    c: &Vector3<f64>,
    cos_t: f64,
    sin_t: f64,
) -> Option<[[f64; 3]; 3]> {
    let e1 = b - a;
    let e2 = c - a;
    let n = e1.cross(&e2);
    let nn = n.norm();
    if !(nn > 0.0 && nn.is_finite()) {
        return None;
    }
    let n = n / nn;
    // R_θ e1 = cosθ e1 + sinθ (n × e1)   (e1 ⟂ n)
    let q2 = e1 * cos_t + n.cross(&e1) * sin_t;
    // In-plane solve [e1 e2] [β γ]ᵀ = q2 via the Gram matrix.
    let g11 = e1.dot(&e1);
    let g12 = e1.dot(&e2);
    let g22 = e2.dot(&e2);
    let r1 = e1.dot(&q2);
    let r2 = e2.dot(&q2);
    let det = g11 * g22 - g12 * g12;
    if det.is_nan() || det <= 0.0 {
        return None;
    }
    let beta = (g22 * r1 - g12 * r2) / det;
    let gamma = (g11 * r2 - g12 * r1) / det;
    Some([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0 - beta - gamma, beta, gamma]])
}

/// The 2×6 matrix M_t of eq. 4.5/4.6 for triangle ABC, acting on p_t = [x_a, y_a, x_b, y_b, x_c, y_c].
/// `None` for a degenerate triangle.
pub fn triangle_rows(
    a: &Vector3<f64>,
    b: &Vector3<f64>,
    c: &Vector3<f64>,
    params: &ConformalParams,
) -> Option<[[f64; 6]; 2]> {
    triangle_rows_cs(a, b, c, params, params.theta_rad.cos(), params.theta_rad.sin())
}

/// [`triangle_rows`] with cos θ and sin θ precomputed (once per mesh instead of once per triangle).
pub fn triangle_rows_cs(
    a: &Vector3<f64>,
    b: &Vector3<f64>,
    c: &Vector3<f64>,
    params: &ConformalParams,
    ct: f64,
    st: f64,
) -> Option<[[f64; 6]; 2]> {
    let q = basis_barycentrics_cs(a, b, c, ct, st)?;
    // d1[j], d2[j]: barycentric differences Δ_1, Δ_2 for vertex j ∈ {a, b, c}.
    let d1 = [q[1][0] - q[0][0], q[1][1] - q[0][1], q[1][2] - q[0][2]];
    let d2 = [q[2][0] - q[0][0], q[2][1] - q[0][1], q[2][2] - q[0][2]];
    let mut m = [[0.0; 6]; 2];
    for j in 0..3 {
        match params.convention {
            RowConvention::Derived => {
                // v2−v0 = R_θ (v1−v0),  R_θ = [[c, −s], [s, c]]  (image coords, v down)
                // row 0:  (v2−v0)_x − c (v1−v0)_x + s (v1−v0)_y = 0
                // row 1:  s (v1−v0)_x + c (v1−v0)_y − (v2−v0)_y = 0
                m[0][2 * j] = d2[j] - ct * d1[j];
                m[0][2 * j + 1] = st * d1[j];
                m[1][2 * j] = st * d1[j];
                m[1][2 * j + 1] = ct * d1[j] - d2[j];
            }
            RowConvention::AsPrinted => {
                m[0][2 * j] = d2[j];
                m[0][2 * j + 1] = d1[j];
                m[1][2 * j] = d1[j];
                m[1][2 * j + 1] = d2[j];
            }
        }
    }
    Some(m)
}

/// Residual M_t p_t (px) of one triangle for 2D positions a, b, c.
#[inline]
pub fn residual(m: &[[f64; 6]; 2], a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> [f64; 2] {
    let p = [a[0], a[1], b[0], b[1], c[0], c[1]];
    let r0: f64 = (0..6).map(|i| m[0][i] * p[i]).sum();
    let r1: f64 = (0..6).map(|i| m[1][i] * p[i]).sum();
    [r0, r1]
}
