//! `laparo-bench stereo`: rectification timing (Bouguet rectification, remap tables of both
//! cameras, bilinear remap of both images) on a real pair (formerly `laparo stereo bench`; OpenCV
//! `initUndistortRectifyMap` + `remap` figures on the same input are in benchmarks/stereo_stats.md).
use crate::timing::med;
use anyhow::{Context, Result};
use clap::Args;
use laparo_core::calib::StereoCalibration;
use laparo_core::remap::{remap, Interp};
use laparo_stereo::{Rectification, RectifyOptions, Side};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Options of `laparo-bench stereo` (those of the former `laparo stereo bench`).
#[derive(Args, Debug)]
pub struct BenchArgs {
    /// Stereo calibration: OpenCV YAML (SCARED, EndoVis, ...), laparo JSON, Middlebury calib.txt,
    /// or `INTRINSICS,EXTRINSICS` (OpenCV stereo_calib layout).
    #[arg(long, value_name = "CALIB")]
    pub calib: String,
    /// Image width for calibration files without an image size (default: the left image's width).
    #[arg(long, requires = "height")]
    pub width: Option<usize>,
    /// Image height for calibration files without an image size (default: the left image's height).
    #[arg(long, requires = "width")]
    pub height: Option<usize>,
    /// Left image.
    #[arg(long)]
    pub left: PathBuf,
    /// Right image.
    #[arg(long)]
    pub right: PathBuf,
    /// Repetitions (the median is reported).
    #[arg(long, default_value_t = 10)]
    pub repeat: usize,
    /// Rayon threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
}

/// The calibration `spec` (`FILE` or `INTRINSICS,EXTRINSICS`); `size` is used when the file does
/// not state the image size.
fn read_calibration(spec: &str, size: (usize, usize)) -> Result<StereoCalibration> {
    if laparo_core::io::extension(Path::new(spec)) == "txt" {
        return laparo_stereo::read_middlebury_calib(spec)
            .with_context(|| format!("cannot read Middlebury calibration {spec}"));
    }
    let (w, h) = size;
    let c = match spec.split_once(',') {
        Some((a, b)) => {
            StereoCalibration::read_pair(a, b).or_else(|_| StereoCalibration::read_pair_with_size(a, b, w, h))
        }
        None => StereoCalibration::read(spec).or_else(|_| StereoCalibration::read_with_size(spec, w, h)),
    };
    c.with_context(|| format!("cannot read stereo calibration {spec}"))
}

pub fn run(a: BenchArgs) -> Result<()> {
    let left = laparo_core::io::read_image(&a.left)?;
    let right = laparo_core::io::read_image(&a.right)?;
    let calib = read_calibration(&a.calib, (a.width.unwrap_or(left.width), a.height.unwrap_or(left.height)))?;
    let pool = rayon::ThreadPoolBuilder::new().num_threads(a.threads.unwrap_or(0)).build()?;
    let n = a.repeat.max(1);
    pool.install(|| -> Result<()> {
        let (mut t_rect, mut t_maps, mut t_remap) = (Vec::new(), Vec::new(), Vec::new());
        for _ in 0..n {
            let t0 = Instant::now();
            let rect = Rectification::new(&calib, RectifyOptions::default())?;
            let t1 = Instant::now();
            let (ml, mr) = (rect.remap_table(Side::Left), rect.remap_table(Side::Right));
            let t2 = Instant::now();
            let (l, _) = remap(&left, &ml, Interp::Bilinear, 0)?;
            let (r, _) = remap(&right, &mr, Interp::Bilinear, 0)?;
            let t3 = Instant::now();
            std::hint::black_box((l, r));
            t_rect.push((t1 - t0).as_secs_f64() * 1e3);
            t_maps.push((t2 - t1).as_secs_f64() * 1e3);
            t_remap.push((t3 - t2).as_secs_f64() * 1e3);
        }
        println!(
            "{}x{}x{} pair, {} threads, median of {n}: stereoRectify-like {:.3} ms, maps (both cameras) {:.2} ms, \
             bilinear remap (both images) {:.2} ms",
            left.width,
            left.height,
            left.channels,
            rayon::current_num_threads(),
            med(t_rect),
            med(t_maps),
            med(t_remap)
        );
        Ok(())
    })
}
