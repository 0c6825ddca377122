//! Landmark LDDMM by geodesic shooting [Beg 2005; Miller, Trouvé & Younes 2006] (thesis §5.4.2
//! baseline "LDDMM").
//!
//! Landmarks q_i (the source material points, mm) carry momenta p_i (mm per unit time); the kernel is
//! K(x, y) = exp(−|x − y|² / σ_K²) (σ_K in mm). The Hamiltonian H = ½ Σ_ij K(q_i, q_j) p_i·p_j gives
//!
//! dq_i/dt = Σ_j K_ij p_j,   dp_i/dt = (2/σ_K²) Σ_j K_ij (p_i·p_j)(q_i − q_j),   t ∈ [0, 1],
//!
//! integrated with the explicit (forward) Euler scheme in `steps` equal steps. The initial momenta
//! minimise J(p₀) = γ ½ p₀ᵀ K(q₀) p₀ + Σ_g ω_g Σ_{k∈g} |q_k(1) − c_k|² (c_k the closest point of
//! q_k(1) on its group's target, eq. 5.10, recomputed at every evaluation) by L-BFGS with the exact
//! gradient of the discrete scheme (adjoint = backpropagation through the Euler steps). Every mesh node
//! is then advected by the same Euler scheme in the flow v(x, t) = Σ_i K(x, q_i(t)) p_i(t).
use super::lbfgs::minimise;
use super::{BaselineProblem, BaselineReport, BaselineResult};
use crate::{RegisterError, Result};
use nalgebra::Vector3;
use rayon::prelude::*;
use std::time::Instant;

/// LDDMM settings.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct LddmmConfig {
    /// Kernel width σ_K (mm); the thesis uses ≈ 20 mm (sweep 10–40).
    pub sigma_mm: f64,
    /// Euler time steps over t ∈ [0, 1] (thesis: 10).
    pub steps: usize,
    /// Weight γ of the geodesic energy ½ p₀ᵀK(q₀)p₀ (dimensionless, relative to Σ dist² in mm²).
    pub gamma: f64,
    /// Maximum L-BFGS iterations.
    pub iterations: usize,
    /// L-BFGS memory.
    pub memory: usize,
    /// Stop when |∂J/∂p₀|_∞ falls below this (mm).
    pub gradient_tolerance: f64,
}

impl Default for LddmmConfig {
    fn default() -> Self {
        LddmmConfig { sigma_mm: 20.0, steps: 10, gamma: 0.01, iterations: 300, memory: 10, gradient_tolerance: 1e-7 }
    }
}

fn kern(a: &Vector3<f64>, b: &Vector3<f64>, s2: f64) -> f64 {
    (-(a - b).norm_squared() / s2).exp()
}

/// Positions (or momenta) at every time step s = 0..=steps.
type Trajectory = Vec<Vec<Vector3<f64>>>;

/// Trajectories q_s, p_s, s = 0..=steps.
fn shoot(q0: &[Vector3<f64>], p0: &[Vector3<f64>], s2: f64, steps: usize) -> (Trajectory, Trajectory) {
    let dt = 1.0 / steps as f64;
    let c = 2.0 / s2;
    let mut qs = vec![q0.to_vec()];
    let mut ps = vec![p0.to_vec()];
    for s in 0..steps {
        let (q, p) = (&qs[s], &ps[s]);
        let upd: Vec<(Vector3<f64>, Vector3<f64>)> = (0..q.len())
            .into_par_iter()
            .map(|i| {
                let (mut f, mut g) = (Vector3::zeros(), Vector3::zeros());
                for j in 0..q.len() {
                    let k = kern(&q[i], &q[j], s2);
                    f += p[j] * k;
                    g += (q[i] - q[j]) * (c * k * p[i].dot(&p[j]));
                }
                (q[i] + f * dt, p[i] + g * dt)
            })
            .collect();
        qs.push(upd.iter().map(|u| u.0).collect());
        ps.push(upd.iter().map(|u| u.1).collect());
    }
    (qs, ps)
}

