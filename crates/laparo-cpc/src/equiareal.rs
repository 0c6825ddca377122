//! Equiareal refinement (thesis §4.4.4, eqs. 4.8/4.9), initialised from the convex solution
//! (§4.4.6 step 4):
//!
//! ```text
//! C(p) = λ Σ_t w_t |M_t p_t|²  +  (1 − λ) Σ_t (A_t / A_tot) (1 − area(t, p) / A_t)²
//! ```
//!
//! with the per-unit-area weights of [`crate::solve`] (eq. 4.8's squared area differences divided
//! by A_t, so that the term is a mean over the image area). Levenberg–Marquardt on the Gauss–Newton
//! normal equations; the area Jacobian of a triangle only couples its three vertices, so the
//! normal matrix has the pattern of the convex system and reuses its symbolic Cholesky. The damping
//! uses the vertex-area mass matrix, which also removes the rigid-motion gauge freedom of eq. 4.9.
use crate::error::{CpcError, Result};
use crate::mesh::{signed_area, CpcMesh};
use crate::solve::{validate_lambda, CpcSystem};
use serde::Serialize;

/// Options of the equiareal refinement.
#[derive(Clone, Debug, Serialize)]
pub struct EquiarealParams {
    /// Maximum number of LM iterations.
    pub max_iterations: usize,
    /// Stop when the relative cost decrease of an accepted step is below this.
    pub rel_tol: f64,
    /// Initial damping, relative to the displacement mass matrix.
    pub initial_damping: f64,
}

impl Default for EquiarealParams {
    fn default() -> Self {
        EquiarealParams { max_iterations: 30, rel_tol: 1e-6, initial_damping: 1e-3 }
    }
}

/// Result of the refinement.
pub struct Refined {
    /// Flattened vertex positions (px).
    pub p: Vec<[f64; 2]>,
    /// Gauss–Newton iterations performed.
    pub iterations: usize,
    /// Cost of eq. 4.9 before and after.
    pub cost_before: f64,
    /// Cost of eq. 4.9 after the refinement.
    pub cost_after: f64,
}

fn area_grad(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> [f64; 6] {
    [
        0.5 * (b[1] - c[1]),
        0.5 * (c[0] - b[0]),
        0.5 * (c[1] - a[1]),
        0.5 * (a[0] - c[0]),
        0.5 * (a[1] - b[1]),
        0.5 * (b[0] - a[0]),
    ]
}

struct Problem<'a> {
    sys: &'a CpcSystem,
    mesh: &'a CpcMesh,
    lambda: f64,
    area0: Vec<f64>,
    a_tot: f64,
}

impl Problem<'_> {
    fn cost(&self, p: &[[f64; 2]]) -> f64 {
        let (ec, _) = self.sys.energies(p);
        let mut ea = 0.0;
        for (t, f) in self.mesh.faces.iter().enumerate() {
            let a = signed_area(p[f[0]], p[f[1]], p[f[2]]);
            ea += self.area0[t] / self.a_tot * (1.0 - a / self.area0[t]).powi(2);
        }
        self.lambda * ec + (1.0 - self.lambda) * ea
    }
}

/// Refine `p0` (the convex solution for `lambda`) by minimising eq. 4.9.
pub fn refine(
    sys: &CpcSystem,
    mesh: &CpcMesh,
    p0: &[[f64; 2]],
    lambda: f64,
    params: &EquiarealParams,
) -> Result<Refined> {
    validate_lambda(lambda)?;
    if p0.len() != mesh.n_vertices() {
        return Err(CpcError::SizeMismatch(format!("{} positions for {} vertices", p0.len(), mesh.n_vertices())));
    }
    let area0: Vec<f64> =
        mesh.faces.iter().map(|f| signed_area(mesh.p_init[f[0]], mesh.p_init[f[1]], mesh.p_init[f[2]])).collect();
    let a_tot: f64 = area0.iter().sum();
    let pb = Problem { sys, mesh, lambda, area0, a_tot };
    let mut p = p0.to_vec();
    let mut cost = pb.cost(&p);
    let cost_before = cost;
    let mut mu = params.initial_damping;
    let mut it = 0;
    let (_, _, diag_pos) = sys.pattern();
    let mass = sys.displacement_weights();
    while it < params.max_iterations {
        it += 1;
        // Gradient (½ ∇C) and Gauss–Newton matrix (½ ∇²C).
        let x: Vec<f64> = p.iter().flat_map(|q| [q[0], q[1]]).collect();
        let kx = sys.conformal_matvec(&x);
        let mut g: Vec<f64> = kx.iter().map(|v| lambda * v).collect();
        let mut vals: Vec<f64> = sys.conformal_values().iter().map(|v| lambda * v).collect();
        for (t, f) in mesh.faces.iter().enumerate() {
            let (a, b, c) = (p[f[0]], p[f[1]], p[f[2]]);
            let at = pb.area0[t];
            let ct = (1.0 - lambda) * at / a_tot;
            let r = 1.0 - signed_area(a, b, c) / at;
            let gr = area_grad(a, b, c);
            for (l, &v) in f.iter().enumerate() {
                g[2 * v] -= ct * r * gr[2 * l] / at;
                g[2 * v + 1] -= ct * r * gr[2 * l + 1] / at;
            }
            let mut k6 = [[0.0; 6]; 6];
            for i in 0..6 {
                for j in 0..6 {
                    k6[i][j] = ct * gr[i] * gr[j] / (at * at);
                }
            }
            sys.add_face_block(&mut vals, f, &k6);
        }
        let gnorm: f64 = g.iter().map(|v| v * v).sum::<f64>().sqrt();
        if gnorm.is_nan() || gnorm <= 0.0 {
            break;
        }
        let mut accepted = false;
        for _ in 0..12 {
            let mut v2 = vals.clone();
            for (u, &pos) in diag_pos.iter().enumerate() {
                v2[pos] += mu * mass[u / 2];
            }
            let mut step: Vec<f64> = g.iter().map(|v| -v).collect();
            if sys.factor_solve(&v2, &mut step).is_err() {
                mu *= 10.0;
                continue;
            }
            let cand: Vec<[f64; 2]> =
                p.iter().enumerate().map(|(i, q)| [q[0] + step[2 * i], q[1] + step[2 * i + 1]]).collect();
            let c2 = pb.cost(&cand);
            if c2.is_finite() && c2 < cost {
                let rel = (cost - c2) / cost.max(1e-300);
                p = cand;
                cost = c2;
                mu = (mu / 3.0).max(1e-12);
                accepted = true;
                if rel < params.rel_tol {
                    return Ok(Refined { p, iterations: it, cost_before, cost_after: cost });
                }
                break;
            }
            mu *= 4.0;
        }
        if !accepted {
            break;
        }
    }
    Ok(Refined { p, iterations: it, cost_before, cost_after: cost })
}
