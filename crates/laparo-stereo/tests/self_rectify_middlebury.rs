//! Self-rectification acceptance (issue 14 item 3) on CATS-perturbed Middlebury Motorcycle
//! pairs: rotations of a few tenths of a degree, principal-point shifts of ±60 px; exact
//! correspondences after rectification: median |dy| ≤ 0.15 px, 95th percentile ≤ 0.5 px.
use laparo_core::{io, Intrinsics};
use laparo_stereo::{augment_stereo, GtRule, StereoSample};
use laparo_stereo::{exact_correspondences, perturbation, self_rectify, DyStats, RectifyMethod, SelfRectifyOptions};
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
    let dy = |r: &laparo_stereo::SelfRectification| {
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
    use laparo_stereo::{fast_matches, sift_matches, FeatureKind};
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
        let eval = |rect: &laparo_stereo::SelfRectification| {
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

/// A GT restricted to the pixels whose exact correspondence lies inside the right image's content
/// (`right_valid`, after the vertical residual `dy`): the points a matcher can see in both views.
fn in_view(
    gt: &[f64],
    dy: Option<&laparo_core::Image<f32>>,
    right_valid: Option<&laparo_core::image::Mask>,
    w: usize,
    h: usize,
) -> Vec<f64> {
    (0..gt.len())
        .map(|i| {
            let g = gt[i];
            if !g.is_finite() {
                return g;
            }
            let dyv = dy.map(|d| d.data[i] as f64).filter(|v| v.is_finite()).unwrap_or(0.0);
            let (xr, yr) = (((i % w) as f64 - g).round(), ((i / w) as f64 + dyv).round());
            if xr < 0.0 || yr < 0.0 || xr > (w - 1) as f64 || yr > (h - 1) as f64 {
                return f64::INFINITY;
            }
            match right_valid {
                Some(m) if !m.data[yr as usize * w + xr as usize] => f64::INFINITY,
                _ => g,
            }
        })
        .collect()
}

/// Filled disparity (invalid → the row background, `sgm::fill`, as `tests/sgm.rs` and `sgbm_ref.py`).
fn filled(d: &laparo_core::Image<f32>) -> Vec<f32> {
    let mut f = d.data.clone();
    laparo_stereo::fill_background(&mut f, d.width, d.height);
    f
}

/// One perturbed pair's EPE against the unperturbed pair's, on the same scene points.
#[derive(Debug, Clone)]
struct EpeRow {
    label: String,
    /// Scene points compared (in view in both pairs).
    n: usize,
    /// EPE of the unperturbed pair's SGM at those points, px: [invalid filled afterwards (the row
    /// background, `sgm::fill`), the matcher's own hole filling (`fill_holes`), valid in both only].
    epe_unperturbed: [f64; 3],
    /// The same EPEs of the self-rectified pipeline on the perturbed pair, px.
    epe_perturbed: [f64; 3],
    /// Density of the pipeline's valid pixels over its in-view GT pixels (no hole filling).
    density: f64,
}

impl EpeRow {
    /// Perturbed / unperturbed EPE for each definition.
    fn ratios(&self) -> [f64; 3] {
        [0, 1, 2].map(|k| self.epe_perturbed[k] / self.epe_unperturbed[k])
    }
}

/// The default SGM on the rectified Motorcycle pair ([0, 64)) against its GT, and the default
/// self-rectified pipeline (fast matches → self-rectification → SGM → disparity in the raw left
/// frame) on CATS-perturbed raw pairs (a zero perturbation, two fixed ones, six random ones with
/// rotations within ±0.4° and principal-point shifts within ±60 px), searched over the GT range
/// widened by 2 px. Both are scored on the same scene points: a perturbed left pixel p' whose exact
/// correspondence is in view, and the unperturbed pixel A_L⁻¹ p' whose correspondence is in view too
/// (a perturbation moves parts of the scene out of the frame; no matcher can see those).
fn epe_rows() -> Option<Vec<EpeRow>> {
    use laparo_stereo::match_self_rectified;
    use laparo_stereo::{match_pair, SgmParams};
    let d = data_dir()?;
    let s = motorcycle(&d);
    let (w, h) = (741usize, 500usize);
    let gt0: Vec<f64> = s.disp_left.as_ref().unwrap().data.iter().map(|&v| v as f64).collect();
    let gt0 = in_view(&gt0, None, None, w, h);
    let d0 = match_pair(&s.left, &s.right, &SgmParams::new(0, 64)).unwrap().disparity;
    let f0 = filled(&d0);
    let h0 = filled(
        &match_pair(&s.left, &s.right, &SgmParams { fill_holes: true, ..SgmParams::new(0, 64) }).unwrap().disparity,
    );
    let (kl, kr) = cameras();
    let mut cases = vec![
        ("zero".to_string(), perturbation(kl, kr, [0.0; 3], [0.0; 3], [0.0, 0.0], [0.0, 0.0])),
        ("fixed 1".into(), perturbation(kl, kr, [0.3, -0.2, 0.25], [-0.2, 0.3, -0.3], [40.0, -50.0], [-60.0, 30.0])),
        ("fixed 2".into(), perturbation(kl, kr, [-0.4, 0.1, -0.3], [0.35, -0.25, 0.2], [-55.0, 45.0], [50.0, -60.0])),
    ];
    for seed in 1u64..=6 {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut ang = || [rng.gen_range(-0.4..0.4), rng.gen_range(-0.4..0.4), rng.gen_range(-0.4..0.4)];
        let (el, er) = (ang(), ang());
        let mut sh = || [rng.gen_range(-60.0..60.0), rng.gen_range(-60.0..60.0)];
        let (sl, sr) = (sh(), sh());
        cases.push((format!("seed {seed}"), perturbation(kl, kr, el, er, sl, sr)));
    }
    let mut rows = vec![];
    for (label, p) in cases {
        let aug = augment_stereo(&s, &p, GtRule::Exact).unwrap();
        let ad = aug.disp_left.as_ref().unwrap();
        let gt: Vec<f64> = ad
            .disparity
            .data
            .iter()
            .zip(&ad.valid.data)
            .map(|(&v, &ok)| if ok && v.is_finite() { v as f64 } else { f64::INFINITY })
            .collect();
        let lo = gt.iter().filter(|v| v.is_finite()).fold(f64::INFINITY, |a, &b| a.min(b));
        let hi = gt.iter().filter(|v| v.is_finite()).fold(f64::NEG_INFINITY, |a, &b| a.max(b));
        let prm = SgmParams::new(lo.floor() as i32 - 2, hi.ceil() as i32 + 3);
        let m = match_self_rectified(&aug.left.image, &aug.right.image, &prm).unwrap();
        let mh =
            match_self_rectified(&aug.left.image, &aug.right.image, &SgmParams { fill_holes: true, ..prm.clone() })
                .unwrap();
        let gt = in_view(&gt, ad.vertical_residual.as_ref(), Some(&aug.right.valid), w, h);
        let fp = filled(&m.output.disparity);
        let hp = filled(&mh.output.disparity);
        let a_inv = p.left.homography_inverse().unwrap();
        let (mut n, mut e0, mut e1, mut n_gt, mut n_valid) = (0usize, [0.0; 3], [0.0; 3], 0usize, 0usize);
        let mut n_both = 0usize;
        for i in 0..gt.len() {
            if !gt[i].is_finite() {
                continue;
            }
            n_gt += 1;
            n_valid += m.output.disparity.data[i].is_finite() as usize;
            let q = a_inv * nalgebra::Vector3::new((i % w) as f64, (i / w) as f64, 1.0);
            let (x, y) = ((q.x / q.z).round(), (q.y / q.z).round());
            if x < 0.0 || y < 0.0 || x > (w - 1) as f64 || y > (h - 1) as f64 {
                continue;
            }
            let j = y as usize * w + x as usize;
            if !gt0[j].is_finite() {
                continue;
            }
            let err = |f: f32, g: f64| ((if f.is_finite() { f as f64 } else { 0.0 }) - g).abs();
            n += 1;
            e0[0] += err(f0[j], gt0[j]);
            e1[0] += err(fp[i], gt[i]);
            e0[1] += err(h0[j], gt0[j]);
            e1[1] += err(hp[i], gt[i]);
            if d0.data[j].is_finite() && m.output.disparity.data[i].is_finite() {
                n_both += 1;
                e0[2] += err(d0.data[j], gt0[j]);
                e1[2] += err(m.output.disparity.data[i], gt[i]);
            }
        }
        let row = EpeRow {
            label: format!("{label} (raw range [{}, {}))", prm.d_min, prm.d_max),
            n,
            epe_unperturbed: [e0[0] / n as f64, e0[1] / n as f64, e0[2] / n_both as f64],
            epe_perturbed: [e1[0] / n as f64, e1[1] / n as f64, e1[2] / n_both as f64],
            density: n_valid as f64 / n_gt as f64,
        };
        let q = row.ratios();
        eprintln!(
            "{}: {} scene points ({} valid in both); EPE unperturbed / self-rectified (ratio): filled afterwards {:.3} / {:.3} px ({:.3}), matcher hole filling {:.3} / {:.3} px ({:.3}), valid in both {:.3} / {:.3} px ({:.3}); density {:.3}; {} matches, {} inliers, f {:.0} px, canvas {:?}",
            row.label, row.n, n_both, row.epe_unperturbed[0], row.epe_perturbed[0], q[0], row.epe_unperturbed[1],
            row.epe_perturbed[1], q[1], row.epe_unperturbed[2], row.epe_perturbed[2], q[2], row.density,
            m.n_matches, m.rectification.n_inliers, m.rectification.focal_px.unwrap_or(f64::NAN),
            m.rectification.rectified_size
        );
        rows.push(row);
    }
    Some(rows)
}

/// Issue 14's "EPE within 15 % of matching the unperturbed pair", on the same scene points (see
/// [`epe_rows`]), for both ways of giving every pixel a disparity: the background fill applied
/// afterwards in the raw left frame (stop 24's definition) and the matcher's own hole filling
/// (`fill_holes`, in each pipeline's matching frame). Measured 2026-12-03 (stop 25: grey bicubic
/// rectification warps): filled afterwards 1.032 (zero perturbation), 1.113, 1.120, 1.110, 1.142,
/// 1.134, 1.081, 1.114, 1.122 (mean 1.108); hole filling 1.033, 1.115, 1.106, 1.109, 1.133, 1.130,
/// 1.086, 1.118, 1.149 (mean 1.109); on the pixels both leave valid 1.00–1.09. Bilinear RGB warps
/// (stop 24) gave 1.08–1.19 (filled afterwards) and 1.07–1.20 (hole filling).
#[test]
fn self_rectified_epe_within_15_percent_of_the_unperturbed_pair() {
    let Some(rows) = epe_rows() else { return };
    let mut mean = [0.0; 3];
    for r in &rows {
        let q = r.ratios();
        assert!(r.n > 200_000, "{}: only {} scene points", r.label, r.n);
        assert!(r.density >= 0.85, "{}: density {}", r.label, r.density);
        assert!(
            q[1] <= 1.15,
            "{}: EPE (matcher hole filling) {:?} vs unperturbed {:?}",
            r.label,
            r.epe_perturbed,
            r.epe_unperturbed
        );
        assert!(q[0] <= 1.15, "{}: EPE (filled afterwards) ratio {}", r.label, q[0]);
        assert!(q[2] <= 1.10, "{}: EPE (valid in both) ratio {}", r.label, q[2]);
        for k in 0..3 {
            mean[k] += q[k] / rows.len() as f64;
        }
    }
    assert!(mean[1] <= 1.12 && mean[0] <= 1.12, "mean EPE ratios {mean:?}");
}

/// The fast matcher (ORB, coarse + guided matching, refinement) and the fit give the same bits
/// with 1 and 2 threads, and take the guided route on a CATS-perturbed pair.
#[test]
fn fast_matches_identical_for_1_and_2_threads() {
    use laparo_stereo::{fast_matches_with, FastParams, MatchRoute};
    let Some(d) = data_dir() else { return };
    let s = motorcycle(&d);
    let (kl, kr) = cameras();
    let p = perturbation(kl, kr, [0.3, -0.2, 0.25], [-0.2, 0.3, -0.3], [40.0, -50.0], [-60.0, 30.0]);
    let aug = augment_stereo(&s, &p, GtRule::Exact).unwrap();
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| {
            let (m, route) = fast_matches_with(&aug.left.image, &aug.right.image, &FastParams::default()).unwrap();
            let r = self_rectify(&m.0, &m.1, (741, 500), &SelfRectifyOptions::default()).unwrap();
            (m, route, r)
        })
    };
    let (m1, r1, s1) = run(1);
    let (m2, r2, s2) = run(2);
    assert!(matches!(r1, MatchRoute::Guided { .. }), "{r1:?}");
    assert_eq!(r1, r2);
    assert_eq!(m1, m2);
    assert_eq!(s1, s2);
    // a coarse fit that cannot qualify falls back to brute force over all keypoints, which finds
    // a superset-like match set of the same geometry
    let strict = FastParams { min_coarse_inliers: usize::MAX, ..FastParams::default() };
    let (mf, rf) = fast_matches_with(&aug.left.image, &aug.right.image, &strict).unwrap();
    assert_eq!(rf, MatchRoute::Full);
    let sf = self_rectify(&mf.0, &mf.1, (741, 500), &SelfRectifyOptions::default()).unwrap();
    eprintln!(
        "guided: {} matches, {} inliers, |dy| {:.4}; full: {} matches, {} inliers, |dy| {:.4}",
        m1.0.len(),
        s1.n_inliers,
        s1.dy_rectified.median_abs,
        mf.0.len(),
        sf.n_inliers,
        sf.dy_rectified.median_abs
    );
    assert!(s1.n_inliers as f64 >= 0.8 * sf.n_inliers as f64, "guided {} vs full {}", s1.n_inliers, sf.n_inliers);
}