struct Lddmm<'a> {
    p: &'a BaselineProblem,
    /// (group, landmark) of every flattened landmark.
    index: Vec<(usize, usize)>,
    q0: Vec<Vector3<f64>>,
    s2: f64,
    cfg: LddmmConfig,
}

impl Lddmm<'_> {
    fn objective(&self, p0: &[Vector3<f64>]) -> (f64, Vec<Vector3<f64>>) {
        let (s2, n, steps) = (self.s2, self.q0.len(), self.cfg.steps);
        let c = 2.0 / s2;
        let dt = 1.0 / steps as f64;
        let (qs, ps) = shoot(&self.q0, p0, s2, steps);
        let qt = &qs[steps];
        let mut val = 0.0;
        let mut aq = vec![Vector3::zeros(); n];
        for (m, &(g, k)) in self.index.iter().enumerate() {
            let grp = &self.p.groups[g];
            let r = qt[m] - grp.closest(k, &qt[m]);
            val += grp.weight * r.norm_squared();
            aq[m] = r * (2.0 * grp.weight);
        }
        let mut ap = vec![Vector3::zeros(); n];
        for s in (0..steps).rev() {
            let (q, p) = (&qs[s], &ps[s]);
            let upd: Vec<(Vector3<f64>, Vector3<f64>)> = (0..n)
                .into_par_iter()
                .map(|i| {
                    let (mut gq, mut gp) = (Vector3::zeros(), Vector3::zeros());
                    for j in 0..n {
                        let d = q[i] - q[j];
                        let k = kern(&q[i], &q[j], s2);
                        // A = Σ_m aq_m·f_m
                        gp += aq[j] * k;
                        gq -= d * (c * k * (aq[i].dot(&p[j]) + aq[j].dot(&p[i])));
                        // B = Σ_m ap_m·g_m
                        let dap = ap[i] - ap[j];
                        gp += p[j] * (c * k * dap.dot(&d));
                        gq += (dap - d * (c * dap.dot(&d))) * (c * k * p[i].dot(&p[j]));
                    }
                    (aq[i] + gq * dt, ap[i] + gp * dt)
                })
                .collect();
            aq = upd.iter().map(|u| u.0).collect();
            ap = upd.iter().map(|u| u.1).collect();
        }
        // geodesic energy γ ½ p₀ᵀ K(q₀) p₀
        let gamma = self.cfg.gamma;
        if gamma > 0.0 {
            let kp: Vec<Vector3<f64>> = (0..n)
                .into_par_iter()
                .map(|i| (0..n).map(|j| p0[j] * kern(&self.q0[i], &self.q0[j], s2)).sum())
                .collect();
            for i in 0..n {
                val += 0.5 * gamma * p0[i].dot(&kp[i]);
                ap[i] += kp[i] * gamma;
            }
        }
        (val, ap)
    }
}

fn setup<'a>(problem: &'a BaselineProblem, cfg: &LddmmConfig) -> Result<Lddmm<'a>> {
    problem.validate()?;
    if !(cfg.sigma_mm.is_finite() && cfg.sigma_mm > 0.0) {
        return Err(RegisterError::param("LDDMM sigma_mm", cfg.sigma_mm, "must be finite and > 0"));
    }
    if cfg.steps == 0 {
        return Err(RegisterError::param("LDDMM steps", 0.0, "must be >= 1"));
    }
    if !(cfg.gamma.is_finite() && cfg.gamma >= 0.0) {
        return Err(RegisterError::param("LDDMM gamma", cfg.gamma, "must be finite and >= 0"));
    }
    let mut index = Vec::new();
    let mut q0 = Vec::new();
    for (g, grp) in problem.groups.iter().enumerate() {
        for (k, mp) in grp.points.iter().enumerate() {
            index.push((g, k));
            q0.push(mp.position(&problem.mesh.vertices));
        }
    }
    Ok(Lddmm { p: problem, index, q0, s2: cfg.sigma_mm * cfg.sigma_mm, cfg: cfg.clone() })
}

