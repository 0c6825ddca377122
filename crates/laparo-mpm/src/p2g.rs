//! Particle-to-grid transfer (eq. 5.6): deformation-gradient update F ← (I + Δt C) F, Kirchhoff
//! stress (one pass in particle order), and the colour-partitioned APIC/MLS scatter of mass and
//! momentum.
use crate::constitutive::ConstitutiveModel;
use crate::error::MpmError;
use crate::linalg::{all_finite, Matrix, Vector};
use crate::scene::Scene;
use crate::sparse_grid::{field_slots, prefetch, SparseGrid, SyncPtr};
use crate::stencil::{affine_at, affine_terms, base_of, bspline, for_stencil};
use rayon::prelude::*;

/// Stress scale of eq. 5.6 for particle p: −Δt V_p 4/Δx² (quadratic B-splines: D_p⁻¹ = 4/Δx²), with
/// `inv_dx` = 1/Δx computed once by the caller (a division per particle is not free).
#[inline(always)]
pub fn stress_scale<const D: usize>(scene: &Scene<D>, p: usize, inv_dx: f64) -> f64 {
    -scene.dt * scene.volumes[p] * 4.0 * inv_dx * inv_dx
}

/// Per-particle part of P2G: F_{t+1} = (I + Δt C_t) F_t and the affine momentum matrix
/// A_p = −Δt V_p 4/Δx² τ(F_{t+1}) + m_p C_t; `None` on an inverted or non-finite F (blow-up).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub fn particle_stress<const D: usize, M: ConstitutiveModel<D>>(
    model: &M,
    mu: f64,
    lambda: f64,
    scene: &Scene<D>,
    c: &Matrix<D>,
    f: &Matrix<D>,
    f_next: &mut Matrix<D>,
    p: usize,
    inv_dx: f64,
) -> Option<Matrix<D>> {
    let nf = (Matrix::<D>::identity() + c * scene.dt) * f;
    *f_next = nf;
    match model.kirchhoff(&nf, mu, lambda) {
        Some(tau) if all_finite(tau.as_slice()) => Some(tau * stress_scale(scene, p, inv_dx) + c * scene.masses[p]),
        _ => None,
    }
}

/// First half of P2G (eq. 5.6), per particle in particle-index order (streaming the particle
/// arrays): F_{t+1} = (I + Δt C) F into `f_next` and the affine momentum matrix A_p into `affine`.
/// It does not need the sparse grid, so the forward step runs it alongside the grid build. Errors
/// on an inverted or non-finite F (reported for the lowest particle index, whatever the thread
/// count).
#[allow(clippy::too_many_arguments)]
pub fn stress<const D: usize, M: ConstitutiveModel<D>>(
    model: &M,
    mu: f64,
    lambda: f64,
    scene: &Scene<D>,
    c: &[Matrix<D>],
    f: &[Matrix<D>],
    f_next: &mut [Matrix<D>],
    affine: &mut Vec<Matrix<D>>,
    step: usize,
) -> Result<(), MpmError> {
    let n = c.len();
    let inv_dx = 1.0 / scene.grid.dx;
    affine.resize(n, Matrix::<D>::zeros());
    let min_len = n.div_ceil(16 * rayon::current_num_threads()).max(1);
    // F_{t+1} goes to checkpoint memory not touched since the previous iteration: ask for the cache
    // lines a few particles ahead.
    let f_ahead = SyncPtr(f_next.as_mut_ptr());
    let bad = f_next
        .par_iter_mut()
        .zip(affine.par_iter_mut())
        .enumerate()
        .with_min_len(min_len)
        .map(|(p, (fnext, a))| {
            if p + 16 < n {
                prefetch(f_ahead.addr(p + 16));
            }
            match particle_stress(model, mu, lambda, scene, &c[p], &f[p], fnext, p, inv_dx) {
                Some(v) => {
                    *a = v;
                    usize::MAX
                }
                None => p,
            }
        })
        .min()
        .unwrap_or(usize::MAX);
    if bad != usize::MAX {
        let j = crate::linalg::det(&f_next[bad]);
        return Err(MpmError::BlowUp {
            step,
            particle: bad,
            reason: if j.is_finite() {
                format!("inverted deformation gradient, J = {j:.3e} <= 0")
            } else {
                "non-finite deformation gradient".into()
            },
        });
    }
    Ok(())
}

/// Node sides of a two-field grid (see [`Scene::crack_side`]): side_i = Σ_p w_ip m_p side_p over the
/// particles with a side, scattered colour by colour (deterministic). No-op on a one-field grid.
pub fn crack_sides<const D: usize>(grid: &mut SparseGrid<D>, scene: &Scene<D>, x: &[Vector<D>]) {
    if grid.side.is_empty() {
        return;
    }
    let inv_dx = 1.0 / scene.grid.dx;
    let side = SyncPtr(grid.side.as_mut_ptr());
    let g = &*grid;
    g.for_each_coloured(
        |_| {},
        |p, nbr| {
            let label = scene.crack_label(p);
            if label == 0.0 {
                return;
            }
            let base = base_of(&x[p], inv_dx);
            let (_, w, _) = bspline(&x[p], &base, inv_dx);
            let st = nbr.nodes(&base);
            let ml = scene.masses[p] * label;
            for_stencil::<D>(&w, |k, _, weight| {
                // SAFETY: same-colour tasks touch disjoint nodes (see sparse_grid).
                unsafe { *side.at(st[k] as usize) += weight * ml };
            });
        },
    );
}

/// Second half of P2G (eq. 5.6), the coloured scatter (into the particle's field of each node on a
/// two-field grid, after [`crack_sides`]): m_i += w_ip m_p,
/// (m v)_i += w_ip (m_p v_p + Δt f_p + A_p (x_i − x_p)) with A_p from [`stress`].
pub fn scatter<const D: usize>(
    grid: &mut SparseGrid<D>,
    scene: &Scene<D>,
    x: &[Vector<D>],
    v: &[Vector<D>],
    affine: &[Matrix<D>],
) {
    let dx = scene.grid.dx;
    let inv_dx = 1.0 / dx;
    let mass = SyncPtr(grid.mass.as_mut_ptr());
    let mom = SyncPtr(grid.mom.as_mut_ptr());
    let g = &*grid;
    let side = &g.side[..];
    let pre = |q: usize| {
        prefetch(&x[q]);
        prefetch(&v[q]);
        prefetch(&affine[q]);
    };
    g.for_each_coloured(pre, |p, nbr| {
        let base = base_of(&x[p], inv_dx);
        let (fx, w, _) = bspline(&x[p], &base, inv_dx);
        let m = scene.masses[p];
        let mut mv = v[p] * m;
        if !scene.external_forces.is_empty() {
            mv += scene.external_forces[p] * scene.dt;
        }
        let st = field_slots(nbr.nodes(&base), side, scene.crack_label(p));
        // mv + A (o − fx) Δx per node from per-axis terms.
        let terms = affine_terms(&mv, &affine[p], &fx, dx);
        for_stencil::<D>(&w, |k, o, weight| {
            let i = st[k] as usize;
            let q = affine_at(&terms, o);
            // SAFETY: same-colour tasks touch disjoint nodes (see sparse_grid).
            unsafe {
                *mom.at(i) += q * weight;
                *mass.at(i) += weight * m;
            }
        });
    });
}
