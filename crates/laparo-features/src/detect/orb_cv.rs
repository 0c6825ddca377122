//! ORB as OpenCV's `cv::ORB` computes it (Rublee et al. 2011; `modules/features2d/src/orb.cpp`):
//! a pyramid (bilinear, factor 1.2), FAST-9 with 3×3 non-maximum suppression on every level,
//! the level's keypoint budget kept by FAST score (2×) then Harris score (eq. of Harris &
//! Stephens, 7×7 Sobel window, k = 0.04), the intensity-centroid orientation (radius 15) and
//! the steered BRIEF test on the level blurred by a 7×7 Gaussian (σ = 2).
use laparo_core::image::Image;
use rayon::prelude::*;

use super::orb::OrbParams;
use super::orb_pattern::BIT_PATTERN_31;
use crate::keypoint::{Descriptors, Features, Keypoint};

/// Keypoints closer than this to a level's border are dropped (OpenCV `edgeThreshold`).
const EDGE: usize = 31;
/// Half of the BRIEF / orientation patch (OpenCV `patchSize` 31).
const HALF_PATCH: i32 = 15;
/// The 16-pixel Bresenham circle of radius 3 (dx, dy), contiguous.
const CIRCLE: [(i32, i32); 16] = [
    (0, 3),
    (1, 3),
    (2, 2),
    (3, 1),
    (3, 0),
    (3, -1),
    (2, -2),
    (1, -3),
    (0, -3),
    (-1, -3),
    (-2, -2),
    (-3, -1),
    (-3, 0),
    (-3, 1),
    (-2, 2),
    (-1, 3),
];

/// Keypoint budget per level: geometric series with ratio 1/scale (OpenCV).
fn per_level(n: usize, levels: usize, scale: f64) -> Vec<usize> {
    let f = 1.0 / scale;
    let mut desired = n as f64 * (1.0 - f) / (1.0 - f.powi(levels as i32));
    let mut out = vec![0; levels];
    let mut sum = 0;
    for o in out.iter_mut().take(levels - 1) {
        *o = desired.round() as usize;
        sum += *o;
        desired *= f;
    }
    out[levels - 1] = n.saturating_sub(sum);
    out
}

/// Source taps of a pixel-centre-aligned bilinear resize from `n` to `m` samples: (i₀, i₁, weight
/// of i₁ in 1/256), position (i + ½)·n/m − ½ clamped to [0, n − 1] (OpenCV INTER_LINEAR_EXACT).
fn taps(n: usize, m: usize) -> Vec<(usize, usize, u32)> {
    let s = n as f64 / m as f64;
    (0..m)
        .map(|i| {
            let f = ((i as f64 + 0.5) * s - 0.5).clamp(0.0, (n - 1) as f64);
            let i0 = f.floor() as usize;
            let wgt = ((f - i0 as f64) * 256.0).round() as u32;
            let i1 = (i0 + 1).min(n - 1);
            if wgt == 256 {
                (i1, i1, 0)
            } else {
                (i0, i1, wgt)
            }
        })
        .collect()
}

/// Bilinear downscale in 8-bit fixed point (weights in 1/256, rounded once at the end).
fn resize(img: &Image<u8>, w: usize, h: usize) -> Image<u8> {
    let (xt, yt) = (taps(img.width, w), taps(img.height, h));
    let sw = img.width;
    let mut out = Image::filled(w, h, 1, 0u8);
    out.data.par_chunks_mut(w).zip(yt.par_iter()).for_each_init(
        || (vec![0u32; w], vec![0u32; w]),
        |(h0, h1), (row, &(y0, y1, wy))| {
            for (dst, yy) in [(&mut *h0, y0), (&mut *h1, y1)] {
                let src = &img.data[yy * sw..(yy + 1) * sw];
                for (d, &(x0, x1, wx)) in dst.iter_mut().zip(&xt) {
                    *d = src[x0] as u32 * (256 - wx) + src[x1] as u32 * wx;
                }
            }
            for ((o, &a), &b) in row.iter_mut().zip(h0.iter()).zip(h1.iter()) {
                *o = ((a * (256 - wy) + b * wy + (1 << 15)) >> 16) as u8;
            }
        },
    );
    out
}

