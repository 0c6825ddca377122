//! The two-field grid of a pre-existing crack (`Scene::crack_side`): exact separation of the two lips
//! (by hand: rigid translations), unchanged results without a labelled particle, exact momentum
//! conservation and the crack front still coupling both sides (the adjoint: `gradient_check.rs`).
use laparo_mpm::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A block of particles (spacing Δx/2) centred at 0.5 with `cells` cells per axis, E 3, ν 0.3.
fn block<const D: usize>(n_grid: usize, cells: [f64; D], steps: usize) -> Scene<D> {
    let grid = GridSpec::unit(n_grid);
    let dx = grid.dx;
    let c = Vector::<D>::from_element(0.5);
    let half = Vector::<D>::from_fn(|d, _| cells[d] * dx / 2.0);
    let pos = box_lattice(c - half, c + half, dx / 2.0);
    let material = Material { model: Model::NeoHookean, youngs_modulus: 3.0, poisson_ratio: 0.3, density: 1.0 };
    let dt = cfl_dt(&material, dx, 0.25);
    let mut s = Scene::new(pos, (dx / 2.0).powi(D as i32), material, grid, dt, steps);
    s.boundary.walls = WallKind::None;
    s
}

/// Side −1 left of x = `xc`, +1 right of it, for particles with `in_crack(x)`; 0 elsewhere.
fn label<const D: usize>(scene: &mut Scene<D>, xc: f64, in_crack: impl Fn(&Vector<D>) -> bool) {
    scene.crack_side = scene
        .positions
        .iter()
        .map(|x| {
            if !in_crack(x) {
                0
            } else if x[0] < xc {
                -1
            } else {
                1
            }
        })
        .collect();
}

/// Two lips cut through the whole block, moving apart at ±v: every particle translates rigidly
/// (no stress arises: C stays 0 and F = I), x_T = x₀ ± v T Δt exactly. The one-field grid couples
/// them across the shared nodes instead.
fn lips_separate<const D: usize>() {
    let mut scene = block::<D>(32, [6.0; D], 40);
    let v = 0.3;
    for p in 0..scene.n_particles() {
        scene.velocities[p][0] = if scene.positions[p][0] < 0.5 { -v } else { v };
    }
    let one = simulate(&scene).unwrap().final_state;
    label(&mut scene, 0.5, |_| true);
    let two = simulate(&scene).unwrap().final_state;
    let t = scene.steps as f64 * scene.dt;
    let mut max_err = 0.0f64;
    let mut max_one = 0.0f64;
    for p in 0..scene.n_particles() {
        let mut want = scene.positions[p];
        want[0] += scene.velocities[p][0] * t;
        max_err = max_err.max((two.x[p] - want).norm());
        max_one = max_one.max((one.x[p] - want).norm());
        assert!((two.f[p] - Matrix::<D>::identity()).norm() < 1e-12, "{D}D particle {p}: F = I");
    }
    assert!(max_err < 1e-12, "{D}D two-field: max deviation from the rigid translations {max_err:e}");
    // the one-field grid averages the lips' velocities on shared nodes: they do not translate freely
    assert!(max_one > 0.1 * v * t, "{D}D one-field deviation {max_one:e} vs opening {:e}", v * t);
}

#[test]
fn cut_lips_translate_apart_exactly_2d() {
    lips_separate::<2>();
}

#[test]
fn cut_lips_translate_apart_exactly_3d() {
    lips_separate::<3>();
}

/// All labels 0 (a crack that is nowhere): the same trajectory, bit for bit, as no crack at all.
#[test]
fn unlabelled_crack_changes_nothing() {
    let mut scene = block::<3>(24, [5.0, 4.0, 4.0], 30);
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    for p in 0..scene.n_particles() {
        scene.velocities[p] = Vector::<3>::from_fn(|_, _| rng.gen_range(-0.5..0.5));
    }
    let a = simulate(&scene).unwrap().final_state;
    scene.crack_side = vec![0; scene.n_particles()];
    let b = simulate(&scene).unwrap().final_state;
    assert_eq!(a.x, b.x);
    assert_eq!(a.f, b.f);
}

