//! Optimisers of the RODS problem (eqs. 5.8–5.9): find the initial particle velocities v₀ (and
//! optionally E) that bring the simulated landmarks onto their targets after T steps.
//!
//! * [`OptimizerKind::Lbfgs`] (default): v₀ = v_warm + S θ with the Gaussian preconditioner S
//!   ([`crate::smoothing`]), L-BFGS on θ with an Armijo backtracking line search; every trial step is
//!   capped to a physical displacement (max |Δv₀|·T·Δt ≤ `max_step_dx`·Δx). Optionally a strong Wolfe
//!   line search ([`LineSearch::StrongWolfe`]) and a distance-smoothing continuation (`epsilon_ratio`:
//!   √(d² + ε²) − ε with ε following the residual down to 0; the reported loss stays eq. 5.10), both
//!   used by [`OptimizerConfig::tear`] for targets that pull adjacent particles apart.
//! * [`OptimizerKind::Adam`]: Adam on θ with the same cap, a rejected step halves the rate.
//! * [`OptimizerKind::ThesisGd`]: the thesis' plain gradient descent on raw v₀ from v₀ = 0 (eq. 5.9),
//!   α₀ then ×`thesis_decay` (0.5) whenever a step would raise the loss (the thesis states "initial lr
//!   25, decay 0.5, 500 iterations" without the schedule or units; α₀ defaults to the step that moves
//!   the fastest particle by `max_step_dx`·Δx).
//!
//! Joint identification of E (`joint_youngs_modulus`) optimises φ = ln(E/E₀) with θ. One deformed
//! snapshot identifies E poorly (v₀ and E trade off: a stiffer body with faster initial velocities
//! reaches the same shape), so treat the recovered E as a by-product, not a measurement (§5.5).
use crate::error::{RegisterError, Result};
use crate::loss::RegistrationLoss;
use crate::smoothing::Smoother;
use laparo_mpm::{simulate_with_gradient_in, GradientWorkspace, ParticleState, Scene, Vector};
use std::time::Instant;

/// Which optimiser.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum OptimizerKind {
    /// Preconditioned L-BFGS with line search (default).
    Lbfgs,
    /// Preconditioned Adam with backtracking.
    Adam,
    /// The thesis' gradient descent from v₀ = 0 (no preconditioning).
    ThesisGd,
}

/// Optimiser settings (lengths in units of the grid cell Δx).
#[derive(Clone, Debug, serde::Serialize)]
pub struct OptimizerConfig {
    /// Optimiser.
    pub kind: OptimizerKind,
    /// Maximum number of iterations (accepted steps).
    pub iterations: usize,
    /// σ of the Gaussian preconditioner in Δx (0 = none).
    pub smoothing_dx: f64,
    /// Largest landmark displacement per step, |Δv₀|·T·Δt, in Δx.
    pub max_step_dx: f64,
    /// Stop when the loss fell by less than this fraction over `patience` iterations.
    pub rel_tol: f64,
    /// Window of the relative-decrease test.
    pub patience: usize,
    /// Stop when the mean landmark distance (eq. 5.10, unsmoothed) is at most this (length units).
    pub target_mean_distance: f64,
    /// Thesis GD: initial step α₀ (None = from `max_step_dx`).
    pub thesis_lr: Option<f64>,
    /// Thesis GD: step factor after a rejected step.
    pub thesis_decay: f64,
    /// L-BFGS memory.
    pub lbfgs_memory: usize,
    /// Line search: maximum halvings.
    pub max_backtracks: usize,
    /// Also optimise E (log-parameterised).
    pub joint_youngs_modulus: bool,
    /// Line search of L-BFGS.
    pub line_search: LineSearch,
    /// Distance-smoothing continuation κ: optimise Σ √(d² + ε²) − ε with ε = κ × the current mean
    /// landmark distance (eq. 5.10), lowered as the residual falls (ε → 0); 0 = off. The reported loss
    /// stays eq. 5.10.
    pub epsilon_ratio: f64,
    /// Strong Wolfe curvature constant c₂ (0.9: quasi-Newton; smaller: closer to an exact line search).
    pub wolfe_c2: f64,
    /// Least-action prior κ (0 = off, the thesis: no regulariser): adds
    /// κ · mean_p |v₀,p T Δt|² / (2 Δx) over the free particles to eq. 5.10, the initial kinetic energy
    /// written as the ballistic displacement v₀ T Δt (length units). Among the initial velocities that
    /// bring the landmarks equally close it prefers the one that moves the least tissue.
    pub kinetic_weight: f64,
    /// At-rest prior λ (L2 of the RODS-MPM ladder; 0 = off): adds the terminal kinetic energy
    /// λ · Σ_p m_p |v_T,p T Δt|² / (2 M Δx) (M: free mass) to the objective — λ Δx KE(T)/KE_ref with
    /// KE_ref = ½ M (Δx / T Δt)², the energy of the body moving one cell over the horizon — so that the
    /// registered state is a shape at rest, not a snapshot of a swing (adjoint terminal condition
    /// v̄_T = λ m v_T (T Δt)² / (M Δx)).
    pub terminal_kinetic_weight: f64,
    /// With a two-field grid (`Scene::crack_side`), blur the gradient within each side of the crack and the
    /// uncut material, never across it ([`Smoother::with_sides`]; L1 of the ladder). Without a crack: no effect.
    pub side_aware_smoothing: bool,
    /// What the optimiser solves for (§5.3.1 allows any unknown state): v₀ (the thesis, default) or a
    /// time-constant load (L3 of the ladder).
    pub unknown: Unknown,
}

