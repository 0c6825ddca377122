//! `laparo mesh tetra` says what it did to a surface users have (issue 50, item 5): an inconsistently
//! wound closed surface is re-oriented and the command says so (the surface volume in the report is
//! then right), a surface in cm gets a units hint instead of a silent one-tetrahedron mesh.
use std::path::Path;
mod common;
use common::command;

/// A box [0, a] × [0, b] × [0, c] as OBJ, 12 outward triangles; the faces in `flip` wound inward.
fn write_box(path: &Path, (a, b, c): (f64, f64, f64), flip: &[usize]) {
    let v: Vec<[f64; 3]> = (0..8)
        .map(|i| [if i & 1 == 0 { 0.0 } else { a }, if i & 2 == 0 { 0.0 } else { b }, if i & 4 == 0 { 0.0 } else { c }])
        .collect();
    let q = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
    let mut s: String = v.iter().map(|p| format!("v {} {} {}\n", p[0], p[1], p[2])).collect();
    for (i, f) in q.iter().flat_map(|f| [[f[0], f[1], f[2]], [f[0], f[2], f[3]]]).enumerate() {
        let f = if flip.contains(&i) { [f[0], f[2], f[1]] } else { f };
        s += &format!("f {} {} {}\n", f[0] + 1, f[1] + 1, f[2] + 1);
    }
    std::fs::write(path, s).unwrap();
}

fn tetra(surface: &Path, out: &Path, report: &Path, edge: &str) -> (bool, String) {
    let o = command()
        .args(["mesh", "tetra", "--surface"])
        .arg(surface)
        .arg("--out")
        .arg(out)
        .arg("--report")
        .arg(report)
        .args(["--edge-mm", edge])
        .output()
        .unwrap();
    (o.status.success(), String::from_utf8_lossy(&o.stderr).into_owned())
}

#[test]
fn tetra_reorients_an_inconsistent_surface_and_hints_at_units() {
    let t = tempfile::tempdir().unwrap();
    let d = t.path();
    write_box(&d.join("wound.obj"), (60.0, 40.0, 30.0), &[1, 4, 9]);
    let (ok, err) = tetra(&d.join("wound.obj"), &d.join("w.vtk"), &d.join("w.json"), "5");
    assert!(ok, "{err}");
    assert!(err.contains("warning") && err.contains("3 of 12 faces") && err.contains("re-oriented"), "{err}");
    let r: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(d.join("w.json")).unwrap()).unwrap();
    assert_eq!(r["orientation_flipped_faces"], 3);
    assert!((r["surface_volume_mm3"].as_f64().unwrap() - 72_000.0).abs() < 1e-6, "{r}");
    // a 20 x 15 x 10 organ in cm read as mm
    write_box(&d.join("cm.obj"), (20.0, 15.0, 10.0), &[]);
    let (ok, err) = tetra(&d.join("cm.obj"), &d.join("c.vtk"), &d.join("c.json"), "6");
    assert!(ok, "{err}");
    assert!(err.contains("in cm or m") && err.contains("mm³"), "{err}");
}
