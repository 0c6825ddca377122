//! Round trips of every mesh format and the real meshes in ../shared/data/meshes.
use super::tests::{cube, cube_tets};
use super::*;
use std::path::PathBuf;

fn data(rel: &str) -> Option<PathBuf> {
    let p = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data/meshes")).join(rel);
    if p.exists() {
        Some(p)
    } else {
        eprintln!("SKIP: {} absent", p.display());
        None
    }
}

/// A cube with awkward coordinates (not representable in decimal with few digits).
fn odd_cube() -> TriMesh {
    let mut c = cube();
    for (i, v) in c.vertices.iter_mut().enumerate() {
        *v = *v * (1.0 / 3.0) + Vector3::new(1e-7 * i as f64, -123.456789, 0.1 + 0.2);
    }
    c
}

#[test]
fn obj_ply_round_trips_bit_exact() {
    let dir = tempfile::tempdir().unwrap();
    let m = odd_cube();
    for (name, write) in [
        ("a.obj", &(|p: &Path, m: &TriMesh| write_obj(p, m)) as &dyn Fn(&Path, &TriMesh) -> Result<()>),
        ("a.ply", &|p: &Path, m: &TriMesh| write_ply(p, m)),
        ("b.ply", &|p: &Path, m: &TriMesh| write_ply_with(p, m, PlyEncoding::Ascii, None)),
    ] {
        let p = dir.path().join(name);
        write(&p, &m).unwrap();
        let back = read_mesh(&p).unwrap();
        assert_eq!(back, m, "{name}");
    }
    // colours, both encodings
    let colors: Vec<[u8; 3]> = (0..8).map(|i| [i * 30, 255 - i * 30, 7]).collect();
    for enc in [PlyEncoding::Ascii, PlyEncoding::BinaryLittleEndian] {
        let p = dir.path().join("c.ply");
        write_ply_with(&p, &m, enc, Some(&colors)).unwrap();
        let (back, c) = read_ply_with_colors(&p).unwrap();
        assert_eq!(back, m);
        assert_eq!(c.unwrap(), colors);
    }
    // a point cloud (no faces)
    let pc = TriMesh { vertices: m.vertices.clone(), faces: vec![] };
    let p = dir.path().join("pc.ply");
    write_ply(&p, &pc).unwrap();
    assert_eq!(read_ply(&p).unwrap(), pc);
}

#[test]
fn stl_round_trips_and_welds() {
    let dir = tempfile::tempdir().unwrap();
    // coordinates exactly representable in f32 so binary STL is exact
    let m = cube()
        .scaled(0.5)
        .transformed(&crate::se3::se3_from_rt(&nalgebra::Matrix3::identity(), &Vector3::new(1.0, -2.0, 3.25)));
    for ascii in [false, true] {
        let p = dir.path().join("a.stl");
        write_stl(&p, &m, ascii).unwrap();
        let back = read_stl(&p).unwrap();
        assert_eq!(back.vertices.len(), 8, "corners welded");
        assert_eq!(back.faces.len(), 12);
        assert!(back.is_closed() && back.is_consistently_oriented());
        assert!((back.signed_volume() - 0.125).abs() < 1e-12);
        // same triangles, same positions
        for (f, g) in m.faces.iter().zip(&back.faces) {
            for k in 0..3 {
                assert_eq!(m.vertices[f[k]], back.vertices[g[k]]);
            }
        }
    }
    // ascii keeps f64 exactly
    let o = odd_cube();
    let p = dir.path().join("o.stl");
    write_stl(&p, &o, true).unwrap();
    let back = read_stl(&p).unwrap();
    assert_eq!(back.vertices.len(), 8);
    for (f, g) in o.faces.iter().zip(&back.faces) {
        for k in 0..3 {
            assert_eq!(o.vertices[f[k]], back.vertices[g[k]]);
        }
    }
}