/// The unknown state q of RODS-MPM (§5.3.1).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Unknown {
    /// The initial velocities v₀ (the thesis).
    InitialVelocity,
    /// A time-constant force density on the particles a crack labels (`Scene::crack_side` ≠ 0, the band around
    /// Σ; every free particle without a crack), projected to zero net force (self-equilibrated), with v₀ = 0
    /// and mass-proportional damping ζ = `damping_per_horizon` / (T Δt) so that x_T is an equilibrium under the
    /// loads. The least-action prior κ becomes an L2 prior on the loads: κ · mean |a (T Δt)²/2|² / (2 Δx) over
    /// the band, a = f / m (the displacement the load alone would give over the horizon).
    Loads {
        /// ζ T Δt: damping over the horizon (≈ 10: the slowest modes the horizon resolves come to rest).
        damping_per_horizon: f64,
    },
}

/// ζ T Δt of [`Unknown::Loads`] unless a caller says otherwise, fixed a priori (not tuned): underdamped modes
/// lose e^{-5} of their amplitude over the horizon.
pub const DEFAULT_DAMPING_PER_HORIZON: f64 = 10.0;

impl Unknown {
    /// The names `laparo register --unknown` and Python's `unknown=` take: `velocity` (v₀, the thesis) and
    /// `loads`.
    pub const NAMES: [&'static str; 2] = ["velocity", "loads"];
    /// The unknown of a name in [`Unknown::NAMES`]; `damping_per_horizon` (ζ T Δt) is used by `loads`.
    pub fn from_name(name: &str, damping_per_horizon: f64) -> Result<Unknown> {
        match name {
            "velocity" => Ok(Unknown::InitialVelocity),
            "loads" => {
                if !(damping_per_horizon >= 0.0 && damping_per_horizon.is_finite()) {
                    return Err(RegisterError::param(
                        "damping_per_horizon",
                        damping_per_horizon,
                        "must be finite and >= 0",
                    ));
                }
                Ok(Unknown::Loads { damping_per_horizon })
            }
            other => {
                Err(RegisterError::bad("unknown", format!("`{other}`: expected one of {}", Unknown::NAMES.join(", "))))
            }
        }
    }
    /// The name of this unknown (in [`Unknown::NAMES`]).
    pub fn name(&self) -> &'static str {
        match self {
            Unknown::InitialVelocity => "velocity",
            Unknown::Loads { .. } => "loads",
        }
    }
}

/// Energies of a registered run (scene units: the organ's mass × length² / time²), the audit every RODS-MPM
/// run reports: what the initial velocities (and the loads, when they are the unknown) put in, what is still
/// moving at T, what is stored elastically, and the rest (dissipated by damping and the grid transfers, or
/// absorbed by held particles).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct EnergyAudit {
    /// Kinetic energy of v₀, Σ ½ m |v₀|².
    pub kinetic_initial: f64,
    /// Kinetic energy at T, Σ ½ m |v_T|².
    pub kinetic_final: f64,
    /// Elastic energy at T, Σ V ψ(F_T).
    pub elastic_final: f64,
    /// Work of the constant loads over the run, Σ f_p · (x_T − x_0) (0 when v₀ is the unknown).
    #[serde(default)]
    pub external_work: f64,
    /// KE(0) + Ψ(0) + W − KE(T) − Ψ(T): lost to damping, the transfers' numerical dissipation and the held
    /// particles.
    pub dissipated: f64,
}

impl EnergyAudit {
    /// The audit of a run from `scene` (with its v₀) to `final_state`.
    pub fn of<const D: usize>(scene: &Scene<D>, final_state: &ParticleState<D>) -> Self {
        let d0 = laparo_mpm::diagnostics(scene, &ParticleState::initial(scene));
        let d1 = laparo_mpm::diagnostics(scene, final_state);
        EnergyAudit {
            kinetic_initial: d0.kinetic_energy,
            kinetic_final: d1.kinetic_energy,
            elastic_final: d1.elastic_energy,
            external_work: 0.0,
            dissipated: d0.kinetic_energy + d0.elastic_energy - d1.kinetic_energy - d1.elastic_energy,
        }
    }
    /// Add the work of constant loads `forces` (per particle) moving the particles from `x0` to `x_t`.
    pub fn with_load_work<const D: usize>(mut self, forces: &[Vector<D>], x0: &[Vector<D>], x_t: &[Vector<D>]) -> Self {
        let w: f64 = forces.iter().zip(x0.iter().zip(x_t)).map(|(f, (a, b))| f.dot(&(b - a))).sum();
        self.external_work += w;
        self.dissipated += w;
        self
    }
    /// KE(T) / KE(0) (0 when nothing moved).
    pub fn kinetic_ratio(&self) -> f64 {
        if self.kinetic_initial > 0.0 {
            self.kinetic_final / self.kinetic_initial
        } else {
            0.0
        }
    }
    /// One line for notes and logs.
    pub fn note(&self) -> String {
        format!(
            "energy audit: KE(0) {:.4e}, KE(T) {:.4e} ({:.1} % of KE(0)), elastic at T {:.4e}, load work {:.4e}, dissipated {:.4e}",
            self.kinetic_initial,
            self.kinetic_final,
            100.0 * self.kinetic_ratio(),
            self.elastic_final,
            self.external_work,
            self.dissipated
        )
    }
}

/// Line search along an L-BFGS direction.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum LineSearch {
    /// Armijo backtracking (halving) from the unit step.
    Backtracking,
    /// Strong Wolfe conditions (Nocedal & Wright Alg. 3.5/3.6: extrapolation, then zoom by cubic
    /// interpolation).
    StrongWolfe,
}

/// The names [`OptimizerConfig::preset`] accepts.
pub const PRESET_NAMES: [&str; 4] = ["lbfgs", "tear", "adam", "thesis-gd"];

impl Default for OptimizerConfig {
    fn default() -> Self {
        OptimizerConfig {
            kind: OptimizerKind::Lbfgs,
            iterations: 50,
            smoothing_dx: 2.0,
            max_step_dx: 0.5,
            rel_tol: 1e-4,
            patience: 5,
            target_mean_distance: 0.0,
            thesis_lr: None,
            thesis_decay: 0.5,
            lbfgs_memory: 10,
            max_backtracks: 10,
            joint_youngs_modulus: false,
            line_search: LineSearch::Backtracking,
            epsilon_ratio: 0.0,
            wolfe_c2: 0.9,
            kinetic_weight: 0.0,
            terminal_kinetic_weight: 0.0,
            side_aware_smoothing: true,
            unknown: Unknown::InitialVelocity,
        }
    }
}

