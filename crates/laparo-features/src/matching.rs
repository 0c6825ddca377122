//! Brute-force descriptor matching: 2-NN search with Lowe's ratio test or VLFeat's `ubcmatch`
//! (thesis §4.5: "SIFT+UBCMatcher", "ORB+NN") and an optional mutual (cross) check.
//!
//! Hamming distances use `count_ones` on u64 words (hardware `popcnt` selected at run time);
//! L2 uses f32 with eight partial sums (AVX2+FMA selected at run time). Rows of image 1 are
//! processed in parallel with rayon; each row's result depends only on that row, and ties are
//! broken by the lower index, so the output is identical for any thread count.
use rayon::prelude::*;

use crate::error::{FeaturesError, Result};
use crate::keypoint::{Descriptors, Features, Match, MatchConfig, RatioTest};

/// The two nearest neighbours of one query: (index, squared-or-Hamming distance).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Knn2 {
    /// Best index (u32::MAX when the reference set is empty).
    pub best: u32,
    /// Best distance (L2 squared for float, bit count for binary).
    pub d_best: f32,
    /// Second-best distance (+∞ when there is none).
    pub d_second: f32,
}

/// Binary descriptors repacked into little-endian u64 words.
pub(crate) fn pack_u64(bytes: usize, data: &[u8]) -> (usize, Vec<u64>) {
    let words = bytes.div_ceil(8);
    let n = data.len() / bytes;
    let mut out = vec![0u64; n * words];
    for i in 0..n {
        for (j, b) in data[i * bytes..(i + 1) * bytes].iter().enumerate() {
            out[i * words + j / 8] |= (*b as u64) << (8 * (j % 8));
        }
    }
    (words, out)
}

#[inline(always)]
fn hamming_generic(a: &[u64], b: &[u64]) -> u32 {
    a.iter().zip(b).map(|(x, y)| (x ^ y).count_ones()).sum()
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "popcnt")]
unsafe fn hamming_popcnt(a: &[u64], b: &[u64]) -> u32 {
    hamming_generic(a, b)
}

/// Hamming distance of two packed descriptors (hardware popcnt when present; same count).
pub(crate) fn hamming_words(a: &[u64], b: &[u64]) -> u32 {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("popcnt") {
        // SAFETY: the CPU supports popcnt (checked just above).
        return unsafe { hamming_popcnt(a, b) };
    }
    hamming_generic(a, b)
}

#[inline(always)]
fn knn2_hamming_row_generic(q: &[u64], refs: &[u64], words: usize) -> Knn2 {
    let mut r = Knn2 { best: u32::MAX, d_best: f32::INFINITY, d_second: f32::INFINITY };
    let (mut b1, mut b2, mut i1) = (u32::MAX, u32::MAX, u32::MAX);
    for (j, d) in refs.chunks_exact(words).enumerate() {
        let h = hamming_generic(q, d);
        if h < b1 {
            b2 = b1;
            b1 = h;
            i1 = j as u32;
        } else if h < b2 {
            b2 = h;
        }
    }
    if i1 != u32::MAX {
        r.best = i1;
        r.d_best = b1 as f32;
        r.d_second = if b2 == u32::MAX { f32::INFINITY } else { b2 as f32 };
    }
    r
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "popcnt")]
unsafe fn knn2_hamming_row_popcnt(q: &[u64], refs: &[u64], words: usize) -> Knn2 {
    knn2_hamming_row_generic(q, refs, words)
}

fn knn2_hamming_row(q: &[u64], refs: &[u64], words: usize) -> Knn2 {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("popcnt") {
        // SAFETY: the CPU supports popcnt (checked just above).
        return unsafe { knn2_hamming_row_popcnt(q, refs, words) };
    }
    knn2_hamming_row_generic(q, refs, words)
}

#[inline(always)]
fn l2_sq_generic(a: &[f32], b: &[f32]) -> f32 {
    let mut acc = [0f32; 8];
    let mut ca = a.chunks_exact(8);
    let mut cb = b.chunks_exact(8);
    for (x, y) in (&mut ca).zip(&mut cb) {
        for k in 0..8 {
            let d = x[k] - y[k];
            acc[k] += d * d;
        }
    }
    let mut s: f32 = ca.remainder().iter().zip(cb.remainder()).map(|(x, y)| (x - y) * (x - y)).sum();
    s += ((acc[0] + acc[4]) + (acc[1] + acc[5])) + ((acc[2] + acc[6]) + (acc[3] + acc[7]));
    s
}

/// Squared L2 distance of two float descriptors (the portable sum order of the brute-force path).
pub(crate) fn l2_sq(a: &[f32], b: &[f32]) -> f32 {
    l2_sq_generic(a, b)
}