#[test]
fn msh_and_vtk_round_trips() {
    let dir = tempfile::tempdir().unwrap();
    let mut t = cube_tets();
    for v in t.vertices.iter_mut() {
        *v = *v * 0.1 + Vector3::new(1.0 / 7.0, 0.0, -5.5);
    }
    let p = dir.path().join("a.msh");
    write_msh(&p, &t).unwrap();
    assert_eq!(read_msh(&p).unwrap(), t);
    let p = dir.path().join("a.vtk");
    write_vtk(&p, &t).unwrap();
    assert_eq!(read_vtk(&p).unwrap(), t);
    // surface of a tet-only file via read_mesh = outward boundary
    let s = read_mesh(&p).unwrap().without_unused_vertices();
    assert!(s.is_closed());
    assert!((s.signed_volume() - 0.001).abs() < 1e-12);
}

#[test]
fn msh_v1_v2_and_vtk_variants_by_hand() {
    let dir = tempfile::tempdir().unwrap();
    // v2 with arbitrary node ids, a point, a line, a triangle, a 2nd-order tet, physical names
    let v2 = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n1\n3 7 \"liver\"\n$EndPhysicalNames\n\
$Nodes\n5\n10 0 0 0\n20 1 0 0\n30 0 1 0\n40 0 0 1\n50 0.5 0.5 0.5\n$EndNodes\n\
$Elements\n4\n1 15 2 0 1 10\n2 1 2 0 1 10 20\n3 2 2 5 1 10 20 30\n4 11 2 7 1 10 20 30 40 50 50 50 50 50 50\n$EndElements\n";
    let p = dir.path().join("v2.msh");
    std::fs::write(&p, v2).unwrap();
    let m = read_msh_mixed(&p).unwrap();
    assert_eq!(m.vertices.len(), 5);
    assert_eq!(m.triangles, vec![[0, 1, 2]]);
    assert_eq!(m.triangle_tags, vec![5]);
    assert_eq!(m.tets, vec![[0, 1, 2, 3]]);
    assert_eq!(m.tet_tags, vec![7]);
    // v1
    let v1 =
        "$NOD\n4\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n$ENDNOD\n$ELM\n2\n1 4 3 1 4 1 2 3 4\n2 2 9 1 3 1 2 3\n$ENDELM\n";
    let p = dir.path().join("v1.msh");
    std::fs::write(&p, v1).unwrap();
    let m = read_msh_mixed(&p).unwrap();
    assert_eq!((m.tets.clone(), m.tet_tags.clone()), (vec![[0, 1, 2, 3]], vec![3]));
    assert_eq!(m.triangles.len(), 1);
    assert!((read_msh(&p).unwrap().volume() - 1.0 / 6.0).abs() < 1e-15);
    // VTK 5.1 offsets/connectivity with METADATA, and POLYDATA
    let vtk51 = "# vtk DataFile Version 5.1\nx\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 4 float\n0 0 0 1 0 0 0 1 0 0 0 1\n\
METADATA\nINFORMATION 0\n\nCELLS 3 7\nOFFSETS vtktypeint64\n0 4 7\nCONNECTIVITY vtktypeint64\n0 1 2 3 0 1 2\nCELL_TYPES 2\n10\n5\n\
CELL_DATA 2\nSCALARS a float\nLOOKUP_TABLE default\n1 2\n";
    let p = dir.path().join("a.vtk");
    std::fs::write(&p, vtk51).unwrap();
    let m = read_vtk_mixed(&p).unwrap();
    assert_eq!((m.tets.len(), m.triangles.len()), (1, 1));
    let poly = "# vtk DataFile Version 3.0\nx\nASCII\nDATASET POLYDATA\nPOINTS 4 double\n0 0 0 1 0 0 1 1 0 0 1 0\nPOLYGONS 1 5\n4 0 1 2 3\n";
    std::fs::write(&p, poly).unwrap();
    let s = read_mesh(&p).unwrap();
    assert_eq!(s.faces, vec![[0, 1, 2], [0, 2, 3]]);
    assert!((s.area() - 1.0).abs() < 1e-15);
    assert!(read_vtk(&p).unwrap_err().to_string().contains("no tetrahedra"));
}

