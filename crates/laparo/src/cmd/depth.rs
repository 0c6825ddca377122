//! `laparo depth ...`: RoDEM evaluation of monocular depth estimation (thesis §3.2, App. C).
//!
//! * `manifest scaffold|validate`: build a dataset manifest from a folder layout, check it;
//! * `eval`: evaluate methods over a manifest (results.json, per-image CSV, tables, figures);
//! * `eval-pair`: one prediction against one GT, printing the metrics of depth_eval_ref.py;
//! * `perturb`, `reproject`: see `depth_tools.rs`.
use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use laparo_core::DepthUnit;
use laparo_depth::align::{Alignment, DepthRange, PredKind};
use laparo_depth::eval::{
    evaluate_files_checked, evaluate_manifest, evaluate_manifest_shard, merge_eval_shards, shard_file_name, EvalConfig,
    EvalShard, GtRangeCheck, ResizeFilter,
};
use laparo_depth::manifest::{scaffold, Manifest, ScaffoldOptions};
use laparo_depth::metrics::{InvalidPredPolicy, PairOptions, METRIC_NAMES};
use laparo_depth::report;
use std::path::PathBuf;

/// `--json[=FILE]` (the convention of every command): absent → `None`; `--json` → print the
/// JSON on stdout; `--json=FILE` → write it to FILE (atomically) and keep the human output.
/// The `=` is required so that `--json CALIB` never takes a positional input for the output.
pub type JsonOut = Option<Option<PathBuf>>;

/// Emit `value` as `--json [FILE]` asks. Returns true when it went to stdout (so the caller
/// prints nothing else there).
pub fn emit_json(json: &JsonOut, value: &serde_json::Value) -> Result<bool> {
    match json {
        None => Ok(false),
        Some(None) => {
            println!("{}", serde_json::to_string_pretty(value)?);
            Ok(true)
        }
        Some(Some(p)) => {
            laparo_core::atomic::write_atomic(p, (serde_json::to_string_pretty(value)? + "\n").as_bytes())?;
            Ok(false)
        }
    }
}

/// Print the GT range/unit warnings of a check on stderr.
fn print_gt_warnings(check: &GtRangeCheck, what: &str, flags: &str) {
    for w in check.warnings(what, flags) {
        eprintln!("warning: {w}");
    }
}

/// An alignment whose fit is undefined (s-alignment of a prediction whose median over the valid
/// pixels is 0, e.g. an all-zero disparity: scale = NaN, JSON `null`) is reported on stderr
/// instead of silently (issue 10); the metrics themselves stay those of the reference.
fn print_fit_warnings(r: &laparo_depth::metrics::PairMetrics, pred: &std::path::Path) {
    for al in Alignment::ALL {
        if let Some(m) = r.get(al) {
            if !m.scale.is_finite() || !m.shift.is_finite() {
                eprintln!(
                    "warning: {}: the '{}' alignment is undefined (scale {}, shift {}): the prediction's median over \
                     the valid pixels is 0 (an all-zero prediction?), so its aligned depth is the far end of the range",
                    pred.display(),
                    al.key(),
                    m.scale,
                    m.shift
                );
            }
        }
    }
}

#[derive(Subcommand)]
pub enum DepthCmd {
    /// Scaffold a dataset manifest from a folder layout, or validate one.
    #[command(subcommand)]
    Manifest(ManifestCmd),
    /// Evaluate methods over a manifest: accuracy (Abs Rel, ..., δ_t) and robustness (mCE, mRR).
    Eval(EvalArgs),
    /// Evaluate one prediction against one ground-truth depth map.
    EvalPair(EvalPairArgs),
    /// Seeded synthetic perturbations (smoke, blood, light, blur, lens dirt) of clean RGB images.
    Perturb(super::depth_tools::PerturbArgs),
    /// Depth-sensor depth to laparoscope-aligned GT depth (thesis §3.2.6).
    Reproject(super::depth_tools::ReprojectArgs),
}

