//! Quadratic tetrahedra (TET10) built from a linear [`TetMesh`] by adding one node at the middle of
//! every edge (straight-sided elements, affine geometry map).
use super::quadrature::TET10_EDGES;
use crate::error::{FemError, Result};
use laparo_core::mesh::TetMesh;
use nalgebra::{Matrix3, Vector3};
use std::collections::HashMap;

/// A TET10 mesh (mm). Nodes `0..n_vertices` are the linear mesh's vertices (same ids), the rest are
/// mid-edge nodes.
#[derive(Clone, Debug)]
pub struct Tet10Mesh {
    /// Reference node positions (mm).
    pub nodes: Vec<Vector3<f64>>,
    /// Number of linear vertices (the first nodes).
    pub n_vertices: usize,
    /// Elements in VTK_QUADRATIC_TETRA order (see [`TET10_EDGES`]), positively oriented.
    pub elements: Vec<[usize; 10]>,
    /// Mid-edge node of each linear edge (key: sorted vertex pair).
    pub edge_nodes: HashMap<(usize, usize), usize>,
    /// Per element: inverse of the (constant) Jacobian ∂X/∂ξ, used for ∇_X N = ∇_ξ N · J⁻¹.
    pub(crate) jac_inv: Vec<Matrix3<f64>>,
    /// Per element: det ∂X/∂ξ = 6 × volume (mm³).
    pub(crate) jac_det: Vec<f64>,
}

fn key(a: usize, b: usize) -> (usize, usize) {
    if a < b {
        (a, b)
    } else {
        (b, a)
    }
}

/// Refuse duplicated tetrahedra ([`FemError::DuplicateElement`]) and tetrahedra folded over a
/// neighbour ([`FemError::InvertedElement`]: two tetrahedra sharing a face on the same side of it, or
/// a face shared by more than two). A consistent global orientation is not required (from_linear
/// reorders negative tets); what is refused is an overlap, whatever the convention.
pub fn check_elements(mesh: &TetMesh) -> Result<()> {
    use rayon::slice::ParallelSliceMut;
    // (sorted face, tet, opposite vertex) for every face of every tet; a face's tets are adjacent after sorting.
    let mut faces: Vec<([usize; 3], usize, usize)> = Vec::with_capacity(4 * mesh.tets.len());
    for (ti, t) in mesh.tets.iter().enumerate() {
        for j in 0..4 {
            let mut f = [t[(j + 1) % 4], t[(j + 2) % 4], t[(j + 3) % 4]];
            f.sort_unstable();
            faces.push((f, ti, t[j]));
        }
    }
    faces.par_sort_unstable();
    let x = &mesh.vertices;
    let side = |f: &[usize; 3], o: usize| (x[f[1]] - x[f[0]]).cross(&(x[f[2]] - x[f[0]])).dot(&(x[o] - x[f[0]]));
    for g in faces.chunk_by(|a, b| a.0 == b.0) {
        for (k, &(f, tb, ob)) in g.iter().enumerate().skip(1) {
            for &(_, ta, oa) in &g[..k] {
                if oa == ob {
                    let (first, second) = (ta.min(tb), ta.max(tb));
                    return Err(FemError::DuplicateElement { first, second, vertices: mesh.tets[second] });
                }
                if side(&f, oa) * side(&f, ob) >= 0.0 {
                    return Err(FemError::InvertedElement { first: ta.min(tb), second: ta.max(tb), face: f });
                }
            }
            if k >= 2 {
                // Three tetrahedra on one face: two of them overlap (caught above unless degenerate).
                return Err(FemError::InvertedElement { first: g[0].1, second: tb, face: f });
            }
        }
    }
    Ok(())
}

