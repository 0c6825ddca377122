//! Load stepping with Newton's method and a backtracking line search on the total potential
//! energy; sparse Cholesky (faer) of the free-DOF tangent in a nested-dissection order
//! ([`FillOrdering`]), shifted when indefinite.
//!
//! Factorisations dominate the cost (dense supernodal kernels), so a Newton direction is first sought
//! by conjugate gradients on the current tangent preconditioned by the Cholesky factor of an earlier
//! tangent (inexact Newton, [`SolverSettings::forcing`]); the tangent is factorised again only when
//! that fails to converge in [`SolverSettings::pcg_max_iterations`] or meets non-positive curvature. The
//! convergence test of Newton's method is unchanged, so the solution meets the same residual tolerance.
use super::linear::{norm, DirectSystem, Factor, NodeGraph};
use super::load_path::LoadPath;
use super::problem::SolidProblem;
use super::two_level::TwoLevel;
use crate::error::{FemError, Result};
use nalgebra::Vector3;
use serde::Serialize;
use std::time::Instant;

/// Settings of [`solve`].
#[derive(Clone, Copy, Debug, Serialize)]
pub struct SolverSettings {
    /// Number of equal load increments (20–50 for the benchmark).
    pub steps: usize,
    /// Convergence: ‖residual‖ ≤ `rel_tol` × ‖applied load‖ (external forces and reactions).
    pub rel_tol: f64,
    /// Newton iterations per increment before the increment is halved.
    pub max_newton: usize,
    /// How many times an increment may be halved (inversion or no convergence) before giving up.
    pub max_cuts: usize,
    /// Forcing term of the inexact Newton directions: conjugate gradients on a reused factor stop at
    /// ‖K d + r‖ ≤ `forcing` ‖r‖ (or a tenth of the Newton tolerance, whichever is larger).
    pub forcing: f64,
    /// Conjugate-gradient iterations on a reused factor before the tangent is factorised again
    /// (0: factorise at every Newton iteration, exact Newton).
    pub pcg_max_iterations: usize,
    /// Fill-reducing ordering of the sparse Cholesky.
    pub ordering: FillOrdering,
    /// Solver of the Newton directions.
    pub linear: LinearSolver,
    /// Conjugate-gradient iterations of the two-level solver per Newton direction; at the limit the
    /// last iterate is taken when it has reduced the residual tenfold.
    pub two_level_max_iterations: usize,
}

/// Solver of the linear systems of Newton's method.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub enum LinearSolver {
    /// Sparse Cholesky of the tangent, reused as a conjugate-gradient preconditioner (inexact Newton).
    Direct,
    /// Conjugate gradients preconditioned by a two-level cycle: block Gauss–Seidel on the TET10 nodes
    /// and a coarse correction on the linear tetrahedra of the same mesh (`two_level.rs`); memory
    /// grows linearly with the mesh instead of as n^{4/3}.
    TwoLevel,
    /// Direct when its Cholesky factor (8 bytes per nonzero, from the symbolic analysis) fits in
    /// `factor_budget_bytes`, two-level otherwise.
    Auto {
        /// Largest factor to hold (bytes).
        factor_budget_bytes: u64,
    },
}

impl Default for LinearSolver {
    /// Direct up to a 32 MiB factor (small meshes), two-level beyond: on the P2ILF liver, 8 load steps, the
    /// two-level solver took 0.71× (16 mm tets, 33k DOF) to 0.57× (10 mm, 131k DOF) of the direct
    /// path's time in 1/6–1/9 of its memory, and at 6 mm (585k DOF, a 20.6 GB factor) it needs 1.7 GB.
    fn default() -> Self {
        LinearSolver::Auto { factor_budget_bytes: 32 << 20 }
    }
}

/// Fill-reducing ordering of the tangent's sparse Cholesky.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum FillOrdering {
    /// Approximate minimum degree (faer's AMD).
    Amd,
    /// Geometric nested dissection of the free nodes (`ordering.rs`), DOF blocks kept together.
    NestedDissection,
}

impl Default for SolverSettings {
    fn default() -> Self {
        Self {
            steps: 20,
            rel_tol: 1e-8,
            max_newton: 25,
            max_cuts: 8,
            forcing: 1e-2,
            pcg_max_iterations: 30,
            ordering: FillOrdering::NestedDissection,
            linear: LinearSolver::default(),
            two_level_max_iterations: 400,
        }
    }
}

