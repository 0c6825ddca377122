//! Fill-reducing orderings of the free-node graph for the sparse Cholesky of the tangent.
//!
//! Geometric nested dissection (George 1973; the coordinate-bisection variant of Miller, Teng,
//! Thurston & Vavasis): the nodes of a 3D mesh are split at the median of their widest coordinate,
//! the nodes of the lower half that touch the upper half form the separator, both halves are ordered
//! recursively and the separator is eliminated last. On a tetrahedral mesh of n nodes the factor then
//! has O(n^{4/3}) nonzeros and costs O(n²) flops, against the larger fill of a minimum-degree order
//! on big 3D meshes. Hand-written: faer takes a custom permutation but ships only AMD, and a graph
//! partitioner crate (METIS) would bring a C build; the mesh coordinates make a geometric split enough.

/// Elimination order of the graph's vertices (`order[k]` = the vertex eliminated k-th) by geometric
/// nested dissection. `points` are the vertex positions (mm), `row_ptr`/`cols` the adjacency (CSR,
/// symmetric; self-loops allowed). Subsets of at most `leaf` vertices are ordered by approximate
/// minimum degree (faer's AMD on the subgraph they induce), as METIS' nested dissection does.
pub(crate) fn nested_dissection(points: &[[f64; 3]], row_ptr: &[usize], cols: &[usize], leaf: usize) -> Vec<usize> {
    let n = points.len();
    let mut order = Vec::with_capacity(n);
    // side[v]: 0 outside the current subset, 1 lower half, 2 upper half
    let mut side = vec![0u8; n];
    let all: Vec<usize> = (0..n).collect();
    dissect(all, points, row_ptr, cols, leaf.max(1), &mut side, &mut order);
    order
}

fn dissect(
    mut set: Vec<usize>,
    points: &[[f64; 3]],
    row_ptr: &[usize],
    cols: &[usize],
    leaf: usize,
    side: &mut [u8],
    order: &mut Vec<usize>,
) {
    if set.len() <= leaf {
        leaf_order(&set, row_ptr, cols, side, order);
        return;
    }
    // the cut plane: among the three axes and a few quantiles around the median, the one with the
    // smallest separator (lower vertices touching the upper side); ties → the earlier candidate
    let mut best: Option<(usize, usize, usize)> = None; // (separator size, axis, split index)
    let mut sorted: [Vec<usize>; 3] = [set.clone(), set.clone(), set.clone()];
    for (axis, s) in sorted.iter_mut().enumerate() {
        // ties broken by the vertex index, so the order is deterministic
        s.sort_unstable_by(|&a, &b| points[a][axis].total_cmp(&points[b][axis]).then(a.cmp(&b)));
        for q in [0.35, 0.4, 0.45, 0.5, 0.55, 0.6, 0.65] {
            let k = ((s.len() as f64 * q) as usize).clamp(1, s.len() - 1);
            // a plane: everything below the k-th coordinate value (lattice meshes have equal coordinates)
            let m = points[s[k]][axis];
            let at = s.partition_point(|&v| points[v][axis] < m);
            let at = if at == 0 { k } else { at };
            for &v in &s[at..] {
                side[v] = 2;
            }
            let sep =
                s[..at].iter().filter(|&&v| cols[row_ptr[v]..row_ptr[v + 1]].iter().any(|&u| side[u] == 2)).count();
            for &v in &s[at..] {
                side[v] = 0;
            }
            if best.is_none_or(|(b, _, _)| sep < b) {
                best = Some((sep, axis, at));
            }
        }
    }
    let (_, axis, at) = best.unwrap_or((0, 0, set.len() / 2));
    set = std::mem::take(&mut sorted[axis]);
    let upper = set.split_off(at);
    for &v in &set {
        side[v] = 1;
    }
    for &v in &upper {
        side[v] = 2;
    }
    // separator: lower vertices with a neighbour in the upper half
    let (mut lower, mut sep) = (Vec::with_capacity(set.len()), Vec::new());
    for &v in &set {
        if cols[row_ptr[v]..row_ptr[v + 1]].iter().any(|&u| side[u] == 2) {
            sep.push(v);
        } else {
            lower.push(v);
        }
    }
    for &v in set.iter().chain(&upper) {
        side[v] = 0;
    }
    if lower.is_empty() || upper.is_empty() {
        // no useful split (a clique-like subset): keep the given order
        order.extend_from_slice(&lower);
        order.extend_from_slice(&upper);
        order.extend_from_slice(&sep);
        return;
    }
    dissect(lower, points, row_ptr, cols, leaf, side, order);
    dissect(upper, points, row_ptr, cols, leaf, side, order);
    order.extend_from_slice(&sep);
}

