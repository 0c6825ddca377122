//! Inputs and timing helpers of `laparo depth bench` (speed is measured there, never in tests).
use crate::align::PredKind;
use crate::metrics::{evaluate_pair, PairMetrics, PairOptions};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use rayon::prelude::*;
use std::time::Instant;

/// The input of depth_eval_ref.py's own timing: GT depth U(0.03, 0.3) m with 10 % holes (0),
/// predicted disparity `(1/z − 2)/5 + N(0, 0.2)` (an affine disparity with noise). Seeded.
pub fn synthetic_pair(width: usize, height: usize, seed: u64) -> (Vec<f64>, Vec<f64>) {
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
pub struct Timing {
    /// Single-image latency on one thread: minimum and median over the repetitions (ms).
    pub min_ms: f64,
    pub median_ms: f64,
    /// Single-image latency with every core working on the one image (ms).
    pub parallel_min_ms: f64,
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
    ts.sort_by(f64::total_cmp);
    (ts[0], ts[ts.len() / 2])
}

/// Time `evaluate_pair` on (pred, gt): `reps` runs on a one-thread pool, `reps` runs with all
/// threads on one image, then a parallel batch of independent images.
pub fn time_evaluation(pred: &[f64], gt: &[f64], opts: &PairOptions, reps: usize) -> (Timing, PairMetrics) {
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
