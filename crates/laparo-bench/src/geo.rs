//! `laparo-bench geo`: robust two-view geometry (laparo-features `ransac/`) and self-rectification
//! (laparo-stereo `self_rectify`) timings, optionally against the OpenCV peer
//! `scripts/self_rectify_opencv.py` (findFundamentalMat + stereoRectifyUncalibrated) on the
//! same matches in the same run.
//!
//! Workloads: (1) H and F RANSAC on 500 synthetic correspondences, 50 % outliers, 0.5 px noise;
//! (2) self-rectification of a CATS-perturbed Middlebury Motorcycle pair (rotations ±0.4°,
//! principal-point shifts ±60 px) whose exact correspondences are scaled to 1280×1024
//! (x·1280/741, y·1024/500: an axis scaling keeps rows rows), 1,500 of them + 500 random
//! outliers as matches; timed: matches → rectifying homographies, and that plus warping two
//! 1280×1024 RGB images; (3) end to end from images (issue 14's ≤ 100 ms per pair): keypoint
//! matches (`fast` = ORB + NCC/LK refinement, `sift`), fit, warps (RGB bilinear, as the peer; and
//! the grey bicubic pair the matcher warps, `MATCH_INTERP`), timed separately, on the real
//! raw SCARED ds1-3 pair and on the perturbed Motorcycle pair resampled to 1280×1024 (bilinear;
//! its exact correspondences scaled the same way evaluate the |dy|); the peer runs ORB +
//! BFMatcher + findFundamentalMat + stereoRectifyUncalibrated + warpPerspective on the same files.
use crate::timing::time_min_median;
use anyhow::{bail, Context, Result};
use clap::Args;
use laparo_core::{io, Image, Intrinsics};
use laparo_features::ransac::{find_fundamental, find_homography, RansacParams};
use laparo_stereo::{augment_stereo, GtRule, StereoSample};
use laparo_stereo::{
    exact_correspondences, fast_detect, fast_match_stage, fast_matches_with, fast_refine, feature_matches,
    perturbation, self_rectify, DyStats, FastParams, FeatureKind, SelfRectifyOptions, MATCH_INTERP,
};
use nalgebra::{Matrix3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use std::path::PathBuf;

/// Options of `laparo-bench geo`.
#[derive(Args)]
pub struct BenchArgs {
    /// Middlebury Motorcycle directory (motorcycle_left.png, motorcycle_right.png, motorcycle_disp.pfm).
    #[arg(long, default_value = "../shared/data/middlebury-motorcycle")]
    pub data: PathBuf,
    /// Seed of the CATS perturbation.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Timed runs (after one warm-up; minimum and median reported).
    #[arg(long, default_value_t = 10)]
    pub runs: usize,
    /// Threads for laparo (rayon) and OpenCV.
    #[arg(long, default_value_t = 2)]
    pub threads: usize,
    /// Python with numpy + opencv-python-headless: run the peer script in the same session.
    #[arg(long)]
    pub peer_python: Option<PathBuf>,
    /// The peer script.
    #[arg(long, default_value = "scripts/self_rectify_opencv.py")]
    pub peer_script: PathBuf,
    /// Real raw SCARED pair directory (Left_Image.png, Right_Image.png) for the end-to-end timing.
    #[arg(long, default_value = "../shared/data/surgical/scared_pair_ds1-3")]
    pub scared: PathBuf,
    /// Timed runs of the SIFT matcher end to end (seconds per pair; 0 = skip it).
    #[arg(long, default_value_t = 1)]
    pub sift_runs: usize,
    /// ORB keypoints per image of the fast matcher (default: `FastParams::default()`).
    #[arg(long)]
    pub orb_features: Option<usize>,
    /// ORB pyramid levels of the fast matcher (default: `FastParams::default()`).
    #[arg(long)]
    pub orb_levels: Option<usize>,
}

/// The fast matcher's parameters with the `--orb-*` overrides.
fn fast_params(a: &BenchArgs) -> FastParams {
    let d = FastParams::default();
    FastParams { n_features: a.orb_features.unwrap_or(d.n_features), n_levels: a.orb_levels.unwrap_or(d.n_levels), ..d }
}

fn synthetic_h() -> (Vec<[f64; 2]>, Vec<[f64; 2]>) {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let n = Normal::new(0.0, 0.5).expect("valid sigma");
    let h = Matrix3::new(0.85, -0.31, 120.0, 0.31, 0.85, -40.0, 2e-4, -1e-4, 1.0);
    let (mut a, mut b) = (vec![], vec![]);
    for i in 0..500 {
        let p = [rng.gen_range(0.0..640.0), rng.gen_range(0.0..480.0)];
        let q = if i % 2 == 0 {
            let v = h * Vector3::new(p[0], p[1], 1.0);
            [v[0] / v[2], v[1] / v[2]]
        } else {
            [rng.gen_range(0.0..640.0), rng.gen_range(0.0..480.0)]
        };
        a.push([p[0] + n.sample(&mut rng), p[1] + n.sample(&mut rng)]);
        b.push([q[0] + n.sample(&mut rng), q[1] + n.sample(&mut rng)]);
    }
    (a, b)
}

fn synthetic_f() -> (Vec<[f64; 2]>, Vec<[f64; 2]>) {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let n = Normal::new(0.0, 0.5).expect("valid sigma");
    let k = Matrix3::new(500.0, 0.0, 320.0, 0.0, 500.0, 240.0, 0.0, 0.0, 1.0);
    let r = *nalgebra::Rotation3::from_euler_angles(0.05, -0.2, 0.03).matrix();
    let t = Vector3::new(0.8, 0.1, 0.15);
    let (mut a, mut b) = (vec![], vec![]);
    while a.len() < 500 {
        let z = rng.gen_range(3.0..8.0);
        let x = Vector3::new(rng.gen_range(-0.6..0.6) * z, rng.gen_range(-0.45..0.45) * z, z);
        let (u, v) = (k * x, k * (r * x + t));
        let p = [u[0] / u[2], u[1] / u[2]];
        let q = if a.len() % 2 == 0 {
            [v[0] / v[2], v[1] / v[2]]
        } else {
            [rng.gen_range(0.0..640.0), rng.gen_range(0.0..480.0)]
        };
        if !(0.0..640.0).contains(&q[0]) || !(0.0..480.0).contains(&q[1]) {
            continue;
        }
        a.push([p[0] + n.sample(&mut rng), p[1] + n.sample(&mut rng)]);
        b.push([q[0] + n.sample(&mut rng), q[1] + n.sample(&mut rng)]);
    }
    (a, b)
}

pub fn run(a: BenchArgs) -> Result<()> {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(a.threads.max(1)).stack_size(8 << 20).build()?;
    pool.install(|| run_in_pool(&a))
}

fn run_in_pool(a: &BenchArgs) -> Result<()> {
    let mut out = serde_json::json!({ "threads": a.threads, "runs": a.runs });
    // (1) RANSAC
    let prm = RansacParams { threshold_px: 2.5, seed: 3, ..Default::default() };
    let (h1, h2) = synthetic_h();
    let (hmin, hmed) = time_min_median(a.runs, || {
        find_homography(&h1, &h2, &prm).expect("synthetic homography fits");
    });
    let (f1, f2) = synthetic_f();
    let fprm = RansacParams { threshold_px: 1.5, seed: 1, ..Default::default() };
    let (fmin, fmed) = time_min_median(a.runs, || {
        find_fundamental(&f1, &f2, &fprm).expect("synthetic F fits");
    });
    out["ransac_500_50pct"] = serde_json::json!({"homography_ms_min": hmin, "homography_ms_median": hmed,
        "fundamental_ms_min": fmin, "fundamental_ms_median": fmed});
    essential_row(a, &mut out)?;
    // (2) self-rectification
    let d = &a.data;
    let s = StereoSample {
        left: io::read_image(d.join("motorcycle_left.png")).with_context(|| format!("reading {}", d.display()))?,
        right: io::read_image(d.join("motorcycle_right.png"))?,
        disp_left: Some(io::read_pfm(d.join("motorcycle_disp.pfm"))?),
        disp_right: None,
        occ_left: None,
        occ_right: None,
    };
    let mut rng = ChaCha8Rng::seed_from_u64(a.seed);
    let mut ang = || [rng.gen_range(-0.4..0.4), rng.gen_range(-0.4..0.4), rng.gen_range(-0.4..0.4)];
    let (el, er) = (ang(), ang());
    let mut sh = || [rng.gen_range(-60.0..60.0), rng.gen_range(-60.0..60.0)];
    let (sl, sr) = (sh(), sh());
    let f = 994.97775;
    let kl = Intrinsics::new(f, f, 311.193, 254.87675, 741, 500)?;
    let kr = Intrinsics::new(f, f, 342.27875, 254.87675, 741, 500)?;
    let aug = augment_stereo(&s, &perturbation(kl, kr, el, er, sl, sr), GtRule::Exact)?;
    let (pl, pr) = exact_correspondences(aug.disp_left.as_ref().expect("left disparity given"), 3)?;
    let (sx, sy) = (1280.0 / 741.0, 1024.0 / 500.0);
    let scale = |v: &[[f64; 2]]| -> Vec<[f64; 2]> { v.iter().map(|p| [p[0] * sx, p[1] * sy]).collect() };
    let (pl, pr) = (scale(&pl), scale(&pr));
    // 1280×1024 pixel (x', y') samples the 741×500 image at (x' / sx, y' / sy)
    let scale_inv = [[1.0 / sx, 0.0, 0.0], [0.0, 1.0 / sy, 0.0], [0.0, 0.0, 1.0]];
    let mut rng = ChaCha8Rng::seed_from_u64(a.seed ^ 0xABCD);
    let (mut ml, mut mr) = (vec![], vec![]);
    for _ in 0..1500 {
        let i = rng.gen_range(0..pl.len());
        ml.push(pl[i]);
        mr.push(pr[i]);
    }
    for _ in 0..500 {
        ml.push([rng.gen_range(0.0..1280.0), rng.gen_range(0.0..1024.0)]);
        mr.push([rng.gen_range(0.0..1280.0), rng.gen_range(0.0..1024.0)]);
    }
    let size = (1280usize, 1024usize);
    let opts = SelfRectifyOptions::default();
    let rect = self_rectify(&ml, &mr, size, &opts)?;
    let dy_eval = |r: &laparo_stereo::SelfRectification| -> Result<DyStats> {
        let mut v = Vec::with_capacity(pl.len());
        for (p, q) in pl.iter().zip(&pr) {
            let (Some(x), Some(y)) = (r.rectify_left(p[0], p[1]), r.rectify_right(q[0], q[1])) else {
                bail!("a correspondence maps to infinity")
            };
            v.push(y[1] - x[1]);
        }
        Ok(DyStats::of(&v))
    };
    let (qmin, qmed) = time_min_median(a.runs, || {
        self_rectify(&ml, &mr, size, &opts).expect("fits");
    });
    let mut img = Image::filled(1280, 1024, 3, 0u8);
    for (i, v) in img.data.iter_mut().enumerate() {
        *v = ((i * 2654435761) >> 13) as u8;
    }
    let (wmin, wmed) = time_min_median(a.runs, || {
        let r = self_rectify(&ml, &mr, size, &opts).expect("fits");
        r.rectify_images(&img, &img).expect("same size");
    });
    let hopts =
        SelfRectifyOptions { method: laparo_stereo::RectifyMethod::Hartley, max_median_dy_px: 5.0, ..opts.clone() };
    let hart = self_rectify(&ml, &mr, size, &hopts)?;
    let (hqmin, _) = time_min_median(a.runs, || {
        self_rectify(&ml, &mr, size, &hopts).expect("fits");
    });
    out["self_rectify_1280x1024"] = serde_json::json!({
        "perturbation": {"left_euler_deg": el, "right_euler_deg": er, "left_shift_px": sl, "right_shift_px": sr},
        "n_matches": ml.len(), "n_exact_eval": pl.len(),
        "quasi_euclidean": {"n_inliers": rect.n_inliers, "focal_px": rect.focal_px, "dy_raw": dy_eval_raw(&pl, &pr),
            "dy_rectified": dy_eval(&rect)?, "max_corner_shift_px": rect.max_corner_shift_px,
            "ms_fit_min": qmin, "ms_fit_median": qmed, "ms_fit_warp_min": wmin, "ms_fit_warp_median": wmed},
        "hartley": {"n_inliers": hart.n_inliers, "dy_rectified": dy_eval(&hart)?, "max_corner_shift_px": hart.max_corner_shift_px,
            "ms_fit_min": hqmin},
    });
    // (3) end to end from images
    let to_1280 = |img: &Image<u8>| {
        laparo_core::remap::warp_homography(img, &scale_inv, 1280, 1024, laparo_core::remap::Interp::Bilinear, 0u8)
            .map(|r| r.0)
    };
    let (tl, tr) = (to_1280(&aug.left.image)?, to_1280(&aug.right.image)?);
    let sd = &a.scared;
    let scared = (
        io::read_image(sd.join("Left_Image.png")).with_context(|| format!("--scared {}", sd.display()))?,
        io::read_image(sd.join("Right_Image.png")).with_context(|| format!("--scared {}", sd.display()))?,
    );
    let tmpdir = std::env::temp_dir().join(format!("laparo_geo_e2e_{}", std::process::id()));
    std::fs::create_dir_all(&tmpdir)?;
    io::write_png(tmpdir.join("moto_left.png"), &tl)?;
    io::write_png(tmpdir.join("moto_right.png"), &tr)?;
    let mut e2e = serde_json::Map::new();
    type Pair<'a> = (&'a str, &'a Image<u8>, &'a Image<u8>, Option<(&'a [[f64; 2]], &'a [[f64; 2]])>);
    let pairs: [Pair; 2] =
        [("scared_ds1-3", &scared.0, &scared.1, None), ("motorcycle_cats_1280x1024", &tl, &tr, Some((&pl, &pr)))];
    for (name, l, r, exact) in pairs {
        let mut per = serde_json::Map::new();
        for (kind, runs) in [(FeatureKind::Fast, a.runs.max(5)), (FeatureKind::Sift, a.sift_runs)] {
            if runs == 0 {
                continue;
            }
            let o = SelfRectifyOptions { features: kind, ..SelfRectifyOptions::default() };
            let size = (l.width, l.height);
            let matches = |l: &Image<u8>, r: &Image<u8>| match kind {
                FeatureKind::Fast => fast_matches_with(l, r, &fast_params(a)).map(|(m, _)| m),
                FeatureKind::Sift => feature_matches(l, r, kind),
            };
            let (ml, mr) = matches(l, r)?;
            let rect = self_rectify(&ml, &mr, size, &o).with_context(|| format!("{name}: self-rectify"))?;
            let mut v = serde_json::json!({"n_matches": ml.len(), "n_inliers": rect.n_inliers,
                "inlier_dy_rectified": rect.dy_rectified, "focal_px": rect.focal_px});
            if kind == FeatureKind::Fast {
                // each stage on its own, then the whole chain images → warped pair in one timed call
                let fp = fast_params(a);
                let ff = fast_detect(l, r, &fp)?;
                let (coarse, route) = fast_match_stage(&ff, &fp)?;
                let t_det = time_min_median(runs, || {
                    fast_detect(l, r, &fp).expect("ORB");
                });
                let t_match = time_min_median(runs, || {
                    fast_match_stage(&ff, &fp).expect("matching");
                });
                let t_ref = time_min_median(runs, || {
                    fast_refine(&ff, &coarse).expect("refinement");
                });
                let t_fit = time_min_median(runs, || {
                    self_rectify(&ml, &mr, size, &o).expect("fits");
                });
                let t_warp = time_min_median(runs, || {
                    rect.rectify_images(l, r).expect("same size");
                });
                // what the matcher warps: the grey pair, bicubic (MATCH_INTERP)
                let grey = |img: &Image<u8>| {
                    Image::from_vec(img.width, img.height, 1, laparo_stereo::to_gray_u8(img)).expect("grey")
                };
                let t_warp_match = time_min_median(runs, || {
                    rect.rectify_images_with(&grey(l), &grey(r), MATCH_INTERP).expect("same size");
                });
                let cpu0 = proc_cpu_ms();
                let t_total = time_min_median(runs, || {
                    let (ml, mr) = matches(l, r).expect("matches");
                    let rect = self_rectify(&ml, &mr, size, &o).expect("fits");
                    rect.rectify_images(l, r).expect("same size");
                });
                let t_total_match = time_min_median(runs, || {
                    let (ml, mr) = matches(l, r).expect("matches");
                    let rect = self_rectify(&ml, &mr, size, &o).expect("fits");
                    rect.rectify_images_with(&grey(l), &grey(r), MATCH_INTERP).expect("same size");
                });
                // process CPU time (user + system, all threads) per pair over the warm-up + timed calls
                v["cpu_ms_total_per_pair"] = serde_json::json!((proc_cpu_ms() - cpu0) / (runs + 1) as f64);
                v["route"] = serde_json::to_value(route)?;
                v["n_keypoints"] = serde_json::json!([ff.left.len(), ff.right.len()]);
                v["n_matches_unrefined"] = serde_json::json!(coarse.0.len());
                for (k, t) in [
                    ("detect", t_det),
                    ("match", t_match),
                    ("refine", t_ref),
                    ("fit", t_fit),
                    ("warps", t_warp),
                    ("warps_grey_bicubic", t_warp_match),
                    ("total", t_total),
                    ("total_grey_bicubic", t_total_match),
                ] {
                    v[format!("ms_{k}_min")] = serde_json::json!(t.0);
                    v[format!("ms_{k}_median")] = serde_json::json!(t.1);
                }
                v["ms_matches_min"] = serde_json::json!(t_det.0 + t_match.0 + t_ref.0);
                v["ms_matches_fit_min"] = serde_json::json!(t_det.0 + t_match.0 + t_ref.0 + t_fit.0);
            } else {
                let (mmin, mmed) = time_min_median(runs, || {
                    feature_matches(l, r, kind).expect("matches");
                });
                let (fmin, fmed) = time_min_median(runs, || {
                    self_rectify(&ml, &mr, size, &o).expect("fits");
                });
                let (wmin, wmed) = time_min_median(runs, || {
                    rect.rectify_images(l, r).expect("same size");
                });
                for (k, t) in [("matches", (mmin, mmed)), ("fit", (fmin, fmed)), ("warps", (wmin, wmed))] {
                    v[format!("ms_{k}_min")] = serde_json::json!(t.0);
                    v[format!("ms_{k}_median")] = serde_json::json!(t.1);
                }
                v["ms_matches_fit_min"] = serde_json::json!(mmin + fmin);
                v["ms_total_min"] = serde_json::json!(mmin + fmin + wmin);
                v["ms_total_median"] = serde_json::json!(mmed + fmed + wmed);
            }
            if let Some((el, er)) = exact {
                v["exact_dy_rectified"] = serde_json::to_value(dy_eval_pts(&rect, el, er)?)?;
            }
            per.insert(format!("{kind:?}").to_lowercase(), v);
        }
        e2e.insert(name.to_string(), serde_json::Value::Object(per));
    }
    out["end_to_end"] = serde_json::Value::Object(e2e);
    if let Some(py) = &a.peer_python {
        let fp = fast_params(a);
        let tmp = std::env::temp_dir().join(format!("laparo_geo_peer_{}.json", std::process::id()));
        let inp = serde_json::json!({"width": 1280, "height": 1024, "fit_left": ml, "fit_right": mr,
            "eval_left": pl, "eval_right": pr, "threshold_px": opts.ransac.threshold_px, "runs": a.runs, "threads": a.threads,
            "e2e": [{"name": "scared_ds1-3", "left": sd.join("Left_Image.png"), "right": sd.join("Right_Image.png"),
                     "orb_features": fp.n_features, "orb_levels": fp.n_levels},
                    {"name": "motorcycle_cats_1280x1024", "left": tmpdir.join("moto_left.png"), "right": tmpdir.join("moto_right.png"),
                     "eval_left": pl, "eval_right": pr, "orb_features": fp.n_features, "orb_levels": fp.n_levels}]});
        laparo_core::atomic::write_atomic(&tmp, serde_json::to_string(&inp)?.as_bytes())?;
        let o = std::process::Command::new(py)
            .arg(&a.peer_script)
            .arg(&tmp)
            .output()
            .with_context(|| format!("running {} {}", py.display(), a.peer_script.display()))?;
        let _ = std::fs::remove_file(&tmp);
        if !o.status.success() {
            bail!("peer script failed: {}", String::from_utf8_lossy(&o.stderr));
        }
        let peer: serde_json::Value = serde_json::from_slice(&o.stdout).context("parsing the peer's JSON")?;
        let ratio = |ours: f64, key: &str| peer[key].as_f64().map(|p| ours / p);
        out["opencv"] = peer.clone();
        out["ratio_ours_over_opencv"] = serde_json::json!({
            "fit_min": ratio(qmin, "ms_fit_min"), "fit_warp_min": ratio(wmin, "ms_fit_warp_min")});
        for name in ["scared_ds1-3", "motorcycle_cats_1280x1024"] {
            let ours = &out["end_to_end"][name]["fast"];
            let theirs = &peer["e2e"][name];
            let r = |k: &str, pk: &str| Some(ours[k].as_f64()? / theirs[pk].as_f64()?);
            out["ratio_ours_over_opencv"][name] = serde_json::json!({
                "matches_min": r("ms_matches_min", "ms_matches_min"), "matches_fit_min": r("ms_matches_fit_min", "ms_matches_fit_min"),
                "total_min": r("ms_total_min", "ms_total_min")});
        }
    }
    let _ = std::fs::remove_dir_all(&tmpdir);
    // one line per pair (stderr; the JSON on stdout stays parseable)
    for name in ["scared_ds1-3", "motorcycle_cats_1280x1024"] {
        let f = &out["end_to_end"][name]["fast"];
        let ms = |k: &str| f[format!("ms_{k}_min")].as_f64().unwrap_or(f64::NAN);
        let peer = out["opencv"]["e2e"][name]["ms_total_min"].as_f64();
        let cpu = |v: &serde_json::Value| v["cpu_ms_total_per_pair"].as_f64().unwrap_or(f64::NAN);
        let peer_cpu = cpu(&out["opencv"]["e2e"][name]);
        eprintln!(
            "self-rectify {name} 1280x1024, {} threads, fast: TOTAL {:.1} ms min ({:.1} median) = detect {:.1} + match {:.1} + refine {:.1} + fit {:.1} + warps {:.1} (part mins){}",
            a.threads, ms("total"), f["ms_total_median"].as_f64().unwrap_or(f64::NAN), ms("detect"), ms("match"), ms("refine"), ms("fit"), ms("warps"),
            peer.map(|p| format!("; OpenCV {p:.1} ms, ratio {:.2}", ms("total") / p)).unwrap_or_default()
        );
        eprintln!(
            "  as the matcher rectifies (grey pair, bicubic): TOTAL {:.1} ms min ({:.1} median), warps {:.1} ms{}",
            ms("total_grey_bicubic"),
            f["ms_total_grey_bicubic_median"].as_f64().unwrap_or(f64::NAN),
            ms("warps_grey_bicubic"),
            peer.map(|p| format!("; ratio to OpenCV {:.2}", ms("total_grey_bicubic") / p)).unwrap_or_default()
        );
        eprintln!("  CPU time per pair (user + sys, all threads): laparo {:.1} ms, OpenCV {peer_cpu:.1} ms", cpu(f));
    }
    println!("{}", serde_json::to_string_pretty(&out)?);
    Ok(())
}

