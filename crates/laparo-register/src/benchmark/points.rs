//! Common evaluation points of the incision benchmark (v2): a material lattice inside the source organ plus
//! side-labelled points on each crack face, with the ground truth interpolated in its own side's TET10
//! element and two fixed distances per point (to the continuous source lip polylines and to the true crack
//! surface). Every method is read at the same points: mesh methods by P1 interpolation in the element that
//! holds the point ([`EvalPoints::p1`]), RODS-MPM by one particle→point transfer; the Fig. 5.8 bins are
//! fixed distance bands, so they do not move with the landmark count.
use super::case::BenchmarkCase;
use super::rods::{sample_lattice, tet_sides, true_crack};
use crate::distance::{ClosestPoint, Polyline, TriangleSurface};
use crate::error::{RegisterError, Result};
use nalgebra::{Matrix3, Vector3};
use std::collections::HashMap;

/// Where an evaluation point comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum PointKind {
    /// A node of the material lattice inside the organ.
    Lattice,
    /// A point on a crack face (one per side: the two lips' copies of the same rest position).
    CrackFace,
}

/// The evaluation points of one case (rest positions in mm).
#[derive(Clone, Debug, PartialEq)]
pub struct EvalPoints {
    /// Lattice spacing (mm) the points were built with.
    pub spacing_mm: f64,
    /// Rest (source) positions (mm).
    pub rest: Vec<Vector3<f64>>,
    /// Incision side: 0 away from the crack (a tetrahedron without a duplicated node), 1 or 2.
    pub side: Vec<u8>,
    /// Lattice or crack-face point.
    pub kind: Vec<PointKind>,
    /// The case tetrahedron that holds the point (on its own side) and the point's barycentric weights in it.
    pub element: Vec<(usize, [f64; 4])>,
    /// Ground-truth deformed position (mm): the TET10 field interpolated in `element`.
    pub ground_truth: Vec<Vector3<f64>>,
    /// Distance (mm) to the continuous source lip polylines (both lips' mouths at rest).
    pub d_lip_mm: Vec<f64>,
    /// Distance (mm) to the true crack surface at rest.
    pub d_crack_mm: Vec<f64>,
}

/// The lattice's offset from the mesh's lowest corner, in spacings: a general position, so the evaluation
/// lattice coincides with no particle lattice (whose origin is the lowest corner itself).
const LATTICE_OFFSET: [f64; 3] = [0.31, 0.53, 0.71];

/// How far (mm) a lip polyline may stray outside the organ mesh before it is refused.
pub const LIP_TOLERANCE_MM: f64 = 1e-6;

