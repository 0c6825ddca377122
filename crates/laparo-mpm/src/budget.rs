//! Memory estimate of a forward simulation, checked (by [`crate::load_scene_file`]) before anything
//! large is allocated.

/// Scene files whose estimate exceeds this are refused by default: 8 GiB.
pub const DEFAULT_MEMORY_LIMIT_BYTES: u64 = 8 << 30;

/// Estimated peak memory (bytes) of a forward simulation ([`crate::simulate_observed`]) of
/// `n_particles` particles in `dim` dimensions on a grid of `n_grid` cells per axis whose particle
/// stencils touch at most `active_blocks` blocks of 4^dim nodes: the block table and counting-sort
/// counters (8 B per block of the full grid), per particle the scene arrays, two particle states,
/// the stress buffer and the sort keys, per active block its nodes (mass, momentum, velocity, wall
/// mask) and its 6^dim node window. f64 so that absurd inputs do not overflow.
pub fn estimate_memory_bytes(dim: usize, n_grid: usize, n_particles: f64, active_blocks: f64) -> f64 {
    let d = dim as f64;
    let blocks_total = (n_grid as f64 / 4.0).ceil().powf(d);
    let per_particle = 8.0 * (3.0 * d + 2.0) + 1.0 // scene: x0, v0, force, m, V, fixed
        + 2.0 * 8.0 * (2.0 * d + 2.0 * d * d) // current and next state: x, v, C, F
        + 8.0 * d * d // affine momentum (stress) buffer
        + 16.0; // block keys, sort order, particle block
    let per_block = 4f64.powf(d) * (8.0 + 16.0 * d + 1.0) + 4.0 * 6f64.powf(d) + 64.0;
    8.0 * blocks_total + n_particles * per_particle + active_blocks.min(blocks_total) * per_block
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn estimate_by_hand() {
        // 3D, n_grid 8 (2³ = 8 blocks), 10 particles, 1 active block:
        // table 64 B; particle 8·11 + 1 + 16·24 + 72 + 16 = 561 B; block 64·57 + 4·216 + 64 = 4576 B.
        assert_eq!(estimate_memory_bytes(3, 8, 10.0, 1.0), 64.0 + 5610.0 + 4576.0);
        // active blocks are capped by the grid's blocks
        assert_eq!(estimate_memory_bytes(3, 8, 0.0, 1e9), 64.0 + 8.0 * 4576.0);
    }
}
