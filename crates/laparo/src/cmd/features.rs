//! `laparo features ...`: keypoints, descriptors, matching and COLMAP export (thesis §4.2, §4.5).
//!
//! * `detect`: SIFT or ORB keypoints (+ descriptors) of one image → JSON;
//! * `match`: detect in two images, match (ratio test, mutual check) → matches.json and a match
//!   picture; with `--homography`, matches are scored (two-way transfer error < ε: green correct,
//!   red wrong) as in thesis §4.5.1;
//! * `colmap`: detect in every image of a folder, match all pairs, verify them (RANSAC F / H),
//!   write a COLMAP database.db that `colmap mapper` reads.
use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use laparo_core::atomic::{refuse_overwrite, refuse_overwrite_files, refuse_overwrite_in, write_atomic};
use laparo_core::image::{Image, Mask};
use laparo_core::io;
use laparo_features::colmap::{CameraModel, ColmapCamera, ColmapDatabase, TwoViewConfig, TwoViewGeometry};
use laparo_features::draw::{GREEN, RED};
use laparo_features::refcheck::{apply_h, invert_h};
use laparo_features::{
    detect_and_describe, draw_matches, find_fundamental, find_homography, match_features, DetectorConfig, Features,
    Match, MatchConfig, RansacParams, RatioTest,
};
use nalgebra::Matrix3;
use rayon::prelude::*;
use serde_json::json;
use std::path::{Path, PathBuf};

#[derive(Subcommand)]
pub enum FeaturesCmd {
    /// Detect keypoints and compute descriptors of one image → JSON (keypoints, descriptors).
    Detect(DetectArgs),
    /// Detect and match two images → matches.json, matches.png (+ scores with --homography).
    Match(MatchArgs),
    /// Detect in every image of a folder, match all pairs, write a COLMAP database.
    Colmap(ColmapArgs),
}

#[derive(Args)]
pub struct DetectArgs {
    /// Input image (PNG, JPEG, TIFF; colour is converted to grey).
    #[arg(long)]
    pub image: PathBuf,
    /// Region of interest: keypoints are kept only where the mask is non-zero.
    #[arg(long)]
    pub mask: Option<PathBuf>,
    /// Detector: sift or orb.
    #[arg(long, default_value = "sift")]
    pub detector: String,
    /// Output JSON.
    #[arg(long)]
    pub out: PathBuf,
}

#[derive(Args)]
pub struct MatchOpts {
    /// Detector: sift or orb.
    #[arg(long, default_value = "sift")]
    pub detector: String,
    /// Ratio test: lowe:R (distance ratio, default lowe:0.8), ubc:T (VLFeat vl_ubcmatch on squared
    /// distances; the thesis code used ubc:2.8), or none.
    #[arg(long, default_value = "lowe:0.8")]
    pub ratio: String,
    /// One-way matching (no mutual nearest-neighbour check).
    #[arg(long)]
    pub no_mutual: bool,
}

#[derive(Args)]
pub struct MatchArgs {
    /// First image.
    #[arg(long)]
    pub image1: PathBuf,
    /// Second image.
    #[arg(long)]
    pub image2: PathBuf,
    /// Mask of image 1 (keypoints kept where non-zero).
    #[arg(long)]
    pub mask1: Option<PathBuf>,
    /// Mask of image 2.
    #[arg(long)]
    pub mask2: Option<PathBuf>,
    #[command(flatten)]
    pub opts: MatchOpts,
    /// Ground-truth homography image 1 → image 2 (JSON: a 3×3 row-major array, or {"H": …});
    /// matches are then scored as correct when the two-way transfer error is below --eps-px.
    #[arg(long)]
    pub homography: Option<PathBuf>,
    /// Correctness threshold on the two-way averaged transfer error, px (thesis: 3).
    #[arg(long, default_value_t = 3.0)]
    pub eps_px: f64,
    /// Output folder.
    #[arg(long)]
    pub out: PathBuf,
}

#[derive(Args)]
pub struct ColmapArgs {
    /// Folder of images (png, jpg, jpeg, tif, tiff; sorted by name; one camera for all).
    #[arg(long)]
    pub images: PathBuf,
    #[command(flatten)]
    pub opts: MatchOpts,
    /// Pinhole intrinsics fx,fy,cx,cy in px (laparo convention: pixel centres at integers);
    /// default: SIMPLE_RADIAL with f = 1.2·max(w, h) and the image centre, refined by COLMAP.
    #[arg(long, value_delimiter = ',')]
    pub intrinsics: Option<Vec<f64>>,
    /// Minimum RANSAC inliers (F, 4 px) for a pair to be written to two_view_geometries (COLMAP: 15).
    #[arg(long, default_value_t = 15)]
    pub min_matches: usize,
    /// Output database (replaced if it exists).
    #[arg(long)]
    pub colmap_db: PathBuf,
}