#[inline(always)]
fn knn2_l2_row_generic(q: &[f32], refs: &[f32], dim: usize) -> Knn2 {
    let mut r = Knn2 { best: u32::MAX, d_best: f32::INFINITY, d_second: f32::INFINITY };
    for (j, d) in refs.chunks_exact(dim).enumerate() {
        let s = l2_sq_generic(q, d);
        if s < r.d_best {
            r.d_second = r.d_best;
            r.d_best = s;
            r.best = j as u32;
        } else if s < r.d_second {
            r.d_second = s;
        }
    }
    r
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn knn2_l2_row_avx2(q: &[f32], refs: &[f32], dim: usize) -> Knn2 {
    knn2_l2_row_generic(q, refs, dim)
}

fn knn2_l2_row(q: &[f32], refs: &[f32], dim: usize) -> Knn2 {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
        // SAFETY: the CPU supports AVX2 and FMA (checked just above).
        return unsafe { knn2_l2_row_avx2(q, refs, dim) };
    }
    knn2_l2_row_generic(q, refs, dim)
}

/// 2-NN of every row of `a` among the rows of `b` (parallel over rows of `a`).
/// Distances: L2 **squared** for float descriptors, Hamming bit counts for binary ones.
pub fn knn2(a: &Descriptors, b: &Descriptors) -> Result<Vec<Knn2>> {
    match (a, b) {
        (Descriptors::Float { dim: da, data: xa }, Descriptors::Float { dim: db, data: xb }) => {
            if da != db || *da == 0 {
                return Err(FeaturesError::invalid(
                    "descriptors",
                    format!("float dimensions differ or are 0 ({da} vs {db})"),
                ));
            }
            Ok(xa.par_chunks_exact(*da).with_min_len(16).map(|q| knn2_l2_row(q, xb, *da)).collect())
        }
        (Descriptors::Binary { bytes: ba, data: xa }, Descriptors::Binary { bytes: bb, data: xb }) => {
            if ba != bb || *ba == 0 {
                return Err(FeaturesError::invalid(
                    "descriptors",
                    format!("binary lengths differ or are 0 ({ba} vs {bb} bytes)"),
                ));
            }
            let (w, pa) = pack_u64(*ba, xa);
            let (_, pb) = pack_u64(*bb, xb);
            Ok(pa.par_chunks_exact(w).with_min_len(16).map(|q| knn2_hamming_row(q, &pb, w)).collect())
        }
        _ => Err(FeaturesError::invalid("descriptors", "cannot match float (SIFT) against binary (ORB) descriptors")),
    }
}

/// Whether the ratio test accepts a best / second-best pair of raw distances
/// (`squared` = the raw distances are squared L2).
pub fn ratio_accepts(ratio: RatioTest, d_best: f32, d_second: f32, squared: bool) -> bool {
    let (d1, d2) = if squared { (d_best.sqrt(), d_second.sqrt()) } else { (d_best, d_second) };
    match ratio {
        RatioTest::None => true,
        // Lowe (2004): d1 < r · d2; no second neighbour → no evidence of distinctiveness.
        RatioTest::Lowe(r) => d2.is_finite() && d1 < r * d2,
        // vl_ubcmatch: thr · d1² < d2² (squared distances).
        RatioTest::Ubc(t) => d2.is_finite() && t * d1 * d1 < d2 * d2,
    }
}

/// The ratio test's parameter is valid: Lowe in (0, 1], ubcmatch ≥ 1.
pub(crate) fn check_ratio(ratio: RatioTest) -> Result<()> {
    match ratio {
        RatioTest::Lowe(r) if !(r > 0.0 && r <= 1.0) => {
            Err(FeaturesError::invalid("ratio", format!("Lowe ratio {r} must be in (0, 1]")))
        }
        RatioTest::Ubc(t) if !(t >= 1.0 && t.is_finite()) => {
            Err(FeaturesError::invalid("ratio", format!("ubcmatch threshold {t} must be ≥ 1")))
        }
        _ => Ok(()),
    }
}

/// Match `a` (image 1) to `b` (image 2): 2-NN, ratio test, optional mutual check.
/// Returned distances are L2 (not squared) or Hamming bit counts; sorted by `i1`.
pub fn match_features(a: &Features, b: &Features, cfg: &MatchConfig) -> Result<Vec<Match>> {
    if a.descriptors.len() != a.keypoints.len() || b.descriptors.len() != b.keypoints.len() {
        return Err(FeaturesError::invalid("features", "keypoint and descriptor counts differ"));
    }
    check_ratio(cfg.ratio)?;
    if a.is_empty() || b.is_empty() {
        return Ok(Vec::new());
    }
    let squared = matches!(a.descriptors, Descriptors::Float { .. });
    let fwd = knn2(&a.descriptors, &b.descriptors)?;
    let bwd = if cfg.mutual { Some(knn2(&b.descriptors, &a.descriptors)?) } else { None };
    let dist = |d: f32| if squared { d.sqrt() } else { d };
    Ok(fwd
        .iter()
        .enumerate()
        .filter(|(_, k)| k.best != u32::MAX && ratio_accepts(cfg.ratio, k.d_best, k.d_second, squared))
        .filter(|(i, k)| bwd.as_ref().is_none_or(|bw| bw[k.best as usize].best == *i as u32))
        .map(|(i, k)| Match { i1: i as u32, i2: k.best, distance: dist(k.d_best) })
        .collect())
}
