//! Adjoint of the G2P transfer and advection.
//!
//! Forward: v' = Σ w_i v_i, C' = 4/Δx Σ w_i v_i (o_i − fx)ᵀ, x' = x + Δt v', with fx = x/Δx − base.
//! Reverse: v̄' ← v̄' + Δt x̄'; u_i = v̄' + 4/Δx C̄' (o_i − fx); v̄_i += w_i u_i (coloured scatter);
//! w̄_i = v_i·u_i; f̄x = Σ_i w̄_i ∂w_i/∂fx − 4/Δx C̄'ᵀ v' (using Σ w_i v_i = v'); x̄ = x̄' + f̄x/Δx.
//!
//! The per-particle body is [`G2pAdjoint::particle`], shared with the fused pass
//! ([`crate::backward::fused`]) that runs it right after the P2G adjoint of the next step.
use crate::linalg::{Matrix, Vector};
use crate::scene::Scene;
use crate::sparse_grid::{
    affine_at, affine_terms, base_of, bspline, for_stencil, node_at, prefetch, weight_grad, SparseGrid, StencilWindow,
    SyncPtr,
};

/// The G2P adjoint of one step, particle by particle: scatters into the node-velocity adjoint
/// `vel_bar` of the step's grid (coloured: the caller visits the particles colour by colour).
pub(crate) struct G2pAdjoint<'a, const D: usize> {
    scene: &'a Scene<D>,
    vel: &'a [Vector<D>],
    x: &'a [Vector<D>],
    v_next: &'a [Vector<D>],
    vel_bar: SyncPtr<Vector<D>>,
    inv_dx: f64,
    dt: f64,
}

impl<'a, const D: usize> G2pAdjoint<'a, D> {
    /// `vel`: the step's node velocities; `x`: positions of the step input; `v_next`: v';
    /// `vel_bar`: node-velocity adjoint (zeroed), one per node of `grid`.
    pub(crate) fn new(
        grid: &SparseGrid<D>,
        scene: &'a Scene<D>,
        vel: &'a [Vector<D>],
        x: &'a [Vector<D>],
        v_next: &'a [Vector<D>],
        vel_bar: &'a mut [Vector<D>],
    ) -> Self {
        assert!(vel.len() == grid.n_nodes() && vel_bar.len() == grid.n_nodes());
        assert!(x.len() == v_next.len());
        G2pAdjoint {
            scene,
            vel,
            x,
            v_next,
            vel_bar: SyncPtr(vel_bar.as_mut_ptr()),
            inv_dx: 1.0 / scene.grid.dx,
            dt: scene.dt,
        }
    }

    /// Prefetch the particle inputs of particle `q`.
    #[inline(always)]
    pub(crate) fn prefetch(&self, q: usize) {
        prefetch(&self.x[q]);
        prefetch(&self.v_next[q]);
    }

    /// Scatter particle `p`'s contribution to the node-velocity adjoint (`nbr`: its block's window
    /// in the step's grid) from (x̄', v̄', C̄') of the step output; returns the G2P part of x̄.
    ///
    /// # Safety
    /// No other thread may touch the stencil nodes of `p` concurrently (same-colour particles only).
    #[inline(always)]
    pub(crate) unsafe fn particle(
        &self,
        p: usize,
        nbr: &StencilWindow<D>,
        x_bar_next: &Vector<D>,
        v_bar_next: &Vector<D>,
        c_bar_next: &Matrix<D>,
    ) -> Vector<D> {
        if self.scene.is_fixed(p) {
            return *x_bar_next;
        }
        let (inv_dx, vel) = (self.inv_dx, self.vel);
        let vb = v_bar_next + x_bar_next * self.dt;
        let cb4 = c_bar_next * (4.0 * inv_dx);
        let x = &self.x[p];
        let base = base_of(x, inv_dx);
        let (fx, w, dw) = bspline(x, &base, inv_dx);
        let st = nbr.nodes(&base);
        let mut fxb = -(cb4.transpose() * self.v_next[p]);
        // u_i = v̄' + 4/Δx C̄' (o_i − fx) from per-axis terms.
        let terms = affine_terms(&vb, &cb4, &fx, 1.0);
        for_stencil::<D>(
            &w,
            #[inline(always)]
            |k, o, weight| {
                let i = st[k] as usize;
                let u = affine_at(&terms, o);
                // SAFETY: see the function's contract.
                unsafe {
                    *self.vel_bar.at(i) += u * weight;
                }
                fxb += weight_grad(&w, &dw, o) * node_at(vel, i).dot(&u);
            },
        );
        x_bar_next + fxb * inv_dx
    }
}

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
    let k = G2pAdjoint::new(grid, scene, vel, x, v_next, vel_bar);
    let xb_ptr = SyncPtr(x_bar.as_mut_ptr());
    let pre = |q: usize| {
        k.prefetch(q);
        prefetch(&x_bar_next[q]);
        prefetch(&v_bar_next[q]);
        prefetch(&c_bar_next[q]);
    };
    grid.for_each_coloured(pre, |p, nbr| {
        // SAFETY: every particle is visited once; nodes are disjoint within a colour.
        unsafe {
            *xb_ptr.at(p) = k.particle(p, nbr, &x_bar_next[p], &v_bar_next[p], &c_bar_next[p]);
        }
    });
}
