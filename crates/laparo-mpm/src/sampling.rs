//! Particles from geometry: voxelised closed surface meshes (OBJ / PLY / STL) and tetrahedral meshes
//! (Gmsh .msh v1/v2 ASCII, legacy VTK ASCII), read with `laparo_core::mesh`.
use crate::error::MpmError;
use crate::linalg::Vector;
pub use laparo_core::mesh::{TetMesh, TriMesh};
use std::path::Path;

fn err(path: &Path, reason: impl Into<String>) -> MpmError {
    MpmError::Mesh { path: path.display().to_string(), reason: reason.into() }
}

/// A laparo-core mesh error (its message already names the file).
fn core_err(path: &Path, e: laparo_core::CoreError) -> MpmError {
    let msg = e.to_string();
    let prefix = format!("{}: ", path.display());
    err(path, msg.strip_prefix(&prefix).unwrap_or(&msg))
}

/// Read an OBJ, PLY or STL triangle mesh (or the surface of a .msh/.vtk).
pub fn read_surface_mesh(path: &Path) -> Result<TriMesh, MpmError> {
    let mesh = laparo_core::mesh::read_mesh(path).map_err(|e| core_err(path, e))?;
    if mesh.faces.is_empty() {
        return Err(err(path, "no triangles"));
    }
    Ok(mesh)
}

/// Error unless every edge is shared by exactly two triangles (a closed, manifold surface).
pub fn check_closed(mesh: &TriMesh, path: &Path) -> Result<(), MpmError> {
    let open = mesh.edge_face_counts().values().filter(|&&c| c != 2).count();
    if open > 0 {
        return Err(err(path, format!("surface is not closed: {open} edges are not shared by exactly two triangles")));
    }
    Ok(())
}

/// Lattice points (spacing `spacing`, cell-centred on the mesh bounding box) inside a closed surface,
/// by ray parity along +x per lattice row.
pub fn voxelize(mesh: &TriMesh, spacing: f64) -> Vec<Vector<3>> {
    let mut lo = Vector::<3>::from_element(f64::INFINITY);
    let mut hi = Vector::<3>::from_element(f64::NEG_INFINITY);
    for v in &mesh.vertices {
        lo = lo.inf(v);
        hi = hi.sup(v);
    }
    let counts: [usize; 3] = std::array::from_fn(|d| ((hi[d] - lo[d]) / spacing).ceil().max(1.0) as usize);
    let mut out = Vec::new();
    for i in 0..counts[1] {
        for j in 0..counts[2] {
            // tiny irrational offsets keep rays off vertices and edges
            let y = lo[1] + (i as f64 + 0.5) * spacing + spacing * 1.234e-7;
            let z = lo[2] + (j as f64 + 0.5) * spacing + spacing * 2.718e-7;
            let mut xs: Vec<f64> = Vec::new();
            for f in &mesh.faces {
                let (a, b, c) = (mesh.vertices[f[0]], mesh.vertices[f[1]], mesh.vertices[f[2]]);
                // barycentric test in the (y, z) plane
                let d = (b[1] - a[1]) * (c[2] - a[2]) - (c[1] - a[1]) * (b[2] - a[2]);
                if d == 0.0 {
                    continue;
                }
                let u = ((y - a[1]) * (c[2] - a[2]) - (c[1] - a[1]) * (z - a[2])) / d;
                let v = ((b[1] - a[1]) * (z - a[2]) - (y - a[1]) * (b[2] - a[2])) / d;
                if u >= 0.0 && v >= 0.0 && u + v <= 1.0 {
                    xs.push(a[0] + u * (b[0] - a[0]) + v * (c[0] - a[0]));
                }
            }
            xs.sort_by(f64::total_cmp);
            for k in 0..counts[0] {
                let x = lo[0] + (k as f64 + 0.5) * spacing;
                let crossings = xs.iter().filter(|&&c| c > x).count();
                if crossings % 2 == 1 {
                    out.push(Vector::<3>::new(x, y, z));
                }
            }
        }
    }
    out
}

/// Read a tetrahedral mesh: Gmsh `.msh` (ASCII v1 or v2) or legacy `.vtk` ASCII unstructured grid.
pub fn read_tet_mesh(path: &Path) -> Result<TetMesh, MpmError> {
    let ext = laparo_core::io::extension(path);
    match ext.as_str() {
        "msh" => laparo_core::mesh::read_msh(path),
        "vtk" => laparo_core::mesh::read_vtk(path),
        e => return Err(err(path, format!("unsupported tetrahedral mesh extension '{e}' (msh, vtk)"))),
    }
    .map_err(|e| core_err(path, e))
    .map_err(|e| match e {
        // e.g. a VTK POLYDATA surface given as a tetrahedral mesh
        MpmError::Mesh { path, reason } if reason.starts_with("no tetrahedra") => MpmError::Mesh {
            path,
            reason: format!(
                "{}: a surface, not a tetrahedral mesh; for a closed surface use shape = \"mesh\" (voxelised at spacing)",
                reason.split(": use ").next().unwrap_or(&reason)
            ),
        },
        e => e,
    })
}

