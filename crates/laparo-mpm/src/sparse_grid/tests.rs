//! Colour partition and node-window invariants of the sparse grid.
use super::*;
use crate::linalg::stencil_len;
use crate::stencil::base_of;

/// Node indices touched by the particles of each colour task, per colour.
fn task_nodes<const D: usize>(g: &SparseGrid<D>, x: &[Vector<D>]) -> Vec<Vec<Vec<u32>>> {
    let inv_dx = 1.0 / g.spec().dx;
    g.colors
        .iter()
        .map(|tasks| {
            tasks
                .iter()
                .map(|&[b0, b1]| {
                    let mut nodes = Vec::new();
                    for pb in b0 as usize..b1 as usize {
                        let blk = g.pblocks[pb];
                        for &p in &g.order[blk.start as usize..blk.end as usize] {
                            let st = g.window(pb).nodes(&base_of(&x[p as usize], inv_dx));
                            nodes.extend_from_slice(&st[..stencil_len(D)]);
                        }
                    }
                    nodes.sort_unstable();
                    nodes.dedup();
                    nodes
                })
                .collect()
        })
        .collect()
}

fn check<const D: usize>(x: &[Vector<D>], n_grid: usize) {
    let mut g = SparseGrid::<D>::new(GridSpec::unit(n_grid));
    g.build(x, 0).unwrap();
    // Every particle in exactly one task; same-colour tasks touch disjoint nodes; stencil node
    // indices agree with the node coordinates.
    let mut seen = vec![0u32; x.len()];
    for tasks in &g.colors {
        for &[b0, b1] in tasks {
            for pb in b0..b1 {
                let blk = g.pblocks[pb as usize];
                for &p in &g.order[blk.start as usize..blk.end as usize] {
                    seen[p as usize] += 1;
                }
            }
        }
    }
    assert!(seen.iter().all(|&c| c == 1));
    for colour in task_nodes(&g, x) {
        let mut all: Vec<u32> = colour.iter().flatten().copied().collect();
        let n = all.len();
        all.sort_unstable();
        all.dedup();
        assert_eq!(all.len(), n, "same-colour tasks share a node");
    }
    let inv_dx = 1.0 / g.spec().dx;
    for (p, xp) in x.iter().enumerate() {
        let b = base_of(xp, inv_dx);
        let st = g.window(g.pblock_of[p] as usize).nodes(&b);
        for_stencil_offsets::<D>(|k, o| {
            let c = g.node_coord(st[k] as usize);
            for d in 0..D {
                assert_eq!(c[d] as i32, b[d] + o[d] as i32);
            }
        });
    }
}

#[test]
fn colour_tasks_are_node_disjoint() {
    // Deterministic pseudo-random clouds: a wide 2D body (several chunks per colour), a narrow
    // one, a sparse scatter, and a 3D body.
    let mut r = 0x2545_f491_4f6c_dd1du64;
    let mut rnd = move || {
        r ^= r << 13;
        r ^= r >> 7;
        r ^= r << 17;
        (r >> 11) as f64 / (1u64 << 53) as f64
    };
    for (lo, hi, n) in
        [([0.1, 0.2], [0.8, 0.6], 20000), ([0.4, 0.1], [0.47, 0.9], 3000), ([0.05, 0.05], [0.95, 0.95], 500)]
    {
        let x: Vec<Vector<2>> = (0..n).map(|_| Vector::<2>::from_fn(|d, _| lo[d] + (hi[d] - lo[d]) * rnd())).collect();
        check::<2>(&x, 96);
    }
    let x: Vec<Vector<3>> = (0..5000).map(|_| Vector::<3>::from_fn(|_, _| 0.3 + 0.4 * rnd())).collect();
    check::<3>(&x, 48);
}
