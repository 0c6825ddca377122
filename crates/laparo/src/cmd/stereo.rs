//! `laparo stereo ...`: calibrated stereo (thesis §2.2.2, §3.3.6–3.3.8): Bouguet rectification
//! with principal points aligned, disparity → depth / point cloud with the principal-point offset
//! term, and the evaluation of Tables 3.7–3.8.
use super::cats_stats::read_calibration;
use anyhow::{bail, Context};
use clap::{Args, Subcommand};
use laparo_core::calib::StereoCalibration;
use laparo_core::colormap::{colorize, percentile_range, Colormap};
use laparo_core::image::{Image, Mask};
use laparo_core::plot::with_colorbar;
use laparo_stereo::{evaluate_maps, EvalOptions, StereoMetrics};
use laparo_stereo::{DisparityGeometry, Rectification, RectifyOptions, Side};
use std::io::Write;
use std::path::{Path, PathBuf};

#[derive(Subcommand)]
pub enum StereoCmd {
    /// Undistort and rectify a stereo pair (Bouguet, principal points aligned); writes the
    /// rectified PNGs, validity masks, the rectified calibration (JSON) and R1/R2/P1/P2/Q.
    Rectify(RectifyArgs),
    /// Evaluate a predicted disparity map: EPE, Bad-1/2/3 and, with a calibration, depth MAE,
    /// RMSE, Abs Rel and δ_0.25 (Tables 3.7–3.8). Writes JSON, markdown and colour-mapped maps.
    /// Every finite GT disparity is valid, negative ones included (public SCARED evaluators keep
    /// only GT > 0 and so drop most pixels of raw, uncalibrated pairs).
    Eval(EvalArgs),
    /// Convert a left disparity map to depth (mm) with d = f b / z + (c_x^L − c_x^R) (§3.3.8),
    /// optionally to a point cloud (PLY).
    Disp2depth(Disp2DepthArgs),
    /// Semi-global matching of a raw or calibrated pair with a signed range [A, B) and an
    /// optional vertical tolerance: disparity (PFM, +inf invalid), confidence, depth (mm),
    /// colour maps with colour bars and stats.json (thesis §3.3).
    Match(super::stereo_match::MatchArgs),
}

/// Calibration arguments shared by the subcommands.
#[derive(Args, Debug, Clone)]
pub struct CalibArgs {
    /// Stereo calibration: OpenCV YAML (SCARED, EndoVis, ...), laparo JSON, Middlebury calib.txt,
    /// or `INTRINSICS,EXTRINSICS` (OpenCV stereo_calib layout).
    #[arg(long, value_name = "CALIB")]
    pub calib: Option<String>,
    /// Image width for calibration files without an image size (default: the input images' width).
    #[arg(long, requires = "height")]
    pub width: Option<usize>,
    /// Image height for calibration files without an image size (default: the input images' height).
    #[arg(long, requires = "width")]
    pub height: Option<usize>,
}

impl CalibArgs {
    fn read(&self) -> anyhow::Result<Option<StereoCalibration>> {
        let Some(spec) = &self.calib else { return Ok(None) };
        Ok(Some(read_calibration(spec, self.width.zip(self.height))?.1))
    }

    /// The files --calib reads (one file, or INTRINSICS,EXTRINSICS): inputs no output may replace.
    pub(crate) fn paths(&self) -> Vec<PathBuf> {
        match &self.calib {
            Some(c) if !Path::new(c).exists() => c.split(',').map(PathBuf::from).collect(),
            Some(c) => vec![PathBuf::from(c)],
            None => Vec::new(),
        }
    }

    /// [`read`](Self::read), taking the size of the images being processed (`w`, `h`) for a
    /// calibration file that states none (SCARED's), unless --width/--height are given.
    pub(crate) fn read_for_images(&self, w: usize, h: usize) -> anyhow::Result<Option<StereoCalibration>> {
        let sized = CalibArgs { width: self.width.or(Some(w)), height: self.height.or(Some(h)), ..self.clone() };
        sized.read()
    }
}

