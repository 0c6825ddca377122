//! Scale-space extrema of the DoG (Lowe 2004 §4; OpenCV `findScaleSpaceExtrema`,
//! `adjustLocalExtrema`): 26-neighbour extrema above a pre-threshold, refined by the Taylor
//! expansion x̂ = −H⁻¹∇D (eq. 3), rejected on contrast |D(x̂)| (eq. 4) and on the principal
//! curvature ratio tr²/det < (r + 1)²/r (§4.1).
use nalgebra::{Matrix3, Vector3};

use super::blur::Plane;

/// Pixels closer than this to a border are not searched (OpenCV `SIFT_IMG_BORDER`).
pub const BORDER: usize = 5;
/// Taylor refinement steps before giving up (OpenCV `SIFT_MAX_INTERP_STEPS`).
const MAX_STEPS: usize = 5;

/// A refined extremum in octave coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Extremum {
    /// Octave index (0 = the pyramid base).
    pub octave: usize,
    /// Integer layer after refinement (1 … S).
    pub layer: usize,
    /// Integer column / row after refinement (octave px).
    pub c: usize,
    /// Integer row.
    pub r: usize,
    /// Sub-pixel offsets (column, row, layer), each in (−0.5, 0.5).
    pub xc: f32,
    /// Row offset.
    pub xr: f32,
    /// Layer offset.
    pub xi: f32,
    /// |D(x̂)| on [0, 1] intensities.
    pub contrast: f32,
}