impl OptimizerConfig {
    /// The thesis mode: gradient descent, 500 iterations, decay 0.5.
    pub fn thesis() -> Self {
        OptimizerConfig { kind: OptimizerKind::ThesisGd, iterations: 500, smoothing_dx: 0.0, ..Default::default() }
    }

    /// Preset for targets that tear adjacent particles apart (the thesis 3D box: two neighbouring rows,
    /// 0.5 Δx apart, pushed apart by ±1.2 Δx). Unsmoothed (σ = 0: any smoothing over ≥ 0.5 Δx gives both
    /// lips one velocity), step cap 16 Δx, strong Wolfe line search with c₂ = 0.1 (close to an exact line
    /// search: the unsquared distances of eq. 5.10 make unit quasi-Newton steps poor) and the
    /// distance-smoothing continuation ε = 0.5 × the mean landmark distance.
    pub fn tear() -> Self {
        OptimizerConfig {
            smoothing_dx: 0.0,
            max_step_dx: 16.0,
            line_search: LineSearch::StrongWolfe,
            wolfe_c2: 0.1,
            epsilon_ratio: 0.5,
            ..Default::default()
        }
    }
    /// The preset of an optimiser name, as `laparo register --optimizer` and the Python package take
    /// it: `lbfgs` ([`Default`]), `tear` ([`Self::tear`]), `adam` (the default settings with Adam) or
    /// `thesis-gd` ([`Self::thesis`]); `None` for any other name (see [`PRESET_NAMES`]).
    pub fn preset(name: &str) -> Option<Self> {
        Some(match name {
            "lbfgs" => Self::default(),
            "tear" => Self::tear(),
            "adam" => OptimizerConfig { kind: OptimizerKind::Adam, ..Self::default() },
            "thesis-gd" => Self::thesis(),
            _ => return None,
        })
    }
}

/// One accepted iteration.
#[derive(Clone, Debug, serde::Serialize)]
pub struct IterationRecord {
    /// Iteration (0 = the starting point).
    pub iteration: usize,
    /// Loss as given (eq. 5.10 for unit weights and ε = 0), at the accepted point.
    pub loss: f64,
    /// Objective as optimised (with the continuation's ε; equals `loss` without continuation).
    pub objective: f64,
    /// ε of the distance-smoothing continuation (length units).
    pub epsilon: f64,
    /// Mean landmark distance (eq. 5.10, unsmoothed, length units).
    pub mean_distance: f64,
    /// Young's modulus.
    pub youngs_modulus: f64,
    /// Landmark-displacement size of the accepted step (length units).
    pub step: f64,
    /// Simulations (forward + backward) so far.
    pub evaluations: usize,
    /// Wall time so far (s).
    pub seconds: f64,
}

/// Result of [`register`].
pub struct Registration<const D: usize> {
    /// Optimised initial velocities v₀.
    pub velocities: Vec<Vector<D>>,
    /// Young's modulus (changed only with joint identification).
    pub youngs_modulus: f64,
    /// Accepted iterations (first = start).
    pub history: Vec<IterationRecord>,
    /// Final particle state of the best v₀.
    pub final_state: ParticleState<D>,
    /// Why the optimiser stopped.
    pub stop_reason: String,
    /// Energies from v₀ to the final state (with loads: the work they did is not counted; `dissipated` is
    /// then KE(0) − KE(T) − Ψ(T), negative by the work of the loads).
    pub energy: EnergyAudit,
    /// The optimised loads per particle (scene force units) when they were the unknown ([`Unknown::Loads`]).
    pub loads: Option<Vec<Vector<D>>>,
}

struct Eval<const D: usize> {
    /// Objective as optimised (active ε).
    loss: f64,
    /// The caller's loss (eq. 5.10) at the same state.
    reported: f64,
    grad: Vec<f64>,
    state: ParticleState<D>,
}

struct Problem<'a, const D: usize> {
    scene: Scene<D>,
    /// The caller's loss.
    user: &'a RegistrationLoss<D>,
    /// The loss optimised (the caller's with the continuation's ε).
    loss: RegistrationLoss<D>,
    smoother: Option<Smoother<D>>,
    warm: Vec<Vector<D>>,
    e0: f64,
    joint: bool,
    /// Least-action prior κ ([`OptimizerConfig::kinetic_weight`]).
    kinetic: f64,
    /// Per-particle coefficient c_p of the at-rest prior ½ Σ c_p |v_T,p|² (empty = off).
    terminal: Vec<f64>,
    /// Loads as the unknown: the particles that carry them (empty = v₀ is the unknown).
    band: Vec<bool>,
    ws: GradientWorkspace<D>,
    evaluations: usize,
}

fn flat<const D: usize>(v: &[Vector<D>]) -> Vec<f64> {
    v.iter().flat_map(|x| x.iter().copied().collect::<Vec<_>>()).collect()
}

fn unflat<const D: usize>(x: &[f64], n: usize) -> Vec<Vector<D>> {
    (0..n).map(|p| Vector::<D>::from_fn(|d, _| x[p * D + d])).collect()
}

