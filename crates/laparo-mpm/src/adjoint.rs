//! `simulate_with_gradient`: forward pass with per-step particle checkpoints, then the hand-derived
//! reverse pass, recomputing each step's grid from its checkpoint (as DiffTaichi's diffmpm does).
//! With [`Scene::checkpoint_segment`] = k > 1, only every k-th step's particle state is kept: the
//! reverse pass recomputes each segment of k steps from its first state before walking back through it
//! (two-level checkpointing; memory for ⌈T/k⌉ + k states instead of T, one more forward pass; the same
//! gradient bit for bit, since a step is deterministic).
use crate::backward::{
    g2p::g2p_adjoint,
    grid_update::{grid_update_adjoint, NodeAdjoint},
    p2g::p2g_adjoint,
    p2g::StateAdjoint,
};
use crate::cfl;
use crate::constitutive::{lame_vjp, ConstitutiveModel};
use crate::error::MpmError;
use crate::error::Warning;
use crate::linalg::{Matrix, Vector};
use crate::loss::Loss;
use crate::scene::{Model, Scene};
use crate::simulate::{ParticleState, Stepper};
use crate::sparse_grid::GridCheckpoint;
use crate::{fixed_corotated::FixedCorotated, neo_hookean::NeoHookean};
use rayon::prelude::*;

/// Loss value and its exact gradient with respect to the scene's inputs.
#[derive(Clone, Debug)]
pub struct GradientResult<const D: usize> {
    /// L.
    pub loss: f64,
    /// ∂L/∂v₀ per particle.
    pub d_velocities: Vec<Vector<D>>,
    /// ∂L/∂x₀ per particle.
    pub d_positions: Vec<Vector<D>>,
    /// ∂L/∂C₀ per particle.
    pub d_affine: Vec<Matrix<D>>,
    /// ∂L/∂F₀ per particle.
    pub d_deformation: Vec<Matrix<D>>,
    /// ∂L/∂f_p of a time-constant external force per particle (`Scene::external_forces`; the unknown of a
    /// load-driven registration): Σ_s Δt Σ_i w_ip p̄_i(s) = Σ_s Δt v̄_p(s) / m_p over the steps s.
    pub d_external_forces: Vec<Vector<D>>,
    /// ∂L/∂E.
    pub d_youngs_modulus: f64,
    /// ∂L/∂ν.
    pub d_poisson_ratio: f64,
    /// ∂L/∂μ.
    pub d_mu: f64,
    /// ∂L/∂λ.
    pub d_lambda: f64,
    /// Final particle state.
    pub final_state: ParticleState<D>,
    /// Non-fatal warnings (CFL).
    pub warnings: Vec<Warning>,
}

/// Buffers of [`simulate_with_gradient_in`], reusable across calls (e.g. the iterations of a
/// registration) to avoid re-allocating the checkpoints.
#[derive(Default)]
pub struct GradientWorkspace<const D: usize> {
    /// The states of one segment (its first state and the k after it).
    states: Vec<ParticleState<D>>,
    /// The grids of one segment's steps.
    grids: Vec<GridCheckpoint<D>>,
    /// The first state of every segment but the first (segmented mode only).
    starts: Vec<ParticleState<D>>,
    // Reverse-pass scratch (kept so that a registration loop does not page-fault fresh memory in
    // every iteration).
    x_bar_g2p: Vec<Vector<D>>,
    lame_bar: Vec<(f64, f64)>,
    vel_bar: Vec<Vector<D>>,
    node_bar: Vec<NodeAdjoint<D>>,
}

impl<const D: usize> GradientWorkspace<D> {
    /// Empty workspace.
    pub fn new() -> Self {
        Self::default()
    }
}

/// The [`Scene::checkpoint_segment`] whose adjoint memory fits `budget_bytes`, for `n_particles` over `steps`
/// steps at `bytes_per_particle_step` (one step's particle state and grid checkpoint per particle): 0 when
/// every step fits (no recomputation); else the longest segment k with (⌈T/k⌉ + k) steps' worth within the
/// budget (the longer the last segment, the less is recomputed); None when even k ≈ √T does not fit.
pub fn checkpoint_segment_for(
    n_particles: usize,
    steps: usize,
    bytes_per_particle_step: f64,
    budget_bytes: f64,
) -> Option<usize> {
    let per_step = n_particles as f64 * bytes_per_particle_step;
    if steps as f64 * per_step <= budget_bytes {
        return Some(0);
    }
    (2..steps).rev().find(|&k| (steps.div_ceil(k) + k) as f64 * per_step <= budget_bytes)
}