/// What happened in one (sub)increment.
#[derive(Clone, Debug, Serialize)]
pub struct StepReport {
    /// 1-based increment index (sub-increments after a cut share the index of the step they belong to).
    pub step: usize,
    /// Load factor reached.
    pub load_factor: f64,
    /// Newton iterations.
    pub iterations: usize,
    /// ‖free residual‖ (mN) before each iteration and at convergence.
    pub residual_history: Vec<f64>,
    /// Convergence threshold used (mN).
    pub tolerance: f64,
    /// Line-search step lengths taken.
    pub line_search_alphas: Vec<f64>,
    /// Iterations whose tangent was not positive definite (solved with a diagonal shift).
    pub shifted_iterations: usize,
    /// Minimum det F over all quadrature points at the converged state.
    pub min_j: f64,
}

/// Timing of the run (s).
#[derive(Clone, Debug, Default, Serialize)]
pub struct Timings {
    /// Whole solve.
    pub total_s: f64,
    /// Element evaluation and assembly (all iterations and line searches).
    pub assembly_s: f64,
    /// Symbolic analysis (fill-reducing ordering, elimination tree), once.
    pub symbolic_s: f64,
    /// Numeric Cholesky factorisations.
    pub factorization_s: f64,
    /// Triangular solves.
    pub solve_s: f64,
    /// Conjugate-gradient iterations preconditioned by a reused factor (each one a tangent product
    /// and a pair of triangular solves).
    pub pcg_iterations: usize,
    /// Numeric factorisations (the rest of the Newton directions came from the reused factor).
    pub factorizations: usize,
    /// Newton iterations in total.
    pub newton_iterations: usize,
}

/// Result of [`solve`].
#[derive(Clone, Debug, Serialize)]
pub struct Solution {
    /// Displacement of every TET10 node (mm); the first `n_vertices` are the linear vertices.
    #[serde(skip)]
    pub displacement: Vec<Vector3<f64>>,
    /// Number of linear vertices.
    pub n_vertices: usize,
    /// Number of free DOFs.
    pub free_dofs: usize,
    /// Nonzeros of the (upper) free tangent.
    pub tangent_nnz: usize,
    /// Nonzeros of its Cholesky factor (the fill of [`SolverSettings::ordering`]); of the coarse
    /// level's for the two-level solver.
    pub factor_nnz: usize,
    /// Solver of the Newton directions that ran: `direct` or `two-level`.
    pub linear_solver: &'static str,
    /// Per-increment reports.
    pub steps: Vec<StepReport>,
    /// Minimum det F over all quadrature points at the final state.
    pub min_j: f64,
    /// Max displacement norm over the nodes (mm).
    pub max_displacement_mm: f64,
    /// Timings.
    pub timings: Timings,
}

impl Solution {
    /// Displacements of the linear-mesh vertices (mm).
    pub fn vertex_displacements(&self) -> &[Vector3<f64>] {
        &self.displacement[..self.n_vertices]
    }
}

/// The free DOFs and the solver of the Newton directions.
pub(super) struct FreeSystem {
    pub(super) n: usize,
    pub(super) free_of_node: Vec<usize>,
    /// Nonzeros of the tangent's upper triangle over the free DOFs.
    pub(super) tangent_nnz: usize,
    linear: Linear,
}

enum Linear {
    Direct(Box<DirectSystem>),
    TwoLevel(Box<TwoLevel>),
}

