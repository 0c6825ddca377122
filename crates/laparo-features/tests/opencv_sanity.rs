//! Detector sanity against OpenCV 4.14 on the shared textures (issue 11 acceptance; protocol of
//! `shared/bench/features_ref.py`, reference table in `shared/spec/features.md` §2):
//! repeatability within ±0.05 of OpenCV's, precision ≥ OpenCV's − 0.03, matching score ≥
//! OpenCV's − 0.05, per texture and detector. Skips when the textures are absent.
use std::path::PathBuf;

use laparo_features::refcheck::{evaluate_homography, load_gray_crop, similarity_h};
use laparo_features::{DetectorConfig, MatchConfig};

/// OpenCV 4.14 figures (features.md §2): texture, SIFT (rep, prec, MS), ORB (rep, prec, MS).
const OPENCV: [(&str, [f64; 3], [f64; 3]); 4] = [
    ("brick.png", [0.785, 0.973, 0.546], [0.839, 0.746, 0.161]),
    ("gravel.png", [0.817, 0.997, 0.515], [0.810, 0.961, 0.344]),
    ("retina.jpg", [0.682, 0.930, 0.564], [0.727, 0.931, 0.500]),
    ("coffee.png", [0.669, 0.973, 0.378], [0.853, 0.953, 0.385]),
];

fn textures() -> Option<PathBuf> {
    let d = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/textures");
    let d = if d.join("brick.png").exists() { d } else { PathBuf::from("/work/shared/data/textures") };
    d.join("brick.png").exists().then_some(d)
}

fn check(detector: &str) {
    let Some(dir) = textures() else {
        eprintln!("SKIP opencv_sanity {detector}: shared/data/textures not found");
        return;
    };
    let det = DetectorConfig::by_name(detector).unwrap();
    let h = similarity_h(30.0, 0.8, 319.5, 239.5);
    let mut failures = vec![];
    for (name, sift, orb) in OPENCV {
        let cv = if detector == "sift" { sift } else { orb };
        let img = load_gray_crop(&dir.join(name), 640, 480).unwrap();
        let r = evaluate_homography(&img, &det, &h, &MatchConfig::default(), 3.0).unwrap();
        eprintln!(
            "{detector} {name}: laparo rep {:.3} prec {:.3} MS {:.3} kp {} | OpenCV rep {:.3} prec {:.3} MS {:.3}",
            r.repeatability, r.precision, r.matching_score, r.kp1, cv[0], cv[1], cv[2]
        );
        if (r.repeatability - cv[0]).abs() > 0.05 {
            failures.push(format!("{name} repeatability {:.3} vs OpenCV {:.3}", r.repeatability, cv[0]));
        }
        if r.precision < cv[1] - 0.03 {
            failures.push(format!("{name} precision {:.3} < OpenCV {:.3} − 0.03", r.precision, cv[1]));
        }
        if r.matching_score < cv[2] - 0.05 {
            failures.push(format!("{name} matching score {:.3} < OpenCV {:.3} − 0.05", r.matching_score, cv[2]));
        }
    }
    assert!(failures.is_empty(), "{detector}: {failures:#?}");
}

#[test]
fn sift_is_as_good_as_opencv_on_shared_textures() {
    check("sift");
}

#[test]
fn orb_is_as_good_as_opencv_on_shared_textures() {
    check("orb");
}