pub fn run(c: FeaturesCmd) -> Result<()> {
    match c {
        FeaturesCmd::Detect(a) => detect_cmd(&a),
        FeaturesCmd::Match(a) => match_cmd(&a),
        FeaturesCmd::Colmap(a) => colmap_cmd(&a),
    }
}

/// Parse `--ratio`.
pub fn parse_ratio(s: &str) -> Result<RatioTest> {
    let s = s.trim().to_ascii_lowercase();
    if s == "none" {
        return Ok(RatioTest::None);
    }
    let (kind, v) = s.split_once(':').with_context(|| format!("--ratio '{s}': expected lowe:R, ubc:T or none"))?;
    let v: f32 = v.parse().with_context(|| format!("--ratio '{s}': '{v}' is not a number"))?;
    match kind {
        "lowe" => Ok(RatioTest::Lowe(v)),
        "ubc" => Ok(RatioTest::Ubc(v)),
        _ => bail!("--ratio '{s}': expected lowe:R, ubc:T or none"),
    }
}

fn match_config(o: &MatchOpts) -> Result<(DetectorConfig, MatchConfig)> {
    let det = DetectorConfig::by_name(&o.detector).context("--detector")?;
    Ok((det, MatchConfig { ratio: parse_ratio(&o.ratio)?, mutual: !o.no_mutual }))
}

fn read_gray(p: &Path) -> Result<Image<u8>> {
    let img = io::read_image(p).with_context(|| format!("reading image {}", p.display()))?;
    Ok(laparo_features::detect::to_gray_u8(&img))
}

fn read_mask(p: &Option<PathBuf>, img: &Image<u8>, what: &str) -> Result<Option<Mask>> {
    let Some(p) = p else { return Ok(None) };
    let m = io::read_mask(p).with_context(|| format!("{what} {}", p.display()))?;
    if m.width != img.width || m.height != img.height {
        bail!("{what} {} is {}x{}, the image is {}x{}", p.display(), m.width, m.height, img.width, img.height);
    }
    Ok(Some(m))
}

fn write_json(p: &Path, v: &serde_json::Value) -> Result<()> {
    write_atomic(p, (serde_json::to_string_pretty(v)? + "\n").as_bytes())
        .with_context(|| format!("writing {}", p.display()))
}

fn detect_cmd(a: &DetectArgs) -> Result<()> {
    let mut inputs: Vec<&Path> = vec![&a.image];
    inputs.extend(a.mask.as_deref());
    refuse_overwrite_files(&[&a.out], &inputs).context("--out")?;
    let det = DetectorConfig::by_name(&a.detector).context("--detector")?;
    let img = read_gray(&a.image)?;
    let mask = read_mask(&a.mask, &img, "--mask")?;
    let f = detect_and_describe(&img, &det, mask.as_ref())?;
    write_json(
        &a.out,
        &json!({"image": a.image, "width": img.width, "height": img.height, "detector": det, "n_keypoints": f.len(),
                "keypoints": f.keypoints, "descriptors": f.descriptors}),
    )?;
    println!("{}: {} {} keypoints -> {}", a.image.display(), f.len(), det.name(), a.out.display());
    Ok(())
}

