//! The ground truth's mesh-convergence comparison (`benchmark::convergence`) on a cut box meshed twice
//! (10 and 7 mm tetrahedra): an affine field is reproduced exactly across the meshes, a field scaled by 1.1
//! gives 0.1 / 1.1, a field that jumps across the crack is read on each point's own side, and a second
//! affine field gives RMS figures computed here from the points alone.
use laparo_fem::mesh::shapes::box_surface;
use laparo_fem::mesh::{cut, tetrahedralize_surface, Blade, Scenario, TetraParams};
use laparo_fem::solid::Tet10Mesh;
use laparo_register::benchmark::build::case_from;
use laparo_register::benchmark::convergence::{compare_ground_truths, locate_on_side, ConvergenceConfig};
use laparo_register::benchmark::rods::tet_sides;
use laparo_register::benchmark::{BenchmarkCase, PointKind, DISTANCE_BIN_EDGES_MM};
use nalgebra::{Matrix3, Vector3};

type V3 = Vector3<f64>;

/// The box [0, 60] × [0, 40] × [0, 30] mm at `edge_mm` tetrahedra, cut from its top face z = 30 along
/// x = 30.3 for y ∈ [6, 34], 15 mm deep, its bottom face fixed (as tests/benchmark_ground_truth.rs).
fn cut_box(name: &str, edge_mm: f64) -> Scenario {
    let s = box_surface(&V3::zeros(), &V3::new(60.0, 40.0, 30.0));
    let m = tetrahedralize_surface(s, "box", &TetraParams { edge_mm, ..TetraParams::default() }).unwrap().0;
    let mouth: Vec<V3> = (0..=14).map(|i| V3::new(30.3, 6.0 + 2.0 * i as f64, 30.0)).collect();
    let blade = Blade::uniform(mouth, -V3::z(), 15.0, 3.0);
    let c = cut(&m, &blade).unwrap();
    let fixed_nodes: Vec<usize> = (0..c.mesh.vertices.len()).filter(|&k| c.mesh.vertices[k].z < 1e-9).collect();
    Scenario {
        name: name.into(),
        cut: c,
        blade,
        tumour: None,
        fixed_nodes,
        anterior: V3::z(),
        entry_point: V3::new(30.3, 20.0, 30.0),
        min_margin_mm: None,
    }
}

/// The case of `scn` whose TET10 displacement at every node (vertices and mid-edge nodes) is `u(x, side)`,
/// side being the node's incision side (a mid-edge node: the larger of its two vertices' sides).
fn case_with(scn: &Scenario, u: &dyn Fn(&V3, u8) -> V3) -> BenchmarkCase {
    let t10 = Tet10Mesh::from_linear(&scn.cut.mesh).unwrap();
    let mut case = case_from(scn, &vec![V3::zeros(); scn.cut.mesh.vertices.len()], None);
    let mut side = vec![0u8; t10.n_nodes()];
    side[..case.node_side.len()].copy_from_slice(&case.node_side);
    for (&(a, b), &k) in &t10.edge_nodes {
        side[k] = case.node_side[a].max(case.node_side[b]);
    }
    let u2: Vec<V3> = t10.nodes.iter().zip(&side).map(|(x, &s)| u(x, s)).collect();
    case.ground_truth = case.rest.iter().zip(&u2).map(|(x, u)| x + u).collect();
    case.ground_truth_p2 = Some(u2);
    case
}

fn gradient() -> Matrix3<f64> {
    Matrix3::new(0.02, -0.01, 0.03, 0.015, 0.01, -0.02, -0.01, 0.025, 0.005)
}

fn affine(x: &V3) -> V3 {
    gradient() * (x - V3::new(30.0, 20.0, 15.0)) + V3::new(1.5, -0.5, 2.0)
}