/// FAST-9 score of pixel (x, y): the largest t for which 9 contiguous circle pixels are all
/// brighter than p + t or all darker than p − t (0 when not a corner at `thr`).
#[inline]
fn fast_score(d: &[u8], w: usize, x: usize, y: usize, thr: i32) -> i32 {
    let p = d[y * w + x] as i32;
    let at = |k: usize| {
        let (dx, dy) = CIRCLE[k];
        d[((y as i32 + dy) as usize) * w + (x as i32 + dx) as usize] as i32
    };
    // Quick rejection: an arc of 9 covers at least 2 of the 4 compass pixels.
    let c = [at(0), at(4), at(8), at(12)];
    let nb = c.iter().filter(|&&v| v > p + thr).count();
    let nd = c.iter().filter(|&&v| v < p - thr).count();
    if nb < 2 && nd < 2 {
        return 0;
    }
    let mut v = [0i32; 16];
    let (mut bm, mut dm) = (0u32, 0u32);
    for (k, e) in v.iter_mut().enumerate() {
        *e = at(k) - p;
        bm |= ((*e > thr) as u32) << k;
        dm |= ((*e < -thr) as u32) << k;
    }
    // 9 contiguous set bits on the 16-ring (doubled so arcs may wrap).
    let has9 = |m: u32| {
        let mut r = m | (m << 16);
        for _ in 1..9 {
            r &= r >> 1;
        }
        r & 0xFFFF != 0
    };
    if !has9(bm) && !has9(dm) {
        return 0;
    }
    let (mut best_b, mut best_d) = (i32::MIN, i32::MIN);
    for s in 0..16 {
        let (mut mb, mut md) = (i32::MAX, i32::MAX);
        for k in 0..9 {
            let e = v[(s + k) & 15];
            mb = mb.min(e);
            md = md.min(-e);
        }
        best_b = best_b.max(mb);
        best_d = best_d.max(md);
    }
    let s = best_b.max(best_d);
    if s > thr {
        s
    } else {
        0
    }
}