fn unflatten(v: &[f64]) -> Vec<Vector3<f64>> {
    v.chunks(3).map(|c| Vector3::new(c[0], c[1], c[2])).collect()
}

/// J(p₀) and ∂J/∂p₀ (one momentum per landmark, groups in order) of the LDDMM objective; for tests.
pub fn lddmm_objective(
    problem: &BaselineProblem,
    cfg: &LddmmConfig,
    p0: &[Vector3<f64>],
) -> Result<(f64, Vec<Vector3<f64>>)> {
    let l = setup(problem, cfg)?;
    if p0.len() != l.q0.len() {
        return Err(RegisterError::bad("LDDMM momenta", format!("{} for {} landmarks", p0.len(), l.q0.len())));
    }
    Ok(l.objective(p0))
}

/// Advect points `x` (mm) in the flow of the trajectories (same Euler scheme).
fn advect(x: &[Vector3<f64>], qs: &[Vec<Vector3<f64>>], ps: &[Vec<Vector3<f64>>], s2: f64) -> Vec<Vector3<f64>> {
    let steps = qs.len() - 1;
    let dt = 1.0 / steps as f64;
    x.par_iter()
        .map(|x0| {
            let mut y = *x0;
            for s in 0..steps {
                let v: Vector3<f64> = qs[s].iter().zip(&ps[s]).map(|(q, p)| p * kern(&y, q, s2)).sum();
                y += v * dt;
            }
            y
        })
        .collect()
}

/// LDDMM registration of `problem`: optimise the initial momenta, advect every mesh node. Fixed nodes
/// are ignored (a diffeomorphic flow has no hard constraints).
pub fn lddmm(problem: &BaselineProblem, cfg: &LddmmConfig) -> Result<BaselineResult> {
    let t0 = Instant::now();
    let l = setup(problem, cfg)?;
    let n = l.q0.len();
    let mut history = Vec::new();
    let out = minimise(
        vec![0.0; 3 * n],
        |v| {
            let (val, g) = l.objective(&unflatten(v));
            (val, g.iter().flat_map(|a| [a[0], a[1], a[2]]).collect())
        },
        cfg.iterations,
        cfg.memory.max(1),
        cfg.gradient_tolerance,
        |v| {
            let (qs, _) = shoot(&l.q0, &unflatten(v), l.s2, cfg.steps);
            let qt = &qs[cfg.steps];
            let d: f64 = l
                .index
                .iter()
                .enumerate()
                .map(|(m, &(g, k))| (qt[m] - problem.groups[g].closest(k, &qt[m])).norm())
                .sum();
            history.push(d / n as f64);
        },
    );
    let p0 = unflatten(&out.x);
    let (qs, ps) = shoot(&l.q0, &p0, l.s2, cfg.steps);
    let x = advect(&problem.mesh.vertices, &qs, &ps, l.s2);
    Ok(BaselineResult {
        report: BaselineReport {
            method: "lddmm".into(),
            iterations: out.iterations,
            initial_mean_distance_mm: problem.mean_distance(&problem.mesh.vertices),
            mean_distance_mm: problem.mean_distance(&x),
            history_mm: history,
            converged: out.converged,
            seconds: t0.elapsed().as_secs_f64(),
        },
        positions: x,
    })
}

/// Kernel-width sweep for the benchmark: one LDDMM run per σ_K in `sigmas_mm` (other settings from
/// `cfg`), returned as (σ_K, result) in the order given.
pub fn lddmm_width_sweep(
    problem: &BaselineProblem,
    sigmas_mm: &[f64],
    cfg: &LddmmConfig,
) -> Result<Vec<(f64, BaselineResult)>> {
    sigmas_mm.iter().map(|&s| Ok((s, lddmm(problem, &LddmmConfig { sigma_mm: s, ..cfg.clone() })?))).collect()
}
