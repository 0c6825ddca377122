//! `laparo mesh tetra` and `laparo mesh incision` end to end (a sphere surface written here; the
//! P2ILF liver when the real data is present), and clear errors for bad input.
use std::path::{Path, PathBuf};
mod common;
use common::command;

/// An icosphere (radius `r` mm, 3 subdivisions) as OBJ text (laparo-fem's test shape).
fn sphere_obj(r: f64) -> String {
    let m = laparo_fem::mesh::shapes::icosphere(&nalgebra::Vector3::zeros(), r, 3);
    let mut s = String::new();
    for p in &m.vertices {
        s += &format!("v {} {} {}\n", p[0], p[1], p[2]);
    }
    for t in &m.faces {
        s += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    s
}

fn run_ok(args: &[&str]) -> String {
    let o = command().args(args).output().unwrap();
    assert!(o.status.success(), "{:?}: {}", args, String::from_utf8_lossy(&o.stderr));
    String::from_utf8_lossy(&o.stdout).into_owned()
}

#[test]
fn tetra_then_incision_on_a_sphere() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("ball.obj");
    std::fs::write(&obj, sphere_obj(40.0)).unwrap();
    let vtk = dir.path().join("ball.vtk");
    let rep = dir.path().join("q.json");
    let s = |p: &PathBuf| p.display().to_string();
    let out =
        run_ok(&["mesh", "tetra", "--surface", &s(&obj), "--edge-mm", "5", "--out", &s(&vtk), "--report", &s(&rep)]);
    assert!(out.contains("tets"), "{out}");
    let q: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&rep).unwrap()).unwrap();
    assert_eq!(q["inverted"], 0);
    let ball = 4.0 / 3.0 * std::f64::consts::PI * 40f64.powi(3);
    let v = q["volume_mm3"].as_f64().unwrap();
    assert!((v - ball).abs() < 0.03 * ball, "{v} vs {ball}");
    let mesh = laparo_core::mesh::read_vtk(&vtk).unwrap();
    assert_eq!(mesh.tets.len() as u64, q["tets"].as_u64().unwrap());
    // incision along an anterior axis +z
    let cut_dir = dir.path().join("cut");
    let out = run_ok(&[
        "mesh",
        "incision",
        "--mesh",
        &s(&vtk),
        "--scenario",
        "anatomical",
        "--anterior",
        "0,0,1",
        "--out",
        &s(&cut_dir),
    ]);
    assert!(out.contains("anatomical"), "{out}");
    for f in [
        "cut.vtk",
        "lips.json",
        "landmarks.json",
        "tumour.json",
        "fixed_nodes.json",
        "scenario.json",
        "cut.png",
        "crack.png",
    ] {
        assert!(cut_dir.join(f).exists(), "{f}");
    }
    let cut = laparo_core::mesh::read_vtk(cut_dir.join("cut.vtk")).unwrap();
    assert_eq!(cut.tets.len(), mesh.tets.len());
    assert!(cut.vertices.len() > mesh.vertices.len());
    let lm: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(cut_dir.join("landmarks.json")).unwrap()).unwrap();
    for n in [20, 50, 250] {
        assert_eq!(lm[n.to_string()]["items"].as_array().unwrap().len(), n);
    }
    let fixed: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(cut_dir.join("fixed_nodes.json")).unwrap()).unwrap();
    // fixed region: the posterior (−z) cap
    for k in fixed["fixed_nodes"].as_array().unwrap() {
        assert!(cut.vertices[k.as_u64().unwrap() as usize].z < -20.0);
    }
    // the lips of a planar cut through the north pole: a 100 mm arc on the sphere of radius 40
    let lips: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(cut_dir.join("lips.json")).unwrap()).unwrap();
    let l = lips["side_a"]["length_mm"].as_f64().unwrap();
    assert!((l - 100.0).abs() < 25.0, "lip length {l}");
    // another blade and fixed region: a 50 mm cut a third of the way down, 30 % of the surface nodes fixed
    let short = dir.path().join("short");
    let s_ = |p: &PathBuf| p.display().to_string();
    run_ok(&[
        "mesh",
        "incision",
        "--mesh",
        &s_(&vtk),
        "--scenario",
        "anatomical",
        "--anterior",
        "0,0,1",
        "--cut-length-mm",
        "50",
        "--cut-depth-fraction",
        "0.3",
        "--fixed-fraction",
        "0.3",
        "--out",
        &s_(&short),
    ]);
    let read =
        |p: PathBuf| -> serde_json::Value { serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap() };
    let l2 = read(short.join("lips.json"))["side_a"]["length_mm"].as_f64().unwrap();
    assert!((l2 - 50.0).abs() < 15.0 && l2 < l - 25.0, "lip length {l2} (default blade {l})");
    let sc = read(short.join("scenario.json"));
    assert_eq!(sc["params"]["length_mm"], 50.0);
    assert_eq!(sc["frame"]["fixed_fraction"], 0.3);
    let n_fixed = |v: &serde_json::Value| v["fixed_nodes"].as_array().unwrap().len() as f64;
    let ratio = n_fixed(&read(short.join("fixed_nodes.json"))) / n_fixed(&fixed);
    assert!((ratio - 2.0).abs() < 0.2, "fixed nodes 30 % / 15 %: ratio {ratio}");
    // the blade depth, in the plane of the cut through the north pole (z = 40 at the mouth, thickness 80)
    let cut2 = laparo_core::mesh::read_vtk(short.join("cut.vtk")).unwrap();
    let deepest = |c: &laparo_core::mesh::TetMesh, faces: &serde_json::Value| {
        let ids = faces.as_array().unwrap().iter().flat_map(|f| f.as_array().unwrap().iter());
        ids.map(|i| c.vertices[i.as_u64().unwrap() as usize].z).fold(f64::INFINITY, f64::min)
    };
    let sc1 = read(cut_dir.join("scenario.json"));
    let (z1, z2) = (deepest(&cut, &sc1["crack_faces_a"]), deepest(&cut2, &sc["crack_faces_a"]));
    assert!(z2 > z1 + 15.0, "0.3 of the thickness ends higher than 0.6: deepest crack node z {z2} vs {z1} mm");
    // the same blade with its plane shifted 6 mm: the crack moves by about that much
    let shifted = dir.path().join("shifted");
    let mut args = vec!["mesh", "incision", "--scenario", "anatomical", "--anterior", "0,0,1"];
    let (v, o) = (s_(&vtk), s_(&shifted));
    args.extend([
        "--mesh",
        &v,
        "--cut-length-mm",
        "50",
        "--cut-depth-fraction",
        "0.3",
        "--cut-offset-mm=-6",
        "--out",
        &o,
    ]);
    run_ok(&args);
    let sc3 = read(shifted.join("scenario.json"));
    assert_eq!(sc3["params"]["offset_mm"], -6.0);
    let cut3 = laparo_core::mesh::read_vtk(shifted.join("cut.vtk")).unwrap();
    let centre = |c: &laparo_core::mesh::TetMesh, faces: &serde_json::Value| {
        let ids: Vec<usize> = faces
            .as_array()
            .unwrap()
            .iter()
            .flat_map(|f| f.as_array().unwrap().iter())
            .map(|i| i.as_u64().unwrap() as usize)
            .collect();
        ids.iter().map(|&i| c.vertices[i]).sum::<nalgebra::Vector3<f64>>() / ids.len() as f64
    };
    let moved = (centre(&cut3, &sc3["crack_faces_a"]) - centre(&cut2, &sc["crack_faces_a"])).norm();
    assert!((3.0..9.0).contains(&moved), "a 6 mm shift moved the crack's centre by {moved} mm");
}