impl<const D: usize> Problem<'_, D> {
    fn n(&self) -> usize {
        self.scene.n_particles()
    }
    /// Velocity change of a parameter change (S applied).
    fn loads(&self) -> bool {
        !self.band.is_empty()
    }
    /// Velocity change (or, with loads, the force field) of a parameter change: S applied, and with loads
    /// restricted to the band and projected to zero net force, f = P S x (P f = f − m Σ_band f / M_band).
    fn dv(&self, dx: &[f64]) -> Vec<Vector<D>> {
        let d = unflat::<D>(dx, self.n());
        let mut d = match &self.smoother {
            Some(s) => s.apply(&d),
            None => d,
        };
        if self.loads() {
            let (mut total, mut mass) = (Vector::<D>::zeros(), 0.0);
            for p in 0..self.n() {
                if self.band[p] {
                    total += d[p];
                    mass += self.scene.masses[p];
                } else {
                    d[p] = Vector::<D>::zeros();
                }
            }
            for p in 0..self.n() {
                if self.band[p] {
                    d[p] -= total * (self.scene.masses[p] / mass);
                }
            }
        }
        d
    }
    /// Pᵀ of [`Self::dv`]'s projection on a force gradient: (Pᵀ g)_p = g_p − Σ_band m_q g_q / M_band on the
    /// band, 0 elsewhere.
    fn project_gradient(&self, g: &mut [Vector<D>]) {
        let (mut total, mut mass) = (Vector::<D>::zeros(), 0.0);
        for p in 0..self.n() {
            if self.band[p] {
                total += g[p] * self.scene.masses[p];
                mass += self.scene.masses[p];
            }
        }
        for p in 0..self.n() {
            g[p] = if self.band[p] { g[p] - total / mass } else { Vector::<D>::zeros() };
        }
    }
    fn eval(&mut self, x: &[f64]) -> Result<Eval<D>> {
        let dv = self.dv(x);
        if self.loads() {
            self.scene.external_forces = dv;
        } else {
            for p in 0..self.n() {
                self.scene.velocities[p] = self.warm[p] + dv[p];
            }
        }
        if self.joint {
            self.scene.material.youngs_modulus = self.e0 * x[self.n() * D].exp();
        }
        let at_rest = AtRest { inner: &self.loss, coef: &self.terminal };
        let mut g = simulate_with_gradient_in(&mut self.ws, &self.scene, &at_rest)?;
        self.evaluations += 1;
        let terminal = at_rest.value(&g.final_state.v);
        if !g.loss.is_finite() {
            return Err(RegisterError::bad("registration", "the loss became non-finite (simulation unstable)"));
        }
        let (prior, raw) = if self.loads() {
            let prior = self.load_prior(&mut g.d_external_forces);
            self.project_gradient(&mut g.d_external_forces);
            (prior, &g.d_external_forces)
        } else {
            (self.kinetic_prior(&mut g.d_velocities), &g.d_velocities)
        };
        let gv = match &self.smoother {
            Some(s) => s.apply(raw),
            None => raw.clone(),
        };
        let mut grad = flat(&gv);
        if self.joint {
            grad.push(self.scene.material.youngs_modulus * g.d_youngs_modulus);
        }
        let reported = if self.loss.epsilon == self.user.epsilon {
            g.loss - terminal
        } else {
            let mut scratch = vec![Vector::<D>::zeros(); self.n()];
            self.user.value_and_gradient(&g.final_state.x, &mut scratch)
        };
        Ok(Eval { loss: g.loss + prior, reported, grad, state: g.final_state })
    }
    /// The least-action prior κ Σ_free |v₀ T Δt|² / (2 n_free Δx) at the scene's v₀, its gradient added to
    /// `grad_v` (∂/∂v₀ = κ (T Δt)² v₀ / (n_free Δx)).
    fn kinetic_prior(&self, grad_v: &mut [Vector<D>]) -> f64 {
        if !(self.kinetic > 0.0) {
            return 0.0;
        }
        let t = self.scene.steps as f64 * self.scene.dt;
        let free = |p: usize| !self.scene.fixed.get(p).copied().unwrap_or(false);
        let n_free = (0..self.n()).filter(|&p| free(p)).count();
        if n_free == 0 {
            return 0.0;
        }
        let c = self.kinetic / (n_free as f64 * self.scene.grid.dx);
        let mut sum = 0.0;
        for (p, (v, g)) in self.scene.velocities.iter().zip(grad_v.iter_mut()).enumerate() {
            if free(p) {
                sum += (v * t).norm_squared();
                *g += v * (c * t * t);
            }
        }
        0.5 * c * sum
    }
    /// The load prior κ mean_band |a (T Δt)²/2|² / (2 Δx), a = f/m, at the scene's loads; its gradient added
    /// to `grad_f` (∂/∂f_p = κ (T Δt)⁴ a_p / (4 n_band Δx m_p)).
    fn load_prior(&self, grad_f: &mut [Vector<D>]) -> f64 {
        if !(self.kinetic > 0.0) {
            return 0.0;
        }
        let n_band = self.band.iter().filter(|&&b| b).count().max(1) as f64;
        let t = self.scene.steps as f64 * self.scene.dt;
        let h = 0.5 * t * t;
        let c = self.kinetic / (n_band * self.scene.grid.dx);
        let mut sum = 0.0;
        for p in 0..self.n() {
            if self.band[p] {
                let m = self.scene.masses[p];
                let a = self.scene.external_forces[p] / m;
                sum += (a * h).norm_squared();
                grad_f[p] += a * (c * h * h / m);
            }
        }
        0.5 * c * sum
    }
    /// Largest landmark displacement of a parameter step: |Δv|·T·Δt, or with loads |Δf|/m (T Δt)²/2.
    fn step_length(&self, dx: &[f64]) -> f64 {
        let t = self.scene.steps as f64 * self.scene.dt;
        let d = self.dv(dx);
        if self.loads() {
            (0..self.n()).map(|p| d[p].norm() / self.scene.masses[p]).fold(0.0, f64::max) * 0.5 * t * t
        } else {
            d.iter().map(|v| v.norm()).fold(0.0, f64::max) * t
        }
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Optimise v₀ (and E) of `scene` for `loss`. `warm` = starting v₀ (video warm start; None = the
/// scene's velocities for L-BFGS/Adam, zero for thesis GD). `observer` sees every accepted iteration
/// and the current v₀; returning false stops the run.
pub fn register<const D: usize>(
    scene: &Scene<D>,
    loss: &RegistrationLoss<D>,
    cfg: &OptimizerConfig,
    warm: Option<&[Vector<D>]>,
    observer: &mut dyn FnMut(&IterationRecord, &[Vector<D>]) -> bool,
) -> Result<Registration<D>> {
    register_sided(scene, loss, cfg, warm, &scene.crack_side, observer)
}

/// [`register`] with the side of a crack Σ of every particle for the side-aware preconditioner
/// ([`OptimizerConfig::side_aware_smoothing`]; e.g. `Organ::smoothing_sides`, which reach beyond the grid's
/// labelling band; empty = none).
pub fn register_sided<const D: usize>(
    scene: &Scene<D>,
    loss: &RegistrationLoss<D>,
    cfg: &OptimizerConfig,
    warm: Option<&[Vector<D>]>,
    smoothing_sides: &[i8],
    observer: &mut dyn FnMut(&IterationRecord, &[Vector<D>]) -> bool,
) -> Result<Registration<D>> {
    scene.validate()?;
    if !smoothing_sides.is_empty() && smoothing_sides.len() != scene.n_particles() {
        return Err(RegisterError::bad(
            "smoothing sides",
            format!("{} sides for {} particles", smoothing_sides.len(), scene.n_particles()),
        ));
    }
    let n = scene.n_particles();
    if loss.groups.iter().all(|g| g.particles.is_empty()) && loss.region.is_none() {
        return Err(RegisterError::bad("landmarks", "no landmark and no region term: nothing to register"));
    }
    for g in &loss.groups {
        if let Some(&p) = g.particles.iter().find(|&&p| p >= n) {
            return Err(RegisterError::bad(
                format!("landmark group `{}`", g.name),
                format!("particle index {p} >= {n}"),
            ));
        }
    }
    let check =
        |name: &str, v: f64, ok: bool| if ok { Ok(()) } else { Err(RegisterError::param(name, v, "out of range")) };
    check("max_step_dx", cfg.max_step_dx, cfg.max_step_dx > 0.0)?;
    check("smoothing_dx", cfg.smoothing_dx, cfg.smoothing_dx >= 0.0)?;
    check("thesis_decay", cfg.thesis_decay, cfg.thesis_decay > 0.0 && cfg.thesis_decay < 1.0)?;
    check("kinetic_weight", cfg.kinetic_weight, cfg.kinetic_weight >= 0.0 && cfg.kinetic_weight.is_finite())?;
    check(
        "terminal_kinetic_weight",
        cfg.terminal_kinetic_weight,
        cfg.terminal_kinetic_weight >= 0.0 && cfg.terminal_kinetic_weight.is_finite(),
    )?;
    let thesis = cfg.kind == OptimizerKind::ThesisGd;
    let warm: Vec<Vector<D>> = match warm {
        Some(w) if w.len() == n => w.to_vec(),
        Some(w) => {
            return Err(RegisterError::bad("warm start", format!("{} velocities for {n} particles", w.len())));
        }
        None if thesis => vec![Vector::<D>::zeros(); n],
        None => scene.velocities.clone(),
    };
    let dxl = scene.grid.dx;
    let sides: &[i8] = if cfg.side_aware_smoothing { smoothing_sides } else { &[] };
    let smoother =
        if thesis { None } else { Smoother::with_sides(&scene.positions, sides, cfg.smoothing_dx * dxl, dxl) };
    let joint = cfg.joint_youngs_modulus;
    let terminal = at_rest_coefficients(scene, cfg.terminal_kinetic_weight);
    let mut sim_scene = scene.clone();
    let band: Vec<bool> = match cfg.unknown {
        Unknown::InitialVelocity => Vec::new(),
        Unknown::Loads { damping_per_horizon } => {
            if !(damping_per_horizon >= 0.0 && damping_per_horizon.is_finite()) {
                return Err(RegisterError::param(
                    "damping_per_horizon",
                    damping_per_horizon,
                    "must be finite and >= 0",
                ));
            }
            if joint || thesis {
                return Err(RegisterError::bad("unknown", "loads are optimised by L-BFGS or Adam with E fixed"));
            }
            let held = |p: usize| scene.fixed.get(p).copied().unwrap_or(false);
            let cracked = scene.crack_side.iter().any(|&s| s != 0);
            let band: Vec<bool> =
                (0..n).map(|p| !held(p) && (!cracked || scene.crack_side.get(p).is_some_and(|&s| s != 0))).collect();
            if !band.iter().any(|&b| b) {
                return Err(RegisterError::bad(
                    "load band",
                    "no free particle carries a load (the band around Σ is empty)",
                ));
            }
            sim_scene.velocities = vec![Vector::<D>::zeros(); n];
            sim_scene.damping = damping_per_horizon / (scene.steps.max(1) as f64 * scene.dt);
            sim_scene.external_forces = vec![Vector::<D>::zeros(); n];
            band
        }
    };
    let warm = if band.is_empty() { warm } else { vec![Vector::<D>::zeros(); n] };
    let mut pb = Problem {
        scene: sim_scene,
        user: loss,
        loss: loss.clone(),
        smoother,
        warm,
        e0: scene.material.youngs_modulus,
        joint,
        kinetic: cfg.kinetic_weight,
        terminal,
        band,
        ws: GradientWorkspace::new(),
        evaluations: 0,
    };
    let dim = n * D + joint as usize;
    let start = Instant::now();
    let mut x = vec![0.0; dim];
    let mut cur = pb.eval(&x)?;
    let continuation = cfg.epsilon_ratio > 0.0 && !thesis;
    if continuation {
        let eps = cfg.epsilon_ratio * loss.mean_distance(&cur.state.x);
        if eps > pb.loss.epsilon {
            pb.loss.epsilon = eps;
            cur = pb.eval(&x)?;
        }
    }
    let max_step = cfg.max_step_dx * dxl;
    let mut history = Vec::new();
    let record = |it: usize, e: &Eval<D>, pb: &Problem<D>, step: f64| IterationRecord {
        iteration: it,
        loss: e.reported,
        objective: e.loss,
        epsilon: pb.loss.epsilon,
        mean_distance: loss.mean_distance(&e.state.x),
        youngs_modulus: pb.scene.material.youngs_modulus,
        step,
        evaluations: pb.evaluations,
        seconds: start.elapsed().as_secs_f64(),
    };
    let r0 = record(0, &cur, &pb, 0.0);
    let mut go_on = observer(&r0, &pb.scene.velocities);
    history.push(r0);
    let mut stop_reason = String::from("iteration limit");
    // optimiser state
    let mut mem_s: Vec<Vec<f64>> = Vec::new();
    let mut mem_y: Vec<Vec<f64>> = Vec::new();
    let mut adam_m = vec![0.0; dim];
    let mut adam_v = vec![0.0; dim];
    let mut adam_lr = 0.0;
    let mut gd_alpha = cfg.thesis_lr.unwrap_or(0.0);
    let mut it = 0;
    while go_on && it < cfg.iterations {
        if history.last().is_some_and(|r| r.mean_distance <= cfg.target_mean_distance) {
            stop_reason = "target mean distance reached".into();
            break;
        }
        if history.len() > cfg.patience && cfg.patience > 0 {
            // with the least-action prior the objective, not eq. 5.10 alone, must keep falling
            let prior = cfg.kinetic_weight > 0.0 || cfg.terminal_kinetic_weight > 0.0;
            let r = &history[history.len() - 1 - cfg.patience];
            let (old, now) = if prior { (r.objective, cur.loss) } else { (r.loss, cur.reported) };
            if old - now <= cfg.rel_tol * old.abs() {
                stop_reason = format!("relative decrease below {} over {} iterations", cfg.rel_tol, cfg.patience);
                break;
            }
        }
        if continuation {
            // ε follows the residual down to the caller's ε (eq. 5.10 in the limit)
            let eps = (cfg.epsilon_ratio * loss.mean_distance(&cur.state.x)).max(loss.epsilon);
            if eps < 0.5 * pb.loss.epsilon {
                pb.loss.epsilon = eps;
                cur = pb.eval(&x)?;
            }
        }
        let g = cur.grad.clone();
        let gnorm = dot(&g, &g).sqrt();
        if gnorm == 0.0 || !gnorm.is_finite() {
            stop_reason = "zero gradient".into();
            break;
        }
        // search direction
        let dir: Vec<f64> = match cfg.kind {
            OptimizerKind::ThesisGd => g.iter().map(|v| -v).collect(),
            OptimizerKind::Lbfgs => {
                let mut q = g.clone();
                let k = mem_s.len();
                let mut alphas = vec![0.0; k];
                for i in (0..k).rev() {
                    let rho = 1.0 / dot(&mem_y[i], &mem_s[i]);
                    alphas[i] = rho * dot(&mem_s[i], &q);
                    for (qj, yj) in q.iter_mut().zip(&mem_y[i]) {
                        *qj -= alphas[i] * yj;
                    }
                }
                if k > 0 {
                    let gamma = dot(&mem_s[k - 1], &mem_y[k - 1]) / dot(&mem_y[k - 1], &mem_y[k - 1]);
                    q.iter_mut().for_each(|v| *v *= gamma);
                }
                for i in 0..k {
                    let rho = 1.0 / dot(&mem_y[i], &mem_s[i]);
                    let beta = rho * dot(&mem_y[i], &q);
                    for (qj, sj) in q.iter_mut().zip(&mem_s[i]) {
                        *qj += (alphas[i] - beta) * sj;
                    }
                }
                let d: Vec<f64> = q.iter().map(|v| -v).collect();
                if dot(&d, &g) >= 0.0 {
                    mem_s.clear();
                    mem_y.clear();
                    g.iter().map(|v| -v).collect()
                } else {
                    d
                }
            }
            OptimizerKind::Adam => {
                let t = (it + 1) as f64;
                let (b1, b2) = (0.9f64, 0.999f64);
                for i in 0..dim {
                    adam_m[i] = b1 * adam_m[i] + (1.0 - b1) * g[i];
                    adam_v[i] = b2 * adam_v[i] + (1.0 - b2) * g[i] * g[i];
                }
                let vmax = adam_v.iter().cloned().fold(0.0, f64::max).sqrt();
                (0..dim)
                    .map(|i| {
                        let mh = adam_m[i] / (1.0 - b1.powf(t));
                        let vh = adam_v[i] / (1.0 - b2.powf(t));
                        -mh / (vh.sqrt() + 1e-8 * vmax + 1e-300)
                    })
                    .collect()
            }
        };
        // step size: physical cap
        let len = pb.step_length(&dir);
        let mut cap = if len > 0.0 { max_step / len } else { 1.0 };
        if joint {
            let de = dir[dim - 1].abs();
            if de > 0.0 {
                cap = cap.min(0.25 / de);
            }
        }
        let mut alpha = match cfg.kind {
            OptimizerKind::Lbfgs => {
                if mem_s.is_empty() {
                    cap
                } else {
                    cap.min(1.0)
                }
            }
            OptimizerKind::Adam => {
                if adam_lr == 0.0 {
                    adam_lr = cap;
                }
                adam_lr.min(cap)
            }
            OptimizerKind::ThesisGd => {
                if gd_alpha == 0.0 {
                    gd_alpha = cap;
                }
                gd_alpha
            }
        };
        let slope = dot(&g, &dir);
        let mut accepted = None;
        if cfg.kind == OptimizerKind::Lbfgs && cfg.line_search == LineSearch::StrongWolfe {
            let mut eval = |a: f64| -> Trial<(Vec<f64>, Eval<D>), RegisterError> {
                let xt: Vec<f64> = x.iter().zip(&dir).map(|(u, v)| u + a * v).collect();
                match pb.eval(&xt) {
                    Ok(e) => Ok(Some((e.loss, dot(&e.grad, &dir), (xt, e)))),
                    Err(RegisterError::Mpm(_)) => Ok(None), // left the domain
                    Err(e) => Err(e),
                }
            };
            let max_evals = 2 * cfg.max_backtracks;
            accepted = strong_wolfe(cur.loss, slope, alpha, cap.max(alpha), cfg.wolfe_c2, max_evals, &mut eval)?
                .map(|(a, (xt, e))| (xt, e, a));
        } else {
            for _ in 0..=cfg.max_backtracks {
                let xt: Vec<f64> = x.iter().zip(&dir).map(|(a, b)| a + alpha * b).collect();
                let trial = match pb.eval(&xt) {
                    Ok(e) => Some(e),
                    Err(RegisterError::Mpm(_)) => None, // left the domain: shorter step
                    Err(e) => return Err(e),
                };
                if let Some(e) = trial {
                    let ok = match cfg.kind {
                        OptimizerKind::Lbfgs => e.loss <= cur.loss + 1e-4 * alpha * slope,
                        _ => e.loss < cur.loss,
                    };
                    if ok {
                        accepted = Some((xt, e, alpha));
                        break;
                    }
                }
                alpha *= 0.5;
                match cfg.kind {
                    OptimizerKind::ThesisGd => gd_alpha *= cfg.thesis_decay,
                    OptimizerKind::Adam => adam_lr *= 0.5,
                    OptimizerKind::Lbfgs => {}
                }
            }
        }
        let Some((xt, e, alpha)) = accepted else {
            if cfg.kind == OptimizerKind::Lbfgs && !mem_s.is_empty() {
                mem_s.clear();
                mem_y.clear();
                continue;
            }
            stop_reason = "line search failed (no decrease along the search direction)".into();
            break;
        };
        if cfg.kind == OptimizerKind::Lbfgs {
            let s: Vec<f64> = xt.iter().zip(&x).map(|(a, b)| a - b).collect();
            let y: Vec<f64> = e.grad.iter().zip(&g).map(|(a, b)| a - b).collect();
            let sy = dot(&s, &y);
            if sy > 1e-12 * dot(&s, &s).sqrt() * dot(&y, &y).sqrt() {
                mem_s.push(s);
                mem_y.push(y);
                if mem_s.len() > cfg.lbfgs_memory {
                    mem_s.remove(0);
                    mem_y.remove(0);
                }
            }
        }
        let step_len = alpha * len;
        x = xt;
        cur = e;
        it += 1;
        let rec = record(it, &cur, &pb, step_len);
        // scene.velocities hold the last evaluated (= accepted) v₀
        go_on = observer(&rec, &pb.scene.velocities);
        history.push(rec);
        if !go_on {
            stop_reason = "stopped by the caller".into();
        }
    }
    if history.last().is_some_and(|r| r.mean_distance <= cfg.target_mean_distance) {
        stop_reason = "target mean distance reached".into();
    }
    // v₀ and E of the accepted point
    let dv = pb.dv(&x);
    let (velocities, loads) = if pb.loads() {
        (vec![Vector::<D>::zeros(); n], Some(dv))
    } else {
        ((0..n).map(|p| pb.warm[p] + dv[p]).collect(), None)
    };
    let youngs_modulus = if joint { pb.e0 * x[dim - 1].exp() } else { pb.e0 };
    let mut at_v0 = pb.scene.clone();
    at_v0.velocities.clone_from(&velocities);
    at_v0.material.youngs_modulus = youngs_modulus;
    let mut energy = EnergyAudit::of(&at_v0, &cur.state);
    if let Some(f) = &loads {
        energy = energy.with_load_work(f, &pb.scene.positions, &cur.state.x);
    }
    Ok(Registration { velocities, youngs_modulus, history, final_state: cur.state, stop_reason, energy, loads })
}

/// The at-rest prior's per-particle coefficients c_p = λ m_p (T Δt)² / (M Δx) (0 for held particles; empty
/// when λ = 0), so that the term is ½ Σ c_p |v_T,p|² ([`OptimizerConfig::terminal_kinetic_weight`]).
fn at_rest_coefficients<const D: usize>(scene: &Scene<D>, lambda: f64) -> Vec<f64> {
    if !(lambda > 0.0) {
        return Vec::new();
    }
    let free = |p: usize| !scene.fixed.get(p).copied().unwrap_or(false);
    let mass: f64 = (0..scene.n_particles()).filter(|&p| free(p)).map(|p| scene.masses[p]).sum();
    if !(mass > 0.0) {
        return Vec::new();
    }
    let t = scene.steps as f64 * scene.dt;
    let c = lambda * t * t / (mass * scene.grid.dx);
    (0..scene.n_particles()).map(|p| if free(p) { c * scene.masses[p] } else { 0.0 }).collect()
}

/// The registration loss with the at-rest prior ½ Σ c_p |v_T,p|² on the final velocities.
struct AtRest<'a, const D: usize> {
    inner: &'a RegistrationLoss<D>,
    coef: &'a [f64],
}

impl<const D: usize> AtRest<'_, D> {
    fn value(&self, v: &[Vector<D>]) -> f64 {
        self.coef.iter().zip(v).map(|(c, v)| 0.5 * c * v.norm_squared()).sum()
    }
}