/// Simulate the scene and return L and ∂L/∂(v₀, x₀, C₀, F₀, E, ν) by reverse-mode differentiation.
pub fn simulate_with_gradient<const D: usize, L: Loss<D> + ?Sized>(
    scene: &Scene<D>,
    loss: &L,
) -> Result<GradientResult<D>, MpmError> {
    simulate_with_gradient_in(&mut GradientWorkspace::new(), scene, loss)
}

/// [`simulate_with_gradient`] reusing the checkpoint buffers of `ws`. Runs on a worker of the
/// current rayon pool (`laparo_core::par::on_pool`), so that its thousands of short parallel
/// regions are not each injected from the calling thread.
pub fn simulate_with_gradient_in<const D: usize, L: Loss<D> + ?Sized>(
    ws: &mut GradientWorkspace<D>,
    scene: &Scene<D>,
    loss: &L,
) -> Result<GradientResult<D>, MpmError> {
    scene.validate()?;
    laparo_core::par::on_pool(|| match scene.material.model {
        Model::NeoHookean => run(ws, &NeoHookean, scene, loss),
        Model::FixedCorotated => run(ws, &FixedCorotated, scene, loss),
    })
}

fn run<const D: usize, M: ConstitutiveModel<D>, L: Loss<D> + ?Sized>(
    ws: &mut GradientWorkspace<D>,
    model: &M,
    scene: &Scene<D>,
    loss: &L,
) -> Result<GradientResult<D>, MpmError> {
    let n = scene.n_particles();
    let t = scene.steps;
    let (mu, la) = scene.material.lame();
    let mut stepper = Stepper::new(scene);
    // Steps per segment: the whole horizon (every step's state and grid kept, no recomputation) unless
    // the scene asks for shorter segments.
    let k = match scene.checkpoint_segment {
        k if k > 1 && k < t => k,
        _ => t.max(1),
    };
    let n_segments = t.div_ceil(k);
    // ---- forward, keeping one segment's states and grids, and the first state of every segment ----
    // Only the initial state is written; later states are fully overwritten by the steps.
    ws.states.truncate(k + 1);
    if ws.states.is_empty() {
        ws.states.push(ParticleState::initial(scene));
    } else {
        ws.states[0].set_initial(scene);
    }
    for st in ws.states.iter_mut() {
        st.x.resize(n, Vector::<D>::zeros());
        st.v.resize(n, Vector::<D>::zeros());
        st.c.resize(n, Matrix::<D>::zeros());
        st.f.resize(n, Matrix::<D>::zeros());
    }
    while ws.states.len() < k + 1 {
        ws.states.push(ws.states[0].clone());
    }
    ws.grids.truncate(k);
    while ws.grids.len() < k {
        ws.grids.push(GridCheckpoint::default());
    }
    ws.starts.truncate(n_segments.saturating_sub(1));
    let GradientWorkspace { states, grids, starts, x_bar_g2p, lame_bar, vel_bar, node_bar } = ws;
    let mut loss_grads: Vec<Option<Vec<Vector<D>>>> = vec![None; t + 1];
    let mut total = 0.0;
    let mut observe = |s: usize, st: &ParticleState<D>, total: &mut f64| -> Result<(), MpmError> {
        if loss.observes(s, t) {
            let mut g = vec![Vector::<D>::zeros(); n];
            let v = loss.evaluate(s, &st.x, &mut g);
            if !v.is_finite() || !g.iter().all(|g| g.iter().all(|c| c.is_finite())) {
                return Err(MpmError::Loss(format!("non-finite loss or gradient at step {s}")));
            }
            *total += v;
            loss_grads[s] = Some(g);
        }
        Ok(())
    };
    // One step of segment-local index j (from states[j] into states[j + 1]), its grid kept in grids[j].
    let step = |stepper: &mut Stepper<D>,
                states: &mut [ParticleState<D>],
                grids: &mut [GridCheckpoint<D>],
                j: usize,
                s: usize| {
        let (head, tail) = states.split_at_mut(j + 1);
        stepper.step(model, scene, &head[j], &mut tail[0], s)?;
        stepper.grid.swap_checkpoint(&mut grids[j]);
        Ok::<(), MpmError>(())
    };
    observe(0, &states[0], &mut total)?;
    for s in 0..t {
        let j = s % k;
        if j == 0 && s > 0 {
            // segment s / k starts from the end state of the previous one
            let seg = s / k;
            if starts.len() < seg {
                starts.push(states[k].clone());
            } else {
                starts[seg - 1].clone_from(&states[k]);
            }
            states.swap(0, k);
        }
        step(&mut stepper, states, grids, j, s)?;
        observe(s + 1, &states[j + 1], &mut total)?;
    }
    let final_state = states[if t == 0 { 0 } else { (t - 1) % k + 1 }].clone();
    // ---- reverse pass, segment by segment (the last one is still in the buffers) ----
    let mut x_bar = loss_grads[t].take().unwrap_or_else(|| vec![Vector::<D>::zeros(); n]);
    // terminal condition v̄_T = ∂L/∂v_T (zero unless the loss has a velocity term)
    let mut v_bar = vec![Vector::<D>::zeros(); n];
    let vt = loss.terminal_velocity(&final_state.v, &mut v_bar);
    if !vt.is_finite() || !v_bar.iter().all(|g| g.iter().all(|c| c.is_finite())) {
        return Err(MpmError::Loss("non-finite terminal velocity term or gradient".into()));
    }
    total += vt;
    let mut c_bar = vec![Matrix::<D>::zeros(); n];
    let mut force_bar = vec![Vector::<D>::zeros(); n];
    let mut f_bar = vec![Matrix::<D>::zeros(); n];
    x_bar_g2p.resize(n, Vector::<D>::zeros());
    lame_bar.clear();
    lame_bar.resize(n, (0.0, 0.0));
    vel_bar.clear();
    for seg in (0..n_segments).rev() {
        let (first, end) = (seg * k, ((seg + 1) * k).min(t));
        if seg + 1 < n_segments {
            // recompute this segment's states and grids from its first state
            if seg == 0 {
                states[0].set_initial(scene);
            } else {
                states[0].clone_from(&starts[seg - 1]);
            }
            stepper.restart();
            for s in first..end {
                step(&mut stepper, states, grids, s - first, s)?;
            }
        }
        for s in (first..end).rev() {
            let j = s - first;
            let cur = &states[j];
            let next = &states[j + 1];
            // The layout and node data of step s, moved into the stepper's grid for the adjoint kernels
            // (and moved back afterwards so that the workspace keeps its buffers).
            stepper.grid.swap_checkpoint(&mut grids[j]);
            let grid = &stepper.grid;
            let nodes = grid.mass.len();
            // All zero: grid_update_adjoint zeroes what it reads.
            vel_bar.resize(nodes, Vector::<D>::zeros());
            node_bar.resize(nodes, NodeAdjoint::default());
            g2p_adjoint(grid, scene, &grid.vel, &cur.x, &next.v, &x_bar, &v_bar, &c_bar, vel_bar, x_bar_g2p);
            grid_update_adjoint(scene, &grid.mass, &grid.vel, &grid.wall_mask, vel_bar, node_bar);
            let lg = loss_grads[s].take();
            p2g_adjoint(
                model,
                mu,
                la,
                grid,
                scene,
                &cur.x,
                &cur.v,
                &cur.c,
                &cur.f,
                &next.f,
                node_bar,
                x_bar_g2p,
                lg.as_deref(),
                StateAdjoint { x: &mut x_bar, v: &mut v_bar, c: &mut c_bar, f: &mut f_bar, lame: lame_bar },
            );
            // f enters P2G as (m v + Δt f): f̄ += Δt v̄ / m (v̄ of the step input is m Σ w p̄)
            let dt = scene.dt;
            force_bar.par_iter_mut().zip(v_bar.par_iter()).zip(scene.masses.par_iter()).with_min_len(4096).for_each(
                |((fb, vb), m)| {
                    if *m > 0.0 {
                        *fb += vb * (dt / m);
                    }
                },
            );
            stepper.grid.swap_checkpoint(&mut grids[j]);
        }
    }
    // (μ̄, λ̄): per-particle sums over the steps (accumulated by `p2g_adjoint`), then summed in particle
    // order: a fixed summation order, deterministic whatever the thread count.
    let (mut mu_bar, mut la_bar) = (0.0, 0.0);
    for &(m, l) in lame_bar.iter() {
        mu_bar += m;
        la_bar += l;
    }
    if t == 0 {
        if let Some(g) = loss_grads[0].take() {
            for p in 0..n {
                x_bar[p] += g[p];
            }
        }
    }
    let (d_e, d_nu) = lame_vjp(scene.material.youngs_modulus, scene.material.poisson_ratio, mu_bar, la_bar);
    Ok(GradientResult {
        loss: total,
        d_velocities: v_bar,
        d_positions: x_bar,
        d_affine: c_bar,
        d_external_forces: force_bar,
        d_deformation: f_bar,
        d_youngs_modulus: d_e,
        d_poisson_ratio: d_nu,
        d_mu: mu_bar,
        d_lambda: la_bar,
        final_state,
        warnings: cfl::cfl_warnings(scene),
    })
}