#[test]
fn obj_ply_variants_by_hand() {
    let dir = tempfile::tempdir().unwrap();
    let obj = "# c\nmtllib x.mtl\no q\nv 0 0 0\nv 1 0 0 0.5 0.5 0.5\nv 1 1 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\ng g\nusemtl m\ns 1\nf 1/1/1 2/1/1 3/1/1 4/1/1\nf -4//1 -2//1 -1//1\n";
    let p = dir.path().join("q.obj");
    std::fs::write(&p, obj).unwrap();
    let m = read_obj(&p).unwrap();
    assert_eq!(m.faces, vec![[0, 1, 2], [0, 2, 3], [0, 2, 3]]);
    // big-endian binary PLY with float coordinates, a uint list and an extra element
    let mut b = b"ply\nformat binary_big_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nproperty uchar intensity\nelement face 1\nproperty list uchar uint vertex_indices\nelement edge 1\nproperty int vertex1\nproperty int vertex2\nend_header\n".to_vec();
    for (x, y) in [(0f32, 0f32), (2.0, 0.0), (0.0, 2.0)] {
        for c in [x, y, 0.5] {
            b.extend_from_slice(&c.to_be_bytes());
        }
        b.push(9);
    }
    b.push(3);
    for k in [0u32, 1, 2] {
        b.extend_from_slice(&k.to_be_bytes());
    }
    b.extend_from_slice(&0i32.to_be_bytes());
    b.extend_from_slice(&1i32.to_be_bytes());
    let p = dir.path().join("be.ply");
    std::fs::write(&p, &b).unwrap();
    let m = read_ply(&p).unwrap();
    assert_eq!(m.vertices[1], Vector3::new(2.0, 0.0, 0.5));
    assert_eq!(m.faces, vec![[0, 1, 2]]);
    assert!((m.area() - 2.0).abs() < 1e-15);
}

