//! Physics acceptance: momentum conservation, bar oscillation frequency, coming to rest on a sticky
//! floor, determinism across thread counts, bad-input errors, blow-up detection.
use laparo_mpm::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn block<const D: usize>(n_grid: usize, cells: [f64; D], centre: f64, e: f64, nu: f64, steps: usize) -> Scene<D> {
    let grid = GridSpec::unit(n_grid);
    let dx = grid.dx;
    let c = Vector::<D>::from_element(centre);
    let half = Vector::<D>::from_fn(|d, _| cells[d] * dx / 2.0);
    let pos = box_lattice(c - half, c + half, dx / 2.0);
    let material = Material { model: Model::NeoHookean, youngs_modulus: e, poisson_ratio: nu, density: 1.0 };
    let dt = cfl_dt(&material, dx, 0.25);
    Scene::new(pos, (dx / 2.0).powi(D as i32), material, grid, dt, steps)
}

fn free_floating_momentum<const D: usize>(model: Model) {
    let mut scene = block::<D>(32, [6.0; D], 0.5, 3.0, 0.3, 0);
    scene.material.model = model;
    scene.boundary.walls = WallKind::None;
    scene.mass_epsilon = 0.0;
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let c = Vector::<D>::from_element(0.5);
    for p in 0..scene.n_particles() {
        let r = scene.positions[p] - c;
        let mut v = Vector::<D>::from_fn(|_, _| rng.gen_range(-0.3..0.3));
        v[0] += 0.2 - 2.0 * r[1] + 3.0 * r[0];
        v[1] += 2.0 * r[0];
        scene.velocities[p] = v;
    }
    let d0 = diagnostics(&scene, &ParticleState::initial(&scene));
    let mut max_l = 0.0f64;
    let mut max_a = 0.0f64;
    scene.steps = 100;
    simulate_observed(&scene, |_, st| {
        let d = diagnostics(&scene, st);
        for k in 0..3 {
            max_l = max_l.max((d.linear_momentum[k] - d0.linear_momentum[k]).abs());
            max_a = max_a.max((d.angular_momentum[k] - d0.angular_momentum[k]).abs());
        }
        Ok(())
    })
    .unwrap();
    let pl = d0.linear_momentum.iter().map(|v| v.abs()).fold(0.0, f64::max);
    let pa = d0.angular_momentum.iter().map(|v| v.abs()).fold(0.0, f64::max);
    assert!(max_l < 1e-13 * pl.max(1e-3), "{D}D linear momentum drift {max_l:e} (|P| {pl:e})");
    assert!(max_a < 1e-12 * pa.max(1e-3), "{D}D angular momentum drift {max_a:e} (|L| {pa:e})");
}

#[test]
fn momentum_conserved_free_floating_2d() {
    free_floating_momentum::<2>(Model::NeoHookean);
    free_floating_momentum::<2>(Model::FixedCorotated);
}

#[test]
fn momentum_conserved_free_floating_3d() {
    free_floating_momentum::<3>(Model::NeoHookean);
}