#[derive(Args, Debug)]
pub struct RectifyArgs {
    #[command(flatten)]
    pub calib: CalibArgs,
    /// Left image (PNG/JPEG/TIFF, 8-bit), or a folder of left frames (batch: the rectification
    /// maps are built once and reused; outputs `OUT/left/<name>.png`, `OUT/right/<name>.png`).
    #[arg(long)]
    pub left: PathBuf,
    /// Right image, or a folder of right frames with the same file names as the left ones.
    #[arg(long)]
    pub right: PathBuf,
    /// Output folder.
    #[arg(long)]
    pub out: PathBuf,
    /// OpenCV's free scaling: 0 = only valid pixels (default), 1 = all source pixels, < 0 = no scaling.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub alpha: f64,
    /// Keep each camera's own c_x (only c_y is shared): doffs ≠ 0.
    #[arg(long)]
    pub keep_offset: bool,
}

#[derive(Args, Debug)]
pub struct EvalArgs {
    /// Predicted left disparity (npy, npz, pfm, tif, 16-bit png).
    #[arg(long)]
    pub pred: PathBuf,
    /// Ground-truth left disparity (non-finite = invalid).
    #[arg(long)]
    pub gt: PathBuf,
    #[command(flatten)]
    pub calib: CalibArgs,
    /// Valid-pixel mask (PNG/JPEG/TIFF: channel 0 non-zero; npy/npz/PFM/EXR: finite and non-zero).
    #[arg(long)]
    pub mask: Option<PathBuf>,
    /// Output folder (metrics.json, metrics.md, PNG maps).
    #[arg(long)]
    pub out: PathBuf,
    /// Print the metrics as one JSON object on stdout, or write it to FILE.
    #[arg(long, value_name = "FILE", num_args = 0..=1, require_equals = true)]
    pub json: Option<Option<PathBuf>>,
    /// Divide the predicted values by this (KITTI 16-bit PNG: 256).
    #[arg(long, default_value_t = 1.0)]
    pub pred_scale: f64,
    /// Divide the ground-truth values by this.
    #[arg(long, default_value_t = 1.0)]
    pub gt_scale: f64,
    /// GT disparity 0 means "no ground truth" (KITTI-style PNGs).
    #[arg(long)]
    pub zero_invalid: bool,
    /// Clamp predicted depth to at least this (m); thesis §3.2.7: 0.01.
    #[arg(long, default_value_t = 0.01)]
    pub depth_min_m: f64,
    /// Clamp predicted depth to at most this (m); thesis §3.2.7: 0.5. `inf` with
    /// `--depth-min-m 0` disables the clamp.
    #[arg(long, default_value_t = 0.5)]
    pub depth_max_m: f64,
    /// Old spelling of --depth-min-m, in mm (hidden; kept for one release).
    #[arg(long, hide = true, conflicts_with = "depth_min_m")]
    pub depth_min_mm: Option<f64>,
    /// Old spelling of --depth-max-m, in mm (hidden; kept for one release).
    #[arg(long, hide = true, conflicts_with = "depth_max_m")]
    pub depth_max_mm: Option<f64>,
    /// Row label in the markdown table.
    #[arg(long, default_value = "prediction")]
    pub label: String,
}

#[derive(Args, Debug)]
pub struct Disp2DepthArgs {
    /// Left disparity map (npy, npz, pfm, tif, 16-bit png).
    #[arg(long)]
    pub disp: PathBuf,
    #[command(flatten)]
    pub calib: CalibArgs,
    /// Output depth map in mm (npy, npz, pfm, tif, or 16-bit png in mm).
    #[arg(long)]
    pub out: PathBuf,
    /// Also write a point cloud (binary PLY, mm; coloured when --image is given).
    #[arg(long)]
    pub ply: Option<PathBuf>,
    /// Left image for point colours.
    #[arg(long)]
    pub image: Option<PathBuf>,
    /// Divide the disparity values by this (KITTI 16-bit PNG: 256).
    #[arg(long, default_value_t = 1.0)]
    pub scale: f64,
}

pub fn run(c: StereoCmd) -> anyhow::Result<()> {
    match c {
        StereoCmd::Rectify(a) => run_rectify(a),
        StereoCmd::Eval(a) => run_eval(a),
        StereoCmd::Disp2depth(a) => run_disp2depth(a),
        StereoCmd::Match(a) => super::stereo_match::run_match(a),
    }
}

fn need_calib(c: &CalibArgs, w: usize, h: usize) -> anyhow::Result<StereoCalibration> {
    c.read_for_images(w, h)?.ok_or_else(|| anyhow::anyhow!("--calib is required"))
}