#[test]
fn an_affine_field_agrees_across_meshes_and_a_scaled_one_by_a_tenth_over_1_1() {
    let (sa, sb) = (cut_box("box", 10.0), cut_box("box", 7.0));
    let a = case_with(&sa, &|x, _| affine(x)).with_points(3.0).unwrap();
    let b = case_with(&sb, &|x, _| affine(x));
    assert_ne!(a.rest.len(), b.rest.len(), "two different meshes");
    let r = compare_ground_truths(&a, &b, &ConvergenceConfig::default()).unwrap();
    let p = a.points.as_ref().unwrap();
    assert_eq!(r.points_a, p.len());
    // both meshes fill the same box: no point is outside B
    assert_eq!((r.points_compared, r.points_skipped), (p.len(), 0));
    let faces = p.kind.iter().filter(|k| **k == PointKind::CrackFace).count();
    assert!(faces > 0 && r.crack_face_points == faces);
    assert!(r.relative_rms < 1e-9 && r.near_lip_relative_rms < 1e-9, "{r:?}");
    assert!(r.max_diff_mm < 1e-9, "{}", r.max_diff_mm);
    assert!(r.points_near_lip > 0);
    assert!(r.none_bin_relative_diff.iter().zip(&r.bin_counts).all(|(d, &n)| n == 0 || *d < 1e-9));
    assert!(r.passes_5pct && r.passes_10pct_near && r.none_bins_within_10pct);
    // the RMS |u| is that of the affine field at the points (computed here)
    let rms = (p.rest.iter().map(|x| affine(x).norm_squared()).sum::<f64>() / p.len() as f64).sqrt();
    assert!((r.rms_u_mm - rms).abs() < 1e-9 * rms && (r.rms_u_a_mm - rms).abs() < 1e-9 * rms);

    // B = 1.1 × A everywhere: |u_B − u_A| = 0.1 |u_A| and RMS |u_B| = 1.1 RMS |u_A|, so 0.1 / 1.1 in every figure
    let b11 = case_with(&sb, &|x, _| affine(x) * 1.1);
    let r = compare_ground_truths(&a, &b11, &ConvergenceConfig::default()).unwrap();
    let expect = 0.1 / 1.1;
    assert!((r.relative_rms - expect).abs() < 1e-9, "{}", r.relative_rms);
    assert!((r.near_lip_relative_rms - expect).abs() < 1e-9);
    assert!((r.rms_u_mm - 1.1 * rms).abs() < 1e-9 * rms && (r.rms_diff_mm - 0.1 * rms).abs() < 1e-9 * rms);
    for k in 0..r.bin_counts.len() {
        if r.bin_counts[k] > 0 {
            assert!((r.none_bin_relative_diff[k] - expect).abs() < 1e-9, "bin {k}");
            assert!((r.none_bins_b_mm[k] - 1.1 * r.none_bins_a_mm[k]).abs() < 1e-9);
        } else {
            assert!(r.none_bins_a_mm[k].is_nan() && r.none_bin_relative_diff[k].is_nan());
        }
    }
    // 9.09 %: above the 5 % overall limit, within the 10 % near the lips and per bin
    assert!(!r.passes_5pct && r.passes_10pct_near && r.none_bins_within_10pct);
    // the report survives JSON (empty bins as null) and its markdown names the verdicts
    let json = serde_json::to_string(&r).unwrap();
    let back: laparo_register::benchmark::convergence::ConvergenceReport = serde_json::from_str(&json).unwrap();
    assert_eq!(back.relative_rms, r.relative_rms);
    assert_eq!(back.bin_counts, r.bin_counts);
    let md = r.markdown();
    assert!(md.contains("9.09 %") && md.contains("FAIL") && md.contains("pass"), "{md}");
}

