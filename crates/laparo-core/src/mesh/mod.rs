//! Triangle surface meshes and tetrahedral volume meshes, with readers and writers.
//!
//! | format | read | write | notes |
//! |---|---|---|---|
//! | Wavefront OBJ | [`read_obj`] | [`write_obj`] | `v`/`f` (with `/` texture/normal indices, negative indices); polygons fan-triangulated |
//! | PLY | [`read_ply`], [`read_ply_with_colors`] | [`write_ply`], [`write_ply_with`] | ascii, binary little/big endian; any numeric property type; optional RGB per vertex |
//! | STL | [`read_stl`] | [`write_stl`] | ascii and binary; identical corner positions are merged into shared vertices |
//! | Gmsh `.msh` | [`read_msh`], [`read_msh_mixed`] | [`write_msh`] | ASCII v1 and v2; tetrahedra (type 4, corners of type 11) and triangles (type 2, corners of type 9) |
//! | legacy VTK | [`read_vtk`], [`read_vtk_mixed`] | [`write_vtk`] | ASCII UNSTRUCTURED_GRID (also 5.1 OFFSETS/CONNECTIVITY) and POLYDATA |
//!
//! Readers reject corrupt content (non-finite coordinates, out-of-range indices, truncation) with
//! an error naming the file and line; they do not reject degenerate faces, which real meshes
//! contain: call [`TriMesh::validate`] where that matters. Units are whatever the file uses
//! (OBJ/PLY/STL carry none): document them at the call site.
//!
//! Hand-written: the OBJ/PLY/STL crates each bring their own mesh types and none reads Gmsh or
//! legacy VTK; these formats are short and this keeps one `TriMesh`/`TetMesh` for the project.
mod msh;
mod obj;
mod ply;
mod stl;
mod vtk;

pub use msh::{read_msh, read_msh_mixed, write_msh};
pub use obj::{read_obj, write_obj};
pub use ply::{read_ply, read_ply_with_colors, write_ply, write_ply_with, PlyEncoding};
pub use stl::{read_stl, write_stl};
pub use vtk::{read_vtk, read_vtk_mixed, write_vtk, write_vtk_fields, VtkField, VtkValues};

use crate::error::{CoreError, Result};
use crate::se3::Se3;
use nalgebra::{Point3, Vector3};
use std::collections::HashMap;
use std::path::Path;

/// A triangle surface mesh. Faces index `vertices`; counter-clockwise seen from outside
/// (right-hand rule) gives outward normals.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriMesh {
    /// Vertex positions (the file's unit, usually mm).
    pub vertices: Vec<Vector3<f64>>,
    /// Triangles as vertex indices, counter-clockwise seen from outside.
    pub faces: Vec<[usize; 3]>,
}

/// A tetrahedral volume mesh.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TetMesh {
    /// Vertex positions (the file's unit, usually mm).
    pub vertices: Vec<Vector3<f64>>,
    /// Tetrahedra as vertex indices.
    pub tets: Vec<[usize; 4]>,
}

/// Triangles and tetrahedra of one file (Gmsh, VTK), with their physical/cell tags (0 if none).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MixedMesh {
    /// Vertex positions (the file's unit).
    pub vertices: Vec<Vector3<f64>>,
    /// Surface triangles as vertex indices.
    pub triangles: Vec<[usize; 3]>,
    /// Physical tag of each triangle (Gmsh physical group; 0 if none).
    pub triangle_tags: Vec<i64>,
    /// Tetrahedra as vertex indices.
    pub tets: Vec<[usize; 4]>,
    /// Physical tag of each tetrahedron (0 if none).
    pub tet_tags: Vec<i64>,
}

impl MixedMesh {
    /// The tetrahedra as a [`TetMesh`] (all vertices kept).
    pub fn tet_mesh(&self) -> TetMesh {
        TetMesh { vertices: self.vertices.clone(), tets: self.tets.clone() }
    }
    /// The triangles as a [`TriMesh`] (all vertices kept).
    pub fn tri_mesh(&self) -> TriMesh {
        TriMesh { vertices: self.vertices.clone(), faces: self.triangles.clone() }
    }
}

/// Length of the bounding-box diagonal (scale for relative tolerances), at least 1e-300.
fn scale_of(v: &[Vector3<f64>]) -> f64 {
    match bbox(v) {
        Some((a, b)) => (b - a).norm().max(1e-300),
        None => 1.0,
    }
}

fn bbox(v: &[Vector3<f64>]) -> Option<(Vector3<f64>, Vector3<f64>)> {
    let first = *v.first()?;
    Some(v.iter().fold((first, first), |(lo, hi), p| (lo.inf(p), hi.sup(p))))
}

