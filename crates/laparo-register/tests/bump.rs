//! The "beyond incisions" case ([`BumpCase`]): on an ellipsoid 120 × 80 × 40 mm (thinnest along z, longest
//! along x) the bump sits on the vertex farthest along z, pushes along the inward normal, and its landmark
//! curve lies in the plane x = c.x on the top face; the displacement is the closed-form Gaussian.
use laparo_register::bump::{BumpCase, BumpConfig};
use nalgebra::Vector3;

#[test]
fn bump_case_on_an_ellipsoid() {
    let s = laparo_fem::mesh::shapes::icosphere(&Vector3::zeros(), 1.0, 4);
    let surface = laparo_core::mesh::TriMesh {
        vertices: s.vertices.iter().map(|v| Vector3::new(60.0 * v.x, 40.0 * v.y, 20.0 * v.z)).collect(),
        faces: s.faces.clone(),
    };
    let cfg = BumpConfig { amplitude_mm: 9.0, sigma_mm: 30.0, landmarks: 20 };
    let case = BumpCase::new(&surface, &cfg).unwrap();
    let top = surface.vertices.iter().map(|v| v.z).fold(f64::MIN, f64::max);
    assert!((case.centre.z - top).abs() < 1e-12, "the centre is the vertex farthest along the thin axis");
    assert!(case.direction.z < -0.99, "inward at the top: {}", case.direction);
    assert_eq!(case.landmarks.len(), 20);
    for (k, p) in case.landmarks.iter().enumerate() {
        assert!((p.x - case.centre.x).abs() < 1e-9, "on the plane across the long axis: {p}");
        assert!((p - case.centre).norm() <= 60.0 + 1e-9 && p.z > 0.0, "within 2σ, on the top face: {p}");
        let e = (p.x / 60.0).powi(2) + (p.y / 40.0).powi(2) + (p.z / 20.0).powi(2);
        assert!(e <= 1.0 + 1e-9 && e > 0.97, "on the faceted ellipsoid: {e}");
        if k > 0 {
            let dir = case.landmarks[1].y - case.landmarks[0].y;
            assert!((p.y - case.landmarks[k - 1].y) * dir > 0.0, "ordered along the curve");
        }
        let r2 = (p - case.centre).norm_squared();
        let want = p + case.direction * 9.0 * (-r2 / (2.0 * 30.0 * 30.0)).exp();
        assert!((case.target[k] - want).norm() < 1e-12);
    }
    assert!((case.displacement(&case.centre) - case.direction * 9.0).norm() < 1e-12);
    let bad = BumpConfig { sigma_mm: 0.0, ..cfg };
    assert!(BumpCase::new(&surface, &bad).unwrap_err().to_string().contains("sigma_mm"));
}
