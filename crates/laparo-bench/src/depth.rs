//! `laparo-bench depth`: per-image RoDEM evaluation time (3 alignments, all metrics) on the input
//! of `../shared/bench/depth_eval_ref.py`'s own timing, optionally against that numpy reference
//! run on the same arrays (formerly `laparo depth bench` and `laparo_depth::bench`).
use crate::timing::{med, vmin};
use anyhow::{bail, Context, Result};
use clap::Args;
use laparo_depth::align::PredKind;
use laparo_depth::metrics::{evaluate_pair, PairMetrics, PairOptions, METRIC_NAMES};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use rayon::prelude::*;
use std::path::PathBuf;
use std::time::Instant;

/// The input of depth_eval_ref.py's own timing: GT depth U(0.03, 0.3) m with 10 % holes (0),
/// predicted disparity `(1/z − 2)/5 + N(0, 0.2)` (an affine disparity with noise). Seeded.
pub(crate) fn synthetic_pair(width: usize, height: usize, seed: u64) -> (Vec<f64>, Vec<f64>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, 0.2).unwrap();
    let n = width * height;
    let mut gt = Vec::with_capacity(n);
    let mut pred = Vec::with_capacity(n);
    for _ in 0..n {
        let z: f64 = rng.gen_range(0.03..0.3);
        let z = if rng.gen::<f64>() < 0.1 { 0.0 } else { z };
        let inv = if z > 0.0 { 1.0 / z } else { 1.0 };
        gt.push(z);
        pred.push((inv - 2.0) / 5.0 + noise.sample(&mut rng));
    }
    (pred, gt)
}

/// Timing of the per-image evaluation (all alignments of `opts`).
#[derive(Clone, Debug, serde::Serialize)]
pub(crate) struct Timing {
    /// Single-image latency on one thread: minimum over the repetitions (ms).
    pub min_ms: f64,
    /// Single-image latency on one thread: median over the repetitions (ms).
    pub median_ms: f64,
    /// Single-image latency with every core working on the one image: minimum (ms).
    pub parallel_min_ms: f64,
    /// Single-image latency with every core working on the one image: median (ms).
    pub parallel_median_ms: f64,
    /// Throughput with rayon over independent images (all cores), images per second.
    pub images_per_s_parallel: f64,
    pub threads: usize,
}

/// Minimum and median (ms) of `reps` evaluations of (pred, gt).
fn latency(pred: &[f64], gt: &[f64], opts: &PairOptions, reps: usize) -> (f64, f64) {
    let mut ts = Vec::with_capacity(reps);
    for _ in 0..reps {
        let t0 = Instant::now();
        let r = evaluate_pair(pred, PredKind::Disparity, gt, None, opts).unwrap();
        ts.push(t0.elapsed().as_secs_f64() * 1e3);
        std::hint::black_box(r);
    }
    (vmin(&ts), med(ts))
}

/// Time `evaluate_pair` on (pred, gt): `reps` runs on a one-thread pool, `reps` runs with all
/// threads on one image, then a parallel batch of independent images.
pub(crate) fn time_evaluation(pred: &[f64], gt: &[f64], opts: &PairOptions, reps: usize) -> (Timing, PairMetrics) {
    let reps = reps.max(1);
    let first = evaluate_pair(pred, PredKind::Disparity, gt, None, opts).expect("benchmark input is valid");
    let (min_ms, median_ms) = match rayon::ThreadPoolBuilder::new().num_threads(1).build() {
        Ok(pool) => pool.install(|| {
            let _ = evaluate_pair(pred, PredKind::Disparity, gt, None, opts); // this pool's buffers
            latency(pred, gt, opts, reps)
        }),
        Err(_) => latency(pred, gt, opts, reps),
    };
    let (parallel_min_ms, parallel_median_ms) = latency(pred, gt, opts, reps);
    let threads = rayon::current_num_threads();
    let batch = (reps * threads).max(4);
    let t0 = Instant::now();
    let n: usize = (0..batch)
        .into_par_iter()
        .map(|_| evaluate_pair(pred, PredKind::Disparity, gt, None, opts).unwrap().n_valid)
        .sum();
    std::hint::black_box(n);
    let dt = t0.elapsed().as_secs_f64();
    let timing = Timing {
        min_ms,
        median_ms,
        parallel_min_ms,
        parallel_median_ms,
        images_per_s_parallel: batch as f64 / dt,
        threads,
    };
    (timing, first)
}

