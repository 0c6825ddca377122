//! Dominant orientations (Lowe 2004 §5; OpenCV `calcOrientationHist`): 36-bin histogram of
//! gradient directions weighted by magnitude and a Gaussian of σ = 1.5·scale over radius
//! 3·1.5·scale, smoothed by [1 4 6 4 1]/16; every local peak ≥ 0.8 · max gives a keypoint, its
//! angle refined by a parabola through the peak and its neighbours.
use super::blur::Plane;
use super::fastmath::mag_ang;

/// Histogram bins.
pub const BINS: usize = 36;
/// Gaussian σ of the weighting, in units of the keypoint scale (OpenCV `SIFT_ORI_SIG_FCTR`).
pub const SIG_FCTR: f32 = 1.5;
/// Window radius, in units of the keypoint scale (OpenCV `SIFT_ORI_RADIUS`).
pub const RADIUS_FCTR: f32 = 3.0 * SIG_FCTR;
/// Secondary peaks down to this fraction of the maximum spawn keypoints.
const PEAK_RATIO: f32 = 0.8;

/// Smoothed orientation histogram around (x, y) of `img` (radius and σ in octave px).
pub fn histogram(img: &Plane, x: usize, y: usize, radius: i64, sigma: f32) -> [f32; BINS] {
    let scale = -1.0 / (2.0 * sigma * sigma);
    // exp(−(i² + j²)/2σ²) = e(i)·e(j).
    let e: Vec<f32> = (-radius..=radius).map(|i| ((i * i) as f32 * scale).exp()).collect();
    let n = (2 * radius + 1) as usize;
    let (mut dx, mut dy, mut wt) = (Vec::with_capacity(n * n), Vec::with_capacity(n * n), Vec::with_capacity(n * n));
    let (w, h) = (img.w as i64, img.h as i64);
    for i in -radius..=radius {
        let yy = y as i64 + i;
        if yy <= 0 || yy >= h - 1 {
            continue;
        }
        let (up, row, dn) = (img.row(yy as usize - 1), img.row(yy as usize), img.row(yy as usize + 1));
        let ei = e[(i + radius) as usize];
        let j0 = (-radius).max(1 - x as i64);
        let j1 = radius.min(w - 2 - x as i64);
        for j in j0..=j1 {
            let xx = (x as i64 + j) as usize;
            dx.push(row[xx + 1] - row[xx - 1]);
            dy.push(up[xx] - dn[xx]);
            wt.push(ei * e[(j + radius) as usize]);
        }
    }
    let mut mag = vec![0f32; dx.len()];
    let mut ang = vec![0f32; dx.len()];
    mag_ang(&dx, &dy, &mut mag, &mut ang);
    let mut t = [0f32; BINS + 4];
    for k in 0..dx.len() {
        let mut b = super::descriptor::round_even(ang[k] * (BINS as f32 / 360.0)) as i64;
        if b >= BINS as i64 {
            b -= BINS as i64;
        }
        if b < 0 {
            b += BINS as i64;
        }
        t[b as usize + 2] += wt[k] * mag[k];
    }
    t[1] = t[BINS + 1];
    t[0] = t[BINS];
    t[BINS + 2] = t[2];
    t[BINS + 3] = t[3];
    std::array::from_fn(|i| {
        (t[i] + t[i + 4]) * (1.0 / 16.0) + (t[i + 1] + t[i + 3]) * (4.0 / 16.0) + t[i + 2] * (6.0 / 16.0)
    })
}

/// Keypoint angles (degrees, OpenCV convention 360 − direction) of the histogram's peaks.
pub fn peak_angles(hist: &[f32; BINS]) -> Vec<f32> {
    let max = hist.iter().cloned().fold(0f32, f32::max);
    let thr = max * PEAK_RATIO;
    let mut out = vec![];
    for j in 0..BINS {
        let l = if j > 0 { j - 1 } else { BINS - 1 };
        let r = if j < BINS - 1 { j + 1 } else { 0 };
        if hist[j] > hist[l] && hist[j] > hist[r] && hist[j] >= thr {
            let mut bin = j as f32 + 0.5 * (hist[l] - hist[r]) / (hist[l] - 2.0 * hist[j] + hist[r]);
            if bin < 0.0 {
                bin += BINS as f32;
            } else if bin >= BINS as f32 {
                bin -= BINS as f32;
            }
            let mut a = 360.0 - (360.0 / BINS as f32) * bin;
            if (a - 360.0).abs() < f32::EPSILON {
                a = 0.0;
            }
            out.push(a);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_ramp_gives_one_peak_along_its_gradient() {
        // I = 2x + 0·y: dx = 4 everywhere, dy = 0 → direction 0°, keypoint angle 360 − 0 → 0.
        let img = Plane { w: 41, h: 41, data: (0..41 * 41).map(|i| 2.0 * (i % 41) as f32).collect() };
        let h = histogram(&img, 20, 20, 8, 3.0);
        assert_eq!(peak_angles(&h), vec![0.0]);
        // I = 3y (rows increase downwards): dy = up − down = −6 → direction 270°, angle 90°.
        let img = Plane { w: 41, h: 41, data: (0..41 * 41).map(|i| 3.0 * (i / 41) as f32).collect() };
        let a = peak_angles(&histogram(&img, 20, 20, 8, 3.0));
        assert_eq!(a.len(), 1);
        assert!((a[0] - 90.0).abs() < 1e-3, "{a:?}");
    }
}
