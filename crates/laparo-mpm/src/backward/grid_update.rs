//! Adjoint of the grid update v_i = mask ⊙ ((m v)_i / (m_i + ε) + Δt g):
//! (m v)̄_i = mask ⊙ v̄_i / (m_i + ε), m̄_i = −(mask ⊙ v̄_i)·(m v)_i / (m_i + ε)².
use crate::linalg::Vector;
use crate::scene::Scene;
use crate::sparse_grid::SparseGrid;
use rayon::prelude::*;

/// Turns `vel_bar` (node velocity adjoint) into the momentum adjoint in place and fills `mass_bar`.
pub fn grid_update_adjoint<const D: usize>(
    grid: &SparseGrid<D>,
    scene: &Scene<D>,
    vel_bar: &mut [Vector<D>],
    mass_bar: &mut [f64],
) {
    let eps = scene.mass_epsilon;
    vel_bar.par_iter_mut().zip(mass_bar.par_iter_mut()).enumerate().with_min_len(256).for_each(|(i, (vb, mb))| {
        let mask = grid.wall_mask[i];
        for d in 0..D {
            if mask & (1 << d) != 0 {
                vb[d] = 0.0;
            }
        }
        let denom = grid.mass[i] + eps;
        if denom > 0.0 {
            let inv = 1.0 / denom;
            *mb = -vb.dot(&grid.mom[i]) * inv * inv;
            *vb *= inv;
        } else {
            *mb = 0.0;
            *vb = Vector::<D>::zeros();
        }
    });
}
