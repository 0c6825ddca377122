//! Grid update: node velocity v_i = (m v)_i / (m_i + ε), gravity, domain walls (every field of a
//! two-field grid alike).
use crate::linalg::Vector;
use crate::scene::{Scene, WallKind};
use crate::sparse_grid::{block_nodes, SparseGrid};
use rayon::prelude::*;

/// Compute node velocities from momenta and apply gravity and the wall conditions
/// (DiffTaichi `grid_op`: a node in the wall layer moving into the wall is stopped).
pub fn update<const D: usize>(grid: &mut SparseGrid<D>, scene: &Scene<D>) {
    let eps = scene.mass_epsilon;
    let dt = scene.dt;
    let n_grid = scene.grid.n_grid;
    let th = scene.boundary.thickness;
    let walls = scene.boundary.walls;
    let gravity = scene.gravity;
    // mass-proportional damping, implicit: v ← v / (1 + ζ Δt)
    let keep = 1.0 / (1.0 + scene.damping * dt);
    let nn = block_nodes(D);
    let SparseGrid { blocks, mass, mom, vel, wall_mask, .. } = grid;
    let blocks = &*blocks;
    // A two-field grid holds the second field's blocks after the first's, in the same order.
    let nb = blocks.len();
    vel.par_chunks_mut(nn)
        .zip(wall_mask.par_chunks_mut(nn))
        .zip(mass.par_chunks(nn).zip(mom.par_chunks(nn)))
        .enumerate()
        .with_min_len(16)
        .for_each(|(b, ((vel, mask), (mass, mom)))| {
            // Blocks away from the wall layers (most of them) skip the per-node wall tests.
            let b = b % nb;
            let interior = walls == WallKind::None
                || blocks[b].iter().all(|&c| {
                    let lo = c as usize * crate::sparse_grid::BLOCK;
                    lo >= th && lo + crate::sparse_grid::BLOCK - 1 + th <= n_grid
                });
            if interior {
                for l in 0..nn {
                    let denom = mass[l] + eps;
                    let mut v = if denom > 0.0 { mom[l] * (keep / denom) } else { Vector::<D>::zeros() };
                    v += gravity * dt;
                    vel[l] = v;
                    mask[l] = 0;
                }
                return;
            }
            for l in 0..nn {
                let denom = mass[l] + eps;
                let mut v = if denom > 0.0 { mom[l] * (keep / denom) } else { Vector::<D>::zeros() };
                v += gravity * dt;
                let mut mk = 0u8;
                if walls != WallKind::None {
                    let mut rem = l;
                    for d in 0..D {
                        let coord = blocks[b][d] as usize * crate::sparse_grid::BLOCK + rem % crate::sparse_grid::BLOCK;
                        rem /= crate::sparse_grid::BLOCK;
                        let into = (coord < th && v[d] < 0.0) || (coord + th > n_grid && v[d] > 0.0);
                        if into {
                            match walls {
                                WallKind::Sticky => {
                                    v = Vector::<D>::zeros();
                                    mk = (1u8 << D) - 1;
                                }
                                _ => {
                                    v[d] = 0.0;
                                    mk |= 1 << d;
                                }
                            }
                        }
                    }
                }
                vel[l] = v;
                mask[l] = mk;
            }
        });
}