impl EvalPoints {
    /// Build the points of `case`: a `spacing_mm` lattice inside the rest mesh, crack-face points at about the
    /// same density on both sides, the ground truth from `case.ground_truth_p2` (TET10, when present; else the
    /// P1 field of `case.ground_truth`), and both distances.
    pub fn build(case: &BenchmarkCase, spacing_mm: f64) -> Result<EvalPoints> {
        if !(spacing_mm.is_finite() && spacing_mm > 0.0) {
            return Err(RegisterError::param("evaluation spacing_mm", spacing_mm, "must be finite and > 0"));
        }
        case.validate()?;
        let lips = lip_polylines(case)?;
        let tside = tet_sides(&case.tets, &case.node_side);
        let lo = case.rest.iter().fold(case.rest[0], |a, b| a.inf(b));
        let hi = case.rest.iter().fold(case.rest[0], |a, b| a.sup(b));
        let cells = ((hi - lo) / spacing_mm).iter().map(|c| c + 1.0).product::<f64>();
        if cells > 5e7 {
            return Err(RegisterError::param(
                "evaluation spacing_mm",
                spacing_mm,
                format!("{cells:.2e} lattice cells over the organ's bounding box (at most 5e7)"),
            ));
        }
        let origin = lo + Vector3::from(LATTICE_OFFSET) * spacing_mm;
        let mut rest = Vec::new();
        let mut side = Vec::new();
        let mut kind = Vec::new();
        let mut element = Vec::new();
        for (x, t) in sample_lattice(&case.rest, &case.tets, &origin, spacing_mm) {
            let w = barycentric(&case.tets[t].map(|i| case.rest[i]), &x);
            rest.push(x);
            side.push(tside[t]);
            kind.push(PointKind::Lattice);
            element.push((t, w));
        }
        // crack faces: each rest face pair once per side, sampled at about one point per spacing²
        for (t, f, s) in crack_faces_by_side(case, &tside) {
            let c = f.map(|i| case.rest[i]);
            let area = 0.5 * (c[1] - c[0]).cross(&(c[2] - c[0])).norm();
            let k = ((area.sqrt() / spacing_mm).ceil() as usize).max(1);
            for (a, b) in sub_triangle_centroids(k) {
                let x = c[0] + (c[1] - c[0]) * a + (c[2] - c[0]) * b;
                let w = barycentric(&case.tets[t].map(|i| case.rest[i]), &x);
                rest.push(x);
                side.push(s);
                kind.push(PointKind::CrackFace);
                element.push((t, w));
            }
        }
        let ground_truth = ground_truth_at(case, &element)?;
        let d_lip_mm = rest.iter().map(|x| lips.iter().map(|l| l.distance(x)).fold(f64::INFINITY, f64::min)).collect();
        let crack = true_crack(&case.rest, &case.tets, &case.node_side);
        let d_crack_mm = if crack.faces.is_empty() {
            vec![f64::INFINITY; rest.len()]
        } else {
            let surf = TriangleSurface::new(crack.vertices, crack.faces);
            rest.iter().map(|x| surf.distance(x)).collect()
        };
        Ok(EvalPoints { spacing_mm, rest, side, kind, element, ground_truth, d_lip_mm, d_crack_mm })
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.rest.len()
    }

    /// True without points.
    pub fn is_empty(&self) -> bool {
        self.rest.is_empty()
    }

    /// A nodal field of the case's mesh (`nodes`: one position per node, mm) interpolated linearly (P1) at
    /// every point in its own element: how a mesh method is read.
    pub fn p1(&self, nodes: &[Vector3<f64>], tets: &[[usize; 4]]) -> Vec<Vector3<f64>> {
        self.element.iter().map(|(t, w)| tets[*t].iter().zip(w).map(|(&i, &w)| nodes[i] * w).sum()).collect()
    }

    /// The same points read in another mesh of the same organ (the methods' independent mesh): each point's
    /// element becomes the tetrahedron of `case` that holds it on its own side
    /// ([`super::convergence::locate_on_side`]); the ground truth and the distances stay. Points farther than
    /// `tolerance_mm` outside `case`'s mesh (the two meshes approximate the surface differently) are dropped;
    /// returns the points and how many were dropped.
    pub fn relocated(&self, case: &BenchmarkCase, tolerance_mm: f64) -> Result<(EvalPoints, usize)> {
        let loc = super::convergence::locate_on_side(case, &self.queries(), tolerance_mm)?;
        let keep: Vec<usize> = (0..self.len()).filter(|&i| loc[i].is_some()).collect();
        let pick = |i: &usize| *i;
        let out = EvalPoints {
            spacing_mm: self.spacing_mm,
            rest: keep.iter().map(|i| self.rest[pick(i)]).collect(),
            side: keep.iter().map(|i| self.side[*i]).collect(),
            kind: keep.iter().map(|i| self.kind[*i]).collect(),
            element: keep.iter().filter_map(|i| loc[*i].map(|l| l.element)).collect(),
            ground_truth: keep.iter().map(|i| self.ground_truth[*i]).collect(),
            d_lip_mm: keep.iter().map(|i| self.d_lip_mm[*i]).collect(),
            d_crack_mm: keep.iter().map(|i| self.d_crack_mm[*i]).collect(),
        };
        Ok((out, self.len() - keep.len()))
    }

