//! Fill-reducing ordering of the CPC system: the geometric nested dissection of the grid.
//!
//! The mesh vertices lie on a regular grid of step `grid_step_px`; a grid line is a vertex
//! separator of the triangulated grid, so splitting the bounding box along its longer side by its
//! middle grid line, ordering both halves recursively and the separator last gives a
//! nested-dissection order in O(n log n) (no graph partitioner, no AMD). The factorisation that
//! uses it is in [`crate::topology`].
use crate::mesh::CpcMesh;

/// Parts of at most this many vertices are left undivided by the nested dissection (measured with
/// the stable partitions, 4 px, second solve on a new topology: leaf 4 4.20 ms, 8 3.84–4.01,
/// 16 3.67–3.70, 24 3.68–3.79, 32 3.79–3.89, 48 4.00–4.04 ms: larger leaves add a little fill
/// but give faer larger supernodes).
pub const ND_LEAF: usize = 16;

/// Geometric nested-dissection order of the mesh vertices (old index at each new position):
/// split the grid box along its longer side by one grid line (a vertex separator of the
/// triangulated grid), order both halves recursively, then the separator.
pub fn nested_dissection(mesh: &CpcMesh) -> Vec<usize> {
    nested_dissection_points(&mesh.p_init, mesh.grid_step_px)
}

/// [`nested_dissection`] of grid points `p_init` (px) on a grid of step `grid_step_px`.
pub fn nested_dissection_points(p_init: &[[f64; 2]], grid_step_px: usize) -> Vec<usize> {
    nested_dissection_leaf(p_init, grid_step_px, ND_LEAF)
}

/// Parts larger than this are ordered on two threads (`rayon::join`); the order is the same
/// whatever the thread count.
const ND_PARALLEL_MIN: usize = 2048;

/// One nested-dissection level of `ids` (grid coordinates `gc`): split the bounding box along its
/// longer side by the middle grid line and stably partition `ids` in place into
/// [left | right | separator] (`scratch`: same length). Returns the sizes (left, right), or `None`
/// when the part is not split (at most `leaf` vertices, or a single point).
fn nd_partition(ids: &mut [u32], scratch: &mut [u32], gc: &[[i32; 2]], leaf: usize) -> Option<(usize, usize)> {
    if ids.len() <= leaf {
        return None;
    }
    let (mut lo, mut hi) = ([i32::MAX; 2], [i32::MIN; 2]);
    for &v in ids.iter() {
        let g = gc[v as usize];
        for k in 0..2 {
            lo[k] = lo[k].min(g[k]);
            hi[k] = hi[k].max(g[k]);
        }
    }
    let ax = if hi[0] - lo[0] >= hi[1] - lo[1] { 0 } else { 1 };
    if hi[ax] == lo[ax] {
        return None;
    }
    let mid = (lo[ax] + hi[ax]) / 2;
    let (mut nl, mut nr) = (0, 0);
    for &v in ids.iter() {
        let c = gc[v as usize][ax];
        nl += (c < mid) as usize;
        nr += (c > mid) as usize;
    }
    let (mut il, mut ir, mut is) = (0, nl, nl + nr);
    for &v in ids.iter() {
        let c = gc[v as usize][ax];
        let slot = if c < mid {
            &mut il
        } else if c > mid {
            &mut ir
        } else {
            &mut is
        };
        scratch[*slot] = v;
        *slot += 1;
    }
    ids.copy_from_slice(scratch);
    Some((nl, nr))
}

/// Order `ids` in place: [order(left) | order(right) | separator], recursively.
fn nd_recurse(ids: &mut [u32], scratch: &mut [u32], gc: &[[i32; 2]], leaf: usize) {
    let Some((nl, nr)) = nd_partition(ids, scratch, gc, leaf) else {
        return;
    };
    let (left, rest) = ids.split_at_mut(nl);
    let (sl, srest) = scratch.split_at_mut(nl);
    let right = &mut rest[..nr];
    let sr = &mut srest[..nr];
    if nl + nr >= ND_PARALLEL_MIN {
        rayon::join(|| nd_recurse(left, sl, gc, leaf), || nd_recurse(right, sr, gc, leaf));
    } else {
        nd_recurse(left, sl, gc, leaf);
        nd_recurse(right, sr, gc, leaf);
    }
}

/// The nested-dissection order of [`nested_dissection_leaf`] and the sizes (left, right) of the
/// two parts of its top level (the separator follows them), `None` when the top is not split.
/// Linear work per level (stable in-place partitions), the two halves of large parts on two threads.
pub(crate) fn nested_dissection_split(
    p_init: &[[f64; 2]],
    grid_step_px: usize,
    leaf: usize,
) -> (Vec<usize>, Option<(usize, usize)>) {
    let s = grid_step_px as f64;
    let gc: Vec<[i32; 2]> = p_init.iter().map(|p| [(p[0] / s).round() as i32, (p[1] / s).round() as i32]).collect();
    let n = p_init.len();
    let mut ids: Vec<u32> = (0..n as u32).collect();
    let mut scratch = vec![0u32; n];
    let top = nd_partition(&mut ids, &mut scratch, &gc, leaf);
    if let Some((nl, nr)) = top {
        let (left, rest) = ids.split_at_mut(nl);
        let (sl, srest) = scratch.split_at_mut(nl);
        rayon::join(|| nd_recurse(left, sl, &gc, leaf), || nd_recurse(&mut rest[..nr], &mut srest[..nr], &gc, leaf));
    }
    (ids.into_iter().map(|v| v as usize).collect(), top)
}

/// [`nested_dissection_points`] with parts of at most `leaf` vertices left undivided.
pub fn nested_dissection_leaf(p_init: &[[f64; 2]], grid_step_px: usize, leaf: usize) -> Vec<usize> {
    nested_dissection_split(p_init, grid_step_px, leaf).0
}
