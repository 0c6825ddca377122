//! Self-rectification acceptance (issue 14 item 3) on CATS-perturbed Middlebury Motorcycle
//! pairs: rotations of a few tenths of a degree, principal-point shifts of ±60 px; exact
//! correspondences after rectification: median |dy| ≤ 0.15 px, 95th percentile ≤ 0.5 px.
use laparo_core::{io, Intrinsics};
use laparo_stereo::augment::{augment_stereo, GtRule, StereoSample};
use laparo_stereo::self_rectify::{
    exact_correspondences, perturbation, self_rectify, DyStats, RectifyMethod, SelfRectifyOptions,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::path::PathBuf;

fn data_dir() -> Option<PathBuf> {
    let d = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data/middlebury-motorcycle"));
    if d.join("motorcycle_left.png").is_file() {
        Some(d)
    } else {
        eprintln!("SKIP: {} is absent; self-rectification Middlebury test not run", d.display());
        None
    }
}

/// The Middlebury Motorcycle pair with its left disparity.
fn motorcycle(d: &std::path::Path) -> StereoSample {
    StereoSample {
        left: io::read_image(d.join("motorcycle_left.png")).unwrap(),
        right: io::read_image(d.join("motorcycle_right.png")).unwrap(),
        disp_left: Some(io::read_pfm(d.join("motorcycle_disp.pfm")).unwrap()),
        disp_right: None,
        occ_left: None,
        occ_right: None,
    }
}

fn cameras() -> (Intrinsics, Intrinsics) {
    let f = 994.97775;
    (
        Intrinsics::new(f, f, 311.193, 254.87675, 741, 500).unwrap(),
        Intrinsics::new(f, f, 342.27875, 254.87675, 741, 500).unwrap(),
    )
}

/// The perturbed pair's exact correspondences for one seed.
fn perturbed(d: &std::path::Path, seed: u64) -> (Vec<[f64; 2]>, Vec<[f64; 2]>, String) {
    let s = motorcycle(d);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut ang = || [rng.gen_range(-0.4..0.4), rng.gen_range(-0.4..0.4), rng.gen_range(-0.4..0.4)];
    let (el, er) = (ang(), ang());
    let mut sh = || [rng.gen_range(-60.0..60.0), rng.gen_range(-60.0..60.0)];
    let (sl, sr) = (sh(), sh());
    let (kl, kr) = cameras();
    let aug = augment_stereo(&s, &perturbation(kl, kr, el, er, sl, sr), GtRule::Exact).unwrap();
    let (pl, pr) = exact_correspondences(aug.disp_left.as_ref().unwrap(), 3).unwrap();
    (pl, pr, format!("seed {seed}: left {el:.2?}° {sl:.1?} px, right {er:.2?}° {sr:.1?} px"))
}

/// Matches = 1500 exact correspondences + 500 random outliers (25 %).
fn matches(pl: &[[f64; 2]], pr: &[[f64; 2]], seed: u64) -> (Vec<[f64; 2]>, Vec<[f64; 2]>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0xABCD);
    let (mut a, mut b) = (vec![], vec![]);
    for _ in 0..1500 {
        let i = rng.gen_range(0..pl.len());
        a.push(pl[i]);
        b.push(pr[i]);
    }
    for _ in 0..500 {
        a.push([rng.gen_range(0.0..741.0), rng.gen_range(0.0..500.0)]);
        b.push([rng.gen_range(0.0..741.0), rng.gen_range(0.0..500.0)]);
    }
    (a, b)
}

