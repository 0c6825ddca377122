//! Guided matching along epipolar lines (H&Z §11.1 "guided matching"): with a fundamental matrix
//! F (x₂ᵀ F x₁ = 0), keypoint i of image 1 is compared only with the keypoints of image 2 within
//! `tol_px` of its epipolar line l₂ = F x₁ (H&Z eq. 9.1), and for the mutual check keypoint j of
//! image 2 only with those of image 1 within `tol_px` of l₁ = Fᵀ x₂. The 2-NN, ratio test and
//! mutual check are those of [`crate::matching`] restricted to these bands.
//!
//! Keypoints are bucketed in a grid of square cells; a line visits the cells of its band column
//! by column (or row by row when it is steeper than 45°). Each query's 2-NN depends only on its
//! candidate set and ties go to the lower index, so the output is identical for any thread count.
use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use crate::error::{FeaturesError, Result};
use crate::keypoint::{Descriptors, Features, Match, MatchConfig};
use crate::matching::{hamming_words, l2_sq, pack_u64, ratio_accepts, Knn2};

/// Side of a grid cell, px.
const CELL: f64 = 16.0;

/// Keypoint positions bucketed in a grid of `CELL`-px cells (indices in increasing order per cell).
struct Grid {
    cols: usize,
    rows: usize,
    start: Vec<u32>,
    idx: Vec<u32>,
    pts: Vec<[f64; 2]>,
}

impl Grid {
    fn new(f: &Features) -> Grid {
        let pts = f.points();
        let (mut mx, mut my) = (0f64, 0f64);
        for p in &pts {
            if p[0].is_finite() && p[1].is_finite() {
                mx = mx.max(p[0]);
                my = my.max(p[1]);
            }
        }
        let cols = (mx / CELL).floor() as usize + 1;
        let rows = (my / CELL).floor() as usize + 1;
        let cell_of = |p: &[f64; 2]| {
            if !(p[0] >= 0.0 && p[1] >= 0.0 && p[0].is_finite() && p[1].is_finite()) {
                return None;
            }
            Some((p[1] / CELL) as usize * cols + (p[0] / CELL) as usize)
        };
        let mut count = vec![0u32; cols * rows + 1];
        for p in &pts {
            if let Some(c) = cell_of(p) {
                count[c + 1] += 1;
            }
        }
        for c in 0..cols * rows {
            count[c + 1] += count[c];
        }
        let mut fill = count.clone();
        let mut idx = vec![0u32; count[cols * rows] as usize];
        for (i, p) in pts.iter().enumerate() {
            if let Some(c) = cell_of(p) {
                idx[fill[c] as usize] = i as u32;
                fill[c] += 1;
            }
        }
        Grid { cols, rows, start: count, idx, pts }
    }

    /// Call `visit(j)` for every point within `tol` of the line a x + b y + c = 0 (a² + b² = 1)
    /// with x in `[xs[0], xs[1]]`.
    fn for_each_near(&self, l: [f64; 3], tol: f64, xs: [f64; 2], mut visit: impl FnMut(usize)) {
        let [a, b, c] = l;
        if !(xs[1] >= 0.0 && xs[0] <= xs[1]) {
            return;
        }
        // cell columns overlapping the x interval
        let (c0, c1) = ((xs[0].max(0.0) / CELL) as usize, ((xs[1] / CELL) as usize).min(self.cols - 1));
        if c0 > c1 {
            return;
        }
        let horizontal = b.abs() >= a.abs();
        let (outer, n_inner) = if horizontal { (c0..c1 + 1, self.rows) } else { (0..self.rows, c1 + 1) };
        // along the outer axis u, the line's inner coordinate is v(u) = −(p u + c) / q
        let (p, q) = if horizontal { (a, b) } else { (b, a) };
        let half = tol / q.abs();
        for o in outer {
            let (u0, u1) = (o as f64 * CELL, (o + 1) as f64 * CELL);
            let (v0, v1) = (-(p * u0 + c) / q, -(p * u1 + c) / q);
            let (lo, hi) = (v0.min(v1) - half, v0.max(v1) + half);
            if hi < 0.0 || !(lo.is_finite() && hi.is_finite()) {
                continue;
            }
            let (mut i0, i1) = ((lo.max(0.0) / CELL) as usize, ((hi / CELL) as usize).min(n_inner - 1));
            if !horizontal {
                i0 = i0.max(c0);
            }
            if i0 >= n_inner || i0 > i1 {
                continue;
            }
            for i in i0..=i1 {
                let cell = if horizontal { i * self.cols + o } else { o * self.cols + i };
                for &j in &self.idx[self.start[cell] as usize..self.start[cell + 1] as usize] {
                    let pt = self.pts[j as usize];
                    if (a * pt[0] + b * pt[1] + c).abs() <= tol && pt[0] >= xs[0] && pt[0] <= xs[1] {
                        visit(j as usize);
                    }
                }
            }
        }
    }
}