/// Reject a calibration that cannot belong to `w`×`h` images: a principal point outside the
/// image is an error; one farther than a quarter of the size from the image centre is
/// reported as a warning (returned), the usual sign of a calibration made at another resolution.
pub fn check_calibration_fits(
    calib: &StereoCalibration,
    w: usize,
    h: usize,
    label: &str,
) -> anyhow::Result<Vec<String>> {
    let mut warnings = Vec::new();
    for (side, k) in [("left", &calib.left), ("right", &calib.right)] {
        let (cx, cy) = (k.cx, k.cy);
        if !(cx >= 0.0 && cx <= w as f64 && cy >= 0.0 && cy <= h as f64) {
            bail!(
                "{label}: the {side} principal point ({cx:.1}, {cy:.1}) px lies outside the {w}x{h} image: \
                 this calibration was made for another image size (or --width/--height are wrong)"
            );
        }
        let (ox, oy) = ((cx - w as f64 / 2.0).abs() / w as f64, (cy - h as f64 / 2.0).abs() / h as f64);
        if ox > 0.25 || oy > 0.25 {
            warnings.push(format!(
                "{label}: the {side} principal point ({cx:.1}, {cy:.1}) px is far from the centre of the {w}x{h} \
                 image; was the calibration made for another image size?"
            ));
        }
    }
    Ok(warnings)
}

/// Image files of a folder, sorted by name.
fn list_images(dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .with_context(|| format!("cannot read folder {}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.is_file() && matches!(laparo_core::io::extension(p).as_str(), "png" | "jpg" | "jpeg" | "tif" | "tiff")
        })
        .collect();
    v.sort();
    Ok(v)
}

fn run_rectify(a: RectifyArgs) -> anyhow::Result<()> {
    // Frames: one pair, or every left image of a folder with its same-named right image.
    let pairs: Vec<(PathBuf, PathBuf)> = if a.left.is_dir() {
        if !a.right.is_dir() {
            bail!("--left {} is a folder, so --right {} must be one too", a.left.display(), a.right.display());
        }
        let lefts = list_images(&a.left)?;
        if lefts.is_empty() {
            bail!("--left {}: no PNG/JPEG/TIFF image in this folder", a.left.display());
        }
        lefts
            .into_iter()
            .map(|l| {
                let r = a.right.join(l.file_name().expect("a file has a name"));
                if !r.is_file() {
                    bail!("{}: no right frame {} of the same name", l.display(), r.display());
                }
                Ok((l, r))
            })
            .collect::<anyhow::Result<_>>()?
    } else {
        vec![(a.left.clone(), a.right.clone())]
    };
    let batch = pairs.len() > 1 || a.left.is_dir();
    let inputs: Vec<&Path> = [a.left.as_path(), a.right.as_path()].into_iter().collect();
    laparo_core::atomic::refuse_overwrite(&a.out, &inputs, true).context("--out")?;
    if batch {
        for sub in ["left", "right"] {
            laparo_core::atomic::refuse_overwrite(&a.out.join(sub), &inputs, true).context("--out")?;
        }
    }
    let left = laparo_core::io::read_image(&pairs[0].0)?;
    let calib = need_calib(&a.calib, left.width, left.height)?;
    let label = a.calib.calib.clone().unwrap_or_default();
    for w in check_calibration_fits(&calib, left.width, left.height, &label)? {
        eprintln!("warning: {w}");
    }
    let opts = RectifyOptions { alpha: a.alpha, align_principal_points: !a.keep_offset };
    let rect = Rectification::new(&calib, opts).context("cannot rectify with this calibration")?;
    // The maps are built once and reused for every frame.
    let (tl, tr) = (rect.remap_table(Side::Left), rect.remap_table(Side::Right));
    std::fs::create_dir_all(&a.out).with_context(|| format!("cannot create {}", a.out.display()))?;
    let mask_png = |m: &Mask| m.map(|v| if v { 255u8 } else { 0 });
    let pb = if batch {
        let pb = indicatif::ProgressBar::new(pairs.len() as u64);
        pb.set_style(
            indicatif::ProgressStyle::with_template("rectify [{bar:40}] {pos}/{len} pairs ({per_sec}, eta {eta})")
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
                .progress_chars("=> "),
        );
        pb
    } else {
        indicatif::ProgressBar::hidden()
    };
    let (mut ml, mut mr) = (None, None);
    for (i, (lp, rp)) in pairs.iter().enumerate() {
        let l_img = if i == 0 { left.clone() } else { laparo_core::io::read_image(lp)? };
        let r_img = laparo_core::io::read_image(rp)?;
        for (p, img) in [(lp, &l_img), (rp, &r_img)] {
            if (img.width, img.height) != (calib.width, calib.height) {
                bail!(
                    "{}: image is {}x{} but the calibration is for {}x{}",
                    p.display(),
                    img.width,
                    img.height,
                    calib.width,
                    calib.height
                );
            }
        }
        let (l, mask_l) = laparo_core::remap::remap(&l_img, &tl, laparo_core::remap::Interp::Bilinear, 0)?;
        let (r, mask_r) = laparo_core::remap::remap(&r_img, &tr, laparo_core::remap::Interp::Bilinear, 0)?;
        if batch {
            let name = |p: &Path| p.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
            laparo_core::io::write_png(a.out.join("left").join(format!("{}.png", name(lp))), &l)?;
            laparo_core::io::write_png(a.out.join("right").join(format!("{}.png", name(rp))), &r)?;
        } else {
            laparo_core::io::write_png(a.out.join("left_rectified.png"), &l)?;
            laparo_core::io::write_png(a.out.join("right_rectified.png"), &r)?;
        }
        if i == 0 {
            ml = Some(mask_l);
            mr = Some(mask_r);
        }
        pb.inc(1);
    }
    pb.finish_and_clear();
    let (ml, mr) = (ml.expect("at least one pair"), mr.expect("at least one pair"));
    laparo_core::io::write_png(a.out.join("left_valid.png"), &mask_png(&ml))?;
    laparo_core::io::write_png(a.out.join("right_valid.png"), &mask_png(&mr))?;
    rect.rectified_calibration().write_json(a.out.join("calib_rectified.json"))?;
    let info = rect.info();
    let text = serde_json::to_string_pretty(&info)? + "\n";
    laparo_core::atomic::write_atomic(&a.out.join("rectification.json"), text.as_bytes())?;
    println!(
        "rectified {} pair(s) {}x{}: f' = {:.3} px, baseline = {:.4} mm, c' = ({:.2}, {:.2}) / ({:.2}, {:.2}), doffs = {:.3} px; \
         valid pixels {:.1} % (left), {:.1} % (right) -> {}",
        pairs.len(),
        info.width,
        info.height,
        info.focal_px,
        info.baseline_mm,
        rect.k1.cx,
        rect.k1.cy,
        rect.k2.cx,
        rect.k2.cy,
        info.doffs_px,
        100.0 * ml.count() as f64 / ml.n_pixels() as f64,
        100.0 * mr.count() as f64 / mr.n_pixels() as f64,
        a.out.display()
    );
    Ok(())
}

