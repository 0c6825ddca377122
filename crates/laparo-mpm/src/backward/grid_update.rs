//! Adjoint of the grid update v_i = mask ⊙ (k (m v)_i / (m_i + ε) + Δt g), k = 1 / (1 + ζ Δt) (damping):
//! (m v)̄_i = k mask ⊙ v̄_i / (m_i + ε), m̄_i = −(mask ⊙ v̄_i)·ṽ_i / (m_i + ε), with ṽ_i = v_i − Δt g the
//! velocity before gravity (equal to k (m v)_i/(m_i + ε) on every component the mask keeps).
use crate::linalg::Vector;
use crate::scene::Scene;
use rayon::prelude::*;

/// Adjoint of a node's P2G result: (m v)̄ and m̄, side by side so that the P2G adjoint (a gather)
/// loads one record per stencil node.
#[derive(Clone, Copy, Debug)]
pub struct NodeAdjoint<const D: usize> {
    /// (m v)̄_i.
    pub mom: Vector<D>,
    /// m̄_i.
    pub mass: f64,
}

impl<const D: usize> Default for NodeAdjoint<D> {
    fn default() -> Self {
        NodeAdjoint { mom: Vector::<D>::zeros(), mass: 0.0 }
    }
}

/// Fills `node_bar` (every entry is written) with the momentum and mass adjoints from `vel_bar`
/// (node velocity adjoint) and the stored node masses, velocities and wall masks of the step. Leaves
/// `vel_bar` zeroed, ready for the next (earlier) step's G2P adjoint scatter.
pub fn grid_update_adjoint<const D: usize>(
    scene: &Scene<D>,
    mass: &[f64],
    vel: &[Vector<D>],
    wall_mask: &[u8],
    vel_bar: &mut [Vector<D>],
    node_bar: &mut [NodeAdjoint<D>],
) {
    let eps = scene.mass_epsilon;
    let gdt = scene.gravity * scene.dt;
    let keep = 1.0 / (1.0 + scene.damping * scene.dt);
    node_bar.par_iter_mut().zip(vel_bar.par_iter_mut()).enumerate().with_min_len(1024).for_each(|(i, (nb, vbi))| {
        let mut vb = std::mem::replace(vbi, Vector::<D>::zeros());
        let mask = wall_mask[i];
        for d in 0..D {
            if mask & (1 << d) != 0 {
                vb[d] = 0.0;
            }
        }
        let denom = mass[i] + eps;
        *nb = if denom > 0.0 {
            let inv = 1.0 / denom;
            // v = keep p / (m + ε) + g Δt: p̄ = keep v̄ / (m + ε), m̄ = −v̄·(v − g Δt) / (m + ε)
            NodeAdjoint { mom: vb * (keep * inv), mass: -vb.dot(&(vel[i] - gdt)) * inv }
        } else {
            NodeAdjoint::default()
        };
    });
}
