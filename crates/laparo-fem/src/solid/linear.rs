//! The sparse Cholesky (faer) of a symmetric matrix stored as 3×3 node blocks, and preconditioned
//! conjugate gradients. Used for the TET10 tangent (the direct path of [`super::solve`]) and for the
//! linear-tetrahedron coarse level of the two-level preconditioner (`two_level.rs`).
use super::newton::{FillOrdering, Timings};
use crate::error::{FemError, Result};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::perm::PermRef;
use faer::sparse::linalg::cholesky::{factorize_symbolic_cholesky, LltRef, SymbolicCholesky, SymmetricOrdering};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMat};
use faer::{Conj, MatMut, Side};
use nalgebra::Vector3;
use std::time::Instant;

/// A symmetric node-block graph: node `b`'s neighbours are `cols[row_ptr[b]..row_ptr[b + 1]]` (sorted,
/// self included), its 3×3 blocks at `9 × index` of a flat array (row-major, `[9 p + 3 k + i]` =
/// K[(b, k), (a, i)] for the neighbour a at index p); `free_of_node` numbers the free nodes
/// (`usize::MAX` = prescribed).
pub(crate) struct NodeGraph<'a> {
    pub row_ptr: &'a [usize],
    pub cols: &'a [usize],
    pub points: &'a [Vector3<f64>],
    pub free_of_node: &'a [usize],
    pub n_free: usize,
}

/// Numeric Cholesky factor values of a [`DirectSystem`]'s symbolic factorisation.
pub(crate) struct Factor(Vec<f64>);

/// Free-DOF sparse structure (upper triangle, CSC) of a [`NodeGraph`] and its symbolic Cholesky.
pub(crate) struct DirectSystem {
    pub n: usize,
    symbolic: SymbolicSparseColMat<usize>,
    /// For each CSC value: index into the flat block array.
    pub src: Vec<usize>,
    /// CSC value index of each diagonal entry.
    pub diag: Vec<usize>,
    chol: SymbolicCholesky<usize>,
}

impl DirectSystem {
    pub fn new(g: &NodeGraph, ordering: FillOrdering) -> Result<Self> {
        let n = 3 * g.n_free;
        if n == 0 {
            return Err(FemError::bad("fixed nodes", "every node is prescribed: nothing to solve"));
        }
        let mut col_ptr = Vec::with_capacity(n + 1);
        let mut row_idx = Vec::new();
        let mut src = Vec::new();
        let mut diag = Vec::with_capacity(n);
        col_ptr.push(0usize);
        for b in 0..g.free_of_node.len() {
            let fb = g.free_of_node[b];
            if fb == usize::MAX {
                continue;
            }
            for k in 0..3 {
                let col = 3 * fb + k;
                for pidx in g.row_ptr[b]..g.row_ptr[b + 1] {
                    let fa = g.free_of_node[g.cols[pidx]];
                    if fa == usize::MAX || fa > fb {
                        continue;
                    }
                    for i in 0..3 {
                        let row = 3 * fa + i;
                        if row > col {
                            continue;
                        }
                        if row == col {
                            diag.push(row_idx.len());
                        }
                        row_idx.push(row);
                        // K[(a,i),(b,k)] = K[(b,k),(a,i)] = block(b,a)[k][i]
                        src.push(9 * pidx + 3 * k + i);
                    }
                }
                col_ptr.push(row_idx.len());
            }
        }
        let symbolic = SymbolicSparseColMat::new_checked(n, n, col_ptr, None, row_idx);
        let perm = match ordering {
            FillOrdering::Amd => None,
            FillOrdering::NestedDissection => Some(Self::nested_dissection(g)),
        };
        let ord = match &perm {
            None => SymmetricOrdering::Amd,
            Some((fwd, inv)) => SymmetricOrdering::Custom(PermRef::new_checked(fwd, inv, n)),
        };
        let chol = factorize_symbolic_cholesky(symbolic.as_ref(), Side::Upper, ord, Default::default())
            .map_err(|e| FemError::Solver(format!("symbolic Cholesky of the {n}-DOF tangent: {e:?}")))?;
        Ok(Self { n, symbolic, src, diag, chol })
    }

