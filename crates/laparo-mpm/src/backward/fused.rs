//! The P2G adjoint of step s fused with the G2P adjoint of step s − 1.
//!
//! Per particle, the P2G adjoint of step s (a gather from the node adjoints of grid s) produces
//! exactly the (x̄, v̄, C̄) of the step input s that the G2P adjoint of step s − 1 (a scatter into the
//! node-velocity adjoint of grid s − 1) consumes. So the reverse pass runs both in one coloured pass
//! over grid s − 1's layout: each particle first does its P2G-adjoint gather on grid s (read-only
//! node adjoints), then its G2P-adjoint scatter into grid s − 1. One parallel region per reverse
//! step less, and the particle arrays of step s are read once instead of twice.
//!
//! Results are bit-identical to running the two stages apart: each particle's gather does the same
//! arithmetic in the same order, and the scatter visits the particles in the same coloured order
//! (that of grid s − 1) as the stand-alone G2P adjoint. Two grid layouts are needed at once: grid s's
//! for the gather windows (looked up through its `pblock_of`), grid s − 1's for the colour tasks.
use crate::backward::{g2p::G2pAdjoint, p2g::P2gAdjoint};
use crate::constitutive::ConstitutiveModel;
use crate::linalg::Vector;
use crate::sparse_grid::{prefetch, SparseGrid, SyncPtr};

/// Run `p2g` (the P2G adjoint of step s, on `grid`) then `g2p` (the G2P adjoint of step s − 1, on
/// `grid_prev`) for every particle, colour by colour of `grid_prev`. `x_bar_g2p`: in, the G2P part
/// of x̄ of step s (from the G2P adjoint of step s); out, that of step s − 1.
pub(crate) fn p2g_g2p_adjoint<const D: usize, M: ConstitutiveModel<D>>(
    grid: &SparseGrid<D>,
    p2g: &P2gAdjoint<'_, D, M>,
    grid_prev: &SparseGrid<D>,
    g2p: &G2pAdjoint<'_, D>,
    x_bar_g2p: &mut [Vector<D>],
) {
    assert_eq!(grid.pblock_of.len(), x_bar_g2p.len());
    assert_eq!(grid_prev.pblock_of.len(), x_bar_g2p.len());
    let xg = SyncPtr(x_bar_g2p.as_mut_ptr());
    let pblock_of = &grid.pblock_of;
    let pre = |q: usize| {
        p2g.prefetch(q);
        g2p.prefetch(q);
        prefetch(xg.addr(q));
        prefetch(&pblock_of[q]);
    };
    grid_prev.for_each_coloured(pre, |p, nbr_prev| {
        let nbr = grid.window(pblock_of[p] as usize);
        // SAFETY: every particle is visited once (its own entries only); the scatter's nodes are
        // disjoint within a colour of `grid_prev`.
        unsafe {
            let xg = xg.at(p);
            let (xb, vb, cb) = p2g.particle(p, &nbr, xg);
            *xg = g2p.particle(p, nbr_prev, &xb, &vb, &cb);
        }
    });
}
