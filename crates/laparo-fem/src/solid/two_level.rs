//! Two-level (p-multigrid) preconditioner of the TET10 tangent, for meshes whose direct Cholesky
//! factor does not fit in memory.
//!
//! The linear-tetrahedron space of the same mesh is a subspace of the quadratic one (a P1 field is
//! reproduced exactly by TET10 nodes: vertex values, and the mean of the two end vertices at each
//! mid-edge node), which gives the prolongation P. One application of the preconditioner is a
//! symmetric two-level cycle: a forward block Gauss–Seidel sweep over the quadratic nodes, the
//! Galerkin coarse correction with Pᵀ K P (factorised by the sparse Cholesky of `linear.rs`, about
//! an eighth of the fine DOFs), and a backward sweep. It is symmetric positive definite whenever K
//! is, so it preconditions conjugate gradients. Hand-written: faer has no multigrid, and the
//! algebraic multigrid crates do not build the P2 → P1 hierarchy that the mesh gives for free.
use super::linear::{norm, pcg, DirectSystem, Factor, NodeGraph, PcgEnd};
use super::newton::{FillOrdering, Timings};
use super::problem::{node_adjacency, SolidProblem};
use crate::error::{FemError, Result};
use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;
use std::time::Instant;

/// The fine (TET10 free nodes) and coarse (free linear vertices) levels.
pub(crate) struct TwoLevel {
    /// Fine free DOFs (3 per free node).
    pub n: usize,
    node_of_free: Vec<usize>,
    /// Per fine free node: up to two coarse parents (vertex id, weight); weight 0 = none.
    parents: Vec<[(usize, f64); 2]>,
    /// Per vertex: its fine children (free node id, weight).
    children: Vec<Vec<(usize, f64)>>,
    /// Vertex adjacency of the linear tetrahedra (CSR, sorted, self included).
    crow_ptr: Vec<usize>,
    ccols: Vec<usize>,
    /// Coarse free index of each vertex (`usize::MAX` = prescribed).
    cfree_of_vertex: Vec<usize>,
    /// Block index of each fine free node's diagonal block.
    diag_block: Vec<usize>,
    /// Fine free nodes grouped by colour (greedy colouring of the node graph: no two coupled nodes share
    /// one): colour c holds `colour_nodes[colour_ptr[c]..colour_ptr[c + 1]]`, ascending.
    colour_ptr: Vec<usize>,
    colour_nodes: Vec<usize>,
    pub coarse: DirectSystem,
}

impl TwoLevel {
    pub fn new(p: &SolidProblem, free_of_node: &[usize], n_free: usize, ordering: FillOrdering) -> Result<Self> {
        let mesh = &p.mesh;
        let nv = mesh.n_vertices;
        let mut node_of_free = vec![0; n_free];
        for (b, &f) in free_of_node.iter().enumerate() {
            if f != usize::MAX {
                node_of_free[f] = b;
            }
        }
        let mut edge_of_node = vec![(usize::MAX, usize::MAX); mesh.n_nodes() - nv];
        for (&(a, b), &m) in &mesh.edge_nodes {
            edge_of_node[m - nv] = (a, b);
        }
        let vertex_free = |v: usize| !p.is_prescribed(v);
        let mut parents = vec![[(0usize, 0.0f64); 2]; n_free];
        let mut children: Vec<Vec<(usize, f64)>> = vec![Vec::new(); nv];
        for (f, &b) in node_of_free.iter().enumerate() {
            let mut list = [(0usize, 0.0f64); 2];
            if b < nv {
                list[0] = (b, 1.0);
            } else {
                let (a, c) = edge_of_node[b - nv];
                let mut k = 0;
                for v in [a, c] {
                    if vertex_free(v) {
                        list[k] = (v, 0.5);
                        k += 1;
                    }
                }
            }
            for &(v, w) in &list {
                if w > 0.0 {
                    children[v].push((b, w));
                }
            }
            parents[f] = list;
        }
        let (crow_ptr, ccols) = node_adjacency(nv, mesh.elements.iter().map(|el| &el[..4]));
        let mut cfree_of_vertex = vec![usize::MAX; nv];
        let mut nc = 0;
        for (v, c) in cfree_of_vertex.iter_mut().enumerate() {
            if vertex_free(v) {
                *c = nc;
                nc += 1;
            }
        }
        let graph = NodeGraph {
            row_ptr: &crow_ptr,
            cols: &ccols,
            points: &mesh.nodes[..nv],
            free_of_node: &cfree_of_vertex,
            n_free: nc,
        };
        let coarse = DirectSystem::new(&graph, ordering)?;
        let diag_block = node_of_free
            .iter()
            .map(|&b| {
                let row = &p.cols[p.row_ptr[b]..p.row_ptr[b + 1]];
                p.row_ptr[b] + row.binary_search(&b).expect("diagonal in pattern")
            })
            .collect();
        let (colour_ptr, colour_nodes) = colour_free_nodes(p, free_of_node, &node_of_free);
        Ok(Self {
            n: 3 * n_free,
            node_of_free,
            parents,
            children,
            crow_ptr,
            ccols,
            cfree_of_vertex,
            diag_block,
            colour_ptr,
            colour_nodes,
            coarse,
        })
    }

