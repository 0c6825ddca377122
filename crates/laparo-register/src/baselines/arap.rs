//! Volumetric as-rigid-as-possible registration [Sorkine & Alexa 2007] on the rest tet mesh with a
//! soft landmark term (thesis §5.4.2 baseline "ARAP"):
//!
//! E(x) = E_ARAP(x, R) + w Σ_g ω_g Σ_{k∈g} |x_k − c_k|², c_k = the closest point of x_k on its group's
//! target (eq. 5.10), re-linearised at every outer iteration.
//!
//! Two ARAP energies (the two libigl uses for tets):
//! - [`ArapEnergy::Spokes`]: per-node rotations over the one-ring edges,
//!   E = Σ_i Σ_{j∈N(i)} w_ij |(x_i − x_j) − R_i (X_i − X_j)|²;
//! - [`ArapEnergy::Elements`]: per-tet rotations, E = Σ_t Σ_{(i,j)∈t} c^t_ij |(x_i − x_j) − R_t (X_i − X_j)|²
//!   = Σ_t V_t |F_t − R_t|²_F with the cotangent weights.
//!
//! Cotangent weights on tets are the P1 stiffness entries, c^t_ij = −V_t ∇φ_i·∇φ_j = l_kl cot θ_kl / 6
//! (θ_kl the dihedral angle at the opposite edge); w_ij = Σ_t c^t_ij. Uniform weights (w_ij = 1) are
//! the alternative for spokes. Local step: SVD per node/tet; global step: one sparse Cholesky factor
//! (faer), three right-hand sides per iteration. Fixed nodes are eliminated (hard constraints).
use super::sparse::{solve_columns, SpdPattern};
use super::{closest_rotation, deformation_gradient, shape_gradients, BaselineProblem, BaselineReport, BaselineResult};
use crate::{RegisterError, Result};
use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;
use std::time::Instant;

/// Which ARAP energy.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ArapEnergy {
    /// Per-node rotations over one-ring edges (Sorkine & Alexa 2007; libigl `ARAP_ENERGY_TYPE_SPOKES`).
    Spokes,
    /// Per-tet rotations (libigl `ARAP_ENERGY_TYPE_ELEMENTS`, its default for tets); always cotangent.
    Elements,
}

/// Edge weights of the spokes energy.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ArapWeights {
    /// w_ij = Σ_t l_kl cot θ_kl / 6 (mm; may be negative on obtuse tets).
    Cotangent,
    /// w_ij = 1.
    Uniform,
}

/// ARAP settings.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct ArapConfig {
    /// Energy variant.
    pub energy: ArapEnergy,
    /// Edge weights (spokes only; elements always use cotangent weights).
    pub weights: ArapWeights,
    /// Landmark weight w (units of the ARAP weights / mm², i.e. 1/mm for cotangent weights);
    /// `None`: 100 × E_ARAP(unit stretch) / (K L²) with K landmarks and L the rest bounding-box diagonal.
    pub landmark_weight: Option<f64>,
    /// Maximum outer (local–global) iterations.
    pub iterations: usize,
    /// Stop when no node moves more than this in an iteration (mm).
    pub tolerance_mm: f64,
}

impl Default for ArapConfig {
    fn default() -> Self {
        ArapConfig {
            energy: ArapEnergy::Spokes,
            weights: ArapWeights::Cotangent,
            landmark_weight: None,
            iterations: 200,
            tolerance_mm: 1e-3,
        }
    }
}

/// Precomputed ARAP operator of a problem (weights, factorised global matrix).
struct ArapSystem {
    /// Spokes: unique edges (i, j, w_ij).
    edges: Vec<(usize, usize, f64)>,
    /// Elements: per-tet shape gradients and volume.
    grads: Vec<([Vector3<f64>; 4], f64)>,
    /// Landmark weight w.
    w: f64,
    /// Proximal weight on the diagonal (keeps islands without landmarks determined).
    eps: f64,
    free: Vec<Option<usize>>,
    /// Free row, fixed node, value: rhs -= value x_fixed.
    coupling: Vec<(usize, usize, f64)>,
    llt: faer::sparse::linalg::solvers::Llt<usize, f64>,
    nfree: usize,
}

