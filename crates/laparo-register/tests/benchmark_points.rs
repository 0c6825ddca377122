//! The v2 ruler of the incision benchmark on a cut box: the common evaluation points (the TET10 ground truth in
//! its own side's element, fixed distance bins), the floors, the configuration hash and the bad inputs.
use laparo_register::baselines::{box_tet_mesh, ArapConfig, DrbcConfig, LddmmConfig};
use laparo_register::benchmark::build::node_sides;
use laparo_register::benchmark::methods::{assumed_cut, Baseline, BaselineMethod, CutDirection, P1Floor};
use laparo_register::benchmark::rods::{OracleMode, RodsOracle};
use laparo_register::benchmark::table::check_floor_line;
use laparo_register::benchmark::{
    config_hash, BenchmarkCase, Column, EvalPoints, LandmarkSet, Method, PointKind, PointScores, ResultStore,
    RodsMethod, DISTANCE_BIN_EDGES_MM,
};
use laparo_register::optimize::OptimizerConfig;
use laparo_register::organ::OrganConfig;
use nalgebra::{Matrix3, Vector3};

/// A 40 mm cube of 4 mm cells cut 16 mm deep under a lip along y on the top face at x = 20 (the cut François
/// et al. assume, here the true crack), its bottom fixed; ground truth = the rest mesh (set by each test).
fn cut_box() -> BenchmarkCase {
    let mesh = box_tet_mesh([10, 10, 10], 4.0, Vector3::zeros());
    let mouth: Vec<Vector3<f64>> = (0..=8).map(|k| Vector3::new(20.0, 4.0 + 4.0 * k as f64, 40.0)).collect();
    let lip = |side: u8| LandmarkSet {
        name: format!("lip {side}"),
        side,
        points: Vec::new(),
        sources: mouth.clone(),
        targets: mouth.clone(),
    };
    let cut = assumed_cut(&mesh, &[lip(1), lip(2)], 16.0, CutDirection::SurfaceNormal).unwrap();
    let v = cut.mesh.vertices.clone();
    let fixed = (0..v.len()).filter(|&i| v[i].z == 0.0).collect();
    BenchmarkCase {
        scenario: "box".into(),
        surface: cut.mesh.boundary().faces,
        node_side: node_sides(&cut),
        original_node: cut.original_node.clone(),
        ground_truth: v.clone(),
        lips: cut.lips.clone(),
        fixed,
        roi: None,
        rest: v,
        tets: cut.mesh.tets.clone(),
        ground_truth_p2: None,
        points: None,
    }
}

/// The TET10 nodes of the case's rest mesh (vertices first, then edge nodes).
fn tet10_nodes(case: &BenchmarkCase) -> Vec<Vector3<f64>> {
    let mesh = laparo_core::mesh::TetMesh { vertices: case.rest.clone(), tets: case.tets.clone() };
    laparo_fem::solid::Tet10Mesh::from_linear(&mesh).unwrap().nodes
}

fn affine(x: &Vector3<f64>) -> Vector3<f64> {
    Matrix3::new(0.02, -0.01, 0.03, 0.01, 0.015, -0.02, 0.0, 0.025, 0.01) * x + Vector3::new(1.5, -0.5, 2.0)
}

fn quadratic(x: &Vector3<f64>) -> Vector3<f64> {
    affine(x) + Vector3::new(1e-3 * x.x * x.z, -2e-3 * x.y * x.y, 1.5e-3 * x.x * x.y)
}

/// The case with the TET10 displacement field `u(x)` at every TET10 node and the vertex ground truth.
fn with_field(mut case: BenchmarkCase, u: fn(&Vector3<f64>) -> Vector3<f64>) -> BenchmarkCase {
    case.ground_truth_p2 = Some(tet10_nodes(&case).iter().map(u).collect());
    case.ground_truth = case.rest.iter().map(|x| x + u(x)).collect();
    case
}

#[test]
fn tet10_interpolates_affine_and_quadratic_fields_exactly_on_both_sides_of_the_crack() {
    for (name, u) in [("affine", affine as fn(&Vector3<f64>) -> Vector3<f64>), ("quadratic", quadratic)] {
        let case = with_field(cut_box(), u).with_points(3.0).unwrap();
        let p = case.points.as_ref().unwrap();
        let worst = (0..p.len()).map(|i| (p.ground_truth[i] - (p.rest[i] + u(&p.rest[i]))).norm()).fold(0.0, f64::max);
        assert!(worst < 1e-11, "{name}: largest interpolation error {worst} mm");
        // points on both sides, crack-face points in pairs (one per lip), each in a tetrahedron of its own side
        let sides = laparo_register::benchmark::rods::tet_sides(&case.tets, &case.node_side);
        for s in [1u8, 2] {
            assert!(p.side.iter().zip(&p.kind).any(|(&x, k)| x == s && *k == PointKind::Lattice), "{name}: side {s}");
        }
        let faces: Vec<usize> = (0..p.len()).filter(|&i| p.kind[i] == PointKind::CrackFace).collect();
        assert!(!faces.is_empty());
        let n1 = faces.iter().filter(|&&i| p.side[i] == 1).count();
        assert_eq!(2 * n1, faces.len(), "{name}: crack-face points come in pairs");
        for &i in &faces {
            assert_eq!(sides[p.element[i].0], p.side[i], "{name}: point {i} read from the other side");
            assert!((p.rest[i].x - 20.0).abs() < 1e-9 && p.rest[i].z >= 24.0 - 1e-9, "{name}: {:?}", p.rest[i]);
            assert!(p.d_crack_mm[i] < 1e-9);
        }
    }
}