    /// Galerkin coarse blocks Pᵀ (K + shift I) P in the vertex graph's block layout.
    fn galerkin(&self, p: &SolidProblem, free_of_node: &[usize], blocks: &[f64], shift: f64) -> Vec<f64> {
        let nv = self.cfree_of_vertex.len();
        let rows: Vec<Vec<f64>> = (0..nv)
            .into_par_iter()
            .map(|pb| {
                let (lo, hi) = (self.crow_ptr[pb], self.crow_ptr[pb + 1]);
                let mut out = vec![0.0; 9 * (hi - lo)];
                if self.cfree_of_vertex[pb] == usize::MAX {
                    return out;
                }
                let crow = &self.ccols[lo..hi];
                for &(b, wb) in &self.children[pb] {
                    for pidx in p.row_ptr[b]..p.row_ptr[b + 1] {
                        let a = p.cols[pidx];
                        let fa = free_of_node[a];
                        if fa == usize::MAX {
                            continue;
                        }
                        let blk = &blocks[9 * pidx..9 * pidx + 9];
                        for &(pa, wa) in &self.parents[fa] {
                            if wa == 0.0 {
                                continue;
                            }
                            let c = crow.binary_search(&pa).expect("coarse pattern holds every fine coupling");
                            let w = wb * wa;
                            let o = &mut out[9 * c..9 * c + 9];
                            for (x, &k) in o.iter_mut().zip(blk) {
                                *x += w * k;
                            }
                            if a == b {
                                for d in 0..3 {
                                    o[4 * d] += w * shift;
                                }
                            }
                        }
                    }
                }
                out
            })
            .collect();
        rows.concat()
    }

    /// Inverses of the fine diagonal blocks (+ shift I); `None` if one is not positive definite.
    fn diagonal_inverses(&self, blocks: &[f64], shift: f64) -> Option<Vec<Matrix3<f64>>> {
        self.diag_block
            .par_iter()
            .map(|&d| {
                let m = Matrix3::from_row_slice(&blocks[9 * d..9 * d + 9]) + Matrix3::identity() * shift;
                let m = (m + m.transpose()) * 0.5;
                m.cholesky().map(|c| c.inverse())
            })
            .collect()
    }

    /// y = (K + shift I) x over the fine free DOFs.
    fn product(&self, p: &SolidProblem, free_of_node: &[usize], blocks: &[f64], shift: f64, x: &[f64], y: &mut [f64]) {
        y.par_chunks_mut(3).enumerate().for_each(|(f, yf)| {
            let b = self.node_of_free[f];
            let mut acc = Vector3::new(shift * x[3 * f], shift * x[3 * f + 1], shift * x[3 * f + 2]);
            for pidx in p.row_ptr[b]..p.row_ptr[b + 1] {
                let fa = free_of_node[p.cols[pidx]];
                if fa == usize::MAX {
                    continue;
                }
                let k = &blocks[9 * pidx..9 * pidx + 9];
                let xa = &x[3 * fa..3 * fa + 3];
                for r in 0..3 {
                    acc[r] += k[3 * r] * xa[0] + k[3 * r + 1] * xa[1] + k[3 * r + 2] * xa[2];
                }
            }
            yf.copy_from_slice(acc.as_slice());
        });
    }

