//! Reachable targets: 2D, 6.4k particles, targets from a forward run with a smooth random v₀*
//! (largest displacement 3 Δx); the default optimiser reaches a mean landmark distance ≤ 0.05 Δx in
//! ≤ 50 iterations. Thesis-mode gradient descent runs too (its figure is printed, not asserted).
use laparo_mpm::prelude::*;
use laparo_register::fig55::{idx, square_scene};
use laparo_register::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn smooth_field(scene: &Scene<2>, seed: u64) -> Vec<Vector<2>> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let modes: Vec<(Vector<2>, Vector<2>, f64)> = (0..4)
        .map(|_| {
            (
                Vector::<2>::new(rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0)),
                Vector::<2>::new(rng.gen_range(-6.0..6.0), rng.gen_range(-6.0..6.0)),
                rng.gen_range(0.0..std::f64::consts::TAU),
            )
        })
        .collect();
    scene
        .positions
        .iter()
        .map(|x| modes.iter().fold(Vector::<2>::zeros(), |a, (amp, k, ph)| a + amp * (k.dot(x) + ph).sin()))
        .collect()
}

fn max_disp(scene: &Scene<2>) -> f64 {
    let fin = simulate(scene).unwrap().final_state;
    fin.x.iter().zip(&scene.positions).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max)
}

pub fn reachable_problem() -> (Scene<2>, RegistrationLoss<2>) {
    let mut scene = square_scene();
    let dx = scene.grid.dx;
    let v = smooth_field(&scene, 5);
    let mut truth = scene.clone();
    let mut scale = 1.0;
    for _ in 0..4 {
        truth.velocities = v.iter().map(|a| a * scale).collect();
        scale *= 3.0 * dx / max_disp(&truth);
    }
    truth.velocities = v.iter().map(|a| a * scale).collect();
    let d = max_disp(&truth);
    assert!((d / dx - 3.0).abs() < 0.05, "largest displacement {} dx", d / dx);
    let fin = simulate(&truth).unwrap().final_state;
    let ticks = [0, 16, 32, 48, 64, 79];
    let particles: Vec<usize> = ticks.iter().flat_map(|&i| ticks.iter().map(move |&j| idx(i, j))).collect();
    let targets = particles.iter().map(|&p| fin.x[p]).collect();
    scene.velocities.iter_mut().for_each(|v| *v = Vector::<2>::zeros());
    let g = LandmarkGroup { name: "points".into(), particles, target: GroupTarget::Paired(targets), weight: 1.0 };
    (scene, RegistrationLoss::new(vec![g]))
}

#[test]
fn reachable_targets_default_optimizer() {
    let (scene, loss) = reachable_problem();
    let dx = scene.grid.dx;
    let cfg = OptimizerConfig { iterations: 50, target_mean_distance: 0.05 * dx, ..Default::default() };
    let r = register(&scene, &loss, &cfg, None, &mut |_, _| true).unwrap();
    let last = r.history.last().unwrap();
    eprintln!(
        "default: {} iterations, {} simulations, mean distance {:.4} dx (start {:.3} dx), {:.1} s, stop: {}",
        last.iteration,
        last.evaluations,
        last.mean_distance / dx,
        r.history[0].mean_distance / dx,
        last.seconds,
        r.stop_reason
    );
    assert!(last.iteration <= 50);
    assert!(last.mean_distance <= 0.05 * dx, "mean distance {} dx", last.mean_distance / dx);
    // the optimiser's own final state agrees with a fresh forward run of its v₀
    let mut s = scene.clone();
    s.velocities = r.velocities.clone();
    let fin = simulate(&s).unwrap().final_state;
    assert!((loss.mean_distance(&fin.x) - last.mean_distance).abs() < 1e-12);
}

#[test]
fn reachable_targets_thesis_gd_runs() {
    let (scene, loss) = reachable_problem();
    let dx = scene.grid.dx;
    let cfg = OptimizerConfig { iterations: 15, ..OptimizerConfig::thesis() };
    let r = register(&scene, &loss, &cfg, None, &mut |_, _| true).unwrap();
    let last = r.history.last().unwrap();
    eprintln!(
        "thesis GD: {} iterations, mean distance {:.4} dx (start {:.3} dx), {:.1} s",
        last.iteration,
        last.mean_distance / dx,
        r.history[0].mean_distance / dx,
        last.seconds
    );
    assert!(last.mean_distance < r.history[0].mean_distance, "thesis GD must decrease the loss");
}

/// The least-action prior (`kinetic_weight` κ): the objective the optimiser reports is eq. 5.10 plus
/// κ · mean |v₀ T Δt|² / (2 Δx), recomputed here from the returned v₀; and the prior buys a v₀ of lower
/// kinetic energy than the unregularised run of the same length.
#[test]
fn kinetic_prior_is_the_stated_term_and_lowers_the_kinetic_energy() {
    let (scene, loss) = reachable_problem();
    let dx = scene.grid.dx;
    let t = scene.steps as f64 * scene.dt;
    let energy = |v: &[Vector<2>]| v.iter().map(|v| (v * t).norm_squared()).sum::<f64>() / v.len() as f64;
    let plain = OptimizerConfig { iterations: 8, ..Default::default() };
    let r0 = register(&scene, &loss, &plain, None, &mut |_, _| true).unwrap();
    let kappa = 5.0;
    let cfg = OptimizerConfig { kinetic_weight: kappa, ..plain.clone() };
    let r = register(&scene, &loss, &cfg, None, &mut |_, _| true).unwrap();
    let last = r.history.last().unwrap();
    let prior = kappa * energy(&r.velocities) / (2.0 * dx);
    assert!(prior > 0.0);
    assert!(
        (last.objective - (last.loss + prior)).abs() <= 1e-12 * last.objective.abs().max(1.0),
        "objective {} vs eq. 5.10 {} + prior {prior}",
        last.objective,
        last.loss
    );
    // the plain run reports the bare eq. 5.10
    let l0 = r0.history.last().unwrap();
    assert_eq!(l0.objective, l0.loss);
    let (e0, e1) = (energy(&r0.velocities), energy(&r.velocities));
    eprintln!("mean |v0 T dt|^2: plain {e0:.4e}, kappa {kappa}: {e1:.4e}; eq. 5.10 {:.4} vs {:.4}", l0.loss, last.loss);
    assert!(e1 < e0, "the prior must lower the kinetic energy: {e1} vs {e0}");
    // a negative weight is refused, naming the parameter
    let bad = OptimizerConfig { kinetic_weight: -1.0, ..plain };
    let Err(err) = register(&scene, &loss, &bad, None, &mut |_, _| true) else { panic!("κ < 0 accepted") };
    let err = err.to_string();
    assert!(err.contains("kinetic_weight"), "{err}");
}
