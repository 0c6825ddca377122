//! Adjoint of the P2G transfer and of the deformation-gradient update (a per-particle gather).
//!
//! Forward: m_i += w_i m, (m v)_i += w_i (m v + Δt f + A dpos_i), dpos_i = (o_i − fx) Δx,
//! A = s τ(F') + m C, F' = (I + Δt C) F, s = −Δt V 4/Δx².
//! Reverse: v̄ = m Σ w_i p̄_i; Ā = Σ w_i p̄_i dpos_iᵀ; w̄_i = p̄_i·(m v + Δt f + A dpos_i) + m̄_i m;
//! f̄x = Σ w̄_i ∂w_i/∂fx − Δx Aᵀ Σ w_i p̄_i; τ̄ = s Ā; F̄' += ∂τ/∂F'ᵀ τ̄; C̄ = m Ā + Δt F̄' Fᵀ;
//! F̄ = (I + Δt C)ᵀ F̄'; (μ̄, λ̄) from the constitutive VJP.
//!
//! The per-particle body is [`P2gAdjoint::particle`], shared with the fused pass
//! ([`crate::backward::fused`]) that runs the G2P adjoint of the previous step right after it.
use crate::backward::grid_update::NodeAdjoint;
use crate::constitutive::ConstitutiveModel;
use crate::linalg::{Matrix, Vector};
use crate::p2g::stress_scale;
use crate::scene::Scene;
use crate::sparse_grid::{
    affine_at, affine_terms, base_of, bspline, for_stencil, node_at, prefetch, weight_grad, SparseGrid, StencilWindow,
    SyncPtr,
};

/// Adjoint arrays of the particle state, updated in place by [`p2g_adjoint`] from those of the
/// step output to those of the step input.
pub struct StateAdjoint<'a, const D: usize> {
    /// x̄: in, ignored; out, x̄ of the step input (G2P part + P2G part + loss gradient).
    pub x: &'a mut [Vector<D>],
    /// v̄ of the step input (out).
    pub v: &'a mut [Vector<D>],
    /// C̄ of the step input (out).
    pub c: &'a mut [Matrix<D>],
    /// F̄: in, of the step output; out, of the step input.
    pub f: &'a mut [Matrix<D>],
    /// (μ̄, λ̄) per particle, accumulated over the steps (in-out; the caller sums them in particle
    /// order at the end of the reverse pass).
    pub lame: &'a mut [(f64, f64)],
}

/// The P2G adjoint of one step, particle by particle (a gather from the node adjoints of the step's
/// grid; each particle writes only its own entries of the state adjoint).
pub(crate) struct P2gAdjoint<'a, const D: usize, M> {
    model: &'a M,
    mu: f64,
    lambda: f64,
    scene: &'a Scene<D>,
    x: &'a [Vector<D>],
    v: &'a [Vector<D>],
    c: &'a [Matrix<D>],
    f: &'a [Matrix<D>],
    f_next: &'a [Matrix<D>],
    node_bar: &'a [NodeAdjoint<D>],
    loss_grad: Option<&'a [Vector<D>]>,
    xb: SyncPtr<Vector<D>>,
    vb: SyncPtr<Vector<D>>,
    cb: SyncPtr<Matrix<D>>,
    fb: SyncPtr<Matrix<D>>,
    lame: SyncPtr<(f64, f64)>,
    dx: f64,
    inv_dx: f64,
    dt: f64,
}

