//! Two-domain split of the complex CPC system for a factorisation on two threads.
//!
//! The top level of the grid nested dissection splits the vertices into two interiors (1, 2) and
//! a separator (3, one grid line) with no coupling between 1 and 2:
//! A = [A11 0 A13; 0 A22 A23; A31 A32 A33]. Each half B_i = [A_ii A_i3; A_3i A33] is factorised
//! on its own (faer supernodal, both halves concurrently): B_i = L_i L_iᴴ with
//! L_i = [L_ii 0; L_3i T_i], T_i T_iᴴ = A33 − L_3i L_3iᴴ. The separator's Schur complement is then
//! Ŝ = A33 − L_31 L_31ᴴ − L_32 L_32ᴴ = T_1 T_1ᴴ + T_2 T_2ᴴ − A33 (dense, one grid line), and
//! A x = b is solved by y_i = L_ii⁻¹ b_i, x_3 = Ŝ⁻¹ (b_3 − L_31 y_1 − L_32 y_2),
//! x_i = L_ii⁻ᴴ (y_i − L_3iᴴ x_3), all through the halves' own triangular solves. Every step has
//! a fixed operation order, so the result does not depend on the number of threads.
use crate::factor_buffers::{FactorBuffers, FactorPool};
use faer::dyn_stack::MemStack;
use faer::linalg::matmul::triangular::{self, BlockStructure};
use faer::linalg::solvers::Solve;
use faer::sparse::linalg::cholesky::supernodal::{SupernodalLltRef, SymbolicSupernodalCholesky};
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, SymbolicCholesky, SymbolicCholeskyRaw, SymmetricOrdering,
};
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{c64, Accum, Conj, Mat, MatMut, Par, Side};
use std::sync::{Arc, Mutex};

/// Smallest system (vertices) split in two.
pub const MIN_SPLIT_VERTICES: usize = 2000;

struct Half {
    /// Interior size n_i (the separator follows, k entries).
    n_int: usize,
    /// Local index → global vertex (interior, then separator).
    glob: Vec<usize>,
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    /// Per local stored value: global value position and whether it is conjugated.
    src: Vec<(u32, bool)>,
    symbolic: SymbolicCholesky<usize>,
    scratch: Mutex<Option<FactorBuffers>>,
    /// The owning solver's buffer pool (see [`crate::factor_buffers`]).
    pool: Option<Arc<FactorPool>>,
}

pub(crate) struct DomainSplit {
    halves: [Half; 2],
    k: usize,
    /// Lower entries of A33 (row, column, global value position, conjugated).
    a33: Vec<(usize, usize, u32, bool)>,
}

impl Drop for Half {
    fn drop(&mut self) {
        if let (Some(pool), Some(b)) = (&self.pool, self.scratch.get_mut().ok().and_then(Option::take)) {
            pool.give_back(b);
        }
    }
}

fn sn(sym: &SymbolicCholesky<usize>) -> &SymbolicSupernodalCholesky<usize> {
    match sym.raw() {
        SymbolicCholeskyRaw::Supernodal(s) => s,
        SymbolicCholeskyRaw::Simplicial(_) => unreachable!("forced supernodal"),
    }
}