/// Read a 3×3 homography from JSON: `[[…],[…],[…]]`, a flat 9-array, or `{"H": …}`.
pub fn read_homography(p: &Path) -> Result<[[f64; 3]; 3]> {
    let s = std::fs::read_to_string(p).with_context(|| format!("reading --homography {}", p.display()))?;
    let v: serde_json::Value =
        serde_json::from_str(&s).with_context(|| format!("parsing --homography {}", p.display()))?;
    let v = v.get("H").cloned().unwrap_or(v);
    let what = format!("--homography {}", p.display());
    let num = |e: &serde_json::Value, at: String| -> Result<f64> {
        e.as_f64().with_context(|| format!("{what}: entry {at} ({e}) is not a number"))
    };
    // Either 3 rows of 3 numbers or a flat array of 9: no ragged rows, no mixing.
    let flat: Vec<f64> = match v.as_array().map(|a| a.as_slice()) {
        Some(rows) if rows.iter().all(serde_json::Value::is_array) => {
            if rows.len() != 3 || rows.iter().any(|r| r.as_array().map_or(0, Vec::len) != 3) {
                let lens: Vec<usize> = rows.iter().map(|r| r.as_array().map_or(0, Vec::len)).collect();
                bail!("{what}: expected 3 rows of 3 numbers, got rows of {lens:?}");
            }
            let mut f = Vec::with_capacity(9);
            for (i, r) in rows.iter().enumerate() {
                for (j, e) in r.as_array().into_iter().flatten().enumerate() {
                    f.push(num(e, format!("[{i}][{j}]"))?);
                }
            }
            f
        }
        Some(flat) if flat.len() == 9 => {
            flat.iter().enumerate().map(|(k, e)| num(e, format!("[{k}]"))).collect::<Result<_>>()?
        }
        _ => bail!("{what}: expected a 3x3 array of numbers (or 9 numbers)"),
    };
    // A homography is defined up to scale: normalise by its largest entry, then the matrix must be
    // well conditioned (an entry of ±1e308 beside entries of 1 is numerically singular and maps every
    // point to infinity).
    let big = flat.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    if !(big.is_finite() && big > 0.0) {
        bail!("{what}: the entries must be finite and not all zero");
    }
    // by the power of two nearest the largest entry: exact, so the transfer errors are those of the matrix as
    // given, bit for bit (Python's match_images takes it unscaled)
    let pow2 = 2f64.powi(big.log2().round() as i32);
    let h: [[f64; 3]; 3] = std::array::from_fn(|i| std::array::from_fn(|j| flat[3 * i + j] / pow2));
    let sv = nalgebra::Matrix3::from_fn(|i, j| h[i][j]).singular_values();
    let cond = sv.max() / sv.min();
    if cond.is_nan() || cond >= 1e12 {
        bail!("{what}: singular or ill-conditioned (condition number {cond:.3e}; an image homography has far less)");
    }
    invert_h(&h).with_context(|| what.clone())?;
    Ok(h)
}

fn match_cmd(a: &MatchArgs) -> Result<()> {
    let mut inputs: Vec<&Path> = vec![&a.image1, &a.image2];
    inputs.extend([&a.mask1, &a.mask2].into_iter().flatten().map(PathBuf::as_path));
    inputs.extend(a.homography.as_deref());
    refuse_overwrite_in(&a.out, &["matches.png", "matches.json"], &inputs).context("--out")?;
    let (det, mcfg) = match_config(&a.opts)?;
    super::check::number("--eps-px", a.eps_px, (std::ops::Bound::Excluded(0.0), std::ops::Bound::Included(1e4)))?;
    let h = a.homography.as_deref().map(read_homography).transpose()?;
    let (img1, img2) = (read_gray(&a.image1)?, read_gray(&a.image2)?);
    let (m1, m2) = (read_mask(&a.mask1, &img1, "--mask1")?, read_mask(&a.mask2, &img2, "--mask2")?);
    let (f1, f2) =
        rayon::join(|| detect_and_describe(&img1, &det, m1.as_ref()), || detect_and_describe(&img2, &det, m2.as_ref()));
    let (f1, f2) = (f1?, f2?);
    let matches = match_features(&f1, &f2, &mcfg)?;
    // Two-way averaged transfer error (thesis §4.5.1) under the homography, if given.
    let errors: Option<Vec<f64>> = h.map(|h| {
        let hinv = invert_h(&h).expect("checked when read");
        matches
            .iter()
            .map(|m| {
                let (p, q) = (f1.keypoints[m.i1 as usize], f2.keypoints[m.i2 as usize]);
                let (tp, tq) = (apply_h(&h, [p.x, p.y]), apply_h(&hinv, [q.x, q.y]));
                0.5 * ((tp[0] - q.x).hypot(tp[1] - q.y) + (tq[0] - p.x).hypot(tq[1] - p.y))
            })
            .collect()
    });
    if let Some(e) = &errors {
        let bad = e.iter().filter(|x| !x.is_finite()).count();
        if bad > 0 {
            bail!(
                "--homography {}: the transfer error is not finite for {bad} of {} matches (the homography maps \
                 them to infinity); check the matrix",
                a.homography.as_deref().unwrap_or(Path::new("")).display(),
                e.len()
            );
        }
    }
    let colours: Vec<[u8; 3]> = match &errors {
        Some(e) => e.iter().map(|&e| if e < a.eps_px { GREEN } else { RED }).collect(),
        None => vec![GREEN; matches.len()],
    };
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let pic = draw_matches(&img1, &img2, &f1.keypoints, &f2.keypoints, &matches, &colours);
    io::write_png(a.out.join("matches.png"), &pic)?;
    let n_correct = errors.as_ref().map(|e| e.iter().filter(|&&x| x < a.eps_px).count());
    let rows: Vec<serde_json::Value> = matches
        .iter()
        .enumerate()
        .map(|(k, m)| {
            let (p, q) = (f1.keypoints[m.i1 as usize], f2.keypoints[m.i2 as usize]);
            let mut r =
                json!({"i1": m.i1, "i2": m.i2, "x1": p.x, "y1": p.y, "x2": q.x, "y2": q.y, "distance": m.distance});
            if let Some(e) = &errors {
                r["transfer_error_px"] = json!(e[k]);
                r["correct"] = json!(e[k] < a.eps_px);
            }
            r
        })
        .collect();
    let summary = json!({
        "image1": a.image1, "image2": a.image2, "detector": det, "match": mcfg,
        "n_keypoints1": f1.len(), "n_keypoints2": f2.len(), "n_matches": matches.len(),
        "n_correct": n_correct, "eps_px": a.eps_px,
        "precision": n_correct.map(|c| if matches.is_empty() { 0.0 } else { c as f64 / matches.len() as f64 }),
        "matches": rows,
    });
    write_json(&a.out.join("matches.json"), &summary)?;
    match n_correct {
        Some(c) => println!(
            "{} matches, {c} correct (two-way transfer error < {} px) -> {}",
            matches.len(),
            a.eps_px,
            a.out.display()
        ),
        None => println!("{} matches ({} / {} keypoints) -> {}", matches.len(), f1.len(), f2.len(), a.out.display()),
    }
    Ok(())
}

