//! One mesh topology of the CPC system: its lower-triangle sparsity pattern, the symbolic
//! supernodal Cholesky factorisation (faer) in the nested-dissection order of
//! [`crate::ordering`], and the numeric factorisation + solve of one λ ([`CpcTopology`]). The
//! assembly of values and the λ loop are in [`crate::solve`].
use crate::dd::DomainSplit;
use crate::error::{CpcError, Result};
use crate::factor_buffers::{FactorBuffers, FactorPool};
use crate::mesh::CpcMesh;
use crate::ordering::{nested_dissection_split, ND_LEAF};
use faer::dyn_stack::MemStack;
use faer::perm::PermRef;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, SymbolicCholesky, SymmetricOrdering,
};
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{c64, Conj, MatMut, Par, Side};
use rayon::prelude::*;
use std::sync::{Arc, Mutex, OnceLock};

/// The pattern and symbolic Cholesky factorisation of one mesh topology (faces, grid positions and
/// step), shared by every [`CpcSystem`] built on it. Build it once per ROI / mesh topology and
/// reuse it across the frames of a video through [`CpcSolver`].
///
/// The normal matrix is stored as a complex Hermitian n × n matrix (one unknown z_v = x_v + i y_v
/// per vertex; see [`CpcSystem`]), lower triangle only, in the original vertex order; the
/// fill-reducing ordering is the geometric nested dissection of the grid.
pub struct CpcTopology {
    n: usize,
    grid_step_px: usize,
    pub(crate) faces: Vec<[usize; 3]>,
    pub(crate) p_init: Vec<[f64; 2]>,
    pub(crate) col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    /// Per face, position in the value array of the entry (row f[r], column f[c]) at index 3r + c,
    /// or `u32::MAX` when that entry lies in the (unstored) upper triangle.
    pub(crate) face_pos: Vec<[u32; 9]>,
    /// Symbolic factorisation of the whole system (built on first use when the system is split).
    symbolic: OnceLock<SymbolicCholesky<usize>>,
    /// Nested-dissection ordering (forward and inverse).
    fwd: Vec<usize>,
    inv: Vec<usize>,
    /// Numeric factor values and workspace, reused by consecutive solves.
    scratch: Mutex<Option<FactorBuffers>>,
    /// Two-domain split of the top nested-dissection level (factorised on two threads), if any.
    split: Option<DomainSplit>,
    /// Pool of the [`crate::CpcSolver`] that built this topology (buffers are taken from it and
    /// returned to it on drop); `None` for a stand-alone topology.
    pool: Option<Arc<FactorPool>>,
}

impl Drop for CpcTopology {
    fn drop(&mut self) {
        if let (Some(pool), Some(b)) = (&self.pool, self.scratch.get_mut().ok().and_then(Option::take)) {
            pool.give_back(b);
        }
    }
}

impl CpcTopology {
    /// Analyse the sparsity pattern of `mesh` (adjacency, nested-dissection ordering, symbolic Cholesky).
    pub fn new(mesh: &CpcMesh) -> Result<CpcTopology> {
        CpcTopology::with_pool(mesh, None)
    }

    /// [`new`](Self::new), taking and returning factor buffers from `pool`.
    pub(crate) fn with_pool(mesh: &CpcMesh, pool: Option<Arc<FactorPool>>) -> Result<CpcTopology> {
        let n = mesh.n_vertices();
        if n == 0 || mesh.faces.is_empty() {
            return Err(CpcError::invalid("mesh", "has no triangle"));
        }
        let ((col_ptr, row_idx, face_pos), (fwd, top)) = rayon::join(
            || lower_pattern(n, &mesh.faces),
            || nested_dissection_split(&mesh.p_init, mesh.grid_step_px, ND_LEAF),
        );
        let mut inv = vec![0usize; n];
        for (k, &o) in fwd.iter().enumerate() {
            inv[o] = k;
        }
        let split = top.and_then(|(n1, n2)| DomainSplit::new(&col_ptr, &row_idx, &fwd, n1, n2, pool.clone()));
        let symbolic = OnceLock::new();
        // Without a split, the whole-system analysis now (its errors surface at assembly);
        // with one, on first use (a fallback or `set_domain_split(false)`).
        if split.is_none() {
            let _ = symbolic.set(whole_symbolic(&col_ptr, &row_idx, &fwd, &inv)?);
        }
        Ok(CpcTopology {
            n,
            grid_step_px: mesh.grid_step_px,
            faces: mesh.faces.clone(),
            p_init: mesh.p_init.clone(),
            col_ptr,
            row_idx,
            face_pos,
            symbolic,
            fwd,
            inv,
            scratch: Mutex::new(None),
            split,
            pool,
        })
    }