impl DomainSplit {
    /// Split for the nested-dissection order `fwd` whose top level is `n1` + `n2` interior vertices
    /// followed by the separator; `None` when it is not a valid split.
    ///
    /// Linear in the number of stored entries: a full (both triangles) adjacency with value
    /// positions is built once, then each half's lower pattern is read off it column by column in
    /// local order (at most a handful of rows per column to sort); the two halves, including
    /// their symbolic factorisations, are analysed concurrently.
    pub(crate) fn new(
        col_ptr: &[usize],
        row_idx: &[usize],
        fwd: &[usize],
        n1: usize,
        n2: usize,
        pool: Option<Arc<FactorPool>>,
    ) -> Option<DomainSplit> {
        let n = fwd.len();
        let k = n - n1 - n2;
        if n < MIN_SPLIT_VERTICES || n1 == 0 || n2 == 0 || k == 0 {
            return None;
        }
        // part: 0, 1 interiors, 2 separator; local index within the half (separator: offset by
        // the half's interior size when used).
        let mut part = vec![0u8; n];
        let mut loc = vec![0u32; n];
        for (p, &v) in fwd.iter().enumerate() {
            let (pt, l) = if p < n1 {
                (0, p)
            } else if p < n1 + n2 {
                (1, p - n1)
            } else {
                (2, p - n1 - n2)
            };
            part[v] = pt;
            loc[v] = l as u32;
        }
        // Full adjacency: for vertex g, (neighbour u, value position of the stored entry,
        // conjugated = the stored entry is (g, u), i.e. A[u, g] = conj(vals[pos])).
        let mut deg = vec![0u32; n + 1];
        for c in 0..n {
            deg[c + 1] += (col_ptr[c + 1] - col_ptr[c]) as u32;
            for &r in &row_idx[col_ptr[c]..col_ptr[c + 1]] {
                if r != c {
                    deg[r + 1] += 1;
                }
            }
        }
        for i in 0..n {
            deg[i + 1] += deg[i];
        }
        let mut fill: Vec<u32> = deg[..n].to_vec();
        let mut adj = vec![(0u32, 0u32, false); deg[n] as usize];
        let mut a33 = Vec::new();
        for c in 0..n {
            for (pos, &r) in row_idx[col_ptr[c]..col_ptr[c + 1]].iter().enumerate().map(|(i, r)| (col_ptr[c] + i, r)) {
                let (pr, pc) = (part[r], part[c]);
                if pr != 2 && pc != 2 && pr != pc {
                    return None; // the interiors are coupled: not a separator
                }
                let pos = pos as u32;
                if pr == 2 && pc == 2 {
                    let (a, b) = (loc[r] as usize, loc[c] as usize);
                    a33.push(if a >= b { (a, b, pos, false) } else { (b, a, pos, true) });
                }
                adj[fill[c] as usize] = (r as u32, pos, false);
                fill[c] += 1;
                if r != c {
                    adj[fill[r] as usize] = (c as u32, pos, true);
                    fill[r] += 1;
                }
            }
        }
        let build_half = |h: usize| -> Option<Half> {
            let n_int = if h == 0 { n1 } else { n2 };
            let m = n_int + k;
            let off = if h == 0 { 0 } else { n1 };
            let mut glob: Vec<usize> = fwd[off..off + n_int].to_vec();
            glob.extend_from_slice(&fwd[n1 + n2..]);
            let local = |u: usize| -> Option<usize> {
                match part[u] {
                    2 => Some(n_int + loc[u] as usize),
                    p if p as usize == h => Some(loc[u] as usize),
                    _ => None,
                }
            };
            let mut cp = Vec::with_capacity(m + 1);
            cp.push(0usize);
            let mut ri = Vec::with_capacity(4 * m);
            let mut src = Vec::with_capacity(4 * m);
            let mut col: Vec<(usize, u32, bool)> = Vec::with_capacity(16);
            for (lc, &g) in glob.iter().enumerate() {
                col.clear();
                for &(u, pos, cj) in &adj[deg[g] as usize..deg[g + 1] as usize] {
                    if let Some(lu) = local(u as usize) {
                        if lu >= lc {
                            col.push((lu, pos, cj));
                        }
                    }
                }
                col.sort_unstable_by_key(|e| e.0);
                ri.extend(col.iter().map(|e| e.0));
                src.extend(col.iter().map(|e| (e.1, e.2)));
                cp.push(ri.len());
            }
            // The half is already in elimination order: faer's `Identity` ordering, whose symbolic
            // analysis reads the upper pattern (the transpose of the stored lower one). The numeric
            // factorisation then takes the lower values as they are (no permuted copy per solve).
            let mut cpu = vec![0usize; m + 1];
            for &r in &ri {
                cpu[r + 1] += 1;
            }
            for i in 0..m {
                cpu[i + 1] += cpu[i];
            }
            let mut riu = vec![0usize; ri.len()];
            let mut next = cpu[..m].to_vec();
            for c in 0..m {
                for &r in &ri[cp[c]..cp[c + 1]] {
                    riu[next[r]] = c;
                    next[r] += 1;
                }
            }
            let sym = SymbolicSparseColMatRef::new_checked(m, m, &cpu, None, &riu);
            let params = CholeskySymbolicParams {
                supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SUPERNODAL,
                ..Default::default()
            };
            let symbolic = factorize_symbolic_cholesky(sym, Side::Upper, SymmetricOrdering::Identity, params).ok()?;
            if !matches!(symbolic.raw(), SymbolicCholeskyRaw::Supernodal(_)) {
                return None;
            }
            Some(Half {
                n_int,
                glob,
                col_ptr: cp,
                row_idx: ri,
                src,
                symbolic,
                scratch: Mutex::new(None),
                pool: pool.clone(),
            })
        };
        let (h0, h1) = rayon::join(|| build_half(0), || build_half(1));
        Some(DomainSplit { halves: [h0?, h1?], k, a33 })
    }