/// A leaf's vertices in approximate-minimum-degree order of the subgraph they induce (faer's AMD);
/// the given order if AMD fails.
fn leaf_order(set: &[usize], row_ptr: &[usize], cols: &[usize], local: &mut [u8], order: &mut Vec<usize>) {
    use faer::dyn_stack::{MemBuffer, MemStack};
    use faer::sparse::linalg::amd;
    use faer::sparse::SymbolicSparseColMatRef;
    let n = set.len();
    if n <= 2 {
        order.extend_from_slice(set);
        return;
    }
    // local index of each vertex of the set (the `side` buffer is free at the leaves: mark, then clear)
    let mut pos = std::collections::HashMap::with_capacity(n);
    for (i, &v) in set.iter().enumerate() {
        pos.insert(v, i);
        local[v] = 3;
    }
    let (mut cp, mut ri) = (vec![0usize], Vec::new());
    for &v in set {
        let j = pos[&v];
        let mut rows: Vec<usize> = cols[row_ptr[v]..row_ptr[v + 1]]
            .iter()
            .filter(|&&u| local[u] == 3)
            .map(|u| pos[u])
            .filter(|&i| i <= j)
            .collect();
        rows.sort_unstable();
        rows.dedup();
        ri.extend(rows);
        cp.push(ri.len());
    }
    for &v in set {
        local[v] = 0;
    }
    let (mut perm, mut inv) = (vec![0usize; n], vec![0usize; n]);
    let a = SymbolicSparseColMatRef::new_checked(n, n, &cp, None, &ri);
    let mut mem = MemBuffer::new(amd::order_scratch::<usize>(n, ri.len()));
    match amd::order(&mut perm, &mut inv, a, amd::Control::default(), MemStack::new(&mut mem)) {
        Ok(_) => order.extend(perm.iter().map(|&k| set[k])),
        Err(_) => order.extend_from_slice(set),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 5-point grid graph of nx × ny × nz vertices.
    fn grid(nx: usize, ny: usize, nz: usize) -> (Vec<[f64; 3]>, Vec<usize>, Vec<usize>) {
        let id = |i: usize, j: usize, k: usize| (k * ny + j) * nx + i;
        let mut pts = vec![];
        let (mut rp, mut cols) = (vec![0], vec![]);
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    pts.push([i as f64, j as f64, k as f64]);
                    let mut nb = vec![id(i, j, k)];
                    if i > 0 {
                        nb.push(id(i - 1, j, k));
                    }
                    if i + 1 < nx {
                        nb.push(id(i + 1, j, k));
                    }
                    if j > 0 {
                        nb.push(id(i, j - 1, k));
                    }
                    if j + 1 < ny {
                        nb.push(id(i, j + 1, k));
                    }
                    if k > 0 {
                        nb.push(id(i, j, k - 1));
                    }
                    if k + 1 < nz {
                        nb.push(id(i, j, k + 1));
                    }
                    nb.sort();
                    cols.extend(nb);
                    rp.push(cols.len());
                }
            }
        }
        (pts, rp, cols)
    }

    #[test]
    fn is_a_permutation_and_the_top_separator_is_last() {
        let (pts, rp, cols) = grid(9, 5, 4);
        let o = nested_dissection(&pts, &rp, &cols, 4);
        let mut seen = o.clone();
        seen.sort();
        assert_eq!(seen, (0..pts.len()).collect::<Vec<_>>());
        // the smallest plane separator of a 9 × 5 × 4 grid is a y-z layer (20 vertices; an x-z layer has
        // 36, an x-y layer 45): one x layer is eliminated last
        let last: Vec<usize> = o[o.len() - 20..].to_vec();
        let xs: std::collections::BTreeSet<i64> = last.iter().map(|&v| pts[v][0] as i64).collect();
        assert_eq!(xs.len(), 1, "top separator is one x layer: {xs:?}");
        let x0 = *xs.iter().next().unwrap();
        assert!((1..8).contains(&x0), "an interior layer: x = {x0}");
        assert_eq!(nested_dissection(&pts, &rp, &cols, 4), o, "deterministic");
    }
}