    /// One multicolour block Gauss–Seidel sweep for (K + shift I) z = r: colour by colour (forward, or
    /// backward in reverse colour order), the nodes of one colour in parallel — no two of them are
    /// coupled, so the result does not depend on the thread count.
    #[allow(clippy::too_many_arguments)] // the level's fixed data and the sweep's vectors
    fn sweep(
        &self,
        p: &SolidProblem,
        free_of_node: &[usize],
        blocks: &[f64],
        dinv: &[Matrix3<f64>],
        r: &[f64],
        z: &mut [f64],
        forward: bool,
    ) {
        let ncol = self.colour_ptr.len() - 1;
        for step in 0..ncol {
            let c = if forward { step } else { ncol - 1 - step };
            let nodes = &self.colour_nodes[self.colour_ptr[c]..self.colour_ptr[c + 1]];
            let zr: &[f64] = z;
            let new: Vec<Vector3<f64>> = nodes
                .par_iter()
                .with_min_len(256)
                .map(|&f| {
                    let b = self.node_of_free[f];
                    let mut s = Vector3::new(r[3 * f], r[3 * f + 1], r[3 * f + 2]);
                    for pidx in p.row_ptr[b]..p.row_ptr[b + 1] {
                        let a = p.cols[pidx];
                        let fa = free_of_node[a];
                        if a == b || fa == usize::MAX {
                            continue;
                        }
                        let k = &blocks[9 * pidx..9 * pidx + 9];
                        let za = &zr[3 * fa..3 * fa + 3];
                        for c in 0..3 {
                            s[c] -= k[3 * c] * za[0] + k[3 * c + 1] * za[1] + k[3 * c + 2] * za[2];
                        }
                    }
                    dinv[f] * s
                })
                .collect();
            for (&f, v) in nodes.iter().zip(&new) {
                z[3 * f..3 * f + 3].copy_from_slice(v.as_slice());
            }
        }
    }

    /// Pᵀ x: fine free DOFs → coarse free DOFs.
    fn restrict(&self, x: &[f64]) -> Vec<f64> {
        let mut xc = vec![0.0; self.coarse.n];
        for (f, par) in self.parents.iter().enumerate() {
            for &(v, w) in par.iter().filter(|(_, w)| *w != 0.0) {
                let c = self.cfree_of_vertex[v];
                for k in 0..3 {
                    xc[3 * c + k] += w * x[3 * f + k];
                }
            }
        }
        xc
    }

    /// x += P xc: a linear-tetrahedron field interpolated at the TET10 nodes.
    fn prolong_add(&self, xc: &[f64], x: &mut [f64]) {
        for (f, par) in self.parents.iter().enumerate() {
            for &(v, w) in par.iter().filter(|(_, w)| *w != 0.0) {
                let c = self.cfree_of_vertex[v];
                for k in 0..3 {
                    x[3 * f + k] += w * xc[3 * c + k];
                }
            }
        }
    }

    /// M⁻¹ r: forward sweep, coarse correction, backward sweep.
    #[allow(clippy::too_many_arguments)] // the level's fixed data and the cycle's vectors
    fn cycle(
        &self,
        p: &SolidProblem,
        free_of_node: &[usize],
        blocks: &[f64],
        shift: f64,
        dinv: &[Matrix3<f64>],
        coarse: &Factor,
        r: &[f64],
    ) -> Vec<f64> {
        let mut z = vec![0.0; self.n];
        self.sweep(p, free_of_node, blocks, dinv, r, &mut z, true);
        let mut kz = vec![0.0; self.n];
        self.product(p, free_of_node, blocks, shift, &z, &mut kz);
        kz.iter_mut().zip(r).for_each(|(k, &ri)| *k = ri - *k); // the residual r − K z
        let mut rc = self.restrict(&kz);
        self.coarse.solve_in_place(coarse, &mut rc);
        self.prolong_add(&rc, &mut z);
        self.sweep(p, free_of_node, blocks, dinv, r, &mut z, false);
        z
    }