    /// DOF permutation (forward: new → old, inverse) from the nested dissection of the free nodes.
    fn nested_dissection(g: &NodeGraph) -> (Vec<usize>, Vec<usize>) {
        let nf = g.n_free;
        let mut points = vec![[0.0; 3]; nf];
        let (mut row_ptr, mut cols) = (Vec::with_capacity(nf + 1), Vec::new());
        let mut node_of_free = vec![0; nf];
        for (b, &f) in g.free_of_node.iter().enumerate() {
            if f != usize::MAX {
                node_of_free[f] = b;
            }
        }
        row_ptr.push(0);
        for &b in &node_of_free {
            let x = g.points[b];
            points[g.free_of_node[b]] = [x.x, x.y, x.z];
            cols.extend(
                g.cols[g.row_ptr[b]..g.row_ptr[b + 1]].iter().map(|&a| g.free_of_node[a]).filter(|&f| f != usize::MAX),
            );
            row_ptr.push(cols.len());
        }
        let leaf = 2000; // AMD below this many nodes (500–8,000 measured within 8 % of each other at 12 mm)
        let order = super::ordering::nested_dissection(&points, &row_ptr, &cols, leaf);
        let fwd: Vec<usize> = order.iter().flat_map(|&f| [3 * f, 3 * f + 1, 3 * f + 2]).collect();
        let mut inv = vec![0; fwd.len()];
        for (new, &old) in fwd.iter().enumerate() {
            inv[old] = new;
        }
        (fwd, inv)
    }

    /// Nonzeros of the Cholesky factor.
    pub fn factor_nnz(&self) -> usize {
        self.chol.len_val()
    }

    /// x ← K⁻¹ x with a factor of K.
    pub fn solve_in_place(&self, f: &Factor, x: &mut [f64]) {
        let par = faer::get_global_parallelism();
        let mut mem = MemBuffer::new(self.chol.solve_in_place_scratch::<f64>(1, par));
        LltRef::new(&self.chol, &f.0).solve_in_place_with_conj(
            Conj::No,
            MatMut::from_column_major_slice_mut(x, self.n, 1),
            par,
            MemStack::new(&mut mem),
        );
    }

    /// Upper-CSC values gathered from a flat block array of the graph.
    pub fn values(&self, blocks: &[f64]) -> Vec<f64> {
        self.src.iter().map(|&s| blocks[s]).collect()
    }

    /// Cholesky factor of K; a diagonal shift grows until it succeeds when K is not positive
    /// definite. Returns the factor and whether a shift was needed.
    pub fn factor(&self, vals: &mut [f64], timings: &mut Timings) -> Result<(Factor, bool)> {
        let par = faer::get_global_parallelism();
        let mut mem = MemBuffer::try_new(self.chol.factorize_numeric_llt_scratch::<f64>(par, Default::default()))
            .map_err(|_| FemError::Solver(format!("out of memory for the Cholesky of the {}-DOF tangent", self.n)))?;
        let mut values = Vec::new();
        values.try_reserve_exact(self.chol.len_val()).map_err(|_| {
            FemError::Solver(format!("out of memory: the Cholesky factor has {} nonzeros", self.chol.len_val()))
        })?;
        values.resize(self.chol.len_val(), 0.0);
        let mut shift = 0.0;
        let dmax = self.diag.iter().map(|&d| vals[d].abs()).fold(0.0, f64::max).max(1e-300);
        let base: Vec<f64> = self.diag.iter().map(|&d| vals[d]).collect();
        for attempt in 0..40 {
            if attempt > 0 {
                shift = if shift == 0.0 { 1e-8 * dmax } else { shift * 10.0 };
                for (&d, &b) in self.diag.iter().zip(&base) {
                    vals[d] = b + shift;
                }
            }
            let t0 = Instant::now();
            let mat = SparseColMatRef::new(self.symbolic.as_ref(), &*vals);
            let ok = self
                .chol
                .factorize_numeric_llt::<f64>(
                    &mut values,
                    mat,
                    Side::Upper,
                    Default::default(),
                    par,
                    MemStack::new(&mut mem),
                    Default::default(),
                )
                .is_ok();
            timings.factorization_s += t0.elapsed().as_secs_f64();
            timings.factorizations += 1;
            if ok {
                return Ok((Factor(values), attempt > 0));
            }
            if shift > 1e3 * dmax {
                break;
            }
        }
        Err(FemError::Solver("the tangent stays singular even with a large diagonal shift".into()))
    }

