//! `laparo depth perturb` (seeded synthetic perturbations, issue 2 item 7) and
//! `laparo depth reproject` (GT preparation of thesis §3.2.6, issue 2 item 6).
use clap::Args;
use std::path::PathBuf;

/// Arguments of `laparo depth perturb`.
#[derive(Args, Debug, Clone)]
pub struct PerturbArgs {
    /// Clean RGB image (PNG/JPEG/TIFF) or a folder of them (processed in sorted order).
    #[arg(long)]
    pub input: PathBuf,
    /// Output folder: `<out>/<kind>/<severity>/<stem>.png`.
    #[arg(long)]
    pub out: PathBuf,
    /// Perturbation kinds: smoke, blood, bright, dark, defocus, motion, dirt.
    #[arg(long, value_delimiter = ',', default_value = "smoke,blood,bright,dark,defocus,motion,dirt")]
    pub kinds: Vec<String>,
    /// Severity levels (1..=3).
    #[arg(long, value_delimiter = ',', default_value = "1,2,3")]
    pub severities: Vec<u8>,
    /// Random seed; the output of one image depends only on (seed, image name, kind, severity).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Optional ground-truth depth file or folder (same stems as the inputs) to list in the manifest.
    #[arg(long)]
    pub gt: Option<PathBuf>,
    /// Recompute outputs that already exist (default: skip them, so an interrupted run resumes).
    #[arg(long)]
    pub overwrite: bool,
}

/// Arguments of `laparo depth reproject`.
#[derive(Args, Debug, Clone)]
pub struct ReprojectArgs {
    /// Depth-sensor depth map (npy/npz/pfm/tif/tiff/png16).
    #[arg(long)]
    pub depth: PathBuf,
    /// Unit of the values in `--depth` (m or mm).
    #[arg(long, default_value = "mm")]
    pub depth_unit: String,
    /// Depth-sensor intrinsics JSON: {"fx","fy","cx","cy","width","height"} or {"K": 3x3, "width", "height"} (px).
    #[arg(long)]
    pub sensor_intrinsics: PathBuf,
    /// T_DS→L JSON (P_L = R P_DS + t): {"T": 4x4} or {"R": 3x3, "t": [x,y,z]}, optional "unit": "mm"|"m"
    /// for the translation (default given by --extrinsics-unit).
    #[arg(long)]
    pub extrinsics: PathBuf,
    /// Unit of the translation in `--extrinsics` when the file does not state it.
    #[arg(long, default_value = "mm")]
    pub extrinsics_unit: String,
    /// Laparoscope intrinsics JSON (same format as --sensor-intrinsics), px.
    #[arg(long)]
    pub intrinsics: PathBuf,
    /// Output width in px (default: from --intrinsics).
    #[arg(long)]
    pub width: Option<usize>,
    /// Output height in px (default: from --intrinsics).
    #[arg(long)]
    pub height: Option<usize>,
    /// Tool mask in the laparoscope view (8-bit PNG, non-zero = tool): removed from the output.
    #[arg(long)]
    pub tool_mask: Option<PathBuf>,
    /// Lower clamp of the output depth in m (values below become invalid).
    #[arg(long, default_value_t = 0.01)]
    pub min_depth_m: f64,
    /// Upper clamp of the output depth in m (values above become invalid).
    #[arg(long, default_value_t = 0.5)]
    pub max_depth_m: f64,
    /// Drop sensor triangles whose depth jump (max/min − 1) exceeds this (depth discontinuities).
    #[arg(long, default_value_t = 0.05)]
    pub max_rel_jump: f64,
    /// Unit of the written depth (m or mm).
    #[arg(long, default_value = "mm")]
    pub out_unit: String,
    /// Output depth file (npy/npz/pfm/tif/tiff/png16 by extension).
    #[arg(long)]
    pub out: PathBuf,
}

/// Run `laparo depth perturb`.
pub fn perturb(a: PerturbArgs) -> anyhow::Result<()> {
    let _ = a;
    anyhow::bail!("laparo depth perturb: being written")
}

/// Run `laparo depth reproject`.
pub fn reproject(a: ReprojectArgs) -> anyhow::Result<()> {
    let _ = a;
    anyhow::bail!("laparo depth reproject: being written")
}
