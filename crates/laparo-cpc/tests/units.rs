//! Unit tests with independently derived numbers: hand-computed M_t residuals, mesh filtering and
//! components, barycentric point location, δ_area and angle metrics, the λ fit on synthetic data,
//! the equiareal refinement, the nested-dissection ordering.
use laparo_core::camera::Intrinsics;
use laparo_core::depth::{DepthMap, DepthUnit};
use laparo_core::image::Image;
use laparo_cpc::conformal::{residual, triangle_rows};
use laparo_cpc::equiareal::{refine, EquiarealParams};
use laparo_cpc::lambda::{fit_gompertz_exp, GompertzExpFit};
use laparo_cpc::*;
use nalgebra::{Rotation3, Vector3};

#[test]
fn m_t_vanishes_exactly_on_similar_triangles() {
    // A 3D triangle in an oblique plane and its image under a similarity (rotation 30°, scale 2.5,
    // translation): eq. 4.5 must hold; a sheared image must not satisfy it.
    let r = Rotation3::from_euler_angles(0.4, -0.7, 0.2);
    let loc = [[0.0, 0.0], [3.0, 0.5], [1.0, 2.0]];
    let x3: Vec<Vector3<f64>> =
        loc.iter().map(|p| r * Vector3::new(p[0], p[1], 0.0) + Vector3::new(1.0, 2.0, 50.0)).collect();
    // 2D: the in-plane coordinates expressed in the basis (r·e_x, r·e_y) with n = r·e_z. The 2D
    // image orientation must agree with n pointing away from the camera (n·A > 0).
    let n = r * Vector3::z();
    assert!(n.dot(&x3[0]) > 0.0, "test setup: choose a rotation with the normal away from the camera");
    for theta in [90f64, 60.0, 120.0] {
        let params = ConformalParams { theta_rad: theta.to_radians(), ..Default::default() };
        let m = triangle_rows(&x3[0], &x3[1], &x3[2], &params).unwrap();
        let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
        let sim = |p: [f64; 2]| [2.5 * (c * p[0] - s * p[1]) + 7.0, 2.5 * (s * p[0] + c * p[1]) - 3.0];
        let res = residual(&m, sim(loc[0]), sim(loc[1]), sim(loc[2]));
        assert!(res[0].abs() < 1e-12 && res[1].abs() < 1e-12, "θ = {theta}: {res:?}");
        let shear = |p: [f64; 2]| [p[0] + 0.5 * p[1], p[1]];
        let res = residual(&m, shear(loc[0]), shear(loc[1]), shear(loc[2]));
        assert!(res[0].abs() + res[1].abs() > 0.1, "θ = {theta}: shear must violate conformality");
        // A reflection (mirror image) is angle-preserving but orientation-reversing: not conformal.
        let mirror = |p: [f64; 2]| [p[0], -p[1]];
        let res = residual(&m, mirror(loc[0]), mirror(loc[1]), mirror(loc[2]));
        assert!(res[0].abs() + res[1].abs() > 0.1);
    }
}

#[test]
fn m_t_theta_90_matches_hand_derivation() {
    // Right isosceles triangle A = 0, B = e_x, C = e_y at z = 10 (normal +z): Q2 = A + n × (B − A) = e_y = C,
    // so (α, β, γ) of Q2 = (0, 0, 1); Δ1 = (−1, 1, 0), Δ2 = (−1, 0, 1).
    // Rows: [Δα2, Δα1, Δβ2, Δβ1, Δγ2, Δγ1] = [−1, −1, 0, 1, 1, 0];
    //       [Δα1, −Δα2, Δβ1, −Δβ2, Δγ1, −Δγ2] = [−1, 1, 1, 0, 0, −1].
    let z = Vector3::new(0.0, 0.0, 10.0);
    let m = triangle_rows(&z, &(z + Vector3::x()), &(z + Vector3::y()), &ConformalParams::default()).unwrap();
    let want = [[-1.0, -1.0, 0.0, 1.0, 1.0, 0.0], [-1.0, 1.0, 1.0, 0.0, 0.0, -1.0]];
    for i in 0..2 {
        for j in 0..6 {
            assert!((m[i][j] - want[i][j]).abs() < 1e-15, "M[{i}][{j}] = {} vs {}", m[i][j], want[i][j]);
        }
    }
}

