//! Robust two-view geometry: homography, fundamental and essential matrices (5-point solver) by
//! RANSAC with MSAC scoring (truncated quadratic loss, Torr & Zisserman 2000), an adaptive iteration count
//! and local optimisation on the inliers; relative pose from E by cheirality ([`pose`]).
//!
//! Determinism: hypothesis `k` draws its minimal sample from its own ChaCha8 stream seeded by
//! (`seed`, `k`); hypotheses are generated and scored in fixed batches of [`BATCH`] (in parallel
//! with rayon), and the best one is chosen by (score, k). The stopping rule is checked only
//! between batches, and so is the local optimisation of a new best hypothesis (for estimators
//! with `LO_ON_NEW_BEST`, the essential matrix). The output is therefore identical for any
//! number of threads.
//!
//! Point convention: pixel centres at integer coordinates (laparo's), `[x, y]` in px.
pub mod essential;
pub mod five_point;
pub mod fundamental;
pub mod homography;
mod linalg;
pub mod pose;

pub use essential::{find_essential, find_essential_with, EssentialSolver};
pub use five_point::five_point;
pub use fundamental::{find_fundamental, sampson_distance_sq, symmetric_epipolar_distance};
pub use homography::{find_homography, transfer_error_sq};
pub use pose::{decompose_essential, recover_pose, RelativePose};

use crate::error::{FeaturesError, Result};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

/// Number of hypotheses drawn per batch (the adaptive stopping rule is checked between batches).
pub const BATCH: usize = 64;

/// RANSAC parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct RansacParams {
    /// Inlier threshold, px (for [`find_essential`]: in the units of its normalised inputs).
    pub threshold_px: f64,
    /// Probability that at least one all-inlier sample was drawn (adaptive stop), in (0, 1).
    pub confidence: f64,
    /// Upper bound on the number of hypotheses.
    pub max_iters: usize,
    /// Seed of the sampler.
    pub seed: u64,
}

impl Default for RansacParams {
    fn default() -> Self {
        RansacParams { threshold_px: 1.0, confidence: 0.999, max_iters: 10_000, seed: 0 }
    }
}

/// The result of a robust fit.
#[derive(Clone, Debug, PartialEq)]
pub struct RobustFit<M> {
    /// The model, refined on the inliers.
    pub model: M,
    /// Inlier flag per correspondence (residual below the threshold).
    pub inliers: Vec<bool>,
    /// RMS residual over the inliers, px (the model's error measure: forward transfer for H,
    /// Sampson distance for F and E).
    pub rms_px: f64,
    /// Number of inliers.
    pub n_inliers: usize,
    /// Number of hypotheses drawn.
    pub iterations: usize,
}

/// A model family for the generic RANSAC loop.
pub(crate) trait Estimator: Sync {
    type Model: Clone + Send;
    /// Size of a minimal sample.
    const SAMPLE: usize;
    /// Name for error messages.
    const NAME: &'static str;
    /// Models from a minimal sample (may be empty when degenerate).
    fn minimal(&self, idx: &[usize]) -> Vec<Self::Model>;
    /// Squared residual of correspondence `i`, px².
    fn residual_sq(&self, m: &Self::Model, i: usize) -> f64;
    /// Least-squares fit on many correspondences (local optimisation).
    fn refit(&self, idx: &[usize]) -> Option<Self::Model>;
    /// Number of correspondences.
    fn len(&self) -> usize;
    /// Run the local optimisation on every new best hypothesis (between batches, LO-RANSAC of
    /// Chum, Matas & Kittler 2003) rather than only on the final one.
    const LO_ON_NEW_BEST: bool = false;
}

/// Validate a correspondence set: same length, enough points, finite coordinates.
pub(crate) fn check_points(p1: &[[f64; 2]], p2: &[[f64; 2]], min: usize, what: &str) -> Result<()> {
    if p1.len() != p2.len() {
        return Err(FeaturesError::invalid(
            format!("{what} correspondences"),
            format!("p1 has {} points, p2 has {}", p1.len(), p2.len()),
        ));
    }
    if p1.len() < min {
        return Err(FeaturesError::Estimation(format!(
            "{what}: too few correspondences: {} (need at least {min})",
            p1.len()
        )));
    }
    for (name, p) in [("p1", p1), ("p2", p2)] {
        if let Some(i) = p.iter().position(|q| !(q[0].is_finite() && q[1].is_finite())) {
            return Err(FeaturesError::invalid(
                format!("{what} correspondences"),
                format!("{name}[{i}] = {:?} is not finite (NaN or inf)", p[i]),
            ));
        }
    }
    Ok(())
}

pub(crate) fn check_params(prm: &RansacParams) -> Result<()> {
    if !(prm.threshold_px.is_finite() && prm.threshold_px > 0.0) {
        return Err(FeaturesError::invalid("threshold_px", format!("{} (need a finite value > 0)", prm.threshold_px)));
    }
    if !(prm.confidence > 0.0 && prm.confidence < 1.0) {
        return Err(FeaturesError::invalid("confidence", format!("{} (need 0 < confidence < 1)", prm.confidence)));
    }
    if prm.max_iters == 0 {
        return Err(FeaturesError::invalid("max_iters", "0 (need at least 1)"));
    }
    Ok(())
}

