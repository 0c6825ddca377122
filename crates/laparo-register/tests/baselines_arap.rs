//! ARAP baseline (thesis §5.4.2): a rigid motion of the sources is recovered exactly, hard constraints
//! are honoured, bad input is named.
use laparo_register::baselines::*;
use laparo_register::distance::Polyline;
use laparo_register::loss::GroupTarget;
use nalgebra::{Rotation3, Vector3};
use std::sync::Arc;

fn rigid() -> (Rotation3<f64>, Vector3<f64>) {
    (
        Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(Vector3::new(0.3, -0.5, 0.8)), 0.45),
        Vector3::new(3.0, -2.0, 5.0),
    )
}

fn problem(paired: bool) -> BaselineProblem {
    let mesh = box_tet_mesh([5, 4, 3], 5.0, Vector3::new(-10.0, 0.0, 2.0));
    let (r, t) = rigid();
    let pts = vec![
        MaterialPoint::node(0),
        MaterialPoint::node(29),
        MaterialPoint::node(119),
        MaterialPoint::combination(&[(7, 0.25), (8, 0.75)]),
        MaterialPoint::combination(&[(40, 0.2), (41, 0.3), (47, 0.5)]),
        MaterialPoint::combination(&[(60, 0.1), (61, 0.2), (66, 0.3), (96, 0.4)]),
        MaterialPoint::node(100),
    ];
    let targets: Vec<Vector3<f64>> = pts.iter().map(|p| r * p.position(&mesh.vertices) + t).collect();
    let target = if paired {
        GroupTarget::Paired(targets.clone())
    } else {
        // each landmark against its own one-point polyline group
        GroupTarget::Shared(Arc::new(Polyline::open(vec![targets[0]])))
    };
    let mut groups = vec![MeshLandmarkGroup { name: "all".into(), points: pts.clone(), target, weight: 1.0 }];
    if !paired {
        groups = pts
            .iter()
            .zip(&targets)
            .enumerate()
            .map(|(k, (p, y))| MeshLandmarkGroup {
                name: format!("lm{k}"),
                points: vec![p.clone()],
                target: GroupTarget::Shared(Arc::new(Polyline::open(vec![*y]))),
                weight: 1.0 + k as f64 * 0.1,
            })
            .collect();
    }
    BaselineProblem::new(mesh, groups)
}

fn max_tre(p: &BaselineProblem, x: &[Vector3<f64>]) -> f64 {
    let (r, t) = rigid();
    p.mesh.vertices.iter().zip(x).map(|(a, b)| (r * a + t - b).norm()).fold(0.0, f64::max)
}

#[test]
fn rigid_motion_is_recovered_by_every_variant() {
    for paired in [true, false] {
        let p = problem(paired);
        for (energy, weights) in [
            (ArapEnergy::Spokes, ArapWeights::Cotangent),
            (ArapEnergy::Spokes, ArapWeights::Uniform),
            (ArapEnergy::Elements, ArapWeights::Cotangent),
        ] {
            let cfg = ArapConfig { energy, weights, iterations: 3000, tolerance_mm: 1e-11, ..Default::default() };
            let r = arap(&p, &cfg).unwrap();
            let tre = max_tre(&p, &r.positions);
            assert!(
                tre < 1e-6,
                "{energy:?} {weights:?} paired={paired}: max TRE {tre} mm after {} it",
                r.report.iterations
            );
            assert!(r.report.converged && r.report.mean_distance_mm < 1e-6);
            assert!(r.report.initial_mean_distance_mm > 1.0);
        }
    }
}

#[test]
fn hard_constraints_are_exact_and_consistent_with_rigid_motion() {
    let mut p = problem(true);
    let (r, t) = rigid();
    // keep 3 landmarks, fix 4 nodes at their rigidly moved positions
    if let GroupTarget::Paired(tg) = &mut p.groups[0].target {
        tg.truncate(3);
    }
    p.groups[0].points.truncate(3);
    for i in [5usize, 23, 58, 110] {
        p.fixed.push((i, r * p.mesh.vertices[i] + t));
    }
    let cfg = ArapConfig { iterations: 3000, tolerance_mm: 1e-11, ..Default::default() };
    let res = arap(&p, &cfg).unwrap();
    for &(i, y) in &p.fixed {
        assert_eq!(res.positions[i], y, "fixed node {i} moved");
    }
    assert!(max_tre(&p, &res.positions) < 1e-6, "{}", max_tre(&p, &res.positions));
}

#[test]
fn soft_landmarks_pull_and_the_mesh_stays_near_rigid() {
    // pull one corner 4 mm up with the bottom face fixed: the landmark moves towards its target, the
    // fixed nodes do not move, and the energy decreases monotonically enough that the distance drops.
    let mesh = box_tet_mesh([4, 4, 4], 5.0, Vector3::zeros());
    let top = mesh.vertices.iter().position(|v| (v - Vector3::new(20.0, 20.0, 20.0)).norm() < 1e-9).unwrap();
    let target = mesh.vertices[top] + Vector3::new(0.0, 0.0, 4.0);
    let mut p = BaselineProblem::new(
        mesh.clone(),
        vec![MeshLandmarkGroup {
            name: "corner".into(),
            points: vec![MaterialPoint::node(top)],
            target: GroupTarget::Paired(vec![target]),
            weight: 1.0,
        }],
    );
    let bottom: Vec<usize> = (0..mesh.vertices.len()).filter(|&i| mesh.vertices[i].z == 0.0).collect();
    p.fix_at_rest(&bottom);
    let r = arap(&p, &ArapConfig::default()).unwrap();
    assert!(r.report.mean_distance_mm < 0.5 * 4.0, "{:?}", r.report);
    for &i in &bottom {
        assert_eq!(r.positions[i], mesh.vertices[i]);
    }
}

