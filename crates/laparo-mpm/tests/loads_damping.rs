//! Mass-proportional damping (`Scene::damping`) and the gradient in a time-constant external force per
//! particle (`GradientResult::d_external_forces`), the two pieces of a load-driven registration (RODS-MPM's
//! ladder rung L3): central differences in 2D and 3D, on one field and across a crack, and a damped block
//! under a constant load that comes to rest.
mod common;
use laparo_mpm::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn block<const D: usize>(steps: usize, cracked: bool, damping: f64, seed: u64) -> Scene<D> {
    let dx = 1.0 / 16.0;
    let half = Vector::<D>::from_fn(|d, _| if d == 0 { 3.0 * dx } else { 2.0 * dx });
    let material = Material { model: Model::NeoHookean, youngs_modulus: 3.0, poisson_ratio: 0.3, density: 1.0 };
    let mut s = common::centred_block(16, half, material, steps);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let n = s.n_particles();
    for p in 0..n {
        s.velocities[p] = Vector::<D>::from_fn(|_, _| 0.3 * rng.gen_range(-1.0..1.0));
    }
    s.external_forces =
        (0..n).map(|p| Vector::<D>::from_fn(|_, _| 40.0 * s.masses[p] * rng.gen_range(-1.0..1.0))).collect();
    if cracked {
        s.crack_side = common::upper_half_crack(&s.positions);
    }
    s.damping = damping;
    s.mass_epsilon = 1e-10;
    s
}

fn loss_for<const D: usize>(s: &Scene<D>, seed: u64) -> LandmarkLoss<D> {
    common::random_landmarks(s, 10, &mut ChaCha8Rng::seed_from_u64(seed))
}

fn value<const D: usize>(s: &Scene<D>, l: &LandmarkLoss<D>) -> f64 {
    let fin = simulate(s).unwrap().final_state;
    let mut g = vec![Vector::<D>::zeros(); fin.x.len()];
    l.evaluate(s.steps, &fin.x, &mut g)
}

fn check<const D: usize>(cracked: bool, damping: f64, seed: u64) {
    let s = block::<D>(15, cracked, damping, seed);
    let l = loss_for(&s, seed + 3);
    let g = simulate_with_gradient(&s, &l).unwrap();
    assert!((g.loss - value(&s, &l)).abs() < 1e-14);
    let n = s.n_particles();
    let mut rng = ChaCha8Rng::seed_from_u64(seed + 1);
    let dir: Vec<Vector<D>> = (0..n).map(|_| Vector::<D>::from_fn(|_, _| rng.gen_range(-1.0..1.0))).collect();
    // ∂L/∂f (step relative to the force scale)
    let h = 1e-5 * s.masses[0] * 40.0;
    let (mut sp, mut sm) = (s.clone(), s.clone());
    for (p, d) in dir.iter().enumerate() {
        sp.external_forces[p] += d * h;
        sm.external_forces[p] -= d * h;
    }
    let fd = (value(&sp, &l) - value(&sm, &l)) / (2.0 * h);
    let ad: f64 = (0..n).map(|p| g.d_external_forces[p].dot(&dir[p])).sum();
    let rel = (fd - ad).abs() / fd.abs().max(ad.abs());
    assert!(ad.abs() > 0.0);
    assert!(rel < 1e-5, "D={D} crack={cracked} ζ={damping} d/df: fd {fd:.12e} adjoint {ad:.12e} rel {rel:.2e}");
    // ∂L/∂v₀ through the damped grid update
    let h = 1e-5;
    let (mut sp, mut sm) = (s.clone(), s.clone());
    for (p, d) in dir.iter().enumerate() {
        sp.velocities[p] += d * h;
        sm.velocities[p] -= d * h;
    }
    let fd = (value(&sp, &l) - value(&sm, &l)) / (2.0 * h);
    let ad: f64 = (0..n).map(|p| g.d_velocities[p].dot(&dir[p])).sum();
    let rel = (fd - ad).abs() / fd.abs().max(ad.abs());
    assert!(rel < 1e-5, "D={D} crack={cracked} ζ={damping} d/dv0: fd {fd:.12e} adjoint {ad:.12e} rel {rel:.2e}");
}

#[test]
fn force_and_damped_velocity_gradients_match_central_differences_2d() {
    check::<2>(false, 0.0, 1);
    check::<2>(false, 30.0, 2);
    check::<2>(true, 30.0, 3);
}

#[test]
fn force_and_damped_velocity_gradients_match_central_differences_3d() {
    check::<3>(false, 30.0, 4);
    check::<3>(true, 30.0, 5);
}