    /// The points as (rest position, side) queries.
    pub fn queries(&self) -> Vec<(Vector3<f64>, u8)> {
        self.rest.iter().copied().zip(self.side.iter().copied()).collect()
    }
}

/// Barycentric weights of `x` in the tetrahedron with corners `c` (not clamped).
fn barycentric(c: &[Vector3<f64>; 4], x: &Vector3<f64>) -> [f64; 4] {
    let l = Matrix3::from_columns(&[c[1] - c[0], c[2] - c[0], c[3] - c[0]])
        .try_inverse()
        .map_or_else(Vector3::zeros, |m| m * (x - c[0]));
    [1.0 - l.sum(), l.x, l.y, l.z]
}

/// The centroids of the k² sub-triangles of a triangle split k times along each edge, as (a, b) with the
/// point c₀ + a (c₁ − c₀) + b (c₂ − c₀).
fn sub_triangle_centroids(k: usize) -> Vec<(f64, f64)> {
    let h = 1.0 / k as f64;
    let mut out = Vec::with_capacity(k * k);
    for i in 0..k {
        for j in 0..k - i {
            // upward triangle (i, j), (i+1, j), (i, j+1)
            out.push(((i as f64 + 1.0 / 3.0) * h, (j as f64 + 1.0 / 3.0) * h));
            if i + j + 1 < k {
                // downward triangle (i+1, j), (i, j+1), (i+1, j+1)
                out.push(((i as f64 + 2.0 / 3.0) * h, (j as f64 + 2.0 / 3.0) * h));
            }
        }
    }
    out
}

/// The crack faces of each side: (tetrahedron, face, side) for every boundary face that coincides at rest
/// with another boundary face (the two lips of the crack), the side being its tetrahedron's.
fn crack_faces_by_side(case: &BenchmarkCase, tside: &[u8]) -> Vec<(usize, [usize; 3], u8)> {
    let face = |t: &[usize; 4], skip: usize| -> [usize; 3] {
        let f: Vec<usize> = (0..4).filter(|&k| k != skip).map(|k| t[k]).collect();
        [f[0], f[1], f[2]]
    };
    let mut count: HashMap<[usize; 3], usize> = HashMap::new();
    for t in &case.tets {
        for skip in 0..4 {
            let mut f = face(t, skip);
            f.sort_unstable();
            *count.entry(f).or_default() += 1;
        }
    }
    let pos_key = |f: &[usize; 3]| {
        let mut k: Vec<[u64; 3]> = f.iter().map(|&i| case.rest[i].map(f64::to_bits).into()).collect();
        k.sort_unstable();
        k
    };
    let mut boundary = Vec::new();
    let mut by_pos: HashMap<Vec<[u64; 3]>, usize> = HashMap::new();
    for (ti, t) in case.tets.iter().enumerate() {
        for skip in 0..4 {
            let f = face(t, skip);
            let mut s = f;
            s.sort_unstable();
            if count[&s] == 1 {
                *by_pos.entry(pos_key(&f)).or_default() += 1;
                boundary.push((ti, f));
            }
        }
    }
    boundary
        .into_iter()
        .filter(|(ti, f)| by_pos[&pos_key(f)] == 2 && tside[*ti] != 0)
        .map(|(ti, f)| (ti, f, tside[ti]))
        .collect()
}

/// The two lips' mouths at rest as continuous polylines; a lip that leaves the organ (a vertex off the mesh)
/// is refused, naming it.
pub fn lip_polylines(case: &BenchmarkCase) -> Result<Vec<Polyline<3>>> {
    let mesh = laparo_core::mesh::TetMesh { vertices: case.rest.clone(), tets: case.tets.clone() };
    let locator = crate::baselines::TetLocator::new(&mesh);
    let mut out = Vec::new();
    for (k, lip) in case.lips.iter().enumerate() {
        let what = format!("benchmark case `{}`: lip {} polyline", case.scenario, k + 1);
        if lip.len() < 2 {
            return Err(RegisterError::bad(what, format!("{} vertices (need ≥ 2)", lip.len())));
        }
        let v: Vec<Vector3<f64>> = lip.iter().map(|&i| case.rest[i]).collect();
        // every vertex and every segment's midpoint must lie in (or on) the organ
        for (j, p) in v.iter().enumerate() {
            locator.locate(p, LIP_TOLERANCE_MM, &format!("{what} (vertex {j}: it leaves the organ)"))?;
        }
        for (j, w) in v.windows(2).enumerate() {
            let m = 0.5 * (w[0] + w[1]);
            locator.locate(&m, LIP_TOLERANCE_MM, &format!("{what} (segment {j}: it leaves the organ)"))?;
        }
        out.push(Polyline::open(v));
    }
    Ok(out)
}

