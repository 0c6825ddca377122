//! Geometric queries on a closed triangle surface: inside/outside (ray parity, majority of three
//! axes), closest point (bucket grid, exact), ray casting; tetrahedron dihedral angles.
use crate::error::{FemError, Result};
use laparo_core::mesh::TriMesh;
use nalgebra::Vector3;

type V3 = Vector3<f64>;

/// Error unless every edge of `mesh` is shared by exactly two triangles; `input` names the mesh.
pub fn check_closed(mesh: &TriMesh, input: &str) -> Result<()> {
    if mesh.faces.is_empty() {
        return Err(FemError::bad(input, "surface has no triangles"));
    }
    let open = mesh.edge_face_counts().values().filter(|&&c| c != 2).count();
    if open > 0 {
        return Err(FemError::bad(
            input,
            format!("not closed: {open} boundary edges (edges not shared by exactly two triangles)"),
        ));
    }
    Ok(())
}

pub use laparo_core::geometry::{closest_point_on_triangle, ray_triangle};

/// All `t ≥ 0` where the ray `o + t d` crosses a triangle of `m`, sorted (brute force).
pub fn ray_hits(m: &TriMesh, o: &V3, d: &V3) -> Vec<f64> {
    let mut ts: Vec<f64> = m
        .faces
        .iter()
        .filter_map(|f| ray_triangle(o, d, &m.vertices[f[0]], &m.vertices[f[1]], &m.vertices[f[2]]))
        .filter(|&t| t >= 0.0)
        .collect();
    ts.sort_by(f64::total_cmp);
    ts
}

/// A 2D bucket grid of triangles projected along one axis, for ray parity along that axis.
struct AxisGrid {
    axis: usize,
    lo: [f64; 2],
    cell: f64,
    n: [usize; 2],
    cells: Vec<Vec<u32>>,
}

impl AxisGrid {
    fn new(mesh: &TriMesh, axis: usize, lo3: &V3, hi3: &V3, cell: f64) -> Self {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        let lo = [lo3[u], lo3[v]];
        let n = [((hi3[u] - lo[0]) / cell).floor() as usize + 1, ((hi3[v] - lo[1]) / cell).floor() as usize + 1];
        let mut cells = vec![Vec::new(); n[0] * n[1]];
        for (fi, f) in mesh.faces.iter().enumerate() {
            let p = f.map(|k| mesh.vertices[k]);
            let (mut a0, mut a1, mut b0, mut b1) = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
            for q in &p {
                a0 = a0.min(q[u]);
                a1 = a1.max(q[u]);
                b0 = b0.min(q[v]);
                b1 = b1.max(q[v]);
            }
            let i0 = ((a0 - lo[0]) / cell).floor().max(0.0) as usize;
            let i1 = (((a1 - lo[0]) / cell).floor() as usize).min(n[0] - 1);
            let j0 = ((b0 - lo[1]) / cell).floor().max(0.0) as usize;
            let j1 = (((b1 - lo[1]) / cell).floor() as usize).min(n[1] - 1);
            for i in i0..=i1 {
                for j in j0..=j1 {
                    cells[i * n[1] + j].push(fi as u32);
                }
            }
        }
        AxisGrid { axis, lo, cell, n, cells }
    }

    /// Parity of the crossings of the ray from `p` towards +axis.
    fn odd(&self, mesh: &TriMesh, p: &V3) -> bool {
        let (ax, u, v) = (self.axis, (self.axis + 1) % 3, (self.axis + 2) % 3);
        let i = ((p[u] - self.lo[0]) / self.cell).floor();
        let j = ((p[v] - self.lo[1]) / self.cell).floor();
        if i < 0.0 || j < 0.0 || i as usize >= self.n[0] || j as usize >= self.n[1] {
            return false;
        }
        let mut odd = false;
        for &fi in &self.cells[i as usize * self.n[1] + j as usize] {
            let f = mesh.faces[fi as usize];
            let (a, b, c) = (mesh.vertices[f[0]], mesh.vertices[f[1]], mesh.vertices[f[2]]);
            let d = (b[u] - a[u]) * (c[v] - a[v]) - (c[u] - a[u]) * (b[v] - a[v]);
            if d == 0.0 {
                continue;
            }
            let s = ((p[u] - a[u]) * (c[v] - a[v]) - (c[u] - a[u]) * (p[v] - a[v])) / d;
            let t = ((b[u] - a[u]) * (p[v] - a[v]) - (p[u] - a[u]) * (b[v] - a[v])) / d;
            if s >= 0.0 && t >= 0.0 && s + t <= 1.0 {
                let x = a[ax] + s * (b[ax] - a[ax]) + t * (c[ax] - a[ax]);
                if x > p[ax] {
                    odd = !odd;
                }
            }
        }
        odd
    }
}