#[test]
fn distances_to_the_lip_polyline_by_hand_and_fixed_bins() {
    let case = with_field(cut_box(), affine).with_points(4.0).unwrap();
    let p = case.points.as_ref().unwrap();
    // the mouth is the segment x = 20, z = 40, y ∈ [4, 36]
    for i in 0..p.len() {
        let r = p.rest[i];
        let y = r.y.clamp(4.0, 36.0);
        let d = ((r.x - 20.0).powi(2) + (r.y - y).powi(2) + (r.z - 40.0).powi(2)).sqrt();
        assert!((p.d_lip_mm[i] - d).abs() < 1e-9, "point {i}: {} vs {d}", p.d_lip_mm[i]);
        // the crack is the rectangle x = 20, y ∈ [4, 36] (at least: the cut overshoots), z ∈ [24, 40]
        assert!(p.d_crack_mm[i] <= d + 1e-9);
    }
    // a registration off by the distance itself: every bin's mean is the mean distance of its points
    let off: Vec<Vector3<f64>> =
        (0..p.len()).map(|i| p.ground_truth[i] + Vector3::new(p.d_lip_mm[i], 0.0, 0.0)).collect();
    let s = PointScores::of(p, &off).unwrap();
    for (k, b) in s.bins_lip.iter().enumerate() {
        let (lo, hi) = (DISTANCE_BIN_EDGES_MM[k], DISTANCE_BIN_EDGES_MM[k + 1]);
        let v: Vec<f64> = p.d_lip_mm.iter().copied().filter(|d| *d >= lo && *d < hi).collect();
        assert_eq!(b.stats.n, v.len(), "bin {lo}–{hi}");
        if !v.is_empty() {
            assert!((b.stats.mean - v.iter().sum::<f64>() / v.len() as f64).abs() < 1e-9);
        }
    }
    assert_eq!(s.bins_lip.iter().map(|b| b.stats.n).sum::<usize>(), p.len());
    let within10: Vec<f64> = p.d_lip_mm.iter().copied().filter(|d| *d < 10.0).collect();
    let expect = within10.iter().sum::<f64>() / within10.len() as f64;
    assert!((s.near_lip_mean_mm(10.0) - expect).abs() < 1e-9);
}

#[test]
fn floors_vanish_for_a_field_each_representation_holds_exactly() {
    // P1 floor: the ground truth at the nodes, read by P1: exact for an affine field, not for a quadratic one
    let lm = |case: &BenchmarkCase| case.lip_landmarks(8).unwrap();
    let score = |case: &BenchmarkCase, m: &dyn Method| {
        let out = m.register(case, &lm(case)).unwrap();
        let x = laparo_register::benchmark::case::registered_points(case, &out).unwrap();
        PointScores::of(case.points.as_ref().unwrap(), &x).unwrap()
    };
    let flat = with_field(cut_box(), affine).with_points(3.0).unwrap();
    assert!(score(&flat, &P1Floor).tre.max < 1e-10, "{:?}", score(&flat, &P1Floor).tre);
    let curved = with_field(cut_box(), quadratic).with_points(3.0).unwrap();
    assert!(score(&curved, &P1Floor).tre.max > 1e-4);
    // RODS-MPM's floor: the particles at the ground truth, read back by its transfer: exact for an affine field
    let organ = OrganConfig { spacing_mm: 2.0, steps: 4, ..OrganConfig::default() };
    let readback = RodsOracle {
        inner: RodsMethod { organ, optimizer: OptimizerConfig::default(), two_field: None, rung: None },
        mode: OracleMode::Readback,
        kerf_mm: 0.0,
    };
    let s = score(&flat, &readback);
    assert!(s.tre.max < 1e-8, "read-back of an affine field: {:?}", s.tre);
    assert!(!readback.uses_landmarks());
    assert_eq!(readback.inner.floor(), Some(readback.name()));
}

