//! The convex least-displacement CPC solve (thesis §4.4.5, eqs. 4.11/4.12):
//!
//! ```text
//! C(p) = λ · Σ_t A_t |M_t p_t|² / |P_b − P_a|²  +  (1 − λ) · Σ_v a_v |p_v − P_v|² / L²     (÷ A_tot)
//! ```
//!
//! Both terms are weighted per unit of image area so that λ means the same at every grid step:
//! A_t is the initial image area of triangle t, a_v = Σ_{t∋v} A_t / 3 the area of vertex v,
//! |M_t p_t| / |P_b − P_a| the relative (dimensionless) conformal defect of t, A_tot the mesh area
//! and L = [`DISPLACEMENT_SCALE`]·√A_tot the length displacements are measured in (10 % of the
//! ROI size). The cost is thus λ·mean(defect²) + (1−λ)·mean((d/L)²), independent of the grid step
//! and of the image resolution (the thesis' plain sums over triangles and vertices change their
//! balance by s² when the grid step s changes). The factor 0.1 places the transition of
//! δ_area(λ) in the middle of [0, 1) (λ ≈ 0.5–0.95) as in the thesis' Fig. 4.11/4.12.
//!
//! The normal equations (λ K + (1−λ) D) p = (1−λ) D P_init (K = Σ w_t M_tᵀM_t, D diagonal) are
//! solved in their equivalent complex Hermitian form (one unknown z = x + i y per vertex, see
//! [`CpcSystem`]), assembled once per mesh on one lower-triangle sparsity pattern; the symbolic
//! sparse Cholesky (faer, supernodal) is computed once per mesh topology ([`CpcTopology`], reusable
//! across video frames through [`CpcSolver`]), with a geometric nested-dissection ordering of the
//! grid (grid lines are vertex separators of the triangulated grid, so the ordering costs
//! O(n log n) and avoids AMD), and every λ costs one numeric factorisation and two triangular
//! solves. The system is block-diagonal over connected components, so one factorisation solves
//! every component separately.
use crate::conformal::{triangle_rows, triangle_rows_cs, ConformalParams, RowConvention};
use crate::dd::DomainSplit;
use crate::error::{CpcError, Result};
use crate::factor_buffers::FactorBuffers;
use crate::mesh::{signed_area, CpcMesh};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::perm::PermRef;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, SymbolicCholesky, SymmetricOrdering,
};
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{c64, Conj, MatMut, Par, Side};
use rayon::prelude::*;
use std::sync::{Arc, Mutex, OnceLock};

/// Parts of at most this many vertices are left undivided by the nested dissection (measured with
/// the stable partitions, 4 px, second solve on a new topology: leaf 4 4.20 ms, 8 3.84–4.01,
/// 16 3.67–3.70, 24 3.68–3.79, 32 3.79–3.89, 48 4.00–4.04 ms: larger leaves add a little fill
/// but give faer larger supernodes).
pub const ND_LEAF: usize = 16;

/// Displacements are measured in units of this fraction of √(mesh area).
pub const DISPLACEMENT_SCALE: f64 = 0.1;

/// Check λ ∈ [0, 1) (λ = 1 makes the system singular: any similarity, including the collapsed
/// solution, is a minimiser).
pub fn validate_lambda(lambda: f64) -> Result<()> {
    if !(lambda.is_finite() && (0.0..1.0).contains(&lambda)) {
        return Err(CpcError::invalid("lambda", format!("{lambda} (must be in [0, 1))")));
    }
    Ok(())
}

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
    faces: Vec<[usize; 3]>,
    p_init: Vec<[f64; 2]>,
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    /// Per face, position in the value array of the entry (row f[r], column f[c]) at index 3r + c,
    /// or `u32::MAX` when that entry lies in the (unstored) upper triangle.
    face_pos: Vec<[u32; 9]>,
    /// Symbolic factorisation of the whole system (built on first use when the system is split).
    symbolic: OnceLock<SymbolicCholesky<usize>>,
    /// Nested-dissection ordering (forward and inverse).
    fwd: Vec<usize>,
    inv: Vec<usize>,
    /// Numeric factor values and workspace, reused by consecutive solves.
    scratch: Mutex<Option<FactorBuffers>>,
    /// Two-domain split of the top nested-dissection level (factorised on two threads), if any.
    split: Option<DomainSplit>,
}

