//! `laparo cats stats CALIB...`: rotations of each camera from the ideal rectified stereo frame,
//! principal-point offsets, baselines and lens-distortion displacement of real stereo calibrations
//! (thesis §3.3.4, Table 3.6), with a CATS configuration fitted to them.
use anyhow::{bail, Context};
use clap::Args;
use laparo_core::calib::StereoCalibration;
use laparo_stereo::{
    calib_stats, fitted_cats_config, offsets_markdown, per_file_markdown, summarize, table_3_6_markdown, CalibStats,
};
use serde_json::json;
use std::path::{Path, PathBuf};

/// Arguments of `laparo cats stats`.
#[derive(Args, Debug, Clone)]
pub struct StatsArgs {
    /// Stereo calibration files: OpenCV FileStorage YAML (SCARED `M1 D1 M2 D2 R T`, EndoVis
    /// `cam1 dis1 cam2 dis2 rot trans`, ...), laparo JSON, EndoVis 2017 `camera_calibration.txt`,
    /// Middlebury `calib.txt`, or a ROS camera_info pair `LEFT.yaml,RIGHT.yaml`. OpenCV's two-file `stereo_calib`
    /// layout is given as `INTRINSICS,EXTRINSICS`, or by either file when the other one sits
    /// next to it with "intrinsics" ↔ "extrinsics" swapped in its name.
    #[arg(required = true, value_name = "CALIB")]
    pub calib: Vec<String>,
    /// Print one JSON object (per-file results and summary statistics) instead of tables, or
    /// write it to FILE.
    #[arg(long, value_name = "FILE", num_args = 0..=1, require_equals = true)]
    pub json: Option<Option<PathBuf>>,
    /// Write a CATS configuration (TOML) fitted to the statistics.
    #[arg(long, value_name = "TOML")]
    pub config_out: Option<PathBuf>,
    /// Image width (px) for calibrations that do not store their image size (SCARED: 1280); only
    /// the distortion displacement uses it (optional: without it a nominal size centred on the
    /// principal point is used and a warning says so).
    #[arg(long, requires = "height")]
    pub width: Option<usize>,
    /// Image height (px) for calibrations that do not store their image size (SCARED: 1024).
    #[arg(long, requires = "width")]
    pub height: Option<usize>,
}

/// The sibling of a `stereo_calib` file with `from` replaced by `to` in its file name, if it exists.
fn sibling(path: &Path, from: &str, to: &str) -> Option<PathBuf> {
    let name = path.file_name()?.to_string_lossy().into_owned();
    if !name.contains(from) {
        return None;
    }
    let p = path.with_file_name(name.replace(from, to));
    p.exists().then_some(p)
}

/// Resolve a CALIB argument to one file or an (intrinsics, extrinsics) pair.
fn resolve(spec: &str) -> (PathBuf, Option<PathBuf>) {
    if let Some((a, b)) = spec.split_once(',') {
        return (PathBuf::from(a), Some(PathBuf::from(b)));
    }
    let p = PathBuf::from(spec);
    if let Some(e) = sibling(&p, "intrinsics", "extrinsics") {
        return (p, Some(e));
    }
    if let Some(i) = sibling(&p, "extrinsics", "intrinsics") {
        return (i, Some(p));
    }
    (p, None)
}

/// Read a calibration given as `FILE` or `INTRINSICS,EXTRINSICS` (see [`StatsArgs::calib`]);
/// `size` is used only when the file does not state the image size. Returns a display label,
/// the calibration and whether its image size was assumed (no size in the file nor given).
pub fn read_calibration(spec: &str, size: Option<(usize, usize)>) -> anyhow::Result<(String, StereoCalibration, bool)> {
    let (a, b) = resolve(spec);
    let label = match &b {
        Some(b) => format!("{} + {}", a.display(), b.display()),
        None => a.display().to_string(),
    };
    for p in std::iter::once(&a).chain(b.iter()) {
        if !p.exists() {
            bail!("{}: calibration file not found", p.display());
        }
    }
    let files: Vec<&Path> = std::iter::once(a.as_path()).chain(b.as_deref()).collect();
    let c = match laparo_core::io::read_stereo_calibration(&files, size) {
        Ok(c) => c,
        // The angles, offsets and baseline need no image size: a file without one (SCARED) is
        // read with a nominal size centred on the left principal point, used only for the
        // distortion displacement (flagged by `size_assumed`).
        Err(e) if size.is_none() && e.to_string().contains("no image size") => {
            let mut c = laparo_core::io::read_stereo_calibration(&files, Some((1, 1)))
                .with_context(|| format!("cannot read stereo calibration {label}"))?;
            let side = |v: f64| (2.0 * v + 1.0).round().clamp(1.0, 65_536.0) as usize;
            let (w, h) = (side(c.left.cx), side(c.left.cy));
            laparo_core::io::check_image_size(w as u64, h as u64, &label)?;
            c.width = w;
            c.height = h;
            for k in [&mut c.left, &mut c.right] {
                k.width = w;
                k.height = h;
            }
            return Ok((label, c, true));
        }
        Err(e) => return Err(anyhow::Error::new(e)).context(format!("cannot read stereo calibration {label}")),
    };
    Ok((label, c, false))
}