    /// The whole-system symbolic factorisation (built on first use).
    fn whole(&self) -> Result<&SymbolicCholesky<usize>> {
        if let Some(s) = self.symbolic.get() {
            return Ok(s);
        }
        let s = whole_symbolic(&self.col_ptr, &self.row_idx, &self.fwd, &self.inv)?;
        Ok(self.symbolic.get_or_init(|| s))
    }

    /// Whether `mesh` has this topology (same grid step, vertex positions and faces).
    pub fn matches(&self, mesh: &CpcMesh) -> bool {
        self.grid_step_px == mesh.grid_step_px && self.faces == mesh.faces && self.p_init == mesh.p_init
    }

    /// Number of stored (lower-triangle) entries of the complex normal matrix.
    pub fn nnz_lower(&self) -> usize {
        self.row_idx.len()
    }

    /// Whether the system is factorised as two halves and a separator on two threads (the top
    /// nested-dissection level; systems of at least [`crate::solve::MIN_SPLIT_VERTICES`] vertices).
    pub fn is_split(&self) -> bool {
        self.split.is_some()
    }

    /// Number of (complex) entries of the Cholesky factor.
    pub fn factor_len(&self) -> usize {
        self.whole().map_or(0, |s| s.len_val())
    }

    /// Multiply–add count of the numeric factorisation of the whole system, Σ_j c_j² over the
    /// factor's column counts c_j (a machine-independent cost measure of an ordering).
    pub fn factor_flops(&self) -> f64 {
        use faer::sparse::linalg::cholesky::SymbolicCholeskyRaw;
        let Ok(sym) = self.whole() else { return 0.0 };
        match sym.raw() {
            SymbolicCholeskyRaw::Supernodal(s) => (0..s.n_supernodes())
                .map(|i| {
                    let (b, e) = (s.supernode_begin()[i], s.supernode_end()[i]);
                    let (c, r) = ((e - b) as f64, s.supernode(i).pattern().len() as f64);
                    (0..c as usize).map(|j| (c - j as f64 + r).powi(2)).sum::<f64>()
                })
                .sum(),
            SymbolicCholeskyRaw::Simplicial(_) => 0.0,
        }
    }

    /// Factorise the Hermitian matrix with lower-triangle values `vals` and solve for `rhs` in place.
    pub(crate) fn factor_solve(&self, vals: &[c64], rhs: &mut [c64], threads: usize, split: bool) -> Result<()> {
        let n = self.n;
        let sym = SymbolicSparseColMatRef::new_checked(n, n, &self.col_ptr, None, &self.row_idx);
        let mat = SparseColMatRef::new(sym, vals);
        // Sequential by default: on the shared, loaded 2-core machine faer's rayon path was not
        // faster (see benchmarks/cpc.md). Its result is bitwise identical for any thread count.
        let par = if threads > 1 { Par::rayon(threads) } else { Par::Seq };
        if let (true, Some(dd)) = (split, &self.split) {
            let mut x = vec![c64::new(0.0, 0.0); n];
            // (A failed split factorisation, e.g. a separator Schur complement that is not
            // numerically positive definite, falls back to the whole-system factorisation.)
            if dd.factor_solve(vals, rhs, &mut x, par).is_ok() {
                rhs.copy_from_slice(&x);
                return Ok(());
            }
        }
        let symbolic = self.whole()?;
        // Reuse the factor buffer and workspace unless another solve holds them.
        let mut guard = self.scratch.try_lock().ok();
        let mut local = None;
        let slot: &mut Option<FactorBuffers> = match guard.as_deref_mut() {
            Some(s) => s,
            None => &mut local,
        };
        let sc = slot.get_or_insert_with(|| {
            let req = symbolic
                .factorize_numeric_llt_scratch::<c64>(par, Default::default())
                .or(symbolic.solve_in_place_scratch::<c64>(1, par));
            FactorBuffers::take(self.pool.as_deref(), symbolic.len_val(), req)
        });
        let llt = symbolic
            .factorize_numeric_llt(
                &mut sc.vals,
                mat,
                Side::Lower,
                Default::default(),
                par,
                MemStack::new(&mut sc.mem),
                Default::default(),
            )
            .map_err(|e| CpcError::Solver(format!("Cholesky failed (matrix not positive definite?): {e:?}")))?;
        llt.solve_in_place_with_conj(
            Conj::No,
            MatMut::from_column_major_slice_mut(rhs, n, 1),
            par,
            MemStack::new(&mut sc.mem),
        );
        Ok(())
    }
}