#[test]
fn quasi_euclidean_on_cats_perturbed_middlebury() {
    let Some(d) = data_dir() else { return };
    for seed in [1u64, 2, 3] {
        let (pl, pr, what) = perturbed(&d, seed);
        let raw = DyStats::of(&pl.iter().zip(&pr).map(|(a, b)| b[1] - a[1]).collect::<Vec<_>>());
        let (ml, mr) = matches(&pl, &pr, seed);
        let rect = self_rectify(&ml, &mr, (741, 500), &SelfRectifyOptions::default()).unwrap();
        // all exact correspondences (not only the fitted ones), rectified
        let dy: Vec<f64> = pl
            .iter()
            .zip(&pr)
            .map(|(a, b)| rect.rectify_right(b[0], b[1]).unwrap()[1] - rect.rectify_left(a[0], a[1]).unwrap()[1])
            .collect();
        let st = DyStats::of(&dy);
        eprintln!("{what}\n  raw |dy| median {:.3} p95 {:.3}; rectified median {:.4} p95 {:.4} max {:.4} (n {}), inliers {}/{}, f {:.0} px, corner shift {:.1} px",
            raw.median_abs, raw.p95_abs, st.median_abs, st.p95_abs, st.max_abs, st.n, rect.n_inliers, rect.n_matches,
            rect.focal_px.unwrap(), rect.max_corner_shift_px);
        assert!(raw.p95_abs > 2.0, "the perturbation must matter: raw p95 {}", raw.p95_abs);
        assert!(st.median_abs <= 0.15, "{what}: median |dy| {}", st.median_abs);
        assert!(st.p95_abs <= 0.5, "{what}: p95 |dy| {}", st.p95_abs);
        // the outliers are rejected, the exact matches kept
        let kept_true = rect.inliers[..1500].iter().filter(|&&b| b).count();
        let kept_false = rect.inliers[1500..].iter().filter(|&&b| b).count();
        assert!(kept_true >= 1450 && kept_false <= 10, "{kept_true} / {kept_false}");
        // the disparity map back to the raw left frame: a rectified disparity built from the
        // exact correspondences maps back to their raw disparity
        let (u, v) = {
            let a = rect.rectify_left(pl[0][0], pl[0][1]).unwrap();
            (a[0], a[1])
        };
        let b = rect.rectify_right(pr[0][0], pr[0][1]).unwrap();
        let back = rect.to_raw(u, v, u - b[0]).unwrap();
        assert!((back[0] - pl[0][0]).abs() < 1e-6 && (back[1] - pl[0][1]).abs() < 1e-6);
        assert!((back[2] - (pl[0][0] - pr[0][0])).abs() < 1e-3 + 1e-6, "raw d {} vs {}", back[2], pl[0][0] - pr[0][0]);
    }
}

#[test]
fn hartley_is_computed_and_compared() {
    let Some(d) = data_dir() else { return };
    let (pl, pr, what) = perturbed(&d, 1);
    let (ml, mr) = matches(&pl, &pr, 1);
    let opts = SelfRectifyOptions { method: RectifyMethod::Hartley, max_median_dy_px: 5.0, ..Default::default() };
    let h = self_rectify(&ml, &mr, (741, 500), &opts).unwrap();
    let q = self_rectify(&ml, &mr, (741, 500), &SelfRectifyOptions::default()).unwrap();
    let dy = |r: &laparo_stereo::self_rectify::SelfRectification| {
        DyStats::of(
            &pl.iter()
                .zip(&pr)
                .map(|(a, b)| r.rectify_right(b[0], b[1]).unwrap()[1] - r.rectify_left(a[0], a[1]).unwrap()[1])
                .collect::<Vec<_>>(),
        )
    };
    let (sh, sq) = (dy(&h), dy(&q));
    eprintln!(
        "{what}\n  Hartley median {:.4} p95 {:.4}, corner shift {:.1} px; quasi-Euclidean median {:.4} p95 {:.4}, corner shift {:.1} px",
        sh.median_abs, sh.p95_abs, h.max_corner_shift_px, sq.median_abs, sq.p95_abs, q.max_corner_shift_px
    );
    // both rectify (F is exact here); the distortion (corner shift) is reported, not asserted
    assert!(sh.median_abs <= 0.15 && sh.p95_abs <= 0.5, "Hartley |dy| {sh:?}");
    assert!(sq.median_abs <= 0.15 && sq.p95_abs <= 0.5, "quasi-Euclidean |dy| {sq:?}");
    assert!(h.focal_px.is_none() && q.focal_px.is_some());
}