/// Same-layer test of one row, written to vectorise: `out[x] = 1` where the pixel is above
/// `thr` and the maximum of its 3×3 neighbourhood (or below −thr and the minimum).
#[inline(always)]
fn row_candidates_impl(a: &[f32], b: &[f32], c: &[f32], thr: f32, out: &mut [u8]) {
    let n = out.len();
    let (a, b, c) = (&a[..n + 2], &b[..n + 2], &c[..n + 2]);
    let mx = |p: f32, q: f32| if p > q { p } else { q };
    let mn = |p: f32, q: f32| if p < q { p } else { q };
    for x in 0..n {
        let v = b[x + 1];
        let hi = mx(mx(mx(a[x], a[x + 1]), mx(a[x + 2], b[x])), mx(mx(b[x + 2], c[x]), mx(c[x + 1], c[x + 2])));
        let lo = mn(mn(mn(a[x], a[x + 1]), mn(a[x + 2], b[x])), mn(mn(b[x + 2], c[x]), mn(c[x + 1], c[x + 2])));
        out[x] = (((v > thr) & (v >= hi)) | ((v < -thr) & (v <= lo))) as u8;
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn row_candidates_avx2(a: &[f32], b: &[f32], c: &[f32], thr: f32, out: &mut [u8]) {
    row_candidates_impl(a, b, c, thr, out)
}

/// Runtime-dispatched same-layer candidate test (exact comparisons: both paths agree).
fn row_candidates(a: &[f32], b: &[f32], c: &[f32], thr: f32, out: &mut [u8]) {
    #[cfg(target_arch = "x86_64")]
    if is_x86_feature_detected!("avx2") {
        // SAFETY: AVX2 is present (checked just above).
        unsafe { row_candidates_avx2(a, b, c, thr, out) };
        return;
    }
    row_candidates_impl(a, b, c, thr, out)
}

/// The 18 neighbours in the layers below and above: all ≤ v (maximum) or all ≥ v (minimum).
#[inline]
fn cross_layer_extremum(prev: &Plane, next: &Plane, x: usize, y: usize, v: f32) -> bool {
    let w = prev.w;
    let idx = [
        y * w - w + x - 1,
        y * w - w + x,
        y * w - w + x + 1,
        y * w + x - 1,
        y * w + x,
        y * w + x + 1,
        y * w + w + x - 1,
        y * w + w + x,
        y * w + w + x + 1,
    ];
    if v > 0.0 {
        idx.iter().all(|&i| v >= prev.data[i] && v >= next.data[i])
    } else {
        idx.iter().all(|&i| v <= prev.data[i] && v <= next.data[i])
    }
}

/// Candidate (column, row) positions of DoG layer `i` (1 … S) of one octave, row-major.
pub fn candidates(dog: &[Plane], i: usize, thr: f32, rows: std::ops::Range<usize>) -> Vec<(usize, usize)> {
    let (prev, cur, next) = (&dog[i - 1], &dog[i], &dog[i + 1]);
    let w = cur.w;
    let mut out = vec![];
    if w < 2 * BORDER + 1 {
        return out;
    }
    let n = w - 2 * BORDER;
    let mut mask = vec![0u8; n];
    for y in rows {
        let (a, b, c) = (&cur.row(y - 1)[BORDER - 1..], &cur.row(y)[BORDER - 1..], &cur.row(y + 1)[BORDER - 1..]);
        row_candidates(a, b, c, thr, &mut mask);
        for (k, &m) in mask.iter().enumerate() {
            if m != 0 {
                let x = k + BORDER;
                if cross_layer_extremum(prev, next, x, y, cur.at(x, y)) {
                    out.push((x, y));
                }
            }
        }
    }
    out
}

/// Gradient ∇D and Hessian of the DoG at (c, r, layer), on [0, 1] intensities (OpenCV's scales).
fn derivatives(dog: &[Plane], layer: usize, c: usize, r: usize) -> (Vector3<f32>, Matrix3<f32>) {
    let (img, prev, next) = (&dog[layer], &dog[layer - 1], &dog[layer + 1]);
    let s = 1.0f32 / 255.0;
    let (ds, sds, cds) = (s * 0.5, s, s * 0.25);
    let at = |p: &Plane, x: usize, y: usize| p.at(x, y);
    let d = Vector3::new(
        (at(img, c + 1, r) - at(img, c - 1, r)) * ds,
        (at(img, c, r + 1) - at(img, c, r - 1)) * ds,
        (at(next, c, r) - at(prev, c, r)) * ds,
    );
    let v2 = at(img, c, r) * 2.0;
    let dxx = (at(img, c + 1, r) + at(img, c - 1, r) - v2) * sds;
    let dyy = (at(img, c, r + 1) + at(img, c, r - 1) - v2) * sds;
    let dss = (at(next, c, r) + at(prev, c, r) - v2) * sds;
    let dxy = (at(img, c + 1, r + 1) - at(img, c - 1, r + 1) - at(img, c + 1, r - 1) + at(img, c - 1, r - 1)) * cds;
    let dxs = (at(next, c + 1, r) - at(next, c - 1, r) - at(prev, c + 1, r) + at(prev, c - 1, r)) * cds;
    let dys = (at(next, c, r + 1) - at(next, c, r - 1) - at(prev, c, r + 1) + at(prev, c, r - 1)) * cds;
    (d, Matrix3::new(dxx, dxy, dxs, dxy, dyy, dys, dxs, dys, dss))
}

/// Refine a candidate at (layer, column, row) (Lowe eq. 3, up to 5 steps), then apply the contrast and edge tests.
pub fn refine(
    dog: &[Plane],
    octave: usize,
    (layer, c, r): (usize, usize, usize),
    s: usize,
    contrast_thr: f32,
    edge_thr: f32,
) -> Option<Extremum> {
    let (w, h) = (dog[0].w, dog[0].h);
    let (mut layer, mut c, mut r) = (layer as i64, c as i64, r as i64);
    let (mut xi, mut xr, mut xc) = (0f32, 0f32, 0f32);
    let mut converged = false;
    for _ in 0..MAX_STEPS {
        let (d, hm) = derivatives(dog, layer as usize, c as usize, r as usize);
        let x = hm.lu().solve(&d).unwrap_or_else(Vector3::zeros);
        (xc, xr, xi) = (-x[0], -x[1], -x[2]);
        if xi.abs() < 0.5 && xr.abs() < 0.5 && xc.abs() < 0.5 {
            converged = true;
            break;
        }
        let big = (i32::MAX / 3) as f32;
        if !(xi.abs() <= big && xr.abs() <= big && xc.abs() <= big) {
            return None;
        }
        c += xc.round() as i64;
        r += xr.round() as i64;
        layer += xi.round() as i64;
        if layer < 1
            || layer > s as i64
            || c < BORDER as i64
            || c >= (w - BORDER) as i64
            || r < BORDER as i64
            || r >= (h - BORDER) as i64
        {
            return None;
        }
    }
    if !converged {
        return None;
    }
    let (l, cu, ru) = (layer as usize, c as usize, r as usize);
    let (d, hm) = derivatives(dog, l, cu, ru);
    let t = d.dot(&Vector3::new(xc, xr, xi));
    let contr = dog[l].at(cu, ru) / 255.0 + t * 0.5;
    if contr.abs() * (s as f32) < contrast_thr {
        return None;
    }
    let (dxx, dyy, dxy) = (hm[(0, 0)], hm[(1, 1)], hm[(0, 1)]);
    let tr = dxx + dyy;
    let det = dxx * dyy - dxy * dxy;
    if det <= 0.0 || tr * tr * edge_thr >= (edge_thr + 1.0) * (edge_thr + 1.0) * det {
        return None;
    }
    Some(Extremum { octave, layer: l, c: cu, r: ru, xc, xr, xi, contrast: contr.abs() })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vector_and_scalar_candidate_tests_agree() {
        let mut s = 7u32;
        let mut rnd = || {
            s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            ((s >> 20) as f32 - 2048.0) / 256.0
        };
        let rows: Vec<Vec<f32>> = (0..3).map(|_| (0..203).map(|_| rnd()).collect()).collect();
        let mut a = vec![0u8; 201];
        let mut b = vec![0u8; 201];
        row_candidates(&rows[0], &rows[1], &rows[2], 1.0, &mut a);
        row_candidates_impl(&rows[0], &rows[1], &rows[2], 1.0, &mut b);
        assert_eq!(a, b);
        // Independent check: brute force over the 3×3 window.
        for x in 0..201 {
            let v = rows[1][x + 1];
            let win: Vec<f32> = (0..3).flat_map(|j| rows[j][x..x + 3].to_vec()).collect();
            let e = (v > 1.0 && win.iter().all(|&q| v >= q)) || (v < -1.0 && win.iter().all(|&q| v <= q));
            assert_eq!(a[x] != 0, e, "x = {x}");
        }
    }

    #[test]
    fn a_quadratic_blob_is_refined_to_its_peak() {
        // D(x, y, s) = 40 − (x − 10.3)² − (y − 9.8)² − 4(s − 1.2)², peak at (10.3, 9.8, 1.2).
        let (w, h) = (21, 21);
        let dog: Vec<Plane> = (0..4)
            .map(|s| Plane {
                w,
                h,
                data: (0..w * h)
                    .map(|i| {
                        let (x, y) = ((i % w) as f32, (i / w) as f32);
                        40.0 - (x - 10.3).powi(2) - (y - 9.8).powi(2) - 4.0 * (s as f32 - 1.2).powi(2)
                    })
                    .collect(),
            })
            .collect();
        let e = refine(&dog, 0, (1, 10, 10), 2, 0.04, 10.0).expect("kept");
        assert_eq!((e.c, e.r, e.layer), (10, 10, 1));
        assert!((e.xc - 0.3).abs() < 1e-4 && (e.xr + 0.2).abs() < 1e-4 && (e.xi - 0.2).abs() < 1e-4, "{e:?}");
        // D at the peak = 40 (on 0…255 grey levels) → 40/255.
        assert!((e.contrast - 40.0 / 255.0).abs() < 1e-5);
    }
}
