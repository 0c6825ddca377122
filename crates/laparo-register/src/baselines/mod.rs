//! Mesh-based registration baselines of the in-silico incision benchmark (thesis §5.4.2, Table 5.1):
//! ARAP [Sorkine & Alexa 2007] ([`arap`]), DRBC [Collins 2020] ([`drbc`]) and landmark LDDMM
//! [Beg 2005] ([`lddmm`]); François et al. [2021] is DRBC on a cut mesh.
//!
//! All methods solve the same [`BaselineProblem`]: a rest tetrahedral mesh (mm; it may contain
//! duplicated nodes along a crack, the methods only use its connectivity), landmark groups whose
//! source landmarks are material points of the mesh ([`MaterialPoint`]) and whose targets are the
//! [`GroupTarget`]s of eq. 5.10 (closest point recomputed at every evaluation, so the distance is the
//! one RODS-MPM is scored with), and optional fixed nodes. Each returns the deformed node positions
//! (mm) and a [`BaselineReport`].
use crate::distance::Accel;
use crate::loss::GroupTarget;
use crate::{RegisterError, Result};
use laparo_core::geometry::closest_point_on_triangle;
use laparo_core::mesh::TetMesh;
use nalgebra::{Matrix3, Vector3};

pub mod arap;
pub mod drbc;
mod lbfgs;
pub mod lddmm;
mod sparse;

pub use arap::{arap, arap_from, ArapConfig, ArapEnergy, ArapWeights};
pub use drbc::{drbc, drbc_objective, DrbcConfig};
pub use lddmm::{lddmm, lddmm_objective, lddmm_width_sweep, LddmmConfig};

/// A material point of the rest mesh, X = Σ_a w_a X_a over 1–4 nodes (w_a ≥ 0, Σ w_a = 1); it moves
/// with the nodes, x = Σ_a w_a x_a.
#[derive(Clone, Debug, PartialEq)]
pub struct MaterialPoint {
    /// (node index, weight) pairs.
    pub nodes: Vec<(usize, f64)>,
}

impl MaterialPoint {
    /// The node `i` itself.
    pub fn node(i: usize) -> Self {
        MaterialPoint { nodes: vec![(i, 1.0)] }
    }
    /// A convex combination of 2–4 nodes (checked by [`BaselineProblem::validate`]).
    pub fn combination(nodes: &[(usize, f64)]) -> Self {
        MaterialPoint { nodes: nodes.to_vec() }
    }
    /// Position (mm) for node positions `x`.
    pub fn position(&self, x: &[Vector3<f64>]) -> Vector3<f64> {
        self.nodes.iter().map(|&(i, w)| x[i] * w).sum()
    }

    /// The material point of the rest mesh at `p` (mm): see [`TetLocator::locate`] (which to use for
    /// many points: this builds the locator's k-d tree for one).
    pub fn locate(mesh: &TetMesh, p: &Vector3<f64>, tolerance_mm: f64, what: &str) -> Result<Self> {
        TetLocator::new(mesh).locate(p, tolerance_mm, what)
    }
}

/// Point location in a rest tetrahedral mesh: a k-d tree over the tetrahedra's centroids and the exact
/// centroid-bound query of [`crate::distance`] (the nearest tetrahedron, ties to the smallest index).
pub struct TetLocator<'a> {
    mesh: &'a TetMesh,
    accel: Accel<3>,
}

impl<'a> TetLocator<'a> {
    /// Index the tetrahedra of `mesh`.
    pub fn new(mesh: &'a TetMesh) -> Self {
        let corners = |t: &[usize; 4]| t.map(|k| mesh.vertices[k]);
        let centroids: Vec<Vector3<f64>> =
            mesh.tets.iter().map(|t| corners(t).iter().sum::<Vector3<f64>>() / 4.0).collect();
        let r_max = mesh
            .tets
            .iter()
            .zip(&centroids)
            .map(|(t, c)| corners(t).iter().map(|v| (v - c).norm()).fold(0.0, f64::max))
            .fold(0.0, f64::max);
        TetLocator { mesh, accel: Accel::new(&centroids, r_max) }
    }