fn cot_edges(p: &BaselineProblem, grads: &[([Vector3<f64>; 4], f64)], uniform: bool) -> Vec<(usize, usize, f64)> {
    let mut e: Vec<(usize, usize, f64)> = Vec::with_capacity(6 * p.mesh.tets.len());
    for (t, (g, v)) in p.mesh.tets.iter().zip(grads) {
        for a in 0..4 {
            for b in a + 1..4 {
                let (i, j) = (t[a].min(t[b]), t[a].max(t[b]));
                e.push((i, j, if uniform { 0.0 } else { -v * g[a].dot(&g[b]) }));
            }
        }
    }
    e.sort_by_key(|x| (x.0, x.1));
    let mut out: Vec<(usize, usize, f64)> = Vec::new();
    for (i, j, w) in e {
        match out.last_mut() {
            Some(l) if l.0 == i && l.1 == j => l.2 += w,
            _ => out.push((i, j, w)),
        }
    }
    if uniform {
        for l in &mut out {
            l.2 = 1.0;
        }
    }
    out
}

impl ArapSystem {
    fn new(p: &BaselineProblem, cfg: &ArapConfig) -> Result<Self> {
        let n = p.mesh.vertices.len();
        let grads = shape_gradients(&p.mesh);
        let x0 = &p.mesh.vertices;
        // full symmetric scalar matrix entries (i, j, value), both orders
        let mut full: Vec<(usize, usize, f64)> = Vec::new();
        let mut edges = Vec::new();
        let unit_energy;
        match cfg.energy {
            ArapEnergy::Spokes => {
                edges = cot_edges(p, &grads, cfg.weights == ArapWeights::Uniform);
                unit_energy = edges.iter().map(|&(i, j, w)| 2.0 * w * (x0[i] - x0[j]).norm_squared()).sum::<f64>();
                for &(i, j, w) in &edges {
                    full.extend([(i, i, 2.0 * w), (j, j, 2.0 * w), (i, j, -2.0 * w), (j, i, -2.0 * w)]);
                }
            }
            ArapEnergy::Elements => {
                unit_energy = 3.0 * grads.iter().map(|g| g.1).sum::<f64>();
                for (t, (g, v)) in p.mesh.tets.iter().zip(&grads) {
                    for a in 0..4 {
                        for b in 0..4 {
                            full.push((t[a], t[b], v * g[a].dot(&g[b])));
                        }
                    }
                }
            }
        }
        let k = p.landmark_count().max(1) as f64;
        let l = p.diameter();
        let w = match cfg.landmark_weight {
            Some(w) if w.is_finite() && w > 0.0 => w,
            Some(w) => return Err(RegisterError::param("ARAP landmark_weight", w, "must be finite and > 0")),
            None => 100.0 * unit_energy.abs() / (k * l * l),
        };
        for g in &p.groups {
            for mp in &g.points {
                for &(a, wa) in &mp.nodes {
                    for &(b, wb) in &mp.nodes {
                        full.push((a, b, w * g.weight * wa * wb));
                    }
                }
            }
        }
        let mut diag = vec![0.0; n];
        for &(i, j, v) in &full {
            if i == j {
                diag[i] += v;
            }
        }
        let eps = 1e-10 * diag.iter().map(|d| d.abs()).sum::<f64>() / n as f64;
        let (free, nfree) = p.free_map();
        if nfree == 0 {
            return Err(RegisterError::bad("ARAP", "every node is fixed"));
        }
        let mut pattern = Vec::new();
        let mut values = Vec::new();
        let mut coupling = Vec::new();
        for &(i, j, v) in &full {
            match (free[i], free[j]) {
                (Some(fi), Some(fj)) if fi >= fj => {
                    pattern.push((fi, fj));
                    values.push(v);
                }
                (Some(fi), None) => coupling.push((fi, j, v)),
                _ => {}
            }
        }
        for f in 0..nfree {
            pattern.push((f, f));
            values.push(eps);
        }
        let sp = SpdPattern::new(nfree, &pattern)?;
        let llt = sp.factor(&values)?;
        debug_assert_eq!(sp.n(), nfree);
        Ok(ArapSystem { edges, grads, w, eps, free, coupling, llt, nfree })
    }

