//! Central finite differences (f64) against the hand-derived adjoint, on 2D and 3D scenes with
//! large deformation (> 50 % stretch), for initial velocities, initial positions, E and ν; and through
//! the two-field grid of a crack (`Scene::crack_side`).
use laparo_mpm::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A block of particles (2 per cell per axis) centred in a unit domain, pulled apart along x by
/// v = k (x − c) plus a rotation and a random perturbation.
fn stretch_scene<const D: usize>(n_grid: usize, cells: [f64; D], steps: usize, model: Model, seed: u64) -> Scene<D> {
    let k = if D == 2 { 22.0 } else { 30.0 };
    let e = if D == 3 && model == Model::FixedCorotated { 1.2 } else { 2.0 };
    let grid = GridSpec::unit(n_grid);
    let dx = grid.dx;
    let half = Vector::<D>::from_fn(|d, _| cells[d] * dx / 2.0);
    let c = Vector::<D>::from_element(0.5);
    let pos = box_lattice(c - half, c + half, dx / 2.0);
    let material = Material { model, youngs_modulus: e, poisson_ratio: 0.3, density: 1.0 };
    let dt = cfl_dt(&material, dx, 0.25);
    let mut scene = Scene::new(pos, (dx / 2.0).powi(D as i32), material, grid, dt, steps);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    for p in 0..scene.n_particles() {
        let r = scene.positions[p] - c;
        let mut v = Vector::<D>::zeros();
        v[0] = k * r[0];
        v[0] -= r[1];
        v[1] += 1.0 * r[0];
        for d in 0..D {
            v[d] += 0.05 * rng.gen_range(-1.0..1.0);
        }
        scene.velocities[p] = v;
    }
    scene.mass_epsilon = 1e-10;
    scene
}

fn random_loss<const D: usize>(scene: &Scene<D>, seed: u64) -> LandmarkLoss<D> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let n = scene.n_particles();
    let indices: Vec<usize> = (0..20).map(|_| rng.gen_range(0..n)).collect();
    let targets =
        indices.iter().map(|&p| scene.positions[p] + Vector::<D>::from_fn(|_, _| rng.gen_range(-0.05..0.05))).collect();
    LandmarkLoss { indices, targets }
}

fn loss_of<const D: usize>(scene: &Scene<D>, loss: &LandmarkLoss<D>) -> f64 {
    let fin = simulate(scene).unwrap().final_state;
    let mut g = vec![Vector::<D>::zeros(); fin.x.len()];
    loss.evaluate(scene.steps, &fin.x, &mut g)
}

fn rel_err(fd: f64, ad: f64) -> f64 {
    (fd - ad).abs() / fd.abs().max(ad.abs()).max(1e-300)
}

fn max_stretch<const D: usize>(f: &[Matrix<D>]) -> f64 {
    // Largest singular value by power iteration on FᵀF.
    f.iter()
        .map(|f| {
            let m = f.transpose() * f;
            let mut v = Vector::<D>::from_element(1.0);
            for _ in 0..100 {
                v = (m * v).normalize();
            }
            (v.dot(&(m * v))).sqrt()
        })
        .fold(0.0, f64::max)
}

