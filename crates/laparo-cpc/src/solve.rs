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
//! The normal equations (λ K + (1−λ) D) p = (1−λ) D P_init are assembled once per mesh (K = Σ w_t M_tᵀM_t,
//! D diagonal, one shared sparsity pattern with unknowns interleaved [x_0, y_0, x_1, y_1, ...]);
//! the symbolic sparse Cholesky (faer) is computed once, with a geometric nested-dissection
//! ordering of the grid (grid lines are vertex separators of the triangulated grid, so the
//! ordering costs O(n log n) and avoids AMD), and and every λ costs one numeric
//! factorisation and two triangular solves. The system is block-diagonal over connected components,
//! so one factorisation solves every component separately.
use crate::conformal::{triangle_rows, ConformalParams};
use crate::error::{CpcError, Result};
use crate::mesh::{signed_area, CpcMesh};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::perm::PermRef;
use faer::sparse::linalg::cholesky::{factorize_symbolic_cholesky, SymbolicCholesky, SymmetricOrdering};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};

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

/// The assembled CPC system of one mesh, ready to be solved for any λ.
pub struct CpcSystem {
    n_vertices: usize,
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    /// Σ_t w_t M_tᵀ M_t on the shared pattern.
    conf_vals: Vec<f64>,
    /// Index of the diagonal entry of every unknown in the value arrays.
    diag_pos: Vec<usize>,
    /// Displacement weight a_v / (L² A_tot) of every vertex.
    disp_w: Vec<f64>,
    p_init: Vec<[f64; 2]>,
    /// M_t of every triangle and its weight w_t = A_t / (|P_b − P_a|² A_tot).
    tri_rows: Vec<[[f64; 6]; 2]>,
    tri_w: Vec<f64>,
    faces: Vec<[usize; 3]>,
    symbolic: SymbolicCholesky<usize>,
    /// Assembly timings (ms): [weights and M_t, sparse pattern and values, ordering + symbolic Cholesky].
    pub assembly_ms: [f64; 3],
}

