//! `laparo fem solve`: outputs, agreement with the library, clear errors.
use laparo_core::io::read_npy;
use laparo_core::mesh::{write_vtk, TetMesh};
use laparo_fem::solid::{solve, FaceTraction, Loads, Quadrature, SolidProblem, SolverSettings, Tet10Mesh};
use laparo_fem::NeoHookean;
use nalgebra::Vector3;
mod common;
use common::run;

/// Box [0,10]×[0,10]×[0,20] mm of 2×2×4 cubes, 6 tets each.
fn column() -> TetMesh {
    laparo_fem::mesh::shapes::kuhn_box([2, 2, 4], 5.0)
}

#[test]
fn fem_solve_writes_displacements_that_match_the_library() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = column();
    let mpath = dir.path().join("col.vtk");
    write_vtk(&mpath, &mesh).unwrap();
    let bottom: Vec<usize> = (0..mesh.vertices.len()).filter(|&i| mesh.vertices[i].z == 0.0).collect();
    let top: Vec<[usize; 3]> =
        mesh.boundary().faces.into_iter().filter(|f| f.iter().all(|&i| mesh.vertices[i].z == 20.0)).collect();
    std::fs::write(dir.path().join("fixed.json"), serde_json::json!({ "vertices": bottom }).to_string()).unwrap();
    // Outward normal of the top faces is +z: a normal traction of −0.3 kPa pushes down; plus a shear.
    let ft: Vec<_> = top.iter().map(|f| serde_json::json!({"face": f, "normal_traction_kpa": -0.3})).collect();
    let loads =
        serde_json::json!({"face_tractions": ft, "nodal_forces": [{"vertex": top[0][0], "force_mn": [1.0, 0.0, 0.0]}]});
    std::fs::write(dir.path().join("loads.json"), loads.to_string()).unwrap();
    let out = dir.path().join("out");
    let o = run(&[
        "fem",
        "solve",
        "--mesh",
        mpath.to_str().unwrap(),
        "--fixed",
        dir.path().join("fixed.json").to_str().unwrap(),
        "--loads",
        dir.path().join("loads.json").to_str().unwrap(),
        "--steps",
        "5",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let u = read_npy(out.join("displacement.npy")).unwrap();
    assert_eq!((u.height, u.width), (mesh.vertices.len(), 3));
    let u10 = read_npy(out.join("displacement_tet10.npy")).unwrap();
    assert!(u10.height > mesh.vertices.len());
    // The same problem through the library.
    let m10 = Tet10Mesh::from_linear(&mesh).unwrap();
    let fixed = SolidProblem::fixed_vertices(&m10, &bottom).unwrap();
    let lib_loads = Loads {
        face_tractions: top
            .iter()
            .map(|&face| FaceTraction { face, traction_kpa: Vector3::new(0.0, 0.0, -0.3) })
            .collect(),
        nodal_forces: vec![laparo_fem::solid::NodalForce { node: top[0][0], force_mn: Vector3::x() }],
        body_force: None,
    };
    let p = SolidProblem::new(m10, NeoHookean::liver(), &fixed, &lib_loads, Quadrature::Degree2).unwrap();
    let s = solve(&p, &SolverSettings { steps: 5, ..Default::default() }).unwrap();
    let mut worst: f64 = 0.0;
    for (i, d) in s.vertex_displacements().iter().enumerate() {
        for c in 0..3 {
            worst = worst.max((u.data[3 * i + c] - d[c]).abs());
        }
    }
    assert!(worst < 1e-12, "CLI vs library {worst:e}");
    // Pushed down: the top moves in −z; total force = −0.3 kPa × 100 mm² in z.
    let top_v = top[0][1];
    assert!(u.data[3 * top_v + 2] < -0.05, "{}", u.data[3 * top_v + 2]);
    let rep: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let fz = rep["total_external_force_mn"][2].as_f64().unwrap();
    assert!((fz + 30.0).abs() < 1e-9, "{fz}");
    // Five increments (a cut increment adds sub-increment reports with the same `step`).
    let steps = rep["solution"]["steps"].as_array().unwrap();
    assert!(steps.len() >= 5 && steps.last().unwrap()["step"] == 5 && steps.last().unwrap()["load_factor"] == 1.0);
    assert!(rep["solution"]["min_j"].as_f64().unwrap() < 1.0);
    let vtk = std::fs::read_to_string(out.join("displacement.vtk")).unwrap();
    assert!(vtk.contains(&format!("POINT_DATA {}\nVECTORS displacement double", mesh.vertices.len())));
}

#[test]
fn fem_solve_bad_inputs_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let mpath = dir.path().join("col.vtk");
    write_vtk(&mpath, &column()).unwrap();
    let fixed = dir.path().join("fixed.json");
    let loads = dir.path().join("loads.json");
    std::fs::write(&fixed, r#"{"vertices": []}"#).unwrap();
    std::fs::write(&loads, r#"{"nodal_forces": [{"vertex": 3, "force_mn": [0, 0, 1]}]}"#).unwrap();
    let out = dir.path().join("out");
    let args = |f: &str, l: &str| {
        run(&[
            "fem",
            "solve",
            "--mesh",
            mpath.to_str().unwrap(),
            "--fixed",
            f,
            "--loads",
            l,
            "--out",
            out.to_str().unwrap(),
        ])
    };
    let o = args(fixed.to_str().unwrap(), loads.to_str().unwrap());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && e.contains("--fixed") && e.contains("rigid"), "{e}");
    std::fs::write(&fixed, r#"{"vertices": [0, 1, 2, 5]}"#).unwrap();
    std::fs::write(&loads, r#"{"nodal_forces": [{"vertex": 999, "force_mn": [0, 0, 1]}]}"#).unwrap();
    let o = args(fixed.to_str().unwrap(), loads.to_str().unwrap());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && e.contains("loads.json") && e.contains("999"), "{e}");
    std::fs::write(&loads, r#"{"face_tractions": [{"face": [0, 1, 2]}]}"#).unwrap();
    let o = args(fixed.to_str().unwrap(), loads.to_str().unwrap());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && e.contains("exactly one"), "{e}");
    assert!(!out.exists());
}