impl<const D: usize> laparo_mpm::Loss<D> for AtRest<'_, D> {
    fn observes(&self, step: usize, n_steps: usize) -> bool {
        self.inner.observes(step, n_steps)
    }
    fn evaluate(&self, step: usize, x: &[Vector<D>], grad: &mut [Vector<D>]) -> f64 {
        self.inner.evaluate(step, x, grad)
    }
    fn terminal_velocity(&self, v: &[Vector<D>], grad: &mut [Vector<D>]) -> f64 {
        for ((g, c), v) in grad.iter_mut().zip(self.coef).zip(v) {
            *g += v * *c;
        }
        self.value(v)
    }
}

/// One line-search trial: φ(α), φ'(α) and a payload, or None when the step is infeasible.
type Trial<T, E> = std::result::Result<Option<(f64, f64, T)>, E>;

/// Strong Wolfe line search on φ(α) = f(x + α d) (Nocedal & Wright Alg. 3.5 and 3.6, c₁ = 1e-4):
/// extrapolate by doubling up to `alpha_max`, then zoom by safeguarded cubic interpolation. `eval(α)`
/// gives φ(α), φ'(α) and a payload, or None when the step is infeasible (φ = +∞). Returns the trial with
/// the lowest φ among those with sufficient decrease (the strong Wolfe point when one was found within
/// `max_evals` trials), or None.
fn strong_wolfe<T, E>(
    phi0: f64,
    dphi0: f64,
    alpha0: f64,
    alpha_max: f64,
    c2: f64,
    max_evals: usize,
    eval: &mut dyn FnMut(f64) -> Trial<T, E>,
) -> std::result::Result<Option<(f64, T)>, E> {
    const C1: f64 = 1e-4;
    // (α, φ, φ'); φ = +∞ and φ' = NaN for an infeasible step
    type Pt = (f64, f64, f64);
    let mut best: Option<(f64, f64, T)> = None;
    let mut evals = 0;
    let mut trial = |a: f64, best: &mut Option<(f64, f64, T)>| -> std::result::Result<(Pt, bool), E> {
        let (f, s) = match eval(a)? {
            Some((f, s, payload)) => {
                if f <= phi0 + C1 * a * dphi0 && best.as_ref().is_none_or(|b| f < b.1) {
                    *best = Some((a, f, payload));
                }
                (f, s)
            }
            None => (f64::INFINITY, f64::NAN),
        };
        let wolfe = f <= phi0 + C1 * a * dphi0 && s.abs() <= -c2 * dphi0;
        Ok(((a, f, s), wolfe))
    };
    let done = |best: Option<(f64, f64, T)>| best.map(|(a, _, p)| (a, p));
    let mut prev: Pt = (0.0, phi0, dphi0);
    let mut a = alpha0.min(alpha_max);
    // bracketing: lo = the end with sufficient decrease and the lower φ, hi = the other end
    let (mut lo, mut hi): (Pt, Pt) = loop {
        let (p, wolfe) = trial(a, &mut best)?;
        evals += 1;
        if wolfe {
            return Ok(done(best));
        }
        let (_, f, s) = p;
        if f > phi0 + C1 * a * dphi0 || (evals > 1 && f >= prev.1) {
            break (prev, p);
        }
        if s >= 0.0 {
            break (p, prev);
        }
        if a >= alpha_max || evals >= max_evals {
            return Ok(done(best));
        }
        prev = p;
        a = (2.0 * a).min(alpha_max);
    };
    while evals < max_evals {
        let (l, h) = (lo.0.min(hi.0), lo.0.max(hi.0));
        let width = h - l;
        if width <= 1e-12 * h {
            break;
        }
        // minimiser of the cubic through (lo, hi) with their slopes (N&W eq. 3.59), else bisection
        let mut t = 0.5 * (lo.0 + hi.0);
        if hi.1.is_finite() && hi.2.is_finite() {
            let d1 = lo.2 + hi.2 - 3.0 * (lo.1 - hi.1) / (lo.0 - hi.0);
            let disc = d1 * d1 - lo.2 * hi.2;
            if disc >= 0.0 {
                let d2 = (hi.0 - lo.0).signum() * disc.sqrt();
                let c = hi.0 - (hi.0 - lo.0) * (hi.2 + d2 - d1) / (hi.2 - lo.2 + 2.0 * d2);
                if c.is_finite() {
                    t = c;
                }
            }
        }
        t = t.clamp(l + 0.1 * width, h - 0.1 * width);
        let (p, wolfe) = trial(t, &mut best)?;
        evals += 1;
        if wolfe {
            return Ok(done(best));
        }
        let (_, f, s) = p;
        if f > phi0 + C1 * t * dphi0 || f >= lo.1 {
            hi = p;
        } else {
            if s * (hi.0 - lo.0) >= 0.0 {
                hi = lo;
            }
            lo = p;
        }
    }
    Ok(done(best))
}