    /// y = K x for the symmetric K stored as its upper triangle.
    pub fn product(&self, vals: &[f64], x: &[f64], y: &mut [f64]) {
        y.iter_mut().for_each(|v| *v = 0.0);
        let cp = self.symbolic.col_ptr();
        let ri = self.symbolic.row_idx();
        for j in 0..self.n {
            let xj = x[j];
            let mut acc = 0.0;
            for k in cp[j]..cp[j + 1] {
                let i = ri[k];
                let v = vals[k];
                if i == j {
                    acc += v * xj;
                } else {
                    y[i] += v * xj;
                    acc += v * x[i];
                }
            }
            y[j] += acc;
        }
    }

    /// Solve K x = rhs to ‖K x − rhs‖ ≤ max(`forcing` ‖rhs‖, `abs_tol`): conjugate gradients
    /// preconditioned by the factor in `reuse` when there is one; otherwise, or when that fails, a
    /// fresh factorisation, which is kept in `reuse` when it needed no shift. Returns whether a shift
    /// was needed.
    pub fn solve_reusing(
        &self,
        vals: &mut [f64],
        rhs: &mut [f64],
        abs_tol: f64,
        (forcing, max_iterations): (f64, usize),
        reuse: &mut Option<Factor>,
        timings: &mut Timings,
    ) -> Result<bool> {
        if let (Some(m), true) = (reuse.as_ref(), max_iterations > 0) {
            let t0 = Instant::now();
            let target = (forcing * norm(rhs)).max(abs_tol);
            let before = timings.pcg_iterations;
            let out = pcg(
                rhs,
                |x, y| self.product(vals, x, y),
                |r| {
                    let mut z = r.to_vec();
                    self.solve_in_place(m, &mut z);
                    z
                },
                target,
                max_iterations,
                &mut timings.pcg_iterations,
            );
            timings.solve_s += t0.elapsed().as_secs_f64();
            if let PcgEnd::Converged(x) = out {
                rhs.copy_from_slice(&x);
                // a slow solve means the tangent has drifted from the factor: refresh it next time
                if timings.pcg_iterations - before > max_iterations / 3 {
                    *reuse = None;
                }
                return Ok(false);
            }
        }
        let (llt, shifted) = self.factor(vals, timings)?;
        let t1 = Instant::now();
        self.solve_in_place(&llt, rhs);
        timings.solve_s += t1.elapsed().as_secs_f64();
        *reuse = if shifted { None } else { Some(llt) };
        Ok(shifted)
    }
}

/// How [`pcg`] ended.
pub(crate) enum PcgEnd {
    /// ‖b − K x‖ ≤ target.
    Converged(Vec<f64>),
    /// The iteration limit: the last iterate and its residual norm (for SPD K a descent direction).
    IterationLimit(Vec<f64>, f64),
    /// pᵀ K p ≤ 0 (K or the preconditioner is not positive definite) or NaN.
    NonPositiveCurvature,
}

/// Preconditioned conjugate gradients from x = 0 for K x = b (`product`: y ← K x; `precondition`:
/// r ↦ M⁻¹ r, symmetric positive definite) until ‖b − K x‖ ≤ `target`. Each iteration adds one to
/// `iterations`.
pub(crate) fn pcg(
    b: &[f64],
    product: impl Fn(&[f64], &mut [f64]),
    precondition: impl Fn(&[f64]) -> Vec<f64>,
    target: f64,
    max_iterations: usize,
    iterations: &mut usize,
) -> PcgEnd {
    let n = b.len();
    let mut x = vec![0.0; n];
    let mut r = b.to_vec();
    if norm(&r) <= target {
        return PcgEnd::Converged(x);
    }
    let mut z = precondition(&r);
    let mut p = z.clone();
    let mut rz = dot(&r, &z);
    let mut q = vec![0.0; n];
    for _ in 0..max_iterations {
        *iterations += 1;
        product(&p, &mut q);
        let pq = dot(&p, &q);
        let positive_curvature = pq > 0.0 && rz > 0.0; // false for NaN too
        if !positive_curvature {
            return PcgEnd::NonPositiveCurvature;
        }
        let alpha = rz / pq;
        for i in 0..n {
            x[i] += alpha * p[i];
            r[i] -= alpha * q[i];
        }
        let rn = norm(&r);
        if rn <= target {
            return PcgEnd::Converged(x);
        }
        if !rn.is_finite() {
            return PcgEnd::NonPositiveCurvature;
        }
        z = precondition(&r);
        let rz_new = dot(&r, &z);
        let beta = rz_new / rz;
        rz = rz_new;
        for i in 0..n {
            p[i] = z[i] + beta * p[i];
        }
    }
    let rn = norm(&r);
    PcgEnd::IterationLimit(x, rn)
}

pub(crate) fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

pub(crate) fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}