    /// The material point at `p` (mm): the barycentric coordinates of the tetrahedron that contains it
    /// (its nodes with weight > 0; a node itself when `p` is on it). A point outside the mesh by at most
    /// `tolerance_mm` (e.g. a landmark picked on the organ surface, which a tetrahedralisation
    /// approximates) takes the closest point of the nearest tetrahedron; farther out is an error naming
    /// `what`. A point on a crack face, where two sides' duplicated nodes coincide, goes to the
    /// tetrahedron of smaller index.
    pub fn locate(&self, p: &Vector3<f64>, tolerance_mm: f64, what: &str) -> Result<MaterialPoint> {
        if !p.iter().all(|c| c.is_finite()) {
            return Err(RegisterError::bad(what, format!("non-finite position {:?}", p.as_slice())));
        }
        let mesh = self.mesh;
        if mesh.tets.is_empty() {
            return Err(RegisterError::bad(what, "the mesh has no tetrahedron"));
        }
        let (q, e) = self.nearest_point(p);
        let Some((_, w)) = closest_point_in_tet(&self.corners(e), p) else {
            return Err(RegisterError::bad(what, "the mesh has no non-degenerate tetrahedron"));
        };
        let dist = (q - p).norm();
        if dist > tolerance_mm {
            return Err(RegisterError::bad(
                what,
                format!(
                    "({:.3}, {:.3}, {:.3}) mm lies {dist:.3} mm outside the mesh (tolerance {tolerance_mm} mm)",
                    p.x, p.y, p.z
                ),
            ));
        }
        let t = mesh.tets[e];
        let nodes: Vec<(usize, f64)> = (0..4).filter(|&a| w[a] > 1e-12).map(|a| (t[a], w[a])).collect();
        let s: f64 = nodes.iter().map(|q| q.1).sum();
        Ok(MaterialPoint { nodes: nodes.into_iter().map(|(i, v)| (i, v / s)).collect() })
    }

    /// The tetrahedron nearest `p` (mm; the one containing it when inside, ties to the smallest index)
    /// and the barycentric coordinates of `p` in it, not clamped: negative outside the mesh, so that
    /// interpolating with them extrapolates the nearest tetrahedron's affine field. `None` for a mesh
    /// without tetrahedra.
    pub fn nearest_tet(&self, p: &Vector3<f64>) -> Option<(usize, [f64; 4])> {
        if self.mesh.tets.is_empty() {
            return None;
        }
        let e = self.nearest_point(p).1;
        let c = self.corners(e);
        let l = Matrix3::from_columns(&[c[1] - c[0], c[2] - c[0], c[3] - c[0]])
            .try_inverse()
            .map_or_else(Vector3::zeros, |m| m * (p - c[0]));
        Some((e, [1.0 - l.sum(), l.x, l.y, l.z]))
    }

    fn corners(&self, e: usize) -> [Vector3<f64>; 4] {
        self.mesh.tets[e].map(|k| self.mesh.vertices[k])
    }

    /// The closest point of the mesh to `p` and its tetrahedron (degenerate tetrahedra never win).
    fn nearest_point(&self, p: &Vector3<f64>) -> (Vector3<f64>, usize) {
        self.accel
            .query(p, |e| closest_point_in_tet(&self.corners(e), p).map_or(Vector3::repeat(f64::INFINITY), |r| r.0))
    }
}

/// The closest point of tetrahedron `c` to `p` and its barycentric weights (≥ 0, sum 1); `None` for a
/// degenerate tetrahedron. Inside: `p` itself; outside: the closest point over the four faces.
pub(crate) fn closest_point_in_tet(c: &[Vector3<f64>; 4], p: &Vector3<f64>) -> Option<(Vector3<f64>, [f64; 4])> {
    let inv = Matrix3::from_columns(&[c[1] - c[0], c[2] - c[0], c[3] - c[0]]).try_inverse()?;
    let weights = |q: &Vector3<f64>| {
        let l = inv * (q - c[0]);
        [1.0 - l.x - l.y - l.z, l.x, l.y, l.z]
    };
    let w = weights(p);
    if w.iter().all(|&v| v >= 0.0) {
        return Some((*p, w));
    }
    let q = [[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]]
        .iter()
        .map(|f| closest_point_on_triangle(p, &c[f[0]], &c[f[1]], &c[f[2]]))
        .min_by(|a, b| (a - p).norm_squared().total_cmp(&(b - p).norm_squared()))?;
    // on a face: clamp the round-off of the opposite corner's weight and renormalise
    let w = weights(&q).map(|v| v.max(0.0));
    let s: f64 = w.iter().sum();
    Some((q, w.map(|v| v / s)))
}