impl FreeSystem {
    pub(super) fn new(p: &SolidProblem, settings: &SolverSettings) -> Result<Self> {
        let nn = p.mesh.n_nodes();
        let mut free_of_node = vec![usize::MAX; nn];
        let mut nf = 0;
        for (i, f) in free_of_node.iter_mut().enumerate() {
            if !p.is_prescribed(i) {
                *f = nf;
                nf += 1;
            }
        }
        if nf == 0 {
            return Err(FemError::bad("fixed nodes", "every node is prescribed: nothing to solve"));
        }
        let mut tangent_nnz = 0;
        for b in 0..nn {
            let fb = free_of_node[b];
            if fb != usize::MAX {
                for &a in &p.cols[p.row_ptr[b]..p.row_ptr[b + 1]] {
                    let fa = free_of_node[a];
                    tangent_nnz += match fa {
                        usize::MAX => 0,
                        fa if fa < fb => 9,
                        fa if fa == fb => 6,
                        _ => 0,
                    };
                }
            }
        }
        let graph = NodeGraph {
            row_ptr: &p.row_ptr,
            cols: &p.cols,
            points: &p.mesh.nodes,
            free_of_node: &free_of_node,
            n_free: nf,
        };
        let ordering = settings.ordering;
        let linear = match settings.linear {
            LinearSolver::Direct => Linear::Direct(Box::new(DirectSystem::new(&graph, ordering)?)),
            LinearSolver::TwoLevel => Linear::TwoLevel(Box::new(TwoLevel::new(p, &free_of_node, nf, ordering)?)),
            LinearSolver::Auto { factor_budget_bytes } => {
                let d = DirectSystem::new(&graph, ordering)?;
                if (d.factor_nnz() as u64).saturating_mul(8) > factor_budget_bytes {
                    drop(d);
                    Linear::TwoLevel(Box::new(TwoLevel::new(p, &free_of_node, nf, ordering)?))
                } else {
                    Linear::Direct(Box::new(d))
                }
            }
        };
        Ok(Self { n: 3 * nf, free_of_node, tangent_nnz, linear })
    }

    /// Nonzeros of the Cholesky factor (of the coarse level for the two-level solver).
    pub(super) fn factor_nnz(&self) -> usize {
        match &self.linear {
            Linear::Direct(d) => d.factor_nnz(),
            Linear::TwoLevel(t) => t.coarse.factor_nnz(),
        }
    }

    pub(super) fn solver_name(&self) -> &'static str {
        match &self.linear {
            Linear::Direct(_) => "direct",
            Linear::TwoLevel(_) => "two-level",
        }
    }

    /// rhs ← K⁻¹ rhs (to the forcing term) for the tangent `blocks`; whether a shift was needed.
    #[allow(clippy::too_many_arguments)] // the Newton iteration's running state
    fn direction(
        &self,
        p: &SolidProblem,
        blocks: &[f64],
        rhs: &mut [f64],
        abs_tol: f64,
        settings: &SolverSettings,
        reuse: &mut Option<Factor>,
        timings: &mut Timings,
    ) -> Result<bool> {
        match &self.linear {
            Linear::Direct(d) => {
                let mut vals = d.values(blocks);
                d.solve_reusing(
                    &mut vals,
                    rhs,
                    abs_tol,
                    (settings.forcing, settings.pcg_max_iterations),
                    reuse,
                    timings,
                )
            }
            Linear::TwoLevel(t) => t.solve(
                p,
                &self.free_of_node,
                blocks,
                rhs,
                abs_tol,
                (settings.forcing, settings.two_level_max_iterations),
                reuse,
                timings,
            ),
        }
    }
}

pub(super) enum StepFail {
    Inverted,
    NoConvergence,
}

/// Sizes and times of one symbolic and one numeric Cholesky of a problem's tangent at rest.
#[derive(Clone, Debug, Serialize)]
pub struct FactorizationProfile {
    /// Ordering used.
    pub ordering: FillOrdering,
    /// Free DOFs.
    pub free_dofs: usize,
    /// Nonzeros of the (upper) tangent.
    pub tangent_nnz: usize,
    /// Nonzeros of the Cholesky factor.
    pub factor_nnz: usize,
    /// Ordering and symbolic analysis (s).
    pub symbolic_s: f64,
    /// Numeric factorisation (s); `None` when only the symbolic analysis was asked for.
    pub numeric_s: Option<f64>,
}

