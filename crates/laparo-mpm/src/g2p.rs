//! Grid-to-particle transfer (eq. 5.7) with the APIC affine matrix C and advection x += Δt v.
use crate::error::MpmError;
use crate::linalg::{all_finite, Matrix, Vector};
use crate::scene::Scene;
use crate::sparse_grid::{field_slots, node_at, prefetch, SparseGrid, SyncPtr};
use crate::stencil::{base_of, bspline, for_stencil};
use std::sync::atomic::{AtomicUsize, Ordering};

/// v_p = Σ_i w_ip v_i (from the particle's field of each node on a two-field grid), C_p = 4/Δx² Σ_i w_ip v_i (x_i − x_p)ᵀ, x_p ← x_p + Δt v_p. Fixed particles keep
/// their position (v = 0, C = 0). Also writes the block key of every new position into `keys_next`
/// (for the next step's [`SparseGrid::build_from_keys`], computed here in parallel while x_p is at
/// hand). Errors when a particle state becomes non-finite.
#[allow(clippy::too_many_arguments)]
pub fn gather<const D: usize>(
    grid: &SparseGrid<D>,
    scene: &Scene<D>,
    x: &[Vector<D>],
    x_next: &mut [Vector<D>],
    v_next: &mut [Vector<D>],
    c_next: &mut [Matrix<D>],
    keys_next: &mut [u32],
    step: usize,
) -> Result<(), MpmError> {
    let inv_dx = 1.0 / scene.grid.dx;
    let dt = scene.dt;
    let keyer = grid.keyer();
    let xn_ptr = SyncPtr(x_next.as_mut_ptr());
    let vn_ptr = SyncPtr(v_next.as_mut_ptr());
    let cn_ptr = SyncPtr(c_next.as_mut_ptr());
    let key_ptr = SyncPtr(keys_next.as_mut_ptr());
    let bad = AtomicUsize::new(usize::MAX);
    assert_eq!(grid.vel.len(), grid.n_slots());
    let side = &grid.side[..];
    let n = x.len();
    grid.for_each_particle(|p, nbr| {
        // The outputs are checkpoint memory not touched since the previous iteration: ask for the
        // cache lines a few particles ahead.
        if p + 16 < n {
            prefetch(xn_ptr.addr(p + 16));
            prefetch(vn_ptr.addr(p + 16));
            prefetch(cn_ptr.addr(p + 16));
        }
        // SAFETY: every particle is visited once.
        let (xn, vn, cn, key) = unsafe { (xn_ptr.at(p), vn_ptr.at(p), cn_ptr.at(p), key_ptr.at(p)) };
        if scene.is_fixed(p) {
            *xn = x[p];
            *vn = Vector::<D>::zeros();
            *cn = Matrix::<D>::zeros();
            *key = keyer.key(xn);
            return;
        }
        let base = base_of(&x[p], inv_dx);
        let (fx, w, _) = bspline(&x[p], &base, inv_dx);
        let st = field_slots(nbr.nodes(&base), side, scene.crack_label(p));
        // v' = Σ w v_i; C' = 4/Δx Σ w v_i (o − fx)ᵀ = 4/Δx Σ_d (Σ_o (o − fx_d) S_d[o]) e_dᵀ with
        // S_d[o] = Σ_{nodes with o_d = o} w v_i.
        let mut sums = [[Vector::<D>::zeros(); 3]; D];
        for_stencil::<D>(&w, |k, o, weight| {
            let gw = node_at(&grid.vel, st[k] as usize) * weight;
            for d in 0..D {
                sums[d][o[d]] += gw;
            }
        });
        let nv = sums[0][0] + sums[0][1] + sums[0][2];
        let mut nc = Matrix::<D>::zeros();
        for d in 0..D {
            let col =
                (sums[d][0] * (0.0 - fx[d]) + sums[d][1] * (1.0 - fx[d]) + sums[d][2] * (2.0 - fx[d])) * (4.0 * inv_dx);
            nc.set_column(d, &col);
        }
        *vn = nv;
        *cn = nc;
        *xn = x[p] + nv * dt;
        *key = keyer.key(xn);
        if !(all_finite(xn.as_slice()) && all_finite(nv.as_slice()) && all_finite(nc.as_slice())) {
            bad.fetch_min(p, Ordering::Relaxed);
        }
    });
    let bad = bad.into_inner();
    if bad != usize::MAX {
        return Err(MpmError::BlowUp {
            step,
            particle: bad,
            reason: "non-finite particle velocity or position".into(),
        });
    }
    Ok(())
}