#[test]
fn the_config_hash_changes_with_every_hyperparameter() {
    let rods = |f: &dyn Fn(&mut RodsMethod)| {
        let mut m = RodsMethod {
            organ: OrganConfig::default(),
            optimizer: OptimizerConfig::default(),
            two_field: None,
            rung: None,
        };
        f(&mut m);
        config_hash(&m.settings())
    };
    let base = |b: Baseline| {
        config_hash(&BaselineMethod { name: "x".into(), baseline: b, hold_outside_roi: false }.settings())
    };
    let hashes = [
        rods(&|_| {}),
        rods(&|m| m.organ.spacing_mm = 2.5),
        rods(&|m| m.organ.steps += 1),
        rods(&|m| m.optimizer.iterations += 1),
        rods(&|m| m.optimizer.kinetic_weight = 1e-3),
        rods(&|m| m.organ.poisson_ratio = 0.45),
        base(Baseline::Drbc(DrbcConfig::default())),
        base(Baseline::Drbc(DrbcConfig { lambda: Some(0.5), ..Default::default() })),
        base(Baseline::Arap(ArapConfig::default())),
        base(Baseline::Lddmm(LddmmConfig::default())),
        base(Baseline::Lddmm(LddmmConfig { sigma_mm: 30.0, ..Default::default() })),
        base(Baseline::Francois {
            drbc: DrbcConfig::default(),
            assumed_depth_mm: 20.0,
            direction: CutDirection::SurfaceNormal,
        }),
        base(Baseline::Francois {
            drbc: DrbcConfig::default(),
            assumed_depth_mm: 25.0,
            direction: CutDirection::SurfaceNormal,
        }),
    ];
    for i in 0..hashes.len() {
        for j in 0..i {
            assert_ne!(hashes[i], hashes[j], "settings {i} and {j} share a hash");
        }
    }
    assert_eq!(rods(&|_| {}), hashes[0], "the same settings, the same hash");
    // the memory budget only chooses how the adjoint is checkpointed: not a hyperparameter
    assert_eq!(rods(&|m| m.organ.memory_limit_bytes = Some(1e9)), hashes[0]);
}

#[test]
fn a_lip_leaving_the_organ_and_a_coarse_floor_are_named() {
    // an L-shaped organ: the box without its upper half beyond x = 28; a lip from the top face (z = 40) to the
    // step's face (z = 20) cuts across the missing corner
    let mut case = cut_box();
    let keep: Vec<[usize; 4]> = case
        .tets
        .iter()
        .copied()
        .filter(|t| {
            let c = t.iter().map(|&i| case.rest[i]).sum::<Vector3<f64>>() / 4.0;
            !(c.x > 28.0 && c.z > 20.0)
        })
        .collect();
    case.tets = keep;
    let node = |p: Vector3<f64>| (0..case.rest.len()).find(|&i| (case.rest[i] - p).norm() < 1e-9).unwrap();
    case.lips[0] = vec![node(Vector3::new(24.0, 20.0, 40.0)), node(Vector3::new(40.0, 20.0, 20.0))];
    let e = EvalPoints::build(&case, 4.0).unwrap_err().to_string();
    assert!(e.contains("lip 1 polyline") && e.contains("leaves the organ"), "{e}");
    // a spacing whose RODS-MPM floor exceeds ¼ of "none" near the lips: refused, naming spacing_mm
    let case = with_field(cut_box(), quadratic).with_points(3.0).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let store = ResultStore::new(dir.path());
    let organ = OrganConfig { spacing_mm: 8.0, steps: 4, ..OrganConfig::default() };
    let readback = RodsOracle {
        inner: RodsMethod { organ, optimizer: OptimizerConfig::default(), two_field: None, rung: None },
        mode: OracleMode::Readback,
        kerf_mm: 0.0,
    };
    let none = laparo_register::benchmark::methods::NoRegistration;
    let col = [Column { landmarks: 8, noise_sigma_mm: 0.0 }];
    let r = laparo_register::benchmark::run_protocol(
        std::slice::from_ref(&case),
        &[&none, &readback],
        &col,
        1,
        &store,
        &mut |_| {},
    )
    .unwrap();
    // the gate on the measured rows: the floor set to 0.3 and to 0.2 × "none" in the 5–10 mm bin
    let none_5_10 =
        r.iter().find(|x| x.key.method == none.name()).unwrap().points.as_ref().unwrap().bins_lip[1].stats.mean;
    assert!(none_5_10 > 0.0);
    let with_floor = |share: f64| {
        let mut v = r.clone();
        for x in v.iter_mut().filter(|x| x.key.method.starts_with("floor: RODS")) {
            let b = &mut x.points.as_mut().unwrap().bins_lip;
            b[0].stats.mean = 0.0;
            b[1].stats.mean = share * none_5_10;
        }
        v
    };
    let e = check_floor_line(&with_floor(0.3), 8.0).unwrap_err().to_string();
    assert!(e.contains("spacing_mm") && e.contains("= 8") && e.contains("5–10 mm"), "{e}");
    let ok = with_floor(0.2);
    check_floor_line(&ok, 8.0).unwrap();
}
