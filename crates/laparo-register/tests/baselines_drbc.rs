//! DRBC baseline (thesis §5.4.2, Collins 2020 style): identity at zero displacement, gradient vs
//! finite differences, inversion-safe line search, hard constraints.
use laparo_fem::NeoHookean;
use laparo_register::baselines::*;
use laparo_register::distance::Polyline;
use laparo_register::loss::GroupTarget;
use nalgebra::{Matrix3, Vector3};
use std::sync::Arc;

fn mesh() -> laparo_core::mesh::TetMesh {
    box_tet_mesh([4, 3, 3], 5.0, Vector3::new(1.0, -2.0, 0.5))
}

fn min_j(p: &BaselineProblem, x: &[Vector3<f64>]) -> f64 {
    p.mesh
        .tets
        .iter()
        .map(|t| {
            let v = &p.mesh.vertices;
            let dm = Matrix3::from_columns(&[v[t[1]] - v[t[0]], v[t[2]] - v[t[0]], v[t[3]] - v[t[0]]]);
            let ds = Matrix3::from_columns(&[x[t[1]] - x[t[0]], x[t[2]] - x[t[0]], x[t[3]] - x[t[0]]]);
            ds.determinant() / dm.determinant()
        })
        .fold(f64::INFINITY, f64::min)
}

#[test]
fn zero_landmark_displacement_gives_the_identity() {
    let m = mesh();
    let pts = [
        MaterialPoint::node(3),
        MaterialPoint::combination(&[(10, 0.5), (11, 0.5)]),
        MaterialPoint::combination(&[(20, 0.2), (26, 0.3), (50, 0.5)]),
        MaterialPoint::node(70),
    ];
    let src: Vec<Vector3<f64>> = pts.iter().map(|p| p.position(&m.vertices)).collect();
    let p = BaselineProblem::new(
        m.clone(),
        vec![
            MeshLandmarkGroup {
                name: "paired".into(),
                points: pts[..2].to_vec(),
                target: GroupTarget::Paired(src[..2].to_vec()),
                weight: 1.0,
            },
            MeshLandmarkGroup {
                name: "curve".into(),
                points: pts[2..].to_vec(),
                target: GroupTarget::Shared(Arc::new(Polyline::open(src[2..].to_vec()))),
                weight: 2.0,
            },
        ],
    );
    let r = drbc(&p, &DrbcConfig::default()).unwrap();
    let err = r.positions.iter().zip(&m.vertices).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
    assert!(err <= 1e-9, "max node displacement {err} mm");
    assert!(r.report.converged && r.report.mean_distance_mm <= 1e-9);
}

fn pulled_problem(pull: Vector3<f64>) -> (BaselineProblem, usize) {
    let m = mesh();
    let corner = m.vertices.len() - 1;
    let mid = 40;
    let y0 = m.vertices[corner] + pull;
    let line = Polyline::open(vec![y0 - Vector3::new(0.0, 6.0, 0.0), y0 + Vector3::new(0.0, 6.0, 0.0)]);
    let mut p = BaselineProblem::new(
        m.clone(),
        vec![
            MeshLandmarkGroup {
                name: "corner".into(),
                points: vec![MaterialPoint::node(corner)],
                target: GroupTarget::Shared(Arc::new(line)),
                weight: 1.0,
            },
            MeshLandmarkGroup {
                name: "mid".into(),
                points: vec![MaterialPoint::combination(&[(mid, 0.5), (mid + 1, 0.5)])],
                target: GroupTarget::Paired(vec![m.vertices[mid] * 0.5 + m.vertices[mid + 1] * 0.5 + pull * 0.3]),
                weight: 1.0,
            },
        ],
    );
    let bottom: Vec<usize> = (0..m.vertices.len()).filter(|&i| m.vertices[i].z == 0.5).collect();
    p.fix_at_rest(&bottom);
    (p, corner)
}