fn check_vertices(v: &[Vector3<f64>]) -> Result<()> {
    if let Some(i) = v.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
        return Err(CoreError::invalid("mesh", format!("vertex {i} is not finite: {:?}", v[i].as_slice())));
    }
    Ok(())
}

impl TriMesh {
    /// The axis-aligned box `[lo, hi]` as 12 outward triangles (volume Π(hi − lo)), 8 vertices
    /// indexed by the bits (x, y, z) of 0..8.
    pub fn cuboid(lo: &Vector3<f64>, hi: &Vector3<f64>) -> TriMesh {
        let v: Vec<Vector3<f64>> = (0..8)
            .map(|i| {
                Vector3::new(
                    if i & 1 == 0 { lo.x } else { hi.x },
                    if (i >> 1) & 1 == 0 { lo.y } else { hi.y },
                    if (i >> 2) & 1 == 0 { lo.z } else { hi.z },
                )
            })
            .collect();
        let f = vec![
            [0, 2, 1],
            [1, 2, 3],
            [4, 5, 6],
            [5, 7, 6],
            [0, 1, 4],
            [1, 5, 4],
            [2, 6, 3],
            [3, 6, 7],
            [0, 4, 2],
            [2, 4, 6],
            [1, 3, 5],
            [3, 7, 5],
        ];
        TriMesh { vertices: v, faces: f }
    }

    /// Build and [`validate`](Self::validate) a mesh.
    pub fn new(vertices: Vec<Vector3<f64>>, faces: Vec<[usize; 3]>) -> Result<Self> {
        let m = TriMesh { vertices, faces };
        m.validate()?;
        Ok(m)
    }

    /// Reject non-finite vertices, out-of-range indices and degenerate faces (a repeated index or
    /// an area below 1e-12 × the squared bounding-box diagonal).
    pub fn validate(&self) -> Result<()> {
        check_vertices(&self.vertices)?;
        let n = self.vertices.len();
        let tol = 1e-12 * scale_of(&self.vertices).powi(2);
        for (i, f) in self.faces.iter().enumerate() {
            if let Some(&bad) = f.iter().find(|&&k| k >= n) {
                return Err(CoreError::invalid("mesh", format!("face {i} uses vertex {bad}, the mesh has {n}")));
            }
            if f[0] == f[1] || f[1] == f[2] || f[0] == f[2] {
                return Err(CoreError::invalid("mesh", format!("face {i} repeats a vertex: {f:?}")));
            }
            if self.face_area(i) <= tol {
                return Err(CoreError::invalid("mesh", format!("face {i} {f:?} has zero area")));
            }
        }
        Ok(())
    }

    /// Unnormalised normal (p1 − p0) × (p2 − p0) of face `i` (its length is twice the area).
    pub fn face_cross(&self, i: usize) -> Vector3<f64> {
        let [a, b, c] = self.faces[i];
        (self.vertices[b] - self.vertices[a]).cross(&(self.vertices[c] - self.vertices[a]))
    }

    /// Unit normal of face `i` (zero vector for a degenerate face).
    pub fn face_normal(&self, i: usize) -> Vector3<f64> {
        self.face_cross(i).try_normalize(0.0).unwrap_or_else(Vector3::zeros)
    }

    /// Area of face `i`.
    pub fn face_area(&self, i: usize) -> f64 {
        0.5 * self.face_cross(i).norm()
    }

    /// Unit face normals.
    pub fn face_normals(&self) -> Vec<Vector3<f64>> {
        (0..self.faces.len()).map(|i| self.face_normal(i)).collect()
    }

    /// Area-weighted unit vertex normals (zero for vertices in no face).
    pub fn vertex_normals(&self) -> Vec<Vector3<f64>> {
        let mut n = vec![Vector3::zeros(); self.vertices.len()];
        for (i, f) in self.faces.iter().enumerate() {
            let c = self.face_cross(i);
            for &k in f {
                n[k] += c;
            }
        }
        n.into_iter().map(|v| v.try_normalize(0.0).unwrap_or_else(Vector3::zeros)).collect()
    }

    /// Total surface area.
    pub fn area(&self) -> f64 {
        (0..self.faces.len()).map(|i| self.face_area(i)).sum()
    }

    /// Signed enclosed volume (divergence theorem, eq. Σ p0·(p1×p2)/6); positive for a closed mesh
    /// with outward normals.
    pub fn signed_volume(&self) -> f64 {
        self.faces
            .iter()
            .map(|&[a, b, c]| self.vertices[a].dot(&self.vertices[b].cross(&self.vertices[c])))
            .sum::<f64>()
            / 6.0
    }

