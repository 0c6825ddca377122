//! The adjoint's terminal condition on the final velocities ([`Loss::terminal_velocity`], the at-rest
//! prior of RODS-MPM's ladder L2): a landmark loss plus ½ Σ c_p |v_T,p|², its gradient in v₀ and E against
//! central differences, in 2D and 3D, on one field and on the two-field grid of a crack.
mod common;
use laparo_mpm::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Landmarks plus a terminal kinetic-energy term with per-particle coefficients.
struct WithTerminal<const D: usize> {
    landmarks: LandmarkLoss<D>,
    coef: Vec<f64>,
}

impl<const D: usize> Loss<D> for WithTerminal<D> {
    fn evaluate(&self, step: usize, x: &[Vector<D>], grad: &mut [Vector<D>]) -> f64 {
        self.landmarks.evaluate(step, x, grad)
    }
    fn terminal_velocity(&self, v: &[Vector<D>], grad: &mut [Vector<D>]) -> f64 {
        let mut total = 0.0;
        for ((g, c), v) in grad.iter_mut().zip(&self.coef).zip(v) {
            *g += v * *c;
            total += 0.5 * c * v.norm_squared();
        }
        total
    }
}

fn scene<const D: usize>(steps: usize, cracked: bool, seed: u64) -> Scene<D> {
    let dx = 1.0 / 16.0;
    let half = Vector::<D>::from_fn(|d, _| if d == 0 { 3.0 * dx } else { 2.0 * dx });
    let material = Material { model: Model::NeoHookean, youngs_modulus: 3.0, poisson_ratio: 0.3, density: 1.0 };
    let mut s = common::centred_block(16, half, material, steps);
    let c = Vector::<D>::from_element(0.5);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    for p in 0..s.n_particles() {
        let r = s.positions[p] - c;
        s.velocities[p] = Vector::<D>::from_fn(|d, _| 4.0 * r[d] + 0.2 * rng.gen_range(-1.0..1.0));
    }
    if cracked {
        s.crack_side = common::upper_half_crack(&s.positions);
    }
    s.mass_epsilon = 1e-10;
    s
}

fn loss_for<const D: usize>(s: &Scene<D>, seed: u64) -> WithTerminal<D> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let n = s.n_particles();
    let landmarks = common::random_landmarks(s, 8, &mut rng);
    let coef = (0..n).map(|p| 40.0 * s.masses[p] * rng.gen_range(0.5..1.5)).collect();
    WithTerminal { landmarks, coef }
}

fn value<const D: usize>(s: &Scene<D>, l: &WithTerminal<D>) -> f64 {
    let fin = simulate(s).unwrap().final_state;
    let n = fin.x.len();
    let mut g = vec![Vector::<D>::zeros(); n];
    let mut gv = vec![Vector::<D>::zeros(); n];
    l.evaluate(s.steps, &fin.x, &mut g) + l.terminal_velocity(&fin.v, &mut gv)
}

fn check<const D: usize>(cracked: bool, seed: u64) {
    let s = scene::<D>(12, cracked, seed);
    let l = loss_for(&s, seed + 7);
    let g = simulate_with_gradient(&s, &l).unwrap();
    let forward = value(&s, &l);
    assert!((g.loss - forward).abs() < 1e-13 * forward.abs().max(1.0), "{} vs {forward}", g.loss);
    // the terminal term is a real part of the loss here
    let mut gv = vec![Vector::<D>::zeros(); s.n_particles()];
    let vt = l.terminal_velocity(&g.final_state.v, &mut gv);
    assert!(vt > 0.1 * g.loss, "terminal term {vt} of {}", g.loss);
    let mut rng = ChaCha8Rng::seed_from_u64(seed + 1);
    let n = s.n_particles();
    let dir: Vec<Vector<D>> = (0..n).map(|_| Vector::<D>::from_fn(|_, _| rng.gen_range(-1.0..1.0))).collect();
    let h = 1e-5;
    let (mut sp, mut sm) = (s.clone(), s.clone());
    for (p, d) in dir.iter().enumerate() {
        sp.velocities[p] += d * h;
        sm.velocities[p] -= d * h;
    }
    let fd = (value(&sp, &l) - value(&sm, &l)) / (2.0 * h);
    let ad: f64 = (0..n).map(|p| g.d_velocities[p].dot(&dir[p])).sum();
    let rel = (fd - ad).abs() / fd.abs().max(ad.abs());
    assert!(rel < 1e-5, "D={D} crack={cracked} d/dv0: fd {fd:.12e} adjoint {ad:.12e} rel {rel:.2e}");
    let h = 1e-5 * s.material.youngs_modulus;
    let (mut sp, mut sm) = (s.clone(), s.clone());
    sp.material.youngs_modulus += h;
    sm.material.youngs_modulus -= h;
    let fd = (value(&sp, &l) - value(&sm, &l)) / (2.0 * h);
    let rel = (fd - g.d_youngs_modulus).abs() / fd.abs().max(g.d_youngs_modulus.abs());
    assert!(rel < 1e-5, "D={D} crack={cracked} d/dE: fd {fd:.12e} adjoint {:.12e} rel {rel:.2e}", g.d_youngs_modulus);
}

#[test]
fn terminal_velocity_gradient_matches_central_differences_2d() {
    check::<2>(false, 3);
    check::<2>(true, 4);
}

#[test]
fn terminal_velocity_gradient_matches_central_differences_3d() {
    check::<3>(false, 5);
    check::<3>(true, 6);
}

/// With zero steps the final velocities are v₀: the gradient is c_p v₀,p exactly.
#[test]
fn terminal_velocity_with_no_step_is_its_own_gradient() {
    let s = scene::<2>(0, false, 9);
    let l = loss_for(&s, 10);
    let g = simulate_with_gradient(&s, &l).unwrap();
    for p in 0..s.n_particles() {
        let want = s.velocities[p] * l.coef[p];
        // plus the landmark term's (zero: landmarks depend on x only)
        assert!((g.d_velocities[p] - want).norm() < 1e-15 * (1.0 + want.norm()), "particle {p}");
    }
}
