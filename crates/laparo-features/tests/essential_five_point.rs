//! The 5-point essential-matrix solver, RANSAC with it, and pose recovery (issue 11, deliverable 1).
//! Reference numbers are derived independently: the true E = [t]ₓ R of a synthetic rigid motion,
//! the cubic constraints evaluated directly with nalgebra, and (for RANSAC) the number of
//! hypotheses of the former 8-point solver on the same data.
use laparo_features::ransac::{
    decompose_essential, find_essential, find_essential_with, five_point, recover_pose, EssentialSolver, RansacParams,
};
use laparo_features::FeaturesError;
use nalgebra::{Matrix3, Rotation3, Unit, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// A random rotation (axis uniform on the sphere, angle in [0.05, 0.6] rad) and unit translation.
fn random_pose(rng: &mut ChaCha8Rng) -> (Matrix3<f64>, Vector3<f64>) {
    let unit = |rng: &mut ChaCha8Rng| loop {
        let v = Vector3::new(rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0));
        let n = v.norm();
        if n > 0.1 && n <= 1.0 {
            return v / n;
        }
    };
    let axis = Unit::new_normalize(unit(rng));
    let r = *Rotation3::from_axis_angle(&axis, rng.gen_range(0.05..0.6)).matrix();
    (r, unit(rng))
}

/// A 3-D point in front of camera 1 (depth 2..10) that is also in front of camera 2.
fn random_point(rng: &mut ChaCha8Rng, r: &Matrix3<f64>, t: &Vector3<f64>) -> Vector3<f64> {
    loop {
        let z = rng.gen_range(2.0..10.0);
        let x = Vector3::new(rng.gen_range(-0.5..0.5) * z, rng.gen_range(-0.5..0.5) * z, z);
        if (r * x + t)[2] > 0.5 {
            return x;
        }
    }
}

fn project(x: &Vector3<f64>) -> [f64; 2] {
    [x[0] / x[2], x[1] / x[2]]
}

/// det E and ‖2 E Eᵀ E − tr(E Eᵀ) E‖ (max entry) of a unit-norm E.
fn cubic_residuals(e: &Matrix3<f64>) -> (f64, f64) {
    let e = e / e.norm();
    let eet = e * e.transpose();
    let c = 2.0 * eet * e - eet.trace() * e;
    (e.determinant().abs(), c.abs().max())
}

fn rel_err(e: &Matrix3<f64>, truth: &Matrix3<f64>) -> f64 {
    let (a, b) = (e / e.norm(), truth / truth.norm());
    (a - b).norm().min((a + b).norm())
}

#[test]
fn five_point_recovers_true_e_and_satisfies_the_constraints() {
    let mut rng = ChaCha8Rng::seed_from_u64(2004);
    let (mut worst_true, mut worst_epi, mut worst_cubic, mut n_sol) = (0.0f64, 0.0f64, 0.0f64, 0usize);
    let trials = 500;
    for _ in 0..trials {
        let (r, t) = random_pose(&mut rng);
        let truth = t.cross_matrix() * r;
        let mut a = [[0.0; 2]; 5];
        let mut b = [[0.0; 2]; 5];
        for k in 0..5 {
            let x = random_point(&mut rng, &r, &t);
            a[k] = project(&x);
            b[k] = project(&(r * x + t));
        }
        let sols = five_point(&a, &b);
        assert!(!sols.is_empty() && sols.len() <= 10, "{} solutions", sols.len());
        n_sol += sols.len();
        let best = sols.iter().map(|e| rel_err(e, &truth)).fold(f64::INFINITY, f64::min);
        worst_true = worst_true.max(best);
        for e in &sols {
            assert!((e.norm() - 1.0).abs() < 1e-12);
            for k in 0..5 {
                let v = Vector3::new(b[k][0], b[k][1], 1.0).dot(&(e * Vector3::new(a[k][0], a[k][1], 1.0)));
                worst_epi = worst_epi.max(v.abs());
            }
            let (d, c) = cubic_residuals(e);
            worst_cubic = worst_cubic.max(d).max(c);
        }
    }
    eprintln!(
        "{trials} trials: mean {:.2} solutions; worst relative error to the true E {worst_true:.2e}, \
         worst epipolar residual {worst_epi:.2e}, worst cubic residual {worst_cubic:.2e}",
        n_sol as f64 / trials as f64
    );
    assert!(worst_true <= 1e-8, "true E not recovered: {worst_true:e}");
    assert!(worst_epi <= 1e-9, "epipolar constraint: {worst_epi:e}");
    assert!(worst_cubic <= 1e-9, "cubic constraints: {worst_cubic:e}");
}

