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
pub use crate::dd::MIN_SPLIT_VERTICES;
use crate::error::{CpcError, Result};
use crate::factor_buffers::FactorPool;
use crate::mesh::{signed_area, CpcMesh};
use crate::ordering::nested_dissection_points;
pub use crate::topology::CpcTopology;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::perm::PermRef;
use faer::sparse::linalg::cholesky::{factorize_symbolic_cholesky, SymbolicCholesky, SymmetricOrdering};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{c64, Conj, MatMut, Par, Side};
use rayon::prelude::*;
use std::sync::{Arc, OnceLock};

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

/// Per-face M_t and w_t, per-vertex displacement weights, and the time taken (ms).
type FaceTerms = (Vec<[[f64; 6]; 2]>, Vec<f64>, Vec<f64>, f64);

/// Reusable CPC solver state for a video: keeps the [`CpcTopology`] of the last mesh and reuses it
/// (sparsity pattern, ordering, symbolic factorisation, factor buffers) when the next frame's mesh
/// has the same topology, e.g. a fixed ROI and the same valid-depth triangles.
#[derive(Default)]
pub struct CpcSolver {
    topo: Option<Arc<CpcTopology>>,
    factor_threads: usize,
    /// Factor buffers of this solver's dropped topologies, handed to its next new topology.
    pool: Arc<FactorPool>,
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
        let mut sys = CpcSystem::assemble_with(mesh, params, cached, Some(&self.pool))?;
        sys.set_factor_threads(self.factor_threads);
        self.topo = Some(sys.topo.clone());
        Ok(sys)
    }

    /// Threads of the numeric Cholesky factorisation of the systems it assembles (≤ 1:
    /// sequential, the default). The result does not depend on it.
    pub fn set_factor_threads(&mut self, threads: usize) {
        self.factor_threads = threads;
    }

    /// Forget the cached topology (its factor buffers stay in this solver's pool for the next one).
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
        CpcSystem::assemble_with(mesh, params, None, None)
    }

    fn assemble_with(
        mesh: &CpcMesh,
        params: &ConformalParams,
        topo: Option<Arc<CpcTopology>>,
        pool: Option<&Arc<FactorPool>>,
    ) -> Result<CpcSystem> {
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
                CpcTopology::with_pool(mesh, pool.cloned()).map(|tp| (Arc::new(tp), t.elapsed().as_secs_f64() * 1e3))
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