/// Factorise the tangent of `p` at rest once with `ordering` (to compare orderings on a mesh); with
/// `numeric` false, only the ordering and symbolic analysis (the factor's size, hence its memory).
pub fn factorization_profile(p: &SolidProblem, ordering: FillOrdering, numeric: bool) -> Result<FactorizationProfile> {
    let t0 = Instant::now();
    let settings = SolverSettings { ordering, linear: LinearSolver::Direct, ..Default::default() };
    let free = FreeSystem::new(p, &settings)?;
    let Linear::Direct(sys) = &free.linear else { unreachable!("direct solver asked") };
    let symbolic_s = t0.elapsed().as_secs_f64();
    if !numeric {
        return Ok(FactorizationProfile {
            ordering,
            free_dofs: sys.n,
            tangent_nnz: free.tangent_nnz,
            factor_nnz: sys.factor_nnz(),
            symbolic_s,
            numeric_s: None,
        });
    }
    let u = vec![0.0; 3 * p.mesh.n_nodes()];
    let a = p.assemble(&u, true).ok_or_else(|| FemError::Solver("the rest state has an inverted element".into()))?;
    let blocks = a.blocks.as_ref().ok_or_else(|| FemError::Solver("no tangent assembled".into()))?;
    let mut vals = sys.values(blocks);
    let mut t = Timings::default();
    sys.factor(&mut vals, &mut t)?;
    Ok(FactorizationProfile {
        ordering,
        free_dofs: sys.n,
        tangent_nnz: free.tangent_nnz,
        factor_nnz: sys.factor_nnz(),
        symbolic_s,
        numeric_s: Some(t.factorization_s),
    })
}

/// Solve the quasi-static problem by `settings.steps` load increments (tractions, forces, body
/// force and prescribed displacements all ramped by the load factor t = k / steps).
pub fn solve(p: &SolidProblem, settings: &SolverSettings) -> Result<Solution> {
    LoadPath::one_shot(p, settings)?.solve_at(1.0)
}

fn free_residual(p: &SolidProblem, sys: &FreeSystem, fint: &[f64], t: f64) -> (Vec<f64>, f64) {
    let mut r = vec![0.0; sys.n];
    let mut react = 0.0;
    let fe = p.external_force();
    for (i, &f) in sys.free_of_node.iter().enumerate() {
        for c in 0..3 {
            let v = fint[3 * i + c] - t * fe[3 * i + c];
            if f == usize::MAX {
                react += v * v;
            } else {
                r[3 * f + c] = v;
            }
        }
    }
    (r, react.sqrt())
}

pub(super) type StepOut = std::result::Result<(Vec<f64>, StepReport), StepFail>;