impl CpcSystem {
    /// Assemble the conformal and displacement terms of `mesh` and analyse the sparsity pattern.
    pub fn assemble(mesh: &CpcMesh, params: &ConformalParams) -> Result<CpcSystem> {
        let th = params.theta_rad;
        if !(th.is_finite() && th > 0.0 && th < std::f64::consts::PI) {
            return Err(CpcError::invalid("theta", format!("{th} rad (must be in (0, π))")));
        }
        let t0 = std::time::Instant::now();
        let n = mesh.n_vertices();
        let m = mesh.n_triangles();
        if m == 0 {
            return Err(CpcError::invalid("mesh", "has no triangle"));
        }
        // Areas and weights.
        let mut area = vec![0.0; m];
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
        let mut disp_w = vec![0.0; n];
        for (t, f) in mesh.faces.iter().enumerate() {
            for &v in f {
                disp_w[v] += area[t] / 3.0;
            }
        }
        for w in disp_w.iter_mut() {
            *w /= l2 * a_tot;
        }
        let mut tri_rows = Vec::with_capacity(m);
        let mut tri_w = Vec::with_capacity(m);
        for (t, f) in mesh.faces.iter().enumerate() {
            let rows = triangle_rows(&mesh.x3d[f[0]], &mesh.x3d[f[1]], &mesh.x3d[f[2]], params)
                .ok_or_else(|| CpcError::invalid("mesh", format!("3D triangle {t} is degenerate")))?;
            let (pa, pb) = (mesh.p_init[f[0]], mesh.p_init[f[1]]);
            let e2 = (pb[0] - pa[0]).powi(2) + (pb[1] - pa[1]).powi(2);
            tri_rows.push(rows);
            tri_w.push(area[t] / (e2 * a_tot));
        }
        let t1 = std::time::Instant::now();
        // Vertex adjacency (including self), sorted.
        let mut nbr: Vec<Vec<usize>> = vec![Vec::with_capacity(8); n];
        for f in &mesh.faces {
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
        for (t, f) in mesh.faces.iter().enumerate() {
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
        let t2 = std::time::Instant::now();
        let sym = SymbolicSparseColMatRef::new_checked(2 * n, 2 * n, &col_ptr, None, &row_idx);
        let fwd_v = nested_dissection(mesh);
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
                .map_err(|e| CpcError::Solver(format!("{e:?}")))?;
        Ok(CpcSystem {
            n_vertices: n,
            col_ptr,
            row_idx,
            conf_vals,
            diag_pos,
            disp_w,
            p_init: mesh.p_init.clone(),
            tri_rows,
            tri_w,
            faces: mesh.faces.clone(),
            symbolic,
            assembly_ms: [
                (t1 - t0).as_secs_f64() * 1e3,
                (t2 - t1).as_secs_f64() * 1e3,
                t2.elapsed().as_secs_f64() * 1e3,
            ],
        })
    }

    /// Number of unknowns (2 per vertex).
    pub fn n_unknowns(&self) -> usize {
        2 * self.n_vertices
    }

    /// Non-zeros of the (full, symmetric) normal matrix.
    pub fn nnz(&self) -> usize {
        self.row_idx.len()
    }

    /// Minimise eq. 4.11 for `lambda` ∈ [0, 1); returns the flattened vertex positions (px).
    /// λ = 0 returns P_init exactly.
    pub fn solve(&self, lambda: f64) -> Result<Vec<[f64; 2]>> {
        validate_lambda(lambda)?;
        if lambda == 0.0 {
            return Ok(self.p_init.clone());
        }
        let mut vals: Vec<f64> = self.conf_vals.iter().map(|&v| lambda * v).collect();
        for (u, &pos) in self.diag_pos.iter().enumerate() {
            vals[pos] += (1.0 - lambda) * self.disp_w[u / 2];
        }
        let mut rhs: Vec<f64> = Vec::with_capacity(2 * self.n_vertices);
        for (v, p) in self.p_init.iter().enumerate() {
            rhs.push((1.0 - lambda) * self.disp_w[v] * p[0]);
            rhs.push((1.0 - lambda) * self.disp_w[v] * p[1]);
        }
        self.factor_solve(&vals, &mut rhs).map_err(|e| CpcError::Solver(format!("lambda = {lambda}: {e}")))?;
        if rhs.iter().any(|v| !v.is_finite()) {
            return Err(CpcError::Solver(format!("non-finite solution for lambda = {lambda}")));
        }
        Ok(rhs.chunks_exact(2).map(|c| [c[0], c[1]]).collect())
    }

    /// The two terms of eq. 4.11 at `p` (area-weighted means): (conformal, displacement).
    pub fn energies(&self, p: &[[f64; 2]]) -> (f64, f64) {
        let mut ec = 0.0;
        for (t, f) in self.faces.iter().enumerate() {
            let r = crate::conformal::residual(&self.tri_rows[t], p[f[0]], p[f[1]], p[f[2]]);
            ec += self.tri_w[t] * (r[0] * r[0] + r[1] * r[1]);
        }
        let ed: f64 = p
            .iter()
            .zip(&self.p_init)
            .zip(&self.disp_w)
            .map(|((a, b), w)| w * ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)))
            .sum();
        (ec, ed)
    }

    /// Per-triangle conformal rows M_t and weights (for the equiareal refinement).
    pub fn triangle_terms(&self) -> (&[[[f64; 6]; 2]], &[f64]) {
        (&self.tri_rows, &self.tri_w)
    }

    /// The shared sparsity pattern: (column pointers, row indices, diagonal positions).
    pub fn pattern(&self) -> (&[usize], &[usize], &[usize]) {
        (&self.col_ptr, &self.row_idx, &self.diag_pos)
    }

    /// The symbolic Cholesky factorisation of the shared pattern.
    pub fn symbolic(&self) -> &SymbolicCholesky<usize> {
        &self.symbolic
    }

    /// y = K x with K = Σ_t w_t M_tᵀ M_t (interleaved unknowns).
    pub fn conformal_matvec(&self, x: &[f64]) -> Vec<f64> {
        let mut y = vec![0.0; x.len()];
        for (c, &xc) in x.iter().enumerate() {
            for k in self.col_ptr[c]..self.col_ptr[c + 1] {
                y[self.row_idx[k]] += self.conf_vals[k] * xc;
            }
        }
        y
    }