#[test]
fn bad_input_is_named() {
    let mut p = problem(true);
    p.groups[0].points[1] = MaterialPoint::combination(&[(1, 0.5), (100000, 0.5)]);
    let e = arap(&p, &ArapConfig::default()).unwrap_err().to_string();
    assert!(e.contains("landmark group `all`") && e.contains("landmark 1"), "{e}");
    let p = problem(true);
    let e = arap(&p, &ArapConfig { landmark_weight: Some(-1.0), ..Default::default() }).unwrap_err().to_string();
    assert!(e.contains("landmark_weight"), "{e}");
    let mut p = problem(true);
    p.fix_at_rest(&[3, 5000]);
    let e = arap(&p, &ArapConfig::default()).unwrap_err().to_string();
    assert!(e.contains("fixed nodes") && e.contains("node 5000"), "{e}");
}

/// `MaterialPoint::locate`: a node is itself, an interior point is reproduced by its weights, a point
/// just outside a face takes the face's closest point, a point farther than the tolerance is named.
#[test]
fn material_point_locate_by_hand() {
    // box [0, 20] x [0, 15] x [0, 10] mm, 5 mm cells
    let mesh = box_tet_mesh([4, 3, 2], 5.0, Vector3::zeros());
    let on_node = MaterialPoint::locate(&mesh, &mesh.vertices[17], 0.0, "lm").unwrap();
    assert_eq!(on_node.nodes, vec![(17, 1.0)]);
    for p in [Vector3::new(3.3, 7.1, 2.2), Vector3::new(17.9, 0.4, 9.6), Vector3::new(10.0, 7.5, 5.0)] {
        let m = MaterialPoint::locate(&mesh, &p, 0.0, "lm").unwrap();
        assert!(m.nodes.iter().all(|&(_, w)| w > 0.0 && w <= 1.0), "{:?}", m.nodes);
        assert!((m.nodes.iter().map(|q| q.1).sum::<f64>() - 1.0).abs() < 1e-12);
        assert!((m.position(&mesh.vertices) - p).norm() < 1e-12, "{p:?}");
    }
    // 0.3 mm above the top face z = 10: the closest point is (x, y, 10)
    let m = MaterialPoint::locate(&mesh, &Vector3::new(6.2, 8.8, 10.3), 0.5, "lm").unwrap();
    assert!((m.position(&mesh.vertices) - Vector3::new(6.2, 8.8, 10.0)).norm() < 1e-12);
    // outside a corner by (1, 1, 1) mm: the corner node, √3 mm away
    let m = MaterialPoint::locate(&mesh, &Vector3::new(21.0, 16.0, 11.0), 2.0, "lm").unwrap();
    assert!((m.position(&mesh.vertices) - Vector3::new(20.0, 15.0, 10.0)).norm() < 1e-12);
    let e = MaterialPoint::locate(&mesh, &Vector3::new(21.0, 16.0, 11.0), 1.7, "group `a` landmark 3").unwrap_err();
    let msg = e.to_string();
    assert!(msg.contains("group `a` landmark 3") && msg.contains("1.732 mm outside"), "{msg}");
    assert!(MaterialPoint::locate(&mesh, &Vector3::new(f64::NAN, 0.0, 0.0), 1.0, "lm").is_err());
    // many points through one locator: inside, reproduced; outside within the tolerance, the box's closest
    // point (the coordinate-wise clamp) — by hand, whichever tetrahedron the k-d tree picks
    let loc = TetLocator::new(&mesh);
    let hi = Vector3::new(20.0, 15.0, 10.0);
    let mut state = 12345u64;
    let mut rnd = || {
        state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    for k in 0..400 {
        let p = Vector3::new(rnd() * 22.0 - 1.0, rnd() * 17.0 - 1.0, rnd() * 12.0 - 1.0);
        let clamp = p.zip_map(&hi, |x, h| x.clamp(0.0, h));
        let m = loc.locate(&p, 2.0, "lm").unwrap();
        assert!((m.position(&mesh.vertices) - clamp).norm() < 1e-9, "point {k} {p:?}");
        assert!((m.nodes.iter().map(|q| q.1).sum::<f64>() - 1.0).abs() < 1e-12);
        // `nearest_tet`: unclamped weights, ≥ 0 inside; an affine field interpolated with them is the field
        // at p itself, inside or outside (extrapolation of the nearest tetrahedron)
        let (e, w) = loc.nearest_tet(&p).unwrap();
        let inside = p.iter().zip(hi.iter()).all(|(&x, &h)| (0.0..=h).contains(&x));
        assert_eq!(w.iter().all(|&v| v >= -1e-12), inside, "point {k} {p:?}: {w:?}");
        let field = |x: &Vector3<f64>| Vector3::new(2.0 * x.x - x.z + 1.0, 0.5 * x.y + 3.0, x.x + x.y + x.z);
        let at: Vector3<f64> = (0..4).map(|a| field(&mesh.vertices[mesh.tets[e][a]]) * w[a]).sum();
        assert!((at - field(&p)).norm() < 1e-9, "point {k} {p:?}");
    }
}
