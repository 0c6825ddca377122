//! `laparo cats ...`: CATS camera augmentation of stereo datasets (thesis §3.3.3–3.3.5).
//!
//! - `augment`: a whole dataset (SceneFlow, Middlebury, generic layouts), parallel, resumable,
//!   deterministic per (seed, sample) whatever the thread count.
//! - `apply`: re-apply a sidecar or hand-written parameters to one sample.
//! - `config`: print / write the thesis configuration (Table 3.6 row, Δx_right ~ U(−100, 0)).
//! - `stats`: calibration statistics (see `cats_stats.rs`).
use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use laparo_core::io;
use laparo_stereo::CatsConfig;
use laparo_stereo::Layout;
use laparo_stereo::{augment_stereo, GtRule};
use nalgebra::Matrix3;
use rayon::prelude::*;
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::Instant;

#[derive(Subcommand)]
pub enum CatsCmd {
    /// Augment a whole stereo dataset (PNG + PFM in; PNG + PFM + JSON sidecar out).
    Augment(AugmentArgs),
    /// Re-apply augmentation parameters (sidecar or hand-written JSON) to one sample.
    Apply(ApplyArgs),
    /// Print or write the thesis CATS configuration (TOML).
    Config(ConfigArgs),
    /// Statistics of real stereo calibrations (Table 3.6) and a fitted CATS config.
    Stats(super::cats_stats::StatsArgs),
}

/// Arguments of `laparo cats augment`.
#[derive(Args)]
pub struct AugmentArgs {
    /// Dataset root.
    #[arg(long)]
    pub input: PathBuf,
    /// Dataset layout: sceneflow, middlebury or generic (left/, right/, disp/).
    #[arg(long)]
    pub layout: Layout,
    /// Output root (mirrors the input tree; sidecars `<id>.cats.json`).
    #[arg(long)]
    pub out: PathBuf,
    /// CATS configuration (TOML); the thesis' (Table 3.6 SCARED+StMIS) when absent.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Random seed; each sample's generator is seeded from (seed, sample id).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Disparity GT rule: exact (correspondences through both cameras) or thesis (§3.3.5).
    #[arg(long, default_value = "exact")]
    pub gt_rule: GtRule,
    /// Process at most this many samples (after skipping finished ones).
    #[arg(long)]
    pub limit: Option<usize>,
    /// Redo samples that already have a sidecar. Without it an interrupted run resumes (samples
    /// written with the same seed, GT rule, layout and configuration are kept) and a run whose
    /// parameters differ from those recorded in the sidecars is refused.
    #[arg(long, alias = "overwrite")]
    pub force: bool,
    /// Process only shard I of N (samples whose position in the sorted sample list is I mod N):
    /// N processes with 0/N .. N-1/N (same --out, or merged with `rsync -a`) write exactly the
    /// files of one unsharded run.
    #[arg(long, value_name = "I/N")]
    pub shard: Option<laparo_core::shard::Shard>,
}

/// Arguments of `laparo cats apply`.
#[derive(Args)]
pub struct ApplyArgs {
    /// Parameters: a `cats augment` sidecar or hand-written JSON (see README).
    #[arg(long)]
    pub params: PathBuf,
    /// Left image.
    #[arg(long)]
    pub left: PathBuf,
    /// Right image.
    #[arg(long)]
    pub right: PathBuf,
    /// Left disparity GT (PFM, npy, npz, TIFF; x_R = x − d).
    #[arg(long)]
    pub disp: Option<PathBuf>,
    /// Right disparity GT (x_L = x + d).
    #[arg(long)]
    pub disp_right: Option<PathBuf>,
    /// Output folder.
    #[arg(long)]
    pub out: PathBuf,
    /// Disparity GT rule.
    #[arg(long, default_value = "exact")]
    pub gt_rule: GtRule,
}

/// Arguments of `laparo cats config`.
#[derive(Args)]
pub struct ConfigArgs {
    /// Table 3.6 row: SCARED, StereoMIS, RIS2017 or SCARED+StMIS.
    #[arg(long, default_value = "SCARED+StMIS")]
    pub row: String,
    /// Write here instead of printing.
    #[arg(long)]
    pub out: Option<PathBuf>,
}

