//! LDDMM baseline (thesis §5.4.2, Beg 2005 landmark shooting): exact matching of noiseless point
//! targets, gradient vs finite differences, the width sweep.
use laparo_register::baselines::*;
use laparo_register::distance::Polyline;
use laparo_register::loss::GroupTarget;
use nalgebra::Vector3;
use std::sync::Arc;

fn displaced(v: &Vector3<f64>) -> Vector3<f64> {
    v + Vector3::new(2.0 * (0.1 * v.z).sin(), 1.5, -1.0 + 0.05 * v.x)
}

fn problem(with_curve: bool) -> BaselineProblem {
    let m = box_tet_mesh([4, 4, 3], 6.0, Vector3::new(0.0, 0.0, 0.0));
    let nodes = [0usize, 4, 24, 30, 57, 79, 99];
    let pts: Vec<MaterialPoint> = nodes.iter().map(|&i| MaterialPoint::node(i)).collect();
    let tg: Vec<Vector3<f64>> = nodes.iter().map(|&i| displaced(&m.vertices[i])).collect();
    let mut groups =
        vec![MeshLandmarkGroup { name: "points".into(), points: pts, target: GroupTarget::Paired(tg), weight: 1.0 }];
    if with_curve {
        let a = displaced(&m.vertices[60]);
        groups.push(MeshLandmarkGroup {
            name: "curve".into(),
            points: vec![MaterialPoint::combination(&[(60, 0.5), (61, 0.5)]), MaterialPoint::node(62)],
            target: GroupTarget::Shared(Arc::new(Polyline::open(vec![a, a + Vector3::new(8.0, 1.0, 0.5)]))),
            weight: 0.7,
        });
    }
    BaselineProblem::new(m, groups)
}

#[test]
fn noiseless_point_targets_are_reached() {
    let p = problem(false);
    let cfg =
        LddmmConfig { sigma_mm: 12.0, gamma: 1e-9, iterations: 2000, gradient_tolerance: 1e-10, ..Default::default() };
    let r = lddmm(&p, &cfg).unwrap();
    let GroupTarget::Paired(tg) = &p.groups[0].target else { unreachable!() };
    let worst =
        p.groups[0].points.iter().zip(tg).map(|(mp, y)| (mp.position(&r.positions) - y).norm()).fold(0.0, f64::max);
    assert!(worst < 0.01, "worst landmark {worst} mm, {:?}", r.report);
    // the flow moves the whole mesh smoothly: every node moved, none by more than twice the largest
    // landmark displacement
    let dmax = tg
        .iter()
        .zip(&p.groups[0].points)
        .map(|(y, mp)| (y - mp.position(&p.mesh.vertices)).norm())
        .fold(0.0, f64::max);
    for (a, b) in r.positions.iter().zip(&p.mesh.vertices) {
        assert!((a - b).norm() < 2.0 * dmax);
    }
}

#[test]
fn gradient_matches_finite_differences() {
    let p = problem(true);
    let cfg = LddmmConfig { sigma_mm: 9.0, gamma: 0.3, steps: 7, ..Default::default() };
    let n = p.landmark_count();
    let p0: Vec<Vector3<f64>> = (0..n)
        .map(|i| Vector3::new((i as f64 * 1.3).sin() * 3.0, (i as f64 * 0.7).cos() * 2.0, 1.0 - 0.3 * i as f64))
        .collect();
    let (f0, g) = lddmm_objective(&p, &cfg, &p0).unwrap();
    assert!(f0 > 0.0);
    let h = 1e-6;
    for i in 0..n {
        for c in 0..3 {
            let (mut a, mut b) = (p0.clone(), p0.clone());
            a[i][c] += h;
            b[i][c] -= h;
            let fd = (lddmm_objective(&p, &cfg, &a).unwrap().0 - lddmm_objective(&p, &cfg, &b).unwrap().0) / (2.0 * h);
            assert!((fd - g[i][c]).abs() <= 1e-5 * (1.0 + fd.abs()), "p[{i}][{c}]: fd {fd} vs {}", g[i][c]);
        }
    }
}

#[test]
fn width_sweep_runs_every_sigma_in_order() {
    let p = problem(true);
    let cfg = LddmmConfig { iterations: 100, ..Default::default() };
    let s = lddmm_width_sweep(&p, &[5.0, 20.0], &cfg).unwrap();
    assert_eq!(s.iter().map(|r| r.0).collect::<Vec<_>>(), vec![5.0, 20.0]);
    for (_, r) in &s {
        assert!(r.report.mean_distance_mm < 0.5 * r.report.initial_mean_distance_mm, "{:?}", r.report);
    }
    // a node far from every landmark follows a wide kernel more than a narrow one
    let src: Vec<Vector3<f64>> =
        p.groups.iter().flat_map(|g| g.points.iter().map(|mp| mp.position(&p.mesh.vertices))).collect();
    let gap = |i: usize| src.iter().map(|s| (s - p.mesh.vertices[i]).norm()).fold(f64::INFINITY, f64::min);
    let far = (0..p.mesh.vertices.len()).max_by(|&a, &b| gap(a).total_cmp(&gap(b))).unwrap();
    assert!(gap(far) > 5.0);
    let d = |r: &BaselineResult| (r.positions[far] - p.mesh.vertices[far]).norm();
    assert!(d(&s[1].1) > d(&s[0].1));
    let e = lddmm(&p, &LddmmConfig { sigma_mm: 0.0, ..cfg }).unwrap_err().to_string();
    assert!(e.contains("sigma_mm"), "{e}");
}