/// SplitMix64 finaliser: decorrelates the per-hypothesis seeds.
fn mix(seed: u64, k: u64) -> u64 {
    let mut z = seed ^ k.wrapping_mul(0x9E37_79B9_7F4A_7C15).wrapping_add(0x632B_E59B_D9B4_E019);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Draw `s` distinct indices in 0..n from hypothesis `k`'s own stream.
fn sample(seed: u64, k: usize, n: usize, s: usize, out: &mut Vec<usize>) {
    let mut rng = ChaCha8Rng::seed_from_u64(mix(seed, k as u64));
    out.clear();
    while out.len() < s {
        let i = rng.gen_range(0..n);
        if !out.contains(&i) {
            out.push(i);
        }
    }
}

/// MSAC score (lower is better): Σ min(r², t²); None as soon as the partial sum exceeds
/// `bound` (the hypothesis cannot win).
fn msac<E: Estimator>(est: &E, m: &E::Model, t2: f64, bound: f64) -> Option<(f64, usize)> {
    let mut s = 0.0;
    let mut n = 0;
    for i in 0..est.len() {
        let r = est.residual_sq(m, i);
        if r < t2 {
            s += r;
            n += 1;
        } else {
            s += t2;
        }
        if s > bound {
            return None;
        }
    }
    Some((s, n))
}

/// Hypotheses needed for `confidence` at inlier ratio `w` and sample size `s`.
fn needed_iterations(confidence: f64, w: f64, s: usize) -> f64 {
    if w <= 0.0 {
        return f64::INFINITY;
    }
    let p = w.powi(s as i32);
    if p >= 1.0 - 1e-15 {
        return 1.0;
    }
    (1.0 - confidence).ln() / (1.0 - p).ln()
}

/// A scored hypothesis: (MSAC score, hypothesis index k, model, inlier count).
type Candidate<M> = (f64, usize, M, usize);

/// Local optimisation: refit on the inliers while the MSAC score improves.
fn local_optimisation<E: Estimator>(est: &E, mut model: E::Model, mut score: f64, t2: f64) -> (E::Model, f64) {
    for _ in 0..10 {
        let idx: Vec<usize> = (0..est.len()).filter(|&i| est.residual_sq(&model, i) < t2).collect();
        if idx.len() < E::SAMPLE {
            break;
        }
        let Some(m2) = est.refit(&idx) else { break };
        let Some((s2, _)) = msac(est, &m2, t2, f64::INFINITY) else { break };
        if s2 < score * (1.0 - 1e-12) {
            score = s2;
            model = m2;
        } else {
            break;
        }
    }
    (model, score)
}

/// The generic loop: sampling, MSAC scoring, adaptive stop, local optimisation.
pub(crate) fn run<E: Estimator>(est: &E, prm: &RansacParams) -> Result<RobustFit<E::Model>> {
    check_params(prm)?;
    let n = est.len();
    let t2 = prm.threshold_px * prm.threshold_px;
    let mut best: Option<Candidate<E::Model>> = None;
    let mut drawn = 0usize;
    let mut needed = prm.max_iters as f64;
    while (drawn as f64) < needed.min(prm.max_iters as f64) {
        let b = BATCH.min(prm.max_iters - drawn);
        // early exit bound from the previous batches only (thread-count independent)
        let bound = best.as_ref().map_or(f64::INFINITY, |b| b.0);
        let batch: Vec<Option<Candidate<E::Model>>> = (drawn..drawn + b)
            .into_par_iter()
            .map_init(Vec::new, |idx, k| {
                sample(prm.seed, k, n, E::SAMPLE, idx);
                let mut bk: Option<Candidate<E::Model>> = None;
                for m in est.minimal(idx) {
                    let Some((s, ni)) = msac(est, &m, t2, bound) else { continue };
                    if bk.as_ref().is_none_or(|b| s < b.0) {
                        bk = Some((s, k, m, ni));
                    }
                }
                bk
            })
            .collect();
        drawn += b;
        let before = best.as_ref().map(|b| b.1);
        for c in batch.into_iter().flatten() {
            if best.as_ref().is_none_or(|b| c.0 < b.0 || (c.0 == b.0 && c.1 < b.1)) {
                best = Some(c);
            }
        }
        if E::LO_ON_NEW_BEST {
            if let Some(b) = best.as_mut().filter(|b| before != Some(b.1)) {
                let (m, s) = local_optimisation(est, b.2.clone(), b.0, t2);
                b.3 = (0..n).filter(|&i| est.residual_sq(&m, i) < t2).count();
                (b.0, b.2) = (s, m);
            }
        }
        if let Some(b) = &best {
            needed = needed_iterations(prm.confidence, b.3 as f64 / n as f64, E::SAMPLE);
        }
    }
    let Some((score, _, model, _)) = best else {
        return Err(FeaturesError::Estimation(format!(
            "{}: every sample of {} correspondences was degenerate ({drawn} tried)",
            E::NAME,
            n
        )));
    };
    let (model, _) = local_optimisation(est, model, score, t2);
    let inliers: Vec<bool> = (0..n).map(|i| est.residual_sq(&model, i) < t2).collect();
    let n_inliers = inliers.iter().filter(|&&b| b).count();
    if n_inliers < E::SAMPLE {
        return Err(FeaturesError::Estimation(format!(
            "{}: degenerate fit, only {n_inliers} of {n} correspondences within {} px",
            E::NAME,
            prm.threshold_px
        )));
    }
    let ss: f64 = (0..n).filter(|&i| inliers[i]).map(|i| est.residual_sq(&model, i)).sum();
    Ok(RobustFit { model, inliers, rms_px: (ss / n_inliers as f64).sqrt(), n_inliers, iterations: drawn })
}