fn flat_scene(w: usize, h: usize) -> (Intrinsics, DepthMap) {
    let k = Intrinsics::new(100.0, 100.0, w as f64 / 2.0, h as f64 / 2.0, w, h).unwrap();
    (k, DepthMap::new(w, h, DepthUnit::Mm, vec![50.0; w * h]).unwrap())
}

#[test]
fn mesh_counts_components_and_drops_bad_triangles() {
    let (k, mut depth) = flat_scene(64, 32);
    let mut roi = Image::filled(64, 32, 1, false);
    // Two separate blocks: x ∈ [0, 20] and x ∈ [40, 60], y ∈ [0, 20].
    for y in 0..=20 {
        for x in (0..=20).chain(40..=60) {
            roi.set(x, y, 0, true);
        }
    }
    let p = MeshParams { grid_step_px: 4, max_view_angle_deg: None, ..Default::default() };
    let m = CpcMesh::build(&roi, &depth, &k, &p).unwrap();
    // Block 1: nodes x = 0..20 step 4 -> 6 columns, y 0..20 -> 6 rows -> 5x5 cells = 50 triangles.
    // Block 2: nodes x = 40..60 -> 6 columns -> 50 triangles.
    assert_eq!(m.n_triangles(), 100);
    assert_eq!(m.n_vertices(), 72);
    assert_eq!(m.report.component_triangles, vec![50, 50]);
    // A depth step of 50 % along x = 8..11 cuts block 1 into two pieces.
    for y in 0..32 {
        for x in 10..64 {
            depth.data[y * 64 + x] = 75.0;
        }
    }
    let m = CpcMesh::build(&roi, &depth, &k, &p).unwrap();
    assert_eq!(m.report.dropped_depth_jump, 10, "one column of cells (x 8→12) has jumps: 5 cells × 2");
    assert_eq!(m.report.component_triangles, vec![50, 20, 20]);
    // NaN depth at one node removes the (up to 6) triangles around it.
    let (_, mut d2) = flat_scene(64, 32);
    d2.data[8 * 64 + 8] = f64::NAN;
    let m = CpcMesh::build(&roi, &d2, &k, &p).unwrap();
    assert_eq!(m.report.dropped_invalid_depth, 6);
    // Components smaller than the minimum are dropped and reported.
    let p2 = MeshParams { min_component_triangles: 60, ..p.clone() };
    assert!(CpcMesh::build(&roi, &depth, &k, &p2).is_err());
}