fn list_images(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .with_context(|| format!("--images {}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            let e = p.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
            matches!(e.as_str(), "png" | "jpg" | "jpeg" | "tif" | "tiff")
        })
        .collect();
    v.sort();
    if v.len() < 2 {
        bail!("--images {}: need at least 2 images (png, jpg, tif), found {}", dir.display(), v.len());
    }
    Ok(v)
}

/// laparo px (pixel centres at integers) → COLMAP px (+0.5): x' = T x, T = [1 0 .5; 0 1 .5; 0 0 1].
fn to_colmap_px(m: &Matrix3<f64>, is_h: bool) -> [f64; 9] {
    let t = Matrix3::new(1.0, 0.0, 0.5, 0.0, 1.0, 0.5, 0.0, 0.0, 1.0);
    let ti = Matrix3::new(1.0, 0.0, -0.5, 0.0, 1.0, -0.5, 0.0, 0.0, 1.0);
    // H' = T H T⁻¹; F' = T⁻ᵀ F T⁻¹.
    let r = if is_h { t * m * ti } else { ti.transpose() * m * ti };
    std::array::from_fn(|k| r[(k / 3, k % 3)])
}

/// RANSAC verification of one pair (None: fewer than `min` inliers or no model).
fn verify_pair(f1: &Features, f2: &Features, m: &[Match], min: usize, seed: u64) -> Option<TwoViewGeometry> {
    if m.len() < min.max(8) {
        return None;
    }
    let p1: Vec<[f64; 2]> = m.iter().map(|m| [f1.keypoints[m.i1 as usize].x, f1.keypoints[m.i1 as usize].y]).collect();
    let p2: Vec<[f64; 2]> = m.iter().map(|m| [f2.keypoints[m.i2 as usize].x, f2.keypoints[m.i2 as usize].y]).collect();
    let prm = RansacParams { threshold_px: 4.0, confidence: 0.999, max_iters: 10_000, seed };
    let ff = find_fundamental(&p1, &p2, &prm).ok()?;
    if ff.n_inliers < min {
        return None;
    }
    let hf = find_homography(&p1, &p2, &prm).ok();
    let planar = hf.as_ref().is_some_and(|h| h.n_inliers as f64 > 0.8 * ff.n_inliers as f64);
    let (config, flags) = if planar {
        (TwoViewConfig::PlanarOrPanoramic, &hf.as_ref().expect("planar implies H").inliers)
    } else {
        (TwoViewConfig::Uncalibrated, &ff.inliers)
    };
    Some(TwoViewGeometry {
        config,
        inliers: m.iter().zip(flags).filter(|(_, &ok)| ok).map(|(m, _)| *m).collect(),
        f: to_colmap_px(&ff.model, false),
        e: [0.0; 9],
        h: hf.map(|h| to_colmap_px(&h.model, true)).unwrap_or([0.0; 9]),
        qvec: [1.0, 0.0, 0.0, 0.0],
        tvec: [0.0; 3],
    })
}

