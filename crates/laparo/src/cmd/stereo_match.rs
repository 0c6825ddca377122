//! `laparo stereo match`: semi-global matching (laparo_stereo::match_pair) of a raw or calibrated
//! stereo pair with a signed disparity range, an optional vertical tolerance, depth, confidence,
//! colour maps and stats.json (issue 14, thesis §3.3).
use super::stereo::CalibArgs;
use anyhow::{bail, Context};
use clap::Args;
use laparo_core::colormap::{colorize, percentile_range, Colormap};
use laparo_core::image::Image;
use laparo_core::plot::with_colorbar;
use laparo_stereo::{match_pair, Paths, SgmOutput, SgmParams};
use laparo_stereo::{DisparityGeometry, Rectification, RectifyOptions, Side};
use std::path::{Path, PathBuf};

#[derive(Args, Debug)]
pub struct MatchArgs {
    /// Left image (8-bit PNG/JPEG/TIFF, grey/RGB/RGBA).
    #[arg(long)]
    pub left: PathBuf,
    /// Right image (same size).
    #[arg(long)]
    pub right: PathBuf,
    /// Disparity range A:B searched, [A, B) in px, d = x_L − x_R; either sign (raw SCARED
    /// pairs: about −48:0). With --calib, in the rectified images.
    #[arg(long, allow_hyphen_values = true)]
    pub range: String,
    /// Output folder.
    #[arg(long)]
    pub out: PathBuf,
    #[command(flatten)]
    pub calib: CalibArgs,
    /// With --calib: OpenCV's free scaling α of the rectification: 0 = only pixels seen by both
    /// source images (default; crops the borders), 1 = every source pixel kept, < 0 = no scaling.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true, requires = "calib")]
    pub alpha: f64,
    /// With --calib: keep each camera's own c_x (doffs = c_x^L − c_x^R ≠ 0, the raw-like
    /// disparity convention) instead of a common principal point. A rig with a large principal-
    /// point offset (SCARED: −91 px) then keeps in the rectified right image the content near the
    /// left border that the right camera does see; --range is in this convention.
    #[arg(long, requires = "calib")]
    pub keep_offset: bool,
    /// Self-rectify the raw pair without a calibration (keypoint matches, robust F, quasi-Euclidean
    /// rectification of laparo_stereo::self_rectify()), match in the rectified frame and map the
    /// disparity back to the raw left frame (d = x_L − x_R). --range is the raw range; the
    /// rectified search range is shifted by the inliers' median change of disparity.
    #[arg(long, conflicts_with = "calib")]
    pub self_rectify: bool,
    /// With --self-rectify: the keypoint matcher, `fast` (ORB + guided matching + sub-pixel
    /// refinement; default, a fraction of a second per 1280×1024 pair) or `sift` (seconds per pair).
    #[arg(long, default_value = "fast", requires = "self_rectify")]
    pub self_rectify_features: String,
    /// `default` (4 paths) or `accurate` (8 paths).
    #[arg(long, default_value = "default")]
    pub mode: String,
    /// Vertical tolerance k (rows): search y ± k in the right image and report the vertical
    /// offset per pixel (dy.pfm). For raw, near-rectified pairs (|dy| ≲ 1 px: k = 1).
    #[arg(long, default_value_t = 0)]
    pub vertical_tol: usize,
    /// Penalty P1 (census bits).
    #[arg(long)]
    pub p1: Option<u16>,
    /// Penalty P2 (census bits, before the intensity adaptation).
    #[arg(long)]
    pub p2: Option<u16>,
    /// Uniqueness margin (percent, 0 = off).
    #[arg(long)]
    pub uniqueness: Option<u8>,
    /// Left–right check tolerance (px); negative = no check.
    #[arg(long, allow_hyphen_values = true)]
    pub lr_max_diff: Option<i32>,
    /// Speckle filter: smallest region kept (px, 0 = off).
    #[arg(long)]
    pub speckle_window: Option<usize>,
    /// Fill invalid pixels with the row background (disparity_filled.pfm is written too).
    #[arg(long)]
    pub fill_holes: bool,
    /// Focal length (px) for depth without a calibration (with --baseline-mm).
    #[arg(long, requires = "baseline_mm")]
    pub focal_px: Option<f64>,
    /// Baseline (mm) for depth without a calibration (with --focal-px).
    #[arg(long, requires = "focal_px")]
    pub baseline_mm: Option<f64>,
    /// Principal-point offset c_x^L − c_x^R (px) for depth without a calibration.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub cx_offset_px: f64,
}

