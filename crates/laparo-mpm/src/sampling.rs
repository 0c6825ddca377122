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
}

/// One particle per tetrahedron at its centroid, with the tetrahedron's volume.
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
        check_closed(&m.boundary(), p).unwrap();
    }
}
