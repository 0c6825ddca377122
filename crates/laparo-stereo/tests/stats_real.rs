//! Real da Vinci calibrations (../shared/data/calib): finite angles within a few degrees, the
//! thesis' "well below 1°" and "< 0.5 px distortion" claims, and the odd student calibration
//! flagged with warnings. Prints our Table 3.6 analogue. Skips when the data is absent.
use laparo_core::calib::StereoCalibration;
use laparo_stereo::{calib_stats, offsets_markdown, per_file_markdown, summarize, table_3_6_markdown};
use std::path::PathBuf;

fn data() -> Option<PathBuf> {
    let d = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data/calib"));
    if d.is_dir() {
        Some(d)
    } else {
        eprintln!("SKIP: {} not found", d.display());
        None
    }
}

#[test]
fn scared_and_endovis_calibrations_are_near_rectified() {
    let Some(d) = data() else { return };
    let mut rows = Vec::new();
    for name in [
        "scared_ds1-3_endoscope_calibration.yaml",
        "scared_ds4-5_endoscope_calibration.yaml",
        "scared_ds8_endoscope_calibration.yaml",
        "ris2017_kidney_ghattab_camera2.yml",
    ] {
        let p = d.join(name);
        if !p.exists() {
            eprintln!("SKIP: {} not found", p.display());
            continue;
        }
        let c = StereoCalibration::read(&p).or_else(|_| StereoCalibration::read_with_size(&p, 1280, 1024)).unwrap();
        let s = calib_stats(&c).unwrap();
        for v in s.left_euler_deg.iter().chain(s.right_euler_deg.iter()) {
            assert!(v.is_finite() && v.abs() < 1.0, "{name}: {s:?}");
        }
        // Thesis §3.3.4: residual distortion "consistently below half a pixel" at 1280x1024. Over
        // the whole image (corners included) SCARED ds4-5 reaches 0.53 px: sub-pixel, not < 0.5.
        assert!(s.max_distortion_px < 1.0, "{name}: {}", s.max_distortion_px);
        // da Vinci: ~4.1–4.4 mm baseline, right principal point ~90–100 px to the right.
        assert!(s.baseline_mm > 4.0 && s.baseline_mm < 4.5, "{name}: {}", s.baseline_mm);
        assert!(s.principal_point_offset_px < -90.0 && s.principal_point_offset_px > -100.0, "{name}");
        assert!(
            !s.warnings.iter().any(|w| w.contains("rotation") || w.contains("swapped")),
            "{name}: {:?}",
            s.warnings
        );
        rows.push((name.to_string(), s));
    }
    if rows.is_empty() {
        return;
    }
    let all: Vec<_> = rows.iter().map(|r| r.1.clone()).collect();
    let scared: Vec<_> = rows.iter().filter(|r| r.0.starts_with("scared")).map(|r| r.1.clone()).collect();
    eprintln!("{}", per_file_markdown(&rows));
    let sums = vec![("SCARED".to_string(), summarize(&scared)), ("SCARED+RIS2017".to_string(), summarize(&all))];
    eprintln!("{}", table_3_6_markdown(&sums));
    eprintln!("{}", offsets_markdown(&sums));
}

#[test]
fn questionable_student_calibration_is_flagged_not_rejected() {
    let Some(d) = data() else { return };
    let (i, e) =
        (d.join("questionable/dvrk_student_intrinsics.yml"), d.join("questionable/dvrk_student_extrinsics.yml"));
    if !(i.exists() && e.exists()) {
        eprintln!("SKIP: questionable calibration not found");
        return;
    }
    let c = StereoCalibration::read_pair_with_size(&i, &e, 640, 480).unwrap();
    let s = calib_stats(&c).unwrap();
    eprintln!("questionable: {s:#?}");
    assert!(s.warnings.iter().any(|w| w.contains("large rectifying rotation")), "{:?}", s.warnings);
    let m = s.left_euler_deg.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    assert!(m > 10.0 && m.is_finite(), "{s:?}");
}
