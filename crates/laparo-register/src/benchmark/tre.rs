//! Target registration error (TRE) at mesh nodes and its dependence on the distance to the nearest incision
//! landmark (Fig. 5.8).
use crate::distance::build_tree;
use crate::error::{RegisterError, Result};
use kiddo::SquaredEuclidean;
use nalgebra::Vector3;

/// Distance bins of Fig. 5.8 (mm): 0–5, 5–10, 10–20, 20–40, 40–80, > 80.
pub const DISTANCE_BIN_EDGES_MM: [f64; 7] = [0.0, 5.0, 10.0, 20.0, 40.0, 80.0, f64::INFINITY];

/// Summary statistics of a set of errors (mm).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Stats {
    /// Number of values.
    pub n: usize,
    /// Mean (mm).
    pub mean: f64,
    /// Population standard deviation (mm).
    pub std: f64,
    /// Median (mm).
    pub median: f64,
    /// 95th percentile (nearest rank, mm).
    pub p95: f64,
    /// Maximum (mm).
    pub max: f64,
}

impl Stats {
    /// Statistics of `v` (all zero for an empty slice). NaN values are an error of the caller: they propagate.
    pub fn of(v: &[f64]) -> Stats {
        if v.is_empty() {
            return Stats::default();
        }
        let n = v.len();
        let mean = v.iter().sum::<f64>() / n as f64;
        let var = v.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / n as f64;
        let mut s = v.to_vec();
        s.sort_by(|a, b| a.total_cmp(b));
        let median = if n % 2 == 1 { s[n / 2] } else { 0.5 * (s[n / 2 - 1] + s[n / 2]) };
        let rank = ((0.95 * n as f64).ceil() as usize).clamp(1, n) - 1;
        Stats { n, mean, std: var.sqrt(), median, p95: s[rank], max: s[n - 1] }
    }
}

/// Node-wise Euclidean error |x_registered − x_ground_truth| (mm). Lengths must agree and be finite.
pub fn node_errors(registered: &[Vector3<f64>], ground_truth: &[Vector3<f64>]) -> Result<Vec<f64>> {
    if registered.len() != ground_truth.len() {
        return Err(RegisterError::bad(
            "TRE",
            format!("{} registered nodes, {} ground-truth nodes", registered.len(), ground_truth.len()),
        ));
    }
    registered
        .iter()
        .zip(ground_truth)
        .enumerate()
        .map(|(i, (a, b))| {
            let e = (a - b).norm();
            if e.is_finite() {
                Ok(e)
            } else {
                Err(RegisterError::bad("TRE", format!("node {i} has a non-finite position")))
            }
        })
        .collect()
}

/// Distance (mm) from each point to the nearest of `landmarks` (rest configuration).
pub fn distance_to_nearest(points: &[Vector3<f64>], landmarks: &[Vector3<f64>]) -> Result<Vec<f64>> {
    if landmarks.is_empty() {
        return Err(RegisterError::bad("landmarks", "no landmark to measure distances to"));
    }
    let tree = build_tree(landmarks);
    Ok(points.iter().map(|p| tree.nearest_one::<SquaredEuclidean>(&[p[0], p[1], p[2]]).distance.sqrt()).collect())
}

/// Errors of one distance bin (Fig. 5.8).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct BinStats {
    /// Lower edge (mm, inclusive).
    pub lo_mm: f64,
    /// Upper edge (mm, exclusive; infinite for the last bin, `null` in JSON).
    #[serde(with = "inf_as_null")]
    pub hi_mm: f64,
    /// Statistics of the errors in the bin.
    pub stats: Stats,
}

/// JSON has no infinity: an infinite edge is written as `null` and read back as +∞.
mod inf_as_null {
    use serde::{Deserialize, Deserializer, Serializer};
    pub fn serialize<S: Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
        if v.is_finite() {
            s.serialize_f64(*v)
        } else {
            s.serialize_none()
        }
    }
    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
        Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::INFINITY))
    }
}

/// The far field of the v2 protocol: points at least this far (mm) from the source lip polylines; a method's
/// far-field figure is its excess TRE there over "none"'s.
pub const FAR_FIELD_MM: f64 = 40.0;

/// Scores of one run at the common evaluation points (v2 protocol).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PointScores {
    /// TRE over every evaluation point (mm).
    pub tre: Stats,
    /// TRE over the crack-face points only (mm).
    pub crack_faces: Stats,
    /// TRE by distance to the continuous source lip polylines ([`DISTANCE_BIN_EDGES_MM`]).
    pub bins_lip: Vec<BinStats>,
    /// TRE by distance to the true crack surface ([`DISTANCE_BIN_EDGES_MM`]).
    pub bins_crack: Vec<BinStats>,
    /// Mean TRE over the points at least [`FAR_FIELD_MM`] from the lips (mm; 0 when there is none).
    pub far_mean_mm: f64,
    /// Points at least [`FAR_FIELD_MM`] from the lips.
    pub far_n: usize,
}

