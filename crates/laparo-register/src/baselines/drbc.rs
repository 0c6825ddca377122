//! Deformable registration with biomechanical constraints, DRBC [Collins 2020] style (thesis §5.4.2
//! baseline): minimise over the node positions x (mm)
//!
//! Φ(x) = Σ_g ω_g Σ_{k∈g} dist²(x_k, target_g) + λ Σ_e V_e ψ_NH(F_e),
//!
//! with linear tets, ψ_NH the compressible Neo-Hookean law of eq. 5.3 (`laparo_fem::NeoHookean`, kPa),
//! V_e the rest volume (mm³) and dist the eq. 5.10 distance (closest point recomputed at every
//! evaluation; its gradient 2 (x_k − c_k) is exact almost everywhere). Newton's method on the exact
//! Hessian (element tangents ∂P/∂F, and 2 (I − ∂c/∂x) for each landmark, i.e. 2 (I − t tᵀ) on a
//! segment), factorised with faer's sparse Cholesky (symbolic analysis once); where that Hessian is not
//! positive definite, the element tangents are projected to their positive part (eigenvalues clamped
//! at 0) plus a growing diagonal shift if needed. Backtracking Armijo line search that rejects any
//! trial with an element J ≤ 0 (inversion-safe).
use super::sparse::{solve_columns, SpdPattern};
use super::{deformation_gradient, shape_gradients, BaselineProblem, BaselineReport, BaselineResult};
use crate::{RegisterError, Result};
use laparo_fem::NeoHookean;
use nalgebra::{SMatrix, SVector, Vector3};
use rayon::prelude::*;
use std::time::Instant;

type M12 = SMatrix<f64, 12, 12>;

/// DRBC settings.
#[derive(Clone, Debug)]
pub struct DrbcConfig {
    /// Material (eq. 5.3); default the thesis liver, E = 4.1 kPa, ν = 0.49.
    pub material: NeoHookean,
    /// Weight λ of the elastic energy (1/(kPa·mm), so that λ V ψ is in mm²); `None`:
    /// 0.01 K L² / (V μ) with K landmarks, L the rest bounding-box diagonal (mm), V the mesh volume
    /// (mm³) and μ the shear modulus (kPa).
    pub lambda: Option<f64>,
    /// Factor on the default λ (used when `lambda` is `None`; the benchmark's tuned hyperparameter), 1 = the default.
    pub lambda_factor: f64,
    /// Maximum Newton iterations.
    pub iterations: usize,
    /// Stop when the largest free gradient component |∂Φ/∂x| falls below this (mm).
    pub gradient_tolerance: f64,
    /// Stop when a Newton step moves no node more than this (mm).
    pub step_tolerance_mm: f64,
    /// Maximum step halvings of the line search.
    pub max_halvings: usize,
}

impl Default for DrbcConfig {
    fn default() -> Self {
        DrbcConfig {
            material: NeoHookean::liver(),
            lambda: None,
            lambda_factor: 1.0,
            iterations: 50,
            gradient_tolerance: 1e-8,
            step_tolerance_mm: 1e-4,
            max_halvings: 40,
        }
    }
}

struct Drbc<'a> {
    p: &'a BaselineProblem,
    mat: NeoHookean,
    lambda: f64,
    grads: Vec<([Vector3<f64>; 4], f64)>,
}

impl Drbc<'_> {
    /// Φ(x) and ∂Φ/∂x; `None` when an element is inverted (J ≤ 0).
    fn value_gradient(&self, x: &[Vector3<f64>], want_grad: bool) -> Option<(f64, Vec<Vector3<f64>>)> {
        let per: Vec<Option<(f64, [Vector3<f64>; 4])>> = self
            .p
            .mesh
            .tets
            .par_iter()
            .zip(&self.grads)
            .map(|(t, (g, v))| {
                let f = deformation_gradient(t, g, x);
                let psi = self.mat.energy_density(&f)?;
                let pk = if want_grad { self.mat.pk1(&f)? } else { nalgebra::Matrix3::zeros() };
                Some((v * psi, std::array::from_fn(|a| pk * g[a] * *v)))
            })
            .collect();
        let mut e = 0.0;
        let mut grad = vec![Vector3::zeros(); if want_grad { x.len() } else { 0 }];
        for (t, r) in self.p.mesh.tets.iter().zip(per) {
            let (ve, fa) = r?;
            e += ve;
            if want_grad {
                for a in 0..4 {
                    grad[t[a]] += fa[a] * self.lambda;
                }
            }
        }
        let mut val = self.lambda * e;
        for g in &self.p.groups {
            let terms: Vec<Vector3<f64>> = g
                .points
                .par_iter()
                .enumerate()
                .map(|(k, mp)| {
                    let y = mp.position(x);
                    y - g.closest(k, &y)
                })
                .collect();
            for (mp, r) in g.points.iter().zip(terms) {
                val += g.weight * r.norm_squared();
                if want_grad {
                    for &(a, wa) in &mp.nodes {
                        grad[a] += r * (2.0 * g.weight * wa);
                    }
                }
            }
        }
        Some((val, grad))
    }

    /// Element Hessians λ V Bᵀ A B (12×12, node-major dofs), with the tangent A projected to its
    /// positive part A₊ when `project` (only where A is not positive definite).
    fn element_hessians(&self, x: &[Vector3<f64>], project: bool) -> Option<Vec<M12>> {
        self.p
            .mesh
            .tets
            .par_iter()
            .zip(&self.grads)
            .map(|(t, (g, v))| {
                let f = deformation_gradient(t, g, x);
                let a = self.mat.tangent(&f)?;
                let a = (a + a.transpose()) * 0.5;
                let ap = if !project || a.cholesky().is_some() {
                    a
                } else {
                    let eig = nalgebra::SymmetricEigen::new(a);
                    let lam = eig.eigenvalues.map(|l| l.max(0.0));
                    eig.eigenvectors * SMatrix::<f64, 9, 9>::from_diagonal(&lam) * eig.eigenvectors.transpose()
                };
                // B[(3i+j), (3a+k)] = δ_ik g_a[j]
                let mut b = SMatrix::<f64, 9, 12>::zeros();
                for na in 0..4 {
                    for i in 0..3 {
                        for j in 0..3 {
                            b[(3 * i + j, 3 * na + i)] = g[na][j];
                        }
                    }
                }
                Some(b.transpose() * ap * b * (self.lambda * v))
            })
            .collect()
    }
}

