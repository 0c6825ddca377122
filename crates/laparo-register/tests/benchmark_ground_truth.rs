//! The incision benchmark's ground truth on the real P2ILF liver (skips when ../shared/data is absent):
//! the calibrated crack pressure opens the non-anatomical incision to 10–15 mm with no inverted element,
//! the posterior region held, and the far field nearly still.
use laparo_fem::mesh::{
    non_anatomical_on, tetrahedralize_surface, NonAnatomicalParams, ScenarioFrame, Surface, TetraParams,
};
use laparo_register::benchmark::build::{
    case_from, crack_gap_by_node_mm, drop_detached_fragments, fem_ground_truth, lip_opening_profile_mm, max_gap_mm,
    node_sides, CrackResolution, GroundTruthConfig,
};
use laparo_register::benchmark::figures::write_crack_opening;
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
        tetrahedralize_surface(surface.clone(), "p2ilf", &TetraParams { edge_mm: 16.0, ..Default::default() }).unwrap();
    assert_eq!(q.inverted, 0);
    let mut scn =
        non_anatomical_on(&mesh, &surface, &ScenarioFrame::default(), &NonAnatomicalParams::default()).unwrap();
    drop_detached_fragments(&mut scn);
    // the blade is traced on the input surface: the crack covers most of the blade inside the liver
    let res = CrackResolution::of(&scn, &Surface::new(surface.clone(), "p2ilf").unwrap());
    eprintln!("{res:?}");
    assert!(res.area_fraction() > 0.6 && res.area_fraction() < 1.2, "{res:?}");
    res.check(16.0, 0.6, 5).unwrap();
    let cfg = GroundTruthConfig { steps: 8, ..GroundTruthConfig::for_scenario("non-anatomical") };
    let mut solves = 0;
    let (u, rep) = fem_ground_truth(&scn, &cfg, &mut |_, _, _| solves += 1).unwrap();
    eprintln!("{rep:?}");
    assert!(rep.max_gap_mm >= 10.0 && rep.max_gap_mm <= 15.0, "gap {}", rep.max_gap_mm);
    assert!(rep.min_j > 0.0);
    let def: Vec<_> = scn.cut.mesh.vertices.iter().zip(&u).map(|(a, b)| a + b).collect();
    assert!((max_gap_mm(&scn.cut, &def) - rep.max_gap_mm).abs() < 1e-12);
    // the mouth's opening profile: zero at rest, closed at both crack ends, never above the largest gap
    assert!(lip_opening_profile_mm(&scn.cut, &scn.cut.mesh.vertices).iter().all(|&g| g == 0.0));
    let prof = &rep.lip_opening_mm;
    assert_eq!(prof, &lip_opening_profile_mm(&scn.cut, &def));
    assert!(prof.len() >= 5 && prof.iter().all(|&g| g <= rep.max_gap_mm + 1e-12), "{prof:?}");
    assert!(prof[0] < 0.5 && prof[prof.len() - 1] < 0.5, "the crack ends stay closed: {prof:?}");
    for &i in &scn.fixed_nodes {
        assert!(u[i].norm() < 1e-12, "fixed node {i} moved {}", u[i].norm());
    }
    // the opening field: one gap per duplicated node, its largest the max gap; the front (not duplicated) absent
    let by_node = crack_gap_by_node_mm(&scn.cut, &def);
    let largest = by_node.values().copied().fold(0.0, f64::max);
    assert!((largest - rep.max_gap_mm).abs() < 1e-12, "{largest} vs {}", rep.max_gap_mm);
    assert!(scn.cut.front_nodes.iter().all(|&k| !by_node.contains_key(&scn.cut.original_node[k])));
    assert!(crack_gap_by_node_mm(&scn.cut, &scn.cut.mesh.vertices).values().all(|&g| g == 0.0));
    let tmp = tempfile::tempdir().unwrap();
    let png = tmp.path().join("crack.png");
    write_crack_opening(&png, &scn, Some(&by_node), "non-anatomical crack").unwrap();
    let img = laparo_core::io::read_image(&png).unwrap();
    assert!(img.width > 900 && img.height >= 300, "{}x{}", img.width, img.height);
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

#[test]
fn a_mesh_too_coarse_for_the_incision_is_refused_naming_the_edge() {
    let Some(path) = liver() else { return };
    let surface = laparo_core::mesh::read_mesh(&path).unwrap();
    let organ = Surface::new(surface.clone(), "p2ilf").unwrap();
    let (mesh, _) =
        tetrahedralize_surface(surface.clone(), "p2ilf", &TetraParams { edge_mm: 30.0, ..Default::default() }).unwrap();
    let Ok(mut scn) = non_anatomical_on(&mesh, &surface, &ScenarioFrame::default(), &NonAnatomicalParams::default())
    else {
        return; // at 30 mm the cut may not even reach a lip: also refused, by laparo-fem
    };
    drop_detached_fragments(&mut scn);
    let res = CrackResolution::of(&scn, &organ);
    // blade area inside the organ is a property of the surface, not the mesh: the same as for 16 mm tets
    let (m16, _) =
        tetrahedralize_surface(surface.clone(), "p2ilf", &TetraParams { edge_mm: 16.0, ..Default::default() }).unwrap();
    let s16 = non_anatomical_on(&m16, &surface, &ScenarioFrame::default(), &NonAnatomicalParams::default()).unwrap();
    let r16 = CrackResolution::of(&s16, &organ);
    assert!((res.blade_area_inside_mm2 - r16.blade_area_inside_mm2).abs() < 1e-9);
    eprintln!("30 mm: {res:?}");
    let err = res.check(30.0, 0.6, 5).unwrap_err().to_string();
    assert!(err.contains("edge_mm") && err.contains("does not resolve"), "{res:?}: {err}");
}