/// The ground truth at points given by (case tetrahedron, barycentric weights): the TET10 field
/// `case.ground_truth_p2` (displacements of every TET10 node, mm) when present, else the P1 field of the
/// vertex positions `case.ground_truth`.
pub fn ground_truth_at(case: &BenchmarkCase, element: &[(usize, [f64; 4])]) -> Result<Vec<Vector3<f64>>> {
    let Some(u2) = &case.ground_truth_p2 else {
        return Ok(element
            .iter()
            .map(|(t, w)| case.tets[*t].iter().zip(w).map(|(&i, &w)| case.ground_truth[i] * w).sum())
            .collect());
    };
    let mesh = laparo_core::mesh::TetMesh { vertices: case.rest.clone(), tets: case.tets.clone() };
    let t10 = laparo_fem::solid::Tet10Mesh::from_linear(&mesh)
        .map_err(|e| RegisterError::bad(format!("benchmark case `{}`: TET10 mesh", case.scenario), e.to_string()))?;
    if u2.len() != t10.n_nodes() {
        return Err(RegisterError::bad(
            format!("benchmark case `{}`: TET10 ground truth", case.scenario),
            format!("{} displacements for {} TET10 nodes", u2.len(), t10.n_nodes()),
        ));
    }
    Ok(element
        .iter()
        .map(|(t, w)| {
            let x: Vector3<f64> = case.tets[*t].iter().zip(w).map(|(&i, &w)| case.rest[i] * w).sum();
            x + t10.interpolate(*t, &Vector3::new(w[1], w[2], w[3]), u2)
        })
        .collect())
}

/// The ground truth of `gt` (TET10 when it has it) at `queries` (rest position mm, side) given in another mesh of
/// the same organ: each read in `gt`'s tetrahedron that holds it on its own side, extrapolated from the nearest
/// one for a query outside `gt`'s mesh by at most `tolerance_mm`; farther out is an error naming the query.
pub fn ground_truth_of(
    gt: &BenchmarkCase,
    queries: &[(Vector3<f64>, u8)],
    tolerance_mm: f64,
) -> Result<Vec<Vector3<f64>>> {
    let loc = super::convergence::locate_on_side(gt, queries, tolerance_mm)?;
    let mut element = Vec::with_capacity(queries.len());
    for (i, l) in loc.iter().enumerate() {
        let Some(l) = l else {
            return Err(RegisterError::bad(
                format!("benchmark case `{}`: point {i} of the methods' mesh", gt.scenario),
                format!(
                    "{:?} lies more than {tolerance_mm} mm outside the ground truth's mesh",
                    queries[i].0.as_slice()
                ),
            ));
        };
        element.push(l.element);
    }
    ground_truth_at(gt, &element)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sub_triangles_cover_the_triangle_once() {
        for k in 1..6 {
            let c = sub_triangle_centroids(k);
            assert_eq!(c.len(), k * k);
            // the centroids of a uniform split average to the triangle's centroid
            let m = c.iter().fold((0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
            assert!(
                (m.0 / c.len() as f64 - 1.0 / 3.0).abs() < 1e-12 && (m.1 / c.len() as f64 - 1.0 / 3.0).abs() < 1e-12
            );
            assert!(c.iter().all(|&(a, b)| a > 0.0 && b > 0.0 && a + b < 1.0));
        }
    }
}
