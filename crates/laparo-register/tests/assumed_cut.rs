//! The cut François et al. and the two-field RODS-MPM assume: from the first lip's source polyline,
//! inward along the surface normal, or in the plane the target lips open across.
use laparo_register::baselines::box_tet_mesh;
use laparo_register::benchmark::methods::{assumed_cut, CutDirection};
use laparo_register::benchmark::LandmarkSet;
use nalgebra::Vector3;

/// Area-weighted mean unit normal of the side-A crack faces.
fn mean_normal(cut: &laparo_fem::mesh::incision::CutMesh) -> Vector3<f64> {
    let v = &cut.mesh.vertices;
    cut.crack_faces[0].iter().map(|f| (v[f[1]] - v[f[0]]).cross(&(v[f[2]] - v[f[0]]))).sum::<Vector3<f64>>().normalize()
}

/// A 40 mm cube; the lip runs along y on the top face (z = 40) at x = 20. The target lips separate along
/// s = (1, 0, 1)/√2: the lip-plane blade leaves the lip along (1, 0, −1)/√2 (the inward normal −z without
/// its component along s), so its crack faces' mean normal is close to ±s; the surface-normal blade goes
/// straight down (mean normal ±x).
#[test]
fn lip_plane_cut_faces_the_separation() {
    let mesh = box_tet_mesh([10, 10, 10], 4.0, Vector3::zeros());
    let mouth: Vec<Vector3<f64>> = (0..=8).map(|k| Vector3::new(20.0, 4.0 + 4.0 * k as f64, 40.0)).collect();
    let s = Vector3::new(1.0, 0.0, 1.0).normalize();
    let lip = |name: &str, side: u8, shift: f64| LandmarkSet {
        name: name.into(),
        side,
        points: Vec::new(),
        sources: mouth.clone(),
        targets: mouth.iter().map(|p| p + s * shift).collect(),
    };
    let lips = [lip("lip 1", 1, -5.0), lip("lip 2", 2, 5.0)];
    let normal = assumed_cut(&mesh, &lips, 16.0, CutDirection::SurfaceNormal).unwrap();
    let n = mean_normal(&normal);
    assert!(n.x.abs() > 0.99, "surface-normal cut: mean crack normal {n:?}");
    let plane = assumed_cut(&mesh, &lips, 16.0, CutDirection::LipSeparation).unwrap();
    let n = mean_normal(&plane);
    assert!(n.dot(&s).abs() > 0.9, "lip-plane cut: mean crack normal {n:?} vs separation {s:?}");
    // one target lip only: no separation direction, named
    let err = assumed_cut(&mesh, &lips[..1], 16.0, CutDirection::LipSeparation).unwrap_err().to_string();
    assert!(err.contains("two target lips"), "{err}");
    let err = assumed_cut(&mesh, &lips, -1.0, CutDirection::SurfaceNormal).unwrap_err().to_string();
    assert!(err.contains("depth"), "{err}");
}