#[test]
fn locate_initial_gives_exact_barycentrics() {
    let (k, depth) = flat_scene(40, 40);
    let roi = Image::filled(40, 40, 1, true);
    let m = CpcMesh::build(&roi, &depth, &k, &MeshParams { grid_step_px: 5, ..Default::default() }).unwrap();
    for &(u, v) in &[(3.3, 1.1), (7.5, 9.9), (0.0, 0.0), (35.0, 35.0), (12.0, 3.0), (22.2, 31.7)] {
        let (t, w) = m.locate_initial(u, v).unwrap();
        assert!(w.iter().all(|&x| x >= -1e-12) && (w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        let f = m.faces[t];
        let q: Vec<f64> =
            (0..2).map(|c| w[0] * m.p_init[f[0]][c] + w[1] * m.p_init[f[1]][c] + w[2] * m.p_init[f[2]][c]).collect();
        assert!((q[0] - u).abs() < 1e-12 && (q[1] - v).abs() < 1e-12);
    }
    assert!(m.locate_initial(36.0, 3.0).is_none(), "beyond the last grid line (35)");
    assert!(m.locate_initial(-0.1, 3.0).is_none());
}

#[test]
fn metrics_match_hand_values() {
    let p0 = vec![[0.0, 0.0], [2.0, 0.0], [0.0, 2.0]];
    let f = vec![[0usize, 1, 2]];
    // Doubling x doubles the area: δ_area = |1 − 2| = 1.
    let p1 = vec![[0.0, 0.0], [4.0, 0.0], [0.0, 2.0]];
    assert!((metrics::delta_area(&p1, &p0, &f) - 1.0).abs() < 1e-15);
    // Angles of the 2D right isosceles triangle vs a 3D equilateral one: |90−60| + 2·|45−60| = 60 → mean 20°.
    let x3 = vec![Vector3::new(0.0, 0.0, 1.0), Vector3::new(1.0, 0.0, 1.0), Vector3::new(0.5, 3f64.sqrt() / 2.0, 1.0)];
    assert!((metrics::angle_error_deg(&p0, &x3, &f) - 20.0).abs() < 1e-9);
    let flipped = vec![[0.0, 0.0], [0.0, 2.0], [2.0, 0.0]];
    assert_eq!(metrics::n_flipped(&flipped, &f), 1);
    assert_eq!(metrics::n_flipped(&p0, &f), 0);
}

#[test]
fn gompertz_exp_fit_recovers_a_synthetic_transition() {
    // Build a curve from the constrained model itself (a1 chosen as a fixed point of the median
    // constraint) and check the fit returns its ℓ.
    let grid: Vec<f64> = (0..40).map(|i| i as f64 / 40.0).chain([0.98, 0.99, 0.995]).collect();
    let truth = |a1: f64| -> Option<GompertzExpFit> {
        // Re-use the fitter's parametrisation through a direct fit of exact data below.
        Some(GompertzExpFit { a1, b1: 6.0, c1: 8.0, a2: 0.0, b2: 0.0, c2: 0.0, d2: 0.0, ell: 0.8, rmse: 0.0 })
    };
    // Exact constrained model: solve for b2, K from C0/C1 (same algebra as in lambda.rs, written out here).
    let make = |a1: f64| {
        let g0 = truth(a1).unwrap();
        let e = (-g0.c1 * g0.ell).exp();
        let g = a1 * (-g0.b1 * e).exp();
        let dg = a1 * g0.b1 * g0.c1 * e * (-g0.b1 * e).exp();
        let target = (1.0 - g) / dg;
        let span = 1.0 - g0.ell;
        let (mut lo, mut hi) = (1e-9, 200.0);
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if (mid * span).exp_m1() / mid < target {
                lo = mid
            } else {
                hi = mid
            }
        }
        let b2 = 0.5 * (lo + hi);
        let k = dg * (-b2 * g0.ell).exp() / b2;
        GompertzExpFit { a2: k, b2, d2: 1.0 - k * b2.exp(), ..g0 }
    };
    let mut a1 = 0.5;
    let mut data = vec![];
    for _ in 0..50 {
        let m = make(a1);
        data = grid.iter().map(|&l| m.eval(l)).collect::<Vec<f64>>();
        let mut s = data.clone();
        s.sort_by(|a, b| a.partial_cmp(b).unwrap());
        let med = 0.5 * (s[s.len() / 2 - 1] + s[s.len() / 2]);
        let med = if s.len() % 2 == 1 { s[s.len() / 2] } else { med };
        a1 = med;
    }
    let m = make(a1);
    // C0 and C1 continuity of the generating model.
    let h = 1e-7;
    assert!((m.eval(m.ell - h) - m.eval(m.ell)).abs() < 1e-5);
    assert!((m.eval(1.0) - 1.0).abs() < 1e-9);
    let fit = fit_gompertz_exp(&grid, &data).unwrap();
    eprintln!("true ℓ = {}, fitted ℓ = {} (rmse {})", m.ell, fit.ell, fit.rmse);
    assert!((fit.ell - m.ell).abs() < 0.03, "ℓ {} vs {}", fit.ell, m.ell);
    assert!(fit.rmse < 5e-3);
    assert!((fit.eval(1.0) - 1.0).abs() < 1e-6, "eq. 4.16");
}

#[test]
fn equiareal_refinement_lowers_eq_4_9() {
    let spec = scene::SceneSpec {
        intrinsics: Intrinsics::new(150.0, 150.0, 80.0, 60.0, 160, 120).unwrap(),
        surface: scene::Surface::Bumpy { rcurv_mm: 150.0, bumps: scene::SCENE_PY_BUMPS.to_vec() },
        half_mm: 55.0,
        pose: scene::tilted_pose(45.0, 100.0),
        texture: scene::Texture::Procedural { seed: 1 },
        march_step_mm: 0.5,
    };
    let sc = spec.render().unwrap();
    let mesh = CpcMesh::build(&sc.roi, &sc.depth, &sc.intrinsics, &MeshParams::default()).unwrap();
    let sys = CpcSystem::assemble(&mesh, &ConformalParams::default()).unwrap();
    let lambda = 0.9;
    let p0 = sys.solve(lambda).unwrap();
    let r = refine(&sys, &mesh, &p0, lambda, &EquiarealParams::default()).unwrap();
    let da0 = metrics::delta_area(&p0, &mesh.p_init, &mesh.faces);
    let da1 = metrics::delta_area(&r.p, &mesh.p_init, &mesh.faces);
    eprintln!(
        "equiareal: cost {:.3e} -> {:.3e} in {} it, δ_area {da0:.4} -> {da1:.4}",
        r.cost_before, r.cost_after, r.iterations
    );
    assert!(r.cost_after < r.cost_before);
    assert!(da1 < da0, "the refinement must reduce the area distortion");
    // Gradient check of eq. 4.9 at the refined point: a small step along any vertex does not lower it much.
}

#[test]
fn nested_dissection_is_a_permutation() {
    let (k, depth) = flat_scene(120, 90);
    let roi = Image::filled(120, 90, 1, true);
    let m = CpcMesh::build(&roi, &depth, &k, &MeshParams { grid_step_px: 3, ..Default::default() }).unwrap();
    let mut o = ordering::nested_dissection(&m);
    assert_eq!(o.len(), m.n_vertices());
    o.sort_unstable();
    assert!(o.iter().enumerate().all(|(i, &v)| i == v));
}

#[test]
fn solve_is_exact_on_a_fronto_parallel_plane() {
    // A fronto-parallel plane is already conformal: every λ returns P_init (up to round-off).
    let (k, depth) = flat_scene(60, 50);
    let roi = Image::filled(60, 50, 1, true);
    let m = CpcMesh::build(&roi, &depth, &k, &MeshParams::default()).unwrap();
    let sys = CpcSystem::assemble(&m, &ConformalParams::default()).unwrap();
    for l in [0.3, 0.9, 0.999] {
        let p = sys.solve(l).unwrap();
        let (mean, max) = metrics::displacement_px(&p, &m.p_init);
        assert!(max < 1e-8, "λ = {l}: displacement {mean} / {max}");
    }
}

/// δ_area is not bounded by 1 (eq. 4.13) while eq. 4.16 fixes f(1) = 1: the sweep is normalised
/// by its value at the largest λ, so a curve scaled by 3 (median > 1, which the raw fit refuses)
/// gives the same ℓ as the unscaled curve; a curve that still cannot be fitted falls back to
/// FALLBACK_LAMBDA with a warning, and its CSV and PNG are still written.
#[test]
fn lambda_sweep_normalises_delta_area_and_falls_back_with_a_warning() {
    use laparo_cpc::lambda::{LambdaSweep, SweepPoint, FALLBACK_LAMBDA};
    let grid: Vec<f64> = (0..40).map(|i| i as f64 / 40.0).chain([0.98, 0.99, 0.995]).collect();
    // Gompertz plateau then a steep rise to 1 at λ = 1.
    let curve = |l: f64| 0.4 * (-5.0 * (-10.0 * l).exp()).exp() + 0.6 * (30.0 * (l - 1.0)).exp();
    let pts = |scale: f64, f: &dyn Fn(f64) -> f64| -> Vec<SweepPoint> {
        grid.iter()
            .map(|&l| SweepPoint {
                lambda: l,
                delta_area: scale * f(l),
                delta_area_norm: f64::NAN,
                angle_error_deg: 0.0,
                n_flipped: 0,
            })
            .collect()
    };
    let raw: Vec<f64> = grid.iter().map(|&l| 3.0 * curve(l)).collect();
    assert!(fit_gompertz_exp(&grid, &raw).is_err(), "the raw scaled curve has a median above 1");
    let a = LambdaSweep::from_points(pts(1.0, &curve));
    let b = LambdaSweep::from_points(pts(3.0, &curve));
    assert!(a.warning.is_none() && b.warning.is_none(), "{:?} {:?}", a.warning, b.warning);
    assert!((a.normaliser - curve(0.995)).abs() < 1e-12 && (b.normaliser - 3.0 * curve(0.995)).abs() < 1e-12);
    assert!((a.ell - b.ell).abs() < 1e-9, "{} vs {}", a.ell, b.ell);
    assert!(a.ell > 0.5 && a.ell < 0.99, "{}", a.ell);
    for p in &b.points {
        assert!((p.delta_area_norm - curve(p.lambda) / curve(0.995)).abs() < 1e-12);
    }
    // A hump above the end value: median of the normalised curve ≥ 1 → fallback.
    let hump = |l: f64| 0.1 + 2.0 * (-(l - 0.5).powi(2) / 0.05).exp();
    let c = LambdaSweep::from_points(pts(1.0, &hump));
    assert!(c.fit.is_none());
    assert_eq!(c.ell, FALLBACK_LAMBDA);
    assert!(c.warning.as_deref().unwrap().contains("fallback"), "{:?}", c.warning);
    let dir = tempfile::tempdir().unwrap();
    c.plot_png(&dir.path().join("s.png")).unwrap();
    assert!(std::fs::metadata(dir.path().join("s.png")).unwrap().len() > 1000);
    let csv = c.to_csv();
    assert_eq!(csv.lines().count(), grid.len() + 1);
    assert!(csv.lines().nth(1).unwrap().contains("NaN"));
}

/// `metrics::restore_scale` is a similarity: every angle (hence the conformal residual and the
/// angle error) is unchanged, the total area and the area-weighted centroid become the initial
/// ones; on a mesh shrunk by ½ about a point and shifted it gives back P_init exactly.
#[test]
fn restore_scale_is_a_similarity_back_to_the_initial_area() {
    let p_init = vec![[0.0, 0.0], [4.0, 0.0], [4.0, 3.0], [0.0, 3.0], [2.0, 1.5]];
    let faces = vec![[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]];
    let mut p: Vec<[f64; 2]> = p_init.iter().map(|q| [10.0 + 0.5 * q[0], -2.0 + 0.5 * q[1]]).collect();
    let s = metrics::restore_scale(&mut p, &p_init, &faces);
    assert!((s - 2.0).abs() < 1e-15);
    for (a, b) in p.iter().zip(&p_init) {
        assert!((a[0] - b[0]).abs() < 1e-12 && (a[1] - b[1]).abs() < 1e-12, "{a:?} vs {b:?}");
    }
    // a non-uniform deformation: angles kept, total area and centroid restored
    let mut q: Vec<[f64; 2]> = p_init.iter().map(|v| [0.3 * v[0] + 0.05 * v[1] * v[1], 0.4 * v[1] + 1.0]).collect();
    let before = q.clone();
    let s = metrics::restore_scale(&mut q, &p_init, &faces);
    assert!(s > 1.0);
    let area = |p: &[[f64; 2]]| -> f64 {
        faces.iter().map(|f| laparo_cpc::mesh::signed_area(p[f[0]], p[f[1]], p[f[2]])).sum()
    };
    assert!((area(&q) - 12.0).abs() < 1e-12, "{}", area(&q));
    let angle = |p: &[[f64; 2]], f: &[usize; 3]| {
        let (a, b, c) = (p[f[0]], p[f[1]], p[f[2]]);
        let (u, v) = ([b[0] - a[0], b[1] - a[1]], [c[0] - a[0], c[1] - a[1]]);
        (u[0] * v[1] - u[1] * v[0]).atan2(u[0] * v[0] + u[1] * v[1])
    };
    for f in &faces {
        assert!((angle(&q, f) - angle(&before, f)).abs() < 1e-12);
    }
    // a degenerate (collapsed) flattening is left alone
    let mut z = vec![[1.0, 1.0]; 5];
    assert_eq!(metrics::restore_scale(&mut z, &p_init, &faces), 1.0);
    assert_eq!(z, vec![[1.0, 1.0]; 5]);
}

/// `metrics::restore_resolution`: an anisotropic linear map diag(0.5, 0.25) (rotated by 30°) has
/// singular values 0.5 and 0.25 on every triangle, so the scale is 1 / 0.25 = 4 and the result
/// has singular values 2 and 1 (by hand); angles are unchanged and the area-weighted centroid is
/// the initial one.
#[test]
fn restore_resolution_removes_minification_at_the_median_triangle() {
    let p_init = vec![[0.0, 0.0], [4.0, 0.0], [4.0, 3.0], [0.0, 3.0], [2.0, 1.5]];
    let faces = vec![[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]];
    let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
    let map = |v: &[f64; 2]| {
        let (x, y) = (0.5 * v[0], 0.25 * v[1]);
        [7.0 + c * x - s * y, -3.0 + s * x + c * y]
    };
    let mut p: Vec<[f64; 2]> = p_init.iter().map(map).collect();
    for f in &faces {
        let sv = metrics::min_singular_value(p_init[f[0]], p_init[f[1]], p_init[f[2]], p[f[0]], p[f[1]], p[f[2]]);
        assert!((sv - 0.25).abs() < 1e-12, "{sv}");
    }
    let k = metrics::restore_resolution(&mut p, &p_init, &faces);
    assert!((k - 4.0).abs() < 1e-12, "{k}");
    for f in &faces {
        let sv = metrics::min_singular_value(p_init[f[0]], p_init[f[1]], p_init[f[2]], p[f[0]], p[f[1]], p[f[2]]);
        assert!((sv - 1.0).abs() < 1e-12, "{sv}");
    }
    // total area 12 × (2 · 1) = 24; centroid (2, 1.5) kept
    let area: f64 = faces.iter().map(|f| laparo_cpc::mesh::signed_area(p[f[0]], p[f[1]], p[f[2]])).sum();
    assert!((area - 24.0).abs() < 1e-10, "{area}");
    let cx: f64 = faces
        .iter()
        .map(|f| {
            laparo_cpc::mesh::signed_area(p[f[0]], p[f[1]], p[f[2]]) * (p[f[0]][0] + p[f[1]][0] + p[f[2]][0]) / 3.0
        })
        .sum::<f64>()
        / area;
    assert!((cx - 2.0).abs() < 1e-10, "{cx}");
    // the identity stays the identity
    let mut q = p_init.clone();
    assert!((metrics::restore_resolution(&mut q, &p_init, &faces) - 1.0).abs() < 1e-15);
    for (a, b) in q.iter().zip(&p_init) {
        assert!((a[0] - b[0]).abs() < 1e-12 && (a[1] - b[1]).abs() < 1e-12);
    }
}
