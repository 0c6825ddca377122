//! Per-sample CATS augmentation with atomic outputs mirroring the input tree and the JSON sidecar
//! written last (a sample is finished iff its sidecar exists).
use super::layout::{load_sample, source_cameras, Layout, SampleFiles};
use crate::augment::{augment_stereo, AugmentedDisparity, GtRule, Mat3Rows, StereoAugmentation};
use crate::cats_params::{sample_rng, sample_seed, CatsConfig};
use crate::error::{Result, StereoError};
use laparo_core::image::Mask;
use laparo_core::{io, Distortion, Image};
use nalgebra::Matrix3;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Summary numbers of one augmented sample (stored in the sidecar).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct SampleStats {
    /// Fraction of augmented left pixels with a source pixel.
    pub valid_fraction_left: f64,
    /// Fraction of augmented right pixels with a source pixel.
    pub valid_fraction_right: f64,
    /// Fraction of augmented left pixels with a known disparity.
    pub disparity_valid_fraction: Option<f64>,
    /// Smallest known augmented disparity (px).
    pub disparity_min_px: Option<f64>,
    /// Largest known augmented disparity (px).
    pub disparity_max_px: Option<f64>,
    /// Exact rule: mean and max |vertical residual| (px).
    pub vertical_residual_mean_abs_px: Option<f64>,
    /// Exact rule: max |vertical residual| (px).
    pub vertical_residual_max_abs_px: Option<f64>,
}

/// The JSON sidecar of an augmented sample.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Sidecar {
    /// Version of laparo that wrote the sample.
    pub laparo_version: String,
    /// Sample id (left image path relative to the root, without extension).
    pub sample_id: String,
    /// Run seed.
    pub seed: u64,
    /// The ChaCha8 seed derived from (seed, sample_id).
    pub sample_seed: u64,
    /// How the disparity GT was carried through the warp.
    pub gt_rule: GtRule,
    /// The config file (or `default`) the parameters were sampled from.
    pub config_source: String,
    /// The sampled parameters (re-apply with `laparo cats apply --params`).
    pub params: StereoAugmentation,
    /// H = K_rel K R K⁻¹ of each camera, row-major.
    pub homography_left: Mat3Rows,
    /// H of the right camera, row-major.
    pub homography_right: Mat3Rows,
    /// Summary numbers of the sample.
    pub stats: SampleStats,
    /// [`run_params_hash`] of the run that wrote this sample (resume check); empty in sidecars
    /// of older versions.
    #[serde(default)]
    pub params_hash: String,
}

/// Hash of everything an augmented sample depends on besides its input files: seed, GT rule,
/// layout and the CATS configuration (its TOML form). Stored in each sidecar.
pub fn run_params_hash(config: &CatsConfig, seed: u64, rule: GtRule, layout: Layout) -> String {
    let text = format!("v1;seed={seed};gt_rule={rule:?};layout={layout:?};config={}", config.to_toml_string());
    laparo_core::atomic::fnv1a64_hex(text.as_bytes())
}

/// Resume state of one sample of an output folder.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ResumeState {
    /// Not (completely) written yet.
    Todo,
    /// Complete, written with the same parameters.
    Done,
    /// Complete, but written with other parameters (or by a version without a parameter hash).
    Stale,
}

/// `is_done` (the sidecar parses), distinguishing outputs written with other parameters (`hash` from
/// [`run_params_hash`]).
pub fn resume_state(f: &SampleFiles, root: &Path, out: &Path, hash: &str) -> ResumeState {
    if !is_done(f, root, out) {
        return ResumeState::Todo;
    }
    let o = output_paths(f, root, out);
    let same = std::fs::read_to_string(&o.sidecar)
        .ok()
        .and_then(|t| serde_json::from_str::<Sidecar>(&t).ok())
        .is_some_and(|sc| sc.params_hash == hash);
    if same {
        ResumeState::Done
    } else {
        ResumeState::Stale
    }
}

fn rows(m: &Matrix3<f64>) -> Mat3Rows {
    [[m[(0, 0)], m[(0, 1)], m[(0, 2)]], [m[(1, 0)], m[(1, 1)], m[(1, 2)]], [m[(2, 0)], m[(2, 1)], m[(2, 2)]]]
}

fn mask_png(m: &Mask) -> Image<u8> {
    m.map(|b| if b { 255 } else { 0 })
}

fn disp_stats(d: &AugmentedDisparity, st: &mut SampleStats) {
    let n = d.valid.data.len().max(1);
    let vals: Vec<f64> =
        d.disparity.data.iter().zip(&d.valid.data).filter(|(_, &v)| v).map(|(&x, _)| x as f64).collect();
    st.disparity_valid_fraction = Some(vals.len() as f64 / n as f64);
    st.disparity_min_px = vals.iter().cloned().reduce(f64::min);
    st.disparity_max_px = vals.iter().cloned().reduce(f64::max);
    if let Some(r) = &d.vertical_residual {
        let a: Vec<f64> = r.data.iter().filter(|v| v.is_finite()).map(|v| v.abs() as f64).collect();
        if !a.is_empty() {
            st.vertical_residual_mean_abs_px = Some(a.iter().sum::<f64>() / a.len() as f64);
            st.vertical_residual_max_abs_px = a.iter().cloned().reduce(f64::max);
        }
    }
}

