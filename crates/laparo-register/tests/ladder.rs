//! The RODS-MPM ladder's unit tests (L1: the side-aware preconditioner of a two-field grid; L2: the at-rest
//! prior and the energy audit every run reports).
use laparo_mpm::prelude::*;
use laparo_mpm::{diagnostics, simulate_with_gradient};
use laparo_register::optimize::EnergyAudit;
use laparo_register::prelude::*;
use laparo_register::smoothing::Smoother;

/// A 2D block of 16×8 particles (2 per cell per axis) labelled by a crack at x = x_mid: above y_front the
/// left half is side −1 and the right half +1, below it uncut (0). `y_front` below the block = fully split.
fn block(y_front: f64) -> Scene<2> {
    let grid = GridSpec::unit(32);
    let mat = Material { model: Model::NeoHookean, youngs_modulus: 5.0, poisson_ratio: 0.3, density: 1.0 };
    let s = grid.dx / 2.0;
    let (lo, hi) = (Vector::<2>::new(0.4, 0.45), Vector::<2>::new(0.4 + 16.0 * s, 0.45 + 8.0 * s));
    let x0 = box_lattice(lo, hi, s);
    let mut scene = Scene::new(x0, s * s, mat, grid, cfl_dt(&mat, grid.dx, 0.3), 20);
    let mid = 0.5 * (lo[0] + hi[0]);
    scene.crack_side = scene
        .positions
        .iter()
        .map(|x| {
            if x[1] > y_front {
                if x[0] < mid {
                    -1
                } else {
                    1
                }
            } else {
                0
            }
        })
        .collect();
    scene
}

/// Landmarks: the left (side −1) particles of the top row, each asked to move up-left by 0.3 Δx.
fn side_a_loss(scene: &Scene<2>) -> RegistrationLoss<2> {
    let top = scene.positions.iter().map(|x| x[1]).fold(f64::MIN, f64::max);
    let particles: Vec<usize> =
        (0..scene.n_particles()).filter(|&p| scene.crack_side[p] == -1 && scene.positions[p][1] > top - 1e-9).collect();
    assert!(particles.len() >= 4);
    let targets = particles.iter().map(|&p| scene.positions[p] + Vector::<2>::new(-0.3, 0.3) * scene.grid.dx).collect();
    RegistrationLoss::new(vec![LandmarkGroup {
        name: "lip A".into(),
        particles,
        target: GroupTarget::Paired(targets),
        weight: 1.0,
    }])
}

fn max_norm(g: &[Vector<2>], keep: impl Fn(usize) -> bool) -> f64 {
    g.iter().enumerate().filter(|(p, _)| keep(*p)).map(|(_, v)| v.norm()).fold(0.0, f64::max)
}

/// M1, fully split: with landmarks on side A only, the two-field simulation's gradient on side B is exactly
/// 0, and so is the side-aware preconditioned gradient; the side-blind Gaussian of the thesis set-up leaks it.
#[test]
fn side_aware_preconditioner_keeps_side_b_at_zero_on_a_split_box() {
    let scene = block(0.0);
    let loss = side_a_loss(&scene);
    let g = simulate_with_gradient(&scene, &loss).unwrap().d_velocities;
    let side_b = |p: usize| scene.crack_side[p] == 1;
    let side_a = |p: usize| scene.crack_side[p] == -1;
    assert!(max_norm(&g, side_a) > 0.0);
    assert_eq!(max_norm(&g, side_b), 0.0, "the two-field grid decouples the halves");
    let h = scene.grid.dx;
    let sided = Smoother::with_sides(&scene.positions, &scene.crack_side, 2.0 * h, h).unwrap().apply(&g);
    assert_eq!(max_norm(&sided, side_b), 0.0, "side-aware smoothing never crosses the crack");
    assert!(max_norm(&sided, side_a) > 0.0);
    let plain = Smoother::new(&scene.positions, 2.0 * h, h).unwrap().apply(&g);
    assert!(
        max_norm(&plain, side_b) > 1e-3 * max_norm(&plain, side_a),
        "the plain Gaussian blurs side A's gradient onto side B ({:.3e})",
        max_norm(&plain, side_b)
    );
}