fn read_map(path: &Path, scale: f64, what: &str) -> anyhow::Result<Image<f64>> {
    if !(scale.is_finite() && scale > 0.0) {
        bail!("--{what}-scale must be > 0 (got {scale})");
    }
    let m = laparo_core::io::read_float_map(path)?;
    if m.channels != 1 {
        bail!("{}: {} channels, expected a single-channel disparity map", path.display(), m.channels);
    }
    Ok(if scale == 1.0 { m } else { m.map(|v| v / scale) })
}

fn save_map(path: &Path, img: &Image<f64>, lo: f64, hi: f64, cmap: Colormap, label: &str) -> anyhow::Result<()> {
    let c = with_colorbar(&colorize(img, lo, hi, cmap), lo, hi, cmap, label);
    laparo_core::io::write_png(path, &c)?;
    Ok(())
}

/// Display range of a map from the 1st–99th percentiles of `reference`, never empty.
fn range_of(reference: &Image<f64>) -> (f64, f64) {
    match percentile_range(reference, 1.0, 99.0) {
        Some((a, b)) if b > a => (a, b),
        Some((a, _)) => (a - 1.0, a + 1.0),
        None => (0.0, 1.0),
    }
}

fn run_eval(a: EvalArgs) -> anyhow::Result<()> {
    let calib_paths = a.calib.paths();
    let mut inputs: Vec<&Path> = vec![&a.pred, &a.gt];
    inputs.extend(a.mask.as_deref());
    inputs.extend(calib_paths.iter().map(PathBuf::as_path));
    laparo_core::atomic::refuse_overwrite_in(
        &a.out,
        &[
            "disparity_pred.png",
            "disparity_gt.png",
            "disparity_error.png",
            "depth_pred.png",
            "depth_gt.png",
            "depth_error.png",
            "metrics.json",
            "metrics.md",
        ],
        &inputs,
    )
    .context("--out")?;
    if let Some(Some(j)) = &a.json {
        laparo_core::atomic::refuse_overwrite_files(&[j], &inputs).context("--json")?;
    }
    let pred = read_map(&a.pred, a.pred_scale, "pred")?;
    let gt = read_map(&a.gt, a.gt_scale, "gt")?;
    if (pred.width, pred.height) != (gt.width, gt.height) {
        bail!(
            "size mismatch: prediction {} is {}x{}, ground truth {} is {}x{}",
            a.pred.display(),
            pred.width,
            pred.height,
            a.gt.display(),
            gt.width,
            gt.height
        );
    }
    let mask = match &a.mask {
        None => None,
        Some(p) => {
            let m = laparo_core::io::read_mask(p)?;
            if (m.width, m.height) != (gt.width, gt.height) {
                bail!(
                    "size mismatch: mask {} is {}x{}, ground truth {} is {}x{}",
                    p.display(),
                    m.width,
                    m.height,
                    a.gt.display(),
                    gt.width,
                    gt.height
                );
            }
            Some(m)
        }
    };
    let geometry = match a.calib.read_for_images(pred.width, pred.height)? {
        None => None,
        Some(c) => Some(DisparityGeometry::from_calibration(&c).context("calibration")?),
    };
    let (lo_mm, hi_mm) = (a.depth_min_mm.unwrap_or(a.depth_min_m * 1e3), a.depth_max_mm.unwrap_or(a.depth_max_m * 1e3));
    let range = if lo_mm <= 0.0 && hi_mm.is_infinite() { None } else { Some((lo_mm, hi_mm)) };
    let opts = EvalOptions { depth_range_mm: range, zero_is_invalid: a.zero_invalid, ..EvalOptions::default() };
    let (m, maps) = evaluate_maps(&pred, &gt, mask.as_ref(), geometry.as_ref(), &opts)
        .with_context(|| format!("evaluating {} against {}", a.pred.display(), a.gt.display()))?;
    std::fs::create_dir_all(&a.out).with_context(|| format!("cannot create {}", a.out.display()))?;
    // Maps: prediction and GT on the GT's display range; errors from 0.
    let valid_gt = Image {
        width: gt.width,
        height: gt.height,
        channels: 1,
        data: gt
            .data
            .iter()
            .enumerate()
            .map(|(i, &v)| {
                let ok = v.is_finite() && !(a.zero_invalid && v == 0.0) && mask.as_ref().is_none_or(|m| m.data[i]);
                if ok {
                    v
                } else {
                    f64::NAN
                }
            })
            .collect(),
    };
    let (lo, hi) = range_of(&valid_gt);
    save_map(&a.out.join("disparity_pred.png"), &pred, lo, hi, Colormap::Turbo, "disparity (px)")?;
    save_map(&a.out.join("disparity_gt.png"), &valid_gt, lo, hi, Colormap::Turbo, "GT disparity (px)")?;
    let ehi = range_of(&maps.disparity_error_px).1.max(3.0);
    save_map(&a.out.join("disparity_error.png"), &maps.disparity_error_px, 0.0, ehi, Colormap::Magma, "|d - d*| (px)")?;
    if let (Some(zp), Some(zg), Some(ze)) = (&maps.depth_pred_mm, &maps.depth_gt_mm, &maps.depth_error_mm) {
        let (zlo, zhi) = range_of(zg);
        save_map(&a.out.join("depth_pred.png"), zp, zlo, zhi, Colormap::Turbo, "depth (mm)")?;
        save_map(&a.out.join("depth_gt.png"), zg, zlo, zhi, Colormap::Turbo, "GT depth (mm)")?;
        let ezhi = range_of(ze).1.max(1e-3);
        save_map(&a.out.join("depth_error.png"), ze, 0.0, ezhi, Colormap::Magma, "|z - z*| (mm)")?;
    }
    let json = serde_json::json!({
        "pred": a.pred.display().to_string(),
        "gt": a.gt.display().to_string(),
        "calib": a.calib.calib,
        "mask": a.mask.as_ref().map(|p| p.display().to_string()),
        "metrics": m,
    });
    let text = serde_json::to_string_pretty(&json)? + "\n";
    laparo_core::atomic::write_atomic(&a.out.join("metrics.json"), text.as_bytes())?;
    let md = markdown_report(&a, &m);
    laparo_core::atomic::write_atomic(&a.out.join("metrics.md"), md.as_bytes())?;
    if !super::depth::emit_json(&a.json, &json)? {
        print!("{md}");
    }
    Ok(())
}