/// The line l = M x (x = (x, y, 1)) scaled to a² + b² = 1; `None` when degenerate.
fn line(m: &Matrix3<f64>, p: [f64; 2]) -> Option<[f64; 3]> {
    let l = m * Vector3::new(p[0], p[1], 1.0);
    let n = l[0].hypot(l[1]);
    (n > 1e-300 && n.is_finite() && l[2].is_finite()).then(|| [l[0] / n, l[1] / n, l[2] / n])
}

/// Descriptor distance between row i of one set and row j of the other (Hamming count or L2²).
enum Dist {
    Bin { words: usize, a: Vec<u64>, b: Vec<u64> },
    Float { dim: usize },
}

/// 2-NN of every query among the candidates in its epipolar band (ties: lower index).
fn knn2_banded(
    q: &Features,
    grid: &Grid,
    m: &Matrix3<f64>,
    tol: f64,
    dx: Option<[f64; 2]>,
    dist: &(dyn Fn(usize, usize) -> f32 + Sync),
) -> Vec<Knn2> {
    q.keypoints
        .par_iter()
        .enumerate()
        .with_min_len(64)
        .map(|(i, k)| {
            let mut out = Knn2 { best: u32::MAX, d_best: f32::INFINITY, d_second: f32::INFINITY };
            let Some(l) = line(m, [k.x, k.y]) else { return out };
            let xs = dx.map_or([f64::NEG_INFINITY, f64::INFINITY], |[lo, hi]| [k.x + lo, k.x + hi]);
            grid.for_each_near(l, tol, xs, |j| {
                let d = dist(i, j);
                if d < out.d_best || (d == out.d_best && (j as u32) < out.best) {
                    if out.best != u32::MAX {
                        out.d_second = out.d_best;
                    }
                    out.d_best = d;
                    out.best = j as u32;
                } else if d < out.d_second {
                    out.d_second = d;
                }
            });
            out
        })
        .collect()
}