/// Parse `A:B` into (A, B).
pub fn parse_range(s: &str) -> anyhow::Result<(i32, i32)> {
    let (a, b) = s.split_once(':').with_context(|| format!("--range {s:?}: expected A:B, e.g. -48:0"))?;
    let a: i32 = a.trim().parse().with_context(|| format!("--range {s:?}: {a:?} is not an integer"))?;
    let b: i32 = b.trim().parse().with_context(|| format!("--range {s:?}: {b:?} is not an integer"))?;
    if b <= a {
        bail!("--range {s:?}: empty range (need A < B)");
    }
    Ok((a, b))
}

fn params(a: &MatchArgs, lo: i32, hi: i32) -> anyhow::Result<SgmParams> {
    let mut p = match a.mode.as_str() {
        "default" => SgmParams::new(lo, hi),
        "accurate" => SgmParams::accurate(lo, hi),
        m => bail!("--mode {m:?}: expected default or accurate"),
    };
    p.vertical_tol = a.vertical_tol;
    if let Some(v) = a.p1 {
        p.p1 = v;
    }
    if let Some(v) = a.p2 {
        p.p2 = v;
    }
    if let Some(v) = a.uniqueness {
        p.uniqueness_pct = v;
    }
    if let Some(v) = a.lr_max_diff {
        p.lr_max_diff = (v >= 0).then_some(v);
    }
    if let Some(v) = a.speckle_window {
        p.speckle_window = v;
    }
    Ok(p)
}

fn f32_to_f64(img: &Image<f32>) -> Image<f64> {
    img.map(|v| if v.is_finite() { v as f64 } else { f64::NAN })
}

fn save_colour(
    path: &Path,
    img: &Image<f64>,
    cmap: Colormap,
    label: &str,
    fixed: Option<(f64, f64)>,
) -> anyhow::Result<()> {
    let (lo, hi) = fixed.or_else(|| percentile_range(img, 1.0, 99.0)).unwrap_or((0.0, 1.0));
    let (lo, hi) = if hi > lo { (lo, hi) } else { (lo - 1.0, lo + 1.0) };
    laparo_core::io::write_png(path, &with_colorbar(&colorize(img, lo, hi, cmap), lo, hi, cmap, label))?;
    Ok(())
}

fn write_pfm(path: &Path, img: &Image<f32>) -> anyhow::Result<()> {
    laparo_core::io::write_pfm(path, img).with_context(|| format!("writing {}", path.display()))
}

/// Map a disparity of the rectified left image back to the raw left frame: for raw pixel
/// (u, v), its rectified position (x', y'), the rectified disparity d' there, the rectified match
/// (x' − d', y'), and that point's raw right position (u_R, v_R): raw d = u − u_R, dy = v_R − v
/// (NaN/+∞ where unknown). d' is interpolated bilinearly when the four surrounding pixels are
/// valid and within 1 px of each other (one surface), else taken from the nearest pixel (so
/// depth edges are not blended and no invalid pixel becomes valid).
pub fn to_raw_frame(rect: &Rectification, disp: &Image<f32>, w: usize, h: usize) -> (Image<f32>, Image<f32>) {
    use rayon::prelude::*;
    let mut d = Image::filled(w, h, 1, f32::INFINITY);
    let mut dy = Image::filled(w, h, 1, f32::NAN);
    d.data.par_chunks_mut(w).zip(dy.data.par_chunks_mut(w)).enumerate().for_each(|(v, (drow, dyrow))| {
        for u in 0..w {
            let Some((x, y)) = rect.rectify_point(Side::Left, u as f64, v as f64) else { continue };
            let Some(dr) = sample_disparity(disp, x, y) else { continue };
            if !dr.is_finite() {
                continue;
            }
            if let Some((ur, vr)) = rect.source_point(Side::Right, x - dr as f64, y) {
                drow[u] = (u as f64 - ur) as f32;
                dyrow[u] = (vr - v as f64) as f32;
            }
        }
    });
    (d, dy)
}