/// A thin 2D bar with ν = 0 (λ = 0: no lateral coupling, the 1D wave equation is exact for small
/// strain with c = sqrt(E/ρ)), pre-stretched by 1 % (F₀ = diag(1.01, 1)) and released: its length is
/// a triangle wave of period 2L/c (free–free bar). The fundamental wavelength 2L is 80 cells, so
/// MPM dispersion is negligible.
#[test]
fn stretched_bar_oscillates_at_1d_frequency() {
    let n_grid = 64;
    let grid = GridSpec::unit(n_grid);
    let dx = grid.dx;
    let (lx, ly) = (40.0 * dx, 4.0 * dx);
    let strain = 0.01;
    let lo = Vector::<2>::new(0.5 - lx / 2.0, 0.5 - ly / 2.0);
    let rest = box_lattice(lo, lo + Vector::<2>::new(lx, ly), dx / 2.0);
    let pos: Vec<Vector<2>> =
        rest.iter().map(|p| Vector::<2>::new(0.5 + (p[0] - 0.5) * (1.0 + strain), p[1])).collect();
    let material = Material { model: Model::NeoHookean, youngs_modulus: 1.0, poisson_ratio: 0.0, density: 1.0 };
    let c = (material.youngs_modulus / material.density).sqrt();
    let period = 2.0 * lx / c;
    let dt = cfl_dt(&material, dx, 0.2);
    let steps = (1.6 * period / dt).ceil() as usize;
    let mut scene = Scene::new(pos, (dx / 2.0).powi(2), material, grid, dt, steps);
    scene.boundary.walls = WallKind::None;
    scene.initial_deformation = vec![Matrix::<2>::new(1.0 + strain, 0.0, 0.0, 1.0); scene.n_particles()];
    let xmin = scene.positions.iter().map(|p| p[0]).fold(f64::INFINITY, f64::min);
    let xmax = scene.positions.iter().map(|p| p[0]).fold(f64::NEG_INFINITY, f64::max);
    let left: Vec<usize> = (0..scene.n_particles()).filter(|&p| scene.positions[p][0] < xmin + 1e-9).collect();
    let right: Vec<usize> = (0..scene.n_particles()).filter(|&p| scene.positions[p][0] > xmax - 1e-9).collect();
    let l0 = xmax - xmin;
    let mut series = Vec::new();
    simulate_observed(&scene, |s, st| {
        let mean = |ids: &[usize]| ids.iter().map(|&p| st.x[p][0]).sum::<f64>() / ids.len() as f64;
        series.push((s as f64 * dt, mean(&right) - mean(&left)));
        Ok(())
    })
    .unwrap();
    // Mid-level of the oscillation: the rest length between the end particles.
    let mid = l0 / (1.0 + strain);
    let mut crossings = Vec::new();
    for w in series.windows(2) {
        let (a, b) = (w[0].1 - mid, w[1].1 - mid);
        if a != 0.0 && a.signum() != b.signum() {
            crossings.push(w[0].0 + (w[1].0 - w[0].0) * a / (a - b));
        }
    }
    assert!(crossings.len() >= 3, "need three mid-level crossings, got {}", crossings.len());
    let measured = crossings[2] - crossings[0];
    let rel = (measured - period).abs() / period;
    eprintln!("bar period {measured:.5} vs 2L/c = {period:.5} (rel {rel:.4})");
    assert!(rel < 0.05, "period {measured:.4} vs 1D prediction 2L/c = {period:.4} (rel {rel:.3})");
}

#[test]
fn body_under_gravity_comes_to_rest_on_sticky_floor() {
    let mut scene = block::<2>(32, [6.0, 6.0], 0.5, 40.0, 0.3, 0);
    // lower the block so that it starts 2 cells above the wall layer
    let dx = scene.grid.dx;
    let ymin = scene.positions.iter().map(|p| p[1]).fold(f64::INFINITY, f64::min);
    for p in scene.positions.iter_mut() {
        p[1] += 5.0 * dx - ymin;
    }
    scene.gravity = Vector::<2>::new(0.0, -9.81);
    scene.steps = 10000;
    let mut ke = Vec::new();
    let sim = simulate_observed(&scene, |_, st| {
        ke.push(diagnostics(&scene, st).kinetic_energy);
        Ok(())
    })
    .unwrap();
    let peak = ke.iter().cloned().fold(0.0, f64::max);
    let last = *ke.last().unwrap();
    let m: f64 = scene.masses.iter().sum();
    let vcm = sim.final_state.v.iter().zip(&scene.masses).fold(Vector::<2>::zeros(), |a, (v, mp)| a + v * *mp) / m;
    assert!(peak > 0.0);
    assert!(last < 1e-3 * peak, "kinetic energy at the end {last:e} vs peak {peak:e}");
    let v_impact = (2.0 * peak / m).sqrt();
    eprintln!("KE end/peak {:.2e}, |v_cm| {:.2e}, peak speed {v_impact:.3}", last / peak, vcm.norm());
    assert!(vcm.norm() < 1e-2 * v_impact, "centre-of-mass velocity {vcm:?} vs impact speed {v_impact}");
    let ymin_end = sim.final_state.x.iter().map(|p| p[1]).fold(f64::INFINITY, f64::min);
    assert!(ymin_end < 3.5 * dx, "body rests on the floor (lowest particle at {:.2} cells)", ymin_end / dx);
}