/// Compass pre-test of one row, written to vectorise over u8 lanes: `out[k] = 1` where at least
/// 2 of the 4 pixels at distance 3 (N, E, S, W) of pixel x = k + 3 are all brighter than p + t
/// or all darker than p − t (an arc of 9 on the 16-circle always covers 2 of them).
#[inline(always)]
fn compass_row_impl(up: &[u8], row: &[u8], dn: &[u8], t: u8, out: &mut [u8]) {
    let n = out.len();
    let (up, dn, mid, west, east) = (&up[3..n + 3], &dn[3..n + 3], &row[3..n + 3], &row[..n], &row[6..n + 6]);
    for k in 0..n {
        let p = mid[k];
        let (hi, lo) = (p.saturating_add(t), p.saturating_sub(t));
        let nb = (up[k] > hi) as u8 + (dn[k] > hi) as u8 + (west[k] > hi) as u8 + (east[k] > hi) as u8;
        let nd = (up[k] < lo) as u8 + (dn[k] < lo) as u8 + (west[k] < lo) as u8 + (east[k] < lo) as u8;
        out[k] = ((nb >= 2) | (nd >= 2)) as u8;
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn compass_row_avx2(up: &[u8], row: &[u8], dn: &[u8], t: u8, out: &mut [u8]) {
    compass_row_impl(up, row, dn, t, out)
}

/// Runtime-dispatched compass pre-test (integer comparisons: both paths agree exactly).
fn compass_row(up: &[u8], row: &[u8], dn: &[u8], t: u8, out: &mut [u8]) {
    #[cfg(target_arch = "x86_64")]
    if is_x86_feature_detected!("avx2") {
        // SAFETY: AVX2 is present (checked just above).
        unsafe { compass_row_avx2(up, row, dn, t, out) };
        return;
    }
    compass_row_impl(up, row, dn, t, out)
}

/// FAST-9 corners with 3×3 non-maximum suppression: (x, y, score).
fn fast9(img: &Image<u8>, thr: i32) -> Vec<(usize, usize, i32)> {
    let (w, h) = (img.width, img.height);
    if w < 7 || h < 7 {
        return vec![];
    }
    let d = &img.data;
    let t = thr.clamp(0, 255) as u8;
    let mut score = vec![0i32; w * h];
    score.par_chunks_mut(w).enumerate().skip(3).take(h - 6).for_each_init(
        || vec![0u8; w - 6],
        |mask, (y, row)| {
            compass_row(&d[(y - 3) * w..(y - 2) * w], &d[y * w..(y + 1) * w], &d[(y + 3) * w..(y + 4) * w], t, mask);
            for (k, &m) in mask.iter().enumerate() {
                if m != 0 {
                    row[k + 3] = fast_score(d, w, k + 3, y, thr);
                }
            }
        },
    );
    let mut out = vec![];
    for y in 4..h.saturating_sub(4) {
        for x in 4..w - 4 {
            let s = score[y * w + x];
            if s == 0 {
                continue;
            }
            let mut is_max = true;
            'n: for dy in -1i32..=1 {
                for dx in -1i32..=1 {
                    if (dx, dy) != (0, 0) && score[(y as i32 + dy) as usize * w + (x as i32 + dx) as usize] >= s {
                        is_max = false;
                        break 'n;
                    }
                }
            }
            if is_max {
                out.push((x, y, s));
            }
        }
    }
    out
}

/// Keep the `n` best by score (and every tie with the n-th, as OpenCV's `retainBest`), in a
/// deterministic order (score descending, then row, then column).
fn retain_best<T: Copy>(mut v: Vec<(usize, usize, T)>, n: usize, key: impl Fn(&T) -> f64) -> Vec<(usize, usize, T)> {
    v.sort_by(|a, b| key(&b.2).total_cmp(&key(&a.2)).then(a.1.cmp(&b.1)).then(a.0.cmp(&b.0)));
    if v.len() > n {
        if n == 0 {
            return vec![];
        }
        let edge = key(&v[n - 1].2);
        let mut k = n;
        while k < v.len() && key(&v[k].2) >= edge {
            k += 1;
        }
        v.truncate(k);
    }
    v
}

/// Harris response over a 7×7 window of 3×3 Sobel gradients (OpenCV `HarrisResponses`).
fn harris(img: &Image<u8>, x: usize, y: usize) -> f64 {
    let (w, d) = (img.width, &img.data);
    let px = |x: usize, y: usize| d[y * w + x] as i32;
    let (mut a, mut b, mut c) = (0i64, 0i64, 0i64);
    for yy in y - 3..=y + 3 {
        for xx in x - 3..=x + 3 {
            let ix = (px(xx + 1, yy) - px(xx - 1, yy)) * 2
                + (px(xx + 1, yy - 1) - px(xx - 1, yy - 1))
                + (px(xx + 1, yy + 1) - px(xx - 1, yy + 1));
            let iy = (px(xx, yy + 1) - px(xx, yy - 1)) * 2
                + (px(xx - 1, yy + 1) - px(xx - 1, yy - 1))
                + (px(xx + 1, yy + 1) - px(xx + 1, yy - 1));
            a += (ix * ix) as i64;
            b += (iy * iy) as i64;
            c += (ix * iy) as i64;
        }
    }
    let scale: f64 = 1.0 / (4.0 * 7.0 * 255.0);
    let (a, b, c) = (a as f64, b as f64, c as f64);
    (a * b - c * c - 0.04 * (a + b) * (a + b)) * scale.powi(4)
}

/// Row half-widths of the circular patch of radius 15 (OpenCV `umax`).
fn umax() -> [i32; 16] {
    let hp = HALF_PATCH;
    let mut u = [0i32; 16];
    let vmax = (hp as f64 * 2f64.sqrt() / 2.0 + 1.0).floor() as i32;
    let vmin = (hp as f64 * 2f64.sqrt() / 2.0).ceil() as i32;
    for v in 0..=vmax {
        u[v as usize] = ((hp * hp - v * v) as f64).sqrt().round() as i32;
    }
    let mut v0 = 0usize;
    let mut v = hp;
    while v >= vmin {
        while u[v0] == u[v0 + 1] {
            v0 += 1;
        }
        u[v as usize] = v0 as i32;
        v0 += 1;
        v -= 1;
    }
    u
}

/// Intensity-centroid orientation (rad, from +x towards +y): atan2(m01, m10) over the disc.
fn ic_angle(img: &Image<u8>, x: usize, y: usize, um: &[i32; 16]) -> f64 {
    let (w, d) = (img.width as i64, &img.data);
    let c = y as i64 * w + x as i64;
    let (mut m01, mut m10) = (0i64, 0i64);
    for u in -HALF_PATCH as i64..=HALF_PATCH as i64 {
        m10 += u * d[(c + u) as usize] as i64;
    }
    for v in 1..=HALF_PATCH as i64 {
        let mut vs = 0i64;
        let r = um[v as usize] as i64;
        for u in -r..=r {
            let (p, m) = (d[(c + u + v * w) as usize] as i64, d[(c + u - v * w) as usize] as i64);
            vs += p - m;
            m10 += u * (p + m);
        }
        m01 += v * vs;
    }
    let a = (m01 as f64).atan2(m10 as f64);
    if a < 0.0 {
        a + std::f64::consts::TAU
    } else {
        a
    }
}

/// 7×7 Gaussian blur, σ = 2, border reflect-101 (OpenCV's pre-BRIEF smoothing); separable,
/// interior rows and columns without border arithmetic so the loops vectorise.
fn blur7(img: &Image<u8>) -> Image<u8> {
    let k: [f32; 7] = {
        let g: [f32; 7] = std::array::from_fn(|i| (-((i as f32 - 3.0).powi(2)) / 8.0).exp());
        let s: f32 = g.iter().sum();
        g.map(|v| v / s)
    };
    let (w, h) = (img.width, img.height);
    let refl = |i: i64, n: usize| -> usize {
        let n = n as i64;
        if n == 1 {
            return 0;
        }
        let mut i = i;
        while i < 0 || i >= n {
            i = if i < 0 { -i } else { 2 * n - 2 - i };
        }
        i as usize
    };
    let mut tmp = vec![0f32; w * h];
    tmp.par_chunks_mut(w).zip(img.data.par_chunks(w)).for_each(|(row, src)| {
        for x in 0..w {
            if x >= 3 && x + 3 < w {
                let win = &src[x - 3..x + 4];
                row[x] = k[0] * win[0] as f32
                    + k[1] * win[1] as f32
                    + k[2] * win[2] as f32
                    + k[3] * win[3] as f32
                    + k[4] * win[4] as f32
                    + k[5] * win[5] as f32
                    + k[6] * win[6] as f32;
            } else {
                row[x] = (0..7).map(|t| k[t] * src[refl(x as i64 + t as i64 - 3, w)] as f32).sum();
            }
        }
    });
    let mut out = Image::filled(w, h, 1, 0u8);
    out.data.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        let rows: [&[f32]; 7] = std::array::from_fn(|t| {
            let yy = refl(y as i64 + t as i64 - 3, h);
            &tmp[yy * w..(yy + 1) * w]
        });
        for x in 0..w {
            let v = k[0] * rows[0][x]
                + k[1] * rows[1][x]
                + k[2] * rows[2][x]
                + k[3] * rows[3][x]
                + k[4] * rows[4][x]
                + k[5] * rows[5][x]
                + k[6] * rows[6][x];
            row[x] = (v + 0.5) as u8;
        }
    });
    out
}

