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
        tetrahedralize_surface(surface, "p2ilf", &TetraParams { edge_mm: 16.0, ..Default::default() }).unwrap();
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
    // crack nodes are duplicated and labelled with their lip (at 16 mm tets the crack holds very few)
    let mut copies = std::collections::HashMap::new();
    for &o in &scn.cut.original_node {
        *copies.entry(o).or_insert(0usize) += 1;
    }
    let dup = copies.values().filter(|&&c| c >= 2).count();
    let (s1, s2) = (sides.iter().filter(|&&s| s == 1).count(), sides.iter().filter(|&&s| s == 2).count());
    assert!(dup > 0 && s1 >= dup && s2 >= dup, "{dup} duplicated nodes, sides {s1} / {s2}");
    let case = case_from(&scn, &u, None);
    case.validate().unwrap();
    let lm = case.lip_landmarks(20).unwrap();
    // the incision opened: lip 2's landmarks are farther from lip 1's in the ground truth than at rest
    let spread = |p: &[nalgebra::Vector3<f64>], q: &[nalgebra::Vector3<f64>]| {
        p.iter().map(|x| q.iter().map(|y| (x - y).norm()).fold(f64::INFINITY, f64::min)).sum::<f64>() / p.len() as f64
    };
    let (rest, opened) = (spread(&lm[1].sources, &lm[0].sources), spread(&lm[1].targets, &lm[0].targets));
    assert!(opened > rest + 0.5, "lips {rest:.2} mm apart at rest, {opened:.2} mm after the opening");
    assert!(solves >= 1);
}