/// Values of the lower-triangular Hessian in the order of the pattern built by [`drbc`]: element
/// blocks, landmark blocks (exact dist² Hessians), then `ndof` diagonal slots (the shift, zero here).
fn assemble(
    problem: &BaselineProblem,
    free: &[Option<usize>],
    x: &[Vector3<f64>],
    he: &[M12],
    ndof: usize,
) -> Vec<f64> {
    let mut values = Vec::new();
    for (t, h) in problem.mesh.tets.iter().zip(he) {
        for a in 0..4 {
            for b in 0..4 {
                if let (Some(fa), Some(fb)) = (free[t[a]], free[t[b]]) {
                    for i in 0..3 {
                        for k in 0..3 {
                            if 3 * fa + i >= 3 * fb + k {
                                values.push(h[(3 * a + i, 3 * b + k)]);
                            }
                        }
                    }
                }
            }
        }
    }
    let h_fd = 1e-7 * problem.diameter();
    for g in &problem.groups {
        let hs: Vec<nalgebra::Matrix3<f64>> =
            g.points.par_iter().map(|mp| g.distance_hessian(&mp.position(x), h_fd)).collect();
        for (mp, hk) in g.points.iter().zip(hs) {
            for &(a, wa) in &mp.nodes {
                for &(b, wb) in &mp.nodes {
                    if let (Some(fa), Some(fb)) = (free[a], free[b]) {
                        for i in 0..3 {
                            for k in 0..3 {
                                if 3 * fa + i >= 3 * fb + k {
                                    values.push(g.weight * wa * wb * hk[(i, k)]);
                                }
                            }
                        }
                    }
                }
            }
        }
    }
    values.resize(values.len() + ndof, 0.0);
    values
}

/// Φ(x) and its gradient ∂Φ/∂x (mm², mm) of DRBC at node positions `x`; `Ok(None)` when an element is
/// inverted. For tests and tuning.
pub fn drbc_objective(
    problem: &BaselineProblem,
    cfg: &DrbcConfig,
    x: &[Vector3<f64>],
) -> Result<Option<(f64, Vec<Vector3<f64>>)>> {
    let d = setup(problem, cfg)?;
    Ok(d.value_gradient(x, true))
}

fn setup<'a>(problem: &'a BaselineProblem, cfg: &DrbcConfig) -> Result<Drbc<'a>> {
    problem.validate()?;
    let k = problem.landmark_count().max(1) as f64;
    let l = problem.diameter();
    let lambda = match cfg.lambda {
        Some(v) if v.is_finite() && v > 0.0 => v,
        Some(v) => return Err(RegisterError::param("DRBC lambda", v, "must be finite and > 0")),
        None if cfg.lambda_factor.is_finite() && cfg.lambda_factor > 0.0 => {
            cfg.lambda_factor * 0.01 * k * l * l / (problem.total_volume() * cfg.material.mu_kpa)
        }
        None => return Err(RegisterError::param("DRBC lambda_factor", cfg.lambda_factor, "must be finite and > 0")),
    };
    Ok(Drbc { p: problem, mat: cfg.material, lambda, grads: shape_gradients(&problem.mesh) })
}