fn markdown_report(a: &EvalArgs, m: &StereoMetrics) -> String {
    let mut s = format!(
        "# Stereo evaluation\n\nprediction `{}`, ground truth `{}`{}; {} valid GT pixels ({} without a finite prediction).\n\n",
        a.pred.display(),
        a.gt.display(),
        a.calib.calib.as_ref().map(|c| format!(", calibration `{c}`")).unwrap_or_default(),
        m.n_valid,
        m.n_pred_missing
    );
    s.push_str(&m.markdown(&a.label));
    if let Some(d) = &m.depth {
        s.push_str(&format!(
            "\nDepth from disparity: f = {:.3} px, b = {:.4} mm, c_x^L − c_x^R = {:.3} px; {} pixels with valid GT depth; \
             predicted depth clamped to {}.\n",
            d.geometry.f_px,
            d.geometry.baseline_mm,
            d.geometry.offset_px(),
            d.n_valid,
            d.depth_range_mm.map(|(a, b)| format!("[{a}, {b}] mm")).unwrap_or_else(|| "nothing".into())
        ));
    }
    s.push_str("\nMaps: disparity_pred.png, disparity_gt.png, disparity_error.png");
    if m.depth.is_some() {
        s.push_str(", depth_pred.png, depth_gt.png, depth_error.png");
    }
    s.push('\n');
    s
}

