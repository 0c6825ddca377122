//! Bouguet rectification against OpenCV 5.0.0 `cv2.stereoRectify` (CALIB_ZERO_DISPARITY, and
//! flags = 0) on the SCARED ds1-3 calibration (values embedded below were produced by
//! `stereoRectify(M1, D1, M2, D2, (1280, 1024), R, T, flags, alpha)` from the same numbers).
//! OpenCV undistorts the corner points in float32, so principal points agree to ~1e-3 px; its
//! alpha rectangles come from a 9×9 grid (laparo: every 8th border pixel), yet the alpha = 0 / 1
//! focal lengths also agree to 1e-3 px on this near-distortion-free calibration. R1, R2 agree to 1e-10 (laparo first projects the
//! file's R, orthonormal to ~1e-9 only, onto SO(3); OpenCV goes through Rodrigues).
use laparo_core::calib::StereoCalibration;
use laparo_stereo::{Rectification, RectifyOptions};
use nalgebra::Matrix3;
use std::path::PathBuf;

const R1: [f64; 9] = [
    0.999983316089937,
    0.005768293050245237,
    0.00030714338632735185,
    -0.005768273277730726,
    0.9999833612462854,
    -6.522250049472137e-05,
    -0.00030751449834051344,
    6.344972534060337e-05,
    0.9999999507044816,
];
const R2: [f64; 9] = [
    0.9999833699122487,
    0.005748748353743922,
    0.0004602078964407568,
    -0.005748777950080071,
    0.9999834736541094,
    6.301382124228095e-05,
    -0.0004598380402847475,
    -6.565840632441738e-05,
    0.9999998921189693,
];

fn calib() -> Option<StereoCalibration> {
    let p = PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../../shared/data/calib/scared_ds1-3_endoscope_calibration.yaml"
    ));
    if !p.exists() {
        eprintln!("SKIP: {} not found", p.display());
        return None;
    }
    Some(StereoCalibration::read_with_size(&p, 1280, 1024).unwrap())
}

#[test]
fn matches_opencv_stereo_rectify() {
    let Some(c) = calib() else { return };
    let r = Rectification::new(&c, RectifyOptions { alpha: -1.0, align_principal_points: true }).unwrap();
    assert!((r.r1 - Matrix3::from_row_slice(&R1)).abs().max() < 1e-10, "R1 {}", r.r1);
    assert!((r.r2 - Matrix3::from_row_slice(&R2)).abs().max() < 1e-10, "R2 {}", r.r2);
    assert!((r.focal_px() - 1035.0333249999999).abs() < 1e-9);
    assert!((r.k1.cx - 642.1874618530273).abs() < 2e-3 && (r.k1.cy - 520.7245674133301).abs() < 2e-3, "{:?}", r.k1);
    let (_, p2) = r.projections();
    assert!((p2[(0, 3)] - -4288.6182348753255).abs() < 1e-6, "P2[0,3] = {}", p2[(0, 3)]);
    // flags = 0: each camera keeps its own c_x.
    let r = Rectification::new(&c, RectifyOptions { alpha: -1.0, align_principal_points: false }).unwrap();
    assert!((r.k1.cx - 596.6018218994141).abs() < 2e-3 && (r.k2.cx - 687.7731018066406).abs() < 2e-3);
    assert!((r.k1.cy - 520.7245674133301).abs() < 2e-3 && r.k1.cy == r.k2.cy);
    // alpha = 0 and 1.
    let f0 = Rectification::new(&c, RectifyOptions { alpha: 0.0, align_principal_points: true }).unwrap().focal_px();
    let f1 = Rectification::new(&c, RectifyOptions { alpha: 1.0, align_principal_points: true }).unwrap().focal_px();
    eprintln!("alpha=0: f' = {f0} (OpenCV 1120.3724809123075); alpha=1: f' = {f1} (OpenCV 961.868970602472)");
    assert!((f0 - 1120.3724809123075).abs() < 1e-3, "{f0}");
    assert!((f1 - 961.868970602472).abs() < 1e-3, "{f1}");
}