/// Largest disparity span (px) of the four pixels around a sample that is still interpolated.
const BILINEAR_MAX_SPAN_PX: f32 = 2.0;

/// Disparity at a sub-pixel position: the nearest pixel's value (`None` outside, +∞ if invalid),
/// bilinear when its four neighbours are valid and span at most 1 px.
fn sample_disparity(disp: &Image<f32>, x: f64, y: f64) -> Option<f32> {
    let near = disp.sample_nearest(x, y, 0)?;
    if !near.is_finite() {
        return Some(near);
    }
    let w = disp.width;
    let v = laparo_core::remap::sample_smooth(w, disp.height, x, y, BILINEAR_MAX_SPAN_PX, |i, j| {
        let v = disp.data[j * w + i];
        v.is_finite().then_some(v)
    });
    Some(v.map_or(near, |v| v as f32))
}

/// `--self-rectify`: `laparo_stereo::match_self_rectified_with` (`--self-rectify-features`
/// matches, self-rectification,
/// SGM on the rectified pair, results in the raw left frame), with its intermediates written to `--out`.
fn self_rectified_match(
    a: &MatchArgs,
    left: &Image<u8>,
    right: &Image<u8>,
    p: &SgmParams,
) -> anyhow::Result<(SgmOutput, serde_json::Value)> {
    let features = self_rectify_features(a)?;
    let opts = laparo_stereo::SelfRectifyOptions { features, ..Default::default() };
    let m = laparo_stereo::match_self_rectified_with(left, right, p, &opts)
        .with_context(|| format!("self-rectified matching of {} / {}", a.left.display(), a.right.display()))?;
    laparo_core::io::write_png(a.out.join("left_rectified.png"), &m.left_rectified)?;
    laparo_core::io::write_png(a.out.join("right_rectified.png"), &m.right_rectified)?;
    write_pfm(&a.out.join("disparity_rectified.pfm"), &m.disparity_rectified)?;
    let (lo, hi) = m.rectified_range_px;
    let info = serde_json::json!({"rectification": m.rectification, "features": features, "n_matches": m.n_matches, "rectified_range_px": [lo, hi], "median_disparity_shift_px": m.median_disparity_shift_px});
    laparo_core::atomic::write_atomic(
        &a.out.join("self_rectification.json"),
        (serde_json::to_string_pretty(&info)? + "\n").as_bytes(),
    )?;
    Ok((m.output, info))
}

/// `--self-rectify-features` parsed (`fast` or `sift`).
fn self_rectify_features(a: &MatchArgs) -> anyhow::Result<laparo_stereo::FeatureKind> {
    a.self_rectify_features
        .parse()
        .map_err(|e| anyhow::anyhow!("--self-rectify-features '{}': {e}", a.self_rectify_features))
}

/// Every file `stereo match` may write into --out.
const MATCH_OUTPUTS: [&str; 17] = [
    "disparity.pfm",
    "confidence.pfm",
    "disparity.png",
    "confidence.png",
    "dy.pfm",
    "dy.png",
    "disparity_filled.pfm",
    "depth_mm.npy",
    "depth.png",
    "disparity_raw.pfm",
    "dy_raw.pfm",
    "disparity_raw.png",
    "left_rectified.png",
    "right_rectified.png",
    "disparity_rectified.pfm",
    "self_rectification.json",
    "stats.json",
];

/// Bytes per pixel a match holds at once (both images decoded as RGBA and grey, two census
/// transforms, disparity, confidence and their f64 copies): the budget is checked before decoding.
const MATCH_BYTES_PER_PX: f64 = 2.0 * 4.0 + 2.0 + 2.0 * 8.0 + 2.0 * 4.0 + 2.0 * 8.0;

/// Largest match (bytes estimated with [`MATCH_BYTES_PER_PX`]): 2 GiB, a 6500×6500 pair.
const MATCH_MAX_BYTES: f64 = 2.0 * (1u64 << 30) as f64;