/// End to end with real keypoints: SIFT (laparo-features) on the perturbed images, Lowe 0.8 +
/// mutual matching, self-rectification; then |dy| of the exact correspondences.
#[test]
fn sift_matches_on_cats_perturbed_middlebury() {
    use laparo_features::{detect_and_describe, match_features, DetectorConfig, MatchConfig};
    let Some(d) = data_dir() else { return };
    let s = motorcycle(&d);
    let (kl, kr) = cameras();
    let p = perturbation(kl, kr, [0.3, -0.2, 0.25], [-0.2, 0.3, -0.3], [40.0, -50.0], [-60.0, 30.0]);
    let aug = augment_stereo(&s, &p, GtRule::Exact).unwrap();
    let sift = DetectorConfig::by_name("sift").unwrap();
    let fl = detect_and_describe(&aug.left.image, &sift, Some(&aug.left.valid)).unwrap();
    let fr = detect_and_describe(&aug.right.image, &sift, Some(&aug.right.valid)).unwrap();
    let m = match_features(&fl, &fr, &MatchConfig::default()).unwrap();
    let (a, b): (Vec<[f64; 2]>, Vec<[f64; 2]>) = m
        .iter()
        .map(|m| {
            let (x, y) = (fl.keypoints[m.i1 as usize], fr.keypoints[m.i2 as usize]);
            ([x.x, x.y], [y.x, y.y])
        })
        .unzip();
    let rect = self_rectify(&a, &b, (741, 500), &SelfRectifyOptions::default()).unwrap();
    let (pl, pr) = exact_correspondences(aug.disp_left.as_ref().unwrap(), 3).unwrap();
    let dy: Vec<f64> = pl
        .iter()
        .zip(&pr)
        .map(|(a, b)| rect.rectify_right(b[0], b[1]).unwrap()[1] - rect.rectify_left(a[0], a[1]).unwrap()[1])
        .collect();
    let st = DyStats::of(&dy);
    eprintln!(
        "SIFT: {} + {} keypoints, {} matches, {} inliers; fitted |dy| median {:.3}; exact correspondences |dy| median {:.4} p95 {:.4} max {:.4}",
        fl.keypoints.len(), fr.keypoints.len(), m.len(), rect.n_inliers, rect.dy_rectified.median_abs,
        st.median_abs, st.p95_abs, st.max_abs
    );
    assert!(rect.n_inliers >= 100, "{} inliers", rect.n_inliers);
    assert!(st.median_abs <= 0.15, "median |dy| {}", st.median_abs);
    assert!(st.p95_abs <= 0.5, "p95 |dy| {}", st.p95_abs);
}

/// End to end with the default (fast) matcher: ORB + Hamming matching + NCC sub-pixel refinement
/// (`fast_matches`) on the perturbed images, then the same |dy| acceptance as with SIFT, and the
/// SIFT route on the same pair for comparison.
#[test]
fn fast_matches_on_cats_perturbed_middlebury() {
    use laparo_stereo::self_rectify::{fast_matches, sift_matches, FeatureKind};
    let Some(d) = data_dir() else { return };
    assert_eq!(SelfRectifyOptions::default().features, FeatureKind::Fast);
    let s = motorcycle(&d);
    let (kl, kr) = cameras();
    for (k, p) in [
        perturbation(kl, kr, [0.3, -0.2, 0.25], [-0.2, 0.3, -0.3], [40.0, -50.0], [-60.0, 30.0]),
        perturbation(kl, kr, [-0.4, 0.1, -0.3], [0.35, -0.25, 0.2], [-55.0, 45.0], [50.0, -60.0]),
    ]
    .into_iter()
    .enumerate()
    {
        let aug = augment_stereo(&s, &p, GtRule::Exact).unwrap();
        let (pl, pr) = exact_correspondences(aug.disp_left.as_ref().unwrap(), 3).unwrap();
        let eval = |rect: &laparo_stereo::self_rectify::SelfRectification| {
            DyStats::of(
                &pl.iter()
                    .zip(&pr)
                    .map(|(a, b)| {
                        rect.rectify_right(b[0], b[1]).unwrap()[1] - rect.rectify_left(a[0], a[1]).unwrap()[1]
                    })
                    .collect::<Vec<_>>(),
            )
        };
        let (a, b) = fast_matches(&aug.left.image, &aug.right.image).unwrap();
        let rect = self_rectify(&a, &b, (741, 500), &SelfRectifyOptions::default()).unwrap();
        let st = eval(&rect);
        let (sa, sb) = sift_matches(&aug.left.image, &aug.right.image).unwrap();
        let srect = self_rectify(&sa, &sb, (741, 500), &SelfRectifyOptions::default()).unwrap();
        let ss = eval(&srect);
        eprintln!(
            "pair {k}: fast {} matches, {} inliers, |dy| median {:.4} p95 {:.4} max {:.4}; SIFT {} matches, {} inliers, median {:.4} p95 {:.4}",
            a.len(), rect.n_inliers, st.median_abs, st.p95_abs, st.max_abs, sa.len(), srect.n_inliers, ss.median_abs, ss.p95_abs
        );
        assert!(rect.n_inliers >= 100, "{} inliers", rect.n_inliers);
        assert!(st.median_abs <= 0.15, "pair {k}: median |dy| {}", st.median_abs);
        assert!(st.p95_abs <= 0.5, "pair {k}: p95 |dy| {}", st.p95_abs);
    }
}