#[test]
fn bad_inputs_fail_clearly() {
    let dir = tempfile::tempdir().unwrap();
    let open = dir.path().join("open.obj");
    std::fs::write(&open, "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\n").unwrap();
    let o = command()
        .args(["mesh", "tetra", "--surface"])
        .arg(&open)
        .arg("--out")
        .arg(dir.path().join("o.vtk"))
        .output()
        .unwrap();
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("open.obj") && e.contains("not closed: 3 boundary edges"), "{e}");
    let o = command()
        .args(["mesh", "incision", "--mesh"])
        .arg(dir.path().join("missing.vtk"))
        .args(["--scenario", "anatomical", "--out"])
        .arg(dir.path().join("x"))
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("missing.vtk"));
    // blade flags that do not fit the scenario, or out of range: named, before any work
    let obj = dir.path().join("ball.obj");
    std::fs::write(&obj, sphere_obj(30.0)).unwrap();
    let vtk = dir.path().join("ball.vtk");
    run_ok(&["mesh", "tetra", "--surface", obj.to_str().unwrap(), "--edge-mm", "8", "--out", vtk.to_str().unwrap()]);
    for (scenario, flags, named) in [
        ("anatomical", &["--cut-depth-mm", "20"][..], "--cut-depth-mm 20"),
        ("non-anatomical", &["--cut-depth-fraction", "0.5"][..], "--cut-depth-fraction 0.5"),
        ("anatomical", &["--cut-depth-fraction", "1.5"][..], "--cut-depth-fraction 1.5"),
        ("anatomical", &["--cut-length-mm=-5"][..], "--cut-length-mm -5"),
        ("non-anatomical", &["--cut-length-mm", "NaN"][..], "--cut-length-mm NaN"),
        ("anatomical", &["--fixed-fraction", "1"][..], "--fixed-fraction 1"),
        ("non-anatomical", &["--cut-offset-mm", "5"][..], "--cut-offset-mm 5"),
        ("anatomical", &["--cut-offset-mm", "inf"][..], "--cut-offset-mm inf"),
    ] {
        let o = command()
            .args(["mesh", "incision", "--mesh", vtk.to_str().unwrap(), "--scenario", scenario])
            .args(flags)
            .arg("--out")
            .arg(dir.path().join("y"))
            .output()
            .unwrap();
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && e.contains(named) && !e.contains("panicked"), "{named}: {e}");
    }
    assert!(!dir.path().join("y").exists(), "nothing written for a refused blade");
}

#[test]
fn p2ilf_liver_both_scenarios() {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/data/meshes/p2ilf/patient2_1_3d-liver-model.obj");
    if !p.exists() {
        eprintln!("skipping: {} not found (real data absent)", p.display());
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let vtk = dir.path().join("liver.vtk");
    let s = |p: &Path| p.display().to_string();
    let out = run_ok(&["mesh", "tetra", "--surface", &s(&p), "--edge-mm", "6", "--out", &s(&vtk)]);
    eprintln!("{out}");
    for sc in ["non-anatomical", "anatomical"] {
        let d = dir.path().join(sc);
        let out = run_ok(&["mesh", "incision", "--mesh", &s(&vtk), "--scenario", sc, "--out", &s(&d)]);
        eprintln!("{out}");
        let t: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(d.join("tumour.json")).unwrap()).unwrap();
        assert_eq!(t.is_null(), sc == "anatomical");
        if let Ok(keep) = std::env::var("LAPARO_MESH_KEEP") {
            let k = PathBuf::from(keep).join(sc);
            std::fs::create_dir_all(&k).unwrap();
            for f in ["cut.png", "crack.png", "scenario.json", "lips.json"] {
                std::fs::copy(d.join(f), k.join(f)).unwrap();
            }
        }
    }
}
