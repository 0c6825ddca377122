//! Adjoint of the G2P transfer and advection.
//!
//! Forward: v' = Σ w_i v_i, C' = 4/Δx Σ w_i v_i (o_i − fx)ᵀ, x' = x + Δt v', with fx = x/Δx − base.
//! Reverse: v̄' ← v̄' + Δt x̄'; v̄_i += w_i v̄' + 4/Δx w_i C̄' (o_i − fx) (coloured scatter);
//! w̄_i = v̄'·v_i + 4/Δx v_iᵀ C̄' (o_i − fx); f̄x = Σ (w̄_i ∂w_i/∂fx − 4/Δx w_i C̄'ᵀ v_i); x̄ = x̄' + f̄x/Δx.
use crate::linalg::{stencil_len, Matrix, Vector};
use crate::scene::Scene;
use crate::sparse_grid::{bspline, stencil_offset, SparseGrid, SyncPtr};

/// Returns nothing; fills `vel_bar` (node velocity adjoint, must be zeroed, one per node) and
/// `x_bar` (the G2P part of the position adjoint of the step's input).
#[allow(clippy::too_many_arguments)]
pub fn g2p_adjoint<const D: usize>(
    grid: &SparseGrid<D>,
    scene: &Scene<D>,
    x: &[Vector<D>],
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
    grid.for_each_coloured(|p| {
        // SAFETY: every particle is visited once; nodes are disjoint within a colour.
        let xb = unsafe { xb_ptr.at(p) };
        if scene.is_fixed(p) {
            *xb = x_bar_next[p];
            return;
        }
        let vb = v_bar_next[p] + x_bar_next[p] * dt;
        let cb = c_bar_next[p];
        let (fx, w, dw) = bspline(&x[p], &grid.base[p], inv_dx);
        let st = &grid.stencil[p];
        let mut fxb = Vector::<D>::zeros();
        for k in 0..stencil_len(D) {
            let o = stencil_offset::<D>(k);
            let mut weight = 1.0;
            let mut dpos = Vector::<D>::zeros();
            for d in 0..D {
                weight *= w[d][o[d]];
                dpos[d] = o[d] as f64 - fx[d];
            }
            let i = st[k] as usize;
            let gv = grid.vel[i];
            let cb_dpos = cb * dpos;
            unsafe {
                *vb_ptr.at(i) += vb * weight + cb_dpos * (4.0 * weight * inv_dx);
            }
            let wbar = vb.dot(&gv) + 4.0 * inv_dx * gv.dot(&cb_dpos);
            fxb -= cb.transpose() * gv * (4.0 * weight * inv_dx);
            for d in 0..D {
                let mut dwd = dw[d][o[d]];
                for e in 0..D {
                    if e != d {
                        dwd *= w[e][o[e]];
                    }
                }
                fxb[d] += wbar * dwd;
            }
        }
        *xb = x_bar_next[p] + fxb * inv_dx;
    });
}