/// M1, partly split: a gradient living on side A reaches the uncut material below the crack front but
/// never a side-B particle (each side's lattice holds only its side and the uncut particles).
#[test]
fn side_aware_preconditioner_reaches_uncut_material_but_not_the_other_lip() {
    let scene = block(0.5);
    let h = scene.grid.dx;
    let g: Vec<Vector<2>> = scene
        .crack_side
        .iter()
        .enumerate()
        .map(|(p, &s)| if s == -1 { Vector::<2>::new(1.0, (p % 3) as f64) } else { Vector::<2>::zeros() })
        .collect();
    let sm = Smoother::with_sides(&scene.positions, &scene.crack_side, 2.0 * h, h).unwrap();
    let out = sm.apply(&g);
    assert_eq!(max_norm(&out, |p| scene.crack_side[p] == 1), 0.0);
    assert!(max_norm(&out, |p| scene.crack_side[p] == 0) > 0.0, "the uncut material below the front is reached");
    // S is symmetric: <a, S b> = <S a, b>
    let a: Vec<Vector<2>> = (0..g.len()).map(|p| Vector::<2>::new((p as f64 * 0.37).sin(), (p as f64).cos())).collect();
    let b: Vec<Vector<2>> =
        (0..g.len()).map(|p| Vector::<2>::new((p as f64 * 1.3).cos(), (p as f64 * 0.7).sin())).collect();
    let dot = |u: &[Vector<2>], v: &[Vector<2>]| u.iter().zip(v).map(|(x, y)| x.dot(y)).sum::<f64>();
    let (l, r) = (dot(&a, &sm.apply(&b)), dot(&sm.apply(&a), &b));
    assert!((l - r).abs() < 1e-12 * l.abs().max(1.0), "{l} vs {r}");
    // without labels it is the plain smoother, bit for bit
    let unl = Smoother::with_sides(&scene.positions, &vec![0; g.len()], 2.0 * h, h).unwrap().apply(&a);
    let plain = Smoother::new(&scene.positions, 2.0 * h, h).unwrap().apply(&a);
    assert_eq!(unl, plain);
}

/// L2: the objective is eq. 5.10 plus λ Σ m |v_T T Δt|² / (2 M Δx) (hand formula at the accepted point), and
/// the at-rest prior leaves less kinetic energy at T than the same run without it; the energy audit adds up.
#[test]
fn at_rest_prior_is_the_terminal_kinetic_energy_and_slows_the_final_state() {
    let mut scene = block(0.0);
    let loss = side_a_loss(&scene);
    scene.crack_side.clear();
    let run = |lambda: f64| {
        let cfg = OptimizerConfig { iterations: 12, terminal_kinetic_weight: lambda, ..Default::default() };
        register(&scene, &loss, &cfg, None, &mut |_, _| true).unwrap()
    };
    let free = run(0.0);
    let lambda = 2.0;
    let rest = run(lambda);
    let t = scene.steps as f64 * scene.dt;
    let m: f64 = scene.masses.iter().sum();
    let v_t = &rest.final_state.v;
    let hand: f64 = lambda * (0..v_t.len()).map(|p| scene.masses[p] * (v_t[p] * t).norm_squared()).sum::<f64>()
        / (2.0 * m * scene.grid.dx);
    let last = rest.history.last().unwrap();
    assert!(hand > 0.0);
    assert!(
        ((last.objective - last.loss) - hand).abs() < 1e-10 * hand.max(1e-12),
        "{} vs {hand}",
        last.objective - last.loss
    );
    // the audit by hand
    let ke0: f64 = (0..v_t.len()).map(|p| 0.5 * scene.masses[p] * rest.velocities[p].norm_squared()).sum();
    let ket: f64 = (0..v_t.len()).map(|p| 0.5 * scene.masses[p] * v_t[p].norm_squared()).sum();
    let e: &EnergyAudit = &rest.energy;
    assert!((e.kinetic_initial - ke0).abs() < 1e-12 * ke0);
    assert!((e.kinetic_final - ket).abs() < 1e-12 * ket.max(1e-300));
    let psi = diagnostics(&scene, &rest.final_state).elastic_energy;
    assert!((e.elastic_final - psi).abs() < 1e-12 * psi.max(1e-300));
    assert!((e.dissipated - (ke0 - ket - psi)).abs() < 1e-12 * ke0);
    assert!(
        rest.energy.kinetic_ratio() < free.energy.kinetic_ratio(),
        "KE(T)/KE(0): λ {lambda} {:.3} vs λ 0 {:.3}",
        rest.energy.kinetic_ratio(),
        free.energy.kinetic_ratio()
    );
    assert!(rest.history.last().unwrap().mean_distance < 0.7 * rest.history[0].mean_distance);
}

