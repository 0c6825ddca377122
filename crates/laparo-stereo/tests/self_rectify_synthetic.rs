//! Self-rectification on synthetic exact correspondences (no data needed) and bad input.
use laparo_stereo::{self_rectify, DyStats, SelfRectifyOptions};
use nalgebra::{Matrix3, Rotation3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A stereo rig (baseline 5 mm along x, f 1000 px, 1280×1024) with small extra rotations and a
/// vertical principal-point offset of the right camera; points at 60–200 mm.
fn rig(seed: u64) -> (Vec<[f64; 2]>, Vec<[f64; 2]>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let kl = Matrix3::new(1000.0, 0.0, 640.0, 0.0, 1000.0, 512.0, 0.0, 0.0, 1.0);
    let kr = Matrix3::new(1000.0, 0.0, 560.0, 0.0, 1000.0, 535.0, 0.0, 0.0, 1.0);
    let rl = Rotation3::from_euler_angles(0.002, -0.004, 0.003);
    let rr = Rotation3::from_euler_angles(-0.003, 0.005, -0.004);
    let (mut a, mut b) = (vec![], vec![]);
    while a.len() < 800 {
        let z = rng.gen_range(60.0..200.0);
        let x = Vector3::new(rng.gen_range(-0.6..0.6) * z, rng.gen_range(-0.5..0.5) * z, z);
        let xl = kl * (rl * x);
        let xr = kr * (rr * (x - Vector3::new(5.0, 0.0, 0.0)));
        let (pa, pb) = ([xl[0] / xl[2], xl[1] / xl[2]], [xr[0] / xr[2], xr[1] / xr[2]]);
        if [pa, pb].iter().all(|p| p[0] >= 0.0 && p[0] < 1280.0 && p[1] >= 0.0 && p[1] < 1024.0) {
            a.push(pa);
            b.push(pb);
        }
    }
    (a, b)
}

#[test]
fn exact_synthetic_rig_is_rectified() {
    let (a, b) = rig(4);
    let r = self_rectify(&a, &b, (1280, 1024), &SelfRectifyOptions::default()).unwrap();
    let raw = DyStats::of(&a.iter().zip(&b).map(|(p, q)| q[1] - p[1]).collect::<Vec<_>>());
    assert!(raw.median_abs > 5.0, "{raw:?}");
    assert!(r.dy_rectified.median_abs < 0.05 && r.dy_rectified.p95_abs < 0.2, "{:?}", r.dy_rectified);
    assert_eq!(r.n_inliers, 800);
    // the disparity keeps its sign convention d = x_L − x_R in the rectified frame: the right
    // point lies left of the left point (positive rectified disparity for this rig)
    let p = r.rectify_left(a[0][0], a[0][1]).unwrap();
    let q = r.rectify_right(b[0][0], b[0][1]).unwrap();
    assert!(p[0] - q[0] > 0.0);
}

#[test]
fn bad_input_is_an_error_not_identity() {
    let (a, b) = rig(5);
    let o = SelfRectifyOptions::default();
    let e = self_rectify(&a[..10], &b[..10], (1280, 1024), &o).unwrap_err().to_string();
    assert!(e.contains("too few matches"), "{e}");
    let e = self_rectify(&a, &b[..100], (1280, 1024), &o).unwrap_err().to_string();
    assert!(e.contains("800 left points vs 100 right points"), "{e}");
    // pure noise: no consistent geometry → error (never an identity)
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let n: Vec<[f64; 2]> = (0..400).map(|_| [rng.gen_range(0.0..1280.0), rng.gen_range(0.0..1024.0)]).collect();
    let m: Vec<[f64; 2]> = (0..400).map(|_| [rng.gen_range(0.0..1280.0), rng.gen_range(0.0..1024.0)]).collect();
    let r = self_rectify(&n, &m, (1280, 1024), &o);
    assert!(r.is_err(), "random matches must not give a rectification: {:?}", r.map(|r| r.dy_rectified));
    // a NaN coordinate is named
    let mut c = a.clone();
    c[3][0] = f64::NAN;
    let e = self_rectify(&c, &b, (1280, 1024), &o).unwrap_err().to_string();
    assert!(e.contains("p1[3]") && e.contains("not finite"), "{e}");
}