#[test]
fn five_point_degenerate_samples_give_no_solution() {
    // five identical correspondences: rank 1
    let a = [[0.1, 0.2]; 5];
    assert!(five_point(&a, &a).is_empty());
    // NaN
    let mut b = [[0.1, 0.2], [0.3, -0.1], [-0.2, 0.05], [0.0, 0.4], [0.25, 0.25]];
    let c = b;
    b[3][0] = f64::NAN;
    assert!(five_point(&c, &b).is_empty());
}

#[test]
fn essential_bad_input_is_a_clear_error() {
    let prm = RansacParams { threshold_px: 1e-3, ..Default::default() };
    let p: Vec<[f64; 2]> = vec![[0.0, 0.0], [0.1, 0.0], [0.0, 0.1], [0.1, 0.1]];
    let e = find_essential(&p, &p, &prm).unwrap_err();
    assert!(matches!(e, FeaturesError::Estimation(_)) && e.to_string().contains("too few"), "{e}");
    assert!(e.to_string().contains("need at least 5"), "{e}");
    let mut q = vec![[0.0, 0.0], [0.1, 0.0], [0.0, 0.1], [0.1, 0.1], [0.2, 0.3], [0.3, -0.2]];
    q[4][1] = f64::NAN;
    let e = find_essential(&p[..2], &q[..2], &prm).unwrap_err();
    assert!(e.to_string().contains("too few"), "{e}");
    let e = find_essential(&q, &q, &prm).unwrap_err();
    assert!(e.to_string().contains("p1[4]") && e.to_string().contains("not finite"), "{e}");
    let e = find_essential(&q[..5], &q, &prm).unwrap_err();
    assert!(e.to_string().contains("p1 has 5 points, p2 has 6"), "{e}");
    // all correspondences identical: every sample degenerate
    let same = vec![[0.05, -0.02]; 30];
    let e = find_essential(&same, &same, &prm).unwrap_err();
    assert!(e.to_string().contains("degenerate"), "{e}");
    let e = find_essential_with(&q[..6], &q[..6], &prm, EssentialSolver::EightPoint).unwrap_err();
    assert!(e.to_string().contains("need at least 8"), "{e}");
    // pose recovery
    let good = vec![[0.0, 0.0]; 3];
    let e = recover_pose(&Matrix3::zeros(), &good, &good, None, 50.0).unwrap_err();
    assert!(e.to_string().contains("essential matrix"), "{e}");
    let ess = Vector3::new(1.0, 0.0, 0.0).cross_matrix();
    let e = recover_pose(&ess, &good, &good[..2], None, 50.0).unwrap_err();
    assert!(e.to_string().contains("p1 has 3 points, p2 has 2"), "{e}");
    let mut nan = good.clone();
    nan[1][0] = f64::NAN;
    let e = recover_pose(&ess, &good, &nan, None, 50.0).unwrap_err();
    assert!(e.to_string().contains("p2[1]"), "{e}");
    let e = recover_pose(&ess, &good, &good, Some(&[true]), 50.0).unwrap_err();
    assert!(e.to_string().contains("mask"), "{e}");
}

const W: f64 = 640.0;
const H: f64 = 480.0;
const F: f64 = 500.0;