#[derive(Subcommand)]
pub enum ManifestCmd {
    /// Write a manifest from `<root>/<scene>/<perturbation>/<level>/{rgb,depth,mask}/` and
    /// `<root>/predictions/<method>/<scene>/<perturbation>/<level>/` (see the crate README).
    Scaffold(ScaffoldArgs),
    /// Check a manifest: structure, and that every listed file exists (all problems at once).
    Validate(ValidateArgs),
}

#[derive(Args)]
pub struct ScaffoldArgs {
    /// Dataset root folder.
    #[arg(long)]
    pub root: PathBuf,
    /// Unit of the GT depth files (m or mm).
    #[arg(long)]
    pub gt_unit: DepthUnit,
    /// Methods whose predictions are depth (the others are taken as disparity).
    #[arg(long, value_delimiter = ',')]
    pub depth_methods: Vec<String>,
    /// Predictions folder, relative to the root.
    #[arg(long, default_value = "predictions")]
    pub predictions: String,
    /// Output manifest (.toml or .json); default `<root>/manifest.toml`.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Near clamp (m) of aligned predicted depth written to the manifest (default 0.01).
    #[arg(long)]
    pub depth_min_m: Option<f64>,
    /// Far clamp (m) of aligned predicted depth written to the manifest (default 0.5).
    #[arg(long)]
    pub depth_max_m: Option<f64>,
    /// Overwrite an existing manifest.
    #[arg(long)]
    pub force: bool,
}

#[derive(Args)]
pub struct ValidateArgs {
    /// Manifest file (.toml or .json).
    pub manifest: PathBuf,
    /// Only check the predictions of these methods.
    #[arg(long, value_delimiter = ',')]
    pub methods: Vec<String>,
    /// Print the report as JSON on stdout, or write it to FILE.
    #[arg(long, value_name = "FILE", num_args = 0..=1, require_equals = true)]
    pub json: Option<Option<PathBuf>>,
}

#[derive(Args)]
pub struct EvalArgs {
    /// Manifest file (.toml or .json).
    #[arg(long)]
    pub manifest: PathBuf,
    /// Methods to evaluate (default: all in the manifest).
    #[arg(long, value_delimiter = ',')]
    pub methods: Vec<String>,
    /// Alignment: none, s, st or all (comma-separated list allowed).
    #[arg(long, default_value = "all")]
    pub alignment: String,
    /// Baseline method of mCE (eq. 3.3); default: the manifest's, else the first method.
    #[arg(long)]
    pub baseline: Option<String>,
    /// Output folder.
    #[arg(long)]
    pub out: PathBuf,
    /// Invalid predictions on valid GT pixels: far (disparity 0), exclude, or error.
    #[arg(long, default_value = "far")]
    pub invalid_pred: InvalidPredPolicy,
    /// Frames (ids) drawn as colour error maps (default: the manifest's error_map_frames).
    #[arg(long, value_delimiter = ',')]
    pub error_maps: Vec<String>,
    /// Alignment of the error maps.
    #[arg(long, default_value = "st")]
    pub error_map_alignment: Alignment,
    /// Skip radar charts and error maps.
    #[arg(long)]
    pub no_figures: bool,
    /// Near clamp (m) of aligned predicted depth (default: the manifest's depth_min_m, else 0.01).
    #[arg(long)]
    pub depth_min_m: Option<f64>,
    /// Far clamp (m) of aligned predicted depth (default: the manifest's depth_max_m, else 0.5).
    #[arg(long)]
    pub depth_max_m: Option<f64>,
    /// Evaluate only shard I of N (frames whose manifest position is I mod N) and write
    /// `<out>/eval-shard-I-of-N.json` (no report). Merge the N shards with `--merge-shards N`.
    #[arg(long, value_name = "I/N", conflicts_with = "merge_shards")]
    pub shard: Option<laparo_core::shard::Shard>,
    /// Merge `<out>/eval-shard-{0..N-1}-of-N.json` (made with the same options) into the report
    /// of one unsharded run (byte-identical files), then delete the shard files.
    #[arg(long, value_name = "N")]
    pub merge_shards: Option<usize>,
}