/// Match `a` (image 1) to `b` (image 2) along the epipolar lines of `f` (x₂ᵀ F x₁ = 0): 2-NN
/// among the keypoints within `tol_px` of the line and, with `dx = Some([lo, hi])`, with
/// x₂ − x₁ in [lo, hi] (a disparity range), ratio test, optional mutual check (the reverse 2-NN
/// within `tol_px` of Fᵀ x₂, x₁ − x₂ in [−hi, −lo]). Distances as [`crate::match_features`];
/// sorted by `i1`.
pub fn match_features_guided(
    a: &Features,
    b: &Features,
    f: &Matrix3<f64>,
    tol_px: f64,
    dx: Option<[f64; 2]>,
    cfg: &MatchConfig,
) -> Result<Vec<Match>> {
    if a.descriptors.len() != a.keypoints.len() || b.descriptors.len() != b.keypoints.len() {
        return Err(FeaturesError::invalid("features", "keypoint and descriptor counts differ"));
    }
    if !(tol_px > 0.0 && tol_px.is_finite()) {
        return Err(FeaturesError::invalid("tol_px", format!("{tol_px} (need a finite value > 0)")));
    }
    if let Some([lo, hi]) = dx {
        if !(lo <= hi && lo.is_finite() && hi.is_finite()) {
            return Err(FeaturesError::invalid("dx range", format!("[{lo}, {hi}] (need finite lo ≤ hi)")));
        }
    }
    if f.iter().any(|v| !v.is_finite()) {
        return Err(FeaturesError::invalid("fundamental matrix", "non-finite entries"));
    }
    crate::matching::check_ratio(cfg.ratio)?;
    if a.is_empty() || b.is_empty() {
        return Ok(Vec::new());
    }
    let dist = match (&a.descriptors, &b.descriptors) {
        (Descriptors::Binary { bytes: ba, data: xa }, Descriptors::Binary { bytes: bb, data: xb })
            if ba == bb && *ba > 0 =>
        {
            let (words, pa) = pack_u64(*ba, xa);
            Dist::Bin { words, a: pa, b: pack_u64(*bb, xb).1 }
        }
        (Descriptors::Float { dim: da, .. }, Descriptors::Float { dim: db, .. }) if da == db && *da > 0 => {
            Dist::Float { dim: *da }
        }
        _ => return Err(FeaturesError::invalid("descriptors", "types or lengths differ between the two images")),
    };
    let squared = matches!(dist, Dist::Float { .. });
    // d(i in a, j in b) and its mirror
    let fwd_d = |i: usize, j: usize| -> f32 {
        match (&dist, &a.descriptors, &b.descriptors) {
            (Dist::Bin { words, a: pa, b: pb }, _, _) => {
                hamming_words(&pa[i * words..(i + 1) * words], &pb[j * words..(j + 1) * words]) as f32
            }
            (Dist::Float { dim }, Descriptors::Float { data: xa, .. }, Descriptors::Float { data: xb, .. }) => {
                l2_sq(&xa[i * dim..(i + 1) * dim], &xb[j * dim..(j + 1) * dim])
            }
            _ => f32::INFINITY,
        }
    };
    let bwd_d = |j: usize, i: usize| fwd_d(i, j);
    let (ga, gb) = (Grid::new(a), Grid::new(b));
    let ft = f.transpose();
    let fwd = knn2_banded(a, &gb, f, tol_px, dx, &fwd_d);
    let bwd =
        if cfg.mutual { Some(knn2_banded(b, &ga, &ft, tol_px, dx.map(|[lo, hi]| [-hi, -lo]), &bwd_d)) } else { None };
    let dist_out = |d: f32| if squared { d.sqrt() } else { d };
    Ok(fwd
        .iter()
        .enumerate()
        .filter(|(_, k)| k.best != u32::MAX && ratio_accepts(cfg.ratio, k.d_best, k.d_second, squared))
        .filter(|(i, k)| bwd.as_ref().is_none_or(|bw| bw[k.best as usize].best == *i as u32))
        .map(|(i, k)| Match { i1: i as u32, i2: k.best, distance: dist_out(k.d_best) })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::keypoint::{Keypoint, RatioTest};

    fn kp(x: f64, y: f64) -> Keypoint {
        Keypoint { x, y, size_px: 31.0, angle_rad: 0.0, response: 0.0, octave: 0 }
    }

    fn feats(pts: &[[f64; 2]], desc: &[u8]) -> Features {
        Features {
            keypoints: pts.iter().map(|p| kp(p[0], p[1])).collect(),
            descriptors: Descriptors::Binary { bytes: 1, data: desc.to_vec() },
        }
    }

    #[test]
    fn grid_band_finds_exactly_the_points_near_the_line() {
        // points on a lattice; the line y = 0.5 x + 10 (a x + b y + c = 0 normalised); compare
        // with a linear scan, for a shallow and a steep line
        let pts: Vec<[f64; 2]> = (0..40).flat_map(|i| (0..30).map(move |j| [i as f64 * 7.3, j as f64 * 5.9])).collect();
        let f = feats(&pts, &vec![0u8; pts.len()]);
        let g = Grid::new(&f);
        for (a, b, c) in [(0.5, -1.0, 10.0), (1.0, -0.2, -50.0), (0.0, 1.0, -88.5), (1.0, 0.0, -100.0)] {
            let n = f64::hypot(a, b);
            let l = [a / n, b / n, c / n];
            for xs in [[f64::NEG_INFINITY, f64::INFINITY], [40.0, 130.5], [-10.0, 3.0]] {
                let mut got = vec![];
                g.for_each_near(l, 3.0, xs, |j| got.push(j));
                got.sort();
                let want: Vec<usize> = (0..pts.len())
                    .filter(|&j| (l[0] * pts[j][0] + l[1] * pts[j][1] + l[2]).abs() <= 3.0)
                    .filter(|&j| pts[j][0] >= xs[0] && pts[j][0] <= xs[1])
                    .collect();
                assert_eq!(got, want, "line {l:?} x in {xs:?}");
                assert!(!want.is_empty() || xs[0].is_finite(), "line {l:?}: the unrestricted band is not empty");
            }
        }
    }

    #[test]
    fn guided_matches_respect_the_epipolar_band() {
        // rectified geometry: F = [e']ₓ with e' = (1, 0, 0) → epipolar lines are rows (y₂ = y₁).
        let f = Matrix3::new(0.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 1.0, 0.0);
        // left: three points; right: an exact descriptor twin off the row (rejected by the band)
        // and a near twin on the row (accepted)
        let a = feats(&[[10.0, 10.0], [50.0, 40.0], [90.0, 70.0]], &[0b0000_1111, 0b1111_0000, 0b1010_1010]);
        let b = feats(
            &[[5.0, 30.0], [8.0, 10.5], [45.0, 40.0], [80.0, 70.2]],
            &[0b0000_1111, 0b0000_1110, 0b1111_0000, 0b1010_1010],
        );
        let cfg = MatchConfig { ratio: RatioTest::None, mutual: true };
        let m = match_features_guided(&a, &b, &f, 1.0, None, &cfg).unwrap();
        let pairs: Vec<(u32, u32, f32)> = m.iter().map(|m| (m.i1, m.i2, m.distance)).collect();
        assert_eq!(pairs, vec![(0, 1, 1.0), (1, 2, 0.0), (2, 3, 0.0)]);
        // with a wide band the exact twin at (5, 30) wins for point 0
        let m = match_features_guided(&a, &b, &f, 25.0, None, &cfg).unwrap();
        assert_eq!((m[0].i1, m[0].i2), (0, 0));
        // a disparity range x₂ − x₁ ∈ [−4, 0] excludes the twin at Δx = −5 again
        let m = match_features_guided(&a, &b, &f, 25.0, Some([-4.0, 0.0]), &cfg).unwrap();
        assert_eq!((m[0].i1, m[0].i2), (0, 1));
        assert!(match_features_guided(&a, &b, &f, 0.0, None, &cfg).is_err());
        assert!(match_features_guided(&a, &b, &f, 1.0, Some([1.0, 0.0]), &cfg).is_err());
    }
}