/// The lower-triangle pattern (rows ≥ column, diagonal first in every column, rows sorted) of the
/// vertex adjacency of `faces` over `n` vertices, and per face the value positions of its 3×3 block
/// (entry 3r + c for rows/columns in face order, `u32::MAX` for the unstored upper entries).
fn lower_pattern(n: usize, faces: &[[usize; 3]]) -> (Vec<usize>, Vec<usize>, Vec<[u32; 9]>) {
    // Lower-triangle adjacency (rows ≥ column, including the diagonal), at most 8 per vertex on
    // a triangulated grid (7 in practice); spill to a sorted Vec otherwise.
    let mut nbr = vec![[u32::MAX; 8]; n];
    let mut cnt = vec![0u8; n];
    let mut spill: Vec<(usize, usize)> = Vec::new();
    for v in 0..n {
        nbr[v][0] = v as u32;
        cnt[v] = 1;
    }
    for f in faces {
        for &c in f {
            for &r in f {
                if r <= c {
                    continue;
                }
                let k = cnt[c] as usize;
                if nbr[c][..k].contains(&(r as u32)) {
                    continue;
                }
                if k < 8 {
                    nbr[c][k] = r as u32;
                    cnt[c] += 1;
                } else {
                    spill.push((c, r));
                }
            }
        }
    }
    spill.sort_unstable();
    spill.dedup();
    let mut col_ptr = Vec::with_capacity(n + 1);
    col_ptr.push(0usize);
    let mut row_idx = Vec::with_capacity(4 * n);
    let mut si = 0;
    let mut tmp: Vec<usize> = Vec::with_capacity(16);
    for c in 0..n {
        tmp.clear();
        tmp.extend(nbr[c][..cnt[c] as usize].iter().map(|&r| r as usize));
        while si < spill.len() && spill[si].0 == c {
            if !tmp.contains(&spill[si].1) {
                tmp.push(spill[si].1);
            }
            si += 1;
        }
        tmp.sort_unstable();
        row_idx.extend_from_slice(&tmp);
        col_ptr.push(row_idx.len());
    }
    // Per face, the value positions of its 3×3 block (independent per face: parallel).
    let face_pos: Vec<[u32; 9]> = faces
        .par_iter()
        .with_min_len(2048)
        .map(|f| {
            let mut fp = [u32::MAX; 9];
            for (rl, &r) in f.iter().enumerate() {
                for (cl, &c) in f.iter().enumerate() {
                    if r < c {
                        continue;
                    }
                    let rows = &row_idx[col_ptr[c]..col_ptr[c + 1]];
                    let k = rows.binary_search(&r).expect("adjacency contains every face pair");
                    fp[3 * rl + cl] = (col_ptr[c] + k) as u32;
                }
            }
            fp
        })
        .collect();
    (col_ptr, row_idx, face_pos)
}

/// Symbolic supernodal Cholesky factorisation of the lower pattern (`col_ptr`, `row_idx`) in the
/// nested-dissection order `fwd` (inverse `inv`).
pub(crate) fn whole_symbolic(
    col_ptr: &[usize],
    row_idx: &[usize],
    fwd: &[usize],
    inv: &[usize],
) -> Result<SymbolicCholesky<usize>> {
    let n = fwd.len();
    let sym = SymbolicSparseColMatRef::new_checked(n, n, col_ptr, None, row_idx);
    let perm = PermRef::new_checked(fwd, inv, n);
    // Supernodal always: faer's flop-ratio heuristic picks the simplicial factorisation for
    // this complex system, which is 1.5× slower here (13.3 vs 8.8 ms CPU at 4 px).
    let params = CholeskySymbolicParams {
        supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SUPERNODAL,
        ..Default::default()
    };
    factorize_symbolic_cholesky(sym, Side::Lower, SymmetricOrdering::Custom(perm), params)
        .map_err(|e| CpcError::Solver(format!("{e:?}")))
}