#[derive(Args)]
pub struct EvalPairArgs {
    /// Prediction (npy, npz, pfm, tif, png16).
    #[arg(long)]
    pub pred: PathBuf,
    /// Ground-truth depth (npy, npz, pfm, tif, png16); 0 / non-finite = invalid.
    #[arg(long)]
    pub gt: PathBuf,
    /// What the prediction holds.
    #[arg(long, default_value = "disparity")]
    pub pred_kind: PredKind,
    /// Unit of the GT values (mm, the default of every laparo command, or m).
    #[arg(long, default_value = "mm")]
    pub gt_unit: DepthUnit,
    /// ROI mask (PNG/JPEG/TIFF: channel 0 non-zero; npy/npz/PFM/EXR: finite and non-zero).
    #[arg(long)]
    pub mask: Option<PathBuf>,
    /// Alignments: none, s, st or all.
    #[arg(long, default_value = "all")]
    pub alignment: String,
    /// Near clamp of aligned depth (m).
    #[arg(long, default_value_t = 0.01, alias = "depth-min")]
    pub depth_min_m: f64,
    /// Far clamp of aligned depth (m).
    #[arg(long, default_value_t = 0.5, alias = "depth-max")]
    pub depth_max_m: f64,
    /// Invalid predictions on valid GT pixels: far (disparity 0), exclude, or error.
    #[arg(long, default_value = "far")]
    pub invalid_pred: InvalidPredPolicy,
    /// Resize a prediction whose size differs from the GT's (network resolution): bilinear or
    /// nearest, pixel centres aligned. Without it a size mismatch is an error.
    #[arg(long, value_name = "FILTER")]
    pub resize_pred: Option<ResizeFilter>,
    /// Print one JSON object (keys of depth_eval_ref.py) on stdout, or write it to FILE.
    #[arg(long, value_name = "FILE", num_args = 0..=1, require_equals = true)]
    pub json: Option<Option<PathBuf>>,
}

pub fn run(c: DepthCmd) -> Result<()> {
    match c {
        DepthCmd::Manifest(ManifestCmd::Scaffold(a)) => run_scaffold(a),
        DepthCmd::Manifest(ManifestCmd::Validate(a)) => run_validate(a),
        DepthCmd::Eval(a) => run_eval(a),
        DepthCmd::EvalPair(a) => run_eval_pair(a),
        DepthCmd::Perturb(a) => super::depth_tools::perturb(a),
        DepthCmd::Reproject(a) => super::depth_tools::reproject(a),
    }
}

fn run_scaffold(a: ScaffoldArgs) -> Result<()> {
    let out = a.out.clone().unwrap_or_else(|| a.root.join("manifest.toml"));
    if out.exists() && !a.force {
        bail!("{} exists (use --force to overwrite)", out.display());
    }
    let opts = ScaffoldOptions { gt_unit: a.gt_unit, depth_methods: a.depth_methods, predictions_dir: a.predictions };
    let mut m = scaffold(&a.root, &opts)?;
    if let Some(v) = a.depth_min_m {
        m.depth_min_m = Some(v);
    }
    if let Some(v) = a.depth_max_m {
        m.depth_max_m = Some(v);
    }
    m.range().context("--depth-min-m/--depth-max-m")?;
    // Paths in the manifest are relative to the root; keep them valid from the output folder.
    let out_dir = out.parent().map(|p| p.to_path_buf()).unwrap_or_default();
    let root_abs = std::fs::canonicalize(&a.root).with_context(|| a.root.display().to_string())?;
    let out_abs = if out_dir.as_os_str().is_empty() {
        std::env::current_dir()?
    } else {
        std::fs::canonicalize(&out_dir).unwrap_or(out_dir.clone())
    };
    if root_abs != out_abs {
        for f in &mut m.frames {
            f.rgb = root_abs.join(&f.rgb);
            f.gt = root_abs.join(&f.gt);
            f.mask = f.mask.as_ref().map(|p| root_abs.join(p));
        }
        for me in &mut m.methods {
            me.predictions = root_abs.join(&me.predictions).display().to_string();
        }
    }
    m.write(&out)?;
    let m = Manifest::read(&out)?;
    let rep = m.validate(None);
    eprintln!(
        "wrote {}: {} frames, {} methods, {} sequences",
        out.display(),
        m.frames.len(),
        m.methods.len(),
        m.sequences.len()
    );
    print_report(&rep);
    if !rep.ok() {
        eprintln!("edit the manifest, then run: laparo depth manifest validate {}", out.display());
    }
    Ok(())
}