#[test]
fn deterministic_across_thread_counts() {
    let mut scene = block::<3>(32, [6.0, 5.0, 4.0], 0.5, 3.0, 0.4, 40);
    for p in 0..scene.n_particles() {
        let r = scene.positions[p] - Vector::<3>::from_element(0.5);
        scene.velocities[p] = Vector::<3>::new(8.0 * r[0] + r[1], -r[0] + 0.1 * (p as f64).sin(), 2.0 * r[2]);
    }
    let loss = LandmarkLoss { indices: vec![0, 7, 50, 99], targets: vec![Vector::<3>::from_element(0.45); 4] };
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| simulate_with_gradient(&scene, &loss).unwrap())
    };
    let (a, b) = (run(1), run(2));
    let bits =
        |v: &[Vector<3>]| v.iter().flat_map(|x| x.iter().map(|c| c.to_bits()).collect::<Vec<_>>()).collect::<Vec<_>>();
    assert_eq!(bits(&a.final_state.x), bits(&b.final_state.x));
    assert_eq!(bits(&a.d_velocities), bits(&b.d_velocities));
    assert_eq!(bits(&a.d_positions), bits(&b.d_positions));
    assert_eq!(a.d_youngs_modulus.to_bits(), b.d_youngs_modulus.to_bits());
    assert_eq!(a.loss.to_bits(), b.loss.to_bits());
}

#[test]
fn deterministic_across_thread_counts_2d() {
    // A body wide enough for several colour tasks per phase (2D stripes of block columns).
    let mut scene = block::<2>(96, [40.0, 24.0], 0.5, 3.0, 0.4, 40);
    for p in 0..scene.n_particles() {
        let r = scene.positions[p] - Vector::<2>::from_element(0.5);
        scene.velocities[p] = Vector::<2>::new(6.0 * r[0] + r[1], -r[0] + 0.1 * (p as f64).sin());
    }
    let loss = LandmarkLoss { indices: vec![0, 7, 50, 99], targets: vec![Vector::<2>::from_element(0.45); 4] };
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| simulate_with_gradient(&scene, &loss).unwrap())
    };
    let bits =
        |v: &[Vector<2>]| v.iter().flat_map(|x| x.iter().map(|c| c.to_bits()).collect::<Vec<_>>()).collect::<Vec<_>>();
    let a = run(1);
    for threads in [2, 3] {
        let b = run(threads);
        assert_eq!(bits(&a.final_state.x), bits(&b.final_state.x));
        assert_eq!(bits(&a.d_velocities), bits(&b.d_velocities));
        assert_eq!(bits(&a.d_positions), bits(&b.d_positions));
        assert_eq!(a.d_youngs_modulus.to_bits(), b.d_youngs_modulus.to_bits());
        assert_eq!(a.loss.to_bits(), b.loss.to_bits());
    }
}

#[test]
fn bad_input_gives_clear_errors() {
    let ok = block::<2>(32, [4.0, 4.0], 0.5, 3.0, 0.3, 5);
    let mut s = ok.clone();
    s.positions.clear();
    s.velocities.clear();
    s.masses.clear();
    s.volumes.clear();
    assert!(matches!(simulate(&s), Err(MpmError::NoParticles)));
    for nu in [0.5, 0.7] {
        let mut s = ok.clone();
        s.material.poisson_ratio = nu;
        let e = simulate(&s).unwrap_err();
        assert!(e.to_string().contains("poisson_ratio"), "{e}");
    }
    for e_mod in [0.0, -1.0, f64::NAN] {
        let mut s = ok.clone();
        s.material.youngs_modulus = e_mod;
        let e = simulate(&s).unwrap_err();
        assert!(e.to_string().contains("youngs_modulus"), "{e}");
    }
    let mut s = ok.clone();
    s.positions[3] = Vector::<2>::new(1.2, 0.5);
    assert!(matches!(simulate(&s), Err(MpmError::OutsideDomain { particle: 3, step: 0 })));
    let mut s = ok.clone();
    s.masses.pop();
    assert!(matches!(simulate(&s), Err(MpmError::LengthMismatch { .. })));
}

#[test]
fn blow_up_is_detected_and_cfl_warned() {
    let mut s = block::<2>(32, [6.0, 6.0], 0.5, 3.0, 0.3, 400);
    for p in 0..s.n_particles() {
        let r = s.positions[p] - Vector::<2>::from_element(0.5);
        s.velocities[p] = Vector::<2>::new(30.0 * r[0], -30.0 * r[1]);
    }
    s.dt *= 40.0;
    assert!(!cfl_warnings(&s).is_empty(), "CFL warning expected");
    match simulate(&s) {
        Err(MpmError::BlowUp { step, .. }) | Err(MpmError::OutsideDomain { step, .. }) => assert!(step < 400),
        other => panic!("expected a blow-up error, got {:?}", other.map(|_| ())),
    }
    let s = block::<2>(32, [6.0, 6.0], 0.5, 3.0, 0.3, 10);
    assert!(simulate(&s).unwrap().warnings.is_empty());
}
