//! End-to-end gradient of the registration loss (polyline + region terms) with respect to v₀ and E:
//! central finite differences in f64, relative error < 1e-5, in 2D and 3D with stretch > 50 %.
#![allow(clippy::needless_range_loop)]
use laparo_mpm::prelude::*;
use laparo_mpm::{simulate_with_gradient, Matrix};
use laparo_register::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::sync::Arc;

fn stretch_scene<const D: usize>(n_grid: usize, cells: [f64; D], steps: usize, seed: u64) -> Scene<D> {
    let k = if D == 2 { 22.0 } else { 30.0 };
    let grid = GridSpec::unit(n_grid);
    let dx = grid.dx;
    let half = Vector::<D>::from_fn(|d, _| cells[d] * dx / 2.0);
    let c = Vector::<D>::from_element(0.5);
    let pos = box_lattice(c - half, c + half, dx / 2.0);
    let material = Material { model: Model::NeoHookean, youngs_modulus: 2.0, poisson_ratio: 0.3, density: 1.0 };
    let dt = cfl_dt(&material, dx, 0.25);
    let mut scene = Scene::new(pos, (dx / 2.0).powi(D as i32), material, grid, dt, steps);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    for p in 0..scene.n_particles() {
        let r = scene.positions[p] - c;
        let mut v = Vector::<D>::zeros();
        v[0] = k * r[0] - r[1];
        v[1] += r[0];
        for d in 0..D {
            v[d] += 0.05 * rng.gen_range(-1.0..1.0);
        }
        scene.velocities[p] = v;
    }
    scene.mass_epsilon = 1e-10;
    scene
}

fn max_stretch<const D: usize>(f: &[Matrix<D>]) -> f64 {
    f.iter()
        .map(|f| {
            let m = f.transpose() * f;
            let mut v = Vector::<D>::from_element(1.0);
            for _ in 0..100 {
                v = (m * v).normalize();
            }
            v.dot(&(m * v)).sqrt()
        })
        .fold(0.0, f64::max)
}

fn build_loss<const D: usize>(scene: &Scene<D>, seed: u64) -> RegistrationLoss<D> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let n = scene.n_particles();
    let c = Vector::<D>::from_element(0.5);
    let curve = |t: f64| {
        let mut p = c;
        p[0] += 0.3 * (t - 0.5);
        p[1] += 0.05 * (6.0 * t).sin() + 0.03;
        p
    };
    let line = Polyline::open((0..15).map(|i| curve(i as f64 / 14.0)).collect());
    let cloud: Vec<Vector<D>> = (0..60).map(|_| c + Vector::<D>::from_fn(|_, _| rng.gen_range(-0.12..0.12))).collect();
    let lm = |k: usize, rng: &mut ChaCha8Rng| (0..k).map(|_| rng.gen_range(0..n)).collect::<Vec<_>>();
    let g1 = LandmarkGroup {
        name: "lip".into(),
        particles: lm(12, &mut rng),
        target: GroupTarget::Shared(Arc::new(line)),
        weight: 1.0,
    };
    let g2 = LandmarkGroup {
        name: "region".into(),
        particles: lm(10, &mut rng),
        target: GroupTarget::Shared(Arc::new(PointCloud::new(cloud.clone()))),
        weight: 0.7,
    };
    let mut loss = RegistrationLoss::new(vec![g1, g2]);
    loss.region =
        Some(RegionTerm { targets: cloud[..30].to_vec(), particles: (0..n).step_by(3).collect(), weight: 0.5 });
    loss
}

fn loss_at<const D: usize>(scene: &Scene<D>, loss: &RegistrationLoss<D>) -> f64 {
    let fin = simulate(scene).unwrap().final_state;
    let mut g = vec![Vector::<D>::zeros(); fin.x.len()];
    loss.value_and_gradient(&fin.x, &mut g)
}

fn check<const D: usize>(scene: Scene<D>, seed: u64) {
    let loss = build_loss(&scene, seed);
    let g = simulate_with_gradient(&scene, &loss).unwrap();
    let stretch = max_stretch(&g.final_state.f);
    assert!(stretch > 1.5, "stretch {stretch} must exceed 1.5");
    let mut rng = ChaCha8Rng::seed_from_u64(seed + 1);
    let n = scene.n_particles();
    for _ in 0..2 {
        let dir: Vec<Vector<D>> = (0..n).map(|_| Vector::<D>::from_fn(|_, _| rng.gen_range(-1.0..1.0))).collect();
        let h = 1e-6;
        let mut sp = scene.clone();
        let mut sm = scene.clone();
        for p in 0..n {
            sp.velocities[p] += dir[p] * h;
            sm.velocities[p] -= dir[p] * h;
        }
        let fd = (loss_at(&sp, &loss) - loss_at(&sm, &loss)) / (2.0 * h);
        let ad: f64 = g.d_velocities.iter().zip(&dir).map(|(a, b)| a.dot(b)).sum();
        let rel = (fd - ad).abs() / fd.abs().max(ad.abs());
        assert!(rel < 1e-5, "D={D} v0: fd {fd} ad {ad} rel {rel:e}");
    }
    let h = 1e-6 * scene.material.youngs_modulus;
    let mut sp = scene.clone();
    let mut sm = scene.clone();
    sp.material.youngs_modulus += h;
    sm.material.youngs_modulus -= h;
    let fd = (loss_at(&sp, &loss) - loss_at(&sm, &loss)) / (2.0 * h);
    let rel = (fd - g.d_youngs_modulus).abs() / fd.abs().max(g.d_youngs_modulus.abs());
    assert!(rel < 1e-5, "D={D} E: fd {fd} ad {} rel {rel:e}", g.d_youngs_modulus);
}

#[test]
fn registration_loss_gradient_2d() {
    check(stretch_scene::<2>(32, [8.0, 6.0], 60, 1), 11);
}

#[test]
fn registration_loss_gradient_3d() {
    check(stretch_scene::<3>(24, [5.0, 4.0, 4.0], 50, 2), 12);
}

#[test]
fn registration_bit_identical_for_1_and_2_threads() {
    let scene = stretch_scene::<2>(32, [8.0, 6.0], 40, 3);
    let loss = build_loss(&scene, 21);
    let cfg = OptimizerConfig { iterations: 4, ..Default::default() };
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| register(&scene, &loss, &cfg, None, &mut |_, _| true).unwrap())
    };
    let (a, b) = (run(1), run(2));
    assert!(a.history.len() > 1);
    for (x, y) in a.velocities.iter().zip(&b.velocities) {
        for d in 0..2 {
            assert_eq!(x[d].to_bits(), y[d].to_bits());
        }
    }
    assert_eq!(a.history.last().unwrap().loss.to_bits(), b.history.last().unwrap().loss.to_bits());
}