    /// Factor of the coarse matrix for `blocks` (+ shift); kept for reuse when unshifted.
    fn coarse_factor(
        &self,
        p: &SolidProblem,
        free_of_node: &[usize],
        blocks: &[f64],
        shift: f64,
        timings: &mut Timings,
    ) -> Result<Factor> {
        let cb = self.galerkin(p, free_of_node, blocks, shift);
        let mut vals = self.coarse.values(&cb);
        // the coarse matrix is SPD when K + shift I is; a shift it needs anyway only weakens the preconditioner
        Ok(self.coarse.factor(&mut vals, timings)?.0)
    }

    /// Solve K x = rhs (in place) to ‖K x − rhs‖ ≤ max(`forcing` ‖rhs‖, `abs_tol`) by conjugate
    /// gradients with the two-level preconditioner. The coarse factor in `reuse` is used when there is
    /// one (a preconditioner of an earlier tangent) and refreshed when the solve is slow or fails.
    /// Non-positive curvature (an indefinite tangent) is met by a growing diagonal shift, as the direct
    /// path does. After `max_iterations` the last iterate is taken if it has reduced the residual
    /// tenfold (inexact Newton with a looser forcing term). Returns whether a shift was needed.
    #[allow(clippy::too_many_arguments)] // the Newton iteration's running state
    pub fn solve(
        &self,
        p: &SolidProblem,
        free_of_node: &[usize],
        blocks: &[f64],
        rhs: &mut [f64],
        abs_tol: f64,
        (forcing, max_iterations): (f64, usize),
        reuse: &mut Option<Factor>,
        timings: &mut Timings,
    ) -> Result<bool> {
        let t0 = Instant::now();
        let bnorm = norm(rhs);
        let target = (forcing * bnorm).max(abs_tol);
        let dmax = self
            .diag_block
            .iter()
            .flat_map(|&d| [blocks[9 * d], blocks[9 * d + 4], blocks[9 * d + 8]])
            .fold(0.0f64, |m, v| m.max(v.abs()))
            .max(1e-300);
        let run = |shift: f64, coarse: &Factor, iterations: &mut usize| -> PcgEnd {
            let Some(dinv) = self.diagonal_inverses(blocks, shift) else { return PcgEnd::NonPositiveCurvature };
            pcg(
                rhs,
                |x, y| self.product(p, free_of_node, blocks, shift, x, y),
                |r| self.cycle(p, free_of_node, blocks, shift, &dinv, coarse, r),
                target,
                max_iterations,
                iterations,
            )
        };
        let mut shift = 0.0;
        let mut fresh = reuse.is_none();
        let mut result = None;
        for _ in 0..16 {
            if fresh {
                *reuse = Some(self.coarse_factor(p, free_of_node, blocks, shift, timings)?);
            }
            let coarse = reuse.as_ref().expect("coarse factor");
            let before = timings.pcg_iterations;
            let out = run(shift, coarse, &mut timings.pcg_iterations);
            let used = timings.pcg_iterations - before;
            match out {
                PcgEnd::Converged(x) => {
                    if !fresh && used > max_iterations / 4 {
                        *reuse = None; // slow: the tangent has drifted from the coarse factor
                    }
                    result = Some(x);
                    break;
                }
                PcgEnd::IterationLimit(x, rn) if fresh && rn <= 0.1 * bnorm => {
                    *reuse = None;
                    result = Some(x);
                    break;
                }
                _ => {}
            }
            if !fresh {
                fresh = true; // first retry: the same shift with a coarse factor of this tangent
                continue;
            }
            if shift > 1e3 * dmax {
                break;
            }
            shift = if shift == 0.0 { 1e-8 * dmax } else { shift * 10.0 };
        }
        if shift > 0.0 {
            *reuse = None; // a shifted coarse factor is not kept
        }
        timings.solve_s += t0.elapsed().as_secs_f64();
        let x = result.ok_or_else(|| {
            FemError::Solver("two-level conjugate gradients fail even with a large diagonal shift".into())
        })?;
        rhs.copy_from_slice(&x);
        Ok(shift > 0.0)
    }
}