    /// Centroid of the enclosed solid (same units as the vertices): the volume-weighted centroids
    /// of the tetrahedra (origin, p0, p1, p2), Σ v_f (p0 + p1 + p2) / 4 / Σ v_f.
    pub fn volume_centroid(&self) -> Vector3<f64> {
        let mut vol = 0.0;
        let mut c = Vector3::zeros();
        for f in &self.faces {
            let (a, b, d) = (self.vertices[f[0]], self.vertices[f[1]], self.vertices[f[2]]);
            let v = a.dot(&b.cross(&d)) / 6.0;
            vol += v;
            c += v * (a + b + d) / 4.0;
        }
        c / vol
    }

    /// Axis-aligned bounding box `(min, max)`, `None` for an empty mesh.
    pub fn bounding_box(&self) -> Option<(Vector3<f64>, Vector3<f64>)> {
        bbox(&self.vertices)
    }

    /// How many faces use each undirected edge `(min, max)`.
    pub fn edge_face_counts(&self) -> HashMap<(usize, usize), usize> {
        let mut m = HashMap::with_capacity(self.faces.len() * 3 / 2);
        for f in &self.faces {
            for k in 0..3 {
                let (a, b) = (f[k], f[(k + 1) % 3]);
                *m.entry((a.min(b), a.max(b))).or_insert(0) += 1;
            }
        }
        m
    }

    /// Edges used by exactly one face (the holes' rims).
    pub fn boundary_edges(&self) -> Vec<(usize, usize)> {
        let mut e: Vec<_> = self.edge_face_counts().into_iter().filter(|&(_, c)| c == 1).map(|(e, _)| e).collect();
        e.sort_unstable();
        e
    }

    /// Closed and edge-manifold: every edge is shared by exactly two faces (and there is a face).
    pub fn is_closed(&self) -> bool {
        !self.faces.is_empty() && self.edge_face_counts().values().all(|&c| c == 2)
    }

    /// Every directed edge occurs at most once, i.e. neighbouring faces have consistent winding.
    pub fn is_consistently_oriented(&self) -> bool {
        let mut seen = std::collections::HashSet::with_capacity(self.faces.len() * 3);
        self.faces.iter().all(|f| (0..3).all(|k| seen.insert((f[k], f[(k + 1) % 3]))))
    }

    /// The mesh with every vertex mapped by `t` (p ↦ R p + t).
    pub fn transformed(&self, t: &Se3) -> TriMesh {
        TriMesh {
            vertices: self.vertices.iter().map(|v| (t * Point3::from(*v)).coords).collect(),
            faces: self.faces.clone(),
        }
    }

    /// The mesh with every coordinate multiplied by `s` (e.g. 10 for cm → mm).
    pub fn scaled(&self, s: f64) -> TriMesh {
        TriMesh { vertices: self.vertices.iter().map(|v| v * s).collect(), faces: self.faces.clone() }
    }

    /// Drop vertices used by no face, renumbering the faces.
    pub fn without_unused_vertices(&self) -> TriMesh {
        let mut map = vec![usize::MAX; self.vertices.len()];
        let mut vertices = Vec::new();
        let faces = self
            .faces
            .iter()
            .map(|f| {
                f.map(|k| {
                    if map[k] == usize::MAX {
                        map[k] = vertices.len();
                        vertices.push(self.vertices[k]);
                    }
                    map[k]
                })
            })
            .collect();
        TriMesh { vertices, faces }
    }
}

impl TetMesh {
    /// Build and [`validate`](Self::validate) a mesh.
    pub fn new(vertices: Vec<Vector3<f64>>, tets: Vec<[usize; 4]>) -> Result<Self> {
        let m = TetMesh { vertices, tets };
        m.validate()?;
        Ok(m)
    }

    /// Reject non-finite vertices, out-of-range indices and degenerate tetrahedra (a repeated
    /// index or |volume| below 1e-15 × the cubed bounding-box diagonal).
    pub fn validate(&self) -> Result<()> {
        check_vertices(&self.vertices)?;
        let n = self.vertices.len();
        let tol = 1e-15 * scale_of(&self.vertices).powi(3);
        for (i, t) in self.tets.iter().enumerate() {
            if let Some(&bad) = t.iter().find(|&&k| k >= n) {
                return Err(CoreError::invalid("tet mesh", format!("tet {i} uses vertex {bad}, the mesh has {n}")));
            }
            if (0..4).any(|a| (a + 1..4).any(|b| t[a] == t[b])) {
                return Err(CoreError::invalid("tet mesh", format!("tet {i} repeats a vertex: {t:?}")));
            }
            if self.tet_volume(i).abs() <= tol {
                return Err(CoreError::invalid("tet mesh", format!("tet {i} {t:?} has zero volume")));
            }
        }
        Ok(())
    }