    /// The conformal values K on the shared pattern.
    pub fn conformal_values(&self) -> &[f64] {
        &self.conf_vals
    }

    /// Add the 6×6 block `k6` (local unknowns [x_a, y_a, x_b, y_b, x_c, y_c]) of face `f` to
    /// `vals` (on the shared pattern).
    pub fn add_face_block(&self, vals: &mut [f64], f: &[usize; 3], k6: &[[f64; 6]; 6]) {
        for (cl, &cv) in f.iter().enumerate() {
            for kc in 0..2 {
                let col = 2 * cv + kc;
                let rows = &self.row_idx[self.col_ptr[col]..self.col_ptr[col + 1]];
                for (rl, &rv) in f.iter().enumerate() {
                    let pos = rows.binary_search(&(2 * rv)).expect("face pair in pattern");
                    let base = self.col_ptr[col] + pos;
                    vals[base] += k6[2 * rl][2 * cl + kc];
                    vals[base + 1] += k6[2 * rl + 1][2 * cl + kc];
                }
            }
        }
    }

    /// Factorise the matrix with values `vals` on the shared pattern and solve for `rhs` in place.
    pub fn factor_solve(&self, vals: &[f64], rhs: &mut [f64]) -> Result<()> {
        let n = 2 * self.n_vertices;
        let sym = SymbolicSparseColMatRef::new_checked(n, n, &self.col_ptr, None, &self.row_idx);
        let mat = SparseColMatRef::new(sym, vals);
        // Sequential: on the shared 2-core machine faer's rayon path was not faster (19.9–30.8 vs 24.6–25.9 ms at 4 px).
        let par = Par::Seq;
        let mut l_vals = vec![0.0f64; self.symbolic.len_val()];
        let mut mem = MemBuffer::new(self.symbolic.factorize_numeric_llt_scratch::<f64>(par, Default::default()));
        let llt = self
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
        let mut mem2 = MemBuffer::new(self.symbolic.solve_in_place_scratch::<f64>(1, par));
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

/// Geometric nested-dissection order of the mesh vertices (old index at each new position):
/// split the grid box along its longer side by one grid line (a vertex separator of the
/// triangulated grid), order both halves recursively, then the separator.
pub fn nested_dissection(mesh: &CpcMesh) -> Vec<usize> {
    let s = mesh.grid_step_px as f64;
    let gc: Vec<[i64; 2]> =
        mesh.p_init.iter().map(|p| [(p[0] / s).round() as i64, (p[1] / s).round() as i64]).collect();
    let mut ids: Vec<usize> = (0..mesh.n_vertices()).collect();
    let mut out = Vec::with_capacity(ids.len());
    fn rec(ids: &mut [usize], gc: &[[i64; 2]], out: &mut Vec<usize>) {
        if ids.len() <= 48 {
            out.extend_from_slice(ids);
            return;
        }
        let (mut lo, mut hi) = ([i64::MAX; 2], [i64::MIN; 2]);
        for &v in ids.iter() {
            for k in 0..2 {
                lo[k] = lo[k].min(gc[v][k]);
                hi[k] = hi[k].max(gc[v][k]);
            }
        }
        let ax = if hi[0] - lo[0] >= hi[1] - lo[1] { 0 } else { 1 };
        if hi[ax] == lo[ax] {
            out.extend_from_slice(ids);
            return;
        }
        let mid = (lo[ax] + hi[ax]) / 2;
        ids.sort_unstable_by_key(|&v| (gc[v][ax] != mid, gc[v][ax] > mid));
        // now: [separator | left | right]
        let n_sep = ids.iter().take_while(|&&v| gc[v][ax] == mid).count();
        let n_left = ids[n_sep..].iter().take_while(|&&v| gc[v][ax] < mid).count();
        let sep: Vec<usize> = ids[..n_sep].to_vec();
        let (left, right) = ids[n_sep..].split_at_mut(n_left);
        rec(left, gc, out);
        rec(right, gc, out);
        out.extend_from_slice(&sep);
    }
    rec(&mut ids, &gc, &mut out);
    out
}
