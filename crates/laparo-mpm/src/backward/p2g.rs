//! Adjoint of the P2G transfer and of the deformation-gradient update (a per-particle gather).
//!
//! Forward: m_i += w_i m, (m v)_i += w_i (m v + Δt f + A dpos_i), dpos_i = (o_i − fx) Δx,
//! A = s τ(F') + m C, F' = (I + Δt C) F, s = −Δt V 4/Δx².
//! Reverse: v̄ = m Σ w_i p̄_i; Ā = Σ w_i p̄_i dpos_iᵀ; w̄_i = p̄_i·(m v + Δt f + A dpos_i) + m̄_i m;
//! f̄x = Σ w̄_i ∂w_i/∂fx − Δx Aᵀ Σ w_i p̄_i; τ̄ = s Ā; F̄' += ∂τ/∂F'ᵀ τ̄; C̄ = m Ā + Δt F̄' Fᵀ;
//! F̄ = (I + Δt C)ᵀ F̄'; (μ̄, λ̄) from the constitutive VJP.
use crate::constitutive::ConstitutiveModel;
use crate::linalg::{Matrix, Vector};
use crate::p2g::stress_scale;
use crate::scene::Scene;
use crate::sparse_grid::{bspline, for_stencil, SparseGrid};
use rayon::prelude::*;

/// Adjoints of one particle's step input.
#[derive(Clone, Copy)]
pub struct ParticleAdjoint<const D: usize> {
    /// x̄ contribution from P2G (added to the G2P part by the caller).
    pub x: Vector<D>,
    /// v̄ of the step input.
    pub v: Vector<D>,
    /// C̄ of the step input.
    pub c: Matrix<D>,
    /// F̄ of the step input.
    pub f: Matrix<D>,
    /// μ̄ contribution.
    pub mu: f64,
    /// λ̄ contribution.
    pub lambda: f64,
}

/// Per-particle adjoint of P2G. `mom_bar`, `mass_bar`: node adjoints from the grid-update adjoint;
/// `f_bar_next`: F̄ of the step output; `f_next`: F of the step output (checkpoint). The stress and
/// the affine matrix A are recomputed here.
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
    mom_bar: &[Vector<D>],
    mass_bar: &[f64],
    f_bar_next: &[Matrix<D>],
    out: &mut [ParticleAdjoint<D>],
) {
    let dx = scene.grid.dx;
    let inv_dx = 1.0 / dx;
    let dt = scene.dt;
    out.par_iter_mut().enumerate().with_min_len(64).for_each(|(p, o_adj)| {
        let (fx, w, dw) = bspline(&x[p], &grid.base[p], inv_dx);
        let m = scene.masses[p];
        let scale = stress_scale(scene, p);
        let tau = model.kirchhoff(&f_next[p], mu, lambda).unwrap_or_else(Matrix::<D>::zeros);
        let a = tau * scale + c[p] * m;
        let mut mv = v[p] * m;
        if !scene.external_forces.is_empty() {
            mv += scene.external_forces[p] * dt;
        }
        let st = grid.stencil_of(p);
        let mut sum_wp = Vector::<D>::zeros();
        let mut ab = Matrix::<D>::zeros();
        let mut fxb = Vector::<D>::zeros();
        for_stencil::<D>(&w, |k, o, weight| {
            let mut dpos = Vector::<D>::zeros();
            for d in 0..D {
                dpos[d] = (o[d] as f64 - fx[d]) * dx;
            }
            let i = st[k] as usize;
            let pb = mom_bar[i];
            let wpb = pb * weight;
            sum_wp += wpb;
            ab += wpb * dpos.transpose();
            let wbar = pb.dot(&(mv + a * dpos)) + mass_bar[i] * m;
            for d in 0..D {
                let mut dwd = dw[d][o[d]];
                for e in 0..D {
                    if e != d {
                        dwd *= w[e][o[e]];
                    }
                }
                fxb[d] += wbar * dwd;
            }
        });
        fxb -= a.transpose() * sum_wp * dx;
        let tau_bar = ab * scale;
        let (fnb_tau, mub, lab) = model.kirchhoff_vjp(&f_next[p], mu, lambda, &tau_bar);
        let fnb = f_bar_next[p] + fnb_tau;
        *o_adj = ParticleAdjoint {
            x: fxb * inv_dx,
            v: sum_wp * m,
            c: ab * m + fnb * f[p].transpose() * dt,
            f: (Matrix::<D>::identity() + c[p] * dt).transpose() * fnb,
            mu: mub,
            lambda: lab,
        };
    });
}