#[test]
fn corrupt_mesh_files_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let m = cube();
    let cases: Vec<(&str, Vec<u8>)> = vec![
        ("idx.obj", b"v 0 0 0\nv 1 0 0\nf 1 2 3\n".to_vec()),
        ("nan.obj", b"v 0 0 nan\nv 1 0 0\nv 0 1 0\nf 1 2 3\n".to_vec()),
        ("word.obj", b"v 0 zero 0\n".to_vec()),
        ("empty.obj", b"# nothing\n".to_vec()),
        ("hdr.ply", b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\n".to_vec()),
        ("short.ply", b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n1 1\n".to_vec()),
        ("idx.ply", b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 5\n".to_vec()),
        ("trunc.stl", { let mut v = vec![0u8; 80]; v.extend_from_slice(&5u32.to_le_bytes()); v.extend_from_slice(&[0u8; 60]); v }),
        ("open.stl", b"solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n".to_vec()),
        ("trunc.msh", b"$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n4\n1 0 0 0\n2 1 0 0\n".to_vec()),
        ("node.msh", b"$NOD\n1\n1 0 0 0\n$ENDNOD\n$ELM\n1\n1 4 1 1 4 1 2 3 4\n$ENDELM\n".to_vec()),
        ("v4.msh", b"$MeshFormat\n4.1 0 8\n$EndMeshFormat\n".to_vec()),
        ("bin.vtk", b"# vtk DataFile Version 3.0\nx\nBINARY\n".to_vec()),
        ("idx.vtk", b"# vtk DataFile Version 3.0\nx\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 1 float\n0 0 0\nCELLS 1 5\n4 0 1 2 3\nCELL_TYPES 1\n10\n".to_vec()),
        ("x.off", b"OFF\n".to_vec()),
    ];
    for (name, content) in cases {
        let p = dir.path().join(name);
        std::fs::write(&p, &content).unwrap();
        let r = if name.ends_with(".msh") {
            read_msh(&p).map(|_| ())
        } else if name.ends_with(".vtk") {
            read_vtk(&p).map(|_| ())
        } else {
            read_mesh(&p).map(|_| ())
        };
        let e = r.expect_err(name).to_string();
        assert!(e.contains(name), "{name}: {e}");
    }
    // writers refuse bad indices and leave nothing behind
    let mut bad = m.clone();
    bad.faces[0] = [0, 1, 42];
    let p = dir.path().join("bad.ply");
    assert!(write_ply(&p, &bad).unwrap_err().to_string().contains("bad.ply"));
    assert!(!p.exists());
}

#[test]
fn real_p2ilf_liver_obj() {
    let Some(p) = data("p2ilf/patient2_1_3d-liver-model.obj") else { return };
    let m = read_mesh(&p).unwrap();
    assert_eq!(m.vertices.len(), 4002);
    assert_eq!(m.faces.len(), 8000);
    // V - E + F = 2 and every edge shared by two faces: a closed genus-0 surface
    assert!(m.is_closed());
    assert_eq!(m.edge_face_counts().len(), 12000);
    assert!(m.is_consistently_oriented());
    m.validate().unwrap();
    // a liver in mm: extent of order 100-300 mm, enclosed volume of order 1-3 litres
    let (lo, hi) = m.bounding_box().unwrap();
    let ext = hi - lo;
    assert!(ext.max() > 100.0 && ext.max() < 400.0, "{ext:?}");
    let vol_ml = m.signed_volume().abs() / 1000.0;
    assert!(vol_ml > 300.0 && vol_ml < 4000.0, "{vol_ml} ml");
    // round trip through binary PLY is bit-exact
    let dir = tempfile::tempdir().unwrap();
    let q = dir.path().join("liver.ply");
    write_ply(&q, &m).unwrap();
    assert_eq!(read_ply(&q).unwrap(), m);
}

#[test]
fn real_sofa_liver_msh_matches_obj_surface() {
    let Some(p) = data("sofa_liver/liver.msh") else { return };
    let t = read_msh(&p).unwrap();
    assert_eq!(t.vertices.len(), 181);
    assert_eq!(t.tets.len(), 596);
    t.validate().unwrap();
    let b = t.boundary();
    assert!(b.without_unused_vertices().is_closed());
    // the boundary volume (divergence theorem) equals the sum of the tet volumes
    assert!((b.signed_volume() - t.volume()).abs() < 1e-9 * t.volume());
    // liver.obj is (nearly) that boundary surface, compared as vertex sets
    if let Some(o) = data("sofa_liver/liver.obj") {
        let s = read_obj(&o).unwrap();
        assert_eq!(s.vertices.len(), 181);
        let key = |f: &[usize; 3]| {
            let mut k = *f;
            k.sort_unstable();
            k
        };
        let mut a: Vec<_> = b.faces.iter().map(key).collect();
        let mut c: Vec<_> = s.faces.iter().map(key).collect();
        a.sort_unstable();
        c.sort_unstable();
        // All obj triangles but one are tet boundary faces. The exception (SOFA's own data):
        // where liver.obj has triangle {89, 92, 93}, the tet surface is a fan of three triangles
        // through the extra surface node 139.
        let only_b: Vec<_> = a.iter().filter(|f| c.binary_search(f).is_err()).copied().collect();
        let only_o: Vec<_> = c.iter().filter(|f| a.binary_search(f).is_err()).copied().collect();
        assert_eq!(a.len() - only_b.len(), 273);
        assert_eq!(only_o, vec![[89, 92, 93]]);
        assert_eq!(only_b, vec![[89, 92, 139], [89, 93, 139], [92, 93, 139]]);
    }
}

/// The one VTK-with-data writer: geometry reads back through the core reader, and the data
/// sections hold the given values in the documented layout (parsed here independently).
#[test]
fn vtk_fields_round_trip_and_reject_bad_arrays() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("m.vtk");
    let v = vec![Vector3::zeros(), Vector3::x(), Vector3::y(), Vector3::new(0.1, 0.2, 1.0 / 3.0)];
    let tre = [0.0, 1.5, 2.0, 1e-17];
    let side = [2i64];
    write_vtk_fields(
        &p,
        "two\nlines",
        &v,
        &[[0, 1, 2, 3]],
        &[VtkField::new("tre_mm", VtkValues::Double(&tre)), VtkField::new("u_mm", VtkValues::Vector(&v))],
        &[VtkField::new("side", VtkValues::Int(&side))],
    )
    .unwrap();
    let m = read_vtk(&p).unwrap();
    assert_eq!(m.vertices, v);
    assert_eq!(m.tets, vec![[0, 1, 2, 3]]);
    let text = std::fs::read_to_string(&p).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines[1], "two lines", "the title stays one line");
    let at = |key: &str| lines.iter().position(|l| *l == key).unwrap_or_else(|| panic!("{key} missing:\n{text}"));
    let c = at("CELL_DATA 1");
    assert_eq!(&lines[c + 1..c + 4], ["SCALARS side int 1", "LOOKUP_TABLE default", "2"]);
    let s = at("SCALARS tre_mm double 1");
    assert_eq!(lines[s - 1], "POINT_DATA 4");
    let back: Vec<f64> = lines[s + 2..s + 6].iter().map(|l| l.parse().unwrap()).collect();
    assert_eq!(back, tre, "doubles round-trip exactly");
    let u = at("VECTORS u_mm double");
    let back: Vec<f64> =
        lines[u + 1..u + 5].iter().flat_map(|l| l.split(' ').map(|x| x.parse::<f64>().unwrap())).collect();
    assert_eq!(back, v.iter().flat_map(|x| [x.x, x.y, x.z]).collect::<Vec<_>>());
    // wrong lengths, bad names and bad indices are errors naming the file, and write nothing
    let q = dir.path().join("bad.vtk");
    let e = write_vtk_fields(&q, "t", &v, &[[0, 1, 2, 3]], &[VtkField::new("x", VtkValues::Double(&[0.0]))], &[])
        .unwrap_err()
        .to_string();
    assert!(e.contains("bad.vtk") && e.contains("1 values for 4 nodes"), "{e}");
    let e = write_vtk_fields(&q, "t", &v, &[[0, 1, 2, 3]], &[], &[VtkField::new("a b", VtkValues::Int(&side))])
        .unwrap_err()
        .to_string();
    assert!(e.contains("bad.vtk") && e.contains("whitespace"), "{e}");
    assert!(write_vtk_fields(&q, "t", &v, &[[0, 1, 2, 4]], &[], &[]).is_err());
    assert!(!q.exists());
}

/// Found by the fuzz campaign of 2026-12-03 (input `1 4 -1` in a v2 `$Elements` block): a negative
/// tag count wrapped to a huge usize and panicked with an out-of-bounds index; likewise a negative
/// v1 node count. Both are errors naming the file and line now.
#[test]
fn msh_negative_counts_are_errors_not_panics() {
    let dir = tempfile::tempdir().unwrap();
    let nodes = "$Nodes\n4\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n$EndNodes\n";
    let cases = [
        ("v2.msh", format!("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n{nodes}$Elements\n1\n1 4 -1\n$EndElements\n")),
        ("v2b.msh", format!("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n{nodes}$Elements\n1\n1 4 9 1 2 3\n$EndElements\n")),
        (
            "v1.msh",
            "$NOD\n4\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n$ENDNOD\n$ELM\n1\n1 4 3 1 -4 1 2 3 4\n$ENDELM\n".to_string(),
        ),
    ];
    for (name, text) in cases {
        let p = dir.path().join(name);
        std::fs::write(&p, text).unwrap();
        let e = std::panic::catch_unwind(|| read_msh_mixed(&p)).expect("no panic").unwrap_err().to_string();
        assert!(e.contains(name) && e.contains("element line"), "{e}");
    }
}