fn check<const D: usize>(scene: Scene<D>, seed: u64) {
    let loss = random_loss(&scene, seed);
    let g = simulate_with_gradient(&scene, &loss).unwrap();
    let stretch = max_stretch(&g.final_state.f);
    assert!(stretch > 1.5, "scene must stretch > 50 % (max principal stretch {stretch})");
    assert!((g.loss - loss_of(&scene, &loss)).abs() < 1e-14, "forward of simulate_with_gradient == simulate");
    let mut rng = ChaCha8Rng::seed_from_u64(seed + 1);
    let n = scene.n_particles();
    for trial in 0..2 {
        // initial velocities
        let dir: Vec<Vector<D>> = (0..n).map(|_| Vector::<D>::from_fn(|_, _| rng.gen_range(-1.0..1.0))).collect();
        let h = 1e-5;
        let mut sp = scene.clone();
        let mut sm = scene.clone();
        for (p, d) in dir.iter().enumerate() {
            sp.velocities[p] += d * h;
            sm.velocities[p] -= d * h;
        }
        let fd = (loss_of(&sp, &loss) - loss_of(&sm, &loss)) / (2.0 * h);
        let ad: f64 = (0..n).map(|p| g.d_velocities[p].dot(&dir[p])).sum();
        eprintln!("D={D} {:?} v0 rel {:.2e}", scene.material.model, rel_err(fd, ad));
        assert!(
            rel_err(fd, ad) < 1e-5,
            "D={D} trial {trial} d/dv0: fd {fd:.12e} adjoint {ad:.12e} rel {:.2e}",
            rel_err(fd, ad)
        );
        // initial positions (the loss is much more curved in x₀: small step)
        let h = 1e-8;
        let mut sp = scene.clone();
        let mut sm = scene.clone();
        for (p, d) in dir.iter().enumerate() {
            sp.positions[p] += d * h;
            sm.positions[p] -= d * h;
        }
        let fd = (loss_of(&sp, &loss) - loss_of(&sm, &loss)) / (2.0 * h);
        let ad: f64 = (0..n).map(|p| g.d_positions[p].dot(&dir[p])).sum();
        eprintln!("D={D} {:?} x0 rel {:.2e}", scene.material.model, rel_err(fd, ad));
        assert!(
            rel_err(fd, ad) < 1e-5,
            "D={D} trial {trial} d/dx0: fd {fd:.12e} adjoint {ad:.12e} rel {:.2e}",
            rel_err(fd, ad)
        );
    }
    // E and nu
    let h = 1e-5 * scene.material.youngs_modulus;
    let mut sp = scene.clone();
    let mut sm = scene.clone();
    sp.material.youngs_modulus += h;
    sm.material.youngs_modulus -= h;
    let fd = (loss_of(&sp, &loss) - loss_of(&sm, &loss)) / (2.0 * h);
    eprintln!("D={D} {:?} E rel {:.2e} (stretch {stretch:.2})", scene.material.model, rel_err(fd, g.d_youngs_modulus));
    assert!(rel_err(fd, g.d_youngs_modulus) < 1e-5, "D={D} dE: fd {fd:.12e} adjoint {:.12e}", g.d_youngs_modulus);
    let h = 1e-6;
    let mut sp = scene.clone();
    let mut sm = scene.clone();
    sp.material.poisson_ratio += h;
    sm.material.poisson_ratio -= h;
    let fd = (loss_of(&sp, &loss) - loss_of(&sm, &loss)) / (2.0 * h);
    eprintln!("D={D} {:?} nu rel {:.2e}", scene.material.model, rel_err(fd, g.d_poisson_ratio));
    assert!(rel_err(fd, g.d_poisson_ratio) < 1e-5, "D={D} dnu: fd {fd:.12e} adjoint {:.12e}", g.d_poisson_ratio);
}

#[test]
fn gradient_check_2d_neo_hookean() {
    check(stretch_scene::<2>(32, [8.0, 6.0], 60, Model::NeoHookean, 1), 11);
}

#[test]
fn gradient_check_3d_neo_hookean() {
    check(stretch_scene::<3>(24, [5.0, 4.0, 4.0], 50, Model::NeoHookean, 2), 12);
}

#[test]
fn gradient_check_2d_fixed_corotated() {
    check(stretch_scene::<2>(32, [8.0, 6.0], 60, Model::FixedCorotated, 3), 13);
}

#[test]
fn gradient_check_3d_fixed_corotated() {
    check(stretch_scene::<3>(24, [5.0, 4.0, 4.0], 50, Model::FixedCorotated, 4), 14);
}

/// A loss observed at intermediate steps as well as the final one, with gravity, external forces
/// and fixed particles.
#[test]
fn gradient_check_intermediate_loss_and_forces_2d() {
    let mut scene = stretch_scene::<2>(32, [8.0, 6.0], 40, Model::NeoHookean, 5);
    let n = scene.n_particles();
    scene.gravity = Vector::<2>::new(0.0, -2.0);
    scene.external_forces = (0..n).map(|p| Vector::<2>::new(1e-4 * (p % 7) as f64, 0.0)).collect();
    scene.fixed = (0..n).map(|p| p % 13 == 0).collect();
    let w: Vec<Vector<2>> = (0..n).map(|p| Vector::<2>::new(((p * 3) as f64).sin(), ((p * 5) as f64).cos())).collect();
    let loss = StepsLoss {
        steps: vec![10, 25, 40],
        f: |s: usize, x: &[Vector<2>], g: &mut [Vector<2>]| {
            let mut l = 0.0;
            for p in 0..x.len() {
                l += (s as f64) * w[p].dot(&x[p]) + 0.5 * x[p].norm_squared();
                g[p] += w[p] * s as f64 + x[p];
            }
            l
        },
    };
    let eval = |sc: &Scene<2>| {
        let mut total = 0.0;
        simulate_observed(sc, |s, st| {
            if loss.observes(s, sc.steps) {
                let mut g = vec![Vector::<2>::zeros(); n];
                total += loss.evaluate(s, &st.x, &mut g);
            }
            Ok(())
        })
        .unwrap();
        total
    };
    let g = simulate_with_gradient(&scene, &loss).unwrap();
    assert!((g.loss - eval(&scene)).abs() < 1e-12 * g.loss.abs());
    let mut rng = ChaCha8Rng::seed_from_u64(99);
    let dir: Vec<Vector<2>> = (0..n).map(|_| Vector::<2>::from_fn(|_, _| rng.gen_range(-1.0..1.0))).collect();
    let h = 1e-5;
    let (mut sp, mut sm) = (scene.clone(), scene.clone());
    for (p, d) in dir.iter().enumerate() {
        sp.velocities[p] += d * h;
        sm.velocities[p] -= d * h;
    }
    let fd = (eval(&sp) - eval(&sm)) / (2.0 * h);
    let ad: f64 = (0..n).map(|p| g.d_velocities[p].dot(&dir[p])).sum();
    assert!(rel_err(fd, ad) < 1e-5, "d/dv0 fd {fd} ad {ad}");
    let h = 1e-8;
    let (mut sp, mut sm) = (scene.clone(), scene.clone());
    for (p, d) in dir.iter().enumerate() {
        sp.positions[p] += d * h;
        sm.positions[p] -= d * h;
    }
    let fd = (eval(&sp) - eval(&sm)) / (2.0 * h);
    let ad: f64 = (0..n).map(|p| g.d_positions[p].dot(&dir[p])).sum();
    assert!(rel_err(fd, ad) < 1e-5, "d/dx0 fd {fd} ad {ad}");
}

