//! Scenes shared by the gradient tests: a block of particles (2 per cell per axis) centred in a unit domain,
//! and the crack through its upper half.
#![allow(dead_code)]
use laparo_mpm::*;
use rand::Rng;
use rand_chacha::ChaCha8Rng;

/// A block of half-extent `half` (domain units) centred at 0.5 in a unit grid of `n_grid` cells, particles
/// 2 per cell per axis, Δt from the CFL condition at 0.25, `steps` steps, at rest.
pub fn centred_block<const D: usize>(n_grid: usize, half: Vector<D>, material: Material, steps: usize) -> Scene<D> {
    let grid = GridSpec::unit(n_grid);
    let dx = grid.dx;
    let c = Vector::<D>::from_element(0.5);
    let pos = box_lattice(c - half, c + half, dx / 2.0);
    let dt = cfl_dt(&material, dx, 0.25);
    Scene::new(pos, (dx / 2.0).powi(D as i32), material, grid, dt, steps)
}

/// Crack sides of a crack along x = 0.5 through the upper half (y > 0.5): −1 left, +1 right, 0 below.
pub fn upper_half_crack<const D: usize>(positions: &[Vector<D>]) -> Vec<i8> {
    positions
        .iter()
        .map(|x| {
            if x[1] > 0.5 {
                if x[0] < 0.5 {
                    -1
                } else {
                    1
                }
            } else {
                0
            }
        })
        .collect()
}

/// `count` random landmark particles of `s`, each with a target within ±0.05 of its rest position per axis.
pub fn random_landmarks<const D: usize>(s: &Scene<D>, count: usize, rng: &mut ChaCha8Rng) -> LandmarkLoss<D> {
    let n = s.n_particles();
    let indices: Vec<usize> = (0..count).map(|_| rng.gen_range(0..n)).collect();
    let targets =
        indices.iter().map(|&p| s.positions[p] + Vector::<D>::from_fn(|_, _| rng.gen_range(-0.05..0.05))).collect();
    LandmarkLoss { indices, targets }
}