impl PointScores {
    /// Score registered point positions `x` against `points.ground_truth`.
    pub fn of(points: &super::points::EvalPoints, x: &[Vector3<f64>]) -> Result<PointScores> {
        let e = node_errors(x, &points.ground_truth)
            .map_err(|err| RegisterError::bad("TRE at the evaluation points", err.to_string()))?;
        let face: Vec<f64> = e
            .iter()
            .zip(&points.kind)
            .filter(|(_, k)| **k == super::points::PointKind::CrackFace)
            .map(|(e, _)| *e)
            .collect();
        let far: Vec<f64> =
            e.iter().zip(&points.d_lip_mm).filter(|(_, d)| **d >= FAR_FIELD_MM).map(|(e, _)| *e).collect();
        Ok(PointScores {
            tre: Stats::of(&e),
            crack_faces: Stats::of(&face),
            bins_lip: binned(&e, &points.d_lip_mm, &DISTANCE_BIN_EDGES_MM),
            bins_crack: binned(&e, &points.d_crack_mm, &DISTANCE_BIN_EDGES_MM),
            far_mean_mm: Stats::of(&far).mean,
            far_n: far.len(),
        })
    }

    /// Mean TRE over the points within `hi_mm` of the lips (the bins below `hi_mm` pooled by count; NaN when
    /// they hold no point). `hi_mm` must be a bin edge.
    pub fn near_lip_mean_mm(&self, hi_mm: f64) -> f64 {
        pooled_below(&self.bins_lip, hi_mm)
    }

    /// Mean TRE over the points within `hi_mm` of the true crack (as [`PointScores::near_lip_mean_mm`]).
    pub fn near_crack_mean_mm(&self, hi_mm: f64) -> f64 {
        pooled_below(&self.bins_crack, hi_mm)
    }
}

/// The mean over the bins whose upper edge is ≤ `hi_mm`, pooled by their counts (NaN without a point).
pub fn pooled_below(bins: &[BinStats], hi_mm: f64) -> f64 {
    let (n, sum) = bins
        .iter()
        .filter(|b| b.hi_mm <= hi_mm)
        .fold((0usize, 0.0), |(n, s), b| (n + b.stats.n, s + b.stats.mean * b.stats.n as f64));
    if n == 0 {
        f64::NAN
    } else {
        sum / n as f64
    }
}

/// Errors grouped by the distance bins `edges` (ascending, mm): bin k holds edges[k] ≤ d < edges[k+1].
pub fn binned(errors: &[f64], distances: &[f64], edges: &[f64]) -> Vec<BinStats> {
    (0..edges.len().saturating_sub(1))
        .map(|k| {
            let v: Vec<f64> = errors
                .iter()
                .zip(distances)
                .filter(|(_, &d)| d >= edges[k] && d < edges[k + 1])
                .map(|(&e, _)| e)
                .collect();
            BinStats { lo_mm: edges[k], hi_mm: edges[k + 1], stats: Stats::of(&v) }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stats_by_hand() {
        let s = Stats::of(&[1.0, 2.0, 3.0, 4.0]);
        assert_eq!(s.n, 4);
        assert_eq!(s.mean, 2.5);
        assert!((s.std - 1.25f64.sqrt()).abs() < 1e-15);
        assert_eq!(s.median, 2.5);
        assert_eq!(s.p95, 4.0);
        assert_eq!(s.max, 4.0);
        assert_eq!(Stats::of(&[]), Stats::default());
    }

    #[test]
    fn errors_and_bins_by_hand() {
        let gt = vec![Vector3::zeros(), Vector3::new(10.0, 0.0, 0.0), Vector3::new(50.0, 0.0, 0.0)];
        let reg = vec![Vector3::new(0.0, 3.0, 4.0), Vector3::new(10.0, 1.0, 0.0), Vector3::new(50.0, 0.0, 2.0)];
        let e = node_errors(&reg, &gt).unwrap();
        assert_eq!(e, vec![5.0, 1.0, 2.0]);
        let d = distance_to_nearest(&gt, &[Vector3::new(-1.0, 0.0, 0.0)]).unwrap();
        assert_eq!(d, vec![1.0, 11.0, 51.0]);
        let b = binned(&e, &d, &DISTANCE_BIN_EDGES_MM);
        assert_eq!(b.len(), 6);
        assert_eq!(b[0].stats.n, 1);
        assert_eq!(b[0].stats.mean, 5.0);
        assert_eq!(b[2].stats.mean, 1.0); // 10–20
        assert_eq!(b[4].stats.mean, 2.0); // 40–80
        assert_eq!(b[5].stats.n, 0);
    }

    #[test]
    fn mismatched_or_nan_is_an_error() {
        assert!(node_errors(&[Vector3::zeros()], &[]).is_err());
        let e = node_errors(&[Vector3::new(f64::NAN, 0.0, 0.0)], &[Vector3::zeros()]).unwrap_err().to_string();
        assert!(e.contains("node 0"), "{e}");
        assert!(distance_to_nearest(&[Vector3::zeros()], &[]).is_err());
    }
}