/// L3: with loads on the band of a crack as the unknown (v₀ = 0, damped), the lips of a half-cut block are
/// pulled apart towards their targets, the loads have zero net force, and the final state is at rest.
#[test]
fn loads_rung_opens_a_half_cut_block_and_ends_at_rest() {
    use laparo_register::optimize::Unknown;
    let mut scene = block(0.5);
    scene.steps = 80;
    let top = scene.positions.iter().map(|x| x[1]).fold(f64::MIN, f64::max);
    let lip = |side: i8| -> Vec<usize> {
        (0..scene.n_particles())
            .filter(|&p| scene.crack_side[p] == side && scene.positions[p][1] > top - 1e-9)
            .collect()
    };
    let (a, b) = (lip(-1), lip(1));
    let dx = scene.grid.dx;
    let group = |name: &str, ps: Vec<usize>, dir: f64| LandmarkGroup {
        name: name.into(),
        target: GroupTarget::Paired(
            ps.iter().map(|&p| scene.positions[p] + Vector::<2>::new(dir * 0.3 * dx, 0.0)).collect(),
        ),
        particles: ps,
        weight: 1.0,
    };
    let loss = RegistrationLoss::new(vec![group("lip A", a, -1.0), group("lip B", b, 1.0)]);
    let cfg =
        OptimizerConfig { iterations: 25, unknown: Unknown::Loads { damping_per_horizon: 10.0 }, ..Default::default() };
    let r = register(&scene, &loss, &cfg, None, &mut |_, _| true).unwrap();
    let (d0, d1) = (r.history[0].mean_distance, r.history.last().unwrap().mean_distance);
    assert!(d1 < 0.5 * d0, "mean landmark distance {d0:.4} → {d1:.4}");
    let f = r.loads.as_ref().expect("loads");
    let net: Vector<2> = f.iter().sum();
    let scale = f.iter().map(|f| f.norm()).sum::<f64>();
    assert!(scale > 0.0 && net.norm() < 1e-9 * scale, "net force {net} of Σ|f| {scale}");
    assert!(
        f.iter().zip(&scene.crack_side).all(|(f, &s)| s != 0 || *f == Vector::<2>::zeros()),
        "loads only on the band"
    );
    assert!(r.velocities.iter().all(|v| *v == Vector::<2>::zeros()), "v₀ = 0 with loads");
    let e = r.energy;
    assert!(
        e.kinetic_final < 0.05 * e.elastic_final,
        "KE(T) {:.3e} vs elastic {:.3e}",
        e.kinetic_final,
        e.elastic_final
    );
    // the audit balances with the loads' work (by hand from the returned loads and final positions)
    let w: f64 = f.iter().zip(scene.positions.iter().zip(&r.final_state.x)).map(|(f, (a, b))| f.dot(&(b - a))).sum();
    assert!((e.external_work - w).abs() <= 1e-12 * w.abs() && w > 0.0 && e.dissipated >= 0.0, "{e:?}");
    // a band whose particles are all held carries no load: refused by name; so are a negative damping and λ
    let mut held = scene.clone();
    held.fixed = held.crack_side.iter().map(|&s| s != 0).collect();
    let err = register(&held, &loss, &cfg, None, &mut |_, _| true).err().expect("refused").to_string();
    assert!(err.contains("load band"), "{err}");
    let bad = OptimizerConfig { unknown: Unknown::Loads { damping_per_horizon: -1.0 }, ..cfg.clone() };
    let err = register(&scene, &loss, &bad, None, &mut |_, _| true).err().expect("refused").to_string();
    assert!(err.contains("damping_per_horizon"), "{err}");
    let bad = OptimizerConfig { terminal_kinetic_weight: -1.0, ..cfg.clone() };
    let err = register(&scene, &loss, &bad, None, &mut |_, _| true).err().expect("refused").to_string();
    assert!(err.contains("terminal_kinetic_weight"), "{err}");
}

/// Landmark offsets: a landmark is scored at its particle plus its rest offset, so at the rest state a
/// landmark that coincides with its target scores 0 even when its particle lies below it (by hand), and
/// the gradient still falls on the particle.
#[test]
fn landmark_offsets_score_the_material_point_not_the_particle() {
    let x = vec![Vector::<2>::new(1.0, 1.0), Vector::<2>::new(3.0, 1.0)];
    let target = vec![Vector::<2>::new(1.0, 1.5), Vector::<2>::new(3.0, 2.5)];
    let mut loss = RegistrationLoss::new(vec![LandmarkGroup {
        name: "lip".into(),
        particles: vec![0, 1],
        target: GroupTarget::Paired(target.clone()),
        weight: 1.0,
    }]);
    // the thesis: the particle itself, 0.5 and 1.5 below the targets
    assert!((loss.mean_distance(&x) - 1.0).abs() < 1e-15);
    loss.offsets = vec![vec![Vector::<2>::new(0.0, 0.5), Vector::<2>::new(0.0, 0.5)]];
    assert!((loss.mean_distance(&x) - 0.5).abs() < 1e-15, "{}", loss.mean_distance(&x));
    let mut g = vec![Vector::<2>::zeros(); 2];
    loss.value_and_gradient(&x, &mut g);
    assert_eq!(g[0], Vector::<2>::zeros(), "on its target: no pull");
    assert!((g[1] - Vector::<2>::new(0.0, -0.5)).norm() < 1e-6, "{}", g[1]);
    let r = loss.residuals(&x);
    assert!((r[0].max - 1.0).abs() < 1e-15);
}
