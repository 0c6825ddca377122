//! The mesh baselines on a cracked mesh (duplicated nodes along a cut, as the incision benchmark's
//! François et al. variant gives them): each lip is pulled towards its own target polyline; ARAP and
//! DRBC open the crack (the duplicated nodes separate), LDDMM cannot (one smooth flow moves both copies
//! of a node identically, thesis Figs. 5.6/5.7).
use laparo_register::baselines::*;
use laparo_register::distance::Polyline;
use laparo_register::loss::GroupTarget;
use nalgebra::Vector3;
use std::sync::Arc;

/// A 6×4×4-cell box (5 mm cells) cut on the plane x = 15 mm from the top (z = 20) down to z = 10:
/// the nodes of that plane strictly above z = 10 are duplicated for the tets on the x > 15 side.
/// Returns the mesh and the (original, copy) node pairs.
fn cracked() -> (laparo_core::mesh::TetMesh, Vec<(usize, usize)>) {
    let mut m = box_tet_mesh([6, 4, 4], 5.0, Vector3::zeros());
    let on_cut = |v: &Vector3<f64>| (v.x - 15.0).abs() < 1e-9 && v.z > 10.0 + 1e-9;
    let mut copy = vec![None; m.vertices.len()];
    let mut pairs = Vec::new();
    for t in 0..m.tets.len() {
        let c: Vector3<f64> = m.tets[t].iter().map(|&i| m.vertices[i]).sum::<Vector3<f64>>() / 4.0;
        if c.x <= 15.0 {
            continue;
        }
        for a in 0..4 {
            let i = m.tets[t][a];
            if on_cut(&m.vertices[i]) {
                let j = *copy[i].get_or_insert_with(|| {
                    m.vertices.push(m.vertices[i]);
                    pairs.push((i, m.vertices.len() - 1));
                    m.vertices.len() - 1
                });
                m.tets[t][a] = j;
            }
        }
    }
    (m, pairs)
}

fn problem() -> (BaselineProblem, Vec<(usize, usize)>) {
    let (m, pairs) = cracked();
    // landmarks: the top-edge nodes of the cut, one lip each; targets: the lips 3 mm apart
    let top: Vec<(usize, usize)> = pairs.iter().copied().filter(|&(i, _)| m.vertices[i].z == 20.0).collect();
    let mk = |name: &str, nodes: Vec<usize>, dx: f64| MeshLandmarkGroup {
        name: name.into(),
        points: nodes.iter().map(|&i| MaterialPoint::node(i)).collect(),
        target: GroupTarget::Shared(Arc::new(Polyline::open(vec![
            Vector3::new(15.0 + dx, -1.0, 20.0),
            Vector3::new(15.0 + dx, 21.0, 20.0),
        ]))),
        weight: 1.0,
    };
    let groups = vec![
        mk("left lip", top.iter().map(|p| p.0).collect(), -1.5),
        mk("right lip", top.iter().map(|p| p.1).collect(), 1.5),
    ];
    let mut p = BaselineProblem::new(m.clone(), groups);
    let bottom: Vec<usize> = (0..m.vertices.len()).filter(|&i| m.vertices[i].z == 0.0).collect();
    p.fix_at_rest(&bottom);
    (p, pairs)
}

#[test]
fn arap_and_drbc_open_the_crack_lddmm_cannot() {
    let (p, pairs) = problem();
    assert_eq!(pairs.len(), 5 * 2, "5 nodes along y × 2 levels above the crack front");
    let gap = |x: &[Vector3<f64>]| pairs.iter().map(|&(i, j)| (x[i] - x[j]).norm()).fold(0.0, f64::max);
    let a = arap(&p, &ArapConfig::default()).unwrap();
    let d = drbc(&p, &DrbcConfig::default()).unwrap();
    let l = lddmm(&p, &LddmmConfig { sigma_mm: 5.0, ..Default::default() }).unwrap();
    for r in [&a, &d] {
        assert!(gap(&r.positions) > 1.5, "{}: crack gap {}", r.report.method, gap(&r.positions));
        assert!(r.report.mean_distance_mm < 0.5 * r.report.initial_mean_distance_mm, "{:?}", r.report);
    }
    // both copies of a node start at the same point: the flow keeps them together
    assert!(gap(&l.positions) < 1e-12, "LDDMM gap {}", gap(&l.positions));
    assert!((l.report.mean_distance_mm - 1.5).abs() < 0.2, "{:?}", l.report);
}