/// Options of `laparo-bench depth` (those of the former `laparo depth bench`).
#[derive(Args)]
pub struct BenchArgs {
    /// Image width (px).
    #[arg(long, default_value_t = 640)]
    pub width: usize,
    /// Image height (px).
    #[arg(long, default_value_t = 480)]
    pub height: usize,
    /// Repetitions (the minimum and the median are reported).
    #[arg(long, default_value_t = 20)]
    pub reps: usize,
    /// Python interpreter with numpy, to time ../shared/bench/depth_eval_ref.py on the same input.
    #[arg(long)]
    pub python: Option<PathBuf>,
    /// Path of depth_eval_ref.py.
    #[arg(long, default_value = "../shared/bench/depth_eval_ref.py")]
    pub reference: PathBuf,
    /// Write the figures as JSON to this file.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

const PY_BENCH: &str = r#"
import json, sys, time
import numpy as np
sys.path.insert(0, sys.argv[1])
from depth_eval_ref import evaluate
pred, gt = np.load(sys.argv[2]), np.load(sys.argv[3])
reps = int(sys.argv[4])
r = evaluate(pred, gt)
ts = []
for _ in range(reps):
    t0 = time.perf_counter(); evaluate(pred, gt); ts.append(time.perf_counter() - t0)
print(json.dumps({"min_ms": min(ts) * 1e3, "median_ms": float(np.median(ts)) * 1e3, "result": r}))
"#;

pub fn run(a: BenchArgs) -> Result<()> {
    let (pred, gt) = synthetic_pair(a.width, a.height, 0);
    let opts = PairOptions::default();
    let (t, rust) = time_evaluation(&pred, &gt, &opts, a.reps);
    println!(
        "laparo: {}x{} per image (3 alignments): min {:.2} ms, median {:.2} ms on 1 thread; min {:.2} ms, median {:.2} ms on {} threads; {:.0} images/s on {} threads",
        a.width,
        a.height,
        t.min_ms,
        t.median_ms,
        t.parallel_min_ms,
        t.parallel_median_ms,
        t.threads,
        t.images_per_s_parallel,
        t.threads
    );
    let mut out = serde_json::json!({"width": a.width, "height": a.height, "laparo": t});
    if let Some(py) = &a.python {
        let dir = tempfile_dir()?;
        let (pp, gp) = (dir.join("pred.npy"), dir.join("gt.npy"));
        let img = |v: &Vec<f64>| laparo_core::Image::from_vec(a.width, a.height, 1, v.clone());
        laparo_core::io::write_npy_f64(&pp, &img(&pred)?)?;
        laparo_core::io::write_npy_f64(&gp, &img(&gt)?)?;
        let ref_dir = a.reference.parent().map(|p| p.to_path_buf()).unwrap_or_default();
        if !a.reference.is_file() {
            bail!("{}: reference script not found", a.reference.display());
        }
        let o = std::process::Command::new(py)
            .arg("-c")
            .arg(PY_BENCH)
            .arg(&ref_dir)
            .arg(&pp)
            .arg(&gp)
            .arg(a.reps.to_string())
            .output()
            .with_context(|| format!("running {}", py.display()))?;
        let _ = std::fs::remove_dir_all(&dir);
        if !o.status.success() {
            bail!("{} failed: {}", py.display(), String::from_utf8_lossy(&o.stderr));
        }
        let v: serde_json::Value = serde_json::from_slice(&o.stdout).context("reading the reference's output")?;
        let np_min = v["min_ms"].as_f64().unwrap_or(f64::NAN);
        let np_med = v["median_ms"].as_f64().unwrap_or(f64::NAN);
        // Agreement of the two on this input.
        let mut worst: f64 = 0.0;
        let rj = serde_json::to_value(&rust)?;
        for al in ["none", "scale", "scale_shift"] {
            for k in METRIC_NAMES {
                let (x, y) = (rj[al][k].as_f64().unwrap_or(f64::NAN), v["result"][al][k].as_f64().unwrap_or(f64::NAN));
                worst = worst.max((x - y).abs() / y.abs().max(1e-12));
            }
        }
        let np_ips = 1e3 / np_min;
        println!("numpy depth_eval_ref.py: min {np_min:.2} ms, median {np_med:.2} ms per image (1 thread)");
        println!(
            "ratio (numpy / laparo): single-thread latency {:.1}x (min), {:.1}x (median); latency on {} threads {:.1}x (min), {:.1}x (median); throughput {:.1}x ({:.0} vs {:.0} images/s)",
            np_min / t.min_ms,
            np_med / t.median_ms,
            t.threads,
            np_min / t.parallel_min_ms,
            np_med / t.parallel_median_ms,
            t.images_per_s_parallel / np_ips,
            t.images_per_s_parallel,
            np_ips
        );
        println!("max relative difference of all metrics vs the reference: {worst:.2e}");
        out["numpy"] = serde_json::json!({"min_ms": np_min, "median_ms": np_med});
        out["ratio_latency_min"] = serde_json::json!(np_min / t.min_ms);
        out["ratio_latency_parallel_min"] = serde_json::json!(np_min / t.parallel_min_ms);
        out["ratio_throughput"] = serde_json::json!(t.images_per_s_parallel / np_ips);
        out["max_rel_diff"] = serde_json::json!(worst);
    } else {
        eprintln!("(pass --python /path/to/python-with-numpy to time depth_eval_ref.py on the same input)");
    }
    if let Some(j) = &a.json {
        laparo_core::atomic::write_atomic(j, serde_json::to_string_pretty(&out)?.as_bytes())?;
    }
    Ok(())
}

fn tempfile_dir() -> Result<PathBuf> {
    let d = std::env::temp_dir().join(format!("laparo-depth-bench-{}", std::process::id()));
    std::fs::create_dir_all(&d).with_context(|| d.display().to_string())?;
    Ok(d)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn synthetic_pair_follows_its_recipe() {
        let (pred, gt) = synthetic_pair(64, 48, 1);
        assert_eq!((pred.len(), gt.len()), (64 * 48, 64 * 48));
        let holes = gt.iter().filter(|&&z| z == 0.0).count() as f64 / gt.len() as f64;
        assert!((0.05..0.15).contains(&holes), "about 10 % holes, got {holes}");
        assert!(gt.iter().all(|&z| z == 0.0 || (0.03..0.3).contains(&z)));
        // Seeded: the same seed gives the same pair.
        assert_eq!(synthetic_pair(64, 48, 1), (pred, gt));
    }
}
