//! `cats stats` acceptance: calibrations synthesised with known per-camera rotations from the
//! ideal rectified frame, principal-point offsets and baselines are written as OpenCV YAML and
//! JSON, read back, and the statistics recover them to < 1e-6 deg / px.
use laparo_core::calib::StereoCalibration;
use laparo_core::camera::{Distortion, Intrinsics};
use laparo_core::se3::{euler_zyx, rotation_zyx};
use laparo_stereo::{calib_stats, fitted_cats_config, stereo_extrinsics_from_rotations, summarize};
use laparo_stereo::{CatsConfig, Dist};
use nalgebra::{Rotation3, Vector3};

/// One synthetic calibration and the values the statistics must recover.
struct Case {
    calib: StereoCalibration,
    left_deg: [f64; 3],
    right_deg: [f64; 3],
    offset_px: f64,
    baseline_mm: f64,
}

fn case(i: usize) -> Case {
    let fi = i as f64;
    // Left: a rotation whose axis is orthogonal to X (the only kind "minimal from the left
    // camera" allows), built with nalgebra's axis-angle constructor; expected Euler angles
    // from nalgebra's own Euler decomposition (independent of laparo's).
    let omega = Vector3::new(0.0, (0.3 - 0.17 * fi).to_radians(), (-0.4 + 0.23 * fi).to_radians());
    let r_left = Rotation3::new(omega);
    let (lx, ly, lz) = r_left.euler_angles();
    let left_deg = [lx.to_degrees(), ly.to_degrees(), lz.to_degrees()];
    // Right: any rotation, R = Rz Ry Rx of known angles.
    let right_deg = [0.05 * fi - 0.1, -0.25 + 0.11 * fi, 0.6 - 0.3 * fi];
    let r_right = rotation_zyx(right_deg[0].to_radians(), right_deg[1].to_radians(), right_deg[2].to_radians());
    let baseline_mm = 4.0 + 0.15 * fi;
    let (r, t) = stereo_extrinsics_from_rotations(r_left.matrix(), &r_right, baseline_mm);
    let left = Intrinsics::new(1030.0 + fi, 1029.5 + fi, 590.0 + 3.0 * fi, 515.0, 1280, 1024).unwrap();
    let right = Intrinsics::new(1031.0 - fi, 1030.0, 680.0 + 5.5 * fi, 516.5, 1280, 1024).unwrap();
    let calib = StereoCalibration {
        width: 1280,
        height: 1024,
        left,
        left_dist: Distortion::brown_conrady(-0.0006, -0.0005, 0.0, 0.0, 0.0018),
        right,
        right_dist: Distortion::brown_conrady(-0.0002, -0.0007, 0.0, 0.0, 0.0008),
        r,
        t_mm: t,
    };
    Case { calib, left_deg, right_deg, offset_px: left.cx - right.cx, baseline_mm }
}

fn check(c: &Case, got: &StereoCalibration, what: &str) {
    let s = calib_stats(got).unwrap();
    for k in 0..3 {
        assert!(
            (s.left_euler_deg[k] - c.left_deg[k]).abs() < 1e-6,
            "{what} left[{k}] {} vs {}",
            s.left_euler_deg[k],
            c.left_deg[k]
        );
        assert!(
            (s.right_euler_deg[k] - c.right_deg[k]).abs() < 1e-6,
            "{what} right[{k}] {} vs {}",
            s.right_euler_deg[k],
            c.right_deg[k]
        );
    }
    assert!((s.principal_point_offset_px - c.offset_px).abs() < 1e-6, "{what} offset");
    assert!((s.baseline_mm - c.baseline_mm).abs() < 1e-9, "{what} baseline");
    assert!(s.warnings.is_empty(), "{what}: {:?}", s.warnings);
}

#[test]
fn recovers_rotations_offsets_baselines_in_memory_yaml_and_json() {
    let dir = tempfile::tempdir().unwrap();
    for i in 0..5 {
        let c = case(i);
        check(&c, &c.calib, "in memory");
        let y = dir.path().join(format!("c{i}.yaml"));
        c.calib.write_opencv_yaml(&y).unwrap();
        check(&c, &StereoCalibration::read(&y).unwrap(), "yaml");
        let j = dir.path().join(format!("c{i}.json"));
        c.calib.write_json(&j).unwrap();
        check(&c, &StereoCalibration::read(&j).unwrap(), "json");
    }
}