#[cfg(test)]
mod tests {
    use super::{strong_wolfe, Trial};

    /// φ(α) = (α − 3)² − 9: φ'(0) = −6; a strong Wolfe point with c₂ = 0.1 has |2(α − 3)| ≤ 0.6, and the
    /// cubic through two points of a quadratic with their slopes is the quadratic, so the zoom lands on 3.
    #[test]
    fn strong_wolfe_on_a_parabola() {
        let mut trials = Vec::new();
        let mut eval = |a: f64| -> Trial<(), ()> {
            trials.push(a);
            Ok(Some(((a - 3.0).powi(2) - 9.0, 2.0 * (a - 3.0), ())))
        };
        let (a, ()) = strong_wolfe(0.0, -6.0, 1.0, 100.0, 0.1, 20, &mut eval).unwrap().unwrap();
        assert!((a - 3.0).abs() < 1e-12, "α = {a}");
        // 1 → 2 (φ' still < −0.6) → 4 (φ(4) = φ(2), no further decrease: bracket [2, 4]) → cubic minimiser 3
        assert_eq!(trials, vec![1.0, 2.0, 4.0, 3.0]);
    }

    /// Infeasible trials (φ = +∞) beyond α = 0.5 shrink the step by bisection; the answer keeps
    /// sufficient decrease.
    #[test]
    fn strong_wolfe_backs_off_infeasible_steps() {
        let mut eval = |a: f64| -> Trial<(), ()> { Ok(if a > 0.5 { None } else { Some((-a, -1.0, ())) }) };
        let (a, ()) = strong_wolfe(0.0, -1.0, 4.0, 4.0, 0.9, 10, &mut eval).unwrap().unwrap();
        assert!(a <= 0.5 && a > 0.0, "α = {a}");
    }
}
