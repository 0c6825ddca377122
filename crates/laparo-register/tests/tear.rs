//! The tear preset ([`OptimizerConfig::tear`]) on the 2D RODS box of the DiffTaichi scripts
//! (`laparo_mpm::reference::rods_scene`: 80×80 particles, n_grid 120, T 200; two adjacent particle
//! columns of the top edge pushed apart by ±1.2 Δx), and the distance-smoothing continuation's
//! bookkeeping: the reported loss stays eq. 5.10 whatever ε the optimiser uses.
use laparo_mpm::prelude::*;
use laparo_mpm::reference::rods_scene;
use laparo_register::prelude::*;

fn rods_box_2d() -> (Scene<2>, RegistrationLoss<2>) {
    let (mut scene, lm) = rods_scene::<2>([80, 80], 120, 200, 2e-4);
    scene.velocities.iter_mut().for_each(|v| *v = Vector::<2>::zeros());
    let g = LandmarkGroup {
        name: "lips".into(),
        particles: lm.indices.clone(),
        target: GroupTarget::Paired(lm.targets.clone()),
        weight: 1.0,
    };
    (scene, RegistrationLoss::new(vec![g]))
}

/// eq. 5.10 by hand: the mean Euclidean distance of the landmarks to their paired targets.
fn eq_5_10(loss: &RegistrationLoss<2>, x: &[Vector<2>]) -> f64 {
    let g = &loss.groups[0];
    let GroupTarget::Paired(t) = &g.target else { unreachable!() };
    g.particles.iter().zip(t).map(|(&p, y)| (x[p] - y).norm()).sum::<f64>() / g.particles.len() as f64
}

#[test]
fn continuation_reports_eq_5_10() {
    let (scene, loss) = rods_box_2d();
    let cfg = OptimizerConfig { iterations: 6, ..OptimizerConfig::tear() };
    assert!(cfg.epsilon_ratio > 0.0);
    let r = register(&scene, &loss, &cfg, None, &mut |_, _| true).unwrap();
    let first = &r.history[0];
    // at v₀ = 0 every landmark is 0.01 from its target: eq. 5.10 = 0.01 exactly (up to rounding),
    // while the optimised objective uses ε = κ · 0.01: √(d² + ε²) − ε
    assert!((first.loss - 0.01).abs() < 1e-12, "{}", first.loss);
    let eps = cfg.epsilon_ratio * 0.01;
    assert!((first.epsilon - eps).abs() < 1e-12);
    assert!((first.objective - ((1e-4 + eps * eps).sqrt() - eps)).abs() < 1e-12, "{}", first.objective);
    // the last record: eq. 5.10 of a fresh forward run of the returned v₀
    let mut s = scene.clone();
    s.velocities = r.velocities.clone();
    let fin = simulate(&s).unwrap().final_state;
    let last = r.history.last().unwrap();
    assert!((eq_5_10(&loss, &fin.x) - last.loss).abs() < 1e-12, "{} vs {}", eq_5_10(&loss, &fin.x), last.loss);
    assert!(last.loss < first.loss);
}