    /// Signed volume of tet `i`: (p1 − p0) · ((p2 − p0) × (p3 − p0)) / 6, positive when p3 is on
    /// the side of triangle (p0, p1, p2) its right-hand normal points to.
    pub fn tet_volume(&self, i: usize) -> f64 {
        let [a, b, c, d] = self.tets[i];
        let p = &self.vertices;
        (p[b] - p[a]).dot(&(p[c] - p[a]).cross(&(p[d] - p[a]))) / 6.0
    }

    /// Sum of |tet volumes|.
    pub fn volume(&self) -> f64 {
        (0..self.tets.len()).map(|i| self.tet_volume(i).abs()).sum()
    }

    /// Swap two vertices of every negatively oriented tet so that all volumes are positive.
    pub fn orient_positive(&mut self) {
        for i in 0..self.tets.len() {
            if self.tet_volume(i) < 0.0 {
                self.tets[i].swap(2, 3);
            }
        }
    }

    /// Axis-aligned bounding box `(min, max)`, `None` for an empty mesh.
    pub fn bounding_box(&self) -> Option<(Vector3<f64>, Vector3<f64>)> {
        bbox(&self.vertices)
    }

    /// The boundary surface: faces belonging to exactly one tet, oriented outward (for positively
    /// and negatively oriented tets alike). Vertices are shared with the tet mesh (unused ones kept).
    pub fn boundary(&self) -> TriMesh {
        let mut count: HashMap<[usize; 3], (usize, [usize; 3])> = HashMap::new();
        for (i, t) in self.tets.iter().enumerate() {
            // Faces opposite each vertex, wound outward for a positive tet.
            let faces = [[t[1], t[2], t[3]], [t[0], t[3], t[2]], [t[0], t[1], t[3]], [t[0], t[2], t[1]]];
            let flip = self.tet_volume(i) < 0.0;
            for f in faces {
                let f = if flip { [f[0], f[2], f[1]] } else { f };
                let mut key = f;
                key.sort_unstable();
                count.entry(key).and_modify(|e| e.0 += 1).or_insert((1, f));
            }
        }
        let mut faces: Vec<[usize; 3]> = count.into_values().filter(|(c, _)| *c == 1).map(|(_, f)| f).collect();
        faces.sort_unstable();
        TriMesh { vertices: self.vertices.clone(), faces }
    }
}

/// Read a surface mesh by extension: `obj`, `ply`, `stl`, or the triangles of a `msh`/`vtk`
/// file (the boundary of its tetrahedra if it has no triangles).
pub fn read_mesh(path: impl AsRef<Path>) -> Result<TriMesh> {
    let path = path.as_ref();
    match crate::io::extension(path).as_str() {
        "obj" => read_obj(path),
        "ply" => read_ply(path),
        "stl" => read_stl(path),
        "msh" | "vtk" => {
            let m = if crate::io::extension(path) == "msh" { read_msh_mixed(path)? } else { read_vtk_mixed(path)? };
            if m.triangles.is_empty() {
                Ok(m.tet_mesh().boundary())
            } else {
                Ok(m.tri_mesh())
            }
        }
        other => Err(CoreError::format(
            path,
            format!("unsupported mesh extension '{other}' (expected obj, ply, stl, msh or vtk)"),
        )),
    }
}

/// Write a surface mesh by extension: `obj`, `ply` (binary), `stl` (binary), atomically.
pub fn write_mesh(path: impl AsRef<Path>, mesh: &TriMesh) -> Result<()> {
    let path = path.as_ref();
    match crate::io::extension(path).as_str() {
        "obj" => write_obj(path, mesh),
        "ply" => write_ply(path, mesh),
        "stl" => write_stl(path, mesh, false),
        other => Err(CoreError::format(path, format!("cannot write a mesh as '{other}' (expected obj, ply or stl)"))),
    }
}

/// Shortest decimal that reads back to the same f64 (used by the text writers).
pub(crate) fn fmt_f64(v: f64) -> String {
    format!("{v:?}")
}