fn print_report(rep: &laparo_depth::manifest::ValidationReport) {
    for w in &rep.warnings {
        eprintln!("warning: {w}");
    }
    for p in &rep.problems {
        eprintln!("problem: {p}");
    }
    eprintln!(
        "{} frames, {} methods, {} files checked: {} problem(s), {} warning(s)",
        rep.n_frames,
        rep.n_methods,
        rep.n_files_checked,
        rep.problems.len(),
        rep.warnings.len()
    );
}

fn run_validate(a: ValidateArgs) -> Result<()> {
    let m = Manifest::read(&a.manifest)?;
    let rep = m.validate(if a.methods.is_empty() { None } else { Some(&a.methods) });
    if !emit_json(&a.json, &serde_json::to_value(&rep)?)? {
        print_report(&rep);
    }
    if !rep.ok() {
        bail!("{}: {} problem(s)", a.manifest.display(), rep.problems.len());
    }
    Ok(())
}

fn run_eval(a: EvalArgs) -> Result<()> {
    let m = Manifest::read(&a.manifest)?;
    let alignments = Alignment::parse_list(&a.alignment)?;
    let methods: Vec<String> =
        if a.methods.is_empty() { m.methods.iter().map(|x| x.name.clone()).collect() } else { a.methods.clone() };
    let baseline = a
        .baseline
        .clone()
        .or_else(|| m.baseline.clone())
        .or_else(|| methods.first().cloned())
        .context("no method to evaluate")?;
    if !methods.contains(&baseline) {
        bail!("baseline '{baseline}' is not among the evaluated methods ({})", methods.join(", "));
    }
    let error_maps = if a.error_maps.is_empty() { m.error_map_frames.clone() } else { a.error_maps.clone() };
    if let Some(bad) = error_maps.iter().find(|id| !m.frames.iter().any(|f| &f.id == *id)) {
        bail!("--error-maps: '{bad}' is not a frame id of {}", a.manifest.display());
    }
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    if a.shard.is_none() {
        report::remove_stale_results(&a.out)?;
        laparo_core::atomic::remove_stale_temps(&a.out)?;
    }
    let range = match (a.depth_min_m, a.depth_max_m) {
        (None, None) => None,
        (lo, hi) => {
            let d = m.range().unwrap_or_default();
            Some(DepthRange::new(lo.unwrap_or(d.min_m), hi.unwrap_or(d.max_m)).context("--depth-min-m/--depth-max-m")?)
        }
    };
    let cfg = EvalConfig { methods, alignments, invalid_pred: a.invalid_pred, range };
    let pb = ProgressBar::new(m.frames.len() as u64);
    pb.set_style(
        ProgressStyle::with_template("{spinner} evaluating [{bar:40}] {pos}/{len} frames ({per_sec}, eta {eta})")
            .unwrap()
            .progress_chars("=> "),
    );
    let t0 = std::time::Instant::now();
    if let Some(shard) = a.shard {
        pb.set_length(m.frames.iter().enumerate().filter(|(i, _)| shard.contains(*i)).count() as u64);
        let r = evaluate_manifest_shard(&m, &cfg, shard, &|n| pb.set_position(n as u64));
        pb.finish_and_clear();
        let r = r?;
        let p = a.out.join(shard_file_name(shard));
        laparo_core::atomic::write_atomic(&p, r.to_json_string().as_bytes())?;
        eprintln!(
            "shard {shard}: {} of {} frames x {} methods in {:.1} s -> {} (merge: laparo depth eval <same options> --merge-shards {})",
            r.frames.len(),
            r.n_frames,
            r.methods.len(),
            t0.elapsed().as_secs_f64(),
            p.display(),
            shard.count
        );
        return Ok(());
    }
    let (out, shard_files) = match a.merge_shards {
        Some(n) => {
            pb.finish_and_clear();
            if n == 0 {
                bail!("--merge-shards: N must be >= 1");
            }
            let mut shards = Vec::with_capacity(n);
            let mut files = Vec::with_capacity(n);
            for i in 0..n {
                let p = a.out.join(shard_file_name(laparo_core::shard::Shard { index: i, count: n }));
                let text = std::fs::read_to_string(&p)
                    .with_context(|| format!("reading shard {i}/{n}: {} (run --shard {i}/{n} first)", p.display()))?;
                shards.push(EvalShard::from_json_str(&text, &p.display().to_string())?);
                files.push(p);
            }
            (merge_eval_shards(&m, &cfg, &shards)?, files)
        }
        None => {
            let out = evaluate_manifest(&m, &cfg, &|n| pb.set_position(n as u64));
            pb.finish_and_clear();
            (out?, Vec::new())
        }
    };
    print_gt_warnings(
        &GtRangeCheck::merge_all(&out.gt_checks),
        &format!("{} ({} frames)", a.manifest.display(), out.gt_checks.len()),
        "depth_min_m/depth_max_m in the manifest or --depth-min-m/--depth-max-m",
    );
    let summary = report::summarize(&out, &baseline)?;
    let mut written = Vec::new();
    if !a.no_figures {
        written.extend(report::write_figures(&a.out, &m, &out, &summary, &error_maps, a.error_map_alignment)?);
    }
    written.extend(report::write_reports(&a.out, &out, &summary)?);
    for f in &shard_files {
        std::fs::remove_file(f).with_context(|| format!("removing merged shard {}", f.display()))?;
    }
    print!("{}", report::terminal_summary(&summary));
    eprintln!(
        "{} frames x {} methods in {:.1} s; wrote {} files under {}",
        out.frames.len(),
        out.methods.len(),
        t0.elapsed().as_secs_f64(),
        written.len(),
        a.out.display()
    );
    Ok(())
}

fn run_eval_pair(a: EvalPairArgs) -> Result<()> {
    let opts = PairOptions {
        alignments: Alignment::parse_list(&a.alignment)?,
        range: DepthRange::new(a.depth_min_m, a.depth_max_m)?,
        invalid_pred: a.invalid_pred,
    };
    let (r, check) =
        evaluate_files_checked(&a.pred, a.pred_kind, &a.gt, a.gt_unit, a.mask.as_deref(), &opts, a.resize_pred)?;
    print_gt_warnings(&check, &format!("{} (--gt-unit {})", a.gt.display(), a.gt_unit), "--depth-min-m/--depth-max-m");
    print_fit_warnings(&r, &a.pred);
    if emit_json(&a.json, &serde_json::to_value(&r)?)? {
        return Ok(());
    }
    println!("valid pixels: {} (invalid predictions among them: {})", r.n_valid, r.n_invalid_pred);
    print!("{:12}", "alignment");
    for n in METRIC_NAMES {
        print!(" {n:>11}");
    }
    println!();
    for al in Alignment::ALL {
        if let Some(m) = r.get(al) {
            print!("{:12}", al.key());
            for v in m.values() {
                print!(" {v:>11.5}");
            }
            println!();
        }
    }
    Ok(())
}