/// Steered BRIEF: 256 tests `I(R p1) < I(R p2)` on the blurred level, R = rotation by `angle`.
fn brief(img: &Image<u8>, x: usize, y: usize, angle: f64) -> [u8; 32] {
    let (a, b) = ((angle as f32).cos(), (angle as f32).sin());
    let (w, d) = (img.width as i64, &img.data);
    let c = y as i64 * w + x as i64;
    // cvRound (half to even) by the 1.5·2²³ trick: exact for |v| < 2²², no libm call (SSE2
    // has no round instruction; `round_ties_even` became a call to rintf, 11 % of ORB's time).
    const MAGIC: f32 = 12_582_912.0;
    let rnd = |v: f32| ((v + MAGIC) - MAGIC) as i64;
    let val = |px: i8, py: i8| {
        let (px, py) = (px as f32, py as f32);
        let yy = rnd(px * b + py * a);
        let xx = rnd(px * a - py * b);
        d[(c + yy * w + xx) as usize]
    };
    let mut out = [0u8; 32];
    for (i, byte) in out.iter_mut().enumerate() {
        for k in 0..8 {
            let p = BIT_PATTERN_31[i * 8 + k];
            if val(p[0], p[1]) < val(p[2], p[3]) {
                *byte |= 1 << k;
            }
        }
    }
    out
}

