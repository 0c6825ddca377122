//! Adjoint of the P2G transfer and of the deformation-gradient update (a per-particle gather).
//!
//! Forward: m_i += w_i m, (m v)_i += w_i (m v + Δt f + A dpos_i), dpos_i = (o_i − fx) Δx,
//! A = s τ(F') + m C, F' = (I + Δt C) F, s = −Δt V 4/Δx².
//! Reverse: v̄ = m Σ w_i p̄_i; Ā = Σ w_i p̄_i dpos_iᵀ; w̄_i = p̄_i·(m v + Δt f + A dpos_i) + m̄_i m;
//! f̄x = Σ w̄_i ∂w_i/∂fx − Δx Aᵀ Σ w_i p̄_i; τ̄ = s Ā; F̄' += ∂τ/∂F'ᵀ τ̄; C̄ = m Ā + Δt F̄' Fᵀ;
//! F̄ = (I + Δt C)ᵀ F̄'; (μ̄, λ̄) from the constitutive VJP.
use crate::backward::grid_update::NodeAdjoint;
use crate::constitutive::ConstitutiveModel;
use crate::linalg::{Matrix, Vector};
use crate::p2g::stress_scale;
use crate::scene::Scene;
use crate::sparse_grid::{field_slots, node_at, SparseGrid, SyncPtr};
use crate::stencil::{affine_at, affine_terms, base_of, bspline, for_stencil, weight_grad};

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
    let dx = scene.grid.dx;
    let inv_dx = 1.0 / dx;
    let dt = scene.dt;
    let (xb_ptr, vb_ptr, cb_ptr) =
        (SyncPtr(out.x.as_mut_ptr()), SyncPtr(out.v.as_mut_ptr()), SyncPtr(out.c.as_mut_ptr()));
    let (fb_ptr, lm_ptr) = (SyncPtr(out.f.as_mut_ptr()), SyncPtr(out.lame.as_mut_ptr()));
    assert_eq!(node_bar.len(), grid.n_slots());
    let side = &grid.side[..];
    grid.for_each_particle(|p, nbr| {
        let m = scene.masses[p];
        // The stencil is set up inside `body`, after τ (whose ln J is a libm call that would force
        // everything live across it to be spilled).
        let (fnb_tau, mub, lab, (sum_wp, ab, fxb)) = model.kirchhoff_then_vjp(&f_next[p], mu, lambda, |tau| {
            let base = base_of(&x[p], inv_dx);
            let (fx, w, dw) = bspline(&x[p], &base, inv_dx);
            let scale = stress_scale(scene, p, inv_dx);
            let mut mv = v[p] * m;
            if !scene.external_forces.is_empty() {
                mv += scene.external_forces[p] * dt;
            }
            let st = field_slots(nbr.nodes(&base), side, scene.crack_label(p));
            let a = tau * scale + c[p] * m;
            // mv + A dpos_i from per-axis terms; Σ w p̄_i and Σ w p̄_i dpos_iᵀ from the per-axis
            // sums S_d[o] = Σ_{nodes with o_d = o} w p̄_i.
            let terms = affine_terms(&mv, &a, &fx, dx);
            let mut sums = [[Vector::<D>::zeros(); 3]; D];
            let mut fxb = Vector::<D>::zeros();
            for_stencil::<D>(&w, |k, o, weight| {
                let nb = node_at(node_bar, st[k] as usize);
                let pb = nb.mom;
                let wpb = pb * weight;
                for d in 0..D {
                    sums[d][o[d]] += wpb;
                }
                let wbar = pb.dot(&affine_at(&terms, o)) + nb.mass * m;
                fxb += weight_grad(&w, &dw, o) * wbar;
            });
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
        });
        // SAFETY: every particle is visited once and only its own entries are touched.
        unsafe {
            let fb = fb_ptr.at(p);
            let fnb = *fb + fnb_tau;
            let xb = xb_ptr.at(p);
            *xb = x_bar_g2p[p] + fxb;
            if let Some(g) = loss_grad {
                *xb += g[p];
            }
            *vb_ptr.at(p) = sum_wp * m;
            *cb_ptr.at(p) = ab * m + fnb * f[p].transpose() * dt;
            *fb = (Matrix::<D>::identity() + c[p] * dt).transpose() * fnb;
            let lm = lm_ptr.at(p);
            lm.0 += mub;
            lm.1 += lab;
        }
    });
}