/// Output locations of one sample.
pub struct OutputPaths {
    /// Augmented left image.
    pub left: PathBuf,
    /// Augmented right image.
    pub right: PathBuf,
    /// Augmented left disparity (PFM).
    pub disp_left: Option<PathBuf>,
    /// Augmented right disparity (PFM).
    pub disp_right: Option<PathBuf>,
    /// JSON sidecar.
    pub sidecar: PathBuf,
    /// Folder of auxiliary outputs (masks, residuals).
    pub aux_dir: PathBuf,
}

/// Where the outputs of sample `f` (from `root`) go under `out`.
pub fn output_paths(f: &SampleFiles, root: &Path, out: &Path) -> OutputPaths {
    let m = |p: &Path| out.join(p.strip_prefix(root).unwrap_or(p));
    let png = |p: &Path| m(p).with_extension("png");
    OutputPaths {
        left: png(&f.left),
        right: png(&f.right),
        disp_left: f.disp_left.as_ref().map(|p| m(p).with_extension("pfm")),
        disp_right: f.disp_right.as_ref().map(|p| m(p).with_extension("pfm")),
        sidecar: out.join(format!("{}.cats.json", f.id)),
        aux_dir: out.join("cats_aux"),
    }
}

/// True when sample `f` already has a readable sidecar and all its outputs (resumability).
pub fn is_done(f: &SampleFiles, root: &Path, out: &Path) -> bool {
    let o = output_paths(f, root, out);
    let Ok(text) = std::fs::read_to_string(&o.sidecar) else { return false };
    serde_json::from_str::<Sidecar>(&text).is_ok()
        && o.left.is_file()
        && o.right.is_file()
        && o.disp_left.as_ref().is_none_or(|p| p.is_file())
        && o.disp_right.as_ref().is_none_or(|p| p.is_file())
}

/// Write an augmented sample (images, disparities, masks) and, last, its sidecar; atomic writes.
pub fn write_augmented(
    f: &SampleFiles,
    root: &Path,
    out: &Path,
    a: &crate::augment::AugmentedStereo,
    mut sidecar: Sidecar,
) -> Result<Sidecar> {
    let o = output_paths(f, root, out);
    io::write_png(&o.left, &a.left.image)?;
    io::write_png(&o.right, &a.right.image)?;
    let aux = |suffix: &str| o.aux_dir.join(format!("{}_{suffix}", f.id));
    io::write_png(aux("valid_left.png"), &mask_png(&a.left.valid))?;
    io::write_png(aux("valid_right.png"), &mask_png(&a.right.valid))?;
    let mut st = SampleStats {
        valid_fraction_left: a.left.valid.count() as f64 / a.left.valid.data.len().max(1) as f64,
        valid_fraction_right: a.right.valid.count() as f64 / a.right.valid.data.len().max(1) as f64,
        ..Default::default()
    };
    for (d, p, side) in [(&a.disp_left, &o.disp_left, "left"), (&a.disp_right, &o.disp_right, "right")] {
        if let (Some(d), Some(p)) = (d, p) {
            io::write_pfm(p, &d.disparity)?;
            if let Some(r) = &d.vertical_residual {
                io::write_pfm(aux(&format!("vres_{side}.pfm")), r)?;
            }
            if side == "left" {
                disp_stats(d, &mut st);
            }
        }
    }
    sidecar.stats = st;
    let text = serde_json::to_string_pretty(&sidecar).expect("sidecar serialises");
    laparo_core::atomic::write_atomic(&o.sidecar, text.as_bytes())?;
    Ok(sidecar)
}

/// Augment one sample of a dataset with parameters drawn from `config` (seeded by
/// (`seed`, sample id)) and write it. Returns the sidecar.
pub fn augment_sample(
    f: &SampleFiles,
    root: &Path,
    out: &Path,
    layout: Layout,
    config: &CatsConfig,
    seed: u64,
    rule: GtRule,
) -> Result<Sidecar> {
    let s = load_sample(f)?;
    let (kl, kr) = source_cameras(f, layout, config, s.left.width, s.left.height)?;
    let mut rng = sample_rng(seed, &f.id);
    let p = config.sample(&mut rng, &kl, &Distortion::default(), &kr, &Distortion::default());
    super::params::check_homographies(&p).map_err(|e| StereoError::FileCheck {
        path: f.left.clone(),
        what: "sampled parameters".into(),
        source: Box::new(e),
    })?;
    let a = augment_stereo(&s, &p, rule)?;
    let sidecar = Sidecar {
        laparo_version: env!("CARGO_PKG_VERSION").into(),
        sample_id: f.id.clone(),
        seed,
        sample_seed: sample_seed(seed, &f.id),
        gt_rule: rule,
        config_source: config.source.clone(),
        homography_left: rows(&p.left.homography()),
        homography_right: rows(&p.right.homography()),
        params: p,
        stats: SampleStats::default(),
        params_hash: run_params_hash(config, seed, rule, layout),
    };
    write_augmented(f, root, out, &a, sidecar)
}

// ---------------------------------------------------------------------------------------------
// Hand-written parameters (`laparo cats apply --params`).