#[test]
fn gradient_matches_finite_differences() {
    let (p, _) = pulled_problem(Vector3::new(2.0, 1.0, 3.0));
    let cfg = DrbcConfig {
        material: NeoHookean::from_young_poisson(4.1, 0.45).unwrap(),
        lambda: Some(0.3),
        ..Default::default()
    };
    // a deformed state: smooth displacement field
    let x: Vec<Vector3<f64>> = p
        .mesh
        .vertices
        .iter()
        .map(|v| v + Vector3::new(0.3 * (0.1 * v.y).sin(), 0.2 * (0.07 * v.x).cos(), 0.05 * v.x))
        .collect();
    let (f0, g) = drbc_objective(&p, &cfg, &x).unwrap().unwrap();
    assert!(f0 > 0.0);
    let h = 1e-6;
    let mut checked = 0;
    for i in (0..x.len()).step_by(7).chain([x.len() - 1, 41]) {
        for c in 0..3 {
            let (mut xp, mut xm) = (x.clone(), x.clone());
            xp[i][c] += h;
            xm[i][c] -= h;
            let fp = drbc_objective(&p, &cfg, &xp).unwrap().unwrap().0;
            let fm = drbc_objective(&p, &cfg, &xm).unwrap().unwrap().0;
            let fd = (fp - fm) / (2.0 * h);
            assert!((fd - g[i][c]).abs() <= 1e-6 * (1.0 + g[i][c].abs()), "node {i} c {c}: fd {fd} vs {}", g[i][c]);
            checked += 1;
        }
    }
    assert!(checked > 30);
    // an inverted state has no objective: reflect one node of tet 0 through its opposite face
    let t = p.mesh.tets[0];
    let n = (x[t[2]] - x[t[1]]).cross(&(x[t[3]] - x[t[1]])).normalize();
    let mut xi = x.clone();
    xi[t[0]] -= n * (2.0 * (x[t[0]] - x[t[1]]).dot(&n));
    assert!(min_j(&p, &xi) < 0.0);
    assert!(drbc_objective(&p, &cfg, &xi).unwrap().is_none());
}

#[test]
fn registration_converges_without_inverting_and_keeps_fixed_nodes() {
    // a large pull (more than the 5 mm cell size, downwards into the block) with a soft material: a
    // full Newton step would invert elements; every accepted iterate must keep J > 0.
    for (k, (pull, lambda)) in
        [(Vector3::new(2.0, 1.0, 3.0), None), (Vector3::new(-4.0, 3.0, -9.0), Some(0.02))].into_iter().enumerate()
    {
        if k == 0 {
            let (p, _) = pulled_problem(pull);
            assert!(drbc(&p, &DrbcConfig::default()).unwrap().report.iterations <= 8);
        }
        let (p, corner) = pulled_problem(pull);
        let cfg = DrbcConfig { lambda, iterations: 100, ..Default::default() };
        let r = drbc(&p, &cfg).unwrap();
        // Newton on the exact Hessian: a handful of iterations (a Gauss–Newton landmark block or a
        // wrong tangent converges linearly and needs tens)
        assert!(r.report.converged && r.report.iterations <= 20, "{:?}", r.report);
        let j = min_j(&p, &r.positions);
        assert!(j > 0.0, "min J {j}");
        assert!(r.report.mean_distance_mm < 0.5 * r.report.initial_mean_distance_mm, "{:?}", r.report);
        for &(i, y) in &p.fixed {
            assert_eq!(r.positions[i], y);
        }
        assert!((r.positions[corner] - p.mesh.vertices[corner]).norm() > 1.0);
        // stationarity: the free gradient is small where Newton reported convergence
        if r.report.converged {
            let (_, g) = drbc_objective(&p, &cfg, &r.positions).unwrap().unwrap();
            let fixed: Vec<usize> = p.fixed.iter().map(|f| f.0).collect();
            let gmax = (0..g.len()).filter(|i| !fixed.contains(i)).map(|i| g[i].amax()).fold(0.0, f64::max);
            assert!(gmax < 1e-4, "gradient {gmax} at convergence");
        }
    }
}

#[test]
fn bad_lambda_is_named() {
    let (p, _) = pulled_problem(Vector3::new(1.0, 0.0, 0.0));
    let e = drbc(&p, &DrbcConfig { lambda: Some(f64::NAN), ..Default::default() }).unwrap_err().to_string();
    assert!(e.contains("DRBC lambda"), "{e}");
}