/// Greedy colouring of the free nodes in index order (each takes the smallest colour none of its coupled,
/// already coloured nodes has), returned as CSR groups.
fn colour_free_nodes(p: &SolidProblem, free_of_node: &[usize], node_of_free: &[usize]) -> (Vec<usize>, Vec<usize>) {
    let nf = node_of_free.len();
    let mut colour = vec![usize::MAX; nf];
    let mut used: Vec<usize> = Vec::new(); // used[c] == f marks colour c taken for node f
    let mut ncol = 0;
    for (f, &b) in node_of_free.iter().enumerate() {
        for &a in &p.cols[p.row_ptr[b]..p.row_ptr[b + 1]] {
            let fa = free_of_node[a];
            if fa != usize::MAX && colour[fa] != usize::MAX {
                used[colour[fa]] = f;
            }
        }
        let c = (0..ncol).find(|&c| used[c] != f).unwrap_or(ncol);
        if c == ncol {
            ncol += 1;
            used.push(usize::MAX);
        }
        colour[f] = c;
    }
    let mut colour_ptr = vec![0; ncol + 1];
    for &c in &colour {
        colour_ptr[c + 1] += 1;
    }
    for c in 0..ncol {
        colour_ptr[c + 1] += colour_ptr[c];
    }
    let mut next = colour_ptr.clone();
    let mut colour_nodes = vec![0; nf];
    for (f, &c) in colour.iter().enumerate() {
        colour_nodes[next[c]] = f;
        next[c] += 1;
    }
    (colour_ptr, colour_nodes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solid::{Quadrature, SolidProblem, Tet10Mesh};
    use crate::NeoHookean;

    /// [0, 10 mm]³ in n³ cubes of 6 Kuhn tetrahedra, bottom face fixed.
    fn cube(n: usize) -> SolidProblem {
        let m = Tet10Mesh::from_linear(&crate::mesh::shapes::kuhn_box([n; 3], 10.0 / n as f64)).unwrap();
        let bottom: Vec<usize> = (0..m.n_vertices).filter(|&i| m.nodes[i].z < 1e-9).collect();
        let fixed = SolidProblem::fixed_vertices(&m, &bottom).unwrap();
        SolidProblem::new(m, NeoHookean::liver(), &fixed, &Default::default(), Quadrature::Degree2).unwrap()
    }

    fn free_numbering(p: &SolidProblem) -> (Vec<usize>, usize) {
        let mut free = vec![usize::MAX; p.mesh.n_nodes()];
        let mut nf = 0;
        for (i, f) in free.iter_mut().enumerate() {
            if !p.is_prescribed(i) {
                *f = nf;
                nf += 1;
            }
        }
        (free, nf)
    }

    fn pseudo_random(n: usize, seed: f64) -> Vec<f64> {
        (0..n).map(|i| ((i as f64 + 1.0) * seed).sin()).collect()
    }

    #[test]
    fn coarse_matrix_is_galerkin_cycle_is_symmetric_and_cg_converges_fast() {
        let p = cube(4);
        let (free, nf) = free_numbering(&p);
        let tl = TwoLevel::new(&p, &free, nf, FillOrdering::NestedDissection).unwrap();
        // a deformed state (0.1 mm field growing with height), so K is not the rest tangent (1 mm makes this
        // non-equilibrium state's tangent indefinite)
        let u: Vec<f64> = p
            .mesh
            .nodes
            .iter()
            .flat_map(|x| {
                let s = x.z / 100.0;
                [s * (0.3 * x.y).sin(), 0.5 * s * s, -0.2 * s * (0.2 * x.x).cos()]
            })
            .collect();
        let a = p.assemble(&u, true).unwrap();
        let blocks = a.blocks.as_ref().unwrap();
        let kd = p.tangent_dense(&u).unwrap();
        let dofs: Vec<usize> = (0..p.mesh.n_nodes())
            .filter(|&i| free[i] != usize::MAX)
            .flat_map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
            .collect();
        assert_eq!(dofs.len(), tl.n);
        // the colouring covers every free node once and never puts two coupled nodes in one colour
        let mut colour = vec![usize::MAX; nf];
        for c in 0..tl.colour_ptr.len() - 1 {
            for &f in &tl.colour_nodes[tl.colour_ptr[c]..tl.colour_ptr[c + 1]] {
                assert_eq!(colour[f], usize::MAX);
                colour[f] = c;
            }
        }
        for (f, &b) in tl.node_of_free.iter().enumerate() {
            for &a in &p.cols[p.row_ptr[b]..p.row_ptr[b + 1]] {
                if a != b && free[a] != usize::MAX {
                    assert_ne!(colour[f], colour[free[a]], "coupled nodes {b} and {a} share a colour");
                }
            }
        }
        // the fine product is the dense tangent restricted to the free DOFs
        let x = pseudo_random(tl.n, 0.37);
        let mut kx = vec![0.0; tl.n];
        tl.product(&p, &free, blocks, 0.0, &x, &mut kx);
        for (r, &g) in dofs.iter().enumerate() {
            let want: f64 = dofs.iter().enumerate().map(|(c, &h)| kd[(g, h)] * x[c]).sum();
            assert!((kx[r] - want).abs() < 1e-10 * (1.0 + want.abs()), "row {r}: {} vs {want}", kx[r]);
        }
        // P reproduces a linear field at the mid-edge nodes; Pᵀ K P c equals the coarse matrix times c
        let xc = pseudo_random(tl.coarse.n, 0.71);
        let mut px = vec![0.0; tl.n];
        tl.prolong_add(&xc, &mut px);
        for (f, &b) in tl.node_of_free.iter().enumerate() {
            if b >= p.mesh.n_vertices {
                let (&(va, vb), _) = p.mesh.edge_nodes.iter().find(|(_, &m)| m == b).unwrap();
                for k in 0..3 {
                    let at = |v: usize| {
                        let c = tl.cfree_of_vertex[v];
                        if c == usize::MAX {
                            0.0
                        } else {
                            xc[3 * c + k]
                        }
                    };
                    assert!((px[3 * f + k] - 0.5 * (at(va) + at(vb))).abs() < 1e-14);
                }
            }
        }
        let mut kpx = vec![0.0; tl.n];
        tl.product(&p, &free, blocks, 0.0, &px, &mut kpx);
        let ptkpx = tl.restrict(&kpx);
        let cb = tl.galerkin(&p, &free, blocks, 0.0);
        let cvals = tl.coarse.values(&cb);
        let mut kc = vec![0.0; tl.coarse.n];
        tl.coarse.product(&cvals, &xc, &mut kc);
        let scale = norm(&ptkpx);
        for (a, b) in kc.iter().zip(&ptkpx) {
            assert!((a - b).abs() < 1e-11 * scale, "{a} vs {b}");
        }
        // the cycle is symmetric: yᵀ M⁻¹ x = xᵀ M⁻¹ y
        let mut t = Timings::default();
        let coarse = tl.coarse_factor(&p, &free, blocks, 0.0, &mut t).unwrap();
        let dinv = tl.diagonal_inverses(blocks, 0.0).unwrap();
        let y = pseudo_random(tl.n, 1.13);
        let mx = tl.cycle(&p, &free, blocks, 0.0, &dinv, &coarse, &x);
        let my = tl.cycle(&p, &free, blocks, 0.0, &dinv, &coarse, &y);
        let (a1, a2) = (crate::solid::linear::dot(&y, &mx), crate::solid::linear::dot(&x, &my));
        assert!((a1 - a2).abs() < 1e-10 * a1.abs().max(a2.abs()), "{a1} vs {a2}");
        for seed in [0.37, 1.13, 2.9, 0.011] {
            let v = pseudo_random(tl.n, seed);
            let mut kv = vec![0.0; tl.n];
            tl.product(&p, &free, blocks, 0.0, &v, &mut kv);
            let mv = tl.cycle(&p, &free, blocks, 0.0, &dinv, &coarse, &v);
            let (vkv, vmv) = (crate::solid::linear::dot(&v, &kv), crate::solid::linear::dot(&v, &mv));
            assert!(vkv > 0.0 && vmv > 0.0, "K and the cycle are positive definite: {vkv}, {vmv}");
        }
        // CG with the cycle reaches 1e-10 in far fewer iterations than with block Jacobi alone
        let target = 1e-10 * norm(&x);
        let (mut it2, mut itj) = (0, 0);
        let sol = match pcg(
            &x,
            |v, w| tl.product(&p, &free, blocks, 0.0, v, w),
            |r| tl.cycle(&p, &free, blocks, 0.0, &dinv, &coarse, r),
            target,
            500,
            &mut it2,
        ) {
            PcgEnd::Converged(s) => s,
            PcgEnd::IterationLimit(_, rn) => panic!("two-level CG: {rn} after {it2} iterations (target {target})"),
            PcgEnd::NonPositiveCurvature => panic!("two-level CG: non-positive curvature after {it2}"),
        };
        let jacobi = |r: &[f64]| -> Vec<f64> {
            r.chunks(3)
                .zip(&dinv)
                .flat_map(|(c, d)| (d * Vector3::new(c[0], c[1], c[2])).iter().copied().collect::<Vec<_>>())
                .collect()
        };
        let PcgEnd::Converged(_) =
            pcg(&x, |v, w| tl.product(&p, &free, blocks, 0.0, v, w), jacobi, target, 5000, &mut itj)
        else {
            panic!("Jacobi CG did not converge")
        };
        assert!(3 * it2 < itj, "two-level {it2} vs block-Jacobi {itj} iterations");
        let mut ks = vec![0.0; tl.n];
        tl.product(&p, &free, blocks, 0.0, &sol, &mut ks);
        let res: Vec<f64> = ks.iter().zip(&x).map(|(a, b)| a - b).collect();
        assert!(norm(&res) <= target * (1.0 + 1e-9));
        // through `solve`: same system, the coarse factor kept for reuse, then reused
        let mut rhs = x.clone();
        let mut reuse = None;
        let shifted = tl.solve(&p, &free, blocks, &mut rhs, target, (0.0, 500), &mut reuse, &mut t).unwrap();
        assert!(!shifted && reuse.is_some());
        let diff = rhs.iter().zip(&sol).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        assert!(diff < 1e-8 * norm(&sol), "{diff}");
    }

    #[test]
    fn an_indefinite_matrix_is_shifted() {
        // K − 2 max|K_ii| I is negative definite: CG meets non-positive curvature, the shift grows until
        // the system is positive definite, and the direction still points along the right-hand side.
        let p = cube(2);
        let (free, nf) = free_numbering(&p);
        let tl = TwoLevel::new(&p, &free, nf, FillOrdering::Amd).unwrap();
        let u = vec![0.0; 3 * p.mesh.n_nodes()];
        let a = p.assemble(&u, true).unwrap();
        let mut blocks = a.blocks.unwrap();
        let dmax = tl
            .diag_block
            .iter()
            .flat_map(|&d| [blocks[9 * d], blocks[9 * d + 4], blocks[9 * d + 8]])
            .fold(0.0f64, f64::max);
        for &d in &tl.diag_block {
            for k in 0..3 {
                blocks[9 * d + 4 * k] -= 2.0 * dmax;
            }
        }
        let rhs = pseudo_random(tl.n, 0.53);
        let mut x = rhs.clone();
        let mut reuse = None;
        let mut t = Timings::default();
        let shifted = tl.solve(&p, &free, &blocks, &mut x, 0.0, (1e-6, 200), &mut reuse, &mut t).unwrap();
        assert!(shifted);
        assert!(reuse.is_none(), "a shifted coarse factor is not kept");
        assert!(crate::solid::linear::dot(&rhs, &x) > 0.0);
    }
}