#[test]
fn another_affine_field_gives_the_rms_figures_computed_from_the_points() {
    let (sa, sb) = (cut_box("box", 10.0), cut_box("box", 7.0));
    let c = V3::new(2.0, 0.0, 0.0);
    let a = case_with(&sa, &|_, _| c).with_points(3.0).unwrap();
    let b = case_with(&sb, &|x, _| c + affine(x) * 0.05);
    let r = compare_ground_truths(&a, &b, &ConvergenceConfig::default()).unwrap();
    let p = a.points.as_ref().unwrap();
    assert_eq!(r.points_skipped, 0);
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let ub: Vec<f64> = p.rest.iter().map(|x| (c + affine(x) * 0.05).norm()).collect();
    let dd: Vec<f64> = p.rest.iter().map(|x| (affine(x) * 0.05).norm()).collect();
    let rms = |v: &[f64]| mean(&v.iter().map(|x| x * x).collect::<Vec<_>>()).sqrt();
    assert!((r.rms_u_mm - rms(&ub)).abs() < 1e-9 && (r.rms_diff_mm - rms(&dd)).abs() < 1e-9);
    assert!((r.relative_rms - rms(&dd) / rms(&ub)).abs() < 1e-9);
    assert!((r.rms_u_a_mm - 2.0).abs() < 1e-12);
    let near: Vec<usize> = (0..p.len()).filter(|&i| p.d_lip_mm[i] < 10.0).collect();
    assert_eq!(r.points_near_lip, near.len());
    let pick = |v: &[f64], ids: &[usize]| ids.iter().map(|&i| v[i]).collect::<Vec<f64>>();
    assert!((r.near_lip_relative_rms - rms(&pick(&dd, &near)) / rms(&pick(&ub, &near))).abs() < 1e-9);
    for k in 0..DISTANCE_BIN_EDGES_MM.len() - 1 {
        let ids: Vec<usize> = (0..p.len())
            .filter(|&i| p.d_lip_mm[i] >= DISTANCE_BIN_EDGES_MM[k] && p.d_lip_mm[i] < DISTANCE_BIN_EDGES_MM[k + 1])
            .collect();
        assert_eq!(r.bin_counts[k], ids.len());
        if ids.is_empty() {
            continue;
        }
        let (na, nb) = (2.0, mean(&pick(&ub, &ids)));
        assert!((r.none_bins_a_mm[k] - na).abs() < 1e-12 && (r.none_bins_b_mm[k] - nb).abs() < 1e-9);
        assert!((r.none_bin_relative_diff[k] - (nb - na).abs() / nb).abs() < 1e-9);
    }
}

#[test]
fn a_field_that_jumps_across_the_crack_is_read_on_each_points_own_side() {
    // each side's copies of the crack nodes (and the mid-edge nodes between them) carry their own offset
    let jump = |x: &V3, s: u8| {
        affine(x)
            + match s {
                1 => V3::new(3.0, 1.0, 0.0),
                2 => V3::new(-3.0, 0.0, 1.0),
                _ => V3::zeros(),
            }
    };
    let sa = cut_box("box", 10.0);
    let a = case_with(&sa, &jump).with_points(3.0).unwrap();
    // A against itself: every point must be read where A's own points were (its side), so exactly zero
    let r = compare_ground_truths(&a, &a, &ConvergenceConfig::default()).unwrap();
    assert!(r.max_diff_mm < 1e-9 && r.crack_face_points > 0, "{r:?}");
    // every crack-face point lands in a tetrahedron of its own side (or side 0), never the other one
    let p = a.points.as_ref().unwrap();
    let tside = tet_sides(&a.tets, &a.node_side);
    let loc = locate_on_side(&a, &p.queries(), 1.0).unwrap();
    let mut crack_sides = [0usize; 3];
    for i in (0..p.len()).filter(|&i| p.kind[i] == PointKind::CrackFace) {
        let t = loc[i].unwrap().element.0;
        assert!(tside[t] == 0 || tside[t] == p.side[i], "point {i} of side {} in a side-{} tet", p.side[i], tside[t]);
        crack_sides[usize::from(p.side[i])] += 1;
    }
    assert!(crack_sides[1] > 0 && crack_sides[2] > 0);
    // the same queries with their sides swapped are read on the other side: the jump shows up (6.1 mm apart)
    let swapped: Vec<(V3, u8)> = p.queries().into_iter().map(|(x, s)| (x, if s == 0 { 0 } else { 3 - s })).collect();
    let loc = locate_on_side(&a, &swapped, 1.0).unwrap();
    for i in (0..p.len()).filter(|&i| p.kind[i] == PointKind::CrackFace) {
        let t = loc[i].unwrap().element.0;
        assert!(tside[t] == 0 || tside[t] == swapped[i].1);
    }
    // on the finer mesh B the jump is the same: crack-face points read on their own side agree up to where
    // the two discretised cracks differ; the lattice away from the crack agrees exactly
    let sb = cut_box("box", 7.0);
    let b = case_with(&sb, &jump);
    let r = compare_ground_truths(&a, &b, &ConvergenceConfig::default()).unwrap();
    eprintln!("{}", r.markdown());
    // far from the crack (≥ 20 mm from the lips: no tetrahedron there touches a crack node) the field is affine
    for k in 3..r.bin_counts.len() {
        if r.bin_counts[k] > 0 {
            assert!(r.bin_relative_rms[k] < 1e-9, "bin {k}: {}", r.bin_relative_rms[k]);
        }
    }
}