/// The cell-centred lattice of spacing `spacing` over an axis-aligned box: point (i, j, k) is
/// lo + (i + ½, j + ½, k + ½)·spacing for i < counts[0], … (the lattice of [`voxelize`]).
#[derive(Clone, Copy, Debug)]
struct Lattice {
    lo: Vector<3>,
    spacing: f64,
    counts: [u64; 3],
}

impl Lattice {
    /// Lattice over [lo, hi] (at least one point per axis).
    fn over(lo: &Vector<3>, hi: &Vector<3>, spacing: f64) -> Lattice {
        let counts = std::array::from_fn(|d| ((hi[d] - lo[d]) / spacing).ceil().max(1.0) as u64);
        Lattice { lo: *lo, spacing, counts }
    }
    /// Index range [first, last] (inclusive, clamped) of the lattice points in [a, b] along axis `d`,
    /// widened by `tol` lattice spacings; `None` when empty.
    fn range(&self, d: usize, a: f64, b: f64, tol: f64) -> Option<(u64, u64)> {
        let first = ((a - self.lo[d]) / self.spacing - 0.5 - tol).ceil().max(0.0);
        let last = ((b - self.lo[d]) / self.spacing - 0.5 + tol).floor().min(self.counts[d] as f64 - 1.0);
        (first <= last).then_some((first as u64, last as u64))
    }
    fn point(&self, i: u64, j: u64, k: u64) -> Vector<3> {
        let s = self.spacing;
        self.lo + Vector::<3>::new((i as f64 + 0.5) * s, (j as f64 + 0.5) * s, (k as f64 + 0.5) * s)
    }
}

/// Number of lattice points [`sample_tet_mesh`] examines (the lattice points in the bounding box of
/// every tetrahedron, summed), as f64 so that absurd spacings do not overflow: a work estimate for
/// the caller to bound before sampling.
pub fn tet_scan_points(mesh: &TetMesh, spacing: f64) -> f64 {
    mesh.tets
        .iter()
        .map(|t| {
            let (lo, hi) = tet_box(mesh, t);
            (0..3).map(|d| ((hi[d] - lo[d]) / spacing).floor() + 1.0).product::<f64>()
        })
        .sum()
}

fn tet_box(mesh: &TetMesh, t: &[usize; 4]) -> (Vector<3>, Vector<3>) {
    let p = t.map(|i| mesh.vertices[i]);
    (p[1..].iter().fold(p[0], |a, b| a.inf(b)), p[1..].iter().fold(p[0], |a, b| a.sup(b)))
}

/// Particles filling a tetrahedral mesh at `spacing`: the points of the cell-centred lattice of
/// spacing `spacing` over the mesh bounding box (as [`voxelize`]) that lie inside a tetrahedron.
/// Each tetrahedron tests the lattice points of its bounding box (barycentric coordinates, all
/// ≥ −1e-9, so points on shared faces are found by both neighbours and kept once); the result is in
/// lattice order (last axis fastest) whatever the thread count. Each particle stands for spacing³ of
/// volume, so the particle count is ≈ mesh volume / spacing³.
pub fn sample_tet_mesh(mesh: &TetMesh, spacing: f64) -> Result<Vec<Vector<3>>, MpmError> {
    use rayon::prelude::*;
    if !(spacing > 0.0 && spacing.is_finite()) {
        return Err(MpmError::InvalidParameter {
            name: "spacing".into(),
            value: spacing,
            reason: "must be finite and > 0".into(),
        });
    }
    let Some((lo, hi)) = mesh.bounding_box() else { return Ok(Vec::new()) };
    let lat = Lattice::over(&lo, &hi, spacing);
    if lat.counts.iter().try_fold(1u64, |a, &c| a.checked_mul(c)).is_none() {
        return Err(MpmError::InvalidParameter {
            name: "spacing".into(),
            value: spacing,
            reason: format!("the lattice over the mesh bounding box has {:?} points per axis", lat.counts),
        });
    }
    let [_, ny, nz] = lat.counts;
    const TOL: f64 = 1e-9;
    let mut keys: Vec<u64> = mesh
        .tets
        .par_iter()
        .flat_map_iter(|t| {
            let p = t.map(|i| mesh.vertices[i]);
            let m = nalgebra::Matrix3::from_columns(&[p[1] - p[0], p[2] - p[0], p[3] - p[0]]);
            let (blo, bhi) = tet_box(mesh, t);
            let ranges = m.try_inverse().and_then(|inv| {
                let r: [Option<(u64, u64)>; 3] = std::array::from_fn(|d| lat.range(d, blo[d], bhi[d], TOL));
                Some((inv, r[0]?, r[1]?, r[2]?))
            });
            let mut out = Vec::new();
            if let Some((inv, (i0, i1), (j0, j1), (k0, k1))) = ranges {
                for i in i0..=i1 {
                    for j in j0..=j1 {
                        for k in k0..=k1 {
                            let b = inv * (lat.point(i, j, k) - p[0]);
                            if b.min() >= -TOL && b.sum() <= 1.0 + TOL {
                                out.push((i * ny + j) * nz + k);
                            }
                        }
                    }
                }
            }
            out
        })
        .collect();
    keys.par_sort_unstable();
    keys.dedup();
    Ok(keys.iter().map(|&key| lat.point(key / (ny * nz), key / nz % ny, key % nz)).collect())
}