/// DRBC registration of `problem` from the rest mesh (fixed nodes at their prescribed positions).
pub fn drbc(problem: &BaselineProblem, cfg: &DrbcConfig) -> Result<BaselineResult> {
    let t0 = Instant::now();
    let d = setup(problem, cfg)?;
    let mut x = problem.initial_positions();
    if d.value_gradient(&x, false).is_none() {
        return Err(RegisterError::bad("DRBC", "the initial mesh (with the fixed nodes moved) has an inverted tet"));
    }
    let (free, nfree) = problem.free_map();
    if nfree == 0 {
        return Err(RegisterError::bad("DRBC", "every node is fixed"));
    }
    let ndof = 3 * nfree;
    // lower-triangular pattern: element blocks, landmark blocks, diagonal (shift)
    let mut pattern = Vec::new();
    for t in &problem.mesh.tets {
        for a in 0..4 {
            for b in 0..4 {
                if let (Some(fa), Some(fb)) = (free[t[a]], free[t[b]]) {
                    for i in 0..3 {
                        for k in 0..3 {
                            let (r, c) = (3 * fa + i, 3 * fb + k);
                            if r >= c {
                                pattern.push((r, c));
                            }
                        }
                    }
                }
            }
        }
    }
    for g in &problem.groups {
        for mp in &g.points {
            for &(a, _) in &mp.nodes {
                for &(b, _) in &mp.nodes {
                    if let (Some(fa), Some(fb)) = (free[a], free[b]) {
                        for i in 0..3 {
                            for k in 0..3 {
                                if 3 * fa + i >= 3 * fb + k {
                                    pattern.push((3 * fa + i, 3 * fb + k));
                                }
                            }
                        }
                    }
                }
            }
        }
    }
    for r in 0..ndof {
        pattern.push((r, r));
    }
    let sp = SpdPattern::new(ndof, &pattern)?;
    let initial = problem.mean_distance(&x);
    let mut history = Vec::new();
    let mut converged = false;
    let mut it = 0;
    let (mut phi, mut grad) = d.value_gradient(&x, true).ok_or_else(|| RegisterError::bad("DRBC", "inverted"))?;
    while it < cfg.iterations {
        let gmax = (0..x.len()).filter(|&i| free[i].is_some()).map(|i| grad[i].amax()).fold(0.0, f64::max);
        if gmax <= cfg.gradient_tolerance {
            converged = true;
            break;
        }
        // exact Hessian first (quadratic convergence near the solution); where it is not positive
        // definite, the projected one (elements' tangents clamped to ≥ 0), then a growing diagonal shift
        let mut llt = None;
        let mut err = None;
        for project in [false, true] {
            let he = d.element_hessians(&x, project).ok_or_else(|| RegisterError::bad("DRBC", "inverted element"))?;
            let values = assemble(problem, &free, &x, &he, ndof);
            let nd = values.len() - ndof;
            let mean_diag =
                pattern.iter().zip(&values).filter(|(rc, _)| rc.0 == rc.1).map(|(_, v)| v).sum::<f64>() / ndof as f64;
            let mut values = values;
            let mut shift = 1e-8 * mean_diag.abs().max(1e-300);
            loop {
                for r in 0..ndof {
                    values[nd + r] = shift;
                }
                match sp.factor(&values) {
                    Ok(l) => {
                        llt = Some(l);
                        break;
                    }
                    Err(e) => {
                        err = Some(e);
                        if !project || shift > 1e6 * mean_diag.abs() {
                            break;
                        }
                        shift *= 100.0;
                    }
                }
            }
            if llt.is_some() {
                break;
            }
        }
        let Some(llt) = llt else {
            return Err(err.unwrap_or_else(|| RegisterError::bad("DRBC", "Hessian factorisation failed")));
        };
        let mut rhs = vec![0.0; ndof];
        for i in 0..x.len() {
            if let Some(f) = free[i] {
                for c in 0..3 {
                    rhs[3 * f + c] = -grad[i][c];
                }
            }
        }
        let dir = solve_columns(&llt, &[rhs]).remove(0);
        let slope: f64 = (0..x.len())
            .filter_map(|i| free[i].map(|f| (0..3).map(|c| grad[i][c] * dir[3 * f + c]).sum::<f64>()))
            .sum();
        let mut alpha = 1.0;
        let mut accepted = None;
        for _ in 0..=cfg.max_halvings {
            let mut xt = x.clone();
            for i in 0..x.len() {
                if let Some(f) = free[i] {
                    xt[i] += SVector::<f64, 3>::new(dir[3 * f], dir[3 * f + 1], dir[3 * f + 2]) * alpha;
                }
            }
            // value only first (cheap rejection of inverted / non-decreasing trials)
            if let Some((v, _)) = d.value_gradient(&xt, false) {
                if v <= phi + 1e-4 * alpha * slope.min(0.0) {
                    accepted = Some(xt);
                    break;
                }
            }
            alpha *= 0.5;
        }
        it += 1;
        let Some(xn) = accepted else {
            history.push(problem.mean_distance(&x));
            break;
        };
        let step = xn.iter().zip(&x).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
        x = xn;
        (phi, grad) = d.value_gradient(&x, true).ok_or_else(|| RegisterError::bad("DRBC", "inverted"))?;
        history.push(problem.mean_distance(&x));
        if step <= cfg.step_tolerance_mm {
            converged = true;
            break;
        }
    }
    Ok(BaselineResult {
        report: BaselineReport {
            method: "drbc".into(),
            iterations: it,
            initial_mean_distance_mm: initial,
            mean_distance_mm: problem.mean_distance(&x),
            history_mm: history,
            converged,
            seconds: t0.elapsed().as_secs_f64(),
        },
        positions: x,
    })
}