pub fn run_match(a: MatchArgs) -> anyhow::Result<()> {
    use super::check::{budget, number, positive};
    let (lo, hi) = parse_range(&a.range)?;
    self_rectify_features(&a)?;
    let p = params(&a, lo, hi)?;
    if let Some(f) = a.focal_px {
        positive("--focal-px", f)?;
    }
    if let Some(b) = a.baseline_mm {
        positive("--baseline-mm", b)?;
    }
    number("--cx-offset-px", a.cx_offset_px, ..)?;
    number("--alpha", a.alpha, ..)?;
    let mut inputs = vec![a.left.as_path(), a.right.as_path()];
    let calib_paths = a.calib.paths();
    inputs.extend(calib_paths.iter().map(PathBuf::as_path));
    laparo_core::atomic::refuse_overwrite_in(&a.out, &MATCH_OUTPUTS, &inputs).context("--out")?;
    for (flag, path) in [("--left", &a.left), ("--right", &a.right)] {
        let (w, h) = laparo_core::io::image_size(path).with_context(|| format!("{flag} {}", path.display()))?;
        budget(
            &format!("{flag} {} ({w}x{h} px)", path.display()),
            w as f64 * h as f64 * MATCH_BYTES_PER_PX,
            MATCH_MAX_BYTES,
            "bytes of matching memory",
        )?;
    }
    let left = laparo_core::io::read_image(&a.left).with_context(|| format!("--left {}", a.left.display()))?;
    let right = laparo_core::io::read_image(&a.right).with_context(|| format!("--right {}", a.right.display()))?;
    if left.size() != right.size() {
        bail!(
            "--left {} is {}x{} but --right {} is {}x{}",
            a.left.display(),
            left.width,
            left.height,
            a.right.display(),
            right.width,
            right.height
        );
    }
    std::fs::create_dir_all(&a.out).with_context(|| format!("cannot create {}", a.out.display()))?;
    let (w, h) = left.size();
    let calib = a.calib.read_for_images(w, h)?;
    let t0 = std::time::Instant::now();
    let mut self_rect = serde_json::Value::Null;
    let (out, geometry, rect): (SgmOutput, Option<DisparityGeometry>, Option<Rectification>) = match &calib {
        None if a.self_rectify => {
            let (o, info) = self_rectified_match(&a, &left, &right, &p)?;
            self_rect = info;
            (o, None, None)
        }
        Some(c) => {
            let label = a.calib.calib.clone().unwrap_or_default();
            for warn in super::stereo::check_calibration_fits(c, w, h, &label)? {
                eprintln!("warning: {warn}");
            }
            let opts = RectifyOptions { alpha: a.alpha, align_principal_points: !a.keep_offset };
            let rect = Rectification::new(c, opts).context("cannot rectify with this calibration")?;
            let (l, ml) = rect.rectify_image(Side::Left, &left)?;
            let (r, mr) = rect.rectify_image(Side::Right, &right)?;
            laparo_core::io::write_png(a.out.join("left_rectified.png"), &l)?;
            // the canvas outside each image (α > 0) is neither matched nor matched against
            let o = laparo_stereo::match_masked(&l, &r, &ml, &mr, &p)?;
            (o, Some(rect.geometry()), Some(rect))
        }
        None => {
            let g = a.focal_px.zip(a.baseline_mm).map(|(f, b)| {
                DisparityGeometry::middlebury(f, b, -a.cx_offset_px, (w as f64 - 1.0) / 2.0, (h as f64 - 1.0) / 2.0)
            });
            (match_pair(&left, &right, &p)?, g, None)
        }
    };
    let ms = t0.elapsed().as_secs_f64() * 1e3;
    let mut disp = out.disparity.clone();
    let o = &a.out;
    write_pfm(&o.join("disparity.pfm"), &disp)?;
    write_pfm(&o.join("confidence.pfm"), &out.confidence)?;
    let disp64 = f32_to_f64(&disp);
    save_colour(&o.join("disparity.png"), &disp64, Colormap::Turbo, "disparity [px]", None)?;
    save_colour(
        &o.join("confidence.png"),
        &out.confidence.map(|v| v as f64),
        Colormap::Viridis,
        "confidence",
        Some((0.0, 1.0)),
    )?;
    if let Some(dy) = &out.dy {
        write_pfm(&o.join("dy.pfm"), dy)?;
        let k = (a.vertical_tol as f64).max(1.0);
        save_colour(&o.join("dy.png"), &f32_to_f64(dy), Colormap::Viridis, "vertical offset [px]", Some((-k, k)))?;
    }
    if a.fill_holes {
        laparo_stereo::fill_background(&mut disp.data, w, h);
    }
    let mut depth_stats = serde_json::Value::Null;
    if let Some(g) = &geometry {
        let dm = g.depth_map(&disp64);
        let depth = Image { width: dm.width, height: dm.height, channels: 1, data: dm.data.clone() };
        laparo_core::io::write_float_map(o.join("depth_mm.npy"), &depth)?;
        save_colour(&o.join("depth.png"), &depth, Colormap::Viridis, "depth [mm]", None)?;
        let mut z: Vec<f64> = depth.data.iter().cloned().filter(|v| v.is_finite()).collect();
        if !z.is_empty() {
            depth_stats =
                serde_json::json!({"n": z.len(), "median_mm": laparo_core::stats::median(&mut z), "geometry": g});
        }
    }
    let mut raw = serde_json::Value::Null;
    if let Some(rect) = &rect {
        let (dr, dyr) = to_raw_frame(rect, &out.disparity, w, h);
        write_pfm(&o.join("disparity_raw.pfm"), &dr)?;
        write_pfm(&o.join("dy_raw.pfm"), &dyr)?;
        save_colour(&o.join("disparity_raw.png"), &f32_to_f64(&dr), Colormap::Turbo, "raw disparity [px]", None)?;
        let mut v: Vec<f64> = dr.data.iter().filter(|d| d.is_finite()).map(|&d| d as f64).collect();
        let n = v.len();
        raw = serde_json::json!({"n_valid": n, "median_px": if n > 0 { laparo_core::stats::median(&mut v) } else { f64::NAN }});
    }
    let mut dv: Vec<f64> = out.disparity.data.iter().filter(|d| d.is_finite()).map(|&d| d as f64).collect();
    let pct = |v: &mut Vec<f64>, q: f64| -> f64 {
        if v.is_empty() {
            return f64::NAN;
        }
        v.sort_by(|a, b| a.total_cmp(b));
        v[((v.len() - 1) as f64 * q).round() as usize]
    };
    let stats = serde_json::json!({
        "left": a.left, "right": a.right, "range_px": [lo, hi], "mode": a.mode,
        "paths": if p.paths == Paths::Eight { 8 } else { 4 },
        "params": p, "counts": out.stats, "ms": ms,
        "valid_fraction": out.stats.n_valid as f64 / (w * h) as f64,
        "disparity_p1_p50_p99_px": [pct(&mut dv, 0.01), pct(&mut dv, 0.5), pct(&mut dv, 0.99)],
        "frame": if rect.is_some() { "rectified (calibrated); disparity_raw.pfm is the raw left frame" } else { "raw left frame" },
        "depth": depth_stats, "raw_frame": raw,
        "rectification": rect.as_ref().map(|_| serde_json::json!({"alpha": a.alpha, "keep_offset": a.keep_offset})),
        "self_rectification": self_rect.get("rectification").map(|r| serde_json::json!({
            "n_matches": self_rect["n_matches"], "n_inliers": r["n_inliers"], "dy_raw": r["dy_raw"],
            "dy_rectified": r["dy_rectified"], "rectified_range_px": self_rect["rectified_range_px"]})),
    });
    laparo_core::atomic::write_atomic(
        &o.join("stats.json"),
        (serde_json::to_string_pretty(&stats)? + "\n").as_bytes(),
    )?;
    println!(
        "matched {}x{} over [{lo}, {hi}) px ({} paths{}) in {ms:.0} ms: {:.1} % valid, d p1/50/99 {:.1}/{:.1}/{:.1} px -> {}",
        w,
        h,
        if p.paths == Paths::Eight { 8 } else { 4 },
        if p.vertical_tol > 0 { format!(", ±{} rows", p.vertical_tol) } else { String::new() },
        100.0 * out.stats.n_valid as f64 / (w * h) as f64,
        stats["disparity_p1_p50_p99_px"][0].as_f64().unwrap_or(f64::NAN),
        stats["disparity_p1_p50_p99_px"][1].as_f64().unwrap_or(f64::NAN),
        stats["disparity_p1_p50_p99_px"][2].as_f64().unwrap_or(f64::NAN),
        o.display()
    );
    Ok(())
}
