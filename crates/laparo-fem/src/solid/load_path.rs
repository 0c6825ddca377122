//! Solves of one problem at several load factors, each from the nearest equilibrium reached before.
//!
//! Calibrating a load (the benchmark's crack pressure, §5.4.2) solves one problem at a sequence of load
//! factors. Quasi-static hyperelastic equilibrium does not depend on the path that reached it, so a solve
//! at load factor T may start from any converged state at t ≤ T instead of from rest: [`LoadPath`] keeps
//! the equilibria of its increments and starts each solve from the highest one not above T, with
//! increments of T / `steps` (as a solve from rest would take). The solution meets the same residual
//! tolerance, so it agrees with a solve from rest to that tolerance.
use super::linear::Factor;
use super::newton::{newton_step, FreeSystem, Solution, SolverSettings, StepFail, Timings};
use super::problem::SolidProblem;
use crate::error::{FemError, Result};
use nalgebra::Vector3;
use std::time::Instant;

/// A quasi-static problem solved at several load factors (see the module docs).
///
/// ```
/// use laparo_fem::solid::{LoadPath, Loads, NodalForce, Quadrature, SolidProblem, SolverSettings, Tet10Mesh};
/// use laparo_fem::{mesh::shapes::kuhn_box, NeoHookean};
/// use nalgebra::Vector3;
///
/// let m = Tet10Mesh::from_linear(&kuhn_box([2, 2, 2], 10.0)).unwrap();
/// let bottom: Vec<usize> = (0..m.n_vertices).filter(|&i| m.nodes[i].z < 1e-9).collect();
/// let top = (0..m.n_vertices).find(|&i| m.nodes[i].z > 19.0).unwrap();
/// let fixed = SolidProblem::fixed_vertices(&m, &bottom).unwrap();
/// let loads = Loads { nodal_forces: vec![NodalForce { node: top, force_mn: Vector3::new(0.0, 0.0, 5.0) }], ..Default::default() };
/// let p = SolidProblem::new(m, NeoHookean::liver(), &fixed, &loads, Quadrature::Degree2).unwrap();
/// let mut path = LoadPath::new(&p, &SolverSettings { steps: 4, ..Default::default() }).unwrap();
/// let full = path.solve_at(1.0).unwrap(); // 4 increments from rest
/// let half = path.solve_at(0.5).unwrap(); // the stored state at t = 0.5: no increment to take
/// assert!(half.max_displacement_mm < full.max_displacement_mm);
/// ```
pub struct LoadPath<'p> {
    problem: &'p SolidProblem,
    settings: SolverSettings,
    sys: FreeSystem,
    /// Converged states (load factor, 3 displacement components per node, mm), by increasing load
    /// factor; rest (0, zeros) first.
    states: Vec<(f64, Vec<f64>)>,
    /// Keep the states of the increments (false: a single solve from rest needs none).
    keep_states: bool,
    reuse: Option<Factor>,
    /// Symbolic set-up time not yet reported (added to the next solve's timings).
    pending_symbolic_s: f64,
}

impl<'p> LoadPath<'p> {
    /// Set up the free DOFs and the linear solver of `problem` (once for every solve). Memory: one
    /// displacement vector (3 × nodes × 8 bytes) per converged increment.
    pub fn new(problem: &'p SolidProblem, settings: &SolverSettings) -> Result<Self> {
        Self::build(problem, settings, true)
    }

    pub(super) fn one_shot(problem: &'p SolidProblem, settings: &SolverSettings) -> Result<Self> {
        Self::build(problem, settings, false)
    }

    fn build(problem: &'p SolidProblem, settings: &SolverSettings, keep_states: bool) -> Result<Self> {
        if settings.steps == 0 {
            return Err(FemError::param("steps", 0.0, "must be ≥ 1"));
        }
        if !(settings.rel_tol > 0.0 && settings.rel_tol < 1.0) {
            return Err(FemError::param("rel_tol", settings.rel_tol, "must lie in (0, 1)"));
        }
        let t0 = Instant::now();
        let sys = FreeSystem::new(problem, settings)?;
        Ok(Self {
            problem,
            settings: *settings,
            sys,
            states: vec![(0.0, vec![0.0; 3 * problem.mesh.n_nodes()])],
            keep_states,
            reuse: None,
            pending_symbolic_s: t0.elapsed().as_secs_f64(),
        })
    }

    /// Converged states stored so far (rest included).
    pub fn stored_states(&self) -> usize {
        self.states.len()
    }