fn run_disp2depth(a: Disp2DepthArgs) -> anyhow::Result<()> {
    let calib_paths = a.calib.paths();
    let mut inputs: Vec<&Path> = vec![&a.disp];
    inputs.extend(a.image.as_deref());
    inputs.extend(calib_paths.iter().map(PathBuf::as_path));
    let mut outputs: Vec<&Path> = vec![&a.out];
    outputs.extend(a.ply.as_deref());
    laparo_core::atomic::refuse_overwrite_files(&outputs, &inputs).context("--out / --ply")?;
    let disp = read_map(&a.disp, a.scale, "")?;
    let calib = need_calib(&a.calib, disp.width, disp.height)?;
    if (disp.width, disp.height) != (calib.width, calib.height) {
        bail!(
            "{}: disparity map is {}x{} but the calibration is for {}x{}",
            a.disp.display(),
            disp.width,
            disp.height,
            calib.width,
            calib.height
        );
    }
    let geo = DisparityGeometry::from_calibration(&calib)?;
    let depth = geo.depth_map(&disp);
    laparo_core::io::write_depth(&a.out, &depth)?;
    let n_valid = depth.data.iter().filter(|v| v.is_finite()).count();
    println!(
        "depth (mm) from d = f b / z + (c_x^L - c_x^R): f = {:.3} px, b = {:.4} mm, offset = {:.3} px; {} of {} pixels valid -> {}",
        geo.f_px,
        geo.baseline_mm,
        geo.offset_px(),
        n_valid,
        depth.data.len(),
        a.out.display()
    );
    if let Some(ply) = &a.ply {
        let colours = match &a.image {
            None => None,
            Some(p) => {
                let img = laparo_core::io::read_rgb8(p)?;
                if (img.width, img.height) != (disp.width, disp.height) {
                    bail!(
                        "{}: image is {}x{}, disparity {}x{}",
                        p.display(),
                        img.width,
                        img.height,
                        disp.width,
                        disp.height
                    );
                }
                Some(img)
            }
        };
        let cloud = geo.point_cloud(&disp);
        let mut buf = Vec::with_capacity(cloud.len() * 15 + 256);
        write!(
            buf,
            "ply\nformat binary_little_endian 1.0\ncomment laparo stereo disp2depth, mm, left camera frame\nelement vertex {}\n\
             property float x\nproperty float y\nproperty float z\n{}end_header\n",
            cloud.len(),
            if colours.is_some() { "property uchar red\nproperty uchar green\nproperty uchar blue\n" } else { "" }
        )?;
        for (x, y, p) in &cloud {
            for v in [p.x, p.y, p.z] {
                buf.extend_from_slice(&(v as f32).to_le_bytes());
            }
            if let Some(img) = &colours {
                buf.extend_from_slice(img.pixel(*x, *y));
            }
        }
        laparo_core::atomic::write_atomic(ply, &buf)?;
        println!("point cloud: {} points -> {}", cloud.len(), ply.display());
    }
    Ok(())
}