#[test]
fn bad_input_is_an_error_naming_it() {
    let sa = cut_box("non-anatomical", 10.0);
    let sb = cut_box("anatomical", 7.0);
    let a = case_with(&sa, &|x, _| affine(x)).with_points(4.0).unwrap();
    let b = case_with(&sb, &|x, _| affine(x));
    let e = compare_ground_truths(&a, &b, &ConvergenceConfig::default()).unwrap_err().to_string();
    assert!(e.contains("`non-anatomical`") && e.contains("`anatomical`"), "{e}");
    // A without evaluation points
    let a0 = case_with(&sa, &|x, _| affine(x));
    let e = compare_ground_truths(&a0, &a, &ConvergenceConfig::default()).unwrap_err().to_string();
    assert!(e.contains("evaluation points"), "{e}");
    // bad tolerance and band
    let cfg = ConvergenceConfig { outside_tolerance_mm: -1.0, ..Default::default() };
    let e = compare_ground_truths(&a, &a, &cfg).unwrap_err().to_string();
    assert!(e.contains("outside_tolerance_mm"), "{e}");
    let cfg = ConvergenceConfig { near_lip_mm: f64::NAN, ..Default::default() };
    assert!(compare_ground_truths(&a, &a, &cfg).unwrap_err().to_string().contains("near_lip_mm"));
    // a query with a side that does not exist, or off in the distance
    let e = locate_on_side(&a, &[(V3::new(1.0, 1.0, 1.0), 3)], 1.0).unwrap_err().to_string();
    assert!(e.contains("query 0") && e.contains("side 3"), "{e}");
    let far = locate_on_side(&a, &[(V3::new(100.0, 1.0, 1.0), 0), (V3::new(60.5, 1.0, 1.0), 0)], 1.0).unwrap();
    assert!(far[0].is_none());
    // 0.5 mm outside the box: within the 1 mm tolerance, read by extrapolating the nearest element
    let near = far[1].unwrap();
    assert!((near.outside_mm - 0.5).abs() < 1e-9, "{near:?}");
    // B moved 50 mm away: no point of A lies in it
    let mut moved = case_with(&cut_box("non-anatomical", 7.0), &|x, _| affine(x));
    moved.rest.iter_mut().for_each(|x| x.x += 500.0);
    let e = compare_ground_truths(&a, &moved, &ConvergenceConfig::default()).unwrap_err().to_string();
    assert!(e.contains("none of A's") && e.contains("outside_tolerance_mm"), "{e}");
}
