//! Tetrahedralisation of closed surfaces with closed-form volumes (box, sphere): no inverted
//! tetrahedron, the guaranteed dihedral bound, volume against the closed form, snapping accuracy.
use laparo_fem::mesh::geom::{dihedral_angles_deg, tet_signed_volume};
use laparo_fem::mesh::shapes::{box_surface, icosphere};
use laparo_fem::mesh::{quality_report, tetrahedralize, tetrahedralize_surface, Surface, TetraParams};
use nalgebra::Vector3;

fn check_valid(m: &laparo_core::mesh::TetMesh, floor_deg: f64) {
    for t in &m.tets {
        let p = t.map(|k| m.vertices[k]);
        assert!(tet_signed_volume(&p) > 0.0, "inverted or flat tet {t:?}");
        let min = dihedral_angles_deg(&p).into_iter().fold(f64::INFINITY, f64::min);
        assert!(min >= floor_deg - 1e-9, "tet {t:?} has min dihedral {min}");
    }
    m.validate().unwrap();
}

#[test]
fn box_volume_and_quality() {
    let lo = Vector3::new(-5.0, 0.0, 2.0);
    let hi = Vector3::new(15.0, 10.0, 17.0);
    let params = TetraParams { edge_mm: 2.0, ..TetraParams::default() };
    let (m, q) = tetrahedralize_surface(box_surface(&lo, &hi), "box", &params).unwrap();
    check_valid(&m, params.min_dihedral_deg);
    let v_exact = 20.0 * 10.0 * 15.0;
    assert!((q.surface_volume_mm3.unwrap() - v_exact).abs() < 1e-9);
    // every lattice tet has volume h³/12 before snapping: the count alone brackets the volume
    assert_eq!(q.inverted, 0);
    assert!(q.volume_rel_error.unwrap().abs() < 0.02, "{q:?}");
    assert!((q.volume_mm3 - m.volume()).abs() < 1e-6 * v_exact);
    assert!(q.min_dihedral_deg >= params.min_dihedral_deg - 1e-9);
    assert!(q.max_dihedral_deg < 180.0);
    assert_eq!(q.dihedral_histogram_10deg.iter().sum::<usize>(), 6 * q.tets);
    // boundary nodes end on the box (mean) and within half a cell of it (all)
    assert!(q.mean_boundary_distance_mm.unwrap() < 0.1, "{q:?}");
    assert!(q.max_boundary_distance_mm.unwrap() <= 0.5 * params.edge_mm, "{q:?}");
    // all nodes inside the box up to the snapping tolerance
    for v in &m.vertices {
        assert!((0..3).all(|d| v[d] > lo[d] - 1e-9 - 0.5 * params.edge_mm && v[d] < hi[d] + 0.5 * params.edge_mm));
    }
}

#[test]
fn sphere_volume_against_closed_form_and_determinism() {
    let r = 20.0;
    let c = Vector3::new(3.0, -2.0, 7.0);
    let surf = icosphere(&c, r, 4);
    let s = Surface::new(surf.clone(), "sphere").unwrap();
    let params = TetraParams { edge_mm: 3.0, ..TetraParams::default() };
    let m = tetrahedralize(&s, &params).unwrap();
    check_valid(&m, params.min_dihedral_deg);
    let q = quality_report(&m, Some(&s));
    let ball = 4.0 / 3.0 * std::f64::consts::PI * r.powi(3);
    // the icosphere (5120 faces) is inscribed: its volume is below the ball's by < 0.3 %
    assert!(s.volume() < ball && s.volume() > 0.997 * ball);
    assert!(((q.volume_mm3 - ball) / ball).abs() < 0.02, "mesh {} vs ball {ball}: {q:?}", q.volume_mm3);
    assert!(q.volume_rel_error.unwrap().abs() < 0.02);
    // boundary nodes on the sphere: distance to the centre ≈ r
    let b = m.boundary();
    let mut nb = 0;
    for f in &b.faces {
        for &k in f {
            let d = (m.vertices[k] - c).norm();
            assert!((d - r).abs() < 0.5 * params.edge_mm, "boundary node at {d}");
            nb += 1;
        }
    }
    assert!(nb > 0);
    // interior nodes strictly inside
    assert!(m.vertices.iter().all(|v| (v - c).norm() < r + 0.5 * params.edge_mm));
    // deterministic
    let m2 = tetrahedralize(&s, &params).unwrap();
    assert_eq!(m, m2);
    // finer lattice: smaller volume error
    let fine = tetrahedralize(&s, &TetraParams { edge_mm: 1.5, ..params.clone() }).unwrap();
    let qf = quality_report(&fine, Some(&s));
    assert!(qf.volume_rel_error.unwrap().abs() <= q.volume_rel_error.unwrap().abs() + 1e-3, "{qf:?} vs {q:?}");
    assert!(qf.tets > 6 * q.tets, "halving the edge multiplies tets by ≈8: {} vs {}", qf.tets, q.tets);
}

#[test]
fn bad_inputs_are_named() {
    let mut open = box_surface(&Vector3::zeros(), &Vector3::new(1.0, 1.0, 1.0));
    open.faces.truncate(10);
    let e = tetrahedralize_surface(open, "liver.obj", &TetraParams::default()).unwrap_err().to_string();
    assert!(e.contains("liver.obj") && e.contains("not closed: 4 boundary edges"), "{e}");
    let cube = box_surface(&Vector3::zeros(), &Vector3::new(10.0, 10.0, 10.0));
    for bad in [0.0, -1.0, f64::NAN, 1000.0] {
        let e = tetrahedralize_surface(cube.clone(), "c", &TetraParams { edge_mm: bad, ..TetraParams::default() })
            .unwrap_err()
            .to_string();
        assert!(e.contains("edge_mm"), "{e}");
    }
}