    /// Factorise the Hermitian matrix with (global, lower) values `vals` and solve for `rhs` into
    /// `x` (same length). Err(message) when a factorisation fails (`x` is then unspecified).
    pub(crate) fn factor_solve(&self, vals: &[c64], rhs: &[c64], x: &mut [c64], par: Par) -> Result<(), String> {
        let k = self.k;
        let rhs_in = |g: usize| rhs[g];
        // Per half: factor, trailing block T_i, T_i T_iᴴ, y_i and L_3i y_i.
        struct HalfOut {
            b: FactorBuffers,
            t: Mat<c64>,
            tt: Mat<c64>,
            y: Vec<c64>,
            w: Vec<c64>,
        }
        let run_half = |h: &Half| -> Result<HalfOut, String> {
            let m = h.n_int + k;
            let sym = SymbolicSparseColMatRef::new_checked(m, m, &h.col_ptr, None, &h.row_idx);
            let v: Vec<c64> =
                h.src.iter().map(|&(p, cj)| if cj { vals[p as usize].conj() } else { vals[p as usize] }).collect();
            let mat = SparseColMatRef::new(sym, &v[..]);
            let mut b = h.scratch.lock().ok().and_then(|mut g| g.take()).unwrap_or_else(|| {
                let req = h
                    .symbolic
                    .factorize_numeric_llt_scratch::<c64>(par, Default::default())
                    .or(h.symbolic.solve_in_place_scratch::<c64>(1, par));
                FactorBuffers::take(h.pool.as_deref(), h.symbolic.len_val(), req)
            });
            h.symbolic
                .factorize_numeric_llt(
                    &mut b.vals,
                    mat,
                    Side::Lower,
                    Default::default(),
                    par,
                    MemStack::new(&mut b.mem),
                    Default::default(),
                )
                .map_err(|e| format!("Cholesky failed (matrix not positive definite?): {e:?}"))?;
            let s = sn(&h.symbolic);
            let llt = SupernodalLltRef::new(s, &b.vals);
            // Trailing k × k block T (separator columns, lower triangular).
            let mut t = Mat::<c64>::zeros(k, k);
            let ni = h.n_int;
            for si in 0..s.n_supernodes() {
                let sup = llt.supernode(si);
                let (start, val) = (sup.start(), sup.val());
                let nc = val.ncols();
                if start + nc <= ni {
                    continue;
                }
                for jj in start.max(ni)..start + nc {
                    let cj = jj - start;
                    for ii in jj..start + nc {
                        t[(ii - ni, jj - ni)] = val[(ii - start, cj)];
                    }
                    for (idx, &p) in sup.pattern().iter().enumerate() {
                        t[(p - ni, jj - ni)] = val[(nc + idx, cj)];
                    }
                }
            }
            let mut tt = Mat::<c64>::zeros(k, k);
            // Lower triangle of T Tᴴ (T lower triangular).
            triangular::matmul(
                tt.as_mut(),
                BlockStructure::TriangularLower,
                Accum::Replace,
                t.as_ref(),
                BlockStructure::TriangularLower,
                t.adjoint(),
                BlockStructure::TriangularUpper,
                c64::new(1.0, 0.0),
                Par::Seq,
            );
            // y = L_ii⁻¹ b_i; the separator part is u = T⁻¹ (0 − L_3i y), so L_3i y = −T u.
            let mut y: Vec<c64> = h.glob.iter().take(ni).map(|&g| rhs_in(g)).collect();
            y.resize(m, c64::new(0.0, 0.0));
            llt.l_solve_with_conj(
                Conj::No,
                MatMut::from_column_major_slice_mut(&mut y, m, 1),
                par,
                MemStack::new(&mut b.mem),
            );
            let mut w = vec![c64::new(0.0, 0.0); k];
            for j in 0..k {
                let uj = y[ni + j];
                for (i, wi) in w.iter_mut().enumerate().skip(j) {
                    *wi -= t[(i, j)] * uj;
                }
            }
            Ok(HalfOut { b, t, tt, y, w })
        };
        let (o0, o1) = rayon::join(|| run_half(&self.halves[0]), || run_half(&self.halves[1]));
        let (mut o0, mut o1) = (o0?, o1?);
        // Ŝ = T1 T1ᴴ + T2 T2ᴴ − A33 (lower triangle).
        let mut s = Mat::<c64>::zeros(k, k);
        for j in 0..k {
            for i in j..k {
                s[(i, j)] = o0.tt[(i, j)] + o1.tt[(i, j)];
            }
        }
        for &(a, b, p, cj) in &self.a33 {
            s[(a, b)] -= if cj { vals[p as usize].conj() } else { vals[p as usize] };
        }
        let sep_glob = &self.halves[0].glob[self.halves[0].n_int..];
        let mut x3 = Mat::<c64>::zeros(k, 1);
        for (j, &g) in sep_glob.iter().enumerate() {
            x3[(j, 0)] = rhs[g] - o0.w[j] - o1.w[j];
        }
        let sl = s.llt(Side::Lower).map_err(|e| format!("separator Cholesky failed: {e:?}"))?;
        let x3 = sl.solve(&x3);
        let back = |h: &Half, o: &mut HalfOut| {
            let (ni, m) = (h.n_int, h.n_int + k);
            // Separator part v = Tᴴ x3, so that the transposed solve subtracts L_3iᴴ x3.
            for j in 0..k {
                let mut acc = c64::new(0.0, 0.0);
                for i in j..k {
                    acc += o.t[(i, j)].conj() * x3[(i, 0)];
                }
                o.y[ni + j] = acc;
            }
            let llt = SupernodalLltRef::new(sn(&h.symbolic), &o.b.vals);
            llt.l_transpose_solve_with_conj(
                Conj::Yes,
                MatMut::from_column_major_slice_mut(&mut o.y, m, 1),
                par,
                MemStack::new(&mut o.b.mem),
            );
        };
        rayon::join(|| back(&self.halves[0], &mut o0), || back(&self.halves[1], &mut o1));
        for (h, o) in self.halves.iter().zip([o0, o1]) {
            for (&g, &v) in h.glob.iter().zip(&o.y).take(h.n_int) {
                x[g] = v;
            }
            if let Ok(mut g) = h.scratch.try_lock() {
                *g = Some(o.b);
            }
        }
        for (j, &g) in sep_glob.iter().enumerate() {
            x[g] = x3[(j, 0)];
        }
        Ok(())
    }
}