/// ∂L/∂v₀, ∂L/∂x₀ and ∂L/∂E through the two-field grid against central differences (the node sides
/// are constant under the small perturbations, so L is smooth there).
fn two_field_check<const D: usize>(n_grid: usize, cells: [f64; D], steps: usize, seed: u64) {
    let mut scene = stretch_scene::<D>(n_grid, cells, steps, Model::NeoHookean, seed);
    scene.mass_epsilon = 1e-10;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    for p in 0..scene.n_particles() {
        let x = scene.positions[p];
        let mut v = Vector::<D>::from_fn(|_, _| 0.05 * rng.gen_range(-1.0..1.0));
        v[0] += if x[0] < 0.5 + 0.5 * scene.grid.dx { -1.0 } else { 1.0 } * if x[1] > 0.5 { 1.0 } else { 0.2 };
        v[1] += 2.0 * (x[0] - 0.5);
        scene.velocities[p] = v;
    }
    // the crack between two particle columns and midway between two node planes: no node side sum is
    // near 0, so the partition of the fields does not change under the perturbations
    let xc = 0.5 + 0.5 * scene.grid.dx;
    scene.crack_side = scene
        .positions
        .iter()
        .map(|x| {
            if x[1] <= 0.5 {
                0
            } else if x[0] < xc {
                -1
            } else {
                1
            }
        })
        .collect();
    let loss = random_loss(&scene, seed + 1);
    let g = simulate_with_gradient(&scene, &loss).unwrap();
    assert!((g.loss - loss_of(&scene, &loss)).abs() < 1e-14);
    let n = scene.n_particles();
    let dir: Vec<Vector<D>> = (0..n).map(|_| Vector::<D>::from_fn(|_, _| rng.gen_range(-1.0..1.0))).collect();
    for (what, h) in [("v0", 1e-5), ("x0", 1e-8)] {
        let (mut sp, mut sm) = (scene.clone(), scene.clone());
        for (p, d) in dir.iter().enumerate() {
            if what == "v0" {
                sp.velocities[p] += d * h;
                sm.velocities[p] -= d * h;
            } else {
                sp.positions[p] += d * h;
                sm.positions[p] -= d * h;
            }
        }
        let fd = (loss_of(&sp, &loss) - loss_of(&sm, &loss)) / (2.0 * h);
        let grad = if what == "v0" { &g.d_velocities } else { &g.d_positions };
        let ad: f64 = (0..n).map(|p| grad[p].dot(&dir[p])).sum();
        assert!(rel_err(fd, ad) < 1e-5, "{D}D d/d{what}: fd {fd:.12e} adjoint {ad:.12e}");
    }
    let h = 1e-5 * scene.material.youngs_modulus;
    let (mut sp, mut sm) = (scene.clone(), scene.clone());
    sp.material.youngs_modulus += h;
    sm.material.youngs_modulus -= h;
    let fd = (loss_of(&sp, &loss) - loss_of(&sm, &loss)) / (2.0 * h);
    assert!(rel_err(fd, g.d_youngs_modulus) < 1e-5, "{D}D dE: fd {fd:.12e} adjoint {:.12e}", g.d_youngs_modulus);
}

#[test]
fn two_field_gradient_check_2d() {
    two_field_check::<2>(32, [8.0, 6.0], 40, 21);
}

#[test]
fn two_field_gradient_check_3d() {
    two_field_check::<3>(24, [5.0, 4.0, 4.0], 30, 22);
}