/// One level: keypoints (level px) with their Harris response, angle and descriptor.
fn level_features(img: &Image<u8>, budget: usize, thr: i32, um: &[i32; 16]) -> Vec<(usize, usize, f64, f64, [u8; 32])> {
    if budget == 0 || img.width <= 2 * EDGE || img.height <= 2 * EDGE {
        return vec![];
    }
    let (w, h) = (img.width, img.height);
    let corners: Vec<_> = fast9(img, thr)
        .into_iter()
        .filter(|&(x, y, _)| x >= EDGE && x < w - EDGE && y >= EDGE && y < h - EDGE)
        .collect();
    let corners = retain_best(corners, 2 * budget, |&s| s as f64);
    let scored: Vec<(usize, usize, f64)> = corners.iter().map(|&(x, y, _)| (x, y, harris(img, x, y))).collect();
    let mut best = retain_best(scored, budget, |&r| r);
    best.truncate(budget);
    let blurred = blur7(img);
    best.iter()
        .map(|&(x, y, r)| {
            let a = ic_angle(img, x, y, um);
            (x, y, r, a, brief(&blurred, x, y, a))
        })
        .collect()
}

/// OpenCV-style ORB on a grey u8 image (parameters checked by the caller).
pub fn detect_and_describe(gray: &Image<u8>, p: &OrbParams) -> Features {
    let scale = p.scale_factor as f64;
    let budgets = per_level(p.n_features, p.n_levels, scale);
    let mut levels = vec![gray.clone()];
    for k in 1..p.n_levels {
        let s = scale.powi(k as i32);
        let (lw, lh) = ((gray.width as f64 / s).round() as usize, (gray.height as f64 / s).round() as usize);
        if lw <= 2 * EDGE || lh <= 2 * EDGE {
            break;
        }
        let next = resize(&levels[k - 1], lw, lh);
        levels.push(next);
    }
    let um = umax();
    let thr = p.fast_threshold.round() as i32;
    let per: Vec<_> = levels.par_iter().enumerate().map(|(k, img)| level_features(img, budgets[k], thr, &um)).collect();
    let mut keypoints = vec![];
    let mut data = vec![];
    for (k, feats) in per.into_iter().enumerate() {
        let s = scale.powi(k as i32);
        for (x, y, r, a, d) in feats {
            keypoints.push(Keypoint {
                x: x as f64 * s,
                y: y as f64 * s,
                size_px: 31.0 * s,
                angle_rad: a,
                response: r,
                octave: k as i32,
            });
            data.extend_from_slice(&d);
        }
    }
    Features { keypoints, descriptors: Descriptors::Binary { bytes: 32, data } }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn level_budgets_sum_to_n() {
        let b = per_level(2000, 8, 1.2);
        assert_eq!(b.iter().sum::<usize>(), 2000);
        assert_eq!(b[0], 434); // 2000 · (1 − 1/1.2) / (1 − 1.2⁻⁸) = 434.35
    }

    #[test]
    fn umax_is_a_disc_of_radius_15() {
        // OpenCV's table for patchSize 31.
        assert_eq!(umax(), [15, 15, 15, 15, 14, 14, 14, 13, 13, 12, 11, 10, 9, 8, 6, 3]);
    }

    #[test]
    fn fast_finds_a_bright_corner_and_not_an_edge() {
        // A bright square on black: its corner at (10, 10) is a FAST corner (arc of ≥ 9 dark
        // circle pixels), a point in the middle of an edge is not.
        let mut img = Image::filled(30, 30, 1, 0u8);
        for y in 10..25 {
            for x in 10..25 {
                img.set(x, y, 0, 200);
            }
        }
        assert!(fast_score(&img.data, 30, 10, 10, 20) > 20);
        assert_eq!(fast_score(&img.data, 30, 17, 10, 20), 0);
        assert_eq!(fast_score(&img.data, 30, 17, 17, 20), 0);
        // Score = the largest threshold still passing: 200 − 0 − 1 would fail at 200.
        assert_eq!(fast_score(&img.data, 30, 10, 10, 20), 200);
    }

    #[test]
    fn resize_taps_and_ramp() {
        // 6 → 5: positions (i + ½)·1.2 − ½ = 0.1, 1.3, 2.5, 3.7, 4.9.
        let t = taps(6, 5);
        assert_eq!(t, vec![(0, 1, 26), (1, 2, 77), (2, 3, 128), (3, 4, 179), (4, 5, 230)]);
        // A ramp 10·x resized keeps 10·position (rounded).
        let img = Image::from_vec(6, 2, 1, (0..12).map(|i| (i % 6 * 10) as u8).collect()).unwrap();
        let r = resize(&img, 5, 2);
        assert_eq!(&r.data[..5], &[1, 13, 25, 37, 49]);
    }

    #[test]
    fn compass_pretest_never_rejects_a_corner() {
        let mut s = 99u32;
        let data: Vec<u8> = (0..64 * 40)
            .map(|_| {
                s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                (s >> 24) as u8
            })
            .collect();
        let img = Image::from_vec(64, 40, 1, data).unwrap();
        let mut m = vec![0u8; 58];
        let mut m2 = vec![0u8; 58];
        let mut corners = 0;
        for y in 3..37 {
            let d = &img.data;
            compass_row(
                &d[(y - 3) * 64..(y - 2) * 64],
                &d[y * 64..(y + 1) * 64],
                &d[(y + 3) * 64..(y + 4) * 64],
                20,
                &mut m,
            );
            compass_row_impl(
                &d[(y - 3) * 64..(y - 2) * 64],
                &d[y * 64..(y + 1) * 64],
                &d[(y + 3) * 64..(y + 4) * 64],
                20,
                &mut m2,
            );
            assert_eq!(m, m2);
            for x in 3..61 {
                if fast_score(d, 64, x, y, 20) > 0 {
                    corners += 1;
                    assert_eq!(m[x - 3], 1, "({x}, {y})");
                }
            }
        }
        assert!(corners > 10);
    }

    #[test]
    fn ic_angle_points_to_the_bright_side() {
        // Brightness increasing with x → angle 0; with y → π/2.
        let gx = Image::from_vec(40, 40, 1, (0..1600).map(|i| (i % 40 * 5) as u8).collect()).unwrap();
        let gy = Image::from_vec(40, 40, 1, (0..1600).map(|i| (i / 40 * 5) as u8).collect()).unwrap();
        let um = umax();
        assert!(ic_angle(&gx, 20, 20, &um).min(std::f64::consts::TAU - ic_angle(&gx, 20, 20, &um)) < 1e-9);
        assert!((ic_angle(&gy, 20, 20, &um) - std::f64::consts::FRAC_PI_2).abs() < 1e-9);
    }
}