struct Scene {
    n1: Vec<[f64; 2]>,
    n2: Vec<[f64; 2]>,
    ok: Vec<bool>,
    r: Matrix3<f64>,
    t: Vector3<f64>,
}

/// 500 correspondences, every other one an outlier, 0.5 px Gaussian noise in both images
/// (focal 500 px, 640 × 480), returned in normalised coordinates.
fn scene(seed: u64) -> Scene {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, 0.5).unwrap();
    let r = *Rotation3::from_euler_angles(0.05, -0.2, 0.03).matrix();
    let t = Vector3::new(0.8, 0.1, 0.15).normalize();
    let px = |x: &Vector3<f64>| [F * x[0] / x[2] + W / 2.0, F * x[1] / x[2] + H / 2.0];
    let mut s = Scene { n1: vec![], n2: vec![], ok: vec![], r, t };
    while s.n1.len() < 500 {
        let inlier = s.n1.len().is_multiple_of(2);
        let z = rng.gen_range(3.0..8.0);
        let x = Vector3::new(rng.gen_range(-0.6..0.6) * z, rng.gen_range(-0.45..0.45) * z, z);
        let a = px(&x);
        let b = if inlier { px(&(r * x + t)) } else { [rng.gen_range(0.0..W), rng.gen_range(0.0..H)] };
        if !(0.0..W).contains(&b[0]) || !(0.0..H).contains(&b[1]) {
            continue;
        }
        let mut n = |p: [f64; 2]| {
            [(p[0] + noise.sample(&mut rng) - W / 2.0) / F, (p[1] + noise.sample(&mut rng) - H / 2.0) / F]
        };
        s.n1.push(n(a));
        s.n2.push(n(b));
        s.ok.push(inlier);
    }
    s
}

fn pool(n: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new().num_threads(n).build().unwrap()
}

fn angle_deg(a: &Matrix3<f64>, b: &Matrix3<f64>) -> f64 {
    (((a.transpose() * b).trace() - 1.0) / 2.0).clamp(-1.0, 1.0).acos().to_degrees()
}

#[test]
fn ransac_five_point_recall_pose_and_fewer_hypotheses() {
    let prm = RansacParams { threshold_px: 1.5 / F, seed: 4, ..Default::default() };
    let (mut it5, mut it8) = (0, 0);
    for seed in [9, 10, 11] {
        let s = scene(seed);
        let fit = find_essential(&s.n1, &s.n2, &prm).unwrap();
        let n_true = s.ok.iter().filter(|&&b| b).count();
        let found = s.ok.iter().zip(&fit.inliers).filter(|(&a, &b)| a && b).count();
        let recall = found as f64 / n_true as f64;
        let pose = recover_pose(&fit.model, &s.n1, &s.n2, Some(&fit.inliers), 50.0).unwrap();
        let rot = angle_deg(&pose.r, &s.r);
        let tdir = pose.t.dot(&s.t).clamp(-1.0, 1.0).acos().to_degrees();
        let fit8 = find_essential_with(&s.n1, &s.n2, &prm, EssentialSolver::EightPoint).unwrap();
        let pose8 = recover_pose(&fit8.model, &s.n1, &s.n2, Some(&fit8.inliers), 50.0).unwrap();
        eprintln!(
            "seed {seed}: 5-point: recall {recall:.4}, {} inliers, rotation error {rot:.4}°, translation \
             direction error {tdir:.4}°, {} hypotheses; 8-point: {} hypotheses, rotation error {:.4}°, \
             translation {:.4}°",
            fit.n_inliers,
            fit.iterations,
            fit8.iterations,
            angle_deg(&pose8.r, &s.r),
            pose8.t.dot(&s.t).clamp(-1.0, 1.0).acos().to_degrees()
        );
        assert!(recall >= 0.98, "inlier recall {recall}");
        assert!(rot <= 0.5, "rotation error {rot}°");
        assert!(tdir <= 2.0, "translation direction error {tdir}°");
        // local optimisation ran: E on the essential manifold
        let sv = fit.model.singular_values();
        let mut sv: Vec<f64> = sv.iter().cloned().collect();
        sv.sort_by(f64::total_cmp);
        assert!(sv[0].abs() < 1e-9 && (sv[1] - sv[2]).abs() < 1e-9, "{sv:?}");
        // most inliers are triangulated in front of both cameras
        assert!(pose.n_in_front as f64 >= 0.95 * fit.n_inliers as f64, "{pose:?}");
        assert!(fit.iterations < fit8.iterations, "5-point {} vs 8-point {}", fit.iterations, fit8.iterations);
        it5 += fit.iterations;
        it8 += fit8.iterations;
    }
    // independent bound: the adaptive rule at w ≈ 0.5 needs ≈ 218 (s = 5) and ≈ 1,765 (s = 8)
    assert!(it5 <= 3 * 512 && it8 >= 3 * 1024, "{it5} vs {it8}");
}