/// A landmark group of a mesh problem: source material points scored against their own target.
#[derive(Clone)]
pub struct MeshLandmarkGroup {
    /// Name (report).
    pub name: String,
    /// Source landmarks.
    pub points: Vec<MaterialPoint>,
    /// Target (paired points, or a shared polyline / surface / cloud, closest point per evaluation).
    pub target: GroupTarget<3>,
    /// Weight of each landmark of this group (default 1).
    pub weight: f64,
}

impl MeshLandmarkGroup {
    /// Closest target point (mm) of landmark `k` at position `x` (eq. 5.10).
    pub fn closest(&self, k: usize, x: &Vector3<f64>) -> Vector3<f64> {
        match &self.target {
            GroupTarget::Paired(t) => t[k],
            GroupTarget::Shared(s) => s.closest(x).0,
        }
    }

    /// Hessian of dist²(x) = |x − c(x)|² of a landmark of this group at `x`: 2 (I − ∂c/∂x), with ∂c/∂x from central
    /// differences of the closest point (step `h_mm`; exact inside a segment or a triangle, where c is
    /// affine in x: 2 (I − t tᵀ) on a polyline, 2 n nᵀ on a surface), symmetrised and clamped to ≥ 0.
    pub(crate) fn distance_hessian(&self, x: &Vector3<f64>, h_mm: f64) -> Matrix3<f64> {
        match &self.target {
            GroupTarget::Paired(_) => Matrix3::identity() * 2.0,
            GroupTarget::Shared(s) => {
                let mut j = Matrix3::zeros();
                for d in 0..3 {
                    let mut e = Vector3::zeros();
                    e[d] = h_mm;
                    j.set_column(d, &((s.closest(&(x + e)).0 - s.closest(&(x - e)).0) / (2.0 * h_mm)));
                }
                let m = (Matrix3::identity() - (j + j.transpose()) * 0.5) * 2.0;
                let eig = m.symmetric_eigen();
                let l = eig.eigenvalues.map(|v| v.max(0.0));
                eig.eigenvectors * Matrix3::from_diagonal(&l) * eig.eigenvectors.transpose()
            }
        }
    }
}

/// What every baseline solves.
#[derive(Clone)]
pub struct BaselineProblem {
    /// Rest tetrahedral mesh (mm).
    pub mesh: TetMesh,
    /// Landmark groups.
    pub groups: Vec<MeshLandmarkGroup>,
    /// Fixed nodes and their prescribed positions (mm): hard constraints.
    pub fixed: Vec<(usize, Vector3<f64>)>,
}

/// Result of a baseline: the deformed nodes and a report.
#[derive(Clone, Debug)]
pub struct BaselineResult {
    /// Deformed node positions (mm), one per rest node.
    pub positions: Vec<Vector3<f64>>,
    /// What happened.
    pub report: BaselineReport,
}

/// Small report of a baseline run.
#[derive(Clone, Debug, serde::Serialize)]
pub struct BaselineReport {
    /// Method name ("arap", "drbc", "lddmm").
    pub method: String,
    /// Outer iterations done.
    pub iterations: usize,
    /// Mean landmark distance (mm, eq. 5.10) at the rest positions.
    pub initial_mean_distance_mm: f64,
    /// Mean landmark distance (mm, eq. 5.10) of the deformed mesh.
    pub mean_distance_mm: f64,
    /// Mean landmark distance (mm) after every iteration.
    pub history_mm: Vec<f64>,
    /// True when the stopping tolerance was met (false: iteration cap or a stalled line search).
    pub converged: bool,
    /// Wall time (s).
    pub seconds: f64,
}

impl BaselineProblem {
    /// A problem with no fixed node.
    pub fn new(mesh: TetMesh, groups: Vec<MeshLandmarkGroup>) -> Self {
        BaselineProblem { mesh, groups, fixed: Vec::new() }
    }

