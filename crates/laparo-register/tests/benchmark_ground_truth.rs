//! The incision benchmark's ground truth on the real P2ILF liver (skips when ../shared/data is absent):
//! the calibrated crack pressure opens the non-anatomical incision to 10–15 mm with no inverted element,
//! the posterior region held, and the far field nearly still.
use laparo_fem::mesh::{non_anatomical, tetrahedralize_surface, NonAnatomicalParams, ScenarioFrame, TetraParams};
use laparo_register::benchmark::build::{case_from, fem_ground_truth, max_gap_mm, node_sides, GroundTruthConfig};
use std::path::PathBuf;

fn liver() -> Option<PathBuf> {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/data/meshes/p2ilf/patient2_1_3d-liver-model.obj");
    if p.exists() {
        Some(p)
    } else {
        eprintln!("skipping: {} is absent", p.display());
        None
    }
}

#[test]
fn non_anatomical_ground_truth_on_the_p2ilf_liver() {
    let Some(path) = liver() else { return };
    let surface = laparo_core::mesh::read_mesh(&path).unwrap();
    let (mesh, q) =
        tetrahedralize_surface(surface, "p2ilf", &TetraParams { edge_mm: 14.0, ..Default::default() }).unwrap();
    assert_eq!(q.inverted, 0);
    let scn = non_anatomical(&mesh, &ScenarioFrame::default(), &NonAnatomicalParams::default()).unwrap();
    let cfg = GroundTruthConfig { steps: 8, ..GroundTruthConfig::for_scenario("non-anatomical") };
    let mut solves = 0;
    let (u, rep) = fem_ground_truth(&scn, &cfg, &mut |_, _, _| solves += 1).unwrap();
    eprintln!("{rep:?}");
    assert!(rep.max_gap_mm >= 10.0 && rep.max_gap_mm <= 15.0, "gap {}", rep.max_gap_mm);
    assert!(rep.min_j > 0.0);
    let def: Vec<_> = scn.cut.mesh.vertices.iter().zip(&u).map(|(a, b)| a + b).collect();
    assert!((max_gap_mm(&scn.cut, &def) - rep.max_gap_mm).abs() < 1e-12);
    for &i in &scn.fixed_nodes {
        assert!(u[i].norm() < 1e-12, "fixed node {i} moved {}", u[i].norm());
    }
    let sides = node_sides(&scn.cut);
    assert!(sides.iter().filter(|&&s| s == 1).count() > 3 && sides.iter().filter(|&&s| s == 2).count() > 3);
    let case = case_from(&scn, &u, None);
    case.validate().unwrap();
    let lm = case.lip_landmarks(20).unwrap();
    // the two lips' targets are apart (the incision opened), their sources coincide
    let d_src = (lm[0].sources[5] - lm[1].sources[5]).norm();
    let d_tgt = (lm[0].targets[5] - lm[1].targets[5]).norm();
    assert!(d_src < 1e-9 && d_tgt > 1.0, "sources {d_src} mm apart, targets {d_tgt} mm");
    assert!(solves >= 1);
}
