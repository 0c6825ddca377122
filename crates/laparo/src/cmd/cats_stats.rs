//! `laparo cats stats CALIB...`: rotations of each camera from the ideal rectified stereo frame,
//! principal-point offsets, baselines and lens-distortion displacement of real stereo calibrations
//! (thesis §3.3.4, Table 3.6), with a CATS configuration fitted to them.
use clap::Args;
use std::path::PathBuf;

/// Arguments of `laparo cats stats`.
#[derive(Args, Debug, Clone)]
pub struct StatsArgs {
    /// Stereo calibration files (OpenCV FileStorage YAML as in SCARED, or JSON).
    #[arg(required = true)]
    pub calib: Vec<PathBuf>,
    /// Print one JSON object (per-file results and summary statistics) instead of tables.
    #[arg(long)]
    pub json: bool,
    /// Write a CATS configuration (TOML) fitted to the statistics.
    #[arg(long)]
    pub config_out: Option<PathBuf>,
    /// Image width (px) for calibrations that do not store their image size.
    #[arg(long)]
    pub width: Option<usize>,
    /// Image height (px) for calibrations that do not store their image size.
    #[arg(long)]
    pub height: Option<usize>,
}

/// Run `laparo cats stats`.
pub fn run_stats(a: StatsArgs) -> anyhow::Result<()> {
    let _ = a;
    anyhow::bail!("laparo cats stats: calibration reader not wired yet")
}