fn colmap_cmd(a: &ColmapArgs) -> Result<()> {
    refuse_overwrite(&a.colmap_db, &[&a.images], false).context("--colmap-db")?;
    let paths = list_images(&a.images)?;
    // Every image read is an input: a database written over one of them would replace the frame.
    let inputs: Vec<&Path> = paths.iter().map(PathBuf::as_path).collect();
    refuse_overwrite_files(&[&a.colmap_db], &inputs).context("--colmap-db")?;
    let (det, mcfg) = match_config(&a.opts)?;
    if let Some(k) = &a.intrinsics {
        if k.len() != 4 || k.iter().any(|v| !v.is_finite()) || k[0] <= 0.0 || k[1] <= 0.0 {
            bail!("--intrinsics: expected fx,fy,cx,cy (4 finite numbers, fx, fy > 0), got {k:?}");
        }
    }
    let style = ProgressStyle::with_template("{msg} {bar:30} {pos}/{len} {elapsed}").expect("valid template");
    let pb = ProgressBar::new(paths.len() as u64).with_style(style.clone()).with_message("detect");
    let feats: Vec<(Image<u8>, Features)> = paths
        .par_iter()
        .map(|p| {
            let img = read_gray(p)?;
            let f = detect_and_describe(&img, &det, None).with_context(|| format!("{}", p.display()))?;
            pb.inc(1);
            Ok((img, f))
        })
        .collect::<Result<_>>()?;
    pb.finish_and_clear();
    let (w, h) = (feats[0].0.width, feats[0].0.height);
    if let Some((i, _)) = feats.iter().enumerate().find(|(_, (im, _))| im.width != w || im.height != h) {
        bail!("{}: all images must have the size of the first ({w}x{h})", paths[i].display());
    }
    let cam = match &a.intrinsics {
        Some(k) => ColmapCamera {
            model: CameraModel::Pinhole,
            width: w as u32,
            height: h as u32,
            params: vec![k[0], k[1], k[2] + 0.5, k[3] + 0.5],
            prior_focal_length: true,
        },
        None => {
            let f = 1.2 * w.max(h) as f64;
            ColmapCamera {
                model: CameraModel::SimpleRadial,
                width: w as u32,
                height: h as u32,
                params: vec![f, w as f64 / 2.0, h as f64 / 2.0, 0.0],
                prior_focal_length: false,
            }
        }
    };
    let pairs: Vec<(usize, usize)> = (0..paths.len()).flat_map(|i| (i + 1..paths.len()).map(move |j| (i, j))).collect();
    let pb = ProgressBar::new(pairs.len() as u64).with_style(style).with_message("match");
    let matched: Vec<Vec<Match>> = pairs
        .par_iter()
        .map(|&(i, j)| {
            let m = match_features(&feats[i].1, &feats[j].1, &mcfg);
            pb.inc(1);
            m
        })
        .collect::<Result<_, _>>()?;
    pb.finish_and_clear();
    let mut db = ColmapDatabase::create(&a.colmap_db)?;
    let cid = db.add_camera(&cam)?;
    let mut ids = vec![];
    for (p, (_, f)) in paths.iter().zip(&feats) {
        let name = p.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        let id = db.add_image(&name, cid)?;
        db.add_keypoints(id, &f.keypoints)?;
        db.add_descriptors(id, &f.descriptors)?;
        ids.push(id);
    }
    // Geometric verification as COLMAP's defaults: F and H by RANSAC (4 px), ≥ min_matches
    // inliers; H explaining > 80 % of F's inliers → PLANAR_OR_PANORAMIC, else UNCALIBRATED.
    let geoms: Vec<Option<TwoViewGeometry>> = pairs
        .par_iter()
        .zip(&matched)
        .enumerate()
        .map(|(k, (&(i, j), m))| verify_pair(&feats[i].1, &feats[j].1, m, a.min_matches, k as u64))
        .collect();
    let mut n_verified = 0;
    for ((&(i, j), m), g) in pairs.iter().zip(&matched).zip(&geoms) {
        db.add_matches(ids[i], ids[j], m)?;
        if let Some(g) = g {
            db.add_two_view_geometry(ids[i], ids[j], g)?;
            n_verified += 1;
        }
    }
    db.finish()?;
    println!(
        "{} images, {} pairs ({n_verified} verified with ≥ {} inliers in two_view_geometries), {} keypoints -> {}",
        paths.len(),
        pairs.len(),
        a.min_matches,
        feats.iter().map(|(_, f)| f.len()).sum::<usize>(),
        a.colmap_db.display()
    );
    Ok(())
}
