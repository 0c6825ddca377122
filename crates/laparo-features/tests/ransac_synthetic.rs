//! Robust estimation acceptance (issue 11): 500 synthetic correspondences, 50 % outliers,
//! 0.5 px Gaussian noise on both images.
use laparo_features::ransac::{
    find_essential, find_fundamental, find_homography, symmetric_epipolar_distance, RansacParams,
};
use laparo_features::FeaturesError;
use nalgebra::{Matrix3, Rotation3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

const W: f64 = 640.0;
const H: f64 = 480.0;

fn apply(h: &Matrix3<f64>, p: [f64; 2]) -> [f64; 2] {
    let v = h * Vector3::new(p[0], p[1], 1.0);
    [v[0] / v[2], v[1] / v[2]]
}

fn true_h() -> Matrix3<f64> {
    // rotation 20° about the centre, scale 0.9, mild perspective, shift
    let (s, c) = 20f64.to_radians().sin_cos();
    let t = Matrix3::new(1.0, 0.0, -W / 2.0, 0.0, 1.0, -H / 2.0, 0.0, 0.0, 1.0);
    let r = Matrix3::new(0.9 * c, -0.9 * s, 0.0, 0.9 * s, 0.9 * c, 0.0, 2e-4, -1e-4, 1.0);
    let ti = Matrix3::new(1.0, 0.0, W / 2.0 + 12.0, 0.0, 1.0, H / 2.0 - 7.0, 0.0, 0.0, 1.0);
    ti * r * t
}

/// (p1, p2, is_true_inlier)
fn homography_data(seed: u64) -> (Vec<[f64; 2]>, Vec<[f64; 2]>, Vec<bool>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let n = Normal::new(0.0, 0.5).unwrap();
    let h = true_h();
    let (mut p1, mut p2, mut ok) = (vec![], vec![], vec![]);
    for i in 0..500 {
        let a = [rng.gen_range(0.0..W), rng.gen_range(0.0..H)];
        let b = if i % 2 == 0 { apply(&h, a) } else { [rng.gen_range(0.0..W), rng.gen_range(0.0..H)] };
        p1.push([a[0] + n.sample(&mut rng), a[1] + n.sample(&mut rng)]);
        p2.push([b[0] + n.sample(&mut rng), b[1] + n.sample(&mut rng)]);
        ok.push(i % 2 == 0);
    }
    (p1, p2, ok)
}

fn pool(n: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new().num_threads(n).build().unwrap()
}

#[test]
fn homography_recall_and_corner_error() {
    let (p1, p2, ok) = homography_data(7);
    let prm = RansacParams { threshold_px: 2.5, seed: 3, ..Default::default() };
    let fit = find_homography(&p1, &p2, &prm).unwrap();
    let n_true = ok.iter().filter(|&&b| b).count();
    let found = ok.iter().zip(&fit.inliers).filter(|(&a, &b)| a && b).count();
    let recall = found as f64 / n_true as f64;
    assert!(recall >= 0.98, "inlier recall {recall}");
    let h = true_h();
    let mut worst: f64 = 0.0;
    for c in [[0.0, 0.0], [W - 1.0, 0.0], [0.0, H - 1.0], [W - 1.0, H - 1.0]] {
        let a = apply(&h, c);
        let b = apply(&fit.model, c);
        worst = worst.max(((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt());
    }
    assert!(worst <= 1.0, "corner error {worst} px");
    // few iterations needed at w = 0.5 and s = 4: log(0.001)/log(1-1/16) ≈ 107 → 2 batches
    assert!(fit.iterations <= 256, "{} iterations", fit.iterations);
}

#[test]
fn homography_same_for_one_and_two_threads() {
    let (p1, p2, _) = homography_data(11);
    let prm = RansacParams { threshold_px: 2.5, seed: 99, ..Default::default() };
    let a = pool(1).install(|| find_homography(&p1, &p2, &prm).unwrap());
    let b = pool(2).install(|| find_homography(&p1, &p2, &prm).unwrap());
    assert_eq!(a, b);
}

struct Scene {
    p1: Vec<[f64; 2]>,
    p2: Vec<[f64; 2]>,
    clean1: Vec<[f64; 2]>,
    clean2: Vec<[f64; 2]>,
    ok: Vec<bool>,
    k: Matrix3<f64>,
    r: Matrix3<f64>,
    t: Vector3<f64>,
}

/// Two views of a random 3-D point cloud; camera 2 = R X + t.
fn two_view(seed: u64) -> Scene {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let n = Normal::new(0.0, 0.5).unwrap();
    let k = Matrix3::new(500.0, 0.0, 320.0, 0.0, 500.0, 240.0, 0.0, 0.0, 1.0);
    let r = *Rotation3::from_euler_angles(0.05, -0.2, 0.03).matrix();
    let t = Vector3::new(0.8, 0.1, 0.15);
    let proj = |x: Vector3<f64>| {
        let v = k * x;
        [v[0] / v[2], v[1] / v[2]]
    };
    let mut s = Scene { p1: vec![], p2: vec![], clean1: vec![], clean2: vec![], ok: vec![], k, r, t };
    while s.p1.len() < 500 {
        let i = s.p1.len();
        let z = rng.gen_range(3.0..8.0);
        let x = Vector3::new(rng.gen_range(-0.6..0.6) * z, rng.gen_range(-0.45..0.45) * z, z);
        let a = proj(x);
        let b = if i % 2 == 0 { proj(r * x + t) } else { [rng.gen_range(0.0..W), rng.gen_range(0.0..H)] };
        if !(0.0..W).contains(&b[0]) || !(0.0..H).contains(&b[1]) {
            continue;
        }
        s.clean1.push(a);
        s.clean2.push(b);
        s.p1.push([a[0] + n.sample(&mut rng), a[1] + n.sample(&mut rng)]);
        s.p2.push([b[0] + n.sample(&mut rng), b[1] + n.sample(&mut rng)]);
        s.ok.push(i % 2 == 0);
    }
    s
}

#[test]
fn fundamental_epipolar_distance_of_true_inliers() {
    let s = two_view(5);
    let prm = RansacParams { threshold_px: 1.5, seed: 1, ..Default::default() };
    let fit = find_fundamental(&s.p1, &s.p2, &prm).unwrap();
    let f = fit.model;
    assert!(f.determinant().abs() < 1e-12, "rank 2: det {}", f.determinant());
    let idx: Vec<usize> = (0..s.p1.len()).filter(|&i| s.ok[i]).collect();
    let mean = |a: &[[f64; 2]], b: &[[f64; 2]]| {
        idx.iter().map(|&i| symmetric_epipolar_distance(&f, a[i], b[i])).sum::<f64>() / idx.len() as f64
    };
    let noisy = mean(&s.p1, &s.p2);
    let clean = mean(&s.clean1, &s.clean2);
    assert!(noisy <= 1.0, "mean epipolar distance of the true (noisy) inliers {noisy} px");
    // against the noise-free positions the estimate is much better than the noise
    assert!(clean <= 0.3, "mean epipolar distance of the noise-free inliers {clean} px");
    let found = idx.iter().filter(|&&i| fit.inliers[i]).count() as f64 / idx.len() as f64;
    assert!(found > 0.9, "inlier recall {found}");
    // independent check: the true F = K⁻ᵀ [t]× R K⁻¹ has the same epipole
    let ki = s.k.try_inverse().unwrap();
    let ftrue = ki.transpose() * s.t.cross_matrix() * s.r * ki;
    let e_true = ftrue.svd(true, true).v_t.unwrap().row(2).transpose();
    let e_est = f.svd(true, true).v_t.unwrap().row(2).transpose();
    let (et, ee) = (e_true.normalize(), e_est.normalize());
    let ang = et.dot(&ee).abs().min(1.0).acos();
    assert!(ang < 0.03, "epipole (far outside the image, weakly constrained) direction off by {ang} rad: {et} vs {ee}");
}

#[test]
fn fundamental_same_for_one_and_two_threads() {
    let s = two_view(8);
    let prm = RansacParams { threshold_px: 1.5, seed: 42, ..Default::default() };
    let a = pool(1).install(|| find_fundamental(&s.p1, &s.p2, &prm).unwrap());
    let b = pool(2).install(|| find_fundamental(&s.p1, &s.p2, &prm).unwrap());
    assert_eq!(a, b);
}

#[test]
fn essential_recovers_true_motion() {
    let s = two_view(9);
    let ki = s.k.try_inverse().unwrap();
    let norm = |p: &[[f64; 2]]| -> Vec<[f64; 2]> {
        p.iter()
            .map(|q| {
                let v = ki * Vector3::new(q[0], q[1], 1.0);
                [v[0], v[1]]
            })
            .collect()
    };
    let (n1, n2) = (norm(&s.p1), norm(&s.p2));
    let prm = RansacParams { threshold_px: 1.5 / 500.0, seed: 2, ..Default::default() };
    let a = pool(1).install(|| find_essential(&n1, &n2, &prm).unwrap());
    let b = pool(2).install(|| find_essential(&n1, &n2, &prm).unwrap());
    assert_eq!(a, b);
    let e_true = s.t.cross_matrix() * s.r;
    let (et, ee) = (e_true / e_true.norm(), a.model / a.model.norm());
    let err = (et - ee).norm().min((et + ee).norm());
    assert!(err < 0.02, "E error {err}");
    let sv = a.model.singular_values();
    let mut sv: Vec<f64> = sv.iter().cloned().collect();
    sv.sort_by(f64::total_cmp);
    assert!(sv[0].abs() < 1e-9 && (sv[1] - sv[2]).abs() < 1e-9, "{sv:?}");
}

#[test]
fn bad_input_is_named() {
    let prm = RansacParams::default();
    let p = vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]];
    let e = find_homography(&p, &p, &prm).unwrap_err();
    assert!(matches!(e, FeaturesError::Estimation(_)) && e.to_string().contains("too few"), "{e}");
    let mut q = vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0], [2.0, 3.0]];
    q[2][1] = f64::NAN;
    let e = find_homography(&q, &q, &prm).unwrap_err();
    assert!(e.to_string().contains("p1[2]") && e.to_string().contains("not finite"), "{e}");
    let e = find_fundamental(&q, &q[..4], &prm).unwrap_err();
    assert!(e.to_string().contains("p1 has 5 points, p2 has 4"), "{e}");
    // all points on one line: no homography
    let line: Vec<[f64; 2]> = (0..50).map(|i| [i as f64, 2.0 * i as f64 + 1.0]).collect();
    let e = find_homography(&line, &line, &prm).unwrap_err();
    assert!(e.to_string().contains("degenerate"), "{e}");
    // all points identical: no F
    let same = vec![[5.0, 5.0]; 20];
    let e = find_fundamental(&same, &same, &prm).unwrap_err();
    assert!(e.to_string().contains("degenerate"), "{e}");
    let e = find_homography(&line, &line, &RansacParams { threshold_px: -1.0, ..Default::default() }).unwrap_err();
    assert!(e.to_string().contains("threshold_px"), "{e}");
}
