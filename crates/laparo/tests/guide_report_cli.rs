//! The report of `laparo guide` says what the numbers say (issue 50, item 3): every stage against the
//! one before with regressions flagged on the page and in the summary, tumour vertices the particles do
//! not carry as a warning, no bare `null` (a reason beside every missing figure), counts as integers,
//! lips by name, no tracker references. Real P2ILF liver, camera and frame from ../shared/data
//! (skipped with a message when absent).
use std::path::PathBuf;
mod common;
use common::{bare_nulls, run};

fn data() -> Option<PathBuf> {
    let d = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data");
    let need = ["meshes/p2ilf/patient2_1_3d-liver-model.obj", "surgical/p2ilf_frame/P2ILF22_patient1_12.jpg"];
    if need.iter().all(|n| d.join(n).exists()) {
        Some(d)
    } else {
        eprintln!("skipping: ../shared/data (P2ILF liver + frame) is absent");
        None
    }
}

/// The rule of `common::bare_nulls` on hand-made JSON: a `null` field or array element is bare unless a
/// `<key>_reason` string explains it (for an array element: beside the array).
#[test]
fn bare_nulls_finds_unexplained_field_and_array_nulls() {
    let v = serde_json::json!({
        "a": null, "a_reason": "not measured",
        "b": null,
        "c": [1.0, null],
        "d": [null, 2.0], "d_reason": "one route only",
        "e": { "f": [[null]], "g": null, "g_reason": 3 },
    });
    assert_eq!(bare_nulls(&v, "s"), ["s.b", "s.c[1]", "s.e.f[0][0]", "s.e.g"]);
}

#[test]
fn guide_report_compares_stages_warns_and_explains_missing_figures() {
    let Some(d) = data() else { return };
    let tmp = tempfile::tempdir().unwrap();
    let sc = tmp.path().join("scenario");
    let o = run(&[
        "guide",
        "scenario",
        "--quick",
        "--organ",
        d.join("meshes/p2ilf/patient2_1_3d-liver-model.obj").to_str().unwrap(),
        "--frame",
        d.join("surgical/p2ilf_frame/P2ILF22_patient1_12.jpg").to_str().unwrap(),
        "--camera",
        d.join("meshes/p2ilf/acquisition-camera-metadata.json").to_str().unwrap(),
        "--out",
        sc.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // the poses are in the one documented transform form, the direction in the key
    let init: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(sc.join("initial_pose.json")).unwrap()).unwrap();
    assert_eq!(init["model_to_camera"]["R"].as_array().map(|r| r.len()), Some(3), "{init}");
    assert_eq!(init["model_to_camera"]["T"][3], serde_json::json!([0.0, 0.0, 0.0, 1.0]));

    let out = tmp.path().join("run");
    let o = run(&[
        "guide",
        "--scenario",
        sc.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--quick",
        "--iterations",
        "3",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let rep: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let s = &rep["summary"];
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    let warnings: Vec<&str> = s["warnings"].as_array().unwrap().iter().map(|w| w.as_str().unwrap()).collect();

    // no bare null in the summary
    let nulls = bare_nulls(s, "summary");
    assert!(nulls.is_empty(), "nulls without a reason: {nulls:?}");

    // every stage against the one before: the verdict follows from the two figures, and each
    // regression is a warning on the page and in the summary
    let cmp = s["stage_comparison"].as_array().unwrap();
    let figures: Vec<&str> = cmp.iter().map(|c| c["figure"].as_str().unwrap()).collect();
    for f in ["liver TRE, mean (mm)", "liver TRE near the incision (mm)", "mean vertex error (mm)"] {
        assert!(figures.contains(&f), "{f} missing from {figures:?}");
    }
    let mut worse = 0;
    for c in cmp {
        let (Some(b), Some(a)) = (c["before"].as_f64(), c["after"].as_f64()) else {
            assert!(c["worse_reason"].is_string(), "{c}");
            continue;
        };
        let expect = a - b > 0.01 && a > 1.01 * b;
        assert_eq!(c["worse"].as_bool(), Some(expect), "{c}");
        if expect {
            worse += 1;
            let fig = c["figure"].as_str().unwrap();
            assert!(warnings.iter().any(|w| w.starts_with("regression") && w.contains(fig)), "{fig}: {warnings:?}");
        }
    }
    assert_eq!(s["regressions"].as_u64(), Some(worse));
    assert_eq!(html.matches("WORSE").count(), worse as usize);
    assert!(html.contains("Each stage against the one before"));
    // near the incision: better or "does not improve" said on the page
    let near_b = s["tre_rigid_only_near_mm"].as_f64().unwrap();
    let near_a = s["tre_near_mm"].as_f64().unwrap();
    assert_eq!(s["registration_improves_on_rigid_near_incision"].as_bool(), Some(near_a < near_b));
    assert_eq!(html.contains("does not improve on the rigid alignment near the incision"), near_a >= near_b);

    // tumour vertices the particles do not carry: at least those farther than a cell diagonal from
    // every particle; a warning on the page and in the summary when there are any
    let outside = s["tumour_vertices_outside_particles"].as_u64().unwrap() as usize;
    let particles = laparo_core::mesh::read_mesh(out.join("registration/particles_rest.ply")).unwrap().vertices;
    let tumour = laparo_core::mesh::read_mesh(out.join("tumour_aligned.obj")).unwrap().vertices;
    let spacing = rep["config"]["spacing_mm"].as_f64().unwrap();
    let far =
        tumour.iter().filter(|t| particles.iter().all(|p| (*t - p).norm() > 3f64.sqrt() * spacing * 1.001)).count();
    assert!(outside >= far && outside <= tumour.len(), "outside {outside}, farther than a cell diagonal {far}");
    assert_eq!(warnings.iter().any(|w| w.contains("outside the particles")), outside > 0, "{warnings:?}");
    assert_eq!(html.contains("outside the particles ("), outside > 0);
    // every summary warning is on the page
    for w in &warnings {
        let w = w.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;");
        assert!(html.contains(&w), "warning not on the page: {w}");
    }

    // lips by name, counts as integers, no tracker references
    let stages = rep["stages"].as_array().unwrap();
    let lips = stages.iter().find(|st| st["name"] == "target lips").unwrap();
    assert_eq!(lips["metrics"]["lips"][0]["lip"], "lip 0");
    assert_eq!(lips["metrics"]["lips"][1]["colour"], "magenta");
    let e0 = lips["metrics"]["lips"][0]["mean_distance_to_true_lip_mm"].as_f64().unwrap();
    assert!(html.contains(&format!("lip 0 (cyan): {e0:.3} mm")), "lip 0 by name");
    let reg = stages.iter().find(|st| st["name"] == "RODS-MPM registration").unwrap();
    let n = reg["metrics"]["particles"].as_u64().unwrap();
    let it = reg["metrics"]["iterations"].as_u64().unwrap();
    assert!(html.contains(&format!("{n} particles, {it} iterations")), "counts as integers");
    assert!(!html.to_lowercase().contains("issue"), "a tracker reference on the page");
}