#[test]
fn left_rotation_is_minimal_and_x_angle_second_order() {
    // The left camera's rotation has no component about the baseline: its axis is orthogonal to X.
    let c = case(3);
    let s = calib_stats(&c.calib).unwrap();
    let r = rotation_zyx(
        s.left_euler_deg[0].to_radians(),
        s.left_euler_deg[1].to_radians(),
        s.left_euler_deg[2].to_radians(),
    );
    let axis = Rotation3::from_matrix_unchecked(r).scaled_axis();
    assert!(axis.x.abs() < 1e-15, "{axis:?}");
    // Sanity of laparo's Euler decomposition against nalgebra's on the right camera.
    let rr = rotation_zyx(0.01, -0.02, 0.03);
    let (a, b, cc) = euler_zyx(&rr);
    let (na, nb, nc) = Rotation3::from_matrix_unchecked(rr).euler_angles();
    assert!((a - na).abs() < 1e-15 && (b - nb).abs() < 1e-15 && (cc - nc).abs() < 1e-15);
}

#[test]
fn summary_and_fitted_config_match_hand_statistics() {
    let cases: Vec<Case> = (0..5).map(case).collect();
    let stats: Vec<_> = cases.iter().map(|c| calib_stats(&c.calib).unwrap()).collect();
    let m = summarize(&stats);
    // Right z angles are 0.6, 0.3, 0.0, −0.3, −0.6: mean 0, population σ = sqrt(0.18).
    assert!(m.right_euler_deg[2].mean.abs() < 1e-9);
    assert!((m.right_euler_deg[2].std - 0.18f64.sqrt()).abs() < 1e-9);
    // Offsets: (590 + 3i) − (680 + 5.5i) = −90 − 2.5i: −90 … −100.
    assert!((m.principal_point_offset_px.min + 100.0).abs() < 1e-9);
    assert!((m.principal_point_offset_px.max + 90.0).abs() < 1e-9);
    let cfg = fitted_cats_config(&m, "synthetic");
    assert_eq!(cfg.disparity_offset.dx_right_px, Dist::uniform(-100.0, 0.0));
    match cfg.right.euler_deg.z {
        Dist::Normal { mean, std } => assert!(mean.abs() < 1e-9 && (std - 0.18f64.sqrt()).abs() < 1e-9),
        d => panic!("{d:?}"),
    }
    // The TOML round-trips through the augmentation engineer's parser.
    let back = CatsConfig::from_toml_str(&cfg.to_toml_string()).unwrap();
    assert_eq!(back, cfg);
}

#[test]
fn odd_calibrations_warn_instead_of_failing() {
    let mut c = case(0).calib;
    // Baseline 30 deg off the image rows.
    let (r, t) = stereo_extrinsics_from_rotations(
        Rotation3::new(Vector3::new(0.0, 0.0, 30f64.to_radians())).matrix(),
        &rotation_zyx(0.0, 0.0, 30f64.to_radians()),
        4.0,
    );
    c.r = r;
    c.t_mm = t;
    c.left_dist = Distortion::brown_conrady(-0.3, 0.1, 0.0, 0.0, 0.0);
    let s = calib_stats(&c).unwrap();
    assert!((s.left_euler_deg[2] - 30.0).abs() < 1e-9);
    assert!(s.warnings.iter().any(|w| w.contains("large rectifying rotation of the left camera")), "{:?}", s.warnings);
    assert!(s.warnings.iter().any(|w| w.contains("left lens distortion")), "{:?}", s.warnings);
    // Swapped cameras.
    let mut c2 = case(1).calib;
    c2.t_mm = -c2.t_mm;
    let s2 = calib_stats(&c2).unwrap();
    assert!(s2.warnings.iter().any(|w| w.contains("swapped")), "{:?}", s2.warnings);
}
