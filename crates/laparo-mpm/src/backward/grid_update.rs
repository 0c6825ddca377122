//! Adjoint of the grid update v_i = mask ⊙ ((m v)_i / (m_i + ε) + Δt g):
//! (m v)̄_i = mask ⊙ v̄_i / (m_i + ε), m̄_i = −(mask ⊙ v̄_i)·ṽ_i / (m_i + ε), with ṽ_i = v_i − Δt g the
//! velocity before gravity (equal to (m v)_i/(m_i + ε) on every component the mask keeps).
use crate::linalg::Vector;
use crate::scene::Scene;
use rayon::prelude::*;

/// Turns `vel_bar` (node velocity adjoint) into the momentum adjoint in place and fills `mass_bar`,
/// from the stored node masses, velocities and wall masks of the step.
pub fn grid_update_adjoint<const D: usize>(
    scene: &Scene<D>,
    mass: &[f64],
    vel: &[Vector<D>],
    wall_mask: &[u8],
    vel_bar: &mut [Vector<D>],
    mass_bar: &mut [f64],
) {
    let eps = scene.mass_epsilon;
    let gdt = scene.gravity * scene.dt;
    vel_bar.par_iter_mut().zip(mass_bar.par_iter_mut()).enumerate().with_min_len(1024).for_each(|(i, (vb, mb))| {
        let mask = wall_mask[i];
        for d in 0..D {
            if mask & (1 << d) != 0 {
                vb[d] = 0.0;
            }
        }
        let denom = mass[i] + eps;
        if denom > 0.0 {
            let inv = 1.0 / denom;
            *mb = -vb.dot(&(vel[i] - gdt)) * inv;
            *vb *= inv;
        } else {
            *mb = 0.0;
            *vb = Vector::<D>::zeros();
        }
    });
}
