//! Two-level checkpointing of the adjoint (`Scene::checkpoint_segment`): keeping every k-th step's state
//! and recomputing each segment in the reverse pass gives the same loss, gradient and final state bit for
//! bit as keeping every step (a step is deterministic), for segment lengths that divide T and that do not,
//! with intermediate loss terms, fixed particles and a two-field crack; `checkpoint_segment_for` by hand.
mod common;
use laparo_mpm::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A block of particles (spacing Δx/2) with random initial velocities, some fixed, a crack across its
/// middle for `crack`.
fn scene<const D: usize>(steps: usize, crack: bool) -> Scene<D> {
    let grid = GridSpec::unit(24);
    let dx = grid.dx;
    let c = Vector::<D>::from_element(0.5);
    let half = Vector::<D>::from_element(3.0 * dx);
    let pos = box_lattice(c - half, c + half, dx / 2.0);
    let material = Material { model: Model::NeoHookean, youngs_modulus: 3.0, poisson_ratio: 0.4, density: 1.0 };
    let dt = cfl_dt(&material, dx, 0.25);
    let mut s = Scene::new(pos, (dx / 2.0).powi(D as i32), material, grid, dt, steps);
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    for v in s.velocities.iter_mut() {
        *v = Vector::<D>::from_fn(|_, _| rng.gen_range(-1.5..1.5));
    }
    s.fixed = s.positions.iter().map(|x| x[1] < 0.5 - 2.5 * dx).collect();
    if crack {
        s.crack_side = common::upper_half_crack(&s.positions);
    }
    s
}

fn same<const D: usize>(a: &GradientResult<D>, b: &GradientResult<D>, what: &str) {
    assert_eq!(a.loss.to_bits(), b.loss.to_bits(), "{what}: loss");
    assert_eq!(a.d_velocities, b.d_velocities, "{what}: dL/dv0");
    assert_eq!(a.d_positions, b.d_positions, "{what}: dL/dx0");
    assert_eq!(a.d_affine, b.d_affine, "{what}: dL/dC0");
    assert_eq!(a.d_deformation, b.d_deformation, "{what}: dL/dF0");
    assert_eq!(a.d_mu.to_bits(), b.d_mu.to_bits(), "{what}: dL/dmu");
    assert_eq!(a.d_lambda.to_bits(), b.d_lambda.to_bits(), "{what}: dL/dlambda");
    assert_eq!(a.final_state.x, b.final_state.x, "{what}: final x");
    assert_eq!(a.final_state.f, b.final_state.f, "{what}: final F");
}

fn segments_give_the_same_gradient<const D: usize>(crack: bool) {
    let steps = 41;
    let base = scene::<D>(steps, crack);
    let n = base.n_particles();
    // terms at steps 5, 16 and the last: the recomputed segments must not lose them
    let loss = StepsLoss {
        steps: vec![5, 16, 30, steps],
        f: |s: usize, x: &[Vector<D>], g: &mut [Vector<D>]| {
            let w = 1.0 + s as f64 / 10.0;
            let mut total = 0.0;
            for p in (0..x.len()).step_by(3) {
                let d = x[p] - Vector::<D>::from_element(0.45);
                total += w * d.norm_squared();
                g[p] += 2.0 * w * d;
            }
            total
        },
    };
    let reference = simulate_with_gradient(&base, &loss).unwrap();
    assert!(reference.d_velocities.iter().any(|v| v.norm() > 0.0));
    let mut ws = GradientWorkspace::new();
    for k in [2, 4, 5, 7, 11, 22, 40, 41, 60] {
        let s = Scene { checkpoint_segment: k, ..base.clone() };
        // a fresh workspace, and one reused across segment lengths (as a registration does)
        same(&simulate_with_gradient(&s, &loss).unwrap(), &reference, &format!("{D}D crack {crack} k {k}"));
        same(&simulate_with_gradient_in(&mut ws, &s, &loss).unwrap(), &reference, &format!("{D}D reused k {k}"));
    }
    // and back to every step on the same workspace
    same(&simulate_with_gradient_in(&mut ws, &base, &loss).unwrap(), &reference, "back to k 0");
    assert_eq!(reference.final_state.x.len(), n);
}

#[test]
fn segments_give_the_same_gradient_2d_and_3d() {
    segments_give_the_same_gradient::<2>(false);
    segments_give_the_same_gradient::<3>(false);
    segments_give_the_same_gradient::<3>(true);
}

#[test]
fn zero_steps_and_the_segment_for_a_budget() {
    let s = Scene { checkpoint_segment: 4, ..scene::<2>(0, false) };
    let loss = FinalLoss(|x: &[Vector<2>], g: &mut [Vector<2>]| {
        g[0] += Vector::<2>::new(1.0, 0.0);
        x[0][0]
    });
    let r = simulate_with_gradient(&s, &loss).unwrap();
    assert_eq!(r.loss, s.positions[0][0]);
    assert_eq!(r.d_positions[0], Vector::<2>::new(1.0, 0.0));
    // 1,000 particles × 100 B per particle-step: T = 200 steps need 20 MB
    assert_eq!(checkpoint_segment_for(1000, 200, 100.0, 20e6), Some(0));
    // 10 MB = 100 steps' worth: the longest k with ⌈200/k⌉ + k ≤ 100 is 97 (3 + 97)
    assert_eq!(checkpoint_segment_for(1000, 200, 100.0, 10e6), Some(97));
    // 3 MB = 30 steps' worth: ⌈200/k⌉ + k ≤ 30 holds for k = 10 … 20 (20 + 10, 10 + 20): the longest is 20
    assert_eq!(checkpoint_segment_for(1000, 200, 100.0, 3e6), Some(20));
    // below 2√200 ≈ 28.3 steps' worth nothing fits
    assert_eq!(checkpoint_segment_for(1000, 200, 100.0, 2.8e6), None);
}