/// Read every calibration of a `cats stats` command line, merging two-file layouts that were
/// given as two arguments.
fn read_all(a: &StatsArgs) -> anyhow::Result<Vec<(String, StereoCalibration, bool)>> {
    let size = a.width.zip(a.height);
    let mut seen: Vec<(PathBuf, Option<PathBuf>)> = Vec::new();
    let mut out = Vec::new();
    for spec in &a.calib {
        let r = resolve(spec);
        if seen.contains(&r) {
            continue;
        }
        seen.push(r);
        out.push(read_calibration(spec, size)?);
    }
    Ok(out)
}

/// Run `laparo cats stats`.
pub fn run_stats(a: StatsArgs) -> anyhow::Result<()> {
    if let Some(out) = &a.config_out {
        let files: Vec<PathBuf> = a
            .calib
            .iter()
            .flat_map(|spec| {
                let (x, y) = resolve(spec);
                std::iter::once(x).chain(y)
            })
            .collect();
        let refs: Vec<&Path> = files.iter().map(PathBuf::as_path).collect();
        laparo_core::atomic::refuse_overwrite(out, &refs, false).context("--config-out")?;
    }
    let calibs = read_all(&a)?;
    let mut rows: Vec<(String, CalibStats)> = Vec::new();
    for (label, c, assumed) in &calibs {
        let mut s = calib_stats(c).with_context(|| format!("{label}: invalid stereo calibration"))?;
        if *assumed {
            s.warnings.push(format!(
                "no image size in the file nor --width/--height: the distortion displacement is over a nominal \
                 {}x{} px image centred on the left principal point (angles, offsets and baseline do not depend on it)",
                c.width, c.height
            ));
        }
        rows.push((label.clone(), s));
    }
    let stats: Vec<CalibStats> = rows.iter().map(|(_, s)| s.clone()).collect();
    let summary = summarize(&stats);
    let label = format!("all ({} calibrations)", summary.n);
    if let Some(path) = &a.config_out {
        let names: Vec<String> = rows
            .iter()
            .map(|(l, _)| {
                Path::new(l.split(" + ").next().unwrap_or(l))
                    .file_name()
                    .map(|n| n.to_string_lossy().into_owned())
                    .unwrap_or_else(|| l.clone())
            })
            .collect();
        let cfg = fitted_cats_config(&summary, &format!("laparo cats stats over {}", names.join(", ")));
        let text = format!(
            "# CATS configuration fitted by `laparo cats stats` to {} stereo calibration(s):\n\
             # per-camera Euler angles (deg, R = Rz(z) Ry(y) Rx(x), rotation from the ideal rectified frame)\n\
             # ~ N(mean, population std); dx_right_px (added to every disparity, = c_x^L - c_x^R) ~ U(min(offsets, 0), max(offsets, 0)).\n{}",
            summary.n,
            cfg.to_toml_string()
        );
        laparo_core::atomic::write_atomic(path, text.as_bytes())
            .with_context(|| format!("cannot write CATS config {}", path.display()))?;
    }
    let warnings: Vec<String> =
        rows.iter().flat_map(|(l, s)| s.warnings.iter().map(move |w| format!("{l}: {w}"))).collect();
    if a.json.is_some() {
        let files: Vec<serde_json::Value> = rows
            .iter()
            .map(|(l, s)| {
                let mut v = serde_json::to_value(s).expect("CalibStats serialises");
                v["file"] = json!(l);
                v
            })
            .collect();
        let out = json!({
            "convention": "R_c maps ideal-rectified-frame coordinates to camera c (X_c = R_c X_s); \
                           Euler [x, y, z] deg with R = Rz(z) Ry(y) Rx(x); ideal frame: X along the baseline, \
                           minimal rotation from the left camera; principal_point_offset_px = c_x^L - c_x^R",
            "files": files,
            "summary": summary,
            "config_out": a.config_out.as_ref().map(|p| p.display().to_string()),
            "warnings": warnings,
        });
        if !super::depth::emit_json(&a.json, &out)? {
            print_tables(&rows, &label, &summary, a.config_out.as_deref(), &warnings);
        }
    } else {
        print_tables(&rows, &label, &summary, a.config_out.as_deref(), &warnings);
    }
    Ok(())
}

fn print_tables(
    rows: &[(String, CalibStats)],
    label: &str,
    summary: &laparo_stereo::StatsSummary,
    config_out: Option<&Path>,
    warnings: &[String],
) {
    {
        println!("Per calibration (Euler angles [x, y, z] in degrees, R = Rz(z) Ry(y) Rx(x), rotation from the ideal rectified frame):\n");
        println!("{}", per_file_markdown(rows));
        println!("Table 3.6 analogue (mean, population σ; degrees):\n");
        println!("{}", table_3_6_markdown(&[(label.to_string(), summary.clone())]));
        println!("Principal-point offsets, baselines, lens distortion:\n");
        println!("{}", offsets_markdown(&[(label.to_string(), summary.clone())]));
        if let Some(p) = config_out {
            println!("wrote CATS config {}", p.display());
        }
        for w in warnings {
            eprintln!("warning: {w}");
        }
    }
}