    /// Fix `nodes` at their rest positions (an out-of-range node is kept with a NaN position, so that
    /// [`validate`](Self::validate) names it).
    pub fn fix_at_rest(&mut self, nodes: &[usize]) {
        for &i in nodes {
            let p = self.mesh.vertices.get(i).copied().unwrap_or_else(|| Vector3::repeat(f64::NAN));
            self.fixed.push((i, p));
        }
    }

    /// Check indices, weights and targets; errors name the group / node.
    pub fn validate(&self) -> Result<()> {
        let n = self.mesh.vertices.len();
        if n == 0 || self.mesh.tets.is_empty() {
            return Err(RegisterError::bad("baseline mesh", "no node or no tetrahedron"));
        }
        if let Some(t) = self.mesh.tets.iter().find(|t| t.iter().any(|&k| k >= n)) {
            return Err(RegisterError::bad("baseline mesh", format!("tet {t:?} uses a node >= {n}")));
        }
        if self.mesh.vertices.iter().any(|v| !v.iter().all(|c| c.is_finite())) {
            return Err(RegisterError::bad("baseline mesh", "non-finite node coordinate"));
        }
        for (i, t) in self.mesh.tets.iter().enumerate() {
            if self.mesh.tet_volume(i) == 0.0 {
                return Err(RegisterError::bad("baseline mesh", format!("tet {i} {t:?} has zero volume")));
            }
        }
        let mut count = 0;
        for g in &self.groups {
            let name = format!("landmark group `{}`", g.name);
            if !(g.weight.is_finite() && g.weight > 0.0) {
                return Err(RegisterError::param(format!("{name} weight"), g.weight, "must be finite and > 0"));
            }
            for (k, p) in g.points.iter().enumerate() {
                let s: f64 = p.nodes.iter().map(|q| q.1).sum();
                if p.nodes.is_empty()
                    || p.nodes.len() > 4
                    || p.nodes.iter().any(|&(i, w)| i >= n || !(w.is_finite() && w >= 0.0))
                    || (s - 1.0).abs() > 1e-9
                {
                    return Err(RegisterError::bad(
                        name,
                        format!("landmark {k} {:?} is not a convex combination of 1-4 of the {n} nodes", p.nodes),
                    ));
                }
            }
            match &g.target {
                GroupTarget::Paired(t) if t.len() != g.points.len() => {
                    return Err(RegisterError::bad(
                        name,
                        format!("{} paired targets for {} landmarks", t.len(), g.points.len()),
                    ))
                }
                GroupTarget::Shared(s) if s.is_empty() => return Err(RegisterError::bad(name, "empty target")),
                _ => {}
            }
            count += g.points.len();
        }
        if count == 0 && self.fixed.is_empty() {
            return Err(RegisterError::bad("baseline landmarks", "no source landmark and no fixed node"));
        }
        let mut seen = vec![false; n];
        for &(i, p) in &self.fixed {
            if i >= n || seen[i] || !p.iter().all(|c| c.is_finite()) {
                return Err(RegisterError::bad(
                    "baseline fixed nodes",
                    format!("node {i} is out of range, repeated or has a non-finite position"),
                ));
            }
            seen[i] = true;
        }
        Ok(())
    }

    /// Number of source landmarks over all groups.
    pub fn landmark_count(&self) -> usize {
        self.groups.iter().map(|g| g.points.len()).sum()
    }

    /// Mean unsquared landmark distance (mm, eq. 5.10; every landmark counts once) at node positions `x`.
    pub fn mean_distance(&self, x: &[Vector3<f64>]) -> f64 {
        let (mut s, mut n) = (0.0, 0usize);
        for g in &self.groups {
            for (k, p) in g.points.iter().enumerate() {
                let y = p.position(x);
                s += (y - g.closest(k, &y)).norm();
                n += 1;
            }
        }
        s / n.max(1) as f64
    }

    /// Rest positions with the fixed nodes moved to their prescribed positions (the initial guess).
    pub fn initial_positions(&self) -> Vec<Vector3<f64>> {
        let mut x = self.mesh.vertices.clone();
        for &(i, p) in &self.fixed {
            if let Some(v) = x.get_mut(i) {
                *v = p;
            }
        }
        x
    }