    /// Equilibrium at load factor `load_factor` (> 0; every load and prescribed displacement scaled by
    /// it), from the highest stored state not above it, by increments of `load_factor / steps`, each
    /// halved on inversion or divergence as in [`super::solve`]. The solution's steps and timings are
    /// this solve's.
    pub fn solve_at(&mut self, load_factor: f64) -> Result<Solution> {
        if !(load_factor.is_finite() && load_factor > 0.0) {
            return Err(FemError::param("load_factor", load_factor, "must be finite and > 0"));
        }
        let t_start = Instant::now();
        let mut timings = Timings { symbolic_s: std::mem::take(&mut self.pending_symbolic_s), ..Default::default() };
        let target = load_factor;
        let (t_from, u_from) =
            self.states.iter().rev().find(|(t, _)| *t <= target * (1.0 + 1e-12)).expect("rest is stored");
        let from_rest = *t_from == 0.0;
        let mut t = *t_from;
        let mut u = u_from.clone();
        let n_inc = ((target - t) / (target / self.settings.steps as f64) - 1e-9).ceil().max(0.0) as usize;
        let mut steps = Vec::new();
        if n_inc == 0 {
            // A stored equilibrium at the target: one Newton check reports it (0 iterations when converged).
            let (u_new, mut rep) =
                newton_step(self.problem, &self.sys, &u, target, target, &self.settings, &mut self.reuse, &mut timings)
                    .map_err(|f| self.failure(f, 1, target, 0))?;
            rep.step = 1;
            steps.push(rep);
            u = u_new;
            t = target;
        }
        let t_base = t;
        let dt0 = if n_inc > 0 { (target - t_base) / n_inc as f64 } else { 0.0 };
        let mut dt = dt0;
        let mut cuts = 0;
        let mut step_idx = 1;
        while t < target - 1e-12 * target {
            let t_new = if t + dt > target - 1e-12 * target { target } else { t + dt };
            match newton_step(self.problem, &self.sys, &u, t, t_new, &self.settings, &mut self.reuse, &mut timings) {
                Ok((u_new, mut rep)) => {
                    u = u_new;
                    t = t_new;
                    rep.step = step_idx;
                    steps.push(rep);
                    let k = (t - t_base) / dt0;
                    if (k - k.round()).abs() < 1e-9 {
                        step_idx = k.round() as usize + 1;
                    }
                    dt = (dt * 2.0).min(dt0);
                    if self.keep_states {
                        self.store(t, &u);
                    }
                }
                Err(fail) => {
                    cuts += 1;
                    if cuts > self.settings.max_cuts || dt < dt0 / 1024.0 {
                        return Err(self.failure(fail, step_idx, t_new, cuts - 1));
                    }
                    dt *= 0.5;
                }
            }
        }
        timings.newton_iterations = steps.iter().map(|s| s.iterations).sum();
        if from_rest && timings.newton_iterations == 0 {
            // From rest, the first residual is the load on the free nodes: non-zero means Newton must move.
            let first = steps.first().and_then(|s| s.residual_history.first().map(|&r| (r, s.tolerance)));
            if let Some((free_load_mn, tolerance_mn)) = first.filter(|&(r, _)| r > 0.0) {
                return Err(FemError::NoNewtonStep { free_load_mn, tolerance_mn });
            }
        }
        let nn = self.problem.mesh.n_nodes();
        let displacement: Vec<Vector3<f64>> =
            (0..nn).map(|i| Vector3::new(u[3 * i], u[3 * i + 1], u[3 * i + 2])).collect();
        let min_j = steps.last().map_or(1.0, |s| s.min_j);
        timings.total_s = t_start.elapsed().as_secs_f64() + timings.symbolic_s;
        Ok(Solution {
            max_displacement_mm: displacement.iter().map(|d| d.norm()).fold(0.0, f64::max),
            displacement,
            n_vertices: self.problem.mesh.n_vertices,
            free_dofs: self.sys.n,
            tangent_nnz: self.sys.tangent_nnz,
            factor_nnz: self.sys.factor_nnz(),
            linear_solver: self.sys.solver_name(),
            steps,
            min_j,
            timings,
        })
    }

    fn store(&mut self, t: f64, u: &[f64]) {
        let at = self.states.partition_point(|(s, _)| *s < t);
        if self.states.get(at).is_some_and(|(s, _)| *s == t) {
            self.states[at].1.copy_from_slice(u);
        } else {
            self.states.insert(at, (t, u.to_vec()));
        }
    }

    fn failure(&self, fail: StepFail, step_idx: usize, t_new: f64, cuts: usize) -> FemError {
        FemError::Solver(match fail {
            StepFail::Inverted => format!(
                "tractions invert elements at step {step_idx} (load factor {t_new:.4}): J ≤ 0 at quadrature points persists after {cuts} step cuts"
            ),
            StepFail::NoConvergence => {
                let hint = match self.sys.solver_name() {
                    "two-level" => format!(
                        "; its directions came from the two-level solver: the direct solver, or a tolerance looser than \
                         {:e}, may converge",
                        self.settings.rel_tol
                    ),
                    _ => String::new(),
                };
                format!(
                    "Newton does not converge at step {step_idx} (load factor {t_new:.4}) after {cuts} step cuts{hint}"
                )
            }
        })
    }
}
