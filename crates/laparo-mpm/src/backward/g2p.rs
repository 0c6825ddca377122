//! Adjoint of the G2P transfer and advection.
//!
//! Forward: v' = Σ w_i v_i, C' = 4/Δx Σ w_i v_i (o_i − fx)ᵀ, x' = x + Δt v', with fx = x/Δx − base.
//! Reverse: v̄' ← v̄' + Δt x̄'; u_i = v̄' + 4/Δx C̄' (o_i − fx); v̄_i += w_i u_i (coloured scatter);
//! w̄_i = v_i·u_i; f̄x = Σ_i w̄_i ∂w_i/∂fx − 4/Δx C̄'ᵀ v' (using Σ w_i v_i = v'); x̄ = x̄' + f̄x/Δx.
use crate::linalg::{Matrix, Vector};
use crate::scene::Scene;
use crate::sparse_grid::{field_slots, node_at, prefetch, SparseGrid, SyncPtr};
use crate::stencil::{affine_at, affine_terms, base_of, bspline, for_stencil, weight_grad};

/// Fills `vel_bar` (node-velocity adjoint, zeroed, one per node of `grid`) and `x_bar` (the G2P part
/// of the position adjoint of the step input). `vel`: the step's node velocities; `v_next`: v'.
#[allow(clippy::too_many_arguments)]
pub fn g2p_adjoint<const D: usize>(
    grid: &SparseGrid<D>,
    scene: &Scene<D>,
    vel: &[Vector<D>],
    x: &[Vector<D>],
    v_next: &[Vector<D>],
    x_bar_next: &[Vector<D>],
    v_bar_next: &[Vector<D>],
    c_bar_next: &[Matrix<D>],
    vel_bar: &mut [Vector<D>],
    x_bar: &mut [Vector<D>],
) {
    let inv_dx = 1.0 / scene.grid.dx;
    let dt = scene.dt;
    let vb_ptr = SyncPtr(vel_bar.as_mut_ptr());
    let xb_ptr = SyncPtr(x_bar.as_mut_ptr());
    assert!(vel.len() == grid.n_slots() && vel_bar.len() == grid.n_slots());
    let side = &grid.side[..];
    let pre = |q: usize| {
        prefetch(&x[q]);
        prefetch(&v_next[q]);
        prefetch(&x_bar_next[q]);
        prefetch(&v_bar_next[q]);
        prefetch(&c_bar_next[q]);
    };
    grid.for_each_coloured(pre, |p, nbr| {
        // SAFETY: every particle is visited once; nodes are disjoint within a colour.
        let xb = unsafe { xb_ptr.at(p) };
        if scene.is_fixed(p) {
            *xb = x_bar_next[p];
            return;
        }
        let vb = v_bar_next[p] + x_bar_next[p] * dt;
        let cb4 = c_bar_next[p] * (4.0 * inv_dx);
        let base = base_of(&x[p], inv_dx);
        let (fx, w, dw) = bspline(&x[p], &base, inv_dx);
        let st = field_slots(nbr.nodes(&base), side, scene.crack_label(p));
        let mut fxb = -(cb4.transpose() * v_next[p]);
        // u_i = v̄' + 4/Δx C̄' (o_i − fx) from per-axis terms.
        let terms = affine_terms(&vb, &cb4, &fx, 1.0);
        for_stencil::<D>(&w, |k, o, weight| {
            let i = st[k] as usize;
            let u = affine_at(&terms, o);
            unsafe {
                *vb_ptr.at(i) += u * weight;
            }
            fxb += weight_grad(&w, &dw, o) * node_at(vel, i).dot(&u);
        });
        *xb = x_bar_next[p] + fxb * inv_dx;
    });
}