/// A closed triangle surface with acceleration grids for inside tests and closest points (mm).
pub struct Surface {
    /// The surface.
    pub mesh: TriMesh,
    lo: V3,
    cell: f64,
    n: [usize; 3],
    cells: Vec<Vec<u32>>,
    axes: [AxisGrid; 3],
}

impl Surface {
    /// Index a closed surface (checked by [`check_closed`]; `input` names it in errors).
    pub fn new(mesh: TriMesh, input: &str) -> Result<Self> {
        mesh.validate().map_err(|e| FemError::bad(input, e.to_string()))?;
        check_closed(&mesh, input)?;
        let (lo, hi) = mesh.bounding_box().ok_or_else(|| FemError::bad(input, "empty surface"))?;
        let mut total = 0.0;
        let mut count = 0usize;
        for f in &mesh.faces {
            for k in 0..3 {
                total += (mesh.vertices[f[k]] - mesh.vertices[f[(k + 1) % 3]]).norm();
                count += 1;
            }
        }
        let diag = (hi - lo).norm();
        let cell = (2.0 * total / count as f64).max(diag / 200.0);
        let n: [usize; 3] = std::array::from_fn(|d| ((hi[d] - lo[d]) / cell).floor() as usize + 1);
        let mut cells = vec![Vec::new(); n[0] * n[1] * n[2]];
        for (fi, f) in mesh.faces.iter().enumerate() {
            let p = f.map(|k| mesh.vertices[k]);
            let a = p[0].inf(&p[1]).inf(&p[2]);
            let b = p[0].sup(&p[1]).sup(&p[2]);
            let i0: [usize; 3] = std::array::from_fn(|d| (((a[d] - lo[d]) / cell).floor() as usize).min(n[d] - 1));
            let i1: [usize; 3] = std::array::from_fn(|d| (((b[d] - lo[d]) / cell).floor() as usize).min(n[d] - 1));
            for i in i0[0]..=i1[0] {
                for j in i0[1]..=i1[1] {
                    for k in i0[2]..=i1[2] {
                        cells[(i * n[1] + j) * n[2] + k].push(fi as u32);
                    }
                }
            }
        }
        let axes = std::array::from_fn(|ax| AxisGrid::new(&mesh, ax, &lo, &hi, cell));
        Ok(Surface { mesh, lo, cell, n, cells, axes })
    }

    /// Volume enclosed by the surface (mm³), |Σ signed tetra volumes|.
    pub fn volume(&self) -> f64 {
        self.mesh.signed_volume().abs()
    }

    /// Inside test: majority of the ray parities along +x, +y and +z (robust to a ray grazing an
    /// edge or vertex of the surface along one axis).
    pub fn contains(&self, p: &V3) -> bool {
        let votes = self.axes.iter().filter(|g| g.odd(&self.mesh, p)).count();
        votes >= 2
    }

    /// Closest point on the surface to `p` and its distance (mm); exact (grid rings searched until
    /// no closer triangle can exist).
    pub fn closest_point(&self, p: &V3) -> (V3, f64) {
        let c: [i64; 3] = std::array::from_fn(|d| ((p[d] - self.lo[d]) / self.cell).floor() as i64);
        // Distance from p to the grid box, to start at the first non-empty shell.
        let mut best = (V3::zeros(), f64::INFINITY);
        let nmax = *self.n.iter().max().unwrap_or(&1) as i64;
        let outside: i64 = (0..3)
            .map(|d| {
                if c[d] < 0 {
                    -c[d]
                } else if c[d] >= self.n[d] as i64 {
                    c[d] - self.n[d] as i64 + 1
                } else {
                    0
                }
            })
            .max()
            .unwrap_or(0);
        let mut r = outside;
        loop {
            for i in c[0] - r..=c[0] + r {
                for j in c[1] - r..=c[1] + r {
                    for k in c[2] - r..=c[2] + r {
                        let on_shell = (i - c[0]).abs() == r || (j - c[1]).abs() == r || (k - c[2]).abs() == r;
                        if !on_shell
                            || i < 0
                            || j < 0
                            || k < 0
                            || i >= self.n[0] as i64
                            || j >= self.n[1] as i64
                            || k >= self.n[2] as i64
                        {
                            continue;
                        }
                        for &fi in &self.cells[((i as usize) * self.n[1] + j as usize) * self.n[2] + k as usize] {
                            let f = self.mesh.faces[fi as usize];
                            let q = closest_point_on_triangle(
                                p,
                                &self.mesh.vertices[f[0]],
                                &self.mesh.vertices[f[1]],
                                &self.mesh.vertices[f[2]],
                            );
                            let d = (q - p).norm();
                            if d < best.1 {
                                best = (q, d);
                            }
                        }
                    }
                }
            }
            // Every point in shell r+1 or beyond is at least r·cell away from p.
            if best.1 <= r as f64 * self.cell || r > nmax + outside + 1 {
                return best;
            }
            r += 1;
        }
    }

