//! Stage 4's outlier test on lifted lip points ([`drop_depth_jumps`]): a point lifted onto another surface
//! (a nearer lobe at an occluding edge) is left out, a smooth lip is kept whole.
use laparo_core::Intrinsics;
use laparo_guide::pipeline::drop_depth_jumps;
use laparo_guide::render::View;
use nalgebra::{Matrix3, Vector3};

#[test]
fn a_point_lifted_onto_a_nearer_surface_is_left_out() {
    // camera at the origin looking down +z; a lip at 90 mm depth along x, one point lifted at 50 mm
    let view = View {
        k: Intrinsics::new(500.0, 500.0, 320.0, 240.0, 640, 480).unwrap(),
        r: Matrix3::identity(),
        t: Vector3::zeros(),
    };
    let mut lip: Vec<Vector3<f64>> = (0..7).map(|k| Vector3::new(-6.0 + 2.0 * k as f64, 0.0, 90.0)).collect();
    let (kept, dropped) = drop_depth_jumps(&lip, &view, 10.0);
    assert_eq!((kept.len(), dropped), (7, 0), "a smooth lip is kept");
    lip[0] *= 50.0 / 90.0; // the first point: same ray, 50 mm from the camera
    lip[3] *= 95.0 / 90.0; // a 5 mm step inside the lip: kept
    let (kept, dropped) = drop_depth_jumps(&lip, &view, 10.0);
    assert_eq!(dropped, 1);
    assert!(kept.iter().all(|p| p.norm() > 80.0), "the 50 mm point is the one left out");
    assert!(kept.contains(&lip[3]));
}