/// ∂L/∂f is Σ_s Δt v̄_p(s)/m_p: with one step and a loss on x_1 only, f enters x_1 through Δt² f / m on a
/// lone particle's grid (a single free particle moves by Δt (v + Δt f/m) exactly).
#[test]
fn one_step_force_gradient_of_a_lone_particle_is_dt_squared_over_m() {
    let grid = GridSpec::unit(16);
    let material = Material { model: Model::NeoHookean, youngs_modulus: 1.0, poisson_ratio: 0.3, density: 2.0 };
    let mut s = Scene::new(vec![Vector::<2>::new(0.5, 0.5)], 0.01, material, grid, 1e-3, 1);
    s.external_forces = vec![Vector::<2>::new(3.0, -1.0)];
    let l = LandmarkLoss { indices: vec![0], targets: vec![Vector::<2>::new(0.6, 0.5)] };
    let g = simulate_with_gradient(&s, &l).unwrap();
    let m = s.masses[0];
    let fin = g.final_state.x[0];
    let want_x = s.positions[0] + (s.external_forces[0] * (s.dt / m)) * s.dt;
    assert!((fin - want_x).norm() < 1e-14, "{fin} vs {want_x}");
    let unit = (fin - l.targets[0]) / ((fin - l.targets[0]).norm_squared() + 1e-12).sqrt();
    let want = unit * (s.dt * s.dt / m);
    assert!((g.d_external_forces[0] - want).norm() < 1e-12 * want.norm(), "{} vs {want}", g.d_external_forces[0]);
}

/// A damped block under a constant self-equilibrated load (its two ends pulled apart, net force zero: the
/// loads of rung L3) comes to rest: KE ≤ 1e-3 of the elastic energy at the end, and the stretch matches the
/// static linear estimate F L / (E A) within 15 %; undamped, it is still oscillating.
#[test]
fn a_damped_block_under_a_self_equilibrated_load_comes_to_rest() {
    let grid = GridSpec::unit(32);
    let dx = grid.dx;
    let e = 20.0;
    let material = Material { model: Model::NeoHookean, youngs_modulus: e, poisson_ratio: 0.0, density: 1.0 };
    let (lo, hi) = (Vector::<2>::new(0.3, 0.45), Vector::<2>::new(0.3 + 12.0 * dx, 0.45 + 4.0 * dx));
    let pos = box_lattice(lo, hi, dx / 2.0);
    // the end columns of particles
    let (x_min, x_max) = pos.iter().fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p[0]), b.max(p[0])));
    let (lo, hi) = (Vector::<2>::new(x_min, lo[1]), Vector::<2>::new(x_max, hi[1]));
    let dt = cfl_dt(&material, dx, 0.3);
    let run = |damping: f64| {
        // lowest axial mode ω₁ = π c / L (free–free), c = √(E/ρ) ≈ 4.5: ω₁ ≈ 37 rad/s; T = 2 s
        let steps = (2.0 / dt) as usize;
        let mut s = Scene::new(pos.clone(), (dx / 2.0).powi(2), material, grid, dt, steps);
        s.external_forces = s
            .positions
            .iter()
            .zip(&s.masses)
            .map(|(x, m)| {
                let pull = 0.6 * *m / (dx / 2.0);
                if x[0] > hi[0] - dx / 4.0 {
                    Vector::<2>::new(pull, 0.0)
                } else if x[0] < lo[0] + dx / 4.0 {
                    Vector::<2>::new(-pull, 0.0)
                } else {
                    Vector::<2>::zeros()
                }
            })
            .collect();
        s.damping = damping;
        let fin = simulate(&s).unwrap().final_state;
        let len = |x: &[Vector<2>]| {
            let right: Vec<f64> =
                x.iter().zip(&pos).filter(|(_, p)| p[0] > hi[0] - dx / 4.0).map(|(x, _)| x[0]).collect();
            let left: Vec<f64> =
                x.iter().zip(&pos).filter(|(_, p)| p[0] < lo[0] + dx / 4.0).map(|(x, _)| x[0]).collect();
            right.iter().sum::<f64>() / right.len() as f64 - left.iter().sum::<f64>() / left.len() as f64
        };
        // traction per unit height: pull × particles per column / height
        let per_column: f64 = s.external_forces.iter().filter(|f| f[0] > 0.0).map(|f| f[0]).sum();
        let height = hi[1] - lo[1];
        let strain = per_column / height / e;
        (diagnostics(&s, &fin), len(&fin.x) / len(&pos) - 1.0, strain)
    };
    // about critical for the lowest mode
    let (damped, stretch, strain) = run(70.0);
    assert!(damped.elastic_energy > 0.0);
    assert!(
        damped.kinetic_energy <= 1e-3 * damped.elastic_energy,
        "KE {:.3e} vs elastic {:.3e}",
        damped.kinetic_energy,
        damped.elastic_energy
    );
    assert!((stretch - strain).abs() < 0.15 * strain, "stretch {stretch:.4} vs F/(EA) {strain:.4}");
    let (free, _, _) = run(0.0);
    assert!(free.kinetic_energy > 1e-2 * free.elastic_energy, "undamped KE {:.3e}", free.kinetic_energy);
}