    /// Smallest `t ≥ 0` where the ray `o + t d` crosses the surface, if any (brute force).
    pub fn ray_hit(&self, o: &V3, d: &V3) -> Option<f64> {
        self.ray_hits(o, d).into_iter().next()
    }

    /// All `t ≥ 0` where the ray `o + t d` crosses the surface, sorted (brute force).
    pub fn ray_hits(&self, o: &V3, d: &V3) -> Vec<f64> {
        ray_hits(&self.mesh, o, d)
    }
}

/// The six interior dihedral angles of tetrahedron (p0, p1, p2, p3) in degrees.
pub fn dihedral_angles_deg(p: &[V3; 4]) -> [f64; 6] {
    const EDGES: [(usize, usize, usize, usize); 6] =
        [(0, 1, 2, 3), (0, 2, 1, 3), (0, 3, 1, 2), (1, 2, 0, 3), (1, 3, 0, 2), (2, 3, 0, 1)];
    EDGES.map(|(i, j, k, l)| {
        let e = (p[j] - p[i]).normalize();
        let a = p[k] - p[i];
        let b = p[l] - p[i];
        let a = a - e * e.dot(&a);
        let b = b - e * e.dot(&b);
        let c = a.dot(&b) / (a.norm() * b.norm());
        c.clamp(-1.0, 1.0).acos().to_degrees()
    })
}

/// Signed volume of tetrahedron (p0, p1, p2, p3), mm³.
pub fn tet_signed_volume(p: &[V3; 4]) -> f64 {
    (p[1] - p[0]).dot(&(p[2] - p[0]).cross(&(p[3] - p[0]))) / 6.0
}

/// Smallest dihedral angle (deg), or −1 when the tetrahedron is inverted or flat.
pub fn tet_min_dihedral_deg(p: &[V3; 4]) -> f64 {
    let v = tet_signed_volume(p);
    let scale = (p[1] - p[0]).norm().max((p[2] - p[0]).norm()).max((p[3] - p[0]).norm());
    if v <= 1e-12 * scale.powi(3) || !v.is_finite() {
        return -1.0;
    }
    dihedral_angles_deg(p).into_iter().fold(f64::INFINITY, f64::min)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regular_tet_dihedral_is_arccos_one_third() {
        let p = [V3::new(1.0, 1.0, 1.0), V3::new(1.0, -1.0, -1.0), V3::new(-1.0, 1.0, -1.0), V3::new(-1.0, -1.0, 1.0)];
        let want = (1.0f64 / 3.0).acos().to_degrees();
        for a in dihedral_angles_deg(&p) {
            assert!((a - want).abs() < 1e-9, "{a} vs {want}");
        }
        // Corner tet: three right angles at the axis edges, arccos(1/√3) at the others.
        let q = [V3::zeros(), V3::x(), V3::y(), V3::z()];
        let mut a = dihedral_angles_deg(&q);
        a.sort_by(f64::total_cmp);
        let b = (1.0f64 / 3.0f64.sqrt()).acos().to_degrees();
        for (x, w) in a.iter().zip([b, b, b, 90.0, 90.0, 90.0]) {
            assert!((x - w).abs() < 1e-9, "{x} vs {w}");
        }
    }

    #[test]
    fn closest_point_matches_brute_force_and_inside_test_on_cube() {
        let cube = crate::mesh::shapes::box_surface(&V3::zeros(), &V3::new(1.0, 1.0, 1.0));
        let s = Surface::new(cube.clone(), "cube").unwrap();
        // Cube [0,1]^3 (test mesh): closest point of an outside point is the clamp.
        let p = V3::new(1.7, 0.3, -0.2);
        let (q, d) = s.closest_point(&p);
        assert!((q - V3::new(1.0, 0.3, 0.0)).norm() < 1e-12, "{q:?}");
        assert!((d - (0.49f64 + 0.04).sqrt()).abs() < 1e-12);
        let inner = V3::new(0.2, 0.5, 0.6);
        assert!((s.closest_point(&inner).1 - 0.2).abs() < 1e-12);
        assert!(s.contains(&inner));
        assert!(!s.contains(&p));
        assert!(!s.contains(&V3::new(0.5, 0.5, 1.0001)));
        let mut open = cube;
        open.faces.pop();
        let e = Surface::new(open, "open.obj").err().unwrap().to_string();
        assert!(e.contains("open.obj") && e.contains("not closed: 3 boundary edges"), "{e}");
    }
}