impl Tet10Mesh {
    /// Build the TET10 mesh; negatively oriented tets are reordered; degenerate, duplicated and
    /// inverted (folded) ones are an error ([`check_elements`]).
    pub fn from_linear(mesh: &TetMesh) -> Result<Self> {
        if mesh.tets.is_empty() {
            return Err(FemError::bad("tet mesh", "has no tetrahedra"));
        }
        mesh.validate().map_err(FemError::from)?;
        let mut nodes = mesh.vertices.clone();
        let n_vertices = nodes.len();
        let mut edge_nodes = HashMap::new();
        let mut elements = Vec::with_capacity(mesh.tets.len());
        let (mut jac_inv, mut jac_det) = (Vec::new(), Vec::new());
        let scale = mesh.bounding_box().map(|(lo, hi)| (hi - lo).norm()).filter(|d| *d > 0.0).unwrap_or(1.0);
        for (ti, t) in mesh.tets.iter().enumerate() {
            let mut v = *t;
            let x = |i: usize| mesh.vertices[i];
            let mut j = Matrix3::from_columns(&[x(v[1]) - x(v[0]), x(v[2]) - x(v[0]), x(v[3]) - x(v[0])]);
            let mut det = j.determinant();
            if det.is_nan() || det.abs() <= 1e-12 * scale.powi(3) {
                return Err(FemError::bad(
                    "tet mesh",
                    format!("tetrahedron {ti} {t:?} is degenerate (volume {:.3e} mm³)", det / 6.0),
                ));
            }
            if det < 0.0 {
                v.swap(1, 2);
                j = Matrix3::from_columns(&[x(v[1]) - x(v[0]), x(v[2]) - x(v[0]), x(v[3]) - x(v[0])]);
                det = -det;
            }
            let mut el = [0usize; 10];
            el[..4].copy_from_slice(&v);
            for (e, &(a, b)) in TET10_EDGES.iter().enumerate() {
                let k = key(v[a], v[b]);
                let id = *edge_nodes.entry(k).or_insert_with(|| {
                    nodes.push((mesh.vertices[k.0] + mesh.vertices[k.1]) * 0.5);
                    nodes.len() - 1
                });
                el[4 + e] = id;
            }
            elements.push(el);
            jac_inv.push(
                j.try_inverse().ok_or_else(|| FemError::bad("tet mesh", format!("tetrahedron {ti} is singular")))?,
            );
            jac_det.push(det);
        }
        check_elements(mesh)?;
        Ok(Self { nodes, n_vertices, elements, edge_nodes, jac_inv, jac_det })
    }

    /// Number of nodes (vertices + mid-edge nodes).
    pub fn n_nodes(&self) -> usize {
        self.nodes.len()
    }

    /// Mid-edge node between linear vertices `a` and `b`, if that edge exists.
    pub fn edge_node(&self, a: usize, b: usize) -> Option<usize> {
        self.edge_nodes.get(&key(a, b)).copied()
    }

    /// The six nodes of a linear boundary triangle: its vertices then the mid-edge nodes of
    /// (0,1), (1,2), (2,0); an error if an edge is not in the mesh.
    pub fn face_nodes(&self, face: [usize; 3]) -> Result<[usize; 6]> {
        let mut out = [face[0], face[1], face[2], 0, 0, 0];
        for (k, (a, b)) in [(0, 1), (1, 2), (2, 0)].into_iter().enumerate() {
            out[3 + k] = self.edge_node(face[a], face[b]).ok_or_else(|| {
                FemError::bad(
                    "face",
                    format!("{face:?}: edge ({}, {}) is not an edge of the tet mesh", face[a], face[b]),
                )
            })?;
        }
        Ok(out)
    }

    /// Volume of element `e` (mm³).
    pub fn element_volume(&self, e: usize) -> f64 {
        self.jac_det[e] / 6.0
    }

    /// Interpolate a nodal field at reference point ξ of element `e`.
    pub fn interpolate(&self, e: usize, xi: &Vector3<f64>, field: &[Vector3<f64>]) -> Vector3<f64> {
        let n = super::quadrature::tet10_shape(xi);
        self.elements[e].iter().zip(n.iter()).map(|(&a, &w)| field[a] * w).sum()
    }

    /// Reference position (mm) of reference point ξ in element `e`.
    pub fn position(&self, e: usize, xi: &Vector3<f64>) -> Vector3<f64> {
        let el = &self.elements[e];
        let x0 = self.nodes[el[0]];
        x0 + (self.nodes[el[1]] - x0) * xi.x + (self.nodes[el[2]] - x0) * xi.y + (self.nodes[el[3]] - x0) * xi.z
    }
}