pub fn run(c: CatsCmd) -> Result<()> {
    match c {
        CatsCmd::Augment(a) => run_augment(a),
        CatsCmd::Apply(a) => run_apply(a),
        CatsCmd::Config(a) => run_config(a),
        CatsCmd::Stats(a) => super::cats_stats::run_stats(a),
    }
}

fn load_config(path: &Option<PathBuf>) -> Result<CatsConfig> {
    match path {
        Some(p) => {
            let text = std::fs::read_to_string(p).with_context(|| format!("reading {}", p.display()))?;
            CatsConfig::from_toml_str(&text).with_context(|| format!("{}", p.display()))
        }
        None => Ok(CatsConfig::thesis("SCARED+StMIS")?),
    }
}

fn run_augment(a: AugmentArgs) -> Result<()> {
    laparo_core::atomic::refuse_overwrite(&a.out, &[&a.input], true).context("--out")?;
    let config = load_config(&a.config)?;
    let samples = laparo_stereo::discover(&a.input, a.layout)?;
    let shard = a.shard.unwrap_or(laparo_core::shard::Shard::ALL);
    let samples = shard.select(samples);
    let total = samples.len();
    // Concurrent shards may share --out: only an unsharded run removes other processes' temporaries.
    if a.out.is_dir() && shard.count == 1 {
        let n = laparo_core::atomic::remove_stale_temps(&a.out)?;
        if n > 0 {
            eprintln!("removed {n} temporary file(s) left by an interrupted run in {}", a.out.display());
        }
    }
    let hash = laparo_stereo::run_params_hash(&config, a.seed, a.gt_rule, a.layout);
    let states: Vec<laparo_stereo::ResumeState> =
        samples.iter().map(|f| laparo_stereo::resume_state(f, &a.input, &a.out, &hash)).collect();
    let stale: Vec<&str> = samples
        .iter()
        .zip(&states)
        .filter(|(_, s)| **s == laparo_stereo::ResumeState::Stale)
        .map(|(f, _)| f.id.as_str())
        .collect();
    if !stale.is_empty() && !a.force {
        bail!(
            "{}: {} sample(s) (e.g. {}) were augmented with another seed, GT rule or configuration \
             (or by an older laparo); re-run with --force to redo them, or choose another --out",
            a.out.display(),
            stale.len(),
            stale[..stale.len().min(3)].join(", ")
        );
    }
    let todo: Vec<_> = samples
        .into_iter()
        .zip(&states)
        .filter(|(_, s)| a.force || **s != laparo_stereo::ResumeState::Done)
        .map(|(f, _)| f)
        .take(a.limit.unwrap_or(usize::MAX))
        .collect();
    eprintln!(
        "{total} samples{} in {}, {} to do ({} already finished); seed {}, GT rule {:?}, {} threads",
        if shard.count > 1 { format!(" of shard {shard}") } else { String::new() },
        a.input.display(),
        todo.len(),
        total - todo.len().min(total),
        a.seed,
        a.gt_rule,
        rayon::current_num_threads()
    );
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let pb = ProgressBar::new(todo.len() as u64);
    pb.set_style(
        ProgressStyle::with_template("{elapsed_precise} [{bar:40}] {pos}/{len} {per_sec} eta {eta} {msg}")
            .expect("valid template")
            .progress_chars("=> "),
    );
    let failures = Mutex::new(Vec::new());
    let empty = Mutex::new(Vec::new());
    let done = AtomicUsize::new(0);
    let t0 = Instant::now();
    todo.par_iter().for_each(|f| {
        match laparo_stereo::augment_sample(f, &a.input, &a.out, a.layout, &config, a.seed, a.gt_rule) {
            Ok(sc) => {
                done.fetch_add(1, Ordering::Relaxed);
                if sc.stats.valid_fraction_left == 0.0 || sc.stats.valid_fraction_right == 0.0 {
                    empty.lock().expect("not poisoned").push(f.id.clone());
                }
            }
            Err(e) => failures.lock().expect("not poisoned").push(format!("{}: {e}", f.id)),
        }
        pb.inc(1);
    });
    pb.finish_and_clear();
    let failures = failures.into_inner().expect("not poisoned");
    let empty = empty.into_inner().expect("not poisoned");
    if !empty.is_empty() {
        eprintln!(
            "warning: {} sample(s) have no valid pixel in one view (e.g. {}): the sampled camera looks away \
             from the image; check the configuration",
            empty.len(),
            empty[..empty.len().min(3)].join(", ")
        );
    }
    eprintln!(
        "augmented {} samples in {:.1} s into {}",
        done.load(Ordering::Relaxed),
        t0.elapsed().as_secs_f64(),
        a.out.display()
    );
    if !failures.is_empty() {
        for f in &failures {
            eprintln!("failed: {f}");
        }
        bail!("{} of {} samples failed (finished samples are kept; re-run to resume)", failures.len(), todo.len());
    }
    Ok(())
}