#[allow(clippy::too_many_arguments)] // the reused factor and the timings are the step's running state
pub(super) fn newton_step(
    p: &SolidProblem,
    sys: &FreeSystem,
    u0: &[f64],
    t0: f64,
    t1: f64,
    settings: &SolverSettings,
    reuse: &mut Option<Factor>,
    timings: &mut Timings,
) -> StepOut {
    let nn = p.mesh.n_nodes();
    let mut u = u0.to_vec();
    let fe = p.external_force();
    let load_norm = t1 * norm(fe);
    let mut rep = StepReport {
        step: 0,
        load_factor: t1,
        iterations: 0,
        residual_history: Vec::new(),
        tolerance: 0.0,
        line_search_alphas: Vec::new(),
        shifted_iterations: 0,
        min_j: f64::NAN,
    };
    // Predictor for the prescribed-displacement increment: K_ff δ = −K_fp Δu_p (linearised at u0).
    let has_dirichlet_increment = (0..nn).any(|i| p.prescribed_value(i).is_some_and(|v| v.norm() > 0.0));
    if has_dirichlet_increment {
        let ta = Instant::now();
        let a = p.assemble(u0, true);
        timings.assembly_s += ta.elapsed().as_secs_f64();
        let Some(a) = a else { return Err(StepFail::Inverted) };
        let blocks = a.blocks.as_ref().expect("tangent asked");
        let mut rhs = vec![0.0; sys.n];
        for b in 0..nn {
            let fb = sys.free_of_node[b];
            if fb == usize::MAX {
                continue;
            }
            for pidx in p.row_ptr[b]..p.row_ptr[b + 1] {
                let a_node = p.cols[pidx];
                if let Some(v) = p.prescribed_value(a_node) {
                    let du = v * (t1 - t0);
                    for k in 0..3 {
                        for i in 0..3 {
                            rhs[3 * fb + k] -= blocks[9 * pidx + 3 * k + i] * du[i];
                        }
                    }
                }
            }
        }
        let tol = 0.1 * settings.rel_tol * load_norm;
        if sys.direction(p, blocks, &mut rhs, tol, settings, reuse, timings).is_err() {
            return Err(StepFail::NoConvergence);
        }
        for (i, &f) in sys.free_of_node.iter().enumerate() {
            for c in 0..3 {
                if f == usize::MAX {
                    u[3 * i + c] = t1 * p.prescribed_value(i).expect("prescribed")[c];
                } else {
                    u[3 * i + c] += rhs[3 * f + c];
                }
            }
        }
    }
    // Line-search trials rejected because an element inverted (J ≤ 0): a failed increment that met
    // some is reported as inversion.
    let mut inverted_trials = 0usize;
    for it in 0..=settings.max_newton {
        let ta = Instant::now();
        let a = p.assemble(&u, true);
        timings.assembly_s += ta.elapsed().as_secs_f64();
        let Some(a) = a else { return Err(StepFail::Inverted) };
        let (r, react) = free_residual(p, sys, &a.internal_force, t1);
        let rn = norm(&r);
        rep.residual_history.push(rn);
        let tol = settings.rel_tol * load_norm.max(react);
        rep.tolerance = tol;
        if rn <= tol || rn == 0.0 {
            rep.iterations = it;
            rep.min_j = a.min_j;
            return Ok((u, rep));
        }
        if it == settings.max_newton {
            break;
        }
        let wext: f64 = fe.iter().zip(&u).map(|(f, x)| f * x).sum();
        let pi0 = a.strain_energy - t1 * wext;
        // d = −K⁻¹ r
        let mut d: Vec<f64> = r.iter().map(|x| -x).collect();
        match sys.direction(p, a.blocks.as_ref().expect("tangent asked"), &mut d, 0.1 * tol, settings, reuse, timings) {
            Ok(shifted) => rep.shifted_iterations += usize::from(shifted),
            Err(_) => return Err(StepFail::NoConvergence),
        }
        let slope: f64 = r.iter().zip(&d).map(|(a, b)| a * b).sum(); // ∇Π·d < 0 for a descent direction
                                                                     // Backtracking line search on Π (Armijo); near convergence Π stalls at round-off, so a
                                                                     // decrease of the residual norm is accepted too.
        let mut alpha = 1.0;
        let mut accepted = false;
        let mut any_valid = false;
        let mut trial = u.clone();
        for _ in 0..30 {
            for (i, &f) in sys.free_of_node.iter().enumerate() {
                if f != usize::MAX {
                    for c in 0..3 {
                        trial[3 * i + c] = u[3 * i + c] + alpha * d[3 * f + c];
                    }
                }
            }
            let ta = Instant::now();
            let pi = p.potential_energy(&trial, t1);
            timings.assembly_s += ta.elapsed().as_secs_f64();
            if pi.is_none() {
                inverted_trials += 1;
            }
            if let Some(pi) = pi {
                any_valid = true;
                if pi <= pi0 + 1e-4 * alpha * slope {
                    accepted = true;
                    break;
                }
                if (pi - pi0).abs() <= 1e-10 * pi0.abs().max(1e-300) {
                    let ta = Instant::now();
                    let at = p.assemble(&trial, false);
                    timings.assembly_s += ta.elapsed().as_secs_f64();
                    if let Some(at) = at {
                        let (rt, _) = free_residual(p, sys, &at.internal_force, t1);
                        if norm(&rt) < rn {
                            accepted = true;
                            break;
                        }
                    }
                }
            }
            alpha *= 0.5;
        }
        if !accepted {
            return Err(if any_valid && inverted_trials == 0 { StepFail::NoConvergence } else { StepFail::Inverted });
        }
        rep.line_search_alphas.push(alpha);
        u = trial;
        rep.iterations = it + 1;
    }
    Err(if inverted_trials == 0 { StepFail::NoConvergence } else { StepFail::Inverted })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solid::{Loads, Quadrature, Tet10Mesh};
    use crate::NeoHookean;
    use laparo_core::mesh::TetMesh;

    fn one_tet() -> SolidProblem {
        let v = vec![
            Vector3::zeros(),
            Vector3::new(10.0, 0.0, 0.0),
            Vector3::new(0.0, 10.0, 0.0),
            Vector3::new(1.0, 2.0, 10.0),
        ];
        let m = Tet10Mesh::from_linear(&TetMesh::new(v, vec![[0, 1, 2, 3]]).unwrap()).unwrap();
        let fixed = SolidProblem::fixed_vertices(&m, &[0, 1, 2]).unwrap();
        SolidProblem::new(m, NeoHookean::liver(), &fixed, &Loads::default(), Quadrature::Degree2).unwrap()
    }

    #[test]
    fn cholesky_solves_the_free_system_and_shifts_an_indefinite_one() {
        let p = one_tet();
        let free = FreeSystem::new(&p, &SolverSettings { linear: LinearSolver::Direct, ..Default::default() }).unwrap();
        let Linear::Direct(sys) = &free.linear else { panic!("direct asked") };
        assert_eq!(sys.n, 12, "vertex 3 and three mid-edge nodes are free");
        assert_eq!(free.tangent_nnz, sys.src.len());
        let u = vec![0.0; 3 * p.mesh.n_nodes()];
        let kd = p.tangent_dense(&u).unwrap();
        let a = p.assemble(&u, true).unwrap();
        let vals = sys.values(a.blocks.as_ref().unwrap());
        let rhs: Vec<f64> = (0..sys.n).map(|i| (i as f64 * 0.7).sin()).collect();
        let mut x = rhs.clone();
        let mut t = Timings::default();
        let mut reuse = None;
        assert!(
            !sys.solve_reusing(&mut vals.clone(), &mut x, 0.0, (1e-4, 30), &mut reuse, &mut t).unwrap(),
            "SPD: no shift"
        );
        assert!(reuse.is_some(), "an unshifted factor is kept for reuse");
        // K_ff x = rhs with the dense tangent restricted to the free DOFs.
        let free: Vec<usize> = (0..p.mesh.n_nodes())
            .filter(|&i| !p.is_prescribed(i))
            .flat_map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
            .collect();
        for (r, &gi) in free.iter().enumerate() {
            let kx: f64 = free.iter().enumerate().map(|(c, &gj)| kd[(gi, gj)] * x[c]).sum();
            assert!((kx - rhs[r]).abs() < 1e-9 * (1.0 + rhs[r].abs()), "row {r}: {kx} vs {}", rhs[r]);
        }
        // Negative definite K − 2 max|K_ii| I: the shift makes it positive definite, giving a
        // direction along the right-hand side.
        let dmax = sys.diag.iter().map(|&d| vals[d].abs()).fold(0.0, f64::max);
        let mut neg = vals.clone();
        for &d in &sys.diag {
            neg[d] -= 2.0 * dmax;
        }
        let mut y = rhs.clone();
        let mut none = None;
        assert!(
            sys.solve_reusing(&mut neg, &mut y, 0.0, (1e-4, 30), &mut none, &mut t).unwrap(),
            "indefinite: shifted"
        );
        assert!(none.is_none(), "a shifted factor is not kept");
        assert!(rhs.iter().zip(&y).map(|(a, b)| a * b).sum::<f64>() > 0.0);
        // Reuse: the factor of K preconditions conjugate gradients on another SPD tangent
        // K' = K + 0.3 diag(K); the residual meets the forcing term without a new factorisation.
        let mut other = vals.clone();
        for &d in &sys.diag {
            other[d] *= 1.3;
        }
        let f0 = t.factorizations;
        let mut z = rhs.clone();
        assert!(!sys.solve_reusing(&mut other.clone(), &mut z, 0.0, (1e-4, 30), &mut reuse, &mut t).unwrap());
        assert_eq!(t.factorizations, f0, "no new factorisation");
        assert!(t.pcg_iterations > 0);
        let mut kz = vec![0.0; sys.n];
        sys.product(&other, &z, &mut kz);
        let res: f64 = kz.iter().zip(&rhs).map(|(a, b)| (a - b) * (a - b)).sum::<f64>().sqrt();
        assert!(res <= 1e-4 * norm(&rhs) * (1.0 + 1e-12), "PCG residual {res}");
        // the symmetric product equals the dense tangent's
        let mut kx = vec![0.0; sys.n];
        sys.product(&vals, &x, &mut kx);
        for (a, b) in kx.iter().zip(&rhs) {
            assert!((a - b).abs() < 1e-9 * (1.0 + b.abs()));
        }
    }
}