/// User + system CPU time of this process so far, ms (/proc/self/stat, 100 ticks per second;
/// NaN where unavailable).
fn proc_cpu_ms() -> f64 {
    let Ok(st) = std::fs::read_to_string("/proc/self/stat") else { return f64::NAN };
    // fields after the parenthesised command name: state is field 3, utime 14, stime 15
    let Some(rest) = st.rsplit_once(')').map(|(_, r)| r) else { return f64::NAN };
    let f: Vec<&str> = rest.split_whitespace().collect();
    let tick = |i: usize| f.get(i).and_then(|v| v.parse::<f64>().ok()).unwrap_or(f64::NAN);
    (tick(11) + tick(12)) * 10.0
}

fn dy_eval_raw(pl: &[[f64; 2]], pr: &[[f64; 2]]) -> DyStats {
    DyStats::of(&pl.iter().zip(pr).map(|(p, q)| q[1] - p[1]).collect::<Vec<_>>())
}

/// Essential matrix on 500 synthetic correspondences (50 % outliers, 0.5 px noise, f = 500 px,
/// 640×480; the scene of `laparo-features/tests/essential_five_point.rs`, seed 9): laparo's
/// 5-point and 8-point RANSAC + `recover_pose`, and with `--peer-python` OpenCV's
/// `findEssentialMat` + `recoverPose` (`scripts/essential_opencv.py`) on the same points.
fn essential_row(a: &BenchArgs, out: &mut serde_json::Value) -> Result<()> {
    use laparo_features::ransac::{find_essential_with, recover_pose, EssentialSolver};
    let (w, h, f) = (640.0, 480.0, 500.0);
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let noise = Normal::new(0.0, 0.5).expect("valid sigma");
    let r = *nalgebra::Rotation3::from_euler_angles(0.05, -0.2, 0.03).matrix();
    let t = Vector3::new(0.8, 0.1, 0.15).normalize();
    let px = |x: &Vector3<f64>| [f * x[0] / x[2] + w / 2.0, f * x[1] / x[2] + h / 2.0];
    let (mut p1, mut p2, mut ok) = (vec![], vec![], vec![]);
    while p1.len() < 500 {
        let inlier = p1.len().is_multiple_of(2);
        let z = rng.gen_range(3.0..8.0);
        let x = Vector3::new(rng.gen_range(-0.6..0.6) * z, rng.gen_range(-0.45..0.45) * z, z);
        let pa = px(&x);
        let pb = if inlier { px(&(r * x + t)) } else { [rng.gen_range(0.0..w), rng.gen_range(0.0..h)] };
        if !(0.0..w).contains(&pb[0]) || !(0.0..h).contains(&pb[1]) {
            continue;
        }
        let mut n = |p: [f64; 2]| [p[0] + noise.sample(&mut rng), p[1] + noise.sample(&mut rng)];
        p1.push(n(pa));
        p2.push(n(pb));
        ok.push(inlier);
    }
    let norm =
        |v: &[[f64; 2]]| -> Vec<[f64; 2]> { v.iter().map(|p| [(p[0] - w / 2.0) / f, (p[1] - h / 2.0) / f]).collect() };
    let (n1, n2) = (norm(&p1), norm(&p2));
    let prm = RansacParams { threshold_px: 1.5 / f, seed: 4, ..Default::default() };
    let mut row = serde_json::json!({});
    let mut pose5 = None;
    for (name, solver) in [("five_point", EssentialSolver::FivePoint), ("eight_point", EssentialSolver::EightPoint)] {
        let fit = find_essential_with(&n1, &n2, &prm, solver)?;
        let pose = recover_pose(&fit.model, &n1, &n2, Some(&fit.inliers), 50.0)?;
        let (tmin, tmed) = time_min_median(a.runs, || {
            let fit = find_essential_with(&n1, &n2, &prm, solver).expect("synthetic E fits");
            recover_pose(&fit.model, &n1, &n2, Some(&fit.inliers), 50.0).expect("pose");
        });
        let recall = ok.iter().zip(&fit.inliers).filter(|(&a, &b)| a && b).count() as f64 / 250.0;
        let rot = (((pose.r.transpose() * r).trace() - 1.0) / 2.0).clamp(-1.0, 1.0).acos().to_degrees();
        let tdir = pose.t.dot(&t).clamp(-1.0, 1.0).acos().to_degrees();
        row[name] = serde_json::json!({"ms_min": tmin, "ms_median": tmed, "hypotheses": fit.iterations,
            "n_inliers": fit.n_inliers, "inlier_recall": recall, "rotation_error_deg": rot, "translation_error_deg": tdir});
        if pose5.is_none() {
            pose5 = Some((pose, fit.inliers));
        }
    }
    if let (Some(py), Some((pose, inliers))) = (&a.peer_python, pose5) {
        let tmp = std::env::temp_dir().join(format!("laparo_geo_essential_{}.json", std::process::id()));
        let inp = serde_json::json!({"p1": p1, "p2": p2, "true_inlier": ok, "focal": f, "pp": [w / 2.0, h / 2.0],
            "threshold_px": 1.5, "runs": a.runs, "threads": a.threads,
            "r_true": r.row_iter().map(|v| [v[0], v[1], v[2]]).collect::<Vec<_>>(), "t_true": [t[0], t[1], t[2]],
            "laparo": {"r": pose.r.row_iter().map(|v| [v[0], v[1], v[2]]).collect::<Vec<_>>(),
                "t": [pose.t[0], pose.t[1], pose.t[2]], "inliers": inliers}});
        laparo_core::atomic::write_atomic(&tmp, serde_json::to_string(&inp)?.as_bytes())?;
        let o = std::process::Command::new(py).arg("scripts/essential_opencv.py").arg(&tmp).output();
        let _ = std::fs::remove_file(&tmp);
        let o = o.context("running scripts/essential_opencv.py")?;
        if !o.status.success() {
            bail!("essential peer script failed: {}", String::from_utf8_lossy(&o.stderr));
        }
        let peer: serde_json::Value = serde_json::from_slice(&o.stdout).context("parsing the essential peer's JSON")?;
        let ours = row["five_point"]["ms_min"].as_f64();
        row["ratio_five_point_over_opencv_min"] =
            serde_json::json!(ours.zip(peer["ms_min"].as_f64()).map(|(a, b)| a / b));
        row["opencv"] = peer;
    }
    out["essential_500_50pct"] = row;
    Ok(())
}

fn dy_eval_pts(r: &laparo_stereo::SelfRectification, pl: &[[f64; 2]], pr: &[[f64; 2]]) -> Result<DyStats> {
    let mut v = Vec::with_capacity(pl.len());
    for (p, q) in pl.iter().zip(pr) {
        let (Some(x), Some(y)) = (r.rectify_left(p[0], p[1]), r.rectify_right(q[0], q[1])) else {
            bail!("a correspondence maps to infinity")
        };
        v.push(y[1] - x[1]);
    }
    Ok(DyStats::of(&v))
}
