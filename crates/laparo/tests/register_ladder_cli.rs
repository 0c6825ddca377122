//! The RODS-MPM ladder's flags through the CLI: bad values are refused by name before any work, and the
//! rung names are listed by the error of an unknown one.
mod common;
use common::laparo_in;

#[test]
fn at_rest_weight_and_rung_names_are_checked_at_the_boundary() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for bad in ["-1", "nan", "inf"] {
        let flag = format!("--at-rest-weight={bad}");
        let (ok, _, err) = laparo_in(
            &["register", "--organ", "o.obj", "--landmarks", "l.json", "--target", "t.json", "--out", "out", &flag],
            d,
        );
        assert!(!ok && err.contains("--at-rest-weight"), "{bad}: {err}");
        let (ok, _, err) = laparo_in(&["register", "benchmark", "--quick", &flag, "--out", "b"], d);
        assert!(!ok && err.contains("--at-rest-weight"), "{bad}: {err}");
    }
    let (ok, _, err) = laparo_in(&["register", "benchmark", "--quick", "--methods", "none,rods-l9", "--out", "b"], d);
    assert!(!ok, "{err}");
    for rung in ["rods-l0", "rods-l1-blind", "rods-l1", "rods-l2", "rods-l3"] {
        assert!(err.contains(rung), "the error lists {rung}: {err}");
    }
    assert!(!d.join("b").exists() && !d.join("out").exists(), "nothing written");
}

/// A 40 × 24 × 16 mm box (two triangles per face, outward).
fn box_obj(path: &std::path::Path) {
    let v = |x, y, z| nalgebra::Vector3::new(x, y, z);
    laparo_core::mesh::write_obj(path, &laparo_core::mesh::TriMesh::cuboid(&v(0.0, 0.0, 0.0), &v(40.0, 24.0, 16.0)))
        .unwrap();
}

/// `laparo register --unknown loads --assumed-cut-depth-mm`: the crack-aware rung L3 outside the benchmark.
/// Two lips along the box's top face pulled apart: the run ends closer to the targets, writes the cut it
/// assumed, and report.json records the unknown and the load work in its energy audit. Bad values are
/// refused by name, nothing written.
#[test]
fn loads_on_a_cut_assumed_from_the_lip() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    box_obj(&d.join("box.obj"));
    let lip = |y: f64| -> String {
        (0..5).map(|k| format!("[{}, {y}, 16.0]", 12.0 + 4.0 * k as f64)).collect::<Vec<_>>().join(", ")
    };
    std::fs::write(
        d.join("L.json"),
        format!(
            r#"{{"groups": [{{"name": "mid", "points": [{}]}}, {{"name": "a", "points": [{}]}}, {{"name": "b", "points": [{}]}}]}}"#,
            lip(12.0),
            lip(11.0),
            lip(13.0)
        ),
    )
    .unwrap();
    std::fs::write(
        d.join("T.json"),
        format!(
            r#"{{"groups": [{{"name": "mid", "type": "cloud", "points": [{}]}}, {{"name": "a", "type": "polyline", "points": [{}]}}, {{"name": "b", "type": "polyline", "points": [{}]}}]}}"#,
            lip(12.0),
            lip(9.0),
            lip(15.0)
        ),
    )
    .unwrap();
    std::fs::write(d.join("one.json"), r#"{"groups": [{"name": "dot", "points": [[20.0, 12.0, 16.0]]}]}"#).unwrap();
    let base = ["register", "--organ", "box.obj", "--spacing-mm", "2", "--steps", "200", "--iterations", "10"];
    let with = |extra: &[&str]| -> Vec<String> { base.iter().chain(extra).map(|s| s.to_string()).collect() };
    let run = |args: Vec<String>| {
        let a: Vec<&str> = args.iter().map(String::as_str).collect();
        laparo_in(&a, d)
    };
    // refused by name before any work
    for (extra, needle) in [
        (vec!["--landmarks", "L.json", "--target", "T.json", "--out", "o1", "--unknown", "forces"], "loads"),
        (
            vec![
                "--landmarks",
                "L.json",
                "--target",
                "T.json",
                "--out",
                "o2",
                "--unknown",
                "loads",
                "--damping-per-horizon=-1",
            ],
            "damping_per_horizon",
        ),
        (
            vec![
                "--landmarks",
                "L.json",
                "--target",
                "T.json",
                "--out",
                "o3",
                "--assumed-cut-depth-mm",
                "10",
                "--assumed-cut-group",
                "nope",
            ],
            "nope",
        ),
        (
            vec!["--landmarks", "one.json", "--target", "one.json", "--out", "o4", "--assumed-cut-depth-mm", "10"],
            "1 distinct point",
        ),
        (vec!["--landmarks", "L.json", "--target", "T.json", "--out", "o5", "--assumed-cut-depth-mm", "0"], "depth"),
        (
            vec![
                "--landmarks",
                "L.json",
                "--target",
                "T.json",
                "--out",
                "o6",
                "--assumed-cut-depth-mm",
                "5",
                "--crack",
                "box.obj",
            ],
            "--crack",
        ),
    ] {
        let (ok, _, err) = run(with(&extra));
        assert!(!ok && err.contains(needle), "{extra:?}: {err}");
        assert!(!err.contains("panicked"), "{err}");
    }
    for o in ["o1", "o2", "o3", "o4", "o5", "o6"] {
        assert!(!d.join(o).join("report.json").exists(), "{o}: nothing written");
    }
    let (ok, out, err) = run(with(&[
        "--landmarks",
        "L.json",
        "--target",
        "T.json",
        "--out",
        "l3",
        "--unknown",
        "loads",
        "--assumed-cut-depth-mm",
        "10",
        "--assumed-cut-group",
        "mid",
    ]));
    assert!(ok, "{out}\n{err}");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("l3/report.json")).unwrap()).unwrap();
    assert!(report["optimizer"]["unknown"].get("loads").is_some(), "{}", report["optimizer"]["unknown"]);
    let before = report["mean_distance_mm"][0].as_f64().unwrap();
    let after = report["mean_distance_mm"][1].as_f64().unwrap();
    assert!(after < 0.85 * before, "{before} → {after}");
    for g in 1..3 {
        let (b, a) = (&report["residual_before"][g], &report["residual_after"][g]);
        assert!(a["mean"].as_f64().unwrap() < 0.85 * b["mean"].as_f64().unwrap(), "lip {}: {b} → {a}", a["name"]);
    }
    let e = &report["energy"];
    assert_eq!(e["kinetic_initial"].as_f64(), Some(0.0), "{e}");
    assert!(e["external_work"].as_f64().unwrap() > 0.0, "{e}");
    let crack = laparo_core::mesh::read_ply(d.join("l3/crack_surface.ply")).unwrap();
    assert_eq!((crack.vertices.len(), crack.faces.len()), (10, 8), "a ribbon: two vertices per lip point");
    assert!(
        report["crack"]["particles"][0].as_u64().unwrap() > 0 && report["crack"]["particles"][1].as_u64().unwrap() > 0
    );
}