/// Check the indices of faces/cells read from `path` and that the vertices are finite.
pub(crate) fn check_read<const N: usize>(path: &Path, v: &[Vector3<f64>], cells: &[[usize; N]]) -> Result<()> {
    if let Some(i) = v.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
        return Err(CoreError::format(path, format!("vertex {} has a non-finite coordinate", i + 1)));
    }
    let n = v.len();
    for (i, c) in cells.iter().enumerate() {
        if let Some(&bad) = c.iter().find(|&&k| k >= n) {
            return Err(CoreError::format(
                path,
                format!("element {} uses vertex index {bad} (0-based), the file has {n} vertices", i + 1),
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod io_tests;

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A unit cube [0,1]^3 with 12 outward triangles.
    pub fn cube() -> TriMesh {
        TriMesh::cuboid(&Vector3::zeros(), &Vector3::repeat(1.0))
    }

    /// The unit cube split into 5 tetrahedra (volume 1).
    pub fn cube_tets() -> TetMesh {
        let v: Vec<Vector3<f64>> =
            (0..8).map(|i| Vector3::new((i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64)).collect();
        let mut m =
            TetMesh { vertices: v, tets: vec![[0, 1, 2, 4], [1, 3, 2, 7], [1, 4, 5, 7], [2, 6, 4, 7], [1, 2, 4, 7]] };
        m.orient_positive();
        m
    }

    #[test]
    fn cube_geometry_by_hand() {
        let c = cube();
        assert!(c.is_closed());
        assert!(c.is_consistently_oriented());
        assert!((c.area() - 6.0).abs() < 1e-12);
        assert!((c.signed_volume() - 1.0).abs() < 1e-12);
        assert_eq!(c.bounding_box(), Some((Vector3::zeros(), Vector3::new(1.0, 1.0, 1.0))));
        assert_eq!(c.face_normal(0), Vector3::new(0.0, 0.0, -1.0));
        let n = c.vertex_normals()[7];
        assert!((n - Vector3::new(1.0, 1.0, 1.0).normalize()).norm() < 0.2);
        let mut open = c.clone();
        open.faces.pop();
        assert!(!open.is_closed());
        assert_eq!(open.boundary_edges().len(), 3);
        let t = crate::se3::se3_from_rt(&crate::se3::rotation_zyx(0.3, 0.2, 0.1), &Vector3::new(1.0, 2.0, 3.0));
        assert!((c.transformed(&t).signed_volume() - 1.0).abs() < 1e-12);
        assert!((c.scaled(10.0).signed_volume() - 1000.0).abs() < 1e-9);
        // The unit cube's centroid is its centre, wherever the origin is.
        assert!((c.volume_centroid() - Vector3::new(0.5, 0.5, 0.5)).norm() < 1e-12);
        let moved = c.transformed(&t);
        let expect = (t * nalgebra::Point3::new(0.5, 0.5, 0.5)).coords;
        assert!((moved.volume_centroid() - expect).norm() < 1e-12);
    }

    #[test]
    fn validate_rejects_bad_meshes() {
        let mut c = cube();
        c.vertices[0].x = f64::NAN;
        assert!(c.validate().unwrap_err().to_string().contains("not finite"));
        let mut c = cube();
        c.faces[3] = [0, 1, 99];
        assert!(c.validate().unwrap_err().to_string().contains("99"));
        let mut c = cube();
        c.faces[3] = [0, 1, 1];
        assert!(c.validate().is_err());
        let mut c = cube();
        c.vertices.push(Vector3::new(2.0, 0.0, 0.0));
        c.faces[3] = [0, 1, 8]; // collinear
        assert!(c.validate().unwrap_err().to_string().contains("zero area"));
        assert!(TetMesh { vertices: cube().vertices, tets: vec![[0, 1, 2, 3]] }.validate().is_err());
        // coplanar
    }

    #[test]
    fn tet_volume_and_boundary() {
        let t = cube_tets();
        t.validate().unwrap();
        assert!((t.volume() - 1.0).abs() < 1e-12);
        assert!((0..5).all(|i| t.tet_volume(i) > 0.0));
        let b = t.boundary().without_unused_vertices();
        assert_eq!(b.faces.len(), 12);
        assert_eq!(b.vertices.len(), 8);
        assert!(b.is_closed() && b.is_consistently_oriented());
        assert!((b.signed_volume() - 1.0).abs() < 1e-12, "boundary must face outward");
        // a single unit tet: volume 1/6 by hand
        let one = TetMesh {
            vertices: vec![Vector3::zeros(), Vector3::x(), Vector3::y(), Vector3::z()],
            tets: vec![[0, 1, 2, 3]],
        };
        assert!((one.tet_volume(0) - 1.0 / 6.0).abs() < 1e-15);
    }
}