    /// One local–global iteration from `x` (fixed nodes already at their positions).
    fn iterate(&self, p: &BaselineProblem, cfg: &ArapConfig, x: &[Vector3<f64>]) -> Vec<Vector3<f64>> {
        let n = x.len();
        let x0 = &p.mesh.vertices;
        let mut b = vec![Vector3::zeros(); n];
        match cfg.energy {
            ArapEnergy::Spokes => {
                let mut s = vec![Matrix3::zeros(); n];
                for &(i, j, w) in &self.edges {
                    let m = (x0[i] - x0[j]) * (x[i] - x[j]).transpose() * w;
                    s[i] += m;
                    s[j] += m;
                }
                let r: Vec<Matrix3<f64>> = s.par_iter().map(|m| closest_rotation(&m.transpose())).collect();
                for &(i, j, w) in &self.edges {
                    let v = (r[i] + r[j]) * (x0[i] - x0[j]) * w;
                    b[i] += v;
                    b[j] -= v;
                }
            }
            ArapEnergy::Elements => {
                let contrib: Vec<[Vector3<f64>; 4]> = p
                    .mesh
                    .tets
                    .par_iter()
                    .zip(&self.grads)
                    .map(|(t, (g, v))| {
                        let r = closest_rotation(&deformation_gradient(t, g, x));
                        std::array::from_fn(|a| r * g[a] * *v)
                    })
                    .collect();
                for (t, c) in p.mesh.tets.iter().zip(contrib) {
                    for a in 0..4 {
                        b[t[a]] += c[a];
                    }
                }
            }
        }
        // landmark term: w ω_g Σ_a b_a c_k
        for g in &p.groups {
            let cs: Vec<Vector3<f64>> =
                g.points.par_iter().enumerate().map(|(k, mp)| g.closest(k, &mp.position(x))).collect();
            for (mp, c) in g.points.iter().zip(cs) {
                for &(a, wa) in &mp.nodes {
                    b[a] += c * (self.w * g.weight * wa);
                }
            }
        }
        let mut cols = vec![vec![0.0; self.nfree]; 3];
        for i in 0..n {
            if let Some(f) = self.free[i] {
                for d in 0..3 {
                    cols[d][f] = b[i][d] + self.eps * x[i][d];
                }
            }
        }
        for &(f, j, v) in &self.coupling {
            for d in 0..3 {
                cols[d][f] -= v * x[j][d];
            }
        }
        let sol = solve_columns(&self.llt, &cols);
        let mut out = x.to_vec();
        for i in 0..n {
            if let Some(f) = self.free[i] {
                out[i] = Vector3::new(sol[0][f], sol[1][f], sol[2][f]);
            }
        }
        out
    }
}

/// ARAP registration of `problem` (thesis §5.4.2 baseline; Sorkine & Alexa 2007), starting from the
/// rest mesh (fixed nodes at their prescribed positions).
pub fn arap(problem: &BaselineProblem, cfg: &ArapConfig) -> Result<BaselineResult> {
    problem.validate()?;
    arap_from(problem, cfg, &problem.initial_positions())
}

/// ARAP from a given initial guess `x_init` (mm, one per node; fixed nodes are reset to their
/// prescribed positions).
pub fn arap_from(problem: &BaselineProblem, cfg: &ArapConfig, x_init: &[Vector3<f64>]) -> Result<BaselineResult> {
    let t0 = Instant::now();
    problem.validate()?;
    if x_init.len() != problem.mesh.vertices.len() {
        return Err(RegisterError::bad(
            "ARAP initial guess",
            format!("{} positions for {} nodes", x_init.len(), problem.mesh.vertices.len()),
        ));
    }
    if !(cfg.tolerance_mm.is_finite() && cfg.tolerance_mm >= 0.0) {
        return Err(RegisterError::param("ARAP tolerance_mm", cfg.tolerance_mm, "must be finite and >= 0"));
    }
    let sys = ArapSystem::new(problem, cfg)?;
    let mut x = x_init.to_vec();
    for &(i, p) in &problem.fixed {
        x[i] = p;
    }
    let initial = problem.mean_distance(&problem.mesh.vertices);
    let mut history = Vec::new();
    let mut converged = false;
    let mut it = 0;
    while it < cfg.iterations {
        let xn = sys.iterate(problem, cfg, &x);
        let step = xn.iter().zip(&x).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
        x = xn;
        it += 1;
        history.push(problem.mean_distance(&x));
        if !step.is_finite() {
            return Err(RegisterError::bad("ARAP", "the global solve produced non-finite positions"));
        }
        if step <= cfg.tolerance_mm {
            converged = true;
            break;
        }
    }
    Ok(BaselineResult {
        report: BaselineReport {
            method: "arap".into(),
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