#[test]
fn ransac_five_point_same_for_one_and_two_threads() {
    let s = scene(12);
    let prm = RansacParams { threshold_px: 1.5 / F, seed: 77, ..Default::default() };
    let a = pool(1).install(|| find_essential(&s.n1, &s.n2, &prm).unwrap());
    let b = pool(2).install(|| find_essential(&s.n1, &s.n2, &prm).unwrap());
    assert_eq!(a, b);
    let pa = pool(1).install(|| recover_pose(&a.model, &s.n1, &s.n2, Some(&a.inliers), 50.0).unwrap());
    let pb = pool(2).install(|| recover_pose(&b.model, &s.n1, &s.n2, Some(&b.inliers), 50.0).unwrap());
    assert_eq!(pa, pb);
}

#[test]
fn recover_pose_picks_the_right_decomposition() {
    // Known pose: 10° about y, then a translation mostly along x. Points in front of both.
    let r = *Rotation3::from_euler_angles(0.0, 10f64.to_radians(), 0.0).matrix();
    let t = Vector3::new(-1.0, 0.1, 0.05).normalize();
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let (mut a, mut b) = (vec![], vec![]);
    for _ in 0..40 {
        let x = random_point(&mut rng, &r, &t);
        a.push(project(&x));
        b.push(project(&(r * x + t)));
    }
    let e = t.cross_matrix() * r;
    // the four candidates: each is [t]ₓ R up to sign; exactly one equals (R, t)
    let cands = decompose_essential(&(e * -3.0)).unwrap();
    let matches: Vec<usize> =
        (0..4).filter(|&k| (cands[k].0 - r).norm() < 1e-12 && (cands[k].1 - t).norm() < 1e-12).collect();
    assert_eq!(matches.len(), 1, "{cands:?}");
    for (rk, tk) in &cands {
        assert!((rk.determinant() - 1.0).abs() < 1e-12);
        assert!(rel_err(&(tk.cross_matrix() * rk), &e) < 1e-12);
    }
    let pose = recover_pose(&(e * -3.0), &a, &b, None, 50.0).unwrap();
    assert!((pose.r - r).norm() < 1e-12 && (pose.t - t).norm() < 1e-12, "{pose:?}");
    assert_eq!(pose.n_in_front, 40);
    assert_eq!(pose.votes[matches[0]], 40);
    // the twisted pair and the reflected translation put points behind a camera
    assert!(pose.votes.iter().enumerate().all(|(k, &v)| k == matches[0] || v < 40), "{:?}", pose.votes);
    // mask: only the first 10 are used
    let mask: Vec<bool> = (0..40).map(|i| i < 10).collect();
    let p = recover_pose(&e, &a, &b, Some(&mask), 50.0).unwrap();
    assert_eq!(p.n_in_front, 10);
    assert!(p.in_front[..10].iter().all(|&f| f) && !p.in_front[10..].iter().any(|&f| f));
}