impl<'a, const D: usize, M: ConstitutiveModel<D>> P2gAdjoint<'a, D, M> {
    /// See [`p2g_adjoint`] for the arguments.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn new(
        model: &'a M,
        mu: f64,
        lambda: f64,
        grid: &SparseGrid<D>,
        scene: &'a Scene<D>,
        x: &'a [Vector<D>],
        v: &'a [Vector<D>],
        c: &'a [Matrix<D>],
        f: &'a [Matrix<D>],
        f_next: &'a [Matrix<D>],
        node_bar: &'a [NodeAdjoint<D>],
        loss_grad: Option<&'a [Vector<D>]>,
        out: StateAdjoint<'a, D>,
    ) -> Self {
        assert_eq!(node_bar.len(), grid.n_nodes());
        let n = x.len();
        assert!([v.len(), c.len(), f.len(), f_next.len(), out.x.len(), out.v.len()].iter().all(|&l| l == n));
        assert!([out.c.len(), out.f.len(), out.lame.len()].iter().all(|&l| l == n));
        assert!(loss_grad.is_none_or(|g| g.len() == n));
        P2gAdjoint {
            model,
            mu,
            lambda,
            scene,
            x,
            v,
            c,
            f,
            f_next,
            node_bar,
            loss_grad,
            xb: SyncPtr(out.x.as_mut_ptr()),
            vb: SyncPtr(out.v.as_mut_ptr()),
            cb: SyncPtr(out.c.as_mut_ptr()),
            fb: SyncPtr(out.f.as_mut_ptr()),
            lame: SyncPtr(out.lame.as_mut_ptr()),
            dx: scene.grid.dx,
            inv_dx: 1.0 / scene.grid.dx,
            dt: scene.dt,
        }
    }

    /// Run [`Self::particle`] for every particle, in particle order (`grid`: the step's grid).
    pub(crate) fn run(&self, grid: &SparseGrid<D>, x_bar_g2p: &[Vector<D>]) {
        assert_eq!(x_bar_g2p.len(), self.x.len());
        assert_eq!(self.node_bar.len(), grid.n_nodes());
        grid.for_each_particle(|p, nbr| {
            // SAFETY: every particle is visited once.
            unsafe {
                self.particle(p, nbr, &x_bar_g2p[p]);
            }
        });
    }

    /// Prefetch the particle data of particle `q` (for visits out of particle order).
    #[inline(always)]
    pub(crate) fn prefetch(&self, q: usize) {
        prefetch(&self.x[q]);
        prefetch(&self.v[q]);
        prefetch(&self.c[q]);
        prefetch(&self.f[q]);
        prefetch(&self.f_next[q]);
        prefetch(self.fb.addr(q));
        prefetch(self.cb.addr(q));
    }

    /// The P2G adjoint of particle `p` (`nbr`: its block's window in the step's grid; `x_bar_g2p`:
    /// the G2P part of its x̄). Writes x̄, v̄, C̄, F̄ of the step input and accumulates (μ̄, λ̄);
    /// returns (x̄, v̄, C̄).
    ///
    /// # Safety
    /// No other thread may run this for the same particle concurrently.
    #[inline(always)]
    pub(crate) unsafe fn particle(
        &self,
        p: usize,
        nbr: &StencilWindow<D>,
        x_bar_g2p: &Vector<D>,
    ) -> (Vector<D>, Vector<D>, Matrix<D>) {
        let scene = self.scene;
        let (x, v, c, node_bar) = (self.x, self.v, self.c, self.node_bar);
        let (dx, inv_dx, dt) = (self.dx, self.inv_dx, self.dt);
        let m = scene.masses[p];
        // The stencil is set up inside `body`, after τ (whose ln J is a libm call that would force
        // everything live across it to be spilled). The closures are inlined by force: LLVM would
        // otherwise call them (the stencil closure 27 times per particle in 3D).
        let (fnb_tau, mub, lab, (sum_wp, ab, fxb)) = self.model.kirchhoff_then_vjp(
            &self.f_next[p],
            self.mu,
            self.lambda,
            #[inline(always)]
            |tau| {
                let base = base_of(&x[p], inv_dx);
                let (fx, w, dw) = bspline(&x[p], &base, inv_dx);
                let scale = stress_scale(scene, p, inv_dx);
                let mut mv = v[p] * m;
                if !scene.external_forces.is_empty() {
                    mv += scene.external_forces[p] * dt;
                }
                let st = nbr.nodes(&base);
                let a = tau * scale + c[p] * m;
                // mv + A dpos_i from per-axis terms; Σ w p̄_i and Σ w p̄_i dpos_iᵀ from the per-axis
                // sums S_d[o] = Σ_{nodes with o_d = o} w p̄_i.
                let terms = affine_terms(&mv, &a, &fx, dx);
                let mut sums = [[Vector::<D>::zeros(); 3]; D];
                let mut fxb = Vector::<D>::zeros();
                for_stencil::<D>(
                    &w,
                    #[inline(always)]
                    |k, o, weight| {
                        let i = st[k] as usize;
                        let nb = node_at(node_bar, i);
                        let pb = nb.mom;
                        let wpb = pb * weight;
                        for d in 0..D {
                            sums[d][o[d]] += wpb;
                        }
                        let wbar = pb.dot(&affine_at(&terms, o)) + nb.mass * m;
                        fxb += weight_grad(&w, &dw, o) * wbar;
                    },
                );
                let sum_wp = sums[0][0] + sums[0][1] + sums[0][2];
                let mut ab = Matrix::<D>::zeros();
                for d in 0..D {
                    let col = sums[d][0] * ((0.0 - fx[d]) * dx)
                        + sums[d][1] * ((1.0 - fx[d]) * dx)
                        + sums[d][2] * ((2.0 - fx[d]) * dx);
                    ab.set_column(d, &col);
                }
                fxb -= a.transpose() * sum_wp * dx;
                (ab * scale, (sum_wp, ab, fxb * inv_dx))
            },
        );
        // SAFETY: see the function's contract; only particle p's entries are touched.
        unsafe {
            let fb = self.fb.at(p);
            let fnb = *fb + fnb_tau;
            let mut xb = x_bar_g2p + fxb;
            if let Some(g) = self.loss_grad {
                xb += g[p];
            }
            let vb = sum_wp * m;
            let cb = ab * m + fnb * self.f[p].transpose() * dt;
            *self.xb.at(p) = xb;
            *self.vb.at(p) = vb;
            *self.cb.at(p) = cb;
            *fb = (Matrix::<D>::identity() + c[p] * dt).transpose() * fnb;
            let lm = self.lame.at(p);
            lm.0 += mub;
            lm.1 += lab;
            (xb, vb, cb)
        }
    }
}

/// Per-particle adjoint of P2G. `node_bar`: node adjoints from the grid-update adjoint;
/// `x_bar_g2p`: the G2P part of x̄; `loss_grad`: ∂L/∂x of the step input when observed; `f_next`: F
/// of the step output (checkpoint). The stress and the affine matrix A are recomputed here.
#[allow(clippy::too_many_arguments)]
pub fn p2g_adjoint<const D: usize, M: ConstitutiveModel<D>>(
    model: &M,
    mu: f64,
    lambda: f64,
    grid: &SparseGrid<D>,
    scene: &Scene<D>,
    x: &[Vector<D>],
    v: &[Vector<D>],
    c: &[Matrix<D>],
    f: &[Matrix<D>],
    f_next: &[Matrix<D>],
    node_bar: &[NodeAdjoint<D>],
    x_bar_g2p: &[Vector<D>],
    loss_grad: Option<&[Vector<D>]>,
    out: StateAdjoint<'_, D>,
) {
    P2gAdjoint::new(model, mu, lambda, grid, scene, x, v, c, f, f_next, node_bar, loss_grad, out).run(grid, x_bar_g2p);
}
