//! Ground-truth protocol (thesis §4.5.1) acceptance: exact transfers, a hand-computed two-way
//! average, unverifiable cases, bad input.
use laparo_core::image::{Image, Mask};
use laparo_core::se3::se3_from_rt;
use laparo_core::{Intrinsics, Se3};
use laparo_features::gt::{evaluate_matches, evaluate_points, DepthView, EvalConfig, GroundTruth, MatchLabel};
use laparo_features::{Keypoint, Match};
use nalgebra::{Matrix3, Point3, Rotation3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn kp(x: f64, y: f64) -> Keypoint {
    Keypoint { x, y, size_px: 1.0, angle_rad: 0.0, response: 1.0, octave: 0 }
}
fn m(i1: u32, i2: u32) -> Match {
    Match { i1, i2, distance: 0.0 }
}

#[test]
fn hand_computed_two_way_average() {
    // x₂ = 2 x₁. Match a = (1, 1) ↔ b = (3, 2): H a = (2, 2), ‖H a − b‖ = 1;
    // H⁻¹ b = (1.5, 1), ‖H⁻¹ b − a‖ = 0.5; two-way average = 0.75 px.
    // Match c = (10, 10) ↔ d = (24, 20): H c = (20, 20), error 4; H⁻¹ d = (12, 10), error 2 → 3.
    let h = Matrix3::new(2.0, 0.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 1.0);
    let kp1 = [kp(1.0, 1.0), kp(10.0, 10.0)];
    let kp2 = [kp(3.0, 2.0), kp(24.0, 20.0)];
    let r =
        evaluate_matches(&kp1, &kp2, &[m(0, 0), m(1, 1)], &GroundTruth::Homography(h), &EvalConfig::default()).unwrap();
    assert_eq!(r.transfer_error_px, vec![0.75, 3.0]);
    // ε = 3 is strict: 3.0 is wrong
    assert_eq!(r.labels, vec![MatchLabel::Correct, MatchLabel::Wrong]);
    assert_eq!((r.n_correct, r.n_matches, r.precision), (1, 2, 0.5));
    // matching score: both image-1 keypoints transfer → 1 / 2
    assert_eq!(r.matching_score, 0.5);
    // GT-matchable: (0,0) mutual nearest with error 0.75 < 3; (1,1) error 3 (not < 3) → 1 pair
    assert_eq!(r.n_matchable, 1);
    assert_eq!(r.recall, 1.0);
    // repeatability in image 2's frame: H·kp1 = (2,2), (20,20) vs kp2 (3,2), (24,20):
    // distances 1 (< 3) and 4 (≥ 3) → ½ (1/2 + 1/2) = 0.5
    assert_eq!(r.repeatability, 0.5);
    // with ε = 3.5 both are correct
    let r = evaluate_matches(
        &kp1,
        &kp2,
        &[m(0, 0), m(1, 1)],
        &GroundTruth::Homography(h),
        &EvalConfig { eps_px: 3.5, ..Default::default() },
    )
    .unwrap();
    assert_eq!(r.n_correct, 2);
}

#[test]
fn recall_counts_matchable_pairs_among_detected() {
    // identity GT; image 1: 4 keypoints, image 2: 3 of them moved by 0.5 px + one far away
    let h = Matrix3::identity();
    let p1 = [[10.0, 10.0], [50.0, 10.0], [10.0, 50.0], [50.0, 50.0]];
    let p2 = [[10.5, 10.0], [50.0, 10.5], [10.0, 50.5], [200.0, 200.0]];
    // matches: (0,0) correct; (1,2) wrong; (3,3) wrong
    let r = evaluate_points(&p1, &p2, &[(0, 0), (1, 2), (3, 3)], &GroundTruth::Homography(h), &EvalConfig::default())
        .unwrap();
    assert_eq!(r.n_matchable, 3); // (0,0), (1,1), (2,2)
    assert_eq!(r.n_correct, 1);
    assert!((r.recall - 1.0 / 3.0).abs() < 1e-15);
    assert_eq!(r.repeatability, 0.5 * (3.0 / 4.0 + 3.0 / 4.0));
}

/// Camera looking down +z at the plane z = `z0` mm; image 2 from a camera translated in x, y and
/// rotated about its optical axis, so both depth maps are constant and the transfer is exact.
fn plane_views(z0: f64) -> (Intrinsics, Image<f64>, Se3, Se3) {
    let k = Intrinsics::new(400.0, 400.0, 159.5, 119.5, 320, 240).unwrap();
    let depth = Image::filled(320, 240, 1, z0);
    let pose1 = Se3::identity();
    let r = *Rotation3::from_axis_angle(&Vector3::z_axis(), 0.3).matrix();
    let pose2 = se3_from_rt(&r, &Vector3::new(-12.0, 7.0, 0.0));
    (k, depth, pose1, pose2)
}

#[test]
fn exact_synthetic_correspondences_have_zero_error() {
    let (k, depth, pose1, pose2) = plane_views(100.0);
    let v1 = DepthView::new("view 1", &depth, &k, Some(pose1), None).unwrap();
    let v2 = DepthView::new("view 2", &depth, &k, Some(pose2), None).unwrap();
    let gt = GroundTruth::DepthPose(v1, v2);
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let (mut p1, mut p2) = (vec![], vec![]);
    while p1.len() < 200 {
        let a = [rng.gen_range(20.0..300.0), rng.gen_range(20.0..220.0)];
        // independent projection: back-project at z0, move to camera 2, project
        let x = Point3::new((a[0] - 159.5) / 400.0 * 100.0, (a[1] - 119.5) / 400.0 * 100.0, 100.0);
        let y = pose2.transform_point(&x);
        let b = [400.0 * y.x / y.z + 159.5, 400.0 * y.y / y.z + 119.5];
        if b[0] < 1.0 || b[1] < 1.0 || b[0] > 318.0 || b[1] > 238.0 {
            continue;
        }
        p1.push(a);
        p2.push(b);
    }
    let pairs: Vec<(usize, usize)> = (0..p1.len()).map(|i| (i, i)).collect();
    let r = evaluate_points(&p1, &p2, &pairs, &gt, &EvalConfig::default()).unwrap();
    let worst = r.transfer_error_px.iter().cloned().fold(0.0, f64::max);
    assert!(worst <= 1e-6, "max transfer error {worst} px");
    assert_eq!(r.n_correct, 200);
    assert_eq!(r.n_matchable, 200);
    assert_eq!((r.precision, r.recall, r.repeatability), (1.0, 1.0, 1.0));
}

#[test]
fn unverifiable_outside_occluded_no_depth_roi() {
    let (k, depth, pose1, pose2) = plane_views(100.0);
    // view 2: an occluder (depth 60 mm) over a block, a hole (0 = no depth), ROI excludes a strip
    let mut d2 = depth.clone();
    for y in 100..140 {
        for x in 100..140 {
            d2.set(x, y, 0, 60.0);
        }
    }
    for y in 0..240 {
        for x in 250..260 {
            d2.set(x, y, 0, 0.0);
        }
    }
    let mut roi1 = Mask::filled(320, 240, 1, true);
    for y in 0..240 {
        for x in 0..30 {
            roi1.set(x, y, 0, false);
        }
    }
    let v1 = DepthView::new("view 1", &depth, &k, Some(pose1), Some(&roi1)).unwrap();
    let v2 = DepthView::new("view 2", &d2, &k, Some(pose2), None).unwrap();
    let gt = GroundTruth::DepthPose(v1, v2);
    let fwd = |a: [f64; 2]| {
        let x = Point3::new((a[0] - 159.5) / 400.0 * 100.0, (a[1] - 119.5) / 400.0 * 100.0, 100.0);
        let y = pose2.transform_point(&x);
        [400.0 * y.x / y.z + 159.5, 400.0 * y.y / y.z + 119.5]
    };
    // find points that land in the occluder, in the hole, outside image 2, and a clean one
    let mut found = [None; 4];
    for yi in 0..240 {
        for xi in 30..320 {
            let a = [xi as f64 + 0.25, yi as f64 + 0.25];
            let b = fwd(a);
            let cls = if b[0] < -1.0 || b[1] < -1.0 || b[0] > 321.0 || b[1] > 241.0 {
                2
            } else if (102.0..138.0).contains(&b[0]) && (102.0..138.0).contains(&b[1]) {
                0
            } else if (252.0..257.0).contains(&b[0]) && (5.0..235.0).contains(&b[1]) {
                1
            } else if (160.0..200.0).contains(&b[0]) && (160.0..200.0).contains(&b[1]) {
                3
            } else {
                continue;
            };
            found[cls].get_or_insert((a, b));
        }
    }
    let f: Vec<([f64; 2], [f64; 2])> = found.iter().map(|v| v.expect("scene covers all cases")).collect();
    assert!(gt.transfer_1to2(f[0].0).is_none(), "occluded");
    assert!(gt.transfer_1to2(f[1].0).is_none(), "no depth in view 2");
    assert!(gt.transfer_1to2(f[2].0).is_none(), "outside view 2");
    let q = gt.transfer_1to2(f[3].0).unwrap();
    assert!((q[0] - f[3].1[0]).abs() < 1e-9 && (q[1] - f[3].1[1]).abs() < 1e-9);
    // outside the ROI of view 1: no depth used there
    assert!(gt.transfer_1to2([10.0, 100.0]).is_none());
    // a match involving an unverifiable point is counted separately, never correct
    let p1: Vec<[f64; 2]> = f.iter().map(|v| v.0).collect();
    let p2: Vec<[f64; 2]> = f.iter().map(|v| v.1).collect();
    let r = evaluate_points(&p1, &p2, &[(0, 0), (1, 1), (2, 2), (3, 3)], &gt, &EvalConfig::default()).unwrap();
    assert_eq!(r.n_unverifiable, 3);
    assert_eq!(r.n_correct, 1);
    assert_eq!(r.precision, 0.25);
    assert_eq!(r.precision_verifiable, 1.0);
    assert!(r.transfer_error_px[0].is_nan());
}

#[test]
fn no_interpolation_across_roi_edge_or_depth_step() {
    let k = Intrinsics::new(400.0, 400.0, 9.5, 9.5, 20, 20).unwrap();
    let mut d = Image::filled(20, 20, 1, 100.0);
    for y in 0..20 {
        for x in 10..20 {
            d.set(x, y, 0, 200.0);
        }
    }
    let v = DepthView { depth_mm: &d, intrinsics: &k, cam_from_world: Se3::identity(), roi: None };
    // between columns 9 (100) and 10 (200): nearest, not the 150 mm average
    assert_eq!(v.depth_at(9.4, 5.0, 5.0), Some(100.0));
    assert_eq!(v.depth_at(9.6, 5.0, 5.0), Some(200.0));
    // smooth region: bilinear
    let mut g = Image::filled(20, 20, 1, 0.0);
    for y in 0..20 {
        for x in 0..20 {
            g.set(x, y, 0, 100.0 + x as f64 + 0.5 * y as f64);
        }
    }
    let mut roi = Mask::filled(20, 20, 1, true);
    roi.set(6, 5, 0, false);
    let v = DepthView { depth_mm: &g, intrinsics: &k, cam_from_world: Se3::identity(), roi: Some(&roi) };
    assert!((v.depth_at(3.25, 4.5, 5.0).unwrap() - (100.0 + 3.25 + 2.25)).abs() < 1e-12);
    // neighbour (6,5) outside the ROI: nearest pixel (5,5) only
    assert_eq!(v.depth_at(5.25, 5.25, 5.0), Some(100.0 + 5.0 + 2.5));
    assert_eq!(v.depth_at(5.75, 5.25, 5.0), None); // nearest pixel is outside the ROI
}

#[test]
fn bad_input_names_the_input() {
    let (k, depth, pose1, _) = plane_views(100.0);
    let e = DepthView::new("view 2", &depth, &k, None, None).unwrap_err().to_string();
    assert!(e.contains("view 2 pose") && e.contains("missing"), "{e}");
    let mut dn = depth.clone();
    dn.set(7, 3, 0, f64::NAN);
    let e = DepthView::new("left.png", &dn, &k, Some(pose1), None).unwrap_err().to_string();
    assert!(e.contains("left.png depth") && e.contains("NaN at pixel (x 7, y 3)"), "{e}");
    // a struct built by hand is validated by evaluate_matches too
    let v1 = DepthView { depth_mm: &dn, intrinsics: &k, cam_from_world: pose1, roi: None };
    let v2 = DepthView { depth_mm: &depth, intrinsics: &k, cam_from_world: pose1, roi: None };
    let e = evaluate_points(
        &[[1.0, 1.0]],
        &[[1.0, 1.0]],
        &[(0, 0)],
        &GroundTruth::DepthPose(v1, v2),
        &EvalConfig::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("view 1 depth") && e.contains("NaN"), "{e}");
    let e = evaluate_points(
        &[[1.0, 1.0]],
        &[[1.0, 1.0]],
        &[(0, 3)],
        &GroundTruth::Homography(Matrix3::identity()),
        &EvalConfig::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("match 0") && e.contains("out of range"), "{e}");
    let small = Image::filled(10, 10, 1, 1.0);
    let e = DepthView::new("view 1", &small, &k, Some(pose1), None).unwrap_err().to_string();
    assert!(e.contains("view 1 depth") && e.contains("10x10"), "{e}");
}