/// Each particle scatters to exactly one field of each node and gathers from the same one: linear
/// momentum is conserved to round-off with a half-cut, elastically loaded block.
#[test]
fn two_field_conserves_linear_momentum() {
    let mut scene = block::<2>(32, [8.0, 8.0], 120);
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    for p in 0..scene.n_particles() {
        let x = scene.positions[p];
        scene.velocities[p] = Vector::<2>::new(3.0 * (x[0] - 0.5) + 0.1, -(x[0] - 0.5))
            + Vector::<2>::from_fn(|_, _| rng.gen_range(-0.2..0.2));
    }
    label(&mut scene, 0.5, |x| x[1] > 0.5);
    let d0 = diagnostics(&scene, &ParticleState::initial(&scene));
    let mut drift = 0.0f64;
    simulate_observed(&scene, |_, st| {
        let d = diagnostics(&scene, st);
        for k in 0..3 {
            drift = drift.max((d.linear_momentum[k] - d0.linear_momentum[k]).abs());
        }
        Ok(())
    })
    .unwrap();
    let p0 = d0.linear_momentum.iter().map(|v| v.abs()).fold(0.0, f64::max);
    assert!(drift < 1e-13 * p0.max(1e-3), "linear momentum drift {drift:e} (|P| {p0:e})");
}

/// A crack through the top half only, lips pulled apart: the cut half opens (its lips separate by
/// nearly the imposed opening) while the uncut half ahead of the crack front holds together.
#[test]
fn crack_front_keeps_the_uncut_part_together() {
    let mut scene = block::<2>(48, [12.0, 12.0], 60);
    let v = 0.4;
    for p in 0..scene.n_particles() {
        let x = scene.positions[p];
        if x[1] > 0.5 {
            scene.velocities[p][0] = if x[0] < 0.5 { -v } else { v };
        }
    }
    label(&mut scene, 0.5, |x| x[1] > 0.5);
    let fin = simulate(&scene).unwrap().final_state;
    // mean x-gap between the particle columns on each side of x = 0.5, in a row band
    let gap = |lo: f64, hi: f64, x: &[Vector<2>]| {
        let (mut l, mut nl, mut r, mut nr) = (0.0, 0, 0.0, 0);
        for (x0, xp) in scene.positions.iter().zip(x) {
            if x0[1] > lo && x0[1] < hi && (x0[0] - 0.5).abs() < 0.5 * scene.grid.dx {
                if x0[0] < 0.5 {
                    l += xp[0];
                    nl += 1;
                } else {
                    r += xp[0];
                    nr += 1;
                }
            }
        }
        r / nr as f64 - l / nl as f64
    };
    let rest_top = gap(0.6, 0.7, &scene.positions);
    let open_top = gap(0.6, 0.7, &fin.x) - rest_top;
    let open_bottom = gap(0.3, 0.4, &fin.x) - gap(0.3, 0.4, &scene.positions);
    let imposed = 2.0 * v * scene.steps as f64 * scene.dt;
    assert!(open_top > 0.5 * imposed, "cut half opens: {open_top:e} of {imposed:e}");
    assert!(open_bottom < 0.1 * open_top, "uncut half stays closed: {open_bottom:e} vs {open_top:e}");
}

#[test]
fn bad_crack_side_is_refused() {
    let mut scene = block::<2>(32, [4.0, 4.0], 2);
    scene.crack_side = vec![0; 3];
    let e = simulate(&scene).unwrap_err().to_string();
    assert!(e.contains("crack_side"), "{e}");
    scene.crack_side = vec![2; scene.n_particles()];
    let e = simulate(&scene).unwrap_err().to_string();
    assert!(e.contains("crack_side") && e.contains("-1, 0 or +1"), "{e}");
}