/// One particle per tetrahedron at its centroid, with the tetrahedron's volume (a coarse
/// representation: use [`sample_tet_mesh`] to fill a mesh at a given spacing).
pub fn tet_particles(mesh: &TetMesh) -> (Vec<Vector<3>>, Vec<f64>) {
    let mut pos = Vec::with_capacity(mesh.tets.len());
    let mut vol = Vec::with_capacity(mesh.tets.len());
    for t in &mesh.tets {
        let [a, b, c, d] = t.map(|i| mesh.vertices[i]);
        let v = ((b - a).cross(&(c - a))).dot(&(d - a)).abs() / 6.0;
        if v > 0.0 {
            pos.push((a + b + c + d) / 4.0);
            vol.push(v);
        }
    }
    (pos, vol)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cube_obj() -> String {
        let mut s = String::new();
        for z in [0.0, 1.0] {
            for y in [0.0, 1.0] {
                for x in [0.0, 1.0] {
                    s += &format!("v {x} {y} {z}\n");
                }
            }
        }
        // 12 outward triangles of the unit cube (vertices 1..8, index = 1 + x + 2y + 4z)
        for f in [
            [1, 3, 4],
            [1, 4, 2],
            [5, 6, 8],
            [5, 8, 7],
            [1, 2, 6],
            [1, 6, 5],
            [3, 7, 8],
            [3, 8, 4],
            [1, 5, 7],
            [1, 7, 3],
            [2, 4, 8],
            [2, 8, 6],
        ] {
            s += &format!("f {} {} {}\n", f[0], f[1], f[2]);
        }
        s
    }

    #[test]
    fn voxelised_cube_has_the_right_volume_and_open_mesh_is_rejected() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("cube.obj");
        std::fs::write(&p, cube_obj()).unwrap();
        let m = read_surface_mesh(&p).unwrap();
        check_closed(&m, &p).unwrap();
        let pts = voxelize(&m, 0.1);
        assert_eq!(pts.len(), 1000);
        let mut open = m.clone();
        open.faces.pop();
        let e = check_closed(&open, &p).unwrap_err().to_string();
        assert!(e.contains("not closed") && e.contains("cube.obj"), "{e}");
    }

    #[test]
    fn gmsh_and_vtk_tetrahedra() {
        let dir = tempfile::tempdir().unwrap();
        let msh = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n4\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n$EndNodes\n$Elements\n2\n1 15 2 0 1 1\n2 4 2 0 1 1 2 3 4\n$EndElements\n";
        let p = dir.path().join("t.msh");
        std::fs::write(&p, msh).unwrap();
        let (pos, vol) = tet_particles(&read_tet_mesh(&p).unwrap());
        assert_eq!(pos.len(), 1);
        assert!((vol[0] - 1.0 / 6.0).abs() < 1e-15 && (pos[0][0] - 0.25).abs() < 1e-15);
        let vtk = "# vtk DataFile Version 2.0\nt\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 4 double\n0 0 0 2 0 0 0 2 0 0 0 2\nCELLS 1 5\n4 0 1 2 3\nCELL_TYPES 1\n10\n";
        let p = dir.path().join("t.vtk");
        std::fs::write(&p, vtk).unwrap();
        let (_, vol) = tet_particles(&read_tet_mesh(&p).unwrap());
        assert!((vol[0] - 8.0 / 6.0).abs() < 1e-12);
    }

    /// The unit corner tetrahedron (0,0,0), (1,0,0), (0,1,0), (0,0,1).
    fn corner_tet() -> TetMesh {
        let v = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        TetMesh { vertices: v.iter().map(|p| Vector::<3>::new(p[0], p[1], p[2])).collect(), tets: vec![[0, 1, 2, 3]] }
    }

    #[test]
    fn corner_tet_lattice_count_is_the_closed_form() {
        // Lattice points (i+½, j+½, k+½)·s with s = 1/50 inside x+y+z ≤ 1: i+j+k ≤ 48.5, i.e.
        // i+j+k ≤ 48 over i, j, k ≥ 0: C(48+3, 3) = 20825 points; V/s³ = 125000/6 = 20833.3.
        let pts = sample_tet_mesh(&corner_tet(), 0.02).unwrap();
        assert_eq!(pts.len(), 20825);
        assert!(pts.iter().all(|p| p.min() > 0.0 && p.sum() <= 1.0));
        // a point of the lattice, in lattice order (last axis fastest)
        assert!((pts[0] - Vector::<3>::new(0.01, 0.01, 0.01)).norm() < 1e-15);
        assert!((pts[1] - Vector::<3>::new(0.01, 0.01, 0.03)).norm() < 1e-15);
        assert!(tet_scan_points(&corner_tet(), 0.02) >= 51f64.powi(3));
    }

    #[test]
    fn cube_of_six_tets_gives_every_lattice_point_once() {
        // The unit cube split into 6 tetrahedra around the diagonal (0,0,0)–(1,1,1): many lattice
        // points (i = j, j = k, …) lie on the shared internal faces and must be kept exactly once.
        let c = |i: usize| Vector::<3>::new((i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64);
        let vertices: Vec<Vector<3>> = (0..8).map(c).collect();
        let tets = vec![[0, 1, 3, 7], [0, 3, 2, 7], [0, 2, 6, 7], [0, 6, 4, 7], [0, 4, 5, 7], [0, 5, 1, 7]];
        let m = TetMesh { vertices, tets };
        assert!((m.volume() - 1.0).abs() < 1e-12);
        for (s, n) in [(0.1, 10usize), (0.05, 20), (1.0 / 7.0, 7)] {
            let pts = sample_tet_mesh(&m, s).unwrap();
            assert_eq!(pts.len(), n * n * n, "spacing {s}");
            let mut keys: Vec<[i64; 3]> =
                pts.iter().map(|p| [0, 1, 2].map(|d| (p[d] / s - 0.5).round() as i64)).collect();
            keys.dedup();
            assert_eq!(keys.len(), n * n * n);
        }
        assert!(sample_tet_mesh(&m, 0.0).is_err() && sample_tet_mesh(&m, f64::NAN).is_err());
    }

    #[test]
    fn real_sofa_liver_gmsh_v1_tetrahedra() {
        let p = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data/meshes/sofa_liver/liver.msh"));
        if !p.is_file() {
            eprintln!("SKIP: {} is absent", p.display());
            return;
        }
        let m = read_tet_mesh(p).unwrap();
        assert_eq!((m.vertices.len(), m.tets.len()), (181, 596));
        let (pos, vol) = tet_particles(&m);
        assert_eq!(pos.len(), 596);
        // particle volumes sum to the mesh volume; the surface of the tets is closed
        let total: f64 = vol.iter().sum();
        assert!((total - m.volume().abs()).abs() < 1e-12 * total, "{total} vs {}", m.volume());
        let surface = m.boundary();
        check_closed(&surface, p).unwrap();
        // Sampled at a spacing: count ≈ volume / spacing³, the volume computed independently from the
        // closed boundary surface (divergence theorem), within the boundary layer's share.
        let v_surf = surface.signed_volume().abs();
        let (lo, hi) = m.bounding_box().unwrap();
        let s = (hi - lo).max() / 40.0;
        let pts = sample_tet_mesh(&m, s).unwrap();
        let expect = v_surf / s.powi(3);
        let rel = (pts.len() as f64 - expect).abs() / expect;
        assert!(pts.len() > 5000 && rel < 0.03, "{} particles vs V/s^3 = {expect:.0} ({rel:.3})", pts.len());
        // the same count as voxelising the boundary surface on the same lattice (ray parity)
        let vox = voxelize(&surface, s);
        assert!(
            (vox.len() as f64 - pts.len() as f64).abs() < 0.01 * pts.len() as f64,
            "{} vs {}",
            vox.len(),
            pts.len()
        );
    }
}