    /// Per node: `Some(free index)` or `None` when fixed; and the number of free nodes.
    pub(crate) fn free_map(&self) -> (Vec<Option<usize>>, usize) {
        let n = self.mesh.vertices.len();
        let mut fixed = vec![false; n];
        for &(i, _) in &self.fixed {
            fixed[i] = true;
        }
        let mut map = vec![None; n];
        let mut m = 0;
        for i in 0..n {
            if !fixed[i] {
                map[i] = Some(m);
                m += 1;
            }
        }
        (map, m)
    }

    /// Bounding-box diagonal of the rest mesh (mm).
    pub(crate) fn diameter(&self) -> f64 {
        self.mesh.bounding_box().map(|(a, b)| (b - a).norm()).unwrap_or(1.0).max(1e-300)
    }

    /// Σ |tet volumes| (mm³).
    pub(crate) fn total_volume(&self) -> f64 {
        self.mesh.volume().max(1e-300)
    }
}

/// Per tet of the rest mesh: the gradients g_a (1/mm) of the four barycentric shape functions and the
/// volume V (mm³); the deformation gradient of a linear tet is F = Σ_a x_a g_aᵀ.
pub(crate) fn shape_gradients(mesh: &TetMesh) -> Vec<([Vector3<f64>; 4], f64)> {
    mesh.tets
        .iter()
        .map(|t| {
            let p = |a: usize| mesh.vertices[t[a]];
            let dm = Matrix3::from_columns(&[p(1) - p(0), p(2) - p(0), p(3) - p(0)]);
            let inv = dm.try_inverse().unwrap_or_else(Matrix3::zeros);
            let g1 = inv.row(0).transpose();
            let g2 = inv.row(1).transpose();
            let g3 = inv.row(2).transpose();
            ([-(g1 + g2 + g3), g1, g2, g3], dm.determinant().abs() / 6.0)
        })
        .collect()
}

/// The deformation gradient F = Σ_a x_a g_aᵀ of tet `t`.
pub(crate) fn deformation_gradient(t: &[usize; 4], g: &[Vector3<f64>; 4], x: &[Vector3<f64>]) -> Matrix3<f64> {
    let mut f = Matrix3::zeros();
    for a in 0..4 {
        f += x[t[a]] * g[a].transpose();
    }
    f
}

/// Rotation closest to `m` (polar factor, det +1; the reflection is removed on the smallest
/// singular direction), as in the ARAP local step.
pub(crate) fn closest_rotation(m: &Matrix3<f64>) -> Matrix3<f64> {
    let svd = m.svd(true, true);
    let (mut u, vt) = (svd.u.unwrap_or_else(Matrix3::identity), svd.v_t.unwrap_or_else(Matrix3::identity));
    let mut r = u * vt;
    if r.determinant() < 0.0 {
        let s = svd.singular_values;
        let mut k = 0;
        for i in 1..3 {
            if s[i] < s[k] {
                k = i;
            }
        }
        let c = -u.column(k);
        u.set_column(k, &c);
        r = u * vt;
    }
    r
}

/// A structured tetrahedral mesh of a box: `n` = cells per axis, spacing `h_mm`, origin `origin`,
/// every cube split into 6 tets along its main diagonal (Freudenthal / Kuhn split; conforming).
pub fn box_tet_mesh(n: [usize; 3], h_mm: f64, origin: Vector3<f64>) -> TetMesh {
    let id = |i: usize, j: usize, k: usize| i + (n[0] + 1) * (j + (n[1] + 1) * k);
    let mut vertices = Vec::new();
    for k in 0..=n[2] {
        for j in 0..=n[1] {
            for i in 0..=n[0] {
                vertices.push(origin + Vector3::new(i as f64, j as f64, k as f64) * h_mm);
            }
        }
    }
    let mut tets = Vec::new();
    // the 6 monotone paths from corner 000 to 111
    let perms = [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]];
    for k in 0..n[2] {
        for j in 0..n[1] {
            for i in 0..n[0] {
                for p in perms {
                    let mut c = [0usize; 3];
                    let mut t = [id(i, j, k); 4];
                    for (s, &ax) in p.iter().enumerate() {
                        c[ax] = 1;
                        t[s + 1] = id(i + c[0], j + c[1], k + c[2]);
                    }
                    tets.push(t);
                }
            }
        }
    }
    let mut m = TetMesh { vertices, tets };
    m.orient_positive();
    m
}