fn run_apply(a: ApplyArgs) -> Result<()> {
    let files = laparo_stereo::SampleFiles {
        id: "sample".into(),
        left: a.left.clone(),
        right: a.right.clone(),
        disp_left: a.disp.clone(),
        disp_right: a.disp_right.clone(),
        calib: None,
    };
    let s = laparo_stereo::load_sample(&files)?;
    let text = std::fs::read_to_string(&a.params).with_context(|| format!("reading {}", a.params.display()))?;
    let p = laparo_stereo::parse_params(&text, s.left.width, s.left.height)
        .with_context(|| format!("{}", a.params.display()))?;
    for (side, k) in [("left", &p.left.k), ("right", &p.right.k)] {
        if (k.width, k.height) != (s.left.width, s.left.height) {
            bail!(
                "{}: {side} camera is {}x{} but the images are {}x{}",
                a.params.display(),
                k.width,
                k.height,
                s.left.width,
                s.left.height
            );
        }
    }
    let inputs: Vec<&std::path::Path> =
        [Some(&a.params), Some(&a.left), Some(&a.right), a.disp.as_ref(), a.disp_right.as_ref()]
            .into_iter()
            .flatten()
            .map(|p| p.as_path())
            .collect();
    for name in ["left.png", "right.png", "params.json", "disp_left.pfm", "disp_right.pfm"] {
        laparo_core::atomic::refuse_overwrite(&a.out.join(name), &inputs, false).context("--out")?;
    }
    let out = augment_stereo(&s, &p, a.gt_rule)?;
    for (side, v) in [("left", &out.left.valid), ("right", &out.right.valid)] {
        if v.count() == 0 {
            eprintln!(
                "warning: the augmented {side} view has no valid pixel: its camera looks entirely outside the \
                 source image (check rotation, K_rel and focal lengths in {})",
                a.params.display()
            );
        }
    }
    let d = &a.out;
    std::fs::create_dir_all(d).with_context(|| format!("creating {}", d.display()))?;
    io::write_png(d.join("left.png"), &out.left.image)?;
    io::write_png(d.join("right.png"), &out.right.image)?;
    io::write_png(d.join("valid_left.png"), &out.left.valid.map(|b| if b { 255 } else { 0 }))?;
    io::write_png(d.join("valid_right.png"), &out.right.valid.map(|b| if b { 255 } else { 0 }))?;
    for (name, disp) in [("disp_left", &out.disp_left), ("disp_right", &out.disp_right)] {
        if let Some(dd) = disp {
            io::write_pfm(d.join(format!("{name}.pfm")), &dd.disparity)?;
            if let Some(v) = &dd.vertical_residual {
                io::write_pfm(d.join(format!("{name}_vertical_residual.pfm")), v)?;
            }
        }
    }
    let canonical = serde_json::json!({
        "gt_rule": a.gt_rule,
        "params": p,
        "homography_left": rows(&p.left.homography()),
        "homography_right": rows(&p.right.homography()),
    });
    laparo_core::atomic::write_atomic(&d.join("params.json"), serde_json::to_string_pretty(&canonical)?.as_bytes())?;
    println!("wrote {}", d.display());
    Ok(())
}

fn rows(m: &Matrix3<f64>) -> [[f64; 3]; 3] {
    [[m[(0, 0)], m[(0, 1)], m[(0, 2)]], [m[(1, 0)], m[(1, 1)], m[(1, 2)]], [m[(2, 0)], m[(2, 1)], m[(2, 2)]]]
}

fn run_config(a: ConfigArgs) -> Result<()> {
    let c = CatsConfig::thesis(&a.row)?;
    let text = c.to_toml_string();
    match a.out {
        Some(p) => {
            laparo_core::atomic::write_atomic(&p, text.as_bytes())?;
            println!("wrote {}", p.display());
        }
        None => print!("{text}"),
    }
    Ok(())
}