impl Drop for CpcTopology {
    fn drop(&mut self) {
        if let Some(b) = self.scratch.get_mut().ok().and_then(Option::take) {
            b.give_back();
        }
    }
}

impl CpcTopology {
    /// Analyse the sparsity pattern of `mesh` (adjacency, nested-dissection ordering, symbolic Cholesky).
    pub fn new(mesh: &CpcMesh) -> Result<CpcTopology> {
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
        let split = top.and_then(|(n1, n2)| DomainSplit::new(&col_ptr, &row_idx, &fwd, n1, n2));
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
    /// nested-dissection level; systems of at least [`crate::dd::MIN_SPLIT_VERTICES`] vertices).
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
    fn factor_solve(&self, vals: &[c64], rhs: &mut [c64], threads: usize, split: bool) -> Result<()> {
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
            FactorBuffers::take(symbolic.len_val(), req)
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
fn whole_symbolic(
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

/// Per-face M_t and w_t, per-vertex displacement weights, and the time taken (ms).
type FaceTerms = (Vec<[[f64; 6]; 2]>, Vec<f64>, Vec<f64>, f64);

/// Reusable CPC solver state for a video: keeps the [`CpcTopology`] of the last mesh and reuses it
/// (sparsity pattern, ordering, symbolic factorisation, factor buffers) when the next frame's mesh
/// has the same topology, e.g. a fixed ROI and the same valid-depth triangles.
#[derive(Default)]
pub struct CpcSolver {
    topo: Option<Arc<CpcTopology>>,
    factor_threads: usize,
}

impl CpcSolver {
    /// A solver with no cached topology.
    pub fn new() -> CpcSolver {
        CpcSolver::default()
    }

    /// Assemble the system of `mesh`, reusing the cached topology when it matches
    /// ([`CpcSystem::topology_reused`] tells which).
    pub fn assemble(&mut self, mesh: &CpcMesh, params: &ConformalParams) -> Result<CpcSystem> {
        let cached = self.topo.as_ref().filter(|t| t.matches(mesh)).cloned();
        let mut sys = CpcSystem::assemble_with(mesh, params, cached)?;
        sys.set_factor_threads(self.factor_threads);
        self.topo = Some(sys.topo.clone());
        Ok(sys)
    }

    /// Threads of the numeric Cholesky factorisation of the systems it assembles (≤ 1:
    /// sequential, the default). The result does not depend on it.
    pub fn set_factor_threads(&mut self, threads: usize) {
        self.factor_threads = threads;
    }

    /// Forget the cached topology.
    pub fn clear(&mut self) {
        self.topo = None;
    }
}

/// The assembled CPC system of one mesh, ready to be solved for any λ.
///
/// With the derived rows of M_t (the default), the two rows of every triangle are
/// r0 = Σ_j A_j x_j + B_j y_j and r1 = Σ_j B_j x_j − A_j y_j, so r0 − i r1 = Σ_j g_j z_j with
/// g_j = A_j − i B_j and z_j = x_j + i y_j: |M_t p_t|² = |g_tᵀ z_t|². The normal equations are
/// then the complex Hermitian positive-definite system (λ H + (1−λ) D) z = (1−λ) D P_init with
/// H = Σ_t w_t conj(g_t) g_tᵀ — half the unknowns of the real interleaved system and about half
/// its factorisation flops, with the same solution. The real interleaved form (needed by the
/// equiareal refinement and by [`RowConvention::AsPrinted`], whose rows lack this structure) is
/// built on first use.
pub struct CpcSystem {
    n_vertices: usize,
    /// Displacement weight a_v / (L² A_tot) of every vertex.
    disp_w: Vec<f64>,
    /// M_t of every triangle and its weight w_t = A_t / (|P_b − P_a|² A_tot).
    tri_rows: Vec<[[f64; 6]; 2]>,
    tri_w: Vec<f64>,
    grid_step_px: usize,
    topo: Arc<CpcTopology>,
    /// λ-free Hermitian conformal matrix H on the topology's lower-triangle pattern (`None` when
    /// the rows of M_t lack the complex structure).
    herm_vals: Option<Vec<c64>>,
    real: OnceLock<std::result::Result<RealSystem, String>>,
    /// Assembly timings (ms): [weights and M_t, H values, topology (pattern, ordering, symbolic
    /// Cholesky; 0 when reused)]; for a new topology the first and last run concurrently.
    pub assembly_ms: [f64; 3],
    /// Whether the topology (pattern, ordering, symbolic factorisation) came from a [`CpcSolver`] cache.
    pub topology_reused: bool,
    factor_threads: usize,
    domain_split: bool,
}

/// The real interleaved system [x_0, y_0, x_1, y_1, ...] (built on demand).
struct RealSystem {
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    conf_vals: Vec<f64>,
    diag_pos: Vec<usize>,
    symbolic: SymbolicCholesky<usize>,
}

impl CpcSystem {
    /// Assemble the conformal and displacement terms of `mesh` and analyse the sparsity pattern.
    pub fn assemble(mesh: &CpcMesh, params: &ConformalParams) -> Result<CpcSystem> {
        CpcSystem::assemble_with(mesh, params, None)
    }

    fn assemble_with(mesh: &CpcMesh, params: &ConformalParams, topo: Option<Arc<CpcTopology>>) -> Result<CpcSystem> {
        let th = params.theta_rad;
        if !(th.is_finite() && th > 0.0 && th < std::f64::consts::PI) {
            return Err(CpcError::invalid("theta", format!("{th} rad (must be in (0, π))")));
        }
        let n = mesh.n_vertices();
        let m = mesh.n_triangles();
        if m == 0 {
            return Err(CpcError::invalid("mesh", "has no triangle"));
        }
        // Image area A_t of every face, their sum A_tot and the displacement weight
        // a_v / (L² A_tot) of every vertex (sums in face order); an error for a face of
        // non-positive area.
        let area_weights = |mesh: &CpcMesh| -> Result<(Vec<f64>, f64, Vec<f64>)> {
            let mut area = vec![0.0; mesh.faces.len()];
            let mut a_tot = 0.0;
            for (t, f) in mesh.faces.iter().enumerate() {
                let a = signed_area(mesh.p_init[f[0]], mesh.p_init[f[1]], mesh.p_init[f[2]]);
                if a.is_nan() || a <= 0.0 {
                    return Err(CpcError::invalid("mesh", format!("triangle {t} has non-positive image area {a}")));
                }
                area[t] = a;
                a_tot += a;
            }
            let l2 = DISPLACEMENT_SCALE * DISPLACEMENT_SCALE * a_tot; // L²
            let mut disp_w = vec![0.0; mesh.n_vertices()];
            for (t, f) in mesh.faces.iter().enumerate() {
                for &v in f {
                    disp_w[v] += area[t] / 3.0;
                }
            }
            for w in disp_w.iter_mut() {
                *w /= l2 * a_tot;
            }
            Ok((area, a_tot, disp_w))
        };
        // Per-face terms (M_t, w_t) and vertex weights; for a new mesh topology they are computed
        // beside its analysis (pattern, ordering, symbolic factorisation), which does not need them.
        let terms = || -> Result<FaceTerms> {
            let t0 = std::time::Instant::now();
            // The image areas and vertex weights (sequential sums, fixed order) run beside the
            // parallel M_t of the faces, which does not need them.
            let (cos_t, sin_t) = (th.cos(), th.sin());
            let (mut tri_rows, mut edge2): (Vec<[[f64; 6]; 2]>, Vec<f64>) = (Vec::new(), Vec::new());
            let degenerate = std::sync::atomic::AtomicBool::new(false);
            let (weights, ()) = rayon::join(
                || area_weights(mesh),
                || {
                    // M_t and |P_b − P_a|² per face (independent per face: parallel, deterministic),
                    // written in place (`unzip_into_vecs` of an indexed iterator; collecting into an
                    // `Option<Vec>` concatenated per-thread lists, which cost a third of the assembly).
                    mesh.faces
                        .par_iter()
                        .with_min_len(1024)
                        .map(|f| {
                            let mr = triangle_rows_cs(
                                &mesh.x3d[f[0]],
                                &mesh.x3d[f[1]],
                                &mesh.x3d[f[2]],
                                params,
                                cos_t,
                                sin_t,
                            )
                            .unwrap_or_else(|| {
                                degenerate.store(true, std::sync::atomic::Ordering::Relaxed);
                                [[0.0; 6]; 2]
                            });
                            let (pa, pb) = (mesh.p_init[f[0]], mesh.p_init[f[1]]);
                            (mr, (pb[0] - pa[0]).powi(2) + (pb[1] - pa[1]).powi(2))
                        })
                        .unzip_into_vecs(&mut tri_rows, &mut edge2)
                },
            );
            let (area, a_tot, disp_w) = weights?;
            let tri_w: Vec<f64> = area.iter().zip(&edge2).map(|(&a, &e2)| a / (e2 * a_tot)).collect();
            if degenerate.into_inner() {
                let t = mesh
                    .faces
                    .iter()
                    .position(|f| triangle_rows(&mesh.x3d[f[0]], &mesh.x3d[f[1]], &mesh.x3d[f[2]], params).is_none())
                    .unwrap_or(0);
                return Err(CpcError::invalid("mesh", format!("3D triangle {t} is degenerate")));
            }
            Ok((tri_rows, tri_w, disp_w, t0.elapsed().as_secs_f64() * 1e3))
        };
        let topology_reused = topo.is_some();
        let (terms, topo) = match topo {
            Some(t) => (terms(), Ok((t, 0.0))),
            None => rayon::join(terms, || {
                let t = std::time::Instant::now();
                CpcTopology::new(mesh).map(|tp| (Arc::new(tp), t.elapsed().as_secs_f64() * 1e3))
            }),
        };
        let (tri_rows, tri_w, disp_w, ms_terms) = terms?;
        let (topo, ms_topo) = topo?;
        let t2 = std::time::Instant::now();
        let herm_vals = (params.convention == RowConvention::Derived).then(|| {
            let mut vals = vec![c64::new(0.0, 0.0); topo.nnz_lower()];
            for ((mr, &w), fp) in tri_rows.iter().zip(&tri_w).zip(&topo.face_pos) {
                // g_j = A_j − i B_j with A_j = M[0][2j], B_j = M[0][2j+1].
                let g = [0, 1, 2].map(|j| c64::new(mr[0][2 * j], -mr[0][2 * j + 1]));
                for r in 0..3 {
                    let gr = c64::new(w * g[r].re, -w * g[r].im); // w · conj(g_r)
                    for c in 0..3 {
                        let pos = fp[3 * r + c];
                        if pos != u32::MAX {
                            vals[pos as usize] += gr * g[c];
                        }
                    }
                }
            }
            vals
        });
        let t3 = std::time::Instant::now();
        Ok(CpcSystem {
            n_vertices: n,
            disp_w,
            tri_rows,
            tri_w,
            grid_step_px: mesh.grid_step_px,
            topo,
            herm_vals,
            real: OnceLock::new(),
            assembly_ms: [ms_terms, (t3 - t2).as_secs_f64() * 1e3, ms_topo],
            topology_reused,
            factor_threads: 1,
            domain_split: true,
        })
    }

    /// Threads of the numeric Cholesky factorisation (≤ 1: sequential, the default); the
    /// solution is bitwise identical for any thread count.
    pub fn set_factor_threads(&mut self, threads: usize) {
        self.factor_threads = threads;
    }

    /// Use the topology's two-domain split when it has one (the default; see
    /// [`CpcTopology::is_split`]); `false` factorises the whole system at once. Both give the same
    /// solution up to round-off.
    pub fn set_domain_split(&mut self, split: bool) {
        self.domain_split = split;
    }

    /// Number of real unknowns (2 per vertex).
    pub fn n_unknowns(&self) -> usize {
        2 * self.n_vertices
    }

    /// Non-zeros of the (full, symmetric) real interleaved normal matrix (4 per vertex pair).
    pub fn nnz(&self) -> usize {
        4 * (2 * self.topo.nnz_lower() - self.n_vertices)
    }

    /// The shared topology (pattern and symbolic factorisation of the complex system).
    pub fn topology(&self) -> &Arc<CpcTopology> {
        &self.topo
    }

    /// Minimise eq. 4.11 for `lambda` ∈ [0, 1); returns the flattened vertex positions (px).
    /// λ = 0 returns P_init exactly.
    pub fn solve(&self, lambda: f64) -> Result<Vec<[f64; 2]>> {
        validate_lambda(lambda)?;
        if lambda == 0.0 {
            return Ok(self.topo.p_init.clone());
        }
        let out: Vec<[f64; 2]> = match &self.herm_vals {
            Some(h) => {
                let mut vals: Vec<c64> = h.iter().map(|&v| c64::new(lambda * v.re, lambda * v.im)).collect();
                for (c, &w) in self.disp_w.iter().enumerate() {
                    // The diagonal entry is the first stored row of every column.
                    vals[self.topo.col_ptr[c]].re += (1.0 - lambda) * w;
                }
                let mut rhs: Vec<c64> = self
                    .topo
                    .p_init
                    .iter()
                    .zip(&self.disp_w)
                    .map(|(p, &w)| c64::new((1.0 - lambda) * w * p[0], (1.0 - lambda) * w * p[1]))
                    .collect();
                self.topo
                    .factor_solve(&vals, &mut rhs, self.factor_threads, self.domain_split)
                    .map_err(|e| CpcError::Solver(format!("lambda = {lambda}: {e}")))?;
                rhs.iter().map(|z| [z.re, z.im]).collect()
            }
            None => {
                let real = self.real()?;
                let mut vals: Vec<f64> = real.conf_vals.iter().map(|&v| lambda * v).collect();
                for (u, &pos) in real.diag_pos.iter().enumerate() {
                    vals[pos] += (1.0 - lambda) * self.disp_w[u / 2];
                }
                let mut rhs: Vec<f64> = Vec::with_capacity(2 * self.n_vertices);
                for (v, p) in self.topo.p_init.iter().enumerate() {
                    rhs.push((1.0 - lambda) * self.disp_w[v] * p[0]);
                    rhs.push((1.0 - lambda) * self.disp_w[v] * p[1]);
                }
                self.factor_solve(&vals, &mut rhs).map_err(|e| CpcError::Solver(format!("lambda = {lambda}: {e}")))?;
                rhs.chunks_exact(2).map(|c| [c[0], c[1]]).collect()
            }
        };
        if out.iter().any(|v| !(v[0].is_finite() && v[1].is_finite())) {
            return Err(CpcError::Solver(format!("non-finite solution for lambda = {lambda}")));
        }
        Ok(out)
    }

    /// The two terms of eq. 4.11 at `p` (area-weighted means): (conformal, displacement).
    pub fn energies(&self, p: &[[f64; 2]]) -> (f64, f64) {
        let mut ec = 0.0;
        for (t, f) in self.topo.faces.iter().enumerate() {
            let r = crate::conformal::residual(&self.tri_rows[t], p[f[0]], p[f[1]], p[f[2]]);
            ec += self.tri_w[t] * (r[0] * r[0] + r[1] * r[1]);
        }
        let ed: f64 = p
            .iter()
            .zip(&self.topo.p_init)
            .zip(&self.disp_w)
            .map(|((a, b), w)| w * ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)))
            .sum();
        (ec, ed)
    }

    /// Per-triangle conformal rows M_t and weights (for the equiareal refinement).
    pub fn triangle_terms(&self) -> (&[[[f64; 6]; 2]], &[f64]) {
        (&self.tri_rows, &self.tri_w)
    }

    fn real(&self) -> Result<&RealSystem> {
        self.real
            .get_or_init(|| {
                RealSystem::build(
                    self.n_vertices,
                    &self.topo.faces,
                    &self.tri_rows,
                    &self.tri_w,
                    &self.topo.p_init,
                    self.grid_step_px,
                )
            })
            .as_ref()
            .map_err(|e| CpcError::Solver(e.clone()))
    }

    fn real_or_panic(&self) -> &RealSystem {
        self.real().expect("symbolic analysis of the real system")
    }

    /// The shared sparsity pattern of the real interleaved system: (column pointers, row indices,
    /// diagonal positions). Built on first use.
    pub fn pattern(&self) -> (&[usize], &[usize], &[usize]) {
        let r = self.real_or_panic();
        (&r.col_ptr, &r.row_idx, &r.diag_pos)
    }

    /// The symbolic Cholesky factorisation of the real interleaved pattern (built on first use).
    pub fn symbolic(&self) -> &SymbolicCholesky<usize> {
        &self.real_or_panic().symbolic
    }

    /// y = K x with K = Σ_t w_t M_tᵀ M_t (interleaved unknowns).
    pub fn conformal_matvec(&self, x: &[f64]) -> Vec<f64> {
        let r = self.real_or_panic();
        let mut y = vec![0.0; x.len()];
        for (c, &xc) in x.iter().enumerate() {
            for k in r.col_ptr[c]..r.col_ptr[c + 1] {
                y[r.row_idx[k]] += r.conf_vals[k] * xc;
            }
        }
        y
    }

    /// The conformal values K on the shared real pattern.
    pub fn conformal_values(&self) -> &[f64] {
        &self.real_or_panic().conf_vals
    }

    /// Add the 6×6 block `k6` (local unknowns [x_a, y_a, x_b, y_b, x_c, y_c]) of face `f` to
    /// `vals` (on the shared real pattern).
    pub fn add_face_block(&self, vals: &mut [f64], f: &[usize; 3], k6: &[[f64; 6]; 6]) {
        let r = self.real_or_panic();
        for (cl, &cv) in f.iter().enumerate() {
            for kc in 0..2 {
                let col = 2 * cv + kc;
                let rows = &r.row_idx[r.col_ptr[col]..r.col_ptr[col + 1]];
                for (rl, &rv) in f.iter().enumerate() {
                    let pos = rows.binary_search(&(2 * rv)).expect("face pair in pattern");
                    let base = r.col_ptr[col] + pos;
                    vals[base] += k6[2 * rl][2 * cl + kc];
                    vals[base + 1] += k6[2 * rl + 1][2 * cl + kc];
                }
            }
        }
    }

    /// Factorise the real interleaved matrix with values `vals` on the shared real pattern and
    /// solve for `rhs` in place.
    pub fn factor_solve(&self, vals: &[f64], rhs: &mut [f64]) -> Result<()> {
        let r = self.real()?;
        let n = 2 * self.n_vertices;
        let sym = SymbolicSparseColMatRef::new_checked(n, n, &r.col_ptr, None, &r.row_idx);
        let mat = SparseColMatRef::new(sym, vals);
        let par = Par::Seq;
        let mut l_vals = vec![0.0f64; r.symbolic.len_val()];
        let mut mem = MemBuffer::new(r.symbolic.factorize_numeric_llt_scratch::<f64>(par, Default::default()));
        let llt = r
            .symbolic
            .factorize_numeric_llt(
                &mut l_vals,
                mat,
                Side::Lower,
                Default::default(),
                par,
                MemStack::new(&mut mem),
                Default::default(),
            )
            .map_err(|e| CpcError::Solver(format!("Cholesky failed (matrix not positive definite?): {e:?}")))?;
        let mut mem2 = MemBuffer::new(r.symbolic.solve_in_place_scratch::<f64>(1, par));
        llt.solve_in_place_with_conj(
            Conj::No,
            MatMut::from_column_major_slice_mut(rhs, n, 1),
            par,
            MemStack::new(&mut mem2),
        );
        Ok(())
    }

    /// Displacement weights per vertex.
    pub fn displacement_weights(&self) -> &[f64] {
        &self.disp_w
    }
}

impl RealSystem {
    fn build(
        n: usize,
        faces: &[[usize; 3]],
        tri_rows: &[[[f64; 6]; 2]],
        tri_w: &[f64],
        p_init: &[[f64; 2]],
        grid_step_px: usize,
    ) -> std::result::Result<RealSystem, String> {
        // Vertex adjacency (including self), sorted.
        let mut nbr: Vec<Vec<usize>> = vec![Vec::with_capacity(8); n];
        for f in faces {
            for &i in f {
                for &j in f {
                    if !nbr[i].contains(&j) {
                        nbr[i].push(j);
                    }
                }
            }
        }
        for l in nbr.iter_mut() {
            l.sort_unstable();
        }
        let mut col_ptr = Vec::with_capacity(2 * n + 1);
        col_ptr.push(0usize);
        let mut row_idx = Vec::new();
        let mut diag_pos = vec![0usize; 2 * n];
        for i in 0..n {
            for k in 0..2 {
                for &w in &nbr[i] {
                    if w == i {
                        diag_pos[2 * i + k] = row_idx.len() + k;
                    }
                    row_idx.push(2 * w);
                    row_idx.push(2 * w + 1);
                }
                col_ptr.push(row_idx.len());
            }
        }
        let mut conf_vals = vec![0.0; row_idx.len()];
        for (t, f) in faces.iter().enumerate() {
            let mr = &tri_rows[t];
            let w = tri_w[t];
            for (cl, &cv) in f.iter().enumerate() {
                for (rl, &rv) in f.iter().enumerate() {
                    let pos = nbr[cv].binary_search(&rv).expect("adjacency contains every face pair");
                    for kc in 0..2 {
                        let base = col_ptr[2 * cv + kc] + 2 * pos;
                        for kr in 0..2 {
                            let (r, c) = (2 * rl + kr, 2 * cl + kc);
                            conf_vals[base + kr] += w * (mr[0][r] * mr[0][c] + mr[1][r] * mr[1][c]);
                        }
                    }
                }
            }
        }
        let sym = SymbolicSparseColMatRef::new_checked(2 * n, 2 * n, &col_ptr, None, &row_idx);
        let fwd_v = nested_dissection_points(p_init, grid_step_px);
        let mut fwd = Vec::with_capacity(2 * n);
        for &v in &fwd_v {
            fwd.push(2 * v);
            fwd.push(2 * v + 1);
        }
        let mut inv = vec![0usize; 2 * n];
        for (k, &o) in fwd.iter().enumerate() {
            inv[o] = k;
        }
        let perm = PermRef::new_checked(&fwd, &inv, 2 * n);
        let symbolic =
            factorize_symbolic_cholesky(sym, Side::Lower, SymmetricOrdering::Custom(perm), Default::default())
                .map_err(|e| format!("{e:?}"))?;
        Ok(RealSystem { col_ptr, row_idx, conf_vals, diag_pos, symbolic })
    }
}

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
fn nested_dissection_split(
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
